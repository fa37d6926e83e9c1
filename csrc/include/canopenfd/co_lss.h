/* LSS, layer setting services (CiA 305): the wire format and the LSS slave.
 *
 * The master sends on 0x7E5, slaves answer on 0x7E4; every frame carries 8
 * bytes, byte 0 is the command specifier. On fd lines the same 8 bytes go in
 * an FD frame (the line's format); frames of either format are accepted when
 * they carry exactly 8 bytes (choice and evidence: docs/protocol-notes.md,
 * "LSS (CiA 305)").
 *
 * The slave has an LSS address (0x1018:01..04: vendor-ID, product code,
 * revision number, serial number), two states (waiting, configuration) and
 * three node-ids: the active one (what the node uses now), the pending one
 * (set by "configure node-id", active after the next reset communication)
 * and the persistent one (what "store configuration" saved). 255 means
 * unconfigured. */
#ifndef CO_LSS_H
#define CO_LSS_H

#include "canopenfd/co_line.h"

/* cffi:begin */
enum {
    CO_LSS_ID_MASTER = 0x7E5,           /* master -> slaves */
    CO_LSS_ID_SLAVE = 0x7E4,            /* slaves -> master */
    CO_LSS_FRAME_LEN = 8,
    CO_LSS_NODE_ID_UNCONFIGURED = 0xFF
};

/* Command specifiers (byte 0). */
typedef enum co_lss_cs {
    CO_LSS_CS_SWITCH_GLOBAL = 0x04,
    CO_LSS_CS_CONFIGURE_NODE_ID = 0x11,
    CO_LSS_CS_CONFIGURE_BIT_TIMING = 0x13,
    CO_LSS_CS_ACTIVATE_BIT_TIMING = 0x15,
    CO_LSS_CS_STORE_CONFIGURATION = 0x17,
    CO_LSS_CS_SELECT_VENDOR = 0x40,
    CO_LSS_CS_SELECT_PRODUCT = 0x41,
    CO_LSS_CS_SELECT_REVISION = 0x42,
    CO_LSS_CS_SELECT_SERIAL = 0x43,
    CO_LSS_CS_SELECT_ANSWER = 0x44,          /* slave: selected, now in configuration */
    CO_LSS_CS_IDENTIFY_VENDOR = 0x46,
    CO_LSS_CS_IDENTIFY_PRODUCT = 0x47,
    CO_LSS_CS_IDENTIFY_REVISION_LOW = 0x48,
    CO_LSS_CS_IDENTIFY_REVISION_HIGH = 0x49,
    CO_LSS_CS_IDENTIFY_SERIAL_LOW = 0x4A,
    CO_LSS_CS_IDENTIFY_SERIAL_HIGH = 0x4B,
    CO_LSS_CS_IDENTIFY_NON_CONFIGURED = 0x4C,
    CO_LSS_CS_IDENTIFY_ANSWER = 0x4F,        /* slave: identify and fast scan answer */
    CO_LSS_CS_NON_CONFIGURED_ANSWER = 0x50,  /* slave: "I have no node-id" */
    CO_LSS_CS_FASTSCAN = 0x51,
    CO_LSS_CS_INQUIRE_VENDOR = 0x5A,
    CO_LSS_CS_INQUIRE_PRODUCT = 0x5B,
    CO_LSS_CS_INQUIRE_REVISION = 0x5C,
    CO_LSS_CS_INQUIRE_SERIAL = 0x5D,
    CO_LSS_CS_INQUIRE_NODE_ID = 0x5E
} co_lss_cs_t;

typedef enum co_lss_state {
    CO_LSS_STATE_WAITING = 0,
    CO_LSS_STATE_CONFIGURATION = 1
} co_lss_state_t;

/* Parts of the LSS address, also the fast scan's LSSSub / LSSNext values. */
typedef enum co_lss_part {
    CO_LSS_VENDOR = 0,
    CO_LSS_PRODUCT = 1,
    CO_LSS_REVISION = 2,
    CO_LSS_SERIAL = 3
} co_lss_part_t;

/* Error codes of the configure / store answers (byte 1). */
enum {
    CO_LSS_ERR_OK = 0,
    CO_LSS_ERR_NODE_ID_RANGE = 1,        /* configure node-id: not 1..127 or 255 */
    CO_LSS_ERR_BIT_TIMING = 1,           /* configure bit timing: not supported */
    CO_LSS_ERR_STORE_NOT_SUPPORTED = 1,
    CO_LSS_ERR_STORE_MEDIA = 2,          /* storage media access error */
    CO_LSS_ERR_SPECIFIC = 0xFF,          /* implementation specific: byte 2 says more */
    /* Not on the wire: the store indication answers later, through
     * co_lss_slave_store_answer (the application writes its medium). */
    CO_LSS_ERR_LATER = 0xFE
};

enum {
    CO_LSS_FASTSCAN_CONFIRM = 0x80      /* bit-checked value of the fast scan's reset */
};

typedef struct co_lss_address {
    uint32_t part[4];                   /* indexed by co_lss_part_t */
} co_lss_address_t;

/* One decoded LSS frame. Which fields mean something depends on cs. */
typedef struct co_lss_msg {
    uint8_t cs;
    uint8_t byte1;        /* state, node-id, table selector, error code */
    uint8_t byte2;        /* table index, implementation-specific error */
    uint16_t delay_ms;    /* activate bit timing: switch delay (bytes 1..2) */
    uint32_t value;       /* bytes 1..4: identity numbers, fast scan IDNumber */
    uint8_t bit_checked;  /* fast scan: byte 5 */
    uint8_t sub;          /* fast scan: byte 6 */
    uint8_t next;         /* fast scan: byte 7 */
} co_lss_msg_t;

typedef enum co_lss_decode {
    CO_LSS_DECODE_OK = 0,
    CO_LSS_DECODE_BAD_LENGTH = 1,        /* not 8 bytes */
    CO_LSS_DECODE_UNKNOWN_CS = 2         /* not a command of that direction */
} co_lss_decode_t;

typedef struct co_lss_slave_stats {
    uint32_t requests;         /* well-formed frames received */
    uint32_t answers;          /* frames sent */
    uint32_t bad_length;       /* frames of another length than 8 */
    uint32_t unknown_cs;       /* unknown command specifier */
    uint32_t bad_argument;     /* a known command with a value out of its range */
    uint32_t not_in_state;     /* a command the current state does not serve */
    uint32_t tx_failed;        /* an answer the tx queue refused */
    uint32_t store_busy;       /* a store request while the last one waits for its answer */
} co_lss_slave_stats_t;
/* cffi:end */

/* ------------------------------------------------------------------ codec
 * Decoders take (data, len) and never read past len. */

/* A master's request (received on 0x7E5). */
co_lss_decode_t co_lss_decode_request(const uint8_t *data, size_t len, co_lss_msg_t *msg);
/* A slave's answer (received on 0x7E4). */
co_lss_decode_t co_lss_decode_answer(const uint8_t *data, size_t len, co_lss_msg_t *msg);

/* Encoders fill all 8 bytes (unused ones 0). */
void co_lss_encode_bytes(uint8_t out[8], uint8_t cs, uint8_t byte1, uint8_t byte2);
void co_lss_encode_value(uint8_t out[8], uint8_t cs, uint32_t value);
void co_lss_encode_delay(uint8_t out[8], uint16_t delay_ms);
void co_lss_encode_fastscan(uint8_t out[8], uint32_t id_number, uint8_t bit_checked,
                            uint8_t sub, uint8_t next);

/* True for 1..127 and 255, the values "configure node-id" accepts. */
static inline bool co_lss_node_id_valid(uint8_t node_id)
{
    return (node_id >= 1u && node_id <= 127u) || node_id == CO_LSS_NODE_ID_UNCONFIGURED;
}

/* ------------------------------------------------------------------ slave */

typedef struct co_lss_slave co_lss_slave_t;

/* What the application decides or is told (each may be NULL). They run
 * inside co_line_process. */
typedef struct co_lss_slave_indications {
    /* configure bit timing: true accepts (the table entry becomes pending),
     * false answers "not supported". NULL: never supported. */
    bool (*check_bit_timing)(co_lss_slave_t *slave, uint8_t table_selector,
                             uint8_t table_index, void *user);
    /* activate bit timing: switch to the pending bit timing after delay_ms,
     * stay silent for another delay_ms, then go on. */
    void (*activate_bit_timing)(co_lss_slave_t *slave, uint16_t delay_ms, void *user);
    /* store configuration: persist node_id (the pending one) and the
     * pending bit timing; returns CO_LSS_ERR_OK, _STORE_NOT_SUPPORTED or
     * _STORE_MEDIA, or CO_LSS_ERR_LATER to answer with
     * co_lss_slave_store_answer. NULL: not supported. */
    uint8_t (*store)(co_lss_slave_t *slave, uint8_t node_id, void *user);
    /* the LSS state changed */
    void (*state_changed)(co_lss_slave_t *slave, co_lss_state_t state, void *user);
    /* a slave that was unconfigured got a node-id and was switched back to
     * waiting: the node must reset communication now (which calls
     * co_lss_slave_reset_communication and so activates node_id). */
    void (*reset_communication)(co_lss_slave_t *slave, uint8_t node_id, void *user);
} co_lss_slave_indications_t;

struct co_lss_slave {
    co_line_t *line;
    co_lss_address_t address;
    co_lss_state_t state;
    uint8_t active_node_id;
    uint8_t pending_node_id;
    uint8_t persistent_node_id;
    uint8_t bit_timing_selector;     /* pending bit timing (after an accepted configure) */
    uint8_t bit_timing_index;
    bool bit_timing_pending;
    uint8_t select_step;             /* switch state selective: parts matched so far */
    uint8_t identify_seen;           /* identify remote slave: bit per part received */
    uint32_t identify[6];            /* ... and the values */
    uint8_t fastscan_pos;            /* fast scan: the part being checked (LSSPos) */
    bool store_waiting;              /* a store's answer comes from the application */
    uint8_t store_node_id;           /* ... for this node-id */
    const co_lss_slave_indications_t *ind;
    void *user;
    co_lss_slave_stats_t stats;
};

/* node_id: the node's active node-id at power-on (1..127 or 255), also the
 * pending and persistent one. Subscribes 0x7E5; false when node_id is not
 * valid or the CAN-ID is taken. */
bool co_lss_slave_init(co_lss_slave_t *slave, co_line_t *line, const co_lss_address_t *address,
                       uint8_t node_id, const co_lss_slave_indications_t *ind, void *user);
void co_lss_slave_deinit(co_lss_slave_t *slave);
/* The answer to a store the indication deferred (CO_LSS_ERR_LATER): error
 * as the indication would have returned it. False when none waits. */
bool co_lss_slave_store_answer(co_lss_slave_t *slave, uint8_t error);
/* The node resets communication: the pending node-id becomes the active one
 * (returned). */
uint8_t co_lss_slave_reset_communication(co_lss_slave_t *slave);
/* The application renumbered the node (not LSS): node_id becomes the active
 * and the pending one; the persistent one stays. */
void co_lss_slave_follow_node_id(co_lss_slave_t *slave, uint8_t node_id);

static inline co_lss_state_t co_lss_slave_state(const co_lss_slave_t *s) { return s->state; }
static inline uint8_t co_lss_slave_active_node_id(const co_lss_slave_t *s)
{
    return s->active_node_id;
}
static inline uint8_t co_lss_slave_pending_node_id(const co_lss_slave_t *s)
{
    return s->pending_node_id;
}
static inline uint8_t co_lss_slave_persistent_node_id(const co_lss_slave_t *s)
{
    return s->persistent_node_id;
}
static inline const co_lss_slave_stats_t *co_lss_slave_stats(const co_lss_slave_t *s)
{
    return &s->stats;
}

#endif
