/* Runtime glue of multiplexed PDOs: the application's DAM and SAM sends on
 * the local node's MPDO TPDOs and its counters. Received MPDOs need no glue:
 * they are OD writes (origin network), which the node's OD hooks report. */
#include "co_rt_internal.h"

#include <string.h>

/* The line, locked, with a local node whose PDOs (and so MPDOs) exist, or
 * NULL with the error set, unlocked. */
static rt_line_t *mpdo_line(co_rt_t *rt, int line)
{
    rt_line_t *l = rt_node_line(rt, line, "an MPDO");
    if (l && co_stack_mpdo(&l->stack) == NULL) {
        rt_mutex_unlock(&rt->lock);
        rt_set_error(rt, "line %d: the local node has no object dictionary, so no MPDOs", line);
        return NULL;
    }
    return l;
}

/* Why a send was refused, in words naming the TPDO. */
static const char *why(co_mpdo_status_t status, bool dam)
{
    switch (status) {
    case CO_MPDO_ERR_ARGUMENT:
        return dam ? "node-id 0..127 (0 = all) and 1..4 data bytes"
                   : "the node has no node-id to send as its source";
    case CO_MPDO_ERR_CHANNEL:
        return dam ? "it is no valid DAM MPDO (mapping sub 0 = 0xFF, COB-ID valid, type 254/255)"
                   : "it is no valid SAM MPDO (mapping sub 0 = 0xFE, COB-ID valid, type 254/255)";
    case CO_MPDO_ERR_NOT_SCANNED:
        return "the object scanner list (0x1FA0..0x1FCF) does not name the object";
    case CO_MPDO_ERR_OBJECT:
        return "the object is missing, not readable or longer than 4 bytes";
    case CO_MPDO_ERR_NOT_SENT:
        return "the node is not operational, the inhibit time runs, or the tx queue is full";
    default:
        return "refused";
    }
}

static int finish(co_rt_t *rt, int line, int tpdo, int index, int sub, co_mpdo_status_t status,
                  bool dam)
{
    if (status == CO_MPDO_OK) {
        return rt_kick_unlock(rt, CO_RT_OK);
    }
    rt_set_error(rt, "line %d: %s MPDO on TPDO %d for %04X:%02X not sent: %s", line,
                 dam ? "DAM" : "SAM", tpdo, (unsigned)index, (unsigned)sub, why(status, dam));
    return rt_kick_unlock(rt, status == CO_MPDO_ERR_ARGUMENT ? CO_RT_ERR_ARGUMENT
                                                             : CO_RT_ERR_STATE);
}

static bool object_ok(co_rt_t *rt, int line, int tpdo, int index, int sub)
{
    if (tpdo < 1 || tpdo > CO_PDO_MAX_NUMBER || index < 0 || index > 0xFFFF || sub < 0 ||
        sub > 0xFF) {
        rt_argument_error(rt, "line %d: MPDO on TPDO %d for %X:%X: TPDOs are 1..512, index "
                          "0..0xFFFF, sub 0..0xFF", line, tpdo, (unsigned)index, (unsigned)sub);
        return false;
    }
    return true;
}

int co_rt_mpdo_send_dam(co_rt_t *rt, int line, int tpdo_number, int node, int index, int sub,
                        const uint8_t *data, int len)
{
    if (!object_ok(rt, line, tpdo_number, index, sub)) {
        return CO_RT_ERR_ARGUMENT;
    }
    if (node < 0 || node > 127 || data == NULL || len < 1 || len > CO_MPDO_DATA_MAX) {
        return rt_argument_error(rt, "line %d: DAM MPDO on TPDO %d: node-id 0..127 (0 = all) "
                                 "and 1..4 data bytes, got node %d and %d bytes", line,
                                 tpdo_number, node, len);
    }
    rt_line_t *l = mpdo_line(rt, line);
    if (!l) {
        return CO_RT_ERR_STATE;
    }
    co_line_set_time(&l->line, co_rt_now_us());
    co_mpdo_status_t status =
        co_mpdo_send_dam(co_stack_mpdo(&l->stack), (uint16_t)tpdo_number, (uint8_t)node,
                         (uint16_t)index, (uint8_t)sub, data, (uint8_t)len);
    return finish(rt, line, tpdo_number, index, sub, status, true);
}

int co_rt_mpdo_send_sam(co_rt_t *rt, int line, int tpdo_number, int index, int sub)
{
    if (!object_ok(rt, line, tpdo_number, index, sub)) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_line_t *l = mpdo_line(rt, line);
    if (!l) {
        return CO_RT_ERR_STATE;
    }
    co_line_set_time(&l->line, co_rt_now_us());
    co_mpdo_status_t status = co_mpdo_send_sam(co_stack_mpdo(&l->stack), (uint16_t)tpdo_number,
                                               (uint16_t)index, (uint8_t)sub);
    return finish(rt, line, tpdo_number, index, sub, status, false);
}

int co_rt_mpdo_stats(co_rt_t *rt, int line, co_mpdo_stats_t *out)
{
    if (out == NULL) {
        return rt_argument_error(rt, "co_rt_mpdo_stats: no output");
    }
    rt_line_t *l = mpdo_line(rt, line);
    if (!l) {
        return CO_RT_ERR_STATE;
    }
    *out = *co_mpdo_stats(co_stack_mpdo(&l->stack));
    rt_mutex_unlock(&rt->lock);
    return CO_RT_OK;
}
