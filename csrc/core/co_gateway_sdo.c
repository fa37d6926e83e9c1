/* co_gateway SDO networking (CiA 302-7 style, seed 000 §13.1): a client's
 * network indication (ccs 7) on a server channel of one port names a target
 * network and node; from then on the gateway relays that client's SDO
 * frames to the target on the line that reaches it (the device itself when
 * its network is attached, the next gateway otherwise, which got the same
 * indication first) and the target's answers back, until the client names
 * another network. No answer within the timeout aborts both sides.
 *
 * Frames to a classic line are relayed as they are (8 bytes), so
 * expedited, segmented and block transfers all pass; the gateway only reads
 * byte 0 (the indication, aborts) and bytes 1..3 (for its own aborts). A
 * node of an attached fd line is reached by translation instead
 * (co_gateway_sdo_buffered.c). Segmented transfers to classic targets keep the two
 * hops running side by side: downloads pipelined (co_gateway_sdo_pipe.c),
 * uploads read ahead by the gateway's own client (co_gateway_sdo_buffered.c). */
#include "canopenfd/co_gateway.h"

#include <string.h>

enum co_gateway_sdo_state {
    SDO_CONNECTING = 1,   /* the indication went to the next gateway */
    SDO_CONNECTED = 2,
    SDO_WAITING = 3       /* a request went to the target */
};

enum { SDO_FRAME = 8, SDO_REQUEST_BASE = 0x600, SDO_RESPONSE_BASE = 0x580,
       SDO_CCS_ABORT = 0x80,
       /* block download: the client's initiate (ccs 6, cs 0) and the
        * server's end response (scs 5, ss 1), as byte 0 masks */
       SDO_BLOCK_DOWN_MASK = 0xE1, SDO_BLOCK_DOWN_INITIATE = 0xC0,
       /* block upload: the client's confirmation of the server's end
        * frame (ccs 5, cs 1), which is not answered */
       SDO_BLOCK_UP_END_RSP = 0xA1,
       SDO_BLOCK_DOWN_END_RSP = 0xA1 };

#define SDO_TIMEOUT 0x05040000u   /* CiA 301: SDO protocol timed out */

static co_line_t *line_of(const co_gateway_port_t *p)
{
    return co_stack_line(p->stack);
}

static uint64_t timeout_us(const co_gateway_t *gw)
{
    return gw->sdo_timeout_us != 0 ? gw->sdo_timeout_us
                                   : (uint64_t)CO_GATEWAY_SDO_TIMEOUT_MS * 1000u;
}

void co_gateway_set_sdo_timeout(co_gateway_t *gw, uint32_t timeout_ms)
{
    gw->sdo_timeout_us = (uint64_t)timeout_ms * 1000u;
}

/* A refused frame (tx queue full) is counted; the peers' timeouts end
 * the transfer as for a lost frame. */
static void send8(co_gateway_t *gw, co_line_t *line, uint32_t id, const uint8_t *data)
{
    if (!co_line_send(line, id, data, SDO_FRAME)) {
        gw->stats.sdo_tx_failed++;
    }
}

static void send_abort(co_gateway_t *gw, co_line_t *line, uint32_t id, const uint8_t *mux,
                       uint32_t code)
{
    uint8_t f[SDO_FRAME] = {SDO_CCS_ABORT, mux[0], mux[1], mux[2], (uint8_t)code,
                            (uint8_t)(code >> 8), (uint8_t)(code >> 16), (uint8_t)(code >> 24)};
    send8(gw, line, id, f);
}

static co_gateway_sdo_t *find(co_gateway_t *gw, const co_gateway_port_t *from, uint8_t channel)
{
    for (uint8_t i = 0; i < CO_GATEWAY_SDO_CONNECTIONS; i++) {
        if (gw->sdo[i].from == from && gw->sdo[i].channel == channel) {
            return &gw->sdo[i];
        }
    }
    return NULL;
}

static co_gateway_sdo_t *find_free(co_gateway_t *gw)
{
    for (uint8_t i = 0; i < CO_GATEWAY_SDO_CONNECTIONS; i++) {
        if (gw->sdo[i].from == NULL) {
            return &gw->sdo[i];
        }
    }
    return NULL;
}

static void on_answer(co_line_t *line, const co_frame_t *f, void *user);

static void release(co_gateway_sdo_t *c)
{
    if (c->from == NULL) {
        return;
    }
    bool relayed = !c->fd;
    co_gateway_sdo_pipe_close(c);
    if (c->buffered) {
        co_gateway_sdo_buffered_close(c);
    }
    if (relayed) {
        co_timer_cancel(co_line_timers(line_of(c->to)), &c->timer);
        co_line_unsubscribe(line_of(c->to), on_answer, c);
    }
    c->from = NULL;
    c->to = NULL;
    c->state = 0;
    c->block_down = false;
}

/* No answer from the target: both sides hear an abort (the target so it
 * does not wait for a request that will not come). */
static void on_timeout(co_timer_t *timer, uint64_t now_us, void *user)
{
    co_gateway_sdo_t *c = user;
    bool connecting = c->state == SDO_CONNECTING;
    (void)timer;
    (void)now_us;
    c->gw->stats.sdo_timeouts++;
    co_gateway_sdo_pipe_close(c);
    send_abort(c->gw, line_of(c->from), c->reply_id, c->mux, SDO_TIMEOUT);
    send_abort(c->gw, line_of(c->to), SDO_REQUEST_BASE + c->target, c->mux, SDO_TIMEOUT);
    c->block_down = false;
    if (connecting) {
        release(c);   /* never connected: the next gateway has nothing open */
    } else {
        c->state = SDO_CONNECTED;
    }
}

/* The target (or the next gateway) answered: relay it to the client. */
static void on_answer(co_line_t *line, const co_frame_t *f, void *user)
{
    co_gateway_sdo_t *c = user;
    (void)line;
    if (c->from == NULL || (f->flags & CO_FRAME_FD) || f->len != SDO_FRAME) {
        return;
    }
    co_timer_cancel(co_line_timers(line_of(c->to)), &c->timer);
    if (c->pipe != 0 && c->state == SDO_WAITING) {
        c->state = SDO_CONNECTED;
        if (co_gateway_sdo_pipe_answer(c, f->data)) {
            return;
        }
    }
    c->gw->stats.sdo_answers++;
    send8(c->gw, line_of(c->from), c->reply_id, f->data);
    if (f->data[0] == SDO_BLOCK_DOWN_END_RSP || f->data[0] == SDO_CCS_ABORT) {
        c->block_down = false;   /* the block download ended */
    }
    if (c->state == SDO_CONNECTING) {
        if (f->data[0] == CO_GATEWAY_SDO_NETWORK_IND) {
            c->state = SDO_CONNECTED;
            c->gw->stats.sdo_connects++;
        } else {
            c->gw->stats.sdo_refused++;
            release(c);   /* the next gateway refused: the client heard its abort */
        }
        return;
    }
    c->state = SDO_CONNECTED;
}

/* An answer the target line's own SDO client did not take (it is not
 * talking to that node): the connection waiting for it relays it. */
static bool on_idle_answer(co_sdo_client_t *client, const co_frame_t *f, void *user)
{
    co_gateway_port_t *to = user;
    co_gateway_t *gw = to->gw;
    (void)client;
    for (uint8_t i = 0; i < CO_GATEWAY_SDO_CONNECTIONS; i++) {
        co_gateway_sdo_t *c = &gw->sdo[i];
        if (c->from != NULL && c->to == to &&
            (uint32_t)SDO_RESPONSE_BASE + c->target == f->id) {
            on_answer(line_of(to), f, c);
            return true;
        }
    }
    return false;
}

/* Receive the target's answers: on a CAN-ID of our own, or through the
 * idle tap of the target line's SDO client when its 0x581..0x5FF receiver
 * holds the CAN-ID (a manager's or tool's client beside the gateway). False
 * when another receiver holds it, or that client talks to the node now. */
static bool listen(co_gateway_sdo_t *c, co_gateway_port_t *to, uint8_t target)
{
    co_line_t *line = line_of(to);
    uint32_t id = (uint32_t)SDO_RESPONSE_BASE + target;
    co_sdo_client_t *own = co_stack_sdo_client(to->stack);
    if (!co_line_id_taken(line, id)) {
        return co_line_subscribe(line, id, id, on_answer, c);
    }
    if (own == NULL || !co_sdo_client_holds(own, id) || co_sdo_client_receives(own, id)) {
        return false;
    }
    co_sdo_client_set_idle_tap(own, on_idle_answer, to);
    return true;
}

/* A classic target the gateway's buffer can serve: the target line's SDO
 * client receives its answers (it holds 0x581..0x5FF). */
static bool can_buffer(const co_gateway_t *gw, const co_gateway_port_t *to, uint8_t target)
{
    co_sdo_client_t *own = co_stack_sdo_client(to->stack);
    return gw->sdo_buf != NULL && own != NULL &&
           co_sdo_client_holds(own, (uint32_t)SDO_RESPONSE_BASE + target);
}

static bool target_taken(const co_gateway_t *gw, const co_gateway_port_t *to, uint8_t target)
{
    for (uint8_t i = 0; i < CO_GATEWAY_SDO_CONNECTIONS; i++) {
        if (gw->sdo[i].from != NULL && gw->sdo[i].to == to && gw->sdo[i].target == target) {
            return true;
        }
    }
    return false;
}

static void arm(co_gateway_sdo_t *c)
{
    co_line_t *line = line_of(c->to);
    co_timer_start(co_line_timers(line), &c->timer, co_line_now(line) + timeout_us(c->gw));
}

static bool refuse(co_gateway_t *gw, co_line_t *line, uint32_t reply_id, const uint8_t *mux,
                   uint32_t code)
{
    gw->stats.sdo_refused++;
    send_abort(gw, line, reply_id, mux, code);
    return true;
}

/* The slot of an ended connection on this server channel, or -1. */
static int ended_slot(const co_gateway_t *gw, const co_stack_t *stack, uint8_t channel)
{
    for (int i = 0; i < CO_GATEWAY_ENDED; i++) {
        if (gw->ended.stack[i] == stack && gw->ended.channel[i] == channel) {
            return i;
        }
    }
    return -1;
}

/* A network indication from a client on `from`'s server channel. */
static bool indication(co_gateway_port_t *from, uint8_t channel, uint32_t reply_id,
                       const uint8_t *data)
{
    co_gateway_t *gw = from->gw;
    co_line_t *line = line_of(from);
    co_gateway_sdo_t *c = find(gw, from, channel);
    uint16_t net = (uint16_t)(data[1] | data[2] << 8);
    uint8_t node = data[3];
    co_stack_t *target_line = NULL;
    uint8_t hop = 0;
    int ended = ended_slot(gw, from->stack, channel);
    if (ended >= 0) {
        gw->ended.stack[ended] = NULL;   /* the client knows: it connects anew */
    }
    if (c != NULL) {
        release(c);   /* a new indication ends the old connection */
    }
    if (net == 0 || (net == from->network_id && node == co_line_node_id(line))) {
        /* back to this gateway's own server */
        gw->stats.sdo_connects++;
        send8(gw, line, reply_id, data);
        return true;
    }
    if (net > 127 || node < 1 || node > 127) {
        return refuse(gw, line, reply_id, data + 1, CO_ABORT_INVALID_VALUE);
    }
    co_gateway_route_kind_t kind = co_gateway_resolve(gw, (uint8_t)net, &target_line, &hop);
    if (kind != CO_GATEWAY_ATTACHED && kind != CO_GATEWAY_VIA) {
        return refuse(gw, line, reply_id, data + 1, CO_GATEWAY_ABORT_NO_ROUTE);
    }
    co_gateway_port_t *to = NULL;
    for (uint8_t i = 0; i < gw->port_count; i++) {
        if (gw->ports[i].stack == target_line) {
            to = &gw->ports[i];
        }
    }
    uint8_t target = kind == CO_GATEWAY_VIA ? hop : node;
    bool fd = to != NULL && co_line_mode(line_of(to)) != CO_MODE_CLASSIC;
    co_usdo_client_t *uc = to != NULL ? co_stack_usdo_client(to->stack) : NULL;
    if (to == NULL || to == from || target == co_line_node_id(line_of(to)) ||
        (fd && (kind != CO_GATEWAY_ATTACHED || uc == NULL || target == uc->node_id))) {
        /* the line it came on, or our own node there, would loop; an fd
         * line is reached by translation only when attached (no remote
         * USDO) and through a USDO client of another node-id */
        return refuse(gw, line, reply_id, data + 1, CO_GATEWAY_ABORT_BUSY);
    }
    c = find_free(gw);
    if (c == NULL || (!fd && (target_taken(gw, to, target) || !listen(c, to, target)))) {
        /* no connection free, or another client already talks to the target */
        return refuse(gw, line, reply_id, data + 1, CO_GATEWAY_ABORT_BUSY);
    }
    c->gw = gw;
    c->from = from;
    c->channel = channel;
    c->reply_id = reply_id;
    c->to = to;
    c->target = target;
    c->net = (uint8_t)net;
    c->node = node;
    memcpy(c->mux, data + 1, 3);
    c->fd = false;
    c->buffered = false;
    if (!fd) {
        co_timer_init(&c->timer, on_timeout, c);
    }
    if (fd || (kind == CO_GATEWAY_ATTACHED && can_buffer(gw, to, target))) {
        co_gateway_sdo_buffered_open(c, fd);
    }
    if (kind == CO_GATEWAY_VIA) {
        /* the next gateway connects on: it confirms or aborts */
        c->state = SDO_CONNECTING;
        send8(gw, line_of(to), SDO_REQUEST_BASE + target, data);
        arm(c);
        return true;
    }
    c->state = SDO_CONNECTED;
    gw->stats.sdo_connects++;
    send8(gw, line, reply_id, data);
    return true;
}

/* A request on a server channel with no connection: when a rebuild ended
 * this client's connection, it hears CO_GATEWAY_ABORT_ENDED instead of an
 * answer from the gateway's own OD it did not ask for (its own abort
 * frames go to the server as usual). */
static bool ended_request(co_gateway_port_t *from, uint8_t channel, uint32_t tx_id,
                          const uint8_t *data)
{
    co_gateway_t *gw = from->gw;
    int slot = data[0] == SDO_CCS_ABORT ? -1 : ended_slot(gw, from->stack, channel);
    if (slot < 0) {
        return false;
    }
    gw->ended.stack[slot] = NULL;
    return refuse(gw, line_of(from), tx_id, data + 1, CO_GATEWAY_ABORT_ENDED);
}

static void remember_ended(co_gateway_t *gw, const co_gateway_sdo_t *c)
{
    int slot = ended_slot(gw, c->from->stack, c->channel);
    for (int i = 0; i < CO_GATEWAY_ENDED && slot < 0; i++) {
        if (gw->ended.stack[i] == NULL) {
            slot = i;
        }
    }
    if (slot < 0) {
        slot = gw->ended.next;   /* all taken: the oldest entry goes */
        gw->ended.next = (uint8_t)((gw->ended.next + 1u) % CO_GATEWAY_ENDED);
    }
    gw->ended.stack[slot] = c->from->stack;
    gw->ended.channel[slot] = c->channel;
}

/* A rebuild ends every connection. The relay does not follow transfer
 * boundaries (a segmented transfer is "connected" between its frames), so
 * both sides hear the abort whether a transfer runs or not: CiA 301 peers
 * ignore an abort for no transfer. */
void co_gateway_sdo_end(co_gateway_t *gw)
{
    for (uint8_t i = 0; i < CO_GATEWAY_SDO_CONNECTIONS; i++) {
        co_gateway_sdo_t *c = &gw->sdo[i];
        if (c->from == NULL) {
            continue;
        }
        gw->stats.connections_ended++;
        remember_ended(gw, c);
        if (c->fd) {
            co_gateway_sdo_buffered_end(c, CO_GATEWAY_ABORT_ENDED);
        } else {
            send_abort(gw, line_of(c->from), c->reply_id, c->mux, CO_GATEWAY_ABORT_ENDED);
            send_abort(gw, line_of(c->to), SDO_REQUEST_BASE + c->target, c->mux,
                       CO_GATEWAY_ABORT_ENDED);
        }
        release(c);
    }
}

/* A client's initiate (download, upload, block upload, block download):
 * the frames whose bytes 1..3 are the transfer's multiplexer (segments
 * carry data there). */
static bool starts_transfer(uint8_t byte0)
{
    uint8_t ccs = byte0 >> 5;
    return ccs == 1 || ccs == 2 || (ccs == 5 && (byte0 & 3u) == 0) || (ccs == 6 && !(byte0 & 1u));
}

static bool on_request(co_sdo_server_t *server, uint8_t channel, uint32_t tx_id,
                       const co_frame_t *f, void *user)
{
    co_gateway_port_t *from = user;
    co_gateway_sdo_t *c = find(from->gw, from, channel);
    /* a block download segment's byte 0 (0x80 | seqno 96..127) looks like
     * an indication: not while one runs, relayed or to our own server */
    bool segment = c != NULL ? c->block_down
                             : channel < server->channel_count &&
                                   server->channels[channel].state == CO_SDO_CH_BLOCK_DOWNLOAD;
    if (!segment && (f->data[0] & 0xE0u) == CO_GATEWAY_SDO_NETWORK_IND) {
        return indication(from, channel, tx_id, f->data);
    }
    if (c == NULL) {
        /* not connected: the gateway's own server answers */
        return ended_request(from, channel, tx_id, f->data);
    }
    if (c->state == SDO_CONNECTING) {
        send_abort(from->gw, line_of(from), c->reply_id, f->data + 1, CO_GATEWAY_ABORT_BUSY);
        return true;
    }
    if (c->pipe != 0 && f->data[0] >> 5 != 0) {
        co_gateway_sdo_pipe_close(c);   /* a new transfer or an abort ends it */
    }
    /* a relayed block download's segments (byte 0 = c | seqno) are no
     * requests of their own: never taken for pipelining or buffering */
    if (!c->block_down && c->buffered && co_gateway_sdo_buffered_request(c, f->data)) {
        return true;   /* fd targets; classic: uploads */
    }
    if (!c->block_down && co_gateway_sdo_pipe_request(c, f->data)) {
        return true;   /* classic: segmented downloads */
    }
    co_gateway_sdo_relay(c, f->data);
    return true;
}

void co_gateway_sdo_relay(co_gateway_sdo_t *c, const uint8_t *data)
{
    c->gw->stats.sdo_relayed++;
    send8(c->gw, line_of(c->to), SDO_REQUEST_BASE + c->target, data);
    if (data[0] == SDO_CCS_ABORT || data[0] == SDO_BLOCK_UP_END_RSP) {
        /* an abort, or the client's confirmation of a block upload's end,
         * is not answered: nothing to wait for */
        co_timer_cancel(co_line_timers(line_of(c->to)), &c->timer);
        c->state = SDO_CONNECTED;
        c->block_down = false;
        return;
    }
    if (!c->block_down && starts_transfer(data[0])) {
        memcpy(c->mux, data + 1, 3);   /* what the gateway's own aborts name */
    }
    if (!c->block_down && (data[0] & SDO_BLOCK_DOWN_MASK) == SDO_BLOCK_DOWN_INITIATE) {
        c->block_down = true;
    }
    c->state = SDO_WAITING;
    arm(c);
}

void co_gateway_sdo_hook(co_gateway_port_t *port)
{
    port->sdo_server = co_stack_sdo_server(port->stack);
    if (port->sdo_server != NULL) {
        co_sdo_server_set_filter(port->sdo_server, on_request, port);
    }
}

void co_gateway_sdo_unhook(co_gateway_port_t *port)
{
    co_gateway_t *gw = port->gw;
    for (uint8_t i = 0; i < CO_GATEWAY_SDO_CONNECTIONS; i++) {
        if (gw->sdo[i].from == port || gw->sdo[i].to == port) {
            release(&gw->sdo[i]);
        }
    }
    if (port->sdo_server != NULL) {
        co_sdo_server_set_filter(port->sdo_server, NULL, NULL);
        port->sdo_server = NULL;
    }
    if (co_stack_sdo_client(port->stack) != NULL) {
        co_sdo_client_clear_idle_tap(co_stack_sdo_client(port->stack), on_idle_answer, port);
    }
}
