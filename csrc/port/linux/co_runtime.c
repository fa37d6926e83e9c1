/* Linux runtime (see co_runtime.h).
 *
 * One pthread per runtime runs every line: epoll over the SocketCAN sockets,
 * one timerfd armed at the earliest deadline and one eventfd for wake-ups.
 *
 * Locks (taken in this order, never the other way round):
 *   life_lock    start / stop / add_line transitions
 *   lock         lines, buses, drivers and core objects; held by the thread
 *                except while it sleeps in epoll_wait, taken briefly by
 *                add_line, host_receive and the snapshot calls
 *   host.lock    per host line: frames waiting for co_rt_host_transmit
 *   events.lock  the bounded event ring
 * mail.lock (command mailbox) and error_lock are leaves, so co_rt_command
 * never waits for the lines to be processed.
 *
 * No Python is ever called from the thread, so it runs without the GIL. */
#define _GNU_SOURCE

#include "co_rt_internal.h"

#include <errno.h>
#include <pthread.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <sys/timerfd.h>
#include <time.h>
#include <unistd.h>

static uint64_t min_u64(uint64_t a, uint64_t b) { return a < b ? a : b; }

uint64_t co_rt_now_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

/* ================================================================ errors */

__attribute__((format(printf, 2, 3)))
void rt_set_error(co_rt_t *rt, const char *fmt, ...)
{
    va_list args;
    va_start(args, fmt);
    pthread_mutex_lock(&rt->error_lock);
    vsnprintf(rt->error, sizeof rt->error, fmt, args);
    pthread_mutex_unlock(&rt->error_lock);
    va_end(args);
}

void co_rt_last_error(co_rt_t *rt, char *buf, size_t size)
{
    if (!rt || !buf || size == 0) {
        return;
    }
    pthread_mutex_lock(&rt->error_lock);
    snprintf(buf, size, "%s", rt->error);
    pthread_mutex_unlock(&rt->error_lock);
}

const char *co_rt_status_text(int status)
{
    switch (status) {
    case CO_RT_OK: return "ok";
    case CO_RT_ERR_ARGUMENT: return "invalid argument";
    case CO_RT_ERR_NO_INTERFACE: return "no such network interface";
    case CO_RT_ERR_MTU: return "interface MTU does not fit the line mode";
    case CO_RT_ERR_SOCKET: return "socket error";
    case CO_RT_ERR_FULL: return "queue or table full";
    case CO_RT_ERR_STATE: return "not allowed in the current state";
    case CO_RT_ERR_NO_MEMORY: return "out of memory";
    case CO_RT_ERR_CLOSED: return "runtime stopped";
    case CO_RT_ERR_MODE: return "membus already open in the other mode";
    default: return status >= 0 ? "ok" : "unknown error";
    }
}

/* ================================================================ waiting */

static void monotonic_cond_init(pthread_cond_t *cond)
{
    pthread_condattr_t attr;
    pthread_condattr_init(&attr);
    pthread_condattr_setclock(&attr, CLOCK_MONOTONIC);
    pthread_cond_init(cond, &attr);
    pthread_condattr_destroy(&attr);
}

static struct timespec deadline_after_ms(int timeout_ms)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    ts.tv_sec += timeout_ms / 1000;
    ts.tv_nsec += (long)(timeout_ms % 1000) * 1000000L;
    if (ts.tv_nsec >= 1000000000L) {
        ts.tv_sec++;
        ts.tv_nsec -= 1000000000L;
    }
    return ts;
}

/* One wait step: false once the timeout has passed. */
static bool wait_step(pthread_cond_t *cond, pthread_mutex_t *lock, int timeout_ms,
                      const struct timespec *deadline)
{
    if (timeout_ms == 0) {
        return false;
    }
    if (timeout_ms < 0) {
        pthread_cond_wait(cond, lock);
        return true;
    }
    return pthread_cond_timedwait(cond, lock, deadline) != ETIMEDOUT;
}

/* ================================================================ events */

static void ring_push(rt_events_t *q, const co_rt_event_t *ev)
{
    q->ring[(q->head + q->count) % q->capacity] = *ev;
    q->count++;
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

static bool events_post(rt_events_t *q, const co_rt_event_t *ev)
{
    pthread_mutex_lock(&q->lock);
    push_lost_marker(q);
    bool queued = q->count < q->capacity;
    if (queued) {
        ring_push(q, ev);
    } else {
        q->lost++;
    }
    if (q->waiters > 0) {
        pthread_cond_signal(&q->ready);
    }
    pthread_mutex_unlock(&q->lock);
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

int co_rt_wait_events(co_rt_t *rt, co_rt_event_t *events, int max, int timeout_ms)
{
    if (!rt || !events || max <= 0) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_events_t *q = &rt->events;
    struct timespec deadline = deadline_after_ms(timeout_ms > 0 ? timeout_ms : 0);
    pthread_mutex_lock(&q->lock);
    q->waiters++;
    while (q->count == 0 && !q->closed && wait_step(&q->ready, &q->lock, timeout_ms, &deadline)) {
    }
    int n = 0;
    for (; n < max && q->count > 0; n++) {
        events[n] = q->ring[q->head];
        q->head = (q->head + 1) % q->capacity;
        q->count--;
    }
    push_lost_marker(q);
    int result = (n == 0 && q->closed) ? CO_RT_ERR_CLOSED : n;
    q->waiters--;
    pthread_mutex_unlock(&q->lock);
    return result;
}

/* ================================================================ core indications */

static rt_line_t *line_of(co_line_t *line)
{
    return (rt_line_t *)(void *)((char *)line - offsetof(rt_line_t, line));
}

static void on_node_state(co_node_t *node, co_nmt_state_t old_state, co_nmt_state_t new_state,
                          void *user)
{
    rt_post(user, CO_EV_NMT_STATE, node->nmt.node_id, (uint32_t)old_state, (uint32_t)new_state,
         NULL);
}

static bool on_allow_operational(co_node_t *node, void *user)
{
    rt_line_t *l = user;
    if (!l->allow_operational) {
        rt_post(l, CO_EV_NMT_VETOED, node->nmt.node_id, 0, 0, NULL);
    }
    return l->allow_operational;
}

/* What each parameter load found is told to Python (a damaged, foreign or
 * unreadable store means the node runs on defaults). */
static void post_store_status(rt_line_t *l)
{
    if (rt_has_store(l)) {
        rt_post(l, CO_EV_STORE, co_stack_node(&l->stack)->nmt.node_id, (uint32_t)co_stack_node(&l->stack)->store_status,
             co_stack_store(&l->stack)->records_skipped, NULL);
    }
}

static void on_node_reset(co_node_t *node, co_nmt_command_t kind, void *user)
{
    rt_post(user, CO_EV_NMT_RESET, node->nmt.node_id, (uint32_t)kind, 0, NULL);
    post_store_status(user);
}

/* Entries changed by the network or a PDO are told to Python (object
 * changed); the application's own writes are not echoed back. */
static void on_od_written(co_od_t *od, const co_od_entry_t *e, co_od_origin_t origin, void *user)
{
    (void)od;
    if (origin == CO_ORIGIN_NETWORK || origin == CO_ORIGIN_PDO) {
        rt_line_t *l = user;
        rt_post(l, CO_EV_OD_CHANGED, co_stack_node(&l->stack)->nmt.node_id, e->key, (uint32_t)origin, NULL);
    }
}

static const co_od_handler_t od_observer = {.after_write = on_od_written};

static void on_pdo_received(co_node_t *node, uint16_t rpdo_number, void *user)
{
    (void)node;
    rt_services_pdo_received(user, rpdo_number);
}

static const co_node_indications_t node_indications = {
    .state_changed = on_node_state,
    .allow_operational = on_allow_operational,
    .reset = on_node_reset,
    .pdo_received = on_pdo_received,
};

static void on_membus_sent(co_line_t *from, const co_frame_t *frame, void *user)
{
    (void)user;
    rt_line_t *l = line_of(from);
    if (l->monitor) {
        rt_post(l, CO_EV_FRAME, 0, 1, 0, frame);
    }
}

/* ================================================================ thread: lines */

void rt_wake(co_rt_t *rt)
{
    const uint64_t one = 1;
    /* EAGAIN only when the counter is saturated: the thread wakes anyway. */
    ssize_t done = write(rt->wakefd, &one, sizeof one);
    (void)done;
}

/* Frames queued in rx but not yet shown to the monitor (any driver). */
static void post_new_rx(rt_line_t *l)
{
    uint32_t count = co_line_rx_count(&l->line);
    for (uint32_t i = l->rx_seen; i < count; i++) {
        rt_post(l, CO_EV_FRAME, 0, 0, 0, co_line_rx_at(&l->line, i));
    }
}

/* Process one line; returns when it needs to run again. */
static uint64_t line_step(rt_line_t *l, uint64_t now)
{
    if (l->monitor) {
        post_new_rx(l);
    }
    uint64_t next = co_line_process(&l->line, now);
    l->rx_seen = co_line_rx_count(&l->line);
    return l->rx_seen == 0 ? next : now;
}

static uint32_t transfer_buses(co_rt_t *rt)
{
    uint32_t moved = 0;
    for (int i = 0; i < rt->bus_count; i++) {
        moved += co_membus_transfer(&rt->buses[i]->bus, on_membus_sent, rt);
    }
    return moved;
}

/* Process every line; frames moved over a membus are processed in further
 * rounds, bounded so a chatty bus cannot starve the event loop. */
static uint64_t run_lines(co_rt_t *rt, uint64_t now)
{
    for (int round = 0; round < RT_TRANSFER_ROUNDS; round++) {
        uint64_t next = CO_TIME_NEVER;
        for (int i = 0; i < rt->line_count; i++) {
            next = min_u64(next, line_step(rt->lines[i], now));
        }
        if (transfer_buses(rt) == 0) {
            return next;
        }
    }
    return now;   /* frames still in flight: come back at once */
}

/* ================================================================ thread: commands */

static const char *command_name(int kind)
{
    static const char *const names[] = {
        "?", "NODE_CREATE", "NMT_SEND", "NMT_LOCAL", "HEARTBEAT_TIME",
        "HB_WATCH", "HB_UNWATCH", "ALLOW_OPERATIONAL", "SEND_FRAME"};
    return kind > 0 && kind < (int)(sizeof names / sizeof names[0]) ? names[kind] : names[0];
}

static int need_node(co_rt_t *rt, const rt_line_t *l, int kind)
{
    if (rt_has_node(l)) {
        return CO_RT_OK;
    }
    rt_set_error(rt, "line %d has no local node (%s needs one)", l->index, command_name(kind));
    return CO_RT_ERR_STATE;
}


/* Drop a defined OD and its store (the node did not come up with it). */
static void od_forget(rt_line_t *l)
{
    rt_od_drop_requests(l);
    rt_od_release(l);
    free(l->store_file);
    l->store_file = NULL;
    rt_app_store_free(l);
    rt_od_free_domains(l);
    l->has_od = false;
}

static void *heap_allocate(void *user, size_t size)
{
    (void)user;
    return malloc(size);
}

static void heap_release(void *user, void *memory, size_t size)
{
    (void)user;
    (void)size;
    free(memory);
}

const co_stack_allocator_t rt_heap = {heap_allocate, heap_release, NULL};

/* Seal the defined OD with the node-id and prepare its store backend. */
static int prepare_od(co_rt_t *rt, rt_line_t *l, uint8_t node_id,
                      co_stack_node_config_t *config)
{
    if (l->od.sealed) {
        rt_set_error(rt, "line %d: object dictionary already served by a node", l->index);
        return CO_RT_ERR_STATE;
    }
    if (!co_od_seal(&l->od, node_id)) {
        rt_set_error(rt, "line %d: OD entry 0x%04X:00 refused: an ARRAY/RECORD needs sub 0 "
                  "(UNSIGNED8)", l->index, l->od.refused_index);
        return CO_RT_ERR_ARGUMENT;
    }
    config->od = &l->od;
    if (l->store_path) {
        l->store_file = calloc(1, sizeof *l->store_file);
        if (!l->store_file || !co_store_file_init(l->store_file, l->store_path)) {
            rt_set_error(rt, "line %d: store %s cannot be used (no memory or path too long)",
                         l->index, l->store_path);
            return l->store_file ? CO_RT_ERR_ARGUMENT : CO_RT_ERR_NO_MEMORY;
        }
        config->store_backend = co_store_file_backend();
        config->store_user = l->store_file;
    } else if (l->app_store.enabled) {
        int status = rt_app_store_open(rt, l, &config->store_image_capacity);
        if (status != CO_RT_OK) {
            return status;
        }
        config->store_backend = &rt_app_store_backend;
        config->store_user = l;
    }
    return CO_RT_OK;
}

static int stack_error(co_rt_t *rt, const rt_line_t *l, co_stack_status_t status)
{
    co_stack_part_t part = co_stack_failed_part(&l->stack);
    const char *name = co_stack_part_name(part);
    switch (status) {
    case CO_STACK_ERR_NO_MEMORY:
        rt_set_error(rt, "line %d: no memory for the %s", l->index, name);
        return CO_RT_ERR_NO_MEMORY;
    case CO_STACK_ERR_OD:
        rt_set_error(rt, "line %d: the OD cannot be used by the %s", l->index, name);
        return CO_RT_ERR_ARGUMENT;
    case CO_STACK_ERR_TAKEN:
        rt_set_error(rt, "line %d: %s could not start (CAN-IDs or OD handler table taken)",
                     l->index, name);
        return CO_RT_ERR_FULL;
    default:
        rt_set_error(rt, "line %d: %s could not be set up (status %d)", l->index, name,
                     (int)status);
        return status == CO_STACK_ERR_ARGUMENT ? CO_RT_ERR_ARGUMENT : CO_RT_ERR_STATE;
    }
}

/* Hooks of the runtime on the node's OD: Python hears changed entries, and
 * network saves into an application store wait until it persisted. */
static int hook_od(co_rt_t *rt, rt_line_t *l)
{
    if (!co_od_subscribe(&l->od, 0x0000, 0, 0xFFFF, 0xFF, &od_observer, l) ||
        (l->app_store.enabled && !rt_app_store_hook(l))) {
        rt_set_error(rt, "line %d: object dictionary handler table full", l->index);
        return CO_RT_ERR_FULL;
    }
    return CO_RT_OK;
}

static int cmd_node_create(co_rt_t *rt, rt_line_t *l, const co_rt_command_t *cmd)
{
    if (rt_has_node(l)) {
        rt_set_error(rt, "line %d already has local node %u", l->index,
                     co_stack_node(&l->stack)->nmt.node_id);
        return CO_RT_ERR_STATE;
    }
    co_stack_node_config_t config = {.node_id = (uint8_t)cmd->a,
                                     .heartbeat_ms = (uint16_t)cmd->b,
                                     .ind = &node_indications,
                                     .user = l};
    int status = l->has_od ? prepare_od(rt, l, (uint8_t)cmd->a, &config) : CO_RT_OK;
    if (status == CO_RT_OK) {
        co_stack_status_t s = co_stack_node_init(&l->stack, &config);
        status = s == CO_STACK_OK ? CO_RT_OK : stack_error(rt, l, s);
    }
    if (status == CO_RT_OK && l->has_od) {
        status = hook_od(rt, l);
    }
    if (status != CO_RT_OK) {
        /* Leave the line as it was before the node: usable for a new try. */
        rt_services_node_detach(l);
        co_stack_node_deinit(&l->stack);
        if (l->has_od) {
            od_forget(l);
        }
        return status;
    }
    co_stack_boot(&l->stack);
    post_store_status(l);
    return CO_RT_OK;
}

static int cmd_queued(co_rt_t *rt, const rt_line_t *l, bool queued)
{
    if (queued) {
        return CO_RT_OK;
    }
    rt_set_error(rt, "line %d: tx queue full, frame not sent", l->index);
    return CO_RT_ERR_FULL;
}

static int cmd_hb_watch(co_rt_t *rt, rt_line_t *l, const co_rt_command_t *cmd)
{
    co_hb_config_result_t r = co_hb_consumer_watch(co_stack_hb_consumer(&l->stack), (uint8_t)cmd->a, (uint16_t)cmd->b);
    if (r == CO_HB_CONFIG_OK) {
        return CO_RT_OK;
    }
    rt_set_error(rt, "line %d: cannot watch node %u (heartbeat config result %d)", l->index,
              (unsigned)cmd->a, (int)r);
    return r == CO_HB_CONFIG_NO_ROOM ? CO_RT_ERR_FULL : CO_RT_ERR_ARGUMENT;
}

/* Consumer entries that mirror 0x1016 sub 1.. of the local node's OD. */
static uint8_t od_consumer_entries(const rt_line_t *l)
{
    uint8_t count = 0;
    if (rt_has_node(l) && l->has_od) {
        co_od_get_u8(&l->od, 0x1016, 0, &count);
    }
    return count;
}

/* Python stops watching: entries that mirror 0x1016 belong to the OD and
 * keep monitoring (the line just stops telling Python). */
static void hb_unwatch(rt_line_t *l, uint8_t node_id)
{
    for (uint8_t i = od_consumer_entries(l); i < co_stack_hb_consumer(&l->stack)->capacity; i++) {
        if (co_stack_hb_consumer(&l->stack)->entries[i].node_id == node_id) {
            co_hb_consumer_set_entry(co_stack_hb_consumer(&l->stack), i, 0);
        }
    }
}

static int apply_to_line(co_rt_t *rt, rt_line_t *l, const co_rt_command_t *cmd)
{
    co_nmt_t *local = rt_has_node(l) ? &co_stack_node(&l->stack)->nmt : NULL;
    switch (cmd->kind) {
    case CO_CMD_NODE_CREATE:
        return cmd_node_create(rt, l, cmd);
    case CO_CMD_NMT_SEND:
        return cmd_queued(rt, l, co_nmt_master_send(&l->line, local, (co_nmt_command_t)cmd->a,
                                                    (uint8_t)cmd->b, cmd->c != 0));
    case CO_CMD_NMT_LOCAL:
        if (local) {
            co_nmt_apply(local, (co_nmt_command_t)cmd->a);
        }
        return need_node(rt, l, cmd->kind);
    case CO_CMD_HEARTBEAT_TIME:
        if (local) {
            co_node_set_heartbeat(co_stack_node(&l->stack), (uint16_t)cmd->a);
        }
        return need_node(rt, l, cmd->kind);
    case CO_CMD_HB_WATCH:
        return cmd_hb_watch(rt, l, cmd);
    case CO_CMD_HB_UNWATCH:
        hb_unwatch(l, (uint8_t)cmd->a);
        return CO_RT_OK;
    case CO_CMD_ALLOW_OPERATIONAL:
        l->allow_operational = cmd->a != 0;
        return CO_RT_OK;
    case CO_CMD_SEND_FRAME:
        return cmd_queued(rt, l, co_line_send_raw(&l->line, &cmd->frame));
    default:
        return CO_RT_ERR_ARGUMENT;   /* validated in co_rt_command */
    }
}

static void apply_command(co_rt_t *rt, const co_rt_command_t *cmd, uint64_t now)
{
    rt_line_t *l = rt->lines[cmd->line];
    /* The core reads the line's clock when arming timers: bring it to now. */
    line_step(l, now);
    int status = apply_to_line(rt, l, cmd);
    if (status != CO_RT_OK) {
        rt_post(l, CO_EV_COMMAND_FAILED, 0, (uint32_t)cmd->kind, (uint32_t)-status, NULL);
    }
}

/* Apply what is in the mailbox now (later commands wait for the next turn). */
static void apply_mailbox(co_rt_t *rt, uint64_t now)
{
    co_rt_command_t chunk[RT_MAIL_CHUNK];
    for (uint32_t budget = RT_MAILBOX_SIZE; budget > 0;) {
        uint32_t n = 0;
        pthread_mutex_lock(&rt->mail.lock);
        for (; n < RT_MAIL_CHUNK && n < budget && rt->mail.count > 0; n++) {
            chunk[n] = rt->mail.ring[rt->mail.head];
            rt->mail.head = (rt->mail.head + 1) % RT_MAILBOX_SIZE;
            rt->mail.count--;
        }
        pthread_mutex_unlock(&rt->mail.lock);
        if (n == 0) {
            return;
        }
        for (uint32_t i = 0; i < n; i++) {
            apply_command(rt, &chunk[i], now);
        }
        budget -= n;
    }
}

/* ================================================================ thread: socketcan */

static bool socket_watch(co_rt_t *rt, rt_line_t *l, int op, bool want_out)
{
    struct epoll_event ev = {.events = EPOLLIN | (want_out ? EPOLLOUT : 0u),
                             .data.ptr = &l->sc.tag};
    return epoll_ctl(rt->epfd, op, l->sc.sock.fd, &ev) == 0;
}

/* The interface went away or down: report once, close, retry later. */
static void socket_down(rt_line_t *l)
{
    if (l->sc.down) {
        return;
    }
    co_sc_close(&l->sc.sock);   /* closing also leaves the epoll set */
    l->sc.down = true;
    l->sc.down_count++;
    l->sc.want_out = false;
    l->sc.retry_at = 0;
    l->sc.reopen_at = co_rt_now_us() + RT_REOPEN_US;
    co_line_comm_event(&l->line, CO_COMM_IFACE_DOWN);
}

static void socket_reopen(co_rt_t *rt, rt_line_t *l, uint64_t now)
{
    char err[RT_ERROR_SIZE];
    co_sc_open_result_t r =
        co_sc_open(&l->sc.sock, l->channel, co_line_mode(&l->line), err, sizeof err);
    if (r == CO_SC_OPEN_OK && !socket_watch(rt, l, EPOLL_CTL_ADD, false)) {
        co_sc_close(&l->sc.sock);
        r = CO_SC_OPEN_SOCKET;
    }
    if (r != CO_SC_OPEN_OK) {
        l->sc.reopen_at = now + RT_REOPEN_US;
        return;
    }
    l->sc.down = false;
    co_line_comm_event(&l->line, CO_COMM_IFACE_UP);
}

static void reopen_sockets(co_rt_t *rt, uint64_t now)
{
    for (int i = 0; i < rt->line_count; i++) {
        rt_line_t *l = rt->lines[i];
        if (l->driver == CO_DRIVER_SOCKETCAN && l->sc.down && now >= l->sc.reopen_at) {
            socket_reopen(rt, l, now);
        }
    }
}

static void socket_read(rt_line_t *l)
{
    co_sc_rx_t items[CO_SC_BATCH];
    uint32_t room;
    /* Read only what rx can hold: the rest waits in the socket buffer. */
    while ((room = co_line_rx_free(&l->line)) > 0) {
        unsigned got = 0;
        co_sc_io_t r = co_sc_read(&l->sc.sock, items, room < CO_SC_BATCH ? room : CO_SC_BATCH,
                                  &got);
        for (unsigned i = 0; i < got; i++) {
            for (uint8_t e = 0; e < items[i].event_count; e++) {
                co_line_comm_event(&l->line, items[i].events[e]);
            }
            if (items[i].has_frame) {
                co_line_receive(&l->line, &items[i].frame);
            }
        }
        if (r == CO_SC_FAILED) {
            socket_down(l);   /* reopening cures whatever broke the socket */
        }
        if (r != CO_SC_DONE) {
            return;
        }
    }
}

static void socket_ready(co_rt_t *rt, rt_line_t *l, uint32_t events)
{
    if (l->sc.down) {
        return;
    }
    if ((events & EPOLLERR) && co_sc_errno_is_iface_down(co_sc_take_socket_error(&l->sc.sock))) {
        socket_down(l);
        return;
    }
    if ((events & EPOLLOUT) && l->sc.want_out) {
        l->sc.want_out = false;
        socket_watch(rt, l, EPOLL_CTL_MOD, false);
    }
    if (events & EPOLLIN) {
        socket_read(l);
    }
}

/* Copy up to max frames from the head of the tx queue without taking them:
 * they leave the queue only once the kernel accepted them. */
static unsigned peek_tx(const co_line_t *line, co_frame_t *out, unsigned max)
{
    uint32_t count = co_line_tx_count(line);
    unsigned n = 0;
    for (; n < max && n < count; n++) {
        out[n] = *co_line_tx_at(line, n);
    }
    return n;
}

static void take_sent(rt_line_t *l, unsigned sent)
{
    co_frame_t frame;
    for (unsigned i = 0; i < sent && co_line_tx_pop(&l->line, &frame); i++) {
        if (l->monitor) {
            rt_post(l, CO_EV_FRAME, 0, 1, 0, &frame);
        }
    }
}

static uint64_t wait_for_room(co_rt_t *rt, rt_line_t *l, uint64_t now)
{
    if (l->sc.sock.last_errno == ENOBUFS) {
        l->sc.retry_at = now + RT_NOBUFS_RETRY_US;
        return l->sc.retry_at;
    }
    l->sc.want_out = true;
    socket_watch(rt, l, EPOLL_CTL_MOD, true);
    return CO_TIME_NEVER;
}

/* A write failed: a frame the kernel refuses is dropped and reported (it
 * would block the queue forever); anything else closes the socket. Returns
 * false when the socket went down. */
static bool handle_write_error(rt_line_t *l)
{
    int err = l->sc.sock.last_errno;
    if (err != EINVAL && err != EMSGSIZE && err != EPERM) {
        socket_down(l);
        return false;
    }
    co_frame_t refused;
    co_line_tx_pop(&l->line, &refused);
    l->sc.tx_refused++;
    co_line_comm_event(&l->line, CO_COMM_TX_OVERFLOW);
    return true;
}

/* Send what the line queued; returns when to try again. */
static uint64_t flush_socket(co_rt_t *rt, rt_line_t *l, uint64_t now)
{
    rt_socket_t *s = &l->sc;
    if (s->down) {
        return s->reopen_at;
    }
    if (s->want_out) {
        return CO_TIME_NEVER;
    }
    if (now < s->retry_at) {
        return s->retry_at;
    }
    co_frame_t batch[CO_SC_BATCH];
    unsigned n;
    while ((n = peek_tx(&l->line, batch, CO_SC_BATCH)) > 0) {
        unsigned sent = 0;
        co_sc_io_t r = co_sc_write(&s->sock, batch, n, &sent);
        take_sent(l, sent);
        if (r == CO_SC_WOULD_BLOCK) {
            return wait_for_room(rt, l, now);
        }
        if (r == CO_SC_FAILED && !handle_write_error(l)) {
            return s->reopen_at;
        }
    }
    return CO_TIME_NEVER;
}

/* ================================================================ thread: host */

static void flush_host(rt_line_t *l)
{
    if (co_line_tx_count(&l->line) == 0) {
        return;
    }
    rt_host_t *h = &l->host;
    co_frame_t frame;
    uint32_t moved = 0;
    pthread_mutex_lock(&h->lock);
    while (!co_queue_is_full(&h->out) && co_line_tx_pop(&l->line, &frame)) {
        co_queue_push(&h->out, &frame);
        moved++;
        if (l->monitor) {
            rt_post(l, CO_EV_FRAME, 0, 1, 0, &frame);
        }
    }
    h->stalled = co_line_tx_count(&l->line) != 0;
    if (moved > 0 && h->waiters > 0) {
        pthread_cond_broadcast(&h->ready);
    }
    pthread_mutex_unlock(&h->lock);
}

/* ================================================================ thread: loop */

static uint64_t flush_drivers(co_rt_t *rt, uint64_t now)
{
    uint64_t next = CO_TIME_NEVER;
    for (int i = 0; i < rt->line_count; i++) {
        rt_line_t *l = rt->lines[i];
        if (l->driver == CO_DRIVER_SOCKETCAN) {
            next = min_u64(next, flush_socket(rt, l, now));
        } else if (l->driver == CO_DRIVER_HOST) {
            flush_host(l);
        }
    }
    return next;
}

static void arm_timer(co_rt_t *rt, uint64_t deadline, uint64_t now)
{
    /* A timer armed at or before the deadline stays: at worst it fires early
     * and that turn arms the right one. Saves a syscall per turn while a
     * transfer pushes its timeout later with every frame. */
    if (rt->armed_us <= deadline && rt->armed_us > now) {
        return;
    }
    struct itimerspec spec;
    memset(&spec, 0, sizeof spec);
    if (deadline != CO_TIME_NEVER) {
        uint64_t at = deadline > now ? deadline : now;
        spec.it_value.tv_sec = (time_t)(at / 1000000u);
        spec.it_value.tv_nsec = (long)(at % 1000000u) * 1000L;
        if (spec.it_value.tv_sec == 0 && spec.it_value.tv_nsec == 0) {
            spec.it_value.tv_nsec = 1;   /* zero would disarm */
        }
    }
    timerfd_settime(rt->timerfd, TFD_TIMER_ABSTIME, &spec, NULL);
    rt->armed_us = deadline;
}

void rt_kick(co_rt_t *rt)
{
    if (rt->stopping || !rt->started) {
        return;
    }
    uint64_t now = co_rt_now_us();
    uint64_t next = CO_TIME_NEVER;
    bool wake = false;
    for (int i = 0; i < rt->line_count; i++) {
        rt_line_t *l = rt->lines[i];
        if (l->driver == CO_DRIVER_SOCKETCAN) {
            next = min_u64(next, flush_socket(rt, l, now));
        } else if (co_line_tx_count(&l->line) != 0) {
            wake = true;
        }
        next = min_u64(next, co_timer_list_next(co_line_timers(&l->line)));
    }
    /* only ever earlier: the thread recomputes everything at its next turn */
    if (next < rt->armed_us) {
        arm_timer(rt, next, now);
    }
    if (wake) {
        rt_wake(rt);
    }
}

void rt_transfer_ended(co_rt_t *rt)
{
    pthread_mutex_lock(&rt->done_lock);
    rt->done_gen++;
    pthread_cond_broadcast(&rt->done_ready);
    pthread_mutex_unlock(&rt->done_lock);
}

uint64_t rt_transfer_generation(co_rt_t *rt)
{
    pthread_mutex_lock(&rt->done_lock);
    uint64_t gen = rt->done_gen;
    pthread_mutex_unlock(&rt->done_lock);
    return gen;
}

bool rt_wait_transfer_end(co_rt_t *rt, uint64_t gen, int timeout_ms)
{
    struct timespec deadline = deadline_after_ms(timeout_ms > 0 ? timeout_ms : 0);
    pthread_mutex_lock(&rt->done_lock);
    while (rt->done_gen == gen && !rt->done_closed &&
           wait_step(&rt->done_ready, &rt->done_lock, timeout_ms, &deadline)) {
    }
    bool changed = rt->done_gen != gen;
    pthread_mutex_unlock(&rt->done_lock);
    return changed;
}

static void iterate(co_rt_t *rt)
{
    uint64_t now = co_rt_now_us();
    reopen_sockets(rt, now);
    apply_mailbox(rt, now);
    uint64_t next = run_lines(rt, now);
    next = min_u64(next, flush_drivers(rt, now));
    /* Sending may have armed timers (a service told of free tx space). */
    for (int i = 0; i < rt->line_count; i++) {
        next = min_u64(next, co_timer_list_next(co_line_timers(&rt->lines[i]->line)));
    }
    arm_timer(rt, next, now);
}

static void drain_fd(int fd)
{
    uint64_t value;
    ssize_t done = read(fd, &value, sizeof value);
    (void)done;
}

static void handle_ready(co_rt_t *rt, const struct epoll_event *ev)
{
    const rt_tag_t *tag = ev->data.ptr;
    switch (tag->kind) {
    case TAG_WAKE:
        drain_fd(rt->wakefd);
        break;
    case TAG_TIMER:
        drain_fd(rt->timerfd);
        rt->armed_us = CO_TIME_NEVER;
        break;
    case TAG_SOCKET:
        socket_ready(rt, tag->line, ev->events);
        break;
    default:
        break;
    }
}

static void *thread_main(void *arg)
{
    co_rt_t *rt = arg;
    struct epoll_event ready[RT_EPOLL_BATCH];
    pthread_mutex_lock(&rt->lock);
    while (!rt->stopping) {
        iterate(rt);
        pthread_mutex_unlock(&rt->lock);
        int n = epoll_wait(rt->epfd, ready, RT_EPOLL_BATCH, -1);
        pthread_mutex_lock(&rt->lock);
        rt->wakeups += n > 0;
        for (int i = 0; i < n; i++) {
            handle_ready(rt, &ready[i]);
        }
    }
    pthread_mutex_unlock(&rt->lock);
    return NULL;
}

/* ================================================================ lifecycle */

static bool watch_fd(co_rt_t *rt, int fd, rt_tag_t *tag)
{
    struct epoll_event ev = {.events = EPOLLIN, .data.ptr = tag};
    return epoll_ctl(rt->epfd, EPOLL_CTL_ADD, fd, &ev) == 0;
}

static void close_fd(int fd)
{
    if (fd >= 0) {
        close(fd);
    }
}

static void line_free(rt_line_t *l)
{
    /* the services first: their deinit still sees the OD and the domains */
    rt_client_free(l);
    co_stack_deinit(&l->stack);
    co_sc_close(&l->sc.sock);
    pthread_mutex_destroy(&l->host.lock);
    pthread_cond_destroy(&l->host.ready);
    free(l->host.slots);
    free(l->od_entries);
    free(l->od_pool);
    free(l->store_path);
    free(l->store_file);
    rt_app_store_free(l);
    rt_od_free_domains(l);
    free(l->rx_slots);
    free(l->tx_slots);
    free(l);
}

static void rt_destroy(co_rt_t *rt)
{
    for (int i = 0; i < rt->line_count; i++) {
        line_free(rt->lines[i]);
    }
    for (int i = 0; i < rt->bus_count; i++) {
        free(rt->buses[i]);
    }
    close_fd(rt->epfd);
    close_fd(rt->wakefd);
    close_fd(rt->timerfd);
    free(rt->events.ring);
    pthread_mutex_destroy(&rt->events.lock);
    pthread_cond_destroy(&rt->events.ready);
    pthread_mutex_destroy(&rt->mail.lock);
    pthread_mutex_destroy(&rt->done_lock);
    pthread_cond_destroy(&rt->done_ready);
    pthread_mutex_destroy(&rt->error_lock);
    pthread_mutex_destroy(&rt->lock);
    pthread_mutex_destroy(&rt->life_lock);
    free(rt);
}

static bool open_fds(co_rt_t *rt)
{
    rt->epfd = epoll_create1(EPOLL_CLOEXEC);
    rt->wakefd = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
    rt->timerfd = timerfd_create(CLOCK_MONOTONIC, TFD_NONBLOCK | TFD_CLOEXEC);
    rt->wake_tag = (rt_tag_t){TAG_WAKE, NULL};
    rt->timer_tag = (rt_tag_t){TAG_TIMER, NULL};
    return rt->epfd >= 0 && rt->wakefd >= 0 && rt->timerfd >= 0 &&
           watch_fd(rt, rt->wakefd, &rt->wake_tag) && watch_fd(rt, rt->timerfd, &rt->timer_tag);
}

co_rt_t *co_rt_new(uint32_t event_capacity)
{
    if (event_capacity > RT_MAX_EVENT_CAPACITY) {
        return NULL;
    }
    co_rt_t *rt = calloc(1, sizeof *rt);
    if (!rt) {
        return NULL;
    }
    pthread_mutex_init(&rt->life_lock, NULL);
    pthread_mutex_init(&rt->lock, NULL);
    pthread_mutex_init(&rt->error_lock, NULL);
    pthread_mutex_init(&rt->mail.lock, NULL);
    pthread_mutex_init(&rt->events.lock, NULL);
    monotonic_cond_init(&rt->events.ready);
    pthread_mutex_init(&rt->done_lock, NULL);
    monotonic_cond_init(&rt->done_ready);
    rt->epfd = rt->wakefd = rt->timerfd = -1;
    rt->armed_us = CO_TIME_NEVER;
    rt->events.capacity = event_capacity ? event_capacity : RT_DEFAULT_EVENTS;
    rt->events.ring = calloc(rt->events.capacity, sizeof *rt->events.ring);
    if (!rt->events.ring || !open_fds(rt)) {
        rt_destroy(rt);
        return NULL;
    }
    return rt;
}

int co_rt_start(co_rt_t *rt)
{
    if (!rt) {
        return CO_RT_ERR_ARGUMENT;
    }
    int status = CO_RT_OK;
    pthread_mutex_lock(&rt->life_lock);
    if (rt->closed) {
        status = CO_RT_ERR_CLOSED;
    } else if (!rt->started) {
        /* Signals belong to the application's threads (Python's main one). */
        sigset_t all, previous;
        sigfillset(&all);
        pthread_sigmask(SIG_SETMASK, &all, &previous);
        int err = pthread_create(&rt->thread, NULL, thread_main, rt);
        pthread_sigmask(SIG_SETMASK, &previous, NULL);
        if (err != 0) {
            rt_set_error(rt, "cannot start the runtime thread: %s", strerror(err));
            status = CO_RT_ERR_NO_MEMORY;
        }
        rt->started = err == 0;
    }
    pthread_mutex_unlock(&rt->life_lock);
    return status;
}

/* Wake everybody blocked in wait_events / host_transmit with CLOSED. */
static void close_waiters(co_rt_t *rt)
{
    pthread_mutex_lock(&rt->done_lock);
    rt->done_closed = true;
    pthread_cond_broadcast(&rt->done_ready);
    pthread_mutex_unlock(&rt->done_lock);
    pthread_mutex_lock(&rt->events.lock);
    rt->events.closed = true;
    pthread_cond_broadcast(&rt->events.ready);
    pthread_mutex_unlock(&rt->events.lock);
    for (int i = 0; i < rt->line_count; i++) {
        rt_host_t *h = &rt->lines[i]->host;
        pthread_mutex_lock(&h->lock);
        h->closed = true;
        pthread_cond_broadcast(&h->ready);
        pthread_mutex_unlock(&h->lock);
    }
}

void co_rt_stop(co_rt_t *rt)
{
    if (!rt) {
        return;
    }
    pthread_mutex_lock(&rt->life_lock);
    if (!rt->closed) {
        rt->closed = true;
        pthread_mutex_lock(&rt->mail.lock);
        rt->mail.closed = true;
        pthread_mutex_unlock(&rt->mail.lock);
        pthread_mutex_lock(&rt->lock);
        rt->stopping = true;
        pthread_mutex_unlock(&rt->lock);
        if (rt->started) {
            rt_wake(rt);
            pthread_join(rt->thread, NULL);
        }
        close_waiters(rt);
    }
    pthread_mutex_unlock(&rt->life_lock);
}

static uint32_t waiter_count(co_rt_t *rt)
{
    pthread_mutex_lock(&rt->events.lock);
    uint32_t n = rt->events.waiters;
    pthread_mutex_unlock(&rt->events.lock);
    for (int i = 0; i < rt->line_count; i++) {
        rt_host_t *h = &rt->lines[i]->host;
        pthread_mutex_lock(&h->lock);
        n += h->waiters;
        pthread_mutex_unlock(&h->lock);
    }
    return n;
}

void co_rt_free(co_rt_t *rt)
{
    if (!rt) {
        return;
    }
    co_rt_stop(rt);
    /* Woken waiters are on their way out; let them leave before the memory goes. */
    while (waiter_count(rt) > 0) {
        nanosleep(&(struct timespec){0, 200000L}, NULL);
    }
    rt_destroy(rt);
}

/* ================================================================ add_line */

static int check_line_config(co_rt_t *rt, const co_rt_line_config_t *c)
{
    if (!c) {
        rt_set_error(rt, "no line configuration given");
    } else if (c->driver < CO_DRIVER_SOCKETCAN || c->driver > CO_DRIVER_HOST) {
        rt_set_error(rt, "driver %d unknown (1 socketcan, 2 membus, 3 host)", c->driver);
    } else if (c->mode != CO_MODE_CLASSIC && c->mode != CO_MODE_FD) {
        rt_set_error(rt, "mode %d unknown (0 classic, 1 fd)", c->mode);
    } else if (!c->channel || c->channel[0] == '\0') {
        rt_set_error(rt, "a line needs a channel name");
    } else if (strlen(c->channel) >= RT_CHANNEL_SIZE) {
        rt_set_error(rt, "channel name longer than %d characters", RT_CHANNEL_SIZE - 1);
    } else if (c->rx_queue > RT_MAX_QUEUE || c->tx_queue > RT_MAX_QUEUE) {
        rt_set_error(rt, "%s: queue of %u frames above the limit of %d", c->channel,
                  (unsigned)(c->rx_queue > RT_MAX_QUEUE ? c->rx_queue : c->tx_queue),
                  RT_MAX_QUEUE);
    } else {
        return CO_RT_OK;
    }
    return CO_RT_ERR_ARGUMENT;
}

static bool line_init_core(rt_line_t *l, const co_rt_line_config_t *c)
{
    uint32_t rx = c->rx_queue ? c->rx_queue : RT_DEFAULT_QUEUE;
    uint32_t tx = c->tx_queue ? c->tx_queue : RT_DEFAULT_QUEUE;
    l->rx_slots = calloc(rx, sizeof *l->rx_slots);
    l->tx_slots = calloc(tx, sizeof *l->tx_slots);
    l->host.slots = c->driver == CO_DRIVER_HOST ? calloc(tx, sizeof *l->host.slots) : NULL;
    if (!l->rx_slots || !l->tx_slots || (c->driver == CO_DRIVER_HOST && !l->host.slots)) {
        return false;
    }
    if (l->host.slots) {
        co_queue_init(&l->host.out, l->host.slots, tx);
    }
    co_line_config_t lc = {.mode = (co_mode_t)c->mode, .brs = c->brs != 0,
                           .rx_slots = l->rx_slots, .rx_capacity = rx,
                           .tx_slots = l->tx_slots, .tx_capacity = tx};
    co_line_init(&l->line, &lc);
    /* Watched PDO frames are offered before any service takes them. */
    if (!rt_services_line_watch(l)) {
        return false;
    }
    co_stack_line_config_t config = {
        .guarded_nodes = c->mode == CO_MODE_CLASSIC ? RT_GUARD_NODES : 0,
        .ind = &rt_services_indications,
        .user = l};
    /* Every line watches boot-ups and heartbeats, local node or not. */
    return co_stack_init(&l->stack, &l->line, &config, rt_heap) == CO_STACK_OK &&
           rt_services_line_init(l);
}

static rt_line_t *line_new(co_rt_t *rt, const co_rt_line_config_t *c)
{
    rt_line_t *l = calloc(1, sizeof *l);
    if (!l) {
        return NULL;
    }
    pthread_mutex_init(&l->host.lock, NULL);
    monotonic_cond_init(&l->host.ready);
    co_sc_init(&l->sc.sock);
    l->rt = rt;
    l->index = -1;
    l->driver = c->driver;
    l->monitor = c->monitor != 0;
    l->allow_operational = true;
    l->sc.tag = (rt_tag_t){TAG_SOCKET, l};
    snprintf(l->channel, sizeof l->channel, "%s", c->channel);
    if (!line_init_core(l, c)) {
        line_free(l);
        return NULL;
    }
    return l;
}

static int open_socketcan(co_rt_t *rt, rt_line_t *l)
{
    char err[RT_ERROR_SIZE];
    switch (co_sc_open(&l->sc.sock, l->channel, co_line_mode(&l->line), err, sizeof err)) {
    case CO_SC_OPEN_OK:
        return CO_RT_OK;
    case CO_SC_OPEN_NO_INTERFACE:
        rt_set_error(rt, "%s", err);
        return CO_RT_ERR_NO_INTERFACE;
    case CO_SC_OPEN_MTU:
        rt_set_error(rt, "%s", err);
        return CO_RT_ERR_MTU;
    case CO_SC_OPEN_DOWN:
        rt_set_error(rt, "%s", err);
        return CO_RT_ERR_STATE;
    case CO_SC_OPEN_SOCKET:
        rt_set_error(rt, "%s", err);
        return CO_RT_ERR_SOCKET;
    default:
        rt_set_error(rt, "%s", err);
        return CO_RT_ERR_ARGUMENT;
    }
}

static rt_bus_t *find_bus(co_rt_t *rt, const char *name)
{
    for (int i = 0; i < rt->bus_count; i++) {
        if (strcmp(rt->buses[i]->name, name) == 0) {
            return rt->buses[i];
        }
    }
    return NULL;
}

static int new_bus(co_rt_t *rt, const rt_line_t *l, rt_bus_t **out)
{
    if (rt->bus_count == RT_MAX_BUSES) {
        rt_set_error(rt, "membus %s: already %d buses in this runtime", l->channel, RT_MAX_BUSES);
        return CO_RT_ERR_FULL;
    }
    rt_bus_t *bus = calloc(1, sizeof *bus);
    if (!bus) {
        return CO_RT_ERR_NO_MEMORY;
    }
    snprintf(bus->name, sizeof bus->name, "%s", l->channel);
    bus->mode = co_line_mode(&l->line);
    co_membus_init(&bus->bus);
    rt->buses[rt->bus_count++] = bus;
    *out = bus;
    return CO_RT_OK;
}

/* Under rt->lock: join (or create) the named in-process bus. */
static int join_membus(co_rt_t *rt, rt_line_t *l)
{
    static const char *const mode_names[] = {"classic", "fd"};
    rt_bus_t *bus = find_bus(rt, l->channel);
    int status = bus ? CO_RT_OK : new_bus(rt, l, &bus);
    if (status != CO_RT_OK) {
        return status;
    }
    if (bus->mode != co_line_mode(&l->line)) {
        rt_set_error(rt, "membus %s: open in %s mode, a %s line cannot join it", bus->name,
                  mode_names[bus->mode], mode_names[co_line_mode(&l->line)]);
        return CO_RT_ERR_MODE;
    }
    if (!co_membus_attach(&bus->bus, &l->line)) {
        rt_set_error(rt, "membus %s: already %d lines", bus->name, CO_MEMBUS_MAX_LINES);
        return CO_RT_ERR_FULL;
    }
    return CO_RT_OK;
}

/* Under rt->lock: hook the line into its driver and publish it. */
static int register_line(co_rt_t *rt, rt_line_t *l)
{
    if (rt->line_count == RT_MAX_LINES) {
        rt_set_error(rt, "%s: already %d lines in this runtime", l->channel, RT_MAX_LINES);
        return CO_RT_ERR_FULL;
    }
    int status = CO_RT_OK;
    if (l->driver == CO_DRIVER_MEMBUS) {
        status = join_membus(rt, l);
    } else if (l->driver == CO_DRIVER_SOCKETCAN && !socket_watch(rt, l, EPOLL_CTL_ADD, false)) {
        rt_set_error(rt, "%s: epoll_ctl failed: %s", l->channel, strerror(errno));
        status = CO_RT_ERR_SOCKET;
    }
    if (status != CO_RT_OK) {
        return status;
    }
    l->index = rt->line_count;
    rt->lines[l->index] = l;
    __atomic_store_n(&rt->line_count, l->index + 1, __ATOMIC_RELEASE);
    return CO_RT_OK;
}

int co_rt_add_line(co_rt_t *rt, const co_rt_line_config_t *config)
{
    if (!rt) {
        return CO_RT_ERR_ARGUMENT;
    }
    int status = check_line_config(rt, config);
    if (status != CO_RT_OK) {
        return status;
    }
    rt_line_t *l = line_new(rt, config);
    if (!l) {
        rt_set_error(rt, "%s: out of memory for the line's queues", config->channel);
        return CO_RT_ERR_NO_MEMORY;
    }
    pthread_mutex_lock(&rt->life_lock);
    status = rt->closed ? CO_RT_ERR_CLOSED : CO_RT_OK;
    if (status == CO_RT_OK && l->driver == CO_DRIVER_SOCKETCAN) {
        status = open_socketcan(rt, l);
    }
    if (status == CO_RT_OK) {
        pthread_mutex_lock(&rt->lock);
        status = register_line(rt, l);
        pthread_mutex_unlock(&rt->lock);
    }
    pthread_mutex_unlock(&rt->life_lock);
    if (status != CO_RT_OK) {
        line_free(l);
        return status;
    }
    rt_wake(rt);
    return l->index;
}

/* ================================================================ commands */

__attribute__((format(printf, 2, 3)))
int rt_argument_error(co_rt_t *rt, const char *fmt, ...)
{
    char text[RT_ERROR_SIZE];
    va_list args;
    va_start(args, fmt);
    vsnprintf(text, sizeof text, fmt, args);
    va_end(args);
    rt_set_error(rt, "%s", text);
    return CO_RT_ERR_ARGUMENT;
}

static int check_node_id(co_rt_t *rt, uint32_t node_id, bool all_allowed)
{
    uint32_t lowest = all_allowed ? 0 : 1;
    if (node_id >= lowest && node_id <= 127) {
        return CO_RT_OK;
    }
    return rt_argument_error(rt, "node-id %u outside %u..127%s", (unsigned)node_id,
                          (unsigned)lowest, all_allowed ? " (0 = all nodes)" : "");
}

static int check_ms(co_rt_t *rt, const char *what, uint32_t ms)
{
    if (ms <= 65535u) {
        return CO_RT_OK;
    }
    return rt_argument_error(rt, "%s %u ms above 65535", what, (unsigned)ms);
}

static int check_nmt_command(co_rt_t *rt, uint32_t command)
{
    if (command <= 0xFFu && co_nmt_command_is_valid((uint8_t)command)) {
        return CO_RT_OK;
    }
    return rt_argument_error(rt, "NMT command 0x%02X unknown (0x01 start, 0x02 stop, "
                              "0x80 pre-operational, 0x81 reset node, 0x82 reset communication)",
                          (unsigned)command);
}

static int check_frame(co_rt_t *rt, const rt_line_t *l, const co_frame_t *f)
{
    if (!co_frame_is_valid(f)) {
        return rt_argument_error(rt, "malformed frame (id 0x%X, len %u, flags 0x%02X)",
                              (unsigned)f->id, f->len, f->flags);
    }
    if ((f->flags & CO_FRAME_FD) && co_line_mode(&l->line) == CO_MODE_CLASSIC) {
        return rt_argument_error(rt, "line %d is classic: it cannot send FD frames", l->index);
    }
    return CO_RT_OK;
}

static int first_error(int a, int b) { return a != CO_RT_OK ? a : b; }

static int check_command_args(co_rt_t *rt, const rt_line_t *l, const co_rt_command_t *cmd)
{
    switch (cmd->kind) {
    case CO_CMD_NODE_CREATE:
        return first_error(check_node_id(rt, cmd->a, false),
                           check_ms(rt, "heartbeat time", cmd->b));
    case CO_CMD_NMT_SEND:
        return first_error(check_nmt_command(rt, cmd->a), check_node_id(rt, cmd->b, true));
    case CO_CMD_NMT_LOCAL:
        return check_nmt_command(rt, cmd->a);
    case CO_CMD_HEARTBEAT_TIME:
        return check_ms(rt, "heartbeat time", cmd->a);
    case CO_CMD_HB_WATCH:
        return first_error(check_node_id(rt, cmd->a, false),
                           check_ms(rt, "heartbeat consumer time", cmd->b));
    case CO_CMD_HB_UNWATCH:
        return check_node_id(rt, cmd->a, false);
    case CO_CMD_ALLOW_OPERATIONAL:
        return cmd->a <= 1 ? CO_RT_OK
                           : rt_argument_error(rt, "allow-operational flag %u is not 0 or 1",
                                            (unsigned)cmd->a);
    case CO_CMD_SEND_FRAME:
        return check_frame(rt, l, &cmd->frame);
    default:
        return rt_argument_error(rt, "command kind %d unknown", cmd->kind);
    }
}

static int validate_command(co_rt_t *rt, const co_rt_command_t *cmd)
{
    int count = __atomic_load_n(&rt->line_count, __ATOMIC_ACQUIRE);
    if (cmd->line < 0 || cmd->line >= count) {
        return rt_argument_error(rt, "line %d does not exist (%d open)", cmd->line, count);
    }
    return check_command_args(rt, rt->lines[cmd->line], cmd);
}

/* Creating the local node runs at once under the lock (the thread is not
 * processing then): the caller learns of a refused OD or store right away,
 * and the node exists for OD access as soon as the call returns. */
static int node_create_now(co_rt_t *rt, const co_rt_command_t *cmd)
{
    rt_line_t *l = rt->lines[cmd->line];
    pthread_mutex_lock(&rt->lock);
    int status = CO_RT_ERR_CLOSED;
    if (!rt->stopping) {
        line_step(l, co_rt_now_us());
        status = cmd_node_create(rt, l, cmd);
    }
    pthread_mutex_unlock(&rt->lock);
    if (status == CO_RT_OK) {
        rt_wake(rt);
    }
    return status;
}

int co_rt_command(co_rt_t *rt, const co_rt_command_t *command)
{
    if (!rt || !command) {
        return CO_RT_ERR_ARGUMENT;
    }
    int status = validate_command(rt, command);
    if (status != CO_RT_OK) {
        return status;
    }
    if (command->kind == CO_CMD_NODE_CREATE) {
        return node_create_now(rt, command);
    }
    rt_mailbox_t *m = &rt->mail;
    pthread_mutex_lock(&m->lock);
    if (m->closed) {
        status = CO_RT_ERR_CLOSED;
    } else if (m->count == RT_MAILBOX_SIZE) {
        status = CO_RT_ERR_FULL;
    } else {
        m->ring[(m->head + m->count) % RT_MAILBOX_SIZE] = *command;
        m->count++;
    }
    pthread_mutex_unlock(&m->lock);
    if (status == CO_RT_ERR_FULL) {
        rt_set_error(rt, "command mailbox full (%d commands pending)", RT_MAILBOX_SIZE);
    }
    if (status == CO_RT_OK) {
        rt_wake(rt);
    }
    return status;
}

/* ================================================================ host driver */

rt_line_t *rt_checked_line(co_rt_t *rt, int line, bool host_only)
{
    int count = __atomic_load_n(&rt->line_count, __ATOMIC_ACQUIRE);
    if (line < 0 || line >= count) {
        rt_argument_error(rt, "line %d does not exist (%d open)", line, count);
        return NULL;
    }
    rt_line_t *l = rt->lines[line];
    if (host_only && l->driver != CO_DRIVER_HOST) {
        rt_argument_error(rt, "line %d (%s) is not a host-driver line", line, l->channel);
        return NULL;
    }
    return l;
}

int co_rt_host_receive(co_rt_t *rt, int line, const co_frame_t *frame)
{
    rt_line_t *l = rt ? rt_checked_line(rt, line, true) : NULL;
    if (!l || !frame) {
        return CO_RT_ERR_ARGUMENT;
    }
    pthread_mutex_lock(&rt->lock);
    bool closed = rt->stopping;
    bool queued = !closed && co_line_receive(&l->line, frame);
    pthread_mutex_unlock(&rt->lock);
    if (closed) {
        return CO_RT_ERR_CLOSED;
    }
    if (!queued) {
        return CO_RT_ERR_FULL;   /* counted as rx overflow by the line */
    }
    rt_wake(rt);
    return CO_RT_OK;
}

int co_rt_host_transmit(co_rt_t *rt, int line, co_frame_t *frames, int max, int timeout_ms)
{
    rt_line_t *l = rt ? rt_checked_line(rt, line, true) : NULL;
    if (!l || !frames || max <= 0) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_host_t *h = &l->host;
    struct timespec deadline = deadline_after_ms(timeout_ms > 0 ? timeout_ms : 0);
    pthread_mutex_lock(&h->lock);
    h->waiters++;
    while (co_queue_is_empty(&h->out) && !h->closed &&
           wait_step(&h->ready, &h->lock, timeout_ms, &deadline)) {
    }
    int n = 0;
    while (n < max && co_queue_pop(&h->out, &frames[n])) {
        n++;
    }
    bool refill = n > 0 && h->stalled;
    int result = (n == 0 && h->closed) ? CO_RT_ERR_CLOSED : n;
    h->waiters--;
    pthread_mutex_unlock(&h->lock);
    if (refill) {
        rt_wake(rt);   /* the line has more frames waiting for room */
    }
    return result;
}

int co_rt_host_comm_event(co_rt_t *rt, int line, int event)
{
    rt_line_t *l = rt ? rt_checked_line(rt, line, true) : NULL;
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    if (event < CO_COMM_BUS_OFF || event > CO_COMM_BUS_OFF_RECOVERED) {
        return rt_argument_error(rt, "communication event %d unknown", event);
    }
    pthread_mutex_lock(&rt->lock);
    bool closed = rt->stopping;
    if (!closed) {
        co_line_comm_event(&l->line, (co_comm_event_t)event);
    }
    pthread_mutex_unlock(&rt->lock);
    return closed ? CO_RT_ERR_CLOSED : CO_RT_OK;
}

/* ================================================================ snapshots */

int co_rt_line_stats(co_rt_t *rt, int line, co_line_stats_t *out)
{
    rt_line_t *l = rt ? rt_checked_line(rt, line, false) : NULL;
    if (!l || !out) {
        return CO_RT_ERR_ARGUMENT;
    }
    pthread_mutex_lock(&rt->lock);
    *out = *co_line_stats(&l->line);
    pthread_mutex_unlock(&rt->lock);
    return CO_RT_OK;
}

int co_rt_driver_stats(co_rt_t *rt, int line, co_rt_driver_stats_t *out)
{
    rt_line_t *l = rt ? rt_checked_line(rt, line, false) : NULL;
    if (!l || !out) {
        return CO_RT_ERR_ARGUMENT;
    }
    pthread_mutex_lock(&rt->lock);
    const co_sc_stats_t *sc = &l->sc.sock.stats;
    *out = (co_rt_driver_stats_t){.kernel_drops = sc->kernel_drops,
                                  .error_frames = sc->error_frames,
                                  .tx_deferred = sc->tx_would_block,
                                  .tx_refused = l->sc.tx_refused,
                                  .iface_down = l->sc.down_count,
                                  .rx_frames = sc->rx_frames,
                                  .rx_calls = sc->rx_calls,
                                  .tx_frames = sc->tx_frames,
                                  .tx_calls = sc->tx_calls,
                                  .loop_wakeups = rt->wakeups};
    pthread_mutex_unlock(&rt->lock);
    pthread_mutex_lock(&l->host.lock);
    out->host_pending = co_queue_count(&l->host.out);
    pthread_mutex_unlock(&l->host.lock);
    return CO_RT_OK;
}

int co_rt_local_state(co_rt_t *rt, int line)
{
    rt_line_t *l = rt ? rt_checked_line(rt, line, false) : NULL;
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    pthread_mutex_lock(&rt->lock);
    int state = rt_has_node(l) ? (int)co_node_state(co_stack_node(&l->stack)) : CO_RT_ERR_STATE;
    pthread_mutex_unlock(&rt->lock);
    return state;
}

int co_rt_remote_state(co_rt_t *rt, int line, int node_id)
{
    rt_line_t *l = rt ? rt_checked_line(rt, line, false) : NULL;
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    if (node_id < 1 || node_id > 127) {
        return rt_argument_error(rt, "node-id %d outside 1..127", node_id);
    }
    pthread_mutex_lock(&rt->lock);
    int state = co_stack_hb_consumer(&l->stack)->last_state[node_id];
    pthread_mutex_unlock(&rt->lock);
    return state;
}
