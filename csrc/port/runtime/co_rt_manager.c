/* Runtime glue of the CiA 302-2 network manager: created over the line's
 * local node (its OD) and client at the first start, its reports posted
 * as CO_EV_MANAGER, the application's answers passed on. The manager lives
 * in the stack (co_stack_manager). */
#include "co_rt_internal.h"

#include <string.h>

static void put32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

static void on_manager_event(co_manager_t *m, const co_manager_report_t *r, void *user)
{
    (void)m;
    const rt_line_t *l = user;
    const co_boot_report_t *b = &r->boot;
    uint8_t error = r->event == CO_MANAGER_EV_BOOT ? b->error : r->error;
    uint32_t a = (uint32_t)r->event | (uint32_t)error << 8 | (uint32_t)(r->mandatory ? 1 : 0) << 16 |
                 (uint32_t)r->command << 24;
    uint32_t bb = 0;
    co_frame_t detail;
    memset(&detail, 0, sizeof detail);
    /* a boot report, and a configuration request's failure, carry the entry */
    if (r->event == CO_MANAGER_EV_BOOT || r->event == CO_MANAGER_EV_CONFIGURED) {
        bb = (uint32_t)b->event | (uint32_t)b->step << 8 | (uint32_t)b->sub << 16 |
             (uint32_t)(b->matched ? 1 : 0) << 24;
        detail.len = 16;
        detail.data[0] = (uint8_t)b->index;
        detail.data[1] = (uint8_t)(b->index >> 8);
        detail.data[2] = b->state;
        detail.data[3] = (uint8_t)(b->got_length > 255 ? 255 : b->got_length);
        put32(&detail.data[4], b->expected);
        put32(&detail.data[8], b->got);
        put32(&detail.data[12], b->abort);
    }
    (void)rt_post(l, CO_EV_MANAGER, r->node_id, a, bb, detail.len ? &detail : NULL);
}

/* Under rt->lock: the line's manager, NULL with the reason set. */
static co_manager_t *manager_of(co_rt_t *rt, rt_line_t *l)
{
    co_manager_t *m = co_stack_manager(&l->stack);
    if (!m) {
        rt_set_error(rt, "line %d: no network manager runs (co_rt_manager_start first)",
                     l->index);
    }
    return m;
}

/* Room for the largest 0x1F22 concise DCF the node keeps in memory (the
 * manager copies one at a time for 0x1F25); 0 = the stack's default. */
static uint32_t concise_dcf_room(const rt_line_t *l)
{
    uint32_t room = 0;
    for (uint8_t i = 0; i < l->domain_count; i++) {
        if (l->domains[i].key >> 8 == 0x1F22 && l->domains[i].capacity > room) {
            room = l->domains[i].capacity;
        }
    }
    return room;
}

int co_rt_manager_start(co_rt_t *rt, int line, int hooks, int parallel, int retry_ms)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    if (hooks < 0 || hooks > 7 || parallel < 0 || parallel > 127 || retry_ms < 0) {
        return rt_argument_error(rt, "line %d: manager hooks %d (0..7), parallel %d (0..127), "
                                 "retry %d ms (>= 0)", line, hooks, parallel, retry_ms);
    }
    rt_mutex_lock(&rt->lock);
    co_line_set_time(&l->line, co_rt_now_us());
    int status = CO_RT_OK;
    if (!co_stack_has_node(&l->stack) || !l->has_od) {
        rt_set_error(rt, "line %d: the network manager needs a local node with an object "
                     "dictionary (0x1F80, 0x1F81..)", line);
        status = CO_RT_ERR_STATE;
    } else if (!rt_client_ready(rt, l)) {
        status = CO_RT_ERR_STATE;
    } else {
        /* made anew at each start: the slave table follows 0x1F81 as it is now */
        co_stack_manager_deinit(&l->stack);
        co_stack_manager_config_t config = {.parallel = (uint8_t)parallel,
                                            .hooks = (uint8_t)hooks,
                                            .retry_ms = (uint32_t)retry_ms,
                                            .on_event = on_manager_event, .user = l,
                                            .dcf_capacity = concise_dcf_room(l)};
        co_stack_status_t s = co_stack_manager_init(&l->stack, &config);
        if (s == CO_STACK_ERR_OD) {
            rt_set_error(rt, "line %d: node %d is no network manager: 0x1F80 bit 0 is clear "
                         "(or 0x1F80 missing)", line, co_line_node_id(&l->line));
            status = CO_RT_ERR_STATE;
        } else if (s != CO_STACK_OK) {
            rt_set_error(rt, "line %d: network manager could not start (%s)", line,
                         s == CO_STACK_ERR_NO_MEMORY ? "no memory" : "state");
            status = s == CO_STACK_ERR_NO_MEMORY ? CO_RT_ERR_NO_MEMORY : CO_RT_ERR_STATE;
        } else if (co_manager_start(co_stack_manager(&l->stack)) != CO_MANAGER_OK) {
            rt_set_error(rt, "line %d: network manager refused to start", line);
            status = CO_RT_ERR_STATE;
        }
    }
    return rt_kick_unlock(rt, status);
}

int co_rt_manager_stop(co_rt_t *rt, int line)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    co_manager_t *m = manager_of(rt, l);
    if (m) {
        co_manager_stop(m);
    }
    return rt_kick_unlock(rt, m ? CO_RT_OK : CO_RT_ERR_STATE);
}

int co_rt_manager_continue(co_rt_t *rt, int line, int what, int node_id, int done)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    if (what != CO_MANAGER_EV_UPDATE_SOFTWARE && what != CO_MANAGER_EV_UPDATE_CONFIG &&
        what != CO_MANAGER_EV_READY_OPERATIONAL) {
        return rt_argument_error(rt, "line %d: manager answer %d: %d software, %d "
                                 "configuration, %d operational", line, what,
                                 CO_MANAGER_EV_UPDATE_SOFTWARE, CO_MANAGER_EV_UPDATE_CONFIG,
                                 CO_MANAGER_EV_READY_OPERATIONAL);
    }
    if (what != CO_MANAGER_EV_READY_OPERATIONAL && (node_id < 1 || node_id > 127)) {
        return rt_argument_error(rt, "line %d: manager answer for node %d (1..127)", line,
                                 node_id);
    }
    rt_mutex_lock(&rt->lock);
    co_line_set_time(&l->line, co_rt_now_us());
    co_manager_t *m = manager_of(rt, l);
    int status = m ? CO_RT_OK : CO_RT_ERR_STATE;
    if (m) {
        bool taken = what == CO_MANAGER_EV_UPDATE_SOFTWARE
                         ? co_manager_continue_software(m, (uint8_t)node_id, done != 0)
                     : what == CO_MANAGER_EV_UPDATE_CONFIG
                         ? co_manager_continue_config(m, (uint8_t)node_id, done != 0)
                         : co_manager_continue_operational(m);
        if (!taken) {
            rt_set_error(rt, "line %d: the network manager does not wait for that answer%s",
                         line, what == CO_MANAGER_EV_READY_OPERATIONAL ? "" : " of that node");
            status = CO_RT_ERR_STATE;
        }
    }
    return rt_kick_unlock(rt, status);
}

int co_rt_manager_state(co_rt_t *rt, int line, int node_id)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    if (node_id < 0 || node_id > 127) {
        return rt_argument_error(rt, "line %d: node %d (1..127, 0 = the manager)", line,
                                 node_id);
    }
    rt_mutex_lock(&rt->lock);
    co_manager_t *m = manager_of(rt, l);
    int value = CO_RT_ERR_STATE;
    if (m) {
        value = node_id == 0 ? (int)co_manager_phase(m)
                             : (int)co_manager_slave_status(m, (uint8_t)node_id) |
                                   (int)co_manager_slave_error(m, (uint8_t)node_id) << 8;
    }
    rt_mutex_unlock(&rt->lock);
    return value;
}
