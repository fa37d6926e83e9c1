/* LSS master (CiA 305): one request at a time, each step with a timeout on
 * the line's timer list, the result told to a completion callback.
 *
 * Besides the single services (switch state, configure, store, inquire,
 * identify) it runs two searches:
 * - fast scan: finds every non-configured slave bit by bit (vendor, product,
 *   revision, serial: 32 checks each), gives each a node-id from the
 *   caller's list and switches it back to waiting, until no slave answers
 *   the scan's reset; filters match or skip parts of the address, and
 *   without node-ids it identifies one slave and leaves it selected;
 * - scan: finds configured or not, every slave of one vendor and product
 *   inside a revision and serial range, by halving the ranges with
 *   "identify remote slave".
 *
 * A step ends at its timeout, or, once an answer came, at the end of the
 * co_line_process call that brought it (so the answers of all slaves that
 * reply in one batch are counted). Answers nobody waits for, or more than
 * one where one is expected, are counted in the statistics and never stop
 * the master. */
#ifndef CO_LSS_MASTER_H
#define CO_LSS_MASTER_H

#include "canopenfd/co_lss.h"

/* cffi:begin */
typedef enum co_lss_request {
    CO_LSS_REQ_NONE = 0,
    CO_LSS_REQ_SWITCH_SELECTIVE = 1,
    CO_LSS_REQ_CONFIGURE_NODE_ID = 2,
    CO_LSS_REQ_CONFIGURE_BIT_TIMING = 3,
    CO_LSS_REQ_STORE = 4,
    CO_LSS_REQ_INQUIRE = 5,
    CO_LSS_REQ_IDENTIFY_REMOTE = 6,
    CO_LSS_REQ_IDENTIFY_NON_CONFIGURED = 7,
    CO_LSS_REQ_FASTSCAN = 8,
    CO_LSS_REQ_SCAN = 9
} co_lss_request_t;

typedef enum co_lss_status {
    CO_LSS_OK = 0,
    CO_LSS_TIMEOUT = 1,      /* no answer (identify: no slave in the range) */
    CO_LSS_REFUSED = 2,      /* the slave answered with an error code */
    CO_LSS_CANCELLED = 3,
    CO_LSS_TX_FAILED = 4,    /* the tx queue refused a frame */
    CO_LSS_DUPLICATE = 5,    /* fast scan: several slaves share one LSS address */
    CO_LSS_NO_NODE_ID = 6,   /* fast scan: slaves left but the node-id list is used up */
    CO_LSS_LOST = 7,         /* a search: a slave stopped answering half-way */
    CO_LSS_FULL = 8          /* a search: more slaves than the caller's table holds */
} co_lss_status_t;

typedef struct co_lss_master_stats {
    uint32_t frames_sent;
    uint32_t answers;          /* well-formed answers received */
    uint32_t unexpected;       /* answers while idle or of another command */
    uint32_t duplicates;       /* more answers than the step expects */
    uint32_t timeouts;         /* steps that ended without an answer */
    uint32_t bad_length;
    uint32_t unknown_cs;
    uint32_t fastscan_restarts; /* fast scans started over after a part failed to confirm */
} co_lss_master_stats_t;

typedef struct co_lss_master_result {
    co_lss_request_t request;
    co_lss_status_t status;
    uint8_t error;             /* REFUSED: the slave's error code */
    uint8_t spec_error;        /* REFUSED with error 0xFF: the implementation's code */
    uint32_t value;            /* inquire: the number or node-id asked for */
    uint32_t answers;          /* answers to the last step (identify: slaves that answered) */
    uint32_t found;            /* searches: slaves found (entries of the device table) */
    uint32_t frames;           /* frames the request sent */
} co_lss_master_result_t;
/* cffi:end */

/* Fast scan filters, per part of the LSS address (vendor, product,
 * revision, serial), as CiA 305 lets the master choose: find the part bit
 * by bit, skip it (the slaves move past it, its value stays unknown: 0 in
 * the result; not the vendor-ID, where every scan starts), or check a
 * given value with one frame (only slaves with that value go on). */
enum { CO_LSS_FS_SCAN = 0, CO_LSS_FS_SKIP = 1, CO_LSS_FS_MATCH = 2 };
typedef struct co_lss_fastscan_filter {
    uint8_t kind[4];               /* CO_LSS_FS_* per part */
    uint32_t match[4];             /* CO_LSS_FS_MATCH: the value */
} co_lss_fastscan_filter_t;

/* A slave a search found. node_id: what fast scan gave it (0 for scan and
 * an identifying fast scan). */
typedef struct co_lss_device {
    co_lss_address_t address;
    uint8_t node_id;
} co_lss_device_t;

typedef struct co_lss_master co_lss_master_t;
typedef void (*co_lss_done_fn)(co_lss_master_t *master, const co_lss_master_result_t *result,
                               void *user);

enum { CO_LSS_SCAN_STACK = 72 };   /* ranges a scan keeps to look at (2 x 33 levels + room) */
/* A fast scan whose part does not confirm (a slave's late answer read as a
 * 0-bit, or a slave gone) starts over with a reset this often before LOST. */
enum { CO_LSS_FASTSCAN_RESTARTS = 2 };

typedef struct co_lss_range {
    uint32_t low;
    uint32_t high;
    uint8_t level;                 /* 0: serial numbers, 1: revisions of one serial */
} co_lss_range_t;

struct co_lss_master {
    co_line_t *line;
    co_timer_t timer;
    uint64_t timeout_us;
    uint64_t settle_us;            /* wait for more answers after the first (see .c) */
    co_lss_done_fn on_done;
    void *user;
    co_lss_master_stats_t stats;
    /* the request */
    co_lss_request_t request;
    uint8_t step;
    uint8_t expected_cs;           /* answer the step waits for (0 = none) */
    bool waiting;
    uint32_t answers;              /* of the step */
    co_lss_msg_t first;            /* the step's first answer */
    uint32_t frames;               /* of the request */
    /* searches */
    co_lss_device_t *devices;
    uint32_t capacity;
    uint32_t found;
    const uint8_t *node_ids;       /* fast scan: node-ids to give, in order */
    uint32_t node_id_count;
    co_lss_address_t id;           /* fast scan: the address being found */
    uint8_t sub;
    uint8_t bit;
    uint32_t reset_answers;        /* fast scan: slaves that answered the last reset */
    uint8_t restarts;              /* fast scan: started over since the last slave found */
    co_lss_fastscan_filter_t filter; /* fast scan: how each part is found */
    uint32_t vendor, product;      /* scan: the fixed parts */
    uint32_t revision_low, revision_high;
    uint32_t serial;               /* scan: the serial number pinned down */
    co_lss_range_t current;        /* scan: the range being identified */
    uint8_t depth;
    co_lss_range_t stack[CO_LSS_SCAN_STACK];
};

/* timeout_ms: per step, 0 = 100 ms. Subscribes 0x7E4; false when taken. */
bool co_lss_master_init(co_lss_master_t *master, co_line_t *line, uint32_t timeout_ms,
                        co_lss_done_fn on_done, void *user);
void co_lss_master_deinit(co_lss_master_t *master);
/* The step timeout of the next requests (0 = 100 ms); false while busy.
 * Sets the settle time to an eighth of it. */
bool co_lss_master_set_timeout(co_lss_master_t *master, uint32_t timeout_ms);
/* How long a step many slaves may answer stays open after its first answer
 * for the others' (slaves answer with different latencies); at most the
 * timeout. False while busy or above the timeout. */
bool co_lss_master_set_settle(co_lss_master_t *master, uint32_t settle_us);
static inline bool co_lss_master_busy(const co_lss_master_t *m)
{
    return m->request != CO_LSS_REQ_NONE;
}
/* Ends the running request with CO_LSS_CANCELLED (told to the callback). */
void co_lss_master_cancel(co_lss_master_t *master);

/* Services without an answer: sent at once (false: busy, bad argument or
 * the tx queue refused). */
bool co_lss_master_switch_global(co_lss_master_t *master, co_lss_state_t state);
bool co_lss_master_activate_bit_timing(co_lss_master_t *master, uint16_t delay_ms);

/* Requests with an answer: false when busy or an argument is bad (nothing
 * sent, no callback); else the callback tells the result. */
bool co_lss_master_switch_selective(co_lss_master_t *master, const co_lss_address_t *address);
bool co_lss_master_configure_node_id(co_lss_master_t *master, uint8_t node_id);
bool co_lss_master_configure_bit_timing(co_lss_master_t *master, uint8_t table_selector,
                                        uint8_t table_index);
bool co_lss_master_store(co_lss_master_t *master);
/* what: CO_LSS_CS_INQUIRE_VENDOR .. CO_LSS_CS_INQUIRE_NODE_ID */
bool co_lss_master_inquire(co_lss_master_t *master, uint8_t what);
bool co_lss_master_identify_remote(co_lss_master_t *master, uint32_t vendor, uint32_t product,
                                   uint32_t revision_low, uint32_t revision_high,
                                   uint32_t serial_low, uint32_t serial_high);
bool co_lss_master_identify_non_configured(co_lss_master_t *master);

/* Fast scan: node_ids (count of them, each 1..127) are given in order to
 * the slaves found, whose addresses go to devices (capacity entries). */
bool co_lss_master_fastscan(co_lss_master_t *master, const uint8_t *node_ids, uint32_t count,
                            co_lss_device_t *devices, uint32_t capacity);
/* Fast scan with filters (NULL: find every part): count node-ids as
 * above; count 0 identifies only: the first non-configured slave that
 * passes the filter is found, its address goes to devices[0] (found = 1,
 * none: found = 0, status OK) and it stays selected in the configuration
 * state (configure it, or switch every slave back to waiting). False for a
 * filter that skips the vendor-ID or a kind above CO_LSS_FS_MATCH. */
bool co_lss_master_fastscan_filtered(co_lss_master_t *master,
                                     const co_lss_fastscan_filter_t *filter,
                                     const uint8_t *node_ids, uint32_t count,
                                     co_lss_device_t *devices, uint32_t capacity);
/* Scan by identify remote slave: every slave of vendor/product whose
 * revision and serial lie in the ranges (inclusive). */
bool co_lss_master_scan(co_lss_master_t *master, uint32_t vendor, uint32_t product,
                        uint32_t revision_low, uint32_t revision_high, uint32_t serial_low,
                        uint32_t serial_high, co_lss_device_t *devices, uint32_t capacity);

static inline const co_lss_master_stats_t *co_lss_master_stats(const co_lss_master_t *m)
{
    return &m->stats;
}

#endif
