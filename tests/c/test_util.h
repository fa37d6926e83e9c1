/* Shared helpers of the C unit tests: lines with their own queue storage, an
 * in-process bus with a fake clock, and a sniffer that records every frame
 * carried on the bus together with the fake time it was carried at.
 *
 * Everything here is header-only (static functions) so that every test binary
 * stays a single translation unit plus the core. */
#ifndef TEST_UTIL_H
#define TEST_UTIL_H

#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "canopenfd/co_frame.h"
#include "canopenfd/co_queue.h"
#include "canopenfd/co_timer.h"
#include "canopenfd/co_line.h"
#include "canopenfd/co_nmt.h"
#include "canopenfd/co_hb.h"
#include "canopenfd/co_node.h"
#include "canopenfd/co_membus.h"

#define TU_QUEUE 256          /* rx and tx slots of every test line */
#define TU_MAX_LINES 4        /* processed lines on a test bus */
#define TU_LOG_MAX 8192       /* frames the sniffer log keeps */
#define TU_MS 1000u           /* microseconds per millisecond */

/* ------------------------------------------------------------------ lines */

typedef struct tu_line {
    co_line_t line;
    co_frame_t rx_slots[TU_QUEUE];
    co_frame_t tx_slots[TU_QUEUE];
} tu_line_t;

static inline void tu_line_init(tu_line_t *l, co_mode_t mode, bool brs)
{
    co_line_config_t cfg;
    memset(&cfg, 0, sizeof cfg);
    cfg.mode = mode;
    cfg.brs = brs;
    cfg.rx_slots = l->rx_slots;
    cfg.rx_capacity = TU_QUEUE;
    cfg.tx_slots = l->tx_slots;
    cfg.tx_capacity = TU_QUEUE;
    assert_true(co_line_init(&l->line, &cfg));
}

/* Flags the line adds to every frame it sends. */
static inline uint8_t tu_mode_flags(co_mode_t mode, bool brs)
{
    if (mode != CO_MODE_FD)
        return 0;
    return (uint8_t)(CO_FRAME_FD | (brs ? CO_FRAME_BRS : 0));
}

/* ------------------------------------------------------------- test bus */

typedef struct tu_logged {
    co_frame_t frame;
    uint64_t t_us;            /* fake time at which the frame was carried */
} tu_logged_t;

typedef struct tu_bus {
    co_membus_t bus;
    co_mode_t mode;
    bool brs;
    tu_line_t *lines[TU_MAX_LINES];   /* lines processed by tu_step() */
    uint8_t count;
    tu_line_t sniffer;                /* attached, never processed */
    tu_logged_t log[TU_LOG_MAX];
    size_t log_count;
    uint64_t now;
} tu_bus_t;

static inline void tu_bus_init(tu_bus_t *tb, co_mode_t mode, bool brs)
{
    memset(tb, 0, sizeof *tb);
    tb->mode = mode;
    tb->brs = brs;
    co_membus_init(&tb->bus);
    tu_line_init(&tb->sniffer, mode, brs);
    assert_true(co_membus_attach(&tb->bus, &tb->sniffer.line));
}

/* Flags every frame on this bus must carry. */
static inline uint8_t tu_bus_flags(const tu_bus_t *tb)
{
    return tu_mode_flags(tb->mode, tb->brs);
}

static inline co_line_t *tu_bus_add_line(tu_bus_t *tb, tu_line_t *l)
{
    assert_true(tb->count < TU_MAX_LINES);
    tu_line_init(l, tb->mode, tb->brs);
    assert_true(co_membus_attach(&tb->bus, &l->line));
    tb->lines[tb->count++] = l;
    return &l->line;
}

/* Move what the sniffer received into the log (the sniffer is never
 * processed, its rx queue is read directly). */
static inline void tu_drain_sniffer(tu_bus_t *tb)
{
    co_frame_t f;
    while (co_line_rx_pop(&tb->sniffer.line, &f)) {
        assert_true(tb->log_count < TU_LOG_MAX);
        tb->log[tb->log_count].frame = f;
        tb->log[tb->log_count].t_us = tb->now;
        tb->log_count++;
    }
}

/* Process every line at `now` and carry frames until the bus is quiet. */
static inline void tu_step(tu_bus_t *tb, uint64_t now)
{
    int round;
    uint8_t i;
    assert_true(now >= tb->now);
    tb->now = now;
    for (round = 0; round < 1000; round++) {
        uint32_t moved;
        for (i = 0; i < tb->count; i++)
            (void)co_line_process(&tb->lines[i]->line, now);
        moved = co_membus_transfer(&tb->bus, NULL, NULL);
        tu_drain_sniffer(tb);
        if (moved == 0)
            return;
    }
    fail_msg("bus did not become quiet at t=%llu", (unsigned long long)now);
}

/* Earliest timer deadline of all processed lines. */
static inline uint64_t tu_next_deadline(const tu_bus_t *tb)
{
    uint64_t next = CO_TIME_NEVER;
    uint8_t i;
    for (i = 0; i < tb->count; i++) {
        uint64_t d = co_timer_list_next(co_line_timers(&tb->lines[i]->line));
        if (d < next)
            next = d;
    }
    return next;
}

/* Advance the fake clock to `until`, stopping at every timer deadline on the
 * way so that everything happens at its exact time. */
static inline void tu_run_until(tu_bus_t *tb, uint64_t until)
{
    long guard = 0;
    for (;;) {
        uint64_t d = tu_next_deadline(tb);
        if (d > until)
            break;
        tu_step(tb, d > tb->now ? d : tb->now);
        if (++guard > 1000000)
            fail_msg("timers keep firing at t=%llu", (unsigned long long)tb->now);
    }
    tu_step(tb, until);
}

/* One line without a bus: run its timers up to until_us, each at its own
 * deadline as a driver would, then process at until_us. */
static inline void tu_line_run_until(co_line_t *line, uint64_t until_us)
{
    for (long guard = 0;; guard++) {
        uint64_t next = co_timer_list_next(co_line_timers(line));
        if (next >= until_us)
            break;
        if (guard > 1000000)
            fail_msg("timers keep firing at t=%llu", (unsigned long long)next);
        (void)co_line_process(line, next > co_line_now(line) ? next : co_line_now(line));
    }
    (void)co_line_process(line, until_us);
}

static inline void tu_log_clear(tu_bus_t *tb)
{
    tb->log_count = 0;
}

/* Number of logged frames with this CAN-ID. */
static inline size_t tu_log_count_id(const tu_bus_t *tb, uint32_t id)
{
    size_t i, n = 0;
    for (i = 0; i < tb->log_count; i++)
        if (tb->log[i].frame.id == id)
            n++;
    return n;
}

/* Index of the k-th (0-based) logged frame with this CAN-ID, or -1. */
static inline long tu_log_find_id(const tu_bus_t *tb, uint32_t id, size_t k)
{
    size_t i;
    for (i = 0; i < tb->log_count; i++)
        if (tb->log[i].frame.id == id && k-- == 0)
            return (long)i;
    return -1;
}

/* Check one frame completely: CAN-ID, flags, length and every payload byte. */
static inline void tu_assert_frame(const co_frame_t *f, uint32_t id, uint8_t flags,
                                   const uint8_t *data, uint8_t len)
{
    assert_int_equal(f->id, id);
    assert_int_equal(f->flags, flags);
    assert_int_equal(f->len, len);
    if (len > 0)
        assert_memory_equal(f->data, data, len);
}

/* Check logged frame `index` as a frame of this bus (flags of the bus mode). */
static inline void tu_assert_logged(const tu_bus_t *tb, long index, uint32_t id,
                                    const uint8_t *data, uint8_t len)
{
    assert_true(index >= 0);
    assert_true((size_t)index < tb->log_count);
    tu_assert_frame(&tb->log[index].frame, id, tu_bus_flags(tb), data, len);
}

/* --------------------------------------------------------------- frames */

static inline co_frame_t tu_frame(uint32_t id, uint8_t flags, const uint8_t *data, uint8_t len)
{
    co_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = id;
    f.flags = flags;
    f.len = len;   /* may be an invalid length on purpose */
    if (data != NULL)
        memcpy(f.data, data, len < CO_FRAME_MAX_DATA ? len : CO_FRAME_MAX_DATA);
    return f;
}

/* Deterministic pseudo-random numbers (xorshift64*), no global state. */
static inline uint64_t tu_rand(uint64_t *state)
{
    uint64_t x = *state;
    x ^= x >> 12;
    x ^= x << 25;
    x ^= x >> 27;
    *state = x;
    return x * 0x2545F4914F6CDD1Dull;
}

#endif
