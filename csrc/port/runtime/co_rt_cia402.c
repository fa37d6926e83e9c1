/* Runtime glue of the simulated CiA 402 drive (co_cia402_sim): one per local
 * node, made on request over the node's OD, SYNC, EMCY producer and PDOs, so the
 * drive answers controlwords and SYNCs in the runtime thread (no Python on
 * the per-SYNC path). Freed with the line. */
#include "co_rt_internal.h"

#include <stdlib.h>

int co_rt_cia402_sim_start(co_rt_t *rt, int line, uint32_t tick_us)
{
    if (tick_us == 0) {
        rt_set_error(rt, "line %d: the simulated drive's tick must be above 0 us", line);
        return CO_RT_ERR_ARGUMENT;
    }
    rt_line_t *l = rt_node_line(rt, line, "a simulated CiA 402 drive");
    if (!l) {
        return CO_RT_ERR_STATE;
    }
    if (l->cia402) {
        rt_set_error(rt, "line %d: the local node already runs a simulated drive", line);
        return rt_kick_unlock(rt, CO_RT_ERR_STATE);
    }
    co_cia402_sim_t *sim = calloc(1, sizeof *sim);
    if (!sim) {
        rt_set_error(rt, "line %d: no memory for the simulated drive", line);
        return rt_kick_unlock(rt, CO_RT_ERR_NO_MEMORY);
    }
    co_line_set_time(&l->line, co_rt_now_us());
    if (!co_cia402_sim_init(sim, &l->line, co_stack_od(&l->stack), co_stack_sync(&l->stack),
                            co_stack_emcy(&l->stack), tick_us)) {
        if (sim->missing_key != 0) {
            rt_set_error(rt, "line %d: the simulated drive needs object 0x%04X:%02X in the "
                         "node's OD", line, (unsigned)(sim->missing_key >> 8),
                         (unsigned)(sim->missing_key & 0xFFu));
        } else {
            rt_set_error(rt, "line %d: the simulated drive found no free OD or SYNC "
                         "subscription", line);
        }
        free(sim);
        return rt_kick_unlock(rt, CO_RT_ERR_STATE);
    }
    co_cia402_sim_set_pdo(sim, co_stack_pdo(&l->stack));
    l->cia402 = sim;
    return rt_kick_unlock(rt, CO_RT_OK);
}

int co_rt_cia402_sim_fault(co_rt_t *rt, int line, uint16_t code)
{
    rt_line_t *l = rt_node_line(rt, line, "a drive fault");
    if (!l) {
        return CO_RT_ERR_STATE;
    }
    if (!l->cia402) {
        rt_set_error(rt, "line %d: the local node runs no simulated drive", line);
        return rt_kick_unlock(rt, CO_RT_ERR_STATE);
    }
    if (code == 0) {
        rt_set_error(rt, "line %d: a drive fault needs an error code (0x603F) above 0", line);
        return rt_kick_unlock(rt, CO_RT_ERR_ARGUMENT);
    }
    co_line_set_time(&l->line, co_rt_now_us());
    co_cia402_sim_fault(l->cia402, code);
    return rt_kick_unlock(rt, CO_RT_OK);
}

void rt_cia402_free(rt_line_t *l)
{
    if (l->cia402) {
        co_cia402_sim_deinit(l->cia402);
        free(l->cia402);
        l->cia402 = NULL;
    }
}
