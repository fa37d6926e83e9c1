/* USDO throughput: a server (csrc/core/co_usdo_server, an OD with an
 * UNSIGNED32 and a 1 MiB DOMAIN served by domain callbacks) on one fd line and
 * a client (csrc/core/co_usdo_client) on another, moving 4 B, 1 KiB, 64 KiB
 * and 1 MiB by expedited, segmented and bulk download and by expedited,
 * segmented and bulk upload (the bulk rows of both directions side by side),
 *   - over the in-process bus (co_membus: one loop processes both lines and
 *     transfers the frames), and
 *   - over SocketCAN (one co_socketcan socket per line on one interface, one
 *     thread running the runtime's loop: ppoll over both sockets, batched
 *     reads into co_line_receive, co_line_process, tx queue flushed with
 *     co_sc_write honouring would-block),
 * side by side with the raw 64-byte frame rate of the same bus measured in the
 * same run (membus: frames through co_membus; SocketCAN: bare CAN_RAW sockets
 * with sendmmsg/recvmmsg 32 per call, as bench/raw_socketcan, and the same
 * through the co_socketcan driver). The figure steered by, bulk download
 * 1 MiB as a share of (raw 64-byte frames/s x 60 B), comes from rounds of a
 * raw run and a bulk transfer back to back (the median round).
 *
 * Every row's data is verified byte for byte once, outside the timed runs
 * (and the destination again after them); every transfer of a timed run must
 * end without abort and move the whole size. Prints figures, asserts nothing
 * about timing. Exit status: 0 ok, 1 a transfer failed / data differed /
 * frames were lost (the tables are still printed), 2 usage or a bus that
 * cannot be used.
 *
 *   usdo_bench [-q] [-s] [-v] [-t SECONDS] [-r RUNS] [-n FRAMES] [-Q QUEUE] [BUS...]
 *   BUS = membus or a CAN FD interface (default: membus vcan0) */
#define _GNU_SOURCE /* ppoll, sendmmsg, recvmmsg; clock_gettime */

#include <errno.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "bench_util.h"
#include "canopenfd/co_line.h"
#include "canopenfd/co_membus.h"
#include "canopenfd/co_od.h"
#include "canopenfd/co_usdo.h"
#include "canopenfd/co_usdo_client.h"
#include "canopenfd/co_usdo_server.h"

#if defined(__linux__) && !defined(USDO_BENCH_NO_SOCKETCAN)
#define HAVE_SOCKETCAN 1
#include <net/if.h>
#include <poll.h>
#include <sys/socket.h>

#include <linux/can.h>
#include <linux/can/raw.h>

#include "canopenfd/co_socketcan.h"
#else
#define HAVE_SOCKETCAN 0
#endif

#define QUEUE_DEFAULT 1024       /* rx and tx queue of each line: the runtime's default */
#define QUEUE_MAX 4096
#define SERVER_NODE 5
#define CLIENT_NODE 1
#define IDX_U32 0x2000
#define IDX_DOMAIN 0x2001
#define DOMAIN_CAP (1u << 20)
#define SERVER_SESSIONS 8        /* as the runtime's server (RT_USDO_SESSIONS) */
#define CLIENT_SESSIONS 8
#define STALL_S 30.0             /* one transfer longer than this: cancelled, reported */
#define PAYLOAD 60.0             /* USDO segment data bytes per 64-byte frame */
#define RAW_ID 0x555u            /* CAN-ID of the reference frames */
#define RAW_BATCH 32             /* frames per sendmmsg/recvmmsg (= CO_SC_BATCH) */
#define POLL_CAP_US 100000u      /* longest ppoll sleep of the loop */

static const char *prog = "usdo_bench";

static struct options {
    double min_s;            /* minimum seconds of one timed run */
    unsigned runs;           /* timed runs per figure, best shown */
    uint64_t raw_frames;     /* frames per run of the reference figures */
    bool quick;
    bool verbose;
    bool steer_only;         /* -s: only the references and the steering figure */
    uint32_t queue;          /* -Q: rx and tx queue capacity of each line */
} opt = {1.0, 3, 100000, false, false, false, QUEUE_DEFAULT};

static int status = 0;       /* 1 once something failed */

/* Download source, upload sink (client side). */
static uint8_t src_data[DOMAIN_CAP];
static uint8_t sink_data[DOMAIN_CAP];

/* ================================================================ helpers */

static void die(int code, const char *fmt, ...) __attribute__((format(printf, 2, 3), noreturn));
static void die(int code, const char *fmt, ...)
{
    va_list ap;
    fflush(stdout);
    fprintf(stderr, "%s: ", prog);
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fputc('\n', stderr);
    exit(code);
}

static uint64_t mono_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

/* Pseudo-random bytes, different per seed. */
static void fill(uint8_t *p, uint32_t n, uint64_t seed)
{
    uint64_t s = seed * 0x9E3779B97F4A7C15ull + 1u;
    uint32_t i = 0;
    while (i < n) {
        uint64_t x = rng_next(&s);
        unsigned k;
        for (k = 0; k < 8 && i < n; k++, i++) {
            p[i] = (uint8_t)(x >> (8 * k));
        }
    }
}

static uint32_t le32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) |
           ((uint32_t)p[3] << 24);
}

static const char *size_label(uint32_t size)
{
    switch (size) {
    case 4:
        return "4 B";
    case 1024:
        return "1 KiB";
    case 65536:
        return "64 KiB";
    case 1u << 20:
        return "1 MiB";
    default:
        return "?";
    }
}

/* ================================================================ server's domain */

/* The DOMAIN 0x2001: a static buffer, written in place by downloads (in
 * order, chunk by chunk), read by uploads; `len` = bytes held. */
typedef struct domain {
    uint8_t data[DOMAIN_CAP];
    uint32_t len;
    uint32_t commits;        /* downloads that ended (last chunk) */
    uint32_t aborts;         /* downloads the server aborted */
} domain_t;

static domain_t dom;

static uint32_t dom_size(co_od_t *od, const co_od_entry_t *e, uint32_t *size, void *user)
{
    const domain_t *d = user;
    (void)od;
    (void)e;
    *size = d->len;
    return 0;
}

static uint32_t dom_read(co_od_t *od, const co_od_entry_t *e, uint32_t offset, uint8_t *buf,
                         uint32_t cap, uint32_t *n, bool *last, void *user)
{
    const domain_t *d = user;
    uint32_t k;
    (void)od;
    (void)e;
    if (offset > d->len) {
        return CO_ABORT_NO_DATA;
    }
    k = d->len - offset;
    if (k > cap) {
        k = cap;
    }
    memcpy(buf, d->data + offset, k);
    *n = k;
    *last = offset + k == d->len;
    return 0;
}

static uint32_t dom_write(co_od_t *od, const co_od_entry_t *e, uint32_t offset,
                          const uint8_t *data, uint32_t n, uint32_t total, bool last,
                          uint32_t abort, void *user)
{
    domain_t *d = user;
    (void)od;
    (void)e;
    if (abort != 0) {
        d->aborts++;
        return 0;
    }
    if ((total != CO_OD_SIZE_UNKNOWN && total > DOMAIN_CAP) || offset > DOMAIN_CAP ||
        n > DOMAIN_CAP - offset) {
        return CO_ABORT_LENGTH_HIGH;
    }
    if (n > 0) {
        memcpy(d->data + offset, data, n);
    }
    if (last) {
        d->len = offset + n;
        d->commits++;
    }
    return 0;
}

static const co_od_handler_t dom_handler = {
    .domain_size = dom_size,
    .domain_read = dom_read,
    .domain_write = dom_write,
};

/* ================================================================ the rig */

typedef struct side {
    co_line_t line;
    co_frame_t rx[QUEUE_MAX];
    co_frame_t tx[QUEUE_MAX];
    /* SocketCAN (stay 0 on membus) */
    uint32_t kernel_drops;   /* frames the socket buffer lost (SO_RXQ_OVFL) */
    uint32_t would_block;    /* writes refused with EAGAIN/ENOBUFS, waited */
    uint32_t tx_refused;     /* frames the kernel refused (dropped, as the runtime does) */
#if HAVE_SOCKETCAN
    co_socketcan_t sc;
    bool want_out;           /* waits for POLLOUT (EAGAIN) */
    uint64_t retry_at;       /* ENOBUFS: try again then */
#endif
} side_t;

/* The bench's own look at the bulk segments the server socket delivers (the
 * server aborts 0x14 at the first wrong counter and ignores the rest; this
 * tells a lost segment from a reordered one). */
typedef struct wire_check {
    bool active;             /* a bulk download seen starting */
    uint8_t session;
    uint8_t expect;          /* next counter */
    uint32_t segments;       /* of this transfer */
    uint32_t anomalies;      /* segments with an unexpected counter (all transfers) */
    unsigned logged;         /* lines in log (the first few of a row) */
    char log[4][120];
} wire_check_t;

typedef struct rig {
    const char *name;        /* "membus" or the interface */
    bool socket;
    side_t srv, cli;
    co_membus_t bus;
    co_od_t od;
    co_od_entry_t entries[4];
    uint8_t pool[64];
    co_od_subscription_t subs[4];
    co_usdo_server_t server;
    co_usdo_session_t sessions[SERVER_SESSIONS];
    uint8_t scratch[SERVER_SESSIONS * 8];
    co_usdo_client_t client;
    co_usdo_client_session_t csessions[CLIENT_SESSIONS];
    bool done;               /* set by the request's done() */
    uint32_t poll_cap_us;
    /* counted over the rig's life */
    uint32_t stalls;         /* transfers cancelled after STALL_S */
    uint32_t mismatches;     /* verification failures */
    uint64_t iterations;     /* loop iterations */
    uint64_t polls;          /* ppoll calls */
    uint32_t softnet_base;   /* softnet_drops() at the start, plus those of reference
                                runs in between (not the rig's) */
    wire_check_t wire;
} rig_t;

static rig_t rig;

static void side_init(side_t *s)
{
    co_line_config_t cfg;
    memset(&cfg, 0, sizeof cfg);
    cfg.mode = CO_MODE_FD;
    cfg.brs = true;
    cfg.rx_slots = s->rx;
    cfg.rx_capacity = opt.queue;
    cfg.tx_slots = s->tx;
    cfg.tx_capacity = opt.queue;
    if (!co_line_init(&s->line, &cfg)) {
        die(2, "co_line_init failed");
    }
#if HAVE_SOCKETCAN
    co_sc_init(&s->sc);
#endif
}

static void build_od(rig_t *r)
{
    co_od_def_t d;
    co_od_init(&r->od, CO_MODE_FD, r->entries, 4, r->pool, sizeof r->pool, r->subs, 4);
    memset(&d, 0, sizeof d);
    d.index = IDX_U32;
    d.object_code = CO_OBJECT_VAR;
    d.type = CO_TYPE_UNSIGNED32;
    d.access = CO_ACCESS_RW;
    d.size = 4;
    if (co_od_add(&r->od, &d) != CO_OD_ADDED) {
        die(2, "co_od_add U32 failed");
    }
    memset(&d, 0, sizeof d);
    d.index = IDX_DOMAIN;
    d.object_code = CO_OBJECT_VAR;
    d.type = CO_TYPE_DOMAIN;
    d.access = CO_ACCESS_RW;
    if (co_od_add(&r->od, &d) != CO_OD_ADDED) {
        die(2, "co_od_add DOMAIN failed");
    }
    if (!co_od_seal(&r->od, SERVER_NODE) ||
        !co_od_subscribe(&r->od, IDX_DOMAIN, 0, IDX_DOMAIN, 0, &dom_handler, &dom)) {
        die(2, "co_od_seal / co_od_subscribe failed");
    }
}

#if HAVE_SOCKETCAN
static bool open_side(side_t *s, const char *ifname)
{
    char err[256];
    if (co_sc_open(&s->sc, ifname, CO_MODE_FD, err, sizeof err) != CO_SC_OPEN_OK) {
        fprintf(stderr, "%s: %s\n", prog, err);
        return false;
    }
    return true;
}
#endif

/* Frames the kernel dropped from its per-CPU input backlog (second column of
 * /proc/net/softnet_stat, summed over CPUs): where a local CAN frame goes on
 * its way to the receiving sockets (can_send -> netif_rx). Such a drop is
 * seen neither by the sender nor by the receiving socket's SO_RXQ_OVFL. */
static uint32_t softnet_drops(void)
{
    uint32_t sum = 0;
#if HAVE_SOCKETCAN
    char line[512];
    FILE *f = fopen("/proc/net/softnet_stat", "r");
    if (f == NULL) {
        return 0;
    }
    while (fgets(line, sizeof line, f) != NULL) {
        unsigned processed, dropped;
        if (sscanf(line, "%x %x", &processed, &dropped) == 2) {
            sum += dropped;
        }
    }
    fclose(f);
#endif
    return sum;
}

static void rig_close(rig_t *r)
{
#if HAVE_SOCKETCAN
    co_sc_close(&r->srv.sc);
    co_sc_close(&r->cli.sc);
#else
    (void)r;
#endif
}

/* False when the bus cannot be used (message printed). */
static bool rig_init(rig_t *r, const char *bus)
{
    co_usdo_server_config_t scfg;
    co_usdo_client_config_t ccfg;
    memset(r, 0, sizeof *r);
    r->name = bus;
    r->socket = strcmp(bus, "membus") != 0;
    r->poll_cap_us = POLL_CAP_US;
    side_init(&r->srv);
    side_init(&r->cli);
    co_line_set_node_id(&r->srv.line, SERVER_NODE);   /* the server reads it from the line */
    build_od(r);

    memset(&scfg, 0, sizeof scfg);
    scfg.sessions = r->sessions;
    scfg.session_count = SERVER_SESSIONS;
    scfg.scratch = r->scratch;
    scfg.scratch_size = co_usdo_server_scratch_need(&r->od);
    if (scfg.scratch_size * SERVER_SESSIONS > sizeof r->scratch ||
        !co_usdo_server_init(&r->server, &r->srv.line, &r->od, &scfg)) {
        die(2, "co_usdo_server_init failed");
    }
    memset(&ccfg, 0, sizeof ccfg);
    ccfg.sessions = r->csessions;
    ccfg.session_count = CLIENT_SESSIONS;
    ccfg.node_id = CLIENT_NODE;
    if (!co_usdo_client_init(&r->client, &r->cli.line, &ccfg)) {
        die(2, "co_usdo_client_init failed");
    }

    if (!r->socket) {
        co_membus_init(&r->bus);
        co_membus_attach(&r->bus, &r->srv.line);
        co_membus_attach(&r->bus, &r->cli.line);
        return true;
    }
#if HAVE_SOCKETCAN
    r->softnet_base = softnet_drops();
    if (!open_side(&r->srv, bus) || !open_side(&r->cli, bus)) {
        rig_close(r);
        return false;
    }
    return true;
#else
    fprintf(stderr, "%s: %s: built without SocketCAN (not Linux)\n", prog, bus);
    return false;
#endif
}

/* ---------------------------------------------------------------- membus loop */

static void membus_iterate(rig_t *r)
{
    uint64_t now = mono_us();
    (void)co_line_process(&r->srv.line, now);
    (void)co_line_process(&r->cli.line, now);
    (void)co_membus_transfer(&r->bus, NULL, NULL);
}

/* ---------------------------------------------------------------- socket loop */

#if HAVE_SOCKETCAN
static uint64_t min_u64(uint64_t a, uint64_t b) { return a < b ? a : b; }

/* A frame the server socket delivered: follow the bulk segment counters. */
static void wire_check(wire_check_t *w, const co_frame_t *f)
{
    co_usdo_msg_t m;
    if (f->id != co_usdo_request_id(CLIENT_NODE) ||
        co_usdo_decode(f->data, f->len, &m) == CO_USDO_DECODE_EMPTY) {
        return;
    }
    if (m.cs == CO_USDO_CS_BULK_INITIATE) {
        w->active = true;
        w->session = m.session;
        w->expect = 0;
        w->segments = 0;
        return;
    }
    if ((m.cs != CO_USDO_CS_BULK_SEGMENT && m.cs != CO_USDO_CS_BULK_LAST) || !w->active ||
        m.session != w->session) {
        return;
    }
    if (m.cs == CO_USDO_CS_BULK_SEGMENT && m.counter != w->expect) {
        w->anomalies++;
        if (w->logged < 4) {
            snprintf(w->log[w->logged++], sizeof w->log[0],
                     "bulk segment #%u of session %u: counter 0x%02X, expected 0x%02X "
                     "(%u ahead, mod 256)", (unsigned)w->segments, (unsigned)w->session,
                     m.counter, w->expect, (unsigned)(uint8_t)(m.counter - w->expect));
        }
    }
    w->segments++;
    w->expect = co_usdo_next_counter(m.counter);
}

/* As the runtime's socket_read: only what rx can hold; the rest waits in the
 * socket buffer. */
static void sock_read(side_t *s, wire_check_t *w)
{
    co_sc_rx_t items[CO_SC_BATCH];
    uint32_t room;
    while ((room = co_line_rx_free(&s->line)) > 0) {
        unsigned got = 0, i;
        uint8_t e;
        co_sc_io_t res = co_sc_read(&s->sc, items, room < CO_SC_BATCH ? room : CO_SC_BATCH,
                                    &got);
        for (i = 0; i < got; i++) {
            for (e = 0; e < items[i].event_count; e++) {
                co_line_comm_event(&s->line, items[i].events[e]);
            }
            if (items[i].has_frame) {
                if (w != NULL) {
                    wire_check(w, &items[i].frame);
                }
                (void)co_line_receive(&s->line, &items[i].frame);
            }
        }
        s->kernel_drops = s->sc.stats.kernel_drops;
        if (res == CO_SC_FAILED) {
            die(2, "%s: read failed: %s", s->sc.ifname, strerror(s->sc.last_errno));
        }
        if (res != CO_SC_DONE) {
            return;
        }
    }
}

/* As the runtime's flush_socket: frames leave the tx queue only once the
 * kernel took them; EAGAIN waits for POLLOUT, ENOBUFS retries after 1 ms.
 * Returns when to try again. */
static uint64_t sock_flush(side_t *s, uint64_t now)
{
    co_frame_t batch[CO_SC_BATCH];
    if (s->want_out) {
        return CO_TIME_NEVER;
    }
    if (now < s->retry_at) {
        return s->retry_at;
    }
    while (co_line_tx_count(&s->line) > 0) {
        unsigned n, sent = 0, i;
        co_frame_t f;
        co_sc_io_t res;
        for (n = 0; n < CO_SC_BATCH && n < co_line_tx_count(&s->line); n++) {
            batch[n] = *co_line_tx_at(&s->line, n);
        }
        res = co_sc_write(&s->sc, batch, n, &sent);
        for (i = 0; i < sent; i++) {
            (void)co_line_tx_pop(&s->line, &f);
        }
        if (res == CO_SC_WOULD_BLOCK) {
            s->would_block++;
            if (s->sc.last_errno == ENOBUFS) {
                s->retry_at = now + 1000u;
                return s->retry_at;
            }
            s->want_out = true;
            return CO_TIME_NEVER;
        }
        if (res == CO_SC_FAILED) {
            int e = s->sc.last_errno;
            if (e != EINVAL && e != EMSGSIZE && e != EPERM) {
                die(2, "%s: write failed: %s", s->sc.ifname, strerror(e));
            }
            (void)co_line_tx_pop(&s->line, &f);   /* refused frame: dropped, counted */
            s->tx_refused++;
        }
    }
    return CO_TIME_NEVER;
}

/* One turn of the runtime's loop: process both lines, flush both tx queues,
 * sleep in ppoll until a socket is readable (or writable when waited for) or
 * the next timer is due, read what arrived. */
static void sock_iterate(rig_t *r)
{
    side_t *sides[2] = {&r->srv, &r->cli};
    struct pollfd p[2];
    struct timespec ts;
    uint64_t now = mono_us(), next = CO_TIME_NEVER, wait;
    int i, n;
    for (i = 0; i < 2; i++) {
        next = min_u64(next, co_line_process(&sides[i]->line, now));
    }
    for (i = 0; i < 2; i++) {
        next = min_u64(next, sock_flush(sides[i], now));
    }
    /* sending may have armed timers (the client told of free tx space) */
    for (i = 0; i < 2; i++) {
        next = min_u64(next, co_timer_list_next(co_line_timers(&sides[i]->line)));
    }
    if (r->done) {
        return;
    }
    for (i = 0; i < 2; i++) {
        p[i].fd = sides[i]->sc.fd;
        p[i].events = (short)(POLLIN | (sides[i]->want_out ? POLLOUT : 0));
        p[i].revents = 0;
    }
    wait = next <= now ? 0 : min_u64(next - now, r->poll_cap_us);
    ts.tv_sec = (time_t)(wait / 1000000u);
    ts.tv_nsec = (long)(wait % 1000000u) * 1000L;
    r->polls++;
    n = ppoll(p, 2, &ts, NULL);
    if (n < 0 && errno != EINTR) {
        die(2, "ppoll: %s", strerror(errno));
    }
    for (i = 0; i < 2 && n > 0; i++) {
        if (p[i].revents & POLLOUT) {
            sides[i]->want_out = false;
        }
        if (p[i].revents & (POLLIN | POLLERR | POLLHUP)) {
            sock_read(sides[i], i == 0 ? &r->wire : NULL);
        }
    }
}
#endif

static void iterate(rig_t *r)
{
    r->iterations++;
#if HAVE_SOCKETCAN
    if (r->socket) {
        sock_iterate(r);
        return;
    }
#endif
    membus_iterate(r);
}

/* Let stray frames (after a failure) arrive and be processed: ~20 ms. */
static void settle(rig_t *r)
{
    uint64_t until = mono_us() + 20000u;
    r->done = false;
    r->poll_cap_us = 1000u;
    while (mono_us() < until) {
        iterate(r);
    }
    r->poll_cap_us = POLL_CAP_US;
}

/* ---------------------------------------------------------------- transfers */

static void on_done(co_usdo_request_t *req)
{
    rig_t *r = req->user;
    r->done = true;
}

/* Run one request to its end; returns its abort code (0 = ok). */
static uint8_t transfer(rig_t *r, co_usdo_request_t *req)
{
    uint8_t code;
    uint64_t k = 0;
    double t0 = 0;
    r->done = false;
    /* the client arms its timers from the line's time of its last process
     * call: bring it up to now first (co_line.h) */
    co_line_set_time(&r->cli.line, mono_us());
    code = co_usdo_client_start(&r->client, req);
    if (code != 0) {
        return code;
    }
    while (!r->done) {
        iterate(r);
        /* membus: no clock read per iteration for the guard */
        if (r->socket || (++k & 1023u) == 0) {
            if (t0 == 0) {
                t0 = now_s();
            } else if (now_s() - t0 > STALL_S) {
                r->stalls++;
                (void)co_usdo_client_cancel(&r->client, req, 0);
            }
        }
    }
    return req->abort;
}

typedef enum { OP_DOWNLOAD, OP_UPLOAD } op_t;

typedef struct row_def {
    op_t op;
    uint8_t mode;            /* co_usdo_mode_t; uploads: what the server picks */
    uint32_t size;
} row_def_t;

static const row_def_t rows[] = {
    {OP_DOWNLOAD, CO_USDO_MODE_EXPEDITED, 4},
    {OP_UPLOAD, CO_USDO_MODE_EXPEDITED, 4},
    {OP_DOWNLOAD, CO_USDO_MODE_SEGMENTED, 1024},
    {OP_DOWNLOAD, CO_USDO_MODE_BULK, 1024},
    {OP_UPLOAD, CO_USDO_MODE_SEGMENTED, 1024},
    {OP_UPLOAD, CO_USDO_MODE_BULK, 1024},
    {OP_DOWNLOAD, CO_USDO_MODE_SEGMENTED, 65536},
    {OP_DOWNLOAD, CO_USDO_MODE_BULK, 65536},
    {OP_UPLOAD, CO_USDO_MODE_SEGMENTED, 65536},
    {OP_UPLOAD, CO_USDO_MODE_BULK, 65536},
    {OP_DOWNLOAD, CO_USDO_MODE_SEGMENTED, 1u << 20},
    {OP_DOWNLOAD, CO_USDO_MODE_BULK, 1u << 20},
    {OP_UPLOAD, CO_USDO_MODE_SEGMENTED, 1u << 20},
    {OP_UPLOAD, CO_USDO_MODE_BULK, 1u << 20},
};
#define ROWS (sizeof rows / sizeof rows[0])

static const char *mode_name(uint8_t mode)
{
    switch (mode) {
    case CO_USDO_MODE_EXPEDITED:
        return "expedited";
    case CO_USDO_MODE_SEGMENTED:
        return "segmented";
    case CO_USDO_MODE_BULK:
        return "bulk";
    default:
        return "auto";
    }
}

static void make_request(rig_t *r, const row_def_t *d, co_usdo_request_t *req,
                         co_usdo_buffer_t *buf)
{
    memset(req, 0, sizeof *req);
    req->server = SERVER_NODE;
    req->index = d->size == 4 ? IDX_U32 : IDX_DOMAIN;
    req->sub = 0;
    req->upload = d->op == OP_UPLOAD;
    req->done = on_done;
    req->user = r;
    req->ctx = buf;
    if (req->upload) {
        buf->data = sink_data;
        buf->size = 0;
        buf->capacity = DOMAIN_CAP;
        req->sink = co_usdo_buffer_sink;
        /* bulk rows ask for it; the others let the server pick */
        req->mode = d->mode == CO_USDO_MODE_BULK ? (uint8_t)CO_USDO_MODE_BULK
                                                 : (uint8_t)CO_USDO_MODE_AUTO;
    } else {
        buf->data = src_data;
        buf->size = d->size;
        buf->capacity = d->size;
        req->source = co_usdo_buffer_source;
        req->size = d->size;
        req->mode = d->mode;
        req->type = d->size == 4 ? (uint8_t)CO_TYPE_UNSIGNED32 : (uint8_t)CO_TYPE_DOMAIN;
    }
}

/* ---------------------------------------------------------------- problem counters */

/* Everything that means a frame was lost or a transfer went wrong. */
#define PROBLEMS(X)                                                                   \
    X("kernel input backlog drops (softnet_stat)",                                    \
      r->socket ? softnet_drops() - r->softnet_base : 0)                              \
    X("server line rx overflow", r->srv.line.stats.rx_overflow)                       \
    X("server line tx overflow", r->srv.line.stats.tx_overflow)                       \
    X("client line rx overflow", r->cli.line.stats.rx_overflow)                       \
    X("client line tx overflow", r->cli.line.stats.tx_overflow)                       \
    X("server line rx invalid", r->srv.line.stats.rx_invalid)                         \
    X("client line rx invalid", r->cli.line.stats.rx_invalid)                         \
    X("server socket kernel drops", r->srv.kernel_drops)                              \
    X("client socket kernel drops", r->cli.kernel_drops)                              \
    X("server frames refused by the kernel", r->srv.tx_refused)                       \
    X("client frames refused by the kernel", r->cli.tx_refused)                       \
    X("client failed", r->client.stats.failed)                                        \
    X("client refused starts", r->client.stats.refused)                               \
    X("client timeouts", r->client.stats.timeouts)                                    \
    X("client aborts received", r->client.stats.aborts_received)                      \
    X("client aborts sent", r->client.stats.aborts_sent)                              \
    X("client tx_failed (queue full)", r->client.stats.tx_failed)                     \
    X("client rx_unexpected", r->client.stats.rx_unexpected)                          \
    X("client rx_no_session", r->client.stats.rx_no_session)                          \
    X("client rx_malformed", r->client.stats.rx_malformed)                            \
    X("client rx_bad_counter", r->client.stats.rx_bad_counter)                        \
    X("client rx_size_mismatch", r->client.stats.rx_size_mismatch)                    \
    X("client bulk_fallback", r->client.stats.bulk_fallback)                          \
    X("server rx_malformed", r->server.stats.rx_malformed)                            \
    X("server rx_unknown_command", r->server.stats.rx_unknown_command)                \
    X("server rx_no_session", r->server.stats.rx_no_session)                          \
    X("server rx_stray_bulk", r->server.stats.rx_stray_bulk)                          \
    X("server rx_stray_ack (bulk upload)", r->server.stats.rx_stray_ack)              \
    X("client bulk upload receive budget full", r->client.stats.bulk_budget_full)     \
    X("server rx_bad_counter", r->server.stats.rx_bad_counter)                        \
    X("server rx_size_mismatch", r->server.stats.rx_size_mismatch)                    \
    X("server rx_client_abort", r->server.stats.rx_client_abort)                      \
    X("server timeouts", r->server.stats.timeouts)                                    \
    X("server od_aborts", r->server.stats.od_aborts)                                  \
    X("server aborts_sent", r->server.stats.aborts_sent)                              \
    X("server tx_failed (queue full)", r->server.stats.tx_failed)                     \
    X("server busy", r->server.stats.busy)                                            \
    X("domain writes aborted", dom.aborts)                                            \
    X("transfers stalled > 30 s (cancelled)", r->stalls)                              \
    X("data differed", r->mismatches)                                                 \
    X("bulk segments out of sequence at the server socket", r->wire.anomalies)

#define COUNT_ONE(name, expr) +1
enum { NPROBLEMS = 0 PROBLEMS(COUNT_ONE) };

typedef struct snapshot {
    uint32_t v[NPROBLEMS];
    /* information, not problems */
    uint64_t iterations, polls;
    uint32_t bulk_paused, would_block, frames;
} snapshot_t;

static void snap(const rig_t *r, snapshot_t *s)
{
    unsigned k = 0;
#define SNAP_ONE(name, expr) s->v[k++] = (uint32_t)(expr);
    PROBLEMS(SNAP_ONE)
#undef SNAP_ONE
    s->iterations = r->iterations;
    s->polls = r->polls;
    s->bulk_paused = r->client.stats.bulk_paused;
    s->would_block = r->srv.would_block + r->cli.would_block;
    s->frames = r->srv.line.stats.tx_frames + r->cli.line.stats.tx_frames;
}

/* Print the problem counters that moved since `before`; returns how many. */
static unsigned report_problems(rig_t *r, const snapshot_t *before)
{
    static const char *const names[] = {
#define NAME_ONE(name, expr) name,
        PROBLEMS(NAME_ONE)
#undef NAME_ONE
    };
    snapshot_t now;
    unsigned i, moved = 0;
    snap(r, &now);
    for (i = 0; i < NPROBLEMS; i++) {
        if (now.v[i] != before->v[i]) {
            printf("  ! %s: %u\n", names[i], (unsigned)(now.v[i] - before->v[i]));
            moved++;
        }
    }
    for (i = 0; i < r->wire.logged; i++) {
        printf("    %s\n", r->wire.log[i]);
    }
    r->wire.logged = 0;
    return moved;
}

/* ---------------------------------------------------------------- one row */

typedef struct row_result {
    double rate;             /* transfers/s of the best run */
    uint64_t transfers;      /* in the best run */
    uint32_t failed;         /* over all runs and the verification */
    uint32_t frames;         /* frames on the bus per transfer (verification) */
} row_result_t;

/* Verified transfer: fresh data at the source, a cleared destination, then
 * byte for byte. Returns false (printed) when anything is off. */
static bool verified_transfer(rig_t *r, const row_def_t *d, uint64_t seed, row_result_t *res)
{
    co_usdo_request_t req;
    co_usdo_buffer_t buf;
    snapshot_t before, after;
    uint8_t code, expect_type;
    bool ok = true;
    uint8_t value[4];

    make_request(r, d, &req, &buf);
    if (d->op == OP_DOWNLOAD) {
        fill(src_data, d->size, seed);
        if (d->size == 4) {
            memset(value, 0, sizeof value);
            (void)co_od_put(&r->od, IDX_U32, 0, value, 4);
        } else {
            memset(dom.data, 0, d->size);
            dom.len = 0;
        }
    } else {
        if (d->size == 4) {
            fill(value, 4, seed);
            if (co_od_put(&r->od, IDX_U32, 0, value, 4) != 0) {
                die(2, "co_od_put failed");
            }
        } else {
            fill(dom.data, d->size, seed);
            dom.len = d->size;
        }
        memset(sink_data, 0, d->size);
    }
    snap(r, &before);
    code = transfer(r, &req);
    snap(r, &after);
    res->frames = after.frames - before.frames;
    if (code != 0) {
        printf("  ! verification transfer aborted: 0x%02X (%s)\n", code,
               req.abort_from_server ? "by the server" : "by the client");
        res->failed++;
        return false;
    }
    if (d->op == OP_DOWNLOAD) {
        uint32_t got;
        if (req.transferred != d->size || req.result_mode != d->mode) {
            printf("  ! download: %u of %u bytes transferred, mode %s (asked %s)\n",
                   (unsigned)req.transferred, (unsigned)d->size, mode_name(req.result_mode),
                   mode_name(d->mode));
            ok = false;
        }
        if (d->size == 4) {
            if (!co_od_get_u32(&r->od, IDX_U32, 0, &got) || got != le32(src_data)) {
                printf("  ! download: U32 holds 0x%08X, sent 0x%08X\n", (unsigned)got,
                       (unsigned)le32(src_data));
                ok = false;
            }
        } else if (dom.len != d->size || memcmp(dom.data, src_data, d->size) != 0) {
            printf("  ! download: the domain holds %u bytes that differ from the %u sent\n",
                   (unsigned)dom.len, (unsigned)d->size);
            ok = false;
        }
    } else {
        const uint8_t *expect = d->size == 4 ? value : dom.data;
        expect_type = d->size == 4 ? (uint8_t)CO_TYPE_UNSIGNED32 : (uint8_t)CO_TYPE_DOMAIN;
        if (d->mode == CO_USDO_MODE_BULK && req.result_mode != CO_USDO_MODE_BULK) {
            printf("  ! upload: mode %s, asked bulk\n", mode_name(req.result_mode));
            ok = false;
        }
        if (buf.size != d->size || memcmp(sink_data, expect, d->size) != 0) {
            printf("  ! upload: %u bytes received that differ from the %u served\n",
                   (unsigned)buf.size, (unsigned)d->size);
            ok = false;
        }
        if (req.result_type != expect_type) {
            printf("  ! upload: data type 0x%02X, the entry has 0x%02X\n", req.result_type,
                   expect_type);
            ok = false;
        }
    }
    if (!ok) {
        r->mismatches++;
        res->failed++;
    }
    return ok;
}

/* The destination still holds the verified data after the timed runs. */
static void check_after(rig_t *r, const row_def_t *d, const co_usdo_buffer_t *buf)
{
    bool ok;
    if (d->size == 4) {
        uint32_t got = 0;
        if (d->op == OP_DOWNLOAD) {
            ok = co_od_get_u32(&r->od, IDX_U32, 0, &got) && got == le32(src_data);
        } else {
            ok = co_od_get_u32(&r->od, IDX_U32, 0, &got) && buf->size == 4 &&
                 got == le32(sink_data);
        }
    } else if (d->op == OP_DOWNLOAD) {
        ok = dom.len == d->size && memcmp(dom.data, src_data, d->size) == 0;
    } else {
        ok = buf->size == d->size && memcmp(sink_data, dom.data, d->size) == 0;
    }
    if (!ok) {
        printf("  ! the data after the timed runs differ\n");
        r->mismatches++;
    }
}

static void print_table_header(void)
{
    printf("%-5s %-8s %-9s %-10s %6s %13s %10s %13s %12s %8s %7s\n", "USDO", "bus", "op", "mode",
           "size", "transfers/s", "MB/s", "share of raw", "frames/xfer", "xfers", "failed");
    printf("%-5s %-8s %-9s %-10s %6s %13s %10s %13s %12s %8s %7s\n", "----", "---", "--", "----",
           "----", "-----------", "----", "------------", "-----------", "-----", "------");
}

/* One timed run: the request again and again until min_s passed (at
 * least once); returns good transfers/s, *count = good transfers, failures
 * added to *failed. */
static double timed_run(rig_t *r, const row_def_t *d, co_usdo_request_t *req, double min_s,
                        uint64_t *count, uint32_t *failed)
{
    uint64_t n = 0;
    double t0 = now_s(), t;
    do {
        uint8_t code = transfer(r, req);
        if (code != 0 || req->transferred != d->size) {
            (*failed)++;   /* its time counts, its bytes do not */
        } else {
            n++;
        }
        t = now_s() - t0;
    } while (t < min_s);
    *count = n;
    return (double)n / t;
}

/* Verify, then opt.runs timed runs of >= opt.min_s each; print the best. */
static double measure_row(rig_t *r, const row_def_t *d, unsigned index, double ref_fps)
{
    co_usdo_request_t req;
    co_usdo_buffer_t buf;
    row_result_t res;
    snapshot_t before, after;
    unsigned run;
    uint64_t all;
    double mbps;
    char share[24];

    memset(&res, 0, sizeof res);
    snap(r, &before);
    if (!verified_transfer(r, d, 0x5EED0000u + index, &res)) {
        status = 1;
        settle(r);
        (void)report_problems(r, &before);
        printf("%-5s %-8s %-9s %-10s %6s  (not measured: the verification failed)\n", "USDO",
               r->name, d->op == OP_DOWNLOAD ? "download" : "upload", mode_name(d->mode),
               size_label(d->size));
        return 0;
    }
    make_request(r, d, &req, &buf);
    all = 1;   /* the verification */
    for (run = 0; run < opt.runs; run++) {
        uint64_t n = 0;
        double rate = timed_run(r, d, &req, opt.min_s, &n, &res.failed);
        all += n;
        if (rate > res.rate) {
            res.rate = rate;
            res.transfers = n;
        }
    }
    if (res.failed == 0) {   /* else the destination may hold an aborted transfer */
        check_after(r, d, &buf);
    }
    snap(r, &after);

    mbps = res.rate * d->size / 1e6;
    if (d->size > CO_USDO_EXPEDITED_MAX && ref_fps > 0) {
        snprintf(share, sizeof share, "%.1f %%", 100.0 * mbps / (ref_fps * PAYLOAD / 1e6));
    } else {
        snprintf(share, sizeof share, "-");
    }
    printf("%-5s %-8s %-9s %-10s %6s %13.1f %10.3f %13s %12u %8llu %7u\n", "USDO", r->name,
           d->op == OP_DOWNLOAD ? "download" : "upload", mode_name(d->mode), size_label(d->size),
           res.rate, mbps, share, (unsigned)res.frames, (unsigned long long)res.transfers,
           (unsigned)res.failed);
    if (opt.verbose) {
        double xfers = (double)all;
        printf("        (per transfer: %.1f loop turns, %.1f ppoll, %.2f bulk pauses, "
               "%.2f would-block)\n",
               (double)(after.iterations - before.iterations) / xfers,
               (double)(after.polls - before.polls) / xfers,
               (double)(after.bulk_paused - before.bulk_paused) / xfers,
               (double)(after.would_block - before.would_block) / xfers);
    }
    if (res.failed != 0) {
        status = 1;
        settle(r);
    }
    if (report_problems(r, &before) != 0) {
        status = 1;
    }
    fflush(stdout);
    return mbps;
}

/* ================================================================ references */

typedef struct ref_result {
    uint64_t sent;
    uint64_t received;       /* good frames */
    uint64_t bad;            /* wrong content or out of sequence */
    uint32_t drops;          /* kernel drops (driver figure) */
    uint32_t backlog;        /* of the lost: dropped from the kernel's input backlog */
    double seconds;
} ref_result_t;

static double ref_fps(const ref_result_t *x)
{
    return x->seconds > 0 ? (double)x->received / x->seconds : 0;
}

static void print_ref_header(void)
{
    printf("%-58s %10s %8s %12s %11s %7s\n", "reference: 64-byte frames, one thread", "frames",
           "time s", "frames/s", "MB/s @60 B", "lost");
    printf("%-58s %10s %8s %12s %11s %7s\n", "-------------------------------------", "------",
           "------", "--------", "----------", "----");
}

typedef void (*ref_run_fn)(const char *bus, uint64_t frames, ref_result_t *x);

/* Frames of a reference run that did not arrive good (lost, out of
 * sequence, corrupted, dropped by a socket buffer); status 1 when any. */
static uint64_t ref_lost(const ref_result_t *x)
{
    uint64_t lost = x->sent - x->received + x->drops;
    if (lost != 0) {
        status = 1;
    }
    return lost;
}

/* Best of opt.runs runs of `fn`, printed; returns its frames/s. */
static double best_ref(const char *what, ref_run_fn fn, const char *bus)
{
    ref_result_t best, cur;
    uint64_t lost = 0, backlog = 0;
    unsigned run;
    double fps;
    memset(&best, 0, sizeof best);
    for (run = 0; run < opt.runs; run++) {
        fn(bus, opt.raw_frames, &cur);
        lost += ref_lost(&cur);
        backlog += cur.backlog;
        if (run == 0 || ref_fps(&cur) > ref_fps(&best)) {
            best = cur;
        }
    }
    fps = ref_fps(&best);
    printf("%-58s %10llu %8.3f %12.0f %11.2f %7llu\n", what,
           (unsigned long long)best.received, best.seconds, fps, fps * PAYLOAD / 1e6,
           (unsigned long long)lost);
    if (lost) {
        printf("  ! frames lost or out of sequence in the reference runs (%llu dropped from "
               "the kernel's input backlog)\n", (unsigned long long)backlog);
    }
    fflush(stdout);
    return fps;
}

/* ---------------------------------------------------------------- membus */

typedef struct counter {
    uint64_t frames;
} counter_t;

static void count_rx(co_line_t *line, const co_frame_t *frame, void *user)
{
    counter_t *c = user;
    (void)line;
    (void)frame;
    c->frames++;
}

/* 64-byte frames through co_membus: co_line_send (256 per round, or the
 * queue capacity when smaller) on one line,
 * co_membus_transfer, co_line_process + dispatch on the other (as
 * core_bench (a), "fd + BRS, 64-byte frames"); `frames` frames and at least
 * opt.min_s / 4 seconds per run. */
static void membus_ref_run(const char *bus, uint64_t frames, ref_result_t *x)
{
    static side_t a, b;
    static co_membus_t mb;
    static counter_t c;
    static bool ready;
    uint8_t data[64];
    uint64_t now = mono_us();
    uint32_t overflows;
    double t0;
    unsigned k;

    (void)bus;
    if (!ready) {
        side_init(&a);
        side_init(&b);
        co_membus_init(&mb);
        co_membus_attach(&mb, &a.line);
        co_membus_attach(&mb, &b.line);
        if (!co_line_subscribe(&b.line, 0x200, 0x27F, count_rx, &c)) {
            die(2, "co_line_subscribe failed");
        }
        ready = true;
    }
    for (k = 0; k < sizeof data; k++) {
        data[k] = (uint8_t)k;
    }
    memset(x, 0, sizeof *x);
    c.frames = 0;
    overflows = a.line.stats.tx_overflow + b.line.stats.rx_overflow;
    t0 = now_s();
    do {
        unsigned batch = opt.queue < 256 ? opt.queue : 256;
        for (k = 0; k < batch; k++) {
            (void)co_line_send(&a.line, 0x200 + (k & 0x7F), data, sizeof data);
        }
        x->sent += batch;
        (void)co_membus_transfer(&mb, NULL, NULL);
        (void)co_line_process(&b.line, now);
        x->seconds = now_s() - t0;
    } while (x->sent < frames || x->seconds < opt.min_s / 4);
    x->received = c.frames;
    x->drops = a.line.stats.tx_overflow + b.line.stats.rx_overflow - overflows;
}

/* ---------------------------------------------------------------- SocketCAN */

#if HAVE_SOCKETCAN
static void make_kframe(struct canfd_frame *f, uint32_t seq)
{
    unsigned i;
    memset(f, 0, sizeof *f);
    f->can_id = RAW_ID;
    f->len = CANFD_MAX_DLEN;
    f->flags = CANFD_BRS;
    for (i = 0; i < 4; i++) {
        f->data[i] = (uint8_t)(seq >> (8 * i));
    }
    for (i = 4; i < CANFD_MAX_DLEN; i++) {
        f->data[i] = (uint8_t)(seq + i);
    }
}

/* A received frame in sequence (bytes 0..3 = expected seq, pattern after). */
static void check_seq(ref_result_t *x, const uint8_t *data, uint8_t len, uint32_t id,
                      uint64_t *expect)
{
    uint32_t seq = le32(data);
    unsigned i;
    bool good = id == RAW_ID && len == CANFD_MAX_DLEN && seq == (uint32_t)*expect;
    for (i = 4; good && i < CANFD_MAX_DLEN; i++) {
        good = data[i] == (uint8_t)(seq + i);
    }
    if (good) {
        x->received++;
    } else {
        x->bad++;
    }
    *expect = (uint64_t)seq + 1;
}

static bool refused_errno(int e)
{
    return e == EAGAIN || e == EWOULDBLOCK || e == ENOBUFS || e == EINTR;
}

static void wait_io(int tx, int rx)
{
    struct pollfd p[2];
    p[0].fd = tx;
    p[0].events = POLLOUT;
    p[1].fd = rx;
    p[1].events = POLLIN;
    if (poll(p, 2, 1) < 0 && errno != EINTR) {
        die(2, "poll: %s", strerror(errno));
    }
}

static int raw_socket(const char *ifname, unsigned ifindex, bool receiver)
{
    struct sockaddr_can addr;
    int on = 1;
    int s = socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
    if (s < 0) {
        die(2, "socket(AF_CAN, CAN_RAW): %s", strerror(errno));
    }
    if (setsockopt(s, SOL_CAN_RAW, CAN_RAW_FD_FRAMES, &on, sizeof on) < 0) {
        die(2, "%s: CAN_RAW_FD_FRAMES: %s", ifname, strerror(errno));
    }
    if (receiver) {
        struct can_filter f;
        int size = 32 << 20;
        f.can_id = RAW_ID;
        f.can_mask = CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_SFF_MASK;
        if (setsockopt(s, SOL_CAN_RAW, CAN_RAW_FILTER, &f, sizeof f) < 0) {
            die(2, "CAN_RAW_FILTER: %s", strerror(errno));
        }
        if (setsockopt(s, SOL_SOCKET, SO_RCVBUFFORCE, &size, sizeof size) < 0) {
            (void)setsockopt(s, SOL_SOCKET, SO_RCVBUF, &size, sizeof size);
        }
    } else if (setsockopt(s, SOL_CAN_RAW, CAN_RAW_FILTER, NULL, 0) < 0) {
        die(2, "CAN_RAW_FILTER: %s", strerror(errno));
    }
    memset(&addr, 0, sizeof addr);
    addr.can_family = AF_CAN;
    addr.can_ifindex = (int)ifindex;
    if (bind(s, (struct sockaddr *)&addr, sizeof addr) < 0) {
        die(2, "bind to %s: %s", ifname, strerror(errno));
    }
    return s;
}

/* bench/raw_socketcan's batched figure: bare CAN_RAW sockets, sendmmsg of
 * 32 frames, after each send the receiver reads what was sent (recvmmsg, 32
 * per call); a refused send waits (poll <= 1 ms) and goes again. */
static void raw_kernel_run(int tx, int rx, uint64_t frames, ref_result_t *x)
{
    static struct canfd_frame tf[RAW_BATCH], rf[RAW_BATCH];
    static struct mmsghdr tm[RAW_BATCH], rm[RAW_BATCH];
    static struct iovec tiov[RAW_BATCH], riov[RAW_BATCH];
    uint64_t expect = 0;
    double t0, last;
    unsigned i;

    memset(x, 0, sizeof *x);
    t0 = now_s();
    last = t0;
    while (x->sent < frames || x->received + x->bad < x->sent) {
        if (x->sent < frames) {
            unsigned want = frames - x->sent < RAW_BATCH ? (unsigned)(frames - x->sent)
                                                         : RAW_BATCH;
            int n;
            for (i = 0; i < want; i++) {
                make_kframe(&tf[i], (uint32_t)(x->sent + i));
                tiov[i].iov_base = &tf[i];
                tiov[i].iov_len = CANFD_MTU;
                memset(&tm[i], 0, sizeof tm[i]);
                tm[i].msg_hdr.msg_iov = &tiov[i];
                tm[i].msg_hdr.msg_iovlen = 1;
            }
            n = sendmmsg(tx, tm, want, MSG_DONTWAIT);
            if (n < 0 && !refused_errno(errno)) {
                die(2, "sendmmsg: %s", strerror(errno));
            }
            if (n > 0) {
                x->sent += (uint64_t)n;
            }
            if (n < (int)want) {
                wait_io(tx, rx);
            }
        } else {
            struct pollfd p;
            p.fd = rx;
            p.events = POLLIN;
            if (poll(&p, 1, 500) == 0) {
                break;   /* the rest is lost */
            }
        }
        while (x->received + x->bad < x->sent) {
            uint64_t left = x->sent - x->received - x->bad;
            unsigned want = left < RAW_BATCH ? (unsigned)left : RAW_BATCH;
            int n;
            for (i = 0; i < want; i++) {
                riov[i].iov_base = &rf[i];
                riov[i].iov_len = sizeof rf[i];
                memset(&rm[i], 0, sizeof rm[i]);
                rm[i].msg_hdr.msg_iov = &riov[i];
                rm[i].msg_hdr.msg_iovlen = 1;
            }
            n = recvmmsg(rx, rm, want, MSG_DONTWAIT, NULL);
            if (n <= 0) {
                if (n < 0 && !refused_errno(errno)) {
                    die(2, "recvmmsg: %s", strerror(errno));
                }
                break;
            }
            for (i = 0; i < (unsigned)n; i++) {
                check_seq(x, rf[i].data, rm[i].msg_len == CANFD_MTU ? rf[i].len : 0,
                          rf[i].can_id, &expect);
            }
            last = now_s();
        }
        if (now_s() - last > 5.0) {
            break;   /* stalled: the rest counts as lost */
        }
    }
    x->seconds = last - t0;
}

/* The same through the co_socketcan driver: co_sc_write of 32 co_frame_t,
 * co_sc_read of up to 32 items. */
static void raw_driver_run(co_socketcan_t *tx, co_socketcan_t *rx, uint64_t frames,
                           ref_result_t *x)
{
    static co_frame_t batch[RAW_BATCH];
    static co_sc_rx_t items[RAW_BATCH];
    uint64_t expect = 0;
    uint32_t drops0 = rx->stats.kernel_drops;
    double t0, last;
    unsigned i;

    memset(x, 0, sizeof *x);
    t0 = now_s();
    last = t0;
    while (x->sent < frames || x->received + x->bad < x->sent) {
        if (x->sent < frames) {
            unsigned want = frames - x->sent < RAW_BATCH ? (unsigned)(frames - x->sent)
                                                         : RAW_BATCH;
            unsigned sent = 0;
            co_sc_io_t res;
            for (i = 0; i < want; i++) {
                uint32_t seq = (uint32_t)(x->sent + i);
                unsigned j;
                batch[i].id = RAW_ID;
                batch[i].len = 64;
                batch[i].flags = CO_FRAME_FD | CO_FRAME_BRS;
                for (j = 0; j < 4; j++) {
                    batch[i].data[j] = (uint8_t)(seq >> (8 * j));
                }
                for (j = 4; j < 64; j++) {
                    batch[i].data[j] = (uint8_t)(seq + j);
                }
            }
            res = co_sc_write(tx, batch, want, &sent);
            x->sent += sent;
            if (res == CO_SC_FAILED) {
                die(2, "co_sc_write: %s", strerror(tx->last_errno));
            }
            if (res == CO_SC_WOULD_BLOCK) {
                wait_io(tx->fd, rx->fd);
            }
        } else {
            struct pollfd p;
            p.fd = rx->fd;
            p.events = POLLIN;
            if (poll(&p, 1, 500) == 0) {
                break;
            }
        }
        while (x->received + x->bad < x->sent) {
            uint64_t left = x->sent - x->received - x->bad;
            unsigned got = 0;
            co_sc_io_t res = co_sc_read(rx, items, left < RAW_BATCH ? (unsigned)left : RAW_BATCH,
                                        &got);
            if (res == CO_SC_FAILED) {
                die(2, "co_sc_read: %s", strerror(rx->last_errno));
            }
            for (i = 0; i < got; i++) {
                if (items[i].has_frame) {
                    check_seq(x, items[i].frame.data, items[i].frame.len, items[i].frame.id,
                              &expect);
                }
            }
            if (res != CO_SC_DONE) {
                break;
            }
            last = now_s();
        }
        if (now_s() - last > 5.0) {
            break;
        }
    }
    x->drops = rx->stats.kernel_drops - drops0;
    x->seconds = last - t0;
}

/* One kernel reference run (bare sockets, opened for the run). */
static void kernel_ref_run(const char *ifname, uint64_t frames, ref_result_t *x)
{
    unsigned ifindex = if_nametoindex(ifname);
    int tx, rx;
    if (ifindex == 0) {
        die(2, "interface %s not found", ifname);
    }
    uint32_t drops0 = softnet_drops();
    rx = raw_socket(ifname, ifindex, true);
    tx = raw_socket(ifname, ifindex, false);
    raw_kernel_run(tx, rx, frames, x);
    close(tx);
    close(rx);
    x->backlog = softnet_drops() - drops0;
}

/* One driver reference run (co_socketcan as the runtime opens it). */
static void driver_ref_run(const char *ifname, uint64_t frames, ref_result_t *x)
{
    co_socketcan_t tx, rx;
    char err[256];
    co_sc_init(&tx);
    co_sc_init(&rx);
    if (co_sc_open(&tx, ifname, CO_MODE_FD, err, sizeof err) != CO_SC_OPEN_OK ||
        co_sc_open(&rx, ifname, CO_MODE_FD, err, sizeof err) != CO_SC_OPEN_OK) {
        die(2, "%s", err);
    }
    uint32_t drops0 = softnet_drops();
    raw_driver_run(&tx, &rx, frames, x);
    co_sc_close(&tx);
    co_sc_close(&rx);
    x->backlog = softnet_drops() - drops0;
}

/* The rig's sockets closed while a reference runs (they would receive its
 * frames: the runtime's sockets have no filter), reopened after. */
static void rig_sockets(rig_t *r, bool open)
{
    if (!open) {
        rig_close(r);
    } else if (!open_side(&r->srv, r->name) || !open_side(&r->cli, r->name)) {
        die(2, "%s: cannot reopen the sockets", r->name);
    }
}
#endif

/* ================================================================ per bus */

typedef struct bus_result {
    const char *name;
    double raw_fps;          /* raw frames/s of the steering round taken */
    double bulk_1m;          /* bulk download 1 MiB, MB/s, same round */
} bus_result_t;

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* The steering figure: rounds of (raw reference run, [driver reference run,]
 * bulk download 1 MiB) back to back, each part about as many frames as one
 * 1 MiB bulk transfer (17 480), so that the host's load changes them alike;
 * 3 x opt.runs rounds, the round with the median share is taken. Over
 * SocketCAN the bulk part is one transfer; over membus (much faster) both
 * parts last at least opt.min_s / 4. */
static void steering(rig_t *r, bus_result_t *out)
{
    static const row_def_t bulk = {OP_DOWNLOAD, CO_USDO_MODE_BULK, 1u << 20};
    const uint64_t frames = opt.raw_frames < 17480 ? opt.raw_frames : 17480;
    co_usdo_request_t req;
    co_usdo_buffer_t buf;
    snapshot_t before;
    double share[300] = {0}, raw[300] = {0}, mb[300] = {0}, sorted[300];
    bool good[300];
    unsigned k, rounds = 3 * opt.runs, median = 0, ngood = 0;
    uint32_t failed = 0;

    printf("steering figure: bulk download 1 MiB and the raw frame rate (%llu-frame runs) "
           "measured back to back, %u rounds\n\n", (unsigned long long)frames, rounds);
    printf("%5s %14s %14s %16s %12s %14s %16s\n", "round", "raw frames/s", "raw MB/s @60",
           "driver frames/s", "bulk MB/s", "share of raw", "share of driver");
    fill(src_data, bulk.size, 0xB01Cu);
    snap(r, &before);
    make_request(r, &bulk, &req, &buf);
    for (k = 0; k < rounds; k++) {
        ref_result_t x, y;
        uint64_t n;
        uint32_t failed0 = failed;
        char drv[24], drv_share[24];
        memset(&y, 0, sizeof y);
#if HAVE_SOCKETCAN
        if (r->socket) {
            uint32_t drops0 = softnet_drops();
            rig_sockets(r, false);
            kernel_ref_run(r->name, frames, &x);
            driver_ref_run(r->name, frames, &y);
            rig_sockets(r, true);
            r->softnet_base += softnet_drops() - drops0;   /* not the rig's */
        } else
#endif
        {
            membus_ref_run(r->name, frames, &x);
        }
        (void)ref_lost(&x);
        (void)ref_lost(&y);
        raw[k] = ref_fps(&x);
        mb[k] = timed_run(r, &bulk, &req, r->socket ? 0 : opt.min_s / 4, &n, &failed) *
                bulk.size / 1e6;
        share[k] = raw[k] > 0 ? 100.0 * mb[k] / (raw[k] * PAYLOAD / 1e6) : 0;
        snprintf(drv, sizeof drv, "-");
        snprintf(drv_share, sizeof drv_share, "-");
        if (r->socket && ref_fps(&y) > 0) {
            snprintf(drv, sizeof drv, "%.0f", ref_fps(&y));
            snprintf(drv_share, sizeof drv_share, "%.1f %%",
                     100.0 * mb[k] / (ref_fps(&y) * PAYLOAD / 1e6));
        }
        /* a round with a failed transfer or lost reference frames is shown,
         * not used */
        good[k] = failed == failed0 && x.sent == x.received && y.sent == y.received &&
                  y.drops == 0;
        if (good[k]) {
            sorted[ngood++] = share[k];
        }
        printf("%5u %14.0f %14.3f %16s %12.3f %12.1f %% %16s%s\n", k + 1, raw[k],
               raw[k] * PAYLOAD / 1e6, drv, mb[k], share[k], drv_share,
               good[k] ? "" : "  (not used)");
        if (failed != failed0) {
            printf("  ! the bulk transfer failed\n");
        }
        if (x.sent != x.received || y.sent != y.received || y.drops) {
            printf("  ! reference frames lost: raw %llu, driver %llu (%u dropped from the "
                   "kernel's input backlog)\n",
                   (unsigned long long)(x.sent - x.received),
                   (unsigned long long)(y.sent - y.received + y.drops),
                   (unsigned)(x.backlog + y.backlog));
        }
        fflush(stdout);
    }
    if (failed != 0) {
        printf("  ! %u bulk transfers failed\n", (unsigned)failed);
        status = 1;
        settle(r);
    }
    if (failed == 0) {
        check_after(r, &bulk, &buf);
    }
    if (report_problems(r, &before) != 0) {
        status = 1;
    }
    if (ngood == 0) {
        printf("\nbulk download 1 MiB over %s: no round without failures, no figure\n\n",
               r->name);
        status = 1;
        fflush(stdout);
        return;
    }
    /* the good round with the median share (the lower middle one when even) */
    qsort(sorted, ngood, sizeof sorted[0], cmp_double);
    for (k = 0; k < rounds; k++) {
        if (good[k] && share[k] == sorted[(ngood - 1) / 2]) {
            median = k;
            break;
        }
    }
    out->raw_fps = raw[median];
    out->bulk_1m = mb[median];
    printf("\nbulk download 1 MiB over %s: %.3f MB/s = %.1f %% of %s frames/s x 60 B%s\n",
           r->name, mb[median], share[median], r->socket ? "raw" : "membus",
           r->socket ? " (target 70 %)" : "");
    printf("  (round %u: the median share of %u round%s, which ranged %.1f .. %.1f %%; "
           "raw = %.0f frames/s = %.3f MB/s @60 B)\n\n",
           median + 1, ngood, ngood == 1 ? "" : "s", sorted[0], sorted[ngood - 1], raw[median],
           raw[median] * PAYLOAD / 1e6);
    fflush(stdout);
}

static void run_bus(const char *bus, bus_result_t *out)
{
    double ref;
    unsigned i;
    bool sock = strcmp(bus, "membus") != 0;
    char what[96];

    memset(out, 0, sizeof *out);
    out->name = bus;
#if !HAVE_SOCKETCAN
    if (sock) {
        die(2, "%s: built without SocketCAN (not Linux)", bus);
    }
#endif
    if (sock) {
        printf("== %s: SocketCAN, one co_socketcan socket per line, one thread (ppoll loop "
               "as the runtime's) ==\n\n", bus);
    } else {
        printf("== membus: the in-process bus, both lines processed by one loop ==\n\n");
    }
#if HAVE_SOCKETCAN
    if (sock) {
        /* the interface can be used (else exit 2 with the driver's message) */
        char err[256];
        co_socketcan_t probe;
        co_sc_init(&probe);
        if (co_sc_open(&probe, bus, CO_MODE_FD, err, sizeof err) != CO_SC_OPEN_OK) {
            die(2, "%s", err);
        }
        co_sc_close(&probe);
    }
#endif
    print_ref_header();
#if HAVE_SOCKETCAN
    if (sock) {
        /* the references first (no USDO socket open yet to fill its buffer) */
        snprintf(what, sizeof what, "%s: raw CAN_RAW, sendmmsg+recvmmsg %d/call", bus, RAW_BATCH);
        ref = best_ref(what, kernel_ref_run, bus);
        snprintf(what, sizeof what, "%s: co_socketcan driver, co_sc_write/co_sc_read %d/call",
                 bus, RAW_BATCH);
        (void)best_ref(what, driver_ref_run, bus);
    } else
#endif
    {
        snprintf(what, sizeof what, "membus: co_line_send -> co_membus -> co_line_process");
        ref = best_ref(what, membus_ref_run, bus);
    }
    printf("\n");

    if (!rig_init(&rig, bus)) {
        die(2, "%s: cannot open the bus", bus);
    }
    if (!opt.steer_only) {
        print_table_header();
        for (i = 0; i < ROWS; i++) {
            (void)measure_row(&rig, &rows[i], i, ref);
        }
        printf("(share of raw: MB/s / (the first reference line's frames/s x 60 B))\n\n");
    }
    steering(&rig, out);
    if (opt.verbose) {
        printf("(%s: %u bulk pauses for tx space, %u writes would block)\n\n", bus,
               (unsigned)rig.client.stats.bulk_paused,
               (unsigned)(rig.srv.would_block + rig.cli.would_block));
    }
    co_usdo_client_deinit(&rig.client);
    co_usdo_server_deinit(&rig.server);
    rig_close(&rig);
    fflush(stdout);
}

/* ================================================================ main */

static void usage(void)
{
    fprintf(stderr,
            "usage: %s [-q] [-s] [-v] [-t SECONDS] [-r RUNS] [-n FRAMES] [-Q QUEUE] [BUS...]\n"
            "  BUS      membus or a CAN FD interface (default: membus vcan0)\n"
            "  -t       minimum seconds of one timed run (default 1; -q: 0.02)\n"
            "  -r       timed runs per figure, the best is shown (default 3; -q: 1)\n"
            "  -n       frames per run of the reference figures (default 100000; -q: 2000)\n"
            "  -q       quick (also USDO_BENCH_QUICK=1): tiny runs, for sanitizer builds\n"
            "  -Q       rx and tx queue capacity of each line (default 1024, the runtime's; "
            "16..4096)\n"
            "  -s       only the reference lines and the steering figure (no table)\n"
            "  -v       per row: loop turns, ppoll calls, bulk pauses, would-block per "
            "transfer\n", prog);
    exit(2);
}

static double parse_double(const char *s, double lo, double hi)
{
    char *end;
    double v;
    errno = 0;
    v = strtod(s, &end);
    if (errno || end == s || *end || !(v >= lo && v <= hi)) {
        usage();
    }
    return v;
}

int main(int argc, char **argv)
{
    static const char *const default_buses[] = {"membus", "vcan0"};
    const char *const *buses = default_buses;
    bus_result_t results[8];
    int nbuses = 2, i, c;
    bool set_t = false, set_r = false, set_n = false;
    const char *quick = getenv("USDO_BENCH_QUICK");

    opt.quick = quick != NULL && *quick != '\0' && strcmp(quick, "0") != 0;
    while ((c = getopt(argc, argv, "qsvt:r:n:Q:h")) != -1) {
        switch (c) {
        case 'Q':
            opt.queue = (uint32_t)parse_double(optarg, 16, QUEUE_MAX);
            break;
        case 's':
            opt.steer_only = true;
            break;
        case 'q':
            opt.quick = true;
            break;
        case 'v':
            opt.verbose = true;
            break;
        case 't':
            opt.min_s = parse_double(optarg, 0, 3600);
            set_t = true;
            break;
        case 'r':
            opt.runs = (unsigned)parse_double(optarg, 1, 100);
            set_r = true;
            break;
        case 'n':
            opt.raw_frames = (uint64_t)parse_double(optarg, 1, 1e8);
            set_n = true;
            break;
        default:
            usage();
        }
    }
    if (opt.quick) {
        opt.min_s = set_t ? opt.min_s : 0.02;
        opt.runs = set_r ? opt.runs : 1;
        opt.raw_frames = set_n ? opt.raw_frames : 2000;
    }
    if (optind < argc) {
        buses = (const char *const *)&argv[optind];
        nbuses = argc - optind;
    }
    if (nbuses > (int)(sizeof results / sizeof results[0])) {
        usage();
    }

    printf("USDO throughput: server (U32 0x%04X, DOMAIN 0x%04X up to 1 MiB, %d sessions) and "
           "client (%d sessions) on two fd lines (BRS), queues %d rx / %d tx, one thread;\n"
           "best of %u run%s of >= %.2f s per figure, data verified once per row outside the "
           "timed runs; MB/s = 10^6 bytes/s\n\n",
           IDX_U32, IDX_DOMAIN, SERVER_SESSIONS, CLIENT_SESSIONS, (int)opt.queue, (int)opt.queue,
           opt.runs,
           opt.runs == 1 ? "" : "s", opt.min_s);
    for (i = 0; i < nbuses; i++) {
        run_bus(buses[i], &results[i]);
    }
    printf("summary: bulk download 1 MiB as a share of the bus's raw 64-byte frames/s x 60 B\n");
    for (i = 0; i < nbuses; i++) {
        const bus_result_t *x = &results[i];
        if (x->raw_fps <= 0) {
            printf("  %-8s no figure (no round without failures)\n", x->name);
            continue;
        }
        printf("  %-8s %10.3f MB/s of %10.3f MB/s = %5.1f %%%s\n", x->name, x->bulk_1m,
               x->raw_fps * PAYLOAD / 1e6,
               x->raw_fps > 0 ? 100.0 * x->bulk_1m / (x->raw_fps * PAYLOAD / 1e6) : 0.0,
               strcmp(x->name, "membus") != 0 ? "   (target 70 %)" : "");
    }
    if (status != 0) {
        fprintf(stderr, "%s: transfers failed, data differed or frames were lost (see above)\n",
                prog);
    }
    return status;
}
