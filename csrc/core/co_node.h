/* The local node of a line: NMT slave + heartbeat producer, and, when an
 * object dictionary is attached, the communication parameters it serves
 * (0x1016 consumer entries, 0x1017 producer time) loaded from defaults or
 * the store at boot and at each reset. Without an OD the node keeps the
 * 0x1017 value given at init. */
#ifndef CO_NODE_H
#define CO_NODE_H

#include "co_hb.h"
#include "co_od.h"
#include "co_store.h"

typedef struct co_node co_node_t;

typedef struct co_node_indications {
    void (*state_changed)(co_node_t *node, co_nmt_state_t old_state,
                          co_nmt_state_t new_state, void *user);
    bool (*allow_operational)(co_node_t *node, void *user);   /* may be NULL */
    void (*reset)(co_node_t *node, co_nmt_command_t kind, void *user); /* may be NULL */
} co_node_indications_t;

struct co_node {
    co_line_t *line;
    co_nmt_t nmt;
    co_hb_producer_t heartbeat;
    uint16_t heartbeat_default_ms;   /* 0x1017 value restored by a reset (no OD) */
    const co_node_indications_t *ind;
    void *user;
    co_od_t *od;                     /* sealed OD, or NULL */
    co_store_t *store;               /* saved parameters, or NULL */
    co_hb_consumer_t *consumer;      /* configured from 0x1016, or NULL */
    co_store_status_t store_status;  /* what the last parameter load found */
};

/* Sets up the node on the line (node_id 1..127, the line's node-id becomes
 * node_id); nothing is sent until co_node_boot(). */
bool co_node_init(co_node_t *node, co_line_t *line, uint8_t node_id,
                  uint16_t heartbeat_ms, const co_node_indications_t *ind, void *user);
void co_node_deinit(co_node_t *node);
/* Serve an object dictionary (sealed) before co_node_boot(): parameters load
 * from the store (or defaults) at boot and resets; writes to 0x1017 re-arm
 * the heartbeat at once; 0x1016 entries configure `consumer` (may be NULL),
 * a duplicate node-id being refused with CO_ABORT_PARAM_INCOMPATIBLE.
 * store may be NULL (defaults only). False when the OD cannot take the hooks. */
bool co_node_attach_od(co_node_t *node, co_od_t *od, co_store_t *store,
                       co_hb_consumer_t *consumer);
/* Power-on: parameters loaded, boot-up message, pre-operational, heartbeat
 * producer running. */
void co_node_boot(co_node_t *node);
/* Write 0x1017: takes effect at once. */
void co_node_set_heartbeat(co_node_t *node, uint16_t time_ms);
static inline co_nmt_state_t co_node_state(const co_node_t *node) { return node->nmt.state; }

#endif
