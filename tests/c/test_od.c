/* co_od: object dictionary building, lookup, application access, network
 * transfers (read/write/domains/split), handlers and defaults. */
#include "test_od_util.h"

#define MAX_ENTRIES 12000
#define POOL_SIZE (512u * 1024u)
#define MAX_SUBS 16
#define SCRATCH 256
#define DOMAIN_BYTES (1024u * 1024u)
#define MAX_CALLS 128

enum { CALL_READ = 1, CALL_CHECK, CALL_AFTER };

typedef struct call {
    int what;
    int tag;
    uint32_t key;
    int origin;
    uint32_t length;            /* check_write: the new length */
    uint8_t value[16];          /* check_write: the new value */
    uint8_t stored[16];         /* the entry's value at the time of the call */
    uint32_t stored_length;
} call_t;

struct fx;

typedef struct hctx {
    struct fx *fx;
    int tag;
    uint32_t read_answer;
    uint32_t check_answer;
    /* before_read: put this U32 into the entry first (0 = don't) */
    uint32_t refresh;
} hctx_t;

/* The application side of a domain: a source to upload, a sink to download. */
typedef struct dom {
    uint8_t *src;
    uint32_t src_len;
    bool announce;              /* domain_size tells the size */
    uint32_t read_pos;
    uint8_t *dst;
    uint32_t dst_len;
    uint32_t write_calls;
    int offset_errors;
    int ends;                   /* calls with last = true */
    uint32_t end_abort;
    uint32_t end_offset;
    uint32_t last_total;
    uint32_t refuse_at;         /* writer refuses the chunk at this offset */
} dom_t;

typedef struct fx {
    co_od_t od;
    co_od_entry_t entries[MAX_ENTRIES];
    uint8_t pool[POOL_SIZE];
    co_od_subscription_t subs[MAX_SUBS];
    co_od_xfer_t xfer;
    uint8_t scratch[SCRATCH];
    call_t calls[MAX_CALLS];
    int ncalls;
    hctx_t h[4];
    dom_t dom;
    uint8_t dom_src[DOMAIN_BYTES];
    uint8_t dom_dst[DOMAIN_BYTES];
    uint8_t dom_got[DOMAIN_BYTES];
    /* snapshots for the no-change-on-refusal property */
    uint8_t pool_snap[POOL_SIZE];
    co_od_entry_t entry_snap[64];
    uint32_t order[MAX_ENTRIES];
} fx_t;

static int setup(void **state)
{
    *state = calloc(1, sizeof(fx_t));
    return *state == NULL ? -1 : 0;
}

static int teardown(void **state)
{
    free(*state);
    return 0;
}

static fx_t *fx_new(void **state, co_mode_t mode)
{
    fx_t *fx = *state;
    int i;
    co_od_init(&fx->od, mode, fx->entries, MAX_ENTRIES, fx->pool, POOL_SIZE, fx->subs, MAX_SUBS);
    co_od_xfer_init(&fx->xfer, fx->scratch, SCRATCH);
    for (i = 0; i < 4; i++) {
        fx->h[i].fx = fx;
        fx->h[i].tag = i;
    }
    fx->dom.src = fx->dom_src;
    fx->dom.dst = fx->dom_dst;
    fx->dom.refuse_at = UINT32_MAX;
    return fx;
}

/* ------------------------------------------------------------ bytes */

static void f32_put(uint8_t *p, float f)
{
    uint32_t bits;
    memcpy(&bits, &f, 4);
    tu_le_put(p, bits, 4);
}

static void f64_put(uint8_t *p, double d)
{
    uint64_t bits;
    memcpy(&bits, &d, 8);
    tu_le_put(p, bits, 8);
}

/* Next float away from zero (one unit in the last place). */
static float f32_away(float f)
{
    uint32_t bits;
    memcpy(&bits, &f, 4);
    bits++;
    memcpy(&f, &bits, 4);
    return f;
}

static float f32_toward(float f)
{
    uint32_t bits;
    memcpy(&bits, &f, 4);
    bits--;
    memcpy(&f, &bits, 4);
    return f;
}

static double f64_away(double d)
{
    uint64_t bits;
    memcpy(&bits, &d, 8);
    bits++;
    memcpy(&d, &bits, 8);
    return d;
}

static double f64_toward(double d)
{
    uint64_t bits;
    memcpy(&bits, &d, 8);
    bits--;
    memcpy(&d, &bits, 8);
    return d;
}

/* ------------------------------------------------------------ definitions */

static co_od_def_t var(uint16_t index, uint8_t sub, uint8_t type, uint8_t access,
                       const uint8_t *dflt, uint32_t dlen)
{
    co_od_def_t d = tu_od_def(index, sub, CO_OBJECT_VAR, type, access, 0, co_od_type_size(type));
    d.default_value = dflt;
    d.default_length = dlen;
    return d;
}

static co_od_def_t u32_var(uint16_t index, uint8_t sub, uint8_t access, uint32_t dflt,
                           uint8_t *buf4)
{
    tu_le_put(buf4, dflt, 4);
    return var(index, sub, CO_TYPE_UNSIGNED32, access, buf4, 4);
}

static co_od_def_t string_var(uint16_t index, uint8_t sub, uint8_t type, uint32_t size,
                              const char *dflt)
{
    co_od_def_t d = var(index, sub, type, CO_ACCESS_RW, (const uint8_t *)dflt,
                        dflt ? (uint32_t)strlen(dflt) : 0);
    d.size = size;
    return d;
}

static co_od_def_t domain_var(uint16_t index, uint8_t sub)
{
    co_od_def_t d = var(index, sub, CO_TYPE_DOMAIN, CO_ACCESS_RW, NULL, 0);
    d.object_code = CO_OBJECT_DOMAIN;
    return d;
}

static co_od_def_t with_limits(co_od_def_t d, const uint8_t *min, const uint8_t *max)
{
    if (min) {
        d.flags |= CO_OD_HAS_MIN;
        memcpy(d.min, min, d.size);
    }
    if (max) {
        d.flags |= CO_OD_HAS_MAX;
        memcpy(d.max, max, d.size);
    }
    return d;
}

static void add(fx_t *fx, co_od_def_t d)
{
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ADDED);
}

static void add_u32(fx_t *fx, uint16_t index, uint8_t sub, uint8_t access, uint32_t dflt)
{
    uint8_t b[4];
    add(fx, u32_var(index, sub, access, dflt, b));
}

static void seal(fx_t *fx)
{
    assert_true(co_od_seal(&fx->od, 0));
}

static uint32_t get32(fx_t *fx, uint16_t index, uint8_t sub)
{
    uint32_t v = 0;
    assert_true(co_od_get_u32(&fx->od, index, sub, &v));
    return v;
}

static uint32_t put32(fx_t *fx, uint16_t index, uint8_t sub, uint32_t v)
{
    uint8_t b[4];
    tu_le_put(b, v, 4);
    return co_od_put(&fx->od, index, sub, b, 4);
}

/* ------------------------------------------------------------ network helpers */

/* Download in chunks of `chunk` bytes; total announced or not. The first
 * non-zero answer is returned (CO_OD_SPLIT included). */
static uint32_t net_write_chunked(fx_t *fx, uint16_t index, uint8_t sub, const uint8_t *data,
                                  uint32_t len, bool announce, uint32_t chunk)
{
    uint32_t r, off = 0;
    r = co_od_write_begin(&fx->od, &fx->xfer, index, sub, announce ? len : CO_OD_SIZE_UNKNOWN);
    if (r != 0)
        return r;
    while (off < len) {
        uint32_t n = len - off < chunk ? len - off : chunk;
        r = co_od_write_chunk(&fx->xfer, data + off, n);
        if (r != 0)
            return r;
        off += n;
    }
    return co_od_write_end(&fx->xfer);
}

static uint32_t net_write(fx_t *fx, uint16_t index, uint8_t sub, const uint8_t *data,
                          uint32_t len)
{
    return net_write_chunked(fx, index, sub, data, len, true, 7);
}

static uint32_t net_write32(fx_t *fx, uint16_t index, uint8_t sub, uint32_t v)
{
    uint8_t b[4];
    tu_le_put(b, v, 4);
    return net_write(fx, index, sub, b, 4);
}

/* Upload everything in chunks of `chunk` bytes. */
static uint32_t net_read_chunked(fx_t *fx, uint16_t index, uint8_t sub, uint8_t *out,
                                 uint32_t cap, uint32_t *len, uint32_t chunk)
{
    uint32_t r = co_od_read_begin(&fx->od, &fx->xfer, index, sub);
    bool last = false;
    *len = 0;
    if (r != 0)
        return r;
    while (!last) {
        uint32_t n = 0;
        assert_true(*len + chunk <= cap);
        r = co_od_read_chunk(&fx->xfer, out + *len, chunk, &n, &last);
        if (r != 0)
            return r;
        *len += n;
    }
    assert_int_equal(fx->xfer.state, CO_XFER_DONE);
    return 0;
}

static uint32_t net_read(fx_t *fx, uint16_t index, uint8_t sub, uint8_t *out, uint32_t cap,
                         uint32_t *len)
{
    return net_read_chunked(fx, index, sub, out, cap, len, 7);
}

/* ------------------------------------------------------------ snapshots */

static void snapshot(fx_t *fx)
{
    assert_true(fx->od.count <= 64);
    memcpy(fx->pool_snap, fx->pool, fx->od.pool_used);
    memcpy(fx->entry_snap, fx->entries, fx->od.count * sizeof fx->entries[0]);
}

static void assert_unchanged(const fx_t *fx)
{
    uint32_t i;
    assert_memory_equal(fx->pool_snap, fx->pool, fx->od.pool_used);
    for (i = 0; i < fx->od.count; i++) {
        const co_od_entry_t *a = &fx->entry_snap[i], *b = &fx->entries[i];
        assert_int_equal(a->key, b->key);
        assert_int_equal(a->length, b->length);
        assert_int_equal(a->value, b->value);
        assert_int_equal(a->flags, b->flags);
    }
}

/* ------------------------------------------------------------ logging handler */

static void log_call(fx_t *fx, int what, int tag, const co_od_entry_t *e)
{
    call_t *c;
    assert_true(fx->ncalls < MAX_CALLS);
    c = &fx->calls[fx->ncalls++];
    memset(c, 0, sizeof *c);
    c->what = what;
    c->tag = tag;
    c->key = e->key;
    c->origin = -1;
    c->stored_length = e->length;
    if (e->type != CO_TYPE_DOMAIN)
        memcpy(c->stored, co_od_value(&fx->od, e), e->size < 16 ? e->size : 16);
}

static uint32_t h_before_read(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e,
                              void *user)
{
    hctx_t *h = user;
    assert_ptr_equal(od, &h->fx->od);
    assert_ptr_equal(xfer->entry, e);
    if (h->refresh != 0)
        assert_int_equal(put32(h->fx, co_od_entry_index(e), co_od_entry_sub(e), h->refresh), 0);
    log_call(h->fx, CALL_READ, h->tag, e);
    return h->read_answer;
}

static uint32_t h_check_write(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e,
                              const uint8_t *value, uint32_t length, void *user)
{
    hctx_t *h = user;
    call_t *c;
    assert_ptr_equal(od, &h->fx->od);
    assert_ptr_equal(xfer->entry, e);
    log_call(h->fx, CALL_CHECK, h->tag, e);
    c = &h->fx->calls[h->fx->ncalls - 1];
    c->length = length;
    memcpy(c->value, value, length < 16 ? length : 16);
    return h->check_answer;
}

static void h_after_write(co_od_t *od, const co_od_entry_t *e, co_od_origin_t origin, void *user)
{
    hctx_t *h = user;
    assert_ptr_equal(od, &h->fx->od);
    log_call(h->fx, CALL_AFTER, h->tag, e);
    h->fx->calls[h->fx->ncalls - 1].origin = (int)origin;
}

static const co_od_handler_t logging_handler = {
    .before_read = h_before_read,
    .check_write = h_check_write,
    .after_write = h_after_write,
};

static void subscribe(fx_t *fx, uint16_t first_index, uint8_t first_sub, uint16_t last_index,
                      uint8_t last_sub, int tag)
{
    assert_true(co_od_subscribe(&fx->od, first_index, first_sub, last_index, last_sub,
                                &logging_handler, &fx->h[tag]));
}

static int count_calls(const fx_t *fx, int what)
{
    int i, n = 0;
    for (i = 0; i < fx->ncalls; i++)
        n += fx->calls[i].what == what;
    return n;
}

/* ------------------------------------------------------------ domain application */

static uint32_t d_size(co_od_t *od, const co_od_entry_t *e, uint32_t *size, void *user)
{
    fx_t *fx = user;
    (void)od;
    (void)e;
    *size = fx->dom.announce ? fx->dom.src_len : CO_OD_SIZE_UNKNOWN;
    return 0;
}

static uint32_t d_read(co_od_t *od, const co_od_entry_t *e, uint32_t offset, uint8_t *buf,
                       uint32_t cap, uint32_t *n, bool *last, void *user)
{
    fx_t *fx = user;
    uint32_t left;
    (void)od;
    (void)e;
    if (offset != fx->dom.read_pos)
        fx->dom.offset_errors++;
    left = fx->dom.src_len - offset;
    *n = cap < left ? cap : left;
    memcpy(buf, fx->dom.src + offset, *n);
    fx->dom.read_pos = offset + *n;
    *last = fx->dom.read_pos == fx->dom.src_len;
    return 0;
}

static uint32_t d_write(co_od_t *od, const co_od_entry_t *e, uint32_t offset,
                        const uint8_t *data, uint32_t n, uint32_t total, bool last,
                        uint32_t abort, void *user)
{
    fx_t *fx = user;
    (void)od;
    (void)e;
    fx->dom.write_calls++;
    fx->dom.last_total = total;
    if (offset != fx->dom.dst_len)
        fx->dom.offset_errors++;
    if (last) {
        assert_int_equal(n, 0);
        assert_non_null(data);
        fx->dom.ends++;
        fx->dom.end_abort = abort;
        fx->dom.end_offset = offset;
        return 0;
    }
    assert_int_equal(abort, 0);
    if (offset == fx->dom.refuse_at)
        return CO_ABORT_DATA_LOCAL;
    assert_true(offset + n <= DOMAIN_BYTES);
    memcpy(fx->dom.dst + offset, data, n);
    fx->dom.dst_len = offset + n;
    return 0;
}

static const co_od_handler_t domain_handler = {
    .domain_size = d_size,
    .domain_read = d_read,
    .domain_write = d_write,
};
static const co_od_handler_t domain_read_only_handler = {.domain_read = d_read};

static void fill_domain_source(fx_t *fx, uint32_t len)
{
    uint64_t rng = 0x1234567887654321ull;
    uint32_t i;
    for (i = 0; i < len; i++)
        fx->dom_src[i] = (uint8_t)tu_rand(&rng);
    fx->dom.src_len = len;
}

/* ================================================================ types */

typedef struct type_case {
    uint8_t type;
    uint32_t size;
} type_case_t;

static const type_case_t fixed_types[] = {
    {CO_TYPE_BOOLEAN, 1},        {CO_TYPE_INTEGER8, 1},        {CO_TYPE_INTEGER16, 2},
    {CO_TYPE_INTEGER24, 3},      {CO_TYPE_INTEGER32, 4},       {CO_TYPE_INTEGER40, 5},
    {CO_TYPE_INTEGER48, 6},      {CO_TYPE_INTEGER56, 7},       {CO_TYPE_INTEGER64, 8},
    {CO_TYPE_UNSIGNED8, 1},      {CO_TYPE_UNSIGNED16, 2},      {CO_TYPE_UNSIGNED24, 3},
    {CO_TYPE_UNSIGNED32, 4},     {CO_TYPE_UNSIGNED40, 5},      {CO_TYPE_UNSIGNED48, 6},
    {CO_TYPE_UNSIGNED56, 7},     {CO_TYPE_UNSIGNED64, 8},      {CO_TYPE_REAL32, 4},
    {CO_TYPE_REAL64, 8},         {CO_TYPE_TIME_OF_DAY, 6},     {CO_TYPE_TIME_DIFFERENCE, 6},
};
#define N_FIXED (sizeof fixed_types / sizeof fixed_types[0])

static void test_type_size_of_every_type(void **state)
{
    size_t i;
    (void)state;
    for (i = 0; i < N_FIXED; i++)
        assert_int_equal(co_od_type_size(fixed_types[i].type), fixed_types[i].size);
    assert_int_equal(co_od_type_size(CO_TYPE_VISIBLE_STRING), 0);
    assert_int_equal(co_od_type_size(CO_TYPE_OCTET_STRING), 0);
    assert_int_equal(co_od_type_size(CO_TYPE_UNICODE_STRING), 0);
    assert_int_equal(co_od_type_size(CO_TYPE_DOMAIN), 0);
    assert_int_equal(co_od_type_size(0x00), 0);
    assert_int_equal(co_od_type_size(0x0E), 0);
    assert_int_equal(co_od_type_size(0x17), 0);
    assert_int_equal(co_od_type_size(0x1C), 0);
}

/* Default pattern of fixed type i: distinct bytes (BOOLEAN: 1). */
static void pattern(uint8_t *p, size_t i, uint32_t size, uint8_t salt)
{
    uint32_t k;
    for (k = 0; k < size; k++)
        p[k] = (uint8_t)(salt + 0x10 * i + k);
    if (fixed_types[i].type == CO_TYPE_BOOLEAN)
        p[0] = salt & 1u;
}

static void test_every_fixed_type_default_get_put_exact_bytes(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t dflt[N_FIXED][8], val[8], got[8];
    uint32_t len;
    size_t i;
    for (i = 0; i < N_FIXED; i++) {
        pattern(dflt[i], i, fixed_types[i].size, 1);
        add(fx, var((uint16_t)(0x2000 + i), 0, fixed_types[i].type, CO_ACCESS_RW, dflt[i],
                    fixed_types[i].size));
    }
    seal(fx);
    for (i = 0; i < N_FIXED; i++) {
        uint16_t index = (uint16_t)(0x2000 + i);
        const co_od_entry_t *e = co_od_find(&fx->od, index, 0);
        uint32_t size = fixed_types[i].size;
        assert_non_null(e);
        assert_int_equal(e->size, size);
        assert_int_equal(e->length, size);
        /* the default, as stored little-endian bytes */
        memset(got, 0xEE, sizeof got);
        assert_int_equal(co_od_get(&fx->od, index, 0, got, sizeof got, &len), 0);
        assert_int_equal(len, size);
        assert_memory_equal(got, dflt[i], size);
        assert_memory_equal(co_od_value(&fx->od, e), dflt[i], size);
        /* a new value, byte for byte */
        pattern(val, i, size, 0x81);
        assert_int_equal(co_od_put(&fx->od, index, 0, val, size), 0);
        assert_int_equal(co_od_get(&fx->od, index, 0, got, sizeof got, &len), 0);
        assert_int_equal(len, size);
        assert_memory_equal(got, val, size);
        assert_memory_equal(co_od_value(&fx->od, e), val, size);
    }
}

static void test_every_fixed_type_network_write_and_read_exact_bytes(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC);
    uint8_t val[8], got[64];
    uint32_t len;
    size_t i;
    for (i = 0; i < N_FIXED; i++)
        add(fx, var((uint16_t)(0x3000 + i), 0, fixed_types[i].type, CO_ACCESS_RW, NULL, 0));
    seal(fx);
    for (i = 0; i < N_FIXED; i++) {
        uint16_t index = (uint16_t)(0x3000 + i);
        uint32_t size = fixed_types[i].size;
        pattern(val, i, size, 0x43);
        assert_int_equal(net_write(fx, index, 0, val, size), 0);
        assert_int_equal(net_read(fx, index, 0, got, sizeof got, &len), 0);
        assert_int_equal(len, size);
        assert_memory_equal(got, val, size);
    }
}

static void test_typed_getters_check_the_size(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t b1[1] = {0xA5}, b2[2] = {0x34, 0x12}, b4[4] = {0x78, 0x56, 0x34, 0x12};
    uint8_t u8 = 0;
    uint16_t u16 = 0;
    uint32_t u32 = 0;
    add(fx, var(0x2000, 0, CO_TYPE_UNSIGNED8, CO_ACCESS_RW, b1, 1));
    add(fx, var(0x2001, 0, CO_TYPE_UNSIGNED16, CO_ACCESS_RW, b2, 2));
    add(fx, var(0x2002, 0, CO_TYPE_UNSIGNED32, CO_ACCESS_RW, b4, 4));
    add(fx, var(0x2003, 0, CO_TYPE_INTEGER32, CO_ACCESS_RW, b4, 4));
    seal(fx);
    assert_true(co_od_get_u8(&fx->od, 0x2000, 0, &u8));
    assert_int_equal(u8, 0xA5);
    assert_true(co_od_get_u16(&fx->od, 0x2001, 0, &u16));
    assert_int_equal(u16, 0x1234);
    assert_true(co_od_get_u32(&fx->od, 0x2002, 0, &u32));
    assert_int_equal(u32, 0x12345678);
    assert_true(co_od_get_u32(&fx->od, 0x2003, 0, &u32));   /* raw bits of any 4-byte type */
    assert_false(co_od_get_u8(&fx->od, 0x2001, 0, &u8));
    assert_false(co_od_get_u16(&fx->od, 0x2002, 0, &u16));
    assert_false(co_od_get_u32(&fx->od, 0x2000, 0, &u32));
    assert_false(co_od_get_u32(&fx->od, 0x2004, 0, &u32));
}

/* ================================================================ add */

static void test_add_refuses_fixed_type_with_wrong_size(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    size_t i;
    for (i = 0; i < N_FIXED; i++) {
        co_od_def_t d = var(0x2000, 0, fixed_types[i].type, CO_ACCESS_RW, NULL, 0);
        d.size = fixed_types[i].size + 1;
        assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_TYPE);
        d.size = fixed_types[i].size - 1;
        assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_TYPE);
    }
    assert_int_equal(fx->od.count, 0);
}

static void test_add_refuses_unknown_types(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    static const uint8_t unknown[] = {0x00, 0x0E, 0x17, 0x1C, 0x20, 0x23, 0xFF};
    size_t i;
    for (i = 0; i < sizeof unknown; i++) {
        co_od_def_t d = var(0x2000, 0, unknown[i], CO_ACCESS_RW, NULL, 0);
        d.size = 4;
        assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_TYPE);
    }
}

static void test_add_checks_string_and_domain_sizes(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    co_od_def_t d = string_var(0x2000, 0, CO_TYPE_UNICODE_STRING, 7, NULL);
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_TYPE);     /* odd unicode size */
    d.size = 8;
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ADDED);
    d = string_var(0x2001, 0, CO_TYPE_VISIBLE_STRING, 0, NULL);   /* size 0 is a string too */
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ADDED);
    d = string_var(0x2002, 0, CO_TYPE_OCTET_STRING, 3, NULL);
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ADDED);
    d = domain_var(0x2003, 0);
    d.size = 4;
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_TYPE);     /* domain with storage */
    d.size = 0;
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ADDED);
}

static void test_add_refuses_unknown_access_and_flags(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    co_od_def_t d = var(0x2000, 0, CO_TYPE_UNSIGNED8, 0, NULL, 0);
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_TYPE);
    d.access = 7;
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_TYPE);
    d.access = CO_ACCESS_RW;
    d.flags = 0x0100;
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_TYPE);
    d.flags = 0x8000;
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_TYPE);
    d.flags = CO_OD_MAP_TPDO | CO_OD_MAP_RPDO | CO_OD_STORE;
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ADDED);
}

static void test_add_refuses_numeric_default_of_wrong_length(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t b[8] = {1, 2, 3, 4, 5, 6, 7, 8};
    co_od_def_t d = var(0x2000, 0, CO_TYPE_UNSIGNED32, CO_ACCESS_RW, b, 3);
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_DEFAULT);
    d.default_length = 5;
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_DEFAULT);
    d.default_length = 4;
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ADDED);
}

static void test_add_numeric_without_default_defaults_to_zero(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    add(fx, var(0x2000, 0, CO_TYPE_UNSIGNED32, CO_ACCESS_RW, NULL, 0));
    seal(fx);
    assert_int_equal(get32(fx, 0x2000, 0), 0);
    assert_int_equal(co_od_find(&fx->od, 0x2000, 0)->length, 4);
}

static void test_add_refuses_default_length_without_pointer(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    co_od_def_t d = var(0x2000, 0, CO_TYPE_UNSIGNED32, CO_ACCESS_RW, NULL, 4);
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_DEFAULT);
}

static void test_add_refuses_string_default_longer_than_size(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    co_od_def_t d = string_var(0x2000, 0, CO_TYPE_VISIBLE_STRING, 4, "hello");
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_DEFAULT);
    d.size = 5;
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ADDED);
    d = string_var(0x2001, 0, CO_TYPE_UNICODE_STRING, 8, "abc");   /* odd unicode default */
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_DEFAULT);
    d = domain_var(0x2002, 0);
    d.default_value = (const uint8_t *)"x";
    d.default_length = 1;
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_DEFAULT);
}

static void test_add_refuses_limits_on_strings_and_domains(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    co_od_def_t d = string_var(0x2000, 0, CO_TYPE_VISIBLE_STRING, 8, NULL);
    d.flags = CO_OD_HAS_MIN;
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_LIMITS);
    d = domain_var(0x2001, 0);
    d.flags = CO_OD_HAS_MAX;
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_LIMITS);
}

static void test_add_refuses_min_above_max_in_the_types_signedness(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t lo[8], hi[8];
    co_od_def_t d;
    /* I16 min -1 (0xFFFF) max 1: fine as signed, would be wrong as unsigned */
    tu_le_put(lo, 0xFFFF, 2);
    tu_le_put(hi, 1, 2);
    d = with_limits(var(0x2000, 0, CO_TYPE_INTEGER16, CO_ACCESS_RW, NULL, 0), lo, hi);
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ADDED);
    /* U16 min 0xFFFF max 1: min > max */
    d = with_limits(var(0x2001, 0, CO_TYPE_UNSIGNED16, CO_ACCESS_RW, NULL, 0), lo, hi);
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_LIMITS);
    /* I16 min 1 max -1 */
    d = with_limits(var(0x2002, 0, CO_TYPE_INTEGER16, CO_ACCESS_RW, NULL, 0), hi, lo);
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_LIMITS);
    /* REAL32 min 2.0 max -3.0 */
    f32_put(lo, 2.0f);
    f32_put(hi, -3.0f);
    d = with_limits(var(0x2003, 0, CO_TYPE_REAL32, CO_ACCESS_RW, NULL, 0), lo, hi);
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_LIMITS);
    /* min == max is fine */
    d = with_limits(var(0x2004, 0, CO_TYPE_REAL32, CO_ACCESS_RW, NULL, 0), hi, hi);
    d.default_value = hi;
    d.default_length = 4;
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ADDED);
}

static void test_add_refuses_nan_limits(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t nan32[4] = {0x00, 0x00, 0xC0, 0x7F}, one[8];
    uint8_t nan64[8] = {0, 0, 0, 0, 0, 0, 0xF8, 0x7F};
    co_od_def_t d;
    f32_put(one, 1.0f);
    d = with_limits(var(0x2000, 0, CO_TYPE_REAL32, CO_ACCESS_RW, NULL, 0), nan32, NULL);
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_LIMITS);
    d = with_limits(var(0x2000, 0, CO_TYPE_REAL32, CO_ACCESS_RW, NULL, 0), NULL, nan32);
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_LIMITS);
    d = with_limits(var(0x2000, 0, CO_TYPE_REAL64, CO_ACCESS_RW, NULL, 0), nan64, NULL);
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_LIMITS);
}

static void test_add_refuses_default_outside_limits(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t lo[8], hi[8], dv[8];
    co_od_def_t d;
    tu_le_put(lo, 10, 1);
    tu_le_put(hi, 20, 1);
    tu_le_put(dv, 21, 1);
    d = with_limits(var(0x2000, 0, CO_TYPE_UNSIGNED8, CO_ACCESS_RW, dv, 1), lo, hi);
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_DEFAULT);
    tu_le_put(dv, 9, 1);
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_DEFAULT);
    /* no default = 0, also below the minimum */
    d.default_value = NULL;
    d.default_length = 0;
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_DEFAULT);
    tu_le_put(dv, 10, 1);
    d.default_value = dv;
    d.default_length = 1;
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ADDED);
}

static void test_add_refuses_boolean_default_other_than_0_1(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t two = 2;
    co_od_def_t d = var(0x2000, 0, CO_TYPE_BOOLEAN, CO_ACCESS_RW, &two, 1);
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_DEFAULT);
}

static void test_add_refuses_nodeid_relative_on_non_integers(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    co_od_def_t d = var(0x2000, 0, CO_TYPE_REAL32, CO_ACCESS_RW, NULL, 0);
    d.flags = CO_OD_NODEID_RELATIVE;
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_TYPE);
    d = string_var(0x2000, 0, CO_TYPE_VISIBLE_STRING, 4, NULL);
    d.flags = CO_OD_NODEID_RELATIVE;
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_TYPE);
    d = var(0x2000, 0, CO_TYPE_BOOLEAN, CO_ACCESS_RW, NULL, 0);
    d.flags = CO_OD_NODEID_RELATIVE;
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_TYPE);
}

static void test_add_refuses_duplicates(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t b[4];
    co_od_def_t d = u32_var(0x2000, 1, CO_ACCESS_RW, 5, b);
    add(fx, d);
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_DUPLICATE);
    d.type = CO_TYPE_UNSIGNED8;
    d.size = 1;
    d.default_length = 1;
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_DUPLICATE);
    assert_int_equal(fx->od.count, 1);
}

static void test_add_reports_full_entry_table(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    co_od_def_t d = var(0x2000, 0, CO_TYPE_UNSIGNED8, CO_ACCESS_RW, NULL, 0);
    co_od_init(&fx->od, CO_MODE_FD, fx->entries, 2, fx->pool, POOL_SIZE, NULL, 0);
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ADDED);
    d.index = 0x2001;
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ADDED);
    d.index = 0x2002;
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_FULL);
    assert_int_equal(fx->od.count, 2);
}

static void test_pool_need_counts_value_default_and_limits(void **state)
{
    uint8_t b[8] = {0};
    co_od_def_t d = var(0x2000, 0, CO_TYPE_UNSIGNED32, CO_ACCESS_RW, NULL, 0);
    (void)state;
    assert_int_equal(co_od_pool_need(&d), 4);
    d.default_value = b;
    d.default_length = 4;
    assert_int_equal(co_od_pool_need(&d), 8);
    d.flags = CO_OD_HAS_MIN;
    assert_int_equal(co_od_pool_need(&d), 16);
    d.flags = CO_OD_HAS_MIN | CO_OD_HAS_MAX;
    assert_int_equal(co_od_pool_need(&d), 16);
    d = string_var(0x2001, 0, CO_TYPE_VISIBLE_STRING, 20, "abc");
    assert_int_equal(co_od_pool_need(&d), 23);
    d = domain_var(0x2002, 0);
    assert_int_equal(co_od_pool_need(&d), 0);
}

static void test_add_reports_full_pool_at_the_exact_byte(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t b[4];
    co_od_def_t d = u32_var(0x2000, 0, CO_ACCESS_RW, 1, b);   /* needs 8 */
    co_od_init(&fx->od, CO_MODE_FD, fx->entries, 16, fx->pool, 15, NULL, 0);
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ADDED);
    d.index = 0x2001;
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_FULL);   /* 7 left */
    co_od_init(&fx->od, CO_MODE_FD, fx->entries, 16, fx->pool, 16, NULL, 0);
    d.index = 0x2000;
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ADDED);
    d.index = 0x2001;
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ADDED);     /* exactly full */
    assert_int_equal(fx->od.pool_used, 16);
    d = domain_var(0x2002, 0);                                 /* needs no pool */
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ADDED);
}

static void test_add_after_seal_is_refused(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t b[4];
    co_od_def_t d = u32_var(0x2000, 0, CO_ACCESS_RW, 1, b);
    seal(fx);
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ERR_SEALED);
}

static void test_mode_filter_on_classic_od(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC);
    uint8_t b[4];
    co_od_def_t d = u32_var(0x2000, 0, CO_ACCESS_RW, 1, b);
    d.flags = CO_OD_FD_ONLY;
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_SKIPPED_MODE);
    d.index = 0x2001;
    d.flags = CO_OD_CLASSIC_ONLY;
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ADDED);
    seal(fx);
    assert_null(co_od_find(&fx->od, 0x2000, 0));
    assert_non_null(co_od_find(&fx->od, 0x2001, 0));
    assert_int_equal(fx->od.count, 1);
    assert_int_equal(fx->od.pool_used, 8);
}

static void test_mode_filter_on_fd_od(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t b[4];
    co_od_def_t d = u32_var(0x2000, 0, CO_ACCESS_RW, 1, b);
    d.flags = CO_OD_FD_ONLY;
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ADDED);
    d.index = 0x2001;
    d.flags = CO_OD_CLASSIC_ONLY;
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_SKIPPED_MODE);
    seal(fx);
    assert_non_null(co_od_find(&fx->od, 0x2000, 0));
    assert_null(co_od_find(&fx->od, 0x2001, 0));
}

/* ================================================================ seal */

static void add_record(fx_t *fx, uint16_t index, uint8_t sub0_value, const uint8_t *subs,
                       size_t nsubs, bool with_sub0)
{
    uint8_t b[4];
    size_t i;
    co_od_def_t d;
    if (with_sub0) {
        d = var(index, 0, CO_TYPE_UNSIGNED8, CO_ACCESS_RO, &sub0_value, 1);
        d.object_code = CO_OBJECT_RECORD;
        add(fx, d);
    }
    for (i = 0; i < nsubs; i++) {
        d = u32_var(index, subs[i], CO_ACCESS_RW, subs[i], b);
        d.object_code = CO_OBJECT_RECORD;
        add(fx, d);
    }
}

static void test_seal_refuses_record_without_sub0(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    static const uint8_t subs[] = {1, 2};
    add_record(fx, 0x2000, 2, subs, 2, false);
    assert_false(co_od_seal(&fx->od, 1));
    assert_false(fx->od.sealed);
    assert_int_equal(fx->od.refused_index, 0x2000);
}

static void test_seal_accepts_sub0_below_highest_sub(void **state)
{
    /* sub 0 counts what is in use (0x1003 errors logged, PDO entries
     * mapped): it may be below the highest sub-index that exists */
    fx_t *fx = fx_new(state, CO_MODE_FD);
    static const uint8_t subs[] = {1, 2, 4};
    add_record(fx, 0x2000, 0, subs, 3, true);
    assert_true(co_od_seal(&fx->od, 1));
}

static void test_seal_refuses_sub0_not_unsigned8(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t b[4];
    co_od_def_t d = u32_var(0x2000, 0, CO_ACCESS_RO, 1, b);
    d.object_code = CO_OBJECT_ARRAY;
    add(fx, d);
    d = u32_var(0x2000, 1, CO_ACCESS_RW, 1, b);
    d.object_code = CO_OBJECT_ARRAY;
    add(fx, d);
    assert_false(co_od_seal(&fx->od, 1));
}

static void test_seal_accepts_records_with_gaps_and_vars(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    static const uint8_t subs[] = {1, 3, 5};
    add_record(fx, 0x2000, 5, subs, 3, true);
    add_record(fx, 0x2001, 0, NULL, 0, true);    /* empty array: sub 0 = 0 */
    add_u32(fx, 0x2002, 0, CO_ACCESS_RW, 1);     /* VAR */
    assert_true(co_od_seal(&fx->od, 1));
    assert_true(fx->od.sealed);
    assert_int_equal(get32(fx, 0x2000, 3), 3);
}

static void test_seal_twice_is_refused(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    add_u32(fx, 0x2000, 0, CO_ACCESS_RW, 1);
    assert_true(co_od_seal(&fx->od, 1));
    assert_false(co_od_seal(&fx->od, 2));
    assert_int_equal(fx->od.node_id, 1);
}

static void test_seal_checks_sub0_of_record_defined_by_var_subs(void **state)
{
    /* EDS files give sub-entries of records the object code VAR: one entry
     * saying RECORD makes the index a record */
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t b[4];
    add(fx, u32_var(0x2000, 1, CO_ACCESS_RW, 0, b));
    co_od_def_t d = u32_var(0x2000, 3, CO_ACCESS_RW, 0, b);
    d.object_code = CO_OBJECT_RECORD;
    add(fx, d);
    assert_false(co_od_seal(&fx->od, 1));   /* a record, and it has no sub 0 */
    assert_int_equal(fx->od.refused_index, 0x2000);
}

static void test_nodeid_relative_defaults_add_the_node_id(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t b1[4], b2[4], b3[2], b4[1];
    co_od_def_t d;
    d = u32_var(0x1400, 1, CO_ACCESS_RW, 0x200, b1);
    d.flags = CO_OD_NODEID_RELATIVE;
    add(fx, d);
    d = u32_var(0x1800, 1, CO_ACCESS_RW, 0xC0000180u, b2);
    d.flags = CO_OD_NODEID_RELATIVE;
    add(fx, d);
    tu_le_put(b3, 0x00FF, 2);      /* carry into the high byte */
    d = var(0x2000, 0, CO_TYPE_UNSIGNED16, CO_ACCESS_RW, b3, 2);
    d.flags = CO_OD_NODEID_RELATIVE;
    add(fx, d);
    d = var(0x2001, 0, CO_TYPE_UNSIGNED8, CO_ACCESS_RW, NULL, 0);   /* no default: node-id */
    d.flags = CO_OD_NODEID_RELATIVE;
    add(fx, d);
    b4[0] = 0x40;
    d = var(0x2002, 0, CO_TYPE_UNSIGNED8, CO_ACCESS_RW, b4, 1);     /* absolute */
    add(fx, d);
    assert_true(co_od_seal(&fx->od, 0x7F));
    assert_int_equal(get32(fx, 0x1400, 1), 0x27F);
    assert_int_equal(get32(fx, 0x1800, 1), 0xC00001FFu);
    {
        uint16_t v;
        uint8_t u;
        assert_true(co_od_get_u16(&fx->od, 0x2000, 0, &v));
        assert_int_equal(v, 0x017E);
        assert_true(co_od_get_u8(&fx->od, 0x2001, 0, &u));
        assert_int_equal(u, 0x7F);
        assert_true(co_od_get_u8(&fx->od, 0x2002, 0, &u));
        assert_int_equal(u, 0x40);
    }
    /* a new node-id (LSS) takes effect at the next load of defaults */
    fx->od.node_id = 5;
    co_od_load_defaults(&fx->od, CO_GROUP_ALL);
    assert_int_equal(get32(fx, 0x1400, 1), 0x205);
    assert_int_equal(get32(fx, 0x1800, 1), 0xC0000185u);
}

static void test_access_before_seal_reports_no_od(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t buf[4];
    uint32_t len;
    uint32_t v;
    add_u32(fx, 0x2000, 0, CO_ACCESS_RW, 7);
    assert_non_null(co_od_find(&fx->od, 0x2000, 0));    /* lookups work */
    assert_int_equal(co_od_get(&fx->od, 0x2000, 0, buf, 4, &len), CO_ABORT_NO_OD);
    assert_int_equal(put32(fx, 0x2000, 0, 1), CO_ABORT_NO_OD);
    assert_false(co_od_get_u32(&fx->od, 0x2000, 0, &v));
    assert_int_equal(co_od_read_begin(&fx->od, &fx->xfer, 0x2000, 0), CO_ABORT_NO_OD);
    assert_int_equal(co_od_write_begin(&fx->od, &fx->xfer, 0x2000, 0, 4), CO_ABORT_NO_OD);
}

/* ================================================================ lookup */

static void test_binary_search_on_10000_entries_added_in_random_order(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint64_t rng = 42;
    uint32_t i, n = 10000;
    /* keys: indices 0x2000.. with subs 0..3, every other index left out */
    for (i = 0; i < n; i++)
        fx->order[i] = i;
    for (i = n - 1; i > 0; i--) {
        uint32_t j = (uint32_t)(tu_rand(&rng) % (i + 1)), t = fx->order[i];
        fx->order[i] = fx->order[j];
        fx->order[j] = t;
    }
    for (i = 0; i < n; i++) {
        uint32_t k = fx->order[i];
        add_u32(fx, (uint16_t)(0x2000 + 2 * (k / 4)), (uint8_t)(k % 4), CO_ACCESS_RW, k);
    }
    assert_int_equal(fx->od.count, n);
    for (i = 1; i < n; i++)
        assert_true(fx->entries[i - 1].key < fx->entries[i].key);
    seal(fx);
    for (i = 0; i < n; i++) {
        uint16_t index = (uint16_t)(0x2000 + 2 * (i / 4));
        const co_od_entry_t *e = co_od_find(&fx->od, index, (uint8_t)(i % 4));
        assert_non_null(e);
        assert_int_equal(e->key, (uint32_t)index << 8 | (i % 4));
        assert_int_equal(get32(fx, index, (uint8_t)(i % 4)), i);
        assert_true(co_od_has_index(&fx->od, index));
        /* misses: the sub after the last, the index in between, around the ends */
        assert_null(co_od_find(&fx->od, index, 4));
        assert_null(co_od_find(&fx->od, (uint16_t)(index + 1), (uint8_t)(i % 4)));
        assert_false(co_od_has_index(&fx->od, (uint16_t)(index + 1)));
    }
    assert_null(co_od_find(&fx->od, 0x1FFF, 0xFF));
    assert_null(co_od_find(&fx->od, 0x0000, 0));
    assert_null(co_od_find(&fx->od, 0xFFFF, 0xFF));
    assert_false(co_od_has_index(&fx->od, 0x1FFF));
    assert_false(co_od_has_index(&fx->od, 0xFFFF));
}

static void test_find_on_empty_od(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    assert_null(co_od_find(&fx->od, 0x1000, 0));
    assert_false(co_od_has_index(&fx->od, 0x1000));
    seal(fx);
    assert_null(co_od_find(&fx->od, 0x1000, 0));
}

/* ================================================================ get / put */

static void test_get_reports_buffer_too_small(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t buf[8];
    uint32_t len = 0;
    add_u32(fx, 0x2000, 0, CO_ACCESS_RW, 0x11223344);
    seal(fx);
    assert_int_equal(co_od_get(&fx->od, 0x2000, 0, buf, 3, &len), CO_ABORT_OUT_OF_MEMORY);
    assert_int_equal(len, 4);
    assert_int_equal(co_od_get(&fx->od, 0x2000, 0, buf, 4, NULL), 0);
    assert_int_equal(tu_le_get(buf, 4), 0x11223344);
}

static void test_get_put_report_missing_object_and_sub(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t buf[8];
    uint32_t len;
    add_u32(fx, 0x2000, 1, CO_ACCESS_RW, 0);
    seal(fx);
    assert_int_equal(co_od_get(&fx->od, 0x2001, 1, buf, 8, &len), CO_ABORT_NO_OBJECT);
    assert_int_equal(co_od_get(&fx->od, 0x2000, 2, buf, 8, &len), CO_ABORT_NO_SUB);
    assert_int_equal(put32(fx, 0x2001, 1, 0), CO_ABORT_NO_OBJECT);
    assert_int_equal(put32(fx, 0x2000, 0, 0), CO_ABORT_NO_SUB);
}

static void test_put_checks_length(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t b[8] = {1, 2, 3, 4, 5, 6, 7, 8};
    add_u32(fx, 0x2000, 0, CO_ACCESS_RW, 9);
    seal(fx);
    snapshot(fx);
    assert_int_equal(co_od_put(&fx->od, 0x2000, 0, b, 5), CO_ABORT_LENGTH_HIGH);
    assert_int_equal(co_od_put(&fx->od, 0x2000, 0, b, 3), CO_ABORT_LENGTH_LOW);
    assert_int_equal(co_od_put(&fx->od, 0x2000, 0, b, 0), CO_ABORT_LENGTH_LOW);
    assert_unchanged(fx);
}

static void test_put_checks_limits(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t lo = 10, hi = 20, v;
    add(fx, with_limits(var(0x2000, 0, CO_TYPE_UNSIGNED8, CO_ACCESS_RW, &lo, 1), &lo, &hi));
    seal(fx);
    v = 21;
    assert_int_equal(co_od_put(&fx->od, 0x2000, 0, &v, 1), CO_ABORT_VALUE_HIGH);
    v = 9;
    assert_int_equal(co_od_put(&fx->od, 0x2000, 0, &v, 1), CO_ABORT_VALUE_LOW);
    v = 20;
    assert_int_equal(co_od_put(&fx->od, 0x2000, 0, &v, 1), 0);
}

static void test_put_notifies_after_write_local_without_check(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    add_u32(fx, 0x2000, 0, CO_ACCESS_RW, 0);
    seal(fx);
    subscribe(fx, 0x2000, 0, 0x2000, 0, 0);
    fx->h[0].check_answer = CO_ABORT_GENERAL;   /* not asked for application writes */
    assert_int_equal(put32(fx, 0x2000, 0, 0xCAFE), 0);
    assert_int_equal(fx->ncalls, 1);
    assert_int_equal(fx->calls[0].what, CALL_AFTER);
    assert_int_equal(fx->calls[0].origin, CO_ORIGIN_LOCAL);
    assert_int_equal(tu_le_get(fx->calls[0].stored, 4), 0xCAFE);
}

static void test_put_may_write_read_only_and_const_entries(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    add_u32(fx, 0x2000, 0, CO_ACCESS_RO, 0);
    add_u32(fx, 0x2001, 0, CO_ACCESS_CONST, 0);
    seal(fx);
    assert_int_equal(put32(fx, 0x2000, 0, 5), 0);
    assert_int_equal(put32(fx, 0x2001, 0, 6), 0);
    assert_int_equal(get32(fx, 0x2000, 0), 5);
    assert_int_equal(get32(fx, 0x2001, 0), 6);
}

static void test_get_put_on_domain_unsupported(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t b[4] = {0};
    uint32_t len;
    add(fx, domain_var(0x2000, 0));
    seal(fx);
    assert_int_equal(co_od_put(&fx->od, 0x2000, 0, b, 4), CO_ABORT_UNSUPPORTED_ACCESS);
    assert_int_equal(co_od_get(&fx->od, 0x2000, 0, b, 4, &len), CO_ABORT_UNSUPPORTED_ACCESS);
}

/* ================================================================ strings */

static void test_string_put_shorter_sets_length_and_zero_fills(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t buf[16];
    uint32_t len;
    const co_od_entry_t *e;
    add(fx, string_var(0x2000, 0, CO_TYPE_VISIBLE_STRING, 10, "abcdefgh"));
    seal(fx);
    e = co_od_find(&fx->od, 0x2000, 0);
    assert_int_equal(e->length, 8);
    assert_int_equal(co_od_put(&fx->od, 0x2000, 0, (const uint8_t *)"xyz", 3), 0);
    assert_int_equal(e->length, 3);
    assert_memory_equal(co_od_value(&fx->od, e), "xyz\0\0\0\0\0\0\0", 10);
    assert_int_equal(co_od_get(&fx->od, 0x2000, 0, buf, sizeof buf, &len), 0);
    assert_int_equal(len, 3);
    assert_memory_equal(buf, "xyz", 3);
}

static void test_string_write_of_max_length(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t buf[16];
    uint32_t len;
    add(fx, string_var(0x2000, 0, CO_TYPE_VISIBLE_STRING, 10, "ab"));
    seal(fx);
    assert_int_equal(net_write(fx, 0x2000, 0, (const uint8_t *)"0123456789", 10), 0);
    assert_int_equal(net_read(fx, 0x2000, 0, buf, sizeof buf, &len), 0);
    assert_int_equal(len, 10);
    assert_memory_equal(buf, "0123456789", 10);
}

static void test_string_write_longer_than_size_refused(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    add(fx, string_var(0x2000, 0, CO_TYPE_VISIBLE_STRING, 10, "ab"));
    seal(fx);
    snapshot(fx);
    /* announced: refused at begin */
    assert_int_equal(co_od_write_begin(&fx->od, &fx->xfer, 0x2000, 0, 11),
                     CO_ABORT_LENGTH_HIGH);
    /* not announced: refused at the chunk that goes beyond */
    assert_int_equal(net_write_chunked(fx, 0x2000, 0, (const uint8_t *)"0123456789A", 11, false,
                                       4),
                     CO_ABORT_LENGTH_HIGH);
    assert_int_equal(fx->xfer.abort, CO_ABORT_LENGTH_HIGH);
    assert_int_equal(fx->xfer.state, CO_XFER_DONE);
    assert_unchanged(fx);
}

static void test_string_write_shorter_keeps_new_length(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t buf[16];
    uint32_t len;
    const co_od_entry_t *e;
    add(fx, string_var(0x2000, 0, CO_TYPE_OCTET_STRING, 10, "abcdefghij"));
    seal(fx);
    e = co_od_find(&fx->od, 0x2000, 0);
    assert_int_equal(net_write_chunked(fx, 0x2000, 0, (const uint8_t *)"\x01\x00\x02", 3, false,
                                       2),
                     0);
    assert_int_equal(e->length, 3);
    assert_memory_equal(co_od_value(&fx->od, e), "\x01\x00\x02\0\0\0\0\0\0\0", 10);
    assert_int_equal(net_read(fx, 0x2000, 0, buf, sizeof buf, &len), 0);
    assert_int_equal(len, 3);
    assert_memory_equal(buf, "\x01\x00\x02", 3);
}

static void test_string_write_empty(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t buf[16];
    uint32_t len = 99;
    bool last = false;
    add(fx, string_var(0x2000, 0, CO_TYPE_VISIBLE_STRING, 10, "abc"));
    seal(fx);
    assert_int_equal(net_write(fx, 0x2000, 0, NULL, 0), 0);
    assert_int_equal(co_od_find(&fx->od, 0x2000, 0)->length, 0);
    assert_int_equal(co_od_read_begin(&fx->od, &fx->xfer, 0x2000, 0), 0);
    assert_int_equal(fx->xfer.total, 0);
    assert_int_equal(co_od_read_chunk(&fx->xfer, buf, sizeof buf, &len, &last), 0);
    assert_int_equal(len, 0);
    assert_true(last);
}

static void test_visible_string_read_total_is_current_length(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    add(fx, string_var(0x2000, 0, CO_TYPE_VISIBLE_STRING, 32, "device"));
    seal(fx);
    assert_int_equal(co_od_read_begin(&fx->od, &fx->xfer, 0x2000, 0), 0);
    assert_int_equal(fx->xfer.total, 6);
}

static void test_unicode_string_of_odd_length_refused(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    co_od_def_t d = var(0x2000, 0, CO_TYPE_UNICODE_STRING, CO_ACCESS_RW,
                        (const uint8_t *)"a\0b\0", 4);
    d.size = 8;
    add(fx, d);
    seal(fx);
    assert_int_equal(co_od_find(&fx->od, 0x2000, 0)->length, 4);
    snapshot(fx);
    assert_int_equal(net_write(fx, 0x2000, 0, (const uint8_t *)"a\0b", 3),
                     CO_ABORT_TYPE_MISMATCH);
    assert_unchanged(fx);
    assert_int_equal(net_write(fx, 0x2000, 0, (const uint8_t *)"x\0y\0z\0", 6), 0);
    assert_int_equal(co_od_find(&fx->od, 0x2000, 0)->length, 6);
}

/* ================================================================ limits */

/* Network-write value v (n bytes) and expect `abort`; on refusal the OD is
 * unchanged, on success the value is stored. */
static void expect_write(fx_t *fx, uint16_t index, const uint8_t *v, uint32_t n, uint32_t abort)
{
    const co_od_entry_t *e = co_od_find(&fx->od, index, 0);
    snapshot(fx);
    assert_int_equal(net_write(fx, index, 0, v, n), abort);
    if (abort != 0) {
        assert_unchanged(fx);
    } else {
        assert_memory_equal(co_od_value(&fx->od, e), v, n);
    }
    /* the application check says the same */
    assert_int_equal(co_od_check_value(&fx->od, e, v, n), abort);
}

static void expect_int(fx_t *fx, uint16_t index, uint32_t size, int64_t value, uint32_t abort)
{
    uint8_t b[8];
    tu_le_put(b, (uint64_t)value, size);
    expect_write(fx, index, b, size, abort);
}

static void add_int_limited(fx_t *fx, uint16_t index, uint8_t type, int64_t min, int64_t max)
{
    uint8_t lo[8], hi[8];
    uint32_t size = co_od_type_size(type);
    tu_le_put(lo, (uint64_t)min, size);
    tu_le_put(hi, (uint64_t)max, size);
    add(fx, with_limits(var(index, 0, type, CO_ACCESS_RW, lo, size), lo, hi));
}

static void test_limits_unsigned8(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    add_int_limited(fx, 0x2000, CO_TYPE_UNSIGNED8, 10, 200);
    seal(fx);
    expect_int(fx, 0x2000, 1, 9, CO_ABORT_VALUE_LOW);
    expect_int(fx, 0x2000, 1, 10, 0);
    expect_int(fx, 0x2000, 1, 11, 0);
    expect_int(fx, 0x2000, 1, 199, 0);
    expect_int(fx, 0x2000, 1, 200, 0);
    expect_int(fx, 0x2000, 1, 201, CO_ABORT_VALUE_HIGH);
    expect_int(fx, 0x2000, 1, 255, CO_ABORT_VALUE_HIGH);
    expect_int(fx, 0x2000, 1, 0, CO_ABORT_VALUE_LOW);
}

static void test_limits_integer16_compare_signed(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    add_int_limited(fx, 0x2000, CO_TYPE_INTEGER16, -300, 300);
    seal(fx);
    expect_int(fx, 0x2000, 2, -301, CO_ABORT_VALUE_LOW);
    expect_int(fx, 0x2000, 2, -300, 0);
    expect_int(fx, 0x2000, 2, -299, 0);
    expect_int(fx, 0x2000, 2, 0, 0);
    expect_int(fx, 0x2000, 2, 299, 0);
    expect_int(fx, 0x2000, 2, 300, 0);
    expect_int(fx, 0x2000, 2, 301, CO_ABORT_VALUE_HIGH);
    expect_int(fx, 0x2000, 2, -32768, CO_ABORT_VALUE_LOW);
    expect_int(fx, 0x2000, 2, 32767, CO_ABORT_VALUE_HIGH);
}

static void test_limits_integer24_sign_extended(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    add_int_limited(fx, 0x2000, CO_TYPE_INTEGER24, -1000, 1000);
    seal(fx);
    expect_int(fx, 0x2000, 3, -1001, CO_ABORT_VALUE_LOW);
    expect_int(fx, 0x2000, 3, -1000, 0);
    expect_int(fx, 0x2000, 3, -999, 0);
    expect_int(fx, 0x2000, 3, 999, 0);
    expect_int(fx, 0x2000, 3, 1000, 0);
    expect_int(fx, 0x2000, 3, 1001, CO_ABORT_VALUE_HIGH);
    expect_int(fx, 0x2000, 3, -8388608, CO_ABORT_VALUE_LOW);   /* 0x800000 */
    expect_int(fx, 0x2000, 3, 8388607, CO_ABORT_VALUE_HIGH);   /* 0x7FFFFF */
    expect_int(fx, 0x2000, 3, -1, 0);                          /* 0xFFFFFF */
}

static void test_limits_unsigned24_not_sign_extended(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    add_int_limited(fx, 0x2000, CO_TYPE_UNSIGNED24, 0x10, 0xFFFFF0);
    seal(fx);
    expect_int(fx, 0x2000, 3, 0x0F, CO_ABORT_VALUE_LOW);
    expect_int(fx, 0x2000, 3, 0x10, 0);
    expect_int(fx, 0x2000, 3, 0x800000, 0);
    expect_int(fx, 0x2000, 3, 0xFFFFF0, 0);
    expect_int(fx, 0x2000, 3, 0xFFFFF1, CO_ABORT_VALUE_HIGH);
}

static void test_limits_integer40_48_56_sign_extended(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    add_int_limited(fx, 0x2000, CO_TYPE_INTEGER40, -5, 5);
    add_int_limited(fx, 0x2001, CO_TYPE_INTEGER48, -5, 5);
    add_int_limited(fx, 0x2002, CO_TYPE_INTEGER56, -5, 5);
    seal(fx);
    expect_int(fx, 0x2000, 5, -6, CO_ABORT_VALUE_LOW);
    expect_int(fx, 0x2000, 5, -5, 0);
    expect_int(fx, 0x2000, 5, 6, CO_ABORT_VALUE_HIGH);
    expect_int(fx, 0x2001, 6, -6, CO_ABORT_VALUE_LOW);
    expect_int(fx, 0x2001, 6, -4, 0);
    expect_int(fx, 0x2001, 6, 6, CO_ABORT_VALUE_HIGH);
    expect_int(fx, 0x2002, 7, -6, CO_ABORT_VALUE_LOW);
    expect_int(fx, 0x2002, 7, 5, 0);
    expect_int(fx, 0x2002, 7, 6, CO_ABORT_VALUE_HIGH);
}

static void test_limits_integer64_extremes(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    add_int_limited(fx, 0x2000, CO_TYPE_INTEGER64, INT64_MIN + 1, INT64_MAX - 1);
    seal(fx);
    expect_int(fx, 0x2000, 8, INT64_MIN, CO_ABORT_VALUE_LOW);
    expect_int(fx, 0x2000, 8, INT64_MIN + 1, 0);
    expect_int(fx, 0x2000, 8, INT64_MIN + 2, 0);
    expect_int(fx, 0x2000, 8, -1, 0);
    expect_int(fx, 0x2000, 8, INT64_MAX - 2, 0);
    expect_int(fx, 0x2000, 8, INT64_MAX - 1, 0);
    expect_int(fx, 0x2000, 8, INT64_MAX, CO_ABORT_VALUE_HIGH);
}

static void test_limits_unsigned64_extremes(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t lo[8], hi[8], v[8];
    tu_le_put(lo, 1, 8);
    tu_le_put(hi, UINT64_MAX - 1, 8);
    add(fx, with_limits(var(0x2000, 0, CO_TYPE_UNSIGNED64, CO_ACCESS_RW, lo, 8), lo, hi));
    seal(fx);
    tu_le_put(v, 0, 8);
    expect_write(fx, 0x2000, v, 8, CO_ABORT_VALUE_LOW);
    tu_le_put(v, 1, 8);
    expect_write(fx, 0x2000, v, 8, 0);
    tu_le_put(v, 0x8000000000000000ull, 8);     /* large, not negative */
    expect_write(fx, 0x2000, v, 8, 0);
    tu_le_put(v, UINT64_MAX - 1, 8);
    expect_write(fx, 0x2000, v, 8, 0);
    tu_le_put(v, UINT64_MAX, 8);
    expect_write(fx, 0x2000, v, 8, CO_ABORT_VALUE_HIGH);
}

static void test_limits_real32(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t lo[4], hi[4], v[4];
    const float min = -1.5f, max = 2.5f;
    f32_put(lo, min);
    f32_put(hi, max);
    add(fx, with_limits(var(0x2000, 0, CO_TYPE_REAL32, CO_ACCESS_RW, lo, 4), lo, hi));
    seal(fx);
    f32_put(v, f32_away(min));           /* just below -1.5 */
    expect_write(fx, 0x2000, v, 4, CO_ABORT_VALUE_LOW);
    f32_put(v, min);
    expect_write(fx, 0x2000, v, 4, 0);
    f32_put(v, f32_toward(min));
    expect_write(fx, 0x2000, v, 4, 0);
    f32_put(v, 0.0f);
    expect_write(fx, 0x2000, v, 4, 0);
    f32_put(v, f32_toward(max));
    expect_write(fx, 0x2000, v, 4, 0);
    f32_put(v, max);
    expect_write(fx, 0x2000, v, 4, 0);
    f32_put(v, f32_away(max));           /* just above 2.5 */
    expect_write(fx, 0x2000, v, 4, CO_ABORT_VALUE_HIGH);
    tu_le_put(v, 0x7F800000u, 4);           /* +inf */
    expect_write(fx, 0x2000, v, 4, CO_ABORT_VALUE_HIGH);
    tu_le_put(v, 0xFF800000u, 4);           /* -inf */
    expect_write(fx, 0x2000, v, 4, CO_ABORT_VALUE_LOW);
    tu_le_put(v, 0x7FC00000u, 4);           /* NaN */
    expect_write(fx, 0x2000, v, 4, CO_ABORT_INVALID_VALUE);
    tu_le_put(v, 0xFFC00001u, 4);           /* another NaN */
    expect_write(fx, 0x2000, v, 4, CO_ABORT_INVALID_VALUE);
}

static void test_limits_real64(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t lo[8], hi[8], v[8];
    const double min = -1e10, max = 0.125;
    f64_put(lo, min);
    f64_put(hi, max);
    add(fx, with_limits(var(0x2000, 0, CO_TYPE_REAL64, CO_ACCESS_RW, hi, 8), lo, hi));
    seal(fx);
    f64_put(v, f64_away(min));
    expect_write(fx, 0x2000, v, 8, CO_ABORT_VALUE_LOW);
    f64_put(v, min);
    expect_write(fx, 0x2000, v, 8, 0);
    f64_put(v, f64_toward(min));
    expect_write(fx, 0x2000, v, 8, 0);
    f64_put(v, f64_toward(max));
    expect_write(fx, 0x2000, v, 8, 0);
    f64_put(v, max);
    expect_write(fx, 0x2000, v, 8, 0);
    f64_put(v, f64_away(max));
    expect_write(fx, 0x2000, v, 8, CO_ABORT_VALUE_HIGH);
    tu_le_put(v, 0x7FF8000000000000ull, 8);
    expect_write(fx, 0x2000, v, 8, CO_ABORT_INVALID_VALUE);
}

static void test_real_without_limits_accepts_nan(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t v[4];
    add(fx, var(0x2000, 0, CO_TYPE_REAL32, CO_ACCESS_RW, NULL, 0));
    seal(fx);
    tu_le_put(v, 0x7FC00000u, 4);
    expect_write(fx, 0x2000, v, 4, 0);
}

static void test_limits_only_min_or_only_max(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t lim[2], d[2];
    tu_le_put(lim, 100, 2);
    tu_le_put(d, 1000, 2);
    add(fx, with_limits(var(0x2000, 0, CO_TYPE_UNSIGNED16, CO_ACCESS_RW, d, 2), lim, NULL));
    tu_le_put(d, 0, 2);
    add(fx, with_limits(var(0x2001, 0, CO_TYPE_UNSIGNED16, CO_ACCESS_RW, d, 2), NULL, lim));
    seal(fx);
    expect_int(fx, 0x2000, 2, 99, CO_ABORT_VALUE_LOW);
    expect_int(fx, 0x2000, 2, 65535, 0);
    expect_int(fx, 0x2001, 2, 101, CO_ABORT_VALUE_HIGH);
    expect_int(fx, 0x2001, 2, 0, 0);
}

static void test_boolean_accepts_only_0_and_1(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    add(fx, var(0x2000, 0, CO_TYPE_BOOLEAN, CO_ACCESS_RW, NULL, 0));
    seal(fx);
    expect_int(fx, 0x2000, 1, 1, 0);
    expect_int(fx, 0x2000, 1, 0, 0);
    expect_int(fx, 0x2000, 1, 2, CO_ABORT_INVALID_VALUE);
    expect_int(fx, 0x2000, 1, 0xFF, CO_ABORT_INVALID_VALUE);
}

/* ================================================================ read access */

static void test_read_missing_object_and_missing_sub(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    add_u32(fx, 0x2000, 1, CO_ACCESS_RW, 0);
    seal(fx);
    assert_int_equal(co_od_read_begin(&fx->od, &fx->xfer, 0x2001, 0), CO_ABORT_NO_OBJECT);
    assert_int_equal(fx->xfer.abort, CO_ABORT_NO_OBJECT);
    assert_int_equal(fx->xfer.state, CO_XFER_DONE);
    assert_int_equal(co_od_read_begin(&fx->od, &fx->xfer, 0x2000, 0), CO_ABORT_NO_SUB);
    assert_int_equal(co_od_read_begin(&fx->od, &fx->xfer, 0x2000, 2), CO_ABORT_NO_SUB);
    assert_int_equal(co_od_read_begin(&fx->od, &fx->xfer, 0x1FFF, 1), CO_ABORT_NO_OBJECT);
}

static void test_read_of_write_only_refused(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    add_u32(fx, 0x2000, 0, CO_ACCESS_WO, 0);
    seal(fx);
    assert_int_equal(co_od_read_begin(&fx->od, &fx->xfer, 0x2000, 0), CO_ABORT_WRITE_ONLY);
}

static void test_read_allowed_for_ro_rw_rwr_rww_const(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    static const uint8_t access[] = {CO_ACCESS_RO, CO_ACCESS_RW, CO_ACCESS_RWR, CO_ACCESS_RWW,
                                     CO_ACCESS_CONST};
    uint8_t buf[16];
    uint32_t len;
    size_t i;
    for (i = 0; i < sizeof access; i++)
        add_u32(fx, (uint16_t)(0x2000 + i), 0, access[i], 0xA0B0C0D0u + (uint32_t)i);
    seal(fx);
    for (i = 0; i < sizeof access; i++) {
        assert_int_equal(net_read(fx, (uint16_t)(0x2000 + i), 0, buf, sizeof buf, &len), 0);
        assert_int_equal(len, 4);
        assert_int_equal(tu_le_get(buf, 4), 0xA0B0C0D0u + i);
    }
}

static void test_read_in_small_chunks_with_offsets(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t d[8] = {1, 2, 3, 4, 5, 6, 7, 8}, buf[8];
    uint32_t n;
    bool last;
    add(fx, var(0x2000, 0, CO_TYPE_UNSIGNED64, CO_ACCESS_RO, d, 8));
    seal(fx);
    assert_int_equal(co_od_read_begin(&fx->od, &fx->xfer, 0x2000, 0), 0);
    assert_int_equal(fx->xfer.total, 8);
    assert_int_equal(fx->xfer.state, CO_XFER_READ);
    assert_int_equal(co_od_read_chunk(&fx->xfer, buf, 3, &n, &last), 0);
    assert_int_equal(n, 3);
    assert_false(last);
    assert_int_equal(fx->xfer.offset, 3);
    assert_int_equal(co_od_read_chunk(&fx->xfer, buf + 3, 3, &n, &last), 0);
    assert_int_equal(n, 3);
    assert_false(last);
    assert_int_equal(co_od_read_chunk(&fx->xfer, buf + 6, 3, &n, &last), 0);
    assert_int_equal(n, 2);
    assert_true(last);
    assert_memory_equal(buf, d, 8);
    assert_int_equal(fx->xfer.state, CO_XFER_DONE);
    /* nothing more to read */
    assert_int_equal(co_od_read_chunk(&fx->xfer, buf, 3, &n, &last), CO_ABORT_GENERAL);
    assert_int_equal(n, 0);
}

static void test_read_is_a_snapshot_taken_at_begin(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t buf[16];
    uint32_t n;
    bool last;
    add(fx, string_var(0x2000, 0, CO_TYPE_VISIBLE_STRING, 12, "old value!"));
    seal(fx);
    assert_int_equal(co_od_read_begin(&fx->od, &fx->xfer, 0x2000, 0), 0);
    assert_int_equal(co_od_read_chunk(&fx->xfer, buf, 4, &n, &last), 0);
    /* the application changes the value mid-upload */
    assert_int_equal(co_od_put(&fx->od, 0x2000, 0, (const uint8_t *)"NEW VALUE!!!", 12), 0);
    assert_int_equal(co_od_read_chunk(&fx->xfer, buf + 4, 16, &n, &last), 0);
    assert_true(last);
    assert_int_equal(n, 6);
    assert_memory_equal(buf, "old value!", 10);
}

static void test_read_with_too_small_scratch_out_of_memory(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    add(fx, string_var(0x2000, 0, CO_TYPE_VISIBLE_STRING, 100, "x"));
    add_u32(fx, 0x2001, 0, CO_ACCESS_RW, 0);
    seal(fx);
    co_od_xfer_init(&fx->xfer, fx->scratch, 99);
    assert_int_equal(co_od_read_begin(&fx->od, &fx->xfer, 0x2000, 0), CO_ABORT_OUT_OF_MEMORY);
    assert_int_equal(co_od_write_begin(&fx->od, &fx->xfer, 0x2000, 0, 1),
                     CO_ABORT_OUT_OF_MEMORY);
    assert_int_equal(co_od_read_begin(&fx->od, &fx->xfer, 0x2001, 0), 0);
    co_od_xfer_init(&fx->xfer, fx->scratch, 100);
    assert_int_equal(co_od_read_begin(&fx->od, &fx->xfer, 0x2000, 0), 0);
}

/* ================================================================ write access */

static void test_write_of_read_only_and_const_refused(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    add_u32(fx, 0x2000, 0, CO_ACCESS_RO, 1);
    add_u32(fx, 0x2001, 0, CO_ACCESS_CONST, 2);
    seal(fx);
    snapshot(fx);
    assert_int_equal(net_write32(fx, 0x2000, 0, 5), CO_ABORT_READ_ONLY);
    assert_int_equal(net_write32(fx, 0x2001, 0, 5), CO_ABORT_READ_ONLY);
    assert_unchanged(fx);
}

static void test_write_allowed_for_wo_rw_rwr_rww(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    static const uint8_t access[] = {CO_ACCESS_WO, CO_ACCESS_RW, CO_ACCESS_RWR, CO_ACCESS_RWW};
    size_t i;
    for (i = 0; i < sizeof access; i++)
        add_u32(fx, (uint16_t)(0x2000 + i), 0, access[i], 0);
    seal(fx);
    for (i = 0; i < sizeof access; i++) {
        assert_int_equal(net_write32(fx, (uint16_t)(0x2000 + i), 0, 0x01020304u + (uint32_t)i),
                         0);
        assert_int_equal(get32(fx, (uint16_t)(0x2000 + i), 0), 0x01020304u + i);
    }
}

static void test_write_missing_object_and_missing_sub(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    add_u32(fx, 0x2000, 1, CO_ACCESS_RW, 0);
    seal(fx);
    assert_int_equal(net_write32(fx, 0x2001, 1, 0), CO_ABORT_NO_OBJECT);
    assert_int_equal(net_write32(fx, 0x2000, 2, 0), CO_ABORT_NO_SUB);
}

static void test_write_announced_too_long_is_length_high(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    add_u32(fx, 0x2000, 0, CO_ACCESS_RW, 0);
    seal(fx);
    assert_int_equal(co_od_write_begin(&fx->od, &fx->xfer, 0x2000, 0, 5), CO_ABORT_LENGTH_HIGH);
    assert_int_equal(fx->xfer.state, CO_XFER_DONE);
}

static void test_write_numeric_announced_too_short_is_length_low(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    add_u32(fx, 0x2000, 0, CO_ACCESS_RW, 0);
    seal(fx);
    assert_int_equal(co_od_write_begin(&fx->od, &fx->xfer, 0x2000, 0, 3), CO_ABORT_LENGTH_LOW);
    assert_int_equal(co_od_write_begin(&fx->od, &fx->xfer, 0x2000, 0, 0), CO_ABORT_LENGTH_LOW);
}

static void test_write_chunk_beyond_size_is_length_high_and_changes_nothing(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t b[8] = {1, 2, 3, 4, 5, 6, 7, 8};
    add_u32(fx, 0x2000, 0, CO_ACCESS_RW, 0x55);
    seal(fx);
    snapshot(fx);
    assert_int_equal(co_od_write_begin(&fx->od, &fx->xfer, 0x2000, 0, CO_OD_SIZE_UNKNOWN), 0);
    assert_int_equal(co_od_write_chunk(&fx->xfer, b, 3), 0);
    assert_int_equal(co_od_write_chunk(&fx->xfer, b + 3, 2), CO_ABORT_LENGTH_HIGH);
    assert_int_equal(fx->xfer.state, CO_XFER_DONE);
    assert_int_equal(co_od_write_chunk(&fx->xfer, b, 1), CO_ABORT_GENERAL);
    assert_int_equal(co_od_write_end(&fx->xfer), CO_ABORT_GENERAL);
    assert_unchanged(fx);
}

static void test_write_chunk_beyond_announced_total_is_length_high(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t b[8] = {1, 2, 3, 4, 5, 6, 7, 8};
    add(fx, string_var(0x2000, 0, CO_TYPE_OCTET_STRING, 8, NULL));
    seal(fx);
    snapshot(fx);
    assert_int_equal(co_od_write_begin(&fx->od, &fx->xfer, 0x2000, 0, 4), 0);
    assert_int_equal(co_od_write_chunk(&fx->xfer, b, 5), CO_ABORT_LENGTH_HIGH);
    assert_unchanged(fx);
}

static void test_write_end_short_numeric_is_length_low(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t b[4] = {1, 2, 3, 4};
    add_u32(fx, 0x2000, 0, CO_ACCESS_RW, 0x55);
    seal(fx);
    snapshot(fx);
    assert_int_equal(net_write_chunked(fx, 0x2000, 0, b, 3, false, 2), CO_ABORT_LENGTH_LOW);
    assert_unchanged(fx);
}

static void test_write_end_less_than_announced_is_length_low(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t b[8] = {1, 2, 3, 4, 5, 6, 7, 8};
    add(fx, string_var(0x2000, 0, CO_TYPE_OCTET_STRING, 8, "zz"));
    seal(fx);
    snapshot(fx);
    assert_int_equal(co_od_write_begin(&fx->od, &fx->xfer, 0x2000, 0, 6), 0);
    assert_int_equal(co_od_write_chunk(&fx->xfer, b, 5), 0);
    assert_int_equal(co_od_write_end(&fx->xfer), CO_ABORT_LENGTH_LOW);
    assert_unchanged(fx);
}

static void test_write_notifies_after_write_network(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    add_u32(fx, 0x2000, 0, CO_ACCESS_RW, 0);
    seal(fx);
    subscribe(fx, 0x2000, 0, 0x2000, 0, 0);
    assert_int_equal(net_write32(fx, 0x2000, 0, 0xDEADBEEF), 0);
    assert_int_equal(fx->ncalls, 2);
    assert_int_equal(fx->calls[0].what, CALL_CHECK);
    assert_int_equal(fx->calls[0].length, 4);
    assert_int_equal(tu_le_get(fx->calls[0].value, 4), 0xDEADBEEF);
    assert_int_equal(tu_le_get(fx->calls[0].stored, 4), 0);         /* not yet changed */
    assert_int_equal(fx->calls[1].what, CALL_AFTER);
    assert_int_equal(fx->calls[1].origin, CO_ORIGIN_NETWORK);
    assert_int_equal(tu_le_get(fx->calls[1].stored, 4), 0xDEADBEEF); /* changed */
    assert_int_equal(fx->xfer.state, CO_XFER_DONE);
    assert_int_equal(fx->xfer.abort, 0);
}

static void test_refused_writes_change_nothing(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t lo[4], hi[4], b[16];
    memset(b, 0x99, sizeof b);
    tu_le_put(lo, 10, 4);
    tu_le_put(hi, 20, 4);
    add(fx, with_limits(var(0x2000, 0, CO_TYPE_UNSIGNED32, CO_ACCESS_RW, lo, 4), lo, hi));
    add_u32(fx, 0x2001, 0, CO_ACCESS_RO, 1);
    add(fx, string_var(0x2002, 0, CO_TYPE_VISIBLE_STRING, 6, "abc"));
    add_u32(fx, 0x2003, 0, CO_ACCESS_RW, 3);
    add(fx, var(0x2004, 0, CO_TYPE_BOOLEAN, CO_ACCESS_RW, NULL, 0));
    seal(fx);
    subscribe(fx, 0x2003, 0, 0x2003, 0, 0);
    fx->h[0].check_answer = CO_ABORT_DATA_STATE;
    snapshot(fx);
    tu_le_put(b, 21, 4);
    assert_int_equal(net_write(fx, 0x2000, 0, b, 4), CO_ABORT_VALUE_HIGH);
    assert_unchanged(fx);
    tu_le_put(b, 9, 4);
    assert_int_equal(net_write(fx, 0x2000, 0, b, 4), CO_ABORT_VALUE_LOW);
    assert_unchanged(fx);
    assert_int_equal(net_write(fx, 0x2000, 0, b, 5), CO_ABORT_LENGTH_HIGH);
    assert_unchanged(fx);
    assert_int_equal(net_write_chunked(fx, 0x2000, 0, b, 2, false, 1), CO_ABORT_LENGTH_LOW);
    assert_unchanged(fx);
    assert_int_equal(net_write(fx, 0x2001, 0, b, 4), CO_ABORT_READ_ONLY);
    assert_unchanged(fx);
    assert_int_equal(net_write_chunked(fx, 0x2002, 0, b, 7, false, 3), CO_ABORT_LENGTH_HIGH);
    assert_unchanged(fx);
    assert_int_equal(net_write(fx, 0x2003, 0, b, 4), CO_ABORT_DATA_STATE);
    assert_unchanged(fx);
    assert_int_equal(net_write(fx, 0x2004, 0, b, 1), CO_ABORT_INVALID_VALUE);
    assert_unchanged(fx);
    assert_int_equal(net_write(fx, 0x2005, 0, b, 1), CO_ABORT_NO_OBJECT);
    assert_unchanged(fx);
    /* aborted half-way by the peer */
    assert_int_equal(co_od_write_begin(&fx->od, &fx->xfer, 0x2002, 0, 6), 0);
    assert_int_equal(co_od_write_chunk(&fx->xfer, b, 6), 0);
    co_od_xfer_abort(&fx->xfer, CO_ABORT_TIMEOUT);
    assert_int_equal(fx->xfer.abort, CO_ABORT_TIMEOUT);
    assert_int_equal(co_od_write_end(&fx->xfer), CO_ABORT_GENERAL);
    assert_unchanged(fx);
    assert_int_equal(count_calls(fx, CALL_AFTER), 0);
}

static void test_begin_on_busy_transfer_aborts_the_old_one(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t b[4] = {1, 2, 3, 4};
    add_u32(fx, 0x2000, 0, CO_ACCESS_RW, 7);
    add(fx, domain_var(0x2001, 0));
    seal(fx);
    assert_true(co_od_subscribe(&fx->od, 0x2001, 0, 0x2001, 0, &domain_handler, fx));
    /* a half-done value write is dropped */
    assert_int_equal(co_od_write_begin(&fx->od, &fx->xfer, 0x2000, 0, 4), 0);
    assert_int_equal(co_od_write_chunk(&fx->xfer, b, 2), 0);
    assert_int_equal(co_od_read_begin(&fx->od, &fx->xfer, 0x2000, 0), 0);
    assert_int_equal(get32(fx, 0x2000, 0), 7);
    assert_int_equal(fx->xfer.state, CO_XFER_READ);
    /* a half-done domain write: the writer is told */
    assert_int_equal(co_od_write_begin(&fx->od, &fx->xfer, 0x2001, 0, 100), 0);
    assert_int_equal(co_od_write_chunk(&fx->xfer, b, 4), 0);
    assert_int_equal(co_od_write_begin(&fx->od, &fx->xfer, 0x2000, 0, 4), 0);
    assert_int_equal(fx->dom.ends, 1);
    assert_int_equal(fx->dom.end_abort, CO_ABORT_GENERAL);
    assert_int_equal(fx->dom.end_offset, 4);
}

static void test_calls_in_the_wrong_state_are_refused(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t b[4] = {0};
    uint32_t n;
    bool last;
    add_u32(fx, 0x2000, 0, CO_ACCESS_RW, 7);
    seal(fx);
    assert_int_equal(co_od_read_chunk(&fx->xfer, b, 4, &n, &last), CO_ABORT_GENERAL);
    assert_int_equal(co_od_write_chunk(&fx->xfer, b, 4), CO_ABORT_GENERAL);
    assert_int_equal(co_od_write_end(&fx->xfer), CO_ABORT_GENERAL);
    assert_int_equal(co_od_resume(&fx->xfer, 0), CO_ABORT_GENERAL);
    co_od_xfer_abort(&fx->xfer, CO_ABORT_TIMEOUT);    /* idle: nothing */
    assert_int_equal(fx->xfer.state, CO_XFER_IDLE);
    assert_int_equal(co_od_read_begin(&fx->od, &fx->xfer, 0x2000, 0), 0);
    assert_int_equal(co_od_write_chunk(&fx->xfer, b, 4), CO_ABORT_GENERAL);
    assert_int_equal(fx->xfer.state, CO_XFER_READ);   /* the read goes on */
}

/* ================================================================ handlers */

static void test_subscribe_refuses_bad_range_null_handler_and_full_table(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    int i;
    assert_false(co_od_subscribe(&fx->od, 0x2001, 0, 0x2000, 0, &logging_handler, NULL));
    assert_false(co_od_subscribe(&fx->od, 0x2000, 2, 0x2000, 1, &logging_handler, NULL));
    assert_false(co_od_subscribe(&fx->od, 0x2000, 0, 0x2000, 0, NULL, NULL));
    for (i = 0; i < MAX_SUBS; i++)
        assert_true(co_od_subscribe(&fx->od, 0x2000, 0, 0x2000, 0, &logging_handler, NULL));
    assert_false(co_od_subscribe(&fx->od, 0x2000, 0, 0x2000, 0, &logging_handler, NULL));
}

static void test_subscription_range_covers_index_sub_keys(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    add_u32(fx, 0x2000, 0, CO_ACCESS_RW, 0);
    add_u32(fx, 0x2000, 1, CO_ACCESS_RW, 0);
    add_u32(fx, 0x2000, 0xFF, CO_ACCESS_RW, 0);
    add_u32(fx, 0x2001, 0, CO_ACCESS_RW, 0);
    add_u32(fx, 0x2001, 1, CO_ACCESS_RW, 0);
    seal(fx);
    subscribe(fx, 0x2000, 1, 0x2001, 0, 0);
    assert_int_equal(put32(fx, 0x2000, 0, 1), 0);
    assert_int_equal(fx->ncalls, 0);
    assert_int_equal(put32(fx, 0x2000, 1, 1), 0);
    assert_int_equal(put32(fx, 0x2000, 0xFF, 1), 0);
    assert_int_equal(put32(fx, 0x2001, 0, 1), 0);
    assert_int_equal(fx->ncalls, 3);
    assert_int_equal(put32(fx, 0x2001, 1, 1), 0);
    assert_int_equal(fx->ncalls, 3);
    assert_int_equal(fx->calls[0].key, 0x200001);
    assert_int_equal(fx->calls[1].key, 0x2000FF);
    assert_int_equal(fx->calls[2].key, 0x200100);
}

static void test_before_read_abort_refuses_the_read(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    add_u32(fx, 0x2000, 0, CO_ACCESS_RW, 0);
    seal(fx);
    subscribe(fx, 0x2000, 0, 0x2000, 0, 0);
    subscribe(fx, 0x2000, 0, 0x2000, 0, 1);
    fx->h[0].read_answer = CO_ABORT_DATA_STATE;
    assert_int_equal(co_od_read_begin(&fx->od, &fx->xfer, 0x2000, 0), CO_ABORT_DATA_STATE);
    assert_int_equal(fx->xfer.state, CO_XFER_DONE);
    assert_int_equal(fx->ncalls, 1);      /* the second handler is not asked */
}

static void test_before_read_handlers_run_in_subscription_order(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    add_u32(fx, 0x2000, 0, CO_ACCESS_RW, 0);
    seal(fx);
    subscribe(fx, 0x2000, 0, 0x2000, 0, 2);
    subscribe(fx, 0x1000, 0, 0x1FFF, 0xFF, 3);    /* does not cover */
    subscribe(fx, 0x2000, 0, 0x2FFF, 0xFF, 0);
    subscribe(fx, 0x0000, 0, 0xFFFF, 0xFF, 1);
    assert_int_equal(co_od_read_begin(&fx->od, &fx->xfer, 0x2000, 0), 0);
    assert_int_equal(fx->ncalls, 3);
    assert_int_equal(fx->calls[0].tag, 2);
    assert_int_equal(fx->calls[1].tag, 0);
    assert_int_equal(fx->calls[2].tag, 1);
}

static void test_before_read_may_refresh_the_value(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t buf[8];
    uint32_t len;
    add_u32(fx, 0x2000, 0, CO_ACCESS_RO, 0);
    seal(fx);
    subscribe(fx, 0x2000, 0, 0x2000, 0, 0);
    fx->h[0].refresh = 0x12345678;
    assert_int_equal(net_read(fx, 0x2000, 0, buf, sizeof buf, &len), 0);
    assert_int_equal(tu_le_get(buf, 4), 0x12345678);
}

static void test_split_read_resume_ok(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint8_t buf[8];
    uint32_t n;
    bool last;
    add_u32(fx, 0x2000, 0, CO_ACCESS_RW, 0x11);
    seal(fx);
    subscribe(fx, 0x2000, 0, 0x2000, 0, 0);
    subscribe(fx, 0x2000, 0, 0x2000, 0, 1);
    fx->h[0].read_answer = CO_OD_SPLIT;
    assert_int_equal(co_od_read_begin(&fx->od, &fx->xfer, 0x2000, 0), CO_OD_SPLIT);
    assert_int_equal(fx->xfer.state, CO_XFER_PENDING_READ);
    assert_int_equal(fx->ncalls, 1);
    assert_int_equal(co_od_read_chunk(&fx->xfer, buf, 8, &n, &last), CO_ABORT_GENERAL);
    /* the data arrives while waiting */
    assert_int_equal(put32(fx, 0x2000, 0, 0x22), 0);
    fx->ncalls = 0;
    assert_int_equal(co_od_resume(&fx->xfer, 0), 0);
    assert_int_equal(fx->ncalls, 1);       /* the chain went on with the next handler */
    assert_int_equal(fx->calls[0].what, CALL_READ);
    assert_int_equal(fx->calls[0].tag, 1);
    assert_int_equal(fx->xfer.state, CO_XFER_READ);
    assert_int_equal(co_od_read_chunk(&fx->xfer, buf, 8, &n, &last), 0);
    assert_int_equal(n, 4);
    assert_true(last);
    assert_int_equal(tu_le_get(buf, 4), 0x22);
}

static void test_split_read_resume_with_abort(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    add_u32(fx, 0x2000, 0, CO_ACCESS_RW, 0x11);
    seal(fx);
    subscribe(fx, 0x2000, 0, 0x2000, 0, 0);
    subscribe(fx, 0x2000, 0, 0x2000, 0, 1);
    fx->h[0].read_answer = CO_OD_SPLIT;
    assert_int_equal(co_od_read_begin(&fx->od, &fx->xfer, 0x2000, 0), CO_OD_SPLIT);
    assert_int_equal(co_od_resume(&fx->xfer, CO_OD_SPLIT), CO_OD_SPLIT);   /* still waiting */
    assert_int_equal(fx->xfer.state, CO_XFER_PENDING_READ);
    assert_int_equal(co_od_resume(&fx->xfer, CO_ABORT_HARDWARE), CO_ABORT_HARDWARE);
    assert_int_equal(fx->xfer.state, CO_XFER_DONE);
    assert_int_equal(fx->xfer.abort, CO_ABORT_HARDWARE);
    assert_int_equal(fx->ncalls, 1);
    assert_int_equal(co_od_resume(&fx->xfer, 0), CO_ABORT_GENERAL);
}

static void test_split_read_twice(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    add_u32(fx, 0x2000, 0, CO_ACCESS_RW, 0x11);
    seal(fx);
    subscribe(fx, 0x2000, 0, 0x2000, 0, 0);
    subscribe(fx, 0x2000, 0, 0x2000, 0, 1);
    fx->h[0].read_answer = CO_OD_SPLIT;
    fx->h[1].read_answer = CO_OD_SPLIT;
    assert_int_equal(co_od_read_begin(&fx->od, &fx->xfer, 0x2000, 0), CO_OD_SPLIT);
    assert_int_equal(co_od_resume(&fx->xfer, 0), CO_OD_SPLIT);
    assert_int_equal(fx->ncalls, 2);
    assert_int_equal(co_od_resume(&fx->xfer, 0), 0);
    assert_int_equal(fx->ncalls, 2);
    assert_int_equal(fx->xfer.total, 4);
}

static void test_split_write_resume_ok_commits(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    add_u32(fx, 0x2000, 0, CO_ACCESS_RW, 0x11);
    seal(fx);
    subscribe(fx, 0x2000, 0, 0x2000, 0, 0);
    subscribe(fx, 0x2000, 0, 0x2000, 0, 1);
    fx->h[0].check_answer = CO_OD_SPLIT;
    assert_int_equal(net_write32(fx, 0x2000, 0, 0x99), CO_OD_SPLIT);
    assert_int_equal(fx->xfer.state, CO_XFER_PENDING_WRITE);
    assert_int_equal(get32(fx, 0x2000, 0), 0x11);          /* not yet */
    assert_int_equal(fx->ncalls, 1);
    assert_int_equal(co_od_resume(&fx->xfer, 0), 0);
    assert_int_equal(get32(fx, 0x2000, 0), 0x99);
    assert_int_equal(fx->xfer.state, CO_XFER_DONE);
    /* check by handler 1, then after_write of both */
    assert_int_equal(fx->ncalls, 4);
    assert_int_equal(fx->calls[1].what, CALL_CHECK);
    assert_int_equal(fx->calls[1].tag, 1);
    assert_int_equal(fx->calls[2].what, CALL_AFTER);
    assert_int_equal(fx->calls[2].tag, 0);
    assert_int_equal(fx->calls[3].what, CALL_AFTER);
    assert_int_equal(fx->calls[3].tag, 1);
}

static void test_split_write_resume_with_abort_changes_nothing(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    add_u32(fx, 0x2000, 0, CO_ACCESS_RW, 0x11);
    seal(fx);
    subscribe(fx, 0x2000, 0, 0x2000, 0, 0);
    subscribe(fx, 0x2000, 0, 0x2000, 0, 1);
    fx->h[0].check_answer = CO_OD_SPLIT;
    snapshot(fx);
    assert_int_equal(net_write32(fx, 0x2000, 0, 0x99), CO_OD_SPLIT);
    assert_int_equal(co_od_resume(&fx->xfer, CO_ABORT_DATA_LOCAL), CO_ABORT_DATA_LOCAL);
    assert_int_equal(fx->xfer.state, CO_XFER_DONE);
    assert_int_equal(fx->xfer.abort, CO_ABORT_DATA_LOCAL);
    assert_unchanged(fx);
    assert_int_equal(fx->ncalls, 1);
}

static void test_abort_while_split_write_changes_nothing(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    add_u32(fx, 0x2000, 0, CO_ACCESS_RW, 0x11);
    seal(fx);
    subscribe(fx, 0x2000, 0, 0x2000, 0, 0);
    fx->h[0].check_answer = CO_OD_SPLIT;
    snapshot(fx);
    assert_int_equal(net_write32(fx, 0x2000, 0, 0x99), CO_OD_SPLIT);
    co_od_xfer_abort(&fx->xfer, CO_ABORT_TIMEOUT);
    assert_int_equal(co_od_resume(&fx->xfer, 0), CO_ABORT_GENERAL);
    assert_unchanged(fx);
    assert_int_equal(count_calls(fx, CALL_AFTER), 0);
}

static void test_second_check_write_refusing_means_no_change_no_after_write(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    add_u32(fx, 0x2000, 0, CO_ACCESS_RW, 0x11);
    seal(fx);
    subscribe(fx, 0x2000, 0, 0x2000, 0, 0);
    subscribe(fx, 0x2000, 0, 0x2000, 0, 1);
    subscribe(fx, 0x2000, 0, 0x2000, 0, 2);
    fx->h[1].check_answer = CO_ABORT_PARAM_INCOMPATIBLE;
    snapshot(fx);
    assert_int_equal(net_write32(fx, 0x2000, 0, 0x99), CO_ABORT_PARAM_INCOMPATIBLE);
    assert_unchanged(fx);
    /* handler 0 and 1 were asked, 2 not; nobody was told of a write */
    assert_int_equal(fx->ncalls, 2);
    assert_int_equal(fx->calls[0].tag, 0);
    assert_int_equal(fx->calls[1].tag, 1);
    assert_int_equal(count_calls(fx, CALL_AFTER), 0);
}

static void test_all_check_writes_run_before_any_after_write(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    add_u32(fx, 0x2000, 0, CO_ACCESS_RW, 0x11);
    seal(fx);
    subscribe(fx, 0x2000, 0, 0x2000, 0, 0);
    subscribe(fx, 0x2000, 0, 0x2000, 0, 1);
    subscribe(fx, 0x2000, 0, 0x2000, 0, 2);
    assert_int_equal(net_write32(fx, 0x2000, 0, 0x99), 0);
    assert_int_equal(fx->ncalls, 6);
    assert_int_equal(fx->calls[0].what, CALL_CHECK);
    assert_int_equal(fx->calls[1].what, CALL_CHECK);
    assert_int_equal(fx->calls[2].what, CALL_CHECK);
    assert_int_equal(tu_le_get(fx->calls[2].stored, 4), 0x11);   /* old value during the test */
    assert_int_equal(fx->calls[3].what, CALL_AFTER);
    assert_int_equal(fx->calls[3].tag, 0);
    assert_int_equal(tu_le_get(fx->calls[3].stored, 4), 0x99);   /* new value when told */
    assert_int_equal(fx->calls[5].tag, 2);
}

static uint32_t check_aborts_itself(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e,
                                    const uint8_t *value, uint32_t length, void *user)
{
    (void)od;
    (void)e;
    (void)value;
    (void)length;
    (void)user;
    co_od_xfer_abort(xfer, CO_ABORT_TIMEOUT);
    return 0;
}

static void test_check_write_that_aborts_the_transfer_stops_it(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    static const co_od_handler_t h = {.check_write = check_aborts_itself};
    add_u32(fx, 0x2000, 0, CO_ACCESS_RW, 0x11);
    seal(fx);
    assert_true(co_od_subscribe(&fx->od, 0x2000, 0, 0x2000, 0, &h, NULL));
    subscribe(fx, 0x2000, 0, 0x2000, 0, 0);
    snapshot(fx);
    assert_int_equal(net_write32(fx, 0x2000, 0, 0x99), CO_ABORT_TIMEOUT);
    assert_unchanged(fx);
    assert_int_equal(fx->ncalls, 0);
}

static void test_cob_id_change_rules(void **state)
{
    (void)state;
    /* valid -> valid with another CAN-ID: refused */
    assert_int_equal(co_od_check_cob_id_change(0x181, 0x182), CO_ABORT_INVALID_VALUE);
    assert_int_equal(co_od_check_cob_id_change(0x40000181u, 0x40000182u),
                     CO_ABORT_INVALID_VALUE);
    /* frame format bit 29 counts as CAN-ID */
    assert_int_equal(co_od_check_cob_id_change(0x181, 0x20000181u), CO_ABORT_INVALID_VALUE);
    /* the same ID, other flag bits (30): fine */
    assert_int_equal(co_od_check_cob_id_change(0x181, 0x40000181u), 0);
    assert_int_equal(co_od_check_cob_id_change(0x181, 0x181), 0);
    /* invalidate, change while invalid, validate with a new ID */
    assert_int_equal(co_od_check_cob_id_change(0x181, 0x80000181u), 0);
    assert_int_equal(co_od_check_cob_id_change(0x80000181u, 0x80000222u), 0);
    assert_int_equal(co_od_check_cob_id_change(0x80000181u, 0x222), 0);
    assert_int_equal(co_od_check_cob_id_change(0x181, 0x80000222u), 0);
}

/* ================================================================ domains */

static void domain_od(fx_t *fx, const co_od_handler_t *h)
{
    add(fx, domain_var(0x2000, 0));
    seal(fx);
    if (h)
        assert_true(co_od_subscribe(&fx->od, 0x2000, 0, 0x2000, 0, h, fx));
}

static void domain_upload(void **state, uint32_t chunk, bool announce)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint32_t got = 0, n;
    bool last = false;
    domain_od(fx, &domain_handler);
    fill_domain_source(fx, DOMAIN_BYTES);
    fx->dom.announce = announce;
    assert_int_equal(co_od_read_begin(&fx->od, &fx->xfer, 0x2000, 0), 0);
    assert_int_equal(fx->xfer.total, announce ? DOMAIN_BYTES : CO_OD_SIZE_UNKNOWN);
    while (!last) {
        uint32_t left = DOMAIN_BYTES - got;
        assert_int_equal(co_od_read_chunk(&fx->xfer, fx->dom_got + got, chunk, &n, &last), 0);
        assert_int_equal(n, left < chunk ? left : chunk);
        got += n;
        assert_int_equal(fx->xfer.offset, got);
    }
    assert_int_equal(got, DOMAIN_BYTES);
    assert_int_equal(fx->dom.offset_errors, 0);
    assert_int_equal(fx->xfer.state, CO_XFER_DONE);
    assert_memory_equal(fx->dom_got, fx->dom_src, DOMAIN_BYTES);
}

static void test_domain_upload_1mib_in_chunks_of_7(void **state)
{
    domain_upload(state, 7, true);
}

static void test_domain_upload_1mib_in_chunks_of_60(void **state)
{
    domain_upload(state, 60, true);
}

static void test_domain_upload_1mib_in_chunks_of_889_size_unknown(void **state)
{
    domain_upload(state, 889, false);
}

static void domain_download(void **state, uint32_t chunk, bool announce)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint32_t off = 0;
    domain_od(fx, &domain_handler);
    subscribe(fx, 0x2000, 0, 0x2000, 0, 0);     /* after_write of the domain */
    fill_domain_source(fx, DOMAIN_BYTES);
    assert_int_equal(co_od_write_begin(&fx->od, &fx->xfer, 0x2000, 0,
                                       announce ? DOMAIN_BYTES : CO_OD_SIZE_UNKNOWN),
                     0);
    while (off < DOMAIN_BYTES) {
        uint32_t n = DOMAIN_BYTES - off < chunk ? DOMAIN_BYTES - off : chunk;
        assert_int_equal(co_od_write_chunk(&fx->xfer, fx->dom_src + off, n), 0);
        off += n;
        assert_int_equal(fx->xfer.offset, off);
        assert_int_equal(fx->dom.dst_len, off);
    }
    assert_int_equal(fx->dom.ends, 0);
    assert_int_equal(co_od_write_end(&fx->xfer), 0);
    assert_int_equal(fx->dom.ends, 1);
    assert_int_equal(fx->dom.end_abort, 0);
    assert_int_equal(fx->dom.end_offset, DOMAIN_BYTES);
    assert_int_equal(fx->dom.last_total, announce ? DOMAIN_BYTES : CO_OD_SIZE_UNKNOWN);
    assert_int_equal(fx->dom.offset_errors, 0);
    assert_int_equal(fx->dom.write_calls, (DOMAIN_BYTES + chunk - 1) / chunk + 1);
    assert_memory_equal(fx->dom_dst, fx->dom_src, DOMAIN_BYTES);
    assert_int_equal(fx->ncalls, 1);                 /* no check_write for domains */
    assert_int_equal(fx->calls[0].what, CALL_AFTER);
    assert_int_equal(fx->calls[0].origin, CO_ORIGIN_NETWORK);
}

static void test_domain_download_1mib_in_chunks_of_7(void **state)
{
    domain_download(state, 7, true);
}

static void test_domain_download_1mib_in_chunks_of_60_size_unknown(void **state)
{
    domain_download(state, 60, false);
}

static void test_domain_download_1mib_in_chunks_of_889(void **state)
{
    domain_download(state, 889, true);
}

static void test_domain_abort_mid_download_notifies_the_writer(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    int i;
    domain_od(fx, &domain_handler);
    subscribe(fx, 0x2000, 0, 0x2000, 0, 0);
    fill_domain_source(fx, 1000);
    assert_int_equal(co_od_write_begin(&fx->od, &fx->xfer, 0x2000, 0, 1000), 0);
    for (i = 0; i < 3; i++)
        assert_int_equal(co_od_write_chunk(&fx->xfer, fx->dom_src + 60 * i, 60), 0);
    co_od_xfer_abort(&fx->xfer, CO_ABORT_TIMEOUT);
    assert_int_equal(fx->dom.ends, 1);
    assert_int_equal(fx->dom.end_abort, CO_ABORT_TIMEOUT);
    assert_int_equal(fx->dom.end_offset, 180);
    assert_int_equal(fx->xfer.state, CO_XFER_DONE);
    /* nothing more reaches the writer */
    assert_int_equal(co_od_write_chunk(&fx->xfer, fx->dom_src, 60), CO_ABORT_GENERAL);
    co_od_xfer_abort(&fx->xfer, CO_ABORT_TIMEOUT);
    assert_int_equal(fx->dom.write_calls, 4);
    assert_int_equal(count_calls(fx, CALL_AFTER), 0);
}

static void test_domain_abort_with_code_0_reports_general_error(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    domain_od(fx, &domain_handler);
    assert_int_equal(co_od_write_begin(&fx->od, &fx->xfer, 0x2000, 0, 10), 0);
    co_od_xfer_abort(&fx->xfer, 0);
    assert_int_equal(fx->dom.end_abort, CO_ABORT_GENERAL);
}

static void test_domain_download_beyond_announced_size_tells_the_writer(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    domain_od(fx, &domain_handler);
    fill_domain_source(fx, 100);
    assert_int_equal(co_od_write_begin(&fx->od, &fx->xfer, 0x2000, 0, 100), 0);
    assert_int_equal(co_od_write_chunk(&fx->xfer, fx->dom_src, 60), 0);
    assert_int_equal(co_od_write_chunk(&fx->xfer, fx->dom_src + 60, 41), CO_ABORT_LENGTH_HIGH);
    assert_int_equal(fx->dom.dst_len, 60);
    assert_int_equal(fx->dom.ends, 1);
    assert_int_equal(fx->dom.end_abort, CO_ABORT_LENGTH_HIGH);
}

static void test_domain_download_shorter_than_announced_tells_the_writer(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    domain_od(fx, &domain_handler);
    fill_domain_source(fx, 100);
    assert_int_equal(co_od_write_begin(&fx->od, &fx->xfer, 0x2000, 0, 100), 0);
    assert_int_equal(co_od_write_chunk(&fx->xfer, fx->dom_src, 60), 0);
    assert_int_equal(co_od_write_end(&fx->xfer), CO_ABORT_LENGTH_LOW);
    assert_int_equal(fx->dom.ends, 1);
    assert_int_equal(fx->dom.end_abort, CO_ABORT_LENGTH_LOW);
    assert_int_equal(fx->dom.end_offset, 60);
}

static void test_domain_writer_refusal_ends_the_transfer(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    domain_od(fx, &domain_handler);
    fill_domain_source(fx, 100);
    fx->dom.refuse_at = 50;
    assert_int_equal(co_od_write_begin(&fx->od, &fx->xfer, 0x2000, 0, CO_OD_SIZE_UNKNOWN), 0);
    assert_int_equal(co_od_write_chunk(&fx->xfer, fx->dom_src, 50), 0);
    assert_int_equal(co_od_write_chunk(&fx->xfer, fx->dom_src + 50, 50), CO_ABORT_DATA_LOCAL);
    assert_int_equal(fx->xfer.state, CO_XFER_DONE);
    assert_int_equal(fx->dom.ends, 0);      /* it refused itself: not told again */
}

static uint32_t d_begin_100(co_od_t *od, const co_od_entry_t *e, uint32_t total, void *user)
{
    fx_t *fx = user;
    (void)od;
    (void)e;
    fx->dom.last_total = total;
    return total != CO_OD_SIZE_UNKNOWN && total > 100 ? CO_ABORT_LENGTH_HIGH : 0;
}

static void test_domain_writer_refuses_an_announced_size_at_the_initiate(void **state)
{
    static const co_od_handler_t h = {
        .domain_size = d_size,
        .domain_read = d_read,
        .domain_write = d_write,
        .domain_begin = d_begin_100,
    };
    fx_t *fx = fx_new(state, CO_MODE_FD);
    domain_od(fx, &h);
    fill_domain_source(fx, 100);
    assert_int_equal(co_od_write_begin(&fx->od, &fx->xfer, 0x2000, 0, 101),
                     CO_ABORT_LENGTH_HIGH);
    assert_int_equal(fx->xfer.state, CO_XFER_DONE);
    assert_int_equal(fx->dom.last_total, 101);
    assert_int_equal(fx->dom.write_calls, 0);     /* refused before any chunk */
    assert_int_equal(co_od_write_begin(&fx->od, &fx->xfer, 0x2000, 0, 100), 0);
    assert_int_equal(co_od_write_chunk(&fx->xfer, fx->dom_src, 100), 0);
    assert_int_equal(co_od_write_end(&fx->xfer), 0);
    assert_int_equal(fx->dom.dst_len, 100);
    assert_int_equal(co_od_write_begin(&fx->od, &fx->xfer, 0x2000, 0, CO_OD_SIZE_UNKNOWN), 0);
}

static void test_domain_without_handlers(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    domain_od(fx, NULL);
    subscribe(fx, 0x2000, 0, 0x2000, 0, 0);   /* no domain callbacks in it */
    assert_int_equal(co_od_read_begin(&fx->od, &fx->xfer, 0x2000, 0), CO_ABORT_NO_DATA);
    assert_int_equal(co_od_write_begin(&fx->od, &fx->xfer, 0x2000, 0, 10),
                     CO_ABORT_UNSUPPORTED_ACCESS);
}

static void test_domain_reader_without_size_handler_has_unknown_size(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint32_t n;
    bool last;
    domain_od(fx, &domain_read_only_handler);
    fill_domain_source(fx, 10);
    assert_int_equal(co_od_read_begin(&fx->od, &fx->xfer, 0x2000, 0), 0);
    assert_int_equal(fx->xfer.total, CO_OD_SIZE_UNKNOWN);
    assert_int_equal(co_od_read_chunk(&fx->xfer, fx->dom_got, 64, &n, &last), 0);
    assert_int_equal(n, 10);
    assert_true(last);
    assert_int_equal(co_od_write_begin(&fx->od, &fx->xfer, 0x2000, 0, 10),
                     CO_ABORT_UNSUPPORTED_ACCESS);
}

static void test_domain_reader_ending_before_announced_size_aborts(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    uint32_t n;
    bool last;
    static const co_od_handler_t h = {.domain_size = d_size, .domain_read = d_read};
    domain_od(fx, &h);
    fill_domain_source(fx, 10);
    fx->dom.announce = true;
    assert_int_equal(co_od_read_begin(&fx->od, &fx->xfer, 0x2000, 0), 0);
    fx->dom.src_len = 5;    /* the data shrank after the size was announced */
    assert_int_equal(co_od_read_chunk(&fx->xfer, fx->dom_got, 64, &n, &last), CO_ABORT_GENERAL);
    assert_int_equal(fx->xfer.state, CO_XFER_DONE);
}

/* ================================================================ defaults */

static void test_group_of(void **state)
{
    (void)state;
    assert_int_equal(co_od_group_of(0x0FFF), 0);
    assert_int_equal(co_od_group_of(0x1000), CO_GROUP_COMMUNICATION);
    assert_int_equal(co_od_group_of(0x1FFF), CO_GROUP_COMMUNICATION);
    assert_int_equal(co_od_group_of(0x2000), CO_GROUP_MANUFACTURER);
    assert_int_equal(co_od_group_of(0x5FFF), CO_GROUP_MANUFACTURER);
    assert_int_equal(co_od_group_of(0x6000), CO_GROUP_APPLICATION);
    assert_int_equal(co_od_group_of(0x9FFF), CO_GROUP_APPLICATION);
    /* same split as the Python model (ODVariable.store_group) */
    assert_int_equal(co_od_group_of(0xA000), CO_GROUP_MANUFACTURER);
    assert_int_equal(co_od_group_of(0xFFFF), CO_GROUP_MANUFACTURER);
}

static void groups_od(fx_t *fx)
{
    uint8_t b[4];
    co_od_def_t d;
    add_u32(fx, 0x1017, 0, CO_ACCESS_RW, 1000);
    d = u32_var(0x1018, 1, CO_ACCESS_RW, 2000, b);
    d.flags = CO_OD_STORE;
    add(fx, d);
    add_u32(fx, 0x2000, 0, CO_ACCESS_RW, 3000);
    add_u32(fx, 0x5FFF, 0, CO_ACCESS_RW, 4000);
    add_u32(fx, 0x6000, 0, CO_ACCESS_RW, 5000);
    add(fx, string_var(0x6001, 0, CO_TYPE_VISIBLE_STRING, 8, "dflt"));
    seal(fx);
    subscribe(fx, 0x0000, 0, 0xFFFF, 0xFF, 0);
    assert_int_equal(put32(fx, 0x1017, 0, 1), 0);
    assert_int_equal(put32(fx, 0x1018, 1, 2), 0);
    assert_int_equal(put32(fx, 0x2000, 0, 3), 0);
    assert_int_equal(put32(fx, 0x5FFF, 0, 4), 0);
    assert_int_equal(put32(fx, 0x6000, 0, 5), 0);
    assert_int_equal(co_od_put(&fx->od, 0x6001, 0, (const uint8_t *)"changed!", 8), 0);
    fx->ncalls = 0;
}

static void test_load_defaults_of_the_communication_group(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    groups_od(fx);
    co_od_load_defaults(&fx->od, CO_GROUP_COMMUNICATION);
    assert_int_equal(get32(fx, 0x1017, 0), 1000);
    assert_int_equal(get32(fx, 0x1018, 1), 2000);
    assert_int_equal(get32(fx, 0x2000, 0), 3);
    assert_int_equal(get32(fx, 0x5FFF, 0), 4);
    assert_int_equal(get32(fx, 0x6000, 0), 5);
    assert_int_equal(fx->ncalls, 2);
    assert_int_equal(fx->calls[0].key, 0x101700);
    assert_int_equal(fx->calls[0].origin, CO_ORIGIN_RESTORE);
    assert_int_equal(fx->calls[1].key, 0x101801);
}

static void test_load_defaults_of_the_manufacturer_group(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    groups_od(fx);
    co_od_load_defaults(&fx->od, CO_GROUP_MANUFACTURER);
    assert_int_equal(get32(fx, 0x1017, 0), 1);
    assert_int_equal(get32(fx, 0x2000, 0), 3000);
    assert_int_equal(get32(fx, 0x5FFF, 0), 4000);
    assert_int_equal(get32(fx, 0x6000, 0), 5);
    assert_int_equal(fx->ncalls, 2);
}

static void test_load_defaults_of_the_application_group_restores_strings(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    const co_od_entry_t *e;
    groups_od(fx);
    co_od_load_defaults(&fx->od, CO_GROUP_APPLICATION);
    assert_int_equal(get32(fx, 0x5FFF, 0), 4);
    assert_int_equal(get32(fx, 0x6000, 0), 5000);
    e = co_od_find(&fx->od, 0x6001, 0);
    assert_int_equal(e->length, 4);
    assert_memory_equal(co_od_value(&fx->od, e), "dflt\0\0\0\0", 8);
    assert_int_equal(fx->ncalls, 2);
}

static void test_load_defaults_tells_only_changed_entries_once(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    groups_od(fx);
    co_od_load_defaults(&fx->od, CO_GROUP_ALL);
    assert_int_equal(fx->ncalls, 6);
    fx->ncalls = 0;
    co_od_load_defaults(&fx->od, CO_GROUP_ALL);    /* nothing changed now */
    assert_int_equal(fx->ncalls, 0);
    assert_int_equal(put32(fx, 0x2000, 0, 77), 0);
    fx->ncalls = 0;
    co_od_load_defaults(&fx->od, CO_GROUP_ALL);
    assert_int_equal(fx->ncalls, 1);
    assert_int_equal(fx->calls[0].key, 0x200000);
    assert_int_equal(fx->entries[0].flags & 0x8000, 0);
}

static void restore_reads_other(co_od_t *od, const co_od_entry_t *e, co_od_origin_t origin,
                                void *user)
{
    fx_t *fx = user;
    uint32_t v = 0;
    (void)e;
    assert_int_equal(origin, CO_ORIGIN_RESTORE);
    /* whichever entry is told first, the other is restored already */
    assert_true(co_od_get_u32(od, 0x2000, 0, &v));
    assert_int_equal(v, 3000);
    assert_true(co_od_get_u32(od, 0x6000, 0, &v));
    assert_int_equal(v, 5000);
    fx->ncalls++;
}

static void test_load_defaults_tells_after_all_are_loaded(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    static const co_od_handler_t h = {.after_write = restore_reads_other};
    groups_od(fx);
    assert_true(co_od_subscribe(&fx->od, 0x2000, 0, 0x6000, 0, &h, fx));
    co_od_load_defaults(&fx->od, CO_GROUP_MANUFACTURER | CO_GROUP_APPLICATION);
    /* logging handler: 0x2000, 0x5FFF, 0x6000, 0x6001; restore_reads_other: 3 */
    assert_int_equal(fx->ncalls, 4 + 3);
}

/* ================================================================ differential */

/* Reference model of a few entries; random writes by network and application
 * must give exactly the model's abort codes and values. */
typedef struct model {
    uint16_t index;
    uint8_t type;
    uint32_t size;
    bool has_limits;
    int64_t min, max;
    uint8_t value[16];
    uint32_t length;
} model_t;

static int64_t model_number(const model_t *m, const uint8_t *v)
{
    switch (m->type) {
    case CO_TYPE_UNSIGNED8:
        return v[0];
    case CO_TYPE_INTEGER16:
        return (int16_t)(uint16_t)(v[0] | v[1] << 8);
    case CO_TYPE_INTEGER24: {
        int32_t x = (int32_t)((uint32_t)v[0] | (uint32_t)v[1] << 8 | (uint32_t)v[2] << 16);
        return x >= 0x800000 ? x - 0x1000000 : x;
    }
    default:
        return 0;
    }
}

static uint32_t model_check(const model_t *m, const uint8_t *v, uint32_t len)
{
    bool str = m->type == CO_TYPE_VISIBLE_STRING;
    if (len > m->size)
        return CO_ABORT_LENGTH_HIGH;
    if (!str && len < m->size)
        return CO_ABORT_LENGTH_LOW;
    if (m->type == CO_TYPE_BOOLEAN && v[0] > 1)
        return CO_ABORT_INVALID_VALUE;
    if (m->has_limits) {
        int64_t x = model_number(m, v);
        if (x < m->min)
            return CO_ABORT_VALUE_LOW;
        if (x > m->max)
            return CO_ABORT_VALUE_HIGH;
    }
    return 0;
}

static void test_random_writes_match_a_reference_model(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD);
    model_t m[] = {
        {0x2000, CO_TYPE_UNSIGNED8, 1, true, 10, 200, {10}, 1},
        {0x2001, CO_TYPE_INTEGER16, 2, true, -300, 300, {0}, 2},
        {0x2002, CO_TYPE_INTEGER24, 3, true, -1000, 1000, {0}, 3},
        {0x2003, CO_TYPE_UNSIGNED32, 4, false, 0, 0, {0}, 4},
        {0x2004, CO_TYPE_VISIBLE_STRING, 10, false, 0, 0, {0}, 0},
        {0x2005, CO_TYPE_BOOLEAN, 1, false, 0, 0, {0}, 1},
    };
    const size_t nm = sizeof m / sizeof m[0];
    uint64_t rng = 7;
    uint8_t v[16], out[16];
    uint32_t len;
    size_t i;
    int round;
    for (i = 0; i < nm; i++) {
        co_od_def_t d;
        if (m[i].type == CO_TYPE_VISIBLE_STRING) {
            d = string_var(m[i].index, 0, m[i].type, m[i].size, NULL);
        } else {
            d = var(m[i].index, 0, m[i].type, CO_ACCESS_RW, m[i].value, m[i].size);
        }
        if (m[i].has_limits) {
            uint8_t lo[8], hi[8];
            tu_le_put(lo, (uint64_t)m[i].min, m[i].size);
            tu_le_put(hi, (uint64_t)m[i].max, m[i].size);
            d = with_limits(d, lo, hi);
        }
        add(fx, d);
    }
    seal(fx);
    for (round = 0; round < 20000; round++) {
        model_t *mm = &m[tu_rand(&rng) % nm];
        uint32_t n = (uint32_t)(tu_rand(&rng) % (mm->size + 3));
        uint32_t how = (uint32_t)(tu_rand(&rng) % 4), expect, got;
        for (i = 0; i < n; i++)
            v[i] = (uint8_t)tu_rand(&rng);
        if (tu_rand(&rng) % 2)     /* often small numbers, to hit the limits */
            for (i = 1; i < n; i++)
                v[i] = (v[n - 1] & 0x80) ? 0xFF : 0x00;
        expect = model_check(mm, v, n);
        if (how == 0)
            got = co_od_put(&fx->od, mm->index, 0, v, n);
        else
            got = net_write_chunked(fx, mm->index, 0, v, n, how == 1, how);
        assert_int_equal(got, expect);
        if (expect == 0) {
            memset(mm->value, 0, sizeof mm->value);
            memcpy(mm->value, v, n);
            mm->length = n;
        }
        for (i = 0; i < nm; i++) {
            assert_int_equal(net_read(fx, m[i].index, 0, out, sizeof out, &len), 0);
            assert_int_equal(len, m[i].length);
            assert_memory_equal(out, m[i].value, len);
            assert_memory_equal(co_od_value(&fx->od, co_od_find(&fx->od, m[i].index, 0)),
                                m[i].value, m[i].size);
        }
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_type_size_of_every_type),
#define T(name) cmocka_unit_test_setup_teardown(name, setup, teardown)
        T(test_every_fixed_type_default_get_put_exact_bytes),
        T(test_every_fixed_type_network_write_and_read_exact_bytes),
        T(test_typed_getters_check_the_size),
        T(test_add_refuses_fixed_type_with_wrong_size),
        T(test_add_refuses_unknown_types),
        T(test_add_checks_string_and_domain_sizes),
        T(test_add_refuses_unknown_access_and_flags),
        T(test_add_refuses_numeric_default_of_wrong_length),
        T(test_add_numeric_without_default_defaults_to_zero),
        T(test_add_refuses_default_length_without_pointer),
        T(test_add_refuses_string_default_longer_than_size),
        T(test_add_refuses_limits_on_strings_and_domains),
        T(test_add_refuses_min_above_max_in_the_types_signedness),
        T(test_add_refuses_nan_limits),
        T(test_add_refuses_default_outside_limits),
        T(test_add_refuses_boolean_default_other_than_0_1),
        T(test_add_refuses_nodeid_relative_on_non_integers),
        T(test_add_refuses_duplicates),
        T(test_add_reports_full_entry_table),
        cmocka_unit_test(test_pool_need_counts_value_default_and_limits),
        T(test_add_reports_full_pool_at_the_exact_byte),
        T(test_add_after_seal_is_refused),
        T(test_mode_filter_on_classic_od),
        T(test_mode_filter_on_fd_od),
        T(test_seal_refuses_record_without_sub0),
        T(test_seal_accepts_sub0_below_highest_sub),
        T(test_seal_refuses_sub0_not_unsigned8),
        T(test_seal_accepts_records_with_gaps_and_vars),
        T(test_seal_twice_is_refused),
        T(test_seal_checks_sub0_of_record_defined_by_var_subs),
        T(test_nodeid_relative_defaults_add_the_node_id),
        T(test_access_before_seal_reports_no_od),
        T(test_binary_search_on_10000_entries_added_in_random_order),
        T(test_find_on_empty_od),
        T(test_get_reports_buffer_too_small),
        T(test_get_put_report_missing_object_and_sub),
        T(test_put_checks_length),
        T(test_put_checks_limits),
        T(test_put_notifies_after_write_local_without_check),
        T(test_put_may_write_read_only_and_const_entries),
        T(test_get_put_on_domain_unsupported),
        T(test_string_put_shorter_sets_length_and_zero_fills),
        T(test_string_write_of_max_length),
        T(test_string_write_longer_than_size_refused),
        T(test_string_write_shorter_keeps_new_length),
        T(test_string_write_empty),
        T(test_visible_string_read_total_is_current_length),
        T(test_unicode_string_of_odd_length_refused),
        T(test_limits_unsigned8),
        T(test_limits_integer16_compare_signed),
        T(test_limits_integer24_sign_extended),
        T(test_limits_unsigned24_not_sign_extended),
        T(test_limits_integer40_48_56_sign_extended),
        T(test_limits_integer64_extremes),
        T(test_limits_unsigned64_extremes),
        T(test_limits_real32),
        T(test_limits_real64),
        T(test_real_without_limits_accepts_nan),
        T(test_limits_only_min_or_only_max),
        T(test_boolean_accepts_only_0_and_1),
        T(test_read_missing_object_and_missing_sub),
        T(test_read_of_write_only_refused),
        T(test_read_allowed_for_ro_rw_rwr_rww_const),
        T(test_read_in_small_chunks_with_offsets),
        T(test_read_is_a_snapshot_taken_at_begin),
        T(test_read_with_too_small_scratch_out_of_memory),
        T(test_write_of_read_only_and_const_refused),
        T(test_write_allowed_for_wo_rw_rwr_rww),
        T(test_write_missing_object_and_missing_sub),
        T(test_write_announced_too_long_is_length_high),
        T(test_write_numeric_announced_too_short_is_length_low),
        T(test_write_chunk_beyond_size_is_length_high_and_changes_nothing),
        T(test_write_chunk_beyond_announced_total_is_length_high),
        T(test_write_end_short_numeric_is_length_low),
        T(test_write_end_less_than_announced_is_length_low),
        T(test_write_notifies_after_write_network),
        T(test_refused_writes_change_nothing),
        T(test_begin_on_busy_transfer_aborts_the_old_one),
        T(test_calls_in_the_wrong_state_are_refused),
        T(test_subscribe_refuses_bad_range_null_handler_and_full_table),
        T(test_subscription_range_covers_index_sub_keys),
        T(test_before_read_abort_refuses_the_read),
        T(test_before_read_handlers_run_in_subscription_order),
        T(test_before_read_may_refresh_the_value),
        T(test_split_read_resume_ok),
        T(test_split_read_resume_with_abort),
        T(test_split_read_twice),
        T(test_split_write_resume_ok_commits),
        T(test_split_write_resume_with_abort_changes_nothing),
        T(test_abort_while_split_write_changes_nothing),
        T(test_second_check_write_refusing_means_no_change_no_after_write),
        T(test_all_check_writes_run_before_any_after_write),
        T(test_check_write_that_aborts_the_transfer_stops_it),
        cmocka_unit_test(test_cob_id_change_rules),
        T(test_domain_upload_1mib_in_chunks_of_7),
        T(test_domain_upload_1mib_in_chunks_of_60),
        T(test_domain_upload_1mib_in_chunks_of_889_size_unknown),
        T(test_domain_download_1mib_in_chunks_of_7),
        T(test_domain_download_1mib_in_chunks_of_60_size_unknown),
        T(test_domain_download_1mib_in_chunks_of_889),
        T(test_domain_abort_mid_download_notifies_the_writer),
        T(test_domain_abort_with_code_0_reports_general_error),
        T(test_domain_download_beyond_announced_size_tells_the_writer),
        T(test_domain_download_shorter_than_announced_tells_the_writer),
        T(test_domain_writer_refusal_ends_the_transfer),
        T(test_domain_writer_refuses_an_announced_size_at_the_initiate),
        T(test_domain_without_handlers),
        T(test_domain_reader_without_size_handler_has_unknown_size),
        T(test_domain_reader_ending_before_announced_size_aborts),
        cmocka_unit_test(test_group_of),
        T(test_load_defaults_of_the_communication_group),
        T(test_load_defaults_of_the_manufacturer_group),
        T(test_load_defaults_of_the_application_group_restores_strings),
        T(test_load_defaults_tells_only_changed_entries_once),
        T(test_load_defaults_tells_after_all_are_loaded),
        T(test_random_writes_match_a_reference_model),
#undef T
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
