/* Classic SDO server: see co_sdo_server.h for the channel model and
 * docs/protocol-notes.md ("Classic SDO") for every wire choice.
 *
 * Rules where CiA 301's public descriptions leave room (all in
 * protocol-notes.md):
 *  - Frames that are not exactly 8 bytes are ignored and counted, as
 *    CANopenNode does; FD frames likewise (a classic line drops them before).
 *  - A client abort (byte 0 = 0x80) ends the open transfer (the object
 *    dictionary is told) and is never answered; one for no transfer is
 *    counted and ignored.
 *  - An initiate on a busy channel ends the open transfer silently and
 *    starts the new one; while the channel waits on the application (split)
 *    the waiting transfer is abandoned and the new one is refused with
 *    0x060A0023 until the application answers. In a block download sub-block
 *    every frame but 0x80 is a segment, so no initiate is seen there.
 *  - A frame the channel's state does not expect: 0x05040001 (the open
 *    transfer ends). Except, ignored and counted: a repeat of the frame that
 *    completed the last transfer (a CAN double reception), a repeat of the
 *    last segment while the block download end is expected.
 *  - Expedited download without size (e = 1, s = 0): the entry's size when it
 *    is a fixed-size type of 1..3 bytes, else all 4 bytes (CANopenNode).
 *  - Uploads of 1..4 bytes (size known) are expedited, everything else
 *    segmented; an unknown size is not indicated (0x40).
 *  - Block download: segments in order are taken (written through to the
 *    object dictionary; the last one, c = 1, is held until the end frame
 *    gives n); a repeated segment (seqno <= last good) is ignored; a segment
 *    after a gap is ignored, and when it ends the sub-block (seqno = blksize
 *    or c = 1) the sub-block is acknowledged with the last good seqno, so the
 *    client repeats from there. At the start of a sub-block (no good segment
 *    yet) out-of-order segments are only ignored (a repeat of the previous
 *    sub-block's end looks like that). A sub-block whose end never comes is
 *    acknowledged when the idle timeout runs out once; without any segment
 *    since the last acknowledgement the timeout aborts.
 *  - Block upload: the server keeps the unacknowledged data of a sub-block
 *    (CO_SDO_SERVER_BUFFER) and sends it again, renumbered from 1, after a
 *    short acknowledgement; segments go out while the tx queue is below three
 *    quarters full and resume on the line's tx-space indication.
 *  - Block transfers: our blksize is the configured one for every sub-block;
 *    seqno 0 or above the block size -> 0x05040003, client blksize 0 or above
 *    127 -> 0x05040002, an ack above the segments sent -> 0x05040003, CRC
 *    mismatch -> 0x05040004 (download: checked only when both sides
 *    announced CRC support; upload: sent whenever we support it). */
#include "canopenfd/co_sdo_server.h"

#include "co_cob_id.h"
#include "co_crc.h"

#include <string.h>

enum answer {
    ANSWER_NONE = 0,
    ANSWER_UPLOAD,                 /* expedited / segmented upload response */
    ANSWER_BLOCK_UPLOAD,           /* block upload initiate response (or the pst switch) */
    ANSWER_DOWNLOAD_EXPEDITED,     /* 0x60 */
    ANSWER_DOWNLOAD_LAST,          /* 0x20 | t<<4 for the last segment */
    ANSWER_BLOCK_DOWNLOAD_END      /* 0xA1 */
};

/* Bits 11..29 of a valid SDO COB-ID: must be 0 (11-bit CAN-IDs only). */
#define COB_RESERVED 0x3FFFF800u

static void on_frame(co_line_t *line, const co_frame_t *f, void *user);

/* ------------------------------------------------------------ sending */

static bool send_msg(co_sdo_channel_t *ch, const co_sdo_msg_t *m)
{
    co_sdo_server_t *s = ch->server;
    uint8_t buf[CO_SDO_FRAME_LEN];
    if (co_sdo_encode(m, buf) == 0 || !co_line_send(s->line, ch->tx_id, buf, sizeof buf)) {
        s->stats.tx_failed++;
        return false;
    }
    return true;
}

static void msg_init(const co_sdo_channel_t *ch, co_sdo_frame_t frame, co_sdo_msg_t *m)
{
    memset(m, 0, sizeof *m);
    m->frame = (uint8_t)frame;
    m->index = ch->index;
    m->sub = ch->sub;
}

static void send_abort(co_sdo_channel_t *ch, uint16_t index, uint8_t sub, uint32_t code)
{
    co_sdo_msg_t m;
    memset(&m, 0, sizeof m);
    m.frame = CO_SDO_ABORT;
    m.index = index;
    m.sub = sub;
    m.abort_code = code;
    ch->server->stats.aborts_sent++;
    (void)send_msg(ch, &m);
}

static void send_simple(co_sdo_channel_t *ch, co_sdo_frame_t frame, uint8_t toggle)
{
    co_sdo_msg_t m;
    msg_init(ch, frame, &m);
    m.toggle = toggle;
    (void)send_msg(ch, &m);
}

/* ------------------------------------------------------------ channels */

static bool is_open(const co_sdo_channel_t *ch)
{
    return ch->state != CO_SDO_CH_IDLE && ch->state != CO_SDO_CH_ABANDONED;
}

static void release(co_sdo_channel_t *ch)
{
    co_timer_cancel(co_line_timers(ch->server->line), &ch->timer);
    ch->state = CO_SDO_CH_IDLE;
    ch->answer = ANSWER_NONE;
    ch->tx_wait = false;
    ch->tx_resume = false;
}

/* Re-arm the idle timeout (every frame of the transfer). */
static void touch(co_sdo_channel_t *ch)
{
    co_sdo_server_t *s = ch->server;
    co_timer_start(co_line_timers(s->line), &ch->timer, co_line_now(s->line) + s->timeout_us);
}

/* End the open transfer: the object dictionary is told (a domain writer
 * learns of it), the abort frame is sent when `send`. A transfer that waits
 * on the application keeps its channel (ABANDONED) until the resume. */
static void close_channel(co_sdo_channel_t *ch, uint32_t code, bool send)
{
    co_od_xfer_abort(&ch->xfer, code);
    if (send) {
        send_abort(ch, ch->index, ch->sub, code);
    }
    ch->done_valid = false;
    if (ch->state == CO_SDO_CH_PENDING) {
        co_timer_cancel(co_line_timers(ch->server->line), &ch->timer);
        ch->state = CO_SDO_CH_ABANDONED;
        ch->tx_wait = false;
        ch->tx_resume = false;
    } else {
        release(ch);
    }
}

static void od_fail(co_sdo_channel_t *ch, uint32_t abort)
{
    ch->server->stats.od_aborts++;
    close_channel(ch, abort, true);
}

/* The transfer completed. `by_frame`: the frame just received completed it
 * (not an initiate), so a repeat of it is recognised afterwards. */
static void finish(co_sdo_channel_t *ch, bool download, bool by_frame)
{
    co_sdo_server_t *s = ch->server;
    if (download) {
        s->stats.downloads++;
    } else {
        s->stats.uploads++;
    }
    if (by_frame) {
        memcpy(ch->done, ch->rx, sizeof ch->done);
    }
    ch->done_valid = by_frame;
    release(ch);
}

/* ------------------------------------------------------------ upload data */

/* Read from the object dictionary into the channel buffer until `want`
 * bytes are queued or the data ended. The CRC (block upload) is taken over
 * each byte once, as it is read. */
static uint32_t queue_fill(co_sdo_channel_t *ch, uint32_t want)
{
    if (want > CO_SDO_SERVER_BUFFER) {
        want = CO_SDO_SERVER_BUFFER;
    }
    while (!ch->data_end && ch->queued < want) {
        uint32_t got = 0;
        bool end = false;
        uint8_t *at = ch->buf + ch->queued;
        uint32_t r = co_od_read_chunk(&ch->xfer, at, want - ch->queued, &got, &end);
        if (r != 0) {
            return r;
        }
        if (ch->crc && got > 0) {
            ch->crc_value = co_crc16_ccitt(ch->crc_value, at, got);
        }
        ch->queued = (uint16_t)(ch->queued + got);
        if (end) {
            ch->data_end = true;
        } else if (got == 0) {
            /* a reader that gives nothing and does not end */
            co_od_xfer_abort(&ch->xfer, CO_ABORT_GENERAL);
            return CO_ABORT_GENERAL;
        }
    }
    return 0;
}

static void queue_take(co_sdo_channel_t *ch, uint32_t n)
{
    if (n >= ch->queued) {
        ch->queued = 0;
        return;
    }
    memmove(ch->buf, ch->buf + n, ch->queued - n);
    ch->queued = (uint16_t)(ch->queued - n);
}

/* ------------------------------------------------------------ answers */

/* The upload initiate response: expedited for 1..4 bytes of known size,
 * else segmented with the size when known. */
static void answer_upload(co_sdo_channel_t *ch)
{
    uint32_t total = ch->xfer.total;
    co_sdo_msg_t m;
    ch->crc = false;
    ch->queued = 0;
    ch->data_end = false;
    msg_init(ch, CO_SDO_UPLOAD_INITIATE_RSP, &m);
    if (total != CO_OD_SIZE_UNKNOWN && total >= 1 && total <= CO_SDO_EXPEDITED_MAX) {
        uint32_t r = queue_fill(ch, total);
        if (r != 0) {
            od_fail(ch, r);
            return;
        }
        m.expedited = true;
        m.size_indicated = true;
        m.length = (uint8_t)ch->queued;
        m.data = ch->buf;
        (void)send_msg(ch, &m);
        finish(ch, false, false);
        return;
    }
    m.size_indicated = total != CO_OD_SIZE_UNKNOWN;
    m.size = m.size_indicated ? total : 0;
    (void)send_msg(ch, &m);
    ch->state = CO_SDO_CH_UPLOAD;
    ch->toggle = 0;
    touch(ch);
}

/* The block upload initiate response, or the switch to a normal upload when
 * the size is known and at most pst bytes. */
static void answer_block_upload(co_sdo_channel_t *ch)
{
    co_sdo_server_t *s = ch->server;
    uint32_t total = ch->xfer.total;
    co_sdo_msg_t m;
    if (ch->pst != 0 && total != CO_OD_SIZE_UNKNOWN && total <= ch->pst) {
        s->stats.protocol_switches++;
        answer_upload(ch);
        return;
    }
    ch->crc_value = 0;
    ch->queued = 0;
    ch->data_end = false;
    msg_init(ch, CO_SDO_BLOCK_UPLOAD_INITIATE_RSP, &m);
    m.crc = s->crc;
    m.size_indicated = total != CO_OD_SIZE_UNKNOWN;
    m.size = m.size_indicated ? total : 0;
    (void)send_msg(ch, &m);
    ch->state = CO_SDO_CH_BLOCK_UPLOAD_START;
    touch(ch);
}

/* What a co_od call returned: wait (split), refuse, or answer. */
static void after_od(co_sdo_channel_t *ch, uint32_t r, uint8_t answer)
{
    if (r == CO_OD_SPLIT) {
        ch->state = CO_SDO_CH_PENDING;
        ch->answer = answer;
        return;
    }
    if (r != 0) {
        od_fail(ch, r);
        return;
    }
    switch (answer) {
    case ANSWER_UPLOAD:
        answer_upload(ch);
        break;
    case ANSWER_BLOCK_UPLOAD:
        answer_block_upload(ch);
        break;
    case ANSWER_DOWNLOAD_EXPEDITED:
        send_simple(ch, CO_SDO_DOWNLOAD_INITIATE_RSP, 0);
        finish(ch, true, false);
        break;
    case ANSWER_DOWNLOAD_LAST:
        send_simple(ch, CO_SDO_DOWNLOAD_SEGMENT_RSP, ch->toggle);
        finish(ch, true, true);
        break;
    case ANSWER_BLOCK_DOWNLOAD_END:
        send_simple(ch, CO_SDO_BLOCK_DOWNLOAD_END_RSP, 0);
        finish(ch, true, true);
        break;
    default:
        close_channel(ch, CO_ABORT_GENERAL, true);
        break;
    }
}

/* ------------------------------------------------------------ block upload */

/* Send the segments of the current sub-block not sent yet, while the tx
 * queue has room; else wait for the tx-space indication. */
static void send_segments(co_sdo_channel_t *ch)
{
    co_sdo_server_t *s = ch->server;
    while (ch->seqno < ch->segments) {
        co_sdo_msg_t m;
        uint32_t off = (uint32_t)ch->seqno * CO_SDO_SEGMENT_DATA;
        uint32_t left = ch->sub_len > off ? ch->sub_len - off : 0;
        if (co_line_tx_room(s->line) == 0) {
            if (!ch->tx_wait) {
                s->stats.tx_deferred++;
            }
            ch->tx_wait = true;
            return;
        }
        memset(&m, 0, sizeof m);
        m.frame = CO_SDO_BLOCK_SEGMENT;
        m.seqno = (uint8_t)(ch->seqno + 1u);
        m.last = ch->sub_last && m.seqno == ch->segments;
        m.length = (uint8_t)(left < CO_SDO_SEGMENT_DATA ? left : CO_SDO_SEGMENT_DATA);
        m.data = ch->buf + off;
        (void)send_msg(ch, &m);   /* a lost segment is repeated after the client's ack */
        ch->seqno++;
    }
    ch->tx_wait = false;
}

/* Start the next sub-block: queue blksize segments of data (plus one byte
 * to know whether they end the data) and send them. */
static void send_sub_block(co_sdo_channel_t *ch)
{
    uint32_t cap = (uint32_t)ch->blksize * CO_SDO_SEGMENT_DATA;
    uint32_t r = queue_fill(ch, cap + 1u);
    if (r != 0) {
        od_fail(ch, r);
        return;
    }
    if (ch->queued > cap) {
        ch->sub_len = (uint16_t)cap;
        ch->sub_last = false;
    } else {
        ch->sub_len = ch->queued;
        ch->sub_last = true;   /* queue_fill stopped below cap + 1: the data ended */
    }
    /* an empty rest (empty value, or data ending on a sub-block boundary of
     * an unknown-size domain) still needs one segment to carry c = 1 */
    ch->segments = (uint8_t)(ch->sub_len == 0 ? 1u
                                              : (ch->sub_len + CO_SDO_SEGMENT_DATA - 1u) /
                                                    CO_SDO_SEGMENT_DATA);
    ch->seqno = 0;
    ch->tx_wait = false;
    ch->tx_resume = false;
    ch->state = CO_SDO_CH_BLOCK_UPLOAD;
    touch(ch);
    send_segments(ch);
}

static void on_block_upload_ack(co_sdo_channel_t *ch, const co_sdo_msg_t *m)
{
    co_sdo_server_t *s = ch->server;
    uint32_t acked;
    if (m->blksize < 1 || m->blksize > CO_SDO_BLKSIZE_MAX) {
        s->stats.rx_bad_blksize++;
        close_channel(ch, CO_ABORT_BLOCK_SIZE, true);
        return;
    }
    if (m->seqno > ch->seqno) {
        /* acknowledges a segment we did not send */
        s->stats.rx_bad_seqno++;
        close_channel(ch, CO_ABORT_SEQUENCE, true);
        return;
    }
    ch->tx_wait = false;
    ch->tx_resume = false;
    acked = (uint32_t)m->seqno * CO_SDO_SEGMENT_DATA;
    if (acked > ch->sub_len) {
        acked = ch->sub_len;
    }
    if (m->seqno == ch->segments && ch->sub_last) {
        co_sdo_msg_t end;
        queue_take(ch, acked);
        msg_init(ch, CO_SDO_BLOCK_UPLOAD_END, &end);
        end.unused = (uint8_t)((uint32_t)ch->segments * CO_SDO_SEGMENT_DATA - ch->sub_len);
        end.crc_value = ch->crc ? ch->crc_value : 0;
        (void)send_msg(ch, &end);
        ch->state = CO_SDO_CH_BLOCK_UPLOAD_END;
        touch(ch);
        return;
    }
    if (m->seqno < ch->seqno) {
        s->stats.block_repeats += (uint32_t)(ch->seqno - m->seqno);
    }
    queue_take(ch, acked);
    ch->blksize = m->blksize;
    send_sub_block(ch);
}

/* ------------------------------------------------------------ block download */

static void send_block_ack(co_sdo_channel_t *ch, uint8_t ackseq)
{
    co_sdo_msg_t m;
    msg_init(ch, CO_SDO_BLOCK_DOWNLOAD_ACK, &m);
    m.seqno = ackseq;
    m.blksize = ch->blksize;
    (void)send_msg(ch, &m);
    ch->seqno = 0;
    ch->seen = false;
}

/* A frame in a block download sub-block (anything but the abort 0x80). */
static void on_block_segment(co_sdo_channel_t *ch, const uint8_t *b)
{
    co_sdo_server_t *s = ch->server;
    co_sdo_msg_t m;
    (void)co_sdo_decode_block_segment(b, CO_SDO_FRAME_LEN, &m);
    if (m.seqno == 0 || m.seqno > ch->blksize) {
        s->stats.rx_bad_seqno++;
        close_channel(ch, CO_ABORT_SEQUENCE, true);
        return;
    }
    touch(ch);
    ch->seen = true;
    if (m.seqno == ch->seqno + 1u) {
        ch->seqno = m.seqno;
        if (m.last) {
            memcpy(ch->held, b, sizeof ch->held);   /* n comes with the end frame */
        } else {
            uint32_t r = co_od_write_chunk(&ch->xfer, m.data, m.length);
            if (r != 0) {
                od_fail(ch, r);
                return;
            }
            if (ch->crc) {
                ch->crc_value = co_crc16_ccitt(ch->crc_value, m.data, m.length);
            }
        }
        if (m.last) {
            send_block_ack(ch, m.seqno);
            ch->state = CO_SDO_CH_BLOCK_DOWNLOAD_END;
        } else if (m.seqno == ch->blksize) {
            send_block_ack(ch, m.seqno);
        }
        return;
    }
    s->stats.rx_block_ignored++;
    if (m.seqno > ch->seqno && ch->seqno != 0 && (m.last || m.seqno == ch->blksize)) {
        /* the end of a sub-block with a gap: the client repeats after the
         * last good segment */
        s->stats.block_partial_acks++;
        send_block_ack(ch, ch->seqno);
    }
}

static void on_block_download_end(co_sdo_channel_t *ch, const co_sdo_msg_t *m)
{
    co_sdo_server_t *s = ch->server;
    uint8_t n = (uint8_t)(CO_SDO_SEGMENT_DATA - m->unused);
    uint32_t r;
    touch(ch);
    if (ch->crc && co_crc16_ccitt(ch->crc_value, ch->held + 1, n) != m->crc_value) {
        s->stats.rx_crc++;
        close_channel(ch, CO_ABORT_CRC, true);
        return;
    }
    r = co_od_write_chunk(&ch->xfer, ch->held + 1, n);
    if (r != 0) {
        od_fail(ch, r);
        return;
    }
    ch->state = CO_SDO_CH_ACTIVE;
    after_od(ch, co_od_write_end(&ch->xfer), ANSWER_BLOCK_DOWNLOAD_END);
}

/* ------------------------------------------------------------ segmented */

static void on_download_segment(co_sdo_channel_t *ch, const co_sdo_msg_t *m)
{
    co_sdo_server_t *s = ch->server;
    uint32_t r;
    if (m->toggle != ch->toggle) {
        s->stats.rx_toggle++;
        close_channel(ch, CO_ABORT_TOGGLE, true);
        return;
    }
    touch(ch);
    r = co_od_write_chunk(&ch->xfer, m->data, m->length);
    if (r != 0) {
        od_fail(ch, r);
        return;
    }
    if (m->last) {
        ch->state = CO_SDO_CH_ACTIVE;
        after_od(ch, co_od_write_end(&ch->xfer), ANSWER_DOWNLOAD_LAST);
        return;
    }
    send_simple(ch, CO_SDO_DOWNLOAD_SEGMENT_RSP, ch->toggle);
    ch->toggle ^= 1u;
}

static void on_upload_segment(co_sdo_channel_t *ch, const co_sdo_msg_t *m)
{
    co_sdo_server_t *s = ch->server;
    co_sdo_msg_t out;
    uint32_t r;
    uint8_t n;
    bool last;
    if (m->toggle != ch->toggle) {
        s->stats.rx_toggle++;
        close_channel(ch, CO_ABORT_TOGGLE, true);
        return;
    }
    r = queue_fill(ch, CO_SDO_SEGMENT_DATA + 1u);   /* one byte more: is this the last? */
    if (r != 0) {
        od_fail(ch, r);
        return;
    }
    n = (uint8_t)(ch->queued < CO_SDO_SEGMENT_DATA ? ch->queued : CO_SDO_SEGMENT_DATA);
    last = ch->data_end && ch->queued <= CO_SDO_SEGMENT_DATA;
    memset(&out, 0, sizeof out);
    out.frame = CO_SDO_UPLOAD_SEGMENT_RSP;
    out.toggle = ch->toggle;
    out.length = n;
    out.last = last;
    out.data = ch->buf;
    (void)send_msg(ch, &out);
    queue_take(ch, n);
    ch->toggle ^= 1u;
    if (last) {
        finish(ch, false, true);
    } else {
        touch(ch);
    }
}

/* ------------------------------------------------------------ initiate */

/* Bytes an expedited download without size indication writes. */
static uint32_t unsized_length(const co_sdo_server_t *s, uint16_t index, uint8_t sub)
{
    const co_od_entry_t *e = co_od_find(s->od, index, sub);
    uint32_t size = e != NULL ? co_od_type_size(e->type) : 0;
    return (size >= 1 && size < CO_SDO_EXPEDITED_MAX) ? size : CO_SDO_EXPEDITED_MAX;
}

static void on_initiate(co_sdo_channel_t *ch, const co_sdo_msg_t *m)
{
    co_sdo_server_t *s = ch->server;
    uint32_t r;
    if (ch->state == CO_SDO_CH_PENDING) {
        s->stats.restarts++;
        close_channel(ch, CO_ABORT_GENERAL, false);
    }
    if (ch->state == CO_SDO_CH_ABANDONED) {
        s->stats.refused_busy++;
        send_abort(ch, m->index, m->sub, CO_ABORT_NO_RESOURCE);
        return;
    }
    if (is_open(ch)) {
        s->stats.restarts++;
        close_channel(ch, CO_ABORT_GENERAL, false);
    }
    ch->done_valid = false;
    if (m->frame == CO_SDO_BLOCK_UPLOAD_INITIATE &&
        (m->blksize < 1 || m->blksize > CO_SDO_BLKSIZE_MAX)) {
        s->stats.rx_bad_blksize++;
        send_abort(ch, m->index, m->sub, CO_ABORT_BLOCK_SIZE);
        return;
    }
    ch->state = CO_SDO_CH_ACTIVE;
    ch->answer = ANSWER_NONE;
    ch->index = m->index;
    ch->sub = m->sub;
    ch->toggle = 0;
    ch->crc = m->crc && s->crc;
    ch->crc_value = 0;
    ch->blksize = s->blksize;
    ch->pst = 0;
    ch->seqno = 0;
    ch->segments = 0;
    ch->seen = false;
    ch->queued = 0;
    ch->data_end = false;
    ch->tx_wait = false;
    ch->tx_resume = false;
    touch(ch);
    switch (m->frame) {
    case CO_SDO_DOWNLOAD_INITIATE:
        if (m->expedited) {
            uint32_t n = m->size_indicated ? m->length : unsized_length(s, m->index, m->sub);
            r = co_od_write_begin(s->od, &ch->xfer, m->index, m->sub, n);
            if (r == 0) {
                r = co_od_write_chunk(&ch->xfer, m->data, n);
            }
            if (r == 0) {
                r = co_od_write_end(&ch->xfer);
            }
            after_od(ch, r, ANSWER_DOWNLOAD_EXPEDITED);
            break;
        }
        r = co_od_write_begin(s->od, &ch->xfer, m->index, m->sub,
                              m->size_indicated ? m->size : CO_OD_SIZE_UNKNOWN);
        if (r != 0) {
            od_fail(ch, r);
            break;
        }
        ch->state = CO_SDO_CH_DOWNLOAD;
        send_simple(ch, CO_SDO_DOWNLOAD_INITIATE_RSP, 0);
        break;
    case CO_SDO_BLOCK_DOWNLOAD_INITIATE: {
        co_sdo_msg_t rsp;
        r = co_od_write_begin(s->od, &ch->xfer, m->index, m->sub,
                              m->size_indicated ? m->size : CO_OD_SIZE_UNKNOWN);
        if (r != 0) {
            od_fail(ch, r);
            break;
        }
        ch->state = CO_SDO_CH_BLOCK_DOWNLOAD;
        msg_init(ch, CO_SDO_BLOCK_DOWNLOAD_INITIATE_RSP, &rsp);
        rsp.crc = s->crc;
        rsp.blksize = ch->blksize;
        (void)send_msg(ch, &rsp);
        break;
    }
    case CO_SDO_BLOCK_UPLOAD_INITIATE:
        /* the CRC goes out whenever we support it: a client that did not
         * ask ignores it, one that looks only at sc (python-canopen) finds
         * it right */
        ch->crc = s->crc;
        ch->blksize = m->blksize;
        ch->pst = m->pst;
        after_od(ch, co_od_read_begin(s->od, &ch->xfer, m->index, m->sub), ANSWER_BLOCK_UPLOAD);
        break;
    default: /* CO_SDO_UPLOAD_INITIATE */
        after_od(ch, co_od_read_begin(s->od, &ch->xfer, m->index, m->sub), ANSWER_UPLOAD);
        break;
    }
}

/* ------------------------------------------------------------ frames */

/* The one frame (other than initiates and aborts) each state expects. */
static co_sdo_frame_t expected_frame(uint8_t state)
{
    switch (state) {
    case CO_SDO_CH_DOWNLOAD:
        return CO_SDO_DOWNLOAD_SEGMENT;
    case CO_SDO_CH_UPLOAD:
        return CO_SDO_UPLOAD_SEGMENT;
    case CO_SDO_CH_BLOCK_DOWNLOAD_END:
        return CO_SDO_BLOCK_DOWNLOAD_END;
    case CO_SDO_CH_BLOCK_UPLOAD_START:
        return CO_SDO_BLOCK_UPLOAD_START;
    case CO_SDO_CH_BLOCK_UPLOAD:
        return CO_SDO_BLOCK_UPLOAD_ACK;
    case CO_SDO_CH_BLOCK_UPLOAD_END:
        return CO_SDO_BLOCK_UPLOAD_END_RSP;
    default:
        return CO_SDO_UNKNOWN;
    }
}

static void handle(co_sdo_channel_t *ch, const uint8_t *b)
{
    co_sdo_server_t *s = ch->server;
    co_sdo_msg_t m;
    memcpy(ch->rx, b, sizeof ch->rx);
    (void)co_sdo_decode(b, CO_SDO_FRAME_LEN, CO_SDO_TO_SERVER, &m);
    if (m.frame == CO_SDO_ABORT) {
        if (!is_open(ch)) {
            s->stats.rx_stray_abort++;
            return;
        }
        s->stats.rx_client_abort++;
        close_channel(ch, m.abort_code != 0 ? m.abort_code : CO_ABORT_GENERAL, false);
        return;
    }
    if (ch->state == CO_SDO_CH_BLOCK_DOWNLOAD) {
        on_block_segment(ch, b);
        return;
    }
    if (ch->state == CO_SDO_CH_BLOCK_DOWNLOAD_END && memcmp(b, ch->held, sizeof ch->held) == 0) {
        s->stats.rx_duplicate++;   /* the last segment again */
        return;
    }
    if (co_sdo_frame_is_initiate((co_sdo_frame_t)m.frame)) {
        on_initiate(ch, &m);
        return;
    }
    if (!is_open(ch)) {
        if (ch->done_valid && memcmp(b, ch->done, sizeof ch->done) == 0) {
            s->stats.rx_duplicate++;   /* the frame that ended the last transfer again */
            return;
        }
        s->stats.rx_unknown_command++;
        send_abort(ch, 0, 0, CO_ABORT_COMMAND);
        return;
    }
    if (m.frame == CO_SDO_UNKNOWN || m.frame != expected_frame(ch->state)) {
        s->stats.rx_unknown_command++;
        close_channel(ch, CO_ABORT_COMMAND, true);
        return;
    }
    switch (m.frame) {
    case CO_SDO_DOWNLOAD_SEGMENT:
        on_download_segment(ch, &m);
        break;
    case CO_SDO_UPLOAD_SEGMENT:
        on_upload_segment(ch, &m);
        break;
    case CO_SDO_BLOCK_DOWNLOAD_END:
        on_block_download_end(ch, &m);
        break;
    case CO_SDO_BLOCK_UPLOAD_START:
        send_sub_block(ch);
        break;
    case CO_SDO_BLOCK_UPLOAD_ACK:
        on_block_upload_ack(ch, &m);
        break;
    default: /* CO_SDO_BLOCK_UPLOAD_END_RSP */
        finish(ch, false, true);
        break;
    }
}

/* ------------------------------------------------------------ configuration */

/* The CAN-IDs a channel should use now; false when it should be off. */
static bool wanted_ids(co_sdo_server_t *s, uint8_t number, uint32_t *rx, uint32_t *tx)
{
    uint32_t c2s = 0, s2c = 0;
    if (number == 0) {
        uint8_t nid = co_line_node_id(s->line);
        if (nid < 1 || nid > 127) {
            return false;
        }
        *rx = co_sdo_request_id(nid);
        *tx = co_sdo_response_id(nid);
        return true;
    }
    if (!co_od_get_u32(s->od, (uint16_t)(CO_SDO_SERVER_PARAM + number), 1, &c2s) ||
        !co_od_get_u32(s->od, (uint16_t)(CO_SDO_SERVER_PARAM + number), 2, &s2c) ||
        ((c2s | s2c) & CO_SDO_COB_INVALID) != 0) {
        return false;
    }
    if (((c2s | s2c) & COB_RESERVED) != 0) {
        s->stats.config_refused++;   /* 29-bit CAN-IDs are not served */
        return false;
    }
    *rx = c2s & CO_SDO_COB_ID_MASK;
    *tx = s2c & CO_SDO_COB_ID_MASK;
    return true;
}

/* Make the channel use what its COB-IDs say now. While the channel is
 * inside a co_od call (it is the one writing its own COB-ID) the change
 * waits until its answer went out on the old CAN-ID. */
static void configure(co_sdo_channel_t *ch)
{
    co_sdo_server_t *s = ch->server;
    uint32_t rx = 0, tx = 0;
    bool want;
    if (ch->state == CO_SDO_CH_ACTIVE) {
        ch->reconfig = true;
        s->reconfig_waiting = true;
        return;
    }
    ch->reconfig = false;
    want = wanted_ids(s, ch->number, &rx, &tx);
    if (want == ch->valid && (!want || (rx == ch->rx_id && tx == ch->tx_id))) {
        return;
    }
    if (ch->state != CO_SDO_CH_IDLE && ch->state != CO_SDO_CH_ABANDONED) {
        s->stats.channel_resets++;
        close_channel(ch, CO_ABORT_DATA_STATE, false);
    }
    if (ch->valid) {
        co_line_unsubscribe(s->line, on_frame, ch);
        ch->valid = false;
    }
    ch->done_valid = false;
    ch->rx_id = 0;
    ch->tx_id = 0;
    if (!want) {
        return;
    }
    if (!co_line_subscribe(s->line, rx, rx, on_frame, ch)) {
        s->stats.config_refused++;
        return;
    }
    ch->valid = true;
    ch->rx_id = rx;
    ch->tx_id = tx;
}

/* COB-ID changes that waited for a co_od call to return. */
static void apply_pending(co_sdo_server_t *s)
{
    uint8_t i;
    if (!s->reconfig_waiting) {
        return;   /* the common case: no scan of up to 128 channels per frame */
    }
    s->reconfig_waiting = false;   /* set again by a channel still inside a co_od call */
    for (i = 0; i < s->channel_count; i++) {
        co_sdo_channel_t *ch = &s->channels[i];
        if (ch->reconfig) {
            configure(ch);   /* still inside its co_od call: flags it again */
        }
    }
}

static uint32_t get_le32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

/* 0x1201..: a valid COB-ID must be an 11-bit CAN-ID outside CiA 301's
 * restricted ranges, and the received one must not be in use by another
 * service of the line. (That the CAN-ID changes only while invalid is
 * co_cob_id's rule.) */
static uint32_t check_cob_id(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e,
                             const uint8_t *value, uint32_t length, void *user)
{
    co_sdo_server_t *s = user;
    uint8_t sub = co_od_entry_sub(e);
    uint32_t v, id;
    (void)od;
    (void)xfer;
    if ((sub != 1 && sub != 2) || e->type != CO_TYPE_UNSIGNED32 || length != 4) {
        return 0;
    }
    v = get_le32(value);
    if ((v & CO_SDO_COB_INVALID) != 0) {
        return 0;
    }
    id = v & CO_SDO_COB_ID_MASK;
    if ((v & COB_RESERVED) != 0 || co_cob_id_restricted(id)) {
        return CO_ABORT_INVALID_VALUE;
    }
    if (sub == 1) {
        uint8_t number = (uint8_t)(co_od_entry_index(e) - CO_SDO_SERVER_PARAM);
        if (number < s->channel_count && co_line_id_taken(s->line, id) &&
            !co_line_id_taken_by(s->line, id, on_frame, &s->channels[number])) {
            return CO_ABORT_INVALID_VALUE;   /* another service receives on it */
        }
    }
    return 0;
}

static void after_cob_id(co_od_t *od, const co_od_entry_t *e, co_od_origin_t origin, void *user)
{
    co_sdo_server_t *s = user;
    uint16_t index = co_od_entry_index(e);
    (void)od;
    (void)origin;
    if (index > CO_SDO_SERVER_PARAM && index < CO_SDO_SERVER_PARAM + s->channel_count) {
        configure(&s->channels[index - CO_SDO_SERVER_PARAM]);
    }
}

static const co_od_handler_t cob_id_handler = {
    .check_write = check_cob_id,
    .after_write = after_cob_id,
};

/* ------------------------------------------------------------ events */

static void on_frame(co_line_t *line, const co_frame_t *f, void *user)
{
    co_sdo_channel_t *ch = user;
    co_sdo_server_t *s = ch->server;
    (void)line;
    s->stats.rx_frames++;
    if (s->not_serving) {
        s->stats.rx_not_serving++;
        return;
    }
    if (f->flags & CO_FRAME_FD) {
        s->stats.rx_fd++;
        return;
    }
    if (f->len != CO_SDO_FRAME_LEN) {
        s->stats.rx_bad_length++;
        return;
    }
    if (s->filter != NULL && s->filter(s, ch->number, ch->tx_id, f, s->filter_user)) {
        return;
    }
    handle(ch, f->data);
    apply_pending(s);
}

void co_sdo_server_set_filter(co_sdo_server_t *server, co_sdo_server_filter_fn fn, void *user)
{
    server->filter = fn;
    server->filter_user = fn != NULL ? user : NULL;
}

static void on_timer(co_timer_t *timer, uint64_t now_us, void *user)
{
    co_sdo_channel_t *ch = user;
    co_sdo_server_t *s = ch->server;
    (void)timer;
    (void)now_us;
    if (ch->state == CO_SDO_CH_BLOCK_UPLOAD && ch->tx_resume) {
        ch->tx_resume = false;
        touch(ch);
        send_segments(ch);
        return;
    }
    if (ch->state == CO_SDO_CH_BLOCK_DOWNLOAD && ch->seen) {
        /* the sub-block's end never came: acknowledge what arrived */
        s->stats.block_partial_acks++;
        send_block_ack(ch, ch->seqno);
        touch(ch);
        return;
    }
    s->stats.timeouts++;
    close_channel(ch, CO_ABORT_TIMEOUT, true);
}

/* The tx queue drained to half: block uploads that waited for room go on
 * (from their timer, i.e. from co_line_process). */
static void on_tx_space(co_line_t *line, void *user)
{
    co_sdo_server_t *s = user;
    uint8_t i;
    for (i = 0; i < s->channel_count; i++) {
        co_sdo_channel_t *ch = &s->channels[i];
        if (ch->state == CO_SDO_CH_BLOCK_UPLOAD && ch->tx_wait) {
            ch->tx_resume = true;
            co_timer_start(co_line_timers(line), &ch->timer, co_line_now(line));
        }
    }
}

/* ------------------------------------------------------------ API */

uint32_t co_sdo_server_scratch_need(const co_od_t *od)
{
    uint32_t i, need = 0;
    for (i = 0; i < od->count; i++) {
        if (od->entries[i].size > need) {
            need = od->entries[i].size;
        }
    }
    return need + CO_SDO_SERVER_BUFFER;
}

bool co_sdo_server_init(co_sdo_server_t *server, co_line_t *line, co_od_t *od,
                        const co_sdo_server_config_t *config)
{
    uint8_t i;
    if (server == NULL || line == NULL || od == NULL || config == NULL ||
        config->channels == NULL || config->channel_count == 0 ||
        config->channel_count > CO_SDO_SERVER_MAX_CHANNELS || config->scratch == NULL ||
        config->scratch_size < CO_SDO_SERVER_BUFFER || config->block_size > CO_SDO_BLKSIZE_MAX ||
        co_line_mode(line) != CO_MODE_CLASSIC) {
        return false;
    }
    memset(server, 0, sizeof *server);
    server->line = line;
    server->od = od;
    server->channels = config->channels;
    server->channel_count = config->channel_count;
    server->blksize = config->block_size != 0 ? config->block_size
                                              : (uint8_t)CO_SDO_SERVER_DEFAULT_BLKSIZE;
    server->crc = !config->no_crc;
    server->timeout_us = (uint64_t)(config->timeout_ms != 0 ? config->timeout_ms
                                                            : CO_SDO_SERVER_DEFAULT_TIMEOUT_MS) *
                         1000u;
    for (i = 0; i < config->channel_count; i++) {
        co_sdo_channel_t *ch = &config->channels[i];
        uint8_t *slice = config->scratch + (size_t)i * config->scratch_size;
        memset(ch, 0, sizeof *ch);
        ch->server = server;
        ch->number = i;
        ch->buf = slice;
        co_timer_init(&ch->timer, on_timer, ch);
        co_od_xfer_init(&ch->xfer, slice + CO_SDO_SERVER_BUFFER,
                        config->scratch_size - CO_SDO_SERVER_BUFFER);
        ch->state = CO_SDO_CH_IDLE;
    }
    if (!co_line_tx_space_register(line, on_tx_space, server)) {
        return false;
    }
    if (config->channel_count > 1) {
        if (!co_od_subscribe(od, CO_SDO_SERVER_PARAM + 1u, 0,
                             (uint16_t)(CO_SDO_SERVER_PARAM + config->channel_count - 1u), 0xFF,
                             &cob_id_handler, server)) {
            co_line_tx_space_unregister(line, on_tx_space, server);
            return false;
        }
        server->od_hooked = true;
    }
    configure(&server->channels[0]);
    if (co_line_node_id(line) != 0 && !server->channels[0].valid) {
        co_sdo_server_deinit(server);
        return false;
    }
    for (i = 1; i < config->channel_count; i++) {
        configure(&server->channels[i]);
    }
    return true;
}

void co_sdo_server_deinit(co_sdo_server_t *server)
{
    uint8_t i;
    for (i = 0; i < server->channel_count; i++) {
        co_sdo_channel_t *ch = &server->channels[i];
        co_od_xfer_abort(&ch->xfer, CO_ABORT_GENERAL);
        if (ch->valid) {
            co_line_unsubscribe(server->line, on_frame, ch);
            ch->valid = false;
        }
        release(ch);
        ch->reconfig = false;
        ch->done_valid = false;
    }
    if (server->od_hooked) {
        co_od_unsubscribe(server->od, &cob_id_handler, server);
        server->od_hooked = false;
    }
    co_line_tx_space_unregister(server->line, on_tx_space, server);
}

void co_sdo_server_refresh(co_sdo_server_t *server)
{
    uint8_t i;
    for (i = 0; i < server->channel_count; i++) {
        configure(&server->channels[i]);
    }
}

bool co_sdo_server_resume(co_sdo_server_t *server, co_od_xfer_t *xfer, uint32_t abort)
{
    uint8_t i;
    for (i = 0; i < server->channel_count; i++) {
        co_sdo_channel_t *ch = &server->channels[i];
        if (&ch->xfer != xfer) {
            continue;
        }
        if (ch->state == CO_SDO_CH_ABANDONED) {
            release(ch);
            apply_pending(server);
            return false;
        }
        if (ch->state != CO_SDO_CH_PENDING) {
            return false;
        }
        ch->state = CO_SDO_CH_ACTIVE;
        after_od(ch, co_od_resume(xfer, abort), ch->answer);
        apply_pending(server);
        return true;
    }
    return false;
}

void co_sdo_server_set_nmt_state(co_sdo_server_t *server, co_nmt_state_t state)
{
    bool serving = state == CO_NMT_PRE_OPERATIONAL || state == CO_NMT_OPERATIONAL;
    uint8_t i;
    server->not_serving = !serving;
    if (serving) {
        return;
    }
    for (i = 0; i < server->channel_count; i++) {
        co_sdo_channel_t *ch = &server->channels[i];
        if (is_open(ch)) {
            server->stats.closed_by_state++;
            close_channel(ch, CO_ABORT_DATA_STATE, false);
        }
        ch->done_valid = false;   /* no late repeat of an answer once serving again */
    }
    apply_pending(server);
}

uint8_t co_sdo_server_active(const co_sdo_server_t *server)
{
    uint8_t i, n = 0;
    for (i = 0; i < server->channel_count; i++) {
        if (server->channels[i].state != CO_SDO_CH_IDLE) {
            n++;
        }
    }
    return n;
}
