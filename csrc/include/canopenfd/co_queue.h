/* Bounded FIFO of frames over caller-owned storage. A push into a full queue
 * fails and is counted; nothing is overwritten. */
#ifndef CO_QUEUE_H
#define CO_QUEUE_H

#include "canopenfd/co_frame.h"

typedef struct co_frame_queue {
    co_frame_t *slots;
    uint32_t capacity;
    uint32_t head;        /* index of the oldest frame */
    uint32_t count;
    uint32_t overflows;   /* pushes refused because the queue was full */
    uint32_t high_water;  /* largest count seen */
} co_frame_queue_t;

void co_queue_init(co_frame_queue_t *q, co_frame_t *slots, uint32_t capacity);
/* Returns false (and counts an overflow) when full. */
bool co_queue_push(co_frame_queue_t *q, const co_frame_t *frame);
/* Returns false when empty. */
bool co_queue_pop(co_frame_queue_t *q, co_frame_t *out);
/* Oldest frame without removing it, NULL when empty. */
const co_frame_t *co_queue_peek(const co_frame_queue_t *q);
void co_queue_drop_head(co_frame_queue_t *q);
void co_queue_clear(co_frame_queue_t *q);

static inline uint32_t co_queue_count(const co_frame_queue_t *q) { return q->count; }
static inline bool co_queue_is_empty(const co_frame_queue_t *q) { return q->count == 0; }
static inline bool co_queue_is_full(const co_frame_queue_t *q) { return q->count == q->capacity; }

#endif
