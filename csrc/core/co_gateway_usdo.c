/* co_gateway remote USDO (CiA 1301 "remote" services): a client on one fd
 * line sends a routed request (command specifier | 0x80, the 4-byte
 * extension: destination network and node, source network and node) to
 * the gateway's node; the gateway carries it out on the line that reaches
 * the destination with that line's own USDO client (to the node itself
 * when its network is attached, as a routed request to the next gateway
 * otherwise) and answers the client with the routed response or abort.
 *
 * Store and forward rather than a frame relay: a target's expedited upload
 * may hold 56 bytes, a routed expedited frame only 52, so frames cannot be
 * passed one to one; each side keeps its own session-IDs and timing, and
 * the gateway needs no session mapping on the target line. Expedited
 * requests only (0x81, 0x91 with values up to 52 bytes); segmented and
 * bulk routed requests are answered 0x13. Layout and choices:
 * docs/protocol-notes.md "Remote USDO". */
#include "canopenfd/co_gateway.h"

#include <string.h>

static co_line_t *line_of(const co_gateway_port_t *p)
{
    return co_stack_line(p->stack);
}

static uint32_t relay_timeout_ms(const co_gateway_t *gw)
{
    return gw->sdo_timeout_us != 0 ? (uint32_t)(gw->sdo_timeout_us / 1000u)
                                   : (uint32_t)CO_GATEWAY_SDO_TIMEOUT_MS;
}

/* An answer to the client on `from`, from the gateway's node there; the
 * extension names the node the client asked for as its source. */
static void answer(co_gateway_t *gw, co_gateway_port_t *from, const co_usdo_msg_t *req,
                   co_usdo_msg_t *m)
{
    uint8_t buf[CO_USDO_FRAME_MAX];
    co_line_t *line = line_of(from);
    size_t n;
    m->remote = true;
    m->session = req->session;
    m->index = req->index;
    m->sub = req->sub;
    m->dst_net = req->src_net;
    m->dst_node = req->src_node;
    m->src_net = req->dst_net;
    m->src_node = req->dst_node;
    n = co_usdo_encode(m, buf);
    if (n == 0 || !co_line_send(line, co_usdo_response_id(co_line_node_id(line)), buf, n)) {
        gw->stats.usdo_tx_failed++;
    }
}

static void answer_abort(co_gateway_t *gw, co_gateway_port_t *from, uint8_t client,
                         const co_usdo_msg_t *req, uint8_t code)
{
    co_usdo_msg_t m;
    memset(&m, 0, sizeof m);
    m.dest = client;
    m.cs = CO_USDO_CS_ABORT;
    m.abort_code = code;
    answer(gw, from, req, &m);
}

static bool refuse(co_gateway_t *gw, co_gateway_port_t *from, uint8_t client,
                   const co_usdo_msg_t *req, uint8_t code)
{
    gw->stats.usdo_refused++;
    answer_abort(gw, from, client, req, code);
    return true;
}

static co_gateway_usdo_t *find(co_gateway_t *gw, const co_gateway_port_t *from, uint8_t client,
                               uint8_t session)
{
    for (uint8_t i = 0; i < CO_GATEWAY_USDO_RELAYS; i++) {
        co_gateway_usdo_t *r = &gw->usdo[i];
        if (r->from == from && r->client == client && r->session == session) {
            return r;
        }
    }
    return NULL;
}

static co_gateway_usdo_t *find_free(co_gateway_t *gw)
{
    for (uint8_t i = 0; i < CO_GATEWAY_USDO_RELAYS; i++) {
        if (gw->usdo[i].from == NULL) {
            return &gw->usdo[i];
        }
    }
    return NULL;
}

/* The request on the target line ended: answer the client. */
static void on_done(co_usdo_request_t *req)
{
    co_gateway_usdo_t *r = req->user;
    co_gateway_port_t *from = r->from;
    co_usdo_msg_t asked;
    co_usdo_msg_t m;
    if (from == NULL) {
        return;   /* cancelled: the client aborted, or the port left */
    }
    r->from = NULL;
    memset(&asked, 0, sizeof asked);
    asked.session = r->session;
    asked.index = req->index;
    asked.sub = req->sub;
    asked.src_net = r->src_net;
    asked.src_node = r->client;
    asked.dst_net = r->net;
    asked.dst_node = r->node;
    r->gw->stats.usdo_answered++;
    if (req->abort != 0) {
        answer_abort(r->gw, from, r->client, &asked, req->abort);
        return;
    }
    memset(&m, 0, sizeof m);
    m.dest = r->client;
    if (req->upload) {
        m.cs = CO_USDO_CS_UPLOAD_EXPEDITED_RSP;
        m.type = req->result_type;
        m.length = (uint8_t)r->buf.size;
        m.data = r->data;
    } else {
        m.cs = CO_USDO_CS_DOWNLOAD_EXPEDITED_RSP;
    }
    answer(r->gw, from, &asked, &m);
}

static co_gateway_port_t *port_of(co_gateway_t *gw, const co_stack_t *stack)
{
    for (uint8_t i = 0; i < gw->port_count; i++) {
        if (gw->ports[i].stack == stack) {
            return &gw->ports[i];
        }
    }
    return NULL;
}

/* A client's routed abort ends the forwarded request (the target hears it
 * from our client); one for nothing we forward is counted. */
static bool client_abort(co_gateway_port_t *from, uint8_t client, const co_usdo_msg_t *m)
{
    co_gateway_t *gw = from->gw;
    co_gateway_usdo_t *r = find(gw, from, client, m->session);
    if (r == NULL) {
        gw->stats.usdo_stray++;
        return true;
    }
    gw->stats.usdo_client_aborts++;
    r->from = NULL;   /* on_done (called from the cancel) answers nobody */
    (void)co_usdo_client_cancel(co_stack_usdo_client(r->to->stack), &r->req,
                                m->abort_code != 0 ? m->abort_code : CO_USDO_ABORT_UNKNOWN);
    return true;
}

static bool on_remote(co_usdo_server_t *server, uint8_t client, co_usdo_decode_result_t res,
                      const co_usdo_msg_t *m, void *user)
{
    co_gateway_port_t *from = user;
    co_gateway_t *gw = from->gw;
    co_stack_t *target_line = NULL;
    co_gateway_port_t *to;
    co_usdo_client_t *uc;
    co_gateway_usdo_t *r;
    uint8_t hop = 0;
    uint8_t code;
    (void)server;
    if (m->cs == CO_USDO_CS_ABORT) {
        return client_abort(from, client, m);
    }
    if (res != CO_USDO_DECODE_OK) {
        return refuse(gw, from, client, m,
                      res == CO_USDO_DECODE_UNKNOWN_CS ? CO_USDO_ABORT_COMMAND
                                                       : CO_USDO_ABORT_DLC);
    }
    if (m->cs != CO_USDO_CS_DOWNLOAD_EXPEDITED && m->cs != CO_USDO_CS_UPLOAD) {
        /* segmented / bulk routed transfers are not forwarded */
        return refuse(gw, from, client, m, CO_USDO_ABORT_COMMAND);
    }
    /* source network 0: a client that does not know its network-id (the
     * answer echoes the 0); another network than this port's is refused */
    if ((m->src_net != 0 && m->src_net != from->network_id) || m->src_node != client) {
        return refuse(gw, from, client, m,
                      m->src_node == client ? CO_USDO_ABORT_SOURCE_NETWORK
                                            : CO_USDO_ABORT_SOURCE_NODE);
    }
    if (m->dst_node < 1 || m->dst_node > 127) {
        return refuse(gw, from, client, m, CO_USDO_ABORT_DEST_NODE);
    }
    co_gateway_route_kind_t kind =
        m->dst_net >= 1 && m->dst_net <= 127
            ? co_gateway_resolve(gw, m->dst_net, &target_line, &hop)
            : CO_GATEWAY_UNKNOWN;
    if (kind != CO_GATEWAY_ATTACHED && kind != CO_GATEWAY_VIA) {
        return refuse(gw, from, client, m, CO_USDO_ABORT_DEST_NETWORK);
    }
    to = port_of(gw, target_line);
    uc = to != NULL ? co_stack_usdo_client(to->stack) : NULL;
    if (to == NULL || to == from || uc == NULL) {
        /* the line it came from, or a line without a USDO client (classic) */
        return refuse(gw, from, client, m, CO_USDO_ABORT_ROUTING);
    }
    if (find(gw, from, client, m->session) != NULL) {
        return refuse(gw, from, client, m, CO_USDO_ABORT_SESSION);
    }
    r = find_free(gw);
    if (r == NULL) {
        return refuse(gw, from, client, m, CO_USDO_ABORT_BUSY);
    }
    memset(r, 0, sizeof *r);
    r->gw = gw;
    r->to = to;
    r->client = client;
    r->session = m->session;
    r->src_net = m->src_net;
    r->net = m->dst_net;
    r->node = m->dst_node;
    r->buf.data = r->data;
    r->buf.capacity = sizeof r->data;
    r->req.index = m->index;
    r->req.sub = m->sub;
    r->req.upload = m->cs == CO_USDO_CS_UPLOAD;
    r->req.done = on_done;
    r->req.user = r;
    r->req.ctx = &r->buf;
    r->req.timeout_ms = relay_timeout_ms(gw);
    if (r->req.upload) {
        r->req.sink = co_usdo_buffer_sink;   /* above 52 bytes: 0x16 (no room) */
    } else {
        memcpy(r->data, m->data, m->length);
        r->buf.size = m->length;
        r->req.size = m->length;
        r->req.type = m->type;
        r->req.mode = CO_USDO_MODE_EXPEDITED;
        r->req.source = co_usdo_buffer_source;
    }
    if (kind == CO_GATEWAY_VIA) {
        /* on to the next gateway, routed again */
        r->req.server = hop;
        r->req.network = m->dst_net;
        r->req.network_node = m->dst_node;
        r->req.source_network = to->network_id;
    } else {
        r->req.server = m->dst_node;
    }
    r->from = from;   /* taken before the start: done() may come from inside it */
    code = co_usdo_client_start(uc, &r->req);
    if (code != 0) {
        r->from = NULL;
        return refuse(gw, from, client, m, code == CO_USDO_ABORT_BUSY ? CO_USDO_ABORT_BUSY
                                                                      : CO_USDO_ABORT_ROUTING);
    }
    gw->stats.usdo_forwarded++;
    return true;
}

void co_gateway_usdo_hook(co_gateway_port_t *port)
{
    port->usdo_server = co_stack_usdo_server(port->stack);
    if (port->usdo_server != NULL) {
        co_usdo_server_set_remote_handler(port->usdo_server, on_remote, port);
    }
}

void co_gateway_usdo_unhook(co_gateway_port_t *port)
{
    co_gateway_t *gw = port->gw;
    for (uint8_t i = 0; i < CO_GATEWAY_USDO_RELAYS; i++) {
        co_gateway_usdo_t *r = &gw->usdo[i];
        if (r->from != NULL && (r->from == port || r->to == port)) {
            r->from = NULL;
            (void)co_usdo_client_cancel(co_stack_usdo_client(r->to->stack), &r->req, 0);
        }
    }
    if (port->usdo_server != NULL) {
        co_usdo_server_set_remote_handler(port->usdo_server, NULL, NULL);
        port->usdo_server = NULL;
    }
}
