/* Linux runtime internals shared by its source files (co_runtime.c: thread,
 * lines, drivers, commands; co_rt_od.c: the local node's object dictionary
 * and its Python indications). Not part of the Python API. */
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
#include "canopenfd/co_socketcan.h"

#include <pthread.h>
#include <stdbool.h>
#include <stdint.h>

enum {
    RT_MAX_LINES = 64,
    RT_MAX_BUSES = 64,
    RT_DEFAULT_QUEUE = 1024,
    RT_MAX_QUEUE = 1 << 20,
    RT_DEFAULT_EVENTS = 4096,
    RT_MAX_EVENT_CAPACITY = 1 << 22,
    RT_MAILBOX_SIZE = 1024,
    RT_MAIL_CHUNK = 64,
    RT_TRANSFER_ROUNDS = 16,
    RT_EPOLL_BATCH = 32,
    RT_ERROR_SIZE = 256,
    RT_CHANNEL_SIZE = 64,
    RT_INDICATIONS = 16,          /* key ranges with Python indications */
    RT_DOMAINS = 8,               /* memory-backed DOMAIN entries per node */
    /* the stack's parts, indications, domains, app store (2) */
    RT_OD_SUBSCRIPTIONS = CO_STACK_OD_SUBSCRIPTIONS + RT_INDICATIONS + RT_DOMAINS + 2,
    RT_GUARD_NODES = 32,          /* remote nodes guarded by a classic line */
    RT_PDO_WATCHES = 64,          /* CAN-IDs of other nodes' PDOs Python hears */
    RT_REQUESTS = 32              /* network accesses waiting on Python at once */
};

#define RT_REOPEN_US 500000u       /* retry period for a vanished interface */
#define RT_NOBUFS_RETRY_US 1000u   /* ENOBUFS does not wake EPOLLOUT: poll instead */

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
    pthread_mutex_t lock;
    pthread_cond_t ready;
    co_frame_queue_t out;  /* frames for co_rt_host_transmit */
    co_frame_t *slots;
    uint32_t waiters;
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
    co_od_subscription_t od_subs[RT_OD_SUBSCRIPTIONS];
    rt_indication_t indications[RT_INDICATIONS];
    uint8_t indication_count;
    rt_request_t requests[RT_REQUESTS];
    rt_domain_t domains[RT_DOMAINS];
    uint8_t domain_count;
    char *store_path;                /* file store, or NULL */
    rt_app_store_t app_store;        /* application store (instead of a file) */
    co_store_file_t *store_file;
    struct rt_client *client;        /* USDO/SDO client: created at the first transfer */
    /* Process data and errors (co_rt_services.c). Per line: */
    bool sync_events;                /* Python hears every SYNC */
    /* PDOs of other nodes that Python hears (CO_EV_PDO_FRAME): CAN-ID, with
     * bit 29 for a 29-bit one; watch_of maps an 11-bit id to its slot + 1. */
    uint32_t watch_ids[RT_PDO_WATCHES];
    uint32_t watch_frames[RT_PDO_WATCHES];   /* frames seen per watch */
    uint8_t watch_count;
    uint8_t watch_of[CO_LINE_ID_MAP_SIZE];
    /* ... and per local node: */
    bool pdo_listen[CO_PDO_MAX_NUMBER];   /* RPDOs Python listens to, by number - 1 */
    rt_socket_t sc;
    rt_host_t host;
} rt_line_t;

typedef struct rt_events {
    pthread_mutex_t lock;
    pthread_cond_t ready;
    co_rt_event_t *ring;
    uint32_t capacity;
    uint32_t head;
    uint32_t count;
    uint32_t lost;         /* dropped since the last CO_EV_EVENTS_LOST */
    uint32_t waiters;
    bool closed;
} rt_events_t;

typedef struct rt_mailbox {
    pthread_mutex_t lock;
    co_rt_command_t ring[RT_MAILBOX_SIZE];
    uint32_t head;
    uint32_t count;
    bool closed;
} rt_mailbox_t;

struct co_rt {
    pthread_mutex_t life_lock;
    pthread_mutex_t lock;
    pthread_mutex_t error_lock;
    pthread_t thread;
    bool started;
    bool closed;           /* stopped for good (under life_lock) */
    bool stopping;         /* under lock: refuse host calls, leave the loop */
    int epfd;
    int wakefd;
    int timerfd;
    rt_tag_t wake_tag;
    rt_tag_t timer_tag;
    uint64_t armed_us;     /* deadline the timerfd holds */
    uint32_t wakeups;      /* epoll_wait returns with something ready */
    int line_count;        /* published with release ordering after lines[] */
    rt_line_t *lines[RT_MAX_LINES];
    int bus_count;
    rt_bus_t *buses[RT_MAX_BUSES];
    rt_mailbox_t mail;
    rt_events_t events;
    /* Client transfers that ended: done_gen counts them, done_ready wakes
     * threads blocked in co_rt_transfer_wait (own lock: never waits for a
     * turn of the runtime thread). */
    pthread_mutex_t done_lock;
    pthread_cond_t done_ready;
    uint64_t done_gen;
    bool done_closed;
    char error[RT_ERROR_SIZE];
};

/* Shared helpers (co_runtime.c). */
__attribute__((format(printf, 2, 3)))
void rt_set_error(co_rt_t *rt, const char *fmt, ...);
/* Sets the error text and returns CO_RT_ERR_ARGUMENT. */
__attribute__((format(printf, 2, 3)))
int rt_argument_error(co_rt_t *rt, const char *fmt, ...);
/* The line, or NULL with the error set (host_only: host-driver lines only). */
rt_line_t *rt_checked_line(co_rt_t *rt, int line, bool host_only);
/* Wake the thread (a deadline or the tx queue changed). */
void rt_wake(co_rt_t *rt);
/* Under rt->lock, from an application thread that just queued frames or
 * armed timers (a transfer started or cancelled): hand the frames to the
 * sockets and move the timerfd earlier at once, instead of waking the
 * runtime thread for it; wakes it only for lines only it can flush
 * (in-process buses, host lines). */
void rt_kick(co_rt_t *rt);
/* Under rt->lock: a client transfer ended (wakes co_rt_transfer_wait). */
void rt_transfer_ended(co_rt_t *rt);
/* Block until done_gen differs from gen or timeout_ms passed (< 0: no
 * limit); false on timeout or when the runtime stopped. */
bool rt_wait_transfer_end(co_rt_t *rt, uint64_t gen, int timeout_ms);
uint64_t rt_transfer_generation(co_rt_t *rt);
/* Post an event of line l; false when the queue was full (dropped, counted). */
bool rt_post(const rt_line_t *l, int kind, uint8_t node, uint32_t a, uint32_t b,
             const co_frame_t *frame);

static inline bool rt_has_store(const rt_line_t *l)
{
    return l->store_path != NULL || l->app_store.enabled;
}

static inline bool rt_has_node(const rt_line_t *l)
{
    return co_stack_has_node(&l->stack);
}

/* Memory of the stack's parts (co_runtime.c): from the heap, at set-up only. */
extern const co_stack_allocator_t rt_heap;

/* co_rt_od.c */
void rt_od_release(rt_line_t *l);
/* Park a network access until the application answers (CO_EV_OD_REQUEST
 * with this kind): CO_OD_SPLIT, or an abort code when it cannot wait. */
uint32_t rt_od_park(rt_line_t *l, co_od_xfer_t *xfer, uint32_t key, const uint8_t *value,
                    uint32_t length, uint8_t kind);
/* Forget every access waiting on Python (the servers holding them are gone). */
void rt_od_drop_requests(rt_line_t *l);
void rt_od_free_domains(rt_line_t *l);

/* co_rt_services.c: process data and errors. */
/* Before the stack: hear watched PDO frames before any service takes them. */
bool rt_services_line_watch(rt_line_t *l);
/* The stack's line indications that post to Python. */
extern const co_stack_indications_t rt_services_indications;
/* After the stack: Python hears SYNC through a listener. */
bool rt_services_line_init(rt_line_t *l);
/* A node that could not be created: forget what Python listened to. */
void rt_services_node_detach(rt_line_t *l);
/* RPDO n was applied: posted to Python when it listens to it. */
void rt_services_pdo_received(rt_line_t *l, uint16_t number);

/* co_rt_store.c: the application store. */
/* Stage buffers sized for the sealed OD (node attach); the image capacity
 * the store needs is put in *capacity. */
int rt_app_store_open(co_rt_t *rt, rt_line_t *l, uint32_t *capacity);
extern const co_store_backend_t rt_app_store_backend;
/* Subscribed after the node: network saves wait until the image persisted. */
bool rt_app_store_hook(rt_line_t *l);
/* The application's answer to a persist request: commit or drop the image;
 * returns the abort to resume the access with. */
uint32_t rt_app_store_persisted(rt_line_t *l, uint32_t abort);
void rt_app_store_free(rt_line_t *l);

/* co_rt_client.c: the client transfers of a line (USDO or SDO). */
void rt_client_free(rt_line_t *l);

#endif
