/* Benchmark of the portable core alone, on the in-process bus (membus), one
 * thread, no OS in the measured path except the clock reads around it.
 * Prints a table of figures; asserts nothing about timing.
 *
 *   (a) frames/s through line processing: send on one line, membus transfer,
 *       receive + dispatch to a trivial handler on the other line
 *   (b) heartbeat consumer: 127 nodes' heartbeats through one consumer
 *   (c) timer list with 10 000 armed timers: start, cancel, restart, run-due
 */
#define _POSIX_C_SOURCE 199309L

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "bench_util.h"
#include "canopenfd/co_frame.h"
#include "canopenfd/co_hb.h"
#include "canopenfd/co_line.h"
#include "canopenfd/co_membus.h"
#include "canopenfd/co_timer.h"

#define QUEUE 512
#define TIMERS 10000

/* ------------------------------------------------------------------ lines */

typedef struct bline {
    co_line_t line;
    co_frame_t rx[QUEUE];
    co_frame_t tx[QUEUE];
} bline_t;

static void bline_init(bline_t *b, co_mode_t mode, bool brs)
{
    co_line_config_t cfg;
    memset(&cfg, 0, sizeof cfg);
    cfg.mode = mode;
    cfg.brs = brs;
    cfg.rx_slots = b->rx;
    cfg.rx_capacity = QUEUE;
    cfg.tx_slots = b->tx;
    cfg.tx_capacity = QUEUE;
    if (!co_line_init(&b->line, &cfg)) {
        fprintf(stderr, "co_line_init failed\n");
        exit(1);
    }
}

typedef struct sink {
    uint64_t frames;
    uint64_t bytes;
} sink_t;

static void count_rx(co_line_t *line, const co_frame_t *frame, void *user)
{
    sink_t *s = user;
    (void)line;
    s->frames++;
    s->bytes += frame->len;
}

/* (a) */
static void bench_line(const char *what, co_mode_t mode, bool brs, size_t len, uint64_t total)
{
    static bline_t a, b;
    co_membus_t bus;
    sink_t sink = {0, 0};
    uint8_t data[64];
    uint64_t sent = 0, now = 0;
    const uint32_t batch = 256;
    double t0, best = 0;
    size_t i;
    int rep;

    for (i = 0; i < sizeof data; i++)
        data[i] = (uint8_t)i;
    bline_init(&a, mode, brs);
    bline_init(&b, mode, brs);
    co_membus_init(&bus);
    co_membus_attach(&bus, &a.line);
    co_membus_attach(&bus, &b.line);
    if (!co_line_subscribe(&b.line, 0x200, 0x27F, count_rx, &sink)) {
        fprintf(stderr, "subscribe failed\n");
        exit(1);
    }

    for (rep = 0; rep < 3; rep++) {     /* best of three */
        double t;
        uint64_t done = 0;
        t0 = now_s();
        while (done < total) {
            uint32_t k;
            for (k = 0; k < batch; k++)
                co_line_send(&a.line, 0x200 + (k & 0x7F), data, len);
            co_membus_transfer(&bus, NULL, NULL);
            co_line_process(&b.line, now);
            now += 1000;
            done += batch;
        }
        t = now_s() - t0;
        if (rep == 0 || t < best)
            best = t;
        sent += done;
    }
    if (sink.frames != sent || a.line.stats.tx_overflow || b.line.stats.rx_overflow) {
        fprintf(stderr, "%s: %llu sent, %llu received (tx_overflow %u, rx_overflow %u)\n", what,
                (unsigned long long)sent, (unsigned long long)sink.frames,
                a.line.stats.tx_overflow, b.line.stats.rx_overflow);
        exit(1);
    }
    row(what, (double)total, best, "frames/s");
}

/* (b) */
typedef struct hb_count {
    uint64_t events;
} hb_count_t;

static void on_hb_event(co_hb_consumer_t *c, uint8_t node_id, co_hb_event_t event,
                        co_nmt_state_t state, void *user)
{
    hb_count_t *h = user;
    (void)c;
    (void)node_id;
    (void)event;
    (void)state;
    h->events++;
}

static void bench_heartbeat(co_mode_t mode, uint64_t rounds)
{
    static bline_t inj, con;
    static co_hb_entry_t entries[127];
    co_hb_consumer_t consumer;
    co_membus_t bus;
    hb_count_t count = {0};
    co_frame_t hb[128];
    uint64_t r, now = 0;
    double t0, best = 0;
    uint8_t n;
    int rep;
    const char *what = mode == CO_MODE_FD ? "(b) heartbeat consumer, 127 nodes, fd"
                                          : "(b) heartbeat consumer, 127 nodes, classic";

    bline_init(&inj, mode, mode == CO_MODE_FD);
    bline_init(&con, mode, mode == CO_MODE_FD);
    co_membus_init(&bus);
    co_membus_attach(&bus, &inj.line);
    co_membus_attach(&bus, &con.line);
    if (!co_hb_consumer_init(&consumer, &con.line, entries, 127, on_hb_event, &count)) {
        fprintf(stderr, "consumer init failed\n");
        exit(1);
    }
    for (n = 1; n <= 127; n++) {
        /* staggered consumer times: every entry has its own deadline */
        if (co_hb_consumer_watch(&consumer, n, (uint16_t)(1000 + n)) != CO_HB_CONFIG_OK) {
            fprintf(stderr, "watch %u failed\n", n);
            exit(1);
        }
        co_hb_encode(CO_NMT_OPERATIONAL, &hb[n], n);
    }

    for (rep = 0; rep < 3; rep++) {     /* best of three */
        double t;
        t0 = now_s();
        for (r = 0; r < rounds; r++) {
            for (n = 1; n <= 127; n++)
                co_line_send_frame(&inj.line, &hb[n]);
            co_membus_transfer(&bus, NULL, NULL);
            co_line_process(&con.line, now);
            now += 100000;     /* 100 ms between rounds: nobody is ever lost */
        }
        t = now_s() - t0;
        if (rep == 0 || t < best)
            best = t;
    }
    if (count.events != 127 * 2 || con.line.stats.rx_overflow) {
        /* 127 STATE_CHANGED (unknown -> operational) + 127 STARTED, nothing else */
        fprintf(stderr, "%s: unexpected %llu events\n", what, (unsigned long long)count.events);
        exit(1);
    }
    row(what, (double)(rounds * 127), best, "heartbeats/s");
}

/* (c) */
typedef struct tctx {
    co_timer_list_t list;
    co_timer_t timers[TIMERS];
    uint64_t rng;
    uint64_t span;       /* random deadlines within now .. now + span */
    uint64_t fired;
} tctx_t;

static void on_fire_rearm(co_timer_t *timer, uint64_t now_us, void *user)
{
    tctx_t *c = user;
    c->fired++;
    co_timer_start(&c->list, timer, now_us + 1 + rng_next(&c->rng) % c->span);
}

static void bench_timers(void)
{
    static tctx_t c;
    static uint32_t order[TIMERS];
    const uint64_t span = 1000000;     /* deadlines spread over 1 s */
    uint64_t now, ops;
    double t0, t1;
    uint32_t i;
    int rep;

    c.rng = 0x9E3779B97F4A7C15ull;
    c.span = span;
    co_timer_list_init(&c.list);
    for (i = 0; i < TIMERS; i++) {
        co_timer_init(&c.timers[i], on_fire_rearm, &c);
        order[i] = i;
    }
    for (i = TIMERS - 1; i > 0; i--) {          /* random cancel order */
        uint32_t j = (uint32_t)(rng_next(&c.rng) % (i + 1)), tmp = order[i];
        order[i] = order[j];
        order[j] = tmp;
    }

    /* start: fill an empty list to 10 000 with random deadlines (avg 5 000 armed) */
    ops = 0;
    t0 = now_s();
    for (rep = 0; rep < 3; rep++) {
        for (i = 0; i < TIMERS; i++)
            co_timer_start(&c.list, &c.timers[i], rng_next(&c.rng) % span);
        ops += TIMERS;
        if (rep < 2)
            for (i = 0; i < TIMERS; i++)
                co_timer_cancel(&c.list, &c.timers[i]);
    }
    t1 = now_s();
    /* the cancels between rounds are cheap (O(1)); they are part of the time */
    row("(c) timers: start random, list 0..10000", (double)ops, t1 - t0, "ops/s");

    /* cancel: 10 000 armed, cancel all in random order, re-fill untimed */
    ops = 0;
    {
        double spent = 0;
        for (rep = 0; rep < 20; rep++) {
            for (i = 0; i < TIMERS; i++)
                if (!co_timer_is_armed(&c.timers[i]))
                    co_timer_start(&c.list, &c.timers[i], rng_next(&c.rng) % span);
            t0 = now_s();
            for (i = 0; i < TIMERS; i++)
                co_timer_cancel(&c.list, &c.timers[order[i]]);
            spent += now_s() - t0;
            ops += TIMERS;
        }
        row("(c) timers: cancel, 10000 armed", (double)ops, spent, "ops/s");
    }

    for (i = 0; i < TIMERS; i++)
        co_timer_start(&c.list, &c.timers[i], rng_next(&c.rng) % span);

    /* restart: random timer to a random deadline, list stays at 10 000
     * (time-bounded: batches of 1000 until 0.5 s have passed) */
    ops = 0;
    t0 = now_s();
    do {
        for (i = 0; i < 1000; i++)
            co_timer_start(&c.list, &c.timers[rng_next(&c.rng) % TIMERS],
                           rng_next(&c.rng) % span);
        ops += 1000;
        t1 = now_s();
    } while (t1 - t0 < 0.5);
    row("(c) timers: restart random, 10000 armed", (double)ops, t1 - t0, "ops/s");

    /* restart periodic: deadline later than all others (lands at the tail) */
    ops = 2000000;
    now = span;
    t0 = now_s();
    for (i = 0; i < ops; i++)
        co_timer_start(&c.list, &c.timers[i % TIMERS], now + i);
    t1 = now_s();
    row("(c) timers: restart at tail, 10000 armed", (double)ops, t1 - t0, "ops/s");

    /* run-due: random deadlines over 1 s; every fired timer re-arms at a
     * random later deadline, so the list stays at 10 000. Time advances in
     * 1 ms ticks (about 10 timers due per tick). */
    for (i = 0; i < TIMERS; i++)
        co_timer_start(&c.list, &c.timers[i], rng_next(&c.rng) % span);
    c.fired = 0;
    now = 0;
    t0 = now_s();
    do {
        int k;
        for (k = 0; k < 100; k++) {
            now += 1000;
            co_timer_list_run(&c.list, now);
        }
        t1 = now_s();
    } while (t1 - t0 < 0.5);
    row("(c) timers: run-due + re-arm random, 10000 armed", (double)c.fired, t1 - t0,
        "fired/s");
    if (c.list.armed != TIMERS) {
        fprintf(stderr, "timer list lost timers: %u armed\n", c.list.armed);
        exit(1);
    }
}

int main(void)
{
    table_header("canopenfd core benchmark: csrc/core + membus, one thread");
    bench_line("(a) line: classic, 8-byte frames", CO_MODE_CLASSIC, false, 8, 4000000);
    bench_line("(a) line: fd + BRS, 64-byte frames", CO_MODE_FD, true, 64, 4000000);
    bench_line("(a) line: fd + BRS, 13 -> 16-byte frames", CO_MODE_FD, true, 13, 4000000);
    bench_heartbeat(CO_MODE_CLASSIC, 20000);
    bench_heartbeat(CO_MODE_FD, 20000);
    bench_timers();
    return 0;
}
