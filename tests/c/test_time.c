/* TIME (co_time): the 6-byte TIME_OF_DAY codec against the worked example
 * of the research notes (§6.8), Unix conversions, and producer / consumer on
 * the in-process bus (classic and FD with BRS): m (index 0) injects frames,
 * p (index 1) produces from its OD, c (index 2) consumes. */
#include "test_od_util.h"

#include "co_cob_id.h"
#include "canopenfd/co_time.h"

#define MAX_EV 16384
/* 2024-01-01 12:34:56.789 UTC */
#define EXAMPLE_UNIX_US 1704112496789000ull
static const uint8_t example_bytes[6] = {0x95, 0x2C, 0xB3, 0x02, 0x12, 0x39};

typedef struct got {
    co_time_of_day_t tod;
    uint64_t t;
} got_t;

typedef struct od_fx {
    co_od_t od;
    co_od_entry_t entries[8];
    uint8_t pool[128];
    co_od_subscription_t subs[4];
} od_fx_t;

typedef struct fx {
    tu_bus_t tb;
    tu_line_t l[3];
    co_line_t *m, *p, *c;
    co_time_t tp, tc;
    od_fx_t odp;
    got_t got[MAX_EV];
    int ngot;
} fx_t;

static void on_time(co_time_t *t, const co_time_of_day_t *tod, void *user)
{
    fx_t *fx = user;
    assert_ptr_equal(t, &fx->tc);
    assert_true(fx->ngot < MAX_EV);
    fx->got[fx->ngot].tod = *tod;
    fx->got[fx->ngot].t = fx->tb.now;
    fx->ngot++;
}

static const tu_od_row_t time_rows[] = {
    { 0x1012, 0, VAR, U32, RW, 0, 4, 0x100, NULL, 0, 0 },
};

static int setup(void **state, co_mode_t mode, bool brs)
{
    fx_t *fx = calloc(1, sizeof *fx);
    if (fx == NULL)
        return -1;
    tu_bus_init(&fx->tb, mode, brs);
    fx->m = tu_bus_add_line(&fx->tb, &fx->l[0]);
    fx->p = tu_bus_add_line(&fx->tb, &fx->l[1]);
    fx->c = tu_bus_add_line(&fx->tb, &fx->l[2]);
    co_od_init(&fx->odp.od, mode, fx->odp.entries, 8, fx->odp.pool, sizeof fx->odp.pool,
               fx->odp.subs, 4);
    tu_od_add_rows(&fx->odp.od, time_rows, 1);
    assert_true(co_od_seal(&fx->odp.od, 3));
    assert_true(co_cob_id_attach(&fx->odp.od));
    co_time_init(&fx->tp, fx->p, NULL, NULL);
    assert_true(co_time_attach_od(&fx->tp, &fx->odp.od));
    co_time_init(&fx->tc, fx->c, on_time, fx);
    assert_true(co_time_set_cob_id(&fx->tc, 0x80000100u));
    co_time_set_nmt_state(&fx->tp, CO_NMT_PRE_OPERATIONAL);
    co_time_set_nmt_state(&fx->tc, CO_NMT_OPERATIONAL);
    *state = fx;
    return 0;
}

static int setup_classic(void **state) { return setup(state, CO_MODE_CLASSIC, false); }
static int setup_fd(void **state) { return setup(state, CO_MODE_FD, true); }

static int teardown(void **state)
{
    fx_t *fx = *state;
    co_time_deinit(&fx->tp);
    co_time_deinit(&fx->tc);
    free(fx);
    return 0;
}

static uint32_t od_write(fx_t *fx, uint32_t value)
{
    uint8_t scratch[8], b[4];
    co_od_xfer_t x;
    uint32_t r;
    tu_le_put(b, value, 4);
    co_od_xfer_init(&x, scratch, sizeof scratch);
    r = co_od_write_begin(&fx->odp.od, &x, 0x1012, 0, 4);
    if (r == 0)
        r = co_od_write_chunk(&x, b, 4);
    if (r == 0)
        r = co_od_write_end(&x);
    return r;
}

static void inject(fx_t *fx, uint32_t id, const uint8_t *data, uint8_t len)
{
    co_frame_t f = tu_frame(id, tu_bus_flags(&fx->tb), data, len);
    assert_true(co_line_send_raw(fx->m, &f));
    tu_step(&fx->tb, fx->tb.now);
}

/* ------------------------------------------------------------ codec */

static void test_example(void **state)
{
    co_time_of_day_t tod = {45296789u, 14610u}, back;
    uint8_t out[6];
    (void)state;
    assert_true(co_time_encode(&tod, out));
    assert_memory_equal(out, example_bytes, 6);
    assert_true(co_time_decode(example_bytes, 6, &back));
    assert_int_equal(back.ms, 45296789u);
    assert_int_equal(back.days, 14610u);
    assert_true(co_time_from_unix_us(EXAMPLE_UNIX_US, &back));
    assert_int_equal(back.ms, 45296789u);
    assert_int_equal(back.days, 14610u);
    assert_int_equal(co_time_to_unix_us(&tod), EXAMPLE_UNIX_US);
    /* sub-millisecond part is truncated */
    assert_true(co_time_from_unix_us(EXAMPLE_UNIX_US + 999, &back));
    assert_int_equal(back.ms, 45296789u);
}

static void test_codec_bounds(void **state)
{
    co_time_of_day_t tod, back;
    uint8_t out[6], in[8] = {0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0, 0};
    (void)state;
    tod = (co_time_of_day_t){CO_TIME_MS_PER_DAY - 1, 0xFFFF};
    assert_true(co_time_encode(&tod, out));
    assert_int_equal(out[3] & 0xF0, 0);
    assert_true(co_time_decode(out, 6, &back));
    assert_int_equal(back.ms, CO_TIME_MS_PER_DAY - 1);
    assert_int_equal(back.days, 0xFFFF);
    tod.ms = CO_TIME_MS_PER_DAY;
    assert_false(co_time_encode(&tod, out));
    /* decoder: exactly 6 bytes; the reserved nibble is ignored */
    assert_false(co_time_decode(in, 0, &back));
    assert_false(co_time_decode(in, 5, &back));
    assert_false(co_time_decode(in, 7, &back));
    assert_false(co_time_decode(in, 8, &back));
    assert_true(co_time_decode(in, 6, &back));
    assert_int_equal(back.ms, 0x0FFFFFFFu);
    assert_int_equal(back.days, 0xFFFF);
    /* the epoch, before it, the last day */
    assert_true(co_time_from_unix_us((uint64_t)CO_TIME_EPOCH_UNIX_S * 1000000u, &back));
    assert_int_equal(back.ms, 0);
    assert_int_equal(back.days, 0);
    assert_false(co_time_from_unix_us((uint64_t)CO_TIME_EPOCH_UNIX_S * 1000000u - 1, &back));
    assert_false(co_time_from_unix_us(0, &back));
    tod = (co_time_of_day_t){CO_TIME_MS_PER_DAY - 1, 0xFFFF};
    assert_true(co_time_from_unix_us(co_time_to_unix_us(&tod), &back));
    assert_int_equal(back.days, 0xFFFF);
    assert_false(co_time_from_unix_us(co_time_to_unix_us(&tod) + 1000, &back));
    assert_false(co_time_from_unix_us(UINT64_MAX, &back));
    /* 1984-01-01 is Unix day 5113 */
    assert_int_equal(CO_TIME_EPOCH_UNIX_S, 5113u * 86400u);
}

/* Random instants: from/to round-trips to the millisecond, encode/decode is
 * exact, decode of any 6 bytes never fails. */
static void test_codec_random(void **state)
{
    uint64_t rng = 0x1234567ull;
    int k;
    (void)state;
    for (k = 0; k < 10000; k++) {
        uint64_t r = tu_rand(&rng);
        uint64_t us = (uint64_t)CO_TIME_EPOCH_UNIX_S * 1000000u + r % (65536ull * 86400000000ull);
        co_time_of_day_t tod, back;
        uint8_t out[6];
        assert_true(co_time_from_unix_us(us, &tod));
        assert_int_equal(co_time_to_unix_us(&tod), us - us % 1000u);
        assert_true(co_time_encode(&tod, out));
        assert_true(co_time_decode(out, 6, &back));
        assert_int_equal(back.ms, tod.ms);
        assert_int_equal(back.days, tod.days);
        memcpy(out, &r, 6);
        assert_true(co_time_decode(out, 6, &back));
        assert_true(back.ms <= 0x0FFFFFFFu);
    }
}

/* ------------------------------------------------------------ service */

/* Producer: exact bytes on 0x100 with the bus's flags; the consumer gets the
 * decoded value. */
static void test_produce_consume(void **state)
{
    fx_t *fx = *state;
    co_time_of_day_t tod = {45296789u, 14610u};
    long i;
    assert_false(co_time_send(&fx->tp, &tod));          /* 0x1012 bit 30 clear */
    assert_int_equal(fx->tp.stats.send_refused, 1);
    assert_int_equal(od_write(fx, 0x40000100u), 0);
    assert_true(co_time_send(&fx->tp, &tod));
    tu_step(&fx->tb, 1000);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x100), 1);
    i = tu_log_find_id(&fx->tb, 0x100, 0);
    tu_assert_logged(&fx->tb, i, 0x100, example_bytes, 6);
    assert_int_equal(fx->ngot, 1);
    assert_int_equal(fx->got[0].tod.ms, 45296789u);
    assert_int_equal(fx->got[0].tod.days, 14610u);
    assert_int_equal(fx->got[0].t, 1000);
    assert_true(co_time_send_unix_us(&fx->tp, EXAMPLE_UNIX_US + 1000));
    tu_step(&fx->tb, 2000);
    assert_int_equal(fx->ngot, 2);
    assert_int_equal(fx->got[1].tod.ms, 45296790u);
    assert_int_equal(fx->tp.stats.produced, 2);
    assert_int_equal(fx->tc.stats.received, 2);
    /* times that do not encode */
    tod.ms = CO_TIME_MS_PER_DAY;
    assert_false(co_time_send(&fx->tp, &tod));
    assert_false(co_time_send_unix_us(&fx->tp, 1000));
    assert_int_equal(fx->tp.stats.send_refused, 3);
    tu_step(&fx->tb, 3000);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x100), 2);
}

/* NMT stopped: nothing produced, nothing consumed (counted). */
static void test_nmt_stopped(void **state)
{
    fx_t *fx = *state;
    co_time_of_day_t tod = {1, 2};
    assert_int_equal(od_write(fx, 0x40000100u), 0);
    co_time_set_nmt_state(&fx->tp, CO_NMT_STOPPED);
    assert_false(co_time_send(&fx->tp, &tod));
    co_time_set_nmt_state(&fx->tp, CO_NMT_INITIALISING);
    assert_false(co_time_send(&fx->tp, &tod));
    tu_step(&fx->tb, 1000);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x100), 0);
    assert_int_equal(fx->tp.stats.send_refused, 2);
    co_time_set_nmt_state(&fx->tp, CO_NMT_OPERATIONAL);
    co_time_set_nmt_state(&fx->tc, CO_NMT_STOPPED);
    assert_true(co_time_send(&fx->tp, &tod));
    tu_step(&fx->tb, 2000);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x100), 1);
    assert_int_equal(fx->ngot, 0);
    assert_int_equal(fx->tc.stats.ignored_state, 1);
    co_time_set_nmt_state(&fx->tc, CO_NMT_PRE_OPERATIONAL);
    assert_true(co_time_send(&fx->tp, &tod));
    tu_step(&fx->tb, 3000);
    assert_int_equal(fx->ngot, 1);
}

/* Wrong lengths ignored and counted; reserved bits of a received frame
 * ignored. */
static void test_consumer_malformed(void **state)
{
    fx_t *fx = *state;
    uint8_t d[12];
    memcpy(d, example_bytes, 6);
    memset(d + 6, 0, 6);
    inject(fx, 0x100, d, 5);
    inject(fx, 0x100, d, 7);
    inject(fx, 0x100, d, 8);
    inject(fx, 0x100, d, 0);
    if (fx->tb.mode == CO_MODE_FD)
        inject(fx, 0x100, d, 12);
    assert_int_equal(fx->ngot, 0);
    assert_int_equal(fx->tc.stats.bad_length, fx->tb.mode == CO_MODE_FD ? 5 : 4);
    d[3] = 0xF2;                                        /* reserved nibble set */
    inject(fx, 0x100, d, 6);
    assert_int_equal(fx->ngot, 1);
    assert_int_equal(fx->got[0].tod.ms, 45296789u);
    assert_int_equal(fx->got[0].tod.days, 14610u);
    /* a remote frame on the TIME id is not a time stamp */
    {
        co_frame_t f = tu_frame(0x100, CO_FRAME_RTR, NULL, 6);
        uint32_t rtr = fx->c->stats.rx_rtr;
        assert_true(co_line_send_raw(fx->m, &f));
        tu_step(&fx->tb, fx->tb.now);
        assert_int_equal(fx->c->stats.rx_rtr, rtr + 1);
        assert_int_equal(fx->ngot, 1);
    }
}

/* 0x1012 writes: unsupported / restricted ids refused, the CAN-ID fixed
 * while active (co_cob_id), the consumer follows the id at once. */
static void test_od_writes(void **state)
{
    fx_t *fx = *state;
    uint32_t v = 0;
    assert_int_equal(od_write(fx, 0x20000100u), CO_ABORT_INVALID_VALUE);
    assert_int_equal(od_write(fx, 0x00000900u), CO_ABORT_INVALID_VALUE);
    assert_int_equal(od_write(fx, 0x120), CO_ABORT_INVALID_VALUE);
    assert_int_equal(od_write(fx, 0x80000701u), CO_ABORT_INVALID_VALUE);
    assert_true(co_od_get_u32(&fx->odp.od, 0x1012, 0, &v));
    assert_int_equal(v, 0x100);
    assert_int_equal(od_write(fx, 0x80000100u), 0);
    assert_true(fx->tp.subscribed);
    assert_int_equal(od_write(fx, 0x80000190u), CO_ABORT_INVALID_VALUE);   /* active */
    assert_int_equal(od_write(fx, 0x00000190u), 0);     /* off and new id in one step */
    assert_false(fx->tp.subscribed);
    assert_int_equal(od_write(fx, 0xC0000190u), 0);     /* consume and produce */
    assert_true(fx->tp.subscribed);
    assert_int_equal(fx->tp.rx_id, 0x190);
    assert_int_equal(co_time_check_cob_id(0x190), 0);
    assert_int_equal(co_time_check_cob_id(0x80000180u), CO_ABORT_INVALID_VALUE);
    /* the producer sends on the new id */
    {
        co_time_of_day_t tod = {45296789u, 14610u};
        assert_true(co_time_send(&fx->tp, &tod));
        tu_step(&fx->tb, 1000);
        tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, 0x190, 0), 0x190, example_bytes, 6);
    }
    /* the consumer without OD: a new id at once */
    assert_true(co_time_set_cob_id(&fx->tc, 0x80000190u));
    inject(fx, 0x190, example_bytes, 6);
    assert_int_equal(fx->ngot, 1);
    inject(fx, 0x100, example_bytes, 6);
    assert_int_equal(fx->ngot, 1);
    assert_int_equal(fx->tp.stats.received, 1);         /* p consumes 0x190 too */
    /* an id someone else holds: refused, counted */
    co_time_deinit(&fx->tc);
    co_time_init(&fx->tc, fx->p, on_time, fx);
    assert_false(co_time_set_cob_id(&fx->tc, 0x80000190u));
    assert_int_equal(fx->tc.stats.subscribe_failed, 1);
    /* a reload of the defaults applies (reset communication) */
    co_od_load_defaults(&fx->odp.od, CO_GROUP_COMMUNICATION);
    assert_false(fx->tp.subscribed);
    assert_int_equal(fx->tp.cob_id, 0x100);
}

/* 10 000 random frames at the consumer: never a crash, every frame on the
 * TIME id accounted for once. */
static void test_random_frames(void **state)
{
    fx_t *fx = *state;
    uint64_t rng = 0xABCDEFull;
    uint32_t on_id = 0;
    int k;
    for (k = 0; k < 10000; k++) {
        uint64_t r = tu_rand(&rng);
        co_frame_t f;
        memset(&f, 0, sizeof f);
        f.id = 0xFE + (uint32_t)(r % 5);
        f.len = (uint8_t)((r >> 8) % 10);
        if ((r >> 60) == 0)
            f.flags = (uint8_t)((r >> 16) & (CO_FRAME_RTR | CO_FRAME_EXT | CO_FRAME_FD));
        else if (fx->tb.mode == CO_MODE_FD && (r >> 59) & 1)
            f.flags = CO_FRAME_FD | CO_FRAME_BRS;
        if ((f.flags & CO_FRAME_FD) && (r >> 58) & 1)
            f.len = co_fd_len_round((size_t)((r >> 24) % 65));
        memcpy(f.data, &r, sizeof r);
        if ((r >> 36) % 89 == 0)
            co_time_set_nmt_state(&fx->tc, (r >> 44) & 1 ? CO_NMT_STOPPED : CO_NMT_OPERATIONAL);
        if (co_frame_is_valid(&f) && !(f.flags & (CO_FRAME_RTR | CO_FRAME_EXT)) &&
            f.id == 0x100 && !(fx->tb.mode == CO_MODE_CLASSIC && (f.flags & CO_FRAME_FD)))
            on_id++;
        co_line_receive(fx->c, &f);
        co_line_process(fx->c, (uint64_t)k * 10);
    }
    assert_true(on_id > 1000);
    assert_true(fx->tc.stats.received > 50);
    assert_int_equal(fx->tc.stats.received + fx->tc.stats.bad_length +
                         fx->tc.stats.ignored_state, on_id);
    assert_int_equal((uint32_t)fx->ngot, fx->tc.stats.received);
    for (k = 0; k < fx->ngot; k++)
        assert_true(fx->got[k].tod.ms <= 0x0FFFFFFFu);
}

#define BOTH(t) cmocka_unit_test_setup_teardown(t, setup_classic, teardown), \
                cmocka_unit_test_setup_teardown(t, setup_fd, teardown)

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_example),
        cmocka_unit_test(test_codec_bounds),
        cmocka_unit_test(test_codec_random),
        BOTH(test_produce_consume),
        BOTH(test_nmt_stopped),
        BOTH(test_consumer_malformed),
        BOTH(test_od_writes),
        BOTH(test_random_frames),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
