/* The CANopen API of seed 004 over the node assembly: the process image is
 * the first bytes of the OD's pool (co_od_reserve_image), so the host's
 * reads and writes are copies within it and the network's writes into it
 * are told to the host as ReceivedData. */
#include "canopenfd/co_api.h"

#include <string.h>

/* ---------------------------------------------------------------- indications */

static void tell_nmt(co_api_t *api, uint8_t state)
{
    if (api->config.cb && api->config.cb->nmt_change) {
        api->config.cb->nmt_change(state, api->config.user);
    }
}

static void tell_received(co_api_t *api, uint32_t offset, uint32_t length)
{
    if (api->config.cb && api->config.cb->received_data && length > 0) {
        api->config.cb->received_data((uint8_t)offset, (uint8_t)length, api->config.user);
    }
}

static const co_node_indications_t *app_ind(const co_api_t *api)
{
    return api->config.node.ind;
}

static void on_state(co_node_t *node, co_nmt_state_t old_state, co_nmt_state_t new_state,
                     void *user)
{
    co_api_t *api = user;
    tell_nmt(api, (uint8_t)new_state);
    if (app_ind(api) && app_ind(api)->state_changed) {
        app_ind(api)->state_changed(node, old_state, new_state, api->config.node.user);
    }
}

static bool on_allow_operational(co_node_t *node, void *user)
{
    co_api_t *api = user;
    if (app_ind(api) && app_ind(api)->allow_operational) {
        return app_ind(api)->allow_operational(node, api->config.node.user);
    }
    return true;
}

static void load_initial_image(co_api_t *api)
{
    co_od_t *od = api->config.node.od;
    if (api->config.initial_image != NULL && co_od_image_size(od) > 0) {
        memcpy(co_od_image(od), api->config.initial_image, co_od_image_size(od));
    }
}

static void on_reset(co_node_t *node, co_nmt_command_t kind, void *user)
{
    co_api_t *api = user;
    if (kind == CO_NMT_CMD_RESET_NODE) {
        load_initial_image(api);
    }
    if (api->own_reset) {          /* InitCANopen asked for it: the host knows */
        api->own_reset = false;
    } else {
        tell_nmt(api, kind == CO_NMT_CMD_RESET_NODE ? CO_API_NMT_RESET_NODE
                                                    : CO_API_NMT_RESET_COMMUNICATION);
    }
    if (app_ind(api) && app_ind(api)->reset) {
        app_ind(api)->reset(node, kind, api->config.node.user);
    }
}

/* An RPDO landed: one ReceivedData per run of consecutive image bytes it
 * wrote (seed 004 §4.2.2), from its compiled mapping. */
static void on_pdo_received(co_node_t *node, uint16_t number, void *user)
{
    co_api_t *api = user;
    co_od_t *od = api->config.node.od;
    const co_pdo_channel_t *ch = co_pdo_channel(co_stack_pdo(api->stack), true, number);
    uint32_t start = 0, length = 0;
    for (uint8_t i = 0; ch != NULL && i < ch->map_count; i++) {
        const co_pdo_map_item_t *it = &ch->map[i];
        uint32_t bytes = ((uint32_t)it->bits + 7u) / 8u;
        bool in_image = it->value < co_od_image_size(od) && (it->flags & CO_PDO_ITEM_DUMMY) == 0;
        if (in_image && length > 0 && start + length == it->value) {
            length += bytes;
            continue;
        }
        tell_received(api, start, length);
        start = it->value;
        length = in_image ? bytes : 0;
    }
    tell_received(api, start, length);
    if (app_ind(api) && app_ind(api)->pdo_received) {
        app_ind(api)->pdo_received(node, number, api->config.node.user);
    }
}

static void on_before_send(co_node_t *node, uint16_t number, void *user)
{
    co_api_t *api = user;
    if (app_ind(api) && app_ind(api)->pdo_before_send) {
        app_ind(api)->pdo_before_send(node, number, api->config.node.user);
    }
}

/* SDO/USDO downloads into image entries. */
static void on_written(co_od_t *od, const co_od_entry_t *e, co_od_origin_t origin, void *user)
{
    if (origin == CO_ORIGIN_NETWORK && co_od_in_image(od, e)) {
        tell_received(user, e->value, e->size);
    }
}

static const co_od_handler_t image_observer = {.after_write = on_written};

/* ---------------------------------------------------------------- life */

bool co_api_init(co_api_t *api, co_stack_t *stack, const co_api_config_t *config)
{
    memset(api, 0, sizeof *api);
    co_od_t *od = config ? config->node.od : NULL;
    if (stack == NULL || od == NULL || !od->sealed || co_stack_has_node(stack) ||
        co_od_image_size(od) > CO_API_IMAGE_MAX || config->default_bps < 1 ||
        config->default_bps > 8 || config->node.node_id < 1 || config->node.node_id > 127) {
        return false;
    }
    if (!co_od_subscribe(od, 0x0000, 0x00, 0xFFFF, 0xFF, &image_observer, api)) {
        return false;
    }
    api->stack = stack;
    api->config = *config;
    api->bps = config->default_bps;
    api->node_ind = (co_node_indications_t){
        .state_changed = on_state, .allow_operational = on_allow_operational,
        .reset = on_reset, .pdo_received = on_pdo_received, .pdo_before_send = on_before_send};
    load_initial_image(api);
    return true;
}

void co_api_deinit(co_api_t *api)
{
    if (api->config.node.od != NULL) {
        co_od_unsubscribe(api->config.node.od, &image_observer, api);
    }
    memset(api, 0, sizeof *api);
}

/* ---------------------------------------------------------------- requests */

void co_api_get_id(const co_api_t *api, uint8_t id[4])
{
    memcpy(id, api->config.id, 4);
}

uint8_t co_api_get_status(const co_api_t *api)
{
    uint32_t size = api->config.node.od ? co_od_image_size(api->config.node.od) : 0;
    uint32_t size_bits = 7u;   /* (value + 1) * 32, 111b = 255; else the class below */
    if (size < CO_API_IMAGE_MAX) {
        size_bits = size < 64u ? 0u : size / 32u - 1u;
        size_bits = size_bits > 6u ? 6u : size_bits;
    }
    uint8_t state = api->stack == NULL ? CO_API_STATE_INITIALISING
                    : api->started ? CO_API_STATE_OPERATING : CO_API_STATE_READY;
    return (uint8_t)(state | size_bits << 2);
}

uint8_t co_api_init_canopen(co_api_t *api, uint8_t bps, uint8_t node_id)
{
    if (api->stack == NULL || bps > 8 || node_id > 127) {
        return CO_API_FALSE;
    }
    bps = bps ? bps : api->config.default_bps;
    node_id = node_id ? node_id : api->config.node.node_id;
    co_node_t *node = co_stack_node(api->stack);
    if (api->config.cb && api->config.cb->set_bit_rate &&
        !api->config.cb->set_bit_rate(bps, api->config.user)) {
        return CO_API_FALSE;
    }
    api->bps = bps;
    if (api->started) {
        /* re-initialise: a reset node, with the new node-id (seed 004 §4.1.3) */
        if (node_id != node->nmt.node_id &&
            co_stack_set_node_id_at_reset(api->stack, node_id) != CO_STACK_OK) {
            return CO_API_FALSE;
        }
        api->own_reset = true;     /* the reset says 'initialising' itself */
        co_nmt_apply(&node->nmt, CO_NMT_CMD_RESET_NODE);
        return CO_API_TRUE;
    }
    co_stack_node_config_t config = api->config.node;
    config.node_id = node_id;
    config.ind = &api->node_ind;
    config.user = api;
    co_od_set_node_id(config.od, node_id);
    tell_nmt(api, CO_NMT_INITIALISING);
    if (co_stack_node_init(api->stack, &config) != CO_STACK_OK ||
        co_stack_boot(api->stack) != CO_STACK_OK) {
        co_stack_node_deinit(api->stack);
        return CO_API_FALSE;
    }
    api->started = true;
    return CO_API_TRUE;
}

/* Bytes offset.. of a `length` request that lie in the image. */
static uint32_t image_span(const co_api_t *api, uint8_t offset, uint8_t length)
{
    uint32_t size = co_od_image_size(api->config.node.od);
    return offset >= size ? 0u : (length < size - offset ? length : size - offset);
}

uint8_t co_api_read(co_api_t *api, uint8_t offset, uint8_t length, uint8_t *data)
{
    uint32_t n = api->stack != NULL ? image_span(api, offset, length) : 0u;
    if (n == 0) {
        api->refused_reads++;
        return 0;
    }
    memcpy(data, co_od_image(api->config.node.od) + offset, n);
    return (uint8_t)n;
}

/* True when any byte of [from, from + n) is marked in `changed`. */
static bool any_changed(const uint8_t *changed, uint32_t from, uint32_t n)
{
    for (uint32_t b = from; b < from + n && b < CO_API_IMAGE_MAX; b++) {
        if (changed[b / 8u] & (1u << (b % 8u))) {
            return true;
        }
    }
    return false;
}

/* Each TPDO mapping a changed byte is triggered once, after the whole write
 * (so it never carries half of it: seed 004 §3.3, consistency). */
static void trigger_tpdos(co_api_t *api, const uint8_t *changed)
{
    co_pdo_t *pdo = api->started ? co_stack_pdo(api->stack) : NULL;
    uint32_t size = co_od_image_size(api->config.node.od);
    for (uint16_t n = 1; pdo != NULL && n <= CO_PDO_MAX_NUMBER; n++) {   /* any numbering */
        const co_pdo_channel_t *ch = co_pdo_channel(pdo, false, n);
        for (uint8_t i = 0; ch != NULL && i < ch->map_count; i++) {
            const co_pdo_map_item_t *it = &ch->map[i];
            if (it->value < size && any_changed(changed, it->value, (it->bits + 7u) / 8u)) {
                (void)co_pdo_trigger(pdo, n);    /* false: not operational, not an event type */
                break;
            }
        }
    }
}

uint8_t co_api_write(co_api_t *api, uint8_t offset, uint8_t length, const uint8_t *data)
{
    uint32_t n = api->stack != NULL ? image_span(api, offset, length) : 0u;
    if (n == 0) {
        api->refused_writes++;
        return 0;
    }
    uint8_t *image = co_od_image(api->config.node.od);
    uint8_t changed[(CO_API_IMAGE_MAX + 7u) / 8u] = {0};
    for (uint32_t i = 0; i < n; i++) {
        if (image[offset + i] != data[i]) {
            changed[(offset + i) / 8u] |= (uint8_t)(1u << ((offset + i) % 8u));
        }
    }
    memcpy(image + offset, data, n);
    trigger_tpdos(api, changed);
    return (uint8_t)n;
}

void co_api_comm_event(co_api_t *api, co_comm_event_t event)
{
    uint8_t code = event == CO_COMM_BUS_OFF ? CO_API_FATAL_BUS_OFF
                   : event == CO_COMM_IFACE_DOWN ? CO_API_FATAL_INTERFACE_DOWN : 0u;
    if (code != 0 && api->config.cb && api->config.cb->fatal_error) {
        api->config.cb->fatal_error(code, api->config.user);
    }
}
