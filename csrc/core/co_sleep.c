/* Sleep and wake-up, master and device (see co_sleep.h). */
#include "canopenfd/co_sleep.h"

#include <string.h>

static uint8_t tell(co_sleep_t *s, co_sleep_event_t event, uint8_t arg, uint8_t arg2)
{
    return s->config.ind ? s->config.ind(s, event, arg, arg2, s->config.user) : 0;
}

static uint64_t after_ms(const co_sleep_t *s, uint16_t ms)
{
    return co_line_now(s->line) + (uint64_t)ms * 1000u;
}

static bool send_command(co_sleep_t *s, uint32_t id, uint8_t byte0, uint8_t byte1)
{
    uint8_t data[CO_SLEEP_FRAME_LENGTH] = {byte0, byte1};
    if (!co_line_send(s->line, id, data, sizeof data)) {
        s->stats.send_failed++;
        return false;
    }
    return true;
}

static uint32_t own_id(const co_sleep_t *s)
{
    return s->config.master ? CO_SLEEP_MASTER_ID : CO_SLEEP_DEVICE_ID;
}

/* A wake-up status must not read as a command on the sender's CAN-ID. */
static bool status_is_command(const co_sleep_t *s, uint8_t status)
{
    return s->config.master ? status == CO_SLEEP_CMD_QUERY || status == CO_SLEEP_CMD_SLEEP
                            : status == CO_SLEEP_CMD_OBJECTION;
}

/* Back awake without a reset: the application refused `phase`. */
static void refused(co_sleep_t *s, co_sleep_phase_t phase)
{
    co_timer_cancel(co_line_timers(s->line), &s->phase_timer);
    co_line_set_silent(s->line, false);
    co_line_watch_rx(s->line, NULL, NULL);
    s->phase = CO_SLEEP_AWAKE;
    tell(s, CO_SLEEP_EV_REFUSED, (uint8_t)phase, 0);
}

static void wake(co_sleep_t *s, uint8_t status, uint8_t reason, co_sleep_cause_t cause)
{
    co_timer_cancel(co_line_timers(s->line), &s->phase_timer);
    co_line_watch_rx(s->line, NULL, NULL);
    co_line_set_silent(s->line, false);
    s->phase = CO_SLEEP_AWAKE;
    s->wake_status = status;
    s->wake_reason = reason;
    if (send_command(s, own_id(s), status, reason)) {
        s->stats.wake_messages_sent++;
    }
    if (s->config.wake_repeat_ms) {
        co_timer_start(co_line_timers(s->line), &s->repeat_timer,
                       after_ms(s, s->config.wake_repeat_ms));
    }
    tell(s, CO_SLEEP_EV_WAKE, (uint8_t)cause, 0);
}

/* --------------------------------------------------------------- phases */

static void enter_silent(co_sleep_t *s)
{
    if (tell(s, CO_SLEEP_EV_SILENT, 0, 0) != 0) {
        refused(s, CO_SLEEP_SILENT);
        return;
    }
    s->phase = CO_SLEEP_SILENT;
    co_line_set_silent(s->line, true);
    co_timer_start(co_line_timers(s->line), &s->phase_timer, after_ms(s, s->config.silent_ms));
}

static void on_bus_traffic(co_line_t *line, const co_frame_t *frame, void *user)
{
    (void)line;
    (void)frame;
    co_sleep_t *s = user;
    if (s->phase == CO_SLEEP_ASLEEP) {
        wake(s, 0, (uint8_t)CO_SLEEP_BY_BUS, CO_SLEEP_BY_BUS);
    }
}

static void enter_asleep(co_sleep_t *s)
{
    s->phase = CO_SLEEP_ASLEEP;
    co_line_watch_rx(s->line, on_bus_traffic, s);
    tell(s, CO_SLEEP_EV_ASLEEP, 0, 0);
}

/* Sleep decided: PREPARE (the application may refuse), the master's sleep
 * command, prepare_ms until silent. */
static bool enter_prepare(co_sleep_t *s)
{
    if (tell(s, CO_SLEEP_EV_PREPARE, 0, 0) != 0) {
        refused(s, CO_SLEEP_PREPARING);
        return false;
    }
    if (s->config.master) {
        if (!send_command(s, CO_SLEEP_MASTER_ID, CO_SLEEP_CMD_SLEEP, 0)) {
            s->phase = CO_SLEEP_AWAKE;
            return false;
        }
        s->stats.sleep_commands_sent++;
    }
    s->phase = CO_SLEEP_PREPARING;
    co_timer_start(co_line_timers(s->line), &s->phase_timer, after_ms(s, s->config.prepare_ms));
    return true;
}

static void on_phase_timer(co_timer_t *timer, uint64_t now_us, void *user)
{
    (void)timer;
    (void)now_us;
    co_sleep_t *s = user;
    switch (s->phase) {
    case CO_SLEEP_CHECKING:   /* no objection came */
        (void)enter_prepare(s);
        break;
    case CO_SLEEP_PREPARING:
        enter_silent(s);
        break;
    case CO_SLEEP_SILENT:
        enter_asleep(s);
        break;
    default:
        break;
    }
}

static void on_repeat_timer(co_timer_t *timer, uint64_t now_us, void *user)
{
    (void)timer;
    (void)now_us;
    co_sleep_t *s = user;
    if (s->phase == CO_SLEEP_AWAKE &&
        send_command(s, own_id(s), s->wake_status, s->wake_reason)) {
        s->stats.wake_messages_sent++;
    }
}

/* ------------------------------------------------------------- receiving */

/* Another node's wake-up message: it wakes a node that is silent or asleep. */
static void wake_message(co_sleep_t *s, const co_frame_t *frame)
{
    s->stats.wake_messages_received++;
    tell(s, CO_SLEEP_EV_WAKE_MESSAGE, frame->data[0], frame->data[1]);
    if (s->phase == CO_SLEEP_SILENT || s->phase == CO_SLEEP_ASLEEP) {
        wake(s, 0, (uint8_t)CO_SLEEP_BY_WAKE_MESSAGE, CO_SLEEP_BY_WAKE_MESSAGE);
    }
}

static void device_receive(co_sleep_t *s, const co_frame_t *frame)
{
    if (frame->id != CO_SLEEP_MASTER_ID) {
        s->stats.rx_ignored++;   /* other devices' objections, requests, wake-ups */
        return;
    }
    switch (frame->data[0]) {
    case CO_SLEEP_CMD_QUERY: {
        if (s->phase != CO_SLEEP_AWAKE) {
            s->stats.rx_ignored++;
            return;
        }
        uint8_t reason = tell(s, CO_SLEEP_EV_QUERY, 0, 0);
        if (reason != 0 && send_command(s, CO_SLEEP_DEVICE_ID, CO_SLEEP_CMD_OBJECTION, reason)) {
            s->stats.objections_sent++;
        }
        return;
    }
    case CO_SLEEP_CMD_SLEEP:
        if (s->phase != CO_SLEEP_AWAKE) {
            s->stats.rx_ignored++;
            return;
        }
        (void)enter_prepare(s);
        return;
    default:
        wake_message(s, frame);
        return;
    }
}

static void master_receive(co_sleep_t *s, const co_frame_t *frame)
{
    if (frame->id == CO_SLEEP_REQUEST_ID) {
        if (frame->data[0] != CO_SLEEP_CMD_REQUEST) {
            s->stats.rx_ignored++;
            return;
        }
        s->stats.requests_received++;
        tell(s, CO_SLEEP_EV_REQUEST, 0, 0);
        return;
    }
    if (frame->id != CO_SLEEP_DEVICE_ID) {
        s->stats.rx_ignored++;   /* another master's frames */
        return;
    }
    if (frame->data[0] != CO_SLEEP_CMD_OBJECTION) {
        wake_message(s, frame);
        return;
    }
    s->stats.objections_received++;
    if (s->phase != CO_SLEEP_CHECKING) {
        s->stats.rx_ignored++;   /* late: the check ended already */
        return;
    }
    co_timer_cancel(co_line_timers(s->line), &s->phase_timer);
    s->phase = CO_SLEEP_AWAKE;
    tell(s, CO_SLEEP_EV_OBJECTION, frame->data[1], 0);
}

static void on_frame(co_line_t *line, const co_frame_t *frame, void *user)
{
    (void)line;
    co_sleep_t *s = user;
    if (frame->len != CO_SLEEP_FRAME_LENGTH) {
        s->stats.rx_bad_length++;
        return;
    }
    if (s->config.master) {
        master_receive(s, frame);
    } else {
        device_receive(s, frame);
    }
}

/* -------------------------------------------------------------- the API */

bool co_sleep_init(co_sleep_t *sleep, co_line_t *line, const co_sleep_config_t *config)
{
    if (!sleep || !line || !config) {
        return false;
    }
    memset(sleep, 0, sizeof *sleep);
    sleep->line = line;
    sleep->config = *config;
    if (!sleep->config.check_ms) {
        sleep->config.check_ms = CO_SLEEP_DEFAULT_MS;
    }
    if (!sleep->config.prepare_ms) {
        sleep->config.prepare_ms = CO_SLEEP_DEFAULT_MS;
    }
    if (!sleep->config.silent_ms) {
        sleep->config.silent_ms = CO_SLEEP_DEFAULT_MS;
    }
    co_timer_init(&sleep->phase_timer, on_phase_timer, sleep);
    co_timer_init(&sleep->repeat_timer, on_repeat_timer, sleep);
    if (!co_line_subscribe(line, CO_SLEEP_DEVICE_ID, CO_SLEEP_REQUEST_ID, on_frame, sleep)) {
        return false;
    }
    sleep->subscribed = true;
    return true;
}

void co_sleep_deinit(co_sleep_t *sleep)
{
    if (!sleep->subscribed) {
        return;
    }
    co_timer_cancel(co_line_timers(sleep->line), &sleep->phase_timer);
    co_timer_cancel(co_line_timers(sleep->line), &sleep->repeat_timer);
    if (sleep->phase == CO_SLEEP_SILENT || sleep->phase == CO_SLEEP_ASLEEP) {
        co_line_set_silent(sleep->line, false);
        co_line_watch_rx(sleep->line, NULL, NULL);
    }
    co_line_unsubscribe(sleep->line, on_frame, sleep);
    sleep->subscribed = false;
    sleep->phase = CO_SLEEP_AWAKE;
}

bool co_sleep_check(co_sleep_t *sleep)
{
    if (!sleep->config.master || sleep->phase != CO_SLEEP_AWAKE ||
        !send_command(sleep, CO_SLEEP_MASTER_ID, CO_SLEEP_CMD_QUERY, 0)) {
        return false;
    }
    sleep->stats.queries_sent++;
    sleep->phase = CO_SLEEP_CHECKING;
    co_timer_start(co_line_timers(sleep->line), &sleep->phase_timer,
                   after_ms(sleep, sleep->config.check_ms));
    return true;
}

bool co_sleep_start(co_sleep_t *sleep)
{
    return sleep->phase == CO_SLEEP_AWAKE && enter_prepare(sleep);
}

bool co_sleep_request(co_sleep_t *sleep)
{
    if (sleep->config.master ||
        !send_command(sleep, CO_SLEEP_REQUEST_ID, CO_SLEEP_CMD_REQUEST, 0)) {
        return false;
    }
    sleep->stats.requests_sent++;
    return true;
}

bool co_sleep_wake(co_sleep_t *sleep, uint8_t status, uint8_t reason)
{
    if (sleep->phase == CO_SLEEP_AWAKE || sleep->phase == CO_SLEEP_CHECKING ||
        status_is_command(sleep, status)) {
        return false;
    }
    wake(sleep, status, reason, CO_SLEEP_BY_APPLICATION);
    return true;
}
