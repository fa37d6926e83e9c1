/* Runtime: the client transfers of a line — USDO on fd lines, SDO on
 * classic lines, behind one API. Transfers run in the runtime thread; the
 * application (Python) starts them from any thread, hears
 * CO_EV_TRANSFER_DONE, collects the result and releases the handle. Data
 * moves between the core clients and memory or a file here, never frame by
 * frame through Python. */

#include "co_rt_internal.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

enum {
    RT_USDO_CLIENT_SESSIONS = 64,      /* USDO transfers in flight per line */
    RT_SDO_CLIENT_CHANNELS = 32,       /* SDO transfers in flight per line (servers) */
    RT_CLIENT_REQUESTS = 128,          /* handles: running + finished, not yet released */
    RT_CLIENT_DEFAULT_MAX = 64u << 20, /* upload to memory: 64 MiB unless told */
    RT_CLIENT_FIRST_CHUNK = 4096,      /* upload of unknown size: first allocation */
    RT_CLIENT_PROGRESS_US = 50000,
    HANDLE_SLOT_BITS = 8
};

/* Why a data path failed, in the words of each protocol. */
typedef enum data_error { DATA_OK = 0, DATA_NO_ROOM, DATA_IO } data_error_t;

typedef struct rt_req {
    union {
        co_usdo_request_t usdo;
        co_sdo_request_t sdo;
    } core;
    rt_line_t *line;
    uint16_t generation;
    bool used;                         /* a handle exists */
    bool running;
    bool progress;
    bool done_event;                   /* post CO_EV_TRANSFER_DONE when it ends ... */
    uint16_t waiters;                  /* ... unless callers wait in co_rt_transfer_wait */
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
    /* USDO broadcast */
    co_rt_usdo_answer_t *answers;
    uint32_t answer_count;
} rt_req_t;

typedef struct rt_client {
    bool fd;                           /* USDO (fd line) or SDO (classic line) */
    bool closing;                      /* freeing: done() posts nothing */
    co_usdo_client_t *usdo;            /* the stack's client of the line's kind */
    co_sdo_client_t *sdo;
    rt_req_t reqs[RT_CLIENT_REQUESTS];
} rt_client_t;

static int handle_of(const rt_client_t *c, const rt_req_t *r)
{
    uint32_t slot = (uint32_t)(r - c->reqs);
    return (int)((uint32_t)r->generation << HANDLE_SLOT_BITS | slot);
}

/* ---------------------------------------------------------------- data paths */

static void maybe_progress(rt_req_t *r, uint32_t moved)
{
    if (!r->progress) {
        return;
    }
    uint64_t now = co_rt_now_us();
    if (now >= r->progress_at) {
        r->progress_at = now + RT_CLIENT_PROGRESS_US;
        rt_post(r->line, CO_EV_TRANSFER_PROGRESS, 0, (uint32_t)handle_of(r->line->client, r),
                moved, NULL);
    }
}

/* Download source: memory or file; fewer bytes than `want` = failed. */
static uint32_t read_source(rt_req_t *r, uint32_t offset, uint8_t *buf, uint32_t want)
{
    if (r->fd < 0) {
        memcpy(buf, r->src + offset, want);
    } else {
        uint32_t got = 0;
        while (got < want) {
            int64_t n = rt_os_pread(r->fd, buf + got, want - got,
                                    r->fd_offset + offset + got);
            if (n < 0 && errno == EINTR) {
                continue;
            }
            if (n <= 0) {
                r->error_number = n < 0 ? errno : EIO;   /* a file shorter than announced */
                return got;
            }
            got += (uint32_t)n;
        }
    }
    maybe_progress(r, offset + want);
    return want;
}

/* Upload sink. Memory: the announced size is allocated at once, an unknown
 * size grows by doubling, anything beyond max_size is refused. */
static data_error_t write_sink(rt_req_t *r, uint32_t offset, const uint8_t *data, uint32_t len,
                               uint32_t total, bool total_known)
{
    if (r->fd >= 0) {
        uint32_t done = 0;
        while (done < len) {
            int64_t n = rt_os_pwrite(r->fd, data + done, len - done,
                                     r->fd_offset + offset + done);
            if (n < 0 && errno == EINTR) {
                continue;
            }
            if (n <= 0) {
                r->error_number = n < 0 ? errno : EIO;
                return DATA_IO;
            }
            done += (uint32_t)n;
        }
    } else {
        uint64_t need = (uint64_t)offset + len;
        if (len == 0 && total_known) {
            need = total;
        }
        if (need > r->max_size) {
            return DATA_NO_ROOM;
        }
        if (need > r->capacity) {
            uint64_t cap = r->capacity ? r->capacity : RT_CLIENT_FIRST_CHUNK;
            while (cap < need) {
                cap *= 2u;
            }
            cap = cap > r->max_size ? r->max_size : cap;
            uint8_t *grown = realloc(r->buf, (size_t)cap);
            if (!grown) {
                return DATA_NO_ROOM;
            }
            r->buf = grown;
            r->capacity = (uint32_t)cap;
        }
        if (len > 0) {
            memcpy(r->buf + offset, data, len);
        }
    }
    if (len > 0) {
        r->held = offset + len;
        maybe_progress(r, r->held);
    }
    return DATA_OK;
}

static uint32_t usdo_source(void *ctx, uint32_t offset, uint8_t *buf, uint32_t want)
{
    return read_source(ctx, offset, buf, want);
}

static uint8_t usdo_sink(void *ctx, uint32_t offset, const uint8_t *data, uint32_t len,
                         uint32_t total)
{
    switch (write_sink(ctx, offset, data, len, total, total != 0xFFFFFFFFu)) {
    case DATA_OK: return 0;
    case DATA_NO_ROOM: return CO_USDO_ABORT_OUT_OF_MEMORY;
    default: return CO_USDO_ABORT_UNKNOWN;
    }
}

static uint32_t sdo_source(void *ctx, uint32_t offset, uint8_t *buf, uint32_t want)
{
    return read_source(ctx, offset, buf, want);
}

static uint32_t sdo_sink(void *ctx, uint32_t offset, const uint8_t *data, uint32_t len,
                         uint32_t total)
{
    switch (write_sink(ctx, offset, data, len, total, total != CO_SDO_CLIENT_SIZE_UNKNOWN)) {
    case DATA_OK: return 0;
    case DATA_NO_ROOM: return CO_ABORT_OUT_OF_MEMORY;
    default: return CO_ABORT_GENERAL;
    }
}

static void on_answer(co_usdo_request_t *req, uint8_t node, uint8_t abort, uint8_t type,
                      const uint8_t *data, uint32_t len)
{
    rt_req_t *r = req->user;
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

static void finished(rt_req_t *r)
{
    r->running = false;
    rt_transfer_ended(r->line->rt);
    rt_client_t *c = r->line->client;
    /* A caller blocked in co_rt_transfer_wait hears of the end directly; an
     * event as well would wake the application's event thread at the same
     * moment, and the two would compete for the application (Python's GIL). */
    if (!c->closing && r->done_event && r->waiters == 0) {
        rt_post(r->line, CO_EV_TRANSFER_DONE, 0, (uint32_t)handle_of(c, r), 0, NULL);
    }
}

static void usdo_done(co_usdo_request_t *req) { finished(req->user); }
static void sdo_done(co_sdo_request_t *req) { finished(req->user); }

/* ---------------------------------------------------------------- clients */

static void req_clear(rt_req_t *r)
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

/* The stack's client: USDO sessions on fd lines, SDO channels on classic
 * lines (the local node's 0x1280.. channels first when it serves an OD). */
static co_stack_status_t client_init(rt_client_t *c, rt_line_t *l, uint8_t node_id)
{
    co_stack_client_config_t config = {
        .sessions = c->fd ? RT_USDO_CLIENT_SESSIONS : RT_SDO_CLIENT_CHANNELS,
        .node_id = node_id};
    co_stack_status_t status = co_stack_client_init(&l->stack, &config);
    c->usdo = co_stack_usdo_client(&l->stack);
    c->sdo = co_stack_sdo_client(&l->stack);
    return status;
}

/* Under rt->lock: the line's client, created on first use. */
static rt_client_t *client_of(co_rt_t *rt, rt_line_t *l, uint8_t node_id)
{
    if (l->client) {
        return l->client;
    }
    if (node_id == 0) {
        node_id = co_line_node_id(&l->line) ? co_line_node_id(&l->line) : 0x7F;
    }
    rt_client_t *c = calloc(1, sizeof *c);
    if (!c) {
        rt_set_error(rt, "line %d: no memory for the client", l->index);
        return NULL;
    }
    c->fd = co_line_mode(&l->line) == CO_MODE_FD;
    for (uint32_t i = 0; i < RT_CLIENT_REQUESTS; i++) {
        c->reqs[i].line = l;
        c->reqs[i].fd = -1;
    }
    co_stack_status_t status = client_init(c, l, node_id);
    if (status != CO_STACK_OK) {
        free(c);
        rt_set_error(rt, "line %d: %s client could not start (%s)", l->index,
                     co_line_mode(&l->line) == CO_MODE_FD ? "USDO" : "SDO",
                     status == CO_STACK_ERR_NO_MEMORY ? "no memory"
                                                      : "CAN-IDs 0x581..0x5FF taken?");
        return NULL;
    }
    l->client = c;
    return c;
}

bool rt_client_ready(co_rt_t *rt, rt_line_t *l)
{
    return client_of(rt, l, 0) != NULL;
}

void rt_client_free(rt_line_t *l)
{
    rt_client_t *c = l->client;
    if (!c) {
        return;
    }
    c->closing = true;
    co_stack_client_deinit(&l->stack);
    for (uint32_t i = 0; i < RT_CLIENT_REQUESTS; i++) {
        req_clear(&c->reqs[i]);
    }
    free(c);
    l->client = NULL;
}

/* Under rt->lock: the request of a handle, or NULL with the reason set. */
static rt_req_t *request_of(co_rt_t *rt, rt_line_t *l, int handle)
{
    rt_client_t *c = l->client;
    uint32_t slot = (uint32_t)handle & ((1u << HANDLE_SLOT_BITS) - 1u);
    rt_req_t *r = (c && handle >= 0 && slot < RT_CLIENT_REQUESTS) ? &c->reqs[slot] : NULL;
    if (!r || !r->used || handle_of(c, r) != handle) {
        rt_set_error(rt, "line %d: no transfer has handle %d (released already?)", l->index,
                     handle);
        return NULL;
    }
    return r;
}

static int check_request(co_rt_t *rt, const rt_line_t *l, const co_rt_transfer_request_t *q)
{
    bool fd = co_line_mode(&l->line) == CO_MODE_FD;
    if (q->server < (fd ? 0 : 1) || q->server > 127) {
        return rt_argument_error(rt, "line %d: server node-id %d outside %d..127%s", l->index,
                                 q->server, fd ? 0 : 1, fd ? " (0 = broadcast)" : "");
    }
    if (q->mode < 0 || q->mode > 3) {
        return rt_argument_error(rt, "line %d: mode %d (0 auto, 1 expedited, 2 segmented, "
                                 "3 %s)", l->index, q->mode, fd ? "bulk" : "block");
    }
    if (!q->upload && q->fd < 0 && !q->data && q->size > 0) {
        return rt_argument_error(rt, "line %d: download of %u bytes without data", l->index,
                                 (unsigned)q->size);
    }
    if (q->upload && q->server == 0 && q->fd >= 0) {
        return rt_argument_error(rt, "line %d: a broadcast upload collects answers in memory",
                                 l->index);
    }
    if (q->network != 0 && (q->server == 0 || q->network > 127 || q->network_node < 1 ||
                            q->network_node > 127)) {
        return rt_argument_error(rt, "line %d: a routed request names its gateway (1..127), "
                                 "network 1..127 and node 1..127 (got gateway %d, network %u, "
                                 "node %u)", l->index, q->server, (unsigned)q->network,
                                 (unsigned)q->network_node);
    }
    if (q->network != 0 && fd && q->mode == CO_USDO_MODE_BULK) {
        return rt_argument_error(rt, "line %d: node %u of network %u: bulk transfers are not "
                                 "routed (remote USDO is expedited or segmented)", l->index,
                                 (unsigned)q->network_node, (unsigned)q->network);
    }
    return CO_RT_OK;
}

static void prepare_usdo(rt_req_t *r, const co_rt_transfer_request_t *q)
{
    co_usdo_request_t *req = &r->core.usdo;
    req->server = (uint8_t)q->server;
    req->index = q->index;
    req->sub = q->sub;
    req->upload = q->upload != 0;
    req->mode = (uint8_t)q->mode;
    req->type = q->type;
    req->size = q->size;   /* upload: the size hint AUTO picks bulk by (0 = unknown) */
    req->timeout_ms = q->timeout_ms;
    req->ctx = r;
    req->user = r;
    req->done = usdo_done;
    req->answer = on_answer;
    req->sink = q->upload ? usdo_sink : NULL;
    req->source = (!q->upload && q->size > 0) ? usdo_source : NULL;
    /* remote (routed) USDO: `server` is the gateway */
    req->network = q->network;
    req->network_node = q->network_node;
    req->source_network = r->line != NULL ? r->line->network_id : 0;
}

static void prepare_sdo(rt_req_t *r, const co_rt_transfer_request_t *q)
{
    co_sdo_request_t *req = &r->core.sdo;
    req->server = (uint8_t)q->server;
    req->index = q->index;
    req->sub = q->sub;
    req->upload = q->upload != 0;
    req->mode = (uint8_t)q->mode;
    req->size = q->size;
    req->timeout_ms = q->timeout_ms;
    req->block_threshold = q->block_threshold;
    req->network = q->network;
    req->network_node = q->network_node;
    req->ctx = r;
    req->user = r;
    req->done = sdo_done;
    req->sink = q->upload ? sdo_sink : NULL;
    req->source = (!q->upload && q->size > 0) ? sdo_source : NULL;
}

/* Under rt->lock: fill a free request slot from q. */
static rt_req_t *prepare(co_rt_t *rt, rt_client_t *c, const co_rt_transfer_request_t *q)
{
    rt_req_t *r = NULL;
    for (uint32_t i = 0; i < RT_CLIENT_REQUESTS && !r; i++) {
        if (!c->reqs[i].used) {
            r = &c->reqs[i];
        }
    }
    if (!r) {
        rt_set_error(rt, "%d transfers are unreleased: release finished ones",
                     RT_CLIENT_REQUESTS);
        return NULL;
    }
    req_clear(r);
    r->generation = (uint16_t)((r->generation + 1u) & 0x7FFFu);   /* handle stays positive */
    if (c->fd && q->server == 0) {
        r->answers = calloc(127, sizeof *r->answers);
        if (!r->answers) {
            rt_set_error(rt, "no memory for broadcast answers");
            return NULL;
        }
    }
    r->fd = q->fd;
    r->fd_offset = q->fd_offset;
    r->src = q->data;
    r->max_size = q->max_size ? q->max_size : RT_CLIENT_DEFAULT_MAX;
    r->progress = q->progress != 0;
    r->done_event = q->no_done_event == 0;
    if (c->fd) {
        prepare_usdo(r, q);
    } else {
        prepare_sdo(r, q);
    }
    return r;
}

static const char *usdo_refusal(uint32_t code)
{
    switch (code) {
    case CO_USDO_ABORT_BUSY:
        return "every USDO client session is in use, or bulk uploads already hold the "
               "line's receive budget";
    case CO_USDO_ABORT_DLC: return "more than 56 bytes cannot go expedited (or broadcast)";
    default: return "request refused (server node-id, mode, size or data)";
    }
}

static const char *sdo_refusal(uint32_t code)
{
    switch (code) {
    case CO_ABORT_NO_RESOURCE: return "the SDO channel to that server is busy";
    case CO_ABORT_TYPE_MISMATCH: return "expedited SDO downloads carry 1..4 bytes";
    default: return "request refused (server node-id, mode, size or data)";
    }
}

/* ---------------------------------------------------------------- API */

int co_rt_usdo_client(co_rt_t *rt, int line, int node_id)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    if (co_line_mode(&l->line) != CO_MODE_FD) {
        return rt_argument_error(rt, "line %d is classic: SDO clients have no node-id", line);
    }
    if (node_id < 1 || node_id > 127) {
        return rt_argument_error(rt, "line %d: USDO client node-id %d outside 1..127", line,
                                 node_id);
    }
    rt_mutex_lock(&rt->lock);
    int status = CO_RT_OK;
    if (l->client) {
        if (l->client->usdo->node_id != node_id) {
            rt_set_error(rt, "line %d: the USDO client already runs as node %d", line,
                         l->client->usdo->node_id);
            status = CO_RT_ERR_STATE;
        }
    } else if (!client_of(rt, l, (uint8_t)node_id)) {
        status = CO_RT_ERR_STATE;
    }
    rt_mutex_unlock(&rt->lock);
    return status;
}

int co_rt_transfer_start(co_rt_t *rt, int line, const co_rt_transfer_request_t *request)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l || !request) {
        return CO_RT_ERR_ARGUMENT;
    }
    int status = check_request(rt, l, request);
    if (status != CO_RT_OK) {
        return status;
    }
    rt_mutex_lock(&rt->lock);
    if (rt->stopping) {
        /* nothing would ever run it: its waiter would wait for good */
        rt_set_error(rt, "runtime stopped");
        rt_mutex_unlock(&rt->lock);
        return CO_RT_ERR_CLOSED;
    }
    rt_client_t *c = client_of(rt, l, 0);
    rt_req_t *r = c ? prepare(rt, c, request) : NULL;
    if (!r) {
        status = c ? CO_RT_ERR_FULL : CO_RT_ERR_STATE;
    } else {
        co_line_set_time(&l->line, co_rt_now_us());
        uint32_t code = c->fd ? co_usdo_client_start(c->usdo, &r->core.usdo)
                              : co_sdo_client_start(c->sdo, &r->core.sdo);
        if (code == 0) {
            r->used = true;
            r->running = true;
            status = handle_of(c, r);
        } else {
            bool busy = c->fd ? code == CO_USDO_ABORT_BUSY : code == CO_ABORT_NO_RESOURCE;
            rt_set_error(rt, "line %d: %s %s 0x%04X:%02X of node %d: %s (0x%0*X)", line,
                         c->fd ? "USDO" : "SDO", request->upload ? "upload" : "download",
                         request->index, request->sub, request->server,
                         c->fd ? usdo_refusal(code) : sdo_refusal(code), c->fd ? 2 : 8,
                         (unsigned)code);
            status = busy ? CO_RT_ERR_FULL : CO_RT_ERR_ARGUMENT;
            req_clear(r);
        }
    }
    if (status >= 0) {
        rt_kick(rt);   /* frames wait in the tx queue, a timer was armed */
    }
    rt_mutex_unlock(&rt->lock);
    return status;
}

/* Under rt->lock: cancel a running request. */
static void cancel(rt_line_t *l, rt_req_t *r, uint32_t code)
{
    rt_client_t *c = l->client;
    co_line_set_time(&l->line, co_rt_now_us());
    if (c->fd) {
        co_usdo_client_cancel(c->usdo, &r->core.usdo, (uint8_t)code);
    } else {
        co_sdo_client_cancel(c->sdo, &r->core.sdo, code);
    }
}

int co_rt_transfer_cancel(co_rt_t *rt, int line, int handle, uint32_t code)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    int status = CO_RT_ERR_STATE;
    rt_req_t *r = request_of(rt, l, handle);
    if (r && l->client->fd && code > 0xFF) {
        status = rt_argument_error(rt, "line %d: 0x%X is not a one-byte USDO abort code", line,
                                   (unsigned)code);
    } else if (r) {
        if (r->running) {
            cancel(l, r, code);
        }
        status = CO_RT_OK;
    }
    rt_kick(rt);
    rt_mutex_unlock(&rt->lock);
    return status;
}

int co_rt_transfer_result(co_rt_t *rt, int line, int handle, co_rt_transfer_result_t *out)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l || !out) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    int status = CO_RT_ERR_STATE;
    rt_req_t *r = request_of(rt, l, handle);
    if (r && l->client->fd) {
        const co_usdo_request_t *q = &r->core.usdo;
        *out = (co_rt_transfer_result_t){.running = r->running,
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
    } else if (r) {
        const co_sdo_request_t *q = &r->core.sdo;
        *out = (co_rt_transfer_result_t){.running = r->running,
                                         .abort = q->abort,
                                         .abort_from_server = q->abort_from_server,
                                         .mode = q->result_mode,
                                         .session_id = q->result_channel,
                                         .transferred = q->upload ? r->held : q->transferred,
                                         .error_number = r->error_number};
        status = CO_RT_OK;
    }
    rt_mutex_unlock(&rt->lock);
    return status;
}

/* Under rt->lock: 1 = ended, 0 = running, < 0 = no such transfer. */
/* 1 ended, 0 running, CO_RT_ERR_STATE released, CO_RT_ERR_CLOSED running
 * but the runtime stopped (it never ends then); waiting (+1 / -1, rt->lock
 * held) counts the caller in or out of the transfer's waiters. A request
 * released meanwhile was cleared, waiters too: nothing to count out. */
static int transfer_ended(co_rt_t *rt, int line, int handle, int waiting)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    rt_req_t *r = l ? request_of(rt, l, handle) : NULL;
    if (!r) {
        return CO_RT_ERR_STATE;
    }
    if (waiting < 0 && r->waiters > 0) {
        r->waiters--;
    }
    if (r->running && rt->stopping) {
        return CO_RT_ERR_CLOSED;
    }
    if (waiting > 0 && r->running) {
        r->waiters++;
    }
    return !r->running;
}

int co_rt_transfer_wait(co_rt_t *rt, int line, int handle, int timeout_ms)
{
    if (!rt_checked_line(rt, line, false)) {
        return CO_RT_ERR_ARGUMENT;
    }
    uint64_t start = rt_os_now_us();
    for (;;) {
        uint64_t gen = rt_transfer_generation(rt);
        rt_mutex_lock(&rt->lock);
        int ended = transfer_ended(rt, line, handle, +1);
        rt_mutex_unlock(&rt->lock);
        if (ended != 0) {
            return ended;
        }
        int left = timeout_ms;
        if (timeout_ms > 0) {
            uint64_t spent = (rt_os_now_us() - start) / 1000u;
            left = spent >= (uint64_t)timeout_ms ? 0 : (int)(timeout_ms - (int)spent);
        }
        bool woken = left != 0 && rt_wait_transfer_end(rt, gen, left);
        rt_mutex_lock(&rt->lock);
        ended = transfer_ended(rt, line, handle, -1);
        rt_mutex_unlock(&rt->lock);
        if (!woken || ended != 0) {
            return ended;
        }
    }
}

int co_rt_transfer_notify(co_rt_t *rt, int line, int handle)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    /* Under the lock finished() either has run (1: no event comes) or will
     * see the flag (0): the end is heard exactly once either way. */
    rt_req_t *r = request_of(rt, l, handle);
    int status = r ? !r->running : CO_RT_ERR_STATE;
    if (r && r->running) {
        r->done_event = true;
    }
    rt_mutex_unlock(&rt->lock);
    return status;
}

int co_rt_transfer_data(co_rt_t *rt, int line, int handle, uint8_t *buf, uint32_t capacity)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l || (!buf && capacity > 0)) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    int status = CO_RT_ERR_STATE;
    rt_req_t *r = request_of(rt, l, handle);
    if (r && r->held > capacity) {
        rt_set_error(rt, "line %d: %u bytes uploaded, buffer of %u", line,
                     (unsigned)r->held, (unsigned)capacity);
        status = CO_RT_ERR_ARGUMENT;
    } else if (r) {
        if (r->held > 0 && r->fd < 0) {
            memcpy(buf, r->buf, r->held);
        }
        status = r->fd < 0 ? (int)r->held : 0;
    }
    rt_mutex_unlock(&rt->lock);
    return status;
}

int co_rt_usdo_answers(co_rt_t *rt, int line, int handle, co_rt_usdo_answer_t *out, int max)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l || (!out && max > 0) || max < 0) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    int status = CO_RT_ERR_STATE;
    rt_req_t *r = request_of(rt, l, handle);
    if (r) {
        uint32_t n = r->answer_count < (uint32_t)max ? r->answer_count : (uint32_t)max;
        if (n > 0) {
            memcpy(out, r->answers, n * sizeof *out);
        }
        status = (int)n;
    }
    rt_mutex_unlock(&rt->lock);
    return status;
}

int co_rt_transfer_release(co_rt_t *rt, int line, int handle)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    int status = CO_RT_ERR_STATE;
    rt_req_t *r = request_of(rt, l, handle);
    if (r) {
        if (r->running) {
            cancel(l, r, 0);
        }
        req_clear(r);
        status = CO_RT_OK;
    }
    rt_mutex_unlock(&rt->lock);
    return status;
}

bool rt_client_cores(co_rt_t *rt, rt_line_t *l, co_usdo_client_t **usdo,
                     co_sdo_client_t **sdo)
{
    rt_client_t *c = client_of(rt, l, 0);
    *usdo = c ? c->usdo : NULL;
    *sdo = c ? c->sdo : NULL;
    return c != NULL;
}
