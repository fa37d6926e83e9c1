/* Node guarding and life guarding (see co_guard.h). */
#include "canopenfd/co_guard.h"

#include <string.h>

enum {
    OD_GUARD_TIME = 0x100C,
    OD_LIFE_TIME_FACTOR = 0x100D,
    OD_PRODUCER_HEARTBEAT = 0x1017
};

static bool is_guard_state(uint8_t state)
{
    return state == CO_NMT_STOPPED || state == CO_NMT_OPERATIONAL ||
           state == CO_NMT_PRE_OPERATIONAL;
}

/* ================================================================== slave */

static uint64_t life_time_us(const co_guard_slave_t *s)
{
    return (uint64_t)s->guard_time_ms * s->life_time_factor * 1000u;
}

static void tell_life(co_guard_slave_t *s, co_guard_life_event_t event)
{
    if (s->on_life) {
        s->on_life(s, event, s->user);
    }
}

/* The life guarding condition ends (whatever the reason). */
static void resolve(co_guard_slave_t *s)
{
    if (s->lost) {
        s->lost = false;
        tell_life(s, CO_GUARD_LIFE_RESOLVED);
    }
}

static void on_life_timer(co_timer_t *timer, uint64_t now_us, void *user)
{
    (void)timer;
    (void)now_us;
    co_guard_slave_t *s = user;
    s->lost = true;
    s->stats.life_lost++;
    tell_life(s, CO_GUARD_LIFE_LOST);
}

/* Life guarding runs from now on (after a remote frame or new times). */
static void restart_life(co_guard_slave_t *s)
{
    co_timer_cancel(co_line_timers(s->line), &s->life_timer);
    uint64_t life = life_time_us(s);
    if (s->guarded && life > 0) {
        co_timer_start(co_line_timers(s->line), &s->life_timer, co_line_now(s->line) + life);
    } else {
        resolve(s);   /* nothing watched any more */
    }
}

/* Guarding stops until the next first remote frame; the toggle starts at 0
 * when it becomes active again. */
static void stop_guarding(co_guard_slave_t *s)
{
    co_timer_cancel(co_line_timers(s->line), &s->life_timer);
    s->guarded = false;
    s->toggle = false;
    resolve(s);
}

static bool on_remote_frame(co_line_t *line, const co_frame_t *frame, void *user)
{
    co_guard_slave_t *s = user;
    const uint32_t id = CO_NMT_EC_COB_ID_BASE + s->nmt->node_id;
    if (!(frame->flags & CO_FRAME_RTR) || (frame->flags & CO_FRAME_EXT) || frame->id != id) {
        return false;
    }
    if (s->heartbeat_ms != 0) {
        s->stats.ignored_heartbeat++;
        return false;   /* unanswered: the line counts it in rx_rtr */
    }
    const uint8_t state = (uint8_t)s->nmt->state;
    if (!is_guard_state(state)) {
        s->stats.ignored_state++;
        return false;
    }
    /* The remote frame came: life guarding (re)starts whatever the answer. */
    s->guarded = true;
    resolve(s);
    restart_life(s);
    const uint8_t answer = (uint8_t)(state | (s->toggle ? CO_GUARD_TOGGLE_BIT : 0));
    if (!co_line_send(line, id, &answer, 1)) {
        s->stats.tx_failed++;   /* not on the bus: the toggle stays for the next */
        return true;
    }
    s->toggle = !s->toggle;
    s->stats.answered++;
    return true;
}

bool co_guard_slave_init(co_guard_slave_t *slave, co_line_t *line, co_nmt_t *nmt,
                         co_guard_life_fn on_life, void *user)
{
    memset(slave, 0, sizeof *slave);
    slave->line = line;
    slave->nmt = nmt;
    slave->on_life = on_life;
    slave->user = user;
    co_timer_init(&slave->life_timer, on_life_timer, slave);
    if (co_line_mode(line) != CO_MODE_CLASSIC) {
        return false;
    }
    return co_line_subscribe_other(line, on_remote_frame, slave);
}

void co_guard_slave_deinit(co_guard_slave_t *slave)
{
    co_guard_slave_detach_od(slave);
    co_timer_cancel(co_line_timers(slave->line), &slave->life_timer);
    co_line_unsubscribe_other(slave->line, on_remote_frame, slave);
}

void co_guard_slave_set_times(co_guard_slave_t *slave, uint16_t guard_time_ms,
                              uint8_t life_time_factor)
{
    if (guard_time_ms == slave->guard_time_ms && life_time_factor == slave->life_time_factor) {
        return;   /* a reload of the same values changes nothing */
    }
    slave->guard_time_ms = guard_time_ms;
    slave->life_time_factor = life_time_factor;
    if (slave->guarded && !slave->lost) {
        restart_life(slave);
    } else if (life_time_us(slave) == 0) {
        resolve(slave);
    }
}

void co_guard_slave_set_heartbeat(co_guard_slave_t *slave, uint16_t heartbeat_ms)
{
    bool was_on = slave->heartbeat_ms != 0;
    slave->heartbeat_ms = heartbeat_ms;
    if (heartbeat_ms != 0 && !was_on) {
        stop_guarding(slave);
    }
}

void co_guard_slave_reset_communication(co_guard_slave_t *slave)
{
    stop_guarding(slave);
}

/* ---- OD */

static void read_od(co_guard_slave_t *s, co_od_t *od)
{
    uint16_t guard = 0, heartbeat;
    uint8_t factor = 0;
    co_od_get_u16(od, OD_GUARD_TIME, 0, &guard);
    co_od_get_u8(od, OD_LIFE_TIME_FACTOR, 0, &factor);
    co_guard_slave_set_times(s, guard, factor);
    if (co_od_get_u16(od, OD_PRODUCER_HEARTBEAT, 0, &heartbeat)) {
        co_guard_slave_set_heartbeat(s, heartbeat);
    }
}

static void after_write(co_od_t *od, const co_od_entry_t *e, co_od_origin_t origin, void *user)
{
    (void)e;
    (void)origin;
    read_od(user, od);
}

static const co_od_handler_t slave_handler = {.after_write = after_write};

bool co_guard_slave_attach_od(co_guard_slave_t *slave, co_od_t *od)
{
    if (!co_od_subscribe(od, OD_GUARD_TIME, 0, OD_LIFE_TIME_FACTOR, 0, &slave_handler, slave) ||
        !co_od_subscribe(od, OD_PRODUCER_HEARTBEAT, 0, OD_PRODUCER_HEARTBEAT, 0, &slave_handler,
                         slave)) {
        co_od_unsubscribe(od, &slave_handler, slave);
        return false;
    }
    slave->od = od;
    read_od(slave, od);
    return true;
}

void co_guard_slave_detach_od(co_guard_slave_t *slave)
{
    if (slave->od) {
        co_od_unsubscribe(slave->od, &slave_handler, slave);
        slave->od = NULL;
    }
}

/* ================================================================= master */

static void emit(co_guard_master_t *m, const co_guard_node_t *n, co_guard_event_t event,
                 uint8_t state)
{
    if (m->on_event) {
        m->on_event(m, n->node_id, event, (co_nmt_state_t)state, m->user);
    }
}

static co_guard_node_t *node_of(const co_guard_master_t *m, uint8_t node_id)
{
    for (uint8_t i = 0; node_id != 0 && i < m->capacity; i++) {
        if (m->nodes[i].node_id == node_id) {
            return &m->nodes[i];
        }
    }
    return NULL;
}

static void send_request(co_guard_master_t *m, co_guard_node_t *n)
{
    co_frame_t rtr;
    memset(&rtr, 0, sizeof rtr);
    rtr.id = CO_NMT_EC_COB_ID_BASE + n->node_id;
    rtr.flags = CO_FRAME_RTR;
    rtr.len = 1;   /* the length of the answer asked for */
    if (!co_line_send_frame(m->line, &rtr)) {
        /* Not on the bus: the node cannot answer it, so it is not waited for. */
        m->stats.tx_failed++;
        return;
    }
    m->stats.rtr_sent++;
    n->waiting = true;
}

static void on_guard_timer(co_timer_t *timer, uint64_t now_us, void *user)
{
    co_guard_node_t *n = user;
    co_guard_master_t *m = n->owner;
    if (n->waiting) {
        m->stats.missed++;
        if (n->missed < UINT8_MAX) {
            n->missed++;
        }
        uint8_t limit = n->life_time_factor ? n->life_time_factor : 1;
        if (n->missed >= limit && n->monitor != CO_GUARD_MONITOR_LOST) {
            n->monitor = CO_GUARD_MONITOR_LOST;
            emit(m, n, CO_GUARD_LOST, n->state);
            if (n->node_id == 0) {
                return;   /* the handler stopped guarding it */
            }
        }
    }
    send_request(m, n);
    if (!co_timer_is_armed(timer)) {
        uint64_t period = (uint64_t)n->guard_time_ms * 1000u;
        uint64_t next = timer->deadline_us + period;
        co_timer_start(co_line_timers(m->line), timer, next > now_us ? next : now_us + period);
    }
}

bool co_guard_master_init(co_guard_master_t *master, co_line_t *line, co_guard_node_t *nodes,
                          uint8_t capacity, co_guard_event_fn on_event, void *user)
{
    memset(master, 0, sizeof *master);
    master->line = line;
    master->nodes = nodes;
    master->capacity = capacity;
    master->on_event = on_event;
    master->user = user;
    for (uint8_t i = 0; i < capacity; i++) {
        nodes[i] = (co_guard_node_t){.owner = master, .state = CO_NMT_UNKNOWN,
                                     .expected_state = CO_NMT_UNKNOWN};
        co_timer_init(&nodes[i].timer, on_guard_timer, &nodes[i]);
    }
    return co_line_mode(line) == CO_MODE_CLASSIC;
}

void co_guard_master_deinit(co_guard_master_t *master)
{
    for (uint8_t i = 0; i < master->capacity; i++) {
        co_timer_cancel(co_line_timers(master->line), &master->nodes[i].timer);
        master->nodes[i].node_id = 0;
    }
}

co_guard_result_t co_guard_master_guard(co_guard_master_t *master, uint8_t node_id,
                                        uint16_t guard_time_ms, uint8_t life_time_factor)
{
    if (node_id < 1 || node_id > 127) {
        return CO_GUARD_BAD_NODE;
    }
    if (guard_time_ms == 0) {
        return CO_GUARD_BAD_TIME;
    }
    if (co_line_mode(master->line) != CO_MODE_CLASSIC) {
        return CO_GUARD_NO_ROOM;   /* no table on an fd line: nothing can be guarded */
    }
    co_guard_node_t *n = node_of(master, node_id);
    uint64_t first = co_line_now(master->line);
    if (n) {
        first += (uint64_t)guard_time_ms * 1000u;   /* new times: next request one period on */
    } else {
        for (uint8_t i = 0; !n && i < master->capacity; i++) {
            if (master->nodes[i].node_id == 0) {
                n = &master->nodes[i];
            }
        }
        if (!n) {
            return CO_GUARD_NO_ROOM;
        }
        *n = (co_guard_node_t){.owner = master, .node_id = node_id, .state = CO_NMT_UNKNOWN,
                               .expected_state = CO_NMT_UNKNOWN, .timer = n->timer};
    }
    n->guard_time_ms = guard_time_ms;
    n->life_time_factor = life_time_factor;
    co_timer_start(co_line_timers(master->line), &n->timer, first);
    return CO_GUARD_OK;
}

void co_guard_master_unguard(co_guard_master_t *master, uint8_t node_id)
{
    co_guard_node_t *n = node_of(master, node_id);
    if (n) {
        co_timer_cancel(co_line_timers(master->line), &n->timer);
        *n = (co_guard_node_t){.owner = master, .state = CO_NMT_UNKNOWN,
                               .expected_state = CO_NMT_UNKNOWN, .timer = n->timer};
    }
}

void co_guard_master_expect_state(co_guard_master_t *master, uint8_t node_id,
                                  co_nmt_state_t state)
{
    co_guard_node_t *n = node_of(master, node_id);
    if (n) {
        n->expected_state = (uint8_t)state;
        n->mismatch = false;   /* judged afresh at the next answer */
    }
}

co_guard_monitor_t co_guard_master_monitor(const co_guard_master_t *master, uint8_t node_id)
{
    const co_guard_node_t *n = node_of(master, node_id);
    return n ? n->monitor : CO_GUARD_MONITOR_OFF;
}

bool co_guard_master_guards(const co_guard_master_t *master, uint8_t node_id)
{
    return master && node_of(master, node_id) != NULL;
}

co_nmt_state_t co_guard_master_state(const co_guard_master_t *master, uint8_t node_id)
{
    const co_guard_node_t *n = node_of(master, node_id);
    return n ? (co_nmt_state_t)n->state : CO_NMT_UNKNOWN;
}

bool co_guard_master_receive(co_line_t *line, const co_frame_t *frame, void *user)
{
    (void)line;
    co_guard_master_t *m = user;
    if ((frame->flags & (CO_FRAME_RTR | CO_FRAME_EXT)) || frame->id <= CO_NMT_EC_COB_ID_BASE ||
        frame->id > CO_NMT_EC_COB_ID_BASE + 127) {
        return false;
    }
    co_guard_node_t *n = node_of(m, (uint8_t)(frame->id - CO_NMT_EC_COB_ID_BASE));
    if (!n) {
        return false;
    }
    if (frame->len == 1 && frame->data[0] == CO_NMT_INITIALISING) {
        n->expected_toggle = 0;   /* reset communication: its toggle starts at 0 */
        n->toggle_known = true;
        return false;             /* the boot-up is the heartbeat consumer's to report */
    }
    if (frame->len != 1) {
        m->stats.bad_length++;
        return true;
    }
    const uint8_t state = frame->data[0] & 0x7Fu;
    const uint8_t toggle = frame->data[0] & CO_GUARD_TOGGLE_BIT;
    if (!is_guard_state(state)) {
        m->stats.bad_state++;
        return true;
    }
    if (!n->toggle_known) {
        /* A node guarded before (by us or another master) goes on toggling
         * from where it was: its first answer tells where that is. */
        n->expected_toggle = toggle;
        n->toggle_known = true;
    }
    if (toggle != n->expected_toggle) {
        /* Not taken as an answer (it counts as missed, as in CANopenNode);
         * the next answer of a node that toggles again matches once more. */
        m->stats.toggle_errors++;
        emit(m, n, CO_GUARD_TOGGLE_ERROR, state);
        return true;
    }
    m->stats.answers++;
    n->expected_toggle ^= CO_GUARD_TOGGLE_BIT;
    n->waiting = false;
    n->missed = 0;
    const uint8_t previous = n->state;
    n->state = state;
    if (previous != state) {
        emit(m, n, CO_GUARD_STATE_CHANGED, state);
    }
    if (n->node_id == 0) {
        return true;   /* a handler stopped guarding it */
    }
    if (n->monitor != CO_GUARD_MONITOR_ACTIVE) {
        co_guard_event_t event =
            n->monitor == CO_GUARD_MONITOR_LOST ? CO_GUARD_RESUMED : CO_GUARD_STARTED;
        n->monitor = CO_GUARD_MONITOR_ACTIVE;
        emit(m, n, event, state);
    }
    if (n->node_id != 0 && n->expected_state != CO_NMT_UNKNOWN && state != n->expected_state) {
        if (!n->mismatch) {
            n->mismatch = true;
            emit(m, n, CO_GUARD_UNEXPECTED_STATE, state);
        }
    } else {
        n->mismatch = false;
    }
    return true;
}
