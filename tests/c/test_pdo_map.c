/* PDO mapping (co_pdo_map): entry checks against the OD (exists, mappable
 * that way, readable / writable, length, dummies, byte-wise on fd), compile
 * of a whole mapping object (count, total length, copy positions), and the
 * copy both ways (byte-aligned, bit-wise on classic, partial objects,
 * strings). */
#include "test_od_util.h"

#include "canopenfd/co_pdo_map.h"

#define N_ENTRIES 64
#define POOL 2048
#define MAP(i, s, bits) (((uint32_t)(i) << 16) | ((uint32_t)(s) << 8) | (uint32_t)(bits))
#define MAP_OBJ 0x1600

typedef struct fx {
    co_od_t od;
    co_od_entry_t entries[N_ENTRIES];
    uint8_t pool[POOL];
    co_od_subscription_t subs[2];
} fx_t;

#define TP CO_OD_MAP_TPDO
#define RP CO_OD_MAP_RPDO
#define BOTH (CO_OD_MAP_TPDO | CO_OD_MAP_RPDO)

static const tu_od_row_t rows[] = {
    {0x2000, 0, VAR, U8, RW, BOTH, 1, 0x11, NULL, 0, 0},
    {0x2001, 0, VAR, U16, RW, BOTH, 2, 0x2222, NULL, 0, 0},
    {0x2002, 0, VAR, U32, RW, BOTH, 4, 0x33333333, NULL, 0, 0},
    {0x2003, 0, VAR, U32, RO, TP, 4, 0x44444444, NULL, 0, 0},     /* TPDO only, read-only */
    {0x2004, 0, VAR, U32, CO_ACCESS_WO, RP, 4, 0, NULL, 0, 0},     /* RPDO only, write-only */
    {0x2005, 0, VAR, U32, RW, 0, 4, 0, NULL, 0, 0},                /* not mappable */
    {0x2006, 0, VAR, VS, RW, BOTH, 6, 0, "abc", 0, 0},            /* string, 6 bytes */
    {0x2007, 0, VAR, I64, RW, BOTH, 8, 0x0102030405060708ll, NULL, 0, 0},
    {0x2008, 0, VAR, U32, RO, RP, 4, 0, NULL, 0, 0},              /* RPDO flag but read-only */
    {0x2009, 0, VAR, U32, CO_ACCESS_WO, TP, 4, 0, NULL, 0, 0},    /* TPDO flag but write-only */
    {0x200A, 0, VAR, U8, CO_ACCESS_RWR, TP, 1, 0x5A, NULL, 0, 0},
    {0x200B, 0, VAR, U8, CO_ACCESS_RWW, RP, 1, 0, NULL, 0, 0},
    {0x200C, 0, VAR, U8, AC_CONST, TP, 1, 0x7E, NULL, 0, 0},
};

static void od_build(fx_t *fx, co_mode_t mode)
{
    co_od_def_t d;
    co_od_init(&fx->od, mode, fx->entries, N_ENTRIES, fx->pool, POOL, fx->subs, 2);
    tu_od_add_rows(&fx->od, rows, sizeof rows / sizeof rows[0]);
    /* a domain with the mapping flags: never mappable */
    d = tu_od_def(0x2010, 0, CO_OBJECT_DOMAIN, CO_TYPE_DOMAIN, RW, BOTH, 0);
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ADDED);
    /* mapping object 0x1600: sub 0 and 8 entries, all 0 */
    d = tu_od_def(MAP_OBJ, 0, REC, U8, RW, 0, 1);
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ADDED);
    for (uint8_t s = 1; s <= 8; s++) {
        d = tu_od_def(MAP_OBJ, s, REC, U32, RW, 0, 4);
        assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ADDED);
    }
    assert_true(co_od_seal(&fx->od, 1));
}

static void set_map(fx_t *fx, uint8_t sub, uint32_t v)
{
    uint8_t b[4];
    tu_le_put(b, v, 4);
    assert_int_equal(co_od_put(&fx->od, MAP_OBJ, sub, b, 4), 0);
}

static void test_entry_checks(void **state)
{
    fx_t fx;
    co_pdo_map_item_t it;
    (void)state;
    od_build(&fx, CO_MODE_CLASSIC);
    /* mappable both ways */
    assert_int_equal(co_pdo_map_check_entry(&fx.od, true, MAP(0x2002, 0, 32), &it), 0);
    assert_int_equal(it.bits, 32);
    assert_int_equal(it.flags, 0);
    assert_ptr_equal(&fx.entries[it.entry], co_od_find(&fx.od, 0x2002, 0));
    assert_int_equal(it.value, co_od_find(&fx.od, 0x2002, 0)->value);
    assert_int_equal(co_pdo_map_check_entry(&fx.od, false, MAP(0x2002, 0, 32), NULL), 0);
    /* direction flags and access */
    assert_int_equal(co_pdo_map_check_entry(&fx.od, false, MAP(0x2003, 0, 32), NULL), 0);
    assert_int_equal(co_pdo_map_check_entry(&fx.od, true, MAP(0x2003, 0, 32), NULL),
                     CO_ABORT_NO_MAP);
    assert_int_equal(co_pdo_map_check_entry(&fx.od, true, MAP(0x2004, 0, 32), NULL), 0);
    assert_int_equal(co_pdo_map_check_entry(&fx.od, false, MAP(0x2004, 0, 32), NULL),
                     CO_ABORT_NO_MAP);
    assert_int_equal(co_pdo_map_check_entry(&fx.od, true, MAP(0x2008, 0, 32), NULL),
                     CO_ABORT_NO_MAP);
    assert_int_equal(co_pdo_map_check_entry(&fx.od, false, MAP(0x2009, 0, 32), NULL),
                     CO_ABORT_NO_MAP);
    assert_int_equal(co_pdo_map_check_entry(&fx.od, false, MAP(0x200A, 0, 8), NULL), 0);
    assert_int_equal(co_pdo_map_check_entry(&fx.od, true, MAP(0x200B, 0, 8), NULL), 0);
    assert_int_equal(co_pdo_map_check_entry(&fx.od, false, MAP(0x200C, 0, 8), NULL), 0);
    /* not mappable, missing, domain */
    assert_int_equal(co_pdo_map_check_entry(&fx.od, false, MAP(0x2005, 0, 32), NULL),
                     CO_ABORT_NO_MAP);
    assert_int_equal(co_pdo_map_check_entry(&fx.od, false, MAP(0x2F00, 0, 8), NULL),
                     CO_ABORT_NO_MAP);
    assert_int_equal(co_pdo_map_check_entry(&fx.od, false, MAP(0x2000, 1, 8), NULL),
                     CO_ABORT_NO_MAP);
    assert_int_equal(co_pdo_map_check_entry(&fx.od, false, MAP(0x2010, 0, 8), NULL),
                     CO_ABORT_NO_MAP);
    /* length: 0, above the object, shorter = partial */
    assert_int_equal(co_pdo_map_check_entry(&fx.od, false, MAP(0x2002, 0, 0), NULL),
                     CO_ABORT_NO_MAP);
    assert_int_equal(co_pdo_map_check_entry(&fx.od, false, MAP(0x2002, 0, 40), NULL),
                     CO_ABORT_NO_MAP);
    assert_int_equal(co_pdo_map_check_entry(&fx.od, false, MAP(0x2002, 0, 16), &it), 0);
    assert_int_equal(it.flags, CO_PDO_ITEM_PARTIAL);
    assert_int_equal(co_pdo_map_check_entry(&fx.od, false, MAP(0x2006, 0, 48), &it), 0);
    assert_int_equal(it.flags, CO_PDO_ITEM_STRING);
    /* bit-wise on classic */
    assert_int_equal(co_pdo_map_check_entry(&fx.od, false, MAP(0x2000, 0, 3), &it), 0);
    assert_int_equal(it.bits, 3);
    /* dummies: RPDO only, exact type size */
    assert_int_equal(co_pdo_map_check_entry(&fx.od, true, MAP(0x0002, 0, 8), &it), 0);
    assert_int_equal(it.flags, CO_PDO_ITEM_DUMMY);
    assert_int_equal(co_pdo_map_check_entry(&fx.od, true, MAP(0x0003, 0, 16), NULL), 0);
    assert_int_equal(co_pdo_map_check_entry(&fx.od, true, MAP(0x0004, 0, 32), NULL), 0);
    assert_int_equal(co_pdo_map_check_entry(&fx.od, true, MAP(0x0005, 0, 8), NULL), 0);
    assert_int_equal(co_pdo_map_check_entry(&fx.od, true, MAP(0x0006, 0, 16), NULL), 0);
    assert_int_equal(co_pdo_map_check_entry(&fx.od, true, MAP(0x0007, 0, 32), NULL), 0);
    assert_int_equal(co_pdo_map_check_entry(&fx.od, true, MAP(0x0007, 0, 16), NULL),
                     CO_ABORT_NO_MAP);
    assert_int_equal(co_pdo_map_check_entry(&fx.od, false, MAP(0x0005, 0, 8), NULL),
                     CO_ABORT_NO_MAP);
    assert_int_equal(co_pdo_map_check_entry(&fx.od, true, MAP(0x0008, 0, 32), NULL),
                     CO_ABORT_NO_MAP);
    assert_int_equal(co_pdo_map_check_entry(&fx.od, true, MAP(0x0001, 0, 8), NULL),
                     CO_ABORT_NO_MAP);
}

static void test_fd_byte_wise_only(void **state)
{
    fx_t fx;
    (void)state;
    od_build(&fx, CO_MODE_FD);
    assert_int_equal(co_pdo_map_check_entry(&fx.od, false, MAP(0x2000, 0, 3), NULL),
                     CO_ABORT_NO_MAP);
    assert_int_equal(co_pdo_map_check_entry(&fx.od, false, MAP(0x2002, 0, 12), NULL),
                     CO_ABORT_NO_MAP);
    assert_int_equal(co_pdo_map_check_entry(&fx.od, false, MAP(0x2002, 0, 24), NULL), 0);
    assert_int_equal(co_pdo_map_max_bits(&fx.od), 512);
}

static void test_compile(void **state)
{
    fx_t fx;
    co_pdo_map_item_t items[8];
    uint16_t bits = 0;
    (void)state;
    od_build(&fx, CO_MODE_CLASSIC);
    assert_int_equal(co_pdo_map_max_bits(&fx.od), 64);
    set_map(&fx, 1, MAP(0x2000, 0, 8));
    set_map(&fx, 2, MAP(0x2001, 0, 16));
    set_map(&fx, 3, MAP(0x2002, 0, 32));
    set_map(&fx, 4, MAP(0x2000, 0, 8));
    assert_int_equal(co_pdo_map_compile(&fx.od, MAP_OBJ, false, 4, 8, items, &bits), 0);
    assert_int_equal(bits, 64);
    assert_int_equal(items[0].bit, 0);
    assert_int_equal(items[1].bit, 8);
    assert_int_equal(items[2].bit, 24);
    assert_int_equal(items[3].bit, 56);
    assert_int_equal(items[2].flags, CO_PDO_ITEM_BYTES);
    /* count 0 is empty; above the capacity or 64 */
    assert_int_equal(co_pdo_map_compile(&fx.od, MAP_OBJ, false, 0, 8, items, &bits), 0);
    assert_int_equal(bits, 0);
    assert_int_equal(co_pdo_map_compile(&fx.od, MAP_OBJ, false, 9, 8, items, &bits),
                     CO_ABORT_VALUE_HIGH);
    assert_int_equal(co_pdo_map_compile(&fx.od, MAP_OBJ, false, 65, 255, items, &bits),
                     CO_ABORT_VALUE_HIGH);
    /* one more byte exceeds 8 bytes */
    set_map(&fx, 5, MAP(0x2000, 0, 8));
    assert_int_equal(co_pdo_map_compile(&fx.od, MAP_OBJ, false, 5, 8, NULL, &bits),
                     CO_ABORT_MAP_LENGTH);
    /* an entry 0 inside the count, a bad entry */
    assert_int_equal(co_pdo_map_compile(&fx.od, MAP_OBJ, false, 6, 8, NULL, &bits),
                     CO_ABORT_MAP_LENGTH);
    set_map(&fx, 1, 0);
    assert_int_equal(co_pdo_map_compile(&fx.od, MAP_OBJ, false, 2, 8, NULL, &bits),
                     CO_ABORT_NO_MAP);
    set_map(&fx, 1, MAP(0x2004, 0, 32));   /* write-only: not for a TPDO */
    assert_int_equal(co_pdo_map_compile(&fx.od, MAP_OBJ, false, 1, 8, NULL, &bits),
                     CO_ABORT_NO_MAP);
    assert_int_equal(co_pdo_map_compile(&fx.od, MAP_OBJ, true, 1, 8, NULL, &bits), 0);
    assert_int_equal(bits, 32);
}

static void test_pack_unpack_bytes(void **state)
{
    fx_t fx;
    co_pdo_map_item_t items[8];
    uint16_t bits = 0;
    uint8_t data[8];
    const uint8_t expect[8] = {0x11, 0x22, 0x22, 0x33, 0x33, 0x33, 0x33, 0x11};
    const uint8_t in[8] = {0xA1, 0xB1, 0xB2, 0xC1, 0xC2, 0xC3, 0xC4, 0xA2};
    uint32_t v32 = 0;
    uint8_t v8 = 0;
    (void)state;
    od_build(&fx, CO_MODE_CLASSIC);
    set_map(&fx, 1, MAP(0x2000, 0, 8));
    set_map(&fx, 2, MAP(0x2001, 0, 16));
    set_map(&fx, 3, MAP(0x2002, 0, 32));
    set_map(&fx, 4, MAP(0x2000, 0, 8));
    assert_int_equal(co_pdo_map_compile(&fx.od, MAP_OBJ, false, 4, 8, items, &bits), 0);
    memset(data, 0xEE, sizeof data);
    co_pdo_map_pack(&fx.od, items, 4, bits, data);
    assert_memory_equal(data, expect, 8);
    co_pdo_map_unpack(&fx.od, items, 4, in);
    assert_true(co_od_get_u32(&fx.od, 0x2002, 0, &v32));
    assert_int_equal(v32, 0xC4C3C2C1u);
    assert_true(co_od_get_u8(&fx.od, 0x2000, 0, &v8));
    assert_int_equal(v8, 0xA2);   /* mapped twice: the later one wins */
}

static void test_bit_wise_classic(void **state)
{
    fx_t fx;
    co_pdo_map_item_t items[8];
    uint16_t bits = 0;
    uint8_t data[8];
    uint8_t v8 = 0;
    uint16_t v16 = 0;
    (void)state;
    od_build(&fx, CO_MODE_CLASSIC);
    /* 3 bits of 0x2000 (0x11 -> 001), 12 bits of 0x2001 (0x2222 -> 0x222), 1 bit of 0x200A */
    set_map(&fx, 1, MAP(0x2000, 0, 3));
    set_map(&fx, 2, MAP(0x2001, 0, 12));
    set_map(&fx, 3, MAP(0x200A, 0, 1));
    assert_int_equal(co_pdo_map_compile(&fx.od, MAP_OBJ, false, 3, 8, items, &bits), 0);
    assert_int_equal(bits, 16);
    assert_int_equal(items[1].bit, 3);
    assert_int_equal(items[2].bit, 15);
    assert_int_equal(items[1].flags, CO_PDO_ITEM_PARTIAL);
    memset(data, 0xEE, sizeof data);
    co_pdo_map_pack(&fx.od, items, 3, bits, data);
    /* bits 0..2 = 001, bits 3..14 = 0x222, bit 15 = 0 (0x5A bit 0) */
    {
        uint16_t w = (uint16_t)(0x1u | (0x222u << 3));
        assert_int_equal(data[0], (uint8_t)w);
        assert_int_equal(data[1], (uint8_t)(w >> 8));
        assert_int_equal(data[2], 0xEE);   /* beyond the mapped bytes: untouched */
    }
    /* receive: an RPDO mapping of the same shape writes bits and zeroes the rest */
    set_map(&fx, 3, MAP(0x200B, 0, 1));
    assert_int_equal(co_pdo_map_compile(&fx.od, MAP_OBJ, true, 3, 8, items, &bits), 0);
    {
        uint16_t w = (uint16_t)(0x6u | (0xABCu << 3) | 0x8000u);
        const uint8_t in[2] = {(uint8_t)w, (uint8_t)(w >> 8)};
        co_pdo_map_unpack(&fx.od, items, 3, in);
    }
    assert_true(co_od_get_u8(&fx.od, 0x2000, 0, &v8));
    assert_int_equal(v8, 0x06);
    assert_true(co_od_get_u16(&fx.od, 0x2001, 0, &v16));
    assert_int_equal(v16, 0x0ABC);
    assert_true(co_od_get_u8(&fx.od, 0x200B, 0, &v8));
    assert_int_equal(v8, 1);
}

static void test_partial_and_string(void **state)
{
    fx_t fx;
    co_pdo_map_item_t items[8];
    uint16_t bits = 0;
    uint8_t data[8];
    const uint8_t in[6] = {0x44, 0x33, 'x', 'y', 'z', 'w'};
    uint8_t str[8];
    uint32_t len = 0, v32 = 0;
    (void)state;
    od_build(&fx, CO_MODE_FD);
    set_map(&fx, 1, MAP(0x2002, 0, 16));   /* low half of a U32 */
    set_map(&fx, 2, MAP(0x2006, 0, 32));   /* first 4 bytes of a 6-byte string */
    assert_int_equal(co_pdo_map_compile(&fx.od, MAP_OBJ, false, 2, 8, items, &bits), 0);
    assert_int_equal(bits, 48);
    co_pdo_map_pack(&fx.od, items, 2, bits, data);
    {
        const uint8_t expect[6] = {0x33, 0x33, 'a', 'b', 'c', 0};
        assert_memory_equal(data, expect, 6);
    }
    co_pdo_map_unpack(&fx.od, items, 2, in);
    assert_true(co_od_get_u32(&fx.od, 0x2002, 0, &v32));
    assert_int_equal(v32, 0x3344u);   /* upper half set to 0 */
    assert_int_equal(co_od_get(&fx.od, 0x2006, 0, str, sizeof str, &len), 0);
    assert_int_equal(len, 4);
    assert_memory_equal(str, "xyzw", 4);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_entry_checks),
        cmocka_unit_test(test_fd_byte_wise_only),
        cmocka_unit_test(test_compile),
        cmocka_unit_test(test_pack_unpack_bytes),
        cmocka_unit_test(test_bit_wise_classic),
        cmocka_unit_test(test_partial_and_string),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
