/* The runtime's OS layer on Windows: SRW locks, condition variables,
 * _beginthreadex, QueryPerformanceCounter, positional ReadFile/WriteFile on
 * the CRT descriptor's handle. See co_rt_os.h. */
#include "co_rt_os.h"

#include <errno.h>
#include <io.h>
#include <process.h>
#include <stdlib.h>
#include <string.h>

void rt_mutex_init(rt_mutex_t *m)
{
    InitializeSRWLock(m);
}

void rt_mutex_destroy(rt_mutex_t *m)
{
    (void)m;   /* an SRW lock holds no resources */
}

void rt_cond_init(rt_cond_t *c)
{
    InitializeConditionVariable(c);
}

void rt_cond_destroy(rt_cond_t *c)
{
    (void)c;   /* a condition variable holds no resources */
}

void rt_cond_wait(rt_cond_t *c, rt_mutex_t *m)
{
    SleepConditionVariableSRW(c, m, INFINITE, 0);
}

bool rt_cond_wait_until(rt_cond_t *c, rt_mutex_t *m, uint64_t deadline_us)
{
    uint64_t now = rt_os_now_us();
    if (now >= deadline_us) {
        return false;
    }
    /* whole milliseconds, rounded up so a wait never ends before the
     * deadline (which would spin on a short remainder) */
    uint64_t ms = (deadline_us - now + 999u) / 1000u;
    DWORD wait_ms = ms >= INFINITE ? INFINITE - 1 : (DWORD)ms;
    if (!SleepConditionVariableSRW(c, m, wait_ms, 0)) {
        return rt_os_now_us() < deadline_us;   /* ERROR_TIMEOUT */
    }
    return true;
}

static unsigned __stdcall thread_entry(void *arg)
{
    rt_thread_t *t = arg;
    t->main(t->arg);
    return 0;
}

int rt_thread_start(rt_thread_t *t, void (*main)(void *arg), void *arg)
{
    t->main = main;
    t->arg = arg;
    uintptr_t handle = _beginthreadex(NULL, 0, thread_entry, t, 0, NULL);
    if (handle == 0) {
        return errno ? errno : EAGAIN;
    }
    t->handle = (HANDLE)handle;
    return 0;
}

void rt_thread_join(rt_thread_t *t)
{
    WaitForSingleObject(t->handle, INFINITE);
    CloseHandle(t->handle);
}

uint64_t rt_os_now_us(void)
{
    static LARGE_INTEGER frequency;   /* constant after boot; a racy first write stores the same value */
    LARGE_INTEGER count;
    if (frequency.QuadPart == 0) {
        QueryPerformanceFrequency(&frequency);
    }
    QueryPerformanceCounter(&count);
    uint64_t ticks = (uint64_t)count.QuadPart;
    uint64_t hz = (uint64_t)frequency.QuadPart;
    /* seconds and remainder apart: ticks * 1000000 would overflow after ~10 days at 10 MHz */
    return ticks / hz * 1000000u + ticks % hz * 1000000u / hz;
}

void rt_os_sleep_us(uint32_t us)
{
    Sleep((us + 999u) / 1000u);
}

/* ReadFile/WriteFile with an offset in the OVERLAPPED structure read and
 * write at that offset on a handle opened for synchronous I/O. */
static int64_t positional_io(int fd, void *buf, uint32_t n, uint64_t offset, bool write)
{
    intptr_t os_handle = _get_osfhandle(fd);
    if (os_handle == -1) {
        errno = EBADF;
        return -1;
    }
    OVERLAPPED at;
    memset(&at, 0, sizeof at);
    at.Offset = (DWORD)(offset & 0xFFFFFFFFu);
    at.OffsetHigh = (DWORD)(offset >> 32);
    DWORD moved = 0;
    BOOL ok = write ? WriteFile((HANDLE)os_handle, buf, n, &moved, &at)
                    : ReadFile((HANDLE)os_handle, buf, n, &moved, &at);
    if (!ok) {
        if (!write && GetLastError() == ERROR_HANDLE_EOF) {
            return 0;
        }
        errno = EIO;
        return -1;
    }
    return (int64_t)moved;
}

int64_t rt_os_pread(int fd, void *buf, uint32_t n, uint64_t offset)
{
    return positional_io(fd, buf, n, offset, false);
}

int64_t rt_os_pwrite(int fd, const void *buf, uint32_t n, uint64_t offset)
{
    return positional_io(fd, (void *)(uintptr_t)buf, n, offset, true);
}

void rt_os_discard(void *p, size_t n)
{
    /* Heap memory: no portable way to give single pages back; the ring
     * stays resident as far as a backlog reached (bounded by its size). */
    (void)p;
    (void)n;
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
