/* Runtime glue of PDOs. The local node's PDOs themselves run in the core
 * (storage sized from the OD by co_stack); here: the RPDOs Python listens to
 * (CO_EV_PDO with their mapped values packed as in the PDO), the PDO CAN-IDs
 * of other nodes Python watches (CO_EV_PDO_FRAME), and TPDO triggers from
 * the application. State: rt_pdo_t in the line. */
#include "co_rt_internal.h"

#include <string.h>

#define WATCH_EXT 0x20000000u   /* bit 29 of a COB-ID: 29-bit CAN-ID */

void rt_pdo_received(rt_line_t *l, uint16_t number)
{
    if (number == 0 || number > CO_PDO_MAX_NUMBER || !l->pdo.listen[number - 1u]) {
        return;
    }
    /* the values as now in the OD, laid out as the mapping says */
    co_frame_t frame;
    memset(&frame, 0, sizeof frame);
    if (co_pdo_pack_values(co_stack_pdo(&l->stack), true, number, frame.data, &frame.len)) {
        rt_post(l, CO_EV_PDO, co_stack_node(&l->stack)->nmt.node_id, number, 0, &frame);
    }
}

void rt_pdo_node_detach(rt_line_t *l)
{
    memset(l->pdo.listen, 0, sizeof l->pdo.listen);
}

static int watch_find(const rt_pdo_t *p, uint32_t can_id)
{
    if (!(can_id & WATCH_EXT)) {
        return (int)p->watch_of[can_id & 0x7FFu] - 1;
    }
    for (int i = 0; i < p->watch_count; i++) {
        if (p->watch_ids[i] == can_id) {
            return i;
        }
    }
    return -1;
}

/* Offered before the PDO service (registered first): watched frames are
 * posted and then left to whoever else takes them. */
static bool on_watched(co_line_t *line, const co_frame_t *frame, void *user)
{
    (void)line;
    rt_line_t *l = user;
    rt_pdo_t *p = &l->pdo;
    if (p->watch_count == 0 || (frame->flags & CO_FRAME_RTR)) {
        return false;
    }
    uint32_t can_id = (frame->flags & CO_FRAME_EXT) ? (frame->id | WATCH_EXT) : frame->id;
    int slot = watch_find(p, can_id);
    if (slot >= 0) {
        p->watch_frames[slot]++;
        rt_post(l, CO_EV_PDO_FRAME, 0, can_id, p->watch_frames[slot], frame);
    }
    return false;
}

bool rt_pdo_line_init(rt_line_t *l)
{
    return co_line_subscribe_other(&l->line, on_watched, l);
}

uint32_t rt_pdo_watched_frames(const rt_line_t *l)
{
    uint32_t frames = 0;
    for (int i = 0; i < l->pdo.watch_count; i++) {
        frames += l->pdo.watch_frames[i];
    }
    return frames;
}

/* The line, locked, with a local node serving an OD (PDOs exist), or NULL
 * with the error set, unlocked. */
static rt_line_t *pdo_line(co_rt_t *rt, int line)
{
    rt_line_t *l = rt_node_line(rt, line, "a PDO");
    if (l && co_stack_pdo(&l->stack) == NULL) {
        rt_mutex_unlock(&rt->lock);
        rt_set_error(rt, "line %d: the local node has no object dictionary, so no PDOs", line);
        return NULL;
    }
    return l;
}

int co_rt_pdo_trigger(co_rt_t *rt, int line, int tpdo_number)
{
    rt_line_t *l = pdo_line(rt, line);
    if (!l) {
        return CO_RT_ERR_STATE;
    }
    co_line_set_time(&l->line, co_rt_now_us());
    co_pdo_t *pdo = co_stack_pdo(&l->stack);
    if (tpdo_number < 1 || tpdo_number > CO_PDO_MAX_NUMBER ||
        !co_pdo_trigger(pdo, (uint16_t)tpdo_number)) {
        rt_set_error(rt, "line %d: TPDO %d not sent: %s", line, tpdo_number,
                     tpdo_number < 1 || tpdo_number > CO_PDO_MAX_NUMBER ? "numbers are 1..512"
                     : !co_pdo_is_active(pdo, false, (uint16_t)tpdo_number)
                         ? "it does not exist or is not valid (COB-ID bit 31, mapping)"
                     : co_stack_node(&l->stack)->nmt.state != CO_NMT_OPERATIONAL
                         ? "the node is not operational"
                         : "its transmission type takes no events (0, 254 or 255 do)");
        return rt_kick_unlock(rt, CO_RT_ERR_STATE);
    }
    return rt_kick_unlock(rt, CO_RT_OK);
}

int co_rt_pdo_trigger_object(co_rt_t *rt, int line, int index, int sub)
{
    rt_line_t *l = pdo_line(rt, line);
    if (!l) {
        return CO_RT_ERR_STATE;
    }
    if (index < 0 || index > 0xFFFF || sub < 0 || sub > 0xFF) {
        rt_mutex_unlock(&rt->lock);
        return rt_argument_error(rt, "line %d: no object %X:%X", line, index, sub);
    }
    co_line_set_time(&l->line, co_rt_now_us());
    uint32_t n = co_pdo_trigger_object(co_stack_pdo(&l->stack), (uint16_t)index, (uint8_t)sub);
    return rt_kick_unlock(rt, (int)n);
}

/* Under rt->lock: start watching can_id (not watched yet). */
static int watch_add(co_rt_t *rt, rt_line_t *l, uint32_t can_id)
{
    rt_pdo_t *p = &l->pdo;
    if (p->watch_count >= RT_PDO_WATCHES) {
        rt_set_error(rt, "line %d: already %d PDO CAN-IDs watched", l->index, RT_PDO_WATCHES);
        return CO_RT_ERR_FULL;
    }
    int slot = p->watch_count++;
    p->watch_ids[slot] = can_id;
    p->watch_frames[slot] = 0;
    if (!(can_id & WATCH_EXT)) {
        p->watch_of[can_id] = (uint8_t)(slot + 1);
    }
    return CO_RT_OK;
}

/* Under rt->lock: stop watching the id in slot; the last slot moves into it. */
static void watch_remove(rt_pdo_t *p, int slot)
{
    uint8_t last = (uint8_t)(p->watch_count - 1u);
    if (!(p->watch_ids[slot] & WATCH_EXT)) {
        p->watch_of[p->watch_ids[slot]] = 0;
    }
    if (slot != last) {
        p->watch_ids[slot] = p->watch_ids[last];
        p->watch_frames[slot] = p->watch_frames[last];
        if (!(p->watch_ids[slot] & WATCH_EXT)) {
            p->watch_of[p->watch_ids[slot]] = (uint8_t)(slot + 1);
        }
    }
    p->watch_count = last;
}

int co_rt_pdo_watch(co_rt_t *rt, int line, uint32_t can_id, int watch)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    bool ext = (can_id & WATCH_EXT) != 0;
    if ((ext && (can_id & ~(WATCH_EXT | 0x1FFFFFFFu)) != 0) || (!ext && can_id > 0x7FFu)) {
        return rt_argument_error(rt, "line %d: PDO CAN-ID 0x%X: 11 bits, or 29 bits with bit "
                                 "29 set", line, (unsigned)can_id);
    }
    rt_mutex_lock(&rt->lock);
    int slot = watch_find(&l->pdo, can_id);
    int status = CO_RT_OK;
    if (watch && slot < 0) {
        status = watch_add(rt, l, can_id);
    } else if (!watch && slot >= 0) {
        watch_remove(&l->pdo, slot);
    }
    rt_mutex_unlock(&rt->lock);
    return status;
}

int co_rt_pdo_listen(co_rt_t *rt, int line, int rpdo_number, int listen)
{
    if (rpdo_number < 1 || rpdo_number > CO_PDO_MAX_NUMBER) {
        return rt_argument_error(rt, "line %d: RPDO %d: numbers are 1..512", line, rpdo_number);
    }
    rt_line_t *l = pdo_line(rt, line);
    if (!l) {
        return CO_RT_ERR_STATE;
    }
    l->pdo.listen[rpdo_number - 1] = listen != 0;
    rt_mutex_unlock(&rt->lock);
    return CO_RT_OK;
}
