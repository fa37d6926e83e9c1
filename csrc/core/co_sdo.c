/* Classic SDO (CiA 301) codec: see co_sdo.h; every byte position and bit
 * is defined once, here, with its evidence in docs/protocol-notes.md. */
#include "canopenfd/co_sdo.h"

#include <string.h>

/* Byte positions. */
enum {
    P_CMD = 0,
    P_INDEX = 1,        /* 2 bytes, little-endian */
    P_SUB = 3,
    P_DATA = 4,         /* expedited data, size, abort code: 4 bytes */
    P_BLKSIZE = 4,      /* block initiate (BLK_MUX) */
    P_PST = 5,          /* block upload initiate */
    P_SEG = 1,          /* segment data: 7 bytes */
    P_ACKSEQ = 1,       /* block ack */
    P_ACK_BLKSIZE = 2,
    P_CRC = 1           /* block end: 2 bytes, little-endian */
};

/* Command byte fields. */
#define CS_SHIFT 5u                 /* bits 7..5: ccs / scs */
#define INIT_N_SHIFT 2u             /* initiate: n in bits 3..2 */
#define INIT_N_MASK 0x03u
#define INIT_E 0x02u
#define INIT_S 0x01u
#define SEG_T 0x10u                 /* segments: t bit 4, n bits 3..1, c bit 0 */
#define SEG_N_SHIFT 1u
#define SEG_N_MASK 0x07u
#define SEG_C 0x01u
#define BLK_CRC 0x04u               /* cc / sc: bit 2 */
#define BLK_S 0x02u                 /* s of block initiate (download request, upload response) */
#define BLK_SUB_MASK 0x03u          /* cs / ss of ccs 5 requests and scs 5 responses: bits 1..0 */
#define BLK_END_BIT 0x01u           /* cs / ss of ccs 6 / scs 6: bit 0 (1 = end) */
#define BLK_END_N_SHIFT 2u          /* end: n in bits 4..2 */
#define BLK_END_N_MASK 0x07u
#define SEGMENT_LAST 0x80u          /* block segment: c in bit 7, seqno in bits 6..0 */
#define SEQNO_MASK 0x7Fu
#define CMD_ABORT 0x80u             /* the abort command: exactly 0x80 */

/* ccs / scs values. */
enum {
    CCS_DOWNLOAD_SEGMENT = 0,
    CCS_DOWNLOAD_INITIATE = 1,
    CCS_UPLOAD_INITIATE = 2,
    CCS_UPLOAD_SEGMENT = 3,
    CCS_ABORT = 4,
    CCS_BLOCK_UPLOAD = 5,
    CCS_BLOCK_DOWNLOAD = 6,
    SCS_UPLOAD_SEGMENT = 0,
    SCS_DOWNLOAD_SEGMENT = 1,
    SCS_UPLOAD_INITIATE = 2,
    SCS_DOWNLOAD_INITIATE = 3,
    SCS_BLOCK_DOWNLOAD = 5,
    SCS_BLOCK_UPLOAD = 6
};

typedef enum layout {
    L_NONE = 0,
    L_MUX,
    L_INITIATE,
    L_SEGMENT,
    L_TOGGLE,
    L_ABORT,
    L_BLK_SIZE,
    L_BLK_MUX,
    L_BLK_ACK,
    L_BLK_END,
    L_BLK_CS,
    L_BLK_SEG
} layout_t;

/* One row per frame: its layout, the command byte without its flags, and
 * the direction. */
typedef struct frame_info {
    uint8_t layout;
    uint8_t base;
    uint8_t dir;
} frame_info_t;

static const frame_info_t frame_table[] = {
    [CO_SDO_UNKNOWN] = {L_NONE, 0x00, CO_SDO_TO_SERVER},
    [CO_SDO_DOWNLOAD_INITIATE] = {L_INITIATE, 0x20, CO_SDO_TO_SERVER},
    [CO_SDO_DOWNLOAD_SEGMENT] = {L_SEGMENT, 0x00, CO_SDO_TO_SERVER},
    [CO_SDO_UPLOAD_INITIATE] = {L_MUX, 0x40, CO_SDO_TO_SERVER},
    [CO_SDO_UPLOAD_SEGMENT] = {L_TOGGLE, 0x60, CO_SDO_TO_SERVER},
    [CO_SDO_BLOCK_DOWNLOAD_INITIATE] = {L_BLK_SIZE, 0xC0, CO_SDO_TO_SERVER},
    [CO_SDO_BLOCK_DOWNLOAD_END] = {L_BLK_END, 0xC1, CO_SDO_TO_SERVER},
    [CO_SDO_BLOCK_UPLOAD_INITIATE] = {L_BLK_MUX, 0xA0, CO_SDO_TO_SERVER},
    [CO_SDO_BLOCK_UPLOAD_END_RSP] = {L_BLK_CS, 0xA1, CO_SDO_TO_SERVER},
    [CO_SDO_BLOCK_UPLOAD_ACK] = {L_BLK_ACK, 0xA2, CO_SDO_TO_SERVER},
    [CO_SDO_BLOCK_UPLOAD_START] = {L_BLK_CS, 0xA3, CO_SDO_TO_SERVER},
    [CO_SDO_DOWNLOAD_INITIATE_RSP] = {L_MUX, 0x60, CO_SDO_TO_CLIENT},
    [CO_SDO_DOWNLOAD_SEGMENT_RSP] = {L_TOGGLE, 0x20, CO_SDO_TO_CLIENT},
    [CO_SDO_UPLOAD_INITIATE_RSP] = {L_INITIATE, 0x40, CO_SDO_TO_CLIENT},
    [CO_SDO_UPLOAD_SEGMENT_RSP] = {L_SEGMENT, 0x00, CO_SDO_TO_CLIENT},
    [CO_SDO_BLOCK_DOWNLOAD_INITIATE_RSP] = {L_BLK_MUX, 0xA0, CO_SDO_TO_CLIENT},
    [CO_SDO_BLOCK_DOWNLOAD_END_RSP] = {L_BLK_CS, 0xA1, CO_SDO_TO_CLIENT},
    [CO_SDO_BLOCK_DOWNLOAD_ACK] = {L_BLK_ACK, 0xA2, CO_SDO_TO_CLIENT},
    [CO_SDO_BLOCK_UPLOAD_INITIATE_RSP] = {L_BLK_SIZE, 0xC0, CO_SDO_TO_CLIENT},
    [CO_SDO_BLOCK_UPLOAD_END] = {L_BLK_END, 0xC1, CO_SDO_TO_CLIENT},
    [CO_SDO_ABORT] = {L_ABORT, CMD_ABORT, CO_SDO_TO_SERVER},
    [CO_SDO_BLOCK_SEGMENT] = {L_BLK_SEG, 0x00, CO_SDO_TO_SERVER}
};

#define FRAME_COUNT (sizeof frame_table / sizeof frame_table[0])

static layout_t layout_of(uint8_t frame)
{
    return frame < FRAME_COUNT ? (layout_t)frame_table[frame].layout : L_NONE;
}

static uint32_t get_le32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static void put_le32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

/* ------------------------------------------------------------ frames */

co_sdo_frame_t co_sdo_frame_of(uint8_t command, co_sdo_dir_t dir)
{
    uint8_t cs = (uint8_t)(command >> CS_SHIFT);
    if (cs == CCS_ABORT) {
        return command == CMD_ABORT ? CO_SDO_ABORT : CO_SDO_UNKNOWN;
    }
    if (dir == CO_SDO_TO_SERVER) {
        switch (cs) {
        case CCS_DOWNLOAD_SEGMENT:
            return CO_SDO_DOWNLOAD_SEGMENT;
        case CCS_DOWNLOAD_INITIATE:
            return CO_SDO_DOWNLOAD_INITIATE;
        case CCS_UPLOAD_INITIATE:
            return CO_SDO_UPLOAD_INITIATE;
        case CCS_UPLOAD_SEGMENT:
            return CO_SDO_UPLOAD_SEGMENT;
        case CCS_BLOCK_UPLOAD:
            switch (command & BLK_SUB_MASK) {
            case 0:
                return CO_SDO_BLOCK_UPLOAD_INITIATE;
            case 1:
                return CO_SDO_BLOCK_UPLOAD_END_RSP;
            case 2:
                return CO_SDO_BLOCK_UPLOAD_ACK;
            default:
                return CO_SDO_BLOCK_UPLOAD_START;
            }
        case CCS_BLOCK_DOWNLOAD:
            return (command & BLK_END_BIT) ? CO_SDO_BLOCK_DOWNLOAD_END
                                           : CO_SDO_BLOCK_DOWNLOAD_INITIATE;
        default:
            return CO_SDO_UNKNOWN;
        }
    }
    switch (cs) {
    case SCS_UPLOAD_SEGMENT:
        return CO_SDO_UPLOAD_SEGMENT_RSP;
    case SCS_DOWNLOAD_SEGMENT:
        return CO_SDO_DOWNLOAD_SEGMENT_RSP;
    case SCS_UPLOAD_INITIATE:
        return CO_SDO_UPLOAD_INITIATE_RSP;
    case SCS_DOWNLOAD_INITIATE:
        return CO_SDO_DOWNLOAD_INITIATE_RSP;
    case SCS_BLOCK_DOWNLOAD:
        switch (command & BLK_SUB_MASK) {
        case 0:
            return CO_SDO_BLOCK_DOWNLOAD_INITIATE_RSP;
        case 1:
            return CO_SDO_BLOCK_DOWNLOAD_END_RSP;
        case 2:
            return CO_SDO_BLOCK_DOWNLOAD_ACK;
        default:
            return CO_SDO_UNKNOWN;
        }
    case SCS_BLOCK_UPLOAD:
        return (command & BLK_END_BIT) ? CO_SDO_BLOCK_UPLOAD_END : CO_SDO_BLOCK_UPLOAD_INITIATE_RSP;
    default:
        return CO_SDO_UNKNOWN;
    }
}

co_sdo_dir_t co_sdo_frame_dir(co_sdo_frame_t frame)
{
    return (unsigned)frame < FRAME_COUNT ? (co_sdo_dir_t)frame_table[frame].dir : CO_SDO_TO_SERVER;
}

bool co_sdo_frame_has_mux(co_sdo_frame_t frame)
{
    layout_t l = layout_of((uint8_t)frame);
    return l == L_MUX || l == L_INITIATE || l == L_ABORT || l == L_BLK_SIZE || l == L_BLK_MUX;
}

bool co_sdo_frame_is_initiate(co_sdo_frame_t frame)
{
    return frame == CO_SDO_DOWNLOAD_INITIATE || frame == CO_SDO_UPLOAD_INITIATE ||
           frame == CO_SDO_BLOCK_DOWNLOAD_INITIATE || frame == CO_SDO_BLOCK_UPLOAD_INITIATE;
}

/* ------------------------------------------------------------ decode */

static void decode_mux(const uint8_t *p, co_sdo_msg_t *m)
{
    m->index = (uint16_t)(p[P_INDEX] | p[P_INDEX + 1] << 8);
    m->sub = p[P_SUB];
}

static void decode_initiate(const uint8_t *p, co_sdo_msg_t *m)
{
    uint8_t c = p[P_CMD];
    decode_mux(p, m);
    m->expedited = (c & INIT_E) != 0;
    m->size_indicated = (c & INIT_S) != 0;
    if (m->expedited) {
        /* e = 1, s = 0: "unspecified number of bytes": all four are given,
         * the receiver decides how many it takes */
        m->length = (uint8_t)(m->size_indicated
                                  ? CO_SDO_EXPEDITED_MAX - ((c >> INIT_N_SHIFT) & INIT_N_MASK)
                                  : CO_SDO_EXPEDITED_MAX);
        m->data = p + P_DATA;
    } else if (m->size_indicated) {
        m->size = get_le32(p + P_DATA);
    }
}

static void decode_segment(const uint8_t *p, co_sdo_msg_t *m)
{
    uint8_t c = p[P_CMD];
    m->toggle = (c & SEG_T) ? 1 : 0;
    m->last = (c & SEG_C) != 0;
    m->length = (uint8_t)(CO_SDO_SEGMENT_DATA - ((c >> SEG_N_SHIFT) & SEG_N_MASK));
    m->data = p + P_SEG;
}

co_sdo_decode_result_t co_sdo_decode(const uint8_t *data, size_t len, co_sdo_dir_t dir,
                                     co_sdo_msg_t *out)
{
    const uint8_t *p = data;
    memset(out, 0, sizeof *out);
    if (len == 0 || data == NULL) {
        return CO_SDO_DECODE_EMPTY;
    }
    out->frame = (uint8_t)co_sdo_frame_of(p[P_CMD], dir);
    if (out->frame == CO_SDO_UNKNOWN) {
        return CO_SDO_DECODE_UNKNOWN;
    }
    if (len < CO_SDO_FRAME_LEN) {
        if (len > P_SUB && co_sdo_frame_has_mux((co_sdo_frame_t)out->frame)) {
            decode_mux(p, out);
        }
        return CO_SDO_DECODE_SHORT;
    }
    switch (layout_of(out->frame)) {
    case L_MUX:
        decode_mux(p, out);
        break;
    case L_INITIATE:
        decode_initiate(p, out);
        break;
    case L_SEGMENT:
        decode_segment(p, out);
        break;
    case L_TOGGLE:
        out->toggle = (p[P_CMD] & SEG_T) ? 1 : 0;
        break;
    case L_ABORT:
        decode_mux(p, out);
        out->abort_code = get_le32(p + P_DATA);
        break;
    case L_BLK_SIZE:
        decode_mux(p, out);
        out->crc = (p[P_CMD] & BLK_CRC) != 0;
        out->size_indicated = (p[P_CMD] & BLK_S) != 0;
        if (out->size_indicated) {
            out->size = get_le32(p + P_DATA);
        }
        break;
    case L_BLK_MUX:
        decode_mux(p, out);
        out->crc = (p[P_CMD] & BLK_CRC) != 0;
        out->blksize = p[P_BLKSIZE];
        if (out->frame == CO_SDO_BLOCK_UPLOAD_INITIATE) {
            out->pst = p[P_PST];
        }
        break;
    case L_BLK_ACK:
        out->seqno = p[P_ACKSEQ];
        out->blksize = p[P_ACK_BLKSIZE];
        break;
    case L_BLK_END:
        out->unused = (uint8_t)((p[P_CMD] >> BLK_END_N_SHIFT) & BLK_END_N_MASK);
        out->crc_value = (uint16_t)(p[P_CRC] | p[P_CRC + 1] << 8);
        break;
    default: /* L_BLK_CS */
        break;
    }
    return CO_SDO_DECODE_OK;
}

co_sdo_decode_result_t co_sdo_decode_block_segment(const uint8_t *data, size_t len,
                                                   co_sdo_msg_t *out)
{
    memset(out, 0, sizeof *out);
    if (len == 0 || data == NULL) {
        return CO_SDO_DECODE_EMPTY;
    }
    out->frame = CO_SDO_BLOCK_SEGMENT;
    out->seqno = (uint8_t)(data[P_CMD] & SEQNO_MASK);
    out->last = (data[P_CMD] & SEGMENT_LAST) != 0;
    if (len < CO_SDO_FRAME_LEN) {
        return CO_SDO_DECODE_SHORT;
    }
    out->length = CO_SDO_SEGMENT_DATA;
    out->data = data + P_SEG;
    return CO_SDO_DECODE_OK;
}

/* ------------------------------------------------------------ encode */

static void encode_mux(const co_sdo_msg_t *m, uint8_t *out)
{
    out[P_INDEX] = (uint8_t)(m->index & 0xFFu);
    out[P_INDEX + 1] = (uint8_t)(m->index >> 8);
    out[P_SUB] = m->sub;
}

static bool copy_data(const co_sdo_msg_t *m, uint8_t *dst)
{
    if (m->length > 0) {
        if (m->data == NULL) {
            return false;
        }
        memcpy(dst, m->data, m->length);
    }
    return true;
}

static bool encode_initiate(const co_sdo_msg_t *m, uint8_t base, uint8_t *out)
{
    uint8_t c = base;
    encode_mux(m, out);
    if (m->expedited) {
        if (m->length > CO_SDO_EXPEDITED_MAX || (m->size_indicated && m->length == 0) ||
            !copy_data(m, out + P_DATA)) {
            return false;
        }
        c |= INIT_E;
        if (m->size_indicated) {
            c |= (uint8_t)(INIT_S | (CO_SDO_EXPEDITED_MAX - m->length) << INIT_N_SHIFT);
        }
    } else if (m->size_indicated) {
        c |= INIT_S;
        put_le32(out + P_DATA, m->size);
    }
    out[P_CMD] = c;
    return true;
}

static bool encode_segment(const co_sdo_msg_t *m, uint8_t *out)
{
    if (m->length > CO_SDO_SEGMENT_DATA || m->toggle > 1 || !copy_data(m, out + P_SEG)) {
        return false;
    }
    out[P_CMD] = (uint8_t)((m->toggle ? SEG_T : 0u) |
                           (unsigned)(CO_SDO_SEGMENT_DATA - m->length) << SEG_N_SHIFT |
                           (m->last ? SEG_C : 0u));
    return true;
}

static bool blksize_ok(uint8_t blksize)
{
    return blksize >= 1 && blksize <= CO_SDO_BLKSIZE_MAX;
}

size_t co_sdo_encode(const co_sdo_msg_t *m, uint8_t out[CO_SDO_FRAME_LEN])
{
    memset(out, 0, CO_SDO_FRAME_LEN);
    if (m->frame >= FRAME_COUNT) {
        return 0;
    }
    uint8_t base = frame_table[m->frame].base;
    bool ok = true;
    out[P_CMD] = base;
    switch (layout_of(m->frame)) {
    case L_MUX:
        encode_mux(m, out);
        break;
    case L_INITIATE:
        ok = encode_initiate(m, base, out);
        break;
    case L_SEGMENT:
        ok = encode_segment(m, out);
        break;
    case L_TOGGLE:
        ok = m->toggle <= 1;
        out[P_CMD] = (uint8_t)(base | (m->toggle ? SEG_T : 0u));
        break;
    case L_ABORT:
        encode_mux(m, out);
        put_le32(out + P_DATA, m->abort_code);
        break;
    case L_BLK_SIZE:
        encode_mux(m, out);
        out[P_CMD] = (uint8_t)(base | (m->crc ? BLK_CRC : 0u) | (m->size_indicated ? BLK_S : 0u));
        if (m->size_indicated) {
            put_le32(out + P_DATA, m->size);
        }
        break;
    case L_BLK_MUX:
        ok = blksize_ok(m->blksize);
        encode_mux(m, out);
        out[P_CMD] = (uint8_t)(base | (m->crc ? BLK_CRC : 0u));
        out[P_BLKSIZE] = m->blksize;
        if (m->frame == CO_SDO_BLOCK_UPLOAD_INITIATE) {
            out[P_PST] = m->pst;
        }
        break;
    case L_BLK_ACK:
        ok = m->seqno <= CO_SDO_BLKSIZE_MAX && blksize_ok(m->blksize);
        out[P_ACKSEQ] = m->seqno;
        out[P_ACK_BLKSIZE] = m->blksize;
        break;
    case L_BLK_END:
        ok = m->unused <= BLK_END_N_MASK;
        out[P_CMD] = (uint8_t)(base | (m->unused & BLK_END_N_MASK) << BLK_END_N_SHIFT);
        out[P_CRC] = (uint8_t)(m->crc_value & 0xFFu);
        out[P_CRC + 1] = (uint8_t)(m->crc_value >> 8);
        break;
    case L_BLK_CS:
        break;
    case L_BLK_SEG:
        ok = m->seqno >= 1 && m->seqno <= CO_SDO_BLKSIZE_MAX &&
             m->length <= CO_SDO_SEGMENT_DATA && copy_data(m, out + P_SEG);
        out[P_CMD] = (uint8_t)(m->seqno | (m->last ? SEGMENT_LAST : 0u));
        break;
    default:
        ok = false;
        break;
    }
    if (!ok) {
        memset(out, 0, CO_SDO_FRAME_LEN);
        return 0;
    }
    return CO_SDO_FRAME_LEN;
}
