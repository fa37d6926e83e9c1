/* Runtime glue of bus redundancy: a line on two buses, A (its own) and B
 * (the redundant one), using the active one only, so only that bus carries
 * what it sends and gives it what it receives: an in-process line is
 * attached to that bus alone, a SocketCAN line has a socket on that
 * interface alone. The stack's redundancy part decides (the master's
 * heartbeat, resets, the record in the node's OD, the master's switch on
 * failure); every switch is posted to the application. */
#include "co_rt_internal.h"

#include <stdio.h>
#include <string.h>

static void on_select(co_rdn_t *rdn, uint8_t bus, void *user)
{
    rt_line_t *l = user;
    (void)rdn;
    if (l->driver == CO_DRIVER_SOCKETCAN) {
        if (strcmp(l->channel, l->redundancy.iface[bus]) != 0) {
            rt_socket_switch(l->rt, l, l->redundancy.iface[bus]);
        }
        return;
    }
    co_membus_detach(&l->redundancy.bus[CO_RDN_BUS_A]->bus, &l->line);
    co_membus_detach(&l->redundancy.bus[CO_RDN_BUS_B]->bus, &l->line);
    /* Start checked the room, but lines opened since may have filled the
     * bus: then the line is on no bus, and says so like a lost interface. */
    if (!co_membus_attach(&l->redundancy.bus[bus]->bus, &l->line)) {
        co_line_comm_event(&l->line, CO_COMM_IFACE_DOWN);
    }
}

static void on_event(co_rdn_t *rdn, co_rdn_event_t event, uint8_t bus, void *user)
{
    rt_post(user, CO_EV_REDUNDANCY, bus, (uint32_t)event,
            co_rdn_read(rdn, CO_RDN_SUB_CTOGGLE), NULL);
}

/* The record in the local node's OD, when there is one, holds Bdefault,
 * Ttoggle and Ntoggle: values given to start as well would be ambiguous. */
static int check_record(co_rt_t *rt, int line, rt_line_t *l, const co_rt_redundancy_config_t *c,
                        uint16_t index)
{
    co_od_t *od = co_stack_od(&l->stack);
    uint8_t bad_sub = 0;
    co_rdn_result_t result = co_stack_redundancy_check_od(od, index, &bad_sub);
    if (result != CO_RDN_OK) {
        return rt_argument_error(rt, "line %d (%s): the redundancy record 0x%04X:%02X of the "
                                 "local node's OD: %s", line, l->channel, (unsigned)index,
                                 (unsigned)bad_sub, co_rdn_result_text(result));
    }
    if (c->values_given && od && co_od_has_index(od, index)) {
        return rt_argument_error(rt, "line %d (%s): the local node's OD has the redundancy "
                                 "record 0x%04X: Bdefault, Ttoggle and Ntoggle come from it "
                                 "(write them there), not from start", line, l->channel,
                                 (unsigned)index);
    }
    return CO_RT_OK;
}

static int check_start(co_rt_t *rt, int line, rt_line_t *l, const co_rt_redundancy_config_t *c,
                       const co_rdn_config_t *rc)
{
    co_rdn_result_t result = co_rdn_check_config(rc);
    if (l->driver != CO_DRIVER_MEMBUS && l->driver != CO_DRIVER_SOCKETCAN) {
        rt_set_error(rt, "line %d (%s): bus redundancy runs on in-process and SocketCAN "
                     "lines only", line, l->channel);
        return CO_RT_ERR_STATE;
    }
    if (!c->redundant || c->redundant[0] == '\0' || strcmp(c->redundant, l->channel) == 0) {
        return rt_argument_error(rt, "line %d (%s): the redundant bus must be another %s, "
                                 "got %s", line, l->channel,
                                 l->driver == CO_DRIVER_MEMBUS ? "in-process bus" : "interface",
                                 c->redundant && c->redundant[0] ? c->redundant : "none");
    }
    if (strlen(c->redundant) >= RT_CHANNEL_SIZE) {
        return rt_argument_error(rt, "line %d: redundant bus name longer than %d characters",
                                 line, RT_CHANNEL_SIZE - 1);
    }
    if (result != CO_RDN_OK) {
        return rt_argument_error(rt, "line %d (%s): redundancy: %s", line, l->channel,
                                 co_rdn_result_text(result));
    }
    if (co_stack_redundancy(&l->stack)) {
        rt_set_error(rt, "line %d (%s): bus redundancy runs on this line already", line,
                     l->channel);
        return CO_RT_ERR_STATE;
    }
    if (c->switch_on_failure && !c->master) {
        return rt_argument_error(rt, "line %d (%s): only the redundancy master switches on "
                                 "a bus failure", line, l->channel);
    }
    return check_record(rt, line, l, c, c->index ? c->index : (uint16_t)CO_RDN_OBJECT_DEFAULT);
}

/* Under rt->lock: both buses found or made, the line placed on B once to
 * learn there is room (then taken off again by the first selection); for
 * SocketCAN, B must open now, so a wrong name is told at once. */
static int join_buses(co_rt_t *rt, rt_line_t *l, const char *redundant)
{
    co_mode_t mode = co_line_mode(&l->line);
    snprintf(l->redundancy.iface[CO_RDN_BUS_A], RT_CHANNEL_SIZE, "%s", l->channel);
    snprintf(l->redundancy.iface[CO_RDN_BUS_B], RT_CHANNEL_SIZE, "%s", redundant);
    if (l->driver == CO_DRIVER_SOCKETCAN) {
        return rt_socket_probe(rt, redundant, mode);
    }
    int status = rt_membus_bus(rt, l->channel, mode, &l->redundancy.bus[CO_RDN_BUS_A]);
    if (status == CO_RT_OK) {
        status = rt_membus_bus(rt, redundant, mode, &l->redundancy.bus[CO_RDN_BUS_B]);
    }
    if (status == CO_RT_OK && !co_membus_attach(&l->redundancy.bus[CO_RDN_BUS_B]->bus, &l->line)) {
        rt_set_error(rt, "membus %s: already %d lines", redundant, CO_MEMBUS_MAX_LINES);
        status = CO_RT_ERR_FULL;
    }
    return status;
}

/* Undo join_buses' placing of an in-process line on B. */
static void leave_redundant_bus(rt_line_t *l)
{
    if (l->driver == CO_DRIVER_MEMBUS) {
        co_membus_detach(&l->redundancy.bus[CO_RDN_BUS_B]->bus, &l->line);
    }
}

int co_rt_redundancy_start(co_rt_t *rt, int line, const co_rt_redundancy_config_t *config)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l || !config) {
        return CO_RT_ERR_ARGUMENT;
    }
    co_stack_redundancy_config_t sc = {
        .rdn = {.role = config->master ? CO_RDN_MASTER : CO_RDN_SLAVE,
                .master_id = config->master_id,
                .master_period_ms = config->master_period_ms,
                .bdefault = config->bdefault,
                .ttoggle = config->ttoggle,
                .ntoggle = config->ntoggle},
        .index = config->index,
        .switch_on_failure = config->switch_on_failure != 0,
        .select = on_select,
        .on_event = on_event,
        .user = l};
    rt_mutex_lock(&rt->lock);
    int status = check_start(rt, line, l, config, &sc.rdn);
    if (status == CO_RT_OK) {
        status = join_buses(rt, l, config->redundant);
    }
    if (status == CO_RT_OK) {
        co_line_set_time(&l->line, co_rt_now_us());
        if (co_stack_redundancy_init(&l->stack, &sc) != CO_STACK_OK) {
            /* the checks passed: a table of the line or its OD is full */
            rt_set_error(rt, "line %d (%s): redundancy: the heartbeat consumer cannot watch "
                         "master %u, or the OD cannot take another handler", line, l->channel,
                         (unsigned)config->master_id);
            leave_redundant_bus(l);
            status = CO_RT_ERR_STATE;
        }
    }
    if (status != CO_RT_OK) {
        rt_mutex_unlock(&rt->lock);
        return status;
    }
    return rt_kick_unlock(rt, CO_RT_OK);
}

static rt_line_t *redundant_line(co_rt_t *rt, int line)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (l && !co_stack_redundancy(&l->stack)) {
        rt_set_error(rt, "line %d (%s): bus redundancy is not started on this line", line,
                     l->channel);
        return NULL;
    }
    return l;
}

int co_rt_redundancy_select(co_rt_t *rt, int line, uint8_t bus)
{
    rt_mutex_lock(&rt->lock);
    rt_line_t *l = redundant_line(rt, line);
    if (!l) {
        rt_mutex_unlock(&rt->lock);
        return CO_RT_ERR_STATE;
    }
    co_rdn_result_t result = co_rdn_master_select(co_stack_redundancy(&l->stack), bus);
    if (result != CO_RDN_OK) {
        rt_set_error(rt, "line %d (%s): select bus %u: %s", line, l->channel, (unsigned)bus,
                     co_rdn_result_text(result));
        return rt_kick_unlock(rt, result == CO_RDN_BAD_BUS ? CO_RT_ERR_ARGUMENT : CO_RT_ERR_STATE);
    }
    return rt_kick_unlock(rt, CO_RT_OK);
}

int co_rt_redundancy_state(co_rt_t *rt, int line, uint8_t *object)
{
    rt_mutex_lock(&rt->lock);
    rt_line_t *l = redundant_line(rt, line);
    int active = CO_RT_ERR_STATE;
    if (l) {
        for (uint8_t sub = CO_RDN_SUB_COUNT; object && sub <= CO_RDN_SUB_CTOGGLE; sub++) {
            object[sub] = co_rdn_read(co_stack_redundancy(&l->stack), sub);
        }
        active = co_rdn_active_bus(co_stack_redundancy(&l->stack));
    }
    rt_mutex_unlock(&rt->lock);
    return active;
}
