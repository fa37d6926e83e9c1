/* Flying master (see co_flyma.h). */
#include "canopenfd/co_flyma.h"

#include <string.h>

enum {
    DEFAULT_DETECT_MS = 100,
    DEFAULT_DELAY_MS = 500,
    DEFAULT_PRIORITY_SLOT_MS = 1500,
    DEFAULT_DEVICE_SLOT_MS = 10,
    DEFAULT_MULTIPLE_MASTER_MS = 4000,
    DEFAULT_CAPABLE_MS = 100
};

static uint16_t or_default(uint16_t value, uint16_t fallback) { return value ? value : fallback; }

static void tell(co_flyma_t *f, co_flyma_event_t event, uint8_t master, uint8_t priority)
{
    if (f->config.ind) {
        f->config.ind(f, event, f->state, master, priority, f->config.user);
    }
}

static void enter(co_flyma_t *f, co_flyma_state_t state)
{
    if (f->state != state) {
        f->state = state;
        tell(f, CO_FLYMA_EV_STATE, f->master, f->master_priority);
    }
}

static void arm(co_flyma_t *f, uint32_t ms)
{
    co_timer_start(co_line_timers(f->line), &f->timer,
                   co_line_now(f->line) + (uint64_t)ms * 1000u);
}

static bool send(co_flyma_t *f, uint32_t id, const uint8_t *data, size_t len)
{
    if (!co_line_send(f->line, id, data, len)) {
        f->stats.send_failed++;
        return false;
    }
    return true;
}

static void announce(co_flyma_t *f)
{
    uint8_t data[2] = {f->config.priority, co_line_node_id(f->line)};
    if (send(f, CO_FLYMA_ID_ACTIVE_MASTER, data, sizeof data)) {
        f->stats.announcements++;
    }
}

/* Wait the own slot; the first candidate whose slot ends announces itself.
 * `send_request`: this node starts the negotiation (else another did). */
static void negotiate(co_flyma_t *f, bool send_request)
{
    if (send_request && !send(f, CO_FLYMA_ID_NEGOTIATE, NULL, 0)) {
        return;
    }
    f->stats.negotiations++;
    f->master = 0;
    f->master_priority = 0;
    arm(f, (uint32_t)f->config.priority * f->config.priority_slot_ms +
               (uint32_t)co_line_node_id(f->line) * f->config.device_slot_ms);
    enter(f, CO_FLYMA_NEGOTIATING);
}

static void become_master(co_flyma_t *f)
{
    f->master = co_line_node_id(f->line);
    f->master_priority = f->config.priority;
    announce(f);
    arm(f, f->config.multiple_master_ms);
    enter(f, CO_FLYMA_MASTER);
}

static void become_slave(co_flyma_t *f, uint8_t node, uint8_t priority)
{
    co_timer_cancel(co_line_timers(f->line), &f->timer);
    bool changed = f->master != node || f->master_priority != priority;
    f->master = node;
    f->master_priority = priority;
    if (f->state == CO_FLYMA_SLAVE && changed) {
        tell(f, CO_FLYMA_EV_STATE, node, priority);   /* a new active master */
    }
    enter(f, CO_FLYMA_SLAVE);
}

/* Ask the active master; the answer (0x71) or the detect timeout decides. */
static void detect(co_flyma_t *f)
{
    enter(f, CO_FLYMA_DETECTING);
    (void)send(f, CO_FLYMA_ID_ASK_ACTIVE, NULL, 0);
    arm(f, f->config.detect_ms);
}

static void on_timer(co_timer_t *timer, uint64_t now_us, void *user)
{
    (void)timer;
    (void)now_us;
    co_flyma_t *f = user;
    switch (f->state) {
    case CO_FLYMA_WAITING:
        detect(f);
        break;
    case CO_FLYMA_DETECTING:
        if (f->power_on) {
            /* the first time no master answers, the whole network starts
             * over together (the reset comes back here as a boot-up) */
            f->power_on = false;
            enter(f, CO_FLYMA_WAITING);
            arm(f, f->config.delay_ms);
            tell(f, CO_FLYMA_EV_RESET_ALL, 0, 0);
        } else {
            negotiate(f, true);
        }
        break;
    case CO_FLYMA_NEGOTIATING:
        become_master(f);
        break;
    case CO_FLYMA_MASTER:   /* a second active master would hear this and renegotiate */
        if (send(f, CO_FLYMA_ID_FORCE, NULL, 0)) {
            f->stats.forced++;
        }
        arm(f, f->config.multiple_master_ms);
        break;
    default:
        break;
    }
}

static void on_capable_timer(co_timer_t *timer, uint64_t now_us, void *user)
{
    (void)timer;
    (void)now_us;
    co_flyma_t *f = user;
    tell(f, CO_FLYMA_EV_CAPABLE_DONE, 0, f->capable_count);
}

/* Another node says it is the active master: the better one stays master. */
static void active_master_heard(co_flyma_t *f, uint8_t priority, uint8_t node)
{
    uint8_t own = co_line_node_id(f->line);
    if (node == own) {
        f->stats.rx_ignored++;   /* a node with our id: not for us to judge */
        return;
    }
    bool other_wins = priority < f->config.priority ||
                      (priority == f->config.priority && node < own);
    if (other_wins) {
        become_slave(f, node, priority);
        return;
    }
    /* a worse active master: force a new negotiation, which we then win */
    if (send(f, CO_FLYMA_ID_FORCE, NULL, 0)) {
        f->stats.forced++;
    }
    negotiate(f, true);
}

static void on_frame(co_line_t *line, const co_frame_t *frame, void *user)
{
    (void)line;
    co_flyma_t *f = user;
    size_t want = frame->id == CO_FLYMA_ID_ACTIVE_MASTER ? 2u : 0u;
    if (frame->len != want) {
        f->stats.rx_bad_length++;
        return;
    }
    if (f->state == CO_FLYMA_IDLE) {
        f->stats.rx_ignored++;
        return;
    }
    switch (frame->id) {
    case CO_FLYMA_ID_ACTIVE_MASTER:
        active_master_heard(f, frame->data[0], frame->data[1]);
        break;
    case CO_FLYMA_ID_NEGOTIATE:
        negotiate(f, false);
        break;
    case CO_FLYMA_ID_ASK_ACTIVE:
        if (f->state == CO_FLYMA_MASTER) {
            announce(f);
        }
        break;
    case CO_FLYMA_ID_CAPABLE:
        f->capable_count++;
        tell(f, CO_FLYMA_EV_CAPABLE, 0, f->capable_count);
        break;
    case CO_FLYMA_ID_ASK_CAPABLE:
        (void)send(f, CO_FLYMA_ID_CAPABLE, NULL, 0);
        break;
    case CO_FLYMA_ID_FORCE:
        /* only an active master gives way to a negotiation it was told of */
        if (f->state == CO_FLYMA_MASTER) {
            negotiate(f, true);
        }
        break;
    default:
        break;
    }
}

/* ------------------------------------------------------------------ API */

bool co_flyma_init(co_flyma_t *flyma, co_line_t *line, const co_flyma_config_t *config)
{
    if (!flyma || !line || !config) {
        return false;
    }
    memset(flyma, 0, sizeof *flyma);
    flyma->line = line;
    flyma->config = *config;
    co_flyma_config_t *c = &flyma->config;
    c->detect_ms = or_default(c->detect_ms, DEFAULT_DETECT_MS);
    c->delay_ms = or_default(c->delay_ms, DEFAULT_DELAY_MS);
    c->priority_slot_ms = or_default(c->priority_slot_ms, DEFAULT_PRIORITY_SLOT_MS);
    c->device_slot_ms = or_default(c->device_slot_ms, DEFAULT_DEVICE_SLOT_MS);
    c->multiple_master_ms = or_default(c->multiple_master_ms, DEFAULT_MULTIPLE_MASTER_MS);
    c->capable_ms = or_default(c->capable_ms, DEFAULT_CAPABLE_MS);
    flyma->power_on = true;
    co_timer_init(&flyma->timer, on_timer, flyma);
    co_timer_init(&flyma->capable_timer, on_capable_timer, flyma);
    if (!co_line_subscribe(line, CO_FLYMA_ID_ACTIVE_MASTER, CO_FLYMA_ID_FORCE, on_frame,
                           flyma)) {
        return false;
    }
    flyma->subscribed = true;
    return true;
}

void co_flyma_deinit(co_flyma_t *flyma)
{
    if (!flyma->subscribed) {
        return;
    }
    co_flyma_stop(flyma);
    co_line_unsubscribe(flyma->line, on_frame, flyma);
    flyma->subscribed = false;
}

void co_flyma_config_from_od(co_flyma_config_t *config, const co_od_t *od)
{
    uint16_t value;
    uint16_t *const fields[6] = {&config->detect_ms, &config->delay_ms, NULL,
                                 &config->priority_slot_ms, &config->device_slot_ms,
                                 &config->multiple_master_ms};
    for (uint8_t sub = 1; sub <= 6; sub++) {
        if (!co_od_get_u16(od, CO_FLYMA_OD_TIMING, sub, &value)) {
            continue;
        }
        if (sub == 3) {
            config->priority = value > 0xFFu ? 0xFFu : (uint8_t)value;
        } else {
            *fields[sub - 1] = value;
        }
    }
    if (co_od_get_u16(od, CO_FLYMA_OD_DETECT, 1, &value)) {
        config->capable_ms = value;
    }
}

void co_flyma_boot(co_flyma_t *flyma)
{
    flyma->master = 0;
    flyma->master_priority = 0;
    enter(flyma, CO_FLYMA_WAITING);
    arm(flyma, flyma->config.delay_ms);
}

void co_flyma_stop(co_flyma_t *flyma)
{
    co_timer_cancel(co_line_timers(flyma->line), &flyma->timer);
    co_timer_cancel(co_line_timers(flyma->line), &flyma->capable_timer);
    flyma->master = 0;
    enter(flyma, CO_FLYMA_IDLE);
}

void co_flyma_node_lost(co_flyma_t *flyma, uint8_t node_id)
{
    if (flyma->state != CO_FLYMA_SLAVE || node_id != flyma->master) {
        return;
    }
    flyma->master = 0;
    enter(flyma, CO_FLYMA_WAITING);
    arm(flyma, flyma->config.delay_ms);
    tell(flyma, CO_FLYMA_EV_RESET_ALL, 0, 0);
}

bool co_flyma_detect_capable(co_flyma_t *flyma)
{
    if (!send(flyma, CO_FLYMA_ID_ASK_CAPABLE, NULL, 0)) {
        return false;
    }
    flyma->capable_count = 0;
    co_timer_start(co_line_timers(flyma->line), &flyma->capable_timer,
                   co_line_now(flyma->line) + (uint64_t)flyma->config.capable_ms * 1000u);
    return true;
}

bool co_flyma_force(co_flyma_t *flyma)
{
    if (flyma->state == CO_FLYMA_IDLE || !send(flyma, CO_FLYMA_ID_FORCE, NULL, 0)) {
        return false;
    }
    flyma->stats.forced++;
    negotiate(flyma, true);
    return true;
}
