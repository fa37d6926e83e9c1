/* The runtime under threads: built with ThreadSanitizer (data races, lock
 * order) and with AddressSanitizer + LeakSanitizer + UBSan (memory, leaks)
 * by tests/stress/Makefile.
 *
 * Each round builds a runtime with two fd lines on one in-process bus (a
 * device, node 5, serving an OD; a tool with a USDO client) and, from
 * several threads at once, runs transfers (started, waited for, cancelled,
 * collected, released), commands (NMT, OD reads and writes, statistics),
 * master-side RPDO producers (opened, written, sent, periodic, on SYNC,
 * stopped, closed), the device's LEDs (listened to, read, a cause set) and
 * the event reader; then stops the runtime while all of that is in flight.
 * Every thread must see the stop (CO_RT_ERR_CLOSED) and end within a bound
 * (a thread still running after it is a hang), every transfer must have
 * ended correctly or with an error code, and after co_rt_free no file
 * descriptor may be left open. A last round runs TRANSFERS transfers to the
 * end before shutting down (the leak check covers them).
 *
 * Prints one line per round and "stress: N passed, M failed" (rounds). */
#define _GNU_SOURCE
#include "canopenfd/co_runtime.h"

#include <dirent.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

enum {
    NODE = 5,
    TOOL = 0x7F,
    BIG = 300,
    WORKERS = 4,
    ROUNDS = 12,
    TRANSFERS = 10000,             /* the last round: transfers run to the end */
    JOIN_LIMIT_MS = 5000           /* a thread not ended this long after the stop: a hang */
};

static const uint8_t u32_zero[4];
static const uint8_t identity[4] = {0x78, 0x56, 0x34, 0x12};
static const co_od_def_t od_defs[] = {
    {.index = 0x1000, .object_code = CO_OBJECT_VAR, .type = CO_TYPE_UNSIGNED32,
     .access = CO_ACCESS_RO, .size = 4, .default_value = u32_zero, .default_length = 4},
    {.index = 0x1001, .object_code = CO_OBJECT_VAR, .type = CO_TYPE_UNSIGNED8,
     .access = CO_ACCESS_RO, .size = 1, .default_value = u32_zero, .default_length = 1},
    {.index = 0x1017, .object_code = CO_OBJECT_VAR, .type = CO_TYPE_UNSIGNED16,
     .access = CO_ACCESS_RW, .size = 2, .default_value = u32_zero, .default_length = 2},
    {.index = 0x1018, .sub = 0, .object_code = CO_OBJECT_RECORD, .type = CO_TYPE_UNSIGNED8,
     .access = CO_ACCESS_RO, .size = 1, .default_value = (const uint8_t *)"\x01",
     .default_length = 1},
    {.index = 0x1018, .sub = 1, .object_code = CO_OBJECT_RECORD, .type = CO_TYPE_UNSIGNED32,
     .access = CO_ACCESS_RO, .size = 4, .default_value = identity, .default_length = 4},
    {.index = 0x2000, .object_code = CO_OBJECT_VAR, .type = CO_TYPE_UNSIGNED32,
     .access = CO_ACCESS_RW, .size = 4, .default_value = u32_zero, .default_length = 4},
#define BIG_ENTRY(i)                                                                     \
    {.index = 0x2005 + (i), .object_code = CO_OBJECT_VAR, .type = CO_TYPE_OCTET_STRING,   \
     .access = CO_ACCESS_RW, .size = BIG, .default_value = (const uint8_t *)"",           \
     .default_length = 0}
    /* one per worker: the server refuses (0x20) two transfers of one entry at once */
    BIG_ENTRY(0), BIG_ENTRY(1), BIG_ENTRY(2), BIG_ENTRY(3),
};

typedef struct round {
    co_rt_t *rt;
    int device, tool;
    atomic_bool stop_asked;            /* the last round: workers end by themselves */
    int limit;                         /* transfers per worker (0 = until the stop) */
    atomic_int ok, closed, failed, wrong;
    atomic_int events;
    atomic_int reported;               /* failures described so far */
    atomic_int running;                /* threads not yet ended */
} round_t;

static uint64_t now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000u + (uint64_t)ts.tv_nsec / 1000000u;
}

static int open_fds(void)
{
    int n = 0;
    DIR *d = opendir("/proc/self/fd");
    if (!d) {
        return -1;
    }
    while (readdir(d)) {
        n++;
    }
    closedir(d);
    return n;
}

typedef struct worker {
    round_t *round;
    int id;                            /* 0..WORKERS-1: its entry is 0x2005 + id */
} worker_t;

/* One transfer from start to release; returns 1 ok, 0 closed, -1 failed. */
static int one_transfer(round_t *r, int id, unsigned n, uint8_t *payload)
{
    co_rt_transfer_request_t q;
    memset(&q, 0, sizeof q);
    q.server = NODE;
    q.fd = -1;
    q.timeout_ms = 500;
    q.no_done_event = (int)(n % 2u);   /* half of them the way the blocking forms run */
    bool upload = n % 3u != 0;
    q.upload = upload;
    if (n % 4u == 0) {
        q.index = 0x1018;
        q.sub = 1;
        q.upload = 1;
        upload = true;
    } else {
        q.index = (uint16_t)(0x2005 + id);
        if (!upload) {
            for (unsigned i = 0; i < BIG; i++) {
                payload[i] = (uint8_t)(n + i);
            }
            q.data = payload;
            q.size = BIG;
        }
    }
    int handle = co_rt_transfer_start(r->rt, r->tool, &q);
    if (handle < 0) {
        return handle == CO_RT_ERR_CLOSED ? 0 : -1;
    }
    if (n % 7u == 3u) {
        (void)co_rt_transfer_cancel(r->rt, r->tool, handle, 0x10);
    }
    if (n % 5u == 1u) {                /* ask for the done event, racing the end */
        int notified = co_rt_transfer_notify(r->rt, r->tool, handle);
        if (notified < 0 && notified != CO_RT_ERR_CLOSED) {
            return -1;
        }
    }
    int ended;
    do {
        ended = co_rt_transfer_wait(r->rt, r->tool, handle, 200);
    } while (ended == 0);
    if (ended < 0) {
        return ended == CO_RT_ERR_CLOSED ? 0 : -1;
    }
    co_rt_transfer_result_t res;
    int rc = co_rt_transfer_result(r->rt, r->tool, handle, &res);
    if (rc == CO_RT_ERR_CLOSED) {
        return 0;
    }
    int outcome = 1;
    if (rc < 0 || res.running) {
        outcome = -1;
    } else if (res.abort == 0 && q.index == 0x1018) {
        uint8_t buf[8];
        int got = co_rt_transfer_data(r->rt, r->tool, handle, buf, sizeof buf);
        if (got == CO_RT_ERR_CLOSED) {
            return 0;
        }
        if (got != 4 || memcmp(buf, identity, 4) != 0) {
            atomic_fetch_add(&r->wrong, 1);
        }
    } else if (res.abort != 0 && n % 7u != 3u) {
        outcome = -1;                  /* only the cancelled ones may abort */
        if (atomic_fetch_add(&r->reported, 1) < 3) {
            fprintf(stderr, "transfer %u (0x%04X %s) aborted 0x%X%s\n", n, q.index,
                    upload ? "upload" : "download", (unsigned)res.abort,
                    res.abort_from_server ? " by the server" : "");
        }
    }
    rc = co_rt_transfer_release(r->rt, r->tool, handle);
    if (rc == CO_RT_ERR_CLOSED) {
        return 0;
    }
    return rc < 0 ? -1 : outcome;
}

static void *worker(void *arg)
{
    worker_t *w = arg;
    round_t *r = w->round;
    uint8_t payload[BIG];
    for (unsigned n = (unsigned)w->id * 13u, done = 0;; n++, done++) {
        if (r->limit && (int)done >= r->limit) {
            break;
        }
        int outcome = one_transfer(r, w->id, n, payload);
        if (outcome == 0) {
            atomic_fetch_add(&r->closed, 1);
            break;
        }
        atomic_fetch_add(outcome > 0 ? &r->ok : &r->failed, 1);
    }
    atomic_fetch_sub(&r->running, 1);
    return NULL;
}

static void *commander(void *arg)
{
    round_t *r = arg;
    for (uint32_t n = 0; !atomic_load(&r->stop_asked); n++) {
        co_rt_command_t c;
        memset(&c, 0, sizeof c);
        c.kind = CO_CMD_NMT_SEND;
        c.line = r->tool;
        c.args.nmt_send.command = n % 2u ? CO_NMT_CMD_START : CO_NMT_CMD_PRE_OPERATIONAL;
        c.args.nmt_send.node_id = NODE;
        if (co_rt_command(r->rt, &c) == CO_RT_ERR_CLOSED) {
            break;
        }
        uint8_t v[4] = {(uint8_t)n, 0, 0, 0};
        if (co_rt_od_write(r->rt, r->device, 0x2000, 0, v, 4) == CO_RT_ERR_CLOSED) {
            break;
        }
        uint32_t len = 0;
        if (co_rt_od_read(r->rt, r->device, 0x2000, 0, v, 4, &len) == CO_RT_ERR_CLOSED) {
            break;
        }
        /* the device's LEDs: listened to on and off, read, the application's
         * cause toggled, while NMT commands change the run LED */
        co_rt_led_state_t leds;
        if (co_rt_led_listen(r->rt, r->device, n % 3u != 0) == CO_RT_ERR_CLOSED ||
            co_rt_led_state(r->rt, r->device, &leds) == CO_RT_ERR_CLOSED ||
            co_rt_led_causes(r->rt, r->device, CO_LED_CAUSE_CONFIG,
                             n % 5u ? 0 : CO_LED_CAUSE_CONFIG) == CO_RT_ERR_CLOSED) {
            break;
        }
        co_line_stats_t ls;
        co_rt_service_stats_t ss;
        if (co_rt_line_stats(r->rt, r->tool, &ls) == CO_RT_ERR_CLOSED ||
            co_rt_service_stats(r->rt, r->device, &ss) == CO_RT_ERR_CLOSED) {
            break;
        }
        usleep(200);
    }
    atomic_fetch_sub(&r->running, 1);
    return NULL;
}

/* Master-side RPDO producers opened, written, sent, run periodically and on
 * SYNC, stopped and closed while the runtime thread sends them. */
static void *rpdo_driver(void *arg)
{
    round_t *r = arg;
    for (uint32_t n = 0; !atomic_load(&r->stop_asked); n++) {
        int slot = co_rt_rpdo_open(r->rt, r->tool, 0x200u + NODE + 0x100u * (n % 4u), 8);
        if (slot == CO_RT_ERR_CLOSED) {
            break;
        }
        if (slot < 0) {
            continue;                  /* all slots taken by earlier rounds of this loop */
        }
        uint8_t v[4] = {(uint8_t)n, (uint8_t)(n >> 8), 0, 0};
        if (co_rt_rpdo_write(r->rt, r->tool, slot, 0, 16, v, 2) == CO_RT_ERR_CLOSED ||
            co_rt_rpdo_send(r->rt, r->tool, slot) == CO_RT_ERR_CLOSED ||
            co_rt_rpdo_start(r->rt, r->tool, slot, 200) == CO_RT_ERR_CLOSED ||
            co_rt_rpdo_sync(r->rt, r->tool, slot, 1 + (int)(n % 3u), 0) == CO_RT_ERR_CLOSED) {
            break;
        }
        usleep(300);
        co_rt_rpdo_stats_t st;
        if (co_rt_rpdo_stats(r->rt, r->tool, slot, &st) == CO_RT_ERR_CLOSED ||
            co_rt_rpdo_stop(r->rt, r->tool, slot) == CO_RT_ERR_CLOSED ||
            co_rt_rpdo_close(r->rt, r->tool, slot) == CO_RT_ERR_CLOSED) {
            break;
        }
    }
    atomic_fetch_sub(&r->running, 1);
    return NULL;
}

static void *reader(void *arg)
{
    round_t *r = arg;
    co_rt_event_t events[64];
    for (;;) {
        int n = co_rt_wait_events(r->rt, events, 64, 50);
        if (n < 0) {
            break;                     /* CO_RT_ERR_CLOSED */
        }
        atomic_fetch_add(&r->events, n);
    }
    atomic_fetch_sub(&r->running, 1);
    return NULL;
}

static int add_line(co_rt_t *rt)
{
    co_rt_line_config_t lc;
    memset(&lc, 0, sizeof lc);
    lc.driver = CO_DRIVER_MEMBUS;
    lc.channel = "stress";
    lc.mode = CO_MODE_FD;
    lc.brs = 1;
    return co_rt_add_line(rt, &lc);
}

/* One round: run_ms of everything at once, then the stop (limit = 0), or
 * `limit` transfers per worker to the end, then the stop. */
static bool run_round(int number, int run_ms, int limit)
{
    int fds_before = open_fds();
    round_t r;
    memset(&r, 0, sizeof r);
    r.limit = limit;
    r.rt = co_rt_new(0);
    if (!r.rt) {
        printf("round %d: co_rt_new failed\n", number);
        return false;
    }
    r.device = add_line(r.rt);
    r.tool = add_line(r.rt);
    co_rt_command_t c;
    memset(&c, 0, sizeof c);
    c.kind = CO_CMD_NODE_CREATE;
    c.line = r.device;
    c.args.node_create.node_id = NODE;
    bool ok = r.device >= 0 && r.tool >= 0 &&
              co_rt_od_define(r.rt, r.device, od_defs, sizeof od_defs / sizeof od_defs[0],
                              NULL) == 0 &&
              co_rt_start(r.rt) == 0 && co_rt_command(r.rt, &c) == 0 &&
              co_rt_usdo_client(r.rt, r.tool, TOOL) == 0;
    if (!ok) {
        char text[200];
        co_rt_last_error(r.rt, text, sizeof text);
        printf("round %d: set-up failed: %s\n", number, text);
        co_rt_free(r.rt);
        return false;
    }
    usleep(20000);                     /* the node boots */
    pthread_t threads[WORKERS + 3];
    atomic_store(&r.running, WORKERS + 3);
    worker_t workers[WORKERS];
    for (int i = 0; i < WORKERS; i++) {
        workers[i] = (worker_t){.round = &r, .id = i};
        pthread_create(&threads[i], NULL, worker, &workers[i]);
    }
    pthread_create(&threads[WORKERS], NULL, commander, &r);
    pthread_create(&threads[WORKERS + 1], NULL, reader, &r);
    pthread_create(&threads[WORKERS + 2], NULL, rpdo_driver, &r);
    if (limit) {
        while (atomic_load(&r.running) > 3) {
            usleep(1000);              /* the workers run their transfers to the end */
        }
    } else {
        usleep((useconds_t)run_ms * 1000u);
    }
    atomic_store(&r.stop_asked, true);
    co_rt_stop(r.rt);                  /* with transfers, waits and commands in flight */
    uint64_t deadline = now_ms() + JOIN_LIMIT_MS;
    while (atomic_load(&r.running) > 0 && now_ms() < deadline) {
        usleep(1000);
    }
    int hung = atomic_load(&r.running);
    if (hung > 0) {
        printf("round %d: %d threads still running %d ms after co_rt_stop: hang\n", number, hung,
               JOIN_LIMIT_MS);
        fflush(stdout);
        _exit(1);                      /* cannot free under them */
    }
    for (int i = 0; i < WORKERS + 3; i++) {
        pthread_join(threads[i], NULL);
    }
    co_rt_free(r.rt);
    int fds_after = open_fds();
    int okn = atomic_load(&r.ok), failed = atomic_load(&r.failed), wrong = atomic_load(&r.wrong);
    bool good = failed == 0 && wrong == 0 && fds_after == fds_before &&
                (!limit || okn == limit * WORKERS) && okn > 0;
    printf("round %2d: %s: %d transfers ok, %d ended by the stop, %d failed, %d wrong data, "
           "%d events, fds %d -> %d\n", number, good ? "ok" : "FAILED", okn,
           atomic_load(&r.closed), failed, wrong, atomic_load(&r.events), fds_before, fds_after);
    return good;
}

int main(void)
{
    int passed = 0, failed = 0;
    for (int i = 0; i < ROUNDS; i++) {
        /* stops at different moments of the traffic */
        if (run_round(i + 1, 30 + (i * 37) % 150, 0)) {
            passed++;
        } else {
            failed++;
        }
    }
    if (run_round(ROUNDS + 1, 0, TRANSFERS / WORKERS)) {
        passed++;
    } else {
        failed++;
    }
    printf("stress: %d passed, %d failed\n", passed, failed);
    return failed ? 1 : 0;
}
