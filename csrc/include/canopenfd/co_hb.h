/* Heartbeat: producer (0x1017) and consumer (0x1016) of the error-control
 * protocol on CAN-ID 0x700 + node-id. */
#ifndef CO_HB_H
#define CO_HB_H

#include "canopenfd/co_nmt.h"

/* cffi:begin */
typedef enum co_hb_event {
    CO_HB_BOOTUP = 1,         /* a node sent its boot-up message */
    CO_HB_STATE_CHANGED = 2,  /* a node reported another NMT state */
    CO_HB_STARTED = 3,        /* monitoring started (or resumed after lost) */
    CO_HB_LOST = 4,           /* no heartbeat within the consumer time */
    CO_HB_TICK = 5            /* a heartbeat of a ticking node (co_hb_consumer_tick),
                                 at most one per its interval */
} co_hb_event_t;
/* cffi:end */

/* -------- producer -------- */
typedef struct co_hb_producer {
    co_line_t *line;
    co_nmt_t *nmt;
    uint16_t time_ms;             /* 0x1017; 0 = off */
    co_timer_t timer;
} co_hb_producer_t;

void co_hb_producer_init(co_hb_producer_t *p, co_line_t *line, co_nmt_t *nmt);
/* Change the producer time; takes effect at once (the next heartbeat goes out
 * time_ms from now; 0 stops it). */
void co_hb_producer_set_time(co_hb_producer_t *p, uint16_t time_ms);
void co_hb_producer_stop(co_hb_producer_t *p);

/* -------- consumer -------- */
typedef enum co_hb_monitor {
    CO_HB_MONITOR_OFF = 0,        /* entry unused or no heartbeat yet */
    CO_HB_MONITOR_ACTIVE = 1,     /* heartbeats arriving in time */
    CO_HB_MONITOR_LOST = 2
} co_hb_monitor_t;

struct co_hb_consumer;

typedef struct co_hb_entry {
    struct co_hb_consumer *owner;
    uint8_t node_id;              /* 0 = unused */
    uint16_t time_ms;             /* 0 = watch states only, no timeout */
    co_hb_monitor_t monitor;
    co_timer_t timer;
} co_hb_entry_t;

/* Nodes whose every heartbeat is told (CO_HB_TICK), for applications that
 * want a liveness tick; bounded per node by an interval, so a node sending
 * heartbeats as fast as the bus allows cannot flood the application. */
#ifndef CO_HB_TICKS
#define CO_HB_TICKS 8
#endif
typedef struct co_hb_tick {
    uint8_t node_id;              /* 0 = unused */
    uint16_t interval_ms;         /* at most one CO_HB_TICK per interval */
    uint64_t next_us;             /* no tick before this time */
} co_hb_tick_t;

typedef void (*co_hb_event_fn)(struct co_hb_consumer *c, uint8_t node_id,
                               co_hb_event_t event, co_nmt_state_t state, void *user);

typedef struct co_hb_consumer {
    co_line_t *line;
    co_hb_entry_t *entries;       /* caller-owned storage */
    uint8_t capacity;
    co_hb_event_fn on_event;
    void *user;
    /* Offered every frame of 0x700..0x77F first; true = taken (node guarding
     * answers of guarded nodes, see co_guard.h). NULL: none. */
    co_rx_other_fn filter;
    void *filter_user;
    /* Last state seen of every node, CO_NMT_UNKNOWN when none. Indexed by node-id. */
    uint8_t last_state[128];
    co_hb_tick_t ticks[CO_HB_TICKS];
} co_hb_consumer_t;

/* Subscribes CAN-IDs 0x700..0x77F (0x700 counted as hb_bad_node). Every node's boot-up and state changes are
 * reported; STARTED / LOST only for configured entries. */
bool co_hb_consumer_init(co_hb_consumer_t *c, co_line_t *line, co_hb_entry_t *entries,
                         uint8_t capacity, co_hb_event_fn on_event, void *user);
void co_hb_consumer_deinit(co_hb_consumer_t *c);
/* Hand frames of the range to fn first (one filter; NULL removes it): a
 * frame it takes is not a heartbeat (co_guard_master_receive takes the node
 * guarding answers of the nodes it guards). */
void co_hb_consumer_set_filter(co_hb_consumer_t *c, co_rx_other_fn fn, void *user);

/* Result codes for entry configuration (map to SDO aborts later). */
typedef enum co_hb_config_result {
    CO_HB_CONFIG_OK = 0,
    CO_HB_CONFIG_BAD_NODE = 1,     /* co_hb_consumer_watch: node-id outside 1..127 */
    CO_HB_CONFIG_DUPLICATE = 2,    /* node already watched by another entry */
    CO_HB_CONFIG_NO_ROOM = 3,      /* index outside the table */
} co_hb_config_result_t;

/* An entry with time 0 elsewhere for the same node gives way (it only
 * watched states); one with a time makes this a CO_HB_CONFIG_DUPLICATE.
 * Set entry `index` the way a write to 0x1016 sub index+1 does: value bits
 * 23..16 node-id (0 or > 127 leaves the entry unused, per CiA 301), bits 15..0
 * time in ms. A new node's monitoring starts at its next heartbeat; a new
 * time for a node already monitored counts from now. */
co_hb_config_result_t co_hb_consumer_set_entry(co_hb_consumer_t *c, uint8_t index,
                                               uint32_t value);
/* Watch a node in the last free entry (or update its entry); the first
 * entries are left to 0x1016. time_ms 0 only watches states: it leaves an
 * existing entry as it is, and gives way when 0x1016 later names the node. */
co_hb_config_result_t co_hb_consumer_watch(co_hb_consumer_t *c, uint8_t node_id,
                                           uint16_t time_ms);
/* Tell every heartbeat of node_id (boot-ups excepted: CO_HB_BOOTUP) as
 * CO_HB_TICK, at most one per interval_ms (0 = every heartbeat; a later call
 * changes the interval); works whether or not the node is watched. Stop with
 * co_hb_consumer_untick. CO_HB_CONFIG_NO_ROOM when CO_HB_TICKS nodes tick. */
co_hb_config_result_t co_hb_consumer_tick(co_hb_consumer_t *c, uint8_t node_id,
                                          uint16_t interval_ms);
void co_hb_consumer_untick(co_hb_consumer_t *c, uint8_t node_id);
/* A heartbeat of a watched node is due now: its monitoring starts as if one
 * had just come (LOST after its consumer time unless one does), for a node
 * that may already be gone (a flying master's slave watching the new active
 * master). False when the node has no entry with a time. */
bool co_hb_consumer_expect(co_hb_consumer_t *c, uint8_t node_id);
/* Stop watching a node (its entry becomes unused); harmless if not watched. */
void co_hb_consumer_unwatch(co_hb_consumer_t *c, uint8_t node_id);
/* 0x1016 value of an entry. */
uint32_t co_hb_consumer_get_entry(const co_hb_consumer_t *c, uint8_t index);
co_hb_monitor_t co_hb_consumer_monitor(const co_hb_consumer_t *c, uint8_t node_id);

/* Heartbeat frame helpers (one place for the wire format). */
bool co_hb_encode(co_nmt_state_t state, co_frame_t *frame, uint8_t node_id);
bool co_hb_state_is_valid(uint8_t state);

#endif
