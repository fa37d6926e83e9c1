/* Bounded FIFO of frames over caller-owned storage. A push into a full queue
 * fails and is counted; nothing is overwritten. */
#ifndef CO_QUEUE_H
#define CO_QUEUE_H

#include "canopenfd/co_assert.h"
#include "canopenfd/co_frame.h"

typedef struct co_frame_queue {
    co_frame_t *slots;
    uint32_t capacity;
    uint32_t head;        /* index of the oldest frame */
    uint32_t count;
    uint32_t overflows;   /* pushes refused because the queue was full */
    uint32_t high_water;  /* largest count seen */
} co_frame_queue_t;

/* slots: capacity frames, capacity > 0 (a caller checks its configuration
 * first; CO_ASSERT catches a broken one). */
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
static inline uint32_t co_queue_room(const co_frame_queue_t *q) { return q->capacity - q->count; }

/* The i-th frame from the oldest, without taking it; i < co_queue_count(q). */
static inline const co_frame_t *co_queue_at(const co_frame_queue_t *q, uint32_t i)
{
    CO_ASSERT(i < q->count);
    uint32_t at = q->head + i;
    return &q->slots[at >= q->capacity ? at - q->capacity : at];
}

#endif
