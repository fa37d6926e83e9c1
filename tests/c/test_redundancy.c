/* Bus redundancy (co_redundancy): the slave's bus selection on a fake clock,
 * the master's choice, the redundancy object's checks, and a slave whose
 * heartbeat consumer watches a master heard on one of two buses. */
#include "test_util.h"
#include "canopenfd/co_redundancy.h"

#define MASTER_ID 1u
#define PERIOD_MS 100u                /* the master's heartbeat consumer time */
#define TTOGGLE 3u
#define NTOGGLE 4u

typedef struct rdn_fx {
    tu_line_t tl;
    co_rdn_t rdn;
    uint8_t selected[32];             /* every bus the driver was told, in order */
    unsigned selects;
    co_rdn_event_t events[32];
    uint8_t event_bus[32];
    unsigned event_count;
} rdn_fx_t;

static void on_select(co_rdn_t *rdn, uint8_t bus, void *user)
{
    rdn_fx_t *fx = user;
    (void)rdn;
    assert_true(fx->selects < 32);
    fx->selected[fx->selects++] = bus;
}

static void on_event(co_rdn_t *rdn, co_rdn_event_t event, uint8_t bus, void *user)
{
    rdn_fx_t *fx = user;
    (void)rdn;
    assert_true(fx->event_count < 32);
    fx->event_bus[fx->event_count] = bus;
    fx->events[fx->event_count++] = event;
}

static co_rdn_config_t slave_config(void)
{
    co_rdn_config_t c = {.role = CO_RDN_SLAVE, .master_id = MASTER_ID,
                         .master_period_ms = PERIOD_MS, .bdefault = CO_RDN_BUS_A,
                         .ttoggle = TTOGGLE, .ntoggle = NTOGGLE};
    return c;
}

static rdn_fx_t *fx_new(const co_rdn_config_t *config)
{
    rdn_fx_t *fx = calloc(1, sizeof *fx);
    assert_non_null(fx);
    tu_line_init(&fx->tl, CO_MODE_CLASSIC, false);
    assert_true(co_rdn_init(&fx->rdn, &fx->tl.line, config, on_select, on_event, fx));
    return fx;
}

static void fx_free(rdn_fx_t *fx)
{
    co_rdn_deinit(&fx->rdn);
    free(fx);
}

static void at_ms(rdn_fx_t *fx, uint64_t ms) { tu_line_run_until(&fx->tl.line, ms * TU_MS); }

/* ---------------------------------------------------------------- checks */

static void test_config_checks(void **state)
{
    (void)state;
    co_rdn_config_t c = slave_config();
    assert_int_equal(co_rdn_check_config(&c), CO_RDN_OK);
    c.bdefault = 2;
    assert_int_equal(co_rdn_check_config(&c), CO_RDN_BAD_BUS);
    c = slave_config();
    c.ntoggle = 0;
    assert_int_equal(co_rdn_check_config(&c), CO_RDN_BAD_NTOGGLE);
    c = slave_config();
    c.master_id = 0;
    assert_int_equal(co_rdn_check_config(&c), CO_RDN_BAD_MASTER);
    c.master_id = 128;
    assert_int_equal(co_rdn_check_config(&c), CO_RDN_BAD_MASTER);
    c = slave_config();
    c.master_period_ms = 0;
    assert_int_equal(co_rdn_check_config(&c), CO_RDN_BAD_PERIOD);
    c.ttoggle = 0;                    /* never switches: no period needed */
    assert_int_equal(co_rdn_check_config(&c), CO_RDN_OK);
    c = slave_config();
    c.role = CO_RDN_MASTER;           /* a master watches nobody */
    c.master_id = 0;
    c.master_period_ms = 0;
    assert_int_equal(co_rdn_check_config(&c), CO_RDN_OK);

    assert_int_equal(co_rdn_check_sub(CO_RDN_SUB_TTOGGLE, 0x0006, 3), CO_RDN_BAD_TYPE);
    assert_int_equal(co_rdn_check_sub(CO_RDN_SUB_COUNT, 0x0007, 4), CO_RDN_BAD_TYPE);
    assert_int_equal(co_rdn_check_sub(5, CO_RDN_TYPE_UNSIGNED8, 0), CO_RDN_NO_SUB);
    assert_int_equal(co_rdn_check_sub(CO_RDN_SUB_BDEFAULT, CO_RDN_TYPE_UNSIGNED8, 1), CO_RDN_OK);
    assert_int_equal(co_rdn_check_sub(CO_RDN_SUB_BDEFAULT, CO_RDN_TYPE_UNSIGNED8, 2), CO_RDN_BAD_BUS);
    assert_int_equal(co_rdn_check_sub(CO_RDN_SUB_NTOGGLE, CO_RDN_TYPE_UNSIGNED8, 0), CO_RDN_BAD_NTOGGLE);
    assert_int_equal(co_rdn_check_sub(CO_RDN_SUB_TTOGGLE, CO_RDN_TYPE_UNSIGNED8, 0), CO_RDN_OK);
    assert_string_equal(co_rdn_result_text(CO_RDN_BAD_BUS), "Bdefault must be 0 (bus A) or 1 (bus B)");
    for (int r = CO_RDN_OK; r <= CO_RDN_NOT_MASTER; r++)
        assert_string_not_equal(co_rdn_result_text((co_rdn_result_t)r), "unknown redundancy result");
}

static void test_init_refuses_bad_config(void **state)
{
    (void)state;
    tu_line_t *tl = calloc(1, sizeof *tl);
    assert_non_null(tl);
    tu_line_init(tl, CO_MODE_CLASSIC, false);
    co_rdn_t rdn;
    co_rdn_config_t c = slave_config();
    assert_false(co_rdn_init(&rdn, &tl->line, &c, NULL, NULL, NULL));
    c.ntoggle = 0;
    assert_false(co_rdn_init(&rdn, &tl->line, &c, on_select, NULL, NULL));
    free(tl);
}

/* ------------------------------------------------------------ the slave */

static void test_start_selects_bdefault(void **state)
{
    (void)state;
    co_rdn_config_t c = slave_config();
    c.bdefault = CO_RDN_BUS_B;
    rdn_fx_t *fx = fx_new(&c);
    assert_int_equal(fx->selects, 0);  /* nothing before start */
    co_rdn_start(&fx->rdn);
    assert_int_equal(fx->selects, 1);
    assert_int_equal(fx->selected[0], CO_RDN_BUS_B);
    assert_int_equal(co_rdn_active_bus(&fx->rdn), CO_RDN_BUS_B);
    assert_int_equal(fx->event_count, 0);
    fx_free(fx);
}

/* Never heard: the first switch comes Ttoggle periods after start. */
static void test_master_never_heard_switches_after_ttoggle(void **state)
{
    (void)state;
    co_rdn_config_t c = slave_config();
    rdn_fx_t *fx = fx_new(&c);
    at_ms(fx, 0);
    co_rdn_start(&fx->rdn);
    at_ms(fx, TTOGGLE * PERIOD_MS - 1);
    assert_int_equal(fx->selects, 1);
    at_ms(fx, TTOGGLE * PERIOD_MS);
    assert_int_equal(fx->selects, 2);
    assert_int_equal(fx->selected[1], CO_RDN_BUS_B);
    assert_int_equal(fx->event_count, 1);
    assert_int_equal(fx->events[0], CO_RDN_EV_BUS_SWITCH);
    assert_int_equal(fx->event_bus[0], CO_RDN_BUS_B);
    assert_int_equal(co_rdn_read(&fx->rdn, CO_RDN_SUB_CTOGGLE), 1);
    fx_free(fx);
}

/* Heard, then lost (the consumer's LOST comes one period after the last
 * heartbeat): the switch comes Ttoggle - 1 periods after LOST. */
static void test_lost_switches_after_remaining_periods(void **state)
{
    (void)state;
    co_rdn_config_t c = slave_config();
    rdn_fx_t *fx = fx_new(&c);
    at_ms(fx, 0);
    co_rdn_start(&fx->rdn);
    at_ms(fx, 50);
    co_rdn_master_heard(&fx->rdn);
    at_ms(fx, 10000);                 /* heard: no countdown */
    assert_int_equal(fx->selects, 1);
    co_rdn_master_lost(&fx->rdn);
    at_ms(fx, 10000 + (TTOGGLE - 1) * PERIOD_MS - 1);
    assert_int_equal(fx->selects, 1);
    at_ms(fx, 10000 + (TTOGGLE - 1) * PERIOD_MS);
    assert_int_equal(fx->selects, 2);
    assert_int_equal(fx->selected[1], CO_RDN_BUS_B);
    fx_free(fx);
}

/* Silent master: a switch every Ttoggle periods, Ctoggle counting, until
 * Ntoggle switches; then no master, Bdefault = where it stays, no more. */
static void test_repeats_then_gives_up(void **state)
{
    (void)state;
    co_rdn_config_t c = slave_config();
    rdn_fx_t *fx = fx_new(&c);
    at_ms(fx, 0);
    co_rdn_start(&fx->rdn);
    for (unsigned k = 1; k <= NTOGGLE; k++) {
        at_ms(fx, k * TTOGGLE * PERIOD_MS - 1);
        assert_int_equal(fx->selects, k);
        at_ms(fx, k * TTOGGLE * PERIOD_MS);
        assert_int_equal(fx->selects, k + 1);
        assert_int_equal(fx->selected[k], k % 2 ? CO_RDN_BUS_B : CO_RDN_BUS_A);
        assert_int_equal(co_rdn_read(&fx->rdn, CO_RDN_SUB_CTOGGLE), k);
        assert_int_equal(fx->events[fx->event_count - (k == NTOGGLE ? 2 : 1)],
                         CO_RDN_EV_BUS_SWITCH);
    }
    /* NTOGGLE = 4 switches: A -> B -> A -> B -> A. */
    assert_int_equal(fx->event_count, NTOGGLE + 1);
    assert_int_equal(fx->events[NTOGGLE], CO_RDN_EV_NO_MASTER);
    assert_int_equal(fx->event_bus[NTOGGLE], CO_RDN_BUS_A);
    assert_int_equal(co_rdn_read(&fx->rdn, CO_RDN_SUB_BDEFAULT), CO_RDN_BUS_A);
    assert_int_equal(co_rdn_read(&fx->rdn, CO_RDN_SUB_CTOGGLE), NTOGGLE);
    at_ms(fx, 100000);
    assert_int_equal(fx->selects, NTOGGLE + 1);
    assert_int_equal(fx->event_count, NTOGGLE + 1);
    fx_free(fx);
}

/* An odd Ntoggle gives up on the other bus: it becomes Bdefault, and the
 * next start begins there. */
static void test_gives_up_on_other_bus_updates_bdefault(void **state)
{
    (void)state;
    co_rdn_config_t c = slave_config();
    c.ntoggle = 1;
    rdn_fx_t *fx = fx_new(&c);
    at_ms(fx, 0);
    co_rdn_start(&fx->rdn);
    at_ms(fx, TTOGGLE * PERIOD_MS);
    assert_int_equal(fx->event_count, 2);
    assert_int_equal(fx->events[0], CO_RDN_EV_BUS_SWITCH);
    assert_int_equal(fx->events[1], CO_RDN_EV_NO_MASTER);
    assert_int_equal(fx->event_bus[1], CO_RDN_BUS_B);
    assert_int_equal(co_rdn_read(&fx->rdn, CO_RDN_SUB_BDEFAULT), CO_RDN_BUS_B);
    co_rdn_start(&fx->rdn);           /* a communication reset */
    assert_int_equal(fx->selected[fx->selects - 1], CO_RDN_BUS_B);
    assert_int_equal(co_rdn_read(&fx->rdn, CO_RDN_SUB_CTOGGLE), 0);
    fx_free(fx);
}

/* A reset (start again) after following the master to B: back on
 * Bdefault, told as a switch, counting from 0 again. */
static void test_restart_returns_to_bdefault(void **state)
{
    (void)state;
    co_rdn_config_t c = slave_config();
    rdn_fx_t *fx = fx_new(&c);
    at_ms(fx, 0);
    co_rdn_start(&fx->rdn);
    assert_int_equal(fx->event_count, 0);   /* the first start leaves nothing */
    at_ms(fx, TTOGGLE * PERIOD_MS);
    co_rdn_master_heard(&fx->rdn);         /* found on B */
    assert_int_equal(co_rdn_active_bus(&fx->rdn), CO_RDN_BUS_B);
    at_ms(fx, 1000);
    co_rdn_start(&fx->rdn);
    assert_int_equal(co_rdn_active_bus(&fx->rdn), CO_RDN_BUS_A);
    assert_int_equal(fx->event_count, 2);
    assert_int_equal(fx->events[1], CO_RDN_EV_BUS_SWITCH);
    assert_int_equal(fx->event_bus[1], CO_RDN_BUS_A);
    assert_int_equal(co_rdn_read(&fx->rdn, CO_RDN_SUB_CTOGGLE), 0);
    at_ms(fx, 1000 + TTOGGLE * PERIOD_MS);   /* silent on A: back to B after Ttoggle */
    assert_int_equal(co_rdn_active_bus(&fx->rdn), CO_RDN_BUS_B);
    fx_free(fx);
}

/* The master heard between switches: counting stops, Ctoggle back to 0;
 * lost again, the full Ntoggle switches are available again. */
static void test_master_heard_resets_counting(void **state)
{
    (void)state;
    co_rdn_config_t c = slave_config();
    rdn_fx_t *fx = fx_new(&c);
    at_ms(fx, 0);
    co_rdn_start(&fx->rdn);
    at_ms(fx, 2 * TTOGGLE * PERIOD_MS);   /* two switches: back on A */
    assert_int_equal(co_rdn_read(&fx->rdn, CO_RDN_SUB_CTOGGLE), 2);
    at_ms(fx, 2 * TTOGGLE * PERIOD_MS + 10);
    co_rdn_master_heard(&fx->rdn);
    assert_int_equal(co_rdn_read(&fx->rdn, CO_RDN_SUB_CTOGGLE), 0);
    unsigned selects = fx->selects;
    at_ms(fx, 50000);
    assert_int_equal(fx->selects, selects);
    co_rdn_master_lost(&fx->rdn);
    for (unsigned k = 0; k < NTOGGLE; k++)
        at_ms(fx, 50000 + (TTOGGLE - 1) * PERIOD_MS + k * TTOGGLE * PERIOD_MS);
    assert_int_equal(fx->selects, selects + NTOGGLE);
    assert_int_equal(fx->events[fx->event_count - 1], CO_RDN_EV_NO_MASTER);
    fx_free(fx);
}

/* Ttoggle 0: the slave never leaves Bdefault; writing 0 stops a countdown. */
static void test_ttoggle_zero_never_switches(void **state)
{
    (void)state;
    co_rdn_config_t c = slave_config();
    c.ttoggle = 0;
    rdn_fx_t *fx = fx_new(&c);
    at_ms(fx, 0);
    co_rdn_start(&fx->rdn);
    co_rdn_master_lost(&fx->rdn);
    at_ms(fx, 100000);
    assert_int_equal(fx->selects, 1);
    assert_int_equal(fx->event_count, 0);
    fx_free(fx);

    c = slave_config();
    fx = fx_new(&c);
    at_ms(fx, 0);
    co_rdn_start(&fx->rdn);
    at_ms(fx, PERIOD_MS);
    assert_int_equal(co_rdn_write(&fx->rdn, CO_RDN_SUB_TTOGGLE, 0), CO_RDN_OK);
    at_ms(fx, 100000);
    assert_int_equal(fx->selects, 1);
    fx_free(fx);
}

/* Ttoggle 1: LOST itself is the whole wait, the switch follows at once. */
static void test_ttoggle_one_switches_at_lost(void **state)
{
    (void)state;
    co_rdn_config_t c = slave_config();
    c.ttoggle = 1;
    rdn_fx_t *fx = fx_new(&c);
    at_ms(fx, 0);
    co_rdn_start(&fx->rdn);
    co_rdn_master_heard(&fx->rdn);
    at_ms(fx, 500);
    co_rdn_master_lost(&fx->rdn);
    at_ms(fx, 500);
    assert_int_equal(fx->selects, 2);
    at_ms(fx, 500 + PERIOD_MS - 1);
    assert_int_equal(fx->selects, 2);
    at_ms(fx, 500 + PERIOD_MS);
    assert_int_equal(fx->selects, 3);
    fx_free(fx);
}

/* ------------------------------------------------------------ the master */

static void test_master_selects_and_never_toggles(void **state)
{
    (void)state;
    co_rdn_config_t c = {.role = CO_RDN_MASTER, .bdefault = CO_RDN_BUS_A, .ttoggle = 3,
                         .ntoggle = 2};
    rdn_fx_t *fx = fx_new(&c);
    at_ms(fx, 0);
    co_rdn_start(&fx->rdn);
    co_rdn_master_lost(&fx->rdn);     /* a master follows nobody */
    at_ms(fx, 100000);
    assert_int_equal(fx->selects, 1);
    assert_int_equal(co_rdn_master_select(&fx->rdn, 2), CO_RDN_BAD_BUS);
    assert_int_equal(co_rdn_master_select(&fx->rdn, CO_RDN_BUS_B), CO_RDN_OK);
    assert_int_equal(fx->selects, 2);
    assert_int_equal(fx->selected[1], CO_RDN_BUS_B);
    assert_int_equal(fx->event_count, 1);
    assert_int_equal(fx->events[0], CO_RDN_EV_BUS_SWITCH);
    assert_int_equal(co_rdn_master_select(&fx->rdn, CO_RDN_BUS_B), CO_RDN_OK);
    assert_int_equal(fx->selects, 2); /* already there: nothing to tell */
    fx_free(fx);

    c = slave_config();
    fx = fx_new(&c);
    co_rdn_start(&fx->rdn);
    assert_int_equal(co_rdn_master_select(&fx->rdn, CO_RDN_BUS_B), CO_RDN_NOT_MASTER);
    assert_int_equal(co_rdn_active_bus(&fx->rdn), CO_RDN_BUS_A);
    fx_free(fx);
}

/* --------------------------------------------------- the object's access */

static void test_object_read_write(void **state)
{
    (void)state;
    co_rdn_config_t c = slave_config();
    rdn_fx_t *fx = fx_new(&c);
    assert_int_equal(co_rdn_read(&fx->rdn, CO_RDN_SUB_COUNT), 4);
    assert_int_equal(co_rdn_read(&fx->rdn, CO_RDN_SUB_TTOGGLE), TTOGGLE);
    assert_int_equal(co_rdn_read(&fx->rdn, CO_RDN_SUB_NTOGGLE), NTOGGLE);
    assert_int_equal(co_rdn_write(&fx->rdn, CO_RDN_SUB_CTOGGLE, 0), CO_RDN_READ_ONLY);
    assert_int_equal(co_rdn_write(&fx->rdn, CO_RDN_SUB_COUNT, 4), CO_RDN_READ_ONLY);
    assert_int_equal(co_rdn_write(&fx->rdn, 5, 0), CO_RDN_NO_SUB);
    assert_int_equal(co_rdn_write(&fx->rdn, CO_RDN_SUB_BDEFAULT, 2), CO_RDN_BAD_BUS);
    assert_int_equal(co_rdn_write(&fx->rdn, CO_RDN_SUB_NTOGGLE, 0), CO_RDN_BAD_NTOGGLE);
    assert_int_equal(co_rdn_read(&fx->rdn, CO_RDN_SUB_BDEFAULT), CO_RDN_BUS_A);
    assert_int_equal(co_rdn_read(&fx->rdn, CO_RDN_SUB_NTOGGLE), NTOGGLE);
    /* Bdefault counts from the next start. */
    assert_int_equal(co_rdn_write(&fx->rdn, CO_RDN_SUB_BDEFAULT, CO_RDN_BUS_B), CO_RDN_OK);
    assert_int_equal(co_rdn_write(&fx->rdn, CO_RDN_SUB_NTOGGLE, 9), CO_RDN_OK);
    assert_int_equal(co_rdn_read(&fx->rdn, CO_RDN_SUB_NTOGGLE), 9);
    co_rdn_start(&fx->rdn);
    assert_int_equal(fx->selected[0], CO_RDN_BUS_B);
    fx_free(fx);

    c.master_period_ms = 0;
    c.ttoggle = 0;
    fx = fx_new(&c);
    assert_int_equal(co_rdn_write(&fx->rdn, CO_RDN_SUB_TTOGGLE, 2), CO_RDN_BAD_PERIOD);
    assert_int_equal(co_rdn_read(&fx->rdn, CO_RDN_SUB_TTOGGLE), 0);
    fx_free(fx);
}

/* ------------------------------------- two buses, a real heartbeat consumer */

/* The slave's driver: a frame reaches the slave only from the bus it uses,
 * and what the slave sends goes out on that bus only. */
typedef struct two_bus {
    rdn_fx_t *fx;
    co_hb_consumer_t cons;
    co_hb_entry_t entries[2];
    co_frame_t sent[2][16];           /* per bus: what the slave sent there */
    unsigned sent_count[2];
} two_bus_t;

static void forward_master(co_hb_consumer_t *c, uint8_t node_id, co_hb_event_t event,
                           co_nmt_state_t st, void *user)
{
    two_bus_t *tb = user;
    (void)c;
    (void)st;
    if (node_id != MASTER_ID)
        return;
    if (event == CO_HB_STARTED)
        co_rdn_master_heard(&tb->fx->rdn);
    else if (event == CO_HB_LOST)
        co_rdn_master_lost(&tb->fx->rdn);
}

static void master_heartbeat_on(two_bus_t *tb, uint8_t bus)
{
    co_frame_t f = {.id = 0x700 + MASTER_ID, .len = 1, .flags = 0, .data = {0x05}};
    if (co_rdn_active_bus(&tb->fx->rdn) == bus)
        assert_true(co_line_receive(&tb->fx->tl.line, &f));
}

static void drive_to(two_bus_t *tb, uint64_t ms)
{
    tu_line_run_until(&tb->fx->tl.line, ms * TU_MS);
    co_frame_t f;
    while (co_line_tx_pop(&tb->fx->tl.line, &f)) {
        uint8_t bus = co_rdn_active_bus(&tb->fx->rdn);
        assert_true(tb->sent_count[bus] < 16);
        tb->sent[bus][tb->sent_count[bus]++] = f;
    }
}

static void slave_says(two_bus_t *tb, uint8_t byte)
{
    uint8_t data[2] = {0xA5, byte};
    assert_true(co_line_send(&tb->fx->tl.line, 0x182, data, sizeof data));
}

static void test_two_buses_master_silent_on_a(void **state)
{
    (void)state;
    co_rdn_config_t c = slave_config();
    two_bus_t *tb = calloc(1, sizeof *tb);
    assert_non_null(tb);
    tb->fx = fx_new(&c);
    co_line_t *line = &tb->fx->tl.line;
    assert_true(co_hb_consumer_init(&tb->cons, line, tb->entries, 2, forward_master, tb));
    assert_int_equal(co_hb_consumer_set_entry(&tb->cons, 0, (MASTER_ID << 16) | PERIOD_MS),
                     CO_HB_CONFIG_OK);
    drive_to(tb, 0);
    co_rdn_start(&tb->fx->rdn);

    /* The master beats on A every 80 ms up to 400 ms: the slave stays on A. */
    uint64_t t;
    for (t = 0; t <= 400; t += 80) {
        master_heartbeat_on(tb, CO_RDN_BUS_A);
        drive_to(tb, t);
    }
    slave_says(tb, 1);
    drive_to(tb, 400);
    assert_int_equal(co_rdn_active_bus(&tb->fx->rdn), CO_RDN_BUS_A);
    assert_int_equal(tb->sent_count[CO_RDN_BUS_A], 1);
    tu_assert_frame(&tb->sent[CO_RDN_BUS_A][0], 0x182, 0, (const uint8_t[]){0xA5, 0x01}, 2);

    /* Now it beats on B only: LOST at 500, the switch Ttoggle periods after
     * the last heartbeat (400 + 300 = 700). */
    for (t = 480; t < 700; t += 80) {
        master_heartbeat_on(tb, CO_RDN_BUS_B);
        drive_to(tb, t);
    }
    drive_to(tb, 699);
    assert_int_equal(co_rdn_active_bus(&tb->fx->rdn), CO_RDN_BUS_A);
    assert_int_equal(co_hb_consumer_monitor(&tb->cons, MASTER_ID), CO_HB_MONITOR_LOST);
    drive_to(tb, 700);
    assert_int_equal(co_rdn_active_bus(&tb->fx->rdn), CO_RDN_BUS_B);
    assert_int_equal(tb->fx->events[0], CO_RDN_EV_BUS_SWITCH);

    /* On B it hears the master: monitoring resumes, counting stops. */
    for (t = 720; t <= 2000; t += 80) {
        master_heartbeat_on(tb, CO_RDN_BUS_B);
        drive_to(tb, t);
    }
    assert_int_equal(co_hb_consumer_monitor(&tb->cons, MASTER_ID), CO_HB_MONITOR_ACTIVE);
    assert_int_equal(co_rdn_read(&tb->fx->rdn, CO_RDN_SUB_CTOGGLE), 0);
    assert_int_equal(co_rdn_active_bus(&tb->fx->rdn), CO_RDN_BUS_B);
    assert_int_equal(tb->fx->event_count, 1);
    slave_says(tb, 2);
    drive_to(tb, 2000);
    assert_int_equal(tb->sent_count[CO_RDN_BUS_A], 1);
    assert_int_equal(tb->sent_count[CO_RDN_BUS_B], 1);
    tu_assert_frame(&tb->sent[CO_RDN_BUS_B][0], 0x182, 0, (const uint8_t[]){0xA5, 0x02}, 2);

    co_hb_consumer_deinit(&tb->cons);
    fx_free(tb->fx);
    free(tb);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_config_checks),
        cmocka_unit_test(test_init_refuses_bad_config),
        cmocka_unit_test(test_start_selects_bdefault),
        cmocka_unit_test(test_master_never_heard_switches_after_ttoggle),
        cmocka_unit_test(test_lost_switches_after_remaining_periods),
        cmocka_unit_test(test_repeats_then_gives_up),
        cmocka_unit_test(test_gives_up_on_other_bus_updates_bdefault),
        cmocka_unit_test(test_restart_returns_to_bdefault),
        cmocka_unit_test(test_master_heard_resets_counting),
        cmocka_unit_test(test_ttoggle_zero_never_switches),
        cmocka_unit_test(test_ttoggle_one_switches_at_lost),
        cmocka_unit_test(test_master_selects_and_never_toggles),
        cmocka_unit_test(test_object_read_write),
        cmocka_unit_test(test_two_buses_master_silent_on_a),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
