/* Runtime: the event queue out to the application. A bounded ring with its
 * own lock: the thread posts, Python waits in co_rt_wait_events. A full
 * queue drops and counts; CO_EV_EVENTS_LOST says so as soon as there is
 * room again.
 *
 * Coalescing: a slow consumer must not lose PDOs at random. Every queued
 * per-frame event (CO_EV_PDO, CO_EV_PDO_FRAME, CO_EV_MPDO, and
 * CO_EV_OD_CHANGED: an MPDO flood writes one entry per frame, and Python
 * reads the entry's value live) is remembered in a small hash table of its
 * source (line, kind, a) -> sequence number. From the high-water mark on
 * (3/4 of the ring), a new event of a source that still has one queued
 * replaces that one in place (latest value, its `coalesced` count grows)
 * instead of taking a slot; the last quarter stays for events that cannot be
 * merged. Each source keeps its order; the replaced values are counted. */
#include "co_rt_internal.h"

#include <stdlib.h>

/* Trimming after a backlog (see trim): what stays resident, and how far past
 * it a backlog must have gone before its pages are given back. */
#define RT_EVENTS_KEEP_BYTES (64u * 1024u)
#define RT_EVENTS_TRIM_MIN_BYTES (256u * 1024u)

bool rt_events_open(rt_events_t *q, uint32_t capacity)
{
    rt_mutex_init(&q->lock);
    rt_cond_init(&q->ready);
    q->capacity = capacity;
    q->high_water = capacity - capacity / 4u;
    /* not calloc: zeroing would make every page resident at once (a slot is
     * always written before it is read) */
    q->ring = malloc((size_t)capacity * sizeof *q->ring);
    q->slots = calloc(RT_COALESCE_SLOTS, sizeof *q->slots);
    return q->ring != NULL && q->slots != NULL;
}

void rt_events_free(rt_events_t *q)
{
    free(q->ring);
    free(q->slots);
    rt_mutex_destroy(&q->lock);
    rt_cond_destroy(&q->ready);
}

static void ring_push(rt_events_t *q, const co_rt_event_t *ev)
{
    uint32_t end = q->head + q->count + 1u;   /* past the slot written (a wrap: all) */
    if (end > q->reached) {
        q->reached = end < q->capacity ? end : q->capacity;
    }
    q->ring[(q->head + q->count) % q->capacity] = *ev;
    q->count++;
    q->pushed++;
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

static bool coalescable(const co_rt_event_t *ev)
{
    return (ev->kind == CO_EV_PDO || ev->kind == CO_EV_PDO_FRAME || ev->kind == CO_EV_MPDO ||
            ev->kind == CO_EV_OD_CHANGED) &&
           ev->line >= 0 && ev->line < RT_MAX_LINES;
}

/* Never 0 (0 marks a slot never used): the kind is never 0. */
static uint64_t source_key(const co_rt_event_t *ev)
{
    return ((uint64_t)(uint32_t)ev->line << 40) | ((uint64_t)(uint8_t)ev->kind << 32) | ev->a;
}

static uint32_t slot_hash(uint64_t key)
{
    return (uint32_t)((key * 0x9E3779B97F4A7C15u) >> 40) & (RT_COALESCE_SLOTS - 1u);
}

static bool still_queued(const rt_events_t *q, uint64_t seq)
{
    return seq >= q->pushed - q->count && seq < q->pushed;
}

/* The slot of key, or (probing a few) a free one for it, or NULL. */
static rt_coalesce_slot_t *slot_of(rt_events_t *q, uint64_t key, bool for_insert)
{
    uint32_t at = slot_hash(key);
    rt_coalesce_slot_t *free_slot = NULL;
    for (uint32_t i = 0; i < RT_COALESCE_PROBES; i++) {
        rt_coalesce_slot_t *slot = &q->slots[(at + i) & (RT_COALESCE_SLOTS - 1u)];
        if (slot->key == key) {
            return slot;
        }
        if (!free_slot && (slot->key == 0 || !still_queued(q, slot->seq))) {
            free_slot = slot;
        }
    }
    return for_insert ? free_slot : NULL;
}

/* Merge ev into the queued event of its source, if it still has one. */
static bool coalesce(rt_events_t *q, const co_rt_event_t *ev)
{
    rt_coalesce_slot_t *slot = slot_of(q, source_key(ev), false);
    if (!slot || !still_queued(q, slot->seq)) {
        return false;
    }
    uint64_t popped = q->pushed - q->count;
    co_rt_event_t *queued = &q->ring[(q->head + (uint32_t)(slot->seq - popped)) % q->capacity];
    uint64_t merged = (uint64_t)queued->coalesced + 1u + ev->coalesced;
    *queued = *ev;
    queued->coalesced = merged > UINT32_MAX ? UINT32_MAX : (uint32_t)merged;
    return true;
}

static void remember(rt_events_t *q, const co_rt_event_t *ev, uint64_t seq)
{
    uint64_t key = source_key(ev);
    rt_coalesce_slot_t *slot = slot_of(q, key, true);
    if (slot) {  /* else: too many sources queued; this one just will not merge */
        slot->key = key;
        slot->seq = seq;
    }
}

static bool events_post(rt_events_t *q, const co_rt_event_t *ev)
{
    rt_mutex_lock(&q->lock);
    push_lost_marker(q);
    bool merge = coalescable(ev);
    co_rt_event_stats_t *stats = ev->line >= 0 && ev->line < RT_MAX_LINES
                                     ? &q->line_stats[ev->line] : NULL;
    bool queued = true;
    if (merge && q->count >= q->high_water && coalesce(q, ev)) {
        if (stats) {
            stats->events_coalesced++;
        }
    } else if (q->count < q->capacity) {
        if (merge) {
            remember(q, ev, q->pushed);
        }
        ring_push(q, ev);
        if (stats) {
            stats->events_posted++;
        }
    } else {
        queued = false;
        q->lost++;
        if (stats) {
            stats->events_lost++;
        }
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

/* The queue is empty: after a backlog that went far into the ring, give its
 * pages back (the first RT_EVENTS_KEEP_BYTES stay: a consumer that keeps up
 * uses only those), so a burst does not leave megabytes resident. */
static void trim(rt_events_t *q)
{
    size_t keep = RT_EVENTS_KEEP_BYTES / sizeof *q->ring;
    if (q->reached <= keep + RT_EVENTS_TRIM_MIN_BYTES / sizeof *q->ring) {
        return;
    }
    rt_os_discard(q->ring + keep, (size_t)(q->reached - keep) * sizeof *q->ring);
    q->reached = (uint32_t)keep;
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
    if (q->count == 0) {
        /* Start again at the first slot: a consumer that keeps up then only
         * ever touches the ring's first pages, so its memory becomes resident
         * only as far as a backlog really reached (not by wrapping around). */
        q->head = 0;
        trim(q);
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

co_rt_event_stats_t rt_events_line_stats(rt_events_t *q, int line)
{
    rt_mutex_lock(&q->lock);
    co_rt_event_stats_t stats = q->line_stats[line];
    rt_mutex_unlock(&q->lock);
    return stats;
}
