/* The runtime's operating-system layer: the few things it needs from the OS
 * (mutex, condition variable with a monotonic timed wait, a thread, a
 * monotonic clock, positional file I/O), one implementation per OS:
 * csrc/port/posix/co_rt_os_posix.c (Linux, macOS) and
 * csrc/port/windows/co_rt_os_win32.c. The lock calls are inline: the
 * thread takes them on every turn and every posted event.
 *
 * Also what the compilers differ in: printf-format checks and atomics. */
#ifndef CO_RT_OS_H
#define CO_RT_OS_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#if defined(_WIN32)
#ifndef WIN32_LEAN_AND_MEAN
#define WIN32_LEAN_AND_MEAN
#endif
#ifndef NOMINMAX
#define NOMINMAX   /* no min/max macros in the runtime's files */
#endif
#include <windows.h>
#else
#include <pthread.h>
#endif

/* SocketCAN and the epoll waiter exist on Linux only. */
#if defined(__linux__)
#define CO_RT_HAVE_SOCKETCAN 1
#else
#define CO_RT_HAVE_SOCKETCAN 0
#endif

#if defined(__GNUC__) || defined(__clang__)
#define RT_PRINTF_FORMAT(fmt, args) __attribute__((format(printf, fmt, args)))
#else
#define RT_PRINTF_FORMAT(fmt, args)
#endif

/* ---------------------------------------------------------------- locks */

#if defined(_WIN32)
typedef SRWLOCK rt_mutex_t;
typedef CONDITION_VARIABLE rt_cond_t;
typedef struct rt_thread {
    HANDLE handle;
    void (*main)(void *arg);
    void *arg;
} rt_thread_t;

static inline void rt_mutex_lock(rt_mutex_t *m) { AcquireSRWLockExclusive(m); }
static inline void rt_mutex_unlock(rt_mutex_t *m) { ReleaseSRWLockExclusive(m); }
static inline void rt_cond_signal(rt_cond_t *c) { WakeConditionVariable(c); }
static inline void rt_cond_broadcast(rt_cond_t *c) { WakeAllConditionVariable(c); }
#else
typedef pthread_mutex_t rt_mutex_t;
typedef pthread_cond_t rt_cond_t;
typedef struct rt_thread {
    pthread_t id;
    void (*main)(void *arg);
    void *arg;
} rt_thread_t;

static inline void rt_mutex_lock(rt_mutex_t *m) { pthread_mutex_lock(m); }
static inline void rt_mutex_unlock(rt_mutex_t *m) { pthread_mutex_unlock(m); }
static inline void rt_cond_signal(rt_cond_t *c) { pthread_cond_signal(c); }
static inline void rt_cond_broadcast(rt_cond_t *c) { pthread_cond_broadcast(c); }
#endif

void rt_mutex_init(rt_mutex_t *m);
void rt_mutex_destroy(rt_mutex_t *m);
/* Timed waits of a condition variable measure on the monotonic clock. */
void rt_cond_init(rt_cond_t *c);
void rt_cond_destroy(rt_cond_t *c);
void rt_cond_wait(rt_cond_t *c, rt_mutex_t *m);
/* Wait until signalled or until rt_os_now_us() reaches deadline_us (wake-ups
 * may be spurious); false once the deadline has passed. */
bool rt_cond_wait_until(rt_cond_t *c, rt_mutex_t *m, uint64_t deadline_us);

/* ---------------------------------------------------------------- thread */

/* Start main(arg) on a new thread (POSIX: with every signal blocked, they
 * belong to the application's threads); 0 or an errno value. */
int rt_thread_start(rt_thread_t *t, void (*main)(void *arg), void *arg);
void rt_thread_join(rt_thread_t *t);

/* ---------------------------------------------------------------- time */

/* Monotonic microseconds (co_rt_now_us). */
uint64_t rt_os_now_us(void);
void rt_os_sleep_us(uint32_t us);

/* ---------------------------------------------------------------- files */

/* Read / write at an offset without moving a shared file position (client
 * file transfers); bytes moved, or -1 with errno set. */
int64_t rt_os_pread(int fd, void *buf, uint32_t n, uint64_t offset);
int64_t rt_os_pwrite(int fd, const void *buf, uint32_t n, uint64_t offset);
/* strdup is POSIX, not ISO C. NULL when out of memory. */
char *rt_os_strdup(const char *s);
/* Give the whole pages inside [p, p + n) of heap memory back to the system
 * (their contents are lost; the memory stays usable and reads as zero or as
 * before): a buffer a burst made resident stops counting once drained.
 * Advisory: may do nothing (Windows does). */
void rt_os_discard(void *p, size_t n);

/* ---------------------------------------------------------------- atomics */

/* lines[] is published with a release store of the count, read with an
 * acquire load by callers that do not take the runtime lock. */
#if defined(_MSC_VER) && !defined(__clang__)
#include <intrin.h>
static inline int rt_atomic_load_acquire(const int *p)
{
    /* an interlocked no-op: a full barrier on every architecture MSVC targets */
    return (int)_InterlockedOr((volatile long *)(void *)(uintptr_t)p, 0);
}
static inline void rt_atomic_store_release(int *p, int v)
{
    _InterlockedExchange((volatile long *)p, (long)v);
}
#else
static inline int rt_atomic_load_acquire(const int *p)
{
    return __atomic_load_n(p, __ATOMIC_ACQUIRE);
}
static inline void rt_atomic_store_release(int *p, int v)
{
    __atomic_store_n(p, v, __ATOMIC_RELEASE);
}
#endif

#endif
