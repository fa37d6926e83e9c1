/* A CAN line as the protocol core sees it: mode (classic or fd) fixed at init,
 * the local node-id, bounded rx/tx queues, a timer list, dispatch of received
 * frames by CAN-ID to the services, and communication-state events. */
#ifndef CO_LINE_H
#define CO_LINE_H

#include "canopenfd/co_assert.h"
#include "canopenfd/co_frame.h"
#include "canopenfd/co_queue.h"
#include "canopenfd/co_timer.h"

/* cffi:begin */
typedef enum co_mode {
    CO_MODE_CLASSIC = 0,
    CO_MODE_FD = 1
} co_mode_t;

/* Communication-state events, reported to the line's indication. */
typedef enum co_comm_event {
    CO_COMM_BUS_OFF = 1,
    CO_COMM_ERROR_PASSIVE = 2,
    CO_COMM_ERROR_ACTIVE = 3,      /* back to error active (recovered) */
    CO_COMM_RX_OVERFLOW = 4,       /* a received frame was lost */
    CO_COMM_TX_OVERFLOW = 5,       /* a frame to send was lost */
    CO_COMM_TX_QUEUE_FULL = 6,
    CO_COMM_TX_QUEUE_EMPTY = 7,
    CO_COMM_IFACE_DOWN = 8,        /* the interface went away or down */
    CO_COMM_IFACE_UP = 9,          /* ... and is back */
    CO_COMM_ERROR_WARNING = 10,
    CO_COMM_BUS_OFF_RECOVERED = 11
} co_comm_event_t;

/* Per-line statistics: everything ignored is counted here, never silent. */
typedef struct co_line_stats {
    uint32_t rx_frames;            /* frames handed to co_line_receive */
    uint32_t tx_frames;            /* frames taken by the driver */
    uint32_t rx_overflow;          /* rx queue full: frame lost */
    uint32_t tx_overflow;          /* tx queue full: frame lost */
    uint32_t rx_unhandled;         /* no service listens on that CAN-ID */
    uint32_t rx_invalid;           /* malformed frame (bad id/length/flags) */
    uint32_t rx_wrong_format;      /* FD frame on a classic line */
    uint32_t rx_rtr;               /* remote frames nobody answers */
    uint32_t tx_invalid;           /* frames a service or tool tried to send malformed */
    uint32_t nmt_bad_length;
    uint32_t nmt_bad_command;
    uint32_t nmt_bad_node;
    uint32_t hb_bad_length;
    uint32_t hb_bad_state;
    uint32_t hb_bad_node;
    uint32_t tx_silenced;          /* frames not sent because the line was silent (sleep) */
} co_line_stats_t;
/* cffi:end */

typedef struct co_line co_line_t;

/* Receive handler of a service. */
typedef void (*co_rx_fn)(co_line_t *line, const co_frame_t *frame, void *user);
typedef void (*co_comm_fn)(co_line_t *line, co_comm_event_t event, void *user);
/* "tx space" indication: the tx queue went from above half full to half
 * full (called from co_line_tx_pop, i.e. from the driver). */
typedef void (*co_tx_space_fn)(co_line_t *line, void *user);
/* Receiver of frames no CAN-ID range takes (see co_line_subscribe_other):
 * returns true when it used the frame. */
typedef bool (*co_rx_other_fn)(co_line_t *line, const co_frame_t *frame, void *user);

enum { CO_LINE_MAX_RECEIVERS = 32, CO_LINE_ID_MAP_SIZE = 2048, CO_LINE_MAX_TX_SPACE = 4,
       CO_LINE_MAX_OTHER = 4 };

typedef struct co_receiver {
    uint32_t first_id;   /* inclusive range of 11-bit CAN-IDs */
    uint32_t last_id;
    co_rx_fn fn;
    void *user;
} co_receiver_t;

typedef struct co_tx_space_cb {
    co_tx_space_fn fn;
    void *user;
} co_tx_space_cb_t;

typedef struct co_other_receiver {
    co_rx_other_fn fn;
    void *user;
} co_other_receiver_t;

/* Public because callers own its storage (no allocation). A caller may read
 * mode, node_id, now_us and stats (the accessors below say the same); the
 * rest is co_line.c's own. No field is written outside co_line.c: services,
 * drivers and the runtime go through the functions and accessors below. */
struct co_line {
    co_mode_t mode;
    uint8_t node_id;              /* 0 = no local node yet */
    uint8_t tx_flags;             /* flags added to every sent frame (FD, BRS) */
    bool tx_was_full;
    co_frame_queue_t rx;
    co_frame_queue_t tx;
    co_timer_list_t timers;
    co_line_stats_t stats;
    uint64_t now_us;              /* time of the current process() call */
    co_comm_fn on_comm;
    void *comm_user;
    uint8_t receiver_count;
    co_receiver_t receivers[CO_LINE_MAX_RECEIVERS];
    uint8_t id_map[CO_LINE_ID_MAP_SIZE];   /* CAN-ID -> receiver index + 1 */
    uint8_t tx_space_count;
    co_tx_space_cb_t tx_space[CO_LINE_MAX_TX_SPACE];
    uint8_t other_count;
    co_other_receiver_t other[CO_LINE_MAX_OTHER];
    bool silent;                  /* co_line_set_silent: nothing is queued for sending */
    co_rx_fn rx_watch;            /* co_line_watch_rx: sees every valid received frame */
    void *rx_watch_user;
};

typedef struct co_line_config {
    co_mode_t mode;
    bool brs;                     /* FD lines: send with bit-rate switch */
    co_frame_t *rx_slots;
    uint32_t rx_capacity;
    co_frame_t *tx_slots;
    uint32_t tx_capacity;
} co_line_config_t;

/* Returns false for an invalid configuration (no queue storage, unknown mode). */
bool co_line_init(co_line_t *line, const co_line_config_t *config);
void co_line_set_comm_indication(co_line_t *line, co_comm_fn fn, void *user);
/* The local node-id (1..127, 0 = none): co_node sets it; a server used
 * without a co_node (tools, tests) sets it itself. */
void co_line_set_node_id(co_line_t *line, uint8_t node_id);

/* Malformed NMT and heartbeat frames, counted in the line's statistics by
 * the services that decode them. */
typedef enum co_line_reject {
    CO_LINE_NMT_BAD_LENGTH,
    CO_LINE_NMT_BAD_COMMAND,
    CO_LINE_NMT_BAD_NODE,
    CO_LINE_HB_BAD_LENGTH,
    CO_LINE_HB_BAD_STATE,
    CO_LINE_HB_BAD_NODE
} co_line_reject_t;
void co_line_count_rejected(co_line_t *line, co_line_reject_t reason);

/* Services register for an inclusive range of 11-bit CAN-IDs. A range that
 * overlaps an existing one, or a full table, returns false. */
bool co_line_subscribe(co_line_t *line, uint32_t first_id, uint32_t last_id,
                       co_rx_fn fn, void *user);
void co_line_unsubscribe(co_line_t *line, co_rx_fn fn, void *user);

/* Services whose CAN-IDs are many and configurable (PDOs, EMCY consumers) or
 * that answer remote frames (TPDOs with RTR, node guarding) register here:
 * they are offered every valid frame no subscribed range takes, i.e. data
 * frames with an 11-bit id nobody subscribed, data frames with a 29-bit id,
 * and every remote (RTR) frame, whatever its id. Offered in registration
 * order until one returns true; a frame nobody takes is counted (rx_rtr for
 * remote frames, rx_unhandled otherwise). At most CO_LINE_MAX_OTHER; false
 * when full, fn is NULL or (fn, user) is already registered. */
bool co_line_subscribe_other(co_line_t *line, co_rx_other_fn fn, void *user);
void co_line_unsubscribe_other(co_line_t *line, co_rx_other_fn fn, void *user);

/* Services that fill the tx queue in bursts (USDO bulk download) register
 * here to learn when it has drained: fn runs inside co_line_tx_pop each time
 * a pop takes the queue from above half full to half full (count ==
 * capacity / 2 after the pop), so a service that stopped at more than half
 * full always hears of it. fn runs in the driver's context: it should only
 * note the fact (arm a timer due now, say) and send from co_line_process.
 * fn must not register or unregister. At most CO_LINE_MAX_TX_SPACE
 * registrations; false when full, fn is NULL or (fn, user) is already
 * registered. */
bool co_line_tx_space_register(co_line_t *line, co_tx_space_fn fn, void *user);
void co_line_tx_space_unregister(co_line_t *line, co_tx_space_fn fn, void *user);

/* Driver side: queue a received frame (false + rx overflow event when full). */
bool co_line_receive(co_line_t *line, const co_frame_t *frame);
/* Take the oldest received frame without dispatching it (a capture line of
 * a tool or test that handles frames itself); false when none. */
bool co_line_rx_pop(co_line_t *line, co_frame_t *out);
/* Driver side: next frame to transmit, false when none. out may be NULL: the
 * frame is only taken (a driver that sent it from co_line_tx_at). */
bool co_line_tx_pop(co_line_t *line, co_frame_t *out);
/* Driver side: report a communication-state change. */
void co_line_comm_event(co_line_t *line, co_comm_event_t event);

/* Silence the line (the sleep service's silent phase): frames queued for
 * sending are dropped and no new ones are taken, each counted in
 * tx_silenced; receiving goes on. */
void co_line_set_silent(co_line_t *line, bool silent);
static inline bool co_line_is_silent(const co_line_t *line) { return line->silent; }
/* One watcher (NULL: none) that sees every valid received frame before it is
 * dispatched: the sleep service wakes on bus traffic with it. */
void co_line_watch_rx(co_line_t *line, co_rx_fn fn, void *user);

/* Service side: queue a frame for transmission. On fd lines the line adds its
 * FD/BRS flags and rounds the length up (zero padding); RTR frames stay
 * classic. False when the frame is invalid (bad id, too long, FD on a classic
 * line; counted in tx_invalid) or the tx queue is full (counted, event). */
bool co_line_send(co_line_t *line, uint32_t id, const uint8_t *data, size_t len);
bool co_line_send_frame(co_line_t *line, const co_frame_t *frame);
/* Tools and tests: queue a frame exactly as given (a classic frame on an fd
 * line, say); refused like above when invalid for the line. */
bool co_line_send_raw(co_line_t *line, const co_frame_t *frame);

/* Drain rx, run due timers; returns the next deadline (CO_TIME_NEVER if none).
 * now_us must not go backwards. Services arm timers relative to the time of
 * the last process() call (or co_line_set_time), so a caller that changes a
 * service between calls sets the time first. */
uint64_t co_line_process(co_line_t *line, uint64_t now_us);

/* Move the line's clock forward without processing (never backwards). */
static inline void co_line_set_time(co_line_t *line, uint64_t now_us)
{
    if (now_us > line->now_us) {
        line->now_us = now_us;
    }
}

static inline co_timer_list_t *co_line_timers(co_line_t *line) { return &line->timers; }

/* ------------------------------------------------------------ reading a line
 * Inline and free: services call them per frame. */

static inline co_mode_t co_line_mode(const co_line_t *line) { return line->mode; }
/* 0 while the line has no local node. */
static inline uint8_t co_line_node_id(const co_line_t *line) { return line->node_id; }
/* Time of the current co_line_process call (or of co_line_set_time). */
static inline uint64_t co_line_now(const co_line_t *line) { return line->now_us; }
static inline const co_line_stats_t *co_line_stats(const co_line_t *line) { return &line->stats; }

/* Received frames waiting for co_line_process; i-th from the oldest, i below
 * the count (a monitor shows them before they are dispatched). */
static inline uint32_t co_line_rx_count(const co_line_t *line)
{
    return co_queue_count(&line->rx);
}

static inline uint32_t co_line_rx_free(const co_line_t *line) { return co_queue_room(&line->rx); }

static inline const co_frame_t *co_line_rx_at(const co_line_t *line, uint32_t i)
{
    return co_queue_at(&line->rx, i);
}

/* Frames waiting for the driver; i-th from the oldest, i below the count (a
 * driver copies a batch and pops what the hardware took). */
static inline uint32_t co_line_tx_count(const co_line_t *line)
{
    return co_queue_count(&line->tx);
}

static inline const co_frame_t *co_line_tx_at(const co_line_t *line, uint32_t i)
{
    return co_queue_at(&line->tx, i);
}

/* Frames a service sending in bursts (block and bulk transfers) may still
 * queue now: the last quarter of the tx queue stays free for the others
 * (heartbeat, PDOs, other transfers' answers). 0 = wait for the tx-space
 * indication. */
static inline uint32_t co_line_tx_room(const co_line_t *line)
{
    uint32_t limit = line->tx.capacity - line->tx.capacity / 4u;
    uint32_t count = co_queue_count(&line->tx);
    return count < limit ? limit - count : 0;
}

/* Whether a subscribed range takes 11-bit CAN-ID id (id < 2048), and
 * whether that subscriber is (fn, user). */
static inline bool co_line_id_taken(const co_line_t *line, uint32_t id)
{
    CO_ASSERT(id < CO_LINE_ID_MAP_SIZE);
    return line->id_map[id] != 0;
}

static inline bool co_line_id_taken_by(const co_line_t *line, uint32_t id, co_rx_fn fn,
                                       const void *user)
{
    CO_ASSERT(id < CO_LINE_ID_MAP_SIZE);
    uint8_t slot = line->id_map[id];
    return slot != 0 && line->receivers[slot - 1u].fn == fn &&
           line->receivers[slot - 1u].user == user;
}

/* Whether co_line_subscribe has a receiver left (the ids must be free too). */
static inline bool co_line_receiver_free(const co_line_t *line)
{
    return line->receiver_count < CO_LINE_MAX_RECEIVERS;
}

#endif
