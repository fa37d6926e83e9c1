/* Multiplexed PDOs (MPDO, CiA 301) over the PDO service.
 *
 * An MPDO is a PDO whose mapping sub 0 is 0xFE (SAM: source address mode)
 * or 0xFF (DAM: destination address mode); co_pdo keeps its COB-ID, type,
 * inhibit time and NMT gating, this service its frames. One frame of 8
 * bytes on classic and fd lines (fd: the same layout, see
 * docs/protocol-notes.md "MPDO"):
 *
 *   byte 0   bit 7 = 1 (DAM): bits 6..0 = destination node-id, 0 = all
 *            bit 7 = 0 (SAM): bits 6..0 = producer node-id
 *   1..2     index (little-endian)   3  sub-index
 *   4..7     value (objects of 1..4 bytes, zero padded)
 *
 * DAM producer: co_mpdo_send_dam writes index:sub of node N (or all).
 * DAM consumer: the value is written into the own OD as an SDO download
 * would (access, type, limits, handlers), for an RPDO-mappable object of at
 * most 4 bytes; refused: nothing written, counted, `refused` told and the
 * EMCY 0x8230 reported through `error`.
 * SAM producer: co_mpdo_send_sam sends a local object the object scanner
 * list (0x1FA0..0x1FCF) names. SAM consumer: the object dispatcher list
 * (0x1FD0..0x1FFF) gives the local object for (producer, index, sub);
 * nothing listed: ignored, counted, `refused` told (no EMCY).
 *
 * No allocation, no global state; a received frame costs a bounded search
 * of the lists (at most 48 objects of 254 entries each). */
#ifndef CO_MPDO_H
#define CO_MPDO_H

#include "canopenfd/co_pdo.h"

enum {
    CO_MPDO_LEN = 8,                /* every MPDO frame, classic and fd */
    CO_MPDO_DATA_MAX = 4,           /* value bytes */
    CO_MPDO_ALL_NODES = 0,          /* DAM destination: every consumer */
    CO_MPDO_EMCY_DAM = 0x8230,      /* DAM MPDO not processed: destination object not available */
    CO_MPDO_SCANNER_FIRST = 0x1FA0,
    CO_MPDO_SCANNER_LAST = 0x1FCF,
    CO_MPDO_DISPATCHER_FIRST = 0x1FD0,
    CO_MPDO_DISPATCHER_LAST = 0x1FFF
};

/* One decoded MPDO frame. */
typedef struct co_mpdo_msg {
    bool dam;
    uint8_t node;                   /* DAM: destination (0 = all); SAM: producer */
    uint16_t index;
    uint8_t sub;
    uint8_t data[CO_MPDO_DATA_MAX];
} co_mpdo_msg_t;

/* cffi:begin */
typedef struct co_mpdo_stats {
    uint32_t tx_frames;             /* MPDOs handed to the PDO service and sent */
    uint32_t tx_refused;            /* send calls refused (argument, channel, object, line) */
    uint32_t rx_applied;            /* values written into the OD */
    uint32_t rx_bad_length;         /* frames not 8 bytes long (ignored) */
    uint32_t rx_wrong_mode;         /* a SAM frame on a DAM consumer or the reverse (ignored) */
    uint32_t rx_other_node;         /* DAM frames for another node (ignored) */
    uint32_t rx_not_dispatched;     /* SAM frames the dispatcher list does not name */
    uint32_t rx_refused;            /* the target object missing or refusing the value */
} co_mpdo_stats_t;
/* cffi:end */

typedef enum co_mpdo_status {
    CO_MPDO_OK = 0,
    CO_MPDO_ERR_ARGUMENT,           /* node-id > 127, more than 4 bytes, NULL data */
    CO_MPDO_ERR_CHANNEL,            /* no active MPDO TPDO of that mode with that number */
    CO_MPDO_ERR_NOT_SCANNED,        /* SAM: the scanner list does not name the object */
    CO_MPDO_ERR_OBJECT,             /* SAM, mapped DAM: missing, unreadable or longer than
                                       4 bytes (mapped DAM: or not the mapped length) */
    CO_MPDO_ERR_NOT_SENT            /* not operational, inhibit time, or the tx queue full */
} co_mpdo_status_t;

typedef struct co_mpdo co_mpdo_t;

/* Callbacks to the integration; each may be NULL. rpdo_number is 1..512. */
typedef struct co_mpdo_indications {
    /* A value was written into local index:sub (origin CO_ORIGIN_NETWORK). */
    void (*received)(co_mpdo_t *mpdo, uint16_t rpdo_number, const co_mpdo_msg_t *msg,
                     uint16_t index, uint8_t sub, void *user);
    /* A frame addressed to this node was not applied to local index:sub (a
     * SAM frame's own index:sub when no list names it): abort = the CiA 301
     * abort code of the write (0x06020000 when a SAM frame is not listed). */
    void (*refused)(co_mpdo_t *mpdo, uint16_t rpdo_number, const co_mpdo_msg_t *msg,
                    uint16_t index, uint8_t sub, uint32_t abort, void *user);
    /* EMCY to report (CO_MPDO_EMCY_DAM, an event: no end is told). */
    void (*error)(co_mpdo_t *mpdo, uint16_t emcy_code, uint16_t rpdo_number, void *user);
} co_mpdo_indications_t;

struct co_mpdo {
    co_pdo_t *pdo;
    const co_mpdo_indications_t *ind;
    void *user;
    co_od_xfer_t xfer;              /* one write or read at a time, never split */
    uint8_t scratch[8];
    co_mpdo_stats_t stats;
};

/* Frame codec: 8 bytes exactly (false otherwise; nothing read past len). */
bool co_mpdo_decode(const uint8_t *data, uint8_t len, co_mpdo_msg_t *msg);
void co_mpdo_encode(const co_mpdo_msg_t *msg, uint8_t out[CO_MPDO_LEN]);

/* Scanner list entry (UNSIGNED32): bits 0..7 sub, 8..23 index, 24..31 block
 * of consecutive subs (0 counts as 1). True when one names index:sub. */
bool co_mpdo_scanner_lists(const co_od_t *od, uint16_t index, uint8_t sub);
/* Dispatcher list entry (UNSIGNED64): bits 0..7 producer node-id, 8..15
 * producer sub, 16..31 producer index, 32..39 local sub, 40..55 local
 * index, 56..63 block of consecutive subs (0 counts as 1). True with the
 * local object when one names the producer's index:sub. */
bool co_mpdo_dispatch(const co_od_t *od, uint8_t producer, uint16_t index, uint8_t sub,
                      uint16_t *local_index, uint8_t *local_sub);

/* Takes the PDO service's MPDO frames (co_pdo_set_mpdo_rx). */
void co_mpdo_init(co_mpdo_t *mpdo, co_pdo_t *pdo, const co_mpdo_indications_t *ind, void *user);
void co_mpdo_deinit(co_mpdo_t *mpdo);
/* DAM: write data (1..4 bytes) into index:sub of node (0 = all) through
 * DAM TPDO tpdo_number. */
co_mpdo_status_t co_mpdo_send_dam(co_mpdo_t *mpdo, uint16_t tpdo_number, uint8_t node,
                                  uint16_t index, uint8_t sub, const uint8_t *data, uint8_t len);
/* DAM, the CiA 301 way: send the local object the TPDO's mapping sub 1
 * names (index << 16 | sub << 8 | length in bits, 8..32), read as an SDO
 * upload would, to the same index:sub of node (0 = all). */
co_mpdo_status_t co_mpdo_send_dam_mapped(co_mpdo_t *mpdo, uint16_t tpdo_number, uint8_t node);
/* SAM: send the local object index:sub (listed in the scanner list, at
 * most 4 bytes, read as an SDO upload would) through SAM TPDO tpdo_number. */
co_mpdo_status_t co_mpdo_send_sam(co_mpdo_t *mpdo, uint16_t tpdo_number, uint16_t index,
                                  uint8_t sub);
static inline const co_mpdo_stats_t *co_mpdo_stats(const co_mpdo_t *mpdo) { return &mpdo->stats; }

#endif
