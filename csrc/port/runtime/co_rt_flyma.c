/* Runtime glue of the flying master: the local node's co_flyma (through
 * co_stack) posts every event to the application, which starts, stops and
 * acts from any thread. */
#include "co_rt_internal.h"

#include <string.h>

static void on_flyma(co_flyma_t *flyma, co_flyma_event_t event, co_flyma_state_t state,
                     uint8_t master, uint8_t priority, void *user)
{
    (void)flyma;
    rt_post(user, CO_EV_FLYMA, (uint8_t)state, (uint32_t)event,
            (uint32_t)master | (uint32_t)priority << 8, NULL);
}

int co_rt_flyma_start(co_rt_t *rt, int line, const co_rt_flyma_config_t *config)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l || !config) {
        return CO_RT_ERR_ARGUMENT;
    }
    co_stack_flyma_config_t c = {
        .flyma = {.priority = config->priority,
                  .detect_ms = config->detect_ms,
                  .delay_ms = config->delay_ms,
                  .priority_slot_ms = config->priority_slot_ms,
                  .device_slot_ms = config->device_slot_ms,
                  .multiple_master_ms = config->multiple_master_ms,
                  .capable_ms = config->capable_ms,
                  .ind = on_flyma,
                  .user = l},
        .master_heartbeat_ms = config->master_heartbeat_ms};
    rt_mutex_lock(&rt->lock);
    co_line_set_time(&l->line, co_rt_now_us());
    bool node = rt_has_node(l);
    co_stack_status_t status = node ? co_stack_flyma_init(&l->stack, &c) : CO_STACK_ERR_STATE;
    if (status != CO_STACK_OK) {
        rt_set_error(rt, "line %d: flying master: %s", line,
                     !node ? "the line has no local node"
                     : status == CO_STACK_ERR_STATE ? "it runs on this line already"
                                                    : "CAN-IDs 0x71..0x76 are taken");
        return rt_kick_unlock(rt, CO_RT_ERR_STATE);
    }
    return rt_kick_unlock(rt, CO_RT_OK);
}

int co_rt_flyma_stop(co_rt_t *rt, int line)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    co_stack_flyma_deinit(&l->stack);
    rt_mutex_unlock(&rt->lock);
    return CO_RT_OK;
}

int co_rt_flyma_act(co_rt_t *rt, int line, int action)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    if (action != CO_RT_FLYMA_DETECT_CAPABLE && action != CO_RT_FLYMA_FORCE) {
        return rt_argument_error(rt, "line %d: unknown flying master action %d", line, action);
    }
    rt_mutex_lock(&rt->lock);
    co_flyma_t *flyma = co_stack_flyma(&l->stack);
    if (!flyma) {
        rt_set_error(rt, "line %d: the flying master is not started on this line", line);
        rt_mutex_unlock(&rt->lock);
        return CO_RT_ERR_STATE;
    }
    co_line_set_time(&l->line, co_rt_now_us());
    bool done = action == CO_RT_FLYMA_FORCE ? co_flyma_force(flyma)
                                            : co_flyma_detect_capable(flyma);
    if (!done) {
        rt_set_error(rt, "line %d: flying master %s refused: %s", line,
                     action == CO_RT_FLYMA_FORCE ? "force" : "detection",
                     co_flyma_state(flyma) == CO_FLYMA_IDLE ? "the node has not booted"
                                                            : "the tx queue is full");
        return rt_kick_unlock(rt, CO_RT_ERR_STATE);
    }
    return rt_kick_unlock(rt, CO_RT_OK);
}

int co_rt_flyma_state(co_rt_t *rt, int line, co_rt_flyma_state_t *out)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l || !out) {
        return CO_RT_ERR_ARGUMENT;
    }
    memset(out, 0, sizeof *out);   /* not started: idle, no master, no counts */
    rt_mutex_lock(&rt->lock);
    const co_flyma_t *flyma = co_stack_flyma(&l->stack);
    if (flyma) {
        out->state = (int)co_flyma_state(flyma);
        out->master = co_flyma_master(flyma);
        out->master_priority = co_flyma_master_priority(flyma);
        out->stats = *co_flyma_stats(flyma);
    }
    rt_mutex_unlock(&rt->lock);
    return CO_RT_OK;
}
