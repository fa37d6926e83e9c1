/* Runtime glue of node guarding: on classic lines the line's guarding
 * master guards the remote nodes the application names; its events and
 * those of the local node's guarding slave reach Python. No state of its
 * own: the stack holds master and slave. */
#include "co_rt_internal.h"

void rt_guard_on_event(co_stack_t *stack, uint8_t node_id, co_guard_event_t event,
                       co_nmt_state_t state, void *user)
{
    (void)stack;
    rt_post(user, CO_EV_GUARD, node_id, (uint32_t)event, (uint32_t)state, NULL);
}

int co_rt_guard(co_rt_t *rt, int line, int node_id, int guard_ms, int life_factor)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    co_guard_master_t *master = co_stack_guard_master(&l->stack);
    if (!master) {
        return rt_argument_error(rt, "line %d: node guarding needs a classic line (CAN FD "
                                 "has no remote frames)", line);
    }
    if (node_id < 1 || node_id > 127 || guard_ms < 0 || guard_ms > 0xFFFF || life_factor < 0 ||
        life_factor > 0xFF) {
        return rt_argument_error(rt, "line %d: guarding node %d every %d ms, factor %d: "
                                 "node 1..127, time 0..65535 ms, factor 0..255", line,
                                 node_id, guard_ms, life_factor);
    }
    rt_mutex_lock(&rt->lock);
    co_line_set_time(&l->line, co_rt_now_us());
    int status = CO_RT_OK;
    if (guard_ms == 0) {
        co_guard_master_unguard(master, (uint8_t)node_id);
    } else if (co_guard_master_guard(master, (uint8_t)node_id, (uint16_t)guard_ms,
                                     (uint8_t)life_factor) != CO_GUARD_OK) {
        rt_set_error(rt, "line %d: cannot guard node %d (%d nodes guarded already)", line,
                     node_id, RT_GUARD_NODES);
        status = CO_RT_ERR_FULL;
    }
    return rt_kick_unlock(rt, status);
}
