/* Runtime: the event queue out to the application. A bounded ring with its
 * own lock: the thread posts, Python waits in co_rt_wait_events. A full
 * queue drops and counts; CO_EV_EVENTS_LOST says so as soon as there is
 * room again. */
#include "co_rt_internal.h"

#include <stdlib.h>

bool rt_events_open(rt_events_t *q, uint32_t capacity)
{
    rt_mutex_init(&q->lock);
    rt_cond_init(&q->ready);
    q->capacity = capacity;
    q->ring = calloc(capacity, sizeof *q->ring);
    return q->ring != NULL;
}

void rt_events_free(rt_events_t *q)
{
    free(q->ring);
    rt_mutex_destroy(&q->lock);
    rt_cond_destroy(&q->ready);
}

static void ring_push(rt_events_t *q, const co_rt_event_t *ev)
{
    q->ring[(q->head + q->count) % q->capacity] = *ev;
    q->count++;
}

/* With q->lock held: report drops as soon as there is room again. */
static void push_lost_marker(rt_events_t *q)
{
    if (q->lost == 0 || q->count == q->capacity) {
        return;
    }
    co_rt_event_t ev = {.kind = CO_EV_EVENTS_LOST, .line = -1, .a = q->lost,
                        .time_us = co_rt_now_us()};
    ring_push(q, &ev);
    q->lost = 0;
}

static bool events_post(rt_events_t *q, const co_rt_event_t *ev)
{
    rt_mutex_lock(&q->lock);
    push_lost_marker(q);
    bool queued = q->count < q->capacity;
    if (queued) {
        ring_push(q, ev);
    } else {
        q->lost++;
    }
    if (q->waiters > 0) {
        rt_cond_signal(&q->ready);
    }
    rt_mutex_unlock(&q->lock);
    return queued;
}

bool rt_post(const rt_line_t *l, int kind, uint8_t node, uint32_t a, uint32_t b,
             const co_frame_t *frame)
{
    co_rt_event_t ev = {.kind = kind, .line = l->index, .node = node, .a = a, .b = b,
                        .time_us = co_rt_now_us()};
    if (frame) {
        ev.frame = *frame;
    }
    return events_post(&l->rt->events, &ev);
}

int co_rt_wait_events(co_rt_t *rt, co_rt_event_t *events, int max, int timeout_ms)
{
    if (!rt || !events || max <= 0) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_events_t *q = &rt->events;
    uint64_t deadline = rt_deadline_after_ms(timeout_ms > 0 ? timeout_ms : 0);
    rt_mutex_lock(&q->lock);
    q->waiters++;
    while (q->count == 0 && !q->closed &&
           rt_wait_step(&q->ready, &q->lock, timeout_ms, deadline)) {
    }
    int n = 0;
    for (; n < max && q->count > 0; n++) {
        events[n] = q->ring[q->head];
        q->head = (q->head + 1) % q->capacity;
        q->count--;
    }
    push_lost_marker(q);
    int result = (n == 0 && q->closed) ? CO_RT_ERR_CLOSED : n;
    q->waiters--;
    rt_mutex_unlock(&q->lock);
    return result;
}

void rt_events_close(rt_events_t *q)
{
    rt_mutex_lock(&q->lock);
    q->closed = true;
    rt_cond_broadcast(&q->ready);
    rt_mutex_unlock(&q->lock);
}

uint32_t rt_events_waiters(rt_events_t *q)
{
    rt_mutex_lock(&q->lock);
    uint32_t n = q->waiters;
    rt_mutex_unlock(&q->lock);
    return n;
}
