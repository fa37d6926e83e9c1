/* Configuration manager (CiA 302-3): downloads a concise DCF into a node
 * through the line's SDO client (classic lines) or USDO client (fd lines).
 *
 * One co_config_t runs one configuration at a time and uses one client
 * transfer at a time (the entries go in DCF order). Several co_config_t on
 * the same client configure several nodes at once, as far as the client has
 * channels / sessions.
 *
 * A configuration:
 *   1. with expected date and time (the values a manager keeps in 0x1F26 /
 *      0x1F27 for the node) and not `force`: upload the node's 0x1020:01 and 0x1020:02; when
 *      both equal the expected values the node is configured already, the
 *      result is SKIPPED and nothing is written. A node that cannot answer
 *      (timeout) ends the configuration with TIMEOUT; any other refusal (the
 *      node lacks 0x1020) means "not known to be configured": go on;
 *   2. download every entry of the DCF in order. Each entry's outcome (abort
 *      code, 0 = written) goes to the `entry` indication. A failed entry
 *      stops the configuration (FAILED, the entry's index:sub and abort
 *      code in the result) unless `continue_on_error` is set, in which case
 *      the rest is still written and the result names the first failure.
 *      A timeout always stops it (TIMEOUT): the node is silent;
 *   3. only when every entry was written and expected values were given:
 *      download 0x1020:01 = date, then 0x1020:02 = time (also told to
 *      `entry`), so the node says it holds this configuration;
 *   4. done() with the result.
 * Why failures stop by default: docs/protocol-notes.md, "Concise DCF".
 *
 * The DCF is validated whole before anything is sent (a malformed DCF never
 * half-configures a node). The DCF, the co_config_t and the request stay
 * caller memory until done(). Nothing allocates; no globals. */
#ifndef CO_CONFIG_H
#define CO_CONFIG_H

#include "canopenfd/co_concise_dcf.h"
#include "canopenfd/co_sdo_client.h"
#include "canopenfd/co_usdo_client.h"

typedef enum co_config_outcome {
    CO_CONFIG_RESULT_OK = 0,        /* every entry written (and 0x1020 stamped) */
    CO_CONFIG_RESULT_SKIPPED = 1,   /* 0x1020 equals the expected date and time */
    CO_CONFIG_RESULT_FAILED = 2,    /* an entry (or the stamp) was refused */
    CO_CONFIG_RESULT_TIMEOUT = 3,   /* the node did not answer */
    CO_CONFIG_RESULT_CANCELLED = 4  /* co_config_cancel, or the client went away */
} co_config_outcome_t;

typedef enum co_config_start_status {
    CO_CONFIG_START_OK = 0,
    CO_CONFIG_START_BUSY = 1,       /* this co_config_t runs a configuration */
    CO_CONFIG_START_ARGUMENT = 2,   /* no client, node-id not 1..127, no done, no DCF */
    CO_CONFIG_START_BAD_DCF = 3,    /* see dcf_status / dcf_offset */
    CO_CONFIG_START_REFUSED = 4,    /* the client refused the first transfer
                                       (result.abort holds its CiA 301 code) */
    CO_CONFIG_START_EMPTY = 5       /* a DCF without entries and no stamp: nothing to do */
} co_config_start_status_t;

typedef struct co_config_result {
    uint8_t outcome;                /* co_config_outcome_t */
    uint8_t node;
    uint32_t written;               /* DCF entries written */
    uint32_t failed;                /* DCF entries refused */
    /* the first failure (FAILED), the unanswered transfer (TIMEOUT): */
    uint16_t index;
    uint8_t sub;
    bool from_node;                 /* the node sent the abort */
    uint32_t abort;                 /* CiA 301 abort code (USDO codes translated) */
    uint32_t entry;                 /* its 0-based DCF entry number (stamp: count) */
} co_config_result_t;

typedef struct co_config co_config_t;
/* One DCF entry (or 0x1020 stamp) done: abort 0 = written. */
typedef void (*co_config_entry_fn)(co_config_t *cfg, uint16_t index, uint8_t sub,
                                   uint32_t abort, void *user);
/* The configuration ended; cfg may start the next one from here. */
typedef void (*co_config_done_fn)(co_config_t *cfg, const co_config_result_t *result,
                                  void *user);

typedef struct co_config_request {
    uint8_t node;                   /* 1..127 */
    const uint8_t *dcf;             /* concise DCF (caller memory, kept until done) */
    uint32_t dcf_length;
    bool check_stamp;               /* compare / write 0x1020 with date and time */
    uint32_t date;                  /* expected 0x1020:01 (0x1F26:node) */
    uint32_t time;                  /* expected 0x1020:02 (0x1F27:node) */
    bool continue_on_error;         /* write the rest after a refused entry */
    bool force;                     /* with check_stamp: write without comparing 0x1020
                                       first (a configuration request), stamp at the end */
    uint32_t timeout_ms;            /* per frame; 0 = the client's default */
    co_config_entry_fn entry;       /* optional */
    co_config_done_fn done;         /* required */
    void *user;
} co_config_request_t;

typedef enum co_config_state {
    CO_CONFIG_IDLE = 0,
    CO_CONFIG_READ_DATE,            /* uploading 0x1020:01 */
    CO_CONFIG_READ_TIME,            /* uploading 0x1020:02 */
    CO_CONFIG_WRITE_ENTRY,          /* downloading a DCF entry */
    CO_CONFIG_WRITE_DATE,           /* downloading 0x1020:01 */
    CO_CONFIG_WRITE_TIME            /* downloading 0x1020:02 */
} co_config_state_t;

struct co_config {
    co_sdo_client_t *sdo;           /* exactly one of the two */
    co_usdo_client_t *usdo;
    co_config_request_t req;        /* copy of the running request */
    co_config_result_t result;
    uint8_t state;                  /* co_config_state_t */
    bool cancelling;
    uint32_t run;                   /* bumped when a configuration ends: a callback
                                       that cancelled or restarted is noticed */
    co_concise_iter_t it;
    co_concise_entry_t current;
    uint8_t dcf_status;             /* after START_BAD_DCF: co_concise_status_t */
    uint32_t dcf_offset;            /* and the byte offset of the error */
    uint8_t word[4];                /* an upload's value / a stamp's bytes */
    co_buffer_t buffer;
    co_sdo_request_t sdo_req;
    co_usdo_request_t usdo_req;
};

/* Bind to a client (initialised by the caller or co_stack). */
void co_config_init_sdo(co_config_t *cfg, co_sdo_client_t *client);
void co_config_init_usdo(co_config_t *cfg, co_usdo_client_t *client);
/* Start a configuration. Frames go out relative to the line's time of its
 * last process call (as every client transfer). done() follows once when
 * START_OK is returned, never otherwise. */
co_config_start_status_t co_config_start(co_config_t *cfg, const co_config_request_t *req);
/* End a running configuration: the open transfer is aborted (0x08000000
 * sent), done() comes with CANCELLED. False when nothing runs. */
bool co_config_cancel(co_config_t *cfg);
bool co_config_running(const co_config_t *cfg);
const char *co_config_outcome_text(co_config_outcome_t outcome);

#endif
