/* Runtime: the configuration manager (co_config.h) of a line, on the line's
 * client (USDO on fd lines, SDO on classic lines). The application starts a
 * configuration from any thread; it runs in the runtime thread, each entry's
 * outcome is kept, CO_EV_CONFIG tells the end, the application collects the
 * result and releases the handle. */

#include "co_rt_internal.h"

#include <stdlib.h>
#include <string.h>

#include "canopenfd/co_config.h"

enum {
    RT_CONFIGS = 16,                   /* configurations per line: running + unreleased */
    HANDLE_SLOT_BITS = 8
};

typedef struct rt_config_slot {
    co_config_t cfg;
    struct rt_config *owner;
    uint16_t generation;
    bool used;                         /* a handle exists */
    bool running;
    uint8_t *dcf;                      /* the caller's DCF, copied */
    co_rt_config_entry_t *entries;     /* each entry's outcome, in order */
    uint32_t entry_count;
    uint32_t entry_capacity;
    co_config_result_t result;
} rt_config_slot_t;

typedef struct rt_config {
    rt_line_t *line;
    bool closing;                      /* the line goes: nothing is posted */
    rt_config_slot_t slots[RT_CONFIGS];
} rt_config_t;

static int handle_of(const rt_config_slot_t *s)
{
    uint32_t slot = (uint32_t)(s - s->owner->slots);
    return (int)((uint32_t)s->generation << HANDLE_SLOT_BITS | slot);
}

static void slot_clear(rt_config_slot_t *s)
{
    rt_config_t *owner = s->owner;
    uint16_t generation = s->generation;
    free(s->dcf);
    free(s->entries);
    memset(s, 0, sizeof *s);
    s->owner = owner;
    s->generation = generation;
}

static void on_entry(co_config_t *cfg, uint16_t index, uint8_t sub, uint32_t abort, void *user)
{
    rt_config_slot_t *s = user;
    (void)cfg;
    if (s->entry_count < s->entry_capacity) {
        s->entries[s->entry_count++] = (co_rt_config_entry_t){index, sub, abort};
    }
}

static void on_done(co_config_t *cfg, const co_config_result_t *result, void *user)
{
    rt_config_slot_t *s = user;
    (void)cfg;
    s->result = *result;
    s->running = false;
    if (!s->owner->closing) {
        rt_post(s->owner->line, CO_EV_CONFIG, result->node, (uint32_t)handle_of(s),
                result->outcome, NULL);
    }
}

/* Under rt->lock: the line's configurations, created at the first use. */
static rt_config_t *configs_of(co_rt_t *rt, rt_line_t *l)
{
    if (l->config == NULL) {
        rt_config_t *c = calloc(1, sizeof *c);
        if (c == NULL) {
            rt_set_error(rt, "line %d: no memory for configurations", l->index);
            return NULL;
        }
        c->line = l;
        for (uint32_t i = 0; i < RT_CONFIGS; i++) {
            c->slots[i].owner = c;
        }
        l->config = c;
    }
    return l->config;
}

/* Under rt->lock: the slot of a handle, or NULL with the reason set. */
static rt_config_slot_t *slot_of(co_rt_t *rt, rt_line_t *l, int handle)
{
    rt_config_t *c = l->config;
    uint32_t slot = (uint32_t)handle & ((1u << HANDLE_SLOT_BITS) - 1u);
    rt_config_slot_t *s = (c && handle >= 0 && slot < RT_CONFIGS) ? &c->slots[slot] : NULL;
    if (!s || !s->used || handle_of(s) != handle) {
        rt_set_error(rt, "line %d: no configuration has handle %d (released already?)",
                     l->index, handle);
        return NULL;
    }
    return s;
}

void rt_config_free(rt_line_t *l)
{
    rt_config_t *c = l->config;
    if (c == NULL) {
        return;
    }
    c->closing = true;
    for (uint32_t i = 0; i < RT_CONFIGS; i++) {
        if (c->slots[i].running) {
            (void)co_config_cancel(&c->slots[i].cfg);
        }
        slot_clear(&c->slots[i]);
    }
    free(c);
    l->config = NULL;
}

static int check_request(co_rt_t *rt, const rt_line_t *l, const co_rt_config_request_t *q,
                         uint32_t *count)
{
    uint32_t offset = 0;
    co_concise_status_t status;
    if (q->node < 1 || q->node > 127) {
        return rt_argument_error(rt, "line %d: configuration of node %d: node-ids are 1..127",
                                 l->index, q->node);
    }
    if (q->dcf == NULL && q->dcf_length > 0) {
        return rt_argument_error(rt, "line %d: configuration of node %d without its DCF",
                                 l->index, q->node);
    }
    status = co_concise_validate(q->dcf, q->dcf_length, count, &offset);
    if (status != CO_CONCISE_OK) {
        return rt_argument_error(rt, "line %d: concise DCF for node %d, byte %u: %s", l->index,
                                 q->node, (unsigned)offset, co_concise_status_text(status));
    }
    if (*count == 0 && !q->check_stamp) {
        return rt_argument_error(rt, "line %d: concise DCF for node %d has no entry and no "
                                 "stamp was given: nothing to do", l->index, q->node);
    }
    return CO_RT_OK;
}

int co_rt_config_start(co_rt_t *rt, int line, const co_rt_config_request_t *request)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    uint32_t count = 0;
    if (!l || !request) {
        return CO_RT_ERR_ARGUMENT;
    }
    int status = check_request(rt, l, request, &count);
    if (status != CO_RT_OK) {
        return status;
    }
    rt_mutex_lock(&rt->lock);
    co_usdo_client_t *usdo = NULL;
    co_sdo_client_t *sdo = NULL;
    rt_config_t *c = NULL;
    rt_config_slot_t *s = NULL;
    if (rt->stopping) {
        rt_set_error(rt, "runtime stopped");
        rt_mutex_unlock(&rt->lock);
        return CO_RT_ERR_CLOSED;
    }
    if (!rt_client_cores(rt, l, &usdo, &sdo) || (c = configs_of(rt, l)) == NULL) {
        rt_mutex_unlock(&rt->lock);
        return CO_RT_ERR_STATE;
    }
    for (uint32_t i = 0; i < RT_CONFIGS && !s; i++) {
        if (!c->slots[i].used) {
            s = &c->slots[i];
        }
    }
    if (!s) {
        rt_set_error(rt, "line %d: %d configurations are unreleased: release finished ones",
                     line, RT_CONFIGS);
        rt_mutex_unlock(&rt->lock);
        return CO_RT_ERR_FULL;
    }
    slot_clear(s);
    s->generation = (uint16_t)((s->generation + 1u) & 0x7FFFu);   /* handle stays positive */
    s->dcf = malloc(request->dcf_length > 0 ? request->dcf_length : 1u);
    s->entry_capacity = count + 2u;   /* the entries and the two stamps */
    s->entries = calloc(s->entry_capacity, sizeof *s->entries);
    if (!s->dcf || !s->entries) {
        slot_clear(s);
        rt_set_error(rt, "line %d: no memory for a DCF of %u bytes", line,
                     (unsigned)request->dcf_length);
        rt_mutex_unlock(&rt->lock);
        return CO_RT_ERR_NO_MEMORY;
    }
    if (request->dcf_length > 0) {
        memcpy(s->dcf, request->dcf, request->dcf_length);
    }
    if (usdo) {
        co_config_init_usdo(&s->cfg, usdo);
    } else {
        co_config_init_sdo(&s->cfg, sdo);
    }
    co_config_request_t q = {.node = (uint8_t)request->node, .dcf = s->dcf,
                             .dcf_length = request->dcf_length,
                             .check_stamp = request->check_stamp != 0,
                             .date = request->date, .time = request->time,
                             .continue_on_error = request->continue_on_error != 0,
                             .timeout_ms = request->timeout_ms,
                             .entry = on_entry, .done = on_done, .user = s};
    co_line_set_time(&l->line, co_rt_now_us());
    s->used = true;
    s->running = true;
    co_config_start_status_t started = co_config_start(&s->cfg, &q);
    if (started == CO_CONFIG_START_OK) {
        status = handle_of(s);
        rt_kick(rt);   /* the first request waits in the tx queue */
    } else {
        rt_set_error(rt, "line %d: configuration of node %d refused: %s (0x%08X)", line,
                     request->node, started == CO_CONFIG_START_REFUSED
                         ? "the client is busy (every channel / session in use?)"
                         : "bad request", (unsigned)s->cfg.result.abort);
        status = started == CO_CONFIG_START_REFUSED ? CO_RT_ERR_FULL : CO_RT_ERR_ARGUMENT;
        slot_clear(s);
    }
    rt_mutex_unlock(&rt->lock);
    return status;
}

int co_rt_config_result(co_rt_t *rt, int line, int handle, co_rt_config_result_t *out)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l || !out) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    int status = CO_RT_ERR_STATE;
    rt_config_slot_t *s = slot_of(rt, l, handle);
    if (s) {
        const co_config_result_t *r = &s->result;
        *out = (co_rt_config_result_t){.running = s->running, .outcome = r->outcome,
                                       .written = r->written, .failed = r->failed,
                                       .index = r->index, .sub = r->sub,
                                       .from_node = r->from_node, .abort = r->abort,
                                       .entry = r->entry, .reported = s->entry_count};
        status = CO_RT_OK;
    }
    rt_mutex_unlock(&rt->lock);
    return status;
}

int co_rt_config_entries(co_rt_t *rt, int line, int handle, co_rt_config_entry_t *out, int max)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l || (!out && max > 0) || max < 0) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    int status = CO_RT_ERR_STATE;
    rt_config_slot_t *s = slot_of(rt, l, handle);
    if (s) {
        uint32_t n = s->entry_count < (uint32_t)max ? s->entry_count : (uint32_t)max;
        if (n > 0) {
            memcpy(out, s->entries, n * sizeof *out);
        }
        status = (int)n;
    }
    rt_mutex_unlock(&rt->lock);
    return status;
}

/* Cancel (release: and free) the configuration `handle` of a line: one
 * prologue for both. A released slot's cancel posts no event. */
static int cancel_or_release(co_rt_t *rt, int line, int handle, bool release)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    int status = CO_RT_ERR_STATE;
    rt_config_slot_t *s = slot_of(rt, l, handle);
    if (s) {
        if (s->running) {
            co_line_set_time(&l->line, co_rt_now_us());
            s->owner->closing = release;   /* released: nobody waits for its event */
            (void)co_config_cancel(&s->cfg);
            s->owner->closing = false;
        }
        if (release) {
            slot_clear(s);
        }
        status = CO_RT_OK;
    }
    return rt_kick_unlock(rt, status);
}

int co_rt_config_cancel(co_rt_t *rt, int line, int handle)
{
    return cancel_or_release(rt, line, handle, false);
}

int co_rt_config_release(co_rt_t *rt, int line, int handle)
{
    return cancel_or_release(rt, line, handle, true);
}
