/* Runtime: runs the core of every line of a network on one C thread without
 * the GIL (on Linux epoll over the sockets, a timerfd for the next deadline,
 * an eventfd for wake-ups; on Windows and macOS, or on Linux with
 * CANOPENFD_PORTABLE_LOOP=1, a condition variable until the next deadline,
 * and no SocketCAN lines). Python talks to it through this header only:
 * commands go in through a mailbox, events come out through a bounded queue. */
#ifndef CO_RUNTIME_H
#define CO_RUNTIME_H

#include "canopenfd/co_line.h"
#include "canopenfd/co_nmt.h"
#include "canopenfd/co_hb.h"
#include "canopenfd/co_led.h"
#include "canopenfd/co_od.h"
#include "canopenfd/co_store.h"
#include "canopenfd/co_emcy.h"
#include "canopenfd/co_flyma.h"
#include "canopenfd/co_gateway.h"
#include "canopenfd/co_guard.h"
#include "canopenfd/co_lss_master.h"
#include "canopenfd/co_mpdo.h"
#include "canopenfd/co_pdo.h"
#include "canopenfd/co_sdo_server.h"
#include "canopenfd/co_sleep.h"
#include "canopenfd/co_srdo.h"
#include "canopenfd/co_gfc.h"
#include "canopenfd/co_sync.h"
#include "canopenfd/co_time.h"
#include "canopenfd/co_usdo_server.h"
#include "canopenfd/co_usdo_client.h"

/* cffi:begin */
typedef struct co_rt co_rt_t;

typedef enum co_rt_driver {
    CO_DRIVER_SOCKETCAN = 1,   /* a Linux SocketCAN interface */
    CO_DRIVER_MEMBUS = 2,      /* the in-process bus named by channel */
    CO_DRIVER_HOST = 3         /* frames moved by the caller (python-can Bus) */
} co_rt_driver_t;

typedef enum co_rt_status {
    CO_RT_OK = 0,
    CO_RT_ERR_ARGUMENT = -1,      /* invalid argument (see co_rt_last_error) */
    CO_RT_ERR_NO_INTERFACE = -2,  /* no such network interface */
    CO_RT_ERR_MTU = -3,           /* interface MTU does not fit the line mode */
    CO_RT_ERR_SOCKET = -4,        /* socket/ioctl failure (errno text in last error) */
    CO_RT_ERR_FULL = -5,          /* mailbox or table full */
    CO_RT_ERR_STATE = -6,         /* not allowed in the current state */
    CO_RT_ERR_NO_MEMORY = -7,
    CO_RT_ERR_CLOSED = -8,        /* runtime stopped */
    CO_RT_ERR_MODE = -9           /* membus already open in the other mode */
} co_rt_status_t;

typedef struct co_rt_line_config {
    int driver;                /* co_rt_driver_t */
    const char *channel;       /* interface name, membus name, or a label */
    int mode;                  /* co_mode_t */
    int brs;                   /* fd lines: bit-rate switch on sent frames */
    uint32_t rx_queue;         /* frames; 0 = default */
    uint32_t tx_queue;         /* frames; 0 = default */
    int monitor;               /* post every frame on the line as CO_EV_FRAME */
} co_rt_line_config_t;

typedef enum co_rt_command_kind {
    CO_CMD_NODE_CREATE = 1,      /* create + boot the local node */
    CO_CMD_NMT_SEND = 2,         /* an NMT command on the line */
    CO_CMD_NMT_LOCAL = 3,        /* an NMT command applied to the local node only, before
                                    co_rt_command returns (its status is the result) */
    CO_CMD_HEARTBEAT_TIME = 4,   /* the local node's 0x1017 producer time */
    CO_CMD_HB_WATCH = 5,         /* watch a node's heartbeat */
    CO_CMD_HB_UNWATCH = 6,
    CO_CMD_ALLOW_OPERATIONAL = 7,/* veto or allow "to operational" */
    CO_CMD_SEND_FRAME = 8,       /* a frame sent as is (tools, tests); refused with
                                    CO_RT_ERR_FULL while a host line's python-can bus
                                    lags (its queues full): send it again later */
    CO_CMD_HB_TICK = 9           /* post a node's heartbeats (CO_HB_TICK), bounded */
} co_rt_command_kind_t;

/* What a command carries: the member of `args` named after its kind. */
typedef struct co_rt_command {
    int kind;                  /* co_rt_command_kind_t */
    int line;                  /* line index from co_rt_add_line */
    union {
        struct { uint32_t node_id; uint32_t heartbeat_ms; } node_create;
        struct { uint32_t command; uint32_t node_id; uint32_t include_self; } nmt_send;
        /* node_id 0 = all nodes; include_self: applied to the local node too */
        struct { uint32_t command; } nmt_local;
        struct { uint32_t time_ms; } heartbeat_time;
        struct { uint32_t node_id; uint32_t time_ms; } hb_watch;   /* time 0 = states only */
        struct { uint32_t node_id; } hb_unwatch;
        struct { uint32_t allow; } allow_operational;
        co_frame_t send_frame;
        /* on 0 stops; interval_ms: at most one CO_HB_TICK per interval */
        struct { uint32_t node_id; uint32_t interval_ms; uint32_t on; } hb_tick;
    } args;
} co_rt_command_t;

typedef enum co_rt_event_kind {
    CO_EV_COMM = 1,            /* a = co_comm_event_t */
    CO_EV_NMT_STATE = 2,       /* local node: a = old state, b = new state */
    CO_EV_HEARTBEAT = 3,       /* node = remote, a = co_hb_event_t, b = its state */
    CO_EV_FRAME = 4,           /* monitor lines: frame, a = 1 when we sent it */
    CO_EV_NMT_VETOED = 5,      /* "to operational" refused by the application */
    CO_EV_NMT_RESET = 6,       /* local node reset: a = co_nmt_command_t */
    CO_EV_EVENTS_LOST = 7,     /* a = events dropped because the queue was full */
    CO_EV_COMMAND_FAILED = 8,  /* a = co_rt_command_kind_t, b = -co_rt_status_t */
    CO_EV_OD_CHANGED = 9,      /* local OD entry written by the network or a PDO:
                                  a = index << 8 | sub, b = co_od_origin_t */
    CO_EV_STORE = 10,          /* parameters loaded at boot or reset from a store:
                                  a = co_store_status_t, b = records skipped */
    CO_EV_OD_REQUEST = 11,     /* a network read/write waits on the application
                                  (co_rt_od_indicate): a = index << 8 | sub,
                                  b = token for co_rt_od_answer; b >> 24 is
                                  CO_RT_INDICATE_READ or CO_RT_INDICATE_WRITE */
    CO_EV_TRANSFER_DONE = 12,  /* a client transfer (USDO/SDO) ended: a = handle */
    CO_EV_TRANSFER_PROGRESS = 13, /* a = handle, b = bytes moved so far */
    CO_EV_EMCY = 14,           /* node = producer, a = 1 FD / 0 classic format, b = code,
                                  frame.data = the EMCY (co_emcy_decode_fd/_classic) */
    CO_EV_PDO = 15,            /* local node's RPDO a (co_rt_pdo_listen) applied:
                                  frame.data = its mapped values as laid out in the PDO */
    CO_EV_SYNC = 16,           /* a = counter (0 = none); only after co_rt_sync_listen */
    CO_EV_TIME = 17,           /* TIME received: a = ms after midnight, b = days since 1984 */
    CO_EV_GUARD = 18,          /* guarded node: a = co_guard_event_t, b = its NMT state */
    CO_EV_PDO_FRAME = 19,      /* a watched PDO (co_rt_pdo_watch): a = CAN-ID (bit 29 =
                                  29-bit), b = frames seen on it so far, frame = it */
    CO_EV_LED = 20,            /* a local node's LED changed (only after co_rt_led_listen):
                                  a = co_led_which_t, b = 1 on / 0 off,
                                  node = its co_led_pattern_t */
    CO_EV_LSS = 21,            /* the line's LSS master finished a request (co_rt_lss_start):
                                  a = co_lss_request_t, b = co_lss_status_t; co_rt_lss_result */
    CO_EV_CONFIG = 22,         /* a configuration (co_rt_config_start) ended: node = the
                                  node configured, a = handle, b = co_config_outcome_t */
    CO_EV_MANAGER = 23,        /* network manager (co_rt_manager_start): node = slave,
                                  a = co_manager_event_t | error letter << 8 |
                                  mandatory << 16 | NMT command << 24; BOOT reports:
                                  b = co_boot_event_t | step << 8 | sub << 16 |
                                  matched << 24, frame.data = index (2 bytes LE), the
                                  node's last state, bytes got (capped at 255),
                                  expected, got, abort (4 bytes LE each) */
    CO_EV_SLEEP = 24,          /* sleep and wake-up (co_rt_sleep_start): a =
                                  co_sleep_event_t, b = arg | arg2 << 8, node = the
                                  phase after it (co_sleep_phase_t) */
    CO_EV_FLYMA = 25,          /* flying master (co_rt_flyma_start): a = co_flyma_event_t,
                                  b = master | priority << 8, node = co_flyma_state_t */
    CO_EV_GATEWAY = 26,        /* gateway between the lines (co_rt_gateway_join): node =
                                  network, a = co_gateway_event_t, b = abort code; posted
                                  on the first joined line */
    CO_EV_STORE_PERSIST = 27,  /* an autonomous save staged an image of the application
                                  store: persist it (co_rt_store_staged, then
                                  co_rt_store_finish) */
    CO_EV_SRDO = 28,           /* an SRDO of the local node entered the safe state
                                  (co_rt_srdo_start): node = SRDO number,
                                  a = co_srdo_violation_t */
    CO_EV_REDUNDANCY = 29,     /* bus redundancy (co_rt_redundancy_start): a =
                                  co_rdn_event_t, node = the bus now active (0 A, 1 B),
                                  b = Ctoggle */
    CO_EV_MPDO = 30,           /* an MPDO addressed to the local node (only after
                                  co_rt_mpdo_listen): a = its address byte << 24 |
                                  index << 8 | sub, b = 0 applied / the abort code;
                                  frame.data = the 8 MPDO bytes, the RPDO number (2
                                  bytes LE), the local index (2 bytes LE) and sub */
    CO_EV_CIA401 = 31          /* the CiA 401 device's physical outputs changed
                                  (co_rt_cia401_start): node = the kind this event
                                  carries (CO_CIA401_OUT_DIGITAL: frame.data = one byte
                                  per output group; _ANALOG: INTEGER16 LE per channel),
                                  a = every kind the write changed (the analogue
                                  event follows the digital one), b = channels */
} co_rt_event_kind_t;

typedef struct co_rt_event {
    int kind;                  /* co_rt_event_kind_t */
    int line;
    uint8_t node;
    uint32_t a;
    uint32_t b;
    uint64_t time_us;          /* CLOCK_MONOTONIC */
    /* CO_EV_PDO, CO_EV_PDO_FRAME, CO_EV_MPDO, CO_EV_OD_CHANGED: newer events
     * of the same source (the same RPDO, watched CAN-ID, MPDO address byte +
     * index:sub, OD entry) replaced this many queued ones, because
     * the queue was filling up: values the application never saw. */
    uint32_t coalesced;
    co_frame_t frame;
} co_rt_event_t;

/* What the event queue did with one line's events. Coalescing: from 3/4 of
 * the queue on, a PDO, MPDO or OD-changed event replaces the queued one of
 * its source (latest
 * value kept, the count of replaced ones carried in `coalesced`) instead of
 * taking a slot, so the last quarter stays free for events that cannot be
 * merged (EMCY, heartbeat, transfers). */
typedef struct co_rt_event_stats {
    uint32_t events_posted;      /* events queued for the application */
    uint32_t events_coalesced;   /* events merged into a queued one of their source */
    uint32_t events_lost;        /* events dropped: the queue was full */
} co_rt_event_stats_t;

/* Create a runtime with an event queue of event_capacity entries (0 = as many
 * as 2 MiB hold, about 20 000; the memory is touched only as far as it fills). */
co_rt_t *co_rt_new(uint32_t event_capacity);
/* Stops the thread, closes every line, frees everything. */
void co_rt_free(co_rt_t *rt);
/* Start the thread (lines may be added before or after). */
int co_rt_start(co_rt_t *rt);
/* Stop the thread and wake every waiter with CO_RT_ERR_CLOSED. */
void co_rt_stop(co_rt_t *rt);
/* Open a line; returns its index (>= 0) or a co_rt_status_t. */
int co_rt_add_line(co_rt_t *rt, const co_rt_line_config_t *config);
/* Text of the last error of this runtime (thread-safe copy into buf). */
void co_rt_last_error(co_rt_t *rt, char *buf, size_t size);
const char *co_rt_status_text(int status);

/* Post a command to the mailbox (validated here first). CO_CMD_NODE_CREATE
 * is carried out before the call returns, so its errors come back at once. */
int co_rt_command(co_rt_t *rt, const co_rt_command_t *command);
/* Wait up to timeout_ms (-1 = forever) for events; copies up to max into
 * events. Returns the count (0 on timeout) or CO_RT_ERR_CLOSED. */
int co_rt_wait_events(co_rt_t *rt, co_rt_event_t *events, int max, int timeout_ms);

/* Host driver lines: hand a received frame to the line (CO_RT_ERR_FULL when
 * the rx queue is full: the frame is lost and counted as rx overflow) ... */
int co_rt_host_receive(co_rt_t *rt, int line, const co_frame_t *frame);
/* ... or hand count frames in at once, in order, without losing any: the
 * rx queue takes what it has room for and, while it is full, the call waits
 * up to timeout_ms (-1 = forever, 0 = not at all) for the runtime thread to
 * drain it (back-pressure: the caller's own buffer holds the rest; nothing is
 * counted as overflow). Returns the frames taken (< count only after the
 * timeout: hand the rest in again) or CO_RT_ERR_CLOSED ... */
int co_rt_host_receive_frames(co_rt_t *rt, int line, const co_frame_t *frames, int count,
                              int timeout_ms);
/* ... and wait for frames the line wants to send: returns count (0 on
 * timeout) or CO_RT_ERR_CLOSED. */
int co_rt_host_transmit(co_rt_t *rt, int line, co_frame_t *frames, int max, int timeout_ms);
/* Host driver: report a communication-state change (e.g. from python-can). */
int co_rt_host_comm_event(co_rt_t *rt, int line, int event);

/* Driver-level counters of a line (what happens below the core). */
typedef struct co_rt_driver_stats {
    uint32_t kernel_drops;       /* SocketCAN: frames the socket buffer lost */
    uint32_t error_frames;       /* SocketCAN: error frames received */
    uint32_t tx_deferred;        /* sends put off because the socket/device queue was full */
    uint32_t tx_refused;         /* frames the kernel refused: dropped, reported as TX_OVERFLOW */
    uint32_t iface_down;         /* times the interface went down or away */
    uint32_t host_pending;       /* host lines: frames waiting for co_rt_host_transmit */
    uint32_t rx_frames;          /* SocketCAN: frames read from the socket; host lines:
                                    frames handed in by co_rt_host_receive(_frames) */
    uint32_t rx_calls;           /* SocketCAN: reads that returned frames (frames per read);
                                    host lines: receive calls that handed frames in */
    uint32_t tx_frames;          /* SocketCAN: frames written to the socket; host lines:
                                    frames co_rt_host_transmit handed out */
    uint32_t tx_calls;           /* SocketCAN: writes that sent frames (frames per write);
                                    host lines: co_rt_host_transmit calls with frames */
    uint32_t loop_wakeups;       /* times the network's runtime thread woke (all its lines) */
    uint32_t host_rx_waits;      /* host lines: receives that found the rx queue full and
                                    waited for room (back-pressure, nothing lost) */
} co_rt_driver_stats_t;

/* Object dictionary of the line's local node, defined before
 * CO_CMD_NODE_CREATE (which seals it with the node-id). Entries for the other
 * kind of line are left out. store_path: file of saved parameters (0x1010),
 * NULL or "" for none. CO_RT_ERR_ARGUMENT names the refused entry. */
int co_rt_od_define(co_rt_t *rt, int line, const co_od_def_t *defs, uint32_t count,
                    const char *store_path);
/* Room for objects added while the node runs (co_rt_od_add): entry slots and
 * pool bytes beyond what the definition needs, allocated by co_rt_od_define
 * (so call this first; default 0: no growth). */
int co_rt_od_reserve(co_rt_t *rt, int line, uint32_t spare_entries, uint32_t spare_bytes);
/* Add entries to the running node's OD, all or none (co_od_add_live each,
 * under the runtime's lock, so they are served at once). CO_RT_ERR_STATE
 * before the node exists; CO_RT_ERR_ARGUMENT names the refused entry and why
 * ("no room left": see co_rt_od_reserve). */
int co_rt_od_add(co_rt_t *rt, int line, const co_od_def_t *defs, uint32_t count);
/* Application access to the local node's OD, atomic with respect to the
 * runtime thread. Return 0, a CiA abort code (> 0) or a co_rt_status_t (< 0).
 * A read with a too small buffer gives CO_ABORT_OUT_OF_MEMORY and the size
 * needed in *length. */
int co_rt_od_read(co_rt_t *rt, int line, uint16_t index, uint8_t sub, uint8_t *buf,
                  uint32_t capacity, uint32_t *length);
int co_rt_od_write(co_rt_t *rt, int line, uint16_t index, uint8_t sub, const uint8_t *data,
                   uint32_t length);
/* What a "save" to 0x1010 / "load" to 0x1011 does, for the application:
 * group_mask of CO_GROUP_*. 0, an abort code, or a co_rt_status_t. */
int co_rt_od_save(co_rt_t *rt, int line, int group_mask);
int co_rt_od_restore_defaults(co_rt_t *rt, int line, int group_mask);
/* What the local node's last parameter load found (co_store_status_t), or a
 * co_rt_status_t when the line has no node with a store. */
int co_rt_store_status(co_rt_t *rt, int line);

/* A DOMAIN entry backed by up to capacity bytes of runtime memory (allocated
 * here, once): the network uploads and downloads it in chunks (a download
 * larger than capacity is refused with CO_ABORT_LENGTH_HIGH; an aborted one
 * leaves the domain empty, never half old and half new), and
 * co_rt_od_read / co_rt_od_write reach its bytes. The OD must be defined. */
int co_rt_od_domain(co_rt_t *rt, int line, uint16_t index, uint8_t sub, uint32_t capacity);

/* Indications answered by the application (Python): network reads
 * (before-read) and/or writes (check-write) of the entries first..last
 * (index << 8 | sub keys, inclusive) wait until co_rt_od_answer. Each one is
 * posted as CO_EV_OD_REQUEST; the answer runs the rest of the access (the
 * SDO/USDO answer goes out then). A before-read answer sees application
 * writes made before it (the value is read after the answer). Ranges stay
 * for the life of the node; the OD must be defined. */
enum { CO_RT_INDICATE_READ = 1, CO_RT_INDICATE_WRITE = 2,
       CO_RT_INDICATE_STORE = 4 /* kind of a request only: persist the staged
                                   image of an application store (co_rt_store_staged),
                                   answer 0 when it is safe, else an abort code */ };
int co_rt_od_indicate(co_rt_t *rt, int line, uint16_t first_index, uint8_t first_sub,
                      uint16_t last_index, uint8_t last_sub, int kinds);
/* The value a waiting check-write would write (length in *length; a too
 * small buffer gives CO_RT_ERR_ARGUMENT with the size in *length). */
int co_rt_od_request_value(co_rt_t *rt, int line, uint32_t token, uint8_t *buf,
                           uint32_t capacity, uint32_t *length);
/* Answer a waiting access: 0 goes on, a CiA abort code refuses it.
 * CO_RT_ERR_STATE when the token waits no more (answered already). */
int co_rt_od_answer(co_rt_t *rt, int line, uint32_t token, uint32_t abort);

/* Parameter store kept by the application instead of a file (before
 * CO_CMD_NODE_CREATE, after co_rt_od_define without a store path): image is
 * what the application's medium holds (copied), status what reading it
 * found (CO_STORE_OK, CO_STORE_EMPTY or CO_STORE_IO). Loads at boot and
 * resets use this image; every save or restore-defaults (0x1010/0x1011 over
 * the network, or co_rt_od_save / co_rt_od_restore_defaults) stages a new
 * image that the application writes to its medium: for network accesses a
 * CO_EV_OD_REQUEST of kind CO_RT_INDICATE_STORE (answer with co_rt_od_answer:
 * 0 = persisted, else the abort for the client), for the application's own
 * calls co_rt_store_finish, for the stack's autonomous saves a
 * CO_EV_STORE_PERSIST then co_rt_store_finish (ok = 0 marks the groups
 * changed again: retried one interval later). Until then the next save is
 * refused. */
int co_rt_store_application(co_rt_t *rt, int line, const uint8_t *image, uint32_t length,
                            int status);
/* The staged image (length in *length; a small buffer gives
 * CO_RT_ERR_ARGUMENT with the size in *length); CO_RT_ERR_STATE if none. */
int co_rt_store_staged(co_rt_t *rt, int line, uint8_t *buf, uint32_t capacity,
                       uint32_t *length);
/* After co_rt_od_save / co_rt_od_restore_defaults: persisted (ok = 1: the
 * staged image becomes the one loads use) or not (ok = 0: dropped). */
int co_rt_store_finish(co_rt_t *rt, int line, int ok);
/* 1 when the staged image is an autonomous save's (CO_EV_STORE_PERSIST), 0
 * when none or another waits. While one waits, other saves are refused:
 * the application persists it first (then finishes it) and saves again. */
int co_rt_store_autonomous_pending(co_rt_t *rt, int line);
/* Declare the node's parameter groups (co_store_config_t; copied), after
 * co_rt_od_define and co_rt_store_application, before CO_CMD_NODE_CREATE,
 * which refuses a declaration co_store_init_config refuses. Autonomously
 * saved groups need a store file (min_interval_ms: least time between two
 * autonomous saves). */
int co_rt_store_groups(co_rt_t *rt, int line, const co_store_group_t *groups, uint32_t rows,
                       uint32_t min_interval_ms);

/* ---- Client transfers: USDO on fd lines, SDO on classic lines. They run in
 * the runtime thread; the caller starts them, is told CO_EV_TRANSFER_DONE
 * (or waits with co_rt_transfer_wait), collects the result and releases the
 * handle. */
typedef struct co_rt_transfer_request {
    int server;                /* node-id 1..127; USDO: 0 = broadcast */
    uint16_t index;
    uint8_t sub;
    int upload;                /* 1 upload (read), 0 download (write) */
    int mode;                  /* 0 auto, 1 expedited, 2 segmented, 3 bulk (USDO) / block (SDO) */
    uint8_t type;              /* USDO download: CiA 301 type byte, 0 = DOMAIN (raw bytes) */
    const uint8_t *data;       /* download from memory: must stay valid until done */
    uint32_t size;             /* download: bytes; SDO upload: expected size (AUTO block), 0 */
    int fd;                    /* >= 0: download from / upload to this file ... */
    uint64_t fd_offset;        /* ... starting at this offset (data unused) */
    uint32_t max_size;         /* upload to memory: largest accepted (0 = 64 MiB) */
    uint32_t timeout_ms;       /* per frame; broadcast: the answer window; 0 = 1000 */
    uint32_t block_threshold;  /* SDO AUTO: block from this size (0 = 1024, 0xFFFFFFFF never) */
    int progress;              /* post CO_EV_TRANSFER_PROGRESS (at most every 50 ms) */
    int no_done_event;         /* 1: post no CO_EV_TRANSFER_DONE; the caller blocks in
                                  co_rt_transfer_wait (or polls co_rt_transfer_result), so
                                  the event loop has nothing to do when the transfer ends */
    uint8_t network;           /* SDO networking: node network_node of this network through
                                  the gateway `server` (0: the server itself); classic lines */
    uint8_t network_node;
} co_rt_transfer_request_t;

typedef struct co_rt_transfer_result {
    int running;               /* 1 until the transfer ended */
    uint32_t abort;            /* 0 = ok; USDO: the one-byte code, SDO: the CiA 301 code */
    uint8_t abort_from_server; /* 1: the server aborted; 0: we did (timeout, cancel, ...) */
    uint8_t type;              /* USDO upload: data type byte the server sent */
    uint8_t mode;              /* mode used: 1 expedited, 2 segmented, 3 bulk / block */
    uint8_t session_id;        /* USDO session-ID; SDO: the channel used */
    uint16_t pacing;           /* USDO bulk: pacing the server asked (100 us units) */
    uint32_t transferred;      /* bytes moved */
    uint32_t answers;          /* USDO broadcast: servers that answered */
    int error_number;          /* file transfers: errno of a failed read/write, else 0 */
} co_rt_transfer_result_t;

typedef struct co_rt_usdo_answer {
    uint8_t node;
    uint8_t abort;             /* 0: data below; else the USDO abort code */
    uint8_t type;
    uint8_t length;
    uint8_t data[56];
} co_rt_usdo_answer_t;

/* Our USDO client node-id on an fd line (1..127): requests go out on
 * 0x600 + it. Once, before the first transfer; the default is the local
 * node's id, else 127. */
int co_rt_usdo_client(co_rt_t *rt, int line, int node_id);
/* Start a transfer: a handle (>= 0) or a co_rt_status_t; a code the core
 * refused it with comes back as CO_RT_ERR_ARGUMENT / CO_RT_ERR_FULL with the
 * reason in the last error. */
int co_rt_transfer_start(co_rt_t *rt, int line, const co_rt_transfer_request_t *request);
/* Abort a running transfer (code 0 = general error; the abort goes to the server). */
int co_rt_transfer_cancel(co_rt_t *rt, int line, int handle, uint32_t code);
int co_rt_transfer_result(co_rt_t *rt, int line, int handle, co_rt_transfer_result_t *out);
/* Block (without the GIL) until the transfer ended: 1 = ended, 0 = still
 * running after timeout_ms (< 0: no limit), < 0 = error. The application
 * thread is woken by the runtime thread directly, not through the event
 * queue, so a blocking request costs one wake-up less. CO_RT_ERR_CLOSED
 * once the runtime stopped with the transfer unfinished (co_rt_transfer_start
 * refuses with it too). A transfer that ends
 * while a caller waits for it here posts no CO_EV_TRANSFER_DONE: the 1
 * returned is the news, and that caller tells whoever else in the
 * application waits for the end. */
int co_rt_transfer_wait(co_rt_t *rt, int line, int handle, int timeout_ms);
/* Ask for CO_EV_TRANSFER_DONE after all, for a transfer started with
 * no_done_event (the application starts every transfer so and asks only when
 * something must hear the end through the event loop, e.g. an awaiting task):
 * 0 = the event will come, 1 = the transfer already ended (no event comes:
 * the caller acts on the end itself), < 0 = error (CO_RT_ERR_STATE: released). */
int co_rt_transfer_notify(co_rt_t *rt, int line, int handle);
/* ---- process data and errors (co_rt_emcy.c, co_rt_errors.c, co_rt_pdo.c, co_rt_sync.c,
 * co_rt_time.c, co_rt_guard.c, co_rt_stats.c) ---- */

/* An error the application raises or clears on its local node's EMCY
 * producer (FD lines send every field, classic lines code, register, msef). */
typedef struct co_rt_emcy {
    uint16_t code;
    uint8_t msef[5];
    uint8_t register_bits;     /* 0x1001 bits besides the code's class bit */
    uint8_t logical_device;    /* FD */
    uint16_t spec_number;      /* FD: CiA specification of the code */
    uint8_t priority;          /* FD: 0..7 */
    int non_recoverable;       /* FD */
    uint64_t time_stamp;       /* FD: 48 bits */
} co_rt_emcy_t;

typedef struct co_rt_emcy_state {
    uint8_t error_register;    /* 0x1001 */
    uint16_t active;           /* errors active */
    uint32_t sent;
    uint32_t dropped;          /* the EMCY queue was full */
} co_rt_emcy_state_t;

/* Raise (clear = 0) or clear an error: 0 = EMCY sent or queued, 1 = already
 * active (classic: nothing sent; FD: sent again as repeated), 2 = clear of
 * an error not active; < 0 = refused (co_rt_status_t, reason in the error). */
int co_rt_emcy(co_rt_t *rt, int line, const co_rt_emcy_t *error, int clear);
int co_rt_emcy_state(co_rt_t *rt, int line, co_rt_emcy_state_t *out);
/* The local node's error-status bits and EMCY code table (co_errors.h). */
typedef struct co_rt_errors_state {
    uint8_t bits[16];          /* bit n in byte n / 8 at bit n % 8 (as 0x2100) */
    uint8_t error_register;    /* 0x1001 as a whole */
    uint8_t bits_register;     /* the part the bits make */
    uint16_t codes[128];       /* the code table: EMCY code per bit, 0 = not defined */
    uint8_t classes[128];      /* the code table: 0x1001 bits per bit */
    uint32_t counts[128];      /* reports of each bit, repetitions included */
} co_rt_errors_state_t;

/* Declare application bit 16..127: EMCY code, 0x1001 class bits. */
int co_rt_errors_define(co_rt_t *rt, int line, int bit, int code, int register_bits);
/* Report (reset = 0) or reset a defined application bit with an info code:
 * 0 = set / cleared (EMCY sent or queued), 1 = already set (counted, nothing
 * sent), 2 = reset of a clear bit; < 0 = refused (reason in the error). */
int co_rt_errors_report(co_rt_t *rt, int line, int bit, int info, int reset);
/* 0x1001 bit register_bit (0..7, not 6) = any bit of mask[16] set. */
int co_rt_errors_condition(co_rt_t *rt, int line, int register_bit, const uint8_t *mask);
int co_rt_errors_state(co_rt_t *rt, int line, co_rt_errors_state_t *out);
/* Show the bits in the node's OD entry index:00 (an OCTET_STRING), once. */
int co_rt_errors_expose(co_rt_t *rt, int line, int index);
/* Hear (CO_EV_EMCY) the EMCYs of node_id on 0x80 + node_id (watch = 0: stop). */
int co_rt_emcy_watch(co_rt_t *rt, int line, int node_id, int watch);
/* Application event for the local node's TPDO n (types 0, 254, 255). */
int co_rt_pdo_trigger(co_rt_t *rt, int line, int tpdo_number);
/* index:sub changed: triggers every event TPDO mapping it (returns how many). */
int co_rt_pdo_trigger_object(co_rt_t *rt, int line, int index, int sub);
/* Post CO_EV_PDO for each reception of the local node's RPDO n. */
int co_rt_pdo_listen(co_rt_t *rt, int line, int rpdo_number, int listen);
/* Hear (CO_EV_PDO_FRAME) every data frame on can_id (bit 29 set: a 29-bit
 * id), e.g. another node's TPDO; a local RPDO on the same id still gets it.
 * watch = 0 stops. At most 64 ids per line. */
int co_rt_pdo_watch(co_rt_t *rt, int line, uint32_t can_id, int watch);
/* Multiplexed PDOs of the local node (co_rt_mpdo.c, co_mpdo.h). DAM: write
 * data (1..4 bytes) into index:sub of node (0 = all) through DAM TPDO n.
 * SAM: send the local object index:sub (named by the scanner list 0x1FA0..)
 * through SAM TPDO n. 0 = sent; < 0 = refused, the reason in the error. */
int co_rt_mpdo_send_dam(co_rt_t *rt, int line, int tpdo_number, int node, int index, int sub,
                        const uint8_t *data, int len);
int co_rt_mpdo_send_sam(co_rt_t *rt, int line, int tpdo_number, int index, int sub);
/* DAM the CiA 301 way: the object DAM TPDO n maps (sub 1) to the same
 * index:sub of node (0 = all). */
int co_rt_mpdo_send_dam_mapped(co_rt_t *rt, int line, int tpdo_number, int node);
/* Post CO_EV_MPDO for each MPDO addressed to the local node (listen = 0 stops). */
int co_rt_mpdo_listen(co_rt_t *rt, int line, int listen);
/* The local node's MPDO counters (received, refused, sent). */
int co_rt_mpdo_stats(co_rt_t *rt, int line, co_mpdo_stats_t *out);
/* RPDOs of other nodes produced by this line (a master driving a device's
 * RPDO), at most 32 per line, slots taken at co_rt_rpdo_open. The frame
 * carries the mapped bytes as the application wrote them (bit-wise on
 * classic lines). Sent once (co_rt_rpdo_send), after SYNCs the line
 * receives or produces (co_rt_rpdo_sync) and/or every period_us on the
 * runtime's timer (co_rt_rpdo_start), until co_rt_rpdo_stop. While the
 * line has a local node, only while that node is OPERATIONAL (CiA 301:
 * PDOs need it); without one, always (a pure master or tool). */
typedef struct co_rt_rpdo_stats {
    uint32_t sent;             /* frames queued */
    uint32_t tx_failed;        /* the tx queue refused one */
    uint32_t not_operational;  /* one not sent: the local node is not OPERATIONAL */
    uint32_t writes;           /* co_rt_rpdo_write calls applied */
} co_rt_rpdo_stats_t;

/* A producer of can_id (bit 29 set: 29-bit) with length bytes, all 0:
 * returns its slot (>= 0). */
int co_rt_rpdo_open(co_rt_t *rt, int line, uint32_t can_id, int length);
/* Stop it and free the slot. */
int co_rt_rpdo_close(co_rt_t *rt, int line, int slot);
/* Put the low bit_length bits of value (little endian, value_len bytes) at
 * bit bit_offset of the frame (bit 0 = low bit of byte 0); atomic with
 * respect to sending. */
int co_rt_rpdo_write(co_rt_t *rt, int line, int slot, int bit_offset, int bit_length,
                     const uint8_t *value, int value_len);
/* Read the frame's bytes as they stand (length bytes into out). */
int co_rt_rpdo_read(co_rt_t *rt, int line, int slot, uint8_t *out, int out_len);
/* Send the frame now (once). */
int co_rt_rpdo_send(co_rt_t *rt, int line, int slot);
/* Send after every every-th SYNC (1..240); acyclic != 0: after the first
 * SYNC following a write or send request only (every must be 1). */
int co_rt_rpdo_sync(co_rt_t *rt, int line, int slot, int every, int acyclic);
/* Send every period_us (>= 100), the first one now. */
int co_rt_rpdo_start(co_rt_t *rt, int line, int slot, uint32_t period_us);
/* No more periodic or SYNC-driven frames. */
int co_rt_rpdo_stop(co_rt_t *rt, int line, int slot);
int co_rt_rpdo_stats(co_rt_t *rt, int line, int slot, co_rt_rpdo_stats_t *out);
/* SYNC producer of the line: every period_us (0 = stop), window, counter
 * overflow (0 or 2..240). With a local node's OD its 0x1005/0x1006/0x1007/
 * 0x1019 are written (as the network would), else the line's SYNC. */
int co_rt_sync_producer(co_rt_t *rt, int line, uint32_t period_us, uint32_t window_us,
                        int overflow);
/* Post CO_EV_SYNC for every SYNC (listen = 0: stop). */
int co_rt_sync_listen(co_rt_t *rt, int line, int listen);
/* Send a TIME stamp (microseconds since 1970, UTC). */
int co_rt_time_send(co_rt_t *rt, int line, uint64_t unix_us);

/* ---- simulated CiA 402 drive on the local node (co_rt_cia402.c) */
/* Start it over the node's OD (which holds the 402 objects; a missing one is
 * named in the error), SYNC and EMCY; its profile modes step every tick_us. */
int co_rt_cia402_sim_start(co_rt_t *rt, int line, uint32_t tick_us);
/* Inject a device fault: 0x603F = code, EMCY, Fault reaction active, Fault. */
int co_rt_cia402_sim_fault(co_rt_t *rt, int line, uint16_t code);

/* ---- the local node as a CiA 401 generic I/O device (co_rt_cia401.c) */
/* Run it over the node's OD (co_stack_cia401_init: its channels and
 * parameters are the OD's profile objects; a bad one is named in the
 * error); CO_EV_CIA401 tells every change of the physical outputs. */
int co_rt_cia401_start(co_rt_t *rt, int line);
/* Raw levels of input groups first..first+count-1 (1-based): 0x6000 and
 * the TPDOs (co_cia401_od_set_inputs). */
int co_rt_cia401_set_inputs(co_rt_t *rt, int line, uint8_t first, const uint8_t *raw,
                            uint8_t count);
int co_rt_cia401_set_analog_input(co_rt_t *rt, int line, uint8_t channel, int16_t value);
/* A device fault: the error modes and values apply. */
int co_rt_cia401_fault(co_rt_t *rt, int line);
/* The physical outputs now: `groups` digital groups, `channels` analogue. */
int co_rt_cia401_outputs(co_rt_t *rt, int line, uint8_t *digital, uint8_t groups,
                         int32_t *analog, uint8_t channels);

/* ---- sleep and wake-up (CiA 320; co_rt_sleep.c) */
typedef struct co_rt_sleep_config {
    int master;                /* 1: power management master, 0: device */
    uint16_t check_ms;         /* as co_sleep_config_t (0 = 1000 ms each) */
    uint16_t prepare_ms;
    uint16_t silent_ms;
    uint16_t wake_repeat_ms;
    uint8_t objection;         /* device: the reason answered to every query (0 = agree) */
} co_rt_sleep_config_t;
typedef enum co_rt_sleep_action {
    CO_RT_SLEEP_CHECK = 1,     /* master: query, then sleep unless a device objects */
    CO_RT_SLEEP_START = 2,     /* master: sleep command at once; device: sleep alone */
    CO_RT_SLEEP_REQUEST = 3,   /* device: ask the master for sleep */
    CO_RT_SLEEP_WAKE = 4       /* wake up with the wake-up message [status, reason] */
} co_rt_sleep_action_t;
/* The line takes part in sleep and wake-up (once; CO_EV_SLEEP tells every
 * event); waking up resets the local node's communication. */
int co_rt_sleep_start(co_rt_t *rt, int line, const co_rt_sleep_config_t *config);
int co_rt_sleep_stop(co_rt_t *rt, int line);
/* The device's answer to later queries (0 = agree). */
int co_rt_sleep_objection(co_rt_t *rt, int line, uint8_t reason);
int co_rt_sleep_act(co_rt_t *rt, int line, int action, uint8_t status, uint8_t reason);
/* The phase (co_sleep_phase_t) and counters. */
int co_rt_sleep_state(co_rt_t *rt, int line, co_sleep_stats_t *stats);

/* ---- bus redundancy (ECSS-E-ST-50-15C; co_rt_redundancy.c) */
typedef struct co_rt_redundancy_config {
    const char *redundant;     /* bus B: another in-process bus's NAME (the line's own is A) */
    int master;                /* 1: the redundancy master, 0: a slave */
    uint8_t master_id;         /* slave: the master's node-id, watched by the heartbeat consumer */
    uint16_t master_period_ms; /* slave: its heartbeat consumer time */
    uint8_t bdefault;          /* the redundancy object's subs (co_redundancy.h), */
    uint8_t ttoggle;           /* used when the local node's OD has no record at index */
    uint8_t ntoggle;
    int values_given;          /* 1: the caller set the three above (refused when the OD
                                  has the record: its values are the ones used) */
    uint16_t index;            /* the record's index in the node's OD, 0 = 0x2000 */
    int switch_on_failure;     /* master: the other bus on bus-off / interface down */
} co_rt_redundancy_config_t;
/* A line runs on one of two buses: its own (A) and config's redundant one
 * (B); it starts on Bdefault at once (once per line; CO_EV_REDUNDANCY tells
 * every switch). The local node's OD, when it has the record at index,
 * serves it (co_stack_redundancy_init; a node created later: its valid record). */
int co_rt_redundancy_start(co_rt_t *rt, int line, const co_rt_redundancy_config_t *config);
/* Master: use bus 0 (A) or 1 (B) from now on. */
int co_rt_redundancy_select(co_rt_t *rt, int line, uint8_t bus);
/* The redundancy object (subs 0..4) into object[5]; returns the active bus. */
int co_rt_redundancy_state(co_rt_t *rt, int line, uint8_t *object);

/* ---- flying master of the local node (CiA 302-2; co_rt_flyma.c) */
typedef struct co_rt_flyma_config {
    uint8_t priority;             /* as co_flyma_config_t; the node's 0x1F90/0x1F91 */
    uint16_t detect_ms;           /* override these where the OD has them */
    uint16_t delay_ms;
    uint16_t priority_slot_ms;
    uint16_t device_slot_ms;
    uint16_t multiple_master_ms;
    uint16_t capable_ms;
    uint16_t master_heartbeat_ms; /* a slave watches the active master this long */
} co_rt_flyma_config_t;
typedef enum co_rt_flyma_action {
    CO_RT_FLYMA_DETECT_CAPABLE = 1,   /* 0x75: who can be master (CO_EV_FLYMA tells) */
    CO_RT_FLYMA_FORCE = 2             /* 0x76 and a new negotiation */
} co_rt_flyma_action_t;
typedef struct co_rt_flyma_state {
    int state;                    /* co_flyma_state_t */
    uint8_t master;               /* the active master, 0 = none */
    uint8_t master_priority;
    co_flyma_stats_t stats;
} co_rt_flyma_state_t;
/* The line's local node takes part in the flying-master negotiation (it
 * starts at once when the node runs, else at its boot). */
int co_rt_flyma_start(co_rt_t *rt, int line, const co_rt_flyma_config_t *config);
int co_rt_flyma_stop(co_rt_t *rt, int line);
int co_rt_flyma_act(co_rt_t *rt, int line, int action);
/* The state (idle when not started), the active master and the counters. */
int co_rt_flyma_state(co_rt_t *rt, int line, co_rt_flyma_state_t *out);
/* The counters of the line's process-data, error and SDO/USDO server
 * services and of its USDO client (zeros for services the line does not
 * run). */
typedef struct co_rt_service_stats {
    co_pdo_stats_t pdo;
    co_emcy_stats_t emcy;             /* the local node's producer */
    co_emcy_stats_t emcy_consumer;
    co_sync_stats_t sync;
    co_time_stats_t time;
    co_guard_slave_stats_t guard_slave;
    co_guard_master_stats_t guard_master;
    uint32_t pdo_watched;             /* frames seen on the PDO CAN-IDs watched now */
    co_sdo_server_stats_t sdo_server;   /* the local node's server (classic lines) */
    co_usdo_server_stats_t usdo_server; /* the local node's server (fd lines) */
    co_usdo_client_stats_t usdo_client; /* the line's USDO client (fd lines, once used) */
} co_rt_service_stats_t;
int co_rt_service_stats(co_rt_t *rt, int line, co_rt_service_stats_t *out);
/* Node guarding of a remote node on a classic line (guard_ms = 0: stop). */
int co_rt_guard(co_rt_t *rt, int line, int node_id, int guard_ms, int life_factor);
/* ---- network manager, CiA 302-2 (co_rt_manager.c) ---- */
/* (Re)start the network boot-up of the line's local node (its OD: 0x1F80
 * bit 0 set, 0x1F81..): hooks = CO_MANAGER_HOOK_* the application answers
 * (with co_rt_manager_continue), parallel = boot processes at once (0 = the
 * client's channels), retry_ms = a silent slave asked again after (0 = 1 s).
 * Events: CO_EV_MANAGER. */
int co_rt_manager_start(co_rt_t *rt, int line, int hooks, int parallel, int retry_ms);
/* Stop every boot process (the slaves stay as they are). */
int co_rt_manager_stop(co_rt_t *rt, int line);
/* The application's answer: what = CO_MANAGER_EV_UPDATE_SOFTWARE,
 * CO_MANAGER_EV_UPDATE_CONFIG (node_id, done) or
 * CO_MANAGER_EV_READY_OPERATIONAL (node_id and done not used).
 * CO_RT_ERR_STATE when nothing waits for that answer. */
int co_rt_manager_continue(co_rt_t *rt, int line, int what, int node_id, int done);
/* The manager's phase (co_manager_phase_t), or a status < 0. With node_id
 * 1..127: that slave's co_manager_slave_status_t | error letter << 8. */
int co_rt_manager_state(co_rt_t *rt, int line, int node_id);

/* ---- LSS master of the line (co_rt_lss.c): one request at a time, its end
 * posted as CO_EV_LSS, its result read with co_rt_lss_result. */
enum {
    CO_RT_LSS_SWITCH_GLOBAL = 100,        /* value[0] = co_lss_state_t; no answer, no event */
    CO_RT_LSS_ACTIVATE_BIT_TIMING = 101   /* value[0] = switch delay ms; no answer, no event */
};
typedef struct co_rt_lss_request {
    int kind;                  /* co_lss_request_t (1..9) or CO_RT_LSS_* */
    /* SWITCH_SELECTIVE: vendor, product, revision, serial; CONFIGURE_NODE_ID:
     * node-id; CONFIGURE_BIT_TIMING: selector, index; INQUIRE: the CS
     * (0x5A..0x5E); IDENTIFY_REMOTE and SCAN: vendor, product, revision low,
     * revision high, serial low, serial high */
    uint32_t value[6];
    uint8_t node_ids[127];     /* FASTSCAN: node-ids to give, in order */
    int node_id_count;         /* FASTSCAN: 0 identifies one slave only (left selected) */
    /* FASTSCAN: per part (vendor, product, revision, serial) 0 find it bit
     * by bit, 1 skip it (not the vendor), 2 check fs_match at once; all 0:
     * no filter (co_lss_fastscan_filter_t) */
    uint8_t fs_kind[4];
    uint32_t fs_match[4];
    int timeout_ms;            /* per step, 0 = 100 */
    /* how long a step several slaves may answer stays open after its first
     * answer, for slower slaves' answers (co_lss_master_set_settle); at most
     * the timeout, 0 = an eighth of it */
    int settle_ms;
} co_rt_lss_request_t;
typedef struct co_rt_lss_device {
    uint32_t address[4];       /* vendor, product, revision, serial */
    uint8_t node_id;           /* FASTSCAN: given; SCAN: 0 */
} co_rt_lss_device_t;
/* Start a request: CO_RT_ERR_STATE while one runs, CO_RT_ERR_ARGUMENT for
 * bad values (the error text says which). */
int co_rt_lss_start(co_rt_t *rt, int line, const co_rt_lss_request_t *request);
/* Ends the running request (if any) with CO_LSS_CANCELLED, posted as
 * CO_EV_LSS like any end: the master is free at once (an application that
 * stopped waiting). */
int co_rt_lss_cancel(co_rt_t *rt, int line);
/* The last finished request's result and up to max of the devices it found;
 * returns the devices copied, CO_RT_ERR_STATE when none finished yet. */
int co_rt_lss_result(co_rt_t *rt, int line, co_lss_master_result_t *out,
                     co_rt_lss_device_t *devices, int max);
int co_rt_lss_stats(co_rt_t *rt, int line, co_lss_master_stats_t *out);
/* The local node's LSS slave (a node whose OD has 0x1018:04) posts CO_EV_LSS
 * with node = 255 (whatever its node-id: the master's events have node 0)
 * and a = one of these: */
enum {
    CO_RT_LSS_SLAVE_STATE = 110,      /* b = co_lss_state_t */
    CO_RT_LSS_SLAVE_STORE = 111,      /* b = node-id to persist: co_rt_lss_slave_answer */
    CO_RT_LSS_SLAVE_ACTIVATE = 112,   /* b = switch delay ms */
    CO_RT_LSS_SLAVE_BIT_TIMING = 113, /* b = selector << 8 | index, accepted */
    CO_RT_LSS_SLAVE_CONFIGURED = 114  /* a node created with node-id 255 got b from LSS,
                                         or a configured node took its pending node-id b
                                         at a reset: it runs (and boots) with it now */
};
/* store != 0: store requests are the application's (answered with
 * co_rt_lss_slave_answer), else "not supported". bit_timings: bit n set =
 * table 0 index n accepted (0: none). */
int co_rt_lss_slave_config(co_rt_t *rt, int line, int store, uint32_t bit_timings);
/* Answer the store request: 0 stored, 1 not supported, 2 storage media error. */
int co_rt_lss_slave_answer(co_rt_t *rt, int line, int error);
/* state, active, pending and persistent node-id of the local node's slave. */
int co_rt_lss_slave_info(co_rt_t *rt, int line, uint8_t out[4]);

/* Upload to memory: copy the data (returns the byte count, or a status). */
int co_rt_transfer_data(co_rt_t *rt, int line, int handle, uint8_t *buf, uint32_t capacity);
/* USDO broadcast: copy up to max answers (returns the count, or a status). */
int co_rt_usdo_answers(co_rt_t *rt, int line, int handle, co_rt_usdo_answer_t *out, int max);
/* Forget a finished transfer (a running one is cancelled first). */
int co_rt_transfer_release(co_rt_t *rt, int line, int handle);

/* Snapshots (thread-safe). */
int co_rt_line_stats(co_rt_t *rt, int line, co_line_stats_t *out);
/* In-process lines only: the line gets comm event `event` (co_comm_event_t)
 * as if its controller had reported it (tests of bus-off, interface down). */
int co_rt_membus_comm_event(co_rt_t *rt, int line, int event);
int co_rt_driver_stats(co_rt_t *rt, int line, co_rt_driver_stats_t *out);
int co_rt_event_stats(co_rt_t *rt, int line, co_rt_event_stats_t *out);
/* Local node state (co_nmt_state_t) or CO_RT_ERR_STATE when the line has none. */
int co_rt_local_state(co_rt_t *rt, int line);
/* The local node takes node_id (1..127) at its next reset, communication or
 * node (co_stack_set_node_id_at_reset); CO_RT_ERR_STATE without a running one. */
int co_rt_node_id_at_reset(co_rt_t *rt, int line, int node_id);
/* Last state seen of a remote node (co_nmt_state_t, CO_NMT_UNKNOWN if none). */
int co_rt_remote_state(co_rt_t *rt, int line, int node_id);
uint64_t co_rt_now_us(void);
/* CiA 303-3 LEDs of the line's local node (co_rt_led.c). */
typedef struct co_rt_led_state {
    int pattern[2];            /* co_led_pattern_t, by co_led_which_t */
    int on[2];                 /* lit now */
    int causes;                /* co_led_cause_t bits active */
} co_rt_led_state_t;
/* Post CO_EV_LED for every change of the local node's LEDs (listen = 0:
 * stop); the 50 ms LED tick runs only while someone listens. */
int co_rt_led_listen(co_rt_t *rt, int line, int listen);
int co_rt_led_state(co_rt_t *rt, int line, co_rt_led_state_t *out);
/* The application's own error causes (CO_LED_CAUSE_CONFIG: invalid
 * configuration): set the bits of mask to those of active. */
int co_rt_led_causes(co_rt_t *rt, int line, int mask, int active);

/* ---- Configuration manager (CiA 302-3, co_config.h) over the line's client:
 * a concise DCF downloaded into a node (0x1020 compared first when a stamp is
 * given, written last). The DCF is copied at the start; CO_EV_CONFIG tells
 * the end; the result and each entry's abort code are collected, then the
 * handle released. */
typedef struct co_rt_config_request {
    int node;                  /* 1..127 */
    const uint8_t *dcf;        /* concise DCF, copied by co_rt_config_start */
    uint32_t dcf_length;
    int check_stamp;           /* compare / write 0x1020:01/02 with date and time */
    uint32_t date;
    uint32_t time;
    int continue_on_error;     /* write the rest after a refused entry */
    uint32_t timeout_ms;       /* per frame, 0 = the client's default */
} co_rt_config_request_t;

typedef struct co_rt_config_result {
    int running;
    int outcome;               /* co_config_outcome_t once ended */
    uint32_t written;          /* DCF entries written */
    uint32_t failed;           /* DCF entries refused */
    uint16_t index;            /* the first failure / the unanswered transfer */
    uint8_t sub;
    int from_node;
    uint32_t abort;            /* CiA 301 abort code */
    uint32_t entry;            /* its DCF entry number */
    uint32_t reported;         /* entries in co_rt_config_entries */
} co_rt_config_result_t;

typedef struct co_rt_config_entry {
    uint16_t index;
    uint8_t sub;
    uint32_t abort;            /* 0 = written */
} co_rt_config_entry_t;

/* A handle (>= 0) or a co_rt_status_t (a malformed DCF: CO_RT_ERR_ARGUMENT,
 * the byte offset in co_rt_last_error). */
int co_rt_config_start(co_rt_t *rt, int line, const co_rt_config_request_t *request);
int co_rt_config_result(co_rt_t *rt, int line, int handle, co_rt_config_result_t *out);
/* Copy up to max entry outcomes in the order they were told (the count). */
int co_rt_config_entries(co_rt_t *rt, int line, int handle, co_rt_config_entry_t *out,
                         int max);
/* End a running configuration (CANCELLED). */
int co_rt_config_cancel(co_rt_t *rt, int line, int handle);
/* Forget a configuration (a running one is cancelled first). */
int co_rt_config_release(co_rt_t *rt, int line, int handle);

/* ---- gateway between the lines of this runtime (co_rt_gateway.c, co_gateway)
 * A line joins with its network-id 1..127 (0 leaves); joined lines route
 * EMCYs per 0x1F2F and forward 0xB000..0xBFFF PDO objects between their
 * local nodes; the 0x1F2C routes are one table for all. A line's local node
 * created after the line joined is joined with it. */
int co_rt_gateway_join(co_rt_t *rt, int line, uint8_t network_id);
/* The line's network-id (0: not joined). */
int co_rt_gateway_network(co_rt_t *rt, int line);
/* Route to network `net` through gateway node_id on network via_net
 * (via_net 0: remove); refused as a 0x1F2C write is (*abort = the CiA 301
 * code, CO_RT_ERR_ARGUMENT with the reason in co_rt_last_error). */
int co_rt_gateway_route(co_rt_t *rt, uint8_t net, uint8_t via_net, uint8_t node_id,
                        uint32_t *abort);
/* co_gateway_route_kind_t of network `net`; *line = the line to send on
 * (-1: none), *node_id = the gateway node to hand requests to (0: attached). */
int co_rt_gateway_resolve(co_rt_t *rt, uint8_t net, int *line, uint8_t *node_id);
/* 0x1F2F sub node_id of a joined line whose OD has none: bit k-1 = network k. */
int co_rt_gateway_emcy_route(co_rt_t *rt, int line, uint8_t node_id, uint32_t networks);
int co_rt_gateway_stats(co_rt_t *rt, co_gateway_stats_t *out);
/* SDO networking into classic networks: segmented transfers with the two
 * hops overlapped (on, the default) or every frame relayed (off). */
int co_rt_gateway_sdo_buffering(co_rt_t *rt, bool on);

/* ---- SRDOs and GFC of the local node (CiA 304; co_rt_srdo.c) */
/* What co_rt_srdo_read reports of one SRDO. */
typedef struct co_rt_srdo_status {
    int state;                 /* co_srdo_state_t */
    int violation;             /* co_srdo_violation_t, why it is safe */
    uint8_t length;            /* valid data bytes (0: not valid) */
    uint8_t data[8];
    co_srdo_stats_t stats;
} co_rt_srdo_status_t;
/* count SRDOs (1..64) and the GFC for the line's node; CO_EV_SRDO tells
 * every safe-state entry. */
int co_rt_srdo_start(co_rt_t *rt, int line, uint8_t count);
/* SRDO number (1..count): its 0x1301+n / 0x1381+n values, the 0x13FE value
 * and its 0x13FF signature; refused while the node is operational. */
int co_rt_srdo_configure(co_rt_t *rt, int line, uint8_t number, const co_srdo_config_t *config,
                         uint8_t valid, uint16_t signature);
int co_rt_srdo_set_data(co_rt_t *rt, int line, uint8_t number, const uint8_t *data,
                        size_t length);
int co_rt_srdo_read(co_rt_t *rt, int line, uint8_t number, co_rt_srdo_status_t *out);
int co_rt_srdo_restart(co_rt_t *rt, int line, uint8_t number);
/* 0x1300 (on: send and hear GFCs), and send one GFC. */
int co_rt_gfc_enable(co_rt_t *rt, int line, bool on);
int co_rt_gfc_send(co_rt_t *rt, int line);
int co_rt_gfc_stats(co_rt_t *rt, int line, co_gfc_stats_t *out);
/* cffi:end */

#endif
