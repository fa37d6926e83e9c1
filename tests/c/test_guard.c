/* Node guarding and life guarding (co_guard) on a classic in-process bus
 * with a fake clock. Lines: m (index 0) is the guarding master with the
 * heartbeat consumer every runtime line has (answers handed over through
 * its filter), s (index 1) carries node 5 (co_node + guard slave bound to
 * its OD), x (index 2) injects frames. The sniffer checks every remote
 * frame and answer: CAN-ID, flags, length, bytes, time. */
#include "test_od_util.h"

#include "canopenfd/co_guard.h"

#define MS(x) ((uint64_t)(x) * TU_MS)
#define ID_S 5
#define MAX_EV 16384

enum { EV_LIFE = 1, EV_GUARD, EV_HB };

typedef struct ev {
    int kind;
    int node;
    int event;
    int state;
    uint64_t t;
} ev_t;

typedef struct fx {
    tu_bus_t tb;
    tu_line_t l[3];
    co_line_t *m, *s, *x;
    co_node_t node;
    co_od_t od;
    co_od_entry_t entries[8];
    uint8_t pool[64];
    co_od_subscription_t subs[8];
    co_guard_slave_t gs;
    co_hb_consumer_t hb;
    co_hb_entry_t hb_entries[4];
    co_guard_master_t gm;
    co_guard_node_t gnodes[2];
    ev_t ev[MAX_EV];
    int nev;
} fx_t;

/* ------------------------------------------------------------ recording */

static void add_ev(fx_t *fx, int kind, int node, int event, int state)
{
    assert_true(fx->nev < MAX_EV);
    fx->ev[fx->nev] = (ev_t){kind, node, event, state, fx->tb.now};
    fx->nev++;
}

static int count_ev(const fx_t *fx, int kind, int event)
{
    int i, n = 0;
    for (i = 0; i < fx->nev; i++)
        if (fx->ev[i].kind == kind && (event < 0 || fx->ev[i].event == event))
            n++;
    return n;
}

static const ev_t *nth_ev(const fx_t *fx, int kind, int event, int k)
{
    int i;
    for (i = 0; i < fx->nev; i++)
        if (fx->ev[i].kind == kind && (event < 0 || fx->ev[i].event == event) && k-- == 0)
            return &fx->ev[i];
    return NULL;
}

static void on_life(co_guard_slave_t *s, co_guard_life_event_t event, void *user)
{
    fx_t *fx = user;
    assert_ptr_equal(s, &fx->gs);
    add_ev(fx, EV_LIFE, ID_S, event, 0);
}

static void on_guard(co_guard_master_t *m, uint8_t node_id, co_guard_event_t event,
                     co_nmt_state_t state, void *user)
{
    fx_t *fx = user;
    assert_ptr_equal(m, &fx->gm);
    add_ev(fx, EV_GUARD, node_id, event, state);
}

static void on_hb(co_hb_consumer_t *c, uint8_t node_id, co_hb_event_t event,
                  co_nmt_state_t state, void *user)
{
    (void)c;
    add_ev(user, EV_HB, node_id, event, state);
}

/* ------------------------------------------------------------ fixture */

static const tu_od_row_t rows[] = {
    { 0x100C, 0, VAR, U16, RW, 0, 2, 0, NULL, 0, 0 },
    { 0x100D, 0, VAR, U8, RW, 0, 1, 0, NULL, 0, 0 },
    { 0x1017, 0, VAR, U16, RW, 0, 2, 0, NULL, 0, 0 },
};

static void step(fx_t *fx, uint64_t t) { tu_step(&fx->tb, t); }
static void run_until(fx_t *fx, uint64_t t) { tu_run_until(&fx->tb, t); }

static int setup(void **state)
{
    fx_t *fx = calloc(1, sizeof *fx);
    if (fx == NULL)
        return -1;
    tu_bus_init(&fx->tb, CO_MODE_CLASSIC, false);
    fx->m = tu_bus_add_line(&fx->tb, &fx->l[0]);
    fx->s = tu_bus_add_line(&fx->tb, &fx->l[1]);
    fx->x = tu_bus_add_line(&fx->tb, &fx->l[2]);
    co_od_init(&fx->od, CO_MODE_CLASSIC, fx->entries, 8, fx->pool, sizeof fx->pool, fx->subs, 8);
    tu_od_add_rows(&fx->od, rows, sizeof rows / sizeof rows[0]);
    assert_true(co_od_seal(&fx->od, ID_S));
    assert_true(co_node_init(&fx->node, fx->s, ID_S, 0, NULL, NULL));
    assert_true(co_node_attach_od(&fx->node, &fx->od, NULL, NULL));
    assert_true(co_guard_slave_init(&fx->gs, fx->s, &fx->node.nmt, on_life, fx));
    assert_true(co_guard_slave_attach_od(&fx->gs, &fx->od));
    assert_true(co_hb_consumer_init(&fx->hb, fx->m, fx->hb_entries, 4, on_hb, fx));
    assert_true(co_guard_master_init(&fx->gm, fx->m, fx->gnodes, 2, on_guard, fx));
    co_hb_consumer_set_filter(&fx->hb, co_guard_master_receive, &fx->gm);
    co_node_boot(&fx->node);
    step(fx, 0);
    *state = fx;
    return 0;
}

static int teardown(void **state)
{
    fx_t *fx = *state;
    co_guard_master_deinit(&fx->gm);
    co_guard_slave_deinit(&fx->gs);
    co_hb_consumer_deinit(&fx->hb);
    co_node_deinit(&fx->node);
    free(fx);
    return 0;
}

static uint32_t od_write(fx_t *fx, uint16_t index, uint32_t value, uint32_t size)
{
    uint8_t scratch[8], b[4];
    co_od_xfer_t x;
    uint32_t r;
    co_line_set_time(fx->s, fx->tb.now);
    tu_le_put(b, value, size);
    co_od_xfer_init(&x, scratch, sizeof scratch);
    r = co_od_write_begin(&fx->od, &x, index, 0, size);
    if (r == 0)
        r = co_od_write_chunk(&x, b, size);
    if (r == 0)
        r = co_od_write_end(&x);
    return r;
}

/* A remote frame from line x at the current time. */
static void rtr(fx_t *fx, uint32_t id, uint8_t dlc, uint8_t extra_flags)
{
    co_frame_t f = tu_frame(id, (uint8_t)(CO_FRAME_RTR | extra_flags), NULL, dlc);
    assert_true(co_line_send_raw(fx->x, &f));
    step(fx, fx->tb.now);
}

static void inject(fx_t *fx, uint32_t id, const uint8_t *data, uint8_t len)
{
    co_frame_t f = tu_frame(id, 0, data, len);
    assert_true(co_line_send_raw(fx->x, &f));
    step(fx, fx->tb.now);
}

/* The k-th answer of node 5 in the log (data frames on 0x705 after the
 * boot-up), -1 if none. */
static long answer(const fx_t *fx, size_t k)
{
    size_t i;
    for (i = 0; i < fx->tb.log_count; i++) {
        const co_frame_t *f = &fx->tb.log[i].frame;
        if (f->id == 0x705 && !(f->flags & CO_FRAME_RTR) && !(f->len == 1 && f->data[0] == 0) &&
            k-- == 0)
            return (long)i;
    }
    return -1;
}

static size_t answers(const fx_t *fx)
{
    size_t n = 0;
    while (answer(fx, n) >= 0)
        n++;
    return n;
}

static size_t rtrs(const fx_t *fx, uint32_t id, uint64_t *at, size_t max)
{
    size_t i, n = 0;
    for (i = 0; i < fx->tb.log_count; i++) {
        const co_frame_t *f = &fx->tb.log[i].frame;
        if (f->id == id && (f->flags & CO_FRAME_RTR)) {
            if (n < max)
                at[n] = fx->tb.log[i].t_us;
            n++;
        }
    }
    return n;
}

/* ------------------------------------------------------------ slave */

/* Answers: one byte, NMT state | toggle, toggle from 0 alternating, for any
 * requested length; other ids, 29-bit and data frames are not taken. */
static void test_slave_answers(void **state)
{
    fx_t *fx = *state;
    static const uint8_t a0 = 0x7F, a1 = 0xFF, a2 = 0x05, a3 = 0x85, a4 = 0x04;
    uint32_t rtr_before = fx->s->stats.rx_rtr;
    rtr(fx, 0x705, 1, 0);
    rtr(fx, 0x705, 0, 0);
    tu_assert_logged(&fx->tb, answer(fx, 0), 0x705, &a0, 1);
    tu_assert_logged(&fx->tb, answer(fx, 1), 0x705, &a1, 1);
    co_nmt_apply(&fx->node.nmt, CO_NMT_CMD_START);
    rtr(fx, 0x705, 8, 0);
    rtr(fx, 0x705, 1, 0);
    tu_assert_logged(&fx->tb, answer(fx, 2), 0x705, &a2, 1);
    tu_assert_logged(&fx->tb, answer(fx, 3), 0x705, &a3, 1);
    co_nmt_apply(&fx->node.nmt, CO_NMT_CMD_STOP);
    rtr(fx, 0x705, 1, 0);
    tu_assert_logged(&fx->tb, answer(fx, 4), 0x705, &a4, 1);
    assert_int_equal(fx->gs.stats.answered, 5);
    /* not ours: another node's id, a 29-bit id */
    rtr(fx, 0x706, 1, 0);
    rtr(fx, 0x705, 1, CO_FRAME_EXT);
    assert_int_equal(answers(fx), 5);
    assert_int_equal(fx->s->stats.rx_rtr, rtr_before + 2);
    /* a data frame on 0x705 is no request */
    inject(fx, 0x705, &a0, 1);
    assert_int_equal(answers(fx), 6);   /* the injected one itself */
    assert_int_equal(fx->gs.stats.answered, 5);
}

/* Reset communication: the toggle starts at 0 again. */
static void test_slave_toggle_reset(void **state)
{
    fx_t *fx = *state;
    static const uint8_t a0 = 0x7F, a1 = 0xFF;
    rtr(fx, 0x705, 1, 0);
    rtr(fx, 0x705, 1, 0);
    co_guard_slave_reset_communication(&fx->gs);
    rtr(fx, 0x705, 1, 0);
    rtr(fx, 0x705, 1, 0);
    tu_assert_logged(&fx->tb, answer(fx, 0), 0x705, &a0, 1);
    tu_assert_logged(&fx->tb, answer(fx, 1), 0x705, &a1, 1);
    tu_assert_logged(&fx->tb, answer(fx, 2), 0x705, &a0, 1);
    tu_assert_logged(&fx->tb, answer(fx, 3), 0x705, &a1, 1);
}

/* Life guarding: off until the first remote frame; then no remote frame
 * within guard time x factor is an event at exactly that time; the next
 * remote frame resolves it and starts over. */
static void test_slave_life_guarding(void **state)
{
    fx_t *fx = *state;
    const ev_t *e;
    assert_int_equal(od_write(fx, 0x100C, 100, 2), 0);
    assert_int_equal(od_write(fx, 0x100D, 3, 1), 0);
    run_until(fx, MS(2000));                     /* no remote frame yet: nothing */
    assert_int_equal(count_ev(fx, EV_LIFE, -1), 0);
    rtr(fx, 0x705, 1, 0);                         /* at 2000 ms */
    run_until(fx, MS(2300) - 1);
    assert_int_equal(count_ev(fx, EV_LIFE, -1), 0);
    run_until(fx, MS(2300));
    e = nth_ev(fx, EV_LIFE, CO_GUARD_LIFE_LOST, 0);
    assert_non_null(e);
    assert_int_equal(e->t, MS(2300));
    assert_int_equal(fx->gs.stats.life_lost, 1);
    run_until(fx, MS(3000));                     /* told once */
    assert_int_equal(count_ev(fx, EV_LIFE, -1), 1);
    rtr(fx, 0x705, 1, 0);
    e = nth_ev(fx, EV_LIFE, CO_GUARD_LIFE_RESOLVED, 0);
    assert_non_null(e);
    assert_int_equal(e->t, MS(3000));
    /* requests in time keep it quiet */
    run_until(fx, MS(3250));
    rtr(fx, 0x705, 1, 0);
    run_until(fx, MS(3500));
    rtr(fx, 0x705, 1, 0);
    run_until(fx, MS(3799));
    assert_int_equal(count_ev(fx, EV_LIFE, -1), 2);
    run_until(fx, MS(3800));
    assert_int_equal(count_ev(fx, EV_LIFE, CO_GUARD_LIFE_LOST), 2);
    assert_int_equal(nth_ev(fx, EV_LIFE, CO_GUARD_LIFE_LOST, 1)->t, MS(3800));
}

/* OD writes of 0x100C / 0x100D take effect at once; 0 switches life
 * guarding off (an open event is resolved). */
static void test_slave_od_changes(void **state)
{
    fx_t *fx = *state;
    assert_int_equal(od_write(fx, 0x100C, 100, 2), 0);
    assert_int_equal(od_write(fx, 0x100D, 3, 1), 0);
    rtr(fx, 0x705, 1, 0);                         /* life time runs to 300 ms */
    run_until(fx, MS(100));
    assert_int_equal(od_write(fx, 0x100C, 50, 2), 0);   /* from now: 150 ms */
    run_until(fx, MS(250) - 1);
    assert_int_equal(count_ev(fx, EV_LIFE, -1), 0);
    run_until(fx, MS(250));
    assert_int_equal(count_ev(fx, EV_LIFE, CO_GUARD_LIFE_LOST), 1);
    assert_int_equal(nth_ev(fx, EV_LIFE, CO_GUARD_LIFE_LOST, 0)->t, MS(250));
    /* factor 0: off, the open event resolved */
    assert_int_equal(od_write(fx, 0x100D, 0, 1), 0);
    assert_int_equal(count_ev(fx, EV_LIFE, CO_GUARD_LIFE_RESOLVED), 1);
    rtr(fx, 0x705, 1, 0);
    run_until(fx, MS(5000));
    assert_int_equal(count_ev(fx, EV_LIFE, -1), 2);
    assert_int_equal(fx->gs.stats.answered, 2);   /* still answers */
    /* factor back: counts from now */
    assert_int_equal(od_write(fx, 0x100D, 2, 1), 0);
    run_until(fx, MS(5100));
    assert_int_equal(count_ev(fx, EV_LIFE, CO_GUARD_LIFE_LOST), 2);
    assert_int_equal(nth_ev(fx, EV_LIFE, CO_GUARD_LIFE_LOST, 1)->t, MS(5100));
    /* a reload (reset communication) applies the defaults: off */
    co_od_load_defaults(&fx->od, CO_GROUP_COMMUNICATION);
    assert_int_equal(fx->gs.guard_time_ms, 0);
    assert_int_equal(count_ev(fx, EV_LIFE, CO_GUARD_LIFE_RESOLVED), 2);
}

/* Heartbeat producer on (0x1017): remote frames unanswered (counted by the
 * line), life guarding stopped; off again: guarding restarts with toggle 0
 * at the next remote frame. */
static void test_slave_heartbeat_excludes_guarding(void **state)
{
    fx_t *fx = *state;
    static const uint8_t a0 = 0x7F;
    uint32_t rx_rtr;
    size_t n;
    assert_int_equal(od_write(fx, 0x100C, 100, 2), 0);
    assert_int_equal(od_write(fx, 0x100D, 2, 1), 0);
    rtr(fx, 0x705, 1, 0);                         /* answered 0x7F, toggle now 1 */
    assert_int_equal(od_write(fx, 0x1017, 1000, 2), 0);
    rx_rtr = fx->s->stats.rx_rtr;
    run_until(fx, MS(500));
    assert_int_equal(count_ev(fx, EV_LIFE, -1), 0);   /* not watching */
    n = answers(fx);
    rtr(fx, 0x705, 1, 0);
    assert_int_equal(answers(fx), n);
    assert_int_equal(fx->s->stats.rx_rtr, rx_rtr + 1);
    assert_int_equal(fx->gs.stats.ignored_heartbeat, 1);
    assert_int_equal(od_write(fx, 0x1017, 0, 2), 0);
    run_until(fx, MS(1500));
    assert_int_equal(count_ev(fx, EV_LIFE, -1), 0);   /* waits for the first request */
    rtr(fx, 0x705, 1, 0);
    tu_assert_logged(&fx->tb, answer(fx, n), 0x705, &a0, 1);   /* toggle 0 again */
    run_until(fx, MS(1700));
    assert_int_equal(count_ev(fx, EV_LIFE, CO_GUARD_LIFE_LOST), 1);
    assert_int_equal(nth_ev(fx, EV_LIFE, CO_GUARD_LIFE_LOST, 0)->t, MS(1700));
    /* heartbeat on while the event is open: resolved */
    co_guard_slave_set_heartbeat(&fx->gs, 200);
    assert_int_equal(count_ev(fx, EV_LIFE, CO_GUARD_LIFE_RESOLVED), 1);
}

/* Before boot-up (initialising) nothing is answered. */
static void test_slave_not_before_bootup(void **state)
{
    fx_t *fx = *state;
    co_node_t node;
    co_guard_slave_t gs;
    tu_line_t extra;
    (void)fx;
    tu_line_init(&extra, CO_MODE_CLASSIC, false);
    assert_true(co_node_init(&node, &extra.line, 9, 0, NULL, NULL));
    assert_true(co_guard_slave_init(&gs, &extra.line, &node.nmt, NULL, NULL));
    {
        co_frame_t f = tu_frame(0x709, CO_FRAME_RTR, NULL, 1);
        assert_true(co_line_receive(&extra.line, &f));
        co_line_process(&extra.line, 0);
    }
    assert_int_equal(gs.stats.ignored_state, 1);
    assert_int_equal(extra.line.stats.rx_rtr, 1);
    assert_int_equal(co_line_tx_count(&extra.line), 0);
    co_guard_slave_deinit(&gs);
    co_node_deinit(&node);
}

/* ------------------------------------------------------------ master */

/* The master's requests: remote frames 0x705 with DLC 1 every guard time,
 * the first at once; the node's answers taken (not heartbeat errors),
 * STATE_CHANGED + STARTED at the first. */
static void test_master_guards(void **state)
{
    fx_t *fx = *state;
    uint64_t at[16];
    size_t k, n;
    const ev_t *e;
    co_line_set_time(fx->m, MS(10));
    step(fx, MS(10));
    assert_int_equal(co_guard_master_guard(&fx->gm, ID_S, 100, 3), CO_GUARD_OK);
    run_until(fx, MS(10) + MS(100) * 9);
    n = rtrs(fx, 0x705, at, 16);
    assert_int_equal(n, 10);
    for (k = 0; k < n; k++)
        assert_int_equal(at[k], MS(10) + MS(100) * k);
    {
        long i;
        size_t i2;
        for (i2 = 0; i2 < fx->tb.log_count; i2++)
            if (fx->tb.log[i2].frame.flags & CO_FRAME_RTR)
                break;
        i = (long)i2;
        assert_int_equal(fx->tb.log[i].frame.id, 0x705);
        assert_int_equal(fx->tb.log[i].frame.flags, CO_FRAME_RTR);
        assert_int_equal(fx->tb.log[i].frame.len, 1);   /* DLC of the answer asked for */
    }
    assert_int_equal(answers(fx), 10);
    for (k = 0; k < 10; k++) {
        uint8_t b = (uint8_t)(0x7F | (k % 2 ? 0x80 : 0));
        tu_assert_logged(&fx->tb, answer(fx, k), 0x705, &b, 1);
    }
    assert_int_equal(fx->gm.stats.answers, 10);
    assert_int_equal(fx->gm.stats.toggle_errors, 0);
    assert_int_equal(fx->gm.stats.missed, 0);
    assert_int_equal(co_guard_master_monitor(&fx->gm, ID_S), CO_GUARD_MONITOR_ACTIVE);
    assert_int_equal(co_guard_master_state(&fx->gm, ID_S), CO_NMT_PRE_OPERATIONAL);
    e = nth_ev(fx, EV_GUARD, CO_GUARD_STATE_CHANGED, 0);
    assert_non_null(e);
    assert_int_equal(e->state, CO_NMT_PRE_OPERATIONAL);
    assert_int_equal(e->t, MS(10));
    assert_int_equal(count_ev(fx, EV_GUARD, CO_GUARD_STARTED), 1);
    assert_int_equal(count_ev(fx, EV_GUARD, -1), 2);
    /* toggled answers are not bad heartbeats; the boot-up was the consumer's */
    assert_int_equal(fx->m->stats.hb_bad_state, 0);
    assert_int_equal(fx->m->stats.hb_bad_length, 0);
    /* the slave's life guarding runs from the master's requests */
    assert_int_equal(fx->gs.stats.answered, 10);
    /* a state change is told */
    co_nmt_apply(&fx->node.nmt, CO_NMT_CMD_START);
    run_until(fx, MS(10) + MS(100) * 10);
    e = nth_ev(fx, EV_GUARD, CO_GUARD_STATE_CHANGED, 1);
    assert_non_null(e);
    assert_int_equal(e->state, CO_NMT_OPERATIONAL);
    assert_int_equal(e->t, MS(1010));
}

/* Answers stop: LOST after life time factor missed periods, at exactly the
 * request time that makes them factor; the node back with its toggle reset:
 * one toggle error (not taken), RESUMED at the answer after it. */
static void test_master_lost_resumed(void **state)
{
    fx_t *fx = *state;
    const ev_t *e;
    assert_int_equal(co_guard_master_guard(&fx->gm, ID_S, 100, 3), CO_GUARD_OK);
    run_until(fx, MS(250));       /* requests at 0, 100, 200 answered: 0x7F 0xFF 0x7F */
    co_guard_slave_set_heartbeat(&fx->gs, 1000);   /* the node stops answering */
    run_until(fx, MS(600) - 1);
    assert_int_equal(count_ev(fx, EV_GUARD, CO_GUARD_LOST), 0);
    run_until(fx, MS(600));       /* 300 unanswered: missed at 400, 500, 600 */
    e = nth_ev(fx, EV_GUARD, CO_GUARD_LOST, 0);
    assert_non_null(e);
    assert_int_equal(e->t, MS(600));
    assert_int_equal(e->node, ID_S);
    assert_int_equal(co_guard_master_monitor(&fx->gm, ID_S), CO_GUARD_MONITOR_LOST);
    assert_int_equal(fx->gm.stats.missed, 3);
    run_until(fx, MS(650));
    co_guard_slave_set_heartbeat(&fx->gs, 0);      /* back, toggle 0 again */
    run_until(fx, MS(700));       /* answer 0x7F, the master expects 0xFF */
    assert_int_equal(count_ev(fx, EV_GUARD, CO_GUARD_TOGGLE_ERROR), 1);
    assert_int_equal(nth_ev(fx, EV_GUARD, CO_GUARD_TOGGLE_ERROR, 0)->t, MS(700));
    assert_int_equal(count_ev(fx, EV_GUARD, CO_GUARD_RESUMED), 0);
    run_until(fx, MS(800));       /* answer 0xFF: taken */
    e = nth_ev(fx, EV_GUARD, CO_GUARD_RESUMED, 0);
    assert_non_null(e);
    assert_int_equal(e->t, MS(800));
    assert_int_equal(co_guard_master_monitor(&fx->gm, ID_S), CO_GUARD_MONITOR_ACTIVE);
    assert_int_equal(count_ev(fx, EV_GUARD, CO_GUARD_LOST), 1);
    assert_int_equal(fx->gm.stats.toggle_errors, 1);
    run_until(fx, MS(2000));
    assert_int_equal(count_ev(fx, EV_GUARD, CO_GUARD_TOGGLE_ERROR), 1);
    assert_int_equal(count_ev(fx, EV_GUARD, CO_GUARD_LOST), 1);
}

/* A node that never answers is reported lost too; factor 0 counts as 1. */
static void test_master_never_answers(void **state)
{
    fx_t *fx = *state;
    assert_int_equal(co_guard_master_guard(&fx->gm, 33, 50, 0), CO_GUARD_OK);
    run_until(fx, MS(49));
    assert_int_equal(count_ev(fx, EV_GUARD, CO_GUARD_LOST), 0);
    run_until(fx, MS(50));
    assert_int_equal(count_ev(fx, EV_GUARD, CO_GUARD_LOST), 1);
    assert_int_equal(nth_ev(fx, EV_GUARD, CO_GUARD_LOST, 0)->node, 33);
    assert_int_equal(nth_ev(fx, EV_GUARD, CO_GUARD_LOST, 0)->state, CO_NMT_UNKNOWN);
    run_until(fx, MS(500));
    assert_int_equal(count_ev(fx, EV_GUARD, CO_GUARD_LOST), 1);
    {
        uint64_t at[16];
        assert_int_equal(rtrs(fx, 0x721, at, 16), 11);
    }
}

/* Wrong toggle, invalid state, wrong length from a guarded node: taken by the
 * master (counted there), never heartbeat errors; the same from an unguarded
 * node stays the heartbeat consumer's. */
static void test_master_malformed(void **state)
{
    fx_t *fx = *state;
    static const uint8_t wrong_toggle = 0x85, bad_state = 0x83, zero_t = 0x80, ok = 0x05;
    static const uint8_t two[2] = {0x05, 0};
    assert_int_equal(co_guard_master_guard(&fx->gm, 9, 1000, 2), CO_GUARD_OK);
    step(fx, 0);
    inject(fx, 0x709, &bad_state, 1);
    inject(fx, 0x709, &zero_t, 1);
    assert_int_equal(fx->gm.stats.bad_state, 2);
    inject(fx, 0x709, two, 2);
    inject(fx, 0x709, NULL, 0);
    assert_int_equal(fx->gm.stats.bad_length, 2);
    assert_int_equal(fx->m->stats.hb_bad_state, 0);
    assert_int_equal(fx->m->stats.hb_bad_length, 0);
    assert_int_equal(co_guard_master_monitor(&fx->gm, 9), CO_GUARD_MONITOR_OFF);
    inject(fx, 0x709, &ok, 1);                 /* the first answer: toggle 0 adopted */
    assert_int_equal(co_guard_master_monitor(&fx->gm, 9), CO_GUARD_MONITOR_ACTIVE);
    assert_int_equal(fx->gm.stats.answers, 1);
    inject(fx, 0x709, &ok, 1);                 /* toggle 0 again: 0x80 expected */
    assert_int_equal(fx->gm.stats.toggle_errors, 1);
    assert_int_equal(nth_ev(fx, EV_GUARD, CO_GUARD_TOGGLE_ERROR, 0)->state, CO_NMT_OPERATIONAL);
    assert_int_equal(fx->gm.stats.answers, 1);
    inject(fx, 0x709, &wrong_toggle, 1);       /* 0x85: the toggle it expects now */
    assert_int_equal(fx->gm.stats.answers, 2);
    assert_int_equal(fx->gm.stats.toggle_errors, 1);
    /* node 10 is not guarded: the consumer sees its frames as before */
    inject(fx, 0x70A, &wrong_toggle, 1);
    assert_int_equal(fx->m->stats.hb_bad_state, 1);
    inject(fx, 0x70A, two, 2);
    assert_int_equal(fx->m->stats.hb_bad_length, 1);
    /* remote frames are not answers */
    {
        co_frame_t f = tu_frame(0x709, CO_FRAME_RTR, NULL, 1);
        assert_false(co_guard_master_receive(fx->m, &f, &fx->gm));
        f = tu_frame(0x709, CO_FRAME_EXT, &ok, 1);
        assert_false(co_guard_master_receive(fx->m, &f, &fx->gm));
        f = tu_frame(0x700, 0, &ok, 1);
        assert_false(co_guard_master_receive(fx->m, &f, &fx->gm));
    }
}

/* A boot-up of a guarded node goes to the heartbeat consumer (BOOTUP event)
 * and resets the expected toggle. */
static void test_master_bootup_resets_toggle(void **state)
{
    fx_t *fx = *state;
    assert_int_equal(co_guard_master_guard(&fx->gm, ID_S, 100, 3), CO_GUARD_OK);
    run_until(fx, MS(250));                      /* 0x7F 0xFF 0x7F: expects 0xFF next */
    assert_int_equal(count_ev(fx, EV_HB, CO_HB_BOOTUP), 1);   /* the power-on one */
    co_nmt_apply(&fx->node.nmt, CO_NMT_CMD_RESET_COMMUNICATION);
    co_guard_slave_reset_communication(&fx->gs);  /* what the integration does */
    step(fx, MS(250));
    assert_int_equal(count_ev(fx, EV_HB, CO_HB_BOOTUP), 2);
    assert_int_equal(nth_ev(fx, EV_HB, CO_HB_BOOTUP, 1)->node, ID_S);
    assert_int_equal(nth_ev(fx, EV_HB, CO_HB_BOOTUP, 1)->t, MS(250));
    run_until(fx, MS(1000));                     /* 0x7F at 300 is what it expects now */
    assert_int_equal(fx->gm.stats.toggle_errors, 0);
    assert_int_equal(fx->gm.stats.answers, 11);
    assert_int_equal(count_ev(fx, EV_GUARD, CO_GUARD_LOST), 0);
}

/* Guarding of a node guarded before (unguard, guard again; or another master
 * before us): the node toggles on from where it was, and the first answer
 * sets what the master expects: no toggle error, answers alternate after. */
static void test_master_adopts_toggle_of_node_guarded_before(void **state)
{
    fx_t *fx = *state;
    assert_int_equal(co_guard_master_guard(&fx->gm, ID_S, 100, 3), CO_GUARD_OK);
    run_until(fx, MS(50));                       /* one answer: 0x7F, the node's next 0xFF */
    assert_int_equal(fx->gm.stats.answers, 1);
    co_guard_master_unguard(&fx->gm, ID_S);
    run_until(fx, MS(500));
    assert_int_equal(co_guard_master_guard(&fx->gm, ID_S, 100, 3), CO_GUARD_OK);
    run_until(fx, MS(500) + MS(100) * 5 + MS(50)); /* 0xFF 0x7F 0xFF 0x7F 0xFF 0x7F */
    {
        static const uint8_t with_toggle = 0xFF;
        tu_assert_logged(&fx->tb, answer(fx, 1), 0x705, &with_toggle, 1);
    }
    assert_int_equal(fx->gm.stats.answers, 7);
    assert_int_equal(fx->gm.stats.toggle_errors, 0);
    assert_int_equal(count_ev(fx, EV_GUARD, CO_GUARD_TOGGLE_ERROR), 0);
    assert_int_equal(co_guard_master_monitor(&fx->gm, ID_S), CO_GUARD_MONITOR_ACTIVE);
}

/* Expected state: one UNEXPECTED_STATE when the answers differ, again after
 * a matching answer. */
static void test_master_expected_state(void **state)
{
    fx_t *fx = *state;
    co_guard_master_expect_state(&fx->gm, ID_S, CO_NMT_OPERATIONAL);   /* not guarded: no-op */
    assert_int_equal(co_guard_master_guard(&fx->gm, ID_S, 100, 3), CO_GUARD_OK);
    co_guard_master_expect_state(&fx->gm, ID_S, CO_NMT_OPERATIONAL);
    run_until(fx, MS(300));
    assert_int_equal(count_ev(fx, EV_GUARD, CO_GUARD_UNEXPECTED_STATE), 1);
    assert_int_equal(nth_ev(fx, EV_GUARD, CO_GUARD_UNEXPECTED_STATE, 0)->state,
                     CO_NMT_PRE_OPERATIONAL);
    assert_int_equal(nth_ev(fx, EV_GUARD, CO_GUARD_UNEXPECTED_STATE, 0)->t, 0);
    co_nmt_apply(&fx->node.nmt, CO_NMT_CMD_START);
    run_until(fx, MS(600));
    assert_int_equal(count_ev(fx, EV_GUARD, CO_GUARD_UNEXPECTED_STATE), 1);
    co_nmt_apply(&fx->node.nmt, CO_NMT_CMD_STOP);
    run_until(fx, MS(900));
    assert_int_equal(count_ev(fx, EV_GUARD, CO_GUARD_UNEXPECTED_STATE), 2);
    assert_int_equal(nth_ev(fx, EV_GUARD, CO_GUARD_UNEXPECTED_STATE, 1)->t, MS(700));
    assert_int_equal(nth_ev(fx, EV_GUARD, CO_GUARD_UNEXPECTED_STATE, 1)->state, CO_NMT_STOPPED);
    co_guard_master_expect_state(&fx->gm, ID_S, CO_NMT_UNKNOWN);
    run_until(fx, MS(1500));
    assert_int_equal(count_ev(fx, EV_GUARD, CO_GUARD_UNEXPECTED_STATE), 2);
}

/* The table and the arguments. */
static void test_master_api(void **state)
{
    fx_t *fx = *state;
    uint64_t at[32];
    assert_int_equal(co_guard_master_guard(&fx->gm, 0, 100, 1), CO_GUARD_BAD_NODE);
    assert_int_equal(co_guard_master_guard(&fx->gm, 128, 100, 1), CO_GUARD_BAD_NODE);
    assert_int_equal(co_guard_master_guard(&fx->gm, 7, 0, 1), CO_GUARD_BAD_TIME);
    assert_int_equal(co_guard_master_guard(&fx->gm, 7, 100, 1), CO_GUARD_OK);
    assert_int_equal(co_guard_master_guard(&fx->gm, 8, 100, 1), CO_GUARD_OK);
    assert_int_equal(co_guard_master_guard(&fx->gm, 9, 100, 1), CO_GUARD_NO_ROOM);
    run_until(fx, MS(150));
    assert_int_equal(rtrs(fx, 0x707, at, 32), 2);
    /* new times: the next request one new period from now */
    assert_int_equal(co_guard_master_guard(&fx->gm, 7, 300, 1), CO_GUARD_OK);
    run_until(fx, MS(450));
    assert_int_equal(rtrs(fx, 0x707, at, 32), 3);
    assert_int_equal(at[2], MS(450));
    co_guard_master_unguard(&fx->gm, 8);
    assert_int_equal(co_guard_master_monitor(&fx->gm, 8), CO_GUARD_MONITOR_OFF);
    assert_int_equal(co_guard_master_state(&fx->gm, 8), CO_NMT_UNKNOWN);
    co_guard_master_unguard(&fx->gm, 99);   /* harmless */
    assert_int_equal(co_guard_master_guard(&fx->gm, 9, 100, 1), CO_GUARD_OK);
    run_until(fx, MS(1000));
    assert_int_equal(rtrs(fx, 0x708, at, 32), 5);   /* 0..400 */
}

/* fd lines: no remote frames, no guarding. */
static void test_fd_refused(void **state)
{
    tu_line_t fd;
    co_nmt_t nmt;
    co_guard_slave_t gs;
    co_guard_master_t gm;
    co_guard_node_t nodes[1];
    (void)state;
    tu_line_init(&fd, CO_MODE_FD, true);
    assert_true(co_nmt_init(&nmt, &fd.line, 3, NULL, NULL));
    assert_false(co_guard_slave_init(&gs, &fd.line, &nmt, NULL, NULL));
    assert_int_equal(fd.line.other_count, 0);
    assert_false(co_guard_master_init(&gm, &fd.line, nodes, 1, NULL, NULL));
    assert_int_equal(co_guard_master_guard(&gm, 5, 100, 1), CO_GUARD_NO_ROOM);
    assert_int_equal(co_timer_list_next(co_line_timers(&fd.line)), CO_TIME_NEVER);
    co_nmt_deinit(&nmt);
}

/* 10 000 random frames at both lines (ids around node 5 and 9 in the error
 * control range, random flags, lengths and bytes) while node 5 is guarded:
 * no crash, every guarded-node frame accounted for by the master. */
static void test_random_frames(void **state)
{
    fx_t *fx = *state;
    uint64_t rng = 0x6A4D;
    int k;
    assert_int_equal(co_guard_master_guard(&fx->gm, ID_S, 10, 2), CO_GUARD_OK);
    assert_int_equal(od_write(fx, 0x100C, 10, 2), 0);
    assert_int_equal(od_write(fx, 0x100D, 2, 1), 0);
    for (k = 0; k < 10000; k++) {
        uint64_t r = tu_rand(&rng);
        co_frame_t f;
        memset(&f, 0, sizeof f);
        f.id = 0x703 + (uint32_t)(r % 8);
        f.len = (uint8_t)((r >> 8) % 10);
        f.flags = (r >> 12) % 4 == 0 ? CO_FRAME_RTR : 0;
        if ((r >> 60) == 0)
            f.flags = (uint8_t)(f.flags | ((r >> 16) & (CO_FRAME_EXT | CO_FRAME_FD)));
        memcpy(f.data, &r, sizeof r);
        co_line_receive((r >> 20) & 1 ? fx->m : fx->s, &f);
        if (k % 10 == 0)
            step(fx, fx->tb.now + 1000);
    }
    run_until(fx, fx->tb.now + MS(100));
    assert_true(fx->gm.stats.answers > 0);
    assert_true(fx->gs.stats.answered > 0);
    assert_true(fx->gm.stats.toggle_errors + fx->gm.stats.bad_state +
                fx->gm.stats.bad_length > 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_slave_answers, setup, teardown),
        cmocka_unit_test_setup_teardown(test_slave_toggle_reset, setup, teardown),
        cmocka_unit_test_setup_teardown(test_slave_life_guarding, setup, teardown),
        cmocka_unit_test_setup_teardown(test_slave_od_changes, setup, teardown),
        cmocka_unit_test_setup_teardown(test_slave_heartbeat_excludes_guarding, setup, teardown),
        cmocka_unit_test_setup_teardown(test_slave_not_before_bootup, setup, teardown),
        cmocka_unit_test_setup_teardown(test_master_guards, setup, teardown),
        cmocka_unit_test_setup_teardown(test_master_lost_resumed, setup, teardown),
        cmocka_unit_test_setup_teardown(test_master_never_answers, setup, teardown),
        cmocka_unit_test_setup_teardown(test_master_malformed, setup, teardown),
        cmocka_unit_test_setup_teardown(test_master_bootup_resets_toggle, setup, teardown),
        cmocka_unit_test_setup_teardown(test_master_adopts_toggle_of_node_guarded_before, setup,
                                        teardown),
        cmocka_unit_test_setup_teardown(test_master_expected_state, setup, teardown),
        cmocka_unit_test_setup_teardown(test_master_api, setup, teardown),
        cmocka_unit_test(test_fd_refused),
        cmocka_unit_test_setup_teardown(test_random_frames, setup, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
