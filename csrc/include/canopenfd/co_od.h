/* Object dictionary: a sorted table of sub-entries (index:sub) over caller
 * storage, built at run time (no allocation), looked up in O(log n). Values
 * are stored little-endian exactly as on the wire. Network access (SDO/USDO)
 * goes through transfers that move data in chunks, so a domain of any size
 * streams through application callbacks and never sits in RAM whole. */
#ifndef CO_OD_H
#define CO_OD_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "canopenfd/co_line.h"

/* cffi:begin */
/* CiA 301 data type indices. */
typedef enum co_od_type {
    CO_TYPE_BOOLEAN = 0x01,
    CO_TYPE_INTEGER8 = 0x02,
    CO_TYPE_INTEGER16 = 0x03,
    CO_TYPE_INTEGER32 = 0x04,
    CO_TYPE_UNSIGNED8 = 0x05,
    CO_TYPE_UNSIGNED16 = 0x06,
    CO_TYPE_UNSIGNED32 = 0x07,
    CO_TYPE_REAL32 = 0x08,
    CO_TYPE_VISIBLE_STRING = 0x09,
    CO_TYPE_OCTET_STRING = 0x0A,
    CO_TYPE_UNICODE_STRING = 0x0B,
    CO_TYPE_TIME_OF_DAY = 0x0C,
    CO_TYPE_TIME_DIFFERENCE = 0x0D,
    CO_TYPE_DOMAIN = 0x0F,
    CO_TYPE_INTEGER24 = 0x10,
    CO_TYPE_REAL64 = 0x11,
    CO_TYPE_INTEGER40 = 0x12,
    CO_TYPE_INTEGER48 = 0x13,
    CO_TYPE_INTEGER56 = 0x14,
    CO_TYPE_INTEGER64 = 0x15,
    CO_TYPE_UNSIGNED24 = 0x16,
    CO_TYPE_UNSIGNED40 = 0x18,
    CO_TYPE_UNSIGNED48 = 0x19,
    CO_TYPE_UNSIGNED56 = 0x1A,
    CO_TYPE_UNSIGNED64 = 0x1B
} co_od_type_t;

typedef enum co_od_object_code {
    CO_OBJECT_DOMAIN = 0x02,
    CO_OBJECT_VAR = 0x07,
    CO_OBJECT_ARRAY = 0x08,
    CO_OBJECT_RECORD = 0x09
} co_od_object_code_t;

typedef enum co_od_access {
    CO_ACCESS_RO = 1,
    CO_ACCESS_WO = 2,
    CO_ACCESS_RW = 3,
    CO_ACCESS_RWR = 4,     /* rw, read by the process (TPDO side) */
    CO_ACCESS_RWW = 5,     /* rw, written by the process (RPDO side) */
    CO_ACCESS_CONST = 6
} co_od_access_t;

enum co_od_flags {
    CO_OD_MAP_TPDO = 0x0001,        /* may be mapped into a TPDO */
    CO_OD_MAP_RPDO = 0x0002,        /* may be mapped into an RPDO */
    CO_OD_STORE = 0x0004,           /* saved by 0x1010, restored at reset */
    CO_OD_NODEID_RELATIVE = 0x0008, /* default is $NODEID + value */
    CO_OD_FD_ONLY = 0x0010,         /* exists on fd lines only */
    CO_OD_CLASSIC_ONLY = 0x0020,    /* exists on classic lines only */
    CO_OD_HAS_MIN = 0x0040,         /* min limit checked on network writes */
    CO_OD_HAS_MAX = 0x0080          /* max limit checked on network writes */
};  /* other bits are refused by co_od_add (CO_OD_ERR_TYPE); 0x8000 is used inside */

/* CiA 301 SDO abort codes; USDO maps each to its one-byte code. */
typedef enum co_abort {
    CO_ABORT_NONE = 0,
    CO_ABORT_TOGGLE = 0x05030000,
    CO_ABORT_TIMEOUT = 0x05040000,
    CO_ABORT_COMMAND = 0x05040001,
    CO_ABORT_BLOCK_SIZE = 0x05040002,
    CO_ABORT_SEQUENCE = 0x05040003,
    CO_ABORT_CRC = 0x05040004,
    CO_ABORT_OUT_OF_MEMORY = 0x05040005,
    CO_ABORT_UNSUPPORTED_ACCESS = 0x06010000,
    CO_ABORT_WRITE_ONLY = 0x06010001,     /* attempt to read a write-only object */
    CO_ABORT_READ_ONLY = 0x06010002,      /* attempt to write a read-only object */
    CO_ABORT_NO_OBJECT = 0x06020000,
    CO_ABORT_NO_MAP = 0x06040041,
    CO_ABORT_MAP_LENGTH = 0x06040042,
    CO_ABORT_PARAM_INCOMPATIBLE = 0x06040043,
    CO_ABORT_DEVICE_INCOMPATIBLE = 0x06040047,
    CO_ABORT_HARDWARE = 0x06060000,
    CO_ABORT_TYPE_MISMATCH = 0x06070010,
    CO_ABORT_LENGTH_HIGH = 0x06070012,
    CO_ABORT_LENGTH_LOW = 0x06070013,
    CO_ABORT_NO_SUB = 0x06090011,
    CO_ABORT_INVALID_VALUE = 0x06090030,
    CO_ABORT_VALUE_HIGH = 0x06090031,
    CO_ABORT_VALUE_LOW = 0x06090032,
    CO_ABORT_MAX_LESS_MIN = 0x06090036,
    CO_ABORT_NO_RESOURCE = 0x060A0023,
    CO_ABORT_GENERAL = 0x08000000,
    CO_ABORT_DATA_STORE = 0x08000020,
    CO_ABORT_DATA_LOCAL = 0x08000021,
    CO_ABORT_DATA_STATE = 0x08000022,
    CO_ABORT_NO_OD = 0x08000023,
    CO_ABORT_NO_DATA = 0x08000024
} co_abort_t;

/* Parameter groups of 0x1010 / 0x1011 (bit masks). */
enum co_od_group {
    CO_GROUP_COMMUNICATION = 0x1,   /* 0x1000..0x1FFF */
    CO_GROUP_APPLICATION = 0x2,     /* 0x6000..0x9FFF (CiA 301: 0x1010 sub 3) */
    CO_GROUP_MANUFACTURER = 0x4,    /* 0x2000..0x5FFF and 0xA000..0xFFFF (sub 4) */
    CO_GROUP_ALL = 0x7
};

/* Who wrote an entry (told to after-write handlers). */
typedef enum co_od_origin {
    CO_ORIGIN_LOCAL = 0,     /* the application (co_od_put) */
    CO_ORIGIN_NETWORK = 1,   /* SDO / USDO download */
    CO_ORIGIN_PDO = 2,       /* received PDO */
    CO_ORIGIN_RESTORE = 3    /* defaults or stored values loaded at reset */
} co_od_origin_t;

/* One sub-entry to add: what an EDS/XDD entry says. */
typedef struct co_od_def {
    uint16_t index;
    uint8_t sub;
    uint8_t object_code;      /* co_od_object_code_t of the object it belongs to */
    uint8_t type;             /* co_od_type_t */
    uint8_t access;           /* co_od_access_t */
    uint16_t flags;           /* co_od_flags */
    uint32_t size;            /* storage bytes: the type's size, the maximum length of a
                                 string, 0 for domains (data lives with the application) */
    const uint8_t *default_value;
    uint32_t default_length;
    uint8_t min[8];           /* limits, little-endian in the entry's type */
    uint8_t max[8];
} co_od_def_t;
/* cffi:end */

/* Returned by handlers to defer the answer (split indication): the transfer
 * waits until the application calls co_od_resume(). */
#define CO_OD_SPLIT 0xFFFFFFFFu
/* Size of a transfer that did not say it (segmented without size). */
#define CO_OD_SIZE_UNKNOWN 0xFFFFFFFFu

typedef struct co_od_entry {
    uint32_t key;             /* index << 8 | sub: the sort key */
    uint8_t object_code;
    uint8_t type;
    uint8_t access;
    uint16_t flags;
    uint32_t size;            /* capacity in bytes (0 for domains) */
    uint32_t length;          /* current length (strings shrink and grow) */
    uint32_t value;           /* offset of the value in the pool */
    uint32_t default_value;   /* offset of the default in the pool */
    uint32_t default_length;
    uint32_t limits;          /* offset of min[size] max[size] in the pool; valid only
                                 when flags has CO_OD_HAS_MIN or CO_OD_HAS_MAX */
} co_od_entry_t;

static inline uint16_t co_od_entry_index(const co_od_entry_t *e) { return (uint16_t)(e->key >> 8); }
static inline uint8_t co_od_entry_sub(const co_od_entry_t *e) { return (uint8_t)(e->key & 0xFFu); }

typedef struct co_od co_od_t;
typedef struct co_od_xfer co_od_xfer_t;

/* Application handlers for a range of entries. Every callback may be NULL.
 * Several handlers may cover one entry: for a write every check_write runs
 * first (test) and only when all accept does the value change and every
 * after_write run (execute). before_read and check_write may return an abort
 * code to refuse, or CO_OD_SPLIT to answer later through co_od_resume(). */
typedef struct co_od_handler {
    uint32_t (*before_read)(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e, void *user);
    uint32_t (*check_write)(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e,
                            const uint8_t *value, uint32_t length, void *user);
    void (*after_write)(co_od_t *od, const co_od_entry_t *e, co_od_origin_t origin, void *user);
    /* Domains: size of the data to upload (CO_OD_SIZE_UNKNOWN if not known). */
    uint32_t (*domain_size)(co_od_t *od, const co_od_entry_t *e, uint32_t *size, void *user);
    /* Domains: copy up to cap bytes from offset into buf; *n = bytes given,
     * *last = true at the end of the data. Returns an abort code or 0. */
    uint32_t (*domain_read)(co_od_t *od, const co_od_entry_t *e, uint32_t offset, uint8_t *buf,
                            uint32_t cap, uint32_t *n, bool *last, void *user);
    /* Domains: accept n bytes at offset (total = announced size or
     * CO_OD_SIZE_UNKNOWN); last = true on the final chunk, and once more with
     * n = 0 and a non-zero abort when the transfer is aborted. */
    uint32_t (*domain_write)(co_od_t *od, const co_od_entry_t *e, uint32_t offset,
                             const uint8_t *data, uint32_t n, uint32_t total, bool last,
                             uint32_t abort, void *user);
    /* Domains, optional, of the handler with domain_write: a download is
     * starting (total = announced size or CO_OD_SIZE_UNKNOWN). An abort code
     * refuses it at the initiate, e.g. CO_ABORT_LENGTH_HIGH when total cannot
     * fit, instead of at its first segment; no domain_write call follows. */
    uint32_t (*domain_begin)(co_od_t *od, const co_od_entry_t *e, uint32_t total, void *user);
} co_od_handler_t;

typedef struct co_od_subscription {
    uint32_t first_key;
    uint32_t last_key;
    const co_od_handler_t *handler;
    void *user;
} co_od_subscription_t;

struct co_od {
    co_mode_t mode;               /* entries of the other mode are not added */
    uint8_t node_id;              /* for $NODEID-relative defaults */
    bool sealed;                  /* no more adds: sorted and checked */
    uint16_t refused_index;       /* the object co_od_seal() refused */
    co_od_entry_t *entries;
    uint32_t count;
    uint32_t sorted_count;        /* entries[0..sorted_count): sorted; the rest were added
                                     live, in arrival order (nothing ever moves after seal) */
    uint32_t capacity;
    uint32_t live_size_max;       /* largest entry at seal: what the servers' scratch holds */
    uint8_t *pool;                /* values, defaults and limits */
    uint32_t pool_used;
    uint32_t pool_size;
    co_od_subscription_t *subs;
    uint8_t sub_count;
    uint8_t sub_capacity;
    uint32_t image_size;          /* pool[0..image_size): the process image (seed 004) */
};

typedef enum co_od_xfer_state {
    CO_XFER_IDLE = 0,
    CO_XFER_READ,             /* upload: chunks can be read */
    CO_XFER_WRITE,            /* download: chunks can be written */
    CO_XFER_PENDING_READ,     /* before_read said CO_OD_SPLIT */
    CO_XFER_PENDING_WRITE,    /* check_write said CO_OD_SPLIT */
    CO_XFER_DONE
} co_od_xfer_state_t;

/* One network access in progress (an SDO/USDO server owns one per session).
 * Non-domain writes collect the value in `scratch` (at least the largest
 * entry size) and change the entry only at the end, after every check. The
 * fields are the OD's: scratch stays as given to co_od_xfer_init. */
struct co_od_xfer {
    co_od_t *od;
    const co_od_entry_t *entry;
    co_od_xfer_state_t state;
    uint32_t offset;          /* bytes moved so far */
    uint32_t total;           /* bytes to move, CO_OD_SIZE_UNKNOWN if not known */
    uint8_t *scratch;
    uint32_t scratch_size;
    uint8_t next_handler;     /* where a split test chain goes on */
    uint32_t abort;           /* the abort code once failed */
};

/* ---- building */
/* entries/pool/subs are caller storage; nothing is allocated later. */
void co_od_init(co_od_t *od, co_mode_t mode, co_od_entry_t *entries, uint32_t capacity,
                uint8_t *pool, uint32_t pool_size, co_od_subscription_t *subs,
                uint8_t sub_capacity);
/* Pool bytes one definition needs (value, default, limits). */
uint32_t co_od_pool_need(const co_od_def_t *def);
typedef enum co_od_add_result {
    CO_OD_ADDED = 0,
    CO_OD_SKIPPED_MODE = 1,       /* entry for the other kind of line: left out */
    CO_OD_ERR_FULL = 2,           /* no room in entries or pool */
    CO_OD_ERR_DUPLICATE = 3,
    CO_OD_ERR_TYPE = 4,           /* unknown type, or size does not fit the type */
    CO_OD_ERR_DEFAULT = 5,        /* default longer than size, or outside the limits */
    CO_OD_ERR_LIMITS = 6,         /* min > max */
    CO_OD_ERR_SEALED = 7,
    CO_OD_ERR_IMAGE = 8,          /* in the image: not fixed-size, past its end, overlapping */
    CO_OD_ERR_NOT_SEALED = 9,     /* co_od_add_live before co_od_seal */
    CO_OD_ERR_TOO_LARGE = 10,     /* live: larger than every entry at seal (the servers'
                                     transfer scratch was sized for those) */
    CO_OD_ERR_COMMUNICATION = 11, /* live: 0x1000..0x1FFF, the services read those at reset */
    CO_OD_ERR_STRUCTURE = 12      /* live: a sub-index > 0 whose index has no UNSIGNED8 sub 0
                                     of an ARRAY/RECORD, or an ARRAY/RECORD sub 0 not UNSIGNED8 */
} co_od_add_result_t;
/* Adds may come in any order (ascending is cheapest: the table stays sorted,
 * out-of-order adds move the entries behind). A fixed-size entry without a
 * default (default_length 0) starts at 0. CO_OD_NODEID_RELATIVE: integer
 * types only; the node-id is added with carry in the entry's width; such
 * defaults are not checked against the limits (the node-id comes later).
 * The definition is checked before the mode filter, so a bad definition is
 * reported on both kinds of line. */
co_od_add_result_t co_od_add(co_od_t *od, const co_od_def_t *def);
/* Sort, check that every ARRAY/RECORD has sub 0 as UNSIGNED8 (its value is
 * the application's: a count or the highest sub-index), load defaults; no adds
 * after. An index is an ARRAY/RECORD when any of its entries says so. False
 * (still unsealed, refused_index set) when a check fails, or when the OD is
 * already sealed. */
bool co_od_seal(co_od_t *od, uint8_t node_id);
/* Add an entry to a sealed OD while the node runs, into the room left in the
 * entries table and the pool at init (size them with spare for growth; a
 * sealed OD keeps what its adds did not use). The entry is appended behind
 * the sorted table, so no entry moves: pointers held by transfers in progress
 * and PDO mapping positions stay valid; lookups search the sorted table, then
 * the live entries one by one. The value starts at the default. Refused, the
 * OD unchanged: a bad definition as co_od_add, CO_OD_ERR_NOT_SEALED, _FULL,
 * _DUPLICATE, _TOO_LARGE, _COMMUNICATION, _STRUCTURE (see the enum). Entries
 * cannot be removed: SDO/PDO holders would keep dangling keys. */
co_od_add_result_t co_od_add_live(co_od_t *od, const co_od_def_t *def);
/* co_od_add_live of defs[0..count), all or none: at the first refusal the
 * entries added by this call are taken back (nothing can hold them yet: the
 * caller keeps other users of the OD out meanwhile) and *refused = its
 * position. Entries of the other line mode are skipped. */
co_od_add_result_t co_od_add_live_all(co_od_t *od, const co_od_def_t *defs, uint32_t count,
                                      uint32_t *refused);
/* The process image (seed 004 §3): the first `size` bytes of the pool hold
 * the values of the entries added with co_od_add_in_image, so PDOs, SDO/USDO
 * and the host (co_api) work on the same bytes. Before any add; false when
 * too late or the pool is smaller. */
bool co_od_reserve_image(co_od_t *od, uint32_t size);
/* Add an entry whose value lives at image byte `offset` (little-endian as
 * every value): fixed-size types only, within the image, sharing no byte
 * with another image entry (else CO_OD_ERR_IMAGE). Its default is what a
 * reset loads there. */
co_od_add_result_t co_od_add_in_image(co_od_t *od, const co_od_def_t *def, uint32_t offset);
/* A sealed OD's node-id changes (LSS gave an unconfigured node one): what
 * $NODEID-relative defaults add from the next co_od_load_defaults on. */
void co_od_set_node_id(co_od_t *od, uint8_t node_id);
bool co_od_subscribe(co_od_t *od, uint16_t first_index, uint8_t first_sub, uint16_t last_index,
                     uint8_t last_sub, const co_od_handler_t *handler, void *user);
/* Remove every subscription of (handler, user); not while a transfer of the
 * OD waits on a split answer (the chain position would shift). */
void co_od_unsubscribe(co_od_t *od, const co_od_handler_t *handler, void *user);

/* ---- lookup and application access (no indications except after_write)
 * find/has_index work at any time (the table is kept sorted while adding);
 * get/put and network access need a sealed OD, else CO_ABORT_NO_OD. */
const co_od_entry_t *co_od_find(const co_od_t *od, uint16_t index, uint8_t sub);
/* True when the index exists at all (to tell "no object" from "no sub"). */
bool co_od_has_index(const co_od_t *od, uint16_t index);
static inline uint8_t *co_od_value(co_od_t *od, const co_od_entry_t *e) { return od->pool + e->value; }
/* The node-id $NODEID-relative defaults add (co_od_seal, co_od_set_node_id). */
static inline uint8_t co_od_node_id(const co_od_t *od) { return od->node_id; }
static inline uint32_t co_od_image_size(const co_od_t *od) { return od->image_size; }
static inline uint8_t *co_od_image(co_od_t *od) { return od->pool; }
/* True when the entry's value lives in the process image. */
static inline bool co_od_in_image(const co_od_t *od, const co_od_entry_t *e)
{
    return e->size > 0 && e->value < od->image_size;
}
/* Fixed size of a type in bytes, 0 for strings and domains. */
uint32_t co_od_type_size(uint8_t type);
/* Copy the value out: abort code or 0; *length = bytes (length may be NULL).
 * cap too small: CO_ABORT_OUT_OF_MEMORY with *length = the bytes needed.
 * Domains: CO_ABORT_UNSUPPORTED_ACCESS (their data lives with the application). */
uint32_t co_od_get(const co_od_t *od, uint16_t index, uint8_t sub, uint8_t *buf, uint32_t cap,
                   uint32_t *length);
/* Application write: type and length checked (limits too), after_write
 * handlers told with CO_ORIGIN_LOCAL. Access rights are not checked (the
 * application may change ro/const entries); no check_write runs. */
uint32_t co_od_put(co_od_t *od, uint16_t index, uint8_t sub, const uint8_t *data, uint32_t length);
bool co_od_get_u8(const co_od_t *od, uint16_t index, uint8_t sub, uint8_t *out);
bool co_od_get_u16(const co_od_t *od, uint16_t index, uint8_t sub, uint16_t *out);
bool co_od_get_u32(const co_od_t *od, uint16_t index, uint8_t sub, uint32_t *out);
/* Check a value against type, length and limits, as a network write would:
 * fixed-size types: longer = LENGTH_HIGH, shorter = LENGTH_LOW; strings
 * longer than the size = LENGTH_HIGH; UNICODE_STRING of odd length =
 * TYPE_MISMATCH; BOOLEAN other than 0/1 = INVALID_VALUE; limits: VALUE_LOW /
 * VALUE_HIGH, NaN = INVALID_VALUE. Domains: 0. */
uint32_t co_od_check_value(const co_od_t *od, const co_od_entry_t *e, const uint8_t *data,
                           uint32_t length);
/* Load defaults of the groups in group_mask (CO_GROUP_*): every entry of the
 * group, CO_OD_STORE or not. All values are loaded first, then after_write
 * is told with CO_ORIGIN_RESTORE once per entry that changed. Indices below
 * 0x1000 belong to no group. */
void co_od_load_defaults(co_od_t *od, uint8_t group_mask);
/* The same for the entries pick() chooses (declared parameter groups). */
typedef bool (*co_od_pick_fn)(const co_od_entry_t *e, void *user);
void co_od_load_defaults_if(co_od_t *od, co_od_pick_fn pick, void *user);
uint8_t co_od_group_of(uint16_t index);

/* ---- network access (SDO/USDO servers)
 * A begin on a transfer still in progress aborts it first (CO_ABORT_GENERAL,
 * a domain writer is told). scratch must hold the entry's size, else
 * CO_ABORT_OUT_OF_MEMORY. Domain callbacks come from the first subscription
 * covering the entry that has them: no domain_read = CO_ABORT_NO_DATA, no
 * domain_size = size unknown, no domain_write = CO_ABORT_UNSUPPORTED_ACCESS.
 * Domains have no check_write pass; after_write runs when a download ends.
 * A handler that split answers through co_od_resume() after it returned. */
void co_od_xfer_init(co_od_xfer_t *xfer, uint8_t *scratch, uint32_t scratch_size);
/* Upload: abort code, 0, or CO_OD_SPLIT (then wait for co_od_resume). On
 * success xfer->total is the size to upload (CO_OD_SIZE_UNKNOWN for a domain
 * that does not know). The value is copied into scratch once every
 * before_read agreed, so the upload is one consistent snapshot. */
uint32_t co_od_read_begin(co_od_t *od, co_od_xfer_t *xfer, uint16_t index, uint8_t sub);
/* Next chunk: up to cap bytes into buf; *n bytes given, *last at the end. */
uint32_t co_od_read_chunk(co_od_xfer_t *xfer, uint8_t *buf, uint32_t cap, uint32_t *n, bool *last);
/* Download: total = announced size or CO_OD_SIZE_UNKNOWN. Checks the entry
 * exists, is writable and the size can fit: announced longer than the entry
 * = LENGTH_HIGH, a fixed-size type announced shorter = LENGTH_LOW. A chunk
 * beyond the size (or the announced total) = LENGTH_HIGH. */
uint32_t co_od_write_begin(co_od_t *od, co_od_xfer_t *xfer, uint16_t index, uint8_t sub,
                           uint32_t total);
uint32_t co_od_write_chunk(co_od_xfer_t *xfer, const uint8_t *data, uint32_t n);
/* All data given: length, limits, test-then-execute. 0, abort, or CO_OD_SPLIT. */
uint32_t co_od_write_end(co_od_xfer_t *xfer);
/* The application's answer to a split: abort = 0 to go on. Returns what
 * the begin/end call would have returned (and may split again). abort =
 * CO_OD_SPLIT leaves it waiting; CO_ABORT_GENERAL when nothing waits. */
uint32_t co_od_resume(co_od_xfer_t *xfer, uint32_t abort);
/* Give up (timeout, abort from the peer): a domain writer is told (abort 0
 * is reported as CO_ABORT_GENERAL). Nothing happens on an idle transfer.
 * Transfers that fail on their own (length, limits, a handler's abort) end
 * in CO_XFER_DONE with xfer->abort set; a domain writer is told of those
 * too, except when it refused the data itself. */
void co_od_xfer_abort(co_od_xfer_t *xfer, uint32_t abort);

/* CiA 301 COB-ID rule for services' check_write: the CAN-ID bits may change
 * only while the entry is invalid (bit 31 set) in the old or new value. */
uint32_t co_od_check_cob_id_change(uint32_t old_value, uint32_t new_value);

#endif
