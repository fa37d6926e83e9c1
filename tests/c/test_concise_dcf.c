/* Concise DCF codec (CiA 302-3): the writer's bytes are the documented
 * layout, the iterator reads them back, and every malformation is refused
 * with its own status and the byte offset where it was found, never reading
 * past the buffer (the ASan build runs each case on an exactly sized heap
 * copy, so one byte too far is a crash). */
#include "test_util.h"

#include "canopenfd/co_concise_dcf.h"

#include <stdlib.h>

/* A heap copy of exactly len bytes, so ASan catches any read past it. */
static uint8_t *exact_copy(const uint8_t *data, uint32_t len)
{
    uint8_t *p = malloc(len > 0 ? len : 1);
    assert_non_null(p);
    if (len > 0)
        memcpy(p, data, len);
    return p;
}

static co_concise_status_t validate(const uint8_t *data, uint32_t len, uint32_t *count,
                                    uint32_t *offset)
{
    uint8_t *copy = exact_copy(data, len);
    co_concise_status_t s = co_concise_validate(copy, len, count, offset);
    free(copy);
    return s;
}

/* Two entries: 0x1017:00 = 1000 (U16) and 0x1800:01 = 0x80000185 (U32). */
static const uint8_t two_entries[] = {
    0x02, 0x00, 0x00, 0x00,                                  /* count 2 */
    0x17, 0x10, 0x00, 0x02, 0x00, 0x00, 0x00, 0xE8, 0x03,    /* 0x1017:00, 2 bytes */
    0x00, 0x18, 0x01, 0x04, 0x00, 0x00, 0x00, 0x85, 0x01, 0x00, 0x80,
};

static void test_writer_bytes_are_the_layout(void **state)
{
    (void)state;
    uint8_t buf[64];
    co_concise_writer_t w;
    co_concise_writer_init(&w, buf, sizeof buf);
    assert_true(co_concise_add_u32(&w, 0x1017, 0, 1000, 2));
    assert_true(co_concise_add_u32(&w, 0x1800, 1, 0x80000185u, 4));
    uint32_t len = co_concise_finish(&w);
    assert_int_equal(len, sizeof two_entries);
    assert_memory_equal(buf, two_entries, sizeof two_entries);
}

static void test_iterator_reads_entries_back(void **state)
{
    (void)state;
    uint8_t *copy = exact_copy(two_entries, sizeof two_entries);
    co_concise_iter_t it;
    co_concise_entry_t e;
    assert_int_equal(co_concise_iter_init(&it, copy, sizeof two_entries), CO_CONCISE_OK);
    assert_int_equal(it.count, 2);
    assert_int_equal(co_concise_next(&it, &e), CO_CONCISE_OK);
    assert_int_equal(e.index, 0x1017);
    assert_int_equal(e.sub, 0);
    assert_int_equal(e.size, 2);
    assert_int_equal(e.offset, 4);
    assert_int_equal(e.number, 0);
    assert_int_equal(e.data[0] | e.data[1] << 8, 1000);
    assert_int_equal(co_concise_next(&it, &e), CO_CONCISE_OK);
    assert_int_equal(e.index, 0x1800);
    assert_int_equal(e.sub, 1);
    assert_int_equal(e.size, 4);
    assert_int_equal(e.offset, 13);
    assert_int_equal(e.number, 1);
    assert_int_equal(co_concise_next(&it, &e), CO_CONCISE_END);
    assert_int_equal(co_concise_next(&it, &e), CO_CONCISE_END);   /* stays at the end */
    free(copy);
    uint32_t count = 99, offset = 99;
    assert_int_equal(validate(two_entries, sizeof two_entries, &count, &offset), CO_CONCISE_OK);
    assert_int_equal(count, 2);
    assert_int_equal(offset, 0);
}

/* Round trip of random DCFs: sizes 0..300, any index and sub. */
static void test_random_round_trip(void **state)
{
    (void)state;
    static uint8_t buf[64 * 1024];
    static uint8_t values[300];
    uint64_t seed = 0x5eed;
    int round;
    for (round = 0; round < 200; round++) {
        co_concise_writer_t w;
        uint32_t n = (uint32_t)(tu_rand(&seed) % 40), i;
        uint16_t idx[40];
        uint8_t sub[40];
        uint32_t size[40];
        co_concise_writer_init(&w, buf, sizeof buf);
        for (i = 0; i < n; i++) {
            uint32_t k;
            idx[i] = (uint16_t)tu_rand(&seed);
            sub[i] = (uint8_t)tu_rand(&seed);
            size[i] = (uint32_t)(tu_rand(&seed) % 300);
            for (k = 0; k < size[i]; k++)
                values[k] = (uint8_t)(i + k);
            assert_true(co_concise_add(&w, idx[i], sub[i], values, size[i]));
        }
        uint32_t len = co_concise_finish(&w);
        assert_true(len >= 4);
        uint8_t *copy = exact_copy(buf, len);
        co_concise_iter_t it;
        co_concise_entry_t e;
        assert_int_equal(co_concise_iter_init(&it, copy, len), CO_CONCISE_OK);
        for (i = 0; i < n; i++) {
            uint32_t k;
            assert_int_equal(co_concise_next(&it, &e), CO_CONCISE_OK);
            assert_int_equal(e.index, idx[i]);
            assert_int_equal(e.sub, sub[i]);
            assert_int_equal(e.size, size[i]);
            for (k = 0; k < e.size; k++)
                assert_int_equal(e.data[k], (uint8_t)(i + k));
        }
        assert_int_equal(co_concise_next(&it, &e), CO_CONCISE_END);
        free(copy);
    }
}

static void test_empty_dcf_is_valid(void **state)
{
    (void)state;
    const uint8_t empty[] = {0, 0, 0, 0};
    uint32_t count = 9;
    assert_int_equal(validate(empty, 4, &count, NULL), CO_CONCISE_OK);
    assert_int_equal(count, 0);
}

/* Fewer than 4 bytes: no count, at offset 0 (also a NULL buffer). */
static void test_no_count(void **state)
{
    (void)state;
    uint32_t len, offset = 99;
    for (len = 0; len < 4; len++) {
        assert_int_equal(validate(two_entries, len, NULL, &offset), CO_CONCISE_NO_COUNT);
        assert_int_equal(offset, 0);
    }
    assert_int_equal(co_concise_validate(NULL, 10, NULL, NULL), CO_CONCISE_NO_COUNT);
}

/* Every cut inside an entry header is TRUNCATED_HEADER at the header's
 * start; every cut inside the data is SIZE_PAST_END at the size field. */
static void test_every_truncation(void **state)
{
    (void)state;
    uint32_t len;
    for (len = 5; len < sizeof two_entries; len++) {
        uint32_t count = 0, offset = 0;
        co_concise_status_t s = validate(two_entries, len, &count, &offset);
        if (len < 4 + 7) {
            assert_int_equal(s, CO_CONCISE_TRUNCATED_HEADER);
            assert_int_equal(offset, 4);
        } else if (len < 13) {
            assert_int_equal(s, CO_CONCISE_SIZE_PAST_END);
            assert_int_equal(offset, 7);
        } else if (len == 13) {
            assert_int_equal(s, CO_CONCISE_COUNT_MISMATCH);   /* one entry of two */
            assert_int_equal(offset, 13);
            assert_int_equal(count, 1);
        } else if (len < 13 + 7) {
            assert_int_equal(s, CO_CONCISE_TRUNCATED_HEADER);
            assert_int_equal(offset, 13);
        } else {
            assert_int_equal(s, CO_CONCISE_SIZE_PAST_END);
            assert_int_equal(offset, 16);
        }
    }
}

/* A size near 2^32 must not wrap the bounds check. */
static void test_huge_size_does_not_wrap(void **state)
{
    (void)state;
    uint8_t d[sizeof two_entries];
    uint32_t offset = 0;
    memcpy(d, two_entries, sizeof d);
    d[7] = 0xFF; d[8] = 0xFF; d[9] = 0xFF; d[10] = 0xFF;
    assert_int_equal(validate(d, sizeof d, NULL, &offset), CO_CONCISE_SIZE_PAST_END);
    assert_int_equal(offset, 7);
    d[7] = 0xF9;   /* 0xFFFFFFF9: header + size wraps to exactly 0 */
    assert_int_equal(validate(d, sizeof d, NULL, &offset), CO_CONCISE_SIZE_PAST_END);
}

static void test_count_mismatch_and_trailing_bytes(void **state)
{
    (void)state;
    uint8_t d[sizeof two_entries + 3];
    uint32_t count = 0, offset = 0;
    memcpy(d, two_entries, sizeof two_entries);
    d[0] = 3;   /* announces 3, holds 2 */
    assert_int_equal(validate(d, sizeof two_entries, &count, &offset), CO_CONCISE_COUNT_MISMATCH);
    assert_int_equal(count, 2);
    assert_int_equal(offset, sizeof two_entries);
    d[0] = 1;   /* announces 1, holds 2: the second one is trailing */
    assert_int_equal(validate(d, sizeof two_entries, &count, &offset),
                     CO_CONCISE_TRAILING_BYTES);
    assert_int_equal(count, 1);
    assert_int_equal(offset, 13);
    d[0] = 2;   /* right count, 3 bytes of junk after */
    d[sizeof two_entries] = 1;
    d[sizeof two_entries + 1] = 2;
    d[sizeof two_entries + 2] = 3;
    assert_int_equal(validate(d, sizeof d, &count, &offset), CO_CONCISE_TRAILING_BYTES);
    assert_int_equal(offset, sizeof two_entries);
    /* a huge count over a short buffer ends as a mismatch, not a long walk */
    d[0] = 0xFF; d[1] = 0xFF; d[2] = 0xFF; d[3] = 0xFF;
    assert_int_equal(validate(d, sizeof two_entries, &count, &offset), CO_CONCISE_COUNT_MISMATCH);
}

/* Errors are sticky: next() keeps returning the first one. */
static void test_errors_are_sticky(void **state)
{
    (void)state;
    co_concise_iter_t it;
    co_concise_entry_t e;
    assert_int_equal(co_concise_iter_init(&it, two_entries, 12), CO_CONCISE_OK);
    assert_int_equal(co_concise_next(&it, &e), CO_CONCISE_SIZE_PAST_END);
    assert_int_equal(co_concise_next(&it, &e), CO_CONCISE_SIZE_PAST_END);
    assert_int_equal(it.error_offset, 7);
    assert_string_equal(co_concise_status_text(CO_CONCISE_SIZE_PAST_END),
                        "entry data size goes past the end");
}

/* The writer refuses what does not fit and then fails finish. */
static void test_writer_overflow(void **state)
{
    (void)state;
    uint8_t buf[14];
    co_concise_writer_t w;
    co_concise_writer_init(&w, buf, sizeof buf);
    assert_true(co_concise_add_u32(&w, 0x2000, 0, 7, 1));     /* 4 + 8 = 12 */
    assert_false(co_concise_add_u32(&w, 0x2001, 0, 7, 1));    /* needs 8 more */
    assert_int_equal(co_concise_finish(&w), 0);
    co_concise_writer_init(&w, buf, 3);                        /* no room for the count */
    assert_int_equal(co_concise_finish(&w), 0);
    co_concise_writer_init(&w, buf, sizeof buf);
    assert_false(co_concise_add_u32(&w, 0x2000, 0, 7, 5));    /* 1..4 bytes only */
    assert_int_equal(co_concise_finish(&w), 0);
    co_concise_writer_init(&w, buf, sizeof buf);
    assert_int_equal(co_concise_finish(&w), 4);                /* empty DCF */
    assert_memory_equal(buf, ((const uint8_t[]){0, 0, 0, 0}), 4);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_writer_bytes_are_the_layout),
        cmocka_unit_test(test_iterator_reads_entries_back),
        cmocka_unit_test(test_random_round_trip),
        cmocka_unit_test(test_empty_dcf_is_valid),
        cmocka_unit_test(test_no_count),
        cmocka_unit_test(test_every_truncation),
        cmocka_unit_test(test_huge_size_does_not_wrap),
        cmocka_unit_test(test_count_mismatch_and_trailing_bytes),
        cmocka_unit_test(test_errors_are_sticky),
        cmocka_unit_test(test_writer_overflow),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
