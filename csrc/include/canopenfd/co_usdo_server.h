/* USDO server (CiA 1301, fd lines only): expedited, segmented and bulk
 * download, expedited, segmented and bulk upload of the local object
 * dictionary, several sessions at once.
 *
 * Requests arrive on 0x601..0x67F (0x600 + client node-id) with byte 0 =
 * our node-id or 0 (broadcast, answered individually); answers go out on
 * 0x580 + our node-id with byte 0 = the client's node-id and the session-ID
 * echoed. A transfer is identified by (client node-id, session-ID).
 *
 * Sessions come from a caller-provided table; each owns a co_od_xfer_t with
 * its own slice of a caller-provided scratch buffer (at least the OD's
 * largest entry size: co_usdo_server_scratch_need). Session states:
 *
 *   FREE -> (request) -> an answer at once, back to FREE          expedited
 *                     -> DOWNLOAD / UPLOAD (segments follow)      segmented
 *                     -> BULK (segments follow, none answered     bulk download
 *                        until the last one)
 *                     -> BULK_UPLOAD (0x36, then segments streamed within the
 *                        client's window; each 0x17 moves the window on)
 *                     -> PENDING (a handler split; waits for co_usdo_server_resume)
 *   DOWNLOAD / BULK -> (last segment) -> answer, FREE, or PENDING (split)
 *   DOWNLOAD/UPLOAD/BULK/PENDING -> idle timeout -> timeout abort sent -> FREE
 *                              (PENDING -> ABANDONED: the slot stays taken
 *                              until the application's resume, which then
 *                              only frees it; nothing is written or sent)
 *
 * Every non-free session has its own timer, re-armed by each frame of its
 * transfer. Wire choices and their evidence: docs/protocol-notes.md. */
#ifndef CO_USDO_SERVER_H
#define CO_USDO_SERVER_H

#include "canopenfd/co_line.h"
#include "canopenfd/co_nmt.h"
#include "canopenfd/co_od.h"
#include "canopenfd/co_usdo.h"

enum { CO_USDO_SERVER_DEFAULT_TIMEOUT_MS = 1000 };

typedef enum co_usdo_session_state {
    CO_USDO_SESSION_FREE = 0,
    CO_USDO_SESSION_ACTIVE,      /* inside a co_od call (not resumable yet) */
    CO_USDO_SESSION_DOWNLOAD,    /* segmented download: waiting for the next segment */
    CO_USDO_SESSION_UPLOAD,      /* segmented upload: waiting for the next segment request */
    CO_USDO_SESSION_PENDING,     /* a handler split: waiting for co_usdo_server_resume */
    CO_USDO_SESSION_ABANDONED,   /* was PENDING, then timed out / aborted: freed by the resume */
    CO_USDO_SESSION_BULK,        /* bulk download: waiting for the next (unanswered) segment */
    CO_USDO_SESSION_BULK_UPLOAD  /* bulk upload: streaming within the client's window */
} co_usdo_session_state_t;

typedef struct co_usdo_server co_usdo_server_t;

typedef struct co_usdo_session {
    co_usdo_server_t *server;
    co_timer_t timer;
    co_od_xfer_t xfer;
    uint8_t state;              /* co_usdo_session_state_t */
    uint8_t answer;             /* PENDING: which answer the resume sends */
    uint8_t client;             /* node-id of the client */
    uint8_t session_id;
    uint8_t sub;
    uint16_t index;
    uint8_t counter;            /* next segment counter expected */
    uint32_t total;             /* download: announced size */
    uint32_t received;          /* download: data bytes received */
    uint32_t sent;              /* bulk upload: segments sent (0x37 and 0x38) */
    uint32_t acked;             /* bulk upload: segments the client acknowledged */
    uint8_t window;             /* bulk upload: the client's window (segments) */
    bool tx_wait;               /* bulk upload: stopped for tx room */
    bool tx_resume;             /* bulk upload: tx room came back, the timer resumes it */
} co_usdo_session_t;

/* cffi:begin */
/* Everything refused or ignored is counted here (never silent). */
typedef struct co_usdo_server_stats {
    uint32_t rx_frames;          /* frames on 0x601..0x67F given to the server */
    uint32_t rx_not_fd;          /* classic frames: ignored */
    uint32_t rx_no_node;         /* the line has no node-id yet: ignored */
    uint32_t rx_empty;           /* fewer than 3 bytes: ignored */
    uint32_t rx_other_dest;      /* byte 0 names another node: ignored */
    uint32_t rx_remote_abort;    /* 0xFF (remote USDO abort): ignored */
    uint32_t rx_malformed;       /* too short / bad length for its layout: abort 0x1E */
    uint32_t rx_unknown_command; /* unknown or unexpected command specifier: abort 0x13 */
    uint32_t rx_no_session;      /* segment for no open transfer: abort 0x21 */
    uint32_t rx_stray_bulk;      /* bulk segment (0x07) for no open transfer: ignored */
    uint32_t rx_bad_counter;     /* abort 0x14 */
    uint32_t rx_size_mismatch;   /* abort 0x15 */
    uint32_t rx_client_abort;    /* a client aborted an open transfer */
    uint32_t rx_stray_abort;     /* a client abort for no open transfer: ignored */
    uint32_t restarts;           /* a new request on an open (client, session-ID) */
    uint32_t busy;               /* abort 0x70: no free session */
    uint32_t parallel;           /* abort 0x20: index:sub in use by another session */
    uint32_t timeouts;           /* abort 0x12 */
    uint32_t od_aborts;          /* transfers refused by the object dictionary */
    uint32_t downloads;          /* completed */
    uint32_t uploads;            /* completed */
    uint32_t aborts_sent;
    uint32_t tx_failed;          /* co_line_send refused (queue full) */
    uint32_t rx_not_serving;     /* the node is stopped (no USDO then): ignored */
    uint32_t closed_by_state;    /* open transfers ended silently on leaving pre-op/op */
    uint32_t rx_short_segment;   /* segment with fewer than 60 data bytes: accepted */
    uint32_t rx_bad_window;      /* bulk upload request with window 0: abort 0x11 */
    uint32_t rx_stray_ack;       /* bulk upload ack (0x17) for no open transfer: ignored */
    uint32_t bulk_uploads;       /* bulk uploads completed (also counted in uploads) */
    uint32_t tx_deferred;        /* bulk upload stopped until the tx queue drained */
} co_usdo_server_stats_t;
/* cffi:end */

/* A remote (routed) request or abort addressed to this server's node (the
 * frame decoded: m->remote, m->cs the local command specifier, r the
 * decode result). True when taken (a gateway relays it), false: the server
 * answers a request 0x13 and counts an abort. */
typedef bool (*co_usdo_remote_fn)(co_usdo_server_t *server, uint8_t client,
                                  co_usdo_decode_result_t r, const co_usdo_msg_t *m, void *user);

struct co_usdo_server {
    co_line_t *line;
    co_usdo_remote_fn remote_fn;  /* co_usdo_server_set_remote_handler */
    void *remote_user;
    co_od_t *od;
    co_usdo_session_t *sessions;
    uint8_t session_count;
    uint64_t timeout_us;
    uint16_t bulk_pacing;        /* sent in 0x26: 100 us units, 0 = none */
    bool not_serving;            /* NMT state outside pre-operational / operational */
    co_usdo_server_stats_t stats;
};

typedef struct co_usdo_server_config {
    co_usdo_session_t *sessions;  /* session table (session_count entries) */
    uint8_t session_count;        /* 1..255 */
    uint8_t *scratch;             /* session_count * scratch_size bytes */
    uint32_t scratch_size;        /* per session: >= co_usdo_server_scratch_need(od) */
    uint32_t timeout_ms;          /* idle timeout of a session; 0 = default (1000) */
    uint16_t bulk_pacing;         /* minimum gap between bulk segments asked of a client,
                                     sent in 0x26: units of 100 us, 0 = none */
} co_usdo_server_config_t;

/* Scratch bytes one session needs: the largest entry size of the OD. */
uint32_t co_usdo_server_scratch_need(const co_od_t *od);

/* Serve `od` on `line` (an fd line; the node-id is read from co_line_node_id
 * at every request, so requests before a node exists are ignored). False on
 * a classic line, a bad configuration, when 0x601..0x67F is taken or the
 * line's tx-space indication table is full (bulk uploads wait on it). */
bool co_usdo_server_init(co_usdo_server_t *server, co_line_t *line, co_od_t *od,
                         const co_usdo_server_config_t *config);
/* Unsubscribe; open transfers are aborted (a domain writer is told),
 * nothing is sent. */
void co_usdo_server_deinit(co_usdo_server_t *server);

/* The application's answer to a split (a before_read / check_write handler
 * returned CO_OD_SPLIT for this xfer): abort = 0 goes on, an abort code
 * refuses, CO_OD_SPLIT keeps waiting. The answer frame is sent from here
 * (the line's time is that of its last process call). Returns false when
 * no session waits on xfer (unknown xfer, called from inside the handler,
 * or the session was abandoned: then it is freed here, nothing is sent). */
bool co_usdo_server_resume(co_usdo_server_t *server, co_od_xfer_t *xfer, uint32_t abort);

/* Route remote requests (cs 0x8x, 0xFF) to fn (NULL: none, answered 0x13). */
void co_usdo_server_set_remote_handler(co_usdo_server_t *server, co_usdo_remote_fn fn,
                                       void *user);

/* Sessions not FREE. */
uint8_t co_usdo_server_active(const co_usdo_server_t *server);

/* The node's NMT state (the node calls it; a server without a node serves
 * always). Like SDO in CiA 301, USDO is served only in pre-operational and
 * operational: in any other state requests are ignored (counted
 * rx_not_serving) and leaving those states ends open transfers without an
 * abort frame (the object dictionary learns of it with 0x08000022). */
void co_usdo_server_set_nmt_state(co_usdo_server_t *server, co_nmt_state_t state);

#endif
