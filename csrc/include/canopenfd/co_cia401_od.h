/* A CiA 401 generic I/O device bound to a node's object dictionary: the
 * channel logic of co_cia401.h run over the OD's profile objects, so a
 * firmware built on the core gets the profile without any code of its own.
 *
 * - The channels are what the OD holds: 0x6000 (digital input groups),
 *   0x6200 (digital output groups), 0x6401 (analogue inputs), 0x6411
 *   (analogue outputs), each sub 1..sub 0 (an absent object: no channel of
 *   that kind). Their parameter objects (0x6002..0x6008, 0x6202..0x6208,
 *   0x6421..0x6428, 0x6443/0x6444) are read once at the attach and again
 *   when one is written (SDO, USDO, RPDO, the application, a reset's
 *   reload): after-write handlers, no polling. An absent parameter object
 *   keeps the device's default (docs/cia401.md).
 * - The application reports inputs (co_cia401_od_set_inputs,
 *   co_cia401_od_set_analog_input): 0x6000 / 0x6401 take them and every
 *   event-driven TPDO mapping a channel whose change passes the interrupt
 *   masks / triggers is sent once (in operational only: the PDO service's
 *   rule).
 * - Writes of 0x6200 / 0x6411 by anyone (SDO, USDO, the application, and
 *   an RPDO through co_cia401_od_rpdo_received) set the physical outputs;
 *   a change is told to `on_outputs` once per write, which reads them with
 *   co_cia401_od_digital_output / co_cia401_od_analog_output.
 * - A fault (co_cia401_od_fault, or the node entering STOPPED through
 *   co_cia401_od_nmt_state) applies the error modes / values; a reset node
 *   (co_cia401_od_reset) puts the inputs back into the reloaded OD and the
 *   outputs follow the reloaded 0x6200 / 0x6411.
 * co_stack runs one for its node (co_stack_cia401_init) and feeds it the
 * RPDOs, NMT states and resets. No allocation: the caller gives the
 * channel memory (co_cia401_od_need). Sources: docs/protocol-notes.md,
 * section "CiA 401". */
#ifndef CO_CIA401_OD_H
#define CO_CIA401_OD_H

#include "canopenfd/co_cia401.h"
#include "canopenfd/co_nmt.h"
#include "canopenfd/co_od.h"
#include "canopenfd/co_pdo.h"

#include <stddef.h>

/* cffi:begin */
/* The profile objects (index of each). */
enum {
    CO_CIA401_OD_READ_INPUT = 0x6000,
    CO_CIA401_OD_INPUT_POLARITY = 0x6002,
    CO_CIA401_OD_INPUT_FILTER = 0x6003,
    CO_CIA401_OD_INPUT_INTERRUPT_ENABLE = 0x6005,
    CO_CIA401_OD_INPUT_ANY_CHANGE = 0x6006,
    CO_CIA401_OD_INPUT_RISING = 0x6007,
    CO_CIA401_OD_INPUT_FALLING = 0x6008,
    CO_CIA401_OD_WRITE_OUTPUT = 0x6200,
    CO_CIA401_OD_OUTPUT_POLARITY = 0x6202,
    CO_CIA401_OD_OUTPUT_ERROR_MODE = 0x6206,
    CO_CIA401_OD_OUTPUT_ERROR_VALUE = 0x6207,
    CO_CIA401_OD_OUTPUT_FILTER_MASK = 0x6208,
    CO_CIA401_OD_READ_ANALOG_INPUT = 0x6401,
    CO_CIA401_OD_WRITE_ANALOG_OUTPUT = 0x6411,
    CO_CIA401_OD_ANALOG_TRIGGER = 0x6421,
    CO_CIA401_OD_ANALOG_INTERRUPT_ENABLE = 0x6423,
    CO_CIA401_OD_ANALOG_UPPER = 0x6424,
    CO_CIA401_OD_ANALOG_LOWER = 0x6425,
    CO_CIA401_OD_ANALOG_DELTA = 0x6426,
    CO_CIA401_OD_ANALOG_NEGATIVE_DELTA = 0x6427,
    CO_CIA401_OD_ANALOG_POSITIVE_DELTA = 0x6428,
    CO_CIA401_OD_ANALOG_OUTPUT_ERROR_MODE = 0x6443,
    CO_CIA401_OD_ANALOG_OUTPUT_ERROR_VALUE = 0x6444
};

/* Which kinds of output changed (the `kinds` bits of the indication). */
enum {
    CO_CIA401_OUT_DIGITAL = 0x01,
    CO_CIA401_OUT_ANALOG = 0x02
};

/* What co_cia401_od_scan and the application calls say. */
typedef enum co_cia401_od_result {
    CO_CIA401_OD_OK = 0,
    CO_CIA401_OD_NO_CHANNELS = 1,   /* none of 0x6000/0x6200/0x6401/0x6411 */
    CO_CIA401_OD_MISSING_SUB = 2,   /* a channel sub 1..sub 0 is missing */
    CO_CIA401_OD_BAD_TYPE = 3,      /* a channel or parameter entry of the wrong type */
    CO_CIA401_OD_BAD_CHANNEL = 4,   /* a group / channel the device does not have */
    CO_CIA401_OD_NOT_ATTACHED = 5
} co_cia401_od_result_t;

/* Channels of each kind, as the OD holds them. */
typedef struct co_cia401_od_counts {
    uint8_t input_groups;
    uint8_t output_groups;
    uint8_t analog_inputs;
    uint8_t analog_outputs;
} co_cia401_od_counts_t;
/* cffi:end */

typedef struct co_cia401_od co_cia401_od_t;

/* Outputs of `kinds` (CO_CIA401_OUT_*) changed: read them now. */
typedef void (*co_cia401_outputs_fn)(co_cia401_od_t *io, uint8_t kinds, void *user);

struct co_cia401_od {
    co_od_t *od;
    co_pdo_t *pdo;                   /* the TPDOs to trigger, or NULL */
    co_cia401_od_counts_t counts;
    co_cia401_din_t *din;            /* counts.input_groups of them, ... */
    co_cia401_dout_t *dout;
    co_cia401_ain_t *ain;
    co_cia401_aout_t *aout;
    co_cia401_outputs_fn on_outputs;
    void *user;
    bool attached;
};

/* The channels `od` (sealed) holds, checked: channel entries UNSIGNED8
 * (digital) / INTEGER16 (analogue), parameter entries of the types
 * docs/cia401.md lists. Not OK: *bad_index / *bad_sub name the entry. */
co_cia401_od_result_t co_cia401_od_scan(const co_od_t *od, co_cia401_od_counts_t *counts,
                                        uint16_t *bad_index, uint8_t *bad_sub);
/* Bytes of channel memory the counts need (aligned for any type). */
size_t co_cia401_od_need(const co_cia401_od_counts_t *counts);
/* Bind to od (scanned to `counts`) over `memory` (co_cia401_od_need bytes,
 * zeroed, aligned for any type); pdo (may be NULL) sends the input TPDOs.
 * Parameters and input states are taken from the OD now; outputs start at
 * 0. False when the OD has no room for the subscription. */
bool co_cia401_od_attach(co_cia401_od_t *io, co_od_t *od, co_pdo_t *pdo,
                         const co_cia401_od_counts_t *counts, void *memory,
                         co_cia401_outputs_fn on_outputs, void *user);
void co_cia401_od_detach(co_cia401_od_t *io);

/* ---- the application */
/* Raw levels of input groups first..first+count-1 (1-based, as 0x6000's
 * subs): polarity and filter applied, 0x6000 written, the TPDOs of the
 * groups whose change passes the masks triggered once each. */
co_cia401_od_result_t co_cia401_od_set_inputs(co_cia401_od_t *io, uint8_t first,
                                              const uint8_t *raw, uint8_t count);
/* A new value of analogue input `channel` (1-based): 0x6401 written, its
 * TPDOs triggered when a selected condition holds. */
co_cia401_od_result_t co_cia401_od_set_analog_input(co_cia401_od_t *io, uint8_t channel,
                                                    int16_t value);
/* A device fault: the error modes / values apply (told when they change). */
void co_cia401_od_fault(co_cia401_od_t *io);
/* The physical levels of output group `group` / analogue output `channel`
 * (1-based; 0 for one the device does not have). */
uint8_t co_cia401_od_digital_output(const co_cia401_od_t *io, uint8_t group);
int32_t co_cia401_od_analog_output(const co_cia401_od_t *io, uint8_t channel);

/* ---- the node's wiring (co_stack does it) */
/* RPDO `number` was applied: the outputs it maps follow. */
void co_cia401_od_rpdo_received(co_cia401_od_t *io, uint16_t number);
/* The node's NMT state changed: entering STOPPED is a fault. */
void co_cia401_od_nmt_state(co_cia401_od_t *io, co_nmt_state_t old_state,
                            co_nmt_state_t new_state);
/* The node was reset (after its reload): reset node puts the input states
 * back and the outputs follow the reloaded values. */
void co_cia401_od_reset(co_cia401_od_t *io, co_nmt_command_t kind);

#endif
