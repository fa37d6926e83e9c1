/* Classic SDO client (co_sdo_client) over the in-process bus.
 *
 * The client runs on classic line 0 (8 channels, all spares unless a test
 * configures them). The real co_sdo_server runs on lines 1..3 as nodes 5, 6
 * and 7, each over its own OD: U8 0x2000, U16 0x2001, U32 0x2002 (its own
 * value per server), U24 0x2011, a string 0x2004, a DOMAIN 0x2009 backed by
 * a 110 000-byte buffer, a size-less DOMAIN 0x200C (same data) and a
 * second server channel 0x1201 (off until a test enables it). Node X (0x40)
 * has no server: tests answer as X by putting raw frames into the client's
 * line (0x5C0), where exact control is needed.
 *
 * Every frame is checked whole through the bus sniffer (CAN-ID, classic
 * flags, length 8, every byte): the client's requests and, against the real
 * servers, their answers. Expected bytes are written out by hand from the
 * CiA 301 layouts (research notes §6.2-6.4), not with the codec; CRCs are
 * checked with a bit-by-bit reference written here. */
#include "test_od_util.h"

#include "co_cob_id.h"
#include "co_crc.h"
#include "canopenfd/co_sdo.h"
#include "canopenfd/co_sdo_client.h"
#include "canopenfd/co_sdo_server.h"

#define NSRV 3
#define X 0x40                    /* scripted server */
#define TX_X (0x600u + X)
#define RX_X (0x580u + X)
#define REQ(n) (0x600u + (n))
#define RSP(n) (0x580u + (n))
#define REQ1_5 0x6A5u             /* server 5's channel 1 (0x1201), once enabled */
#define RSP1_5 0x6B5u
#define MS(x) ((uint64_t)(x) * TU_MS)
#define NCH 8                     /* client channels */
#define SRV_NCH 2
#define N_ENTRIES 32
#define POOL 4096
#define SUBS 6
#define DOM_CAP 110000u

#define U24 CO_TYPE_UNSIGNED24
#define DOM CO_TYPE_DOMAIN

/* Abort codes as the research notes give them (§6.4). */
#define AB_TOGGLE 0x05030000u
#define AB_TIMEOUT 0x05040000u
#define AB_COMMAND 0x05040001u
#define AB_BLKSIZE 0x05040002u
#define AB_SEQNO 0x05040003u
#define AB_CRC 0x05040004u
#define AB_MEMORY 0x05040005u
#define AB_HARDWARE 0x06060000u
#define AB_TYPE 0x06070010u
#define AB_INVALID 0x06090030u
#define AB_RESOURCE 0x060A0023u
#define AB_GENERAL 0x08000000u
#define AB_STORE 0x08000020u

typedef struct fx fx_t;

/* ------------------------------------------------------------- reference CRC */

/* CRC-16-CCITT bit by bit (poly 0x1021, init 0, MSB first, no xorout). */
static uint16_t ref_crc(const uint8_t *p, size_t n)
{
    uint16_t crc = 0;
    size_t i;
    int b;
    for (i = 0; i < n; i++) {
        crc ^= (uint16_t)(p[i] << 8);
        for (b = 0; b < 8; b++)
            crc = (crc & 0x8000u) ? (uint16_t)((crc << 1) ^ 0x1021u) : (uint16_t)(crc << 1);
    }
    return crc;
}

/* ------------------------------------------------------------- servers */

typedef struct srv {
    fx_t *fx;
    uint8_t id;
    co_line_t *line;
    co_od_t od;
    co_od_entry_t entries[N_ENTRIES];
    uint8_t pool[POOL];
    co_od_subscription_t subs[SUBS];
    co_sdo_server_t s;
    co_sdo_channel_t ch[SRV_NCH];
    uint8_t *scratch;
    uint32_t scratch_need;
    bool running;
    uint8_t *dom;
    uint32_t dom_len;
    uint32_t dom_commits;
    uint32_t dom_aborts;
    uint32_t dom_fail_at;         /* the writer refuses data beyond this offset (0 = never) */
} srv_t;

typedef struct treq treq_t;
typedef void (*treq_hook_fn)(treq_t *t);

/* A request with its bookkeeping. */
struct treq {
    co_sdo_request_t r;
    fx_t *fx;
    co_sdo_buffer_t buf;           /* source or sink */
    unsigned starts;
    unsigned done_calls;
    uint64_t done_at;
    unsigned announces;
    bool in_run;
    uint32_t announced;
    treq_hook_fn hook;             /* run from done() */
    uint32_t cancel_at;            /* sink: cancel when this offset is reached (0 = never) */
};

struct fx {
    tu_bus_t tb;
    tu_line_t l[1 + NSRV];
    co_line_t *cl;
    srv_t *srv[NSRV];
    co_sdo_client_t c;
    co_sdo_client_channel_t cch[NCH];
    size_t cursor;                 /* next log entry to look at */
    /* observer of every frame on the bus instead of the log (big transfers) */
    void (*observe)(fx_t *fx, const co_frame_t *f);
    unsigned count_id[0x800];      /* frames per CAN-ID seen by observe_count */
    /* fault injection: drop the nth frame (1-based) with CAN-ID fault_id */
    uint32_t fault_id;
    unsigned fault_seen;
    unsigned fault_nth;
    unsigned fault_rate;           /* random drops: 1 in fault_rate frames (0 = off) */
    unsigned fault_dropped;
    /* client OD (test_od_channels) */
    co_od_t cod;
    co_od_entry_t centries[N_ENTRIES];
    uint8_t cpool[POOL];
    co_od_subscription_t csubs[SUBS];
    /* random tests */
    uint64_t seed;
};

static const tu_od_row_t od_rows[] = {
    { 0x1201, 0, REC, U8, AC_CONST, 0, 1, 3, NULL, 0, 0 },
    { 0x1201, 1, REC, U32, RW, 0, 4, 0x80000000, NULL, 0, 0 },
    { 0x1201, 2, REC, U32, RW, 0, 4, 0x80000000, NULL, 0, 0 },
    { 0x1201, 3, REC, U8, RW, 0, 1, 0, NULL, 0, 0 },
    { 0x2000, 0, VAR, U8, RW, 0, 1, 0x11, NULL, 0, 0 },
    { 0x2001, 0, VAR, U16, RW, 0, 2, 0x2222, NULL, 0, 0 },
    { 0x2002, 0, VAR, U32, RW, 0, 4, 0x33333333, NULL, 0, 0 },
    { 0x2004, 0, VAR, VS, RW, 0, 200, 0, "hello", 0, 0 },
    { 0x2006, 0, VAR, U32, RO, 0, 4, 0xCAFEF00D, NULL, 0, 0 },
    { 0x2011, 0, VAR, U24, RW, 0, 3, 0x123456, NULL, 0, 0 },
};

static uint32_t dom_size(co_od_t *od, const co_od_entry_t *e, uint32_t *size, void *user)
{
    srv_t *s = user;
    (void)od;
    (void)e;
    *size = s->dom_len;
    return 0;
}

static uint32_t dom_read(co_od_t *od, const co_od_entry_t *e, uint32_t offset, uint8_t *buf,
                         uint32_t cap, uint32_t *n, bool *last, void *user)
{
    srv_t *s = user;
    uint32_t k;
    (void)od;
    (void)e;
    assert_true(offset <= s->dom_len);
    k = s->dom_len - offset;
    if (k > cap)
        k = cap;
    if (k > 0)
        memcpy(buf, s->dom + offset, k);
    *n = k;
    *last = offset + k == s->dom_len;
    return 0;
}

static uint32_t dom_write(co_od_t *od, const co_od_entry_t *e, uint32_t offset,
                          const uint8_t *data, uint32_t n, uint32_t total, bool last,
                          uint32_t abort, void *user)
{
    srv_t *s = user;
    (void)od;
    (void)e;
    if (abort != 0) {
        s->dom_aborts++;
        return 0;
    }
    if ((total != CO_OD_SIZE_UNKNOWN && total > DOM_CAP) || offset > DOM_CAP ||
        n > DOM_CAP - offset)
        return CO_ABORT_LENGTH_HIGH;
    if (s->dom_fail_at != 0 && offset + n > s->dom_fail_at)
        return CO_ABORT_DATA_STORE;
    if (n > 0)
        memcpy(s->dom + offset, data, n);
    if (last) {
        s->dom_len = offset + n;
        s->dom_commits++;
    }
    return 0;
}

static const co_od_handler_t dom_handler = {
    .domain_size = dom_size,
    .domain_read = dom_read,
    .domain_write = dom_write,
};
static const co_od_handler_t dom_nosize_handler = {.domain_read = dom_read};

static void server_start(srv_t *s, uint32_t timeout_ms, uint8_t block_size, bool no_crc)
{
    co_sdo_server_config_t cfg;
    memset(&cfg, 0, sizeof cfg);
    cfg.channels = s->ch;
    cfg.channel_count = SRV_NCH;
    cfg.scratch = s->scratch;
    cfg.scratch_size = s->scratch_need;
    cfg.timeout_ms = timeout_ms;
    cfg.block_size = block_size;
    cfg.no_crc = no_crc;
    assert_true(co_sdo_server_init(&s->s, s->line, &s->od, &cfg));
    s->running = true;
}

static void server_restart(srv_t *s, uint32_t timeout_ms, uint8_t block_size, bool no_crc)
{
    co_sdo_server_deinit(&s->s);
    server_start(s, timeout_ms, block_size, no_crc);
}

static void server_build(fx_t *fx, srv_t *s, uint8_t id, co_line_t *line)
{
    co_od_def_t d;
    uint8_t v[4];
    s->fx = fx;
    s->id = id;
    s->line = line;
    co_line_set_node_id(line, id);   /* the server's default channel comes from the line */
    s->dom = calloc(1, DOM_CAP);
    assert_non_null(s->dom);
    co_od_init(&s->od, CO_MODE_CLASSIC, s->entries, N_ENTRIES, s->pool, POOL, s->subs, SUBS);
    tu_od_add_rows(&s->od, od_rows, sizeof od_rows / sizeof od_rows[0]);
    d = tu_od_def(0x2009, 0, VAR, DOM, RW, 0, 0);
    assert_int_equal(co_od_add(&s->od, &d), CO_OD_ADDED);
    d = tu_od_def(0x200C, 0, VAR, DOM, RW, 0, 0);
    assert_int_equal(co_od_add(&s->od, &d), CO_OD_ADDED);
    assert_true(co_od_seal(&s->od, id));
    assert_true(co_od_subscribe(&s->od, 0x2009, 0, 0x2009, 0, &dom_handler, s));
    assert_true(co_od_subscribe(&s->od, 0x200C, 0, 0x200C, 0, &dom_nosize_handler, s));
    assert_true(co_cob_id_attach(&s->od));
    tu_le_put(v, 0x33333300u + id, 4);   /* every server its own value */
    assert_int_equal(co_od_put(&s->od, 0x2002, 0, v, 4), 0);
    s->scratch_need = co_sdo_server_scratch_need(&s->od);
    s->scratch = calloc(SRV_NCH, s->scratch_need);
    assert_non_null(s->scratch);
}

static uint8_t membus_fault(const co_frame_t *f, void *user)
{
    fx_t *fx = user;
    if (fx->fault_rate != 0 && (tu_rand(&fx->seed) % fx->fault_rate) == 0) {
        fx->fault_dropped++;
        return 0;
    }
    if (f->id != fx->fault_id)
        return 1;
    fx->fault_seen++;
    if (fx->fault_seen == fx->fault_nth) {
        fx->fault_dropped++;
        return 0;
    }
    return 1;
}

static void fault_drop_nth(fx_t *fx, uint32_t id, unsigned nth)
{
    fx->fault_id = id;
    fx->fault_seen = 0;
    fx->fault_nth = nth;
    fx->fault_dropped = 0;
}

static void client_start_cfg(fx_t *fx, co_od_t *od, uint32_t timeout_ms, uint32_t threshold)
{
    co_sdo_client_config_t cfg;
    memset(&cfg, 0, sizeof cfg);
    cfg.channels = fx->cch;
    cfg.channel_count = NCH;
    cfg.od = od;
    cfg.timeout_ms = timeout_ms;
    cfg.block_threshold = threshold;
    assert_true(co_sdo_client_init(&fx->c, fx->cl, &cfg));
}

static void step(fx_t *fx, uint64_t now);

static int setup(void **state)
{
    int i;
    fx_t *fx = calloc(1, sizeof *fx);
    if (fx == NULL)
        return -1;
    tu_bus_init(&fx->tb, CO_MODE_CLASSIC, false);
    fx->cl = tu_bus_add_line(&fx->tb, &fx->l[0]);
    co_membus_set_fault(&fx->tb.bus, membus_fault, fx);
    fx->fault_id = 0xFFFFFFFFu;
    for (i = 0; i < NSRV; i++) {
        co_line_t *line = tu_bus_add_line(&fx->tb, &fx->l[1 + i]);
        fx->srv[i] = calloc(1, sizeof(srv_t));
        assert_non_null(fx->srv[i]);
        server_build(fx, fx->srv[i], (uint8_t)(5 + i), line);
        server_start(fx->srv[i], 0, 0, false);
    }
    client_start_cfg(fx, NULL, 0, 0);
    fx->seed = 0x5D0C11E47ull;
    step(fx, MS(10));
    *state = fx;
    return 0;
}

static int teardown(void **state)
{
    fx_t *fx = *state;
    int i;
    for (i = 0; i < NSRV; i++) {
        if (fx->srv[i] != NULL) {
            free(fx->srv[i]->dom);
            free(fx->srv[i]->scratch);
            free(fx->srv[i]);
        }
    }
    free(fx);
    return 0;
}

/* ------------------------------------------------------------- stepping */

/* One round: every line processed, the bus carries once. */
static uint32_t round1(fx_t *fx)
{
    tu_bus_t *tb = &fx->tb;
    uint32_t moved;
    co_frame_t f;
    uint8_t i;
    for (i = 0; i < tb->count; i++)
        (void)co_line_process(&tb->lines[i]->line, tb->now);
    moved = co_membus_transfer(&tb->bus, NULL, NULL);
    if (fx->observe != NULL) {
        while (co_line_rx_pop(&tb->sniffer.line, &f))
            fx->observe(fx, &f);
    } else {
        tu_drain_sniffer(tb);
    }
    return moved;
}

static void step(fx_t *fx, uint64_t now)
{
    long round;
    assert_true(now >= fx->tb.now);
    fx->tb.now = now;
    for (round = 0; round < 200000; round++)
        if (round1(fx) == 0)
            return;
    fail_msg("bus did not become quiet");
}

static void settle(fx_t *fx) { step(fx, fx->tb.now); }

static void rounds(fx_t *fx, int n)
{
    int i;
    for (i = 0; i < n; i++)
        (void)round1(fx);
}

static void run_until(fx_t *fx, uint64_t until)
{
    long guard = 0;
    for (;;) {
        uint64_t d = tu_next_deadline(&fx->tb);
        if (d > until)
            break;
        step(fx, d > fx->tb.now ? d : fx->tb.now);
        if (++guard > 2000000)
            fail_msg("timers keep firing");
    }
    step(fx, until);
}

static void run_ms(fx_t *fx, uint32_t ms) { run_until(fx, fx->tb.now + MS(ms)); }

static void log_reset(fx_t *fx)
{
    tu_log_clear(&fx->tb);
    fx->cursor = 0;
}

static void observe_nothing(fx_t *fx, const co_frame_t *f)
{
    (void)fx;
    (void)f;
}

static void observe_count(fx_t *fx, const co_frame_t *f)
{
    assert_int_equal(f->flags, 0);
    assert_int_equal(f->len, 8);
    fx->count_id[f->id & 0x7FFu]++;
}

/* ------------------------------------------------------------- frames */

static void fill_pattern(uint8_t *p, uint32_t n, uint8_t seed)
{
    uint32_t i;
    for (i = 0; i < n; i++)
        p[i] = (uint8_t)(seed + i * 13u + (i >> 8));
}

static void mux8(uint8_t *b, uint8_t cmd, uint16_t index, uint8_t sub, uint32_t d)
{
    b[0] = cmd;
    b[1] = (uint8_t)(index & 0xFF);
    b[2] = (uint8_t)(index >> 8);
    b[3] = sub;
    tu_le_put(b + 4, d, 4);
}

static void seg8(uint8_t *b, uint8_t cmd, const uint8_t *data, uint32_t n)
{
    memset(b, 0, 8);
    b[0] = cmd;
    if (n > 0)
        memcpy(b + 1, data, n);
}

/* The next logged frame with this CAN-ID (others skipped) is exactly b. */
static void expect_frame(fx_t *fx, uint32_t id, const uint8_t *b)
{
    while (fx->cursor < fx->tb.log_count) {
        const co_frame_t *f = &fx->tb.log[fx->cursor++].frame;
        if (f->id == id) {
            tu_assert_frame(f, id, 0, b, 8);
            return;
        }
    }
    fail_msg("no frame on 0x%03X (expected byte 0 = 0x%02X)", (unsigned)id, b[0]);
}

static void expect_mux(fx_t *fx, uint32_t id, uint8_t cmd, uint16_t index, uint8_t sub,
                       uint32_t d)
{
    uint8_t b[8];
    mux8(b, cmd, index, sub, d);
    expect_frame(fx, id, b);
}

static void expect_seg(fx_t *fx, uint32_t id, uint8_t cmd, const uint8_t *data, uint32_t n)
{
    uint8_t b[8];
    seg8(b, cmd, data, n);
    expect_frame(fx, id, b);
}

static void expect_cmd(fx_t *fx, uint32_t id, uint8_t cmd) { expect_seg(fx, id, cmd, NULL, 0); }

/* The next logged frame with this CAN-ID and byte 0 (others skipped) is
 * exactly b. */
static void expect_next_cmd(fx_t *fx, uint32_t id, const uint8_t *b)
{
    while (fx->cursor < fx->tb.log_count) {
        const co_frame_t *f = &fx->tb.log[fx->cursor++].frame;
        if (f->id == id && f->len > 0 && f->data[0] == b[0]) {
            tu_assert_frame(f, id, 0, b, 8);
            return;
        }
    }
    fail_msg("no frame 0x%02X on 0x%03X", b[0], (unsigned)id);
}

/* The next abort frame on this CAN-ID (other frames skipped). */
static void expect_abort(fx_t *fx, uint32_t id, uint16_t index, uint8_t sub, uint32_t code)
{
    uint8_t b[8];
    mux8(b, 0x80, index, sub, code);
    expect_next_cmd(fx, id, b);
}

/* No further logged frame with this CAN-ID. */
static void expect_none(fx_t *fx, uint32_t id)
{
    size_t i;
    for (i = fx->cursor; i < fx->tb.log_count; i++)
        if (fx->tb.log[i].frame.id == id)
            fail_msg("unexpected frame on 0x%03X, byte 0 = 0x%02X", (unsigned)id,
                     fx->tb.log[i].frame.data[0]);
}

/* A frame from the server side straight into the client's line, then the
 * bus settles. */
static void inject_raw(fx_t *fx, uint32_t id, uint8_t flags, const uint8_t *b, uint8_t len)
{
    co_frame_t f = tu_frame(id, flags, b, len);
    assert_true(co_line_receive(fx->cl, &f));
    settle(fx);
}

static void inject(fx_t *fx, uint32_t id, const uint8_t *b) { inject_raw(fx, id, 0, b, 8); }

static void inject_mux(fx_t *fx, uint32_t id, uint8_t cmd, uint16_t index, uint8_t sub,
                       uint32_t d)
{
    uint8_t b[8];
    mux8(b, cmd, index, sub, d);
    inject(fx, id, b);
}

static void inject_seg(fx_t *fx, uint32_t id, uint8_t cmd, const uint8_t *data, uint32_t n)
{
    uint8_t b[8];
    seg8(b, cmd, data, n);
    inject(fx, id, b);
}

/* ------------------------------------------------------------- requests */

static void on_done(co_sdo_request_t *req)
{
    treq_t *t = req->user;
    t->done_calls++;
    t->done_at = t->fx->tb.now;
    t->in_run = false;
    /* the channel is already free when done() runs */
    assert_false(co_sdo_client_running(&t->fx->c, req));
    if (t->hook != NULL)
        t->hook(t);
}

/* A sink that checks the announcement, then is the buffer sink. */
static uint32_t counting_sink(void *ctx, uint32_t offset, const uint8_t *data, uint32_t len,
                              uint32_t total)
{
    treq_t *t = ctx;
    if (len == 0) {
        assert_int_equal(offset, 0);
        assert_null(data);
        assert_false(t->in_run);   /* once per run */
        t->in_run = true;
        t->announces++;
        t->announced = total;
    } else {
        assert_true(t->in_run);    /* before any data */
        if (t->cancel_at != 0 && offset + len >= t->cancel_at) {
            assert_true(co_sdo_client_cancel(&t->fx->c, &t->r, AB_HARDWARE));
            return 0;
        }
    }
    return co_sdo_buffer_sink(&t->buf, offset, data, len, total);
}

static void req_base(fx_t *fx, treq_t *t, uint8_t server, uint16_t index, uint8_t sub)
{
    memset(t, 0, sizeof *t);
    t->fx = fx;
    t->r.server = server;
    t->r.index = index;
    t->r.sub = sub;
    t->r.done = on_done;
    t->r.user = t;
}

static void dl_req(fx_t *fx, treq_t *t, uint8_t server, uint16_t index, uint8_t sub,
                   const uint8_t *data, uint32_t size, uint8_t mode)
{
    req_base(fx, t, server, index, sub);
    t->buf.data = (uint8_t *)(uintptr_t)data;
    t->buf.size = size;
    t->r.size = size;
    t->r.mode = mode;
    t->r.source = co_sdo_buffer_source;
    t->r.ctx = &t->buf;
}

static void ul_req(fx_t *fx, treq_t *t, uint8_t server, uint16_t index, uint8_t sub,
                   uint8_t *mem, uint32_t cap)
{
    req_base(fx, t, server, index, sub);
    t->r.upload = true;
    t->buf.data = mem;
    t->buf.capacity = cap;
    t->r.sink = counting_sink;
    t->r.ctx = t;
}

static void start_ok(fx_t *fx, treq_t *t)
{
    assert_int_equal(co_sdo_client_start(&fx->c, &t->r), 0);
    t->starts++;
}

static void assert_done(const treq_t *t, uint32_t abort, bool from_server)
{
    assert_int_equal(t->done_calls, t->starts);
    assert_int_equal(t->r.abort, abort);
    assert_int_equal(t->r.abort_from_server, from_server);
}

static void assert_all_idle(fx_t *fx)
{
    int i;
    assert_int_equal(co_sdo_client_active(&fx->c), 0);
    for (i = 0; i < NSRV; i++)
        if (fx->srv[i]->running)
            assert_int_equal(co_sdo_server_active(&fx->srv[i]->s), 0);
}

static void assert_od_bytes(srv_t *s, uint16_t index, const uint8_t *data, uint32_t n)
{
    uint8_t buf[256];
    uint32_t len = 0;
    assert_int_equal(co_od_get(&s->od, index, 0, buf, sizeof buf, &len), 0);
    assert_int_equal(len, n);
    if (n > 0)
        assert_memory_equal(buf, data, n);
}

static void set_domain(srv_t *s, uint32_t n, uint8_t seed)
{
    fill_pattern(s->dom, n, seed);
    s->dom_len = n;
}

/* Enable server 5's channel 1 (0x1201: 0x6A5 / 0x6B5). */
static void enable_server_channel1(fx_t *fx)
{
    uint8_t v[4];
    tu_le_put(v, RSP1_5, 4);
    assert_int_equal(co_od_put(&fx->srv[0]->od, 0x1201, 2, v, 4), 0);
    tu_le_put(v, REQ1_5, 4);
    assert_int_equal(co_od_put(&fx->srv[0]->od, 0x1201, 1, v, 4), 0);
    assert_true(fx->srv[0]->ch[1].valid);
}

/* A network-style write into an OD (every check_write runs). */
static uint32_t od_net_write(co_od_t *od, uint16_t index, uint8_t sub, const uint8_t *v,
                             uint32_t n)
{
    uint8_t scratch[64];
    co_od_xfer_t x;
    uint32_t r;
    co_od_xfer_init(&x, scratch, sizeof scratch);
    r = co_od_write_begin(od, &x, index, sub, n);
    if (r == 0)
        r = co_od_write_chunk(&x, v, n);
    if (r == 0)
        r = co_od_write_end(&x);
    return r;
}

static uint32_t od_net_write_u32(co_od_t *od, uint16_t index, uint8_t sub, uint32_t value)
{
    uint8_t v[4];
    tu_le_put(v, value, 4);
    return od_net_write(od, index, sub, v, 4);
}

/* ================================================= init and start */

static void dummy_rx(co_line_t *line, const co_frame_t *f, void *user)
{
    (void)line;
    (void)f;
    (void)user;
}

static void dummy_space(co_line_t *line, void *user)
{
    (void)line;
    (void)user;
}

static void test_init_refuses_bad_config(void **state)
{
    fx_t *fx = *state;
    tu_line_t *fd = calloc(1, sizeof *fd);
    co_sdo_client_t c2;
    co_sdo_client_channel_t *ch = calloc(2, sizeof *ch);
    co_sdo_client_config_t cfg;
    int i, users[CO_LINE_MAX_TX_SPACE];
    assert_non_null(fd);
    assert_non_null(ch);
    memset(&cfg, 0, sizeof cfg);
    cfg.channels = ch;
    cfg.channel_count = 2;
    tu_line_init(fd, CO_MODE_FD, true);
    assert_false(co_sdo_client_init(&c2, &fd->line, &cfg));   /* fd line */
    cfg.channel_count = 0;
    assert_false(co_sdo_client_init(&c2, fx->cl, &cfg));
    cfg.channel_count = 129;
    assert_false(co_sdo_client_init(&c2, fx->cl, &cfg));
    cfg.channel_count = 2;
    cfg.channels = NULL;
    assert_false(co_sdo_client_init(&c2, fx->cl, &cfg));
    cfg.channels = ch;
    assert_false(co_sdo_client_init(NULL, fx->cl, &cfg));
    assert_false(co_sdo_client_init(&c2, NULL, &cfg));
    assert_false(co_sdo_client_init(&c2, fx->cl, NULL));
    /* 0x581..0x5FF already taken by the fixture's client */
    assert_false(co_sdo_client_init(&c2, fx->cl, &cfg));
    /* a full tx-space table: refused, and the range is left free */
    co_sdo_client_deinit(&fx->c);
    for (i = 0; i < CO_LINE_MAX_TX_SPACE; i++)
        assert_true(co_line_tx_space_register(fx->cl, dummy_space, &users[i]));
    assert_false(co_sdo_client_init(&c2, fx->cl, &cfg));
    assert_true(co_line_subscribe(fx->cl, 0x581, 0x5FF, dummy_rx, NULL));
    co_line_unsubscribe(fx->cl, dummy_rx, NULL);
    for (i = 0; i < CO_LINE_MAX_TX_SPACE; i++)
        co_line_tx_space_unregister(fx->cl, dummy_space, &users[i]);
    /* an OD without room for the handler: refused, nothing left behind */
    {
        co_od_t od;
        co_od_entry_t e[2];
        uint8_t pool[16];
        co_od_init(&od, CO_MODE_CLASSIC, e, 2, pool, sizeof pool, NULL, 0);
        assert_true(co_od_seal(&od, 1));
        cfg.od = &od;
        assert_false(co_sdo_client_init(&c2, fx->cl, &cfg));
        assert_int_equal(fx->cl->tx_space_count, 0);
        assert_int_equal(fx->cl->receiver_count, 0);
        cfg.od = NULL;
    }
    assert_true(co_sdo_client_init(&c2, fx->cl, &cfg));
    co_sdo_client_deinit(&c2);
    free(ch);
    free(fd);
}

static void refused_start(fx_t *fx, treq_t *t, uint32_t code)
{
    assert_int_equal(co_sdo_client_start(&fx->c, &t->r), code);
}

static void test_start_refusals(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t data[8] = { 1, 2, 3, 4, 5, 6, 7, 8 }, mem[8];
    uint32_t refused;
    assert_int_equal(co_sdo_client_start(NULL, &t.r), AB_GENERAL);
    assert_int_equal(co_sdo_client_start(&fx->c, NULL), AB_GENERAL);
    dl_req(fx, &t, 5, 0x2002, 0, data, 4, CO_SDO_MODE_AUTO);
    t.r.done = NULL;
    refused_start(fx, &t, AB_GENERAL);
    dl_req(fx, &t, 128, 0x2002, 0, data, 4, CO_SDO_MODE_AUTO);
    refused_start(fx, &t, AB_GENERAL);
    dl_req(fx, &t, 5, 0x2002, 0, data, 4, 4);             /* unknown mode */
    refused_start(fx, &t, AB_GENERAL);
    dl_req(fx, &t, 5, 0x2002, 0, data, 4, CO_SDO_MODE_AUTO);
    t.r.source = NULL;
    refused_start(fx, &t, AB_GENERAL);
    dl_req(fx, &t, 5, 0x2009, 0, data, 0xFFFFFFFFu, CO_SDO_MODE_AUTO);
    refused_start(fx, &t, AB_GENERAL);
    dl_req(fx, &t, 5, 0x2002, 0, data, 5, CO_SDO_MODE_EXPEDITED);
    refused_start(fx, &t, AB_TYPE);
    dl_req(fx, &t, 5, 0x2002, 0, data, 0, CO_SDO_MODE_EXPEDITED);
    refused_start(fx, &t, AB_TYPE);
    ul_req(fx, &t, 5, 0x2002, 0, mem, sizeof mem);
    t.r.sink = NULL;
    refused_start(fx, &t, AB_GENERAL);
    ul_req(fx, &t, 5, 0x2002, 0, mem, sizeof mem);
    t.r.blksize = 128;
    refused_start(fx, &t, AB_BLKSIZE);
    /* by channel index: out of range, not configured */
    ul_req(fx, &t, 0, 0x2002, 0, mem, sizeof mem);
    t.r.channel = NCH;
    refused_start(fx, &t, AB_GENERAL);
    t.r.channel = 2;
    refused_start(fx, &t, AB_GENERAL);
    /* an expedited download whose source fails: refused, nothing sent */
    dl_req(fx, &t, 5, 0x2002, 0, data, 4, CO_SDO_MODE_AUTO);
    t.buf.size = 3;
    log_reset(fx);
    refused_start(fx, &t, AB_GENERAL);
    settle(fx);
    assert_int_equal(fx->tb.log_count, 0);
    assert_int_equal(fx->c.stats.source_failed, 1);
    /* already running */
    ul_req(fx, &t, X, 0x2002, 0, mem, sizeof mem);
    start_ok(fx, &t);
    refused_start(fx, &t, AB_GENERAL);
    assert_true(co_sdo_client_cancel(&fx->c, &t.r, 0));
    assert_done(&t, AB_GENERAL, false);
    refused = fx->c.stats.refused;
    assert_int_equal(refused, 14);
    assert_int_equal(fx->c.stats.started, 1);
    assert_false(co_sdo_client_cancel(&fx->c, &t.r, 0));
    assert_false(co_sdo_client_cancel(NULL, &t.r, 0));
    assert_false(co_sdo_client_running(NULL, &t.r));
    assert_false(co_sdo_client_running(&fx->c, NULL));
    settle(fx);
    assert_all_idle(fx);
}

/* ================================================= expedited */

static const uint16_t size_index[5] = { 0, 0x2000, 0x2001, 0x2011, 0x2002 };

static void test_expedited_download_each_size(void **state)
{
    fx_t *fx = *state;
    const uint8_t data[4] = { 0xA1, 0xB2, 0xC3, 0xD4 };
    uint32_t n;
    for (n = 1; n <= 4; n++) {
        treq_t t;
        uint8_t e[8];
        uint16_t index = size_index[n];
        log_reset(fx);
        dl_req(fx, &t, 5, index, 0, data, n, CO_SDO_MODE_AUTO);
        start_ok(fx, &t);
        assert_int_equal(co_sdo_client_active(&fx->c), 1);
        settle(fx);
        mux8(e, (uint8_t)(0x23u | (4u - n) << 2), index, 0, 0);
        memcpy(e + 4, data, n);
        expect_frame(fx, REQ(5), e);
        expect_mux(fx, RSP(5), 0x60, index, 0, 0);
        expect_none(fx, REQ(5));
        assert_done(&t, 0, false);
        assert_int_equal(t.r.result_mode, CO_SDO_MODE_EXPEDITED);
        assert_int_equal(t.r.transferred, n);
        assert_int_equal(t.r.result_channel, 0);   /* the first spare */
        assert_od_bytes(fx->srv[0], index, data, n);
    }
    /* forced EXPEDITED: the same frame */
    {
        treq_t t;
        log_reset(fx);
        dl_req(fx, &t, 6, 0x2001, 0, data, 2, CO_SDO_MODE_EXPEDITED);
        start_ok(fx, &t);
        settle(fx);
        expect_mux(fx, REQ(6), 0x2B, 0x2001, 0, 0xB2A1);
        assert_done(&t, 0, false);
    }
    assert_int_equal(fx->c.stats.completed, 5);
    assert_all_idle(fx);
}

static void test_expedited_upload_each_size(void **state)
{
    fx_t *fx = *state;
    const uint32_t values[5] = { 0, 0x11, 0x2222, 0x123456, 0x33333305 };
    uint32_t n;
    for (n = 1; n <= 4; n++) {
        treq_t t;
        uint8_t mem[4];
        uint8_t want[4];
        uint16_t index = size_index[n];
        log_reset(fx);
        ul_req(fx, &t, 5, index, 0, mem, sizeof mem);
        start_ok(fx, &t);
        settle(fx);
        expect_mux(fx, REQ(5), 0x40, index, 0, 0);
        expect_mux(fx, RSP(5), (uint8_t)(0x43u | (4u - n) << 2), index, 0, values[n]);
        expect_none(fx, REQ(5));   /* nothing after an expedited answer */
        assert_done(&t, 0, false);
        tu_le_put(want, values[n], 4);
        assert_int_equal(t.buf.size, n);
        assert_memory_equal(mem, want, n);
        assert_int_equal(t.announces, 1);
        assert_int_equal(t.announced, n);
        assert_int_equal(t.r.total, n);
        assert_int_equal(t.r.transferred, n);
        assert_int_equal(t.r.result_mode, CO_SDO_MODE_EXPEDITED);
    }
    assert_all_idle(fx);
}

/* e = 1, s = 0 ("unspecified number of bytes"): all four are taken. */
static void test_expedited_upload_without_size(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t mem[8];
    ul_req(fx, &t, X, 0x2000, 0, mem, sizeof mem);
    start_ok(fx, &t);
    inject_mux(fx, RX_X, 0x42, 0x2000, 0, 0x04030201);
    assert_done(&t, 0, false);
    assert_int_equal(t.buf.size, 4);
    assert_memory_equal(mem, "\x01\x02\x03\x04", 4);
    assert_int_equal(t.announced, 4);
}

/* ================================================= segmented */

static void test_segmented_exact_bytes_both_ways(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t mem[200];
    const uint8_t *d = (const uint8_t *)"0123456789ABCD";
    /* download 10 bytes: 0x21 + size, 7 bytes, then 3 bytes with c = 1 */
    log_reset(fx);
    dl_req(fx, &t, 5, 0x2004, 0, d, 10, CO_SDO_MODE_AUTO);
    start_ok(fx, &t);
    settle(fx);
    expect_mux(fx, REQ(5), 0x21, 0x2004, 0, 10);
    expect_mux(fx, RSP(5), 0x60, 0x2004, 0, 0);
    expect_seg(fx, REQ(5), 0x00, d, 7);
    expect_cmd(fx, RSP(5), 0x20);
    expect_seg(fx, REQ(5), 0x19, d + 7, 3);   /* t = 1, n = 4, c = 1 */
    expect_cmd(fx, RSP(5), 0x30);
    expect_none(fx, REQ(5));
    assert_done(&t, 0, false);
    assert_int_equal(t.r.result_mode, CO_SDO_MODE_SEGMENTED);
    assert_int_equal(t.r.transferred, 10);
    assert_od_bytes(fx->srv[0], 0x2004, d, 10);
    /* upload it back */
    log_reset(fx);
    ul_req(fx, &t, 5, 0x2004, 0, mem, sizeof mem);
    start_ok(fx, &t);
    settle(fx);
    expect_mux(fx, REQ(5), 0x40, 0x2004, 0, 0);
    expect_mux(fx, RSP(5), 0x41, 0x2004, 0, 10);
    expect_cmd(fx, REQ(5), 0x60);
    expect_seg(fx, RSP(5), 0x00, d, 7);
    expect_cmd(fx, REQ(5), 0x70);
    expect_seg(fx, RSP(5), 0x19, d + 7, 3);
    expect_none(fx, REQ(5));
    assert_done(&t, 0, false);
    assert_int_equal(t.r.result_mode, CO_SDO_MODE_SEGMENTED);
    assert_int_equal(t.announced, 10);
    assert_int_equal(t.buf.size, 10);
    assert_memory_equal(mem, d, 10);
    /* exactly 7 bytes: one segment with n = 0, c = 1 */
    log_reset(fx);
    dl_req(fx, &t, 5, 0x2004, 0, d, 7, CO_SDO_MODE_AUTO);
    start_ok(fx, &t);
    settle(fx);
    expect_mux(fx, REQ(5), 0x21, 0x2004, 0, 7);
    expect_seg(fx, REQ(5), 0x01, d, 7);
    assert_done(&t, 0, false);
    /* 0 bytes: AUTO is segmented, size 0, one empty segment (n = 7, c = 1) */
    log_reset(fx);
    dl_req(fx, &t, 5, 0x2004, 0, NULL, 0, CO_SDO_MODE_AUTO);
    t.r.source = NULL;
    start_ok(fx, &t);
    settle(fx);
    expect_mux(fx, REQ(5), 0x21, 0x2004, 0, 0);
    expect_mux(fx, RSP(5), 0x60, 0x2004, 0, 0);
    expect_cmd(fx, REQ(5), 0x0F);
    expect_cmd(fx, RSP(5), 0x20);
    assert_done(&t, 0, false);
    assert_od_bytes(fx->srv[0], 0x2004, NULL, 0);
    /* ... and back: size 0 indicated, one empty segment */
    log_reset(fx);
    ul_req(fx, &t, 5, 0x2004, 0, mem, sizeof mem);
    start_ok(fx, &t);
    settle(fx);
    expect_mux(fx, RSP(5), 0x41, 0x2004, 0, 0);
    expect_cmd(fx, REQ(5), 0x60);
    expect_cmd(fx, RSP(5), 0x0F);
    assert_done(&t, 0, false);
    assert_int_equal(t.buf.size, 0);
    assert_int_equal(t.r.total, 0);
    assert_all_idle(fx);
}

static void test_segmented_100k_domain_both_ways(void **state)
{
    fx_t *fx = *state;
    const uint32_t n = 100000;
    uint8_t *data = malloc(n), *mem = malloc(n);
    treq_t t;
    assert_non_null(data);
    assert_non_null(mem);
    fill_pattern(data, n, 3);
    fx->observe = observe_count;
    dl_req(fx, &t, 5, 0x2009, 0, data, n, CO_SDO_MODE_SEGMENTED);
    start_ok(fx, &t);
    settle(fx);
    assert_done(&t, 0, false);
    assert_int_equal(t.r.result_mode, CO_SDO_MODE_SEGMENTED);
    assert_int_equal(fx->srv[0]->dom_len, n);
    assert_memory_equal(fx->srv[0]->dom, data, n);
    assert_int_equal(fx->count_id[REQ(5)], 1 + (n + 6) / 7);
    assert_int_equal(fx->count_id[RSP(5)], 1 + (n + 6) / 7);
    /* upload (AUTO without a size hint: a normal upload, the server goes
     * segmented with the size) */
    memset(fx->count_id, 0, sizeof fx->count_id);
    ul_req(fx, &t, 5, 0x2009, 0, mem, n);
    start_ok(fx, &t);
    settle(fx);
    assert_done(&t, 0, false);
    assert_int_equal(t.r.result_mode, CO_SDO_MODE_SEGMENTED);
    assert_int_equal(t.r.total, n);
    assert_int_equal(t.buf.size, n);
    assert_memory_equal(mem, data, n);
    assert_int_equal(fx->count_id[REQ(5)], 1 + (n + 6) / 7);
    /* the same without a size: the server does not indicate it */
    memset(mem, 0, n);
    ul_req(fx, &t, 5, 0x200C, 0, mem, n);
    start_ok(fx, &t);
    settle(fx);
    assert_done(&t, 0, false);
    assert_int_equal(t.r.total, CO_SDO_CLIENT_SIZE_UNKNOWN);
    assert_int_equal(t.announced, CO_SDO_CLIENT_SIZE_UNKNOWN);
    assert_int_equal(t.buf.size, n);
    assert_memory_equal(mem, data, n);
    fx->observe = NULL;
    assert_all_idle(fx);
    free(data);
    free(mem);
}

/* ================================================= block download */

static void test_block_download_exact_bytes(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t d[20], e[8];
    uint16_t crc;
    fill_pattern(d, 20, 0x31);
    crc = ref_crc(d, 20);
    /* CRC on both sides */
    log_reset(fx);
    dl_req(fx, &t, 5, 0x2009, 0, d, 20, CO_SDO_MODE_BLOCK);
    start_ok(fx, &t);
    settle(fx);
    expect_mux(fx, REQ(5), 0xC6, 0x2009, 0, 20);        /* cc = 1, s = 1 */
    expect_mux(fx, RSP(5), 0xA4, 0x2009, 0, 127);       /* sc = 1, blksize 127 */
    expect_seg(fx, REQ(5), 0x01, d, 7);
    expect_seg(fx, REQ(5), 0x02, d + 7, 7);
    expect_seg(fx, REQ(5), 0x83, d + 14, 6);            /* c = 1, seqno 3 */
    expect_frame(fx, RSP(5), (const uint8_t[8]){ 0xA2, 3, 127, 0, 0, 0, 0, 0 });
    memset(e, 0, 8);
    e[0] = 0xC5;                                        /* n = 1 */
    e[1] = (uint8_t)(crc & 0xFF);
    e[2] = (uint8_t)(crc >> 8);
    expect_frame(fx, REQ(5), e);
    expect_cmd(fx, RSP(5), 0xA1);
    expect_none(fx, REQ(5));
    assert_done(&t, 0, false);
    assert_true(t.r.crc_used);
    assert_int_equal(t.r.result_mode, CO_SDO_MODE_BLOCK);
    assert_int_equal(t.r.transferred, 20);
    assert_int_equal(fx->srv[0]->dom_len, 20);
    assert_memory_equal(fx->srv[0]->dom, d, 20);
    /* the client offers no CRC: cc = 0, the end carries 0 */
    log_reset(fx);
    dl_req(fx, &t, 5, 0x2009, 0, d, 20, CO_SDO_MODE_BLOCK);
    t.r.no_crc = true;
    start_ok(fx, &t);
    settle(fx);
    expect_mux(fx, REQ(5), 0xC2, 0x2009, 0, 20);
    expect_mux(fx, RSP(5), 0xA4, 0x2009, 0, 127);
    expect_next_cmd(fx, REQ(5), (const uint8_t[8]){ 0xC5, 0, 0, 0, 0, 0, 0, 0 });
    assert_done(&t, 0, false);
    assert_false(t.r.crc_used);
    /* the server has no CRC: sc = 0, the end carries 0 */
    server_restart(fx->srv[0], 0, 0, true);
    log_reset(fx);
    dl_req(fx, &t, 5, 0x2009, 0, d, 20, CO_SDO_MODE_BLOCK);
    start_ok(fx, &t);
    settle(fx);
    expect_mux(fx, REQ(5), 0xC6, 0x2009, 0, 20);
    expect_mux(fx, RSP(5), 0xA0, 0x2009, 0, 127);
    expect_next_cmd(fx, REQ(5), (const uint8_t[8]){ 0xC5, 0, 0, 0, 0, 0, 0, 0 });
    assert_done(&t, 0, false);
    assert_false(t.r.crc_used);
    assert_memory_equal(fx->srv[0]->dom, d, 20);
    /* 0 bytes: one empty segment with c = 1, n = 7 */
    server_restart(fx->srv[0], 0, 0, false);
    log_reset(fx);
    dl_req(fx, &t, 5, 0x2009, 0, NULL, 0, CO_SDO_MODE_BLOCK);
    start_ok(fx, &t);
    settle(fx);
    expect_mux(fx, REQ(5), 0xC6, 0x2009, 0, 0);
    expect_cmd(fx, REQ(5), 0x81);
    expect_cmd(fx, REQ(5), 0xDD);                       /* 0xC1 | 7<<2, CRC 0 */
    assert_done(&t, 0, false);
    assert_int_equal(fx->srv[0]->dom_len, 0);
    assert_all_idle(fx);
}

static void test_block_download_blksizes_crc(void **state)
{
    fx_t *fx = *state;
    static const uint8_t blksizes[3] = { 1, 7, 127 };
    const uint32_t n = 3000, segs = (n + 6) / 7;
    uint8_t *data = malloc(n);
    int b, crc;
    assert_non_null(data);
    fx->observe = observe_count;
    for (b = 0; b < 3; b++) {
        for (crc = 0; crc < 2; crc++) {
            treq_t t;
            uint32_t subs = (segs + blksizes[b] - 1u) / blksizes[b];
            server_restart(fx->srv[1], 0, blksizes[b], false);
            fill_pattern(data, n, (uint8_t)(b * 2 + crc));
            memset(fx->count_id, 0, sizeof fx->count_id);
            dl_req(fx, &t, 6, 0x2009, 0, data, n, CO_SDO_MODE_AUTO);
            t.r.no_crc = crc == 0;
            start_ok(fx, &t);
            settle(fx);
            assert_done(&t, 0, false);
            assert_int_equal(t.r.result_mode, CO_SDO_MODE_BLOCK);
            assert_int_equal(t.r.crc_used, crc == 1);
            assert_int_equal(fx->srv[1]->dom_len, n);
            assert_memory_equal(fx->srv[1]->dom, data, n);
            /* initiate, every segment once, end; initiate response, one ack
             * per sub-block, end response */
            assert_int_equal(fx->count_id[REQ(6)], 2 + segs);
            assert_int_equal(fx->count_id[RSP(6)], 2 + subs);
        }
    }
    fx->observe = NULL;
    assert_int_equal(fx->c.stats.block_repeats, 0);
    assert_all_idle(fx);
    free(data);
}

/* One segment lost: the server acknowledges the sub-block short, the client
 * repeats the rest renumbered from 1 (CiA 301). */
static void test_block_download_lost_segment_repeated(void **state)
{
    fx_t *fx = *state;
    const uint32_t n = 2000;
    uint8_t *data = malloc(n);
    treq_t t;
    long k;
    assert_non_null(data);
    fill_pattern(data, n, 9);
    fault_drop_nth(fx, REQ(5), 4);   /* initiate, 1, 2, [3] */
    log_reset(fx);
    dl_req(fx, &t, 5, 0x2009, 0, data, n, CO_SDO_MODE_BLOCK);
    start_ok(fx, &t);
    settle(fx);
    assert_done(&t, 0, false);
    assert_int_equal(fx->fault_dropped, 1);
    assert_int_equal(fx->srv[0]->dom_len, n);
    assert_memory_equal(fx->srv[0]->dom, data, n);
    /* the server's short ack, then the client's next sub-block starts with
     * the data of the lost segment, as seqno 1 */
    expect_mux(fx, REQ(5), 0xC6, 0x2009, 0, n);
    expect_seg(fx, REQ(5), 0x01, data, 7);
    expect_seg(fx, REQ(5), 0x02, data + 7, 7);
    expect_seg(fx, REQ(5), 0x04, data + 21, 7);          /* (3 was lost) */
    expect_frame(fx, RSP(5), (const uint8_t[8]){ 0xA2, 2, 127, 0, 0, 0, 0, 0 });
    k = (long)fx->cursor;
    while (fx->tb.log[k].frame.id != REQ(5))
        k++;
    fx->cursor = (size_t)k;
    expect_seg(fx, REQ(5), 0x01, data + 14, 7);
    expect_seg(fx, REQ(5), 0x02, data + 21, 7);
    assert_int_equal(fx->c.stats.block_repeats, 125);
    assert_int_equal(fx->srv[0]->s.stats.block_partial_acks, 1);
    assert_true(t.r.crc_used);
    assert_all_idle(fx);
    free(data);
}

/* Block download segments go out in bursts of at most
 * CO_SDO_CLIENT_BLOCK_BURST per co_line_process call. */
static void test_block_download_burst_per_process_call(void **state)
{
    fx_t *fx = *state;
    const uint32_t n = 3000;
    uint8_t *data = malloc(n);
    treq_t t;
    co_frame_t f;
    co_sdo_client_channel_t *ch;
    unsigned i;
    assert_non_null(data);
    fill_pattern(data, n, 45);
    dl_req(fx, &t, X, 0x2009, 0, data, n, CO_SDO_MODE_BLOCK);
    start_ok(fx, &t);
    settle(fx);
    ch = &fx->cch[t.r.result_channel];
    f = tu_frame(RX_X, 0, (const uint8_t[8]){ 0xA4, 0x09, 0x20, 0, 127, 0, 0, 0 }, 8);
    assert_true(co_line_receive(fx->cl, &f));
    (void)co_line_process(fx->cl, fx->tb.now);
    assert_int_equal(co_queue_count(&fx->cl->tx), CO_SDO_CLIENT_BLOCK_BURST);
    assert_int_equal(ch->state, CO_SDO_CLIENT_BD_SEND);
    (void)co_line_process(fx->cl, fx->tb.now);
    assert_int_equal(co_queue_count(&fx->cl->tx), 127);
    assert_int_equal(ch->state, CO_SDO_CLIENT_BD_ACK);
    (void)co_line_process(fx->cl, fx->tb.now);
    assert_int_equal(co_queue_count(&fx->cl->tx), 127);
    for (i = 1; i <= 127; i++) {
        uint8_t e[8];
        assert_true(co_line_tx_pop(fx->cl, &f));
        seg8(e, (uint8_t)i, data + (i - 1) * 7, 7);
        tu_assert_frame(&f, TX_X, 0, e, 8);
    }
    assert_true(co_sdo_client_cancel(&fx->c, &t.r, 0));
    settle(fx);
    assert_all_idle(fx);
    free(data);
}

/* A server that acknowledges at the gap, while the client is still
 * sending, and a stale ack: the tx queue is kept nearly full so the
 * sub-block goes out slowly. */
static void test_block_download_flow_control_and_early_ack(void **state)
{
    fx_t *fx = *state;
    const uint32_t n = 3000;
    uint8_t *data = malloc(n);
    uint8_t filler[8] = { 0 };
    treq_t t;
    co_frame_t f;
    co_sdo_client_channel_t *ch;
    unsigned i;
    assert_non_null(data);
    fill_pattern(data, n, 44);
    dl_req(fx, &t, X, 0x2009, 0, data, n, CO_SDO_MODE_BLOCK);
    start_ok(fx, &t);
    settle(fx);
    ch = &fx->cch[t.r.result_channel];
    /* 150 frames of another service wait in the tx queue: 42 segments fit
     * below 3/4 (192 of 256) */
    for (i = 0; i < 150; i++)
        assert_true(co_line_send(fx->cl, 0x181, filler, 8));
    f = tu_frame(RX_X, 0, (const uint8_t[8]){ 0xA4, 0x09, 0x20, 0, 127, 0, 0, 0 }, 8);
    assert_true(co_line_receive(fx->cl, &f));
    (void)co_line_process(fx->cl, fx->tb.now);
    assert_int_equal(ch->state, CO_SDO_CLIENT_BD_SEND);
    assert_int_equal(ch->seqno, 42);
    assert_true(ch->wait_space);
    assert_int_equal(co_queue_count(&fx->cl->tx), 192);
    assert_int_equal(fx->c.stats.tx_paused, 1);
    /* nothing more without room */
    (void)co_line_process(fx->cl, fx->tb.now);
    assert_int_equal(ch->seqno, 42);
    /* a stale ack (above what was sent): ignored */
    f = tu_frame(RX_X, 0, (const uint8_t[8]){ 0xA2, 100, 127, 0, 0, 0, 0, 0 }, 8);
    assert_true(co_line_receive(fx->cl, &f));
    (void)co_line_process(fx->cl, fx->tb.now);
    assert_int_equal(fx->c.stats.rx_duplicate, 1);
    assert_int_equal(ch->seqno, 42);
    /* an ack at a gap while sending: taken, the rest from segment 6 again */
    f = tu_frame(RX_X, 0, (const uint8_t[8]){ 0xA2, 5, 20, 0, 0, 0, 0, 0 }, 8);
    assert_true(co_line_receive(fx->cl, &f));
    (void)co_line_process(fx->cl, fx->tb.now);
    assert_int_equal(t.r.transferred, 35);
    assert_int_equal(fx->c.stats.block_repeats, 37);
    assert_int_equal(ch->blksize, 20);
    assert_int_equal(ch->seqno, 0);          /* still no room */
    assert_true(ch->wait_space);
    /* the driver takes frames: at half the client resumes (next process) */
    while (co_queue_count(&fx->cl->tx) > 128)
        assert_true(co_line_tx_pop(fx->cl, &f));
    assert_false(ch->wait_space);
    (void)co_line_process(fx->cl, fx->tb.now);
    assert_int_equal(ch->state, CO_SDO_CLIENT_BD_ACK);
    assert_int_equal(ch->seqno, 20);
    /* the queue's tail: the new sub-block, renumbered from 1 at byte 35 */
    while (co_queue_count(&fx->cl->tx) > 20)
        assert_true(co_line_tx_pop(fx->cl, &f));
    for (i = 1; i <= 20; i++) {
        uint8_t e[8];
        assert_true(co_line_tx_pop(fx->cl, &f));
        seg8(e, (uint8_t)i, data + 35 + (i - 1) * 7, 7);
        tu_assert_frame(&f, TX_X, 0, e, 8);
    }
    assert_true(co_sdo_client_cancel(&fx->c, &t.r, 0));
    settle(fx);
    assert_all_idle(fx);
    free(data);
}

/* ================================================= block upload */

static void test_block_upload_exact_bytes(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t mem[64], e[8];
    uint16_t crc;
    set_domain(fx->srv[0], 10, 0x51);
    crc = ref_crc(fx->srv[0]->dom, 10);
    log_reset(fx);
    ul_req(fx, &t, 5, 0x2009, 0, mem, sizeof mem);
    t.r.mode = CO_SDO_MODE_BLOCK;
    start_ok(fx, &t);
    settle(fx);
    expect_mux(fx, REQ(5), 0xA4, 0x2009, 0, 127);        /* cc = 1, blksize 127, pst 0 */
    expect_mux(fx, RSP(5), 0xC6, 0x2009, 0, 10);         /* sc = 1, s = 1, size 10 */
    expect_cmd(fx, REQ(5), 0xA3);
    expect_seg(fx, RSP(5), 0x01, fx->srv[0]->dom, 7);
    expect_seg(fx, RSP(5), 0x82, fx->srv[0]->dom + 7, 3);
    expect_frame(fx, REQ(5), (const uint8_t[8]){ 0xA2, 2, 127, 0, 0, 0, 0, 0 });
    memset(e, 0, 8);
    e[0] = 0xD1;                                         /* n = 4 */
    e[1] = (uint8_t)(crc & 0xFF);
    e[2] = (uint8_t)(crc >> 8);
    expect_frame(fx, RSP(5), e);
    expect_cmd(fx, REQ(5), 0xA1);
    expect_none(fx, REQ(5));
    assert_done(&t, 0, false);
    assert_true(t.r.crc_used);
    assert_int_equal(t.r.result_mode, CO_SDO_MODE_BLOCK);
    assert_int_equal(t.announced, 10);
    assert_int_equal(t.buf.size, 10);
    assert_memory_equal(mem, fx->srv[0]->dom, 10);
    /* client without CRC, blksize 5, pst 3 (the size is above it) */
    log_reset(fx);
    ul_req(fx, &t, 5, 0x2009, 0, mem, sizeof mem);
    t.r.mode = CO_SDO_MODE_BLOCK;
    t.r.no_crc = true;
    t.r.blksize = 5;
    t.r.pst = 3;
    start_ok(fx, &t);
    settle(fx);
    mux8(e, 0xA0, 0x2009, 0, 0);
    e[4] = 5;
    e[5] = 3;
    expect_frame(fx, REQ(5), e);
    expect_mux(fx, RSP(5), 0xC6, 0x2009, 0, 10);         /* the server still has CRC */
    expect_cmd(fx, REQ(5), 0xA3);
    expect_frame(fx, REQ(5), (const uint8_t[8]){ 0xA2, 2, 5, 0, 0, 0, 0, 0 });
    assert_done(&t, 0, false);
    assert_false(t.r.crc_used);
    assert_memory_equal(mem, fx->srv[0]->dom, 10);
    /* an empty domain: one segment with c = 1 and n = 7 */
    fx->srv[0]->dom_len = 0;
    log_reset(fx);
    ul_req(fx, &t, 5, 0x2009, 0, mem, sizeof mem);
    t.r.mode = CO_SDO_MODE_BLOCK;
    start_ok(fx, &t);
    settle(fx);
    expect_mux(fx, RSP(5), 0xC6, 0x2009, 0, 0);
    expect_cmd(fx, RSP(5), 0x81);
    expect_cmd(fx, RSP(5), 0xDD);
    assert_done(&t, 0, false);
    assert_int_equal(t.buf.size, 0);
    assert_all_idle(fx);
}

static void test_block_upload_blksizes_crc(void **state)
{
    fx_t *fx = *state;
    static const uint8_t blksizes[3] = { 1, 7, 127 };
    const uint32_t n = 3000, segs = (n + 6) / 7;
    uint8_t *mem = malloc(n);
    int b, crc;
    assert_non_null(mem);
    fx->observe = observe_count;
    for (b = 0; b < 3; b++) {
        for (crc = 0; crc < 2; crc++) {
            treq_t t;
            uint32_t subs = (segs + blksizes[b] - 1u) / blksizes[b];
            set_domain(fx->srv[2], n, (uint8_t)(b * 2 + crc + 100));
            memset(fx->count_id, 0, sizeof fx->count_id);
            memset(mem, 0, n);
            ul_req(fx, &t, 7, 0x2009, 0, mem, n);
            t.r.mode = CO_SDO_MODE_BLOCK;
            t.r.blksize = blksizes[b];
            t.r.no_crc = crc == 0;
            start_ok(fx, &t);
            settle(fx);
            assert_done(&t, 0, false);
            assert_int_equal(t.r.crc_used, crc == 1);
            assert_int_equal(t.buf.size, n);
            assert_memory_equal(mem, fx->srv[2]->dom, n);
            /* initiate, start, one ack per sub-block, end response */
            assert_int_equal(fx->count_id[REQ(7)], 3 + subs);
            assert_int_equal(fx->count_id[RSP(7)], 2 + segs);
        }
    }
    /* the unknown size of 0x200C (not indicated) with blksize 7 */
    {
        treq_t t;
        set_domain(fx->srv[2], 777, 1);
        ul_req(fx, &t, 7, 0x200C, 0, mem, n);
        t.r.mode = CO_SDO_MODE_BLOCK;
        t.r.blksize = 7;
        start_ok(fx, &t);
        settle(fx);
        assert_done(&t, 0, false);
        assert_int_equal(t.r.total, CO_SDO_CLIENT_SIZE_UNKNOWN);
        assert_int_equal(t.buf.size, 777);
        assert_memory_equal(mem, fx->srv[2]->dom, 777);
    }
    fx->observe = NULL;
    assert_int_equal(fx->c.stats.block_partial_acks, 0);
    assert_all_idle(fx);
    free(mem);
}

/* One segment from the server lost: the client acknowledges the sub-block
 * with the last good seqno, the server repeats from there. */
static void test_block_upload_lost_segment_repeated(void **state)
{
    fx_t *fx = *state;
    const uint32_t n = 2000;
    uint8_t *mem = malloc(n);
    treq_t t;
    assert_non_null(mem);
    set_domain(fx->srv[0], n, 77);
    fault_drop_nth(fx, RSP(5), 6);   /* initiate response, 1..4, [5] */
    log_reset(fx);
    ul_req(fx, &t, 5, 0x2009, 0, mem, n);
    t.r.mode = CO_SDO_MODE_BLOCK;
    start_ok(fx, &t);
    settle(fx);
    assert_done(&t, 0, false);
    assert_int_equal(fx->fault_dropped, 1);
    assert_int_equal(t.buf.size, n);
    assert_memory_equal(mem, fx->srv[0]->dom, n);
    expect_mux(fx, REQ(5), 0xA4, 0x2009, 0, 127);
    expect_cmd(fx, REQ(5), 0xA3);
    expect_frame(fx, REQ(5), (const uint8_t[8]){ 0xA2, 4, 127, 0, 0, 0, 0, 0 });
    /* the repeat: seqno 1 carries the lost data (bytes 28..34) */
    expect_seg(fx, RSP(5), 0x01, fx->srv[0]->dom + 28, 7);
    assert_int_equal(fx->c.stats.block_partial_acks, 1);
    assert_int_equal(fx->c.stats.rx_block_ignored, 122);
    assert_int_equal(fx->srv[0]->s.stats.block_repeats, 123);
    assert_all_idle(fx);
    free(mem);
}

/* Duplicated and out-of-order segments, scripted: a repeat is ignored, a
 * gap makes the end of the sub-block a short ack. */
static void test_block_upload_scripted_repeats(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t mem[64], d[28];
    fill_pattern(d, sizeof d, 5);
    log_reset(fx);
    ul_req(fx, &t, X, 0x2009, 0, mem, sizeof mem);
    t.r.mode = CO_SDO_MODE_BLOCK;
    t.r.blksize = 3;
    start_ok(fx, &t);
    inject_mux(fx, RX_X, 0xC6, 0x2009, 0, 32);
    expect_mux(fx, TX_X, 0xA4, 0x2009, 0, 3);
    expect_cmd(fx, TX_X, 0xA3);
    inject_seg(fx, RX_X, 0x01, d, 7);
    inject_seg(fx, RX_X, 0x01, d, 7);                    /* repeated: ignored */
    inject_seg(fx, RX_X, 0x03, d + 14, 7);               /* gap, ends the sub-block */
    expect_frame(fx, TX_X, (const uint8_t[8]){ 0xA2, 1, 3, 0, 0, 0, 0, 0 });
    inject_seg(fx, RX_X, 0x01, d + 7, 7);
    inject_seg(fx, RX_X, 0x02, d + 14, 7);
    inject_seg(fx, RX_X, 0x03, d + 21, 7);
    expect_frame(fx, TX_X, (const uint8_t[8]){ 0xA2, 3, 3, 0, 0, 0, 0, 0 });
    /* a repeat of the last segment at the start of a sub-block: ignored,
     * no ack */
    inject_seg(fx, RX_X, 0x03, d + 21, 7);
    expect_none(fx, TX_X);
    inject_seg(fx, RX_X, 0x81, d + 7, 7);                /* the last one: 4 bytes (n = 3) */
    expect_frame(fx, TX_X, (const uint8_t[8]){ 0xA2, 1, 3, 0, 0, 0, 0, 0 });
    inject_seg(fx, RX_X, 0x81, d + 7, 7);                /* again: ignored */
    {
        uint8_t all[32];
        uint16_t crc;
        uint8_t e[8] = { 0xCD, 0, 0, 0, 0, 0, 0, 0 };   /* 0xC1 | 3<<2 */
        memcpy(all, d, 28);
        memcpy(all + 28, d + 7, 4);
        crc = ref_crc(all, 32);
        e[1] = (uint8_t)(crc & 0xFF);
        e[2] = (uint8_t)(crc >> 8);
        inject(fx, RX_X, e);
        expect_cmd(fx, TX_X, 0xA1);
        assert_done(&t, 0, false);
        assert_int_equal(t.buf.size, 32);
        assert_memory_equal(mem, all, 32);
    }
    assert_int_equal(fx->c.stats.rx_block_ignored, 3);
    assert_int_equal(fx->c.stats.rx_duplicate, 1);
    assert_int_equal(fx->c.stats.block_partial_acks, 1);
    /* a sub-block whose end never comes: acknowledged at the first timeout,
     * aborted at the second */
    log_reset(fx);
    ul_req(fx, &t, X, 0x2009, 0, mem, sizeof mem);
    t.r.mode = CO_SDO_MODE_BLOCK;
    t.r.blksize = 3;
    start_ok(fx, &t);
    inject_mux(fx, RX_X, 0xC6, 0x2009, 0, 32);
    inject_seg(fx, RX_X, 0x01, d, 7);
    run_ms(fx, 999);
    expect_mux(fx, TX_X, 0xA4, 0x2009, 0, 3);
    expect_cmd(fx, TX_X, 0xA3);
    expect_none(fx, TX_X);
    run_ms(fx, 1);
    expect_frame(fx, TX_X, (const uint8_t[8]){ 0xA2, 1, 3, 0, 0, 0, 0, 0 });
    run_ms(fx, 1000);
    expect_abort(fx, TX_X, 0x2009, 0, AB_TIMEOUT);
    assert_done(&t, AB_TIMEOUT, false);
    assert_all_idle(fx);
}

/* The server answers the block upload initiate as a normal upload (pst). */
static void test_block_upload_protocol_switch(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t mem[64], e[8];
    log_reset(fx);
    ul_req(fx, &t, 5, 0x2004, 0, mem, sizeof mem);
    t.r.mode = CO_SDO_MODE_BLOCK;
    t.r.pst = 10;
    start_ok(fx, &t);
    settle(fx);
    mux8(e, 0xA4, 0x2004, 0, 0);
    e[4] = 127;
    e[5] = 10;
    expect_frame(fx, REQ(5), e);
    expect_mux(fx, RSP(5), 0x41, 0x2004, 0, 5);          /* "hello": segmented */
    expect_cmd(fx, REQ(5), 0x60);
    expect_seg(fx, RSP(5), 0x05, (const uint8_t *)"hello", 5);
    expect_none(fx, REQ(5));
    assert_done(&t, 0, false);
    assert_int_equal(t.r.result_mode, CO_SDO_MODE_SEGMENTED);
    assert_int_equal(t.buf.size, 5);
    assert_memory_equal(mem, "hello", 5);
    /* ... and expedited */
    log_reset(fx);
    ul_req(fx, &t, 5, 0x2002, 0, mem, sizeof mem);
    t.r.mode = CO_SDO_MODE_BLOCK;
    t.r.pst = 4;
    start_ok(fx, &t);
    settle(fx);
    expect_mux(fx, RSP(5), 0x43, 0x2002, 0, 0x33333305);
    expect_none(fx, REQ(5));
    assert_done(&t, 0, false);
    assert_int_equal(t.r.result_mode, CO_SDO_MODE_EXPEDITED);
    assert_int_equal(t.buf.size, 4);
    assert_int_equal(fx->c.stats.protocol_switches, 2);
    assert_int_equal(fx->srv[0]->s.stats.protocol_switches, 2);
    assert_all_idle(fx);
}

/* ================================================= AUTO and fallback */

static uint8_t first_cmd(fx_t *fx, uint32_t id)
{
    long k = tu_log_find_id(&fx->tb, id, 0);
    assert_true(k >= 0);
    return fx->tb.log[k].frame.data[0];
}

static void test_auto_mode_choice(void **state)
{
    fx_t *fx = *state;
    static uint8_t data[3000];
    uint8_t mem[3000];
    static const struct {
        uint32_t size;
        uint32_t req_threshold;
        uint8_t cmd;
        uint8_t mode;
    } dl[] = {
        { 1, 0, 0x2F, CO_SDO_MODE_EXPEDITED },
        { 4, 0, 0x23, CO_SDO_MODE_EXPEDITED },
        { 5, 0, 0x21, CO_SDO_MODE_SEGMENTED },
        { 1023, 0, 0x21, CO_SDO_MODE_SEGMENTED },
        { 1024, 0, 0xC6, CO_SDO_MODE_BLOCK },
        { 2999, 0, 0xC6, CO_SDO_MODE_BLOCK },
        { 100, 100, 0xC6, CO_SDO_MODE_BLOCK },          /* per request */
        { 99, 100, 0x21, CO_SDO_MODE_SEGMENTED },
        { 2999, CO_SDO_CLIENT_NO_BLOCK, 0x21, CO_SDO_MODE_SEGMENTED },
        { 4, 1, 0x23, CO_SDO_MODE_EXPEDITED },          /* expedited first */
    };
    size_t i;
    fill_pattern(data, sizeof data, 8);
    assert_int_equal(co_sdo_client_choose_mode(CO_SDO_MODE_AUTO, 0, 0), CO_SDO_MODE_SEGMENTED);
    assert_int_equal(co_sdo_client_choose_mode(CO_SDO_MODE_AUTO, 4, 0), CO_SDO_MODE_EXPEDITED);
    assert_int_equal(co_sdo_client_choose_mode(CO_SDO_MODE_AUTO, 1023, 0), CO_SDO_MODE_SEGMENTED);
    assert_int_equal(co_sdo_client_choose_mode(CO_SDO_MODE_AUTO, 1024, 0), CO_SDO_MODE_BLOCK);
    assert_int_equal(co_sdo_client_choose_mode(CO_SDO_MODE_AUTO, 50, 50), CO_SDO_MODE_BLOCK);
    assert_int_equal(co_sdo_client_choose_mode(CO_SDO_MODE_SEGMENTED, 5000, 0),
                     CO_SDO_MODE_SEGMENTED);
    assert_int_equal(co_sdo_client_choose_mode(CO_SDO_MODE_BLOCK, 3, 0), CO_SDO_MODE_BLOCK);
    for (i = 0; i < sizeof dl / sizeof dl[0]; i++) {
        treq_t t;
        log_reset(fx);
        dl_req(fx, &t, 5, 0x2009, 0, data, dl[i].size, CO_SDO_MODE_AUTO);
        t.r.block_threshold = dl[i].req_threshold;
        start_ok(fx, &t);
        settle(fx);
        assert_done(&t, 0, false);
        assert_int_equal(first_cmd(fx, REQ(5)), dl[i].cmd);
        assert_int_equal(t.r.result_mode, dl[i].mode);
        assert_int_equal(fx->srv[0]->dom_len, dl[i].size);
    }
    /* uploads: block from the size hint on, else a normal upload */
    {
        static const struct {
            uint32_t hint, req_threshold;
            uint8_t cmd;
        } ul[] = { { 0, 0, 0x40 }, { 1023, 0, 0x40 }, { 1024, 0, 0xA4 }, { 500, 500, 0xA4 },
                   { 3, 1, 0x40 } };
        set_domain(fx->srv[0], 1500, 2);
        for (i = 0; i < sizeof ul / sizeof ul[0]; i++) {
            treq_t t;
            log_reset(fx);
            ul_req(fx, &t, 5, 0x2009, 0, mem, sizeof mem);
            t.r.size = ul[i].hint;
            t.r.block_threshold = ul[i].req_threshold;
            start_ok(fx, &t);
            settle(fx);
            assert_done(&t, 0, false);
            assert_int_equal(first_cmd(fx, REQ(5)), ul[i].cmd);
            assert_int_equal(t.r.result_mode,
                             ul[i].cmd == 0xA4 ? CO_SDO_MODE_BLOCK : CO_SDO_MODE_SEGMENTED);
            assert_int_equal(t.buf.size, 1500);
            assert_memory_equal(mem, fx->srv[0]->dom, 1500);
        }
    }
    /* the client's default threshold is configurable */
    co_sdo_client_deinit(&fx->c);
    client_start_cfg(fx, NULL, 0, 100);
    {
        treq_t t;
        log_reset(fx);
        dl_req(fx, &t, 5, 0x2009, 0, data, 100, CO_SDO_MODE_AUTO);
        start_ok(fx, &t);
        settle(fx);
        assert_done(&t, 0, false);
        assert_int_equal(first_cmd(fx, REQ(5)), 0xC6);
        log_reset(fx);
        dl_req(fx, &t, 5, 0x2009, 0, data, 99, CO_SDO_MODE_AUTO);
        start_ok(fx, &t);
        settle(fx);
        assert_int_equal(first_cmd(fx, REQ(5)), 0x21);
    }
    assert_all_idle(fx);
}

/* A server without block transfer refuses the block initiate with
 * 0x05040001: AUTO does the transfer again without block; forced BLOCK
 * reports the refusal. */
static void test_block_refused_falls_back(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t d[12], mem[16];
    fill_pattern(d, sizeof d, 0x21);
    log_reset(fx);
    dl_req(fx, &t, X, 0x2009, 0, d, 12, CO_SDO_MODE_AUTO);
    t.r.block_threshold = 10;
    start_ok(fx, &t);
    settle(fx);
    expect_mux(fx, TX_X, 0xC6, 0x2009, 0, 12);
    inject_mux(fx, RX_X, 0x80, 0x2009, 0, AB_COMMAND);
    expect_mux(fx, TX_X, 0x21, 0x2009, 0, 12);           /* at once, segmented */
    inject_mux(fx, RX_X, 0x60, 0x2009, 0, 0);
    expect_seg(fx, TX_X, 0x00, d, 7);
    inject_seg(fx, RX_X, 0x20, NULL, 0);
    expect_seg(fx, TX_X, 0x15, d + 7, 5);               /* t = 1, n = 2, c = 1 */
    inject_seg(fx, RX_X, 0x30, NULL, 0);
    expect_none(fx, TX_X);
    assert_done(&t, 0, false);
    assert_true(t.r.fell_back);
    assert_int_equal(t.r.result_mode, CO_SDO_MODE_SEGMENTED);
    assert_int_equal(t.r.transferred, 12);
    assert_int_equal(fx->c.stats.block_fallback, 1);
    /* the segmented attempt refused too: reported, no second fallback */
    log_reset(fx);
    start_ok(fx, &t);
    inject_mux(fx, RX_X, 0x80, 0x2009, 0, AB_COMMAND);
    inject_mux(fx, RX_X, 0x80, 0x2009, 0, AB_COMMAND);
    assert_done(&t, AB_COMMAND, true);
    assert_true(t.r.fell_back);
    assert_int_equal(fx->c.stats.block_fallback, 2);
    /* forced BLOCK: the refusal is the result */
    log_reset(fx);
    dl_req(fx, &t, X, 0x2009, 0, d, 12, CO_SDO_MODE_BLOCK);
    start_ok(fx, &t);
    inject_mux(fx, RX_X, 0x80, 0x2009, 0, AB_COMMAND);
    assert_done(&t, AB_COMMAND, true);
    assert_false(t.r.fell_back);
    expect_mux(fx, TX_X, 0xC6, 0x2009, 0, 12);
    expect_none(fx, TX_X);
    /* AUTO upload with a size hint: a normal upload instead */
    log_reset(fx);
    ul_req(fx, &t, X, 0x2009, 0, mem, sizeof mem);
    t.r.size = 2000;
    start_ok(fx, &t);
    inject_mux(fx, RX_X, 0x80, 0x2009, 0, AB_COMMAND);
    expect_mux(fx, TX_X, 0xA4, 0x2009, 0, 127);
    expect_mux(fx, TX_X, 0x40, 0x2009, 0, 0);
    inject_mux(fx, RX_X, 0x4B, 0x2009, 0, 0xBEEF);
    assert_done(&t, 0, false);
    assert_true(t.r.fell_back);
    assert_int_equal(t.r.result_mode, CO_SDO_MODE_EXPEDITED);
    assert_int_equal(t.buf.size, 2);
    assert_int_equal(fx->c.stats.block_fallback, 3);
    /* another code than 0x05040001 is not a fallback reason */
    log_reset(fx);
    dl_req(fx, &t, X, 0x2009, 0, d, 12, CO_SDO_MODE_AUTO);
    t.r.block_threshold = 10;
    start_ok(fx, &t);
    inject_mux(fx, RX_X, 0x80, 0x2009, 0, AB_STORE);
    assert_done(&t, AB_STORE, true);
    assert_int_equal(fx->c.stats.block_fallback, 3);
    assert_all_idle(fx);
}

/* ================================================= channels */

static void test_three_servers_at_once(void **state)
{
    fx_t *fx = *state;
    const uint32_t n = 5000;
    uint8_t *d5 = malloc(n), *d6 = malloc(n), *mem = malloc(n);
    treq_t t[4];
    uint8_t up6[8];
    int i;
    assert_non_null(d5);
    assert_non_null(d6);
    assert_non_null(mem);
    fill_pattern(d5, n, 5);
    fill_pattern(d6, 300, 6);
    set_domain(fx->srv[2], n, 7);
    dl_req(fx, &t[0], 5, 0x2009, 0, d5, n, CO_SDO_MODE_AUTO);          /* block */
    dl_req(fx, &t[1], 6, 0x2009, 0, d6, 300, CO_SDO_MODE_SEGMENTED);
    ul_req(fx, &t[2], 7, 0x2009, 0, mem, n);
    t[2].r.mode = CO_SDO_MODE_BLOCK;
    ul_req(fx, &t[3], 6, 0x2002, 0, up6, sizeof up6);
    for (i = 0; i < 3; i++)
        start_ok(fx, &t[i]);
    assert_int_equal(co_sdo_client_active(&fx->c), 3);
    /* server 6's default channel is busy: refused, nothing changes */
    assert_int_equal(co_sdo_client_start(&fx->c, &t[3].r), AB_RESOURCE);
    rounds(fx, 3);
    for (i = 0; i < NSRV; i++)
        assert_int_equal(co_sdo_server_active(&fx->srv[i]->s), 1);
    fx->observe = observe_count;
    settle(fx);
    fx->observe = NULL;
    for (i = 0; i < 3; i++)
        assert_done(&t[i], 0, false);
    assert_int_not_equal(t[0].r.result_channel, t[1].r.result_channel);
    assert_int_not_equal(t[1].r.result_channel, t[2].r.result_channel);
    assert_int_equal(fx->srv[0]->dom_len, n);
    assert_memory_equal(fx->srv[0]->dom, d5, n);
    assert_int_equal(fx->srv[1]->dom_len, 300);
    assert_memory_equal(fx->srv[1]->dom, d6, 300);
    assert_int_equal(t[2].buf.size, n);
    assert_memory_equal(mem, fx->srv[2]->dom, n);
    assert_true(fx->count_id[REQ(5)] > 400 && fx->count_id[REQ(6)] > 30 &&
                fx->count_id[REQ(7)] > 3);
    /* now it goes */
    start_ok(fx, &t[3]);
    settle(fx);
    assert_done(&t[3], 0, false);
    assert_int_equal(tu_le_get(up6, 4), 0x33333306);
    assert_all_idle(fx);
    free(d5);
    free(d6);
    free(mem);
}

/* Two configured channels to server 5 (its default channel and its 0x1201
 * channel) carry two transfers at once; a request by channel index. */
static void test_two_channels_to_one_server(void **state)
{
    fx_t *fx = *state;
    const uint32_t n = 4000;
    uint8_t *d = malloc(n), *mem = malloc(n);
    treq_t t[3];
    assert_non_null(d);
    assert_non_null(mem);
    fill_pattern(d, n, 12);
    set_domain(fx->srv[0], n, 13);
    enable_server_channel1(fx);
    assert_true(co_sdo_client_channel_set(&fx->c, 3, 5, REQ1_5, RSP1_5));
    assert_true(fx->cch[3].subscribed);   /* 0x6B5: outside 0x581..0x5FF */
    assert_true(co_sdo_client_channel_set(&fx->c, 4, 5, 0, 0));
    assert_int_equal(fx->cch[4].tx_id, REQ(5));
    assert_int_equal(fx->cch[4].rx_id, RSP(5));
    ul_req(fx, &t[0], 5, 0x2009, 0, mem, n);
    t[0].r.mode = CO_SDO_MODE_BLOCK;
    dl_req(fx, &t[1], 5, 0x2004, 0, d, 150, CO_SDO_MODE_AUTO);
    dl_req(fx, &t[2], 5, 0x2000, 0, d, 1, CO_SDO_MODE_AUTO);
    log_reset(fx);
    start_ok(fx, &t[0]);
    start_ok(fx, &t[1]);
    assert_int_equal(t[0].r.result_channel, 3);
    assert_int_equal(t[1].r.result_channel, 4);
    /* both of server 5's channels are busy */
    assert_int_equal(co_sdo_client_start(&fx->c, &t[2].r), AB_RESOURCE);
    rounds(fx, 3);
    assert_int_equal(co_sdo_server_active(&fx->srv[0]->s), 2);
    settle(fx);
    assert_done(&t[0], 0, false);
    assert_done(&t[1], 0, false);
    assert_memory_equal(mem, fx->srv[0]->dom, n);
    assert_od_bytes(fx->srv[0], 0x2004, d, 150);
    expect_mux(fx, REQ1_5, 0xA4, 0x2009, 0, 127);
    fx->cursor = 0;
    expect_mux(fx, REQ(5), 0x21, 0x2004, 0, 150);
    assert_int_equal(fx->c.stats.rx_idle, 0);
    /* by channel index */
    log_reset(fx);
    t[2].r.server = 0;
    t[2].r.channel = 3;
    start_ok(fx, &t[2]);
    settle(fx);
    assert_done(&t[2], 0, false);
    expect_mux(fx, REQ1_5, 0x2F, 0x2000, 0, d[0]);
    expect_mux(fx, RSP1_5, 0x60, 0x2000, 0, 0);
    /* a channel to no server in particular: only by index */
    assert_true(co_sdo_client_channel_set(&fx->c, 3, 0, REQ1_5, RSP1_5));
    t[2].r.server = 5;
    start_ok(fx, &t[2]);
    assert_int_equal(t[2].r.result_channel, 4);
    settle(fx);
    assert_done(&t[2], 0, false);
    assert_all_idle(fx);
    free(d);
    free(mem);
}

static void test_busy_and_no_free_channel(void **state)
{
    fx_t *fx = *state;
    treq_t t[NCH + 1], u;
    uint8_t mem[NCH + 1][8];
    uint32_t i;
    for (i = 0; i < NCH; i++) {
        ul_req(fx, &t[i], (uint8_t)(X + i), 0x2000, 0, mem[i], 8);
        start_ok(fx, &t[i]);
        assert_int_equal(t[i].r.result_channel, i);
    }
    /* the default channel of X is busy */
    ul_req(fx, &u, X, 0x2001, 0, mem[NCH], 8);
    assert_int_equal(co_sdo_client_start(&fx->c, &u.r), AB_RESOURCE);
    /* no channel free at all */
    ul_req(fx, &t[NCH], X + NCH, 0x2000, 0, mem[NCH], 8);
    assert_int_equal(co_sdo_client_start(&fx->c, &t[NCH].r), AB_RESOURCE);
    assert_int_equal(fx->c.stats.refused, 2);
    assert_int_equal(co_sdo_client_active(&fx->c), NCH);
    for (i = 0; i < NCH; i++)
        assert_true(co_sdo_client_cancel(&fx->c, &t[i].r, 0));
    assert_int_equal(u.done_calls, 0);
    assert_int_equal(t[NCH].done_calls, 0);
    /* the tx queue refuses the first frame: refused, the channel is free */
    {
        uint8_t filler[8] = { 0 };
        settle(fx);
        while (co_line_send(fx->cl, 0x181, filler, 8))
            ;
        assert_int_equal(co_sdo_client_start(&fx->c, &u.r), AB_RESOURCE);
        assert_int_equal(co_sdo_client_active(&fx->c), 0);
        assert_int_equal(u.done_calls, 0);
        settle(fx);
        start_ok(fx, &u);
        assert_true(co_sdo_client_cancel(&fx->c, &u.r, 0));
    }
    settle(fx);
    assert_all_idle(fx);
}

/* ================================================= timeouts, cancel, aborts */

static void test_timeout_silent_server(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t mem[8];
    uint64_t t0 = fx->tb.now;
    log_reset(fx);
    ul_req(fx, &t, X, 0x2000, 0, mem, sizeof mem);
    start_ok(fx, &t);
    run_until(fx, t0 + MS(999));
    assert_int_equal(t.done_calls, 0);
    run_until(fx, t0 + MS(1000));
    assert_done(&t, AB_TIMEOUT, false);
    assert_int_equal(t.done_at, t0 + MS(1000));
    expect_mux(fx, TX_X, 0x40, 0x2000, 0, 0);
    expect_abort(fx, TX_X, 0x2000, 0, AB_TIMEOUT);   /* the abort on the bus */
    expect_none(fx, TX_X);
    /* per request; re-armed by every answer */
    log_reset(fx);
    t0 = fx->tb.now;
    ul_req(fx, &t, X, 0x2009, 0, mem, sizeof mem);
    t.r.timeout_ms = 50;
    start_ok(fx, &t);
    run_until(fx, t0 + MS(40));
    inject_mux(fx, RX_X, 0x41, 0x2009, 0, 8);
    run_until(fx, t0 + MS(89));
    assert_int_equal(t.done_calls, 0);
    run_until(fx, t0 + MS(90));
    assert_done(&t, AB_TIMEOUT, false);
    expect_mux(fx, TX_X, 0x40, 0x2009, 0, 0);
    expect_cmd(fx, TX_X, 0x60);
    expect_abort(fx, TX_X, 0x2009, 0, AB_TIMEOUT);
    assert_int_equal(fx->c.stats.timeouts, 2);
    /* the client's default */
    co_sdo_client_deinit(&fx->c);
    client_start_cfg(fx, NULL, 20, 0);
    t0 = fx->tb.now;
    start_ok(fx, &t);
    t.r.timeout_ms = 0;
    run_until(fx, t0 + MS(100));
    assert_done(&t, AB_TIMEOUT, false);
    assert_int_equal(t.done_at, t0 + MS(50));   /* the request's 50 ms was in force */
    t0 = fx->tb.now;
    start_ok(fx, &t);
    run_until(fx, t0 + MS(100));
    assert_int_equal(t.done_at, t0 + MS(20));
    assert_all_idle(fx);
}

static void test_cancel_mid_block(void **state)
{
    fx_t *fx = *state;
    const uint32_t n = 50000;
    uint8_t *d = malloc(n);
    treq_t t;
    long k;
    assert_non_null(d);
    fill_pattern(d, n, 1);
    set_domain(fx->srv[0], 100, 0);
    dl_req(fx, &t, 5, 0x2009, 0, d, n, CO_SDO_MODE_BLOCK);
    start_ok(fx, &t);
    rounds(fx, 8);   /* initiate and a few sub-blocks */
    assert_int_equal(co_sdo_server_active(&fx->srv[0]->s), 1);
    assert_true(t.r.transferred > 0 && t.r.transferred < n);
    log_reset(fx);
    assert_true(co_sdo_client_cancel(&fx->c, &t.r, AB_HARDWARE));
    assert_false(co_sdo_client_cancel(&fx->c, &t.r, AB_HARDWARE));
    assert_done(&t, AB_HARDWARE, false);
    settle(fx);
    k = tu_log_find_id(&fx->tb, REQ(5), tu_log_count_id(&fx->tb, REQ(5)) - 1);
    {
        uint8_t e[8];
        mux8(e, 0x80, 0x2009, 0, AB_HARDWARE);
        tu_assert_logged(&fx->tb, k, REQ(5), e, 8);
    }
    assert_int_equal(fx->srv[0]->s.stats.rx_client_abort, 1);
    assert_int_equal(fx->srv[0]->dom_aborts, 1);
    assert_int_equal(fx->srv[0]->dom_len, 100);      /* nothing committed */
    assert_int_equal(fx->c.stats.cancelled, 1);
    /* cancel with 0: the general error */
    dl_req(fx, &t, 5, 0x2009, 0, d, n, CO_SDO_MODE_BLOCK);
    start_ok(fx, &t);
    rounds(fx, 4);
    assert_true(co_sdo_client_cancel(&fx->c, &t.r, 0));
    assert_done(&t, AB_GENERAL, false);
    settle(fx);
    assert_all_idle(fx);
    free(d);
}

static void test_server_abort_mid_transfer(void **state)
{
    fx_t *fx = *state;
    const uint32_t n = 5000;
    uint8_t *d = malloc(n);
    uint8_t mem[64];
    treq_t t;
    assert_non_null(d);
    fill_pattern(d, n, 4);
    /* the real server's domain writer refuses after 2000 bytes */
    fx->srv[0]->dom_fail_at = 2000;
    dl_req(fx, &t, 5, 0x2009, 0, d, n, CO_SDO_MODE_BLOCK);
    start_ok(fx, &t);
    settle(fx);
    assert_done(&t, AB_STORE, true);
    assert_true(t.r.transferred < 2000 + 889);
    assert_int_equal(fx->c.stats.aborts_received, 1);
    fx->srv[0]->dom_fail_at = 0;
    /* scripted, mid segmented upload */
    log_reset(fx);
    ul_req(fx, &t, X, 0x2009, 0, mem, sizeof mem);
    start_ok(fx, &t);
    inject_mux(fx, RX_X, 0x41, 0x2009, 0, 20);
    inject_seg(fx, RX_X, 0x00, d, 7);
    inject_mux(fx, RX_X, 0x80, 0x2009, 0, AB_HARDWARE);
    assert_done(&t, AB_HARDWARE, true);
    assert_int_equal(t.r.transferred, 7);
    expect_mux(fx, TX_X, 0x40, 0x2009, 0, 0);
    expect_cmd(fx, TX_X, 0x60);
    expect_cmd(fx, TX_X, 0x70);
    expect_none(fx, TX_X);   /* a server abort is not answered */
    /* code 0 counts as the general error; 0000:00 names any transfer */
    start_ok(fx, &t);
    inject_mux(fx, RX_X, 0x80, 0x0000, 0, 0);
    assert_done(&t, AB_GENERAL, true);
    /* an abort naming another object is a late one: ignored */
    start_ok(fx, &t);
    inject_mux(fx, RX_X, 0x80, 0x2001, 0, AB_TIMEOUT);
    assert_int_equal(fx->c.stats.rx_bad_mux, 1);
    assert_true(co_sdo_client_running(&fx->c, &t.r));
    inject_mux(fx, RX_X, 0x80, 0x2009, 0, AB_TIMEOUT);
    assert_done(&t, AB_TIMEOUT, true);
    /* an abort while idle: ignored */
    {
        uint32_t idle = fx->c.stats.rx_idle;
        inject_mux(fx, RX_X, 0x80, 0x2009, 0, AB_TIMEOUT);
        assert_int_equal(fx->c.stats.rx_idle, idle + 1);
    }
    assert_all_idle(fx);
    free(d);
}

static void test_toggle_errors(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t mem[64], d[20];
    fill_pattern(d, sizeof d, 2);
    /* upload: the first segment with t = 1 */
    log_reset(fx);
    ul_req(fx, &t, X, 0x2009, 0, mem, sizeof mem);
    start_ok(fx, &t);
    inject_mux(fx, RX_X, 0x41, 0x2009, 0, 14);
    inject_seg(fx, RX_X, 0x10, d, 7);
    expect_mux(fx, TX_X, 0x40, 0x2009, 0, 0);
    expect_cmd(fx, TX_X, 0x60);
    expect_abort(fx, TX_X, 0x2009, 0, AB_TOGGLE);
    assert_done(&t, AB_TOGGLE, false);
    assert_int_equal(t.r.transferred, 0);
    /* upload: the second segment repeats t = 0 with other data */
    log_reset(fx);
    start_ok(fx, &t);
    inject_mux(fx, RX_X, 0x41, 0x2009, 0, 21);
    inject_seg(fx, RX_X, 0x00, d, 7);
    inject_seg(fx, RX_X, 0x00, d + 7, 7);
    expect_abort(fx, TX_X, 0x2009, 0, AB_TOGGLE);
    assert_done(&t, AB_TOGGLE, false);
    /* download: the answer to segment t = 0 comes with t = 1 */
    log_reset(fx);
    dl_req(fx, &t, X, 0x2009, 0, d, 20, CO_SDO_MODE_SEGMENTED);
    start_ok(fx, &t);
    inject_mux(fx, RX_X, 0x60, 0x2009, 0, 0);
    inject_seg(fx, RX_X, 0x30, NULL, 0);
    expect_mux(fx, TX_X, 0x21, 0x2009, 0, 20);
    expect_seg(fx, TX_X, 0x00, d, 7);
    expect_abort(fx, TX_X, 0x2009, 0, AB_TOGGLE);
    assert_done(&t, AB_TOGGLE, false);
    assert_int_equal(fx->c.stats.rx_toggle, 3);
    assert_all_idle(fx);
}

static void test_crc_error(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t mem[64], d[14], e[8];
    uint16_t crc;
    fill_pattern(d, sizeof d, 3);
    crc = ref_crc(d, 10);
    log_reset(fx);
    ul_req(fx, &t, X, 0x2009, 0, mem, sizeof mem);
    t.r.mode = CO_SDO_MODE_BLOCK;
    start_ok(fx, &t);
    inject_mux(fx, RX_X, 0xC6, 0x2009, 0, 10);
    inject_seg(fx, RX_X, 0x01, d, 7);
    inject_seg(fx, RX_X, 0x82, d + 7, 7);
    expect_mux(fx, TX_X, 0xA4, 0x2009, 0, 127);
    expect_cmd(fx, TX_X, 0xA3);
    expect_frame(fx, TX_X, (const uint8_t[8]){ 0xA2, 2, 127, 0, 0, 0, 0, 0 });
    memset(e, 0, 8);
    e[0] = 0xD1;
    e[1] = (uint8_t)((crc ^ 1u) & 0xFF);
    e[2] = (uint8_t)(crc >> 8);
    inject(fx, RX_X, e);
    expect_abort(fx, TX_X, 0x2009, 0, AB_CRC);
    expect_none(fx, TX_X);
    assert_done(&t, AB_CRC, false);
    assert_int_equal(t.r.transferred, 7);   /* the last bytes were held back */
    assert_int_equal(fx->c.stats.rx_crc, 1);
    /* without CRC on our side the same CRC is not looked at */
    log_reset(fx);
    ul_req(fx, &t, X, 0x2009, 0, mem, sizeof mem);
    t.r.mode = CO_SDO_MODE_BLOCK;
    t.r.no_crc = true;
    start_ok(fx, &t);
    inject_mux(fx, RX_X, 0xC6, 0x2009, 0, 10);
    inject_seg(fx, RX_X, 0x01, d, 7);
    inject_seg(fx, RX_X, 0x82, d + 7, 7);
    inject(fx, RX_X, e);
    expect_next_cmd(fx, TX_X, (const uint8_t[8]){ 0xA1, 0, 0, 0, 0, 0, 0, 0 });
    assert_done(&t, 0, false);
    assert_memory_equal(mem, d, 10);
    /* the server does not support CRC (sc = 0): not looked at either */
    log_reset(fx);
    ul_req(fx, &t, X, 0x2009, 0, mem, sizeof mem);
    t.r.mode = CO_SDO_MODE_BLOCK;
    start_ok(fx, &t);
    inject_mux(fx, RX_X, 0xC2, 0x2009, 0, 10);
    inject_seg(fx, RX_X, 0x01, d, 7);
    inject_seg(fx, RX_X, 0x82, d + 7, 7);
    inject(fx, RX_X, e);
    assert_done(&t, 0, false);
    assert_false(t.r.crc_used);
    assert_all_idle(fx);
}

static void test_size_mismatch(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t mem[64], d[21];
    fill_pattern(d, sizeof d, 4);
    /* segmented upload: 10 indicated, 14 sent */
    log_reset(fx);
    ul_req(fx, &t, X, 0x2009, 0, mem, sizeof mem);
    start_ok(fx, &t);
    inject_mux(fx, RX_X, 0x41, 0x2009, 0, 10);
    inject_seg(fx, RX_X, 0x00, d, 7);
    inject_seg(fx, RX_X, 0x11, d + 7, 7);
    expect_abort(fx, TX_X, 0x2009, 0, AB_TYPE);
    assert_done(&t, AB_TYPE, false);
    assert_int_equal(t.r.transferred, 7);
    /* ... 20 indicated, 10 sent */
    log_reset(fx);
    start_ok(fx, &t);
    inject_mux(fx, RX_X, 0x41, 0x2009, 0, 20);
    inject_seg(fx, RX_X, 0x00, d, 7);
    inject_seg(fx, RX_X, 0x19, d + 7, 3);
    expect_abort(fx, TX_X, 0x2009, 0, AB_TYPE);
    assert_done(&t, AB_TYPE, false);
    /* ... 5 indicated, a full first segment already too long */
    log_reset(fx);
    start_ok(fx, &t);
    inject_mux(fx, RX_X, 0x41, 0x2009, 0, 5);
    inject_seg(fx, RX_X, 0x00, d, 7);
    expect_abort(fx, TX_X, 0x2009, 0, AB_TYPE);
    assert_done(&t, AB_TYPE, false);
    assert_int_equal(t.r.transferred, 0);
    /* block upload: 10 indicated, the end says 14 */
    log_reset(fx);
    ul_req(fx, &t, X, 0x2009, 0, mem, sizeof mem);
    t.r.mode = CO_SDO_MODE_BLOCK;
    t.r.no_crc = true;
    start_ok(fx, &t);
    inject_mux(fx, RX_X, 0xC6, 0x2009, 0, 10);
    inject_seg(fx, RX_X, 0x01, d, 7);
    inject_seg(fx, RX_X, 0x82, d + 7, 7);
    inject_seg(fx, RX_X, 0xC1, NULL, 0);                 /* n = 0: 7 bytes */
    expect_abort(fx, TX_X, 0x2009, 0, AB_TYPE);
    assert_done(&t, AB_TYPE, false);
    /* block upload: 10 indicated, a third full segment before the last */
    log_reset(fx);
    start_ok(fx, &t);
    inject_mux(fx, RX_X, 0xC6, 0x2009, 0, 10);
    inject_seg(fx, RX_X, 0x01, d, 7);
    inject_seg(fx, RX_X, 0x02, d + 7, 7);
    expect_abort(fx, TX_X, 0x2009, 0, AB_TYPE);
    assert_done(&t, AB_TYPE, false);
    assert_int_equal(fx->c.stats.rx_size_mismatch, 5);
    /* more than the sink holds: its code goes to the server */
    log_reset(fx);
    ul_req(fx, &t, X, 0x2009, 0, mem, 8);
    start_ok(fx, &t);
    inject_mux(fx, RX_X, 0x41, 0x2009, 0, 9);
    expect_abort(fx, TX_X, 0x2009, 0, AB_MEMORY);
    assert_done(&t, AB_MEMORY, false);
    assert_int_equal(fx->c.stats.sink_refused, 1);
    /* against the real server */
    set_domain(fx->srv[0], 1000, 1);
    ul_req(fx, &t, 5, 0x2009, 0, mem, 64);
    start_ok(fx, &t);
    settle(fx);
    assert_done(&t, AB_MEMORY, false);
    assert_int_equal(fx->srv[0]->s.stats.rx_client_abort, 1);
    assert_all_idle(fx);
}

/* Block protocol errors of a server: seqno, block sizes. */
static void test_block_protocol_errors(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t mem[64], d[40];
    fill_pattern(d, sizeof d, 5);
    /* block upload: seqno 0, and above our block size */
    ul_req(fx, &t, X, 0x2009, 0, mem, sizeof mem);
    t.r.mode = CO_SDO_MODE_BLOCK;
    t.r.blksize = 4;
    log_reset(fx);
    start_ok(fx, &t);
    inject_mux(fx, RX_X, 0xC6, 0x2009, 0, 40);
    inject_seg(fx, RX_X, 0x05, d, 7);
    expect_abort(fx, TX_X, 0x2009, 0, AB_SEQNO);
    assert_done(&t, AB_SEQNO, false);
    start_ok(fx, &t);
    inject_mux(fx, RX_X, 0xC6, 0x2009, 0, 40);
    inject_seg(fx, RX_X, 0x00, d, 7);
    assert_done(&t, AB_SEQNO, false);
    /* block download: the server's block size 0 / 128 */
    dl_req(fx, &t, X, 0x2009, 0, d, 40, CO_SDO_MODE_BLOCK);
    log_reset(fx);
    start_ok(fx, &t);
    inject_mux(fx, RX_X, 0xA4, 0x2009, 0, 0);
    expect_abort(fx, TX_X, 0x2009, 0, AB_BLKSIZE);
    assert_done(&t, AB_BLKSIZE, false);
    start_ok(fx, &t);
    inject_mux(fx, RX_X, 0xA4, 0x2009, 0, 128);
    assert_done(&t, AB_BLKSIZE, false);
    /* an ack with block size 0, and one above the segments sent */
    start_ok(fx, &t);
    inject_mux(fx, RX_X, 0xA4, 0x2009, 0, 127);
    inject(fx, RX_X, (const uint8_t[8]){ 0xA2, 6, 0, 0, 0, 0, 0, 0 });
    assert_done(&t, AB_BLKSIZE, false);
    log_reset(fx);
    start_ok(fx, &t);
    inject_mux(fx, RX_X, 0xA4, 0x2009, 0, 127);
    inject(fx, RX_X, (const uint8_t[8]){ 0xA2, 7, 127, 0, 0, 0, 0, 0 });
    expect_abort(fx, TX_X, 0x2009, 0, AB_SEQNO);
    assert_done(&t, AB_SEQNO, false);
    /* a short ack, then the rest, then the end: complete */
    log_reset(fx);
    start_ok(fx, &t);
    inject_mux(fx, RX_X, 0xA4, 0x2009, 0, 127);
    inject(fx, RX_X, (const uint8_t[8]){ 0xA2, 2, 2, 0, 0, 0, 0, 0 });
    inject(fx, RX_X, (const uint8_t[8]){ 0xA2, 2, 2, 0, 0, 0, 0, 0 });   /* same bytes, new ack */
    inject(fx, RX_X, (const uint8_t[8]){ 0xA2, 2, 127, 0, 0, 0, 0, 0 });
    expect_mux(fx, TX_X, 0xC6, 0x2009, 0, 40);
    {
        uint8_t q;
        for (q = 1; q <= 5; q++)
            expect_seg(fx, TX_X, q, d + (q - 1u) * 7u, 7);
    }
    expect_seg(fx, TX_X, 0x86, d + 35, 5);
    expect_seg(fx, TX_X, 0x01, d + 14, 7);               /* after the short ack */
    expect_seg(fx, TX_X, 0x02, d + 21, 7);
    expect_seg(fx, TX_X, 0x01, d + 28, 7);               /* after the second */
    expect_seg(fx, TX_X, 0x82, d + 35, 5);
    {
        uint8_t e[8] = { 0xC9, 0, 0, 0, 0, 0, 0, 0 };   /* n = 2 */
        uint16_t crc = ref_crc(d, 40);
        e[1] = (uint8_t)(crc & 0xFF);
        e[2] = (uint8_t)(crc >> 8);
        expect_frame(fx, TX_X, e);
    }
    inject_seg(fx, RX_X, 0xA1, NULL, 0);
    assert_done(&t, 0, false);
    assert_int_equal(t.r.transferred, 40);
    assert_int_equal(fx->c.stats.block_repeats, 4 + 0);
    assert_all_idle(fx);
}

/* ================================================= ignored frames */

static void test_ignored_frames_are_counted(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t mem[64], d[14];
    co_sdo_client_stats_t s0;
    fill_pattern(d, sizeof d, 6);
    /* a frame for a channel without a transfer */
    inject_mux(fx, RX_X, 0x60, 0x2009, 0, 0);
    inject_mux(fx, RSP(0x7F), 0x60, 0x2009, 0, 0);
    assert_int_equal(fx->c.stats.rx_idle, 2);
    ul_req(fx, &t, X, 0x2009, 0, mem, sizeof mem);
    log_reset(fx);
    start_ok(fx, &t);
    s0 = fx->c.stats;
    /* wrong length, FD (as a driver would never deliver on a classic line) */
    inject_raw(fx, RX_X, 0, (const uint8_t[8]){ 0x41, 0x09, 0x20, 0, 14, 0, 0, 0 }, 7);
    inject_raw(fx, RX_X, 0, (const uint8_t[8]){ 0x41, 0x09, 0x20, 0, 14, 0, 0, 0 }, 0);
    assert_int_equal(fx->c.stats.rx_bad_length, s0.rx_bad_length + 2);
    {
        co_frame_t f = tu_frame(RX_X, CO_FRAME_FD, (const uint8_t[8]){ 0x41, 9, 0x20 }, 8);
        assert_true(co_line_receive(fx->cl, &f));
        settle(fx);
        assert_int_equal(fx->cl->stats.rx_wrong_format, 1);   /* the line drops it */
    }
    /* an answer for another object, a command not expected now */
    inject_mux(fx, RX_X, 0x41, 0x2001, 0, 14);
    inject_mux(fx, RX_X, 0x60, 0x2009, 0, 0);
    inject_seg(fx, RX_X, 0x00, d, 7);
    assert_int_equal(fx->c.stats.rx_bad_mux, s0.rx_bad_mux + 1);
    assert_int_equal(fx->c.stats.rx_unexpected, s0.rx_unexpected + 2);
    assert_true(co_sdo_client_running(&fx->c, &t.r));
    expect_mux(fx, TX_X, 0x40, 0x2009, 0, 0);
    expect_none(fx, TX_X);
    /* the right one, then it again (double reception) */
    inject_mux(fx, RX_X, 0x41, 0x2009, 0, 14);
    inject_mux(fx, RX_X, 0x41, 0x2009, 0, 14);
    assert_int_equal(fx->c.stats.rx_duplicate, s0.rx_duplicate + 1);
    inject_seg(fx, RX_X, 0x00, d, 7);
    inject_seg(fx, RX_X, 0x00, d, 7);
    assert_int_equal(fx->c.stats.rx_duplicate, s0.rx_duplicate + 2);
    inject_seg(fx, RX_X, 0x11, d + 7, 7);
    assert_done(&t, 0, false);
    expect_cmd(fx, TX_X, 0x60);
    expect_cmd(fx, TX_X, 0x70);
    expect_none(fx, TX_X);
    assert_memory_equal(mem, d, 14);
    /* late: the last segment once more, now idle */
    inject_seg(fx, RX_X, 0x11, d + 7, 7);
    assert_int_equal(fx->c.stats.rx_idle, 3);
    assert_all_idle(fx);
}

static void test_unknown_command_aborts(void **state)
{
    fx_t *fx = *state;
    static const uint8_t unknown[] = { 0x81, 0x9F, 0xE0, 0xFF, 0xA3, 0xB7 };
    treq_t t;
    uint8_t mem[8];
    size_t i;
    for (i = 0; i < sizeof unknown; i++) {
        log_reset(fx);
        ul_req(fx, &t, X, 0x2001, 0, mem, sizeof mem);
        start_ok(fx, &t);
        inject_mux(fx, RX_X, unknown[i], 0x2001, 0, 0);
        expect_mux(fx, TX_X, 0x40, 0x2001, 0, 0);
        expect_abort(fx, TX_X, 0x2001, 0, AB_COMMAND);
        assert_done(&t, AB_COMMAND, false);
    }
    assert_int_equal(fx->c.stats.rx_unknown_command, sizeof unknown);
    assert_all_idle(fx);
}

/* ================================================= configuration */

static void test_channel_set_api(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t d[100], mem[8];
    fill_pattern(d, sizeof d, 7);
    assert_false(co_sdo_client_channel_set(NULL, 0, 5, 0, 0));
    assert_false(co_sdo_client_channel_set(&fx->c, NCH, 5, 0, 0));
    assert_false(co_sdo_client_channel_set(&fx->c, 0, 128, 0, 0));
    assert_false(co_sdo_client_channel_set(&fx->c, 0, 0, 0, 0));
    assert_false(co_sdo_client_channel_set(&fx->c, 0, 5, 0x701, 0x6B5));   /* restricted */
    assert_false(co_sdo_client_channel_set(&fx->c, 0, 5, 0x6A5, 0x000));
    assert_false(co_sdo_client_channel_set(&fx->c, 0, 5, 0x6A5, 0x800));
    assert_false(co_sdo_client_channel_set(&fx->c, 0, 5, 0x6A5, 0x6A5));   /* equal */
    assert_false(co_sdo_client_channel_set(&fx->c, 0, 5, 0x585, 0x605));   /* directions */
    assert_true(co_line_subscribe(fx->cl, 0x6C0, 0x6C0, dummy_rx, NULL));
    assert_false(co_sdo_client_channel_set(&fx->c, 0, 5, 0x6A5, 0x6C0));   /* taken */
    co_line_unsubscribe(fx->cl, dummy_rx, NULL);
    assert_int_equal(fx->c.stats.config_refused, 6);
    assert_int_equal(fx->cch[0].kind, CO_SDO_CLIENT_SPARE);
    assert_true(co_sdo_client_channel_set(&fx->c, 0, 5, 0x6A5, 0x6C0));
    assert_true(fx->cch[0].valid);
    assert_true(fx->cch[0].subscribed);
    /* the same CAN-IDs on another channel: refused */
    assert_false(co_sdo_client_channel_set(&fx->c, 1, 6, 0x6A5, 0x6C1));
    assert_false(co_sdo_client_channel_set(&fx->c, 1, 6, 0x6A6, 0x6C0));
    /* again on the same channel: fine; then elsewhere */
    assert_true(co_sdo_client_channel_set(&fx->c, 0, 5, 0x6A5, 0x6C0));
    assert_true(co_sdo_client_channel_set(&fx->c, 0, 5, 0x6A5, 0x6C1));
    assert_int_equal(fx->cl->id_map[0x6C0], 0);
    assert_true(fx->cl->id_map[0x6C1] != 0);
    /* a transfer runs on a spare bound to server 6's default channel; a
     * channel configured with those CAN-IDs takes them: the spare's
     * transfer ends with 0x08000000 (sent) */
    log_reset(fx);
    dl_req(fx, &t, 6, 0x2009, 0, d, 100, CO_SDO_MODE_SEGMENTED);
    start_ok(fx, &t);
    rounds(fx, 3);
    assert_int_equal(t.r.result_channel, 1);
    assert_true(co_sdo_client_channel_set(&fx->c, 2, 6, 0, 0));
    assert_done(&t, AB_GENERAL, false);
    assert_int_equal(fx->c.stats.channel_resets, 1);
    settle(fx);
    {
        long k = tu_log_find_id(&fx->tb, REQ(6), tu_log_count_id(&fx->tb, REQ(6)) - 1);
        uint8_t e[8];
        mux8(e, 0x80, 0x2009, 0, AB_GENERAL);
        tu_assert_logged(&fx->tb, k, REQ(6), e, 8);
    }
    assert_int_equal(fx->cch[1].tx_id, 0);
    /* the configured channel works; clearing it makes it a spare */
    start_ok(fx, &t);
    assert_int_equal(t.r.result_channel, 2);
    settle(fx);
    assert_done(&t, 0, false);
    assert_true(co_sdo_client_channel_clear(&fx->c, 2));
    assert_false(fx->cch[2].valid);
    assert_int_equal(fx->cch[2].kind, CO_SDO_CLIENT_SPARE);
    assert_true(co_sdo_client_channel_clear(&fx->c, 2));   /* twice: harmless */
    assert_false(co_sdo_client_channel_clear(&fx->c, NCH));
    /* a transfer on a channel that is reconfigured ends; the same CAN-IDs
     * again keep it */
    ul_req(fx, &t, X, 0x2000, 0, mem, sizeof mem);
    assert_true(co_sdo_client_channel_set(&fx->c, 5, X, 0, 0));
    start_ok(fx, &t);
    assert_int_equal(t.r.result_channel, 5);
    assert_true(co_sdo_client_channel_set(&fx->c, 5, X, 0, 0));
    assert_true(co_sdo_client_running(&fx->c, &t.r));
    assert_true(co_sdo_client_channel_clear(&fx->c, 5));
    assert_done(&t, AB_GENERAL, false);
    assert_int_equal(fx->c.stats.channel_resets, 2);
    settle(fx);
    assert_all_idle(fx);
}

static const tu_od_row_t client_rows[] = {
    { 0x1280, 0, REC, U8, AC_CONST, 0, 1, 3, NULL, 0, 0 },
    { 0x1280, 1, REC, U32, RW, 0, 4, 0x80000000, NULL, 0, 0 },
    { 0x1280, 2, REC, U32, RW, 0, 4, 0x80000000, NULL, 0, 0 },
    { 0x1280, 3, REC, U8, RW, 0, 1, 0, NULL, 0, 0 },
    { 0x1281, 0, REC, U8, AC_CONST, 0, 1, 3, NULL, 0, 0 },
    { 0x1281, 1, REC, U32, RW, 0, 4, 0x80000000 | REQ1_5, NULL, 0, 0 },
    { 0x1281, 2, REC, U32, RW, 0, 4, 0x80000000 | RSP1_5, NULL, 0, 0 },
    { 0x1281, 3, REC, U8, RW, 0, 1, 5, NULL, 0, 0 },
};

/* Channels from 0x1280 + k: configured at init, re-read on every write,
 * checked on network writes. */
static void test_od_channels(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t d[300], mem[300], v[4];
    fill_pattern(d, sizeof d, 9);
    co_sdo_client_deinit(&fx->c);
    co_od_init(&fx->cod, CO_MODE_CLASSIC, fx->centries, N_ENTRIES, fx->cpool, POOL, fx->csubs,
               SUBS);
    tu_od_add_rows(&fx->cod, client_rows, sizeof client_rows / sizeof client_rows[0]);
    assert_true(co_od_seal(&fx->cod, 0x10));
    assert_true(co_cob_id_attach(&fx->cod));
    client_start_cfg(fx, &fx->cod, 0, 0);
    assert_int_equal(fx->cch[0].kind, CO_SDO_CLIENT_OD);
    assert_int_equal(fx->cch[1].kind, CO_SDO_CLIENT_OD);
    assert_int_equal(fx->cch[2].kind, CO_SDO_CLIENT_SPARE);
    assert_false(fx->cch[0].valid);
    assert_false(fx->cch[1].valid);
    /* OD-bound channels are not the API's */
    assert_false(co_sdo_client_channel_set(&fx->c, 0, 6, 0, 0));
    assert_false(co_sdo_client_channel_clear(&fx->c, 1));
    /* channel 0 to server 6's default channel, written as the network would */
    assert_int_equal(od_net_write(&fx->cod, 0x1280, 3, (const uint8_t *)"\x06", 1), 0);
    assert_int_equal(od_net_write_u32(&fx->cod, 0x1280, 2, RSP(6)), 0);
    assert_false(fx->cch[0].valid);
    assert_int_equal(od_net_write_u32(&fx->cod, 0x1280, 1, REQ(6)), 0);
    assert_true(fx->cch[0].valid);
    assert_int_equal(fx->cch[0].server, 6);
    ul_req(fx, &t, 6, 0x2004, 0, mem, sizeof mem);
    start_ok(fx, &t);
    assert_int_equal(t.r.result_channel, 0);
    settle(fx);
    assert_done(&t, 0, false);
    assert_memory_equal(mem, "hello", 5);
    /* refused values: 29-bit, restricted, node-id, a CAN-ID of another
     * channel, a received CAN-ID another service listens to */
    assert_int_equal(od_net_write_u32(&fx->cod, 0x1281, 1, 0x80000000u | 0x20000000u | 0x6A5),
                     0);   /* invalid: anything goes */
    assert_int_equal(od_net_write_u32(&fx->cod, 0x1281, 1, 0x20000000u | 0x6A5), AB_INVALID);
    assert_int_equal(od_net_write_u32(&fx->cod, 0x1281, 1, 0x701), AB_INVALID);
    assert_int_equal(od_net_write_u32(&fx->cod, 0x1281, 1, 0x585), AB_INVALID);
    assert_int_equal(od_net_write_u32(&fx->cod, 0x1281, 2, 0x605), AB_INVALID);
    assert_int_equal(od_net_write_u32(&fx->cod, 0x1281, 1, REQ(6)), AB_INVALID);
    assert_int_equal(od_net_write_u32(&fx->cod, 0x1281, 2, RSP(6)), AB_INVALID);
    assert_int_equal(od_net_write(&fx->cod, 0x1281, 3, (const uint8_t *)"\x80", 1), AB_INVALID);
    assert_true(co_line_subscribe(fx->cl, 0x6C0, 0x6C0, dummy_rx, NULL));
    assert_int_equal(od_net_write_u32(&fx->cod, 0x1281, 2, 0x6C0), AB_INVALID);
    co_line_unsubscribe(fx->cl, dummy_rx, NULL);
    /* channel 1 to server 5's second channel (0x6A5 / 0x6B5, node 5) */
    enable_server_channel1(fx);
    assert_int_equal(od_net_write_u32(&fx->cod, 0x1281, 1, 0x80000000u | REQ1_5), 0);
    assert_int_equal(od_net_write_u32(&fx->cod, 0x1281, 2, RSP1_5), 0);
    assert_int_equal(od_net_write_u32(&fx->cod, 0x1281, 1, REQ1_5), 0);
    assert_true(fx->cch[1].valid);
    assert_true(fx->cch[1].subscribed);
    /* the COB-ID rule: no CAN-ID change while valid */
    assert_int_equal(od_net_write_u32(&fx->cod, 0x1281, 1, 0x6A7), AB_INVALID);
    log_reset(fx);
    dl_req(fx, &t, 5, 0x2004, 0, d, 100, CO_SDO_MODE_AUTO);
    start_ok(fx, &t);
    assert_int_equal(t.r.result_channel, 1);
    settle(fx);
    assert_done(&t, 0, false);
    assert_od_bytes(fx->srv[0], 0x2004, d, 100);
    expect_mux(fx, REQ1_5, 0x21, 0x2004, 0, 100);
    expect_mux(fx, RSP1_5, 0x60, 0x2004, 0, 0);
    /* invalidated while a transfer runs: it ends, the abort goes out on the
     * old CAN-ID */
    log_reset(fx);
    start_ok(fx, &t);
    rounds(fx, 3);
    tu_le_put(v, 0x80000000u | REQ1_5, 4);
    assert_int_equal(co_od_put(&fx->cod, 0x1281, 1, v, 4), 0);
    assert_done(&t, AB_GENERAL, false);
    assert_false(fx->cch[1].valid);
    assert_false(fx->cch[1].subscribed);
    settle(fx);
    {
        long k = tu_log_find_id(&fx->tb, REQ1_5, tu_log_count_id(&fx->tb, REQ1_5) - 1);
        uint8_t e[8];
        mux8(e, 0x80, 0x2004, 0, AB_GENERAL);
        tu_assert_logged(&fx->tb, k, REQ1_5, e, 8);
    }
    /* the request to 5 now takes 5's default channel on a spare */
    start_ok(fx, &t);
    assert_int_equal(t.r.result_channel, 2);
    settle(fx);
    assert_done(&t, 0, false);
    /* an application put of a 29-bit CAN-ID (no check): not used, counted */
    tu_le_put(v, 0x20000000u | REQ1_5, 4);
    assert_int_equal(co_od_put(&fx->cod, 0x1281, 1, v, 4), 0);
    assert_false(fx->cch[1].valid);
    assert_true(fx->c.stats.config_refused >= 1);
    /* reset communication: the defaults (all off) */
    co_od_load_defaults(&fx->cod, CO_GROUP_COMMUNICATION);
    assert_false(fx->cch[0].valid);
    assert_false(fx->cch[1].valid);
    /* a request by index to an OD channel that is off */
    ul_req(fx, &t, 0, 0x2004, 0, mem, sizeof mem);
    t.r.channel = 0;
    assert_int_equal(co_sdo_client_start(&fx->c, &t.r), AB_GENERAL);
    /* refresh reads the OD again; deinit unhooks it */
    co_sdo_client_refresh(&fx->c);
    co_sdo_client_deinit(&fx->c);
    assert_int_equal(od_net_write_u32(&fx->cod, 0x1281, 2, 0x605), 0);   /* no check any more */
    assert_all_idle(fx);
}

/* ================================================= robustness */

static void random_hook(treq_t *t);

static void random_job_start(fx_t *fx, treq_t *t)
{
    if (co_sdo_client_start(&fx->c, &t->r) == 0)
        t->starts++;
}

/* Results are only checked for sanity: a frame with the right CAN-ID and
 * command is indistinguishable from the server's. Jobs restart from the
 * main loop, in a rotating order (jobs share servers, and a server's
 * default channel carries one transfer at a time). */
static void random_hook(treq_t *t)
{
    assert_true(t->r.abort != 0 || t->r.transferred <= 6000u);
    if (t->r.upload)
        assert_true(t->buf.size <= t->buf.capacity);
}

static void test_random_frames_while_transfers_run(void **state)
{
    static const uint8_t cmds[] = { 0x60, 0x20, 0x30, 0x40, 0x41, 0x43, 0x4F, 0x00, 0x10,
                                    0x01, 0x11, 0x80, 0xA0, 0xA4, 0xA1, 0xA2, 0xC0, 0xC6,
                                    0xC1, 0xD1, 0x81, 0x02, 0x7F, 0xFF };
    static const uint16_t idx[] = { 0x2002, 0x2004, 0x2009, 0x200C };
    fx_t *fx = *state;
    treq_t *jobs = calloc(6, sizeof *jobs);
    uint8_t *src = malloc(6000);
    uint8_t *mem[6];
    unsigned i, j, total_starts = 0, total_done = 0;
    int s;
    assert_non_null(jobs);
    assert_non_null(src);
    fill_pattern(src, 6000, 99);
    for (s = 0; s < NSRV; s++) {
        server_restart(fx->srv[s], 150, 0, false);
        set_domain(fx->srv[s], 500, (uint8_t)s);
    }
    enable_server_channel1(fx);
    co_sdo_client_deinit(&fx->c);
    client_start_cfg(fx, NULL, 100, 0);
    assert_true(co_sdo_client_channel_set(&fx->c, 7, 5, REQ1_5, RSP1_5));
    for (j = 0; j < 6; j++) {
        mem[j] = malloc(600);   /* exactly the sink's capacity: ASan sees overruns */
        assert_non_null(mem[j]);
    }
    dl_req(fx, &jobs[0], 5, 0x2002, 0, src, 4, CO_SDO_MODE_AUTO);
    dl_req(fx, &jobs[1], 6, 0x2004, 0, src, 150, CO_SDO_MODE_AUTO);
    ul_req(fx, &jobs[2], 7, 0x2009, 0, mem[2], 600);
    jobs[2].r.mode = CO_SDO_MODE_BLOCK;
    jobs[2].r.blksize = 10;
    dl_req(fx, &jobs[3], 5, 0x2009, 0, src, 6000, CO_SDO_MODE_AUTO);   /* block */
    ul_req(fx, &jobs[4], 6, 0x200C, 0, mem[4], 600);
    ul_req(fx, &jobs[5], 5, 0x2004, 0, mem[5], 600);   /* "hello" */
    jobs[5].r.mode = CO_SDO_MODE_BLOCK;
    fx->observe = observe_nothing;   /* far more frames than the log holds */
    for (j = 0; j < 6; j++) {
        jobs[j].hook = random_hook;
        random_job_start(fx, &jobs[j]);
    }
    for (i = 0; i < 10000; i++) {
        co_frame_t f;
        uint64_t r = tu_rand(&fx->seed);
        size_t k;
        memset(&f, 0, sizeof f);
        switch (r % 8u) {
        case 0:
            f.id = 0x581u + (uint32_t)((r >> 3) % 127u);
            break;
        case 1:
            f.id = RSP1_5;
            break;
        default:
            f.id = 0x585u + (uint32_t)((r >> 3) % 3u);
            break;
        }
        f.len = ((r >> 8) & 7u) == 0 ? (uint8_t)((r >> 11) % 9u) : 8;
        for (k = 0; k < f.len; k++)
            f.data[k] = (uint8_t)tu_rand(&fx->seed);
        r = tu_rand(&fx->seed);
        if (f.len > 0 && (r & 3u) != 0)
            f.data[0] = cmds[(r >> 2) % sizeof cmds];
        if (f.len > 3 && ((r >> 8) & 3u) != 0) {
            uint16_t x = idx[(r >> 10) % 4u];
            f.data[1] = (uint8_t)x;
            f.data[2] = (uint8_t)(x >> 8);
            f.data[3] = 0;
        }
        if (f.len > 4 && ((r >> 13) & 1u) != 0)
            f.data[4] = (uint8_t)((r >> 14) % 130u);
        (void)co_line_receive(fx->cl, &f);
        if (i % 8 == 7) {
            run_until(fx, fx->tb.now + 300);
            for (j = 0; j < 6; j++) {
                treq_t *job = &jobs[(j + i / 8) % 6];
                if (!co_sdo_client_running(&fx->c, &job->r))
                    random_job_start(fx, job);
            }
        }
    }
    assert_true(fx->c.stats.rx_frames >= 10000);
    /* everything ends by itself (timeouts at the latest) */
    run_ms(fx, 2000);
    fx->observe = NULL;
    for (j = 0; j < 6; j++) {
        assert_true(jobs[j].starts > 1);
        assert_int_equal(jobs[j].done_calls, jobs[j].starts);
        total_starts += jobs[j].starts;
        total_done += jobs[j].done_calls;
    }
    assert_int_equal(fx->c.stats.started, total_starts);
    assert_int_equal(fx->c.stats.completed + fx->c.stats.failed, total_done);
    assert_true(fx->c.stats.completed > 0);
    assert_true(fx->c.stats.failed > 0);
    assert_all_idle(fx);
    /* nothing is wedged: the same transfers now run clean and correct
     * (three of them go to server 5, which has two channels: in turn) */
    log_reset(fx);
    for (j = 0; j < 6; j++) {
        jobs[j].hook = NULL;
        jobs[j].starts = jobs[j].done_calls = 0;
        start_ok(fx, &jobs[j]);
        if (j >= 3)
            settle(fx);
    }
    settle(fx);
    for (j = 0; j < 6; j++)
        assert_done(&jobs[j], 0, false);
    {
        uint32_t v = 0;
        assert_true(co_od_get_u32(&fx->srv[0]->od, 0x2002, 0, &v));
        assert_int_equal(v, (uint32_t)tu_le_get(src, 4));
    }
    assert_od_bytes(fx->srv[1], 0x2004, src, 150);
    assert_int_equal(fx->srv[0]->dom_len, 6000);
    assert_memory_equal(fx->srv[0]->dom, src, 6000);
    assert_int_equal(jobs[2].buf.size, 500);
    assert_memory_equal(mem[2], fx->srv[2]->dom, 500);
    assert_int_equal(jobs[4].buf.size, 500);
    assert_memory_equal(mem[4], fx->srv[1]->dom, 500);
    assert_int_equal(jobs[5].buf.size, 5);
    assert_memory_equal(mem[5], "hello", 5);
    assert_all_idle(fx);
    for (j = 0; j < 6; j++)
        free(mem[j]);
    free(src);
    free(jobs);
}

/* 1 000 transfers of every kind and size, three at a time (one per
 * server), with random frame losses on the bus: every request completes
 * once, the good ones with the right data, and no channel is left taken. */
typedef struct mixed {
    fx_t *fx;
    treq_t t[NSRV];
    bool pending[NSRV];           /* a run started and not yet checked */
    uint8_t *src;
    uint8_t *mem[NSRV];
    unsigned started, ok, failed;
} mixed_t;

static void mixed_next(mixed_t *m, int s)
{
    fx_t *fx = m->fx;
    treq_t *t = &m->t[s];
    uint64_t r;
    uint32_t size;
    uint8_t kind, mode, server = (uint8_t)(5 + s);
    const uint8_t *src;
    if (m->started >= 1000)
        return;
    r = tu_rand(&fx->seed);
    kind = (uint8_t)(r % 6u);
    mode = (uint8_t)((r >> 4) % 4u);
    size = (uint32_t)((r >> 8) % 3000u);
    if ((r >> 20) % 4u == 0)
        size = (uint32_t)((r >> 24) % 9u);
    src = m->src + (r >> 40) % 64u;
    switch (kind) {
    case 0: /* a small value */
        dl_req(fx, t, server, 0x2002, 0, src, 4,
               ((r >> 30) & 1u) ? CO_SDO_MODE_AUTO : CO_SDO_MODE_EXPEDITED);
        break;
    case 1:
    case 2: /* domain download, any mode */
        if (mode == CO_SDO_MODE_EXPEDITED && (size == 0 || size > 4))
            mode = CO_SDO_MODE_AUTO;
        dl_req(fx, t, server, 0x2009, 0, src, size, mode);
        t->r.no_crc = ((r >> 33) & 1u) != 0;
        break;
    case 3: /* string upload */
        ul_req(fx, t, server, 0x2004, 0, m->mem[s], 4000);
        t->r.mode = mode;
        break;
    default: /* domain upload, any mode, block size, pst, CRC or not */
        ul_req(fx, t, server, 0x2009, 0, m->mem[s], 4000);
        t->r.mode = mode;
        t->r.size = size;
        t->r.blksize = (uint8_t)((r >> 34) % 128u);
        t->r.pst = (uint8_t)((r >> 42) % 3u == 0 ? (r >> 45) % 20u : 0);
        t->r.no_crc = ((r >> 50) & 1u) != 0;
        break;
    }
    m->started++;
    m->pending[s] = true;
    start_ok(fx, t);
}

static void mixed_check(mixed_t *m, int s)
{
    treq_t *t = &m->t[s];
    srv_t *srv = m->fx->srv[s];
    m->pending[s] = false;
    assert_int_equal(t->done_calls, 1);
    if (t->r.abort != 0) {
        m->failed++;
        return;
    }
    m->ok++;
    if (t->r.upload && t->r.index == 0x2009) {
        assert_int_equal(t->buf.size, srv->dom_len);
        assert_memory_equal(t->buf.data, srv->dom, srv->dom_len);
    } else if (!t->r.upload && t->r.index == 0x2009) {
        assert_int_equal(srv->dom_len, t->r.size);
        assert_int_equal(t->r.transferred, t->r.size);
        if (t->r.size > 0)
            assert_memory_equal(srv->dom, t->buf.data, t->r.size);
    }
}

static void test_mixed_transfers_no_leak(void **state)
{
    fx_t *fx = *state;
    mixed_t *m = calloc(1, sizeof *m);
    unsigned guard = 0;
    int s;
    assert_non_null(m);
    m->fx = fx;
    m->src = malloc(3100);
    assert_non_null(m->src);
    fill_pattern(m->src, 3100, 21);
    for (s = 0; s < NSRV; s++) {
        m->mem[s] = malloc(4000);
        assert_non_null(m->mem[s]);
        set_domain(fx->srv[s], 100, (uint8_t)s);
        server_restart(fx->srv[s], 0, (uint8_t)(s == 0 ? 127 : s == 1 ? 7 : 33), s == 2);
    }
    fx->observe = observe_nothing;
    fx->fault_rate = 2000;
    for (s = 0; s < NSRV; s++)
        mixed_next(m, s);
    /* done() of these requests only counts; the loop checks finished runs
     * and starts the next ones */
    while (m->pending[0] || m->pending[1] || m->pending[2]) {
        bool progress = false;
        settle(fx);
        for (s = 0; s < NSRV; s++) {
            if (m->pending[s] && m->t[s].done_calls == 1) {
                mixed_check(m, s);
                mixed_next(m, s);
                progress = true;
            }
        }
        if (!progress)   /* a lost frame: on to the next timeout */
            run_until(fx, tu_next_deadline(&fx->tb));
        assert_true(++guard < 200000);
    }
    fx->fault_rate = 0;
    fx->observe = NULL;
    assert_int_equal(m->started, 1000);
    assert_int_equal(m->ok + m->failed, 1000);
    assert_int_equal(fx->c.stats.started, 1000);
    assert_int_equal(fx->c.stats.completed + fx->c.stats.failed, 1000);
    assert_int_equal(fx->c.stats.completed, m->ok);
    assert_true(m->ok > 800);
    assert_true(fx->fault_dropped > 0);
    run_ms(fx, 2000);   /* servers that lost a frame time out */
    assert_all_idle(fx);
    for (s = 0; s < NCH; s++) {
        assert_int_equal(fx->cch[s].state, CO_SDO_CLIENT_FREE);
        assert_int_equal(fx->cch[s].tx_id, 0);
        assert_null(fx->cch[s].req);
        assert_false(co_timer_is_armed(&fx->cch[s].timer));
        assert_false(co_timer_is_armed(&fx->cch[s].pace));
    }
    assert_int_equal(fx->c.waiting, 0);
    for (s = 0; s < NSRV; s++)
        free(m->mem[s]);
    free(m->src);
    free(m);
}

/* ================================================= re-entrancy, deinit */

static void restart_hook(treq_t *t)
{
    if (t->done_calls < 3)
        start_ok(t->fx, t);
}

static void test_done_may_start_new_requests(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t mem[8];
    ul_req(fx, &t, 6, 0x2002, 0, mem, sizeof mem);
    t.hook = restart_hook;
    start_ok(fx, &t);
    settle(fx);
    assert_int_equal(t.done_calls, 3);
    assert_done(&t, 0, false);
    assert_int_equal(tu_le_get(mem, 4), 0x33333306);
    assert_all_idle(fx);
}

static void test_cancel_from_inside_a_sink(void **state)
{
    fx_t *fx = *state;
    const uint32_t n = 3000;
    uint8_t *mem = malloc(n);
    treq_t t;
    int mode;
    assert_non_null(mem);
    set_domain(fx->srv[1], n, 31);
    for (mode = 0; mode < 2; mode++) {
        ul_req(fx, &t, 6, 0x2009, 0, mem, n);
        t.r.mode = mode == 0 ? CO_SDO_MODE_SEGMENTED : CO_SDO_MODE_BLOCK;
        t.cancel_at = 1000;
        start_ok(fx, &t);
        settle(fx);
        assert_done(&t, AB_HARDWARE, false);
        assert_true(t.r.transferred < 1000);
        assert_int_equal(fx->c.stats.cancelled, (uint32_t)mode + 1);
        run_ms(fx, 10);
        assert_all_idle(fx);
    }
    free(mem);
}

static void refused_start_hook(treq_t *t)
{
    assert_int_equal(co_sdo_client_start(&t->fx->c, &t->r), AB_GENERAL);
}

static void test_deinit_ends_open_requests(void **state)
{
    fx_t *fx = *state;
    treq_t t[3];
    uint8_t mem[8];
    static uint8_t data[3000];
    int i;
    assert_true(co_sdo_client_channel_set(&fx->c, 6, X + 1, 0x6A5, 0x6C0));
    ul_req(fx, &t[0], X, 0x2002, 0, mem, sizeof mem);
    dl_req(fx, &t[1], X + 2, 0x2009, 0, data, 3000, CO_SDO_MODE_AUTO);
    ul_req(fx, &t[2], X + 1, 0x2002, 0, mem, sizeof mem);
    for (i = 0; i < 3; i++) {
        t[i].hook = refused_start_hook;   /* a start from done() during deinit is refused */
        start_ok(fx, &t[i]);
    }
    assert_int_equal(t[2].r.result_channel, 6);
    settle(fx);
    log_reset(fx);
    co_sdo_client_deinit(&fx->c);
    for (i = 0; i < 3; i++)
        assert_done(&t[i], AB_GENERAL, false);
    assert_int_equal(co_sdo_client_start(&fx->c, &t[0].r), AB_GENERAL);
    assert_false(co_sdo_client_cancel(&fx->c, &t[0].r, 0));
    assert_false(co_sdo_client_channel_set(&fx->c, 0, 5, 0, 0));
    settle(fx);
    assert_int_equal(fx->tb.log_count, 0);   /* nothing sent */
    assert_int_equal(co_sdo_client_active(&fx->c), 0);
    assert_int_equal(co_timer_list_next(co_line_timers(fx->cl)), CO_TIME_NEVER);
    assert_int_equal(fx->cl->tx_space_count, 0);
    assert_int_equal(fx->cl->receiver_count, 0);
    /* answers now reach nobody; the range is free for a new client */
    inject_mux(fx, RX_X, 0x60, 0x2009, 0, 0);
    assert_int_equal(fx->cl->stats.rx_unhandled, 1);
    co_sdo_client_deinit(&fx->c);   /* twice: harmless */
    co_sdo_client_refresh(&fx->c);
    client_start_cfg(fx, NULL, 0, 0);
    t[0].hook = NULL;
    start_ok(fx, &t[0]);
    assert_true(co_sdo_client_running(&fx->c, &t[0].r));
    assert_true(co_sdo_client_cancel(&fx->c, &t[0].r, 0));
}

/* ================================================= buffers */

static void test_buffer_source_and_sink(void **state)
{
    uint8_t data[10], out[10], mem[6];
    co_sdo_buffer_t src = { data, 10, 0 };
    co_sdo_buffer_t snk = { mem, 0, 6 };
    (void)state;
    fill_pattern(data, 10, 1);
    assert_int_equal(co_sdo_buffer_source(&src, 0, out, 4), 4);
    assert_memory_equal(out, data, 4);
    assert_int_equal(co_sdo_buffer_source(&src, 8, out, 4), 2);
    assert_memory_equal(out, data + 8, 2);
    assert_int_equal(co_sdo_buffer_source(&src, 10, out, 4), 0);
    assert_int_equal(co_sdo_buffer_source(&src, 0xFFFFFFF0u, out, 4), 0);
    assert_int_equal(co_sdo_buffer_sink(&snk, 0, NULL, 0, 7), AB_MEMORY);
    assert_int_equal(co_sdo_buffer_sink(&snk, 0, NULL, 0, 6), 0);
    assert_int_equal(co_sdo_buffer_sink(&snk, 0, NULL, 0, CO_SDO_CLIENT_SIZE_UNKNOWN), 0);
    assert_int_equal(co_sdo_buffer_sink(&snk, 0, data, 4, CO_SDO_CLIENT_SIZE_UNKNOWN), 0);
    assert_int_equal(co_sdo_buffer_sink(&snk, 4, data + 4, 3, CO_SDO_CLIENT_SIZE_UNKNOWN),
                     AB_MEMORY);
    assert_int_equal(co_sdo_buffer_sink(&snk, 4, data + 4, 2, CO_SDO_CLIENT_SIZE_UNKNOWN), 0);
    assert_int_equal(snk.size, 6);
    assert_memory_equal(mem, data, 6);
    assert_int_equal(co_sdo_buffer_sink(&snk, 0xFFFFFFFFu, data, 1, 0), AB_MEMORY);
}

#define T(t) cmocka_unit_test_setup_teardown(t, setup, teardown)

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_buffer_source_and_sink),
        T(test_init_refuses_bad_config),
        T(test_start_refusals),
        T(test_expedited_download_each_size),
        T(test_expedited_upload_each_size),
        T(test_expedited_upload_without_size),
        T(test_segmented_exact_bytes_both_ways),
        T(test_segmented_100k_domain_both_ways),
        T(test_block_download_exact_bytes),
        T(test_block_download_blksizes_crc),
        T(test_block_download_lost_segment_repeated),
        T(test_block_download_burst_per_process_call),
        T(test_block_download_flow_control_and_early_ack),
        T(test_block_upload_exact_bytes),
        T(test_block_upload_blksizes_crc),
        T(test_block_upload_lost_segment_repeated),
        T(test_block_upload_scripted_repeats),
        T(test_block_upload_protocol_switch),
        T(test_auto_mode_choice),
        T(test_block_refused_falls_back),
        T(test_three_servers_at_once),
        T(test_two_channels_to_one_server),
        T(test_busy_and_no_free_channel),
        T(test_timeout_silent_server),
        T(test_cancel_mid_block),
        T(test_server_abort_mid_transfer),
        T(test_toggle_errors),
        T(test_crc_error),
        T(test_size_mismatch),
        T(test_block_protocol_errors),
        T(test_ignored_frames_are_counted),
        T(test_unknown_command_aborts),
        T(test_channel_set_api),
        T(test_od_channels),
        T(test_random_frames_while_transfers_run),
        T(test_mixed_transfers_no_leak),
        T(test_done_may_start_new_requests),
        T(test_cancel_from_inside_a_sink),
        T(test_deinit_ends_open_requests),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
