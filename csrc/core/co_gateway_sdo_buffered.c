/* co_gateway SDO networking, buffered: the gateway is the SDO server the
 * client talks to and moves the value with its own client on the target
 * line, one whole transfer at a time. Two kinds of target use it:
 *
 *   a node of an attached fd line: always (classic SDO frames cannot be
 *             relayed to a USDO server); the fd line's USDO client moves
 *             the value;
 *   a node of an attached classic line: uploads, when the buffer and the
 *             line's SDO client are idle (else relayed, co_gateway_sdo.c):
 *             the client's segment requests are served from the buffer
 *             while the gateway's own client reads ahead, so the two hops
 *             run side by side instead of one frame after the other (a
 *             relay doubles every segment's round trip). Downloads to a
 *             classic target: co_gateway_sdo_pipe.c.
 *
 *   download  (fd targets) expedited: the 1..4 bytes go out at once;
 *             segmented: the segments are collected in the gateway's buffer
 *             (each answered at once), the last one is answered only when
 *             the download of the whole value to the target has ended;
 *   upload    the initiate starts an upload into the buffer. As soon as
 *             the target has announced a size above 4 bytes the initiate is
 *             answered with it and the client's segment requests are served
 *             from the buffer while the data still arrives (a request the
 *             data has not reached yet waits for it; the last one waits for
 *             the end of the target's transfer), so the client never waits
 *             for the whole value. 1..4 bytes (expedited answer) and a size
 *             the target does not announce wait for the end of the transfer.
 *
 * Aborts pass both ways (USDO codes mapped: co_usdo_abort_from_co / _to_co);
 * a target transfer that times out reaches the client as 0x05040000, a
 * client silent in the middle of a segmented transfer is aborted with
 * 0x05040000 after the gateway's SDO timeout. Block transfers into an fd
 * network are refused with 0x05040001 (a client then goes segmented).
 * Choices: docs/protocol-notes.md "Gateway". */
#include "canopenfd/co_gateway.h"

#include <string.h>

enum xstate {
    X_IDLE = 0,
    X_DL_SEG,     /* segmented download: segments expected from the client */
    X_DL_WAIT,    /* the USDO download runs: the client's answer waits */
    X_UL_WAIT,    /* the USDO upload runs: the initiate's answer waits */
    X_UL_SEG      /* segmented upload: segment requests expected */
};

enum { FRAME = 8, SEG_DATA = 7, RESPONSE_BASE = 0x580, REQUEST_BASE = 0x600 };

static co_line_t *client_line(const co_gateway_sdo_t *c)
{
    return co_stack_line(c->from->stack);
}

static void send_client(co_gateway_sdo_t *c, const uint8_t *f)
{
    c->gw->stats.sdo_answers++;
    if (!co_line_send(client_line(c), c->reply_id, f, FRAME)) {
        c->gw->stats.sdo_tx_failed++;
    }
}

static void abort_client(co_gateway_sdo_t *c, uint32_t code)
{
    uint8_t f[FRAME] = {0x80, c->mux[0], c->mux[1], c->mux[2], (uint8_t)code,
                        (uint8_t)(code >> 8), (uint8_t)(code >> 16), (uint8_t)(code >> 24)};
    send_client(c, f);
}

static uint32_t get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

/* Idle timer of the client side (segments expected). */
static void arm(co_gateway_sdo_t *c)
{
    co_line_t *line = client_line(c);
    uint64_t us = c->gw->sdo_timeout_us != 0 ? c->gw->sdo_timeout_us
                                             : (uint64_t)CO_GATEWAY_SDO_TIMEOUT_MS * 1000u;
    co_timer_start(co_line_timers(line), &c->xtimer, co_line_now(line) + us);
}

/* The transfer ends (the connection stays): timer off, buffer given back. */
static void finish(co_gateway_sdo_t *c)
{
    co_timer_cancel(co_line_timers(client_line(c)), &c->xtimer);
    if (c->gw->sdo_buf_owner == c) {
        c->gw->sdo_buf_owner = NULL;
    }
    c->xstate = X_IDLE;
    c->seg_pending = false;
}

/* Stop the target's running transfer with the client's code (mapped for USDO). */
static void cancel_fetch(co_gateway_sdo_t *c, uint32_t co_code)
{
    c->xstate = X_IDLE;   /* fetched() below finds nothing to answer */
    c->fetch_running = false;
    if (c->fd) {
        co_usdo_client_t *uc = co_stack_usdo_client(c->to->stack);
        if (uc != NULL && co_usdo_client_running(uc, &c->fetch.usdo)) {
            uint8_t code = co_usdo_abort_from_co(co_code);
            (void)co_usdo_client_cancel(uc, &c->fetch.usdo, code ? code : CO_USDO_ABORT_UNKNOWN);
        }
        return;
    }
    co_sdo_client_t *sc = co_stack_sdo_client(c->to->stack);
    if (sc != NULL && co_sdo_client_running(sc, &c->fetch.sdo)) {
        (void)co_sdo_client_cancel(sc, &c->fetch.sdo, co_code);
    }
}

/* The transfer fails: the client hears `code`, a USDO transfer still
 * running is stopped with the same code (mapped). */
static void fail(co_gateway_sdo_t *c, uint32_t code)
{
    if (c->fetch_running) {
        cancel_fetch(c, code);
    }
    c->gw->stats.sdo_translate_failed++;
    abort_client(c, code);
    finish(c);
}

static void on_timeout(co_timer_t *timer, uint64_t now_us, void *user)
{
    co_gateway_sdo_t *c = user;
    (void)timer;
    (void)now_us;
    c->gw->stats.sdo_timeouts++;
    fail(c, CO_ABORT_TIMEOUT);
}

static bool take_buffer(co_gateway_sdo_t *c, uint32_t need)
{
    co_gateway_t *gw = c->gw;
    if (gw->sdo_buf_owner != NULL && gw->sdo_buf_owner != c) {
        gw->stats.sdo_buffer_busy++;
        fail(c, CO_ABORT_NO_RESOURCE);
        return false;
    }
    if (gw->sdo_buf == NULL || need > gw->sdo_buf_size) {
        gw->stats.sdo_too_big++;
        fail(c, CO_ABORT_OUT_OF_MEMORY);
        return false;
    }
    gw->sdo_buf_owner = c;
    c->data = (co_buffer_t){.data = gw->sdo_buf, .size = 0, .capacity = gw->sdo_buf_size};
    return true;
}

/* Answer the client's segment request (toggle already checked) when the
 * data it needs is in the buffer, else keep it pending. The last segment
 * also waits for the end of the USDO transfer. */
static void serve_segment(co_gateway_sdo_t *c)
{
    uint32_t left = c->size - c->offset;
    uint32_t n = left < SEG_DATA ? left : SEG_DATA;
    bool last = n == left;
    if (c->data.size < c->offset + n || (last && c->fetch_running)) {
        c->seg_pending = true;   /* the device's data decides: its timeout applies */
        co_timer_cancel(co_line_timers(client_line(c)), &c->xtimer);
        return;
    }
    c->seg_pending = false;
    uint8_t f[FRAME] = {(uint8_t)(c->toggle << 4 | (SEG_DATA - n) << 1 | (last ? 1u : 0u)), 0,
                        0, 0, 0, 0, 0, 0};
    memcpy(f + 1, c->data.data + c->offset, n);
    c->offset += n;
    send_client(c, f);
    if (last) {
        c->gw->stats.sdo_translated++;
        finish(c);
        return;
    }
    c->toggle ^= 1u;
    arm(c);
}

/* Answer the upload initiate with the size: segments are served from now on. */
static void answer_segmented(co_gateway_sdo_t *c, uint32_t n)
{
    uint8_t f[FRAME] = {0x41, c->mux[0], c->mux[1], c->mux[2], (uint8_t)n, (uint8_t)(n >> 8),
                        (uint8_t)(n >> 16), (uint8_t)(n >> 24)};
    c->size = n;
    c->offset = 0;
    c->toggle = 0;
    c->seg_pending = false;
    c->xstate = X_UL_SEG;
    send_client(c, f);
    arm(c);
}

/* Data from the target's upload: into the buffer, and the client's answers
 * as it comes. `total` is announced with len 0 before any data. False: more
 * than the buffer holds. */
static bool accept(co_gateway_sdo_t *c, uint32_t offset, const uint8_t *data, uint32_t len,
                   uint32_t total, uint32_t unknown)
{
    if (len == 0) {
        if (total != unknown && total > c->data.capacity) {
            return false;
        }
        c->data.size = 0;
        if (c->xstate == X_UL_WAIT && total > 4 && total != unknown) {
            answer_segmented(c, total);   /* the client starts while the data comes */
        }
        return true;
    }
    if (offset > c->data.capacity || len > c->data.capacity - offset) {
        return false;
    }
    memcpy(c->data.data + offset, data, len);
    c->data.size = offset + len;
    if (c->xstate == X_UL_SEG && c->seg_pending) {
        serve_segment(c);
    }
    return true;
}

static uint8_t usdo_sink(void *ctx, uint32_t offset, const uint8_t *data, uint32_t len,
                         uint32_t total)
{
    return accept(ctx, offset, data, len, total, 0xFFFFFFFFu) ? 0 : CO_USDO_ABORT_OUT_OF_MEMORY;
}

static uint32_t sdo_sink(void *ctx, uint32_t offset, const uint8_t *data, uint32_t len,
                         uint32_t total)
{
    return accept(ctx, offset, data, len, total, CO_SDO_CLIENT_SIZE_UNKNOWN)
               ? 0
               : (uint32_t)CO_ABORT_OUT_OF_MEMORY;
}

/* The target's transfer ended: `abort` is a CiA 301 code (0 = done);
 * `own_refusal` when our sink refused (larger than the buffer). */
static void fetched(co_gateway_sdo_t *c, uint32_t abort, bool own_refusal)
{
    uint8_t state = c->xstate;
    bool live = c->fetch_running;
    c->fetch_running = false;
    if (!live || (state != X_DL_WAIT && state != X_UL_WAIT && state != X_UL_SEG)) {
        return;   /* cancelled by the client or the connection's end */
    }
    if (abort != 0 && own_refusal && !c->fd && state == X_UL_WAIT) {
        /* a classic target's value larger than the buffer: the client's
         * initiate goes to the target as it came, relayed from now on */
        finish(c);
        const uint8_t initiate[FRAME] = {0x40, c->mux[0], c->mux[1], c->mux[2], 0, 0, 0, 0};
        co_gateway_sdo_relay(c, initiate);
        return;
    }
    if (abort != 0) {
        if (own_refusal) {
            c->gw->stats.sdo_too_big++;
        }
        fail(c, abort);
        return;
    }
    if (state == X_DL_WAIT) {
        c->gw->stats.sdo_translated++;
        send_client(c, c->answer);
        finish(c);
        return;
    }
    if (state == X_UL_SEG) {   /* streamed: the announced size must have come */
        if (c->data.size != c->size) {
            fail(c, c->data.size > c->size ? CO_ABORT_LENGTH_HIGH : CO_ABORT_LENGTH_LOW);
        } else if (c->seg_pending) {
            serve_segment(c);
        }
        return;
    }
    uint32_t n = c->data.size;
    if (n >= 1 && n <= 4) {
        uint8_t f[FRAME] = {(uint8_t)(0x43u | (4u - n) << 2), c->mux[0], c->mux[1], c->mux[2],
                            0, 0, 0, 0};   /* expedited, size indicated */
        memcpy(f + 4, c->data.data, n);
        c->gw->stats.sdo_translated++;
        send_client(c, f);
        finish(c);
        return;
    }
    answer_segmented(c, n);   /* size not announced, or 0 bytes (one empty segment) */
}

static void usdo_done(co_usdo_request_t *req)
{
    fetched(req->user, co_usdo_abort_to_co(req->abort),
            req->abort == CO_USDO_ABORT_OUT_OF_MEMORY && !req->abort_from_server);
}

static void sdo_done(co_sdo_request_t *req)
{
    fetched(req->user, req->abort, req->abort == CO_ABORT_OUT_OF_MEMORY && !req->abort_from_server);
}

static uint32_t fetch_timeout_ms(const co_gateway_sdo_t *c)
{
    return (uint32_t)((c->gw->sdo_timeout_us != 0 ? c->gw->sdo_timeout_us
                                                   : (uint64_t)CO_GATEWAY_SDO_TIMEOUT_MS * 1000u) /
                      1000u);
}

/* Start the target's transfer with the line's client; a CiA 301 code when
 * the client refuses it at once. */
static uint32_t start_fetch(co_gateway_sdo_t *c, bool upload, const co_buffer_t *data)
{
    uint16_t index = (uint16_t)(c->mux[0] | c->mux[1] << 8);
    c->data = *data;
    if (c->fd) {
        co_usdo_client_t *uc = co_stack_usdo_client(c->to->stack);
        c->fetch.usdo = (co_usdo_request_t){
            .server = c->target, .index = index, .sub = c->mux[2], .upload = upload,
            .mode = CO_USDO_MODE_AUTO, .size = upload ? 0 : data->size,
            .source = upload ? NULL : co_usdo_buffer_source, .sink = upload ? usdo_sink : NULL,
            .ctx = upload ? (void *)c : (void *)&c->data, .done = usdo_done, .user = c,
            .timeout_ms = fetch_timeout_ms(c)};
        uint8_t refused = uc != NULL ? co_usdo_client_start(uc, &c->fetch.usdo)
                                     : CO_USDO_ABORT_BUSY;
        return refused != 0 ? co_usdo_abort_to_co(refused) : 0;
    }
    /* classic targets: uploads only (downloads: co_gateway_sdo_pipe.c); a
     * normal upload, so a small value costs one exchange as when relayed */
    c->fetch.sdo = (co_sdo_request_t){
        .server = c->target, .index = index, .sub = c->mux[2], .upload = true,
        .mode = CO_SDO_MODE_SEGMENTED, .sink = sdo_sink, .ctx = c, .done = sdo_done, .user = c,
        .timeout_ms = fetch_timeout_ms(c)};
    return co_sdo_client_start(co_stack_sdo_client(c->to->stack), &c->fetch.sdo);
}

/* Start the target's transfer; the client hears the refusal when there is one. */
static void start_or_fail(co_gateway_sdo_t *c, bool upload, const co_buffer_t *data)
{
    co_timer_cancel(co_line_timers(client_line(c)), &c->xtimer);
    c->xstate = upload ? X_UL_WAIT : X_DL_WAIT;
    c->fetch_running = true;
    uint32_t refused = start_fetch(c, upload, data);
    if (refused != 0) {
        c->fetch_running = false;
        fail(c, refused);
    }
}

static void download_initiate(co_gateway_sdo_t *c, const uint8_t *d)
{
    bool expedited = (d[0] & 0x02u) != 0, sized = (d[0] & 0x01u) != 0;
    memcpy(c->mux, d + 1, 3);
    c->answer[0] = 0x60;
    memcpy(c->answer + 1, d + 1, 3);
    memset(c->answer + 4, 0, 4);
    if (expedited) {
        uint32_t n = sized ? 4u - ((d[0] >> 2) & 3u) : 4u;
        memcpy(c->small, d + 4, n);
        co_buffer_t b = {.data = c->small, .size = n, .capacity = sizeof c->small};
        start_or_fail(c, false, &b);
        return;
    }
    c->size_known = sized;
    c->size = sized ? get_u32(d + 4) : 0;
    if (!take_buffer(c, c->size)) {
        return;
    }
    c->offset = 0;
    c->toggle = 0;
    c->xstate = X_DL_SEG;
    send_client(c, c->answer);
    arm(c);
}

static void download_segment(co_gateway_sdo_t *c, const uint8_t *d)
{
    uint8_t t = (d[0] >> 4) & 1u;
    uint32_t n = SEG_DATA - ((d[0] >> 1) & 7u);
    bool last = (d[0] & 1u) != 0;
    if (t != c->toggle) {
        fail(c, CO_ABORT_TOGGLE);
        return;
    }
    if (c->offset + n > c->data.capacity) {
        c->gw->stats.sdo_too_big++;
        fail(c, CO_ABORT_OUT_OF_MEMORY);
        return;
    }
    memcpy(c->data.data + c->offset, d + 1, n);
    c->offset += n;
    uint8_t ack[FRAME] = {(uint8_t)(0x20u | t << 4), 0, 0, 0, 0, 0, 0, 0};
    if (!last) {
        c->toggle ^= 1u;
        send_client(c, ack);
        arm(c);
        return;
    }
    if (c->size_known && c->offset != c->size) {
        fail(c, c->offset > c->size ? CO_ABORT_LENGTH_HIGH : CO_ABORT_LENGTH_LOW);
        return;
    }
    memcpy(c->answer, ack, FRAME);   /* sent when the target has the value */
    co_buffer_t b = {.data = c->data.data, .size = c->offset, .capacity = c->data.capacity};
    start_or_fail(c, false, &b);
}

static void upload_initiate(co_gateway_sdo_t *c, const uint8_t *d)
{
    memcpy(c->mux, d + 1, 3);
    if (!take_buffer(c, 0)) {
        return;
    }
    co_buffer_t b = {.data = c->gw->sdo_buf, .size = 0, .capacity = c->gw->sdo_buf_size};
    start_or_fail(c, true, &b);
}

static void upload_segment(co_gateway_sdo_t *c, const uint8_t *d)
{
    uint8_t t = (d[0] >> 4) & 1u;
    if (c->seg_pending) {
        return;   /* the client repeats itself while the data is on its way */
    }
    if (t != c->toggle) {
        fail(c, CO_ABORT_TOGGLE);
        return;
    }
    serve_segment(c);
}

void co_gateway_sdo_buffered_open(co_gateway_sdo_t *c, bool fd)
{
    c->fd = fd;
    c->buffered = true;
    c->xstate = X_IDLE;
    co_timer_init(&c->xtimer, on_timeout, c);
}

/* A classic target's transfer the gateway buffers: an upload, while the
 * buffer and the line's SDO client are idle (downloads: co_gateway_sdo_pipe.c;
 * the client's block transfers are relayed as they are). */
static bool buffers(const co_gateway_sdo_t *c, const uint8_t *d)
{
    co_sdo_client_t *sc = co_stack_sdo_client(c->to->stack);
    return d[0] >> 5 == 2 && sc != NULL && !c->gw->sdo_relay_only &&
           (c->gw->sdo_buf_owner == NULL || c->gw->sdo_buf_owner == c) &&
           c->gw->sdo_buf != NULL && !co_sdo_client_receives(sc, 0x580u + c->target);
}

/* The client's request on a buffered connection. False: a classic target's
 * frame to relay (no buffered transfer runs and this one does not start one;
 * one that ran is ended first when the client starts another kind). */
bool co_gateway_sdo_buffered_request(co_gateway_sdo_t *c, const uint8_t *d)
{
    uint8_t ccs = d[0] >> 5;
    if (!c->fd && !buffers(c, d) && (c->xstate == X_IDLE || ccs == 1 || ccs == 2 || ccs >= 5)) {
        if (c->xstate != X_IDLE) {   /* the client started anew, relayed this time */
            if (c->fetch_running) {
                cancel_fetch(c, CO_ABORT_GENERAL);
            }
            finish(c);
        }
        return false;
    }
    c->gw->stats.sdo_relayed++;
    if (ccs == 4) {   /* the client's abort: the target's transfer ends with it */
        if (c->fetch_running) {
            cancel_fetch(c, get_u32(d + 4));
        }
        finish(c);
        return true;
    }
    if (ccs == 1 || ccs == 2) {   /* a new initiate ends an open transfer */
        if (c->fetch_running) {
            cancel_fetch(c, CO_ABORT_GENERAL);
        }
        finish(c);
        if (ccs == 1) {
            download_initiate(c, d);
        } else {
            upload_initiate(c, d);
        }
        return true;
    }
    if (ccs == 0 && c->xstate == X_DL_SEG) {
        download_segment(c, d);
        return true;
    }
    if (ccs == 3 && c->xstate == X_UL_SEG) {
        upload_segment(c, d);
        return true;
    }
    if (c->xstate == X_DL_WAIT || c->xstate == X_UL_WAIT) {
        return true;   /* the client repeats itself while the target works: ignored */
    }
    if (ccs == 5 || ccs == 6) {
        memcpy(c->mux, d + 1, 3);   /* block transfer: not translated, segmented instead */
    }
    fail(c, CO_ABORT_COMMAND);
    return true;
}

void co_gateway_sdo_buffered_close(co_gateway_sdo_t *c)
{
    if (c->fetch_running) {
        cancel_fetch(c, CO_ABORT_GENERAL);
    }
    finish(c);
    c->fd = false;
    c->buffered = false;
}

void co_gateway_set_sdo_buffering(co_gateway_t *gw, bool on)
{
    gw->sdo_relay_only = !on;
}

void co_gateway_sdo_buffered_end(co_gateway_sdo_t *c, uint32_t code)
{
    if (c->fetch_running) {
        cancel_fetch(c, code);
    }
    abort_client(c, code);
    finish(c);
}

void co_gateway_set_sdo_buffer(co_gateway_t *gw, uint8_t *buf, uint32_t size)
{
    gw->sdo_buf = size != 0 ? buf : NULL;
    gw->sdo_buf_size = buf != NULL ? size : 0;
}
