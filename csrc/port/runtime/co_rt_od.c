/* Runtime: the local node's object dictionary (definition, atomic
 * application access, store calls) and the Python indications on it. */

#include "co_rt_internal.h"

#include <stdlib.h>
#include <string.h>

static const char *od_add_problem(co_od_add_result_t r)
{
    switch (r) {
    case CO_OD_ERR_FULL: return "no room left";
    case CO_OD_ERR_DUPLICATE: return "defined twice";
    case CO_OD_ERR_TYPE: return "unknown type, flags, or size that does not fit the type";
    case CO_OD_ERR_DEFAULT: return "default longer than the entry or outside its limits";
    case CO_OD_ERR_LIMITS: return "minimum above maximum";
    case CO_OD_ERR_SEALED: return "dictionary already in use";
    case CO_OD_ERR_NOT_SEALED: return "the node does not run yet";
    case CO_OD_ERR_TOO_LARGE: return "larger than every entry the node started with "
                                     "(its SDO/USDO servers' buffers)";
    case CO_OD_ERR_COMMUNICATION: return "0x1000..0x1FFF are the services' objects, fixed "
                                         "while the node runs";
    case CO_OD_ERR_STRUCTURE: return "a sub-index above 0 needs an ARRAY/RECORD with an "
                                     "UNSIGNED8 sub-index 0 (add sub-index 0 first)";
    default: return "refused";
    }
}

/* Under rt->lock: allocate and fill the OD (setup time, before the node). */
static int od_fill(co_rt_t *rt, rt_line_t *l, const co_od_def_t *defs, uint32_t count)
{
    uint64_t pool = l->od_spare_bytes;   /* the room for co_rt_od_add */
    for (uint32_t i = 0; i < count; i++) {
        pool += co_od_pool_need(&defs[i]);
    }
    uint64_t slots = (uint64_t)count + l->od_spare_entries;
    if (pool > UINT32_MAX || slots > UINT32_MAX) {
        return rt_argument_error(rt, "line %d: object dictionary too large", l->index);
    }
    l->od_entries = calloc(slots ? (size_t)slots : 1, sizeof *l->od_entries);
    l->od_pool = calloc(pool ? (size_t)pool : 1, 1);
    if (!l->od_entries || !l->od_pool) {
        rt_set_error(rt, "line %d: no memory for %u OD entries", l->index, (unsigned)count);
        return CO_RT_ERR_NO_MEMORY;
    }
    co_od_init(&l->od, co_line_mode(&l->line), l->od_entries, (uint32_t)slots, l->od_pool,
               (uint32_t)pool, l->od_subs, RT_OD_SUBSCRIPTIONS);
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
    free(l->store_groups);
    l->od_entries = NULL;
    l->od_pool = NULL;
    l->store_path = NULL;
    l->store_groups = NULL;
    l->store_group_rows = 0;
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
    rt_mutex_lock(&rt->lock);
    int status = CO_RT_OK;
    if (rt_has_node(l) || l->has_od) {
        rt_set_error(rt, "line %d: the object dictionary must be defined once, before the local "
                  "node", line);
        status = CO_RT_ERR_STATE;
    } else {
        status = od_fill(rt, l, defs, count);
        if (status == CO_RT_OK && store_path && store_path[0]) {
            l->store_path = rt_os_strdup(store_path);
            status = l->store_path ? CO_RT_OK : CO_RT_ERR_NO_MEMORY;
        }
        if (status == CO_RT_OK) {
            l->has_od = true;
        } else {
            rt_od_release(l);
        }
    }
    rt_mutex_unlock(&rt->lock);
    return status;
}

int co_rt_od_reserve(co_rt_t *rt, int line, uint32_t spare_entries, uint32_t spare_bytes)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    int status = CO_RT_OK;
    if (l->has_od) {
        rt_set_error(rt, "line %d: room for growth is reserved before the object dictionary "
                  "is defined", line);
        status = CO_RT_ERR_STATE;
    } else {
        l->od_spare_entries = spare_entries;
        l->od_spare_bytes = spare_bytes;
    }
    rt_mutex_unlock(&rt->lock);
    return status;
}

/* The first of defs at the running redundancy service's record index when the
 * OD does not hold that record yet (count: none). */
static uint32_t redundancy_record_in(rt_line_t *l, const co_od_def_t *defs, uint32_t count)
{
    uint16_t index = co_stack_redundancy_record_index(&l->stack);
    if (index == 0 || co_od_has_index(&l->od, index)) {
        return count;   /* not running, or bound (a second add is a duplicate) */
    }
    for (uint32_t i = 0; i < count; i++) {
        if (defs[i].index == index) {
            return i;
        }
    }
    return count;
}

int co_rt_od_add(co_rt_t *rt, int line, const co_od_def_t *defs, uint32_t count)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    if (!defs || count == 0) {
        return rt_argument_error(rt, "line %d: no OD entries given", line);
    }
    rt_mutex_lock(&rt->lock);
    int status = CO_RT_OK;
    uint32_t refused = 0;
    co_od_add_result_t r;
    if (!l->has_od || !rt_has_node(l)) {
        rt_set_error(rt, "line %d: entries are added at run time to a local node's object "
                  "dictionary once the node exists", line);
        status = CO_RT_ERR_STATE;
    } else if ((refused = redundancy_record_in(l, defs, count)) < count) {
        status = rt_argument_error(rt, "line %d: OD entry 0x%04X:%02X: the redundancy record, "
                                   "read when the redundancy service started; add it before "
                                   "starting the service", line, defs[refused].index,
                                   defs[refused].sub);
    } else if ((r = co_od_add_live_all(&l->od, defs, count, &refused)) != CO_OD_ADDED) {
        status = rt_argument_error(rt, "line %d: OD entry 0x%04X:%02X: %s", line,
                                   defs[refused].index, defs[refused].sub, od_add_problem(r));
    }
    rt_mutex_unlock(&rt->lock);
    return status;
}

/* ================================================================ memory domains */

static rt_domain_t *domain_of(rt_line_t *l, uint16_t index, uint8_t sub)
{
    uint32_t key = (uint32_t)index << 8 | sub;
    for (uint8_t i = 0; i < l->domain_count; i++) {
        if (l->domains[i].key == key) {
            return &l->domains[i];
        }
    }
    return NULL;
}

static int domain_get(const rt_domain_t *d, uint8_t *buf, uint32_t capacity, uint32_t *length)
{
    *length = d->size;
    if (capacity < d->size) {
        return (int)CO_ABORT_OUT_OF_MEMORY;
    }
    if (d->size > 0) {
        memcpy(buf, d->data, d->size);
    }
    return 0;
}

static int domain_put(rt_domain_t *d, const uint8_t *data, uint32_t length)
{
    if (length > d->capacity) {
        return (int)CO_ABORT_LENGTH_HIGH;
    }
    if (length > 0) {
        memcpy(d->data, data, length);
    }
    d->size = length;
    return 0;
}

static uint32_t on_domain_size(co_od_t *od, const co_od_entry_t *e, uint32_t *size, void *user)
{
    (void)od;
    (void)e;
    *size = ((const rt_domain_t *)user)->size;
    return 0;
}

static uint32_t on_domain_read(co_od_t *od, const co_od_entry_t *e, uint32_t offset,
                               uint8_t *buf, uint32_t cap, uint32_t *n, bool *last, void *user)
{
    const rt_domain_t *d = user;
    (void)od;
    (void)e;
    uint32_t left = offset < d->size ? d->size - offset : 0;
    *n = left < cap ? left : cap;
    if (*n > 0) {
        memcpy(buf, d->data + offset, *n);
    }
    *last = offset + *n >= d->size;
    return 0;
}

/* Downloads land in place and the domain reads empty until the last chunk
 * is in; an abort (or a gap) leaves it empty: never a mix of old and new. */
static uint32_t on_domain_write(co_od_t *od, const co_od_entry_t *e, uint32_t offset,
                                const uint8_t *data, uint32_t n, uint32_t total, bool last,
                                uint32_t abort, void *user)
{
    rt_domain_t *d = user;
    (void)od;
    (void)e;
    if (offset == 0) {
        d->filled = 0;
    }
    d->size = 0;
    if (abort != 0) {
        return 0;
    }
    if ((total != CO_OD_SIZE_UNKNOWN && total > d->capacity) || n > d->capacity ||
        offset > d->capacity - n) {
        return CO_ABORT_LENGTH_HIGH;
    }
    if (offset != d->filled) {
        return CO_ABORT_GENERAL;   /* chunks arrive in order: a gap is a bug upstream */
    }
    if (n > 0) {
        memcpy(d->data + offset, data, n);
    }
    d->filled = offset + n;
    if (last) {
        d->size = d->filled;
    }
    return 0;
}

/* An announced size beyond the capacity is refused at the initiate. */
static uint32_t on_domain_begin(co_od_t *od, const co_od_entry_t *e, uint32_t total, void *user)
{
    const rt_domain_t *d = user;
    (void)od;
    (void)e;
    return total != CO_OD_SIZE_UNKNOWN && total > d->capacity ? CO_ABORT_LENGTH_HIGH : 0;
}

static const co_od_handler_t domain_handler = {.domain_size = on_domain_size,
                                               .domain_begin = on_domain_begin,
                                               .domain_read = on_domain_read,
                                               .domain_write = on_domain_write};

void rt_od_free_domains(rt_line_t *l)
{
    for (uint8_t i = 0; i < l->domain_count; i++) {
        free(l->domains[i].data);
    }
    memset(l->domains, 0, sizeof l->domains);
    l->domain_count = 0;
}

int co_rt_od_domain(co_rt_t *rt, int line, uint16_t index, uint8_t sub, uint32_t capacity)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    int status = CO_RT_OK;
    const co_od_entry_t *e = l->has_od ? co_od_find(&l->od, index, sub) : NULL;
    if (!l->has_od) {
        rt_set_error(rt, "line %d: define the object dictionary before its domains", line);
        status = CO_RT_ERR_STATE;
    } else if (!e || e->type != CO_TYPE_DOMAIN) {
        status = rt_argument_error(rt, "line %d: 0x%04X:%02X is %s", line, index, sub,
                                   e ? "not a DOMAIN" : "not in the object dictionary");
    } else if (domain_of(l, index, sub)) {
        status = rt_argument_error(rt, "line %d: 0x%04X:%02X already has memory", line, index,
                                   sub);
    } else if (l->domain_count == RT_DOMAINS) {
        rt_set_error(rt, "line %d: no room for more than %d memory domains", line, RT_DOMAINS);
        status = CO_RT_ERR_FULL;
    } else {
        rt_domain_t *d = &l->domains[l->domain_count];
        d->data = malloc(capacity ? capacity : 1u);
        if (!d->data) {
            rt_set_error(rt, "line %d: no memory for a %u-byte domain", line,
                         (unsigned)capacity);
            status = CO_RT_ERR_NO_MEMORY;
        } else if (!co_od_subscribe(&l->od, index, sub, index, sub, &domain_handler, d)) {
            free(d->data);
            d->data = NULL;
            rt_set_error(rt, "line %d: object dictionary handler table full", line);
            status = CO_RT_ERR_FULL;
        } else {
            d->line = l;
            d->key = (uint32_t)index << 8 | sub;
            d->capacity = capacity;
            d->size = 0;
            l->domain_count++;
        }
    }
    rt_mutex_unlock(&rt->lock);
    return status;
}

/* Under rt->lock: the line's served OD, or NULL with the reason set. */
static co_od_t *served_od(co_rt_t *rt, rt_line_t *l)
{
    if (!rt_has_node(l) || !l->has_od) {
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
    rt_mutex_lock(&rt->lock);
    co_od_t *od = served_od(rt, l);
    rt_domain_t *d = od ? domain_of(l, index, sub) : NULL;
    int result = CO_RT_ERR_STATE;
    if (d) {
        result = domain_get(d, buf, capacity, length);
    } else if (od) {
        result = (int)co_od_get(od, index, sub, buf, capacity, length);
    }
    rt_mutex_unlock(&rt->lock);
    return result;
}

/* The entries the EMCY producer keeps (error register, history, FD active
 * list and count): an application write would be replaced at once. */
static bool kept_by_emcy(uint16_t index, uint8_t sub)
{
    return index == 0x1001 || (index == 0x1003 && sub != 0) || index == 0x1032 ||
           (index == 0x1031 && sub == 1);
}

int co_rt_od_write(co_rt_t *rt, int line, uint16_t index, uint8_t sub, const uint8_t *data,
                   uint32_t length)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l || (!data && length > 0)) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    co_od_t *od = served_od(rt, l);
    int result = CO_RT_ERR_STATE;
    if (od) {
        /* Services re-arm timers from the line's clock (0x1017 at once). */
        co_line_set_time(&l->line, co_rt_now_us());
        rt_domain_t *d = domain_of(l, index, sub);
        const co_od_entry_t *e = co_od_find(od, index, sub);
        if (e && (co_stack_emcy(&l->stack) != NULL) && kept_by_emcy(index, sub)) {
            /* a wrong value is told as such first, as for any entry */
            result = (int)co_od_check_value(od, e, data, length);
            if (result == 0) {
                rt_set_error(rt, "line %d: 0x%04X:%02X is kept by the EMCY producer from "
                             "the active errors: raise or clear an error instead", line,
                             index, sub);
                result = (int)CO_ABORT_READ_ONLY;
            }
        } else {
            result = d ? domain_put(d, data, length)
                       : (int)co_od_put(od, index, sub, data, length);
        }
    }
    if (result == 0) {
        rt_kick(rt);   /* a frame may wait (a TPDO), a deadline may have moved earlier */
    }
    rt_mutex_unlock(&rt->lock);
    return result;
}

/* Under rt->lock: the store of the line's node, or NULL with the reason set. */
static co_store_t *served_store(co_rt_t *rt, rt_line_t *l)
{
    if (!served_od(rt, l)) {
        return NULL;
    }
    if (!rt_has_store(l)) {
        rt_set_error(rt, "line %d: the local node has no parameter store (give a store file)",
                  l->index);
        return NULL;
    }
    return co_stack_store(&l->stack);
}

static int store_call(co_rt_t *rt, int line, int group_mask, bool save)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    if (group_mask <= 0 || group_mask > 0xFF) {
        return rt_argument_error(rt, "parameter group mask %d outside 1..255", group_mask);
    }
    rt_mutex_lock(&rt->lock);
    co_store_t *store = served_store(rt, l);
    int result = CO_RT_ERR_STATE;
    if (store) {
        result = (int)(save ? co_store_save(store, (uint8_t)group_mask)
                            : co_store_restore_defaults(store, (uint8_t)group_mask));
    }
    rt_mutex_unlock(&rt->lock);
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
    rt_mutex_lock(&rt->lock);
    int result = served_store(rt, l) ? (int)co_stack_node(&l->stack)->store_status : CO_RT_ERR_STATE;
    rt_mutex_unlock(&rt->lock);
    return result;
}

/* ================================================================ Python indications
 * A network access to a range the application watches is parked with
 * CO_OD_SPLIT (the runtime thread never calls Python), posted as
 * CO_EV_OD_REQUEST and resumed by co_rt_od_answer from any thread. */

enum { TOKEN_SLOT_BITS = 8, TOKEN_KIND_SHIFT = 24 };

static uint32_t token_of(const rt_line_t *l, uint32_t slot, uint8_t kind)
{
    return (uint32_t)kind << TOKEN_KIND_SHIFT |
           (uint32_t)l->requests[slot].generation << TOKEN_SLOT_BITS | slot;
}

/* Runtime thread, under rt->lock: park the access and tell Python. */
uint32_t rt_od_park(rt_line_t *l, co_od_xfer_t *xfer, uint32_t key, const uint8_t *value,
                    uint32_t length, uint8_t kind)
{
    for (uint32_t i = 0; i < RT_REQUESTS; i++) {
        rt_request_t *r = &l->requests[i];
        if (r->xfer) {
            continue;
        }
        r->xfer = xfer;
        r->value = value;
        r->length = length;
        r->generation = (uint16_t)(r->generation + 1u);
        if (!rt_post(l, CO_EV_OD_REQUEST, co_stack_node(&l->stack)->nmt.node_id, key, token_of(l, i, kind),
                     NULL)) {
            r->xfer = NULL;   /* nobody would ever answer it */
            return CO_ABORT_NO_RESOURCE;
        }
        return CO_OD_SPLIT;
    }
    return CO_ABORT_NO_RESOURCE;   /* more accesses wait than the table holds */
}

static uint32_t park(rt_indication_t *ind, co_od_xfer_t *xfer, const co_od_entry_t *e,
                     const uint8_t *value, uint32_t length, uint8_t kind)
{
    return (ind->kinds & kind) ? rt_od_park(ind->line, xfer, e->key, value, length, kind) : 0;
}

static uint32_t on_before_read(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e,
                               void *user)
{
    (void)od;
    return park(user, xfer, e, NULL, 0, CO_RT_INDICATE_READ);
}

static uint32_t on_check_write(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e,
                               const uint8_t *value, uint32_t length, void *user)
{
    (void)od;
    return park(user, xfer, e, value, length, CO_RT_INDICATE_WRITE);
}

static const co_od_handler_t indication_handler = {.before_read = on_before_read,
                                                   .check_write = on_check_write};

void rt_od_drop_requests(rt_line_t *l)
{
    for (uint32_t i = 0; i < RT_REQUESTS; i++) {
        l->requests[i].xfer = NULL;
    }
}

int co_rt_od_indicate(co_rt_t *rt, int line, uint16_t first_index, uint8_t first_sub,
                      uint16_t last_index, uint8_t last_sub, int kinds)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    if (kinds <= 0 || kinds > (CO_RT_INDICATE_READ | CO_RT_INDICATE_WRITE)) {
        return rt_argument_error(rt, "line %d: indication kinds %d (1 read, 2 write, 3 both)",
                                 line, kinds);
    }
    if (((uint32_t)first_index << 8 | first_sub) > ((uint32_t)last_index << 8 | last_sub)) {
        return rt_argument_error(rt, "line %d: indication range 0x%04X:%02X..0x%04X:%02X is "
                                 "empty", line, first_index, first_sub, last_index, last_sub);
    }
    rt_mutex_lock(&rt->lock);
    int status = CO_RT_OK;
    if (!l->has_od) {
        rt_set_error(rt, "line %d: define the object dictionary before its indications", line);
        status = CO_RT_ERR_STATE;
    } else if (l->indication_count == RT_INDICATIONS) {
        rt_set_error(rt, "line %d: no room for more than %d indication ranges", line,
                     RT_INDICATIONS);
        status = CO_RT_ERR_FULL;
    } else {
        rt_indication_t *ind = &l->indications[l->indication_count];
        ind->line = l;
        ind->kinds = (uint8_t)kinds;
        if (co_od_subscribe(&l->od, first_index, first_sub, last_index, last_sub,
                            &indication_handler, ind)) {
            l->indication_count++;
        } else {
            rt_set_error(rt, "line %d: object dictionary handler table full", line);
            status = CO_RT_ERR_FULL;
        }
    }
    rt_mutex_unlock(&rt->lock);
    return status;
}

/* Under rt->lock: the waiting request of token, or NULL with the reason set. */
static rt_request_t *waiting_request(co_rt_t *rt, rt_line_t *l, uint32_t token)
{
    uint32_t slot = token & ((1u << TOKEN_SLOT_BITS) - 1u);
    rt_request_t *r = slot < RT_REQUESTS ? &l->requests[slot] : NULL;
    if (!r || !r->xfer || token != token_of(l, slot, (uint8_t)(token >> TOKEN_KIND_SHIFT))) {
        rt_set_error(rt, "line %d: no access waits on token 0x%08X (answered already?)",
                     l->index, (unsigned)token);
        return NULL;
    }
    return r;
}

int co_rt_od_request_value(co_rt_t *rt, int line, uint32_t token, uint8_t *buf,
                           uint32_t capacity, uint32_t *length)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l || !length || (!buf && capacity > 0)) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    int status = CO_RT_ERR_STATE;
    rt_request_t *r = waiting_request(rt, l, token);
    if (r) {
        *length = r->length;
        if (r->length > capacity) {
            rt_set_error(rt, "line %d: value of %u bytes, buffer of %u", line,
                         (unsigned)r->length, (unsigned)capacity);
            status = CO_RT_ERR_ARGUMENT;
        } else {
            if (r->length > 0) {
                memcpy(buf, r->value, r->length);
            }
            status = CO_RT_OK;
        }
    }
    rt_mutex_unlock(&rt->lock);
    return status;
}

int co_rt_od_answer(co_rt_t *rt, int line, uint32_t token, uint32_t abort)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    if (abort == CO_OD_SPLIT) {
        return rt_argument_error(rt, "line %d: 0x%08X is not an abort code", line,
                                 (unsigned)abort);
    }
    rt_mutex_lock(&rt->lock);
    int status = CO_RT_ERR_STATE;
    rt_request_t *r = waiting_request(rt, l, token);
    if (r) {
        co_od_xfer_t *xfer = r->xfer;
        r->xfer = NULL;   /* free before resuming: the rest of the chain may park again */
        if (token >> TOKEN_KIND_SHIFT == CO_RT_INDICATE_STORE) {
            abort = rt_app_store_persisted(l, abort);
        }
        co_line_set_time(&l->line, co_rt_now_us());
        /* whichever server parked it (the other does not know the xfer) */
        if (!((co_stack_usdo_server(&l->stack) != NULL) && co_usdo_server_resume(co_stack_usdo_server(&l->stack), xfer, abort)) && (co_stack_sdo_server(&l->stack) != NULL)) {
            co_sdo_server_resume(co_stack_sdo_server(&l->stack), xfer, abort);
        }
        status = CO_RT_OK;
    }
    rt_mutex_unlock(&rt->lock);
    rt_wake(rt);   /* the answer frame waits in the tx queue */
    return status;
}
