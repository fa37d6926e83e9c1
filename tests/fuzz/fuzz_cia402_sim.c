/* libFuzzer harness: the simulated CiA 402 drive (co_cia402_sim). One line,
 * one OD with the drive's objects, an EMCY producer; the input writes the
 * controlword, the mode and the targets (as an SDO server does: with the
 * OD's checks and the after-write indication, or as an RPDO does: into the
 * value, seen at the next tick or SYNC), sends SYNCs, injects faults, steps
 * the model and lets time pass (the drive's tick runs on the line's timers).
 * First input byte: bits 0..7 = the drive's 0x6502 (supported modes, bit
 * mode-1; 0 = the OD has no 0x6502: every modelled mode).
 *
 * Checks after every record: the state is one of the eight; the statusword
 * is exactly the state's pattern, the remote bit, and bits 10/12 only while
 * operation is enabled; 0x6061 shows 0 or a supported mode; position and
 * velocity are finite, the axis is still and nothing moves outside Operation
 * enabled and Quick stop active; a single state change follows the CiA 402
 * graph (transitions 2..16 and the fault). */
#include "fuzz_input.h"

#include "canopenfd/co_cia402_sim.h"
#include "canopenfd/co_emcy.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { SLOTS = 32, ENTRIES = 40, POOL = 1024, SUBS = 4, NODE = 5, TICK_US = 1000 };

typedef struct drive_world {
    co_line_t line;
    co_frame_t rx[SLOTS], tx[SLOTS];
    co_od_t od;
    co_od_entry_t entries[ENTRIES];
    uint8_t pool[POOL];
    co_od_subscription_t subs[SUBS];
    co_emcy_t emcy;
    co_emcy_msg_t emcy_queue[4];
    co_emcy_active_t emcy_active[4];
    co_cia402_sim_t sim;
    uint64_t now;
    uint32_t supported;      /* 0x6502, 0: not in the OD */
} drive_world_t;

static drive_world_t W;
static const uint32_t ids[] = {0x000, 0x080, 0x085, 0x605};

/* The objects a write action picks from. */
static const struct {
    uint16_t index;
    uint8_t sub;
} writable[] = {
    {0x6040, 0}, {0x6060, 0}, {0x607A, 0}, {0x60FF, 0}, {0x6071, 0},
    {0x6081, 0}, {0x6083, 0}, {0x6084, 0}, {0x6098, 0}, {0x60C2, 1}, {0x60C2, 2},
};
enum { WRITABLE = sizeof writable / sizeof writable[0] };

static uint32_t od_u(uint16_t index, uint8_t sub);

static void fail(const char *what)
{
    fprintf(stderr, "fuzz invariant broken: %s (state %d, statusword 0x%04X, controlword "
            "0x%04X)\n", what, (int)W.sim.state, (unsigned)od_u(0x6041, 0),
            (unsigned)W.sim.controlword);
    abort();
}

#define CHECK(cond, what) do { if (!(cond)) { fail(what); } } while (0)

static void add(uint16_t index, uint8_t sub, uint8_t object, uint8_t type, uint8_t access,
                uint32_t value)
{
    CHECK(fz_od_add(&W.od, index, sub, object, type, access, value), "OD refuses an entry");
}

static void od_build(void)
{
    const uint8_t var = CO_OBJECT_VAR, rec = CO_OBJECT_RECORD;
    co_od_init(&W.od, CO_MODE_CLASSIC, W.entries, ENTRIES, W.pool, POOL, W.subs, SUBS);
    add(0x1001, 0, var, CO_TYPE_UNSIGNED8, CO_ACCESS_RO, 0);
    add(0x603F, 0, var, CO_TYPE_UNSIGNED16, CO_ACCESS_RO, 0);
    add(0x6040, 0, var, CO_TYPE_UNSIGNED16, CO_ACCESS_RW, 0);
    add(0x6041, 0, var, CO_TYPE_UNSIGNED16, CO_ACCESS_RO, 0);
    add(0x6060, 0, var, CO_TYPE_INTEGER8, CO_ACCESS_RW, 0);
    add(0x6061, 0, var, CO_TYPE_INTEGER8, CO_ACCESS_RO, 0);
    add(0x6064, 0, var, CO_TYPE_INTEGER32, CO_ACCESS_RO, 0);
    add(0x606C, 0, var, CO_TYPE_INTEGER32, CO_ACCESS_RO, 0);
    add(0x6071, 0, var, CO_TYPE_INTEGER16, CO_ACCESS_RW, 0);
    add(0x6077, 0, var, CO_TYPE_INTEGER16, CO_ACCESS_RO, 0);
    add(0x607A, 0, var, CO_TYPE_INTEGER32, CO_ACCESS_RW, 0);
    add(0x6081, 0, var, CO_TYPE_UNSIGNED32, CO_ACCESS_RW, 1000);
    add(0x6083, 0, var, CO_TYPE_UNSIGNED32, CO_ACCESS_RW, 10000);
    add(0x6084, 0, var, CO_TYPE_UNSIGNED32, CO_ACCESS_RW, 10000);
    add(0x6098, 0, var, CO_TYPE_INTEGER8, CO_ACCESS_RW, 35);
    add(0x60C2, 0, rec, CO_TYPE_UNSIGNED8, CO_ACCESS_RO, 2);
    add(0x60C2, 1, rec, CO_TYPE_UNSIGNED8, CO_ACCESS_RW, 1);
    add(0x60C2, 2, rec, CO_TYPE_INTEGER8, CO_ACCESS_RW, (uint32_t)-3);
    add(0x60FF, 0, var, CO_TYPE_INTEGER32, CO_ACCESS_RW, 0);
    if (W.supported != 0) {
        add(0x6502, 0, var, CO_TYPE_UNSIGNED32, CO_ACCESS_RO, W.supported);
    }
    CHECK(co_od_seal(&W.od, NODE), "OD does not seal");
}

static uint32_t od_u(uint16_t index, uint8_t sub)
{
    uint8_t b[4] = {0, 0, 0, 0};
    uint32_t n = 0;
    (void)co_od_get(&W.od, index, sub, b, sizeof b, &n);
    return (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24;
}

static bool mode_ok(int8_t mode)
{
    bool modelled = mode == 1 || mode == 3 || mode == 6 || mode == 8 || mode == 9 || mode == 10;
    if (mode == 0) {
        return true;
    }
    return modelled && (W.supported == 0 || ((W.supported >> (mode - 1)) & 1u));
}

/* May one enter() go from a to b? The CiA 402 graph; a fault from anywhere
 * but Fault reaction active and Fault. */
static bool edge(co_cia402_state_t a, co_cia402_state_t b)
{
    enum { SOD = CO_CIA402_SWITCH_ON_DISABLED, RTSO = CO_CIA402_READY_TO_SWITCH_ON,
           SO = CO_CIA402_SWITCHED_ON, OE = CO_CIA402_OPERATION_ENABLED,
           QSA = CO_CIA402_QUICK_STOP_ACTIVE, FRA = CO_CIA402_FAULT_REACTION_ACTIVE,
           FLT = CO_CIA402_FAULT };
    if (b == FRA) {
        return a != FRA && a != FLT;
    }
    switch (a) {
    case SOD: return b == RTSO;
    case RTSO: return b == SOD || b == SO;
    case SO: return b == SOD || b == RTSO || b == OE;
    case OE: return b == SOD || b == RTSO || b == SO || b == QSA;
    case QSA: return b == SOD || b == OE;
    case FRA: return b == FLT;
    case FLT: return b == SOD;
    default: return false;
    }
}

static co_cia402_state_t last_state;
static uint32_t last_transitions;

static void check(void)
{
    const co_cia402_sim_t *s = &W.sim;
    uint16_t sw = (uint16_t)od_u(0x6041, 0);
    bool enabled = s->state == CO_CIA402_OPERATION_ENABLED;
    bool in_motion_state = enabled || s->state == CO_CIA402_QUICK_STOP_ACTIVE;
    CHECK(s->state <= CO_CIA402_FAULT, "state out of range");
    CHECK((sw & 0x00FFu) == co_cia402_state_bits(s->state), "statusword is not the state's");
    CHECK(sw & CO_CIA402_SW_REMOTE, "statusword without the remote bit");
    CHECK((sw & 0xE900u) == 0u, "statusword bits 8, 11, 13..15 set");
    CHECK(enabled || (sw & (CO_CIA402_SW_TARGET_REACHED | CO_CIA402_SW_MODE_BIT12)) == 0u,
          "mode bits 10/12 outside Operation enabled");
    CHECK(mode_ok((int8_t)od_u(0x6061, 0)), "0x6061 shows an unsupported mode");
    CHECK(isfinite(s->position) && isfinite(s->velocity), "position or velocity not finite");
    CHECK(in_motion_state || (s->velocity == 0.0 && !s->moving && !s->has_pending &&
                              !s->homing),
          "the axis moves with the power stage off");
    if (s->transitions == last_transitions + 1u) {
        CHECK(edge(last_state, s->state), "a state change the CiA 402 graph does not have");
    }
    last_state = s->state;
    last_transitions = s->transitions;
}

/* As an SDO server writes: the OD's checks and check_write, after_write. */
static void network_write(uint16_t index, uint8_t sub, uint32_t value)
{
    const co_od_entry_t *e = co_od_find(&W.od, index, sub);
    co_od_xfer_t x;
    uint8_t scratch[16];
    uint8_t b[4] = {(uint8_t)value, (uint8_t)(value >> 8), (uint8_t)(value >> 16),
                    (uint8_t)(value >> 24)};
    CHECK(e != NULL, "a drive object is missing");
    co_od_xfer_init(&x, scratch, sizeof scratch);
    if (co_od_write_begin(&W.od, &x, index, sub, e->size) == 0 &&
        co_od_write_chunk(&x, b, e->size) == 0) {
        (void)co_od_write_end(&x);
    }
}

/* As an RPDO writes: into the value, no indication (seen at a tick or SYNC). */
static void pdo_write(uint16_t index, uint8_t sub, uint32_t value)
{
    const co_od_entry_t *e = co_od_find(&W.od, index, sub);
    uint8_t *v;
    CHECK(e != NULL, "a drive object is missing");
    v = co_od_value(&W.od, e);
    for (uint32_t i = 0; i < e->size && i < 4; i++) {
        v[i] = (uint8_t)(value >> (8 * i));
    }
}

static uint32_t controlword(fz_reader_t *r)
{
    /* mostly the power commands and the mode bits, sometimes anything */
    static const uint16_t common[] = {0x00, 0x02, 0x06, 0x07, 0x0F, 0x1F, 0x3F, 0x5F, 0x80,
                                      0x10F, 0x0B, 0x86};
    uint8_t pick = fz_u8(r);
    return pick < 200 ? common[pick % (sizeof common / sizeof common[0])] : fz_u16(r);
}

static void act(fz_reader_t *r, uint8_t p)
{
    co_line_set_time(&W.line, W.now);
    switch (p % 8) {
    case 0:
        network_write(0x6040, 0, controlword(r));
        break;
    case 1:
        pdo_write(0x6040, 0, controlword(r));
        break;
    case 2: {
        uint8_t which = fz_u8(r);
        network_write(writable[which % WRITABLE].index, writable[which % WRITABLE].sub,
                      fz_u32(r));
        break;
    }
    case 3: {
        uint8_t which = fz_u8(r);
        pdo_write(writable[which % WRITABLE].index, writable[which % WRITABLE].sub, fz_u32(r));
        break;
    }
    case 4:
        co_cia402_sim_on_sync(fz_u8(r), &W.sim);
        break;
    case 5:
        co_cia402_sim_fault(&W.sim, fz_u16(r));
        break;
    case 6:
        co_cia402_sim_step(&W.sim, fz_u16(r));
        break;
    default:
        network_write(0x6060, 0, (uint32_t)(int32_t)(int8_t)fz_u8(r));
        break;
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    co_emcy_config_t ec;
    fz_reader_t r;
    fz_record_t rec;
    co_frame_t drop;
    if (size == 0) {
        return 0;
    }
    memset(&W, 0, sizeof W);
    W.supported = data[0];
    CHECK(fz_line_init(&W.line, CO_MODE_CLASSIC, W.rx, W.tx, SLOTS), "line init");
    od_build();
    memset(&ec, 0, sizeof ec);
    ec.queue = W.emcy_queue;
    ec.queue_capacity = 4;
    ec.active = W.emcy_active;
    ec.active_capacity = 4;
    CHECK(co_emcy_init(&W.emcy, &W.line, NODE, &ec), "EMCY init");
    co_emcy_set_nmt_state(&W.emcy, CO_NMT_OPERATIONAL);
    CHECK(co_cia402_sim_init(&W.sim, &W.line, &W.od, NULL, &W.emcy, TICK_US), "sim init");
    last_state = W.sim.state;
    last_transitions = W.sim.transitions;
    check();
    fz_reader_init(&r, data + 1, size - 1);
    while (fz_next(&r, &rec, ids, sizeof ids / sizeof ids[0], CO_MODE_CLASSIC)) {
        switch (rec.op) {
        case FZ_OP_TIME: {
            /* every tick at its own time */
            uint64_t until = W.now + (uint64_t)rec.ms * 1000u;
            for (;;) {
                uint64_t next = co_timer_list_next(co_line_timers(&W.line));
                if (next > until) {
                    break;
                }
                W.now = next > W.now ? next : W.now;
                (void)co_line_process(&W.line, W.now);
                check();
            }
            W.now = until;
            (void)co_line_process(&W.line, W.now);
            break;
        }
        case FZ_OP_ACTION:
            act(&r, rec.p);
            break;
        default:
            if (rec.op == FZ_OP_FRAME || rec.op == FZ_OP_FRAME2) {
                (void)co_line_receive(&W.line, &rec.frame);   /* nothing here serves it */
            }
            (void)co_line_process(&W.line, W.now);
            break;
        }
        while (co_line_tx_pop(&W.line, &drop)) {
        }
        check();
    }
    co_cia402_sim_deinit(&W.sim);
    co_emcy_deinit(&W.emcy);
    return 0;
}
