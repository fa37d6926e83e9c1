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
 * passed one to one; each side keeps its own session-IDs, counters and
 * timing, and the gateway needs no session mapping on the target line.
 * Values up to CO_GATEWAY_USDO_VALUE_MAX bytes, expedited or segmented with
 * the client (a segmented download the target takes segmented starts at
 * the client's initiate and each segment goes on as soon as the client
 * sent it, the source saying "not yet" until then; a smaller one is
 * collected first; an upload is answered as soon as the target announced a size too
 * long for a routed expedited frame, and the client's segment requests are
 * served while the data still arrives, so the two hops overlap; a smaller
 * or unannounced value is fetched whole first); routed bulk requests are
 * answered 0x13. Layout and choices:
 * docs/protocol-notes.md "Remote USDO". */
#include "canopenfd/co_gateway.h"

#include <string.h>

enum co_gateway_usdo_state {
    RELAY_FORWARD = 1,   /* our request runs on the target line */
    RELAY_DL_RX = 2,     /* taking the client's download segments */
    RELAY_UL_TX = 3      /* serving the fetched value to the client in segments */
};

static co_line_t *line_of(const co_gateway_port_t *p)
{
    return co_stack_line(p->stack);
}

static uint32_t relay_timeout_ms(const co_gateway_t *gw)
{
    return gw->sdo_timeout_us != 0 ? (uint32_t)(gw->sdo_timeout_us / 1000u)
                                   : (uint32_t)CO_GATEWAY_SDO_TIMEOUT_MS;
}

/* A frame to the client on `from`, from the gateway's node there. The
 * extension (written only in the layouts with a multiplexer) names the
 * node the client asked for as its source. */
static void send_to_client(co_gateway_t *gw, co_gateway_port_t *from, uint8_t client,
                           const co_usdo_msg_t *asked, co_usdo_msg_t *m)
{
    uint8_t buf[CO_USDO_FRAME_MAX];
    co_line_t *line = line_of(from);
    size_t n;
    m->dest = client;
    m->remote = true;
    m->session = asked->session;
    m->index = asked->index;
    m->sub = asked->sub;
    m->dst_net = asked->src_net;
    m->dst_node = asked->src_node;
    m->src_net = asked->dst_net;
    m->src_node = asked->dst_node;
    n = co_usdo_encode(m, buf);
    if (n == 0 || !co_line_send(line, co_usdo_response_id(co_line_node_id(line)), buf, n)) {
        gw->stats.usdo_tx_failed++;
    }
}

static void abort_to_client(co_gateway_t *gw, co_gateway_port_t *from, uint8_t client,
                            const co_usdo_msg_t *asked, uint8_t code)
{
    co_usdo_msg_t m;
    memset(&m, 0, sizeof m);
    m.cs = CO_USDO_CS_ABORT;
    m.abort_code = code;
    send_to_client(gw, from, client, asked, &m);
}

static bool refuse(co_gateway_t *gw, co_gateway_port_t *from, uint8_t client,
                   const co_usdo_msg_t *asked, uint8_t code)
{
    gw->stats.usdo_refused++;
    abort_to_client(gw, from, client, asked, code);
    return true;
}

/* What the client asked (session, mux, route), rebuilt from the relay for
 * the frames after the first (segments carry no extension). */
static void asked_of(const co_gateway_usdo_t *r, co_usdo_msg_t *asked)
{
    memset(asked, 0, sizeof *asked);
    asked->session = r->session;
    asked->index = r->req.index;
    asked->sub = r->req.sub;
    asked->src_net = r->src_net;
    asked->src_node = r->client;
    asked->dst_net = r->net;
    asked->dst_node = r->node;
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

/* Free the relay; a request still running on the target line is
 * cancelled (the target hears `code`), its done() then answers nobody. */
static void release(co_gateway_usdo_t *r, uint8_t code)
{
    co_gateway_port_t *from = r->from;
    if (from == NULL) {
        return;
    }
    co_timer_cancel(co_line_timers(line_of(from)), &r->timer);
    r->from = NULL;
    if (r->fetching) {
        r->fetching = false;
        (void)co_usdo_client_cancel(co_stack_usdo_client(r->to->stack), &r->req, code);
    }
    r->state = 0;
}

/* The transfer ends with `code`, told to the client and (when running)
 * to the target. */
static void fail(co_gateway_usdo_t *r, uint8_t code)
{
    co_gateway_port_t *from = r->from;
    co_usdo_msg_t asked;
    asked_of(r, &asked);
    release(r, code);
    abort_to_client(r->gw, from, r->client, &asked, code);
}

/* The client's silence in the middle of a segmented exchange. */
static void on_client_timeout(co_timer_t *timer, uint64_t now_us, void *user)
{
    co_gateway_usdo_t *r = user;
    (void)timer;
    (void)now_us;
    r->gw->stats.usdo_timeouts++;
    fail(r, CO_USDO_ABORT_TIMEOUT);
}

static void arm(co_gateway_usdo_t *r)
{
    co_line_t *line = line_of(r->from);
    co_timer_start(co_line_timers(line), &r->timer,
                   co_line_now(line) + (uint64_t)relay_timeout_ms(r->gw) * 1000u);
}

/* The client's segment request (counter checked): the next segment when
 * the data has come (the last one also waits for the end of our request),
 * else it waits for the data (the target's timeout governs meanwhile). */
static void serve_upload(co_gateway_usdo_t *r)
{
    co_usdo_msg_t asked;
    co_usdo_msg_t out;
    uint32_t rest = r->size - r->offset;
    bool last = rest <= CO_USDO_SEGMENT_DATA;
    uint32_t n = last ? rest : CO_USDO_SEGMENT_DATA;
    if (r->buf.size < r->offset + n || (last && r->fetching)) {
        r->seg_pending = true;
        co_timer_cancel(co_line_timers(line_of(r->from)), &r->timer);
        return;
    }
    r->seg_pending = false;
    asked_of(r, &asked);
    memset(&out, 0, sizeof out);
    out.data = r->data + r->offset;
    out.length = (uint8_t)n;
    if (!last) {
        out.cs = CO_USDO_CS_UPLOAD_SEGMENT_RSP;
        out.counter = r->counter;
        r->offset += n;
        r->counter = co_usdo_next_counter(r->counter);
        send_to_client(r->gw, r->from, r->client, &asked, &out);
        arm(r);
        return;
    }
    co_gateway_port_t *from = r->from;
    out.cs = CO_USDO_CS_UPLOAD_LAST_RSP;
    release(r, 0);
    r->gw->stats.usdo_answered++;
    send_to_client(r->gw, from, r->client, &asked, &out);
}

/* Answer the client's upload with the size: segments from now on. */
static void answer_segmented(co_gateway_usdo_t *r, uint32_t size)
{
    co_usdo_msg_t asked;
    co_usdo_msg_t m;
    asked_of(r, &asked);
    memset(&m, 0, sizeof m);
    m.cs = CO_USDO_CS_UPLOAD_INITIATE_RSP;
    m.type = r->type;
    m.size = size;
    r->size = size;
    r->state = RELAY_UL_TX;
    r->counter = 0;
    r->offset = 0;
    r->seg_pending = false;
    send_to_client(r->gw, r->from, r->client, &asked, &m);
    arm(r);
}

/* Our upload's data: into the value, and to the client as it comes. An
 * announced size too long for a routed expedited answer is answered at
 * once. */
static uint8_t upload_sink(void *ctx, uint32_t offset, const uint8_t *data, uint32_t len,
                           uint32_t total)
{
    co_gateway_usdo_t *r = ctx;
    uint8_t code = co_usdo_buffer_sink(&r->buf, offset, data, len, total);
    if (code != 0 || r->from == NULL) {
        return code;
    }
    if (len == 0) {
        r->type = r->req.result_type;
        if (r->state == RELAY_FORWARD && total != 0xFFFFFFFFu &&
            total > CO_USDO_REMOTE_EXPEDITED_MAX) {
            answer_segmented(r, total);
        }
    } else if (r->state == RELAY_UL_TX && r->seg_pending) {
        serve_upload(r);
    }
    return 0;
}

/* Our download's data: what the client has sent so far; a streamed
 * download (still taking the client's segments) waits for the rest. */
static uint32_t download_source(void *ctx, uint32_t offset, uint8_t *buf, uint32_t want)
{
    co_gateway_usdo_t *r = ctx;
    if (r->state == RELAY_DL_RX && (offset > r->offset || want > r->offset - offset)) {
        return CO_USDO_SOURCE_LATER;
    }
    return co_usdo_buffer_source(&r->buf, offset, buf, want);
}

/* Our upload ended while the client was already served segments. */
static void streamed(co_gateway_usdo_t *r, uint8_t abort)
{
    if (abort != 0) {
        r->gw->stats.usdo_answered++;
        fail(r, abort);
        return;
    }
    if (r->buf.size != r->size) {
        r->gw->stats.usdo_answered++;
        fail(r, CO_USDO_ABORT_DATA_SIZE);
        return;
    }
    if (r->seg_pending) {
        serve_upload(r);
    }
}

/* The request on the target line ended: answer the client. */
static void on_done(co_usdo_request_t *req)
{
    co_gateway_usdo_t *r = req->user;
    co_gateway_port_t *from = r->from;
    co_usdo_msg_t asked;
    co_usdo_msg_t m;
    bool live = r->fetching;
    r->fetching = false;
    if (from == NULL || !live) {
        return;   /* cancelled: the client aborted, or a port left */
    }
    if (r->state == RELAY_UL_TX) {
        streamed(r, req->abort);
        return;
    }
    if (r->state == RELAY_DL_RX) {
        /* streamed download: the target has it all (or aborted, maybe while
         * the client still sends): the client's silence timer is done */
        co_timer_cancel(co_line_timers(line_of(from)), &r->timer);
        r->state = RELAY_FORWARD;
    }
    if (r->state != RELAY_FORWARD) {
        return;
    }
    asked_of(r, &asked);
    r->state = 0;
    if (req->abort != 0 || !req->upload || r->buf.size <= CO_USDO_REMOTE_EXPEDITED_MAX) {
        r->gw->stats.usdo_answered++;   /* this answer ends it (else the last segment) */
    }
    if (req->abort != 0) {
        r->from = NULL;
        abort_to_client(r->gw, from, r->client, &asked, req->abort);
        return;
    }
    memset(&m, 0, sizeof m);
    if (!req->upload) {
        /* expedited, or the end of the client's segmented download */
        m.cs = r->size <= CO_USDO_REMOTE_EXPEDITED_MAX && r->offset == 0
                   ? CO_USDO_CS_DOWNLOAD_EXPEDITED_RSP
                   : CO_USDO_CS_DOWNLOAD_LAST_RSP;
        r->from = NULL;
        send_to_client(r->gw, from, r->client, &asked, &m);
        return;
    }
    r->size = r->buf.size;
    r->type = req->result_type;
    m.type = r->type;
    if (r->size <= CO_USDO_REMOTE_EXPEDITED_MAX) {
        m.cs = CO_USDO_CS_UPLOAD_EXPEDITED_RSP;
        m.length = (uint8_t)r->size;
        m.data = r->data;
        r->from = NULL;
        send_to_client(r->gw, from, r->client, &asked, &m);
        return;
    }
    /* too long for a routed expedited frame, size not announced before:
     * segmented, the client asks */
    answer_segmented(r, r->size);
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

/* Start our request on the target line for the relay: false (the client
 * told why) when the target line's client refuses it. */
static bool start_request(co_gateway_usdo_t *r)
{
    co_usdo_msg_t asked;
    uint8_t code;
    r->fetching = true;
    code = co_usdo_client_start(co_stack_usdo_client(r->to->stack), &r->req);
    if (code != 0) {
        r->fetching = false;
        co_gateway_port_t *from = r->from;
        asked_of(r, &asked);
        r->from = NULL;
        r->state = 0;
        r->gw->stats.usdo_refused++;
        abort_to_client(r->gw, from, r->client, &asked,
                        code == CO_USDO_ABORT_BUSY ? CO_USDO_ABORT_BUSY : CO_USDO_ABORT_ROUTING);
        return false;
    }
    r->gw->stats.usdo_forwarded++;
    return true;
}

/* The whole request goes to the target now; the client waits for its end. */
static void forward(co_gateway_usdo_t *r)
{
    r->state = RELAY_FORWARD;
    (void)start_request(r);
}

/* A first frame (expedited download, segmented download initiate, upload):
 * route it, take a relay. */
static bool on_request(co_gateway_port_t *from, uint8_t client, const co_usdo_msg_t *m)
{
    co_gateway_t *gw = from->gw;
    co_stack_t *target_line = NULL;
    co_gateway_port_t *to;
    co_gateway_usdo_t *r;
    uint8_t hop = 0;
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
    if (to == NULL || to == from || co_stack_usdo_client(to->stack) == NULL) {
        /* the line it came from, or a line without a USDO client (classic) */
        return refuse(gw, from, client, m, CO_USDO_ABORT_ROUTING);
    }
    if (find(gw, from, client, m->session) != NULL) {
        return refuse(gw, from, client, m, CO_USDO_ABORT_SESSION);
    }
    if (m->cs == CO_USDO_CS_DOWNLOAD_INITIATE && m->size > CO_GATEWAY_USDO_VALUE_MAX) {
        return refuse(gw, from, client, m, CO_USDO_ABORT_OUT_OF_MEMORY);
    }
    r = find_free(gw);
    if (r == NULL) {
        return refuse(gw, from, client, m, CO_USDO_ABORT_BUSY);
    }
    memset(r, 0, sizeof *r);
    r->gw = gw;
    r->from = from;
    r->to = to;
    r->client = client;
    r->session = m->session;
    r->src_net = m->src_net;
    r->net = m->dst_net;
    r->node = m->dst_node;
    r->type = m->type;
    r->buf.data = r->data;
    r->buf.capacity = sizeof r->data;
    co_timer_init(&r->timer, on_client_timeout, r);
    r->req.index = m->index;
    r->req.sub = m->sub;
    r->req.upload = m->cs == CO_USDO_CS_UPLOAD;
    r->req.done = on_done;
    r->req.user = r;
    r->req.ctx = r;
    r->req.timeout_ms = relay_timeout_ms(gw);
    r->req.sink = upload_sink;             /* above the buffer: 0x16 */
    r->req.source = download_source;
    if (kind == CO_GATEWAY_VIA) {
        /* on to the next gateway, routed again */
        r->req.server = hop;
        r->req.network = m->dst_net;
        r->req.network_node = m->dst_node;
        r->req.source_network = to->network_id;
    } else {
        r->req.server = m->dst_node;
    }
    if (m->cs == CO_USDO_CS_DOWNLOAD_INITIATE) {
        /* the client hears 0xA2 now; a value the target takes segmented
         * goes on segment by segment as the client's come (the two hops
         * overlap), a smaller one is collected first */
        co_usdo_msg_t rsp;
        r->size = m->size;
        r->state = RELAY_DL_RX;
        r->buf.size = m->size;   /* the source reads what the client sent (r->offset) */
        if (m->size > CO_USDO_EXPEDITED_MAX) {
            r->req.size = m->size;
            r->req.type = m->type;
            r->req.mode = CO_USDO_MODE_SEGMENTED;
            if (!start_request(r)) {
                return true;
            }
        }
        memset(&rsp, 0, sizeof rsp);
        rsp.cs = CO_USDO_CS_DOWNLOAD_INITIATE_RSP;
        send_to_client(gw, from, client, m, &rsp);
        arm(r);
        return true;
    }
    if (m->cs == CO_USDO_CS_DOWNLOAD_EXPEDITED) {
        memcpy(r->data, m->data, m->length);
        r->buf.size = m->length;
        r->size = m->length;
        r->req.size = m->length;
        r->req.type = m->type;
    }
    forward(r);
    return true;
}

/* A segment of the client's download, or its request for the next upload
 * segment. */
static bool on_segment(co_gateway_port_t *from, uint8_t client, const co_usdo_msg_t *m)
{
    co_gateway_t *gw = from->gw;
    co_gateway_usdo_t *r = find(gw, from, client, m->session);
    co_usdo_msg_t asked;
    co_usdo_msg_t out;
    bool download = m->cs != CO_USDO_CS_UPLOAD_SEGMENT;
    if (r == NULL) {
        gw->stats.usdo_stray++;   /* no route known to answer it: the client's timeout */
        return true;
    }
    if (r->state != (download ? RELAY_DL_RX : RELAY_UL_TX)) {
        fail(r, CO_USDO_ABORT_COMMAND);
        return true;
    }
    asked_of(r, &asked);
    memset(&out, 0, sizeof out);
    if (!download) {
        if (m->counter != r->counter) {
            fail(r, CO_USDO_ABORT_COUNTER);
            return true;
        }
        if (!r->seg_pending) {   /* (a repeat while one waits is the same request) */
            serve_upload(r);
        }
        return true;
    }
    if (m->cs == CO_USDO_CS_DOWNLOAD_SEGMENT) {
        if (m->counter != r->counter) {
            fail(r, CO_USDO_ABORT_COUNTER);
            return true;
        }
        if (m->length > r->size - r->offset) {
            fail(r, CO_USDO_ABORT_DATA_SIZE);
            return true;
        }
        memcpy(r->data + r->offset, m->data, m->length);
        r->offset += m->length;
        out.cs = CO_USDO_CS_DOWNLOAD_SEGMENT_RSP;
        out.counter = m->counter;
        r->counter = co_usdo_next_counter(r->counter);
        send_to_client(gw, from, client, &asked, &out);
        arm(r);
        if (r->fetching) {
            (void)co_usdo_client_resume(co_stack_usdo_client(r->to->stack), &r->req);
        }
        return true;
    }
    /* the last segment: the value is whole, send it on */
    if (m->length != r->size - r->offset) {
        fail(r, CO_USDO_ABORT_DATA_SIZE);
        return true;
    }
    memcpy(r->data + r->offset, m->data, m->length);
    r->offset += m->length;
    co_timer_cancel(co_line_timers(line_of(from)), &r->timer);
    if (r->fetching) {   /* streamed: the rest goes on, 0xA4 when the target has it */
        (void)co_usdo_client_resume(co_stack_usdo_client(r->to->stack), &r->req);
        return true;
    }
    r->buf.size = r->size;
    r->req.size = r->size;
    r->req.type = r->type;
    forward(r);
    return true;
}

/* A client's routed abort ends the relay (a request running on the target
 * line is cancelled: the target hears the client's code); one for nothing
 * we relay is counted. */
static bool client_abort(co_gateway_port_t *from, uint8_t client, const co_usdo_msg_t *m)
{
    co_gateway_t *gw = from->gw;
    co_gateway_usdo_t *r = find(gw, from, client, m->session);
    if (r == NULL) {
        gw->stats.usdo_stray++;
        return true;
    }
    gw->stats.usdo_client_aborts++;
    release(r, m->abort_code != 0 ? m->abort_code : CO_USDO_ABORT_UNKNOWN);
    return true;
}

static bool on_remote(co_usdo_server_t *server, uint8_t client, co_usdo_decode_result_t res,
                      const co_usdo_msg_t *m, void *user)
{
    co_gateway_port_t *from = user;
    co_gateway_t *gw = from->gw;
    (void)server;
    if (m->cs == CO_USDO_CS_ABORT) {
        return client_abort(from, client, m);
    }
    switch (res == CO_USDO_DECODE_OK ? m->cs : 0) {
    case CO_USDO_CS_DOWNLOAD_EXPEDITED:
    case CO_USDO_CS_DOWNLOAD_INITIATE:
    case CO_USDO_CS_UPLOAD:
        return on_request(from, client, m);
    case CO_USDO_CS_DOWNLOAD_SEGMENT:
    case CO_USDO_CS_DOWNLOAD_LAST:
    case CO_USDO_CS_UPLOAD_SEGMENT:
        return on_segment(from, client, m);
    default:
        break;
    }
    /* malformed, unknown, bulk (not routed), or a response sent as a request */
    co_gateway_usdo_t *r = find(gw, from, client, m->session);
    uint8_t code = res == CO_USDO_DECODE_OK || res == CO_USDO_DECODE_UNKNOWN_CS
                       ? CO_USDO_ABORT_COMMAND
                       : CO_USDO_ABORT_DLC;
    if (r != NULL) {
        fail(r, code);
        return true;
    }
    return refuse(gw, from, client, m, code);
}

/* A rebuild ends every request being carried out: the client hears a
 * routed abort, a request running on the target line is stopped, both
 * with the USDO counterpart of CO_GATEWAY_ABORT_ENDED. */
void co_gateway_usdo_end(co_gateway_t *gw)
{
    for (uint8_t i = 0; i < CO_GATEWAY_USDO_RELAYS; i++) {
        if (gw->usdo[i].from != NULL) {
            gw->stats.connections_ended++;
            fail(&gw->usdo[i], co_usdo_abort_from_co(CO_GATEWAY_ABORT_ENDED));
        }
    }
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
            release(r, CO_USDO_ABORT_UNKNOWN);
        }
    }
    if (port->usdo_server != NULL) {
        co_usdo_server_set_remote_handler(port->usdo_server, NULL, NULL);
        port->usdo_server = NULL;
    }
}
