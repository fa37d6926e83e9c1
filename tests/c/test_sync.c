/* SYNC producer and consumer (co_sync) on three lines of the in-process bus
 * with a fake clock: m (index 0) injects frames, p (index 1) produces SYNC
 * from its OD, c (index 2) consumes. Bus tests run on a classic bus and on
 * an FD bus with bit-rate switch; the sniffer checks every frame's CAN-ID,
 * flags, length and bytes and the time it was carried at. */
#include "test_od_util.h"

#include "co_cob_id.h"
#include "canopenfd/co_sync.h"

#define MS(x) ((uint64_t)(x) * TU_MS)
#define MAX_EV 16384

enum { EV_SYNC = 1, EV_WINDOW, EV_ERROR };

typedef struct ev {
    int kind;
    int who;                  /* 'p' or 'c' */
    unsigned value;           /* counter, EMCY code */
    unsigned length;          /* EV_ERROR: received length */
    uint64_t t;
} ev_t;

typedef struct od_fx {
    co_od_t od;
    co_od_entry_t entries[16];
    uint8_t pool[256];
    co_od_subscription_t subs[8];
} od_fx_t;

typedef struct fx {
    tu_bus_t tb;
    tu_line_t l[3];
    co_line_t *m, *p, *c;
    co_sync_t sp, sc;
    od_fx_t odp;
    ev_t ev[MAX_EV];
    int nev;
    int listener_calls;       /* counted by the flood listener */
} fx_t;

/* Who a callback's user pointer is: the fixture with a tag. */
typedef struct tag {
    fx_t *fx;
    int who;
} tag_t;

static tag_t tag_p, tag_c;

/* ------------------------------------------------------------ recording */

static void add_ev(fx_t *fx, int kind, int who, unsigned value, unsigned length)
{
    assert_true(fx->nev < MAX_EV);
    fx->ev[fx->nev] = (ev_t){kind, who, value, length, fx->tb.now};
    fx->nev++;
}

static int count_ev(const fx_t *fx, int kind, int who)
{
    int i, n = 0;
    for (i = 0; i < fx->nev; i++)
        if (fx->ev[i].kind == kind && fx->ev[i].who == who)
            n++;
    return n;
}

/* k-th (0-based) event of a kind from who, NULL if none. */
static const ev_t *nth_ev(const fx_t *fx, int kind, int who, int k)
{
    int i;
    for (i = 0; i < fx->nev; i++)
        if (fx->ev[i].kind == kind && fx->ev[i].who == who && k-- == 0)
            return &fx->ev[i];
    return NULL;
}

static void on_sync(uint8_t counter, void *user)
{
    tag_t *t = user;
    add_ev(t->fx, EV_SYNC, t->who, counter, 0);
}

static void on_window(co_sync_t *s, void *user)
{
    tag_t *t = user;
    assert_ptr_equal(s, t->who == 'p' ? &t->fx->sp : &t->fx->sc);
    add_ev(t->fx, EV_WINDOW, t->who, 0, 0);
}

static void on_error(co_sync_t *s, uint16_t code, uint8_t length, void *user)
{
    tag_t *t = user;
    assert_ptr_equal(s, t->who == 'p' ? &t->fx->sp : &t->fx->sc);
    add_ev(t->fx, EV_ERROR, t->who, code, length);
}

/* ------------------------------------------------------------ fixture */

static const tu_od_row_t sync_rows[] = {
    { 0x1005, 0, VAR, U32, RW, 0, 4, 0x80, NULL, 0, 0 },
    { 0x1006, 0, VAR, U32, RW, 0, 4, 0, NULL, 0, 0 },
    { 0x1007, 0, VAR, U32, RW, 0, 4, 0, NULL, 0, 0 },
    { 0x1017, 0, VAR, U16, RW, 0, 2, 0, NULL, 0, 0 },    /* in between: not SYNC's */
    { 0x1019, 0, VAR, U8, RW, 0, 1, 0, NULL, 0, 0 },
};

static void build_od(od_fx_t *o, co_mode_t mode)
{
    co_od_init(&o->od, mode, o->entries, 16, o->pool, sizeof o->pool, o->subs, 8);
    tu_od_add_rows(&o->od, sync_rows, sizeof sync_rows / sizeof sync_rows[0]);
    assert_true(co_od_seal(&o->od, 3));
    assert_true(co_cob_id_attach(&o->od));   /* what co_node hooks */
}

static int setup(void **state, co_mode_t mode, bool brs)
{
    fx_t *fx = calloc(1, sizeof *fx);
    if (fx == NULL)
        return -1;
    tu_bus_init(&fx->tb, mode, brs);
    fx->m = tu_bus_add_line(&fx->tb, &fx->l[0]);
    fx->p = tu_bus_add_line(&fx->tb, &fx->l[1]);
    fx->c = tu_bus_add_line(&fx->tb, &fx->l[2]);
    tag_p = (tag_t){fx, 'p'};
    tag_c = (tag_t){fx, 'c'};
    build_od(&fx->odp, mode);
    assert_true(co_sync_init(&fx->sp, fx->p));
    assert_true(co_sync_attach_od(&fx->sp, &fx->odp.od));
    assert_true(co_sync_init(&fx->sc, fx->c));
    assert_true(co_sync_add_listener(&fx->sp, on_sync, &tag_p));
    assert_true(co_sync_add_listener(&fx->sc, on_sync, &tag_c));
    co_sync_set_window_indication(&fx->sp, on_window, &tag_p);
    co_sync_set_window_indication(&fx->sc, on_window, &tag_c);
    co_sync_set_error_indication(&fx->sp, on_error, &tag_p);
    co_sync_set_error_indication(&fx->sc, on_error, &tag_c);
    co_sync_set_nmt_state(&fx->sp, CO_NMT_PRE_OPERATIONAL);
    co_sync_set_nmt_state(&fx->sc, CO_NMT_PRE_OPERATIONAL);
    *state = fx;
    return 0;
}

static int setup_classic(void **state) { return setup(state, CO_MODE_CLASSIC, false); }
static int setup_fd(void **state) { return setup(state, CO_MODE_FD, true); }

static int teardown(void **state)
{
    fx_t *fx = *state;
    co_sync_deinit(&fx->sp);
    co_sync_deinit(&fx->sc);
    free(fx);
    return 0;
}

/* ------------------------------------------------------------ helpers */

static void run_until(fx_t *fx, uint64_t t) { tu_run_until(&fx->tb, t); }

/* A network write to the producer's OD, as an SDO server does it. */
static uint32_t od_write(fx_t *fx, uint16_t index, uint32_t value, uint32_t size)
{
    uint8_t scratch[8], b[4];
    co_od_xfer_t x;
    uint32_t r;
    co_line_set_time(fx->p, fx->tb.now);
    tu_le_put(b, value, size);
    co_od_xfer_init(&x, scratch, sizeof scratch);
    r = co_od_write_begin(&fx->odp.od, &x, index, 0, size);
    if (r == 0)
        r = co_od_write_chunk(&x, b, size);
    if (r == 0)
        r = co_od_write_end(&x);
    return r;
}

static uint32_t od_u32(fx_t *fx, uint16_t index)
{
    uint32_t v = 0xDEADBEEF;
    uint8_t v8;
    if (index == 0x1019) {
        assert_true(co_od_get_u8(&fx->odp.od, index, 0, &v8));
        return v8;
    }
    assert_true(co_od_get_u32(&fx->odp.od, index, 0, &v));
    return v;
}

static void consumer_config(fx_t *fx, uint32_t cob_id, uint32_t window_us, uint8_t overflow)
{
    co_sync_config_t c = {cob_id, 0, window_us, overflow};
    co_line_set_time(fx->c, fx->tb.now);
    co_sync_configure(&fx->sc, &c);
}

/* Producer on 0x80 every period_us with this counter overflow value. */
static void start_producer(fx_t *fx, uint32_t period_us, uint8_t overflow)
{
    assert_int_equal(od_write(fx, 0x1019, overflow, 1), 0);
    assert_int_equal(od_write(fx, 0x1005, 0x40000080u, 4), 0);
    assert_int_equal(od_write(fx, 0x1006, period_us, 4), 0);
}

/* A frame from line m, at the current time, exactly as given (an FD bus
 * gets FD frames). */
static void inject(fx_t *fx, uint32_t id, const uint8_t *data, uint8_t len)
{
    co_frame_t f = tu_frame(id, tu_bus_flags(&fx->tb), data, len);
    assert_true(co_line_send_raw(fx->m, &f));
    tu_step(&fx->tb, fx->tb.now);
}

/* ------------------------------------------------------------ tests */

/* Producer without counter: 0-byte SYNCs on 0x80 exactly every period, its
 * own listener told at the same moments (CAN does not echo), the consumer
 * too, with counter 0. */
static void test_producer_period(void **state)
{
    fx_t *fx = *state;
    int k;
    start_producer(fx, 10000, 0);
    run_until(fx, MS(55));
    assert_int_equal(tu_log_count_id(&fx->tb, 0x80), 5);
    for (k = 0; k < 5; k++) {
        long i = tu_log_find_id(&fx->tb, 0x80, (size_t)k);
        tu_assert_logged(&fx->tb, i, 0x80, NULL, 0);
        assert_int_equal(fx->tb.log[i].t_us, MS(10) * (uint64_t)(k + 1));
        assert_int_equal(nth_ev(fx, EV_SYNC, 'p', k)->t, MS(10) * (uint64_t)(k + 1));
        assert_int_equal(nth_ev(fx, EV_SYNC, 'p', k)->value, 0);
        assert_int_equal(nth_ev(fx, EV_SYNC, 'c', k)->t, MS(10) * (uint64_t)(k + 1));
        assert_int_equal(nth_ev(fx, EV_SYNC, 'c', k)->value, 0);
    }
    assert_int_equal(count_ev(fx, EV_SYNC, 'p'), 5);
    assert_int_equal(count_ev(fx, EV_SYNC, 'c'), 5);
    assert_int_equal(fx->sp.stats.produced, 5);
    assert_int_equal(fx->sc.stats.received, 5);
    assert_int_equal(fx->sc.stats.bad_length, 0);
    assert_false(fx->sp.subscribed);   /* a producer does not consume */
}

/* Counter 1..overflow then 1 again, on the bus and at the consumer. */
static void test_counter_wrap(void **state)
{
    fx_t *fx = *state;
    static const uint8_t expect[] = {1, 2, 3, 1, 2, 3, 1};
    size_t k;
    start_producer(fx, 1000, 3);
    consumer_config(fx, 0x80, 0, 3);
    run_until(fx, 7000);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x80), 7);
    for (k = 0; k < 7; k++) {
        long i = tu_log_find_id(&fx->tb, 0x80, k);
        tu_assert_logged(&fx->tb, i, 0x80, &expect[k], 1);
        assert_int_equal(nth_ev(fx, EV_SYNC, 'p', (int)k)->value, expect[k]);
        assert_int_equal(nth_ev(fx, EV_SYNC, 'c', (int)k)->value, expect[k]);
    }
    assert_int_equal(fx->sc.last_counter, 1);
}

/* The largest overflow value 240 wraps after 240. */
static void test_counter_wrap_240(void **state)
{
    fx_t *fx = *state;
    start_producer(fx, 100, 240);
    run_until(fx, 100 * 242);
    assert_int_equal(count_ev(fx, EV_SYNC, 'p'), 242);
    assert_int_equal(nth_ev(fx, EV_SYNC, 'p', 0)->value, 1);
    assert_int_equal(nth_ev(fx, EV_SYNC, 'p', 239)->value, 240);
    assert_int_equal(nth_ev(fx, EV_SYNC, 'p', 240)->value, 1);
    assert_int_equal(nth_ev(fx, EV_SYNC, 'p', 241)->value, 2);
}

/* Network writes: reserved counter values, 0x1019 while 0x1006 != 0,
 * unsupported and restricted COB-IDs, the CAN-ID rule while producing;
 * nothing changes on a refusal. */
static void test_od_aborts(void **state)
{
    fx_t *fx = *state;
    assert_int_equal(od_write(fx, 0x1019, 1, 1), CO_ABORT_INVALID_VALUE);
    assert_int_equal(od_write(fx, 0x1019, 241, 1), CO_ABORT_INVALID_VALUE);
    assert_int_equal(od_write(fx, 0x1019, 255, 1), CO_ABORT_INVALID_VALUE);
    assert_int_equal(od_u32(fx, 0x1019), 0);
    assert_int_equal(od_write(fx, 0x1019, 2, 1), 0);
    assert_int_equal(od_write(fx, 0x1019, 240, 1), 0);
    assert_int_equal(od_write(fx, 0x1019, 0, 1), 0);
    assert_int_equal(od_write(fx, 0x1006, 1000, 4), 0);
    assert_int_equal(od_write(fx, 0x1019, 5, 1), CO_ABORT_DATA_STATE);
    assert_int_equal(od_write(fx, 0x1019, 0, 1), 0);          /* unchanged: fine */
    assert_int_equal(od_write(fx, 0x1019, 241, 1), CO_ABORT_INVALID_VALUE);
    assert_int_equal(od_u32(fx, 0x1019), 0);
    /* COB-ID: 29-bit frame bit, high id bits, restricted CAN-IDs */
    assert_int_equal(od_write(fx, 0x1005, 0x20000080u, 4), CO_ABORT_INVALID_VALUE);
    assert_int_equal(od_write(fx, 0x1005, 0x00000880u, 4), CO_ABORT_INVALID_VALUE);
    assert_int_equal(od_write(fx, 0x1005, 0x701, 4), CO_ABORT_INVALID_VALUE);
    assert_int_equal(od_write(fx, 0x1005, 0x7F, 4), CO_ABORT_INVALID_VALUE);
    assert_int_equal(od_write(fx, 0x1005, 0x601, 4), CO_ABORT_INVALID_VALUE);
    assert_int_equal(od_u32(fx, 0x1005), 0x80);
    assert_int_equal(od_write(fx, 0x1005, 0x80000090u, 4), 0);   /* bit 31: do not care */
    assert_int_equal(od_write(fx, 0x1005, 0x40000090u, 4), 0);
    /* producing: the CAN-ID is fixed (co_cob_id) */
    assert_int_equal(od_write(fx, 0x1005, 0x40000091u, 4), CO_ABORT_INVALID_VALUE);
    assert_int_equal(od_u32(fx, 0x1005), 0x40000090u);
    /* the entry in between is not SYNC's business */
    assert_int_equal(od_write(fx, 0x1017, 100, 2), 0);
    /* the pure check agrees */
    assert_int_equal(co_sync_check(&fx->sp, 0x1019, 7), CO_ABORT_DATA_STATE);
    assert_int_equal(co_sync_check(&fx->sp, 0x1005, 0x1A0), 0);
    assert_int_equal(co_sync_check(&fx->sp, 0x1005, 0x180), CO_ABORT_INVALID_VALUE);
    assert_int_equal(co_sync_check(&fx->sp, 0x1006, 0xFFFFFFFFu), 0);
}

/* A new period restarts production at once: counter 1, first SYNC one new
 * period after the write. 0x1019 only while the period is 0. */
static void test_restart_on_change(void **state)
{
    fx_t *fx = *state;
    static const uint8_t one = 1, two = 2, five = 5;
    long i;
    start_producer(fx, 10000, 4);
    run_until(fx, MS(35));                       /* counters 1 2 3 */
    assert_int_equal(od_write(fx, 0x1006, 4000, 4), 0);
    run_until(fx, MS(43));
    /* after the write at 35 ms: 39 ms counter 1, 43 ms counter 2 */
    assert_int_equal(tu_log_count_id(&fx->tb, 0x80), 5);
    i = tu_log_find_id(&fx->tb, 0x80, 3);
    tu_assert_logged(&fx->tb, i, 0x80, &one, 1);
    assert_int_equal(fx->tb.log[i].t_us, MS(39));
    i = tu_log_find_id(&fx->tb, 0x80, 4);
    tu_assert_logged(&fx->tb, i, 0x80, &two, 1);
    assert_int_equal(fx->tb.log[i].t_us, MS(43));
    /* period 0: production stops; then the counter may change */
    assert_int_equal(od_write(fx, 0x1006, 0, 4), 0);
    run_until(fx, MS(100));
    assert_int_equal(tu_log_count_id(&fx->tb, 0x80), 5);
    assert_int_equal(od_write(fx, 0x1019, 5, 1), 0);
    assert_int_equal(od_write(fx, 0x1006, 2000, 4), 0);
    run_until(fx, MS(110));
    assert_int_equal(tu_log_count_id(&fx->tb, 0x80), 10);
    i = tu_log_find_id(&fx->tb, 0x80, 5);
    tu_assert_logged(&fx->tb, i, 0x80, &one, 1);
    assert_int_equal(fx->tb.log[i].t_us, MS(102));
    i = tu_log_find_id(&fx->tb, 0x80, 9);
    tu_assert_logged(&fx->tb, i, 0x80, &five, 1);
    /* producer bit off: no more SYNC, the node consumes again */
    assert_int_equal(od_write(fx, 0x1005, 0x80, 4), 0);
    assert_true(fx->sp.subscribed);
    run_until(fx, MS(130));
    assert_int_equal(tu_log_count_id(&fx->tb, 0x80), 10);
    /* on again: counter 1 one period later */
    assert_int_equal(od_write(fx, 0x1005, 0x40000080u, 4), 0);
    run_until(fx, MS(132));
    i = tu_log_find_id(&fx->tb, 0x80, 10);
    tu_assert_logged(&fx->tb, i, 0x80, &one, 1);
    assert_int_equal(fx->tb.log[i].t_us, MS(132));
}

/* A reload of the OD (reset communication loading defaults) applies too. */
static void test_reload_applies(void **state)
{
    fx_t *fx = *state;
    start_producer(fx, 1000, 0);
    run_until(fx, 3500);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x80), 3);
    co_od_load_defaults(&fx->odp.od, CO_GROUP_COMMUNICATION);
    assert_false(co_sync_is_producer(&fx->sp));
    run_until(fx, 10000);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x80), 3);
}

/* The consumer follows a new COB-ID at once; the old id is free again. */
static void test_consumer_resubscribes(void **state)
{
    fx_t *fx = *state;
    uint32_t unhandled;
    consumer_config(fx, 0x90, 0, 0);
    unhandled = fx->c->stats.rx_unhandled;
    inject(fx, 0x80, NULL, 0);
    assert_int_equal(count_ev(fx, EV_SYNC, 'c'), 0);
    assert_int_equal(fx->c->stats.rx_unhandled, unhandled + 1);
    inject(fx, 0x90, NULL, 0);
    assert_int_equal(count_ev(fx, EV_SYNC, 'c'), 1);
    /* the producer's consumer side follows its OD the same way */
    assert_int_equal(od_write(fx, 0x1005, 0x95, 4), 0);
    assert_int_equal(fx->sp.rx_id, 0x95);
    inject(fx, 0x95, NULL, 0);
    assert_int_equal(count_ev(fx, EV_SYNC, 'p'), 2);          /* 0x80 before, 0x95 now */
    assert_int_equal(fx->sp.stats.received, 2);
    inject(fx, 0x80, NULL, 0);
    assert_int_equal(fx->sp.stats.received, 2);
}

/* Wrong lengths: ignored, counted, reported with 0x8240 and the length. */
static void test_wrong_length(void **state)
{
    fx_t *fx = *state;
    static const uint8_t d[8] = {7, 1, 2, 3, 4, 5, 6, 7};
    const ev_t *e;
    inject(fx, 0x80, d, 1);                      /* counter byte, none expected */
    assert_int_equal(count_ev(fx, EV_SYNC, 'c'), 0);
    assert_int_equal(fx->sc.stats.bad_length, 1);
    e = nth_ev(fx, EV_ERROR, 'c', 0);
    assert_non_null(e);
    assert_int_equal(e->value, 0x8240);
    assert_int_equal(e->length, 1);
    consumer_config(fx, 0x80, 0, 10);
    inject(fx, 0x80, NULL, 0);                   /* counter missing */
    inject(fx, 0x80, d, 2);
    inject(fx, 0x80, d, 8);
    assert_int_equal(fx->sc.stats.bad_length, 4);
    assert_int_equal(count_ev(fx, EV_ERROR, 'c'), 4);
    assert_int_equal(nth_ev(fx, EV_ERROR, 'c', 1)->length, 0);
    assert_int_equal(nth_ev(fx, EV_ERROR, 'c', 3)->length, 8);
    assert_int_equal(count_ev(fx, EV_SYNC, 'c'), 0);
    inject(fx, 0x80, d, 1);
    assert_int_equal(count_ev(fx, EV_SYNC, 'c'), 1);
    assert_int_equal(nth_ev(fx, EV_SYNC, 'c', 0)->value, 7);
    assert_int_equal(fx->sc.stats.received, 1);
    /* remote frames on the SYNC id are not SYNCs */
    {
        co_frame_t f = tu_frame(0x80, CO_FRAME_RTR, NULL, 1);
        assert_true(co_line_send_raw(fx->m, &f));
        tu_step(&fx->tb, fx->tb.now);
        assert_int_equal(fx->sc.stats.received + fx->sc.stats.bad_length, 5);
    }
}

/* A tool's consumer (co_sync_accept_any_counter) takes SYNC with and
 * without the counter; longer frames stay errors; switched off, the 0x1019
 * rule is back. */
static void test_accept_any_counter(void **state)
{
    fx_t *fx = *state;
    static const uint8_t d[8] = {9, 1, 2, 3, 4, 5, 6, 7};
    co_sync_accept_any_counter(&fx->sc, true);
    inject(fx, 0x80, NULL, 0);
    inject(fx, 0x80, d, 1);
    inject(fx, 0x80, d, 2);
    assert_int_equal(count_ev(fx, EV_SYNC, 'c'), 2);
    assert_int_equal(nth_ev(fx, EV_SYNC, 'c', 0)->value, 0);
    assert_int_equal(nth_ev(fx, EV_SYNC, 'c', 1)->value, 9);
    assert_int_equal(fx->sc.stats.bad_length, 1);
    co_sync_accept_any_counter(&fx->sc, false);
    inject(fx, 0x80, d, 1);                      /* 0x1019 = 0: no counter expected */
    assert_int_equal(count_ev(fx, EV_SYNC, 'c'), 2);
    assert_int_equal(fx->sc.stats.bad_length, 2);
}

/* The window indication 0x1007 µs after each SYNC, produced and received;
 * window_check true before, false (counted) after. */
static void test_window(void **state)
{
    fx_t *fx = *state;
    assert_int_equal(od_write(fx, 0x1007, 3000, 4), 0);
    consumer_config(fx, 0x80, 2500, 0);
    assert_false(co_sync_window_check(&fx->sc));  /* no SYNC yet */
    start_producer(fx, 10000, 0);
    run_until(fx, MS(10) + 2499);
    assert_true(co_sync_window_check(&fx->sp));
    assert_true(co_sync_window_check(&fx->sc));
    assert_int_equal(count_ev(fx, EV_WINDOW, 'c'), 0);
    run_until(fx, MS(10) + 2500);
    assert_int_equal(count_ev(fx, EV_WINDOW, 'c'), 1);
    assert_int_equal(nth_ev(fx, EV_WINDOW, 'c', 0)->t, MS(10) + 2500);
    assert_false(co_sync_window_check(&fx->sc));
    assert_true(co_sync_window_check(&fx->sp));
    run_until(fx, MS(10) + 2999);
    assert_int_equal(count_ev(fx, EV_WINDOW, 'p'), 0);
    run_until(fx, MS(13));
    assert_int_equal(count_ev(fx, EV_WINDOW, 'p'), 1);
    assert_int_equal(nth_ev(fx, EV_WINDOW, 'p', 0)->t, MS(13));
    assert_false(co_sync_window_check(&fx->sp));
    assert_int_equal(fx->sp.stats.outside_window, 1);
    assert_int_equal(fx->sc.stats.outside_window, 2);
    run_until(fx, MS(50));
    assert_int_equal(count_ev(fx, EV_WINDOW, 'p'), 4);        /* 13 23 33 43 */
    assert_int_equal(nth_ev(fx, EV_WINDOW, 'p', 3)->t, MS(43));
    /* window 0: always inside, the open one ends without indication */
    assert_int_equal(od_write(fx, 0x1007, 0, 4), 0);
    run_until(fx, MS(80));
    assert_int_equal(count_ev(fx, EV_WINDOW, 'p'), 4);
    assert_true(co_sync_window_check(&fx->sp));
}

/* A shorter window written while one is open closes it at the new end; a
 * write after that end closes it at once. */
static void test_window_change_while_open(void **state)
{
    fx_t *fx = *state;
    assert_int_equal(od_write(fx, 0x1007, 5000, 4), 0);
    start_producer(fx, 10000, 0);
    run_until(fx, MS(11));
    assert_int_equal(od_write(fx, 0x1007, 3000, 4), 0);
    run_until(fx, MS(13));
    assert_int_equal(count_ev(fx, EV_WINDOW, 'p'), 1);
    assert_int_equal(nth_ev(fx, EV_WINDOW, 'p', 0)->t, MS(13));
    run_until(fx, MS(21));
    assert_int_equal(od_write(fx, 0x1007, 500, 4), 0);
    run_until(fx, MS(21));
    assert_int_equal(count_ev(fx, EV_WINDOW, 'p'), 2);
    assert_int_equal(nth_ev(fx, EV_WINDOW, 'p', 1)->t, MS(21));
}

/* NMT: nothing produced or consumed in stopped or before boot; back to
 * pre-operational the counter starts at 1 one period later. */
static void test_nmt_states(void **state)
{
    fx_t *fx = *state;
    static const uint8_t one = 1;
    long i;
    start_producer(fx, 1000, 5);
    consumer_config(fx, 0x80, 0, 5);
    run_until(fx, 3000);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x80), 3);
    co_sync_set_nmt_state(&fx->sp, CO_NMT_OPERATIONAL);   /* no restart */
    run_until(fx, 4000);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x80), 4);
    assert_int_equal(nth_ev(fx, EV_SYNC, 'p', 3)->value, 4);
    co_sync_set_nmt_state(&fx->sp, CO_NMT_STOPPED);
    run_until(fx, 10000);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x80), 4);
    co_line_set_time(fx->p, 10200);
    co_sync_set_nmt_state(&fx->sp, CO_NMT_PRE_OPERATIONAL);
    run_until(fx, 11200);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x80), 5);
    i = tu_log_find_id(&fx->tb, 0x80, 4);
    tu_assert_logged(&fx->tb, i, 0x80, &one, 1);
    assert_int_equal(fx->tb.log[i].t_us, 11200);
    /* the consumer in stopped ignores (and counts) */
    co_sync_set_nmt_state(&fx->sc, CO_NMT_STOPPED);
    run_until(fx, 14200);
    assert_int_equal(fx->sc.stats.ignored_state, 3);
    assert_int_equal(count_ev(fx, EV_SYNC, 'c'), 5);
    co_sync_set_nmt_state(&fx->sc, CO_NMT_INITIALISING);
    co_sync_set_nmt_state(&fx->sc, CO_NMT_OPERATIONAL);
    run_until(fx, 15200);
    assert_int_equal(count_ev(fx, EV_SYNC, 'c'), 6);
    /* initialising (reset) stops the producer like stopped */
    co_sync_set_nmt_state(&fx->sp, CO_NMT_INITIALISING);
    run_until(fx, 20000);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x80), 9);
}

static void dummy_rx(co_line_t *line, const co_frame_t *frame, void *user)
{
    (void)line;
    (void)frame;
    (void)user;
}

/* Configuration without an OD, and the listener list's bounds. */
static void test_api_without_od(void **state)
{
    fx_t *fx = *state;
    co_sync_t s;
    co_sync_config_t c = {0x40000085u, 2000, 0, 1};   /* overflow 1 counts as 2 */
    static const uint8_t one = 1, two = 2;
    tag_t tags[CO_SYNC_MAX_LISTENERS + 1];
    int k;
    (void)fx;
    co_sync_deinit(&fx->sp);
    assert_true(co_sync_init(&s, fx->p));
    for (k = 0; k < CO_SYNC_MAX_LISTENERS; k++) {
        tags[k] = (tag_t){fx, 'x'};
        assert_true(co_sync_add_listener(&s, on_sync, &tags[k]));
    }
    assert_false(co_sync_add_listener(&s, on_sync, &tags[0]));      /* full */
    co_sync_remove_listener(&s, on_sync, &tags[3]);
    assert_int_equal(s.listener_count, CO_SYNC_MAX_LISTENERS - 1);
    assert_false(co_sync_add_listener(&s, on_sync, &tags[0]));      /* already in */
    assert_false(co_sync_add_listener(&s, NULL, &tags[3]));
    assert_true(co_sync_add_listener(&s, on_sync, &tags[3]));
    co_sync_configure(&s, &c);
    co_sync_set_nmt_state(&s, CO_NMT_OPERATIONAL);
    run_until(fx, 6000);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x85), 3);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, 0x85, 0), 0x85, &one, 1);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, 0x85, 1), 0x85, &two, 1);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, 0x85, 2), 0x85, &one, 1);
    assert_int_equal(count_ev(fx, EV_SYNC, 'x'), 3 * CO_SYNC_MAX_LISTENERS);
    co_sync_deinit(&s);
    run_until(fx, 20000);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x85), 3);
    /* the CAN-ID is taken by someone else: init says so */
    assert_true(co_line_subscribe(fx->p, 0x80, 0x80, dummy_rx, NULL));
    assert_false(co_sync_init(&s, fx->p));
    assert_int_equal(s.stats.subscribe_failed, 1);
    co_sync_deinit(&s);
    assert_true(co_sync_init(&fx->sp, fx->m));   /* teardown deinits it */
}

/* A tx queue that refuses: counted, no counter step, listeners not told. */
static void test_tx_refused(void **state)
{
    fx_t *fx = *state;
    co_frame_t f = tu_frame(0x222, 0, NULL, 0);
    static const uint8_t one = 1;
    start_producer(fx, 1000, 3);
    co_line_set_time(fx->p, 0);
    while (co_line_send_raw(fx->p, &f))
        ;
    co_line_process(fx->p, 1000);                /* the SYNC finds the queue full */
    assert_int_equal(fx->sp.stats.tx_failed, 1);
    assert_int_equal(count_ev(fx, EV_SYNC, 'p'), 0);
    {
        co_frame_t out;
        while (co_line_tx_pop(fx->p, &out))
            ;
    }
    fx->tb.now = 1000;
    run_until(fx, 2000);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, 0x80, 0), 0x80, &one, 1);
    assert_int_equal(nth_ev(fx, EV_SYNC, 'p', 0)->value, 1);
}

/* 10 000 random frames at the consumer (random id near the SYNC id, length,
 * flags, bytes, NMT state, overflow): never a crash, every frame on the SYNC
 * id accounted for exactly once. */
static void test_random_frames(void **state)
{
    fx_t *fx = *state;
    uint64_t rng = 0x5EED5EEDull;
    uint32_t on_id = 0;
    int k;
    for (k = 0; k < 10000; k++) {
        uint64_t r = tu_rand(&rng);
        co_frame_t f;
        memset(&f, 0, sizeof f);
        f.id = 0x7E + (uint32_t)(r % 5);
        f.len = (uint8_t)((r >> 8) % 10);
        if ((r >> 60) == 0)   /* 1 in 16: some flags */
            f.flags = (uint8_t)((r >> 16) & (CO_FRAME_RTR | CO_FRAME_EXT | CO_FRAME_FD));
        else if (fx->tb.mode == CO_MODE_FD && (r >> 59) & 1)
            f.flags = CO_FRAME_FD | CO_FRAME_BRS;
        memcpy(f.data, &r, sizeof r);
        if (fx->tb.mode == CO_MODE_FD && (f.flags & CO_FRAME_FD))
            f.len = co_fd_len_round((size_t)((r >> 24) % 65));
        if ((r >> 32) % 97 == 0)
            consumer_config(fx, 0x80, (uint32_t)((r >> 40) % 3) * 100, (uint8_t)((r >> 48) % 4));
        if ((r >> 36) % 89 == 0)
            co_sync_set_nmt_state(&fx->sc, (r >> 44) & 1 ? CO_NMT_STOPPED : CO_NMT_OPERATIONAL);
        if (co_frame_is_valid(&f) && !(f.flags & (CO_FRAME_RTR | CO_FRAME_EXT)) &&
            f.id == 0x80 && !(fx->tb.mode == CO_MODE_CLASSIC && (f.flags & CO_FRAME_FD)))
            on_id++;
        co_line_receive(fx->c, &f);
        co_line_process(fx->c, fx->tb.now + (uint64_t)k * 50);
    }
    assert_true(on_id > 500);
    assert_int_equal(fx->sc.stats.received + fx->sc.stats.bad_length +
                         fx->sc.stats.ignored_state, on_id);
    assert_int_equal((uint32_t)count_ev(fx, EV_SYNC, 'c'), fx->sc.stats.received);
    assert_int_equal((uint32_t)count_ev(fx, EV_ERROR, 'c'), fx->sc.stats.bad_length);
}

static void count_listener(uint8_t counter, void *user)
{
    (void)counter;
    ((fx_t *)user)->listener_calls++;
}

/* A SYNC flood: every frame costs one listener round and one timer re-arm;
 * the timer list does not grow, the window closes once after the flood. */
static void test_flood(void **state)
{
    fx_t *fx = *state;
    int round, k;
    co_sync_remove_listener(&fx->sc, on_sync, &tag_c);
    assert_true(co_sync_add_listener(&fx->sc, count_listener, fx));
    consumer_config(fx, 0x80, 1000, 0);
    for (round = 0; round < 100; round++) {
        co_frame_t f = tu_frame(0x80, tu_bus_flags(&fx->tb), NULL, 0);
        for (k = 0; k < 200; k++)
            assert_true(co_line_receive(fx->c, &f));
        co_line_process(fx->c, (uint64_t)round * 10);
        assert_true(fx->c->timers.armed <= 1);
    }
    assert_int_equal(fx->listener_calls, 20000);
    assert_int_equal(fx->sc.stats.received, 20000);
    co_line_process(fx->c, 990 + 999);
    assert_int_equal(count_ev(fx, EV_WINDOW, 'c'), 0);
    co_line_process(fx->c, 990 + 1000);
    assert_int_equal(count_ev(fx, EV_WINDOW, 'c'), 1);
}

#define BOTH(t) cmocka_unit_test_setup_teardown(t, setup_classic, teardown), \
                cmocka_unit_test_setup_teardown(t, setup_fd, teardown)

int main(void)
{
    const struct CMUnitTest tests[] = {
        BOTH(test_producer_period),
        BOTH(test_counter_wrap),
        BOTH(test_counter_wrap_240),
        BOTH(test_od_aborts),
        BOTH(test_restart_on_change),
        BOTH(test_reload_applies),
        BOTH(test_consumer_resubscribes),
        BOTH(test_wrong_length),
        BOTH(test_accept_any_counter),
        BOTH(test_window),
        BOTH(test_window_change_while_open),
        BOTH(test_nmt_states),
        BOTH(test_api_without_od),
        BOTH(test_tx_refused),
        BOTH(test_random_frames),
        BOTH(test_flood),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
