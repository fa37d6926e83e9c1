/* Runtime glue of bus redundancy: a line on two buses, A (its own) and B
 * (the redundant one), using the active one only, so only that bus carries
 * what it sends and gives it what it receives: an in-process line is
 * attached to that bus alone, a SocketCAN line has a socket on that
 * interface alone. The core's co_rdn decides; the stack's heartbeat
 * indication tells it about the redundancy master; every switch is posted
 * to the application. */
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

void rt_redundancy_on_heartbeat(rt_line_t *l, uint8_t node_id, co_hb_event_t event)
{
    co_rdn_t *rdn = &l->redundancy.rdn;
    if (!l->redundancy.on || rdn->config.role != CO_RDN_SLAVE || node_id != rdn->config.master_id) {
        return;
    }
    if (event == CO_HB_STARTED) {
        co_rdn_master_heard(rdn);
    } else if (event == CO_HB_LOST) {
        co_rdn_master_lost(rdn);
    }
}

void rt_redundancy_on_reset(rt_line_t *l)
{
    if (l->redundancy.on) {
        co_rdn_start(&l->redundancy.rdn);
    }
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
    if (l->redundancy.on) {
        rt_set_error(rt, "line %d (%s): bus redundancy runs on this line already", line,
                     l->channel);
        return CO_RT_ERR_STATE;
    }
    return CO_RT_OK;
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

int co_rt_redundancy_start(co_rt_t *rt, int line, const co_rt_redundancy_config_t *config)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l || !config) {
        return CO_RT_ERR_ARGUMENT;
    }
    co_rdn_config_t rc = {.role = config->master ? CO_RDN_MASTER : CO_RDN_SLAVE,
                          .master_id = config->master_id,
                          .master_period_ms = config->master_period_ms,
                          .bdefault = config->bdefault,
                          .ttoggle = config->ttoggle,
                          .ntoggle = config->ntoggle};
    rt_mutex_lock(&rt->lock);
    co_hb_consumer_t *consumer = co_stack_hb_consumer(&l->stack);
    int status = check_start(rt, line, l, config, &rc);
    if (status == CO_RT_OK && rc.role == CO_RDN_SLAVE &&
        co_hb_consumer_watch(consumer, rc.master_id, rc.master_period_ms) != CO_HB_CONFIG_OK) {
        rt_set_error(rt, "line %d: the heartbeat consumer cannot watch master %u", line,
                     (unsigned)rc.master_id);
        status = CO_RT_ERR_STATE;
    } else if (status == CO_RT_OK) {
        status = join_buses(rt, l, config->redundant);
        if (status != CO_RT_OK && rc.role == CO_RDN_SLAVE) {
            co_hb_consumer_unwatch(consumer, rc.master_id);
        }
    }
    if (status != CO_RT_OK) {
        rt_mutex_unlock(&rt->lock);
        return status;
    }
    co_line_set_time(&l->line, co_rt_now_us());
    co_rdn_init(&l->redundancy.rdn, &l->line, &rc, on_select, on_event, l);
    l->redundancy.on = true;
    co_rdn_start(&l->redundancy.rdn);
    return rt_kick_unlock(rt, CO_RT_OK);
}

static rt_line_t *redundant_line(co_rt_t *rt, int line)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (l && !l->redundancy.on) {
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
    co_rdn_result_t result = co_rdn_master_select(&l->redundancy.rdn, bus);
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
            object[sub] = co_rdn_read(&l->redundancy.rdn, sub);
        }
        active = co_rdn_active_bus(&l->redundancy.rdn);
    }
    rt_mutex_unlock(&rt->lock);
    return active;
}
