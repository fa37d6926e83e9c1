/* Runtime: host-driver lines (any python-can Bus). Two Python threads move
 * the frames in batches: one hands received frames in
 * (co_rt_host_receive_frames: as many as the rx queue has room for, then it
 * waits for the runtime thread to drain the queue, so a burst pushes back
 * into python-can's own buffer instead of being dropped), one waits for
 * frames to send (co_rt_host_transmit) on a queue of its own, filled by the
 * runtime thread at the end of each turn. */
#include "co_rt_internal.h"

#include <stdlib.h>

bool rt_host_init(rt_line_t *l, uint32_t capacity)
{
    rt_host_t *h = &l->host;
    rt_mutex_init(&h->lock);
    rt_cond_init(&h->ready);
    rt_cond_init(&h->room);
    if (capacity == 0) {
        return true;
    }
    h->tx_limit = capacity - capacity / 4u;   /* the last quarter: the services' */
    h->slots = calloc(capacity, sizeof *h->slots);
    if (!h->slots) {
        return false;
    }
    co_queue_init(&h->out, h->slots, capacity);
    return true;
}

void rt_host_free(rt_line_t *l)
{
    rt_mutex_destroy(&l->host.lock);
    rt_cond_destroy(&l->host.ready);
    rt_cond_destroy(&l->host.room);
    free(l->host.slots);
}

void rt_host_flush(rt_line_t *l)
{
    rt_host_t *h = &l->host;
    co_frame_t frame;
    uint32_t moved = 0;
    rt_mutex_lock(&h->lock);
    /* The turn processed the rx queue: a receiver waiting for room may go
     * on. The generation moves even with no waiter yet: a receiver that
     * filled the queue just before this turn and is on its way to the wait
     * sees it changed and does not sleep through the room made here. */
    h->rx_gen++;
    if (h->rx_waiters > 0) {
        rt_cond_broadcast(&h->room);
    }
    if (co_line_tx_count(&l->line) == 0) {
        h->line_tx = 0;
        rt_mutex_unlock(&h->lock);
        return;
    }
    while (!co_queue_is_full(&h->out) && co_line_tx_pop(&l->line, &frame)) {
        co_queue_push(&h->out, &frame);
        moved++;
        if (l->monitor) {
            rt_post(l, CO_EV_FRAME, 0, 1, 0, &frame);
        }
    }
    h->line_tx = co_line_tx_count(&l->line);
    h->stalled = h->line_tx != 0;
    if (moved > 0 && h->waiters > 0) {
        rt_cond_broadcast(&h->ready);
    }
    rt_mutex_unlock(&h->lock);
}

void rt_host_close(rt_line_t *l)
{
    rt_host_t *h = &l->host;
    rt_mutex_lock(&h->lock);
    h->closed = true;
    rt_cond_broadcast(&h->ready);
    rt_cond_broadcast(&h->room);
    rt_mutex_unlock(&h->lock);
}

uint32_t rt_host_waiters(rt_line_t *l)
{
    rt_mutex_lock(&l->host.lock);
    uint32_t n = l->host.waiters + l->host.rx_waiters;
    rt_mutex_unlock(&l->host.lock);
    return n;
}

bool rt_host_reserve_send(rt_line_t *l)
{
    if (l->driver != CO_DRIVER_HOST) {
        return true;
    }
    rt_host_t *h = &l->host;
    rt_mutex_lock(&h->lock);
    bool room = h->posted + h->line_tx < h->tx_limit;
    if (room) {
        h->posted++;
    }
    rt_mutex_unlock(&h->lock);
    return room;
}

void rt_host_send_unreserve(rt_line_t *l)
{
    if (l->driver == CO_DRIVER_HOST) {
        rt_mutex_lock(&l->host.lock);
        l->host.posted--;
        rt_mutex_unlock(&l->host.lock);
    }
}

void rt_host_send_applied(rt_line_t *l, bool queued)
{
    if (l->driver != CO_DRIVER_HOST) {
        return;
    }
    rt_mutex_lock(&l->host.lock);
    l->host.posted--;
    l->host.line_tx += queued ? 1u : 0u;
    rt_mutex_unlock(&l->host.lock);
}

int co_rt_host_receive(co_rt_t *rt, int line, const co_frame_t *frame)
{
    rt_line_t *l = rt ? rt_checked_line(rt, line, true) : NULL;
    if (!l || !frame) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    bool closed = rt->stopping;
    bool queued = !closed && co_line_receive(&l->line, frame);
    rt_mutex_unlock(&rt->lock);
    if (closed) {
        return CO_RT_ERR_CLOSED;
    }
    if (!queued) {
        return CO_RT_ERR_FULL;   /* counted as rx overflow by the line */
    }
    rt_mutex_lock(&l->host.lock);
    l->host.rx_frames++;
    l->host.rx_calls++;
    rt_mutex_unlock(&l->host.lock);
    rt_wake(rt);
    return CO_RT_OK;
}

/* Under rt->lock: queue frames[*taken..count) while the rx queue has room. */
static int take_frames(rt_line_t *l, const co_frame_t *frames, int count, int taken)
{
    uint32_t room = co_line_rx_free(&l->line);
    while (taken < count && room > 0) {
        (void)co_line_receive(&l->line, &frames[taken]);   /* cannot fail: room */
        taken++;
        room--;
    }
    return taken;
}

int co_rt_host_receive_frames(co_rt_t *rt, int line, const co_frame_t *frames, int count,
                              int timeout_ms)
{
    rt_line_t *l = rt ? rt_checked_line(rt, line, true) : NULL;
    if (!l || !frames || count < 0) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_host_t *h = &l->host;
    uint64_t deadline = rt_deadline_after_ms(timeout_ms > 0 ? timeout_ms : 0);
    int taken = 0;
    bool waited = false;
    for (;;) {
        /* The generation before looking at the queue: room made after the
         * look bumps it, so the wait below cannot miss it. */
        rt_mutex_lock(&h->lock);
        uint32_t gen = h->rx_gen;
        rt_mutex_unlock(&h->lock);
        rt_mutex_lock(&rt->lock);
        bool closed = rt->stopping;
        int before = taken;
        if (!closed) {
            taken = take_frames(l, frames, count, taken);
        }
        rt_mutex_unlock(&rt->lock);
        if (closed) {
            return CO_RT_ERR_CLOSED;
        }
        if (taken > before) {
            rt_mutex_lock(&h->lock);
            h->rx_frames += (uint32_t)(taken - before);
            h->rx_calls += before == 0 ? 1u : 0u;
            rt_mutex_unlock(&h->lock);
            rt_wake(rt);
        }
        if (taken == count) {
            return taken;
        }
        /* Full: wait for the runtime thread to drain the queue. */
        rt_mutex_lock(&h->lock);
        if (!waited) {
            h->rx_waits++;
            waited = true;
        }
        h->rx_waiters++;
        bool in_time = true;
        while (h->rx_gen == gen && !h->closed &&
               (in_time = rt_wait_step(&h->room, &h->lock, timeout_ms, deadline))) {
        }
        h->rx_waiters--;
        closed = h->closed;
        rt_mutex_unlock(&h->lock);
        if (closed) {
            return CO_RT_ERR_CLOSED;
        }
        if (!in_time) {
            return taken;   /* timed out: the caller hands the rest in again */
        }
    }
}

int co_rt_host_transmit(co_rt_t *rt, int line, co_frame_t *frames, int max, int timeout_ms)
{
    rt_line_t *l = rt ? rt_checked_line(rt, line, true) : NULL;
    if (!l || !frames || max <= 0) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_host_t *h = &l->host;
    uint64_t deadline = rt_deadline_after_ms(timeout_ms > 0 ? timeout_ms : 0);
    rt_mutex_lock(&h->lock);
    h->waiters++;
    while (co_queue_is_empty(&h->out) && !h->closed &&
           rt_wait_step(&h->ready, &h->lock, timeout_ms, deadline)) {
    }
    int n = 0;
    while (n < max && co_queue_pop(&h->out, &frames[n])) {
        n++;
    }
    if (n > 0) {
        h->tx_frames += (uint32_t)n;
        h->tx_calls++;
    }
    bool refill = n > 0 && h->stalled;
    int result = (n == 0 && h->closed) ? CO_RT_ERR_CLOSED : n;
    h->waiters--;
    rt_mutex_unlock(&h->lock);
    if (refill) {
        rt_wake(rt);   /* the line has more frames waiting for room */
    }
    return result;
}

int co_rt_host_comm_event(co_rt_t *rt, int line, int event)
{
    rt_line_t *l = rt ? rt_checked_line(rt, line, true) : NULL;
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    if (event < CO_COMM_BUS_OFF || event > CO_COMM_BUS_OFF_RECOVERED) {
        return rt_argument_error(rt, "communication event %d unknown", event);
    }
    rt_mutex_lock(&rt->lock);
    bool closed = rt->stopping;
    if (!closed) {
        co_line_comm_event(&l->line, (co_comm_event_t)event);
    }
    rt_mutex_unlock(&rt->lock);
    return closed ? CO_RT_ERR_CLOSED : CO_RT_OK;
}
