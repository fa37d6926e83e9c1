/* Classic SDO client: see co_sdo_client.h for the channel model and
 * docs/protocol-notes.md (section "Classic SDO client") for every wire
 * choice.
 *
 * Rules where CiA 301's public descriptions leave room:
 *  - Frames that are not exactly 8 bytes, FD frames, frames for a channel
 *    without a transfer are ignored and counted.
 *  - A server abort (byte 0 = 0x80) ends the transfer with its code (0 is
 *    taken as 0x08000000) when it names the transfer's index/sub-index or
 *    0000:00 (what a server sends for a frame it has no transfer for); one
 *    naming another object is a late abort of an earlier transfer on the
 *    channel: ignored and counted.
 *  - The previous frame again (CAN double reception) is ignored, except
 *    block download acks and block upload segments, which may repeat
 *    legitimately (they follow their own sequence rules).
 *  - A command byte that names no server -> client frame: 0x05040001. A
 *    known command the state does not expect (a late answer of an earlier
 *    step or transfer) and an initiate response for another index/sub-index
 *    are ignored and counted; the timeout still guards the transfer.
 *  - Toggle mismatch 0x05030000; block seqno 0 or above the block size, or
 *    an ack above the segments sent, 0x05040003; block size 0 or above 127
 *    0x05040002; CRC mismatch 0x05040004; upload data longer or shorter than
 *    the indicated size 0x06070010. Each abort is sent to the server.
 *  - Block download: the sub-block's data stays in the channel buffer until
 *    acknowledged; after a short ack the rest goes again, renumbered from 1,
 *    in a sub-block of the server's new size; the CRC runs over acknowledged
 *    data. An ack while a sub-block is still being sent is taken (servers
 *    that acknowledge at a gap), one above the segments sent so far is a
 *    stale one and ignored.
 *  - Block upload: segments in order go to the sink at once (the one with
 *    c = 1 waits for the end frame's n); a repeated segment is ignored; a
 *    segment after a gap is ignored, and when it ends the sub-block the
 *    sub-block is acknowledged with the last good seqno (the server repeats
 *    from there). A sub-block whose end never comes is acknowledged when the
 *    timeout runs out once; a second expiry without a segment aborts.
 *  - AUTO: a block initiate refused with 0x05040001 is done once more
 *    without block (segmented download / normal upload). */
#include "canopenfd/co_sdo_client.h"

#include "co_cob_id.h"
#include "co_crc.h"

#include <string.h>

enum {
    NODE_MAX = 127,
    CMD_ABORT = 0x80,
    CMD_BLOCK_ACK = 0xA2,
    NETWORK_IND = 0xE0   /* SDO networking: ccs/scs 7 (docs/protocol-notes.md) */
};

/* routed[]: the gateway's connection is not known (an indication went
 * unanswered): the next request of any kind sends one first */
#define ROUTED_UNKNOWN 0xFFFFu

#define COB_RESERVED 0x3FFFF800u    /* bits 11..29 of a valid COB-ID: 11-bit CAN-IDs only */
#define RANGE_FIRST (CO_SDO_RESPONSE_BASE + 1u)
#define RANGE_LAST (CO_SDO_RESPONSE_BASE + NODE_MAX)

static void on_range_frame(co_line_t *line, const co_frame_t *f, void *user);
static void on_own_frame(co_line_t *line, const co_frame_t *f, void *user);

/* ------------------------------------------------------------ helpers */

static co_timer_list_t *timers_of(const co_sdo_client_channel_t *ch)
{
    return co_line_timers(ch->client->line);
}

static uint64_t now_of(const co_sdo_client_t *c)
{
    return co_line_now(c->line);
}

static void arm_timeout(co_sdo_client_channel_t *ch)
{
    const co_sdo_request_t *req = ch->req;
    uint64_t t = req->timeout_ms != 0 ? (uint64_t)req->timeout_ms * 1000u : ch->client->timeout_us;
    co_timer_start(timers_of(ch), &ch->timer, now_of(ch->client) + t);
}

static bool in_range(uint32_t id)
{
    return id >= RANGE_FIRST && id <= RANGE_LAST;
}

/* CAN-IDs a client channel may use: 11-bit, not CiA 301 restricted, except
 * the default SDO channels (0x601..0x67F sent, 0x581..0x5FF received). */
static bool tx_id_ok(uint32_t id)
{
    return id <= CO_SDO_COB_ID_MASK &&
           (!co_cob_id_restricted(id) ||
            (id > CO_SDO_REQUEST_BASE && id <= CO_SDO_REQUEST_BASE + NODE_MAX));
}

static bool rx_id_ok(uint32_t id)
{
    return id <= CO_SDO_COB_ID_MASK && (!co_cob_id_restricted(id) || in_range(id));
}

static bool is_busy(const co_sdo_client_channel_t *ch)
{
    return ch->state != CO_SDO_CLIENT_FREE;
}

/* ------------------------------------------------------------ sending */

static bool send_msg(co_sdo_client_channel_t *ch, const co_sdo_msg_t *m)
{
    co_sdo_client_t *c = ch->client;
    uint8_t buf[CO_SDO_FRAME_LEN];
    if (co_sdo_encode(m, buf) == 0 || !co_line_send(c->line, ch->tx_id, buf, sizeof buf)) {
        c->stats.tx_failed++;
        return false;
    }
    return true;
}

static void msg_init(const co_sdo_client_channel_t *ch, co_sdo_frame_t frame, co_sdo_msg_t *m)
{
    memset(m, 0, sizeof *m);
    m->frame = (uint8_t)frame;
    m->index = ch->req->index;
    m->sub = ch->req->sub;
}

static void send_abort(co_sdo_client_channel_t *ch, uint32_t code)
{
    co_sdo_msg_t m;
    msg_init(ch, CO_SDO_ABORT, &m);
    m.abort_code = code;
    ch->client->stats.aborts_sent++;
    (void)send_msg(ch, &m);
}

/* ------------------------------------------------------------ channels */

static void stop_waiting(co_sdo_client_channel_t *ch)
{
    if (ch->wait_space) {
        ch->wait_space = false;
        ch->client->waiting--;
    }
}

/* Free the channel (timers; a spare forgets its binding); the request
 * stays untouched. */
static void release(co_sdo_client_channel_t *ch)
{
    if (ch->state == CO_SDO_CLIENT_NET_IND && ch->req != NULL) {
        /* ended before the gateway's answer (cancel, reconfiguration,
         * deinit): it may have switched already, so assume nothing */
        ch->client->routed[ch->req->server] = ROUTED_UNKNOWN;
    }
    co_timer_cancel(timers_of(ch), &ch->timer);
    co_timer_cancel(timers_of(ch), &ch->pace);
    stop_waiting(ch);
    ch->state = CO_SDO_CLIENT_FREE;
    ch->req = NULL;
    ch->last_valid = false;
    if (ch->kind == CO_SDO_CLIENT_SPARE) {
        ch->tx_id = 0;
        ch->rx_id = 0;
        ch->server = 0;
    }
}

static void report(co_sdo_client_t *c, co_sdo_request_t *req, uint32_t code, bool from_server)
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

/* End the request: the channel is free before done() runs, so done() may
 * start new requests (this one included). Nothing may touch `ch` after. */
static void finish(co_sdo_client_channel_t *ch, uint32_t code, bool from_server)
{
    co_sdo_client_t *c = ch->client;
    co_sdo_request_t *req = ch->req;
    release(ch);
    report(c, req, code, from_server);
}

/* Our own abort: sent to the server, then the end. */
static void fail(co_sdo_client_channel_t *ch, uint32_t code)
{
    send_abort(ch, code);
    finish(ch, code, false);
}

/* Still the same transfer after a callback into the application (which may
 * have cancelled it, and even started a new one on the same channel)? */
static bool alive(const co_sdo_client_channel_t *ch, uint32_t run)
{
    return ch->run == run && ch->state != CO_SDO_CLIENT_FREE;
}

/* ------------------------------------------------------------ data */

/* `want` bytes from the source at `offset`; false (and the transfer
 * aborted 0x08000000, or ended by the source itself) otherwise. */
static bool read_source(co_sdo_client_channel_t *ch, uint8_t *buf, uint32_t offset, uint32_t want)
{
    co_sdo_request_t *req = ch->req;
    uint32_t run = ch->run;
    uint32_t got;
    if (want == 0) {
        return true;
    }
    got = req->source(req->ctx, offset, buf, want);
    if (!alive(ch, run)) {
        return false;
    }
    if (got != want) {
        ch->client->stats.source_failed++;
        fail(ch, CO_ABORT_GENERAL);
        return false;
    }
    return true;
}

/* Hand data to the sink (len 0: the announcement); false when the transfer
 * ended (refused, or ended by the sink itself). */
static bool to_sink(co_sdo_client_channel_t *ch, const uint8_t *data, uint32_t len)
{
    co_sdo_request_t *req = ch->req;
    uint32_t run = ch->run;
    uint32_t code = req->sink(req->ctx, ch->offset, data, len, ch->total);
    if (!alive(ch, run)) {
        return false;
    }
    if (code != 0) {
        ch->client->stats.sink_refused++;
        fail(ch, code);
        return false;
    }
    if (len > 0) {
        ch->offset += len;
        req->transferred = ch->offset;
    }
    return true;
}

/* Bytes an upload may still bring without passing the indicated size. */
static uint32_t upload_room(const co_sdo_client_channel_t *ch)
{
    return ch->total - ch->offset;   /* unknown: 0xFFFFFFFF - offset */
}

static void size_mismatch(co_sdo_client_channel_t *ch)
{
    ch->client->stats.rx_size_mismatch++;
    fail(ch, CO_ABORT_TYPE_MISMATCH);
}

/* ------------------------------------------------------------ segmented */

/* The next download segment: 7 bytes, or the rest with c = 1. A refused
 * send leaves the transfer to its timeout. */
static void send_download_segment(co_sdo_client_channel_t *ch)
{
    co_sdo_request_t *req = ch->req;
    uint32_t left = req->size - ch->offset;
    uint8_t data[CO_SDO_SEGMENT_DATA];
    co_sdo_msg_t m;
    bool last = left <= CO_SDO_SEGMENT_DATA;
    uint32_t n = last ? left : CO_SDO_SEGMENT_DATA;
    if (!read_source(ch, data, ch->offset, n)) {
        return;
    }
    msg_init(ch, CO_SDO_DOWNLOAD_SEGMENT, &m);
    m.toggle = ch->toggle;
    m.length = (uint8_t)n;
    m.last = last;
    m.data = data;
    (void)send_msg(ch, &m);
    ch->offset += n;
    req->transferred = ch->offset;
    ch->last_sent = last;
    ch->state = CO_SDO_CLIENT_DL_SEG;
}

static void send_upload_segment_request(co_sdo_client_channel_t *ch)
{
    co_sdo_msg_t m;
    msg_init(ch, CO_SDO_UPLOAD_SEGMENT, &m);
    m.toggle = ch->toggle;
    (void)send_msg(ch, &m);
}

/* ------------------------------------------------------------ block download */

static void wait_space(co_sdo_client_channel_t *ch)
{
    if (!ch->wait_space) {
        ch->wait_space = true;
        ch->client->waiting++;
        ch->client->stats.tx_paused++;
    }
}

/* Start the next sub-block: the next blksize segments of data (what the
 * buffer holds from an unacknowledged sub-block, then fresh data). */
static void start_sub_block(co_sdo_client_channel_t *ch)
{
    co_sdo_request_t *req = ch->req;
    uint32_t left = req->size - ch->offset;
    uint32_t cap = (uint32_t)ch->blksize * CO_SDO_SEGMENT_DATA;
    uint32_t want = left < cap ? left : cap;
    if (ch->queued < want) {
        if (!read_source(ch, ch->buf + ch->queued, ch->offset + ch->queued, want - ch->queued)) {
            return;
        }
        ch->queued = (uint16_t)want;
    }
    ch->sub_len = (uint16_t)want;
    ch->sub_last = want == left;
    /* an empty rest (a download of 0 bytes) still needs one segment with c = 1 */
    ch->segments = (uint8_t)(want == 0 ? 1u : (want + CO_SDO_SEGMENT_DATA - 1u) /
                                                  CO_SDO_SEGMENT_DATA);
    ch->seqno = 0;
    ch->state = CO_SDO_CLIENT_BD_SEND;
    /* the first burst goes from the pace timer: frames arrive in
     * co_line_process before its timers run, so even then one burst per
     * process call */
    co_timer_start(timers_of(ch), &ch->pace, now_of(ch->client));
    arm_timeout(ch);
}

/* One burst of the current sub-block (at most CO_SDO_CLIENT_BLOCK_BURST
 * segments, while the tx queue has room), from the pace timer; then the
 * pace timer again (due at once: a timer armed while timers run waits for
 * the next process call) or the tx-space indication goes on. */
static void send_run(co_sdo_client_channel_t *ch)
{
    co_sdo_client_t *c = ch->client;
    uint32_t budget = CO_SDO_CLIENT_BLOCK_BURST;
    while (ch->seqno < ch->segments && budget > 0) {
        co_sdo_msg_t m;
        uint32_t off = (uint32_t)ch->seqno * CO_SDO_SEGMENT_DATA;
        uint32_t left = ch->sub_len > off ? ch->sub_len - off : 0;
        if (co_line_tx_room(c->line) == 0) {
            wait_space(ch);
            break;
        }
        memset(&m, 0, sizeof m);
        m.frame = CO_SDO_BLOCK_SEGMENT;
        m.seqno = (uint8_t)(ch->seqno + 1u);
        m.last = ch->sub_last && m.seqno == ch->segments;
        m.length = (uint8_t)(left < CO_SDO_SEGMENT_DATA ? left : CO_SDO_SEGMENT_DATA);
        m.data = ch->buf + off;
        if (!send_msg(ch, &m)) {
            wait_space(ch);   /* room was checked: only a full queue gets here */
            break;
        }
        ch->seqno++;
        budget--;
    }
    if (ch->seqno == ch->segments) {
        ch->state = CO_SDO_CLIENT_BD_ACK;
        co_timer_cancel(timers_of(ch), &ch->pace);
    } else if (!ch->wait_space) {
        co_timer_start(timers_of(ch), &ch->pace, now_of(c));
    }
    arm_timeout(ch);   /* the server says nothing while we send: time without progress */
}

static void on_pace(co_timer_t *timer, uint64_t now_us, void *user)
{
    co_sdo_client_channel_t *ch = user;
    (void)timer;
    (void)now_us;
    if (ch->state == CO_SDO_CLIENT_BD_SEND && !ch->wait_space) {
        send_run(ch);
    }
}

/* The tx queue drained to half (called from co_line_tx_pop, in the
 * driver's context): waiting channels resume from the next process call,
 * a different one first each time. */
static void on_tx_space(co_line_t *line, void *user)
{
    co_sdo_client_t *c = user;
    uint8_t k;
    (void)line;
    if (c->waiting == 0) {
        return;
    }
    for (k = 0; k < c->channel_count; k++) {
        co_sdo_client_channel_t *ch = &c->channels[(c->space_rr + k) % c->channel_count];
        if (ch->wait_space) {
            stop_waiting(ch);
            co_timer_start(timers_of(ch), &ch->pace, now_of(c));
        }
    }
    c->space_rr = (uint8_t)((c->space_rr + 1u) % c->channel_count);
}

/* 0xA2 from the server: confirm, then the next sub-block or the end. */
static void on_block_download_ack(co_sdo_client_channel_t *ch, const co_sdo_msg_t *m)
{
    co_sdo_client_t *c = ch->client;
    uint32_t acked;
    if (m->seqno > ch->seqno) {
        if (ch->state == CO_SDO_CLIENT_BD_SEND) {
            c->stats.rx_duplicate++;   /* the previous sub-block's ack again */
            return;
        }
        c->stats.rx_bad_seqno++;
        fail(ch, CO_ABORT_SEQUENCE);
        return;
    }
    if (m->blksize < 1 || m->blksize > CO_SDO_BLKSIZE_MAX) {
        c->stats.rx_bad_blksize++;
        fail(ch, CO_ABORT_BLOCK_SIZE);
        return;
    }
    stop_waiting(ch);
    co_timer_cancel(timers_of(ch), &ch->pace);
    if (m->seqno < ch->seqno) {
        c->stats.block_repeats += (uint32_t)(ch->seqno - m->seqno);
    }
    acked = (uint32_t)m->seqno * CO_SDO_SEGMENT_DATA;
    if (acked > ch->sub_len) {
        acked = ch->sub_len;
    }
    if (ch->crc && acked > 0) {
        ch->crc_value = co_crc16_ccitt(ch->crc_value, ch->buf, acked);
    }
    ch->offset += acked;
    ch->req->transferred = ch->offset;
    if (acked < ch->queued) {
        memmove(ch->buf, ch->buf + acked, ch->queued - acked);
    }
    ch->queued = (uint16_t)(ch->queued - acked);
    if (m->seqno == ch->segments && ch->sub_last) {
        co_sdo_msg_t end;
        msg_init(ch, CO_SDO_BLOCK_DOWNLOAD_END, &end);
        end.unused = (uint8_t)((uint32_t)ch->segments * CO_SDO_SEGMENT_DATA - ch->sub_len);
        end.crc_value = ch->crc ? ch->crc_value : 0;
        (void)send_msg(ch, &end);
        ch->state = CO_SDO_CLIENT_BD_END;
        return;
    }
    ch->blksize = m->blksize;
    start_sub_block(ch);
}

/* ------------------------------------------------------------ block upload */

static void send_block_upload_ack(co_sdo_client_channel_t *ch, uint8_t ackseq)
{
    co_sdo_msg_t m;
    msg_init(ch, CO_SDO_BLOCK_UPLOAD_ACK, &m);
    m.seqno = ackseq;
    m.blksize = ch->blksize;
    (void)send_msg(ch, &m);
    ch->seqno = 0;
    ch->seen = false;
}

/* A frame while sub-block segments are expected: the abort, or a segment. */
static void on_block_upload_segment(co_sdo_client_channel_t *ch, const uint8_t *b)
{
    co_sdo_client_t *c = ch->client;
    co_sdo_msg_t m;
    (void)co_sdo_decode_block_segment(b, CO_SDO_FRAME_LEN, &m);
    if (m.seqno == 0 || m.seqno > ch->blksize) {
        c->stats.rx_bad_seqno++;
        fail(ch, CO_ABORT_SEQUENCE);
        return;
    }
    memcpy(ch->last_rx, b, sizeof ch->last_rx);
    ch->last_valid = true;
    arm_timeout(ch);
    ch->seen = true;
    if (m.seqno != ch->seqno + 1u) {
        c->stats.rx_block_ignored++;
        if (m.seqno > ch->seqno && ch->seqno != 0 && (m.last || m.seqno == ch->blksize)) {
            /* the end of a sub-block with a gap: the server repeats after
             * the last good segment */
            c->stats.block_partial_acks++;
            send_block_upload_ack(ch, ch->seqno);
        }
        return;
    }
    if (m.last) {
        memcpy(ch->held, m.data, sizeof ch->held);   /* n comes with the end frame */
        send_block_upload_ack(ch, m.seqno);
        ch->state = CO_SDO_CLIENT_BU_END;
        return;
    }
    if (upload_room(ch) < CO_SDO_SEGMENT_DATA) {
        size_mismatch(ch);
        return;
    }
    if (ch->crc) {
        ch->crc_value = co_crc16_ccitt(ch->crc_value, m.data, m.length);
    }
    if (!to_sink(ch, m.data, m.length)) {
        return;
    }
    ch->seqno = m.seqno;
    if (m.seqno == ch->blksize) {
        send_block_upload_ack(ch, m.seqno);
    }
}

/* 0xC1 | n<<2: size, CRC, the held bytes, then 0xA1. */
static void on_block_upload_end(co_sdo_client_channel_t *ch, const co_sdo_msg_t *m)
{
    co_sdo_client_t *c = ch->client;
    co_sdo_msg_t rsp;
    uint32_t n = (uint32_t)(CO_SDO_SEGMENT_DATA - m->unused);
    if (upload_room(ch) < n || (ch->total != CO_SDO_CLIENT_SIZE_UNKNOWN && upload_room(ch) != n)) {
        size_mismatch(ch);
        return;
    }
    if (ch->crc && co_crc16_ccitt(ch->crc_value, ch->held, n) != m->crc_value) {
        c->stats.rx_crc++;
        fail(ch, CO_ABORT_CRC);
        return;
    }
    if (n > 0 && !to_sink(ch, ch->held, n)) {
        return;
    }
    msg_init(ch, CO_SDO_BLOCK_UPLOAD_END_RSP, &rsp);
    (void)send_msg(ch, &rsp);
    finish(ch, 0, false);
}

/* ------------------------------------------------------------ upload */

/* The upload initiate response (also the protocol switch of a block
 * upload): expedited data at once, or the segments. */
static void on_upload_initiate(co_sdo_client_channel_t *ch, const co_sdo_msg_t *m)
{
    co_sdo_request_t *req = ch->req;
    if (ch->state == CO_SDO_CLIENT_BU_INIT) {
        ch->client->stats.protocol_switches++;
    }
    if (m->expedited) {
        /* s = 0: "unspecified number of bytes": all four are given */
        req->result_mode = CO_SDO_MODE_EXPEDITED;
        ch->total = m->length;
        req->total = ch->total;
        if (!to_sink(ch, NULL, 0)) {
            return;
        }
        if (m->length > 0 && !to_sink(ch, m->data, m->length)) {
            return;
        }
        finish(ch, 0, false);
        return;
    }
    req->result_mode = CO_SDO_MODE_SEGMENTED;
    ch->total = m->size_indicated ? m->size : CO_SDO_CLIENT_SIZE_UNKNOWN;
    req->total = ch->total;
    if (!to_sink(ch, NULL, 0)) {
        return;
    }
    ch->toggle = 0;
    ch->state = CO_SDO_CLIENT_UL_SEG;
    send_upload_segment_request(ch);
}

static void on_upload_segment(co_sdo_client_channel_t *ch, const co_sdo_msg_t *m)
{
    co_sdo_client_t *c = ch->client;
    uint32_t room = upload_room(ch);
    if (m->toggle != ch->toggle) {
        c->stats.rx_toggle++;
        fail(ch, CO_ABORT_TOGGLE);
        return;
    }
    if (m->length > room ||
        (m->last && ch->total != CO_SDO_CLIENT_SIZE_UNKNOWN && m->length != room)) {
        size_mismatch(ch);
        return;
    }
    if (m->length > 0 && !to_sink(ch, m->data, m->length)) {
        return;
    }
    if (m->last) {
        finish(ch, 0, false);
        return;
    }
    ch->toggle ^= 1u;
    send_upload_segment_request(ch);
}

/* 0xC0 | sc<<2 | s<<1: the size, then "start". */
static void on_block_upload_initiate(co_sdo_client_channel_t *ch, const co_sdo_msg_t *m)
{
    co_sdo_request_t *req = ch->req;
    co_sdo_msg_t start;
    ch->crc = !req->no_crc && m->crc;
    req->crc_used = ch->crc;
    ch->crc_value = 0;
    ch->total = m->size_indicated ? m->size : CO_SDO_CLIENT_SIZE_UNKNOWN;
    req->total = ch->total;
    if (!to_sink(ch, NULL, 0)) {
        return;
    }
    msg_init(ch, CO_SDO_BLOCK_UPLOAD_START, &start);
    (void)send_msg(ch, &start);
    ch->seqno = 0;
    ch->seen = false;
    ch->state = CO_SDO_CLIENT_BU_DATA;
}

/* ------------------------------------------------------------ starting */

co_sdo_mode_t co_sdo_client_choose_mode(uint8_t mode, uint32_t size, uint32_t threshold)
{
    if (mode != CO_SDO_MODE_AUTO) {
        return (co_sdo_mode_t)mode;
    }
    if (threshold == 0) {
        threshold = CO_SDO_CLIENT_DEFAULT_BLOCK_THRESHOLD;
    }
    if (size >= 1 && size <= CO_SDO_EXPEDITED_MAX) {
        return CO_SDO_MODE_EXPEDITED;
    }
    return size >= threshold ? CO_SDO_MODE_BLOCK : CO_SDO_MODE_SEGMENTED;
}

static uint32_t threshold_of(const co_sdo_client_t *c, const co_sdo_request_t *req)
{
    return req->block_threshold != 0 ? req->block_threshold : c->block_threshold;
}

/* The protocol a request starts with: uploads BLOCK or anything else
 * (= a normal upload); downloads EXPEDITED, SEGMENTED or BLOCK. */
static co_sdo_mode_t mode_of(const co_sdo_client_t *c, const co_sdo_request_t *req)
{
    co_sdo_mode_t mode = co_sdo_client_choose_mode(req->mode, req->size, threshold_of(c, req));
    if (req->upload) {
        /* AUTO: block only for a known expected size from the threshold on */
        return (mode == CO_SDO_MODE_BLOCK && (req->mode != CO_SDO_MODE_AUTO || req->size != 0))
                   ? CO_SDO_MODE_BLOCK
                   : CO_SDO_MODE_SEGMENTED;
    }
    return mode;
}

/* The first frame of the transfer in `ch->mode` (`data`: an expedited
 * download's bytes, read before); 0 or why it did not go. */
static uint32_t send_first(co_sdo_client_channel_t *ch, const uint8_t *data)
{
    co_sdo_request_t *req = ch->req;
    co_sdo_msg_t m;
    bool block = ch->mode == CO_SDO_MODE_BLOCK;
    if (req->upload && block) {
        msg_init(ch, CO_SDO_BLOCK_UPLOAD_INITIATE, &m);
        m.crc = !req->no_crc;
        m.blksize = ch->blksize;
        m.pst = req->pst;
        ch->state = CO_SDO_CLIENT_BU_INIT;
    } else if (req->upload) {
        msg_init(ch, CO_SDO_UPLOAD_INITIATE, &m);
        ch->state = CO_SDO_CLIENT_UL_INIT;
    } else if (ch->mode == CO_SDO_MODE_EXPEDITED) {
        msg_init(ch, CO_SDO_DOWNLOAD_INITIATE, &m);
        m.expedited = true;
        m.size_indicated = true;
        m.length = (uint8_t)req->size;
        m.data = data;
        ch->state = CO_SDO_CLIENT_DL_EXPEDITED;
    } else if (block) {
        msg_init(ch, CO_SDO_BLOCK_DOWNLOAD_INITIATE, &m);
        m.crc = !req->no_crc;
        m.size_indicated = true;
        m.size = req->size;
        ch->state = CO_SDO_CLIENT_BD_INIT;
    } else {
        msg_init(ch, CO_SDO_DOWNLOAD_INITIATE, &m);
        m.size_indicated = true;
        m.size = req->size;
        ch->state = CO_SDO_CLIENT_DL_INIT;
    }
    if (!send_msg(ch, &m)) {
        return CO_ABORT_NO_RESOURCE;
    }
    if (!req->upload && ch->mode == CO_SDO_MODE_EXPEDITED) {
        req->transferred = req->size;   /* all of it is in the initiate */
    }
    arm_timeout(ch);
    return 0;
}

/* AUTO: the server has no block transfer (0x05040001 to the block
 * initiate): once more without block, on the same channel. */
static void fall_back(co_sdo_client_channel_t *ch)
{
    co_sdo_request_t *req = ch->req;
    ch->client->stats.block_fallback++;
    req->fell_back = true;
    ch->mode = CO_SDO_MODE_SEGMENTED;
    req->result_mode = CO_SDO_MODE_SEGMENTED;
    req->crc_used = false;
    req->total = 0;
    ch->offset = 0;
    ch->total = 0;
    ch->queued = 0;
    ch->last_valid = false;
    req->transferred = 0;
    /* a refused send is left to the timeout, like any lost frame */
    if (send_first(ch, NULL) != 0) {
        arm_timeout(ch);
    }
}

static bool running(const co_sdo_client_t *c, const co_sdo_request_t *req)
{
    uint8_t i;
    for (i = 0; i < c->channel_count; i++) {
        if (is_busy(&c->channels[i]) && c->channels[i].req == req) {
            return true;
        }
    }
    return false;
}

/* Why a request cannot start (0 = it can). */
static uint32_t check_request(const co_sdo_client_t *c, const co_sdo_request_t *req)
{
    if (c->line == NULL || req == NULL || req->done == NULL || req->server > NODE_MAX ||
        (req->server == 0 && req->channel >= c->channel_count) ||
        req->mode > CO_SDO_MODE_BLOCK || running(c, req)) {
        return CO_ABORT_GENERAL;
    }
    if (req->network != 0 && (req->server == 0 || req->network > NODE_MAX ||
                              req->network_node < 1 || req->network_node > NODE_MAX)) {
        return CO_ABORT_GENERAL;   /* a routed request names its gateway and target */
    }
    if (req->blksize > CO_SDO_BLKSIZE_MAX) {
        return CO_ABORT_BLOCK_SIZE;
    }
    if (req->upload) {
        return req->sink == NULL ? (uint32_t)CO_ABORT_GENERAL : 0u;
    }
    if (req->size > CO_SDO_CLIENT_SIZE_MAX || (req->size > 0 && req->source == NULL)) {
        return CO_ABORT_GENERAL;
    }
    if (req->mode == CO_SDO_MODE_EXPEDITED &&
        (req->size == 0 || req->size > CO_SDO_EXPEDITED_MAX)) {
        return CO_ABORT_TYPE_MISMATCH;
    }
    return 0;
}

/* A configured (or busy) channel other than `self` using tx or rx. */
static co_sdo_client_channel_t *holder_of(co_sdo_client_t *c, const co_sdo_client_channel_t *self,
                                          uint32_t tx, uint32_t rx, bool busy_spares)
{
    uint8_t i;
    for (i = 0; i < c->channel_count; i++) {
        co_sdo_client_channel_t *ch = &c->channels[i];
        bool counts = ch->valid || (busy_spares && is_busy(ch));
        if (ch != self && counts && (ch->tx_id == tx || ch->rx_id == rx)) {
            return ch;
        }
    }
    return NULL;
}

/* The channel a request runs on, or NULL with *code saying why not. */
static co_sdo_client_channel_t *pick_channel(co_sdo_client_t *c, const co_sdo_request_t *req,
                                             uint32_t *code)
{
    uint8_t i, n = req->server;
    co_sdo_client_channel_t *ch;
    *code = CO_ABORT_NO_RESOURCE;
    if (n == 0) {
        ch = &c->channels[req->channel];
        if (!ch->valid) {
            *code = CO_ABORT_GENERAL;
            return NULL;
        }
        return is_busy(ch) ? NULL : ch;
    }
    for (i = 0; i < c->channel_count; i++) {
        ch = &c->channels[i];
        if (ch->valid && ch->server == n && !is_busy(ch)) {
            return ch;
        }
    }
    /* the server's default channel */
    ch = holder_of(c, NULL, co_sdo_request_id(n), co_sdo_response_id(n), true);
    if (ch != NULL) {
        bool same = ch->tx_id == co_sdo_request_id(n) && ch->rx_id == co_sdo_response_id(n);
        return (same && ch->valid && !is_busy(ch) && (ch->server == 0 || ch->server == n)) ? ch
                                                                                          : NULL;
    }
    for (i = 0; i < c->channel_count; i++) {
        ch = &c->channels[i];
        if (ch->kind == CO_SDO_CLIENT_SPARE && !is_busy(ch)) {
            ch->tx_id = co_sdo_request_id(n);
            ch->rx_id = co_sdo_response_id(n);
            ch->server = n;
            return ch;
        }
    }
    return NULL;
}

/* ------------------------------------------------------------ SDO networking */

/* The gateway connection a request needs (network | node << 8; 0 = none). */
static uint16_t routed_of(const co_sdo_request_t *req)
{
    return req->network != 0 ? (uint16_t)(req->network | req->network_node << 8) : 0u;
}

/* The gateway (req->server) holds another connection for us: the network
 * indication goes first (network 0 = back to the gateway's own OD); the
 * transfer's first frame follows its confirmation. */
static uint32_t send_network_indication(co_sdo_client_channel_t *ch, const uint8_t *data)
{
    co_sdo_request_t *req = ch->req;
    uint8_t f[CO_SDO_FRAME_LEN] = {NETWORK_IND, req->network, 0, req->network_node, 0, 0, 0, 0};
    if (data != NULL) {
        memcpy(ch->first_data, data, sizeof ch->first_data);
    }
    if (req->network == 0) {
        f[3] = 0;
    }
    if (!co_line_send(ch->client->line, ch->tx_id, f, sizeof f)) {
        ch->client->stats.tx_failed++;
        return CO_ABORT_NO_RESOURCE;
    }
    ch->state = CO_SDO_CLIENT_NET_IND;
    arm_timeout(ch);
    return 0;
}

/* The gateway's answer to our network indication. */
static void on_network_answer(co_sdo_client_channel_t *ch, const uint8_t *b)
{
    co_sdo_client_t *c = ch->client;
    co_sdo_request_t *req = ch->req;
    uint8_t node = req->network != 0 ? req->network_node : 0;
    if (b[1] != req->network || b[2] != 0 || b[3] != node ||
        (b[0] != NETWORK_IND && b[0] != CMD_ABORT)) {
        c->stats.rx_unexpected++;
        return;
    }
    if (b[0] == CMD_ABORT) {
        uint32_t code = (uint32_t)b[4] | (uint32_t)b[5] << 8 | (uint32_t)b[6] << 16 |
                        (uint32_t)b[7] << 24;
        c->routed[req->server] = 0;   /* a refusing gateway keeps no connection */
        c->stats.aborts_received++;
        finish(ch, code != 0 ? code : (uint32_t)CO_ABORT_GENERAL, true);
        return;
    }
    c->routed[req->server] = routed_of(req);
    if (send_first(ch, ch->first_data) != 0) {
        finish(ch, CO_ABORT_NO_RESOURCE, false);
    }
}

/* Take a channel for req and send the first frame; 0 or why not. */
static uint32_t open_channel(co_sdo_client_t *c, co_sdo_request_t *req, const uint8_t *data)
{
    uint32_t code;
    co_sdo_client_channel_t *ch = pick_channel(c, req, &code);
    if (ch == NULL) {
        return code;
    }
    ch->req = req;
    ch->run++;
    ch->mode = (uint8_t)mode_of(c, req);
    ch->offset = 0;
    ch->total = 0;
    ch->toggle = 0;
    ch->last_sent = false;
    ch->crc = false;
    ch->crc_value = 0;
    ch->blksize = req->blksize != 0 ? req->blksize : (uint8_t)CO_SDO_CLIENT_DEFAULT_BLKSIZE;
    ch->seqno = 0;
    ch->segments = 0;
    ch->sub_last = false;
    ch->seen = false;
    ch->wait_space = false;
    ch->queued = 0;
    ch->sub_len = 0;
    ch->last_valid = false;
    req->abort = 0;
    req->abort_from_server = false;
    req->fell_back = false;
    req->crc_used = false;
    req->result_mode = req->upload && ch->mode != CO_SDO_MODE_BLOCK ? (uint8_t)CO_SDO_MODE_AUTO
                                                                    : ch->mode;
    req->result_channel = ch->number;
    req->total = 0;
    req->transferred = 0;
    ch->state = CO_SDO_CLIENT_UL_INIT;   /* taken; send_first sets the real state */
    ch->indicated = routed_of(req) != c->routed[req->server];
    if (routed_of(req) != 0) {
        memcpy(ch->first_data, data, sizeof ch->first_data);   /* kept for a resend */
    }
    code = ch->indicated ? send_network_indication(ch, data) : send_first(ch, data);
    if (code != 0) {
        release(ch);
    }
    return code;
}

uint32_t co_sdo_client_start(co_sdo_client_t *c, co_sdo_request_t *req)
{
    uint8_t data[CO_SDO_EXPEDITED_MAX];
    uint32_t code;
    if (c == NULL) {
        return CO_ABORT_GENERAL;
    }
    code = check_request(c, req);
    if (code == 0 && !req->upload && mode_of(c, req) == CO_SDO_MODE_EXPEDITED) {
        /* read before anything changes here (the source may call into the
         * client), so a failing source refuses the start and sends nothing */
        if (req->source(req->ctx, 0, data, req->size) != req->size) {
            c->stats.source_failed++;
            code = CO_ABORT_GENERAL;
        } else {
            code = check_request(c, req);
        }
    }
    if (code == 0) {
        code = open_channel(c, req, data);
    }
    if (code != 0) {
        c->stats.refused++;
        return code;
    }
    c->stats.started++;
    return 0;
}

/* ------------------------------------------------------------ receiving */

static bool expected(uint8_t state, uint8_t frame)
{
    switch (state) {
    case CO_SDO_CLIENT_DL_EXPEDITED:
    case CO_SDO_CLIENT_DL_INIT:
        return frame == CO_SDO_DOWNLOAD_INITIATE_RSP;
    case CO_SDO_CLIENT_DL_SEG:
        return frame == CO_SDO_DOWNLOAD_SEGMENT_RSP;
    case CO_SDO_CLIENT_UL_INIT:
        return frame == CO_SDO_UPLOAD_INITIATE_RSP;
    case CO_SDO_CLIENT_UL_SEG:
        return frame == CO_SDO_UPLOAD_SEGMENT_RSP;
    case CO_SDO_CLIENT_BD_INIT:
        return frame == CO_SDO_BLOCK_DOWNLOAD_INITIATE_RSP;
    case CO_SDO_CLIENT_BD_SEND:
    case CO_SDO_CLIENT_BD_ACK:
        return frame == CO_SDO_BLOCK_DOWNLOAD_ACK;
    case CO_SDO_CLIENT_BD_END:
        return frame == CO_SDO_BLOCK_DOWNLOAD_END_RSP;
    case CO_SDO_CLIENT_BU_INIT:
        return frame == CO_SDO_BLOCK_UPLOAD_INITIATE_RSP || frame == CO_SDO_UPLOAD_INITIATE_RSP;
    case CO_SDO_CLIENT_BU_END:
        return frame == CO_SDO_BLOCK_UPLOAD_END;
    default:
        return false;
    }
}

static bool initiating(uint8_t state)
{
    return state == CO_SDO_CLIENT_UL_INIT || state == CO_SDO_CLIENT_DL_EXPEDITED ||
           state == CO_SDO_CLIENT_DL_INIT || state == CO_SDO_CLIENT_BD_INIT ||
           state == CO_SDO_CLIENT_BU_INIT;
}

/* A server's abort. AUTO block refused as unknown: once more without. */
static void on_server_abort(co_sdo_client_channel_t *ch, uint32_t code)
{
    co_sdo_request_t *req = ch->req;
    ch->client->stats.aborts_received++;
    if (code == CO_ABORT_NO_RESOURCE && routed_of(req) != 0) {
        /* SDO networking: "no SDO connection" - the gateway ended ours (it
         * was rebuilt) or holds none; an initiate sent on the old connection
         * goes again once, after a new network indication */
        ch->client->routed[req->server] = ROUTED_UNKNOWN;
        if (initiating(ch->state) && !ch->indicated) {
            ch->indicated = true;
            if (send_network_indication(ch, NULL) != 0) {
                finish(ch, CO_ABORT_NO_RESOURCE, false);
            }
            return;
        }
    }
    if ((ch->state == CO_SDO_CLIENT_BD_INIT || ch->state == CO_SDO_CLIENT_BU_INIT) &&
        req->mode == CO_SDO_MODE_AUTO && code == CO_ABORT_COMMAND && !req->fell_back) {
        fall_back(ch);
        return;
    }
    finish(ch, code != 0 ? code : (uint32_t)CO_ABORT_GENERAL, true);
}

/* A frame on the channel's server -> client CAN-ID. */
static void handle(co_sdo_client_channel_t *ch, const co_frame_t *f)
{
    co_sdo_client_t *c = ch->client;
    const uint8_t *b = f->data;
    co_sdo_msg_t m;
    if (f->flags & CO_FRAME_FD) {
        c->stats.rx_fd++;
        return;
    }
    if (f->len != CO_SDO_FRAME_LEN) {
        c->stats.rx_bad_length++;
        return;
    }
    if (!is_busy(ch)) {
        c->stats.rx_idle++;
        return;
    }
    if (ch->state == CO_SDO_CLIENT_NET_IND) {
        on_network_answer(ch, b);
        return;
    }
    if (b[0] == CMD_ABORT) {
        (void)co_sdo_decode(b, CO_SDO_FRAME_LEN, CO_SDO_TO_CLIENT, &m);
        if ((m.index != ch->req->index || m.sub != ch->req->sub) && (m.index != 0 || m.sub != 0)) {
            c->stats.rx_bad_mux++;   /* an earlier transfer's abort, late */
            return;
        }
        on_server_abort(ch, m.abort_code);
        return;
    }
    if (ch->state == CO_SDO_CLIENT_BU_DATA) {
        on_block_upload_segment(ch, b);
        return;
    }
    if (ch->last_valid && memcmp(b, ch->last_rx, sizeof ch->last_rx) == 0 &&
        !(b[0] == CMD_BLOCK_ACK &&
          (ch->state == CO_SDO_CLIENT_BD_SEND || ch->state == CO_SDO_CLIENT_BD_ACK))) {
        c->stats.rx_duplicate++;
        return;
    }
    (void)co_sdo_decode(b, CO_SDO_FRAME_LEN, CO_SDO_TO_CLIENT, &m);
    if (m.frame == CO_SDO_UNKNOWN) {
        c->stats.rx_unknown_command++;
        fail(ch, CO_ABORT_COMMAND);
        return;
    }
    if (!expected(ch->state, m.frame)) {
        c->stats.rx_unexpected++;
        return;
    }
    if (co_sdo_frame_has_mux((co_sdo_frame_t)m.frame) &&
        (m.index != ch->req->index || m.sub != ch->req->sub)) {
        c->stats.rx_bad_mux++;
        return;
    }
    memcpy(ch->last_rx, b, sizeof ch->last_rx);
    ch->last_valid = true;
    arm_timeout(ch);
    switch (m.frame) {
    case CO_SDO_DOWNLOAD_INITIATE_RSP:
        if (ch->state == CO_SDO_CLIENT_DL_EXPEDITED) {
            finish(ch, 0, false);
        } else {
            send_download_segment(ch);
        }
        break;
    case CO_SDO_DOWNLOAD_SEGMENT_RSP:
        if (m.toggle != ch->toggle) {
            c->stats.rx_toggle++;
            fail(ch, CO_ABORT_TOGGLE);
        } else if (ch->last_sent) {
            finish(ch, 0, false);
        } else {
            ch->toggle ^= 1u;
            send_download_segment(ch);
        }
        break;
    case CO_SDO_UPLOAD_INITIATE_RSP:
        on_upload_initiate(ch, &m);
        break;
    case CO_SDO_UPLOAD_SEGMENT_RSP:
        on_upload_segment(ch, &m);
        break;
    case CO_SDO_BLOCK_DOWNLOAD_INITIATE_RSP:
        if (m.blksize < 1 || m.blksize > CO_SDO_BLKSIZE_MAX) {
            c->stats.rx_bad_blksize++;
            fail(ch, CO_ABORT_BLOCK_SIZE);
            break;
        }
        ch->crc = !ch->req->no_crc && m.crc;
        ch->req->crc_used = ch->crc;
        ch->crc_value = 0;
        ch->blksize = m.blksize;
        ch->queued = 0;
        start_sub_block(ch);
        break;
    case CO_SDO_BLOCK_DOWNLOAD_ACK:
        on_block_download_ack(ch, &m);
        break;
    case CO_SDO_BLOCK_DOWNLOAD_END_RSP:
        finish(ch, 0, false);
        break;
    case CO_SDO_BLOCK_UPLOAD_INITIATE_RSP:
        on_block_upload_initiate(ch, &m);
        break;
    default: /* CO_SDO_BLOCK_UPLOAD_END */
        on_block_upload_end(ch, &m);
        break;
    }
}

/* 0x581..0x5FF: the busy channel with that CAN-ID. */
static void on_range_frame(co_line_t *line, const co_frame_t *f, void *user)
{
    co_sdo_client_t *c = user;
    uint8_t i;
    (void)line;
    c->stats.rx_frames++;
    for (i = 0; i < c->channel_count; i++) {
        co_sdo_client_channel_t *ch = &c->channels[i];
        if (is_busy(ch) && ch->rx_id == f->id) {
            handle(ch, f);
            return;
        }
    }
    if (c->idle_tap != NULL && c->idle_tap(c, f, c->idle_user)) {
        return;
    }
    c->stats.rx_idle++;
}

void co_sdo_client_set_idle_tap(co_sdo_client_t *c, co_sdo_client_idle_fn fn, void *user)
{
    c->idle_tap = fn;
    c->idle_user = fn != NULL ? user : NULL;
}

void co_sdo_client_clear_idle_tap(co_sdo_client_t *c, co_sdo_client_idle_fn fn, void *user)
{
    if (c->idle_tap == fn && c->idle_user == user) {
        co_sdo_client_set_idle_tap(c, NULL, NULL);
    }
}

bool co_sdo_client_holds(const co_sdo_client_t *c, uint32_t id)
{
    return c->line != NULL && in_range(id) && co_line_id_taken_by(c->line, id, on_range_frame, c);
}

bool co_sdo_client_receives(const co_sdo_client_t *c, uint32_t id)
{
    for (uint8_t i = 0; i < c->channel_count; i++) {
        if (is_busy(&c->channels[i]) && c->channels[i].rx_id == id) {
            return true;
        }
    }
    return false;
}

/* A channel's own CAN-ID (outside the range). */
static void on_own_frame(co_line_t *line, const co_frame_t *f, void *user)
{
    co_sdo_client_channel_t *ch = user;
    (void)line;
    ch->client->stats.rx_frames++;
    handle(ch, f);
}

/* Per-frame timeout; in a block upload sub-block whose end never came, the
 * first expiry acknowledges what arrived. */
static void on_timeout(co_timer_t *timer, uint64_t now_us, void *user)
{
    co_sdo_client_channel_t *ch = user;
    (void)timer;
    (void)now_us;
    if (ch->state == CO_SDO_CLIENT_BU_DATA && ch->seen) {
        ch->client->stats.block_partial_acks++;
        send_block_upload_ack(ch, ch->seqno);
        arm_timeout(ch);
        return;
    }
    ch->client->stats.timeouts++;
    if (ch->state == CO_SDO_CLIENT_NET_IND) {
        ch->client->routed[ch->req->server] = ROUTED_UNKNOWN;   /* the gateway's state */
    }
    fail(ch, CO_ABORT_TIMEOUT);
}

/* ------------------------------------------------------------ configuration */

/* Up to three transfers a reconfiguration ends: the channel itself and
 * spares bound to the CAN-IDs it takes. They are freed first and reported
 * after the configuration is in place, so a done() that starts a request
 * sees it. */
typedef struct ended {
    co_sdo_request_t *req[3];
    uint8_t count;
} ended_t;

static void end_transfer(co_sdo_client_channel_t *ch, ended_t *e)
{
    co_sdo_request_t *req = ch->req;
    ch->client->stats.channel_resets++;
    send_abort(ch, CO_ABORT_GENERAL);
    release(ch);
    if (e->count < 3) {
        e->req[e->count++] = req;
    }
}

static void report_ended(co_sdo_client_t *c, const ended_t *e)
{
    uint8_t i;
    for (i = 0; i < e->count; i++) {
        report(c, e->req[i], CO_ABORT_GENERAL, false);
    }
}

/* Whether `ch` may take these CAN-IDs (valid ones, not used by another
 * configured channel, the received one free on the line). */
static bool ids_usable(co_sdo_client_t *c, const co_sdo_client_channel_t *ch, uint32_t tx,
                       uint32_t rx)
{
    if (!tx_id_ok(tx) || !rx_id_ok(rx) || tx == rx || holder_of(c, ch, tx, rx, false) != NULL) {
        return false;
    }
    if (!in_range(rx)) {
        if (co_line_id_taken(c->line, rx)) {
            return co_line_id_taken_by(c->line, rx, on_own_frame, ch);
        }
        return co_line_receiver_free(c->line);
    }
    return true;
}

/* Make channel `ch` use (tx, rx) for `server`, or nothing (want = false).
 * A transfer on it whose CAN-IDs change ends, as do spares' transfers on
 * CAN-IDs it takes. False when the CAN-IDs cannot be used (the channel is
 * then off). */
static bool apply(co_sdo_client_channel_t *ch, bool want, uint32_t tx, uint32_t rx, uint8_t server)
{
    co_sdo_client_t *c = ch->client;
    ended_t ended;
    bool ok = true;
    ended.count = 0;
    if (want && !ids_usable(c, ch, tx, rx)) {
        c->stats.config_refused++;
        want = false;
        ok = false;
    }
    if (is_busy(ch) && !(want && ch->tx_id == tx && ch->rx_id == rx)) {
        end_transfer(ch, &ended);
    }
    if (ch->subscribed && !(want && ch->rx_id == rx)) {
        co_line_unsubscribe(c->line, on_own_frame, ch);
        ch->subscribed = false;
    }
    ch->valid = false;
    ch->server = server;
    if (!is_busy(ch)) {
        ch->tx_id = 0;
        ch->rx_id = 0;
    }
    if (want) {
        co_sdo_client_channel_t *other;
        uint8_t guard;
        for (guard = 0; guard < 2; guard++) {
            other = holder_of(c, ch, tx, rx, true);
            if (other == NULL) {
                break;
            }
            end_transfer(other, &ended);   /* a spare bound to these CAN-IDs */
        }
        if (!in_range(rx) && !ch->subscribed) {
            if (!co_line_subscribe(c->line, rx, rx, on_own_frame, ch)) {
                c->stats.config_refused++;
                want = false;
                ok = false;
            } else {
                ch->subscribed = true;
            }
        }
    }
    if (want) {
        ch->valid = true;
        ch->tx_id = tx;
        ch->rx_id = rx;
    } else if (is_busy(ch)) {
        end_transfer(ch, &ended);
        ch->tx_id = 0;
        ch->rx_id = 0;
    }
    report_ended(c, &ended);
    return ok;
}

static uint16_t param_index(uint8_t number)
{
    return (uint16_t)(CO_SDO_CLIENT_PARAM + number);
}

/* An OD-bound channel: what 0x1280 + k says now. */
static void configure_from_od(co_sdo_client_channel_t *ch)
{
    co_sdo_client_t *c = ch->client;
    uint16_t index = param_index(ch->number);
    uint32_t tx = 0, rx = 0;
    uint8_t node = 0;
    bool want = co_od_get_u32(c->od, index, 1, &tx) && co_od_get_u32(c->od, index, 2, &rx) &&
                ((tx | rx) & CO_SDO_COB_INVALID) == 0;
    if (!co_od_get_u8(c->od, index, 3, &node) || node > NODE_MAX) {
        node = 0;
    }
    if (want && ((tx | rx) & COB_RESERVED) != 0) {
        c->stats.config_refused++;   /* 29-bit CAN-IDs are not used */
        want = false;
    }
    (void)apply(ch, want, tx & CO_SDO_COB_ID_MASK, rx & CO_SDO_COB_ID_MASK, node);
}

static uint32_t get_le32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

/* 0x1280 + k: a valid COB-ID must be an 11-bit CAN-ID the channel may use
 * (see tx_id_ok / rx_id_ok) and not used by another configured channel (the
 * received one not by another service of the line); the node-id 0..127.
 * (That a CAN-ID changes only while invalid is co_cob_id's rule.) */
static uint32_t check_param(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e,
                            const uint8_t *value, uint32_t length, void *user)
{
    co_sdo_client_t *c = user;
    uint8_t sub = co_od_entry_sub(e);
    uint8_t number = (uint8_t)(co_od_entry_index(e) - CO_SDO_CLIENT_PARAM);
    co_sdo_client_channel_t *ch;
    uint32_t v, id;
    (void)od;
    (void)xfer;
    if (number >= c->channel_count) {
        return 0;
    }
    ch = &c->channels[number];
    if (sub == 3 && e->type == CO_TYPE_UNSIGNED8 && length == 1) {
        return value[0] > NODE_MAX ? (uint32_t)CO_ABORT_INVALID_VALUE : 0u;
    }
    if ((sub != 1 && sub != 2) || e->type != CO_TYPE_UNSIGNED32 || length != 4) {
        return 0;
    }
    v = get_le32(value);
    if ((v & CO_SDO_COB_INVALID) != 0) {
        return 0;
    }
    id = v & CO_SDO_COB_ID_MASK;
    if ((v & COB_RESERVED) != 0 || !(sub == 1 ? tx_id_ok(id) : rx_id_ok(id))) {
        return CO_ABORT_INVALID_VALUE;
    }
    if (sub == 1 ? holder_of(c, ch, id, 0xFFFFFFFFu, false) != NULL
                 : holder_of(c, ch, 0xFFFFFFFFu, id, false) != NULL) {
        return CO_ABORT_INVALID_VALUE;
    }
    if (sub == 2 && !in_range(id)) {
        if (co_line_id_taken(c->line, id) && !co_line_id_taken_by(c->line, id, on_own_frame, ch)) {
            return CO_ABORT_INVALID_VALUE;
        }
    }
    return 0;
}

static void after_param(co_od_t *od, const co_od_entry_t *e, co_od_origin_t origin, void *user)
{
    co_sdo_client_t *c = user;
    uint16_t index = co_od_entry_index(e);
    uint8_t sub = co_od_entry_sub(e);
    (void)od;
    (void)origin;
    if (c->line != NULL && index >= CO_SDO_CLIENT_PARAM &&
        index < CO_SDO_CLIENT_PARAM + c->channel_count && sub >= 1 && sub <= 3) {
        co_sdo_client_channel_t *ch = &c->channels[index - CO_SDO_CLIENT_PARAM];
        if (ch->kind == CO_SDO_CLIENT_OD) {
            configure_from_od(ch);
        }
    }
}

static const co_od_handler_t param_handler = {
    .check_write = check_param,
    .after_write = after_param,
};

/* ------------------------------------------------------------ API */

bool co_sdo_client_init(co_sdo_client_t *c, co_line_t *line, const co_sdo_client_config_t *cfg)
{
    uint8_t i;
    if (c == NULL || line == NULL || cfg == NULL || cfg->channels == NULL ||
        cfg->channel_count == 0 || cfg->channel_count > CO_SDO_CLIENT_MAX_CHANNELS ||
        co_line_mode(line) != CO_MODE_CLASSIC) {
        return false;
    }
    memset(c, 0, sizeof *c);
    c->channels = cfg->channels;
    c->channel_count = cfg->channel_count;
    c->od = cfg->od;
    c->timeout_us = (uint64_t)(cfg->timeout_ms != 0 ? cfg->timeout_ms
                                                    : CO_SDO_CLIENT_DEFAULT_TIMEOUT_MS) *
                    1000u;
    c->block_threshold = cfg->block_threshold != 0 ? cfg->block_threshold
                                                   : (uint32_t)CO_SDO_CLIENT_DEFAULT_BLOCK_THRESHOLD;
    for (i = 0; i < cfg->channel_count; i++) {
        co_sdo_client_channel_t *ch = &cfg->channels[i];
        memset(ch, 0, sizeof *ch);
        ch->client = c;
        ch->number = i;
        co_timer_init(&ch->timer, on_timeout, ch);
        co_timer_init(&ch->pace, on_pace, ch);
        if (c->od != NULL && co_od_find(c->od, param_index(i), 1) != NULL &&
            co_od_find(c->od, param_index(i), 2) != NULL) {
            ch->kind = CO_SDO_CLIENT_OD;
        }
    }
    if (!co_line_subscribe(line, RANGE_FIRST, RANGE_LAST, on_range_frame, c)) {
        return false;
    }
    if (!co_line_tx_space_register(line, on_tx_space, c)) {
        co_line_unsubscribe(line, on_range_frame, c);
        return false;
    }
    if (c->od != NULL) {
        if (!co_od_subscribe(c->od, CO_SDO_CLIENT_PARAM, 0,
                             (uint16_t)(CO_SDO_CLIENT_PARAM + cfg->channel_count - 1u), 0xFF,
                             &param_handler, c)) {
            co_line_tx_space_unregister(line, on_tx_space, c);
            co_line_unsubscribe(line, on_range_frame, c);
            return false;
        }
        c->od_hooked = true;
    }
    c->line = line;
    co_sdo_client_refresh(c);
    return true;
}

void co_sdo_client_deinit(co_sdo_client_t *c)
{
    uint8_t i;
    if (c == NULL || c->line == NULL) {
        return;
    }
    co_line_unsubscribe(c->line, on_range_frame, c);
    co_line_tx_space_unregister(c->line, on_tx_space, c);
    if (c->od_hooked) {
        co_od_unsubscribe(c->od, &param_handler, c);
        c->od_hooked = false;
    }
    /* free every channel first (the request is kept for the report), then
     * report with the line gone, so a done() cannot start anything */
    for (i = 0; i < c->channel_count; i++) {
        co_sdo_client_channel_t *ch = &c->channels[i];
        co_sdo_request_t *req = ch->req;
        if (ch->subscribed) {
            co_line_unsubscribe(c->line, on_own_frame, ch);
            ch->subscribed = false;
        }
        if (is_busy(ch)) {
            release(ch);
            ch->req = req;
        }
        ch->valid = false;
    }
    c->line = NULL;
    for (i = 0; i < c->channel_count; i++) {
        co_sdo_client_channel_t *ch = &c->channels[i];
        if (ch->req != NULL) {
            co_sdo_request_t *req = ch->req;
            ch->req = NULL;
            report(c, req, CO_ABORT_GENERAL, false);
        }
    }
}

void co_sdo_client_refresh(co_sdo_client_t *c)
{
    uint8_t i;
    if (c == NULL || c->line == NULL) {
        return;
    }
    for (i = 0; i < c->channel_count; i++) {
        if (c->channels[i].kind == CO_SDO_CLIENT_OD) {
            configure_from_od(&c->channels[i]);
        }
    }
}

bool co_sdo_client_channel_set(co_sdo_client_t *c, uint8_t ch, uint8_t server, uint32_t tx_id,
                               uint32_t rx_id)
{
    co_sdo_client_channel_t *chan;
    if (c == NULL || c->line == NULL || ch >= c->channel_count || server > NODE_MAX) {
        return false;
    }
    chan = &c->channels[ch];
    if (chan->kind == CO_SDO_CLIENT_OD) {
        return false;
    }
    if (tx_id == 0 && rx_id == 0) {
        if (server == 0) {
            return false;
        }
        tx_id = co_sdo_request_id(server);
        rx_id = co_sdo_response_id(server);
    }
    if (!ids_usable(c, chan, tx_id, rx_id)) {
        c->stats.config_refused++;
        return false;
    }
    chan->kind = CO_SDO_CLIENT_SET;
    return apply(chan, true, tx_id, rx_id, server);
}

bool co_sdo_client_channel_clear(co_sdo_client_t *c, uint8_t ch)
{
    co_sdo_client_channel_t *chan;
    if (c == NULL || c->line == NULL || ch >= c->channel_count) {
        return false;
    }
    chan = &c->channels[ch];
    if (chan->kind == CO_SDO_CLIENT_OD) {
        return false;
    }
    if (chan->kind == CO_SDO_CLIENT_SET) {
        (void)apply(chan, false, 0, 0, 0);
        chan->kind = CO_SDO_CLIENT_SPARE;
    }
    return true;
}

bool co_sdo_client_cancel(co_sdo_client_t *c, co_sdo_request_t *req, uint32_t code)
{
    uint8_t i;
    if (c == NULL || c->line == NULL || req == NULL) {
        return false;
    }
    for (i = 0; i < c->channel_count; i++) {
        co_sdo_client_channel_t *ch = &c->channels[i];
        if (is_busy(ch) && ch->req == req) {
            c->stats.cancelled++;
            fail(ch, code != 0 ? code : (uint32_t)CO_ABORT_GENERAL);
            return true;
        }
    }
    return false;
}

uint8_t co_sdo_client_active(const co_sdo_client_t *c)
{
    uint8_t i, n = 0;
    for (i = 0; i < c->channel_count; i++) {
        if (is_busy(&c->channels[i])) {
            n++;
        }
    }
    return n;
}

bool co_sdo_client_running(const co_sdo_client_t *c, const co_sdo_request_t *req)
{
    return c != NULL && req != NULL && running(c, req);
}

/* ------------------------------------------------------------ buffers */

uint32_t co_sdo_buffer_source(void *ctx, uint32_t offset, uint8_t *buf, uint32_t want)
{
    return co_buffer_read(ctx, offset, buf, want);
}

uint32_t co_sdo_buffer_sink(void *ctx, uint32_t offset, const uint8_t *data, uint32_t len,
                            uint32_t total)
{
    bool known = total != CO_SDO_CLIENT_SIZE_UNKNOWN;
    return co_buffer_put(ctx, offset, data, len, total, known) ? 0u : CO_ABORT_OUT_OF_MEMORY;
}
