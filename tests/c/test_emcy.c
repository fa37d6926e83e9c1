/* EMCY: the classic and FD codecs (exact bytes, every field, lengths), the
 * producer (frames on the bus byte for byte, error register, repeated
 * raises, inhibit time on the fake clock, queue overflow, 0x1014 bit 31,
 * NMT states), its OD binding (0x1001, 0x1003 over the SDO-server write
 * path, 0x1014/0x1015 writes, 0x1031/0x1032 on FD) and the consumer (both
 * formats, 0x1028 entries, wrong lengths, random frames). Bus tests run on a
 * classic bus and on an FD bus with bit-rate switch.
 *
 * Lines: a (the producer, node 5), b (the consumer). */
#include "test_od_util.h"

#include "canopenfd/co_emcy.h"

#define NODE 5
#define EMCY_ID (0x80u + NODE)
#define QUEUE 4
#define ACTIVE 8
#define HISTORY 8
#define N_ENTRIES 64
#define POOL 1024
#define SUBS 8
#define MAX_RX 64
#define DOMAIN CO_TYPE_DOMAIN

typedef struct fx {
    tu_bus_t tb;
    tu_line_t l[2];
    co_line_t *a, *b;
    co_emcy_t emcy;
    co_emcy_msg_t queue[QUEUE];
    co_emcy_active_t active[ACTIVE];
    uint32_t history[HISTORY];
    co_emcy_consumer_t cons;
    co_od_t od;                   /* the producer's OD (when a test builds it) */
    co_od_entry_t entries[N_ENTRIES];
    uint8_t pool[POOL];
    co_od_subscription_t subs[SUBS];
    co_od_t od_b;                 /* the consumer's OD */
    co_od_entry_t entries_b[N_ENTRIES];
    uint8_t pool_b[POOL];
    co_od_subscription_t subs_b[SUBS];
    co_emcy_msg_t rx[MAX_RX];
    uint8_t rx_node[MAX_RX];
    int nrx;
} fx_t;

static void on_emcy(co_emcy_consumer_t *c, uint8_t node_id, const co_emcy_msg_t *msg, void *user)
{
    fx_t *fx = user;
    assert_ptr_equal(c, &fx->cons);
    if (fx->nrx < MAX_RX) {       /* the random-frames test counts beyond */
        fx->rx[fx->nrx] = *msg;
        fx->rx_node[fx->nrx] = node_id;
    }
    fx->nrx++;
}

static int setup(void **state, co_mode_t mode, bool brs)
{
    fx_t *fx = calloc(1, sizeof *fx);
    co_emcy_config_t cfg;
    assert_non_null(fx);
    tu_bus_init(&fx->tb, mode, brs);
    fx->a = tu_bus_add_line(&fx->tb, &fx->l[0]);
    fx->b = tu_bus_add_line(&fx->tb, &fx->l[1]);
    memset(&cfg, 0, sizeof cfg);
    cfg.queue = fx->queue;
    cfg.queue_capacity = QUEUE;
    cfg.active = fx->active;
    cfg.active_capacity = ACTIVE;
    cfg.history = fx->history;
    cfg.history_capacity = HISTORY;
    assert_true(co_emcy_init(&fx->emcy, fx->a, NODE, &cfg));
    assert_true(co_emcy_consumer_init(&fx->cons, fx->b, on_emcy, fx));
    *state = fx;
    return 0;
}

static int setup_classic(void **state) { return setup(state, CO_MODE_CLASSIC, false); }
static int setup_fd(void **state) { return setup(state, CO_MODE_FD, true); }

static int teardown(void **state)
{
    fx_t *fx = *state;
    co_emcy_consumer_deinit(&fx->cons);
    co_emcy_deinit(&fx->emcy);
    free(fx);
    return 0;
}

static bool fd_bus(const fx_t *fx) { return fx->tb.mode == CO_MODE_FD; }
static uint8_t emcy_len(const fx_t *fx) { return fd_bus(fx) ? CO_EMCY_FD_LEN : CO_EMCY_CLASSIC_LEN; }

/* Move the fake clock to t (timers on the way fire at their time). */
static void at(fx_t *fx, uint64_t t) { tu_run_until(&fx->tb, t); }
/* Carry what the lines queued at the current time. */
static void carry(fx_t *fx) { tu_step(&fx->tb, fx->tb.now); }

static co_emcy_error_t err_of(uint16_t code)
{
    co_emcy_error_t e;
    memset(&e, 0, sizeof e);
    e.code = code;
    e.msef[0] = 0x11;
    e.msef[1] = 0x22;
    e.msef[2] = 0x33;
    e.msef[3] = 0x44;
    e.msef[4] = 0x55;
    e.logical_device = 2;
    e.spec_number = 0x0191;       /* CiA 401 */
    e.priority = 3;
    e.non_recoverable = true;
    e.time_stamp = 0x0000A1B2C3D4E5F6ull;
    return e;
}

static void raise_ok(fx_t *fx, uint16_t code)
{
    co_emcy_error_t e = err_of(code);
    assert_int_equal(co_emcy_raise(&fx->emcy, &e), CO_EMCY_OK);
}

static void clear_ok(fx_t *fx, uint16_t code)
{
    co_emcy_error_t e = err_of(code);
    memset(e.msef, 0, sizeof e.msef);
    assert_int_equal(co_emcy_clear(&fx->emcy, &e), CO_EMCY_OK);
}

/* The bytes the producer must send for this message on this bus. */
static uint8_t expected(const fx_t *fx, const co_emcy_msg_t *m, uint8_t *out)
{
    size_t n = fd_bus(fx) ? co_emcy_encode_fd(m, out, 64) : co_emcy_encode_classic(m, out, 64);
    assert_int_equal(n, emcy_len(fx));
    return (uint8_t)n;
}

static void start(fx_t *fx)
{
    co_emcy_set_nmt_state(&fx->emcy, CO_NMT_PRE_OPERATIONAL);
    at(fx, 1000);
}

/* ============================================================ codec */

static void test_classic_codec_exact_bytes(void **state)
{
    (void)state;
    co_emcy_msg_t m, d;
    uint8_t out[8];
    static const uint8_t want[8] = {0x10, 0x32, 0x03, 1, 2, 3, 4, 5};
    memset(&m, 0, sizeof m);
    m.code = 0x3210;
    m.error_register = 0x03;
    memcpy(m.msef, "\x01\x02\x03\x04\x05", 5);
    m.logical_device = 9;         /* FD-only fields do not reach the classic frame */
    assert_int_equal(co_emcy_encode_classic(&m, out, sizeof out), 8);
    assert_memory_equal(out, want, 8);
    assert_int_equal(co_emcy_encode_classic(&m, out, 7), 0);
    assert_true(co_emcy_decode_classic(want, 8, &d));
    assert_int_equal(d.code, 0x3210);
    assert_int_equal(d.error_register, 0x03);
    assert_memory_equal(d.msef, want + 3, 5);
    assert_int_equal(d.logical_device, 0);
    assert_int_equal(d.status, 0);
    assert_true(d.time_stamp == 0);
    /* Shorter and longer frames are refused; nothing is written. */
    memset(&d, 0xAB, sizeof d);
    assert_false(co_emcy_decode_classic(want, 7, &d));
    assert_false(co_emcy_decode_classic(want, 0, &d));
    assert_false(co_emcy_decode_classic(NULL, 8, &d));
    assert_int_equal(d.code, 0xABAB);
    {
        uint8_t nine[9] = {0};
        assert_false(co_emcy_decode_classic(nine, 9, &d));
    }
}

static void test_fd_codec_exact_bytes(void **state)
{
    (void)state;
    co_emcy_msg_t m, d;
    uint8_t out[24];
    static const uint8_t want[20] = {
        0x30, 0x81,                   /* EEC 0x8130 */
        0x11,                         /* error register */
        0xA1, 0xA2, 0xA3, 0xA4, 0xA5, /* msef */
        0x07,                         /* logical device */
        0x15, 0x05,                   /* CiA 1301 */
        0x3C,                         /* status: prio 4, non-recoverable, occurred, repeated */
        0x06, 0x05, 0x04, 0x03, 0x02, 0x01,   /* time 0x010203040506 */
        0x00, 0x00};
    memset(&m, 0, sizeof m);
    m.code = 0x8130;
    m.error_register = 0x11;
    memcpy(m.msef, "\xA1\xA2\xA3\xA4\xA5", 5);
    m.logical_device = 7;
    m.spec_number = 1301;
    m.status = 0x3C;
    m.time_stamp = 0x010203040506ull;
    memset(out, 0xEE, sizeof out);
    assert_int_equal(co_emcy_encode_fd(&m, out, sizeof out), CO_EMCY_FD_LEN);
    assert_memory_equal(out, want, 20);
    assert_true(co_fd_len_valid(CO_EMCY_FD_LEN));
    assert_int_equal(co_emcy_encode_fd(&m, out, 19), 0);
    m.time_stamp = CO_EMCY_TIME_MAX + 1;
    assert_int_equal(co_emcy_encode_fd(&m, out, sizeof out), 0);

    assert_true(co_emcy_decode_fd(want, 20, &d));
    assert_int_equal(d.code, 0x8130);
    assert_int_equal(d.error_register, 0x11);
    assert_memory_equal(d.msef, want + 3, 5);
    assert_int_equal(d.logical_device, 7);
    assert_int_equal(d.spec_number, 1301);
    assert_int_equal(d.status, 0x3C);
    assert_true(d.time_stamp == 0x010203040506ull);
    /* Shorter than the layout: refused; longer (padding): the layout read. */
    assert_false(co_emcy_decode_fd(want, 19, &d));
    assert_false(co_emcy_decode_fd(want, 8, &d));
    {
        uint8_t longer[24];
        memset(longer, 0x99, sizeof longer);
        memcpy(longer, want, 20);
        assert_true(co_emcy_decode_fd(longer, 24, &d));
        assert_true(d.time_stamp == 0x010203040506ull);
    }
}

static void test_fd_codec_round_trip_every_field(void **state)
{
    (void)state;
    uint64_t seed = 0x1234567ull;
    for (int i = 0; i < 2000; i++) {
        co_emcy_msg_t m, d;
        uint8_t out[20];
        uint64_t r = tu_rand(&seed);
        memset(&m, 0, sizeof m);
        m.code = (uint16_t)r;
        m.error_register = (uint8_t)(r >> 16);
        m.logical_device = (uint8_t)(r >> 24);
        m.spec_number = (uint16_t)(r >> 32);
        m.status = (uint8_t)(r >> 48);
        r = tu_rand(&seed);
        memcpy(m.msef, &r, 5);
        m.time_stamp = tu_rand(&seed) & CO_EMCY_TIME_MAX;
        assert_int_equal(co_emcy_encode_fd(&m, out, sizeof out), 20);
        assert_true(co_emcy_decode_fd(out, 20, &d));
        assert_memory_equal(&d.code, &m.code, sizeof m.code);
        assert_int_equal(d.code, m.code);
        assert_int_equal(d.error_register, m.error_register);
        assert_memory_equal(d.msef, m.msef, 5);
        assert_int_equal(d.logical_device, m.logical_device);
        assert_int_equal(d.spec_number, m.spec_number);
        assert_int_equal(d.status, m.status);
        assert_true(d.time_stamp == m.time_stamp);
        /* the classic codec carries the common fields */
        assert_int_equal(co_emcy_encode_classic(&m, out, sizeof out), 8);
        assert_true(co_emcy_decode_classic(out, 8, &d));
        assert_int_equal(d.code, m.code);
        assert_int_equal(d.error_register, m.error_register);
        assert_memory_equal(d.msef, m.msef, 5);
    }
}

static void test_codec_register_bits(void **state)
{
    (void)state;
    assert_int_equal(co_emcy_code_register_bits(0x0000), 0);
    assert_int_equal(co_emcy_code_register_bits(0x1000), 0);
    assert_int_equal(co_emcy_code_register_bits(0x2310), CO_EMCY_ER_CURRENT);
    assert_int_equal(co_emcy_code_register_bits(0x3210), CO_EMCY_ER_VOLTAGE);
    assert_int_equal(co_emcy_code_register_bits(0x4210), CO_EMCY_ER_TEMPERATURE);
    assert_int_equal(co_emcy_code_register_bits(0x5000), 0);
    assert_int_equal(co_emcy_code_register_bits(0x6100), 0);
    assert_int_equal(co_emcy_code_register_bits(0x8000), CO_EMCY_ER_COMMUNICATION);
    assert_int_equal(co_emcy_code_register_bits(0x8130), CO_EMCY_ER_COMMUNICATION);
    assert_int_equal(co_emcy_code_register_bits(0x8210), CO_EMCY_ER_COMMUNICATION);
    assert_int_equal(co_emcy_code_register_bits(0x8400), 0);
    assert_int_equal(co_emcy_code_register_bits(0x9000), 0);
    assert_int_equal(co_emcy_code_register_bits(0xF000), 0);
    assert_int_equal(co_emcy_code_register_bits(0xFF01), CO_EMCY_ER_MANUFACTURER);
}

/* ========================================================= producer */

static void test_init_refuses_bad_config(void **state)
{
    fx_t *fx = *state;
    co_emcy_t e;
    co_emcy_config_t cfg;
    memset(&cfg, 0, sizeof cfg);
    cfg.queue = fx->queue;
    cfg.queue_capacity = QUEUE;
    cfg.active = fx->active;
    cfg.active_capacity = ACTIVE;
    assert_true(co_emcy_init(&e, fx->a, 127, &cfg));
    assert_false(co_emcy_init(&e, fx->a, 0, &cfg));
    assert_false(co_emcy_init(&e, fx->a, 128, &cfg));
    cfg.history_capacity = 3;     /* no storage */
    assert_false(co_emcy_init(&e, fx->a, 1, &cfg));
    cfg.history_capacity = 0;
    cfg.queue_capacity = 0;
    assert_false(co_emcy_init(&e, fx->a, 1, &cfg));
    cfg.queue_capacity = QUEUE;
    cfg.active = NULL;
    assert_false(co_emcy_init(&e, fx->a, 1, &cfg));
}

static void test_raise_sends_exact_frame(void **state)
{
    fx_t *fx = *state;
    co_emcy_msg_t m;
    uint8_t want[20];
    start(fx);
    raise_ok(fx, 0x3210);
    carry(fx);
    assert_int_equal(fx->tb.log_count, 1);
    memset(&m, 0, sizeof m);
    m.code = 0x3210;
    m.error_register = CO_EMCY_ER_GENERIC | CO_EMCY_ER_VOLTAGE;
    memcpy(m.msef, "\x11\x22\x33\x44\x55", 5);
    if (fd_bus(fx)) {
        m.logical_device = 2;
        m.spec_number = 0x0191;
        m.status = 3 | CO_EMCY_STATUS_NON_RECOVERABLE | CO_EMCY_STATUS_OCCURRED;
        m.time_stamp = 0x0000A1B2C3D4E5F6ull;
    }
    tu_assert_logged(&fx->tb, 0, EMCY_ID, want, expected(fx, &m, want));
    /* spelled out once, so an encoder change cannot hide here */
    assert_int_equal(fx->tb.log[0].frame.data[0], 0x10);
    assert_int_equal(fx->tb.log[0].frame.data[1], 0x32);
    assert_int_equal(fx->tb.log[0].frame.data[2], 0x05);
    if (fd_bus(fx)) {
        assert_int_equal(fx->tb.log[0].frame.data[8], 2);
        assert_int_equal(fx->tb.log[0].frame.data[11], 0x1B);
        assert_int_equal(fx->tb.log[0].frame.data[17], 0xA1);
    }
    assert_int_equal(fx->emcy.stats.sent, 1);
    assert_int_equal(fx->emcy.stats.queued, 0);
}

static void test_error_register_follows_active_errors(void **state)
{
    fx_t *fx = *state;
    co_emcy_error_t e = err_of(0x6100);
    uint8_t want[20];
    co_emcy_msg_t m;
    start(fx);
    assert_int_equal(co_emcy_error_register(&fx->emcy), 0);
    raise_ok(fx, 0x2310);
    assert_int_equal(co_emcy_error_register(&fx->emcy), 0x03);
    raise_ok(fx, 0x3210);
    assert_int_equal(co_emcy_error_register(&fx->emcy), 0x07);
    raise_ok(fx, 0x4210);
    assert_int_equal(co_emcy_error_register(&fx->emcy), 0x0F);
    raise_ok(fx, 0x8130);
    assert_int_equal(co_emcy_error_register(&fx->emcy), 0x1F);
    raise_ok(fx, 0xFF01);
    assert_int_equal(co_emcy_error_register(&fx->emcy), 0x9F);
    e.register_bits = CO_EMCY_ER_DEVICE_PROFILE | 0x40;   /* bit 6 reserved: ignored */
    assert_int_equal(co_emcy_raise(&fx->emcy, &e), CO_EMCY_OK);
    assert_int_equal(co_emcy_error_register(&fx->emcy), 0xBF);
    assert_int_equal(co_emcy_active_count(&fx->emcy), 6);

    clear_ok(fx, 0x3210);
    assert_int_equal(co_emcy_error_register(&fx->emcy), 0xBB);
    carry(fx);
    /* the clear's EMCY carries the register after the clear */
    assert_int_equal(fx->tb.log_count, 7);
    memset(&m, 0, sizeof m);
    if (fd_bus(fx)) {
        m.code = 0x3210;
        m.logical_device = 2;
        m.spec_number = 0x0191;
        m.status = 3 | CO_EMCY_STATUS_NON_RECOVERABLE;   /* removed */
        m.time_stamp = 0x0000A1B2C3D4E5F6ull;
    }
    m.error_register = 0xBB;
    tu_assert_logged(&fx->tb, 6, EMCY_ID, want, expected(fx, &m, want));

    clear_ok(fx, 0x2310);
    clear_ok(fx, 0x4210);
    clear_ok(fx, 0x8130);
    clear_ok(fx, 0xFF01);
    assert_int_equal(co_emcy_error_register(&fx->emcy), 0x21);   /* 0x6100 + profile */
    clear_ok(fx, 0x6100);
    assert_int_equal(co_emcy_error_register(&fx->emcy), 0);
    carry(fx);
    assert_int_equal(fx->tb.log_count, 12);
    assert_int_equal(fx->tb.log[11].frame.data[2], 0);
    if (!fd_bus(fx)) {
        /* error reset / no error: EEC 0x0000 */
        assert_int_equal(fx->tb.log[11].frame.data[0], 0);
        assert_int_equal(fx->tb.log[11].frame.data[1], 0);
    }
    assert_int_equal(co_emcy_clear(&fx->emcy, &e), CO_EMCY_NOT_ACTIVE);
}

static void test_repeated_raise(void **state)
{
    fx_t *fx = *state;
    co_emcy_error_t e = err_of(0x8130);
    start(fx);
    raise_ok(fx, 0x8130);
    e.msef[0] = 0x77;
    e.time_stamp = 42;
    assert_int_equal(co_emcy_raise(&fx->emcy, &e), CO_EMCY_REPEATED);
    carry(fx);
    assert_int_equal(fx->emcy.stats.repeated, 1);
    assert_int_equal(co_emcy_active_count(&fx->emcy), 1);
    if (!fd_bus(fx)) {
        /* classic: one EMCY per error event */
        assert_int_equal(fx->tb.log_count, 1);
        assert_int_equal(fx->emcy.stats.sent, 1);
    } else {
        const co_frame_t *f = &fx->tb.log[1].frame;
        assert_int_equal(fx->tb.log_count, 2);
        assert_int_equal(f->data[3], 0x77);
        assert_int_equal(f->data[11], 3 | CO_EMCY_STATUS_NON_RECOVERABLE |
                                          CO_EMCY_STATUS_OCCURRED | CO_EMCY_STATUS_REPEATED);
        assert_int_equal(f->data[12], 42);
        /* the same code on another logical device is another error */
        e.logical_device = 3;
        assert_int_equal(co_emcy_raise(&fx->emcy, &e), CO_EMCY_OK);
        assert_int_equal(co_emcy_active_count(&fx->emcy), 2);
    }
}

static void test_bad_arguments(void **state)
{
    fx_t *fx = *state;
    co_emcy_error_t e = err_of(0);
    start(fx);
    assert_int_equal(co_emcy_raise(&fx->emcy, &e), CO_EMCY_BAD_ARGUMENT);
    assert_int_equal(co_emcy_clear(&fx->emcy, &e), CO_EMCY_BAD_ARGUMENT);
    e = err_of(0x1000);
    e.priority = 8;
    assert_int_equal(co_emcy_raise(&fx->emcy, &e), CO_EMCY_BAD_ARGUMENT);
    e.priority = 7;
    e.time_stamp = CO_EMCY_TIME_MAX + 1;
    assert_int_equal(co_emcy_raise(&fx->emcy, &e), CO_EMCY_BAD_ARGUMENT);
    assert_int_equal(co_emcy_raise(&fx->emcy, NULL), CO_EMCY_BAD_ARGUMENT);
    carry(fx);
    assert_int_equal(fx->tb.log_count, 0);
    assert_int_equal(co_emcy_error_register(&fx->emcy), 0);
}

static void test_active_table_full(void **state)
{
    fx_t *fx = *state;
    co_emcy_error_t e;
    start(fx);
    for (uint16_t i = 0; i < ACTIVE; i++)
        raise_ok(fx, (uint16_t)(0x1000 + i));
    e = err_of(0x2000);
    assert_int_equal(co_emcy_raise(&fx->emcy, &e), CO_EMCY_TABLE_FULL);
    assert_int_equal(fx->emcy.stats.table_full, 1);
    assert_int_equal(co_emcy_error_register(&fx->emcy), 0x01);   /* no current bit */
    assert_false(co_emcy_is_active(&fx->emcy, 0x2000, 2));
}

static void test_inhibit_time_delays_second_emcy(void **state)
{
    fx_t *fx = *state;
    long i1;
    co_emcy_set_inhibit(&fx->emcy, 10);     /* 10 x 100 us = 1 ms */
    start(fx);
    raise_ok(fx, 0x1000);
    carry(fx);
    at(fx, 1050);
    raise_ok(fx, 0x2000);
    assert_int_equal(fx->emcy.stats.queued, 1);
    at(fx, 1999);
    assert_int_equal(fx->tb.log_count, 1);
    at(fx, 2000);
    assert_int_equal(fx->tb.log_count, 2);
    assert_true(fx->tb.log[0].t_us == 1000);
    i1 = tu_log_find_id(&fx->tb, EMCY_ID, 1);
    assert_true(fx->tb.log[i1].t_us == 2000);
    assert_int_equal(fx->tb.log[i1].frame.data[1], 0x20);
    assert_int_equal(fx->emcy.stats.sent, 2);
}

static void test_inhibit_write_retimes_pending(void **state)
{
    fx_t *fx = *state;
    co_emcy_set_inhibit(&fx->emcy, 10);
    start(fx);
    raise_ok(fx, 0x1000);
    carry(fx);
    at(fx, 1100);
    raise_ok(fx, 0x2000);
    co_emcy_set_inhibit(&fx->emcy, 50);     /* 5 ms from the first EMCY */
    at(fx, 5999);
    assert_int_equal(fx->tb.log_count, 1);
    at(fx, 6000);
    assert_int_equal(fx->tb.log_count, 2);
    /* shortened below the time passed: goes at once */
    raise_ok(fx, 0x3000);
    co_emcy_set_inhibit(&fx->emcy, 20);
    at(fx, 7999);
    assert_int_equal(fx->tb.log_count, 2);
    at(fx, 8000);
    assert_int_equal(fx->tb.log_count, 3);
    co_emcy_set_inhibit(&fx->emcy, 0);
    raise_ok(fx, 0x4000);
    raise_ok(fx, 0x5000);
    carry(fx);
    assert_int_equal(fx->tb.log_count, 5);
}

static void test_queue_overflow_drops_and_counts(void **state)
{
    fx_t *fx = *state;
    co_emcy_set_inhibit(&fx->emcy, 10);
    start(fx);
    for (uint16_t i = 0; i < 6; i++)
        raise_ok(fx, (uint16_t)(0x1000 + i));
    carry(fx);
    assert_int_equal(fx->tb.log_count, 1);
    assert_int_equal(fx->emcy.stats.queued, QUEUE);
    assert_int_equal(fx->emcy.stats.dropped, 1);
    assert_true(co_emcy_take_overflow(&fx->emcy));
    assert_false(co_emcy_take_overflow(&fx->emcy));
    at(fx, 10000);
    assert_int_equal(fx->tb.log_count, 5);
    for (int k = 0; k < 5; k++) {
        assert_true(fx->tb.log[k].t_us == 1000u + 1000u * (unsigned)k);
        assert_int_equal(fx->tb.log[k].frame.data[0], k);   /* in order, 0x1005 dropped */
        assert_int_equal(fx->tb.log[k].frame.data[1], 0x10);
    }
    /* the dropped error is still active */
    assert_true(co_emcy_is_active(&fx->emcy, 0x1005, 2));
}

static void test_cob_id_invalid_sends_nothing(void **state)
{
    fx_t *fx = *state;
    co_emcy_set_cob_id(&fx->emcy, 0x80000000u | EMCY_ID);
    start(fx);
    raise_ok(fx, 0x3000);
    carry(fx);
    assert_int_equal(fx->tb.log_count, 0);
    assert_int_equal(fx->emcy.stats.suppressed, 1);
    assert_int_equal(co_emcy_error_register(&fx->emcy), 0x05);
    /* valid again, another CAN-ID */
    co_emcy_set_cob_id(&fx->emcy, 0xA0);
    raise_ok(fx, 0x4000);
    carry(fx);
    assert_int_equal(fx->tb.log_count, 1);
    assert_int_equal(fx->tb.log[0].frame.id, 0xA0);
    /* waiting EMCYs are discarded when it becomes invalid */
    co_emcy_set_inhibit(&fx->emcy, 10);
    raise_ok(fx, 0x5000);
    assert_int_equal(fx->emcy.stats.queued, 1);
    co_emcy_set_cob_id(&fx->emcy, 0x800000A0u);
    at(fx, 5000);
    assert_int_equal(fx->tb.log_count, 1);
    assert_int_equal(fx->emcy.stats.suppressed, 2);
}

static void test_29_bit_cob_id(void **state)
{
    fx_t *fx = *state;
    co_emcy_set_cob_id(&fx->emcy, CO_EMCY_COB_ID_FRAME | 0x1234567u);
    assert_true(co_emcy_consumer_set_entry(&fx->cons, 9, CO_EMCY_COB_ID_FRAME | 0x1234567u));
    start(fx);
    raise_ok(fx, 0x3000);
    carry(fx);
    assert_int_equal(fx->tb.log_count, 1);
    assert_int_equal(fx->tb.log[0].frame.id, 0x1234567);
    assert_true(fx->tb.log[0].frame.flags & CO_FRAME_EXT);
    assert_int_equal(fx->nrx, 1);
    assert_int_equal(fx->rx_node[0], 9);
}

static void test_nmt_stopped_sends_nothing(void **state)
{
    fx_t *fx = *state;
    co_emcy_set_nmt_state(&fx->emcy, CO_NMT_STOPPED);
    at(fx, 1000);
    raise_ok(fx, 0x2000);
    raise_ok(fx, 0x3000);
    clear_ok(fx, 0x2000);
    at(fx, 50000);
    assert_int_equal(fx->tb.log_count, 0);
    assert_int_equal(co_emcy_error_register(&fx->emcy), 0x05);
    assert_int_equal(fx->emcy.stats.queued, 3);
    /* initialising sends nothing either */
    co_emcy_set_nmt_state(&fx->emcy, CO_NMT_INITIALISING);
    at(fx, 60000);
    assert_int_equal(fx->tb.log_count, 0);
    /* on entering operational they go out, in order */
    co_emcy_set_nmt_state(&fx->emcy, CO_NMT_OPERATIONAL);
    carry(fx);
    assert_int_equal(fx->tb.log_count, 3);
    assert_int_equal(fx->tb.log[0].frame.data[1], 0x20);
    assert_int_equal(fx->tb.log[1].frame.data[1], 0x30);
    assert_int_equal(fx->tb.log[2].frame.data[2], 0x05);   /* the clear: register then */
    assert_int_equal(fx->emcy.stats.sent, 3);
}

static void test_clear_all(void **state)
{
    fx_t *fx = *state;
    start(fx);
    assert_int_equal(co_emcy_clear_all(&fx->emcy), 0);
    raise_ok(fx, 0x2000);
    raise_ok(fx, 0x3000);
    carry(fx);
    tu_log_clear(&fx->tb);
    assert_int_equal(co_emcy_clear_all(&fx->emcy), 2);
    carry(fx);
    assert_int_equal(co_emcy_error_register(&fx->emcy), 0);
    if (fd_bus(fx)) {
        assert_int_equal(fx->tb.log_count, 2);
        assert_int_equal(fx->tb.log[0].frame.data[1], 0x20);
        assert_int_equal(fx->tb.log[0].frame.data[2], 0x05);   /* 0x3000 still active */
        assert_int_equal(fx->tb.log[0].frame.data[11] & CO_EMCY_STATUS_OCCURRED, 0);
        assert_int_equal(fx->tb.log[1].frame.data[1], 0x30);
        assert_int_equal(fx->tb.log[1].frame.data[2], 0x00);
    } else {
        static const uint8_t reset[8] = {0};
        assert_int_equal(fx->tb.log_count, 1);
        tu_assert_logged(&fx->tb, 0, EMCY_ID, reset, 8);
    }
}

/* ======================================================= OD binding */

static void add_u(co_od_t *od, uint16_t index, uint8_t sub, uint8_t object_code, uint8_t type,
                  uint8_t access, uint16_t flags, uint32_t value)
{
    co_od_def_t d = tu_od_def(index, sub, object_code, type, access, flags, co_od_type_size(type));
    uint8_t v[4];
    tu_le_put(v, value, d.size);
    d.default_value = v;
    d.default_length = d.size;
    assert_int_equal(co_od_add(od, &d), CO_OD_ADDED);
}

/* history_subs: number of 0x1003 entries. */
static void build_od(fx_t *fx, co_od_t *od, co_od_entry_t *entries, uint8_t *pool,
                     co_od_subscription_t *subs, uint8_t history_subs, uint8_t node_id)
{
    uint8_t sub;
    co_od_def_t d;
    co_od_init(od, fx->tb.mode, entries, N_ENTRIES, pool, POOL, subs, SUBS);
    add_u(od, 0x1001, 0, VAR, U8, RO, 0, 0);
    add_u(od, 0x1003, 0, ARR, U8, RW, 0, 0);
    for (sub = 1; sub <= history_subs; sub++)
        add_u(od, 0x1003, sub, ARR, U32, RO, 0, 0);
    add_u(od, 0x1014, 0, VAR, U32, RW, CO_OD_NODEID_RELATIVE, 0x80);
    add_u(od, 0x1015, 0, VAR, U16, RW, 0, 0);
    add_u(od, 0x1028, 0, ARR, U8, RO, 0, 9);
    for (sub = 1; sub <= 9; sub++)
        add_u(od, 0x1028, sub, ARR, U32, RW, 0, 0x80000000u);
    add_u(od, 0x1031, 0, REC, U8, RO, 0, 5);
    add_u(od, 0x1031, 1, REC, U32, RO, 0, 0);
    d = tu_od_def(0x1031, 4, REC, DOMAIN, RO, 0, 0);
    assert_int_equal(co_od_add(od, &d), CO_OD_ADDED);
    add_u(od, 0x1032, 0, ARR, U8, RO, 0, 0);
    for (sub = 1; sub <= 3; sub++)
        add_u(od, 0x1032, sub, ARR, U32, RO, 0, 0);
    assert_true(co_od_seal(od, node_id));
}

static void bind_od(fx_t *fx, uint8_t history_subs)
{
    build_od(fx, &fx->od, fx->entries, fx->pool, fx->subs, history_subs, NODE);
    assert_true(co_emcy_attach_od(&fx->emcy, &fx->od));
}

/* A network download as the SDO server does it: begin with the size, the
 * data in two chunks, end. Returns the abort code (0 = written). */
static uint32_t net_write(co_od_t *od, uint16_t index, uint8_t sub, uint32_t value, uint32_t len)
{
    co_od_xfer_t x;
    uint8_t scratch[8], data[4];
    uint32_t r, half = len / 2;
    tu_le_put(data, value, len);
    co_od_xfer_init(&x, scratch, sizeof scratch);
    r = co_od_write_begin(od, &x, index, sub, len);
    if (r != 0)
        return r;
    r = co_od_write_chunk(&x, data, half);
    if (r != 0)
        return r;
    r = co_od_write_chunk(&x, data + half, len - half);
    if (r != 0)
        return r;
    r = co_od_write_end(&x);
    assert_int_not_equal(r, CO_OD_SPLIT);
    assert_int_equal(x.state, CO_XFER_DONE);
    return r;
}

static uint32_t od_u32(fx_t *fx, uint16_t index, uint8_t sub)
{
    uint32_t v = 0xDEADBEEF;
    assert_true(co_od_get_u32(&fx->od, index, sub, &v));
    return v;
}

static uint8_t od_u8(fx_t *fx, uint16_t index, uint8_t sub)
{
    uint8_t v = 0xEE;
    assert_true(co_od_get_u8(&fx->od, index, sub, &v));
    return v;
}

static uint32_t list_value(uint16_t code) { return code | 0x11u << 16 | 0x22u << 24; }

static void test_od_history_order_clear_abort(void **state)
{
    fx_t *fx = *state;
    bind_od(fx, 4);
    start(fx);
    assert_int_equal(od_u8(fx, 0x1003, 0), 0);
    raise_ok(fx, 0x1000);
    raise_ok(fx, 0x2000);
    assert_int_equal(od_u8(fx, 0x1003, 0), 2);
    assert_int_equal(od_u32(fx, 0x1003, 1), list_value(0x2000));   /* newest at sub 1 */
    assert_int_equal(od_u32(fx, 0x1003, 2), list_value(0x1000));
    assert_int_equal(od_u32(fx, 0x1003, 3), 0);
    raise_ok(fx, 0x3000);
    raise_ok(fx, 0x4000);
    raise_ok(fx, 0x5000);       /* 0x1000 shifts out: 4 entries */
    assert_int_equal(od_u8(fx, 0x1003, 0), 4);
    assert_int_equal(od_u32(fx, 0x1003, 1), list_value(0x5000));
    assert_int_equal(od_u32(fx, 0x1003, 4), list_value(0x2000));
    /* a clear is not a history entry */
    clear_ok(fx, 0x5000);
    assert_int_equal(od_u32(fx, 0x1003, 1), list_value(0x5000));
    /* error register in the OD */
    assert_int_equal(od_u8(fx, 0x1001, 0), 0x0F);

    /* any value but 0: 0x06090030, nothing changes */
    assert_int_equal(net_write(&fx->od, 0x1003, 0, 1, 1), CO_ABORT_INVALID_VALUE);
    assert_int_equal(net_write(&fx->od, 0x1003, 0, 4, 1), CO_ABORT_INVALID_VALUE);
    assert_int_equal(od_u8(fx, 0x1003, 0), 4);
    /* entries are read-only */
    assert_int_equal(net_write(&fx->od, 0x1003, 1, 0, 4), CO_ABORT_READ_ONLY);
    /* 0 clears */
    assert_int_equal(net_write(&fx->od, 0x1003, 0, 0, 1), 0);
    assert_int_equal(od_u8(fx, 0x1003, 0), 0);
    for (uint8_t s = 1; s <= 4; s++)
        assert_int_equal(od_u32(fx, 0x1003, s), 0);
    /* the active errors are untouched; new ones start a new history */
    assert_int_equal(co_emcy_active_count(&fx->emcy), 4);
    raise_ok(fx, 0x6000);
    assert_int_equal(od_u8(fx, 0x1003, 0), 1);
    assert_int_equal(od_u32(fx, 0x1003, 1), list_value(0x6000));
    /* a reset loading defaults gets the producer's values back */
    co_od_load_defaults(&fx->od, CO_GROUP_COMMUNICATION);
    assert_int_equal(od_u8(fx, 0x1003, 0), 1);
    assert_int_equal(od_u32(fx, 0x1003, 1), list_value(0x6000));
    assert_int_equal(od_u8(fx, 0x1001, 0), 0x0F);
}

static void test_od_history_length_is_the_od_s(void **state)
{
    fx_t *fx = *state;
    bind_od(fx, 2);
    start(fx);
    raise_ok(fx, 0x1000);
    raise_ok(fx, 0x2000);
    raise_ok(fx, 0x3000);
    assert_int_equal(od_u8(fx, 0x1003, 0), 2);
    assert_int_equal(od_u32(fx, 0x1003, 1), list_value(0x3000));
    assert_int_equal(od_u32(fx, 0x1003, 2), list_value(0x2000));
    assert_null(co_od_find(&fx->od, 0x1003, 3));
}

static void test_od_cob_id_and_inhibit_writes(void **state)
{
    fx_t *fx = *state;
    bind_od(fx, 4);
    start(fx);
    /* $NODEID default */
    assert_int_equal(od_u32(fx, 0x1014, 0), EMCY_ID);
    assert_int_equal(net_write(&fx->od, 0x1014, 0, 0x80000000u | EMCY_ID, 4), 0);
    raise_ok(fx, 0x1000);
    carry(fx);
    assert_int_equal(fx->tb.log_count, 0);
    assert_int_equal(net_write(&fx->od, 0x1014, 0, 0x90, 4), 0);
    assert_int_equal(net_write(&fx->od, 0x1015, 0, 10, 2), 0);
    raise_ok(fx, 0x2000);
    carry(fx);
    at(fx, 1100);
    raise_ok(fx, 0x3000);
    assert_int_equal(net_write(&fx->od, 0x1015, 0, 30, 2), 0);   /* re-times it */
    at(fx, 3999);
    assert_int_equal(fx->tb.log_count, 1);
    at(fx, 4000);
    assert_int_equal(fx->tb.log_count, 2);
    assert_int_equal(fx->tb.log[1].frame.id, 0x90);
    /* the API writes the OD */
    co_emcy_set_inhibit(&fx->emcy, 7);
    assert_int_equal(od_u32(fx, 0x1014, 0), 0x90);
    {
        uint16_t v = 0;
        assert_true(co_od_get_u16(&fx->od, 0x1015, 0, &v));
        assert_int_equal(v, 7);
    }
}

static void test_od_fd_active_list_and_history_domain(void **state)
{
    fx_t *fx = *state;
    co_od_xfer_t x;
    uint8_t scratch[8], buf[64];
    uint32_t n_total = 0, n;
    bool last = false;
    bind_od(fx, 4);
    start(fx);
    raise_ok(fx, 0x2000);
    raise_ok(fx, 0x3000);
    raise_ok(fx, 0x4000);
    raise_ok(fx, 0x5000);
    clear_ok(fx, 0x3000);
    /* 0x1032: the active errors, newest first, as many as it holds */
    assert_int_equal(od_u8(fx, 0x1032, 0), 3);
    assert_int_equal(od_u32(fx, 0x1032, 1), list_value(0x5000));
    assert_int_equal(od_u32(fx, 0x1032, 2), list_value(0x4000));
    assert_int_equal(od_u32(fx, 0x1032, 3), list_value(0x2000));
    assert_int_equal(od_u32(fx, 0x1031, 1), 3);
    clear_ok(fx, 0x5000);
    clear_ok(fx, 0x4000);
    assert_int_equal(od_u8(fx, 0x1032, 0), 1);
    assert_int_equal(od_u32(fx, 0x1032, 1), list_value(0x2000));
    assert_int_equal(od_u32(fx, 0x1032, 2), 0);
    raise_ok(fx, 0x6000);
    /* 0x1031:04: one FD EMCY record per active error, newest first, read in
     * small chunks as an SDO server would */
    co_od_xfer_init(&x, scratch, sizeof scratch);
    assert_int_equal(co_od_read_begin(&fx->od, &x, 0x1031, 4), 0);
    assert_int_equal(x.total, 2 * CO_EMCY_FD_LEN);
    while (!last) {
        assert_int_equal(co_od_read_chunk(&x, buf + n_total, 7, &n, &last), 0);
        n_total += n;
        assert_true(n_total <= sizeof buf);
    }
    assert_int_equal(n_total, 40);
    {
        co_emcy_msg_t m;
        assert_true(co_emcy_decode_fd(buf, 20, &m));
        assert_int_equal(m.code, 0x6000);
        assert_int_equal(m.error_register, 0x03);   /* 0x2000 is still active */
        assert_int_equal(m.logical_device, 2);
        assert_true(m.time_stamp == 0x0000A1B2C3D4E5F6ull);
        assert_true(co_emcy_decode_fd(buf + 20, 20, &m));
        assert_int_equal(m.code, 0x2000);
        assert_int_equal(m.status & CO_EMCY_STATUS_OCCURRED, CO_EMCY_STATUS_OCCURRED);
    }
}

static void test_od_attach_refuses_unsealed(void **state)
{
    fx_t *fx = *state;
    co_od_init(&fx->od, fx->tb.mode, fx->entries, N_ENTRIES, fx->pool, POOL, fx->subs, SUBS);
    add_u(&fx->od, 0x1001, 0, VAR, U8, RO, 0, 0);
    assert_false(co_emcy_attach_od(&fx->emcy, &fx->od));
    assert_false(co_emcy_consumer_attach_od(&fx->cons, &fx->od));
    assert_true(co_od_seal(&fx->od, NODE));
    assert_true(co_emcy_attach_od(&fx->emcy, &fx->od));
    assert_false(co_emcy_attach_od(&fx->emcy, &fx->od));   /* already bound */
    /* works with an OD that has only 0x1001 */
    start(fx);
    raise_ok(fx, 0x4000);
    carry(fx);
    assert_int_equal(fx->tb.log_count, 1);
    assert_int_equal(od_u8(fx, 0x1001, 0), 0x09);
}

/* ========================================================= consumer */

static void test_consumer_delivers_every_field(void **state)
{
    fx_t *fx = *state;
    co_emcy_msg_t *m;
    assert_true(co_emcy_consumer_watch(&fx->cons, NODE));
    assert_int_equal(co_emcy_consumer_get_entry(&fx->cons, NODE), EMCY_ID);
    start(fx);
    raise_ok(fx, 0x4210);
    carry(fx);
    assert_int_equal(fx->nrx, 1);
    assert_int_equal(fx->rx_node[0], NODE);
    m = &fx->rx[0];
    assert_int_equal(m->code, 0x4210);
    assert_int_equal(m->error_register, 0x09);
    assert_memory_equal(m->msef, "\x11\x22\x33\x44\x55", 5);
    if (fd_bus(fx)) {
        assert_int_equal(m->logical_device, 2);
        assert_int_equal(m->spec_number, 0x0191);
        assert_int_equal(m->status, 3 | CO_EMCY_STATUS_NON_RECOVERABLE | CO_EMCY_STATUS_OCCURRED);
        assert_true(m->time_stamp == 0x0000A1B2C3D4E5F6ull);
    } else {
        assert_int_equal(m->logical_device, 0);
        assert_int_equal(m->status, 0);
        assert_true(m->time_stamp == 0);
    }
    assert_int_equal(fx->cons.stats.received, 1);
    /* not consumed any more: the line counts it as unhandled */
    co_emcy_consumer_unwatch(&fx->cons, NODE);
    raise_ok(fx, 0x5000);
    carry(fx);
    assert_int_equal(fx->nrx, 1);
    assert_int_equal(fx->b->stats.rx_unhandled, 1);
    assert_false(co_emcy_consumer_set_entry(&fx->cons, 0, EMCY_ID));
    assert_false(co_emcy_consumer_set_entry(&fx->cons, 128, EMCY_ID));
}

static void test_consumer_from_od_entries(void **state)
{
    fx_t *fx = *state;
    build_od(fx, &fx->od_b, fx->entries_b, fx->pool_b, fx->subs_b, 1, 6);
    assert_true(co_emcy_consumer_attach_od(&fx->cons, &fx->od_b));
    start(fx);
    raise_ok(fx, 0x1000);
    carry(fx);
    assert_int_equal(fx->nrx, 0);   /* every entry invalid */
    /* sub n configures node n: an EMCY on 0x85 consumed by sub 9 is node 9's */
    assert_int_equal(net_write(&fx->od_b, 0x1028, 9, EMCY_ID, 4), 0);
    assert_int_equal(co_emcy_consumer_get_entry(&fx->cons, 9), EMCY_ID);
    raise_ok(fx, 0x2000);
    carry(fx);
    assert_int_equal(fx->nrx, 1);
    assert_int_equal(fx->rx_node[0], 9);
    assert_int_equal(fx->rx[0].code, 0x2000);
    /* 11-bit entry with bits 11..28: refused, nothing changes */
    assert_int_equal(net_write(&fx->od_b, 0x1028, 3, 0x00000885u, 4), CO_ABORT_INVALID_VALUE);
    assert_int_equal(co_emcy_consumer_get_entry(&fx->cons, 3), 0x80000000u);
    /* invalid again */
    assert_int_equal(net_write(&fx->od_b, 0x1028, 9, 0x80000000u | EMCY_ID, 4), 0);
    raise_ok(fx, 0x3000);
    carry(fx);
    assert_int_equal(fx->nrx, 1);
}

static void inject(fx_t *fx, uint32_t id, uint8_t flags, const uint8_t *data, uint8_t len)
{
    co_frame_t f = tu_frame(id, flags, data, len);
    assert_true(co_line_receive(fx->b, &f));
    (void)co_line_process(fx->b, fx->tb.now);
}

static void test_consumer_wrong_length_counted(void **state)
{
    fx_t *fx = *state;
    uint8_t data[64];
    uint8_t fl = tu_bus_flags(&fx->tb);
    memset(data, 0x5A, sizeof data);
    assert_true(co_emcy_consumer_watch(&fx->cons, NODE));
    if (!fd_bus(fx)) {
        inject(fx, EMCY_ID, 0, data, 7);
        inject(fx, EMCY_ID, 0, data, 0);
        inject(fx, EMCY_ID, 0, data, 8);
        assert_int_equal(fx->cons.stats.rx_bad_length, 2);
        assert_int_equal(fx->cons.stats.received, 1);
    } else {
        inject(fx, EMCY_ID, fl, data, 16);
        inject(fx, EMCY_ID, 0, data, 8);        /* classic frame on the fd line */
        inject(fx, EMCY_ID, fl, data, 20);
        inject(fx, EMCY_ID, fl, data, 64);      /* longer FD length: padding */
        assert_int_equal(fx->cons.stats.rx_bad_length, 2);
        assert_int_equal(fx->cons.stats.received, 2);
    }
    assert_int_equal(fx->nrx, fx->cons.stats.received);
    assert_int_equal(fx->rx[0].code, 0x5A5A);
    /* a remote frame on the id is not an EMCY: left to the line */
    {
        co_frame_t f = tu_frame(EMCY_ID, CO_FRAME_RTR, NULL, 0);
        assert_true(co_line_receive(fx->b, &f));
        (void)co_line_process(fx->b, fx->tb.now);
        assert_int_equal(fx->b->stats.rx_rtr, 1);
    }
}

static void test_consumer_random_frames(void **state)
{
    fx_t *fx = *state;
    uint64_t seed = 0xC0FFEEull;
    static const uint8_t fd_lens[] = {0, 1, 5, 8, 12, 16, 20, 24, 32, 48, 64};
    uint32_t on_ids = 0;
    assert_true(co_emcy_consumer_watch(&fx->cons, NODE));
    assert_true(co_emcy_consumer_watch(&fx->cons, 127));
    assert_true(co_emcy_consumer_set_entry(&fx->cons, 1, CO_EMCY_COB_ID_FRAME | 0x10000u));
    for (int i = 0; i < 10000; i++) {
        uint64_t r = tu_rand(&seed);
        co_frame_t f;
        uint32_t id;
        uint8_t flags = 0, len;
        switch (r & 3) {
        case 0: id = EMCY_ID; break;
        case 1: id = 0xFF; break;
        case 2: id = (uint32_t)(r >> 8) & 0x7FF; break;
        default: id = 0x10000; flags = CO_FRAME_EXT; break;
        }
        if (fd_bus(fx)) {
            flags |= tu_bus_flags(&fx->tb);
            len = fd_lens[(r >> 24) % sizeof fd_lens];
        } else {
            len = (uint8_t)((r >> 24) % 9);
            if (((r >> 40) & 15) == 0) {
                flags |= CO_FRAME_RTR;
            }
        }
        f = tu_frame(id, flags, NULL, len);
        for (uint8_t k = 0; k < len; k++)
            f.data[k] = (uint8_t)tu_rand(&seed);
        if (!(flags & CO_FRAME_RTR) && (id == EMCY_ID || id == 0xFF || (flags & CO_FRAME_EXT)))
            on_ids++;
        if (!co_line_receive(fx->b, &f))
            fail();
        (void)co_line_process(fx->b, (uint64_t)i);
    }
    /* every data frame on a consumed id was delivered or counted */
    assert_int_equal(fx->cons.stats.received + fx->cons.stats.rx_bad_length, on_ids);
    assert_int_equal(fx->nrx, fx->cons.stats.received);
    assert_true(fx->cons.stats.received > 100);
    assert_true(fx->cons.stats.rx_bad_length > 100);
}

/* ============================================================ runner */

#define BOTH(t) \
    {"classic: " #t, t, setup_classic, teardown, NULL}, \
    {"fd: " #t, t, setup_fd, teardown, NULL}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_classic_codec_exact_bytes),
        cmocka_unit_test(test_fd_codec_exact_bytes),
        cmocka_unit_test(test_fd_codec_round_trip_every_field),
        cmocka_unit_test(test_codec_register_bits),
        BOTH(test_init_refuses_bad_config),
        BOTH(test_raise_sends_exact_frame),
        BOTH(test_error_register_follows_active_errors),
        BOTH(test_repeated_raise),
        BOTH(test_bad_arguments),
        BOTH(test_active_table_full),
        BOTH(test_inhibit_time_delays_second_emcy),
        BOTH(test_inhibit_write_retimes_pending),
        BOTH(test_queue_overflow_drops_and_counts),
        BOTH(test_cob_id_invalid_sends_nothing),
        BOTH(test_29_bit_cob_id),
        BOTH(test_nmt_stopped_sends_nothing),
        BOTH(test_clear_all),
        BOTH(test_od_history_order_clear_abort),
        BOTH(test_od_history_length_is_the_od_s),
        BOTH(test_od_cob_id_and_inhibit_writes),
        {"fd: test_od_fd_active_list_and_history_domain", test_od_fd_active_list_and_history_domain,
         setup_fd, teardown, NULL},
        BOTH(test_od_attach_refuses_unsealed),
        BOTH(test_consumer_delivers_every_field),
        BOTH(test_consumer_from_od_entries),
        BOTH(test_consumer_wrong_length_counted),
        BOTH(test_consumer_random_frames),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
