/* Runtime (see co_runtime.h): its life cycle, error text and clock.
 *
 * One pthread per runtime runs every line (co_rt_loop.c): epoll over the
 * SocketCAN sockets, one timerfd armed at the earliest deadline and one
 * eventfd for wake-ups.
 *
 * Locks (taken in this order, never the other way round):
 *   life_lock    start / stop / add_line transitions
 *   lock         lines, buses, drivers and core objects; held by the thread
 *                except while it sleeps in epoll_wait, taken briefly by
 *                add_line, host_receive and the snapshot calls
 *   host.lock    per host line: frames waiting for co_rt_host_transmit
 *   events.lock  the bounded event ring
 * mail.lock (command mailbox) and error_lock are leaves, so co_rt_command
 * never waits for the lines to be processed.
 *
 * No Python is ever called from the thread, so it runs without the GIL. */
#define _GNU_SOURCE

#include "co_rt_internal.h"

#include <errno.h>
#include <pthread.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

uint64_t co_rt_now_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

/* ================================================================ errors */

__attribute__((format(printf, 2, 3)))
void rt_set_error(co_rt_t *rt, const char *fmt, ...)
{
    va_list args;
    va_start(args, fmt);
    pthread_mutex_lock(&rt->error_lock);
    vsnprintf(rt->error, sizeof rt->error, fmt, args);
    pthread_mutex_unlock(&rt->error_lock);
    va_end(args);
}

__attribute__((format(printf, 2, 3)))
int rt_argument_error(co_rt_t *rt, const char *fmt, ...)
{
    char text[RT_ERROR_SIZE];
    va_list args;
    va_start(args, fmt);
    vsnprintf(text, sizeof text, fmt, args);
    va_end(args);
    rt_set_error(rt, "%s", text);
    return CO_RT_ERR_ARGUMENT;
}

void co_rt_last_error(co_rt_t *rt, char *buf, size_t size)
{
    if (!rt || !buf || size == 0) {
        return;
    }
    pthread_mutex_lock(&rt->error_lock);
    snprintf(buf, size, "%s", rt->error);
    pthread_mutex_unlock(&rt->error_lock);
}

const char *co_rt_status_text(int status)
{
    switch (status) {
    case CO_RT_OK: return "ok";
    case CO_RT_ERR_ARGUMENT: return "invalid argument";
    case CO_RT_ERR_NO_INTERFACE: return "no such network interface";
    case CO_RT_ERR_MTU: return "interface MTU does not fit the line mode";
    case CO_RT_ERR_SOCKET: return "socket error";
    case CO_RT_ERR_FULL: return "queue or table full";
    case CO_RT_ERR_STATE: return "not allowed in the current state";
    case CO_RT_ERR_NO_MEMORY: return "out of memory";
    case CO_RT_ERR_CLOSED: return "runtime stopped";
    case CO_RT_ERR_MODE: return "membus already open in the other mode";
    default: return status >= 0 ? "ok" : "unknown error";
    }
}

/* ================================================================ memory */

static void *heap_allocate(void *user, size_t size)
{
    (void)user;
    return malloc(size);
}

static void heap_release(void *user, void *memory, size_t size)
{
    (void)user;
    (void)size;
    free(memory);
}

const co_stack_allocator_t rt_heap = {heap_allocate, heap_release, NULL};

/* ================================================================ waiting */

void rt_cond_init_monotonic(pthread_cond_t *cond)
{
    pthread_condattr_t attr;
    pthread_condattr_init(&attr);
    pthread_condattr_setclock(&attr, CLOCK_MONOTONIC);
    pthread_cond_init(cond, &attr);
    pthread_condattr_destroy(&attr);
}

struct timespec rt_deadline_after_ms(int timeout_ms)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    ts.tv_sec += timeout_ms / 1000;
    ts.tv_nsec += (long)(timeout_ms % 1000) * 1000000L;
    if (ts.tv_nsec >= 1000000000L) {
        ts.tv_sec++;
        ts.tv_nsec -= 1000000000L;
    }
    return ts;
}

bool rt_wait_step(pthread_cond_t *cond, pthread_mutex_t *lock, int timeout_ms,
                  const struct timespec *deadline)
{
    if (timeout_ms == 0) {
        return false;
    }
    if (timeout_ms < 0) {
        pthread_cond_wait(cond, lock);
        return true;
    }
    return pthread_cond_timedwait(cond, lock, deadline) != ETIMEDOUT;
}

/* ================================================================ lifecycle */

static void rt_destroy(co_rt_t *rt)
{
    for (int i = 0; i < rt->line_count; i++) {
        rt_line_free(rt->lines[i]);
    }
    rt_membus_free_all(rt);
    rt_loop_close(rt);
    rt_events_free(&rt->events);
    pthread_mutex_destroy(&rt->mail.lock);
    pthread_mutex_destroy(&rt->done_lock);
    pthread_cond_destroy(&rt->done_ready);
    pthread_mutex_destroy(&rt->error_lock);
    pthread_mutex_destroy(&rt->lock);
    pthread_mutex_destroy(&rt->life_lock);
    free(rt);
}

co_rt_t *co_rt_new(uint32_t event_capacity)
{
    if (event_capacity > RT_MAX_EVENT_CAPACITY) {
        return NULL;
    }
    co_rt_t *rt = calloc(1, sizeof *rt);
    if (!rt) {
        return NULL;
    }
    pthread_mutex_init(&rt->life_lock, NULL);
    pthread_mutex_init(&rt->lock, NULL);
    pthread_mutex_init(&rt->error_lock, NULL);
    pthread_mutex_init(&rt->mail.lock, NULL);
    pthread_mutex_init(&rt->done_lock, NULL);
    rt_cond_init_monotonic(&rt->done_ready);
    bool events = rt_events_open(&rt->events, event_capacity ? event_capacity
                                                             : RT_DEFAULT_EVENTS);
    if (!rt_loop_open(rt) || !events) {
        rt_destroy(rt);
        return NULL;
    }
    return rt;
}

int co_rt_start(co_rt_t *rt)
{
    if (!rt) {
        return CO_RT_ERR_ARGUMENT;
    }
    int status = CO_RT_OK;
    pthread_mutex_lock(&rt->life_lock);
    if (rt->closed) {
        status = CO_RT_ERR_CLOSED;
    } else if (!rt->started) {
        /* Signals belong to the application's threads (Python's main one). */
        sigset_t all, previous;
        sigfillset(&all);
        pthread_sigmask(SIG_SETMASK, &all, &previous);
        int err = pthread_create(&rt->thread, NULL, rt_loop_main, rt);
        pthread_sigmask(SIG_SETMASK, &previous, NULL);
        if (err != 0) {
            rt_set_error(rt, "cannot start the runtime thread: %s", strerror(err));
            status = CO_RT_ERR_NO_MEMORY;
        }
        rt->started = err == 0;
    }
    pthread_mutex_unlock(&rt->life_lock);
    return status;
}

/* Wake everybody blocked in wait_events / host_transmit / transfer_wait with CLOSED. */
static void close_waiters(co_rt_t *rt)
{
    rt_transfer_waits_close(rt);
    rt_events_close(&rt->events);
    for (int i = 0; i < rt->line_count; i++) {
        rt_host_close(rt->lines[i]);
    }
}

void co_rt_stop(co_rt_t *rt)
{
    if (!rt) {
        return;
    }
    pthread_mutex_lock(&rt->life_lock);
    if (!rt->closed) {
        rt->closed = true;
        rt_mailbox_close(&rt->mail);
        pthread_mutex_lock(&rt->lock);
        rt->stopping = true;
        pthread_mutex_unlock(&rt->lock);
        if (rt->started) {
            rt_wake(rt);
            pthread_join(rt->thread, NULL);
        }
        close_waiters(rt);
    }
    pthread_mutex_unlock(&rt->life_lock);
}

static uint32_t waiter_count(co_rt_t *rt)
{
    uint32_t n = rt_events_waiters(&rt->events);
    for (int i = 0; i < rt->line_count; i++) {
        n += rt_host_waiters(rt->lines[i]);
    }
    return n;
}

void co_rt_free(co_rt_t *rt)
{
    if (!rt) {
        return;
    }
    co_rt_stop(rt);
    /* Woken waiters are on their way out; let them leave before the memory goes. */
    while (waiter_count(rt) > 0) {
        nanosleep(&(struct timespec){0, 200000L}, NULL);
    }
    rt_destroy(rt);
}
