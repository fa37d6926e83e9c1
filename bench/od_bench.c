/* Benchmark of the object dictionary (csrc/core/co_od) alone, one thread.
 * Prints a table of figures; asserts nothing about timing, but checks every
 * result and exits non-zero when one is wrong.
 *
 *   (d) building a 10 000-entry OD: adds in ascending and in random order
 *   (e) lookups on that OD: random hits, random misses
 *   (f) application access: co_od_get / co_od_put of a U32
 *   (g) network access: a full write (begin/chunk/end) and read of a U32
 *   (h) memory per entry
 */
#define _POSIX_C_SOURCE 199309L

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "bench_util.h"
#include "canopenfd/co_od.h"

#define ENTRIES 10000
#define KEYS 4096          /* random keys per batch (fits in cache like a real OD) */

static void die(const char *what)
{
    fprintf(stderr, "od_bench: %s\n", what);
    exit(1);
}

typedef struct bod {
    co_od_t od;
    co_od_entry_t entries[ENTRIES];
    uint8_t pool[ENTRIES * 8];
    co_od_subscription_t subs[4];
} bod_t;

/* Entry k: index 0x2000 + 2 * (k / 4), sub k % 4, U32 with default k; the
 * odd indices in between are the misses. */
static uint16_t index_of(uint32_t k)
{
    return (uint16_t)(0x2000 + 2 * (k / 4));
}

static void build(bod_t *b, const uint32_t *order)
{
    uint32_t i;
    co_od_init(&b->od, CO_MODE_FD, b->entries, ENTRIES, b->pool, sizeof b->pool, b->subs, 4);
    for (i = 0; i < ENTRIES; i++) {
        uint32_t k = order[i];
        uint8_t dflt[4] = {(uint8_t)k, (uint8_t)(k >> 8), (uint8_t)(k >> 16), (uint8_t)(k >> 24)};
        co_od_def_t d;
        memset(&d, 0, sizeof d);
        d.index = index_of(k);
        d.sub = (uint8_t)(k % 4);
        d.object_code = CO_OBJECT_VAR;
        d.type = CO_TYPE_UNSIGNED32;
        d.access = CO_ACCESS_RW;
        d.size = 4;
        d.default_value = dflt;
        d.default_length = 4;
        if (co_od_add(&b->od, &d) != CO_OD_ADDED)
            die("add failed");
    }
}

static uint32_t count_after;

static void after_write(co_od_t *od, const co_od_entry_t *e, co_od_origin_t origin, void *user)
{
    (void)od;
    (void)e;
    (void)origin;
    (void)user;
    count_after++;
}

int main(void)
{
    static bod_t b;
    static uint32_t ascending[ENTRIES], shuffled[ENTRIES];
    static uint16_t key_index[KEYS];
    static uint8_t key_sub[KEYS];
    static const co_od_handler_t handler = {.after_write = after_write};
    uint8_t scratch[64];
    co_od_xfer_t xfer;
    uint64_t rng = 0x9E3779B97F4A7C15ull;
    volatile uintptr_t sink = 0;
    double t0, t1, best;
    uint32_t i, found;
    int rep;

    table_header("canopenfd object dictionary benchmark: csrc/core/co_od, one thread");

    for (i = 0; i < ENTRIES; i++)
        ascending[i] = shuffled[i] = i;
    for (i = ENTRIES - 1; i > 0; i--) {
        uint32_t j = (uint32_t)(rng_next(&rng) % (i + 1)), t = shuffled[i];
        shuffled[i] = shuffled[j];
        shuffled[j] = t;
    }

    /* (d) build */
    best = 0;
    for (rep = 0; rep < 3; rep++) {
        t0 = now_s();
        build(&b, ascending);
        t1 = now_s();
        if (rep == 0 || t1 - t0 < best)
            best = t1 - t0;
    }
    row("(d) build: add 10000 in ascending order", ENTRIES, best, "adds/s");
    best = 0;
    for (rep = 0; rep < 3; rep++) {
        t0 = now_s();
        build(&b, shuffled);
        t1 = now_s();
        if (rep == 0 || t1 - t0 < best)
            best = t1 - t0;
    }
    row("(d) build: add 10000 in random order", ENTRIES, best, "adds/s");
    t0 = now_s();
    if (!co_od_seal(&b.od, 1))
        die("seal failed");
    t1 = now_s();
    row("(d) build: seal 10000 (checks + defaults)", ENTRIES, t1 - t0, "entries/s");

    /* (e) lookups */
    for (i = 0; i < KEYS; i++) {
        uint32_t k = (uint32_t)(rng_next(&rng) % ENTRIES);
        key_index[i] = index_of(k);
        key_sub[i] = (uint8_t)(k % 4);
    }
    {
        const uint32_t rounds = 2000;
        uint32_t r;
        best = 0;
        for (rep = 0; rep < 3; rep++) {
            found = 0;
            t0 = now_s();
            for (r = 0; r < rounds; r++)
                for (i = 0; i < KEYS; i++) {
                    const co_od_entry_t *e = co_od_find(&b.od, key_index[i], key_sub[i]);
                    found += e != NULL;
                    sink ^= (uintptr_t)e;
                }
            t1 = now_s();
            if (found != rounds * KEYS)
                die("a lookup missed");
            if (rep == 0 || t1 - t0 < best)
                best = t1 - t0;
        }
        row("(e) lookup: random hits, 10000 entries", (double)rounds * KEYS, best, "lookups/s");
        best = 0;
        for (rep = 0; rep < 3; rep++) {
            found = 0;
            t0 = now_s();
            for (r = 0; r < rounds; r++)
                for (i = 0; i < KEYS; i++) {
                    /* odd index (between two present ones) or a sub past the last */
                    const co_od_entry_t *e =
                        (i & 1) ? co_od_find(&b.od, (uint16_t)(key_index[i] + 1), key_sub[i])
                                : co_od_find(&b.od, key_index[i], (uint8_t)(4 + key_sub[i]));
                    found += e != NULL;
                    sink ^= (uintptr_t)e;
                }
            t1 = now_s();
            if (found != 0)
                die("a miss was found");
            if (rep == 0 || t1 - t0 < best)
                best = t1 - t0;
        }
        row("(e) lookup: random misses, 10000 entries", (double)rounds * KEYS, best, "lookups/s");
    }

    /* (f) application access */
    /* one after_write handler covering every entry, as a facade would have */
    if (!co_od_subscribe(&b.od, 0x2000, 0, 0xFFFF, 0xFF, &handler, NULL))
        die("subscribe failed");
    {
        const uint32_t rounds = 1000;
        uint32_t r, len;
        uint8_t buf[4];
        uint64_t sum = 0;
        best = 0;
        for (rep = 0; rep < 3; rep++) {
            t0 = now_s();
            for (r = 0; r < rounds; r++)
                for (i = 0; i < KEYS; i++) {
                    if (co_od_get(&b.od, key_index[i], key_sub[i], buf, 4, &len) != 0)
                        die("get failed");
                    sum += buf[0];
                }
            t1 = now_s();
            if (rep == 0 || t1 - t0 < best)
                best = t1 - t0;
        }
        sink ^= (uintptr_t)sum;
        row("(f) co_od_get U32, random keys", (double)rounds * KEYS, best, "gets/s");
        best = 0;
        for (rep = 0; rep < 3; rep++) {
            t0 = now_s();
            for (r = 0; r < rounds; r++)
                for (i = 0; i < KEYS; i++) {
                    uint8_t v[4] = {(uint8_t)r, (uint8_t)i, 0, 0};
                    if (co_od_put(&b.od, key_index[i], key_sub[i], v, 4) != 0)
                        die("put failed");
                }
            t1 = now_s();
            if (rep == 0 || t1 - t0 < best)
                best = t1 - t0;
        }
        row("(f) co_od_put U32, random keys", (double)rounds * KEYS, best, "puts/s");
    }

    /* (g) network access */
    co_od_xfer_init(&xfer, scratch, sizeof scratch);
    {
        const uint32_t rounds = 500;
        uint32_t r, n;
        bool last;
        uint8_t buf[4];
        best = 0;
        for (rep = 0; rep < 3; rep++) {
            t0 = now_s();
            for (r = 0; r < rounds; r++)
                for (i = 0; i < KEYS; i++) {
                    uint8_t v[4] = {(uint8_t)r, (uint8_t)i, 1, 0};
                    if (co_od_write_begin(&b.od, &xfer, key_index[i], key_sub[i], 4) != 0 ||
                        co_od_write_chunk(&xfer, v, 4) != 0 || co_od_write_end(&xfer) != 0)
                        die("network write failed");
                }
            t1 = now_s();
            if (rep == 0 || t1 - t0 < best)
                best = t1 - t0;
        }
        row("(g) network write U32 (begin/chunk/end)", (double)rounds * KEYS, best, "writes/s");
        best = 0;
        for (rep = 0; rep < 3; rep++) {
            t0 = now_s();
            for (r = 0; r < rounds; r++)
                for (i = 0; i < KEYS; i++) {
                    if (co_od_read_begin(&b.od, &xfer, key_index[i], key_sub[i]) != 0 ||
                        co_od_read_chunk(&xfer, buf, 4, &n, &last) != 0 || n != 4 || !last)
                        die("network read failed");
                    sink ^= buf[1];
                }
            t1 = now_s();
            if (rep == 0 || t1 - t0 < best)
                best = t1 - t0;
        }
        row("(g) network read U32 (begin/chunk)", (double)rounds * KEYS, best, "reads/s");
    }
    if (count_after != 3u * 1000u * KEYS + 3u * 500u * KEYS)
        die("after_write did not run once per put and write");

    /* (h) memory */
    printf("\n%-48s %11s %9s %24s\n", "memory per entry", "entry B", "pool B", "total B");
    printf("%-48s %11zu %9.1f %24.1f\n", "(h) U32 with default, 10000 entries",
           sizeof(co_od_entry_t), (double)b.od.pool_used / b.od.count,
           (double)sizeof(co_od_entry_t) + (double)b.od.pool_used / b.od.count);
    {
        co_od_def_t d;
        memset(&d, 0, sizeof d);
        d.type = CO_TYPE_UNSIGNED32;
        d.size = 4;
        d.default_length = 4;
        d.flags = CO_OD_HAS_MIN | CO_OD_HAS_MAX;
        printf("%-48s %11zu %9u %24.1f\n", "(h) U32 with default and limits",
               sizeof(co_od_entry_t), co_od_pool_need(&d),
               (double)sizeof(co_od_entry_t) + co_od_pool_need(&d));
        d.type = CO_TYPE_UNSIGNED8;
        d.size = 1;
        d.default_length = 1;
        d.flags = 0;
        printf("%-48s %11zu %9u %24.1f\n", "(h) U8 with default", sizeof(co_od_entry_t),
               co_od_pool_need(&d), (double)sizeof(co_od_entry_t) + co_od_pool_need(&d));
    }
    (void)sink;
    return 0;
}
