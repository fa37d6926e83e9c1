/* Linux runtime: the local node's object dictionary (definition, atomic
 * application access, store calls) and the Python indications on it. */
#define _GNU_SOURCE

#include "co_rt_internal.h"

#include <stdlib.h>
#include <string.h>

static const char *od_add_problem(co_od_add_result_t r)
{
    switch (r) {
    case CO_OD_ERR_FULL: return "no room";
    case CO_OD_ERR_DUPLICATE: return "defined twice";
    case CO_OD_ERR_TYPE: return "unknown type, flags, or size that does not fit the type";
    case CO_OD_ERR_DEFAULT: return "default longer than the entry or outside its limits";
    case CO_OD_ERR_LIMITS: return "minimum above maximum";
    case CO_OD_ERR_SEALED: return "dictionary already in use";
    default: return "refused";
    }
}

/* Under rt->lock: allocate and fill the OD (setup time, before the node). */
static int od_fill(co_rt_t *rt, rt_line_t *l, const co_od_def_t *defs, uint32_t count)
{
    uint64_t pool = 0;
    for (uint32_t i = 0; i < count; i++) {
        pool += co_od_pool_need(&defs[i]);
    }
    if (pool > UINT32_MAX) {
        return rt_argument_error(rt, "line %d: object dictionary too large", l->index);
    }
    l->od_entries = calloc(count ? count : 1, sizeof *l->od_entries);
    l->od_pool = calloc(pool ? (size_t)pool : 1, 1);
    if (!l->od_entries || !l->od_pool) {
        rt_set_error(rt, "line %d: no memory for %u OD entries", l->index, (unsigned)count);
        return CO_RT_ERR_NO_MEMORY;
    }
    co_od_init(&l->od, l->line.mode, l->od_entries, count, l->od_pool, (uint32_t)pool,
               l->od_subs, RT_OD_SUBSCRIPTIONS);
    for (uint32_t i = 0; i < count; i++) {
        co_od_add_result_t r = co_od_add(&l->od, &defs[i]);
        if (r != CO_OD_ADDED && r != CO_OD_SKIPPED_MODE) {
            return rt_argument_error(rt, "line %d: OD entry 0x%04X:%02X: %s", l->index,
                                  defs[i].index, defs[i].sub, od_add_problem(r));
        }
    }
    return CO_RT_OK;
}

void rt_od_release(rt_line_t *l)
{
    free(l->od_entries);
    free(l->od_pool);
    free(l->store_path);
    l->od_entries = NULL;
    l->od_pool = NULL;
    l->store_path = NULL;
}

int co_rt_od_define(co_rt_t *rt, int line, const co_od_def_t *defs, uint32_t count,
                    const char *store_path)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    if (!defs && count > 0) {
        return rt_argument_error(rt, "line %d: no OD entries given", line);
    }
    pthread_mutex_lock(&rt->lock);
    int status = CO_RT_OK;
    if (l->has_node || l->has_od) {
        rt_set_error(rt, "line %d: the object dictionary must be defined once, before the local "
                  "node", line);
        status = CO_RT_ERR_STATE;
    } else {
        status = od_fill(rt, l, defs, count);
        if (status == CO_RT_OK && store_path && store_path[0]) {
            l->store_path = strdup(store_path);
            status = l->store_path ? CO_RT_OK : CO_RT_ERR_NO_MEMORY;
        }
        if (status == CO_RT_OK) {
            l->has_od = true;
        } else {
            rt_od_release(l);
        }
    }
    pthread_mutex_unlock(&rt->lock);
    return status;
}

/* Under rt->lock: the line's served OD, or NULL with the reason set. */
static co_od_t *served_od(co_rt_t *rt, rt_line_t *l)
{
    if (!l->has_node || !l->has_od) {
        rt_set_error(rt, "line %d has no local node serving an object dictionary", l->index);
        return NULL;
    }
    return &l->od;
}

int co_rt_od_read(co_rt_t *rt, int line, uint16_t index, uint8_t sub, uint8_t *buf,
                  uint32_t capacity, uint32_t *length)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l || !buf || !length) {
        return CO_RT_ERR_ARGUMENT;
    }
    pthread_mutex_lock(&rt->lock);
    co_od_t *od = served_od(rt, l);
    int result = od ? (int)co_od_get(od, index, sub, buf, capacity, length) : CO_RT_ERR_STATE;
    pthread_mutex_unlock(&rt->lock);
    return result;
}

int co_rt_od_write(co_rt_t *rt, int line, uint16_t index, uint8_t sub, const uint8_t *data,
                   uint32_t length)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l || (!data && length > 0)) {
        return CO_RT_ERR_ARGUMENT;
    }
    pthread_mutex_lock(&rt->lock);
    co_od_t *od = served_od(rt, l);
    int result = CO_RT_ERR_STATE;
    if (od) {
        /* Services re-arm timers from the line's clock (0x1017 at once). */
        co_line_set_time(&l->line, co_rt_now_us());
        result = (int)co_od_put(od, index, sub, data, length);
    }
    pthread_mutex_unlock(&rt->lock);
    if (result == 0) {
        rt_wake(rt);   /* a deadline may have moved earlier */
    }
    return result;
}

/* Under rt->lock: the store of the line's node, or NULL with the reason set. */
static co_store_t *served_store(co_rt_t *rt, rt_line_t *l)
{
    if (!served_od(rt, l)) {
        return NULL;
    }
    if (!l->store_path) {
        rt_set_error(rt, "line %d: the local node has no parameter store (give a store file)",
                  l->index);
        return NULL;
    }
    return &l->store;
}

static int store_call(co_rt_t *rt, int line, int group_mask, bool save)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    if (group_mask <= 0 || group_mask > CO_GROUP_ALL) {
        return rt_argument_error(rt, "parameter group mask %d outside 1..%d", group_mask,
                              CO_GROUP_ALL);
    }
    pthread_mutex_lock(&rt->lock);
    co_store_t *store = served_store(rt, l);
    int result = CO_RT_ERR_STATE;
    if (store) {
        result = (int)(save ? co_store_save(store, (uint8_t)group_mask)
                            : co_store_restore_defaults(store, (uint8_t)group_mask));
    }
    pthread_mutex_unlock(&rt->lock);
    return result;
}

int co_rt_od_save(co_rt_t *rt, int line, int group_mask)
{
    return store_call(rt, line, group_mask, true);
}

int co_rt_od_restore_defaults(co_rt_t *rt, int line, int group_mask)
{
    return store_call(rt, line, group_mask, false);
}

int co_rt_store_status(co_rt_t *rt, int line)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    pthread_mutex_lock(&rt->lock);
    int result = served_store(rt, l) ? (int)l->node.store_status : CO_RT_ERR_STATE;
    pthread_mutex_unlock(&rt->lock);
    return result;
}
