/* Runtime glue of TIME: every line consumes TIME (Python hears each stamp);
 * the application sends one on any line (a line without the node's 0x1012
 * makes the application the producer). No state of its own. */
#include "co_rt_internal.h"

void rt_time_on_received(co_stack_t *stack, const co_time_of_day_t *tod, void *user)
{
    (void)stack;
    rt_post(user, CO_EV_TIME, 0, tod->ms, tod->days, NULL);
}

int co_rt_time_send(co_rt_t *rt, int line, uint64_t unix_us)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    co_line_set_time(&l->line, co_rt_now_us());
    co_time_t *time = co_stack_time(&l->stack);
    if (!time->od && !(time->cob_id & CO_TIME_PRODUCER_BIT)) {
        /* a line without the node's 0x1012: the application is the producer */
        (void)co_time_set_cob_id(time, time->cob_id | CO_TIME_PRODUCER_BIT);
    }
    if (!co_time_send_unix_us(time, unix_us)) {
        rt_set_error(rt, "line %d: TIME not sent: %s", line,
                     !(time->cob_id & CO_TIME_PRODUCER_BIT)
                         ? "the node's 0x1012 does not make it the TIME producer (bit 30)"
                     : !time->nmt_active ? "the node is stopped"
                                         : "time before 1984 or the tx queue is full");
        return rt_kick_unlock(rt, CO_RT_ERR_STATE);
    }
    return rt_kick_unlock(rt, CO_RT_OK);
}
