/* SYNC producer and consumer (see co_sync.h). */
#include "canopenfd/co_sync.h"

#include "co_cob_id.h"

#include <string.h>

enum {
    OD_COB_ID = 0x1005,
    OD_PERIOD = 0x1006,
    OD_WINDOW = 0x1007,
    OD_OVERFLOW = 0x1019
};

#define CAN_ID_MASK 0x7FFu
/* Bits 11..29: the rest of a 29-bit id and the frame bit (29-bit ids are
 * not supported by the line's subscriptions). Bit 31 is "do not care". */
#define EXTENDED_BITS 0x3FFFF800u

/* 0x1019 as used: 1 counts as 2, above 240 as 240 (stored values that a
 * network write would have refused). */
static uint8_t usable_overflow(uint8_t overflow)
{
    if (overflow == 1) {
        return 2;
    }
    return overflow > CO_SYNC_COUNTER_MAX ? CO_SYNC_COUNTER_MAX : overflow;
}

static bool producing(const co_sync_t *s)
{
    return s->nmt_active && co_sync_is_producer(s) && s->config.period_us > 0;
}

/* ---------------------------------------------------------------- a SYNC */

static void on_window_timer(co_timer_t *timer, uint64_t now_us, void *user)
{
    (void)timer;
    (void)now_us;
    co_sync_t *s = user;
    s->window_open = false;
    if (s->on_window_closed) {
        s->on_window_closed(s, s->window_user);
    }
}

/* A SYNC happened (sent or received): open its window, tell the listeners. */
static void sync_event(co_sync_t *s, uint8_t counter)
{
    s->last_sync_us = co_line_now(s->line);
    s->last_counter = counter;
    if (s->config.window_us > 0) {
        s->window_open = true;
        co_timer_start(co_line_timers(s->line), &s->window_timer,
                       co_line_now(s->line) + s->config.window_us);
    }
    /* Every listener registered at the SYNC is told, even when an earlier
     * one changes the list. */
    co_sync_listener_t listeners[CO_SYNC_MAX_LISTENERS];
    uint8_t count = s->listener_count;
    memcpy(listeners, s->listeners, sizeof listeners[0] * count);
    for (uint8_t i = 0; i < count; i++) {
        listeners[i].fn(counter, listeners[i].user);
    }
}

/* ------------------------------------------------------------- producer */

static void produce(co_sync_t *s)
{
    const uint8_t counter = s->config.overflow ? s->next_counter : 0;
    if (!co_line_send(s->line, s->config.cob_id & CAN_ID_MASK, &counter,
                      s->config.overflow ? 1u : 0u)) {
        s->stats.tx_failed++;   /* not on the bus: no counter step, nobody told */
        return;
    }
    s->stats.produced++;
    if (s->config.overflow) {
        s->next_counter = s->next_counter >= s->config.overflow ? 1 : (uint8_t)(s->next_counter + 1);
    }
    sync_event(s, counter);
}

static void on_producer_timer(co_timer_t *timer, uint64_t now_us, void *user)
{
    co_sync_t *s = user;
    produce(s);
    /* Next one a period after the deadline, so a late wake-up does not shift
     * the cycle; after a long stall restart from now. A listener may have
     * stopped production (reconfigured the service) meanwhile. */
    if (producing(s) && !co_timer_is_armed(timer)) {
        uint64_t next = timer->deadline_us + s->config.period_us;
        co_timer_start(co_line_timers(s->line), timer,
                       next > now_us ? next : now_us + s->config.period_us);
    }
}

/* (Re)start production from now: counter 1, first SYNC one period later. */
static void restart_producer(co_sync_t *s)
{
    co_timer_cancel(co_line_timers(s->line), &s->producer_timer);
    s->next_counter = 1;
    if (producing(s)) {
        co_timer_start(co_line_timers(s->line), &s->producer_timer,
                       co_line_now(s->line) + s->config.period_us);
    }
}

/* ------------------------------------------------------------- consumer */

static void on_timeout_timer(co_timer_t *timer, uint64_t now_us, void *user)
{
    (void)timer;
    (void)now_us;
    co_sync_t *s = user;
    s->timed_out = true;
    if (s->on_timeout) {
        s->on_timeout(s, true, s->timeout_user);
    }
}

static bool monitoring(const co_sync_t *s)
{
    return s->on_timeout && s->nmt_active && !co_sync_is_producer(s) &&
           s->config.period_us > 0;
}

/* Monitoring ends (or restarts at the next SYNC): a timeout told is over. */
static void stop_monitoring(co_sync_t *s)
{
    co_timer_cancel(co_line_timers(s->line), &s->timeout_timer);
    if (s->timed_out) {
        s->timed_out = false;
        if (s->on_timeout) {
            s->on_timeout(s, false, s->timeout_user);
        }
    }
}

/* A SYNC was received: the next is due within 1.5 periods. */
static void sync_received(co_sync_t *s)
{
    if (!monitoring(s)) {
        return;
    }
    stop_monitoring(s);
    uint64_t limit = (uint64_t)s->config.period_us + s->config.period_us / 2u;
    co_timer_start(co_line_timers(s->line), &s->timeout_timer, co_line_now(s->line) + limit);
}

void co_sync_set_timeout_indication(co_sync_t *sync, co_sync_timeout_fn fn, void *user)
{
    stop_monitoring(sync);
    sync->on_timeout = fn;
    sync->timeout_user = user;
}

static void on_sync_frame(co_line_t *line, const co_frame_t *frame, void *user)
{
    (void)line;
    co_sync_t *s = user;
    if (!s->nmt_active) {
        s->stats.ignored_state++;
        return;
    }
    uint8_t expected = s->config.overflow ? 1 : 0;
    if (s->any_counter && frame->len <= 1) {
        expected = frame->len;   /* a tool's line: with or without counter */
    }
    if (frame->len != expected) {
        s->stats.bad_length++;
        if (s->on_error) {
            s->on_error(s, CO_SYNC_EMCY_LENGTH, frame->len, s->error_user);
        }
        return;
    }
    s->stats.received++;
    sync_received(s);
    sync_event(s, expected ? frame->data[0] : 0);
}

void co_sync_accept_any_counter(co_sync_t *sync, bool accept)
{
    sync->any_counter = accept;
}

/* The consumer listens on the COB-ID's CAN-ID unless this node produces
 * (a second producer on the same id is a configuration error; our own
 * SYNCs are told to the listeners by the producer). */
static void update_subscription(co_sync_t *s)
{
    bool want = !co_sync_is_producer(s);
    uint32_t id = s->config.cob_id & CAN_ID_MASK;
    if (s->subscribed && (!want || id != s->rx_id)) {
        co_line_unsubscribe(s->line, on_sync_frame, s);
        s->subscribed = false;
    }
    if (want && !s->subscribed) {
        if (co_line_subscribe(s->line, id, id, on_sync_frame, s)) {
            s->subscribed = true;
            s->rx_id = id;
        } else {
            s->stats.subscribe_failed++;
        }
    }
}

/* ----------------------------------------------------------- configuration */

static void apply(co_sync_t *s, const co_sync_config_t *config)
{
    co_sync_config_t c = *config;
    c.overflow = usable_overflow(c.overflow);
    bool restart = c.cob_id != s->config.cob_id || c.period_us != s->config.period_us ||
                   c.overflow != s->config.overflow;
    bool new_window = c.window_us != s->config.window_us;
    s->config = c;
    update_subscription(s);
    if (restart) {
        stop_monitoring(s);   /* starts again at the next SYNC received */
        restart_producer(s);
    }
    if (new_window && s->window_open) {
        /* The open window takes the new length at once. */
        if (c.window_us == 0) {
            co_timer_cancel(co_line_timers(s->line), &s->window_timer);
            s->window_open = false;
        } else {
            uint64_t end = s->last_sync_us + c.window_us;
            co_timer_start(co_line_timers(s->line), &s->window_timer,
                           end > co_line_now(s->line) ? end : co_line_now(s->line));
        }
    }
}

bool co_sync_init(co_sync_t *sync, co_line_t *line)
{
    memset(sync, 0, sizeof *sync);
    sync->line = line;
    sync->next_counter = 1;
    co_timer_init(&sync->producer_timer, on_producer_timer, sync);
    co_timer_init(&sync->window_timer, on_window_timer, sync);
    co_timer_init(&sync->timeout_timer, on_timeout_timer, sync);
    sync->config.cob_id = CO_SYNC_DEFAULT_COB_ID;
    update_subscription(sync);
    return sync->subscribed;
}

void co_sync_deinit(co_sync_t *sync)
{
    co_sync_detach_od(sync);
    co_timer_cancel(co_line_timers(sync->line), &sync->producer_timer);
    co_timer_cancel(co_line_timers(sync->line), &sync->window_timer);
    co_timer_cancel(co_line_timers(sync->line), &sync->timeout_timer);
    sync->timed_out = false;
    sync->on_timeout = NULL;
    if (sync->subscribed) {
        co_line_unsubscribe(sync->line, on_sync_frame, sync);
        sync->subscribed = false;
    }
    sync->window_open = false;
}

uint32_t co_sync_check(const co_sync_t *sync, uint16_t index, uint32_t value)
{
    switch (index) {
    case OD_COB_ID:
        if ((value & EXTENDED_BITS) != 0 || co_cob_id_restricted(value & CAN_ID_MASK)) {
            return CO_ABORT_INVALID_VALUE;
        }
        return 0;
    case OD_OVERFLOW:
        if (value == 1 || value > CO_SYNC_COUNTER_MAX) {
            return CO_ABORT_INVALID_VALUE;
        }
        /* CiA 301: 0x1019 may change only while 0x1006 is 0. */
        if (value != sync->config.overflow && sync->config.period_us != 0) {
            return CO_ABORT_DATA_STATE;
        }
        return 0;
    default:
        return 0;
    }
}

void co_sync_configure(co_sync_t *sync, const co_sync_config_t *config)
{
    apply(sync, config);
}

void co_sync_set_nmt_state(co_sync_t *sync, co_nmt_state_t state)
{
    bool active = state == CO_NMT_PRE_OPERATIONAL || state == CO_NMT_OPERATIONAL;
    if (active == sync->nmt_active) {
        return;
    }
    sync->nmt_active = active;
    if (!active) {
        co_timer_cancel(co_line_timers(sync->line), &sync->window_timer);
        sync->window_open = false;
        stop_monitoring(sync);
    }
    /* CiA: the counter is reset to 1 when the device leaves stopped. */
    restart_producer(sync);
}

bool co_sync_add_listener(co_sync_t *sync, co_sync_fn fn, void *user)
{
    if (fn == NULL || sync->listener_count >= CO_SYNC_MAX_LISTENERS) {
        return false;
    }
    for (uint8_t i = 0; i < sync->listener_count; i++) {
        if (sync->listeners[i].fn == fn && sync->listeners[i].user == user) {
            return false;
        }
    }
    sync->listeners[sync->listener_count++] = (co_sync_listener_t){fn, user};
    return true;
}

void co_sync_remove_listener(co_sync_t *sync, co_sync_fn fn, void *user)
{
    uint8_t kept = 0;
    for (uint8_t i = 0; i < sync->listener_count; i++) {
        if (sync->listeners[i].fn != fn || sync->listeners[i].user != user) {
            sync->listeners[kept++] = sync->listeners[i];
        }
    }
    sync->listener_count = kept;
}

void co_sync_set_window_indication(co_sync_t *sync, co_sync_window_fn fn, void *user)
{
    sync->on_window_closed = fn;
    sync->window_user = user;
}

void co_sync_set_error_indication(co_sync_t *sync, co_sync_error_fn fn, void *user)
{
    sync->on_error = fn;
    sync->error_user = user;
}

bool co_sync_window_check(co_sync_t *sync)
{
    if (sync->config.window_us == 0 || sync->window_open) {
        return true;
    }
    sync->stats.outside_window++;
    return false;
}

/* ------------------------------------------------------------------ OD */

static uint32_t get_le(const uint8_t *p, uint32_t n)
{
    uint32_t v = 0;
    for (uint32_t i = 0; i < n && i < 4; i++) {
        v |= (uint32_t)p[i] << (8 * i);
    }
    return v;
}

static void read_od(co_od_t *od, co_sync_config_t *c)
{
    uint8_t overflow = 0;
    *c = (co_sync_config_t){.cob_id = CO_SYNC_DEFAULT_COB_ID};
    co_od_get_u32(od, OD_COB_ID, 0, &c->cob_id);
    co_od_get_u32(od, OD_PERIOD, 0, &c->period_us);
    co_od_get_u32(od, OD_WINDOW, 0, &c->window_us);
    co_od_get_u8(od, OD_OVERFLOW, 0, &overflow);
    c->overflow = overflow;
}

static uint32_t check_write(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e,
                            const uint8_t *value, uint32_t length, void *user)
{
    (void)od;
    (void)xfer;
    if (co_od_entry_sub(e) != 0) {
        return 0;
    }
    return co_sync_check(user, co_od_entry_index(e), get_le(value, length));
}

static void after_write(co_od_t *od, const co_od_entry_t *e, co_od_origin_t origin, void *user)
{
    (void)e;
    (void)origin;
    co_sync_config_t c;
    read_od(od, &c);
    apply(user, &c);
}

static const co_od_handler_t sync_handler = {
    .check_write = check_write,
    .after_write = after_write,
};

bool co_sync_attach_od(co_sync_t *sync, co_od_t *od)
{
    if (co_od_find(od, OD_COB_ID, 0) == NULL) {
        return false;
    }
    if (!co_od_subscribe(od, OD_COB_ID, 0, OD_WINDOW, 0, &sync_handler, sync) ||
        !co_od_subscribe(od, OD_OVERFLOW, 0, OD_OVERFLOW, 0, &sync_handler, sync)) {
        co_od_unsubscribe(od, &sync_handler, sync);
        return false;
    }
    sync->od = od;
    co_sync_config_t c;
    read_od(od, &c);
    apply(sync, &c);
    return true;
}

void co_sync_detach_od(co_sync_t *sync)
{
    if (sync->od) {
        co_od_unsubscribe(sync->od, &sync_handler, sync);
        sync->od = NULL;
    }
}
