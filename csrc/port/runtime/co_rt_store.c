/* Runtime: a parameter store kept by the application (Python) instead
 * of a file. The runtime thread never waits on the application: loads come
 * from a RAM copy of the application's image, and each new image is staged
 * until the application says it is on its medium; a network "save" is
 * answered only then (CiA 301: the answer follows the save). */

#include "co_rt_internal.h"

#include <stdlib.h>
#include <string.h>

/* ---------------------------------------------------------------- backend */

static co_store_status_t app_load(void *user, uint8_t *image, uint32_t capacity,
                                  uint32_t *length)
{
    const rt_app_store_t *a = &((const rt_line_t *)user)->app_store;
    if (a->status != CO_STORE_OK) {
        return a->status;
    }
    if (a->committed_length > capacity) {
        return CO_STORE_TOO_BIG;
    }
    if (a->committed_length > 0) {
        memcpy(image, a->committed, a->committed_length);
    }
    *length = a->committed_length;
    return CO_STORE_OK;
}

static co_store_status_t app_save(void *user, const uint8_t *image, uint32_t length)
{
    rt_app_store_t *a = &((rt_line_t *)user)->app_store;
    if (a->staged_pending || length > a->staged_capacity) {
        return CO_STORE_IO;   /* one save at a time: the last is not persisted yet */
    }
    memcpy(a->staged, image, length);
    a->staged_length = length;
    a->staged_pending = true;
    return CO_STORE_OK;
}

const co_store_backend_t rt_app_store_backend = {.save = app_save, .load = app_load};

/* The staged image is now the application's: loads use it from now on. */
static void commit(rt_app_store_t *a)
{
    uint8_t *old = a->committed;
    a->committed = a->staged;
    a->committed_length = a->staged_length;
    a->staged = old;
    a->status = CO_STORE_OK;
    a->staged_pending = false;
    a->staged_autonomous = false;
}

uint32_t rt_app_store_persisted(rt_line_t *l, uint32_t abort)
{
    rt_app_store_t *a = &l->app_store;
    if (!a->staged_pending) {
        return abort ? abort : CO_ABORT_GENERAL;
    }
    if (abort == 0) {
        commit(a);
        return 0;
    }
    a->staged_pending = false;
    if (a->staged_autonomous) {
        /* not on the medium: the values are still to be saved */
        a->staged_autonomous = false;
        co_store_changed(co_stack_store(&l->stack), 0xFF);
    }
    return abort;
}

void rt_app_store_autonomous(co_store_t *s, uint32_t abort, void *user)
{
    rt_line_t *l = user;
    (void)s;
    if (abort == 0 && l->app_store.enabled && l->app_store.staged_pending) {
        l->app_store.staged_autonomous = true;
        rt_post(l, CO_EV_STORE_PERSIST, co_stack_node(&l->stack)->nmt.node_id, 0, 0, NULL);
    }
}

/* ---------------------------------------------------------------- node attach */

int rt_app_store_open(co_rt_t *rt, rt_line_t *l, uint32_t *capacity_out)
{
    rt_app_store_t *a = &l->app_store;
    uint32_t need = co_store_image_need_grown(&l->od);   /* entries added live too */
    /* Committed and staged swap places, so both hold an image of either size. */
    uint32_t capacity = need > a->committed_length ? need : a->committed_length;
    uint8_t *committed = realloc(a->committed, capacity ? capacity : 1u);
    if (committed) {
        a->committed = committed;
    }
    a->staged = malloc(capacity ? capacity : 1u);
    if (!committed || !a->staged) {
        rt_set_error(rt, "line %d: no memory for the parameter store", l->index);
        return CO_RT_ERR_NO_MEMORY;
    }
    a->staged_capacity = capacity;
    *capacity_out = capacity ? capacity : 1u;
    return CO_RT_OK;
}

/* Runs after the store's own check-write, which staged the image. */
static uint32_t on_check_persist(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e,
                                 const uint8_t *value, uint32_t length, void *user)
{
    rt_line_t *l = user;
    (void)od;
    (void)value;
    (void)length;
    if (!l->app_store.staged_pending) {
        return 0;   /* nothing staged (e.g. restore-defaults with nothing saved) */
    }
    uint32_t r = rt_od_park(l, xfer, e->key, NULL, 0, CO_RT_INDICATE_STORE);
    if (r != CO_OD_SPLIT) {
        l->app_store.staged_pending = false;   /* nobody will persist it */
    }
    return r;
}

static const co_od_handler_t persist_handler = {.check_write = on_check_persist};

bool rt_app_store_hook(rt_line_t *l)
{
    uint8_t last = co_stack_store(&l->stack)->last_sub;   /* the store hooked 1..last */
    return (!co_od_has_index(&l->od, 0x1010) ||
            co_od_subscribe(&l->od, 0x1010, 1, 0x1010, last, &persist_handler, l)) &&
           (!co_od_has_index(&l->od, 0x1011) ||
            co_od_subscribe(&l->od, 0x1011, 1, 0x1011, last, &persist_handler, l));
}

void rt_app_store_free(rt_line_t *l)
{
    free(l->app_store.committed);
    free(l->app_store.staged);
    memset(&l->app_store, 0, sizeof l->app_store);
}

/* ---------------------------------------------------------------- API */

int co_rt_store_application(co_rt_t *rt, int line, const uint8_t *image, uint32_t length,
                            int status)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l || (!image && length > 0)) {
        return CO_RT_ERR_ARGUMENT;
    }
    if (status != CO_STORE_OK && status != CO_STORE_EMPTY && status != CO_STORE_IO) {
        return rt_argument_error(rt, "line %d: store load status %d (OK, EMPTY or IO)", line,
                                 status);
    }
    rt_mutex_lock(&rt->lock);
    int result = CO_RT_OK;
    if (!l->has_od || rt_has_node(l) || rt_has_store(l)) {
        rt_set_error(rt, "line %d: an application store comes once, after the object "
                     "dictionary (defined without a store file) and before the node", line);
        result = CO_RT_ERR_STATE;
    } else {
        rt_app_store_t *a = &l->app_store;
        a->committed = malloc(length ? length : 1u);
        if (!a->committed) {
            result = CO_RT_ERR_NO_MEMORY;
        } else {
            if (length > 0) {
                memcpy(a->committed, image, length);
            }
            a->committed_length = length;
            a->status = (co_store_status_t)status;
            a->enabled = true;
        }
    }
    rt_mutex_unlock(&rt->lock);
    return result;
}

/* Under rt->lock: the application store of the line, or NULL with the reason set. */
static rt_app_store_t *app_store_of(co_rt_t *rt, rt_line_t *l)
{
    if (!l->app_store.enabled) {
        rt_set_error(rt, "line %d has no application parameter store", l->index);
        return NULL;
    }
    return &l->app_store;
}

int co_rt_store_staged(co_rt_t *rt, int line, uint8_t *buf, uint32_t capacity,
                       uint32_t *length)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l || !length || (!buf && capacity > 0)) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    int result = CO_RT_ERR_STATE;
    rt_app_store_t *a = app_store_of(rt, l);
    if (a && !a->staged_pending) {
        rt_set_error(rt, "line %d: no parameter image waits to be persisted", line);
    } else if (a) {
        *length = a->staged_length;
        if (a->staged_length > capacity) {
            rt_set_error(rt, "line %d: image of %u bytes, buffer of %u", line,
                         (unsigned)a->staged_length, (unsigned)capacity);
            result = CO_RT_ERR_ARGUMENT;
        } else {
            memcpy(buf, a->staged, a->staged_length);
            result = CO_RT_OK;
        }
    }
    rt_mutex_unlock(&rt->lock);
    return result;
}

int co_rt_store_finish(co_rt_t *rt, int line, int ok)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    int result = CO_RT_ERR_STATE;
    rt_app_store_t *a = app_store_of(rt, l);
    if (a && !a->staged_pending) {
        rt_set_error(rt, "line %d: no parameter image waits to be persisted", line);
    } else if (a) {
        (void)rt_app_store_persisted(l, ok ? 0u : CO_ABORT_DATA_STORE);
        result = CO_RT_OK;
        rt_kick(rt);   /* a failed autonomous save re-armed its timer */
    }
    rt_mutex_unlock(&rt->lock);
    return result;
}

int co_rt_store_autonomous_pending(co_rt_t *rt, int line)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    int result = l->app_store.staged_pending && l->app_store.staged_autonomous ? 1 : 0;
    rt_mutex_unlock(&rt->lock);
    return result;
}

/* ---------------------------------------------------------------- groups */

int co_rt_store_groups(co_rt_t *rt, int line, const co_store_group_t *groups, uint32_t rows,
                       uint32_t min_interval_ms)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l || !groups || rows == 0 || rows > CO_STORE_MAX_GROUP_ROWS ||
        !co_store_groups_valid(groups, (uint8_t)rows)) {
        return rt_argument_error(rt, "line %d: parameter groups refused (1..%d blocks in "
                                 "0x1000..0xFFFF that do not overlap, sub-indices 2, 3, ... "
                                 "without gaps, one mode and reset type per group)", line,
                                 CO_STORE_MAX_GROUP_ROWS);
    }
    rt_mutex_lock(&rt->lock);
    int result = CO_RT_OK;
    if (!l->has_od || rt_has_node(l) || l->store_groups) {
        rt_set_error(rt, "line %d: parameter groups come once, after the object dictionary "
                     "and before the node", line);
        result = CO_RT_ERR_STATE;
    } else {
        l->store_groups = malloc(rows * sizeof *groups);
        if (!l->store_groups) {
            result = CO_RT_ERR_NO_MEMORY;
        } else {
            memcpy(l->store_groups, groups, rows * sizeof *groups);
            l->store_group_rows = (uint8_t)rows;
            l->store_min_interval_ms = min_interval_ms;
        }
    }
    rt_mutex_unlock(&rt->lock);
    return result;
}
