/* The world most harnesses run in: two lines on an in-process bus (membus)
 * with a fake clock. The device line carries a node assembled by co_stack
 * (an OD with every service's entries, a store, the SDO server channels or
 * USDO server sessions); the tool line carries a second co_stack with the
 * line services and a client (USDO on fd lines, SDO on classic lines).
 *
 * Harnesses differ in the line mode, the line their FRAME records are
 * queued on, the CAN-IDs their frames use and the actions they allow; the
 * run loop, the actions and the invariant checks are shared here.
 *
 * Invariants checked (a failure calls fw_fail, which aborts):
 *   - every frame carried on the bus is valid (co_frame_is_valid), and
 *     carries no FD flag on a classic line;
 *   - queue counts never exceed their capacities;
 *   - every started client request ends exactly once, never twice, and
 *     done() is only called for a running request;
 *   - a domain is written in order (each chunk at the previous end);
 *   - indications name node-ids 1..127;
 *   - after SETTLE (and at the end of every input): every split answer was
 *     resumed, 15 s passed without new input, then no client request is
 *     open and every server session / channel is free;
 *   - the bus becomes quiet after every step (no endless frame exchange at
 *     one instant) and timers do not fire forever at one instant. */
#ifndef FUZZ_WORLD_H
#define FUZZ_WORLD_H

#include "fuzz_input.h"

#include "canopenfd/co_stack.h"
#include "canopenfd/co_membus.h"

enum { FW_NODE = 5, FW_CLIENT = 9 };

/* Application actions (ACTION records); a harness lists the ones it allows
 * and p picks from that list. Arguments read with fz_*: see fuzz_world.c. */
typedef enum fw_action {
    FW_CLIENT_START,      /* tool's client starts a request on a free slot */
    FW_CLIENT_CANCEL,     /* tool cancels a running request */
    FW_SPLIT_MODE,        /* device: 0x2100's handler answers later (or not) */
    FW_RESUME,            /* device: answer one split access */
    FW_NMT_LOCAL,         /* device: an NMT command applied locally */
    FW_NMT_MASTER,        /* tool: an NMT command sent on the bus */
    FW_OD_WRITE,          /* device: a checked write through the OD (as a server does) */
    FW_OD_PUT,            /* device: an application write (co_od_put) */
    FW_PDO_TRIGGER,       /* device: trigger a TPDO / the TPDOs mapping an object */
    FW_EMCY,              /* device: raise or clear an error */
    FW_TIME_SEND,         /* device or tool: send a TIME object */
    FW_WATCH,             /* tool: heartbeat / EMCY consumer watch, guarding */
    FW_STORE,             /* device: save / restore defaults */
    FW_LED,               /* device: LED inputs an LSS slave or the application gives */
    FW_MPDO_SEND,         /* device: send a DAM or SAM MPDO through a TPDO */
    FW_ACTION_COUNT
} fw_action_t;

typedef struct fw_config {
    co_mode_t mode;
    bool inject_tool;             /* FRAME records go to the tool line, else the device's */
    const uint32_t *ids;          /* CAN-ID table of FRAME records */
    uint8_t id_count;
    const uint8_t *actions;       /* allowed actions (fw_action_t) */
    uint8_t action_count;
    bool device_client;           /* classic: the device runs its 0x1280 SDO client too */
} fw_config_t;

/* Run one input in a fresh world. */
void fw_run(const fw_config_t *config, const uint8_t *data, size_t size);

/* An invariant broke: print and abort (libFuzzer records the input). */
void fw_fail(const char *what);

#endif
