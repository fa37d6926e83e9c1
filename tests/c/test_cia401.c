/* co_cia401: digital input polarity, filter and interrupt masks, digital
 * output polarity, filter mask and error mode, analogue input limits and
 * deltas, analogue output error mode. */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include "canopenfd/co_cia401.h"

static co_cia401_din_t din_all_changes(void)
{
    co_cia401_din_t din = {0};
    din.interrupt_enable = true;
    din.any_change = 0xFF;
    return din;
}

static void test_din_polarity_inverts_the_stored_value(void **state)
{
    co_cia401_din_t din = din_all_changes();
    (void)state;
    din.polarity = 0x0F;
    assert_true(co_cia401_din_update(&din, 0x00));
    assert_int_equal(din.value, 0x0F);
    assert_false(co_cia401_din_update(&din, 0x00));    /* nothing changed */
    assert_true(co_cia401_din_update(&din, 0x81));
    assert_int_equal(din.value, 0x8E);
}

static void test_din_any_change_mask_selects_the_bits(void **state)
{
    co_cia401_din_t din = din_all_changes();
    (void)state;
    din.any_change = 0x02;
    assert_false(co_cia401_din_update(&din, 0x01));    /* bit 0 not in the mask */
    assert_int_equal(din.value, 0x01);                 /* but still stored */
    assert_true(co_cia401_din_update(&din, 0x03));
    assert_true(co_cia401_din_update(&din, 0x01));     /* bit 1 falls: any change */
}

static void test_din_rising_and_falling_edges(void **state)
{
    co_cia401_din_t din = din_all_changes();
    (void)state;
    din.any_change = 0;
    din.rising = 0x01;
    din.falling = 0x80;
    assert_true(co_cia401_din_update(&din, 0x01));     /* bit 0 rises */
    assert_false(co_cia401_din_update(&din, 0x00));    /* bit 0 falls: not selected */
    assert_false(co_cia401_din_update(&din, 0x80));    /* bit 7 rises: not selected */
    assert_true(co_cia401_din_update(&din, 0x00));     /* bit 7 falls */
}

static void test_din_global_enable_off_stores_without_trigger(void **state)
{
    co_cia401_din_t din = din_all_changes();
    (void)state;
    din.interrupt_enable = false;
    assert_false(co_cia401_din_update(&din, 0xFF));
    assert_int_equal(din.value, 0xFF);
}

static void test_din_filter_needs_two_equal_samples(void **state)
{
    co_cia401_din_t din = din_all_changes();
    (void)state;
    din.filter = 0x01;
    assert_true(co_cia401_din_update(&din, 0x03));     /* bit 1 at once, bit 0 waits */
    assert_int_equal(din.value, 0x02);
    assert_false(co_cia401_din_update(&din, 0x02));    /* bit 0 glitch gone: stays 0 */
    assert_int_equal(din.value, 0x02);
    assert_false(co_cia401_din_update(&din, 0x03));    /* first sample of the new level */
    assert_int_equal(din.value, 0x02);
    assert_true(co_cia401_din_update(&din, 0x03));     /* second equal sample */
    assert_int_equal(din.value, 0x03);
}

static void test_din_null_is_refused(void **state)
{
    (void)state;
    assert_false(co_cia401_din_update(NULL, 0xFF));
}

static void test_dout_polarity_and_filter_mask(void **state)
{
    co_cia401_dout_t dout = {0};
    (void)state;
    dout.polarity = 0x01;
    dout.filter_mask = 0xFF;
    assert_int_equal(co_cia401_dout_write(&dout, 0x00), 0x01);
    assert_int_equal(co_cia401_dout_write(&dout, 0x81), 0x80);
    dout.filter_mask = 0x0F;                            /* upper bits stay */
    assert_int_equal(co_cia401_dout_write(&dout, 0x0E), 0x8F);
    assert_int_equal(dout.physical, 0x8F);
}

static void test_dout_fault_takes_error_values_of_selected_bits(void **state)
{
    co_cia401_dout_t dout = {0};
    (void)state;
    dout.filter_mask = 0xFF;
    dout.polarity = 0xFF;
    dout.error_mode = 0x0F;
    dout.error_value = 0x05;
    assert_int_equal(co_cia401_dout_write(&dout, 0x00), 0xFF);
    /* low nibble to the error value (no polarity), high nibble kept */
    assert_int_equal(co_cia401_dout_fault(&dout), 0xF5);
    assert_int_equal(co_cia401_dout_write(NULL, 1), 0);
    assert_int_equal(co_cia401_dout_fault(NULL), 0);
}

static co_cia401_ain_t ain_with(uint8_t trigger)
{
    co_cia401_ain_t ain = {0};
    ain.trigger = trigger;
    ain.interrupt_enable = true;
    ain.upper_limit = 1000;
    ain.lower_limit = -1000;
    ain.delta = 100;
    ain.negative_delta = 50;
    ain.positive_delta = 200;
    co_cia401_ain_reset(&ain, 0);
    return ain;
}

static void test_ain_upper_limit_fires_when_reached(void **state)
{
    co_cia401_ain_t ain = ain_with(CO_CIA401_AI_UPPER);
    (void)state;
    assert_false(co_cia401_ain_update(&ain, 999));
    assert_true(co_cia401_ain_update(&ain, 1000));     /* equal counts as reached */
    assert_false(co_cia401_ain_update(&ain, 1500));    /* still above: no repeat */
    assert_false(co_cia401_ain_update(&ain, 10));
    assert_true(co_cia401_ain_update(&ain, 2000));
    assert_int_equal(ain.value, 2000);
}

static void test_ain_lower_limit_fires_below(void **state)
{
    co_cia401_ain_t ain = ain_with(CO_CIA401_AI_LOWER);
    (void)state;
    assert_false(co_cia401_ain_update(&ain, -1000));   /* equal is not below */
    assert_true(co_cia401_ain_update(&ain, -1001));
    assert_false(co_cia401_ain_update(&ain, -3000));
}

static void test_ain_delta_from_the_last_trigger(void **state)
{
    co_cia401_ain_t ain = ain_with(CO_CIA401_AI_DELTA);
    (void)state;
    assert_false(co_cia401_ain_update(&ain, 60));
    assert_false(co_cia401_ain_update(&ain, 100));     /* 100 is not more than 100 */
    assert_true(co_cia401_ain_update(&ain, 101));      /* reference now 101 */
    assert_false(co_cia401_ain_update(&ain, 150));
    assert_true(co_cia401_ain_update(&ain, 0));        /* -101 from 101 */
}

static void test_ain_negative_and_positive_delta(void **state)
{
    co_cia401_ain_t ain = ain_with(CO_CIA401_AI_NEGATIVE_DELTA);
    (void)state;
    assert_false(co_cia401_ain_update(&ain, 500));     /* rising: not selected */
    assert_true(co_cia401_ain_update(&ain, -51));
    ain = ain_with(CO_CIA401_AI_POSITIVE_DELTA);
    assert_false(co_cia401_ain_update(&ain, -500));
    assert_false(co_cia401_ain_update(&ain, -300));    /* +200 from 0? no: -300 */
    assert_true(co_cia401_ain_update(&ain, 201));
}

static void test_ain_global_enable_off_and_extremes(void **state)
{
    co_cia401_ain_t ain = ain_with(0x1F);
    (void)state;
    ain.interrupt_enable = false;
    assert_false(co_cia401_ain_update(&ain, 5000));
    assert_int_equal(ain.value, 5000);
    assert_int_equal(ain.reference, 0);                 /* nothing sent: reference kept */
    ain.interrupt_enable = true;
    co_cia401_ain_reset(&ain, INT32_MIN);
    assert_true(co_cia401_ain_update(&ain, INT32_MAX)); /* no overflow in the step */
    assert_false(co_cia401_ain_update(NULL, 1));
    co_cia401_ain_reset(NULL, 1);
}

static void test_aout_write_and_fault(void **state)
{
    co_cia401_aout_t aout = {0};
    (void)state;
    assert_int_equal(co_cia401_aout_write(&aout, -1234), -1234);
    assert_int_equal(co_cia401_aout_fault(&aout), -1234);   /* error mode off */
    aout.error_mode = true;
    aout.error_value = 77;
    assert_int_equal(co_cia401_aout_fault(&aout), 77);
    aout.error_value = 100000;
    assert_int_equal(co_cia401_aout_fault(&aout), INT16_MAX);
    aout.error_value = -100000;
    assert_int_equal(co_cia401_aout_fault(&aout), INT16_MIN);
    assert_int_equal(co_cia401_aout_write(NULL, 5), 0);
    assert_int_equal(co_cia401_aout_fault(NULL), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_din_polarity_inverts_the_stored_value),
        cmocka_unit_test(test_din_any_change_mask_selects_the_bits),
        cmocka_unit_test(test_din_rising_and_falling_edges),
        cmocka_unit_test(test_din_global_enable_off_stores_without_trigger),
        cmocka_unit_test(test_din_filter_needs_two_equal_samples),
        cmocka_unit_test(test_din_null_is_refused),
        cmocka_unit_test(test_dout_polarity_and_filter_mask),
        cmocka_unit_test(test_dout_fault_takes_error_values_of_selected_bits),
        cmocka_unit_test(test_ain_upper_limit_fires_when_reached),
        cmocka_unit_test(test_ain_lower_limit_fires_below),
        cmocka_unit_test(test_ain_delta_from_the_last_trigger),
        cmocka_unit_test(test_ain_negative_and_positive_delta),
        cmocka_unit_test(test_ain_global_enable_off_and_extremes),
        cmocka_unit_test(test_aout_write_and_fault),
    };
    return cmocka_run_group_tests_name("cia401", tests, NULL, NULL);
}
