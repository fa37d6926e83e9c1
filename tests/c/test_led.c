/* co_led: the CiA 303-3 run and error LEDs on a fake clock.
 *
 * The expected timelines are written from the timing rules themselves
 * (segments of on/off milliseconds), not from co_led_lit, so a wrong
 * pattern table fails here. */
#include "test_util.h"

#include "canopenfd/co_led.h"
#include "canopenfd/co_stack.h"

enum { LOG_MAX = 512, NODE = 5, PEER = 9 };

typedef struct change {
    uint64_t t_ms;
    co_led_which_t which;
    bool on;
    co_led_pattern_t pattern;
} change_t;

typedef struct recorder {
    change_t log[LOG_MAX];
    size_t count;
    const co_line_t *line;
} recorder_t;

static void record(co_led_t *led, co_led_which_t which, bool on, co_led_pattern_t pattern,
                   void *user)
{
    (void)led;
    recorder_t *r = user;
    assert_true(r->count < LOG_MAX);
    r->log[r->count++] = (change_t){.t_ms = co_line_now(r->line) / TU_MS, .which = which,
                                    .on = on, .pattern = pattern};
}

/* For the stack: the co_stack user is the recorder. */
static void record_stack(co_led_t *led, co_led_which_t which, bool on,
                         co_led_pattern_t pattern, void *user)
{
    record(led, which, on, pattern, user);
}

/* A lone line whose timers run at their exact deadlines. */
typedef struct world {
    tu_line_t line;
    co_led_t led;
    recorder_t rec;
} world_t;

static world_t *world_new(bool same_phase)
{
    world_t *w = calloc(1, sizeof *w);
    assert_non_null(w);
    tu_line_init(&w->line, CO_MODE_CLASSIC, false);
    co_line_set_time(&w->line.line, 0);
    w->rec.line = &w->line.line;
    co_led_config_t config = {.same_phase = same_phase, .changed = record, .user = &w->rec};
    co_led_init(&w->led, &w->line.line, &config);
    return w;
}

static void world_free(world_t *w)
{
    co_led_deinit(&w->led);
    free(w);
}

/* Run the line's timers up to until_ms, each at its deadline. */
static void run_until(world_t *w, uint64_t until_ms)
{
    tu_line_run_until(&w->line.line, until_ms * TU_MS);
}

static void at(world_t *w, uint64_t t_ms)
{
    run_until(w, t_ms);
}

/* ------------------------------------------------------------ expected */

/* A pattern as CiA 303-3 describes it: (ms, lit) segments repeated. */
typedef struct segments {
    uint32_t ms[10];
    bool lit[10];
    int count;
} segments_t;

static segments_t segments_of(co_led_pattern_t p)
{
    segments_t s = {0};
    switch (p) {
    case CO_LED_FLICKERING:
        s = (segments_t){{50, 50}, {true, false}, 2};
        break;
    case CO_LED_BLINKING:
        s = (segments_t){{200, 200}, {true, false}, 2};
        break;
    case CO_LED_SINGLE_FLASH:
        s = (segments_t){{200, 1000}, {true, false}, 2};
        break;
    case CO_LED_DOUBLE_FLASH:
        s = (segments_t){{200, 200, 200, 1000}, {true, false, true, false}, 4};
        break;
    case CO_LED_TRIPLE_FLASH:
        s = (segments_t){{200, 200, 200, 200, 200, 1000},
                         {true, false, true, false, true, false}, 6};
        break;
    case CO_LED_QUADRUPLE_FLASH:
        s = (segments_t){{200, 200, 200, 200, 200, 200, 200, 1000},
                         {true, false, true, false, true, false, true, false}, 8};
        break;
    default:
        fail_msg("no segments for pattern %d", (int)p);
    }
    return s;
}

/* Whether the pattern, started delay_ms late (dark before), lights at t_ms. */
static bool expected_lit(co_led_pattern_t p, uint32_t delay_ms, uint64_t t_ms)
{
    if (p == CO_LED_ON || p == CO_LED_OFF) {
        return p == CO_LED_ON;
    }
    if (t_ms < delay_ms) {
        return false;
    }
    segments_t s = segments_of(p);
    uint32_t period = 0;
    for (int i = 0; i < s.count; i++) {
        period += s.ms[i];
    }
    uint64_t in_period = (t_ms - delay_ms) % period;
    for (int i = 0; i < s.count; i++) {
        if (in_period < s.ms[i]) {
            return s.lit[i];
        }
        in_period -= s.ms[i];
    }
    return false;
}

/* The recorded changes of one LED are exactly the edges of the expected
 * timeline from t0 (one change at t0 telling the pattern, then one per
 * edge) up to end_ms. */
static void check_timeline(const recorder_t *r, co_led_which_t which, co_led_pattern_t p,
                           uint32_t delay_ms, uint64_t t0, uint64_t end_ms)
{
    /* the last change of this LED at t0 (inputs set one after the other may
     * tell intermediate patterns first) */
    size_t k = r->count;
    for (size_t i = 0; i < r->count; i++) {
        if (r->log[i].which == which && r->log[i].t_ms == t0) {
            k = i;
        }
    }
    assert_true(k < r->count);
    assert_int_equal(r->log[k].t_ms, t0);
    assert_int_equal(r->log[k].pattern, p);
    assert_int_equal(r->log[k].on, expected_lit(p, delay_ms, t0 - t0));
    bool level = r->log[k].on;
    size_t edges = 0;
    for (uint64_t t = t0 + 1; t <= end_ms; t++) {
        bool want = expected_lit(p, delay_ms, t - t0);
        if (want == level) {
            continue;
        }
        level = want;
        do {
            k++;
        } while (k < r->count && r->log[k].which != which);
        if (k >= r->count) {
            fail_msg("LED %d pattern %s: no change at %llu ms (edge %zu)", (int)which,
                     co_led_pattern_name(p), (unsigned long long)t, edges);
        }
        if (r->log[k].t_ms != t || r->log[k].on != want || r->log[k].pattern != p) {
            fail_msg("LED %d pattern %s: edge %zu expected at %llu ms to %d, got %llu ms "
                     "to %d (pattern %d)", (int)which, co_led_pattern_name(p), edges,
                     (unsigned long long)t, (int)want, (unsigned long long)r->log[k].t_ms,
                     (int)r->log[k].on, (int)r->log[k].pattern);
        }
        edges++;
    }
    /* nothing more for this LED up to end_ms */
    for (size_t j = k + 1; j < r->count; j++) {
        if (r->log[j].which == which && r->log[j].t_ms <= end_ms) {
            fail_msg("LED %d: unexpected change at %llu ms", (int)which,
                     (unsigned long long)r->log[j].t_ms);
        }
    }
    assert_true(edges > 0 || p == CO_LED_ON || p == CO_LED_OFF);
}

/* ------------------------------------------------------------ tests */

/* Every error LED pattern from its cause: 3 s of edges at their exact times. */
static void test_error_led_timelines(void **state)
{
    (void)state;
    static const struct {
        uint8_t cause;
        bool lss;
        co_led_pattern_t pattern;
    } cases[] = {
        {CO_LED_CAUSE_CONFIG, false, CO_LED_BLINKING},
        {CO_LED_CAUSE_WARNING, false, CO_LED_SINGLE_FLASH},
        {CO_LED_CAUSE_ERROR_CONTROL, false, CO_LED_DOUBLE_FLASH},
        {CO_LED_CAUSE_SYNC, false, CO_LED_TRIPLE_FLASH},
        {CO_LED_CAUSE_EVENT_TIMER, false, CO_LED_QUADRUPLE_FLASH},
        {0, true, CO_LED_FLICKERING},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        world_t *w = world_new(false);
        if (cases[i].lss) {
            co_led_set_lss(&w->led, true);
        } else {
            co_led_set_cause(&w->led, cases[i].cause, true);
        }
        assert_int_equal(co_led_pattern(&w->led, CO_LED_ERROR), cases[i].pattern);
        run_until(w, 3000);
        check_timeline(&w->rec, CO_LED_ERROR, cases[i].pattern, 0, 0, 3000);
        world_free(w);
    }
}

/* Every run LED pattern from the NMT state; by default it runs one 200 ms
 * slot behind the error LED's (flickering: 50 ms, in antiphase). */
static void test_run_led_timelines(void **state)
{
    (void)state;
    static const struct {
        co_nmt_state_t nmt;
        bool lss;
        co_led_pattern_t pattern;
    } cases[] = {
        {CO_NMT_PRE_OPERATIONAL, false, CO_LED_BLINKING},
        {CO_NMT_STOPPED, false, CO_LED_SINGLE_FLASH},
        {CO_NMT_OPERATIONAL, true, CO_LED_FLICKERING},
    };
    for (int same = 0; same < 2; same++) {
        for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
            world_t *w = world_new(same != 0);
            co_led_set_nmt_state(&w->led, cases[i].nmt);
            co_led_set_lss(&w->led, cases[i].lss);
            assert_int_equal(co_led_pattern(&w->led, CO_LED_RUN), cases[i].pattern);
            run_until(w, 3000);
            uint32_t delay = cases[i].pattern == CO_LED_FLICKERING ? 50u : (same ? 0u : 200u);
            check_timeline(&w->rec, CO_LED_RUN, cases[i].pattern, delay, 0, 3000);
            world_free(w);
        }
    }
}

/* Steady patterns: one change each, no timer. */
static void test_steady_patterns_stop_the_timer(void **state)
{
    (void)state;
    world_t *w = world_new(false);
    co_timer_list_t *timers = co_line_timers(&w->line.line);
    co_led_set_nmt_state(&w->led, CO_NMT_OPERATIONAL);
    assert_int_equal(co_timer_list_next(timers), CO_TIME_NEVER);
    assert_int_equal(w->rec.count, 1);
    assert_true(w->rec.log[0].on);
    assert_int_equal(w->rec.log[0].pattern, CO_LED_ON);
    co_led_set_cause(&w->led, CO_LED_CAUSE_BUS_OFF, true);
    assert_int_equal(co_timer_list_next(timers), CO_TIME_NEVER);
    assert_int_equal(w->rec.count, 2);
    assert_int_equal(w->rec.log[1].which, CO_LED_ERROR);
    assert_true(w->rec.log[1].on);

    /* pre-operational blinks: the timer runs, armed for the next change only
     * (the run LED, a slot behind, lights at 200 ms), until operational again */
    at(w, 1000);
    co_led_set_nmt_state(&w->led, CO_NMT_PRE_OPERATIONAL);
    assert_int_equal(co_timer_list_next(timers), 1200 * TU_MS);
    at(w, 1200);
    assert_int_equal(co_timer_list_next(timers), 1400 * TU_MS);
    at(w, 1330);
    size_t before = w->rec.count;
    co_led_set_nmt_state(&w->led, CO_NMT_OPERATIONAL);
    assert_int_equal(co_timer_list_next(timers), CO_TIME_NEVER);
    assert_int_equal(w->rec.count, before + 1);
    assert_int_equal(w->rec.log[before].t_ms, 1330);
    assert_true(w->rec.log[before].on);
    assert_int_equal(w->rec.log[before].pattern, CO_LED_ON);
    run_until(w, 5000);
    assert_int_equal(w->rec.count, before + 1);

    /* without an indication nothing ticks, yet the state follows the timeline */
    co_led_set_indication(&w->led, NULL, NULL);
    co_led_set_cause(&w->led, CO_LED_CAUSE_BUS_OFF, false);
    co_led_set_cause(&w->led, CO_LED_CAUSE_WARNING, true);   /* at 5000: single flash */
    assert_int_equal(co_timer_list_next(timers), CO_TIME_NEVER);
    assert_true(co_led_is_on(&w->led, CO_LED_ERROR));
    co_line_set_time(&w->line.line, 5199 * TU_MS);
    assert_true(co_led_is_on(&w->led, CO_LED_ERROR));
    co_line_set_time(&w->line.line, 5200 * TU_MS);
    assert_false(co_led_is_on(&w->led, CO_LED_ERROR));
    co_line_set_time(&w->line.line, 6200 * TU_MS);
    assert_true(co_led_is_on(&w->led, CO_LED_ERROR));
    /* an indication set again arms the timer for the next change on the
     * timebase's grid: the flash lit at 6200 ends at 6400 */
    co_line_set_time(&w->line.line, 6210 * TU_MS);
    co_led_set_indication(&w->led, record, &w->rec);
    assert_int_equal(co_timer_list_next(timers), 6400 * TU_MS);
    world_free(w);
}

/* The timer wakes the line only where a LED changes: every 50 ms while
 * flickering, at each edge of a flash pattern (a quadruple flash: 8 edges
 * in 2.4 s). */
static void test_timer_fires_at_changes_only(void **state)
{
    (void)state;
    world_t *w = world_new(false);
    co_led_set_cause(&w->led, CO_LED_CAUSE_EVENT_TIMER, true);
    uint32_t fired = 0;
    for (uint64_t next; (next = co_timer_list_next(co_line_timers(&w->line.line))) <=
                        2400 * TU_MS;) {
        (void)co_line_process(&w->line.line, next);
        fired++;
    }
    assert_int_equal(fired, 8);   /* lit at 0 (told at once), then 8 edges up to 2400 */
    assert_int_equal(w->rec.count, 9);
    co_led_set_lss(&w->led, true);
    co_line_set_time(&w->line.line, 2400 * TU_MS);
    uint64_t next = co_timer_list_next(co_line_timers(&w->line.line));
    assert_int_equal(next, 2450 * TU_MS);
    world_free(w);
}

/* Precedence: the highest active cause wins; clearing it shows the next. */
static void test_precedence(void **state)
{
    (void)state;
    world_t *w = world_new(false);
    co_led_t *led = &w->led;
    co_led_set_cause(led, CO_LED_CAUSES, true);
    co_led_set_lss(led, true);
    co_led_set_nmt_state(led, CO_NMT_STOPPED);
    static const struct {
        uint8_t clear;          /* cleared before the check (0xFF: LSS off) */
        co_led_pattern_t error;
    } steps[] = {
        {0, CO_LED_ON},                                /* bus-off beats everything */
        {CO_LED_CAUSE_BUS_OFF, CO_LED_FLICKERING},     /* then LSS */
        {0xFF, CO_LED_QUADRUPLE_FLASH},
        {CO_LED_CAUSE_EVENT_TIMER, CO_LED_TRIPLE_FLASH},
        {CO_LED_CAUSE_SYNC, CO_LED_DOUBLE_FLASH},
        {CO_LED_CAUSE_ERROR_CONTROL, CO_LED_SINGLE_FLASH},
        {CO_LED_CAUSE_WARNING, CO_LED_BLINKING},
        {CO_LED_CAUSE_CONFIG, CO_LED_OFF},
    };
    for (size_t i = 0; i < sizeof steps / sizeof steps[0]; i++) {
        if (steps[i].clear == 0xFF) {
            assert_int_equal(co_led_pattern(led, CO_LED_RUN), CO_LED_FLICKERING);
            co_led_set_lss(led, false);
        } else if (steps[i].clear) {
            co_led_set_cause(led, steps[i].clear, false);
        }
        assert_int_equal(co_led_pattern(led, CO_LED_ERROR), steps[i].error);
    }
    /* run LED: LSS over NMT, then the NMT state */
    assert_int_equal(co_led_pattern(led, CO_LED_RUN), CO_LED_SINGLE_FLASH);
    co_led_set_nmt_state(led, CO_NMT_PRE_OPERATIONAL);
    assert_int_equal(co_led_pattern(led, CO_LED_RUN), CO_LED_BLINKING);
    co_led_set_nmt_state(led, CO_NMT_OPERATIONAL);
    assert_int_equal(co_led_pattern(led, CO_LED_RUN), CO_LED_ON);
    co_led_set_nmt_state(led, CO_NMT_INITIALISING);
    assert_int_equal(co_led_pattern(led, CO_LED_RUN), CO_LED_OFF);
    /* unknown cause bits change nothing */
    co_led_set_cause(led, 0xC0, true);
    assert_int_equal(co_led_causes(led), 0);
    assert_string_equal(co_led_pattern_name(CO_LED_TRIPLE_FLASH), "triple flash");
    world_free(w);
}

/* Both LEDs start their patterns together: blinking in the same slots when
 * asked, else alternating; never lit at once in the default mode, with any
 * pair of flash patterns, even when one starts later mid-slot. */
static void test_phase_alignment(void **state)
{
    (void)state;
    for (int same = 0; same < 2; same++) {
        world_t *w = world_new(same != 0);
        co_led_set_nmt_state(&w->led, CO_NMT_PRE_OPERATIONAL);
        co_led_set_cause(&w->led, CO_LED_CAUSE_CONFIG, true);
        run_until(w, 2000);
        check_timeline(&w->rec, CO_LED_ERROR, CO_LED_BLINKING, 0, 0, 2000);
        check_timeline(&w->rec, CO_LED_RUN, CO_LED_BLINKING, same ? 0 : 200, 0, 2000);
        world_free(w);
    }
    /* run LED single flash (stopped) from 0, error double flash from 1030 ms:
     * the error LED joins the running timebase (its flashes begin on the
     * 200 ms slots counted from 0), and the two are never lit together */
    world_t *w = world_new(false);
    co_led_set_nmt_state(&w->led, CO_NMT_STOPPED);
    at(w, 1030);
    co_led_set_cause(&w->led, CO_LED_CAUSE_ERROR_CONTROL, true);
    bool lit[2] = {false, false};
    size_t seen = 0;
    for (uint64_t t = 1030; t <= 6000; t += 10) {
        run_until(w, t);
        for (; seen < w->rec.count; seen++) {
            lit[w->rec.log[seen].which] = w->rec.log[seen].on;
            if (w->rec.log[seen].which == CO_LED_ERROR && w->rec.log[seen].t_ms > 1030) {
                assert_int_equal(w->rec.log[seen].t_ms % 200, 0);
            }
        }
        assert_false(lit[CO_LED_RUN] && lit[CO_LED_ERROR]);
    }
    /* replayed change by change (a GPIO driver's view): a LED going dark is
     * told before one lighting up in the same tick, so never both lit */
    lit[0] = lit[1] = false;
    for (size_t i = 0; i < w->rec.count; i++) {
        lit[w->rec.log[i].which] = w->rec.log[i].on;
        assert_false(lit[CO_LED_RUN] && lit[CO_LED_ERROR]);
    }
    /* the double flash as counted from the timebase: slots 8k and 8k + 2 */
    for (size_t i = 0; i < w->rec.count; i++) {
        const change_t *c = &w->rec.log[i];
        if (c->which == CO_LED_ERROR && c->on) {
            uint64_t slot = c->t_ms / 200;
            assert_true(slot % 8 == 0 || slot % 8 == 2);
        }
    }
    world_free(w);
}

/* A late co_line_process (here 730 ms late) does not fire a burst of ticks:
 * the LEDs jump to where the timeline is, and the next tick is on the grid. */
static void test_late_processing(void **state)
{
    (void)state;
    world_t *w = world_new(false);
    co_led_set_cause(&w->led, CO_LED_CAUSE_CONFIG, true);
    assert_int_equal(w->rec.count, 1);                    /* lit at 0 */
    assert_int_equal(co_timer_list_next(co_line_timers(&w->line.line)), 200 * TU_MS);
    (void)co_line_process(&w->line.line, 780 * TU_MS);   /* due at 200 */
    /* 780 ms: slot 3, dark: one change, not one per missed tick */
    assert_int_equal(w->rec.count, 2);
    assert_false(w->rec.log[1].on);
    assert_int_equal(co_timer_list_next(co_line_timers(&w->line.line)), 800 * TU_MS);
    (void)co_line_process(&w->line.line, 800 * TU_MS);
    assert_int_equal(w->rec.count, 3);
    assert_true(w->rec.log[2].on);
    world_free(w);
}

/* ------------------------------------------------------------ SYNC timeout */

typedef struct timeouts {
    uint64_t t_ms[16];
    bool value[16];
    int count;
    const co_line_t *line;
} timeouts_t;

static void on_timeout(co_sync_t *sync, bool timed_out, void *user)
{
    (void)sync;
    timeouts_t *t = user;
    assert_true(t->count < 16);
    t->t_ms[t->count] = co_line_now(t->line) / TU_MS;
    t->value[t->count++] = timed_out;
}

static void sync_frame_at(tu_line_t *l, uint64_t t_ms)
{
    co_frame_t f = {.id = 0x80, .len = 0};
    for (uint64_t next; (next = co_timer_list_next(co_line_timers(&l->line))) <= t_ms * TU_MS;) {
        (void)co_line_process(&l->line, next);
    }
    assert_true(co_line_receive(&l->line, &f));
    (void)co_line_process(&l->line, t_ms * TU_MS);
}

static void run_line(tu_line_t *l, uint64_t t_ms)
{
    for (uint64_t next; (next = co_timer_list_next(co_line_timers(&l->line))) <= t_ms * TU_MS;) {
        (void)co_line_process(&l->line, next);
    }
    co_line_set_time(&l->line, t_ms * TU_MS);
}

/* The SYNC consumer's monitoring: from the first SYNC, 1.5 x 0x1006; over
 * at the next SYNC, when the node leaves pre-operational/operational or the
 * period changes; none for a producer or without 0x1006. */
static void test_sync_consumer_timeout(void **state)
{
    (void)state;
    tu_line_t *l = calloc(1, sizeof *l);
    co_sync_t *sync = calloc(1, sizeof *sync);
    timeouts_t t = {.line = &l->line};
    assert_non_null(l);
    assert_non_null(sync);
    tu_line_init(l, CO_MODE_CLASSIC, false);
    co_line_set_time(&l->line, 0);
    assert_true(co_sync_init(sync, &l->line));
    co_sync_config_t consume = {.cob_id = 0x80, .period_us = 100000};
    co_sync_configure(sync, &consume);
    co_sync_set_nmt_state(sync, CO_NMT_PRE_OPERATIONAL);
    co_sync_set_timeout_indication(sync, on_timeout, &t);
    run_line(l, 1000);
    assert_int_equal(t.count, 0);              /* nothing before the first SYNC */
    sync_frame_at(l, 1000);
    sync_frame_at(l, 1140);                     /* in time */
    run_line(l, 1289);
    assert_int_equal(t.count, 0);
    run_line(l, 1290);                          /* 1140 + 150 */
    assert_int_equal(t.count, 1);
    assert_int_equal(t.t_ms[0], 1290);
    assert_true(t.value[0]);
    run_line(l, 3000);
    assert_int_equal(t.count, 1);               /* told once */
    sync_frame_at(l, 3000);
    assert_int_equal(t.count, 2);
    assert_false(t.value[1]);
    run_line(l, 3150);
    assert_int_equal(t.count, 3);
    /* stopped: monitoring ends, the timeout with it */
    co_sync_set_nmt_state(sync, CO_NMT_STOPPED);
    assert_int_equal(t.count, 4);
    assert_false(t.value[3]);
    co_sync_set_nmt_state(sync, CO_NMT_OPERATIONAL);
    run_line(l, 5000);
    assert_int_equal(t.count, 4);
    /* a new period restarts monitoring at the next SYNC */
    sync_frame_at(l, 5000);
    consume.period_us = 200000;
    co_sync_configure(sync, &consume);
    run_line(l, 5400);
    assert_int_equal(t.count, 4);
    sync_frame_at(l, 5400);
    run_line(l, 5700);
    assert_int_equal(t.count, 5);
    assert_int_equal(t.t_ms[4], 5700);
    /* a producer does not monitor; changing to one ends the timeout */
    co_sync_config_t produce = {.cob_id = 0x80 | CO_SYNC_PRODUCER_BIT, .period_us = 100000};
    co_sync_configure(sync, &produce);
    assert_int_equal(t.count, 6);
    assert_false(t.value[5]);
    run_line(l, 8000);
    assert_int_equal(t.count, 6);
    co_sync_deinit(sync);
    free(sync);
    free(l);
}

/* ------------------------------------------------------------ the stack */

typedef struct stack_fx {
    tu_bus_t tb;
    tu_line_t dev_line;
    tu_line_t peer_line;
    co_stack_t dev;
    co_stack_t peer;
    co_stack_arena_t dev_arena;
    co_stack_arena_t peer_arena;
    unsigned char dev_memory[16 * 1024];
    unsigned char peer_memory[16 * 1024];
    recorder_t rec;
} stack_fx_t;

/* The last change of a LED in the log. */
static const change_t *last_change(const recorder_t *r, co_led_which_t which)
{
    for (size_t i = r->count; i-- > 0;) {
        if (r->log[i].which == which) {
            return &r->log[i];
        }
    }
    return NULL;
}

/* A node built by co_stack with its LEDs: NMT commands from another node on
 * the bus, a comm event of the line, a heartbeat lost: the patterns follow
 * without the application calling co_led. */
static void test_stack_wiring(void **state)
{
    (void)state;
    stack_fx_t *fx = calloc(1, sizeof *fx);
    assert_non_null(fx);
    tu_bus_init(&fx->tb, CO_MODE_CLASSIC, false);
    tu_bus_add_line(&fx->tb, &fx->dev_line);
    tu_bus_add_line(&fx->tb, &fx->peer_line);
    fx->rec.line = &fx->dev_line.line;
    co_stack_arena_init(&fx->dev_arena, fx->dev_memory, sizeof fx->dev_memory);
    co_stack_arena_init(&fx->peer_arena, fx->peer_memory, sizeof fx->peer_memory);
    co_stack_line_config_t lc = {.heartbeat_entries = 4};
    assert_int_equal(co_stack_init(&fx->dev, &fx->dev_line.line, &lc,
                                   co_stack_arena_allocator(&fx->dev_arena)), CO_STACK_OK);
    assert_int_equal(co_stack_init(&fx->peer, &fx->peer_line.line, &lc,
                                   co_stack_arena_allocator(&fx->peer_arena)), CO_STACK_OK);

    /* LEDs take no memory: the need is the same with and without */
    co_stack_node_config_t plain = {.node_id = NODE, .heartbeat_ms = 100};
    co_stack_node_config_t nc = {.node_id = NODE, .heartbeat_ms = 100, .leds = true,
                                 .led_changed = record_stack, .user = &fx->rec};
    assert_int_equal(co_stack_node_need(&fx->dev_line.line, &nc),
                     co_stack_node_need(&fx->dev_line.line, &plain));
    /* an indication without leds is refused, naming the part */
    co_stack_node_config_t bad = plain;
    bad.led_changed = record_stack;
    assert_int_equal(co_stack_node_init(&fx->dev, &bad), CO_STACK_ERR_ARGUMENT);
    assert_int_equal(co_stack_failed_part(&fx->dev), CO_STACK_PART_LED);
    assert_string_equal(co_stack_part_name(CO_STACK_PART_LED), "LED indicators");
    assert_null(co_stack_led(&fx->dev));
    size_t used = fx->dev_arena.used;
    assert_int_equal(co_stack_node_init(&fx->dev, &nc), CO_STACK_OK);
    assert_int_equal(fx->dev_arena.used - used, co_stack_node_need(&fx->dev_line.line, &nc));
    co_led_t *led = co_stack_led(&fx->dev);
    assert_non_null(led);
    assert_int_equal(co_led_pattern(led, CO_LED_RUN), CO_LED_OFF);

    co_stack_node_config_t pc = {.node_id = PEER, .heartbeat_ms = 100};
    assert_int_equal(co_stack_node_init(&fx->peer, &pc), CO_STACK_OK);
    /* the device consumes the peer's heartbeat: 250 ms */
    assert_int_equal(co_hb_consumer_set_entry(co_stack_hb_consumer(&fx->dev), 0,
                                              ((uint32_t)PEER << 16) | 250u), CO_HB_CONFIG_OK);
    co_line_set_time(&fx->dev_line.line, 0);
    assert_int_equal(co_stack_boot(&fx->dev), CO_STACK_OK);
    assert_int_equal(co_stack_boot(&fx->peer), CO_STACK_OK);
    tu_run_until(&fx->tb, 1000 * TU_MS);
    assert_int_equal(co_led_pattern(led, CO_LED_RUN), CO_LED_BLINKING);
    check_timeline(&fx->rec, CO_LED_RUN, CO_LED_BLINKING, 200, 0, 1000);

    /* the peer (NMT master) starts the device: run LED on, the tick stops */
    co_line_set_time(&fx->peer_line.line, fx->tb.now);
    assert_true(co_nmt_master_send(&fx->peer_line.line, NULL, CO_NMT_CMD_START, NODE, false));
    tu_step(&fx->tb, fx->tb.now);
    tu_run_until(&fx->tb, 1010 * TU_MS);
    const change_t *c = last_change(&fx->rec, CO_LED_RUN);
    assert_int_equal(c->t_ms, 1000);
    assert_true(c->on);
    assert_int_equal(c->pattern, CO_LED_ON);
    assert_int_equal(co_led_pattern(led, CO_LED_ERROR), CO_LED_OFF);

    /* stopped: single flash */
    co_line_set_time(&fx->peer_line.line, fx->tb.now);
    assert_true(co_nmt_master_send(&fx->peer_line.line, NULL, CO_NMT_CMD_STOP, NODE, false));
    tu_step(&fx->tb, fx->tb.now);
    tu_run_until(&fx->tb, 1020 * TU_MS);
    assert_int_equal(co_led_pattern(led, CO_LED_RUN), CO_LED_SINGLE_FLASH);
    co_line_set_time(&fx->peer_line.line, fx->tb.now);
    assert_true(co_nmt_master_send(&fx->peer_line.line, NULL, CO_NMT_CMD_START, NODE, false));
    tu_step(&fx->tb, fx->tb.now);
    tu_run_until(&fx->tb, 1030 * TU_MS);
    assert_int_equal(co_led_pattern(led, CO_LED_RUN), CO_LED_ON);

    /* the driver says bus-off: red on; error active again: off */
    co_line_comm_event(&fx->dev_line.line, CO_COMM_BUS_OFF);
    c = last_change(&fx->rec, CO_LED_ERROR);
    assert_true(c->on);
    assert_int_equal(c->pattern, CO_LED_ON);
    co_line_comm_event(&fx->dev_line.line, CO_COMM_ERROR_ACTIVE);
    assert_int_equal(co_led_pattern(led, CO_LED_ERROR), CO_LED_OFF);
    assert_false(last_change(&fx->rec, CO_LED_ERROR)->on);
    /* bus-off is an error-class event: 0x1029 absent = pre-operational */
    assert_int_equal(co_led_pattern(led, CO_LED_RUN), CO_LED_BLINKING);
    co_line_comm_event(&fx->dev_line.line, CO_COMM_ERROR_PASSIVE);
    assert_int_equal(co_led_pattern(led, CO_LED_ERROR), CO_LED_SINGLE_FLASH);
    co_line_comm_event(&fx->dev_line.line, CO_COMM_ERROR_ACTIVE);
    co_line_comm_event(&fx->dev_line.line, CO_COMM_ERROR_WARNING);
    assert_int_equal(co_led_pattern(led, CO_LED_ERROR), CO_LED_SINGLE_FLASH);
    co_line_comm_event(&fx->dev_line.line, CO_COMM_ERROR_ACTIVE);
    assert_int_equal(co_led_pattern(led, CO_LED_ERROR), CO_LED_OFF);

    /* the peer goes silent: heartbeat lost after 250 ms, double flash;
     * it comes back: off */
    co_stack_node_deinit(&fx->peer);
    tu_run_until(&fx->tb, 1400 * TU_MS);
    assert_int_equal(co_led_pattern(led, CO_LED_ERROR), CO_LED_DOUBLE_FLASH);
    assert_true(co_led_causes(led) & CO_LED_CAUSE_ERROR_CONTROL);
    assert_int_equal(co_stack_node_init(&fx->peer, &pc), CO_STACK_OK);
    co_line_set_time(&fx->peer_line.line, fx->tb.now);
    assert_int_equal(co_stack_boot(&fx->peer), CO_STACK_OK);
    tu_run_until(&fx->tb, 1700 * TU_MS);
    assert_int_equal(co_led_pattern(led, CO_LED_ERROR), CO_LED_OFF);

    /* SYNC: the peer produces every 100 ms, the device consumes with 0x1006
     * = 100 ms; the peer stops: 150 ms after its last SYNC the error LED
     * triple-flashes; SYNC again: off. A wrong length is a SYNC error too. */
    co_sync_config_t produce = {.cob_id = 0x80u | CO_SYNC_PRODUCER_BIT, .period_us = 100000};
    co_sync_config_t consume = {.cob_id = 0x80u, .period_us = 100000};
    co_sync_configure(co_stack_sync(&fx->dev), &consume);
    co_line_set_time(&fx->peer_line.line, fx->tb.now);
    co_sync_configure(co_stack_sync(&fx->peer), &produce);
    tu_run_until(&fx->tb, 2000 * TU_MS);
    assert_int_equal(co_led_pattern(led, CO_LED_ERROR), CO_LED_OFF);
    uint64_t last_sync = 1700 + 300;   /* the peer's SYNCs: 1800, 1900, 2000 */
    produce.period_us = 0;
    co_sync_configure(co_stack_sync(&fx->peer), &produce);
    tu_run_until(&fx->tb, (last_sync + 149) * TU_MS);
    assert_int_equal(co_led_pattern(led, CO_LED_ERROR), CO_LED_OFF);
    tu_run_until(&fx->tb, (last_sync + 150) * TU_MS);
    assert_int_equal(co_led_pattern(led, CO_LED_ERROR), CO_LED_TRIPLE_FLASH);
    c = last_change(&fx->rec, CO_LED_ERROR);
    assert_int_equal(c->t_ms, last_sync + 150);
    assert_int_equal(co_led_causes(led), CO_LED_CAUSE_SYNC);
    produce.period_us = 100000;
    co_line_set_time(&fx->peer_line.line, fx->tb.now);
    co_sync_configure(co_stack_sync(&fx->peer), &produce);
    tu_run_until(&fx->tb, (last_sync + 260) * TU_MS);
    assert_int_equal(co_led_pattern(led, CO_LED_ERROR), CO_LED_OFF);
    /* a SYNC of 2 bytes (this node without OD takes 0 or 1: a tool's rule) */
    produce.period_us = 0;
    co_sync_configure(co_stack_sync(&fx->peer), &produce);
    co_line_set_time(&fx->peer_line.line, fx->tb.now);
    assert_true(co_line_send(&fx->peer_line.line, 0x80, (const uint8_t[]){1, 2}, 2));
    tu_step(&fx->tb, fx->tb.now);
    assert_int_equal(co_led_pattern(led, CO_LED_ERROR), CO_LED_TRIPLE_FLASH);
    co_sync_configure(co_stack_sync(&fx->dev), &(co_sync_config_t){.cob_id = 0x80u});
    assert_true(co_line_send(&fx->peer_line.line, 0x80, NULL, 0));
    tu_step(&fx->tb, fx->tb.now);
    assert_int_equal(co_led_pattern(led, CO_LED_ERROR), CO_LED_OFF);

    /* LSS (the slave calls this): both flicker */
    co_led_set_lss(led, true);
    assert_int_equal(co_led_pattern(led, CO_LED_RUN), CO_LED_FLICKERING);
    assert_int_equal(co_led_pattern(led, CO_LED_ERROR), CO_LED_FLICKERING);
    co_led_set_lss(led, false);

    /* the node goes: its LED timer with it */
    co_stack_node_deinit(&fx->dev);
    assert_null(co_stack_led(&fx->dev));
    size_t count = fx->rec.count;
    tu_run_until(&fx->tb, 3000 * TU_MS);
    assert_int_equal(fx->rec.count, count);
    co_stack_deinit(&fx->dev);
    co_stack_deinit(&fx->peer);
    free(fx);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_error_led_timelines),
        cmocka_unit_test(test_run_led_timelines),
        cmocka_unit_test(test_steady_patterns_stop_the_timer),
        cmocka_unit_test(test_timer_fires_at_changes_only),
        cmocka_unit_test(test_precedence),
        cmocka_unit_test(test_phase_alignment),
        cmocka_unit_test(test_late_processing),
        cmocka_unit_test(test_sync_consumer_timeout),
        cmocka_unit_test(test_stack_wiring),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
