/* co_store with parameter groups declared by the application: the checks of
 * a declaration, the CiA 301 capability bits 0x1010/0x1011 report per group,
 * "save" refused for groups not saved on command, the reset type (restored at
 * reset communication or only at reset node), and autonomous saves: a
 * written member marks its group, saves come at most once per interval, a
 * failed (power-cut) save keeps the previous image whole and is retried. */
#include "test_od_util.h"
#include "test_util.h"

static const tu_od_row_t rows[] = {
    { 0x1010, 0, ARR, U8, RO, 0, 1, 5, NULL, 0, 0 },
    { 0x1010, 1, ARR, U32, RW, 0, 4, 0, NULL, 0, 0 },
    { 0x1010, 2, ARR, U32, RW, 0, 4, 0, NULL, 0, 0 },
    { 0x1010, 3, ARR, U32, RW, 0, 4, 0, NULL, 0, 0 },
    { 0x1010, 4, ARR, U32, RW, 0, 4, 0, NULL, 0, 0 },
    { 0x1010, 5, ARR, U32, RW, 0, 4, 0, NULL, 0, 0 },
    { 0x1011, 0, ARR, U8, RO, 0, 1, 5, NULL, 0, 0 },
    { 0x1011, 1, ARR, U32, RW, 0, 4, 0, NULL, 0, 0 },
    { 0x1011, 2, ARR, U32, RW, 0, 4, 0, NULL, 0, 0 },
    { 0x1011, 3, ARR, U32, RW, 0, 4, 0, NULL, 0, 0 },
    { 0x1011, 4, ARR, U32, RW, 0, 4, 0, NULL, 0, 0 },
    { 0x1011, 5, ARR, U32, RW, 0, 4, 0, NULL, 0, 0 },
    { 0x1017, 0, VAR, U16, RW, ST, 2, 1000, NULL, 0, 0 },
    { 0x2000, 0, VAR, U32, RW, ST, 4, 1, NULL, 0, 0 },   /* sub 3: autonomous, reset node */
    { 0x2001, 0, VAR, U32, RW, ST, 4, 2, NULL, 0, 0 },   /* sub 4: both, reset communication */
    { 0x6000, 0, VAR, U32, RW, ST, 4, 3, NULL, 0, 0 },   /* sub 5: disabled */
};

/* sub 2 communication on command (reset communication), 3 autonomous, 4 both,
 * 5 disabled */
static const co_store_group_t groups[] = {
    { 0x100000u, 0x1FFFFFu, 2, CO_STORE_MODE_ON_COMMAND, CO_STORE_RESET_COMMUNICATION },
    { 0x200000u, 0x2000FFu, 3, CO_STORE_MODE_AUTONOMOUS, CO_STORE_RESET_NODE },
    { 0x200100u, 0x2001FFu, 4, CO_STORE_MODE_BOTH, CO_STORE_RESET_COMMUNICATION },
    { 0x600000u, 0x6000FFu, 5, CO_STORE_MODE_DISABLED, CO_STORE_RESET_NODE },
};
#define ROWS(a) ((uint8_t)(sizeof(a) / sizeof(a)[0]))
#define INTERVAL_MS 100u

typedef struct fixture {
    co_od_t od;
    co_od_entry_t entries[32];
    uint8_t pool[1024];
    co_od_subscription_t subs[8];
    co_store_t store;
    uint8_t buf[2048];
    tu_mem_backend_t mem;
    tu_line_t line;
    unsigned told;               /* autonomous_saved calls */
    uint32_t last_abort;
} fixture_t;

static void on_saved(co_store_t *s, uint32_t abort, void *user)
{
    fixture_t *fx = user;
    (void)s;
    fx->told++;
    fx->last_abort = abort;
}

static co_store_config_t config_of(fixture_t *fx, const co_store_group_t *g, uint8_t n)
{
    co_store_config_t c = { g, n, &fx->line.line, INTERVAL_MS, on_saved, fx };
    return c;
}

static int setup(void **state)
{
    fixture_t *fx = calloc(1, sizeof *fx);
    co_store_config_t c;
    assert_non_null(fx);
    co_od_init(&fx->od, CO_MODE_FD, fx->entries, 32, fx->pool, sizeof fx->pool, fx->subs, 8);
    tu_od_add_rows(&fx->od, rows, sizeof rows / sizeof rows[0]);
    assert_true(co_od_seal(&fx->od, 1));
    tu_line_init(&fx->line, CO_MODE_FD, false);
    c = config_of(fx, groups, ROWS(groups));
    assert_true(co_store_init_config(&fx->store, &fx->od, &tu_mem_ops, &fx->mem, fx->buf,
                                     sizeof fx->buf, &c));
    *state = fx;
    return 0;
}

static int teardown(void **state)
{
    fixture_t *fx = *state;
    co_store_deinit(&fx->store);
    free(fx);
    return 0;
}

static void put(fixture_t *fx, uint16_t index, uint32_t v)
{
    const co_od_entry_t *e = co_od_find(&fx->od, index, 0);
    uint8_t b[4];
    assert_non_null(e);
    tu_le_put(b, v, e->size);
    assert_int_equal(co_od_put(&fx->od, index, 0, b, e->size), 0);
}

static uint32_t get(fixture_t *fx, uint16_t index)
{
    const co_od_entry_t *e = co_od_find(&fx->od, index, 0);
    assert_non_null(e);
    return (uint32_t)tu_le_get(co_od_value(&fx->od, e), e->size);
}

static uint32_t net_read(fixture_t *fx, uint16_t index, uint8_t sub)
{
    uint32_t v = 0;
    assert_int_equal(tu_od_net_read_u32(&fx->od, index, sub, &v), 0);
    return v;
}

static uint32_t net_write(fixture_t *fx, uint16_t index, uint8_t sub, uint32_t v)
{
    return tu_od_net_write_u32(&fx->od, index, sub, v);
}

static void at_ms(fixture_t *fx, uint64_t ms)
{
    (void)co_line_process(&fx->line.line, ms * TU_MS);
}

/* --------------------------------------------------------------- tests */

static void test_declarations_that_are_refused(void **state)
{
    fixture_t *fx = *state;
    co_store_t other;
    size_t i;
    static const co_store_group_t bad[][2] = {
        /* overlapping blocks: an entry in two groups */
        { { 0x200000u, 0x2010FFu, 2, 1, 0 }, { 0x201000u, 0x2020FFu, 3, 1, 0 } },
        /* sub-indices with a gap (2, 4) */
        { { 0x200000u, 0x2000FFu, 2, 1, 0 }, { 0x200100u, 0x2001FFu, 4, 1, 0 } },
        /* sub 1 is "all", not a group */
        { { 0x200000u, 0x2000FFu, 1, 1, 0 }, { 0x200100u, 0x2001FFu, 2, 1, 0 } },
        /* an unknown mode, an unknown reset type */
        { { 0x200000u, 0x2000FFu, 2, 4, 0 }, { 0x200100u, 0x2001FFu, 3, 1, 0 } },
        { { 0x200000u, 0x2000FFu, 2, 1, 2 }, { 0x200100u, 0x2001FFu, 3, 1, 0 } },
        /* an empty block, a block below 0x1000 */
        { { 0x2000FFu, 0x200000u, 2, 1, 0 }, { 0x200100u, 0x2001FFu, 3, 1, 0 } },
        { { 0x0F0000u, 0x1000FFu, 2, 1, 0 }, { 0x200100u, 0x2001FFu, 3, 1, 0 } },
        /* one group (sub 2) with two behaviours */
        { { 0x200000u, 0x2000FFu, 2, 1, 0 }, { 0x200100u, 0x2001FFu, 2, 3, 0 } },
    };
    co_store_deinit(&fx->store);
    for (i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        co_store_config_t c = config_of(fx, bad[i], 2);
        assert_false(co_store_init_config(&other, &fx->od, &tu_mem_ops, &fx->mem, fx->buf,
                                          sizeof fx->buf, &c));
    }
    /* autonomous saves need a line (their clock) */
    {
        co_store_config_t c = config_of(fx, groups, ROWS(groups));
        c.line = NULL;
        assert_false(co_store_init_config(&other, &fx->od, &tu_mem_ops, &fx->mem, fx->buf,
                                          sizeof fx->buf, &c));
    }
    assert_int_equal(fx->od.sub_count, 0);   /* nothing half-hooked */
    {
        co_store_config_t c = config_of(fx, groups, ROWS(groups));
        assert_true(co_store_init_config(&fx->store, &fx->od, &tu_mem_ops, &fx->mem, fx->buf,
                                         sizeof fx->buf, &c));
    }
}

static void test_capability_bits_per_group(void **state)
{
    fixture_t *fx = *state;
    /* 0x1010: bit 0 on command, bit 1 autonomously; sub 1 = every group */
    assert_int_equal(net_read(fx, 0x1010, 1), 3);
    assert_int_equal(net_read(fx, 0x1010, 2), 1);
    assert_int_equal(net_read(fx, 0x1010, 3), 2);
    assert_int_equal(net_read(fx, 0x1010, 4), 3);
    assert_int_equal(net_read(fx, 0x1010, 5), 0);
    /* 0x1011: bit 0 "restores defaults" for an enabled group */
    assert_int_equal(net_read(fx, 0x1011, 3), 1);
    assert_int_equal(net_read(fx, 0x1011, 5), 0);
    assert_int_equal(co_store_group_of(&fx->store, 0x200000u), 0x2);
    assert_int_equal(co_store_group_of(&fx->store, 0x600000u), 0x8);
    assert_int_equal(co_store_group_of(&fx->store, 0x700000u), 0);
}

static void test_save_on_command_only_where_declared(void **state)
{
    fixture_t *fx = *state;
    put(fx, 0x1017, 500);
    put(fx, 0x2000, 11);
    put(fx, 0x2001, 22);
    put(fx, 0x6000, 33);
    /* autonomous only, disabled: "save" is refused */
    assert_int_equal(net_write(fx, 0x1010, 3, CO_STORE_SAVE_SIGNATURE), CO_ABORT_DATA_STORE);
    assert_int_equal(net_write(fx, 0x1010, 5, CO_STORE_SAVE_SIGNATURE), CO_ABORT_DATA_STORE);
    assert_int_equal(net_write(fx, 0x1011, 5, CO_STORE_LOAD_SIGNATURE), CO_ABORT_DATA_STORE);
    /* sub 1 saves the groups saved on command: 2 and 4 */
    assert_int_equal(net_write(fx, 0x1010, 1, CO_STORE_SAVE_SIGNATURE), 0);
    put(fx, 0x1017, 1);
    put(fx, 0x2000, 1);
    put(fx, 0x2001, 1);
    put(fx, 0x6000, 1);
    assert_int_equal(co_store_load_at_reset(&fx->store, true), CO_STORE_OK);
    assert_int_equal(get(fx, 0x1017), 500);
    assert_int_equal(get(fx, 0x2001), 22);
    assert_int_equal(get(fx, 0x2000), 1);   /* default: never saved on command */
    assert_int_equal(get(fx, 0x6000), 3);   /* disabled: default */
}

static void test_reset_type_decides_when_a_group_comes_back(void **state)
{
    fixture_t *fx = *state;
    put(fx, 0x1017, 500);
    put(fx, 0x2000, 11);
    put(fx, 0x2001, 22);
    put(fx, 0x6000, 33);                   /* disabled: never saved, even by "all" */
    assert_int_equal(co_store_save(&fx->store, 0xFF), 0);
    put(fx, 0x1017, 7);
    put(fx, 0x2000, 7);
    put(fx, 0x2001, 7);
    put(fx, 0x6000, 7);
    /* reset communication: groups 2 and 4 (reset type communication) only */
    assert_int_equal(co_store_reset_groups(&fx->store, false), 0x1 | 0x4);
    assert_int_equal(co_store_load_at_reset(&fx->store, false), CO_STORE_OK);
    assert_int_equal(get(fx, 0x1017), 500);
    assert_int_equal(get(fx, 0x2001), 22);
    assert_int_equal(get(fx, 0x2000), 7);   /* reset node group: untouched */
    assert_int_equal(get(fx, 0x6000), 7);
    /* reset node: every group */
    assert_int_equal(co_store_load_at_reset(&fx->store, true), CO_STORE_OK);
    assert_int_equal(get(fx, 0x2000), 11);
    assert_int_equal(get(fx, 0x6000), 3);
}

static void test_autonomous_saves_are_rate_bounded(void **state)
{
    fixture_t *fx = *state;
    uint32_t v;
    at_ms(fx, 1000);
    put(fx, 0x1017, 600);              /* on command only: no autonomous save */
    at_ms(fx, 1001);
    assert_int_equal(fx->mem.saves, 0);
    put(fx, 0x2000, 100);              /* the first change is saved at once */
    at_ms(fx, 1001);
    assert_int_equal(fx->mem.saves, 1);
    /* a burst: one save one interval after the previous */
    for (v = 101; v < 151; v++) {
        put(fx, 0x2000, v);
        at_ms(fx, 1001 + (v - 100));
    }
    assert_int_equal(fx->mem.saves, 1);
    at_ms(fx, 1001 + INTERVAL_MS - 1);
    assert_int_equal(fx->mem.saves, 1);
    at_ms(fx, 1001 + INTERVAL_MS);
    assert_int_equal(fx->mem.saves, 2);
    assert_int_equal(fx->store.autonomous_saves, 2);
    /* what was saved: the last value; 0x1017 (on command) was not */
    put(fx, 0x2000, 1);
    put(fx, 0x1017, 1);
    assert_int_equal(co_store_load_at_reset(&fx->store, true), CO_STORE_OK);
    assert_int_equal(get(fx, 0x2000), 150);
    assert_int_equal(get(fx, 0x1017), 1000);
    /* a load is no change: nothing armed */
    at_ms(fx, 5000);
    assert_int_equal(fx->mem.saves, 2);
    /* the reload wrote 0x2000 back to 150 (CO_ORIGIN_RESTORE): still 2 */
    assert_int_equal(fx->store.changed, 0);
}

static void test_power_cut_during_an_autonomous_save(void **state)
{
    fixture_t *fx = *state;
    co_store_t rebooted;
    uint8_t buf2[2048];
    co_store_config_t c;
    put(fx, 0x2001, 40);
    at_ms(fx, 10);
    assert_int_equal(fx->mem.saves, 1);
    /* the medium loses power while the next autonomous image is written: an
     * atomic backend keeps the previous image (co_store_file: temp + rename) */
    fx->mem.fail_save = true;
    put(fx, 0x2001, 41);
    at_ms(fx, 10 + INTERVAL_MS);
    assert_int_equal(fx->store.autonomous_failures, 1);
    assert_int_equal(fx->store.changed, 0x4);   /* kept for the retry */
    /* the device restarts from the medium: the old value, whole */
    co_store_deinit(&fx->store);
    fx->mem.fail_save = false;
    c = config_of(fx, groups, ROWS(groups));
    assert_true(co_store_init_config(&rebooted, &fx->od, &tu_mem_ops, &fx->mem, buf2,
                                     sizeof buf2, &c));
    assert_int_equal(co_store_load_at_reset(&rebooted, true), CO_STORE_OK);
    assert_int_equal(get(fx, 0x2001), 40);
    co_store_deinit(&rebooted);
    c = config_of(fx, groups, ROWS(groups));
    assert_true(co_store_init_config(&fx->store, &fx->od, &tu_mem_ops, &fx->mem, fx->buf,
                                     sizeof fx->buf, &c));
}

static void test_a_failed_autonomous_save_is_retried(void **state)
{
    fixture_t *fx = *state;
    fx->mem.fail_save = true;
    put(fx, 0x2000, 9);
    at_ms(fx, 0);
    assert_int_equal(fx->store.autonomous_failures, 1);
    assert_int_equal(fx->told, 1);
    assert_int_equal(fx->last_abort, CO_ABORT_HARDWARE);   /* the application hears it */
    fx->mem.fail_save = false;
    at_ms(fx, INTERVAL_MS - 1);
    assert_int_equal(fx->store.autonomous_saves, 0);
    at_ms(fx, INTERVAL_MS);
    assert_int_equal(fx->store.autonomous_saves, 1);
    assert_int_equal(fx->told, 2);
    assert_int_equal(fx->last_abort, 0);
    put(fx, 0x2000, 1);
    assert_int_equal(co_store_load_at_reset(&fx->store, true), CO_STORE_OK);
    assert_int_equal(get(fx, 0x2000), 9);
}

static void test_changed_behind_the_od_is_saved_too(void **state)
{
    fixture_t *fx = *state;
    const co_od_entry_t *e = co_od_find(&fx->od, 0x2001, 0);
    /* the application changed the value in place (no co_od_put) and says so */
    tu_le_put(co_od_value(&fx->od, e), 77, 4);
    co_store_changed(&fx->store, 0xFF);    /* only autonomous groups are marked */
    assert_int_equal(fx->store.changed, 0x2 | 0x4);
    at_ms(fx, 0);
    assert_int_equal(fx->store.autonomous_saves, 1);
    tu_le_put(co_od_value(&fx->od, e), 1, 4);
    assert_int_equal(co_store_load_at_reset(&fx->store, true), CO_STORE_OK);
    assert_int_equal(get(fx, 0x2001), 77);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_declarations_that_are_refused, setup, teardown),
        cmocka_unit_test_setup_teardown(test_capability_bits_per_group, setup, teardown),
        cmocka_unit_test_setup_teardown(test_save_on_command_only_where_declared, setup,
                                        teardown),
        cmocka_unit_test_setup_teardown(test_reset_type_decides_when_a_group_comes_back, setup,
                                        teardown),
        cmocka_unit_test_setup_teardown(test_autonomous_saves_are_rate_bounded, setup,
                                        teardown),
        cmocka_unit_test_setup_teardown(test_power_cut_during_an_autonomous_save, setup,
                                        teardown),
        cmocka_unit_test_setup_teardown(test_a_failed_autonomous_save_is_retried, setup,
                                        teardown),
        cmocka_unit_test_setup_teardown(test_changed_behind_the_od_is_saved_too, setup,
                                        teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
