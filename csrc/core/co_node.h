/* The local node of a line: NMT slave + heartbeat producer, with the few
 * object-dictionary values they need (0x1017) until the OD service lands. */
#ifndef CO_NODE_H
#define CO_NODE_H

#include "co_hb.h"

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
    uint16_t heartbeat_default_ms;   /* 0x1017 value restored by a reset */
    const co_node_indications_t *ind;
    void *user;
};

/* Sets up the node on the line (node_id 1..127, the line's node-id becomes
 * node_id); nothing is sent until co_node_boot(). */
bool co_node_init(co_node_t *node, co_line_t *line, uint8_t node_id,
                  uint16_t heartbeat_ms, const co_node_indications_t *ind, void *user);
void co_node_deinit(co_node_t *node);
/* Power-on: boot-up message, pre-operational, heartbeat producer running. */
void co_node_boot(co_node_t *node);
/* Write 0x1017: takes effect at once. */
void co_node_set_heartbeat(co_node_t *node, uint16_t time_ms);
static inline co_nmt_state_t co_node_state(const co_node_t *node) { return node->nmt.state; }

#endif
