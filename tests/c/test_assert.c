/* CO_ASSERT: an application or test may define it; the core then reports
 * broken internal contracts through it. This binary builds the core with
 * CO_ASSERT going to cmocka (test_assert_hook.h), breaks documented
 * preconditions on purpose and expects each to be caught. */
#include "test_util.h"

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

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_queue_without_storage_is_caught),
        cmocka_unit_test(test_queue_at_past_the_count_is_caught),
        cmocka_unit_test(test_corrupt_queue_is_caught),
        cmocka_unit_test(test_timer_cancelled_on_another_list_is_caught),
        cmocka_unit_test(test_line_id_beyond_11_bits_is_caught),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
