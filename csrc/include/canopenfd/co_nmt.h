/* NMT: the slave state machine of the local node, and the master's commands. */
#ifndef CO_NMT_H
#define CO_NMT_H

#include "canopenfd/co_line.h"

/* cffi:begin */
typedef enum co_nmt_state {
    CO_NMT_INITIALISING = 0x00,   /* also the boot-up heartbeat value */
    CO_NMT_STOPPED = 0x04,
    CO_NMT_OPERATIONAL = 0x05,
    CO_NMT_PRE_OPERATIONAL = 0x7F,
    CO_NMT_UNKNOWN = 0xFF         /* not seen yet (remote nodes only) */
} co_nmt_state_t;

typedef enum co_nmt_command {
    CO_NMT_CMD_START = 0x01,
    CO_NMT_CMD_STOP = 0x02,
    CO_NMT_CMD_PRE_OPERATIONAL = 0x80,
    CO_NMT_CMD_RESET_NODE = 0x81,
    CO_NMT_CMD_RESET_COMMUNICATION = 0x82
} co_nmt_command_t;
/* cffi:end */

enum { CO_NMT_COB_ID = 0x000, CO_NMT_EC_COB_ID_BASE = 0x700 };

typedef struct co_nmt co_nmt_t;

typedef struct co_nmt_indications {
    /* The state changed (after boot-up too). */
    void (*state_changed)(co_nmt_t *nmt, co_nmt_state_t old_state,
                          co_nmt_state_t new_state, void *user);
    /* Test pass before "to operational": return false to veto. May be NULL. */
    bool (*allow_operational)(co_nmt_t *nmt, void *user);
    /* A reset is being executed: the application reloads its parameters
     * (communication ones only for CO_NMT_CMD_RESET_COMMUNICATION) before the
     * boot-up message goes out. May be NULL. */
    void (*reset)(co_nmt_t *nmt, co_nmt_command_t kind, void *user);
} co_nmt_indications_t;

struct co_nmt {
    co_line_t *line;
    uint8_t node_id;
    co_nmt_state_t state;
    const co_nmt_indications_t *ind;
    void *user;
    uint32_t vetoed;              /* "to operational" refusals */
};

/* Binds the NMT slave to the line (subscribes CAN-ID 0). State stays
 * INITIALISING until co_nmt_boot(). node_id must be 1..127. */
bool co_nmt_init(co_nmt_t *nmt, co_line_t *line, uint8_t node_id,
                 const co_nmt_indications_t *ind, void *user);
void co_nmt_deinit(co_nmt_t *nmt);
/* Power-on: initialisation -> boot-up message -> pre-operational. */
void co_nmt_boot(co_nmt_t *nmt);
/* Apply a command to the local node, as if received from the master. */
void co_nmt_apply(co_nmt_t *nmt, co_nmt_command_t command);
static inline co_nmt_state_t co_nmt_state(const co_nmt_t *nmt) { return nmt->state; }

/* True for the five command codes of CiA 301. */
bool co_nmt_command_is_valid(uint8_t command);
/* State a command leads to (INITIALISING for the resets). */
co_nmt_state_t co_nmt_command_target(co_nmt_command_t command);

/* NMT master: send a command to node_id (0 = all nodes). CAN does not echo
 * our own frames, so when the target includes the local node (its own id, or
 * 0 with include_self) the command is applied to `local` too.
 * local may be NULL (no local node). False when the frame could not be queued
 * or the arguments are invalid (the local node still follows the command). */
bool co_nmt_master_send(co_line_t *line, co_nmt_t *local, co_nmt_command_t command,
                        uint8_t node_id, bool include_self);

#endif
