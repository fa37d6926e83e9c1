/* Classic SDO client (CiA 301, classic lines only): expedited, segmented and
 * block download and upload, to one or many servers at once.
 *
 * Channels come from a caller-provided table (1..128 entries). A channel is
 * one SDO connection: a COB-ID client -> server (sent) and a COB-ID
 * server -> client (received). SDO is not multiplexed, so a channel runs
 * one transfer at a time. A channel is
 *   OD-bound   when an object dictionary is given and has 0x1280 + k sub 1
 *              and sub 2: sub 1 = COB-ID client -> server, sub 2 = COB-ID
 *              server -> client (bit 31 = invalid: the channel is off while
 *              either has it), sub 3 (optional, U8) = the server's node-id.
 *              Writes of those entries (network, application, a reset's
 *              defaults) take effect at once; the API cannot change them;
 *   set        by co_sdo_client_channel_set (server node-id and COB-IDs,
 *              by default the server's default channel 0x600 + n /
 *              0x580 + n);
 *   spare      otherwise: while a request to server n runs on it, it is
 *              bound to n's default channel (0x600 + n / 0x580 + n).
 * A request names the server's node-id (the client picks the channel) or a
 * channel by its index. For server n the client takes the first free
 * configured channel whose server is n; else n's default channel, on a
 * configured channel with those COB-IDs when one exists and is free, else on
 * a free spare; when the default channel is busy (or no channel is free)
 * the start is refused with 0x060A0023. So several transfers run at once to
 * different servers, and to one server over several configured channels.
 *
 * The client listens on 0x581..0x5FF as one range (one line receiver for
 * every default channel) and tells the channels apart by CAN-ID; a channel
 * configured with a server -> client CAN-ID outside that range subscribes
 * it alone (the line has CO_LINE_MAX_RECEIVERS = 32 in all).
 *
 * Channel states:
 *
 *   FREE -> start -> DL_EXPEDITED (initiate e = 1 sent, waits for 0x60)
 *                 -> DL_INIT -> DL_SEG ...                 segmented download
 *                 -> BD_INIT -> BD_SEND <-> BD_ACK -> BD_END   block download
 *                 -> UL_INIT -> done (expedited) / UL_SEG ...  upload
 *                 -> BU_INIT -> BU_DATA <-> (acks) -> BU_END   block upload
 *                            -> UL_SEG / done             (protocol switch)
 *   any -> done / abort (server's, ours, timeout, cancel) -> FREE, then done()
 *
 * Every transfer has a per-frame timeout (time without an accepted frame
 * from the server; during block download sending, without progress). Block
 * download segments go out at most CO_SDO_CLIENT_BLOCK_BURST per process
 * call while the line's tx queue is below 3/4 full, and resume when it has
 * drained to half (co_line tx-space indication). The client's timers run
 * from the line's clock: a caller that starts a transfer outside
 * co_line_process sets the line's time first (co_line_set_time).
 *
 * Nothing allocates; no globals. Wire choices and their evidence:
 * docs/protocol-notes.md, section "Classic SDO client". */
#ifndef CO_SDO_CLIENT_H
#define CO_SDO_CLIENT_H

#include "canopenfd/co_buffer.h"
#include "canopenfd/co_line.h"
#include "canopenfd/co_od.h"
#include "canopenfd/co_sdo.h"

enum {
    CO_SDO_CLIENT_DEFAULT_TIMEOUT_MS = 1000,
    /* AUTO: transfers of at least this many bytes go as block transfers
     * (downloads: the size; uploads: the request's size hint). A server
     * without block transfer costs one refused initiate (then segmented). */
    CO_SDO_CLIENT_DEFAULT_BLOCK_THRESHOLD = 1024,
    CO_SDO_CLIENT_DEFAULT_BLKSIZE = 127,    /* block upload: segments per sub-block asked */
    /* Block download: at most this many segments per co_line_process call
     * and channel (the rest follow at the next call). */
    CO_SDO_CLIENT_BLOCK_BURST = 64,
    /* Block download buffer of a channel: one sub-block of 127 segments (kept
     * until acknowledged, to repeat after a short acknowledgement). */
    CO_SDO_CLIENT_BUFFER = CO_SDO_BLKSIZE_MAX * CO_SDO_SEGMENT_DATA,
    CO_SDO_CLIENT_MAX_CHANNELS = 128        /* 0x1280 .. 0x12FF */
};
/* Largest download (0xFFFFFFFF is "unknown" for uploads). */
#define CO_SDO_CLIENT_SIZE_MAX 0xFFFFFFFEu
/* Upload total when the server did not indicate the size. */
#define CO_SDO_CLIENT_SIZE_UNKNOWN 0xFFFFFFFFu
/* block_threshold value: AUTO never picks block transfer. */
#define CO_SDO_CLIENT_NO_BLOCK 0xFFFFFFFFu

typedef enum co_sdo_mode {
    CO_SDO_MODE_AUTO = 0,
    CO_SDO_MODE_EXPEDITED,      /* uploads: a normal upload (the server picks) */
    CO_SDO_MODE_SEGMENTED,      /* uploads: a normal upload (the server picks) */
    CO_SDO_MODE_BLOCK
} co_sdo_mode_t;

/* Download source: copy `want` bytes starting at `offset` into buf; return
 * the bytes given. The client asks exactly what it needs next (in block
 * transfer up to one sub-block), each byte once, in order; anything but
 * `want` means the source failed: the client aborts 0x08000000 (sent to the
 * server) and reports it. */
typedef uint32_t (*co_sdo_source_fn)(void *ctx, uint32_t offset, uint8_t *buf, uint32_t want);
/* Upload sink: called once with len 0 and `total` = the size the server
 * indicated (CO_SDO_CLIENT_SIZE_UNKNOWN when it did not) before any data,
 * then with each chunk in order; return 0 to go on or a CiA 301 abort code
 * (e.g. 0x05040005 when total exceeds what it can hold): the client aborts
 * the transfer with that code. `data` is only valid during the call. */
typedef uint32_t (*co_sdo_sink_fn)(void *ctx, uint32_t offset, const uint8_t *data,
                                   uint32_t len, uint32_t total);

typedef struct co_sdo_request co_sdo_request_t;
/* Completion: exactly once per started request (also on cancel, timeout,
 * abort, deinit). The channel is already free: done() may start new
 * requests, the same request struct included. */
typedef void (*co_sdo_done_fn)(co_sdo_request_t *req);

struct co_sdo_request {             /* caller-owned; must live until done() */
    uint8_t server;                 /* server node-id 1..127; 0 = use `channel` */
    uint8_t channel;                /* channel index when server = 0 (a configured one) */
    uint16_t index;
    uint8_t sub;
    bool upload;
    uint8_t mode;                   /* co_sdo_mode_t */
    uint32_t size;                  /* download: total bytes (at most 0xFFFFFFFE);
                                       upload: expected size for AUTO, 0 = unknown */
    co_sdo_source_fn source;        /* downloads (may be NULL when size is 0) */
    co_sdo_sink_fn sink;            /* uploads */
    void *ctx;                      /* for source / sink */
    co_sdo_done_fn done;            /* required */
    void *user;
    uint32_t timeout_ms;            /* per frame; 0 = client default */
    uint32_t block_threshold;       /* AUTO: block from this size on; 0 = client default,
                                       CO_SDO_CLIENT_NO_BLOCK = never */
    uint8_t blksize;                /* block upload: segments per sub-block 1..127, 0 = 127 */
    uint8_t pst;                    /* block upload: protocol switch threshold (bytes),
                                       0 = no switch */
    bool no_crc;                    /* block transfers: do not offer CRC (default: offered) */
    /* SDO networking (CiA 302-7 style): reach node `network_node` of network
     * `network` through the gateway `server` (network 0: the server itself).
     * The client sends the gateway a network indication first whenever the
     * gateway's connection (remembered per server) differs. */
    uint8_t network;
    uint8_t network_node;
    /* results (written by the client) */
    uint32_t abort;                 /* 0 = ok, else the CiA 301 abort code */
    bool abort_from_server;         /* true when the server sent the abort */
    bool fell_back;                 /* AUTO: block refused, done again without block */
    bool crc_used;                  /* block: both sides supported CRC, it was checked */
    uint8_t result_mode;            /* co_sdo_mode_t used (after AUTO, a fallback, or the
                                       server's choice / protocol switch on uploads) */
    uint8_t result_channel;         /* channel index used */
    uint32_t total;                 /* upload: size the server indicated
                                       (CO_SDO_CLIENT_SIZE_UNKNOWN = not indicated) */
    uint32_t transferred;           /* download: data bytes sent (block: acknowledged;
                                       all confirmed when abort = 0); upload: bytes
                                       given to the sink */
};

typedef enum co_sdo_client_state {
    CO_SDO_CLIENT_FREE = 0,
    CO_SDO_CLIENT_DL_EXPEDITED,     /* expedited initiate sent: waits for 0x60 */
    CO_SDO_CLIENT_DL_INIT,          /* segmented initiate sent: waits for 0x60 */
    CO_SDO_CLIENT_DL_SEG,           /* segment sent: waits for 0x20 | t<<4 */
    CO_SDO_CLIENT_UL_INIT,          /* 0x40 sent: waits for the initiate response */
    CO_SDO_CLIENT_UL_SEG,           /* 0x60 | t<<4 sent: waits for a segment */
    CO_SDO_CLIENT_BD_INIT,          /* block download initiate sent: waits for 0xA0 | sc<<2 */
    CO_SDO_CLIENT_BD_SEND,          /* sending a sub-block (paced / waiting for tx space) */
    CO_SDO_CLIENT_BD_ACK,           /* sub-block sent: waits for 0xA2 */
    CO_SDO_CLIENT_BD_END,           /* end sent: waits for 0xA1 */
    CO_SDO_CLIENT_BU_INIT,          /* block upload initiate sent: waits for 0xC0 | ... */
    CO_SDO_CLIENT_BU_DATA,          /* start / ack sent: receives sub-block segments */
    CO_SDO_CLIENT_BU_END,           /* last segment acknowledged: waits for 0xC1 | n<<2 */
    CO_SDO_CLIENT_NET_IND           /* network indication sent: waits for 0xE0 or an abort */
} co_sdo_client_state_t;

/* How a channel got its COB-IDs. */
typedef enum co_sdo_client_channel_kind {
    CO_SDO_CLIENT_SPARE = 0,        /* none: bound to a default channel while in use */
    CO_SDO_CLIENT_SET,              /* co_sdo_client_channel_set */
    CO_SDO_CLIENT_OD                /* 0x1280 + k */
} co_sdo_client_channel_kind_t;

typedef struct co_sdo_client co_sdo_client_t;

typedef struct co_sdo_client_channel {
    co_sdo_client_t *client;
    co_sdo_request_t *req;
    co_timer_t timer;               /* per-frame timeout */
    co_timer_t pace;                /* block download: next burst, resume after tx space */
    uint32_t run;                   /* bumped at every start: a finished run is told
                                       from a new one after a callback */
    uint32_t tx_id;                 /* CAN-IDs: configured (valid), or bound while a
                                       spare runs a transfer; 0 otherwise */
    uint32_t rx_id;
    uint8_t number;                 /* index in the table (0x1280 + number) */
    uint8_t kind;                   /* co_sdo_client_channel_kind_t */
    uint8_t server;                 /* server node-id (0: reachable by index only) */
    bool valid;                     /* configured and usable */
    bool subscribed;                /* rx_id outside 0x581..0x5FF: own line receiver */
    uint8_t state;                  /* co_sdo_client_state_t */
    uint8_t first_data[4];          /* an expedited download's bytes while NET_IND
                                       (and for a routed initiate sent again) */
    bool indicated;                 /* routed: this transfer sent a network indication */
    uint8_t mode;                   /* co_sdo_mode_t in use */
    uint8_t toggle;                 /* segmented: toggle of the next exchange */
    bool last_sent;                 /* segmented download: the last segment is out */
    bool crc;                       /* block: CRC in use (both sides support it) */
    uint16_t crc_value;             /* CRC of the data confirmed / received so far */
    uint8_t blksize;                /* block: segments per sub-block */
    uint8_t seqno;                  /* block download: segments of the sub-block sent;
                                       block upload: last in-order seqno received */
    uint8_t segments;               /* block download: segments of the current sub-block */
    bool sub_last;                  /* block download: the current sub-block ends the data */
    bool seen;                      /* block upload: a segment arrived since the last ack */
    bool wait_space;                /* block download: waits for the tx-space indication */
    uint16_t queued;                /* block download: bytes in buf (not acknowledged) */
    uint16_t sub_len;               /* block download: data bytes of the current sub-block */
    uint32_t offset;                /* download: bytes sent (block: acknowledged);
                                       upload: bytes given to the sink */
    uint32_t total;                 /* upload: indicated size or CO_SDO_CLIENT_SIZE_UNKNOWN */
    bool last_valid;
    uint8_t last_rx[CO_SDO_FRAME_LEN];   /* the last frame taken (duplicates are ignored) */
    uint8_t held[CO_SDO_SEGMENT_DATA];   /* block upload: the segment with c = 1 */
    uint8_t buf[CO_SDO_CLIENT_BUFFER];   /* block download: the unacknowledged data */
} co_sdo_client_channel_t;

/* Everything ignored or refused is counted here (never silent). */
typedef struct co_sdo_client_stats {
    uint32_t rx_frames;             /* frames on a channel's (or the default range's) CAN-ID */
    uint32_t rx_bad_length;         /* not 8 bytes: ignored */
    uint32_t rx_fd;                 /* FD frames: ignored (a classic line drops them before) */
    uint32_t rx_idle;               /* for no channel with a transfer: ignored */
    uint32_t rx_duplicate;          /* the previous frame again, or a stale block ack: ignored */
    uint32_t rx_unexpected;         /* a command the state does not expect: ignored */
    uint32_t rx_bad_mux;            /* an initiate response or abort for another
                                       index/sub: ignored */
    uint32_t rx_unknown_command;    /* no such command: abort 0x05040001 */
    uint32_t rx_toggle;             /* abort 0x05030000 */
    uint32_t rx_bad_seqno;          /* abort 0x05040003 */
    uint32_t rx_bad_blksize;        /* abort 0x05040002 */
    uint32_t rx_crc;                /* abort 0x05040004 */
    uint32_t rx_size_mismatch;      /* upload data other than the indicated size: 0x06070010 */
    uint32_t rx_block_ignored;      /* block upload: segment repeated or after a gap: ignored */
    uint32_t block_partial_acks;    /* block upload: a sub-block acknowledged short */
    uint32_t block_repeats;         /* block download: segments sent again after a short ack */
    uint32_t protocol_switches;     /* block upload answered as a normal upload */
    uint32_t block_fallback;        /* AUTO: block refused with 0x05040001, done without */
    uint32_t started;
    uint32_t refused;               /* co_sdo_client_start said no */
    uint32_t completed;             /* ended with abort = 0 */
    uint32_t failed;                /* ended with an abort (any origin) */
    uint32_t timeouts;              /* our 0x05040000 */
    uint32_t aborts_received;
    uint32_t aborts_sent;
    uint32_t cancelled;
    uint32_t source_failed;         /* a source gave fewer bytes than asked: 0x08000000 */
    uint32_t sink_refused;          /* a sink returned an abort code */
    uint32_t tx_failed;             /* co_line_send refused (queue full) */
    uint32_t tx_paused;             /* block download stopped to wait for tx space */
    uint32_t channel_resets;        /* a transfer ended because its channel was reconfigured */
    uint32_t config_refused;        /* COB-IDs that cannot be used (29-bit, taken, restricted) */
} co_sdo_client_stats_t;

/* Sees the frames of 0x581..0x5FF no channel with a transfer takes; true =
 * taken (not counted idle). The gateway's SDO networking relays answers of
 * nodes this client is not talking to through it. */
typedef bool (*co_sdo_client_idle_fn)(co_sdo_client_t *client, const co_frame_t *frame,
                                      void *user);

struct co_sdo_client {
    co_line_t *line;                /* NULL when not initialised */
    co_sdo_client_idle_fn idle_tap; /* NULL: none */
    void *idle_user;
    co_od_t *od;                    /* NULL: no OD-bound channels */
    co_sdo_client_channel_t *channels;
    uint8_t channel_count;
    uint8_t space_rr;               /* who resumes first after tx space (fairness) */
    uint8_t waiting;                /* channels waiting for tx space */
    bool od_hooked;
    uint64_t timeout_us;
    uint32_t block_threshold;
    /* SDO networking: per server node-id, the connection its gateway holds
     * for us (network | node << 8; 0 = its own OD; 0xFFFF = not known: an
     * indication ended unanswered, the next request sends one) */
    uint16_t routed[128];
    co_sdo_client_stats_t stats;
};

typedef struct co_sdo_client_config {
    co_sdo_client_channel_t *channels;
    uint8_t channel_count;          /* 1..128; channel k is 0x1280 + k */
    co_od_t *od;                    /* optional (sealed): channels from 0x1280.. */
    uint32_t timeout_ms;            /* default per-frame timeout, 0 = 1000 */
    uint32_t block_threshold;       /* default AUTO block threshold, 0 = 1024 */
} co_sdo_client_config_t;

/* Classic lines only; subscribes 0x581..0x5FF, registers for the line's tx
 * space indication and, with an OD, for writes of 0x1280..; reads the
 * OD-bound channels. False on an fd line, a bad configuration, or when the
 * range, the indication table or the OD's handler table is taken. */
bool co_sdo_client_init(co_sdo_client_t *c, co_line_t *line, const co_sdo_client_config_t *cfg);
/* Open requests end with 0x08000000 (done() called), nothing is sent; no
 * request can start afterwards (until a new init). */
void co_sdo_client_deinit(co_sdo_client_t *c);
/* Read every OD-bound channel again (e.g. after the OD was replaced whole). */
void co_sdo_client_refresh(co_sdo_client_t *c);

/* Configure channel `ch` for server node-id `server` (0 = only by index):
 * tx_id = COB-ID client -> server, rx_id = server -> client (11-bit CAN-IDs);
 * both 0 = the server's default channel 0x600 + server / 0x580 + server.
 * False (nothing changed) when ch is out of range or OD-bound, server > 127,
 * the CAN-IDs are not usable (above 0x7FF, equal, CiA 301 restricted
 * other than 0x601..0x67F sent / 0x581..0x5FF received), used by another
 * configured channel, or the received one is taken on the line. A transfer
 * on this channel (or on a spare bound to these CAN-IDs) whose CAN-IDs
 * change ends: abort 0x08000000 sent, done() with it. */
bool co_sdo_client_channel_set(co_sdo_client_t *c, uint8_t ch, uint8_t server, uint32_t tx_id,
                               uint32_t rx_id);
/* Make a set channel a spare again (an open transfer ends as above). False
 * when ch is out of range or OD-bound. */
bool co_sdo_client_channel_clear(co_sdo_client_t *c, uint8_t ch);

/* Start: 0 when started (done() will be called once), else a CiA 301 abort
 * code saying why not, and done() is never called:
 *   0x060A0023  the channel it needs is busy / no free channel, or the tx
 *               queue refused the first frame
 *   0x06070010  EXPEDITED mode with a download size of 0 or above 4
 *   0x05040002  blksize above 127
 *   0x08000000  bad request: no done(), server > 127, channel index out of
 *               range or not configured, no sink on an upload, no source for
 *               data, unknown mode, size 0xFFFFFFFF, the request already
 *               running, client not initialised, or an expedited download
 *               whose source failed.
 * Frames go out relative to the line's time of its last process call. */
uint32_t co_sdo_client_start(co_sdo_client_t *c, co_sdo_request_t *req);
/* Cancel: sends an abort frame with `code` (0 = 0x08000000 general error)
 * to the server, completes the request with that code and frees the
 * channel. False when req is not running. */
bool co_sdo_client_cancel(co_sdo_client_t *c, co_sdo_request_t *req, uint32_t code);
/* Channels with a transfer. */
uint8_t co_sdo_client_active(const co_sdo_client_t *c);
/* Set the one idle-frame tap (fn NULL: clear). */
void co_sdo_client_set_idle_tap(co_sdo_client_t *c, co_sdo_client_idle_fn fn, void *user);
/* Clear the tap only when it is fn with user (another user's stays). */
void co_sdo_client_clear_idle_tap(co_sdo_client_t *c, co_sdo_client_idle_fn fn, void *user);
/* Whether CAN-ID `id` reaches this client's 0x581..0x5FF receiver (so its
 * idle tap sees it when no transfer uses it). */
bool co_sdo_client_holds(const co_sdo_client_t *c, uint32_t id);
/* Whether a channel with a transfer receives on CAN-ID `id`. */
bool co_sdo_client_receives(const co_sdo_client_t *c, uint32_t id);
bool co_sdo_client_running(const co_sdo_client_t *c, const co_sdo_request_t *req);
/* The mode AUTO resolves to for a download of `size` bytes with this block
 * threshold (0 = the default): 1..4 bytes expedited, from the threshold on
 * block, else segmented (also 0 bytes). Other modes are returned as they
 * are. */
co_sdo_mode_t co_sdo_client_choose_mode(uint8_t mode, uint32_t size, uint32_t threshold);

/* Buffer source/sink for tests, benches and simple callers. Source: the
 * first `size` bytes of data. Sink: refuses (0x05040005) an indicated total
 * or data beyond `capacity`; `size` = bytes held. */
typedef co_buffer_t co_sdo_buffer_t;   /* see co_buffer.h */
uint32_t co_sdo_buffer_source(void *ctx, uint32_t offset, uint8_t *buf, uint32_t want);
uint32_t co_sdo_buffer_sink(void *ctx, uint32_t offset, const uint8_t *data, uint32_t len,
                            uint32_t total);

#endif
