/* Shared helpers of the benchmarks: wall clock, pseudo-random numbers and the
 * result table (header and one row per figure).
 *
 * Header-only (static inline) so that every benchmark stays one translation
 * unit plus the core. The includer defines _POSIX_C_SOURCE (for
 * clock_gettime) before its first #include. */
#ifndef BENCH_UTIL_H
#define BENCH_UTIL_H

#include <stdint.h>
#include <stdio.h>
#include <time.h>

/* Monotonic wall time in seconds. */
static inline double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

/* Deterministic pseudo-random numbers (xorshift64*). */
static inline uint64_t rng_next(uint64_t *s)
{
    uint64_t x = *s;
    x ^= x >> 12;
    x ^= x << 25;
    x ^= x >> 27;
    *s = x;
    return x * 0x2545F4914F6CDD1Dull;
}

/* Title line and column heads of the result table. */
static inline void table_header(const char *title)
{
    printf("%s\n\n", title);
    printf("%-48s %11s %9s %24s %8s\n", "figure", "count", "time s", "rate", "ns/op");
    printf("%-48s %11s %9s %24s %8s\n", "------", "-----", "------", "----", "-----");
}

/* One figure: `count` operations in `seconds`. */
static inline void row(const char *what, double count, double seconds, const char *unit)
{
    double rate = count / seconds;
    const char *scale = "";
    double shown = rate;
    if (rate >= 1e6) {
        shown = rate / 1e6;
        scale = "M";
    } else if (rate >= 1e3) {
        shown = rate / 1e3;
        scale = "k";
    }
    printf("%-48s %11.0f %9.3f %9.2f %1s%-13s %8.1f\n", what, count, seconds, shown, scale,
           unit, seconds * 1e9 / count);
    fflush(stdout);
}

#endif
