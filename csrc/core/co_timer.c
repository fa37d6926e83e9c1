#include "canopenfd/co_timer.h"

#include "canopenfd/co_assert.h"

#include <stddef.h>

void co_timer_list_init(co_timer_list_t *list)
{
    list->head = NULL;
    list->tail = NULL;
    list->armed = 0;
    list->seq = 0;
}

void co_timer_init(co_timer_t *timer, co_timer_fn fn, void *user)
{
    timer->prev = NULL;
    timer->next = NULL;
    timer->deadline_us = 0;
    timer->seq = 0;
    timer->fn = fn;
    timer->user = user;
    timer->armed = false;
}

static void unlink_timer(co_timer_list_t *list, co_timer_t *timer)
{
    /* armed on this list: its neighbours (or the list's ends) point at it */
    CO_ASSERT(list->armed > 0);
    CO_ASSERT(timer->prev ? timer->prev->next == timer : list->head == timer);
    CO_ASSERT(timer->next ? timer->next->prev == timer : list->tail == timer);
    if (timer->prev) {
        timer->prev->next = timer->next;
    } else {
        list->head = timer->next;
    }
    if (timer->next) {
        timer->next->prev = timer->prev;
    } else {
        list->tail = timer->prev;
    }
    timer->prev = NULL;
    timer->next = NULL;
    timer->armed = false;
    list->armed--;
}

void co_timer_cancel(co_timer_list_t *list, co_timer_t *timer)
{
    if (timer->armed) {
        unlink_timer(list, timer);
    }
}

void co_timer_start(co_timer_list_t *list, co_timer_t *timer, uint64_t deadline_us)
{
    co_timer_cancel(list, timer);
    timer->deadline_us = deadline_us;
    timer->seq = ++list->seq;
    timer->armed = true;
    list->armed++;

    /* Scan from the tail: periodic timers re-armed at now + period usually
     * belong at (or near) the end, so insertion is O(1) in the common case.
     * Stopping at the first timer with deadline <= ours keeps equal deadlines
     * in arm order. */
    co_timer_t *after = list->tail;
    while (after && after->deadline_us > deadline_us) {
        after = after->prev;
    }
    timer->prev = after;
    if (after) {
        timer->next = after->next;
        after->next = timer;
    } else {
        timer->next = list->head;
        list->head = timer;
    }
    if (timer->next) {
        timer->next->prev = timer;
    } else {
        list->tail = timer;
    }
}

uint64_t co_timer_list_next(const co_timer_list_t *list)
{
    return list->head ? list->head->deadline_us : CO_TIME_NEVER;
}

/* First timer that was due when the run started: skip the ones armed since
 * (seq > entry_seq); they sit among the due ones only when armed at <= now. */
static co_timer_t *first_due(const co_timer_list_t *list, uint64_t now_us, uint64_t entry_seq)
{
    co_timer_t *t = list->head;
    while (t && t->deadline_us <= now_us && t->seq > entry_seq) {
        t = t->next;
    }
    return (t && t->deadline_us <= now_us) ? t : NULL;
}

uint32_t co_timer_list_run(co_timer_list_t *list, uint64_t now_us)
{
    const uint64_t entry_seq = list->seq;
    uint32_t fired = 0;
    co_timer_t *timer;
    while ((timer = first_due(list, now_us, entry_seq)) != NULL) {
        unlink_timer(list, timer);
        fired++;
        if (timer->fn) {
            timer->fn(timer, now_us, timer->user);
        }
    }
    return fired;
}
