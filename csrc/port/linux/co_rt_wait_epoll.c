/* Runtime: the Linux waiter. The thread sleeps in epoll over the SocketCAN
 * sockets, a timerfd armed (absolute, monotonic) at the earliest deadline
 * and an eventfd that rt_wake writes. Needed for SocketCAN lines; the
 * portable waiter serves the rest everywhere. */
#define _GNU_SOURCE

#include "co_rt_internal.h"

#include <string.h>
#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <sys/timerfd.h>
#include <time.h>
#include <unistd.h>

static bool watch_fd(rt_epoll_waiter_t *w, int fd, rt_tag_t *tag)
{
    struct epoll_event ev = {.events = EPOLLIN, .data.ptr = tag};
    return epoll_ctl(w->epfd, EPOLL_CTL_ADD, fd, &ev) == 0;
}

bool rt_epoll_open(co_rt_t *rt)
{
    rt_epoll_waiter_t *w = &rt->epoll;
    w->epfd = epoll_create1(EPOLL_CLOEXEC);
    w->wakefd = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
    w->timerfd = timerfd_create(CLOCK_MONOTONIC, TFD_NONBLOCK | TFD_CLOEXEC);
    w->wake_tag = (rt_tag_t){TAG_WAKE, NULL};
    w->timer_tag = (rt_tag_t){TAG_TIMER, NULL};
    return w->epfd >= 0 && w->wakefd >= 0 && w->timerfd >= 0 &&
           watch_fd(w, w->wakefd, &w->wake_tag) && watch_fd(w, w->timerfd, &w->timer_tag);
}

static void close_fd(int fd)
{
    if (fd >= 0) {
        close(fd);
    }
}

void rt_epoll_close(co_rt_t *rt)
{
    close_fd(rt->epoll.epfd);
    close_fd(rt->epoll.wakefd);
    close_fd(rt->epoll.timerfd);
}

void rt_epoll_wake(co_rt_t *rt)
{
    const uint64_t one = 1;
    /* EAGAIN only when the counter is saturated: the thread wakes anyway. */
    ssize_t done = write(rt->epoll.wakefd, &one, sizeof one);
    (void)done;
}

void rt_epoll_arm(co_rt_t *rt, uint64_t deadline, uint64_t now)
{
    struct itimerspec spec;
    memset(&spec, 0, sizeof spec);
    if (deadline != CO_TIME_NEVER) {
        uint64_t at = deadline > now ? deadline : now;
        spec.it_value.tv_sec = (time_t)(at / 1000000u);
        spec.it_value.tv_nsec = (long)(at % 1000000u) * 1000L;
        if (spec.it_value.tv_sec == 0 && spec.it_value.tv_nsec == 0) {
            spec.it_value.tv_nsec = 1;   /* zero would disarm */
        }
    }
    timerfd_settime(rt->epoll.timerfd, TFD_TIMER_ABSTIME, &spec, NULL);
}

static void drain_fd(int fd)
{
    uint64_t value;
    ssize_t done = read(fd, &value, sizeof value);
    (void)done;
}

static void handle_ready(co_rt_t *rt, const struct epoll_event *ev)
{
    const rt_tag_t *tag = ev->data.ptr;
    switch (tag->kind) {
    case TAG_WAKE:
        drain_fd(rt->epoll.wakefd);
        break;
    case TAG_TIMER:
        drain_fd(rt->epoll.timerfd);
        rt->armed_us = CO_TIME_NEVER;
        break;
    case TAG_SOCKET:
        rt_socket_ready(rt, tag->line, ev->events);
        break;
    default:
        break;
    }
}

void rt_epoll_sleep(co_rt_t *rt)
{
    struct epoll_event ready[RT_EPOLL_BATCH];
    rt_mutex_unlock(&rt->lock);
    int n = epoll_wait(rt->epoll.epfd, ready, RT_EPOLL_BATCH, -1);
    rt_mutex_lock(&rt->lock);
    rt->wakeups += n > 0;
    for (int i = 0; i < n; i++) {
        handle_ready(rt, &ready[i]);
    }
}
