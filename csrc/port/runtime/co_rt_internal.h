/* Runtime internals shared by its source files, one file per concern:
 *   co_runtime.c     life cycle (new, start, stop, free), error text, clock
 *   co_rt_loop.c     the thread: turns, wake-ups, kicks, transfer-end waits; it
 *                    sleeps in one of two waiters:
 *   co_rt_wait_portable.c  a condition variable until the next deadline (any OS)
 *   ../linux/co_rt_wait_epoll.c  epoll + timerfd + eventfd (Linux; SocketCAN needs it)
 *   co_rt_mailbox.c  commands in (a bounded ring with its own lock)
 *   co_rt_events.c   events out (a bounded ring, the "events lost" marker)
 *   co_rt_lines.c    adding a line: queues, the stack, its driver
 *   co_rt_membus.c, co_rt_host.c, ../linux/co_rt_socketcan.c   one file per driver
 *   co_rt_commands.c checking and applying mailbox commands
 *   co_rt_node.c     the local node: creation, its OD hooks, NMT/heartbeat view
 *   co_rt_od.c, co_rt_store.c, co_rt_client.c        OD access, app store, clients
 *   co_rt_emcy.c, co_rt_pdo.c, co_rt_sync.c, co_rt_time.c, co_rt_guard.c,
 *   co_rt_sleep.c, co_rt_srdo.c
 *                    one service's runtime glue each (its state: rt_<service>_t)
 *   co_rt_stats.c    counter snapshots
 * The OS itself is reached through co_rt_os.h only (../posix, ../windows).
 * Not part of the Python API. */
#ifndef CO_RT_INTERNAL_H
#define CO_RT_INTERNAL_H

#include "canopenfd/co_runtime.h"

#include "canopenfd/co_stack.h"
#include "canopenfd/co_node.h"
#include "canopenfd/co_od.h"
#include "canopenfd/co_store.h"
#include "canopenfd/co_sdo_client.h"
#include "canopenfd/co_sdo_server.h"
#include "canopenfd/co_usdo_client.h"
#include "canopenfd/co_usdo_server.h"
#include "canopenfd/co_store_file.h"
#include "canopenfd/co_membus.h"
#include "canopenfd/co_redundancy.h"
#include "canopenfd/co_socketcan.h"
#include "canopenfd/co_cia402_sim.h"

#include "co_rt_os.h"

#include <stdbool.h>
#include <stdint.h>

enum {
    RT_MAX_LINES = 64,
    RT_MAX_BUSES = 64,
    RT_DEFAULT_QUEUE = 1024,
    RT_MAX_QUEUE = 1 << 20,
    RT_DEFAULT_EVENT_BYTES = 2 << 20, /* default event queue: what 2 MiB hold (~20 000) */
    RT_MAX_EVENT_CAPACITY = 1 << 22,
    RT_COALESCE_SLOTS = 1024,     /* sources (PDOs) the event queue can coalesce at once */
    RT_COALESCE_PROBES = 8,
    RT_MAILBOX_SIZE = 1024,
    RT_MAIL_CHUNK = 64,
    RT_TRANSFER_ROUNDS = 16,
    RT_EPOLL_BATCH = 32,
    RT_ERROR_SIZE = 256,
    /* the gateway's buffer for SDO transfers into fd networks: the largest
     * value a classic client moves through it */
    RT_GATEWAY_SDO_BUFFER = 64 * 1024,
    RT_CHANNEL_SIZE = 64,
    RT_INDICATIONS = 16,          /* key ranges with Python indications */
    RT_DOMAINS = 8,               /* memory-backed DOMAIN entries per node */
    /* the stack's parts, indications, domains, app store (2), simulated drive (1) */
    RT_OD_SUBSCRIPTIONS = CO_STACK_OD_SUBSCRIPTIONS + RT_INDICATIONS + RT_DOMAINS + 2 + 1 +
                          CO_GATEWAY_OD_SUBSCRIPTIONS,
    RT_GUARD_NODES = 32,          /* remote nodes guarded by a classic line */
    RT_PDO_WATCHES = 64,          /* CAN-IDs of other nodes' PDOs Python hears */
    RT_RPDO_PRODUCERS = 32,       /* other nodes' RPDOs the line produces (a master) */
    RT_REQUESTS = 32              /* network accesses waiting on Python at once */
};

#define RT_REOPEN_US 500000u       /* retry period for a vanished interface */
#define RT_NOBUFS_RETRY_US 1000u   /* ENOBUFS does not wake EPOLLOUT: poll instead */

/* The environment variable that selects the portable loop on Linux. */
#define RT_PORTABLE_LOOP_ENV "CANOPENFD_PORTABLE_LOOP"

enum { TAG_WAKE = 1, TAG_TIMER = 2, TAG_SOCKET = 3 };

struct rt_line;

/* What an epoll event points at. */
typedef struct rt_tag {
    int kind;
    struct rt_line *line;
} rt_tag_t;

typedef struct rt_bus {
    char name[RT_CHANNEL_SIZE];
    co_mode_t mode;
    co_membus_t bus;
} rt_bus_t;

typedef struct rt_socket {
    co_socketcan_t sock;
    rt_tag_t tag;
    bool down;             /* closed after the interface went away */
    bool want_out;         /* EAGAIN: waiting for EPOLLOUT */
    uint64_t reopen_at;
    uint64_t retry_at;     /* ENOBUFS: send again at this time */
    uint32_t tx_refused;   /* frames the kernel refused (reported as TX_OVERFLOW) */
    uint32_t down_count;
} rt_socket_t;

typedef struct rt_host {
    rt_mutex_t lock;
    rt_cond_t ready;       /* frames for co_rt_host_transmit */
    rt_cond_t room;        /* the runtime thread drained the line's rx queue */
    co_frame_queue_t out;  /* frames for co_rt_host_transmit */
    co_frame_t *slots;
    uint32_t waiters;      /* threads in co_rt_host_transmit */
    uint32_t rx_waiters;   /* threads in co_rt_host_receive_frames waiting for room */
    uint32_t rx_gen;       /* bumped each time room is signalled */
    uint32_t rx_waits;     /* times a receive found the rx queue full and waited */
    uint32_t rx_frames;    /* frames co_rt_host_receive(_frames) queued */
    uint32_t rx_calls;     /* calls that queued frames (frames per call: batching) */
    uint32_t tx_frames;    /* frames co_rt_host_transmit handed out */
    uint32_t tx_calls;     /* calls that handed frames out */
    uint32_t posted;       /* CO_CMD_SEND_FRAMEs in the mailbox, not applied yet */
    uint32_t line_tx;      /* the line's tx count: set by each flush, + each applied
                              SEND_FRAME (posted + line_tx: what the tx queue gets) */
    uint32_t tx_limit;     /* posted + line_tx above it: SEND_FRAME refused */
    bool stalled;          /* the line holds frames the full out-queue refused */
    bool closed;
} rt_host_t;

/* A key range whose network reads and/or writes wait on Python. */
typedef struct rt_indication {
    struct rt_line *line;
    uint8_t kinds;           /* CO_RT_INDICATE_READ | CO_RT_INDICATE_WRITE */
} rt_indication_t;

/* A network access parked (CO_OD_SPLIT) until Python answers it. */
typedef struct rt_request {
    co_od_xfer_t *xfer;      /* NULL: slot free */
    const uint8_t *value;    /* check-write: the new value (the server's scratch) */
    uint32_t length;
    uint16_t generation;     /* a stale token does not match a reused slot */
} rt_request_t;

/* A parameter store kept by the application (Python): the runtime loads
 * from a RAM copy of the saved image and stages each new image until the
 * application reports it persisted (then it becomes the RAM copy). */
typedef struct rt_app_store {
    bool enabled;
    co_store_status_t status;    /* what the application's load found */
    uint8_t *committed;          /* the image the application has (status OK) */
    uint32_t committed_length;
    uint8_t *staged;             /* a saved image not yet persisted */
    uint32_t staged_length;
    uint32_t staged_capacity;
    bool staged_pending;
    bool staged_autonomous;      /* the stack's autonomous save staged it */
} rt_app_store_t;

/* A DOMAIN entry whose data the runtime keeps in memory (co_rt_od_domain). */
typedef struct rt_domain {
    struct rt_line *line;
    uint32_t key;            /* index << 8 | sub */
    uint8_t *data;
    uint32_t size;           /* bytes held (0 while a download fills it) */
    uint32_t filled;         /* bytes of the download in progress */
    uint32_t capacity;
} rt_domain_t;

/* PDO glue (co_rt_pdo.c). Per line: PDOs of other nodes that Python hears
 * (CO_EV_PDO_FRAME): CAN-ID, with bit 29 for a 29-bit one; watch_of maps an
 * 11-bit id to its slot + 1. Per local node: the RPDOs Python listens to. */
typedef struct rt_pdo {
    uint32_t watch_ids[RT_PDO_WATCHES];
    uint32_t watch_frames[RT_PDO_WATCHES];   /* frames seen per watch */
    uint8_t watch_count;
    uint8_t watch_of[CO_LINE_ID_MAP_SIZE];
    bool listen[CO_PDO_MAX_NUMBER];          /* by RPDO number - 1 */
    bool mpdo_events;                        /* CO_EV_MPDO wanted (co_rt_mpdo_listen) */
} rt_pdo_t;

/* One RPDO of another node that this line produces (co_rt_rpdo_out.c): the
 * mapped bytes, written by the application under rt->lock (so a frame never
 * carries half an update), and what makes it go out: once, every n-th SYNC
 * (or, acyclic, the first SYNC after a change), every period_us. */
typedef struct rt_rpdo_out {
    struct rt_line *line;
    bool used;
    uint32_t can_id;         /* bit 29 set: a 29-bit CAN-ID */
    uint8_t length;          /* bytes (1..8 classic, 1..64 fd) */
    uint8_t data[64];
    uint8_t sync_every;      /* 0: not on SYNC; n: after every n-th SYNC */
    bool sync_acyclic;       /* only the first SYNC after a change (type 0) */
    bool changed;            /* written since it was last sent */
    uint8_t sync_seen;       /* SYNCs since the last SYNC-driven send */
    uint32_t period_us;      /* 0: not periodic */
    co_timer_t timer;
    co_rt_rpdo_stats_t stats;
} rt_rpdo_out_t;

/* SYNC glue (co_rt_sync.c). */
typedef struct rt_sync {
    bool events;                             /* Python hears every SYNC */
} rt_sync_t;

/* The line's LSS master glue (co_rt_lss.c): what the last request found. */
typedef struct rt_lss {
    bool finished;                   /* a request finished since the line opened */
    co_lss_master_result_t result;
    uint8_t node_ids[127];           /* the running fast scan's list */
    co_lss_device_t devices[127];
    /* the local node's slave */
    co_lss_slave_indications_t slave_ind;
    bool store_by_app;
    uint32_t bit_timings;            /* bit n: table 0 index n accepted */
} rt_lss_t;
/* Bus redundancy glue (co_rt_redundancy.c): the two buses, in-process
 * buses or SocketCAN interfaces. */
typedef struct rt_redundancy {
    struct rt_bus *bus[2];                   /* mem: lines */
    char iface[2][RT_CHANNEL_SIZE];          /* SocketCAN lines */
} rt_redundancy_t;
/* Sleep and wake-up glue (co_rt_sleep.c). */
typedef struct rt_sleep {
    uint8_t objection;                       /* the device's answer to a query */
} rt_sleep_t;
/* LED glue (co_rt_led.c). */
typedef struct rt_led {
    bool events;                             /* Python hears every LED change */
} rt_led_t;

typedef struct rt_line {
    co_rt_t *rt;
    int index;
    int driver;
    bool monitor;
    bool allow_operational;
    char channel[RT_CHANNEL_SIZE];
    co_line_t line;
    co_frame_t *rx_slots;
    co_frame_t *tx_slots;
    uint32_t rx_seen;      /* rx frames already posted as CO_EV_FRAME */
    /* The line's services and its local node, assembled by the core
     * (co_stack): heartbeat consumer, SYNC, TIME, EMCY consumer, guarding
     * master; the node with its EMCY producer, PDOs, guarding slave and
     * SDO/USDO server; the client. */
    co_stack_t stack;
    /* The local node's object dictionary (co_rt_od_define) and its store. */
    bool has_od;
    co_od_t od;
    co_od_entry_t *od_entries;
    uint8_t *od_pool;
    uint32_t od_spare_entries;       /* co_rt_od_reserve: room for co_rt_od_add */
    uint32_t od_spare_bytes;
    co_od_subscription_t od_subs[RT_OD_SUBSCRIPTIONS];
    rt_indication_t indications[RT_INDICATIONS];
    uint8_t indication_count;
    rt_request_t requests[RT_REQUESTS];
    rt_domain_t domains[RT_DOMAINS];
    uint8_t domain_count;
    char *store_path;                /* file store, or NULL */
    rt_app_store_t app_store;        /* application store (instead of a file) */
    co_store_group_t *store_groups;  /* declared parameter groups, or NULL: the default */
    uint8_t store_group_rows;
    uint32_t store_min_interval_ms;
    co_store_file_t *store_file;
    struct rt_client *client;        /* USDO/SDO client: created at the first transfer */
    /* Runtime state of the services' glue (EMCY, TIME and guarding keep none). */
    rt_pdo_t pdo;
    rt_rpdo_out_t rpdo_out[RT_RPDO_PRODUCERS];
    rt_sync_t sync;
    rt_sleep_t sleep;
    rt_redundancy_t redundancy;
    rt_socket_t sc;
    rt_host_t host;
    rt_led_t led;
    struct rt_config *config;        /* configurations (co_rt_config.c): at the first one */
    co_cia402_sim_t *cia402;         /* simulated drive (co_rt_cia402.c), or NULL */
    rt_lss_t lss;
    /* gateway (co_rt_gateway.c): the network-id (0: not joined) and the
     * 0x1F2F routes given through the API, kept across rebuilds */
    uint8_t network_id;
    uint32_t emcy_routes[CO_GATEWAY_NETWORKS];
} rt_line_t;

/* The Linux waiter (co_rt_wait_epoll.c): epoll over the sockets, a timerfd
 * at the earliest deadline, an eventfd for wake-ups. */
typedef struct rt_epoll_waiter {
    int epfd;
    int wakefd;
    int timerfd;
    rt_tag_t wake_tag;
    rt_tag_t timer_tag;
} rt_epoll_waiter_t;

/* The portable waiter (co_rt_wait_portable.c): a condition variable waited
 * on until the deadline, signalled by rt_wake and by an earlier deadline. */
typedef struct rt_portable_waiter {
    rt_mutex_t lock;
    rt_cond_t wake;
    bool woken;
    uint64_t deadline;     /* CO_TIME_NEVER: none */
} rt_portable_waiter_t;

/* The latest queued event of one coalescable source (see co_rt_events.c). */
typedef struct rt_coalesce_slot {
    uint64_t key;          /* line, kind and a of the source; 0 = never used */
    uint64_t seq;          /* its sequence number (still queued while >= popped) */
} rt_coalesce_slot_t;

typedef struct rt_events {
    rt_mutex_t lock;
    rt_cond_t ready;
    co_rt_event_t *ring;
    rt_coalesce_slot_t *slots;  /* RT_COALESCE_SLOTS, open addressing */
    uint32_t capacity;
    uint32_t high_water;   /* from this many queued events on, sources coalesce */
    uint32_t head;
    uint32_t count;
    uint32_t reached;      /* slots written since the ring was last trimmed (0..capacity) */
    uint64_t pushed;       /* events ever queued: the next one's sequence number */
    uint32_t lost;         /* dropped since the last CO_EV_EVENTS_LOST */
    uint32_t waiters;
    bool closed;
    co_rt_event_stats_t line_stats[RT_MAX_LINES];
} rt_events_t;

typedef struct rt_mailbox {
    rt_mutex_t lock;
    co_rt_command_t ring[RT_MAILBOX_SIZE];
    uint32_t head;
    uint32_t count;
    bool closed;
} rt_mailbox_t;

struct co_rt {
    rt_mutex_t life_lock;
    rt_mutex_t lock;
    rt_mutex_t error_lock;
    rt_thread_t thread;
    bool started;
    bool closed;           /* stopped for good (under life_lock) */
    bool stopping;         /* under lock: refuse host calls, leave the loop */
    /* What the thread sleeps on: epoll (Linux, unless RT_PORTABLE_LOOP_ENV
     * is 1) or the portable waiter; fixed at co_rt_new. */
    bool portable_loop;
    rt_epoll_waiter_t epoll;
    rt_portable_waiter_t portable;
    uint64_t armed_us;     /* deadline the waiter's timer holds */
    uint32_t wakeups;      /* the thread woke with something to do */
    int line_count;        /* published with release ordering after lines[] */
    rt_line_t *lines[RT_MAX_LINES];
    int bus_count;
    rt_bus_t *buses[RT_MAX_BUSES];
    rt_mailbox_t mail;
    rt_events_t events;
    co_gateway_t gateway;  /* between the joined lines (co_rt_gateway.c), under lock */
    /* SDO networking into fd networks: one translated transfer at a time
     * goes through it (co_gateway_set_sdo_buffer) */
    uint8_t gateway_sdo_buf[RT_GATEWAY_SDO_BUFFER];
    /* Client transfers that ended: done_gen counts them, done_ready wakes
     * threads blocked in co_rt_transfer_wait (own lock: never waits for a
     * turn of the runtime thread). */
    rt_mutex_t done_lock;
    rt_cond_t done_ready;
    uint64_t done_gen;
    bool done_closed;
    char error[RT_ERROR_SIZE];
};

/* ---------------------------------------------------------------- co_runtime.c */
RT_PRINTF_FORMAT(2, 3)
void rt_set_error(co_rt_t *rt, const char *fmt, ...);
/* Sets the error text and returns CO_RT_ERR_ARGUMENT. */
RT_PRINTF_FORMAT(2, 3)
int rt_argument_error(co_rt_t *rt, const char *fmt, ...);
/* Memory of the stack's parts: from the heap, at set-up only. */
extern const co_stack_allocator_t rt_heap;
/* The deadline of a wait of timeout_ms (< 0: none) from now. */
uint64_t rt_deadline_after_ms(int timeout_ms);
/* One wait step: false once the timeout (< 0: none) has passed. */
bool rt_wait_step(rt_cond_t *cond, rt_mutex_t *lock, int timeout_ms, uint64_t deadline_us);

/* ---------------------------------------------------------------- co_rt_loop.c */
/* Open / close what the thread sleeps on (at co_rt_new / destroy). */
bool rt_loop_open(co_rt_t *rt);
void rt_loop_close(co_rt_t *rt);
/* The runtime thread's body. */
void rt_loop_main(void *arg);
/* Wake the thread (a deadline or the tx queue changed). */
void rt_wake(co_rt_t *rt);
/* Under rt->lock, from an application thread that just queued frames or
 * armed timers (a transfer started or cancelled): hand the frames to the
 * sockets and move the timer earlier at once, instead of waking the
 * runtime thread for it; wakes it only for lines only it can flush
 * (in-process buses, host lines). */
void rt_kick(co_rt_t *rt);
/* rt_kick, then release rt->lock; returns status (the API calls' tail). */
int rt_kick_unlock(co_rt_t *rt, int status);
/* Under rt->lock: a client transfer ended (wakes co_rt_transfer_wait). */
void rt_transfer_ended(co_rt_t *rt);
/* Block until done_gen differs from gen or timeout_ms passed (< 0: no
 * limit); false on timeout or when the runtime stopped. */
bool rt_wait_transfer_end(co_rt_t *rt, uint64_t gen, int timeout_ms);
uint64_t rt_transfer_generation(co_rt_t *rt);
/* Wake whoever waits for a transfer's end with CLOSED. */
void rt_transfer_waits_close(co_rt_t *rt);
/* Monitor lines: post the frames queued in rx not yet shown (any driver). */
void rt_post_new_rx(rt_line_t *l);

/* Process one line; returns when it needs to run again. Inline: the loop
 * runs it for every line in every round. */
static inline uint64_t rt_line_step(rt_line_t *l, uint64_t now)
{
    if (l->monitor) {
        rt_post_new_rx(l);
    }
    uint64_t next = co_line_process(&l->line, now);
    l->rx_seen = co_line_rx_count(&l->line);
    return l->rx_seen == 0 ? next : now;
}

static inline uint64_t rt_min_u64(uint64_t a, uint64_t b) { return a < b ? a : b; }

/* The waiters. open/close at co_rt_new/destroy; wake from any thread; arm
 * (under rt->lock) makes the thread wake at deadline; sleep is entered and
 * left with rt->lock held, released while asleep, and handles what woke it
 * (sockets ready, the timer fired: armed_us = CO_TIME_NEVER). */
bool rt_portable_open(co_rt_t *rt);
void rt_portable_close(co_rt_t *rt);
void rt_portable_wake(co_rt_t *rt);
void rt_portable_arm(co_rt_t *rt, uint64_t deadline);
void rt_portable_sleep(co_rt_t *rt);
#if CO_RT_HAVE_SOCKETCAN
bool rt_epoll_open(co_rt_t *rt);
void rt_epoll_close(co_rt_t *rt);
void rt_epoll_wake(co_rt_t *rt);
void rt_epoll_arm(co_rt_t *rt, uint64_t deadline, uint64_t now);
void rt_epoll_sleep(co_rt_t *rt);
#endif

/* ---------------------------------------------------------------- co_rt_mailbox.c */
/* Queue a validated command: CO_RT_OK, CO_RT_ERR_FULL or CO_RT_ERR_CLOSED. */
int rt_mailbox_post(rt_mailbox_t *m, const co_rt_command_t *command);
/* Take up to max commands in order; returns how many. */
uint32_t rt_mailbox_take(rt_mailbox_t *m, co_rt_command_t *out, uint32_t max);
void rt_mailbox_close(rt_mailbox_t *m);

/* ---------------------------------------------------------------- co_rt_events.c */
bool rt_events_open(rt_events_t *q, uint32_t capacity);
void rt_events_free(rt_events_t *q);
/* Post an event of line l; false when the queue was full (dropped, counted). */
bool rt_post(const rt_line_t *l, int kind, uint8_t node, uint32_t a, uint32_t b,
             const co_frame_t *frame);
/* Wake every waiter with CLOSED; how many still wait. */
void rt_events_close(rt_events_t *q);
/* The event counters of one line (under the queue's lock). */
co_rt_event_stats_t rt_events_line_stats(rt_events_t *q, int line);
uint32_t rt_events_waiters(rt_events_t *q);

/* ---------------------------------------------------------------- co_rt_lines.c */
/* The line, or NULL with the error set (host_only: host-driver lines only). */
rt_line_t *rt_checked_line(co_rt_t *rt, int line, bool host_only);
void rt_line_free(rt_line_t *l);

/* ---------------------------------------------------------------- co_rt_gateway.c */
/* Under rt->lock: join the lines with a network-id again (a local node was
 * created or set up by LSS); routes and API EMCY routes are kept. */
int rt_gateway_rebuild(co_rt_t *rt);

/* ---------------------------------------------------------------- drivers */
/* co_rt_membus.c: under rt->lock, join (or create) the line's named bus. */
int rt_membus_join(co_rt_t *rt, rt_line_t *l);
/* co_rt_membus.c: under rt->lock, the bus named name (created when new). */
int rt_membus_bus(co_rt_t *rt, const char *name, co_mode_t mode, rt_bus_t **out);
/* Move the frames of every bus; returns how many moved. */
uint32_t rt_membus_transfer(co_rt_t *rt);
void rt_membus_free_all(co_rt_t *rt);
/* co_rt_socketcan.c (Linux): SocketCAN lines. Elsewhere, and under the
 * portable loop, co_rt_add_line refuses them, so only the init, close and
 * the loop's calls (which find no SocketCAN line) remain, as no-ops. */
#if CO_RT_HAVE_SOCKETCAN
void rt_socket_init(rt_line_t *l);
/* Open the interface; CO_RT_OK or a status with the error set. */
int rt_socket_open(co_rt_t *rt, rt_line_t *l);
/* Under rt->lock: add the open socket to what the thread waits on. */
int rt_socket_register(co_rt_t *rt, rt_line_t *l);
void rt_socket_close(rt_line_t *l);
/* Re-open lost interfaces that are due. */
void rt_socket_reopen_due(co_rt_t *rt, uint64_t now);
/* The socket is readable / writable / failed (epoll events). */
void rt_socket_ready(co_rt_t *rt, rt_line_t *l, uint32_t events);
/* Send what the line queued; returns when to try again. */
uint64_t rt_socket_flush(co_rt_t *rt, rt_line_t *l, uint64_t now);
/* Bus redundancy: use interface iface instead of the one in use (l->channel
 * becomes iface); one that cannot be opened counts as lost: IFACE_DOWN, retried. */
void rt_socket_switch(co_rt_t *rt, rt_line_t *l, const char *iface);
/* CO_RT_OK when iface can be opened in mode, else the status with the error set. */
int rt_socket_probe(co_rt_t *rt, const char *iface, co_mode_t mode);
#else
static inline void rt_socket_switch(co_rt_t *rt, rt_line_t *l, const char *iface)
{
    (void)rt;
    (void)l;
    (void)iface;
}
static inline int rt_socket_probe(co_rt_t *rt, const char *iface, co_mode_t mode)
{
    (void)rt;
    (void)iface;
    (void)mode;
    return CO_RT_ERR_SOCKET;
}
static inline void rt_socket_init(rt_line_t *l) { l->sc.sock.fd = -1; }
static inline int rt_socket_register(co_rt_t *rt, rt_line_t *l)
{
    (void)rt;
    (void)l;
    return CO_RT_ERR_SOCKET;
}
static inline void rt_socket_close(rt_line_t *l) { (void)l; }
static inline void rt_socket_reopen_due(co_rt_t *rt, uint64_t now)
{
    (void)rt;
    (void)now;
}
static inline uint64_t rt_socket_flush(co_rt_t *rt, rt_line_t *l, uint64_t now)
{
    (void)rt;
    (void)l;
    (void)now;
    return CO_TIME_NEVER;
}
#endif
/* co_rt_host.c */
bool rt_host_init(rt_line_t *l, uint32_t capacity);
void rt_host_free(rt_line_t *l);
/* Hand the line's tx frames to co_rt_host_transmit's queue. */
void rt_host_flush(rt_line_t *l);
void rt_host_close(rt_line_t *l);
uint32_t rt_host_waiters(rt_line_t *l);
/* Host lines: reserve a tx slot for a CO_CMD_SEND_FRAME about to be posted;
 * false (refuse it) when the frames posted and queued reach 3/4 of the tx
 * queue (the python-can bus is slower than the sender). Always true for
 * other lines. rt_host_send_applied: the command was applied (queued or not). */
bool rt_host_reserve_send(rt_line_t *l);
void rt_host_send_unreserve(rt_line_t *l);
void rt_host_send_applied(rt_line_t *l, bool queued);

/* ---------------------------------------------------------------- co_rt_commands.c */
/* In the thread: carry out a mailbox command (a failure is posted). */
void rt_command_apply(co_rt_t *rt, const co_rt_command_t *cmd, uint64_t now);

/* ---------------------------------------------------------------- co_rt_node.c */
/* Under rt->lock: create and boot the line's local node (a = node-id,
 * b = heartbeat ms); on failure the line is left as it was. */
int rt_node_create(co_rt_t *rt, rt_line_t *l, const co_rt_command_t *cmd);
/* The line, locked, with a local node (or NULL with the error set, unlocked). */
rt_line_t *rt_node_line(co_rt_t *rt, int line, const char *what);

static inline bool rt_has_store(const rt_line_t *l)
{
    return l->store_path != NULL || l->app_store.enabled;
}

static inline bool rt_has_node(const rt_line_t *l)
{
    return co_stack_has_node(&l->stack);
}

/* ---------------------------------------------------------------- co_rt_od.c */
void rt_od_release(rt_line_t *l);
/* Park a network access until the application answers (CO_EV_OD_REQUEST
 * with this kind): CO_OD_SPLIT, or an abort code when it cannot wait. */
uint32_t rt_od_park(rt_line_t *l, co_od_xfer_t *xfer, uint32_t key, const uint8_t *value,
                    uint32_t length, uint8_t kind);
/* Forget every access waiting on Python (the servers holding them are gone). */
void rt_od_drop_requests(rt_line_t *l);
void rt_od_free_domains(rt_line_t *l);

/* ---------------------------------------------------------------- co_rt_store.c */
/* Stage buffers sized for the sealed OD (node attach); the image capacity
 * the store needs is put in *capacity. */
int rt_app_store_open(co_rt_t *rt, rt_line_t *l, uint32_t *capacity);
extern const co_store_backend_t rt_app_store_backend;
/* Subscribed after the node: network saves wait until the image persisted. */
bool rt_app_store_hook(rt_line_t *l);
/* co_stack_node_config_t.store_saved of an application store: an
 * autonomous save staged an image, the application persists it. */
void rt_app_store_autonomous(co_store_t *s, uint32_t abort, void *user);
/* The application's answer to a persist request: commit or drop the image;
 * returns the abort to resume the access with. */
uint32_t rt_app_store_persisted(rt_line_t *l, uint32_t abort);
void rt_app_store_free(rt_line_t *l);

/* ---------------------------------------------------------------- co_rt_client.c */
void rt_client_free(rt_line_t *l);
/* Under rt->lock: the line's core client (created at the first use), the
 * USDO one on fd lines, the SDO one on classic lines; false (error set)
 * when it cannot start. */
bool rt_client_cores(co_rt_t *rt, rt_line_t *l, co_usdo_client_t **usdo,
                     co_sdo_client_t **sdo);

/* ---------------------------------------------------------------- co_rt_config.c */
/* Before the client goes: running configurations end (nothing posted). */
void rt_config_free(rt_line_t *l);
void rt_cia402_free(rt_line_t *l);
/* Under rt->lock: the line's client exists (created now if needed); false
 * with the reason set. */
bool rt_client_ready(co_rt_t *rt, rt_line_t *l);

/* ---------------------------------------------------------------- services' glue */
/* The stack's indications that post to Python, one per service file. */
void rt_emcy_on_received(co_stack_t *stack, uint8_t node_id, const co_emcy_msg_t *msg,
                         void *user);
void rt_time_on_received(co_stack_t *stack, const co_time_of_day_t *tod, void *user);
/* co_rt_lss.c: the indications of the local node's LSS slave. */
const co_lss_slave_indications_t *rt_lss_slave_indications(rt_line_t *l);

void rt_guard_on_event(co_stack_t *stack, uint8_t node_id, co_guard_event_t event,
                       co_nmt_state_t state, void *user);
/* co_rt_pdo.c: before the stack, hear watched PDO frames before any
 * service takes them. */
bool rt_pdo_line_init(rt_line_t *l);
/* RPDO n was applied: posted to Python when it listens to it. */
void rt_pdo_received(rt_line_t *l, uint16_t number);
/* An MPDO addressed to the local node was applied (abort 0) or refused. */
void rt_mpdo_received(rt_line_t *l, uint16_t rpdo_number, const co_mpdo_msg_t *msg,
                      uint16_t index, uint8_t sub, uint32_t abort);
/* A node that could not be created: forget what Python listened to. */
void rt_pdo_node_detach(rt_line_t *l);
/* Frames seen on the watched CAN-IDs (service stats). */
uint32_t rt_pdo_watched_frames(const rt_line_t *l);
/* co_rt_rpdo_out.c: after the stack, the RPDO producers hear SYNC. */
bool rt_rpdo_out_line_init(rt_line_t *l);
/* co_rt_sync.c: after the stack, Python hears SYNC through a listener. */
bool rt_sync_line_init(rt_line_t *l);
/* co_rt_led.c: the node's LED indication (user = the rt_line_t), given to
 * co_stack at node creation while Python listens. */
void rt_led_changed(co_led_t *led, co_led_which_t which, bool on, co_led_pattern_t pattern,
                    void *user);

#endif
