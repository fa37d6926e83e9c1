#include "co_timer.h"

#include <stddef.h>

void co_timer_list_init(co_timer_list_t *list)
{
    list->head = NULL;
    list->tail = NULL;
    list->armed = 0;
}

void co_timer_init(co_timer_t *timer, co_timer_fn fn, void *user)
{
    timer->prev = NULL;
    timer->next = NULL;
    timer->deadline_us = 0;
    timer->fn = fn;
    timer->user = user;
    timer->armed = false;
}

static void unlink_timer(co_timer_list_t *list, co_timer_t *timer)
{
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

uint32_t co_timer_list_run(co_timer_list_t *list, uint64_t now_us)
{
    /* Bound the run to the timers due at entry: a callback that re-arms at or
     * before now must not make this loop spin. */
    uint32_t budget = list->armed;
    uint32_t fired = 0;
    while (fired < budget && list->head && list->head->deadline_us <= now_us) {
        co_timer_t *timer = list->head;
        unlink_timer(list, timer);
        fired++;
        if (timer->fn) {
            timer->fn(timer, now_us, timer->user);
        }
    }
    return fired;
}
