/* USDO server: see co_usdo_server.h for the session model and
 * docs/protocol-notes.md for every wire choice.
 *
 * Rules where the public sources leave room (all in protocol-notes.md):
 *  - Requests must be CAN FD frames; classic frames on 0x601..0x67F are
 *    ignored and counted.
 *  - A frame naming another node in byte 0 is ignored; frames shorter than
 *    3 bytes (no session-ID) are ignored; both counted.
 *  - An unknown command specifier (incl. multiple sub-indices and the
 *    remote variants) is answered with 0x13, a frame too short for its
 *    layout with 0x1E; if the (client, session-ID) has an open transfer,
 *    that transfer ends with the same abort.
 *  - A new request (0x01, 0x02, 0x06, 0x11) on an open (client, session-ID)
 *    ends the old transfer silently and starts the new one.
 *  - A segment for no open transfer: 0x21, except a bulk segment (0x07),
 *    which is ignored and counted: after an abort the client may still have
 *    many bulk segments in flight, and answering each would flood the bus.
 *    A segment of the wrong kind for the open transfer (0x03/0x04 in a bulk
 *    download, 0x07/0x08 in a segmented one, a download segment in an
 *    upload, or any segment while the transfer waits on the application):
 *    0x13.
 *  - The data type byte of a download must be the entry's type or DOMAIN
 *    (0x0F, "raw bytes"), else 0x36 (checked after the entry, access and
 *    length checks of co_od_write_begin).
 *  - Uploads of 0..56 bytes are expedited (an empty value: N = 0); anything
 *    else (more than 56, a domain of unknown size) is segmented. A domain of
 *    unknown size announces 0xFFFFFFFF as its size.
 *  - A bulk upload (0x16, our layout) is answered 0x36 (type, size) and the
 *    data streamed as 0x37 segments (counter as in segmented transfers) and
 *    one 0x38; never more than the client's window beyond the segments it
 *    acknowledged (0x17 names the counter of the last segment it took). An
 *    acknowledgement naming no segment in flight: 0x14. Window 0: 0x11.
 *    A 0x17 for no open transfer is ignored and counted (acknowledgements
 *    may cross the last segment).
 *  - Segments shorter than 64 bytes are taken (data = frame length - 4)
 *    and counted: liberal in what we accept; we always send 64.
 *  - The size announced in a segmented or bulk download is checked on every
 *    segment and at the end: more or fewer bytes = 0x15.
 *  - A bulk download (0x06) is a segmented download whose segments (0x07)
 *    are not answered: same initiate checks, same counter (0 first, +1 per
 *    segment, wrapping), 0x26 carries the configured pacing, only the last
 *    segment (0x08) is answered (0x28). A wrong counter (lost, repeated or
 *    reordered segment) aborts with 0x14 once.
 *  - An abort is never answered with an abort. */
#include "canopenfd/co_usdo_server.h"

#include <string.h>

enum answer {
    ANSWER_NONE = 0,
    ANSWER_UPLOAD,                /* 0x31, or 0x32 and then segments */
    ANSWER_DOWNLOAD_EXPEDITED,    /* 0x21 */
    ANSWER_DOWNLOAD_LAST,         /* 0x24 */
    ANSWER_BULK_LAST,             /* 0x28 */
    ANSWER_BULK_UPLOAD            /* 0x36 and then streamed segments */
};

/* ------------------------------------------------------------ sending */

static void send_msg(co_usdo_server_t *s, const co_usdo_msg_t *m)
{
    uint8_t buf[CO_USDO_FRAME_MAX];
    size_t n = co_usdo_encode(m, buf);
    if (n == 0 || !co_line_send(s->line, co_usdo_response_id(co_line_node_id(s->line)), buf, n)) {
        s->stats.tx_failed++;
    }
}

static void send_abort(co_usdo_server_t *s, uint8_t client, uint8_t session_id, uint16_t index,
                       uint8_t sub, uint8_t code)
{
    co_usdo_msg_t m;
    memset(&m, 0, sizeof m);
    m.dest = client;
    m.cs = CO_USDO_CS_ABORT;
    m.session = session_id;
    m.index = index;
    m.sub = sub;
    m.abort_code = code;
    s->stats.aborts_sent++;
    send_msg(s, &m);
}

/* The header (and mux where the layout has one) of a frame to the client of
 * session `ses`. */
static void session_msg(const co_usdo_session_t *ses, uint8_t cs, co_usdo_msg_t *m)
{
    memset(m, 0, sizeof *m);
    m->dest = ses->client;
    m->cs = cs;
    m->session = ses->session_id;
    m->index = ses->index;
    m->sub = ses->sub;
}

/* A frame of session `ses` without data. */
static void send_simple(co_usdo_server_t *s, const co_usdo_session_t *ses, uint8_t cs,
                        uint8_t counter)
{
    co_usdo_msg_t m;
    session_msg(ses, cs, &m);
    m.counter = counter;
    send_msg(s, &m);
}

/* 0x26: the bulk download is accepted; carries the pacing asked of the client. */
static void send_bulk_accept(co_usdo_server_t *s, const co_usdo_session_t *ses)
{
    co_usdo_msg_t m;
    session_msg(ses, CO_USDO_CS_BULK_INITIATE_RSP, &m);
    m.pacing = s->bulk_pacing;
    send_msg(s, &m);
}

/* ------------------------------------------------------------ sessions */

static bool is_open(const co_usdo_session_t *ses)
{
    return ses->state == CO_USDO_SESSION_ACTIVE || ses->state == CO_USDO_SESSION_DOWNLOAD ||
           ses->state == CO_USDO_SESSION_UPLOAD || ses->state == CO_USDO_SESSION_BULK ||
           ses->state == CO_USDO_SESSION_BULK_UPLOAD || ses->state == CO_USDO_SESSION_PENDING;
}

static co_usdo_session_t *find(co_usdo_server_t *s, uint8_t client, uint8_t session_id)
{
    uint8_t i;
    for (i = 0; i < s->session_count; i++) {
        co_usdo_session_t *ses = &s->sessions[i];
        if (is_open(ses) && ses->client == client && ses->session_id == session_id) {
            return ses;
        }
    }
    return NULL;
}

static co_usdo_session_t *alloc(co_usdo_server_t *s)
{
    uint8_t i;
    for (i = 0; i < s->session_count; i++) {
        if (s->sessions[i].state == CO_USDO_SESSION_FREE) {
            return &s->sessions[i];
        }
    }
    return NULL;
}

static bool in_use(const co_usdo_server_t *s, uint16_t index, uint8_t sub)
{
    uint8_t i;
    for (i = 0; i < s->session_count; i++) {
        const co_usdo_session_t *ses = &s->sessions[i];
        if (is_open(ses) && ses->index == index && ses->sub == sub) {
            return true;
        }
    }
    return false;
}

static void release(co_usdo_session_t *ses)
{
    co_timer_cancel(co_line_timers(ses->server->line), &ses->timer);
    ses->state = CO_USDO_SESSION_FREE;
    ses->answer = ANSWER_NONE;
    ses->tx_wait = false;
    ses->tx_resume = false;
}

/* Re-arm the idle timeout (every frame of the transfer). */
static void touch(co_usdo_session_t *ses)
{
    co_usdo_server_t *s = ses->server;
    co_timer_start(co_line_timers(s->line), &ses->timer, co_line_now(s->line) + s->timeout_us);
}

/* End an open transfer with a USDO abort code: the object dictionary is told
 * (a domain writer learns of it), the abort frame is sent when `send`. A
 * transfer that waits on the application keeps its slot (ABANDONED) until
 * the application's resume. */
static void close_session(co_usdo_session_t *ses, uint8_t code, bool send)
{
    co_usdo_server_t *s = ses->server;
    co_od_xfer_abort(&ses->xfer, co_usdo_abort_to_co(code));
    if (send) {
        send_abort(s, ses->client, ses->session_id, ses->index, ses->sub, code);
    }
    if (ses->state == CO_USDO_SESSION_PENDING) {
        co_timer_cancel(co_line_timers(s->line), &ses->timer);
        ses->state = CO_USDO_SESSION_ABANDONED;
    } else {
        release(ses);
    }
}

/* The object dictionary refused (CiA 301 code): its one-byte counterpart. */
static void od_fail(co_usdo_session_t *ses, uint32_t abort)
{
    ses->server->stats.od_aborts++;
    close_session(ses, co_usdo_abort_from_co(abort), true);
}

static void bulk_stream(co_usdo_session_t *ses);

static void on_timeout(co_timer_t *timer, uint64_t now_us, void *user)
{
    co_usdo_session_t *ses = user;
    (void)timer;
    (void)now_us;
    if (ses->tx_resume) {   /* not a timeout: the tx queue has room again */
        ses->tx_resume = false;
        touch(ses);
        bulk_stream(ses);
        return;
    }
    ses->server->stats.timeouts++;
    close_session(ses, CO_USDO_ABORT_TIMEOUT, true);
}

/* ------------------------------------------------------------ answers */

/* Read up to `want` bytes of the upload into buf: *n bytes, *last at the end
 * of the data. A reader that gives nothing and does not end is an error. */
static uint32_t fill(co_usdo_session_t *ses, uint8_t *buf, uint32_t want, uint32_t *n,
                     bool *last)
{
    *n = 0;
    *last = false;
    while (*n < want) {
        uint32_t got = 0;
        bool end = false;
        uint32_t r = co_od_read_chunk(&ses->xfer, buf + *n, want - *n, &got, &end);
        if (r != 0) {
            return r;
        }
        *n += got;
        if (end) {
            *last = true;
            return 0;
        }
        if (got == 0) {
            co_od_xfer_abort(&ses->xfer, CO_ABORT_GENERAL);
            return CO_ABORT_GENERAL;
        }
    }
    return 0;
}

static void answer_upload(co_usdo_session_t *ses)
{
    co_usdo_server_t *s = ses->server;
    uint32_t total = ses->xfer.total;
    co_usdo_msg_t m;
    memset(&m, 0, sizeof m);
    m.dest = ses->client;
    m.session = ses->session_id;
    m.index = ses->index;
    m.sub = ses->sub;
    m.type = ses->xfer.entry->type;
    if (total != CO_OD_SIZE_UNKNOWN && total <= CO_USDO_EXPEDITED_MAX) {   /* N = 0 too */
        uint8_t data[CO_USDO_EXPEDITED_MAX];
        uint32_t n = 0;
        bool last = false;
        uint32_t r = fill(ses, data, total, &n, &last);
        if (r != 0) {
            od_fail(ses, r);
            return;
        }
        m.cs = CO_USDO_CS_UPLOAD_EXPEDITED_RSP;
        m.length = (uint8_t)n;
        m.data = data;
        send_msg(s, &m);
        s->stats.uploads++;
        release(ses);
        return;
    }
    m.cs = CO_USDO_CS_UPLOAD_INITIATE_RSP;
    m.size = total;   /* CO_OD_SIZE_UNKNOWN = 0xFFFFFFFF: size not known */
    send_msg(s, &m);
    ses->state = CO_USDO_SESSION_UPLOAD;
    ses->counter = 0;
    touch(ses);
}

/* ------------------------------------------------------------ bulk upload */

/* The next upload segment, read from the OD: `cs_last` with the rest (the
 * session then ends) or `cs_segment` with 60 bytes and the session's
 * counter. False when the transfer ended (last segment sent, or the OD
 * failed and the client was aborted). Segmented and bulk uploads share it. */
static bool send_upload_segment(co_usdo_session_t *ses, uint8_t cs_segment, uint8_t cs_last)
{
    co_usdo_server_t *s = ses->server;
    uint8_t data[CO_USDO_SEGMENT_DATA];
    uint32_t n = 0;
    bool last = false;
    co_usdo_msg_t out;
    uint32_t r = fill(ses, data, CO_USDO_SEGMENT_DATA, &n, &last);
    if (r != 0) {
        od_fail(ses, r);
        return false;
    }
    memset(&out, 0, sizeof out);
    out.dest = ses->client;
    out.session = ses->session_id;
    out.data = data;
    if (last) {
        out.cs = cs_last;
        out.length = (uint8_t)n;
        send_msg(s, &out);
        s->stats.uploads++;
        if (cs_last == CO_USDO_CS_BULK_UPLOAD_LAST_RSP) {
            s->stats.bulk_uploads++;
        }
        release(ses);
        return false;
    }
    out.cs = cs_segment;
    out.counter = ses->counter;
    out.length = CO_USDO_SEGMENT_DATA;
    send_msg(s, &out);
    ses->counter = co_usdo_next_counter(ses->counter);
    return true;
}

/* Stream segments while the client's window and the tx queue have room:
 * 0x37 with 60 bytes, 0x38 with the rest (a multiple of 60 ends with a full
 * 0x38, as segmented uploads do). Out of window: wait for the client's 0x17
 * (the idle timeout runs); out of tx room: wait for the tx-space
 * indication. */
static void bulk_stream(co_usdo_session_t *ses)
{
    co_usdo_server_t *s = ses->server;
    while (ses->state == CO_USDO_SESSION_BULK_UPLOAD &&
           ses->sent - ses->acked < ses->window) {
        if (co_line_tx_room(s->line) == 0) {
            if (!ses->tx_wait) {
                s->stats.tx_deferred++;
            }
            ses->tx_wait = true;
            return;
        }
        if (!send_upload_segment(ses, CO_USDO_CS_BULK_UPLOAD_SEGMENT_RSP,
                                 CO_USDO_CS_BULK_UPLOAD_LAST_RSP)) {
            return;
        }
        ses->sent++;
    }
    ses->tx_wait = false;
}

/* 0x36 (type, size as 0x32) and the first window of segments. */
static void answer_bulk_upload(co_usdo_session_t *ses)
{
    co_usdo_msg_t m;
    session_msg(ses, CO_USDO_CS_BULK_UPLOAD_INITIATE_RSP, &m);
    m.type = ses->xfer.entry->type;
    m.size = ses->xfer.total;   /* CO_OD_SIZE_UNKNOWN = 0xFFFFFFFF: size not known */
    send_msg(ses->server, &m);
    ses->state = CO_USDO_SESSION_BULK_UPLOAD;
    ses->counter = 0;
    ses->sent = 0;
    ses->acked = 0;
    touch(ses);
    bulk_stream(ses);
}

/* 0x17: the client took every segment up to the one with this counter.
 * Segments in flight are acked+1..sent; the window (< 256) makes the
 * counter name at most one of them. */
static void on_bulk_ack(co_usdo_server_t *s, co_usdo_session_t *ses, const co_usdo_msg_t *m)
{
    uint32_t k;
    if (ses == NULL) {
        s->stats.rx_stray_ack++;
        return;
    }
    if (ses->state != CO_USDO_SESSION_BULK_UPLOAD) {
        s->stats.rx_unknown_command++;
        close_session(ses, CO_USDO_ABORT_COMMAND, true);
        return;
    }
    for (k = ses->acked + 1u; k <= ses->sent; k++) {
        if ((uint8_t)(k - 1u) == m->counter) {
            break;
        }
    }
    if (k > ses->sent) {
        s->stats.rx_bad_counter++;
        close_session(ses, CO_USDO_ABORT_COUNTER, true);
        return;
    }
    ses->acked = k;
    /* touch replaces a pending resume's timer: this call streams instead */
    ses->tx_resume = false;
    touch(ses);
    if (!ses->tx_wait) {
        bulk_stream(ses);
    }
}

/* The tx queue drained to half: bulk uploads that waited for room go on
 * from their timer (i.e. from co_line_process, not the driver's context). */
static void on_tx_space(co_line_t *line, void *user)
{
    co_usdo_server_t *s = user;
    uint8_t i;
    for (i = 0; i < s->session_count; i++) {
        co_usdo_session_t *ses = &s->sessions[i];
        if (ses->state == CO_USDO_SESSION_BULK_UPLOAD && ses->tx_wait) {
            ses->tx_wait = false;
            ses->tx_resume = true;
            co_timer_start(co_line_timers(line), &ses->timer, co_line_now(line));
        }
    }
}

/* What a co_od call returned: wait (split), refuse, or answer. */
static void after_od(co_usdo_session_t *ses, uint32_t r, uint8_t answer)
{
    co_usdo_server_t *s = ses->server;
    if (r == CO_OD_SPLIT) {
        ses->state = CO_USDO_SESSION_PENDING;
        ses->answer = answer;
        return;
    }
    if (r != 0) {
        od_fail(ses, r);
        return;
    }
    switch (answer) {
    case ANSWER_UPLOAD:
        answer_upload(ses);
        break;
    case ANSWER_BULK_UPLOAD:
        answer_bulk_upload(ses);
        break;
    case ANSWER_DOWNLOAD_EXPEDITED:
        send_simple(s, ses, CO_USDO_CS_DOWNLOAD_EXPEDITED_RSP, 0);
        s->stats.downloads++;
        release(ses);
        break;
    case ANSWER_DOWNLOAD_LAST:
    case ANSWER_BULK_LAST:
        send_simple(s, ses,
                    answer == ANSWER_BULK_LAST ? CO_USDO_CS_BULK_LAST_RSP
                                               : CO_USDO_CS_DOWNLOAD_LAST_RSP,
                    0);
        s->stats.downloads++;
        release(ses);
        break;
    default:
        close_session(ses, CO_USDO_ABORT_UNKNOWN, true);
        break;
    }
}

/* ------------------------------------------------------------ requests */

/* The data type byte of a download: the entry's type, or DOMAIN = raw bytes. */
static bool type_acceptable(const co_od_entry_t *e, uint8_t type)
{
    return type == e->type || type == CO_TYPE_DOMAIN;
}

static uint32_t begin_download(co_usdo_server_t *s, co_usdo_session_t *ses, uint32_t total,
                               uint8_t type)
{
    uint32_t r = co_od_write_begin(s->od, &ses->xfer, ses->index, ses->sub, total);
    if (r == 0 && !type_acceptable(ses->xfer.entry, type)) {
        co_od_xfer_abort(&ses->xfer, CO_ABORT_TYPE_MISMATCH);
        r = CO_ABORT_TYPE_MISMATCH;
    }
    return r;
}

/* 0x01, 0x02, 0x06, 0x11, 0x16: a new transfer. */
static void on_initiate(co_usdo_server_t *s, co_usdo_session_t *ses, uint8_t client,
                        const co_usdo_msg_t *m)
{
    uint32_t r;
    if (ses != NULL) {
        s->stats.restarts++;
        close_session(ses, CO_USDO_ABORT_UNKNOWN, false);
    }
    if (m->cs == CO_USDO_CS_BULK_UPLOAD && m->window == 0) {
        s->stats.rx_bad_window++;   /* nothing could ever be sent */
        send_abort(s, client, m->session, m->index, m->sub, CO_USDO_ABORT_PROTOCOL);
        return;
    }
    ses = alloc(s);
    if (ses == NULL) {
        s->stats.busy++;
        send_abort(s, client, m->session, m->index, m->sub, CO_USDO_ABORT_BUSY);
        return;
    }
    if (in_use(s, m->index, m->sub)) {
        s->stats.parallel++;
        send_abort(s, client, m->session, m->index, m->sub, CO_USDO_ABORT_PARALLEL);
        return;
    }
    ses->state = CO_USDO_SESSION_ACTIVE;
    ses->answer = ANSWER_NONE;
    ses->client = client;
    ses->session_id = m->session;
    ses->index = m->index;
    ses->sub = m->sub;
    ses->counter = 0;
    ses->total = 0;
    ses->received = 0;
    ses->window = m->window;
    ses->tx_wait = false;
    ses->tx_resume = false;
    touch(ses);
    switch (m->cs) {
    case CO_USDO_CS_DOWNLOAD_EXPEDITED:
        r = begin_download(s, ses, m->length, m->type);
        if (r == 0) {
            r = co_od_write_chunk(&ses->xfer, m->data, m->length);
        }
        if (r == 0) {
            r = co_od_write_end(&ses->xfer);
        }
        after_od(ses, r, ANSWER_DOWNLOAD_EXPEDITED);
        break;
    case CO_USDO_CS_DOWNLOAD_INITIATE:
    case CO_USDO_CS_BULK_INITIATE:
        r = begin_download(s, ses, m->size, m->type);
        if (r != 0) {
            od_fail(ses, r);
            break;
        }
        ses->total = m->size;
        if (m->cs == CO_USDO_CS_BULK_INITIATE) {
            ses->state = CO_USDO_SESSION_BULK;
            send_bulk_accept(s, ses);
        } else {
            ses->state = CO_USDO_SESSION_DOWNLOAD;
            send_simple(s, ses, CO_USDO_CS_DOWNLOAD_INITIATE_RSP, 0);
        }
        break;
    default: /* CO_USDO_CS_UPLOAD, CO_USDO_CS_BULK_UPLOAD */
        r = co_od_read_begin(s->od, &ses->xfer, ses->index, ses->sub);
        after_od(ses, r, m->cs == CO_USDO_CS_BULK_UPLOAD ? ANSWER_BULK_UPLOAD : ANSWER_UPLOAD);
        break;
    }
}

/* A segment frame needs an open transfer of the right kind. A bulk segment
 * (0x07) for no open transfer is ignored: after an abort the client may
 * still have many of them in flight, and one abort each would flood the bus. */
static bool segment_session_ok(co_usdo_server_t *s, co_usdo_session_t *ses, uint8_t client,
                               const co_usdo_msg_t *m, uint8_t state)
{
    if (ses == NULL) {
        if (m->cs == CO_USDO_CS_BULK_SEGMENT) {
            s->stats.rx_stray_bulk++;
            return false;
        }
        s->stats.rx_no_session++;
        send_abort(s, client, m->session, 0, 0, CO_USDO_ABORT_SESSION);
        return false;
    }
    if (ses->state != state) {
        s->stats.rx_unknown_command++;
        close_session(ses, CO_USDO_ABORT_COMMAND, true);
        return false;
    }
    touch(ses);
    return true;
}

/* 0x03, 0x04 (segmented) and 0x07, 0x08 (bulk): the same path; a bulk
 * segment is not answered and the end is answered with 0x28, not 0x24. */
static void on_download_segment(co_usdo_server_t *s, co_usdo_session_t *ses, uint8_t client,
                                const co_usdo_msg_t *m)
{
    uint32_t r;
    bool bulk = m->cs == CO_USDO_CS_BULK_SEGMENT || m->cs == CO_USDO_CS_BULK_LAST;
    if (!segment_session_ok(s, ses, client, m,
                            bulk ? CO_USDO_SESSION_BULK : CO_USDO_SESSION_DOWNLOAD)) {
        return;
    }
    uint32_t room = ses->total - ses->received;   /* received <= total always */
    if (m->cs == CO_USDO_CS_DOWNLOAD_SEGMENT || m->cs == CO_USDO_CS_BULK_SEGMENT) {
        if (co_usdo_short_segment(m)) {
            s->stats.rx_short_segment++;   /* a sender with a smaller MTU: taken */
        }
        if (m->counter != ses->counter) {
            s->stats.rx_bad_counter++;
            close_session(ses, CO_USDO_ABORT_COUNTER, true);
            return;
        }
        if (m->length > room) {
            s->stats.rx_size_mismatch++;
            close_session(ses, CO_USDO_ABORT_DATA_SIZE, true);
            return;
        }
        r = co_od_write_chunk(&ses->xfer, m->data, m->length);
        if (r != 0) {
            od_fail(ses, r);
            return;
        }
        ses->received += m->length;
        if (!bulk) {
            send_simple(s, ses, CO_USDO_CS_DOWNLOAD_SEGMENT_RSP, m->counter);
        }
        ses->counter = co_usdo_next_counter(ses->counter);
        return;
    }
    if (m->length != room) {
        s->stats.rx_size_mismatch++;
        close_session(ses, CO_USDO_ABORT_DATA_SIZE, true);
        return;
    }
    r = co_od_write_chunk(&ses->xfer, m->data, m->length);
    if (r != 0) {
        od_fail(ses, r);
        return;
    }
    ses->received += m->length;
    ses->state = CO_USDO_SESSION_ACTIVE;
    r = co_od_write_end(&ses->xfer);
    after_od(ses, r, bulk ? ANSWER_BULK_LAST : ANSWER_DOWNLOAD_LAST);
}

/* 0x13 */
static void on_upload_segment(co_usdo_server_t *s, co_usdo_session_t *ses, uint8_t client,
                              const co_usdo_msg_t *m)
{
    if (!segment_session_ok(s, ses, client, m, CO_USDO_SESSION_UPLOAD)) {
        return;
    }
    if (m->counter != ses->counter) {
        s->stats.rx_bad_counter++;
        close_session(ses, CO_USDO_ABORT_COUNTER, true);
        return;
    }
    (void)send_upload_segment(ses, CO_USDO_CS_UPLOAD_SEGMENT_RSP, CO_USDO_CS_UPLOAD_LAST_RSP);
}

static void on_frame(co_line_t *line, const co_frame_t *f, void *user)
{
    co_usdo_server_t *s = user;
    co_usdo_msg_t m;
    uint8_t me = co_line_node_id(line);
    uint8_t client = (uint8_t)(f->id - CO_USDO_REQUEST_BASE);
    s->stats.rx_frames++;
    if (s->not_serving) {
        s->stats.rx_not_serving++;
        return;
    }
    if (!(f->flags & CO_FRAME_FD)) {
        s->stats.rx_not_fd++;
        return;
    }
    if (me == 0) {
        s->stats.rx_no_node++;
        return;
    }
    co_usdo_decode_result_t r = co_usdo_decode(f->data, f->len, &m);
    if (r == CO_USDO_DECODE_EMPTY) {
        s->stats.rx_empty++;
        return;
    }
    if (m.dest != me && m.dest != CO_USDO_BROADCAST) {
        s->stats.rx_other_dest++;
        return;
    }
    if (m.remote) {
        /* routed requests belong to a gateway (co_gateway_usdo.c); without
         * one there is no routing here: 0x13, as for any unknown command */
        if (s->remote_fn != NULL && s->remote_fn(s, client, r, &m, s->remote_user)) {
            return;
        }
        if (m.cs == CO_USDO_CS_ABORT) {
            s->stats.rx_remote_abort++;
            return;
        }
        s->stats.rx_unknown_command++;
        send_abort(s, client, m.session, 0, 0, CO_USDO_ABORT_COMMAND);
        return;
    }
    co_usdo_session_t *ses = find(s, client, m.session);
    if (m.cs == CO_USDO_CS_ABORT) {
        if (r != CO_USDO_DECODE_OK) {
            s->stats.rx_malformed++;
        }
        if (ses == NULL) {
            s->stats.rx_stray_abort++;
            return;
        }
        s->stats.rx_client_abort++;
        close_session(ses, r == CO_USDO_DECODE_OK ? m.abort_code : CO_USDO_ABORT_UNKNOWN, false);
        return;
    }
    if (r != CO_USDO_DECODE_OK) {
        uint8_t code = CO_USDO_ABORT_DLC;
        if (r == CO_USDO_DECODE_UNKNOWN_CS) {
            s->stats.rx_unknown_command++;
            code = CO_USDO_ABORT_COMMAND;
        } else {
            s->stats.rx_malformed++;
        }
        if (ses != NULL) {
            close_session(ses, code, true);
        } else {
            send_abort(s, client, m.session, m.index, m.sub, code);
        }
        return;
    }
    switch (m.cs) {
    case CO_USDO_CS_DOWNLOAD_EXPEDITED:
    case CO_USDO_CS_DOWNLOAD_INITIATE:
    case CO_USDO_CS_BULK_INITIATE:
    case CO_USDO_CS_UPLOAD:
    case CO_USDO_CS_BULK_UPLOAD:
        on_initiate(s, ses, client, &m);
        break;
    case CO_USDO_CS_BULK_UPLOAD_ACK:
        on_bulk_ack(s, ses, &m);
        break;
    case CO_USDO_CS_DOWNLOAD_SEGMENT:
    case CO_USDO_CS_DOWNLOAD_LAST:
    case CO_USDO_CS_BULK_SEGMENT:
    case CO_USDO_CS_BULK_LAST:
        on_download_segment(s, ses, client, &m);
        break;
    case CO_USDO_CS_UPLOAD_SEGMENT:
        on_upload_segment(s, ses, client, &m);
        break;
    default:
        /* a response's command specifier sent as a request */
        s->stats.rx_unknown_command++;
        if (ses != NULL) {
            close_session(ses, CO_USDO_ABORT_COMMAND, true);
        } else {
            send_abort(s, client, m.session, m.index, m.sub, CO_USDO_ABORT_COMMAND);
        }
        break;
    }
}

/* ------------------------------------------------------------ API */

uint32_t co_usdo_server_scratch_need(const co_od_t *od)
{
    uint32_t i, need = 0;
    for (i = 0; i < od->count; i++) {
        if (od->entries[i].size > need) {
            need = od->entries[i].size;
        }
    }
    return need;
}

bool co_usdo_server_init(co_usdo_server_t *server, co_line_t *line, co_od_t *od,
                         const co_usdo_server_config_t *config)
{
    uint8_t i;
    if (server == NULL || line == NULL || od == NULL || config == NULL ||
        config->sessions == NULL || config->session_count == 0 ||
        (config->scratch == NULL && config->scratch_size != 0) ||
        co_line_mode(line) != CO_MODE_FD) {
        return false;
    }
    memset(server, 0, sizeof *server);
    server->line = line;
    server->od = od;
    server->sessions = config->sessions;
    server->session_count = config->session_count;
    server->timeout_us = (uint64_t)(config->timeout_ms != 0 ? config->timeout_ms
                                                            : CO_USDO_SERVER_DEFAULT_TIMEOUT_MS) *
                         1000u;
    server->bulk_pacing = config->bulk_pacing;
    for (i = 0; i < config->session_count; i++) {
        co_usdo_session_t *ses = &config->sessions[i];
        memset(ses, 0, sizeof *ses);
        ses->server = server;
        co_timer_init(&ses->timer, on_timeout, ses);
        co_od_xfer_init(&ses->xfer,
                        config->scratch != NULL ? config->scratch + (size_t)i * config->scratch_size
                                                : NULL,
                        config->scratch_size);
        ses->state = CO_USDO_SESSION_FREE;
    }
    if (!co_line_subscribe(line, CO_USDO_REQUEST_BASE + 1u, CO_USDO_REQUEST_BASE + 127u, on_frame,
                           server)) {
        return false;
    }
    if (!co_line_tx_space_register(line, on_tx_space, server)) {
        co_line_unsubscribe(line, on_frame, server);
        return false;
    }
    return true;
}

void co_usdo_server_deinit(co_usdo_server_t *server)
{
    uint8_t i;
    co_line_unsubscribe(server->line, on_frame, server);
    co_line_tx_space_unregister(server->line, on_tx_space, server);
    for (i = 0; i < server->session_count; i++) {
        co_usdo_session_t *ses = &server->sessions[i];
        if (ses->state != CO_USDO_SESSION_FREE) {
            co_od_xfer_abort(&ses->xfer, CO_ABORT_GENERAL);
            release(ses);
        }
    }
}

bool co_usdo_server_resume(co_usdo_server_t *server, co_od_xfer_t *xfer, uint32_t abort)
{
    uint8_t i;
    for (i = 0; i < server->session_count; i++) {
        co_usdo_session_t *ses = &server->sessions[i];
        if (&ses->xfer != xfer) {
            continue;
        }
        if (ses->state == CO_USDO_SESSION_ABANDONED) {
            release(ses);
            return false;
        }
        if (ses->state != CO_USDO_SESSION_PENDING) {
            return false;
        }
        ses->state = CO_USDO_SESSION_ACTIVE;
        after_od(ses, co_od_resume(xfer, abort), ses->answer);
        return true;
    }
    return false;
}

void co_usdo_server_set_nmt_state(co_usdo_server_t *server, co_nmt_state_t state)
{
    bool serving = state == CO_NMT_PRE_OPERATIONAL || state == CO_NMT_OPERATIONAL;
    uint8_t i;
    server->not_serving = !serving;
    for (i = 0; !serving && i < server->session_count; i++) {
        co_usdo_session_t *ses = &server->sessions[i];
        if (is_open(ses)) {
            server->stats.closed_by_state++;
            close_session(ses, co_usdo_abort_from_co(CO_ABORT_DATA_STATE), false);
        }
    }
}

uint8_t co_usdo_server_active(const co_usdo_server_t *server)
{
    uint8_t i, n = 0;
    for (i = 0; i < server->session_count; i++) {
        if (server->sessions[i].state != CO_USDO_SESSION_FREE) {
            n++;
        }
    }
    return n;
}

void co_usdo_server_set_remote_handler(co_usdo_server_t *server, co_usdo_remote_fn fn,
                                       void *user)
{
    server->remote_fn = fn;
    server->remote_user = user;
}
