/* A simulated CiA 402 drive on a local node: the power state machine driven
 * by controlword writes (0x6040, from SDO/USDO, RPDO or the application),
 * the statusword (0x6041) it answers with, and a simple motion model per
 * mode of operation (0x6060/0x6061): profile position, profile velocity and
 * homing advance on a periodic tick; cyclic synchronous position, velocity
 * and torque apply their targets at each SYNC. A fault can be injected
 * (0x603F set, EMCY raised, Fault reaction active, then Fault).
 *
 * The drive keeps no state outside its struct and allocates nothing; its
 * objects must be in the node's sealed OD (co_cia402_sim_init names the
 * first one missing). Protocol facts and sources: docs/protocol-notes.md,
 * "CiA 402 drive". */
#ifndef CO_CIA402_SIM_H
#define CO_CIA402_SIM_H

#include "canopenfd/co_emcy.h"
#include "canopenfd/co_line.h"
#include "canopenfd/co_od.h"
#include "canopenfd/co_pdo.h"
#include "canopenfd/co_sync.h"

/* The power states, numbered as the Python helper names them. */
typedef enum co_cia402_state {
    CO_CIA402_NOT_READY_TO_SWITCH_ON = 0,
    CO_CIA402_SWITCH_ON_DISABLED = 1,
    CO_CIA402_READY_TO_SWITCH_ON = 2,
    CO_CIA402_SWITCHED_ON = 3,
    CO_CIA402_OPERATION_ENABLED = 4,
    CO_CIA402_QUICK_STOP_ACTIVE = 5,
    CO_CIA402_FAULT_REACTION_ACTIVE = 6,
    CO_CIA402_FAULT = 7
} co_cia402_state_t;

/* Modes of operation (0x6060 values) the simulator models. */
typedef enum co_cia402_mode {
    CO_CIA402_MODE_NONE = 0,
    CO_CIA402_MODE_PROFILE_POSITION = 1,
    CO_CIA402_MODE_PROFILE_VELOCITY = 3,
    CO_CIA402_MODE_HOMING = 6,
    CO_CIA402_MODE_CSP = 8,
    CO_CIA402_MODE_CSV = 9,
    CO_CIA402_MODE_CST = 10
} co_cia402_mode_t;

/* Statusword bits (0x6041). */
#define CO_CIA402_SW_VOLTAGE_ENABLED 0x0010u
#define CO_CIA402_SW_QUICK_STOP 0x0020u        /* 1: quick stop NOT active */
#define CO_CIA402_SW_REMOTE 0x0200u
#define CO_CIA402_SW_TARGET_REACHED 0x0400u
#define CO_CIA402_SW_MODE_BIT12 0x1000u        /* set-point ack / homing attained / speed 0 /
                                                  following the cyclic target */
/* Controlword bits (0x6040). */
#define CO_CIA402_CW_NEW_SET_POINT 0x0010u
#define CO_CIA402_CW_CHANGE_IMMEDIATELY 0x0020u
#define CO_CIA402_CW_RELATIVE 0x0040u
#define CO_CIA402_CW_FAULT_RESET 0x0080u
#define CO_CIA402_CW_HALT 0x0100u

/* The objects co_cia402_sim_init requires, index << 8 | sub. */
#define CO_CIA402_SIM_REQUIRED_COUNT 15u
extern const uint32_t co_cia402_sim_required[CO_CIA402_SIM_REQUIRED_COUNT];

typedef struct co_cia402_sim {
    co_od_t *od;
    co_line_t *line;
    co_sync_t *sync;             /* NULL: cyclic modes follow co_cia402_sim_on_sync calls */
    co_emcy_t *emcy;             /* NULL: faults send no EMCY */
    co_pdo_t *pdo;               /* NULL: no event TPDO triggered on a new statusword */
    co_timer_t tick;
    uint32_t tick_us;
    co_cia402_state_t state;
    uint16_t controlword;        /* last one applied (edges of bits 4 and 7) */
    double position;             /* units, fractional between ticks */
    double velocity;             /* units/s */
    int32_t target;              /* profile position: the set-point in progress */
    int32_t pending_target;      /* the buffered next set-point (bit 5 clear) */
    bool moving;
    bool has_pending;
    bool homing;
    bool homing_attained;
    bool set_point_ack;
    bool subscribed;
    uint32_t missing_key;        /* the object init did not find (0: none) */
    uint32_t syncs;              /* SYNCs seen in a cyclic mode while enabled */
    uint32_t transitions;        /* state changes since init */
} co_cia402_sim_t;

/* Starts the drive in Switch on disabled (after passing Not ready to switch
 * on) and its tick every tick_us (> 0) on the line's timer list. False when
 * an object is missing (sim->missing_key names it), the OD has no room for
 * the subscription, the SYNC has no listener slot, or an argument is bad. */
bool co_cia402_sim_init(co_cia402_sim_t *sim, co_line_t *line, co_od_t *od, co_sync_t *sync,
                        co_emcy_t *emcy, uint32_t tick_us);
void co_cia402_sim_deinit(co_cia402_sim_t *sim);
/* Event TPDOs (types 0, 254, 255) mapping the statusword or the mode display
 * are triggered when they change, as a real drive sends them (NULL: none). */
void co_cia402_sim_set_pdo(co_cia402_sim_t *sim, co_pdo_t *pdo);

/* A device fault: 0x603F = code, EMCY raised with it, Fault reaction active
 * (motion stops), Fault at the next tick. Ignored while already in fault. */
void co_cia402_sim_fault(co_cia402_sim_t *sim, uint16_t code);
/* A SYNC: cyclic synchronous modes apply their target (co_cia402_sim_init
 * registers this with the SYNC it is given). */
void co_cia402_sim_on_sync(uint8_t counter, void *sim);
/* One tick of the profile modes' motion model, dt_us long (the timer calls it). */
void co_cia402_sim_step(co_cia402_sim_t *sim, uint32_t dt_us);

static inline co_cia402_state_t co_cia402_sim_state(const co_cia402_sim_t *sim)
{
    return sim->state;
}
/* The statusword bits 0..6 of a state (0x4F / 0x6F patterns). */
uint16_t co_cia402_state_bits(co_cia402_state_t state);

#endif
