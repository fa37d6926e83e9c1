/* Classic SDO (CiA 301): CRC-16-CCITT, the wire codec (co_sdo) and the
 * server (co_sdo_server).
 *
 * Codec: every frame decoded from and encoded to exact bytes, every command
 * byte of both directions classified, every truncation refused without
 * reading past the buffer (heap blocks of exactly the decoded length, so
 * ASan sees any overrun), random input.
 *
 * Server: node S (id 5) serves an OD on classic line a; the "client" is raw
 * 8-byte frames sent from line b on 0x605 (or on the CAN-ID of a further
 * channel), and the sniffer checks every response frame whole: CAN-ID,
 * classic flags, length 8, every byte. The request bytes and the expected
 * answers are written out here by hand from the CiA 301 layouts (research
 * notes §6.2-6.4), not with the codec under test; the CRC is checked with a
 * bit-by-bit reference written here. */
#include "test_od_util.h"

#include "co_cob_id.h"
#include "co_crc.h"
#include "canopenfd/co_sdo.h"
#include "canopenfd/co_sdo_server.h"

#define ID_S 5
#define REQ0 (0x600u + ID_S)
#define RSP0 (0x580u + ID_S)
#define REQ1 0x6A5u                 /* channel 1 (0x1201), once enabled */
#define RSP1 0x6B5u
#define MS(x) ((uint64_t)(x) * TU_MS)
#define N_ENTRIES 48
#define POOL 8192
#define SUBS 8
#define NCH 3
#define SCR (CO_SDO_SERVER_BUFFER + 1000u)
#define DOM_CAP 102400u

#define OS CO_TYPE_OCTET_STRING
#define U24 CO_TYPE_UNSIGNED24
#define U64 CO_TYPE_UNSIGNED64
#define DOM CO_TYPE_DOMAIN
#define WO CO_ACCESS_WO

/* Abort codes as the research notes give them (§6.4). */
#define AB_TOGGLE 0x05030000u
#define AB_TIMEOUT 0x05040000u
#define AB_COMMAND 0x05040001u
#define AB_BLKSIZE 0x05040002u
#define AB_SEQNO 0x05040003u
#define AB_CRC 0x05040004u
#define AB_MEMORY 0x05040005u
#define AB_WRITE_ONLY 0x06010001u
#define AB_READ_ONLY 0x06010002u
#define AB_NO_OBJECT 0x06020000u
#define AB_LEN_HIGH 0x06070012u
#define AB_LEN_LOW 0x06070013u
#define AB_NO_SUB 0x06090011u
#define AB_INVALID 0x06090030u
#define AB_HIGH 0x06090031u
#define AB_LOW 0x06090032u
#define AB_RESOURCE 0x060A0023u
#define AB_STATE 0x08000022u

/* ------------------------------------------------------------- reference CRC */

/* CRC-16-CCITT bit by bit (poly 0x1021, init 0, MSB first, no xorout). */
static uint16_t ref_crc(uint16_t crc, const uint8_t *p, size_t n)
{
    size_t i;
    int b;
    for (i = 0; i < n; i++) {
        crc ^= (uint16_t)(p[i] << 8);
        for (b = 0; b < 8; b++)
            crc = (crc & 0x8000u) ? (uint16_t)((crc << 1) ^ 0x1021u) : (uint16_t)(crc << 1);
    }
    return crc;
}

/* ------------------------------------------------------------- fixture */

typedef struct fault {
    uint32_t id;                  /* frames with this CAN-ID are counted (1-based) */
    uint32_t count;
    uint32_t drop[8];             /* numbers to lose */
    unsigned n_drop;
    uint32_t dup[8];              /* numbers to deliver twice */
    unsigned n_dup;
    bool dup_all;
} fault_t;

typedef struct fx {
    tu_bus_t tb;
    tu_line_t l[2];
    co_line_t *a, *b;
    co_node_t node;
    co_od_t od;
    co_od_entry_t entries[N_ENTRIES];
    uint8_t pool[POOL];
    co_od_subscription_t subs[SUBS];
    co_sdo_server_t srv;
    co_sdo_channel_t ch[NCH];
    uint8_t scratch[NCH * SCR];
    size_t cursor;                /* next log entry to look at */
    uint32_t req_id, rsp_id;      /* the channel a test talks to */
    /* the domain 0x2009 (and 0x200C, same data, size unknown) */
    uint8_t domain[DOM_CAP];
    uint32_t dom_len;
    uint8_t staging[DOM_CAP];
    uint32_t dom_read_error;
    unsigned dom_commits;
    unsigned dom_aborts;
    uint32_t dom_last_abort;
    /* split handler of 0x200B */
    bool split_read, split_write;
    co_od_xfer_t *held;
    fault_t fault;
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
    k = fx->dom_len - offset;
    if (k > cap)
        k = cap;
    if (k > 100)               /* small chunks: the server must collect them */
        k = 100;
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
    { 0x1200, 0, REC, U8, AC_CONST, 0, 1, 2, NULL, 0, 0 },
    { 0x1200, 1, REC, U32, AC_CONST, CO_OD_NODEID_RELATIVE, 4, 0x600, NULL, 0, 0 },
    { 0x1200, 2, REC, U32, AC_CONST, CO_OD_NODEID_RELATIVE, 4, 0x580, NULL, 0, 0 },
    { 0x1201, 0, REC, U8, AC_CONST, 0, 1, 3, NULL, 0, 0 },
    { 0x1201, 1, REC, U32, RW, 0, 4, 0x80000000, NULL, 0, 0 },
    { 0x1201, 2, REC, U32, RW, 0, 4, 0x80000000, NULL, 0, 0 },
    { 0x1201, 3, REC, U8, RW, 0, 1, 0, NULL, 0, 0 },
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
    { 0x2011, 0, VAR, U24, RW, 0, 3, 0x123456, NULL, 0, 0 },
    { 0x2012, 0, VAR, OS, RW, 0, 2000, 0, "", 0, 0 },   /* larger than a channel's scratch */
};

static void build_od(fx_t *fx)
{
    co_od_def_t d;
    co_od_init(&fx->od, CO_MODE_CLASSIC, fx->entries, N_ENTRIES, fx->pool, POOL, fx->subs, SUBS);
    tu_od_add_rows(&fx->od, od_rows, sizeof od_rows / sizeof od_rows[0]);
    d = tu_od_def(0x2009, 0, VAR, DOM, RW, 0, 0);
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ADDED);
    d = tu_od_def(0x200C, 0, VAR, DOM, RW, 0, 0);
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ADDED);
    assert_true(co_od_seal(&fx->od, ID_S));
    assert_true(co_od_subscribe(&fx->od, 0x2009, 0, 0x2009, 0, &dom_handler, fx));
    assert_true(co_od_subscribe(&fx->od, 0x200C, 0, 0x200C, 0, &dom_nosize_handler, fx));
    assert_true(co_od_subscribe(&fx->od, 0x200B, 0, 0x200B, 0, &split_handler, fx));
    assert_true(co_cob_id_attach(&fx->od));
}

static void server_init_cfg(fx_t *fx, uint32_t timeout_ms, uint8_t block_size, bool no_crc)
{
    co_sdo_server_config_t cfg;
    memset(&cfg, 0, sizeof cfg);
    cfg.channels = fx->ch;
    cfg.channel_count = NCH;
    cfg.scratch = fx->scratch;
    cfg.scratch_size = SCR;
    cfg.timeout_ms = timeout_ms;
    cfg.block_size = block_size;
    cfg.no_crc = no_crc;
    assert_true(co_sdo_server_init(&fx->srv, fx->a, &fx->od, &cfg));
}

static uint8_t fault_fn(const co_frame_t *f, void *user)
{
    fault_t *ft = user;
    unsigned i;
    if (f->id != ft->id)
        return 1;
    ft->count++;
    for (i = 0; i < ft->n_drop; i++)
        if (ft->drop[i] == ft->count)
            return 0;
    for (i = 0; i < ft->n_dup; i++)
        if (ft->dup[i] == ft->count)
            return 2;
    return ft->dup_all ? 2 : 1;
}

static int setup(void **state)
{
    uint32_t i;
    fx_t *fx = calloc(1, sizeof *fx);
    if (fx == NULL)
        return -1;
    tu_bus_init(&fx->tb, CO_MODE_CLASSIC, false);
    fx->a = tu_bus_add_line(&fx->tb, &fx->l[0]);
    fx->b = tu_bus_add_line(&fx->tb, &fx->l[1]);
    build_od(fx);
    assert_true(co_node_init(&fx->node, fx->a, ID_S, 0, NULL, NULL));
    fx->dom_len = 100;
    for (i = 0; i < DOM_CAP; i++)
        fx->domain[i] = (uint8_t)(i * 7u + 3u);
    server_init_cfg(fx, 0, 0, false);
    fx->req_id = REQ0;
    fx->rsp_id = RSP0;
    co_membus_set_fault(&fx->tb.bus, fault_fn, &fx->fault);
    fx->fault.id = 0xFFFFFFFFu;
    tu_step(&fx->tb, MS(10));
    *state = fx;
    return 0;
}

static int teardown(void **state)
{
    free(*state);
    return 0;
}

/* ------------------------------------------------------------ frames */

static void le_put32(uint8_t *p, uint32_t v) { tu_le_put(p, v, 4); }

/* An 8-byte frame: command, index, sub, 4 bytes (LE value). */
static void mux8(uint8_t *b, uint8_t cmd, uint16_t index, uint8_t sub, uint32_t d)
{
    b[0] = cmd;
    b[1] = (uint8_t)(index & 0xFF);
    b[2] = (uint8_t)(index >> 8);
    b[3] = sub;
    le_put32(b + 4, d);
}

/* An 8-byte frame: byte 0, then up to 7 bytes of data (rest 0). */
static void seg8(uint8_t *b, uint8_t cmd, const uint8_t *data, uint32_t n)
{
    memset(b, 0, 8);
    b[0] = cmd;
    if (n > 0)
        memcpy(b + 1, data, n);
}

static void drop_consumed(fx_t *fx)
{
    if (fx->cursor == fx->tb.log_count) {
        tu_log_clear(&fx->tb);
        fx->cursor = 0;
    }
}

/* Send an 8-byte request on the current channel and let the bus settle. */
static void req(fx_t *fx, const uint8_t *b)
{
    drop_consumed(fx);
    assert_true(co_line_send(fx->b, fx->req_id, b, 8));
    tu_step(&fx->tb, fx->tb.now);
}

/* Send a frame exactly as given (any length, id). */
static void req_raw(fx_t *fx, uint32_t id, const uint8_t *b, uint8_t len)
{
    co_frame_t f = tu_frame(id, 0, b, len);
    drop_consumed(fx);
    assert_true(co_line_send_raw(fx->b, &f));
    tu_step(&fx->tb, fx->tb.now);
}

static void req_mux(fx_t *fx, uint8_t cmd, uint16_t index, uint8_t sub, uint32_t d)
{
    uint8_t b[8];
    mux8(b, cmd, index, sub, d);
    req(fx, b);
}

static void req_cmd(fx_t *fx, uint8_t cmd)
{
    uint8_t b[8];
    seg8(b, cmd, NULL, 0);
    req(fx, b);
}

static bool is_request_id(uint32_t id)
{
    return id == REQ0 || id == REQ1 || (id >= 0x601u && id <= 0x67Fu) || id == 0x6A6u ||
           id == 0x6C0u;
}

/* Next server frame on the current response CAN-ID (requests skipped). */
static const co_frame_t *next_rsp(fx_t *fx)
{
    while (fx->cursor < fx->tb.log_count) {
        const co_frame_t *f = &fx->tb.log[fx->cursor++].frame;
        if (f->id == fx->rsp_id)
            return f;
        if (!is_request_id(f->id))
            fail_msg("unexpected frame 0x%03X", (unsigned)f->id);
    }
    return NULL;
}

static void expect(fx_t *fx, const uint8_t *b)
{
    const co_frame_t *f = next_rsp(fx);
    if (f == NULL)
        fail_msg("no response");
    tu_assert_frame(f, fx->rsp_id, 0, b, 8);
}

static void expect_mux(fx_t *fx, uint8_t cmd, uint16_t index, uint8_t sub, uint32_t d)
{
    uint8_t e[8];
    mux8(e, cmd, index, sub, d);
    expect(fx, e);
}

static void expect_cmd(fx_t *fx, uint8_t cmd)
{
    uint8_t e[8];
    seg8(e, cmd, NULL, 0);
    expect(fx, e);
}

static void expect_abort(fx_t *fx, uint16_t index, uint8_t sub, uint32_t code)
{
    expect_mux(fx, 0x80, index, sub, code);
}

static void expect_none(fx_t *fx)
{
    const co_frame_t *f = next_rsp(fx);
    if (f != NULL)
        fail_msg("unexpected response 0x%02X", f->data[0]);
}

static void expect_ack(fx_t *fx, uint8_t ackseq, uint8_t blksize)
{
    uint8_t e[8] = { 0xA2, ackseq, blksize, 0, 0, 0, 0, 0 };
    expect(fx, e);
}

/* ------------------------------------------------------------ client flows */

/* Expedited download with the size indicated (n = 1..4). */
static void exp_write_ok(fx_t *fx, uint16_t index, uint8_t sub, const uint8_t *data, uint8_t n)
{
    uint8_t b[8];
    mux8(b, (uint8_t)(0x23 | (4 - n) << 2), index, sub, 0);
    memcpy(b + 4, data, n);
    req(fx, b);
    expect_mux(fx, 0x60, index, sub, 0);
    expect_none(fx);
}

/* Expedited upload of n = 1..4 bytes. */
static void exp_read_ok(fx_t *fx, uint16_t index, uint8_t sub, const uint8_t *data, uint8_t n)
{
    uint8_t e[8];
    req_mux(fx, 0x40, index, sub, 0);
    mux8(e, (uint8_t)(0x43 | (4 - n) << 2), index, sub, 0);
    memcpy(e + 4, data, n);
    expect(fx, e);
    expect_none(fx);
}

/* Segments 1..: every 7 bytes, toggle from 0, c on the last; every answer
 * checked. */
static void seg_segments_ok(fx_t *fx, const uint8_t *data, uint32_t n)
{
    uint32_t off = 0;
    uint8_t t = 0;
    for (;;) {
        uint8_t b[8];
        uint32_t k = n - off < 7 ? n - off : 7;
        bool last = off + k == n;
        seg8(b, (uint8_t)(t << 4 | (7 - k) << 1 | (last ? 1 : 0)), data + off, k);
        req(fx, b);
        expect_cmd(fx, (uint8_t)(0x20 | t << 4));
        off += k;
        t ^= 1;
        if (last)
            break;
    }
    expect_none(fx);
}

static void seg_write_ok(fx_t *fx, uint16_t index, uint8_t sub, const uint8_t *data, uint32_t n,
                         bool size_indicated)
{
    req_mux(fx, size_indicated ? 0x21 : 0x20, index, sub, size_indicated ? n : 0);
    expect_mux(fx, 0x60, index, sub, 0);
    seg_segments_ok(fx, data, n);
}

/* Segmented upload of data[n]; `size` = the size the initiate response must
 * indicate, or -1 for none (0x40). */
static void seg_read_ok(fx_t *fx, uint16_t index, uint8_t sub, const uint8_t *data, uint32_t n,
                        int64_t size)
{
    uint32_t off = 0;
    uint8_t t = 0;
    req_mux(fx, 0x40, index, sub, 0);
    if (size < 0)
        expect_mux(fx, 0x40, index, sub, 0);
    else
        expect_mux(fx, 0x41, index, sub, (uint32_t)size);
    for (;;) {
        uint8_t e[8];
        uint32_t k = n - off < 7 ? n - off : 7;
        bool last = off + k == n;
        req_cmd(fx, (uint8_t)(0x60 | t << 4));
        seg8(e, (uint8_t)(t << 4 | (7 - k) << 1 | (last ? 1 : 0)), data + off, k);
        expect(fx, e);
        off += k;
        t ^= 1;
        if (last)
            break;
    }
    expect_none(fx);
}

/* Block download of data[n], every frame checked: the initiate answer with
 * `blksize` and sc = `sc`, one ack per sub-block, the end with the CRC. */
static void block_write_ok(fx_t *fx, uint16_t index, uint8_t sub, const uint8_t *data,
                           uint32_t n, bool cc, bool size_indicated, bool sc, uint8_t blksize)
{
    uint32_t off = 0;
    uint8_t seq = 0, last_len = 0;
    uint8_t b[8];
    req_mux(fx, (uint8_t)(0xC0 | (cc ? 4 : 0) | (size_indicated ? 2 : 0)), index, sub,
            size_indicated ? n : 0);
    expect_mux(fx, (uint8_t)(0xA0 | (sc ? 4 : 0)), index, sub, blksize);
    for (;;) {
        uint32_t k = n - off < 7 ? n - off : 7;
        bool last = off + k >= n;
        seq++;
        seg8(b, (uint8_t)(seq | (last ? 0x80 : 0)), data + off, k);
        req(fx, b);
        off += k;
        last_len = (uint8_t)k;
        if (last || seq == blksize) {
            expect_ack(fx, seq, blksize);
            expect_none(fx);
            seq = 0;
            if (last)
                break;
        } else {
            expect_none(fx);
        }
    }
    {
        uint16_t crc = cc && sc ? ref_crc(0, data, n) : 0;
        b[0] = (uint8_t)(0xC1 | (7 - last_len) << 2);
        b[1] = (uint8_t)(crc & 0xFF);
        b[2] = (uint8_t)(crc >> 8);
        memset(b + 3, 0, 5);
        req(fx, b);
    }
    expect_cmd(fx, 0xA1);
    expect_none(fx);
}

/* Block upload of data[n] with the client's blksize (pst 0), every frame
 * checked; size < 0: the size is not indicated. */
static void block_read_ok(fx_t *fx, uint16_t index, uint8_t sub, const uint8_t *data, uint32_t n,
                          bool cc, bool sc, uint8_t blksize, int64_t size)
{
    uint32_t off = 0;
    uint8_t b[8];
    mux8(b, (uint8_t)(0xA0 | (cc ? 4 : 0)), index, sub, 0);
    b[4] = blksize;
    req(fx, b);
    expect_mux(fx, (uint8_t)(0xC0 | (sc ? 4 : 0) | (size >= 0 ? 2 : 0)), index, sub,
               size >= 0 ? (uint32_t)size : 0);
    expect_none(fx);
    req_cmd(fx, 0xA3);
    for (;;) {
        uint8_t seq;
        uint32_t k = 7;
        bool last = false;
        for (seq = 1; seq <= blksize; seq++) {
            uint8_t e[8];
            k = n - off < 7 ? n - off : 7;
            last = off + k >= n;
            seg8(e, (uint8_t)(seq | (last ? 0x80 : 0)), data + off, k);
            expect(fx, e);
            off += k;
            if (last)
                break;
        }
        expect_none(fx);
        b[0] = 0xA2;
        b[1] = last ? seq : blksize;
        b[2] = blksize;
        memset(b + 3, 0, 5);
        req(fx, b);
        if (last) {
            /* the server sends its CRC whenever it supports it */
            uint16_t crc = sc ? ref_crc(0, data, n) : 0;
            uint8_t e[8] = { (uint8_t)(0xC1 | (7 - k) << 2), (uint8_t)(crc & 0xFF),
                             (uint8_t)(crc >> 8), 0, 0, 0, 0, 0 };
            expect(fx, e);
            expect_none(fx);
            break;
        }
    }
    req_cmd(fx, 0xA1);
    expect_none(fx);
}

static void fill_pattern(uint8_t *p, uint32_t n, uint8_t seed)
{
    uint32_t i;
    for (i = 0; i < n; i++)
        p[i] = (uint8_t)(seed + i * 13u + (i >> 8));
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
    static uint8_t buf[2000];
    uint32_t len = 0;
    assert_int_equal(co_od_get(&fx->od, index, sub, buf, sizeof buf, &len), 0);
    assert_int_equal(len, n);
    if (n > 0)
        assert_memory_equal(buf, data, n);
}

static void assert_all_idle(const fx_t *fx)
{
    uint8_t i;
    assert_int_equal(co_sdo_server_active(&fx->srv), 0);
    for (i = 0; i < NCH; i++)
        assert_false(co_timer_is_armed(&fx->ch[i].timer));
}

static void use_channel(fx_t *fx, uint32_t req_id, uint32_t rsp_id)
{
    fx->req_id = req_id;
    fx->rsp_id = rsp_id;
}

static void reinit_server(fx_t *fx, uint32_t timeout_ms, uint8_t block_size, bool no_crc)
{
    co_sdo_server_deinit(&fx->srv);
    server_init_cfg(fx, timeout_ms, block_size, no_crc);
}

/* Enable channel 1 on REQ1 / RSP1 through the default channel. */
static void enable_channel1(fx_t *fx)
{
    uint32_t r = fx->req_id, s = fx->rsp_id;
    uint8_t v[4];
    use_channel(fx, REQ0, RSP0);
    le_put32(v, RSP1);
    exp_write_ok(fx, 0x1201, 2, v, 4);
    le_put32(v, REQ1);
    exp_write_ok(fx, 0x1201, 1, v, 4);
    assert_true(fx->ch[1].valid);
    use_channel(fx, r, s);
}

/* ================================================= CRC */

static void test_crc16_ccitt(void **state)
{
    static const uint8_t check[] = "123456789";
    uint8_t data[1000];
    uint64_t seed = 42;
    unsigned i;
    (void)state;
    assert_int_equal(co_crc16_ccitt(0, check, 9), 0x31C3);
    assert_int_equal(ref_crc(0, check, 9), 0x31C3);
    assert_int_equal(co_crc16_ccitt(0, NULL, 0), 0);
    assert_int_equal(co_crc16_ccitt(co_crc16_ccitt(0, check, 4), check + 4, 5), 0x31C3);
    for (i = 0; i < sizeof data; i++)
        data[i] = (uint8_t)tu_rand(&seed);
    for (i = 0; i < 200; i++) {
        size_t n = (size_t)(tu_rand(&seed) % sizeof data);
        size_t cut = n == 0 ? 0 : (size_t)(tu_rand(&seed) % n);
        uint16_t whole = co_crc16_ccitt(0, data, n);
        assert_int_equal(whole, ref_crc(0, data, n));
        assert_int_equal(co_crc16_ccitt(co_crc16_ccitt(0, data, cut), data + cut, n - cut), whole);
    }
}

/* ================================================= codec */

/* Decode from a heap block of exactly len bytes (ASan sees any overrun). */
static co_sdo_decode_result_t decode_exact(const uint8_t *b, size_t len, co_sdo_dir_t dir,
                                           co_sdo_msg_t *m, bool segment)
{
    co_sdo_decode_result_t r;
    uint8_t *p = malloc(len > 0 ? len : 1);
    assert_non_null(p);
    if (len > 0)
        memcpy(p, b, len);
    r = segment ? co_sdo_decode_block_segment(len > 0 ? p : NULL, len, m)
                : co_sdo_decode(len > 0 ? p : NULL, len, dir, m);
    if (m->data != NULL) {
        assert_true(m->data >= p && m->data + m->length <= p + len);
        m->data = b + (m->data - p);
    }
    free(p);
    return r;
}

static co_sdo_msg_t dec(const uint8_t *b, co_sdo_dir_t dir)
{
    co_sdo_msg_t m;
    assert_int_equal(decode_exact(b, 8, dir, &m, false), CO_SDO_DECODE_OK);
    return m;
}

static void test_codec_decode_requests(void **state)
{
    co_sdo_msg_t m;
    /* expedited download, 2 bytes, size indicated: 0x2B */
    const uint8_t e2[8] = { 0x2B, 0x17, 0x10, 0x00, 0xE8, 0x03, 0x99, 0x99 };
    /* expedited, size not indicated: 0x22 */
    const uint8_t e4[8] = { 0x22, 0x00, 0x20, 0x01, 1, 2, 3, 4 };
    /* segmented download with size 0x12345 */
    const uint8_t sd[8] = { 0x21, 0x09, 0x20, 0x00, 0x45, 0x23, 0x01, 0x00 };
    const uint8_t seg[8] = { 0x1B, 'a', 'b', 'c', 'd', 'e', 0, 0 };   /* t=1 n=5 c=1 */
    const uint8_t up[8] = { 0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0 };
    const uint8_t us[8] = { 0x70, 0, 0, 0, 0, 0, 0, 0 };
    const uint8_t bdi[8] = { 0xC6, 0x09, 0x20, 0x00, 0xA0, 0x86, 0x01, 0x00 };
    const uint8_t bde[8] = { 0xD5, 0x34, 0x12, 0, 0, 0, 0, 0 };        /* n = 5 */
    const uint8_t bui[8] = { 0xA4, 0x09, 0x20, 0x00, 0x7F, 0x15, 0, 0 };
    const uint8_t bur[8] = { 0xA1, 0, 0, 0, 0, 0, 0, 0 };
    const uint8_t bua[8] = { 0xA2, 0x05, 0x40, 0, 0, 0, 0, 0 };
    const uint8_t bus_[8] = { 0xA3, 0, 0, 0, 0, 0, 0, 0 };
    const uint8_t ab[8] = { 0x80, 0x00, 0x20, 0x03, 0x00, 0x00, 0x04, 0x05 };
    (void)state;
    m = dec(e2, CO_SDO_TO_SERVER);
    assert_int_equal(m.frame, CO_SDO_DOWNLOAD_INITIATE);
    assert_int_equal(m.index, 0x1017);
    assert_int_equal(m.sub, 0);
    assert_true(m.expedited && m.size_indicated);
    assert_int_equal(m.length, 2);
    assert_ptr_equal(m.data, e2 + 4);
    m = dec(e4, CO_SDO_TO_SERVER);
    assert_true(m.expedited && !m.size_indicated);
    assert_int_equal(m.length, 4);
    assert_int_equal(m.sub, 1);
    m = dec(sd, CO_SDO_TO_SERVER);
    assert_false(m.expedited);
    assert_true(m.size_indicated);
    assert_int_equal(m.size, 0x12345);
    assert_int_equal(m.length, 0);
    assert_null(m.data);
    m = dec(seg, CO_SDO_TO_SERVER);
    assert_int_equal(m.frame, CO_SDO_DOWNLOAD_SEGMENT);
    assert_int_equal(m.toggle, 1);
    assert_true(m.last);
    assert_int_equal(m.length, 2);
    assert_ptr_equal(m.data, seg + 1);
    m = dec(up, CO_SDO_TO_SERVER);
    assert_int_equal(m.frame, CO_SDO_UPLOAD_INITIATE);
    assert_int_equal(m.index, 0x1018);
    assert_int_equal(m.sub, 1);
    m = dec(us, CO_SDO_TO_SERVER);
    assert_int_equal(m.frame, CO_SDO_UPLOAD_SEGMENT);
    assert_int_equal(m.toggle, 1);
    m = dec(bdi, CO_SDO_TO_SERVER);
    assert_int_equal(m.frame, CO_SDO_BLOCK_DOWNLOAD_INITIATE);
    assert_true(m.crc && m.size_indicated);
    assert_int_equal(m.size, 100000);
    assert_int_equal(m.index, 0x2009);
    m = dec(bde, CO_SDO_TO_SERVER);
    assert_int_equal(m.frame, CO_SDO_BLOCK_DOWNLOAD_END);
    assert_int_equal(m.unused, 5);
    assert_int_equal(m.crc_value, 0x1234);
    m = dec(bui, CO_SDO_TO_SERVER);
    assert_int_equal(m.frame, CO_SDO_BLOCK_UPLOAD_INITIATE);
    assert_true(m.crc);
    assert_int_equal(m.blksize, 127);
    assert_int_equal(m.pst, 21);
    m = dec(bur, CO_SDO_TO_SERVER);
    assert_int_equal(m.frame, CO_SDO_BLOCK_UPLOAD_END_RSP);
    m = dec(bua, CO_SDO_TO_SERVER);
    assert_int_equal(m.frame, CO_SDO_BLOCK_UPLOAD_ACK);
    assert_int_equal(m.seqno, 5);
    assert_int_equal(m.blksize, 0x40);
    m = dec(bus_, CO_SDO_TO_SERVER);
    assert_int_equal(m.frame, CO_SDO_BLOCK_UPLOAD_START);
    m = dec(ab, CO_SDO_TO_SERVER);
    assert_int_equal(m.frame, CO_SDO_ABORT);
    assert_int_equal(m.index, 0x2000);
    assert_int_equal(m.sub, 3);
    assert_int_equal(m.abort_code, 0x05040000);
}

static void test_codec_decode_responses(void **state)
{
    co_sdo_msg_t m;
    const uint8_t di[8] = { 0x60, 0x17, 0x10, 0x00, 0, 0, 0, 0 };
    const uint8_t ds[8] = { 0x30, 0, 0, 0, 0, 0, 0, 0 };
    const uint8_t ue[8] = { 0x4F, 0x00, 0x20, 0x00, 0x11, 0, 0, 0 };     /* 1 byte */
    const uint8_t us[8] = { 0x41, 0x04, 0x20, 0x00, 0x05, 0, 0, 0 };     /* size 5 */
    const uint8_t un[8] = { 0x40, 0x0C, 0x20, 0x00, 0, 0, 0, 0 };        /* size not indicated */
    const uint8_t seg[8] = { 0x05, 'h', 'e', 'l', 'l', 'o', 0, 0 };     /* t=0 n=2 c=1 */
    const uint8_t bdi[8] = { 0xA4, 0x09, 0x20, 0x00, 0x7F, 0, 0, 0 };
    const uint8_t bde[8] = { 0xA1, 0, 0, 0, 0, 0, 0, 0 };
    const uint8_t bda[8] = { 0xA2, 0x7F, 0x7F, 0, 0, 0, 0, 0 };
    const uint8_t bui[8] = { 0xC6, 0x09, 0x20, 0x00, 0x64, 0, 0, 0 };
    const uint8_t bue[8] = { 0xC9, 0xC3, 0x31, 0, 0, 0, 0, 0 };          /* n = 2 */
    (void)state;
    m = dec(di, CO_SDO_TO_CLIENT);
    assert_int_equal(m.frame, CO_SDO_DOWNLOAD_INITIATE_RSP);
    assert_int_equal(m.index, 0x1017);
    m = dec(ds, CO_SDO_TO_CLIENT);
    assert_int_equal(m.frame, CO_SDO_DOWNLOAD_SEGMENT_RSP);
    assert_int_equal(m.toggle, 1);
    m = dec(ue, CO_SDO_TO_CLIENT);
    assert_int_equal(m.frame, CO_SDO_UPLOAD_INITIATE_RSP);
    assert_true(m.expedited && m.size_indicated);
    assert_int_equal(m.length, 1);
    assert_int_equal(m.data[0], 0x11);
    m = dec(us, CO_SDO_TO_CLIENT);
    assert_false(m.expedited);
    assert_true(m.size_indicated);
    assert_int_equal(m.size, 5);
    m = dec(un, CO_SDO_TO_CLIENT);
    assert_false(m.expedited || m.size_indicated);
    assert_int_equal(m.index, 0x200C);
    m = dec(seg, CO_SDO_TO_CLIENT);
    assert_int_equal(m.frame, CO_SDO_UPLOAD_SEGMENT_RSP);
    assert_int_equal(m.toggle, 0);
    assert_true(m.last);
    assert_int_equal(m.length, 5);
    m = dec(bdi, CO_SDO_TO_CLIENT);
    assert_int_equal(m.frame, CO_SDO_BLOCK_DOWNLOAD_INITIATE_RSP);
    assert_true(m.crc);
    assert_int_equal(m.blksize, 127);
    assert_int_equal(m.pst, 0);
    m = dec(bde, CO_SDO_TO_CLIENT);
    assert_int_equal(m.frame, CO_SDO_BLOCK_DOWNLOAD_END_RSP);
    m = dec(bda, CO_SDO_TO_CLIENT);
    assert_int_equal(m.frame, CO_SDO_BLOCK_DOWNLOAD_ACK);
    assert_int_equal(m.seqno, 127);
    assert_int_equal(m.blksize, 127);
    m = dec(bui, CO_SDO_TO_CLIENT);
    assert_int_equal(m.frame, CO_SDO_BLOCK_UPLOAD_INITIATE_RSP);
    assert_true(m.crc && m.size_indicated);
    assert_int_equal(m.size, 100);
    m = dec(bue, CO_SDO_TO_CLIENT);
    assert_int_equal(m.frame, CO_SDO_BLOCK_UPLOAD_END);
    assert_int_equal(m.unused, 2);
    assert_int_equal(m.crc_value, 0x31C3);
    /* block segments (either direction) */
    {
        const uint8_t bs[8] = { 0x85, 1, 2, 3, 4, 5, 6, 7 };
        assert_int_equal(decode_exact(bs, 8, CO_SDO_TO_SERVER, &m, true), CO_SDO_DECODE_OK);
        assert_int_equal(m.frame, CO_SDO_BLOCK_SEGMENT);
        assert_int_equal(m.seqno, 5);
        assert_true(m.last);
        assert_int_equal(m.length, 7);
        assert_ptr_equal(m.data, bs + 1);
    }
}

/* Every frame encoded to exact bytes, then decoded back to the same fields. */
static void check_encode(const co_sdo_msg_t *m, const uint8_t *want)
{
    uint8_t out[8];
    co_sdo_msg_t back;
    co_sdo_dir_t dir = co_sdo_frame_dir((co_sdo_frame_t)m->frame);
    assert_int_equal(co_sdo_encode(m, out), 8);
    assert_memory_equal(out, want, 8);
    if (m->frame == CO_SDO_BLOCK_SEGMENT)
        assert_int_equal(co_sdo_decode_block_segment(out, 8, &back), CO_SDO_DECODE_OK);
    else
        assert_int_equal(co_sdo_decode(out, 8, dir, &back), CO_SDO_DECODE_OK);
    assert_int_equal(back.frame, m->frame);
    assert_int_equal(back.index, m->index);
    assert_int_equal(back.sub, m->sub);
    assert_int_equal(back.toggle, m->toggle);
    assert_int_equal(back.last, m->last);
    assert_int_equal(back.crc, m->crc);
    assert_int_equal(back.seqno, m->seqno);
    assert_int_equal(back.blksize, m->blksize);
    assert_int_equal(back.unused, m->unused);
    assert_int_equal(back.crc_value, m->crc_value);
    assert_int_equal(back.abort_code, m->abort_code);
    if (m->size_indicated)
        assert_int_equal(back.size, m->size);
}

static co_sdo_msg_t msg(co_sdo_frame_t frame, uint16_t index, uint8_t sub)
{
    co_sdo_msg_t m;
    memset(&m, 0, sizeof m);
    m.frame = (uint8_t)frame;
    m.index = index;
    m.sub = sub;
    return m;
}

static void test_codec_encode_every_frame(void **state)
{
    static const uint8_t d[7] = { 1, 2, 3, 4, 5, 6, 7 };
    co_sdo_msg_t m;
    (void)state;
    /* client -> server */
    m = msg(CO_SDO_DOWNLOAD_INITIATE, 0x1017, 0);
    m.expedited = m.size_indicated = true;
    m.length = 2;
    m.data = d;
    check_encode(&m, (const uint8_t[8]){ 0x2B, 0x17, 0x10, 0x00, 1, 2, 0, 0 });
    m.length = 1;
    check_encode(&m, (const uint8_t[8]){ 0x2F, 0x17, 0x10, 0x00, 1, 0, 0, 0 });
    m.length = 3;
    check_encode(&m, (const uint8_t[8]){ 0x27, 0x17, 0x10, 0x00, 1, 2, 3, 0 });
    m.length = 4;
    check_encode(&m, (const uint8_t[8]){ 0x23, 0x17, 0x10, 0x00, 1, 2, 3, 4 });
    m.size_indicated = false;
    check_encode(&m, (const uint8_t[8]){ 0x22, 0x17, 0x10, 0x00, 1, 2, 3, 4 });
    m = msg(CO_SDO_DOWNLOAD_INITIATE, 0x2009, 0);
    m.size_indicated = true;
    m.size = 100000;
    check_encode(&m, (const uint8_t[8]){ 0x21, 0x09, 0x20, 0x00, 0xA0, 0x86, 0x01, 0x00 });
    m.size_indicated = false;
    check_encode(&m, (const uint8_t[8]){ 0x20, 0x09, 0x20, 0x00, 0, 0, 0, 0 });
    m = msg(CO_SDO_DOWNLOAD_SEGMENT, 0, 0);
    m.length = 7;
    m.data = d;
    check_encode(&m, (const uint8_t[8]){ 0x00, 1, 2, 3, 4, 5, 6, 7 });
    m.toggle = 1;
    m.last = true;
    m.length = 3;
    check_encode(&m, (const uint8_t[8]){ 0x19, 1, 2, 3, 0, 0, 0, 0 });
    m.length = 0;
    check_encode(&m, (const uint8_t[8]){ 0x1F, 0, 0, 0, 0, 0, 0, 0 });
    m = msg(CO_SDO_UPLOAD_INITIATE, 0x1018, 4);
    check_encode(&m, (const uint8_t[8]){ 0x40, 0x18, 0x10, 0x04, 0, 0, 0, 0 });
    m = msg(CO_SDO_UPLOAD_SEGMENT, 0, 0);
    check_encode(&m, (const uint8_t[8]){ 0x60, 0, 0, 0, 0, 0, 0, 0 });
    m.toggle = 1;
    check_encode(&m, (const uint8_t[8]){ 0x70, 0, 0, 0, 0, 0, 0, 0 });
    m = msg(CO_SDO_BLOCK_DOWNLOAD_INITIATE, 0x2009, 0);
    m.crc = true;
    m.size_indicated = true;
    m.size = 0x01020304;
    check_encode(&m, (const uint8_t[8]){ 0xC6, 0x09, 0x20, 0x00, 4, 3, 2, 1 });
    m.crc = false;
    m.size_indicated = false;
    check_encode(&m, (const uint8_t[8]){ 0xC0, 0x09, 0x20, 0x00, 0, 0, 0, 0 });
    m = msg(CO_SDO_BLOCK_DOWNLOAD_END, 0, 0);
    m.unused = 6;
    m.crc_value = 0xBEEF;
    check_encode(&m, (const uint8_t[8]){ 0xD9, 0xEF, 0xBE, 0, 0, 0, 0, 0 });
    m = msg(CO_SDO_BLOCK_UPLOAD_INITIATE, 0x2009, 0);
    m.crc = true;
    m.blksize = 127;
    m.pst = 21;
    check_encode(&m, (const uint8_t[8]){ 0xA4, 0x09, 0x20, 0x00, 0x7F, 0x15, 0, 0 });
    m = msg(CO_SDO_BLOCK_UPLOAD_END_RSP, 0, 0);
    check_encode(&m, (const uint8_t[8]){ 0xA1, 0, 0, 0, 0, 0, 0, 0 });
    m = msg(CO_SDO_BLOCK_UPLOAD_ACK, 0, 0);
    m.seqno = 0;
    m.blksize = 1;
    check_encode(&m, (const uint8_t[8]){ 0xA2, 0, 1, 0, 0, 0, 0, 0 });
    m = msg(CO_SDO_BLOCK_UPLOAD_START, 0, 0);
    check_encode(&m, (const uint8_t[8]){ 0xA3, 0, 0, 0, 0, 0, 0, 0 });
    /* server -> client */
    m = msg(CO_SDO_DOWNLOAD_INITIATE_RSP, 0x1017, 0);
    check_encode(&m, (const uint8_t[8]){ 0x60, 0x17, 0x10, 0x00, 0, 0, 0, 0 });
    m = msg(CO_SDO_DOWNLOAD_SEGMENT_RSP, 0, 0);
    m.toggle = 1;
    check_encode(&m, (const uint8_t[8]){ 0x30, 0, 0, 0, 0, 0, 0, 0 });
    m = msg(CO_SDO_UPLOAD_INITIATE_RSP, 0x1000, 0);
    m.expedited = m.size_indicated = true;
    m.length = 4;
    m.data = d;
    check_encode(&m, (const uint8_t[8]){ 0x43, 0x00, 0x10, 0x00, 1, 2, 3, 4 });
    m.expedited = false;
    m.size = 5;
    m.length = 0;
    m.data = NULL;
    check_encode(&m, (const uint8_t[8]){ 0x41, 0x00, 0x10, 0x00, 5, 0, 0, 0 });
    m = msg(CO_SDO_UPLOAD_SEGMENT_RSP, 0, 0);
    m.length = 5;
    m.last = true;
    m.data = (const uint8_t *)"hello";
    check_encode(&m, (const uint8_t[8]){ 0x05, 'h', 'e', 'l', 'l', 'o', 0, 0 });
    m = msg(CO_SDO_BLOCK_DOWNLOAD_INITIATE_RSP, 0x2009, 0);
    m.crc = true;
    m.blksize = 7;
    check_encode(&m, (const uint8_t[8]){ 0xA4, 0x09, 0x20, 0x00, 7, 0, 0, 0 });
    m = msg(CO_SDO_BLOCK_DOWNLOAD_END_RSP, 0, 0);
    check_encode(&m, (const uint8_t[8]){ 0xA1, 0, 0, 0, 0, 0, 0, 0 });
    m = msg(CO_SDO_BLOCK_DOWNLOAD_ACK, 0, 0);
    m.seqno = 127;
    m.blksize = 127;
    check_encode(&m, (const uint8_t[8]){ 0xA2, 0x7F, 0x7F, 0, 0, 0, 0, 0 });
    m = msg(CO_SDO_BLOCK_UPLOAD_INITIATE_RSP, 0x2009, 0);
    m.crc = true;
    m.size_indicated = true;
    m.size = 100000;
    check_encode(&m, (const uint8_t[8]){ 0xC6, 0x09, 0x20, 0x00, 0xA0, 0x86, 0x01, 0x00 });
    m.crc = false;
    m.size_indicated = false;
    check_encode(&m, (const uint8_t[8]){ 0xC0, 0x09, 0x20, 0x00, 0, 0, 0, 0 });
    m = msg(CO_SDO_BLOCK_UPLOAD_END, 0, 0);
    m.unused = 7;
    m.crc_value = 0x31C3;
    check_encode(&m, (const uint8_t[8]){ 0xDD, 0xC3, 0x31, 0, 0, 0, 0, 0 });
    /* both */
    m = msg(CO_SDO_ABORT, 0x2000, 3);
    m.abort_code = 0x06090011;
    check_encode(&m, (const uint8_t[8]){ 0x80, 0x00, 0x20, 0x03, 0x11, 0x00, 0x09, 0x06 });
    m = msg(CO_SDO_BLOCK_SEGMENT, 0, 0);
    m.seqno = 127;
    m.length = 7;
    m.data = d;
    check_encode(&m, (const uint8_t[8]){ 0x7F, 1, 2, 3, 4, 5, 6, 7 });
    m.seqno = 1;
    m.last = true;
    m.length = 2;
    check_encode(&m, (const uint8_t[8]){ 0x81, 1, 2, 0, 0, 0, 0, 0 });
}

static void test_codec_encode_refuses(void **state)
{
    static const uint8_t d[8] = { 0 };
    uint8_t out[8];
    co_sdo_msg_t m;
    (void)state;
    m = msg(CO_SDO_UNKNOWN, 0, 0);
    assert_int_equal(co_sdo_encode(&m, out), 0);
    m.frame = 200;
    assert_int_equal(co_sdo_encode(&m, out), 0);
    m = msg(CO_SDO_DOWNLOAD_INITIATE, 0, 0);
    m.expedited = m.size_indicated = true;
    m.data = d;
    m.length = 0;
    assert_int_equal(co_sdo_encode(&m, out), 0);      /* expedited with size: 1..4 */
    m.length = 5;
    assert_int_equal(co_sdo_encode(&m, out), 0);
    m.length = 2;
    m.data = NULL;
    assert_int_equal(co_sdo_encode(&m, out), 0);
    m = msg(CO_SDO_UPLOAD_SEGMENT_RSP, 0, 0);
    m.length = 8;
    m.data = d;
    assert_int_equal(co_sdo_encode(&m, out), 0);
    m.length = 1;
    m.toggle = 2;
    assert_int_equal(co_sdo_encode(&m, out), 0);
    m = msg(CO_SDO_UPLOAD_SEGMENT, 0, 0);
    m.toggle = 3;
    assert_int_equal(co_sdo_encode(&m, out), 0);
    m = msg(CO_SDO_BLOCK_SEGMENT, 0, 0);
    m.seqno = 0;
    assert_int_equal(co_sdo_encode(&m, out), 0);
    m.seqno = 128;
    assert_int_equal(co_sdo_encode(&m, out), 0);
    m = msg(CO_SDO_BLOCK_UPLOAD_INITIATE, 0, 0);
    m.blksize = 0;
    assert_int_equal(co_sdo_encode(&m, out), 0);
    m.blksize = 128;
    assert_int_equal(co_sdo_encode(&m, out), 0);
    m = msg(CO_SDO_BLOCK_DOWNLOAD_ACK, 0, 0);
    m.seqno = 128;
    m.blksize = 1;
    assert_int_equal(co_sdo_encode(&m, out), 0);
    m.seqno = 0;
    m.blksize = 0;
    assert_int_equal(co_sdo_encode(&m, out), 0);
    m = msg(CO_SDO_BLOCK_UPLOAD_END, 0, 0);
    m.unused = 8;
    assert_int_equal(co_sdo_encode(&m, out), 0);
}

/* Every command byte in both directions, against a classification written
 * here from the research notes' tables (§6.2, §6.3). */
static co_sdo_frame_t classify(unsigned c, co_sdo_dir_t dir)
{
    unsigned cs = c >> 5;
    if (cs == 4)
        return c == 0x80 ? CO_SDO_ABORT : CO_SDO_UNKNOWN;
    if (dir == CO_SDO_TO_SERVER) {
        switch (cs) {
        case 0: return CO_SDO_DOWNLOAD_SEGMENT;
        case 1: return CO_SDO_DOWNLOAD_INITIATE;
        case 2: return CO_SDO_UPLOAD_INITIATE;
        case 3: return CO_SDO_UPLOAD_SEGMENT;
        case 5:
            return (c & 3) == 0 ? CO_SDO_BLOCK_UPLOAD_INITIATE
                 : (c & 3) == 1 ? CO_SDO_BLOCK_UPLOAD_END_RSP
                 : (c & 3) == 2 ? CO_SDO_BLOCK_UPLOAD_ACK : CO_SDO_BLOCK_UPLOAD_START;
        case 6: return (c & 1) ? CO_SDO_BLOCK_DOWNLOAD_END : CO_SDO_BLOCK_DOWNLOAD_INITIATE;
        default: return CO_SDO_UNKNOWN;
        }
    }
    switch (cs) {
    case 0: return CO_SDO_UPLOAD_SEGMENT_RSP;
    case 1: return CO_SDO_DOWNLOAD_SEGMENT_RSP;
    case 2: return CO_SDO_UPLOAD_INITIATE_RSP;
    case 3: return CO_SDO_DOWNLOAD_INITIATE_RSP;
    case 5:
        return (c & 3) == 0 ? CO_SDO_BLOCK_DOWNLOAD_INITIATE_RSP
             : (c & 3) == 1 ? CO_SDO_BLOCK_DOWNLOAD_END_RSP
             : (c & 3) == 2 ? CO_SDO_BLOCK_DOWNLOAD_ACK : CO_SDO_UNKNOWN;
    case 6: return (c & 1) ? CO_SDO_BLOCK_UPLOAD_END : CO_SDO_BLOCK_UPLOAD_INITIATE_RSP;
    default: return CO_SDO_UNKNOWN;
    }
}

static void test_codec_every_command_byte(void **state)
{
    unsigned c, d;
    (void)state;
    for (d = 0; d < 2; d++) {
        for (c = 0; c < 256; c++) {
            co_sdo_frame_t want = classify(c, (co_sdo_dir_t)d);
            uint8_t b[8] = { (uint8_t)c, 0x34, 0x12, 0x56, 1, 2, 3, 4 };
            co_sdo_msg_t m;
            assert_int_equal(co_sdo_frame_of((uint8_t)c, (co_sdo_dir_t)d), want);
            assert_int_equal(decode_exact(b, 8, (co_sdo_dir_t)d, &m, false),
                             want == CO_SDO_UNKNOWN ? CO_SDO_DECODE_UNKNOWN : CO_SDO_DECODE_OK);
            assert_int_equal(m.frame, want);
            if (want != CO_SDO_UNKNOWN && want != CO_SDO_ABORT)
                assert_int_equal(co_sdo_frame_dir(want), (co_sdo_dir_t)d);
            if (co_sdo_frame_has_mux(want)) {
                assert_int_equal(m.index, 0x1234);
                assert_int_equal(m.sub, 0x56);
            } else {
                assert_int_equal(m.index, 0);
            }
        }
    }
    assert_true(co_sdo_frame_is_initiate(CO_SDO_DOWNLOAD_INITIATE));
    assert_true(co_sdo_frame_is_initiate(CO_SDO_BLOCK_UPLOAD_INITIATE));
    assert_false(co_sdo_frame_is_initiate(CO_SDO_UPLOAD_INITIATE_RSP));
    assert_false(co_sdo_frame_is_initiate(CO_SDO_ABORT));
}

static void test_codec_truncated_frames(void **state)
{
    static const uint8_t frames[][8] = {
        { 0x23, 0x00, 0x20, 0x01, 1, 2, 3, 4 }, { 0x21, 0x09, 0x20, 0x00, 9, 0, 0, 0 },
        { 0x0B, 1, 2, 3, 4, 5, 6, 7 },          { 0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0 },
        { 0x60, 0, 0, 0, 0, 0, 0, 0 },          { 0xC6, 0x09, 0x20, 0x00, 1, 0, 0, 0 },
        { 0xC5, 0x12, 0x34, 0, 0, 0, 0, 0 },    { 0xA4, 0x09, 0x20, 0x00, 0x7F, 9, 0, 0 },
        { 0xA2, 0x05, 0x7F, 0, 0, 0, 0, 0 },    { 0x80, 0x00, 0x20, 0x00, 1, 0, 4, 5 },
        { 0x43, 0x00, 0x10, 0x00, 1, 2, 3, 4 },
    };
    size_t i, len;
    unsigned d;
    (void)state;
    for (i = 0; i < sizeof frames / sizeof frames[0]; i++) {
        for (d = 0; d < 2; d++) {
            co_sdo_msg_t full, m;
            co_sdo_decode_result_t r0 = decode_exact(frames[i], 8, (co_sdo_dir_t)d, &full, false);
            for (len = 0; len < 8; len++) {
                co_sdo_decode_result_t r = decode_exact(frames[i], len, (co_sdo_dir_t)d, &m, false);
                if (len == 0) {
                    assert_int_equal(r, CO_SDO_DECODE_EMPTY);
                    assert_int_equal(m.frame, 0);
                } else if (r0 == CO_SDO_DECODE_UNKNOWN) {
                    assert_int_equal(r, CO_SDO_DECODE_UNKNOWN);
                } else {
                    assert_int_equal(r, CO_SDO_DECODE_SHORT);
                    assert_int_equal(m.frame, full.frame);
                    assert_null(m.data);
                    assert_int_equal(m.size, 0);
                    assert_int_equal(m.abort_code, 0);
                    if (len >= 4 && co_sdo_frame_has_mux((co_sdo_frame_t)full.frame)) {
                        assert_int_equal(m.index, full.index);
                        assert_int_equal(m.sub, full.sub);
                    } else {
                        assert_int_equal(m.index, 0);
                    }
                }
            }
            /* trailing bytes are not looked at */
            {
                uint8_t longer[12];
                memcpy(longer, frames[i], 8);
                memset(longer + 8, 0xEE, 4);
                assert_int_equal(decode_exact(longer, 12, (co_sdo_dir_t)d, &m, false), r0);
                assert_int_equal(m.frame, full.frame);
                assert_int_equal(m.size, full.size);
            }
        }
        for (len = 0; len < 8; len++) {
            co_sdo_msg_t m;
            co_sdo_decode_result_t r = decode_exact(frames[i], len, CO_SDO_TO_SERVER, &m, true);
            assert_int_equal(r, len == 0 ? CO_SDO_DECODE_EMPTY : CO_SDO_DECODE_SHORT);
            assert_null(m.data);
            assert_int_equal(m.length, 0);
        }
    }
}

static void test_codec_random_input(void **state)
{
    uint64_t seed = 0x5D0C0DEC;
    unsigned i;
    (void)state;
    for (i = 0; i < 20000; i++) {
        uint8_t b[10];
        size_t len = (size_t)(tu_rand(&seed) % 11u), j;
        co_sdo_msg_t m;
        co_sdo_dir_t dir = (co_sdo_dir_t)(tu_rand(&seed) & 1u);
        co_sdo_decode_result_t r;
        for (j = 0; j < len; j++)
            b[j] = (uint8_t)tu_rand(&seed);
        r = decode_exact(b, len, dir, &m, false);
        if (len == 0)
            assert_int_equal(r, CO_SDO_DECODE_EMPTY);
        else if (co_sdo_frame_of(b[0], dir) == CO_SDO_UNKNOWN)
            assert_int_equal(r, CO_SDO_DECODE_UNKNOWN);
        else
            assert_int_equal(r, len >= 8 ? CO_SDO_DECODE_OK : CO_SDO_DECODE_SHORT);
        if (r == CO_SDO_DECODE_OK) {
            uint8_t out[8];
            /* what decodes re-encodes to the same frame (reserved bits 0) */
            size_t n = co_sdo_encode(&m, out);
            if (n == 8)
                assert_int_equal(co_sdo_frame_of(out[0], dir), m.frame);
        }
        (void)decode_exact(b, len, dir, &m, true);
    }
}

static void test_codec_restricted_ids(void **state)
{
    static const uint32_t restricted[] = { 0x000, 0x07F, 0x101, 0x180, 0x581, 0x5FF, 0x601,
                                           0x67F, 0x6E0, 0x6FF, 0x701, 0x7FF };
    static const uint32_t free_ids[] = { 0x080, 0x100, 0x181, 0x580, 0x600, 0x680, 0x6DF,
                                         0x6A5, 0x700, 0x200 };
    size_t i;
    (void)state;
    for (i = 0; i < sizeof restricted / sizeof restricted[0]; i++)
        assert_true(co_cob_id_restricted(restricted[i]));
    for (i = 0; i < sizeof free_ids / sizeof free_ids[0]; i++)
        assert_false(co_cob_id_restricted(free_ids[i]));
    assert_int_equal(co_sdo_request_id(5), 0x605);
    assert_int_equal(co_sdo_response_id(127), 0x5FF);
}

/* ================================================= server: setup */

static void test_init_refuses_bad_config(void **state)
{
    fx_t *fx = *state;
    static co_sdo_server_t s;
    static co_sdo_channel_t other[NCH];
    static uint8_t other_scratch[NCH * SCR];
    co_sdo_server_config_t cfg;
    static tu_line_t fd;
    co_sdo_server_deinit(&fx->srv);
    memset(&cfg, 0, sizeof cfg);
    cfg.channels = fx->ch;
    cfg.channel_count = NCH;
    cfg.scratch = fx->scratch;
    cfg.scratch_size = SCR;
    tu_line_init(&fd, CO_MODE_FD, true);
    assert_false(co_sdo_server_init(&s, &fd.line, &fx->od, &cfg));
    cfg.channel_count = 0;
    assert_false(co_sdo_server_init(&s, fx->a, &fx->od, &cfg));
    cfg.channel_count = NCH;
    cfg.scratch_size = CO_SDO_SERVER_BUFFER - 1;
    assert_false(co_sdo_server_init(&s, fx->a, &fx->od, &cfg));
    cfg.scratch_size = SCR;
    cfg.scratch = NULL;
    assert_false(co_sdo_server_init(&s, fx->a, &fx->od, &cfg));
    cfg.scratch = fx->scratch;
    cfg.block_size = 128;
    assert_false(co_sdo_server_init(&s, fx->a, &fx->od, &cfg));
    cfg.block_size = 0;
    cfg.channels = NULL;
    assert_false(co_sdo_server_init(&s, fx->a, &fx->od, &cfg));
    cfg.channels = fx->ch;
    cfg.channel_count = CO_SDO_SERVER_MAX_CHANNELS;
    cfg.channel_count++;   /* 129 */
    assert_false(co_sdo_server_init(&s, fx->a, &fx->od, &cfg));
    /* the default CAN-ID taken by someone else (the first server): refused,
     * and what the refused one set up is undone */
    cfg.channel_count = NCH;
    assert_true(co_sdo_server_init(&fx->srv, fx->a, &fx->od, &cfg));
    cfg.channels = other;
    cfg.scratch = other_scratch;
    assert_false(co_sdo_server_init(&s, fx->a, &fx->od, &cfg));
    assert_int_equal(fx->od.sub_count, 5);
    /* scratch need: the buffer plus the largest entry */
    assert_int_equal(co_sdo_server_scratch_need(&fx->od), CO_SDO_SERVER_BUFFER + 2000u);
    exp_read_ok(fx, 0x2000, 0, (const uint8_t *)"\x11", 1);
}

/* ================================================= expedited */

static void test_expedited_upload_each_size(void **state)
{
    fx_t *fx = *state;
    exp_read_ok(fx, 0x2000, 0, (const uint8_t *)"\x11", 1);
    exp_read_ok(fx, 0x2001, 0, (const uint8_t *)"\x22\x22", 2);
    exp_read_ok(fx, 0x2011, 0, (const uint8_t *)"\x56\x34\x12", 3);
    exp_read_ok(fx, 0x2002, 0, (const uint8_t *)"\x33\x33\x33\x33", 4);
    exp_read_ok(fx, 0x200A, 0, (const uint8_t *)"\x01", 1);
    /* exact bytes once more, by hand: 0x4F 00 20 00 11 */
    {
        const uint8_t e[8] = { 0x4F, 0x00, 0x20, 0x00, 0x11, 0, 0, 0 };
        req_mux(fx, 0x40, 0x2000, 0, 0);
        expect(fx, e);
    }
    assert_int_equal(fx->srv.stats.uploads, 6);
    assert_all_idle(fx);
}

static void test_expedited_download_each_size(void **state)
{
    fx_t *fx = *state;
    uint8_t b[8];
    exp_write_ok(fx, 0x2000, 0, (const uint8_t *)"\x9A", 1);
    exp_write_ok(fx, 0x2001, 0, (const uint8_t *)"\x34\x12", 2);
    exp_write_ok(fx, 0x2011, 0, (const uint8_t *)"\x03\x02\x01", 3);
    exp_write_ok(fx, 0x2002, 0, (const uint8_t *)"\x78\x56\x34\x12", 4);
    exp_read_ok(fx, 0x2000, 0, (const uint8_t *)"\x9A", 1);
    exp_read_ok(fx, 0x2001, 0, (const uint8_t *)"\x34\x12", 2);
    exp_read_ok(fx, 0x2011, 0, (const uint8_t *)"\x03\x02\x01", 3);
    assert_int_equal(od_u32(fx, 0x2002, 0), 0x12345678u);
    /* size not indicated (0x22): a U32 takes the 4 bytes */
    mux8(b, 0x22, 0x2002, 0, 0xAABBCCDDu);
    req(fx, b);
    expect_mux(fx, 0x60, 0x2002, 0, 0);
    assert_int_equal(od_u32(fx, 0x2002, 0), 0xAABBCCDDu);
    /* ... a U8 / U16 takes its own size (the first bytes) */
    mux8(b, 0x22, 0x2000, 0, 0x77665544u);
    req(fx, b);
    expect_mux(fx, 0x60, 0x2000, 0, 0);
    exp_read_ok(fx, 0x2000, 0, (const uint8_t *)"\x44", 1);
    mux8(b, 0x22, 0x2001, 0, 0x77665544u);
    req(fx, b);
    expect_mux(fx, 0x60, 0x2001, 0, 0);
    exp_read_ok(fx, 0x2001, 0, (const uint8_t *)"\x44\x55", 2);
    /* ... a string takes all 4 */
    mux8(b, 0x22, 0x2004, 0, 0);
    memcpy(b + 4, "abcd", 4);
    req(fx, b);
    expect_mux(fx, 0x60, 0x2004, 0, 0);
    assert_od_bytes(fx, 0x2004, 0, (const uint8_t *)"abcd", 4);
    /* a U64 cannot be written expedited: too short */
    mux8(b, 0x22, 0x2003, 0, 1);
    req(fx, b);
    expect_abort(fx, 0x2003, 0, AB_LEN_LOW);
    assert_int_equal(fx->srv.stats.downloads, 8);
    assert_all_idle(fx);
}

/* ================================================= segmented */

static void test_segmented_upload_toggle(void **state)
{
    fx_t *fx = *state;
    uint8_t data[20];
    const uint8_t e1[8] = { 0x41, 0x03, 0x20, 0x00, 0x08, 0, 0, 0 };
    const uint8_t s1[8] = { 0x00, 0x44, 0x44, 0x44, 0x44, 0x44, 0x44, 0x44 };
    const uint8_t s2[8] = { 0x1D, 0x44, 0, 0, 0, 0, 0, 0 };   /* t=1 n=6 c=1 */
    /* U64: 8 bytes, two segments, by hand */
    req_mux(fx, 0x40, 0x2003, 0, 0);
    expect(fx, e1);
    req_cmd(fx, 0x60);
    expect(fx, s1);
    req_cmd(fx, 0x70);
    expect(fx, s2);
    expect_none(fx);
    /* "hello" (5 bytes): one segment 0x05 */
    seg_read_ok(fx, 0x2004, 0, (const uint8_t *)"hello", 5, 5);
    /* 20 bytes: toggle 0, 1, 0 */
    fill_pattern(data, sizeof data, 1);
    seg_write_ok(fx, 0x2005, 0, data, 20, true);
    seg_read_ok(fx, 0x2005, 0, data, 20, 20);
    /* exactly 14 bytes: the second segment is the last, with 7 bytes */
    seg_write_ok(fx, 0x2005, 0, data, 14, true);
    seg_read_ok(fx, 0x2005, 0, data, 14, 14);
    assert_all_idle(fx);
}

static void test_segmented_download_size_or_not(void **state)
{
    fx_t *fx = *state;
    uint8_t data[1000];
    const uint8_t init[8] = { 0x21, 0x05, 0x20, 0x00, 0x0A, 0, 0, 0 };
    const uint8_t ok[8] = { 0x60, 0x05, 0x20, 0x00, 0, 0, 0, 0 };
    const uint8_t sg1[8] = { 0x00, 1, 2, 3, 4, 5, 6, 7 };
    const uint8_t sg2[8] = { 0x19, 8, 9, 10, 0, 0, 0, 0 };   /* t=1 n=4 c=1 */
    const uint8_t r1[8] = { 0x20, 0, 0, 0, 0, 0, 0, 0 };
    const uint8_t r2[8] = { 0x30, 0, 0, 0, 0, 0, 0, 0 };
    /* by hand: 10 bytes into 0x2005 */
    req(fx, init);
    expect(fx, ok);
    req(fx, sg1);
    expect(fx, r1);
    req(fx, sg2);
    expect(fx, r2);
    expect_none(fx);
    assert_od_bytes(fx, 0x2005, 0, (const uint8_t *)"\1\2\3\4\5\6\7\x8\x9\xA", 10);
    fill_pattern(data, sizeof data, 9);
    seg_write_ok(fx, 0x2005, 0, data, 1000, true);
    assert_od_bytes(fx, 0x2005, 0, data, 1000);
    seg_write_ok(fx, 0x2005, 0, data + 1, 999, false);   /* size not indicated */
    assert_od_bytes(fx, 0x2005, 0, data + 1, 999);
    seg_write_ok(fx, 0x2002, 0, (const uint8_t *)"\x01\x02\x03\x04", 4, false);
    assert_int_equal(od_u32(fx, 0x2002, 0), 0x04030201u);
    /* not indicated, too long / too short for the entry: at the end */
    req_mux(fx, 0x20, 0x2002, 0, 0);
    expect_mux(fx, 0x60, 0x2002, 0, 0);
    req(fx, (const uint8_t[8]){ 0x00, 1, 2, 3, 4, 5, 6, 7 });
    expect_abort(fx, 0x2002, 0, AB_LEN_HIGH);
    req_mux(fx, 0x20, 0x2002, 0, 0);
    expect_mux(fx, 0x60, 0x2002, 0, 0);
    req(fx, (const uint8_t[8]){ 0x0B, 1, 2, 0, 0, 0, 0, 0 });   /* n=5: 2 bytes, last */
    expect_abort(fx, 0x2002, 0, AB_LEN_LOW);
    /* indicated: more than announced at once, fewer at the end */
    req_mux(fx, 0x21, 0x2005, 0, 5);
    expect_mux(fx, 0x60, 0x2005, 0, 0);
    req(fx, (const uint8_t[8]){ 0x00, 1, 2, 3, 4, 5, 6, 7 });
    expect_abort(fx, 0x2005, 0, AB_LEN_HIGH);
    req_mux(fx, 0x21, 0x2005, 0, 9);
    expect_mux(fx, 0x60, 0x2005, 0, 0);
    req(fx, (const uint8_t[8]){ 0x01, 1, 2, 3, 4, 5, 6, 7 });
    expect_abort(fx, 0x2005, 0, AB_LEN_LOW);
    assert_od_bytes(fx, 0x2004, 0, (const uint8_t *)"hello", 5);
    assert_od_bytes(fx, 0x2005, 0, data + 1, 999);
    assert_all_idle(fx);
}

static void test_segmented_domain_100k_both_ways(void **state)
{
    fx_t *fx = *state;
    static uint8_t data[100000];
    fill_pattern(data, sizeof data, 0x5A);
    seg_write_ok(fx, 0x2009, 0, data, sizeof data, true);
    assert_int_equal(fx->dom_len, sizeof data);
    assert_memory_equal(fx->domain, data, sizeof data);
    assert_int_equal(fx->dom_commits, 1);
    seg_read_ok(fx, 0x2009, 0, data, sizeof data, sizeof data);
    /* without a size, both ways: the unknown-size domain 0x200C reads the same data */
    fill_pattern(data, sizeof data, 0x3C);
    seg_write_ok(fx, 0x2009, 0, data, sizeof data, false);
    assert_memory_equal(fx->domain, data, sizeof data);
    seg_read_ok(fx, 0x200C, 0, data, sizeof data, -1);
    assert_all_idle(fx);
}

/* Unknown-size domain: the last segment is known by reading ahead, also
 * when the data ends on a 7-byte boundary; an empty one ends with n = 7. */
static void test_segmented_unknown_size_ends(void **state)
{
    fx_t *fx = *state;
    const uint8_t empty[8] = { 0x0F, 0, 0, 0, 0, 0, 0, 0 };
    fx->dom_len = 14;
    seg_read_ok(fx, 0x200C, 0, fx->domain, 14, -1);
    fx->dom_len = 3;
    seg_read_ok(fx, 0x200C, 0, fx->domain, 3, -1);
    fx->dom_len = 0;
    req_mux(fx, 0x40, 0x200C, 0, 0);
    expect_mux(fx, 0x40, 0x200C, 0, 0);
    req_cmd(fx, 0x60);
    expect(fx, empty);
    /* the empty octet string: size 0 indicated, one empty segment */
    req_mux(fx, 0x40, 0x2005, 0, 0);
    expect_mux(fx, 0x41, 0x2005, 0, 0);
    req_cmd(fx, 0x60);
    expect(fx, empty);
    /* and an empty download */
    seg_write_ok(fx, 0x2004, 0, (const uint8_t *)"", 0, true);
    assert_od_bytes(fx, 0x2004, 0, NULL, 0);
    assert_all_idle(fx);
}

/* ================================================= block download */

static void test_block_download_exact(void **state)
{
    fx_t *fx = *state;
    const uint8_t data[20] = { 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18,
                               19, 20 };
    uint16_t crc = ref_crc(0, data, 20);
    uint8_t end[8] = { 0xC5, (uint8_t)crc, (uint8_t)(crc >> 8), 0, 0, 0, 0, 0 };   /* n=1 */
    /* by hand: C6 (crc, size) -> A4 blksize 127; 3 segments; ack 3; end */
    req_mux(fx, 0xC6, 0x2005, 0, 20);
    expect_mux(fx, 0xA4, 0x2005, 0, 0x7F);
    req(fx, (const uint8_t[8]){ 0x01, 1, 2, 3, 4, 5, 6, 7 });
    req(fx, (const uint8_t[8]){ 0x02, 8, 9, 10, 11, 12, 13, 14 });
    expect_none(fx);
    req(fx, (const uint8_t[8]){ 0x83, 15, 16, 17, 18, 19, 20, 0 });
    expect_ack(fx, 3, 127);
    expect_none(fx);
    req(fx, end);
    expect_cmd(fx, 0xA1);
    expect_none(fx);
    assert_od_bytes(fx, 0x2005, 0, data, 20);
    /* the same without CRC and without size */
    block_write_ok(fx, 0x2005, 0, data + 1, 19, false, false, true, 127);
    assert_od_bytes(fx, 0x2005, 0, data + 1, 19);
    /* into a U32, and an empty value */
    block_write_ok(fx, 0x2002, 0, (const uint8_t *)"\x0D\x0C\x0B\x0A", 4, true, true, true, 127);
    assert_int_equal(od_u32(fx, 0x2002, 0), 0x0A0B0C0Du);
    block_write_ok(fx, 0x2004, 0, (const uint8_t *)"", 0, true, true, true, 127);
    assert_od_bytes(fx, 0x2004, 0, NULL, 0);
    assert_int_equal(fx->srv.stats.downloads, 4);
    assert_all_idle(fx);
}

static void test_block_download_100k_blksizes_crc(void **state)
{
    fx_t *fx = *state;
    static uint8_t data[100000];
    static const uint8_t sizes[] = { 1, 7, 127 };
    size_t i;
    unsigned crc;
    for (i = 0; i < sizeof sizes; i++) {
        for (crc = 0; crc < 3; crc++) {
            /* crc 0: client without CRC; 1: both; 2: server without CRC */
            uint32_t n = (uint32_t)sizeof data - (uint32_t)(i * 3 + crc);
            reinit_server(fx, 0, sizes[i], crc == 2);
            fill_pattern(data, n, (uint8_t)(i * 16 + crc));
            block_write_ok(fx, 0x2009, 0, data, n, crc != 0, crc != 1, crc != 2, sizes[i]);
            assert_int_equal(fx->dom_len, n);
            assert_memory_equal(fx->domain, data, n);
        }
    }
    assert_int_equal(fx->dom_aborts, 0);
    assert_all_idle(fx);
}

/* A lost segment (dropped on the bus): the sub-block is acknowledged with
 * the last good seqno at its end, the client repeats from there numbering
 * from 1 again. */
static void test_block_download_lost_segment_repeated(void **state)
{
    fx_t *fx = *state;
    uint8_t data[60];
    uint8_t b[8];
    uint32_t off;
    uint8_t s;
    uint16_t crc;
    fill_pattern(data, sizeof data, 7);
    crc = ref_crc(0, data, 60);
    reinit_server(fx, 0, 7, false);
    fx->fault.id = REQ0;
    fx->fault.count = 0;
    fx->fault.drop[0] = 4;                    /* init is 1: segment 3 of the first sub-block */
    fx->fault.n_drop = 1;
    req_mux(fx, 0xC6, 0x2005, 0, 60);
    expect_mux(fx, 0xA4, 0x2005, 0, 7);
    for (s = 1; s <= 7; s++) {
        seg8(b, s, data + (s - 1) * 7, 7);
        req(fx, b);
    }
    expect_ack(fx, 2, 7);                     /* 1, 2 good; 3 lost; 4..7 ignored */
    expect_none(fx);
    assert_int_equal(fx->srv.stats.rx_block_ignored, 4);
    assert_int_equal(fx->srv.stats.block_partial_acks, 1);
    /* repeat from byte 14: 14 + 7 * 6 = 56, then 4 bytes in seqno 7 (c) */
    off = 14;
    for (s = 1; s <= 7; s++) {
        uint32_t k = 60 - off < 7 ? 60 - off : 7;
        bool last = off + k == 60;
        seg8(b, (uint8_t)(s | (last ? 0x80 : 0)), data + off, k);
        req(fx, b);
        off += k;
        if (s < 7)
            expect_none(fx);
    }
    expect_ack(fx, 7, 7);
    b[0] = 0xCD;                              /* n = 3 */
    b[1] = (uint8_t)crc;
    b[2] = (uint8_t)(crc >> 8);
    memset(b + 3, 0, 5);
    req(fx, b);
    expect_cmd(fx, 0xA1);
    assert_od_bytes(fx, 0x2005, 0, data, 60);
    assert_all_idle(fx);
}

/* The end of a sub-block lost: no ack until the idle timeout ran out once,
 * then the last good seqno; lost first segment: ack 0 after the timeout;
 * a reordered sub-block; duplicated segments are ignored. */
static void test_block_download_faults_recover(void **state)
{
    fx_t *fx = *state;
    uint8_t data[35];
    uint8_t b[8];
    uint8_t s;
    uint64_t t0;
    uint16_t crc;
    fill_pattern(data, sizeof data, 3);
    crc = ref_crc(0, data, 35);
    reinit_server(fx, 0, 5, false);
    req_mux(fx, 0xC6, 0x2005, 0, 35);
    expect_mux(fx, 0xA4, 0x2005, 0, 5);
    /* sub-block of 5 with the end (seqno 5 = c) lost: 1..4 arrive */
    for (s = 1; s <= 4; s++) {
        seg8(b, s, data + (s - 1) * 7, 7);
        req(fx, b);
    }
    expect_none(fx);
    t0 = fx->tb.now;
    tu_run_until(&fx->tb, t0 + MS(999));
    expect_none(fx);
    tu_run_until(&fx->tb, t0 + MS(1000));
    expect_ack(fx, 4, 5);
    /* the client repeats segment 5 as seqno 1 (c) */
    seg8(b, 0x81, data + 28, 7);
    req(fx, b);
    expect_ack(fx, 1, 5);
    /* a duplicate of the last segment before the end frame: ignored */
    req(fx, b);
    expect_none(fx);
    b[0] = 0xC1;
    b[1] = (uint8_t)crc;
    b[2] = (uint8_t)(crc >> 8);
    memset(b + 3, 0, 5);
    req(fx, b);
    expect_cmd(fx, 0xA1);
    assert_od_bytes(fx, 0x2005, 0, data, 35);
    assert_int_equal(fx->srv.stats.rx_duplicate, 1);
    /* the first segment of a sub-block lost: the rest is ignored, ack 0 */
    req_mux(fx, 0xC4, 0x2005, 0, 0);          /* crc, no size */
    expect_mux(fx, 0xA4, 0x2005, 0, 5);
    for (s = 2; s <= 5; s++) {
        seg8(b, s, data + (s - 1) * 7, 7);
        req(fx, b);
    }
    expect_none(fx);
    t0 = fx->tb.now;
    tu_run_until(&fx->tb, t0 + MS(1000));
    expect_ack(fx, 0, 5);
    /* reordered: 1, 2, 4, 3, 5 -> 3 taken after the gap, 4 was dropped: ack 3 */
    for (s = 1; s <= 5; s++) {
        uint8_t k = s == 3 ? 4 : s == 4 ? 3 : s;
        seg8(b, (uint8_t)(k | (k == 5 ? 0x80 : 0)), data + (k - 1) * 7, 7);
        req(fx, b);
    }
    expect_ack(fx, 3, 5);
    /* the client repeats 4, 5 as 1, 2; every segment delivered twice */
    fx->fault.id = REQ0;
    fx->fault.dup_all = true;
    seg8(b, 0x01, data + 21, 7);
    req(fx, b);
    seg8(b, 0x82, data + 28, 7);
    req(fx, b);
    expect_ack(fx, 2, 5);
    expect_none(fx);
    fx->fault.dup_all = false;
    b[0] = 0xC1;
    b[1] = (uint8_t)crc;
    b[2] = (uint8_t)(crc >> 8);
    memset(b + 3, 0, 5);
    req(fx, b);
    expect_cmd(fx, 0xA1);
    assert_od_bytes(fx, 0x2005, 0, data, 35);
    /* nothing arrives at all after the acknowledgement: timeout abort */
    req_mux(fx, 0xC4, 0x2005, 0, 0);
    expect_mux(fx, 0xA4, 0x2005, 0, 5);
    t0 = fx->tb.now;
    tu_run_until(&fx->tb, t0 + MS(1000));
    expect_abort(fx, 0x2005, 0, AB_TIMEOUT);
    assert_all_idle(fx);
}

/* A large block download through the membus fault hook: random losses and
 * duplicates of client frames, the client following the acks. */
static void test_block_download_random_losses(void **state)
{
    fx_t *fx = *state;
    static uint8_t data[20000];
    uint32_t n = sizeof data, acked = 0, guard = 0, k;
    uint64_t seed = 77;
    uint8_t blksize, b[8];
    unsigned lost = 0;
    fill_pattern(data, n, 0x77);
    req_mux(fx, 0xC6, 0x2009, 0, n);
    expect_mux(fx, 0xA4, 0x2009, 0, 127);
    blksize = 127;
    fx->fault.id = REQ0;
    fx->fault.count = 0;
    for (;;) {
        const co_frame_t *f;
        uint32_t off = acked;
        uint8_t s, sent_last = 0;
        assert_true(++guard < 2000);
        for (s = 1; s <= blksize && off < n; s++) {
            uint32_t len = n - off < 7 ? n - off : 7;
            bool last = off + len == n;
            uint64_t r = tu_rand(&seed);
            fx->fault.n_drop = 0;
            fx->fault.n_dup = 0;
            if (r % 50 == 0) {
                fx->fault.drop[0] = fx->fault.count + 1;
                fx->fault.n_drop = 1;
                lost++;
            } else if (r % 50 == 1) {
                fx->fault.dup[0] = fx->fault.count + 1;
                fx->fault.n_dup = 1;
            }
            seg8(b, (uint8_t)(s | (last ? 0x80 : 0)), data + off, len);
            req(fx, b);
            off += len;
            if (last) {
                sent_last = s;
                break;
            }
        }
        fx->fault.n_drop = 0;
        fx->fault.n_dup = 0;
        f = next_rsp(fx);
        if (f == NULL) {
            tu_run_until(&fx->tb, fx->tb.now + MS(1000));
            f = next_rsp(fx);
        }
        assert_non_null(f);
        assert_int_equal(f->data[0], 0xA2);
        assert_int_equal(f->data[2], 127);
        expect_none(fx);
        k = f->data[1];
        acked += k * 7;
        if (sent_last != 0 && k == sent_last)
            break;
        assert_true(acked < n);
    }
    b[0] = (uint8_t)(0xC1 | (7 - (n % 7 == 0 ? 7 : n % 7)) << 2);
    b[1] = (uint8_t)ref_crc(0, data, n);
    b[2] = (uint8_t)(ref_crc(0, data, n) >> 8);
    memset(b + 3, 0, 5);
    req(fx, b);
    expect_cmd(fx, 0xA1);
    assert_true(lost > 0);
    assert_int_equal(fx->dom_len, n);
    assert_memory_equal(fx->domain, data, n);
    assert_true(fx->srv.stats.block_partial_acks > 0);
    assert_true(fx->srv.stats.rx_block_ignored > 0);
    assert_all_idle(fx);
}

/* ================================================= block upload */

static void test_block_upload_exact(void **state)
{
    fx_t *fx = *state;
    uint8_t data[20];
    uint16_t crc;
    fill_pattern(data, 20, 0x10);
    seg_write_ok(fx, 0x2005, 0, data, 20, true);
    crc = ref_crc(0, data, 20);
    /* by hand */
    req(fx, (const uint8_t[8]){ 0xA4, 0x05, 0x20, 0x00, 0x7F, 0x00, 0, 0 });
    expect_mux(fx, 0xC6, 0x2005, 0, 20);
    req_cmd(fx, 0xA3);
    expect(fx, (const uint8_t[8]){ 0x01, data[0], data[1], data[2], data[3], data[4], data[5],
                                   data[6] });
    expect(fx, (const uint8_t[8]){ 0x02, data[7], data[8], data[9], data[10], data[11], data[12],
                                   data[13] });
    expect(fx, (const uint8_t[8]){ 0x83, data[14], data[15], data[16], data[17], data[18],
                                   data[19], 0 });
    expect_none(fx);
    req(fx, (const uint8_t[8]){ 0xA2, 0x03, 0x7F, 0, 0, 0, 0, 0 });
    expect(fx, (const uint8_t[8]){ 0xC5, (uint8_t)crc, (uint8_t)(crc >> 8), 0, 0, 0, 0, 0 });
    req_cmd(fx, 0xA1);
    expect_none(fx);
    /* the helper, without CRC, the U32, an unknown-size domain, empty */
    block_read_ok(fx, 0x2005, 0, data, 20, false, true, 127, 20);
    block_read_ok(fx, 0x2002, 0, (const uint8_t *)"\x33\x33\x33\x33", 4, true, true, 5, 4);
    fx->dom_len = 21;
    block_read_ok(fx, 0x200C, 0, fx->domain, 21, true, true, 3, -1);
    fx->dom_len = 0;
    block_read_ok(fx, 0x200C, 0, fx->domain, 0, true, true, 3, -1);
    seg_write_ok(fx, 0x2005, 0, (const uint8_t *)"", 0, true);
    block_read_ok(fx, 0x2005, 0, (const uint8_t *)"", 0, true, true, 127, 0);
    assert_int_equal(fx->srv.stats.uploads, 6);
    assert_all_idle(fx);
}

static void test_block_upload_100k_blksizes_crc(void **state)
{
    fx_t *fx = *state;
    static const uint8_t sizes[] = { 1, 7, 127 };
    size_t i;
    unsigned crc;
    for (i = 0; i < sizeof sizes; i++) {
        for (crc = 0; crc < 3; crc++) {
            fx->dom_len = 100000u + (uint32_t)(i * 3 + crc);
            fill_pattern(fx->domain, fx->dom_len, (uint8_t)(0x40 + i * 8 + crc));
            reinit_server(fx, 0, 0, crc == 2);
            block_read_ok(fx, 0x2009, 0, fx->domain, fx->dom_len, crc != 0, crc != 2, sizes[i],
                          fx->dom_len);
        }
    }
    /* unknown size, 100 000 bytes */
    fx->dom_len = 100000u;
    block_read_ok(fx, 0x200C, 0, fx->domain, fx->dom_len, true, false, 127, -1);
    assert_all_idle(fx);
}

/* A short ack: the unacknowledged segments go out again, numbered from 1,
 * with the new block size. */
static void test_block_upload_short_ack_repeats(void **state)
{
    fx_t *fx = *state;
    uint8_t data[50];
    uint8_t b[8];
    uint16_t crc;
    unsigned s;
    fill_pattern(data, 50, 0x61);
    seg_write_ok(fx, 0x2005, 0, data, 50, true);
    crc = ref_crc(0, data, 50);
    mux8(b, 0xA4, 0x2005, 0, 0);
    b[4] = 5;
    req(fx, b);
    expect_mux(fx, 0xC6, 0x2005, 0, 50);
    req_cmd(fx, 0xA3);
    for (s = 1; s <= 5; s++) {
        seg8(b, (uint8_t)s, data + (s - 1) * 7, 7);
        expect(fx, b);
    }
    expect_none(fx);
    /* segments 1, 2 received; next block size 3 */
    req(fx, (const uint8_t[8]){ 0xA2, 2, 3, 0, 0, 0, 0, 0 });
    for (s = 1; s <= 3; s++) {
        seg8(b, (uint8_t)s, data + 14 + (s - 1) * 7, 7);
        expect(fx, b);
    }
    expect_none(fx);
    assert_int_equal(fx->srv.stats.block_repeats, 3);
    /* nothing received (ackseq 0): the same three again, block size 4 */
    req(fx, (const uint8_t[8]){ 0xA2, 0, 4, 0, 0, 0, 0, 0 });
    for (s = 1; s <= 4; s++) {
        seg8(b, (uint8_t)s, data + 14 + (s - 1) * 7, 7);
        expect(fx, b);
    }
    req(fx, (const uint8_t[8]){ 0xA2, 4, 127, 0, 0, 0, 0, 0 });
    /* 42 acked: 8 left = 7 + 1 */
    seg8(b, 1, data + 42, 7);
    expect(fx, b);
    seg8(b, 0x82, data + 49, 1);
    expect(fx, b);
    expect_none(fx);
    /* the last segment lost: ack 1 -> it comes again as seqno 1 */
    req(fx, (const uint8_t[8]){ 0xA2, 1, 127, 0, 0, 0, 0, 0 });
    seg8(b, 0x81, data + 49, 1);
    expect(fx, b);
    expect_none(fx);
    req(fx, (const uint8_t[8]){ 0xA2, 1, 127, 0, 0, 0, 0, 0 });
    expect(fx, (const uint8_t[8]){ 0xD9, (uint8_t)crc, (uint8_t)(crc >> 8), 0, 0, 0, 0, 0 });
    req_cmd(fx, 0xA1);
    expect_none(fx);
    assert_int_equal(fx->srv.stats.uploads, 1);
    assert_all_idle(fx);
}

/* pst: a known size <= pst is answered as a normal upload. */
static void test_block_upload_protocol_switch(void **state)
{
    fx_t *fx = *state;
    uint8_t b[8];
    mux8(b, 0xA4, 0x2002, 0, 0);
    b[4] = 127;
    b[5] = 4;                                  /* 4 bytes <= 4: expedited */
    req(fx, b);
    expect_mux(fx, 0x43, 0x2002, 0, 0x33333333u);
    expect_none(fx);
    mux8(b, 0xA0, 0x2004, 0, 0);
    b[4] = 10;
    b[5] = 21;                                 /* "hello": segmented */
    req(fx, b);
    expect_mux(fx, 0x41, 0x2004, 0, 5);
    req_cmd(fx, 0x60);
    expect(fx, (const uint8_t[8]){ 0x05, 'h', 'e', 'l', 'l', 'o', 0, 0 });
    expect_none(fx);
    b[5] = 4;                                  /* 5 > 4: block */
    req(fx, b);
    expect_mux(fx, 0xC6, 0x2004, 0, 5);
    req_cmd(fx, 0x80);                         /* (the client gives up) */
    b[5] = 0;                                  /* 0: never switch */
    mux8(b, 0xA0, 0x2000, 0, 0);
    b[4] = 1;
    req(fx, b);
    expect_mux(fx, 0xC6, 0x2000, 0, 1);
    req_cmd(fx, 0xA3);
    expect(fx, (const uint8_t[8]){ 0x81, 0x11, 0, 0, 0, 0, 0, 0 });
    req(fx, (const uint8_t[8]){ 0xA2, 1, 1, 0, 0, 0, 0, 0 });
    {
        uint16_t crc = ref_crc(0, (const uint8_t *)"\x11", 1);   /* sent though cc = 0 */
        expect(fx, (const uint8_t[8]){ 0xD9, (uint8_t)crc, (uint8_t)(crc >> 8), 0, 0, 0, 0, 0 });
    }
    req_cmd(fx, 0xA1);
    /* unknown size: never switched */
    mux8(b, 0xA0, 0x200C, 0, 0);
    b[4] = 127;
    b[5] = 127;
    req(fx, b);
    expect_mux(fx, 0xC4, 0x200C, 0, 0);
    req_cmd(fx, 0x80);
    assert_int_equal(fx->srv.stats.protocol_switches, 2);
    assert_all_idle(fx);
}


/* Frames of one CAN-ID in the log, in order (copied out); the log is
 * cleared. */
static size_t collect(fx_t *fx, uint32_t id, co_frame_t *out, size_t max)
{
    size_t i, n = 0;
    for (i = 0; i < fx->tb.log_count; i++) {
        if (fx->tb.log[i].frame.id == id) {
            assert_true(n < max);
            out[n++] = fx->tb.log[i].frame;
        }
    }
    return n;
}

static void check_segments(const co_frame_t *f, size_t count, const uint8_t *data, uint32_t n,
                           uint32_t off, uint8_t blksize)
{
    size_t i;
    for (i = 0; i < count; i++) {
        uint8_t e[8];
        uint32_t k = n - off < 7 ? n - off : 7;
        bool last = off + k >= n;
        seg8(e, (uint8_t)((i + 1) | (last ? 0x80 : 0)), data + off, k);
        assert_int_equal(f[i].len, 8);
        assert_memory_equal(f[i].data, e, 8);
        off += k;
        assert_true(i + 1 <= blksize);
    }
}

/* Two channels upload 127-segment sub-blocks at once: the second waits for
 * room in the tx queue (three quarters of its 256 slots) and goes on when
 * the queue drained to half. */
static void test_block_upload_waits_for_tx_room(void **state)
{
    fx_t *fx = *state;
    static co_frame_t f0[200], f1[200];
    uint8_t b[8];
    size_t n0, n1;
    uint16_t crc;
    enable_channel1(fx);
    fx->dom_len = 1000;
    crc = ref_crc(0, fx->domain, 1000);
    mux8(b, 0xA4, 0x2009, 0, 0);
    b[4] = 127;
    use_channel(fx, REQ0, RSP0);
    req(fx, b);
    expect_mux(fx, 0xC6, 0x2009, 0, 1000);
    mux8(b, 0xA4, 0x200C, 0, 0);
    b[4] = 127;
    use_channel(fx, REQ1, RSP1);
    req(fx, b);
    expect_mux(fx, 0xC4, 0x200C, 0, 0);
    /* both starts in one go */
    tu_log_clear(&fx->tb);
    fx->cursor = 0;
    seg8(b, 0xA3, NULL, 0);
    assert_true(co_line_send(fx->b, REQ0, b, 8));
    assert_true(co_line_send(fx->b, REQ1, b, 8));
    tu_step(&fx->tb, fx->tb.now);
    n0 = collect(fx, RSP0, f0, 200);
    n1 = collect(fx, RSP1, f1, 200);
    assert_int_equal(n0, 127);
    assert_int_equal(n1, 127);
    check_segments(f0, n0, fx->domain, 1000, 0, 127);
    check_segments(f1, n1, fx->domain, 1000, 0, 127);
    assert_int_equal(fx->srv.stats.tx_deferred, 1);
    assert_int_equal(fx->srv.stats.tx_failed, 0);
    /* both acknowledge: 111 bytes left each = 16 segments */
    tu_log_clear(&fx->tb);
    seg8(b, 0xA2, NULL, 0);
    b[1] = 127;
    b[2] = 127;
    assert_true(co_line_send(fx->b, REQ0, b, 8));
    assert_true(co_line_send(fx->b, REQ1, b, 8));
    tu_step(&fx->tb, fx->tb.now);
    n0 = collect(fx, RSP0, f0, 200);
    n1 = collect(fx, RSP1, f1, 200);
    assert_int_equal(n0, 16);
    assert_int_equal(n1, 16);
    check_segments(f0, n0, fx->domain, 1000, 889, 127);
    check_segments(f1, n1, fx->domain, 1000, 889, 127);
    tu_log_clear(&fx->tb);
    fx->cursor = 0;
    b[1] = 16;
    use_channel(fx, REQ0, RSP0);
    req(fx, b);
    expect(fx, (const uint8_t[8]){ 0xC5, (uint8_t)crc, (uint8_t)(crc >> 8), 0, 0, 0, 0, 0 });
    req_cmd(fx, 0xA1);
    use_channel(fx, REQ1, RSP1);
    req(fx, b);
    expect(fx, (const uint8_t[8]){ 0xC5, (uint8_t)crc, (uint8_t)(crc >> 8), 0, 0, 0, 0, 0 });
    req_cmd(fx, 0xA1);
    expect_none(fx);
    assert_int_equal(fx->srv.stats.uploads, 2);
    assert_all_idle(fx);
}

/* ================================================= aborts */

static void test_abort_block_protocol_errors(void **state)
{
    fx_t *fx = *state;
    uint8_t b[8];
    uint8_t data[21];
    fill_pattern(data, 21, 0x21);
    /* block upload initiate: blksize 0 and 128 */
    mux8(b, 0xA0, 0x2005, 0, 0);
    req(fx, b);
    expect_abort(fx, 0x2005, 0, AB_BLKSIZE);
    b[4] = 128;
    req(fx, b);
    expect_abort(fx, 0x2005, 0, AB_BLKSIZE);
    assert_int_equal(fx->srv.stats.rx_bad_blksize, 2);
    /* ack with blksize 0 / 200, ack beyond the segments sent */
    seg_write_ok(fx, 0x2005, 0, data, 21, true);
    b[4] = 2;
    req(fx, b);
    expect_mux(fx, 0xC6, 0x2005, 0, 21);
    req_cmd(fx, 0xA3);
    seg8(b, 1, data, 7);
    expect(fx, b);
    seg8(b, 2, data + 7, 7);
    expect(fx, b);
    req(fx, (const uint8_t[8]){ 0xA2, 2, 0, 0, 0, 0, 0, 0 });
    expect_abort(fx, 0x2005, 0, AB_BLKSIZE);
    req(fx, (const uint8_t[8]){ 0xA0, 0x05, 0x20, 0x00, 2, 0, 0, 0 });
    expect_mux(fx, 0xC6, 0x2005, 0, 21);
    req_cmd(fx, 0xA3);
    (void)next_rsp(fx);
    (void)next_rsp(fx);
    req(fx, (const uint8_t[8]){ 0xA2, 2, 200, 0, 0, 0, 0, 0 });
    expect_abort(fx, 0x2005, 0, AB_BLKSIZE);
    req(fx, (const uint8_t[8]){ 0xA0, 0x05, 0x20, 0x00, 2, 0, 0, 0 });
    expect_mux(fx, 0xC6, 0x2005, 0, 21);
    req_cmd(fx, 0xA3);
    (void)next_rsp(fx);
    (void)next_rsp(fx);
    req(fx, (const uint8_t[8]){ 0xA2, 3, 2, 0, 0, 0, 0, 0 });
    expect_abort(fx, 0x2005, 0, AB_SEQNO);
    /* block download: seqno 0, seqno above the block size */
    reinit_server(fx, 0, 4, false);
    req_mux(fx, 0xC6, 0x2005, 0, 21);
    expect_mux(fx, 0xA4, 0x2005, 0, 4);
    req(fx, (const uint8_t[8]){ 0x00, 1, 2, 3, 4, 5, 6, 7 });
    expect_abort(fx, 0x2005, 0, AB_SEQNO);
    req_mux(fx, 0xC6, 0x2005, 0, 21);
    expect_mux(fx, 0xA4, 0x2005, 0, 4);
    req(fx, (const uint8_t[8]){ 0x01, 1, 2, 3, 4, 5, 6, 7 });
    req(fx, (const uint8_t[8]){ 0x05, 1, 2, 3, 4, 5, 6, 7 });
    expect_abort(fx, 0x2005, 0, AB_SEQNO);
    assert_int_equal(fx->srv.stats.rx_bad_seqno, 2);   /* (since the re-init) */
    /* CRC mismatch: 0x05040004, nothing written; the domain writer told */
    req_mux(fx, 0xC6, 0x2005, 0, 7);
    expect_mux(fx, 0xA4, 0x2005, 0, 4);
    seg8(b, 0x81, data, 7);
    req(fx, b);
    expect_ack(fx, 1, 4);
    req(fx, (const uint8_t[8]){ 0xC1, 0x12, 0x34, 0, 0, 0, 0, 0 });
    expect_abort(fx, 0x2005, 0, AB_CRC);
    assert_od_bytes(fx, 0x2005, 0, data, 21);
    req_mux(fx, 0xC6, 0x2009, 0, 14);
    expect_mux(fx, 0xA4, 0x2009, 0, 4);
    seg8(b, 0x01, data, 7);
    req(fx, b);
    seg8(b, 0x82, data + 7, 7);
    req(fx, b);
    expect_ack(fx, 2, 4);
    req(fx, (const uint8_t[8]){ 0xC1, 0, 0, 0, 0, 0, 0, 0 });
    expect_abort(fx, 0x2009, 0, AB_CRC);
    assert_int_equal(fx->dom_aborts, 1);
    assert_int_equal(fx->dom_last_abort, AB_CRC);
    assert_int_equal(fx->dom_len, 100);
    /* ... without CRC on one side the CRC field is not checked */
    req_mux(fx, 0xC2, 0x2005, 0, 7);
    expect_mux(fx, 0xA4, 0x2005, 0, 4);
    seg8(b, 0x81, data + 1, 7);
    req(fx, b);
    expect_ack(fx, 1, 4);
    req(fx, (const uint8_t[8]){ 0xC1, 0x12, 0x34, 0, 0, 0, 0, 0 });
    expect_cmd(fx, 0xA1);
    assert_od_bytes(fx, 0x2005, 0, data + 1, 7);
    /* the end frame before the last segment: 0x05040001? no: it is a
     * segment there (seqno 0x41 > blksize 4) */
    req_mux(fx, 0xC6, 0x2005, 0, 7);
    expect_mux(fx, 0xA4, 0x2005, 0, 4);
    req(fx, (const uint8_t[8]){ 0xC1, 0, 0, 0, 0, 0, 0, 0 });
    expect_abort(fx, 0x2005, 0, AB_SEQNO);
    assert_int_equal(fx->srv.stats.rx_crc, 2);
    assert_all_idle(fx);
}

static void test_abort_toggle(void **state)
{
    fx_t *fx = *state;
    uint8_t data[30];
    fill_pattern(data, 30, 1);
    seg_write_ok(fx, 0x2005, 0, data, 30, true);
    /* download: the second segment repeats toggle 0 */
    req_mux(fx, 0x21, 0x2005, 0, 30);
    expect_mux(fx, 0x60, 0x2005, 0, 0);
    req(fx, (const uint8_t[8]){ 0x00, 1, 2, 3, 4, 5, 6, 7 });
    expect_cmd(fx, 0x20);
    req(fx, (const uint8_t[8]){ 0x00, 1, 2, 3, 4, 5, 6, 7 });
    expect_abort(fx, 0x2005, 0, AB_TOGGLE);
    /* ... the first one with toggle 1 */
    req_mux(fx, 0x21, 0x2005, 0, 30);
    expect_mux(fx, 0x60, 0x2005, 0, 0);
    req(fx, (const uint8_t[8]){ 0x10, 1, 2, 3, 4, 5, 6, 7 });
    expect_abort(fx, 0x2005, 0, AB_TOGGLE);
    /* upload */
    req_mux(fx, 0x40, 0x2005, 0, 0);
    expect_mux(fx, 0x41, 0x2005, 0, 30);
    req_cmd(fx, 0x60);
    (void)next_rsp(fx);
    req_cmd(fx, 0x60);
    expect_abort(fx, 0x2005, 0, AB_TOGGLE);
    assert_int_equal(fx->srv.stats.rx_toggle, 3);
    assert_od_bytes(fx, 0x2005, 0, data, 30);
    assert_all_idle(fx);
}

static void test_abort_unknown_command(void **state)
{
    fx_t *fx = *state;
    /* ccs 7 while idle: abort with mux 0 */
    req_mux(fx, 0xE0, 0x2000, 0, 0);
    expect_abort(fx, 0, 0, AB_COMMAND);
    /* frames that start nothing, while idle */
    req_cmd(fx, 0x60);
    expect_abort(fx, 0, 0, AB_COMMAND);
    req(fx, (const uint8_t[8]){ 0x00, 1, 2, 3, 4, 5, 6, 7 });
    expect_abort(fx, 0, 0, AB_COMMAND);
    req_cmd(fx, 0xA3);
    expect_abort(fx, 0, 0, AB_COMMAND);
    req_cmd(fx, 0xC1);
    expect_abort(fx, 0, 0, AB_COMMAND);
    req_cmd(fx, 0x81);                       /* not an abort: only 0x80 is */
    expect_abort(fx, 0, 0, AB_COMMAND);
    /* an unexpected frame ends the open transfer with its mux */
    req_mux(fx, 0x21, 0x2005, 0, 30);
    expect_mux(fx, 0x60, 0x2005, 0, 0);
    req_cmd(fx, 0x60);
    expect_abort(fx, 0x2005, 0, AB_COMMAND);
    req_mux(fx, 0x40, 0x2004, 0, 0);
    expect_mux(fx, 0x41, 0x2004, 0, 5);
    req_cmd(fx, 0xE5);
    expect_abort(fx, 0x2004, 0, AB_COMMAND);
    req(fx, (const uint8_t[8]){ 0xA0, 0x04, 0x20, 0x00, 5, 0, 0, 0 });
    expect_mux(fx, 0xC4 | 2, 0x2004, 0, 5);
    req(fx, (const uint8_t[8]){ 0xA2, 1, 5, 0, 0, 0, 0, 0 });   /* ack before the start */
    expect_abort(fx, 0x2004, 0, AB_COMMAND);
    assert_int_equal(fx->srv.stats.rx_unknown_command, 9);
    assert_all_idle(fx);
}

static void test_abort_timeout(void **state)
{
    fx_t *fx = *state;
    uint64_t t0;
    /* segmented download waiting for its first segment: exactly 1000 ms */
    req_mux(fx, 0x21, 0x2005, 0, 30);
    expect_mux(fx, 0x60, 0x2005, 0, 0);
    t0 = fx->tb.now;
    tu_run_until(&fx->tb, t0 + MS(1000) - 1);
    expect_none(fx);
    assert_int_equal(co_sdo_server_active(&fx->srv), 1);
    tu_run_until(&fx->tb, t0 + MS(1000));
    expect_abort(fx, 0x2005, 0, AB_TIMEOUT);
    /* every frame re-arms it */
    req_mux(fx, 0x40, 0x2004, 0, 0);
    expect_mux(fx, 0x41, 0x2004, 0, 5);
    t0 = fx->tb.now;
    tu_run_until(&fx->tb, t0 + MS(900));
    req(fx, (const uint8_t[8]){ 0xA0, 0x04, 0x20, 0x00, 5, 0, 0, 0 });   /* restart: block */
    expect_mux(fx, 0xC6, 0x2004, 0, 5);
    tu_run_until(&fx->tb, t0 + MS(1899));
    expect_none(fx);
    tu_run_until(&fx->tb, t0 + MS(1900));
    expect_abort(fx, 0x2004, 0, AB_TIMEOUT);
    assert_int_equal(fx->srv.stats.timeouts, 2);
    assert_int_equal(fx->srv.stats.restarts, 1);
    /* block upload waiting for the ack; configurable timeout */
    reinit_server(fx, 250, 0, false);
    req(fx, (const uint8_t[8]){ 0xA0, 0x04, 0x20, 0x00, 5, 0, 0, 0 });
    expect_mux(fx, 0xC6, 0x2004, 0, 5);
    req_cmd(fx, 0xA3);
    (void)next_rsp(fx);
    t0 = fx->tb.now;
    tu_run_until(&fx->tb, t0 + MS(250));
    expect_abort(fx, 0x2004, 0, AB_TIMEOUT);
    assert_int_equal(fx->srv.stats.timeouts, 1);
    assert_all_idle(fx);
}

/* Every OD refusal passes its own code, whatever the protocol. */
static void test_abort_od_errors(void **state)
{
    fx_t *fx = *state;
    uint8_t b[8];
    /* no object / no sub-index */
    req_mux(fx, 0x40, 0x3000, 0, 0);
    expect_abort(fx, 0x3000, 0, AB_NO_OBJECT);
    req_mux(fx, 0x23, 0x3000, 0, 1);
    expect_abort(fx, 0x3000, 0, AB_NO_OBJECT);
    req_mux(fx, 0x40, 0x200A, 5, 0);
    expect_abort(fx, 0x200A, 5, AB_NO_SUB);
    req_mux(fx, 0xC6, 0x200A, 5, 4);
    expect_abort(fx, 0x200A, 5, AB_NO_SUB);
    mux8(b, 0xA4, 0x3000, 1, 0);
    b[4] = 127;
    req(fx, b);
    expect_abort(fx, 0x3000, 1, AB_NO_OBJECT);
    /* read-only, write-only */
    req_mux(fx, 0x23, 0x2006, 0, 1);
    expect_abort(fx, 0x2006, 0, AB_READ_ONLY);
    req_mux(fx, 0x21, 0x2006, 0, 4);
    expect_abort(fx, 0x2006, 0, AB_READ_ONLY);
    req_mux(fx, 0xC6, 0x2006, 0, 4);
    expect_abort(fx, 0x2006, 0, AB_READ_ONLY);
    req_mux(fx, 0x40, 0x2007, 0, 0);
    expect_abort(fx, 0x2007, 0, AB_WRITE_ONLY);
    mux8(b, 0xA4, 0x2007, 0, 0);
    b[4] = 127;
    req(fx, b);
    expect_abort(fx, 0x2007, 0, AB_WRITE_ONLY);
    /* length */
    req_mux(fx, 0x23, 0x2001, 0, 1);          /* 4 bytes into a U16 */
    expect_abort(fx, 0x2001, 0, AB_LEN_HIGH);
    req_mux(fx, 0x2F, 0x2002, 0, 1);          /* 1 byte into a U32 */
    expect_abort(fx, 0x2002, 0, AB_LEN_LOW);
    req_mux(fx, 0x21, 0x2001, 0, 3);
    expect_abort(fx, 0x2001, 0, AB_LEN_HIGH);
    req_mux(fx, 0xC6, 0x2002, 0, 100);
    expect_abort(fx, 0x2002, 0, AB_LEN_HIGH);
    req_mux(fx, 0xC6, 0x2004, 0, 201);
    expect_abort(fx, 0x2004, 0, AB_LEN_HIGH);
    /* value range (10..100) */
    req_mux(fx, 0x2B, 0x2008, 0, 5);
    expect_abort(fx, 0x2008, 0, AB_LOW);
    req_mux(fx, 0x2B, 0x2008, 0, 200);
    expect_abort(fx, 0x2008, 0, AB_HIGH);
    req_mux(fx, 0xC6, 0x2008, 0, 2);
    expect_mux(fx, 0xA4, 0x2008, 0, 127);
    req(fx, (const uint8_t[8]){ 0x81, 0xFF, 0x00, 0, 0, 0, 0, 0 });
    expect_ack(fx, 1, 127);
    {
        uint16_t crc = ref_crc(0, (const uint8_t *)"\xFF\x00", 2);
        req(fx, (const uint8_t[8]){ 0xD5, (uint8_t)crc, (uint8_t)(crc >> 8), 0, 0, 0, 0, 0 });
    }
    expect_abort(fx, 0x2008, 0, AB_HIGH);
    exp_read_ok(fx, 0x2008, 0, (const uint8_t *)"\x32\x00", 2);
    /* more than the channel's scratch: out of memory */
    req_mux(fx, 0x40, 0x2012, 0, 0);
    expect_abort(fx, 0x2012, 0, AB_MEMORY);
    req_mux(fx, 0x21, 0x2012, 0, 10);
    expect_abort(fx, 0x2012, 0, AB_MEMORY);
    /* the domain reader refuses: at the first segment / at the start */
    fx->dom_read_error = 0x08000024u;
    req_mux(fx, 0x40, 0x2009, 0, 0);
    expect_mux(fx, 0x41, 0x2009, 0, 100);
    req_cmd(fx, 0x60);
    expect_abort(fx, 0x2009, 0, 0x08000024u);
    mux8(b, 0xA0, 0x2009, 0, 0);
    b[4] = 127;
    req(fx, b);
    expect_mux(fx, 0xC6, 0x2009, 0, 100);
    req_cmd(fx, 0xA3);
    expect_abort(fx, 0x2009, 0, 0x08000024u);
    fx->dom_read_error = 0;
    assert_int_equal(fx->srv.stats.od_aborts, 22);
    assert_int_equal(fx->srv.stats.downloads, 0);
    assert_all_idle(fx);
}

/* ================================================= client aborts, restarts */

static void test_client_abort_and_restart(void **state)
{
    fx_t *fx = *state;
    uint8_t data[70];
    fill_pattern(data, 70, 5);
    /* a client abort ends the transfer, the domain writer is told, no answer */
    req_mux(fx, 0x21, 0x2009, 0, 70);
    expect_mux(fx, 0x60, 0x2009, 0, 0);
    req(fx, (const uint8_t[8]){ 0x00, 1, 2, 3, 4, 5, 6, 7 });
    expect_cmd(fx, 0x20);
    req_mux(fx, 0x80, 0x2009, 0, 0x05040000);
    expect_none(fx);
    assert_int_equal(fx->dom_aborts, 1);
    assert_int_equal(fx->dom_last_abort, 0x05040000);
    assert_int_equal(fx->dom_len, 100);
    /* ... also inside a block download sub-block */
    req_mux(fx, 0xC6, 0x2009, 0, 70);
    expect_mux(fx, 0xA4, 0x2009, 0, 127);
    req(fx, (const uint8_t[8]){ 0x01, 1, 2, 3, 4, 5, 6, 7 });
    req_mux(fx, 0x80, 0x2009, 0, 0);
    expect_none(fx);
    assert_int_equal(fx->dom_aborts, 2);
    /* a stray abort is counted, not answered */
    req_mux(fx, 0x80, 0x2009, 0, 0x08000000);
    expect_none(fx);
    assert_int_equal(fx->srv.stats.rx_client_abort, 2);
    assert_int_equal(fx->srv.stats.rx_stray_abort, 1);
    /* a new initiate on a busy channel starts over, silently */
    req_mux(fx, 0x21, 0x2009, 0, 70);
    expect_mux(fx, 0x60, 0x2009, 0, 0);
    req(fx, (const uint8_t[8]){ 0x00, 1, 2, 3, 4, 5, 6, 7 });
    expect_cmd(fx, 0x20);
    seg_write_ok(fx, 0x2009, 0, data, 70, true);
    assert_int_equal(fx->dom_aborts, 3);
    assert_int_equal(fx->srv.stats.restarts, 1);
    assert_memory_equal(fx->domain, data, 70);
    req_mux(fx, 0x40, 0x2009, 0, 0);
    expect_mux(fx, 0x41, 0x2009, 0, 70);
    exp_read_ok(fx, 0x2000, 0, (const uint8_t *)"\x11", 1);
    assert_int_equal(fx->srv.stats.restarts, 2);
    assert_all_idle(fx);
}

static void test_ignored_frames_are_counted(void **state)
{
    fx_t *fx = *state;
    co_frame_t f;
    uint8_t b[8] = { 0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0 };
    uint8_t len;
    /* shorter (and no longer frames exist on a classic line) */
    for (len = 0; len < 8; len++)
        req_raw(fx, REQ0, b, len);
    expect_none(fx);
    assert_int_equal(fx->srv.stats.rx_bad_length, 8);
    /* an FD frame: dropped by the classic line */
    f = tu_frame(REQ0, CO_FRAME_FD, b, 8);
    assert_true(co_line_receive(fx->a, &f));
    tu_step(&fx->tb, fx->tb.now);
    expect_none(fx);
    assert_int_equal(fx->a->stats.rx_wrong_format, 1);
    /* a remote frame: dropped by the line */
    f = tu_frame(REQ0, CO_FRAME_RTR, NULL, 0);
    assert_true(co_line_receive(fx->a, &f));
    tu_step(&fx->tb, fx->tb.now);
    expect_none(fx);
    assert_int_equal(fx->a->stats.rx_rtr, 1);
    /* a channel that is off: nobody listens */
    req_raw(fx, REQ1, b, 8);
    expect_none(fx);
    assert_int_equal(fx->srv.stats.rx_frames, 8);
    assert_all_idle(fx);
    exp_read_ok(fx, 0x2000, 0, (const uint8_t *)"\x11", 1);
}

/* Faults on the bus in segmented transfers: a lost request or answer ends
 * in the timeout abort, a duplicated segment in the toggle abort, a repeat
 * of the frame that ended a transfer is ignored; never a wedged channel. */
static void test_segmented_faults(void **state)
{
    fx_t *fx = *state;
    uint8_t data[30];
    uint64_t t0;
    fill_pattern(data, 30, 0x31);
    /* duplicated second request (the first segment) */
    fx->fault.id = REQ0;
    fx->fault.count = 0;
    fx->fault.dup[0] = 2;
    fx->fault.n_dup = 1;
    req_mux(fx, 0x21, 0x2005, 0, 30);
    expect_mux(fx, 0x60, 0x2005, 0, 0);
    req(fx, (const uint8_t[8]){ 0x00, 1, 2, 3, 4, 5, 6, 7 });
    expect_cmd(fx, 0x20);
    expect_abort(fx, 0x2005, 0, AB_TOGGLE);
    fx->fault.n_dup = 0;
    /* lost segment request */
    fx->fault.count = 0;
    fx->fault.drop[0] = 2;
    fx->fault.n_drop = 1;
    req_mux(fx, 0x40, 0x2005, 0, 0);
    expect_mux(fx, 0x41, 0x2005, 0, 0);
    req_cmd(fx, 0x60);
    expect_none(fx);
    t0 = fx->tb.now;
    tu_run_until(&fx->tb, t0 + MS(1000));
    expect_abort(fx, 0x2005, 0, AB_TIMEOUT);
    fx->fault.n_drop = 0;
    /* lost answer */
    fx->fault.id = RSP0;
    fx->fault.count = 0;
    fx->fault.drop[0] = 1;
    fx->fault.n_drop = 1;
    req_mux(fx, 0x21, 0x2005, 0, 30);
    expect_none(fx);
    t0 = fx->tb.now;
    tu_run_until(&fx->tb, t0 + MS(1000));
    expect_abort(fx, 0x2005, 0, AB_TIMEOUT);
    fx->fault.n_drop = 0;
    /* the last segment of a download and the end of an upload delivered
     * twice: the repeat is ignored */
    fx->fault.id = REQ0;
    fx->fault.count = 0;
    fx->fault.dup[0] = 6;                      /* init + 4 segments + last */
    fx->fault.n_dup = 1;
    seg_write_ok(fx, 0x2005, 0, data, 30, true);
    fx->fault.count = 0;
    fx->fault.dup[0] = 6;
    seg_read_ok(fx, 0x2005, 0, data, 30, 30);
    fx->fault.count = 0;
    fx->fault.dup[0] = 4;                      /* init, start, ack, end response */
    block_read_ok(fx, 0x2005, 0, data, 30, true, true, 127, 30);
    fx->fault.count = 0;
    fx->fault.dup[0] = 7;                      /* init, 5 segments, end */
    block_write_ok(fx, 0x2005, 0, data, 30, true, true, true, 127);
    fx->fault.n_dup = 0;
    assert_int_equal(fx->srv.stats.rx_duplicate, 4);
    assert_int_equal(fx->srv.stats.aborts_sent, 3);
    assert_od_bytes(fx, 0x2005, 0, data, 30);
    assert_all_idle(fx);
}

/* ================================================= split answers */

static void test_split_deferral(void **state)
{
    fx_t *fx = *state;
    co_od_xfer_t *held;
    uint8_t b[8];
    uint64_t t0;
    /* upload: no answer until the application says so */
    fx->split_read = true;
    req_mux(fx, 0x40, 0x200B, 0, 0);
    expect_none(fx);
    assert_non_null(fx->held);
    held = fx->held;
    assert_true(co_sdo_server_resume(&fx->srv, held, CO_OD_SPLIT));
    tu_step(&fx->tb, fx->tb.now);
    expect_none(fx);
    assert_true(co_sdo_server_resume(&fx->srv, held, 0));
    tu_step(&fx->tb, fx->tb.now);
    expect_mux(fx, 0x43, 0x200B, 0, 0xB0B0B0B0u);
    assert_false(co_sdo_server_resume(&fx->srv, held, 0));
    /* block upload initiate */
    mux8(b, 0xA4, 0x200B, 0, 0);
    b[4] = 127;
    req(fx, b);
    expect_none(fx);
    assert_true(co_sdo_server_resume(&fx->srv, fx->held, 0));
    tu_step(&fx->tb, fx->tb.now);
    expect_mux(fx, 0xC6, 0x200B, 0, 4);
    req_cmd(fx, 0x80);
    fx->split_read = false;
    /* expedited download: accepted, refused */
    fx->split_write = true;
    req_mux(fx, 0x23, 0x200B, 0, 0x12345678u);
    expect_none(fx);
    assert_int_equal(od_u32(fx, 0x200B, 0), 0xB0B0B0B0u);
    assert_true(co_sdo_server_resume(&fx->srv, fx->held, 0));
    tu_step(&fx->tb, fx->tb.now);
    expect_mux(fx, 0x60, 0x200B, 0, 0);
    assert_int_equal(od_u32(fx, 0x200B, 0), 0x12345678u);
    req_mux(fx, 0x23, 0x200B, 0, 1);
    assert_true(co_sdo_server_resume(&fx->srv, fx->held, AB_STATE));
    tu_step(&fx->tb, fx->tb.now);
    expect_abort(fx, 0x200B, 0, AB_STATE);
    /* segmented: the answer to the last segment waits (the timeout counts
     * from that segment) */
    req_mux(fx, 0x21, 0x200B, 0, 4);
    expect_mux(fx, 0x60, 0x200B, 0, 0);
    t0 = fx->tb.now;
    tu_run_until(&fx->tb, t0 + MS(600));
    req(fx, (const uint8_t[8]){ 0x07, 0x44, 0x33, 0x22, 0x11, 0, 0, 0 });
    expect_none(fx);
    assert_int_equal(fx->ch[0].timer.deadline_us, t0 + MS(1600));
    assert_true(co_sdo_server_resume(&fx->srv, fx->held, 0));
    tu_step(&fx->tb, fx->tb.now);
    expect_cmd(fx, 0x20);
    assert_int_equal(od_u32(fx, 0x200B, 0), 0x11223344u);
    /* block: the answer to the end frame waits */
    req_mux(fx, 0xC6, 0x200B, 0, 4);
    expect_mux(fx, 0xA4, 0x200B, 0, 127);
    req(fx, (const uint8_t[8]){ 0x81, 0xDD, 0xCC, 0xBB, 0xAA, 0, 0, 0 });
    expect_ack(fx, 1, 127);
    {
        uint16_t crc = ref_crc(0, (const uint8_t *)"\xDD\xCC\xBB\xAA", 4);
        req(fx, (const uint8_t[8]){ 0xCD, (uint8_t)crc, (uint8_t)(crc >> 8), 0, 0, 0, 0, 0 });
    }
    expect_none(fx);
    assert_true(co_sdo_server_resume(&fx->srv, fx->held, 0));
    tu_step(&fx->tb, fx->tb.now);
    expect_cmd(fx, 0xA1);
    assert_int_equal(od_u32(fx, 0x200B, 0), 0xAABBCCDDu);
    /* a new initiate while waiting: the waiting one is dropped, the new one
     * refused until the application answered */
    req_mux(fx, 0x23, 0x200B, 0, 5);
    held = fx->held;
    req_mux(fx, 0x40, 0x2000, 0, 0);
    expect_abort(fx, 0x2000, 0, AB_RESOURCE);
    assert_int_equal(fx->ch[0].state, CO_SDO_CH_ABANDONED);
    assert_false(co_sdo_server_resume(&fx->srv, held, 0));
    tu_step(&fx->tb, fx->tb.now);
    expect_none(fx);
    assert_int_equal(od_u32(fx, 0x200B, 0), 0xAABBCCDDu);
    exp_read_ok(fx, 0x2000, 0, (const uint8_t *)"\x11", 1);
    /* a timeout while waiting: abort sent, the late answer only frees */
    req_mux(fx, 0x23, 0x200B, 0, 6);
    t0 = fx->tb.now;
    tu_run_until(&fx->tb, t0 + MS(1000));
    expect_abort(fx, 0x200B, 0, AB_TIMEOUT);
    assert_int_equal(co_sdo_server_active(&fx->srv), 1);
    assert_false(co_sdo_server_resume(&fx->srv, fx->held, 0));
    assert_int_equal(od_u32(fx, 0x200B, 0), 0xAABBCCDDu);
    /* a client abort while waiting: nothing sent */
    req_mux(fx, 0x23, 0x200B, 0, 7);
    req_mux(fx, 0x80, 0x200B, 0, 0);
    expect_none(fx);
    assert_false(co_sdo_server_resume(&fx->srv, fx->held, 0));
    /* any other frame while waiting: 0x05040001 */
    req_mux(fx, 0x23, 0x200B, 0, 8);
    req_cmd(fx, 0x60);
    expect_abort(fx, 0x200B, 0, AB_COMMAND);
    assert_false(co_sdo_server_resume(&fx->srv, fx->held, 0));
    tu_step(&fx->tb, fx->tb.now);
    expect_none(fx);
    fx->split_write = false;
    assert_int_equal(od_u32(fx, 0x200B, 0), 0xAABBCCDDu);
    assert_false(co_sdo_server_resume(&fx->srv, NULL, 0));
    assert_all_idle(fx);
}

/* ================================================= further channels */

static void dummy_rx(co_line_t *line, const co_frame_t *frame, void *user)
{
    (void)line;
    (void)frame;
    (void)user;
}

static void test_second_channel_via_1201(void **state)
{
    fx_t *fx = *state;
    uint8_t v[4];
    uint8_t data[40];
    fill_pattern(data, 40, 0x40);
    assert_false(fx->ch[1].valid);
    assert_false(fx->ch[2].valid);          /* no 0x1202 in the OD */
    /* off: nobody answers on its CAN-ID */
    use_channel(fx, REQ1, RSP1);
    req_mux(fx, 0x40, 0x2000, 0, 0);
    expect_none(fx);
    /* enable: sub 2 first (still off), then sub 1 */
    use_channel(fx, REQ0, RSP0);
    le_put32(v, RSP1);
    exp_write_ok(fx, 0x1201, 2, v, 4);
    assert_false(fx->ch[1].valid);
    le_put32(v, REQ1);
    exp_write_ok(fx, 0x1201, 1, v, 4);
    assert_true(fx->ch[1].valid);
    use_channel(fx, REQ1, RSP1);
    exp_read_ok(fx, 0x2000, 0, (const uint8_t *)"\x11", 1);
    /* both channels at once, interleaved */
    req_mux(fx, 0x21, 0x2005, 0, 14);
    expect_mux(fx, 0x60, 0x2005, 0, 0);
    use_channel(fx, REQ0, RSP0);
    req_mux(fx, 0x40, 0x2004, 0, 0);
    expect_mux(fx, 0x41, 0x2004, 0, 5);
    use_channel(fx, REQ1, RSP1);
    req(fx, (const uint8_t[8]){ 0x00, 1, 2, 3, 4, 5, 6, 7 });
    expect_cmd(fx, 0x20);
    use_channel(fx, REQ0, RSP0);
    req_cmd(fx, 0x60);
    expect(fx, (const uint8_t[8]){ 0x05, 'h', 'e', 'l', 'l', 'o', 0, 0 });
    use_channel(fx, REQ1, RSP1);
    req(fx, (const uint8_t[8]){ 0x11, 8, 9, 10, 11, 12, 13, 14 });
    expect_cmd(fx, 0x30);
    assert_od_bytes(fx, 0x2005, 0, (const uint8_t *)"\1\2\3\4\5\6\7\x8\x9\xA\xB\xC\xD\xE", 14);
    block_write_ok(fx, 0x2009, 0, data, 40, true, true, true, 127);
    block_read_ok(fx, 0x2009, 0, data, 40, true, true, 3, 40);
    /* a CAN-ID change while valid: refused by the COB-ID rule */
    use_channel(fx, REQ0, RSP0);
    req_mux(fx, 0x23, 0x1201, 1, 0x6C1);
    expect_abort(fx, 0x1201, 1, AB_INVALID);
    req_mux(fx, 0x23, 0x1201, 2, 0x6C1);
    expect_abort(fx, 0x1201, 2, AB_INVALID);
    /* the default channel's entries are read-only */
    req_mux(fx, 0x23, 0x1200, 1, 0x6C1);
    expect_abort(fx, 0x1200, 1, AB_READ_ONLY);
    exp_read_ok(fx, 0x1200, 1, (const uint8_t *)"\x05\x06\x00\x00", 4);
    /* channel 1 turns itself off: the answer still goes out on its CAN-ID */
    use_channel(fx, REQ1, RSP1);
    le_put32(v, 0x80000000u | REQ1);
    exp_write_ok(fx, 0x1201, 1, v, 4);
    assert_false(fx->ch[1].valid);
    req_mux(fx, 0x40, 0x2000, 0, 0);
    expect_none(fx);
    /* restricted, 29-bit, in use by another service: refused */
    use_channel(fx, REQ0, RSP0);
    req_mux(fx, 0x23, 0x1201, 1, 0x605);
    expect_abort(fx, 0x1201, 1, AB_INVALID);
    req_mux(fx, 0x23, 0x1201, 1, 0x20000000u | REQ1);
    expect_abort(fx, 0x1201, 1, AB_INVALID);
    req_mux(fx, 0x23, 0x1201, 2, 0x5A0);
    expect_abort(fx, 0x1201, 2, AB_INVALID);
    assert_true(co_line_subscribe(fx->a, 0x6C0, 0x6C0, dummy_rx, NULL));
    req_mux(fx, 0x23, 0x1201, 1, 0x6C0);
    expect_abort(fx, 0x1201, 1, AB_INVALID);
    co_line_unsubscribe(fx->a, dummy_rx, NULL);
    /* change and re-enable in one write (allowed: it was invalid) */
    req_mux(fx, 0x23, 0x1201, 1, 0x6A6);
    expect_mux(fx, 0x60, 0x1201, 1, 0);
    assert_true(fx->ch[1].valid);
    assert_int_equal(fx->ch[1].rx_id, 0x6A6);
    use_channel(fx, 0x6A6, RSP1);
    exp_read_ok(fx, 0x2000, 0, (const uint8_t *)"\x11", 1);
    /* the application's write takes effect too (no checks for it) */
    le_put32(v, 0x80000000u);
    assert_int_equal(co_od_put(&fx->od, 0x1201, 1, v, 4), 0);
    assert_false(fx->ch[1].valid);
    le_put32(v, REQ1);
    assert_int_equal(co_od_put(&fx->od, 0x1201, 1, v, 4), 0);
    assert_true(fx->ch[1].valid);
    use_channel(fx, REQ1, RSP1);
    exp_read_ok(fx, 0x2000, 0, (const uint8_t *)"\x11", 1);
    /* ... a 29-bit CAN-ID from the application is not served, counted */
    le_put32(v, 0x20000000u | REQ1);
    assert_int_equal(co_od_put(&fx->od, 0x1201, 1, v, 4), 0);
    assert_false(fx->ch[1].valid);
    assert_int_equal(fx->srv.stats.config_refused, 1);
    assert_all_idle(fx);
}

/* A channel that writes its own COB-ID answers on the old CAN-ID, then takes
 * the new one (the change waits for its own co_od call to end), and a later
 * frame on another channel finds nothing left waiting. */
static void test_channel_changes_its_own_cob_id(void **state)
{
    fx_t *fx = *state;
    enable_channel1(fx);
    use_channel(fx, REQ1, RSP1);
    req_mux(fx, 0x23, 0x1201, 1, 0x80000000u | REQ1);   /* disable myself */
    expect_mux(fx, 0x60, 0x1201, 1, 0);                 /* answered on RSP1 */
    assert_false(fx->ch[1].valid);
    assert_false(fx->ch[1].reconfig);
    assert_false(fx->srv.reconfig_waiting);
    req_mux(fx, 0x40, 0x2000, 0, 0);                     /* channel 1 is gone */
    expect_none(fx);
    use_channel(fx, REQ0, RSP0);
    exp_read_ok(fx, 0x2000, 0, (const uint8_t *)"\x11", 1);
    assert_all_idle(fx);
}

/* An open transfer on a channel whose COB-ID changes ends: the object
 * dictionary is told, nothing is sent (the channel is gone). */
static void test_channel_reset_on_cob_id_change(void **state)
{
    fx_t *fx = *state;
    uint8_t v[4];
    enable_channel1(fx);
    use_channel(fx, REQ1, RSP1);
    req_mux(fx, 0x21, 0x2009, 0, 70);
    expect_mux(fx, 0x60, 0x2009, 0, 0);
    le_put32(v, 0x80000000u | REQ1);
    assert_int_equal(co_od_put(&fx->od, 0x1201, 1, v, 4), 0);
    tu_step(&fx->tb, fx->tb.now);
    expect_none(fx);
    assert_int_equal(fx->dom_aborts, 1);
    assert_int_equal(fx->dom_last_abort, AB_STATE);
    assert_int_equal(fx->srv.stats.channel_resets, 1);
    assert_all_idle(fx);
    /* the same value again changes nothing */
    enable_channel1(fx);
    use_channel(fx, REQ1, RSP1);
    req_mux(fx, 0x21, 0x2009, 0, 70);
    expect_mux(fx, 0x60, 0x2009, 0, 0);
    le_put32(v, REQ1);
    assert_int_equal(co_od_put(&fx->od, 0x1201, 1, v, 4), 0);
    assert_int_equal(co_sdo_server_active(&fx->srv), 1);
    req_mux(fx, 0x80, 0x2009, 0, 0);
    assert_all_idle(fx);
}

static void test_refresh_and_deinit(void **state)
{
    fx_t *fx = *state;
    /* a new node-id moves the default channel */
    fx->a->node_id = 6;
    co_sdo_server_refresh(&fx->srv);
    use_channel(fx, 0x606, 0x586);
    exp_read_ok(fx, 0x2000, 0, (const uint8_t *)"\x11", 1);
    use_channel(fx, REQ0, RSP0);
    req_mux(fx, 0x40, 0x2000, 0, 0);
    expect_none(fx);
    fx->a->node_id = ID_S;
    co_sdo_server_refresh(&fx->srv);
    exp_read_ok(fx, 0x2000, 0, (const uint8_t *)"\x11", 1);
    /* deinit with an open transfer: the domain writer is told, nothing
     * sent, nothing armed, nothing answered after */
    enable_channel1(fx);
    req_mux(fx, 0x21, 0x2009, 0, 70);
    expect_mux(fx, 0x60, 0x2009, 0, 0);
    co_sdo_server_deinit(&fx->srv);
    assert_int_equal(fx->dom_aborts, 1);
    assert_all_idle(fx);
    assert_int_equal(co_timer_list_next(co_line_timers(fx->a)), CO_TIME_NEVER);
    req(fx, (const uint8_t[8]){ 0x00, 1, 2, 3, 4, 5, 6, 7 });
    expect_none(fx);
    /* the OD hook is gone: a COB-ID write changes nothing here */
    {
        uint8_t v[4];
        le_put32(v, 0x80000000u | REQ1);
        assert_int_equal(co_od_put(&fx->od, 0x1201, 1, v, 4), 0);
        le_put32(v, REQ1);
        assert_int_equal(co_od_put(&fx->od, 0x1201, 1, v, 4), 0);
    }
    /* a new server picks the configuration up */
    server_init_cfg(fx, 0, 0, false);
    assert_true(fx->ch[1].valid);
    exp_read_ok(fx, 0x2000, 0, (const uint8_t *)"\x11", 1);
    /* created before the line has a node-id: no default channel until the
     * refresh */
    co_sdo_server_deinit(&fx->srv);
    fx->a->node_id = 0;
    server_init_cfg(fx, 0, 0, false);
    assert_false(fx->ch[0].valid);
    assert_true(fx->ch[1].valid);
    req_mux(fx, 0x40, 0x2000, 0, 0);
    expect_none(fx);
    fx->a->node_id = ID_S;
    co_sdo_server_refresh(&fx->srv);
    assert_true(fx->ch[0].valid);
    exp_read_ok(fx, 0x2000, 0, (const uint8_t *)"\x11", 1);
}

/* ================================================= garbage and endurance */

static void check_channels_bounded(const fx_t *fx, uint64_t now)
{
    uint8_t k;
    for (k = 0; k < NCH; k++) {
        const co_sdo_channel_t *c = &fx->ch[k];
        if (c->state == CO_SDO_CH_IDLE)
            continue;
        assert_true(c->state >= CO_SDO_CH_DOWNLOAD && c->state <= CO_SDO_CH_BLOCK_UPLOAD_END);
        assert_true(co_timer_is_armed(&c->timer));
        assert_true(c->timer.deadline_us > now);
        assert_true(c->timer.deadline_us <= now + MS(1000));
        assert_true(c->xfer.state == CO_XFER_WRITE || c->xfer.state == CO_XFER_READ ||
                    c->xfer.state == CO_XFER_DONE);
    }
}

static void test_random_frames_never_wedge(void **state)
{
    fx_t *fx = *state;
    static const uint8_t cmds[] = { 0x00, 0x10, 0x01, 0x0B, 0x20, 0x21, 0x22, 0x23, 0x2B, 0x2F,
                                    0x40, 0x60, 0x70, 0x80, 0xA0, 0xA4, 0xA1, 0xA2, 0xA3, 0xC0,
                                    0xC4, 0xC6, 0xC1, 0xC5, 0xE0, 0x81, 0x85, 0x7F, 0x03 };
    uint64_t seed = 0x5D05EED;
    uint64_t now;
    unsigned i, responses = 0;
    size_t j;
    enable_channel1(fx);
    memset(&fx->srv.stats, 0, sizeof fx->srv.stats);
    now = fx->tb.now;
    for (i = 0; i < 10000; i++) {
        co_frame_t f;
        uint64_t r = tu_rand(&seed);
        memset(&f, 0, sizeof f);
        f.id = (r & 1u) ? REQ0 : REQ1;
        f.len = ((r >> 1) & 15u) == 0 ? (uint8_t)((r >> 5) % 8u) : 8;
        for (j = 0; j < f.len; j++)
            f.data[j] = (uint8_t)tu_rand(&seed);
        r = tu_rand(&seed);
        if (f.len > 0 && (r & 3u) != 0)
            f.data[0] = cmds[(r >> 2) % sizeof cmds];
        if (f.len > 3 && ((r >> 8) & 3u) != 0) {
            f.data[1] = (uint8_t)((r >> 10) % 14u);
            f.data[2] = 0x20;
            f.data[3] = (uint8_t)((r >> 14) % 2u);
        }
        if (f.len > 7 && ((r >> 16) & 1u)) {
            f.data[4] = (uint8_t)((r >> 17) % 130u);   /* small sizes, block sizes */
            f.data[5] = (uint8_t)((r >> 24) % 3u);
            f.data[6] = 0;
            f.data[7] = 0;
        }
        assert_true(co_line_send_raw(fx->b, &f));
        r = tu_rand(&seed);
        now += (r % 8u == 0) ? (r >> 8) % MS(1500) : (r >> 8) % MS(20);
        tu_run_until(&fx->tb, now);
        for (j = 0; j < fx->tb.log_count; j++) {
            const co_frame_t *g = &fx->tb.log[j].frame;
            if (g->id != RSP0 && g->id != RSP1)
                continue;
            responses++;
            assert_int_equal(g->flags, 0);
            assert_int_equal(g->len, 8);
        }
        tu_log_clear(&fx->tb);
        fx->cursor = 0;
        check_channels_bounded(fx, now);
    }
    tu_run_until(&fx->tb, now + MS(2001));
    tu_log_clear(&fx->tb);
    fx->cursor = 0;
    assert_all_idle(fx);
    assert_true(fx->ch[1].valid);
    assert_int_equal(fx->srv.stats.rx_frames, 10000);
    assert_true(fx->srv.stats.rx_bad_length > 0);
    assert_true(fx->srv.stats.rx_unknown_command > 0);
    assert_true(fx->srv.stats.rx_toggle > 0);
    assert_true(fx->srv.stats.rx_bad_seqno > 0);
    assert_true(fx->srv.stats.rx_bad_blksize > 0);
    assert_true(fx->srv.stats.rx_stray_abort > 0);
    assert_true(fx->srv.stats.rx_block_ignored > 0);
    assert_true(fx->srv.stats.od_aborts > 0);
    assert_true(fx->srv.stats.timeouts > 0);
    assert_true(fx->srv.stats.downloads + fx->srv.stats.uploads > 0);
    assert_true(responses > 1000);
    assert_int_equal(fx->srv.stats.tx_failed, 0);
    /* the server still works on both channels */
    use_channel(fx, REQ0, RSP0);
    exp_read_ok(fx, 0x2006, 0, (const uint8_t *)"\x0D\xF0\xFE\xCA", 4);
    use_channel(fx, REQ1, RSP1);
    exp_read_ok(fx, 0x2006, 0, (const uint8_t *)"\x0D\xF0\xFE\xCA", 4);
}

/* 1 000 transfers of every kind on both channels, sizes at random: every
 * one completes, byte for byte, and leaves no channel behind. */
static void test_mixed_transfers_no_leak(void **state)
{
    fx_t *fx = *state;
    static uint8_t data[3000];
    uint64_t seed = 0xA11;
    unsigned i;
    unsigned kinds[8] = { 0 };
    enable_channel1(fx);
    for (i = 0; i < 1000; i++) {
        uint64_t r = tu_rand(&seed);
        unsigned kind = (unsigned)(r % 8u);
        bool dom = ((r >> 3) & 1u) != 0;
        uint16_t index = dom ? 0x2009 : 0x2005;
        uint32_t n = (uint32_t)((r >> 4) % (dom ? 3000u : 1001u));
        bool crc = ((r >> 20) & 1u) != 0;
        uint8_t blk = (uint8_t)(1u + (r >> 21) % 127u);
        if ((r >> 30) & 1u)
            use_channel(fx, REQ1, RSP1);
        else
            use_channel(fx, REQ0, RSP0);
        fill_pattern(data, n, (uint8_t)i);
        kinds[kind]++;
        switch (kind) {
        case 0: { /* expedited both ways on the U32 */
            uint8_t v[4];
            le_put32(v, (uint32_t)r);
            exp_write_ok(fx, 0x2002, 0, v, 4);
            exp_read_ok(fx, 0x2002, 0, v, 4);
            break;
        }
        case 1:
            seg_write_ok(fx, index, 0, data, n, true);
            break;
        case 2:
            seg_write_ok(fx, index, 0, data, n, false);
            break;
        case 3:
            block_write_ok(fx, index, 0, data, n, crc, true, true, 127);
            break;
        case 4:
            block_write_ok(fx, index, 0, data, n, crc, false, true, 127);
            break;
        default:
            seg_write_ok(fx, index, 0, data, n, true);
            break;
        }
        if (kind == 0) {
            assert_all_idle(fx);
            continue;
        }
        /* read it back */
        if (kind >= 5 && n > 0)
            block_read_ok(fx, index, 0, data, n, crc, true, blk, n);
        else if (n > 4 || n == 0)
            seg_read_ok(fx, index, 0, data, n, n);
        else
            exp_read_ok(fx, index, 0, data, (uint8_t)n);
        assert_all_idle(fx);
    }
    for (i = 0; i < 8; i++)
        assert_true(kinds[i] > 50);
    assert_int_equal(fx->srv.stats.aborts_sent, 0);
    assert_int_equal(fx->srv.stats.tx_failed, 0);
    assert_int_equal(co_timer_list_next(co_line_timers(fx->a)), CO_TIME_NEVER);
}

/* ================================================= runner */

#define T(t) cmocka_unit_test_setup_teardown(t, setup, teardown)

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_crc16_ccitt),
        cmocka_unit_test(test_codec_decode_requests),
        cmocka_unit_test(test_codec_decode_responses),
        cmocka_unit_test(test_codec_encode_every_frame),
        cmocka_unit_test(test_codec_encode_refuses),
        cmocka_unit_test(test_codec_every_command_byte),
        cmocka_unit_test(test_codec_truncated_frames),
        cmocka_unit_test(test_codec_random_input),
        cmocka_unit_test(test_codec_restricted_ids),
        T(test_init_refuses_bad_config),
        T(test_expedited_upload_each_size),
        T(test_expedited_download_each_size),
        T(test_segmented_upload_toggle),
        T(test_segmented_download_size_or_not),
        T(test_segmented_domain_100k_both_ways),
        T(test_segmented_unknown_size_ends),
        T(test_block_download_exact),
        T(test_block_download_100k_blksizes_crc),
        T(test_block_download_lost_segment_repeated),
        T(test_block_download_faults_recover),
        T(test_block_download_random_losses),
        T(test_block_upload_exact),
        T(test_block_upload_100k_blksizes_crc),
        T(test_block_upload_short_ack_repeats),
        T(test_block_upload_protocol_switch),
        T(test_block_upload_waits_for_tx_room),
        T(test_abort_block_protocol_errors),
        T(test_abort_toggle),
        T(test_abort_unknown_command),
        T(test_abort_timeout),
        T(test_abort_od_errors),
        T(test_client_abort_and_restart),
        T(test_ignored_frames_are_counted),
        T(test_segmented_faults),
        T(test_split_deferral),
        T(test_second_channel_via_1201),
        T(test_channel_changes_its_own_cob_id),
        T(test_channel_reset_on_cob_id_change),
        T(test_refresh_and_deinit),
        T(test_random_frames_never_wedge),
        T(test_mixed_transfers_no_leak),
    };
    return cmocka_run_group_tests_name("sdo", tests, NULL, NULL);
}
