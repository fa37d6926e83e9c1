/* Simulated CiA 402 drive: power state machine, statusword, motion model.
 * The drive's values live in the OD only (the master sees what the model
 * sees); the struct keeps what the OD has no place for: the fractional
 * position, the velocity and the edges of the controlword. */
#include "canopenfd/co_cia402_sim.h"

#include <string.h>

#define KEY(index, sub) (((uint32_t)(index) << 8) | (uint32_t)(sub))

const uint32_t co_cia402_sim_required[CO_CIA402_SIM_REQUIRED_COUNT] = {
    KEY(0x603F, 0), KEY(0x6040, 0), KEY(0x6041, 0), KEY(0x6060, 0), KEY(0x6061, 0),
    KEY(0x6064, 0), KEY(0x606C, 0), KEY(0x6071, 0), KEY(0x6077, 0), KEY(0x607A, 0),
    KEY(0x6081, 0), KEY(0x6083, 0), KEY(0x6084, 0), KEY(0x60FF, 0), KEY(0x6098, 0)};

/* ------------------------------------------------------------ OD values */

static int64_t get_int(const co_cia402_sim_t *sim, uint16_t index, uint8_t sub, bool is_signed)
{
    uint8_t b[4] = {0, 0, 0, 0};
    uint32_t n = 0, i;
    uint32_t u = 0;
    if (co_od_get(sim->od, index, sub, b, sizeof b, &n) != 0 || n == 0 || n > 4) {
        return 0;
    }
    for (i = 0; i < n; i++) {
        u |= (uint32_t)b[i] << (8 * i);
    }
    if (is_signed && n < 4 && (u & (1u << (8 * n - 1)))) {
        u |= ~0u << (8 * n);              /* sign-extend a shorter integer */
    }
    return is_signed ? (int64_t)(int32_t)u : (int64_t)u;
}

/* Writes a value in the entry's own width (the entries differ in size). */
static void put_int(co_cia402_sim_t *sim, uint16_t index, int64_t v)
{
    const co_od_entry_t *e = co_od_find(sim->od, index, 0);
    uint8_t b[4];
    uint32_t i, n;
    if (!e) {
        return;
    }
    n = e->size < 4 ? e->size : 4;
    for (i = 0; i < n; i++) {
        b[i] = (uint8_t)((uint64_t)v >> (8 * i));
    }
    (void)co_od_put(sim->od, index, 0, b, n);
}

static int32_t clamp_i32(double v)
{
    if (v >= 2147483647.0) {
        return INT32_MAX;
    }
    if (v <= -2147483648.0) {
        return INT32_MIN;
    }
    return (int32_t)(v < 0 ? v - 0.5 : v + 0.5);
}

static uint8_t mode_of(const co_cia402_sim_t *sim)
{
    return (uint8_t)get_int(sim, 0x6061, 0, false);
}

/* Seconds per SYNC from 0x60C2 (0 without it: cyclic velocity integrates nothing). */
static double interpolation_period_s(const co_cia402_sim_t *sim)
{
    double period;
    int64_t exponent;
    if (!co_od_find(sim->od, 0x60C2, 1) || !co_od_find(sim->od, 0x60C2, 2)) {
        return 0.0;
    }
    period = (double)get_int(sim, 0x60C2, 1, false);
    for (exponent = get_int(sim, 0x60C2, 2, true); exponent < 0; exponent++) {
        period /= 10.0;
    }
    for (; exponent > 0; exponent--) {
        period *= 10.0;
    }
    return period;
}

/* ------------------------------------------------------------ statusword */

uint16_t co_cia402_state_bits(co_cia402_state_t state)
{
    switch (state) {
    case CO_CIA402_SWITCH_ON_DISABLED: return 0x0040;
    case CO_CIA402_READY_TO_SWITCH_ON: return 0x0031;
    case CO_CIA402_SWITCHED_ON: return 0x0033;
    case CO_CIA402_OPERATION_ENABLED: return 0x0037;
    case CO_CIA402_QUICK_STOP_ACTIVE: return 0x0017;
    case CO_CIA402_FAULT_REACTION_ACTIVE: return 0x001F;
    case CO_CIA402_FAULT: return 0x0018;
    case CO_CIA402_NOT_READY_TO_SWITCH_ON:
    default: return 0x0000;
    }
}

/* Bits 10 and 12 mean something per mode, and only while operation is enabled. */
static uint16_t mode_bits(const co_cia402_sim_t *sim)
{
    uint16_t bits = 0;
    double target_velocity;
    if (sim->state != CO_CIA402_OPERATION_ENABLED) {
        return 0;
    }
    switch (mode_of(sim)) {
    case CO_CIA402_MODE_PROFILE_POSITION:
        bits |= (!sim->moving && !sim->has_pending) ? CO_CIA402_SW_TARGET_REACHED : 0u;
        bits |= sim->set_point_ack ? CO_CIA402_SW_MODE_BIT12 : 0u;
        break;
    case CO_CIA402_MODE_PROFILE_VELOCITY:
        target_velocity = (sim->controlword & CO_CIA402_CW_HALT)
                              ? 0.0 : (double)get_int(sim, 0x60FF, 0, true);
        bits |= (sim->velocity == target_velocity) ? CO_CIA402_SW_TARGET_REACHED : 0u;
        bits |= (sim->velocity == 0.0) ? CO_CIA402_SW_MODE_BIT12 : 0u;
        break;
    case CO_CIA402_MODE_HOMING:
        bits |= sim->homing_attained ? (CO_CIA402_SW_TARGET_REACHED | CO_CIA402_SW_MODE_BIT12)
                                     : 0u;
        break;
    case CO_CIA402_MODE_CSP:
    case CO_CIA402_MODE_CSV:
    case CO_CIA402_MODE_CST:
        bits |= CO_CIA402_SW_MODE_BIT12;    /* the drive follows the cyclic target */
        break;
    default:
        break;
    }
    return bits;
}

static void publish(co_cia402_sim_t *sim)
{
    uint16_t sw = (uint16_t)(co_cia402_state_bits(sim->state) | CO_CIA402_SW_REMOTE |
                             mode_bits(sim));
    put_int(sim, 0x6064, clamp_i32(sim->position));
    put_int(sim, 0x606C, clamp_i32(sim->velocity));
    if ((uint16_t)get_int(sim, 0x6041, 0, false) != sw) {
        put_int(sim, 0x6041, sw);   /* only on change: an event TPDO sends changes */
        if (sim->pdo) {
            (void)co_pdo_trigger_object(sim->pdo, 0x6041, 0);
        }
    }
}

static void enter(co_cia402_sim_t *sim, co_cia402_state_t state)
{
    if (state == sim->state) {
        return;
    }
    if (state == CO_CIA402_OPERATION_ENABLED) {
        /* hold where the axis is: no jump to a stale target */
        sim->target = clamp_i32(sim->position);
        sim->moving = sim->has_pending = sim->homing = false;
        sim->set_point_ack = false;
    }
    if (state != CO_CIA402_OPERATION_ENABLED && state != CO_CIA402_QUICK_STOP_ACTIVE) {
        sim->velocity = 0.0;     /* power off: the axis stops where it is */
        sim->moving = sim->has_pending = sim->homing = false;
    }
    sim->state = state;
    sim->transitions++;
}

/* ------------------------------------------------------------ controlword */

static void power_command(co_cia402_sim_t *sim, uint16_t cw)
{
    co_cia402_state_t s = sim->state;
    bool powered = s == CO_CIA402_READY_TO_SWITCH_ON || s == CO_CIA402_SWITCHED_ON ||
                   s == CO_CIA402_OPERATION_ENABLED || s == CO_CIA402_QUICK_STOP_ACTIVE;
    if ((cw & 0x82u) == 0x00u) {                        /* disable voltage */
        if (powered) {
            enter(sim, CO_CIA402_SWITCH_ON_DISABLED);
        }
    } else if ((cw & 0x86u) == 0x02u) {                 /* quick stop */
        if (s == CO_CIA402_OPERATION_ENABLED) {
            enter(sim, CO_CIA402_QUICK_STOP_ACTIVE);
        } else if (s == CO_CIA402_READY_TO_SWITCH_ON || s == CO_CIA402_SWITCHED_ON) {
            enter(sim, CO_CIA402_SWITCH_ON_DISABLED);
        }
    } else if ((cw & 0x87u) == 0x06u) {                 /* shutdown */
        if (s == CO_CIA402_SWITCH_ON_DISABLED || s == CO_CIA402_SWITCHED_ON ||
            s == CO_CIA402_OPERATION_ENABLED) {
            enter(sim, CO_CIA402_READY_TO_SWITCH_ON);
        }
    } else if ((cw & 0x8Fu) == 0x07u) {                 /* switch on / disable operation */
        if (s == CO_CIA402_READY_TO_SWITCH_ON || s == CO_CIA402_OPERATION_ENABLED) {
            enter(sim, CO_CIA402_SWITCHED_ON);
        }
    } else if ((cw & 0x8Fu) == 0x0Fu) {                 /* enable operation */
        if (s == CO_CIA402_READY_TO_SWITCH_ON) {
            enter(sim, CO_CIA402_SWITCHED_ON);          /* 3 then 4, as many drives do */
        }
        if (sim->state == CO_CIA402_SWITCHED_ON || s == CO_CIA402_QUICK_STOP_ACTIVE) {
            enter(sim, CO_CIA402_OPERATION_ENABLED);
        }
    }
}

static void start_set_point(co_cia402_sim_t *sim, uint16_t cw)
{
    int32_t value = (int32_t)get_int(sim, 0x607A, 0, true);
    bool immediately = (cw & CO_CIA402_CW_CHANGE_IMMEDIATELY) != 0;
    int32_t base = (sim->moving && !immediately) ? sim->target : clamp_i32(sim->position);
    int32_t goal = (cw & CO_CIA402_CW_RELATIVE) ? (int32_t)((uint32_t)base + (uint32_t)value)
                                                : value;
    if (sim->moving && !immediately) {
        sim->pending_target = goal;      /* one buffered set-point, started at the target */
        sim->has_pending = true;
    } else {
        sim->target = goal;
        sim->moving = true;
    }
    sim->set_point_ack = true;
}

static void mode_command(co_cia402_sim_t *sim, uint16_t cw, uint16_t previous)
{
    bool rising4 = (cw & CO_CIA402_CW_NEW_SET_POINT) && !(previous & CO_CIA402_CW_NEW_SET_POINT);
    switch (mode_of(sim)) {
    case CO_CIA402_MODE_PROFILE_POSITION:
        if (rising4) {
            start_set_point(sim, cw);
        } else if (!(cw & CO_CIA402_CW_NEW_SET_POINT)) {
            sim->set_point_ack = false;
        }
        break;
    case CO_CIA402_MODE_HOMING:
        if (rising4) {
            sim->homing = true;
            sim->homing_attained = false;
        }
        break;
    default:
        break;
    }
}

static void apply_controlword(co_cia402_sim_t *sim, uint16_t cw)
{
    uint16_t previous = sim->controlword;
    sim->controlword = cw;
    if (sim->state == CO_CIA402_FAULT) {
        if ((cw & CO_CIA402_CW_FAULT_RESET) && !(previous & CO_CIA402_CW_FAULT_RESET)) {
            co_emcy_error_t err;
            memset(&err, 0, sizeof err);
            err.code = (uint16_t)get_int(sim, 0x603F, 0, false);
            err.spec_number = 402;
            if (sim->emcy && err.code != 0) {
                (void)co_emcy_clear(sim->emcy, &err);
            }
            put_int(sim, 0x603F, 0);
            enter(sim, CO_CIA402_SWITCH_ON_DISABLED);
        }
    } else if (sim->state != CO_CIA402_FAULT_REACTION_ACTIVE &&
               sim->state != CO_CIA402_NOT_READY_TO_SWITCH_ON) {
        power_command(sim, cw);
        if (sim->state == CO_CIA402_OPERATION_ENABLED) {
            mode_command(sim, cw, previous);
        }
    }
    publish(sim);
}

/* ------------------------------------------------------------ OD handlers */

static bool mode_supported(const co_cia402_sim_t *sim, int64_t mode);

static void apply_mode(co_cia402_sim_t *sim)
{
    int64_t mode = get_int(sim, 0x6060, 0, true);
    if (mode_supported(sim, mode) || mode == 0) {
        put_int(sim, 0x6061, mode);
        if (sim->pdo) {
            (void)co_pdo_trigger_object(sim->pdo, 0x6061, 0);
        }
        sim->moving = sim->has_pending = sim->homing = false;
        sim->homing_attained = sim->set_point_ack = false;
        publish(sim);
    }
}

/* RPDOs write the OD without after-write indications: what they wrote is
 * taken at the next tick or SYNC (a value overwritten within one tick is
 * not seen, so an edge must last a tick). The power commands are levels, as
 * in a real drive: the one in 0x6040 is evaluated again at every tick. */
static void follow_pdo_writes(co_cia402_sim_t *sim)
{
    uint16_t cw = (uint16_t)get_int(sim, 0x6040, 0, false);
    if (get_int(sim, 0x6060, 0, true) != get_int(sim, 0x6061, 0, true)) {
        apply_mode(sim);
    }
    if (cw != sim->controlword) {
        apply_controlword(sim, cw);
    } else if (sim->state != CO_CIA402_FAULT && sim->state != CO_CIA402_FAULT_REACTION_ACTIVE &&
               sim->state != CO_CIA402_NOT_READY_TO_SWITCH_ON) {
        power_command(sim, cw);
    }
}

static bool mode_supported(const co_cia402_sim_t *sim, int64_t mode)
{
    if (mode != CO_CIA402_MODE_PROFILE_POSITION && mode != CO_CIA402_MODE_PROFILE_VELOCITY &&
        mode != CO_CIA402_MODE_HOMING && mode != CO_CIA402_MODE_CSP &&
        mode != CO_CIA402_MODE_CSV && mode != CO_CIA402_MODE_CST) {
        return false;
    }
    /* 0x6502 bit (mode - 1) says which of them this drive offers */
    return !co_od_find(sim->od, 0x6502, 0) ||
           ((uint32_t)get_int(sim, 0x6502, 0, false) >> (mode - 1)) & 1u;
}

static uint32_t check_write(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e,
                            const uint8_t *value, uint32_t length, void *user)
{
    (void)od;
    (void)xfer;
    if (e->key == KEY(0x6060, 0) && length == 1 &&
        !mode_supported(user, (int64_t)(int8_t)value[0])) {
        return CO_ABORT_INVALID_VALUE;
    }
    return 0;
}

static void after_write(co_od_t *od, const co_od_entry_t *e, co_od_origin_t origin, void *user)
{
    co_cia402_sim_t *sim = user;
    (void)od;
    if (origin == CO_ORIGIN_RESTORE) {
        return;
    }
    if (e->key == KEY(0x6040, 0)) {
        apply_controlword(sim, (uint16_t)get_int(sim, 0x6040, 0, false));
    } else if (e->key == KEY(0x6060, 0)) {
        apply_mode(sim);
    } else if (e->key == KEY(0x60FF, 0)) {
        publish(sim);     /* target reached (bit 10) no longer holds for a new target */
    }
}

static const co_od_handler_t handler = {
    .check_write = check_write,
    .after_write = after_write,
};

/* ------------------------------------------------------------ motion */

/* Speed after dt towards `want` (units/s), changing by at most rate * dt
 * (rate 0: at once). */
static double ramp(double v, double want, double rate, double dt)
{
    double step = rate * dt;
    if (rate <= 0.0 || (v < want ? want - v : v - want) <= step) {
        return want;
    }
    return v < want ? v + step : v - step;
}

static void step_profile_position(co_cia402_sim_t *sim, double dt)
{
    double remaining = (double)sim->target - sim->position;
    double direction = remaining < 0 ? -1.0 : 1.0;
    double speed = sim->velocity * direction;   /* negative: moving away */
    double vmax = (double)get_int(sim, 0x6081, 0, false);
    double acc = (double)get_int(sim, 0x6083, 0, false);
    double dec = (double)get_int(sim, 0x6084, 0, false);
    double distance = remaining * direction;
    bool halt = (sim->controlword & CO_CIA402_CW_HALT) != 0;
    double braking = (dec > 0.0 && speed > 0.0) ? speed * speed / (2.0 * dec) : 0.0;
    double want = (halt || speed < 0.0 || braking >= distance) ? 0.0 : vmax;
    speed = ramp(speed, want, want > speed ? acc : dec, dt);
    if (!halt && (speed * dt >= distance || (speed <= 0.0 && distance < 0.5))) {
        sim->position = (double)sim->target;
        sim->velocity = 0.0;
        sim->moving = false;
        if (sim->has_pending) {
            sim->has_pending = false;
            sim->target = sim->pending_target;
            sim->moving = true;
        }
        return;
    }
    sim->velocity = speed * direction;
    sim->position += sim->velocity * dt;
}

void co_cia402_sim_step(co_cia402_sim_t *sim, uint32_t dt_us)
{
    double dt = (double)dt_us / 1e6;
    double dec = (double)get_int(sim, 0x6084, 0, false);
    follow_pdo_writes(sim);
    if (sim->state == CO_CIA402_FAULT_REACTION_ACTIVE) {
        sim->velocity = 0.0;               /* the reaction: stop, then Fault */
        enter(sim, CO_CIA402_FAULT);
    } else if (sim->state == CO_CIA402_QUICK_STOP_ACTIVE) {
        sim->velocity = ramp(sim->velocity, 0.0, dec, dt);
        sim->position += sim->velocity * dt;
    } else if (sim->state == CO_CIA402_OPERATION_ENABLED) {
        switch (mode_of(sim)) {
        case CO_CIA402_MODE_PROFILE_POSITION:
            if (sim->moving) {
                step_profile_position(sim, dt);
            }
            break;
        case CO_CIA402_MODE_PROFILE_VELOCITY: {
            double want = (sim->controlword & CO_CIA402_CW_HALT)
                              ? 0.0 : (double)get_int(sim, 0x60FF, 0, true);
            double acc = (double)get_int(sim, 0x6083, 0, false);
            bool speeding_up = (want > 0 && want > sim->velocity) ||
                               (want < 0 && want < sim->velocity);
            sim->velocity = ramp(sim->velocity, want, speeding_up ? acc : dec, dt);
            sim->position += sim->velocity * dt;
            break;
        }
        case CO_CIA402_MODE_HOMING:
            if (sim->homing) {             /* the model homes in one tick: here is zero */
                sim->position = 0.0;
                sim->velocity = 0.0;
                sim->homing = false;
                sim->homing_attained = true;
            }
            break;
        default:
            break;
        }
    }
    publish(sim);
}

void co_cia402_sim_on_sync(uint8_t counter, void *user)
{
    co_cia402_sim_t *sim = user;
    double period;
    (void)counter;
    follow_pdo_writes(sim);
    if (sim->state != CO_CIA402_OPERATION_ENABLED) {
        return;
    }
    period = interpolation_period_s(sim);
    switch (mode_of(sim)) {
    case CO_CIA402_MODE_CSP: {
        double goal = (double)get_int(sim, 0x607A, 0, true);
        sim->velocity = period > 0.0 ? (goal - sim->position) / period : 0.0;
        sim->position = goal;
        break;
    }
    case CO_CIA402_MODE_CSV:
        sim->velocity = (double)get_int(sim, 0x60FF, 0, true);
        sim->position += sim->velocity * period;
        break;
    case CO_CIA402_MODE_CST:
        put_int(sim, 0x6077, get_int(sim, 0x6071, 0, true));
        break;
    default:
        return;
    }
    sim->syncs++;
    publish(sim);
}

static void on_tick(co_timer_t *timer, uint64_t now_us, void *user)
{
    co_cia402_sim_t *sim = user;
    co_cia402_sim_step(sim, sim->tick_us);
    co_timer_start(co_line_timers(sim->line), timer, now_us + sim->tick_us);
}

/* ------------------------------------------------------------ life */

void co_cia402_sim_fault(co_cia402_sim_t *sim, uint16_t code)
{
    co_emcy_error_t err;
    if (sim->state == CO_CIA402_FAULT || sim->state == CO_CIA402_FAULT_REACTION_ACTIVE) {
        return;
    }
    put_int(sim, 0x603F, code);
    if (sim->emcy) {
        memset(&err, 0, sizeof err);
        err.code = code;
        err.spec_number = 402;
        err.register_bits = CO_EMCY_ER_DEVICE_PROFILE;
        (void)co_emcy_raise(sim->emcy, &err);
    }
    enter(sim, CO_CIA402_FAULT_REACTION_ACTIVE);
    publish(sim);
}

bool co_cia402_sim_init(co_cia402_sim_t *sim, co_line_t *line, co_od_t *od, co_sync_t *sync,
                        co_emcy_t *emcy, uint32_t tick_us)
{
    uint32_t i;
    if (!sim || !line || !od || tick_us == 0) {
        return false;
    }
    memset(sim, 0, sizeof *sim);
    sim->od = od;
    sim->line = line;
    sim->emcy = emcy;
    sim->tick_us = tick_us;
    for (i = 0; i < CO_CIA402_SIM_REQUIRED_COUNT; i++) {
        uint32_t key = co_cia402_sim_required[i];
        if (!co_od_find(od, (uint16_t)(key >> 8), (uint8_t)key)) {
            sim->missing_key = key;
            return false;
        }
    }
    if (!co_od_subscribe(od, 0x6040, 0, 0x60FF, 0, &handler, sim)) {
        return false;
    }
    sim->subscribed = true;
    if (sync) {
        if (!co_sync_add_listener(sync, co_cia402_sim_on_sync, sim)) {
            co_od_unsubscribe(od, &handler, sim);
            sim->subscribed = false;
            return false;
        }
        sim->sync = sync;
    }
    sim->position = (double)get_int(sim, 0x6064, 0, true);
    sim->controlword = (uint16_t)get_int(sim, 0x6040, 0, false);
    sim->state = CO_CIA402_NOT_READY_TO_SWITCH_ON;
    enter(sim, CO_CIA402_SWITCH_ON_DISABLED);     /* self-test passed at once */
    put_int(sim, 0x6061, get_int(sim, 0x6060, 0, true));
    publish(sim);
    co_timer_init(&sim->tick, on_tick, sim);
    co_timer_start(co_line_timers(line), &sim->tick, co_line_now(line) + tick_us);
    return true;
}

void co_cia402_sim_set_pdo(co_cia402_sim_t *sim, co_pdo_t *pdo)
{
    sim->pdo = pdo;
}

void co_cia402_sim_deinit(co_cia402_sim_t *sim)
{
    co_timer_cancel(co_line_timers(sim->line), &sim->tick);
    if (sim->sync) {
        co_sync_remove_listener(sim->sync, co_cia402_sim_on_sync, sim);
        sim->sync = NULL;
    }
    if (sim->subscribed) {
        co_od_unsubscribe(sim->od, &handler, sim);
        sim->subscribed = false;
    }
}
