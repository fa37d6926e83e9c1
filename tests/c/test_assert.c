/* CO_ASSERT: an application or test may define it; the core then reports
 * broken internal contracts through it. This binary builds the core with
 * CO_ASSERT going to cmocka (test_assert_hook.h), breaks documented
 * preconditions on purpose and expects each to be caught. */
#include "test_od_util.h"

#ifdef NDEBUG
#error "the C tests run with assertions on"
#endif

#ifndef TEST_ASSERT_HOOK_H
#error "test_assert is built with -include test_assert_hook.h"
#endif

static void test_queue_without_storage_is_caught(void **state)
{
    co_frame_queue_t q;
    (void)state;
    expect_assert_failure(co_queue_init(&q, NULL, 4));
}

static void test_queue_at_past_the_count_is_caught(void **state)
{
    co_frame_t slots[4];
    co_frame_queue_t q;
    co_frame_t f;
    (void)state;
    co_queue_init(&q, slots, 4);
    co_frame_set(&f, 0x181, 0, (const uint8_t *)"\x01", 1);
    assert_true(co_queue_push(&q, &f));
    assert_int_equal(co_queue_at(&q, 0)->id, 0x181);   /* within the count: no report */
    expect_assert_failure(co_queue_at(&q, 1));
}

static void test_corrupt_queue_is_caught(void **state)
{
    co_frame_t slots[4];
    co_frame_queue_t q;
    co_frame_t f;
    (void)state;
    co_queue_init(&q, slots, 4);
    co_frame_set(&f, 0x181, 0, (const uint8_t *)"\x01", 1);
    q.count = 5;   /* more frames than slots: only a bug gets here */
    expect_assert_failure(co_queue_push(&q, &f));
}

static void noop(co_timer_t *timer, uint64_t now_us, void *user)
{
    (void)timer;
    (void)now_us;
    (void)user;
}

static void test_timer_cancelled_on_another_list_is_caught(void **state)
{
    co_timer_list_t mine;
    co_timer_list_t other;
    co_timer_t t;
    co_timer_t elsewhere;
    (void)state;
    co_timer_list_init(&mine);
    co_timer_list_init(&other);
    co_timer_init(&t, noop, NULL);
    co_timer_init(&elsewhere, noop, NULL);
    co_timer_start(&mine, &t, 100);
    co_timer_start(&other, &elsewhere, 100);   /* so only the links give it away */
    expect_assert_failure(co_timer_cancel(&other, &t));
    co_timer_cancel(&mine, &t);   /* its own list: no report */
    assert_false(co_timer_is_armed(&t));
}

static void test_line_id_beyond_11_bits_is_caught(void **state)
{
    static tu_line_t l;
    volatile uint32_t id = 0x800;   /* unknown to the compiler: no bounds warning */
    (void)state;
    tu_line_init(&l, CO_MODE_CLASSIC, false);
    assert_false(co_line_id_taken(&l.line, 0x7FF));
    expect_assert_failure(co_line_id_taken(&l.line, id));
}

/* The scratch a transfer collects into shrinks under it (a caller changed
 * what co_od_xfer_init was given): the chunk that would overrun is caught. */
static void test_od_scratch_changed_during_a_transfer_is_caught(void **state)
{
    co_od_entry_t entries[1];
    uint8_t pool[8];
    co_od_subscription_t subs[1];
    co_od_t od;
    co_od_xfer_t x;
    uint8_t scratch[8];
    const uint8_t value[4] = {1, 2, 3, 4};
    co_od_def_t d = tu_od_def(0x2000, 0, VAR, U32, RW, 0, 4);
    (void)state;
    co_od_init(&od, CO_MODE_CLASSIC, entries, 1, pool, sizeof pool, subs, 1);
    assert_int_equal(co_od_add(&od, &d), CO_OD_ADDED);
    assert_true(co_od_seal(&od, 1));
    co_od_xfer_init(&x, scratch, sizeof scratch);
    assert_int_equal(co_od_write_begin(&od, &x, 0x2000, 0, 4), 0);
    x.scratch_size = 2;
    expect_assert_failure(co_od_write_chunk(&x, value, 4));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_queue_without_storage_is_caught),
        cmocka_unit_test(test_queue_at_past_the_count_is_caught),
        cmocka_unit_test(test_corrupt_queue_is_caught),
        cmocka_unit_test(test_timer_cancelled_on_another_list_is_caught),
        cmocka_unit_test(test_line_id_beyond_11_bits_is_caught),
        cmocka_unit_test(test_od_scratch_changed_during_a_transfer_is_caught),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
