/* co_frame: CAN FD length rules, DLC table, frame validity, co_frame_set. */
#include "test_util.h"

/* Reference: smallest valid CAN FD length >= n (CAN FD spec, research §1.1). */
static unsigned ref_round(size_t n)
{
    static const unsigned steps[] = {12, 16, 20, 24, 32, 48, 64};
    size_t i;
    if (n <= 8)
        return (unsigned)n;
    for (i = 0; i < sizeof steps / sizeof steps[0]; i++)
        if (n <= steps[i])
            return steps[i];
    return 0xFF;
}

static const uint8_t dlc_table[16] = {0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64};

/* ------------------------------------------------------------ lengths */

static void test_fd_len_round_every_n_0_to_65(void **state)
{
    size_t n;
    (void)state;
    for (n = 0; n <= 65; n++) {
        uint8_t got = co_fd_len_round(n);
        if (got != ref_round(n))
            fail_msg("co_fd_len_round(%u) = %u, expected %u", (unsigned)n, got, ref_round(n));
    }
}

static void test_fd_len_round_examples_from_spec(void **state)
{
    (void)state;
    assert_int_equal(co_fd_len_round(13), 16);
    assert_int_equal(co_fd_len_round(25), 32);
    assert_int_equal(co_fd_len_round(49), 64);
    assert_int_equal(co_fd_len_round(9), 12);
    assert_int_equal(co_fd_len_round(64), 64);
}

static void test_fd_len_round_too_long_gives_ff(void **state)
{
    (void)state;
    assert_int_equal(co_fd_len_round(65), 0xFF);
    assert_int_equal(co_fd_len_round(255), 0xFF);
    assert_int_equal(co_fd_len_round(256), 0xFF);     /* must not wrap to 0 */
    assert_int_equal(co_fd_len_round(100000), 0xFF);
    assert_int_equal(co_fd_len_round((size_t)-1), 0xFF);
}

static void test_fd_len_valid_exactly_the_sixteen_lengths(void **state)
{
    size_t n;
    (void)state;
    for (n = 0; n <= 300; n++) {
        bool expected = (n <= 64) && ref_round(n) == n;
        if (co_fd_len_valid(n) != expected)
            fail_msg("co_fd_len_valid(%u) = %d, expected %d", (unsigned)n,
                     (int)co_fd_len_valid(n), (int)expected);
    }
    assert_false(co_fd_len_valid(64 + 256));          /* no truncation to uint8 */
}

static void test_fd_dlc_to_len_table(void **state)
{
    uint8_t dlc;
    (void)state;
    for (dlc = 0; dlc < 16; dlc++)
        assert_int_equal(co_fd_dlc_to_len(dlc), dlc_table[dlc]);
}

static void test_fd_dlc_to_len_codes_above_15_give_ff(void **state)
{
    unsigned dlc;
    (void)state;
    for (dlc = 16; dlc <= 255; dlc++)
        assert_int_equal(co_fd_dlc_to_len((uint8_t)dlc), 0xFF);
}

static void test_fd_len_to_dlc_table(void **state)
{
    uint8_t dlc;
    (void)state;
    for (dlc = 0; dlc < 16; dlc++)
        assert_int_equal(co_fd_len_to_dlc(dlc_table[dlc]), dlc);
}

static void test_fd_len_to_dlc_invalid_lengths_give_ff(void **state)
{
    size_t n;
    (void)state;
    for (n = 0; n <= 300; n++) {
        if (n <= 64 && ref_round(n) == n)
            continue;
        if (co_fd_len_to_dlc(n) != 0xFF)
            fail_msg("co_fd_len_to_dlc(%u) = %u, expected 0xFF", (unsigned)n,
                     co_fd_len_to_dlc(n));
    }
    assert_int_equal(co_fd_len_to_dlc(8 + 256), 0xFF);   /* no truncation to uint8 */
}

static void test_fd_dlc_len_round_trip(void **state)
{
    uint8_t dlc;
    (void)state;
    for (dlc = 0; dlc < 16; dlc++)
        assert_int_equal(co_fd_len_to_dlc(co_fd_dlc_to_len(dlc)), dlc);
}

/* Every length function against the ISO 11898-1 DLC table alone (dlc_table:
 * the 16 codes and their payload lengths), for every length 0..64 and far
 * beyond (the contract: 0xFF / invalid for anything over 64, never a length
 * cut to 8 bits): round = the smallest table length >= n, valid = n is a
 * table length, to_dlc = its code; co_frame_set pads exactly to the round. */
static void check_len_against_dlc_table(size_t n)
{
    unsigned want_round = 0xFF, want_dlc = 0xFF;
    int dlc;
    for (dlc = 15; dlc >= 0; dlc--) {
        if (dlc_table[dlc] >= n)
            want_round = dlc_table[dlc];
        if (dlc_table[dlc] == n)
            want_dlc = (unsigned)dlc;
    }
    if (co_fd_len_round(n) != want_round)
        fail_msg("co_fd_len_round(%zu) = %u, DLC table: %u", n, co_fd_len_round(n), want_round);
    if (co_fd_len_valid(n) != (want_dlc != 0xFF))
        fail_msg("co_fd_len_valid(%zu) = %d, DLC table: %d", n, (int)co_fd_len_valid(n),
                 (int)(want_dlc != 0xFF));
    if (co_fd_len_to_dlc(n) != want_dlc)
        fail_msg("co_fd_len_to_dlc(%zu) = %u, DLC table: %u", n, co_fd_len_to_dlc(n), want_dlc);
    if (n <= 64) {
        uint8_t d[64];
        co_frame_t f;
        size_t i;
        memset(d, 0x5A, sizeof d);
        memset(&f, 0xAA, sizeof f);
        assert_true(co_frame_set(&f, 0x123, CO_FRAME_FD, d, n));
        assert_int_equal(f.len, want_round);
        for (i = 0; i < f.len; i++)
            if (f.data[i] != (i < n ? 0x5A : 0))
                fail_msg("co_frame_set(%zu bytes): byte %zu is 0x%02X", n, i, f.data[i]);
        assert_true(co_frame_is_valid(&f));
    }
}

static void test_fd_len_functions_match_the_dlc_table(void **state)
{
    size_t n;
    (void)state;
    for (n = 0; n <= 1024; n++)
        check_len_against_dlc_table(n);
    for (n = 0; n <= 64; n++) {   /* lengths whose low 8 or 16 bits are a valid length */
        check_len_against_dlc_table(n + 256);
        check_len_against_dlc_table(n + 65536);
        check_len_against_dlc_table((size_t)-1 - n);
    }
}

/* ------------------------------------------------------------ validity */

static bool valid(uint32_t id, uint8_t flags, uint8_t len)
{
    co_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = id;
    f.flags = flags;
    f.len = len;
    return co_frame_is_valid(&f);
}

static void test_valid_11bit_id_limit(void **state)
{
    (void)state;
    assert_true(valid(0x000, 0, 0));
    assert_true(valid(0x7FF, 0, 8));
    assert_false(valid(0x800, 0, 8));
    assert_false(valid(0xFFFFFFFFu, 0, 8));
    assert_true(valid(0x7FF, CO_FRAME_FD, 8));
    assert_false(valid(0x800, CO_FRAME_FD, 8));
}

static void test_valid_29bit_id_limit(void **state)
{
    (void)state;
    assert_true(valid(0x00000000, CO_FRAME_EXT, 0));
    assert_true(valid(0x800, CO_FRAME_EXT, 8));
    assert_true(valid(0x1FFFFFFF, CO_FRAME_EXT, 8));
    assert_false(valid(0x20000000, CO_FRAME_EXT, 8));
    assert_false(valid(0x80000000u, CO_FRAME_EXT, 8));
    assert_true(valid(0x1FFFFFFF, CO_FRAME_EXT | CO_FRAME_FD, 64));
    assert_false(valid(0x20000000, CO_FRAME_EXT | CO_FRAME_FD, 64));
}

static void test_valid_classic_lengths_0_to_8_only(void **state)
{
    unsigned len;
    (void)state;
    for (len = 0; len <= 8; len++)
        assert_true(valid(0x123, 0, (uint8_t)len));
    for (len = 9; len <= 255; len++)
        assert_false(valid(0x123, 0, (uint8_t)len));
}

static void test_valid_fd_lengths_only_the_fd_steps(void **state)
{
    unsigned len;
    (void)state;
    for (len = 0; len <= 255; len++) {
        bool expected = len <= 64 && ref_round(len) == len;
        if (valid(0x123, CO_FRAME_FD, (uint8_t)len) != expected)
            fail_msg("FD frame of %u bytes: valid=%d, expected %d", len,
                     (int)!expected, (int)expected);
    }
}

static void test_valid_rtr_on_fd_is_invalid(void **state)
{
    (void)state;
    assert_true(valid(0x123, CO_FRAME_RTR, 0));
    assert_false(valid(0x123, CO_FRAME_FD | CO_FRAME_RTR, 0));
    assert_false(valid(0x123, CO_FRAME_FD | CO_FRAME_BRS | CO_FRAME_RTR, 8));
}

static void test_valid_brs_on_classic_is_invalid(void **state)
{
    (void)state;
    assert_false(valid(0x123, CO_FRAME_BRS, 8));
    assert_true(valid(0x123, CO_FRAME_FD | CO_FRAME_BRS, 8));
}

static void test_valid_esi_on_classic_is_invalid(void **state)
{
    (void)state;
    assert_false(valid(0x123, CO_FRAME_ESI, 8));
    assert_true(valid(0x123, CO_FRAME_FD | CO_FRAME_ESI, 8));
}

static void test_valid_fd_brs_esi_ext_together(void **state)
{
    (void)state;
    assert_true(valid(0x1ABCDEF, CO_FRAME_EXT | CO_FRAME_FD | CO_FRAME_BRS | CO_FRAME_ESI, 48));
}

/* ------------------------------------------------------------ co_frame_set */

static void test_set_classic_copies_without_rounding(void **state)
{
    co_frame_t f;
    const uint8_t d[5] = {1, 2, 3, 4, 5};
    (void)state;
    memset(&f, 0xAA, sizeof f);
    assert_true(co_frame_set(&f, 0x181, 0, d, sizeof d));
    assert_int_equal(f.id, 0x181);
    assert_int_equal(f.flags, 0);
    assert_int_equal(f.len, 5);
    assert_memory_equal(f.data, d, 5);
    assert_true(co_frame_is_valid(&f));
}

static void test_set_classic_more_than_8_bytes_refused(void **state)
{
    co_frame_t f;
    uint8_t d[9] = {0};
    (void)state;
    assert_false(co_frame_set(&f, 0x181, 0, d, 9));
}

static void test_set_fd_rounds_every_length_and_zero_pads(void **state)
{
    uint8_t d[64];
    size_t n, i;
    (void)state;
    for (i = 0; i < sizeof d; i++)
        d[i] = (uint8_t)(0x80 | i);
    for (n = 0; n <= 64; n++) {
        co_frame_t f;
        memset(&f, 0xAA, sizeof f);
        assert_true(co_frame_set(&f, 0x181, CO_FRAME_FD | CO_FRAME_BRS, d, n));
        assert_int_equal(f.id, 0x181);
        assert_int_equal(f.flags, CO_FRAME_FD | CO_FRAME_BRS);
        assert_int_equal(f.len, ref_round(n));
        if (n > 0)
            assert_memory_equal(f.data, d, n);
        for (i = n; i < f.len; i++)
            if (f.data[i] != 0)
                fail_msg("n=%u: padding byte %u is 0x%02X, expected 0", (unsigned)n,
                         (unsigned)i, f.data[i]);
        assert_true(co_frame_is_valid(&f));
    }
}

static void test_set_fd_more_than_64_bytes_refused(void **state)
{
    co_frame_t f;
    uint8_t d[65] = {0};
    (void)state;
    assert_false(co_frame_set(&f, 0x181, CO_FRAME_FD, d, 65));
}

static void test_set_extended_id_kept(void **state)
{
    co_frame_t f;
    const uint8_t d[2] = {0x12, 0x34};
    (void)state;
    assert_true(co_frame_set(&f, 0x1ABCDEF, CO_FRAME_EXT | CO_FRAME_FD, d, 2));
    assert_int_equal(f.id, 0x1ABCDEF);
    assert_int_equal(f.flags, CO_FRAME_EXT | CO_FRAME_FD);
    assert_int_equal(f.len, 2);
}

static void test_set_zero_length_with_null_data(void **state)
{
    co_frame_t f;
    (void)state;
    memset(&f, 0xAA, sizeof f);
    assert_true(co_frame_set(&f, 0x080, 0, NULL, 0));
    assert_int_equal(f.id, 0x080);
    assert_int_equal(f.len, 0);
    assert_int_equal(f.flags, 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_fd_len_round_every_n_0_to_65),
        cmocka_unit_test(test_fd_len_round_examples_from_spec),
        cmocka_unit_test(test_fd_len_round_too_long_gives_ff),
        cmocka_unit_test(test_fd_len_valid_exactly_the_sixteen_lengths),
        cmocka_unit_test(test_fd_dlc_to_len_table),
        cmocka_unit_test(test_fd_dlc_to_len_codes_above_15_give_ff),
        cmocka_unit_test(test_fd_len_to_dlc_table),
        cmocka_unit_test(test_fd_len_to_dlc_invalid_lengths_give_ff),
        cmocka_unit_test(test_fd_dlc_len_round_trip),
        cmocka_unit_test(test_fd_len_functions_match_the_dlc_table),
        cmocka_unit_test(test_valid_11bit_id_limit),
        cmocka_unit_test(test_valid_29bit_id_limit),
        cmocka_unit_test(test_valid_classic_lengths_0_to_8_only),
        cmocka_unit_test(test_valid_fd_lengths_only_the_fd_steps),
        cmocka_unit_test(test_valid_rtr_on_fd_is_invalid),
        cmocka_unit_test(test_valid_brs_on_classic_is_invalid),
        cmocka_unit_test(test_valid_esi_on_classic_is_invalid),
        cmocka_unit_test(test_valid_fd_brs_esi_ext_together),
        cmocka_unit_test(test_set_classic_copies_without_rounding),
        cmocka_unit_test(test_set_classic_more_than_8_bytes_refused),
        cmocka_unit_test(test_set_fd_rounds_every_length_and_zero_pads),
        cmocka_unit_test(test_set_fd_more_than_64_bytes_refused),
        cmocka_unit_test(test_set_extended_id_kept),
        cmocka_unit_test(test_set_zero_length_with_null_data),
    };
    return cmocka_run_group_tests_name("frame", tests, NULL, NULL);
}
