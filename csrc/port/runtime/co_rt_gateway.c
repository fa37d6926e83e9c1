/* Runtime glue of the gateway between the lines of one runtime (co_gateway):
 * lines join with a network-id; the core then routes EMCYs and forwards
 * 0xB000..0xBFFF PDO objects between their local nodes inside the runtime
 * thread (no Python per frame). The ports are rebuilt whenever a joined
 * line's local node appears, since the core hooks the node's OD and PDOs.
 * A joined fd line gets its USDO client (the line's node-id as client) so
 * classic clients reach its nodes by SDO networking, through the runtime's
 * RT_GATEWAY_SDO_BUFFER bytes; a joined classic line its SDO client, so
 * the gateway can read uploads from its nodes ahead of the client. A
 * rebuild ends the open SDO networking connections and remote USDO requests
 * with aborts (co_gateway_end_connections). */
#include "co_rt_internal.h"

#include <string.h>

static rt_line_t *line_of_stack(co_rt_t *rt, const co_stack_t *stack)
{
    int count = rt_atomic_load_acquire(&rt->line_count);
    for (int i = 0; i < count; i++) {
        if (&rt->lines[i]->stack == stack) {
            return rt->lines[i];
        }
    }
    return NULL;
}

/* A classic line's SDO client receives 0x581..0x5FF: none of them taken
 * by someone else (or the client is there already). */
static bool sdo_client_possible(rt_line_t *l)
{
    if (l->client != NULL) {
        return true;
    }
    for (uint32_t id = 0x581; id <= 0x5FF; id++) {
        if (co_line_id_taken(&l->line, id)) {
            return false;
        }
    }
    return true;
}

/* Route loops and refusals go to Python on the first joined line. */
static void on_gateway_event(co_gateway_t *gw, co_gateway_event_t event, uint8_t net,
                             uint32_t code, void *user)
{
    co_rt_t *rt = user;
    rt_line_t *l = gw->port_count ? line_of_stack(rt, gw->ports[0].stack) : NULL;
    if (l != NULL) {
        rt_post(l, CO_EV_GATEWAY, net, (uint32_t)event, code, NULL);
    }
}

int rt_gateway_rebuild(co_rt_t *rt)
{
    co_gateway_t *gw = &rt->gateway;
    uint16_t routes[CO_GATEWAY_NETWORKS];
    bool relay_only = gw->sdo_relay_only;
    int count = rt_atomic_load_acquire(&rt->line_count);
    /* open connections end with aborts on both sides (not silently: the
     * peers would wait for their timeouts); what they were is kept so the
     * clients' next requests are refused, not served from our own OD */
    co_gateway_end_connections(gw);
    co_gateway_stats_t stats = gw->stats;
    co_gateway_ended_t ended = gw->ended;
    co_gateway_emcy_sent_t emcy_sent[CO_GATEWAY_EMCY_RECENT];   /* echoes still known */
    uint8_t emcy_next = gw->emcy_next;
    memcpy(emcy_sent, gw->emcy_sent, sizeof emcy_sent);
    memcpy(routes, gw->routes, sizeof routes);
    co_gateway_deinit(gw);
    co_gateway_init(gw, on_gateway_event, rt);
    memcpy(gw->routes, routes, sizeof routes);
    memcpy(gw->emcy_sent, emcy_sent, sizeof emcy_sent);
    gw->emcy_next = emcy_next;
    gw->stats = stats;
    co_gateway_set_sdo_buffering(gw, !relay_only);
    gw->ended = ended;
    co_gateway_set_sdo_buffer(gw, rt->gateway_sdo_buf, sizeof rt->gateway_sdo_buf);
    for (int i = 0; i < count; i++) {
        rt_line_t *l = rt->lines[i];
        if (l->network_id == 0) {
            continue;
        }
        if (co_line_mode(&l->line) == CO_MODE_FD ? co_line_node_id(&l->line) != 0
                                                 : sdo_client_possible(l)) {
            /* remote USDO requests and SDO networking into an fd line are
             * carried out by the line's USDO client; on a classic line the
             * SDO client lets the gateway buffer transfers (without it,
             * when 0x581..0x5FF are taken, its frames are relayed) */
            (void)rt_client_ready(rt, l);
        }
        co_gateway_status_t s = co_gateway_add_port(gw, &l->stack, l->network_id);
        if (s == CO_GATEWAY_ERR_FULL) {
            rt_set_error(rt, "line %d: a gateway joins at most %d lines", i,
                         CO_GATEWAY_MAX_PORTS);
            return CO_RT_ERR_FULL;
        }
        if (s != CO_GATEWAY_OK) {
            rt_set_error(rt, "line %d: the local node's object dictionary has no room for "
                         "the gateway's handlers", i);
            return CO_RT_ERR_FULL;
        }
        for (uint8_t node = 1; node < CO_GATEWAY_NETWORKS; node++) {
            if (l->emcy_routes[node] != 0) {
                (void)co_gateway_set_emcy_route(gw, &l->stack, node, l->emcy_routes[node]);
            }
        }
    }
    return CO_RT_OK;
}

int co_rt_gateway_join(co_rt_t *rt, int line, uint8_t network_id)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    if (network_id >= CO_GATEWAY_NETWORKS) {
        return rt_argument_error(rt, "line %d: network-id %u is not 1..127 (0 = leave)", line,
                                 (unsigned)network_id);
    }
    rt_mutex_lock(&rt->lock);
    int count = rt_atomic_load_acquire(&rt->line_count);
    for (int i = 0; i < count && network_id != 0; i++) {
        if (i != line && rt->lines[i]->network_id == network_id) {
            rt_mutex_unlock(&rt->lock);
            return rt_argument_error(rt, "line %d: another line (%s) carries network %u "
                                     "already", line, rt->lines[i]->channel,
                                     (unsigned)network_id);
        }
    }
    uint8_t old = l->network_id;
    l->network_id = network_id;
    int status = rt_gateway_rebuild(rt);
    if (status != CO_RT_OK) {
        l->network_id = old;
        (void)rt_gateway_rebuild(rt);
    }
    return rt_kick_unlock(rt, status);   /* the rebuild's aborts go out now */
}

int co_rt_gateway_network(co_rt_t *rt, int line)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    int net = l->network_id;
    rt_mutex_unlock(&rt->lock);
    return net;
}

static const char *route_refusal(uint32_t abort)
{
    return abort == CO_ABORT_INVALID_VALUE ? "via network must be 1..127 and node 1..127"
           : abort == CO_ABORT_NO_SUB      ? "networks are 1..127"
                                           : "it is attached, goes through itself or this "
                                             "gateway's own node, or closes a loop";
}

int co_rt_gateway_route(co_rt_t *rt, uint8_t net, uint8_t via_net, uint8_t node_id,
                        uint32_t *abort)
{
    uint32_t code;
    rt_mutex_lock(&rt->lock);
    code = co_gateway_set_route(&rt->gateway, net, via_net, node_id);
    rt_mutex_unlock(&rt->lock);
    if (abort) {
        *abort = code;
    }
    if (code != 0) {
        return rt_argument_error(rt, "refused with abort code 0x%08X: %s", (unsigned)code,
                                 route_refusal(code));
    }
    return CO_RT_OK;
}

int co_rt_gateway_resolve(co_rt_t *rt, uint8_t net, int *line, uint8_t *node_id)
{
    co_stack_t *stack = NULL;
    uint8_t node = 0;
    rt_mutex_lock(&rt->lock);
    co_gateway_route_kind_t kind = co_gateway_resolve(&rt->gateway, net, &stack, &node);
    rt_line_t *l = stack ? line_of_stack(rt, stack) : NULL;
    rt_mutex_unlock(&rt->lock);
    if (line) {
        *line = l ? l->index : -1;
    }
    if (node_id) {
        *node_id = node;
    }
    return (int)kind;
}

int co_rt_gateway_emcy_route(co_rt_t *rt, int line, uint8_t node_id, uint32_t networks)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    if (node_id < 1 || node_id > 127) {
        return rt_argument_error(rt, "line %d: EMCY route of node %u: node-ids are 1..127",
                                 line, (unsigned)node_id);
    }
    rt_mutex_lock(&rt->lock);
    l->emcy_routes[node_id] = networks;
    if (l->network_id != 0) {
        (void)co_gateway_set_emcy_route(&rt->gateway, &l->stack, node_id, networks);
    }
    rt_mutex_unlock(&rt->lock);
    return CO_RT_OK;
}

int co_rt_gateway_stats(co_rt_t *rt, co_gateway_stats_t *out)
{
    if (!out) {
        return rt_argument_error(rt, "gateway stats: no output given");
    }
    rt_mutex_lock(&rt->lock);
    *out = *co_gateway_stats(&rt->gateway);
    rt_mutex_unlock(&rt->lock);
    return CO_RT_OK;
}

int co_rt_gateway_sdo_buffering(co_rt_t *rt, bool on)
{
    rt_mutex_lock(&rt->lock);
    co_gateway_set_sdo_buffering(&rt->gateway, on);
    rt_mutex_unlock(&rt->lock);
    return CO_RT_OK;
}
