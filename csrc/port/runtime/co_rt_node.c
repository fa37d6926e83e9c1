/* Runtime: the line's local node. Creating it seals the defined OD with the
 * node-id, prepares its store (file or application), lets co_stack assemble
 * the node with its services, and hooks the runtime onto its OD (changed
 * entries told to Python; network saves into an application store wait
 * until it persisted). Also the NMT view: the local and remote states. */
#include "co_rt_internal.h"

#include <stdlib.h>

/* ================================================================ indications */

static void on_node_state(co_node_t *node, co_nmt_state_t old_state, co_nmt_state_t new_state,
                          void *user)
{
    rt_post(user, CO_EV_NMT_STATE, node->nmt.node_id, (uint32_t)old_state, (uint32_t)new_state,
         NULL);
}

static bool on_allow_operational(co_node_t *node, void *user)
{
    rt_line_t *l = user;
    if (!l->allow_operational) {
        rt_post(l, CO_EV_NMT_VETOED, node->nmt.node_id, 0, 0, NULL);
    }
    return l->allow_operational;
}

/* What each parameter load found is told to Python (a damaged, foreign or
 * unreadable store means the node runs on defaults). */
static void post_store_status(rt_line_t *l)
{
    if (rt_has_store(l)) {
        rt_post(l, CO_EV_STORE, co_stack_node(&l->stack)->nmt.node_id, (uint32_t)co_stack_node(&l->stack)->store_status,
             co_stack_store(&l->stack)->records_skipped, NULL);
    }
}

static void on_node_reset(co_node_t *node, co_nmt_command_t kind, void *user)
{
    rt_post(user, CO_EV_NMT_RESET, node->nmt.node_id, (uint32_t)kind, 0, NULL);
    post_store_status(user);
}

static void on_pdo_received(co_node_t *node, uint16_t rpdo_number, void *user)
{
    (void)node;
    rt_pdo_received(user, rpdo_number);
}

static void on_mpdo_received(co_node_t *node, uint16_t rpdo_number, const co_mpdo_msg_t *msg,
                             uint16_t index, uint8_t sub, uint32_t abort, void *user)
{
    (void)node;
    rt_mpdo_received(user, rpdo_number, msg, index, sub, abort);
}

static const co_node_indications_t node_indications = {
    .state_changed = on_node_state,
    .allow_operational = on_allow_operational,
    .reset = on_node_reset,
    .pdo_received = on_pdo_received,
    .mpdo_received = on_mpdo_received,
};

/* Entries changed by the network or a PDO are told to Python (object
 * changed); the application's own writes are not echoed back. */
static void on_od_written(co_od_t *od, const co_od_entry_t *e, co_od_origin_t origin, void *user)
{
    (void)od;
    if (origin == CO_ORIGIN_NETWORK || origin == CO_ORIGIN_PDO) {
        rt_line_t *l = user;
        rt_post(l, CO_EV_OD_CHANGED, co_stack_node(&l->stack)->nmt.node_id, e->key, (uint32_t)origin, NULL);
    }
}

static const co_od_handler_t od_observer = {.after_write = on_od_written};

/* ================================================================ creation */

/* Drop a defined OD and its store (the node did not come up with it). */
static void od_forget(rt_line_t *l)
{
    rt_od_drop_requests(l);
    rt_od_release(l);
    free(l->store_file);
    l->store_file = NULL;
    rt_app_store_free(l);
    rt_od_free_domains(l);
    l->has_od = false;
}

/* Seal the defined OD with the node-id and prepare its store backend. */
static int prepare_od(co_rt_t *rt, rt_line_t *l, uint8_t node_id,
                      co_stack_node_config_t *config)
{
    if (l->od.sealed) {
        rt_set_error(rt, "line %d: object dictionary already served by a node", l->index);
        return CO_RT_ERR_STATE;
    }
    if (!co_od_seal(&l->od, node_id)) {
        rt_set_error(rt, "line %d: OD entry 0x%04X:00 refused: an ARRAY/RECORD needs sub 0 "
                  "(UNSIGNED8)", l->index, l->od.refused_index);
        return CO_RT_ERR_ARGUMENT;
    }
    config->od = &l->od;
    if (l->store_path) {
        l->store_file = calloc(1, sizeof *l->store_file);
        if (!l->store_file || !co_store_file_init(l->store_file, l->store_path)) {
            rt_set_error(rt, "line %d: store %s cannot be used (no memory or path too long)",
                         l->index, l->store_path);
            return l->store_file ? CO_RT_ERR_ARGUMENT : CO_RT_ERR_NO_MEMORY;
        }
        config->store_backend = co_store_file_backend();
        config->store_user = l->store_file;
        config->store_image_capacity = co_store_image_need_grown(&l->od);   /* live adds too */
    } else if (l->app_store.enabled) {
        int status = rt_app_store_open(rt, l, &config->store_image_capacity);
        if (status != CO_RT_OK) {
            return status;
        }
        config->store_backend = &rt_app_store_backend;
        config->store_user = l;
        config->store_saved = rt_app_store_autonomous;
    }
    config->store_groups = l->store_groups;
    config->store_group_rows = l->store_group_rows;
    config->store_min_interval_ms = l->store_min_interval_ms;
    return CO_RT_OK;
}

static int stack_error(co_rt_t *rt, const rt_line_t *l, co_stack_status_t status)
{
    co_stack_part_t part = co_stack_failed_part(&l->stack);
    const char *name = co_stack_part_name(part);
    switch (status) {
    case CO_STACK_ERR_NO_MEMORY:
        rt_set_error(rt, "line %d: no memory for the %s", l->index, name);
        return CO_RT_ERR_NO_MEMORY;
    case CO_STACK_ERR_OD:
        rt_set_error(rt, "line %d: the OD cannot be used by the %s", l->index, name);
        return CO_RT_ERR_ARGUMENT;
    case CO_STACK_ERR_TAKEN:
        rt_set_error(rt, "line %d: %s could not start (CAN-IDs or OD handler table taken)",
                     l->index, name);
        return CO_RT_ERR_FULL;
    default:
        rt_set_error(rt, "line %d: %s could not be set up (status %d)", l->index, name,
                     (int)status);
        return status == CO_STACK_ERR_ARGUMENT ? CO_RT_ERR_ARGUMENT : CO_RT_ERR_STATE;
    }
}

/* Hooks of the runtime on the node's OD: Python hears changed entries, and
 * network saves into an application store wait until it persisted. */
static int hook_od(co_rt_t *rt, rt_line_t *l)
{
    if (!co_od_subscribe(&l->od, 0x0000, 0, 0xFFFF, 0xFF, &od_observer, l) ||
        (l->app_store.enabled && !rt_app_store_hook(l))) {
        rt_set_error(rt, "line %d: object dictionary handler table full", l->index);
        return CO_RT_ERR_FULL;
    }
    return CO_RT_OK;
}

int rt_node_create(co_rt_t *rt, rt_line_t *l, const co_rt_command_t *cmd)
{
    if (co_stack_unconfigured(&l->stack)) {
        rt_set_error(rt, "line %d already has a local node, waiting for an LSS node-id",
                     l->index);
        return CO_RT_ERR_STATE;
    }
    if (rt_has_node(l)) {
        rt_set_error(rt, "line %d already has local node %u", l->index,
                     co_stack_node(&l->stack)->nmt.node_id);
        return CO_RT_ERR_STATE;
    }
    co_stack_node_config_t config = {.node_id = (uint8_t)cmd->args.node_create.node_id,
                                     .heartbeat_ms = (uint16_t)cmd->args.node_create.heartbeat_ms,
                                     .ind = &node_indications,
                                     .user = l,
                                     /* CiA 303-3 LEDs: Python hears them while
                                      * it listens (co_rt_led.c) */
                                     .leds = true,
                                     .led_changed = l->led.events ? rt_led_changed : NULL,
                                     .lss_ind = rt_lss_slave_indications(l),
                                     .lss_user = l};
    int status = l->has_od ? prepare_od(rt, l, config.node_id, &config) : CO_RT_OK;
    if (status == CO_RT_OK) {
        co_stack_status_t s = co_stack_node_init(&l->stack, &config);
        status = s == CO_STACK_OK ? CO_RT_OK : stack_error(rt, l, s);
    }
    if (status == CO_RT_OK && l->has_od) {
        status = hook_od(rt, l);
    }
    if (status != CO_RT_OK) {
        /* Leave the line as it was before the node: usable for a new try. */
        rt_pdo_node_detach(l);
        co_stack_node_deinit(&l->stack);
        if (l->has_od) {
            od_forget(l);
        }
        return status;
    }
    co_stack_boot(&l->stack);
    post_store_status(l);
    /* the gateway hooks the new node's OD and PDOs */
    return l->network_id != 0 ? rt_gateway_rebuild(rt) : CO_RT_OK;
}

/* Creating the local node runs at once under the lock (the thread is not
 * processing then): the caller learns of a refused OD or store right away,
 * and the node exists for OD access as soon as the call returns. */
rt_line_t *rt_node_line(co_rt_t *rt, int line, const char *what)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return NULL;
    }
    rt_mutex_lock(&rt->lock);
    if (!rt_has_node(l)) {
        rt_mutex_unlock(&rt->lock);
        rt_set_error(rt, "line %d: %s needs a local node", line, what);
        return NULL;
    }
    return l;
}

/* ================================================================ NMT view */

int co_rt_local_state(co_rt_t *rt, int line)
{
    rt_line_t *l = rt ? rt_checked_line(rt, line, false) : NULL;
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    int state = rt_has_node(l) ? (int)co_node_state(co_stack_node(&l->stack)) : CO_RT_ERR_STATE;
    rt_mutex_unlock(&rt->lock);
    return state;
}

int co_rt_node_id_at_reset(co_rt_t *rt, int line, int node_id)
{
    rt_line_t *l = rt ? rt_checked_line(rt, line, false) : NULL;
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    if (node_id < 1 || node_id > 127) {
        return rt_argument_error(rt, "line %d: node-id %d outside 1..127", line, node_id);
    }
    rt_mutex_lock(&rt->lock);
    int status = CO_RT_OK;
    if (co_stack_set_node_id_at_reset(&l->stack, (uint8_t)node_id) != CO_STACK_OK) {
        rt_set_error(rt, "line %d: no running local node to give node-id %d (boot it first)",
                     line, node_id);
        status = CO_RT_ERR_STATE;
    }
    rt_mutex_unlock(&rt->lock);
    return status;
}

int co_rt_remote_state(co_rt_t *rt, int line, int node_id)
{
    rt_line_t *l = rt ? rt_checked_line(rt, line, false) : NULL;
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    if (node_id < 1 || node_id > 127) {
        return rt_argument_error(rt, "node-id %d outside 1..127", node_id);
    }
    rt_mutex_lock(&rt->lock);
    int state = co_stack_hb_consumer(&l->stack)->last_state[node_id];
    rt_mutex_unlock(&rt->lock);
    return state;
}
