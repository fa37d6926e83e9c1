/* The local node of a line: NMT slave + heartbeat producer, and, when an
 * object dictionary is attached, the communication parameters it serves
 * (0x1016 consumer entries, 0x1017 producer time) loaded from defaults or
 * the store at boot and at each reset. Without an OD the node keeps the
 * 0x1017 value given at init. */
#ifndef CO_NODE_H
#define CO_NODE_H

#include "canopenfd/co_emcy.h"
#include "canopenfd/co_errors.h"
#include "canopenfd/co_flyma.h"
#include "canopenfd/co_guard.h"
#include "canopenfd/co_hb.h"
#include "canopenfd/co_led.h"
#include "canopenfd/co_mpdo.h"
#include "canopenfd/co_od.h"
#include "canopenfd/co_pdo.h"
#include "canopenfd/co_redundancy.h"
#include "canopenfd/co_srdo.h"
#include "canopenfd/co_srdo_od.h"
#include "canopenfd/co_store.h"
#include "canopenfd/co_sync.h"
#include "canopenfd/co_time.h"

typedef struct co_node co_node_t;

typedef struct co_node_indications {
    void (*state_changed)(co_node_t *node, co_nmt_state_t old_state,
                          co_nmt_state_t new_state, void *user);
    bool (*allow_operational)(co_node_t *node, void *user);   /* may be NULL */
    void (*reset)(co_node_t *node, co_nmt_command_t kind, void *user); /* may be NULL */
    /* RPDO n was applied to the OD (may be NULL). */
    void (*pdo_received)(co_node_t *node, uint16_t rpdo_number, void *user);
    /* TPDO n is about to be sampled: refresh its values now (may be NULL). */
    void (*pdo_before_send)(co_node_t *node, uint16_t tpdo_number, void *user);
    /* An MPDO addressed to this node on RPDO n was applied to local
     * index:sub (abort 0) or refused with abort (may be NULL). */
    void (*mpdo_received)(co_node_t *node, uint16_t rpdo_number, const co_mpdo_msg_t *msg,
                          uint16_t index, uint8_t sub, uint32_t abort, void *user);
} co_node_indications_t;

/* The services a node runs besides NMT and heartbeat, each set up by the
 * caller over its own storage (and bound to the OD) before
 * co_node_attach_services; any may be NULL. The node wires them together:
 * NMT state to each (PDOs flow only in operational, the SDO/USDO server
 * serves only in pre-operational and operational), SYNC to the PDOs, the
 * errors they detect to EMCY, communication errors to 0x1029, resets to a
 * reload. A PDO service must be set up with co_node_pdo_indications and the
 * node as user, a guarding slave with co_node_guard_life and the node. */
typedef struct co_node_services {
    co_emcy_t *emcy;
    /* Error-status bits in front of emcy: the node keeps its stack bits in
     * step with the errors it raises, and applies 0x1029:01 when a report
     * sets a communication-class bit. */
    co_errors_t *errors;
    co_sync_t *sync;
    co_time_t *time;
    co_pdo_t *pdo;
    co_guard_slave_t *guard;
    /* The SDO or USDO server, told each NMT state through server_state
     * (co_sdo_server_set_nmt_state / co_usdo_server_set_nmt_state behind a
     * void * adapter: the node links no server it does not run). */
    void *server;
    void (*server_state)(void *server, co_nmt_state_t state);
    /* Flying master: started over at every reset (co_node_attach_flyma). */
    co_flyma_t *flyma;
    /* CiA 303-3 indicators: told the NMT state and the errors the node
     * tracks (bus-off, warning, heartbeat/guarding lost, SYNC and RPDO
     * deadline errors); may be NULL. */
    co_led_t *led;
    /* SRDOs (CiA 304): run only in operational (co_node_attach_srdo);
     * srdo_od (may be NULL) guards their OD objects and reloads them on
     * entering operational, before they start. */
    co_srdo_t *srdo;
    uint8_t srdo_count;
    /* Bus redundancy: Bdefault selected again at every reset, after the
     * reload (co_node_attach_redundancy). */
    co_rdn_t *rdn;
    co_srdo_od_t *srdo_od;
} co_node_services_t;

enum {
    CO_NODE_ERROR_BEHAVIOUR = 0x1029,   /* sub 1: communication error */
    CO_NODE_EMCY_CAN_OVERRUN = 0x8110,
    CO_NODE_EMCY_ERROR_PASSIVE = 0x8120,
    CO_NODE_EMCY_LIFE_GUARD = 0x8130,   /* heartbeat consumer or life guarding */
    CO_NODE_EMCY_BUS_OFF = 0x8140,      /* "recovered from bus off" */
    CO_NODE_PDO_BITMAP = CO_PDO_MAX_NUMBER / 8,
    CO_NODE_OVERRUN_QUIET_US = 1000000
};

/* The node-id a node runs with after the reset it is in (1..127; another
 * value keeps the current one). Runs inside the reset, before the
 * parameters reload and the boot-up is sent. */
typedef uint8_t (*co_node_reset_id_fn)(co_node_t *node, co_nmt_command_t kind, void *user);

struct co_node {
    co_line_t *line;
    co_nmt_t nmt;
    co_hb_producer_t heartbeat;
    uint16_t heartbeat_default_ms;   /* 0x1017 value restored by a reset (no OD) */
    const co_node_indications_t *ind;
    void *user;
    /* A part of the node assembly hearing the same indications, first
     * (co_node_set_part_indications), or NULL. */
    const co_node_indications_t *part_ind;
    void *part_user;
    co_od_t *od;                     /* sealed OD, or NULL */
    co_store_t *store;               /* saved parameters, or NULL */
    co_hb_consumer_t *consumer;      /* configured from 0x1016, or NULL */
    co_store_status_t store_status;  /* what the last parameter load found */
    co_node_services_t services;
    /* Errors the node raised and clears once their cause is gone. */
    uint8_t rpdo_short[CO_NODE_PDO_BITMAP];     /* RPDOs in 0x8210 */
    uint8_t rpdo_long[CO_NODE_PDO_BITMAP];      /* RPDOs in 0x8220 */
    uint8_t rpdo_late[CO_NODE_PDO_BITMAP];      /* RPDOs in 0x8250 */
    uint8_t hb_lost[128 / 8];                   /* consumed nodes lost (0x8130) */
    bool life_lost;                             /* life guarding (0x8130) */
    bool sync_length_error;                     /* 0x8240 */
    bool overrun_told;                          /* 0x8110 sent at overrun_told_us */
    uint64_t overrun_told_us;
    bool sync_timeout;                          /* no SYNC within 1.5 x 0x1006 (LED) */
    /* Asked at each reset, before the parameters reload (co_stack: the LSS
     * slave's pending node-id, CiA 305); NULL: the node-id stays. */
    co_node_reset_id_fn reset_node_id;
    void *reset_node_id_user;
};

extern const co_pdo_indications_t co_node_pdo_indications;
/* The MPDO service's indications to the node: a DAM MPDO not processed
 * sends EMCY 0x8230 and, being an event, clears it at once (user = node). */
extern const co_mpdo_indications_t co_node_mpdo_indications;

/* Sets up the node on the line (node_id 1..127, the line's node-id becomes
 * node_id); nothing is sent until co_node_boot(). */
bool co_node_init(co_node_t *node, co_line_t *line, uint8_t node_id,
                  uint16_t heartbeat_ms, const co_node_indications_t *ind, void *user);
void co_node_deinit(co_node_t *node);
/* Serve an object dictionary (sealed) before co_node_boot(): parameters load
 * from the store (or defaults) at boot and resets; writes to 0x1017 re-arm
 * the heartbeat at once; 0x1016 entries configure `consumer` (may be NULL),
 * a duplicate node-id being refused with CO_ABORT_PARAM_INCOMPATIBLE.
 * store may be NULL (defaults only). False when the OD cannot take the hooks. */
bool co_node_attach_od(co_node_t *node, co_od_t *od, co_store_t *store,
                       co_hb_consumer_t *consumer);
/* Power-on: parameters loaded, boot-up message, pre-operational, heartbeat
 * producer running. */
void co_node_boot(co_node_t *node);
/* Wire the services (see co_node_services_t) before co_node_boot(). */
void co_node_attach_services(co_node_t *node, const co_node_services_t *services);
/* The flying master the node runs (NULL: none); every reset starts it over. */
void co_node_attach_flyma(co_node_t *node, co_flyma_t *flyma);
/* The node's SRDOs (count of them, NULL/0: none), told the NMT state now and
 * at every change. */
/* The bus redundancy the node runs (NULL: none); every reset starts it over. */
void co_node_attach_redundancy(co_node_t *node, co_rdn_t *rdn);
void co_node_attach_srdo(co_node_t *node, co_srdo_t *srdo, uint8_t count,
                         co_srdo_od_t *srdo_od);
/* A part the node assembly runs over the node (co_stack's CiA 401 device)
 * hears its state changes, applied RPDOs and resets (after the reload)
 * before the application does; one slot, ind NULL clears it. Only those
 * three indications are used. */
void co_node_set_part_indications(co_node_t *node, const co_node_indications_t *ind,
                                  void *user);
/* Errors the stack detects outside the node's services, told by the
 * driver side: a consumed node's heartbeat lost / back (EMCY 0x8130 and
 * 0x1029:01), and the line's communication events (bus-off 0x8140 with
 * 0x1029:01, error passive 0x8120, lost frames 0x8110). */
void co_node_heartbeat_event(co_node_t *node, uint8_t node_id, bool lost);
void co_node_comm_event(co_node_t *node, co_comm_event_t event);
/* Apply the error behaviour of 0x1029 sub `error_class` (1 = communication;
 * 0 -> pre-operational when operational, 1 -> no change, 2 -> stopped;
 * a missing entry means 0, as CiA 301's default). */
void co_node_error_behaviour(co_node_t *node, uint8_t error_class);
/* Guarding slave's indication (pass it to co_guard_slave_init with the node). */
void co_node_guard_life(co_guard_slave_t *slave, co_guard_life_event_t event, void *user);
/* Write 0x1017: takes effect at once. */
void co_node_set_heartbeat(co_node_t *node, uint16_t time_ms);
/* Who decides the node-id at each reset (NULL: nobody, it stays). When it
 * names another one the node takes it before its parameters reload: NMT,
 * the line (services reading co_line_node_id), the OD's $NODEID defaults,
 * the EMCY producer's default COB-ID; the boot-up carries it. */
void co_node_set_reset_node_id(co_node_t *node, co_node_reset_id_fn fn, void *user);
/* Renumber the node now (1..127), as a reset with fn naming node_id does,
 * without reloading anything; false for an invalid node-id. */
bool co_node_set_node_id(co_node_t *node, uint8_t node_id);
static inline co_nmt_state_t co_node_state(const co_node_t *node) { return node->nmt.state; }

#endif
