/* Instructions per frame / segment of the core, counted by valgrind's
 * callgrind (exact and repeatable, unlike wall-clock time on a shared host).
 *
 * Each figure runs its unit of work twice, a short run and a long run, with
 * callgrind's collection switched on only around the run, and dumps the
 * counters after each (CALLGRIND_DUMP_STATS_AT, named "<figure> <units>").
 * bench/frame_cost.sh reads the dumps and prints
 *   (instructions of the long run - of the short run) / (units difference),
 * the cost of one more frame or segment with every fixed cost (setup, the
 * transfer's initiate and end, the loop's first pass) cancelled out.
 *
 * Figures (two lines on a membus, one thread, a fixed simulated clock):
 *   fd64     64-byte FD+BRS frame: co_line_send, membus, co_line_process,
 *            dispatch to a handler that counts it
 *   classic8 8-byte classic frame, the same path
 *   usdo-bulk     one bulk download segment (60 bytes), client and server
 *   usdo-seg      one segmented download segment (60 bytes) and its confirmation
 *   sdo-block     one SDO block download segment (7 bytes), sub-block acks shared out
 *   sdo-seg       one SDO segmented download segment (7 bytes) and its confirmation
 *
 * Run natively it does the same work and prints only what it moved (the
 * callgrind macros do nothing outside valgrind); `make -C bench callgrind`
 * is the measurement. */
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <valgrind/callgrind.h>

#include "canopenfd/co_line.h"
#include "canopenfd/co_membus.h"
#include "canopenfd/co_od.h"
#include "canopenfd/co_sdo_client.h"
#include "canopenfd/co_sdo_server.h"
#include "canopenfd/co_usdo.h"
#include "canopenfd/co_usdo_client.h"
#include "canopenfd/co_usdo_server.h"

#define QUEUE 256
#define BATCH 64                 /* frames sent before each membus transfer + process */
#define SERVER_NODE 5
#define CLIENT_NODE 1
#define IDX_DOMAIN 0x2001
#define DOMAIN_CAP (64u * 1024u)
#define SESSIONS 2

static void die(const char *what)
{
    fprintf(stderr, "frame_cost: %s\n", what);
    exit(1);
}

/* ------------------------------------------------------------- measuring */

static void measure_begin(void)
{
    CALLGRIND_TOGGLE_COLLECT;
}

/* Ends a measured run and dumps its counters as "<name> <units>". */
static void measure_end(const char *name, uint32_t units)
{
    char label[64];
    CALLGRIND_TOGGLE_COLLECT;
    snprintf(label, sizeof label, "%s %u", name, (unsigned)units);
    CALLGRIND_DUMP_STATS_AT(label);
    (void)label;
    printf("%-10s %8u units\n", name, (unsigned)units);
}

/* ------------------------------------------------------------- lines */

typedef struct side {
    co_line_t line;
    co_frame_t rx[QUEUE];
    co_frame_t tx[QUEUE];
} side_t;

static void side_init(side_t *s, co_mode_t mode)
{
    co_line_config_t cfg;
    memset(&cfg, 0, sizeof cfg);
    cfg.mode = mode;
    cfg.brs = mode == CO_MODE_FD;
    cfg.rx_slots = s->rx;
    cfg.rx_capacity = QUEUE;
    cfg.tx_slots = s->tx;
    cfg.tx_capacity = QUEUE;
    if (!co_line_init(&s->line, &cfg)) {
        die("co_line_init failed");
    }
}

/* ------------------------------------------------------------- (1) frames */

static uint64_t rx_frames;
static uint64_t rx_bytes;

static void count_rx(co_line_t *line, const co_frame_t *frame, void *user)
{
    (void)line;
    (void)user;
    rx_frames++;
    rx_bytes += frame->len;
}

static void frames_run(side_t *a, side_t *b, co_membus_t *bus, size_t len, uint32_t batches,
                       uint64_t *now)
{
    static const uint8_t data[64] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16,
                                     17, 18, 19, 20, 21, 22, 23, 24, 25, 26, 27, 28, 29, 30,
                                     31, 32, 33, 34, 35, 36, 37, 38, 39, 40, 41, 42, 43, 44,
                                     45, 46, 47, 48, 49, 50, 51, 52, 53, 54, 55, 56, 57, 58,
                                     59, 60, 61, 62, 63, 64};
    for (uint32_t n = 0; n < batches; n++) {
        for (uint32_t k = 0; k < BATCH; k++) {
            (void)co_line_send(&a->line, 0x200 + (k & 0x7F), data, len);
        }
        (void)co_membus_transfer(bus, NULL, NULL);
        (void)co_line_process(&b->line, *now);
        *now += 1000;
    }
}

static void frames_figure(const char *name, co_mode_t mode, size_t len)
{
    static side_t a, b;
    co_membus_t bus;
    uint64_t now = 1;
    const uint32_t runs[2] = {4, 36};   /* batches: 256 and 2304 frames */
    side_init(&a, mode);
    side_init(&b, mode);
    co_membus_init(&bus);
    co_membus_attach(&bus, &a.line);
    co_membus_attach(&bus, &b.line);
    if (!co_line_subscribe(&b.line, 0x200, 0x27F, count_rx, NULL)) {
        die("subscribe failed");
    }
    rx_frames = 0;
    frames_run(&a, &b, &bus, len, 4, &now);   /* warm-up */
    for (int r = 0; r < 2; r++) {
        measure_begin();
        frames_run(&a, &b, &bus, len, runs[r], &now);
        measure_end(name, runs[r] * BATCH);
    }
    uint64_t want = (uint64_t)(4 + runs[0] + runs[1]) * BATCH;
    if (rx_frames != want || a.line.stats.tx_overflow || b.line.stats.rx_overflow ||
        b.line.stats.rx_invalid) {
        die("frames lost");
    }
}

/* ------------------------------------------------------------- transfers */

static uint8_t src_data[DOMAIN_CAP];

/* The server's DOMAIN: written in place, chunk by chunk. */
typedef struct domain {
    uint8_t data[DOMAIN_CAP];
    uint32_t len;
    uint32_t commits;
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
    (void)od;
    (void)e;
    uint32_t k = offset > d->len ? 0 : d->len - offset;
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
        return 0;
    }
    if ((total != CO_OD_SIZE_UNKNOWN && total > DOMAIN_CAP) || offset > DOMAIN_CAP ||
        n > DOMAIN_CAP - offset) {
        return 0x06070012u;   /* length too high */
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

typedef struct rig {
    side_t srv, cli;
    co_membus_t bus;
    co_od_t od;
    co_od_entry_t entries[4];
    uint8_t pool[64];
    co_od_subscription_t subs[4];
    uint8_t scratch[2048];         /* server scratch (SDO: block buffer + entry) */
    uint64_t now;
    bool done;
    uint32_t abort;
} rig_t;

static void rig_init(rig_t *r, co_mode_t mode)
{
    co_od_def_t d;
    memset(r, 0, sizeof *r);
    r->now = 1;
    side_init(&r->srv, mode);
    side_init(&r->cli, mode);
    co_line_set_node_id(&r->srv.line, SERVER_NODE);
    co_od_init(&r->od, mode, r->entries, 4, r->pool, sizeof r->pool, r->subs, 4);
    memset(&d, 0, sizeof d);
    d.index = IDX_DOMAIN;
    d.object_code = CO_OBJECT_VAR;
    d.type = CO_TYPE_DOMAIN;
    d.access = CO_ACCESS_RW;
    if (co_od_add(&r->od, &d) != CO_OD_ADDED || !co_od_seal(&r->od, SERVER_NODE) ||
        !co_od_subscribe(&r->od, IDX_DOMAIN, 0, IDX_DOMAIN, 0, &dom_handler, &dom)) {
        die("OD setup failed");
    }
    co_membus_init(&r->bus);
    co_membus_attach(&r->bus, &r->srv.line);
    co_membus_attach(&r->bus, &r->cli.line);
}

/* One loop turn: both lines processed, the bus moved, the clock 1 us on. */
static void rig_iterate(rig_t *r)
{
    (void)co_line_process(&r->srv.line, r->now);
    (void)co_line_process(&r->cli.line, r->now);
    (void)co_membus_transfer(&r->bus, NULL, NULL);
    r->now += 1;
}

static void check_domain(uint32_t size)
{
    if (dom.len != size || memcmp(dom.data, src_data, size) != 0) {
        die("downloaded data differ");
    }
}

/* USDO */

static rig_t urig;
static co_usdo_server_t userver;
static co_usdo_session_t usessions[SESSIONS];
static co_usdo_client_t uclient;
static co_usdo_client_session_t ucsessions[SESSIONS];

static void usdo_done(co_usdo_request_t *req)
{
    rig_t *r = req->user;
    r->done = true;
    r->abort = req->abort;
}

static void usdo_setup(void)
{
    co_usdo_server_config_t scfg;
    co_usdo_client_config_t ccfg;
    rig_init(&urig, CO_MODE_FD);
    memset(&scfg, 0, sizeof scfg);
    scfg.sessions = usessions;
    scfg.session_count = SESSIONS;
    scfg.scratch = urig.scratch;
    scfg.scratch_size = co_usdo_server_scratch_need(&urig.od);
    if (scfg.scratch_size * SESSIONS > sizeof urig.scratch ||
        !co_usdo_server_init(&userver, &urig.srv.line, &urig.od, &scfg)) {
        die("co_usdo_server_init failed");
    }
    memset(&ccfg, 0, sizeof ccfg);
    ccfg.sessions = ucsessions;
    ccfg.session_count = SESSIONS;
    ccfg.node_id = CLIENT_NODE;
    if (!co_usdo_client_init(&uclient, &urig.cli.line, &ccfg)) {
        die("co_usdo_client_init failed");
    }
}

static void usdo_download(uint8_t mode, uint32_t size)
{
    co_usdo_request_t req;
    co_usdo_buffer_t buf = {src_data, size, size};
    memset(&req, 0, sizeof req);
    req.server = SERVER_NODE;
    req.index = IDX_DOMAIN;
    req.mode = mode;
    req.type = CO_TYPE_DOMAIN;
    req.size = size;
    req.source = co_usdo_buffer_source;
    req.ctx = &buf;
    req.done = usdo_done;
    req.user = &urig;
    urig.done = false;
    co_line_set_time(&urig.cli.line, urig.now);
    if (co_usdo_client_start(&uclient, &req) != 0) {
        die("co_usdo_client_start refused");
    }
    while (!urig.done) {
        rig_iterate(&urig);
    }
    if (urig.abort != 0 || req.result_mode != mode) {
        die("USDO download failed");
    }
}

static void usdo_figure(const char *name, uint8_t mode)
{
    const uint32_t segs[2] = {64, 576};
    usdo_setup();
    usdo_download(mode, 16 * CO_USDO_SEGMENT_DATA);   /* warm-up */
    for (int r = 0; r < 2; r++) {
        uint32_t size = segs[r] * CO_USDO_SEGMENT_DATA;
        measure_begin();
        usdo_download(mode, size);
        measure_end(name, segs[r]);
        check_domain(size);
    }
    co_usdo_client_deinit(&uclient);
    co_usdo_server_deinit(&userver);
}

/* SDO */

static rig_t srig;
static co_sdo_server_t sserver;
static co_sdo_channel_t schannels[1];
static co_sdo_client_t sclient;
static co_sdo_client_channel_t scchannels[1];

static void sdo_done(co_sdo_request_t *req)
{
    rig_t *r = req->user;
    r->done = true;
    r->abort = req->abort;
}

static void sdo_setup(void)
{
    co_sdo_server_config_t scfg;
    co_sdo_client_config_t ccfg;
    rig_init(&srig, CO_MODE_CLASSIC);
    memset(&scfg, 0, sizeof scfg);
    scfg.channels = schannels;
    scfg.channel_count = 1;
    scfg.scratch = srig.scratch;
    scfg.scratch_size = co_sdo_server_scratch_need(&srig.od);
    if (scfg.scratch_size > sizeof srig.scratch ||
        !co_sdo_server_init(&sserver, &srig.srv.line, &srig.od, &scfg)) {
        die("co_sdo_server_init failed");
    }
    memset(&ccfg, 0, sizeof ccfg);
    ccfg.channels = scchannels;
    ccfg.channel_count = 1;
    if (!co_sdo_client_init(&sclient, &srig.cli.line, &ccfg)) {
        die("co_sdo_client_init failed");
    }
}

static void sdo_download(uint8_t mode, uint32_t size)
{
    co_sdo_request_t req;
    co_sdo_buffer_t buf = {src_data, size, size};
    memset(&req, 0, sizeof req);
    req.server = SERVER_NODE;
    req.index = IDX_DOMAIN;
    req.mode = mode;
    req.size = size;
    req.source = co_sdo_buffer_source;
    req.ctx = &buf;
    req.done = sdo_done;
    req.user = &srig;
    srig.done = false;
    co_line_set_time(&srig.cli.line, srig.now);
    if (co_sdo_client_start(&sclient, &req) != 0) {
        die("co_sdo_client_start refused");
    }
    while (!srig.done) {
        rig_iterate(&srig);
    }
    if (srig.abort != 0 || req.result_mode != mode) {
        die("SDO download failed");
    }
}

static void sdo_figure(const char *name, uint8_t mode)
{
    /* whole sub-blocks of 127 segments (block), the same counts (segmented) */
    const uint32_t segs[2] = {2 * 127, 10 * 127};
    sdo_setup();
    sdo_download(mode, 127 * CO_SDO_SEGMENT_DATA);   /* warm-up */
    for (int r = 0; r < 2; r++) {
        uint32_t size = segs[r] * CO_SDO_SEGMENT_DATA;
        measure_begin();
        sdo_download(mode, size);
        measure_end(name, segs[r]);
        check_domain(size);
    }
    co_sdo_client_deinit(&sclient);
    co_sdo_server_deinit(&sserver);
}

int main(void)
{
    for (uint32_t i = 0; i < DOMAIN_CAP; i++) {
        src_data[i] = (uint8_t)(i * 131u + (i >> 8));
    }
    frames_figure("fd64", CO_MODE_FD, 64);
    frames_figure("classic8", CO_MODE_CLASSIC, 8);
    usdo_figure("usdo-bulk", CO_USDO_MODE_BULK);
    usdo_figure("usdo-seg", CO_USDO_MODE_SEGMENTED);
    sdo_figure("sdo-block", CO_SDO_MODE_BLOCK);
    sdo_figure("sdo-seg", CO_SDO_MODE_SEGMENTED);
    return 0;
}
