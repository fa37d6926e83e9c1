/* USDO client (co_usdo_client) over the in-process bus.
 *
 * Client node C (0x10) on line 0; with the "servers" fixture the real
 * co_usdo_server runs on lines 1..3 as nodes 5, 6 and 7, each over its own
 * OD (U8..U64, strings, a domain 0x2009 that stores what it is given, a
 * size-less domain 0x200C, 32 octet strings 0x3000..0x301F). With the
 * "bare" fixture no server runs and the tests answer as scripted node 0x40
 * by putting raw frames into the client's line.
 *
 * Every frame the client puts on the bus is checked whole through the
 * bus sniffer: CAN-ID 0x610, FD + BRS, length rounded up to a valid FD
 * length with zero padding, every byte. Expected bytes are written out by
 * hand from the research notes (§2.4-2.9), not with the codec. */
#include "test_od_util.h"

#include "canopenfd/co_usdo.h"
#include "canopenfd/co_usdo_client.h"
#include "canopenfd/co_usdo_server.h"

#define C 0x10
#define REQ_ID (0x600u + C)
#define X 0x40                    /* scripted server (bare fixture) */
#define NSRV 3
#define MS(x) ((uint64_t)(x) * TU_MS)
#define FDF (CO_FRAME_FD | CO_FRAME_BRS)
#define N_ENTRIES 48
#define POOL 16384
#define SUBS 4
#define NSES 40                   /* server sessions */
#define SCRATCH 1000
#define NCSES 255                 /* client sessions (the fixture uses 40 unless told) */
#define DOM_BIG (1100u * 1024u)   /* server 5's domain: > 1 MiB */
#define DOM_SMALL (128u * 1024u)
#define MAX_ANS 8

#define OS CO_TYPE_OCTET_STRING
#define U64 CO_TYPE_UNSIGNED64
#define DOM CO_TYPE_DOMAIN

/* Command specifiers and abort codes (research notes §2.4, §2.9). */
#define DL_EXP 0x01
#define DL_INIT 0x02
#define DL_SEG 0x03
#define DL_LAST 0x04
#define BULK_INIT 0x06
#define BULK_SEG 0x07
#define BULK_LAST 0x08
#define UL 0x11
#define UL_SEG 0x13
#define DL_EXP_RSP 0x21
#define DL_INIT_RSP 0x22
#define DL_SEG_RSP 0x23
#define DL_LAST_RSP 0x24
#define BULK_INIT_RSP 0x26
#define BULK_LAST_RSP 0x28
#define UL_EXP_RSP 0x31
#define UL_INIT_RSP 0x32
#define UL_SEG_RSP 0x33
#define UL_LAST_RSP 0x34
#define ABORT 0x7F
/* Bulk upload: our layout (docs/protocol-notes.md, "Bulk upload") */
#define BUL_REQ 0x16
#define BUL_ACK 0x17
#define BUL_INIT_RSP 0x36
#define BUL_SEG_RSP 0x37
#define BUL_LAST_RSP 0x38

typedef struct fx fx_t;

/* ------------------------------------------------------------- servers */

typedef struct srv {
    fx_t *fx;
    uint8_t id;
    co_line_t *line;
    co_od_t od;
    co_od_entry_t entries[N_ENTRIES];
    uint8_t pool[POOL];
    co_od_subscription_t subs[SUBS];
    co_usdo_server_t s;
    co_usdo_session_t ses[NSES];
    uint8_t scratch[NSES * SCRATCH];
    bool running;
    /* domain 0x2009 (0x200C: the same data, no size) */
    uint8_t *dom;
    uint32_t dom_cap;
    uint32_t dom_len;
    uint32_t dom_commits;
    uint32_t dom_aborts;
    uint32_t dom_fail_at;         /* the writer refuses data at or beyond this offset (0 = never) */
    /* 0x2002: refuse reads and writes (abort 0x62) */
    bool refuse;
} srv_t;

typedef struct treq treq_t;
typedef void (*treq_hook_fn)(treq_t *t);

/* A request with its bookkeeping. */
struct treq {
    co_usdo_request_t r;
    fx_t *fx;
    co_usdo_buffer_t buf;          /* source or sink */
    unsigned starts;
    unsigned done_calls;
    uint64_t done_at;
    unsigned announces;            /* sink calls with len 0 */
    bool in_run;                   /* announced in this run (reset by done()) */
    uint32_t announced;            /* total of the last announce */
    unsigned n_ans;
    struct {
        uint8_t node, abort, type;
        uint32_t len;
        uint8_t data[56];
    } ans[MAX_ANS];
    treq_hook_fn hook;             /* run from done() */
    int tag;
};

struct fx {
    tu_bus_t tb;
    tu_line_t l[1 + NSRV];
    co_line_t *cl;
    srv_t *srv[NSRV];
    co_usdo_client_t c;
    co_usdo_client_session_t cses[NCSES];
    size_t cursor;                 /* next log entry to look at */
    /* observer of every frame on the bus instead of the log (big transfers) */
    void (*observe)(fx_t *fx, const co_frame_t *f);
    /* fault injection */
    uint8_t (*fault)(fx_t *fx, const co_frame_t *f);
    unsigned fault_seen;
    unsigned fault_nth;            /* which matching frame to hit */
    uint8_t fault_cs;
    bool hold_valid;
    co_frame_t held;
    /* bulk observer */
    const uint8_t *expect_src;
    uint32_t expect_size, expect_off;
    uint8_t expect_counter;
    unsigned bulk_frames;
    bool saw_wrap;
    /* bulk upload observer */
    uint32_t ul_segs;              /* 0x37 / 0x38 seen from the server */
    uint32_t ul_acked;             /* segments our 0x17s acknowledged */
    uint32_t ul_acks;
    uint32_t ul_max_in_flight;
    /* random test */
    bool random_running;
    uint64_t seed;
};

static const tu_od_row_t od_rows[] = {
    { 0x2000, 0, VAR, U8, RW, 0, 1, 0x11, NULL, 0, 0 },
    { 0x2001, 0, VAR, U16, RW, 0, 2, 0x2222, NULL, 0, 0 },
    { 0x2002, 0, VAR, U32, RW, 0, 4, 0x33333333, NULL, 0, 0 },
    { 0x2003, 0, VAR, U64, RW, 0, 8, 0x4444444444444444, NULL, 0, 0 },
    { 0x2004, 0, VAR, VS, RW, 0, 200, 0, "hello", 0, 0 },
    { 0x2005, 0, VAR, OS, RW, 0, 1000, 0, "", 0, 0 },
    { 0x2006, 0, VAR, U32, RO, 0, 4, 0xCAFEF00D, NULL, 0, 0 },
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
    if ((total != CO_OD_SIZE_UNKNOWN && total > s->dom_cap) || offset > s->dom_cap ||
        n > s->dom_cap - offset)
        return CO_ABORT_LENGTH_HIGH;
    if (s->dom_fail_at != 0 && offset + n > s->dom_fail_at)
        return CO_ABORT_DATA_STORE;   /* 0x60 */
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

static uint32_t refuse_read(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e, void *user)
{
    srv_t *s = user;
    (void)od;
    (void)xfer;
    (void)e;
    return s->refuse ? CO_ABORT_DATA_STATE : 0;
}

static uint32_t refuse_write(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e,
                             const uint8_t *value, uint32_t length, void *user)
{
    srv_t *s = user;
    (void)od;
    (void)xfer;
    (void)e;
    (void)value;
    (void)length;
    return s->refuse ? CO_ABORT_DATA_STATE : 0;
}

static const co_od_handler_t refuse_handler = {
    .before_read = refuse_read,
    .check_write = refuse_write,
};

static void server_start(srv_t *s, uint32_t timeout_ms)
{
    co_usdo_server_config_t cfg;
    memset(&cfg, 0, sizeof cfg);
    cfg.sessions = s->ses;
    cfg.session_count = NSES;
    cfg.scratch = s->scratch;
    cfg.scratch_size = SCRATCH;
    cfg.timeout_ms = timeout_ms;
    assert_true(co_usdo_server_init(&s->s, s->line, &s->od, &cfg));
    s->running = true;
}

static void server_build(fx_t *fx, srv_t *s, uint8_t id, co_line_t *line, uint32_t dom_cap)
{
    co_od_def_t d;
    uint16_t i;
    uint8_t v[4];
    s->fx = fx;
    s->id = id;
    s->line = line;
    co_line_set_node_id(line, id);   /* the server reads its node-id from the line */
    s->dom_cap = dom_cap;
    s->dom = calloc(1, dom_cap);
    assert_non_null(s->dom);
    co_od_init(&s->od, CO_MODE_FD, s->entries, N_ENTRIES, s->pool, POOL, s->subs, SUBS);
    tu_od_add_rows(&s->od, od_rows, sizeof od_rows / sizeof od_rows[0]);
    d = tu_od_def(0x2009, 0, VAR, DOM, RW, 0, 0);
    assert_int_equal(co_od_add(&s->od, &d), CO_OD_ADDED);
    d = tu_od_def(0x200C, 0, VAR, DOM, RW, 0, 0);
    assert_int_equal(co_od_add(&s->od, &d), CO_OD_ADDED);
    for (i = 0; i < 32; i++) {
        d = tu_od_def((uint16_t)(0x3000 + i), 0, VAR, OS, RW, 0, 200);
        assert_int_equal(co_od_add(&s->od, &d), CO_OD_ADDED);
    }
    assert_true(co_od_seal(&s->od, id));
    assert_true(co_od_subscribe(&s->od, 0x2009, 0, 0x2009, 0, &dom_handler, s));
    assert_true(co_od_subscribe(&s->od, 0x200C, 0, 0x200C, 0, &dom_nosize_handler, s));
    assert_true(co_od_subscribe(&s->od, 0x2002, 0, 0x2002, 0, &refuse_handler, s));
    tu_le_put(v, 0x33333300u + id, 4);   /* every server its own value */
    assert_int_equal(co_od_put(&s->od, 0x2002, 0, v, 4), 0);
}

static uint8_t membus_fault(const co_frame_t *f, void *user)
{
    fx_t *fx = user;
    return fx->fault != NULL ? fx->fault(fx, f) : 1;
}

static void client_start(fx_t *fx, uint8_t sessions, uint32_t timeout_ms)
{
    co_usdo_client_config_t cfg;
    memset(&cfg, 0, sizeof cfg);
    cfg.sessions = fx->cses;
    cfg.session_count = sessions;
    cfg.node_id = C;
    cfg.timeout_ms = timeout_ms;
    assert_true(co_usdo_client_init(&fx->c, fx->cl, &cfg));
}

static void step(fx_t *fx, uint64_t now);

static int setup_common(void **state, bool servers)
{
    int i;
    fx_t *fx = calloc(1, sizeof *fx);
    if (fx == NULL)
        return -1;
    tu_bus_init(&fx->tb, CO_MODE_FD, true);
    fx->cl = tu_bus_add_line(&fx->tb, &fx->l[0]);
    co_membus_set_fault(&fx->tb.bus, membus_fault, fx);
    for (i = 0; i < NSRV; i++) {
        co_line_t *line = tu_bus_add_line(&fx->tb, &fx->l[1 + i]);
        if (!servers)
            continue;
        fx->srv[i] = calloc(1, sizeof(srv_t));
        assert_non_null(fx->srv[i]);
        server_build(fx, fx->srv[i], (uint8_t)(5 + i), line, i == 0 ? DOM_BIG : DOM_SMALL);
        server_start(fx->srv[i], 0);
    }
    client_start(fx, 40, 0);
    fx->seed = 0x5EED0C11E47ull;
    step(fx, MS(10));
    *state = fx;
    return 0;
}

static int setup(void **state) { return setup_common(state, true); }
static int setup_bare(void **state) { return setup_common(state, false); }

static int teardown(void **state)
{
    fx_t *fx = *state;
    int i;
    for (i = 0; i < NSRV; i++) {
        if (fx->srv[i] != NULL) {
            free(fx->srv[i]->dom);
            free(fx->srv[i]);
        }
    }
    free(fx);
    return 0;
}

/* ------------------------------------------------------------- stepping */

/* tu_step with the sniffer drained into the log, or into fx->observe. */
static void step(fx_t *fx, uint64_t now)
{
    tu_bus_t *tb = &fx->tb;
    long round;
    uint8_t i;
    assert_true(now >= tb->now);
    tb->now = now;
    for (round = 0; round < 100000; round++) {
        uint32_t moved;
        co_frame_t f;
        for (i = 0; i < tb->count; i++)
            (void)co_line_process(&tb->lines[i]->line, now);
        moved = co_membus_transfer(&tb->bus, NULL, NULL);
        if (fx->observe != NULL) {
            while (co_line_rx_pop(&tb->sniffer.line, &f))
                fx->observe(fx, &f);
        } else {
            tu_drain_sniffer(tb);
        }
        if (moved == 0)
            return;
    }
    fail_msg("bus did not become quiet");
}

static void settle(fx_t *fx) { step(fx, fx->tb.now); }

/* Advance to `until`, stopping at every timer deadline on the way. */
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

/* ------------------------------------------------------------- frames */

static void mux(uint8_t *b, uint8_t dest, uint8_t cs, uint8_t sid, uint16_t index, uint8_t sub)
{
    b[0] = dest;
    b[1] = cs;
    b[2] = sid;
    b[3] = sub;
    b[4] = (uint8_t)(index & 0xFF);
    b[5] = (uint8_t)(index >> 8);
}

static void fill_pattern(uint8_t *p, uint32_t n, uint8_t seed)
{
    uint32_t i;
    for (i = 0; i < n; i++)
        p[i] = (uint8_t)(seed + i * 13u + (i >> 8));
}

/* Next client frame in the log (others are skipped), NULL when none. */
static const tu_logged_t *next_req(fx_t *fx)
{
    while (fx->cursor < fx->tb.log_count) {
        const tu_logged_t *l = &fx->tb.log[fx->cursor++];
        if (l->frame.id == REQ_ID)
            return l;
    }
    return NULL;
}

/* The next client frame is exactly these n bytes (FD length, zero padding). */
static const tu_logged_t *expect_req(fx_t *fx, const uint8_t *b, size_t n)
{
    uint8_t padded[64];
    const tu_logged_t *l = next_req(fx);
    if (l == NULL)
        fail_msg("no client frame (expected command 0x%02X)", b[1]);
    memset(padded, 0, sizeof padded);
    memcpy(padded, b, n);
    tu_assert_frame(&l->frame, REQ_ID, FDF, padded, co_fd_len_round(n));
    return l;
}

static void expect_no_req(fx_t *fx)
{
    const tu_logged_t *l = next_req(fx);
    if (l != NULL)
        fail_msg("unexpected client frame, command 0x%02X", l->frame.data[1]);
}

static void expect_req_mux(fx_t *fx, uint8_t dest, uint8_t cs, uint8_t sid, uint16_t index,
                           uint8_t sub)
{
    uint8_t b[6];
    mux(b, dest, cs, sid, index, sub);
    expect_req(fx, b, 6);
}

static void expect_req_abort(fx_t *fx, uint8_t dest, uint8_t sid, uint16_t index, uint8_t sub,
                             uint8_t code)
{
    uint8_t b[7];
    mux(b, dest, ABORT, sid, index, sub);
    b[6] = code;
    expect_req(fx, b, 7);
}

static void expect_req_counter(fx_t *fx, uint8_t dest, uint8_t cs, uint8_t sid, uint8_t counter)
{
    uint8_t b[4] = { dest, cs, sid, counter };
    expect_req(fx, b, 4);
}

/* A frame from server `node` to the client, straight into the client's
 * line (as if from the bus), then the bus settles. */
static void inject_raw(fx_t *fx, uint8_t node, uint8_t flags, const uint8_t *b, uint8_t len)
{
    co_frame_t f = tu_frame(0x580u + node, flags, b, len);
    assert_true(co_line_receive(fx->cl, &f));
    settle(fx);
}

static void inject(fx_t *fx, uint8_t node, const uint8_t *b, size_t n)
{
    uint8_t padded[64];
    memset(padded, 0, sizeof padded);
    memcpy(padded, b, n);
    inject_raw(fx, node, FDF, padded, co_fd_len_round(n));
}

static void inject_mux(fx_t *fx, uint8_t node, uint8_t cs, uint8_t sid, uint16_t index,
                       uint8_t sub)
{
    uint8_t b[6];
    mux(b, C, cs, sid, index, sub);
    inject(fx, node, b, 6);
}

static void inject_abort(fx_t *fx, uint8_t node, uint8_t sid, uint16_t index, uint8_t sub,
                         uint8_t code)
{
    uint8_t b[7];
    mux(b, C, ABORT, sid, index, sub);
    b[6] = code;
    inject(fx, node, b, 7);
}

static void inject_counter(fx_t *fx, uint8_t node, uint8_t cs, uint8_t sid, uint8_t counter)
{
    uint8_t b[4] = { C, cs, sid, counter };
    inject(fx, node, b, 4);
}

static void inject_initiate(fx_t *fx, uint8_t node, uint8_t cs, uint8_t sid, uint16_t index,
                            uint8_t sub, uint8_t type, uint32_t size)
{
    uint8_t b[12];
    mux(b, C, cs, sid, index, sub);
    b[6] = type;
    b[7] = 0;
    tu_le_put(b + 8, size, 4);
    inject(fx, node, b, 12);
}

static void inject_segment(fx_t *fx, uint8_t node, uint8_t sid, uint8_t counter,
                           const uint8_t *data)
{
    uint8_t b[64] = { C, UL_SEG_RSP, sid, counter };
    memcpy(b + 4, data, 60);
    inject(fx, node, b, 64);
}

static void inject_last(fx_t *fx, uint8_t node, uint8_t sid, const uint8_t *data, uint8_t n)
{
    uint8_t b[64] = { C, UL_LAST_RSP, sid, n };
    if (n > 0)
        memcpy(b + 4, data, n);
    inject(fx, node, b, 4u + n);
}

static void inject_bulk_accept(fx_t *fx, uint8_t node, uint8_t sid, uint16_t index, uint8_t sub,
                               uint16_t pacing)
{
    uint8_t b[8];
    mux(b, C, BULK_INIT_RSP, sid, index, sub);
    tu_le_put(b + 6, pacing, 2);
    inject(fx, node, b, 8);
}

/* ------------------------------------------------------------- requests */

static void on_done(co_usdo_request_t *req)
{
    treq_t *t = req->user;
    t->done_calls++;
    t->done_at = t->fx->tb.now;
    t->in_run = false;
    /* the session is already free when done() runs */
    assert_false(co_usdo_client_running(&t->fx->c, req));
    if (t->hook != NULL)
        t->hook(t);
}

static void on_answer(co_usdo_request_t *req, uint8_t node, uint8_t abort, uint8_t type,
                      const uint8_t *data, uint32_t len)
{
    treq_t *t = req->user;
    assert_true(t->n_ans < MAX_ANS);
    assert_true(len <= 56);
    t->ans[t->n_ans].node = node;
    t->ans[t->n_ans].abort = abort;
    t->ans[t->n_ans].type = type;
    t->ans[t->n_ans].len = len;
    if (len > 0)
        memcpy(t->ans[t->n_ans].data, data, len);
    t->n_ans++;
}

/* A sink that counts the announces, then is the buffer sink. */
static uint8_t counting_sink(void *ctx, uint32_t offset, const uint8_t *data, uint32_t len,
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
    }
    return co_usdo_buffer_sink(&t->buf, offset, data, len, total);
}

static void req_base(fx_t *fx, treq_t *t, uint8_t server, uint16_t index, uint8_t sub)
{
    memset(t, 0, sizeof *t);
    t->fx = fx;
    t->r.server = server;
    t->r.index = index;
    t->r.sub = sub;
    t->r.done = on_done;
    t->r.answer = on_answer;
    t->r.user = t;
}

static void dl_req(fx_t *fx, treq_t *t, uint8_t server, uint16_t index, uint8_t sub,
                   uint8_t type, const uint8_t *data, uint32_t size, uint8_t mode)
{
    req_base(fx, t, server, index, sub);
    t->buf.data = (uint8_t *)(uintptr_t)data;
    t->buf.size = size;
    t->r.type = type;
    t->r.size = size;
    t->r.mode = mode;
    t->r.source = co_usdo_buffer_source;
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
    assert_int_equal(co_usdo_client_start(&fx->c, &t->r), 0);
    t->starts++;
}

static void assert_done(const treq_t *t, uint8_t abort, bool from_server)
{
    assert_int_equal(t->done_calls, t->starts);
    assert_int_equal(t->r.abort, abort);
    assert_int_equal(t->r.abort_from_server, from_server);
}

static void assert_all_idle(fx_t *fx)
{
    int i;
    assert_int_equal(co_usdo_client_active(&fx->c), 0);
    for (i = 0; i < NSRV; i++)
        if (fx->srv[i] != NULL && fx->srv[i]->running)
            assert_int_equal(co_usdo_server_active(&fx->srv[i]->s), 0);
}

static uint32_t od_u32(srv_t *s, uint16_t index)
{
    uint32_t v = 0;
    assert_true(co_od_get_u32(&s->od, index, 0, &v));
    return v;
}

static void assert_od_bytes(srv_t *s, uint16_t index, const uint8_t *data, uint32_t n)
{
    uint8_t buf[1000];
    uint32_t len = 0;
    assert_int_equal(co_od_get(&s->od, index, 0, buf, sizeof buf, &len), 0);
    assert_int_equal(len, n);
    if (n > 0)
        assert_memory_equal(buf, data, n);
}

/* ================================================= init and start */

static void dummy_space(co_line_t *line, void *user)
{
    (void)line;
    (void)user;
}

static void test_init_refuses_bad_config(void **state)
{
    fx_t *fx = *state;
    tu_line_t *classic = calloc(1, sizeof *classic);
    co_usdo_client_t c2;
    co_usdo_client_session_t ses[2];
    co_usdo_client_config_t cfg;
    int i, users[CO_LINE_MAX_TX_SPACE];
    assert_non_null(classic);
    memset(&cfg, 0, sizeof cfg);
    cfg.sessions = ses;
    cfg.session_count = 2;
    cfg.node_id = 0x11;
    tu_line_init(classic, CO_MODE_CLASSIC, false);
    assert_false(co_usdo_client_init(&c2, &classic->line, &cfg));
    cfg.node_id = 0;
    assert_false(co_usdo_client_init(&c2, fx->cl, &cfg));
    cfg.node_id = 128;
    assert_false(co_usdo_client_init(&c2, fx->cl, &cfg));
    cfg.node_id = 0x11;
    cfg.session_count = 0;
    assert_false(co_usdo_client_init(&c2, fx->cl, &cfg));
    cfg.session_count = 2;
    cfg.sessions = NULL;
    assert_false(co_usdo_client_init(&c2, fx->cl, &cfg));
    cfg.sessions = ses;
    assert_false(co_usdo_client_init(NULL, fx->cl, &cfg));
    assert_false(co_usdo_client_init(&c2, NULL, &cfg));
    assert_false(co_usdo_client_init(&c2, fx->cl, NULL));
    /* 0x581..0x5FF already taken by the fixture's client */
    assert_false(co_usdo_client_init(&c2, fx->cl, &cfg));
    /* a full tx-space table: refused, and the receive range is left free */
    co_usdo_client_deinit(&fx->c);
    for (i = 0; i < CO_LINE_MAX_TX_SPACE; i++)
        assert_true(co_line_tx_space_register(fx->cl, dummy_space, &users[i]));
    assert_false(co_usdo_client_init(&c2, fx->cl, &cfg));
    for (i = 0; i < CO_LINE_MAX_TX_SPACE; i++)
        co_line_tx_space_unregister(fx->cl, dummy_space, &users[i]);
    assert_true(co_usdo_client_init(&c2, fx->cl, &cfg));
    assert_int_equal(c2.timeout_us, 1000000u);   /* defaults */
    assert_int_equal(c2.max_pacing, 100);
    co_usdo_client_deinit(&c2);
    free(classic);
}

static uint32_t failing_source(void *ctx, uint32_t offset, uint8_t *buf, uint32_t want)
{
    (void)ctx;
    (void)offset;
    (void)buf;
    return want > 0 ? want - 1 : 0;
}

static void test_start_refusals(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t data[100], mem[8];
    fill_pattern(data, sizeof data, 1);

    dl_req(fx, &t, 5, 0x2002, 0, U32, data, 4, CO_USDO_MODE_AUTO);
    t.r.done = NULL;
    assert_int_equal(co_usdo_client_start(&fx->c, &t.r), 0x10);
    assert_int_equal(co_usdo_client_start(&fx->c, NULL), 0x10);
    assert_int_equal(co_usdo_client_start(NULL, &t.r), 0x10);
    dl_req(fx, &t, 128, 0x2002, 0, U32, data, 4, CO_USDO_MODE_AUTO);
    assert_int_equal(co_usdo_client_start(&fx->c, &t.r), 0x10);
    dl_req(fx, &t, C, 0x2002, 0, U32, data, 4, CO_USDO_MODE_AUTO);   /* ourselves */
    assert_int_equal(co_usdo_client_start(&fx->c, &t.r), 0x10);
    dl_req(fx, &t, 5, 0x2002, 0, U32, data, 4, 4);                    /* unknown mode */
    assert_int_equal(co_usdo_client_start(&fx->c, &t.r), 0x10);
    dl_req(fx, &t, 5, 0x2002, 0, U32, data, 4, CO_USDO_MODE_AUTO);
    t.r.source = NULL;
    assert_int_equal(co_usdo_client_start(&fx->c, &t.r), 0x10);
    dl_req(fx, &t, 5, 0x2009, 0, DOM, data, 0xFFFFFFFFu, CO_USDO_MODE_SEGMENTED);
    assert_int_equal(co_usdo_client_start(&fx->c, &t.r), 0x10);
    /* expedited forced with more than 56 bytes */
    dl_req(fx, &t, 5, 0x2005, 0, OS, data, 57, CO_USDO_MODE_EXPEDITED);
    assert_int_equal(co_usdo_client_start(&fx->c, &t.r), 0x1E);
    /* broadcast downloads: expedited only */
    dl_req(fx, &t, 0, 0x2005, 0, OS, data, 57, CO_USDO_MODE_AUTO);
    assert_int_equal(co_usdo_client_start(&fx->c, &t.r), 0x1E);
    dl_req(fx, &t, 0, 0x2005, 0, OS, data, 10, CO_USDO_MODE_SEGMENTED);
    assert_int_equal(co_usdo_client_start(&fx->c, &t.r), 0x10);
    /* a unicast upload needs a sink */
    ul_req(fx, &t, 5, 0x2002, 0, mem, sizeof mem);
    t.r.sink = NULL;
    assert_int_equal(co_usdo_client_start(&fx->c, &t.r), 0x10);
    /* an expedited source that fails: refused, nothing sent */
    dl_req(fx, &t, 5, 0x2002, 0, U32, data, 4, CO_USDO_MODE_AUTO);
    t.r.source = failing_source;
    assert_int_equal(co_usdo_client_start(&fx->c, &t.r), 0x10);
    assert_int_equal(fx->c.stats.source_failed, 1);
    /* already running */
    dl_req(fx, &t, 5, 0x2002, 0, U32, data, 4, CO_USDO_MODE_AUTO);
    start_ok(fx, &t);
    assert_int_equal(co_usdo_client_start(&fx->c, &t.r), 0x10);
    assert_true(co_usdo_client_running(&fx->c, &t.r));
    settle(fx);
    assert_done(&t, 0, false);
    assert_int_equal(t.done_calls, 1);   /* refused starts never call done() */
    assert_int_equal(fx->c.stats.refused, 13);   /* the NULL client is not counted */
    assert_int_equal(fx->c.stats.started, 1);
    /* exactly one frame went out for all of that */
    assert_int_equal(tu_log_count_id(&fx->tb, REQ_ID), 1);
    assert_all_idle(fx);
}

static void test_no_free_session_or_full_queue(void **state)
{
    fx_t *fx = *state;
    treq_t t[41];
    uint8_t data[4] = { 1, 2, 3, 4 };
    int i;
    for (i = 0; i < 40; i++) {
        dl_req(fx, &t[i], X, 0x2002, 0, U32, data, 4, CO_USDO_MODE_AUTO);
        start_ok(fx, &t[i]);
    }
    dl_req(fx, &t[40], X, 0x2002, 0, U32, data, 4, CO_USDO_MODE_AUTO);
    assert_int_equal(co_usdo_client_start(&fx->c, &t[40].r), 0x70);
    assert_int_equal(co_usdo_client_active(&fx->c), 40);
    for (i = 0; i < 40; i++)
        assert_true(co_usdo_client_cancel(&fx->c, &t[i].r, 0));
    assert_int_equal(co_usdo_client_active(&fx->c), 0);
    /* the tx queue full: 0x70, the session is not kept */
    while (co_line_send(fx->cl, 0x123, data, 1))
        ;
    assert_int_equal(co_usdo_client_start(&fx->c, &t[40].r), 0x70);
    assert_int_equal(co_usdo_client_active(&fx->c), 0);
    assert_int_equal(t[40].done_calls, 0);
    settle(fx);
    assert_int_equal(co_usdo_client_start(&fx->c, &t[40].r), 0);
    assert_int_equal(co_usdo_client_active(&fx->c), 1);
}

/* ================================================= expedited */

static void test_expedited_download_exact_bytes(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    const uint8_t v[4] = { 0x78, 0x56, 0x34, 0x12 };
    uint8_t e[12];
    dl_req(fx, &t, 5, 0x2002, 0, U32, v, 4, CO_USDO_MODE_AUTO);
    start_ok(fx, &t);
    assert_int_equal(t.r.session_id, 1);
    settle(fx);
    /* §2.13 example 1 with client 0x10 */
    mux(e, 5, DL_EXP, 1, 0x2002, 0);
    e[6] = 0x07;
    e[7] = 4;
    memcpy(e + 8, v, 4);
    expect_req(fx, e, 12);
    expect_no_req(fx);
    assert_done(&t, 0, false);
    assert_int_equal(t.r.transferred, 4);
    assert_int_equal(t.r.result_mode, CO_USDO_MODE_EXPEDITED);
    assert_int_equal(od_u32(fx->srv[0], 0x2002), 0x12345678u);
    /* the server's answer as the client saw it */
    assert_int_equal(tu_log_count_id(&fx->tb, 0x585), 1);

    /* type 0 goes out as DOMAIN (0x0F), and an empty write is 8 bytes */
    log_reset(fx);
    dl_req(fx, &t, 5, 0x2004, 0, 0, (const uint8_t *)"", 0, CO_USDO_MODE_AUTO);
    start_ok(fx, &t);
    settle(fx);
    mux(e, 5, DL_EXP, 2, 0x2004, 0);
    e[6] = 0x0F;
    e[7] = 0;
    expect_req(fx, e, 8);
    assert_done(&t, 0, false);
    assert_od_bytes(fx->srv[0], 0x2004, NULL, 0);
    assert_int_equal(fx->c.stats.completed, 2);
    assert_all_idle(fx);
}

static void test_expedited_upload_exact_bytes(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t mem[64];
    ul_req(fx, &t, 6, 0x2002, 0, mem, sizeof mem);
    start_ok(fx, &t);
    settle(fx);
    expect_req_mux(fx, 6, UL, 1, 0x2002, 0);
    expect_no_req(fx);
    assert_done(&t, 0, false);
    assert_int_equal(t.r.result_type, 0x07);
    assert_int_equal(t.announces, 1);
    assert_int_equal(t.announced, 4);
    assert_int_equal(t.buf.size, 4);
    assert_int_equal(tu_le_get(mem, 4), 0x33333306u);
    assert_int_equal(t.r.transferred, 4);

    /* 56 bytes: still expedited */
    uint8_t s56[56];
    fill_pattern(s56, 56, 9);
    assert_int_equal(co_od_put(&fx->srv[1]->od, 0x2004, 0, s56, 56), 0);
    ul_req(fx, &t, 6, 0x2004, 0, mem, sizeof mem);
    start_ok(fx, &t);
    settle(fx);
    expect_req_mux(fx, 6, UL, 2, 0x2004, 0);
    assert_done(&t, 0, false);
    assert_int_equal(t.r.result_type, 0x09);
    assert_int_equal(t.buf.size, 56);
    assert_memory_equal(mem, s56, 56);
    assert_all_idle(fx);
}

/* ================================================= segmented */

static void test_segmented_exact_bytes_both_ways(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t data[100], mem[200], e[64];
    fill_pattern(data, 100, 3);
    dl_req(fx, &t, 5, 0x2009, 0, DOM, data, 100, CO_USDO_MODE_AUTO);
    start_ok(fx, &t);
    settle(fx);
    /* §2.13 example 5 with client 0x10, session 1 */
    mux(e, 5, DL_INIT, 1, 0x2009, 0);
    e[6] = 0x0F;
    e[7] = 0;
    tu_le_put(e + 8, 100, 4);
    expect_req(fx, e, 12);
    e[0] = 5;
    e[1] = DL_SEG;
    e[2] = 1;
    e[3] = 0;
    memcpy(e + 4, data, 60);
    expect_req(fx, e, 64);
    e[1] = DL_LAST;
    e[3] = 40;
    memcpy(e + 4, data + 60, 40);
    {
        const tu_logged_t *l = expect_req(fx, e, 44);
        assert_int_equal(l->frame.len, 48);   /* 44 rounded up, zero fill */
    }
    expect_no_req(fx);
    assert_done(&t, 0, false);
    assert_int_equal(t.r.result_mode, CO_USDO_MODE_SEGMENTED);
    assert_int_equal(t.r.transferred, 100);
    assert_int_equal(fx->srv[0]->dom_len, 100);
    assert_memory_equal(fx->srv[0]->dom, data, 100);

    /* back up: 0x11, 0x13 counter 0, 0x13 counter 1 */
    log_reset(fx);
    ul_req(fx, &t, 5, 0x2009, 0, mem, sizeof mem);
    start_ok(fx, &t);
    settle(fx);
    expect_req_mux(fx, 5, UL, 2, 0x2009, 0);
    expect_req_counter(fx, 5, UL_SEG, 2, 0);
    expect_req_counter(fx, 5, UL_SEG, 2, 1);
    expect_no_req(fx);
    assert_done(&t, 0, false);
    assert_int_equal(t.r.result_type, 0x0F);
    assert_int_equal(t.announced, 100);
    assert_int_equal(t.buf.size, 100);
    assert_memory_equal(mem, data, 100);
    assert_all_idle(fx);
}

/* A size that is a multiple of 60 ends with a full 0x04; 0 bytes segmented
 * is 0x02 size 0 and 0x04 n = 0. */
static void test_segmented_boundaries(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t data[120], e[64];
    fill_pattern(data, sizeof data, 5);
    dl_req(fx, &t, 5, 0x2005, 0, OS, data, 120, CO_USDO_MODE_AUTO);
    start_ok(fx, &t);
    settle(fx);
    assert_done(&t, 0, false);
    assert_od_bytes(fx->srv[0], 0x2005, data, 120);
    assert_int_equal(next_req(fx)->frame.data[1], DL_INIT);
    e[0] = 5;
    e[1] = DL_SEG;
    e[2] = 1;
    e[3] = 0;
    memcpy(e + 4, data, 60);
    expect_req(fx, e, 64);
    e[1] = DL_LAST;
    e[3] = 60;   /* a full last segment, never an empty one after it */
    memcpy(e + 4, data + 60, 60);
    expect_req(fx, e, 64);
    expect_no_req(fx);
    log_reset(fx);

    dl_req(fx, &t, 5, 0x2005, 0, OS, data, 0, CO_USDO_MODE_SEGMENTED);
    t.r.source = NULL;   /* nothing to read */
    start_ok(fx, &t);
    settle(fx);
    mux(e, 5, DL_INIT, 2, 0x2005, 0);
    e[6] = OS;
    e[7] = 0;
    tu_le_put(e + 8, 0, 4);
    expect_req(fx, e, 12);
    expect_req(fx, (const uint8_t[]){ 5, DL_LAST, 2, 0 }, 4);
    expect_no_req(fx);
    assert_done(&t, 0, false);
    assert_od_bytes(fx->srv[0], 0x2005, NULL, 0);
    assert_all_idle(fx);
}

static void check_seg_frames(fx_t *fx, uint8_t cs, uint8_t sid, const uint8_t *data,
                             uint32_t size)
{
    /* every 0x03 (or 0x13) frame of the client, counter 0,1,..,0xFF,0,.. */
    uint32_t seen = 0, off = 0;
    uint8_t counter = 0;
    bool wrapped = false;
    size_t i;
    for (i = 0; i < fx->tb.log_count; i++) {
        const co_frame_t *f = &fx->tb.log[i].frame;
        if (f->id != REQ_ID || f->data[1] != cs)
            continue;
        assert_int_equal(f->data[0], 5);
        assert_int_equal(f->data[2], sid);
        assert_int_equal(f->data[3], counter);
        if (cs == DL_SEG) {
            assert_int_equal(f->len, 64);
            assert_memory_equal(f->data + 4, data + off, 60);
            off += 60;
        } else {
            assert_int_equal(f->len, 4);
        }
        if (counter == 0xFF)
            wrapped = true;
        counter = (uint8_t)(counter + 1);
        seen++;
    }
    assert_true(wrapped);
    assert_int_equal(seen, cs == DL_SEG ? (size - 1) / 60 : (size + 59) / 60);
}

static void test_segmented_100k_domain_both_ways(void **state)
{
    fx_t *fx = *state;
    const uint32_t n = 100000;
    uint8_t *data = malloc(n);
    uint8_t *back = malloc(n);
    treq_t t;
    assert_non_null(data);
    assert_non_null(back);
    fill_pattern(data, n, 77);
    dl_req(fx, &t, 5, 0x2009, 0, DOM, data, n, CO_USDO_MODE_SEGMENTED);
    start_ok(fx, &t);
    settle(fx);
    assert_done(&t, 0, false);
    assert_int_equal(t.r.transferred, n);
    assert_int_equal(fx->srv[0]->dom_len, n);
    assert_memory_equal(fx->srv[0]->dom, data, n);
    check_seg_frames(fx, DL_SEG, 1, data, n);

    log_reset(fx);
    ul_req(fx, &t, 5, 0x2009, 0, back, n);   /* a sink of exactly the size */
    start_ok(fx, &t);
    settle(fx);
    assert_done(&t, 0, false);
    assert_int_equal(t.announced, n);
    assert_int_equal(t.buf.size, n);
    assert_int_equal(t.r.transferred, n);
    assert_memory_equal(back, data, n);
    check_seg_frames(fx, UL_SEG, 2, NULL, n);
    assert_all_idle(fx);
    free(data);
    free(back);
}

/* A domain that does not say its size: 0xFFFFFFFF announced, ends at 0x34. */
static void test_segmented_upload_unknown_size(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t *mem = malloc(500);
    assert_non_null(mem);
    fill_pattern(fx->srv[2]->dom, 450, 4);
    fx->srv[2]->dom_len = 450;
    ul_req(fx, &t, 7, 0x200C, 0, mem, 500);
    start_ok(fx, &t);
    settle(fx);
    assert_done(&t, 0, false);
    assert_int_equal(t.announced, 0xFFFFFFFFu);
    assert_int_equal(t.buf.size, 450);
    assert_memory_equal(mem, fx->srv[2]->dom, 450);
    /* the sink too small for what comes: 0x16 at the chunk that does not fit */
    log_reset(fx);
    ul_req(fx, &t, 7, 0x200C, 0, mem, 200);
    start_ok(fx, &t);
    settle(fx);
    assert_done(&t, 0x16, false);
    expect_req_mux(fx, 7, UL, 2, 0x200C, 0);
    expect_req_counter(fx, 7, UL_SEG, 2, 0);
    expect_req_counter(fx, 7, UL_SEG, 2, 1);
    expect_req_counter(fx, 7, UL_SEG, 2, 2);
    expect_req_counter(fx, 7, UL_SEG, 2, 3);
    expect_req_abort(fx, 7, 2, 0x200C, 0, 0x16);
    expect_no_req(fx);
    assert_int_equal(t.buf.size, 180);
    assert_all_idle(fx);
    free(mem);
}

/* ================================================= bulk */

/* Observer of a bulk download: every 0x07 in order with its counter and
 * the source's bytes, then one 0x08 with the rest. */
static void observe_bulk(fx_t *fx, const co_frame_t *f)
{
    if (f->id != REQ_ID)
        return;
    assert_int_equal(f->flags, FDF);
    if (f->data[1] == BULK_SEG) {
        assert_int_equal(f->len, 64);
        assert_int_equal(f->data[3], fx->expect_counter);
        assert_true(fx->expect_size - fx->expect_off > 60);
        assert_memory_equal(f->data + 4, fx->expect_src + fx->expect_off, 60);
        if (fx->expect_counter == 0xFF)
            fx->saw_wrap = true;
        fx->expect_counter = (uint8_t)(fx->expect_counter + 1);
        fx->expect_off += 60;
        fx->bulk_frames++;
    } else if (f->data[1] == BULK_LAST) {
        uint32_t left = fx->expect_size - fx->expect_off;
        assert_int_equal(f->data[3], left);
        assert_memory_equal(f->data + 4, fx->expect_src + fx->expect_off, left);
        fx->expect_off += left;
        fx->bulk_frames++;
    }
}

/* Depends on the server's bulk download (co_usdo_server.c). */
static void test_bulk_download_1mib_real_server(void **state)
{
    fx_t *fx = *state;
    const uint32_t n = 1024u * 1024u + 7u;
    uint8_t *data = malloc(n);
    treq_t t;
    assert_non_null(data);
    fill_pattern(data, n, 11);
    dl_req(fx, &t, 5, 0x2009, 0, DOM, data, n, CO_USDO_MODE_BULK);
    fx->observe = observe_bulk;
    fx->expect_src = data;
    fx->expect_size = n;
    start_ok(fx, &t);
    settle(fx);
    fx->observe = NULL;
    if (t.r.abort == 0x13 && t.r.abort_from_server) {
        free(data);
        print_message("server without bulk download: skipped\n");
        skip();
    }
    assert_done(&t, 0, false);
    assert_int_equal(t.r.result_mode, CO_USDO_MODE_BULK);
    assert_int_equal(t.r.transferred, n);
    assert_int_equal(fx->expect_off, n);
    assert_int_equal(fx->bulk_frames, (n + 59) / 60);
    assert_true(fx->saw_wrap);
    assert_int_equal(fx->srv[0]->dom_len, n);
    assert_memory_equal(fx->srv[0]->dom, data, n);
    /* a quarter of the tx queue always stayed free, and no process call
     * queued more than two bursts (one from the received 0x26, one from
     * the pace timer in the same call) */
    assert_true(fx->cl->tx.high_water <= TU_QUEUE - TU_QUEUE / 4);
    assert_true(fx->cl->tx.high_water <= 2u * CO_USDO_CLIENT_BULK_BURST + 2u);
    assert_int_equal(fx->cl->stats.tx_overflow, 0);
    assert_int_equal(fx->srv[0]->line->stats.rx_overflow, 0);
    assert_all_idle(fx);
    free(data);
}

/* Scripted server: the 0x06 / 0x07 ... / 0x08 bytes, unpaced. */
static void test_bulk_scripted_bytes(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t data[200], e[64];
    fill_pattern(data, sizeof data, 21);
    dl_req(fx, &t, X, 0x2009, 0, DOM, data, 200, CO_USDO_MODE_BULK);
    start_ok(fx, &t);
    settle(fx);
    mux(e, X, BULK_INIT, 1, 0x2009, 0);
    e[6] = 0x0F;
    e[7] = 0;
    tu_le_put(e + 8, 200, 4);
    expect_req(fx, e, 12);
    expect_no_req(fx);
    inject_bulk_accept(fx, X, 1, 0x2009, 0, 0);
    e[0] = X;
    e[1] = BULK_SEG;
    e[2] = 1;
    for (uint8_t k = 0; k < 3; k++) {
        e[3] = k;
        memcpy(e + 4, data + 60u * k, 60);
        expect_req(fx, e, 64);
    }
    e[1] = BULK_LAST;
    e[3] = 20;
    memcpy(e + 4, data + 180, 20);
    expect_req(fx, e, 24);
    expect_no_req(fx);
    assert_int_equal(t.done_calls, 0);
    /* all at the same time: unpaced */
    assert_int_equal(fx->tb.log[fx->cursor - 1].t_us, fx->tb.log[fx->cursor - 4].t_us);
    inject(fx, X, (const uint8_t[]){ C, BULK_LAST_RSP, 1 }, 3);
    assert_done(&t, 0, false);
    assert_int_equal(t.r.pacing, 0);
    assert_int_equal(t.r.transferred, 200);
    assert_all_idle(fx);
}

/* Times of the client's bulk segments (0x07 and 0x08) in the log. */
static size_t bulk_times(const fx_t *fx, uint64_t *at, size_t max)
{
    size_t i, n = 0;
    for (i = 0; i < fx->tb.log_count && n < max; i++) {
        const co_frame_t *f = &fx->tb.log[i].frame;
        if (f->id == REQ_ID && (f->data[1] == BULK_SEG || f->data[1] == BULK_LAST))
            at[n++] = fx->tb.log[i].t_us;
    }
    return n;
}

/* A paced bulk of `segments` full segments to the scripted server; the
 * times of the segments in at[]. `gap_us`: the gap expected after the cap. */
static void bulk_paced(fx_t *fx, uint16_t pacing, uint32_t segments, uint32_t gap_us,
                       uint64_t *at, size_t *n)
{
    treq_t t;
    static uint8_t data[60 * 200];
    uint64_t t0;
    fill_pattern(data, sizeof data, 2);
    log_reset(fx);
    dl_req(fx, &t, X, 0x2009, 0, DOM, data, 60u * segments, CO_USDO_MODE_BULK);
    start_ok(fx, &t);
    settle(fx);
    inject_bulk_accept(fx, X, t.r.session_id, 0x2009, 0, pacing);
    t0 = fx->tb.now;
    run_ms(fx, (uint32_t)((uint64_t)segments * gap_us / 1000u) + 100u);
    *n = bulk_times(fx, at, 200);
    assert_int_equal(*n, segments);
    assert_int_equal(at[0], t0);   /* the first one at once */
    assert_int_equal(t.done_calls, 0);
    assert_int_equal(t.r.pacing, pacing);
    inject(fx, X, (const uint8_t[]){ C, BULK_LAST_RSP, t.r.session_id }, 3);
    assert_done(&t, 0, false);
}

static void test_bulk_scripted_pacing(void **state)
{
    fx_t *fx = *state;
    uint64_t at[200];
    size_t n, i;

    /* 2 ms: one segment every 2 ms */
    bulk_paced(fx, 20, 10, 2000, at, &n);
    for (i = 1; i < n; i++)
        assert_int_equal(at[i] - at[i - 1], 2000);

    /* 300 us (below the 1 ms tick): bursts of 4 every 1.2 ms */
    bulk_paced(fx, 3, 12, 300, at, &n);
    for (i = 0; i < n; i++)
        assert_int_equal(at[i] - at[0], (i / 4) * 1200u);

    /* 100 us: bursts of 10 every 1 ms */
    bulk_paced(fx, 1, 25, 100, at, &n);
    for (i = 0; i < n; i++)
        assert_int_equal(at[i] - at[0], (i / 10) * 1000u);

    /* 50 ms asked, capped at 10 ms (default max_pacing); 150 segments take
     * 1.5 s, longer than the 1 s timeout: sending re-arms it, no timeout */
    bulk_paced(fx, 500, 150, 10000, at, &n);
    for (i = 1; i < n; i++)
        assert_int_equal(at[i] - at[i - 1], 10000);
    assert_int_equal(fx->c.stats.timeouts, 0);
    assert_all_idle(fx);
}

static void test_bulk_max_pacing_configurable(void **state)
{
    fx_t *fx = *state;
    co_usdo_client_config_t cfg;
    uint64_t at[200];
    size_t n, i;
    co_usdo_client_deinit(&fx->c);
    memset(&cfg, 0, sizeof cfg);
    cfg.sessions = fx->cses;
    cfg.session_count = 4;
    cfg.node_id = C;
    cfg.max_pacing = 30;   /* 3 ms */
    assert_true(co_usdo_client_init(&fx->c, fx->cl, &cfg));
    bulk_paced(fx, 500, 5, 3000, at, &n);
    for (i = 1; i < n; i++)
        assert_int_equal(at[i] - at[i - 1], 3000);
}

/* Unpaced bulk with a driver that does not drain: the client stops at 3/4
 * of the tx queue, keeps a quarter for others, does not spin, and resumes
 * when the queue has drained to half. Only the client's line runs here. */
static void test_bulk_flow_control(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    const uint32_t n = 60u * 1000u;
    uint8_t *data = malloc(n);
    uint8_t b[8];
    co_frame_t f;
    uint64_t t0;
    uint32_t i, limit = TU_QUEUE - TU_QUEUE / 4;
    assert_non_null(data);
    fill_pattern(data, n, 8);
    dl_req(fx, &t, X, 0x2009, 0, DOM, data, n, CO_USDO_MODE_BULK);
    start_ok(fx, &t);
    settle(fx);   /* the 0x06 is out */
    t0 = fx->tb.now;
    mux(b, C, BULK_INIT_RSP, 1, 0x2009, 0);
    b[6] = 0;
    b[7] = 0;
    f = tu_frame(0x580u + X, FDF, b, 8);
    assert_true(co_line_receive(fx->cl, &f));
    /* at most two bursts per process call (the 0x26 and the pace timer),
     * until the queue is 3/4 full */
    for (i = 1; co_queue_count(&fx->cl->tx) < limit; i++) {
        uint32_t before = co_queue_count(&fx->cl->tx);
        (void)co_line_process(fx->cl, t0);
        assert_true(co_queue_count(&fx->cl->tx) - before <= 2u * CO_USDO_CLIENT_BULK_BURST);
        assert_true(i < 100);
    }
    assert_int_equal(co_line_process(fx->cl, t0), t0 + MS(1000));
    assert_int_equal(co_queue_count(&fx->cl->tx), limit);
    /* waiting: the next deadline is the timeout, not "now" */
    assert_int_equal(co_line_process(fx->cl, t0 + 10), t0 + MS(1000));
    assert_int_equal(co_queue_count(&fx->cl->tx), limit);
    /* other services still have their quarter */
    for (i = 0; i < TU_QUEUE - limit; i++)
        assert_true(co_line_send(fx->cl, 0x700u + C, (const uint8_t[]){ 5 }, 1));
    assert_false(co_line_send(fx->cl, 0x700u + C, (const uint8_t[]){ 5 }, 1));
    /* drain to just above half: nothing yet */
    while (co_queue_count(&fx->cl->tx) > TU_QUEUE / 2 + 1)
        assert_true(co_line_tx_pop(fx->cl, &f));
    assert_int_equal(co_line_process(fx->cl, t0 + 20), t0 + MS(1000));
    assert_int_equal(co_queue_count(&fx->cl->tx), TU_QUEUE / 2 + 1);
    /* the pop that reaches half: resume at the next process call */
    assert_true(co_line_tx_pop(fx->cl, &f));
    assert_int_equal(co_timer_list_next(co_line_timers(fx->cl)), t0 + 20);
    while (co_queue_count(&fx->cl->tx) < limit)
        (void)co_line_process(fx->cl, t0 + 30);
    assert_int_equal(co_line_process(fx->cl, t0 + 30), t0 + 30 + MS(1000));
    assert_int_equal(co_queue_count(&fx->cl->tx), limit);
    assert_int_equal(fx->c.stats.bulk_paused, 2);
    assert_int_equal(t.r.transferred, 60u * (limit + limit - TU_QUEUE / 2));
    /* no progress for the timeout: 0x12 (the abort finds room in the reserve) */
    (void)co_line_process(fx->cl, t0 + 30 + MS(1000));
    assert_int_equal(t.done_calls, 1);
    assert_int_equal(t.r.abort, 0x12);
    assert_int_equal(co_queue_count(&fx->cl->tx), limit + 1);
    assert_int_equal(fx->c.stats.timeouts, 1);
    assert_int_equal(fx->c.stats.tx_failed, 0);
    assert_int_equal(co_usdo_client_active(&fx->c), 0);
    free(data);
}

static void observe_nothing(fx_t *fx, const co_frame_t *f)
{
    (void)fx;
    (void)f;
}

/* Several unpaced bulk downloads at once share the queue; each gets its
 * turn (none starves), all complete against the real server. Depends on the
 * server's bulk download. */
static void test_bulk_three_servers_at_once(void **state)
{
    fx_t *fx = *state;
    const uint32_t n = 100000;
    uint8_t *data[NSRV];
    treq_t t[NSRV];
    bool no_bulk = false;
    int i;
    for (i = 0; i < NSRV; i++) {
        data[i] = malloc(n);
        assert_non_null(data[i]);
        fill_pattern(data[i], n, (uint8_t)(40 + i));
        dl_req(fx, &t[i], (uint8_t)(5 + i), 0x2009, 0, DOM, data[i], n, CO_USDO_MODE_BULK);
        start_ok(fx, &t[i]);
    }
    fx->observe = observe_nothing;   /* 5000 frames: more than the log holds */
    settle(fx);
    fx->observe = NULL;
    for (i = 0; i < NSRV; i++) {
        if (t[i].r.abort == 0x13 && t[i].r.abort_from_server)
            no_bulk = true;
        else {
            assert_done(&t[i], 0, false);
            assert_int_equal(fx->srv[i]->dom_len, n);
            assert_memory_equal(fx->srv[i]->dom, data[i], n);
        }
    }
    for (i = 0; i < NSRV; i++)
        free(data[i]);
    if (no_bulk)
        skip();
    assert_true(fx->cl->tx.high_water <= TU_QUEUE - TU_QUEUE / 4);
    assert_all_idle(fx);
}

/* ================================================= modes */

static void test_auto_mode_choice(void **state)
{
    fx_t *fx = *state;
    static uint8_t data[5000];
    static const struct {
        uint32_t size;
        uint8_t cs;
        uint8_t mode;
    } cases[] = {
        { 0, DL_EXP, CO_USDO_MODE_EXPEDITED },    { 1, DL_EXP, CO_USDO_MODE_EXPEDITED },
        { 56, DL_EXP, CO_USDO_MODE_EXPEDITED },   { 57, DL_INIT, CO_USDO_MODE_SEGMENTED },
        { 4095, DL_INIT, CO_USDO_MODE_SEGMENTED }, { 4096, BULK_INIT, CO_USDO_MODE_BULK },
        { 5000, BULK_INIT, CO_USDO_MODE_BULK },
    };
    size_t i;
    treq_t t;
    assert_int_equal(co_usdo_client_choose_mode(CO_USDO_MODE_AUTO, 0xFFFFFFFEu),
                     CO_USDO_MODE_BULK);
    assert_int_equal(co_usdo_client_choose_mode(CO_USDO_MODE_SEGMENTED, 5),
                     CO_USDO_MODE_SEGMENTED);
    for (i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        const tu_logged_t *l;
        assert_int_equal(co_usdo_client_choose_mode(CO_USDO_MODE_AUTO, cases[i].size),
                         cases[i].mode);
        log_reset(fx);
        dl_req(fx, &t, X, 0x2009, 0, DOM, data, cases[i].size, CO_USDO_MODE_AUTO);
        start_ok(fx, &t);
        settle(fx);
        assert_int_equal(t.r.result_mode, cases[i].mode);
        l = next_req(fx);
        assert_non_null(l);
        assert_int_equal(l->frame.data[1], cases[i].cs);
        if (cases[i].cs != DL_EXP)
            assert_int_equal(tu_le_get(l->frame.data + 8, 4), cases[i].size);
        else
            assert_int_equal(l->frame.data[7], cases[i].size);
        assert_true(co_usdo_client_cancel(&fx->c, &t.r, 0));
        assert_done(&t, 0x10, false);
        settle(fx);
    }
    assert_int_equal(co_usdo_client_active(&fx->c), 0);
}

static void test_mode_override(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    static uint8_t data[5000];
    fill_pattern(data, sizeof data, 31);
    /* 4 bytes segmented */
    dl_req(fx, &t, 5, 0x2002, 0, U32, data, 4, CO_USDO_MODE_SEGMENTED);
    start_ok(fx, &t);
    settle(fx);
    assert_done(&t, 0, false);
    assert_int_equal(next_req(fx)->frame.data[1], DL_INIT);
    assert_int_equal(next_req(fx)->frame.data[1], DL_LAST);
    assert_int_equal(od_u32(fx->srv[0], 0x2002), (uint32_t)tu_le_get(data, 4));
    /* 5000 bytes segmented instead of bulk */
    log_reset(fx);
    dl_req(fx, &t, 5, 0x2009, 0, DOM, data, 5000, CO_USDO_MODE_SEGMENTED);
    start_ok(fx, &t);
    settle(fx);
    assert_done(&t, 0, false);
    assert_int_equal(next_req(fx)->frame.data[1], DL_INIT);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x585), 1 + 84);   /* every segment answered */
    assert_memory_equal(fx->srv[0]->dom, data, 5000);
    /* 10 bytes expedited forced: fine; bulk forced on 10 bytes: 0x06 then 0x08 */
    log_reset(fx);
    dl_req(fx, &t, 5, 0x2009, 0, DOM, data + 7, 10, CO_USDO_MODE_EXPEDITED);
    start_ok(fx, &t);
    settle(fx);
    assert_done(&t, 0, false);
    assert_int_equal(next_req(fx)->frame.data[1], DL_EXP);
    log_reset(fx);
    dl_req(fx, &t, 5, 0x2009, 0, DOM, data + 9, 10, CO_USDO_MODE_BULK);
    start_ok(fx, &t);
    settle(fx);
    if (t.r.abort == 0x13)
        skip();   /* server without bulk download */
    assert_done(&t, 0, false);
    assert_int_equal(next_req(fx)->frame.data[1], BULK_INIT);
    assert_int_equal(next_req(fx)->frame.data[1], BULK_LAST);
    assert_int_equal(fx->srv[0]->dom_len, 10);
    assert_memory_equal(fx->srv[0]->dom, data + 9, 10);
    assert_all_idle(fx);
}

/* AUTO bulk refused with 0x13 (a server without bulk): once more
 * segmented, with a fresh session-ID. */
static void test_auto_bulk_falls_back_to_segmented(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    static uint8_t data[5000];
    uint8_t e[12];
    fill_pattern(data, sizeof data, 1);
    dl_req(fx, &t, X, 0x2009, 0, DOM, data, 5000, CO_USDO_MODE_AUTO);
    start_ok(fx, &t);
    settle(fx);
    assert_int_equal(next_req(fx)->frame.data[1], BULK_INIT);
    inject_abort(fx, X, 1, 0, 0, 0x13);
    assert_int_equal(t.done_calls, 0);
    assert_int_equal(fx->c.stats.bulk_fallback, 1);
    assert_int_equal(t.r.session_id, 2);
    assert_int_equal(t.r.result_mode, CO_USDO_MODE_SEGMENTED);
    mux(e, X, DL_INIT, 2, 0x2009, 0);
    e[6] = 0x0F;
    e[7] = 0;
    tu_le_put(e + 8, 5000, 4);
    expect_req(fx, e, 12);
    /* a late frame of the first attempt meets no session */
    inject_abort(fx, X, 1, 0, 0, 0x13);
    assert_int_equal(fx->c.stats.rx_no_session, 1);
    inject_mux(fx, X, DL_INIT_RSP, 2, 0x2009, 0);
    assert_int_equal(next_req(fx)->frame.data[1], DL_SEG);
    /* forced bulk does not fall back */
    assert_true(co_usdo_client_cancel(&fx->c, &t.r, 0));
    dl_req(fx, &t, X, 0x2009, 0, DOM, data, 5000, CO_USDO_MODE_BULK);
    start_ok(fx, &t);
    settle(fx);
    inject_abort(fx, X, t.r.session_id, 0, 0, 0x13);
    assert_done(&t, 0x13, true);
    assert_int_equal(fx->c.stats.bulk_fallback, 1);
    assert_all_idle(fx);
}

/* ================================================= bulk upload */

static uint8_t fault_drop(fx_t *fx, const co_frame_t *f);
static void fault_reset(fx_t *fx, uint8_t (*fn)(fx_t *, const co_frame_t *), uint8_t cs,
                        unsigned nth);

/* Drop the nth matching frame and every later one. */
static uint8_t fault_drop_from(fx_t *fx, const co_frame_t *f)
{
    if (f->len > 1 && f->data[1] == fx->fault_cs && fx->fault_seen++ >= fx->fault_nth)
        return 0;
    return 1;
}

static void client_restart(fx_t *fx, uint8_t window)
{
    co_usdo_client_config_t cfg;
    co_usdo_client_deinit(&fx->c);
    memset(&cfg, 0, sizeof cfg);
    cfg.sessions = fx->cses;
    cfg.session_count = 40;
    cfg.node_id = C;
    cfg.bulk_window = window;
    assert_true(co_usdo_client_init(&fx->c, fx->cl, &cfg));
}

static void expect_bul_req(fx_t *fx, uint8_t dest, uint8_t sid, uint16_t index, uint8_t sub,
                           uint8_t window)
{
    uint8_t b[8];
    mux(b, dest, BUL_REQ, sid, index, sub);
    b[6] = window;
    b[7] = 0;
    expect_req(fx, b, 8);
}

static void inject_bul_seg(fx_t *fx, uint8_t node, uint8_t sid, uint8_t counter,
                           const uint8_t *data, uint8_t len)
{
    uint8_t b[64] = { C, BUL_SEG_RSP, sid, counter };
    memcpy(b + 4, data, len);
    inject_raw(fx, node, FDF, b, (uint8_t)(4u + len));
}

static void inject_bul_last(fx_t *fx, uint8_t node, uint8_t sid, const uint8_t *data, uint8_t n)
{
    uint8_t b[64] = { C, BUL_LAST_RSP, sid, n };
    if (n > 0)
        memcpy(b + 4, data, n);
    inject(fx, node, b, 4u + n);
}

/* Every frame of a bulk upload from server 5: its segments in order, our
 * acknowledgements every half window naming the last segment taken, and
 * never more than the window in flight. */
static void observe_bulk_upload(fx_t *fx, const co_frame_t *f)
{
    if (f->id == 0x585u && f->len > 1 &&
        (f->data[1] == BUL_SEG_RSP || f->data[1] == BUL_LAST_RSP)) {
        uint32_t in_flight;
        if (f->data[1] == BUL_SEG_RSP) {
            assert_int_equal(f->len, 64);
            assert_int_equal(f->data[3], (uint8_t)fx->ul_segs);
        }
        fx->ul_segs++;
        in_flight = fx->ul_segs - fx->ul_acked;
        if (in_flight > fx->ul_max_in_flight)
            fx->ul_max_in_flight = in_flight;
    } else if (f->id == REQ_ID && f->len > 1 && f->data[1] == BUL_ACK) {
        assert_int_equal(f->len, 4);    /* 4 bytes: a valid FD length as it is */
        fx->ul_acks++;
        fx->ul_acked = fx->ul_acks * 32u;
        assert_int_equal(f->data[3], (uint8_t)(fx->ul_acked - 1u));
        assert_true(fx->ul_acked <= fx->ul_segs);
    }
}

/* 1 MiB from the real server: every byte, the counter wraps, a window of
 * 64 (a quarter of the 256-frame receive queue) never exceeded on the bus,
 * no receive overflow anywhere. */
static void test_bulk_upload_1mib_real_server(void **state)
{
    fx_t *fx = *state;
    const uint32_t n = 1024u * 1024u + 7u;
    uint8_t *mem = malloc(n);
    treq_t t;
    assert_non_null(mem);
    fill_pattern(fx->srv[0]->dom, n, 23);
    fx->srv[0]->dom_len = n;
    ul_req(fx, &t, 5, 0x2009, 0, mem, n);
    t.r.mode = CO_USDO_MODE_BULK;
    fx->observe = observe_bulk_upload;
    start_ok(fx, &t);
    settle(fx);
    fx->observe = NULL;
    assert_done(&t, 0, false);
    assert_int_equal(t.r.result_mode, CO_USDO_MODE_BULK);
    assert_int_equal(t.r.transferred, n);
    assert_int_equal(t.buf.size, n);
    assert_memory_equal(mem, fx->srv[0]->dom, n);
    assert_int_equal(t.announced, n);
    assert_int_equal(fx->ul_segs, (n + 59) / 60);
    /* every 32 segments, until the credit (a window beyond) covers the rest:
     * none crosses the end */
    {
        uint32_t segs = (n + 59) / 60, k = 0;
        while (32u * (k + 1u) + 32u < segs)
            k++;
        assert_int_equal(fx->ul_acks, k);
    }
    assert_int_equal(fx->srv[0]->s.stats.rx_stray_ack, 0);
    assert_true(fx->ul_max_in_flight <= 64);
    assert_int_equal(fx->c.stats.bulk_uploads, 1);
    assert_int_equal(fx->c.stats.acks_sent, fx->ul_acks);
    assert_int_equal(fx->srv[0]->s.stats.bulk_uploads, 1);
    assert_int_equal(fx->cl->stats.rx_overflow, 0);
    assert_int_equal(fx->srv[0]->line->stats.rx_overflow, 0);
    assert_all_idle(fx);
    free(mem);
}

/* Scripted server, window 4: the exact 0x16 and 0x17 bytes, acknowledgements
 * every 2 segments naming the last one taken, 0x38 ends it. */
static void test_bulk_upload_scripted_bytes(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    static uint8_t data[300], mem[400];
    fill_pattern(data, sizeof data, 5);
    client_restart(fx, 4);
    ul_req(fx, &t, X, 0x2009, 0, mem, sizeof mem);
    t.r.mode = CO_USDO_MODE_BULK;
    start_ok(fx, &t);
    settle(fx);
    expect_bul_req(fx, X, 1, 0x2009, 0, 4);
    expect_no_req(fx);
    inject_initiate(fx, X, BUL_INIT_RSP, 1, 0x2009, 0, DOM, 250);
    expect_no_req(fx);
    assert_int_equal(t.announced, 250);
    inject_bul_seg(fx, X, 1, 0, data, 60);
    expect_no_req(fx);
    inject_bul_seg(fx, X, 1, 1, data + 60, 60);
    expect_req_counter(fx, X, BUL_ACK, 1, 1);
    inject_bul_seg(fx, X, 1, 2, data + 120, 60);
    inject_bul_seg(fx, X, 1, 3, data + 180, 60);
    /* no acknowledgement: the credit (segments 4 and 5) covers the 10 bytes left */
    expect_no_req(fx);
    inject_bul_last(fx, X, 1, data + 240, 10);
    expect_no_req(fx);
    assert_done(&t, 0, false);
    assert_int_equal(t.r.result_mode, CO_USDO_MODE_BULK);
    assert_int_equal(t.r.result_type, DOM);
    assert_int_equal(t.buf.size, 250);
    assert_memory_equal(mem, data, 250);
    /* an empty value: 0x36 size 0, 0x38 n = 0 */
    ul_req(fx, &t, X, 0x2004, 0, mem, sizeof mem);
    t.r.mode = CO_USDO_MODE_BULK;
    start_ok(fx, &t);
    settle(fx);
    expect_bul_req(fx, X, 2, 0x2004, 0, 4);
    inject_initiate(fx, X, BUL_INIT_RSP, 2, 0x2004, 0, 0x09, 0);
    inject_bul_last(fx, X, 2, NULL, 0);
    assert_done(&t, 0, false);
    assert_int_equal(t.buf.size, 0);
    assert_int_equal(fx->c.stats.bulk_uploads, 2);
    assert_all_idle(fx);
}

/* What the client does when a bulk upload goes wrong: a wrong counter
 * (0x14), more data than announced (0x15), a wrong total at the end (0x15),
 * the server silent (0x12), the server's abort; each abort frame checked. */
static void test_bulk_upload_scripted_aborts(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    static uint8_t data[300], mem[400];
    uint8_t sid;
    fill_pattern(data, sizeof data, 6);
    /* a lost segment: counter 1 first */
    ul_req(fx, &t, X, 0x2009, 0, mem, sizeof mem);
    t.r.mode = CO_USDO_MODE_BULK;
    start_ok(fx, &t);
    settle(fx);
    sid = t.r.session_id;
    inject_initiate(fx, X, BUL_INIT_RSP, sid, 0x2009, 0, DOM, 250);
    log_reset(fx);
    inject_bul_seg(fx, X, sid, 1, data, 60);
    expect_req_abort(fx, X, sid, 0x2009, 0, 0x14);
    assert_done(&t, 0x14, false);
    /* more than announced */
    ul_req(fx, &t, X, 0x2009, 0, mem, sizeof mem);
    t.r.mode = CO_USDO_MODE_BULK;
    start_ok(fx, &t);
    settle(fx);
    sid = t.r.session_id;
    inject_initiate(fx, X, BUL_INIT_RSP, sid, 0x2009, 0, DOM, 50);
    log_reset(fx);
    inject_bul_seg(fx, X, sid, 0, data, 60);
    expect_req_abort(fx, X, sid, 0x2009, 0, 0x15);
    assert_done(&t, 0x15, false);
    /* fewer at the end */
    ul_req(fx, &t, X, 0x2009, 0, mem, sizeof mem);
    t.r.mode = CO_USDO_MODE_BULK;
    start_ok(fx, &t);
    settle(fx);
    sid = t.r.session_id;
    inject_initiate(fx, X, BUL_INIT_RSP, sid, 0x2009, 0, DOM, 100);
    inject_bul_seg(fx, X, sid, 0, data, 60);
    log_reset(fx);
    inject_bul_last(fx, X, sid, data + 60, 30);
    expect_req_abort(fx, X, sid, 0x2009, 0, 0x15);
    assert_done(&t, 0x15, false);
    /* the server goes silent after its first segment */
    ul_req(fx, &t, X, 0x2009, 0, mem, sizeof mem);
    t.r.mode = CO_USDO_MODE_BULK;
    t.r.timeout_ms = 200;
    start_ok(fx, &t);
    settle(fx);
    sid = t.r.session_id;
    inject_initiate(fx, X, BUL_INIT_RSP, sid, 0x2009, 0, DOM, 250);
    inject_bul_seg(fx, X, sid, 0, data, 60);
    log_reset(fx);
    run_ms(fx, 199);
    expect_no_req(fx);
    run_ms(fx, 1);
    expect_req_abort(fx, X, sid, 0x2009, 0, 0x12);
    assert_done(&t, 0x12, false);
    /* the server aborts in the middle */
    ul_req(fx, &t, X, 0x2009, 0, mem, sizeof mem);
    t.r.mode = CO_USDO_MODE_BULK;
    start_ok(fx, &t);
    settle(fx);
    sid = t.r.session_id;
    inject_initiate(fx, X, BUL_INIT_RSP, sid, 0x2009, 0, DOM, 250);
    inject_bul_seg(fx, X, sid, 0, data, 60);
    log_reset(fx);
    inject_abort(fx, X, sid, 0x2009, 0, 0x35);
    expect_no_req(fx);
    assert_done(&t, 0x35, true);
    /* a later segment of it meets no session */
    inject_bul_seg(fx, X, sid, 1, data, 60);
    expect_no_req(fx);
    assert_int_equal(fx->c.stats.rx_bad_counter, 1);
    assert_int_equal(fx->c.stats.rx_size_mismatch, 2);
    assert_int_equal(fx->c.stats.timeouts, 1);
    assert_int_equal(fx->c.stats.rx_no_session, 1);
    assert_int_equal(fx->c.bulk_rx, 0);
    assert_all_idle(fx);
}

/* AUTO picks bulk for a size hint of 4 KiB and more; a server without bulk
 * (0x13) gets the plain 0x11 with a fresh session-ID; forced BULK does not
 * fall back; a server may answer 0x16 with 0x31 or 0x32. */
static void test_bulk_upload_auto_and_fallback(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    static uint8_t data[200], mem[5000];
    uint8_t sid;
    fill_pattern(data, sizeof data, 7);
    assert_int_equal(co_usdo_client_choose_upload_mode(CO_USDO_MODE_AUTO, 4095),
                     CO_USDO_MODE_AUTO);
    assert_int_equal(co_usdo_client_choose_upload_mode(CO_USDO_MODE_AUTO, 4096),
                     CO_USDO_MODE_BULK);
    assert_int_equal(co_usdo_client_choose_upload_mode(CO_USDO_MODE_AUTO, 0), CO_USDO_MODE_AUTO);
    assert_int_equal(co_usdo_client_choose_upload_mode(CO_USDO_MODE_BULK, 0), CO_USDO_MODE_BULK);
    /* a small hint: plain */
    ul_req(fx, &t, X, 0x2009, 0, mem, sizeof mem);
    t.r.size = 100;
    start_ok(fx, &t);
    settle(fx);
    expect_req_mux(fx, X, UL, t.r.session_id, 0x2009, 0);
    assert_true(co_usdo_client_cancel(&fx->c, &t.r, 0));
    settle(fx);
    log_reset(fx);
    /* a big one: bulk, refused 0x13, then 0x11 */
    ul_req(fx, &t, X, 0x2009, 0, mem, sizeof mem);
    t.r.size = 5000;
    start_ok(fx, &t);
    settle(fx);
    sid = t.r.session_id;
    expect_bul_req(fx, X, sid, 0x2009, 0, 64);
    inject_abort(fx, X, sid, 0x2009, 0, 0x13);
    assert_int_equal(t.done_calls, 0);
    assert_int_equal(fx->c.stats.bulk_fallback, 1);
    assert_int_equal(t.r.session_id, (uint8_t)(sid + 1u));
    expect_req_mux(fx, X, UL, (uint8_t)(sid + 1u), 0x2009, 0);
    inject_initiate(fx, X, UL_INIT_RSP, (uint8_t)(sid + 1u), 0x2009, 0, DOM, 70);
    expect_req_counter(fx, X, UL_SEG, (uint8_t)(sid + 1u), 0);
    inject_segment(fx, X, (uint8_t)(sid + 1u), 0, data);
    inject_last(fx, X, (uint8_t)(sid + 1u), data + 60, 10);
    assert_done(&t, 0, false);
    assert_int_equal(t.r.result_mode, CO_USDO_MODE_SEGMENTED);
    assert_memory_equal(mem, data, 70);
    /* forced bulk: 0x13 ends it */
    ul_req(fx, &t, X, 0x2009, 0, mem, sizeof mem);
    t.r.mode = CO_USDO_MODE_BULK;
    start_ok(fx, &t);
    settle(fx);
    inject_abort(fx, X, t.r.session_id, 0x2009, 0, 0x13);
    assert_done(&t, 0x13, true);
    assert_int_equal(fx->c.stats.bulk_fallback, 1);
    /* the server answers the bulk request plainly: expedited, then segmented */
    log_reset(fx);
    ul_req(fx, &t, X, 0x2009, 0, mem, sizeof mem);
    t.r.mode = CO_USDO_MODE_BULK;
    start_ok(fx, &t);
    settle(fx);
    sid = t.r.session_id;
    {
        uint8_t b[16];
        mux(b, C, UL_EXP_RSP, sid, 0x2009, 0);
        b[6] = DOM;
        b[7] = 3;
        memcpy(b + 8, data, 3);
        inject(fx, X, b, 11);
    }
    assert_done(&t, 0, false);
    assert_int_equal(t.r.result_mode, CO_USDO_MODE_EXPEDITED);
    assert_int_equal(t.buf.size, 3);
    ul_req(fx, &t, X, 0x2009, 0, mem, sizeof mem);
    t.r.mode = CO_USDO_MODE_BULK;
    start_ok(fx, &t);
    settle(fx);
    sid = t.r.session_id;
    log_reset(fx);
    inject_initiate(fx, X, UL_INIT_RSP, sid, 0x2009, 0, DOM, 10);
    expect_req_counter(fx, X, UL_SEG, sid, 0);
    inject_last(fx, X, sid, data, 10);
    assert_done(&t, 0, false);
    assert_int_equal(t.r.result_mode, CO_USDO_MODE_SEGMENTED);
    /* a broadcast bulk upload is refused */
    ul_req(fx, &t, 0, 0x2009, 0, NULL, 0);
    t.r.mode = CO_USDO_MODE_BULK;
    assert_int_equal(co_usdo_client_start(&fx->c, &t.r), 0x10);
    assert_int_equal(fx->c.bulk_rx, 0);
    assert_all_idle(fx);
}

/* The receive budget: windows of 64 in a 256-frame queue, at most two bulk
 * uploads at once (half the queue); a third AUTO one goes plain, a third
 * forced one is refused 0x70 until one ends. */
static void test_bulk_upload_receive_budget(void **state)
{
    fx_t *fx = *state;
    treq_t t[4];
    static uint8_t mem[4][100];
    int i;
    assert_int_equal(fx->c.bulk_window, 64);
    assert_int_equal(fx->c.bulk_budget, 128);
    for (i = 0; i < 2; i++) {
        ul_req(fx, &t[i], X, (uint16_t)(0x3000 + i), 0, mem[i], 100);
        t[i].r.mode = CO_USDO_MODE_BULK;
        start_ok(fx, &t[i]);
    }
    ul_req(fx, &t[2], X, 0x3002, 0, mem[2], 100);
    t[2].r.mode = CO_USDO_MODE_BULK;
    assert_int_equal(co_usdo_client_start(&fx->c, &t[2].r), 0x70);
    ul_req(fx, &t[3], X, 0x3003, 0, mem[3], 100);
    t[3].r.size = 10000;
    start_ok(fx, &t[3]);
    settle(fx);
    expect_bul_req(fx, X, t[0].r.session_id, 0x3000, 0, 64);
    expect_bul_req(fx, X, t[1].r.session_id, 0x3001, 0, 64);
    expect_req_mux(fx, X, UL, t[3].r.session_id, 0x3003, 0);
    assert_int_equal(fx->c.stats.bulk_budget_full, 2);
    /* one ends (the server answered plainly): room for the next */
    inject_initiate(fx, X, UL_INIT_RSP, t[0].r.session_id, 0x3000, 0, OS, 0);
    inject_last(fx, X, t[0].r.session_id, NULL, 0);
    assert_done(&t[0], 0, false);
    start_ok(fx, &t[2]);
    assert_int_equal(fx->c.bulk_rx, 2);
    for (i = 1; i < 4; i++)
        assert_true(co_usdo_client_cancel(&fx->c, &t[i].r, 0));
    assert_int_equal(fx->c.bulk_rx, 0);
    /* the window follows the receive queue: a window of 200 asked, 64 given */
    client_restart(fx, 200);
    assert_int_equal(fx->c.bulk_window, 64);
    client_restart(fx, 3);
    assert_int_equal(fx->c.bulk_window, 3);
    /* a refused start is never reported, not even when the client ends */
    client_restart(fx, 0);
    for (i = 0; i < 3; i++) {
        ul_req(fx, &t[i], X, (uint16_t)(0x3000 + i), 0, mem[i], 100);
        t[i].r.mode = CO_USDO_MODE_BULK;
    }
    start_ok(fx, &t[0]);
    start_ok(fx, &t[1]);
    assert_int_equal(co_usdo_client_start(&fx->c, &t[2].r), 0x70);
    client_restart(fx, 0);
    assert_int_equal(t[0].done_calls, 1);
    assert_int_equal(t[1].done_calls, 1);
    assert_int_equal(t[2].done_calls, 0);
    assert_int_equal(fx->c.bulk_rx, 0);
    assert_all_idle(fx);
}

/* Lost frames with the real server: a lost segment is a counter error
 * (0x14 to the server, which stops); one lost acknowledgement is made good
 * by the next (they are cumulative); when every acknowledgement from the
 * second on is lost, both wait: the client times out and aborts. */
static void test_bulk_upload_faults_real_server(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t *mem = malloc(20000);
    assert_non_null(mem);
    fill_pattern(fx->srv[0]->dom, 20000, 31);
    fx->srv[0]->dom_len = 20000;
    fault_reset(fx, fault_drop, BUL_SEG_RSP, 40);
    ul_req(fx, &t, 5, 0x2009, 0, mem, 20000);
    t.r.mode = CO_USDO_MODE_BULK;
    start_ok(fx, &t);
    settle(fx);
    assert_done(&t, 0x14, false);
    assert_int_equal(t.r.transferred, 40u * 60u);
    assert_int_equal(fx->srv[0]->s.stats.rx_client_abort, 1);
    assert_all_idle(fx);
    /* the second acknowledgement is lost: the third one covers it */
    fault_reset(fx, fault_drop, BUL_ACK, 1);
    ul_req(fx, &t, 5, 0x2009, 0, mem, 20000);
    t.r.mode = CO_USDO_MODE_BULK;
    start_ok(fx, &t);
    settle(fx);
    assert_done(&t, 0, false);
    assert_memory_equal(mem, fx->srv[0]->dom, 20000);
    /* every acknowledgement from the second on is lost */
    fault_reset(fx, fault_drop_from, BUL_ACK, 1);
    ul_req(fx, &t, 5, 0x2009, 0, mem, 20000);
    t.r.mode = CO_USDO_MODE_BULK;
    t.r.timeout_ms = 300;
    start_ok(fx, &t);
    settle(fx);
    assert_int_equal(t.done_calls, 0);
    run_ms(fx, 300);
    assert_done(&t, 0x12, false);
    assert_int_equal(t.r.transferred, 96u * 60u);   /* the window beyond the first ack */
    assert_int_equal(fx->srv[0]->s.stats.rx_client_abort, 2);
    assert_all_idle(fx);
    fx->fault = NULL;
    /* and then a complete one */
    ul_req(fx, &t, 5, 0x2009, 0, mem, 20000);
    t.r.mode = CO_USDO_MODE_BULK;
    start_ok(fx, &t);
    settle(fx);
    assert_done(&t, 0, false);
    assert_memory_equal(mem, fx->srv[0]->dom, 20000);
    free(mem);
}

/* ================================================= receiving leniently */

/* An empty value: expedited with N = 0 (what our server sends) and
 * segmented with size 0 (what others may send) are both taken. Segments
 * shorter than 64 bytes (a smaller MTU) are taken and counted. */
static void test_empty_values_and_short_segments(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    static uint8_t data[200], mem[300];
    uint8_t b[8];
    uint8_t sid;
    fill_pattern(data, sizeof data, 8);
    ul_req(fx, &t, X, 0x2004, 0, mem, sizeof mem);
    start_ok(fx, &t);
    settle(fx);
    mux(b, C, UL_EXP_RSP, t.r.session_id, 0x2004, 0);
    b[6] = 0x09;
    b[7] = 0;
    inject(fx, X, b, 8);
    assert_done(&t, 0, false);
    assert_int_equal(t.announced, 0);
    assert_int_equal(t.buf.size, 0);
    assert_int_equal(t.r.result_mode, CO_USDO_MODE_EXPEDITED);
    ul_req(fx, &t, X, 0x2004, 0, mem, sizeof mem);
    start_ok(fx, &t);
    settle(fx);
    inject_initiate(fx, X, UL_INIT_RSP, t.r.session_id, 0x2004, 0, 0x09, 0);
    inject_last(fx, X, t.r.session_id, NULL, 0);
    assert_done(&t, 0, false);
    assert_int_equal(t.buf.size, 0);
    /* segmented: 28 + 44 + the last 8 */
    ul_req(fx, &t, X, 0x2009, 0, mem, sizeof mem);
    start_ok(fx, &t);
    settle(fx);
    sid = t.r.session_id;
    inject_initiate(fx, X, UL_INIT_RSP, sid, 0x2009, 0, DOM, 80);
    {
        uint8_t f[64] = { C, UL_SEG_RSP, sid, 0 };
        memcpy(f + 4, data, 28);
        inject_raw(fx, X, FDF, f, 32);
        f[3] = 1;
        memcpy(f + 4, data + 28, 44);
        inject_raw(fx, X, FDF, f, 48);
    }
    log_reset(fx);
    inject_last(fx, X, sid, data + 72, 8);
    assert_done(&t, 0, false);
    assert_memory_equal(mem, data, 80);
    /* bulk: a 20-byte segment carries 16 */
    ul_req(fx, &t, X, 0x2009, 0, mem, sizeof mem);
    t.r.mode = CO_USDO_MODE_BULK;
    start_ok(fx, &t);
    settle(fx);
    sid = t.r.session_id;
    inject_initiate(fx, X, BUL_INIT_RSP, sid, 0x2009, 0, DOM, 26);
    inject_bul_seg(fx, X, sid, 0, data, 16);
    inject_bul_last(fx, X, sid, data + 16, 10);
    assert_done(&t, 0, false);
    assert_memory_equal(mem, data, 26);
    assert_int_equal(fx->c.stats.rx_short_segment, 3);
    /* a segment without data is malformed: 0x1E */
    ul_req(fx, &t, X, 0x2009, 0, mem, sizeof mem);
    start_ok(fx, &t);
    settle(fx);
    sid = t.r.session_id;
    inject_initiate(fx, X, UL_INIT_RSP, sid, 0x2009, 0, DOM, 80);
    log_reset(fx);
    {
        uint8_t f[4] = { C, UL_SEG_RSP, sid, 0 };
        inject_raw(fx, X, FDF, f, 4);
    }
    expect_req_abort(fx, X, sid, 0x2009, 0, 0x1E);
    assert_done(&t, 0x1E, false);
    assert_all_idle(fx);
}

/* ================================================= broadcast */

static void test_broadcast_upload_three_servers(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    int i;
    fx->srv[2]->refuse = true;   /* node 7 answers with an abort (0x62) */
    ul_req(fx, &t, 0, 0x2002, 0, NULL, 0);
    t.r.sink = NULL;
    t.r.timeout_ms = 200;
    start_ok(fx, &t);
    settle(fx);
    expect_req_mux(fx, 0, UL, 1, 0x2002, 0);
    expect_no_req(fx);
    assert_int_equal(t.n_ans, 3);
    assert_int_equal(t.done_calls, 0);   /* collecting until the window ends */
    for (i = 0; i < 3; i++) {
        assert_int_equal(t.ans[i].node, 5 + i);
        if (i < 2) {
            assert_int_equal(t.ans[i].abort, 0);
            assert_int_equal(t.ans[i].type, 0x07);
            assert_int_equal(t.ans[i].len, 4);
            assert_int_equal(tu_le_get(t.ans[i].data, 4), 0x33333300u + 5 + i);
        } else {
            assert_int_equal(t.ans[i].abort, 0x62);
            assert_int_equal(t.ans[i].len, 0);
        }
    }
    run_ms(fx, 199);
    assert_int_equal(t.done_calls, 0);
    run_ms(fx, 1);
    assert_done(&t, 0, false);
    assert_int_equal(t.r.answers, 3);
    assert_int_equal(t.done_at - fx->tb.log[0].t_us, MS(200));
    expect_no_req(fx);   /* the window's end sends nothing */
    assert_all_idle(fx);
}

static void test_broadcast_download_three_servers(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    const uint8_t v[4] = { 0xEF, 0xBE, 0xAD, 0xDE };
    uint8_t e[12];
    fx->srv[1]->refuse = true;
    dl_req(fx, &t, 0, 0x2002, 0, U32, v, 4, CO_USDO_MODE_AUTO);
    t.r.timeout_ms = 50;
    start_ok(fx, &t);
    settle(fx);
    mux(e, 0, DL_EXP, 1, 0x2002, 0);
    e[6] = 0x07;
    e[7] = 4;
    memcpy(e + 8, v, 4);
    expect_req(fx, e, 12);
    run_ms(fx, 50);
    assert_done(&t, 0, false);
    assert_int_equal(t.r.answers, 3);
    assert_int_equal(t.ans[0].node, 5);
    assert_int_equal(t.ans[0].abort, 0);
    assert_int_equal(t.ans[1].node, 6);
    assert_int_equal(t.ans[1].abort, 0x62);
    assert_int_equal(t.ans[2].node, 7);
    assert_int_equal(t.ans[2].abort, 0);
    assert_int_equal(od_u32(fx->srv[0], 0x2002), 0xDEADBEEFu);
    assert_int_equal(od_u32(fx->srv[1], 0x2002), 0x33333306u);
    assert_int_equal(od_u32(fx->srv[2], 0x2002), 0xDEADBEEFu);
    assert_all_idle(fx);
}

/* Scripted answers: a segmented answer is refused with 0x13 (sent to that
 * server, reported), duplicates and wrong commands are ignored. */
static void test_broadcast_scripted_answers(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t e[64];
    ul_req(fx, &t, 0, 0x2004, 0, NULL, 0);
    t.r.sink = NULL;
    t.r.timeout_ms = 100;
    start_ok(fx, &t);
    settle(fx);
    expect_req_mux(fx, 0, UL, 1, 0x2004, 0);
    mux(e, C, UL_EXP_RSP, 1, 0x2004, 0);
    e[6] = 0x09;
    e[7] = 2;
    e[8] = 'h';
    e[9] = 'i';
    inject(fx, 0x41, e, 10);
    inject(fx, 0x41, e, 10);                                   /* duplicate */
    assert_int_equal(fx->c.stats.rx_duplicate, 1);
    inject_initiate(fx, 0x42, UL_INIT_RSP, 1, 0x2004, 0, 0x09, 100);
    expect_req_abort(fx, 0x42, 1, 0x2004, 0, 0x13);
    inject_abort(fx, 0x43, 1, 0x2004, 0, 0x33);
    inject_counter(fx, 0x44, UL_SEG_RSP, 1, 0);                /* wrong command: ignored */
    assert_int_equal(fx->c.stats.rx_unexpected, 1);
    inject_mux(fx, 0x45, UL_EXP_RSP, 1, 0x2004, 0);            /* too short: 0x1E */
    mux(e, C, UL_EXP_RSP, 1, 0x2005, 0);                       /* other index: 0x1F */
    e[6] = 0x09;
    e[7] = 0;
    inject(fx, 0x46, e, 8);
    inject_abort(fx, 0x47, 1, 0x2004, 0, 0);                   /* code 0: 0x10 */
    expect_no_req(fx);
    assert_int_equal(t.n_ans, 6);
    assert_int_equal(t.ans[0].node, 0x41);
    assert_int_equal(t.ans[0].abort, 0);
    assert_int_equal(t.ans[0].len, 2);
    assert_memory_equal(t.ans[0].data, "hi", 2);
    assert_int_equal(t.ans[1].node, 0x42);
    assert_int_equal(t.ans[1].abort, 0x13);
    assert_int_equal(t.ans[2].node, 0x43);
    assert_int_equal(t.ans[2].abort, 0x33);
    assert_int_equal(t.ans[3].node, 0x45);
    assert_int_equal(t.ans[3].abort, 0x1E);
    assert_int_equal(t.ans[4].node, 0x46);
    assert_int_equal(t.ans[4].abort, 0x1F);
    assert_int_equal(t.ans[5].node, 0x47);
    assert_int_equal(t.ans[5].abort, 0x10);
    run_ms(fx, 100);
    assert_done(&t, 0, false);
    assert_int_equal(t.r.answers, 6);
    /* after the window: late answers meet no session */
    inject(fx, 0x48, e, 8);
    assert_int_equal(fx->c.stats.rx_no_session, 1);
    /* cancel of a broadcast: the abort goes to all */
    log_reset(fx);
    start_ok(fx, &t);
    settle(fx);
    assert_true(co_usdo_client_cancel(&fx->c, &t.r, 0x12));
    settle(fx);
    expect_req_mux(fx, 0, UL, 2, 0x2004, 0);
    expect_req_abort(fx, 0, 2, 0x2004, 0, 0x12);
    assert_done(&t, 0x12, false);
    assert_all_idle(fx);
}

/* ================================================= concurrency */

typedef struct job {
    treq_t t;
    uint8_t data[200];
    uint8_t back[200];
} job_t;

static void run_jobs(fx_t *fx, const uint8_t *servers, size_t nservers)
{
    job_t *jobs = calloc(32, sizeof *jobs);
    int i;
    assert_non_null(jobs);
    for (i = 0; i < 32; i++) {
        job_t *j = &jobs[i];
        uint8_t node = servers[(size_t)i % nservers];
        srv_t *s = fx->srv[node - 5];
        uint16_t index = (uint16_t)(0x3000 + i);
        uint32_t len = 1u + (uint32_t)(i * 37) % 199u;   /* expedited and segmented sizes */
        fill_pattern(j->data, len, (uint8_t)i);
        if (i % 2 == 0) {
            dl_req(fx, &j->t, node, index, 0, OS, j->data, len, CO_USDO_MODE_AUTO);
        } else {
            assert_int_equal(co_od_put(&s->od, index, 0, j->data, len), 0);
            ul_req(fx, &j->t, node, index, 0, j->back, sizeof j->back);
        }
        j->t.tag = (int)len;
        start_ok(fx, &j->t);
    }
    assert_int_equal(co_usdo_client_active(&fx->c), 32);
    settle(fx);
    for (i = 0; i < 32; i++) {
        job_t *j = &jobs[i];
        srv_t *s = fx->srv[j->t.r.server - 5];
        uint32_t len = (uint32_t)j->t.tag;
        assert_done(&j->t, 0, false);
        assert_int_equal(j->t.r.session_id, i + 1 + (fx->c.stats.started - 32));
        if (i % 2 == 0) {
            assert_od_bytes(s, j->t.r.index, j->data, len);
        } else {
            assert_int_equal(j->t.buf.size, len);
            assert_memory_equal(j->back, j->data, len);
        }
    }
    assert_int_equal(fx->c.stats.completed, fx->c.stats.started);
    assert_all_idle(fx);
    free(jobs);
}

static void test_32_concurrent_one_server(void **state)
{
    fx_t *fx = *state;
    const uint8_t servers[] = { 5 };
    run_jobs(fx, servers, 1);
    /* the transfers really overlapped at the server */
    assert_true(fx->srv[0]->s.stats.downloads + fx->srv[0]->s.stats.uploads == 32);
}

static void test_32_concurrent_three_servers(void **state)
{
    fx_t *fx = *state;
    const uint8_t servers[] = { 5, 6, 7 };
    run_jobs(fx, servers, 3);
    run_jobs(fx, servers, 3);   /* and again: session-IDs go on round-robin */
}

/* ================================================= timeouts, cancel, aborts */

static void test_timeout_server_silent(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t mem[8];
    uint64_t t0 = fx->tb.now;
    ul_req(fx, &t, X, 0x2002, 0, mem, sizeof mem);
    t.r.timeout_ms = 200;
    start_ok(fx, &t);
    run_until(fx, t0 + MS(199));
    assert_int_equal(t.done_calls, 0);
    run_until(fx, t0 + MS(200));
    expect_req_mux(fx, X, UL, 1, 0x2002, 0);
    expect_req_abort(fx, X, 1, 0x2002, 0, 0x12);
    assert_done(&t, 0x12, false);
    assert_int_equal(fx->c.stats.timeouts, 1);
    assert_int_equal(co_usdo_client_active(&fx->c), 0);
    /* the late answer is ignored and counted */
    mux(mem, C, UL_EXP_RSP, 1, 0x2002, 0);
    inject(fx, X, mem, 6);
    assert_int_equal(fx->c.stats.rx_no_session, 1);
    assert_int_equal(t.done_calls, 1);

    /* per frame: re-armed by every frame of the server (default 1 s) */
    log_reset(fx);
    static uint8_t data[200];
    dl_req(fx, &t, X, 0x2009, 0, DOM, data, 200, CO_USDO_MODE_SEGMENTED);
    t0 = fx->tb.now;
    start_ok(fx, &t);
    run_until(fx, t0 + MS(900));
    inject_mux(fx, X, DL_INIT_RSP, 2, 0x2009, 0);
    run_until(fx, t0 + MS(1800));
    inject_counter(fx, X, DL_SEG_RSP, 2, 0);
    run_until(fx, t0 + MS(2799));
    assert_int_equal(t.done_calls, 0);
    run_until(fx, t0 + MS(2800));
    assert_done(&t, 0x12, false);
    next_req(fx);
    next_req(fx);
    next_req(fx);
    expect_req_abort(fx, X, 2, 0x2009, 0, 0x12);
    /* frames the session did not expect do not re-arm it (checked above
     * by the exact time) */
    assert_all_idle(fx);
}

/* Step a few bus rounds only (a transfer stays in the middle). */
static void rounds(fx_t *fx, int n)
{
    int r;
    uint8_t i;
    for (r = 0; r < n; r++) {
        for (i = 0; i < fx->tb.count; i++)
            (void)co_line_process(&fx->tb.lines[i]->line, fx->tb.now);
        (void)co_membus_transfer(&fx->tb.bus, NULL, NULL);
        tu_drain_sniffer(&fx->tb);
    }
}

static void test_cancel_mid_segmented(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t data[1000];
    fill_pattern(data, sizeof data, 6);
    dl_req(fx, &t, 6, 0x2005, 0, OS, data, 1000, CO_USDO_MODE_AUTO);
    start_ok(fx, &t);
    rounds(fx, 8);   /* initiate and a few segments */
    assert_int_equal(co_usdo_server_active(&fx->srv[1]->s), 1);
    assert_true(co_usdo_client_cancel(&fx->c, &t.r, 0));
    assert_false(co_usdo_client_cancel(&fx->c, &t.r, 0));   /* not running any more */
    assert_done(&t, 0x10, false);
    assert_int_equal(co_usdo_client_active(&fx->c), 0);
    settle(fx);
    /* the abort frame is the client's last frame */
    {
        long k = (long)tu_log_count_id(&fx->tb, REQ_ID) - 1;
        long idx = tu_log_find_id(&fx->tb, REQ_ID, (size_t)k);
        uint8_t e[7];
        mux(e, 6, ABORT, 1, 0x2005, 0);
        e[6] = 0x10;
        tu_assert_logged(&fx->tb, idx, REQ_ID, e, 7);
    }
    assert_int_equal(fx->srv[1]->s.stats.rx_client_abort, 1);
    assert_od_bytes(fx->srv[1], 0x2005, NULL, 0);   /* nothing written */
    assert_int_equal(fx->c.stats.cancelled, 1);
    assert_int_equal(t.done_calls, 1);
    assert_all_idle(fx);
}

static void test_server_abort_mid_transfer(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    static uint8_t data[3000];
    fill_pattern(data, sizeof data, 12);
    fx->srv[0]->dom_fail_at = 500;   /* the writer refuses from byte 500 on: 0x60 */
    dl_req(fx, &t, 5, 0x2009, 0, DOM, data, 3000, CO_USDO_MODE_SEGMENTED);
    start_ok(fx, &t);
    settle(fx);
    assert_done(&t, 0x60, true);
    assert_int_equal(t.r.transferred, 540);   /* the segment the server refused was sent */
    assert_int_equal(fx->c.stats.aborts_received, 1);
    assert_int_equal(fx->c.stats.aborts_sent, 0);
    assert_all_idle(fx);
}

/* done(): what the client's line had carried or queued at that moment. */
static void mark_tx_hook(treq_t *t)
{
    co_line_t *cl = t->fx->cl;
    t->tag = (int)(cl->stats.tx_frames + co_queue_count(&cl->tx));
}

/* Depends on the server's bulk download: an abort mid-bulk stops the
 * sending at once (frames already queued still go out; no new ones). */
static void test_server_abort_mid_bulk(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    const uint32_t n = 60000;
    uint8_t *data = malloc(n);
    uint32_t frames_then;
    assert_non_null(data);
    fill_pattern(data, n, 13);
    fx->srv[0]->dom_fail_at = 20000;
    dl_req(fx, &t, 5, 0x2009, 0, DOM, data, n, CO_USDO_MODE_BULK);
    t.hook = mark_tx_hook;
    start_ok(fx, &t);
    settle(fx);
    free(data);
    if (t.r.abort == 0x13 && t.r.abort_from_server)
        skip();
    assert_done(&t, 0x60, true);
    frames_then = (uint32_t)t.tag;
    assert_true(t.r.transferred < n);
    /* at most two queue-fulls ahead of the server when it refused */
    assert_true(t.r.transferred <= 20040u + 2u * 60u * (TU_QUEUE - TU_QUEUE / 4));
    run_ms(fx, 100);
    assert_int_equal(fx->cl->stats.tx_frames, frames_then);   /* nothing after the abort */
    assert_int_equal(fx->srv[0]->s.stats.rx_no_session, 0);   /* strays: ignored */
    assert_all_idle(fx);
}

/* ================================================= robustness */

static void test_stray_late_duplicated_answers(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    static uint8_t data[300];
    uint8_t b[64];
    fill_pattern(data, sizeof data, 4);
    dl_req(fx, &t, X, 0x2009, 0, DOM, data, 300, CO_USDO_MODE_SEGMENTED);
    start_ok(fx, &t);
    settle(fx);
    next_req(fx);
    /* not for us / nobody's / wrong server / classic / empty */
    mux(b, C + 1, DL_INIT_RSP, 1, 0x2009, 0);
    inject(fx, X, b, 6);
    assert_int_equal(fx->c.stats.rx_other_dest, 1);
    inject_mux(fx, X, DL_INIT_RSP, 9, 0x2009, 0);
    assert_int_equal(fx->c.stats.rx_no_session, 1);
    inject_mux(fx, X + 1, DL_INIT_RSP, 1, 0x2009, 0);
    assert_int_equal(fx->c.stats.rx_no_session, 2);
    mux(b, C, DL_INIT_RSP, 1, 0x2009, 0);
    inject_raw(fx, X, 0, b, 6);
    assert_int_equal(fx->c.stats.rx_not_fd, 1);
    inject_raw(fx, X, FDF, b, 2);
    assert_int_equal(fx->c.stats.rx_malformed, 1);
    inject_raw(fx, X, FDF, b, 0);
    assert_int_equal(fx->c.stats.rx_malformed, 2);
    /* answers of another state: ignored */
    inject_counter(fx, X, DL_SEG_RSP, 1, 0);
    inject(fx, X, (const uint8_t[]){ C, DL_LAST_RSP, 1 }, 3);
    inject(fx, X, (const uint8_t[]){ C, 0x55, 1, 0, 0 }, 5);   /* unknown command */
    inject(fx, X, (const uint8_t[]){ C, 0xFF, 1, 0, 0, 0, 0 }, 7);   /* remote abort */
    assert_int_equal(fx->c.stats.rx_unexpected, 4);
    expect_no_req(fx);
    assert_int_equal(t.done_calls, 0);
    /* the real answer goes on, a repeat of it is ignored */
    inject_mux(fx, X, DL_INIT_RSP, 1, 0x2009, 0);
    inject_mux(fx, X, DL_INIT_RSP, 1, 0x2009, 0);
    assert_int_equal(fx->c.stats.rx_unexpected, 5);
    b[0] = X;
    b[1] = DL_SEG;
    b[2] = 1;
    b[3] = 0;
    memcpy(b + 4, data, 60);
    expect_req(fx, b, 64);
    expect_no_req(fx);
    inject_counter(fx, X, DL_SEG_RSP, 1, 0);
    next_req(fx);
    inject_counter(fx, X, DL_SEG_RSP, 1, 1);
    next_req(fx);
    inject_counter(fx, X, DL_SEG_RSP, 1, 2);
    next_req(fx);
    inject_counter(fx, X, DL_SEG_RSP, 1, 3);
    b[1] = DL_LAST;
    b[3] = 60;
    memcpy(b + 4, data + 240, 60);
    expect_req(fx, b, 64);
    inject(fx, X, (const uint8_t[]){ C, DL_LAST_RSP, 1 }, 3);
    assert_done(&t, 0, false);
    /* late and repeated answers of the finished transfer */
    inject(fx, X, (const uint8_t[]){ C, DL_LAST_RSP, 1 }, 3);
    inject_counter(fx, X, DL_SEG_RSP, 1, 3);
    inject_abort(fx, X, 1, 0x2009, 0, 0x12);
    assert_int_equal(fx->c.stats.rx_no_session, 5);
    assert_int_equal(t.done_calls, 1);
    expect_no_req(fx);
    assert_all_idle(fx);
}

/* Duplicate every server answer on the bus: a duplicated expedited answer
 * arrives after the end (ignored), a duplicated segment answer is a wrong
 * counter (0x14). */
static uint8_t dup_from_servers(fx_t *fx, const co_frame_t *f)
{
    (void)fx;
    return (f->id >= 0x581 && f->id <= 0x5FF) ? 2 : 1;
}

static void test_duplicated_answers_on_the_bus(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t mem[8];
    static uint8_t data[200];
    fx->fault = dup_from_servers;
    ul_req(fx, &t, 5, 0x2002, 0, mem, sizeof mem);
    start_ok(fx, &t);
    settle(fx);
    assert_done(&t, 0, false);
    assert_int_equal(fx->c.stats.rx_no_session, 1);
    assert_int_equal(t.done_calls, 1);

    dl_req(fx, &t, 5, 0x2009, 0, DOM, data, 200, CO_USDO_MODE_SEGMENTED);
    start_ok(fx, &t);
    settle(fx);
    /* 0x22 twice: the repeat arrives in DL_SEG (ignored); 0x23 #0 twice:
     * the repeat has the old counter: 0x14 */
    assert_done(&t, 0x14, false);
    assert_int_equal(fx->c.stats.rx_unexpected, 1);
    assert_int_equal(fx->c.stats.rx_bad_counter, 1);
    assert_int_equal(fx->srv[0]->s.stats.rx_client_abort, 1);
    assert_all_idle(fx);
}

static void test_upload_wrong_counter(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t mem[300], seg[60];
    fill_pattern(seg, 60, 1);
    ul_req(fx, &t, X, 0x2009, 0, mem, sizeof mem);
    start_ok(fx, &t);
    settle(fx);
    expect_req_mux(fx, X, UL, 1, 0x2009, 0);
    inject_initiate(fx, X, UL_INIT_RSP, 1, 0x2009, 0, 0x0F, 200);
    expect_req_counter(fx, X, UL_SEG, 1, 0);
    inject_segment(fx, X, 1, 0, seg);
    expect_req_counter(fx, X, UL_SEG, 1, 1);
    inject_segment(fx, X, 1, 2, seg);
    expect_req_abort(fx, X, 1, 0x2009, 0, 0x14);
    expect_no_req(fx);
    assert_done(&t, 0x14, false);
    assert_int_equal(fx->c.stats.rx_bad_counter, 1);
    assert_int_equal(t.buf.size, 60);   /* nothing of the bad segment */
    assert_all_idle(fx);
}

static void test_upload_size_mismatch(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t mem[300], seg[60];
    fill_pattern(seg, 60, 2);
    /* fewer than announced */
    ul_req(fx, &t, X, 0x2009, 0, mem, sizeof mem);
    start_ok(fx, &t);
    settle(fx);
    inject_initiate(fx, X, UL_INIT_RSP, 1, 0x2009, 0, 0x0F, 100);
    inject_segment(fx, X, 1, 0, seg);
    inject_last(fx, X, 1, seg, 30);
    next_req(fx);
    expect_req_counter(fx, X, UL_SEG, 1, 0);
    expect_req_counter(fx, X, UL_SEG, 1, 1);
    expect_req_abort(fx, X, 1, 0x2009, 0, 0x15);
    assert_done(&t, 0x15, false);
    /* more than announced, in a middle segment */
    log_reset(fx);
    start_ok(fx, &t);
    settle(fx);
    inject_initiate(fx, X, UL_INIT_RSP, 2, 0x2009, 0, 0x0F, 70);
    inject_segment(fx, X, 2, 0, seg);
    inject_segment(fx, X, 2, 1, seg);
    next_req(fx);
    next_req(fx);
    next_req(fx);
    expect_req_abort(fx, X, 2, 0x2009, 0, 0x15);
    assert_done(&t, 0x15, false);
    assert_int_equal(t.buf.size, 60);
    /* more than announced in the last one */
    log_reset(fx);
    start_ok(fx, &t);
    settle(fx);
    inject_initiate(fx, X, UL_INIT_RSP, 3, 0x2009, 0, 0x0F, 10);
    inject_last(fx, X, 3, seg, 11);
    next_req(fx);
    next_req(fx);
    expect_req_abort(fx, X, 3, 0x2009, 0, 0x15);
    assert_done(&t, 0x15, false);
    /* exactly right: fine (a full segment, then an empty last one) */
    log_reset(fx);
    start_ok(fx, &t);
    settle(fx);
    inject_initiate(fx, X, UL_INIT_RSP, 4, 0x2009, 0, 0x0F, 60);
    inject_segment(fx, X, 4, 0, seg);
    inject_last(fx, X, 4, NULL, 0);
    assert_done(&t, 0, false);
    assert_int_equal(t.buf.size, 60);
    assert_int_equal(fx->c.stats.rx_size_mismatch, 3);
    assert_all_idle(fx);
}

static void test_upload_bigger_than_sink(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t *mem = malloc(500);
    assert_non_null(mem);
    fill_pattern(fx->srv[0]->dom, 1000, 3);
    fx->srv[0]->dom_len = 1000;
    ul_req(fx, &t, 5, 0x2009, 0, mem, 500);
    start_ok(fx, &t);
    settle(fx);
    expect_req_mux(fx, 5, UL, 1, 0x2009, 0);
    expect_req_abort(fx, 5, 1, 0x2009, 0, 0x16);
    expect_no_req(fx);
    assert_done(&t, 0x16, false);
    assert_int_equal(t.announced, 1000);
    assert_int_equal(fx->c.stats.sink_refused, 1);
    assert_int_equal(fx->srv[0]->s.stats.rx_client_abort, 1);
    /* expedited answer into a 2-byte sink: 0x16 too (told to the server,
     * which has nothing open any more and ignores it) */
    log_reset(fx);
    ul_req(fx, &t, 5, 0x2002, 0, mem, 2);
    start_ok(fx, &t);
    settle(fx);
    expect_req_mux(fx, 5, UL, 2, 0x2002, 0);
    expect_req_abort(fx, 5, 2, 0x2002, 0, 0x16);
    assert_done(&t, 0x16, false);
    assert_int_equal(fx->srv[0]->s.stats.rx_stray_abort, 1);
    assert_all_idle(fx);
    free(mem);
}

static void test_expected_frame_malformed_or_wrong_mux(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t mem[64], b[12];
    ul_req(fx, &t, X, 0x2002, 0, mem, sizeof mem);
    start_ok(fx, &t);
    settle(fx);
    mux(b, C, UL_EXP_RSP, 1, 0x2002, 0);
    b[6] = 7;
    b[7] = 10;
    inject(fx, X, b, 9);   /* N = 10, 4 bytes there (with the FD padding to 12) */
    next_req(fx);
    expect_req_abort(fx, X, 1, 0x2002, 0, 0x1E);
    assert_done(&t, 0x1E, false);
    start_ok(fx, &t);
    settle(fx);
    mux(b, C, UL_EXP_RSP, 2, 0x2002, 1);   /* sub-index 1 instead of 0 */
    b[6] = 7;
    b[7] = 0;
    inject(fx, X, b, 8);
    next_req(fx);
    expect_req_abort(fx, X, 2, 0x2002, 0, 0x1F);
    assert_done(&t, 0x1F, false);
    /* a server abort with code 0 or too short: 0x10 from the server */
    start_ok(fx, &t);
    settle(fx);
    inject_abort(fx, X, 3, 0x2002, 0, 0);
    assert_done(&t, 0x10, true);
    start_ok(fx, &t);
    settle(fx);
    inject(fx, X, (const uint8_t[]){ C, ABORT, 4, 0, 2, 0x20 }, 6);
    assert_done(&t, 0x10, true);
    assert_int_equal(fx->c.stats.rx_malformed, 2);
    assert_int_equal(fx->c.stats.rx_bad_mux, 1);
    assert_all_idle(fx);
}

/* ---- faults injected on the bus */

/* Drop / duplicate / hold the fault_nth frame of command fault_cs. */
static uint8_t fault_drop(fx_t *fx, const co_frame_t *f)
{
    if (f->len > 1 && f->data[1] == fx->fault_cs && fx->fault_seen++ == fx->fault_nth)
        return 0;
    return 1;
}

static uint8_t fault_dup(fx_t *fx, const co_frame_t *f)
{
    if (f->len > 1 && f->data[1] == fx->fault_cs && fx->fault_seen++ == fx->fault_nth)
        return 2;
    return 1;
}

/* Keep a copy of the frame (delivered normally) to bring it back later. */
static uint8_t fault_copy(fx_t *fx, const co_frame_t *f)
{
    if (f->len > 1 && f->data[1] == fx->fault_cs && fx->fault_seen++ == fx->fault_nth) {
        fx->held = *f;
        fx->hold_valid = true;
    }
    return 1;
}

/* Hold the frame back (not delivered) and deliver it right after the next
 * frame of the same command: the two swap places. */
static uint8_t fault_swap(fx_t *fx, const co_frame_t *f)
{
    int i;
    if (f->len < 2 || f->data[1] != fx->fault_cs)
        return 1;
    if (fx->fault_seen == fx->fault_nth) {
        fx->fault_seen++;
        fx->held = *f;
        fx->hold_valid = true;
        return 0;
    }
    if (fx->fault_seen++ != fx->fault_nth + 1 || !fx->hold_valid)
        return 1;
    fx->hold_valid = false;
    /* this frame, then the held one, to every line but the client (the sender) */
    co_line_receive(&fx->tb.sniffer.line, f);
    co_line_receive(&fx->tb.sniffer.line, &fx->held);
    for (i = 1; i < 1 + NSRV; i++) {
        co_line_receive(&fx->l[i].line, f);
        co_line_receive(&fx->l[i].line, &fx->held);
    }
    return 0;
}

static void fault_reset(fx_t *fx, uint8_t (*fn)(fx_t *, const co_frame_t *), uint8_t cs,
                        unsigned nth)
{
    fx->fault = fn;
    fx->fault_cs = cs;
    fx->fault_nth = nth;
    fx->fault_seen = 0;
    fx->hold_valid = false;
}

static void test_fault_lost_segment(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    static uint8_t data[1000];
    fill_pattern(data, sizeof data, 14);
    fault_reset(fx, fault_drop, DL_SEG, 4);
    dl_req(fx, &t, 5, 0x2009, 0, DOM, data, 1000, CO_USDO_MODE_SEGMENTED);
    t.r.timeout_ms = 300;   /* the client notices before the server's 1 s */
    start_ok(fx, &t);
    run_ms(fx, 300);
    assert_done(&t, 0x12, false);
    assert_int_equal(fx->srv[0]->s.stats.rx_client_abort, 1);
    assert_int_equal(fx->srv[0]->dom_aborts, 1);
    assert_int_equal(fx->srv[0]->dom_commits, 0);
    assert_all_idle(fx);
    /* a lost answer: the same */
    fault_reset(fx, fault_drop, UL_SEG_RSP, 2);
    fx->srv[0]->dom_len = 1000;
    uint8_t *mem = malloc(1000);
    assert_non_null(mem);
    ul_req(fx, &t, 5, 0x2009, 0, mem, 1000);
    t.r.timeout_ms = 300;
    start_ok(fx, &t);
    run_ms(fx, 300);
    assert_done(&t, 0x12, false);
    assert_int_equal(fx->srv[0]->s.stats.rx_client_abort, 2);
    assert_all_idle(fx);
    free(mem);
}

static void test_fault_duplicated_segment(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    static uint8_t data[1000];
    uint8_t *mem = malloc(1000);
    assert_non_null(mem);
    fill_pattern(data, sizeof data, 15);
    /* a duplicated download segment: the server's 0x14 */
    fault_reset(fx, fault_dup, DL_SEG, 3);
    dl_req(fx, &t, 5, 0x2009, 0, DOM, data, 1000, CO_USDO_MODE_SEGMENTED);
    start_ok(fx, &t);
    settle(fx);
    assert_done(&t, 0x14, true);
    assert_int_equal(fx->srv[0]->s.stats.rx_bad_counter, 1);
    assert_int_equal(fx->srv[0]->dom_commits, 0);
    assert_all_idle(fx);
    /* a duplicated upload segment: our 0x14 */
    fault_reset(fx, fault_dup, UL_SEG_RSP, 3);
    fx->srv[0]->dom_len = 1000;
    ul_req(fx, &t, 5, 0x2009, 0, mem, 1000);
    start_ok(fx, &t);
    settle(fx);
    assert_done(&t, 0x14, false);
    assert_int_equal(fx->c.stats.rx_bad_counter, 1);
    assert_int_equal(fx->srv[0]->s.stats.rx_client_abort, 1);
    assert_int_equal(t.buf.size, 240);
    assert_all_idle(fx);
    free(mem);
}

static void test_fault_reordered_segment(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t *mem = malloc(1000);
    assert_non_null(mem);
    /* an old upload segment comes back later (reordered after newer ones) */
    fill_pattern(fx->srv[1]->dom, 1000, 16);
    fx->srv[1]->dom_len = 1000;
    fault_reset(fx, fault_copy, UL_SEG_RSP, 2);
    ul_req(fx, &t, 6, 0x2009, 0, mem, 1000);
    start_ok(fx, &t);
    rounds(fx, 12);   /* segments 0..4 or so are through */
    assert_true(fx->hold_valid);
    assert_true(co_line_receive(fx->cl, &fx->held));
    settle(fx);
    assert_done(&t, 0x14, false);
    assert_int_equal(fx->srv[1]->s.stats.rx_client_abort, 1);
    assert_all_idle(fx);
    free(mem);
}

/* Depends on the server's bulk download: lost, duplicated and swapped bulk
 * segments end in the server's 0x14 and nothing is left open. */
static void test_fault_bulk_segments(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    const uint32_t n = 30000;
    uint8_t *data = malloc(n);
    uint8_t (*faults[3])(fx_t *, const co_frame_t *) = { fault_drop, fault_dup, fault_swap };
    int k;
    assert_non_null(data);
    fill_pattern(data, n, 17);
    for (k = 0; k < 3; k++) {
        fault_reset(fx, faults[k], BULK_SEG, 100);
        dl_req(fx, &t, 5, 0x2009, 0, DOM, data, n, CO_USDO_MODE_BULK);
        start_ok(fx, &t);
        settle(fx);
        if (t.r.abort == 0x13)
            skip();
        assert_done(&t, 0x14, true);
        assert_true(t.r.transferred < n);
        run_ms(fx, 50);
        assert_all_idle(fx);
    }
    assert_int_equal(fx->srv[0]->dom_commits, 0);
    free(data);
}

/* ---- random frames */

static void random_hook(treq_t *t);

static void random_job_start(fx_t *fx, treq_t *t)
{
    if (co_usdo_client_start(&fx->c, &t->r) == 0)
        t->starts++;
}

/* Results are only checked for sanity: a frame with the right addressing
 * and counter is indistinguishable from the server's. A job restarts from
 * done() once per step (the bus is instantaneous: unbounded restarts would
 * run forever at one instant), else from the main loop. */
static void random_hook(treq_t *t)
{
    assert_true(t->r.abort != 0 || t->r.transferred <= 6000u);
    if (t->r.upload && t->r.server != 0)
        assert_true(t->buf.size <= t->buf.capacity);
    if (t->fx->random_running && t->tag == 0) {
        t->tag = 1;
        random_job_start(t->fx, t);
    }
}

static void test_random_frames_while_transfers_run(void **state)
{
    static const uint8_t fd_lens[] = { 0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64 };
    static const uint8_t cmds[] = { 0x21, 0x22, 0x23, 0x24, 0x26, 0x28, 0x31, 0x32, 0x33,
                                    0x34, 0x7F, 0xFF, 0x01, 0x06 };
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
        co_usdo_server_deinit(&fx->srv[s]->s);
        server_start(fx->srv[s], 150);
        fill_pattern(fx->srv[s]->dom, 500, (uint8_t)s);
        fx->srv[s]->dom_len = 500;
    }
    co_usdo_client_deinit(&fx->c);
    client_start(fx, 40, 100);
    for (j = 0; j < 6; j++) {
        mem[j] = malloc(600);   /* exactly the sink's capacity: ASan sees overruns */
        assert_non_null(mem[j]);
    }
    dl_req(fx, &jobs[0], 5, 0x2002, 0, U32, src, 4, CO_USDO_MODE_AUTO);
    dl_req(fx, &jobs[1], 6, 0x3001, 0, OS, src, 150, CO_USDO_MODE_AUTO);
    ul_req(fx, &jobs[2], 7, 0x2004, 0, mem[2], 600);
    dl_req(fx, &jobs[3], 5, 0x2009, 0, DOM, src, 6000, CO_USDO_MODE_AUTO);
    ul_req(fx, &jobs[4], 6, 0x200C, 0, mem[4], 600);
    ul_req(fx, &jobs[5], 0, 0x2002, 0, NULL, 0);
    jobs[5].r.sink = NULL;
    jobs[5].r.answer = NULL;
    jobs[5].r.timeout_ms = 20;
    fx->random_running = true;
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
        f.id = (r & 1u) ? 0x585u + (uint32_t)((r >> 1) % 3u) : 0x581u + (uint32_t)((r >> 1) % 127u);
        if (((r >> 8) & 15u) == 0) {
            f.flags = 0;
            f.len = (uint8_t)((r >> 12) % 9u);
        } else {
            f.flags = FDF;
            f.len = fd_lens[(r >> 12) % sizeof fd_lens];
        }
        for (k = 0; k < f.len; k++)
            f.data[k] = (uint8_t)tu_rand(&fx->seed);
        r = tu_rand(&fx->seed);
        if (f.len > 0 && (r & 3u) != 0)
            f.data[0] = C;
        if (f.len > 1 && ((r >> 2) & 3u) != 0)
            f.data[1] = cmds[(r >> 4) % sizeof cmds];
        if (f.len > 2 && ((r >> 12) & 3u) != 0)
            f.data[2] = jobs[(r >> 14) % 6].r.session_id;
        if (f.len > 3 && ((r >> 20) & 1u) != 0)
            f.data[3] = (uint8_t)((r >> 21) % 4u);
        if (f.len > 7 && ((r >> 24) & 1u) != 0)
            f.data[7] = (uint8_t)((r >> 25) % 70u);
        (void)co_line_receive(fx->cl, &f);
        if (i % 8 == 7) {
            run_until(fx, fx->tb.now + 250);
            for (j = 0; j < 6; j++) {
                jobs[j].tag = 0;
                if (!co_usdo_client_running(&fx->c, &jobs[j].r))
                    random_job_start(fx, &jobs[j]);
            }
        }
    }
    assert_true(fx->c.stats.rx_frames >= 10000);
    /* stop restarting; everything ends by itself (timeouts at the latest) */
    fx->random_running = false;
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
    assert_all_idle(fx);
    /* nothing is wedged: the same transfers now run clean and correct */
    log_reset(fx);
    for (j = 0; j < 5; j++) {
        jobs[j].hook = NULL;
        jobs[j].starts = jobs[j].done_calls = 0;
        start_ok(fx, &jobs[j]);
    }
    settle(fx);
    for (j = 0; j < 5; j++)
        assert_done(&jobs[j], 0, false);
    assert_int_equal(od_u32(fx->srv[0], 0x2002), (uint32_t)tu_le_get(src, 4));
    assert_od_bytes(fx->srv[1], 0x3001, src, 150);
    assert_int_equal(fx->srv[0]->dom_len, 6000);
    assert_memory_equal(fx->srv[0]->dom, src, 6000);
    assert_int_equal(jobs[4].buf.size, 500);
    assert_memory_equal(mem[4], fx->srv[1]->dom, 500);
    assert_all_idle(fx);
    for (j = 0; j < 6; j++)
        free(mem[j]);
    free(src);
    free(jobs);
}

/* ================================================= session-IDs, re-entrancy, deinit */

static void test_session_ids_never_reused_while_live(void **state)
{
    fx_t *fx = *state;
    treq_t *t = calloc(257, sizeof *t);
    uint8_t mem[8];
    unsigned i;
    assert_non_null(t);
    co_usdo_client_deinit(&fx->c);
    client_start(fx, 255, 0);
    for (i = 0; i < 255; i++) {
        ul_req(fx, &t[i], X, 0x2000, (uint8_t)i, mem, sizeof mem);
        start_ok(fx, &t[i]);
        assert_int_equal(t[i].r.session_id, i + 1);   /* round-robin from 1, never 0 */
    }
    ul_req(fx, &t[255], X, 0x2000, 0, mem, sizeof mem);
    assert_int_equal(co_usdo_client_start(&fx->c, &t[255].r), 0x70);
    settle(fx);
    for (i = 0; i < 255; i++) {
        const tu_logged_t *l = next_req(fx);
        assert_non_null(l);
        assert_int_equal(l->frame.data[2], i + 1);
    }
    /* free 100: the only free ID, so the next start takes it */
    inject_abort(fx, X, 100, 0x2000, 99, 0x33);
    assert_done(&t[99], 0x33, true);
    start_ok(fx, &t[255]);
    assert_int_equal(t[255].r.session_id, 100);
    /* free 5 and 6: round-robin goes on after 100 and finds 5 */
    inject_abort(fx, X, 5, 0x2000, 4, 0x33);
    inject_abort(fx, X, 6, 0x2000, 5, 0x33);
    start_ok(fx, &t[4]);
    assert_int_equal(t[4].r.session_id, 5);
    start_ok(fx, &t[5]);
    assert_int_equal(t[5].r.session_id, 6);
    /* all time out together: 255 aborts, every session free */
    run_ms(fx, 1000);
    assert_int_equal(co_usdo_client_active(&fx->c), 0);
    assert_int_equal(fx->c.stats.timeouts, 255);
    for (i = 0; i < 256; i++)
        assert_int_equal(t[i].done_calls, t[i].starts);
    /* with the table free, the IDs go on where they were (7), not back to 1 */
    start_ok(fx, &t[0]);
    assert_int_equal(t[0].r.session_id, 7);
    co_usdo_client_deinit(&fx->c);
    free(t);
}

/* done() starts the next request (the same struct), ten times in a row. */
static void chain_hook(treq_t *t)
{
    if (t->tag > 0) {
        t->tag--;
        assert_int_equal(co_usdo_client_start(&t->fx->c, &t->r), 0);
        t->starts++;
    }
}

static void test_done_may_start_new_requests(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t mem[8];
    ul_req(fx, &t, 7, 0x2002, 0, mem, sizeof mem);
    t.hook = chain_hook;
    t.tag = 9;
    start_ok(fx, &t);
    settle(fx);
    assert_int_equal(t.starts, 10);
    assert_done(&t, 0, false);
    assert_int_equal(t.r.session_id, 10);
    assert_int_equal(tu_le_get(mem, 4), 0x33333307u);
    assert_all_idle(fx);
}

/* Cancel from inside a sink: the transfer ends at once, nothing after. */
static uint8_t cancelling_sink(void *ctx, uint32_t offset, const uint8_t *data, uint32_t len,
                               uint32_t total)
{
    treq_t *t = ctx;
    (void)data;
    (void)total;
    if (offset >= 120 && len > 0)
        assert_true(co_usdo_client_cancel(&t->fx->c, &t->r, 0x16));
    return 0;
}

static void test_cancel_from_inside_a_sink(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    uint8_t mem[8];
    fill_pattern(fx->srv[0]->dom, 1000, 3);
    fx->srv[0]->dom_len = 1000;
    ul_req(fx, &t, 5, 0x2009, 0, mem, sizeof mem);
    t.r.sink = cancelling_sink;
    start_ok(fx, &t);
    settle(fx);
    assert_done(&t, 0x16, false);
    assert_int_equal(fx->c.stats.cancelled, 1);
    assert_int_equal(fx->c.stats.aborts_sent, 1);
    assert_int_equal(tu_log_count_id(&fx->tb, REQ_ID), 1 + 3 + 1);
    assert_all_idle(fx);
}

static void refused_start_hook(treq_t *t)
{
    assert_int_equal(co_usdo_client_start(&t->fx->c, &t->r), 0x10);
}

static void test_deinit_ends_open_requests(void **state)
{
    fx_t *fx = *state;
    treq_t t[3];
    uint8_t mem[8];
    static uint8_t data[300];
    int i;
    ul_req(fx, &t[0], X, 0x2002, 0, mem, sizeof mem);
    dl_req(fx, &t[1], X, 0x2009, 0, DOM, data, 300, CO_USDO_MODE_AUTO);
    ul_req(fx, &t[2], 0, 0x2002, 0, NULL, 0);
    t[2].r.sink = NULL;
    for (i = 0; i < 3; i++) {
        t[i].hook = refused_start_hook;   /* a start from done() during deinit is refused */
        start_ok(fx, &t[i]);
    }
    settle(fx);
    log_reset(fx);
    co_usdo_client_deinit(&fx->c);
    for (i = 0; i < 3; i++)
        assert_done(&t[i], 0x10, false);
    assert_int_equal(co_usdo_client_start(&fx->c, &t[0].r), 0x10);
    assert_false(co_usdo_client_cancel(&fx->c, &t[0].r, 0));
    settle(fx);
    expect_no_req(fx);   /* nothing sent */
    assert_int_equal(co_usdo_client_active(&fx->c), 0);
    assert_int_equal(co_timer_list_next(co_line_timers(fx->cl)), CO_TIME_NEVER);
    assert_int_equal(fx->cl->tx_space_count, 0);
    /* answers now reach nobody; the range is free for a new client */
    inject_mux(fx, X, DL_INIT_RSP, 2, 0x2009, 0);
    assert_int_equal(fx->cl->stats.rx_unhandled, 1);
    co_usdo_client_deinit(&fx->c);   /* twice: harmless */
    client_start(fx, 40, 0);
    t[0].hook = NULL;
    start_ok(fx, &t[0]);
    assert_true(co_usdo_client_running(&fx->c, &t[0].r));
    assert_int_equal(t[0].r.session_id, 1);
}

/* ================================================= buffers */

static void test_buffer_source_and_sink(void **state)
{
    uint8_t data[10], out[10], mem[6];
    co_usdo_buffer_t src = { data, 10, 0 };
    co_usdo_buffer_t snk = { mem, 0, 6 };
    (void)state;
    fill_pattern(data, 10, 1);
    assert_int_equal(co_usdo_buffer_source(&src, 0, out, 4), 4);
    assert_memory_equal(out, data, 4);
    assert_int_equal(co_usdo_buffer_source(&src, 8, out, 4), 2);
    assert_memory_equal(out, data + 8, 2);
    assert_int_equal(co_usdo_buffer_source(&src, 10, out, 4), 0);
    assert_int_equal(co_usdo_buffer_source(&src, 0xFFFFFFF0u, out, 4), 0);
    assert_int_equal(co_usdo_buffer_sink(&snk, 0, NULL, 0, 7), 0x16);
    assert_int_equal(co_usdo_buffer_sink(&snk, 0, NULL, 0, 6), 0);
    assert_int_equal(co_usdo_buffer_sink(&snk, 0, NULL, 0, 0xFFFFFFFFu), 0);
    assert_int_equal(co_usdo_buffer_sink(&snk, 0, data, 4, 0xFFFFFFFFu), 0);
    assert_int_equal(co_usdo_buffer_sink(&snk, 4, data + 4, 3, 0xFFFFFFFFu), 0x16);
    assert_int_equal(co_usdo_buffer_sink(&snk, 4, data + 4, 2, 0xFFFFFFFFu), 0);
    assert_int_equal(snk.size, 6);
    assert_memory_equal(mem, data, 6);
    assert_int_equal(co_usdo_buffer_sink(&snk, 0xFFFFFFFFu, data, 1, 0xFFFFFFFFu), 0x16);
}

/* ================================================= source says "later" */

/* A buffer source that says CO_USDO_SOURCE_LATER for the segment at
 * `later_off` while `hold` is set; it may also try a resume from inside. */
typedef struct later_src {
    fx_t *fx;
    treq_t *t;
    co_usdo_buffer_t buf;
    uint32_t later_off;
    bool hold;
    bool resume_inside;
    uint8_t inside_rc;
    unsigned calls;
} later_src_t;

static uint32_t later_source(void *ctx, uint32_t offset, uint8_t *buf, uint32_t want)
{
    later_src_t *s = ctx;
    s->calls++;
    if (s->resume_inside) {
        s->resume_inside = false;
        s->inside_rc = co_usdo_client_resume(&s->fx->c, &s->t->r);
    }
    if (s->hold && offset == s->later_off)
        return CO_USDO_SOURCE_LATER;
    return co_usdo_buffer_source(&s->buf, offset, buf, want);
}

static void later_req(fx_t *fx, treq_t *t, later_src_t *s, uint8_t server, const uint8_t *data,
                      uint32_t size, uint8_t mode, uint32_t later_off)
{
    dl_req(fx, t, server, 0x2009, 0, DOM, data, size, mode);
    memset(s, 0, sizeof *s);
    s->fx = fx;
    s->t = t;
    s->buf.data = (uint8_t *)(uintptr_t)data;
    s->buf.size = size;
    s->later_off = later_off;
    s->hold = true;
    t->r.source = later_source;
    t->r.ctx = s;
}

static void expect_dl_init(fx_t *fx, uint8_t dest, uint8_t sid, uint8_t cs, uint32_t size)
{
    uint8_t e[12];
    mux(e, dest, cs, sid, 0x2009, 0);
    e[6] = DOM;
    e[7] = 0;
    tu_le_put(e + 8, size, 4);
    expect_req(fx, e, 12);
}

static void expect_dl_segment(fx_t *fx, uint8_t dest, uint8_t cs, uint8_t sid, uint8_t counter,
                              const uint8_t *data, uint8_t n)
{
    uint8_t e[64] = { dest, cs, sid, counter };
    memcpy(e + 4, data, n);
    expect_req(fx, e, 4u + n);
}

static uint8_t session_state_of(fx_t *fx, const treq_t *t)
{
    int i;
    for (i = 0; i < fx->c.session_count; i++)
        if (fx->c.sessions[i].req == &t->r && fx->c.sessions[i].state != CO_USDO_CLIENT_FREE)
            return fx->c.sessions[i].state;
    return CO_USDO_CLIENT_FREE;
}

/* Segment 2 is late: nothing on the bus while the source waits (even far
 * beyond the per-frame timeout), then the segment and the rest; the real
 * server stores the whole value. */
static void test_later_segment_then_resume_real_server(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    later_src_t s;
    uint8_t data[150];
    fill_pattern(data, sizeof data, 21);
    later_req(fx, &t, &s, 5, data, 150, CO_USDO_MODE_SEGMENTED, 60);
    t.r.timeout_ms = 100;   /* our timeout well inside the server's 1000 ms */
    start_ok(fx, &t);
    settle(fx);
    expect_dl_init(fx, 5, 1, DL_INIT, 150);
    expect_dl_segment(fx, 5, DL_SEG, 1, 0, data, 60);
    expect_no_req(fx);
    assert_int_equal(fx->c.stats.source_waits, 1);
    assert_int_equal(session_state_of(fx, &t), CO_USDO_CLIENT_DL_WAIT_SOURCE);
    assert_int_equal(t.r.transferred, 60);
    run_ms(fx, 500);   /* five of our timeouts: none fires */
    expect_no_req(fx);
    assert_int_equal(t.done_calls, 0);
    assert_int_equal(fx->c.stats.timeouts, 0);
    assert_true(co_usdo_client_running(&fx->c, &t.r));

    s.hold = false;
    assert_int_equal(co_usdo_client_resume(&fx->c, &t.r), 0);
    settle(fx);
    expect_dl_segment(fx, 5, DL_SEG, 1, 1, data + 60, 60);
    expect_dl_segment(fx, 5, DL_LAST, 1, 30, data + 120, 30);
    expect_no_req(fx);
    assert_done(&t, 0, false);
    assert_int_equal(t.r.transferred, 150);
    assert_int_equal(fx->srv[0]->dom_len, 150);
    assert_memory_equal(fx->srv[0]->dom, data, 150);
    assert_int_equal(fx->srv[0]->dom_commits, 1);
    assert_int_equal(fx->c.stats.source_waits, 1);
    assert_int_equal(fx->c.stats.source_failed, 0);
    assert_all_idle(fx);
}

/* Scripted server: exact frames, a wait of 5 s with the default 1 s
 * timeout, a second LATER on resume, resumes that must not send. */
static void test_later_scripted_wait_and_resume(void **state)
{
    fx_t *fx = *state;
    treq_t t, other;
    later_src_t s;
    uint8_t data[130];
    fill_pattern(data, sizeof data, 22);
    later_req(fx, &t, &s, X, data, 130, CO_USDO_MODE_SEGMENTED, 60);
    /* not running yet: refused, nothing sent */
    assert_int_equal(co_usdo_client_resume(&fx->c, &t.r), 0x10);
    assert_int_equal(co_usdo_client_resume(NULL, &t.r), 0x10);
    assert_int_equal(co_usdo_client_resume(&fx->c, NULL), 0x10);
    start_ok(fx, &t);
    settle(fx);
    expect_dl_init(fx, X, 1, DL_INIT, 130);
    /* the initiate's answer is due: no segment may go early */
    assert_int_equal(co_usdo_client_resume(&fx->c, &t.r), CO_USDO_CLIENT_NOT_WAITING);
    settle(fx);
    expect_no_req(fx);
    inject_mux(fx, X, DL_INIT_RSP, 1, 0x2009, 0);
    expect_dl_segment(fx, X, DL_SEG, 1, 0, data, 60);
    expect_no_req(fx);
    /* segment 0's answer is due: resume is a no-op */
    assert_int_equal(co_usdo_client_resume(&fx->c, &t.r), CO_USDO_CLIENT_NOT_WAITING);
    settle(fx);
    expect_no_req(fx);
    assert_int_equal(s.calls, 1);
    inject_counter(fx, X, DL_SEG_RSP, 1, 0);
    expect_no_req(fx);   /* the source said LATER for segment 1 */
    assert_int_equal(s.calls, 2);
    assert_int_equal(session_state_of(fx, &t), CO_USDO_CLIENT_DL_WAIT_SOURCE);
    /* a repeated answer while waiting is not expected: ignored, no send */
    inject_counter(fx, X, DL_SEG_RSP, 1, 0);
    assert_int_equal(fx->c.stats.rx_unexpected, 1);
    run_ms(fx, 5000);
    expect_no_req(fx);
    assert_int_equal(t.done_calls, 0);
    assert_int_equal(fx->c.stats.timeouts, 0);

    /* still not ready: waits again, nothing sent */
    assert_int_equal(co_usdo_client_resume(&fx->c, &t.r), 0);
    settle(fx);
    expect_no_req(fx);
    assert_int_equal(fx->c.stats.source_waits, 2);
    run_ms(fx, 3000);
    expect_no_req(fx);
    assert_int_equal(t.done_calls, 0);

    /* ready; a resume from inside the source is a no-op (no second send) */
    s.hold = false;
    s.resume_inside = true;
    assert_int_equal(co_usdo_client_resume(&fx->c, &t.r), 0);
    assert_int_equal(s.inside_rc, CO_USDO_CLIENT_NOT_WAITING);
    settle(fx);
    expect_dl_segment(fx, X, DL_SEG, 1, 1, data + 60, 60);
    expect_no_req(fx);
    assert_int_equal(co_usdo_client_resume(&fx->c, &t.r), CO_USDO_CLIENT_NOT_WAITING);
    settle(fx);
    expect_no_req(fx);
    /* the timeout runs again from the resume: 1 s of silence aborts 0x12 */
    run_ms(fx, 999);
    assert_int_equal(t.done_calls, 0);
    inject_counter(fx, X, DL_SEG_RSP, 1, 1);
    expect_dl_segment(fx, X, DL_LAST, 1, 10, data + 120, 10);
    inject_mux(fx, X, DL_LAST_RSP, 1, 0x2009, 0);
    assert_done(&t, 0, false);
    assert_int_equal(t.r.transferred, 130);
    assert_int_equal(co_usdo_client_resume(&fx->c, &t.r), 0x10);   /* finished */

    /* a resumed segment whose answer never comes still times out */
    log_reset(fx);
    later_req(fx, &other, &s, X, data, 130, CO_USDO_MODE_SEGMENTED, 0);
    start_ok(fx, &other);
    settle(fx);
    expect_dl_init(fx, X, 2, DL_INIT, 130);
    inject_mux(fx, X, DL_INIT_RSP, 2, 0x2009, 0);
    expect_no_req(fx);   /* segment 0 is late */
    run_ms(fx, 2000);
    s.hold = false;
    assert_int_equal(co_usdo_client_resume(&fx->c, &other.r), 0);
    settle(fx);
    expect_dl_segment(fx, X, DL_SEG, 2, 0, data, 60);
    run_ms(fx, 1000);
    expect_req_abort(fx, X, 2, 0x2009, 0, 0x12);
    assert_done(&other, 0x12, false);
    assert_int_equal(fx->c.stats.timeouts, 1);
    assert_all_idle(fx);
}

/* Cancel while waiting for the source: the abort goes out, done() once,
 * and nothing more (no timeout later). */
static void test_later_cancel_while_waiting(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    later_src_t s;
    uint8_t data[200];
    fill_pattern(data, sizeof data, 23);
    later_req(fx, &t, &s, X, data, 200, CO_USDO_MODE_SEGMENTED, 120);
    start_ok(fx, &t);
    settle(fx);
    expect_dl_init(fx, X, 1, DL_INIT, 200);
    inject_mux(fx, X, DL_INIT_RSP, 1, 0x2009, 0);
    expect_dl_segment(fx, X, DL_SEG, 1, 0, data, 60);
    inject_counter(fx, X, DL_SEG_RSP, 1, 0);
    expect_dl_segment(fx, X, DL_SEG, 1, 1, data + 60, 60);
    inject_counter(fx, X, DL_SEG_RSP, 1, 1);
    expect_no_req(fx);
    assert_int_equal(session_state_of(fx, &t), CO_USDO_CLIENT_DL_WAIT_SOURCE);
    run_ms(fx, 1500);
    assert_true(co_usdo_client_cancel(&fx->c, &t.r, 0x60));
    assert_false(co_usdo_client_cancel(&fx->c, &t.r, 0x60));
    settle(fx);
    expect_req_abort(fx, X, 1, 0x2009, 0, 0x60);
    expect_no_req(fx);
    assert_done(&t, 0x60, false);
    assert_int_equal(t.done_calls, 1);
    assert_int_equal(t.r.transferred, 120);
    assert_int_equal(fx->c.stats.cancelled, 1);
    assert_int_equal(co_usdo_client_resume(&fx->c, &t.r), 0x10);
    run_ms(fx, 5000);
    expect_no_req(fx);
    assert_int_equal(t.done_calls, 1);
    assert_int_equal(fx->c.stats.timeouts, 0);
    assert_all_idle(fx);
}

/* LATER where it is not allowed: an expedited download (read at start) is
 * refused 0x10 with nothing sent; a bulk download aborts 0x10 mid-stream. */
static void test_later_refused_expedited_and_bulk(void **state)
{
    fx_t *fx = *state;
    treq_t t;
    later_src_t s;
    static uint8_t data[5000];
    fill_pattern(data, sizeof data, 24);
    later_req(fx, &t, &s, X, data, 20, CO_USDO_MODE_AUTO, 0);
    assert_int_equal(co_usdo_client_start(&fx->c, &t.r), 0x10);
    settle(fx);
    expect_no_req(fx);
    assert_int_equal(t.done_calls, 0);
    assert_int_equal(fx->c.stats.source_failed, 1);
    assert_int_equal(fx->c.stats.source_waits, 0);

    later_req(fx, &t, &s, X, data, 5000, CO_USDO_MODE_BULK, 120);
    start_ok(fx, &t);
    settle(fx);
    expect_dl_init(fx, X, 1, BULK_INIT, 5000);
    inject_bulk_accept(fx, X, 1, 0x2009, 0, 0);
    expect_dl_segment(fx, X, BULK_SEG, 1, 0, data, 60);
    expect_dl_segment(fx, X, BULK_SEG, 1, 1, data + 60, 60);
    expect_req_abort(fx, X, 1, 0x2009, 0, 0x10);
    expect_no_req(fx);
    assert_done(&t, 0x10, false);
    assert_int_equal(t.r.transferred, 120);
    assert_int_equal(fx->c.stats.source_failed, 2);
    assert_int_equal(fx->c.stats.source_waits, 0);
    assert_int_equal(co_usdo_client_resume(&fx->c, &t.r), 0x10);
    assert_all_idle(fx);
}

#define T(t) cmocka_unit_test_setup_teardown(t, setup, teardown)
#define B(t) cmocka_unit_test_setup_teardown(t, setup_bare, teardown)

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_buffer_source_and_sink),
        T(test_init_refuses_bad_config),
        T(test_start_refusals),
        B(test_no_free_session_or_full_queue),
        T(test_expedited_download_exact_bytes),
        T(test_expedited_upload_exact_bytes),
        T(test_segmented_exact_bytes_both_ways),
        T(test_segmented_boundaries),
        T(test_segmented_100k_domain_both_ways),
        T(test_segmented_upload_unknown_size),
        T(test_bulk_download_1mib_real_server),
        B(test_bulk_scripted_bytes),
        B(test_bulk_scripted_pacing),
        B(test_bulk_max_pacing_configurable),
        B(test_bulk_flow_control),
        T(test_bulk_three_servers_at_once),
        B(test_auto_mode_choice),
        T(test_mode_override),
        B(test_auto_bulk_falls_back_to_segmented),
        T(test_bulk_upload_1mib_real_server),
        B(test_bulk_upload_scripted_bytes),
        B(test_bulk_upload_scripted_aborts),
        B(test_bulk_upload_auto_and_fallback),
        B(test_bulk_upload_receive_budget),
        T(test_bulk_upload_faults_real_server),
        B(test_empty_values_and_short_segments),
        T(test_broadcast_upload_three_servers),
        T(test_broadcast_download_three_servers),
        B(test_broadcast_scripted_answers),
        T(test_32_concurrent_one_server),
        T(test_32_concurrent_three_servers),
        B(test_timeout_server_silent),
        T(test_cancel_mid_segmented),
        T(test_server_abort_mid_transfer),
        T(test_server_abort_mid_bulk),
        B(test_stray_late_duplicated_answers),
        T(test_duplicated_answers_on_the_bus),
        B(test_upload_wrong_counter),
        B(test_upload_size_mismatch),
        T(test_upload_bigger_than_sink),
        B(test_expected_frame_malformed_or_wrong_mux),
        T(test_fault_lost_segment),
        T(test_fault_duplicated_segment),
        T(test_fault_reordered_segment),
        T(test_fault_bulk_segments),
        T(test_random_frames_while_transfers_run),
        B(test_session_ids_never_reused_while_live),
        T(test_done_may_start_new_requests),
        T(test_cancel_from_inside_a_sink),
        B(test_deinit_ends_open_requests),
        T(test_later_segment_then_resume_real_server),
        B(test_later_scripted_wait_and_resume),
        B(test_later_cancel_while_waiting),
        B(test_later_refused_expedited_and_bulk),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
