/* GFC (CiA 304 global fail-safe command): a frame on CAN-ID 0x001 with no
 * data that tells every safety device to enter its safe state at once. It
 * is neither timed nor answered. 0x1300 (UNSIGNED8, 1 = on) switches it on
 * for both sending and receiving; what the safe state is stays the
 * application's (co_stack hands it to every SRDO with co_srdo_fail). */
#ifndef CO_GFC_H
#define CO_GFC_H

#include "canopenfd/co_line.h"

enum { CO_GFC_COB_ID = 0x001 };

/* cffi:begin */
typedef struct co_gfc_stats {
    uint32_t sent;             /* GFC frames queued */
    uint32_t received;         /* GFC frames acted on */
    uint32_t bad_length;       /* a frame on 0x001 with data: not a GFC */
    uint32_t send_refused;     /* GFC off (0x1300 = 0) or the tx queue full */
} co_gfc_stats_t;
/* cffi:end */

typedef struct co_gfc co_gfc_t;
typedef void (*co_gfc_fn)(co_gfc_t *gfc, void *user);

struct co_gfc {
    co_line_t *line;
    bool enabled;              /* 0x1300 */
    bool subscribed;
    co_gfc_fn on_gfc;
    void *user;
    co_gfc_stats_t stats;
};

/* Off (0x1300 = 0); on_gfc may be NULL. */
void co_gfc_init(co_gfc_t *gfc, co_line_t *line, co_gfc_fn on_gfc, void *user);
void co_gfc_deinit(co_gfc_t *gfc);
/* 0x1300: on subscribes CAN-ID 0x001 (false when it is taken). */
bool co_gfc_set_enabled(co_gfc_t *gfc, bool enabled);
/* Send a GFC (false, counted, when off or the tx queue is full). */
bool co_gfc_send(co_gfc_t *gfc);

#endif
