/* Flying master (co_flyma, CiA 302-2) on the in-process bus with a fake
 * clock: candidates on their own lines agree on one active master; the
 * frames' bytes, the timeline of the slots, the power-on network reset, the
 * loss of the active master, a better late joiner, two active masters
 * meeting, ties broken by node-id, the 0x75/0x74 detection, malformed
 * frames, and the timing read from 0x1F90/0x1F91. The harness stands in
 * for the integration: a network reset asked for boots every candidate. */
#include "test_od_util.h"

#include "canopenfd/co_flyma.h"
#include "canopenfd/co_stack.h"

#define DELAY_MS 500u
#define DETECT_MS 100u
#define PSLOT_MS 1500u
#define DSLOT_MS 10u
#define CYCLE_MS 4000u

typedef struct cand {
    struct fx *fx;
    co_flyma_t flyma;
    bool up;                      /* taking part (a killed node is not) */
    int resets;                   /* EV_RESET_ALL asked */
    int capable;                  /* last EV_CAPABLE_DONE count */
    int states;                   /* EV_STATE told */
} cand_t;

typedef struct fx {
    tu_bus_t tb;
    tu_line_t l[4];
    cand_t c[4];
    int n;
    bool reset_pending;
} fx_t;

static void on_event(co_flyma_t *flyma, co_flyma_event_t event, co_flyma_state_t state,
                     uint8_t master, uint8_t priority, void *user)
{
    (void)flyma;
    (void)state;
    (void)master;
    cand_t *c = user;
    if (event == CO_FLYMA_EV_RESET_ALL) {
        c->resets++;
        c->fx->reset_pending = true;   /* the NMT reset reaches every node */
    } else if (event == CO_FLYMA_EV_CAPABLE_DONE) {
        c->capable = priority;
    } else if (event == CO_FLYMA_EV_STATE) {
        c->states++;
    }
}

/* Candidates with these node-ids and priorities, booted together. */
static fx_t *fx_new(int n, const uint8_t *ids, const uint8_t *priorities)
{
    fx_t *fx = calloc(1, sizeof *fx);
    assert_non_null(fx);
    fx->n = n;
    tu_bus_init(&fx->tb, CO_MODE_CLASSIC, false);
    for (int i = 0; i < n; i++) {
        co_line_t *line = tu_bus_add_line(&fx->tb, &fx->l[i]);
        co_line_set_node_id(line, ids[i]);
        co_flyma_config_t config = {.priority = priorities[i], .detect_ms = DETECT_MS,
                                    .delay_ms = DELAY_MS, .priority_slot_ms = PSLOT_MS,
                                    .device_slot_ms = DSLOT_MS, .multiple_master_ms = CYCLE_MS,
                                    .ind = on_event, .user = &fx->c[i]};
        fx->c[i].fx = fx;
        fx->c[i].up = true;
        assert_true(co_flyma_init(&fx->c[i].flyma, line, &config));
    }
    return fx;
}

static void fx_free(fx_t *fx)
{
    for (int i = 0; i < fx->n; i++) {
        co_flyma_deinit(&fx->c[i].flyma);
    }
    free(fx);
}

static void boot_all(fx_t *fx)
{
    for (int i = 0; i < fx->n; i++) {
        if (fx->c[i].up) {
            co_line_set_time(&fx->l[i].line, fx->tb.now);
            co_flyma_boot(&fx->c[i].flyma);
        }
    }
}

/* Run in 1 ms steps, rebooting everyone when a network reset was asked. */
static void run(fx_t *fx, uint64_t ms)
{
    uint64_t end = fx->tb.now + ms * TU_MS;
    while (fx->tb.now < end) {
        tu_run_until(&fx->tb, fx->tb.now + TU_MS);
        if (fx->reset_pending) {
            fx->reset_pending = false;
            boot_all(fx);
        }
    }
}

static int masters(const fx_t *fx)
{
    int n = 0;
    for (int i = 0; i < fx->n; i++) {
        n += fx->c[i].up && co_flyma_state(&fx->c[i].flyma) == CO_FLYMA_MASTER;
    }
    return n;
}

/* A candidate taken off the bus: it neither sends nor receives any more. */
static void kill(fx_t *fx, int i)
{
    fx->c[i].up = false;
    co_flyma_stop(&fx->c[i].flyma);
    co_membus_detach(&fx->tb.bus, &fx->l[i].line);
}

/* ------------------------------------------------------------ tests */

/* Power-on: nobody answers the first detection, the network is reset once,
 * the second detection fails too, the negotiation's slots decide: priority
 * 0 (node 11) announces after 110 ms, the others become its slaves. */
static void test_power_on_negotiation(void **state)
{
    (void)state;
    fx_t *fx = fx_new(3, (const uint8_t[]){10, 11, 12}, (const uint8_t[]){1, 0, 1});
    boot_all(fx);
    for (int i = 0; i < 3; i++) {
        assert_int_equal(co_flyma_state(&fx->c[i].flyma), CO_FLYMA_WAITING);
    }
    run(fx, DELAY_MS);
    assert_int_equal(tu_log_count_id(&fx->tb, CO_FLYMA_ID_ASK_ACTIVE), 3);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, CO_FLYMA_ID_ASK_ACTIVE, 0),
                     CO_FLYMA_ID_ASK_ACTIVE, NULL, 0);
    assert_int_equal(fx->tb.log[tu_log_find_id(&fx->tb, CO_FLYMA_ID_ASK_ACTIVE, 0)].t_us,
                     DELAY_MS * TU_MS);
    run(fx, DETECT_MS + 1);                       /* no answer: the network reset */
    assert_int_equal(fx->c[0].resets + fx->c[1].resets + fx->c[2].resets, 3);
    run(fx, DELAY_MS + DETECT_MS);                /* second detection, no answer */
    uint64_t t_nego = fx->tb.now;
    assert_int_equal(tu_log_count_id(&fx->tb, CO_FLYMA_ID_NEGOTIATE), 3);
    for (int i = 0; i < 3; i++) {
        assert_int_equal(co_flyma_state(&fx->c[i].flyma), CO_FLYMA_NEGOTIATING);
    }
    run(fx, 200);
    long a = tu_log_find_id(&fx->tb, CO_FLYMA_ID_ACTIVE_MASTER, 0);
    tu_assert_logged(&fx->tb, a, CO_FLYMA_ID_ACTIVE_MASTER, (const uint8_t[]){0x00, 11}, 2);
    assert_true(fx->tb.log[a].t_us >= t_nego + 100 * TU_MS - TU_MS);
    assert_true(fx->tb.log[a].t_us <= t_nego + 110 * TU_MS);
    assert_int_equal(co_flyma_state(&fx->c[1].flyma), CO_FLYMA_MASTER);
    for (int i = 0; i < 3; i += 2) {
        assert_int_equal(co_flyma_state(&fx->c[i].flyma), CO_FLYMA_SLAVE);
        assert_int_equal(co_flyma_master(&fx->c[i].flyma), 11);
    }
    assert_int_equal(tu_log_count_id(&fx->tb, CO_FLYMA_ID_ACTIVE_MASTER), 1);
    /* stable: the master's 0x76 every cycle changes nobody's mind */
    tu_log_clear(&fx->tb);
    run(fx, 2 * CYCLE_MS + 10);
    assert_int_equal(tu_log_count_id(&fx->tb, CO_FLYMA_ID_FORCE), 2);
    assert_int_equal(tu_log_count_id(&fx->tb, CO_FLYMA_ID_NEGOTIATE), 0);
    assert_int_equal(masters(fx), 1);
    fx_free(fx);
}

/* The active master dies: a slave that loses its heartbeat asks for a
 * network reset, the survivors negotiate (no second power-on reset) and
 * the better one (node 10, 1600 ms before node 12's 1620) takes over. */
static void test_master_lost(void **state)
{
    (void)state;
    fx_t *fx = fx_new(3, (const uint8_t[]){10, 11, 12}, (const uint8_t[]){1, 0, 1});
    boot_all(fx);
    run(fx, 2 * (DELAY_MS + DETECT_MS) + 300);
    assert_int_equal(co_flyma_state(&fx->c[1].flyma), CO_FLYMA_MASTER);
    kill(fx, 1);
    co_flyma_node_lost(&fx->c[0].flyma, 12);      /* not the master: nothing */
    assert_int_equal(fx->c[0].resets, 1);
    co_line_set_time(&fx->l[0].line, fx->tb.now);
    co_flyma_node_lost(&fx->c[0].flyma, 11);
    assert_int_equal(fx->c[0].resets, 2);
    tu_log_clear(&fx->tb);
    run(fx, DELAY_MS + DETECT_MS + 1700);
    assert_int_equal(co_flyma_state(&fx->c[0].flyma), CO_FLYMA_MASTER);
    assert_int_equal(co_flyma_state(&fx->c[2].flyma), CO_FLYMA_SLAVE);
    assert_int_equal(co_flyma_master(&fx->c[2].flyma), 10);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, CO_FLYMA_ID_ACTIVE_MASTER, 0),
                     CO_FLYMA_ID_ACTIVE_MASTER, (const uint8_t[]){0x01, 10}, 2);
    /* node 12 asked once, at power-on; node 10 once more for the lost master */
    assert_int_equal(fx->c[2].resets, 1);
    assert_int_equal(fx->c[0].resets, 2);
    fx_free(fx);
}

/* A late joiner asks for the active master and gets its answer: a worse
 * joiner becomes a slave at once; a better one forces a negotiation and
 * wins it. */
static void test_late_joiners(void **state)
{
    (void)state;
    fx_t *fx = fx_new(3, (const uint8_t[]){20, 30, 5}, (const uint8_t[]){1, 2, 0});
    fx->c[1].up = false;
    fx->c[2].up = false;
    boot_all(fx);
    run(fx, 2 * (DELAY_MS + DETECT_MS) + PSLOT_MS + 250);
    assert_int_equal(co_flyma_state(&fx->c[0].flyma), CO_FLYMA_MASTER);
    /* worse: priority 2 */
    fx->c[1].up = true;
    co_line_set_time(&fx->l[1].line, fx->tb.now);
    co_flyma_boot(&fx->c[1].flyma);
    tu_log_clear(&fx->tb);
    run(fx, DELAY_MS + 10);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, CO_FLYMA_ID_ACTIVE_MASTER, 0),
                     CO_FLYMA_ID_ACTIVE_MASTER, (const uint8_t[]){0x01, 20}, 2);
    assert_int_equal(co_flyma_state(&fx->c[1].flyma), CO_FLYMA_SLAVE);
    assert_int_equal(co_flyma_master(&fx->c[1].flyma), 20);
    assert_int_equal(tu_log_count_id(&fx->tb, CO_FLYMA_ID_FORCE), 0);
    /* better: priority 0 */
    fx->c[2].up = true;
    co_line_set_time(&fx->l[2].line, fx->tb.now);
    co_flyma_boot(&fx->c[2].flyma);
    tu_log_clear(&fx->tb);
    run(fx, DELAY_MS + 10 + 3 * PSLOT_MS);
    assert_true(tu_log_count_id(&fx->tb, CO_FLYMA_ID_FORCE) >= 1);
    assert_int_equal(co_flyma_state(&fx->c[2].flyma), CO_FLYMA_MASTER);
    assert_int_equal(co_flyma_master(&fx->c[0].flyma), 5);
    assert_int_equal(co_flyma_master(&fx->c[1].flyma), 5);
    assert_int_equal(masters(fx), 1);
    fx_free(fx);
}

/* Two active masters meet (two networks joined): the cyclic 0x76 makes
 * them negotiate again; one stays. Equal priorities: the lower node-id. */
static void test_two_masters_meet(void **state)
{
    (void)state;
    fx_t *fx = fx_new(2, (const uint8_t[]){7, 3}, (const uint8_t[]){1, 1});
    /* each decided alone: the other was off the bus */
    co_membus_detach(&fx->tb.bus, &fx->l[1].line);
    fx->c[1].up = false;
    boot_all(fx);
    run(fx, 2 * (DELAY_MS + DETECT_MS) + PSLOT_MS + 100);
    fx->c[1].up = true;
    fx->c[0].up = false;
    co_membus_detach(&fx->tb.bus, &fx->l[0].line);
    co_membus_attach(&fx->tb.bus, &fx->l[1].line);
    co_line_set_time(&fx->l[1].line, fx->tb.now);
    co_flyma_boot(&fx->c[1].flyma);
    run(fx, 2 * (DELAY_MS + DETECT_MS) + PSLOT_MS + 100);
    assert_int_equal(co_flyma_state(&fx->c[0].flyma), CO_FLYMA_MASTER);
    assert_int_equal(co_flyma_state(&fx->c[1].flyma), CO_FLYMA_MASTER);
    fx->c[0].up = true;
    co_membus_attach(&fx->tb.bus, &fx->l[0].line);
    run(fx, CYCLE_MS + PSLOT_MS + 200);
    assert_int_equal(masters(fx), 1);
    assert_int_equal(co_flyma_state(&fx->c[1].flyma), CO_FLYMA_MASTER);   /* node 3 */
    assert_int_equal(co_flyma_master(&fx->c[0].flyma), 3);
    fx_free(fx);
}

/* 0x75 asks who can be master: the other candidates answer 0x74. */
static void test_detect_capable(void **state)
{
    (void)state;
    fx_t *fx = fx_new(3, (const uint8_t[]){1, 2, 3}, (const uint8_t[]){0, 1, 2});
    boot_all(fx);
    co_line_set_time(&fx->l[0].line, fx->tb.now);
    assert_true(co_flyma_detect_capable(&fx->c[0].flyma));
    run(fx, 150);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, CO_FLYMA_ID_ASK_CAPABLE, 0),
                     CO_FLYMA_ID_ASK_CAPABLE, NULL, 0);
    assert_int_equal(tu_log_count_id(&fx->tb, CO_FLYMA_ID_CAPABLE), 2);
    assert_int_equal(fx->c[0].capable, 2);
    fx_free(fx);
}

/* Wrong lengths are counted; an idle candidate ignores everything; a 0x71
 * naming our own node-id is not taken. */
static void test_malformed_and_idle(void **state)
{
    (void)state;
    fx_t *fx = fx_new(2, (const uint8_t[]){1, 2}, (const uint8_t[]){0, 0});
    co_line_t *tool = &fx->l[0].line;
    co_frame_t f;
    co_frame_set(&f, CO_FLYMA_ID_ACTIVE_MASTER, 0, (const uint8_t[]){0, 9}, 2);
    assert_true(co_line_send_raw(tool, &f));      /* candidate 2 idle: ignored */
    tu_run_until(&fx->tb, fx->tb.now + TU_MS);
    assert_int_equal(co_flyma_stats(&fx->c[1].flyma)->rx_ignored, 1);
    assert_int_equal(fx->c[1].states, 0);
    co_line_set_time(&fx->l[1].line, fx->tb.now);
    co_flyma_boot(&fx->c[1].flyma);
    co_frame_set(&f, CO_FLYMA_ID_ACTIVE_MASTER, 0, (const uint8_t[]){0}, 1);
    assert_true(co_line_send_raw(tool, &f));
    co_frame_set(&f, CO_FLYMA_ID_NEGOTIATE, 0, (const uint8_t[]){0}, 1);
    assert_true(co_line_send_raw(tool, &f));
    co_frame_set(&f, CO_FLYMA_ID_ACTIVE_MASTER, 0, (const uint8_t[]){0, 2}, 2);
    assert_true(co_line_send_raw(tool, &f));      /* our own id */
    tu_run_until(&fx->tb, fx->tb.now + TU_MS);
    assert_int_equal(co_flyma_stats(&fx->c[1].flyma)->rx_bad_length, 2);
    assert_int_equal(co_flyma_stats(&fx->c[1].flyma)->rx_ignored, 2);
    assert_int_equal(co_flyma_state(&fx->c[1].flyma), CO_FLYMA_WAITING);
    assert_false(co_flyma_force(&fx->c[0].flyma));   /* idle */
    fx_free(fx);
}

static const tu_od_row_t timing_rows[] = {
    { 0x1F90, 0, VAR, U8, RO, 0, 1, 6, NULL, 0, 0 },
    { 0x1F90, 1, VAR, U16, RW, 0, 2, 150, NULL, 0, 0 },
    { 0x1F90, 2, VAR, U16, RW, 0, 2, 250, NULL, 0, 0 },
    { 0x1F90, 3, VAR, U16, RW, 0, 2, 2, NULL, 0, 0 },
    { 0x1F90, 4, VAR, U16, RW, 0, 2, 1000, NULL, 0, 0 },
    { 0x1F90, 5, VAR, U16, RW, 0, 2, 20, NULL, 0, 0 },
    { 0x1F90, 6, VAR, U16, RW, 0, 2, 3000, NULL, 0, 0 },
    { 0x1F91, 0, VAR, U8, RO, 0, 1, 1, NULL, 0, 0 },
    { 0x1F91, 1, VAR, U16, RW, 0, 2, 80, NULL, 0, 0 },
};

static void test_timing_from_od(void **state)
{
    (void)state;
    co_od_t od;
    co_od_entry_t entries[16];
    uint8_t pool[64];
    co_od_subscription_t subs[2];
    co_od_init(&od, CO_MODE_CLASSIC, entries, 16, pool, sizeof pool, subs, 2);
    tu_od_add_rows(&od, timing_rows, sizeof timing_rows / sizeof timing_rows[0]);
    assert_true(co_od_seal(&od, 1));
    co_flyma_config_t c = {.priority = 9, .delay_ms = 7};
    co_flyma_config_from_od(&c, &od);
    assert_int_equal(c.detect_ms, 150);
    assert_int_equal(c.delay_ms, 250);
    assert_int_equal(c.priority, 2);
    assert_int_equal(c.priority_slot_ms, 1000);
    assert_int_equal(c.device_slot_ms, 20);
    assert_int_equal(c.multiple_master_ms, 3000);
    assert_int_equal(c.capable_ms, 80);
}

/* ------------------------------------------------------------ co_stack */

typedef struct stack_fx {
    tu_bus_t tb;
    tu_line_t l[3];
    co_stack_t st[3];
    co_stack_arena_t arena[3];
    unsigned char memory[3][8 * 1024];
    int masters_told[3];
} stack_fx_t;

static void on_stack_flyma(co_flyma_t *flyma, co_flyma_event_t event, co_flyma_state_t state,
                           uint8_t master, uint8_t priority, void *user)
{
    (void)flyma;
    (void)master;
    (void)priority;
    int *told = user;
    if (event == CO_FLYMA_EV_STATE && state == CO_FLYMA_MASTER) {
        (*told)++;
    }
}

/* Three nodes built by co_stack (heartbeat 50 ms, the master's watched for
 * 150 ms): node 11 (priority 0) becomes the master; taken off the bus, the
 * others lose its heartbeat, reset the network with NMT (0x000 [82 00]),
 * boot again and node 10 takes over. */
static void run_stack_master_killed(bool at_once)
{
    stack_fx_t *fx = calloc(1, sizeof *fx);
    assert_non_null(fx);
    tu_bus_init(&fx->tb, CO_MODE_CLASSIC, false);
    const uint8_t ids[3] = {10, 11, 12}, prio[3] = {1, 0, 1};
    for (int i = 0; i < 3; i++) {
        co_line_t *line = tu_bus_add_line(&fx->tb, &fx->l[i]);
        co_stack_arena_init(&fx->arena[i], fx->memory[i], sizeof fx->memory[i]);
        co_stack_line_config_t lc = {.heartbeat_entries = 4};
        assert_int_equal(co_stack_init(&fx->st[i], line, &lc,
                                       co_stack_arena_allocator(&fx->arena[i])), CO_STACK_OK);
        co_stack_node_config_t nc = {.node_id = ids[i], .heartbeat_ms = 50};
        assert_int_equal(co_stack_node_init(&fx->st[i], &nc), CO_STACK_OK);
        co_stack_flyma_config_t fc = {
            .flyma = {.priority = prio[i], .detect_ms = DETECT_MS, .delay_ms = DELAY_MS,
                      .priority_slot_ms = PSLOT_MS, .device_slot_ms = DSLOT_MS,
                      .multiple_master_ms = CYCLE_MS, .ind = on_stack_flyma,
                      .user = &fx->masters_told[i]},
            .master_heartbeat_ms = 150};
        assert_int_equal(co_stack_flyma_init(&fx->st[i], &fc), CO_STACK_OK);
        assert_int_equal(co_stack_flyma_init(&fx->st[i], &fc), CO_STACK_ERR_STATE);
        assert_int_equal(co_stack_failed_part(&fx->st[i]), CO_STACK_PART_FLYMA);
        assert_int_equal(co_stack_boot(&fx->st[i]), CO_STACK_OK);
    }
    /* power-on: two detections around the network reset, then node 11's slot;
     * at_once: it dies the moment it was elected (no heartbeat of it after) */
    uint64_t elected = 2 * (DELAY_MS + DETECT_MS) * TU_MS + 400 * TU_MS;
    while (at_once && co_flyma_state(co_stack_flyma(&fx->st[0])) != CO_FLYMA_SLAVE) {
        tu_run_until(&fx->tb, fx->tb.now + TU_MS);
        assert_true(fx->tb.now < elected);
    }
    if (!at_once) {
        tu_run_until(&fx->tb, elected);
    }
    long reset = tu_log_find_id(&fx->tb, 0x000, 0);
    tu_assert_logged(&fx->tb, reset, 0x000, (const uint8_t[]){0x82, 0x00}, 2);
    assert_int_equal(co_flyma_state(co_stack_flyma(&fx->st[1])), CO_FLYMA_MASTER);
    assert_int_equal(co_flyma_master(co_stack_flyma(&fx->st[0])), 11);
    assert_int_equal(co_flyma_master(co_stack_flyma(&fx->st[2])), 11);
    assert_int_equal(fx->masters_told[1], 1);

    co_membus_detach(&fx->tb.bus, &fx->l[1].line);
    tu_log_clear(&fx->tb);
    uint64_t t_kill = fx->tb.now;
    tu_run_until(&fx->tb, t_kill + (200 + DELAY_MS + DETECT_MS + 1700) * TU_MS);
    long nmt = tu_log_find_id(&fx->tb, 0x000, 0);
    tu_assert_logged(&fx->tb, nmt, 0x000, (const uint8_t[]){0x82, 0x00}, 2);
    assert_true(fx->tb.log[nmt].t_us >= t_kill + 150 * TU_MS);
    assert_true(fx->tb.log[nmt].t_us <= t_kill + 210 * TU_MS);
    /* both booted again (boot-up 0x70A / 0x70C after the reset) */
    long boot = -1;
    for (size_t i = (size_t)nmt; i < fx->tb.log_count && boot < 0; i++) {
        boot = fx->tb.log[i].frame.id == 0x70A ? (long)i : -1;
    }
    tu_assert_logged(&fx->tb, boot, 0x70A, (const uint8_t[]){0}, 1);
    assert_int_equal(co_flyma_state(co_stack_flyma(&fx->st[0])), CO_FLYMA_MASTER);
    assert_int_equal(co_flyma_master(co_stack_flyma(&fx->st[2])), 10);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, CO_FLYMA_ID_ACTIVE_MASTER, 0),
                     CO_FLYMA_ID_ACTIVE_MASTER, (const uint8_t[]){0x01, 10}, 2);
    for (int i = 0; i < 3; i++) {
        co_stack_deinit(&fx->st[i]);
    }
    free(fx);
}

static void test_stack_three_nodes_master_killed(void **state)
{
    (void)state;
    run_stack_master_killed(false);
}

/* The slaves watch the new master from the moment it is elected: one that
 * dies before its first heartbeat is noticed too (co_hb_consumer_expect). */
static void test_stack_master_killed_at_once(void **state)
{
    (void)state;
    run_stack_master_killed(true);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_power_on_negotiation),
        cmocka_unit_test(test_master_lost),
        cmocka_unit_test(test_late_joiners),
        cmocka_unit_test(test_two_masters_meet),
        cmocka_unit_test(test_detect_capable),
        cmocka_unit_test(test_malformed_and_idle),
        cmocka_unit_test(test_timing_from_od),
        cmocka_unit_test(test_stack_three_nodes_master_killed),
        cmocka_unit_test(test_stack_master_killed_at_once),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
