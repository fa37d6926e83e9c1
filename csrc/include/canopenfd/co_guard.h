/* Node guarding and life guarding (CiA 301 error control with remote
 * frames), classic lines only: CAN FD has no remote frames.
 *
 * Slave (the local node): answers a remote frame on 0x700 + own node-id with
 * one byte, the NMT state (0x04 / 0x05 / 0x7F) | toggle bit 7; the toggle
 * starts at 0 when the protocol becomes active and alternates with every
 * answer. Life guarding: with guard time 0x100C (ms) and life time factor
 * 0x100D both non-zero, once the first remote frame came, no remote frame
 * within guard time x factor is a life guarding event. A node whose
 * heartbeat producer time (0x1017) is non-zero uses the heartbeat instead:
 * it neither answers nor watches (CiA 301: one error control protocol at a
 * time, heartbeat when 0x1017 != 0).
 *
 * Master (guarding remote nodes): per guarded node a remote frame every
 * guard time; an answer must come with the toggle bit alternating; missed
 * answers for life time factor periods in a row: "lost"; answers again:
 * "resumed". The answers come on 0x700 + node-id, the heartbeat consumer's
 * range: hand them over with co_hb_consumer_set_filter(consumer,
 * co_guard_master_receive, master) (or, on a line without a heartbeat
 * consumer, co_line_subscribe_other with the same function). */
#ifndef CO_GUARD_H
#define CO_GUARD_H

#include "canopenfd/co_nmt.h"
#include "canopenfd/co_od.h"

enum {
    CO_GUARD_EMCY_LIFE = 0x8130,     /* EMCY code: life guard or heartbeat error */
    CO_GUARD_TOGGLE_BIT = 0x80
};

/* ------------------------------------------------------------------ slave */

typedef enum co_guard_life_event {
    CO_GUARD_LIFE_LOST = 1,       /* no remote frame within the life time */
    CO_GUARD_LIFE_RESOLVED = 2    /* the condition ended: a remote frame came, or life
                                     guarding was switched off or reset */
} co_guard_life_event_t;

typedef struct co_guard_slave co_guard_slave_t;
typedef void (*co_guard_life_fn)(co_guard_slave_t *slave, co_guard_life_event_t event,
                                 void *user);

/* cffi:begin */
typedef struct co_guard_slave_stats {
    uint32_t answered;            /* remote frames answered */
    uint32_t ignored_heartbeat;   /* not answered: the heartbeat producer is on */
    uint32_t ignored_state;       /* not answered: no boot-up yet (initialising) */
    uint32_t tx_failed;           /* answer refused by the tx queue (toggle unchanged) */
    uint32_t life_lost;           /* life guarding events */
} co_guard_slave_stats_t;
/* cffi:end */

struct co_guard_slave {
    co_line_t *line;
    co_nmt_t *nmt;                /* state and node-id of the local node */
    co_od_t *od;
    uint16_t guard_time_ms;       /* 0x100C */
    uint8_t life_time_factor;     /* 0x100D */
    uint16_t heartbeat_ms;        /* 0x1017; non-zero switches guarding off */
    bool toggle;                  /* toggle bit of the next answer */
    bool guarded;                 /* a remote frame came since guarding became active */
    bool lost;                    /* LIFE_LOST told, not resolved yet */
    co_timer_t life_timer;
    co_guard_life_fn on_life;
    void *user;
    co_guard_slave_stats_t stats;
};

/* Registers an "other" receiver for remote frames. False on an fd line or
 * when the line's table of other receivers is full. */
bool co_guard_slave_init(co_guard_slave_t *slave, co_line_t *line, co_nmt_t *nmt,
                         co_guard_life_fn on_life, void *user);
void co_guard_slave_deinit(co_guard_slave_t *slave);
/* Bind to a sealed OD: 0x100C, 0x100D (missing = 0) and 0x1017 (missing:
 * left as set) read now and hooked: writes and reloads apply at once. */
bool co_guard_slave_attach_od(co_guard_slave_t *slave, co_od_t *od);
void co_guard_slave_detach_od(co_guard_slave_t *slave);
/* New guard time / life time factor, at once: a running life time starts
 * over from now with the new values; 0 switches life guarding off. */
void co_guard_slave_set_times(co_guard_slave_t *slave, uint16_t guard_time_ms,
                              uint8_t life_time_factor);
/* The heartbeat producer time: non-zero switches node guarding off (no
 * answers, no life guarding, toggle back to 0 for when it returns). */
void co_guard_slave_set_heartbeat(co_guard_slave_t *slave, uint16_t heartbeat_ms);
/* NMT reset communication (and reset node): toggle 0, life guarding waits
 * for the next first remote frame. */
void co_guard_slave_reset_communication(co_guard_slave_t *slave);

/* ------------------------------------------------------------------ master */

typedef enum co_guard_event {
    CO_GUARD_STARTED = 1,           /* first valid answer */
    CO_GUARD_STATE_CHANGED = 2,     /* an answer with another state than the last */
    CO_GUARD_LOST = 3,              /* life time factor answers missed in a row */
    CO_GUARD_RESUMED = 4,           /* a valid answer after LOST */
    CO_GUARD_TOGGLE_ERROR = 5,      /* answer with the wrong toggle: not taken */
    CO_GUARD_UNEXPECTED_STATE = 6   /* valid answer, not the state the master expects */
} co_guard_event_t;

typedef enum co_guard_monitor {
    CO_GUARD_MONITOR_OFF = 0,       /* not guarded, or no valid answer yet */
    CO_GUARD_MONITOR_ACTIVE = 1,
    CO_GUARD_MONITOR_LOST = 2
} co_guard_monitor_t;

typedef enum co_guard_result {
    CO_GUARD_OK = 0,
    CO_GUARD_BAD_NODE = 1,          /* node-id outside 1..127 */
    CO_GUARD_BAD_TIME = 2,          /* guard time 0 */
    CO_GUARD_NO_ROOM = 3            /* table full */
} co_guard_result_t;

struct co_guard_master;

typedef struct co_guard_node {
    struct co_guard_master *owner;
    uint8_t node_id;                /* 0 = unused */
    uint16_t guard_time_ms;
    uint8_t life_time_factor;       /* 0 counts as 1 */
    uint8_t expected_toggle;        /* 0 or CO_GUARD_TOGGLE_BIT */
    bool toggle_known;              /* false from guard() until the first answer or boot-up */
    uint8_t missed;                 /* guard periods in a row without a valid answer */
    bool waiting;                   /* remote frame sent, no valid answer since */
    uint8_t state;                  /* last answered state, CO_NMT_UNKNOWN */
    uint8_t expected_state;         /* CO_NMT_UNKNOWN = any */
    bool mismatch;                  /* UNEXPECTED_STATE told, still differing */
    co_guard_monitor_t monitor;
    co_timer_t timer;
} co_guard_node_t;

typedef struct co_guard_master co_guard_master_t;
typedef void (*co_guard_event_fn)(co_guard_master_t *master, uint8_t node_id,
                                  co_guard_event_t event, co_nmt_state_t state, void *user);

/* cffi:begin */
typedef struct co_guard_master_stats {
    uint32_t rtr_sent;
    uint32_t answers;               /* valid answers taken */
    uint32_t missed;                /* guard periods without a valid answer */
    uint32_t toggle_errors;
    uint32_t bad_length;            /* frames of a guarded node not 1 byte long */
    uint32_t bad_state;             /* answers whose state is no NMT state */
    uint32_t tx_failed;             /* remote frame refused by the tx queue */
} co_guard_master_stats_t;
/* cffi:end */

struct co_guard_master {
    co_line_t *line;
    co_guard_node_t *nodes;         /* caller storage */
    uint8_t capacity;
    co_guard_event_fn on_event;
    void *user;
    co_guard_master_stats_t stats;
};

/* False on an fd line. */
bool co_guard_master_init(co_guard_master_t *master, co_line_t *line, co_guard_node_t *nodes,
                          uint8_t capacity, co_guard_event_fn on_event, void *user);
void co_guard_master_deinit(co_guard_master_t *master);
/* Guard a node (or change its times, effective from now): the first remote
 * frame goes out now, then every guard time. */
co_guard_result_t co_guard_master_guard(co_guard_master_t *master, uint8_t node_id,
                                        uint16_t guard_time_ms, uint8_t life_time_factor);
void co_guard_master_unguard(co_guard_master_t *master, uint8_t node_id);
/* The state the master expects the node in (after its NMT commands);
 * CO_NMT_UNKNOWN = any. An answer with another state is told once as
 * UNEXPECTED_STATE (again after a matching answer). */
void co_guard_master_expect_state(co_guard_master_t *master, uint8_t node_id,
                                  co_nmt_state_t state);
co_guard_monitor_t co_guard_master_monitor(const co_guard_master_t *master, uint8_t node_id);
/* Whether node_id is in the guard table (guarded from guard() to unguard()). */
bool co_guard_master_guards(const co_guard_master_t *master, uint8_t node_id);
co_nmt_state_t co_guard_master_state(const co_guard_master_t *master, uint8_t node_id);
/* Frame hand-over (co_rx_other_fn): takes the data frames of guarded nodes
 * on 0x700 + node-id, except a boot-up (0x00), which it notes (the node's
 * toggle starts at 0 again) and leaves to the heartbeat consumer. */
bool co_guard_master_receive(co_line_t *line, const co_frame_t *frame, void *user);

#endif
