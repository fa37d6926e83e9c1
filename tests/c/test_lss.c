/* LSS (CiA 305) wire format and slave: the exact bytes of every answer, the
 * state transitions, node-id handling, indications, malformed frames. */
#include "test_util.h"

#include "canopenfd/co_lss.h"

static const co_lss_address_t ADDRESS = {{0x00000123u, 0x45670001u, 0x00020003u, 0xCAFE0042u}};

typedef struct fixture {
    tu_line_t l;
    co_lss_slave_t slave;
    co_lss_slave_indications_t ind;
    /* what the indications saw / answer */
    bool accept_bit_timing;
    uint8_t bit_selector, bit_index;
    int bit_checks;
    int activations;
    uint16_t delay;
    int stores;
    uint8_t stored_id;
    uint8_t store_answer;
    int resets;
    uint8_t reset_id;
    int state_changes;
    co_lss_state_t last_state;
    uint64_t now;
} fixture_t;

static bool check_bit_timing(co_lss_slave_t *s, uint8_t sel, uint8_t idx, void *user)
{
    (void)s;
    fixture_t *f = user;
    f->bit_checks++;
    f->bit_selector = sel;
    f->bit_index = idx;
    return f->accept_bit_timing;
}

static void activate_bit_timing(co_lss_slave_t *s, uint16_t delay, void *user)
{
    (void)s;
    fixture_t *f = user;
    f->activations++;
    f->delay = delay;
}

static uint8_t store(co_lss_slave_t *s, uint8_t node_id, void *user)
{
    (void)s;
    fixture_t *f = user;
    f->stores++;
    f->stored_id = node_id;
    return f->store_answer;
}

static void reset_communication(co_lss_slave_t *s, uint8_t node_id, void *user)
{
    fixture_t *f = user;
    f->resets++;
    f->reset_id = node_id;
    assert_int_equal(co_lss_slave_reset_communication(s), node_id);
}

static void state_changed(co_lss_slave_t *s, co_lss_state_t state, void *user)
{
    (void)s;
    fixture_t *f = user;
    f->state_changes++;
    f->last_state = state;
}

static fixture_t *make(co_mode_t mode, uint8_t node_id, bool with_ind)
{
    fixture_t *f = test_calloc(1, sizeof *f);
    tu_line_init(&f->l, mode, mode == CO_MODE_FD);
    f->ind = (co_lss_slave_indications_t){check_bit_timing, activate_bit_timing, store,
                                          state_changed, reset_communication};
    assert_true(co_lss_slave_init(&f->slave, &f->l.line, &ADDRESS, node_id,
                                  with_ind ? &f->ind : NULL, f));
    return f;
}

static int setup(void **state)
{
    *state = make(CO_MODE_CLASSIC, 0x20, true);
    return 0;
}

static int teardown(void **state)
{
    fixture_t *f = *state;
    co_lss_slave_deinit(&f->slave);
    test_free(f);
    return 0;
}

/* Feed one request (any length, flags) and process. */
static void feed_raw(fixture_t *f, uint8_t flags, const uint8_t *data, uint8_t len)
{
    co_frame_t fr = tu_frame(CO_LSS_ID_MASTER, flags, data, len);
    assert_true(co_line_receive(&f->l.line, &fr));
    f->now += 1000;
    (void)co_line_process(&f->l.line, f->now);
}

static void feed(fixture_t *f, uint8_t b0, uint8_t b1, uint8_t b2, uint8_t b3, uint8_t b4,
                 uint8_t b5, uint8_t b6, uint8_t b7)
{
    const uint8_t d[8] = {b0, b1, b2, b3, b4, b5, b6, b7};
    feed_raw(f, 0, d, 8);
}

static void feed_value(fixture_t *f, uint8_t cs, uint32_t v)
{
    feed(f, cs, (uint8_t)v, (uint8_t)(v >> 8), (uint8_t)(v >> 16), (uint8_t)(v >> 24), 0, 0, 0);
}

static uint32_t sent_count(fixture_t *f) { return co_line_tx_count(&f->l.line); }

/* The oldest sent frame must be exactly these 8 bytes on 0x7E4. */
static void expect_answer(fixture_t *f, uint8_t flags, const uint8_t expected[8])
{
    co_frame_t out;
    assert_true(co_line_tx_pop(&f->l.line, &out));
    tu_assert_frame(&out, CO_LSS_ID_SLAVE, flags, expected, 8);
}

static void expect_bytes(fixture_t *f, uint8_t b0, uint8_t b1, uint8_t b2)
{
    const uint8_t d[8] = {b0, b1, b2, 0, 0, 0, 0, 0};
    expect_answer(f, 0, d);
}

static void expect_silence(fixture_t *f) { assert_int_equal(sent_count(f), 0); }

static void to_configuration(fixture_t *f)
{
    feed(f, 0x04, 0x01, 0, 0, 0, 0, 0, 0);
    assert_int_equal(co_lss_slave_state(&f->slave), CO_LSS_STATE_CONFIGURATION);
}

/* ------------------------------------------------------------------ codec */

static void test_codec(void **state)
{
    (void)state;
    uint8_t d[8];
    co_lss_msg_t m;
    co_lss_encode_fastscan(d, 0x11223344u, 31, 2, 3);
    const uint8_t fs[8] = {0x51, 0x44, 0x33, 0x22, 0x11, 31, 2, 3};
    assert_memory_equal(d, fs, 8);
    assert_int_equal(co_lss_decode_request(d, 8, &m), CO_LSS_DECODE_OK);
    assert_int_equal(m.cs, 0x51);
    assert_int_equal(m.value, 0x11223344u);
    assert_int_equal(m.bit_checked, 31);
    assert_int_equal(m.sub, 2);
    assert_int_equal(m.next, 3);
    co_lss_encode_delay(d, 0xABCD);
    const uint8_t act[8] = {0x15, 0xCD, 0xAB, 0, 0, 0, 0, 0};
    assert_memory_equal(d, act, 8);
    assert_int_equal(co_lss_decode_request(d, 8, &m), CO_LSS_DECODE_OK);
    assert_int_equal(m.delay_ms, 0xABCD);
    co_lss_encode_value(d, 0x5D, 0xCAFE0042u);
    const uint8_t inq[8] = {0x5D, 0x42, 0x00, 0xFE, 0xCA, 0, 0, 0};
    assert_memory_equal(d, inq, 8);
    assert_int_equal(co_lss_decode_answer(d, 8, &m), CO_LSS_DECODE_OK);
    assert_int_equal(m.value, 0xCAFE0042u);

    /* Direction matters: 0x44 is only an answer, 0x51 only a request. */
    co_lss_encode_bytes(d, 0x44, 0, 0);
    assert_int_equal(co_lss_decode_request(d, 8, &m), CO_LSS_DECODE_UNKNOWN_CS);
    assert_int_equal(co_lss_decode_answer(d, 8, &m), CO_LSS_DECODE_OK);
    co_lss_encode_bytes(d, 0x51, 0, 0);
    assert_int_equal(co_lss_decode_answer(d, 8, &m), CO_LSS_DECODE_UNKNOWN_CS);
    /* Every request CS of the table is known; neighbours are not. */
    const uint8_t known[] = {0x04, 0x11, 0x13, 0x15, 0x17, 0x40, 0x41, 0x42, 0x43, 0x46,
                             0x47, 0x48, 0x49, 0x4A, 0x4B, 0x4C, 0x51, 0x5A, 0x5B, 0x5C,
                             0x5D, 0x5E};
    int known_count = 0;
    for (unsigned cs = 0; cs < 256; cs++) {
        co_lss_encode_bytes(d, (uint8_t)cs, 0, 0);
        if (co_lss_decode_request(d, 8, &m) == CO_LSS_DECODE_OK) {
            known_count++;
            assert_non_null(memchr(known, (int)cs, sizeof known));
        }
    }
    assert_int_equal(known_count, (int)sizeof known);

    /* Wrong lengths: the decoder reads nothing (exact-size heap buffers,
     * so the sanitizer build catches any read past the end). */
    for (size_t len = 0; len < 8; len++) {
        uint8_t *p = test_malloc(len ? len : 1);
        memset(p, 0x5A, len ? len : 1);
        assert_int_equal(co_lss_decode_request(p, len, &m), CO_LSS_DECODE_BAD_LENGTH);
        assert_int_equal(co_lss_decode_answer(p, len, &m), CO_LSS_DECODE_BAD_LENGTH);
        test_free(p);
    }
    uint8_t big[12] = {0x04};
    assert_int_equal(co_lss_decode_request(big, 12, &m), CO_LSS_DECODE_BAD_LENGTH);
    assert_true(co_lss_node_id_valid(1));
    assert_true(co_lss_node_id_valid(127));
    assert_true(co_lss_node_id_valid(255));
    assert_false(co_lss_node_id_valid(0));
    assert_false(co_lss_node_id_valid(128));
    assert_false(co_lss_node_id_valid(254));
}

/* ------------------------------------------------------------- slave states */

static void test_switch_global(void **state)
{
    fixture_t *f = *state;
    assert_int_equal(co_lss_slave_state(&f->slave), CO_LSS_STATE_WAITING);
    to_configuration(f);
    assert_int_equal(f->state_changes, 1);
    assert_int_equal(f->last_state, CO_LSS_STATE_CONFIGURATION);
    expect_silence(f);                     /* switch state global has no answer */
    feed(f, 0x04, 0x01, 0, 0, 0, 0, 0, 0);   /* again: no second indication */
    assert_int_equal(f->state_changes, 1);
    feed(f, 0x04, 0x02, 0, 0, 0, 0, 0, 0);   /* no such state */
    assert_int_equal(co_lss_slave_stats(&f->slave)->bad_argument, 1);
    assert_int_equal(co_lss_slave_state(&f->slave), CO_LSS_STATE_CONFIGURATION);
    feed(f, 0x04, 0x00, 0, 0, 0, 0, 0, 0);
    assert_int_equal(co_lss_slave_state(&f->slave), CO_LSS_STATE_WAITING);
    assert_int_equal(f->state_changes, 2);
    assert_int_equal(f->last_state, CO_LSS_STATE_WAITING);
    /* A configured node switched back: no reset communication. */
    assert_int_equal(f->resets, 0);
    expect_silence(f);
}

static void test_switch_selective(void **state)
{
    fixture_t *f = *state;
    /* The right four frames in order: selected, answer 0x44. */
    feed_value(f, 0x40, ADDRESS.part[0]);
    feed_value(f, 0x41, ADDRESS.part[1]);
    feed_value(f, 0x42, ADDRESS.part[2]);
    expect_silence(f);
    feed_value(f, 0x43, ADDRESS.part[3]);
    expect_bytes(f, 0x44, 0, 0);
    assert_int_equal(co_lss_slave_state(&f->slave), CO_LSS_STATE_CONFIGURATION);
    feed(f, 0x04, 0x00, 0, 0, 0, 0, 0, 0);

    /* One part wrong: nothing. */
    feed_value(f, 0x40, ADDRESS.part[0]);
    feed_value(f, 0x41, ADDRESS.part[1] ^ 1u);
    feed_value(f, 0x42, ADDRESS.part[2]);
    feed_value(f, 0x43, ADDRESS.part[3]);
    expect_silence(f);
    /* Out of order (serial first, vendor skipped): nothing. */
    feed_value(f, 0x41, ADDRESS.part[1]);
    feed_value(f, 0x42, ADDRESS.part[2]);
    feed_value(f, 0x43, ADDRESS.part[3]);
    expect_silence(f);
    feed_value(f, 0x43, ADDRESS.part[3]);
    feed_value(f, 0x40, ADDRESS.part[0]);
    feed_value(f, 0x41, ADDRESS.part[1]);
    feed_value(f, 0x42, ADDRESS.part[2]);
    expect_silence(f);
    assert_int_equal(co_lss_slave_state(&f->slave), CO_LSS_STATE_WAITING);
    /* A restarted sequence after a broken one works. */
    feed_value(f, 0x40, ADDRESS.part[0]);
    feed_value(f, 0x41, ADDRESS.part[1]);
    feed_value(f, 0x42, ADDRESS.part[2]);
    feed_value(f, 0x43, ADDRESS.part[3]);
    expect_bytes(f, 0x44, 0, 0);
    /* In configuration, selective frames are not served (counted). */
    uint32_t before = co_lss_slave_stats(&f->slave)->not_in_state;
    feed_value(f, 0x40, ADDRESS.part[0]);
    assert_int_equal(co_lss_slave_stats(&f->slave)->not_in_state, before + 1);
}

/* ---------------------------------------------------------- configuration */

static void test_configure_node_id(void **state)
{
    fixture_t *f = *state;
    /* Waiting: not served, no answer. */
    feed(f, 0x11, 5, 0, 0, 0, 0, 0, 0);
    expect_silence(f);
    assert_int_equal(co_lss_slave_stats(&f->slave)->not_in_state, 1);
    assert_int_equal(co_lss_slave_pending_node_id(&f->slave), 0x20);

    to_configuration(f);
    feed(f, 0x11, 5, 0, 0, 0, 0, 0, 0);
    expect_bytes(f, 0x11, 0, 0);
    assert_int_equal(co_lss_slave_pending_node_id(&f->slave), 5);
    assert_int_equal(co_lss_slave_active_node_id(&f->slave), 0x20);   /* until reset comm */
    const uint8_t bad[] = {0, 128, 200, 254};
    for (size_t i = 0; i < sizeof bad; i++) {
        feed(f, 0x11, bad[i], 0, 0, 0, 0, 0, 0);
        expect_bytes(f, 0x11, 1, 0);
        assert_int_equal(co_lss_slave_pending_node_id(&f->slave), 5);
    }
    feed(f, 0x11, 127, 0, 0, 0, 0, 0, 0);
    expect_bytes(f, 0x11, 0, 0);
    feed(f, 0x11, 255, 0, 0, 0, 0, 0, 0);
    expect_bytes(f, 0x11, 0, 0);
    assert_int_equal(co_lss_slave_pending_node_id(&f->slave), 255);
    /* Inquire node-id gives the active one. */
    feed(f, 0x5E, 0, 0, 0, 0, 0, 0, 0);
    expect_bytes(f, 0x5E, 0x20, 0);
    assert_int_equal(co_lss_slave_reset_communication(&f->slave), 255);
    feed(f, 0x5E, 0, 0, 0, 0, 0, 0, 0);
    expect_bytes(f, 0x5E, 0xFF, 0);
}

static void test_inquire(void **state)
{
    fixture_t *f = *state;
    feed(f, 0x5A, 0, 0, 0, 0, 0, 0, 0);   /* waiting: not served */
    expect_silence(f);
    to_configuration(f);
    for (uint8_t i = 0; i < 4; i++) {
        feed(f, (uint8_t)(0x5A + i), 0, 0, 0, 0, 0, 0, 0);
        uint32_t v = ADDRESS.part[i];
        const uint8_t d[8] = {(uint8_t)(0x5A + i), (uint8_t)v, (uint8_t)(v >> 8),
                              (uint8_t)(v >> 16), (uint8_t)(v >> 24), 0, 0, 0};
        expect_answer(f, 0, d);
    }
    feed(f, 0x5E, 0, 0, 0, 0, 0, 0, 0);
    expect_bytes(f, 0x5E, 0x20, 0);
}

static void test_bit_timing(void **state)
{
    fixture_t *f = *state;
    to_configuration(f);
    f->accept_bit_timing = false;
    feed(f, 0x13, 0, 2, 0, 0, 0, 0, 0);
    expect_bytes(f, 0x13, 1, 0);
    assert_int_equal(f->bit_checks, 1);
    assert_false(f->slave.bit_timing_pending);
    f->accept_bit_timing = true;
    feed(f, 0x13, 0, 3, 0, 0, 0, 0, 0);
    expect_bytes(f, 0x13, 0, 0);
    assert_int_equal(f->bit_selector, 0);
    assert_int_equal(f->bit_index, 3);
    assert_true(f->slave.bit_timing_pending);
    /* Activate: no answer, the indication gets the delay. */
    feed(f, 0x15, 0x34, 0x12, 0, 0, 0, 0, 0);
    expect_silence(f);
    assert_int_equal(f->activations, 1);
    assert_int_equal(f->delay, 0x1234);
}

static void test_without_indications(void **state)
{
    (void)state;
    fixture_t *f = make(CO_MODE_CLASSIC, 0x20, false);
    to_configuration(f);
    feed(f, 0x13, 0, 2, 0, 0, 0, 0, 0);
    expect_bytes(f, 0x13, 1, 0);          /* bit timing not supported */
    feed(f, 0x17, 0, 0, 0, 0, 0, 0, 0);
    expect_bytes(f, 0x17, 1, 0);          /* store not supported */
    feed(f, 0x15, 1, 0, 0, 0, 0, 0, 0);
    expect_silence(f);
    co_lss_slave_deinit(&f->slave);
    test_free(f);
}

static void test_store(void **state)
{
    fixture_t *f = *state;
    to_configuration(f);
    feed(f, 0x11, 9, 0, 0, 0, 0, 0, 0);
    expect_bytes(f, 0x11, 0, 0);
    f->store_answer = CO_LSS_ERR_STORE_MEDIA;
    feed(f, 0x17, 0, 0, 0, 0, 0, 0, 0);
    expect_bytes(f, 0x17, 2, 0);
    assert_int_equal(f->stored_id, 9);
    assert_int_equal(co_lss_slave_persistent_node_id(&f->slave), 0x20);
    f->store_answer = CO_LSS_ERR_STORE_NOT_SUPPORTED;
    feed(f, 0x17, 0, 0, 0, 0, 0, 0, 0);
    expect_bytes(f, 0x17, 1, 0);
    f->store_answer = 77;                 /* an undefined answer is "not supported" */
    feed(f, 0x17, 0, 0, 0, 0, 0, 0, 0);
    expect_bytes(f, 0x17, 1, 0);
    f->store_answer = CO_LSS_ERR_OK;
    feed(f, 0x17, 0, 0, 0, 0, 0, 0, 0);
    expect_bytes(f, 0x17, 0, 0);
    assert_int_equal(f->stores, 4);
    assert_int_equal(co_lss_slave_persistent_node_id(&f->slave), 9);
    assert_int_equal(co_lss_slave_active_node_id(&f->slave), 0x20);
    /* The application answers later (it writes its medium first). */
    feed(f, 0x11, 10, 0, 0, 0, 0, 0, 0);
    expect_bytes(f, 0x11, 0, 0);
    f->store_answer = CO_LSS_ERR_LATER;
    feed(f, 0x17, 0, 0, 0, 0, 0, 0, 0);
    expect_silence(f);
    feed(f, 0x17, 0, 0, 0, 0, 0, 0, 0);         /* a second one while waiting */
    expect_silence(f);
    assert_int_equal(co_lss_slave_stats(&f->slave)->store_busy, 1);
    assert_int_equal(f->stores, 5);
    feed(f, 0x11, 11, 0, 0, 0, 0, 0, 0);         /* pending changes meanwhile */
    expect_bytes(f, 0x11, 0, 0);
    assert_true(co_lss_slave_store_answer(&f->slave, CO_LSS_ERR_OK));
    expect_bytes(f, 0x17, 0, 0);
    assert_int_equal(co_lss_slave_persistent_node_id(&f->slave), 10);   /* what was asked */
    assert_false(co_lss_slave_store_answer(&f->slave, CO_LSS_ERR_OK));
    expect_silence(f);
    feed(f, 0x17, 0, 0, 0, 0, 0, 0, 0);
    assert_true(co_lss_slave_store_answer(&f->slave, CO_LSS_ERR_STORE_MEDIA));
    expect_bytes(f, 0x17, 2, 0);
    assert_int_equal(co_lss_slave_persistent_node_id(&f->slave), 10);
}

/* An unconfigured node (255) that gets a node-id: switched back to
 * waiting, it resets communication and uses the new one. */
static void test_unconfigured_gets_node_id(void **state)
{
    (void)state;
    fixture_t *f = make(CO_MODE_CLASSIC, 255, true);
    to_configuration(f);
    feed(f, 0x04, 0x00, 0, 0, 0, 0, 0, 0);   /* nothing pending: no reset */
    assert_int_equal(f->resets, 0);
    to_configuration(f);
    feed(f, 0x11, 42, 0, 0, 0, 0, 0, 0);
    expect_bytes(f, 0x11, 0, 0);
    assert_int_equal(co_lss_slave_active_node_id(&f->slave), 255);
    feed(f, 0x04, 0x00, 0, 0, 0, 0, 0, 0);
    assert_int_equal(f->resets, 1);
    assert_int_equal(f->reset_id, 42);
    assert_int_equal(co_lss_slave_active_node_id(&f->slave), 42);
    /* Configured now: a second round changes pending only. */
    to_configuration(f);
    feed(f, 0x11, 43, 0, 0, 0, 0, 0, 0);
    expect_bytes(f, 0x11, 0, 0);
    feed(f, 0x04, 0x00, 0, 0, 0, 0, 0, 0);
    assert_int_equal(f->resets, 1);
    assert_int_equal(co_lss_slave_active_node_id(&f->slave), 42);
    co_lss_slave_deinit(&f->slave);
    test_free(f);
}

/* --------------------------------------------------------- identification */

static void identify(fixture_t *f, uint32_t v, uint32_t p, uint32_t rl, uint32_t rh, uint32_t sl,
                     uint32_t sh)
{
    feed_value(f, 0x46, v);
    feed_value(f, 0x47, p);
    feed_value(f, 0x48, rl);
    feed_value(f, 0x49, rh);
    feed_value(f, 0x4A, sl);
    feed_value(f, 0x4B, sh);
}

static void test_identify_remote(void **state)
{
    fixture_t *f = *state;
    const uint32_t *a = ADDRESS.part;
    identify(f, a[0], a[1], a[2], a[2], a[3], a[3]);   /* exact */
    expect_bytes(f, 0x4F, 0, 0);
    identify(f, a[0], a[1], 0, UINT32_MAX, 0, UINT32_MAX);   /* everything */
    expect_bytes(f, 0x4F, 0, 0);
    identify(f, a[0], a[1], a[2] + 1, UINT32_MAX, 0, UINT32_MAX);   /* revision above */
    identify(f, a[0], a[1], 0, a[2] - 1, 0, UINT32_MAX);            /* revision below */
    identify(f, a[0], a[1], 0, UINT32_MAX, a[3] + 1, UINT32_MAX);   /* serial above */
    identify(f, a[0], a[1], 0, UINT32_MAX, 0, a[3] - 1);            /* serial below */
    identify(f, a[0] + 1, a[1], 0, UINT32_MAX, 0, UINT32_MAX);      /* other vendor */
    identify(f, a[0], a[1] + 1, 0, UINT32_MAX, 0, UINT32_MAX);      /* other product */
    expect_silence(f);
    /* Only the serial-high frame: the other five are missing. */
    feed_value(f, 0x4B, UINT32_MAX);
    expect_silence(f);
    /* Served in configuration too. */
    to_configuration(f);
    identify(f, a[0], a[1], a[2], a[2], a[3], a[3]);
    expect_bytes(f, 0x4F, 0, 0);
}

static void test_identify_non_configured(void **state)
{
    fixture_t *f = *state;
    feed(f, 0x4C, 0, 0, 0, 0, 0, 0, 0);   /* configured: silent */
    expect_silence(f);
    fixture_t *u = make(CO_MODE_CLASSIC, 255, true);
    feed(u, 0x4C, 0, 0, 0, 0, 0, 0, 0);
    expect_bytes(u, 0x50, 0, 0);
    /* A pending node-id counts as configured. */
    to_configuration(u);
    feed(u, 0x11, 3, 0, 0, 0, 0, 0, 0);
    expect_bytes(u, 0x11, 0, 0);
    feed(u, 0x4C, 0, 0, 0, 0, 0, 0, 0);
    expect_silence(u);
    co_lss_slave_deinit(&u->slave);
    test_free(u);
}

/* ---------------------------------------------------------------- fast scan */

static void fastscan(fixture_t *f, uint32_t id, uint8_t bit, uint8_t sub, uint8_t next)
{
    uint8_t d[8];
    co_lss_encode_fastscan(d, id, bit, sub, next);
    feed_raw(f, 0, d, 8);
}

static void test_fastscan_slave(void **state)
{
    fixture_t *f = *state;
    /* A configured slave takes no part. */
    fastscan(f, 0, 0x80, 0, 0);
    expect_silence(f);
    fixture_t *u = make(CO_MODE_CLASSIC, 255, true);
    fastscan(u, 0, 0x80, 0, 0);
    expect_bytes(u, 0x4F, 0, 0);
    const uint32_t *a = ADDRESS.part;
    /* Bit 31 of the vendor-ID: 0 matches (0x123). */
    fastscan(u, 0, 31, 0, 0);
    expect_bytes(u, 0x4F, 0, 0);
    /* Bits 8..31 as 0x000000xx: 0x123 has bit 8 set: no match. */
    fastscan(u, 0, 8, 0, 0);
    expect_silence(u);
    fastscan(u, 0x100, 8, 0, 0);
    expect_bytes(u, 0x4F, 0, 0);
    /* Another part than the slave's position: no answer. */
    fastscan(u, a[1], 0, 1, 2);
    expect_silence(u);
    /* The whole vendor-ID: the slave moves to the product code. */
    fastscan(u, a[0], 0, 0, 1);
    expect_bytes(u, 0x4F, 0, 0);
    fastscan(u, a[0], 0, 0, 1);             /* position is 1 now */
    expect_silence(u);
    fastscan(u, a[1], 0, 1, 2);
    expect_bytes(u, 0x4F, 0, 0);
    fastscan(u, a[2], 0, 2, 3);
    expect_bytes(u, 0x4F, 0, 0);
    assert_int_equal(co_lss_slave_state(&u->slave), CO_LSS_STATE_WAITING);
    fastscan(u, a[3] ^ 1u, 0, 3, 0);         /* last bit wrong */
    expect_silence(u);
    fastscan(u, a[3], 0, 3, 0);              /* whole serial, next < sub: selected */
    expect_bytes(u, 0x4F, 0, 0);
    assert_int_equal(co_lss_slave_state(&u->slave), CO_LSS_STATE_CONFIGURATION);
    /* Selected: fast scan is a waiting-state service. */
    fastscan(u, 0, 0x80, 0, 0);
    expect_silence(u);
    assert_int_equal(co_lss_slave_stats(&u->slave)->not_in_state, 1);
    feed(u, 0x04, 0x00, 0, 0, 0, 0, 0, 0);
    /* Reset puts the position back to the vendor-ID. */
    fastscan(u, a[0], 0, 0, 1);
    expect_bytes(u, 0x4F, 0, 0);
    fastscan(u, 0, 0x80, 0, 0);
    expect_bytes(u, 0x4F, 0, 0);
    fastscan(u, a[1], 0, 1, 2);
    expect_silence(u);
    /* Bad fields: bit 32..127 and 0x81.., sub or next > 3. */
    uint32_t before = co_lss_slave_stats(&u->slave)->bad_argument;
    fastscan(u, 0, 32, 0, 0);
    fastscan(u, 0, 0x81, 0, 0);
    fastscan(u, 0, 31, 4, 0);
    fastscan(u, 0, 31, 0, 4);
    expect_silence(u);
    assert_int_equal(co_lss_slave_stats(&u->slave)->bad_argument, before + 4);
    co_lss_slave_deinit(&u->slave);
    test_free(u);
}

/* ------------------------------------------------------------- bad frames */

static void test_malformed(void **state)
{
    fixture_t *f = *state;
    const uint8_t d[12] = {0x04, 0x01};
    for (uint8_t len = 0; len < 8; len++) {
        feed_raw(f, 0, d, len);
    }
    assert_int_equal(co_lss_slave_stats(&f->slave)->bad_length, 8);
    assert_int_equal(co_lss_slave_state(&f->slave), CO_LSS_STATE_WAITING);
    /* A remote frame on 0x7E5 never reaches the slave: the line counts it. */
    feed_raw(f, CO_FRAME_RTR, NULL, 0);
    assert_int_equal(co_line_stats(&f->l.line)->rx_rtr, 1);
    const uint8_t unknown[] = {0x00, 0x05, 0x44, 0x4F, 0x50, 0x99, 0xFF, 0x45, 0x4D, 0x5F};
    for (size_t i = 0; i < sizeof unknown; i++) {
        feed(f, unknown[i], 1, 0, 0, 0, 0, 0, 0);
    }
    assert_int_equal(co_lss_slave_stats(&f->slave)->unknown_cs, sizeof unknown);
    expect_silence(f);
    assert_int_equal(co_lss_slave_stats(&f->slave)->requests, 0);
    /* Still working. */
    to_configuration(f);
    assert_int_equal(co_lss_slave_stats(&f->slave)->requests, 1);
}

static void test_random_frames(void **state)
{
    fixture_t *f = *state;
    uint64_t seed = 0x1505;
    for (int i = 0; i < 20000; i++) {
        uint8_t d[8];
        uint64_t r = tu_rand(&seed);
        for (int k = 0; k < 8; k++) {
            d[k] = (uint8_t)(r >> (8 * k));
        }
        /* favour the known command specifiers */
        if (r & 1u) {
            const uint8_t cs[] = {0x04, 0x11, 0x13, 0x15, 0x17, 0x40, 0x43, 0x4B, 0x4C, 0x51, 0x5E};
            d[0] = cs[(r >> 1) % sizeof cs];
        }
        feed_raw(f, 0, d, (uint8_t)((r >> 40) % 9u));
        co_frame_t out;
        while (co_line_tx_pop(&f->l.line, &out)) {
            assert_int_equal(out.id, CO_LSS_ID_SLAVE);
            assert_int_equal(out.len, 8);
        }
    }
    const co_lss_slave_stats_t *st = co_lss_slave_stats(&f->slave);
    assert_true(st->bad_length > 0 && st->unknown_cs > 0 && st->requests > 0);
    assert_int_equal(st->tx_failed, 0);
}

/* On fd lines the answer is an 8-byte FD frame; requests in either format
 * with 8 bytes are served, other lengths counted. */
static void test_fd_line(void **state)
{
    (void)state;
    fixture_t *f = make(CO_MODE_FD, 0x20, true);
    const uint8_t sw[8] = {0x04, 0x01};
    feed_raw(f, CO_FRAME_FD | CO_FRAME_BRS, sw, 8);
    assert_int_equal(co_lss_slave_state(&f->slave), CO_LSS_STATE_CONFIGURATION);
    const uint8_t inq[8] = {0x5E};
    feed_raw(f, CO_FRAME_FD, inq, 8);
    const uint8_t ans[8] = {0x5E, 0x20};
    expect_answer(f, CO_FRAME_FD | CO_FRAME_BRS, ans);
    feed_raw(f, 0, inq, 8);                  /* classic frame on the fd line */
    expect_answer(f, CO_FRAME_FD | CO_FRAME_BRS, ans);
    const uint8_t longer[12] = {0x5E};
    feed_raw(f, CO_FRAME_FD, longer, 12);
    expect_silence(f);
    assert_int_equal(co_lss_slave_stats(&f->slave)->bad_length, 1);
    co_lss_slave_deinit(&f->slave);
    test_free(f);
}

static void test_init_refused(void **state)
{
    (void)state;
    tu_line_t *l = test_calloc(1, sizeof *l);
    tu_line_init(l, CO_MODE_CLASSIC, false);
    co_lss_slave_t a, b;
    assert_false(co_lss_slave_init(&a, &l->line, &ADDRESS, 0, NULL, NULL));
    assert_false(co_lss_slave_init(&a, &l->line, &ADDRESS, 128, NULL, NULL));
    assert_true(co_lss_slave_init(&a, &l->line, &ADDRESS, 1, NULL, NULL));
    assert_false(co_lss_slave_init(&b, &l->line, &ADDRESS, 1, NULL, NULL));   /* 0x7E5 taken */
    co_lss_slave_deinit(&a);
    assert_true(co_lss_slave_init(&b, &l->line, &ADDRESS, 1, NULL, NULL));
    co_lss_slave_deinit(&b);
    test_free(l);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_codec),
        cmocka_unit_test_setup_teardown(test_switch_global, setup, teardown),
        cmocka_unit_test_setup_teardown(test_switch_selective, setup, teardown),
        cmocka_unit_test_setup_teardown(test_configure_node_id, setup, teardown),
        cmocka_unit_test_setup_teardown(test_inquire, setup, teardown),
        cmocka_unit_test_setup_teardown(test_bit_timing, setup, teardown),
        cmocka_unit_test(test_without_indications),
        cmocka_unit_test_setup_teardown(test_store, setup, teardown),
        cmocka_unit_test(test_unconfigured_gets_node_id),
        cmocka_unit_test_setup_teardown(test_identify_remote, setup, teardown),
        cmocka_unit_test_setup_teardown(test_identify_non_configured, setup, teardown),
        cmocka_unit_test_setup_teardown(test_fastscan_slave, setup, teardown),
        cmocka_unit_test_setup_teardown(test_malformed, setup, teardown),
        cmocka_unit_test_setup_teardown(test_random_frames, setup, teardown),
        cmocka_unit_test(test_fd_line),
        cmocka_unit_test(test_init_refused),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
