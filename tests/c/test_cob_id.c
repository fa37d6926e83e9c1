/* COB-ID entry rules (co_cob_id): which entries, which bit makes an object
 * active, refusal with 0x06090030 while active and the entry unchanged,
 * "disable + change" and "change + enable" in one write allowed. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <cmocka.h>
#include <string.h>

#include "co_cob_id.h"
#include "test_od_util.h"

typedef struct fx {
    co_od_t od;
    co_od_entry_t entries[16];
    uint8_t pool[256];
    co_od_subscription_t subs[4];
} fx_t;

static const tu_od_row_t rows[] = {
    { 0x1005, 0, VAR, U32, RW, 0, 4, 0x80, NULL, 0, 0 },          /* SYNC, not generating */
    { 0x1012, 0, VAR, U32, RW, 0, 4, 0x100, NULL, 0, 0 },         /* TIME, off */
    { 0x1014, 0, VAR, U32, RW, 0, 4, 0x85, NULL, 0, 0 },          /* EMCY, valid */
    { 0x1017, 0, VAR, U16, RW, 0, 2, 0, NULL, 0, 0 },             /* not a COB-ID */
    { 0x1200, 0, REC, U8, RO, 0, 1, 2, NULL, 0, 0 },
    { 0x1200, 1, REC, U32, RW, 0, 4, 0x605, NULL, 0, 0 },         /* SDO server rx, valid */
    { 0x1800, 0, REC, U8, RO, 0, 1, 2, NULL, 0, 0 },
    { 0x1800, 1, REC, U32, RW, 0, 4, 0x185, NULL, 0, 0 },         /* TPDO 1, valid */
    { 0x1800, 2, REC, U8, RW, 0, 1, 0xFE, NULL, 0, 0 },           /* transmission type */
};

static int setup(void **state)
{
    static fx_t fx;
    memset(&fx, 0, sizeof fx);
    co_od_init(&fx.od, CO_MODE_FD, fx.entries, 16, fx.pool, sizeof fx.pool, fx.subs, 4);
    tu_od_add_rows(&fx.od, rows, sizeof rows / sizeof rows[0]);
    assert_true(co_od_seal(&fx.od, 5));
    assert_true(co_cob_id_attach(&fx.od));
    *state = &fx;
    return 0;
}

static uint32_t write_u32(fx_t *fx, uint16_t index, uint8_t sub, uint32_t value)
{
    uint8_t scratch[8], b[4];
    co_od_xfer_t x;
    uint32_t r;
    tu_le_put(b, value, 4);
    co_od_xfer_init(&x, scratch, sizeof scratch);
    r = co_od_write_begin(&fx->od, &x, index, sub, 4);
    if (r == 0)
        r = co_od_write_chunk(&x, b, 4);
    if (r == 0)
        r = co_od_write_end(&x);
    return r;
}

static uint32_t value_of(fx_t *fx, uint16_t index, uint8_t sub)
{
    uint32_t v = 0;
    assert_true(co_od_get_u32(&fx->od, index, sub, &v));
    return v;
}

static void test_kinds(void **state)
{
    (void)state;
    assert_int_equal(co_cob_id_kind(0x1005, 0), CO_COB_ID_SYNC);
    assert_int_equal(co_cob_id_kind(0x1012, 0), CO_COB_ID_TIME);
    assert_int_equal(co_cob_id_kind(0x1014, 0), CO_COB_ID_VALID_BIT31);
    assert_int_equal(co_cob_id_kind(0x1028, 1), CO_COB_ID_VALID_BIT31);
    assert_int_equal(co_cob_id_kind(0x1028, 0x7F), CO_COB_ID_VALID_BIT31);
    assert_int_equal(co_cob_id_kind(0x1028, 0), CO_COB_ID_NONE);
    assert_int_equal(co_cob_id_kind(0x1200, 1), CO_COB_ID_VALID_BIT31);
    assert_int_equal(co_cob_id_kind(0x12FF, 2), CO_COB_ID_VALID_BIT31);
    assert_int_equal(co_cob_id_kind(0x1200, 3), CO_COB_ID_NONE);   /* node-id of the client */
    assert_int_equal(co_cob_id_kind(0x1400, 1), CO_COB_ID_VALID_BIT31);
    assert_int_equal(co_cob_id_kind(0x15FF, 1), CO_COB_ID_VALID_BIT31);
    assert_int_equal(co_cob_id_kind(0x1600, 1), CO_COB_ID_NONE);   /* RPDO mapping */
    assert_int_equal(co_cob_id_kind(0x1800, 1), CO_COB_ID_VALID_BIT31);
    assert_int_equal(co_cob_id_kind(0x19FF, 1), CO_COB_ID_VALID_BIT31);
    assert_int_equal(co_cob_id_kind(0x1800, 2), CO_COB_ID_NONE);
    assert_int_equal(co_cob_id_kind(0x1A00, 1), CO_COB_ID_NONE);   /* TPDO mapping */
    assert_int_equal(co_cob_id_kind(0x1017, 0), CO_COB_ID_NONE);
}

static void test_pure_rules(void **state)
{
    (void)state;
    /* valid-bit objects: CAN-ID fixed while valid in old and new */
    assert_int_equal(co_cob_id_check(CO_COB_ID_VALID_BIT31, 0x185, 0x186), CO_ABORT_INVALID_VALUE);
    assert_int_equal(co_cob_id_check(CO_COB_ID_VALID_BIT31, 0x185, 0x80000185u), 0);
    assert_int_equal(co_cob_id_check(CO_COB_ID_VALID_BIT31, 0x80000185u, 0x80000186u), 0);
    assert_int_equal(co_cob_id_check(CO_COB_ID_VALID_BIT31, 0x80000185u, 0x186), 0);
    assert_int_equal(co_cob_id_check(CO_COB_ID_VALID_BIT31, 0x185, 0x20000185u),
                     CO_ABORT_INVALID_VALUE);                 /* frame bit is part of the id */
    assert_int_equal(co_cob_id_check(CO_COB_ID_VALID_BIT31, 0x185, 0x185), 0);
    /* SYNC: active while generating (bit 30) */
    assert_int_equal(co_cob_id_check(CO_COB_ID_SYNC, 0x40000080u, 0x40000081u),
                     CO_ABORT_INVALID_VALUE);
    assert_int_equal(co_cob_id_check(CO_COB_ID_SYNC, 0x80, 0x81), 0);
    assert_int_equal(co_cob_id_check(CO_COB_ID_SYNC, 0x80, 0x40000081u), 0);
    assert_int_equal(co_cob_id_check(CO_COB_ID_SYNC, 0x40000080u, 0x40000080u), 0);
    /* TIME: active while producing (30) or consuming (31) */
    assert_int_equal(co_cob_id_check(CO_COB_ID_TIME, 0x80000100u, 0x80000101u),
                     CO_ABORT_INVALID_VALUE);
    assert_int_equal(co_cob_id_check(CO_COB_ID_TIME, 0x40000100u, 0x40000101u),
                     CO_ABORT_INVALID_VALUE);
    assert_int_equal(co_cob_id_check(CO_COB_ID_TIME, 0x100, 0x101), 0);
    assert_int_equal(co_cob_id_check(CO_COB_ID_NONE, 1, 2), 0);
}

static void test_network_writes(void **state)
{
    fx_t *fx = *state;
    /* TPDO 1 valid: a new CAN-ID is refused and nothing changes */
    assert_int_equal(write_u32(fx, 0x1800, 1, 0x186), CO_ABORT_INVALID_VALUE);
    assert_int_equal(value_of(fx, 0x1800, 1), 0x185);
    /* disable, change while invalid, enable again */
    assert_int_equal(write_u32(fx, 0x1800, 1, 0x80000185u), 0);
    assert_int_equal(write_u32(fx, 0x1800, 1, 0x80000186u), 0);
    assert_int_equal(write_u32(fx, 0x1800, 1, 0x186), 0);
    assert_int_equal(value_of(fx, 0x1800, 1), 0x186);
    /* EMCY and SDO entries follow the same rule */
    assert_int_equal(write_u32(fx, 0x1014, 0, 0x86), CO_ABORT_INVALID_VALUE);
    assert_int_equal(value_of(fx, 0x1014, 0), 0x85);
    assert_int_equal(write_u32(fx, 0x1200, 1, 0x606), CO_ABORT_INVALID_VALUE);
    /* SYNC: free while not generating, fixed once generating */
    assert_int_equal(write_u32(fx, 0x1005, 0, 0x81), 0);
    assert_int_equal(write_u32(fx, 0x1005, 0, 0x40000081u), 0);
    assert_int_equal(write_u32(fx, 0x1005, 0, 0x40000082u), CO_ABORT_INVALID_VALUE);
    assert_int_equal(value_of(fx, 0x1005, 0), 0x40000081u);
    /* TIME */
    assert_int_equal(write_u32(fx, 0x1012, 0, 0x80000100u), 0);
    assert_int_equal(write_u32(fx, 0x1012, 0, 0x80000101u), CO_ABORT_INVALID_VALUE);
    /* other entries of the range are untouched by the rule */
    {
        uint8_t scratch[8], b[1] = { 1 };
        co_od_xfer_t x;
        co_od_xfer_init(&x, scratch, sizeof scratch);
        assert_int_equal(co_od_write_begin(&fx->od, &x, 0x1800, 2, 1), 0);
        assert_int_equal(co_od_write_chunk(&x, b, 1), 0);
        assert_int_equal(co_od_write_end(&x), 0);
    }
    /* the application writes freely (access rules are for the network) */
    {
        uint8_t b[4];
        tu_le_put(b, 0x187, 4);
        assert_int_equal(co_od_put(&fx->od, 0x1800, 1, b, 4), 0);
        assert_int_equal(value_of(fx, 0x1800, 1), 0x187);
    }
    co_cob_id_detach(&fx->od);
    assert_int_equal(write_u32(fx, 0x1014, 0, 0x86), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_kinds),
        cmocka_unit_test(test_pure_rules),
        cmocka_unit_test_setup(test_network_writes, setup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
