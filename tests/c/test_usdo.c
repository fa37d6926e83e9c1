/* USDO (CiA 1301): the wire codec (co_usdo) and the server (co_usdo_server).
 *
 * Codec: every layout decoded from and encoded to exact bytes, every
 * truncation of every frame refused without reading past the buffer (the
 * buffers are heap blocks of exactly the decoded length, so ASan sees any
 * overrun), random input, and the abort-code mapping.
 *
 * Server: node S (id 5) serves an OD on fd line a; the "client" is raw
 * frames sent from line b (node-ids 1 and 2, as CAN-ID 0x600 + client), and
 * the sniffer checks every response frame whole: CAN-ID 0x585, FD + BRS
 * flags, length rounded up to a valid FD length with zero padding, every
 * byte. The request bytes are written out here by hand (not with the codec
 * under test). */
#include "test_od_util.h"

#include "canopenfd/co_usdo.h"
#include "canopenfd/co_usdo_server.h"

#define ID_S 5
#define C1 1
#define C2 2
#define RSP_ID (0x580u + ID_S)
#define MS(x) ((uint64_t)(x) * TU_MS)
#define N_ENTRIES 32
#define POOL 4096
#define SUBS 8
#define NSES 3
#define SCRATCH 1000
#define DOM_CAP 102400u
#define BIG_CAP (1048576u + 37u)   /* 0x200D: 17476 bulk segments + 37 bytes */
#define FDF (CO_FRAME_FD | CO_FRAME_BRS)

#define OS CO_TYPE_OCTET_STRING
#define U64 CO_TYPE_UNSIGNED64
#define DOM CO_TYPE_DOMAIN
#define WO CO_ACCESS_WO

/* Command specifiers and abort codes as the research notes give them
 * (§2.4, §2.9), written independently of co_usdo.h. */
#define DL_EXP 0x01
#define DL_INIT 0x02
#define DL_SEG 0x03
#define DL_LAST 0x04
#define UL 0x11
#define UL_SEG 0x13
#define BULK_INIT 0x06
#define BULK_SEG 0x07
#define BULK_LAST 0x08
#define ABORT 0x7F
/* Bulk upload: our layout (docs/protocol-notes.md, "Bulk upload") */
#define BUL_REQ 0x16
#define BUL_ACK 0x17
#define BUL_INIT 0x36
#define BUL_SEG 0x37
#define BUL_LAST 0x38

/* ------------------------------------------------------------- fixture */

typedef struct fx {
    tu_bus_t tb;
    tu_line_t l[2];
    co_line_t *a, *b;
    co_node_t node;
    co_od_t od;
    co_od_entry_t entries[N_ENTRIES];
    uint8_t pool[POOL];
    co_od_subscription_t subs[SUBS];
    co_usdo_server_t srv;
    co_usdo_session_t ses[NSES];
    uint8_t scratch[NSES * SCRATCH];
    size_t cursor;                /* next log entry to look at */
    /* the domain 0x2009 (and 0x200C, same data, size unknown) */
    uint8_t domain[DOM_CAP];
    uint32_t dom_len;
    uint8_t staging[DOM_CAP];
    uint32_t dom_read_max;        /* 0 = as much as asked */
    bool dom_stall;               /* the reader gives nothing and does not end */
    uint32_t dom_read_error;      /* the reader refuses with this code */
    unsigned dom_commits;
    unsigned dom_aborts;
    uint32_t dom_last_abort;
    /* the write-only 1 MiB domain 0x200D */
    uint8_t big[BIG_CAP];
    uint32_t big_len;
    unsigned big_commits;
    unsigned big_aborts;
    /* split handler of 0x200B */
    bool split_read, split_write;
    co_od_xfer_t *held;
    /* snapshot for "nothing changed" */
    uint8_t pool_snap[POOL];
    uint32_t len_snap[N_ENTRIES];
    uint8_t dom_snap[DOM_CAP];
    uint32_t dom_len_snap;
} fx_t;

static uint32_t dom_size(co_od_t *od, const co_od_entry_t *e, uint32_t *size, void *user)
{
    fx_t *fx = user;
    (void)od;
    (void)e;
    *size = fx->dom_len;
    return 0;
}

static uint32_t dom_read(co_od_t *od, const co_od_entry_t *e, uint32_t offset, uint8_t *buf,
                         uint32_t cap, uint32_t *n, bool *last, void *user)
{
    fx_t *fx = user;
    uint32_t k;
    (void)od;
    (void)e;
    assert_true(offset <= fx->dom_len);
    if (fx->dom_read_error != 0)
        return fx->dom_read_error;
    if (fx->dom_stall && offset >= 60) {
        *n = 0;
        *last = false;
        return 0;
    }
    k = fx->dom_len - offset;
    if (k > cap)
        k = cap;
    if (fx->dom_read_max != 0 && k > fx->dom_read_max)
        k = fx->dom_read_max;
    if (k > 0)
        memcpy(buf, fx->domain + offset, k);
    *n = k;
    *last = offset + k == fx->dom_len;
    return 0;
}

static uint32_t dom_write(co_od_t *od, const co_od_entry_t *e, uint32_t offset,
                          const uint8_t *data, uint32_t n, uint32_t total, bool last,
                          uint32_t abort, void *user)
{
    fx_t *fx = user;
    (void)od;
    (void)e;
    if (abort != 0) {
        fx->dom_aborts++;
        fx->dom_last_abort = abort;
        return 0;
    }
    if ((total != CO_OD_SIZE_UNKNOWN && total > DOM_CAP) || offset > DOM_CAP ||
        n > DOM_CAP - offset)
        return CO_ABORT_LENGTH_HIGH;
    if (n > 0)
        memcpy(fx->staging + offset, data, n);
    if (last) {
        memcpy(fx->domain, fx->staging, offset + n);
        fx->dom_len = offset + n;
        fx->dom_commits++;
    }
    return 0;
}

static const co_od_handler_t dom_handler = {
    .domain_size = dom_size,
    .domain_read = dom_read,
    .domain_write = dom_write,
};

/* 0x200D: written straight into fx->big, in order; the length is known at
 * the end. */
static uint32_t big_write(co_od_t *od, const co_od_entry_t *e, uint32_t offset,
                          const uint8_t *data, uint32_t n, uint32_t total, bool last,
                          uint32_t abort, void *user)
{
    fx_t *fx = user;
    (void)od;
    (void)e;
    if (abort != 0) {
        fx->big_aborts++;
        return 0;
    }
    if ((total != CO_OD_SIZE_UNKNOWN && total > BIG_CAP) || offset > BIG_CAP ||
        n > BIG_CAP - offset)
        return CO_ABORT_LENGTH_HIGH;
    if (n > 0)
        memcpy(fx->big + offset, data, n);
    if (last) {
        fx->big_len = offset + n;
        fx->big_commits++;
    }
    return 0;
}

static const co_od_handler_t big_handler = {.domain_write = big_write};
/* 0x200C: the same data, without a size (upload size unknown) and without a
 * writer. */
static const co_od_handler_t dom_nosize_handler = {.domain_read = dom_read};

static uint32_t split_before_read(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e,
                                  void *user)
{
    fx_t *fx = user;
    (void)od;
    (void)e;
    if (!fx->split_read)
        return 0;
    fx->held = xfer;
    return CO_OD_SPLIT;
}

static uint32_t split_check_write(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e,
                                  const uint8_t *value, uint32_t length, void *user)
{
    fx_t *fx = user;
    (void)od;
    (void)e;
    (void)value;
    (void)length;
    if (!fx->split_write)
        return 0;
    fx->held = xfer;
    return CO_OD_SPLIT;
}

static const co_od_handler_t split_handler = {
    .before_read = split_before_read,
    .check_write = split_check_write,
};

static const tu_od_row_t od_rows[] = {
    { 0x2000, 0, VAR, U8, RW, 0, 1, 0x11, NULL, 0, 0 },
    { 0x2001, 0, VAR, U16, RW, 0, 2, 0x2222, NULL, 0, 0 },
    { 0x2002, 0, VAR, U32, RW, 0, 4, 0x33333333, NULL, 0, 0 },
    { 0x2003, 0, VAR, U64, RW, 0, 8, 0x4444444444444444, NULL, 0, 0 },
    { 0x2004, 0, VAR, VS, RW, 0, 200, 0, "hello", 0, 0 },
    { 0x2005, 0, VAR, OS, RW, 0, 1000, 0, "", 0, 0 },
    { 0x2006, 0, VAR, U32, RO, 0, 4, 0xCAFEF00D, NULL, 0, 0 },
    { 0x2007, 0, VAR, U32, WO, 0, 4, 0x77, NULL, 0, 0 },
    { 0x2008, 0, VAR, U16, RW, MINMAX, 2, 50, NULL, 10, 100 },
    { 0x200A, 0, REC, U8, RO, 0, 1, 1, NULL, 0, 0 },
    { 0x200A, 1, REC, U32, RW, 0, 4, 0xA1, NULL, 0, 0 },
    { 0x200B, 0, VAR, U32, RW, 0, 4, 0xB0B0B0B0, NULL, 0, 0 },
};

static void build_od(fx_t *fx)
{
    co_od_def_t d;
    co_od_init(&fx->od, CO_MODE_FD, fx->entries, N_ENTRIES, fx->pool, POOL, fx->subs, SUBS);
    tu_od_add_rows(&fx->od, od_rows, sizeof od_rows / sizeof od_rows[0]);
    d = tu_od_def(0x2009, 0, VAR, DOM, RW, 0, 0);
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ADDED);
    d = tu_od_def(0x200C, 0, VAR, DOM, RW, 0, 0);
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ADDED);
    d = tu_od_def(0x200D, 0, VAR, DOM, WO, 0, 0);
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ADDED);
    assert_true(co_od_seal(&fx->od, ID_S));
    assert_true(co_od_subscribe(&fx->od, 0x2009, 0, 0x2009, 0, &dom_handler, fx));
    assert_true(co_od_subscribe(&fx->od, 0x200C, 0, 0x200C, 0, &dom_nosize_handler, fx));
    assert_true(co_od_subscribe(&fx->od, 0x200B, 0, 0x200B, 0, &split_handler, fx));
    assert_true(co_od_subscribe(&fx->od, 0x200D, 0, 0x200D, 0, &big_handler, fx));
}

static void server_init_paced(fx_t *fx, uint8_t sessions, uint32_t timeout_ms,
                              uint16_t bulk_pacing)
{
    co_usdo_server_config_t cfg;
    memset(&cfg, 0, sizeof cfg);
    cfg.sessions = fx->ses;
    cfg.session_count = sessions;
    cfg.scratch = fx->scratch;
    cfg.scratch_size = SCRATCH;
    cfg.timeout_ms = timeout_ms;
    cfg.bulk_pacing = bulk_pacing;
    assert_true(co_usdo_server_init(&fx->srv, fx->a, &fx->od, &cfg));
}

static void server_init(fx_t *fx, uint8_t sessions, uint32_t timeout_ms)
{
    server_init_paced(fx, sessions, timeout_ms, 0);
}

static int setup(void **state)
{
    uint32_t i;
    fx_t *fx = calloc(1, sizeof *fx);
    if (fx == NULL)
        return -1;
    tu_bus_init(&fx->tb, CO_MODE_FD, true);
    fx->a = tu_bus_add_line(&fx->tb, &fx->l[0]);
    fx->b = tu_bus_add_line(&fx->tb, &fx->l[1]);
    build_od(fx);
    assert_true(co_node_init(&fx->node, fx->a, ID_S, 0, NULL, NULL));
    fx->dom_len = 100;
    for (i = 0; i < DOM_CAP; i++)
        fx->domain[i] = (uint8_t)(i * 7u + 3u);
    server_init(fx, NSES, 0);
    tu_step(&fx->tb, MS(10));
    *state = fx;
    return 0;
}

static int teardown(void **state)
{
    free(*state);
    return 0;
}

/* ------------------------------------------------------------ helpers */

static void le_put32(uint8_t *p, uint32_t v) { tu_le_put(p, v, 4); }

/* Header of a request or response with the mux (sub-index, index). */
static void mux(uint8_t *b, uint8_t dest, uint8_t cs, uint8_t sid, uint16_t index, uint8_t sub)
{
    b[0] = dest;
    b[1] = cs;
    b[2] = sid;
    b[3] = sub;
    b[4] = (uint8_t)(index & 0xFF);
    b[5] = (uint8_t)(index >> 8);
}

/* Send a request from `client` (FD, BRS, length rounded up by the line) and
 * let the bus settle. Consumed log entries are dropped first. */
static void req(fx_t *fx, uint8_t client, const uint8_t *b, size_t n)
{
    if (fx->cursor == fx->tb.log_count) {
        tu_log_clear(&fx->tb);
        fx->cursor = 0;
    }
    assert_true(co_line_send(fx->b, 0x600u + client, b, n));
    tu_step(&fx->tb, fx->tb.now);
}

/* Send a frame exactly as given (any length, classic or FD). */
static void req_raw(fx_t *fx, uint32_t id, uint8_t flags, const uint8_t *b, uint8_t len)
{
    co_frame_t f = tu_frame(id, flags, b, len);
    if (fx->cursor == fx->tb.log_count) {
        tu_log_clear(&fx->tb);
        fx->cursor = 0;
    }
    assert_true(co_line_send_raw(fx->b, &f));
    tu_step(&fx->tb, fx->tb.now);
}

/* Next server frame in the log (requests are skipped), NULL when none. */
static const co_frame_t *next_rsp(fx_t *fx)
{
    while (fx->cursor < fx->tb.log_count) {
        const co_frame_t *f = &fx->tb.log[fx->cursor++].frame;
        if (f->id == RSP_ID)
            return f;
        if (f->id < 0x601u || f->id > 0x67Fu)
            fail_msg("unexpected frame 0x%03X", (unsigned)f->id);
    }
    return NULL;
}

/* The next server frame is exactly these n bytes (FD length, zero padding). */
static void expect(fx_t *fx, const uint8_t *b, size_t n)
{
    uint8_t padded[64];
    const co_frame_t *f = next_rsp(fx);
    if (f == NULL)
        fail_msg("no response");
    memset(padded, 0, sizeof padded);
    memcpy(padded, b, n);
    tu_assert_frame(f, RSP_ID, FDF, padded, co_fd_len_round(n));
}

static void expect_none(fx_t *fx)
{
    const co_frame_t *f = next_rsp(fx);
    if (f != NULL)
        fail_msg("unexpected response, command 0x%02X", f->data[1]);
}

static void expect_abort(fx_t *fx, uint8_t client, uint8_t sid, uint16_t index, uint8_t sub,
                         uint8_t code)
{
    uint8_t e[7];
    mux(e, client, ABORT, sid, index, sub);
    e[6] = code;
    expect(fx, e, 7);
}

static void expect_mux(fx_t *fx, uint8_t client, uint8_t cs, uint8_t sid, uint16_t index,
                       uint8_t sub)
{
    uint8_t e[6];
    mux(e, client, cs, sid, index, sub);
    expect(fx, e, 6);
}

/* ---- client operations (every response checked) */

static void send_exp_write(fx_t *fx, uint8_t client, uint8_t dest, uint8_t sid, uint16_t index,
                           uint8_t sub, uint8_t type, const uint8_t *data, uint8_t n)
{
    uint8_t b[64];
    mux(b, dest, DL_EXP, sid, index, sub);
    b[6] = type;
    b[7] = n;
    if (n > 0)
        memcpy(b + 8, data, n);
    req(fx, client, b, 8u + n);
}

static void exp_write_ok(fx_t *fx, uint8_t client, uint8_t sid, uint16_t index, uint8_t sub,
                         uint8_t type, const uint8_t *data, uint8_t n)
{
    send_exp_write(fx, client, ID_S, sid, index, sub, type, data, n);
    expect_mux(fx, client, 0x21, sid, index, sub);
    expect_none(fx);
}

static void send_upload(fx_t *fx, uint8_t client, uint8_t dest, uint8_t sid, uint16_t index,
                        uint8_t sub)
{
    uint8_t b[6];
    mux(b, dest, UL, sid, index, sub);
    req(fx, client, b, 6);
}

static void exp_read_ok(fx_t *fx, uint8_t client, uint8_t sid, uint16_t index, uint8_t sub,
                        uint8_t type, const uint8_t *data, uint8_t n)
{
    uint8_t e[64];
    send_upload(fx, client, ID_S, sid, index, sub);
    mux(e, client, 0x31, sid, index, sub);
    e[6] = type;
    e[7] = n;
    if (n > 0)
        memcpy(e + 8, data, n);
    expect(fx, e, 8u + n);
    expect_none(fx);
}

static void send_dl_init(fx_t *fx, uint8_t client, uint8_t sid, uint16_t index, uint8_t sub,
                         uint8_t type, uint32_t total)
{
    uint8_t b[12];
    mux(b, ID_S, DL_INIT, sid, index, sub);
    b[6] = type;
    b[7] = 0;
    le_put32(b + 8, total);
    req(fx, client, b, 12);
}

static void send_dl_seg(fx_t *fx, uint8_t client, uint8_t sid, uint8_t counter,
                        const uint8_t *data)
{
    uint8_t b[64];
    b[0] = ID_S;
    b[1] = DL_SEG;
    b[2] = sid;
    b[3] = counter;
    memcpy(b + 4, data, 60);
    req(fx, client, b, 64);
}

static void send_dl_last(fx_t *fx, uint8_t client, uint8_t sid, const uint8_t *data, uint8_t n)
{
    uint8_t b[64];
    b[0] = ID_S;
    b[1] = DL_LAST;
    b[2] = sid;
    b[3] = n;
    if (n > 0)
        memcpy(b + 4, data, n);
    req(fx, client, b, 4u + n);
}

static void expect_seg_ack(fx_t *fx, uint8_t client, uint8_t sid, uint8_t counter)
{
    uint8_t e[4] = { client, 0x23, sid, counter };
    expect(fx, e, 4);
}

static void expect_end_ack(fx_t *fx, uint8_t client, uint8_t sid)
{
    uint8_t e[3] = { client, 0x24, sid };
    expect(fx, e, 3);
}

/* Segmented download of `total` bytes, every response checked. */
static void seg_write_ok(fx_t *fx, uint8_t client, uint8_t sid, uint16_t index, uint8_t sub,
                         uint8_t type, const uint8_t *data, uint32_t total)
{
    uint32_t off = 0;
    unsigned k = 0;
    send_dl_init(fx, client, sid, index, sub, type, total);
    expect_mux(fx, client, 0x22, sid, index, sub);
    while (total - off > 60) {
        send_dl_seg(fx, client, sid, (uint8_t)k, data + off);
        expect_seg_ack(fx, client, sid, (uint8_t)k);
        off += 60;
        k++;
    }
    send_dl_last(fx, client, sid, data + off, (uint8_t)(total - off));
    expect_end_ack(fx, client, sid);
    expect_none(fx);
}

static void send_ul_seg(fx_t *fx, uint8_t client, uint8_t sid, uint8_t counter)
{
    uint8_t b[4] = { ID_S, UL_SEG, sid, counter };
    req(fx, client, b, 4);
}

/* Segmented upload expecting `size` in the initiate response (0xFFFFFFFF =
 * unknown) and exactly `data[total]`, every frame checked. */
static void seg_read_ok(fx_t *fx, uint8_t client, uint8_t sid, uint16_t index, uint8_t sub,
                        uint8_t type, const uint8_t *data, uint32_t total, uint32_t size)
{
    uint8_t e[64];
    uint32_t off = 0;
    unsigned k = 0;
    send_upload(fx, client, ID_S, sid, index, sub);
    mux(e, client, 0x32, sid, index, sub);
    e[6] = type;
    e[7] = 0;
    le_put32(e + 8, size);
    expect(fx, e, 12);
    for (;;) {
        send_ul_seg(fx, client, sid, (uint8_t)k);
        e[0] = client;
        e[2] = sid;
        if (total - off > 60) {
            e[1] = 0x33;
            e[3] = (uint8_t)k;
            memcpy(e + 4, data + off, 60);
            expect(fx, e, 64);
            off += 60;
            k++;
        } else {
            uint32_t n = total - off;
            e[1] = 0x34;
            e[3] = (uint8_t)n;
            if (n > 0)
                memcpy(e + 4, data + off, n);
            expect(fx, e, 4 + n);
            break;
        }
    }
    expect_none(fx);
}

/* ---- bulk download (0x06 / 0x07 / 0x08; answers 0x26, 0x28) */

static void send_bulk_init(fx_t *fx, uint8_t client, uint8_t sid, uint16_t index, uint8_t sub,
                           uint8_t type, uint32_t total)
{
    uint8_t b[12];
    mux(b, ID_S, BULK_INIT, sid, index, sub);
    b[6] = type;
    b[7] = 0;
    le_put32(b + 8, total);
    req(fx, client, b, 12);
}

static void send_bulk_seg(fx_t *fx, uint8_t client, uint8_t sid, uint8_t counter,
                          const uint8_t *data)
{
    uint8_t b[64];
    b[0] = ID_S;
    b[1] = BULK_SEG;
    b[2] = sid;
    b[3] = counter;
    memcpy(b + 4, data, 60);
    req(fx, client, b, 64);
}

static void send_bulk_last(fx_t *fx, uint8_t client, uint8_t sid, const uint8_t *data,
                           uint8_t n)
{
    uint8_t b[64];
    b[0] = ID_S;
    b[1] = BULK_LAST;
    b[2] = sid;
    b[3] = n;
    if (n > 0)
        memcpy(b + 4, data, n);
    req(fx, client, b, 4u + n);
}

/* 0x26: mux, then the pacing (100 us units) little-endian in bytes 6-7. */
static void expect_bulk_accept(fx_t *fx, uint8_t client, uint8_t sid, uint16_t index,
                               uint8_t sub, uint16_t pacing)
{
    uint8_t e[8];
    mux(e, client, 0x26, sid, index, sub);
    e[6] = (uint8_t)(pacing & 0xFF);
    e[7] = (uint8_t)(pacing >> 8);
    expect(fx, e, 8);
}

static void expect_bulk_end(fx_t *fx, uint8_t client, uint8_t sid)
{
    uint8_t e[3] = { client, 0x28, sid };
    expect(fx, e, 3);
}

/* n / 60 bulk segments of `data`, counters from `counter` on (wrapping),
 * none of them answered. Returns the counter after the last one. */
static uint8_t bulk_segs(fx_t *fx, uint8_t client, uint8_t sid, uint8_t counter,
                         const uint8_t *data, uint32_t n)
{
    uint32_t off;
    for (off = 0; off + 60 <= n; off += 60) {
        send_bulk_seg(fx, client, sid, counter, data + off);
        expect_none(fx);
        counter = (uint8_t)(counter + 1u);
    }
    return counter;
}

/* Bytes a bulk download of `total` bytes sends in full segments: the last
 * segment carries 1..60 bytes (0 only for an empty value). */
static uint32_t bulk_full_part(uint32_t total)
{
    return total == 0 ? 0 : (total - 1u) / 60u * 60u;
}

/* Bulk download of `total` bytes, every frame checked: 0x26 with `pacing`,
 * no answer to any segment, 0x28 at the end. */
static void bulk_write_ok(fx_t *fx, uint8_t client, uint8_t sid, uint16_t index, uint8_t sub,
                          uint8_t type, const uint8_t *data, uint32_t total, uint16_t pacing)
{
    uint32_t full = bulk_full_part(total);
    send_bulk_init(fx, client, sid, index, sub, type, total);
    expect_bulk_accept(fx, client, sid, index, sub, pacing);
    expect_none(fx);
    (void)bulk_segs(fx, client, sid, 0, data, full);
    send_bulk_last(fx, client, sid, data + full, (uint8_t)(total - full));
    expect_bulk_end(fx, client, sid);
    expect_none(fx);
}

/* ---- bulk upload (0x16 / 0x17; answers 0x36, 0x37, 0x38) */

static void send_bul_req(fx_t *fx, uint8_t client, uint8_t sid, uint16_t index, uint8_t sub,
                         uint8_t window)
{
    uint8_t b[8];
    mux(b, ID_S, BUL_REQ, sid, index, sub);
    b[6] = window;
    b[7] = 0;
    req(fx, client, b, 8);
}

static void send_bul_ack(fx_t *fx, uint8_t client, uint8_t sid, uint8_t counter)
{
    uint8_t b[4] = { ID_S, BUL_ACK, sid, counter };
    req(fx, client, b, 4);
}

/* 0x36: as 0x32, mux, type, 0, size LE. */
static void expect_bul_init(fx_t *fx, uint8_t client, uint8_t sid, uint16_t index, uint8_t sub,
                            uint8_t type, uint32_t size)
{
    uint8_t e[12];
    mux(e, client, BUL_INIT, sid, index, sub);
    e[6] = type;
    e[7] = 0;
    le_put32(e + 8, size);
    expect(fx, e, 12);
}

/* Bulk upload of `total` bytes with window `window`: 0x36 announcing
 * `size`, then at most `window` segments beyond those acknowledged (checked:
 * nothing more arrives), acknowledged in full windows; every byte checked. */
static void bulk_read_ok(fx_t *fx, uint8_t client, uint8_t sid, uint16_t index, uint8_t sub,
                         uint8_t type, const uint8_t *data, uint32_t total, uint32_t size,
                         uint8_t window)
{
    uint8_t e[64];
    uint32_t off = 0, k = 0, acked = 0;
    send_bul_req(fx, client, sid, index, sub, window);
    expect_bul_init(fx, client, sid, index, sub, type, size);
    for (;;) {
        while (k < acked + window) {
            e[0] = client;
            e[2] = sid;
            if (total - off > 60) {
                e[1] = BUL_SEG;
                e[3] = (uint8_t)k;
                memcpy(e + 4, data + off, 60);
                expect(fx, e, 64);
                off += 60;
                k++;
            } else {
                uint32_t n = total - off;
                e[1] = BUL_LAST;
                e[3] = (uint8_t)n;
                if (n > 0)
                    memcpy(e + 4, data + off, n);
                expect(fx, e, 4 + n);
                expect_none(fx);
                return;
            }
        }
        expect_none(fx);   /* the window is full: the server waits */
        send_bul_ack(fx, client, sid, (uint8_t)(k - 1u));
        acked = k;
    }
}

static void fill_pattern(uint8_t *p, uint32_t n, uint8_t seed)
{
    uint32_t i;
    for (i = 0; i < n; i++)
        p[i] = (uint8_t)(seed + i * 13u);
}

/* ---- OD checks */

static void snap(fx_t *fx)
{
    uint32_t i;
    memcpy(fx->pool_snap, fx->pool, POOL);
    for (i = 0; i < fx->od.count; i++)
        fx->len_snap[i] = fx->od.entries[i].length;
    memcpy(fx->dom_snap, fx->domain, DOM_CAP);
    fx->dom_len_snap = fx->dom_len;
}

static void assert_unchanged(const fx_t *fx)
{
    uint32_t i;
    assert_memory_equal(fx->pool_snap, fx->pool, POOL);
    for (i = 0; i < fx->od.count; i++)
        assert_int_equal(fx->len_snap[i], fx->od.entries[i].length);
    assert_int_equal(fx->dom_len_snap, fx->dom_len);
    assert_memory_equal(fx->dom_snap, fx->domain, DOM_CAP);
}

static uint32_t od_u32(const fx_t *fx, uint16_t index, uint8_t sub)
{
    uint32_t v = 0;
    assert_true(co_od_get_u32(&fx->od, index, sub, &v));
    return v;
}

static void assert_od_bytes(const fx_t *fx, uint16_t index, uint8_t sub, const uint8_t *data,
                            uint32_t n)
{
    static uint8_t buf[1000];
    uint32_t len = 0;
    assert_int_equal(co_od_get(&fx->od, index, sub, buf, sizeof buf, &len), 0);
    assert_int_equal(len, n);
    if (n > 0)
        assert_memory_equal(buf, data, n);
}

/* ================================================= codec */

/* Decode from a heap block of exactly len bytes (ASan sees any overrun). */
static co_usdo_decode_result_t decode_exact(const uint8_t *b, size_t len, co_usdo_msg_t *m)
{
    co_usdo_decode_result_t r;
    uint8_t *p = malloc(len > 0 ? len : 1);
    assert_non_null(p);
    if (len > 0)
        memcpy(p, b, len);
    r = co_usdo_decode(len > 0 ? p : NULL, len, m);
    if (r == CO_USDO_DECODE_OK && m->length > 0) {
        /* the data pointer lies inside the block */
        assert_true(m->data >= p && m->data + m->length <= p + len);
        m->data = b + (m->data - p);
    }
    free(p);
    return r;
}

static void test_codec_decode_each_layout(void **state)
{
    co_usdo_msg_t m;
    /* §2.13 example 1: expedited write of U32 0x12345678 to 0x2000:00 */
    const uint8_t exp[] = { 0x05, 0x01, 0x01, 0x00, 0x00, 0x20, 0x07, 0x04,
                            0x78, 0x56, 0x34, 0x12 };
    const uint8_t up[] = { 0x05, 0x11, 0x02, 0x01, 0x18, 0x10 };
    const uint8_t init[] = { 0x05, 0x02, 0x05, 0x00, 0x10, 0x20, 0x0F, 0x00,
                             0x64, 0x00, 0x00, 0x00 };
    uint8_t seg[64], last[48];
    const uint8_t ctr[] = { 0x05, 0x13, 0x07, 0x2A };
    const uint8_t end[] = { 0x01, 0x24, 0x05 };
    const uint8_t ab[] = { 0x01, 0x7F, 0x03, 0x00, 0x00, 0x21, 0x33 };
    (void)state;

    assert_int_equal(decode_exact(exp, sizeof exp, &m), CO_USDO_DECODE_OK);
    assert_int_equal(m.dest, 5);
    assert_int_equal(m.cs, 0x01);
    assert_int_equal(m.session, 1);
    assert_int_equal(m.sub, 0);
    assert_int_equal(m.index, 0x2000);
    assert_int_equal(m.type, 0x07);
    assert_int_equal(m.length, 4);
    assert_memory_equal(m.data, exp + 8, 4);

    assert_int_equal(decode_exact(up, sizeof up, &m), CO_USDO_DECODE_OK);
    assert_int_equal(m.cs, 0x11);
    assert_int_equal(m.session, 2);
    assert_int_equal(m.sub, 1);
    assert_int_equal(m.index, 0x1018);
    assert_int_equal(m.length, 0);

    assert_int_equal(decode_exact(init, sizeof init, &m), CO_USDO_DECODE_OK);
    assert_int_equal(m.cs, 0x02);
    assert_int_equal(m.index, 0x2010);
    assert_int_equal(m.type, 0x0F);
    assert_int_equal(m.size, 100);

    seg[0] = 5;
    seg[1] = 0x03;
    seg[2] = 5;
    seg[3] = 0xFE;
    fill_pattern(seg + 4, 60, 1);
    assert_int_equal(decode_exact(seg, 64, &m), CO_USDO_DECODE_OK);
    assert_int_equal(m.counter, 0xFE);
    assert_int_equal(m.length, 60);
    assert_memory_equal(m.data, seg + 4, 60);

    /* §2.13 example 5, last segment: 44 bytes sent as 48 (4 fill bytes) */
    memset(last, 0, sizeof last);
    last[0] = 5;
    last[1] = 0x04;
    last[2] = 5;
    last[3] = 0x28;
    fill_pattern(last + 4, 40, 9);
    assert_int_equal(decode_exact(last, 48, &m), CO_USDO_DECODE_OK);
    assert_int_equal(m.length, 40);
    assert_memory_equal(m.data, last + 4, 40);
    assert_int_equal(m.sub, 0);
    assert_int_equal(m.index, 0);

    assert_int_equal(decode_exact(ctr, sizeof ctr, &m), CO_USDO_DECODE_OK);
    assert_int_equal(m.cs, 0x13);
    assert_int_equal(m.session, 7);
    assert_int_equal(m.counter, 0x2A);

    assert_int_equal(decode_exact(end, sizeof end, &m), CO_USDO_DECODE_OK);
    assert_int_equal(m.dest, 1);
    assert_int_equal(m.cs, 0x24);
    assert_int_equal(m.session, 5);

    assert_int_equal(decode_exact(ab, sizeof ab, &m), CO_USDO_DECODE_OK);
    assert_int_equal(m.cs, 0x7F);
    assert_int_equal(m.session, 3);
    assert_int_equal(m.index, 0x2100);
    assert_int_equal(m.abort_code, 0x33);
}

static void test_codec_layout_of_every_command(void **state)
{
    unsigned cs;
    (void)state;
    for (cs = 0; cs < 256; cs++) {
        co_usdo_layout_t l = co_usdo_layout_of((uint8_t)cs);
        co_usdo_layout_t want = CO_USDO_LAYOUT_UNKNOWN;
        switch (cs) {
        case 0x11: case 0x21: case 0x22: want = CO_USDO_LAYOUT_MUX; break;
        case 0x01: case 0x31: want = CO_USDO_LAYOUT_EXPEDITED; break;
        case 0x02: case 0x32: case 0x06: case 0x36: want = CO_USDO_LAYOUT_INITIATE; break;
        case 0x03: case 0x33: case 0x07: case 0x37: want = CO_USDO_LAYOUT_SEGMENT; break;
        case 0x04: case 0x34: case 0x08: case 0x38: want = CO_USDO_LAYOUT_LAST; break;
        case 0x13: case 0x23: case 0x17: want = CO_USDO_LAYOUT_COUNTER; break;
        case 0x24: case 0x28: want = CO_USDO_LAYOUT_END; break;
        case 0x26: want = CO_USDO_LAYOUT_BULK_ACCEPT; break;
        case 0x16: want = CO_USDO_LAYOUT_BULK_REQUEST; break;
        case 0x7F: want = CO_USDO_LAYOUT_ABORT; break;
        default: break;
        }
        if (l != want)
            fail_msg("cs 0x%02X: layout %d, expected %d", cs, (int)l, (int)want);
    }
}

static size_t enc(uint8_t cs, uint8_t dest, uint8_t sid, uint16_t index, uint8_t sub,
                  uint8_t type, uint8_t counter, uint32_t size, const uint8_t *data,
                  uint8_t length, uint8_t code, uint8_t *out)
{
    co_usdo_msg_t m;
    memset(&m, 0, sizeof m);
    m.cs = cs;
    m.dest = dest;
    m.session = sid;
    m.index = index;
    m.sub = sub;
    m.type = type;
    m.counter = counter;
    m.size = size;
    m.data = data;
    m.length = length;
    m.abort_code = code;
    return co_usdo_encode(&m, out);
}

static void assert_encoded(const uint8_t *out, size_t n, const uint8_t *want, size_t want_n)
{
    uint8_t full[64];
    assert_int_equal(n, want_n);
    memset(full, 0, sizeof full);
    memcpy(full, want, want_n);
    assert_memory_equal(out, full, 64);   /* the rest of the buffer is 0 */
}

static void test_codec_encode_each_response(void **state)
{
    uint8_t out[64], data[60], want[64];
    const uint8_t r21[] = { 0x01, 0x21, 0x01, 0x00, 0x00, 0x20 };
    const uint8_t r22[] = { 0x01, 0x22, 0x05, 0x00, 0x10, 0x20 };
    const uint8_t r23[] = { 0x01, 0x23, 0x05, 0x00 };
    const uint8_t r24[] = { 0x01, 0x24, 0x05 };
    const uint8_t r31[] = { 0x01, 0x31, 0x02, 0x01, 0x18, 0x10, 0x07, 0x04,
                            0xAA, 0xBB, 0xCC, 0xDD };
    const uint8_t r32[] = { 0x01, 0x32, 0x09, 0x03, 0x04, 0x20, 0x09, 0x00,
                            0x78, 0x56, 0x34, 0x12 };
    const uint8_t r7f[] = { 0x01, 0x7F, 0x03, 0x00, 0x00, 0x21, 0x33 };
    (void)state;
    fill_pattern(data, 60, 0x40);

    assert_encoded(out, enc(0x21, 1, 1, 0x2000, 0, 0, 0, 0, NULL, 0, 0, out), r21, 6);
    assert_encoded(out, enc(0x22, 1, 5, 0x2010, 0, 0, 0, 0, NULL, 0, 0, out), r22, 6);
    assert_encoded(out, enc(0x23, 1, 5, 0, 0, 0, 0, 0, NULL, 0, 0, out), r23, 4);
    assert_encoded(out, enc(0x24, 1, 5, 0, 0, 0, 0, 0, NULL, 0, 0, out), r24, 3);
    assert_encoded(out, enc(0x31, 1, 2, 0x1018, 1, 7, 0, 0, r31 + 8, 4, 0, out), r31, 12);
    assert_encoded(out, enc(0x32, 1, 9, 0x2004, 3, 9, 0, 0x12345678, NULL, 0, 0, out), r32, 12);
    assert_encoded(out, enc(0x7F, 1, 3, 0x2100, 0, 0, 0, 0, NULL, 0, 0x33, out), r7f, 7);

    want[0] = 1;
    want[1] = 0x33;
    want[2] = 4;
    want[3] = 0x99;
    memcpy(want + 4, data, 60);
    assert_encoded(out, enc(0x33, 1, 4, 0, 0, 0, 0x99, 0, data, 60, 0, out), want, 64);
    want[1] = 0x34;
    want[3] = 17;
    assert_encoded(out, enc(0x34, 1, 4, 0, 0, 0, 0, 0, data, 17, 0, out), want, 21);
    want[3] = 0;
    assert_encoded(out, enc(0x34, 1, 4, 0, 0, 0, 0, 0, NULL, 0, 0, out), want, 4);
    /* expedited with 56 bytes: 64 */
    mux(want, 1, 0x31, 4, 0x2004, 0);
    want[6] = 9;
    want[7] = 56;
    memcpy(want + 8, data, 56);
    assert_encoded(out, enc(0x31, 1, 4, 0x2004, 0, 9, 0, 0, data, 56, 0, out), want, 64);
}

static void test_codec_encode_refuses_what_does_not_fit(void **state)
{
    uint8_t out[64], data[64];
    static const uint8_t zero[64];
    (void)state;
    memset(data, 0xEE, sizeof data);
    assert_int_equal(enc(0x31, 1, 1, 0x2000, 0, 7, 0, 0, data, 57, 0, out), 0);
    assert_memory_equal(out, zero, 64);
    assert_int_equal(enc(0x33, 1, 1, 0, 0, 0, 0, 0, data, 59, 0, out), 0);
    assert_int_equal(enc(0x33, 1, 1, 0, 0, 0, 0, 0, NULL, 60, 0, out), 0);
    assert_int_equal(enc(0x34, 1, 1, 0, 0, 0, 0, 0, data, 61, 0, out), 0);
    assert_int_equal(enc(0x34, 1, 1, 0, 0, 0, 0, 0, NULL, 1, 0, out), 0);
    assert_int_equal(enc(0x31, 1, 1, 0, 0, 0, 0, 0, NULL, 1, 0, out), 0);
    /* bulk segments: exactly 60 bytes, last 0..60 with data */
    assert_int_equal(enc(0x07, 1, 1, 0, 0, 0, 0, 0, data, 59, 0, out), 0);
    assert_int_equal(enc(0x07, 1, 1, 0, 0, 0, 0, 0, NULL, 60, 0, out), 0);
    assert_int_equal(enc(0x08, 1, 1, 0, 0, 0, 0, 0, data, 61, 0, out), 0);
    assert_int_equal(enc(0x08, 1, 1, 0, 0, 0, 0, 0, NULL, 1, 0, out), 0);
    /* no layout: multiple sub-indices, remote, reserved */
    assert_int_equal(enc(0x05, 1, 1, 0, 0, 0, 0, 0, NULL, 0, 0, out), 0);
    assert_int_equal(enc(0x15, 1, 1, 0, 0, 0, 0, 0, NULL, 0, 0, out), 0);
    assert_int_equal(enc(0x81, 1, 1, 0, 0, 0, 0, 0, NULL, 0, 0, out), 0);
    assert_int_equal(enc(0x91, 1, 1, 0, 0, 0, 0, 0, NULL, 0, 0, out), 0);
    assert_int_equal(enc(0x86, 1, 1, 0, 0, 0, 0, 0, NULL, 0, 0, out), 0);
    assert_int_equal(enc(0x18, 1, 1, 0, 0, 0, 0, 0, NULL, 0, 0, out), 0);
    /* bulk upload segments: exactly 60 bytes too (we never send a short one) */
    assert_int_equal(enc(0x37, 1, 1, 0, 0, 0, 0, 0, data, 59, 0, out), 0);
    assert_int_equal(enc(0x38, 1, 1, 0, 0, 0, 0, 0, data, 61, 0, out), 0);
    assert_int_equal(enc(0xFF, 1, 1, 0, 0, 0, 0, 0, NULL, 0, 0, out), 0);
    assert_memory_equal(out, zero, 64);
}

static void test_codec_decode_refuses_bad_lengths_and_commands(void **state)
{
    co_usdo_msg_t m;
    uint8_t b[64];
    (void)state;
    memset(b, 0, sizeof b);
    /* expedited N = 57 */
    mux(b, 5, 0x01, 1, 0x2000, 0);
    b[6] = 7;
    b[7] = 57;
    assert_int_equal(decode_exact(b, 64, &m), CO_USDO_DECODE_BAD_LENGTH);
    /* expedited N = 8 in a 12-byte frame */
    b[7] = 8;
    assert_int_equal(decode_exact(b, 12, &m), CO_USDO_DECODE_SHORT);
    assert_int_equal(m.index, 0x2000);   /* the mux is still there for the abort */
    assert_int_equal(decode_exact(b, 16, &m), CO_USDO_DECODE_OK);
    /* last segment n = 61 */
    b[1] = 0x04;
    b[3] = 61;
    assert_int_equal(decode_exact(b, 64, &m), CO_USDO_DECODE_BAD_LENGTH);
    b[3] = 60;
    assert_int_equal(decode_exact(b, 64, &m), CO_USDO_DECODE_OK);
    assert_int_equal(decode_exact(b, 48, &m), CO_USDO_DECODE_SHORT);
    /* a segment of fewer than 64 bytes carries the rest of the frame (a
     * sender with a smaller MTU); it needs one data byte at least */
    b[1] = 0x03;
    b[3] = 9;
    assert_int_equal(decode_exact(b, 48, &m), CO_USDO_DECODE_OK);
    assert_int_equal(m.length, 44);
    assert_int_equal(m.counter, 9);
    assert_true(co_usdo_short_segment(&m));
    assert_int_equal(decode_exact(b, 5, &m), CO_USDO_DECODE_OK);
    assert_int_equal(m.length, 1);
    assert_int_equal(decode_exact(b, 4, &m), CO_USDO_DECODE_SHORT);
    assert_int_equal(m.counter, 9);
    assert_int_equal(decode_exact(b, 64, &m), CO_USDO_DECODE_OK);
    assert_false(co_usdo_short_segment(&m));
    /* bulk: the same for bulk segments (both directions), a bulk last n <= 60 */
    b[1] = 0x07;
    assert_int_equal(decode_exact(b, 48, &m), CO_USDO_DECODE_OK);
    assert_int_equal(m.length, 44);
    assert_int_equal(decode_exact(b, 4, &m), CO_USDO_DECODE_SHORT);
    b[1] = 0x37;
    assert_int_equal(decode_exact(b, 20, &m), CO_USDO_DECODE_OK);
    assert_int_equal(m.length, 16);
    assert_int_equal(decode_exact(b, 4, &m), CO_USDO_DECODE_SHORT);
    b[1] = 0x38;
    b[3] = 61;
    assert_int_equal(decode_exact(b, 64, &m), CO_USDO_DECODE_BAD_LENGTH);
    b[1] = 0x08;
    b[3] = 61;
    assert_int_equal(decode_exact(b, 64, &m), CO_USDO_DECODE_BAD_LENGTH);
    /* unknown commands: multiple sub-indices, remote, anything else */
    mux(b, 5, 0x05, 1, 0x2000, 0);
    assert_int_equal(decode_exact(b, 64, &m), CO_USDO_DECODE_UNKNOWN_CS);
    assert_int_equal(m.dest, 5);
    assert_int_equal(m.cs, 0x05);
    assert_int_equal(m.session, 1);
    assert_int_equal(m.index, 0);   /* no layout: the mux is not read */
    b[1] = 0x15;
    assert_int_equal(decode_exact(b, 64, &m), CO_USDO_DECODE_UNKNOWN_CS);
    /* remote (routed) frames decode as their local layout, flagged remote
     * (their bytes: tests/c/test_gateway_usdo.c); 0x85 has no local layout */
    b[1] = 0x91;
    assert_int_equal(decode_exact(b, 64, &m), CO_USDO_DECODE_OK);
    assert_true(m.remote);
    assert_int_equal(m.cs, 0x11);
    b[1] = 0x85;
    assert_int_equal(decode_exact(b, 64, &m), CO_USDO_DECODE_UNKNOWN_CS);
    assert_true(m.remote);
    b[1] = 0x81;
    /* fewer than 3 bytes */
    assert_int_equal(decode_exact(b, 2, &m), CO_USDO_DECODE_EMPTY);
    assert_int_equal(m.dest, 5);
    assert_int_equal(m.cs, 0x81);
    assert_int_equal(decode_exact(b, 0, &m), CO_USDO_DECODE_EMPTY);
}

/* Every proper prefix of every valid frame is refused, and read only within
 * its length. */
/* The bulk frames: exact bytes both ways, and every truncation refused. */
static void test_codec_bulk_frames(void **state)
{
    co_usdo_msg_t m;
    uint8_t out[64], seg[64], last[64];
    /* 0x06: as 0x02 (12 bytes), size 0x0010002D */
    const uint8_t init[] = { 0x05, 0x06, 0x09, 0x00, 0x0D, 0x20, 0x0F, 0x00,
                             0x2D, 0x00, 0x10, 0x00 };
    /* 0x26: mux, pacing 0x1234 little-endian (8 bytes) */
    const uint8_t acc[] = { 0x01, 0x26, 0x09, 0x02, 0x0A, 0x20, 0x34, 0x12 };
    const uint8_t end[] = { 0x01, 0x28, 0x09 };
    struct {
        const uint8_t *b;
        size_t n;
    } frames[5];
    size_t i, len;
    (void)state;

    assert_int_equal(decode_exact(init, sizeof init, &m), CO_USDO_DECODE_OK);
    assert_int_equal(m.dest, 5);
    assert_int_equal(m.cs, 0x06);
    assert_int_equal(m.session, 9);
    assert_int_equal(m.sub, 0);
    assert_int_equal(m.index, 0x200D);
    assert_int_equal(m.type, 0x0F);
    assert_int_equal(m.size, 0x0010002Du);
    assert_int_equal(m.length, 0);
    assert_int_equal(m.pacing, 0);
    assert_encoded(out, co_usdo_encode(&m, out), init, sizeof init);

    assert_int_equal(decode_exact(acc, sizeof acc, &m), CO_USDO_DECODE_OK);
    assert_int_equal(m.dest, 1);
    assert_int_equal(m.cs, 0x26);
    assert_int_equal(m.session, 9);
    assert_int_equal(m.sub, 2);
    assert_int_equal(m.index, 0x200A);
    assert_int_equal(m.pacing, 0x1234);
    assert_int_equal(m.size, 0);
    memset(&m, 0, sizeof m);
    m.dest = 1;
    m.cs = 0x26;
    m.session = 9;
    m.sub = 2;
    m.index = 0x200A;
    m.pacing = 0x1234;
    assert_encoded(out, co_usdo_encode(&m, out), acc, sizeof acc);
    m.pacing = 0xFFFF;
    assert_int_equal(co_usdo_encode(&m, out), 8);
    assert_int_equal(out[6], 0xFF);
    assert_int_equal(out[7], 0xFF);
    m.pacing = 0;
    assert_int_equal(co_usdo_encode(&m, out), 8);
    assert_int_equal(out[6], 0);
    assert_int_equal(out[7], 0);

    /* 0x07: as 0x03 (64 bytes), counter 0xFF */
    seg[0] = 5;
    seg[1] = 0x07;
    seg[2] = 9;
    seg[3] = 0xFF;
    fill_pattern(seg + 4, 60, 0x31);
    assert_int_equal(decode_exact(seg, 64, &m), CO_USDO_DECODE_OK);
    assert_int_equal(m.cs, 0x07);
    assert_int_equal(m.session, 9);
    assert_int_equal(m.counter, 0xFF);
    assert_int_equal(m.length, 60);
    assert_memory_equal(m.data, seg + 4, 60);
    assert_int_equal(m.index, 0);
    assert_encoded(out, co_usdo_encode(&m, out), seg, 64);

    /* 0x08: as 0x04 (4 + n bytes), n = 17, 0 and 60 */
    memset(last, 0, sizeof last);
    last[0] = 5;
    last[1] = 0x08;
    last[2] = 9;
    last[3] = 17;
    fill_pattern(last + 4, 60, 0x52);
    assert_int_equal(decode_exact(last, 21, &m), CO_USDO_DECODE_OK);
    assert_int_equal(m.cs, 0x08);
    assert_int_equal(m.length, 17);
    assert_memory_equal(m.data, last + 4, 17);
    assert_encoded(out, co_usdo_encode(&m, out), last, 21);
    last[3] = 60;
    assert_int_equal(decode_exact(last, 64, &m), CO_USDO_DECODE_OK);
    assert_encoded(out, co_usdo_encode(&m, out), last, 64);
    last[3] = 0;
    assert_int_equal(decode_exact(last, 4, &m), CO_USDO_DECODE_OK);
    assert_int_equal(m.length, 0);
    assert_int_equal(co_usdo_encode(&m, out), 4);
    /* n > 60, n beyond the frame */
    last[3] = 61;
    assert_int_equal(decode_exact(last, 64, &m), CO_USDO_DECODE_BAD_LENGTH);
    last[3] = 40;
    assert_int_equal(decode_exact(last, 32, &m), CO_USDO_DECODE_SHORT);
    last[3] = 17;

    /* 0x28: as 0x24 (3 bytes) */
    assert_int_equal(decode_exact(end, sizeof end, &m), CO_USDO_DECODE_OK);
    assert_int_equal(m.dest, 1);
    assert_int_equal(m.cs, 0x28);
    assert_int_equal(m.session, 9);
    assert_encoded(out, co_usdo_encode(&m, out), end, sizeof end);

    /* every short frame of each: no session-ID below 3 bytes, else too short */
    frames[0].b = init;
    frames[0].n = sizeof init;
    frames[1].b = acc;
    frames[1].n = sizeof acc;
    frames[2].b = seg;
    frames[2].n = 64;
    frames[3].b = last;
    frames[3].n = 21;
    frames[4].b = end;
    frames[4].n = sizeof end;
    for (i = 0; i < 5; i++) {
        for (len = 0; len < frames[i].n; len++) {
            co_usdo_decode_result_t r = decode_exact(frames[i].b, len, &m);
            if (i == 2 && len >= 5) {   /* a short segment: len - 4 data bytes */
                assert_int_equal(r, CO_USDO_DECODE_OK);
                assert_int_equal(m.length, len - 4);
                continue;
            }
            assert_int_equal(r, len < 3 ? CO_USDO_DECODE_EMPTY : CO_USDO_DECODE_SHORT);
            if (len >= 3)
                assert_int_equal(m.cs, frames[i].b[1]);
        }
    }
    /* the mux is read where the layout has one, even from a short frame */
    assert_int_equal(decode_exact(acc, 7, &m), CO_USDO_DECODE_SHORT);
    assert_int_equal(m.index, 0x200A);
    assert_int_equal(m.sub, 2);
    assert_true(co_usdo_layout_has_mux(co_usdo_layout_of(0x06)));
    assert_true(co_usdo_layout_has_mux(co_usdo_layout_of(0x26)));
    assert_false(co_usdo_layout_has_mux(co_usdo_layout_of(0x07)));
    assert_false(co_usdo_layout_has_mux(co_usdo_layout_of(0x08)));
    assert_false(co_usdo_layout_has_mux(co_usdo_layout_of(0x28)));
}

static void test_codec_every_truncation_refused(void **state)
{
    static const uint8_t cmds[] = { 0x01, 0x02, 0x03, 0x04, 0x06, 0x07, 0x08, 0x11,
                                    0x13, 0x16, 0x17, 0x21, 0x22, 0x23, 0x24, 0x26,
                                    0x28, 0x31, 0x32, 0x33, 0x34, 0x36, 0x37, 0x38,
                                    0x7F };
    uint8_t data[60], buf[64];
    size_t i, len;
    (void)state;
    fill_pattern(data, 60, 0x11);
    for (i = 0; i < sizeof cmds; i++) {
        bool segment = co_usdo_layout_of(cmds[i]) == CO_USDO_LAYOUT_SEGMENT;
        uint8_t dlen = (uint8_t)(segment ? 60 : 23);
        size_t n = enc(cmds[i], 5, 1, 0x2004, 2, 9, 3, 1000, data, dlen, 0x33, buf);
        co_usdo_msg_t m;
        assert_true(n >= 3);
        assert_int_equal(decode_exact(buf, n, &m), CO_USDO_DECODE_OK);
        /* a segment cut after 5+ bytes is a short segment, taken (other tests) */
        for (len = 0; len < (segment ? 5u : n); len++) {
            co_usdo_decode_result_t r = decode_exact(buf, len, &m);
            assert_int_equal(r, len < 3 ? CO_USDO_DECODE_EMPTY : CO_USDO_DECODE_SHORT);
        }
    }
}

/* Random input: never reads outside, and a frame that decodes encodes back
 * to the same bytes (the reserved byte 7 of initiate frames aside). */
static void test_codec_random_input(void **state)
{
    uint64_t seed = 0xC0DEC0DE12345ull;
    static const uint8_t cmds[] = { 0x01, 0x02, 0x03, 0x04, 0x06, 0x07, 0x08, 0x11,
                                    0x13, 0x16, 0x17, 0x21, 0x22, 0x23, 0x24, 0x26,
                                    0x28, 0x31, 0x32, 0x33, 0x34, 0x36, 0x37, 0x38,
                                    0x7F };
    unsigned i, ok = 0;
    (void)state;
    for (i = 0; i < 200000; i++) {
        uint8_t b[64], out[64];
        co_usdo_msg_t m;
        size_t len = (size_t)(tu_rand(&seed) % 65), k;
        for (k = 0; k < len; k++)
            b[k] = (uint8_t)tu_rand(&seed);
        if (len > 1 && (tu_rand(&seed) & 1))
            b[1] = cmds[tu_rand(&seed) % sizeof cmds];
        if (len > 7 && b[1] == 0x01 && (tu_rand(&seed) & 1))
            b[7] = (uint8_t)(tu_rand(&seed) % 60);
        if (len > 3 && (b[1] == 0x04 || b[1] == 0x08 || b[1] == 0x38) && (tu_rand(&seed) & 1))
            b[3] = (uint8_t)(tu_rand(&seed) % 64);
        if (decode_exact(b, len, &m) == CO_USDO_DECODE_OK) {
            size_t n = co_usdo_encode(&m, out);
            ok++;
            if (co_usdo_layout_of(m.cs) == CO_USDO_LAYOUT_SEGMENT && co_usdo_short_segment(&m)) {
                assert_int_equal(n, 0);   /* taken, but never sent that way */
                assert_int_equal(m.length, len - 4);
                continue;
            }
            assert_true(n >= 3 && n <= len);
            if (m.cs == 0x02 || m.cs == 0x32 || m.cs == 0x06 || m.cs == 0x36 || m.cs == 0x16) {
                size_t reserved = m.remote ? 11 : 7;   /* behind the routed extension */
                assert_int_equal(out[reserved], 0);
                out[reserved] = b[reserved];
            }
            assert_memory_equal(out, b, n);
        }
    }
    assert_true(ok > 10000);
}

static void test_codec_abort_mapping(void **state)
{
    static const struct {
        uint32_t co;
        uint8_t usdo;
        bool back;
    } map[] = {
        { CO_ABORT_GENERAL, 0x10, true },
        { CO_ABORT_TIMEOUT, 0x12, true },
        { CO_ABORT_COMMAND, 0x13, true },
        { CO_ABORT_TOGGLE, 0x14, true },
        { CO_ABORT_SEQUENCE, 0x14, false },
        { CO_ABORT_BLOCK_SIZE, 0x11, false },
        { CO_ABORT_CRC, 0x11, false },
        { CO_ABORT_OUT_OF_MEMORY, 0x16, true },
        { CO_ABORT_UNSUPPORTED_ACCESS, 0x30, true },
        { CO_ABORT_WRITE_ONLY, 0x31, true },
        { CO_ABORT_READ_ONLY, 0x32, true },
        { CO_ABORT_NO_OBJECT, 0x33, true },
        { CO_ABORT_NO_MAP, 0x50, true },
        { CO_ABORT_MAP_LENGTH, 0x51, true },
        { CO_ABORT_PARAM_INCOMPATIBLE, 0x17, true },
        { CO_ABORT_DEVICE_INCOMPATIBLE, 0x18, true },
        { CO_ABORT_HARDWARE, 0x35, true },
        { CO_ABORT_TYPE_MISMATCH, 0x36, true },
        { CO_ABORT_LENGTH_HIGH, 0x37, true },
        { CO_ABORT_LENGTH_LOW, 0x38, true },
        { CO_ABORT_NO_SUB, 0x34, true },
        { CO_ABORT_INVALID_VALUE, 0x40, true },
        { CO_ABORT_VALUE_HIGH, 0x41, true },
        { CO_ABORT_VALUE_LOW, 0x42, true },
        { CO_ABORT_MAX_LESS_MIN, 0x43, true },
        { CO_ABORT_NO_RESOURCE, 0x70, true },
        { CO_ABORT_DATA_STORE, 0x60, true },
        { CO_ABORT_DATA_LOCAL, 0x61, true },
        { CO_ABORT_DATA_STATE, 0x62, true },
        { CO_ABORT_NO_OD, 0x63, true },
        { CO_ABORT_NO_DATA, 0x64, true },
    };
    size_t i;
    unsigned code;
    (void)state;
    /* every co_abort_t value is covered above (31 of them besides NONE) */
    assert_int_equal(sizeof map / sizeof map[0], 31);
    for (i = 0; i < sizeof map / sizeof map[0]; i++) {
        if (co_usdo_abort_from_co(map[i].co) != map[i].usdo)
            fail_msg("0x%08X -> 0x%02X, expected 0x%02X", (unsigned)map[i].co,
                     co_usdo_abort_from_co(map[i].co), map[i].usdo);
        if (map[i].back)
            assert_int_equal(co_usdo_abort_to_co(map[i].usdo), map[i].co);
    }
    assert_int_equal(co_usdo_abort_from_co(0), 0);
    assert_int_equal(co_usdo_abort_to_co(0), 0);
    assert_int_equal(co_usdo_abort_from_co(0x12345678u), 0x10);
    assert_int_equal(co_usdo_abort_from_co(CO_OD_SPLIT), 0x10);
    /* USDO-only codes */
    assert_int_equal(co_usdo_abort_to_co(0x15), CO_ABORT_TYPE_MISMATCH);
    assert_int_equal(co_usdo_abort_to_co(0x44), CO_ABORT_MAX_LESS_MIN);
    assert_int_equal(co_usdo_abort_to_co(0x11), CO_ABORT_GENERAL);
    assert_int_equal(co_usdo_abort_to_co(0x1E), CO_ABORT_GENERAL);
    assert_int_equal(co_usdo_abort_to_co(0x20), CO_ABORT_GENERAL);
    assert_int_equal(co_usdo_abort_to_co(0x21), CO_ABORT_GENERAL);
    assert_int_equal(co_usdo_abort_to_co(0xC0), CO_ABORT_GENERAL);
    /* every one-byte code maps to some CiA 301 code and back to a code */
    for (code = 1; code < 256; code++) {
        uint32_t co = co_usdo_abort_to_co((uint8_t)code);
        assert_true(co != 0);
        assert_true(co_usdo_abort_from_co(co) != 0);
    }
    assert_int_equal(co_usdo_next_counter(0xFF), 0);
    assert_int_equal(co_usdo_next_counter(0x00), 1);
}

/* ================================================= server: setup */

static void test_init_refuses_classic_line_and_bad_config(void **state)
{
    fx_t *fx = *state;
    tu_line_t classic;
    co_usdo_server_t other;
    co_usdo_session_t ses[1];
    co_usdo_server_config_t cfg;
    memset(&cfg, 0, sizeof cfg);
    cfg.sessions = ses;
    cfg.session_count = 1;
    tu_line_init(&classic, CO_MODE_CLASSIC, false);
    assert_false(co_usdo_server_init(&other, &classic.line, &fx->od, &cfg));
    /* 0x601..0x67F already taken by fx->srv */
    assert_false(co_usdo_server_init(&other, fx->a, &fx->od, &cfg));
    cfg.session_count = 0;
    assert_false(co_usdo_server_init(&other, fx->b, &fx->od, &cfg));
    cfg.session_count = 1;
    cfg.scratch_size = 10;   /* size without a buffer */
    assert_false(co_usdo_server_init(&other, fx->b, &fx->od, &cfg));
    assert_int_equal(co_usdo_server_scratch_need(&fx->od), 1000);
}

static void test_default_timeout_is_one_second(void **state)
{
    fx_t *fx = *state;
    assert_int_equal(fx->srv.timeout_us, MS(1000));
    assert_int_equal(fx->srv.session_count, NSES);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
}

/* ================================================= expedited */

/* §2.13 example 1 (on 0x2002), example 2 (read), example 3 (no object). */
static void test_derived_example_frames(void **state)
{
    fx_t *fx = *state;
    const uint8_t w[] = { 0x05, 0x01, 0x01, 0x00, 0x02, 0x20, 0x07, 0x04,
                          0x78, 0x56, 0x34, 0x12 };
    const uint8_t w_rsp[] = { 0x01, 0x21, 0x01, 0x00, 0x02, 0x20 };
    const uint8_t r[] = { 0x05, 0x11, 0x02, 0x00, 0x02, 0x20 };
    const uint8_t r_rsp[] = { 0x01, 0x31, 0x02, 0x00, 0x02, 0x20, 0x07, 0x04,
                              0x78, 0x56, 0x34, 0x12 };
    const uint8_t x[] = { 0x05, 0x11, 0x03, 0x00, 0x00, 0x21 };
    const uint8_t x_rsp[] = { 0x01, 0x7F, 0x03, 0x00, 0x00, 0x21, 0x33 };
    req(fx, C1, w, sizeof w);
    expect(fx, w_rsp, sizeof w_rsp);
    assert_int_equal(od_u32(fx, 0x2002, 0), 0x12345678u);
    req(fx, C1, r, sizeof r);
    expect(fx, r_rsp, sizeof r_rsp);
    req(fx, C1, x, sizeof x);
    expect(fx, x_rsp, sizeof x_rsp);
    expect_none(fx);
    /* the 6-byte and 7-byte frames are sent as they are, 12 stays 12 */
    assert_int_equal(fx->tb.log[fx->cursor - 1].frame.len, 7);
    assert_int_equal(fx->srv.stats.downloads, 1);
    assert_int_equal(fx->srv.stats.uploads, 1);
    assert_int_equal(fx->srv.stats.od_aborts, 1);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
}

static void test_expedited_each_size_class(void **state)
{
    fx_t *fx = *state;
    const uint8_t u8[] = { 0x9A };
    const uint8_t u16[] = { 0x34, 0x12 };
    const uint8_t u32[] = { 0x01, 0x02, 0x03, 0x04 };
    const uint8_t u64[] = { 1, 2, 3, 4, 5, 6, 7, 8 };
    uint8_t s[56];
    uint8_t n;
    fill_pattern(s, sizeof s, 'A');

    exp_read_ok(fx, C1, 1, 0x2000, 0, U8, (const uint8_t *)"\x11", 1);
    exp_write_ok(fx, C1, 2, 0x2000, 0, U8, u8, 1);
    exp_read_ok(fx, C1, 3, 0x2000, 0, U8, u8, 1);

    exp_write_ok(fx, C1, 4, 0x2001, 0, U16, u16, 2);
    exp_read_ok(fx, C1, 5, 0x2001, 0, U16, u16, 2);
    exp_write_ok(fx, C1, 6, 0x2002, 0, U32, u32, 4);
    exp_read_ok(fx, C1, 7, 0x2002, 0, U32, u32, 4);
    exp_write_ok(fx, C1, 8, 0x2003, 0, U64, u64, 8);
    exp_read_ok(fx, C1, 9, 0x2003, 0, U64, u64, 8);
    assert_od_bytes(fx, 0x2003, 0, u64, 8);

    /* strings: 1, 12, 55, 56 bytes (frame lengths 12, 20, 64, 64) */
    exp_read_ok(fx, C1, 10, 0x2004, 0, VS, (const uint8_t *)"hello", 5);
    for (n = 1; n <= 56; n++) {
        if (n != 1 && n != 12 && n != 13 && n != 55 && n != 56)
            continue;
        exp_write_ok(fx, C2, n, 0x2004, 0, VS, s, n);
        exp_read_ok(fx, C2, (uint8_t)(n + 100), 0x2004, 0, VS, s, n);
        assert_od_bytes(fx, 0x2004, 0, s, n);
    }
    /* raw bytes (DOMAIN as the type byte) are taken for any entry */
    exp_write_ok(fx, C1, 11, 0x2002, 0, DOM, u32, 4);
    /* an expedited write to the domain, and reading it back expedited */
    exp_write_ok(fx, C1, 12, 0x2009, 0, DOM, s, 33);
    assert_int_equal(fx->dom_len, 33);
    exp_read_ok(fx, C1, 13, 0x2009, 0, DOM, s, 33);
    assert_int_equal(fx->srv.stats.downloads, 11);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
}

static void test_expedited_empty_write(void **state)
{
    fx_t *fx = *state;
    exp_write_ok(fx, C1, 1, 0x2004, 0, VS, NULL, 0);
    assert_od_bytes(fx, 0x2004, 0, NULL, 0);
    /* an empty value is uploaded expedited with N = 0 */
    exp_read_ok(fx, C1, 2, 0x2004, 0, VS, NULL, 0);
}

static void test_broadcast_answered_individually(void **state)
{
    fx_t *fx = *state;
    uint8_t e[12];
    const uint8_t v[] = { 0x55, 0x66 };
    /* §2.13 example 4: broadcast read */
    send_upload(fx, C1, 0, 4, 0x2002, 0);
    mux(e, C1, 0x31, 4, 0x2002, 0);
    e[6] = U32;
    e[7] = 4;
    le_put32(e + 8, 0x33333333u);
    expect(fx, e, 12);
    /* broadcast write */
    send_exp_write(fx, C2, 0, 9, 0x2001, 0, U16, v, 2);
    expect_mux(fx, C2, 0x21, 9, 0x2001, 0);
    assert_od_bytes(fx, 0x2001, 0, v, 2);
    /* session-ID 0 is taken like any other */
    exp_read_ok(fx, C2, 0, 0x2001, 0, U16, v, 2);
    /* a broadcast abort from the client ends its transfer */
    send_dl_init(fx, C1, 3, 0x2004, 0, VS, 100);
    expect_mux(fx, C1, 0x22, 3, 0x2004, 0);
    mux(e, 0, ABORT, 3, 0x2004, 0);
    e[6] = 0x10;
    req(fx, C1, e, 7);
    expect_none(fx);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
    /* a request to node 6 is not ours */
    send_upload(fx, C1, 6, 5, 0x2002, 0);
    expect_none(fx);
    assert_int_equal(fx->srv.stats.rx_other_dest, 1);
}

/* ================================================= segmented */

static void test_segmented_boundaries(void **state)
{
    fx_t *fx = *state;
    static const uint32_t sizes[] = { 57, 60, 61, 119, 120, 121, 180, 200 };
    uint8_t data[200];
    size_t i;
    for (i = 0; i < sizeof sizes / sizeof sizes[0]; i++) {
        uint8_t sid = (uint8_t)(20 + i);
        fill_pattern(data, sizes[i], (uint8_t)i);
        seg_write_ok(fx, C1, sid, 0x2004, 0, VS, data, sizes[i]);
        assert_od_bytes(fx, 0x2004, 0, data, sizes[i]);
        seg_read_ok(fx, C2, sid, 0x2004, 0, VS, data, sizes[i], sizes[i]);
    }
    /* a short value may also be written segmented */
    seg_write_ok(fx, C1, 1, 0x2002, 0, U32, (const uint8_t *)"\x10\x20\x30\x40", 4);
    assert_int_equal(od_u32(fx, 0x2002, 0), 0x40302010u);
    assert_int_equal(fx->srv.stats.downloads, 9);
    assert_int_equal(fx->srv.stats.uploads, 8);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
}

/* The frames of §2.13 example 5 (100 bytes to the domain), byte for byte. */
static void test_segmented_example_5(void **state)
{
    fx_t *fx = *state;
    uint8_t data[100], b[64];
    const uint8_t init[] = { 0x05, 0x02, 0x05, 0x00, 0x09, 0x20, 0x0F, 0x00,
                             0x64, 0x00, 0x00, 0x00 };
    fill_pattern(data, 100, 0x21);
    req(fx, C1, init, sizeof init);
    expect_mux(fx, C1, 0x22, 5, 0x2009, 0);
    send_dl_seg(fx, C1, 5, 0, data);
    expect_seg_ack(fx, C1, 5, 0);
    b[0] = 5;
    b[1] = 0x04;
    b[2] = 5;
    b[3] = 0x28;
    memcpy(b + 4, data + 60, 40);
    req(fx, C1, b, 44);
    /* the request went out as 48 bytes (DLC 14) */
    assert_int_equal(fx->tb.log[fx->tb.log_count - 2].frame.len, 48);
    expect_end_ack(fx, C1, 5);
    assert_int_equal(fx->dom_len, 100);
    assert_memory_equal(fx->domain, data, 100);
    assert_int_equal(fx->dom_commits, 1);
}

static void test_segmented_octet_string_1000(void **state)
{
    fx_t *fx = *state;
    static uint8_t data[1000];
    fill_pattern(data, sizeof data, 0x77);
    seg_write_ok(fx, C1, 1, 0x2005, 0, OS, data, 1000);
    assert_od_bytes(fx, 0x2005, 0, data, 1000);
    seg_read_ok(fx, C2, 200, 0x2005, 0, OS, data, 1000, 1000);
}

/* 102400 bytes: 1707 segments, the 8-bit counter wraps six times. */
static void test_segmented_domain_100k_both_ways(void **state)
{
    fx_t *fx = *state;
    static uint8_t data[DOM_CAP];
    fill_pattern(data, DOM_CAP, 0x5A);
    data[DOM_CAP - 1] = 0xEE;
    seg_write_ok(fx, C1, 77, 0x2009, 0, DOM, data, DOM_CAP);
    assert_int_equal(fx->dom_len, DOM_CAP);
    assert_memory_equal(fx->domain, data, DOM_CAP);
    assert_int_equal(fx->dom_commits, 1);
    assert_int_equal(fx->dom_aborts, 0);
    /* read back, with a reader that gives 7 bytes at a time */
    fx->dom_read_max = 7;
    seg_read_ok(fx, C2, 78, 0x2009, 0, DOM, data, DOM_CAP, DOM_CAP);
    fx->dom_read_max = 0;
    seg_read_ok(fx, C1, 79, 0x2009, 0, DOM, data, DOM_CAP, DOM_CAP);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
}

static void test_segmented_domain_unknown_size(void **state)
{
    fx_t *fx = *state;
    /* 0x200C has no size handler: announced as 0xFFFFFFFF, even when short */
    seg_read_ok(fx, C1, 1, 0x200C, 0, DOM, fx->domain, 100, 0xFFFFFFFFu);
    fx->dom_len = 120;
    seg_read_ok(fx, C1, 2, 0x200C, 0, DOM, fx->domain, 120, 0xFFFFFFFFu);
    fx->dom_len = 10;
    seg_read_ok(fx, C1, 3, 0x200C, 0, DOM, fx->domain, 10, 0xFFFFFFFFu);
}

/* A domain reader that gives nothing without ending, or refuses. */
static void test_domain_reader_stall_or_error(void **state)
{
    fx_t *fx = *state;
    uint8_t e[64];
    /* stalls after 60 bytes: the first segment goes, then 0x10 */
    fx->dom_stall = true;
    send_upload(fx, C1, ID_S, 1, 0x2009, 0);
    next_rsp(fx);
    send_ul_seg(fx, C1, 1, 0);
    e[0] = C1;
    e[1] = 0x33;
    e[2] = 1;
    e[3] = 0;
    memcpy(e + 4, fx->domain, 60);
    expect(fx, e, 64);
    send_ul_seg(fx, C1, 1, 1);
    expect_abort(fx, C1, 1, 0x2009, 0, 0x10);
    fx->dom_stall = false;
    /* refuses: its code, expedited and segmented */
    fx->dom_read_error = CO_ABORT_HARDWARE;
    send_upload(fx, C1, ID_S, 2, 0x2009, 0);
    next_rsp(fx);
    send_ul_seg(fx, C1, 2, 0);
    expect_abort(fx, C1, 2, 0x2009, 0, 0x35);
    fx->dom_len = 20;
    send_upload(fx, C1, ID_S, 3, 0x2009, 0);
    expect_abort(fx, C1, 3, 0x2009, 0, 0x35);
    expect_none(fx);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
}

/* ================================================= abort paths */

static void exp_write_refused(fx_t *fx, uint16_t index, uint8_t sub, uint8_t type,
                              const uint8_t *data, uint8_t n, uint8_t code)
{
    snap(fx);
    send_exp_write(fx, C1, ID_S, 0x42, index, sub, type, data, n);
    expect_abort(fx, C1, 0x42, index, sub, code);
    expect_none(fx);
    assert_unchanged(fx);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
}

static void test_abort_od_refusals(void **state)
{
    fx_t *fx = *state;
    const uint8_t v4[] = { 1, 2, 3, 4, 5 };
    uint8_t v2[2];
    static uint8_t big[201];

    exp_write_refused(fx, 0x2100, 0, U32, v4, 4, 0x33);   /* no object */
    exp_write_refused(fx, 0x200A, 2, U32, v4, 4, 0x34);   /* no sub */
    exp_write_refused(fx, 0x2006, 0, U32, v4, 4, 0x32);   /* read-only */
    exp_write_refused(fx, 0x200C, 0, DOM, v4, 4, 0x30);   /* domain without a writer */
    exp_write_refused(fx, 0x2002, 0, U32, v4, 5, 0x37);   /* length too high */
    exp_write_refused(fx, 0x2002, 0, U32, v4, 2, 0x38);   /* length too low */
    exp_write_refused(fx, 0x2002, 0, U16, v4, 4, 0x36);   /* type byte wrong */
    exp_write_refused(fx, 0x2004, 0, OS, v4, 4, 0x36);
    tu_le_put(v2, 101, 2);
    exp_write_refused(fx, 0x2008, 0, U16, v2, 2, 0x41);   /* value too high */
    tu_le_put(v2, 9, 2);
    exp_write_refused(fx, 0x2008, 0, U16, v2, 2, 0x42);   /* value too low */
    tu_le_put(v2, 100, 2);
    exp_write_ok(fx, C1, 1, 0x2008, 0, U16, v2, 2);       /* the limit itself is fine */

    /* reads */
    send_upload(fx, C1, ID_S, 3, 0x2007, 0);               /* write-only */
    expect_abort(fx, C1, 3, 0x2007, 0, 0x31);
    send_upload(fx, C1, ID_S, 4, 0x2100, 7);
    expect_abort(fx, C1, 4, 0x2100, 7, 0x33);
    send_upload(fx, C1, ID_S, 5, 0x200A, 9);
    expect_abort(fx, C1, 5, 0x200A, 9, 0x34);

    /* segmented: announced longer than the entry, at the initiate */
    snap(fx);
    send_dl_init(fx, C1, 6, 0x2004, 0, VS, 201);
    expect_abort(fx, C1, 6, 0x2004, 0, 0x37);
    send_dl_init(fx, C1, 6, 0x2006, 0, U32, 4);
    expect_abort(fx, C1, 6, 0x2006, 0, 0x32);
    send_dl_init(fx, C1, 6, 0x2002, 0, VS, 4);
    expect_abort(fx, C1, 6, 0x2002, 0, 0x36);
    /* the domain refuses more than it holds at the first segment */
    send_dl_init(fx, C1, 7, 0x2009, 0, DOM, DOM_CAP + 1);
    expect_mux(fx, C1, 0x22, 7, 0x2009, 0);
    send_dl_seg(fx, C1, 7, 0, big);
    expect_abort(fx, C1, 7, 0x2009, 0, 0x37);
    /* limits checked at the end of a segmented write */
    send_dl_init(fx, C1, 8, 0x2008, 0, U16, 2);
    expect_mux(fx, C1, 0x22, 8, 0x2008, 0);
    tu_le_put(v2, 500, 2);
    send_dl_last(fx, C1, 8, v2, 2);
    expect_abort(fx, C1, 8, 0x2008, 0, 0x41);
    expect_none(fx);
    assert_unchanged(fx);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
    assert_int_equal(fx->srv.stats.od_aborts, 18);
}

static void test_abort_unknown_command(void **state)
{
    fx_t *fx = *state;
    uint8_t b[64];
    memset(b, 0, sizeof b);
    snap(fx);
    /* multiple sub-indices (TBD), remote (incl. remote bulk), garbage */
    static const uint8_t cmds[] = { 0x05, 0x15, 0x81, 0x86, 0x87, 0x91, 0x00, 0x09, 0x40 };
    size_t i;
    for (i = 0; i < sizeof cmds; i++) {
        mux(b, ID_S, cmds[i], (uint8_t)(30 + i), 0x2002, 0);
        req(fx, C1, b, 12);
        expect_abort(fx, C1, (uint8_t)(30 + i), 0, 0, 0x13);
    }
    /* a response's command specifier sent as a request: the mux is echoed */
    mux(b, ID_S, 0x21, 40, 0x2002, 0);
    req(fx, C1, b, 6);
    expect_abort(fx, C1, 40, 0x2002, 0, 0x13);
    mux(b, ID_S, 0x23, 41, 0x2002, 0);
    req(fx, C1, b, 4);
    expect_abort(fx, C1, 41, 0, 0, 0x13);
    /* the bulk responses as requests */
    mux(b, ID_S, 0x26, 42, 0x2002, 0);
    req(fx, C1, b, 8);
    expect_abort(fx, C1, 42, 0x2002, 0, 0x13);
    mux(b, ID_S, 0x28, 43, 0x2002, 0);
    req(fx, C1, b, 3);
    expect_abort(fx, C1, 43, 0, 0, 0x13);
    /* the bulk upload responses as requests */
    mux(b, ID_S, 0x36, 44, 0x2002, 0);
    req(fx, C1, b, 12);
    expect_abort(fx, C1, 44, 0x2002, 0, 0x13);
    mux(b, ID_S, 0x37, 45, 0x2002, 0);
    req(fx, C1, b, 64);
    expect_abort(fx, C1, 45, 0, 0, 0x13);
    mux(b, ID_S, 0x38, 46, 0x2002, 0);
    b[3] = 0;
    req(fx, C1, b, 4);
    expect_abort(fx, C1, 46, 0, 0, 0x13);
    expect_none(fx);
    assert_unchanged(fx);
    assert_int_equal(fx->srv.stats.rx_unknown_command, sizeof cmds + 7);
}

static void test_abort_unknown_command_ends_open_transfer(void **state)
{
    fx_t *fx = *state;
    uint8_t b[12];
    send_dl_init(fx, C1, 3, 0x2004, 0, VS, 100);
    expect_mux(fx, C1, 0x22, 3, 0x2004, 0);
    mux(b, ID_S, 0x05, 3, 0, 0);
    req(fx, C1, b, 12);
    expect_abort(fx, C1, 3, 0x2004, 0, 0x13);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
}

static void test_abort_wrong_counter(void **state)
{
    fx_t *fx = *state;
    uint8_t data[180];
    fill_pattern(data, sizeof data, 1);
    snap(fx);
    /* download: counter 1 where 0 is expected */
    send_dl_init(fx, C1, 1, 0x2004, 0, VS, 180);
    expect_mux(fx, C1, 0x22, 1, 0x2004, 0);
    send_dl_seg(fx, C1, 1, 1, data);
    expect_abort(fx, C1, 1, 0x2004, 0, 0x14);
    /* the transfer is gone: its next segment has no session */
    send_dl_seg(fx, C1, 1, 0, data);
    expect_abort(fx, C1, 1, 0, 0, 0x21);
    /* a repeated segment */
    send_dl_init(fx, C1, 2, 0x2004, 0, VS, 180);
    expect_mux(fx, C1, 0x22, 2, 0x2004, 0);
    send_dl_seg(fx, C1, 2, 0, data);
    expect_seg_ack(fx, C1, 2, 0);
    send_dl_seg(fx, C1, 2, 0, data);
    expect_abort(fx, C1, 2, 0x2004, 0, 0x14);
    expect_none(fx);
    assert_unchanged(fx);
    /* upload: counter 0, then 2 */
    fill_pattern(data, 180, 7);
    seg_write_ok(fx, C1, 4, 0x2005, 0, OS, data, 180);
    send_upload(fx, C1, ID_S, 3, 0x2005, 0);
    next_rsp(fx);
    send_ul_seg(fx, C1, 3, 1);
    expect_abort(fx, C1, 3, 0x2005, 0, 0x14);
    send_upload(fx, C1, ID_S, 5, 0x2005, 0);
    next_rsp(fx);
    send_ul_seg(fx, C1, 5, 0);
    next_rsp(fx);
    send_ul_seg(fx, C1, 5, 2);
    expect_abort(fx, C1, 5, 0x2005, 0, 0x14);
    expect_none(fx);
    assert_int_equal(fx->srv.stats.rx_bad_counter, 4);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
}

static void test_abort_size_mismatch(void **state)
{
    fx_t *fx = *state;
    uint8_t data[200];
    fill_pattern(data, sizeof data, 3);
    snap(fx);
    /* fewer bytes than announced */
    send_dl_init(fx, C1, 1, 0x2004, 0, VS, 100);
    expect_mux(fx, C1, 0x22, 1, 0x2004, 0);
    send_dl_seg(fx, C1, 1, 0, data);
    expect_seg_ack(fx, C1, 1, 0);
    send_dl_last(fx, C1, 1, data + 60, 39);
    expect_abort(fx, C1, 1, 0x2004, 0, 0x15);
    /* more bytes than announced, in the last segment */
    send_dl_init(fx, C1, 2, 0x2004, 0, VS, 100);
    expect_mux(fx, C1, 0x22, 2, 0x2004, 0);
    send_dl_seg(fx, C1, 2, 0, data);
    expect_seg_ack(fx, C1, 2, 0);
    send_dl_last(fx, C1, 2, data + 60, 41);
    expect_abort(fx, C1, 2, 0x2004, 0, 0x15);
    /* more bytes than announced, in a full segment */
    send_dl_init(fx, C1, 3, 0x2004, 0, VS, 100);
    expect_mux(fx, C1, 0x22, 3, 0x2004, 0);
    send_dl_seg(fx, C1, 3, 0, data);
    expect_seg_ack(fx, C1, 3, 0);
    send_dl_seg(fx, C1, 3, 1, data + 60);
    expect_abort(fx, C1, 3, 0x2004, 0, 0x15);
    /* the domain: its writer is told, nothing committed */
    send_dl_init(fx, C1, 4, 0x2009, 0, DOM, 70);
    expect_mux(fx, C1, 0x22, 4, 0x2009, 0);
    send_dl_seg(fx, C1, 4, 0, data);
    expect_seg_ack(fx, C1, 4, 0);
    send_dl_last(fx, C1, 4, data, 5);
    expect_abort(fx, C1, 4, 0x2009, 0, 0x15);
    assert_int_equal(fx->dom_aborts, 1);
    assert_int_equal(fx->dom_last_abort, CO_ABORT_TYPE_MISMATCH);
    assert_int_equal(fx->dom_commits, 0);
    expect_none(fx);
    assert_unchanged(fx);
    assert_int_equal(fx->srv.stats.rx_size_mismatch, 4);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
}

static void test_abort_segment_without_session_or_of_wrong_kind(void **state)
{
    fx_t *fx = *state;
    uint8_t data[60];
    fill_pattern(data, 60, 1);
    snap(fx);
    send_dl_seg(fx, C1, 9, 0, data);
    expect_abort(fx, C1, 9, 0, 0, 0x21);
    send_dl_last(fx, C1, 9, data, 3);
    expect_abort(fx, C1, 9, 0, 0, 0x21);
    send_ul_seg(fx, C1, 9, 0);
    expect_abort(fx, C1, 9, 0, 0, 0x21);
    /* same session-ID, other client: not the same transfer */
    send_dl_init(fx, C1, 9, 0x2004, 0, VS, 100);
    expect_mux(fx, C1, 0x22, 9, 0x2004, 0);
    send_dl_seg(fx, C2, 9, 0, data);
    expect_abort(fx, C2, 9, 0, 0, 0x21);
    /* an upload segment request on a download */
    send_ul_seg(fx, C1, 9, 0);
    expect_abort(fx, C1, 9, 0x2004, 0, 0x13);
    /* a download segment on an upload */
    send_upload(fx, C1, ID_S, 10, 0x2009, 0);
    next_rsp(fx);
    send_dl_seg(fx, C1, 10, 0, data);
    expect_abort(fx, C1, 10, 0x2009, 0, 0x13);
    expect_none(fx);
    assert_unchanged(fx);
    assert_int_equal(fx->srv.stats.rx_no_session, 4);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
}

static void test_abort_malformed_frames(void **state)
{
    fx_t *fx = *state;
    uint8_t b[64];
    memset(b, 0, sizeof b);
    snap(fx);
    /* expedited N = 8 in a 12-byte frame */
    mux(b, ID_S, DL_EXP, 1, 0x2003, 0);
    b[6] = U64;
    b[7] = 8;
    req_raw(fx, 0x601, FDF, b, 12);
    expect_abort(fx, C1, 1, 0x2003, 0, 0x1E);
    /* N = 57 */
    b[7] = 57;
    req_raw(fx, 0x601, FDF, b, 64);
    expect_abort(fx, C1, 1, 0x2003, 0, 0x1E);
    /* an upload request of 4 bytes: no mux */
    mux(b, ID_S, UL, 2, 0x2002, 0);
    req_raw(fx, 0x601, FDF, b, 4);
    expect_abort(fx, C1, 2, 0, 0, 0x1E);
    /* an initiate of 8 bytes */
    mux(b, ID_S, DL_INIT, 3, 0x2004, 0);
    req_raw(fx, 0x601, FDF, b, 8);
    expect_abort(fx, C1, 3, 0x2004, 0, 0x1E);
    /* a segment without a data byte ends the open transfer */
    send_dl_init(fx, C1, 4, 0x2004, 0, VS, 100);
    expect_mux(fx, C1, 0x22, 4, 0x2004, 0);
    b[0] = ID_S;
    b[1] = DL_SEG;
    b[2] = 4;
    b[3] = 0;
    req_raw(fx, 0x601, FDF, b, 4);
    expect_abort(fx, C1, 4, 0x2004, 0, 0x1E);
    /* a last segment claiming more than the frame holds */
    send_dl_init(fx, C1, 5, 0x2004, 0, VS, 100);
    expect_mux(fx, C1, 0x22, 5, 0x2004, 0);
    b[1] = DL_LAST;
    b[2] = 5;
    b[3] = 40;
    req_raw(fx, 0x601, FDF, b, 32);
    expect_abort(fx, C1, 5, 0x2004, 0, 0x1E);
    expect_none(fx);
    assert_unchanged(fx);
    assert_int_equal(fx->srv.stats.rx_malformed, 6);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
}

static void test_ignored_frames_are_counted(void **state)
{
    fx_t *fx = *state;
    uint8_t b[8];
    mux(b, ID_S, UL, 1, 0x2002, 0);
    /* classic frame */
    req_raw(fx, 0x601, 0, b, 6);
    /* fewer than 3 bytes */
    req_raw(fx, 0x601, FDF, b, 2);
    req_raw(fx, 0x601, FDF, b, 0);
    /* remote abort */
    mux(b, ID_S, 0xFF, 1, 0x2002, 0);
    req_raw(fx, 0x601, FDF, b, 8);
    /* abort for nothing open, and a short one */
    mux(b, ID_S, ABORT, 1, 0x2002, 0);
    b[6] = 0x10;
    req_raw(fx, 0x601, FDF, b, 7);
    req_raw(fx, 0x601, FDF, b, 5);
    /* no node-id on the line */
    fx->a->node_id = 0;
    mux(b, ID_S, UL, 1, 0x2002, 0);
    req_raw(fx, 0x601, FDF, b, 6);
    fx->a->node_id = ID_S;
    expect_none(fx);
    assert_int_equal(fx->srv.stats.rx_frames, 7);
    assert_int_equal(fx->srv.stats.rx_not_fd, 1);
    assert_int_equal(fx->srv.stats.rx_empty, 2);
    assert_int_equal(fx->srv.stats.rx_remote_abort, 1);
    assert_int_equal(fx->srv.stats.rx_stray_abort, 2);
    assert_int_equal(fx->srv.stats.rx_malformed, 1);
    assert_int_equal(fx->srv.stats.rx_no_node, 1);
    assert_int_equal(fx->srv.stats.aborts_sent, 0);
}

static void test_abort_busy(void **state)
{
    fx_t *fx = *state;
    uint8_t data[100];
    fill_pattern(data, 100, 4);
    send_dl_init(fx, C1, 1, 0x2004, 0, VS, 100);
    expect_mux(fx, C1, 0x22, 1, 0x2004, 0);
    send_dl_init(fx, C1, 2, 0x2005, 0, OS, 100);
    expect_mux(fx, C1, 0x22, 2, 0x2005, 0);
    send_upload(fx, C2, ID_S, 1, 0x2009, 0);
    next_rsp(fx);
    assert_int_equal(co_usdo_server_active(&fx->srv), 3);
    /* a fourth transfer, even expedited */
    snap(fx);
    send_exp_write(fx, C2, ID_S, 2, 0x2000, 0, U8, data, 1);
    expect_abort(fx, C2, 2, 0x2000, 0, 0x70);
    send_upload(fx, C2, ID_S, 3, 0x2002, 0);
    expect_abort(fx, C2, 3, 0x2002, 0, 0x70);
    assert_unchanged(fx);
    /* one ends: room again */
    send_dl_seg(fx, C1, 1, 0, data);
    expect_seg_ack(fx, C1, 1, 0);
    send_dl_last(fx, C1, 1, data + 60, 40);
    expect_end_ack(fx, C1, 1);
    exp_read_ok(fx, C2, 3, 0x2002, 0, U32, (const uint8_t *)"\x33\x33\x33\x33", 4);
    assert_int_equal(fx->srv.stats.busy, 2);
    assert_int_equal(co_usdo_server_active(&fx->srv), 2);
}

static void test_abort_parallel_access(void **state)
{
    fx_t *fx = *state;
    uint8_t data[100];
    fill_pattern(data, 100, 4);
    send_dl_init(fx, C1, 1, 0x2004, 0, VS, 100);
    expect_mux(fx, C1, 0x22, 1, 0x2004, 0);
    snap(fx);
    /* another client, and the same client with another session */
    send_upload(fx, C2, ID_S, 7, 0x2004, 0);
    expect_abort(fx, C2, 7, 0x2004, 0, 0x20);
    send_exp_write(fx, C1, ID_S, 2, 0x2004, 0, VS, data, 3);
    expect_abort(fx, C1, 2, 0x2004, 0, 0x20);
    send_dl_init(fx, C2, 8, 0x2004, 0, VS, 10);
    expect_abort(fx, C2, 8, 0x2004, 0, 0x20);
    assert_unchanged(fx);
    /* other entries are fine meanwhile */
    exp_read_ok(fx, C2, 9, 0x2000, 0, U8, (const uint8_t *)"\x11", 1);
    /* the first transfer goes on undisturbed */
    send_dl_seg(fx, C1, 1, 0, data);
    expect_seg_ack(fx, C1, 1, 0);
    send_dl_last(fx, C1, 1, data + 60, 40);
    expect_end_ack(fx, C1, 1);
    assert_od_bytes(fx, 0x2004, 0, data, 100);
    seg_read_ok(fx, C2, 7, 0x2004, 0, VS, data, 100, 100);
    assert_int_equal(fx->srv.stats.parallel, 3);
}

static void test_abort_timeout(void **state)
{
    fx_t *fx = *state;
    uint8_t data[200];
    uint64_t t0;
    fill_pattern(data, 200, 9);
    snap(fx);
    t0 = fx->tb.now;
    send_dl_init(fx, C1, 1, 0x2004, 0, VS, 200);
    expect_mux(fx, C1, 0x22, 1, 0x2004, 0);
    /* each segment re-arms the timeout */
    tu_run_until(&fx->tb, t0 + MS(600));
    send_dl_seg(fx, C1, 1, 0, data);
    expect_seg_ack(fx, C1, 1, 0);
    tu_run_until(&fx->tb, t0 + MS(1599));
    expect_none(fx);
    assert_int_equal(co_usdo_server_active(&fx->srv), 1);
    tu_run_until(&fx->tb, t0 + MS(1600));
    expect_abort(fx, C1, 1, 0x2004, 0, 0x12);
    assert_int_equal(fx->tb.log[fx->cursor - 1].t_us, t0 + MS(1600));
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
    send_dl_seg(fx, C1, 1, 1, data + 60);
    expect_abort(fx, C1, 1, 0, 0, 0x21);
    assert_unchanged(fx);
    /* an upload waiting for its next segment request */
    t0 = fx->tb.now;
    send_upload(fx, C2, ID_S, 2, 0x2009, 0);
    next_rsp(fx);
    tu_run_until(&fx->tb, t0 + MS(1000));
    expect_abort(fx, C2, 2, 0x2009, 0, 0x12);
    /* a domain writer is told of the timeout */
    send_dl_init(fx, C1, 3, 0x2009, 0, DOM, 200);
    expect_mux(fx, C1, 0x22, 3, 0x2009, 0);
    send_dl_seg(fx, C1, 3, 0, data);
    expect_seg_ack(fx, C1, 3, 0);
    tu_run_until(&fx->tb, fx->tb.now + MS(1000));
    expect_abort(fx, C1, 3, 0x2009, 0, 0x12);
    assert_int_equal(fx->dom_aborts, 1);
    assert_int_equal(fx->dom_last_abort, CO_ABORT_TIMEOUT);
    assert_unchanged(fx);
    assert_int_equal(fx->srv.stats.timeouts, 3);
}

static void test_timeout_configurable(void **state)
{
    fx_t *fx = *state;
    uint64_t t0;
    co_usdo_server_deinit(&fx->srv);
    server_init(fx, 1, 250);
    t0 = fx->tb.now;
    send_dl_init(fx, C1, 1, 0x2004, 0, VS, 100);
    expect_mux(fx, C1, 0x22, 1, 0x2004, 0);
    tu_run_until(&fx->tb, t0 + MS(249));
    expect_none(fx);
    tu_run_until(&fx->tb, t0 + MS(250));
    expect_abort(fx, C1, 1, 0x2004, 0, 0x12);
    /* one session only: a second transfer is busy */
    send_dl_init(fx, C1, 2, 0x2004, 0, VS, 100);
    expect_mux(fx, C1, 0x22, 2, 0x2004, 0);
    send_upload(fx, C2, ID_S, 2, 0x2000, 0);
    expect_abort(fx, C2, 2, 0x2000, 0, 0x70);
}

static void test_client_abort_ends_transfer(void **state)
{
    fx_t *fx = *state;
    uint8_t data[60], b[7];
    fill_pattern(data, 60, 2);
    snap(fx);
    send_dl_init(fx, C1, 1, 0x2009, 0, DOM, 200);
    expect_mux(fx, C1, 0x22, 1, 0x2009, 0);
    send_dl_seg(fx, C1, 1, 0, data);
    expect_seg_ack(fx, C1, 1, 0);
    /* the client aborts on its request CAN-ID: no answer */
    mux(b, ID_S, ABORT, 1, 0x2009, 0);
    b[6] = 0x62;
    req(fx, C1, b, 7);
    expect_none(fx);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
    assert_int_equal(fx->dom_aborts, 1);
    assert_int_equal(fx->dom_last_abort, CO_ABORT_DATA_STATE);
    send_dl_seg(fx, C1, 1, 1, data);
    expect_abort(fx, C1, 1, 0, 0, 0x21);
    assert_unchanged(fx);
    assert_int_equal(fx->srv.stats.rx_client_abort, 1);
}

static void test_new_request_on_open_session_restarts(void **state)
{
    fx_t *fx = *state;
    uint8_t data[60];
    fill_pattern(data, 60, 2);
    snap(fx);
    send_dl_init(fx, C1, 1, 0x2004, 0, VS, 100);
    expect_mux(fx, C1, 0x22, 1, 0x2004, 0);
    send_dl_seg(fx, C1, 1, 0, data);
    expect_seg_ack(fx, C1, 1, 0);
    /* same (client, session-ID), new request: the old one ends silently */
    exp_read_ok(fx, C1, 1, 0x2004, 0, VS, (const uint8_t *)"hello", 5);
    assert_int_equal(fx->srv.stats.restarts, 1);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
    assert_unchanged(fx);
    /* and a restart on the same entry is not "parallel" */
    send_dl_init(fx, C1, 2, 0x2004, 0, VS, 100);
    expect_mux(fx, C1, 0x22, 2, 0x2004, 0);
    send_dl_init(fx, C1, 2, 0x2004, 0, VS, 100);
    expect_mux(fx, C1, 0x22, 2, 0x2004, 0);
    assert_int_equal(co_usdo_server_active(&fx->srv), 1);
}

/* ================================================= split answers */

static void test_split_read_and_write(void **state)
{
    fx_t *fx = *state;
    uint8_t e[12];
    const uint8_t v[] = { 0x01, 0x23, 0xCD, 0xAB };
    co_od_xfer_t *held;
    /* read */
    fx->split_read = true;
    send_upload(fx, C1, ID_S, 1, 0x200B, 0);
    expect_none(fx);
    assert_non_null(fx->held);
    assert_int_equal(co_usdo_server_active(&fx->srv), 1);
    held = fx->held;
    fx->held = NULL;
    /* still waiting */
    assert_true(co_usdo_server_resume(&fx->srv, held, CO_OD_SPLIT));
    tu_step(&fx->tb, fx->tb.now);
    expect_none(fx);
    assert_true(co_usdo_server_resume(&fx->srv, held, 0));
    tu_step(&fx->tb, fx->tb.now);
    mux(e, C1, 0x31, 1, 0x200B, 0);
    e[6] = U32;
    e[7] = 4;
    le_put32(e + 8, 0xB0B0B0B0u);
    expect(fx, e, 12);
    assert_false(co_usdo_server_resume(&fx->srv, held, 0));   /* nothing waits now */
    fx->split_read = false;
    /* write */
    fx->split_write = true;
    send_exp_write(fx, C1, ID_S, 2, 0x200B, 0, U32, v, 4);
    expect_none(fx);
    assert_int_equal(od_u32(fx, 0x200B, 0), 0xB0B0B0B0u);
    assert_true(co_usdo_server_resume(&fx->srv, fx->held, 0));
    tu_step(&fx->tb, fx->tb.now);
    expect_mux(fx, C1, 0x21, 2, 0x200B, 0);
    assert_int_equal(od_u32(fx, 0x200B, 0), 0xABCD2301u);
    /* refused by the application */
    snap(fx);
    send_exp_write(fx, C1, ID_S, 3, 0x200B, 0, U32, (const uint8_t *)"\0\0\0\0", 4);
    expect_none(fx);
    assert_true(co_usdo_server_resume(&fx->srv, fx->held, CO_ABORT_DATA_STATE));
    tu_step(&fx->tb, fx->tb.now);
    expect_abort(fx, C1, 3, 0x200B, 0, 0x62);
    assert_unchanged(fx);
    /* a segmented write split at its end */
    send_dl_init(fx, C1, 4, 0x200B, 0, U32, 4);
    expect_mux(fx, C1, 0x22, 4, 0x200B, 0);
    send_dl_last(fx, C1, 4, (const uint8_t *)"\x44\x33\x22\x11", 4);
    expect_none(fx);
    assert_true(co_usdo_server_resume(&fx->srv, fx->held, 0));
    tu_step(&fx->tb, fx->tb.now);
    expect_end_ack(fx, C1, 4);
    assert_int_equal(od_u32(fx, 0x200B, 0), 0x11223344u);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
    /* unknown xfer */
    assert_false(co_usdo_server_resume(&fx->srv, NULL, 0));
}

static void test_split_while_waiting_other_sessions_work(void **state)
{
    fx_t *fx = *state;
    uint8_t b[64];
    fx->split_write = true;
    send_exp_write(fx, C1, ID_S, 1, 0x200B, 0, U32, (const uint8_t *)"\1\2\3\4", 4);
    expect_none(fx);
    exp_read_ok(fx, C2, 1, 0x2000, 0, U8, (const uint8_t *)"\x11", 1);
    /* the waiting entry is in use */
    send_upload(fx, C2, ID_S, 2, 0x200B, 0);
    expect_abort(fx, C2, 2, 0x200B, 0, 0x20);
    /* a segment on the waiting transfer: unexpected, it ends */
    b[0] = ID_S;
    b[1] = UL_SEG;
    b[2] = 1;
    b[3] = 0;
    req(fx, C1, b, 4);
    expect_abort(fx, C1, 1, 0x200B, 0, 0x13);
    /* the slot waits for the application's answer, which then only frees it */
    assert_int_equal(co_usdo_server_active(&fx->srv), 1);
    assert_false(co_usdo_server_resume(&fx->srv, fx->held, 0));
    tu_step(&fx->tb, fx->tb.now);
    expect_none(fx);
    assert_int_equal(od_u32(fx, 0x200B, 0), 0xB0B0B0B0u);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
}

static void test_split_timeout_then_late_answer(void **state)
{
    fx_t *fx = *state;
    uint64_t t0 = fx->tb.now;
    uint8_t b[7];
    fx->split_write = true;
    send_exp_write(fx, C1, ID_S, 1, 0x200B, 0, U32, (const uint8_t *)"\1\2\3\4", 4);
    tu_run_until(&fx->tb, t0 + MS(1000));
    expect_abort(fx, C1, 1, 0x200B, 0, 0x12);
    assert_int_equal(co_usdo_server_active(&fx->srv), 1);
    /* the late "go on" writes nothing and sends nothing */
    assert_false(co_usdo_server_resume(&fx->srv, fx->held, 0));
    tu_step(&fx->tb, fx->tb.now);
    expect_none(fx);
    assert_int_equal(od_u32(fx, 0x200B, 0), 0xB0B0B0B0u);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
    /* a client abort while waiting: the same */
    send_exp_write(fx, C1, ID_S, 2, 0x200B, 0, U32, (const uint8_t *)"\1\2\3\4", 4);
    mux(b, ID_S, ABORT, 2, 0x200B, 0);
    b[6] = 0x12;
    req(fx, C1, b, 7);
    expect_none(fx);
    assert_false(co_usdo_server_resume(&fx->srv, fx->held, 0));
    assert_int_equal(od_u32(fx, 0x200B, 0), 0xB0B0B0B0u);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
}

static void test_deinit_aborts_open_transfers(void **state)
{
    fx_t *fx = *state;
    uint8_t data[60];
    fill_pattern(data, 60, 1);
    send_dl_init(fx, C1, 1, 0x2009, 0, DOM, 200);
    expect_mux(fx, C1, 0x22, 1, 0x2009, 0);
    send_dl_seg(fx, C1, 1, 0, data);
    expect_seg_ack(fx, C1, 1, 0);
    co_usdo_server_deinit(&fx->srv);
    assert_int_equal(fx->dom_aborts, 1);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
    assert_int_equal(co_timer_list_next(co_line_timers(fx->a)), CO_TIME_NEVER);
    send_dl_seg(fx, C1, 1, 1, data);
    expect_none(fx);
    /* the range is free again */
    server_init(fx, NSES, 0);
    exp_read_ok(fx, C1, 1, 0x2000, 0, U8, (const uint8_t *)"\x11", 1);
}

/* ================================================= bulk download */

/* 0x26 byte for byte: the mux, then the configured pacing (100 us units)
 * little-endian; 0 = none by default. */
static void test_bulk_accept_frame_carries_pacing(void **state)
{
    fx_t *fx = *state;
    const uint8_t init7[] = { 0x05, 0x06, 0x07, 0x01, 0x0A, 0x20, 0x07, 0x00,
                              0x04, 0x00, 0x00, 0x00 };
    const uint8_t acc7[] = { 0x01, 0x26, 0x07, 0x01, 0x0A, 0x20, 0x00, 0x00 };
    const uint8_t init8[] = { 0x05, 0x06, 0x08, 0x01, 0x0A, 0x20, 0x07, 0x00,
                              0x04, 0x00, 0x00, 0x00 };
    const uint8_t acc8[] = { 0x01, 0x26, 0x08, 0x01, 0x0A, 0x20, 0x34, 0x12 };
    const uint8_t last8[] = { 0x05, 0x08, 0x08, 0x04, 0x44, 0x33, 0x22, 0x11 };
    const uint8_t end8[] = { 0x01, 0x28, 0x08 };
    req(fx, C1, init7, sizeof init7);
    expect(fx, acc7, sizeof acc7);
    assert_int_equal(fx->tb.log[fx->cursor - 1].frame.len, 8);
    send_bulk_last(fx, C1, 7, (const uint8_t *)"\x01\x02\x03\x04", 4);
    expect_bulk_end(fx, C1, 7);
    assert_int_equal(od_u32(fx, 0x200A, 1), 0x04030201u);

    co_usdo_server_deinit(&fx->srv);
    server_init_paced(fx, NSES, 0, 0x1234);   /* 0x1234 * 100 us = 466 ms */
    assert_int_equal(fx->srv.bulk_pacing, 0x1234);
    req(fx, C1, init8, sizeof init8);
    expect(fx, acc8, sizeof acc8);
    assert_int_equal(fx->tb.log[fx->cursor - 1].frame.len, 8);
    req(fx, C1, last8, sizeof last8);
    expect(fx, end8, sizeof end8);
    assert_int_equal(fx->tb.log[fx->cursor - 1].frame.len, 3);
    expect_none(fx);
    assert_int_equal(od_u32(fx, 0x200A, 1), 0x11223344u);
    assert_int_equal(fx->srv.stats.downloads, 1);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
}

/* 1 MiB + 37 bytes into a domain: 17476 unanswered segments (the counter
 * wraps 68 times) and a last one of 37, compared byte for byte; then
 * 100 KiB into the readable domain, read back segmented. */
static void test_bulk_domain_1mib_counter_wraps(void **state)
{
    fx_t *fx = *state;
    static uint8_t data[BIG_CAP];
    uint64_t seed = 0xB01CB01C5EEDull;
    uint32_t i;
    for (i = 0; i < BIG_CAP; i++)
        data[i] = (uint8_t)tu_rand(&seed);
    assert_int_equal(bulk_full_part(BIG_CAP), 17476u * 60u);
    bulk_write_ok(fx, C1, 0x42, 0x200D, 0, DOM, data, BIG_CAP, 0);
    assert_int_equal(fx->big_len, BIG_CAP);
    assert_memory_equal(fx->big, data, BIG_CAP);
    assert_int_equal(fx->big_commits, 1);
    assert_int_equal(fx->big_aborts, 0);

    for (i = 0; i < DOM_CAP; i++)
        data[i] = (uint8_t)tu_rand(&seed);
    bulk_write_ok(fx, C2, 0x43, 0x2009, 0, DOM, data, DOM_CAP, 0);
    assert_int_equal(fx->dom_len, DOM_CAP);
    assert_memory_equal(fx->domain, data, DOM_CAP);
    assert_int_equal(fx->dom_commits, 1);
    seg_read_ok(fx, C1, 0x44, 0x2009, 0, DOM, data, DOM_CAP, DOM_CAP);

    assert_int_equal(fx->srv.stats.downloads, 2);
    assert_int_equal(fx->srv.stats.aborts_sent, 0);
    assert_int_equal(fx->srv.stats.rx_stray_bulk, 0);
    assert_int_equal(fx->srv.stats.tx_failed, 0);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
}

/* Bulk into ordinary entries: U32 (only a last segment), strings at the
 * segment boundaries, an empty string, 1000 octets, broadcast. */
static void test_bulk_into_u32_and_strings(void **state)
{
    fx_t *fx = *state;
    static const uint32_t sizes[] = { 1, 59, 60, 61, 119, 120, 121, 200 };
    static uint8_t data[1000];
    uint8_t b[12];
    size_t i;
    bulk_write_ok(fx, C1, 1, 0x2002, 0, U32, (const uint8_t *)"\x78\x56\x34\x12", 4, 0);
    assert_int_equal(od_u32(fx, 0x2002, 0), 0x12345678u);
    /* raw bytes (DOMAIN as the type byte) */
    bulk_write_ok(fx, C1, 2, 0x2002, 0, DOM, (const uint8_t *)"\x01\x00\x00\x80", 4, 0);
    assert_int_equal(od_u32(fx, 0x2002, 0), 0x80000001u);
    for (i = 0; i < sizeof sizes / sizeof sizes[0]; i++) {
        uint8_t sid = (uint8_t)(10 + i);
        fill_pattern(data, sizes[i], (uint8_t)(0x30 + i));
        bulk_write_ok(fx, C2, sid, 0x2004, 0, VS, data, sizes[i], 0);
        assert_od_bytes(fx, 0x2004, 0, data, sizes[i]);
    }
    seg_read_ok(fx, C1, 3, 0x2004, 0, VS, data, 200, 200);
    /* an empty value: 0x06 with size 0, 0x08 with n = 0 */
    bulk_write_ok(fx, C1, 4, 0x2004, 0, VS, NULL, 0, 0);
    assert_od_bytes(fx, 0x2004, 0, NULL, 0);
    fill_pattern(data, 1000, 0x99);
    bulk_write_ok(fx, C1, 5, 0x2005, 0, OS, data, 1000, 0);
    assert_od_bytes(fx, 0x2005, 0, data, 1000);
    /* broadcast initiate: answered by us, the segments carry our node-id */
    mux(b, 0, BULK_INIT, 6, 0x2001, 0);
    b[6] = U16;
    b[7] = 0;
    le_put32(b + 8, 2);
    req(fx, C2, b, 12);
    expect_bulk_accept(fx, C2, 6, 0x2001, 0, 0);
    send_bulk_last(fx, C2, 6, (const uint8_t *)"\xCD\xAB", 2);
    expect_bulk_end(fx, C2, 6);
    assert_od_bytes(fx, 0x2001, 0, (const uint8_t *)"\xCD\xAB", 2);
    expect_none(fx);
    assert_int_equal(fx->srv.stats.downloads, 13);
    assert_int_equal(fx->srv.stats.aborts_sent, 0);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
}

/* The initiate is checked like 0x02: entry, access, length, type byte. */
static void test_bulk_initiate_refusals(void **state)
{
    fx_t *fx = *state;
    static uint8_t data[120];
    fill_pattern(data, sizeof data, 5);
    snap(fx);
    send_bulk_init(fx, C1, 1, 0x2004, 0, VS, 201);       /* longer than the entry */
    expect_abort(fx, C1, 1, 0x2004, 0, 0x37);
    send_bulk_init(fx, C1, 2, 0x2006, 0, U32, 4);        /* read-only */
    expect_abort(fx, C1, 2, 0x2006, 0, 0x32);
    send_bulk_init(fx, C1, 3, 0x2002, 0, VS, 4);         /* type byte wrong */
    expect_abort(fx, C1, 3, 0x2002, 0, 0x36);
    send_bulk_init(fx, C1, 4, 0x2100, 0, U32, 4);        /* no object */
    expect_abort(fx, C1, 4, 0x2100, 0, 0x33);
    send_bulk_init(fx, C1, 5, 0x200A, 2, U32, 4);        /* no sub-index */
    expect_abort(fx, C1, 5, 0x200A, 2, 0x34);
    send_bulk_init(fx, C1, 6, 0x200C, 0, DOM, 100);      /* domain without a writer */
    expect_abort(fx, C1, 6, 0x200C, 0, 0x30);
    /* the domain refuses more than it holds at the first segment; the
     * segments still in flight are ignored */
    send_bulk_init(fx, C1, 7, 0x2009, 0, DOM, DOM_CAP + 1);
    expect_bulk_accept(fx, C1, 7, 0x2009, 0, 0);
    send_bulk_seg(fx, C1, 7, 0, data);
    expect_abort(fx, C1, 7, 0x2009, 0, 0x37);
    send_bulk_seg(fx, C1, 7, 1, data + 60);
    expect_none(fx);
    /* limits are checked at the end */
    send_bulk_init(fx, C1, 8, 0x2008, 0, U16, 2);
    expect_bulk_accept(fx, C1, 8, 0x2008, 0, 0);
    send_bulk_last(fx, C1, 8, (const uint8_t *)"\xF4\x01", 2);
    expect_abort(fx, C1, 8, 0x2008, 0, 0x41);
    expect_none(fx);
    assert_unchanged(fx);
    assert_int_equal(fx->srv.stats.od_aborts, 8);
    assert_int_equal(fx->srv.stats.rx_stray_bulk, 1);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
}

/* A lost segment: 0x14 once, the session is freed, the domain writer is
 * told, nothing is committed; the rest of the burst is ignored, the last
 * segment finds no transfer (0x21). */
static void test_bulk_lost_segment(void **state)
{
    fx_t *fx = *state;
    static uint8_t data[600];
    uint8_t k;
    fill_pattern(data, sizeof data, 0x11);
    snap(fx);
    send_bulk_init(fx, C1, 1, 0x2009, 0, DOM, 600);
    expect_bulk_accept(fx, C1, 1, 0x2009, 0, 0);
    assert_int_equal(bulk_segs(fx, C1, 1, 0, data, 120), 2);
    send_bulk_seg(fx, C1, 1, 3, data + 180);             /* 2 was lost */
    expect_abort(fx, C1, 1, 0x2009, 0, 0x14);
    expect_none(fx);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
    assert_int_equal(fx->dom_aborts, 1);
    assert_int_equal(fx->dom_last_abort, co_usdo_abort_to_co(0x14));
    assert_int_equal(fx->dom_commits, 0);
    for (k = 4; k < 9; k++) {
        send_bulk_seg(fx, C1, 1, k, data + 60u * (k - 1u));
        expect_none(fx);
    }
    send_bulk_last(fx, C1, 1, data + 540, 60);
    expect_abort(fx, C1, 1, 0, 0, 0x21);
    expect_none(fx);
    assert_unchanged(fx);
    assert_int_equal(fx->srv.stats.rx_bad_counter, 1);
    assert_int_equal(fx->srv.stats.rx_stray_bulk, 5);
    assert_int_equal(fx->srv.stats.rx_no_session, 1);
    assert_int_equal(fx->srv.stats.aborts_sent, 2);
    assert_int_equal(fx->srv.stats.downloads, 0);
    /* the same (client, session-ID) can start again */
    fill_pattern(data, sizeof data, 0x12);
    bulk_write_ok(fx, C1, 1, 0x2009, 0, DOM, data, 600, 0);
    assert_int_equal(fx->dom_len, 600);
    assert_memory_equal(fx->domain, data, 600);
}

static void test_bulk_duplicated_segment(void **state)
{
    fx_t *fx = *state;
    static uint8_t data[200];
    fill_pattern(data, sizeof data, 0x21);
    snap(fx);
    send_bulk_init(fx, C1, 2, 0x2004, 0, VS, 200);
    expect_bulk_accept(fx, C1, 2, 0x2004, 0, 0);
    send_bulk_seg(fx, C1, 2, 0, data);
    expect_none(fx);
    send_bulk_seg(fx, C1, 2, 0, data);
    expect_abort(fx, C1, 2, 0x2004, 0, 0x14);
    send_bulk_seg(fx, C1, 2, 1, data + 60);
    expect_none(fx);
    assert_unchanged(fx);
    /* a repeat right after a wrap: 0xFF twice */
    send_bulk_init(fx, C1, 3, 0x2009, 0, DOM, 60u * 300u);
    expect_bulk_accept(fx, C1, 3, 0x2009, 0, 0);
    {
        static uint8_t big[60u * 300u];
        fill_pattern(big, sizeof big, 0x22);
        assert_int_equal(bulk_segs(fx, C1, 3, 0, big, 60u * 256u), 0);
        send_bulk_seg(fx, C1, 3, 0xFF, big);
        expect_abort(fx, C1, 3, 0x2009, 0, 0x14);
    }
    expect_none(fx);
    assert_unchanged(fx);
    assert_int_equal(fx->dom_aborts, 1);
    assert_int_equal(fx->srv.stats.rx_bad_counter, 2);
    assert_int_equal(fx->srv.stats.rx_stray_bulk, 1);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
}

static void test_bulk_reordered_segments(void **state)
{
    fx_t *fx = *state;
    static uint8_t data[300];
    fill_pattern(data, sizeof data, 0x31);
    snap(fx);
    send_bulk_init(fx, C2, 4, 0x2005, 0, OS, 300);
    expect_bulk_accept(fx, C2, 4, 0x2005, 0, 0);
    send_bulk_seg(fx, C2, 4, 0, data);
    expect_none(fx);
    send_bulk_seg(fx, C2, 4, 2, data + 120);
    expect_abort(fx, C2, 4, 0x2005, 0, 0x14);
    send_bulk_seg(fx, C2, 4, 1, data + 60);
    expect_none(fx);
    send_bulk_seg(fx, C2, 4, 3, data + 180);
    expect_none(fx);
    send_bulk_last(fx, C2, 4, data + 240, 60);
    expect_abort(fx, C2, 4, 0, 0, 0x21);
    expect_none(fx);
    assert_unchanged(fx);
    assert_int_equal(fx->srv.stats.rx_bad_counter, 1);
    assert_int_equal(fx->srv.stats.rx_stray_bulk, 2);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
}

/* The announced size: more bytes than announced in a segment = 0x15 at
 * once; fewer or more at the last segment = 0x15. */
static void test_bulk_size_mismatch(void **state)
{
    fx_t *fx = *state;
    static uint8_t data[200];
    fill_pattern(data, sizeof data, 0x41);
    snap(fx);
    /* too big, mid-stream */
    send_bulk_init(fx, C1, 1, 0x2004, 0, VS, 100);
    expect_bulk_accept(fx, C1, 1, 0x2004, 0, 0);
    send_bulk_seg(fx, C1, 1, 0, data);
    expect_none(fx);
    send_bulk_seg(fx, C1, 1, 1, data + 60);
    expect_abort(fx, C1, 1, 0x2004, 0, 0x15);
    send_bulk_seg(fx, C1, 1, 2, data + 120);
    expect_none(fx);
    /* too small at the end */
    send_bulk_init(fx, C1, 2, 0x2004, 0, VS, 100);
    expect_bulk_accept(fx, C1, 2, 0x2004, 0, 0);
    send_bulk_seg(fx, C1, 2, 0, data);
    expect_none(fx);
    send_bulk_last(fx, C1, 2, data + 60, 39);
    expect_abort(fx, C1, 2, 0x2004, 0, 0x15);
    /* too big at the end */
    send_bulk_init(fx, C1, 3, 0x2004, 0, VS, 100);
    expect_bulk_accept(fx, C1, 3, 0x2004, 0, 0);
    send_bulk_seg(fx, C1, 3, 0, data);
    expect_none(fx);
    send_bulk_last(fx, C1, 3, data + 60, 41);
    expect_abort(fx, C1, 3, 0x2004, 0, 0x15);
    /* a size of 0 and a segment */
    send_bulk_init(fx, C1, 4, 0x2004, 0, VS, 0);
    expect_bulk_accept(fx, C1, 4, 0x2004, 0, 0);
    send_bulk_seg(fx, C1, 4, 0, data);
    expect_abort(fx, C1, 4, 0x2004, 0, 0x15);
    /* the domain: its writer is told, nothing committed */
    send_bulk_init(fx, C1, 5, 0x2009, 0, DOM, 70);
    expect_bulk_accept(fx, C1, 5, 0x2009, 0, 0);
    send_bulk_seg(fx, C1, 5, 0, data);
    expect_none(fx);
    send_bulk_last(fx, C1, 5, data, 5);
    expect_abort(fx, C1, 5, 0x2009, 0, 0x15);
    assert_int_equal(fx->dom_aborts, 1);
    assert_int_equal(fx->dom_last_abort, CO_ABORT_TYPE_MISMATCH);
    assert_int_equal(fx->dom_commits, 0);
    expect_none(fx);
    assert_unchanged(fx);
    assert_int_equal(fx->srv.stats.rx_size_mismatch, 5);
    assert_int_equal(fx->srv.stats.rx_stray_bulk, 1);
    assert_int_equal(fx->srv.stats.downloads, 0);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
}

/* A bulk segment for no open transfer is ignored and counted, nothing is
 * sent; a bulk last segment for none is answered 0x21 as other segments. */
static void test_bulk_stray_segment_ignored(void **state)
{
    fx_t *fx = *state;
    static uint8_t data[100];
    uint8_t b[64];
    fill_pattern(data, sizeof data, 0x51);
    snap(fx);
    send_bulk_seg(fx, C1, 9, 0, data);
    expect_none(fx);
    send_bulk_seg(fx, C1, 9, 7, data);
    expect_none(fx);
    /* broadcast, too */
    b[0] = 0;
    b[1] = BULK_SEG;
    b[2] = 9;
    b[3] = 8;
    memcpy(b + 4, data, 60);
    req(fx, C1, b, 64);
    expect_none(fx);
    /* the same session-ID of another client is not its transfer */
    send_bulk_init(fx, C1, 10, 0x2004, 0, VS, 100);
    expect_bulk_accept(fx, C1, 10, 0x2004, 0, 0);
    send_bulk_seg(fx, C2, 10, 0, data);
    expect_none(fx);
    assert_int_equal(co_usdo_server_active(&fx->srv), 1);
    assert_int_equal(fx->srv.stats.rx_stray_bulk, 4);
    assert_int_equal(fx->srv.stats.rx_no_session, 0);
    assert_int_equal(fx->srv.stats.aborts_sent, 0);
    /* which goes on undisturbed */
    send_bulk_seg(fx, C1, 10, 0, data);
    expect_none(fx);
    send_bulk_last(fx, C1, 10, data + 60, 40);
    expect_bulk_end(fx, C1, 10);
    assert_od_bytes(fx, 0x2004, 0, data, 100);
    snap(fx);
    /* 0x08 for no transfer: 0x21 */
    send_bulk_last(fx, C1, 9, data, 3);
    expect_abort(fx, C1, 9, 0, 0, 0x21);
    /* a bulk segment too short for its layout is malformed, not stray */
    b[0] = ID_S;
    req_raw(fx, 0x601, FDF, b, 4);
    expect_abort(fx, C1, 9, 0, 0, 0x1E);
    expect_none(fx);
    assert_unchanged(fx);
    assert_int_equal(fx->srv.stats.rx_stray_bulk, 4);
    assert_int_equal(fx->srv.stats.rx_no_session, 1);
    assert_int_equal(fx->srv.stats.rx_malformed, 1);
    assert_int_equal(fx->srv.stats.aborts_sent, 2);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
}

/* Segmented frames in a bulk download and bulk frames in a segmented
 * download or an upload: 0x13, the transfer ends. */
static void test_bulk_wrong_kind(void **state)
{
    fx_t *fx = *state;
    static uint8_t data[120];
    fill_pattern(data, sizeof data, 0x61);
    snap(fx);
    /* 0x03 in a bulk download */
    send_bulk_init(fx, C1, 1, 0x2004, 0, VS, 100);
    expect_bulk_accept(fx, C1, 1, 0x2004, 0, 0);
    send_dl_seg(fx, C1, 1, 0, data);
    expect_abort(fx, C1, 1, 0x2004, 0, 0x13);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
    /* 0x04 in a bulk download */
    send_bulk_init(fx, C1, 2, 0x2004, 0, VS, 100);
    expect_bulk_accept(fx, C1, 2, 0x2004, 0, 0);
    send_bulk_seg(fx, C1, 2, 0, data);
    expect_none(fx);
    send_dl_last(fx, C1, 2, data + 60, 40);
    expect_abort(fx, C1, 2, 0x2004, 0, 0x13);
    /* 0x07 in a segmented download */
    send_dl_init(fx, C1, 3, 0x2004, 0, VS, 100);
    expect_mux(fx, C1, 0x22, 3, 0x2004, 0);
    send_bulk_seg(fx, C1, 3, 0, data);
    expect_abort(fx, C1, 3, 0x2004, 0, 0x13);
    /* 0x08 in a segmented download */
    send_dl_init(fx, C1, 4, 0x2004, 0, VS, 100);
    expect_mux(fx, C1, 0x22, 4, 0x2004, 0);
    send_dl_seg(fx, C1, 4, 0, data);
    expect_seg_ack(fx, C1, 4, 0);
    send_bulk_last(fx, C1, 4, data + 60, 40);
    expect_abort(fx, C1, 4, 0x2004, 0, 0x13);
    /* 0x07 in an upload, and 0x13 in a bulk download */
    send_upload(fx, C2, ID_S, 5, 0x200C, 0);
    next_rsp(fx);
    send_bulk_seg(fx, C2, 5, 0, data);
    expect_abort(fx, C2, 5, 0x200C, 0, 0x13);
    send_bulk_init(fx, C2, 6, 0x2009, 0, DOM, 100);
    expect_bulk_accept(fx, C2, 6, 0x2009, 0, 0);
    send_ul_seg(fx, C2, 6, 0);
    expect_abort(fx, C2, 6, 0x2009, 0, 0x13);
    assert_int_equal(fx->dom_aborts, 1);
    /* what is still in flight afterwards is ignored */
    send_bulk_seg(fx, C1, 1, 1, data);
    expect_none(fx);
    assert_unchanged(fx);
    assert_int_equal(fx->srv.stats.rx_unknown_command, 6);
    assert_int_equal(fx->srv.stats.rx_stray_bulk, 1);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
}

/* Frames too short for their layout in a bulk download: 0x1E. */
static void test_bulk_malformed_frames(void **state)
{
    fx_t *fx = *state;
    uint8_t b[64];
    memset(b, 0, sizeof b);
    snap(fx);
    /* an initiate of 8 bytes: the mux is echoed */
    mux(b, ID_S, BULK_INIT, 1, 0x2004, 0);
    req_raw(fx, 0x601, FDF, b, 8);
    expect_abort(fx, C1, 1, 0x2004, 0, 0x1E);
    /* a bulk segment without data ends the open transfer */
    send_bulk_init(fx, C1, 2, 0x2004, 0, VS, 100);
    expect_bulk_accept(fx, C1, 2, 0x2004, 0, 0);
    b[0] = ID_S;
    b[1] = BULK_SEG;
    b[2] = 2;
    b[3] = 0;
    req_raw(fx, 0x601, FDF, b, 4);
    expect_abort(fx, C1, 2, 0x2004, 0, 0x1E);
    /* a bulk last segment claiming more than the frame holds, and n > 60 */
    send_bulk_init(fx, C1, 3, 0x2004, 0, VS, 100);
    expect_bulk_accept(fx, C1, 3, 0x2004, 0, 0);
    b[1] = BULK_LAST;
    b[2] = 3;
    b[3] = 40;
    req_raw(fx, 0x601, FDF, b, 32);
    expect_abort(fx, C1, 3, 0x2004, 0, 0x1E);
    send_bulk_init(fx, C1, 4, 0x2004, 0, VS, 100);
    expect_bulk_accept(fx, C1, 4, 0x2004, 0, 0);
    b[2] = 4;
    b[3] = 61;
    req_raw(fx, 0x601, FDF, b, 64);
    expect_abort(fx, C1, 4, 0x2004, 0, 0x1E);
    expect_none(fx);
    assert_unchanged(fx);
    assert_int_equal(fx->srv.stats.rx_malformed, 4);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
}

/* Idle timeout: re-armed by every (unanswered) segment; the domain writer
 * is told; what comes later is stray. */
static void test_bulk_timeout(void **state)
{
    fx_t *fx = *state;
    static uint8_t data[600];
    uint64_t t0;
    fill_pattern(data, sizeof data, 0x71);
    snap(fx);
    t0 = fx->tb.now;
    send_bulk_init(fx, C1, 1, 0x2009, 0, DOM, 600);
    expect_bulk_accept(fx, C1, 1, 0x2009, 0, 0);
    tu_run_until(&fx->tb, t0 + MS(600));
    send_bulk_seg(fx, C1, 1, 0, data);
    expect_none(fx);
    tu_run_until(&fx->tb, t0 + MS(1300));
    send_bulk_seg(fx, C1, 1, 1, data + 60);
    expect_none(fx);
    tu_run_until(&fx->tb, t0 + MS(2299));
    expect_none(fx);
    assert_int_equal(co_usdo_server_active(&fx->srv), 1);
    tu_run_until(&fx->tb, t0 + MS(2300));
    expect_abort(fx, C1, 1, 0x2009, 0, 0x12);
    assert_int_equal(fx->tb.log[fx->cursor - 1].t_us, t0 + MS(2300));
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
    assert_int_equal(fx->dom_aborts, 1);
    assert_int_equal(fx->dom_last_abort, CO_ABORT_TIMEOUT);
    send_bulk_seg(fx, C1, 1, 2, data + 120);
    expect_none(fx);
    send_bulk_last(fx, C1, 1, data + 180, 60);
    expect_abort(fx, C1, 1, 0, 0, 0x21);
    expect_none(fx);
    assert_unchanged(fx);
    assert_int_equal(fx->srv.stats.timeouts, 1);
    assert_int_equal(fx->srv.stats.rx_stray_bulk, 1);
    assert_int_equal(co_timer_list_next(co_line_timers(fx->a)), CO_TIME_NEVER);
}

/* A check_write handler that splits at the end: 0x28 waits for the
 * application's answer. */
static void test_bulk_split_at_end_defers_0x28(void **state)
{
    fx_t *fx = *state;
    co_od_xfer_t *held;
    fx->split_write = true;
    send_bulk_init(fx, C1, 1, 0x200B, 0, U32, 4);
    expect_bulk_accept(fx, C1, 1, 0x200B, 0, 0);
    send_bulk_last(fx, C1, 1, (const uint8_t *)"\x44\x33\x22\x11", 4);
    expect_none(fx);
    assert_non_null(fx->held);
    assert_int_equal(co_usdo_server_active(&fx->srv), 1);
    assert_int_equal(od_u32(fx, 0x200B, 0), 0xB0B0B0B0u);
    held = fx->held;
    fx->held = NULL;
    assert_true(co_usdo_server_resume(&fx->srv, held, CO_OD_SPLIT));
    tu_step(&fx->tb, fx->tb.now);
    expect_none(fx);
    assert_true(co_usdo_server_resume(&fx->srv, held, 0));
    tu_step(&fx->tb, fx->tb.now);
    expect_bulk_end(fx, C1, 1);
    expect_none(fx);
    assert_int_equal(od_u32(fx, 0x200B, 0), 0x11223344u);
    assert_int_equal(fx->srv.stats.downloads, 1);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
    assert_false(co_usdo_server_resume(&fx->srv, held, 0));
    /* refused by the application: its code instead of 0x28 */
    send_bulk_init(fx, C1, 2, 0x200B, 0, U32, 4);
    expect_bulk_accept(fx, C1, 2, 0x200B, 0, 0);
    send_bulk_last(fx, C1, 2, (const uint8_t *)"\0\0\0\0", 4);
    expect_none(fx);
    assert_true(co_usdo_server_resume(&fx->srv, fx->held, CO_ABORT_DATA_STATE));
    tu_step(&fx->tb, fx->tb.now);
    expect_abort(fx, C1, 2, 0x200B, 0, 0x62);
    assert_int_equal(od_u32(fx, 0x200B, 0), 0x11223344u);
    /* a bulk segment while it waits: unexpected (0x13); the late answer
     * then only frees the slot */
    send_bulk_init(fx, C1, 3, 0x200B, 0, U32, 4);
    expect_bulk_accept(fx, C1, 3, 0x200B, 0, 0);
    send_bulk_last(fx, C1, 3, (const uint8_t *)"\1\2\3\4", 4);
    expect_none(fx);
    send_bulk_seg(fx, C1, 3, 0, fx->domain);
    expect_abort(fx, C1, 3, 0x200B, 0, 0x13);
    assert_int_equal(co_usdo_server_active(&fx->srv), 1);
    assert_false(co_usdo_server_resume(&fx->srv, fx->held, 0));
    tu_step(&fx->tb, fx->tb.now);
    expect_none(fx);
    assert_int_equal(od_u32(fx, 0x200B, 0), 0x11223344u);
    assert_int_equal(fx->srv.stats.downloads, 1);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
}

static void test_bulk_busy(void **state)
{
    fx_t *fx = *state;
    static uint8_t data[100];
    fill_pattern(data, sizeof data, 0x81);
    send_bulk_init(fx, C1, 1, 0x2004, 0, VS, 100);
    expect_bulk_accept(fx, C1, 1, 0x2004, 0, 0);
    send_dl_init(fx, C1, 2, 0x2005, 0, OS, 100);
    expect_mux(fx, C1, 0x22, 2, 0x2005, 0);
    send_bulk_init(fx, C2, 1, 0x2009, 0, DOM, 100);
    expect_bulk_accept(fx, C2, 1, 0x2009, 0, 0);
    assert_int_equal(co_usdo_server_active(&fx->srv), 3);
    snap(fx);
    send_bulk_init(fx, C2, 2, 0x2002, 0, U32, 4);
    expect_abort(fx, C2, 2, 0x2002, 0, 0x70);
    send_exp_write(fx, C2, ID_S, 3, 0x2000, 0, U8, data, 1);
    expect_abort(fx, C2, 3, 0x2000, 0, 0x70);
    expect_none(fx);
    assert_unchanged(fx);
    assert_int_equal(fx->srv.stats.busy, 2);
    /* one bulk transfer ends: room again */
    send_bulk_seg(fx, C1, 1, 0, data);
    expect_none(fx);
    send_bulk_last(fx, C1, 1, data + 60, 40);
    expect_bulk_end(fx, C1, 1);
    assert_od_bytes(fx, 0x2004, 0, data, 100);
    bulk_write_ok(fx, C2, 2, 0x2002, 0, U32, (const uint8_t *)"\x04\x03\x02\x01", 4, 0);
    assert_int_equal(od_u32(fx, 0x2002, 0), 0x01020304u);
    assert_int_equal(co_usdo_server_active(&fx->srv), 2);
}

static void test_bulk_parallel_access(void **state)
{
    fx_t *fx = *state;
    static uint8_t data[100];
    fill_pattern(data, sizeof data, 0x91);
    send_bulk_init(fx, C1, 1, 0x2004, 0, VS, 100);
    expect_bulk_accept(fx, C1, 1, 0x2004, 0, 0);
    snap(fx);
    /* another client's bulk, its read, the same client's other session */
    send_bulk_init(fx, C2, 7, 0x2004, 0, VS, 10);
    expect_abort(fx, C2, 7, 0x2004, 0, 0x20);
    send_upload(fx, C2, ID_S, 8, 0x2004, 0);
    expect_abort(fx, C2, 8, 0x2004, 0, 0x20);
    send_dl_init(fx, C1, 2, 0x2004, 0, VS, 10);
    expect_abort(fx, C1, 2, 0x2004, 0, 0x20);
    /* and a bulk on an entry in a segmented download */
    send_dl_init(fx, C2, 9, 0x2005, 0, OS, 100);
    expect_mux(fx, C2, 0x22, 9, 0x2005, 0);
    send_bulk_init(fx, C1, 3, 0x2005, 0, OS, 10);
    expect_abort(fx, C1, 3, 0x2005, 0, 0x20);
    expect_none(fx);
    assert_unchanged(fx);
    assert_int_equal(fx->srv.stats.parallel, 4);
    /* the first transfer goes on undisturbed */
    send_bulk_seg(fx, C1, 1, 0, data);
    expect_none(fx);
    send_bulk_last(fx, C1, 1, data + 60, 40);
    expect_bulk_end(fx, C1, 1);
    assert_od_bytes(fx, 0x2004, 0, data, 100);
}

/* A new request on an open (client, session-ID) restarts it, bulk or not;
 * a client abort ends a bulk download, its segments in flight are stray. */
static void test_bulk_restart_and_client_abort(void **state)
{
    fx_t *fx = *state;
    static uint8_t data[200];
    uint8_t b[7];
    fill_pattern(data, sizeof data, 0xA1);
    snap(fx);
    send_bulk_init(fx, C1, 1, 0x2004, 0, VS, 200);
    expect_bulk_accept(fx, C1, 1, 0x2004, 0, 0);
    send_bulk_seg(fx, C1, 1, 0, data);
    expect_none(fx);
    /* the same entry again: a restart, not parallel; the counter starts over */
    send_bulk_init(fx, C1, 1, 0x2004, 0, VS, 200);
    expect_bulk_accept(fx, C1, 1, 0x2004, 0, 0);
    assert_int_equal(fx->srv.stats.restarts, 1);
    assert_int_equal(co_usdo_server_active(&fx->srv), 1);
    /* a segmented download restarted as bulk, and the other way round */
    send_dl_init(fx, C1, 2, 0x2005, 0, OS, 100);
    expect_mux(fx, C1, 0x22, 2, 0x2005, 0);
    send_bulk_init(fx, C1, 2, 0x2005, 0, OS, 100);
    expect_bulk_accept(fx, C1, 2, 0x2005, 0, 0);
    send_dl_init(fx, C1, 2, 0x2005, 0, OS, 100);
    expect_mux(fx, C1, 0x22, 2, 0x2005, 0);
    assert_int_equal(fx->srv.stats.restarts, 3);
    assert_int_equal(co_usdo_server_active(&fx->srv), 2);
    mux(b, ID_S, ABORT, 2, 0x2005, 0);
    b[6] = 0x10;
    req(fx, C1, b, 7);
    expect_none(fx);
    /* the restarted bulk from counter 0 */
    assert_int_equal(bulk_segs(fx, C1, 1, 0, data, 180), 3);
    send_bulk_last(fx, C1, 1, data + 180, 20);
    expect_bulk_end(fx, C1, 1);
    assert_od_bytes(fx, 0x2004, 0, data, 200);
    snap(fx);
    /* client abort of a bulk download into the domain */
    send_bulk_init(fx, C2, 3, 0x2009, 0, DOM, 200);
    expect_bulk_accept(fx, C2, 3, 0x2009, 0, 0);
    send_bulk_seg(fx, C2, 3, 0, data);
    expect_none(fx);
    mux(b, ID_S, ABORT, 3, 0x2009, 0);
    b[6] = 0x62;
    req(fx, C2, b, 7);
    expect_none(fx);
    assert_int_equal(fx->dom_aborts, 1);
    assert_int_equal(fx->dom_last_abort, CO_ABORT_DATA_STATE);
    send_bulk_seg(fx, C2, 3, 1, data + 60);
    expect_none(fx);
    send_bulk_seg(fx, C2, 3, 2, data + 120);
    expect_none(fx);
    assert_unchanged(fx);
    assert_int_equal(fx->srv.stats.rx_client_abort, 2);
    assert_int_equal(fx->srv.stats.rx_stray_bulk, 2);
    assert_int_equal(fx->srv.stats.aborts_sent, 0);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
}

/* ================================================= bulk upload */

/* The exact frames: 0x36 with type and size, 0x37 segments with the counter,
 * a 0x38 with the rest; never more than the window beyond the acknowledged
 * segments; an acknowledgement of part of the window moves it that far. */
static void test_bulk_upload_frames_and_window(void **state)
{
    fx_t *fx = *state;
    uint8_t e[64];
    unsigned i;
    fx->dom_len = 1000;   /* 16 segments of 60, then 40 */
    bulk_read_ok(fx, C1, 1, 0x2009, 0, DOM, fx->domain, 1000, 1000, 4);
    /* window 4, acknowledged two by two (as our client does: every half window) */
    send_bul_req(fx, C2, 2, 0x2009, 0, 4);
    expect_bul_init(fx, C2, 2, 0x2009, 0, DOM, 1000);
    for (i = 0; i < 4; i++) {
        e[0] = C2;
        e[1] = BUL_SEG;
        e[2] = 2;
        e[3] = (uint8_t)i;
        memcpy(e + 4, fx->domain + 60u * i, 60);
        expect(fx, e, 64);
    }
    expect_none(fx);
    send_bul_ack(fx, C2, 2, 1);   /* took 0 and 1: two more may come */
    for (i = 4; i < 6; i++) {
        e[3] = (uint8_t)i;
        memcpy(e + 4, fx->domain + 60u * i, 60);
        expect(fx, e, 64);
    }
    expect_none(fx);
    send_bul_ack(fx, C2, 2, 1);   /* the same acknowledgement again: names nothing in flight */
    expect_abort(fx, C2, 2, 0x2009, 0, 0x14);
    expect_none(fx);
    assert_int_equal(fx->srv.stats.bulk_uploads, 1);
    assert_int_equal(fx->srv.stats.uploads, 1);
    assert_int_equal(fx->srv.stats.rx_bad_counter, 1);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
}

/* 100 KiB through a window of 255: 1707 segments, the counter wraps six
 * times; an exact multiple of 60 ends with a full 0x38; values of other
 * types; an empty value; a domain of unknown size. */
static void test_bulk_upload_sizes_and_counter_wrap(void **state)
{
    fx_t *fx = *state;
    static uint8_t data[1000];
    fx->dom_len = DOM_CAP;
    bulk_read_ok(fx, C1, 1, 0x2009, 0, DOM, fx->domain, DOM_CAP, DOM_CAP, 255);
    fx->dom_len = 120;
    bulk_read_ok(fx, C1, 2, 0x2009, 0, DOM, fx->domain, 120, 120, 2);
    bulk_read_ok(fx, C1, 3, 0x2002, 0, U32, (const uint8_t *)"\x33\x33\x33\x33", 4, 4, 1);
    fill_pattern(data, 1000, 3);
    seg_write_ok(fx, C1, 4, 0x2005, 0, OS, data, 1000);
    bulk_read_ok(fx, C2, 5, 0x2005, 0, OS, data, 1000, 1000, 7);
    exp_write_ok(fx, C1, 6, 0x2004, 0, VS, NULL, 0);
    bulk_read_ok(fx, C1, 7, 0x2004, 0, VS, NULL, 0, 0, 1);
    fx->dom_len = 150;
    bulk_read_ok(fx, C1, 8, 0x200C, 0, DOM, fx->domain, 150, 0xFFFFFFFFu, 3);
    assert_int_equal(fx->srv.stats.bulk_uploads, 6);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
}

/* Refusals at the request: window 0 (0x11), the object dictionary's (no
 * object, write-only), parallel access; a malformed request. */
static void test_bulk_upload_refusals(void **state)
{
    fx_t *fx = *state;
    uint8_t b[8];
    send_bul_req(fx, C1, 1, 0x2009, 0, 0);
    expect_abort(fx, C1, 1, 0x2009, 0, 0x11);
    send_bul_req(fx, C1, 2, 0x2999, 0, 8);
    expect_abort(fx, C1, 2, 0x2999, 0, 0x33);
    send_bul_req(fx, C1, 3, 0x2007, 0, 8);
    expect_abort(fx, C1, 3, 0x2007, 0, 0x31);
    /* a request of 7 bytes has no window */
    mux(b, ID_S, BUL_REQ, 4, 0x2009, 0);
    b[6] = 8;
    req_raw(fx, 0x601, FDF, b, 7);
    expect_abort(fx, C1, 4, 0x2009, 0, 0x1E);
    /* parallel access and busy: sessions held by waiting bulk uploads */
    fx->dom_len = 1000;
    send_bul_req(fx, C1, 5, 0x2009, 0, 1);
    expect_bul_init(fx, C1, 5, 0x2009, 0, DOM, 1000);
    next_rsp(fx);
    expect_none(fx);
    send_bul_req(fx, C2, 6, 0x2009, 0, 1);
    expect_abort(fx, C2, 6, 0x2009, 0, 0x20);
    send_bul_req(fx, C2, 7, 0x2005, 0, 1);
    expect_bul_init(fx, C2, 7, 0x2005, 0, OS, 0);
    next_rsp(fx);   /* 0x38 n = 0: done, the session is free again */
    send_upload(fx, C2, ID_S, 8, 0x2009, 0);
    expect_abort(fx, C2, 8, 0x2009, 0, 0x20);
    assert_int_equal(fx->srv.stats.rx_bad_window, 1);
    assert_int_equal(fx->srv.stats.od_aborts, 2);
    assert_int_equal(fx->srv.stats.rx_malformed, 1);
    assert_int_equal(fx->srv.stats.parallel, 2);
    assert_int_equal(co_usdo_server_active(&fx->srv), 1);
}

/* Every way a bulk upload ends early: a lost acknowledgement (the server
 * times out, 0x12 once), the client's abort (nothing more is sent, later
 * acknowledgements are stray), a wrong acknowledgement counter (0x14), an
 * acknowledgement on a segmented upload (0x13), a reader error. */
static void test_bulk_upload_aborts(void **state)
{
    fx_t *fx = *state;
    uint8_t b[7];
    uint64_t t0;
    fx->dom_len = 1000;
    /* waiting for an acknowledgement that never comes */
    t0 = fx->tb.now;
    send_bul_req(fx, C1, 1, 0x2009, 0, 2);
    expect_bul_init(fx, C1, 1, 0x2009, 0, DOM, 1000);
    next_rsp(fx);
    next_rsp(fx);
    expect_none(fx);
    tu_run_until(&fx->tb, t0 + MS(999));
    expect_none(fx);
    tu_run_until(&fx->tb, t0 + MS(1000));
    expect_abort(fx, C1, 1, 0x2009, 0, 0x12);
    tu_run_until(&fx->tb, t0 + MS(3000));
    expect_none(fx);
    /* a late acknowledgement of that transfer: stray, ignored */
    send_bul_ack(fx, C1, 1, 1);
    expect_none(fx);
    /* the client aborts in the middle */
    send_bul_req(fx, C1, 2, 0x2009, 0, 3);
    expect_bul_init(fx, C1, 2, 0x2009, 0, DOM, 1000);
    next_rsp(fx);
    next_rsp(fx);
    next_rsp(fx);
    mux(b, ID_S, ABORT, 2, 0x2009, 0);
    b[6] = 0x16;
    req(fx, C1, b, 7);
    expect_none(fx);
    send_bul_ack(fx, C1, 2, 2);
    expect_none(fx);
    /* an acknowledgement naming a segment not sent yet */
    send_bul_req(fx, C1, 3, 0x2009, 0, 3);
    expect_bul_init(fx, C1, 3, 0x2009, 0, DOM, 1000);
    next_rsp(fx);
    next_rsp(fx);
    next_rsp(fx);
    send_bul_ack(fx, C1, 3, 3);
    expect_abort(fx, C1, 3, 0x2009, 0, 0x14);
    /* an acknowledgement on a segmented upload */
    send_upload(fx, C1, ID_S, 4, 0x2009, 0);
    next_rsp(fx);
    send_bul_ack(fx, C1, 4, 0);
    expect_abort(fx, C1, 4, 0x2009, 0, 0x13);
    /* the reader fails after the first window */
    send_bul_req(fx, C1, 5, 0x2009, 0, 1);
    expect_bul_init(fx, C1, 5, 0x2009, 0, DOM, 1000);
    next_rsp(fx);
    fx->dom_read_error = CO_ABORT_HARDWARE;
    send_bul_ack(fx, C1, 5, 0);
    expect_abort(fx, C1, 5, 0x2009, 0, 0x35);
    expect_none(fx);
    assert_int_equal(fx->srv.stats.timeouts, 1);
    assert_int_equal(fx->srv.stats.rx_stray_ack, 2);
    assert_int_equal(fx->srv.stats.rx_client_abort, 1);
    assert_int_equal(fx->srv.stats.rx_bad_counter, 1);
    assert_int_equal(fx->srv.stats.rx_unknown_command, 1);
    assert_int_equal(fx->srv.stats.bulk_uploads, 0);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
}

/* A window larger than the tx queue's room: the server stops at the room
 * and goes on when the queue drained (tx-space indication); the frames stay
 * in order and complete. */
static void test_bulk_upload_waits_for_tx_room(void **state)
{
    fx_t *fx = *state;
    fx->dom_len = 255u * 60u + 10u;
    bulk_read_ok(fx, C1, 1, 0x2009, 0, DOM, fx->domain, fx->dom_len, fx->dom_len, 255);
    assert_true(fx->srv.stats.tx_deferred >= 1);
    assert_int_equal(fx->srv.stats.tx_failed, 0);
    assert_int_equal(fx->srv.stats.bulk_uploads, 1);
}

/* An acknowledgement that arrives in the same processing round as the
 * tx-space indication streams at once and re-arms the idle timeout: the
 * pending "resume" must not survive it, or the next idle timeout is taken
 * for a resume and the abort comes a whole timeout late. */
static void test_bulk_upload_ack_with_tx_space_keeps_the_timeout(void **state)
{
    fx_t *fx = *state;
    uint32_t room = co_line_tx_room(fx->a);
    uint8_t window = (uint8_t)(room + 2u);
    co_usdo_session_t *ses = NULL;
    uint8_t b[8];
    uint64_t t_ack;
    uint32_t i;
    assert_true(room + 2u <= 255u);
    fx->dom_len = (window + 10u) * 60u;
    mux(b, ID_S, BUL_REQ, 1, 0x2009, 0);
    b[6] = window;
    b[7] = 0;
    /* the request reaches the server, which streams until its tx queue is full */
    assert_true(co_line_send(fx->b, 0x600u + C1, b, 8));
    (void)co_membus_transfer(&fx->tb.bus, NULL, NULL);
    (void)co_line_process(fx->a, fx->tb.now);
    for (i = 0; i < NSES; i++)
        if (fx->ses[i].state == CO_USDO_SESSION_BULK_UPLOAD)
            ses = &fx->ses[i];
    assert_non_null(ses);
    assert_true(ses->tx_wait);
    /* the acknowledgement of segment 0 travels with the drain of that queue */
    b[1] = BUL_ACK;
    b[2] = 1;
    b[3] = 0;
    assert_true(co_line_send(fx->b, 0x600u + C1, b, 4));
    tu_step(&fx->tb, fx->tb.now);
    t_ack = fx->tb.now;
    assert_false(ses->tx_wait);
    assert_int_equal(ses->sent - ses->acked, window);   /* stopped by the window */
    /* the client goes silent: the abort comes one timeout after its last frame */
    tu_run_until(&fx->tb, t_ack + MS(999));
    assert_int_equal(fx->srv.stats.timeouts, 0);
    tu_run_until(&fx->tb, t_ack + MS(1000));
    assert_int_equal(fx->srv.stats.timeouts, 1);
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
}

/* A split before_read: the 0x36 and the stream start with the
 * application's answer. */
static void test_bulk_upload_split(void **state)
{
    fx_t *fx = *state;
    uint8_t e[12];
    fx->split_read = true;
    send_bul_req(fx, C1, 1, 0x200B, 0, 4);
    expect_none(fx);
    assert_non_null(fx->held);
    assert_true(co_usdo_server_resume(&fx->srv, fx->held, 0));
    tu_step(&fx->tb, fx->tb.now);
    expect_bul_init(fx, C1, 1, 0x200B, 0, U32, 4);
    e[0] = C1;
    e[1] = BUL_LAST;
    e[2] = 1;
    e[3] = 4;
    tu_le_put(e + 4, 0xB0B0B0B0u, 4);
    expect(fx, e, 8);
    expect_none(fx);
    assert_int_equal(fx->srv.stats.bulk_uploads, 1);
}

/* ================================================= short segments */

/* Segments shorter than 64 bytes (a sender with a smaller MTU) are taken:
 * data = frame length - 4; counted; the size check still holds. */
static void test_short_segments_accepted_and_counted(void **state)
{
    fx_t *fx = *state;
    uint8_t b[64];
    static uint8_t data[200];
    fill_pattern(data, sizeof data, 0x21);
    /* segmented: 28 + 44 + 60, then the last 8 */
    send_dl_init(fx, C1, 1, 0x2005, 0, OS, 140);
    expect_mux(fx, C1, 0x22, 1, 0x2005, 0);
    b[0] = ID_S;
    b[1] = DL_SEG;
    b[2] = 1;
    b[3] = 0;
    memcpy(b + 4, data, 28);
    req(fx, C1, b, 32);
    expect_seg_ack(fx, C1, 1, 0);
    b[3] = 1;
    memcpy(b + 4, data + 28, 44);
    req(fx, C1, b, 48);
    expect_seg_ack(fx, C1, 1, 1);
    send_dl_seg(fx, C1, 1, 2, data + 72);
    expect_seg_ack(fx, C1, 1, 2);
    send_dl_last(fx, C1, 1, data + 132, 8);
    expect_end_ack(fx, C1, 1);
    assert_od_bytes(fx, 0x2005, 0, data, 140);
    /* bulk: a 20-byte frame carries 16 */
    send_bulk_init(fx, C1, 2, 0x2005, 0, OS, 76);
    expect_bulk_accept(fx, C1, 2, 0x2005, 0, 0);
    b[1] = BULK_SEG;
    b[2] = 2;
    b[3] = 0;
    memcpy(b + 4, data + 50, 16);
    req(fx, C1, b, 20);
    expect_none(fx);
    send_bulk_last(fx, C1, 2, data + 66, 60);
    expect_bulk_end(fx, C1, 2);
    assert_od_bytes(fx, 0x2005, 0, data + 50, 76);
    /* padding taken as data shows in the size check: 0x15 */
    send_dl_init(fx, C1, 3, 0x2005, 0, OS, 30);
    expect_mux(fx, C1, 0x22, 3, 0x2005, 0);
    b[1] = DL_SEG;
    b[2] = 3;
    b[3] = 0;
    req(fx, C1, b, 48);
    expect_abort(fx, C1, 3, 0x2005, 0, 0x15);
    assert_int_equal(fx->srv.stats.rx_short_segment, 4);
    assert_int_equal(fx->srv.stats.downloads, 2);
}

/* ================================================= garbage */

static void test_random_garbage_never_wedges(void **state)
{
    fx_t *fx = *state;
    static const uint8_t fd_lens[] = { 0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64 };
    static const uint8_t cmds[] = { 0x01, 0x02, 0x03, 0x04, 0x11, 0x13, 0x7F, 0x21, 0x05,
                                    0x06, 0x07, 0x08, 0x26, 0xFF, 0x16, 0x17 };
    uint64_t seed = 0x6A7BA6E5EEDull;
    uint64_t now = fx->tb.now;
    unsigned i, responses = 0;
    uint8_t k;
    for (i = 0; i < 10000; i++) {
        co_frame_t f;
        uint64_t r = tu_rand(&seed);
        size_t j;
        memset(&f, 0, sizeof f);
        f.id = 0x601u + (uint32_t)(r % 127u);
        if (((r >> 8) & 15u) == 0) {
            f.flags = 0;
            f.len = (uint8_t)((r >> 12) % 9u);
        } else {
            f.flags = FDF;
            f.len = fd_lens[(r >> 12) % sizeof fd_lens];
        }
        for (j = 0; j < f.len; j++)
            f.data[j] = (uint8_t)tu_rand(&seed);
        /* steer most frames into the parser: our node or broadcast, known
         * commands, few sessions, the test entries, small sizes */
        r = tu_rand(&seed);
        if (f.len > 0 && (r & 7u) != 0)
            f.data[0] = (r & 8u) ? 0 : ID_S;
        if (f.len > 1 && ((r >> 4) & 7u) != 0)
            f.data[1] = cmds[(r >> 8) % sizeof cmds];
        if (f.len > 2 && ((r >> 12) & 3u) != 0)
            f.data[2] = (uint8_t)((r >> 16) % 4u);
        if (f.len > 3 && ((r >> 20) & 3u) != 0)
            f.data[3] = (uint8_t)((r >> 22) % 3u);
        if (f.len > 5 && ((r >> 24) & 3u) != 0) {
            f.data[4] = (uint8_t)((r >> 26) % 13u);
            f.data[5] = 0x20;
        }
        if (f.len > 7 && f.data[1] == 0x01 && ((r >> 30) & 1u))
            f.data[7] = (uint8_t)((r >> 32) % 57u);
        if (f.len > 11 && (f.data[1] == 0x02 || f.data[1] == 0x06) && ((r >> 38) & 1u)) {
            f.data[8] = (uint8_t)((r >> 40) % 250u);
            f.data[9] = (uint8_t)((r >> 48) % 2u);
            f.data[10] = 0;
            f.data[11] = 0;
        }
        if (f.len > 3 && (f.data[1] == 0x04 || f.data[1] == 0x08) && ((r >> 50) & 1u))
            f.data[3] = (uint8_t)((r >> 52) % 61u);
        assert_true(co_line_send_raw(fx->b, &f));
        r = tu_rand(&seed);
        now += (r % 8u == 0) ? (r >> 8) % MS(1500) : (r >> 8) % MS(20);
        tu_run_until(&fx->tb, now);
        /* every answer is well formed */
        for (j = 0; j < fx->tb.log_count; j++) {
            const co_frame_t *g = &fx->tb.log[j].frame;
            if (g->id != RSP_ID)
                continue;
            responses++;
            assert_int_equal(g->flags, FDF);
            assert_true(co_fd_len_valid(g->len));
            assert_true(g->data[1] == 0x21 || g->data[1] == 0x22 || g->data[1] == 0x23 ||
                        g->data[1] == 0x24 || g->data[1] == 0x31 || g->data[1] == 0x32 ||
                        g->data[1] == 0x33 || g->data[1] == 0x34 || g->data[1] == 0x26 ||
                        g->data[1] == 0x28 || g->data[1] == 0x36 || g->data[1] == 0x37 ||
                        g->data[1] == 0x38 || g->data[1] == 0x7F);
            assert_true(g->data[0] >= 1 && g->data[0] <= 127);
        }
        tu_log_clear(&fx->tb);
        fx->cursor = 0;
        /* no session outlives its timeout */
        for (k = 0; k < NSES; k++) {
            const co_usdo_session_t *s = &fx->ses[k];
            if (s->state == CO_USDO_SESSION_FREE)
                continue;
            assert_true(s->state == CO_USDO_SESSION_DOWNLOAD ||
                        s->state == CO_USDO_SESSION_UPLOAD || s->state == CO_USDO_SESSION_BULK);
            assert_true(co_timer_is_armed(&s->timer));
            assert_true(s->timer.deadline_us > now);
            assert_true(s->timer.deadline_us <= now + MS(1000));
            assert_true(s->xfer.state == CO_XFER_WRITE || s->xfer.state == CO_XFER_READ);
        }
    }
    tu_run_until(&fx->tb, now + MS(1000));
    assert_int_equal(co_usdo_server_active(&fx->srv), 0);
    /* everything counted */
    assert_int_equal(fx->srv.stats.rx_frames, 10000);
    assert_true(fx->srv.stats.rx_not_fd > 0);
    assert_true(fx->srv.stats.rx_empty > 0);
    assert_true(fx->srv.stats.rx_other_dest > 0);
    assert_true(fx->srv.stats.rx_malformed > 0);
    assert_true(fx->srv.stats.rx_unknown_command > 0);
    assert_true(fx->srv.stats.rx_no_session > 0);
    assert_true(fx->srv.stats.rx_stray_bulk > 0);
    assert_true(fx->srv.stats.rx_stray_abort > 0);
    assert_true(fx->srv.stats.rx_remote_abort > 0);
    assert_true(fx->srv.stats.od_aborts > 0);
    assert_true(fx->srv.stats.downloads + fx->srv.stats.uploads > 0);
    assert_true(responses > 1000);
    assert_int_equal(fx->srv.stats.tx_failed, 0);
    /* the server still works */
    exp_read_ok(fx, C1, 200, 0x2006, 0, U32, (const uint8_t *)"\x0D\xF0\xFE\xCA", 4);
}

/* ================================================= runner */

#define T(t) cmocka_unit_test_setup_teardown(t, setup, teardown)
#define BULK_UPLOAD_TESTS \
        T(test_bulk_upload_frames_and_window), \
        T(test_bulk_upload_sizes_and_counter_wrap), \
        T(test_bulk_upload_refusals), \
        T(test_bulk_upload_aborts), \
        T(test_bulk_upload_waits_for_tx_room), \
        T(test_bulk_upload_ack_with_tx_space_keeps_the_timeout), \
        T(test_bulk_upload_split), \
        T(test_short_segments_accepted_and_counted),

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_codec_decode_each_layout),
        cmocka_unit_test(test_codec_layout_of_every_command),
        cmocka_unit_test(test_codec_encode_each_response),
        cmocka_unit_test(test_codec_encode_refuses_what_does_not_fit),
        cmocka_unit_test(test_codec_decode_refuses_bad_lengths_and_commands),
        cmocka_unit_test(test_codec_bulk_frames),
        cmocka_unit_test(test_codec_every_truncation_refused),
        cmocka_unit_test(test_codec_random_input),
        cmocka_unit_test(test_codec_abort_mapping),
        T(test_init_refuses_classic_line_and_bad_config),
        T(test_default_timeout_is_one_second),
        T(test_derived_example_frames),
        T(test_expedited_each_size_class),
        T(test_expedited_empty_write),
        T(test_broadcast_answered_individually),
        T(test_segmented_boundaries),
        T(test_segmented_example_5),
        T(test_segmented_octet_string_1000),
        T(test_segmented_domain_100k_both_ways),
        T(test_segmented_domain_unknown_size),
        T(test_domain_reader_stall_or_error),
        T(test_abort_od_refusals),
        T(test_abort_unknown_command),
        T(test_abort_unknown_command_ends_open_transfer),
        T(test_abort_wrong_counter),
        T(test_abort_size_mismatch),
        T(test_abort_segment_without_session_or_of_wrong_kind),
        T(test_abort_malformed_frames),
        T(test_ignored_frames_are_counted),
        T(test_abort_busy),
        T(test_abort_parallel_access),
        T(test_abort_timeout),
        T(test_timeout_configurable),
        T(test_client_abort_ends_transfer),
        T(test_new_request_on_open_session_restarts),
        T(test_split_read_and_write),
        T(test_split_while_waiting_other_sessions_work),
        T(test_split_timeout_then_late_answer),
        T(test_deinit_aborts_open_transfers),
        T(test_bulk_accept_frame_carries_pacing),
        T(test_bulk_domain_1mib_counter_wraps),
        T(test_bulk_into_u32_and_strings),
        T(test_bulk_initiate_refusals),
        T(test_bulk_lost_segment),
        T(test_bulk_duplicated_segment),
        T(test_bulk_reordered_segments),
        T(test_bulk_size_mismatch),
        T(test_bulk_stray_segment_ignored),
        T(test_bulk_wrong_kind),
        T(test_bulk_malformed_frames),
        T(test_bulk_timeout),
        T(test_bulk_split_at_end_defers_0x28),
        T(test_bulk_busy),
        T(test_bulk_parallel_access),
        T(test_bulk_restart_and_client_abort),
        BULK_UPLOAD_TESTS
        T(test_random_garbage_never_wedges),
    };
    return cmocka_run_group_tests_name("usdo", tests, NULL, NULL);
}
