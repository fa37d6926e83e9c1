/* Linux SocketCAN driver: one non-blocking AF_CAN raw socket bound to an
 * interface, frames converted to and from co_frame_t, error frames mapped to
 * communication events. Reads and writes give tri-state results so the
 * runtime can tell "try again later" from "the interface is gone".
 * Linux only: the portable core never includes this header. */
#ifndef CO_SOCKETCAN_H
#define CO_SOCKETCAN_H

#include "canopenfd/co_line.h"

enum {
    CO_SC_NAME_SIZE = 16,    /* IFNAMSIZ, checked in co_socketcan.c */
    CO_SC_BATCH = 32,        /* frames per recvmmsg/sendmmsg call */
    CO_SC_MAX_EVENTS = 4     /* comm events one received item can carry */
};

typedef enum co_sc_io {
    CO_SC_DONE = 1,          /* read: items returned; write: every frame sent */
    CO_SC_WOULD_BLOCK = 0,   /* read: nothing pending; write: buffer full */
    CO_SC_FAILED = -1        /* errno in last_errno (see co_sc_errno_is_iface_down) */
} co_sc_io_t;

typedef enum co_sc_open_result {
    CO_SC_OPEN_OK = 0,
    CO_SC_OPEN_BAD_NAME,     /* empty or longer than IFNAMSIZ - 1 */
    CO_SC_OPEN_NO_INTERFACE, /* no interface of that name */
    CO_SC_OPEN_NOT_CAN,      /* the interface is not a CAN interface */
    CO_SC_OPEN_MTU,          /* MTU does not fit the line mode */
    CO_SC_OPEN_DOWN,         /* the interface exists but is down */
    CO_SC_OPEN_SOCKET        /* socket, ioctl, setsockopt or bind failed */
} co_sc_open_result_t;

typedef struct co_sc_stats {
    uint32_t rx_frames;
    uint32_t tx_frames;
    uint32_t error_frames;        /* every error frame received */
    uint32_t error_frames_other;  /* error frames with no comm event (bus errors...) */
    uint32_t kernel_drops;        /* frames the socket buffer lost (SO_RXQ_OVFL) */
    uint32_t tx_would_block;      /* writes refused with EAGAIN/ENOBUFS */
    uint32_t rx_calls;            /* recvmmsg calls that returned frames (rx_frames / rx_calls:
                                     frames per read, i.e. how well reads batch) */
    uint32_t tx_calls;            /* sendmmsg calls that sent frames */
} co_sc_stats_t;

typedef struct co_socketcan {
    int fd;                       /* -1 while closed */
    char ifname[CO_SC_NAME_SIZE];
    co_mode_t mode;
    int last_errno;               /* of the last failed call */
    uint32_t drop_counter;        /* last SO_RXQ_OVFL value seen */
    bool backlog;                 /* a full batch was read since the socket was last empty */
    co_sc_stats_t stats;
} co_socketcan_t;

/* One item read: the comm events an error frame (or a socket drop) maps to,
 * followed by a data frame when has_frame. Report events first. */
typedef struct co_sc_rx {
    bool has_frame;
    co_frame_t frame;
    uint8_t event_count;
    co_comm_event_t events[CO_SC_MAX_EVENTS];
} co_sc_rx_t;

void co_sc_init(co_socketcan_t *sc);
/* Open and bind: checks that the interface exists, is CAN, is up and has an
 * MTU fitting the mode (fd needs 72; classic takes 16 or 72). On failure err
 * gets a message naming the interface and the fix. */
co_sc_open_result_t co_sc_open(co_socketcan_t *sc, const char *ifname, co_mode_t mode,
                               char *err, size_t err_size);
void co_sc_close(co_socketcan_t *sc);
static inline bool co_sc_is_open(const co_socketcan_t *sc) { return sc->fd >= 0; }

/* Read up to max (<= CO_SC_BATCH) items; DONE with *count > 0, WOULD_BLOCK
 * with *count == 0, or FAILED. */
co_sc_io_t co_sc_read(co_socketcan_t *sc, co_sc_rx_t *items, unsigned max, unsigned *count);
/* Send frames in order. *sent tells how many left: DONE (all), WOULD_BLOCK
 * (socket or device queue full; last_errno EAGAIN or ENOBUFS), or FAILED
 * (frames[*sent] was refused; last_errno tells why). */
co_sc_io_t co_sc_write(co_socketcan_t *sc, const co_frame_t *frames, unsigned count,
                       unsigned *sent);
/* Pending asynchronous socket error (SO_ERROR, cleared by reading), 0 if none. */
int co_sc_take_socket_error(co_socketcan_t *sc);
/* True for the errno values that mean the interface went down or away. */
bool co_sc_errno_is_iface_down(int err);

/* Wire conversions, exposed for unit tests. struct canfd_frame is the kernel's
 * (a classic can_frame shares its first CAN_MTU bytes). */
struct canfd_frame;
/* Kernel frame of nbytes (CAN_MTU or CANFD_MTU) -> frame; false for error
 * frames and other sizes. */
bool co_sc_frame_from_kernel(const struct canfd_frame *k, size_t nbytes, co_frame_t *out);
/* Frame -> kernel frame; returns the bytes to send (CAN_MTU or CANFD_MTU),
 * 0 when the frame is malformed. */
size_t co_sc_frame_to_kernel(const co_frame_t *frame, struct canfd_frame *k);
/* Comm events of an error frame (can_id with CAN_ERR_FLAG, 8 data bytes). */
uint8_t co_sc_error_events(uint32_t can_id, const uint8_t data[8], co_comm_event_t *out,
                           uint8_t max);

#endif
