/* Runtime: the thread. A turn: re-open lost interfaces that are due, apply
 * the mailbox (each command's line processed first, so timers it arms start
 * from the current time), process every line and move membus frames until
 * nothing moves (bounded rounds), hand tx frames to the drivers, arm the
 * timer at the earliest deadline. Between turns it sleeps without rt->lock
 * in one of two waiters: epoll over the sockets, a timerfd and an eventfd
 * (../linux/co_rt_wait_epoll.c, Linux), or a condition variable until the
 * deadline (co_rt_wait_portable.c, anywhere; no SocketCAN lines then). */
#include "co_rt_internal.h"

/* ================================================================ the waiter */

static void waiter_arm(co_rt_t *rt, uint64_t deadline, uint64_t now)
{
#if CO_RT_HAVE_SOCKETCAN
    if (!rt->portable_loop) {
        rt_epoll_arm(rt, deadline, now);
        return;
    }
#endif
    (void)now;
    rt_portable_arm(rt, deadline);
}

static void waiter_sleep(co_rt_t *rt)
{
#if CO_RT_HAVE_SOCKETCAN
    if (!rt->portable_loop) {
        rt_epoll_sleep(rt);
        return;
    }
#endif
    rt_portable_sleep(rt);
}

bool rt_loop_open(co_rt_t *rt)
{
    rt->armed_us = CO_TIME_NEVER;
#if CO_RT_HAVE_SOCKETCAN
    if (!rt->portable_loop) {
        return rt_epoll_open(rt);
    }
#endif
    return rt_portable_open(rt);
}

void rt_loop_close(co_rt_t *rt)
{
#if CO_RT_HAVE_SOCKETCAN
    if (!rt->portable_loop) {
        rt_epoll_close(rt);
        return;
    }
#endif
    rt_portable_close(rt);
}

/* ================================================================ wake-ups */

void rt_wake(co_rt_t *rt)
{
#if CO_RT_HAVE_SOCKETCAN
    if (!rt->portable_loop) {
        rt_epoll_wake(rt);
        return;
    }
#endif
    rt_portable_wake(rt);
}

static void arm_timer(co_rt_t *rt, uint64_t deadline, uint64_t now)
{
    /* A timer armed at or before the deadline stays: at worst it fires early
     * and that turn arms the right one. Saves a call per turn while a
     * transfer pushes its timeout later with every frame. */
    if (rt->armed_us <= deadline && rt->armed_us > now) {
        return;
    }
    waiter_arm(rt, deadline, now);
    rt->armed_us = deadline;
}

void rt_kick(co_rt_t *rt)
{
    if (rt->stopping || !rt->started) {
        return;
    }
    uint64_t now = co_rt_now_us();
    uint64_t next = CO_TIME_NEVER;
    bool wake = false;
    for (int i = 0; i < rt->line_count; i++) {
        rt_line_t *l = rt->lines[i];
        if (l->driver == CO_DRIVER_SOCKETCAN) {
            next = rt_min_u64(next, rt_socket_flush(rt, l, now));
        } else if (co_line_tx_count(&l->line) != 0) {
            wake = true;
        }
        next = rt_min_u64(next, co_timer_list_next(co_line_timers(&l->line)));
    }
    /* only ever earlier: the thread recomputes everything at its next turn */
    if (next < rt->armed_us) {
        arm_timer(rt, next, now);
    }
    if (wake) {
        rt_wake(rt);
    }
}

int rt_kick_unlock(co_rt_t *rt, int status)
{
    rt_kick(rt);
    rt_mutex_unlock(&rt->lock);
    return status;
}

/* ================================================================ transfer ends */

void rt_transfer_ended(co_rt_t *rt)
{
    rt_mutex_lock(&rt->done_lock);
    rt->done_gen++;
    rt_cond_broadcast(&rt->done_ready);
    rt_mutex_unlock(&rt->done_lock);
}

uint64_t rt_transfer_generation(co_rt_t *rt)
{
    rt_mutex_lock(&rt->done_lock);
    uint64_t gen = rt->done_gen;
    rt_mutex_unlock(&rt->done_lock);
    return gen;
}

bool rt_wait_transfer_end(co_rt_t *rt, uint64_t gen, int timeout_ms)
{
    uint64_t deadline = rt_deadline_after_ms(timeout_ms > 0 ? timeout_ms : 0);
    rt_mutex_lock(&rt->done_lock);
    while (rt->done_gen == gen && !rt->done_closed &&
           rt_wait_step(&rt->done_ready, &rt->done_lock, timeout_ms, deadline)) {
    }
    bool changed = rt->done_gen != gen;
    rt_mutex_unlock(&rt->done_lock);
    return changed;
}

void rt_transfer_waits_close(co_rt_t *rt)
{
    rt_mutex_lock(&rt->done_lock);
    rt->done_closed = true;
    rt_cond_broadcast(&rt->done_ready);
    rt_mutex_unlock(&rt->done_lock);
}

/* ================================================================ a turn */

void rt_post_new_rx(rt_line_t *l)
{
    uint32_t count = co_line_rx_count(&l->line);
    for (uint32_t i = l->rx_seen; i < count; i++) {
        rt_post(l, CO_EV_FRAME, 0, 0, 0, co_line_rx_at(&l->line, i));
    }
}

/* Process every line; frames moved over a membus are processed in further
 * rounds, bounded so a chatty bus cannot starve the event loop. */
static uint64_t run_lines(co_rt_t *rt, uint64_t now)
{
    for (int round = 0; round < RT_TRANSFER_ROUNDS; round++) {
        uint64_t next = CO_TIME_NEVER;
        for (int i = 0; i < rt->line_count; i++) {
            next = rt_min_u64(next, rt_line_step(rt->lines[i], now));
        }
        if (rt_membus_transfer(rt) == 0) {
            return next;
        }
    }
    return now;   /* frames still in flight: come back at once */
}

/* Apply what is in the mailbox now (later commands wait for the next turn). */
static void apply_mailbox(co_rt_t *rt, uint64_t now)
{
    co_rt_command_t chunk[RT_MAIL_CHUNK];
    for (uint32_t budget = RT_MAILBOX_SIZE; budget > 0;) {
        uint32_t n = rt_mailbox_take(&rt->mail, chunk,
                                     budget < RT_MAIL_CHUNK ? budget : RT_MAIL_CHUNK);
        if (n == 0) {
            return;
        }
        for (uint32_t i = 0; i < n; i++) {
            rt_command_apply(rt, &chunk[i], now);
        }
        budget -= n;
    }
}

static uint64_t flush_drivers(co_rt_t *rt, uint64_t now)
{
    uint64_t next = CO_TIME_NEVER;
    for (int i = 0; i < rt->line_count; i++) {
        rt_line_t *l = rt->lines[i];
        if (l->driver == CO_DRIVER_SOCKETCAN) {
            next = rt_min_u64(next, rt_socket_flush(rt, l, now));
        } else if (l->driver == CO_DRIVER_HOST) {
            rt_host_flush(l);
        }
    }
    return next;
}

static void iterate(co_rt_t *rt)
{
    uint64_t now = co_rt_now_us();
    rt_socket_reopen_due(rt, now);
    apply_mailbox(rt, now);
    uint64_t next = run_lines(rt, now);
    next = rt_min_u64(next, flush_drivers(rt, now));
    /* Sending may have armed timers (a service told of free tx space). */
    for (int i = 0; i < rt->line_count; i++) {
        next = rt_min_u64(next, co_timer_list_next(co_line_timers(&rt->lines[i]->line)));
    }
    arm_timer(rt, next, now);
}

/* ================================================================ the thread */

void rt_loop_main(void *arg)
{
    co_rt_t *rt = arg;
    rt_mutex_lock(&rt->lock);
    while (!rt->stopping) {
        iterate(rt);
        waiter_sleep(rt);
    }
    rt_mutex_unlock(&rt->lock);
}
