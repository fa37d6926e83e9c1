/* co_store: store and restore of parameters (0x1010 / 0x1011) over an
 * in-memory backend, the image format, damaged / foreign / other-layout
 * images, and a fuzz of the image decoder. */
#include "test_od_util.h"

#include "co_crc.h"

/* ----------------------------------------------------------- test OD */

/* Layout A: stored entries in all three groups, entries without CO_OD_STORE,
 * limits, a string, and 0x1010 / 0x1011 with sub 0..4. */
static const tu_od_row_t layout_a[] = {
    { 0x1008, 0, VAR, VS, AC_CONST, 0, 16, 0, "canopenfd", 0, 0 },
    { 0x1010, 0, ARR, U8, RO, 0, 1, 4, NULL, 0, 0 },
    { 0x1010, 1, ARR, U32, RW, 0, 4, 1, NULL, 0, 0 },
    { 0x1010, 2, ARR, U32, RW, 0, 4, 1, NULL, 0, 0 },
    { 0x1010, 3, ARR, U32, RW, 0, 4, 1, NULL, 0, 0 },
    { 0x1010, 4, ARR, U32, RW, 0, 4, 1, NULL, 0, 0 },
    { 0x1011, 0, ARR, U8, RO, 0, 1, 4, NULL, 0, 0 },
    { 0x1011, 1, ARR, U32, RW, 0, 4, 1, NULL, 0, 0 },
    { 0x1011, 2, ARR, U32, RW, 0, 4, 1, NULL, 0, 0 },
    { 0x1011, 3, ARR, U32, RW, 0, 4, 1, NULL, 0, 0 },
    { 0x1011, 4, ARR, U32, RW, 0, 4, 1, NULL, 0, 0 },
    { 0x1017, 0, VAR, U16, RW, ST, 2, 1000, NULL, 0, 0 },
    { 0x1800, 0, REC, U8, RO, 0, 1, 2, NULL, 0, 0 },
    { 0x1800, 1, REC, U32, RW, ST, 4, 0x181, NULL, 0, 0 },
    { 0x1800, 2, REC, U8, RW, ST, 1, 254, NULL, 0, 0 },
    { 0x2000, 0, VAR, U8, RW, ST | CO_OD_HAS_MAX, 1, 5, NULL, 0, 200 },
    { 0x2001, 0, VAR, VS, RW, ST, 16, 0, "abc", 0, 0 },
    { 0x2002, 0, VAR, I64, RW, ST | MINMAX, 8, -5, NULL, -1000000000000ll, 1000000000000ll },
    { 0x2003, 0, VAR, U32, RW, 0, 4, 7, NULL, 0, 0 },
    { 0x6000, 0, VAR, U16, RW, ST | MINMAX, 2, 100, NULL, 10, 1000 },
    { 0x6001, 0, VAR, U32, RW, 0, 4, 9, NULL, 0, 0 },
    { 0x6002, 0, VAR, I64, RW, ST, 8, 0, NULL, 0, 0 },
};

/* Layout B, "the next firmware": 0x2000 became INTEGER8 (same size, other
 * meaning), 0x2001 shrank to
 * 4 bytes, 0x2002 is gone, 0x6000 got a narrower range, 0x6002 is no longer
 * stored, 0x2005 is new, no 0x1010 / 0x1011. */
static const tu_od_row_t layout_b[] = {
    { 0x1017, 0, VAR, U16, RW, ST, 2, 1000, NULL, 0, 0 },
    { 0x1800, 0, REC, U8, RO, 0, 1, 2, NULL, 0, 0 },
    { 0x1800, 1, REC, U32, RW, ST, 4, 0x181, NULL, 0, 0 },
    { 0x1800, 2, REC, U8, RW, ST, 1, 254, NULL, 0, 0 },
    { 0x2000, 0, VAR, CO_TYPE_INTEGER8, RW, ST, 1, 6, NULL, 0, 0 },
    { 0x2001, 0, VAR, VS, RW, ST, 4, 0, "xy", 0, 0 },
    { 0x2005, 0, VAR, U32, RW, ST, 4, 55, NULL, 0, 0 },
    { 0x6000, 0, VAR, U16, RW, ST | MINMAX, 2, 100, NULL, 10, 200 },
    { 0x6002, 0, VAR, I64, RW, 0, 8, 0, NULL, 0, 0 },
};

#define N_ENTRIES 64
#define POOL 4096
#define SUBS 8
#define BUF 4096

typedef struct fixture {
    co_od_t od;
    co_od_entry_t entries[N_ENTRIES];
    uint8_t pool[POOL];
    co_od_subscription_t subs[SUBS];
    co_store_t store;
    uint8_t buf[BUF];
    tu_mem_backend_t mem;
    unsigned restored;            /* after_write with CO_ORIGIN_RESTORE on 0x2000..0x6FFF */
    unsigned other_origin;
} fixture_t;

static void od_build(fixture_t *fx, const tu_od_row_t *defs, size_t n)
{
    co_od_init(&fx->od, CO_MODE_FD, fx->entries, N_ENTRIES, fx->pool, POOL, fx->subs, SUBS);
    tu_od_add_rows(&fx->od, defs, n);
    assert_true(co_od_seal(&fx->od, 1));
}

static void on_observe(co_od_t *od, const co_od_entry_t *e, co_od_origin_t origin, void *user)
{
    fixture_t *fx = user;
    (void)od;
    (void)e;
    if (origin == CO_ORIGIN_RESTORE)
        fx->restored++;
    else
        fx->other_origin++;
}

static const co_od_handler_t observer = {.after_write = on_observe};

static fixture_t *fixture_new(const tu_od_row_t *defs, size_t n)
{
    fixture_t *fx = calloc(1, sizeof *fx);
    assert_non_null(fx);
    od_build(fx, defs, n);
    assert_true(co_od_subscribe(&fx->od, 0x2000, 0, 0x6FFF, 0xFF, &observer, fx));
    assert_true(co_store_init(&fx->store, &fx->od, &tu_mem_ops, &fx->mem, fx->buf, BUF));
    return fx;
}

static int setup_a(void **state)
{
    *state = fixture_new(layout_a, sizeof layout_a / sizeof layout_a[0]);
    return 0;
}

static int teardown(void **state)
{
    free(*state);
    return 0;
}

static void put_num(fixture_t *fx, uint16_t index, uint8_t sub, int64_t v)
{
    const co_od_entry_t *e = co_od_find(&fx->od, index, sub);
    uint8_t b[8];
    assert_non_null(e);
    tu_le_put(b, (uint64_t)v, e->size);
    assert_int_equal(co_od_put(&fx->od, index, sub, b, e->size), 0);
}

static int64_t get_num(fixture_t *fx, uint16_t index, uint8_t sub)
{
    uint8_t b[8];
    uint32_t n = 0;
    uint64_t v;
    assert_int_equal(co_od_get(&fx->od, index, sub, b, sizeof b, &n), 0);
    assert_true(n >= 1 && n <= 8);
    v = tu_le_get(b, n);
    return (int64_t)v;
}

static void put_str(fixture_t *fx, uint16_t index, const char *s)
{
    assert_int_equal(co_od_put(&fx->od, index, 0, (const uint8_t *)s, (uint32_t)strlen(s)), 0);
}

static void assert_str(fixture_t *fx, uint16_t index, const char *s)
{
    uint8_t b[64];
    uint32_t n = 0;
    assert_int_equal(co_od_get(&fx->od, index, 0, b, sizeof b, &n), 0);
    assert_int_equal(n, strlen(s));
    assert_memory_equal(b, s, n);
}

/* Value sets of the stored (and two unstored) entries of layout A. */
typedef struct vset {
    int64_t hb, cob, tt, m8;
    const char *str;
    int64_t m64, a16, a64;
    int64_t unstored_m, unstored_a;
} vset_t;

static const vset_t DEF = { 1000, 0x181, 254, 5, "abc", -5, 100, 0, 7, 9 };
static const vset_t VA = { 1500, 0x182, 1, 150, "hello world", -123456789012ll, 500,
                           0x1122334455667788ll, 70, 90 };
static const vset_t VB = { 2000, 0x183, 2, 151, "x", 42, 501, -1, 71, 91 };
static const vset_t VC = { 2500, 0x184, 3, 152, "", 43, 502, -2, 72, 92 };

static void set_values(fixture_t *fx, const vset_t *v)
{
    put_num(fx, 0x1017, 0, v->hb);
    put_num(fx, 0x1800, 1, v->cob);
    put_num(fx, 0x1800, 2, v->tt);
    put_num(fx, 0x2000, 0, v->m8);
    put_str(fx, 0x2001, v->str);
    put_num(fx, 0x2002, 0, v->m64);
    put_num(fx, 0x2003, 0, v->unstored_m);
    put_num(fx, 0x6000, 0, v->a16);
    put_num(fx, 0x6001, 0, v->unstored_a);
    put_num(fx, 0x6002, 0, v->a64);
}

static void expect_comm(fixture_t *fx, const vset_t *v)
{
    assert_int_equal(get_num(fx, 0x1017, 0), v->hb);
    assert_int_equal(get_num(fx, 0x1800, 1), v->cob);
    assert_int_equal(get_num(fx, 0x1800, 2), v->tt);
}

static void expect_manuf(fixture_t *fx, const vset_t *v)
{
    assert_int_equal(get_num(fx, 0x2000, 0), v->m8);
    assert_str(fx, 0x2001, v->str);
    assert_true(get_num(fx, 0x2002, 0) == v->m64);
}

static void expect_app(fixture_t *fx, const vset_t *v)
{
    assert_int_equal(get_num(fx, 0x6000, 0), v->a16);
    assert_true(get_num(fx, 0x6002, 0) == v->a64);
}

static void expect_all(fixture_t *fx, const vset_t *v)
{
    expect_comm(fx, v);
    expect_manuf(fx, v);
    expect_app(fx, v);
}

/* ------------------------------------------------- network access (SDO) */

static uint32_t net_write_u32(fixture_t *fx, uint16_t index, uint8_t sub, uint32_t v)
{
    return tu_od_net_write_u32(&fx->od, index, sub, v);
}

static uint32_t net_read_u32(fixture_t *fx, uint16_t index, uint8_t sub, uint32_t *out)
{
    return tu_od_net_read_u32(&fx->od, index, sub, out);
}

/* --------------------------------------------------------- image access */

#define HDR 28

static uint32_t img_u32(const uint8_t *img, uint32_t off)
{
    return (uint32_t)tu_le_get(img + off, 4);
}

/* Recompute the CRC of an image edited on purpose (so that the edit, not the
 * CRC, is what the decoder sees). */
static void img_fix_crc(uint8_t *img, uint32_t length)
{
    uint32_t crc;
    assert_true(length >= HDR);
    crc = co_crc32(0, img, 24);
    crc = co_crc32(crc, img + HDR, length - HDR);
    tu_le_put(img + 24, crc, 4);
}

/* Offset of the record with this key in a valid image, or 0. */
static uint32_t img_find(const uint8_t *img, uint32_t length, uint32_t key)
{
    uint32_t pos = HDR;
    while (pos + 9 <= length) {
        if (img_u32(img, pos) == key)
            return pos;
        pos += 9 + img_u32(img, pos + 5);
    }
    return 0;
}

static co_store_status_t load_image(fixture_t *fx, const uint8_t *img, uint32_t length)
{
    tu_mem_set(&fx->mem, img, length);
    return co_store_load(&fx->store, CO_GROUP_ALL);
}

/* ---------------------------------------------------------------- tests */

static void test_crc32(void **state)
{
    const uint8_t *s = (const uint8_t *)"123456789";
    (void)state;
    assert_int_equal(co_crc32(0, s, 9), 0xCBF43926u);
    assert_int_equal(co_crc32(co_crc32(0, s, 3), s + 3, 6), 0xCBF43926u);
    assert_int_equal(co_crc32(0, s, 0), 0);
}

static void test_image_need(void **state)
{
    fixture_t *fx = *state;
    /* 8 stored entries: sizes 2 + 4 + 1 + 1 + 16 + 8 + 2 + 8 */
    assert_int_equal(co_store_image_need(&fx->od), HDR + 8 * 9 + 42);
}

static void test_init_arguments(void **state)
{
    fixture_t *fx = *state;
    co_store_t s;
    uint32_t need = co_store_image_need(&fx->od);
    co_store_backend_t half = { tu_mem_save, NULL };
    assert_false(co_store_init(&s, &fx->od, &tu_mem_ops, &fx->mem, fx->buf, 2 * need - 1));
    assert_false(co_store_init(&s, &fx->od, NULL, &fx->mem, fx->buf, BUF));
    assert_false(co_store_init(&s, &fx->od, &half, &fx->mem, fx->buf, BUF));
    assert_false(co_store_init(&s, &fx->od, &tu_mem_ops, &fx->mem, NULL, BUF));
    assert_false(co_store_init(NULL, &fx->od, &tu_mem_ops, &fx->mem, fx->buf, BUF));
    assert_int_equal(fx->store.last_load, CO_STORE_EMPTY);
    assert_int_equal(fx->store.image_capacity, BUF / 2);
}

static void test_init_unsealed_or_full(void **state)
{
    fixture_t *fx = calloc(1, sizeof *fx);
    (void)state;
    assert_non_null(fx);
    co_od_init(&fx->od, CO_MODE_FD, fx->entries, N_ENTRIES, fx->pool, POOL, fx->subs, 1);
    tu_od_add_rows(&fx->od, layout_a, sizeof layout_a / sizeof layout_a[0]);
    assert_false(co_store_init(&fx->store, &fx->od, &tu_mem_ops, &fx->mem, fx->buf, BUF));
    assert_true(co_od_seal(&fx->od, 1));
    /* 0x1010 and 0x1011 need two subscriptions, the table has one: nothing
     * is hooked at all. */
    assert_false(co_store_init(&fx->store, &fx->od, &tu_mem_ops, &fx->mem, fx->buf, BUF));
    assert_int_equal(fx->od.sub_count, 0);
    free(fx);
}

static void test_without_1010_1011(void **state)
{
    fixture_t *fx = fixture_new(layout_b, sizeof layout_b / sizeof layout_b[0]);
    (void)state;
    assert_int_equal(fx->od.sub_count, 1);   /* the observer only */
    put_num(fx, 0x2005, 0, 99);
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_ALL), 0);
    put_num(fx, 0x2005, 0, 98);
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_OK);
    assert_int_equal(get_num(fx, 0x2005, 0), 99);
    free(fx);
}

static void test_load_empty(void **state)
{
    fixture_t *fx = *state;
    set_values(fx, &VA);
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_EMPTY);
    assert_int_equal(fx->store.last_load, CO_STORE_EMPTY);
    expect_all(fx, &DEF);
    assert_int_equal(get_num(fx, 0x2003, 0), 7);
}

static void test_save_load_roundtrip(void **state)
{
    fixture_t *fx = *state;
    set_values(fx, &VA);
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_ALL), 0);
    assert_int_equal(fx->mem.saves, 1);
    assert_int_equal(fx->mem.loads, 0);   /* saving everything reads nothing */
    set_values(fx, &VB);
    fx->restored = 0;
    fx->other_origin = 0;
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_OK);
    assert_int_equal(fx->store.last_load, CO_STORE_OK);
    assert_int_equal(fx->store.records_skipped, 0);
    expect_all(fx, &VA);
    /* not stored: back to the defaults */
    assert_int_equal(get_num(fx, 0x2003, 0), 7);
    assert_int_equal(get_num(fx, 0x6001, 0), 9);
    /* the 5 stored entries of 0x2000..0x6FFF were told as restored (defaults
     * may have told them too) */
    assert_true(fx->restored >= 5);
    assert_int_equal(fx->other_origin, 0);
}

static void test_image_format(void **state)
{
    fixture_t *fx = *state;
    const uint8_t *img = fx->mem.data;
    uint32_t pos, i, last = 0, sig = 0;
    uint8_t b[9];
    set_values(fx, &VA);
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_ALL), 0);
    assert_memory_equal(img, "CoFDpar\0", 8);
    assert_int_equal(tu_le_get(img + 8, 2), 1);
    assert_int_equal(tu_le_get(img + 10, 2), HDR);
    for (i = 0; i < fx->od.count; i++) {
        const co_od_entry_t *e = &fx->od.entries[i];
        if (!(e->flags & CO_OD_STORE))
            continue;
        tu_le_put(b, e->key, 4);
        b[4] = e->type;
        tu_le_put(b + 5, e->size, 4);
        sig = co_crc32(sig, b, 9);
    }
    assert_int_equal(img_u32(img, 12), sig);
    assert_int_equal(img_u32(img, 16), 8);
    assert_int_equal(img_u32(img, 20), fx->mem.length - HDR);
    assert_int_equal(img_u32(img, 24),
                     co_crc32(co_crc32(0, img, 24), img + HDR, fx->mem.length - HDR));
    /* full record walk: ascending keys, exact lengths */
    pos = HDR;
    for (i = 0; i < 8; i++) {
        uint32_t key = img_u32(img, pos);
        assert_true(key > last);
        last = key;
        pos += 9 + img_u32(img, pos + 5);
    }
    assert_int_equal(pos, fx->mem.length);
    /* first record: 0x1017:00 UNSIGNED16 1500 */
    {
        static const uint8_t rec[] = { 0x00, 0x17, 0x10, 0x00, 0x06, 0x02, 0, 0, 0, 0xDC, 0x05 };
        assert_memory_equal(img + HDR, rec, sizeof rec);
    }
    /* a string record carries its current length, not the capacity */
    pos = img_find(img, fx->mem.length, 0x200100);
    assert_int_not_equal(pos, 0);
    assert_int_equal(img[pos + 4], VS);
    assert_int_equal(img_u32(img, pos + 5), 11);
    assert_memory_equal(img + pos + 9, "hello world", 11);
    assert_true(fx->mem.length <= co_store_image_need(&fx->od));
}

static void test_save_groups_keep_others(void **state)
{
    fixture_t *fx = *state;
    set_values(fx, &VA);
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_ALL), 0);
    set_values(fx, &VB);
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_COMMUNICATION), 0);
    set_values(fx, &VC);
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_APPLICATION), 0);
    set_values(fx, &DEF);
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_OK);
    expect_comm(fx, &VB);
    expect_app(fx, &VC);
    expect_manuf(fx, &VA);
    assert_int_equal(img_u32(fx->mem.data, 16), 8);
    /* a partial save over nothing saved: only that group */
    memset(&fx->mem, 0, sizeof fx->mem);
    set_values(fx, &VB);
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_MANUFACTURER), 0);
    assert_int_equal(img_u32(fx->mem.data, 16), 3);
    set_values(fx, &VC);
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_OK);
    expect_manuf(fx, &VB);
    expect_comm(fx, &DEF);
    expect_app(fx, &DEF);
}

static void test_save_over_bad_previous(void **state)
{
    fixture_t *fx = *state;
    set_values(fx, &VA);
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_ALL), 0);
    /* damaged previous image: nothing of it could load, nothing is kept */
    fx->mem.data[HDR + 10] ^= 0x40;
    set_values(fx, &VB);
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_APPLICATION), 0);
    assert_int_equal(img_u32(fx->mem.data, 16), 2);
    /* previous unreadable: a partial save refuses (it would drop the other
     * groups), a full save does not need it */
    fx->mem.force_load = true;
    fx->mem.load_status = CO_STORE_IO;
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_COMMUNICATION), CO_ABORT_HARDWARE);
    assert_int_equal(co_store_restore_defaults(&fx->store, CO_GROUP_COMMUNICATION),
                     CO_ABORT_HARDWARE);
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_ALL), 0);
    fx->mem.force_load = false;
    set_values(fx, &VC);
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_OK);
    expect_all(fx, &VB);
    /* backend save failure */
    fx->mem.fail_save = true;
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_ALL), CO_ABORT_HARDWARE);
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_APPLICATION), CO_ABORT_HARDWARE);
    assert_int_equal(co_store_restore_defaults(&fx->store, CO_GROUP_ALL), CO_ABORT_HARDWARE);
}

static void test_restore_defaults(void **state)
{
    fixture_t *fx = *state;
    set_values(fx, &VA);
    /* nothing saved: nothing to forget, the medium is not written */
    assert_int_equal(co_store_restore_defaults(&fx->store, CO_GROUP_ALL), 0);
    assert_int_equal(fx->mem.saves, 0);
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_ALL), 0);
    assert_int_equal(co_store_restore_defaults(&fx->store, CO_GROUP_APPLICATION), 0);
    /* the defaults come at the next reset, not now */
    expect_all(fx, &VA);
    set_values(fx, &VB);
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_OK);
    expect_comm(fx, &VA);
    expect_manuf(fx, &VA);
    expect_app(fx, &DEF);
    assert_int_equal(co_store_restore_defaults(&fx->store, CO_GROUP_ALL), 0);
    assert_int_equal(fx->mem.length, HDR);   /* an image with zero records */
    assert_int_equal(img_u32(fx->mem.data, 16), 0);
    set_values(fx, &VB);
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_OK);
    expect_all(fx, &DEF);
    /* a damaged image is replaced by an empty one */
    fx->mem.data[3] ^= 1;
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_FOREIGN);
    assert_int_equal(co_store_restore_defaults(&fx->store, CO_GROUP_COMMUNICATION), 0);
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_OK);
}

static void test_load_some_groups(void **state)
{
    fixture_t *fx = *state;
    set_values(fx, &VA);
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_ALL), 0);
    set_values(fx, &VB);
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_COMMUNICATION), CO_STORE_OK);
    expect_comm(fx, &VA);
    expect_manuf(fx, &VB);
    expect_app(fx, &VB);
    assert_int_equal(get_num(fx, 0x2003, 0), 71);   /* not loaded, not reset */
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_APPLICATION | CO_GROUP_MANUFACTURER),
                     CO_STORE_OK);
    expect_all(fx, &VA);
    assert_int_equal(get_num(fx, 0x2003, 0), 7);
    assert_int_equal(fx->store.records_skipped, 0);
}

static void test_1010_1011_read_capability(void **state)
{
    fixture_t *fx = *state;
    uint32_t v = 0;
    uint8_t sub;
    for (sub = 1; sub <= 4; sub++) {
        put_num(fx, 0x1010, sub, 0x12345678);   /* whatever the value says */
        assert_int_equal(net_read_u32(fx, 0x1010, sub, &v), 0);
        assert_int_equal(v, 1);
        assert_int_equal(net_read_u32(fx, 0x1011, sub, &v), 0);
        assert_int_equal(v, 1);
    }
    assert_int_equal(get_num(fx, 0x1010, 0), 4);
    assert_int_equal(net_write_u32(fx, 0x1010, 1, CO_STORE_SAVE_SIGNATURE), 0);
    assert_int_equal(net_read_u32(fx, 0x1010, 1, &v), 0);
    assert_int_equal(v, 1);
}

static void test_1010_save_by_network(void **state)
{
    fixture_t *fx = *state;
    set_values(fx, &VA);
    assert_int_equal(net_write_u32(fx, 0x1010, 1, 0x65766172), CO_ABORT_DATA_STORE);
    assert_int_equal(net_write_u32(fx, 0x1010, 1, CO_STORE_LOAD_SIGNATURE), CO_ABORT_DATA_STORE);
    assert_int_equal(net_write_u32(fx, 0x1010, 2, 0), CO_ABORT_DATA_STORE);
    assert_int_equal(fx->mem.saves, 0);
    assert_int_equal(net_write_u32(fx, 0x1010, 1, CO_STORE_SAVE_SIGNATURE), 0);
    assert_int_equal(fx->mem.saves, 1);
    /* sub 2 = communication, 3 = application, 4 = manufacturer */
    set_values(fx, &VB);
    assert_int_equal(net_write_u32(fx, 0x1010, 2, CO_STORE_SAVE_SIGNATURE), 0);
    set_values(fx, &VC);
    assert_int_equal(net_write_u32(fx, 0x1010, 3, CO_STORE_SAVE_SIGNATURE), 0);
    set_values(fx, &DEF);
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_OK);
    expect_comm(fx, &VB);
    expect_app(fx, &VC);
    expect_manuf(fx, &VA);
    set_values(fx, &VB);
    assert_int_equal(net_write_u32(fx, 0x1010, 4, CO_STORE_SAVE_SIGNATURE), 0);
    set_values(fx, &DEF);
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_OK);
    expect_comm(fx, &VB);
    expect_app(fx, &VC);
    expect_manuf(fx, &VB);
    /* the backend fails: the writer hears it */
    fx->mem.fail_save = true;
    assert_int_equal(net_write_u32(fx, 0x1010, 1, CO_STORE_SAVE_SIGNATURE), CO_ABORT_HARDWARE);
}

static void test_1011_restore_by_network(void **state)
{
    fixture_t *fx = *state;
    set_values(fx, &VA);
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_ALL), 0);
    assert_int_equal(net_write_u32(fx, 0x1011, 1, CO_STORE_SAVE_SIGNATURE), CO_ABORT_DATA_STORE);
    assert_int_equal(net_write_u32(fx, 0x1011, 3, 1), CO_ABORT_DATA_STORE);
    assert_int_equal(net_write_u32(fx, 0x1011, 4, CO_STORE_LOAD_SIGNATURE), 0);
    expect_all(fx, &VA);   /* at the next reset, not now */
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_OK);
    expect_comm(fx, &VA);
    expect_app(fx, &VA);
    expect_manuf(fx, &DEF);
    assert_int_equal(net_write_u32(fx, 0x1011, 2, CO_STORE_LOAD_SIGNATURE), 0);
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_OK);
    expect_comm(fx, &DEF);
    expect_app(fx, &VA);
    assert_int_equal(net_write_u32(fx, 0x1011, 1, CO_STORE_LOAD_SIGNATURE), 0);
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_OK);
    expect_all(fx, &DEF);
    fx->mem.force_load = true;
    fx->mem.load_status = CO_STORE_IO;
    assert_int_equal(net_write_u32(fx, 0x1011, 1, CO_STORE_LOAD_SIGNATURE), CO_ABORT_HARDWARE);
}

/* Every single-byte change of a valid image is noticed: nothing loads. */
static void test_every_byte_flip(void **state)
{
    fixture_t *fx = *state;
    uint8_t img[512];
    uint32_t len, i;
    set_values(fx, &VA);
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_ALL), 0);
    len = fx->mem.length;
    memcpy(img, fx->mem.data, len);
    for (i = 0; i < len; i++) {
        uint8_t bit;
        for (bit = 0; bit < 8; bit++) {
            co_store_status_t st;
            img[i] ^= (uint8_t)(1u << bit);
            set_values(fx, &VB);
            st = load_image(fx, img, len);
            if (i < 10)
                assert_int_equal(st, CO_STORE_FOREIGN);   /* magic or version */
            else
                assert_int_equal(st, CO_STORE_DAMAGED);
            assert_int_equal(fx->store.last_load, st);
            expect_all(fx, &DEF);
            img[i] ^= (uint8_t)(1u << bit);
        }
    }
    assert_int_equal(load_image(fx, img, len), CO_STORE_OK);
    expect_all(fx, &VA);
}

static void test_every_truncation(void **state)
{
    fixture_t *fx = *state;
    uint32_t len, i;
    set_values(fx, &VA);
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_ALL), 0);
    len = fx->mem.length;
    for (i = 0; i < len; i++) {
        fx->mem.length = i;
        set_values(fx, &VB);
        assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_DAMAGED);
        expect_all(fx, &DEF);
    }
    /* one byte too many */
    fx->mem.length = len + 1;
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_DAMAGED);
}

static void test_foreign(void **state)
{
    fixture_t *fx = *state;
    uint8_t img[512];
    uint32_t len;
    set_values(fx, &VA);
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_ALL), 0);
    len = fx->mem.length;
    memcpy(img, fx->mem.data, len);
    img[0] = 'X';
    img_fix_crc(img, len);
    assert_int_equal(load_image(fx, img, len), CO_STORE_FOREIGN);
    expect_all(fx, &DEF);
    memcpy(img, fx->mem.data, len);
    tu_le_put(img + 8, 2, 2);   /* version 2 */
    img_fix_crc(img, len);
    assert_int_equal(load_image(fx, img, len), CO_STORE_FOREIGN);
    assert_int_equal(fx->store.last_load, CO_STORE_FOREIGN);
    /* a short file that is not ours at all */
    assert_int_equal(load_image(fx, (const uint8_t *)"#!/bin/sh\n", 10), CO_STORE_FOREIGN);
    assert_int_equal(load_image(fx, (const uint8_t *)"CoFD", 4), CO_STORE_DAMAGED);
}

typedef void (*edit_fn)(uint8_t *img, uint32_t *len);

static void edit_swap_records(uint8_t *img, uint32_t *len)
{
    /* the first two records are 0x1017:00 (11 bytes) and 0x1800:01 (13) */
    uint8_t tmp[24];
    (void)len;
    memcpy(tmp, img + HDR + 11, 13);
    memcpy(tmp + 13, img + HDR, 11);
    memcpy(img + HDR, tmp, 24);
}

static void edit_duplicate_key(uint8_t *img, uint32_t *len)
{
    (void)len;
    tu_le_put(img + HDR + 11, 0x101700, 4);
}

static void edit_count_plus(uint8_t *img, uint32_t *len)
{
    (void)len;
    tu_le_put(img + 16, img_u32(img, 16) + 1, 4);
}

static void edit_count_minus(uint8_t *img, uint32_t *len)
{
    (void)len;
    tu_le_put(img + 16, img_u32(img, 16) - 1, 4);
}

static void edit_count_huge(uint8_t *img, uint32_t *len)
{
    (void)len;
    tu_le_put(img + 16, 0xFFFFFFFFu, 4);
}

static void edit_trailing(uint8_t *img, uint32_t *len)
{
    img[*len] = 0;
    *len += 1;
    tu_le_put(img + 20, *len - HDR, 4);
}

static void edit_record_too_long(uint8_t *img, uint32_t *len)
{
    tu_le_put(img + HDR + 5, *len, 4);
}

static void edit_record_huge(uint8_t *img, uint32_t *len)
{
    (void)len;
    tu_le_put(img + HDR + 5, 0xFFFFFFF7u, 4);
}

static void edit_payload_length(uint8_t *img, uint32_t *len)
{
    tu_le_put(img + 20, *len - HDR - 1, 4);
}

static void edit_header_short(uint8_t *img, uint32_t *len)
{
    (void)len;
    tu_le_put(img + 10, 27, 2);
}

static void edit_header_huge(uint8_t *img, uint32_t *len)
{
    (void)len;
    tu_le_put(img + 10, 0xFFFF, 2);
}

static void edit_key_wide(uint8_t *img, uint32_t *len)
{
    /* the last record's key gets bits above 24: still ascending */
    uint32_t pos = img_find(img, *len, 0x600200);
    assert_int_not_equal(pos, 0);
    tu_le_put(img + pos, 0x01600200, 4);
}

/* Malformed images with a valid CRC: the structure checks catch them. */
static void test_malformed_records(void **state)
{
    fixture_t *fx = *state;
    static const edit_fn edits[] = {
        edit_swap_records, edit_duplicate_key, edit_count_plus, edit_count_minus,
        edit_count_huge, edit_trailing, edit_record_too_long, edit_record_huge,
        edit_payload_length, edit_header_short, edit_header_huge, edit_key_wide
    };
    uint8_t orig[512], img[512];
    uint32_t orig_len, len, i;
    set_values(fx, &VA);
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_ALL), 0);
    orig_len = fx->mem.length;
    memcpy(orig, fx->mem.data, orig_len);
    assert_int_equal(img_u32(orig, HDR), 0x101700);
    assert_int_equal(img_u32(orig, HDR + 11), 0x180001);
    for (i = 0; i < sizeof edits / sizeof edits[0]; i++) {
        len = orig_len;
        memcpy(img, orig, len);
        edits[i](img, &len);
        img_fix_crc(img, len);
        set_values(fx, &VB);
        if (load_image(fx, img, len) != CO_STORE_DAMAGED)
            fail_msg("edit %u was not refused", i);
        expect_all(fx, &DEF);
    }
    /* the unedited image loads */
    assert_int_equal(load_image(fx, orig, orig_len), CO_STORE_OK);
    expect_all(fx, &VA);
}

/* A later minor format may append header fields: the records start at the
 * header length. */
static void test_longer_header(void **state)
{
    fixture_t *fx = *state;
    uint8_t img[512];
    uint32_t len;
    set_values(fx, &VA);
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_ALL), 0);
    len = fx->mem.length;
    memcpy(img, fx->mem.data, HDR);
    memset(img + HDR, 0xEE, 4);
    memcpy(img + HDR + 4, fx->mem.data + HDR, len - HDR);
    tu_le_put(img + 10, HDR + 4, 2);
    img_fix_crc(img, len + 4);
    set_values(fx, &VB);
    assert_int_equal(load_image(fx, img, len + 4), CO_STORE_OK);
    expect_all(fx, &VA);
}

/* An image of layout A loaded by layout B: records are applied one by one. */
static void test_other_od_layout(void **state)
{
    fixture_t *fa = *state;
    fixture_t *fb = fixture_new(layout_b, sizeof layout_b / sizeof layout_b[0]);
    set_values(fa, &VA);
    put_num(fa, 0x6000, 0, 300);   /* outside B's 10..200 */
    assert_int_equal(co_store_save(&fa->store, CO_GROUP_ALL), 0);
    assert_true(fa->mem.length <= fb->store.image_capacity);
    put_num(fb, 0x2005, 0, 1);
    put_num(fb, 0x1017, 0, 1);
    tu_mem_set(&fb->mem, fa->mem.data, fa->mem.length);
    assert_int_equal(co_store_load(&fb->store, CO_GROUP_ALL), CO_STORE_OK);
    /* applied: 0x1017, 0x1800:1, 0x1800:2 */
    assert_int_equal(get_num(fb, 0x1017, 0), VA.hb);
    assert_int_equal(get_num(fb, 0x1800, 1), VA.cob);
    assert_int_equal(get_num(fb, 0x1800, 2), VA.tt);
    /* skipped: 0x2000 (other type), 0x2001 (too long), 0x2002 (gone),
     * 0x6000 (refused by the limits), 0x6002 (not stored any more) */
    assert_int_equal(fb->store.records_skipped, 5);
    assert_int_equal(get_num(fb, 0x2000, 0), 6);
    assert_str(fb, 0x2001, "xy");
    assert_int_equal(get_num(fb, 0x6000, 0), 100);
    assert_int_equal(get_num(fb, 0x2005, 0), 55);   /* new entry: its default */
    /* only the groups asked for are looked at */
    assert_int_equal(co_store_load(&fb->store, CO_GROUP_COMMUNICATION), CO_STORE_OK);
    assert_int_equal(fb->store.records_skipped, 0);
    assert_int_equal(co_store_load(&fb->store, CO_GROUP_APPLICATION), CO_STORE_OK);
    assert_int_equal(fb->store.records_skipped, 2);
    /* a partial save in B keeps only what B can use: the next image has no
     * records B would skip */
    assert_int_equal(co_store_save(&fb->store, CO_GROUP_MANUFACTURER), 0);
    /* 3 comm records kept, 3 manuf saved, the app record (300) dropped */
    assert_int_equal(img_u32(fb->mem.data, 16), 3 + 3);
    assert_int_equal(co_store_load(&fb->store, CO_GROUP_ALL), CO_STORE_OK);
    assert_int_equal(fb->store.records_skipped, 0);
    assert_int_equal(get_num(fb, 0x1017, 0), VA.hb);
    free(fb);
}

static void test_backend_statuses(void **state)
{
    fixture_t *fx = *state;
    static const co_store_status_t given[] = { CO_STORE_TOO_BIG, CO_STORE_IO, CO_STORE_EMPTY,
                                               CO_STORE_DAMAGED, CO_STORE_FOREIGN };
    static const co_store_status_t seen[] = { CO_STORE_TOO_BIG, CO_STORE_IO, CO_STORE_EMPTY,
                                              CO_STORE_IO, CO_STORE_IO };
    size_t i;
    set_values(fx, &VA);
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_ALL), 0);
    fx->mem.force_load = true;
    for (i = 0; i < sizeof given / sizeof given[0]; i++) {
        fx->mem.load_status = given[i];
        set_values(fx, &VB);
        assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), seen[i]);
        assert_int_equal(fx->store.last_load, seen[i]);
        expect_all(fx, &DEF);
    }
    fx->mem.force_load = false;
    fx->mem.lie_length = true;
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_IO);
    fx->mem.lie_length = false;
    /* larger than the buffer's half: the backend says so */
    fx->mem.length = fx->store.image_capacity + 1;
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_TOO_BIG);
    expect_all(fx, &DEF);
}

/* ------------------------------------------------------------------ fuzz */

static void fuzz_mutate(uint8_t *img, uint32_t *len, uint32_t cap, uint64_t *rng)
{
    uint32_t ops = 1 + (uint32_t)(tu_rand(rng) % 3), k;
    for (k = 0; k < ops; k++) {
        uint32_t n = *len;
        uint32_t at = n > 0 ? (uint32_t)(tu_rand(rng) % n) : 0;
        switch (tu_rand(rng) % 8) {
        case 0:   /* flip a bit */
            if (n > 0)
                img[at] ^= (uint8_t)(1u << (tu_rand(rng) % 8));
            break;
        case 1:   /* a random byte, preferably in the records */
            if (n > HDR)
                img[HDR + tu_rand(rng) % (n - HDR)] = (uint8_t)tu_rand(rng);
            break;
        case 2:   /* truncate */
            *len = n > 0 ? (uint32_t)(tu_rand(rng) % n) : 0;
            break;
        case 3:   /* insert random bytes */
        {
            uint32_t m = 1 + (uint32_t)(tu_rand(rng) % 8), i;
            if (n + m > cap)
                break;
            memmove(img + at + m, img + at, n - at);
            for (i = 0; i < m; i++)
                img[at + i] = (uint8_t)tu_rand(rng);
            *len = n + m;
            break;
        }
        case 4:   /* an interesting 32-bit value anywhere */
        {
            static const uint32_t vals[] = { 0, 1, 0x7F, 0xFF, 0xFFFF, 0x7FFFFFFF, 0x80000000u,
                                             0xFFFFFFFFu, 0xFFFFFFF7u, 9 };
            if (n >= 4)
                tu_le_put(img + (at > n - 4 ? n - 4 : at), vals[tu_rand(rng) % 10], 4);
            break;
        }
        case 5:   /* a record's type byte */
            if (n > HDR + 4)
                img[HDR + 4] = (uint8_t)(tu_rand(rng) % 0x20);
            break;
        case 6:   /* delete bytes */
        {
            uint32_t m = 1 + (uint32_t)(tu_rand(rng) % 8);
            if (at + m > n)
                break;
            memmove(img + at, img + at + m, n - at - m);
            *len = n - m;
            break;
        }
        default:   /* change a value byte (the last 16 bytes hold values) */
            if (n > 16)
                img[n - 1 - tu_rand(rng) % 16] = (uint8_t)tu_rand(rng);
            break;
        }
    }
}

/* 100 000 random mutations of valid images: the decoder never reads out of
 * bounds (ASan/UBSan) and no value that fails co_od_check_value ever lands in
 * the OD. Half of the mutants get their CRC (and payload length) repaired so
 * the record checks, not the CRC, are what stops them. */
static void test_fuzz_load(void **state)
{
    fixture_t *fx = *state;
    uint8_t base[3][512], img[600];
    uint32_t base_len[3], iter, i;
    uint64_t rng = 0x5EED5EEDull;
    unsigned count[6] = { 0, 0, 0, 0, 0, 0 };
    unsigned changed = 0;
    const vset_t *sets[3] = { &VA, &VB, &VC };

    for (i = 0; i < 3; i++) {
        set_values(fx, sets[i]);
        assert_int_equal(co_store_save(&fx->store, CO_GROUP_ALL), 0);
        base_len[i] = fx->mem.length;
        memcpy(base[i], fx->mem.data, base_len[i]);
    }
    for (iter = 0; iter < 100000; iter++) {
        uint32_t which = (uint32_t)(tu_rand(&rng) % 3), len = base_len[which];
        co_store_status_t st;
        memcpy(img, base[which], len);
        fuzz_mutate(img, &len, sizeof img, &rng);
        if ((tu_rand(&rng) & 1) && len >= HDR) {
            if (tu_rand(&rng) & 1)
                tu_le_put(img + 20, len - (uint32_t)tu_le_get(img + 10, 2), 4);
            img_fix_crc(img, len);
        }
        tu_mem_set(&fx->mem, img, len);
        st = co_store_load(&fx->store, CO_GROUP_ALL);
        assert_true(st == CO_STORE_OK || st == CO_STORE_DAMAGED || st == CO_STORE_FOREIGN);
        count[st]++;
        /* every value in the OD passes its own checks */
        for (i = 0; i < fx->od.count; i++) {
            const co_od_entry_t *e = &fx->od.entries[i];
            if (e->size == 0)
                continue;
            assert_true(e->length <= e->size);
            if (co_od_check_value(&fx->od, e, co_od_value(&fx->od, e), e->length) != 0)
                fail_msg("iteration %u: 0x%06X holds a value its checks refuse", iter, e->key);
        }
        if (st != CO_STORE_OK) {
            expect_all(fx, &DEF);
        } else if (get_num(fx, 0x2000, 0) != 5 && get_num(fx, 0x2000, 0) != VA.m8 &&
                   get_num(fx, 0x2000, 0) != VB.m8 && get_num(fx, 0x2000, 0) != VC.m8) {
            changed++;   /* a mutated value that passed the checks */
        }
    }
    print_message("fuzz: ok %u damaged %u foreign %u, mutated values loaded %u\n",
                  count[CO_STORE_OK], count[CO_STORE_DAMAGED], count[CO_STORE_FOREIGN], changed);
    /* the repaired half reaches the record checks and loads */
    assert_true(count[CO_STORE_OK] > 1000);
    assert_true(count[CO_STORE_DAMAGED] > 1000);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_crc32),
        cmocka_unit_test_setup_teardown(test_image_need, setup_a, teardown),
        cmocka_unit_test_setup_teardown(test_init_arguments, setup_a, teardown),
        cmocka_unit_test(test_init_unsealed_or_full),
        cmocka_unit_test(test_without_1010_1011),
        cmocka_unit_test_setup_teardown(test_load_empty, setup_a, teardown),
        cmocka_unit_test_setup_teardown(test_save_load_roundtrip, setup_a, teardown),
        cmocka_unit_test_setup_teardown(test_image_format, setup_a, teardown),
        cmocka_unit_test_setup_teardown(test_save_groups_keep_others, setup_a, teardown),
        cmocka_unit_test_setup_teardown(test_save_over_bad_previous, setup_a, teardown),
        cmocka_unit_test_setup_teardown(test_restore_defaults, setup_a, teardown),
        cmocka_unit_test_setup_teardown(test_load_some_groups, setup_a, teardown),
        cmocka_unit_test_setup_teardown(test_1010_1011_read_capability, setup_a, teardown),
        cmocka_unit_test_setup_teardown(test_1010_save_by_network, setup_a, teardown),
        cmocka_unit_test_setup_teardown(test_1011_restore_by_network, setup_a, teardown),
        cmocka_unit_test_setup_teardown(test_every_byte_flip, setup_a, teardown),
        cmocka_unit_test_setup_teardown(test_every_truncation, setup_a, teardown),
        cmocka_unit_test_setup_teardown(test_foreign, setup_a, teardown),
        cmocka_unit_test_setup_teardown(test_malformed_records, setup_a, teardown),
        cmocka_unit_test_setup_teardown(test_longer_header, setup_a, teardown),
        cmocka_unit_test_setup_teardown(test_other_od_layout, setup_a, teardown),
        cmocka_unit_test_setup_teardown(test_backend_statuses, setup_a, teardown),
        cmocka_unit_test_setup_teardown(test_fuzz_load, setup_a, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
