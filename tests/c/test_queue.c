/* co_queue: bounded frame FIFO over caller-owned storage. */
#include "test_util.h"

#define CAP 4

static co_frame_t numbered(uint32_t n)
{
    co_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = n & 0x7FF;
    f.len = 4;
    f.data[0] = (uint8_t)n;
    f.data[1] = (uint8_t)(n >> 8);
    f.data[2] = (uint8_t)(n >> 16);
    f.data[3] = (uint8_t)(n >> 24);
    return f;
}

static uint32_t number_of(const co_frame_t *f)
{
    return (uint32_t)f->data[0] | ((uint32_t)f->data[1] << 8) |
           ((uint32_t)f->data[2] << 16) | ((uint32_t)f->data[3] << 24);
}

static void test_init_empty(void **state)
{
    co_frame_t slots[CAP];
    co_frame_queue_t q;
    co_frame_t out;
    (void)state;
    co_queue_init(&q, slots, CAP);
    assert_true(co_queue_is_empty(&q));
    assert_false(co_queue_is_full(&q));
    assert_int_equal(co_queue_count(&q), 0);
    assert_int_equal(q.overflows, 0);
    assert_int_equal(q.high_water, 0);
    assert_null(co_queue_peek(&q));
    assert_false(co_queue_pop(&q, &out));
}

static void test_fill_to_capacity(void **state)
{
    co_frame_t slots[CAP];
    co_frame_queue_t q;
    uint32_t i;
    (void)state;
    co_queue_init(&q, slots, CAP);
    for (i = 0; i < CAP; i++) {
        co_frame_t f = numbered(i);
        assert_false(co_queue_is_full(&q));
        assert_true(co_queue_push(&q, &f));
        assert_int_equal(co_queue_count(&q), i + 1);
    }
    assert_true(co_queue_is_full(&q));
    assert_int_equal(q.overflows, 0);
}

static void test_overflow_refused_and_counted(void **state)
{
    co_frame_t slots[CAP];
    co_frame_queue_t q;
    co_frame_t f, out;
    uint32_t i;
    (void)state;
    co_queue_init(&q, slots, CAP);
    for (i = 0; i < CAP; i++) {
        f = numbered(i);
        assert_true(co_queue_push(&q, &f));
    }
    f = numbered(100);
    assert_false(co_queue_push(&q, &f));
    f = numbered(101);
    assert_false(co_queue_push(&q, &f));
    assert_int_equal(q.overflows, 2);
    assert_int_equal(co_queue_count(&q), CAP);
    /* nothing was overwritten */
    for (i = 0; i < CAP; i++) {
        assert_true(co_queue_pop(&q, &out));
        assert_int_equal(number_of(&out), i);
    }
    assert_true(co_queue_is_empty(&q));
}

static void test_pop_copies_whole_frame(void **state)
{
    co_frame_t slots[CAP];
    co_frame_queue_t q;
    co_frame_t f, out;
    uint8_t i;
    (void)state;
    co_queue_init(&q, slots, CAP);
    memset(&f, 0, sizeof f);
    f.id = 0x1ABCDEF;
    f.flags = CO_FRAME_EXT | CO_FRAME_FD | CO_FRAME_BRS;
    f.len = 64;
    for (i = 0; i < 64; i++)
        f.data[i] = (uint8_t)(i * 3 + 1);
    assert_true(co_queue_push(&q, &f));
    memset(&out, 0, sizeof out);
    assert_true(co_queue_pop(&q, &out));
    tu_assert_frame(&out, f.id, f.flags, f.data, 64);
}

static void test_fifo_order_across_wrap_around(void **state)
{
    co_frame_t slots[CAP];
    co_frame_queue_t q;
    co_frame_t f, out;
    uint32_t next_in = 0, next_out = 0;
    int round;
    (void)state;
    co_queue_init(&q, slots, CAP);
    /* Push 3, pop 2 repeatedly: head and tail wrap many times at
     * different offsets. */
    for (round = 0; round < 50; round++) {
        int k;
        for (k = 0; k < 3 && !co_queue_is_full(&q); k++) {
            f = numbered(next_in++);
            assert_true(co_queue_push(&q, &f));
        }
        for (k = 0; k < 2; k++) {
            assert_true(co_queue_pop(&q, &out));
            assert_int_equal(number_of(&out), next_out++);
        }
    }
    while (co_queue_pop(&q, &out))
        assert_int_equal(number_of(&out), next_out++);
    assert_int_equal(next_in, next_out);
    assert_true(next_in > 3 * CAP);
    assert_int_equal(q.overflows, 0);
}

static void test_peek_returns_oldest_without_removing(void **state)
{
    co_frame_t slots[CAP];
    co_frame_queue_t q;
    co_frame_t f;
    const co_frame_t *p;
    (void)state;
    co_queue_init(&q, slots, CAP);
    f = numbered(7);
    assert_true(co_queue_push(&q, &f));
    f = numbered(8);
    assert_true(co_queue_push(&q, &f));
    p = co_queue_peek(&q);
    assert_non_null(p);
    assert_int_equal(number_of(p), 7);
    assert_int_equal(co_queue_count(&q), 2);
    p = co_queue_peek(&q);
    assert_int_equal(number_of(p), 7);
}

static void test_drop_head_removes_oldest(void **state)
{
    co_frame_t slots[CAP];
    co_frame_queue_t q;
    co_frame_t f, out;
    (void)state;
    co_queue_init(&q, slots, CAP);
    f = numbered(1);
    assert_true(co_queue_push(&q, &f));
    f = numbered(2);
    assert_true(co_queue_push(&q, &f));
    co_queue_drop_head(&q);
    assert_int_equal(co_queue_count(&q), 1);
    assert_int_equal(number_of(co_queue_peek(&q)), 2);
    assert_true(co_queue_pop(&q, &out));
    assert_int_equal(number_of(&out), 2);
}

static void test_drop_head_on_empty_is_harmless(void **state)
{
    co_frame_t slots[CAP];
    co_frame_queue_t q;
    co_frame_t f, out;
    (void)state;
    co_queue_init(&q, slots, CAP);
    co_queue_drop_head(&q);
    assert_int_equal(co_queue_count(&q), 0);
    f = numbered(5);
    assert_true(co_queue_push(&q, &f));
    assert_true(co_queue_pop(&q, &out));
    assert_int_equal(number_of(&out), 5);
    assert_true(co_queue_is_empty(&q));
}

static void test_peek_drop_across_wrap_around(void **state)
{
    co_frame_t slots[CAP];
    co_frame_queue_t q;
    co_frame_t f;
    uint32_t in = 0, out = 0;
    int i;
    (void)state;
    co_queue_init(&q, slots, CAP);
    for (i = 0; i < 3 * CAP + 1; i++) {
        f = numbered(in++);
        assert_true(co_queue_push(&q, &f));
        if (i % 2 == 1) {
            assert_int_equal(number_of(co_queue_peek(&q)), out++);
            co_queue_drop_head(&q);
        }
        if (co_queue_is_full(&q)) {
            assert_int_equal(number_of(co_queue_peek(&q)), out++);
            co_queue_drop_head(&q);
        }
    }
    while (!co_queue_is_empty(&q)) {
        assert_int_equal(number_of(co_queue_peek(&q)), out++);
        co_queue_drop_head(&q);
    }
    assert_int_equal(in, out);
}

static void test_high_water_tracks_largest_count(void **state)
{
    co_frame_t slots[CAP];
    co_frame_queue_t q;
    co_frame_t f, out;
    (void)state;
    co_queue_init(&q, slots, CAP);
    f = numbered(0);
    assert_true(co_queue_push(&q, &f));
    assert_true(co_queue_push(&q, &f));
    assert_true(co_queue_push(&q, &f));
    assert_int_equal(q.high_water, 3);
    assert_true(co_queue_pop(&q, &out));
    assert_true(co_queue_pop(&q, &out));
    assert_int_equal(q.high_water, 3);
    assert_true(co_queue_push(&q, &f));
    assert_int_equal(q.high_water, 3);
    assert_true(co_queue_push(&q, &f));
    assert_true(co_queue_push(&q, &f));
    assert_int_equal(q.high_water, 4);
    assert_false(co_queue_push(&q, &f));
    assert_int_equal(q.high_water, 4);
}

static void test_clear_empties_queue(void **state)
{
    co_frame_t slots[CAP];
    co_frame_queue_t q;
    co_frame_t f, out;
    (void)state;
    co_queue_init(&q, slots, CAP);
    f = numbered(1);
    assert_true(co_queue_push(&q, &f));
    assert_true(co_queue_push(&q, &f));
    co_queue_clear(&q);
    assert_true(co_queue_is_empty(&q));
    assert_null(co_queue_peek(&q));
    assert_false(co_queue_pop(&q, &out));
    /* usable again, to full capacity */
    for (f.id = 0; f.id < CAP; f.id++)
        assert_true(co_queue_push(&q, &f));
    assert_true(co_queue_is_full(&q));
}

static void test_capacity_one(void **state)
{
    co_frame_t slots[1];
    co_frame_queue_t q;
    co_frame_t f, out;
    uint32_t i;
    (void)state;
    co_queue_init(&q, slots, 1);
    for (i = 0; i < 5; i++) {
        f = numbered(i);
        assert_true(co_queue_push(&q, &f));
        assert_true(co_queue_is_full(&q));
        assert_false(co_queue_push(&q, &f));
        assert_true(co_queue_pop(&q, &out));
        assert_int_equal(number_of(&out), i);
    }
    assert_int_equal(q.overflows, 5);
    assert_int_equal(q.high_water, 1);
}

static void test_storage_stays_inside_slots(void **state)
{
    /* Guard frames around the storage must never be written. */
    co_frame_t storage[CAP + 2];
    co_frame_queue_t q;
    co_frame_t f, out, guard;
    uint32_t i;
    (void)state;
    memset(storage, 0x5A, sizeof storage);
    memset(&guard, 0x5A, sizeof guard);
    co_queue_init(&q, &storage[1], CAP);
    for (i = 0; i < 10 * CAP; i++) {
        f = numbered(i);
        memset(f.data + 4, 0xEE, 60);
        f.len = 64;
        f.flags = CO_FRAME_FD;
        (void)co_queue_push(&q, &f);
        (void)co_queue_push(&q, &f);
        assert_true(co_queue_pop(&q, &out));
    }
    assert_memory_equal(&storage[0], &guard, sizeof guard);
    assert_memory_equal(&storage[CAP + 1], &guard, sizeof guard);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_init_empty),
        cmocka_unit_test(test_fill_to_capacity),
        cmocka_unit_test(test_overflow_refused_and_counted),
        cmocka_unit_test(test_pop_copies_whole_frame),
        cmocka_unit_test(test_fifo_order_across_wrap_around),
        cmocka_unit_test(test_peek_returns_oldest_without_removing),
        cmocka_unit_test(test_drop_head_removes_oldest),
        cmocka_unit_test(test_drop_head_on_empty_is_harmless),
        cmocka_unit_test(test_peek_drop_across_wrap_around),
        cmocka_unit_test(test_high_water_tracks_largest_count),
        cmocka_unit_test(test_clear_empties_queue),
        cmocka_unit_test(test_capacity_one),
        cmocka_unit_test(test_storage_stays_inside_slots),
    };
    return cmocka_run_group_tests_name("queue", tests, NULL, NULL);
}
