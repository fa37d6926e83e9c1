#include "co_node.h"

#include "co_cob_id.h"

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

enum { OD_CONSUMER_HEARTBEAT = 0x1016, OD_PRODUCER_HEARTBEAT = 0x1017 };

/* Consumer entry for 0x1016 sub `sub` (1-based), if the consumer has it. */
static bool consumer_entry_of(const co_node_t *node, uint8_t sub, uint8_t *index)
{
    if (!node->consumer || sub == 0 || sub > node->consumer->capacity) {
        return false;
    }
    *index = (uint8_t)(sub - 1);
    return true;
}

/* Bring the services in line with the OD's communication parameters. */
static void apply_od_parameters(co_node_t *node)
{
    uint16_t time_ms;
    if (co_od_get_u16(node->od, OD_PRODUCER_HEARTBEAT, 0, &time_ms)) {
        co_hb_producer_set_time(&node->heartbeat, time_ms);
    }
    uint8_t count = 0;
    co_od_get_u8(node->od, OD_CONSUMER_HEARTBEAT, 0, &count);
    for (uint8_t sub = 1; sub != 0 && sub <= count; sub++) {
        uint32_t value;
        uint8_t index;
        if (co_od_get_u32(node->od, OD_CONSUMER_HEARTBEAT, sub, &value) &&
            consumer_entry_of(node, sub, &index)) {
            co_hb_consumer_set_entry(node->consumer, index, value);
        }
    }
}

/* Boot and resets: defaults, then saved values, of the groups concerned. */
static void load_parameters(co_node_t *node, uint8_t groups)
{
    if (!node->od) {
        co_hb_producer_set_time(&node->heartbeat, node->heartbeat_default_ms);
        return;
    }
    if (node->store) {
        node->store_status = co_store_load(node->store, groups);
    } else {
        co_od_load_defaults(node->od, groups);
    }
    apply_od_parameters(node);
}

static void on_reset(co_nmt_t *nmt, co_nmt_command_t kind, void *user)
{
    (void)nmt;
    co_node_t *node = user;
    /* Reset communication reloads the communication parameters, reset node
     * all of them. The boot-up message follows right after this, the first
     * heartbeat one period later. */
    load_parameters(node, kind == CO_NMT_CMD_RESET_COMMUNICATION ? CO_GROUP_COMMUNICATION
                                                                  : CO_GROUP_ALL);
    if (node->ind && node->ind->reset) {
        node->ind->reset(node, kind, node->user);
    }
}

/* 0x1016: a node-id may be watched by one entry only (CiA 301). */
static uint32_t check_comm_write(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e,
                                 const uint8_t *value, uint32_t length, void *user)
{
    (void)od;
    (void)xfer;
    co_node_t *node = user;
    uint8_t index;
    if (co_od_entry_index(e) != OD_CONSUMER_HEARTBEAT || length != 4 ||
        !consumer_entry_of(node, co_od_entry_sub(e), &index)) {
        return CO_ABORT_NONE;
    }
    uint8_t node_id = value[2];
    if (node_id == 0 || node_id > 127) {
        return CO_ABORT_NONE;
    }
    for (uint8_t i = 0; i < node->consumer->capacity; i++) {
        if (i != index && node->consumer->entries[i].node_id == node_id &&
            node->consumer->entries[i].time_ms != 0) {
            return CO_ABORT_PARAM_INCOMPATIBLE;
        }
    }
    return CO_ABORT_NONE;
}

static void after_comm_write(co_od_t *od, const co_od_entry_t *e, co_od_origin_t origin,
                             void *user)
{
    (void)origin;
    co_node_t *node = user;
    uint8_t index;
    uint32_t value;
    if (co_od_entry_index(e) == OD_PRODUCER_HEARTBEAT) {
        uint16_t time_ms;
        if (co_od_get_u16(od, OD_PRODUCER_HEARTBEAT, 0, &time_ms)) {
            co_hb_producer_set_time(&node->heartbeat, time_ms);   /* at once */
        }
    } else if (consumer_entry_of(node, co_od_entry_sub(e), &index) &&
               co_od_get_u32(od, OD_CONSUMER_HEARTBEAT, co_od_entry_sub(e), &value)) {
        co_hb_consumer_set_entry(node->consumer, index, value);
    }
}

static const co_od_handler_t comm_handler = {
    .check_write = check_comm_write,
    .after_write = after_comm_write,
};

bool co_node_attach_od(co_node_t *node, co_od_t *od, co_store_t *store,
                       co_hb_consumer_t *consumer)
{
    if (!co_od_subscribe(od, OD_CONSUMER_HEARTBEAT, 1, OD_PRODUCER_HEARTBEAT, 0, &comm_handler,
                         node)) {
        return false;
    }
    if (!co_cob_id_attach(od)) {
        co_od_unsubscribe(od, &comm_handler, node);
        return false;
    }
    node->od = od;
    node->store = store;
    node->consumer = consumer;
    return true;
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
    node->od = NULL;
    node->store = NULL;
    node->consumer = NULL;
    node->store_status = CO_STORE_EMPTY;
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
    if (node->od) {
        co_od_unsubscribe(node->od, &comm_handler, node);
        co_cob_id_detach(node->od);
        node->od = NULL;
    }
    co_hb_producer_stop(&node->heartbeat);
    co_nmt_deinit(&node->nmt);
    node->line->node_id = 0;
}

void co_node_boot(co_node_t *node)
{
    /* Power-on loads every parameter (without an OD: the producer time set
     * so far); the first heartbeat follows the boot-up one period later. */
    if (node->od) {
        load_parameters(node, CO_GROUP_ALL);
    } else {
        co_hb_producer_set_time(&node->heartbeat, node->heartbeat.time_ms);
    }
    co_nmt_boot(&node->nmt);
}

void co_node_set_heartbeat(co_node_t *node, uint16_t time_ms)
{
    /* With an OD, 0x1017 is the one truth: its after-write handler re-arms. */
    const uint8_t value[2] = {(uint8_t)time_ms, (uint8_t)(time_ms >> 8)};
    if (!node->od || co_od_put(node->od, OD_PRODUCER_HEARTBEAT, 0, value, 2) != CO_ABORT_NONE) {
        co_hb_producer_set_time(&node->heartbeat, time_ms);
    }
}
