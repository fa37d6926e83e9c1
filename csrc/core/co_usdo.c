/* USDO wire format: one encoder and one decoder per frame layout, selected
 * by the command specifier (byte 1). Layouts and their evidence:
 * docs/protocol-notes.md, section "USDO". */
#include "canopenfd/co_usdo.h"

#include <string.h>

#include "canopenfd/co_od.h"

/* Byte positions shared by the layouts. */
enum {
    P_DEST = 0,
    P_CS = 1,
    P_SESSION = 2,
    P_SUB = 3,       /* MUX-based layouts */
    P_INDEX = 4,     /* 2 bytes, little-endian */
    P_TYPE = 6,      /* EXPEDITED, INITIATE */
    P_N = 7,         /* EXPEDITED: data length */
    P_RESERVED = 7,  /* INITIATE: reserved, sent as 0 */
    P_SIZE = 8,      /* INITIATE: 4 bytes, little-endian */
    P_EXP_DATA = 8,  /* EXPEDITED data */
    P_COUNTER = 3,   /* SEGMENT, COUNTER; LAST: n */
    P_SEG_DATA = 4,  /* SEGMENT, LAST data */
    P_CODE = 6,      /* ABORT */
    P_PACING = 6,    /* BULK_ACCEPT: 2 bytes, little-endian */
    P_WINDOW = 6,    /* BULK_REQUEST: 1 byte, then 1 reserved byte (sent as 0) */
    HEAD_LEN = 3,    /* dest, cs, session */
    MUX_LEN = 6,
    EXP_HEAD_LEN = 8,
    INITIATE_LEN = 12,
    SEG_HEAD_LEN = 4,
    SEGMENT_LEN = 64,
    ABORT_LEN = 7,
    BULK_ACCEPT_LEN = 8,
    BULK_REQUEST_LEN = 8
};

co_usdo_layout_t co_usdo_layout_of(uint8_t cs)
{
    switch (cs) {
    case CO_USDO_CS_UPLOAD:
    case CO_USDO_CS_DOWNLOAD_EXPEDITED_RSP:
    case CO_USDO_CS_DOWNLOAD_INITIATE_RSP:
        return CO_USDO_LAYOUT_MUX;
    case CO_USDO_CS_DOWNLOAD_EXPEDITED:
    case CO_USDO_CS_UPLOAD_EXPEDITED_RSP:
        return CO_USDO_LAYOUT_EXPEDITED;
    case CO_USDO_CS_DOWNLOAD_INITIATE:
    case CO_USDO_CS_UPLOAD_INITIATE_RSP:
    case CO_USDO_CS_BULK_INITIATE:
    case CO_USDO_CS_BULK_UPLOAD_INITIATE_RSP:
        return CO_USDO_LAYOUT_INITIATE;
    case CO_USDO_CS_DOWNLOAD_SEGMENT:
    case CO_USDO_CS_UPLOAD_SEGMENT_RSP:
    case CO_USDO_CS_BULK_SEGMENT:
    case CO_USDO_CS_BULK_UPLOAD_SEGMENT_RSP:
        return CO_USDO_LAYOUT_SEGMENT;
    case CO_USDO_CS_DOWNLOAD_LAST:
    case CO_USDO_CS_UPLOAD_LAST_RSP:
    case CO_USDO_CS_BULK_LAST:
    case CO_USDO_CS_BULK_UPLOAD_LAST_RSP:
        return CO_USDO_LAYOUT_LAST;
    case CO_USDO_CS_BULK_INITIATE_RSP:
        return CO_USDO_LAYOUT_BULK_ACCEPT;
    case CO_USDO_CS_BULK_UPLOAD:
        return CO_USDO_LAYOUT_BULK_REQUEST;
    case CO_USDO_CS_UPLOAD_SEGMENT:
    case CO_USDO_CS_DOWNLOAD_SEGMENT_RSP:
    case CO_USDO_CS_BULK_UPLOAD_ACK:
        return CO_USDO_LAYOUT_COUNTER;
    case CO_USDO_CS_DOWNLOAD_LAST_RSP:
    case CO_USDO_CS_BULK_LAST_RSP:
        return CO_USDO_LAYOUT_END;
    case CO_USDO_CS_ABORT:
        return CO_USDO_LAYOUT_ABORT;
    default:
        return CO_USDO_LAYOUT_UNKNOWN;
    }
}

bool co_usdo_layout_has_mux(co_usdo_layout_t layout)
{
    return layout == CO_USDO_LAYOUT_MUX || layout == CO_USDO_LAYOUT_EXPEDITED ||
           layout == CO_USDO_LAYOUT_INITIATE || layout == CO_USDO_LAYOUT_ABORT ||
           layout == CO_USDO_LAYOUT_BULK_ACCEPT || layout == CO_USDO_LAYOUT_BULK_REQUEST;
}

/* ------------------------------------------------------------ helpers */

static void put_mux(uint8_t *out, const co_usdo_msg_t *m)
{
    out[P_SUB] = m->sub;
    out[P_INDEX] = (uint8_t)(m->index & 0xFFu);
    out[P_INDEX + 1] = (uint8_t)(m->index >> 8);
}

static void get_mux(const uint8_t *in, co_usdo_msg_t *m)
{
    m->sub = in[P_SUB];
    m->index = (uint16_t)(in[P_INDEX] | (in[P_INDEX + 1] << 8));
}

static void copy_data(uint8_t *dst, const uint8_t *src, size_t n)
{
    if (n > 0) {
        memcpy(dst, src, n);
    }
}

/* ------------------------------------------------------------ layouts
 * Each decode_x is called with len >= HEAD_LEN (and len >= MUX_LEN for the
 * mux layouts, whose mux is already in *m); it checks the rest. */

static size_t encode_mux(const co_usdo_msg_t *m, uint8_t *out)
{
    put_mux(out, m);
    return MUX_LEN;
}

static co_usdo_decode_result_t decode_mux(const uint8_t *in, size_t len, co_usdo_msg_t *m)
{
    (void)in;
    (void)m;
    (void)len;
    return CO_USDO_DECODE_OK;
}

static size_t encode_expedited(const co_usdo_msg_t *m, uint8_t *out)
{
    if (m->length > CO_USDO_EXPEDITED_MAX || (m->length > 0 && m->data == NULL)) {
        return 0;
    }
    put_mux(out, m);
    out[P_TYPE] = m->type;
    out[P_N] = m->length;
    copy_data(out + P_EXP_DATA, m->data, m->length);
    return (size_t)EXP_HEAD_LEN + m->length;
}

static co_usdo_decode_result_t decode_expedited(const uint8_t *in, size_t len, co_usdo_msg_t *m)
{
    if (len < EXP_HEAD_LEN) {
        return CO_USDO_DECODE_SHORT;
    }
    m->type = in[P_TYPE];
    if (in[P_N] > CO_USDO_EXPEDITED_MAX) {
        return CO_USDO_DECODE_BAD_LENGTH;
    }
    if (len - EXP_HEAD_LEN < in[P_N]) {
        return CO_USDO_DECODE_SHORT;
    }
    m->length = in[P_N];
    m->data = in + P_EXP_DATA;
    return CO_USDO_DECODE_OK;
}

static size_t encode_initiate(const co_usdo_msg_t *m, uint8_t *out)
{
    put_mux(out, m);
    out[P_TYPE] = m->type;
    out[P_RESERVED] = 0;
    out[P_SIZE] = (uint8_t)(m->size & 0xFFu);
    out[P_SIZE + 1] = (uint8_t)((m->size >> 8) & 0xFFu);
    out[P_SIZE + 2] = (uint8_t)((m->size >> 16) & 0xFFu);
    out[P_SIZE + 3] = (uint8_t)(m->size >> 24);
    return INITIATE_LEN;
}

static co_usdo_decode_result_t decode_initiate(const uint8_t *in, size_t len, co_usdo_msg_t *m)
{
    if (len < INITIATE_LEN) {
        return CO_USDO_DECODE_SHORT;
    }
    m->type = in[P_TYPE];   /* byte 7 (reserved) is not looked at */
    m->size = (uint32_t)in[P_SIZE] | ((uint32_t)in[P_SIZE + 1] << 8) |
              ((uint32_t)in[P_SIZE + 2] << 16) | ((uint32_t)in[P_SIZE + 3] << 24);
    return CO_USDO_DECODE_OK;
}

static size_t encode_segment(const co_usdo_msg_t *m, uint8_t *out)
{
    if (m->length != CO_USDO_SEGMENT_DATA || m->data == NULL) {
        return 0;
    }
    out[P_COUNTER] = m->counter;
    copy_data(out + P_SEG_DATA, m->data, CO_USDO_SEGMENT_DATA);
    return SEGMENT_LEN;
}

/* No size field: the frame's length says how much data it carries. 64 bytes
 * (what we send) give 60; a shorter frame from a sender with a smaller MTU
 * gives len - 4 (at least 1), so padding up to an FD length would count as
 * data there: the announced total catches it at the end. */
static co_usdo_decode_result_t decode_segment(const uint8_t *in, size_t len, co_usdo_msg_t *m)
{
    if (len > P_COUNTER) {
        m->counter = in[P_COUNTER];
    }
    if (len < CO_USDO_SEGMENT_MIN) {
        return CO_USDO_DECODE_SHORT;
    }
    m->length = (uint8_t)(len < SEGMENT_LEN ? len - SEG_HEAD_LEN : CO_USDO_SEGMENT_DATA);
    m->data = in + P_SEG_DATA;
    return CO_USDO_DECODE_OK;
}

static size_t encode_last(const co_usdo_msg_t *m, uint8_t *out)
{
    if (m->length > CO_USDO_SEGMENT_DATA || (m->length > 0 && m->data == NULL)) {
        return 0;
    }
    out[P_COUNTER] = m->length;
    copy_data(out + P_SEG_DATA, m->data, m->length);
    return (size_t)SEG_HEAD_LEN + m->length;
}

static co_usdo_decode_result_t decode_last(const uint8_t *in, size_t len, co_usdo_msg_t *m)
{
    if (len < SEG_HEAD_LEN) {
        return CO_USDO_DECODE_SHORT;
    }
    if (in[P_COUNTER] > CO_USDO_SEGMENT_DATA) {
        return CO_USDO_DECODE_BAD_LENGTH;
    }
    if (len - SEG_HEAD_LEN < in[P_COUNTER]) {
        return CO_USDO_DECODE_SHORT;
    }
    m->length = in[P_COUNTER];
    m->data = in + P_SEG_DATA;
    return CO_USDO_DECODE_OK;
}

static size_t encode_counter(const co_usdo_msg_t *m, uint8_t *out)
{
    out[P_COUNTER] = m->counter;
    return SEG_HEAD_LEN;
}

static co_usdo_decode_result_t decode_counter(const uint8_t *in, size_t len, co_usdo_msg_t *m)
{
    if (len < SEG_HEAD_LEN) {
        return CO_USDO_DECODE_SHORT;
    }
    m->counter = in[P_COUNTER];
    return CO_USDO_DECODE_OK;
}

static size_t encode_end(const co_usdo_msg_t *m, uint8_t *out)
{
    (void)m;
    (void)out;
    return HEAD_LEN;
}

static co_usdo_decode_result_t decode_end(const uint8_t *in, size_t len, co_usdo_msg_t *m)
{
    (void)in;
    (void)len;
    (void)m;
    return CO_USDO_DECODE_OK;
}

static size_t encode_abort(const co_usdo_msg_t *m, uint8_t *out)
{
    put_mux(out, m);
    out[P_CODE] = m->abort_code;
    return ABORT_LEN;
}

static co_usdo_decode_result_t decode_abort(const uint8_t *in, size_t len, co_usdo_msg_t *m)
{
    if (len < ABORT_LEN) {
        return CO_USDO_DECODE_SHORT;
    }
    m->abort_code = in[P_CODE];
    return CO_USDO_DECODE_OK;
}

static size_t encode_bulk_accept(const co_usdo_msg_t *m, uint8_t *out)
{
    put_mux(out, m);
    out[P_PACING] = (uint8_t)(m->pacing & 0xFFu);
    out[P_PACING + 1] = (uint8_t)(m->pacing >> 8);
    return BULK_ACCEPT_LEN;
}

static co_usdo_decode_result_t decode_bulk_accept(const uint8_t *in, size_t len, co_usdo_msg_t *m)
{
    if (len < BULK_ACCEPT_LEN) {
        return CO_USDO_DECODE_SHORT;
    }
    m->pacing = (uint16_t)(in[P_PACING] | (in[P_PACING + 1] << 8));
    return CO_USDO_DECODE_OK;
}

static size_t encode_bulk_request(const co_usdo_msg_t *m, uint8_t *out)
{
    put_mux(out, m);
    out[P_WINDOW] = m->window;
    out[P_WINDOW + 1] = 0;
    return BULK_REQUEST_LEN;
}

static co_usdo_decode_result_t decode_bulk_request(const uint8_t *in, size_t len,
                                                   co_usdo_msg_t *m)
{
    if (len < BULK_REQUEST_LEN) {
        return CO_USDO_DECODE_SHORT;
    }
    m->window = in[P_WINDOW];   /* the reserved byte after it is not looked at */
    return CO_USDO_DECODE_OK;
}

/* ------------------------------------------------------------ dispatch */

static co_usdo_decode_result_t decode_local(const uint8_t *data, size_t len, co_usdo_msg_t *out)
{
    memset(out, 0, sizeof *out);
    if (data == NULL || len < HEAD_LEN) {
        if (data != NULL && len > P_DEST) {
            out->dest = data[P_DEST];
        }
        if (data != NULL && len > P_CS) {
            out->cs = data[P_CS];
        }
        return CO_USDO_DECODE_EMPTY;
    }
    out->dest = data[P_DEST];
    out->cs = data[P_CS];
    out->session = data[P_SESSION];
    co_usdo_layout_t layout = co_usdo_layout_of(out->cs);
    if (layout == CO_USDO_LAYOUT_UNKNOWN) {
        return CO_USDO_DECODE_UNKNOWN_CS;
    }
    if (co_usdo_layout_has_mux(layout)) {
        if (len < MUX_LEN) {
            return CO_USDO_DECODE_SHORT;
        }
        get_mux(data, out);
    }
    switch (layout) {
    case CO_USDO_LAYOUT_MUX:
        return decode_mux(data, len, out);
    case CO_USDO_LAYOUT_EXPEDITED:
        return decode_expedited(data, len, out);
    case CO_USDO_LAYOUT_INITIATE:
        return decode_initiate(data, len, out);
    case CO_USDO_LAYOUT_SEGMENT:
        return decode_segment(data, len, out);
    case CO_USDO_LAYOUT_LAST:
        return decode_last(data, len, out);
    case CO_USDO_LAYOUT_COUNTER:
        return decode_counter(data, len, out);
    case CO_USDO_LAYOUT_END:
        return decode_end(data, len, out);
    case CO_USDO_LAYOUT_ABORT:
        return decode_abort(data, len, out);
    case CO_USDO_LAYOUT_BULK_ACCEPT:
        return decode_bulk_accept(data, len, out);
    case CO_USDO_LAYOUT_BULK_REQUEST:
        return decode_bulk_request(data, len, out);
    default:
        return CO_USDO_DECODE_UNKNOWN_CS;
    }
}

static size_t encode_local(const co_usdo_msg_t *msg, uint8_t out[CO_USDO_FRAME_MAX])
{
    size_t n;
    memset(out, 0, CO_USDO_FRAME_MAX);
    out[P_DEST] = msg->dest;
    out[P_CS] = msg->cs;
    out[P_SESSION] = msg->session;
    switch (co_usdo_layout_of(msg->cs)) {
    case CO_USDO_LAYOUT_MUX:
        n = encode_mux(msg, out);
        break;
    case CO_USDO_LAYOUT_EXPEDITED:
        n = encode_expedited(msg, out);
        break;
    case CO_USDO_LAYOUT_INITIATE:
        n = encode_initiate(msg, out);
        break;
    case CO_USDO_LAYOUT_SEGMENT:
        n = encode_segment(msg, out);
        break;
    case CO_USDO_LAYOUT_LAST:
        n = encode_last(msg, out);
        break;
    case CO_USDO_LAYOUT_COUNTER:
        n = encode_counter(msg, out);
        break;
    case CO_USDO_LAYOUT_END:
        n = encode_end(msg, out);
        break;
    case CO_USDO_LAYOUT_ABORT:
        n = encode_abort(msg, out);
        break;
    case CO_USDO_LAYOUT_BULK_ACCEPT:
        n = encode_bulk_accept(msg, out);
        break;
    case CO_USDO_LAYOUT_BULK_REQUEST:
        n = encode_bulk_request(msg, out);
        break;
    default:
        n = 0;
        break;
    }
    if (n == 0) {
        memset(out, 0, CO_USDO_FRAME_MAX);
    }
    return n;
}

/* ------------------------------------------------------------ remote frames
 * A remote (routed) frame is the local frame with bit 7 of the command
 * specifier set; the frames that carry the multiplexer (the first frame of
 * each direction, and the abort) have the 4-byte addressing extension
 * inserted after the session-ID, the rest of the local layout follows
 * shifted by 4. Layout UNCONFIRMED (docs/protocol-notes.md "Remote USDO"). */

enum { P_EXT = 3 };

static bool mux_of_cs(uint8_t cs)
{
    return co_usdo_layout_has_mux(co_usdo_layout_of((uint8_t)(cs & ~CO_USDO_REMOTE_BIT)));
}

co_usdo_decode_result_t co_usdo_decode(const uint8_t *data, size_t len, co_usdo_msg_t *out)
{
    uint8_t local[CO_USDO_FRAME_MAX];
    size_t n;
    size_t shift;
    co_usdo_decode_result_t r;
    if (data == NULL || len < HEAD_LEN || !(data[P_CS] & CO_USDO_REMOTE_BIT)) {
        return decode_local(data, len, out);
    }
    if (len > CO_USDO_FRAME_MAX) {
        len = CO_USDO_FRAME_MAX;   /* nothing of a USDO frame lies beyond 64 bytes */
    }
    shift = mux_of_cs(data[P_CS]) ? CO_USDO_REMOTE_EXT : 0;
    if (len < HEAD_LEN + shift) {
        memset(out, 0, sizeof *out);
        out->dest = data[P_DEST];
        out->cs = (uint8_t)(data[P_CS] & ~CO_USDO_REMOTE_BIT);
        out->session = data[P_SESSION];
        out->remote = true;
        return CO_USDO_DECODE_SHORT;
    }
    /* the local frame: header, then what follows the extension */
    memcpy(local, data, HEAD_LEN);
    local[P_CS] = (uint8_t)(data[P_CS] & ~CO_USDO_REMOTE_BIT);
    n = len - shift;
    memcpy(local + HEAD_LEN, data + HEAD_LEN + shift, n - HEAD_LEN);
    r = decode_local(local, n, out);
    if (out->data != NULL) {
        out->data = data + (out->data - local) + shift;   /* into the caller's buffer */
    }
    out->remote = true;
    if (shift != 0) {
        out->dst_net = data[P_EXT];
        out->dst_node = data[P_EXT + 1];
        out->src_net = data[P_EXT + 2];
        out->src_node = data[P_EXT + 3];
    }
    return r;
}

size_t co_usdo_encode(const co_usdo_msg_t *msg, uint8_t out[CO_USDO_FRAME_MAX])
{
    uint8_t local[CO_USDO_FRAME_MAX];
    co_usdo_msg_t m;
    size_t n;
    size_t shift;
    if (!msg->remote) {
        return encode_local(msg, out);
    }
    m = *msg;
    m.cs = (uint8_t)(msg->cs & ~CO_USDO_REMOTE_BIT);
    shift = mux_of_cs(m.cs) ? CO_USDO_REMOTE_EXT : 0;
    n = encode_local(&m, local);
    memset(out, 0, CO_USDO_FRAME_MAX);
    if (n == 0 || n + shift > CO_USDO_FRAME_MAX) {
        return 0;   /* e.g. an expedited value above 52 bytes */
    }
    memcpy(out, local, HEAD_LEN);
    out[P_CS] = (uint8_t)(m.cs | CO_USDO_REMOTE_BIT);
    if (shift != 0) {
        out[P_EXT] = msg->dst_net;
        out[P_EXT + 1] = msg->dst_node;
        out[P_EXT + 2] = msg->src_net;
        out[P_EXT + 3] = msg->src_node;
    }
    memcpy(out + HEAD_LEN + shift, local + HEAD_LEN, n - HEAD_LEN);
    return n + shift;
}

/* ------------------------------------------------------------ abort codes
 * CiA 301 code <-> USDO code, matched by meaning (docs/protocol-notes.md).
 * Each row says which way it maps; a CiA 301 code without a row becomes
 * CO_USDO_ABORT_UNKNOWN, a USDO code without one CO_ABORT_GENERAL. */

enum { BOTH = 3, FWD = 1, BACK = 2 };   /* FWD: co -> usdo, BACK: usdo -> co */

typedef struct abort_pair {
    uint32_t co;
    uint8_t usdo;
    uint8_t way;
} abort_pair_t;

static const abort_pair_t abort_map[] = {
    { CO_ABORT_GENERAL, CO_USDO_ABORT_UNKNOWN, BOTH },
    { CO_ABORT_TIMEOUT, CO_USDO_ABORT_TIMEOUT, BOTH },
    { CO_ABORT_COMMAND, CO_USDO_ABORT_COMMAND, BOTH },
    { CO_ABORT_TOGGLE, CO_USDO_ABORT_COUNTER, BOTH },   /* the counter replaces the toggle bit */
    { CO_ABORT_SEQUENCE, CO_USDO_ABORT_COUNTER, FWD },
    { CO_ABORT_BLOCK_SIZE, CO_USDO_ABORT_PROTOCOL, FWD },
    { CO_ABORT_CRC, CO_USDO_ABORT_PROTOCOL, FWD },    /* 0x15 is "data size", not CRC */
    { CO_ABORT_TYPE_MISMATCH, CO_USDO_ABORT_DATA_SIZE, BACK },   /* "length does not match" */
    { CO_ABORT_OUT_OF_MEMORY, CO_USDO_ABORT_OUT_OF_MEMORY, BOTH },
    { CO_ABORT_PARAM_INCOMPATIBLE, CO_USDO_ABORT_PARAM_INCOMPATIBLE, BOTH },
    { CO_ABORT_DEVICE_INCOMPATIBLE, CO_USDO_ABORT_DEVICE_INCOMPATIBLE, BOTH },
    { CO_ABORT_UNSUPPORTED_ACCESS, CO_USDO_ABORT_UNSUPPORTED_ACCESS, BOTH },
    { CO_ABORT_WRITE_ONLY, CO_USDO_ABORT_WRITE_ONLY, BOTH },
    { CO_ABORT_READ_ONLY, CO_USDO_ABORT_READ_ONLY, BOTH },
    { CO_ABORT_NO_OBJECT, CO_USDO_ABORT_NO_OBJECT, BOTH },
    { CO_ABORT_NO_SUB, CO_USDO_ABORT_NO_SUB, BOTH },
    { CO_ABORT_HARDWARE, CO_USDO_ABORT_HARDWARE, BOTH },
    { CO_ABORT_TYPE_MISMATCH, CO_USDO_ABORT_TYPE_MISMATCH, BOTH },
    { CO_ABORT_LENGTH_HIGH, CO_USDO_ABORT_LENGTH_HIGH, BOTH },
    { CO_ABORT_LENGTH_LOW, CO_USDO_ABORT_LENGTH_LOW, BOTH },
    { CO_ABORT_INVALID_VALUE, CO_USDO_ABORT_INVALID_VALUE, BOTH },
    { CO_ABORT_VALUE_HIGH, CO_USDO_ABORT_VALUE_HIGH, BOTH },
    { CO_ABORT_VALUE_LOW, CO_USDO_ABORT_VALUE_LOW, BOTH },
    { CO_ABORT_MAX_LESS_MIN, CO_USDO_ABORT_MAX_LESS_MIN, BOTH },
    { CO_ABORT_MAX_LESS_MIN, CO_USDO_ABORT_MIN_MORE_MAX, BACK },
    { CO_ABORT_NO_MAP, CO_USDO_ABORT_NO_MAP, BOTH },
    { CO_ABORT_MAP_LENGTH, CO_USDO_ABORT_MAP_LENGTH, BOTH },
    { CO_ABORT_DATA_STORE, CO_USDO_ABORT_DATA_STORE, BOTH },
    { CO_ABORT_DATA_LOCAL, CO_USDO_ABORT_DATA_LOCAL, BOTH },
    { CO_ABORT_DATA_STATE, CO_USDO_ABORT_DATA_STATE, BOTH },
    { CO_ABORT_NO_OD, CO_USDO_ABORT_NO_OD, BOTH },
    { CO_ABORT_NO_DATA, CO_USDO_ABORT_NO_DATA, BOTH },
    { CO_ABORT_NO_RESOURCE, CO_USDO_ABORT_BUSY, BOTH }
};

#define ABORT_MAP_COUNT (sizeof abort_map / sizeof abort_map[0])

uint8_t co_usdo_abort_from_co(uint32_t co_abort)
{
    size_t i;
    if (co_abort == CO_ABORT_NONE) {
        return CO_USDO_ABORT_NONE;
    }
    for (i = 0; i < ABORT_MAP_COUNT; i++) {
        if (abort_map[i].co == co_abort && (abort_map[i].way & FWD)) {
            return abort_map[i].usdo;
        }
    }
    return CO_USDO_ABORT_UNKNOWN;
}

uint32_t co_usdo_abort_to_co(uint8_t usdo_abort)
{
    size_t i;
    if (usdo_abort == CO_USDO_ABORT_NONE) {
        return CO_ABORT_NONE;
    }
    for (i = 0; i < ABORT_MAP_COUNT; i++) {
        if (abort_map[i].usdo == usdo_abort && (abort_map[i].way & BACK)) {
            return abort_map[i].co;
        }
    }
    return CO_ABORT_GENERAL;
}
