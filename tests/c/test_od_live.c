/* co_od_add_live: objects added to a sealed (running) dictionary. They are
 * appended behind the sorted table, so nothing that holds an entry (a
 * transfer in progress, a PDO mapping position) sees it move; every refusal
 * leaves the dictionary as it was. */
#include "test_od_util.h"

#include <stdlib.h>

#define SLOTS 8
#define POOL 128

typedef struct {
    co_od_t od;
    co_od_entry_t entries[SLOTS];
    uint8_t pool[POOL];
} live_t;

static const tu_od_row_t ROWS[] = {
    {0x1000, 0, VAR, U32, RO, 0, 4, 0x191, NULL, 0, 0},
    {0x2000, 0, VAR, U32, RW, 0, 4, 10, NULL, 0, 0},
    {0x2010, 0, REC, U8, RO, 0, 1, 1, NULL, 0, 0},
    {0x2010, 1, REC, U16, RW, 0, 2, 7, NULL, 0, 0},
    {0x2020, 0, VAR, U32, RW, 0, 4, 20, NULL, 0, 0},
};
#define NROWS (sizeof ROWS / sizeof ROWS[0])

static int setup(void **state)
{
    live_t *l = calloc(1, sizeof *l);
    co_od_init(&l->od, CO_MODE_FD, l->entries, SLOTS, l->pool, POOL, NULL, 0);
    tu_od_add_rows(&l->od, ROWS, NROWS);
    assert_true(co_od_seal(&l->od, 5));
    *state = l;
    return 0;
}

static int teardown(void **state)
{
    free(*state);
    return 0;
}

static co_od_def_t u32_def(uint16_t index, uint8_t sub, uint8_t *b, uint32_t value)
{
    co_od_def_t d = tu_od_def(index, sub, VAR, U32, RW, 0, 4);
    tu_le_put(b, value, 4);
    d.default_value = b;
    d.default_length = 4;
    return d;
}

static void test_live_entry_is_found_read_and_written_at_once(void **state)
{
    live_t *l = *state;
    uint8_t b[4];
    uint32_t v = 0;
    co_od_def_t d = u32_def(0x2015, 0, b, 0xCAFE);
    assert_false(co_od_has_index(&l->od, 0x2015));
    assert_int_equal(co_od_add_live(&l->od, &d), CO_OD_ADDED);
    assert_non_null(co_od_find(&l->od, 0x2015, 0));
    assert_true(co_od_has_index(&l->od, 0x2015));
    assert_true(co_od_get_u32(&l->od, 0x2015, 0, &v));
    assert_int_equal(v, 0xCAFE);                                 /* starts at its default */
    assert_int_equal(tu_od_net_read_u32(&l->od, 0x2015, 0, &v), 0);
    assert_int_equal(v, 0xCAFE);
    assert_int_equal(tu_od_net_write_u32(&l->od, 0x2015, 0, 0x12345678), 0);
    assert_memory_equal(co_od_value(&l->od, co_od_find(&l->od, 0x2015, 0)),
                        "\x78\x56\x34\x12", 4);                  /* little-endian, as on the wire */
    /* missing keys around it still say which is missing */
    assert_null(co_od_find(&l->od, 0x2015, 1));
    assert_null(co_od_find(&l->od, 0x2016, 0));
    /* every sealed entry is still found where it was */
    for (size_t i = 0; i < NROWS; i++) {
        assert_ptr_equal(co_od_find(&l->od, ROWS[i].index, ROWS[i].sub), &l->entries[i]);
    }
    /* a reset loads its default again */
    co_od_load_defaults(&l->od, 0xFF);
    assert_true(co_od_get_u32(&l->od, 0x2015, 0, &v));
    assert_int_equal(v, 0xCAFE);
}

static void test_no_sealed_entry_moves_so_a_transfer_in_progress_survives(void **state)
{
    live_t *l = *state;
    co_od_xfer_t x;
    uint8_t scratch[16], b[4], value[4] = {0xEF, 0xBE, 0xAD, 0xDE};
    uint32_t v = 0;
    const co_od_entry_t *held = co_od_find(&l->od, 0x2020, 0);
    co_od_xfer_init(&x, scratch, sizeof scratch);
    assert_int_equal(co_od_write_begin(&l->od, &x, 0x2020, 0, 4), 0);
    assert_int_equal(co_od_write_chunk(&x, value, 2), 0);
    /* keys below and above the entry being written */
    co_od_def_t below = u32_def(0x2001, 0, b, 1);
    assert_int_equal(co_od_add_live(&l->od, &below), CO_OD_ADDED);
    co_od_def_t above = u32_def(0x3000, 0, b, 2);
    assert_int_equal(co_od_add_live(&l->od, &above), CO_OD_ADDED);
    assert_ptr_equal(co_od_find(&l->od, 0x2020, 0), held);
    assert_int_equal(co_od_write_chunk(&x, value + 2, 2), 0);
    assert_int_equal(co_od_write_end(&x), 0);
    assert_true(co_od_get_u32(&l->od, 0x2020, 0, &v));
    assert_int_equal(v, 0xDEADBEEF);
    assert_true(co_od_get_u32(&l->od, 0x2001, 0, &v));
    assert_int_equal(v, 1);
    assert_true(co_od_get_u32(&l->od, 0x3000, 0, &v));
    assert_int_equal(v, 2);
    assert_ptr_equal(co_od_find(&l->od, 0x2020, 0), &l->entries[4]);
    assert_ptr_equal(co_od_find(&l->od, 0x2001, 0), &l->entries[NROWS]);
}

/* count, pool use and every value byte as before */
static void assert_unchanged(const live_t *l, const live_t *before)
{
    assert_int_equal(l->od.count, before->od.count);
    assert_int_equal(l->od.pool_used, before->od.pool_used);
    assert_memory_equal(l->pool, before->pool, POOL);
    assert_memory_equal(l->entries, before->entries, sizeof l->entries);
}

static void test_refusals_leave_the_dictionary_unchanged(void **state)
{
    live_t *l = *state;
    live_t *before = malloc(sizeof *before);
    uint8_t b[4];
    memcpy(before, l, sizeof *l);
    co_od_def_t d = u32_def(0x2000, 0, b, 1);                    /* exists */
    assert_int_equal(co_od_add_live(&l->od, &d), CO_OD_ERR_DUPLICATE);
    d = u32_def(0x1801, 0, b, 1);                                /* communication area */
    assert_int_equal(co_od_add_live(&l->od, &d), CO_OD_ERR_COMMUNICATION);
    d = tu_od_def(0x2030, 0, VAR, VS, RW, 0, 5);                 /* above the largest (4) */
    assert_int_equal(co_od_add_live(&l->od, &d), CO_OD_ERR_TOO_LARGE);
    d = tu_od_def(0x2040, 1, REC, U16, RW, 0, 2);                /* record without sub 0 */
    assert_int_equal(co_od_add_live(&l->od, &d), CO_OD_ERR_STRUCTURE);
    d = tu_od_def(0x2000, 1, REC, U16, RW, 0, 2);                /* sub 0 is a U32 VAR */
    assert_int_equal(co_od_add_live(&l->od, &d), CO_OD_ERR_STRUCTURE);
    d = tu_od_def(0x2040, 0, ARR, U16, RO, 0, 2);                /* sub 0 not UNSIGNED8 */
    assert_int_equal(co_od_add_live(&l->od, &d), CO_OD_ERR_STRUCTURE);
    d = tu_od_def(0x2040, 0, VAR, U16, RW, 0, 3);                /* size not the type's */
    assert_int_equal(co_od_add_live(&l->od, &d), CO_OD_ERR_TYPE);
    assert_int_equal(co_od_add_live(&l->od, NULL), CO_OD_ERR_TYPE);
    d = tu_od_def(0x2040, 0, VAR, U16, RW, CO_OD_CLASSIC_ONLY, 2);   /* fd line */
    assert_int_equal(co_od_add_live(&l->od, &d), CO_OD_SKIPPED_MODE);
    assert_unchanged(l, before);
    free(before);
}

static void test_a_sub_entry_joins_an_existing_record(void **state)
{
    live_t *l = *state;
    co_od_def_t d = tu_od_def(0x2010, 2, REC, U16, RW, 0, 2);
    uint16_t v = 1;
    assert_int_equal(co_od_add_live(&l->od, &d), CO_OD_ADDED);
    assert_true(co_od_get_u16(&l->od, 0x2010, 2, &v));
    assert_int_equal(v, 0);                                      /* no default: 0 */
    d = tu_od_def(0x2050, 0, REC, U8, RO, 0, 1);                 /* a new record, sub 0 first */
    assert_int_equal(co_od_add_live(&l->od, &d), CO_OD_ADDED);
    d = tu_od_def(0x2050, 1, VAR, U32, RW, 0, 4);
    assert_int_equal(co_od_add_live(&l->od, &d), CO_OD_ADDED);
    assert_non_null(co_od_find(&l->od, 0x2050, 1));
}

static void test_full_when_the_slots_or_the_pool_are_used(void **state)
{
    live_t *l = *state;
    uint8_t b[4];
    uint16_t index = 0x2100;
    co_od_def_t d;
    while (l->od.count < SLOTS) {                                /* the 3 spare slots */
        d = u32_def(index++, 0, b, 3);
        assert_int_equal(co_od_add_live(&l->od, &d), CO_OD_ADDED);
    }
    live_t *before = malloc(sizeof *before);
    memcpy(before, l, sizeof *l);
    d = u32_def(index, 0, b, 3);
    assert_int_equal(co_od_add_live(&l->od, &d), CO_OD_ERR_FULL);
    assert_unchanged(l, before);
    free(before);
}

static void test_full_when_the_pool_has_no_room(void **state)
{
    live_t *l = *state;
    uint8_t b[4];
    l->od.pool_size = l->od.pool_used + 7;                       /* value + default need 8 */
    co_od_def_t d = u32_def(0x2100, 0, b, 3);
    assert_int_equal(co_od_add_live(&l->od, &d), CO_OD_ERR_FULL);
    assert_null(co_od_find(&l->od, 0x2100, 0));
    d = tu_od_def(0x2100, 0, VAR, U16, RW, 0, 2);                /* 2 bytes still fit */
    assert_int_equal(co_od_add_live(&l->od, &d), CO_OD_ADDED);
}

static void test_a_batch_is_added_all_or_none(void **state)
{
    live_t *l = *state;
    uint8_t b0[4], b1[4];
    co_od_def_t batch[3];
    uint32_t refused = 99;
    batch[0] = tu_od_def(0x2060, 0, REC, U8, RO, 0, 1);
    batch[1] = u32_def(0x2060, 1, b0, 1);
    batch[2] = u32_def(0x2000, 0, b1, 2);                        /* exists: the batch fails */
    live_t *before = malloc(sizeof *before);
    memcpy(before, l, sizeof *l);
    assert_int_equal(co_od_add_live_all(&l->od, batch, 3, &refused), CO_OD_ERR_DUPLICATE);
    assert_int_equal(refused, 2);
    assert_int_equal(l->od.count, before->od.count);
    assert_int_equal(l->od.pool_used, before->od.pool_used);
    assert_false(co_od_has_index(&l->od, 0x2060));
    free(before);
    batch[2] = u32_def(0x2061, 0, b1, 2);
    assert_int_equal(co_od_add_live_all(&l->od, batch, 3, &refused), CO_OD_ADDED);
    assert_non_null(co_od_find(&l->od, 0x2060, 1));
    assert_non_null(co_od_find(&l->od, 0x2061, 0));
}

static void test_the_grown_store_image_holds_what_live_adds_can_store(void **state)
{
    live_t *l = *state;
    uint8_t b[4];
    uint16_t index = 0x2100;
    uint32_t bound = co_store_image_need_grown(&l->od);
    assert_true(bound > co_store_image_need(&l->od));
    while (l->od.count < SLOTS) {                                /* stored entries, as many as fit */
        co_od_def_t d = u32_def(index++, 0, b, 3);
        d.flags = CO_OD_STORE;
        assert_int_equal(co_od_add_live(&l->od, &d), CO_OD_ADDED);
    }
    assert_true(co_store_image_need(&l->od) <= bound);
    assert_int_equal(co_store_image_need_grown(&l->od),             /* full: nothing more */
                     co_store_image_need(&l->od) + (l->od.pool_size - l->od.pool_used));
}

static void test_before_seal_it_is_refused(void **state)
{
    live_t l;
    uint8_t b[4];
    (void)state;
    co_od_init(&l.od, CO_MODE_FD, l.entries, SLOTS, l.pool, POOL, NULL, 0);
    co_od_def_t d = u32_def(0x2000, 0, b, 1);
    assert_int_equal(co_od_add_live(&l.od, &d), CO_OD_ERR_NOT_SEALED);
    assert_int_equal(l.od.count, 0);
    assert_true(co_od_seal(&l.od, 1));
    /* an empty dictionary has no entry size for the servers' scratch */
    assert_int_equal(co_od_add_live(&l.od, &d), CO_OD_ERR_TOO_LARGE);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_live_entry_is_found_read_and_written_at_once,
                                        setup, teardown),
        cmocka_unit_test_setup_teardown(test_no_sealed_entry_moves_so_a_transfer_in_progress_survives,
                                        setup, teardown),
        cmocka_unit_test_setup_teardown(test_refusals_leave_the_dictionary_unchanged, setup,
                                        teardown),
        cmocka_unit_test_setup_teardown(test_a_sub_entry_joins_an_existing_record, setup,
                                        teardown),
        cmocka_unit_test_setup_teardown(test_full_when_the_slots_or_the_pool_are_used, setup,
                                        teardown),
        cmocka_unit_test_setup_teardown(test_full_when_the_pool_has_no_room, setup, teardown),
        cmocka_unit_test_setup_teardown(test_a_batch_is_added_all_or_none, setup, teardown),
        cmocka_unit_test_setup_teardown(test_the_grown_store_image_holds_what_live_adds_can_store,
                                        setup, teardown),
        cmocka_unit_test(test_before_seal_it_is_refused),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
