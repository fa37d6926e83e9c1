#include "canopenfd/co_queue.h"

void co_queue_init(co_frame_queue_t *q, co_frame_t *slots, uint32_t capacity)
{
    CO_ASSERT(slots != NULL && capacity > 0);
    q->slots = slots;
    q->capacity = capacity;
    q->head = 0;
    q->count = 0;
    q->overflows = 0;
    q->high_water = 0;
}

bool co_queue_push(co_frame_queue_t *q, const co_frame_t *frame)
{
    CO_ASSERT(q->count <= q->capacity && q->head < q->capacity);
    if (q->count == q->capacity) {
        q->overflows++;
        return false;
    }
    uint32_t tail = q->head + q->count;
    if (tail >= q->capacity) {
        tail -= q->capacity;
    }
    q->slots[tail] = *frame;
    q->count++;
    if (q->count > q->high_water) {
        q->high_water = q->count;
    }
    return true;
}

const co_frame_t *co_queue_peek(const co_frame_queue_t *q)
{
    return q->count ? &q->slots[q->head] : NULL;
}

void co_queue_drop_head(co_frame_queue_t *q)
{
    if (q->count == 0) {
        return;
    }
    CO_ASSERT(q->count <= q->capacity && q->head < q->capacity);
    q->head = (q->head + 1 == q->capacity) ? 0 : q->head + 1;
    q->count--;
}

bool co_queue_pop(co_frame_queue_t *q, co_frame_t *out)
{
    if (q->count == 0) {
        return false;
    }
    *out = q->slots[q->head];
    co_queue_drop_head(q);
    return true;
}

void co_queue_clear(co_frame_queue_t *q)
{
    q->head = 0;
    q->count = 0;
}
