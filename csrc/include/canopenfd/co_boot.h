/* co_boot: the "boot slave" process of CiA 302-2 for one node, run by a
 * network manager (co_manager) before it starts the node.
 *
 * The process checks that the node on the bus is the one the manager
 * expects, brings it to a known state and starts its error control:
 *
 *   start -> 1F81 bit 0 clear: done, error A (not in the network list)
 *         -> 1F81 bit 2 clear: no checks, straight to ERROR_CONTROL
 *   DEVICE_TYPE  read 0x1000 (sub 1 on fd lines; no answer: B; differs from
 *                1F84 when that is not 0: C)
 *   VENDOR .. SERIAL  read 0x1018:01..04 and compare with 1F85..1F88, each
 *                only when the expected value is not 0 (D, M, N, O on a
 *                difference or an abort)
 *   NODE_STATE   1F81 bit 4 (keep-alive): wait for the node's heartbeat
 *                (within its consumer time, else E) or ask its state with
 *                one node guarding remote frame (answer within
 *                guard_timeout_ms, else F); operational: skip to
 *                ERROR_CONTROL (and end with L instead of OK)
 *   RESET_COMM   NMT reset communication to the node, wait for its boot-up
 *                (within reset_timeout_ms, else B)
 *   SOFTWARE     1F81 bit 5: read 0x1F56:01 and compare with 1F55 (1F55 = 0
 *                or the read aborted: G); differs: with bit 6 set and bit 4
 *                clear the application updates the software
 *                (CO_BOOT_EV_UPDATE_SOFTWARE, co_boot_continue_software:
 *                done -> again from DEVICE_TYPE, failed -> I; still
 *                different after the update -> I), else H
 *   CONFIG_DATE/TIME  with 1F26 and 1F27 both not 0, read 0x1020:01/02;
 *                both equal: configuration is current
 *   CONFIG_UPDATE otherwise the application brings the configuration
 *                (CO_BOOT_EV_UPDATE_CONFIG, co_boot_continue_config;
 *                failed -> J)
 *   ERROR_CONTROL with a heartbeat consumer time: wait for the first
 *                heartbeat within it (else K); then done
 *
 * Reads that time out (SDO abort 0x05040000) are repeated
 * CO_BOOT_UPLOAD_RETRIES times: a node that just reset may not answer yet.
 * The process does not read an object dictionary: the manager fills the
 * expected values (co_boot_expect_t) from its own. It reaches the node
 * through an access the caller gives (uploads, NMT commands, a guarding
 * remote frame) and is fed the node's error control frames
 * (co_boot_ec_frame) and the uploads' completions (co_boot_upload_done).
 * Its one timer runs on the line's timer list. No allocation, no globals.
 *
 * Choices and evidence: docs/protocol-notes.md, "CiA 302-2 network
 * boot-up". */
#ifndef CO_BOOT_H
#define CO_BOOT_H

#include "canopenfd/co_line.h"
#include "canopenfd/co_nmt.h"
#include "canopenfd/co_timer.h"

#include <stdbool.h>
#include <stdint.h>

enum {
    CO_BOOT_UPLOAD_RETRIES = 3,          /* repeats of a read that timed out */
    CO_BOOT_DEFAULT_RESET_TIMEOUT_MS = 1000,   /* boot-up after reset communication */
    CO_BOOT_DEFAULT_GUARD_TIMEOUT_MS = 100     /* guarding answer in the keep-alive check */
};

/* The SDO abort code of a read that got no answer (the retried one). */
#define CO_BOOT_ABORT_TIMEOUT 0x05040000u

/* cffi:begin */
/* The result of a boot process: OK, or the CiA 302-2 error status letter
 * (the value is the letter's ASCII code). */
typedef enum co_boot_error {
    CO_BOOT_OK = 0,
    CO_BOOT_ERR_A = 0x41, /* 'A': not in the network list (0x1F81 bit 0 clear) */
    CO_BOOT_ERR_B = 0x42, /* 'B': no answer: device type 0x1000, or no boot-up after reset */
    CO_BOOT_ERR_C = 0x43, /* 'C': device type differs from 0x1F84 */
    CO_BOOT_ERR_D = 0x44, /* 'D': vendor-ID 0x1018:01 differs from 0x1F85 (or no answer) */
    CO_BOOT_ERR_E = 0x45, /* 'E': keep-alive check: no heartbeat within its consumer time */
    CO_BOOT_ERR_F = 0x46, /* 'F': keep-alive check: no node guarding answer */
    CO_BOOT_ERR_G = 0x47, /* 'G': software check: 0x1F55 is 0, or 0x1F56:01 not readable */
    CO_BOOT_ERR_H = 0x48, /* 'H': software differs, update not allowed */
    CO_BOOT_ERR_I = 0x49, /* 'I': software update failed */
    CO_BOOT_ERR_J = 0x4A, /* 'J': configuration update failed */
    CO_BOOT_ERR_K = 0x4B, /* 'K': start of error control: no first heartbeat */
    CO_BOOT_ERR_L = 0x4C, /* 'L': keep-alive: the node was operational (not reset, not checked
                               further); the manager treats it as booted */
    CO_BOOT_ERR_M = 0x4D, /* 'M': product code 0x1018:02 differs from 0x1F86 */
    CO_BOOT_ERR_N = 0x4E, /* 'N': revision 0x1018:03 differs from 0x1F87 */
    CO_BOOT_ERR_O = 0x4F  /* 'O': serial number 0x1018:04 differs from 0x1F88 */
} co_boot_error_t;

/* Where a process is. */
typedef enum co_boot_step {
    CO_BOOT_STEP_IDLE = 0,
    CO_BOOT_STEP_DEVICE_TYPE = 1,
    CO_BOOT_STEP_VENDOR = 2,
    CO_BOOT_STEP_PRODUCT = 3,
    CO_BOOT_STEP_REVISION = 4,
    CO_BOOT_STEP_SERIAL = 5,
    CO_BOOT_STEP_NODE_STATE = 6,
    CO_BOOT_STEP_RESET_COMM = 7,
    CO_BOOT_STEP_SOFTWARE = 8,
    CO_BOOT_STEP_UPDATE_SOFTWARE = 9,
    CO_BOOT_STEP_CONFIG_DATE = 10,
    CO_BOOT_STEP_CONFIG_TIME = 11,
    CO_BOOT_STEP_UPDATE_CONFIG = 12,
    CO_BOOT_STEP_ERROR_CONTROL = 13,
    CO_BOOT_STEP_DONE = 14
} co_boot_step_t;

typedef enum co_boot_event {
    CO_BOOT_EV_STARTED = 1,          /* the process began */
    CO_BOOT_EV_CHECKED = 2,          /* a read ended: index/sub, expected, got, abort */
    CO_BOOT_EV_UPDATE_SOFTWARE = 3,  /* answer with co_boot_continue_software */
    CO_BOOT_EV_UPDATE_CONFIG = 4,    /* answer with co_boot_continue_config */
    CO_BOOT_EV_DONE = 5              /* ended: error (CO_BOOT_OK or a letter), state */
} co_boot_event_t;

/* What the process tells (valid during the report call). */
typedef struct co_boot_report {
    uint8_t event;                   /* co_boot_event_t */
    uint8_t node_id;
    uint8_t step;                    /* co_boot_step_t the event belongs to */
    uint8_t sub;                     /* CHECKED: the entry read */
    uint16_t index;
    bool matched;                    /* CHECKED: value as expected */
    uint32_t expected;               /* CHECKED: the manager's value */
    uint32_t got;                    /* CHECKED: the node's value (abort = 0, 4 bytes) */
    uint32_t got_length;             /* CHECKED: bytes the node gave */
    uint32_t abort;                  /* CHECKED: SDO abort code, 0 = read */
    uint8_t error;                   /* DONE: co_boot_error_t */
    uint8_t state;                   /* DONE: last NMT state seen (CO_NMT_UNKNOWN: none) */
} co_boot_report_t;
/* cffi:end */

/* What the manager expects of the node (from its 0x1F81.. entries, sub-index
 * = node-id). A value 0 is not checked. */
typedef struct co_boot_expect {
    uint32_t assignment;             /* 0x1F81: bit 0 in the list, 2 boot, 3 mandatory,
                                        4 keep-alive, 5 check software, 6 update allowed,
                                        8..15 retry factor, 16..31 guard time (ms) */
    uint32_t device_type;            /* 0x1F84 */
    uint32_t vendor_id;              /* 0x1F85 */
    uint32_t product_code;           /* 0x1F86 */
    uint32_t revision;               /* 0x1F87 */
    uint32_t serial;                 /* 0x1F88 */
    uint32_t config_date;            /* 0x1F26 */
    uint32_t config_time;            /* 0x1F27 */
    uint32_t software_id;            /* 0x1F55 */
    uint16_t heartbeat_ms;           /* the manager's 0x1016 consumer time of the node */
    uint8_t device_type_sub;         /* 0x1000 sub-index read: 0 on classic lines, 1 on fd
                                        lines (CiA 1301: an ARRAY, one device type per
                                        logical device; the first is checked) */
    uint32_t reset_timeout_ms;       /* 0 = CO_BOOT_DEFAULT_RESET_TIMEOUT_MS */
    uint32_t guard_timeout_ms;       /* 0 = CO_BOOT_DEFAULT_GUARD_TIMEOUT_MS */
} co_boot_expect_t;

/* 0x1F81 bits. */
enum {
    CO_BOOT_ASSIGN_SLAVE = 0x01,
    CO_BOOT_ASSIGN_BOOT = 0x04,
    CO_BOOT_ASSIGN_MANDATORY = 0x08,
    CO_BOOT_ASSIGN_KEEP_ALIVE = 0x10,
    CO_BOOT_ASSIGN_CHECK_SOFTWARE = 0x20,
    CO_BOOT_ASSIGN_UPDATE_SOFTWARE = 0x40
};

typedef struct co_boot co_boot_t;

/* How the process reaches the node (given by the manager). */
typedef struct co_boot_access {
    /* Start reading index:sub of the node; the result comes later through
     * co_boot_upload_done. Returns 0 when started, else the abort code the
     * read ends with now (co_boot_upload_done is then not expected). */
    uint32_t (*upload)(co_boot_t *boot, uint16_t index, uint8_t sub, void *user);
    /* Send an NMT command to the node; false when it could not be queued. */
    bool (*nmt)(co_boot_t *boot, co_nmt_command_t command, void *user);
    /* Send one node guarding remote frame to the node (classic lines); may
     * be NULL (fd lines: the keep-alive check then listens only). */
    bool (*guard_request)(co_boot_t *boot, void *user);
    /* Every report (required). A DONE report comes after the process
     * ended: it may start it again. */
    void (*report)(co_boot_t *boot, const co_boot_report_t *report, void *user);
    void *user;
} co_boot_access_t;

struct co_boot {
    co_line_t *line;
    const co_boot_access_t *access;
    co_boot_expect_t expect;
    co_timer_t timer;
    uint8_t node_id;
    uint8_t step;                    /* co_boot_step_t */
    uint8_t error;                   /* co_boot_error_t the current step fails with */
    uint8_t state;                   /* last NMT state seen of the node */
    uint8_t retries;                 /* repeats left of the current read */
    bool updated;                    /* the software was updated in this process */
    bool reading;                    /* an upload runs */
    uint16_t index;                  /* the read running */
    uint8_t sub;
};

/* Binds a process to a node (1..127); false on a bad argument. */
bool co_boot_init(co_boot_t *boot, co_line_t *line, uint8_t node_id,
                  const co_boot_access_t *access);
/* Start (or start again) the process with these expectations; false while it
 * runs. Reports STARTED, then steps on. */
bool co_boot_start(co_boot_t *boot, const co_boot_expect_t *expect);
/* Stop without a DONE report (the caller cancels a read it runs itself). */
void co_boot_cancel(co_boot_t *boot);
static inline bool co_boot_running(const co_boot_t *boot)
{
    return boot->step != CO_BOOT_STEP_IDLE && boot->step != CO_BOOT_STEP_DONE;
}
static inline co_boot_step_t co_boot_step(const co_boot_t *boot)
{
    return (co_boot_step_t)boot->step;
}
/* The read started by access->upload ended: abort 0 with the bytes, or the
 * abort code. Ignored when no read runs. */
void co_boot_upload_done(co_boot_t *boot, uint32_t abort, const uint8_t *data, uint32_t len);
/* A data frame on 0x700 + node-id (heartbeat, boot-up or guarding answer). */
void co_boot_ec_frame(co_boot_t *boot, const uint8_t *data, uint8_t len);
/* The application's answers to UPDATE_SOFTWARE / UPDATE_CONFIG; false when the
 * process does not wait for that answer. */
bool co_boot_continue_software(co_boot_t *boot, bool done);
bool co_boot_continue_config(co_boot_t *boot, bool done);

/* A text for an error letter ("OK" for CO_BOOT_OK). */
const char *co_boot_error_text(co_boot_error_t error);

#endif
