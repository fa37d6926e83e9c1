/* co_gateway: routing between the CAN lines of one device (CiA 302-7 style,
 * seed 000 §13): each line (a co_stack, its "port") carries a network-id
 * 1..127, and the gateway
 *
 *   - keeps the network routes of 0x1F2C: sub n (network n) = via network
 *     (bits 0..7) | next gateway's node-id on it (bits 8..15), 0 = no route;
 *     a route to an attached network, through itself, through our own node
 *     or closing a loop is refused (0x06040043) and a loop met while
 *     resolving one (values loaded from a store are not checked) is counted
 *     and reported;
 *   - routes EMCYs per 0x1F2F: sub n, parallel to 0x1028 sub n (node n's
 *     EMCY on the same line), bit k-1 = re-send it on network k (1..32),
 *     re-encoded for the target line (classic 8 bytes / fd 20 bytes) on the
 *     CAN-ID it was heard on; never onto the network it came from, and an
 *     EMCY equal to one it re-sent within CO_GATEWAY_EMCY_ECHO_MS, heard on
 *     the network that one came from or went to, is its echo through
 *     another gateway and is not re-sent (no EMCY ping-pong);
 *   - forwards process data: when an RPDO of one line has written objects of
 *     0xB000..0xBFFF, the same objects on the other lines get the values and
 *     every TPDO there that maps one is triggered once (event-driven, no
 *     application call per frame). Mapping such an object partially, or with
 *     another type or size than the other lines hold, is refused with
 *     0x06040043; what a classic PDO cannot hold is refused by the PDO
 *     service (0x06040041 / 0x06040042);
 *   - relays SDO networking (co_gateway_sdo.c): a client's network
 *     indication (0xE0, network LE16, node) on a classic port's SDO server
 *     connects it to a node of another network; its frames then go to that
 *     node (or the next gateway) and the answers back, unchanged; a node of
 *     an attached fd network is reached by translation instead
 *     (co_gateway_sdo_buffered.c): the gateway serves the client's SDO transfer
 *     itself and moves the whole value with the fd line's USDO client
 *     through a buffer the caller gives (co_gateway_set_sdo_buffer);
 *   - forwards remote USDO (co_gateway_usdo.c): a routed request (cs | 0x80,
 *     CiA 1301; expedited or segmented, values up to
 *     CO_GATEWAY_USDO_VALUE_MAX bytes) to its node on an fd port is carried
 *     out with the target line's USDO client (store and forward) and
 *     answered with the routed response or a routed abort (0xFF).
 *
 * Layouts of 0x1F2C / 0x1F2F and their evidence: docs/protocol-notes.md
 * "Gateway". No global state, no allocation: the caller owns co_gateway_t. */
#ifndef CO_GATEWAY_H
#define CO_GATEWAY_H

#include "canopenfd/co_stack.h"

enum {
    CO_GATEWAY_MAX_PORTS = 8,        /* lines one gateway joins */
    CO_GATEWAY_NETWORKS = 128,       /* network-ids 1..127 index the route table */
    CO_GATEWAY_ROUTES = 0x1F2C,
    CO_GATEWAY_EMCY_ROUTES = 0x1F2F,
    CO_GATEWAY_PDO_FIRST = 0xB000,   /* objects forwarded between lines */
    CO_GATEWAY_PDO_LAST = 0xBFFF,
    CO_GATEWAY_EMCY_NETWORKS = 32,   /* 0x1F2F is UNSIGNED32: networks 1..32 */
    CO_GATEWAY_SDO_CONNECTIONS = 4,  /* SDO networking connections at once */
    CO_GATEWAY_SDO_PIPE_DEPTH = 8,   /* download segments answered ahead of the target */
    /* OD handler subscriptions a joined node's OD needs besides
     * CO_STACK_OD_SUBSCRIPTIONS (mapping checks, 0x1F2C) */
    CO_GATEWAY_OD_SUBSCRIPTIONS = 2,
    CO_GATEWAY_SDO_TIMEOUT_MS = 1000, /* default wait for the target's answer */
    CO_GATEWAY_USDO_RELAYS = 4,      /* remote USDO requests forwarded at once */
    CO_GATEWAY_USDO_VALUE_MAX = 1024, /* largest value a remote USDO request moves (0x16 above) */
    CO_GATEWAY_ENDED = 8,            /* connections ended by a rebuild remembered at once */
    CO_GATEWAY_EMCY_RECENT = 8,      /* EMCYs re-sent lately, kept to know their echoes */
    CO_GATEWAY_EMCY_ECHO_MS = 500    /* how long an EMCY re-sent is taken as ours */
};

/* SDO networking (CiA 302-7 style; layout in docs/protocol-notes.md): byte 0
 * of the "network indication" request and of its confirmation (ccs/scs 7). */
#define CO_GATEWAY_SDO_NETWORK_IND 0xE0u
/* Aborts of the gateway: no connection or target CAN-ID free (the seed's
 * "SDO client busy"), and a network it cannot reach. */
#define CO_GATEWAY_ABORT_BUSY 0x060A0023u
#define CO_GATEWAY_ABORT_NO_ROUTE 0x08000000u
/* What ends a connection when the gateway is rebuilt, on both sides, and
 * answers the next request of a client whose idle connection was ended:
 * CiA 301 "resource not available: SDO connection" (remote USDO: its CiA
 * 1301 counterpart 0x70). Why this code: docs/protocol-notes.md "Gateway". */
#define CO_GATEWAY_ABORT_ENDED 0x060A0023u

/* cffi:begin */
typedef struct co_gateway_stats {
    uint32_t emcy_routed;        /* EMCYs re-sent on a target line */
    uint32_t emcy_no_route;      /* a 0x1F2F bit names a network no line carries */
    uint32_t emcy_tx_failed;     /* the target line refused the frame */
    uint32_t pdo_forwarded;      /* RPDOs whose objects were copied to another line */
    uint32_t pdo_values;         /* object values copied */
    uint32_t pdo_mismatch;       /* an object another line holds with another type/size */
    uint32_t tpdo_triggered;     /* TPDOs triggered by a forwarded value */
    uint32_t tpdo_refused;       /* a trigger the PDO service refused (not operational) */
    uint32_t routes_refused;     /* 0x1F2C writes / route calls refused */
    uint32_t route_loops;        /* loops met while resolving a route */
    uint32_t sdo_connects;       /* network indications confirmed */
    uint32_t sdo_refused;        /* network indications refused (abort sent) */
    uint32_t sdo_relayed;        /* client requests relayed to a target */
    uint32_t sdo_answers;        /* target answers relayed to a client */
    uint32_t sdo_timeouts;       /* no answer from the target: aborted both ways */
    uint32_t sdo_tx_failed;      /* a relayed frame the line refused (tx queue full) */
    uint32_t usdo_forwarded;     /* remote USDO requests started on the target line */
    uint32_t usdo_answered;      /* ... answered to the client (a response or an abort) */
    uint32_t usdo_refused;       /* remote requests refused at once (routed abort sent) */
    uint32_t usdo_client_aborts; /* a client's routed abort: the forwarded request cancelled */
    uint32_t usdo_stray;         /* routed aborts / frames for no forwarded request */
    uint32_t usdo_tx_failed;     /* an answer the client's line refused (tx queue full) */
    uint32_t usdo_timeouts;      /* a client stopped in the middle of a segmented transfer */
    uint32_t sdo_translated;     /* transfers to an fd node completed through USDO */
    uint32_t sdo_translate_failed; /* ... ended with an abort (either side, timeouts) */
    uint32_t sdo_too_big;        /* ... refused: larger than the gateway's buffer */
    uint32_t sdo_buffer_busy;    /* ... refused: another connection holds the buffer */
    uint32_t sdo_pipelined;      /* download segments answered ahead of a classic target */
    uint32_t connections_ended;  /* SDO connections and remote USDO requests a rebuild
                                    ended (aborts sent to both sides) */
    uint32_t emcy_echoes;        /* an EMCY this gateway re-sent came back (through
                                    another gateway): not re-sent again */
} co_gateway_stats_t;

/* Results of co_gateway_resolve. */
typedef enum co_gateway_route_kind {
    CO_GATEWAY_ATTACHED = 0,     /* the network is a line of ours */
    CO_GATEWAY_VIA = 1,          /* reached through a gateway node on one of our lines */
    CO_GATEWAY_UNKNOWN = 2,      /* no route */
    CO_GATEWAY_LOOP = 3          /* the routes form a loop (counted, reported) */
} co_gateway_route_kind_t;

/* Events told to the indication. */
typedef enum co_gateway_event {
    CO_GATEWAY_EV_ROUTE_LOOP = 1,   /* resolving network `net` met a loop */
    CO_GATEWAY_EV_ROUTE_REFUSED = 2 /* a route to `net` was refused (abort in `code`) */
} co_gateway_event_t;
/* cffi:end */

typedef struct co_gateway co_gateway_t;
struct co_gateway_port;

/* One SDO networking connection: a client on a port's server channel whose
 * requests go to `target` on another port's line (the device itself when its
 * network is attached, else the next gateway). */
typedef struct co_gateway_sdo {
    co_gateway_t *gw;
    struct co_gateway_port *from;    /* NULL: free */
    uint8_t channel;                 /* the server channel the client uses */
    uint32_t reply_id;               /* its answer CAN-ID */
    struct co_gateway_port *to;
    uint8_t target;                  /* node-id addressed on the target line */
    uint8_t net;                     /* what the client asked for */
    uint8_t node;
    uint8_t state;                   /* co_gateway_sdo_state in co_gateway_sdo.c */
    uint8_t mux[3];                  /* bytes 1..3 of the last relayed request */
    bool block_down;                 /* a relayed block download runs: the client's
                                        segments (0x80 | seqno may be 0xE0..0xFF)
                                        are no network indications */
    co_timer_t timer;
    /* segmented downloads answered ahead of the target (co_gateway_sdo_pipe.c) */
    uint8_t pipe;                    /* its state, 0: off */
    uint8_t pipe_head;               /* oldest waiting segment */
    uint8_t pipe_count;              /* segments waiting */
    bool pipe_target_busy;           /* a segment awaits the target's answer */
    bool pipe_ack_held;              /* the client's answer waits for room */
    uint8_t pipe_held_toggle;
    bool pipe_last_in;               /* the client sent its last segment */
    bool pipe_last_sent;             /* ... and it went to the target */
    uint8_t pipe_frames[CO_GATEWAY_SDO_PIPE_DEPTH][8];
    /* buffered transfers (co_gateway_sdo_buffered.c): every transfer to an fd
     * target, uploads from a classic one */
    bool fd;                         /* the target is on an fd line */
    bool buffered;                   /* transfers may go through the buffer */
    uint8_t xstate;                  /* co_gateway_sdo_buffered.c's transfer state */
    uint8_t toggle;                  /* segmented: toggle expected next */
    bool size_known;                 /* segmented download: the client gave its size */
    bool fetch_running;              /* the target's transfer has not ended yet */
    bool seg_pending;                /* upload: a segment request waits for data */
    uint32_t size;                   /* announced (download) / held (upload) bytes */
    uint32_t offset;                 /* bytes moved to / from the client so far */
    uint8_t small[4];                /* an expedited download's data (no buffer needed) */
    uint8_t answer[8];               /* the client's answer once the target has the value */
    co_buffer_t data;                /* the transfer's view of the gateway's buffer */
    co_timer_t xtimer;               /* the client's silence during a buffered transfer */
    union {                          /* the gateway's transfer with the target */
        co_usdo_request_t usdo;      /* fd line: its USDO client */
        co_sdo_request_t sdo;        /* classic line: its SDO client */
    } fetch;
} co_gateway_sdo_t;

/* One remote USDO request being carried out: the client's request on
 * `from`, the gateway's own request on `to` (store and forward). */
typedef struct co_gateway_usdo {
    co_gateway_t *gw;
    struct co_gateway_port *from;    /* NULL: free */
    struct co_gateway_port *to;
    uint8_t client;                  /* client node-id on `from` */
    uint8_t session;                 /* its session-ID */
    uint8_t src_net;                 /* the client's network (from its request) */
    uint8_t net;                     /* the target it asked for */
    uint8_t node;
    uint8_t state;                   /* co_gateway_usdo_state in co_gateway_usdo.c */
    uint8_t counter;                 /* segmented with the client: next counter */
    uint8_t type;                    /* the value's data type byte */
    uint32_t size;                   /* the value's size (download: announced) */
    uint32_t offset;                 /* segmented with the client: bytes moved */
    bool fetching;                   /* our request on `to` has not ended yet */
    bool seg_pending;                /* upload: the client's segment request waits for data */
    co_timer_t timer;                /* segmented with the client: its silence */
    co_usdo_request_t req;           /* on `to`'s USDO client */
    co_buffer_t buf;
    uint8_t data[CO_GATEWAY_USDO_VALUE_MAX];
} co_gateway_usdo_t;

typedef void (*co_gateway_event_fn)(co_gateway_t *gw, co_gateway_event_t event, uint8_t net,
                                    uint32_t code, void *user);

typedef struct co_gateway_port {
    co_gateway_t *gw;
    co_stack_t *stack;
    uint8_t network_id;
    bool od_hooked;              /* mapping / 0x1F2C handlers on the line's OD */
    co_pdo_t *pdo;               /* tapped PDO service, or NULL */
    co_sdo_server_t *sdo_server; /* filtered SDO server (classic lines), or NULL */
    co_usdo_server_t *usdo_server; /* USDO server whose remote requests we take, or NULL */
    /* 0x1F2F of lines without one in their OD (co_gateway_set_emcy_route) */
    uint32_t emcy_routes[CO_GATEWAY_NETWORKS];
} co_gateway_port_t;

/* The server channels whose SDO networking connection a rebuild ended
 * (co_gateway_end_connections): a client's next request there is aborted
 * with CO_GATEWAY_ABORT_ENDED, not answered by the gateway's own server,
 * until it sends a network indication. The owner carries it over to the
 * rebuilt gateway. */
typedef struct co_gateway_ended {
    const co_stack_t *stack[CO_GATEWAY_ENDED];   /* NULL: free */
    uint8_t channel[CO_GATEWAY_ENDED];
    uint8_t next;                /* the slot taken over when all are in use */
} co_gateway_ended_t;

/* An EMCY the gateway re-sent: its CAN-ID and classic 8 bytes (what every
 * line's format keeps), the network it came from, those it went to. */
typedef struct co_gateway_emcy_sent {
    uint64_t at_us;
    uint32_t cob_id;
    uint32_t to_nets;            /* bit k-1 = network k; 0: a free slot */
    uint8_t from_net;
    uint8_t data[8];
} co_gateway_emcy_sent_t;

struct co_gateway {
    co_gateway_port_t ports[CO_GATEWAY_MAX_PORTS];
    uint8_t port_count;
    uint16_t routes[CO_GATEWAY_NETWORKS];   /* via network | node << 8, 0 = none */
    bool syncing;                /* copying a route into the other ODs */
    co_gateway_sdo_t sdo[CO_GATEWAY_SDO_CONNECTIONS];
    co_gateway_usdo_t usdo[CO_GATEWAY_USDO_RELAYS];
    uint32_t sdo_timeout_us;
    uint8_t *sdo_buf;            /* translation buffer (caller memory), NULL: none */
    uint32_t sdo_buf_size;
    co_gateway_sdo_t *sdo_buf_owner; /* the connection using it, NULL: free */
    bool sdo_relay_only;         /* classic targets: every frame relayed, never buffered */
    co_gateway_ended_t ended;
    co_gateway_emcy_sent_t emcy_sent[CO_GATEWAY_EMCY_RECENT];
    uint8_t emcy_next;           /* the slot the next re-sent EMCY takes */
    co_gateway_event_fn on_event;
    void *user;
    co_gateway_stats_t stats;
};

typedef enum co_gateway_status {
    CO_GATEWAY_OK = 0,
    CO_GATEWAY_ERR_ARGUMENT = 1, /* network-id outside 1..127, NULL, the same line twice */
    CO_GATEWAY_ERR_NETWORK = 2,  /* another line has this network-id */
    CO_GATEWAY_ERR_FULL = 3,     /* CO_GATEWAY_MAX_PORTS lines already */
    CO_GATEWAY_ERR_TAKEN = 4     /* the OD has no room for the gateway's handlers */
} co_gateway_status_t;

void co_gateway_init(co_gateway_t *gw, co_gateway_event_fn on_event, void *user);
/* Join a line: after its node (if any) is set up, since the gateway hooks
 * the node's OD (0x1600..0x1BFF mapping checks, 0x1F2C), its PDOs and the
 * line's EMCY consumer. Routes found in the OD's 0x1F2C join the table. */
co_gateway_status_t co_gateway_add_port(co_gateway_t *gw, co_stack_t *stack,
                                        uint8_t network_id);
/* Every hook removed (before the stacks go). */
void co_gateway_deinit(co_gateway_t *gw);
/* Before a rebuild (co_gateway_deinit, co_gateway_init, the ports again):
 * every open SDO networking connection, translation and remote USDO request
 * ends as CiA 301 ends a transfer, with an abort (CO_GATEWAY_ABORT_ENDED)
 * to the client and to the target, counted in connections_ended; the SDO
 * clients' server channels go into gw->ended (copy it to the new gateway). */
void co_gateway_end_connections(co_gateway_t *gw);

/* The line carrying network `net`, or NULL. */
co_stack_t *co_gateway_line_of(co_gateway_t *gw, uint8_t net);
/* The network-id of a joined line, 0 when it is none of ours. */
uint8_t co_gateway_network_of(const co_gateway_t *gw, const co_stack_t *stack);

/* Set (value 0: remove) the route to `net` as a write of 0x1F2C sub net
 * does, written into every joined OD with 0x1F2C: 0 or the abort code. */
uint32_t co_gateway_set_route(co_gateway_t *gw, uint8_t net, uint8_t via_net, uint8_t node_id);
/* Where requests for node(s) of network `net` go: *line = the line to send
 * on, *node_id = the gateway node to hand them to (0 when attached). */
co_gateway_route_kind_t co_gateway_resolve(co_gateway_t *gw, uint8_t net, co_stack_t **line,
                                           uint8_t *node_id);

/* 0x1F2F sub node_id of a line whose OD has no such entry: bit k-1 =
 * network k. False for an unknown line or node-id. */
bool co_gateway_set_emcy_route(co_gateway_t *gw, co_stack_t *stack, uint8_t node_id,
                               uint32_t networks);

/* SDO networking: how long a relayed request waits for the target (0 =
 * CO_GATEWAY_SDO_TIMEOUT_MS). */
void co_gateway_set_sdo_timeout(co_gateway_t *gw, uint32_t timeout_ms);

/* SDO networking into fd networks: the buffer one translated segmented
 * transfer at a time goes through (a value larger than `size` is refused
 * with 0x05040005; a second transfer while one holds it with 0x060A0023).
 * NULL / 0: none (expedited downloads of 1..4 bytes still pass). The fd
 * line's stack needs a USDO client (co_stack_client_init) whose node-id
 * is not the target's. */
void co_gateway_set_sdo_buffer(co_gateway_t *gw, uint8_t *buf, uint32_t size);
/* Overlapped hops into classic networks (pipelined downloads, buffered
 * uploads) on (the default) or off: off, every frame of a classic target's
 * connection is relayed as it came and waits for the target (fd targets are
 * always translated). Takes effect at the next transfer. */
void co_gateway_set_sdo_buffering(co_gateway_t *gw, bool on);

/* co_gateway_sdo.c, for co_gateway.c: hook / unhook a port's SDO server. */
void co_gateway_sdo_hook(struct co_gateway_port *port);
void co_gateway_sdo_unhook(struct co_gateway_port *port);
/* ... and the SDO / remote USDO parts of co_gateway_end_connections. */
void co_gateway_sdo_end(co_gateway_t *gw);
void co_gateway_usdo_end(co_gateway_t *gw);
/* co_gateway_usdo.c, for co_gateway.c: the same for a port's USDO server
 * (unhook cancels the requests forwarded from or to the port). */
void co_gateway_usdo_hook(struct co_gateway_port *port);
void co_gateway_usdo_unhook(struct co_gateway_port *port);
/* co_gateway_sdo_buffered.c, for co_gateway_sdo.c: buffered transfers on a
 * connection (to an fd target: all of them), a connected client's request
 * (false: a classic target's frame to relay), and the end of the connection. */
void co_gateway_sdo_buffered_open(co_gateway_sdo_t *c, bool fd);
bool co_gateway_sdo_buffered_request(co_gateway_sdo_t *c, const uint8_t *data);
/* co_gateway_sdo.c, for co_gateway_sdo_buffered.c / _pipe.c: relay a request to the target. */
void co_gateway_sdo_relay(co_gateway_sdo_t *c, const uint8_t *data);
/* co_gateway_sdo_pipe.c, for co_gateway_sdo.c: a client's request (true:
 * taken), the target's answer (true: taken, not for the client), the end. */
bool co_gateway_sdo_pipe_request(co_gateway_sdo_t *c, const uint8_t *data);
bool co_gateway_sdo_pipe_answer(co_gateway_sdo_t *c, const uint8_t *data);
void co_gateway_sdo_pipe_close(co_gateway_sdo_t *c);
void co_gateway_sdo_buffered_close(co_gateway_sdo_t *c);
/* A rebuild ends the connection: the client hears `code`, a running USDO
 * transfer is stopped with its USDO counterpart. */
void co_gateway_sdo_buffered_end(co_gateway_sdo_t *c, uint32_t code);

static inline const co_gateway_stats_t *co_gateway_stats(const co_gateway_t *gw)
{
    return &gw->stats;
}

#endif
