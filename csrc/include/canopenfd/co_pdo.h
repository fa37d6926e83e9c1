/* PDO service (CiA 301 / CiA 1301): up to 512 RPDOs and 512 TPDOs taken
 * from a sealed object dictionary, their data in the OD's value pool.
 *
 *   RPDO n (1..512): communication 0x1400 + n - 1, mapping 0x1600 + n - 1
 *   TPDO n (1..512): communication 0x1800 + n - 1, mapping 0x1A00 + n - 1
 *
 * A PDO exists when its communication object has sub 1 (COB-ID); it has as
 * many mapping slots as its mapping object has sub-entries (at most 64).
 * It works (is "active") while its COB-ID has bit 31 clear, its mapping
 * compiles with at least one entry and its transmission type suits it;
 * data flow only while the node is operational (co_pdo_set_operational).
 *
 * Configuration follows the OD at once: a handler on 0x1400..0x1BFF checks
 * network writes (CiA 301 abort codes, see docs/protocol-notes.md "PDO")
 * and re-reads the PDO after every write. Values loaded by a reset (origin
 * RESTORE) are not re-read one by one: call co_pdo_reload after loading.
 *
 * Transmission types: 0 (sent at the next SYNC after a trigger), 1..240
 * (every n-th SYNC, SYNC start value sub 6), 252 (classic: sampled at SYNC,
 * sent on RTR), 253 (classic: sampled and sent on RTR), 254/255 (events:
 * trigger, trigger by mapped object, event timer sub 5; inhibit time sub 3).
 * RPDOs 0..240 are applied at the next SYNC, 254/255 at once; sub 5 of an
 * RPDO is its reception deadline.
 *
 * A mapping sub 0 of 0xFE (SAM) or 0xFF (DAM) makes the PDO a multiplexed
 * PDO (MPDO, CiA 301): it has no compiled mapping, needs type 254/255, its
 * received frames go to the MPDO service (co_pdo_set_mpdo_rx, co_mpdo.h)
 * and it sends only what that service hands to co_pdo_send_mpdo.
 *
 * Reception goes through co_line_subscribe_other (COB-IDs are configurable):
 * an 11-bit id finds its RPDO in a 2048-entry table, a 29-bit id by a
 * bounded search of the RPDOs with 29-bit COB-IDs. Nothing allocates; all
 * storage is the caller's, sized by co_pdo_need. */
#ifndef CO_PDO_H
#define CO_PDO_H

#include "canopenfd/co_line.h"
#include "canopenfd/co_od.h"
#include "canopenfd/co_pdo_map.h"

enum {
    CO_PDO_MAX_NUMBER = 512,        /* RPDOs and TPDOs each */
    CO_PDO_SCAN_MAX = 8,            /* channels up to which a scan beats the CAN-ID tables */
    CO_PDO_RPDO_COMM = 0x1400,
    CO_PDO_RPDO_MAP = 0x1600,
    CO_PDO_TPDO_COMM = 0x1800,
    CO_PDO_TPDO_MAP = 0x1A00,
    CO_PDO_MAP_SAM = 0xFE,          /* mapping sub 0: source address mode MPDO */
    CO_PDO_MAP_DAM = 0xFF           /* mapping sub 0: destination address mode MPDO */
};

/* EMCY error codes handed to the error callback (CiA 301). */
enum {
    CO_PDO_EMCY_RECEIVED_AGAIN = 0x0000,   /* an RPDO that missed its deadline arrived */
    CO_PDO_EMCY_LENGTH = 0x8210,           /* RPDO shorter than its mapping: ignored */
    CO_PDO_EMCY_LENGTH_EXCEEDED = 0x8220,  /* RPDO longer than allowed: applied */
    CO_PDO_EMCY_RPDO_TIMEOUT = 0x8250      /* no RPDO within its event time */
};

/* Transmission types (sub 2). */
enum {
    CO_PDO_TYPE_SYNC_ACYCLIC = 0,
    CO_PDO_TYPE_SYNC_MAX = 240,
    CO_PDO_TYPE_RTR_SYNC = 252,
    CO_PDO_TYPE_RTR_EVENT = 253,
    CO_PDO_TYPE_EVENT_MANUFACTURER = 254,
    CO_PDO_TYPE_EVENT_PROFILE = 255
};

/* cffi:begin */
typedef struct co_pdo_stats {
    uint32_t tx_frames;             /* TPDOs queued for sending */
    uint32_t tx_failed;             /* the line refused a TPDO (tx queue full) */
    uint32_t tx_inhibited;          /* events held back until the inhibit time ended */
    uint32_t sync_window_drops;     /* synchronous TPDOs still unsent when the window closed */
    uint32_t rx_frames;             /* RPDOs applied (at once or at SYNC) */
    uint32_t rx_short;              /* RPDOs shorter than their mapping (ignored) */
    uint32_t rx_long;               /* RPDOs longer than allowed (applied) */
    uint32_t rx_not_ours;           /* frames offered whose id is no active RPDO */
    uint32_t rx_not_operational;    /* RPDO / RTR frames while not operational */
    uint32_t rx_timeouts;           /* RPDO deadlines missed */
    uint32_t rtr_answered;
    uint32_t rtr_refused;           /* RTR on a type 252 TPDO before its first SYNC sample;
                                       an RTR no TPDO allows (bit 30 set) is the line's
                                       rx_rtr */
    uint32_t config_invalid;        /* a valid COB-ID whose PDO cannot work (mapping, type, id) */
    uint32_t id_conflicts;          /* an RPDO COB-ID another RPDO or service already takes */
} co_pdo_stats_t;
/* cffi:end */

struct co_pdo;

typedef struct co_pdo_channel {
    struct co_pdo *owner;
    co_pdo_map_item_t *map;         /* slice of the caller's items */
    uint8_t map_capacity;           /* mapping sub-entries in the OD */
    uint8_t map_count;              /* compiled items */
    uint16_t bits;                  /* mapped length in bits */
    uint16_t number;                /* 1..512 */
    bool is_rpdo;
    bool active;
    bool ext;                       /* 29-bit CAN-ID */
    bool rtr_allowed;               /* TPDO, classic, COB-ID bit 30 clear */
    bool takes_id;                  /* RPDO: receives on can_id (11-bit); TPDO: answers RTRs
                                       on it (the CAN-ID tables or the scan see it) */
    uint8_t type;
    uint8_t mpdo;                   /* CO_PDO_MAP_SAM / _DAM, 0 = a plain PDO */
    uint32_t can_id;
    uint16_t inhibit_100us;
    uint16_t event_ms;
    uint8_t sync_start;
    /* runtime */
    uint8_t sync_count;             /* SYNCs still to go (1..240); 0 = not counting yet */
    bool wait_start;                /* waiting for the SYNC start value */
    bool event_pending;             /* TPDO: an event waits (inhibit time, or SYNC for type 0) */
    bool sync_due;                  /* TPDO: sampled at SYNC, not queued yet */
    bool has_data;                  /* TPDO: buf holds data for an RTR */
    bool rx_pending;                /* RPDO: buf holds a frame for the next SYNC */
    bool monitoring;                /* RPDO: deadline armed (from the first reception) */
    bool timed_out;                 /* RPDO: deadline missed, not received since (0x8250) */
    bool sampling;                  /* TPDO: inside before_send */
    uint16_t rx_error;              /* RPDO: length error in force (0x8210/0x8220, 0 = none) */
    uint8_t len;                    /* bytes in buf */
    uint64_t inhibit_end_us;
    co_timer_t timer;               /* TPDO event timer / RPDO deadline */
    co_timer_t inhibit_timer;
    uint8_t buf[CO_PDO_FD_BYTES];
} co_pdo_channel_t;

typedef struct co_pdo co_pdo_t;

/* A second listener of applied RPDOs, beside the node's indications: the
 * gateway forwards what an RPDO wrote (co_pdo_set_rx_tap). */
typedef void (*co_pdo_rx_tap_fn)(co_pdo_t *pdo, uint16_t rpdo_number, void *user);
/* The receiver of an active MPDO RPDO's frames (kind: CO_PDO_MAP_SAM/_DAM),
 * told only while operational; it checks the frame itself. */
typedef void (*co_pdo_mpdo_rx_fn)(co_pdo_t *pdo, uint16_t rpdo_number, uint8_t kind,
                                  const co_frame_t *f, void *user);

/* Why an RPDO's reception error began or ended (rx_error_changed). */
typedef enum co_pdo_rx_cause {
    CO_PDO_RX_FRAME,            /* a frame's length, or a frame after a missed deadline */
    CO_PDO_RX_DEADLINE,         /* no frame within the event time (sub 5) */
    CO_PDO_RX_RECONFIGURED      /* its parameters were written or reloaded */
} co_pdo_rx_cause_t;

/* Callbacks to the integration; each may be NULL. pdo_number is 1..512. */
typedef struct co_pdo_indications {
    /* emcy_code: CO_PDO_EMCY_* (a length error is reported once until it
     * ends; RECEIVED_AGAIN: a frame ended a timeout; rx_error_changed tells
     * every start and end). */
    void (*error)(co_pdo_t *pdo, uint16_t emcy_code, bool is_rpdo, uint16_t pdo_number,
                  void *user);
    /* An RPDO's data were written into the OD (origin "pdo"). */
    void (*received)(co_pdo_t *pdo, uint16_t pdo_number, void *user);
    /* A TPDO is about to be sampled: refresh its mapped values now
     * (co_pdo_trigger of this TPDO is refused from inside). */
    void (*before_send)(co_pdo_t *pdo, uint16_t pdo_number, void *user);
    /* RPDO n's error emcy_code (LENGTH or LENGTH_EXCEEDED: at most one of
     * them, and RPDO_TIMEOUT) began (active) or ended, told once per edge
     * after the change took effect. Frames end what frames started; a
     * write to its parameters ends what no longer applies: everything when
     * it stops working (COB-ID invalid, as the CiA 301 mapping procedure
     * starts) or takes another CAN-ID, a length error when its mapped
     * length changes, a timeout when its deadline is switched off;
     * co_pdo_reload ends all. Leaving operational ends nothing (a frame
     * after re-entering does). */
    void (*rx_error_changed)(co_pdo_t *pdo, uint16_t rpdo_number, uint16_t emcy_code,
                             bool active, co_pdo_rx_cause_t cause, void *user);
} co_pdo_indications_t;

typedef struct co_pdo_config {
    co_pdo_channel_t *channels;     /* co_pdo_need's channel count */
    uint32_t channel_count;
    co_pdo_map_item_t *items;       /* co_pdo_need's item count */
    uint32_t item_count;
    /* Optional CAN-ID tables, CO_LINE_ID_MAP_SIZE entries each (zeroed here):
     * a received frame finds its RPDO, a remote frame its TPDO, in one step.
     * NULL: the channels are scanned, which costs little for a few PDOs and
     * saves 8 KB (co_stack gives tables above CO_PDO_SCAN_MAX channels). */
    uint16_t *rx_map;
    uint16_t *rtr_map;
    const co_pdo_indications_t *ind;
    void *user;
} co_pdo_config_t;

struct co_pdo {
    co_line_t *line;
    co_od_t *od;
    const co_pdo_indications_t *ind;
    void *user;
    co_pdo_channel_t *channels;
    uint16_t channel_count;
    bool operational;
    bool hooked;
    uint16_t ext_rpdos;             /* active RPDOs with a 29-bit COB-ID */
    uint16_t rpdo_count;            /* channels [0, rpdo_count) are RPDOs, then TPDOs, each
                                       by ascending number (a number finds its channel by
                                       binary search) */
    uint16_t *rx_map;               /* 11-bit CAN-ID -> active RPDO channel + 1, or NULL */
    uint16_t *rtr_map;              /* 11-bit CAN-ID -> TPDO answering RTR + 1, or NULL */
    co_timer_t retry_timer;         /* sends synchronous TPDOs the tx queue refused */
    co_pdo_rx_tap_fn rx_tap;        /* told after `received` (NULL: none) */
    void *rx_tap_user;
    co_pdo_mpdo_rx_fn mpdo_rx;      /* MPDO RPDO frames (NULL: counted in rx_not_ours) */
    void *mpdo_rx_user;
    co_pdo_stats_t stats;
};

/* Storage a sealed OD needs: PDOs (communication objects with sub 1) and
 * mapping slots (sub-entries 1..64 of their mapping objects). False when
 * the OD is not sealed. */
bool co_pdo_need(const co_od_t *od, uint32_t *channel_count, uint32_t *item_count);
/* Reads every PDO from the OD (as co_pdo_reload), hooks the OD's write path
 * and the line's "other" receivers. Not operational yet. False when the OD
 * is not sealed, its mode differs from the line's, storage is too small, or
 * a hook is refused (nothing stays hooked then). */
bool co_pdo_init(co_pdo_t *pdo, co_line_t *line, co_od_t *od, const co_pdo_config_t *config);
void co_pdo_deinit(co_pdo_t *pdo);
/* Re-read every PDO's communication and mapping parameters (after a reset
 * loaded them); running timers and buffered data start over, reception
 * errors end (told). */
void co_pdo_reload(co_pdo_t *pdo);
/* NMT operational or not: leaving stops every timer and drops buffered
 * data (reception errors stay); entering starts the TPDO event timers. */
void co_pdo_set_operational(co_pdo_t *pdo, bool operational);
/* A SYNC was received (or produced); counter = its counter value, 0 when
 * the SYNC carries none. Applies buffered synchronous RPDOs, then samples
 * and sends the synchronous TPDOs that are due. */
void co_pdo_sync(co_pdo_t *pdo, uint8_t counter);
/* The synchronous window (0x1007) closed: synchronous TPDOs not sent yet
 * are dropped (counted in sync_window_drops). */
void co_pdo_sync_window_closed(co_pdo_t *pdo);
/* Application event for TPDO n: types 254/255 send now (or when the
 * inhibit time ends), type 0 at the next SYNC. False when the TPDO does not
 * exist, is not active, not operational, or its type takes no events. */
bool co_pdo_trigger(co_pdo_t *pdo, uint16_t tpdo_number);
/* The mapped object index:sub changed: triggers every active TPDO of type
 * 0, 254 or 255 that maps it. Returns how many were triggered. */
uint32_t co_pdo_trigger_object(co_pdo_t *pdo, uint16_t index, uint8_t sub);
/* Chooses OD entries (co_pdo_trigger_mapped, co_pdo_each_mapped). */
typedef bool (*co_pdo_pick_fn)(const co_od_entry_t *e, void *user);
/* Several mapped objects changed at once: triggers every active TPDO of
 * type 0, 254 or 255 that maps at least one entry pick() chooses, once
 * each. Returns how many were triggered (0 when not operational). */
uint32_t co_pdo_trigger_mapped(co_pdo_t *pdo, co_pdo_pick_fn pick, void *user);
/* fn(entry) for every object PDO `number` maps (dummies left out; its
 * return value is not used); nothing when the PDO does not exist. */
void co_pdo_each_mapped(const co_pdo_t *pdo, bool is_rpdo, uint16_t number,
                        co_pdo_pick_fn fn, void *user);
/* Active = configured and usable (independent of the NMT state). */
bool co_pdo_is_active(const co_pdo_t *pdo, bool is_rpdo, uint16_t number);
/* The mapped values of a PDO as the OD holds them now, laid out as its
 * mapping says (data: CO_FRAME_MAX_DATA bytes, zeroed past the mapping);
 * *len = the mapped bytes. False when the PDO does not exist. */
bool co_pdo_pack_values(const co_pdo_t *pdo, bool is_rpdo, uint16_t number, uint8_t *data,
                        uint8_t *len);
/* The channel of PDO `number` (its compiled mapping, type, state), or NULL. */
const co_pdo_channel_t *co_pdo_channel(const co_pdo_t *pdo, bool is_rpdo, uint16_t number);
/* Set (fn NULL: clear) the one rx tap: told after every applied RPDO, after
 * the node's `received` indication. Survives co_pdo_reload, not deinit. */
void co_pdo_set_rx_tap(co_pdo_t *pdo, co_pdo_rx_tap_fn fn, void *user);
/* Set (fn NULL: clear) the receiver of MPDO RPDO frames (the MPDO service). */
void co_pdo_set_mpdo_rx(co_pdo_t *pdo, co_pdo_mpdo_rx_fn fn, void *user);
/* Send an MPDO frame (len bytes of data) on TPDO n's COB-ID. False when it
 * is no active MPDO TPDO, the node is not operational, its inhibit time
 * (sub 3) has not ended since the last one (tx_inhibited) or the line
 * refused it (tx_failed). */
bool co_pdo_send_mpdo(co_pdo_t *pdo, uint16_t tpdo_number, const uint8_t *data, uint8_t len);
static inline const co_pdo_stats_t *co_pdo_stats(const co_pdo_t *pdo) { return &pdo->stats; }

#endif
