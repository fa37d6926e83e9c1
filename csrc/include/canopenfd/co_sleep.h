/* Sleep and wake-up of a CANopen network (CiA 320; the sleep mode battery
 * powered CiA 454 and CiA 447 networks use), as power management master or
 * device.
 *
 * The master asks every device whether it objects to sleeping (a query on
 * 0x691); a device that must stay awake answers with an objection and its
 * reason (0x690). Without objection within the check window the master
 * sends the sleep command (0x691) and both sides go through the same
 * phases: prepare (the application winds down; frames still flow), silent
 * (nothing is sent any more, frames are still received) and asleep (the
 * application may power the transceiver down). Any frame received while
 * asleep, or the application, wakes the node: it sends a wake-up message
 * (0x691 from the master, 0x690 from a device) and resets communication.
 * A device may ask the master for sleep (0x692). Every frame is 8 bytes,
 * byte 0 a command; the layouts and where they come from are in
 * docs/protocol-notes.md ("Sleep and wake-up"). */
#ifndef CO_SLEEP_H
#define CO_SLEEP_H

#include "canopenfd/co_line.h"

enum {
    CO_SLEEP_DEVICE_ID = 0x690,    /* devices -> master: objection, wake-up message */
    CO_SLEEP_MASTER_ID = 0x691,    /* master -> devices: query, sleep, wake-up message */
    CO_SLEEP_REQUEST_ID = 0x692,   /* devices -> master: sleep request */
    CO_SLEEP_FRAME_LENGTH = 8,
    CO_SLEEP_CMD_QUERY = 0x01,
    CO_SLEEP_CMD_SLEEP = 0x02,
    CO_SLEEP_CMD_REQUEST = 0x03,
    CO_SLEEP_CMD_OBJECTION = 0x81,
    CO_SLEEP_DEFAULT_MS = 1000     /* check window, prepare and silent phases */
};

/* cffi:begin */
typedef enum co_sleep_phase {
    CO_SLEEP_AWAKE = 0,
    CO_SLEEP_CHECKING = 1,         /* master: query sent, objections awaited */
    CO_SLEEP_PREPARING = 2,        /* sleep decided: the application winds down */
    CO_SLEEP_SILENT = 3,           /* nothing is sent; frames are still received */
    CO_SLEEP_ASLEEP = 4            /* the next frame received wakes the node */
} co_sleep_phase_t;

typedef enum co_sleep_event {
    CO_SLEEP_EV_QUERY = 1,         /* device: the master asks; return 1..255 to object
                                      (the reason sent), 0 to agree */
    CO_SLEEP_EV_OBJECTION = 2,     /* master: a device objected, arg = its reason; the
                                      check ended, the network stays awake */
    CO_SLEEP_EV_REQUEST = 3,       /* master: a device asks for sleep */
    CO_SLEEP_EV_PREPARE = 4,       /* sleep decided: wind down; return non-zero to stay
                                      awake (the master then sends no sleep command) */
    CO_SLEEP_EV_SILENT = 5,        /* the node stops sending; return non-zero to stay awake */
    CO_SLEEP_EV_ASLEEP = 6,        /* the node sleeps; the transceiver may go down */
    CO_SLEEP_EV_WAKE = 7,          /* awake again, arg = co_sleep_cause_t; communication
                                      is reset after this */
    CO_SLEEP_EV_WAKE_MESSAGE = 8,  /* another node's wake-up message: arg = its status,
                                      arg2 = its reason */
    CO_SLEEP_EV_REFUSED = 9        /* the application refused a phase: back awake without a
                                      reset, arg = the phase refused */
} co_sleep_event_t;

typedef enum co_sleep_cause {
    CO_SLEEP_BY_APPLICATION = 0,   /* co_sleep_wake */
    CO_SLEEP_BY_BUS = 1,           /* a frame received while asleep */
    CO_SLEEP_BY_WAKE_MESSAGE = 2   /* another node's wake-up message while silent or asleep */
} co_sleep_cause_t;

typedef struct co_sleep_stats {
    uint32_t queries_sent;         /* master */
    uint32_t sleep_commands_sent;  /* master */
    uint32_t objections_sent;      /* device */
    uint32_t requests_sent;        /* device */
    uint32_t wake_messages_sent;   /* repeats included */
    uint32_t objections_received;  /* master */
    uint32_t requests_received;    /* master */
    uint32_t wake_messages_received;
    uint32_t rx_bad_length;        /* not 8 bytes */
    uint32_t rx_ignored;           /* a command for the other role, or out of phase */
    uint32_t send_failed;          /* tx queue full */
} co_sleep_stats_t;
/* cffi:end */

typedef struct co_sleep co_sleep_t;

/* The application's part: see co_sleep_event_t for what each event means and
 * what the return value says (0 everywhere else). */
typedef uint8_t (*co_sleep_fn)(co_sleep_t *sleep, co_sleep_event_t event, uint8_t arg,
                               uint8_t arg2, void *user);

typedef struct co_sleep_config {
    bool master;                   /* power management master, else device */
    uint16_t check_ms;             /* master: objections awaited this long (0 = 1000) */
    uint16_t prepare_ms;           /* sleep command -> silent (0 = 1000) */
    uint16_t silent_ms;            /* silent -> asleep (0 = 1000) */
    uint16_t wake_repeat_ms;       /* the wake-up message once more after this (0 = once) */
    co_sleep_fn ind;               /* may be NULL: never objects, never refuses */
    void *user;
} co_sleep_config_t;

/* Read the fields through the functions below only. */
struct co_sleep {
    co_line_t *line;
    co_sleep_config_t config;
    co_sleep_phase_t phase;
    bool subscribed;
    co_timer_t phase_timer;
    co_timer_t repeat_timer;
    uint8_t wake_status;           /* of our last wake-up message (for the repeat) */
    uint8_t wake_reason;
    co_sleep_stats_t stats;
};

/* Subscribes 0x690..0x692 on the line; false when the range is taken or the
 * arguments are invalid. */
bool co_sleep_init(co_sleep_t *sleep, co_line_t *line, const co_sleep_config_t *config);
void co_sleep_deinit(co_sleep_t *sleep);

/* Master: send the query and wait check_ms for objections; without one,
 * PREPARE then the sleep command. False unless master and awake, or when
 * the query could not be queued. */
bool co_sleep_check(co_sleep_t *sleep);
/* Master: the sleep command now, without asking (PREPARE first). Device:
 * go to sleep alone, as if commanded. False unless awake. */
bool co_sleep_start(co_sleep_t *sleep);
/* Device: ask the master for sleep. False for a master or a full tx queue. */
bool co_sleep_request(co_sleep_t *sleep);
/* Wake up (from preparing, silent or asleep): the line sends again, the
 * wake-up message [status, reason] goes out on the node's own CAN-ID (and
 * once more after wake_repeat_ms), EV_WAKE, then reset communication (the
 * integration's part, see co_stack). Status values that read as commands on
 * that CAN-ID are refused: 1, 2 from a master, 0x81 from a device. False
 * when awake or refused. */
bool co_sleep_wake(co_sleep_t *sleep, uint8_t status, uint8_t reason);

static inline co_sleep_phase_t co_sleep_phase(const co_sleep_t *sleep) { return sleep->phase; }
static inline const co_sleep_stats_t *co_sleep_stats(const co_sleep_t *sleep)
{
    return &sleep->stats;
}

#endif
