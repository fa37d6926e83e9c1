/* Runtime glue of the LSS master: the line's co_stack master, set up at the
 * first request; a request's end is kept in rt_lss_t and posted as
 * CO_EV_LSS, the application reads it with co_rt_lss_result. */
#include "co_rt_internal.h"

#include <string.h>

static void on_done(co_lss_master_t *master, const co_lss_master_result_t *result, void *user)
{
    (void)master;
    rt_line_t *l = user;
    l->lss.result = *result;
    l->lss.finished = true;
    rt_post(l, CO_EV_LSS, 0, (uint32_t)result->request, (uint32_t)result->status, NULL);
}

/* Values the request needs, checked before anything is sent. */
static int check_request(co_rt_t *rt, int line, const co_rt_lss_request_t *r)
{
    const uint32_t *v = r->value;
    if (r->timeout_ms < 0 || r->timeout_ms > 60000) {
        return rt_argument_error(rt, "line %d: LSS step timeout %d ms: 0..60000", line,
                                 r->timeout_ms);
    }
    int timeout_ms = r->timeout_ms ? r->timeout_ms : 100;
    if (r->settle_ms < 0 || r->settle_ms > timeout_ms) {
        return rt_argument_error(rt, "line %d: LSS settle time %d ms: 0..%d (the step timeout)",
                                 line, r->settle_ms, timeout_ms);
    }
    switch (r->kind) {
    case CO_RT_LSS_SWITCH_GLOBAL:
        if (v[0] > CO_LSS_STATE_CONFIGURATION) {
            return rt_argument_error(rt, "line %d: LSS state %u: 0 waiting, 1 configuration",
                                     line, (unsigned)v[0]);
        }
        return CO_RT_OK;
    case CO_RT_LSS_ACTIVATE_BIT_TIMING:
        if (v[0] > 0xFFFFu) {
            return rt_argument_error(rt, "line %d: LSS switch delay %u ms: 0..65535", line,
                                     (unsigned)v[0]);
        }
        return CO_RT_OK;
    case CO_LSS_REQ_CONFIGURE_NODE_ID:
        if (v[0] > 0xFFu || !co_lss_node_id_valid((uint8_t)v[0])) {
            return rt_argument_error(rt, "line %d: LSS node-id %u: 1..127 or 255", line,
                                     (unsigned)v[0]);
        }
        return CO_RT_OK;
    case CO_LSS_REQ_CONFIGURE_BIT_TIMING:
        if (v[0] > 0xFFu || v[1] > 0xFFu) {
            return rt_argument_error(rt, "line %d: LSS bit timing table %u index %u: 0..255 "
                                     "each", line, (unsigned)v[0], (unsigned)v[1]);
        }
        return CO_RT_OK;
    case CO_LSS_REQ_INQUIRE:
        if (v[0] < CO_LSS_CS_INQUIRE_VENDOR || v[0] > CO_LSS_CS_INQUIRE_NODE_ID) {
            return rt_argument_error(rt, "line %d: LSS inquire 0x%X: 0x5A..0x5E", line,
                                     (unsigned)v[0]);
        }
        return CO_RT_OK;
    case CO_LSS_REQ_IDENTIFY_REMOTE:
    case CO_LSS_REQ_SCAN:
        if (v[2] > v[3] || v[4] > v[5]) {
            return rt_argument_error(rt, "line %d: LSS ranges revision 0x%X..0x%X, serial "
                                     "0x%X..0x%X: low above high", line, (unsigned)v[2],
                                     (unsigned)v[3], (unsigned)v[4], (unsigned)v[5]);
        }
        return CO_RT_OK;
    case CO_LSS_REQ_FASTSCAN:
        if (r->node_id_count < 0 || r->node_id_count > 127) {
            return rt_argument_error(rt, "line %d: LSS fast scan with %d node-ids: 0..127 "
                                     "(0: identify one device only)", line, r->node_id_count);
        }
        if (r->fs_kind[0] == CO_LSS_FS_SKIP) {
            return rt_argument_error(rt, "line %d: LSS fast scan: the vendor-ID cannot be "
                                     "skipped (every scan starts with it)", line);
        }
        for (int i = 0; i < 4; i++) {
            if (r->fs_kind[i] > CO_LSS_FS_MATCH) {
                return rt_argument_error(rt, "line %d: LSS fast scan filter %u for part %d: "
                                         "0 scan, 1 skip, 2 match", line,
                                         (unsigned)r->fs_kind[i], i);
            }
        }
        for (int i = 0; i < r->node_id_count; i++) {
            if (r->node_ids[i] < 1u || r->node_ids[i] > 127u) {
                return rt_argument_error(rt, "line %d: LSS fast scan node-id %u (entry %d): "
                                         "1..127", line, r->node_ids[i], i);
            }
        }
        return CO_RT_OK;
    case CO_LSS_REQ_SWITCH_SELECTIVE:
    case CO_LSS_REQ_STORE:
    case CO_LSS_REQ_IDENTIFY_NON_CONFIGURED:
        return CO_RT_OK;
    default:
        return rt_argument_error(rt, "line %d: unknown LSS request %d", line, r->kind);
    }
}

static bool start(rt_line_t *l, co_lss_master_t *m, const co_rt_lss_request_t *r)
{
    const uint32_t *v = r->value;
    switch (r->kind) {
    case CO_RT_LSS_SWITCH_GLOBAL:
        return co_lss_master_switch_global(m, (co_lss_state_t)v[0]);
    case CO_RT_LSS_ACTIVATE_BIT_TIMING:
        return co_lss_master_activate_bit_timing(m, (uint16_t)v[0]);
    case CO_LSS_REQ_SWITCH_SELECTIVE: {
        co_lss_address_t a = {{v[0], v[1], v[2], v[3]}};
        return co_lss_master_switch_selective(m, &a);
    }
    case CO_LSS_REQ_CONFIGURE_NODE_ID:
        return co_lss_master_configure_node_id(m, (uint8_t)v[0]);
    case CO_LSS_REQ_CONFIGURE_BIT_TIMING:
        return co_lss_master_configure_bit_timing(m, (uint8_t)v[0], (uint8_t)v[1]);
    case CO_LSS_REQ_STORE:
        return co_lss_master_store(m);
    case CO_LSS_REQ_INQUIRE:
        return co_lss_master_inquire(m, (uint8_t)v[0]);
    case CO_LSS_REQ_IDENTIFY_REMOTE:
        return co_lss_master_identify_remote(m, v[0], v[1], v[2], v[3], v[4], v[5]);
    case CO_LSS_REQ_IDENTIFY_NON_CONFIGURED:
        return co_lss_master_identify_non_configured(m);
    case CO_LSS_REQ_FASTSCAN: {
        co_lss_fastscan_filter_t filter;
        memcpy(filter.kind, r->fs_kind, sizeof filter.kind);
        memcpy(filter.match, r->fs_match, sizeof filter.match);
        memcpy(l->lss.node_ids, r->node_ids, (size_t)r->node_id_count);
        return co_lss_master_fastscan_filtered(m, &filter, l->lss.node_ids,
                                               (uint32_t)r->node_id_count, l->lss.devices,
                                               r->node_id_count ? 127u : 1u);
    }
    case CO_LSS_REQ_SCAN:
    default:
        return co_lss_master_scan(m, v[0], v[1], v[2], v[3], v[4], v[5], l->lss.devices, 127);
    }
}

int co_rt_lss_start(co_rt_t *rt, int line, const co_rt_lss_request_t *request)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l || !request) {
        return CO_RT_ERR_ARGUMENT;
    }
    int status = check_request(rt, line, request);
    if (status != CO_RT_OK) {
        return status;
    }
    rt_mutex_lock(&rt->lock);
    co_line_set_time(&l->line, co_rt_now_us());
    co_lss_master_t *m = co_stack_lss_master(&l->stack);
    if (!m) {
        if (co_stack_lss_master_init(&l->stack, 0, on_done, l) != CO_STACK_OK) {
            rt_set_error(rt, "line %d: the LSS master cannot start: 0x7E4 is taken", line);
            return rt_kick_unlock(rt, CO_RT_ERR_STATE);
        }
        m = co_stack_lss_master(&l->stack);
    }
    if (co_lss_master_busy(m)) {
        rt_set_error(rt, "line %d: an LSS request is running (one at a time)", line);
        return rt_kick_unlock(rt, CO_RT_ERR_STATE);
    }
    (void)co_lss_master_set_timeout(m, (uint32_t)request->timeout_ms);
    if (request->settle_ms > 0) {
        (void)co_lss_master_set_settle(m, (uint32_t)request->settle_ms * 1000u);
    }
    if (!start(l, m, request)) {
        rt_set_error(rt, "line %d: LSS request %d refused (tx queue full?)", line,
                     request->kind);
        status = CO_RT_ERR_FULL;
    }
    return rt_kick_unlock(rt, status);
}

int co_rt_lss_cancel(co_rt_t *rt, int line)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    co_lss_master_t *m = co_stack_lss_master(&l->stack);
    if (m) {
        co_lss_master_cancel(m);    /* no-op when idle; else on_done posts CANCELLED */
    }
    return rt_kick_unlock(rt, CO_RT_OK);
}

int co_rt_lss_result(co_rt_t *rt, int line, co_lss_master_result_t *out,
                     co_rt_lss_device_t *devices, int max)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l || !out || max < 0 || (max > 0 && !devices)) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    int count = CO_RT_ERR_STATE;
    if (l->lss.finished) {
        *out = l->lss.result;
        uint32_t found = out->request == CO_LSS_REQ_FASTSCAN || out->request == CO_LSS_REQ_SCAN
                             ? out->found : 0u;
        count = (int)(found < (uint32_t)max ? found : (uint32_t)max);
        for (int i = 0; i < count; i++) {
            memcpy(devices[i].address, l->lss.devices[i].address.part,
                   sizeof devices[i].address);
            devices[i].node_id = l->lss.devices[i].node_id;
        }
    }
    rt_mutex_unlock(&rt->lock);
    if (count == CO_RT_ERR_STATE) {
        rt_set_error(rt, "line %d: no LSS request finished yet", line);
    }
    return count;
}

int co_rt_lss_stats(co_rt_t *rt, int line, co_lss_master_stats_t *out)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l || !out) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    co_lss_master_t *m = co_stack_lss_master(&l->stack);
    if (m) {
        *out = *co_lss_master_stats(m);
    } else {
        memset(out, 0, sizeof *out);
    }
    rt_mutex_unlock(&rt->lock);
    return CO_RT_OK;
}

/* ---------------------------------------------------------------- the local node's slave */

/* Slave events carry node 255, whatever the node's id (it may change). */
static uint8_t own_id(const rt_line_t *l)
{
    (void)l;
    return CO_LSS_NODE_ID_UNCONFIGURED;
}

static bool slave_check_bit_timing(co_lss_slave_t *slave, uint8_t selector, uint8_t index,
                                   void *user)
{
    (void)slave;
    rt_line_t *l = user;
    bool ok = selector == 0u && index < 32u && (l->lss.bit_timings >> index) & 1u;
    if (ok) {
        rt_post(l, CO_EV_LSS, own_id(l), CO_RT_LSS_SLAVE_BIT_TIMING,
                (uint32_t)selector << 8 | index, NULL);
    }
    return ok;
}

static void slave_activate(co_lss_slave_t *slave, uint16_t delay_ms, void *user)
{
    (void)slave;
    rt_line_t *l = user;
    rt_post(l, CO_EV_LSS, own_id(l), CO_RT_LSS_SLAVE_ACTIVATE, delay_ms, NULL);
}

static uint8_t slave_store(co_lss_slave_t *slave, uint8_t node_id, void *user)
{
    (void)slave;
    rt_line_t *l = user;
    if (!l->lss.store_by_app) {
        return CO_LSS_ERR_STORE_NOT_SUPPORTED;
    }
    /* The thread never waits for Python: the answer comes with
     * co_rt_lss_slave_answer once the application has written it. */
    if (!rt_post(l, CO_EV_LSS, own_id(l), CO_RT_LSS_SLAVE_STORE, node_id, NULL)) {
        return CO_LSS_ERR_STORE_MEDIA;   /* nobody will hear of it */
    }
    return CO_LSS_ERR_LATER;
}

static void slave_state(co_lss_slave_t *slave, co_lss_state_t state, void *user)
{
    (void)slave;
    rt_line_t *l = user;
    rt_post(l, CO_EV_LSS, own_id(l), CO_RT_LSS_SLAVE_STATE, (uint32_t)state, NULL);
}

/* co_stack set the node up with the node-id LSS gave it (the gateway heard
 * it through the line's node_id_changed). */
static void slave_configured(co_lss_slave_t *slave, uint8_t node_id, void *user)
{
    (void)slave;
    rt_line_t *l = user;
    rt_post(l, CO_EV_LSS, own_id(l), CO_RT_LSS_SLAVE_CONFIGURED, node_id, NULL);
}

const co_lss_slave_indications_t *rt_lss_slave_indications(rt_line_t *l)
{
    l->lss.slave_ind = (co_lss_slave_indications_t){slave_check_bit_timing, slave_activate,
                                                    slave_store, slave_state,
                                                    slave_configured};
    return &l->lss.slave_ind;
}

/* The slave, under rt->lock; NULL with the error set. */
static co_lss_slave_t *slave_of(co_rt_t *rt, rt_line_t *l)
{
    co_lss_slave_t *s = co_stack_lss_slave(&l->stack);
    if (!s) {
        rt_set_error(rt, "line %d: no LSS slave (a local node whose OD has the serial "
                     "number 0x1018:04)", l->index);
    }
    return s;
}

int co_rt_lss_slave_config(co_rt_t *rt, int line, int store, uint32_t bit_timings)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    l->lss.store_by_app = store != 0;
    l->lss.bit_timings = bit_timings;
    rt_mutex_unlock(&rt->lock);
    return CO_RT_OK;
}

int co_rt_lss_slave_answer(co_rt_t *rt, int line, int error)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    if (error < CO_LSS_ERR_OK || error > CO_LSS_ERR_STORE_MEDIA) {
        return rt_argument_error(rt, "line %d: LSS store answer %d: 0 stored, 1 not "
                                 "supported, 2 storage media error", line, error);
    }
    rt_mutex_lock(&rt->lock);
    co_line_set_time(&l->line, co_rt_now_us());
    co_lss_slave_t *s = slave_of(rt, l);
    int status = CO_RT_ERR_STATE;
    if (s && co_lss_slave_store_answer(s, (uint8_t)error)) {
        status = CO_RT_OK;
    } else if (s) {
        rt_set_error(rt, "line %d: no LSS store request waits for an answer", line);
    }
    return rt_kick_unlock(rt, status);
}

int co_rt_lss_slave_info(co_rt_t *rt, int line, uint8_t out[4])
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l || !out) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    co_lss_slave_t *s = slave_of(rt, l);
    if (s) {
        out[0] = (uint8_t)co_lss_slave_state(s);
        out[1] = co_lss_slave_active_node_id(s);
        out[2] = co_lss_slave_pending_node_id(s);
        out[3] = co_lss_slave_persistent_node_id(s);
    }
    rt_mutex_unlock(&rt->lock);
    return s ? CO_RT_OK : CO_RT_ERR_STATE;
}
