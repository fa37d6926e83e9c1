/* USDO client (CiA 1301, fd lines only): expedited, segmented and bulk
 * download, expedited, segmented and bulk upload, unicast and broadcast,
 * many transfers at once to one or many servers.
 *
 * The client has its own node-id (a tool without a local node can be client
 * 0x7F): requests go out on 0x600 + that node-id with byte 0 = the server's
 * node-id (0 = broadcast); a server answers on 0x580 + its node-id with
 * byte 0 = our node-id and our session-ID echoed. Any other frame on
 * 0x581..0x5FF is ignored and counted.
 *
 * Sessions come from a caller-provided table; each runs one request. A
 * session-ID is allocated per request, round-robin over 1..255, never one
 * that is live (so a late answer to a finished transfer meets no session
 * for 254 allocations). Session states:
 *
 *   FREE -> start -> DL_EXPEDITED (0x01 sent, waits for 0x21)
 *                 -> UL_INIT (0x11 sent) -> 0x31: done
 *                                        -> 0x32: UL_SEG ... (0x13 / 0x33 until 0x34)
 *                 -> UL_BULK_INIT (0x16 sent) -> 0x36: UL_BULK ... (0x37 streamed,
 *                                        a 0x17 every half window, until 0x38)
 *                                        (0x31 / 0x32 taken too: the server's choice)
 *                 -> DL_INIT -> DL_SEG ... -> DL_LAST           segmented download
 *                    (DL_WAIT_SOURCE between segments while the source says
 *                     LATER, until co_usdo_client_resume)
 *                 -> BULK_INIT -> BULK_SEND -> BULK_LAST         bulk download
 *                 -> BROADCAST (collects answers until the window ends)
 *   any -> done / abort (server's, ours, timeout, cancel) -> FREE, then done()
 *
 * Every session has a per-frame timeout (time without a frame from the
 * server; re-armed by every accepted frame, and during bulk sending by
 * every segment sent). Bulk segments go back to back, at most
 * CO_USDO_CLIENT_BULK_BURST per process call, while the line's tx queue is
 * below 3/4 full (a quarter stays free for other services), and resume when
 * it has drained to half (co_line tx-space indication); a server's pacing
 * is honoured with a timer. A bulk upload gives the server a window of
 * segments it may send beyond those acknowledged; the windows of all bulk
 * uploads running together never exceed half the line's receive queue, so
 * the server's stream cannot overflow it (see co_usdo_client_config_t). The client's timers run from the line's clock:
 * a caller that starts a transfer outside co_line_process sets the line's
 * time first (co_line_set_time), or the per-frame timeout counts from the
 * last process call. Wire choices and their
 * evidence: docs/protocol-notes.md, section "USDO client". */
#ifndef CO_USDO_CLIENT_H
#define CO_USDO_CLIENT_H

#include "canopenfd/co_buffer.h"
#include "canopenfd/co_line.h"
#include "canopenfd/co_usdo.h"

enum {
    CO_USDO_CLIENT_DEFAULT_TIMEOUT_MS = 1000,
    CO_USDO_CLIENT_DEFAULT_MAX_PACING = 100,   /* 100 us units: 10 ms */
    /* AUTO downloads: <= 56 bytes expedited, up to this size segmented,
     * from this size on bulk (68+ segments: the per-segment round trip
     * starts to dominate). */
    CO_USDO_CLIENT_BULK_THRESHOLD = 4096,
    /* Pacing gaps below this go out as bursts: k segments every k gaps, so
     * the timer is never asked for less than about 1 ms. */
    CO_USDO_CLIENT_PACE_TICK_US = 1000,
    /* Unpaced bulk: at most this many segments per co_line_process call
     * (the rest follow at the next call), so a receiver on the same thread
     * or behind a small socket buffer reads between bursts. */
    CO_USDO_CLIENT_BULK_BURST = 64,
    /* Bulk upload window (segments the server may send beyond those we
     * acknowledged), before the cap by the receive queue (see the config). */
    CO_USDO_CLIENT_DEFAULT_BULK_WINDOW = 64
};
/* Largest download: 0xFFFFFFFF means "unknown size" in USDO size fields. */
#define CO_USDO_CLIENT_SIZE_MAX 0xFFFFFFFEu
/* co_usdo_client_resume: the request runs but does not wait for its source
 * (not a USDO abort code: never sent). */
#define CO_USDO_CLIENT_NOT_WAITING 0x01u

typedef enum co_usdo_mode {
    CO_USDO_MODE_AUTO = 0,
    CO_USDO_MODE_EXPEDITED,
    CO_USDO_MODE_SEGMENTED,
    CO_USDO_MODE_BULK
} co_usdo_mode_t;

/* Download source: copy up to `want` bytes starting at `offset` into buf;
 * return the bytes given. The client always asks exactly what is left of
 * the chunk it sends, so anything but `want` (or CO_USDO_SOURCE_LATER where
 * allowed) means the source failed: the client aborts 0x10 (sent to the
 * server) and reports it. */
typedef uint32_t (*co_usdo_source_fn)(void *ctx, uint32_t offset, uint8_t *buf, uint32_t want);
/* "Not yet": the source has no data for this segment now. Only for a
 * segment of a segmented download (0x03 / 0x04, also the segmented retry
 * of an AUTO bulk refused with 0x13): the client sends nothing, keeps the
 * session open (state DL_WAIT_SOURCE, stats.source_waits counted) and
 * STOPS its per-frame timeout, since the server owes nothing while our
 * data is late. The caller owns that wait: it calls co_usdo_client_resume
 * when the data is there, or co_usdo_client_cancel to give up (the server's
 * own timeout keeps running on its side). Anywhere else it is a failed
 * source, as any short count: an expedited download (read at start: the
 * start is refused 0x10, nothing sent) and a bulk download (abort 0x10). A
 * source that may say LATER asks for CO_USDO_MODE_SEGMENTED. */
#define CO_USDO_SOURCE_LATER 0xFFFFFFFFu
/* Upload sink: called once with len 0 and `total` = announced size
 * (0xFFFFFFFF unknown) before any data, then with each chunk in order;
 * return 0 to go on or a USDO abort code (e.g. 0x16 when total exceeds what
 * it can hold): the client aborts the transfer with that code. `data` is
 * only valid during the call. */
typedef uint8_t (*co_usdo_sink_fn)(void *ctx, uint32_t offset, const uint8_t *data,
                                   uint32_t len, uint32_t total);

typedef struct co_usdo_request co_usdo_request_t;
/* Completion: exactly once per started request (also on cancel, timeout,
 * abort, deinit). The session is already free: done() may start new
 * requests, the same request struct included. */
typedef void (*co_usdo_done_fn)(co_usdo_request_t *req);
/* Broadcast: one call per answering server: abort = 0 with the expedited
 * data (upload) or no data (download acknowledged), or the abort code (the
 * server's, or ours for an answer we refused). data valid during the call. */
typedef void (*co_usdo_answer_fn)(co_usdo_request_t *req, uint8_t node, uint8_t abort,
                                  uint8_t type, const uint8_t *data, uint32_t len);

struct co_usdo_request {            /* caller-owned; must live until done() */
    uint8_t server;                 /* node-id 1..127, 0 = broadcast */
    uint16_t index;
    uint8_t sub;
    bool upload;
    uint8_t mode;                   /* co_usdo_mode_t; uploads: AUTO (0x11, or bulk for a
                                       size hint >= CO_USDO_CLIENT_BULK_THRESHOLD) or BULK */
    uint8_t type;                   /* data type byte sent with a download; 0 is sent as
                                       0x0F (DOMAIN = raw bytes) */
    uint32_t size;                  /* download: total bytes (at most 0xFFFFFFFE);
                                       upload: bytes expected, 0 = unknown (AUTO's choice) */
    co_usdo_source_fn source;       /* downloads (may be NULL when size is 0) */
    co_usdo_sink_fn sink;           /* unicast uploads */
    void *ctx;                      /* for source / sink */
    co_usdo_done_fn done;           /* required */
    co_usdo_answer_fn answer;       /* broadcast (may be NULL: answers only counted) */
    void *user;
    uint32_t timeout_ms;            /* per frame; broadcast: the collection window;
                                       0 = client default */
    /* Remote (routed) USDO: network != 0 sends the request to the gateway
     * `server` as a remote request (cs | 0x80) for node `network_node` of
     * network `network`; `source_network` is the network-id of our own
     * line (written in the request, the gateway checks it). Downloads up to
     * 52 bytes go expedited, larger ones segmented; bulk is refused. */
    uint8_t network;
    uint8_t network_node;
    uint8_t source_network;
    /* results (written by the client) */
    uint8_t abort;                  /* 0 = ok, else USDO abort code */
    bool abort_from_server;         /* true when the server sent the abort */
    uint8_t result_type;            /* upload: data type byte the server sent */
    uint8_t result_mode;            /* mode used (after AUTO and a bulk fallback) */
    uint8_t session_id;             /* session-ID of the (last) attempt */
    uint16_t pacing;                /* bulk: pacing the server asked (before the cap) */
    uint32_t transferred;           /* download: data bytes sent (all confirmed when
                                       abort = 0); upload: bytes given to the sink */
    uint32_t answers;               /* broadcast: servers that answered */
};

typedef struct co_usdo_client co_usdo_client_t;

typedef enum co_usdo_client_state {
    CO_USDO_CLIENT_FREE = 0,
    CO_USDO_CLIENT_DL_EXPEDITED,    /* 0x01 sent: waits for 0x21 */
    CO_USDO_CLIENT_UL_INIT,         /* 0x11 sent: waits for 0x31 / 0x32 */
    CO_USDO_CLIENT_DL_INIT,         /* 0x02 sent: waits for 0x22 */
    CO_USDO_CLIENT_DL_SEG,          /* 0x03 sent: waits for 0x23 */
    CO_USDO_CLIENT_DL_LAST,         /* 0x04 sent: waits for 0x24 */
    CO_USDO_CLIENT_UL_SEG,          /* 0x13 sent: waits for 0x33 / 0x34 */
    CO_USDO_CLIENT_BULK_INIT,       /* 0x06 sent: waits for 0x26 */
    CO_USDO_CLIENT_BULK_SEND,       /* sending 0x07 (paced / waiting for tx space) */
    CO_USDO_CLIENT_BULK_LAST,       /* 0x08 sent: waits for 0x28 */
    CO_USDO_CLIENT_BROADCAST,       /* collecting answers until the window ends */
    CO_USDO_CLIENT_UL_BULK_INIT,    /* 0x16 sent: waits for 0x36 (or 0x31 / 0x32) */
    CO_USDO_CLIENT_UL_BULK,         /* taking 0x37 until 0x38, acknowledging with 0x17 */
    CO_USDO_CLIENT_DL_WAIT_SOURCE   /* segmented download: the source said LATER; no
                                       timeout, waits for co_usdo_client_resume */
} co_usdo_client_state_t;

typedef struct co_usdo_client_session {
    co_usdo_client_t *client;
    co_usdo_request_t *req;
    co_timer_t timer;               /* per-frame timeout; broadcast: the window */
    co_timer_t pace;                /* bulk: next burst, or resume after tx space */
    uint64_t next_at;               /* bulk: earliest time of the next burst */
    uint32_t run;                   /* bumped at every start: a finished run is told
                                       from a new one after a callback */
    uint32_t offset;                /* data bytes moved so far */
    uint32_t total;                 /* upload: announced size (0xFFFFFFFF unknown) */
    uint32_t period_us;             /* bulk: time between bursts, 0 = unpaced */
    uint32_t answered[4];           /* broadcast: one bit per node-id that answered */
    uint8_t state;                  /* co_usdo_client_state_t */
    uint8_t mode;                   /* co_usdo_mode_t in use */
    uint8_t session_id;
    uint8_t counter;                /* segment counter outstanding / next to send */
    uint8_t burst;                  /* bulk: segments per burst */
    uint8_t since_ack;              /* bulk upload: segments taken since our last 0x17 */
    bool short_seen;                /* bulk upload: a segment of fewer than 60 bytes came */
    uint32_t taken;                 /* bulk upload: segments taken */
    uint32_t acked;                 /* bulk upload: segments our last 0x17 acknowledged */
    bool wait_space;                /* bulk: waits for the tx-space indication */
    bool bulk_rx;                   /* bulk upload: holds a window of the receive budget */
} co_usdo_client_session_t;

/* cffi:begin */
/* Everything ignored or refused is counted here (never silent). */
typedef struct co_usdo_client_stats {
    uint32_t rx_frames;             /* frames on 0x581..0x5FF given to the client */
    uint32_t rx_not_fd;             /* classic frames: ignored */
    uint32_t rx_other_dest;         /* byte 0 is not our node-id: ignored */
    uint32_t rx_no_session;         /* no live session (server, session-ID): stray or late */
    uint32_t rx_malformed;          /* too short / bad length (0x1E when the session
                                       expected that command, else ignored) */
    uint32_t rx_unexpected;         /* command not expected in the session's state: ignored */
    uint32_t rx_bad_counter;        /* abort 0x14 */
    uint32_t rx_bad_mux;            /* index/sub-index differ from the request: abort 0x1F */
    uint32_t rx_size_mismatch;      /* upload longer/shorter than announced: abort 0x15 */
    uint32_t rx_duplicate;          /* broadcast: a second answer of one server: ignored */
    uint32_t started;
    uint32_t refused;               /* co_usdo_client_start said no */
    uint32_t completed;             /* ended with abort = 0 */
    uint32_t failed;                /* ended with an abort (any origin) */
    uint32_t timeouts;              /* our 0x12 */
    uint32_t aborts_received;
    uint32_t aborts_sent;
    uint32_t cancelled;
    uint32_t source_failed;         /* a source gave fewer bytes than asked: 0x10 */
    uint32_t sink_refused;          /* a sink returned an abort code */
    uint32_t tx_failed;             /* co_line_send refused (queue full) */
    uint32_t bulk_paused;           /* bulk sending stopped to wait for tx space */
    uint32_t bulk_fallback;         /* AUTO: bulk refused with 0x13, retried segmented
                                       (downloads) or as a plain upload (uploads) */
    uint32_t rx_short_segment;      /* segment with fewer than 60 data bytes: accepted */
    uint32_t bulk_uploads;          /* bulk uploads completed */
    uint32_t acks_sent;             /* bulk upload acknowledgements (0x17) */
    uint32_t bulk_budget_full;      /* bulk upload not started: the receive budget is
                                       taken (AUTO went plain, BULK refused 0x70) */
    uint32_t source_waits;          /* a segmented download's source said LATER */
} co_usdo_client_stats_t;
/* cffi:end */

struct co_usdo_client {
    co_line_t *line;                /* NULL when not initialised */
    co_usdo_client_session_t *sessions;
    uint8_t session_count;
    uint8_t node_id;
    uint8_t next_sid;               /* round-robin session-ID allocation */
    uint8_t space_rr;               /* who resumes first after tx space (fairness) */
    uint8_t waiting;                /* sessions waiting for tx space */
    uint16_t max_pacing;
    uint8_t bulk_window;            /* bulk upload window (segments) */
    uint8_t bulk_rx;                /* bulk uploads holding a window now */
    uint32_t bulk_budget;           /* segments all windows together may hold */
    uint64_t timeout_us;
    uint32_t live_sid[8];           /* one bit per live session-ID */
    co_usdo_client_stats_t stats;
};

typedef struct co_usdo_client_config {
    co_usdo_client_session_t *sessions;
    uint8_t session_count;          /* 1..255 */
    uint8_t node_id;                /* our client node-id 1..127 (not the line's node-id) */
    uint32_t timeout_ms;            /* default per-frame timeout, 0 = 1000 */
    uint16_t max_pacing;            /* cap on a server's bulk pacing, 100 us units, 0 = 100 */
    uint8_t bulk_window;            /* bulk upload window in segments, 0 = 64; capped at a
                                       quarter of the line's receive queue (at least 1).
                                       Bulk uploads run together only while their windows
                                       fit in half the receive queue. */
} co_usdo_client_config_t;

/* fd lines only; subscribes 0x581..0x5FF and registers for the line's tx
 * space indication. False on a classic line, a bad configuration, or when
 * the range or the indication table is taken. */
bool co_usdo_client_init(co_usdo_client_t *c, co_line_t *line, const co_usdo_client_config_t *cfg);
/* Open requests end with abort 0x10 (done() called), nothing is sent; no
 * request can start afterwards (until a new init). */
void co_usdo_client_deinit(co_usdo_client_t *c);

/* Start: 0 when started (done() will be called once), else a USDO abort
 * code saying why not, and done() is never called:
 *   0x70  no free session, the tx queue refused the first frame, or a BULK
 *         upload whose window does not fit in the receive budget now
 *   0x1E  EXPEDITED mode (or a broadcast download) with more than 56 bytes
 *   0x10  bad request: no done(), server > 127 or = our node-id, no sink on
 *         a unicast upload, no source for data, unknown mode, a broadcast
 *         bulk upload, size
 *         0xFFFFFFFF, a broadcast download not expedited, the request
 *         already running, client not initialised, or an expedited
 *         download whose source failed.
 * Frames go out relative to the line's time of its last process call. */
uint8_t co_usdo_client_start(co_usdo_client_t *c, co_usdo_request_t *req);
/* Cancel: sends an abort frame with `code` (0 = 0x10 general error) to the
 * server (broadcast: to all), completes the request with that code and
 * frees the session. False when req is not running. */
bool co_usdo_client_cancel(co_usdo_client_t *c, co_usdo_request_t *req, uint8_t code);
/* Resume a segmented download whose source said CO_USDO_SOURCE_LATER: the
 * waiting segment is asked of the source again and sent with the per-frame
 * timeout re-armed (the source may say LATER again: it waits again; a
 * failing source aborts 0x10 as usual). Returns 0 then;
 * CO_USDO_CLIENT_NOT_WAITING (nothing done, nothing sent) when req runs but
 * does not wait for its source, e.g. a segment's answer is still due or
 * the resume comes from inside the source; 0x10 when req is not running or
 * the client is not initialised. */
uint8_t co_usdo_client_resume(co_usdo_client_t *c, co_usdo_request_t *req);
/* Sessions in use. */
uint8_t co_usdo_client_active(const co_usdo_client_t *c);
bool co_usdo_client_running(const co_usdo_client_t *c, const co_usdo_request_t *req);
/* The mode AUTO resolves to for a download of `size` bytes (other modes are
 * returned as they are). */
co_usdo_mode_t co_usdo_client_choose_mode(uint8_t mode, uint32_t size);
/* Uploads: BULK for BULK, or for AUTO with a size hint of at least
 * CO_USDO_CLIENT_BULK_THRESHOLD; else AUTO (0x11: the server picks
 * expedited or segmented). */
co_usdo_mode_t co_usdo_client_choose_upload_mode(uint8_t mode, uint32_t size_hint);

/* Buffer source/sink for tests, benches and simple callers. Source: the
 * first `size` bytes of data. Sink: refuses (0x16) an announced total or
 * data beyond `capacity`; `size` = bytes held. */
typedef co_buffer_t co_usdo_buffer_t;   /* see co_buffer.h */
uint32_t co_usdo_buffer_source(void *ctx, uint32_t offset, uint8_t *buf, uint32_t want);
uint8_t co_usdo_buffer_sink(void *ctx, uint32_t offset, const uint8_t *data, uint32_t len,
                            uint32_t total);

#endif
