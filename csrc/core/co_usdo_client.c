/* USDO client: see co_usdo_client.h for the session model and
 * docs/protocol-notes.md (section "USDO client") for every wire choice.
 *
 * Rules where the public sources leave room:
 *  - Only CAN FD frames whose byte 0 is our node-id count; a frame is bound
 *    to a session by (sender node-id from the CAN-ID, session-ID); for a
 *    broadcast session any sender matches. Everything else is ignored and
 *    counted.
 *  - A frame of a live session whose command the session does not expect
 *    in its state (a repeated 0x22, an early 0x28, ...) is ignored and
 *    counted; it does not re-arm the timeout. A frame the session expects
 *    but that is too short / has a bad length is answered with 0x1E, index
 *    or sub-index other than the request's with 0x1F, a wrong segment
 *    counter with 0x14, more or fewer upload bytes than announced with 0x15.
 *  - A server abort with code 0 (or too short to hold a code) counts as 0x10.
 *  - Every error of ours on a unicast transfer is sent to the server as an
 *    abort, even after the server's last frame (0x31, 0x34): it then only
 *    tells the server the data was not taken (the server ignores it).
 *  - AUTO: a bulk initiate refused with 0x13 (the server has no bulk) is
 *    retried once as a segmented download with a fresh session-ID; a bulk
 *    upload request (0x16) refused with 0x13 once as a plain upload (0x11).
 *  - Bulk upload (our layout, docs/protocol-notes.md): 0x16 carries our
 *    window; we acknowledge (0x17, the counter of the last segment taken)
 *    every half window, so the server never has more than a window of
 *    segments in flight towards our receive queue.
 *  - Segments shorter than 64 bytes (0x33, 0x37) are taken and counted. */
#include "canopenfd/co_usdo_client.h"

#include "co_bits.h"

#include <string.h>

enum {
    NODE_MAX = 127,
    SID_MAX = 255,
    TYPE_DOMAIN = 0x0F
};

#define SIZE_UNKNOWN 0xFFFFFFFFu   /* announced size of an upload that does not know it */

/* ------------------------------------------------------------ helpers */

static co_timer_list_t *timers_of(const co_usdo_client_session_t *ses)
{
    return co_line_timers(ses->client->line);
}

static uint64_t now_of(const co_usdo_client_t *c)
{
    return co_line_now(c->line);
}

static uint64_t timeout_of(const co_usdo_client_session_t *ses)
{
    const co_usdo_request_t *req = ses->req;
    return req->timeout_ms != 0 ? (uint64_t)req->timeout_ms * 1000u : ses->client->timeout_us;
}

static void arm_timeout_at(co_usdo_client_session_t *ses, uint64_t from)
{
    co_timer_start(timers_of(ses), &ses->timer, from + timeout_of(ses));
}

static void arm_timeout(co_usdo_client_session_t *ses)
{
    arm_timeout_at(ses, now_of(ses->client));
}

static bool sid_live(const co_usdo_client_t *c, uint8_t sid)
{
    return co_bit32_test(c->live_sid, sid);
}

static void sid_mark(co_usdo_client_t *c, uint8_t sid, bool live)
{
    co_bit32_put(c->live_sid, sid, live);
}

/* Round-robin over 1..255, skipping live IDs: a finished transfer's ID
 * comes back only after every other one was handed out. Never 0 while a
 * session is unused (at most 254 are live then). */
static uint8_t sid_next(co_usdo_client_t *c)
{
    unsigned k;
    for (k = 0; k < SID_MAX; k++) {
        uint8_t sid = c->next_sid;
        c->next_sid = (uint8_t)(sid == SID_MAX ? 1u : sid + 1u);
        if (!sid_live(c, sid)) {
            sid_mark(c, sid, true);
            return sid;
        }
    }
    return 0;
}

static bool is_broadcast(const co_usdo_client_session_t *ses)
{
    return ses->req->server == CO_USDO_BROADCAST;
}

/* ------------------------------------------------------------ sending */

static bool send_msg(co_usdo_client_t *c, const co_usdo_msg_t *m)
{
    uint8_t buf[CO_USDO_FRAME_MAX];
    size_t n = co_usdo_encode(m, buf);
    if (n == 0 || !co_line_send(c->line, co_usdo_request_id(c->node_id), buf, n)) {
        c->stats.tx_failed++;
        return false;
    }
    return true;
}

/* Header and mux of a frame of this session to `dest`. */
static void session_msg(const co_usdo_client_session_t *ses, uint8_t dest, uint8_t cs,
                        co_usdo_msg_t *m)
{
    memset(m, 0, sizeof *m);
    m->dest = dest;
    m->cs = cs;
    m->session = ses->session_id;
    m->index = ses->req->index;
    m->sub = ses->req->sub;
    if (ses->req->network != 0) {
        /* remote: the server (a gateway) forwards it to (network, node) */
        m->remote = true;
        m->dst_net = ses->req->network;
        m->dst_node = ses->req->network_node;
        m->src_net = ses->req->source_network;
        m->src_node = ses->client->node_id;
    }
}

static void send_abort(co_usdo_client_session_t *ses, uint8_t dest, uint8_t code)
{
    co_usdo_msg_t m;
    session_msg(ses, dest, CO_USDO_CS_ABORT, &m);
    m.abort_code = code;
    ses->client->stats.aborts_sent++;
    (void)send_msg(ses->client, &m);
}

/* ------------------------------------------------------------ sessions */

static co_usdo_client_session_t *find(co_usdo_client_t *c, uint8_t node, uint8_t sid)
{
    uint8_t i;
    if (!sid_live(c, sid)) {
        return NULL;
    }
    for (i = 0; i < c->session_count; i++) {
        co_usdo_client_session_t *ses = &c->sessions[i];
        if (ses->state != CO_USDO_CLIENT_FREE && ses->session_id == sid) {
            /* session-IDs are unique among live sessions: this is the one */
            return (ses->req->server == CO_USDO_BROADCAST || ses->req->server == node) ? ses
                                                                                    : NULL;
        }
    }
    return NULL;
}

/* The live session running req, or NULL. */
static co_usdo_client_session_t *session_of(const co_usdo_client_t *c,
                                            const co_usdo_request_t *req)
{
    uint8_t i;
    for (i = 0; i < c->session_count; i++) {
        if (c->sessions[i].state != CO_USDO_CLIENT_FREE && c->sessions[i].req == req) {
            return &c->sessions[i];
        }
    }
    return NULL;
}

static void stop_waiting(co_usdo_client_session_t *ses)
{
    if (ses->wait_space) {
        ses->wait_space = false;
        ses->client->waiting--;
    }
}

/* A bulk upload gives its window back to the receive budget. */
static void stop_bulk_rx(co_usdo_client_session_t *ses)
{
    if (ses->bulk_rx) {
        ses->bulk_rx = false;
        ses->client->bulk_rx--;
    }
}

/* Free the session (timers, session-ID); the request stays untouched. */
static void release(co_usdo_client_session_t *ses)
{
    co_timer_cancel(timers_of(ses), &ses->timer);
    co_timer_cancel(timers_of(ses), &ses->pace);
    stop_waiting(ses);
    stop_bulk_rx(ses);
    sid_mark(ses->client, ses->session_id, false);
    ses->state = CO_USDO_CLIENT_FREE;
    ses->req = NULL;
}

static void report(co_usdo_client_t *c, co_usdo_request_t *req, uint8_t code, bool from_server)
{
    req->abort = code;
    req->abort_from_server = code != 0 && from_server;
    if (code == 0) {
        c->stats.completed++;
    } else {
        c->stats.failed++;
    }
    req->done(req);
}

/* End the request: the session is free before done() runs, so done() may
 * start new requests (this one included). Nothing may touch `ses` after. */
static void finish(co_usdo_client_session_t *ses, uint8_t code, bool from_server)
{
    co_usdo_client_t *c = ses->client;
    co_usdo_request_t *req = ses->req;
    release(ses);
    report(c, req, code, from_server);
}

/* Our own abort: sent to the server (broadcast: to all), then the end. */
static void fail(co_usdo_client_session_t *ses, uint8_t code)
{
    send_abort(ses, ses->req->server, code);
    finish(ses, code, false);
}

/* Still the same transfer after a callback into the application (which may
 * have cancelled it, and even started a new one on the same session)? */
static bool alive(const co_usdo_client_session_t *ses, uint32_t run)
{
    return ses->run == run && ses->state != CO_USDO_CLIENT_FREE;
}

/* ------------------------------------------------------------ data */

/* `want` bytes from the source at the current offset; false otherwise:
 * the transfer aborted 0x10, ended by the source itself, or (only where
 * `may_wait`: segmented downloads) the source said CO_USDO_SOURCE_LATER and
 * the session now waits for co_usdo_client_resume, its timeout stopped. */
static bool read_source(co_usdo_client_session_t *ses, uint8_t *buf, uint32_t want,
                        bool may_wait)
{
    co_usdo_request_t *req = ses->req;
    uint32_t run = ses->run;
    uint32_t got;
    if (want == 0) {
        return true;
    }
    got = req->source(req->ctx, ses->offset, buf, want);
    if (!alive(ses, run)) {
        return false;
    }
    if (got == CO_USDO_SOURCE_LATER && may_wait) {
        /* nothing is owed by the server now: its timeout must not run
         * while the caller's data is late (the caller resumes or cancels) */
        co_timer_cancel(timers_of(ses), &ses->timer);
        ses->state = CO_USDO_CLIENT_DL_WAIT_SOURCE;
        ses->client->stats.source_waits++;
        return false;
    }
    if (got != want) {
        ses->client->stats.source_failed++;
        fail(ses, CO_USDO_ABORT_UNKNOWN);
        return false;
    }
    return true;
}

/* Hand data to the sink; false when the transfer ended (refused, or ended
 * by the sink itself). */
static bool to_sink(co_usdo_client_session_t *ses, const uint8_t *data, uint32_t len)
{
    co_usdo_request_t *req = ses->req;
    uint32_t run = ses->run;
    uint8_t code = req->sink(req->ctx, ses->offset, data, len, ses->total);
    if (!alive(ses, run)) {
        return false;
    }
    if (code != 0) {
        ses->client->stats.sink_refused++;
        fail(ses, code);
        return false;
    }
    return true;
}

/* ------------------------------------------------------------ segmented */

/* Next 0x03 (more than 60 bytes left) or 0x04 (the rest, 0..60 bytes). A
 * refused send leaves the transfer to its timeout. */
static void send_download_segment(co_usdo_client_session_t *ses)
{
    co_usdo_request_t *req = ses->req;
    uint32_t left = req->size - ses->offset;
    uint8_t data[CO_USDO_SEGMENT_DATA];
    co_usdo_msg_t m;
    bool last = left <= CO_USDO_SEGMENT_DATA;
    uint32_t n = last ? left : CO_USDO_SEGMENT_DATA;
    if (!read_source(ses, data, n, true)) {
        return;
    }
    session_msg(ses, req->server, last ? CO_USDO_CS_DOWNLOAD_LAST : CO_USDO_CS_DOWNLOAD_SEGMENT,
                &m);
    m.counter = ses->counter;
    m.length = (uint8_t)n;
    m.data = data;
    (void)send_msg(ses->client, &m);
    ses->offset += n;
    req->transferred = ses->offset;
    ses->state = last ? CO_USDO_CLIENT_DL_LAST : CO_USDO_CLIENT_DL_SEG;
}

static void send_upload_segment_request(co_usdo_client_session_t *ses)
{
    co_usdo_msg_t m;
    session_msg(ses, ses->req->server, CO_USDO_CS_UPLOAD_SEGMENT, &m);
    m.counter = ses->counter;
    (void)send_msg(ses->client, &m);
}

/* ------------------------------------------------------------ bulk */

static void wait_space(co_usdo_client_session_t *ses)
{
    if (!ses->wait_space) {
        ses->wait_space = true;
        ses->client->waiting++;
        ses->client->stats.bulk_paused++;
    }
}

/* One bulk segment (0x07) or the last one (0x08). True while more follow. */
static bool bulk_send_segment(co_usdo_client_session_t *ses)
{
    co_usdo_request_t *req = ses->req;
    uint32_t left = req->size - ses->offset;
    uint8_t data[CO_USDO_SEGMENT_DATA];
    co_usdo_msg_t m;
    bool last = left <= CO_USDO_SEGMENT_DATA;
    uint32_t n = last ? left : CO_USDO_SEGMENT_DATA;
    if (!read_source(ses, data, n, false)) {   /* bulk streams: no waiting */
        return false;
    }
    session_msg(ses, req->server, last ? CO_USDO_CS_BULK_LAST : CO_USDO_CS_BULK_SEGMENT, &m);
    m.counter = ses->counter;
    m.length = (uint8_t)n;
    m.data = data;
    if (!send_msg(ses->client, &m)) {
        wait_space(ses);   /* room was checked: only a full queue gets here */
        return false;
    }
    ses->offset += n;
    req->transferred = ses->offset;
    if (last) {
        ses->state = CO_USDO_CLIENT_BULK_LAST;
        arm_timeout(ses);
        return false;
    }
    ses->counter = co_usdo_next_counter(ses->counter);
    return true;
}

/* Send one burst (paced: k segments; unpaced: CO_USDO_CLIENT_BULK_BURST),
 * then wait for the pace timer (unpaced: due at once, i.e. the next process
 * call) or the tx-space indication. Never loops longer than the queue has
 * room. */
static void bulk_run(co_usdo_client_session_t *ses)
{
    co_usdo_client_t *c = ses->client;
    uint64_t now = now_of(c);
    uint32_t budget = ses->period_us != 0 ? ses->burst : CO_USDO_CLIENT_BULK_BURST;
    if (ses->period_us != 0) {
        ses->next_at = now + ses->period_us;
    }
    while (budget > 0) {
        if (co_line_tx_room(c->line) == 0) {
            wait_space(ses);
            break;
        }
        if (!bulk_send_segment(ses)) {
            break;
        }
        budget--;
    }
    if (ses->state != CO_USDO_CLIENT_BULK_SEND) {
        return;   /* ended, or the last segment is out */
    }
    if (!ses->wait_space) {
        co_timer_start(timers_of(ses), &ses->pace, ses->next_at);
    }
    /* the server says nothing while we send: time without progress */
    arm_timeout_at(ses, ses->next_at > now ? ses->next_at : now);
}

static void on_pace(co_timer_t *timer, uint64_t now_us, void *user)
{
    co_usdo_client_session_t *ses = user;
    (void)timer;
    (void)now_us;
    if (ses->state == CO_USDO_CLIENT_BULK_SEND && !ses->wait_space) {
        bulk_run(ses);
    }
}

/* The tx queue drained to half (called from co_line_tx_pop, in the
 * driver's context): waiting sessions resume from the next process call,
 * a different one first each time. */
static void on_tx_space(co_line_t *line, void *user)
{
    co_usdo_client_t *c = user;
    uint8_t k;
    (void)line;
    if (c->waiting == 0) {
        return;
    }
    for (k = 0; k < c->session_count; k++) {
        co_usdo_client_session_t *ses = &c->sessions[(c->space_rr + k) % c->session_count];
        if (ses->wait_space) {
            uint64_t at = ses->next_at > now_of(c) ? ses->next_at : now_of(c);
            stop_waiting(ses);
            co_timer_start(timers_of(ses), &ses->pace, at);
        }
    }
    c->space_rr = (uint8_t)((c->space_rr + 1u) % c->session_count);
}

/* 0x26: the server's pacing (100 us units), capped; gaps below the timer
 * tick go out as bursts of k segments every k gaps. */
static void bulk_accepted(co_usdo_client_session_t *ses, uint16_t pacing)
{
    co_usdo_client_t *c = ses->client;
    uint32_t gap;
    ses->req->pacing = pacing;
    if (pacing > c->max_pacing) {
        pacing = c->max_pacing;
    }
    gap = (uint32_t)pacing * 100u;
    ses->period_us = 0;
    ses->burst = 0;
    if (gap >= CO_USDO_CLIENT_PACE_TICK_US) {
        ses->burst = 1;
        ses->period_us = gap;
    } else if (gap > 0) {
        ses->burst = (uint8_t)((CO_USDO_CLIENT_PACE_TICK_US + gap - 1u) / gap);
        ses->period_us = ses->burst * gap;
    }
    ses->next_at = now_of(c);
    ses->state = CO_USDO_CLIENT_BULK_SEND;
    bulk_run(ses);
}

/* ------------------------------------------------------------ starting */

co_usdo_mode_t co_usdo_client_choose_mode(uint8_t mode, uint32_t size)
{
    if (mode != CO_USDO_MODE_AUTO) {
        return (co_usdo_mode_t)mode;
    }
    if (size <= CO_USDO_EXPEDITED_MAX) {
        return CO_USDO_MODE_EXPEDITED;
    }
    return size < CO_USDO_CLIENT_BULK_THRESHOLD ? CO_USDO_MODE_SEGMENTED : CO_USDO_MODE_BULK;
}

co_usdo_mode_t co_usdo_client_choose_upload_mode(uint8_t mode, uint32_t size_hint)
{
    if (mode == CO_USDO_MODE_BULK ||
        (mode == CO_USDO_MODE_AUTO && size_hint >= CO_USDO_CLIENT_BULK_THRESHOLD)) {
        return CO_USDO_MODE_BULK;
    }
    return CO_USDO_MODE_AUTO;
}

/* Whether one more bulk upload's window fits in the receive budget. */
static bool bulk_rx_fits(const co_usdo_client_t *c)
{
    return ((uint32_t)c->bulk_rx + 1u) * c->bulk_window <= c->bulk_budget;
}

/* The first frame of the transfer in `ses->mode` (`data`: an expedited
 * download's bytes, read before); 0 or why it did not go. */
static uint8_t send_first(co_usdo_client_session_t *ses, const uint8_t *data)
{
    co_usdo_request_t *req = ses->req;
    co_usdo_msg_t m;
    uint8_t type = req->type != 0 ? req->type : (uint8_t)TYPE_DOMAIN;
    if (req->upload && ses->mode == CO_USDO_MODE_BULK) {
        session_msg(ses, req->server, CO_USDO_CS_BULK_UPLOAD, &m);
        m.window = ses->client->bulk_window;
        ses->state = CO_USDO_CLIENT_UL_BULK_INIT;
        ses->bulk_rx = true;
        ses->client->bulk_rx++;
    } else if (req->upload) {
        session_msg(ses, req->server, CO_USDO_CS_UPLOAD, &m);
        ses->state = is_broadcast(ses) ? CO_USDO_CLIENT_BROADCAST : CO_USDO_CLIENT_UL_INIT;
    } else if (ses->mode == CO_USDO_MODE_EXPEDITED) {
        session_msg(ses, req->server, CO_USDO_CS_DOWNLOAD_EXPEDITED, &m);
        m.type = type;
        m.length = (uint8_t)req->size;
        m.data = data;
        ses->state = is_broadcast(ses) ? CO_USDO_CLIENT_BROADCAST : CO_USDO_CLIENT_DL_EXPEDITED;
    } else {
        bool bulk = ses->mode == CO_USDO_MODE_BULK;
        session_msg(ses, req->server,
                    bulk ? CO_USDO_CS_BULK_INITIATE : CO_USDO_CS_DOWNLOAD_INITIATE, &m);
        m.type = type;
        m.size = req->size;
        ses->state = bulk ? CO_USDO_CLIENT_BULK_INIT : CO_USDO_CLIENT_DL_INIT;
    }
    if (!send_msg(ses->client, &m)) {
        return CO_USDO_ABORT_BUSY;
    }
    if (!req->upload && ses->mode == CO_USDO_MODE_EXPEDITED) {
        req->transferred = req->size;   /* all of it is in the request */
    }
    arm_timeout(ses);
    return 0;
}

/* AUTO: the server has no bulk (0x13 to 0x06 / 0x16): once more, segmented
 * (a download) or as a plain upload (0x11), with a fresh session-ID (a late
 * frame of the refused attempt then meets none). */
static void fall_back_from_bulk(co_usdo_client_session_t *ses)
{
    co_usdo_client_t *c = ses->client;
    co_usdo_mode_t mode = ses->req->upload ? CO_USDO_MODE_AUTO : CO_USDO_MODE_SEGMENTED;
    c->stats.bulk_fallback++;
    stop_bulk_rx(ses);
    sid_mark(c, ses->session_id, false);
    ses->session_id = sid_next(c);
    ses->req->session_id = ses->session_id;
    ses->mode = (uint8_t)mode;
    ses->req->result_mode = (uint8_t)mode;
    ses->offset = 0;
    ses->counter = 0;
    ses->req->transferred = 0;
    /* a refused send is left to the timeout, like any lost frame */
    if (send_first(ses, NULL) != 0) {
        arm_timeout(ses);
    }
}

static bool running(const co_usdo_client_t *c, const co_usdo_request_t *req)
{
    return session_of(c, req) != NULL;
}

/* Why a request cannot start (0 = it can). */
/* Remote downloads: AUTO is expedited up to 52 bytes (the extension takes
 * 4 of the 56), segmented above; bulk is not routed (refused). */
static co_usdo_mode_t download_mode(const co_usdo_request_t *req)
{
    if (req->network != 0 && req->mode == CO_USDO_MODE_AUTO) {
        return req->size <= CO_USDO_REMOTE_EXPEDITED_MAX ? CO_USDO_MODE_EXPEDITED
                                                         : CO_USDO_MODE_SEGMENTED;
    }
    return co_usdo_client_choose_mode(req->mode, req->size);
}

static uint8_t check_request(const co_usdo_client_t *c, const co_usdo_request_t *req)
{
    co_usdo_mode_t mode;
    if (c->line == NULL || req == NULL || req->done == NULL || req->server > NODE_MAX ||
        req->server == c->node_id || running(c, req)) {
        return CO_USDO_ABORT_UNKNOWN;
    }
    if (req->network != 0 &&
        (req->network > NODE_MAX || req->network_node < 1 || req->network_node > NODE_MAX ||
         req->server == CO_USDO_BROADCAST || req->mode == CO_USDO_MODE_BULK)) {
        return CO_USDO_ABORT_UNKNOWN;   /* remote: one node through one gateway, no bulk */
    }
    if (req->upload) {
        if (req->mode > CO_USDO_MODE_BULK ||
            (req->server == CO_USDO_BROADCAST && req->mode == CO_USDO_MODE_BULK)) {
            return CO_USDO_ABORT_UNKNOWN;   /* a broadcast collects expedited answers */
        }
        return (req->server != CO_USDO_BROADCAST && req->sink == NULL) ? CO_USDO_ABORT_UNKNOWN
                                                                        : 0;
    }
    if (req->mode > CO_USDO_MODE_BULK || req->size > CO_USDO_CLIENT_SIZE_MAX ||
        (req->size > 0 && req->source == NULL)) {
        return CO_USDO_ABORT_UNKNOWN;
    }
    mode = download_mode(req);
    if ((mode == CO_USDO_MODE_EXPEDITED || req->server == CO_USDO_BROADCAST) &&
        req->size > (req->network != 0 ? CO_USDO_REMOTE_EXPEDITED_MAX : CO_USDO_EXPEDITED_MAX)) {
        return CO_USDO_ABORT_DLC;
    }
    if (req->server == CO_USDO_BROADCAST && mode != CO_USDO_MODE_EXPEDITED) {
        return CO_USDO_ABORT_UNKNOWN;   /* broadcast downloads are expedited only */
    }
    return 0;
}

static co_usdo_client_session_t *free_session(co_usdo_client_t *c)
{
    uint8_t i;
    for (i = 0; i < c->session_count; i++) {
        if (c->sessions[i].state == CO_USDO_CLIENT_FREE) {
            return &c->sessions[i];
        }
    }
    return NULL;
}

/* Take a free session for req and send the first frame; 0 or why not. */
static uint8_t open_session(co_usdo_client_t *c, co_usdo_request_t *req, const uint8_t *data)
{
    co_usdo_client_session_t *ses = free_session(c);
    uint8_t code;
    co_usdo_mode_t mode;
    if (ses == NULL) {
        return CO_USDO_ABORT_BUSY;
    }
    mode = req->upload ? co_usdo_client_choose_upload_mode(req->mode, req->size)
                       : download_mode(req);
    if (req->upload && req->network != 0) {
        mode = CO_USDO_MODE_AUTO;   /* remote: a plain upload (0x91) */
    }
    if (req->upload && mode == CO_USDO_MODE_BULK &&
        (req->server == CO_USDO_BROADCAST || !bulk_rx_fits(c))) {
        if (req->mode == CO_USDO_MODE_BULK) {
            c->stats.bulk_budget_full++;
            return CO_USDO_ABORT_BUSY;   /* nothing taken: the session stays as it was */
        }
        if (req->server != CO_USDO_BROADCAST) {
            c->stats.bulk_budget_full++;
        }
        mode = CO_USDO_MODE_AUTO;   /* AUTO: a plain upload, the server picks */
    }
    ses->req = req;
    ses->run++;
    ses->mode = (uint8_t)mode;
    ses->offset = 0;
    ses->total = 0;
    ses->counter = 0;
    ses->period_us = 0;
    ses->burst = 0;
    ses->next_at = 0;
    ses->wait_space = false;
    ses->bulk_rx = false;
    ses->since_ack = 0;
    memset(ses->answered, 0, sizeof ses->answered);
    ses->session_id = sid_next(c);
    req->abort = 0;
    req->abort_from_server = false;
    req->result_type = 0;
    req->result_mode = ses->mode;
    req->session_id = ses->session_id;
    req->pacing = 0;
    req->transferred = 0;
    req->answers = 0;
    ses->state = CO_USDO_CLIENT_UL_INIT;   /* taken; send_first sets the real state */
    code = ses->session_id == 0 ? (uint8_t)CO_USDO_ABORT_BUSY : send_first(ses, data);
    if (code != 0) {
        release(ses);
    }
    return code;
}

uint8_t co_usdo_client_start(co_usdo_client_t *c, co_usdo_request_t *req)
{
    uint8_t data[CO_USDO_EXPEDITED_MAX];
    uint8_t code;
    if (c == NULL) {
        return CO_USDO_ABORT_UNKNOWN;
    }
    code = check_request(c, req);
    if (code == 0 && !req->upload && req->size > 0 &&
        download_mode(req) == CO_USDO_MODE_EXPEDITED) {
        /* read before anything changes here (the source may call into the
         * client), so a failing source refuses the start and sends nothing */
        if (req->source(req->ctx, 0, data, req->size) != req->size) {
            c->stats.source_failed++;
            code = CO_USDO_ABORT_UNKNOWN;
        } else {
            code = check_request(c, req);
        }
    }
    if (code == 0) {
        code = open_session(c, req, data);
    }
    if (code != 0) {
        c->stats.refused++;
        return code;
    }
    c->stats.started++;
    return 0;
}

/* ------------------------------------------------------------ receiving */

static bool expected(uint8_t state, uint8_t cs)
{
    switch (state) {
    case CO_USDO_CLIENT_DL_EXPEDITED:
        return cs == CO_USDO_CS_DOWNLOAD_EXPEDITED_RSP;
    case CO_USDO_CLIENT_UL_INIT:
        return cs == CO_USDO_CS_UPLOAD_EXPEDITED_RSP || cs == CO_USDO_CS_UPLOAD_INITIATE_RSP;
    case CO_USDO_CLIENT_DL_INIT:
        return cs == CO_USDO_CS_DOWNLOAD_INITIATE_RSP;
    case CO_USDO_CLIENT_DL_SEG:
        return cs == CO_USDO_CS_DOWNLOAD_SEGMENT_RSP;
    case CO_USDO_CLIENT_DL_LAST:
        return cs == CO_USDO_CS_DOWNLOAD_LAST_RSP;
    case CO_USDO_CLIENT_UL_SEG:
        return cs == CO_USDO_CS_UPLOAD_SEGMENT_RSP || cs == CO_USDO_CS_UPLOAD_LAST_RSP;
    case CO_USDO_CLIENT_BULK_INIT:
        return cs == CO_USDO_CS_BULK_INITIATE_RSP;
    case CO_USDO_CLIENT_BULK_LAST:
        return cs == CO_USDO_CS_BULK_LAST_RSP;
    case CO_USDO_CLIENT_UL_BULK_INIT:   /* a server may answer a bulk request plainly */
        return cs == CO_USDO_CS_BULK_UPLOAD_INITIATE_RSP ||
               cs == CO_USDO_CS_UPLOAD_EXPEDITED_RSP || cs == CO_USDO_CS_UPLOAD_INITIATE_RSP;
    case CO_USDO_CLIENT_UL_BULK:
        return cs == CO_USDO_CS_BULK_UPLOAD_SEGMENT_RSP || cs == CO_USDO_CS_BULK_UPLOAD_LAST_RSP;
    default:   /* BULK_SEND, DL_WAIT_SOURCE: only an abort */
        return false;
    }
}

static bool mux_matches(const co_usdo_client_session_t *ses, const co_usdo_msg_t *m)
{
    return !co_usdo_layout_has_mux(co_usdo_layout_of(m->cs)) ||
           (m->index == ses->req->index && m->sub == ses->req->sub);
}

/* 0x31 unicast: announce, deliver, done. */
static void on_upload_expedited(co_usdo_client_session_t *ses, const co_usdo_msg_t *m)
{
    ses->req->result_type = m->type;
    ses->total = m->length;
    if (!to_sink(ses, NULL, 0)) {
        return;
    }
    if (m->length > 0 && !to_sink(ses, m->data, m->length)) {
        return;
    }
    ses->offset = m->length;
    ses->req->transferred = m->length;
    finish(ses, 0, false);
}

/* 0x32: announce the size, ask for segment 0. */
static void on_upload_initiate(co_usdo_client_session_t *ses, const co_usdo_msg_t *m)
{
    ses->req->result_type = m->type;
    ses->total = m->size;
    if (!to_sink(ses, NULL, 0)) {
        return;
    }
    ses->state = CO_USDO_CLIENT_UL_SEG;
    ses->counter = 0;
    send_upload_segment_request(ses);
}

/* 0x36: announce the size; the server streams from now on. */
static void on_bulk_upload_initiate(co_usdo_client_session_t *ses, const co_usdo_msg_t *m)
{
    ses->req->result_type = m->type;
    ses->total = m->size;
    if (!to_sink(ses, NULL, 0)) {
        return;
    }
    ses->state = CO_USDO_CLIENT_UL_BULK;
    ses->counter = 0;
    ses->since_ack = 0;
    ses->short_seen = false;
    ses->taken = 0;
    ses->acked = 0;
}

/* Whether the server's credit already covers the rest of a known size (in
 * full 60-byte segments and one last one): then no acknowledgement is
 * needed any more, and one sent would only cross the end. Not assumed once
 * a short segment came (the rest may need more segments). */
static bool credit_covers_rest(const co_usdo_client_session_t *ses)
{
    uint32_t credit = ses->acked + ses->client->bulk_window - ses->taken;
    uint32_t rest;
    if (ses->total == SIZE_UNKNOWN || ses->short_seen) {
        return false;
    }
    rest = ses->total - ses->offset;
    return (rest == 0 ? 1u : (rest + CO_USDO_SEGMENT_DATA - 1u) / CO_USDO_SEGMENT_DATA) <= credit;
}

/* 0x17 every half window (at least every segment for a window of 1): the
 * server may then send a window beyond the segment just taken; none once
 * its credit covers the rest of a known size. */
static void bulk_upload_taken(co_usdo_client_session_t *ses, uint8_t counter)
{
    co_usdo_client_t *c = ses->client;
    uint8_t every = (uint8_t)((c->bulk_window + 1u) / 2u);
    ses->since_ack++;
    ses->taken++;
    if (ses->since_ack >= every && !credit_covers_rest(ses)) {
        co_usdo_msg_t m;
        session_msg(ses, ses->req->server, CO_USDO_CS_BULK_UPLOAD_ACK, &m);
        m.counter = counter;
        ses->since_ack = 0;
        ses->acked = ses->taken;
        c->stats.acks_sent++;
        /* a lost or refused ack leaves the server waiting: both time out */
        (void)send_msg(c, &m);
    }
}

/* 0x33 / 0x34 (segmented) and 0x37 / 0x38 (bulk): counter, size against the
 * announcement, then the sink; then ask for the next segment (segmented)
 * or acknowledge now and then (bulk). */
static void on_upload_segment(co_usdo_client_session_t *ses, const co_usdo_msg_t *m)
{
    co_usdo_client_t *c = ses->client;
    bool bulk = m->cs == CO_USDO_CS_BULK_UPLOAD_SEGMENT_RSP ||
                m->cs == CO_USDO_CS_BULK_UPLOAD_LAST_RSP;
    bool last = m->cs == CO_USDO_CS_UPLOAD_LAST_RSP || m->cs == CO_USDO_CS_BULK_UPLOAD_LAST_RSP;
    uint8_t counter = m->counter;
    if (!last && co_usdo_short_segment(m)) {
        c->stats.rx_short_segment++;   /* a server with a smaller MTU: taken */
        ses->short_seen = true;
    }
    uint32_t room = ses->total == SIZE_UNKNOWN ? SIZE_UNKNOWN - ses->offset
                                               : ses->total - ses->offset;
    if (!last && m->counter != ses->counter) {
        c->stats.rx_bad_counter++;
        fail(ses, CO_USDO_ABORT_COUNTER);
        return;
    }
    if (m->length > room ||
        (last && ses->total != SIZE_UNKNOWN && m->length != room)) {
        c->stats.rx_size_mismatch++;
        fail(ses, CO_USDO_ABORT_DATA_SIZE);
        return;
    }
    if (m->length > 0 && !to_sink(ses, m->data, m->length)) {
        return;
    }
    ses->offset += m->length;
    ses->req->transferred = ses->offset;
    if (last) {
        if (bulk) {
            c->stats.bulk_uploads++;
        }
        finish(ses, 0, false);
        return;
    }
    ses->counter = co_usdo_next_counter(ses->counter);
    if (bulk) {
        bulk_upload_taken(ses, counter);
    } else {
        send_upload_segment_request(ses);
    }
}

/* An answer (or abort) of one server to a broadcast request: reported once
 * per server. A segmented upload answer (0x32) is refused with 0x13: the
 * broadcast collects expedited answers only. */
static void on_broadcast_answer(co_usdo_client_session_t *ses, uint8_t node,
                                co_usdo_decode_result_t r, const co_usdo_msg_t *m)
{
    co_usdo_client_t *c = ses->client;
    co_usdo_request_t *req = ses->req;
    uint8_t code = 0, type = 0;
    const uint8_t *data = NULL;
    uint32_t len = 0;
    bool takes = req->upload ? (m->cs == CO_USDO_CS_UPLOAD_EXPEDITED_RSP ||
                                m->cs == CO_USDO_CS_UPLOAD_INITIATE_RSP)
                             : m->cs == CO_USDO_CS_DOWNLOAD_EXPEDITED_RSP;
    if (co_bit32_test(ses->answered, node)) {
        c->stats.rx_duplicate++;
        return;
    }
    if (m->cs == CO_USDO_CS_ABORT) {
        c->stats.aborts_received++;
        if (r != CO_USDO_DECODE_OK) {
            c->stats.rx_malformed++;
        }
        code = (r == CO_USDO_DECODE_OK && m->abort_code != 0) ? m->abort_code
                                                              : (uint8_t)CO_USDO_ABORT_UNKNOWN;
    } else if (!takes) {
        c->stats.rx_unexpected++;
        return;
    } else if (r != CO_USDO_DECODE_OK) {
        c->stats.rx_malformed++;
        code = CO_USDO_ABORT_DLC;
    } else if (!mux_matches(ses, m)) {
        c->stats.rx_bad_mux++;
        code = CO_USDO_ABORT_MULTIPLEXER;
    } else if (m->cs == CO_USDO_CS_UPLOAD_INITIATE_RSP) {
        code = CO_USDO_ABORT_COMMAND;
    } else if (m->cs == CO_USDO_CS_UPLOAD_EXPEDITED_RSP) {
        type = m->type;
        data = m->data;
        len = m->length;
    }
    if (m->cs == CO_USDO_CS_UPLOAD_INITIATE_RSP) {
        send_abort(ses, node, code);   /* that server holds an open upload */
    }
    co_bit32_put(ses->answered, node, true);
    req->answers++;
    if (req->answer != NULL) {
        req->answer(req, node, code, type, data, len);   /* last use of ses */
    }
}

/* A server's abort. AUTO bulk refused as unknown: retry segmented. */
static void on_server_abort(co_usdo_client_session_t *ses, uint8_t code)
{
    if ((ses->state == CO_USDO_CLIENT_BULK_INIT || ses->state == CO_USDO_CLIENT_UL_BULK_INIT) &&
        ses->req->mode == CO_USDO_MODE_AUTO && code == CO_USDO_ABORT_COMMAND) {
        fall_back_from_bulk(ses);
        return;
    }
    finish(ses, code, true);
}

static void on_frame(co_line_t *line, const co_frame_t *f, void *user)
{
    co_usdo_client_t *c = user;
    co_usdo_client_session_t *ses;
    co_usdo_msg_t m;
    uint8_t node = (uint8_t)(f->id - CO_USDO_RESPONSE_BASE);   /* 1..127 by the subscription */
    co_usdo_decode_result_t r;
    (void)line;
    c->stats.rx_frames++;
    if (!(f->flags & CO_FRAME_FD)) {
        c->stats.rx_not_fd++;
        return;
    }
    r = co_usdo_decode(f->data, f->len, &m);
    if (r == CO_USDO_DECODE_EMPTY) {
        c->stats.rx_malformed++;
        return;
    }
    if (m.dest != c->node_id) {
        c->stats.rx_other_dest++;
        return;
    }
    ses = find(c, node, m.session);
    if (ses == NULL) {
        c->stats.rx_no_session++;
        return;
    }
    if (m.remote != (ses->req->network != 0) ||
        (m.remote && co_usdo_layout_has_mux(co_usdo_layout_of(m.cs)) &&
         r != CO_USDO_DECODE_SHORT &&
         (m.src_net != ses->req->network || m.src_node != ses->req->network_node ||
          m.dst_node != c->node_id))) {
        /* a local answer to a routed request (or the reverse), or a routed
         * answer from another node than the one asked */
        c->stats.rx_unexpected++;
        return;
    }
    if (ses->state == CO_USDO_CLIENT_BROADCAST) {
        on_broadcast_answer(ses, node, r, &m);
        return;
    }
    if (m.cs == CO_USDO_CS_ABORT) {
        c->stats.aborts_received++;
        if (r != CO_USDO_DECODE_OK) {
            c->stats.rx_malformed++;
        }
        on_server_abort(ses, (r == CO_USDO_DECODE_OK && m.abort_code != 0)
                                 ? m.abort_code
                                 : (uint8_t)CO_USDO_ABORT_UNKNOWN);
        return;
    }
    if (!expected(ses->state, m.cs)) {
        c->stats.rx_unexpected++;   /* incl. unknown commands: the timeout still runs */
        return;
    }
    if (r != CO_USDO_DECODE_OK) {
        c->stats.rx_malformed++;
        fail(ses, CO_USDO_ABORT_DLC);
        return;
    }
    if (!mux_matches(ses, &m)) {
        c->stats.rx_bad_mux++;
        fail(ses, CO_USDO_ABORT_MULTIPLEXER);
        return;
    }
    arm_timeout(ses);
    switch (m.cs) {
    case CO_USDO_CS_DOWNLOAD_EXPEDITED_RSP:
    case CO_USDO_CS_DOWNLOAD_LAST_RSP:
    case CO_USDO_CS_BULK_LAST_RSP:
        finish(ses, 0, false);
        break;
    case CO_USDO_CS_UPLOAD_EXPEDITED_RSP:
        ses->req->result_mode = CO_USDO_MODE_EXPEDITED;   /* the server chose */
        stop_bulk_rx(ses);
        on_upload_expedited(ses, &m);
        break;
    case CO_USDO_CS_UPLOAD_INITIATE_RSP:
        ses->req->result_mode = CO_USDO_MODE_SEGMENTED;
        stop_bulk_rx(ses);
        on_upload_initiate(ses, &m);
        break;
    case CO_USDO_CS_BULK_UPLOAD_INITIATE_RSP:
        ses->req->result_mode = CO_USDO_MODE_BULK;
        on_bulk_upload_initiate(ses, &m);
        break;
    case CO_USDO_CS_UPLOAD_SEGMENT_RSP:
    case CO_USDO_CS_UPLOAD_LAST_RSP:
    case CO_USDO_CS_BULK_UPLOAD_SEGMENT_RSP:
    case CO_USDO_CS_BULK_UPLOAD_LAST_RSP:
        on_upload_segment(ses, &m);
        break;
    case CO_USDO_CS_DOWNLOAD_INITIATE_RSP:
        send_download_segment(ses);
        break;
    case CO_USDO_CS_DOWNLOAD_SEGMENT_RSP:
        if (m.counter != ses->counter) {
            c->stats.rx_bad_counter++;
            fail(ses, CO_USDO_ABORT_COUNTER);
            break;
        }
        ses->counter = co_usdo_next_counter(ses->counter);
        send_download_segment(ses);
        break;
    default: /* CO_USDO_CS_BULK_INITIATE_RSP */
        bulk_accepted(ses, m.pacing);
        break;
    }
}

/* Per-frame timeout; for a broadcast the end of the collection window. */
static void on_timeout(co_timer_t *timer, uint64_t now_us, void *user)
{
    co_usdo_client_session_t *ses = user;
    (void)timer;
    (void)now_us;
    if (ses->state == CO_USDO_CLIENT_BROADCAST) {
        finish(ses, 0, false);
        return;
    }
    ses->client->stats.timeouts++;
    fail(ses, CO_USDO_ABORT_TIMEOUT);
}

/* ------------------------------------------------------------ API */

bool co_usdo_client_init(co_usdo_client_t *c, co_line_t *line, const co_usdo_client_config_t *cfg)
{
    uint8_t i;
    if (c == NULL || line == NULL || cfg == NULL || cfg->sessions == NULL ||
        cfg->session_count == 0 || cfg->node_id == 0 || cfg->node_id > NODE_MAX ||
        co_line_mode(line) != CO_MODE_FD) {
        return false;
    }
    memset(c, 0, sizeof *c);
    c->sessions = cfg->sessions;
    c->session_count = cfg->session_count;
    c->node_id = cfg->node_id;
    c->next_sid = 1;
    c->timeout_us = (uint64_t)(cfg->timeout_ms != 0 ? cfg->timeout_ms
                                                    : CO_USDO_CLIENT_DEFAULT_TIMEOUT_MS) *
                    1000u;
    c->max_pacing = cfg->max_pacing != 0 ? cfg->max_pacing
                                         : (uint16_t)CO_USDO_CLIENT_DEFAULT_MAX_PACING;
    /* bulk upload: a window of at most a quarter of the receive queue, all
     * windows together at most half of it (the rest for other traffic) */
    {
        uint32_t rx = line->rx.capacity;
        uint32_t window = cfg->bulk_window != 0 ? cfg->bulk_window
                                                : (uint32_t)CO_USDO_CLIENT_DEFAULT_BULK_WINDOW;
        if (window > rx / 4u) {
            window = rx / 4u;
        }
        c->bulk_window = (uint8_t)(window != 0 ? window : 1u);
        c->bulk_budget = rx / 2u > c->bulk_window ? rx / 2u : c->bulk_window;
    }
    for (i = 0; i < cfg->session_count; i++) {
        co_usdo_client_session_t *ses = &cfg->sessions[i];
        memset(ses, 0, sizeof *ses);
        ses->client = c;
        co_timer_init(&ses->timer, on_timeout, ses);
        co_timer_init(&ses->pace, on_pace, ses);
    }
    if (!co_line_subscribe(line, CO_USDO_RESPONSE_BASE + 1u, CO_USDO_RESPONSE_BASE + NODE_MAX,
                           on_frame, c)) {
        return false;
    }
    if (!co_line_tx_space_register(line, on_tx_space, c)) {
        co_line_unsubscribe(line, on_frame, c);
        return false;
    }
    c->line = line;
    return true;
}

void co_usdo_client_deinit(co_usdo_client_t *c)
{
    uint8_t i;
    if (c == NULL || c->line == NULL) {
        return;
    }
    co_line_unsubscribe(c->line, on_frame, c);
    co_line_tx_space_unregister(c->line, on_tx_space, c);
    /* free every session first (the request is kept for the report), then
     * report with the line gone, so a done() cannot start anything */
    for (i = 0; i < c->session_count; i++) {
        co_usdo_client_session_t *ses = &c->sessions[i];
        if (ses->state != CO_USDO_CLIENT_FREE) {
            co_usdo_request_t *req = ses->req;
            release(ses);
            ses->req = req;
        }
    }
    c->line = NULL;
    for (i = 0; i < c->session_count; i++) {
        co_usdo_client_session_t *ses = &c->sessions[i];
        if (ses->req != NULL) {
            co_usdo_request_t *req = ses->req;
            ses->req = NULL;
            report(c, req, CO_USDO_ABORT_UNKNOWN, false);
        }
    }
}

bool co_usdo_client_cancel(co_usdo_client_t *c, co_usdo_request_t *req, uint8_t code)
{
    co_usdo_client_session_t *ses;
    if (c == NULL || c->line == NULL || req == NULL) {
        return false;
    }
    ses = session_of(c, req);
    if (ses == NULL) {
        return false;
    }
    c->stats.cancelled++;
    fail(ses, code != 0 ? code : (uint8_t)CO_USDO_ABORT_UNKNOWN);
    return true;
}

uint8_t co_usdo_client_resume(co_usdo_client_t *c, co_usdo_request_t *req)
{
    co_usdo_client_session_t *ses;
    if (c == NULL || c->line == NULL || req == NULL) {
        return CO_USDO_ABORT_UNKNOWN;
    }
    ses = session_of(c, req);
    if (ses == NULL) {
        return CO_USDO_ABORT_UNKNOWN;
    }
    if (ses->state != CO_USDO_CLIENT_DL_WAIT_SOURCE) {
        return CO_USDO_CLIENT_NOT_WAITING;   /* e.g. an answer still due */
    }
    /* out of the waiting state before the source runs: a resume from
     * inside the source is then a no-op, not a second send */
    ses->state = CO_USDO_CLIENT_DL_SEG;
    arm_timeout(ses);
    send_download_segment(ses);
    return 0;
}

uint8_t co_usdo_client_active(const co_usdo_client_t *c)
{
    uint8_t i, n = 0;
    for (i = 0; i < c->session_count; i++) {
        if (c->sessions[i].state != CO_USDO_CLIENT_FREE) {
            n++;
        }
    }
    return n;
}

bool co_usdo_client_running(const co_usdo_client_t *c, const co_usdo_request_t *req)
{
    return c != NULL && req != NULL && running(c, req);
}

/* ------------------------------------------------------------ buffers */

uint32_t co_usdo_buffer_source(void *ctx, uint32_t offset, uint8_t *buf, uint32_t want)
{
    return co_buffer_read(ctx, offset, buf, want);
}

uint8_t co_usdo_buffer_sink(void *ctx, uint32_t offset, const uint8_t *data, uint32_t len,
                            uint32_t total)
{
    bool known = total != SIZE_UNKNOWN;
    return co_buffer_put(ctx, offset, data, len, total, known) ? 0u : CO_USDO_ABORT_OUT_OF_MEMORY;
}
