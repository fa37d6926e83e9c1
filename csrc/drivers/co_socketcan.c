/* Linux SocketCAN driver (see co_socketcan.h). */
#define _GNU_SOURCE   /* recvmmsg, sendmmsg */

#include "canopenfd/co_socketcan.h"

#include <errno.h>
#include <net/if.h>
#include <net/if_arp.h>
#include <stdio.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <linux/sock_diag.h>

#ifndef SO_RXQ_OVFL
#define SO_RXQ_OVFL 40
#endif
#ifndef SO_MEMINFO
#define SO_MEMINFO 55
#endif

_Static_assert(CO_SC_NAME_SIZE == IFNAMSIZ, "CO_SC_NAME_SIZE must equal IFNAMSIZ");

/* Socket buffers large enough to ride out bursts while the runtime thread is
 * busy; the kernel caps SO_RCVBUF at rmem_max for unprivileged callers. */
enum { SC_BUFFER_BYTES = 4 * 1024 * 1024 };

void co_sc_init(co_socketcan_t *sc)
{
    memset(sc, 0, sizeof *sc);
    sc->fd = -1;
}

void co_sc_close(co_socketcan_t *sc)
{
    if (sc->fd >= 0) {
        close(sc->fd);
        sc->fd = -1;
    }
}

bool co_sc_errno_is_iface_down(int err)
{
    return err == ENETDOWN || err == ENODEV || err == ENXIO || err == EBADFD;
}

/* ------------------------------------------------------------ conversions */

bool co_sc_frame_from_kernel(const struct canfd_frame *k, size_t nbytes, co_frame_t *out)
{
    if ((k->can_id & CAN_ERR_FLAG) || (nbytes != CAN_MTU && nbytes != CANFD_MTU)) {
        return false;
    }
    memset(out, 0, sizeof *out);
    bool extended = (k->can_id & CAN_EFF_FLAG) != 0;
    out->id = k->can_id & (extended ? CAN_EFF_MASK : CAN_SFF_MASK);
    out->flags = extended ? CO_FRAME_EXT : 0;
    if (nbytes == CANFD_MTU) {
        out->flags |= CO_FRAME_FD;
        out->flags |= (k->flags & CANFD_BRS) ? CO_FRAME_BRS : 0;
        out->flags |= (k->flags & CANFD_ESI) ? CO_FRAME_ESI : 0;
        out->len = k->len <= CANFD_MAX_DLEN ? k->len : CANFD_MAX_DLEN;
    } else {
        out->flags |= (k->can_id & CAN_RTR_FLAG) ? CO_FRAME_RTR : 0;
        out->len = k->len <= CAN_MAX_DLEN ? k->len : CAN_MAX_DLEN;
    }
    /* A remote frame's length is the requested DLC; it carries no data. */
    if (!(out->flags & CO_FRAME_RTR)) {
        memcpy(out->data, k->data, out->len);
    }
    return true;
}

size_t co_sc_frame_to_kernel(const co_frame_t *frame, struct canfd_frame *k)
{
    if (!co_frame_is_valid(frame)) {
        return 0;
    }
    memset(k, 0, sizeof *k);
    k->can_id = frame->id;
    k->can_id |= (frame->flags & CO_FRAME_EXT) ? CAN_EFF_FLAG : 0;
    k->can_id |= (frame->flags & CO_FRAME_RTR) ? CAN_RTR_FLAG : 0;
    k->len = frame->len;
    if (!(frame->flags & CO_FRAME_RTR)) {
        memcpy(k->data, frame->data, frame->len);
    }
    if (!(frame->flags & CO_FRAME_FD)) {
        return CAN_MTU;   /* struct can_frame is the first CAN_MTU bytes */
    }
#ifdef CANFD_FDF
    k->flags = CANFD_FDF;
#endif
    k->flags |= (frame->flags & CO_FRAME_BRS) ? CANFD_BRS : 0;
    k->flags |= (frame->flags & CO_FRAME_ESI) ? CANFD_ESI : 0;
    return CANFD_MTU;
}

static uint8_t add_event(co_comm_event_t *out, uint8_t count, uint8_t max,
                         co_comm_event_t event)
{
    for (uint8_t i = 0; i < count; i++) {
        if (out[i] == event) {
            return count;
        }
    }
    if (count < max) {
        out[count++] = event;
    }
    return count;
}

/* Controller status byte (data[1] of a CAN_ERR_CRTL frame). */
static uint8_t controller_events(uint8_t status, co_comm_event_t *out, uint8_t n,
                                 uint8_t max)
{
    if (status & CAN_ERR_CRTL_RX_OVERFLOW) {
        n = add_event(out, n, max, CO_COMM_RX_OVERFLOW);
    }
    if (status & CAN_ERR_CRTL_TX_OVERFLOW) {
        n = add_event(out, n, max, CO_COMM_TX_OVERFLOW);
    }
    if (status & (CAN_ERR_CRTL_RX_WARNING | CAN_ERR_CRTL_TX_WARNING)) {
        n = add_event(out, n, max, CO_COMM_ERROR_WARNING);
    }
    if (status & (CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE)) {
        n = add_event(out, n, max, CO_COMM_ERROR_PASSIVE);
    }
#ifdef CAN_ERR_CRTL_ACTIVE
    if (status & CAN_ERR_CRTL_ACTIVE) {
        n = add_event(out, n, max, CO_COMM_ERROR_ACTIVE);
    }
#endif
    return n;
}

uint8_t co_sc_error_events(uint32_t can_id, const uint8_t data[8], co_comm_event_t *out,
                           uint8_t max)
{
    uint8_t n = 0;
    if (can_id & CAN_ERR_CRTL) {
        n = controller_events(data[1], out, n, max);
    }
    if (can_id & CAN_ERR_BUSOFF) {
        n = add_event(out, n, max, CO_COMM_BUS_OFF);
    }
    if (can_id & CAN_ERR_RESTARTED) {
        n = add_event(out, n, max, CO_COMM_BUS_OFF_RECOVERED);
    }
    return n;
}

/* ------------------------------------------------------------------- open */

/* Close, keep errno and write "<ifname>: <problem>" into err. */
static co_sc_open_result_t fail(co_socketcan_t *sc, co_sc_open_result_t result, char *err,
                                size_t err_size, const char *problem)
{
    sc->last_errno = errno;
    co_sc_close(sc);
    if (err && err_size > 0) {
        snprintf(err, err_size, "%s: %s", sc->ifname, problem);
    }
    return result;
}

/* fail() for problems that carry errno's text. */
static co_sc_open_result_t fail_errno(co_socketcan_t *sc, co_sc_open_result_t result,
                                      char *err, size_t err_size, const char *what)
{
    char problem[160];
    snprintf(problem, sizeof problem, "%s: %s", what, strerror(errno));
    return fail(sc, result, err, err_size, problem);
}

static void set_buffer(int fd, int force_option, int option)
{
    int bytes = SC_BUFFER_BYTES;
    /* The FORCE variants pass rmem_max/wmem_max but need CAP_NET_ADMIN. */
    if (setsockopt(fd, SOL_SOCKET, force_option, &bytes, sizeof bytes) != 0) {
        setsockopt(fd, SOL_SOCKET, option, &bytes, sizeof bytes);
    }
}

static bool set_options(int fd, co_mode_t mode)
{
    const int on = 1;
    const can_err_mask_t errors = CAN_ERR_MASK;
    if (mode == CO_MODE_FD &&
        setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FD_FRAMES, &on, sizeof on) != 0) {
        return false;
    }
    if (setsockopt(fd, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &errors, sizeof errors) != 0) {
        return false;
    }
    /* Optional: lets us report frames the socket buffer dropped. */
    setsockopt(fd, SOL_SOCKET, SO_RXQ_OVFL, &on, sizeof on);
    set_buffer(fd, SO_RCVBUFFORCE, SO_RCVBUF);
    set_buffer(fd, SO_SNDBUFFORCE, SO_SNDBUF);
    return true;
}

static bool mtu_fits(int mtu, co_mode_t mode)
{
    if (mode == CO_MODE_FD) {
        return mtu >= (int)CANFD_MTU;
    }
    return mtu == (int)CAN_MTU || mtu >= (int)CANFD_MTU;
}

/* Interface checks on the open socket; fills ifr's index on success. */
static co_sc_open_result_t check_interface(co_socketcan_t *sc, struct ifreq *ifr,
                                           char *err, size_t err_size)
{
    char problem[128];
    if (ioctl(sc->fd, SIOCGIFINDEX, ifr) != 0) {
        return errno == ENODEV
                   ? fail(sc, CO_SC_OPEN_NO_INTERFACE, err, err_size, "no such interface")
                   : fail_errno(sc, CO_SC_OPEN_SOCKET, err, err_size, "SIOCGIFINDEX");
    }
    int index = ifr->ifr_ifindex;
    if (ioctl(sc->fd, SIOCGIFHWADDR, ifr) == 0 && ifr->ifr_hwaddr.sa_family != ARPHRD_CAN) {
        return fail(sc, CO_SC_OPEN_NOT_CAN, err, err_size, "not a CAN interface");
    }
    if (ioctl(sc->fd, SIOCGIFMTU, ifr) != 0) {
        return fail_errno(sc, CO_SC_OPEN_SOCKET, err, err_size, "SIOCGIFMTU");
    }
    if (!mtu_fits(ifr->ifr_mtu, sc->mode)) {
        snprintf(problem, sizeof problem,
                 "MTU %d, an fd line needs MTU 72 (ip link set %s mtu 72)", ifr->ifr_mtu,
                 sc->ifname);
        return fail(sc, CO_SC_OPEN_MTU, err, err_size, problem);
    }
    if (ioctl(sc->fd, SIOCGIFFLAGS, ifr) == 0 && !(ifr->ifr_flags & IFF_UP)) {
        snprintf(problem, sizeof problem, "interface is down (ip link set %s up)",
                 sc->ifname);
        return fail(sc, CO_SC_OPEN_DOWN, err, err_size, problem);
    }
    ifr->ifr_ifindex = index;
    return CO_SC_OPEN_OK;
}

static co_sc_open_result_t open_socket(co_socketcan_t *sc, char *err, size_t err_size)
{
    sc->fd = socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
    if (sc->fd >= 0) {
        return CO_SC_OPEN_OK;
    }
    bool no_can = errno == EAFNOSUPPORT || errno == EPROTONOSUPPORT;
    return fail_errno(sc, CO_SC_OPEN_SOCKET, err, err_size,
                      no_can ? "cannot open a CAN socket (kernel without CAN support? "
                               "try modprobe can-raw)"
                             : "cannot open a CAN socket");
}

co_sc_open_result_t co_sc_open(co_socketcan_t *sc, const char *ifname, co_mode_t mode,
                               char *err, size_t err_size)
{
    co_sc_close(sc);
    size_t name_len = ifname ? strlen(ifname) : 0;
    snprintf(sc->ifname, sizeof sc->ifname, "%s", ifname ? ifname : "");
    sc->mode = mode;
    if (name_len == 0 || name_len >= IFNAMSIZ) {
        if (err && err_size > 0) {
            snprintf(err, err_size, "%s: interface name must have 1..%d characters",
                     ifname ? ifname : "", IFNAMSIZ - 1);
        }
        sc->last_errno = EINVAL;
        return CO_SC_OPEN_BAD_NAME;
    }
    /* Checked before the CAN socket so a typo reads as such on any kernel. */
    if (if_nametoindex(ifname) == 0 && errno == ENODEV) {
        return fail(sc, CO_SC_OPEN_NO_INTERFACE, err, err_size, "no such interface");
    }
    co_sc_open_result_t result = open_socket(sc, err, err_size);
    struct ifreq ifr;
    memset(&ifr, 0, sizeof ifr);
    memcpy(ifr.ifr_name, ifname, name_len);
    if (result == CO_SC_OPEN_OK) {
        result = check_interface(sc, &ifr, err, err_size);
    }
    if (result != CO_SC_OPEN_OK) {
        return result;
    }
    if (!set_options(sc->fd, mode)) {
        return fail_errno(sc, CO_SC_OPEN_SOCKET, err, err_size, "setsockopt");
    }
    struct sockaddr_can addr;
    memset(&addr, 0, sizeof addr);
    addr.can_family = AF_CAN;
    addr.can_ifindex = ifr.ifr_ifindex;
    if (bind(sc->fd, (struct sockaddr *)&addr, sizeof addr) != 0) {
        return fail_errno(sc, errno == ENODEV ? CO_SC_OPEN_NO_INTERFACE : CO_SC_OPEN_SOCKET,
                          err, err_size, "bind");
    }
    sc->drop_counter = 0;
    sc->backlog = false;
    sc->last_errno = 0;
    return CO_SC_OPEN_OK;
}

int co_sc_take_socket_error(co_socketcan_t *sc)
{
    int value = 0;
    socklen_t size = sizeof value;
    if (sc->fd < 0 || getsockopt(sc->fd, SOL_SOCKET, SO_ERROR, &value, &size) != 0) {
        return sc->fd < 0 ? EBADF : errno;
    }
    return value;
}

/* ------------------------------------------------------------------- read */

typedef union {
    char bytes[CMSG_SPACE(sizeof(uint32_t))];
    size_t align;   /* cmsghdr alignment */
} sc_control_t;

/* The socket's drop counter moved past what we reported: count and report
 * the difference once. Counters from older frames may lag behind. */
static void note_drops(co_socketcan_t *sc, uint32_t counter, co_sc_rx_t *item)
{
    uint32_t delta = counter - sc->drop_counter;
    if (delta == 0 || delta > UINT32_MAX / 2) {
        return;
    }
    sc->stats.kernel_drops += delta;
    sc->drop_counter = counter;
    item->events[item->event_count++] = CO_COMM_RX_OVERFLOW;
}

/* SO_RXQ_OVFL: the drop counter rides along on frames queued after drops. */
static void check_drops(co_socketcan_t *sc, struct msghdr *msg, co_sc_rx_t *item)
{
    for (struct cmsghdr *c = CMSG_FIRSTHDR(msg); c; c = CMSG_NXTHDR(msg, c)) {
        if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SO_RXQ_OVFL) {
            uint32_t counter;
            memcpy(&counter, CMSG_DATA(c), sizeof counter);
            note_drops(sc, counter, item);
        }
    }
}

/* Drops with no frame after them show only in the socket's counter: look at
 * it whenever the queue ran empty. True when it gave an RX_OVERFLOW item. */
static bool check_trailing_drops(co_socketcan_t *sc, co_sc_rx_t *item)
{
    uint32_t info[SK_MEMINFO_VARS];
    socklen_t size = sizeof info;
    /* Drops followed by a frame arrive with it (SO_RXQ_OVFL); this extra
     * system call finds drops nothing followed yet. Drops need a full socket
     * buffer, i.e. a drain that read full batches, so light traffic
     * (request/response) does not pay a system call per frame for it. */
    if (!sc->backlog) {
        return false;
    }
    sc->backlog = false;
    if (getsockopt(sc->fd, SOL_SOCKET, SO_MEMINFO, info, &size) != 0 ||
        size <= SK_MEMINFO_DROPS * sizeof info[0]) {
        return false;
    }
    item->has_frame = false;
    item->event_count = 0;
    note_drops(sc, info[SK_MEMINFO_DROPS], item);
    return item->event_count > 0;
}

static void decode_message(co_socketcan_t *sc, struct mmsghdr *m, const struct canfd_frame *k,
                           co_sc_rx_t *item)
{
    item->has_frame = false;
    item->event_count = 0;
    check_drops(sc, &m->msg_hdr, item);
    if (m->msg_hdr.msg_flags & MSG_TRUNC) {
        return;
    }
    if (k->can_id & CAN_ERR_FLAG) {
        sc->stats.error_frames++;
        uint8_t room = (uint8_t)(CO_SC_MAX_EVENTS - item->event_count);
        uint8_t n = co_sc_error_events(k->can_id, k->data, item->events + item->event_count,
                                       room);
        sc->stats.error_frames_other += n == 0;
        item->event_count = (uint8_t)(item->event_count + n);
        return;
    }
    if (co_sc_frame_from_kernel(k, m->msg_len, &item->frame)) {
        item->has_frame = true;
        sc->stats.rx_frames++;
    }
}

static int receive_batch(co_socketcan_t *sc, struct canfd_frame *frames, struct mmsghdr *msgs,
                         unsigned max)
{
    struct iovec iov[CO_SC_BATCH];
    sc_control_t control[CO_SC_BATCH];
    memset(msgs, 0, max * sizeof *msgs);
    for (unsigned i = 0; i < max; i++) {
        iov[i] = (struct iovec){.iov_base = &frames[i], .iov_len = sizeof frames[i]};
        msgs[i].msg_hdr.msg_iov = &iov[i];
        msgs[i].msg_hdr.msg_iovlen = 1;
        msgs[i].msg_hdr.msg_control = control[i].bytes;
        msgs[i].msg_hdr.msg_controllen = sizeof control[i].bytes;
    }
    int n;
    do {
        n = recvmmsg(sc->fd, msgs, max, MSG_DONTWAIT, NULL);
    } while (n < 0 && errno == EINTR);
    return n;
}

co_sc_io_t co_sc_read(co_socketcan_t *sc, co_sc_rx_t *items, unsigned max, unsigned *count)
{
    struct canfd_frame frames[CO_SC_BATCH];
    struct mmsghdr msgs[CO_SC_BATCH];
    *count = 0;
    if (sc->fd < 0) {
        sc->last_errno = EBADF;
        return CO_SC_FAILED;
    }
    max = max < CO_SC_BATCH ? max : CO_SC_BATCH;
    /* Loop so that a batch of unreported error frames does not read as "empty". */
    while (max > 0 && *count == 0) {
        int n = receive_batch(sc, frames, msgs, max);
        if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK) {
            sc->last_errno = errno;
            return CO_SC_FAILED;
        }
        if (n < 0) {
            sc->last_errno = errno;
            *count = check_trailing_drops(sc, &items[0]);
            return *count > 0 ? CO_SC_DONE : CO_SC_WOULD_BLOCK;
        }
        if (n == (int)max) {
            sc->backlog = true;
        }
        sc->stats.rx_calls += n > 0;
        for (int i = 0; i < n; i++) {
            decode_message(sc, &msgs[i], &frames[i], &items[*count]);
            *count += items[*count].has_frame || items[*count].event_count > 0;
        }
    }
    return *count > 0 ? CO_SC_DONE : CO_SC_WOULD_BLOCK;
}

/* ------------------------------------------------------------------ write */

/* Converts up to max frames; stops before the first malformed one. */
static unsigned prepare_batch(const co_frame_t *frames, unsigned max, struct canfd_frame *k,
                              struct iovec *iov, struct mmsghdr *msgs)
{
    unsigned n = 0;
    memset(msgs, 0, max * sizeof *msgs);
    for (; n < max; n++) {
        size_t bytes = co_sc_frame_to_kernel(&frames[n], &k[n]);
        if (bytes == 0) {
            break;
        }
        iov[n] = (struct iovec){.iov_base = &k[n], .iov_len = bytes};
        msgs[n].msg_hdr.msg_iov = &iov[n];
        msgs[n].msg_hdr.msg_iovlen = 1;
    }
    return n;
}

co_sc_io_t co_sc_write(co_socketcan_t *sc, const co_frame_t *frames, unsigned count,
                       unsigned *sent)
{
    struct canfd_frame k[CO_SC_BATCH];
    struct iovec iov[CO_SC_BATCH];
    struct mmsghdr msgs[CO_SC_BATCH];
    *sent = 0;
    if (sc->fd < 0) {
        sc->last_errno = EBADF;
        return CO_SC_FAILED;
    }
    while (*sent < count) {
        unsigned left = count - *sent;
        unsigned n = prepare_batch(frames + *sent, left < CO_SC_BATCH ? left : CO_SC_BATCH, k,
                                   iov, msgs);
        if (n == 0) {
            sc->last_errno = EINVAL;   /* frames[*sent] is malformed */
            return CO_SC_FAILED;
        }
        int done = sendmmsg(sc->fd, msgs, n, MSG_DONTWAIT);
        if (done < 0 && errno == EINTR) {
            continue;
        }
        if (done < 0) {
            sc->last_errno = errno;
            /* ENOBUFS: the device queue is full (the socket itself still
             * polls writable); EAGAIN: the socket send buffer is full. */
            bool full = errno == EAGAIN || errno == EWOULDBLOCK || errno == ENOBUFS;
            sc->stats.tx_would_block += full;
            return full ? CO_SC_WOULD_BLOCK : CO_SC_FAILED;
        }
        *sent += (unsigned)done;
        sc->stats.tx_frames += (uint32_t)done;
        sc->stats.tx_calls += done > 0;
    }
    return CO_SC_DONE;
}
