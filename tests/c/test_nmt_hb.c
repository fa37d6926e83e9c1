/* NMT slave/master and heartbeat producer/consumer, on three lines connected
 * by the in-process bus with a fake clock. Every bus test runs twice: on a
 * classic bus and on an FD bus with bit-rate switch; the sniffer checks every
 * frame's CAN-ID, flags, length and bytes.
 *
 * Lines: m (index 0: NMT master, frame injector), a (index 1), b (index 2).
 * Node-ids: master 1, node A 5, node B 6; node 9 is a "remote" whose frames
 * the tests inject by hand from line m. */
#include "test_util.h"

#define ID_MASTER 1
#define ID_A 5
#define ID_B 6
#define ID_X 9
#define ID_Y 10
#define MAX_EV 1024
#define MS(x) ((uint64_t)(x) * TU_MS)

enum { EV_STATE = 1, EV_RESET, EV_ALLOW, EV_HB };

typedef struct ev {
    int kind;
    uint8_t node;             /* node the event is about */
    int a;                    /* EV_STATE old, EV_RESET kind, EV_HB event */
    int b;                    /* EV_STATE new, EV_HB state, EV_ALLOW/RESET: state then */
    uint64_t t;
    bool bootup_queued;       /* EV_RESET: the boot-up frame was already queued */
} ev_t;

typedef struct fx {
    tu_bus_t tb;
    tu_line_t l[3];
    co_line_t *m, *a, *b;
    co_node_t master, na, nb;
    co_hb_consumer_t cons;
    co_hb_entry_t entries[8];
    bool allow;               /* answer of allow_operational */
    ev_t ev[MAX_EV];
    int nev;
} fx_t;

/* ------------------------------------------------------------ recording */

static void add_ev(fx_t *fx, int kind, uint8_t node, int a, int b)
{
    assert_true(fx->nev < MAX_EV);
    memset(&fx->ev[fx->nev], 0, sizeof fx->ev[0]);
    fx->ev[fx->nev].kind = kind;
    fx->ev[fx->nev].node = node;
    fx->ev[fx->nev].a = a;
    fx->ev[fx->nev].b = b;
    fx->ev[fx->nev].t = fx->tb.now;
    fx->nev++;
}

/* Count events; -1 matches anything. */
static int count_ev(const fx_t *fx, int kind, int node, int a, int b)
{
    int i, n = 0;
    for (i = 0; i < fx->nev; i++) {
        const ev_t *e = &fx->ev[i];
        if (e->kind == kind && (node < 0 || e->node == node) && (a < 0 || e->a == a) &&
            (b < 0 || e->b == b))
            n++;
    }
    return n;
}

/* Last event of a kind about a node, NULL if none. */
static const ev_t *last_ev(const fx_t *fx, int kind, int node)
{
    int i;
    for (i = fx->nev - 1; i >= 0; i--)
        if (fx->ev[i].kind == kind && fx->ev[i].node == node)
            return &fx->ev[i];
    return NULL;
}

static bool tx_has_bootup(const co_line_t *line, uint8_t node_id)
{
    uint32_t i;
    for (i = 0; i < co_line_tx_count(line); i++) {
        const co_frame_t *f = co_line_tx_at(line, i);
        if (f->id == 0x700u + node_id && f->len >= 1 && f->data[0] == 0x00)
            return true;
    }
    return false;
}

static void on_state(co_node_t *node, co_nmt_state_t old_state, co_nmt_state_t new_state,
                     void *user)
{
    add_ev(user, EV_STATE, node->nmt.node_id, old_state, new_state);
}

static bool on_allow(co_node_t *node, void *user)
{
    fx_t *fx = user;
    add_ev(fx, EV_ALLOW, node->nmt.node_id, 0, co_node_state(node));
    return fx->allow;
}

static void on_reset(co_node_t *node, co_nmt_command_t kind, void *user)
{
    fx_t *fx = user;
    add_ev(fx, EV_RESET, node->nmt.node_id, kind, co_node_state(node));
    fx->ev[fx->nev - 1].bootup_queued = tx_has_bootup(node->line, node->nmt.node_id);
}

static const co_node_indications_t node_ind = {.state_changed = on_state, .allow_operational = on_allow, .reset = on_reset};
static const co_node_indications_t node_ind_no_allow = {.state_changed = on_state};

static void on_hb(co_hb_consumer_t *c, uint8_t node_id, co_hb_event_t event,
                  co_nmt_state_t state, void *user)
{
    fx_t *fx = user;
    assert_ptr_equal(c, &fx->cons);
    add_ev(fx, EV_HB, node_id, event, state);
}

/* ------------------------------------------------------------ fixture */

static int setup(void **state, co_mode_t mode, bool brs)
{
    fx_t *fx = calloc(1, sizeof *fx);
    if (fx == NULL)
        return -1;
    tu_bus_init(&fx->tb, mode, brs);
    fx->m = tu_bus_add_line(&fx->tb, &fx->l[0]);
    fx->a = tu_bus_add_line(&fx->tb, &fx->l[1]);
    fx->b = tu_bus_add_line(&fx->tb, &fx->l[2]);
    fx->allow = true;
    *state = fx;
    return 0;
}

static int setup_classic(void **state) { return setup(state, CO_MODE_CLASSIC, false); }
static int setup_fd(void **state) { return setup(state, CO_MODE_FD, true); }

static int teardown(void **state)
{
    free(*state);
    return 0;
}

/* ------------------------------------------------------------ helpers */

static void step(fx_t *fx, uint64_t t) { tu_step(&fx->tb, t); }
static void run_until(fx_t *fx, uint64_t t) { tu_run_until(&fx->tb, t); }

static void boot_node(fx_t *fx, co_node_t *node, co_line_t *line, uint8_t id, uint16_t hb_ms)
{
    assert_true(co_node_init(node, line, id, hb_ms, &node_ind, fx));
    co_node_boot(node);
    step(fx, fx->tb.now);
}

/* Both nodes A (line a) and B (line b) booted, no heartbeat. */
static void boot_a_b(fx_t *fx)
{
    boot_node(fx, &fx->na, fx->a, ID_A, 0);
    boot_node(fx, &fx->nb, fx->b, ID_B, 0);
}

/* NMT command from line m (no local node there). */
static void nmt(fx_t *fx, co_nmt_command_t cmd, uint8_t node_id)
{
    assert_true(co_nmt_master_send(fx->m, NULL, cmd, node_id, false));
    step(fx, fx->tb.now);
}

/* Any frame from line m, at the current time. */
static void inject(fx_t *fx, uint32_t id, const uint8_t *data, size_t len)
{
    co_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = id;
    f.len = (uint8_t)len;
    if (len > 0)
        memcpy(f.data, data, len);
    if (fx->tb.mode == CO_MODE_FD)
        f.len = co_fd_len_round(len);
    assert_true(co_line_send_frame(fx->m, &f));
    step(fx, fx->tb.now);
}

static void inject_hb(fx_t *fx, uint8_t node_id, uint8_t state_byte)
{
    inject(fx, 0x700u + node_id, &state_byte, 1);
}

static void consumer_on_a(fx_t *fx)
{
    assert_true(co_hb_consumer_init(&fx->cons, fx->a, fx->entries, 8, on_hb, fx));
}

/* Logged heartbeat/boot-up frames of a node: their times and state bytes. */
static size_t hb_frames(const fx_t *fx, uint8_t node_id, uint64_t *at, uint8_t *st, size_t max)
{
    size_t i, n = 0;
    for (i = 0; i < fx->tb.log_count && n < max; i++) {
        const tu_logged_t *e = &fx->tb.log[i];
        if (e->frame.id != 0x700u + node_id)
            continue;
        tu_assert_frame(&e->frame, 0x700u + node_id, tu_bus_flags(&fx->tb), &e->frame.data[0], 1);
        at[n] = e->t_us;
        st[n] = e->frame.data[0];
        n++;
    }
    return n;
}

/* Drive a node (already booted) into `target` with master commands. */
static void drive_to(fx_t *fx, uint8_t id, co_nmt_state_t target)
{
    nmt(fx, CO_NMT_CMD_PRE_OPERATIONAL, id);
    if (target == CO_NMT_OPERATIONAL)
        nmt(fx, CO_NMT_CMD_START, id);
    else if (target == CO_NMT_STOPPED)
        nmt(fx, CO_NMT_CMD_STOP, id);
}

/* ================================================= pure helpers (no bus) */

static void test_nmt_command_codes_valid_exactly_five(void **state)
{
    unsigned c;
    (void)state;
    for (c = 0; c < 256; c++) {
        bool expected = c == 0x01 || c == 0x02 || c == 0x80 || c == 0x81 || c == 0x82;
        if (co_nmt_command_is_valid((uint8_t)c) != expected)
            fail_msg("co_nmt_command_is_valid(0x%02X) = %d", c, (int)!expected);
    }
}

static void test_nmt_command_targets(void **state)
{
    (void)state;
    assert_int_equal(co_nmt_command_target(CO_NMT_CMD_START), CO_NMT_OPERATIONAL);
    assert_int_equal(co_nmt_command_target(CO_NMT_CMD_STOP), CO_NMT_STOPPED);
    assert_int_equal(co_nmt_command_target(CO_NMT_CMD_PRE_OPERATIONAL), CO_NMT_PRE_OPERATIONAL);
    assert_int_equal(co_nmt_command_target(CO_NMT_CMD_RESET_NODE), CO_NMT_INITIALISING);
    assert_int_equal(co_nmt_command_target(CO_NMT_CMD_RESET_COMMUNICATION), CO_NMT_INITIALISING);
}

static void test_hb_state_valid_exactly_four(void **state)
{
    unsigned s;
    (void)state;
    for (s = 0; s < 256; s++) {
        bool expected = s == 0x00 || s == 0x04 || s == 0x05 || s == 0x7F;
        if (co_hb_state_is_valid((uint8_t)s) != expected)
            fail_msg("co_hb_state_is_valid(0x%02X) = %d", s, (int)!expected);
    }
}

static void test_hb_encode_frame(void **state)
{
    co_frame_t f;
    const uint8_t op[1] = {0x05}, boot[1] = {0x00};
    (void)state;
    memset(&f, 0xAA, sizeof f);
    assert_true(co_hb_encode(CO_NMT_OPERATIONAL, &f, 5));
    tu_assert_frame(&f, 0x705, 0, op, 1);
    assert_true(co_hb_encode(CO_NMT_INITIALISING, &f, 127));
    tu_assert_frame(&f, 0x77F, 0, boot, 1);
    assert_false(co_hb_encode(CO_NMT_OPERATIONAL, &f, 0));
    assert_false(co_hb_encode(CO_NMT_OPERATIONAL, &f, 128));
    assert_false(co_hb_encode(CO_NMT_UNKNOWN, &f, 5));
}

static void test_nmt_init_refuses_bad_node_id(void **state)
{
    fx_t *fx = *state;
    co_nmt_t slave;
    static const co_nmt_indications_t none = {NULL, NULL, NULL};
    assert_false(co_nmt_init(&slave, fx->a, 0, &none, NULL));
    assert_false(co_nmt_init(&slave, fx->a, 128, &none, NULL));
    assert_false(co_nmt_init(&slave, fx->a, 255, &none, NULL));
}

static void test_node_init_refuses_bad_node_id(void **state)
{
    fx_t *fx = *state;
    co_node_t node;
    assert_false(co_node_init(&node, fx->a, 0, 100, &node_ind, fx));
    assert_false(co_node_init(&node, fx->a, 128, 100, &node_ind, fx));
}

/* ================================================= boot-up */

static void test_node_init_sends_nothing_and_sets_line_node_id(void **state)
{
    fx_t *fx = *state;
    assert_true(co_node_init(&fx->na, fx->a, ID_A, 100, &node_ind, fx));
    assert_int_equal(fx->a->node_id, ID_A);
    assert_int_equal(co_node_state(&fx->na), CO_NMT_INITIALISING);
    run_until(fx, MS(1000));
    assert_int_equal(fx->tb.log_count, 0);
}

static void test_boot_sends_bootup_frame(void **state)
{
    fx_t *fx = *state;
    const uint8_t bootup[1] = {0x00};
    step(fx, MS(3));
    boot_node(fx, &fx->na, fx->a, ID_A, 0);
    assert_int_equal(fx->tb.log_count, 1);
    tu_assert_logged(&fx->tb, 0, 0x705, bootup, 1);
    assert_int_equal(fx->tb.log[0].t_us, MS(3));
}

static void test_boot_enters_pre_operational(void **state)
{
    fx_t *fx = *state;
    const ev_t *e;
    boot_node(fx, &fx->na, fx->a, ID_A, 0);
    assert_int_equal(co_node_state(&fx->na), CO_NMT_PRE_OPERATIONAL);
    e = last_ev(fx, EV_STATE, ID_A);
    assert_non_null(e);
    assert_int_equal(e->b, CO_NMT_PRE_OPERATIONAL);
    assert_int_equal(count_ev(fx, EV_RESET, -1, -1, -1), 0);
}

static void test_boot_nmt_alone_without_node(void **state)
{
    /* The NMT slave works on its own too (without co_node). */
    fx_t *fx = *state;
    co_nmt_t slave;
    static const co_nmt_indications_t none = {NULL, NULL, NULL};
    const uint8_t bootup[1] = {0x00};
    assert_true(co_nmt_init(&slave, fx->a, 42, &none, NULL));
    assert_int_equal(co_nmt_state(&slave), CO_NMT_INITIALISING);
    co_nmt_boot(&slave);
    step(fx, 0);
    assert_int_equal(co_nmt_state(&slave), CO_NMT_PRE_OPERATIONAL);
    assert_int_equal(fx->tb.log_count, 1);
    tu_assert_logged(&fx->tb, 0, 0x700 + 42, bootup, 1);
    nmt(fx, CO_NMT_CMD_START, 42);
    assert_int_equal(co_nmt_state(&slave), CO_NMT_OPERATIONAL);
    co_nmt_apply(&slave, CO_NMT_CMD_STOP);
    assert_int_equal(co_nmt_state(&slave), CO_NMT_STOPPED);
}

/* ================================================= NMT commands */

static void test_master_send_frame_bytes(void **state)
{
    fx_t *fx = *state;
    const uint8_t start5[2] = {0x01, 0x05}, resetall[2] = {0x81, 0x00};
    const uint8_t stop127[2] = {0x02, 0x7F}, preop[2] = {0x80, 0x05}, rcomm[2] = {0x82, 0x06};
    assert_true(co_nmt_master_send(fx->m, NULL, CO_NMT_CMD_START, 5, false));
    assert_true(co_nmt_master_send(fx->m, NULL, CO_NMT_CMD_RESET_NODE, 0, false));
    assert_true(co_nmt_master_send(fx->m, NULL, CO_NMT_CMD_STOP, 127, false));
    assert_true(co_nmt_master_send(fx->m, NULL, CO_NMT_CMD_PRE_OPERATIONAL, 5, true));
    assert_true(co_nmt_master_send(fx->m, NULL, CO_NMT_CMD_RESET_COMMUNICATION, 6, false));
    step(fx, 0);
    assert_int_equal(fx->tb.log_count, 5);
    tu_assert_logged(&fx->tb, 0, 0x000, start5, 2);
    tu_assert_logged(&fx->tb, 1, 0x000, resetall, 2);
    tu_assert_logged(&fx->tb, 2, 0x000, stop127, 2);
    tu_assert_logged(&fx->tb, 3, 0x000, preop, 2);
    tu_assert_logged(&fx->tb, 4, 0x000, rcomm, 2);
}

static void test_master_send_refuses_invalid_arguments(void **state)
{
    fx_t *fx = *state;
    assert_false(co_nmt_master_send(fx->m, NULL, (co_nmt_command_t)0x03, 5, false));
    assert_false(co_nmt_master_send(fx->m, NULL, (co_nmt_command_t)0x00, 5, false));
    assert_false(co_nmt_master_send(fx->m, NULL, CO_NMT_CMD_START, 128, false));
    assert_false(co_nmt_master_send(fx->m, NULL, CO_NMT_CMD_START, 255, false));
    step(fx, 0);
    assert_int_equal(fx->tb.log_count, 0);
}

typedef struct transition {
    co_nmt_command_t cmd;
    co_nmt_state_t expected;
    bool reset;
} transition_t;

static const transition_t all_commands[] = {
    {CO_NMT_CMD_START, CO_NMT_OPERATIONAL, false},
    {CO_NMT_CMD_STOP, CO_NMT_STOPPED, false},
    {CO_NMT_CMD_PRE_OPERATIONAL, CO_NMT_PRE_OPERATIONAL, false},
    {CO_NMT_CMD_RESET_NODE, CO_NMT_PRE_OPERATIONAL, true},
    {CO_NMT_CMD_RESET_COMMUNICATION, CO_NMT_PRE_OPERATIONAL, true},
};

/* CiA 301 NMT slave: from pre-operational, operational and stopped every
 * command is accepted. A reset goes through initialising, sends a new
 * boot-up and ends in pre-operational. */
static void check_commands_from(fx_t *fx, co_nmt_state_t from)
{
    size_t i;
    boot_a_b(fx);
    for (i = 0; i < sizeof all_commands / sizeof all_commands[0]; i++) {
        const transition_t *t = &all_commands[i];
        size_t bootups_before;
        int resets_before;
        drive_to(fx, ID_A, from);
        assert_int_equal(co_node_state(&fx->na), from);
        bootups_before = tu_log_count_id(&fx->tb, 0x705);
        resets_before = count_ev(fx, EV_RESET, ID_A, t->cmd, -1);
        nmt(fx, t->cmd, ID_A);
        if (co_node_state(&fx->na) != t->expected)
            fail_msg("command 0x%02X from state 0x%02X: state 0x%02X, expected 0x%02X",
                     t->cmd, from, co_node_state(&fx->na), t->expected);
        assert_int_equal(tu_log_count_id(&fx->tb, 0x705), bootups_before + (t->reset ? 1 : 0));
        assert_int_equal(count_ev(fx, EV_RESET, ID_A, t->cmd, -1), resets_before + (t->reset ? 1 : 0));
        /* node B was not addressed */
        assert_int_equal(co_node_state(&fx->nb), CO_NMT_PRE_OPERATIONAL);
    }
    assert_int_equal(fx->a->stats.nmt_bad_command + fx->a->stats.nmt_bad_length +
                     fx->a->stats.nmt_bad_node, 0);
}

static void test_nmt_commands_from_pre_operational(void **state)
{
    check_commands_from(*state, CO_NMT_PRE_OPERATIONAL);
}

static void test_nmt_commands_from_operational(void **state)
{
    check_commands_from(*state, CO_NMT_OPERATIONAL);
}

static void test_nmt_commands_from_stopped(void **state)
{
    check_commands_from(*state, CO_NMT_STOPPED);
}

static void test_nmt_state_changed_reports_old_and_new(void **state)
{
    fx_t *fx = *state;
    const ev_t *e;
    boot_a_b(fx);
    nmt(fx, CO_NMT_CMD_START, ID_A);
    e = last_ev(fx, EV_STATE, ID_A);
    assert_int_equal(e->a, CO_NMT_PRE_OPERATIONAL);
    assert_int_equal(e->b, CO_NMT_OPERATIONAL);
    nmt(fx, CO_NMT_CMD_STOP, ID_A);
    e = last_ev(fx, EV_STATE, ID_A);
    assert_int_equal(e->a, CO_NMT_OPERATIONAL);
    assert_int_equal(e->b, CO_NMT_STOPPED);
    nmt(fx, CO_NMT_CMD_PRE_OPERATIONAL, ID_A);
    e = last_ev(fx, EV_STATE, ID_A);
    assert_int_equal(e->a, CO_NMT_STOPPED);
    assert_int_equal(e->b, CO_NMT_PRE_OPERATIONAL);
}

static void test_nmt_start_vetoed_stays_pre_operational(void **state)
{
    fx_t *fx = *state;
    int changes;
    boot_a_b(fx);
    fx->allow = false;
    changes = count_ev(fx, EV_STATE, ID_A, -1, -1);
    nmt(fx, CO_NMT_CMD_START, ID_A);
    assert_int_equal(co_node_state(&fx->na), CO_NMT_PRE_OPERATIONAL);
    assert_int_equal(fx->na.nmt.vetoed, 1);
    assert_int_equal(count_ev(fx, EV_ALLOW, ID_A, -1, -1), 1);
    assert_int_equal(count_ev(fx, EV_STATE, ID_A, -1, -1), changes);
    /* allowed again: the next start works */
    fx->allow = true;
    nmt(fx, CO_NMT_CMD_START, ID_A);
    assert_int_equal(co_node_state(&fx->na), CO_NMT_OPERATIONAL);
    assert_int_equal(fx->na.nmt.vetoed, 1);
}

static void test_nmt_start_vetoed_from_stopped_stays_stopped(void **state)
{
    fx_t *fx = *state;
    boot_a_b(fx);
    nmt(fx, CO_NMT_CMD_STOP, ID_A);
    fx->allow = false;
    nmt(fx, CO_NMT_CMD_START, ID_A);
    assert_int_equal(co_node_state(&fx->na), CO_NMT_STOPPED);
    assert_int_equal(fx->na.nmt.vetoed, 1);
}

static void test_nmt_allow_operational_asked_before_change(void **state)
{
    fx_t *fx = *state;
    const ev_t *e;
    boot_a_b(fx);
    nmt(fx, CO_NMT_CMD_START, ID_A);
    e = last_ev(fx, EV_ALLOW, ID_A);
    assert_non_null(e);
    assert_int_equal(e->b, CO_NMT_PRE_OPERATIONAL);    /* test pass: not changed yet */
    assert_int_equal(co_node_state(&fx->na), CO_NMT_OPERATIONAL);
}

static void test_nmt_without_allow_indication_start_allowed(void **state)
{
    fx_t *fx = *state;
    assert_true(co_node_init(&fx->na, fx->a, ID_A, 0, &node_ind_no_allow, fx));
    co_node_boot(&fx->na);
    step(fx, 0);
    nmt(fx, CO_NMT_CMD_START, ID_A);
    assert_int_equal(co_node_state(&fx->na), CO_NMT_OPERATIONAL);
}

static void test_nmt_node_zero_addresses_all(void **state)
{
    fx_t *fx = *state;
    boot_a_b(fx);
    nmt(fx, CO_NMT_CMD_START, 0);
    assert_int_equal(co_node_state(&fx->na), CO_NMT_OPERATIONAL);
    assert_int_equal(co_node_state(&fx->nb), CO_NMT_OPERATIONAL);
    nmt(fx, CO_NMT_CMD_STOP, 0);
    assert_int_equal(co_node_state(&fx->na), CO_NMT_STOPPED);
    assert_int_equal(co_node_state(&fx->nb), CO_NMT_STOPPED);
}

static void test_nmt_reset_all_boots_every_node(void **state)
{
    fx_t *fx = *state;
    boot_a_b(fx);
    nmt(fx, CO_NMT_CMD_START, 0);
    tu_log_clear(&fx->tb);
    nmt(fx, CO_NMT_CMD_RESET_COMMUNICATION, 0);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x705), 1);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x706), 1);
    assert_int_equal(co_node_state(&fx->na), CO_NMT_PRE_OPERATIONAL);
    assert_int_equal(co_node_state(&fx->nb), CO_NMT_PRE_OPERATIONAL);
}

static void test_nmt_command_for_other_node_ignored(void **state)
{
    fx_t *fx = *state;
    co_line_stats_t before;
    boot_a_b(fx);
    before = fx->a->stats;
    nmt(fx, CO_NMT_CMD_START, ID_B);
    assert_int_equal(co_node_state(&fx->na), CO_NMT_PRE_OPERATIONAL);
    assert_int_equal(co_node_state(&fx->nb), CO_NMT_OPERATIONAL);
    nmt(fx, CO_NMT_CMD_RESET_NODE, 100);
    assert_int_equal(co_node_state(&fx->na), CO_NMT_PRE_OPERATIONAL);
    assert_int_equal(co_node_state(&fx->nb), CO_NMT_OPERATIONAL);
    assert_int_equal(count_ev(fx, EV_RESET, -1, -1, -1), 0);
    /* not an error: nothing counted */
    assert_int_equal(fx->a->stats.nmt_bad_node, before.nmt_bad_node);
    assert_int_equal(fx->a->stats.nmt_bad_command, before.nmt_bad_command);
    assert_int_equal(fx->a->stats.rx_unhandled, before.rx_unhandled);
}

static void test_nmt_wrong_length_ignored_and_counted(void **state)
{
    fx_t *fx = *state;
    const uint8_t one[1] = {0x01};
    const uint8_t three[3] = {0x01, ID_A, 0x00};
    const uint8_t zero_len[1] = {0};
    boot_a_b(fx);
    inject(fx, 0x000, one, 1);
    inject(fx, 0x000, three, 3);
    inject(fx, 0x000, zero_len, 0);
    assert_int_equal(co_node_state(&fx->na), CO_NMT_PRE_OPERATIONAL);
    assert_int_equal(fx->a->stats.nmt_bad_length, 3);
    assert_int_equal(fx->a->stats.nmt_bad_command, 0);
    assert_int_equal(fx->a->stats.nmt_bad_node, 0);
}

static void test_nmt_unknown_command_ignored_and_counted(void **state)
{
    fx_t *fx = *state;
    const uint8_t bad_own[2] = {0x03, ID_A}, bad_all[2] = {0x83, 0x00};
    boot_a_b(fx);
    inject(fx, 0x000, bad_own, 2);
    inject(fx, 0x000, bad_all, 2);
    assert_int_equal(co_node_state(&fx->na), CO_NMT_PRE_OPERATIONAL);
    assert_int_equal(fx->a->stats.nmt_bad_command, 2);
    assert_int_equal(count_ev(fx, EV_RESET, -1, -1, -1), 0);
}

static void test_nmt_node_id_above_127_ignored_and_counted(void **state)
{
    fx_t *fx = *state;
    const uint8_t n128[2] = {0x01, 0x80}, n255[2] = {0x81, 0xFF};
    boot_a_b(fx);
    inject(fx, 0x000, n128, 2);
    inject(fx, 0x000, n255, 2);
    assert_int_equal(co_node_state(&fx->na), CO_NMT_PRE_OPERATIONAL);
    assert_int_equal(fx->a->stats.nmt_bad_node, 2);
    assert_int_equal(count_ev(fx, EV_RESET, -1, -1, -1), 0);
}

static void check_reset(fx_t *fx, co_nmt_command_t kind)
{
    const ev_t *e;
    long cmd_at, boot_at;
    int i, reset_index = -1, preop_index = -1;
    const uint8_t bootup[1] = {0x00};
    boot_a_b(fx);
    nmt(fx, CO_NMT_CMD_START, ID_A);
    tu_log_clear(&fx->tb);
    fx->nev = 0;
    nmt(fx, kind, ID_A);
    /* reset indication, with the node not yet announced */
    assert_int_equal(count_ev(fx, EV_RESET, ID_A, kind, -1), 1);
    e = last_ev(fx, EV_RESET, ID_A);
    assert_false(e->bootup_queued);
    /* then a boot-up frame after the command frame */
    cmd_at = tu_log_find_id(&fx->tb, 0x000, 0);
    boot_at = tu_log_find_id(&fx->tb, 0x705, 0);
    assert_true(cmd_at >= 0);
    assert_true(boot_at > cmd_at);
    tu_assert_logged(&fx->tb, boot_at, 0x705, bootup, 1);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x705), 1);
    /* then pre-operational, reported after the reset indication */
    assert_int_equal(co_node_state(&fx->na), CO_NMT_PRE_OPERATIONAL);
    for (i = 0; i < fx->nev; i++) {
        if (fx->ev[i].kind == EV_RESET && reset_index < 0)
            reset_index = i;
        if (fx->ev[i].kind == EV_STATE && fx->ev[i].b == CO_NMT_PRE_OPERATIONAL)
            preop_index = i;
    }
    assert_true(reset_index >= 0);
    assert_true(preop_index > reset_index);
    assert_int_equal(co_node_state(&fx->nb), CO_NMT_PRE_OPERATIONAL);
}

static void test_nmt_reset_node_indication_bootup_preop(void **state)
{
    check_reset(*state, CO_NMT_CMD_RESET_NODE);
}

static void test_nmt_reset_comm_indication_bootup_preop(void **state)
{
    check_reset(*state, CO_NMT_CMD_RESET_COMMUNICATION);
}

static void test_master_include_self_applies_to_own_node(void **state)
{
    fx_t *fx = *state;
    const uint8_t start_all[2] = {0x01, 0x00};
    boot_node(fx, &fx->master, fx->m, ID_MASTER, 0);
    boot_a_b(fx);
    tu_log_clear(&fx->tb);
    assert_true(co_nmt_master_send(fx->m, &fx->master.nmt, CO_NMT_CMD_START, 0, true));
    step(fx, fx->tb.now);
    assert_int_equal(co_node_state(&fx->master), CO_NMT_OPERATIONAL);
    assert_int_equal(co_node_state(&fx->na), CO_NMT_OPERATIONAL);
    assert_int_equal(co_node_state(&fx->nb), CO_NMT_OPERATIONAL);
    assert_int_equal(fx->tb.log_count, 1);
    tu_assert_logged(&fx->tb, 0, 0x000, start_all, 2);
}

static void test_master_without_include_self_leaves_own_node(void **state)
{
    fx_t *fx = *state;
    boot_node(fx, &fx->master, fx->m, ID_MASTER, 0);
    boot_a_b(fx);
    assert_true(co_nmt_master_send(fx->m, &fx->master.nmt, CO_NMT_CMD_START, 0, false));
    step(fx, fx->tb.now);
    assert_int_equal(co_node_state(&fx->master), CO_NMT_PRE_OPERATIONAL);
    assert_int_equal(co_node_state(&fx->na), CO_NMT_OPERATIONAL);
    assert_int_equal(co_node_state(&fx->nb), CO_NMT_OPERATIONAL);
}

static void test_master_to_own_id_applies_locally(void **state)
{
    fx_t *fx = *state;
    const uint8_t stop_self[2] = {0x02, ID_MASTER};
    boot_node(fx, &fx->master, fx->m, ID_MASTER, 0);
    boot_a_b(fx);
    tu_log_clear(&fx->tb);
    assert_true(co_nmt_master_send(fx->m, &fx->master.nmt, CO_NMT_CMD_STOP, ID_MASTER, false));
    step(fx, fx->tb.now);
    assert_int_equal(co_node_state(&fx->master), CO_NMT_STOPPED);
    assert_int_equal(co_node_state(&fx->na), CO_NMT_PRE_OPERATIONAL);
    assert_int_equal(co_node_state(&fx->nb), CO_NMT_PRE_OPERATIONAL);
    assert_int_equal(fx->tb.log_count, 1);
    tu_assert_logged(&fx->tb, 0, 0x000, stop_self, 2);
}

static void test_master_reset_self_sends_own_bootup(void **state)
{
    fx_t *fx = *state;
    const uint8_t bootup[1] = {0x00};
    boot_node(fx, &fx->master, fx->m, ID_MASTER, 0);
    tu_log_clear(&fx->tb);
    assert_true(co_nmt_master_send(fx->m, &fx->master.nmt, CO_NMT_CMD_RESET_NODE, ID_MASTER, false));
    step(fx, fx->tb.now);
    assert_int_equal(count_ev(fx, EV_RESET, ID_MASTER, CO_NMT_CMD_RESET_NODE, -1), 1);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x701), 1);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, 0x701, 0), 0x701, bootup, 1);
    assert_int_equal(co_node_state(&fx->master), CO_NMT_PRE_OPERATIONAL);
}

/* ================================================= heartbeat producer */

static void test_heartbeat_period_exact(void **state)
{
    fx_t *fx = *state;
    uint64_t at[16];
    uint8_t st[16];
    size_t n;
    step(fx, MS(10));
    boot_node(fx, &fx->na, fx->a, ID_A, 100);
    run_until(fx, MS(10) + MS(350));
    n = hb_frames(fx, ID_A, at, st, 16);
    assert_int_equal(n, 4);
    assert_int_equal(st[0], 0x00);
    assert_int_equal(at[0], MS(10));
    assert_int_equal(st[1], 0x7F);
    assert_int_equal(at[1], MS(110));
    assert_int_equal(st[2], 0x7F);
    assert_int_equal(at[2], MS(210));
    assert_int_equal(st[3], 0x7F);
    assert_int_equal(at[3], MS(310));
}

static void test_heartbeat_period_does_not_drift(void **state)
{
    fx_t *fx = *state;
    uint64_t at[128];
    uint8_t st[128];
    size_t n, i;
    boot_node(fx, &fx->na, fx->a, ID_A, 7);
    run_until(fx, MS(700));
    n = hb_frames(fx, ID_A, at, st, 128);
    assert_int_equal(n, 101);             /* boot-up + 100 heartbeats */
    for (i = 1; i < n; i++)
        assert_int_equal(at[i], MS(7) * i);
}

static void test_heartbeat_time_change_takes_effect_at_once(void **state)
{
    fx_t *fx = *state;
    uint64_t at[16];
    uint8_t st[16];
    size_t n;
    boot_node(fx, &fx->na, fx->a, ID_A, 100);
    run_until(fx, MS(250));
    co_node_set_heartbeat(&fx->na, 30);      /* line time is 250 ms */
    run_until(fx, MS(345));
    n = hb_frames(fx, ID_A, at, st, 16);
    assert_int_equal(n, 6);
    assert_int_equal(at[1], MS(100));
    assert_int_equal(at[2], MS(200));
    assert_int_equal(at[3], MS(280));
    assert_int_equal(at[4], MS(310));
    assert_int_equal(at[5], MS(340));
}

static void test_heartbeat_time_zero_stops_producer(void **state)
{
    fx_t *fx = *state;
    uint64_t at[16];
    uint8_t st[16];
    boot_node(fx, &fx->na, fx->a, ID_A, 100);
    run_until(fx, MS(250));
    co_node_set_heartbeat(&fx->na, 0);
    assert_true(tu_next_deadline(&fx->tb) == CO_TIME_NEVER);
    run_until(fx, MS(5000));
    assert_int_equal(hb_frames(fx, ID_A, at, st, 16), 3);    /* boot-up, 100, 200 */
    co_node_set_heartbeat(&fx->na, 50);                       /* and on again */
    run_until(fx, MS(5120));
    assert_int_equal(hb_frames(fx, ID_A, at, st, 16), 5);
    assert_int_equal(at[3], MS(5050));
    assert_int_equal(at[4], MS(5100));
}

static void test_heartbeat_off_at_boot_sends_only_bootup(void **state)
{
    fx_t *fx = *state;
    boot_node(fx, &fx->na, fx->a, ID_A, 0);
    run_until(fx, MS(10000));
    assert_int_equal(fx->tb.log_count, 1);
    assert_true(tu_next_deadline(&fx->tb) == CO_TIME_NEVER);
}

static void test_heartbeat_byte_is_current_state(void **state)
{
    fx_t *fx = *state;
    uint64_t at[16];
    uint8_t st[16];
    boot_node(fx, &fx->na, fx->a, ID_A, 100);
    run_until(fx, MS(150));
    nmt(fx, CO_NMT_CMD_START, ID_A);
    run_until(fx, MS(250));
    nmt(fx, CO_NMT_CMD_STOP, ID_A);
    run_until(fx, MS(350));
    nmt(fx, CO_NMT_CMD_PRE_OPERATIONAL, ID_A);
    run_until(fx, MS(450));
    assert_int_equal(hb_frames(fx, ID_A, at, st, 16), 5);
    assert_int_equal(st[0], 0x00);
    assert_int_equal(st[1], 0x7F);
    assert_int_equal(st[2], 0x05);
    assert_int_equal(st[3], 0x04);           /* heartbeat continues when stopped */
    assert_int_equal(st[4], 0x7F);
}

static void test_heartbeat_producer_stop(void **state)
{
    fx_t *fx = *state;
    uint64_t at[16];
    uint8_t st[16];
    boot_node(fx, &fx->na, fx->a, ID_A, 100);
    run_until(fx, MS(150));
    co_hb_producer_stop(&fx->na.heartbeat);
    run_until(fx, MS(1000));
    assert_int_equal(hb_frames(fx, ID_A, at, st, 16), 2);
}

static void test_reset_communication_restores_heartbeat_time(void **state)
{
    fx_t *fx = *state;
    uint64_t at[32];
    uint8_t st[32];
    size_t n;
    boot_node(fx, &fx->na, fx->a, ID_A, 100);
    co_node_set_heartbeat(&fx->na, 20);
    run_until(fx, MS(50));                    /* heartbeats at 20, 40 */
    nmt(fx, CO_NMT_CMD_RESET_COMMUNICATION, ID_A);   /* at 50 ms: 0x1017 back to 100 */
    run_until(fx, MS(260));
    n = hb_frames(fx, ID_A, at, st, 32);
    assert_int_equal(fx->na.heartbeat.time_ms, 100);
    assert_int_equal(n, 6);
    assert_int_equal(at[1], MS(20));
    assert_int_equal(at[2], MS(40));
    assert_int_equal(st[3], 0x00);            /* new boot-up at 50 */
    assert_int_equal(at[3], MS(50));
    assert_int_equal(at[4], MS(150));
    assert_int_equal(at[5], MS(250));
}

static void test_node_deinit_stops_heartbeat_and_nmt(void **state)
{
    fx_t *fx = *state;
    uint64_t at[16];
    uint8_t st[16];
    boot_node(fx, &fx->na, fx->a, ID_A, 100);
    run_until(fx, MS(150));
    co_node_deinit(&fx->na);
    assert_int_equal(fx->a->node_id, 0);
    run_until(fx, MS(1000));
    assert_int_equal(hb_frames(fx, ID_A, at, st, 16), 2);
    nmt(fx, CO_NMT_CMD_START, ID_A);
    assert_int_equal(co_node_state(&fx->na), CO_NMT_PRE_OPERATIONAL);
    assert_int_equal(fx->a->stats.rx_unhandled, 1);
}

/* ================================================= heartbeat consumer */

static void test_consumer_init_subscribes_heartbeat_ids(void **state)
{
    fx_t *fx = *state;
    consumer_on_a(fx);
    inject_hb(fx, 1, 0x05);
    inject_hb(fx, 127, 0x05);
    assert_int_equal(fx->a->stats.rx_unhandled, 0);
    assert_int_equal(fx->cons.last_state[1], 0x05);
    assert_int_equal(fx->cons.last_state[127], 0x05);
    assert_int_equal(fx->cons.last_state[9], CO_NMT_UNKNOWN);
}

static void test_consumer_frame_on_0x700_counted_no_event(void **state)
{
    fx_t *fx = *state;
    const uint8_t op[1] = {0x05};
    co_line_stats_t *s = &fx->a->stats;
    consumer_on_a(fx);
    inject(fx, 0x700, op, 1);
    assert_int_equal(count_ev(fx, EV_HB, -1, -1, -1), 0);
    assert_int_equal(s->hb_bad_node + s->rx_unhandled, 1);
}

static void test_consumer_monitoring_starts_at_first_heartbeat(void **state)
{
    fx_t *fx = *state;
    consumer_on_a(fx);
    assert_int_equal(co_hb_consumer_watch(&fx->cons, ID_X, 100), CO_HB_CONFIG_OK);
    run_until(fx, MS(1000));
    assert_int_equal(co_hb_consumer_monitor(&fx->cons, ID_X), CO_HB_MONITOR_OFF);
    assert_int_equal(count_ev(fx, EV_HB, ID_X, CO_HB_LOST, -1), 0);
    inject_hb(fx, ID_X, 0x05);
    assert_int_equal(co_hb_consumer_monitor(&fx->cons, ID_X), CO_HB_MONITOR_ACTIVE);
    assert_int_equal(count_ev(fx, EV_HB, ID_X, CO_HB_STARTED, -1), 1);
}

static void test_consumer_lost_exactly_after_consumer_time(void **state)
{
    fx_t *fx = *state;
    const ev_t *e;
    const uint64_t t0 = MS(1000) + 17;
    consumer_on_a(fx);
    assert_int_equal(co_hb_consumer_watch(&fx->cons, ID_X, 100), CO_HB_CONFIG_OK);
    step(fx, t0);
    inject_hb(fx, ID_X, 0x7F);
    run_until(fx, t0 + MS(100) - 1);
    assert_int_equal(co_hb_consumer_monitor(&fx->cons, ID_X), CO_HB_MONITOR_ACTIVE);
    assert_int_equal(count_ev(fx, EV_HB, ID_X, CO_HB_LOST, -1), 0);
    run_until(fx, t0 + MS(100));
    assert_int_equal(co_hb_consumer_monitor(&fx->cons, ID_X), CO_HB_MONITOR_LOST);
    assert_int_equal(count_ev(fx, EV_HB, ID_X, CO_HB_LOST, -1), 1);
    e = last_ev(fx, EV_HB, ID_X);
    assert_int_equal(e->a, CO_HB_LOST);
    assert_int_equal(e->t, t0 + MS(100));
}

static void test_consumer_heartbeats_in_time_never_lost(void **state)
{
    fx_t *fx = *state;
    int i;
    consumer_on_a(fx);
    assert_int_equal(co_hb_consumer_watch(&fx->cons, ID_X, 100), CO_HB_CONFIG_OK);
    for (i = 0; i < 50; i++) {
        run_until(fx, MS(99) * (uint64_t)i);
        inject_hb(fx, ID_X, 0x05);
    }
    assert_int_equal(count_ev(fx, EV_HB, ID_X, CO_HB_LOST, -1), 0);
    assert_int_equal(count_ev(fx, EV_HB, ID_X, CO_HB_STARTED, -1), 1);
    assert_int_equal(co_hb_consumer_monitor(&fx->cons, ID_X), CO_HB_MONITOR_ACTIVE);
}

static void test_consumer_lost_reported_once(void **state)
{
    fx_t *fx = *state;
    consumer_on_a(fx);
    assert_int_equal(co_hb_consumer_watch(&fx->cons, ID_X, 100), CO_HB_CONFIG_OK);
    inject_hb(fx, ID_X, 0x05);
    run_until(fx, MS(10000));
    assert_int_equal(count_ev(fx, EV_HB, ID_X, CO_HB_LOST, -1), 1);
    assert_true(tu_next_deadline(&fx->tb) == CO_TIME_NEVER);
}

static void test_consumer_started_again_when_heartbeats_resume(void **state)
{
    fx_t *fx = *state;
    const ev_t *e;
    consumer_on_a(fx);
    assert_int_equal(co_hb_consumer_watch(&fx->cons, ID_X, 100), CO_HB_CONFIG_OK);
    inject_hb(fx, ID_X, 0x05);
    run_until(fx, MS(500));
    assert_int_equal(co_hb_consumer_monitor(&fx->cons, ID_X), CO_HB_MONITOR_LOST);
    inject_hb(fx, ID_X, 0x05);
    assert_int_equal(co_hb_consumer_monitor(&fx->cons, ID_X), CO_HB_MONITOR_ACTIVE);
    assert_int_equal(count_ev(fx, EV_HB, ID_X, CO_HB_STARTED, -1), 2);
    e = last_ev(fx, EV_HB, ID_X);
    assert_int_equal(e->t, MS(500));
    /* and lost again, exactly one consumer time later */
    run_until(fx, MS(600) - 1);
    assert_int_equal(count_ev(fx, EV_HB, ID_X, CO_HB_LOST, -1), 1);
    run_until(fx, MS(600));
    assert_int_equal(count_ev(fx, EV_HB, ID_X, CO_HB_LOST, -1), 2);
}

static void test_consumer_bootup_event(void **state)
{
    fx_t *fx = *state;
    consumer_on_a(fx);
    assert_int_equal(co_hb_consumer_watch(&fx->cons, ID_X, 100), CO_HB_CONFIG_OK);
    inject_hb(fx, ID_X, 0x00);
    assert_int_equal(count_ev(fx, EV_HB, ID_X, CO_HB_BOOTUP, CO_NMT_INITIALISING), 1);
    /* also for nodes nobody watches */
    inject_hb(fx, 33, 0x00);
    assert_int_equal(count_ev(fx, EV_HB, 33, CO_HB_BOOTUP, CO_NMT_INITIALISING), 1);
    assert_int_equal(count_ev(fx, EV_HB, 33, CO_HB_STARTED, -1), 0);
}

static void test_consumer_bootup_of_real_node(void **state)
{
    fx_t *fx = *state;
    consumer_on_a(fx);
    boot_node(fx, &fx->nb, fx->b, ID_B, 0);
    assert_int_equal(count_ev(fx, EV_HB, ID_B, CO_HB_BOOTUP, -1), 1);
}

static void test_consumer_state_changed_events(void **state)
{
    fx_t *fx = *state;
    consumer_on_a(fx);
    assert_int_equal(co_hb_consumer_watch(&fx->cons, ID_X, 1000), CO_HB_CONFIG_OK);
    inject_hb(fx, ID_X, 0x7F);
    inject_hb(fx, ID_X, 0x7F);
    inject_hb(fx, ID_X, 0x05);
    assert_int_equal(count_ev(fx, EV_HB, ID_X, CO_HB_STATE_CHANGED, CO_NMT_OPERATIONAL), 1);
    inject_hb(fx, ID_X, 0x05);
    inject_hb(fx, ID_X, 0x04);
    assert_int_equal(count_ev(fx, EV_HB, ID_X, CO_HB_STATE_CHANGED, CO_NMT_OPERATIONAL), 1);
    assert_int_equal(count_ev(fx, EV_HB, ID_X, CO_HB_STATE_CHANGED, CO_NMT_STOPPED), 1);
    assert_int_equal(fx->cons.last_state[ID_X], 0x04);
}

static void test_consumer_state_of_unwatched_node_reported(void **state)
{
    fx_t *fx = *state;
    consumer_on_a(fx);
    inject_hb(fx, 40, 0x7F);
    inject_hb(fx, 40, 0x05);
    assert_int_equal(count_ev(fx, EV_HB, 40, CO_HB_STATE_CHANGED, CO_NMT_OPERATIONAL), 1);
    assert_int_equal(count_ev(fx, EV_HB, 40, CO_HB_STARTED, -1), 0);
    assert_int_equal(co_hb_consumer_monitor(&fx->cons, 40), CO_HB_MONITOR_OFF);
    assert_int_equal(fx->cons.last_state[40], 0x05);
}

static void test_consumer_follows_real_producer_then_lost(void **state)
{
    fx_t *fx = *state;
    const ev_t *e;
    consumer_on_a(fx);
    assert_int_equal(co_hb_consumer_watch(&fx->cons, ID_B, 120), CO_HB_CONFIG_OK);
    boot_node(fx, &fx->nb, fx->b, ID_B, 50);
    run_until(fx, MS(1010));                  /* heartbeats at 50, 100, ..., 1000 */
    assert_int_equal(count_ev(fx, EV_HB, ID_B, CO_HB_STARTED, -1), 1);
    assert_int_equal(count_ev(fx, EV_HB, ID_B, CO_HB_LOST, -1), 0);
    co_node_set_heartbeat(&fx->nb, 0);
    run_until(fx, MS(2000));
    assert_int_equal(count_ev(fx, EV_HB, ID_B, CO_HB_LOST, -1), 1);
    e = last_ev(fx, EV_HB, ID_B);
    assert_int_equal(e->a, CO_HB_LOST);
    assert_int_equal(e->t, MS(1000) + MS(120));
}

static void test_consumer_state_only_watch_gives_way_to_an_entry_with_time(void **state)
{
    fx_t *fx = *state;
    consumer_on_a(fx);
    /* a watch with time 0 (states only) takes the last entry ... */
    assert_int_equal(co_hb_consumer_watch(&fx->cons, ID_X, 0), CO_HB_CONFIG_OK);
    assert_int_equal(co_hb_consumer_get_entry(&fx->cons, (uint8_t)(fx->cons.capacity - 1)),
                     (uint32_t)ID_X << 16);
    /* ... and gives way when an entry with a time names the node */
    assert_int_equal(co_hb_consumer_set_entry(&fx->cons, 0, ((uint32_t)ID_X << 16) | 100),
                     CO_HB_CONFIG_OK);
    assert_int_equal(co_hb_consumer_get_entry(&fx->cons, (uint8_t)(fx->cons.capacity - 1)), 0);
    /* a later state-only watch leaves the timed entry as it is */
    assert_int_equal(co_hb_consumer_watch(&fx->cons, ID_X, 0), CO_HB_CONFIG_OK);
    assert_int_equal(co_hb_consumer_get_entry(&fx->cons, 0), ((uint32_t)ID_X << 16) | 100);
    inject_hb(fx, ID_X, 0x05);
    run_until(fx, MS(150));
    assert_int_equal(count_ev(fx, EV_HB, ID_X, CO_HB_LOST, -1), 1);
}

static void test_consumer_duplicate_node_refused(void **state)
{
    fx_t *fx = *state;
    consumer_on_a(fx);
    assert_int_equal(co_hb_consumer_set_entry(&fx->cons, 0, ((uint32_t)ID_X << 16) | 100),
                     CO_HB_CONFIG_OK);
    assert_int_equal(co_hb_consumer_set_entry(&fx->cons, 1, ((uint32_t)ID_X << 16) | 200),
                     CO_HB_CONFIG_DUPLICATE);
    assert_int_equal(co_hb_consumer_get_entry(&fx->cons, 1), 0);
    assert_int_equal(co_hb_consumer_get_entry(&fx->cons, 0), ((uint32_t)ID_X << 16) | 100);
    /* rewriting the same entry is not a duplicate */
    assert_int_equal(co_hb_consumer_set_entry(&fx->cons, 0, ((uint32_t)ID_X << 16) | 300),
                     CO_HB_CONFIG_OK);
    assert_int_equal(co_hb_consumer_get_entry(&fx->cons, 0), ((uint32_t)ID_X << 16) | 300);
}

static void test_consumer_watch_updates_existing_entry(void **state)
{
    fx_t *fx = *state;
    int i, used = 0;
    consumer_on_a(fx);
    assert_int_equal(co_hb_consumer_watch(&fx->cons, ID_X, 100), CO_HB_CONFIG_OK);
    assert_int_equal(co_hb_consumer_watch(&fx->cons, ID_X, 250), CO_HB_CONFIG_OK);
    for (i = 0; i < 8; i++) {
        uint32_t v = co_hb_consumer_get_entry(&fx->cons, (uint8_t)i);
        if (v != 0) {
            used++;
            assert_int_equal(v, ((uint32_t)ID_X << 16) | 250);
        }
    }
    assert_int_equal(used, 1);
}

static void test_consumer_watch_bad_node_refused(void **state)
{
    fx_t *fx = *state;
    int i;
    consumer_on_a(fx);
    assert_int_equal(co_hb_consumer_watch(&fx->cons, 0, 100), CO_HB_CONFIG_BAD_NODE);
    assert_int_equal(co_hb_consumer_watch(&fx->cons, 128, 100), CO_HB_CONFIG_BAD_NODE);
    assert_int_equal(co_hb_consumer_watch(&fx->cons, 255, 100), CO_HB_CONFIG_BAD_NODE);
    for (i = 0; i < 8; i++)
        assert_int_equal(co_hb_consumer_get_entry(&fx->cons, (uint8_t)i), 0);
}

/* CiA 301 0x1016: a node-id of 0 or above 127 leaves the entry unused. */
static void test_consumer_entry_node_above_127_means_unused(void **state)
{
    fx_t *fx = *state;
    consumer_on_a(fx);
    assert_int_equal(co_hb_consumer_set_entry(&fx->cons, 0, ((uint32_t)ID_X << 16) | 100),
                     CO_HB_CONFIG_OK);
    assert_int_equal(co_hb_consumer_set_entry(&fx->cons, 0, (128u << 16) | 100),
                     CO_HB_CONFIG_OK);
    assert_int_equal(co_hb_consumer_get_entry(&fx->cons, 0), 0);
    assert_int_equal(co_hb_consumer_set_entry(&fx->cons, 1, (255u << 16) | 100),
                     CO_HB_CONFIG_OK);
    assert_int_equal(co_hb_consumer_get_entry(&fx->cons, 1), 0);
    inject_hb(fx, ID_X, 0x05);
    run_until(fx, MS(1000));
    assert_int_equal(count_ev(fx, EV_HB, ID_X, CO_HB_STARTED, -1), 0);
    assert_int_equal(count_ev(fx, EV_HB, ID_X, CO_HB_LOST, -1), 0);
}

static void test_consumer_entry_index_outside_table(void **state)
{
    fx_t *fx = *state;
    consumer_on_a(fx);
    assert_int_equal(co_hb_consumer_set_entry(&fx->cons, 8, ((uint32_t)ID_X << 16) | 100),
                     CO_HB_CONFIG_NO_ROOM);
    assert_int_equal(co_hb_consumer_get_entry(&fx->cons, 8), 0);
}

/* Ticks: every heartbeat of a ticking node is told (watched or not), at most
 * one per interval; boot-ups stay CO_HB_BOOTUP; untick stops them; the table
 * holds CO_HB_TICKS nodes. */
static void test_consumer_ticks_every_heartbeat_bounded_by_interval(void **state)
{
    fx_t *fx = *state;
    uint8_t n;
    consumer_on_a(fx);
    assert_int_equal(co_hb_consumer_tick(&fx->cons, ID_X, 0), CO_HB_CONFIG_OK);
    for (n = 0; n < 3; n++) {
        inject_hb(fx, ID_X, 0x7F);
    }
    assert_int_equal(count_ev(fx, EV_HB, ID_X, CO_HB_TICK, CO_NMT_PRE_OPERATIONAL), 3);
    inject_hb(fx, ID_X, 0x00);                          /* boot-up: not a tick */
    assert_int_equal(count_ev(fx, EV_HB, ID_X, CO_HB_TICK, -1), 3);
    assert_int_equal(count_ev(fx, EV_HB, ID_X, CO_HB_BOOTUP, -1), 1);
    /* 50 ms interval: of heartbeats every 10 ms for 200 ms, one per 50 ms */
    assert_int_equal(co_hb_consumer_tick(&fx->cons, ID_X, 50), CO_HB_CONFIG_OK);
    fx->nev = 0;
    uint64_t start = fx->tb.now;
    for (n = 0; n < 20; n++) {
        run_until(fx, start + (uint64_t)n * 10 * TU_MS);
        inject_hb(fx, ID_X, 0x05);
    }
    assert_int_equal(count_ev(fx, EV_HB, ID_X, CO_HB_TICK, CO_NMT_OPERATIONAL), 4);
    co_hb_consumer_untick(&fx->cons, ID_X);
    fx->nev = 0;
    run_until(fx, fx->tb.now + 100 * TU_MS);
    inject_hb(fx, ID_X, 0x05);
    assert_int_equal(count_ev(fx, EV_HB, ID_X, CO_HB_TICK, -1), 0);
    for (n = 1; n <= CO_HB_TICKS; n++) {
        assert_int_equal(co_hb_consumer_tick(&fx->cons, n, 10), CO_HB_CONFIG_OK);
    }
    assert_int_equal(co_hb_consumer_tick(&fx->cons, CO_HB_TICKS + 1, 10), CO_HB_CONFIG_NO_ROOM);
    assert_int_equal(co_hb_consumer_tick(&fx->cons, 0, 10), CO_HB_CONFIG_BAD_NODE);
    assert_int_equal(co_hb_consumer_tick(&fx->cons, 128, 10), CO_HB_CONFIG_BAD_NODE);
    co_hb_consumer_untick(&fx->cons, 1);
    assert_int_equal(co_hb_consumer_tick(&fx->cons, CO_HB_TICKS + 1, 10), CO_HB_CONFIG_OK);
}

static void test_consumer_watch_table_full(void **state)
{
    fx_t *fx = *state;
    uint8_t n;
    consumer_on_a(fx);
    for (n = 1; n <= 8; n++)
        assert_int_equal(co_hb_consumer_watch(&fx->cons, n, 100), CO_HB_CONFIG_OK);
    assert_int_equal(co_hb_consumer_watch(&fx->cons, 9, 100), CO_HB_CONFIG_NO_ROOM);
}

static void test_consumer_entry_node_zero_disables(void **state)
{
    fx_t *fx = *state;
    consumer_on_a(fx);
    assert_int_equal(co_hb_consumer_set_entry(&fx->cons, 0, ((uint32_t)ID_X << 16) | 100),
                     CO_HB_CONFIG_OK);
    inject_hb(fx, ID_X, 0x05);
    run_until(fx, MS(50));
    assert_int_equal(co_hb_consumer_set_entry(&fx->cons, 0, 0), CO_HB_CONFIG_OK);
    run_until(fx, MS(1000));
    assert_int_equal(count_ev(fx, EV_HB, ID_X, CO_HB_LOST, -1), 0);
    assert_int_equal(co_hb_consumer_monitor(&fx->cons, ID_X), CO_HB_MONITOR_OFF);
    /* the freed entry takes another node */
    assert_int_equal(co_hb_consumer_set_entry(&fx->cons, 1, ((uint32_t)ID_X << 16) | 100),
                     CO_HB_CONFIG_OK);
}

static void test_consumer_set_entry_same_node_keeps_monitoring_new_time_from_now(void **state)
{
    fx_t *fx = *state;
    consumer_on_a(fx);
    assert_int_equal(co_hb_consumer_set_entry(&fx->cons, 0, ((uint32_t)ID_X << 16) | 100),
                     CO_HB_CONFIG_OK);
    inject_hb(fx, ID_X, 0x05);
    run_until(fx, MS(50));
    /* a new time for a node already monitored counts from now: no heartbeat
     * may ever come again, so monitoring must not wait for one */
    assert_int_equal(co_hb_consumer_set_entry(&fx->cons, 0, ((uint32_t)ID_X << 16) | 300),
                     CO_HB_CONFIG_OK);
    assert_int_equal(co_hb_consumer_monitor(&fx->cons, ID_X), CO_HB_MONITOR_ACTIVE);
    run_until(fx, MS(349));
    assert_int_equal(count_ev(fx, EV_HB, ID_X, CO_HB_LOST, -1), 0);
    run_until(fx, MS(351));
    assert_int_equal(count_ev(fx, EV_HB, ID_X, CO_HB_LOST, -1), 1);
    assert_int_equal(count_ev(fx, EV_HB, ID_X, CO_HB_STARTED, -1), 1);
}

static void test_consumer_set_entry_other_node_restarts_at_next_heartbeat(void **state)
{
    fx_t *fx = *state;
    consumer_on_a(fx);
    assert_int_equal(co_hb_consumer_set_entry(&fx->cons, 0, ((uint32_t)ID_X << 16) | 100),
                     CO_HB_CONFIG_OK);
    inject_hb(fx, ID_X, 0x05);
    run_until(fx, MS(50));
    assert_int_equal(co_hb_consumer_set_entry(&fx->cons, 0, ((uint32_t)ID_Y << 16) | 100),
                     CO_HB_CONFIG_OK);
    run_until(fx, MS(500));
    assert_int_equal(count_ev(fx, EV_HB, ID_X, CO_HB_LOST, -1), 0);
    assert_int_equal(count_ev(fx, EV_HB, ID_Y, CO_HB_LOST, -1), 0);
    inject_hb(fx, ID_Y, 0x05);
    assert_int_equal(count_ev(fx, EV_HB, ID_Y, CO_HB_STARTED, -1), 1);
    run_until(fx, MS(600));
    assert_int_equal(count_ev(fx, EV_HB, ID_Y, CO_HB_LOST, -1), 1);
}

static void test_consumer_wrong_length_counted_and_ignored(void **state)
{
    fx_t *fx = *state;
    const uint8_t two[2] = {0x05, 0x00};
    consumer_on_a(fx);
    assert_int_equal(co_hb_consumer_watch(&fx->cons, ID_X, 100), CO_HB_CONFIG_OK);
    inject(fx, 0x700 + ID_X, two, 0);
    inject(fx, 0x700 + ID_X, two, 2);
    assert_int_equal(fx->a->stats.hb_bad_length, 2);
    assert_int_equal(count_ev(fx, EV_HB, -1, -1, -1), 0);
    assert_int_equal(co_hb_consumer_monitor(&fx->cons, ID_X), CO_HB_MONITOR_OFF);
    assert_int_equal(fx->cons.last_state[ID_X], CO_NMT_UNKNOWN);
}

static void test_consumer_invalid_state_counted_and_ignored(void **state)
{
    fx_t *fx = *state;
    consumer_on_a(fx);
    assert_int_equal(co_hb_consumer_watch(&fx->cons, ID_X, 100), CO_HB_CONFIG_OK);
    inject_hb(fx, ID_X, 0x03);
    inject_hb(fx, ID_X, 0x85);        /* node-guarding toggle bit: not a heartbeat */
    inject_hb(fx, ID_X, 0xFF);
    assert_int_equal(fx->a->stats.hb_bad_state, 3);
    assert_int_equal(count_ev(fx, EV_HB, -1, -1, -1), 0);
    assert_int_equal(co_hb_consumer_monitor(&fx->cons, ID_X), CO_HB_MONITOR_OFF);
}

static void test_consumer_bad_heartbeat_does_not_feed_monitoring(void **state)
{
    fx_t *fx = *state;
    const uint8_t two[2] = {0x05, 0x00};
    consumer_on_a(fx);
    assert_int_equal(co_hb_consumer_watch(&fx->cons, ID_X, 100), CO_HB_CONFIG_OK);
    inject_hb(fx, ID_X, 0x05);
    run_until(fx, MS(60));
    inject_hb(fx, ID_X, 0x03);
    inject(fx, 0x700 + ID_X, two, 2);
    run_until(fx, MS(100));
    assert_int_equal(count_ev(fx, EV_HB, ID_X, CO_HB_LOST, -1), 1);
}

static void test_consumer_time_zero_never_lost(void **state)
{
    fx_t *fx = *state;
    consumer_on_a(fx);
    assert_int_equal(co_hb_consumer_watch(&fx->cons, ID_X, 0), CO_HB_CONFIG_OK);
    inject_hb(fx, ID_X, 0x7F);
    run_until(fx, MS(100000));
    inject_hb(fx, ID_X, 0x05);
    run_until(fx, MS(200000));
    assert_int_equal(count_ev(fx, EV_HB, ID_X, CO_HB_LOST, -1), 0);
    assert_int_equal(count_ev(fx, EV_HB, ID_X, CO_HB_STATE_CHANGED, CO_NMT_OPERATIONAL), 1);
    assert_true(tu_next_deadline(&fx->tb) == CO_TIME_NEVER);
}

static void test_consumer_deinit_stops_everything(void **state)
{
    fx_t *fx = *state;
    consumer_on_a(fx);
    assert_int_equal(co_hb_consumer_watch(&fx->cons, ID_X, 100), CO_HB_CONFIG_OK);
    inject_hb(fx, ID_X, 0x05);
    co_hb_consumer_deinit(&fx->cons);
    run_until(fx, MS(1000));
    inject_hb(fx, ID_X, 0x04);
    assert_int_equal(count_ev(fx, EV_HB, ID_X, CO_HB_LOST, -1), 0);
    assert_int_equal(count_ev(fx, EV_HB, ID_X, CO_HB_STATE_CHANGED, CO_NMT_STOPPED), 0);
    assert_int_equal(fx->a->stats.rx_unhandled, 1);
}

static void test_consumer_many_nodes_lost_each_at_own_time(void **state)
{
    fx_t *fx = *state;
    uint8_t n;
    consumer_on_a(fx);
    for (n = 1; n <= 8; n++)
        assert_int_equal(co_hb_consumer_watch(&fx->cons, (uint8_t)(20 + n), (uint16_t)(10 * n)),
                         CO_HB_CONFIG_OK);
    for (n = 1; n <= 8; n++)
        inject_hb(fx, (uint8_t)(20 + n), 0x05);
    for (n = 1; n <= 8; n++) {
        run_until(fx, MS(10) * n - 1);
        assert_int_equal(count_ev(fx, EV_HB, -1, CO_HB_LOST, -1), n - 1);
        run_until(fx, MS(10) * n);
        assert_int_equal(count_ev(fx, EV_HB, 20 + n, CO_HB_LOST, -1), 1);
    }
}

/* ================================================= runner */

#define BOTH(t) \
    {"classic: " #t, t, setup_classic, teardown, NULL}, \
    {"fd: " #t, t, setup_fd, teardown, NULL}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_nmt_command_codes_valid_exactly_five),
        cmocka_unit_test(test_nmt_command_targets),
        cmocka_unit_test(test_hb_state_valid_exactly_four),
        cmocka_unit_test(test_hb_encode_frame),
        BOTH(test_nmt_init_refuses_bad_node_id),
        BOTH(test_node_init_refuses_bad_node_id),
        BOTH(test_node_init_sends_nothing_and_sets_line_node_id),
        BOTH(test_boot_sends_bootup_frame),
        BOTH(test_boot_enters_pre_operational),
        BOTH(test_boot_nmt_alone_without_node),
        BOTH(test_master_send_frame_bytes),
        BOTH(test_master_send_refuses_invalid_arguments),
        BOTH(test_nmt_commands_from_pre_operational),
        BOTH(test_nmt_commands_from_operational),
        BOTH(test_nmt_commands_from_stopped),
        BOTH(test_nmt_state_changed_reports_old_and_new),
        BOTH(test_nmt_start_vetoed_stays_pre_operational),
        BOTH(test_nmt_start_vetoed_from_stopped_stays_stopped),
        BOTH(test_nmt_allow_operational_asked_before_change),
        BOTH(test_nmt_without_allow_indication_start_allowed),
        BOTH(test_nmt_node_zero_addresses_all),
        BOTH(test_nmt_reset_all_boots_every_node),
        BOTH(test_nmt_command_for_other_node_ignored),
        BOTH(test_nmt_wrong_length_ignored_and_counted),
        BOTH(test_nmt_unknown_command_ignored_and_counted),
        BOTH(test_nmt_node_id_above_127_ignored_and_counted),
        BOTH(test_nmt_reset_node_indication_bootup_preop),
        BOTH(test_nmt_reset_comm_indication_bootup_preop),
        BOTH(test_master_include_self_applies_to_own_node),
        BOTH(test_master_without_include_self_leaves_own_node),
        BOTH(test_master_to_own_id_applies_locally),
        BOTH(test_master_reset_self_sends_own_bootup),
        BOTH(test_heartbeat_period_exact),
        BOTH(test_heartbeat_period_does_not_drift),
        BOTH(test_heartbeat_time_change_takes_effect_at_once),
        BOTH(test_heartbeat_time_zero_stops_producer),
        BOTH(test_heartbeat_off_at_boot_sends_only_bootup),
        BOTH(test_heartbeat_byte_is_current_state),
        BOTH(test_heartbeat_producer_stop),
        BOTH(test_reset_communication_restores_heartbeat_time),
        BOTH(test_node_deinit_stops_heartbeat_and_nmt),
        BOTH(test_consumer_init_subscribes_heartbeat_ids),
        BOTH(test_consumer_frame_on_0x700_counted_no_event),
        BOTH(test_consumer_monitoring_starts_at_first_heartbeat),
        BOTH(test_consumer_lost_exactly_after_consumer_time),
        BOTH(test_consumer_heartbeats_in_time_never_lost),
        BOTH(test_consumer_lost_reported_once),
        BOTH(test_consumer_started_again_when_heartbeats_resume),
        BOTH(test_consumer_bootup_event),
        BOTH(test_consumer_bootup_of_real_node),
        BOTH(test_consumer_state_changed_events),
        BOTH(test_consumer_state_of_unwatched_node_reported),
        BOTH(test_consumer_follows_real_producer_then_lost),
        BOTH(test_consumer_duplicate_node_refused),
        BOTH(test_consumer_state_only_watch_gives_way_to_an_entry_with_time),
        BOTH(test_consumer_watch_updates_existing_entry),
        BOTH(test_consumer_watch_bad_node_refused),
        BOTH(test_consumer_entry_node_above_127_means_unused),
        BOTH(test_consumer_entry_index_outside_table),
        BOTH(test_consumer_ticks_every_heartbeat_bounded_by_interval),
        BOTH(test_consumer_watch_table_full),
        BOTH(test_consumer_entry_node_zero_disables),
        BOTH(test_consumer_set_entry_same_node_keeps_monitoring_new_time_from_now),
        BOTH(test_consumer_set_entry_other_node_restarts_at_next_heartbeat),
        BOTH(test_consumer_wrong_length_counted_and_ignored),
        BOTH(test_consumer_invalid_state_counted_and_ignored),
        BOTH(test_consumer_bad_heartbeat_does_not_feed_monitoring),
        BOTH(test_consumer_time_zero_never_lost),
        BOTH(test_consumer_deinit_stops_everything),
        BOTH(test_consumer_many_nodes_lost_each_at_own_time),
    };
    return cmocka_run_group_tests_name("nmt_hb", tests, NULL, NULL);
}
