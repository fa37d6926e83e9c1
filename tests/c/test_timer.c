/* co_timer: sorted timer list with caller-owned timers. */
#include "test_util.h"

#define MAX_FIRED 64

typedef struct rec {
    int ids[MAX_FIRED];
    uint64_t at[MAX_FIRED];
    int count;
} rec_t;

typedef struct tt tt_t;
struct tt {
    co_timer_t timer;
    int id;
    rec_t *rec;
    co_timer_list_t *list;
    /* What the callback does after recording itself. */
    enum { ACT_NONE, ACT_REARM_SELF, ACT_CANCEL_OTHER, ACT_START_OTHER } action;
    uint64_t arg;             /* re-arm / start deadline, absolute */
    int64_t period;           /* ACT_REARM_SELF with period != 0: deadline += period */
    tt_t *other;
};

static void record_fn(co_timer_t *timer, uint64_t now_us, void *user)
{
    tt_t *t = user;
    assert_ptr_equal(timer, &t->timer);
    assert_true(t->rec->count < MAX_FIRED);
    /* a firing timer is no longer armed unless the callback re-arms it */
    assert_false(co_timer_is_armed(timer));
    t->rec->ids[t->rec->count] = t->id;
    t->rec->at[t->rec->count] = now_us;
    t->rec->count++;
    switch (t->action) {
    case ACT_NONE:
        break;
    case ACT_REARM_SELF:
        if (t->period != 0)
            co_timer_start(t->list, timer, timer->deadline_us + (uint64_t)t->period);
        else
            co_timer_start(t->list, timer, t->arg);
        break;
    case ACT_CANCEL_OTHER:
        co_timer_cancel(t->list, &t->other->timer);
        break;
    case ACT_START_OTHER:
        co_timer_start(t->list, &t->other->timer, t->arg);
        break;
    }
}

static void tt_init(tt_t *t, int id, rec_t *rec, co_timer_list_t *list)
{
    memset(t, 0, sizeof *t);
    t->id = id;
    t->rec = rec;
    t->list = list;
    co_timer_init(&t->timer, record_fn, t);
}

static void assert_fired(const rec_t *rec, const int *ids, int n)
{
    int i;
    if (rec->count != n)
        fail_msg("fired %d timers, expected %d", rec->count, n);
    for (i = 0; i < n; i++)
        if (rec->ids[i] != ids[i])
            fail_msg("firing #%d was timer %d, expected %d", i, rec->ids[i], ids[i]);
}

/* ------------------------------------------------------------ basics */

static void test_empty_list_next_is_never(void **state)
{
    co_timer_list_t list;
    (void)state;
    co_timer_list_init(&list);
    assert_true(co_timer_list_next(&list) == CO_TIME_NEVER);
    assert_int_equal(co_timer_list_run(&list, 1000000), 0);
    assert_int_equal(list.armed, 0);
}

static void test_init_timer_is_unarmed(void **state)
{
    co_timer_t t;
    (void)state;
    memset(&t, 0xFF, sizeof t);
    co_timer_init(&t, NULL, NULL);
    assert_false(co_timer_is_armed(&t));
}

static void test_fires_in_deadline_order(void **state)
{
    co_timer_list_t list;
    rec_t rec = {{0}, {0}, 0};
    tt_t a, b, c;
    const int expected[] = {2, 3, 1};
    (void)state;
    co_timer_list_init(&list);
    tt_init(&a, 1, &rec, &list);
    tt_init(&b, 2, &rec, &list);
    tt_init(&c, 3, &rec, &list);
    co_timer_start(&list, &a.timer, 30);
    co_timer_start(&list, &b.timer, 10);
    co_timer_start(&list, &c.timer, 20);
    assert_int_equal(list.armed, 3);
    assert_int_equal(co_timer_list_run(&list, 100), 3);
    assert_fired(&rec, expected, 3);
    assert_int_equal(rec.at[0], 100);   /* callbacks get the run's now */
    assert_int_equal(list.armed, 0);
    assert_true(co_timer_list_next(&list) == CO_TIME_NEVER);
}

static void test_only_due_timers_fire(void **state)
{
    co_timer_list_t list;
    rec_t rec = {{0}, {0}, 0};
    tt_t a, b;
    const int first[] = {1}, both[] = {1, 2};
    (void)state;
    co_timer_list_init(&list);
    tt_init(&a, 1, &rec, &list);
    tt_init(&b, 2, &rec, &list);
    co_timer_start(&list, &a.timer, 10);
    co_timer_start(&list, &b.timer, 20);
    assert_int_equal(co_timer_list_run(&list, 9), 0);
    assert_int_equal(co_timer_list_run(&list, 19), 1);
    assert_fired(&rec, first, 1);
    assert_true(co_timer_is_armed(&b.timer));
    assert_int_equal(co_timer_list_next(&list), 20);
    assert_int_equal(co_timer_list_run(&list, 20), 1);   /* deadline == now fires */
    assert_fired(&rec, both, 2);
}

static void test_deadline_zero_fires_at_zero(void **state)
{
    co_timer_list_t list;
    rec_t rec = {{0}, {0}, 0};
    tt_t a;
    (void)state;
    co_timer_list_init(&list);
    tt_init(&a, 1, &rec, &list);
    co_timer_start(&list, &a.timer, 0);
    assert_int_equal(co_timer_list_next(&list), 0);
    assert_int_equal(co_timer_list_run(&list, 0), 1);
}

static void test_equal_deadlines_fire_in_arm_order(void **state)
{
    co_timer_list_t list;
    rec_t rec = {{0}, {0}, 0};
    tt_t t[6];
    const int expected[] = {0, 4, 2, 5, 1, 3};
    int i;
    (void)state;
    co_timer_list_init(&list);
    for (i = 0; i < 6; i++)
        tt_init(&t[i], i, &rec, &list);
    /* deadlines 10: arm order 0, 4, 2; deadline 20: arm order 5, 1, 3 */
    co_timer_start(&list, &t[5].timer, 20);
    co_timer_start(&list, &t[0].timer, 10);
    co_timer_start(&list, &t[1].timer, 20);
    co_timer_start(&list, &t[4].timer, 10);
    co_timer_start(&list, &t[2].timer, 10);
    co_timer_start(&list, &t[3].timer, 20);
    assert_int_equal(co_timer_list_run(&list, 20), 6);
    assert_fired(&rec, expected, 6);
}

static void test_restart_with_same_deadline_goes_behind_equal_ones(void **state)
{
    co_timer_list_t list;
    rec_t rec = {{0}, {0}, 0};
    tt_t a, b, c;
    const int expected[] = {2, 3, 1};
    (void)state;
    co_timer_list_init(&list);
    tt_init(&a, 1, &rec, &list);
    tt_init(&b, 2, &rec, &list);
    tt_init(&c, 3, &rec, &list);
    co_timer_start(&list, &a.timer, 10);
    co_timer_start(&list, &b.timer, 10);
    co_timer_start(&list, &c.timer, 10);
    co_timer_start(&list, &a.timer, 10);    /* armed again: now the last one */
    assert_int_equal(list.armed, 3);
    assert_int_equal(co_timer_list_run(&list, 10), 3);
    assert_fired(&rec, expected, 3);
}

/* ------------------------------------------------------------ cancel */

static void cancel_case(int which, const int *expected)
{
    co_timer_list_t list;
    rec_t rec = {{0}, {0}, 0};
    tt_t t[3];
    int i;
    co_timer_list_init(&list);
    for (i = 0; i < 3; i++) {
        tt_init(&t[i], i, &rec, &list);
        co_timer_start(&list, &t[i].timer, 10u * (unsigned)(i + 1));
    }
    co_timer_cancel(&list, &t[which].timer);
    assert_false(co_timer_is_armed(&t[which].timer));
    assert_int_equal(list.armed, 2);
    assert_int_equal(co_timer_list_next(&list), which == 0 ? 20 : 10);
    assert_int_equal(co_timer_list_run(&list, 100), 2);
    assert_fired(&rec, expected, 2);
    assert_null(list.head);
    assert_null(list.tail);
}

static void test_cancel_head(void **state)
{
    const int expected[] = {1, 2};
    (void)state;
    cancel_case(0, expected);
}

static void test_cancel_middle(void **state)
{
    const int expected[] = {0, 2};
    (void)state;
    cancel_case(1, expected);
}

static void test_cancel_tail(void **state)
{
    const int expected[] = {0, 1};
    (void)state;
    cancel_case(2, expected);
}

static void test_cancel_unarmed_is_harmless(void **state)
{
    co_timer_list_t list;
    rec_t rec = {{0}, {0}, 0};
    tt_t a, b;
    const int expected[] = {2};
    (void)state;
    co_timer_list_init(&list);
    tt_init(&a, 1, &rec, &list);
    tt_init(&b, 2, &rec, &list);
    co_timer_cancel(&list, &a.timer);             /* never armed */
    co_timer_start(&list, &b.timer, 10);
    co_timer_cancel(&list, &a.timer);
    assert_int_equal(list.armed, 1);
    assert_int_equal(co_timer_list_next(&list), 10);
    co_timer_start(&list, &a.timer, 5);
    co_timer_cancel(&list, &a.timer);
    co_timer_cancel(&list, &a.timer);             /* twice */
    assert_int_equal(list.armed, 1);
    assert_int_equal(co_timer_list_run(&list, 100), 1);
    assert_fired(&rec, expected, 1);
}

static void test_cancel_only_timer_empties_list(void **state)
{
    co_timer_list_t list;
    rec_t rec = {{0}, {0}, 0};
    tt_t a;
    (void)state;
    co_timer_list_init(&list);
    tt_init(&a, 1, &rec, &list);
    co_timer_start(&list, &a.timer, 10);
    co_timer_cancel(&list, &a.timer);
    assert_null(list.head);
    assert_null(list.tail);
    assert_int_equal(list.armed, 0);
    assert_true(co_timer_list_next(&list) == CO_TIME_NEVER);
    assert_int_equal(co_timer_list_run(&list, 100), 0);
}

/* ------------------------------------------------------------ restart */

static void test_restart_later_moves_timer_back(void **state)
{
    co_timer_list_t list;
    rec_t rec = {{0}, {0}, 0};
    tt_t a, b;
    const int expected[] = {2, 1};
    (void)state;
    co_timer_list_init(&list);
    tt_init(&a, 1, &rec, &list);
    tt_init(&b, 2, &rec, &list);
    co_timer_start(&list, &a.timer, 10);
    co_timer_start(&list, &b.timer, 20);
    co_timer_start(&list, &a.timer, 30);
    assert_int_equal(list.armed, 2);
    assert_int_equal(co_timer_list_next(&list), 20);
    assert_int_equal(a.timer.deadline_us, 30);
    assert_int_equal(co_timer_list_run(&list, 25), 1);
    assert_int_equal(co_timer_list_run(&list, 30), 1);
    assert_fired(&rec, expected, 2);
    assert_int_equal(rec.at[1], 30);
}

static void test_restart_earlier_moves_timer_forward(void **state)
{
    co_timer_list_t list;
    rec_t rec = {{0}, {0}, 0};
    tt_t a, b, c;
    const int expected[] = {3, 1, 2};
    (void)state;
    co_timer_list_init(&list);
    tt_init(&a, 1, &rec, &list);
    tt_init(&b, 2, &rec, &list);
    tt_init(&c, 3, &rec, &list);
    co_timer_start(&list, &a.timer, 10);
    co_timer_start(&list, &b.timer, 20);
    co_timer_start(&list, &c.timer, 30);
    co_timer_start(&list, &c.timer, 5);
    assert_int_equal(list.armed, 3);
    assert_int_equal(co_timer_list_next(&list), 5);
    assert_int_equal(co_timer_list_run(&list, 100), 3);
    assert_fired(&rec, expected, 3);
}

/* ------------------------------------------------------------ callbacks */

static void test_periodic_rearm_from_callback(void **state)
{
    co_timer_list_t list;
    rec_t rec = {{0}, {0}, 0};
    tt_t a;
    (void)state;
    co_timer_list_init(&list);
    tt_init(&a, 1, &rec, &list);
    a.action = ACT_REARM_SELF;
    a.period = 10;
    co_timer_start(&list, &a.timer, 10);
    assert_int_equal(co_timer_list_run(&list, 10), 1);
    assert_true(co_timer_is_armed(&a.timer));
    assert_int_equal(co_timer_list_next(&list), 20);
    assert_int_equal(co_timer_list_run(&list, 15), 0);
    assert_int_equal(co_timer_list_run(&list, 20), 1);
    assert_int_equal(co_timer_list_next(&list), 30);
    assert_int_equal(rec.count, 2);
    assert_int_equal(list.armed, 1);
}

static void test_rearm_at_or_before_now_does_not_spin(void **state)
{
    co_timer_list_t list;
    rec_t rec = {{0}, {0}, 0};
    tt_t a;
    (void)state;
    co_timer_list_init(&list);
    tt_init(&a, 1, &rec, &list);
    a.action = ACT_REARM_SELF;
    a.period = 0;
    a.arg = 50;                 /* in the past at run(100) */
    co_timer_start(&list, &a.timer, 50);
    assert_int_equal(co_timer_list_run(&list, 100), 1);
    assert_int_equal(rec.count, 1);
    assert_true(co_timer_is_armed(&a.timer));
    assert_int_equal(co_timer_list_next(&list), 50);
    assert_int_equal(co_timer_list_run(&list, 100), 1);   /* fires again next call */
    assert_int_equal(rec.count, 2);
}

static void test_rearm_at_exactly_now_does_not_spin(void **state)
{
    co_timer_list_t list;
    rec_t rec = {{0}, {0}, 0};
    tt_t a;
    (void)state;
    co_timer_list_init(&list);
    tt_init(&a, 1, &rec, &list);
    a.action = ACT_REARM_SELF;
    a.period = 0;
    a.arg = 100;
    co_timer_start(&list, &a.timer, 100);
    assert_int_equal(co_timer_list_run(&list, 100), 1);
    assert_int_equal(co_timer_list_next(&list), 100);
    assert_int_equal(co_timer_list_run(&list, 100), 1);
    assert_int_equal(rec.count, 2);
}

/* The same with another (not due) timer armed: the "fires again only on the
 * next call" rule must not depend on how many other timers are armed. */
static void test_rearm_at_now_fires_once_with_other_timers_armed(void **state)
{
    co_timer_list_t list;
    rec_t rec = {{0}, {0}, 0};
    tt_t a, far1, far2;
    (void)state;
    co_timer_list_init(&list);
    tt_init(&a, 1, &rec, &list);
    tt_init(&far1, 2, &rec, &list);
    tt_init(&far2, 3, &rec, &list);
    a.action = ACT_REARM_SELF;
    a.period = 0;
    a.arg = 100;
    co_timer_start(&list, &a.timer, 100);
    co_timer_start(&list, &far1.timer, 5000);
    co_timer_start(&list, &far2.timer, 6000);
    assert_int_equal(co_timer_list_run(&list, 100), 1);
    assert_int_equal(rec.count, 1);
    assert_true(co_timer_is_armed(&a.timer));
}

static void test_timer_armed_by_callback_at_now_waits_with_other_timers_armed(void **state)
{
    co_timer_list_t list;
    rec_t rec = {{0}, {0}, 0};
    tt_t a, b, far;
    const int expected[] = {1};
    (void)state;
    co_timer_list_init(&list);
    tt_init(&a, 1, &rec, &list);
    tt_init(&b, 2, &rec, &list);
    tt_init(&far, 3, &rec, &list);
    a.action = ACT_START_OTHER;
    a.other = &b;
    a.arg = 100;
    co_timer_start(&list, &a.timer, 100);
    co_timer_start(&list, &far.timer, 5000);
    assert_int_equal(co_timer_list_run(&list, 100), 1);
    assert_fired(&rec, expected, 1);
    assert_true(co_timer_is_armed(&b.timer));
}

static void test_timers_arming_each_other_at_now_do_not_spin(void **state)
{
    co_timer_list_t list;
    rec_t rec = {{0}, {0}, 0};
    tt_t a, b;
    const int expected[] = {1};
    (void)state;
    co_timer_list_init(&list);
    tt_init(&a, 1, &rec, &list);
    tt_init(&b, 2, &rec, &list);
    a.action = ACT_START_OTHER;
    a.other = &b;
    a.arg = 100;
    b.action = ACT_START_OTHER;
    b.other = &a;
    b.arg = 100;
    co_timer_start(&list, &a.timer, 100);
    /* b is armed (at now) by a's callback: it waits for the next call. */
    assert_int_equal(co_timer_list_run(&list, 100), 1);
    assert_fired(&rec, expected, 1);
    assert_true(co_timer_is_armed(&b.timer));
    assert_int_equal(co_timer_list_run(&list, 100), 1);
    assert_int_equal(rec.count, 2);
    assert_int_equal(rec.ids[1], 2);
    assert_true(co_timer_is_armed(&a.timer));
}

static void test_rearm_into_future_fires_later(void **state)
{
    co_timer_list_t list;
    rec_t rec = {{0}, {0}, 0};
    tt_t a, b;
    const int expected[] = {1, 2, 1};
    (void)state;
    co_timer_list_init(&list);
    tt_init(&a, 1, &rec, &list);
    tt_init(&b, 2, &rec, &list);
    a.action = ACT_REARM_SELF;
    a.arg = 25;
    co_timer_start(&list, &a.timer, 10);
    co_timer_start(&list, &b.timer, 20);
    assert_int_equal(co_timer_list_run(&list, 20), 2);
    a.action = ACT_NONE;
    assert_int_equal(co_timer_list_next(&list), 25);
    assert_int_equal(co_timer_list_run(&list, 30), 1);
    assert_fired(&rec, expected, 3);
}

static void test_cancel_other_due_timer_from_callback(void **state)
{
    co_timer_list_t list;
    rec_t rec = {{0}, {0}, 0};
    tt_t a, b, c;
    const int expected[] = {1, 3};
    (void)state;
    co_timer_list_init(&list);
    tt_init(&a, 1, &rec, &list);
    tt_init(&b, 2, &rec, &list);
    tt_init(&c, 3, &rec, &list);
    a.action = ACT_CANCEL_OTHER;
    a.other = &b;
    co_timer_start(&list, &a.timer, 10);
    co_timer_start(&list, &b.timer, 10);
    co_timer_start(&list, &c.timer, 15);
    assert_int_equal(co_timer_list_run(&list, 20), 2);
    assert_fired(&rec, expected, 2);
    assert_false(co_timer_is_armed(&b.timer));
    assert_int_equal(list.armed, 0);
}

static void test_cancel_self_from_callback_is_harmless(void **state)
{
    co_timer_list_t list;
    rec_t rec = {{0}, {0}, 0};
    tt_t a, b;
    const int expected[] = {1, 2};
    (void)state;
    co_timer_list_init(&list);
    tt_init(&a, 1, &rec, &list);
    tt_init(&b, 2, &rec, &list);
    a.action = ACT_CANCEL_OTHER;
    a.other = &a;
    co_timer_start(&list, &a.timer, 10);
    co_timer_start(&list, &b.timer, 10);
    assert_int_equal(co_timer_list_run(&list, 10), 2);
    assert_fired(&rec, expected, 2);
    assert_int_equal(list.armed, 0);
}

static void test_restart_other_due_timer_later_from_callback(void **state)
{
    co_timer_list_t list;
    rec_t rec = {{0}, {0}, 0};
    tt_t a, b;
    const int expected[] = {1};
    (void)state;
    co_timer_list_init(&list);
    tt_init(&a, 1, &rec, &list);
    tt_init(&b, 2, &rec, &list);
    a.action = ACT_START_OTHER;
    a.other = &b;
    a.arg = 50;
    co_timer_start(&list, &a.timer, 10);
    co_timer_start(&list, &b.timer, 10);
    assert_int_equal(co_timer_list_run(&list, 20), 1);
    assert_fired(&rec, expected, 1);
    assert_int_equal(co_timer_list_next(&list), 50);
}

static void test_next_deadline_follows_head(void **state)
{
    co_timer_list_t list;
    rec_t rec = {{0}, {0}, 0};
    tt_t a, b, c;
    (void)state;
    co_timer_list_init(&list);
    tt_init(&a, 1, &rec, &list);
    tt_init(&b, 2, &rec, &list);
    tt_init(&c, 3, &rec, &list);
    co_timer_start(&list, &a.timer, 300);
    assert_int_equal(co_timer_list_next(&list), 300);
    co_timer_start(&list, &b.timer, 100);
    assert_int_equal(co_timer_list_next(&list), 100);
    co_timer_start(&list, &c.timer, 200);
    assert_int_equal(co_timer_list_next(&list), 100);
    co_timer_cancel(&list, &b.timer);
    assert_int_equal(co_timer_list_next(&list), 200);
    assert_int_equal(co_timer_list_run(&list, 250), 1);
    assert_int_equal(co_timer_list_next(&list), 300);
    co_timer_cancel(&list, &a.timer);
    assert_true(co_timer_list_next(&list) == CO_TIME_NEVER);
}

static void test_large_deadlines(void **state)
{
    co_timer_list_t list;
    rec_t rec = {{0}, {0}, 0};
    tt_t a, b;
    const int expected[] = {2, 1};
    (void)state;
    co_timer_list_init(&list);
    tt_init(&a, 1, &rec, &list);
    tt_init(&b, 2, &rec, &list);
    co_timer_start(&list, &a.timer, CO_TIME_NEVER - 1);
    co_timer_start(&list, &b.timer, (uint64_t)1 << 40);
    assert_true(co_timer_list_next(&list) == ((uint64_t)1 << 40));
    assert_int_equal(co_timer_list_run(&list, CO_TIME_NEVER - 1), 2);
    assert_fired(&rec, expected, 2);
}

/* ------------------------------------------------------------ random model */

#define NT 64
#define OPS 100000

typedef struct model_timer {
    bool armed;
    uint64_t deadline;
    uint64_t seq;             /* arm order */
} model_timer_t;

typedef struct rnd_ctx {
    co_timer_list_t list;
    co_timer_t timers[NT];
    model_timer_t model[NT];
    uint64_t seq;
    uint64_t rng;
    int fired[NT];            /* ids fired in the current run, in order */
    int nfired;
    uint64_t now;
    bool rearm[NT];           /* callback re-arms itself */
    uint64_t rearm_to[NT];
} rnd_ctx_t;

static void rnd_fn(co_timer_t *timer, uint64_t now_us, void *user)
{
    rnd_ctx_t *c = user;
    int id = (int)(timer - c->timers);
    assert_true(id >= 0 && id < NT);
    assert_int_equal(now_us, c->now);
    assert_true(c->nfired < NT);
    c->fired[c->nfired++] = id;
    if (c->rearm[id])
        co_timer_start(&c->list, timer, c->rearm_to[id]);
}

static void model_start(rnd_ctx_t *c, int id, uint64_t deadline)
{
    c->model[id].armed = true;
    c->model[id].deadline = deadline;
    c->model[id].seq = ++c->seq;
}

static uint64_t model_next(const rnd_ctx_t *c)
{
    uint64_t next = CO_TIME_NEVER;
    int i;
    for (i = 0; i < NT; i++)
        if (c->model[i].armed && c->model[i].deadline < next)
            next = c->model[i].deadline;
    return next;
}

static int model_armed(const rnd_ctx_t *c)
{
    int i, n = 0;
    for (i = 0; i < NT; i++)
        n += c->model[i].armed;
    return n;
}

/* Due timers of the model, earliest first, equal deadlines in arm order. */
static int model_due(const rnd_ctx_t *c, uint64_t now, int *out)
{
    int i, j, n = 0;
    for (i = 0; i < NT; i++)
        if (c->model[i].armed && c->model[i].deadline <= now)
            out[n++] = i;
    for (i = 1; i < n; i++) {
        int k = out[i];
        for (j = i; j > 0; j--) {
            const model_timer_t *p = &c->model[out[j - 1]], *q = &c->model[k];
            if (p->deadline < q->deadline || (p->deadline == q->deadline && p->seq < q->seq))
                break;
            out[j] = out[j - 1];
        }
        out[j] = k;
    }
    return n;
}

static int setup_rnd(void **state)
{
    *state = calloc(1, sizeof(rnd_ctx_t));
    return *state == NULL ? -1 : 0;
}

static int teardown_rnd(void **state)
{
    free(*state);
    return 0;
}

static void test_random_operations_match_reference_model(void **state)
{
    rnd_ctx_t *c = *state;
    long op;
    int i;
    c->rng = 0x9E3779B97F4A7C15ull;
    co_timer_list_init(&c->list);
    for (i = 0; i < NT; i++)
        co_timer_init(&c->timers[i], rnd_fn, c);

    for (op = 0; op < OPS; op++) {
        uint64_t r = tu_rand(&c->rng);
        int id = (int)((r >> 8) % NT);
        unsigned kind = (unsigned)(r % 100);
        /* small deadline range so that equal deadlines are frequent */
        uint64_t deadline = c->now + ((r >> 20) % 40);
        if (kind < 45) {                       /* start / restart */
            co_timer_start(&c->list, &c->timers[id], deadline);
            model_start(c, id, deadline);
        } else if (kind < 65) {                /* cancel (armed or not) */
            co_timer_cancel(&c->list, &c->timers[id]);
            c->model[id].armed = false;
        } else {                               /* advance and run */
            int due[NT], ndue, k;
            uint32_t n;
            c->now += (r >> 40) % 12;
            ndue = model_due(c, c->now, due);
            for (k = 0; k < NT; k++) {
                /* about one in four re-arms itself, sometimes at or before now */
                uint64_t x = tu_rand(&c->rng);
                c->rearm[k] = (x % 4) == 0;
                c->rearm_to[k] = c->now - (c->now > 3 ? (x >> 8) % 3 : 0) + ((x >> 16) % 20);
            }
            c->nfired = 0;
            n = co_timer_list_run(&c->list, c->now);
            if ((int)n != ndue || c->nfired != ndue)
                fail_msg("op %ld: run(%llu) fired %u (callbacks %d), model %d", op,
                         (unsigned long long)c->now, n, c->nfired, ndue);
            for (k = 0; k < ndue; k++) {
                if (c->fired[k] != due[k])
                    fail_msg("op %ld: firing #%d was timer %d, model %d", op, k,
                             c->fired[k], due[k]);
                c->model[due[k]].armed = false;
                if (c->rearm[due[k]])
                    model_start(c, due[k], c->rearm_to[due[k]]);
            }
        }
        /* invariants after every operation */
        if (co_timer_list_next(&c->list) != model_next(c))
            fail_msg("op %ld: next deadline %llu, model %llu", op,
                     (unsigned long long)co_timer_list_next(&c->list),
                     (unsigned long long)model_next(c));
        if ((int)c->list.armed != model_armed(c))
            fail_msg("op %ld: %u armed, model %d", op, c->list.armed, model_armed(c));
        for (i = 0; i < NT; i++)
            if (co_timer_is_armed(&c->timers[i]) != c->model[i].armed)
                fail_msg("op %ld: timer %d armed=%d, model %d", op, i,
                         (int)co_timer_is_armed(&c->timers[i]), (int)c->model[i].armed);
    }
}

static void test_list_links_consistent_after_random_operations(void **state)
{
    /* Walk the list both ways after a random workload: sorted, head/tail and
     * the armed count agree with the links. */
    rnd_ctx_t *c = *state;
    int op, i, n;
    const co_timer_t *t, *last = NULL;
    c->rng = 12345;
    co_timer_list_init(&c->list);
    for (i = 0; i < NT; i++)
        co_timer_init(&c->timers[i], rnd_fn, c);
    for (op = 0; op < 20000; op++) {
        uint64_t r = tu_rand(&c->rng);
        int id = (int)((r >> 8) % NT);
        if (r % 3 == 0)
            co_timer_cancel(&c->list, &c->timers[id]);
        else
            co_timer_start(&c->list, &c->timers[id], (r >> 20) % 1000);
    }
    n = 0;
    for (t = c->list.head; t != NULL; t = t->next) {
        assert_ptr_equal(t->prev, last);
        assert_true(t->armed);
        if (last != NULL)
            assert_true(last->deadline_us <= t->deadline_us);
        last = t;
        n++;
    }
    assert_ptr_equal(c->list.tail, last);
    assert_int_equal(n, c->list.armed);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_empty_list_next_is_never),
        cmocka_unit_test(test_init_timer_is_unarmed),
        cmocka_unit_test(test_fires_in_deadline_order),
        cmocka_unit_test(test_only_due_timers_fire),
        cmocka_unit_test(test_deadline_zero_fires_at_zero),
        cmocka_unit_test(test_equal_deadlines_fire_in_arm_order),
        cmocka_unit_test(test_restart_with_same_deadline_goes_behind_equal_ones),
        cmocka_unit_test(test_cancel_head),
        cmocka_unit_test(test_cancel_middle),
        cmocka_unit_test(test_cancel_tail),
        cmocka_unit_test(test_cancel_unarmed_is_harmless),
        cmocka_unit_test(test_cancel_only_timer_empties_list),
        cmocka_unit_test(test_restart_later_moves_timer_back),
        cmocka_unit_test(test_restart_earlier_moves_timer_forward),
        cmocka_unit_test(test_periodic_rearm_from_callback),
        cmocka_unit_test(test_rearm_at_or_before_now_does_not_spin),
        cmocka_unit_test(test_rearm_at_exactly_now_does_not_spin),
        cmocka_unit_test(test_rearm_at_now_fires_once_with_other_timers_armed),
        cmocka_unit_test(test_timer_armed_by_callback_at_now_waits_with_other_timers_armed),
        cmocka_unit_test(test_timers_arming_each_other_at_now_do_not_spin),
        cmocka_unit_test(test_rearm_into_future_fires_later),
        cmocka_unit_test(test_cancel_other_due_timer_from_callback),
        cmocka_unit_test(test_cancel_self_from_callback_is_harmless),
        cmocka_unit_test(test_restart_other_due_timer_later_from_callback),
        cmocka_unit_test(test_next_deadline_follows_head),
        cmocka_unit_test(test_large_deadlines),
        cmocka_unit_test_setup_teardown(test_random_operations_match_reference_model, setup_rnd, teardown_rnd),
        cmocka_unit_test_setup_teardown(test_list_links_consistent_after_random_operations, setup_rnd, teardown_rnd),
    };
    return cmocka_run_group_tests_name("timer", tests, NULL, NULL);
}
