/* Runtime glue of a master driving other nodes' RPDOs: the line produces
 * the PDO the device's RPDO consumes (its COB-ID, its mapped bytes). Per
 * line a fixed table of RT_RPDO_PRODUCERS (part of the line, allocated with
 * it); nothing is allocated per frame. Every access holds rt->lock, as the
 * runtime thread does while it processes the line (timers, SYNC), so a
 * frame carries either all of a write or none of it.
 *
 * What goes out when:
 *   co_rt_rpdo_send   at once;
 *   co_rt_rpdo_sync   right after every n-th SYNC the line receives or
 *                     produces (the device applies synchronous RPDO data at
 *                     the SYNC after the reception, whatever its type 0..240:
 *                     sending just after a SYNC gives it the whole cycle);
 *                     acyclic (type 0): after the first SYNC following a
 *                     write, so unchanged data is not repeated;
 *   co_rt_rpdo_start  every period_us on the line's timer list.
 * NMT: while the line has a local node, frames go out only while it is
 * OPERATIONAL (CiA 301 allows PDOs in that state only); a line without a
 * local node (a pure master or tool) sends regardless. */
#include "co_rt_internal.h"

#include <string.h>

#define RPDO_EXT 0x20000000u    /* bit 29 of a COB-ID: 29-bit CAN-ID */
#define RPDO_MIN_PERIOD_US 100u

static bool may_send(rt_line_t *l)
{
    return !rt_has_node(l) || co_stack_node(&l->stack)->nmt.state == CO_NMT_OPERATIONAL;
}

/* Under rt->lock: queue the frame; false (counted) when not sent. */
static bool send_now(rt_rpdo_out_t *p)
{
    rt_line_t *l = p->line;
    if (!may_send(l)) {
        p->stats.not_operational++;
        return false;
    }
    co_frame_t f;
    f.id = p->can_id & 0x1FFFFFFFu;
    f.flags = (p->can_id & RPDO_EXT) ? CO_FRAME_EXT : 0;
    f.len = p->length;
    memcpy(f.data, p->data, p->length);
    if (!co_line_send_frame(&l->line, &f)) {   /* fd lines round the length up */
        p->stats.tx_failed++;
        return false;
    }
    p->stats.sent++;
    p->changed = false;
    return true;
}

static void on_timer(co_timer_t *timer, uint64_t now_us, void *user)
{
    rt_rpdo_out_t *p = user;
    /* the next period from the planned deadline (no drift), unless far behind */
    uint64_t next = timer->deadline_us + p->period_us;
    if (next <= now_us) {
        next = now_us + p->period_us;
    }
    co_timer_start(co_line_timers(&p->line->line), timer, next);
    send_now(p);
}

static void on_sync(uint8_t counter, void *user)
{
    (void)counter;
    rt_line_t *l = user;
    for (int i = 0; i < RT_RPDO_PRODUCERS; i++) {
        rt_rpdo_out_t *p = &l->rpdo_out[i];
        if (!p->used || p->sync_every == 0) {
            continue;
        }
        if (p->sync_acyclic) {
            if (p->changed) {
                send_now(p);
            }
        } else if (++p->sync_seen >= p->sync_every) {
            p->sync_seen = 0;
            send_now(p);
        }
    }
}

bool rt_rpdo_out_line_init(rt_line_t *l)
{
    for (int i = 0; i < RT_RPDO_PRODUCERS; i++) {
        l->rpdo_out[i].line = l;
        co_timer_init(&l->rpdo_out[i].timer, on_timer, &l->rpdo_out[i]);
    }
    return co_sync_add_listener(co_stack_sync(&l->stack), on_sync, l);
}

/* The line, locked, and its producer in slot (used), or NULL with the error
 * set, unlocked. */
static rt_rpdo_out_t *producer(co_rt_t *rt, int line, int slot, rt_line_t **out)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return NULL;
    }
    if (slot < 0 || slot >= RT_RPDO_PRODUCERS) {
        rt_argument_error(rt, "line %d: RPDO producer %d: slots are 0..%d", line, slot,
                          RT_RPDO_PRODUCERS - 1);
        return NULL;
    }
    rt_mutex_lock(&rt->lock);
    if (!l->rpdo_out[slot].used) {
        rt_mutex_unlock(&rt->lock);
        rt_set_error(rt, "line %d: RPDO producer %d is not open", line, slot);
        return NULL;
    }
    *out = l;
    co_line_set_time(&l->line, co_rt_now_us());   /* timers armed from now */
    return &l->rpdo_out[slot];
}

static void halt(rt_rpdo_out_t *p)
{
    co_timer_cancel(co_line_timers(&p->line->line), &p->timer);
    p->period_us = 0;
    p->sync_every = 0;
    p->sync_acyclic = false;
}

int co_rt_rpdo_open(co_rt_t *rt, int line, uint32_t can_id, int length)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    bool ext = (can_id & RPDO_EXT) != 0;
    if ((ext && (can_id & ~(RPDO_EXT | 0x1FFFFFFFu)) != 0) || (!ext && can_id > 0x7FFu)) {
        return rt_argument_error(rt, "line %d: RPDO CAN-ID 0x%X: 11 bits, or 29 bits with "
                                 "bit 29 set", line, (unsigned)can_id);
    }
    int most = l->line.mode == CO_MODE_CLASSIC ? 8 : 64;
    if (length < 1 || length > most) {
        return rt_argument_error(rt, "line %d: RPDO of %d bytes: 1..%d on a %s line", line,
                                 length, most, most == 8 ? "classic" : "fd");
    }
    rt_mutex_lock(&rt->lock);
    for (int i = 0; i < RT_RPDO_PRODUCERS; i++) {
        rt_rpdo_out_t *p = &l->rpdo_out[i];
        if (!p->used) {
            p->used = true;
            p->can_id = can_id;
            p->length = (uint8_t)length;
            memset(p->data, 0, sizeof p->data);
            p->changed = false;
            p->sync_seen = 0;
            memset(&p->stats, 0, sizeof p->stats);
            halt(p);
            rt_mutex_unlock(&rt->lock);
            return i;
        }
    }
    rt_mutex_unlock(&rt->lock);
    rt_set_error(rt, "line %d: already %d RPDO producers (stop and forget one first)", line,
                 RT_RPDO_PRODUCERS);
    return CO_RT_ERR_FULL;
}

int co_rt_rpdo_close(co_rt_t *rt, int line, int slot)
{
    rt_line_t *l;
    rt_rpdo_out_t *p = producer(rt, line, slot, &l);
    if (!p) {
        return CO_RT_ERR_ARGUMENT;
    }
    halt(p);
    p->used = false;
    return rt_kick_unlock(rt, CO_RT_OK);
}

int co_rt_rpdo_write(co_rt_t *rt, int line, int slot, int bit_offset, int bit_length,
                     const uint8_t *value, int value_len)
{
    rt_line_t *l;
    rt_rpdo_out_t *p = producer(rt, line, slot, &l);
    if (!p) {
        return CO_RT_ERR_ARGUMENT;
    }
    int bits = 8 * p->length;
    if (bit_offset < 0 || bit_length < 1 || bit_offset > bits - bit_length ||
        value == NULL || value_len < (bit_length + 7) / 8) {
        rt_mutex_unlock(&rt->lock);
        return rt_argument_error(rt, "line %d: RPDO producer %d: bits %d..%d from %d value "
                                 "bytes do not fit its %d bits", line, slot, bit_offset,
                                 bit_offset + bit_length - 1, value_len, bits);
    }
    if (bit_offset % 8 == 0 && bit_length % 8 == 0) {
        memcpy(p->data + bit_offset / 8, value, (size_t)bit_length / 8u);
    } else {
        for (int i = 0; i < bit_length; i++) {
            bool on = (value[i / 8] >> (i % 8)) & 1u;
            int at = bit_offset + i;
            uint8_t mask = (uint8_t)(1u << (at % 8));
            p->data[at / 8] = on ? (uint8_t)(p->data[at / 8] | mask)
                                 : (uint8_t)(p->data[at / 8] & ~mask);
        }
    }
    p->changed = true;
    p->stats.writes++;
    rt_mutex_unlock(&rt->lock);
    return CO_RT_OK;
}

int co_rt_rpdo_read(co_rt_t *rt, int line, int slot, uint8_t *out, int out_len)
{
    rt_line_t *l;
    rt_rpdo_out_t *p = producer(rt, line, slot, &l);
    if (!p) {
        return CO_RT_ERR_ARGUMENT;
    }
    int n = p->length;
    if (out == NULL || out_len < n) {
        rt_mutex_unlock(&rt->lock);
        return rt_argument_error(rt, "line %d: RPDO producer %d: %d bytes need room", line,
                                 slot, n);
    }
    memcpy(out, p->data, (size_t)n);
    rt_mutex_unlock(&rt->lock);
    return n;
}

int co_rt_rpdo_send(co_rt_t *rt, int line, int slot)
{
    rt_line_t *l;
    rt_rpdo_out_t *p = producer(rt, line, slot, &l);
    if (!p) {
        return CO_RT_ERR_ARGUMENT;
    }
    if (!send_now(p)) {
        rt_set_error(rt, "line %d: RPDO on CAN-ID 0x%X not sent: %s", line,
                     (unsigned)(p->can_id & 0x1FFFFFFFu),
                     may_send(l) ? "the line's transmit queue is full"
                                 : "the line's local node is not OPERATIONAL (PDOs are sent "
                                   "in OPERATIONAL only)");
        return rt_kick_unlock(rt, CO_RT_ERR_STATE);
    }
    return rt_kick_unlock(rt, CO_RT_OK);
}

int co_rt_rpdo_sync(co_rt_t *rt, int line, int slot, int every, int acyclic)
{
    if (every < 1 || every > CO_SYNC_COUNTER_MAX || (acyclic && every != 1)) {
        return rt_argument_error(rt, "line %d: RPDO producer %d: every %d SYNC%s: 1..240 "
                                 "(acyclic: 1)", line, slot, every, acyclic ? " acyclic" : "");
    }
    rt_line_t *l;
    rt_rpdo_out_t *p = producer(rt, line, slot, &l);
    if (!p) {
        return CO_RT_ERR_ARGUMENT;
    }
    p->sync_every = (uint8_t)every;
    p->sync_acyclic = acyclic != 0;
    p->sync_seen = 0;
    if (p->sync_acyclic) {
        p->changed = true;      /* the values as they stand go out at the next SYNC */
    }
    rt_mutex_unlock(&rt->lock);
    return CO_RT_OK;
}

int co_rt_rpdo_start(co_rt_t *rt, int line, int slot, uint32_t period_us)
{
    if (period_us < RPDO_MIN_PERIOD_US) {
        return rt_argument_error(rt, "line %d: RPDO producer %d: period %u us: at least %u",
                                 line, slot, (unsigned)period_us, RPDO_MIN_PERIOD_US);
    }
    rt_line_t *l;
    rt_rpdo_out_t *p = producer(rt, line, slot, &l);
    if (!p) {
        return CO_RT_ERR_ARGUMENT;
    }
    p->period_us = period_us;
    /* the first frame now: armed at the line's time, the next turn sends it */
    co_timer_start(co_line_timers(&l->line), &p->timer, co_line_now(&l->line));
    return rt_kick_unlock(rt, CO_RT_OK);
}

int co_rt_rpdo_stop(co_rt_t *rt, int line, int slot)
{
    rt_line_t *l;
    rt_rpdo_out_t *p = producer(rt, line, slot, &l);
    if (!p) {
        return CO_RT_ERR_ARGUMENT;
    }
    halt(p);
    return rt_kick_unlock(rt, CO_RT_OK);
}

int co_rt_rpdo_stats(co_rt_t *rt, int line, int slot, co_rt_rpdo_stats_t *out)
{
    rt_line_t *l;
    rt_rpdo_out_t *p = out ? producer(rt, line, slot, &l) : NULL;
    if (!p) {
        return out ? CO_RT_ERR_ARGUMENT : rt_argument_error(rt, "no stats buffer");
    }
    *out = p->stats;
    rt_mutex_unlock(&rt->lock);
    return CO_RT_OK;
}
