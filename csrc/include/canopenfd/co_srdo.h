/* SRDO (CiA 304 / EN 50325-5 safety-relevant data object): one SRDO, as
 * producer or consumer, on a classic line.
 *
 * A producer sends its data every SCT (safeguard cycle time) as a pair of
 * frames: the normal frame on the odd CAN-ID, then the same bytes
 * bit-inverted on the next (even) CAN-ID. A consumer takes the data only
 * when the pair checks: same length as configured, every inverted byte the
 * complement of its normal byte, the inverted frame within SRVT (safety
 * relevant validation time) of the normal one and a new normal frame
 * within SCT of the previous one. Any violation makes the data invalid and
 * latches the safe state, told once through the event callback with what
 * went wrong; it stays until co_srdo_restart or the next entry into NMT
 * operational. An SRDO runs only in NMT operational, only when 0x13FE says
 * the configuration is valid (0xA5) and the configuration's CRC equals its
 * 0x13FF signature.
 *
 * The data are the application's bytes (co_srdo_set_data / co_srdo_data)
 * or, once co_srdo_bind_od has resolved the mapping in an OD, the mapped
 * variables: odd mapping sub-indices feed the normal frame, even ones the
 * inverted frame (those variables hold the complement).
 * This is no certified safety stack: see the README's SRDO section. */
#ifndef CO_SRDO_H
#define CO_SRDO_H

#include "canopenfd/co_line.h"
#include "canopenfd/co_nmt.h"
#include "canopenfd/co_pdo_map.h"
#include "canopenfd/co_timer.h"

/* cffi:begin */
enum {
    CO_SRDO_MAX_DATA = 8,            /* classic CAN payload */
    CO_SRDO_MAX_MAPPED = 16,         /* 0x1381+n sub 1..16: normal, inverted alternating */
    CO_SRDO_CONFIG_VALID = 0xA5,     /* 0x13FE: configuration valid */
    CO_SRDO_TRANSMISSION_TYPE = 254, /* 0x1301+n sub 4: the only value allowed */
    CO_SRDO_COB_ID_FIRST = 0x101,    /* normal CAN-IDs: odd, 0x101..0x17F */
    CO_SRDO_COB_ID_LAST = 0x180      /* inverted CAN-IDs: even, 0x102..0x180 */
};

typedef enum co_srdo_direction {
    CO_SRDO_OFF = 0,
    CO_SRDO_PRODUCE = 1,
    CO_SRDO_CONSUME = 2
} co_srdo_direction_t;

typedef enum co_srdo_state {
    CO_SRDO_STOPPED = 0,     /* not NMT operational, or direction 0 */
    CO_SRDO_WAITING = 1,     /* operational, no pair produced / checked yet */
    CO_SRDO_RUNNING = 2,     /* pairs flow; a consumer's data are valid */
    CO_SRDO_SAFE = 3         /* a violation: data invalid until restarted */
} co_srdo_state_t;

/* Why an SRDO entered the safe state. */
typedef enum co_srdo_violation {
    CO_SRDO_NONE = 0,
    CO_SRDO_INVERTED_MISMATCH = 1,   /* an inverted byte is not the complement */
    CO_SRDO_SRVT_EXCEEDED = 2,       /* the inverted frame came later than SRVT */
    CO_SRDO_SCT_EXCEEDED = 3,        /* no new normal frame within SCT */
    CO_SRDO_WRONG_LENGTH = 4,        /* a frame of another length than mapped */
    CO_SRDO_INVERTED_MISSING = 5,    /* a normal frame came while the inverted was due */
    CO_SRDO_INVERTED_UNEXPECTED = 6, /* an inverted frame without its normal frame */
    CO_SRDO_CONFIG_INVALID = 7,      /* 0x13FE is not 0xA5 */
    CO_SRDO_CRC_MISMATCH = 8,        /* 0x13FF's signature is not the configuration's CRC */
    CO_SRDO_BAD_PARAMETER = 9,       /* a 0x1301+n / 0x1381+n value out of range */
    CO_SRDO_GFC = 10,                /* a global fail-safe command (co_srdo_fail) */
    CO_SRDO_TX_FAILED = 11,          /* a producer's frame found the tx queue full */
    CO_SRDO_APPLICATION = 12         /* the application's own reason (co_srdo_fail) */
} co_srdo_violation_t;

typedef struct co_srdo_stats {
    uint32_t pairs_sent;         /* producer: normal + inverted queued */
    uint32_t pairs_valid;        /* consumer: pairs that checked good */
    uint32_t violations;         /* safe-state entries */
    uint32_t ignored;            /* frames received while stopped or safe */
} co_srdo_stats_t;

/* 0x1301+n and 0x1381+n of one SRDO. */
typedef struct co_srdo_config {
    uint8_t direction;           /* sub 1: co_srdo_direction_t */
    uint16_t sct_ms;             /* sub 2: SCT, 1..65535 ms */
    uint8_t srvt_ms;             /* sub 3: SRVT, 1..255 ms */
    uint8_t transmission_type;   /* sub 4: 254 */
    uint32_t cob_id_normal;      /* sub 5 */
    uint32_t cob_id_inverted;    /* sub 6 */
    uint8_t map_count;           /* 0x1381+n sub 0: even, 0..16 */
    uint32_t map[CO_SRDO_MAX_MAPPED];   /* index << 16 | sub << 8 | bits */
} co_srdo_config_t;
/* cffi:end */


/* EMCY error codes of a safe-state entry (the stack sends one per entry,
 * manufacturer bytes: SRDO number, co_srdo_violation_t). No EMCY for a GFC
 * or the application's reason: those are commands, not errors. */
enum {
    CO_SRDO_EMCY_CONFIG = 0x6300,    /* data set: 0x13FE, 0x13FF or a parameter */
    CO_SRDO_EMCY_LENGTH = 0x8210,    /* a frame of another length than mapped */
    CO_SRDO_EMCY_PROTOCOL = 0x8200   /* any other violation of the pair or its timing */
};

/* Which parameter a configuration check refused (CO_SRDO_PARAM_OK: none). */
typedef enum co_srdo_param {
    CO_SRDO_PARAM_OK = 0,
    CO_SRDO_PARAM_DIRECTION = 1,         /* 0x1301+n sub 1 */
    CO_SRDO_PARAM_SCT = 2,               /* sub 2 */
    CO_SRDO_PARAM_SRVT = 3,              /* sub 3 */
    CO_SRDO_PARAM_TRANSMISSION_TYPE = 4, /* sub 4 */
    CO_SRDO_PARAM_COB_ID_NORMAL = 5,     /* sub 5 */
    CO_SRDO_PARAM_COB_ID_INVERTED = 6,   /* sub 6 */
    CO_SRDO_PARAM_MAP_COUNT = 7,         /* 0x1381+n sub 0 */
    CO_SRDO_PARAM_MAP_LENGTH = 8         /* an entry not whole bytes, the halves differ,
                                            or the data not 1..8 bytes */
} co_srdo_param_t;

typedef struct co_srdo co_srdo_t;

/* The SRDO entered the safe state (once per entry). */
typedef void (*co_srdo_fn)(co_srdo_t *srdo, co_srdo_violation_t why, void *user);

struct co_srdo {
    co_line_t *line;
    co_srdo_config_t config;
    co_srdo_param_t param_error;     /* the configuration's check */
    co_srdo_violation_t config_fault; /* NONE, CONFIG_INVALID, CRC_MISMATCH, BAD_PARAMETER */
    uint8_t length;                  /* data bytes, from the mapping */
    uint8_t data[CO_SRDO_MAX_DATA];  /* produced data, or the last valid pair's */
    uint8_t normal[CO_SRDO_MAX_DATA];   /* consumer: normal frame awaiting its inverse */
    bool inverted_due;
    bool operational;
    bool subscribed;
    uint64_t normal_at_us;           /* consumer: when the pending normal frame came */
    uint64_t sct_deadline_us;        /* consumer: the next normal frame is due by then */
    co_srdo_state_t state;
    co_srdo_violation_t violation;   /* why it is safe (NONE otherwise) */
    co_timer_t cycle_timer;          /* producer: next pair; consumer: SCT */
    co_timer_t srvt_timer;           /* consumer: SRVT */
    co_srdo_fn on_safe;
    co_srdo_fn on_leave;             /* left the safe state (co_srdo_set_leave_fn) */
    void *user;
    co_srdo_stats_t stats;
    co_od_t *od;                     /* mapped variables' OD (co_srdo_bind_od) or NULL */
    co_pdo_map_item_t items[CO_SRDO_MAX_MAPPED];   /* normal half first, then inverted */
    uint8_t normal_items;            /* items[0..normal_items) feed the normal frame */
    uint8_t inverted_items;          /* the next ones the inverted frame */
};

/* CRC-16 of a configuration, as 0x13FF sub n holds it: CRC-16-CCITT
 * (co_crc16_ccitt: polynomial 0x1021, initial 0) over direction (1 byte),
 * SCT (2), SRVT (1), normal COB-ID (4), inverted COB-ID (4), the mapping
 * count (1), then for every mapping entry its sub-index (1) and value (4),
 * multi-byte values little-endian; the transmission type is not included
 * (see docs/protocol-notes.md, SRDO). */
/* cffi:begin */
uint16_t co_srdo_crc(const co_srdo_config_t *config);
/* cffi:end */
/* The configuration's range check; *length (may be NULL) gets the data
 * length of a good mapping. Direction 0 passes whatever the rest says. */
co_srdo_param_t co_srdo_check(const co_srdo_config_t *config, uint8_t *length);

/* Stopped, direction 0, not subscribed; on_safe may be NULL. */
void co_srdo_init(co_srdo_t *srdo, co_line_t *line, co_srdo_fn on_safe, void *user);
void co_srdo_deinit(co_srdo_t *srdo);
/* Take a configuration with the 0x13FE value and this SRDO's 0x13FF
 * signature. Refused (false) while operational (CiA 304 changes the
 * configuration only outside operational) or when a consumer cannot
 * subscribe its CAN-IDs. A configuration that fails valid, signature or
 * range check is kept: the SRDO then enters the safe state saying so
 * when it should start. */
bool co_srdo_configure(co_srdo_t *srdo, const co_srdo_config_t *config, uint8_t valid,
                       uint16_t signature);
void co_srdo_set_nmt_state(co_srdo_t *srdo, co_nmt_state_t state);
/* Take the data from and give them to the mapped variables of `od` (after
 * co_srdo_configure, not while operational): a producer packs the odd
 * sub-indices' variables into the normal frame and the even ones' into the
 * inverted frame; a consumer writes a valid pair's normal bytes into the
 * odd ones and its inverted bytes into the even ones, never the bytes of a
 * pair that failed. Returns 0, or the abort of the first entry that cannot
 * be mapped (0x06040041: missing, not mappable in this direction as a PDO
 * would, or longer than its variable); the SRDO then keeps no OD and
 * enters the safe state with CO_SRDO_BAD_PARAMETER when it starts. od NULL
 * unbinds (the application's bytes again). */
uint32_t co_srdo_bind_od(co_srdo_t *srdo, co_od_t *od);
/* Producer: the data of the next pairs (exactly the mapped length); with
 * an OD bound they are written into the mapped variables (normal bytes and
 * their complement) at once, so no pair mixes old and new halves. */
bool co_srdo_set_data(co_srdo_t *srdo, const uint8_t *data, size_t length);
/* Consumer: copies the last valid pair's data into out (CO_SRDO_MAX_DATA
 * bytes room) and returns their length while RUNNING; 0 when the data are
 * not valid (nothing checked yet, stopped or safe). */
size_t co_srdo_data(const co_srdo_t *srdo, uint8_t *out);
/* Enter the safe state now (a GFC, or CO_SRDO_APPLICATION); CO_SRDO_NONE
 * is no reason and changes nothing. */
void co_srdo_fail(co_srdo_t *srdo, co_srdo_violation_t why);
/* Leave the safe state: start again as on entering operational. */
void co_srdo_restart(co_srdo_t *srdo);
/* Called (with co_srdo_init's user and the violation it had) when the SRDO
 * leaves the safe state: leaving NMT operational (it stops), a restart or an
 * entry into operational that does not fail again at once, a new
 * configuration. A start that fails again at once is a new entry (on_safe)
 * without a leave in between. NULL: not told. */
void co_srdo_set_leave_fn(co_srdo_t *srdo, co_srdo_fn on_leave);

static inline co_srdo_state_t co_srdo_state(const co_srdo_t *srdo) { return srdo->state; }
static inline co_srdo_violation_t co_srdo_violation(const co_srdo_t *srdo)
{
    return srdo->violation;
}
static inline const co_srdo_stats_t *co_srdo_stats(const co_srdo_t *srdo)
{
    return &srdo->stats;
}
const char *co_srdo_violation_name(co_srdo_violation_t why);

#endif
