#include "co_node.h"

static void on_state_changed(co_nmt_t *nmt, co_nmt_state_t old_state,
                             co_nmt_state_t new_state, void *user)
{
    (void)nmt;
    co_node_t *node = user;
    if (node->ind && node->ind->state_changed) {
        node->ind->state_changed(node, old_state, new_state, node->user);
    }
}

static bool on_allow_operational(co_nmt_t *nmt, void *user)
{
    (void)nmt;
    co_node_t *node = user;
    if (node->ind && node->ind->allow_operational) {
        return node->ind->allow_operational(node, node->user);
    }
    return true;
}

static void on_reset(co_nmt_t *nmt, co_nmt_command_t kind, void *user)
{
    (void)nmt;
    co_node_t *node = user;
    /* Both resets reload the communication parameters; 0x1017 is one. The
     * boot-up message follows right after this, the first heartbeat one
     * period later. */
    co_hb_producer_set_time(&node->heartbeat, node->heartbeat_default_ms);
    if (node->ind && node->ind->reset) {
        node->ind->reset(node, kind, node->user);
    }
}

static const co_nmt_indications_t nmt_indications = {
    .state_changed = on_state_changed,
    .allow_operational = on_allow_operational,
    .reset = on_reset,
};

bool co_node_init(co_node_t *node, co_line_t *line, uint8_t node_id,
                  uint16_t heartbeat_ms, const co_node_indications_t *ind, void *user)
{
    node->line = line;
    node->ind = ind;
    node->user = user;
    node->heartbeat_default_ms = heartbeat_ms;
    if (!co_nmt_init(&node->nmt, line, node_id, &nmt_indications, node)) {
        return false;
    }
    co_hb_producer_init(&node->heartbeat, line, &node->nmt);
    node->heartbeat.time_ms = heartbeat_ms;
    line->node_id = node_id;
    return true;
}

void co_node_deinit(co_node_t *node)
{
    co_hb_producer_stop(&node->heartbeat);
    co_nmt_deinit(&node->nmt);
    node->line->node_id = 0;
}

void co_node_boot(co_node_t *node)
{
    co_nmt_boot(&node->nmt);
    /* The first heartbeat follows the boot-up one producer period later. */
    co_hb_producer_set_time(&node->heartbeat, node->heartbeat.time_ms);
}

void co_node_set_heartbeat(co_node_t *node, uint16_t time_ms)
{
    co_hb_producer_set_time(&node->heartbeat, time_ms);
}
