/* Runtime: the portable waiter, for systems without epoll (Windows, macOS)
 * and for Linux with CANOPENFD_PORTABLE_LOOP=1. The thread waits on a
 * condition variable until the armed deadline; rt_wake and an earlier
 * deadline (rt_kick from an application thread) signal it. Like a one-shot
 * timer, a deadline that passed is forgotten until the next arm. */
#include "co_rt_internal.h"

bool rt_portable_open(co_rt_t *rt)
{
    rt_portable_waiter_t *w = &rt->portable;
    rt_mutex_init(&w->lock);
    rt_cond_init(&w->wake);
    w->woken = false;
    w->deadline = CO_TIME_NEVER;
    return true;
}

void rt_portable_close(co_rt_t *rt)
{
    rt_mutex_destroy(&rt->portable.lock);
    rt_cond_destroy(&rt->portable.wake);
}

void rt_portable_wake(co_rt_t *rt)
{
    rt_portable_waiter_t *w = &rt->portable;
    rt_mutex_lock(&w->lock);
    w->woken = true;
    rt_cond_signal(&w->wake);
    rt_mutex_unlock(&w->lock);
}

void rt_portable_arm(co_rt_t *rt, uint64_t deadline)
{
    rt_portable_waiter_t *w = &rt->portable;
    rt_mutex_lock(&w->lock);
    bool earlier = deadline < w->deadline;
    w->deadline = deadline;
    if (earlier) {
        rt_cond_signal(&w->wake);   /* a sleeping thread waits for the old one */
    }
    rt_mutex_unlock(&w->lock);
}

void rt_portable_sleep(co_rt_t *rt)
{
    rt_portable_waiter_t *w = &rt->portable;
    rt_mutex_unlock(&rt->lock);
    rt_mutex_lock(&w->lock);
    bool fired = false;
    while (!w->woken && !fired) {
        if (w->deadline == CO_TIME_NEVER) {
            rt_cond_wait(&w->wake, &w->lock);
        } else {
            /* re-read each round: an arm may have moved the deadline */
            fired = !rt_cond_wait_until(&w->wake, &w->lock, w->deadline);
        }
    }
    w->woken = false;
    if (fired) {
        w->deadline = CO_TIME_NEVER;
    }
    rt_mutex_unlock(&w->lock);
    rt_mutex_lock(&rt->lock);
    rt->wakeups++;
    if (fired) {
        rt->armed_us = CO_TIME_NEVER;
    }
}
