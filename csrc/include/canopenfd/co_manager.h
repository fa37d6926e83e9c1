/* co_manager: the CiA 302-2 network start-up ("NMT master start-up") of a
 * line's local node acting as the network manager.
 *
 * The local node's object dictionary says what to do:
 *   0x1F80     NMT start-up: bit 0 this node is the manager (else nothing
 *              starts), bit 1 start every slave with one NMT start to node
 *              0 instead of one per slave, bit 2 the application (not the
 *              manager) switches the manager to operational, bit 3 the
 *              application (not the manager) starts the slaves, bit 4 a
 *              mandatory slave's error control event resets all nodes,
 *              bit 6 it stops all nodes (bit 6 wins over bit 4; neither: only
 *              that slave is reset and booted again)
 *   0x1F81:n   slave assignment of node n (co_boot.h: in the list, boot,
 *              mandatory, keep-alive, software check/update, retry factor
 *              and guard time)
 *   0x1F84..0x1F88:n, 0x1F26/0x1F27:n, 0x1F55:n   expected identity,
 *              configuration date/time, software (0 or absent = not checked)
 *   0x1F89     boot time (ms): how long a mandatory slave may stay silent
 *              before the start fails (0 = wait for ever)
 *   0x1016     heartbeat consumer times: a slave with one is watched by
 *              heartbeat, else with a guard time (0x1F81 bits 16..31) by
 *              node guarding (classic lines)
 *   0x1F82:n   request NMT (when the OD has it): a network write of 4 stop,
 *              5 start, 6 reset node, 7 reset communication or 127
 *              pre-operational sends that NMT command to slave n of the list
 *              (sub 0x80: to all nodes); other values or nodes: 0x06090030.
 *              It reads as the last state the manager heard of slave n.
 *   0x1F83:n   request node guarding (classic lines): a network write of 1
 *              guards slave n with its 0x1F81:n guard time and factor, 0
 *              stops (sub 0x80: every slave of the list); it reads 1 while
 *              n is guarded. Fd lines refuse writes with 0x06010000 (no
 *              remote frames, so no guarding); a node outside the list or
 *              another value 0x06090030, no guard time 0x08000022.
 *   0x1F25:n   configuration request (CiA 302-3): a network write of "conf"
 *              (0x666E6F63) downloads the concise DCF of 0x1F22:n to slave n
 *              (sub 0x80: every slave with a 0x1F22 entry), one node after
 *              the other, stamping 0x1020 from 0x1F26/0x1F27 when both are
 *              set; CO_MANAGER_EV_CONFIGURED per node. Another value:
 *              0x08000020; no 0x1F22 entry: 0x08000024; that node's
 *              configuration still pending or running: 0x08000022.
 *
 * While another node is the active master (flying master, see
 * co_manager_set_active) the manager sends nothing: no NMT, no boot,
 * and 0x1F82/0x1F83/0x1F25 writes are refused with 0x08000021.
 *
 * co_manager_start runs a boot process (co_boot) for every slave of the
 * list, at most `parallel` at once, over the stack's SDO client (classic
 * lines) or USDO client (fd lines). A slave that does not answer (error B)
 * is tried again every retry_ms, and at once when its boot-up message comes;
 * a mandatory one only until the boot time has passed. When every mandatory
 * slave booted, the application is asked "ready for operational" (when it
 * asked for that hook), then the manager enters operational (bit 2 clear)
 * and starts the slaves (bit 3 clear). A mandatory slave that fails halts
 * the start (CO_MANAGER_EV_HALTED with the node and its error). Optional
 * slaves are started as soon as their own boot ended, also later (when they
 * appear, or come back after an error control event).
 *
 * The stack composes it (co_stack_manager_init) and feeds it the error
 * control frames (co_manager_ec_frame) and events (co_manager_ec_event).
 * No allocation after init, no globals. Choices and evidence:
 * docs/protocol-notes.md, "CiA 302-2 network boot-up". */
#ifndef CO_MANAGER_H
#define CO_MANAGER_H

#include "canopenfd/co_boot.h"
#include "canopenfd/co_config.h"
#include "canopenfd/co_guard.h"
#include "canopenfd/co_hb.h"
#include "canopenfd/co_od.h"
#include "canopenfd/co_sdo_client.h"
#include "canopenfd/co_usdo_client.h"

enum {
    CO_MANAGER_DEFAULT_RETRY_MS = 1000,   /* a silent slave is asked again after this */
    CO_MANAGER_READ_BUFFER = 8,           /* bytes kept of one read (checked values: 4) */
    CO_MANAGER_DCF_BUFFER = 1024,         /* default room for one 0x1F22 concise DCF */
    CO_MANAGER_CONFIG_SIGNATURE = 0x666E6F63   /* "conf" written to 0x1F25 */
};

/* 0x1F80 bits. */
enum {
    CO_MANAGER_STARTUP_MANAGER = 0x01,
    CO_MANAGER_STARTUP_START_ALL = 0x02,
    CO_MANAGER_STARTUP_APP_OPERATIONAL = 0x04,
    CO_MANAGER_STARTUP_APP_STARTS_SLAVES = 0x08,
    CO_MANAGER_STARTUP_RESET_ALL = 0x10,
    CO_MANAGER_STARTUP_STOP_ALL = 0x40
};

/* Which questions the application answers itself (else the manager answers:
 * configuration done, software update failed, operational go). */
enum {
    CO_MANAGER_HOOK_SOFTWARE = 0x01,
    CO_MANAGER_HOOK_CONFIG = 0x02,
    CO_MANAGER_HOOK_OPERATIONAL = 0x04
};

/* cffi:begin */
typedef enum co_manager_slave_status {
    CO_MANAGER_SLAVE_NONE = 0,       /* not in the network list */
    CO_MANAGER_SLAVE_PENDING = 1,    /* waits for a free boot slot */
    CO_MANAGER_SLAVE_BOOTING = 2,
    CO_MANAGER_SLAVE_WAITING = 3,    /* did not answer (B): tried again later */
    CO_MANAGER_SLAVE_BOOTED = 4,     /* ended OK or L */
    CO_MANAGER_SLAVE_FAILED = 5      /* ended with another error: again at its boot-up */
} co_manager_slave_status_t;

typedef enum co_manager_phase {
    CO_MANAGER_IDLE = 0,             /* not started */
    CO_MANAGER_BOOTING = 1,          /* waits for the mandatory slaves */
    CO_MANAGER_READY = 2,            /* asked the application "ready for operational" */
    CO_MANAGER_RUNNING = 3,          /* network started */
    CO_MANAGER_HALTED = 4            /* a mandatory slave failed */
} co_manager_phase_t;

typedef enum co_manager_event {
    CO_MANAGER_EV_BOOT = 1,              /* a boot process report (`boot`) */
    CO_MANAGER_EV_SLAVE_BOOTED = 2,      /* node booted (error OK or L) */
    CO_MANAGER_EV_SLAVE_FAILED = 3,      /* node failed for good (error); mandatory: halt */
    CO_MANAGER_EV_UPDATE_SOFTWARE = 4,   /* answer: co_manager_continue_software */
    CO_MANAGER_EV_UPDATE_CONFIG = 5,     /* answer: co_manager_continue_config */
    CO_MANAGER_EV_READY_OPERATIONAL = 6, /* answer: co_manager_continue_operational */
    CO_MANAGER_EV_NETWORK_STARTED = 7,   /* every mandatory slave booted, start done */
    CO_MANAGER_EV_HALTED = 8,            /* a mandatory slave failed (node, error) */
    CO_MANAGER_EV_SLAVE_STARTED = 9,     /* NMT start sent to node (0: all) */
    CO_MANAGER_EV_ERROR_CONTROL = 10,    /* a booted slave's heartbeat / guarding was
                                            lost (reaction in `command`) */
    CO_MANAGER_EV_CONFIGURED = 11,       /* a 0x1F25 configuration request of node
                                            ended: error 0 or J (boot.index/sub/abort:
                                            the first failure) */
    CO_MANAGER_EV_ACTIVE = 12,           /* the flying master made this node the
                                            active master: the start-up runs */
    CO_MANAGER_EV_PASSIVE = 13           /* another node is (or may become) the active
                                            master: the manager stopped, sends nothing */
} co_manager_event_t;

typedef struct co_manager_report {
    uint8_t event;                   /* co_manager_event_t */
    uint8_t node_id;
    uint8_t error;                   /* co_boot_error_t (SLAVE_*, HALTED) */
    bool mandatory;
    uint8_t command;                 /* ERROR_CONTROL: NMT command sent (to 0 for all
                                        with STOP_ALL / RESET_ALL) */
    co_boot_report_t boot;           /* BOOT: the process's report */
} co_manager_report_t;
/* cffi:end */

typedef struct co_manager co_manager_t;

typedef struct co_manager_slave {
    co_manager_t *owner;
    co_boot_t boot;
    co_boot_expect_t expect;
    co_timer_t retry;                /* next try after B */
    union {
        co_sdo_request_t sdo;
        co_usdo_request_t usdo;
    } req;
    co_buffer_t sink;
    uint8_t data[CO_MANAGER_READ_BUFFER];
    uint8_t node_id;
    uint8_t status;                  /* co_manager_slave_status_t */
    uint8_t error;                   /* co_boot_error_t of the last process */
    bool mandatory;
    bool reading;                    /* req runs on the client */
    bool started;                    /* NMT start sent since its last boot */
} co_manager_slave_t;

typedef void (*co_manager_event_fn)(co_manager_t *manager, const co_manager_report_t *report,
                                    void *user);

typedef struct co_manager_config {
    co_manager_slave_t *slaves;      /* caller storage: one per 0x1F81 slave */
    uint8_t capacity;
    uint8_t parallel;                /* boot processes at once, 0 = the client's sessions */
    uint8_t hooks;                   /* CO_MANAGER_HOOK_* the application answers */
    uint32_t retry_ms;               /* 0 = CO_MANAGER_DEFAULT_RETRY_MS */
    co_manager_event_fn on_event;    /* may be NULL */
    void *user;
    uint8_t *dcf_buffer;             /* caller storage for one 0x1F22 DCF (0x1F25), */
    uint32_t dcf_capacity;           /* NULL / 0: 0x1F25 is not served */
} co_manager_config_t;

struct co_manager {
    co_line_t *line;
    co_od_t *od;
    co_nmt_t *local;                 /* the manager's own NMT state machine */
    co_sdo_client_t *sdo;            /* classic lines */
    co_usdo_client_t *usdo;          /* fd lines */
    co_guard_master_t *guard;        /* NULL: no node guarding */
    co_boot_access_t access;
    co_manager_slave_t *slaves;
    uint8_t capacity;
    uint8_t count;                   /* slaves in the list of the current start */
    uint8_t slot_of[128];            /* node-id -> slave index + 1, 0 = none */
    uint8_t parallel;
    uint8_t booting;                 /* processes running */
    bool launching;                  /* launch_pending runs */
    uint8_t phase;                   /* co_manager_phase_t */
    uint8_t hooks;
    uint32_t startup;                /* 0x1F80 read at start */
    uint32_t boot_time_ms;           /* 0x1F89 */
    uint32_t retry_ms;
    uint64_t started_us;
    co_manager_event_fn on_event;
    void *user;
    bool request_nmt;                /* 0x1F82 (request NMT) hooked in the OD */
    bool request_guard;              /* 0x1F83 (request node guarding) hooked */
    bool request_config;             /* 0x1F25 (configuration request) hooked */
    bool wanted;                     /* started, not stopped by the application */
    bool passive;                    /* another node is the active master */
    /* 0x1F25: one configuration at a time over the client */
    co_config_t config;
    uint8_t *dcf;
    uint32_t dcf_capacity;
    uint8_t config_pending[16];      /* bit per node-id asked for */
    uint8_t config_node;             /* node being configured, 0 = none */
};

/* Slaves in the OD's network list (0x1F81:n bit 0, n = 1..127 but the
 * manager's own node-id): the capacity co_manager_start needs. */
uint8_t co_manager_slaves_in(const co_od_t *od, uint8_t own_node_id);

/* Bind to a line whose local node has an OD (local = its NMT), with the
 * client of the line's kind (sdo or usdo) and, optionally, the guarding
 * master. False on a bad argument. */
bool co_manager_init(co_manager_t *m, co_line_t *line, co_od_t *od, co_nmt_t *local,
                     co_sdo_client_t *sdo, co_usdo_client_t *usdo, co_guard_master_t *guard,
                     const co_manager_config_t *config);
void co_manager_deinit(co_manager_t *m);

typedef enum co_manager_status {
    CO_MANAGER_OK = 0,
    CO_MANAGER_NOT_MANAGER = 1,      /* 0x1F80 bit 0 clear (or no 0x1F80) */
    CO_MANAGER_NO_ROOM = 2,          /* more slaves in 0x1F81 than the capacity */
    CO_MANAGER_NO_CLIENT = 3         /* no SDO/USDO client to reach the slaves */
} co_manager_status_t;

/* Read the OD and boot the network (again: every running process is
 * stopped first). While passive (another active master) the start waits
 * until co_manager_set_active(m, true). */
co_manager_status_t co_manager_start(co_manager_t *m);
/* Stop every boot process and retry (the slaves stay as they are). */
void co_manager_stop(co_manager_t *m);
/* The flying master's decision (co_stack calls it on each of its state
 * changes): active = this node is the active master: EV_ACTIVE, and a
 * started manager runs its start-up from the beginning (boots the slaves);
 * not active: every boot process and configuration stops, phase IDLE,
 * EV_PASSIVE once, and nothing is sent until it is active again. */
void co_manager_set_active(co_manager_t *m, bool active);
static inline bool co_manager_passive(const co_manager_t *m)
{
    return m->passive;
}

/* Input from the stack: a data frame on 0x700 + node (peeked, never taken),
 * and a heartbeat / guarding loss of a node. */
void co_manager_ec_frame(co_manager_t *m, const co_frame_t *frame);
void co_manager_ec_lost(co_manager_t *m, uint8_t node_id);

/* The application's answers; false when that node (or the manager) does not
 * wait for it. */
bool co_manager_continue_software(co_manager_t *m, uint8_t node_id, bool done);
bool co_manager_continue_config(co_manager_t *m, uint8_t node_id, bool done);
bool co_manager_continue_operational(co_manager_t *m);

static inline co_manager_phase_t co_manager_phase(const co_manager_t *m)
{
    return (co_manager_phase_t)m->phase;
}
/* A slave's status and the error of its last boot process. */
co_manager_slave_status_t co_manager_slave_status(const co_manager_t *m, uint8_t node_id);
co_boot_error_t co_manager_slave_error(const co_manager_t *m, uint8_t node_id);

#endif
