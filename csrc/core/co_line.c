#include "canopenfd/co_line.h"

#include <string.h>

/* co_queue_drop_head for a queue known not to be empty, here so that the
 * per-frame paths (dispatch, the driver's pop) need no call for it. */
static inline void queue_drop_head(co_frame_queue_t *q)
{
    CO_ASSERT(q->count > 0 && q->count <= q->capacity && q->head < q->capacity);
    q->head = (q->head + 1 == q->capacity) ? 0 : q->head + 1;
    q->count--;
}

bool co_line_init(co_line_t *line, const co_line_config_t *config)
{
    if (!config || !config->rx_slots || !config->tx_slots || config->rx_capacity == 0 ||
        config->tx_capacity == 0 ||
        (config->mode != CO_MODE_CLASSIC && config->mode != CO_MODE_FD)) {
        return false;
    }
    memset(line, 0, sizeof *line);
    line->mode = config->mode;
    if (config->mode == CO_MODE_FD) {
        line->tx_flags = CO_FRAME_FD | (config->brs ? CO_FRAME_BRS : 0);
    }
    co_queue_init(&line->rx, config->rx_slots, config->rx_capacity);
    co_queue_init(&line->tx, config->tx_slots, config->tx_capacity);
    co_timer_list_init(&line->timers);
    return true;
}

void co_line_set_comm_indication(co_line_t *line, co_comm_fn fn, void *user)
{
    line->on_comm = fn;
    line->comm_user = user;
}

void co_line_set_node_id(co_line_t *line, uint8_t node_id)
{
    line->node_id = node_id;
}

void co_line_count_rejected(co_line_t *line, co_line_reject_t reason)
{
    co_line_stats_t *s = &line->stats;
    switch (reason) {
    case CO_LINE_NMT_BAD_LENGTH:
        s->nmt_bad_length++;
        break;
    case CO_LINE_NMT_BAD_COMMAND:
        s->nmt_bad_command++;
        break;
    case CO_LINE_NMT_BAD_NODE:
        s->nmt_bad_node++;
        break;
    case CO_LINE_HB_BAD_LENGTH:
        s->hb_bad_length++;
        break;
    case CO_LINE_HB_BAD_STATE:
        s->hb_bad_state++;
        break;
    case CO_LINE_HB_BAD_NODE:
        s->hb_bad_node++;
        break;
    }
}

void co_line_comm_event(co_line_t *line, co_comm_event_t event)
{
    if (line->on_comm) {
        line->on_comm(line, event, line->comm_user);
    }
}

bool co_line_subscribe(co_line_t *line, uint32_t first_id, uint32_t last_id,
                       co_rx_fn fn, void *user)
{
    if (!fn || first_id > last_id || last_id >= CO_LINE_ID_MAP_SIZE ||
        line->receiver_count >= CO_LINE_MAX_RECEIVERS) {
        return false;
    }
    for (uint32_t id = first_id; id <= last_id; id++) {
        if (line->id_map[id] != 0) {
            return false;
        }
    }
    uint8_t slot = line->receiver_count++;
    line->receivers[slot] = (co_receiver_t){first_id, last_id, fn, user};
    for (uint32_t id = first_id; id <= last_id; id++) {
        line->id_map[id] = (uint8_t)(slot + 1);
    }
    return true;
}

static void rebuild_id_map(co_line_t *line)
{
    memset(line->id_map, 0, sizeof line->id_map);
    for (uint8_t slot = 0; slot < line->receiver_count; slot++) {
        const co_receiver_t *r = &line->receivers[slot];
        for (uint32_t id = r->first_id; id <= r->last_id; id++) {
            line->id_map[id] = (uint8_t)(slot + 1);
        }
    }
}

void co_line_unsubscribe(co_line_t *line, co_rx_fn fn, void *user)
{
    uint8_t kept = 0;
    for (uint8_t slot = 0; slot < line->receiver_count; slot++) {
        const co_receiver_t *r = &line->receivers[slot];
        if (r->fn != fn || r->user != user) {
            line->receivers[kept++] = *r;
        }
    }
    if (kept != line->receiver_count) {
        line->receiver_count = kept;
        rebuild_id_map(line);
    }
}

bool co_line_subscribe_other(co_line_t *line, co_rx_other_fn fn, void *user)
{
    if (fn == NULL || line->other_count >= CO_LINE_MAX_OTHER) {
        return false;
    }
    for (uint8_t i = 0; i < line->other_count; i++) {
        if (line->other[i].fn == fn && line->other[i].user == user) {
            return false;
        }
    }
    line->other[line->other_count++] = (co_other_receiver_t){fn, user};
    return true;
}

void co_line_unsubscribe_other(co_line_t *line, co_rx_other_fn fn, void *user)
{
    uint8_t kept = 0;
    for (uint8_t i = 0; i < line->other_count; i++) {
        if (line->other[i].fn != fn || line->other[i].user != user) {
            line->other[kept++] = line->other[i];
        }
    }
    line->other_count = kept;
}

bool co_line_receive(co_line_t *line, const co_frame_t *frame)
{
    line->stats.rx_frames++;
    if (co_queue_push(&line->rx, frame)) {
        return true;
    }
    line->stats.rx_overflow++;
    co_line_comm_event(line, CO_COMM_RX_OVERFLOW);
    return false;
}

bool co_line_rx_pop(co_line_t *line, co_frame_t *out)
{
    return co_queue_pop(&line->rx, out);
}

bool co_line_tx_space_register(co_line_t *line, co_tx_space_fn fn, void *user)
{
    if (fn == NULL || line->tx_space_count >= CO_LINE_MAX_TX_SPACE) {
        return false;
    }
    for (uint8_t i = 0; i < line->tx_space_count; i++) {
        if (line->tx_space[i].fn == fn && line->tx_space[i].user == user) {
            return false;
        }
    }
    line->tx_space[line->tx_space_count++] = (co_tx_space_cb_t){fn, user};
    return true;
}

void co_line_tx_space_unregister(co_line_t *line, co_tx_space_fn fn, void *user)
{
    uint8_t kept = 0;
    for (uint8_t i = 0; i < line->tx_space_count; i++) {
        if (line->tx_space[i].fn != fn || line->tx_space[i].user != user) {
            line->tx_space[kept++] = line->tx_space[i];
        }
    }
    line->tx_space_count = kept;
}

/* One pop lowers the count by one, so "from above half to at-or-below half"
 * is exactly "count == capacity / 2 after the pop". */
static void tx_space_notify(co_line_t *line)
{
    if (co_queue_count(&line->tx) != line->tx.capacity / 2u) {
        return;
    }
    for (uint8_t i = 0; i < line->tx_space_count; i++) {
        line->tx_space[i].fn(line, line->tx_space[i].user);
    }
}

bool co_line_tx_pop(co_line_t *line, co_frame_t *out)
{
    if (co_queue_is_empty(&line->tx)) {
        return false;
    }
    if (out != NULL) {
        *out = *co_queue_at(&line->tx, 0);
    }
    queue_drop_head(&line->tx);
    line->stats.tx_frames++;
    if (line->tx_space_count != 0) {   /* the only cost when nobody listens */
        tx_space_notify(line);
    }
    if (line->tx_was_full && co_queue_is_empty(&line->tx)) {
        line->tx_was_full = false;
        co_line_comm_event(line, CO_COMM_TX_QUEUE_EMPTY);
    }
    return true;
}

/* Queue a frame already checked for the line; overflow and full events. */
static bool queue_tx(co_line_t *line, const co_frame_t *frame)
{
    if (line->silent) {
        line->stats.tx_silenced++;
        return false;
    }
    if (!co_queue_push(&line->tx, frame)) {
        line->stats.tx_overflow++;
        co_line_comm_event(line, CO_COMM_TX_OVERFLOW);
        return false;
    }
    if (!line->tx_was_full && co_queue_is_full(&line->tx)) {
        line->tx_was_full = true;
        co_line_comm_event(line, CO_COMM_TX_QUEUE_FULL);
    }
    return true;
}

void co_line_set_silent(co_line_t *line, bool silent)
{
    if (silent && !line->silent) {
        line->stats.tx_silenced += co_queue_count(&line->tx);
        while (!co_queue_is_empty(&line->tx)) {
            queue_drop_head(&line->tx);
        }
        line->tx_was_full = false;
    }
    line->silent = silent;
}

void co_line_watch_rx(co_line_t *line, co_rx_fn fn, void *user)
{
    line->rx_watch = fn;
    line->rx_watch_user = user;
}

bool co_line_send_raw(co_line_t *line, const co_frame_t *frame)
{
    if (!co_frame_is_valid(frame) ||
        ((frame->flags & CO_FRAME_FD) && line->mode == CO_MODE_CLASSIC)) {
        line->stats.tx_invalid++;
        return false;
    }
    return queue_tx(line, frame);
}

bool co_line_send_frame(co_line_t *line, const co_frame_t *frame)
{
    if (line->mode == CO_MODE_CLASSIC || (frame->flags & CO_FRAME_RTR)) {
        return co_line_send_raw(line, frame);
    }
    if (frame->len > CO_FRAME_MAX_DATA) {
        line->stats.tx_invalid++;
        return false;
    }
    co_frame_t fd;
    co_frame_set(&fd, frame->id, (uint8_t)(frame->flags | line->tx_flags), frame->data,
                 frame->len);
    return co_line_send_raw(line, &fd);
}

/* The same as building the frame and co_line_send_frame, without a second
 * copy: an 11-bit id and no flags, so the checks left are the id and the
 * length (co_frame_set rounds an fd length to a valid one). */
bool co_line_send(co_line_t *line, uint32_t id, const uint8_t *data, size_t len)
{
    co_frame_t frame;
    if (id > 0x7FFu || len > (line->mode == CO_MODE_CLASSIC ? (size_t)CO_FRAME_CLASSIC_MAX
                                                             : (size_t)CO_FRAME_MAX_DATA)) {
        line->stats.tx_invalid++;
        return false;
    }
    (void)co_frame_set(&frame, id, line->tx_flags, data, len);
    return queue_tx(line, &frame);
}

/* Offer a frame no range takes to the "other" receivers; count it when
 * nobody uses it. */
static void dispatch_other(co_line_t *line, const co_frame_t *frame)
{
    for (uint8_t i = 0; i < line->other_count; i++) {
        if (line->other[i].fn(line, frame, line->other[i].user)) {
            return;
        }
    }
    if (frame->flags & CO_FRAME_RTR) {
        line->stats.rx_rtr++;
    } else {
        line->stats.rx_unhandled++;
    }
}

/* Route a received frame to the service that takes it; everything refused is
 * counted in the line statistics. */
static void dispatch(co_line_t *line, const co_frame_t *frame)
{
    if (!co_frame_is_valid(frame)) {
        line->stats.rx_invalid++;
        return;
    }
    if ((frame->flags & CO_FRAME_FD) && line->mode == CO_MODE_CLASSIC) {
        line->stats.rx_wrong_format++;
        return;
    }
    if (line->rx_watch) {
        line->rx_watch(line, frame, line->rx_watch_user);
    }
    if ((frame->flags & (CO_FRAME_RTR | CO_FRAME_EXT)) || line->id_map[frame->id] == 0) {
        dispatch_other(line, frame);
        return;
    }
    CO_ASSERT(line->id_map[frame->id] <= line->receiver_count);
    const co_receiver_t *r = &line->receivers[line->id_map[frame->id] - 1];
    r->fn(line, frame, r->user);
}

uint64_t co_line_process(co_line_t *line, uint64_t now_us)
{
    co_line_set_time(line, now_us);
    /* Only the frames present at entry: a handler that causes more input
     * (loopback drivers) cannot keep this call busy forever. */
    uint32_t pending = co_queue_count(&line->rx);
    /* Dispatched in place, then dropped: no copy. A handler's pushes go to
     * the tail and cannot reach the head slot while it is counted; should a
     * handler take frames itself (co_line_rx_pop), its frame is gone already
     * and is not dropped twice. */
    while (pending-- > 0 && !co_queue_is_empty(&line->rx)) {
        uint32_t head = line->rx.head;
        const co_frame_t *frame = co_queue_at(&line->rx, 0);
        dispatch(line, frame);
        if (line->rx.head == head && !co_queue_is_empty(&line->rx)) {
            queue_drop_head(&line->rx);
        }
    }
    co_timer_list_run(&line->timers, line->now_us);
    return co_timer_list_next(&line->timers);
}
