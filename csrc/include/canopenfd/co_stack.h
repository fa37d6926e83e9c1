/* co_stack: the portable assembly of what a CAN line and its local node run.
 *
 * A line's services (heartbeat consumer, SYNC, TIME, EMCY consumer, node
 * guarding master on classic lines, an SDO or USDO client) and, once a local
 * node is added, everything that node runs (NMT slave and heartbeat
 * producer, its object dictionary and store, EMCY producer, PDOs, the SDO
 * server channels or USDO server sessions, the guarding slave on classic
 * lines), set up over memory the caller gives and wired together the CiA
 * way: NMT state to every service, SYNC to the PDOs, detected errors to
 * EMCY, communication errors to 0x1029, resets to a reload.
 *
 * Memory comes from an allocator the caller provides: a bump arena over a
 * static buffer (co_stack_arena_*) for builds that know their memory at
 * compile time (co_stack_line_need / co_stack_node_need say how much, and
 * CO_STACK_NODE_MEMORY bounds it from counts), or any allocate/release
 * pair for builds that size at run time. It is used only while a part is
 * set up; nothing is allocated while frames flow.
 *
 * Typical use (see examples/c/):
 *   co_stack_init(&stack, &line, &line_config, allocator);
 *   co_stack_node_init(&stack, &node_config);   // OD sealed with the node-id
 *   co_stack_boot(&stack);                      // boot-up, pre-operational
 *   for (;;) { feed frames with co_line_receive; co_line_process(&line, now);
 *              send what co_line_tx_pop gives }
 */
#ifndef CO_STACK_H
#define CO_STACK_H

#include "canopenfd/co_cia401_od.h"
#include "canopenfd/co_emcy.h"
#include "canopenfd/co_flyma.h"
#include "canopenfd/co_guard.h"
#include "canopenfd/co_hb.h"
#include "canopenfd/co_led.h"
#include "canopenfd/co_lss.h"
#include "canopenfd/co_lss_master.h"
#include "canopenfd/co_manager.h"
#include "canopenfd/co_node.h"
#include "canopenfd/co_od.h"
#include "canopenfd/co_pdo.h"
#include "canopenfd/co_redundancy.h"
#include "canopenfd/co_sdo_client.h"
#include "canopenfd/co_sdo_server.h"
#include "canopenfd/co_sleep.h"
#include "canopenfd/co_srdo.h"
#include "canopenfd/co_gfc.h"
#include "canopenfd/co_store.h"
#include "canopenfd/co_sync.h"
#include "canopenfd/co_time.h"
#include "canopenfd/co_usdo_client.h"
#include "canopenfd/co_usdo_server.h"

#include <stddef.h>

/* Which kinds of line the stack is built for (both by default). A build for
 * one kind links none of the other's services (SDO server/client and
 * guarding for classic lines, USDO server/client for fd lines); a line of
 * the other kind is refused with CO_STACK_ERR_ARGUMENT. */
#ifndef CO_CONFIG_CLASSIC
#define CO_CONFIG_CLASSIC 1
#endif
#ifndef CO_CONFIG_FD
#define CO_CONFIG_FD 1
#endif

/* What a co_stack call says when it refuses. */
typedef enum co_stack_status {
    CO_STACK_OK = 0,
    CO_STACK_ERR_ARGUMENT = 1,   /* a bad configuration value (node-id, counts, NULL) */
    CO_STACK_ERR_NO_MEMORY = 2,  /* the allocator gave nothing */
    CO_STACK_ERR_STATE = 3,      /* wrong moment: a node exists already, none exists,
                                    the OD is not sealed, a client runs already */
    CO_STACK_ERR_OD = 4,         /* the OD cannot be used (mode, PDO entries) */
    CO_STACK_ERR_TAKEN = 5       /* a CAN-ID range, handler or indication table is full */
} co_stack_status_t;

/* The part a refused call was setting up (co_stack_failed_part). */
typedef enum co_stack_part {
    CO_STACK_PART_NONE = 0,
    CO_STACK_PART_HEARTBEAT = 1,
    CO_STACK_PART_SYNC = 2,
    CO_STACK_PART_TIME = 3,
    CO_STACK_PART_EMCY_CONSUMER = 4,
    CO_STACK_PART_GUARD_MASTER = 5,
    CO_STACK_PART_NODE = 6,
    CO_STACK_PART_STORE = 7,
    CO_STACK_PART_EMCY = 8,
    CO_STACK_PART_PDO = 9,
    CO_STACK_PART_GUARD_SLAVE = 10,
    CO_STACK_PART_SERVER = 11,   /* SDO server channels (classic) or USDO sessions (fd) */
    CO_STACK_PART_CLIENT = 12,   /* SDO client channels (classic) or USDO sessions (fd) */
    CO_STACK_PART_LSS = 13,      /* LSS slave of the node or LSS master of the line */
    CO_STACK_PART_LED = 14,      /* CiA 303-3 indicators */
    CO_STACK_PART_MANAGER = 16,  /* CiA 302-2 network manager (co_manager) */
    CO_STACK_PART_SLEEP = 17,    /* sleep and wake-up (CiA 320), master or device */
    CO_STACK_PART_FLYMA = 18,    /* flying master (CiA 302-2) */
    CO_STACK_PART_SRDO = 19,     /* SRDOs and GFC (CiA 304) */
    CO_STACK_PART_REDUNDANCY = 20,  /* bus redundancy (co_redundancy) */
    CO_STACK_PART_CIA401 = 21       /* CiA 401 generic I/O over the OD (co_cia401_od) */
} co_stack_part_t;

typedef struct co_stack co_stack_t;

/* Memory for the parts: allocate returns storage aligned for any type (or
 * NULL); release (may be NULL) gets back what a part no longer needs, in
 * reverse order of allocation when a set-up is undone. */
typedef struct co_stack_allocator {
    void *(*allocate)(void *user, size_t size);
    void (*release)(void *user, void *memory, size_t size);
    void *user;
} co_stack_allocator_t;

/* A bump arena over caller memory: the allocator of static builds. A
 * release gives memory back only when it is the last block handed out. */
typedef struct co_stack_arena {
    unsigned char *base;
    size_t size;
    size_t used;
    size_t peak;                 /* most bytes ever in use */
} co_stack_arena_t;

enum {
    CO_STACK_ALIGN = 8,          /* every block starts on this boundary */
    CO_STACK_MAX_BLOCKS = 24,    /* blocks a stack holds at once */
    /* OD handler subscriptions the node's parts take at most (node, store,
     * SDO/USDO server and client, EMCY, SYNC, TIME, EMCY consumer, PDO,
     * guarding slave, autonomous saves, error-status bits, SRDO objects,
     * CiA 401 objects): an
     * OD served by a stack needs at least this many subscription slots
     * besides the application's own. */
    CO_STACK_OD_SUBSCRIPTIONS = 20,
    CO_STACK_DEFAULT_HB_ENTRIES = 127,
    CO_STACK_DEFAULT_SERVER_SESSIONS = 8,    /* fd lines: USDO server sessions */
    CO_STACK_DEFAULT_EMCY_QUEUE = 16,
    CO_STACK_DEFAULT_EMCY_ACTIVE = 32,
    CO_STACK_DEFAULT_EMCY_HISTORY = 254
};

/* Rounds a block size up as the arena and the sizing functions do. */
#define CO_STACK_BLOCK(bytes) ((((size_t)(bytes)) + CO_STACK_ALIGN - 1u) / CO_STACK_ALIGN * \
                               CO_STACK_ALIGN)

void co_stack_arena_init(co_stack_arena_t *arena, void *memory, size_t size);
co_stack_allocator_t co_stack_arena_allocator(co_stack_arena_t *arena);

/* Indications of the line's services (each may be NULL). They run inside
 * co_line_process (or co_line_receive's caller's context for comm events). */
typedef struct co_stack_indications {
    /* a node's boot-up, state change, heartbeat started or lost */
    void (*heartbeat)(co_stack_t *stack, uint8_t node_id, co_hb_event_t event,
                      co_nmt_state_t state, void *user);
    /* an EMCY of a consumed node */
    void (*emcy)(co_stack_t *stack, uint8_t node_id, const co_emcy_msg_t *msg, void *user);
    /* a TIME object */
    void (*time)(co_stack_t *stack, const co_time_of_day_t *tod, void *user);
    /* node guarding master (classic lines) */
    void (*guard)(co_stack_t *stack, uint8_t node_id, co_guard_event_t event,
                  co_nmt_state_t state, void *user);
    /* the line's communication events (bus-off, overflow, ...) */
    void (*comm)(co_stack_t *stack, co_comm_event_t event, void *user);
    /* the local node runs with a new node-id: LSS configured it, or a reset
     * activated an LSS pending one or co_stack_set_node_id_at_reset's */
    void (*node_id_changed)(co_stack_t *stack, uint8_t node_id, void *user);
} co_stack_indications_t;

typedef struct co_stack_line_config {
    uint8_t heartbeat_entries;   /* heartbeat consumer entries (0x1016 + watched), 0 = 127 */
    uint8_t guarded_nodes;       /* classic lines: nodes the guarding master guards (0 = none) */
    const co_stack_indications_t *ind;   /* may be NULL */
    void *user;
} co_stack_line_config_t;

typedef struct co_stack_node_config {
    uint8_t node_id;             /* 1..127, or 255: unconfigured, waits for LSS */
    uint16_t heartbeat_ms;       /* 0x1017 without an OD */
    co_od_t *od;                 /* sealed with node_id (co_od_seal), or NULL: then
                                    its SDO / USDO server serves an empty OD, so
                                    every request is aborted 0x06020000 at once */
    /* Parameters saved through this backend (NULL: defaults only; needs the OD). */
    const co_store_backend_t *store_backend;
    void *store_user;
    uint32_t store_image_capacity;   /* bytes per image, 0 = co_store_image_need(od) */
    /* Declared parameter groups (co_store_config_t; NULL: CiA 301's default
     * groups) and the least time between autonomous saves, on the line's clock. */
    const co_store_group_t *store_groups;
    uint8_t store_group_rows;
    uint32_t store_min_interval_ms;
    co_store_saved_fn store_saved;   /* told after autonomous saves, with `user` (may be NULL) */
    /* fd lines: USDO server sessions, 0 = CO_STACK_DEFAULT_SERVER_SESSIONS.
     * classic lines: the default SDO channel plus one per 0x1201..0x127F
     * object of the OD (this field is not used). */
    uint8_t server_sessions;
    uint16_t emcy_queue;         /* EMCYs waiting for the inhibit time, 0 = 16 */
    uint16_t emcy_active;        /* errors active at once, 0 = 32 */
    uint8_t emcy_history;        /* 0x1003 entries at most, 0 = 254 */
    const co_node_indications_t *ind;   /* the node's (may be NULL) */
    void *user;
    /* CiA 303-3 run and error LEDs (co_led, inside co_stack_t: no memory),
     * fed by the node without the application: leds = true runs them;
     * led_changed (may be NULL, needs leds) hears every change with `user`;
     * led_same_phase: see co_led_config_t. */
    bool leds;
    bool led_same_phase;
    co_led_fn led_changed;
    /* LSS slave (CiA 305): runs when the OD has 0x1018:04 (serial number),
     * unless lss_off. node_id 255 = unconfigured: only the LSS slave runs
     * (no boot-up, heartbeat, EMCY, PDO, SDO/USDO server) until LSS gives
     * the node a node-id and switches it back to waiting; then the node is
     * set up with it (the OD's $NODEID defaults reloaded) and, when
     * co_stack_boot was called, boots (boot-up with the new node-id). */
    bool lss_off;
    /* The application's LSS indications (may be NULL): bit timing, store,
     * state changes; reset_communication tells that an unconfigured node
     * now runs with its new node-id. */
    const co_lss_slave_indications_t *lss_ind;
    void *lss_user;
} co_stack_node_config_t;

typedef struct co_stack_client_config {
    uint8_t sessions;            /* USDO sessions (fd) / SDO channels (classic), 1..128 */
    uint8_t node_id;             /* fd lines: our USDO client node-id 1..127 */
    uint32_t timeout_ms;         /* default per-frame timeout, 0 = 1000 */
} co_stack_client_config_t;

/* The network manager (CiA 302-2): needs the local node (its OD with
 * 0x1F80 bit 0 set) and the client; its slave table is sized from 0x1F81. */
typedef struct co_stack_manager_config {
    uint8_t parallel;            /* boot processes at once, 0 = the client's sessions */
    uint8_t hooks;               /* CO_MANAGER_HOOK_* the application answers */
    uint32_t retry_ms;           /* 0 = CO_MANAGER_DEFAULT_RETRY_MS */
    co_manager_event_fn on_event;   /* may be NULL */
    void *user;
    uint32_t dcf_capacity;       /* OD with 0x1F25: room for one 0x1F22 concise DCF,
                                    0 = CO_MANAGER_DCF_BUFFER */
} co_stack_manager_config_t;

/* A block the stack holds (what it gives back at deinit). */
typedef struct co_stack_block {
    void *memory;
    size_t size;
    uint8_t owner;               /* the line, the node or the client */
} co_stack_block_t;

/* The parts live here; read them through the accessors below (NULL when a
 * part does not run), never write the fields. */
struct co_stack {
    co_line_t *line;
    co_stack_allocator_t alloc;
    const co_stack_indications_t *ind;
    void *user;
    co_stack_part_t failed;
    uint8_t block_count;
    co_stack_block_t blocks[CO_STACK_MAX_BLOCKS];
    /* the line's services */
    co_hb_consumer_t hb_consumer;
    co_sync_t sync;
    co_time_t time;
    co_emcy_consumer_t emcy_consumer;
    bool has_guard_master;
    co_guard_master_t guard_master;
    /* the local node */
    bool has_node;
    co_node_t node;
    co_od_t *od;
    co_od_t no_od;               /* what the server serves when od is NULL: nothing */
    bool has_store;
    co_store_t store;
    bool has_emcy;
    co_emcy_t emcy;
    bool has_errors;
    co_errors_t errors;
    bool has_pdo;
    co_pdo_t pdo;
    bool has_mpdo;
    co_mpdo_t mpdo;              /* the PDOs whose mapping says MPDO (no memory of its own) */
    bool has_guard_slave;
    co_guard_slave_t guard_slave;
    bool has_usdo_server;
    co_usdo_server_t usdo_server;
    bool has_sdo_server;
    co_sdo_server_t sdo_server;
    /* the client */
    bool has_usdo_client;
    co_usdo_client_t usdo_client;
    bool has_sdo_client;
    co_sdo_client_t sdo_client;
    /* LSS: the node's slave (also while the node is unconfigured), the line's master */
    bool has_lss_slave;
    co_lss_slave_t lss_slave;
    co_lss_slave_indications_t lss_wiring;   /* the stack's own, forwarding to lss_app */
    const co_lss_slave_indications_t *lss_app;
    void *lss_user;
    uint8_t node_id_at_reset;    /* co_stack_set_node_id_at_reset's, 0 = none */
    bool unconfigured;           /* node_id 255: the node waits for LSS */
    bool boot_requested;         /* co_stack_boot came while unconfigured */
    co_stack_node_config_t node_config;   /* kept to set the node up once configured */
    co_timer_t lss_timer;        /* sets the node up outside the LSS frame's handler */
    bool has_lss_master;
    co_lss_master_t lss_master;
    /* the network manager */
    bool has_manager;
    co_manager_t manager;
    /* sleep and wake-up */
    bool has_sleep;
    co_sleep_t sleep;
    co_sleep_fn sleep_ind;           /* the application's, behind the stack's own */
    void *sleep_user;
    /* flying master */
    bool has_flyma;
    co_flyma_t flyma;
    co_flyma_fn flyma_ind;           /* the application's, behind the stack's own */
    void *flyma_user;
    uint16_t flyma_watch_ms;
    uint8_t flyma_watched;           /* the active master whose heartbeat we watch, 0 none */
    /* the node's indicators */
    bool has_led;
    co_led_t led;
    /* SRDOs and the GFC of the node (CiA 304) */
    bool has_srdo;
    co_srdo_t *srdo;
    uint8_t srdo_count;
    co_gfc_t gfc;
    co_srdo_od_t srdo_od;            /* their OD objects, when the OD has 0x13FE */
    co_srdo_fn srdo_ind;             /* the application's safe-state indication */
    void *srdo_user;
    uint64_t srdo_errors;            /* bit n-1: SRDO n's safe-state EMCY error is active */
    /* bus redundancy (co_stack_redundancy.c) */
    bool has_rdn;
    co_rdn_t rdn;
    co_od_t *rdn_od;                 /* the node's OD serving the record, or NULL */
    uint16_t rdn_index;
    bool rdn_switch_on_failure;
    bool rdn_selecting;              /* inside a select: its own comm events are no failure */
    co_rdn_select_fn rdn_select;     /* the driver's, behind the stack's own */
    co_rdn_event_fn rdn_event;       /* the application's, behind the stack's own */
    void *rdn_user;
    /* CiA 401 generic I/O of the node (co_stack_cia401.c) */
    bool has_cia401;
    co_cia401_od_t cia401;
};

/* ---- sizing (bytes the allocator is asked for, alignment included) */
size_t co_stack_line_need(const co_line_t *line, const co_stack_line_config_t *config);
/* The node's need depends on its OD (PDO count, largest entry, store image). */
size_t co_stack_node_need(const co_line_t *line, const co_stack_node_config_t *config);
size_t co_stack_client_need(const co_line_t *line, const co_stack_client_config_t *config);

/* ---- set-up; each returns CO_STACK_OK or says why not (and which part,
 * co_stack_failed_part), leaving the stack as it was before the call. */
co_stack_status_t co_stack_init(co_stack_t *stack, co_line_t *line,
                                const co_stack_line_config_t *config,
                                co_stack_allocator_t allocator);
/* The line's local node (the line's node-id becomes node_id). Nothing is
 * sent until co_stack_boot. */
co_stack_status_t co_stack_node_init(co_stack_t *stack, const co_stack_node_config_t *config);
/* Power-on of the node: parameters loaded, boot-up sent, pre-operational. */
co_stack_status_t co_stack_boot(co_stack_t *stack);
/* The running node takes node_id (1..127) at its next reset (communication
 * or node), as a pending LSS node-id would: the $NODEID defaults reload
 * with it and the boot-up carries it; an LSS slave reports it as active.
 * It wins over an LSS pending node-id. CO_STACK_ERR_STATE without a
 * running node (also while it waits for LSS). */
co_stack_status_t co_stack_set_node_id_at_reset(co_stack_t *stack, uint8_t node_id);
/* Undo co_stack_node_init (the client goes too when it was bound to the
 * node's OD). */
void co_stack_node_deinit(co_stack_t *stack);
/* The SDO (classic) or USDO (fd) client; on classic lines with a node that
 * has an OD, its 0x1280.. channels come first. */
co_stack_status_t co_stack_client_init(co_stack_t *stack, const co_stack_client_config_t *config);
void co_stack_client_deinit(co_stack_t *stack);
/* The line's LSS master (no memory taken); timeout_ms per step, 0 = 100. */
co_stack_status_t co_stack_lss_master_init(co_stack_t *stack, uint32_t timeout_ms,
                                           co_lss_done_fn on_done, void *user);
void co_stack_lss_master_deinit(co_stack_t *stack);
/* The network manager over the node and the client (CO_STACK_ERR_STATE
 * without them or when one runs, CO_STACK_ERR_OD when 0x1F80 bit 0 is
 * clear). Start it with co_manager_start(co_stack_manager(stack)). It is
 * fed the line's error control frames and losses; it goes when the node or
 * the client goes. co_stack_manager_need: the bytes co_stack_manager_init
 * takes with that config (NULL: the defaults), its DCF room included. */
size_t co_stack_manager_need(co_stack_t *stack, const co_stack_manager_config_t *config);
co_stack_status_t co_stack_manager_init(co_stack_t *stack,
                                        const co_stack_manager_config_t *config);
void co_stack_manager_deinit(co_stack_t *stack);
/* Sleep and wake-up on the line (needs no memory): a master, or a device;
 * waking up resets the local node's communication. */
co_stack_status_t co_stack_sleep_init(co_stack_t *stack, const co_sleep_config_t *config);
void co_stack_sleep_deinit(co_stack_t *stack);
/* Flying master of the local node (needs the node; no memory). The OD's
 * 0x1F90/0x1F91 entries, where present, override config's timing. A slave
 * watches the active master's heartbeat for master_heartbeat_ms (0: only
 * what 0x1016 says); losing it (or a network reset another node asked for)
 * starts a new negotiation; a network reset the service asks for goes out
 * as NMT reset communication to all nodes, this one included. */
typedef struct co_stack_flyma_config {
    co_flyma_config_t flyma;
    uint16_t master_heartbeat_ms;
} co_stack_flyma_config_t;
co_stack_status_t co_stack_flyma_init(co_stack_t *stack, const co_stack_flyma_config_t *config);
void co_stack_flyma_deinit(co_stack_t *stack);
/* count SRDOs (1..64, off until co_srdo_configure) and the GFC (off until
 * co_gfc_set_enabled) of the local node: they follow the
 * node's NMT state, a GFC received puts every SRDO in the safe state, and
 * on_safe (may be NULL) hears every safe-state entry. They go when the node
 * goes. CO_STACK_ERR_STATE without a node or when they run already. */
co_stack_status_t co_stack_srdo_init(co_stack_t *stack, uint8_t count, co_srdo_fn on_safe,
                                     void *user);
void co_stack_srdo_deinit(co_stack_t *stack);
/* Bus redundancy of the line (no memory taken): the heartbeat consumer
 * watches a slave's master and tells the service its STARTED / LOST; a
 * node's reset starts it over (Bdefault). When the local node's OD has the
 * redundancy record at `index` (subs 1..4, UNSIGNED8, valid values), its
 * Bdefault / Ttoggle / Ntoggle are used instead of config's, writes to it
 * (SDO, USDO, the application) are checked and applied, and its Ctoggle and
 * Bdefault follow the service; a bad record is CO_STACK_ERR_OD
 * (co_stack_redundancy_check_od says which sub and why). A master with
 * switch_on_failure moves to the other bus when the line reports bus-off or
 * interface down (our choice: docs/protocol-notes.md). */
typedef struct co_stack_redundancy_config {
    co_rdn_config_t rdn;             /* role, master, its period, and the object's
                                        values when the OD has no record */
    uint16_t index;                  /* the record's index, 0 = CO_RDN_OBJECT_DEFAULT */
    bool switch_on_failure;          /* master only */
    co_rdn_select_fn select;         /* the driver: use this bus (not NULL) */
    co_rdn_event_fn on_event;        /* may be NULL */
    void *user;                      /* for select and on_event */
} co_stack_redundancy_config_t;
co_stack_status_t co_stack_redundancy_init(co_stack_t *stack,
                                           const co_stack_redundancy_config_t *config);
void co_stack_redundancy_deinit(co_stack_t *stack);
/* The record's index while the service runs (0: it does not). The record is
 * read and bound at init only: whoever adds OD entries to a running node
 * refuses that index (co_rt_od_add does), so a record added later cannot
 * look configured while the service ignores it. */
uint16_t co_stack_redundancy_record_index(const co_stack_t *stack);
/* The record at index in od: CO_RDN_OK (also when od has no such object:
 * then *bad_sub = 0) or the first problem, *bad_sub = its sub-index. */
co_rdn_result_t co_stack_redundancy_check_od(const co_od_t *od, uint16_t index,
                                             uint8_t *bad_sub);
/* The local node as a CiA 401 generic I/O device (co_cia401_od.h): its
 * channels and parameters are what the node's OD holds; it hears the
 * node's RPDOs, NMT states (STOPPED is a fault) and resets, and triggers
 * the node's TPDOs; on_outputs (may be NULL) is told every change of the
 * physical outputs. It goes when the node goes. CO_STACK_ERR_STATE without
 * a node or when it runs already, CO_STACK_ERR_OD when the OD has no valid
 * channel objects (co_cia401_od_scan says which entry), CO_STACK_ERR_TAKEN
 * when the OD has no subscription slot left. co_stack_cia401_need: the
 * bytes it takes (0 when the OD holds no valid channels). */
size_t co_stack_cia401_need(co_stack_t *stack);
co_stack_status_t co_stack_cia401_init(co_stack_t *stack, co_cia401_outputs_fn on_outputs,
                                       void *user);
void co_stack_cia401_deinit(co_stack_t *stack);
/* Everything, memory given back. */
void co_stack_deinit(co_stack_t *stack);
co_stack_part_t co_stack_failed_part(const co_stack_t *stack);
const char *co_stack_part_name(co_stack_part_t part);

/* ---- the parts (NULL when not running) */
static inline co_line_t *co_stack_line(co_stack_t *s) { return s->line; }
static inline co_hb_consumer_t *co_stack_hb_consumer(co_stack_t *s) { return &s->hb_consumer; }
static inline co_sync_t *co_stack_sync(co_stack_t *s) { return &s->sync; }
static inline co_time_t *co_stack_time(co_stack_t *s) { return &s->time; }
static inline co_emcy_consumer_t *co_stack_emcy_consumer(co_stack_t *s)
{
    return &s->emcy_consumer;
}
static inline co_guard_master_t *co_stack_guard_master(co_stack_t *s)
{
    return s->has_guard_master ? &s->guard_master : NULL;
}
static inline bool co_stack_has_node(const co_stack_t *s) { return s->has_node; }
static inline co_node_t *co_stack_node(co_stack_t *s) { return s->has_node ? &s->node : NULL; }
static inline co_od_t *co_stack_od(co_stack_t *s) { return s->has_node ? s->od : NULL; }
static inline co_store_t *co_stack_store(co_stack_t *s) { return s->has_store ? &s->store : NULL; }
static inline co_emcy_t *co_stack_emcy(co_stack_t *s) { return s->has_emcy ? &s->emcy : NULL; }
static inline co_errors_t *co_stack_errors(co_stack_t *s)
{
    return s->has_errors ? &s->errors : NULL;
}
static inline co_pdo_t *co_stack_pdo(co_stack_t *s) { return s->has_pdo ? &s->pdo : NULL; }
static inline co_mpdo_t *co_stack_mpdo(co_stack_t *s) { return s->has_mpdo ? &s->mpdo : NULL; }
static inline co_guard_slave_t *co_stack_guard_slave(co_stack_t *s)
{
    return s->has_guard_slave ? &s->guard_slave : NULL;
}
static inline co_usdo_server_t *co_stack_usdo_server(co_stack_t *s)
{
    return s->has_usdo_server ? &s->usdo_server : NULL;
}
static inline co_sdo_server_t *co_stack_sdo_server(co_stack_t *s)
{
    return s->has_sdo_server ? &s->sdo_server : NULL;
}
static inline co_usdo_client_t *co_stack_usdo_client(co_stack_t *s)
{
    return s->has_usdo_client ? &s->usdo_client : NULL;
}
static inline co_sdo_client_t *co_stack_sdo_client(co_stack_t *s)
{
    return s->has_sdo_client ? &s->sdo_client : NULL;
}
static inline co_lss_slave_t *co_stack_lss_slave(co_stack_t *s)
{
    return s->has_lss_slave ? &s->lss_slave : NULL;
}
static inline co_lss_master_t *co_stack_lss_master(co_stack_t *s)
{
    return s->has_lss_master ? &s->lss_master : NULL;
}
/* The node waits for LSS to give it a node-id (co_stack_has_node is false). */
static inline bool co_stack_unconfigured(const co_stack_t *s) { return s->unconfigured; }
static inline co_manager_t *co_stack_manager(co_stack_t *s)
{
    return s->has_manager ? &s->manager : NULL;
}
static inline co_sleep_t *co_stack_sleep(co_stack_t *s) { return s->has_sleep ? &s->sleep : NULL; }
static inline co_flyma_t *co_stack_flyma(co_stack_t *s) { return s->has_flyma ? &s->flyma : NULL; }
static inline co_led_t *co_stack_led(co_stack_t *s) { return s->has_led ? &s->led : NULL; }
/* SRDO number 1..srdo_count, NULL otherwise or when they do not run. */
static inline co_srdo_t *co_stack_srdo(co_stack_t *s, uint8_t number)
{
    return s->has_srdo && number >= 1 && number <= s->srdo_count ? &s->srdo[number - 1] : NULL;
}
static inline co_rdn_t *co_stack_redundancy(co_stack_t *s) { return s->has_rdn ? &s->rdn : NULL; }
static inline co_gfc_t *co_stack_gfc(co_stack_t *s) { return s->has_srdo ? &s->gfc : NULL; }
static inline co_cia401_od_t *co_stack_cia401(co_stack_t *s)
{
    return s->has_cia401 ? &s->cia401 : NULL;
}

/* ---- compile-time bounds, for static builds: a line's memory from its
 * configuration (guarded_nodes counts on classic lines only), */
#define CO_STACK_LINE_MEMORY(hb_entries, guarded_nodes)                                 \
    (CO_STACK_BLOCK(sizeof(co_hb_entry_t) * (hb_entries)) +                             \
     ((guarded_nodes) ? CO_STACK_BLOCK(sizeof(co_guard_node_t) * (guarded_nodes)) : 0u))

/* ---- and a node's, for static builds:
 * pdo_channels / map_items as co_pdo_need says for the OD (RPDOs + TPDOs,
 * and their mapping sub-entries), largest_entry = the OD's largest
 * entry size in bytes (co_od_entry_t.size), store_image = co_store_image_need (0 without a
 * store), servers = USDO sessions (fd) or SDO channels (classic) the node
 * serves. co_stack_node_need never exceeds it for such an OD (tested). */
#define CO_STACK_NODE_MEMORY(pdo_channels, map_items, largest_entry, store_image, servers) \
    (CO_STACK_BLOCK(sizeof(co_emcy_msg_t) * CO_STACK_DEFAULT_EMCY_QUEUE) +                  \
     CO_STACK_BLOCK(sizeof(co_emcy_active_t) * CO_STACK_DEFAULT_EMCY_ACTIVE) +              \
     CO_STACK_BLOCK(sizeof(uint32_t) * CO_STACK_DEFAULT_EMCY_HISTORY) +                     \
     CO_STACK_BLOCK(sizeof(co_pdo_channel_t) * ((pdo_channels) ? (pdo_channels) : 1)) +     \
     CO_STACK_BLOCK(sizeof(co_pdo_map_item_t) * ((map_items) ? (map_items) : 1)) +          \
     ((size_t)(pdo_channels) > (size_t)CO_PDO_SCAN_MAX                                       \
          ? CO_STACK_BLOCK(2u * CO_LINE_ID_MAP_SIZE * sizeof(uint16_t)) : 0u) +             \
     CO_STACK_BLOCK(2u * (size_t)(store_image)) +                                            \
     CO_STACK_BLOCK((sizeof(co_usdo_session_t) > sizeof(co_sdo_channel_t)                   \
                         ? sizeof(co_usdo_session_t) : sizeof(co_sdo_channel_t)) *          \
                    (servers)) +                                                             \
     CO_STACK_BLOCK(((size_t)(largest_entry) + CO_SDO_SERVER_BUFFER) * (servers) + 1u))

#endif
