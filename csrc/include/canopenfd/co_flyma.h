/* Flying master (CiA 302-2): several nodes able to be the network's NMT
 * master agree on one. After its boot-up a candidate waits the negotiation
 * delay and asks for the active master (0x73); the active master answers
 * with its priority and node-id (0x71). Without an answer the candidates
 * negotiate (0x72): each waits priority x priority slot + node-id x device
 * slot and the first whose wait ends announces itself (0x71); the others
 * compare and become slaves (lower priority value wins, then lower
 * node-id). A better candidate that hears a worse active master forces a
 * new negotiation (0x76); the active master sends 0x76 now and then so a
 * second active master shows. A slave that loses the active master's
 * heartbeat asks for a reset of the whole network, which starts a new
 * negotiation. 0x75 / 0x74 find the nodes able to be master. The frames
 * and where their layout comes from: docs/protocol-notes.md ("Flying
 * master"). */
#ifndef CO_FLYMA_H
#define CO_FLYMA_H

#include "canopenfd/co_line.h"
#include "canopenfd/co_od.h"

enum {
    CO_FLYMA_ID_ACTIVE_MASTER = 0x71,   /* [priority, node-id]: the active master */
    CO_FLYMA_ID_NEGOTIATE = 0x72,       /* start a negotiation */
    CO_FLYMA_ID_ASK_ACTIVE = 0x73,      /* which is the active master? */
    CO_FLYMA_ID_CAPABLE = 0x74,         /* a node able to be master answers 0x75 */
    CO_FLYMA_ID_ASK_CAPABLE = 0x75,     /* which nodes are able to be master? */
    CO_FLYMA_ID_FORCE = 0x76,           /* force a new negotiation */
    CO_FLYMA_OD_TIMING = 0x1F90,        /* sub 1..6: the timing parameters below */
    CO_FLYMA_OD_DETECT = 0x1F91         /* sub 1: the time 0x75 answers are awaited */
};

/* cffi:begin */
typedef enum co_flyma_state {
    CO_FLYMA_IDLE = 0,            /* not started (or stopped) */
    CO_FLYMA_WAITING = 1,         /* the negotiation delay after a boot-up */
    CO_FLYMA_DETECTING = 2,       /* asked for the active master, awaiting its answer */
    CO_FLYMA_NEGOTIATING = 3,     /* waiting the own time slot */
    CO_FLYMA_MASTER = 4,          /* this node is the active master */
    CO_FLYMA_SLAVE = 5            /* another node is the active master */
} co_flyma_state_t;

typedef enum co_flyma_event {
    CO_FLYMA_EV_STATE = 1,        /* the state changed (master: the active master's id) */
    CO_FLYMA_EV_RESET_ALL = 2,    /* the integration resets every node's communication
                                   * (NMT to all, this node included) */
    CO_FLYMA_EV_CAPABLE = 3,      /* a node answered 0x75 (count so far in priority) */
    CO_FLYMA_EV_CAPABLE_DONE = 4  /* the 0x75 window closed (count in priority) */
} co_flyma_event_t;

typedef struct co_flyma_stats {
    uint32_t negotiations;        /* negotiations this node took part in */
    uint32_t announcements;       /* 0x71 sent */
    uint32_t forced;              /* 0x76 sent */
    uint32_t rx_bad_length;       /* 0x71 not 2 bytes, others not 0 bytes */
    uint32_t rx_ignored;          /* frames while idle, a 0x71 from our own node-id */
    uint32_t send_failed;         /* tx queue full */
} co_flyma_stats_t;
/* cffi:end */

typedef struct co_flyma co_flyma_t;

/* state: the new state (EV_STATE); master: the active master's node-id (0:
 * none yet), priority: its priority (EV_CAPABLE*: the answers counted). */
typedef void (*co_flyma_fn)(co_flyma_t *flyma, co_flyma_event_t event, co_flyma_state_t state,
                            uint8_t master, uint8_t priority, void *user);

/* 0x1F90 sub 1..6 and 0x1F91 sub 1 (ms unless said; 0 = the default). */
typedef struct co_flyma_config {
    uint16_t detect_ms;           /* 1F90:1 answer of the active master awaited, 100 */
    uint16_t delay_ms;            /* 1F90:2 negotiation delay after a boot-up, 500 */
    uint8_t priority;             /* 1F90:3 priority, lower wins (0 is a valid value) */
    uint16_t priority_slot_ms;    /* 1F90:4, 1500 */
    uint16_t device_slot_ms;      /* 1F90:5, 10 */
    uint16_t multiple_master_ms;  /* 1F90:6 cycle of the active master's 0x76, 4000 */
    uint16_t capable_ms;          /* 1F91:1 answers to 0x75 awaited, 100 */
    co_flyma_fn ind;              /* may be NULL */
    void *user;
} co_flyma_config_t;

/* Read through the functions below. */
struct co_flyma {
    co_line_t *line;
    co_flyma_config_t config;
    co_flyma_state_t state;
    bool subscribed;
    bool power_on;                /* no network reset asked for yet */
    uint8_t master;               /* the active master's node-id, 0 = none */
    uint8_t master_priority;
    uint8_t capable_count;
    co_timer_t timer;             /* delay, detection, own slot, multiple-master cycle */
    co_timer_t capable_timer;
    co_flyma_stats_t stats;
};

/* Subscribes 0x71..0x76; the node-id is the line's (co_line_node_id) at the
 * time of each frame sent. False when the range is taken or the arguments
 * are invalid. Starts IDLE. */
bool co_flyma_init(co_flyma_t *flyma, co_line_t *line, const co_flyma_config_t *config);
void co_flyma_deinit(co_flyma_t *flyma);
/* The timing from a sealed OD's 0x1F90 / 0x1F91 (the entries present;
 * others keep their value in config). */
void co_flyma_config_from_od(co_flyma_config_t *config, const co_od_t *od);
/* The node booted (power-on or reset communication): wait the delay, then
 * detect the active master. */
void co_flyma_boot(co_flyma_t *flyma);
/* Stop taking part (IDLE). */
void co_flyma_stop(co_flyma_t *flyma);
/* Error control lost node_id: when it is the active master, a slave asks
 * for a network reset (EV_RESET_ALL) and starts over. */
void co_flyma_node_lost(co_flyma_t *flyma, uint8_t node_id);
/* Ask for the nodes able to be master (0x75); EV_CAPABLE per answer,
 * EV_CAPABLE_DONE when capable_ms passed. False when the frame could not
 * be queued. */
bool co_flyma_detect_capable(co_flyma_t *flyma);
/* Force a new negotiation (0x76 then 0x72). False unless started. */
bool co_flyma_force(co_flyma_t *flyma);

static inline co_flyma_state_t co_flyma_state(const co_flyma_t *flyma) { return flyma->state; }
static inline uint8_t co_flyma_master(const co_flyma_t *flyma) { return flyma->master; }
static inline uint8_t co_flyma_master_priority(const co_flyma_t *flyma)
{
    return flyma->master_priority;
}
static inline const co_flyma_stats_t *co_flyma_stats(const co_flyma_t *flyma)
{
    return &flyma->stats;
}

#endif
