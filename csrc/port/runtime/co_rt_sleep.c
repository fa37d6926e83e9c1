/* Runtime glue of sleep and wake-up: the line's co_sleep (through co_stack)
 * posts every event to the application; a device answers queries with the
 * objection the application set beforehand (the runtime thread cannot wait
 * for Python inside the core's indication); the application acts from any
 * thread. */
#include "co_rt_internal.h"

static uint8_t on_sleep(co_sleep_t *sleep, co_sleep_event_t event, uint8_t arg, uint8_t arg2,
                        void *user)
{
    rt_line_t *l = user;
    uint8_t answer = event == CO_SLEEP_EV_QUERY ? l->sleep.objection : 0;
    /* the phase after the event: a query answered or refused leaves it as it is */
    co_sleep_phase_t phase = co_sleep_phase(sleep);
    if (event == CO_SLEEP_EV_PREPARE) {
        phase = CO_SLEEP_PREPARING;
    } else if (event == CO_SLEEP_EV_SILENT) {
        phase = CO_SLEEP_SILENT;
    }
    rt_post(l, CO_EV_SLEEP, (uint8_t)phase, (uint32_t)event, (uint32_t)arg | (uint32_t)arg2 << 8,
            NULL);
    return answer;
}

static bool valid_ms(uint16_t ms) { return ms <= 60000u; }

int co_rt_sleep_start(co_rt_t *rt, int line, const co_rt_sleep_config_t *config)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l || !config) {
        return CO_RT_ERR_ARGUMENT;
    }
    if (!valid_ms(config->check_ms) || !valid_ms(config->prepare_ms) ||
        !valid_ms(config->silent_ms) || !valid_ms(config->wake_repeat_ms)) {
        return rt_argument_error(rt, "line %d: sleep times are 0..60000 ms (0 = 1000)", line);
    }
    co_sleep_config_t c = {.master = config->master != 0,
                           .check_ms = config->check_ms,
                           .prepare_ms = config->prepare_ms,
                           .silent_ms = config->silent_ms,
                           .wake_repeat_ms = config->wake_repeat_ms,
                           .ind = on_sleep,
                           .user = l};
    rt_mutex_lock(&rt->lock);
    co_line_set_time(&l->line, co_rt_now_us());
    l->sleep.objection = config->objection;
    co_stack_status_t status = co_stack_sleep_init(&l->stack, &c);
    rt_mutex_unlock(&rt->lock);
    if (status == CO_STACK_ERR_STATE) {
        rt_set_error(rt, "line %d: sleep and wake-up runs on this line already", line);
        return CO_RT_ERR_STATE;
    }
    if (status != CO_STACK_OK) {
        rt_set_error(rt, "line %d: sleep and wake-up: CAN-IDs 0x690..0x692 are taken", line);
        return CO_RT_ERR_STATE;
    }
    return CO_RT_OK;
}

int co_rt_sleep_stop(co_rt_t *rt, int line)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    co_stack_sleep_deinit(&l->stack);
    rt_mutex_unlock(&rt->lock);
    return CO_RT_OK;
}

int co_rt_sleep_objection(co_rt_t *rt, int line, uint8_t reason)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    l->sleep.objection = reason;
    rt_mutex_unlock(&rt->lock);
    return CO_RT_OK;
}

/* Why an action was refused, for the error text. */
static const char *refusal(const co_sleep_t *sleep, int action)
{
    bool master = sleep->config.master;
    co_sleep_phase_t phase = co_sleep_phase(sleep);
    if ((action == CO_RT_SLEEP_CHECK && !master) || (action == CO_RT_SLEEP_REQUEST && master)) {
        return master ? "a master does not request sleep" : "only the master checks";
    }
    if (action == CO_RT_SLEEP_WAKE) {
        return phase == CO_SLEEP_AWAKE || phase == CO_SLEEP_CHECKING
                   ? "the line is awake"
                   : master ? "status 1 and 2 read as commands from the master"
                            : "status 0x81 reads as an objection from a device";
    }
    if (phase != CO_SLEEP_AWAKE) {
        return "a sleep is under way";
    }
    return "refused by the application or the tx queue is full";
}

int co_rt_sleep_act(co_rt_t *rt, int line, int action, uint8_t status, uint8_t reason)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    if (action < CO_RT_SLEEP_CHECK || action > CO_RT_SLEEP_WAKE) {
        return rt_argument_error(rt, "line %d: unknown sleep action %d", line, action);
    }
    rt_mutex_lock(&rt->lock);
    co_sleep_t *sleep = co_stack_sleep(&l->stack);
    if (!sleep) {
        rt_set_error(rt, "line %d: sleep and wake-up is not started on this line", line);
        rt_mutex_unlock(&rt->lock);
        return CO_RT_ERR_STATE;
    }
    co_line_set_time(&l->line, co_rt_now_us());
    bool done = action == CO_RT_SLEEP_CHECK     ? co_sleep_check(sleep)
                : action == CO_RT_SLEEP_START   ? co_sleep_start(sleep)
                : action == CO_RT_SLEEP_REQUEST ? co_sleep_request(sleep)
                                                : co_sleep_wake(sleep, status, reason);
    if (!done) {
        rt_set_error(rt, "line %d: sleep action refused: %s", line, refusal(sleep, action));
        return rt_kick_unlock(rt, CO_RT_ERR_STATE);
    }
    return rt_kick_unlock(rt, CO_RT_OK);
}

int co_rt_sleep_state(co_rt_t *rt, int line, co_sleep_stats_t *stats)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    co_sleep_t *sleep = co_stack_sleep(&l->stack);
    int phase = sleep ? (int)co_sleep_phase(sleep) : CO_RT_ERR_STATE;
    if (sleep && stats) {
        *stats = *co_sleep_stats(sleep);
    }
    rt_mutex_unlock(&rt->lock);
    if (!sleep) {
        rt_set_error(rt, "line %d: sleep and wake-up is not started on this line", line);
    }
    return phase;
}
