/* co_stack's bus redundancy part: the service (co_redundancy) wired to the
 * line's heartbeat consumer, comm events and node resets, and its object
 * served from the local node's OD when the OD has the record. */
#include "co_stack_rdn.h"

#include <stddef.h>

static uint8_t other_bus(uint8_t bus) { return bus == CO_RDN_BUS_A ? CO_RDN_BUS_B : CO_RDN_BUS_A; }

static co_od_entry_t *record_entry(co_stack_t *s, uint8_t sub)
{
    return (co_od_entry_t *)co_od_find(s->rdn_od, s->rdn_index, sub);
}

/* The OD shows what the service holds: the service changes Ctoggle and
 * Bdefault itself, and a refused value must not stay visible. Written in
 * place, so no after-write handler runs. */
static void show_sub(co_stack_t *s, uint8_t sub)
{
    co_od_entry_t *e = s->rdn_od ? record_entry(s, sub) : NULL;
    if (e) {
        *co_od_value(s->rdn_od, e) = co_rdn_read(&s->rdn, sub);
    }
}

static void show_in_od(co_stack_t *s)
{
    for (uint8_t sub = CO_RDN_SUB_BDEFAULT; s->has_rdn && sub <= CO_RDN_SUB_CTOGGLE; sub++) {
        show_sub(s, sub);
    }
}

static void on_select(co_rdn_t *rdn, uint8_t bus, void *user)
{
    co_stack_t *s = user;
    s->rdn_selecting = true;
    s->rdn_select(rdn, bus, s->rdn_user);
    s->rdn_selecting = false;
    show_in_od(s);   /* a start (boot, reset) zeroes Ctoggle before it selects */
}

static void on_event(co_rdn_t *rdn, co_rdn_event_t event, uint8_t bus, void *user)
{
    co_stack_t *s = user;
    show_in_od(s);
    if (s->rdn_event) {
        s->rdn_event(rdn, event, bus, s->rdn_user);
    }
}

/* ---------------------------------------------------------------- the OD record */

static uint32_t abort_of(co_rdn_result_t result)
{
    switch (result) {
    case CO_RDN_OK: return CO_ABORT_NONE;
    case CO_RDN_BAD_BUS: return CO_ABORT_VALUE_HIGH;
    case CO_RDN_BAD_NTOGGLE: return CO_ABORT_VALUE_LOW;
    case CO_RDN_READ_ONLY: return CO_ABORT_READ_ONLY;
    case CO_RDN_BAD_TYPE: return CO_ABORT_TYPE_MISMATCH;
    case CO_RDN_NO_SUB:
    case CO_RDN_MISSING_SUB: return CO_ABORT_NO_SUB;
    default: return CO_ABORT_PARAM_INCOMPATIBLE;   /* Ttoggle on a slave without period */
    }
}

static uint32_t record_before_read(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e,
                                   void *user)
{
    (void)od;
    (void)xfer;
    (void)e;
    show_in_od(user);
    return CO_ABORT_NONE;
}

/* A network write: the service's own check, so the abort says what is wrong. */
static uint32_t record_check_write(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e,
                                   const uint8_t *value, uint32_t length, void *user)
{
    (void)od;
    (void)xfer;
    co_stack_t *s = user;
    uint8_t sub = co_od_entry_sub(e);
    if (length != 1) {
        return length > 1 ? CO_ABORT_LENGTH_HIGH : CO_ABORT_LENGTH_LOW;
    }
    if (sub == CO_RDN_SUB_CTOGGLE) {
        return CO_ABORT_READ_ONLY;
    }
    co_rdn_result_t result = co_rdn_check_sub(sub, CO_RDN_TYPE_UNSIGNED8, value[0]);
    if (result == CO_RDN_OK && sub == CO_RDN_SUB_TTOGGLE && value[0] != 0 &&
        s->rdn.config.role == CO_RDN_SLAVE && s->rdn.config.master_period_ms == 0) {
        result = CO_RDN_BAD_PERIOD;
    }
    return abort_of(result);
}

/* Any write that got through (network, application, reload at a reset):
 * the service takes it, or the OD shows the service's value again. Only
 * this sub: a reload tells each changed entry after loading them all. */
static void record_after_write(co_od_t *od, const co_od_entry_t *e, co_od_origin_t origin,
                               void *user)
{
    (void)origin;
    co_stack_t *s = user;
    uint8_t sub = co_od_entry_sub(e);
    uint8_t value = *co_od_value(od, e);
    if (sub != CO_RDN_SUB_CTOGGLE) {
        (void)co_rdn_write(&s->rdn, sub, value);
    }
    show_sub(s, sub);
}

static const co_od_handler_t record_handler = {
    .before_read = record_before_read,
    .check_write = record_check_write,
    .after_write = record_after_write,
};

co_rdn_result_t co_stack_redundancy_check_od(const co_od_t *od, uint16_t index,
                                             uint8_t *bad_sub)
{
    *bad_sub = 0;
    if (!od || !co_od_has_index(od, index)) {
        return CO_RDN_OK;
    }
    for (uint8_t sub = CO_RDN_SUB_BDEFAULT; sub <= CO_RDN_SUB_CTOGGLE; sub++) {
        const co_od_entry_t *e = co_od_find(od, index, sub);
        uint8_t value = 0;
        *bad_sub = sub;
        if (!e) {
            return CO_RDN_MISSING_SUB;
        }
        if (e->type != CO_TYPE_UNSIGNED8 || !co_od_get_u8(od, index, sub, &value)) {
            return CO_RDN_BAD_TYPE;
        }
        co_rdn_result_t result = co_rdn_check_sub(sub, e->type, value);
        if (result != CO_RDN_OK) {
            return result;
        }
    }
    *bad_sub = 0;
    return CO_RDN_OK;
}

/* The record's values replace config's (the OD is where a tool sets them). */
static void take_from_od(const co_od_t *od, uint16_t index, co_rdn_config_t *c)
{
    (void)co_od_get_u8(od, index, CO_RDN_SUB_BDEFAULT, &c->bdefault);
    (void)co_od_get_u8(od, index, CO_RDN_SUB_TTOGGLE, &c->ttoggle);
    (void)co_od_get_u8(od, index, CO_RDN_SUB_NTOGGLE, &c->ntoggle);
}

/* Serve the record of the node's OD at the service's index, when it has a
 * valid one (false: nothing served). */
static bool bind_record(co_stack_t *s, co_od_t *od)
{
    uint8_t bad_sub;
    if (!od || !co_od_has_index(od, s->rdn_index) ||
        co_stack_redundancy_check_od(od, s->rdn_index, &bad_sub) != CO_RDN_OK ||
        !co_od_subscribe(od, s->rdn_index, CO_RDN_SUB_BDEFAULT, s->rdn_index,
                         CO_RDN_SUB_CTOGGLE, &record_handler, s)) {
        return false;
    }
    s->rdn_od = od;
    return true;
}

/* ---------------------------------------------------------------- set-up */

static co_stack_status_t refuse(co_stack_t *s, co_stack_status_t status)
{
    s->failed = CO_STACK_PART_REDUNDANCY;
    return status;
}

co_stack_status_t co_stack_redundancy_init(co_stack_t *stack,
                                           const co_stack_redundancy_config_t *config)
{
    if (!stack || !stack->line || !config || !config->select ||
        (config->switch_on_failure && config->rdn.role != CO_RDN_MASTER)) {
        return CO_STACK_ERR_ARGUMENT;
    }
    co_stack_t *s = stack;
    s->failed = CO_STACK_PART_NONE;
    if (s->has_rdn) {
        return refuse(s, CO_STACK_ERR_STATE);
    }
    uint16_t index = config->index ? config->index : (uint16_t)CO_RDN_OBJECT_DEFAULT;
    co_od_t *od = co_stack_od(s);
    uint8_t bad_sub;
    if (co_stack_redundancy_check_od(od, index, &bad_sub) != CO_RDN_OK) {
        return refuse(s, CO_STACK_ERR_OD);
    }
    co_rdn_config_t c = config->rdn;
    bool served = od && co_od_has_index(od, index);
    if (served) {
        take_from_od(od, index, &c);
    }
    if (co_rdn_check_config(&c) != CO_RDN_OK) {
        return refuse(s, CO_STACK_ERR_ARGUMENT);
    }
    if (c.role == CO_RDN_SLAVE &&
        co_hb_consumer_watch(&s->hb_consumer, c.master_id, c.master_period_ms) != CO_HB_CONFIG_OK) {
        return refuse(s, CO_STACK_ERR_TAKEN);
    }
    s->rdn_index = index;
    s->rdn_od = NULL;
    if (served && !bind_record(s, od)) {
        if (c.role == CO_RDN_SLAVE) {
            co_hb_consumer_unwatch(&s->hb_consumer, c.master_id);
        }
        return refuse(s, CO_STACK_ERR_TAKEN);
    }
    s->rdn_switch_on_failure = config->switch_on_failure;
    s->rdn_select = config->select;
    s->rdn_event = config->on_event;
    s->rdn_user = config->user;
    (void)co_rdn_init(&s->rdn, s->line, &c, on_select, on_event, s);
    s->has_rdn = true;
    if (s->has_node) {
        co_node_attach_redundancy(&s->node, &s->rdn);
    }
    co_rdn_start(&s->rdn);
    show_in_od(s);
    return CO_STACK_OK;
}

void co_stack_redundancy_deinit(co_stack_t *stack)
{
    if (!stack || !stack->has_rdn) {
        return;
    }
    co_stack_rdn_node_gone(stack);
    if (stack->rdn.config.role == CO_RDN_SLAVE) {
        co_hb_consumer_unwatch(&stack->hb_consumer, stack->rdn.config.master_id);
    }
    co_rdn_deinit(&stack->rdn);
    stack->has_rdn = false;
}

uint16_t co_stack_redundancy_record_index(const co_stack_t *stack)
{
    return stack && stack->has_rdn ? stack->rdn_index : 0;
}

/* ---------------------------------------------------------------- what co_stack.c tells */

void co_stack_rdn_heartbeat(co_stack_t *s, uint8_t node_id, co_hb_event_t event)
{
    if (!s->has_rdn || s->rdn.config.role != CO_RDN_SLAVE || node_id != s->rdn.config.master_id) {
        return;
    }
    if (event == CO_HB_STARTED) {
        co_rdn_master_heard(&s->rdn);
        show_in_od(s);   /* Ctoggle 0 */
    } else if (event == CO_HB_LOST) {
        co_rdn_master_lost(&s->rdn);
    }
}

void co_stack_rdn_comm(co_stack_t *s, co_comm_event_t event)
{
    /* A failed selection (the other bus could not take the line) reports
     * itself as interface down: not a reason to move again at once. */
    if (!s->has_rdn || !s->rdn_switch_on_failure || s->rdn_selecting ||
        (event != CO_COMM_BUS_OFF && event != CO_COMM_IFACE_DOWN)) {
        return;
    }
    (void)co_rdn_master_select(&s->rdn, other_bus(co_rdn_active_bus(&s->rdn)));
}

void co_stack_rdn_node_added(co_stack_t *s)
{
    if (!s->has_rdn) {
        return;
    }
    co_node_attach_redundancy(&s->node, &s->rdn);
    if (bind_record(s, s->od)) {
        for (uint8_t sub = CO_RDN_SUB_BDEFAULT; sub <= CO_RDN_SUB_NTOGGLE; sub++) {
            uint8_t value = 0;
            (void)co_od_get_u8(s->od, s->rdn_index, sub, &value);
            (void)co_rdn_write(&s->rdn, sub, value);   /* one refused keeps the running value */
        }
        show_in_od(s);
    }
}

void co_stack_rdn_node_gone(co_stack_t *s)
{
    if (!s->has_rdn) {
        return;
    }
    if (s->has_node) {
        co_node_attach_redundancy(&s->node, NULL);
    }
    if (s->rdn_od) {
        co_od_unsubscribe(s->rdn_od, &record_handler, s);
        s->rdn_od = NULL;
    }
}

void co_stack_rdn_boot(co_stack_t *s)
{
    if (s->has_rdn) {
        co_rdn_start(&s->rdn);
        show_in_od(s);
    }
}
