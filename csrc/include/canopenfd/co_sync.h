/* SYNC (CiA 301): producer and consumer of the synchronisation object on
 * classic and fd lines, configured by 0x1005 (COB-ID, bit 30 = produce),
 * 0x1006 (cycle period, µs), 0x1007 (synchronous window, µs) and 0x1019
 * (counter overflow value). Every SYNC, produced or received, is told to a
 * small list of listeners with its counter (0 when 0x1019 = 0); a "window
 * closed" indication follows 0x1007 µs after each SYNC. SYNC is produced
 * and consumed only in NMT pre-operational and operational. */
#ifndef CO_SYNC_H
#define CO_SYNC_H

#include "canopenfd/co_nmt.h"
#include "canopenfd/co_od.h"

enum {
    CO_SYNC_MAX_LISTENERS = 8,
    CO_SYNC_DEFAULT_COB_ID = 0x80,
    CO_SYNC_EMCY_LENGTH = 0x8240,       /* EMCY code: SYNC data length error */
    CO_SYNC_COUNTER_MAX = 240           /* highest valid 0x1019 value */
};

#define CO_SYNC_PRODUCER_BIT 0x40000000u   /* 0x1005 bit 30: this node produces */

typedef struct co_sync co_sync_t;

/* Listener: called for every SYNC with its counter (0 = SYNC without data). */
typedef void (*co_sync_fn)(uint8_t counter, void *user);
/* The synchronous window (0x1007) of the last SYNC has closed. */
typedef void (*co_sync_window_fn)(co_sync_t *sync, void *user);
/* A SYNC was refused: emcy_code is CO_SYNC_EMCY_LENGTH, length the received
 * data length. The integration raises the EMCY. */
typedef void (*co_sync_error_fn)(co_sync_t *sync, uint16_t emcy_code, uint8_t length,
                                 void *user);
/* Consumer monitoring: no SYNC came within 1.5 x 0x1006 of the last one
 * (timed_out true), or SYNCs came back / monitoring stopped (false). */
typedef void (*co_sync_timeout_fn)(co_sync_t *sync, bool timed_out, void *user);

/* cffi:begin */
typedef struct co_sync_stats {
    uint32_t produced;          /* SYNC frames queued by the producer */
    uint32_t received;          /* SYNC frames consumed */
    uint32_t bad_length;        /* received with a length other than 0 / 1 expected */
    uint32_t ignored_state;     /* received outside pre-operational / operational */
    uint32_t tx_failed;         /* a SYNC the tx queue refused (not counted, not told) */
    uint32_t outside_window;    /* co_sync_window_check() answered "late" */
    uint32_t subscribe_failed;  /* the SYNC CAN-ID could not be subscribed */
} co_sync_stats_t;
/* cffi:end */

/* The four parameters, as in the OD. */
typedef struct co_sync_config {
    uint32_t cob_id;            /* 0x1005 */
    uint32_t period_us;         /* 0x1006; 0 = no production */
    uint32_t window_us;         /* 0x1007; 0 = no window */
    uint8_t overflow;           /* 0x1019; 0 or 2..240 */
} co_sync_config_t;

typedef struct co_sync_listener {
    co_sync_fn fn;
    void *user;
} co_sync_listener_t;

struct co_sync {
    co_line_t *line;
    co_od_t *od;                  /* bound by co_sync_attach_od, or NULL */
    co_sync_config_t config;
    bool nmt_active;              /* pre-operational or operational */
    bool subscribed;              /* consumer holds rx_id */
    uint32_t rx_id;
    uint8_t next_counter;         /* counter of the next produced SYNC (1..overflow) */
    uint8_t last_counter;         /* counter of the last SYNC (0 = none / no data) */
    bool window_open;             /* a SYNC came less than window_us ago */
    bool any_counter;             /* take SYNC of length 0 and 1 (no 0x1019 of our own) */
    uint64_t last_sync_us;
    co_timer_t producer_timer;
    co_timer_t window_timer;
    uint8_t listener_count;
    co_sync_listener_t listeners[CO_SYNC_MAX_LISTENERS];
    co_sync_window_fn on_window_closed;
    void *window_user;
    co_sync_error_fn on_error;
    void *error_user;
    co_sync_stats_t stats;
    /* consumer monitoring (co_sync_set_timeout_indication) */
    co_timer_t timeout_timer;
    bool timed_out;
    co_sync_timeout_fn on_timeout;
    void *timeout_user;
};

/* Defaults: COB-ID 0x80, consumer only, no period, no window, no counter;
 * NMT not active yet (co_sync_set_nmt_state). Subscribes 0x80; false when
 * that fails. */
bool co_sync_init(co_sync_t *sync, co_line_t *line);
void co_sync_deinit(co_sync_t *sync);

/* Check a value for one of the entries as a network write would, given the
 * current configuration: 0 or a CiA abort code. 0x1005: bits 11..29 set
 * (29-bit ids are not supported) or a restricted CAN-ID: 0x06090030;
 * 0x1019: 1 or > 240: 0x06090030, a change while 0x1006 != 0: 0x08000022.
 * The CAN-ID change rule of 0x1005 is co_cob_id's. */
uint32_t co_sync_check(const co_sync_t *sync, uint16_t index, uint32_t value);

/* Apply a whole configuration without an OD (values are taken as given;
 * 0x1019 = 1 counts as 2, > 240 as 240). A change of COB-ID, period or
 * overflow restarts production at once: counter 1, first SYNC one period
 * from now. A new window applies to the open window too. */
void co_sync_configure(co_sync_t *sync, const co_sync_config_t *config);

/* Bind to a sealed OD: reads 0x1005 (required), 0x1006, 0x1007, 0x1019
 * (missing = 0) and hooks them (checks as co_sync_check; every accepted write
 * or reload applies at once). False when 0x1005 is missing or the OD cannot
 * take the subscriptions. */
bool co_sync_attach_od(co_sync_t *sync, co_od_t *od);
void co_sync_detach_od(co_sync_t *sync);

/* The local node's NMT state: SYNC lives in pre-operational and operational
 * only. Entering them from another state (re)starts production with
 * counter 1; leaving them stops it and closes the window silently. */
void co_sync_set_nmt_state(co_sync_t *sync, co_nmt_state_t state);

/* Listeners of every SYNC (produced or received, in that order of events).
 * False when the list is full, fn is NULL or (fn, user) is already in. */
bool co_sync_add_listener(co_sync_t *sync, co_sync_fn fn, void *user);
void co_sync_remove_listener(co_sync_t *sync, co_sync_fn fn, void *user);
void co_sync_set_window_indication(co_sync_t *sync, co_sync_window_fn fn, void *user);
void co_sync_set_error_indication(co_sync_t *sync, co_sync_error_fn fn, void *user);
/* Monitor the SYNC consumer (only while an indication is set): from the
 * first SYNC received in pre-operational / operational, with 0x1006 != 0
 * and this node not producing, a SYNC must follow within 1.5 x 0x1006 of
 * the previous one, else fn(sync, true); the next SYNC tells fn(sync,
 * false), and so does the end of monitoring (NMT state left, COB-ID or
 * period changed, indication replaced) while timed out. No EMCY is tied to
 * it (CiA 301 defines none); CiA 303-3 shows it on the error LED. */
void co_sync_set_timeout_indication(co_sync_t *sync, co_sync_timeout_fn fn, void *user);

/* A synchronous action (a synchronous TPDO) asks whether it is still inside
 * the window of the last SYNC: true without a window (0x1007 = 0) or while
 * it is open; false (counted in outside_window) otherwise. */
bool co_sync_window_check(co_sync_t *sync);
/* A consumer with no 0x1019 of its own (a tool's line, no local node) takes
 * SYNC with or without the counter byte; off (the default), a length other
 * than 0x1019 says is refused with CO_SYNC_EMCY_LENGTH, as CiA 301 wants. */
void co_sync_accept_any_counter(co_sync_t *sync, bool accept);
static inline bool co_sync_is_producer(const co_sync_t *sync)
{
    return (sync->config.cob_id & CO_SYNC_PRODUCER_BIT) != 0;
}

#endif
