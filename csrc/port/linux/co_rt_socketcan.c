/* Runtime: SocketCAN lines (Linux, under the epoll waiter only). The socket
 * sits in the thread's epoll set; reads take only what the line's rx queue
 * can hold, a frame leaves the tx queue only once the kernel took it, a
 * vanished or downed interface reports IFACE_DOWN and is re-opened every
 * RT_REOPEN_US. */
#define _GNU_SOURCE

#include "co_rt_internal.h"

#include <errno.h>
#include <stdio.h>
#include <string.h>
#include <sys/epoll.h>

void rt_socket_init(rt_line_t *l)
{
    co_sc_init(&l->sc.sock);
    l->sc.tag = (rt_tag_t){TAG_SOCKET, l};
}

void rt_socket_close(rt_line_t *l)
{
    co_sc_close(&l->sc.sock);
}

static int open_status(co_rt_t *rt, co_sc_open_result_t result, const char *err)
{
    switch (result) {
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

int rt_socket_open(co_rt_t *rt, rt_line_t *l)
{
    char err[RT_ERROR_SIZE];
    return open_status(rt, co_sc_open(&l->sc.sock, l->channel, co_line_mode(&l->line), err,
                                      sizeof err), err);
}

int rt_socket_probe(co_rt_t *rt, const char *iface, co_mode_t mode)
{
    char err[RT_ERROR_SIZE];
    co_socketcan_t probe;
    co_sc_init(&probe);
    co_sc_open_result_t result = co_sc_open(&probe, iface, mode, err, sizeof err);
    co_sc_close(&probe);
    return open_status(rt, result, err);
}

static bool socket_watch(co_rt_t *rt, rt_line_t *l, int op, bool want_out)
{
    struct epoll_event ev = {.events = EPOLLIN | (want_out ? EPOLLOUT : 0u),
                             .data.ptr = &l->sc.tag};
    return epoll_ctl(rt->epoll.epfd, op, l->sc.sock.fd, &ev) == 0;
}

int rt_socket_register(co_rt_t *rt, rt_line_t *l)
{
    if (socket_watch(rt, l, EPOLL_CTL_ADD, false)) {
        return CO_RT_OK;
    }
    rt_set_error(rt, "%s: epoll_ctl failed: %s", l->channel, strerror(errno));
    return CO_RT_ERR_SOCKET;
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

void rt_socket_switch(co_rt_t *rt, rt_line_t *l, const char *iface)
{
    char err[RT_ERROR_SIZE];
    snprintf(l->channel, sizeof l->channel, "%s", iface);
    co_sc_close(&l->sc.sock);   /* closing also leaves the epoll set */
    l->sc.want_out = false;
    l->sc.retry_at = 0;
    if (co_sc_open(&l->sc.sock, iface, co_line_mode(&l->line), err, sizeof err) ==
            CO_SC_OPEN_OK && socket_watch(rt, l, EPOLL_CTL_ADD, false)) {
        if (l->sc.down) {
            l->sc.down = false;
            co_line_comm_event(&l->line, CO_COMM_IFACE_UP);
        }
        return;
    }
    if (l->sc.down) {
        l->sc.reopen_at = co_rt_now_us() + RT_REOPEN_US;   /* already told: retry iface */
        return;
    }
    socket_down(l);
}

void rt_socket_reopen_due(co_rt_t *rt, uint64_t now)
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

void rt_socket_ready(co_rt_t *rt, rt_line_t *l, uint32_t events)
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

uint64_t rt_socket_flush(co_rt_t *rt, rt_line_t *l, uint64_t now)
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
