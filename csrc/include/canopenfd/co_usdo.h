/* USDO (CiA 1301 Universal SDO) wire format: CAN-IDs, command specifiers,
 * one encoder/decoder pair for every frame layout, and the mapping between
 * CiA 301 32-bit abort codes and the one-byte USDO abort codes.
 *
 * Every layout choice and its evidence is written down in
 * docs/protocol-notes.md (section "USDO"); a layout found wrong later is
 * changed here, in one place. The decoder takes (data, len), never reads
 * beyond len, and fills what it could read even when the frame is refused,
 * so a server can still address its abort. */
#ifndef CO_USDO_H
#define CO_USDO_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* CAN-IDs: the low 7 bits always name the SENDER; the addressee is byte 0. */
enum {
    CO_USDO_REQUEST_BASE = 0x600,    /* client -> server: 0x600 + client node-id */
    CO_USDO_RESPONSE_BASE = 0x580,   /* server -> client: 0x580 + server node-id */
    CO_USDO_BROADCAST = 0,           /* byte 0 of a request to every server */
    CO_USDO_EXPEDITED_MAX = 56,      /* data bytes of an expedited frame (64 - 8) */
    CO_USDO_SEGMENT_DATA = 60,       /* data bytes of a segment frame (64 - 4) */
    CO_USDO_SEGMENT_MIN = 5,         /* shortest segment accepted: 4 header bytes + 1 */
    CO_USDO_FRAME_MAX = 64,
    /* Remote (routed) USDO, layout UNCONFIRMED (docs/protocol-notes.md):
     * command specifier | 0x80; the frames with a multiplexer carry 4 bytes
     * after the session-ID: destination network, destination node, source
     * network, source node. */
    CO_USDO_REMOTE_BIT = 0x80,
    CO_USDO_REMOTE_EXT = 4,
    CO_USDO_REMOTE_EXPEDITED_MAX = 52  /* 64 - 8 - 4 */
};

/* Command specifiers (byte 1). Bit 5 = response, bit 4 = upload direction;
 * the abort is the same for both directions. */
typedef enum co_usdo_cs {
    CO_USDO_CS_DOWNLOAD_EXPEDITED = 0x01,      /* request, expedited data */
    CO_USDO_CS_DOWNLOAD_INITIATE = 0x02,       /* request, segmented: total size */
    CO_USDO_CS_DOWNLOAD_SEGMENT = 0x03,        /* request, 60 data bytes */
    CO_USDO_CS_DOWNLOAD_LAST = 0x04,           /* request, last 0..60 bytes */
    CO_USDO_CS_BULK_INITIATE = 0x06,           /* request, bulk download: total size */
    CO_USDO_CS_BULK_SEGMENT = 0x07,            /* request, 60 data bytes, not confirmed */
    CO_USDO_CS_BULK_LAST = 0x08,               /* request, last 0..60 bytes */
    CO_USDO_CS_UPLOAD = 0x11,                  /* request (expedited or segmented) */
    CO_USDO_CS_UPLOAD_SEGMENT = 0x13,          /* request for the next segment */
    CO_USDO_CS_BULK_UPLOAD = 0x16,             /* request, bulk upload: the client's window
                                                  (layout UNCONFIRMED, our choice) */
    CO_USDO_CS_BULK_UPLOAD_ACK = 0x17,         /* request: segments received up to a counter,
                                                  more credit (our choice) */
    CO_USDO_CS_DOWNLOAD_EXPEDITED_RSP = 0x21,
    CO_USDO_CS_DOWNLOAD_INITIATE_RSP = 0x22,
    CO_USDO_CS_DOWNLOAD_SEGMENT_RSP = 0x23,
    CO_USDO_CS_DOWNLOAD_LAST_RSP = 0x24,
    CO_USDO_CS_BULK_INITIATE_RSP = 0x26,       /* carries the server's pacing */
    CO_USDO_CS_BULK_LAST_RSP = 0x28,
    CO_USDO_CS_UPLOAD_EXPEDITED_RSP = 0x31,
    CO_USDO_CS_UPLOAD_INITIATE_RSP = 0x32,
    CO_USDO_CS_UPLOAD_SEGMENT_RSP = 0x33,
    CO_USDO_CS_UPLOAD_LAST_RSP = 0x34,
    CO_USDO_CS_BULK_UPLOAD_INITIATE_RSP = 0x36, /* bulk upload: type and total size */
    CO_USDO_CS_BULK_UPLOAD_SEGMENT_RSP = 0x37,  /* 60 data bytes, not confirmed one by one */
    CO_USDO_CS_BULK_UPLOAD_LAST_RSP = 0x38,     /* last 0..60 bytes: the transfer ends */
    CO_USDO_CS_ABORT = 0x7F,
    CO_USDO_CS_REMOTE_ABORT = 0xFF             /* the abort of a remote transfer (0x7F | 0x80) */
} co_usdo_cs_t;

/* One-byte USDO abort codes (byte 6 of the abort frame). */
typedef enum co_usdo_abort {
    CO_USDO_ABORT_NONE = 0x00,
    CO_USDO_ABORT_UNKNOWN = 0x10,              /* unknown (general) error */
    CO_USDO_ABORT_PROTOCOL = 0x11,
    CO_USDO_ABORT_TIMEOUT = 0x12,
    CO_USDO_ABORT_COMMAND = 0x13,              /* command specifier unknown / unexpected */
    CO_USDO_ABORT_COUNTER = 0x14,              /* invalid segment counter */
    CO_USDO_ABORT_DATA_SIZE = 0x15,            /* size field differs from bytes moved */
    CO_USDO_ABORT_OUT_OF_MEMORY = 0x16,
    CO_USDO_ABORT_PARAM_INCOMPATIBLE = 0x17,
    CO_USDO_ABORT_DEVICE_INCOMPATIBLE = 0x18,
    CO_USDO_ABORT_ROUTING = 0x19,
    CO_USDO_ABORT_DEST_NETWORK = 0x1A,
    CO_USDO_ABORT_DEST_NODE = 0x1B,
    CO_USDO_ABORT_SOURCE_NETWORK = 0x1C,
    CO_USDO_ABORT_SOURCE_NODE = 0x1D,
    CO_USDO_ABORT_DLC = 0x1E,                  /* unexpected data length */
    CO_USDO_ABORT_MULTIPLEXER = 0x1F,
    CO_USDO_ABORT_PARALLEL = 0x20,             /* value UNCONFIRMED (docs/protocol-notes.md) */
    CO_USDO_ABORT_SESSION = 0x21,              /* session-ID wrong or unknown */
    CO_USDO_ABORT_UNSUPPORTED_ACCESS = 0x30,
    CO_USDO_ABORT_WRITE_ONLY = 0x31,           /* read of a write-only entry */
    CO_USDO_ABORT_READ_ONLY = 0x32,            /* write of a read-only entry */
    CO_USDO_ABORT_NO_OBJECT = 0x33,
    CO_USDO_ABORT_NO_SUB = 0x34,
    CO_USDO_ABORT_HARDWARE = 0x35,
    CO_USDO_ABORT_TYPE_MISMATCH = 0x36,
    CO_USDO_ABORT_LENGTH_HIGH = 0x37,
    CO_USDO_ABORT_LENGTH_LOW = 0x38,
    CO_USDO_ABORT_INVALID_VALUE = 0x40,
    CO_USDO_ABORT_VALUE_HIGH = 0x41,
    CO_USDO_ABORT_VALUE_LOW = 0x42,
    CO_USDO_ABORT_MAX_LESS_MIN = 0x43,
    CO_USDO_ABORT_MIN_MORE_MAX = 0x44,
    CO_USDO_ABORT_CAN_ID_READ_ONLY = 0x45,
    CO_USDO_ABORT_NO_MAP = 0x50,
    CO_USDO_ABORT_MAP_LENGTH = 0x51,
    CO_USDO_ABORT_NOT_MAPPABLE = 0x52,
    CO_USDO_ABORT_RPDO_ONLY = 0x53,
    CO_USDO_ABORT_TPDO_ONLY = 0x54,
    CO_USDO_ABORT_PDO_VALID = 0x55,
    CO_USDO_ABORT_MAPPING_VALID = 0x56,
    CO_USDO_ABORT_DATA_STORE = 0x60,
    CO_USDO_ABORT_DATA_LOCAL = 0x61,
    CO_USDO_ABORT_DATA_STATE = 0x62,
    CO_USDO_ABORT_NO_OD = 0x63,
    CO_USDO_ABORT_NO_DATA = 0x64,
    CO_USDO_ABORT_BUSY = 0x70                  /* USDO server busy */
} co_usdo_abort_t;

/* Frame layouts; each command specifier has exactly one. */
typedef enum co_usdo_layout {
    CO_USDO_LAYOUT_UNKNOWN = 0,   /* command specifier without a known layout */
    CO_USDO_LAYOUT_MUX,           /* 6: dest cs sid sub index(2)                 0x11 0x21 0x22 */
    CO_USDO_LAYOUT_EXPEDITED,     /* 8+N: mux type N data[N], N 0..56            0x01 0x31 */
    CO_USDO_LAYOUT_INITIATE,      /* 12: mux type 0 size(4)                 0x02 0x32 0x06 0x36 */
    CO_USDO_LAYOUT_SEGMENT,       /* 64: dest cs sid counter data[60]       0x03 0x33 0x07 0x37
                                     (5..63 bytes accepted: data = the rest) */
    CO_USDO_LAYOUT_LAST,          /* 4+n: dest cs sid n data[n], n 0..60    0x04 0x34 0x08 0x38 */
    CO_USDO_LAYOUT_COUNTER,       /* 4: dest cs sid counter                 0x13 0x23 0x17 */
    CO_USDO_LAYOUT_END,           /* 3: dest cs sid                              0x24 0x28 */
    CO_USDO_LAYOUT_ABORT,         /* 7: mux code                                 0x7F */
    CO_USDO_LAYOUT_BULK_ACCEPT,   /* 8: mux pacing(2), 100 us units, 0 = none    0x26 (UNCONFIRMED) */
    CO_USDO_LAYOUT_BULK_REQUEST   /* 8: mux window(1) reserved(1)                0x16 (UNCONFIRMED) */
} co_usdo_layout_t;

/* A decoded (or to-be-encoded) frame. Fields a layout does not have are 0. */
typedef struct co_usdo_msg {
    uint8_t dest;          /* byte 0: addressee (requests: server or 0; responses: client) */
    uint8_t cs;            /* byte 1: command specifier */
    uint8_t session;       /* byte 2: session-ID */
    uint8_t sub;           /* MUX, EXPEDITED, INITIATE, ABORT */
    uint16_t index;
    uint8_t type;          /* EXPEDITED, INITIATE: CiA 301 data type */
    uint8_t counter;       /* SEGMENT, COUNTER: 8-bit segment counter */
    uint8_t abort_code;    /* ABORT: co_usdo_abort_t */
    uint32_t size;         /* INITIATE: total size of the transfer */
    uint16_t pacing;       /* BULK_ACCEPT: minimum gap between bulk segments, 100 us units */
    uint8_t window;        /* BULK_REQUEST: segments the server may send beyond those
                              acknowledged (0 is invalid: the server refuses it) */
    uint8_t length;        /* EXPEDITED: N, SEGMENT: 60 (sent; 1..60 received), LAST: n */
    const uint8_t *data;   /* decode: points into the decoded buffer; encode: source */
    /* Remote (routed) frames: `cs` above is the local command specifier, the
     * wire carries cs | 0x80. The addressing extension is read and written
     * only for the layouts with a multiplexer (0 in the others). */
    bool remote;
    uint8_t dst_net;       /* network-id of the addressed server */
    uint8_t dst_node;      /* its node-id */
    uint8_t src_net;       /* network-id of the client */
    uint8_t src_node;      /* its node-id */
} co_usdo_msg_t;

typedef enum co_usdo_decode_result {
    CO_USDO_DECODE_OK = 0,
    CO_USDO_DECODE_EMPTY = 1,        /* fewer than 3 bytes: no dest/cs/session */
    CO_USDO_DECODE_UNKNOWN_CS = 2,   /* no layout for byte 1 (dest, cs, session filled) */
    CO_USDO_DECODE_SHORT = 3,        /* shorter than the layout needs (incl. its data) */
    CO_USDO_DECODE_BAD_LENGTH = 4    /* N > 56 or n > 60 */
} co_usdo_decode_result_t;

co_usdo_layout_t co_usdo_layout_of(uint8_t cs);
/* True when the layout carries sub-index and index (bytes 3..5). */
bool co_usdo_layout_has_mux(co_usdo_layout_t layout);

/* Decode len bytes (trailing padding is fine: in-frame size fields give the
 * data length). A SEGMENT frame has no size field: 64 bytes carry 60 data
 * bytes; a shorter one (5..63 bytes, a sender with a smaller "MTU") is
 * accepted with len - 4 data bytes (co_usdo_short_segment tells). Never reads data[len] or beyond. *out is always written:
 * whatever could be read (dest, cs, session from 3 bytes on; sub/index when
 * the layout has them and 6 bytes are there), the rest 0. */
co_usdo_decode_result_t co_usdo_decode(const uint8_t *data, size_t len, co_usdo_msg_t *out);

/* A decoded SEGMENT frame that carried fewer than 60 data bytes (we never
 * send one; receivers accept and count it). */
static inline bool co_usdo_short_segment(const co_usdo_msg_t *m)
{
    return m->length < CO_USDO_SEGMENT_DATA;
}

/* Encode into out (64 bytes): returns the frame length before FD rounding
 * (the line rounds up and pads with 0), 0 when the command specifier has no
 * layout or the data length does not fit it. */
size_t co_usdo_encode(const co_usdo_msg_t *msg, uint8_t out[CO_USDO_FRAME_MAX]);

/* Abort code mapping. co_abort_t values without a USDO counterpart give
 * CO_USDO_ABORT_UNKNOWN; USDO codes without a CiA 301 counterpart give
 * CO_ABORT_GENERAL (0x08000000). */
/* cffi:begin */
uint8_t co_usdo_abort_from_co(uint32_t co_abort);
uint32_t co_usdo_abort_to_co(uint8_t usdo_abort);
/* cffi:end */

/* The segment counter after `counter`: wraps from 0xFF to 0x00 (UNCONFIRMED,
 * see docs/protocol-notes.md). */
static inline uint8_t co_usdo_next_counter(uint8_t counter) { return (uint8_t)(counter + 1u); }

static inline uint32_t co_usdo_request_id(uint8_t client) { return CO_USDO_REQUEST_BASE + client; }
static inline uint32_t co_usdo_response_id(uint8_t server) { return CO_USDO_RESPONSE_BASE + server; }

#endif
