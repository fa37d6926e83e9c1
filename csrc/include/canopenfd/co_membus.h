/* In-process CAN bus: connects lines inside one process with exact frame
 * semantics (a frame reaches every other line on the bus, in order, never its
 * sender). Portable: no OS, no allocation; used by the runtime, the C unit
 * tests and the benchmarks. */
#ifndef CO_MEMBUS_H
#define CO_MEMBUS_H

#include "canopenfd/co_line.h"

enum { CO_MEMBUS_MAX_LINES = 32 };

/* Fault injection hook: called once per frame on the bus; returns how many
 * times the frame is delivered (0 = lost, 1 = normal, 2 = duplicated). */
typedef uint8_t (*co_membus_fault_fn)(const co_frame_t *frame, void *user);

typedef struct co_membus {
    co_line_t *lines[CO_MEMBUS_MAX_LINES];
    uint8_t count;
    uint32_t frames;              /* frames carried */
    co_membus_fault_fn fault;
    void *fault_user;
} co_membus_t;

void co_membus_init(co_membus_t *bus);
bool co_membus_attach(co_membus_t *bus, co_line_t *line);
void co_membus_detach(co_membus_t *bus, co_line_t *line);
void co_membus_set_fault(co_membus_t *bus, co_membus_fault_fn fn, void *user);
typedef void (*co_membus_sent_fn)(co_line_t *from, const co_frame_t *frame, void *user);

/* Move every queued tx frame of every attached line to the other lines'
 * rx queues, sender by sender in attach order. `sent` (may be NULL) sees every
 * frame carried, for monitoring. Returns frames moved. */
uint32_t co_membus_transfer(co_membus_t *bus, co_membus_sent_fn sent, void *user);

#endif
