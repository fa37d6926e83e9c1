/* Runtime glue of multiplexed PDOs: the application's DAM and SAM sends on
 * the local node's MPDO TPDOs, its counters, and CO_EV_MPDO for each MPDO
 * addressed to the node, applied or refused, while Python listens (the
 * values also reach Python as OD writes of origin network). */
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
        return dam ? "its mapping sub 1 names no readable object of that length (8..32 bits)"
                   : "the object is missing, not readable or longer than 4 bytes";
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

int co_rt_mpdo_send_dam_mapped(co_rt_t *rt, int line, int tpdo_number, int node)
{
    if (!object_ok(rt, line, tpdo_number, 0, 0)) {
        return CO_RT_ERR_ARGUMENT;
    }
    if (node < 0 || node > 127) {
        return rt_argument_error(rt, "line %d: DAM MPDO on TPDO %d: node-id 0..127 (0 = all), "
                                 "got %d", line, tpdo_number, node);
    }
    rt_line_t *l = mpdo_line(rt, line);
    if (!l) {
        return CO_RT_ERR_STATE;
    }
    co_line_set_time(&l->line, co_rt_now_us());
    co_mpdo_t *mpdo = co_stack_mpdo(&l->stack);
    co_mpdo_status_t status = co_mpdo_send_dam_mapped(mpdo, (uint16_t)tpdo_number, (uint8_t)node);
    uint32_t entry = 0;   /* for the error text: what the mapping names */
    (void)co_od_get_u32(mpdo->pdo->od, (uint16_t)(CO_PDO_TPDO_MAP + tpdo_number - 1), 1, &entry);
    return finish(rt, line, tpdo_number, (int)(entry >> 16), (int)(uint8_t)(entry >> 8), status,
                  true);
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

void rt_mpdo_received(rt_line_t *l, uint16_t rpdo_number, const co_mpdo_msg_t *msg,
                      uint16_t index, uint8_t sub, uint32_t abort)
{
    if (!l->pdo.mpdo_events) {
        return;
    }
    /* the frame as received, then the RPDO and the local object (see CO_EV_MPDO) */
    co_frame_t frame;
    memset(&frame, 0, sizeof frame);
    co_mpdo_encode(msg, frame.data);
    frame.data[8] = (uint8_t)rpdo_number;
    frame.data[9] = (uint8_t)(rpdo_number >> 8);
    frame.data[10] = (uint8_t)index;
    frame.data[11] = (uint8_t)(index >> 8);
    frame.data[12] = sub;
    frame.len = 13;
    uint32_t mux = (uint32_t)frame.data[0] << 24 | (uint32_t)msg->index << 8 | msg->sub;
    rt_post(l, CO_EV_MPDO, co_stack_node(&l->stack)->nmt.node_id, mux, abort, &frame);
}

int co_rt_mpdo_listen(co_rt_t *rt, int line, int listen)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    l->pdo.mpdo_events = listen != 0;   /* kept across node rebuilds, as the LEDs' */
    rt_mutex_unlock(&rt->lock);
    return CO_RT_OK;
}
