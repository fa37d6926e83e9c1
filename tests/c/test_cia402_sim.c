/* The simulated CiA 402 drive (co_cia402_sim): every power state transition
 * from controlword writes, the statusword of each state, each mode's motion
 * model on a fake clock (profile position with its set-point handshake,
 * profile velocity, homing, CSP/CSV/CST on SYNC), the injected fault (0x603F,
 * EMCY bytes, Fault reaction active → Fault, fault reset), refused input,
 * and on the membus: the statusword's event-driven TPDO on every change. */
#include "test_od_util.h"

#include "canopenfd/co_cia402_sim.h"
#include "canopenfd/co_emcy.h"
#include "canopenfd/co_pdo.h"

#define I8 CO_TYPE_INTEGER8
#define I16 CO_TYPE_INTEGER16
#define I32 CO_TYPE_INTEGER32
#define TICK_US 1000u
#define SLOTS 64
#define POOL 2048

typedef struct fixture {
    tu_line_t tl;
    co_od_t od;
    co_od_entry_t entries[SLOTS];
    uint8_t pool[POOL];
    co_od_subscription_t subs[8];
    co_emcy_t emcy;
    co_emcy_msg_t emcy_queue[4];
    co_emcy_active_t emcy_active[4];
    co_cia402_sim_t sim;
    uint64_t now;
} fixture_t;

static const tu_od_row_t drive_rows[] = {
    {0x1001, 0, VAR, U8, RO, 0, 1, 0, NULL, 0, 0},
    {0x603F, 0, VAR, U16, RO, 0, 2, 0, NULL, 0, 0},
    {0x6040, 0, VAR, U16, RW, CO_OD_MAP_RPDO, 2, 0, NULL, 0, 0},
    {0x6041, 0, VAR, U16, RO, CO_OD_MAP_TPDO, 2, 0, NULL, 0, 0},
    {0x6060, 0, VAR, I8, RW, 0, 1, 0, NULL, 0, 0},
    {0x6061, 0, VAR, I8, RO, 0, 1, 0, NULL, 0, 0},
    {0x6064, 0, VAR, I32, RO, 0, 4, 0, NULL, 0, 0},
    {0x606C, 0, VAR, I32, RO, 0, 4, 0, NULL, 0, 0},
    {0x6071, 0, VAR, I16, RW, 0, 2, 0, NULL, 0, 0},
    {0x6077, 0, VAR, I16, RO, 0, 2, 0, NULL, 0, 0},
    {0x607A, 0, VAR, I32, RW, 0, 4, 0, NULL, 0, 0},
    {0x6081, 0, VAR, U32, RW, 0, 4, 1000, NULL, 0, 0},
    {0x6083, 0, VAR, U32, RW, 0, 4, 10000, NULL, 0, 0},
    {0x6084, 0, VAR, U32, RW, 0, 4, 10000, NULL, 0, 0},
    {0x6098, 0, VAR, I8, RW, 0, 1, 35, NULL, 0, 0},
    {0x60C2, 0, REC, U8, RO, 0, 1, 2, NULL, 0, 0},
    {0x60C2, 1, REC, U8, RW, 0, 1, 1, NULL, 0, 0},
    {0x60C2, 2, REC, I8, RW, 0, 1, -3, NULL, 0, 0},
    {0x60FF, 0, VAR, I32, RW, 0, 4, 0, NULL, 0, 0},
    /* PP, PV, homing, CSP, CSV; not CST */
    {0x6502, 0, VAR, U32, RO, 0, 4, 0x1A5, NULL, 0, 0},
};

/* The drive's objects, not sealed yet (complete: with 0x606C). */
static void od_add_drive(fixture_t *f, bool complete)
{
    size_t i;
    co_od_init(&f->od, CO_MODE_CLASSIC, f->entries, SLOTS, f->pool, POOL, f->subs, 8);
    for (i = 0; i < sizeof drive_rows / sizeof drive_rows[0]; i++) {
        if (!complete && drive_rows[i].index == 0x606C) {
            continue;
        }
        tu_od_add_rows(&f->od, &drive_rows[i], 1);
    }
}

static void od_build(fixture_t *f, bool complete)
{
    od_add_drive(f, complete);
    assert_true(co_od_seal(&f->od, 5));
}

static int setup(void **state)
{
    fixture_t *f = test_calloc(1, sizeof *f);
    co_emcy_config_t cfg;
    tu_line_init(&f->tl, CO_MODE_CLASSIC, false);
    od_build(f, true);
    memset(&cfg, 0, sizeof cfg);
    cfg.queue = f->emcy_queue;
    cfg.queue_capacity = 4;
    cfg.active = f->emcy_active;
    cfg.active_capacity = 4;
    assert_true(co_emcy_init(&f->emcy, &f->tl.line, 5, &cfg));
    co_emcy_set_nmt_state(&f->emcy, CO_NMT_PRE_OPERATIONAL);
    assert_true(co_cia402_sim_init(&f->sim, &f->tl.line, &f->od, NULL, &f->emcy, TICK_US));
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    fixture_t *f = *state;
    co_cia402_sim_deinit(&f->sim);
    co_emcy_deinit(&f->emcy);
    test_free(f);
    return 0;
}

/* ---------------------------------------------------------------- helpers */

static int64_t od_int(fixture_t *f, uint16_t index, bool is_signed)
{
    uint8_t b[4] = {0};
    uint32_t n = 0;
    int64_t v;
    assert_int_equal(co_od_get(&f->od, index, 0, b, 4, &n), 0);
    v = (int64_t)tu_le_get(b, n);
    if (is_signed && n < 8 && (v & ((int64_t)1 << (8 * n - 1)))) {
        v -= (int64_t)1 << (8 * n);
    }
    return v;
}

static void put(fixture_t *f, uint16_t index, int64_t v)
{
    const co_od_entry_t *e = co_od_find(&f->od, index, 0);
    uint8_t b[4];
    assert_non_null(e);
    tu_le_put(b, (uint64_t)v, e->size);
    assert_int_equal(co_od_put(&f->od, index, 0, b, e->size), 0);
}

static uint16_t statusword(fixture_t *f) { return (uint16_t)od_int(f, 0x6041, false); }

static void run_ms(fixture_t *f, uint32_t ms)
{
    uint32_t i;
    for (i = 0; i < ms; i++) {
        f->now += TICK_US;
        (void)co_line_process(&f->tl.line, f->now);
    }
}

/* Brings the drive to Operation enabled in `mode`. */
static void enable(fixture_t *f, int mode)
{
    put(f, 0x6060, mode);
    put(f, 0x6040, 0x06);
    put(f, 0x6040, 0x07);
    put(f, 0x6040, 0x0F);
    assert_int_equal(co_cia402_sim_state(&f->sim), CO_CIA402_OPERATION_ENABLED);
}

/* ---------------------------------------------------------------- states */

static void test_starts_switch_on_disabled(void **state)
{
    fixture_t *f = *state;
    assert_int_equal(co_cia402_sim_state(&f->sim), CO_CIA402_SWITCH_ON_DISABLED);
    assert_int_equal(statusword(f), 0x0240);     /* 0x40 + remote */
    assert_int_equal(statusword(f) & 0x4F, 0x40);
}

static void test_statusword_patterns(void **state)
{
    (void)state;
    /* the 0x4F / 0x6F masks of the profile identify each state */
    assert_int_equal(co_cia402_state_bits(CO_CIA402_NOT_READY_TO_SWITCH_ON) & 0x4F, 0x00);
    assert_int_equal(co_cia402_state_bits(CO_CIA402_SWITCH_ON_DISABLED) & 0x4F, 0x40);
    assert_int_equal(co_cia402_state_bits(CO_CIA402_READY_TO_SWITCH_ON) & 0x6F, 0x21);
    assert_int_equal(co_cia402_state_bits(CO_CIA402_SWITCHED_ON) & 0x6F, 0x23);
    assert_int_equal(co_cia402_state_bits(CO_CIA402_OPERATION_ENABLED) & 0x6F, 0x27);
    assert_int_equal(co_cia402_state_bits(CO_CIA402_QUICK_STOP_ACTIVE) & 0x6F, 0x07);
    assert_int_equal(co_cia402_state_bits(CO_CIA402_FAULT_REACTION_ACTIVE) & 0x4F, 0x0F);
    assert_int_equal(co_cia402_state_bits(CO_CIA402_FAULT) & 0x4F, 0x08);
}

typedef struct step {
    uint16_t controlword;
    co_cia402_state_t expect;
} step_t;

static void run_steps(fixture_t *f, const step_t *steps, size_t n)
{
    size_t i;
    for (i = 0; i < n; i++) {
        put(f, 0x6040, steps[i].controlword);
        assert_int_equal(co_cia402_sim_state(&f->sim), steps[i].expect);
        assert_int_equal(statusword(f) & 0x6F, co_cia402_state_bits(steps[i].expect) & 0x6F);
    }
}

static void test_every_transition(void **state)
{
    fixture_t *f = *state;
    static const step_t steps[] = {
        {0x07, CO_CIA402_SWITCH_ON_DISABLED},   /* switch on is not valid here */
        {0x06, CO_CIA402_READY_TO_SWITCH_ON},   /* 2 */
        {0x07, CO_CIA402_SWITCHED_ON},          /* 3 */
        {0x0F, CO_CIA402_OPERATION_ENABLED},    /* 4 */
        {0x07, CO_CIA402_SWITCHED_ON},          /* 5 */
        {0x06, CO_CIA402_READY_TO_SWITCH_ON},   /* 6 */
        {0x00, CO_CIA402_SWITCH_ON_DISABLED},   /* 7 (disable voltage) */
        {0x06, CO_CIA402_READY_TO_SWITCH_ON},
        {0x02, CO_CIA402_SWITCH_ON_DISABLED},   /* 7 (quick stop) */
        {0x06, CO_CIA402_READY_TO_SWITCH_ON},
        {0x0F, CO_CIA402_OPERATION_ENABLED},    /* 3 + 4 in one go */
        {0x06, CO_CIA402_READY_TO_SWITCH_ON},   /* 8 */
        {0x07, CO_CIA402_SWITCHED_ON},
        {0x00, CO_CIA402_SWITCH_ON_DISABLED},   /* 10 */
        {0x06, CO_CIA402_READY_TO_SWITCH_ON},
        {0x07, CO_CIA402_SWITCHED_ON},
        {0x02, CO_CIA402_SWITCH_ON_DISABLED},   /* 10 (quick stop) */
        {0x06, CO_CIA402_READY_TO_SWITCH_ON},
        {0x0F, CO_CIA402_OPERATION_ENABLED},
        {0x00, CO_CIA402_SWITCH_ON_DISABLED},   /* 9 */
        {0x06, CO_CIA402_READY_TO_SWITCH_ON},
        {0x0F, CO_CIA402_OPERATION_ENABLED},
        {0x02, CO_CIA402_QUICK_STOP_ACTIVE},    /* 11 */
        {0x06, CO_CIA402_QUICK_STOP_ACTIVE},    /* shutdown is not valid here */
        {0x0F, CO_CIA402_OPERATION_ENABLED},    /* 16 */
        {0x02, CO_CIA402_QUICK_STOP_ACTIVE},
        {0x00, CO_CIA402_SWITCH_ON_DISABLED},   /* 12 */
    };
    run_steps(f, steps, sizeof steps / sizeof steps[0]);
    /* 27 steps: 2 refused, 3 of them 3 + 4 in one go, plus the start */
    assert_int_equal(f->sim.transitions, 29);
}

static void test_fault_reaction_and_reset(void **state)
{
    fixture_t *f = *state;
    static const uint8_t emcy[8] = {0x10, 0x23, 0x23, 0, 0, 0, 0, 0};
    co_frame_t fr;
    enable(f, CO_CIA402_MODE_PROFILE_VELOCITY);
    co_cia402_sim_fault(&f->sim, 0x2310);
    assert_int_equal(co_cia402_sim_state(&f->sim), CO_CIA402_FAULT_REACTION_ACTIVE);
    assert_int_equal(statusword(f) & 0x4F, 0x0F);
    assert_int_equal(od_int(f, 0x603F, false), 0x2310);
    /* the EMCY: code 0x2310, register generic + current + device profile */
    run_ms(f, 1);
    assert_true(co_line_tx_pop(&f->tl.line, &fr));
    tu_assert_frame(&fr, 0x85, 0, emcy, 8);
    assert_int_equal(co_cia402_sim_state(&f->sim), CO_CIA402_FAULT);
    assert_int_equal(statusword(f) & 0x4F, 0x08);
    /* controls are ignored in Fault; a level (no edge) of bit 7 resets nothing */
    put(f, 0x6040, 0x0F);
    assert_int_equal(co_cia402_sim_state(&f->sim), CO_CIA402_FAULT);
    co_cia402_sim_fault(&f->sim, 0x5000);       /* a second fault changes nothing */
    assert_int_equal(od_int(f, 0x603F, false), 0x2310);
    put(f, 0x6040, 0x80);
    assert_int_equal(co_cia402_sim_state(&f->sim), CO_CIA402_SWITCH_ON_DISABLED);
    assert_int_equal(od_int(f, 0x603F, false), 0);
    assert_true(co_line_tx_pop(&f->tl.line, &fr));   /* error reset EMCY */
    assert_int_equal(fr.id, 0x85);
    assert_int_equal(fr.data[0] | fr.data[1], 0);
    put(f, 0x6040, 0x86);                            /* bit 7 still high: no command */
    assert_int_equal(co_cia402_sim_state(&f->sim), CO_CIA402_SWITCH_ON_DISABLED);
    put(f, 0x6040, 0x06);
    assert_int_equal(co_cia402_sim_state(&f->sim), CO_CIA402_READY_TO_SWITCH_ON);
}

static void test_fault_mid_move_stops(void **state)
{
    fixture_t *f = *state;
    enable(f, CO_CIA402_MODE_PROFILE_POSITION);
    put(f, 0x607A, 100000);
    put(f, 0x6040, 0x1F);
    run_ms(f, 50);
    assert_true(od_int(f, 0x606C, true) > 0);
    co_cia402_sim_fault(&f->sim, 0x7121);
    run_ms(f, 2);
    assert_int_equal(co_cia402_sim_state(&f->sim), CO_CIA402_FAULT);
    assert_int_equal(od_int(f, 0x606C, true), 0);
    int64_t stopped = od_int(f, 0x6064, true);
    run_ms(f, 20);
    assert_int_equal(od_int(f, 0x6064, true), stopped);
    assert_int_equal(statusword(f) & CO_CIA402_SW_TARGET_REACHED, 0);
}

/* ---------------------------------------------------------------- modes */

static void test_profile_position_move(void **state)
{
    fixture_t *f = *state;
    uint32_t ms;
    enable(f, CO_CIA402_MODE_PROFILE_POSITION);
    assert_true(statusword(f) & CO_CIA402_SW_TARGET_REACHED);   /* holding, no set-point */
    put(f, 0x607A, 500);
    put(f, 0x6040, 0x1F);                                       /* new set-point */
    assert_true(statusword(f) & CO_CIA402_SW_MODE_BIT12);       /* acknowledged */
    assert_false(statusword(f) & CO_CIA402_SW_TARGET_REACHED);
    put(f, 0x6040, 0x0F);
    assert_false(statusword(f) & CO_CIA402_SW_MODE_BIT12);
    /* 1000 u/s, 10000 u/s²: 0.1 s to full speed, 500 u need ~0.6 s */
    for (ms = 0; ms < 2000 && !(statusword(f) & CO_CIA402_SW_TARGET_REACHED); ms++) {
        run_ms(f, 1);
        assert_true(od_int(f, 0x606C, true) <= 1000);
    }
    assert_int_equal(od_int(f, 0x6064, true), 500);
    assert_int_equal(od_int(f, 0x606C, true), 0);
    assert_in_range(ms, 550, 650);
    /* relative move backwards */
    put(f, 0x607A, -200);
    put(f, 0x6040, 0x5F);
    put(f, 0x6040, 0x4F);
    run_ms(f, 1000);
    assert_int_equal(od_int(f, 0x6064, true), 300);
}

static void test_profile_position_buffered_and_immediate(void **state)
{
    fixture_t *f = *state;
    enable(f, CO_CIA402_MODE_PROFILE_POSITION);
    put(f, 0x607A, 1000);
    put(f, 0x6040, 0x1F);
    put(f, 0x6040, 0x0F);
    run_ms(f, 100);
    /* without bit 5 the next set-point waits for the first target */
    put(f, 0x607A, 200);
    put(f, 0x6040, 0x1F);
    put(f, 0x6040, 0x0F);
    run_ms(f, 300);
    assert_true(od_int(f, 0x6064, true) > 200);     /* still heading for 1000 */
    run_ms(f, 3000);
    assert_int_equal(od_int(f, 0x6064, true), 200);
    /* with bit 5 it replaces the move in progress */
    put(f, 0x607A, 5000);
    put(f, 0x6040, 0x1F);
    put(f, 0x6040, 0x0F);
    run_ms(f, 200);
    put(f, 0x607A, 0);
    put(f, 0x6040, 0x3F);
    put(f, 0x6040, 0x2F);
    run_ms(f, 3000);
    assert_int_equal(od_int(f, 0x6064, true), 0);
    assert_true(statusword(f) & CO_CIA402_SW_TARGET_REACHED);
}

static void test_profile_velocity_and_quick_stop(void **state)
{
    fixture_t *f = *state;
    enable(f, CO_CIA402_MODE_PROFILE_VELOCITY);
    assert_true(statusword(f) & CO_CIA402_SW_MODE_BIT12);       /* speed 0 */
    put(f, 0x60FF, -400);
    assert_false(statusword(f) & CO_CIA402_SW_TARGET_REACHED);  /* at once, not at the tick */
    run_ms(f, 10);
    assert_int_equal(od_int(f, 0x606C, true), -100);            /* 10000 u/s² for 10 ms */
    assert_false(statusword(f) & CO_CIA402_SW_TARGET_REACHED);
    run_ms(f, 40);
    assert_int_equal(od_int(f, 0x606C, true), -400);
    assert_true(statusword(f) & CO_CIA402_SW_TARGET_REACHED);
    assert_true(od_int(f, 0x6064, true) < 0);
    put(f, 0x6040, 0x02);                                       /* quick stop: decelerate */
    assert_int_equal(co_cia402_sim_state(&f->sim), CO_CIA402_QUICK_STOP_ACTIVE);
    run_ms(f, 20);
    assert_int_equal(od_int(f, 0x606C, true), -200);
    run_ms(f, 30);
    assert_int_equal(od_int(f, 0x606C, true), 0);
}

static void test_homing(void **state)
{
    fixture_t *f = *state;
    enable(f, CO_CIA402_MODE_PROFILE_VELOCITY);
    put(f, 0x60FF, 1000);
    run_ms(f, 200);
    assert_true(od_int(f, 0x6064, true) > 50);
    put(f, 0x6040, 0x07);
    put(f, 0x6060, CO_CIA402_MODE_HOMING);
    put(f, 0x6040, 0x0F);
    assert_false(statusword(f) & CO_CIA402_SW_MODE_BIT12);
    put(f, 0x6040, 0x1F);
    run_ms(f, 1);
    assert_int_equal(od_int(f, 0x6064, true), 0);
    assert_int_equal(statusword(f) & 0x1400, 0x1400);        /* attained, reached */
}

static void test_cyclic_modes_on_sync(void **state)
{
    fixture_t *f = *state;
    enable(f, CO_CIA402_MODE_CSP);
    put(f, 0x607A, 7);
    run_ms(f, 5);
    assert_int_equal(od_int(f, 0x6064, true), 0);      /* nothing moves without SYNC */
    co_cia402_sim_on_sync(0, &f->sim);
    assert_int_equal(od_int(f, 0x6064, true), 7);
    assert_int_equal(od_int(f, 0x606C, true), 7000);   /* 7 u per 1 ms period (0x60C2) */
    assert_true(statusword(f) & CO_CIA402_SW_MODE_BIT12);
    put(f, 0x6040, 0x07);
    put(f, 0x6060, CO_CIA402_MODE_CSV);
    put(f, 0x6040, 0x0F);
    put(f, 0x60FF, 2000);
    co_cia402_sim_on_sync(1, &f->sim);
    co_cia402_sim_on_sync(2, &f->sim);
    assert_int_equal(od_int(f, 0x6064, true), 11);     /* + 2 u per 1 ms */
    assert_int_equal(od_int(f, 0x606C, true), 2000);
    assert_int_equal(f->sim.syncs, 3);
    put(f, 0x6040, 0x06);
    co_cia402_sim_on_sync(3, &f->sim);                  /* not enabled: ignored */
    assert_int_equal(f->sim.syncs, 3);
}

static void test_cyclic_torque(void **state)
{
    fixture_t *f = *state;
    put(f, 0x6502, 0x3A5);                              /* now CST is offered too */
    enable(f, CO_CIA402_MODE_CST);
    put(f, 0x6071, -300);
    assert_int_equal(od_int(f, 0x6077, true), 0);
    co_cia402_sim_on_sync(0, &f->sim);
    assert_int_equal(od_int(f, 0x6077, true), -300);
}

/* An RPDO writes the OD in place, without after-write indications. */
static void pdo_write(fixture_t *f, uint16_t index, int64_t v)
{
    const co_od_entry_t *e = co_od_find(&f->od, index, 0);
    assert_non_null(e);
    tu_le_put(co_od_value(&f->od, e), (uint64_t)v, e->size);
}

static void test_pdo_writes_taken_at_tick_and_sync(void **state)
{
    fixture_t *f = *state;
    pdo_write(f, 0x6040, 0x06);
    assert_int_equal(co_cia402_sim_state(&f->sim), CO_CIA402_SWITCH_ON_DISABLED);
    run_ms(f, 1);
    assert_int_equal(co_cia402_sim_state(&f->sim), CO_CIA402_READY_TO_SWITCH_ON);
    pdo_write(f, 0x6060, CO_CIA402_MODE_CSP);
    pdo_write(f, 0x6040, 0x0F);
    pdo_write(f, 0x607A, 42);
    co_cia402_sim_on_sync(0, &f->sim);              /* mode, controlword, then the target */
    assert_int_equal(od_int(f, 0x6061, true), CO_CIA402_MODE_CSP);
    assert_int_equal(co_cia402_sim_state(&f->sim), CO_CIA402_OPERATION_ENABLED);
    assert_int_equal(od_int(f, 0x6064, true), 42);
    pdo_write(f, 0x6060, CO_CIA402_MODE_CST);       /* not in 0x6502: stays CSP */
    run_ms(f, 1);
    assert_int_equal(od_int(f, 0x6061, true), CO_CIA402_MODE_CSP);
    /* the power command is a level: a controlword already seen still acts at
     * the next tick when the state did not follow it (here: forced back) */
    put(f, 0x6040, 0x07);
    assert_int_equal(co_cia402_sim_state(&f->sim), CO_CIA402_SWITCHED_ON);
    pdo_write(f, 0x6040, 0x0F);
    f->sim.controlword = 0x0F;
    run_ms(f, 1);
    assert_int_equal(co_cia402_sim_state(&f->sim), CO_CIA402_OPERATION_ENABLED);
}

/* ------------------------------------------------- statusword TPDO, membus */

#define TPDO_ID 0x185u
#define RPDO_ID 0x205u

/* The drive (node 5) on a membus line, its PDOs: RPDO 1 = the controlword
 * (0x205, type 255), TPDO 1 = the statusword (0x185, event-driven type
 * `type`); tool is the line that sends the RPDO, the bus sniffer logs all. */
typedef struct bus_drive {
    tu_bus_t tb;
    tu_line_t tool;
    fixture_t f;
    co_pdo_channel_t channels[2];
    co_pdo_map_item_t items[2];
    co_pdo_t pdo;
} bus_drive_t;

static bus_drive_t *bus_drive_new(uint8_t type)
{
    bus_drive_t *b = test_calloc(1, sizeof *b);
    fixture_t *f = &b->f;
    uint32_t channels = 0, items = 0;
    co_pdo_config_t pc;
    tu_bus_init(&b->tb, CO_MODE_CLASSIC, false);
    (void)tu_bus_add_line(&b->tb, &b->tool);
    (void)tu_bus_add_line(&b->tb, &f->tl);
    od_add_drive(f, true);
    tu_od_add_value(&f->od, 0x1400, 0, REC, U8, RO, 0, 2);
    tu_od_add_value(&f->od, 0x1400, 1, REC, U32, RW, 0, RPDO_ID);
    tu_od_add_value(&f->od, 0x1400, 2, REC, U8, RW, 0, 255);
    tu_od_add_value(&f->od, 0x1600, 0, REC, U8, RW, 0, 1);
    tu_od_add_value(&f->od, 0x1600, 1, REC, U32, RW, 0, 0x60400010u);
    tu_od_add_value(&f->od, 0x1800, 0, REC, U8, RO, 0, 5);
    tu_od_add_value(&f->od, 0x1800, 1, REC, U32, RW, 0, TPDO_ID);
    tu_od_add_value(&f->od, 0x1800, 2, REC, U8, RW, 0, type);
    tu_od_add_value(&f->od, 0x1800, 3, REC, U16, RW, 0, 0);   /* no inhibit time */
    tu_od_add_value(&f->od, 0x1800, 5, REC, U16, RW, 0, 0);   /* no event timer */
    tu_od_add_value(&f->od, 0x1A00, 0, REC, U8, RW, 0, 1);
    tu_od_add_value(&f->od, 0x1A00, 1, REC, U32, RW, 0, 0x60410010u);
    assert_true(co_od_seal(&f->od, 5));
    assert_true(co_pdo_need(&f->od, &channels, &items));
    assert_int_equal(channels, 2);
    assert_int_equal(items, 2);
    memset(&pc, 0, sizeof pc);
    pc.channels = b->channels;
    pc.channel_count = 2;
    pc.items = b->items;
    pc.item_count = 2;
    assert_true(co_pdo_init(&b->pdo, &f->tl.line, &f->od, &pc));
    assert_true(co_pdo_is_active(&b->pdo, false, 1));
    co_emcy_config_t ec = {.queue = f->emcy_queue, .queue_capacity = 4,
                           .active = f->emcy_active, .active_capacity = 4};
    assert_true(co_emcy_init(&f->emcy, &f->tl.line, 5, &ec));
    assert_true(co_cia402_sim_init(&f->sim, &f->tl.line, &f->od, NULL, &f->emcy, TICK_US));
    co_cia402_sim_set_pdo(&f->sim, &b->pdo);
    co_pdo_set_operational(&b->pdo, true);
    tu_step(&b->tb, 0);
    tu_log_clear(&b->tb);
    return b;
}

static void bus_drive_free(bus_drive_t *b)
{
    co_cia402_sim_deinit(&b->f.sim);
    co_emcy_deinit(&b->f.emcy);
    co_pdo_deinit(&b->pdo);
    test_free(b);
}

/* ms milliseconds of the drive's ticks, the bus carrying every frame. */
static void bus_run_ms(bus_drive_t *b, uint32_t ms)
{
    for (uint32_t i = 0; i < ms; i++) {
        tu_step(&b->tb, b->tb.now + TICK_US);
    }
}

static void send_controlword(bus_drive_t *b, uint16_t cw)
{
    const uint8_t data[2] = {(uint8_t)cw, (uint8_t)(cw >> 8)};
    assert_true(co_line_send(&b->tool.line, RPDO_ID, data, 2));
}

/* The k-th TPDO on the bus carries statusword sw (little-endian, 2 bytes). */
static void assert_tpdo(bus_drive_t *b, size_t k, uint16_t sw)
{
    const uint8_t data[2] = {(uint8_t)sw, (uint8_t)(sw >> 8)};
    tu_assert_logged(&b->tb, tu_log_find_id(&b->tb, TPDO_ID, k), TPDO_ID, data, 2);
}

/* A statusword change sends the event-driven TPDO that maps it (types 254
 * and 255), with the new statusword; a controlword that changes nothing,
 * and the ticks in between, send none. */
static void test_statusword_change_sends_event_tpdo(void **state)
{
    static const uint8_t types[] = {254, 255};
    (void)state;
    for (size_t t = 0; t < sizeof types; t++) {
        bus_drive_t *b = bus_drive_new(types[t]);
        fixture_t *f = &b->f;
        bus_run_ms(b, 5);                            /* Switch on disabled, unchanged */
        assert_int_equal(tu_log_count_id(&b->tb, TPDO_ID), 0);
        send_controlword(b, 0x06);                   /* shutdown, by RPDO: at the tick */
        bus_run_ms(b, 2);
        assert_int_equal(co_cia402_sim_state(&f->sim), CO_CIA402_READY_TO_SWITCH_ON);
        assert_int_equal(tu_log_count_id(&b->tb, TPDO_ID), 1);
        assert_tpdo(b, 0, 0x0231);                   /* ready to switch on + remote */
        send_controlword(b, 0x06);                   /* the same again: no change */
        bus_run_ms(b, 5);
        put(f, 0x6040, 0x06);
        bus_run_ms(b, 5);
        assert_int_equal(tu_log_count_id(&b->tb, TPDO_ID), 1);
        put(f, 0x6040, 0x07);                        /* switch on, as an SDO write */
        bus_run_ms(b, 1);
        assert_int_equal(tu_log_count_id(&b->tb, TPDO_ID), 2);
        assert_tpdo(b, 1, 0x0233);
        put(f, 0x6040, 0x0F);                        /* enable operation */
        bus_run_ms(b, 5);
        assert_int_equal(tu_log_count_id(&b->tb, TPDO_ID), 3);
        assert_tpdo(b, 2, 0x0237);
        bus_drive_free(b);
    }
}

/* ---------------------------------------------------------------- refusals */

static void test_unsupported_mode_refused(void **state)
{
    fixture_t *f = *state;
    /* CST is not in 0x6502 (0x1A5), 2 is not modelled: a network write is refused */
    assert_int_equal(tu_od_net_write_u32(&f->od, 0x6060, 0, 0), CO_ABORT_LENGTH_HIGH);
    co_od_xfer_t x;
    uint8_t scratch[16];
    uint8_t v = CO_CIA402_MODE_CST;
    co_od_xfer_init(&x, scratch, sizeof scratch);
    assert_int_equal(co_od_write_begin(&f->od, &x, 0x6060, 0, 1), 0);
    assert_int_equal(co_od_write_chunk(&x, &v, 1), 0);
    assert_int_equal(co_od_write_end(&x), CO_ABORT_INVALID_VALUE);
    assert_int_equal(od_int(f, 0x6061, true), 0);
    v = CO_CIA402_MODE_CSP;
    co_od_xfer_init(&x, scratch, sizeof scratch);
    assert_int_equal(co_od_write_begin(&f->od, &x, 0x6060, 0, 1), 0);
    assert_int_equal(co_od_write_chunk(&x, &v, 1), 0);
    assert_int_equal(co_od_write_end(&x), 0);
    assert_int_equal(od_int(f, 0x6061, true), CO_CIA402_MODE_CSP);
}

static void test_missing_object_named(void **state)
{
    fixture_t *f = test_calloc(1, sizeof *f);
    (void)state;
    tu_line_init(&f->tl, CO_MODE_CLASSIC, false);
    od_build(f, false);
    assert_false(co_cia402_sim_init(&f->sim, &f->tl.line, &f->od, NULL, NULL, TICK_US));
    assert_int_equal(f->sim.missing_key, 0x606C00);
    assert_false(co_cia402_sim_init(&f->sim, &f->tl.line, &f->od, NULL, NULL, 0));
    test_free(f);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_starts_switch_on_disabled, setup, teardown),
        cmocka_unit_test(test_statusword_patterns),
        cmocka_unit_test_setup_teardown(test_every_transition, setup, teardown),
        cmocka_unit_test_setup_teardown(test_fault_reaction_and_reset, setup, teardown),
        cmocka_unit_test_setup_teardown(test_fault_mid_move_stops, setup, teardown),
        cmocka_unit_test_setup_teardown(test_profile_position_move, setup, teardown),
        cmocka_unit_test_setup_teardown(test_profile_position_buffered_and_immediate, setup,
                                        teardown),
        cmocka_unit_test_setup_teardown(test_profile_velocity_and_quick_stop, setup, teardown),
        cmocka_unit_test_setup_teardown(test_homing, setup, teardown),
        cmocka_unit_test_setup_teardown(test_cyclic_modes_on_sync, setup, teardown),
        cmocka_unit_test_setup_teardown(test_cyclic_torque, setup, teardown),
        cmocka_unit_test_setup_teardown(test_pdo_writes_taken_at_tick_and_sync, setup, teardown),
        cmocka_unit_test_setup_teardown(test_unsupported_mode_refused, setup, teardown),
        cmocka_unit_test(test_missing_object_named),
        cmocka_unit_test(test_statusword_change_sends_event_tpdo),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
