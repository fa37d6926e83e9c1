/* Runtime (see co_runtime.h): its life cycle, error text and clock.
 *
 * One thread per runtime runs every line (co_rt_loop.c). On Linux it sleeps
 * in epoll over the SocketCAN sockets, one timerfd armed at the earliest
 * deadline and one eventfd for wake-ups; elsewhere, or on Linux with
 * CANOPENFD_PORTABLE_LOOP=1, on a condition variable until the deadline
 * (no SocketCAN lines then).
 *
 * Locks (taken in this order, never the other way round):
 *   life_lock    start / stop / add_line transitions
 *   lock         lines, buses, drivers and core objects; held by the thread
 *                except while it sleeps, taken briefly by
 *                add_line, host_receive and the snapshot calls
 *   host.lock    per host line: frames waiting for co_rt_host_transmit
 *   events.lock  the bounded event ring
 * mail.lock (command mailbox) and error_lock are leaves, so co_rt_command
 * never waits for the lines to be processed.
 *
 * No Python is ever called from the thread, so it runs without the GIL. */
#include "co_rt_internal.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

uint64_t co_rt_now_us(void)
{
    return rt_os_now_us();
}

/* ================================================================ errors */

RT_PRINTF_FORMAT(2, 3)
void rt_set_error(co_rt_t *rt, const char *fmt, ...)
{
    va_list args;
    va_start(args, fmt);
    rt_mutex_lock(&rt->error_lock);
    vsnprintf(rt->error, sizeof rt->error, fmt, args);
    rt_mutex_unlock(&rt->error_lock);
    va_end(args);
}

RT_PRINTF_FORMAT(2, 3)
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
    rt_mutex_lock(&rt->error_lock);
    snprintf(buf, size, "%s", rt->error);
    rt_mutex_unlock(&rt->error_lock);
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

uint64_t rt_deadline_after_ms(int timeout_ms)
{
    return timeout_ms < 0 ? CO_TIME_NEVER : rt_os_now_us() + (uint64_t)timeout_ms * 1000u;
}

bool rt_wait_step(rt_cond_t *cond, rt_mutex_t *lock, int timeout_ms, uint64_t deadline_us)
{
    if (timeout_ms == 0) {
        return false;
    }
    if (timeout_ms < 0) {
        rt_cond_wait(cond, lock);
        return true;
    }
    return rt_cond_wait_until(cond, lock, deadline_us);
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
    rt_mutex_destroy(&rt->mail.lock);
    rt_mutex_destroy(&rt->done_lock);
    rt_cond_destroy(&rt->done_ready);
    rt_mutex_destroy(&rt->error_lock);
    rt_mutex_destroy(&rt->lock);
    rt_mutex_destroy(&rt->life_lock);
    free(rt);
}

/* Linux: CANOPENFD_PORTABLE_LOOP=1 runs the loop that other systems use
 * (tests of that loop, and SocketCAN-free set-ups). */
static bool portable_loop_asked(void)
{
    const char *value = getenv(RT_PORTABLE_LOOP_ENV);
    return value != NULL && strcmp(value, "1") == 0;
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
    rt_mutex_init(&rt->life_lock);
    rt_mutex_init(&rt->lock);
    rt_mutex_init(&rt->error_lock);
    rt_mutex_init(&rt->mail.lock);
    rt_mutex_init(&rt->done_lock);
    rt_cond_init(&rt->done_ready);
    rt->portable_loop = !CO_RT_HAVE_SOCKETCAN || portable_loop_asked();
    bool events = rt_events_open(&rt->events,
                                 event_capacity ? event_capacity
                                                : RT_DEFAULT_EVENT_BYTES / sizeof(co_rt_event_t));
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
    rt_mutex_lock(&rt->life_lock);
    if (rt->closed) {
        status = CO_RT_ERR_CLOSED;
    } else if (!rt->started) {
        int err = rt_thread_start(&rt->thread, rt_loop_main, rt);
        if (err != 0) {
            rt_set_error(rt, "cannot start the runtime thread: %s", strerror(err));
            status = CO_RT_ERR_NO_MEMORY;
        }
        rt->started = err == 0;
    }
    rt_mutex_unlock(&rt->life_lock);
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
    rt_mutex_lock(&rt->life_lock);
    if (!rt->closed) {
        rt->closed = true;
        rt_mailbox_close(&rt->mail);
        rt_mutex_lock(&rt->lock);
        rt->stopping = true;
        rt_mutex_unlock(&rt->lock);
        if (rt->started) {
            rt_wake(rt);
            rt_thread_join(&rt->thread);
        }
        close_waiters(rt);
    }
    rt_mutex_unlock(&rt->life_lock);
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
        rt_os_sleep_us(200);
    }
    rt_destroy(rt);
}
