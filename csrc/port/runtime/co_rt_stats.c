/* Runtime: counter snapshots for the application (line.stats,
 * line.driver_stats, line.service_stats), copied under the runtime lock. */
#include "co_rt_internal.h"

#include <string.h>

int co_rt_line_stats(co_rt_t *rt, int line, co_line_stats_t *out)
{
    rt_line_t *l = rt ? rt_checked_line(rt, line, false) : NULL;
    if (!l || !out) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    *out = *co_line_stats(&l->line);
    rt_mutex_unlock(&rt->lock);
    return CO_RT_OK;
}

int co_rt_driver_stats(co_rt_t *rt, int line, co_rt_driver_stats_t *out)
{
    rt_line_t *l = rt ? rt_checked_line(rt, line, false) : NULL;
    if (!l || !out) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    const co_sc_stats_t *sc = &l->sc.sock.stats;
    *out = (co_rt_driver_stats_t){.kernel_drops = sc->kernel_drops,
                                  .error_frames = sc->error_frames,
                                  .tx_deferred = sc->tx_would_block,
                                  .tx_refused = l->sc.tx_refused,
                                  .iface_down = l->sc.down_count,
                                  .rx_frames = sc->rx_frames,
                                  .rx_calls = sc->rx_calls,
                                  .tx_frames = sc->tx_frames,
                                  .tx_calls = sc->tx_calls,
                                  .loop_wakeups = rt->wakeups};
    rt_mutex_unlock(&rt->lock);
    rt_mutex_lock(&l->host.lock);
    const rt_host_t *h = &l->host;
    out->host_pending = co_queue_count(&h->out);
    out->host_rx_waits = h->rx_waits;
    if (l->driver == CO_DRIVER_HOST) {
        out->rx_frames = h->rx_frames;
        out->rx_calls = h->rx_calls;
        out->tx_frames = h->tx_frames;
        out->tx_calls = h->tx_calls;
    }
    rt_mutex_unlock(&l->host.lock);
    return CO_RT_OK;
}

int co_rt_event_stats(co_rt_t *rt, int line, co_rt_event_stats_t *out)
{
    rt_line_t *l = rt ? rt_checked_line(rt, line, false) : NULL;
    if (!l || !out) {
        return CO_RT_ERR_ARGUMENT;
    }
    *out = rt_events_line_stats(&rt->events, line);
    return CO_RT_OK;
}

int co_rt_service_stats(co_rt_t *rt, int line, co_rt_service_stats_t *out)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l || !out) {
        return CO_RT_ERR_ARGUMENT;
    }
    memset(out, 0, sizeof *out);
    rt_mutex_lock(&rt->lock);
    co_stack_t *s = &l->stack;
    if (co_stack_pdo(s)) {
        out->pdo = co_stack_pdo(s)->stats;
    }
    if (co_stack_emcy(s)) {
        out->emcy = co_stack_emcy(s)->stats;
    }
    if (co_stack_guard_slave(s)) {
        out->guard_slave = co_stack_guard_slave(s)->stats;
    }
    if (co_stack_guard_master(s)) {
        out->guard_master = co_stack_guard_master(s)->stats;
    }
    out->emcy_consumer = co_stack_emcy_consumer(s)->stats;
    out->sync = co_stack_sync(s)->stats;
    out->time = co_stack_time(s)->stats;
    out->pdo_watched = rt_pdo_watched_frames(l);
    if (co_stack_sdo_server(s)) {
        out->sdo_server = co_stack_sdo_server(s)->stats;
    }
    if (co_stack_usdo_server(s)) {
        out->usdo_server = co_stack_usdo_server(s)->stats;
    }
    if (co_stack_usdo_client(s)) {
        out->usdo_client = co_stack_usdo_client(s)->stats;
    }
    rt_mutex_unlock(&rt->lock);
    return CO_RT_OK;
}
