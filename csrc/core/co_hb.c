#include "canopenfd/co_hb.h"

#include <string.h>

bool co_hb_state_is_valid(uint8_t state)
{
    return state == CO_NMT_INITIALISING || state == CO_NMT_STOPPED ||
           state == CO_NMT_OPERATIONAL || state == CO_NMT_PRE_OPERATIONAL;
}

bool co_hb_encode(co_nmt_state_t state, co_frame_t *frame, uint8_t node_id)
{
    if (node_id < 1 || node_id > 127 || !co_hb_state_is_valid((uint8_t)state)) {
        return false;
    }
    const uint8_t data = (uint8_t)state;
    return co_frame_set(frame, CO_NMT_EC_COB_ID_BASE + node_id, 0, &data, 1);
}

/* ---------------------------------------------------------------- producer */

static void send_heartbeat(co_hb_producer_t *p)
{
    const uint8_t state = (uint8_t)p->nmt->state;
    co_line_send(p->line, CO_NMT_EC_COB_ID_BASE + p->nmt->node_id, &state, 1);
}

static void on_producer_timer(co_timer_t *timer, uint64_t now_us, void *user)
{
    co_hb_producer_t *p = user;
    /* A node still initialising has sent no boot-up yet: stay quiet. */
    if (p->nmt->state != CO_NMT_INITIALISING) {
        send_heartbeat(p);
    }
    /* Next one a period after the deadline, not after now, so a late wake-up
     * does not shift every later heartbeat; after a long stall restart from now. */
    uint64_t period = (uint64_t)p->time_ms * 1000u;
    uint64_t next = timer->deadline_us + period;
    co_timer_start(co_line_timers(p->line), timer, next > now_us ? next : now_us + period);
}

void co_hb_producer_init(co_hb_producer_t *p, co_line_t *line, co_nmt_t *nmt)
{
    p->line = line;
    p->nmt = nmt;
    p->time_ms = 0;
    co_timer_init(&p->timer, on_producer_timer, p);
}

void co_hb_producer_set_time(co_hb_producer_t *p, uint16_t time_ms)
{
    p->time_ms = time_ms;
    co_timer_cancel(co_line_timers(p->line), &p->timer);
    if (time_ms > 0) {
        co_timer_start(co_line_timers(p->line), &p->timer,
                       co_line_now(p->line) + (uint64_t)time_ms * 1000u);
    }
}

void co_hb_producer_stop(co_hb_producer_t *p)
{
    co_timer_cancel(co_line_timers(p->line), &p->timer);
}

/* ---------------------------------------------------------------- consumer */

static void emit(co_hb_consumer_t *c, uint8_t node_id, co_hb_event_t event,
                 co_nmt_state_t state)
{
    if (c->on_event) {
        c->on_event(c, node_id, event, state, c->user);
    }
}

static co_hb_entry_t *entry_of(co_hb_consumer_t *c, uint8_t node_id)
{
    for (uint8_t i = 0; i < c->capacity; i++) {
        if (c->entries[i].node_id == node_id) {
            return &c->entries[i];
        }
    }
    return NULL;
}

static void on_consumer_timeout(co_timer_t *timer, uint64_t now_us, void *user)
{
    (void)timer;
    (void)now_us;
    co_hb_entry_t *e = user;
    e->monitor = CO_HB_MONITOR_LOST;
    emit(e->owner, e->node_id, CO_HB_LOST, (co_nmt_state_t)e->owner->last_state[e->node_id]);
}

static void monitor_heartbeat(co_hb_consumer_t *c, co_hb_entry_t *e, co_nmt_state_t state)
{
    if (e->monitor != CO_HB_MONITOR_ACTIVE) {
        e->monitor = CO_HB_MONITOR_ACTIVE;
        emit(c, e->node_id, CO_HB_STARTED, state);
    }
    if (e->time_ms > 0) {
        co_timer_start(co_line_timers(c->line), &e->timer,
                       co_line_now(c->line) + (uint64_t)e->time_ms * 1000u);
    }
}

static co_hb_tick_t *tick_of(co_hb_consumer_t *c, uint8_t node_id)
{
    for (size_t i = 0; i < CO_HB_TICKS; i++) {
        if (c->ticks[i].node_id == node_id) {
            return &c->ticks[i];
        }
    }
    return NULL;
}

/* A heartbeat of a ticking node: told unless its interval has not passed. */
static void tick(co_hb_consumer_t *c, uint8_t node_id, co_nmt_state_t state)
{
    co_hb_tick_t *t = tick_of(c, node_id);
    uint64_t now = co_line_now(c->line);
    if (t && now >= t->next_us) {
        t->next_us = now + (uint64_t)t->interval_ms * 1000u;
        emit(c, node_id, CO_HB_TICK, state);
    }
}

static void on_heartbeat_frame(co_line_t *line, const co_frame_t *frame, void *user)
{
    co_hb_consumer_t *c = user;
    if (c->filter && c->filter(line, frame, c->filter_user)) {
        return;
    }
    uint8_t node_id = (uint8_t)(frame->id - CO_NMT_EC_COB_ID_BASE);
    if (node_id == 0) {
        co_line_count_rejected(line, CO_LINE_HB_BAD_NODE);
        return;
    }
    if (frame->len != 1) {
        co_line_count_rejected(line, CO_LINE_HB_BAD_LENGTH);
        return;
    }
    if (!co_hb_state_is_valid(frame->data[0])) {
        co_line_count_rejected(line, CO_LINE_HB_BAD_STATE);
        return;
    }
    co_nmt_state_t state = (co_nmt_state_t)frame->data[0];
    uint8_t previous = c->last_state[node_id];
    c->last_state[node_id] = (uint8_t)state;
    co_hb_entry_t *e = entry_of(c, node_id);

    if (state == CO_NMT_INITIALISING) {
        /* Boot-up: the node starts over; monitoring resumes with its first
         * real heartbeat (its producer may not be configured yet). */
        emit(c, node_id, CO_HB_BOOTUP, state);
        if (e) {
            co_timer_cancel(co_line_timers(line), &e->timer);
            e->monitor = CO_HB_MONITOR_OFF;
        }
        return;
    }
    if (previous != (uint8_t)state) {
        emit(c, node_id, CO_HB_STATE_CHANGED, state);
    }
    if (e) {
        monitor_heartbeat(c, e, state);
    }
    tick(c, node_id, state);
}

bool co_hb_consumer_init(co_hb_consumer_t *c, co_line_t *line, co_hb_entry_t *entries,
                         uint8_t capacity, co_hb_event_fn on_event, void *user)
{
    c->line = line;
    c->entries = entries;
    c->capacity = capacity;
    c->on_event = on_event;
    c->user = user;
    c->filter = NULL;
    c->filter_user = NULL;
    memset(c->last_state, CO_NMT_UNKNOWN, sizeof c->last_state);
    memset(c->ticks, 0, sizeof c->ticks);
    for (uint8_t i = 0; i < capacity; i++) {
        entries[i] = (co_hb_entry_t){.owner = c};
        co_timer_init(&entries[i].timer, on_consumer_timeout, &entries[i]);
    }
    return co_line_subscribe(line, CO_NMT_EC_COB_ID_BASE, CO_NMT_EC_COB_ID_BASE + 127,
                             on_heartbeat_frame, c);
}

void co_hb_consumer_deinit(co_hb_consumer_t *c)
{
    for (uint8_t i = 0; i < c->capacity; i++) {
        co_timer_cancel(co_line_timers(c->line), &c->entries[i].timer);
    }
    co_line_unsubscribe(c->line, on_heartbeat_frame, c);
}

void co_hb_consumer_set_filter(co_hb_consumer_t *c, co_rx_other_fn fn, void *user)
{
    c->filter = fn;
    c->filter_user = user;
}

co_hb_config_result_t co_hb_consumer_set_entry(co_hb_consumer_t *c, uint8_t index,
                                               uint32_t value)
{
    if (index >= c->capacity) {
        return CO_HB_CONFIG_NO_ROOM;
    }
    uint32_t node_field = (value >> 16) & 0xFFu;
    /* CiA 301: node-id 0 or > 127 leaves the entry unused. */
    uint8_t node_id = (node_field >= 1 && node_field <= 127) ? (uint8_t)node_field : 0;
    co_hb_entry_t *e = &c->entries[index];
    if (node_id != 0) {
        co_hb_entry_t *other = entry_of(c, node_id);
        if (other && other != e) {
            if (other->time_ms != 0) {
                return CO_HB_CONFIG_DUPLICATE;
            }
            /* An entry with time 0 only watches states: it gives way. */
            co_timer_cancel(co_line_timers(c->line), &other->timer);
            *other = (co_hb_entry_t){.owner = c, .timer = other->timer};
        }
    }
    uint16_t time_ms = node_id ? (uint16_t)(value & 0xFFFFu) : 0;
    co_timer_cancel(co_line_timers(c->line), &e->timer);
    if (node_id != 0 && node_id == e->node_id && e->monitor == CO_HB_MONITOR_ACTIVE) {
        /* Same node, new time: monitoring goes on, the new time counts from
         * now (a heartbeat may never come again, so do not wait for one). */
        e->time_ms = time_ms;
        if (time_ms > 0) {
            co_timer_start(co_line_timers(c->line), &e->timer,
                           co_line_now(c->line) + (uint64_t)time_ms * 1000u);
        }
        return CO_HB_CONFIG_OK;
    }
    e->node_id = node_id;
    e->time_ms = time_ms;
    e->monitor = CO_HB_MONITOR_OFF;
    return CO_HB_CONFIG_OK;
}

co_hb_config_result_t co_hb_consumer_watch(co_hb_consumer_t *c, uint8_t node_id,
                                           uint16_t time_ms)
{
    if (node_id < 1 || node_id > 127) {
        return CO_HB_CONFIG_BAD_NODE;
    }
    co_hb_entry_t *e = entry_of(c, node_id);
    if (e && time_ms == 0) {
        return CO_HB_CONFIG_OK;   /* already watched: keep its consumer time */
    }
    /* A new watch takes the last free entry: the first ones mirror 0x1016
     * sub-indices when the node serves an object dictionary. */
    for (uint8_t i = c->capacity; !e && i > 0; i--) {
        if (c->entries[i - 1].node_id == 0) {
            e = &c->entries[i - 1];
        }
    }
    if (!e) {
        return CO_HB_CONFIG_NO_ROOM;
    }
    return co_hb_consumer_set_entry(c, (uint8_t)(e - c->entries),
                                    ((uint32_t)node_id << 16) | time_ms);
}

bool co_hb_consumer_expect(co_hb_consumer_t *c, uint8_t node_id)
{
    co_hb_entry_t *e = node_id ? entry_of(c, node_id) : NULL;
    if (!e || e->time_ms == 0) {
        return false;
    }
    e->monitor = CO_HB_MONITOR_ACTIVE;
    co_timer_start(co_line_timers(c->line), &e->timer,
                   co_line_now(c->line) + (uint64_t)e->time_ms * 1000u);
    return true;
}

co_hb_config_result_t co_hb_consumer_tick(co_hb_consumer_t *c, uint8_t node_id,
                                          uint16_t interval_ms)
{
    if (node_id < 1 || node_id > 127) {
        return CO_HB_CONFIG_BAD_NODE;
    }
    co_hb_tick_t *t = tick_of(c, node_id);
    if (!t) {
        t = tick_of(c, 0);
        if (!t) {
            return CO_HB_CONFIG_NO_ROOM;
        }
        *t = (co_hb_tick_t){.node_id = node_id};
    }
    t->interval_ms = interval_ms;
    t->next_us = 0;   /* the next heartbeat is told */
    return CO_HB_CONFIG_OK;
}

void co_hb_consumer_untick(co_hb_consumer_t *c, uint8_t node_id)
{
    co_hb_tick_t *t = node_id ? tick_of(c, node_id) : NULL;
    if (t) {
        *t = (co_hb_tick_t){0};
    }
}

void co_hb_consumer_unwatch(co_hb_consumer_t *c, uint8_t node_id)
{
    co_hb_entry_t *e = node_id ? entry_of(c, node_id) : NULL;
    if (e) {
        co_hb_consumer_set_entry(c, (uint8_t)(e - c->entries), 0);
    }
}

uint32_t co_hb_consumer_get_entry(const co_hb_consumer_t *c, uint8_t index)
{
    if (index >= c->capacity || c->entries[index].node_id == 0) {
        return 0;
    }
    const co_hb_entry_t *e = &c->entries[index];
    return ((uint32_t)e->node_id << 16) | e->time_ms;
}

co_hb_monitor_t co_hb_consumer_monitor(const co_hb_consumer_t *c, uint8_t node_id)
{
    for (uint8_t i = 0; i < c->capacity; i++) {
        if (c->entries[i].node_id == node_id && node_id != 0) {
            return c->entries[i].monitor;
        }
    }
    return CO_HB_MONITOR_OFF;
}
