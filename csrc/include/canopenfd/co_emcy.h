/* EMCY service: the producer of the local node (0x1014 COB-ID, 0x1015
 * inhibit time, 0x1001 error register, 0x1003 pre-defined error field, FD:
 * 0x1031 active error history and 0x1032 active error list) and the
 * consumer of other nodes' EMCYs (0x1028 or by node-id). Classic lines speak
 * the 8-byte CiA 301 EMCY, fd lines the extended CANopen FD EMCY (wire
 * format in co_emcy_codec.h).
 *
 * Producer: the application raises and clears errors; an active-error
 * table (caller storage) keeps what is active, so the error register is
 * always derived from it and a repeated raise does not flood the bus.
 * EMCYs go out only in NMT pre-operational and operational; what cannot go
 * out at once (inhibit time, another NMT state) waits in a bounded queue
 * (caller storage) and leaves in order. Everything works without an object
 * dictionary (parameters through the API); with one bound, the OD entries
 * are the parameters and network writes take effect at once.
 *
 * Choices on unconfirmed points are in docs/protocol-notes.md ("EMCY"). */
#ifndef CO_EMCY_H
#define CO_EMCY_H

#include "canopenfd/co_emcy_codec.h"
#include "canopenfd/co_line.h"
#include "canopenfd/co_nmt.h"
#include "canopenfd/co_od.h"

/* cffi:begin */
/* Statistics of a producer or a consumer (each has its own). */
typedef struct co_emcy_stats {
    /* producer */
    uint32_t sent;            /* EMCYs handed to the line */
    uint32_t queued;          /* EMCYs that had to wait (inhibit time, NMT state) */
    uint32_t dropped;         /* the wait queue was full: EMCY lost */
    uint32_t suppressed;      /* not sent because 0x1014 is invalid (bit 31) */
    uint32_t tx_failed;       /* the line refused the frame (tx queue full) */
    uint32_t repeated;        /* raises of an error already active */
    uint32_t table_full;      /* raises refused: the active-error table is full */
    /* consumer */
    uint32_t received;        /* EMCYs decoded and delivered */
    uint32_t rx_bad_length;   /* frame on a consumed CAN-ID of a wrong length: ignored */
} co_emcy_stats_t;

typedef enum co_emcy_result {
    CO_EMCY_OK = 0,           /* new error: EMCY sent or waiting (see the statistics) */
    CO_EMCY_REPEATED = 1,     /* already active: classic sends nothing, FD sends it
                                 again with "occurred more than once" */
    CO_EMCY_NOT_ACTIVE = 2,   /* clear of an error that is not active: nothing sent */
    CO_EMCY_TABLE_FULL = 3,   /* the active-error table is full: refused, nothing sent */
    CO_EMCY_BAD_ARGUMENT = 4  /* code 0, priority > 7, time stamp > 48 bits, NULL */
} co_emcy_result_t;
/* cffi:end */

#define CO_EMCY_COB_ID_INVALID 0x80000000u   /* 0x1014 / 0x1028 bit 31 */
#define CO_EMCY_COB_ID_FRAME 0x20000000u     /* bit 29: 29-bit CAN-ID */
enum { CO_EMCY_MAX_NODES = 128 };            /* consumer table, indexed by node-id */

/* An error as the application raises (or clears) it. */
typedef struct co_emcy_error {
    uint16_t code;            /* EEC, not 0 */
    uint8_t msef[5];          /* manufacturer-specific error field */
    uint8_t register_bits;    /* 0x1001 bits to set besides the code's own class bit
                                 (e.g. CO_EMCY_ER_DEVICE_PROFILE); bit 0 is always set */
    /* FD only (ignored on classic lines): */
    uint8_t logical_device;
    uint16_t spec_number;     /* CiA specification defining the code (301 = 0x012D) */
    uint8_t priority;         /* 0 (highest) .. 7 */
    bool non_recoverable;     /* error class */
    uint64_t time_stamp;      /* up to CO_EMCY_TIME_MAX, 0 = not supported */
    /* Whose error it is: 0 the application's (and the node's own); a stack
     * service raising one error per object of its own gives each its key
     * (an SRDO: CO_EMCY_SOURCE_SRDO + n), so equal codes stay apart. */
    uint16_t source;
} co_emcy_error_t;

/* The source key of SRDO n's error: its 0x1301 + n - 1 communication object. */
enum { CO_EMCY_SOURCE_SRDO = 0x1300 };

/* One active error. Kept oldest first. */
typedef struct co_emcy_active {
    co_emcy_msg_t msg;        /* the last EMCY sent for it (error_register not kept) */
    uint8_t register_bits;    /* its 0x1001 bits besides generic */
    uint16_t source;          /* co_emcy_error_t.source: who raised it */
} co_emcy_active_t;

/* ---------------------------------------------------------------- producer */

typedef struct co_emcy_config {
    co_emcy_msg_t *queue;            /* EMCYs waiting to be sent (>= 1) */
    uint16_t queue_capacity;
    co_emcy_active_t *active;        /* active-error table (>= 1) */
    uint16_t active_capacity;
    uint32_t *history;               /* 0x1003 entries, newest first; may be NULL */
    uint8_t history_capacity;        /* 0..254 */
} co_emcy_config_t;

typedef struct co_emcy {
    co_line_t *line;
    co_od_t *od;                     /* bound OD or NULL */
    uint8_t node_id;
    uint32_t cob_id;                 /* 0x1014 */
    uint16_t inhibit_100us;          /* 0x1015 */
    bool may_send;                   /* NMT pre-operational or operational */
    bool has_sent;
    uint64_t last_sent_us;
    co_timer_t timer;                /* end of the inhibit time */
    co_emcy_msg_t *queue;
    uint16_t queue_capacity;
    uint16_t queue_head;
    uint16_t queue_count;
    co_emcy_active_t *active;
    uint16_t active_capacity;
    uint16_t active_count;
    uint32_t *history;
    uint8_t history_capacity;        /* storage */
    uint8_t history_limit;           /* entries kept: storage, and the subs 0x1003 has */
    uint8_t history_count;
    uint8_t error_register;          /* 0x1001 */
    uint8_t extra_register;          /* 0x1001 bits another error source holds (co_errors) */
    bool overflow;                   /* an EMCY was dropped since the last take */
    co_emcy_stats_t stats;
} co_emcy_t;

/* The line's mode chooses the format. Starts with COB-ID 0x80 + node_id,
 * no inhibit time, sending not allowed (NMT initialising) until
 * co_emcy_set_nmt_state. False for a bad configuration (node-id outside
 * 1..127, no queue or active storage, history_capacity > 254). */
bool co_emcy_init(co_emcy_t *e, co_line_t *line, uint8_t node_id, const co_emcy_config_t *cfg);
/* Stops the timer; the queue is discarded. Detaches a bound OD. */
void co_emcy_deinit(co_emcy_t *e);

/* Bind a sealed OD: 0x1014, 0x1015 are read (entries missing keep the API
 * values), 0x1001, 0x1003, 0x1031, 0x1032 are kept up to date from the
 * producer's state (the producer owns their values; it writes them in
 * place, no after-write indications), handlers make network writes take
 * effect at once: 0x1014 (re-targets), 0x1015 (re-times a waiting EMCY),
 * 0x1003:00 (0 clears the history, any other value 0x06090030). The history
 * keeps as many entries as both the storage and 0x1003 (subs 1..n) hold.
 * A reset loading defaults into these entries gets the producer's values
 * back. False when the OD is not sealed or has no room for the
 * subscriptions (2). */
bool co_emcy_attach_od(co_emcy_t *e, co_od_t *od);
void co_emcy_detach_od(co_emcy_t *e);

/* The NMT state of the local node: EMCYs go out only in pre-operational and
 * operational. In other states raises and clears still change the active
 * table, the register and the history; their EMCYs wait in the queue and go
 * out (in order, inhibit time respected) on entering pre-operational or
 * operational. */
void co_emcy_set_nmt_state(co_emcy_t *e, co_nmt_state_t state);
/* The node got another node-id (LSS at a reset): the default COB-ID
 * 0x80 + node-id follows when the OD has no 0x1014 (with one, the reload of
 * its $NODEID default does). */
void co_emcy_set_node_id(co_emcy_t *e, uint8_t node_id);

/* Parameters without an OD (with one bound, they are written into 0x1014 /
 * 0x1015 and take effect through its handlers). An invalid COB-ID (bit 31)
 * discards waiting EMCYs (counted as suppressed). A new inhibit time counts
 * from the last EMCY sent. */
void co_emcy_set_cob_id(co_emcy_t *e, uint32_t cob_id);
void co_emcy_set_inhibit(co_emcy_t *e, uint16_t inhibit_100us);

/* Raise an error. New: added to the active table, the register and the
 * history, its EMCY sent (or queued). Already active (same code and source,
 * and on FD the same logical device): classic sends nothing; FD updates the entry
 * (msef, priority, class, time) and sends it again with "occurred more than
 * once" set. */
co_emcy_result_t co_emcy_raise(co_emcy_t *e, const co_emcy_error_t *err);
/* Clear an active error (code and source, and on FD logical device, name
 * it). Classic:
 * sends the "error reset" EMCY: EEC 0x0000, the error register after the
 * clear (0 once nothing is active), err->msef. FD: sends the error's own
 * EMCY with state "removed" (status bit 4 and 5 clear), err->msef and
 * err->time_stamp, the rest as raised. */
co_emcy_result_t co_emcy_clear(co_emcy_t *e, const co_emcy_error_t *err);
/* Clear every active error: classic sends one error reset (msef zero), FD
 * one "removed" EMCY per error. Returns the number cleared. */
uint16_t co_emcy_clear_all(co_emcy_t *e);

/* For an error source that keeps its own error state (co_errors): the
 * 0x1001 bits it holds, ORed with those of the active errors. */
void co_emcy_set_extra_register(co_emcy_t *e, uint8_t bits);
/* Send the EMCY of an error kept outside the active table: occurred = its
 * EMCY as co_emcy_raise builds it, and a 0x1003 entry; not occurred = the
 * removal as co_emcy_clear builds it (classic: error reset 0x0000 with
 * err->msef). The register is the current one. */
co_emcy_result_t co_emcy_signal(co_emcy_t *e, const co_emcy_error_t *err, bool occurred);

static inline uint8_t co_emcy_error_register(const co_emcy_t *e) { return e->error_register; }
static inline uint16_t co_emcy_active_count(const co_emcy_t *e) { return e->active_count; }
/* Whether the application's error (source 0) with this code is active. */
bool co_emcy_is_active(const co_emcy_t *e, uint16_t code, uint8_t logical_device);
/* True once after EMCYs were dropped (queue full); for the integration to
 * report (e.g. as a communication event). */
bool co_emcy_take_overflow(co_emcy_t *e);
/* 0x1032 entry value of an error (EmSA): EEC | msef[0] << 16 | msef[1] << 24;
 * also the 0x1003 entry value. */
uint32_t co_emcy_list_value(const co_emcy_msg_t *msg);

/* ---------------------------------------------------------------- consumer */

struct co_emcy_consumer;

/* Every EMCY received from a consumed node, every field decoded (FD-only
 * fields 0 on classic lines). */
typedef void (*co_emcy_rx_fn)(struct co_emcy_consumer *c, uint8_t node_id,
                              const co_emcy_msg_t *msg, void *user);

typedef struct co_emcy_consumer {
    co_line_t *line;
    co_od_t *od;
    co_emcy_rx_fn on_emcy;
    void *user;
    co_emcy_rx_fn tap;                    /* a second listener (the gateway), or NULL */
    void *tap_user;
    uint32_t cob_id[CO_EMCY_MAX_NODES];   /* per node-id; bit 31 = not consumed */
    uint32_t id_used[2048 / 32];          /* 11-bit CAN-IDs some entry uses (fast reject) */
    co_emcy_stats_t stats;
} co_emcy_consumer_t;

/* Registers with co_line_subscribe_other (ids are configurable); consumes
 * nothing until entries are set. False when the line has no room. */
bool co_emcy_consumer_init(co_emcy_consumer_t *c, co_line_t *line, co_emcy_rx_fn on_emcy,
                           void *user);
void co_emcy_consumer_deinit(co_emcy_consumer_t *c);
/* Set node node_id's entry as a write to 0x1028 sub node_id does: bit 31 =
 * not consumed, bit 29 = 29-bit CAN-ID, else bits 0..10. False for a
 * node-id outside 1..127. */
bool co_emcy_consumer_set_entry(co_emcy_consumer_t *c, uint8_t node_id, uint32_t cob_id);
/* Consume node_id's EMCY on its default CAN-ID 0x80 + node_id / stop. */
bool co_emcy_consumer_watch(co_emcy_consumer_t *c, uint8_t node_id);
void co_emcy_consumer_unwatch(co_emcy_consumer_t *c, uint8_t node_id);
uint32_t co_emcy_consumer_get_entry(const co_emcy_consumer_t *c, uint8_t node_id);
/* Bind a sealed OD: 0x1028 sub n (n = 1..127) configures node n; writes take
 * effect at once (a CAN-ID above 0x7FF without bit 29: 0x06090030). Nodes
 * the OD has no entry for keep their API entries. */
/* Set (fn NULL: clear) the one tap: told of every EMCY after on_emcy. */
void co_emcy_consumer_set_tap(co_emcy_consumer_t *c, co_emcy_rx_fn fn, void *user);
bool co_emcy_consumer_attach_od(co_emcy_consumer_t *c, co_od_t *od);
void co_emcy_consumer_detach_od(co_emcy_consumer_t *c);

#endif
