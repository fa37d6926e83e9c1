/* Linux runtime: the USDO client of an fd line. Transfers run in the
 * runtime thread; the application (Python) starts them from any thread,
 * hears CO_EV_USDO_DONE, collects the result and releases the handle.
 * Data moves between the core client and memory or a file here, never
 * frame by frame through Python. */
#define _GNU_SOURCE

#include "co_rt_internal.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

enum {
    RT_USDO_SESSIONS_MAX = 64,         /* transfers in flight per line */
    RT_USDO_REQUESTS = 128,            /* handles: running + finished, not yet released */
    RT_USDO_DEFAULT_MAX = 64u << 20,   /* upload to memory: 64 MiB unless told */
    RT_USDO_FIRST_CHUNK = 4096,        /* upload of unknown size: first allocation */
    RT_USDO_PROGRESS_US = 50000,
    HANDLE_SLOT_BITS = 8
};

typedef struct rt_usdo_req {
    co_usdo_request_t req;             /* first: the core hands back &req */
    rt_line_t *line;
    uint16_t generation;
    bool used;                         /* a handle exists */
    bool running;
    bool progress;
    uint64_t progress_at;              /* next progress event not before */
    /* download from memory (the caller's buffer) or a file */
    const uint8_t *src;
    int fd;
    uint64_t fd_offset;
    int error_number;
    /* upload to memory */
    uint8_t *buf;
    uint32_t held;
    uint32_t capacity;
    uint32_t max_size;
    /* broadcast */
    co_rt_usdo_answer_t *answers;
    uint32_t answer_count;
} rt_usdo_req_t;

typedef struct rt_usdo {
    co_usdo_client_t client;
    bool closing;                      /* freeing: done() posts nothing */
    co_usdo_client_session_t sessions[RT_USDO_SESSIONS_MAX];
    rt_usdo_req_t reqs[RT_USDO_REQUESTS];
} rt_usdo_t;

static int handle_of(const rt_usdo_t *u, const rt_usdo_req_t *r)
{
    uint32_t slot = (uint32_t)(r - u->reqs);
    return (int)((uint32_t)r->generation << HANDLE_SLOT_BITS | slot);
}

/* ---------------------------------------------------------------- data paths */

static void maybe_progress(rt_usdo_req_t *r, uint32_t moved)
{
    if (!r->progress) {
        return;
    }
    uint64_t now = co_rt_now_us();
    if (now >= r->progress_at) {
        r->progress_at = now + RT_USDO_PROGRESS_US;
        rt_usdo_t *u = r->line->usdo_client;
        rt_post(r->line, CO_EV_USDO_PROGRESS, r->req.server, (uint32_t)handle_of(u, r), moved,
                NULL);
    }
}

static uint32_t memory_source(void *ctx, uint32_t offset, uint8_t *buf, uint32_t want)
{
    rt_usdo_req_t *r = ctx;
    memcpy(buf, r->src + offset, want);
    maybe_progress(r, offset + want);
    return want;
}

static uint32_t file_source(void *ctx, uint32_t offset, uint8_t *buf, uint32_t want)
{
    rt_usdo_req_t *r = ctx;
    uint32_t got = 0;
    while (got < want) {
        ssize_t n = pread(r->fd, buf + got, want - got, (off_t)(r->fd_offset + offset + got));
        if (n < 0 && errno == EINTR) {
            continue;
        }
        if (n <= 0) {
            r->error_number = n < 0 ? errno : EIO;   /* a file shorter than announced */
            return got;                              /* the client aborts 0x10 */
        }
        got += (uint32_t)n;
    }
    maybe_progress(r, offset + want);
    return want;
}

/* Memory sink: the announced size is allocated at once; an unknown size
 * grows by doubling; anything beyond max_size is refused (0x16). */
static uint8_t memory_sink(void *ctx, uint32_t offset, const uint8_t *data, uint32_t len,
                           uint32_t total)
{
    rt_usdo_req_t *r = ctx;
    uint64_t need = (uint64_t)offset + len;
    if (len == 0 && total != 0xFFFFFFFFu) {
        need = total;
    }
    if (need > r->max_size) {
        return CO_USDO_ABORT_OUT_OF_MEMORY;
    }
    if (need > r->capacity) {
        uint64_t cap = r->capacity ? r->capacity : RT_USDO_FIRST_CHUNK;
        while (cap < need) {
            cap *= 2u;
        }
        if (cap > r->max_size) {
            cap = r->max_size;
        }
        uint8_t *grown = realloc(r->buf, (size_t)cap);
        if (!grown) {
            return CO_USDO_ABORT_OUT_OF_MEMORY;
        }
        r->buf = grown;
        r->capacity = (uint32_t)cap;
    }
    if (len > 0) {
        memcpy(r->buf + offset, data, len);
        r->held = (uint32_t)need;
        maybe_progress(r, r->held);
    }
    return 0;
}

static uint8_t file_sink(void *ctx, uint32_t offset, const uint8_t *data, uint32_t len,
                         uint32_t total)
{
    rt_usdo_req_t *r = ctx;
    (void)total;
    uint32_t done = 0;
    while (done < len) {
        ssize_t n = pwrite(r->fd, data + done, len - done,
                           (off_t)(r->fd_offset + offset + done));
        if (n < 0 && errno == EINTR) {
            continue;
        }
        if (n <= 0) {
            r->error_number = n < 0 ? errno : EIO;
            return CO_USDO_ABORT_UNKNOWN;
        }
        done += (uint32_t)n;
    }
    r->held = offset + len;
    if (len > 0) {
        maybe_progress(r, r->held);
    }
    return 0;
}

static void on_answer(co_usdo_request_t *req, uint8_t node, uint8_t abort, uint8_t type,
                      const uint8_t *data, uint32_t len)
{
    rt_usdo_req_t *r = (rt_usdo_req_t *)req;
    if (!r->answers || r->answer_count >= 127u) {
        return;
    }
    co_rt_usdo_answer_t *a = &r->answers[r->answer_count++];
    a->node = node;
    a->abort = abort;
    a->type = type;
    a->length = (uint8_t)(len <= sizeof a->data ? len : sizeof a->data);
    if (a->length > 0) {
        memcpy(a->data, data, a->length);
    }
}

static void on_done(co_usdo_request_t *req)
{
    rt_usdo_req_t *r = (rt_usdo_req_t *)req;
    r->running = false;
    rt_usdo_t *u = r->line->usdo_client;
    if (!u->closing) {
        rt_post(r->line, CO_EV_USDO_DONE, req->server, (uint32_t)handle_of(u, r), req->abort,
                NULL);
    }
}

/* ---------------------------------------------------------------- client */

static void req_clear(rt_usdo_req_t *r)
{
    free(r->buf);
    free(r->answers);
    uint16_t generation = r->generation;
    rt_line_t *line = r->line;
    memset(r, 0, sizeof *r);
    r->generation = generation;
    r->line = line;
    r->fd = -1;
}

/* Under rt->lock: the line's client, created on first use. */
static rt_usdo_t *client_of(co_rt_t *rt, rt_line_t *l, uint8_t node_id)
{
    if (l->usdo_client) {
        return l->usdo_client;
    }
    if (l->line.mode != CO_MODE_FD) {
        rt_set_error(rt, "line %d (%s) is a classic line: USDO needs CAN FD (use SDO)",
                     l->index, l->channel);
        return NULL;
    }
    if (node_id == 0) {
        node_id = l->line.node_id ? l->line.node_id : 0x7F;
    }
    rt_usdo_t *u = calloc(1, sizeof *u);
    if (!u) {
        rt_set_error(rt, "line %d: no memory for the USDO client", l->index);
        return NULL;
    }
    for (uint32_t i = 0; i < RT_USDO_REQUESTS; i++) {
        u->reqs[i].line = l;
        u->reqs[i].fd = -1;
    }
    co_usdo_client_config_t config = {.sessions = u->sessions,
                                      .session_count = RT_USDO_SESSIONS_MAX,
                                      .node_id = node_id};
    if (!co_usdo_client_init(&u->client, &l->line, &config)) {
        free(u);
        rt_set_error(rt, "line %d: USDO client could not start (CAN-IDs 0x581..0x5FF taken?)",
                     l->index);
        return NULL;
    }
    l->usdo_client = u;
    return u;
}

void rt_usdo_free(rt_line_t *l)
{
    rt_usdo_t *u = l->usdo_client;
    if (!u) {
        return;
    }
    u->closing = true;
    co_usdo_client_deinit(&u->client);
    for (uint32_t i = 0; i < RT_USDO_REQUESTS; i++) {
        req_clear(&u->reqs[i]);
    }
    free(u);
    l->usdo_client = NULL;
}

/* Under rt->lock: the request of a handle, or NULL with the reason set. */
static rt_usdo_req_t *request_of(co_rt_t *rt, rt_line_t *l, int handle)
{
    rt_usdo_t *u = l->usdo_client;
    uint32_t slot = (uint32_t)handle & ((1u << HANDLE_SLOT_BITS) - 1u);
    rt_usdo_req_t *r = (u && handle >= 0 && slot < RT_USDO_REQUESTS) ? &u->reqs[slot] : NULL;
    if (!r || !r->used || handle_of(u, r) != handle) {
        rt_set_error(rt, "line %d: no USDO transfer has handle %d (released already?)",
                     l->index, handle);
        return NULL;
    }
    return r;
}

static const char *start_problem(uint8_t code)
{
    switch (code) {
    case CO_USDO_ABORT_BUSY: return "every USDO client session is in use";
    case CO_USDO_ABORT_DLC: return "more than 56 bytes cannot go expedited (or broadcast)";
    default: return "request refused (server node-id, mode, size or data)";
    }
}

static int check_request(co_rt_t *rt, int line, const co_rt_usdo_request_t *q)
{
    if (q->server < 0 || q->server > 127) {
        return rt_argument_error(rt, "line %d: USDO server node-id %d outside 0..127", line,
                                 q->server);
    }
    if (q->mode < CO_USDO_MODE_AUTO || q->mode > CO_USDO_MODE_BULK) {
        return rt_argument_error(rt, "line %d: USDO mode %d (0 auto, 1 expedited, 2 "
                                 "segmented, 3 bulk)", line, q->mode);
    }
    if (!q->upload && q->fd < 0 && !q->data && q->size > 0) {
        return rt_argument_error(rt, "line %d: USDO download of %u bytes without data", line,
                                 (unsigned)q->size);
    }
    if (q->upload && q->server == 0 && q->fd >= 0) {
        return rt_argument_error(rt, "line %d: a broadcast upload collects answers in memory",
                                 line);
    }
    return CO_RT_OK;
}

/* Under rt->lock: fill a free request slot from q. */
static rt_usdo_req_t *prepare(co_rt_t *rt, rt_usdo_t *u, const co_rt_usdo_request_t *q)
{
    rt_usdo_req_t *r = NULL;
    for (uint32_t i = 0; i < RT_USDO_REQUESTS && !r; i++) {
        if (!u->reqs[i].used) {
            r = &u->reqs[i];
        }
    }
    if (!r) {
        rt_set_error(rt, "%d USDO transfers are unreleased: release finished ones",
                     RT_USDO_REQUESTS);
        return NULL;
    }
    req_clear(r);
    r->generation = (uint16_t)((r->generation + 1u) & 0x7FFFu);   /* handle stays positive */
    if (q->server == 0) {
        r->answers = calloc(127, sizeof *r->answers);
        if (!r->answers) {
            rt_set_error(rt, "no memory for broadcast answers");
            return NULL;
        }
    }
    co_usdo_request_t *req = &r->req;
    req->server = (uint8_t)q->server;
    req->index = q->index;
    req->sub = q->sub;
    req->upload = q->upload != 0;
    req->mode = (uint8_t)q->mode;
    req->type = q->type;
    req->size = q->upload ? 0 : q->size;
    req->timeout_ms = q->timeout_ms;
    req->ctx = r;
    req->done = on_done;
    req->answer = on_answer;
    r->fd = q->fd;
    r->fd_offset = q->fd_offset;
    r->src = q->data;
    r->max_size = q->max_size ? q->max_size : RT_USDO_DEFAULT_MAX;
    r->progress = q->progress != 0;
    if (q->upload) {
        req->sink = q->fd >= 0 ? file_sink : memory_sink;
    } else if (q->size > 0) {
        req->source = q->fd >= 0 ? file_source : memory_source;
    }
    return r;
}

/* ---------------------------------------------------------------- API */

int co_rt_usdo_client(co_rt_t *rt, int line, int node_id)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    if (node_id < 1 || node_id > 127) {
        return rt_argument_error(rt, "line %d: USDO client node-id %d outside 1..127", line,
                                 node_id);
    }
    pthread_mutex_lock(&rt->lock);
    int status = CO_RT_OK;
    if (l->usdo_client) {
        if (l->usdo_client->client.node_id != node_id) {
            rt_set_error(rt, "line %d: the USDO client already runs as node %d", line,
                         l->usdo_client->client.node_id);
            status = CO_RT_ERR_STATE;
        }
    } else if (!client_of(rt, l, (uint8_t)node_id)) {
        status = CO_RT_ERR_STATE;
    }
    pthread_mutex_unlock(&rt->lock);
    return status;
}

int co_rt_usdo_start(co_rt_t *rt, int line, const co_rt_usdo_request_t *request)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l || !request) {
        return CO_RT_ERR_ARGUMENT;
    }
    int status = check_request(rt, line, request);
    if (status != CO_RT_OK) {
        return status;
    }
    pthread_mutex_lock(&rt->lock);
    rt_usdo_t *u = client_of(rt, l, 0);
    rt_usdo_req_t *r = u ? prepare(rt, u, request) : NULL;
    if (!r) {
        status = u ? CO_RT_ERR_FULL : CO_RT_ERR_STATE;
    } else {
        co_line_set_time(&l->line, co_rt_now_us());
        uint8_t code = co_usdo_client_start(&u->client, &r->req);
        if (code == 0) {
            r->used = true;
            r->running = true;
            status = handle_of(u, r);
        } else {
            rt_set_error(rt, "line %d: USDO %s 0x%04X:%02X of node %d: %s (0x%02X)", line,
                         request->upload ? "upload" : "download", request->index,
                         request->sub, request->server, start_problem(code), code);
            status = code == CO_USDO_ABORT_BUSY ? CO_RT_ERR_FULL : CO_RT_ERR_ARGUMENT;
            req_clear(r);
        }
    }
    pthread_mutex_unlock(&rt->lock);
    if (status >= 0) {
        rt_wake(rt);   /* frames wait in the tx queue, a timer was armed */
    }
    return status;
}

int co_rt_usdo_cancel(co_rt_t *rt, int line, int handle, uint8_t code)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    pthread_mutex_lock(&rt->lock);
    int status = CO_RT_ERR_STATE;
    rt_usdo_req_t *r = request_of(rt, l, handle);
    if (r) {
        co_line_set_time(&l->line, co_rt_now_us());
        if (r->running) {
            co_usdo_client_cancel(&l->usdo_client->client, &r->req, code);
        }
        status = CO_RT_OK;
    }
    pthread_mutex_unlock(&rt->lock);
    rt_wake(rt);
    return status;
}

int co_rt_usdo_result(co_rt_t *rt, int line, int handle, co_rt_usdo_result_t *out)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l || !out) {
        return CO_RT_ERR_ARGUMENT;
    }
    pthread_mutex_lock(&rt->lock);
    int status = CO_RT_ERR_STATE;
    rt_usdo_req_t *r = request_of(rt, l, handle);
    if (r) {
        const co_usdo_request_t *q = &r->req;
        *out = (co_rt_usdo_result_t){.running = r->running,
                                     .abort = q->abort,
                                     .abort_from_server = q->abort_from_server,
                                     .type = q->result_type,
                                     .mode = q->result_mode,
                                     .session_id = q->session_id,
                                     .pacing = q->pacing,
                                     .transferred = q->upload ? r->held : q->transferred,
                                     .answers = q->answers,
                                     .error_number = r->error_number};
        status = CO_RT_OK;
    }
    pthread_mutex_unlock(&rt->lock);
    return status;
}

int co_rt_usdo_data(co_rt_t *rt, int line, int handle, uint8_t *buf, uint32_t capacity)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l || (!buf && capacity > 0)) {
        return CO_RT_ERR_ARGUMENT;
    }
    pthread_mutex_lock(&rt->lock);
    int status = CO_RT_ERR_STATE;
    rt_usdo_req_t *r = request_of(rt, l, handle);
    if (r && r->held > capacity) {
        rt_set_error(rt, "line %d: %u bytes uploaded, buffer of %u", line,
                     (unsigned)r->held, (unsigned)capacity);
        status = CO_RT_ERR_ARGUMENT;
    } else if (r) {
        if (r->held > 0) {
            memcpy(buf, r->buf, r->held);
        }
        status = (int)r->held;
    }
    pthread_mutex_unlock(&rt->lock);
    return status;
}

int co_rt_usdo_answers(co_rt_t *rt, int line, int handle, co_rt_usdo_answer_t *out, int max)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l || (!out && max > 0) || max < 0) {
        return CO_RT_ERR_ARGUMENT;
    }
    pthread_mutex_lock(&rt->lock);
    int status = CO_RT_ERR_STATE;
    rt_usdo_req_t *r = request_of(rt, l, handle);
    if (r) {
        uint32_t n = r->answer_count < (uint32_t)max ? r->answer_count : (uint32_t)max;
        if (n > 0) {
            memcpy(out, r->answers, n * sizeof *out);
        }
        status = (int)n;
    }
    pthread_mutex_unlock(&rt->lock);
    return status;
}

int co_rt_usdo_release(co_rt_t *rt, int line, int handle)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    pthread_mutex_lock(&rt->lock);
    int status = CO_RT_ERR_STATE;
    rt_usdo_req_t *r = request_of(rt, l, handle);
    if (r) {
        if (r->running) {
            co_line_set_time(&l->line, co_rt_now_us());
            co_usdo_client_cancel(&l->usdo_client->client, &r->req, 0);
        }
        req_clear(r);
        status = CO_RT_OK;
    }
    pthread_mutex_unlock(&rt->lock);
    return status;
}
