#include "canopenfd/co_node.h"

#include "co_bits.h"
#include "co_cob_id.h"

#include <string.h>

/* Every service hears the NMT state (PDOs flow only in operational, SDO/USDO
 * are served only in pre-operational and operational). */
static void services_set_state(co_node_t *node, co_nmt_state_t state)
{
    const co_node_services_t *s = &node->services;
    if (s->pdo) {
        co_pdo_set_operational(s->pdo, state == CO_NMT_OPERATIONAL);
    }
    if (s->emcy) {
        co_emcy_set_nmt_state(s->emcy, state);
    }
    if (s->sync) {
        co_sync_set_nmt_state(s->sync, state);
    }
    if (s->time) {
        co_time_set_nmt_state(s->time, state);
    }
    if (s->server && s->server_state) {
        s->server_state(s->server, state);
    }
    if (s->led) {
        co_led_set_nmt_state(s->led, state);
    }
    if (s->srdo_od) {
        co_srdo_od_set_nmt_state(s->srdo_od, state);   /* reconfigures before they start */
    }
    for (uint8_t i = 0; i < s->srdo_count; i++) {
        co_srdo_set_nmt_state(&s->srdo[i], state);
    }
}

static void on_state_changed(co_nmt_t *nmt, co_nmt_state_t old_state,
                             co_nmt_state_t new_state, void *user)
{
    (void)nmt;
    co_node_t *node = user;
    services_set_state(node, new_state);
    if (node->part_ind && node->part_ind->state_changed) {
        node->part_ind->state_changed(node, old_state, new_state, node->part_user);
    }
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

/* Boot and resets: defaults, then saved values, of the groups concerned
 * (with a store: the groups whose reset type says so). */
static void load_parameters(co_node_t *node, bool reset_node)
{
    if (!node->od) {
        co_hb_producer_set_time(&node->heartbeat, node->heartbeat_default_ms);
        return;
    }
    if (node->store) {
        node->store_status = co_store_load_at_reset(node->store, reset_node);
    } else {
        co_od_load_defaults(node->od, reset_node ? CO_GROUP_ALL : CO_GROUP_COMMUNICATION);
    }
    apply_od_parameters(node);
}

/* ------------------------------------------------------------ errors */

/* The error states the node tracks to clear its own EMCYs (not the EMCYs). */
static void forget_detected_errors(co_node_t *node)
{
    memset(node->rpdo_short, 0, sizeof node->rpdo_short);
    memset(node->rpdo_long, 0, sizeof node->rpdo_long);
    memset(node->rpdo_late, 0, sizeof node->rpdo_late);
    memset(node->hb_lost, 0, sizeof node->hb_lost);
    node->life_lost = false;
    node->sync_length_error = false;
    node->sync_timeout = false;
}

static bool bits_any(const uint8_t *map, size_t size)
{
    for (size_t i = 0; i < size; i++) {
        if (map[i] != 0) {
            return true;
        }
    }
    return false;
}

/* The error LED shows the causes the node tracks (bus-off and warning come
 * straight from co_node_comm_event). */
static void led_show_errors(co_node_t *node)
{
    co_led_t *led = node->services.led;
    if (!led) {
        return;
    }
    uint8_t active = 0;
    if (node->life_lost || bits_any(node->hb_lost, sizeof node->hb_lost)) {
        active |= CO_LED_CAUSE_ERROR_CONTROL;
    }
    if (node->sync_length_error || node->sync_timeout) {
        active |= CO_LED_CAUSE_SYNC;
    }
    if (bits_any(node->rpdo_late, sizeof node->rpdo_late)) {
        active |= CO_LED_CAUSE_EVENT_TIMER;
    }
    co_led_set_causes(led, CO_LED_CAUSE_ERROR_CONTROL | CO_LED_CAUSE_SYNC |
                               CO_LED_CAUSE_EVENT_TIMER, active);
}

static void led_cause(co_node_t *node, uint8_t cause, bool active)
{
    if (node->services.led) {
        co_led_set_cause(node->services.led, cause, active);
    }
}

/* The stack's own errors use CiA 301's code table; info (a node-id, a PDO
 * number) goes to the first manufacturer-specific bytes. */
/* The error-status bit of a code the node raises follows it. */
static void note_bit(co_node_t *node, uint16_t code, bool active)
{
    int bit = co_errors_stack_bit(code);
    if (node->services.errors && bit >= 0) {
        co_errors_note(node->services.errors, (uint8_t)bit, active);
    }
}

static void raise_error(co_node_t *node, uint16_t code, uint16_t info)
{
    note_bit(node, code, true);
    if (node->services.emcy) {
        co_emcy_error_t err = {.code = code, .spec_number = 301};
        err.msef[0] = (uint8_t)info;
        err.msef[1] = (uint8_t)(info >> 8);
        (void)co_emcy_raise(node->services.emcy, &err);
    }
}

static void clear_error(co_node_t *node, uint16_t code)
{
    note_bit(node, code, false);
    if (node->services.emcy) {
        co_emcy_error_t err = {.code = code, .spec_number = 301};
        (void)co_emcy_clear(node->services.emcy, &err);
    }
}

void co_node_error_behaviour(co_node_t *node, uint8_t error_class)
{
    uint8_t behaviour = 0;
    if (node->od) {
        (void)co_od_get_u8(node->od, CO_NODE_ERROR_BEHAVIOUR, error_class, &behaviour);
    }
    co_nmt_state_t state = node->nmt.state;
    if (behaviour == 0 && state == CO_NMT_OPERATIONAL) {
        co_nmt_apply(&node->nmt, CO_NMT_CMD_PRE_OPERATIONAL);
    } else if (behaviour == 2 && state != CO_NMT_STOPPED && state != CO_NMT_INITIALISING) {
        co_nmt_apply(&node->nmt, CO_NMT_CMD_STOP);
    }
}

/* 0x8130 stays active while any consumed node is lost or life guarding is. */
static void life_guard_changed(co_node_t *node)
{
    if (!node->life_lost && !bits_any(node->hb_lost, sizeof node->hb_lost)) {
        clear_error(node, CO_NODE_EMCY_LIFE_GUARD);
    }
}

void co_node_heartbeat_event(co_node_t *node, uint8_t node_id, bool lost)
{
    if (node_id == 0 || node_id > 127 || co_bit_test(node->hb_lost, node_id) == lost) {
        return;
    }
    co_bit_put(node->hb_lost, node_id, lost);
    if (lost) {
        raise_error(node, CO_NODE_EMCY_LIFE_GUARD, node_id);
        co_node_error_behaviour(node, 1);
    } else {
        life_guard_changed(node);
    }
    led_show_errors(node);
}

void co_node_guard_life(co_guard_slave_t *slave, co_guard_life_event_t event, void *user)
{
    (void)slave;
    co_node_t *node = user;
    if (event == CO_GUARD_LIFE_LOST && !node->life_lost) {
        node->life_lost = true;
        raise_error(node, CO_NODE_EMCY_LIFE_GUARD, node->nmt.node_id);
        co_node_error_behaviour(node, 1);
    } else if (event == CO_GUARD_LIFE_RESOLVED && node->life_lost) {
        node->life_lost = false;
        life_guard_changed(node);
    }
    led_show_errors(node);
}

void co_node_comm_event(co_node_t *node, co_comm_event_t event)
{
    switch (event) {
    case CO_COMM_BUS_OFF:
        led_cause(node, CO_LED_CAUSE_BUS_OFF, true);
        raise_error(node, CO_NODE_EMCY_BUS_OFF, 0);   /* goes out after recovery */
        co_node_error_behaviour(node, 1);
        break;
    case CO_COMM_BUS_OFF_RECOVERED:
        /* a controller back from bus-off starts with its error counters at 0 */
        led_cause(node, CO_LED_CAUSE_BUS_OFF | CO_LED_CAUSE_WARNING, false);
        clear_error(node, CO_NODE_EMCY_BUS_OFF);
        break;
    case CO_COMM_ERROR_WARNING:
        led_cause(node, CO_LED_CAUSE_WARNING, true);
        break;
    case CO_COMM_ERROR_PASSIVE:
        led_cause(node, CO_LED_CAUSE_WARNING, true);
        raise_error(node, CO_NODE_EMCY_ERROR_PASSIVE, 0);
        break;
    case CO_COMM_ERROR_ACTIVE:
        led_cause(node, CO_LED_CAUSE_BUS_OFF | CO_LED_CAUSE_WARNING, false);
        clear_error(node, CO_NODE_EMCY_ERROR_PASSIVE);
        clear_error(node, CO_NODE_EMCY_BUS_OFF);
        break;
    case CO_COMM_RX_OVERFLOW:
        /* received frames were lost: an EMCY and its reset (the loss is
         * over), at most one pair per CO_NODE_OVERRUN_QUIET_US so a lasting
         * overload does not add an EMCY flood; tx overflow gets none: the
         * EMCY could not be sent either */
        if (!node->overrun_told ||
            co_line_now(node->line) - node->overrun_told_us >= CO_NODE_OVERRUN_QUIET_US) {
            node->overrun_told = true;
            node->overrun_told_us = co_line_now(node->line);
            raise_error(node, CO_NODE_EMCY_CAN_OVERRUN, 0);
            clear_error(node, CO_NODE_EMCY_CAN_OVERRUN);
        }
        break;
    default:
        break;
    }
}

/* ------------------------------------------------------------ services */

static void on_sync(uint8_t counter, void *user)
{
    co_node_t *node = user;
    if (node->sync_length_error) {
        node->sync_length_error = false;   /* a SYNC of the right length came */
        clear_error(node, CO_SYNC_EMCY_LENGTH);
        led_show_errors(node);
    }
    if (node->services.pdo) {
        co_pdo_sync(node->services.pdo, counter);
    }
}

static void on_sync_window(co_sync_t *sync, void *user)
{
    (void)sync;
    co_node_t *node = user;
    if (node->services.pdo) {
        co_pdo_sync_window_closed(node->services.pdo);
    }
}

static void on_sync_error(co_sync_t *sync, uint16_t code, uint8_t length, void *user)
{
    (void)sync;
    co_node_t *node = user;
    if (!node->sync_length_error) {
        node->sync_length_error = true;
        raise_error(node, code, length);
        led_show_errors(node);
    }
}

/* SYNC consumer monitoring: shown on the error LED only (no EMCY). */
static void on_sync_timeout(co_sync_t *sync, bool timed_out, void *user)
{
    (void)sync;
    co_node_t *node = user;
    node->sync_timeout = timed_out;
    led_show_errors(node);
}

/* The node's record of which RPDOs are in error `code`. */
static uint8_t *rpdo_error_map(co_node_t *node, uint16_t code)
{
    switch (code) {
    case CO_PDO_EMCY_LENGTH:
        return node->rpdo_short;
    case CO_PDO_EMCY_LENGTH_EXCEEDED:
        return node->rpdo_long;
    case CO_PDO_EMCY_RPDO_TIMEOUT:
        return node->rpdo_late;
    default:
        return NULL;
    }
}

/* An RPDO's error raises its code; the code is cleared once no RPDO has it
 * (co_pdo tells every end: a good frame, the RPDO disabled, re-mapped or
 * reloaded). */
static void on_rpdo_error_changed(co_pdo_t *pdo, uint16_t number, uint16_t code, bool active,
                                  co_pdo_rx_cause_t cause, void *user)
{
    (void)pdo;
    (void)cause;
    co_node_t *node = user;
    uint8_t *map = rpdo_error_map(node, code);
    if (map == NULL || number == 0 || number > CO_PDO_MAX_NUMBER) {
        return;
    }
    uint16_t bit = (uint16_t)(number - 1u);
    if (co_bit_test(map, bit) == active) {
        return;
    }
    co_bit_put(map, bit, active);
    if (active) {
        raise_error(node, code, number);   /* classic: once per code; FD: per RPDO */
    } else if (!bits_any(map, CO_NODE_PDO_BITMAP)) {
        clear_error(node, code);
    }
    led_show_errors(node);
}

static void on_pdo_received(co_pdo_t *pdo, uint16_t number, void *user)
{
    (void)pdo;
    co_node_t *node = user;
    if (node->part_ind && node->part_ind->pdo_received) {
        node->part_ind->pdo_received(node, number, node->part_user);
    }
    if (node->ind && node->ind->pdo_received) {
        node->ind->pdo_received(node, number, node->user);
    }
}

static void on_pdo_before_send(co_pdo_t *pdo, uint16_t number, void *user)
{
    (void)pdo;
    co_node_t *node = user;
    if (node->ind && node->ind->pdo_before_send) {
        node->ind->pdo_before_send(node, number, node->user);
    }
}

const co_pdo_indications_t co_node_pdo_indications = {
    .received = on_pdo_received,
    .before_send = on_pdo_before_send,
    .rx_error_changed = on_rpdo_error_changed,
};

/* A refused DAM MPDO is an event, not a condition: EMCY 0x8230 (the RPDO
 * number in the manufacturer bytes), then its error reset. */
static void on_mpdo_error(co_mpdo_t *mpdo, uint16_t code, uint16_t rpdo_number, void *user)
{
    (void)mpdo;
    co_node_t *node = user;
    raise_error(node, code, rpdo_number);
    clear_error(node, code);
}

static void tell_mpdo(co_mpdo_t *mpdo, uint16_t rpdo_number, const co_mpdo_msg_t *msg,
                      uint16_t index, uint8_t sub, uint32_t abort, void *user)
{
    (void)mpdo;
    co_node_t *node = user;
    if (node->ind && node->ind->mpdo_received) {
        node->ind->mpdo_received(node, rpdo_number, msg, index, sub, abort, node->user);
    }
}

static void on_mpdo_received(co_mpdo_t *mpdo, uint16_t rpdo_number, const co_mpdo_msg_t *msg,
                             uint16_t index, uint8_t sub, void *user)
{
    tell_mpdo(mpdo, rpdo_number, msg, index, sub, 0, user);
}

const co_mpdo_indications_t co_node_mpdo_indications = {
    .received = on_mpdo_received,
    .refused = tell_mpdo,
    .error = on_mpdo_error,
};

static void on_comm_bit(co_errors_t *errors, void *user)
{
    (void)errors;
    co_node_error_behaviour(user, 1);   /* 0x1029:01: communication error */
}

void co_node_attach_services(co_node_t *node, const co_node_services_t *services)
{
    co_flyma_t *flyma = node->services.flyma;   /* attached on its own */
    co_rdn_t *rdn = node->services.rdn;         /* so is this */
    node->services = *services;
    if (!services->flyma) {
        node->services.flyma = flyma;
    }
    if (!services->rdn) {
        node->services.rdn = rdn;
    }
    if (services->errors) {
        co_errors_set_comm_indication(services->errors, on_comm_bit, node);
    }
    if (services->sync) {
        (void)co_sync_add_listener(services->sync, on_sync, node);
        co_sync_set_window_indication(services->sync, on_sync_window, node);
        co_sync_set_error_indication(services->sync, on_sync_error, node);
        if (services->led) {
            /* only the LED shows it: no monitoring timer without one */
            co_sync_set_timeout_indication(services->sync, on_sync_timeout, node);
        }
    }
    services_set_state(node, node->nmt.state);
}

void co_node_set_part_indications(co_node_t *node, const co_node_indications_t *ind,
                                  void *user)
{
    node->part_ind = ind;
    node->part_user = ind ? user : NULL;
}

void co_node_attach_flyma(co_node_t *node, co_flyma_t *flyma)
{
    node->services.flyma = flyma;
}

void co_node_attach_redundancy(co_node_t *node, co_rdn_t *rdn)
{
    node->services.rdn = rdn;
}

void co_node_attach_srdo(co_node_t *node, co_srdo_t *srdo, uint8_t count,
                         co_srdo_od_t *srdo_od)
{
    node->services.srdo = srdo;
    node->services.srdo_od = srdo ? srdo_od : NULL;
    node->services.srdo_count = srdo ? count : 0;
    for (uint8_t i = 0; i < node->services.srdo_count; i++) {
        co_srdo_set_nmt_state(&srdo[i], node->nmt.state);
    }
}

/* Resets reload what the OD now says; the errors the node detected start
 * over (the watched nodes, the PDOs and guarding start over too, a flying
 * master negotiates again). */
static void services_reset(co_node_t *node)
{
    const co_node_services_t *s = &node->services;
    if (s->flyma) {
        co_flyma_boot(s->flyma);
    }
    if (s->rdn) {
        co_rdn_start(s->rdn);   /* after the reload: the OD's Bdefault */
    }
    if (s->pdo) {
        co_pdo_reload(s->pdo);
    }
    if (s->guard) {
        co_guard_slave_reset_communication(s->guard);
    }
    static const uint16_t own[] = {CO_NODE_EMCY_LIFE_GUARD, CO_SYNC_EMCY_LENGTH,
                                   CO_PDO_EMCY_LENGTH, CO_PDO_EMCY_LENGTH_EXCEEDED,
                                   CO_PDO_EMCY_RPDO_TIMEOUT};
    for (size_t i = 0; i < sizeof own / sizeof own[0]; i++) {
        clear_error(node, own[i]);
    }
    forget_detected_errors(node);
    led_show_errors(node);
}

bool co_node_set_node_id(co_node_t *node, uint8_t node_id)
{
    if (node_id < 1u || node_id > 127u) {
        return false;
    }
    node->nmt.node_id = node_id;            /* NMT commands, boot-up, heartbeat, guarding */
    co_line_set_node_id(node->line, node_id);   /* SDO/USDO servers, flying master */
    if (node->od) {
        co_od_set_node_id(node->od, node_id);   /* $NODEID defaults at the next load */
    }
    if (node->services.emcy) {
        co_emcy_set_node_id(node->services.emcy, node_id);
    }
    return true;
}

void co_node_set_reset_node_id(co_node_t *node, co_node_reset_id_fn fn, void *user)
{
    node->reset_node_id = fn;
    node->reset_node_id_user = user;
}

static void on_reset(co_nmt_t *nmt, co_nmt_command_t kind, void *user)
{
    (void)nmt;
    co_node_t *node = user;
    /* A new node-id first (LSS: the pending one becomes active at reset
     * communication), so the reloaded $NODEID defaults and the boot-up use it. */
    if (node->reset_node_id) {
        uint8_t id = node->reset_node_id(node, kind, node->reset_node_id_user);
        if (id != node->nmt.node_id) {
            (void)co_node_set_node_id(node, id);
        }
    }
    /* Reset communication reloads the communication parameters, reset node
     * all of them. The boot-up message follows right after this, the first
     * heartbeat one period later. */
    load_parameters(node, kind != CO_NMT_CMD_RESET_COMMUNICATION);
    services_reset(node);
    if (node->part_ind && node->part_ind->reset) {
        node->part_ind->reset(node, kind, node->part_user);
    }
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
    node->part_ind = NULL;
    node->part_user = NULL;
    node->heartbeat_default_ms = heartbeat_ms;
    node->od = NULL;
    node->store = NULL;
    node->consumer = NULL;
    node->store_status = CO_STORE_EMPTY;
    memset(&node->services, 0, sizeof node->services);
    forget_detected_errors(node);
    node->overrun_told = false;
    node->overrun_told_us = 0;
    node->reset_node_id = NULL;
    node->reset_node_id_user = NULL;
    if (!co_nmt_init(&node->nmt, line, node_id, &nmt_indications, node)) {
        return false;
    }
    co_hb_producer_init(&node->heartbeat, line, &node->nmt);
    node->heartbeat.time_ms = heartbeat_ms;
    co_line_set_node_id(line, node_id);
    return true;
}

void co_node_deinit(co_node_t *node)
{
    if (node->services.sync) {
        co_sync_remove_listener(node->services.sync, on_sync, node);
        co_sync_set_window_indication(node->services.sync, NULL, NULL);
        co_sync_set_error_indication(node->services.sync, NULL, NULL);
        co_sync_set_timeout_indication(node->services.sync, NULL, NULL);
    }
    if (node->services.errors) {
        co_errors_set_comm_indication(node->services.errors, NULL, NULL);
    }
    memset(&node->services, 0, sizeof node->services);
    if (node->od) {
        co_od_unsubscribe(node->od, &comm_handler, node);
        co_cob_id_detach(node->od);
        node->od = NULL;
    }
    co_hb_producer_stop(&node->heartbeat);
    co_nmt_deinit(&node->nmt);
    co_line_set_node_id(node->line, 0);
}

void co_node_boot(co_node_t *node)
{
    /* Power-on loads every parameter (without an OD: the producer time set
     * so far); the first heartbeat follows the boot-up one period later. */
    if (node->od) {
        load_parameters(node, true);
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
