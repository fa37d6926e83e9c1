/* Runtime glue of SYNC: every line consumes SYNC and Python hears each one
 * while it listens (rt_sync_t); the application runs the line's producer,
 * through the node's OD (0x1005/0x1006/0x1007/0x1019, as the network would
 * write them) when the node serves one, else directly. */
#include "co_rt_internal.h"

static void on_sync(uint8_t counter, void *user)
{
    rt_line_t *l = user;
    if (l->sync.events) {
        rt_post(l, CO_EV_SYNC, 0, counter, 0, NULL);
    }
}

bool rt_sync_line_init(rt_line_t *l)
{
    return co_sync_add_listener(co_stack_sync(&l->stack), on_sync, l);
}

/* Under rt->lock: write a communication entry of the node's OD the way the
 * network would (checks, then the services' handlers). */
static uint32_t od_put_u32(rt_line_t *l, uint16_t index, uint32_t value, uint32_t size)
{
    uint8_t b[4] = {(uint8_t)value, (uint8_t)(value >> 8), (uint8_t)(value >> 16),
                    (uint8_t)(value >> 24)};
    return co_od_put(&l->od, index, 0, b, size);
}

/* Under rt->lock: the producer through the node's OD; 0 or the abort code. */
static uint32_t configure_through_od(rt_line_t *l, uint32_t cob_id, uint32_t period_us,
                                     uint32_t window_us, int overflow)
{
    /* 0x1019 may change only while 0x1006 is 0 (CiA 301): stop first */
    uint32_t abort = od_put_u32(l, 0x1006, 0, 4);
    if (!abort && co_od_has_index(&l->od, 0x1019)) {
        abort = od_put_u32(l, 0x1019, (uint32_t)overflow, 1);
    }
    if (!abort && co_od_has_index(&l->od, 0x1007)) {
        abort = od_put_u32(l, 0x1007, window_us, 4);
    }
    if (!abort) {
        abort = od_put_u32(l, 0x1005, cob_id, 4);
    }
    if (!abort && period_us) {
        abort = od_put_u32(l, 0x1006, period_us, 4);
    }
    return abort;
}

int co_rt_sync_producer(co_rt_t *rt, int line, uint32_t period_us, uint32_t window_us,
                        int overflow)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    if (overflow < 0 || overflow == 1 || overflow > CO_SYNC_COUNTER_MAX) {
        return rt_argument_error(rt, "line %d: SYNC counter overflow %d: 0 (no counter) or "
                                 "2..240", line, overflow);
    }
    rt_mutex_lock(&rt->lock);
    co_line_set_time(&l->line, co_rt_now_us());
    co_sync_t *sync = co_stack_sync(&l->stack);
    uint32_t id = sync->config.cob_id & 0x7FFu;
    uint32_t cob_id = period_us ? (id | CO_SYNC_PRODUCER_BIT) : id;
    if (sync->od) {
        uint32_t abort = configure_through_od(l, cob_id, period_us, window_us, overflow);
        if (abort) {
            rt_set_error(rt, "line %d: SYNC producer: the node's OD refused the SYNC "
                         "parameters (abort 0x%08X)", line, (unsigned)abort);
            return rt_kick_unlock(rt, CO_RT_ERR_ARGUMENT);
        }
    } else {
        co_sync_config_t config = {.cob_id = cob_id,
                                   .period_us = period_us,
                                   .window_us = window_us,
                                   .overflow = (uint8_t)overflow};
        co_sync_configure(sync, &config);
    }
    return rt_kick_unlock(rt, CO_RT_OK);
}

int co_rt_sync_listen(co_rt_t *rt, int line, int listen)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    l->sync.events = listen != 0;
    rt_mutex_unlock(&rt->lock);
    return CO_RT_OK;
}
