/* Runtime: the process-data and error services of a line and its node.
 *
 * Per line (local node or not): SYNC and TIME (consumers always; producers
 * from the node's OD or the API), the EMCY consumer (nodes watched by the
 * application, 0x1028 of the node's OD), and on classic lines the node
 * guarding master. Per local node: the EMCY producer, and with an OD the
 * PDOs and (classic) the guarding slave; co_node wires them together.
 * Python hears what it asked for: received EMCYs, RPDOs it listens to, TIME,
 * SYNC when asked, guarding events. The thread never calls Python: all of
 * it is posted as events. */
#include "co_rt_internal.h"

#include <stdlib.h>
#include <string.h>

/* ---------------------------------------------------------------- events */

static void on_emcy(co_stack_t *stack, uint8_t node_id, const co_emcy_msg_t *msg, void *user)
{
    (void)stack;
    rt_line_t *l = user;
    co_frame_t frame;
    memset(&frame, 0, sizeof frame);
    bool fd = co_line_mode(&l->line) == CO_MODE_FD;
    frame.len = (uint8_t)(fd ? co_emcy_encode_fd(msg, frame.data, sizeof frame.data)
                             : co_emcy_encode_classic(msg, frame.data, sizeof frame.data));
    rt_post(l, CO_EV_EMCY, node_id, fd ? 1u : 0u, msg->code, &frame);
}

static void on_time(co_stack_t *stack, const co_time_of_day_t *tod, void *user)
{
    (void)stack;
    rt_post(user, CO_EV_TIME, 0, tod->ms, tod->days, NULL);
}

static void on_sync(uint8_t counter, void *user)
{
    rt_line_t *l = user;
    if (l->sync_events) {
        rt_post(l, CO_EV_SYNC, 0, counter, 0, NULL);
    }
}

static void on_guard(co_stack_t *stack, uint8_t node_id, co_guard_event_t event,
                     co_nmt_state_t state, void *user)
{
    (void)stack;
    rt_post(user, CO_EV_GUARD, node_id, (uint32_t)event, (uint32_t)state, NULL);
}

/* Boot-ups, states and heartbeat losses of every node (local node or not);
 * the stack tells the node itself. */
static void on_heartbeat(co_stack_t *stack, uint8_t node_id, co_hb_event_t event,
                         co_nmt_state_t state, void *user)
{
    (void)stack;
    rt_post(user, CO_EV_HEARTBEAT, node_id, (uint32_t)event, (uint32_t)state, NULL);
}

static void on_comm(co_stack_t *stack, co_comm_event_t event, void *user)
{
    (void)stack;
    rt_post(user, CO_EV_COMM, 0, (uint32_t)event, 0, NULL);
}

void rt_services_pdo_received(rt_line_t *l, uint16_t number)
{
    if (number == 0 || number > CO_PDO_MAX_NUMBER || !l->pdo_listen[number - 1u]) {
        return;
    }
    /* the values as now in the OD, laid out as the mapping says */
    co_frame_t frame;
    memset(&frame, 0, sizeof frame);
    if (co_pdo_pack_values(co_stack_pdo(&l->stack), true, number, frame.data, &frame.len)) {
        rt_post(l, CO_EV_PDO, co_stack_node(&l->stack)->nmt.node_id, number, 0, &frame);
    }
}

#define WATCH_EXT 0x20000000u   /* bit 29 of a COB-ID: 29-bit CAN-ID */

static int watch_find(const rt_line_t *l, uint32_t can_id)
{
    if (!(can_id & WATCH_EXT)) {
        return (int)l->watch_of[can_id & 0x7FFu] - 1;
    }
    for (int i = 0; i < l->watch_count; i++) {
        if (l->watch_ids[i] == can_id) {
            return i;
        }
    }
    return -1;
}

/* Offered before the PDO service (registered first): watched frames are
 * posted and then left to whoever else takes them. */
static bool on_watched(co_line_t *line, const co_frame_t *frame, void *user)
{
    (void)line;
    rt_line_t *l = user;
    if (l->watch_count == 0 || (frame->flags & CO_FRAME_RTR)) {
        return false;
    }
    uint32_t can_id = (frame->flags & CO_FRAME_EXT) ? (frame->id | WATCH_EXT) : frame->id;
    int slot = watch_find(l, can_id);
    if (slot >= 0) {
        l->watch_frames[slot]++;
        rt_post(l, CO_EV_PDO_FRAME, 0, can_id, l->watch_frames[slot], frame);
    }
    return false;
}

/* ---------------------------------------------------------------- set-up */

bool rt_services_line_watch(rt_line_t *l)
{
    return co_line_subscribe_other(&l->line, on_watched, l);
}

const co_stack_indications_t rt_services_indications = {
    .heartbeat = on_heartbeat,
    .emcy = on_emcy,
    .time = on_time,
    .guard = on_guard,
    .comm = on_comm,
};

bool rt_services_line_init(rt_line_t *l)
{
    return co_sync_add_listener(co_stack_sync(&l->stack), on_sync, l);
}

/* A node that could not be created: nothing of it is listened to. */
void rt_services_node_detach(rt_line_t *l)
{
    memset(l->pdo_listen, 0, sizeof l->pdo_listen);
}

/* ---------------------------------------------------------------- API */

/* The line, locked, with a local node (or NULL with the error set, unlocked). */
static rt_line_t *node_line(co_rt_t *rt, int line, const char *what)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return NULL;
    }
    pthread_mutex_lock(&rt->lock);
    if (!rt_has_node(l)) {
        pthread_mutex_unlock(&rt->lock);
        rt_set_error(rt, "line %d: %s needs a local node", line, what);
        return NULL;
    }
    return l;
}

static int done(co_rt_t *rt, int status)
{
    rt_kick(rt);
    pthread_mutex_unlock(&rt->lock);
    return status;
}

int co_rt_emcy(co_rt_t *rt, int line, const co_rt_emcy_t *error, int clear)
{
    if (!error) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_line_t *l = node_line(rt, line, clear ? "clearing an EMCY" : "raising an EMCY");
    if (!l) {
        return CO_RT_ERR_STATE;
    }
    co_emcy_error_t err = {.code = error->code,
                           .register_bits = error->register_bits,
                           .logical_device = error->logical_device,
                           .spec_number = error->spec_number,
                           .priority = error->priority,
                           .non_recoverable = error->non_recoverable != 0,
                           .time_stamp = error->time_stamp};
    memcpy(err.msef, error->msef, sizeof err.msef);
    co_line_set_time(&l->line, co_rt_now_us());
    co_emcy_result_t r = clear ? co_emcy_clear(co_stack_emcy(&l->stack), &err) : co_emcy_raise(co_stack_emcy(&l->stack), &err);
    if (r == CO_EMCY_BAD_ARGUMENT) {
        rt_set_error(rt, "line %d: EMCY 0x%04X refused: code 0, priority %u > 7 or time "
                     "stamp above 48 bits", line, error->code, (unsigned)error->priority);
        return done(rt, CO_RT_ERR_ARGUMENT);
    }
    if (r == CO_EMCY_TABLE_FULL) {
        rt_set_error(rt, "line %d: EMCY 0x%04X refused: %u errors are active already", line,
                     error->code, (unsigned)co_stack_emcy(&l->stack)->active_capacity);
        return done(rt, CO_RT_ERR_FULL);
    }
    return done(rt, (int)r);
}

int co_rt_emcy_state(co_rt_t *rt, int line, co_rt_emcy_state_t *out)
{
    if (!out) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_line_t *l = node_line(rt, line, "the EMCY state");
    if (!l) {
        return CO_RT_ERR_STATE;
    }
    *out = (co_rt_emcy_state_t){.error_register = co_emcy_error_register(co_stack_emcy(&l->stack)),
                                .active = co_emcy_active_count(co_stack_emcy(&l->stack)),
                                .sent = co_stack_emcy(&l->stack)->stats.sent,
                                .dropped = co_stack_emcy(&l->stack)->stats.dropped};
    pthread_mutex_unlock(&rt->lock);
    return CO_RT_OK;
}

int co_rt_emcy_watch(co_rt_t *rt, int line, int node_id, int watch)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    if (node_id < 1 || node_id > 127) {
        return rt_argument_error(rt, "line %d: EMCY of node %d: node-ids are 1..127", line,
                                 node_id);
    }
    pthread_mutex_lock(&rt->lock);
    int status = CO_RT_OK;
    if (!watch) {
        co_emcy_consumer_unwatch(co_stack_emcy_consumer(&l->stack), (uint8_t)node_id);
    } else if (!co_emcy_consumer_watch(co_stack_emcy_consumer(&l->stack), (uint8_t)node_id)) {
        rt_set_error(rt, "line %d: cannot consume the EMCY of node %d (CAN-ID 0x%X taken?)",
                     line, node_id, 0x80 + node_id);
        status = CO_RT_ERR_STATE;
    }
    pthread_mutex_unlock(&rt->lock);
    return status;
}

static rt_line_t *pdo_line(co_rt_t *rt, int line)
{
    rt_line_t *l = node_line(rt, line, "a PDO");
    if (l && !(co_stack_pdo(&l->stack) != NULL)) {
        pthread_mutex_unlock(&rt->lock);
        rt_set_error(rt, "line %d: the local node has no object dictionary, so no PDOs", line);
        return NULL;
    }
    return l;
}

int co_rt_pdo_trigger(co_rt_t *rt, int line, int tpdo_number)
{
    rt_line_t *l = pdo_line(rt, line);
    if (!l) {
        return CO_RT_ERR_STATE;
    }
    co_line_set_time(&l->line, co_rt_now_us());
    if (tpdo_number < 1 || tpdo_number > CO_PDO_MAX_NUMBER ||
        !co_pdo_trigger(co_stack_pdo(&l->stack), (uint16_t)tpdo_number)) {
        rt_set_error(rt, "line %d: TPDO %d not sent: %s", line, tpdo_number,
                     tpdo_number < 1 || tpdo_number > CO_PDO_MAX_NUMBER ? "numbers are 1..512"
                     : !co_pdo_is_active(co_stack_pdo(&l->stack), false, (uint16_t)tpdo_number)
                         ? "it does not exist or is not valid (COB-ID bit 31, mapping)"
                     : co_stack_node(&l->stack)->nmt.state != CO_NMT_OPERATIONAL
                         ? "the node is not operational"
                         : "its transmission type takes no events (0, 254 or 255 do)");
        return done(rt, CO_RT_ERR_STATE);
    }
    return done(rt, CO_RT_OK);
}

int co_rt_pdo_trigger_object(co_rt_t *rt, int line, int index, int sub)
{
    rt_line_t *l = pdo_line(rt, line);
    if (!l) {
        return CO_RT_ERR_STATE;
    }
    if (index < 0 || index > 0xFFFF || sub < 0 || sub > 0xFF) {
        pthread_mutex_unlock(&rt->lock);
        return rt_argument_error(rt, "line %d: no object %X:%X", line, index, sub);
    }
    co_line_set_time(&l->line, co_rt_now_us());
    uint32_t n = co_pdo_trigger_object(co_stack_pdo(&l->stack), (uint16_t)index, (uint8_t)sub);
    return done(rt, (int)n);
}

int co_rt_pdo_watch(co_rt_t *rt, int line, uint32_t can_id, int watch)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    bool ext = (can_id & WATCH_EXT) != 0;
    if ((ext && (can_id & ~(WATCH_EXT | 0x1FFFFFFFu)) != 0) || (!ext && can_id > 0x7FFu)) {
        return rt_argument_error(rt, "line %d: PDO CAN-ID 0x%X: 11 bits, or 29 bits with bit "
                                 "29 set", line, (unsigned)can_id);
    }
    pthread_mutex_lock(&rt->lock);
    int slot = watch_find(l, can_id);
    int status = CO_RT_OK;
    if (watch && slot < 0) {
        if (l->watch_count >= RT_PDO_WATCHES) {
            rt_set_error(rt, "line %d: already %d PDO CAN-IDs watched", line, RT_PDO_WATCHES);
            status = CO_RT_ERR_FULL;
        } else {
            slot = l->watch_count++;
            l->watch_ids[slot] = can_id;
            l->watch_frames[slot] = 0;
            if (!ext) {
                l->watch_of[can_id] = (uint8_t)(slot + 1);
            }
        }
    } else if (!watch && slot >= 0) {
        /* the last slot moves into the freed one */
        uint8_t last = (uint8_t)(l->watch_count - 1u);
        if (!ext) {
            l->watch_of[can_id] = 0;
        }
        if (slot != last) {
            l->watch_ids[slot] = l->watch_ids[last];
            l->watch_frames[slot] = l->watch_frames[last];
            if (!(l->watch_ids[slot] & WATCH_EXT)) {
                l->watch_of[l->watch_ids[slot]] = (uint8_t)(slot + 1);
            }
        }
        l->watch_count = last;
    }
    pthread_mutex_unlock(&rt->lock);
    return status;
}

int co_rt_pdo_listen(co_rt_t *rt, int line, int rpdo_number, int listen)
{
    if (rpdo_number < 1 || rpdo_number > CO_PDO_MAX_NUMBER) {
        return rt_argument_error(rt, "line %d: RPDO %d: numbers are 1..512", line, rpdo_number);
    }
    rt_line_t *l = pdo_line(rt, line);
    if (!l) {
        return CO_RT_ERR_STATE;
    }
    l->pdo_listen[rpdo_number - 1] = listen != 0;
    pthread_mutex_unlock(&rt->lock);
    return CO_RT_OK;
}

/* Under rt->lock: write a communication entry of the node's OD the way the
 * network would (checks, then the services' handlers). */
static uint32_t od_put_u32(rt_line_t *l, uint16_t index, uint32_t value, uint32_t size)
{
    uint8_t b[4] = {(uint8_t)value, (uint8_t)(value >> 8), (uint8_t)(value >> 16),
                    (uint8_t)(value >> 24)};
    return co_od_put(&l->od, index, 0, b, size);
}

int co_rt_sync_producer(co_rt_t *rt, int line, uint32_t period_us, uint32_t window_us,
                        int overflow)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    if (overflow < 0 || overflow == 1 || overflow > CO_SYNC_COUNTER_MAX) {
        return rt_argument_error(rt, "line %d: SYNC counter overflow %d: 0 (no counter) or "
                                 "2..240", line, overflow);
    }
    pthread_mutex_lock(&rt->lock);
    co_line_set_time(&l->line, co_rt_now_us());
    uint32_t id = co_stack_sync(&l->stack)->config.cob_id & 0x7FFu;
    uint32_t cob_id = period_us ? (id | CO_SYNC_PRODUCER_BIT) : id;
    if (co_stack_sync(&l->stack)->od) {
        /* 0x1019 may change only while 0x1006 is 0 (CiA 301): stop first */
        uint32_t abort = od_put_u32(l, 0x1006, 0, 4);
        if (!abort && co_od_has_index(&l->od, 0x1019)) {
            abort = od_put_u32(l, 0x1019, (uint32_t)overflow, 1);
        }
        if (!abort && co_od_has_index(&l->od, 0x1007)) {
            abort = od_put_u32(l, 0x1007, window_us, 4);
        }
        if (!abort) {
            abort = od_put_u32(l, 0x1005, cob_id, 4);
        }
        if (!abort && period_us) {
            abort = od_put_u32(l, 0x1006, period_us, 4);
        }
        if (abort) {
            rt_set_error(rt, "line %d: SYNC producer: the node's OD refused the SYNC "
                         "parameters (abort 0x%08X)", line, (unsigned)abort);
            return done(rt, CO_RT_ERR_ARGUMENT);
        }
    } else {
        co_sync_config_t config = {.cob_id = cob_id,
                                   .period_us = period_us,
                                   .window_us = window_us,
                                   .overflow = (uint8_t)overflow};
        co_sync_configure(co_stack_sync(&l->stack), &config);
    }
    return done(rt, CO_RT_OK);
}

int co_rt_sync_listen(co_rt_t *rt, int line, int listen)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    pthread_mutex_lock(&rt->lock);
    l->sync_events = listen != 0;
    pthread_mutex_unlock(&rt->lock);
    return CO_RT_OK;
}

int co_rt_time_send(co_rt_t *rt, int line, uint64_t unix_us)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    pthread_mutex_lock(&rt->lock);
    co_line_set_time(&l->line, co_rt_now_us());
    if (!co_stack_time(&l->stack)->od && !(co_stack_time(&l->stack)->cob_id & CO_TIME_PRODUCER_BIT)) {
        /* a line without the node's 0x1012: the application is the producer */
        (void)co_time_set_cob_id(co_stack_time(&l->stack), co_stack_time(&l->stack)->cob_id | CO_TIME_PRODUCER_BIT);
    }
    if (!co_time_send_unix_us(co_stack_time(&l->stack), unix_us)) {
        rt_set_error(rt, "line %d: TIME not sent: %s", line,
                     !(co_stack_time(&l->stack)->cob_id & CO_TIME_PRODUCER_BIT)
                         ? "the node's 0x1012 does not make it the TIME producer (bit 30)"
                     : !co_stack_time(&l->stack)->nmt_active ? "the node is stopped"
                                           : "time before 1984 or the tx queue is full");
        return done(rt, CO_RT_ERR_STATE);
    }
    return done(rt, CO_RT_OK);
}

int co_rt_guard(co_rt_t *rt, int line, int node_id, int guard_ms, int life_factor)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    if (!(co_stack_guard_master(&l->stack) != NULL)) {
        return rt_argument_error(rt, "line %d: node guarding needs a classic line (CAN FD "
                                 "has no remote frames)", line);
    }
    if (node_id < 1 || node_id > 127 || guard_ms < 0 || guard_ms > 0xFFFF || life_factor < 0 ||
        life_factor > 0xFF) {
        return rt_argument_error(rt, "line %d: guarding node %d every %d ms, factor %d: "
                                 "node 1..127, time 0..65535 ms, factor 0..255", line,
                                 node_id, guard_ms, life_factor);
    }
    pthread_mutex_lock(&rt->lock);
    co_line_set_time(&l->line, co_rt_now_us());
    int status = CO_RT_OK;
    if (guard_ms == 0) {
        co_guard_master_unguard(co_stack_guard_master(&l->stack), (uint8_t)node_id);
    } else if (co_guard_master_guard(co_stack_guard_master(&l->stack), (uint8_t)node_id, (uint16_t)guard_ms,
                                     (uint8_t)life_factor) != CO_GUARD_OK) {
        rt_set_error(rt, "line %d: cannot guard node %d (%d nodes guarded already)", line,
                     node_id, RT_GUARD_NODES);
        status = CO_RT_ERR_FULL;
    }
    return done(rt, status);
}

int co_rt_service_stats(co_rt_t *rt, int line, co_rt_service_stats_t *out)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l || !out) {
        return CO_RT_ERR_ARGUMENT;
    }
    memset(out, 0, sizeof *out);
    pthread_mutex_lock(&rt->lock);
    if (co_stack_pdo(&l->stack)) {
        out->pdo = co_stack_pdo(&l->stack)->stats;
    }
    if (co_stack_emcy(&l->stack)) {
        out->emcy = co_stack_emcy(&l->stack)->stats;
    }
    if (co_stack_guard_slave(&l->stack)) {
        out->guard_slave = co_stack_guard_slave(&l->stack)->stats;
    }
    if (co_stack_guard_master(&l->stack)) {
        out->guard_master = co_stack_guard_master(&l->stack)->stats;
    }
    out->emcy_consumer = co_stack_emcy_consumer(&l->stack)->stats;
    out->sync = co_stack_sync(&l->stack)->stats;
    out->time = co_stack_time(&l->stack)->stats;
    for (int i = 0; i < l->watch_count; i++) {
        out->pdo_watched += l->watch_frames[i];
    }
    pthread_mutex_unlock(&rt->lock);
    return CO_RT_OK;
}
