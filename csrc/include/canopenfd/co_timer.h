/* Sorted timer list. Timers are caller-owned structs linked into the list, so
 * any number can be armed without allocation. The list is kept sorted by
 * deadline; a tick only looks at the head. Equal deadlines fire in the order
 * they were armed. */
#ifndef CO_TIMER_H
#define CO_TIMER_H

#include <stdbool.h>
#include <stdint.h>

#define CO_TIME_NEVER UINT64_MAX

typedef struct co_timer co_timer_t;
typedef void (*co_timer_fn)(co_timer_t *timer, uint64_t now_us, void *user);

struct co_timer {
    co_timer_t *prev;
    co_timer_t *next;
    uint64_t deadline_us;
    uint64_t seq;          /* arm order: tells timers armed during a run apart */
    co_timer_fn fn;
    void *user;
    bool armed;
};

typedef struct co_timer_list {
    co_timer_t *head;     /* earliest deadline */
    co_timer_t *tail;     /* latest deadline: periodic re-arms usually land here */
    uint32_t armed;
    uint64_t seq;         /* last arm sequence number handed out */
} co_timer_list_t;

void co_timer_list_init(co_timer_list_t *list);
void co_timer_init(co_timer_t *timer, co_timer_fn fn, void *user);
/* Arm (or re-arm) a timer to fire at deadline_us. An armed timer belongs to
 * the list it was armed on: start and cancel it on that list only. */
void co_timer_start(co_timer_list_t *list, co_timer_t *timer, uint64_t deadline_us);
/* Disarm; harmless on a timer that is not armed. */
void co_timer_cancel(co_timer_list_t *list, co_timer_t *timer);
/* Earliest deadline, CO_TIME_NEVER when nothing is armed. */
uint64_t co_timer_list_next(const co_timer_list_t *list);
/* Fire the timers that were due (deadline <= now_us) when the call started,
 * earliest first. A callback may arm, re-arm or cancel any timer; a timer
 * armed during the run waits for the next call even when it is already due,
 * so a zero period cannot make a run spin (the returned next deadline is then
 * <= now_us). Returns the number fired. */
uint32_t co_timer_list_run(co_timer_list_t *list, uint64_t now_us);

static inline bool co_timer_is_armed(const co_timer_t *timer) { return timer->armed; }

#endif
