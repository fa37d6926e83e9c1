/* A CANopen FD (or classic) device written in C only, over the portable core:
 * its object dictionary is a static table, co_stack assembles the services,
 * and the caller's loop feeds frames and time. The same file builds for
 * Linux (main_linux.c) and for a Cortex-M (main_bare.c). */
#ifndef EXAMPLE_DEVICE_H
#define EXAMPLE_DEVICE_H

#include "canopenfd/co_stack.h"

enum {
    DEVICE_QUEUE = 32,            /* rx and tx frames the line holds */
    DEVICE_OD_ENTRIES = 48,
    DEVICE_OD_POOL = 512,
    DEVICE_HB_ENTRIES = 4,        /* nodes whose heartbeat the device can watch */
    DEVICE_SERVER_SESSIONS = 2,   /* fd: USDO transfers served at once */
    DEVICE_PDO_CHANNELS = 2,      /* one RPDO, one TPDO */
    DEVICE_MAP_ITEMS = 8,         /* mapping sub-entries of both */
    DEVICE_LARGEST_ENTRY = 32,    /* 0x1008 device name */
    DEVICE_COUNTER_PERIOD_US = 100000
};

/* The stack's memory, known at compile time (co_stack_*_need match it:
 * device_init refuses to start otherwise). */
#define DEVICE_MEMORY                                                              \
    (CO_STACK_LINE_MEMORY(DEVICE_HB_ENTRIES, 0) +                                   \
     CO_STACK_NODE_MEMORY(DEVICE_PDO_CHANNELS, DEVICE_MAP_ITEMS, DEVICE_LARGEST_ENTRY, 0, \
                          DEVICE_SERVER_SESSIONS))

typedef struct device {
    co_line_t line;
    co_frame_t rx[DEVICE_QUEUE];
    co_frame_t tx[DEVICE_QUEUE];
    co_od_t od;
    co_od_entry_t entries[DEVICE_OD_ENTRIES];
    uint8_t pool[DEVICE_OD_POOL];
    co_od_subscription_t subs[CO_STACK_OD_SUBSCRIPTIONS];
    co_stack_t stack;
    co_stack_arena_t arena;
    uint64_t memory[(DEVICE_MEMORY + 7) / 8];
    co_timer_t counter_timer;     /* the application: a counter sent by TPDO 1 */
} device_t;

/* Set up the line (fd or classic), the OD and the stack with node node_id;
 * boots the node (boot-up queued). NULL when it started, else what failed. */
const char *device_init(device_t *d, co_mode_t mode, uint8_t node_id);
/* Run what is due at now_us (frames received so far, timers); returns the
 * next deadline. Frames to send are then in the line's tx queue. */
uint64_t device_process(device_t *d, uint64_t now_us);

#endif
