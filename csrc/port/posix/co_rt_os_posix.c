/* The runtime's OS layer on POSIX systems (Linux, macOS): pthreads, the
 * monotonic clock, pread/pwrite. See co_rt_os.h. */
#if defined(__linux__)
#define _GNU_SOURCE   /* pread/pwrite and pthread_sigmask under -std=c99 */
#endif

#include "co_rt_os.h"

#include <errno.h>
#include <signal.h>
#include <stdlib.h>
#include <stdint.h>
#include <string.h>
#include <sys/mman.h>
#include <time.h>
#include <unistd.h>

void rt_mutex_init(rt_mutex_t *m)
{
    pthread_mutex_init(m, NULL);
}

void rt_mutex_destroy(rt_mutex_t *m)
{
    pthread_mutex_destroy(m);
}

void rt_cond_init(rt_cond_t *c)
{
#if defined(__APPLE__)
    /* macOS has no pthread_condattr_setclock: its timed waits are relative
     * (pthread_cond_timedwait_relative_np below), so no clock is chosen. */
    pthread_cond_init(c, NULL);
#else
    pthread_condattr_t attr;
    pthread_condattr_init(&attr);
    pthread_condattr_setclock(&attr, CLOCK_MONOTONIC);
    pthread_cond_init(c, &attr);
    pthread_condattr_destroy(&attr);
#endif
}

void rt_cond_destroy(rt_cond_t *c)
{
    pthread_cond_destroy(c);
}

void rt_cond_wait(rt_cond_t *c, rt_mutex_t *m)
{
    pthread_cond_wait(c, m);
}

bool rt_cond_wait_until(rt_cond_t *c, rt_mutex_t *m, uint64_t deadline_us)
{
    uint64_t now = rt_os_now_us();
    if (now >= deadline_us) {
        return false;
    }
#if defined(__APPLE__)
    uint64_t left = deadline_us - now;
    struct timespec rel = {(time_t)(left / 1000000u), (long)(left % 1000000u) * 1000L};
    return pthread_cond_timedwait_relative_np(c, m, &rel) != ETIMEDOUT;
#else
    /* same clock as rt_os_now_us, chosen in rt_cond_init */
    struct timespec at = {(time_t)(deadline_us / 1000000u),
                          (long)(deadline_us % 1000000u) * 1000L};
    return pthread_cond_timedwait(c, m, &at) != ETIMEDOUT;
#endif
}

static void *thread_entry(void *arg)
{
    rt_thread_t *t = arg;
    t->main(t->arg);
    return NULL;
}

int rt_thread_start(rt_thread_t *t, void (*main)(void *arg), void *arg)
{
    t->main = main;
    t->arg = arg;
    /* Signals belong to the application's threads (Python's main one). */
    sigset_t all, previous;
    sigfillset(&all);
    pthread_sigmask(SIG_SETMASK, &all, &previous);
    int err = pthread_create(&t->id, NULL, thread_entry, t);
    pthread_sigmask(SIG_SETMASK, &previous, NULL);
    return err;
}

void rt_thread_join(rt_thread_t *t)
{
    pthread_join(t->id, NULL);
}

uint64_t rt_os_now_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

void rt_os_sleep_us(uint32_t us)
{
    struct timespec ts = {(time_t)(us / 1000000u), (long)(us % 1000000u) * 1000L};
    nanosleep(&ts, NULL);
}

int64_t rt_os_pread(int fd, void *buf, uint32_t n, uint64_t offset)
{
    return (int64_t)pread(fd, buf, n, (off_t)offset);
}

int64_t rt_os_pwrite(int fd, const void *buf, uint32_t n, uint64_t offset)
{
    return (int64_t)pwrite(fd, buf, n, (off_t)offset);
}

void rt_os_discard(void *p, size_t n)
{
    long page = sysconf(_SC_PAGESIZE);
    if (page <= 0 || n == 0) {
        return;
    }
    uintptr_t mask = (uintptr_t)page - 1u;
    uintptr_t start = ((uintptr_t)p + mask) & ~mask;   /* whole pages inside only */
    uintptr_t end = ((uintptr_t)p + n) & ~mask;
    if (end > start) {
        (void)madvise((void *)start, end - start, MADV_DONTNEED);
    }
}

char *rt_os_strdup(const char *s)
{
    size_t n = strlen(s) + 1;
    char *copy = malloc(n);
    if (copy) {
        memcpy(copy, s, n);
    }
    return copy;
}
