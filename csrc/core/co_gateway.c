/* co_gateway: network-ids, 0x1F2C routes, EMCY routing (0x1F2F) and PDO
 * forwarding (0xB000..0xBFFF) between the lines of one device. */
#include "canopenfd/co_gateway.h"

#include "canopenfd/co_emcy_codec.h"

#include <string.h>

static bool is_forwarded(uint16_t index)
{
    return index >= CO_GATEWAY_PDO_FIRST && index <= CO_GATEWAY_PDO_LAST;
}

static bool valid_net(uint8_t net)
{
    return net >= 1 && net < CO_GATEWAY_NETWORKS;
}

static uint32_t le32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static co_gateway_port_t *port_of_net(co_gateway_t *gw, uint8_t net)
{
    for (uint8_t i = 0; i < gw->port_count; i++) {
        if (gw->ports[i].network_id == net) {
            return &gw->ports[i];
        }
    }
    return NULL;
}

static void report(co_gateway_t *gw, co_gateway_event_t event, uint8_t net, uint32_t code)
{
    if (gw->on_event) {
        gw->on_event(gw, event, net, code, gw->user);
    }
}

/* ------------------------------------------------------------- routes */

/* Follows the route of `net` through the table `routes` (the gateway's or
 * one being checked) to an attached network: the port and the first hop's
 * node, or UNKNOWN / LOOP. A chain visits each network at most once. */
static co_gateway_route_kind_t walk(co_gateway_t *gw, const uint16_t *routes, uint8_t net,
                                    co_gateway_port_t **port, uint8_t *node_id)
{
    uint8_t seen[CO_GATEWAY_NETWORKS / 8];
    uint8_t hop_node = 0;
    memset(seen, 0, sizeof seen);
    *port = NULL;
    *node_id = 0;
    while (valid_net(net)) {
        co_gateway_port_t *p = port_of_net(gw, net);
        if (p != NULL) {
            *port = p;
            *node_id = hop_node;
            return hop_node ? CO_GATEWAY_VIA : CO_GATEWAY_ATTACHED;
        }
        if (seen[net / 8] & (1u << (net % 8))) {
            return CO_GATEWAY_LOOP;
        }
        seen[net / 8] |= (uint8_t)(1u << (net % 8));
        if (routes[net] == 0 || (routes[net] >> 8) < 1 || (routes[net] >> 8) > 127) {
            /* no route, or one loaded unchecked whose node byte is no
             * node-id: node 0 would read as "attached to the via network" */
            return CO_GATEWAY_UNKNOWN;
        }
        /* the first hop is the gateway toward the via network: the nearest
         * route decides it, the further ones only name the way on */
        hop_node = (uint8_t)(routes[net] >> 8);
        net = (uint8_t)(routes[net] & 0xFFu);
    }
    return CO_GATEWAY_UNKNOWN;
}

/* 0 or the abort code for route value `value` of network `net`. */
static uint32_t check_route(co_gateway_t *gw, uint8_t net, uint32_t value)
{
    uint16_t trial[CO_GATEWAY_NETWORKS];
    co_gateway_port_t *p;
    uint8_t via = (uint8_t)(value & 0xFFu), node = (uint8_t)((value >> 8) & 0xFFu), hop;
    if (!valid_net(net)) {
        return CO_ABORT_NO_SUB;
    }
    if (value == 0) {
        return 0;
    }
    if ((value >> 16) != 0 || !valid_net(via) || node < 1 || node > 127) {
        return CO_ABORT_INVALID_VALUE;
    }
    if (port_of_net(gw, net) != NULL || via == net) {
        return CO_ABORT_PARAM_INCOMPATIBLE;   /* attached, or through itself */
    }
    p = port_of_net(gw, via);
    if (p != NULL && node == co_line_node_id(co_stack_line(p->stack))) {
        return CO_ABORT_PARAM_INCOMPATIBLE;   /* through ourselves: a loop */
    }
    memcpy(trial, gw->routes, sizeof trial);
    trial[net] = (uint16_t)value;
    if (walk(gw, trial, net, &p, &hop) == CO_GATEWAY_LOOP) {
        gw->stats.route_loops++;
        report(gw, CO_GATEWAY_EV_ROUTE_LOOP, net, CO_ABORT_PARAM_INCOMPATIBLE);
        return CO_ABORT_PARAM_INCOMPATIBLE;
    }
    return 0;
}

/* The route of `net` is now `value`: the table, and every other OD. */
static void store_route(co_gateway_t *gw, const co_od_t *from, uint8_t net, uint32_t value)
{
    gw->routes[net] = (uint16_t)value;
    if (gw->syncing) {
        return;
    }
    gw->syncing = true;
    for (uint8_t i = 0; i < gw->port_count; i++) {
        co_od_t *od = co_stack_od(gw->ports[i].stack);
        uint8_t bytes[4] = {(uint8_t)value, (uint8_t)(value >> 8), 0, 0};
        if (od != NULL && od != from && gw->ports[i].od_hooked &&
            co_od_find(od, CO_GATEWAY_ROUTES, net) != NULL) {
            (void)co_od_put(od, CO_GATEWAY_ROUTES, net, bytes, 4);
        }
    }
    gw->syncing = false;
}

uint32_t co_gateway_set_route(co_gateway_t *gw, uint8_t net, uint8_t via_net, uint8_t node_id)
{
    uint32_t value = via_net == 0 ? 0u : (uint32_t)via_net | (uint32_t)node_id << 8;
    uint32_t abort = check_route(gw, net, value);
    if (abort != 0) {
        gw->stats.routes_refused++;
        report(gw, CO_GATEWAY_EV_ROUTE_REFUSED, net, abort);
        return abort;
    }
    store_route(gw, NULL, net, value);
    return 0;
}

co_gateway_route_kind_t co_gateway_resolve(co_gateway_t *gw, uint8_t net, co_stack_t **line,
                                           uint8_t *node_id)
{
    co_gateway_port_t *p;
    co_gateway_route_kind_t kind = walk(gw, gw->routes, net, &p, node_id);
    *line = p != NULL ? p->stack : NULL;
    if (kind == CO_GATEWAY_LOOP) {
        gw->stats.route_loops++;
        report(gw, CO_GATEWAY_EV_ROUTE_LOOP, net, 0);
    }
    return kind;
}

/* -------------------------------------------------- OD: routes, mapping */

/* A mapping entry of this port's PDOs: an object forwarded between lines
 * must be mapped whole and be the same on every line that holds it. */
static uint32_t check_mapping(co_gateway_port_t *port, uint32_t mapping)
{
    co_gateway_t *gw = port->gw;
    uint16_t index = (uint16_t)(mapping >> 16);
    uint8_t sub = (uint8_t)(mapping >> 8), bits = (uint8_t)mapping;
    const co_od_entry_t *e;
    if (!is_forwarded(index)) {
        return 0;
    }
    e = co_od_find(co_stack_od(port->stack), index, sub);
    if (e == NULL) {
        return 0;   /* the PDO service refuses it */
    }
    if ((uint32_t)bits != e->size * 8u) {
        return CO_ABORT_PARAM_INCOMPATIBLE;   /* a part would be forwarded */
    }
    for (uint8_t i = 0; i < gw->port_count; i++) {
        co_od_t *other = co_stack_od(gw->ports[i].stack);
        const co_od_entry_t *o;
        if (&gw->ports[i] == port || other == NULL) {
            continue;
        }
        o = co_od_find(other, index, sub);
        if (o != NULL && (o->type != e->type || o->size != e->size)) {
            return CO_ABORT_PARAM_INCOMPATIBLE;
        }
    }
    return 0;
}

static uint32_t on_check_write(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e,
                               const uint8_t *value, uint32_t length, void *user)
{
    co_gateway_port_t *port = user;
    uint16_t index = co_od_entry_index(e);
    uint8_t sub = co_od_entry_sub(e);
    (void)xfer;
    if (index == CO_GATEWAY_ROUTES) {
        uint32_t abort;
        if (sub == 0 || length != 4 || port->gw->syncing) {
            return 0;
        }
        abort = check_route(port->gw, sub, le32(value));
        if (abort != 0) {
            port->gw->stats.routes_refused++;
            report(port->gw, CO_GATEWAY_EV_ROUTE_REFUSED, sub, abort);
        }
        return abort;
    }
    if (index >= CO_PDO_TPDO_COMM && index < CO_PDO_TPDO_MAP) {
        return 0;   /* TPDO communication parameters */
    }
    if (sub == 0 && length == 1) {
        /* enabling a mapping: every entry it will use */
        for (uint16_t k = 1; k <= value[0]; k++) {   /* 16 bits: 255 must not wrap */
            uint32_t mapping, abort;
            if (!co_od_get_u32(od, index, (uint8_t)k, &mapping)) {
                return 0;   /* the PDO service refuses a missing entry */
            }
            abort = check_mapping(port, mapping);
            if (abort != 0) {
                return abort;
            }
        }
        return 0;
    }
    return (sub >= 1 && length == 4) ? check_mapping(port, le32(value)) : 0;
}

static void on_after_write(co_od_t *od, const co_od_entry_t *e, co_od_origin_t origin,
                           void *user)
{
    co_gateway_port_t *port = user;
    uint32_t value;
    (void)origin;
    if (co_od_entry_index(e) != CO_GATEWAY_ROUTES || co_od_entry_sub(e) == 0 ||
        !co_od_get_u32(od, CO_GATEWAY_ROUTES, co_od_entry_sub(e), &value)) {
        return;
    }
    /* values a reset loads are not checked: resolving reports their loops */
    store_route(port->gw, od, co_od_entry_sub(e), value & 0xFFFFu);
}

static const co_od_handler_t gateway_handler = {
    .check_write = on_check_write,
    .after_write = on_after_write,
};

/* ------------------------------------------------------------- EMCY */

static uint32_t emcy_networks(co_gateway_port_t *port, uint8_t node_id)
{
    co_od_t *od = co_stack_od(port->stack);
    uint32_t value;
    if (od != NULL && co_od_get_u32(od, CO_GATEWAY_EMCY_ROUTES, node_id, &value)) {
        return value;
    }
    return port->emcy_routes[node_id];
}

static uint32_t net_bit(uint8_t net)
{
    return net >= 1 && net <= CO_GATEWAY_EMCY_NETWORKS ? 1u << (net - 1u) : 0u;
}

/* An EMCY equal to one we re-sent lately, heard on the network that one
 * came from or went to: our own EMCY coming back through another gateway
 * (EMCY frames carry no origin). Re-sending it would bounce it between the
 * gateways for ever. */
static bool is_echo(co_gateway_t *gw, const co_gateway_port_t *from, uint32_t cob_id,
                    const uint8_t *data, uint64_t now)
{
    for (uint8_t i = 0; i < CO_GATEWAY_EMCY_RECENT; i++) {
        const co_gateway_emcy_sent_t *e = &gw->emcy_sent[i];
        /* lines keep their own time: one a little behind another reads 0 */
        uint64_t age = now > e->at_us ? now - e->at_us : 0u;
        if (e->to_nets != 0 && age < (uint64_t)CO_GATEWAY_EMCY_ECHO_MS * 1000u &&
            e->cob_id == cob_id && memcmp(e->data, data, sizeof e->data) == 0 &&
            (e->from_net == from->network_id || (e->to_nets & net_bit(from->network_id)))) {
            return true;
        }
    }
    return false;
}

static void remember_sent(co_gateway_t *gw, const co_gateway_port_t *from, uint32_t cob_id,
                          const uint8_t *data, uint64_t now, uint32_t to_nets)
{
    co_gateway_emcy_sent_t *e = &gw->emcy_sent[gw->emcy_next];
    gw->emcy_next = (uint8_t)((gw->emcy_next + 1u) % CO_GATEWAY_EMCY_RECENT);
    e->at_us = now;
    e->cob_id = cob_id;
    e->to_nets = to_nets;
    e->from_net = from->network_id;
    memcpy(e->data, data, sizeof e->data);
}

static void on_emcy(co_emcy_consumer_t *c, uint8_t node_id, const co_emcy_msg_t *msg,
                    void *user)
{
    co_gateway_port_t *from = user;
    co_gateway_t *gw = from->gw;
    uint32_t networks = emcy_networks(from, node_id);
    uint32_t cob_id = co_emcy_consumer_get_entry(c, node_id);
    uint64_t now = co_line_now(co_stack_line(from->stack));
    uint8_t key[8] = {0};
    uint32_t sent = 0;
    if (networks == 0) {
        return;
    }
    (void)co_emcy_encode_classic(msg, key, sizeof key);
    if (is_echo(gw, from, cob_id, key, now)) {
        gw->stats.emcy_echoes++;
        return;
    }
    for (uint8_t k = 0; k < CO_GATEWAY_EMCY_NETWORKS && networks != 0; k++) {
        co_gateway_port_t *to;
        co_frame_t frame;
        if (!(networks & (1u << k))) {
            continue;
        }
        networks &= ~(1u << k);
        to = port_of_net(gw, (uint8_t)(k + 1u));
        if (to == NULL) {
            gw->stats.emcy_no_route++;
            continue;
        }
        if (to == from) {
            continue;   /* never back onto the line it came from */
        }
        memset(&frame, 0, sizeof frame);
        if (cob_id & CO_EMCY_COB_ID_FRAME) {
            frame.id = cob_id & 0x1FFFFFFFu;
            frame.flags = CO_FRAME_EXT;
        } else {
            frame.id = cob_id & 0x7FFu;
        }
        frame.len = (uint8_t)(co_line_mode(co_stack_line(to->stack)) == CO_MODE_FD
                                  ? co_emcy_encode_fd(msg, frame.data, sizeof frame.data)
                                  : co_emcy_encode_classic(msg, frame.data, sizeof frame.data));
        if (frame.len != 0 && co_line_send_frame(co_stack_line(to->stack), &frame)) {
            gw->stats.emcy_routed++;
            sent |= net_bit(to->network_id);
        } else {
            gw->stats.emcy_tx_failed++;
        }
    }
    if (sent != 0) {
        remember_sent(gw, from, cob_id, key, now, sent);
    }
}

bool co_gateway_set_emcy_route(co_gateway_t *gw, co_stack_t *stack, uint8_t node_id,
                               uint32_t networks)
{
    for (uint8_t i = 0; i < gw->port_count; i++) {
        if (gw->ports[i].stack == stack && node_id >= 1 && node_id <= 127) {
            gw->ports[i].emcy_routes[node_id] = networks;
            return true;
        }
    }
    return false;
}

/* ------------------------------------------------------ PDO forwarding */

/* RPDO `number` of `from` wrote its objects: copy the forwarded ones to the
 * other lines and trigger, once each, the TPDOs there that map them. */
static void on_rpdo(co_pdo_t *pdo, uint16_t number, void *user)
{
    co_gateway_port_t *from = user;
    co_gateway_t *gw = from->gw;
    const co_pdo_channel_t *rx = co_pdo_channel(pdo, true, number);
    co_od_t *src = co_stack_od(from->stack);
    if (rx == NULL || src == NULL) {
        return;
    }
    for (uint8_t i = 0; i < gw->port_count; i++) {
        co_gateway_port_t *to = &gw->ports[i];
        co_od_t *dst = co_stack_od(to->stack);
        uint32_t trigger[CO_PDO_MAX_NUMBER * 2 / 32];
        bool copied = false;
        if (to == from || to->pdo == NULL || dst == NULL) {
            continue;
        }
        memset(trigger, 0, sizeof trigger);
        for (uint8_t k = 0; k < rx->map_count; k++) {
            const co_od_entry_t *e = &src->entries[rx->map[k].entry];
            const co_od_entry_t *d;
            uint32_t entry;
            if ((rx->map[k].flags & CO_PDO_ITEM_DUMMY) || !is_forwarded(co_od_entry_index(e))) {
                continue;
            }
            d = co_od_find(dst, co_od_entry_index(e), co_od_entry_sub(e));
            if (d == NULL) {
                continue;
            }
            if (d->type != e->type || d->size != e->size ||
                co_od_put(dst, co_od_entry_index(e), co_od_entry_sub(e), co_od_value(src, e),
                          e->length) != 0) {
                gw->stats.pdo_mismatch++;
                continue;
            }
            gw->stats.pdo_values++;
            copied = true;
            entry = (uint32_t)(d - dst->entries);
            for (uint16_t c = 0; c < to->pdo->channel_count; c++) {
                const co_pdo_channel_t *ch = &to->pdo->channels[c];
                if (ch->is_rpdo || !ch->active) {
                    continue;
                }
                for (uint8_t m = 0; m < ch->map_count; m++) {
                    if (ch->map[m].entry == entry && !(ch->map[m].flags & CO_PDO_ITEM_DUMMY)) {
                        trigger[c / 32] |= 1u << (c % 32);
                        break;
                    }
                }
            }
        }
        if (copied) {
            gw->stats.pdo_forwarded++;
        }
        for (uint16_t c = 0; c < to->pdo->channel_count; c++) {
            if (trigger[c / 32] & (1u << (c % 32))) {
                if (co_pdo_trigger(to->pdo, to->pdo->channels[c].number)) {
                    gw->stats.tpdo_triggered++;
                } else {
                    gw->stats.tpdo_refused++;
                }
            }
        }
    }
}

/* ------------------------------------------------------------- ports */

void co_gateway_init(co_gateway_t *gw, co_gateway_event_fn on_event, void *user)
{
    memset(gw, 0, sizeof *gw);
    gw->on_event = on_event;
    gw->user = user;
}

static void unhook(co_gateway_port_t *p)
{
    co_od_t *od = co_stack_od(p->stack);
    co_gateway_sdo_unhook(p);
    co_gateway_usdo_unhook(p);
    if (p->od_hooked && od != NULL) {
        co_od_unsubscribe(od, &gateway_handler, p);
    }
    p->od_hooked = false;
    if (p->pdo != NULL) {
        co_pdo_set_rx_tap(p->pdo, NULL, NULL);
        p->pdo = NULL;
    }
    co_emcy_consumer_set_tap(co_stack_emcy_consumer(p->stack), NULL, NULL);
}

co_gateway_status_t co_gateway_add_port(co_gateway_t *gw, co_stack_t *stack,
                                        uint8_t network_id)
{
    co_gateway_port_t *p;
    co_od_t *od;
    if (gw == NULL || stack == NULL || !valid_net(network_id) ||
        co_gateway_network_of(gw, stack) != 0) {
        return CO_GATEWAY_ERR_ARGUMENT;
    }
    if (port_of_net(gw, network_id) != NULL) {
        return CO_GATEWAY_ERR_NETWORK;
    }
    if (gw->port_count >= CO_GATEWAY_MAX_PORTS) {
        return CO_GATEWAY_ERR_FULL;
    }
    p = &gw->ports[gw->port_count];
    memset(p, 0, sizeof *p);
    p->gw = gw;
    p->stack = stack;
    p->network_id = network_id;
    od = co_stack_od(stack);
    if (od != NULL) {
        bool mapping = co_od_subscribe(od, CO_PDO_RPDO_MAP, 0, CO_PDO_TPDO_MAP + 0x1FF, 0xFF,
                                       &gateway_handler, p);
        if (!mapping || (co_od_has_index(od, CO_GATEWAY_ROUTES) &&
                         !co_od_subscribe(od, CO_GATEWAY_ROUTES, 0, CO_GATEWAY_ROUTES, 0xFF,
                                          &gateway_handler, p))) {
            if (mapping) {
                co_od_unsubscribe(od, &gateway_handler, p);
            }
            return CO_GATEWAY_ERR_TAKEN;
        }
        p->od_hooked = true;
    }
    gw->port_count++;
    /* a route to this network is now "attached": the table keeps it, the
     * resolution finds the line first */
    if (od != NULL) {
        for (uint8_t net = 1; net < CO_GATEWAY_NETWORKS; net++) {
            uint32_t value;
            if (co_od_get_u32(od, CO_GATEWAY_ROUTES, net, &value) && value != 0) {
                gw->routes[net] = (uint16_t)value;
            }
        }
    }
    p->pdo = co_stack_pdo(stack);
    if (p->pdo != NULL) {
        co_pdo_set_rx_tap(p->pdo, on_rpdo, p);
    }
    co_emcy_consumer_set_tap(co_stack_emcy_consumer(stack), on_emcy, p);
    co_gateway_sdo_hook(p);
    co_gateway_usdo_hook(p);
    return CO_GATEWAY_OK;
}

void co_gateway_end_connections(co_gateway_t *gw)
{
    co_gateway_sdo_end(gw);
    co_gateway_usdo_end(gw);
}

void co_gateway_deinit(co_gateway_t *gw)
{
    for (uint8_t i = 0; i < gw->port_count; i++) {
        unhook(&gw->ports[i]);
    }
    gw->port_count = 0;
}

co_stack_t *co_gateway_line_of(co_gateway_t *gw, uint8_t net)
{
    co_gateway_port_t *p = port_of_net(gw, net);
    return p != NULL ? p->stack : NULL;
}

uint8_t co_gateway_network_of(const co_gateway_t *gw, const co_stack_t *stack)
{
    for (uint8_t i = 0; i < gw->port_count; i++) {
        if (gw->ports[i].stack == stack) {
            return gw->ports[i].network_id;
        }
    }
    return 0;
}
