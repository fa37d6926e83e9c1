/* Bus redundancy: one node on two CAN lines, a default and a redundant one,
 * of which only one (the active bus) carries traffic at a time. The scheme
 * is the one ECSS-E-ST-50-15C describes (CiA 302-6 is not public): the
 * redundancy master decides the active bus and sends its heartbeat there;
 * a slave follows that heartbeat. A slave that misses it for Ttoggle
 * heartbeat periods switches to the other bus, tries again every Ttoggle
 * periods while the master stays silent, and after Ntoggle switches stays
 * where it is, makes that bus its default and reports "no master". Sources
 * and what is uncertain: docs/protocol-notes.md ("Bus redundancy").
 *
 * The service only decides; the driver owns the two interfaces and is told
 * which one to use through the select callback. Heartbeat supervision of
 * the master stays with the heartbeat consumer: the caller forwards its
 * STARTED and LOST events of the master (co_rdn_master_heard / _lost);
 * co_stack_redundancy_init does that, and serves the object from the OD. */
#ifndef CO_REDUNDANCY_H
#define CO_REDUNDANCY_H

#include "canopenfd/co_line.h"

enum {
    CO_RDN_OBJECT_DEFAULT = 0x2000,   /* a manufacturer index: the standard's is not public */
    CO_RDN_SUB_COUNT = 0,             /* highest sub-index: 4 */
    CO_RDN_SUB_BDEFAULT = 1,          /* the bus used after start: 0 = A, 1 = B */
    CO_RDN_SUB_TTOGGLE = 2,           /* master heartbeat periods missed before a switch; 0 = never switch */
    CO_RDN_SUB_NTOGGLE = 3,           /* switches before the slave stays put (1..255) */
    CO_RDN_SUB_CTOGGLE = 4,           /* switches since the master was last heard (read-only) */
    CO_RDN_BUS_A = 0,
    CO_RDN_BUS_B = 1,
    CO_RDN_TYPE_UNSIGNED8 = 0x0005    /* the data type of every sub-index */
};

typedef enum co_rdn_role {
    CO_RDN_SLAVE = 0,                 /* follows the master's heartbeat */
    CO_RDN_MASTER = 1                 /* decides the bus (co_rdn_master_select) */
} co_rdn_role_t;

/* cffi:begin */
typedef enum co_rdn_event {
    CO_RDN_EV_BUS_SWITCH = 1,         /* the active bus changed; bus = the new one */
    CO_RDN_EV_NO_MASTER = 2           /* a slave gave up after Ntoggle switches; bus = where it stays */
} co_rdn_event_t;
/* cffi:end */

typedef enum co_rdn_result {
    CO_RDN_OK = 0,
    CO_RDN_BAD_TYPE = 1,              /* a sub-index not UNSIGNED8 */
    CO_RDN_BAD_BUS = 2,               /* Bdefault not 0 or 1 */
    CO_RDN_BAD_NTOGGLE = 3,           /* Ntoggle 0 */
    CO_RDN_READ_ONLY = 4,             /* a write to Ctoggle or the sub-index count */
    CO_RDN_NO_SUB = 5,                /* a sub-index above 4 */
    CO_RDN_BAD_MASTER = 6,            /* slave: master node-id outside 1..127 */
    CO_RDN_BAD_PERIOD = 7,            /* slave that may switch: master heartbeat period 0 */
    CO_RDN_NOT_MASTER = 8,            /* co_rdn_master_select on a slave */
    CO_RDN_MISSING_SUB = 9            /* an OD record without one of sub-indices 1..4 */
} co_rdn_result_t;

typedef struct co_rdn_config {
    co_rdn_role_t role;
    uint8_t master_id;                /* slave: the redundancy master's node-id */
    uint16_t master_period_ms;        /* slave: its heartbeat consumer time (0x1016 entry) */
    uint8_t bdefault;
    uint8_t ttoggle;
    uint8_t ntoggle;
} co_rdn_config_t;

struct co_rdn;
typedef void (*co_rdn_select_fn)(struct co_rdn *rdn, uint8_t bus, void *user);
typedef void (*co_rdn_event_fn)(struct co_rdn *rdn, co_rdn_event_t event, uint8_t bus,
                                void *user);

typedef struct co_rdn {
    co_line_t *line;                  /* its timer list and clock */
    co_rdn_config_t config;
    uint8_t active;                   /* the bus in use */
    uint8_t ctoggle;
    co_rdn_select_fn select;          /* the driver: use this bus from now on */
    co_rdn_event_fn on_event;         /* the application; NULL: none */
    void *user;
    co_timer_t toggle_timer;          /* slave: the next switch while the master is silent */
} co_rdn_t;

/* Check a configuration before use: CO_RDN_OK or the first problem. */
co_rdn_result_t co_rdn_check_config(const co_rdn_config_t *config);
/* Check one sub-index of the redundancy object as a configuration file or
 * a write gives it: its data type, then its value. */
co_rdn_result_t co_rdn_check_sub(uint8_t sub, uint16_t data_type, uint8_t value);
/* What a result expects, in words ("Bdefault must be 0 (bus A) or 1 (bus B)"). */
const char *co_rdn_result_text(co_rdn_result_t result);

/* False (nothing changed) for an invalid configuration or NULL select.
 * Nothing happens before co_rdn_start. */
bool co_rdn_init(co_rdn_t *rdn, co_line_t *line, const co_rdn_config_t *config,
                 co_rdn_select_fn select, co_rdn_event_fn on_event, void *user);
void co_rdn_deinit(co_rdn_t *rdn);
/* At boot and each communication reset: select Bdefault (a BUS_SWITCH event
 * when that leaves the bus in use), Ctoggle 0; a slave that may switch
 * starts counting at once (the master may never be heard). */
void co_rdn_start(co_rdn_t *rdn);
/* The heartbeat consumer's STARTED for the master (its heartbeat arrived
 * after none or after LOST): a slave stops counting and Ctoggle returns to 0. */
void co_rdn_master_heard(co_rdn_t *rdn);
/* The heartbeat consumer's LOST for the master: one period has passed
 * already, so a slave switches after Ttoggle - 1 more. */
void co_rdn_master_lost(co_rdn_t *rdn);
/* Master: make bus the active one (on its own detection of a bus failure:
 * the application decides). CO_RDN_NOT_MASTER on a slave, CO_RDN_BAD_BUS. */
co_rdn_result_t co_rdn_master_select(co_rdn_t *rdn, uint8_t bus);

/* The redundancy object as the object dictionary shows it. */
uint8_t co_rdn_read(const co_rdn_t *rdn, uint8_t sub);
/* A write: checked like co_rdn_check_sub. Bdefault counts from the next
 * start; Ttoggle 0 stops a countdown in progress, another value is used
 * from the next one; Ntoggle at the next switch. */
co_rdn_result_t co_rdn_write(co_rdn_t *rdn, uint8_t sub, uint8_t value);

static inline uint8_t co_rdn_active_bus(const co_rdn_t *rdn) { return rdn->active; }

#endif
