/* Classic SDO server (CiA 301, classic lines only): expedited, segmented and
 * block download and upload of the local object dictionary over one or more
 * SDO server channels.
 *
 * Channels come from a caller-provided table:
 *   channel 0      the default server: requests on 0x600 + node-id, answers
 *                  on 0x580 + node-id (the line's node-id), always valid;
 *                  an OD entry 0x1200 is not read (CiA 301 makes it
 *                  read-only: it only describes this channel);
 *   channel k>=1   further servers, configured from OD entries
 *                  0x1200 + k sub 1 (COB-ID client -> server, received) and
 *                  sub 2 (COB-ID server -> client, sent): the channel serves
 *                  while both have bit 31 clear. Writes of those entries
 *                  (network, application or a reset's defaults) take effect
 *                  at once; a channel without the entries stays off.
 * One transfer per channel at a time (SDO is not multiplexed); a new
 * initiate on a busy channel ends the open transfer silently and starts the
 * new one. Each channel owns a co_od_xfer_t and a slice of a caller-provided
 * scratch buffer (co_sdo_server_scratch_need), and an idle timer.
 *
 *   IDLE -> (initiate) -> answer at once, IDLE            expedited
 *                      -> DOWNLOAD / UPLOAD               segmented (toggle bit)
 *                      -> BLOCK_DOWNLOAD -> BLOCK_DOWNLOAD_END
 *                      -> BLOCK_UPLOAD_START -> BLOCK_UPLOAD -> BLOCK_UPLOAD_END
 *                      -> PENDING (a handler split: waits for co_sdo_server_resume)
 *   any open state -> idle timeout -> abort 0x05040000 sent -> IDLE
 *                     (PENDING -> ABANDONED: the channel stays taken until
 *                     the application's resume, which then only frees it)
 *
 * Nothing allocates; no globals. Wire choices and their evidence:
 * docs/protocol-notes.md, section "Classic SDO". */
#ifndef CO_SDO_SERVER_H
#define CO_SDO_SERVER_H

#include "canopenfd/co_line.h"
#include "canopenfd/co_nmt.h"
#include "canopenfd/co_od.h"
#include "canopenfd/co_sdo.h"

enum {
    CO_SDO_SERVER_DEFAULT_TIMEOUT_MS = 1000,
    CO_SDO_SERVER_DEFAULT_BLKSIZE = 127,
    /* Block buffer of a channel: one sub-block of 127 segments plus one byte
     * of look-ahead (to know which segment is the last). */
    CO_SDO_SERVER_BUFFER = CO_SDO_BLKSIZE_MAX * CO_SDO_SEGMENT_DATA + 1,
    CO_SDO_SERVER_MAX_CHANNELS = 128   /* 0x1200 .. 0x127F */
};

typedef enum co_sdo_channel_state {
    CO_SDO_CH_IDLE = 0,
    CO_SDO_CH_ACTIVE,              /* inside a co_od call (not resumable yet) */
    CO_SDO_CH_DOWNLOAD,            /* segmented download: next segment expected */
    CO_SDO_CH_UPLOAD,              /* segmented upload: next segment request expected */
    CO_SDO_CH_BLOCK_DOWNLOAD,      /* block download: sub-block segments expected */
    CO_SDO_CH_BLOCK_DOWNLOAD_END,  /* block download: all data acknowledged, end frame expected */
    CO_SDO_CH_BLOCK_UPLOAD_START,  /* block upload: initiate answered, 0xA3 expected */
    CO_SDO_CH_BLOCK_UPLOAD,        /* block upload: sub-block (being) sent, ack expected */
    CO_SDO_CH_BLOCK_UPLOAD_END,    /* block upload: end sent, 0xA1 expected */
    CO_SDO_CH_PENDING,             /* a handler split: waiting for co_sdo_server_resume */
    CO_SDO_CH_ABANDONED            /* was PENDING, then timed out / aborted: freed by the resume */
} co_sdo_channel_state_t;

typedef struct co_sdo_server co_sdo_server_t;

typedef struct co_sdo_channel {
    co_sdo_server_t *server;
    co_timer_t timer;
    co_od_xfer_t xfer;
    uint8_t *buf;                 /* CO_SDO_SERVER_BUFFER bytes of the scratch slice */
    uint8_t number;               /* 0 = default, k = 0x1200 + k */
    uint8_t state;                /* co_sdo_channel_state_t */
    uint8_t answer;               /* PENDING: which answer the resume sends */
    bool valid;                   /* serving: rx CAN-ID subscribed */
    bool reconfig;                /* a COB-ID write waits for the running co_od call */
    uint32_t rx_id;               /* CAN-IDs while valid */
    uint32_t tx_id;
    uint16_t index;               /* the open transfer */
    uint8_t sub;
    uint8_t toggle;               /* segmented: toggle expected next */
    /* block transfers */
    bool crc;                     /* CRC in use: download: both sides announced it;
                                     upload: we support it (sent in any case) */
    uint16_t crc_value;           /* CRC of the data so far */
    uint8_t blksize;              /* segments per sub-block */
    uint8_t pst;                  /* block upload: protocol switch threshold */
    uint8_t seqno;                /* download: last in-order seqno of the sub-block;
                                     upload: segments sent of the sub-block */
    uint8_t segments;             /* upload: segments of the current sub-block */
    bool seen;                    /* download: a segment arrived since the last ack */
    bool sub_last;                /* upload: the current sub-block ends the data */
    bool tx_wait;                 /* upload: waiting for room in the tx queue */
    bool tx_resume;               /* upload: the tx queue drained, go on sending */
    bool data_end;                /* upload: the reader said the data ends after `queued` */
    uint16_t queued;              /* upload: bytes in buf, not yet acknowledged */
    uint16_t sub_len;             /* upload: data bytes of the current sub-block */
    uint8_t held[CO_SDO_FRAME_LEN];  /* download: the segment with c = 1 (written at the end) */
    uint8_t rx[CO_SDO_FRAME_LEN];    /* the last frame received */
    uint8_t done[CO_SDO_FRAME_LEN];  /* the frame that completed the last transfer */
    bool done_valid;
} co_sdo_channel_t;

/* cffi:begin */
/* Everything refused or ignored is counted here (never silent). */
typedef struct co_sdo_server_stats {
    uint32_t rx_frames;           /* frames on a serving channel's CAN-ID */
    uint32_t rx_bad_length;       /* not 8 bytes: ignored */
    uint32_t rx_fd;               /* FD frames: ignored (a classic line drops them before) */
    uint32_t rx_unknown_command;  /* unknown or unexpected command: abort 0x05040001 */
    uint32_t rx_toggle;           /* abort 0x05030000 */
    uint32_t rx_bad_seqno;        /* abort 0x05040003 */
    uint32_t rx_bad_blksize;      /* abort 0x05040002 */
    uint32_t rx_crc;              /* abort 0x05040004 */
    uint32_t rx_block_ignored;    /* block download segment repeated or out of order: ignored */
    uint32_t rx_duplicate;        /* repeat of a transfer's last frame after it ended: ignored */
    uint32_t rx_client_abort;     /* the client aborted an open transfer */
    uint32_t rx_stray_abort;      /* a client abort for no open transfer: ignored */
    uint32_t restarts;            /* an initiate on a busy channel */
    uint32_t refused_busy;        /* abort 0x060A0023: the channel waits on the application */
    uint32_t timeouts;            /* abort 0x05040000 */
    uint32_t od_aborts;           /* transfers refused by the object dictionary */
    uint32_t downloads;           /* completed, every protocol */
    uint32_t uploads;
    uint32_t block_partial_acks;  /* block download: a sub-block acknowledged short */
    uint32_t block_repeats;       /* block upload: segments sent again after a short ack */
    uint32_t protocol_switches;   /* block upload answered as a normal upload (pst) */
    uint32_t aborts_sent;
    uint32_t tx_failed;           /* co_line_send refused (queue full) */
    uint32_t tx_deferred;         /* block upload paused for room in the tx queue */
    uint32_t channel_resets;      /* an open transfer ended by a COB-ID change */
    uint32_t config_refused;      /* valid COB-IDs that cannot be served (29-bit, in use) */
    uint32_t rx_not_serving;      /* the node is stopped (CiA 301: no SDO then): ignored */
    uint32_t closed_by_state;     /* open transfers ended silently on leaving pre-op/op */
} co_sdo_server_stats_t;
/* cffi:end */

/* Sees every 8-byte request of a serving channel first (channel number,
 * the channel's answer CAN-ID); true = taken, the server ignores it. The
 * gateway's SDO networking relays a connected client's requests with it. */
typedef bool (*co_sdo_server_filter_fn)(co_sdo_server_t *server, uint8_t channel, uint32_t tx_id,
                                        const co_frame_t *frame, void *user);

struct co_sdo_server {
    co_line_t *line;
    co_sdo_server_filter_fn filter;   /* NULL: none */
    void *filter_user;
    co_od_t *od;
    co_sdo_channel_t *channels;
    uint8_t channel_count;
    uint8_t blksize;              /* offered in block downloads */
    bool crc;                     /* CRC support announced */
    bool od_hooked;
    bool reconfig_waiting;        /* some channel's reconfig is set */
    bool not_serving;             /* NMT state outside pre-operational / operational */
    uint64_t timeout_us;
    co_sdo_server_stats_t stats;
};

typedef struct co_sdo_server_config {
    co_sdo_channel_t *channels;   /* channel table: [0] default, [k] = 0x1200 + k */
    uint8_t channel_count;        /* 1..128 */
    uint8_t *scratch;             /* channel_count * scratch_size bytes */
    uint32_t scratch_size;        /* per channel: >= co_sdo_server_scratch_need(od) */
    uint32_t timeout_ms;          /* idle timeout of a channel; 0 = default (1000) */
    uint8_t block_size;           /* segments per sub-block asked of clients in block
                                     downloads: 1..127; 0 = default (127) */
    bool no_crc;                  /* announce no CRC support in block transfers */
} co_sdo_server_config_t;

/* Scratch bytes one channel needs: the block buffer plus the OD's largest
 * entry size (a transfer of a larger entry is refused with 0x05040005). */
uint32_t co_sdo_server_scratch_need(const co_od_t *od);

/* Serve `od` on `line` (a classic line). Channel 0 uses the line's node-id
 * (none while it is 0: call co_sdo_server_refresh once it is set); channels
 * 1..count-1 read 0x1201.. from the OD, which must be sealed. False on an fd
 * line, a bad configuration, a full OD handler table or tx-space table, or
 * when the default channel's CAN-ID is taken. */
bool co_sdo_server_init(co_sdo_server_t *server, co_line_t *line, co_od_t *od,
                        const co_sdo_server_config_t *config);
/* Unsubscribe everything; open transfers end (a domain writer is told),
 * nothing is sent. */
void co_sdo_server_deinit(co_sdo_server_t *server);
/* Read the node-id (channel 0) and every channel's COB-IDs again, e.g.
 * after the line's node-id changed. Channels whose CAN-IDs change lose
 * their open transfer (nothing sent). */
void co_sdo_server_refresh(co_sdo_server_t *server);

/* The application's answer to a split (a before_read / check_write handler
 * returned CO_OD_SPLIT for this xfer): abort = 0 goes on, an abort code
 * refuses, CO_OD_SPLIT keeps waiting. The answer frame is sent from here
 * (the line's time is that of its last process call). Returns false when no
 * channel waits on xfer (unknown xfer, called from inside the handler, or
 * the channel was abandoned: then it is freed here, nothing is sent). */
bool co_sdo_server_resume(co_sdo_server_t *server, co_od_xfer_t *xfer, uint32_t abort);

/* Channels not IDLE. */
uint8_t co_sdo_server_active(const co_sdo_server_t *server);

/* The node's NMT state (the node calls it; a server without a node serves
 * always). CiA 301 has SDO only in pre-operational and operational: in any
 * other state requests are ignored (counted rx_not_serving) and leaving those
 * states ends open transfers without an abort frame (the object dictionary
 * learns of it with 0x08000022). */
void co_sdo_server_set_nmt_state(co_sdo_server_t *server, co_nmt_state_t state);
/* Set (fn NULL: clear) the one request filter. */
void co_sdo_server_set_filter(co_sdo_server_t *server, co_sdo_server_filter_fn fn, void *user);

#endif
