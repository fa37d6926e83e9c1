/* Classic SDO (CiA 301) wire format: the CAN-IDs of the default channel, the
 * command byte of every frame, and one encoder/decoder pair per frame
 * layout, for both directions, so a server and a client share one codec.
 *
 * Every SDO frame is 8 bytes. Byte 0 is the command: bits 7..5 the command
 * specifier (ccs client -> server, scs server -> client), the rest its
 * flags (n, e, s, t, c, cc/sc, cs/ss). Bytes 1-2 index (little-endian),
 * byte 3 sub-index ("mux") in initiate and abort frames; bytes 4-7 data,
 * size, block size or abort code. The same command byte means different
 * frames in the two directions (0x60 is a download initiate response from a
 * server and an upload segment request from a client), so the decoder is
 * told the direction. Block sub-block segments (byte 0 = c<<7 | seqno) can
 * only be told from other frames by the receiver's state: they have their
 * own decoder.
 *
 * Every layout choice and its evidence: docs/protocol-notes.md (section
 * "Classic SDO"). Decoders take (data, len), never read data[len] or
 * beyond, and fill what they could read even when they refuse the frame;
 * reserved bits ("x") are sent as 0 and ignored on receipt. */
#ifndef CO_SDO_H
#define CO_SDO_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

enum {
    CO_SDO_REQUEST_BASE = 0x600,     /* client -> server, default channel: 0x600 + server node-id */
    CO_SDO_RESPONSE_BASE = 0x580,    /* server -> client, default channel: 0x580 + server node-id */
    CO_SDO_FRAME_LEN = 8,            /* every SDO frame */
    CO_SDO_EXPEDITED_MAX = 4,        /* data bytes of an expedited initiate frame */
    CO_SDO_SEGMENT_DATA = 7,         /* data bytes of a segment / block segment */
    CO_SDO_BLKSIZE_MAX = 127,        /* segments per sub-block: 1..127 */
    CO_SDO_SERVER_PARAM = 0x1200,    /* SDO server parameter: 0x1200 default, 0x1201..0x127F */
    CO_SDO_SERVER_PARAM_LAST = 0x127F,
    CO_SDO_CLIENT_PARAM = 0x1280,    /* SDO client parameter: 0x1280..0x12FF */
    CO_SDO_CLIENT_PARAM_LAST = 0x12FF
};

/* COB-ID entries (0x1200..0x12FF sub 1 / sub 2). */
#define CO_SDO_COB_INVALID 0x80000000u   /* bit 31: the channel is not used */
#define CO_SDO_COB_DYNAMIC 0x40000000u   /* bit 30: allocated dynamically */
#define CO_SDO_COB_FRAME 0x20000000u     /* bit 29: 29-bit CAN-ID (not served here) */
#define CO_SDO_COB_ID_MASK 0x000007FFu   /* bits 0..10: 11-bit CAN-ID */

/* Direction of a frame. */
typedef enum co_sdo_dir {
    CO_SDO_TO_SERVER = 0,   /* request: client -> server (ccs) */
    CO_SDO_TO_CLIENT = 1    /* response: server -> client (scs) */
} co_sdo_dir_t;

/* Every frame the protocol has. The comment gives byte 0 with its flags. */
typedef enum co_sdo_frame {
    CO_SDO_UNKNOWN = 0,                       /* no such command in that direction */
    /* client -> server */
    CO_SDO_DOWNLOAD_INITIATE,                 /* 0x20 | n<<2 | e<<1 | s      ccs 1 */
    CO_SDO_DOWNLOAD_SEGMENT,                  /* t<<4 | n<<1 | c             ccs 0 */
    CO_SDO_UPLOAD_INITIATE,                   /* 0x40                        ccs 2 */
    CO_SDO_UPLOAD_SEGMENT,                    /* 0x60 | t<<4                 ccs 3 */
    CO_SDO_BLOCK_DOWNLOAD_INITIATE,           /* 0xC0 | cc<<2 | s<<1         ccs 6, cs 0 */
    CO_SDO_BLOCK_DOWNLOAD_END,                /* 0xC1 | n<<2                 ccs 6, cs 1 */
    CO_SDO_BLOCK_UPLOAD_INITIATE,             /* 0xA0 | cc<<2                ccs 5, cs 0 */
    CO_SDO_BLOCK_UPLOAD_END_RSP,              /* 0xA1                        ccs 5, cs 1 */
    CO_SDO_BLOCK_UPLOAD_ACK,                  /* 0xA2                        ccs 5, cs 2 */
    CO_SDO_BLOCK_UPLOAD_START,                /* 0xA3                        ccs 5, cs 3 */
    /* server -> client */
    CO_SDO_DOWNLOAD_INITIATE_RSP,             /* 0x60                        scs 3 */
    CO_SDO_DOWNLOAD_SEGMENT_RSP,              /* 0x20 | t<<4                 scs 1 */
    CO_SDO_UPLOAD_INITIATE_RSP,               /* 0x40 | n<<2 | e<<1 | s      scs 2 */
    CO_SDO_UPLOAD_SEGMENT_RSP,                /* t<<4 | n<<1 | c             scs 0 */
    CO_SDO_BLOCK_DOWNLOAD_INITIATE_RSP,       /* 0xA0 | sc<<2                scs 5, ss 0 */
    CO_SDO_BLOCK_DOWNLOAD_END_RSP,            /* 0xA1                        scs 5, ss 1 */
    CO_SDO_BLOCK_DOWNLOAD_ACK,                /* 0xA2                        scs 5, ss 2 */
    CO_SDO_BLOCK_UPLOAD_INITIATE_RSP,         /* 0xC0 | sc<<2 | s<<1         scs 6, ss 0 */
    CO_SDO_BLOCK_UPLOAD_END,                  /* 0xC1 | n<<2                 scs 6, ss 1 */
    /* both directions */
    CO_SDO_ABORT,                             /* 0x80                        (c)cs 4 */
    CO_SDO_BLOCK_SEGMENT                      /* c<<7 | seqno (1..127): co_sdo_decode_block_segment */
} co_sdo_frame_t;

/* Frame layouts (bytes after byte 0); each frame has exactly one:
 *   MUX        1-2 index, 3 sub, 4-7 zero          UPLOAD_INITIATE, DOWNLOAD_INITIATE_RSP
 *   INITIATE   1-3 mux, 4-7 data (e=1) or size     DOWNLOAD_INITIATE, UPLOAD_INITIATE_RSP
 *   SEGMENT    1-7 data (7 - n bytes)              DOWNLOAD_SEGMENT, UPLOAD_SEGMENT_RSP
 *   TOGGLE     1-7 zero                            UPLOAD_SEGMENT, DOWNLOAD_SEGMENT_RSP
 *   ABORT      1-3 mux, 4-7 abort code U32         ABORT
 *   BLK_SIZE   1-3 mux, 4-7 size (s=1) or 0        BLOCK_DOWNLOAD_INITIATE, BLOCK_UPLOAD_INITIATE_RSP
 *   BLK_MUX    1-3 mux, 4 blksize, 5 pst, 6-7 zero BLOCK_UPLOAD_INITIATE, BLOCK_DOWNLOAD_INITIATE_RSP
 *                                                  (pst: request only, 0 in the response)
 *   BLK_ACK    1 ackseq, 2 blksize, 3-7 zero       BLOCK_UPLOAD_ACK, BLOCK_DOWNLOAD_ACK
 *   BLK_END    1-2 CRC (LE), 3-7 zero              BLOCK_DOWNLOAD_END, BLOCK_UPLOAD_END
 *   BLK_CS     1-7 zero                            BLOCK_UPLOAD_START, BLOCK_UPLOAD_END_RSP,
 *                                                  BLOCK_DOWNLOAD_END_RSP
 *   BLK_SEG    1-7 data                            BLOCK_SEGMENT */

/* A decoded (or to-be-encoded) frame. Fields the frame does not have are 0. */
typedef struct co_sdo_msg {
    uint8_t frame;          /* co_sdo_frame_t */
    uint16_t index;         /* MUX, INITIATE, ABORT, BLK_SIZE, BLK_MUX */
    uint8_t sub;
    bool expedited;         /* e: INITIATE */
    bool size_indicated;    /* s: INITIATE, BLK_SIZE */
    bool crc;               /* cc / sc: BLK_SIZE, BLK_MUX */
    bool last;              /* c: SEGMENT, BLOCK_SEGMENT */
    uint8_t toggle;         /* t (0 or 1): SEGMENT, TOGGLE */
    uint8_t length;         /* data bytes carried: INITIATE e=1: 4 - n (s=1) or 4 (s=0);
                               SEGMENT: 7 - n; BLOCK_SEGMENT: 7 (decode) / 0..7 (encode) */
    uint8_t unused;         /* BLK_END: n, bytes of the last segment without data (0..7) */
    uint8_t seqno;          /* BLOCK_SEGMENT: 1..127; BLK_ACK: ackseq 0..127 */
    uint8_t blksize;        /* BLK_MUX, BLK_ACK: 1..127 */
    uint8_t pst;            /* BLOCK_UPLOAD_INITIATE: protocol switch threshold, bytes */
    uint16_t crc_value;     /* BLK_END */
    uint32_t size;          /* INITIATE e=0 s=1, BLK_SIZE s=1 */
    uint32_t abort_code;    /* ABORT */
    const uint8_t *data;    /* decode: points into the decoded buffer; encode: source */
} co_sdo_msg_t;

typedef enum co_sdo_decode_result {
    CO_SDO_DECODE_OK = 0,
    CO_SDO_DECODE_EMPTY = 1,        /* no byte at all */
    CO_SDO_DECODE_UNKNOWN = 2,      /* byte 0 names no frame of that direction (frame = 0) */
    CO_SDO_DECODE_SHORT = 3         /* fewer than 8 bytes: frame (and the mux when bytes
                                       1-3 are there) filled, nothing else */
} co_sdo_decode_result_t;

/* Which frame byte 0 names in that direction (CO_SDO_UNKNOWN if none; never
 * CO_SDO_BLOCK_SEGMENT). */
co_sdo_frame_t co_sdo_frame_of(uint8_t command, co_sdo_dir_t dir);
/* Direction of a frame (CO_SDO_ABORT and CO_SDO_BLOCK_SEGMENT go both ways:
 * CO_SDO_TO_SERVER is returned for them). */
co_sdo_dir_t co_sdo_frame_dir(co_sdo_frame_t frame);
/* True when the frame carries index and sub-index in bytes 1-3. */
bool co_sdo_frame_has_mux(co_sdo_frame_t frame);
/* True for the frames that start a transfer (client -> server initiates). */
bool co_sdo_frame_is_initiate(co_sdo_frame_t frame);

/* Decode len bytes sent in direction dir. Bytes after the 8th are not
 * looked at. Never reads data[len] or beyond; *out is always written. */
co_sdo_decode_result_t co_sdo_decode(const uint8_t *data, size_t len, co_sdo_dir_t dir,
                                     co_sdo_msg_t *out);
/* Decode a block sub-block segment (either direction): seqno = bits 0..6
 * (0 and values above the block size are the caller's to refuse), last =
 * bit 7, length 7, data = bytes 1..7. */
co_sdo_decode_result_t co_sdo_decode_block_segment(const uint8_t *data, size_t len,
                                                   co_sdo_msg_t *out);

/* Encode into out (8 bytes, unused bytes 0): returns 8, or 0 when the frame
 * is unknown or a field does not fit it (expedited length 1..4 with the size
 * indicated, 0..4 without; segment length 0..7; toggle 0/1; seqno 1..127;
 * ackseq 0..127; blksize 1..127; unused 0..7; data NULL with length > 0). */
size_t co_sdo_encode(const co_sdo_msg_t *msg, uint8_t out[CO_SDO_FRAME_LEN]);

/* The default channel of a server with this node-id (0x1200). */
static inline uint32_t co_sdo_request_id(uint8_t server_node) { return CO_SDO_REQUEST_BASE + server_node; }
static inline uint32_t co_sdo_response_id(uint8_t server_node) { return CO_SDO_RESPONSE_BASE + server_node; }

#endif
