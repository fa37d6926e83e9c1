/* Runtime glue of the local node's SRDOs and GFC (CiA 304): co_stack runs
 * them; every safe-state entry is posted to the application, which
 * configures, feeds and reads them from any thread. No state of its own. */
#include "co_rt_internal.h"

#include <string.h>

static void on_safe(co_srdo_t *srdo, co_srdo_violation_t why, void *user)
{
    rt_line_t *l = user;
    uint8_t number = (uint8_t)(srdo - l->stack.srdo + 1);
    rt_post(l, CO_EV_SRDO, number, (uint32_t)why, 0, NULL);
}

int co_rt_srdo_start(co_rt_t *rt, int line, uint8_t count)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    if (count == 0 || count > 64) {
        return rt_argument_error(rt, "line %d: SRDO count must be 1..64, got %u", line, count);
    }
    rt_mutex_lock(&rt->lock);
    co_line_set_time(&l->line, co_rt_now_us());
    co_stack_status_t status = co_stack_srdo_init(&l->stack, count, on_safe, l);
    rt_mutex_unlock(&rt->lock);
    if (status == CO_STACK_ERR_STATE) {
        rt_set_error(rt, "line %d: SRDOs need the line's node and start once", line);
        return CO_RT_ERR_STATE;
    }
    if (status != CO_STACK_OK) {
        rt_set_error(rt, "line %d: no memory for %u SRDOs", line, count);
        return CO_RT_ERR_STATE;
    }
    return CO_RT_OK;
}

/* The SRDO under rt->lock, or NULL with *status set (no lock held, error
 * text set). */
static co_srdo_t *locked_srdo(co_rt_t *rt, int line, uint8_t number, int *status)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    *status = l ? CO_RT_ERR_STATE : CO_RT_ERR_ARGUMENT;
    if (!l) {
        return NULL;
    }
    rt_mutex_lock(&rt->lock);
    co_srdo_t *srdo = co_stack_srdo(&l->stack, number);
    if (!srdo) {
        unsigned count = l->stack.srdo_count;
        rt_mutex_unlock(&rt->lock);
        rt_set_error(rt, "line %d: SRDO %u does not run (co_rt_srdo_start: 1..%u)", line,
                     number, count);
    } else {
        co_line_set_time(&l->line, co_rt_now_us());
    }
    return srdo;
}

static const char *param_text(co_srdo_param_t p)
{
    switch (p) {
    case CO_SRDO_PARAM_OK: return "";
    case CO_SRDO_PARAM_DIRECTION: return "sub 1 (direction): 0, 1 or 2";
    case CO_SRDO_PARAM_SCT: return "sub 2 (SCT): 1..65535 ms";
    case CO_SRDO_PARAM_SRVT: return "sub 3 (SRVT): 1..255 ms";
    case CO_SRDO_PARAM_TRANSMISSION_TYPE: return "sub 4 (transmission type): 254";
    case CO_SRDO_PARAM_COB_ID_NORMAL: return "sub 5 (normal COB-ID): odd, 0x101..0x17F";
    case CO_SRDO_PARAM_COB_ID_INVERTED: return "sub 6 (inverted COB-ID): normal + 1";
    case CO_SRDO_PARAM_MAP_COUNT: return "mapping sub 0: even, 2..16";
    case CO_SRDO_PARAM_MAP_LENGTH:
        return "mapping: whole bytes, normal and inverted halves equal, 1..8 bytes";
    }
    return "unknown";
}

int co_rt_srdo_configure(co_rt_t *rt, int line, uint8_t number, const co_srdo_config_t *config,
                         uint8_t valid, uint16_t signature)
{
    if (!config) {
        return CO_RT_ERR_ARGUMENT;
    }
    co_srdo_param_t param = co_srdo_check(config, NULL);
    if (param != CO_SRDO_PARAM_OK) {
        return rt_argument_error(rt, "line %d: SRDO %u: 0x%04X %s", line, number,
                                 (param >= CO_SRDO_PARAM_MAP_COUNT ? 0x1380u : 0x1300u) + number,
                                 param_text(param));
    }
    int status;
    co_srdo_t *srdo = locked_srdo(rt, line, number, &status);
    if (!srdo) {
        return status;
    }
    bool done = co_srdo_configure(srdo, config, valid, signature);
    co_srdo_od_t *objects = &rt_checked_line(rt, line, false)->stack.srdo_od;
    /* with the objects in the OD, they are the configuration the next
     * start reloads: they get the same values (and the mapped variables) */
    bool in_od = done && objects->od != NULL &&
                 co_od_has_index(objects->od, (uint16_t)(CO_SRDO_OD_COMMUNICATION + number));
    uint32_t stored = in_od ? co_srdo_od_store(objects, number, config, valid, signature) : 0;
    uint32_t bound = in_od && stored == 0 ? co_srdo_bind_od(srdo, objects->od) : 0;
    rt_mutex_unlock(&rt->lock);
    if (stored != 0) {
        rt_set_error(rt, "line %d: SRDO %u: the node's OD lacks a sub-entry of 0x%04X, 0x%04X "
                     "or 0x13FF sub %u (abort 0x%08X)", line, number, 0x1300u + number,
                     0x1380u + number, number, (unsigned)stored);
        return CO_RT_ERR_ARGUMENT;
    }
    if (bound != 0) {
        rt_set_error(rt, "line %d: SRDO %u: mapping 0x%04X does not resolve in the node's OD "
                     "(abort 0x%08X: an object missing, not mappable this way or shorter "
                     "than mapped); it enters the safe state (bad parameter) when started",
                     line, number, 0x1380u + number, (unsigned)bound);
        return CO_RT_ERR_ARGUMENT;
    }
    if (!done) {
        rt_set_error(rt, "line %d: SRDO %u not configured: %s", line, number,
                     srdo->operational ? "the node is operational"
                                       : "its CAN-IDs are taken by another service");
        return CO_RT_ERR_STATE;
    }
    return CO_RT_OK;
}

int co_rt_srdo_set_data(co_rt_t *rt, int line, uint8_t number, const uint8_t *data,
                        size_t length)
{
    if (!data && length) {
        return CO_RT_ERR_ARGUMENT;
    }
    int status;
    co_srdo_t *srdo = locked_srdo(rt, line, number, &status);
    if (!srdo) {
        return status;
    }
    bool done = co_srdo_set_data(srdo, data, length);
    uint8_t want = srdo->length;
    bool producer = srdo->config.direction == CO_SRDO_PRODUCE;
    rt_mutex_unlock(&rt->lock);
    if (!done) {
        return producer ? rt_argument_error(rt, "line %d: SRDO %u maps %u bytes, got %u", line,
                                            number, want, (unsigned)length)
                        : rt_argument_error(rt, "line %d: SRDO %u is not a producer", line,
                                            number);
    }
    return CO_RT_OK;
}

int co_rt_srdo_read(co_rt_t *rt, int line, uint8_t number, co_rt_srdo_status_t *out)
{
    if (!out) {
        return CO_RT_ERR_ARGUMENT;
    }
    int status;
    co_srdo_t *srdo = locked_srdo(rt, line, number, &status);
    if (!srdo) {
        return status;
    }
    memset(out, 0, sizeof *out);
    out->state = (int)co_srdo_state(srdo);
    out->violation = (int)co_srdo_violation(srdo);
    out->length = (uint8_t)co_srdo_data(srdo, out->data);
    out->stats = *co_srdo_stats(srdo);
    rt_mutex_unlock(&rt->lock);
    return CO_RT_OK;
}

int co_rt_srdo_restart(co_rt_t *rt, int line, uint8_t number)
{
    int status;
    co_srdo_t *srdo = locked_srdo(rt, line, number, &status);
    if (!srdo) {
        return status;
    }
    co_srdo_restart(srdo);
    return rt_kick_unlock(rt, CO_RT_OK);
}

/* The GFC under rt->lock, or NULL with *status set (no lock held, error
 * text set). */
static co_gfc_t *locked_gfc(co_rt_t *rt, int line, int *status)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    *status = l ? CO_RT_ERR_STATE : CO_RT_ERR_ARGUMENT;
    if (!l) {
        return NULL;
    }
    rt_mutex_lock(&rt->lock);
    co_gfc_t *gfc = co_stack_gfc(&l->stack);
    if (!gfc) {
        rt_mutex_unlock(&rt->lock);
        rt_set_error(rt, "line %d: the GFC runs with the SRDOs (co_rt_srdo_start)", line);
    } else {
        co_line_set_time(&l->line, co_rt_now_us());
    }
    return gfc;
}

int co_rt_gfc_enable(co_rt_t *rt, int line, bool on)
{
    int status;
    co_gfc_t *gfc = locked_gfc(rt, line, &status);
    if (!gfc) {
        return status;
    }
    co_srdo_od_t *objects = &rt_checked_line(rt, line, false)->stack.srdo_od;
    bool done;
    if (objects->od && co_od_find(objects->od, CO_SRDO_OD_GFC, 0)) {
        /* 0x1300 is the switch: the GFC follows it (co_srdo_od) */
        const uint8_t value = on ? 1u : 0u;
        done = co_od_put(objects->od, CO_SRDO_OD_GFC, 0, &value, 1) == 0 && gfc->enabled == on;
    } else {
        done = co_gfc_set_enabled(gfc, on);
    }
    rt_mutex_unlock(&rt->lock);
    if (!done) {
        rt_set_error(rt, "line %d: CAN-ID 0x001 (GFC) is taken by another service", line);
        return CO_RT_ERR_STATE;
    }
    return CO_RT_OK;
}

int co_rt_gfc_send(co_rt_t *rt, int line)
{
    int status;
    co_gfc_t *gfc = locked_gfc(rt, line, &status);
    if (!gfc) {
        return status;
    }
    if (!co_gfc_send(gfc)) {
        rt_set_error(rt, "line %d: GFC not sent: %s", line,
                     gfc->enabled ? "the tx queue is full" : "GFC is off (0x1300 = 0)");
        return rt_kick_unlock(rt, CO_RT_ERR_STATE);
    }
    return rt_kick_unlock(rt, CO_RT_OK);
}

int co_rt_gfc_stats(co_rt_t *rt, int line, co_gfc_stats_t *out)
{
    if (!out) {
        return CO_RT_ERR_ARGUMENT;
    }
    int status;
    co_gfc_t *gfc = locked_gfc(rt, line, &status);
    if (!gfc) {
        return status;
    }
    *out = gfc->stats;
    rt_mutex_unlock(&rt->lock);
    return CO_RT_OK;
}
