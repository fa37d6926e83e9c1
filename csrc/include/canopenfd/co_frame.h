/* One frame type for classic CAN and CAN FD, plus the CAN FD length rules. */
#ifndef CO_FRAME_H
#define CO_FRAME_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* Blocks between cffi:begin and cffi:end are read by build_ext.py as the Python
 * binding's cdef, so they use only what cffi's parser understands (no macros). */
/* cffi:begin */
enum {
    CO_FRAME_MAX_DATA = 64,      /* CAN FD maximum payload */
    CO_FRAME_CLASSIC_MAX = 8
};

/* Frame flags. */
enum {
    CO_FRAME_FD  = 0x01,   /* CAN FD format (FDF) */
    CO_FRAME_BRS = 0x02,   /* bit-rate switch in the data phase (FD only) */
    CO_FRAME_ESI = 0x04,   /* error state indicator (FD only, receive side) */
    CO_FRAME_EXT = 0x08,   /* 29-bit identifier */
    CO_FRAME_RTR = 0x10    /* remote request (classic only) */
};

typedef struct co_frame {
    uint32_t id;           /* 11-bit or 29-bit identifier, no flag bits */
    uint8_t len;           /* payload bytes, 0..8 classic, valid FD length on FD */
    uint8_t flags;         /* CO_FRAME_* */
    uint8_t data[64];
} co_frame_t;

/* Smallest valid CAN FD length >= n (0..8, 12, 16, 20, 24, 32, 48, 64);
 * 0xFF when n > 64. */
uint8_t co_fd_len_round(size_t n);
/* True when len is one of the valid CAN FD lengths. */
bool co_fd_len_valid(size_t len);
/* DLC code (0..15) of a valid FD length; 0xFF for an invalid length. */
uint8_t co_fd_len_to_dlc(size_t len);
/* Payload length of a DLC code; codes > 15 give 0xFF. */
uint8_t co_fd_dlc_to_len(uint8_t dlc);
/* True when the frame is well formed: id fits its width, length fits its
 * format, no FD-only flags on a classic frame and no RTR on an FD frame. */
bool co_frame_is_valid(const co_frame_t *frame);
/* cffi:end */

/* Fill a frame: payload copied, length rounded up to a valid FD length on FD
 * frames (padding bytes set to 0). Returns false when the payload is too long
 * for the format. */
bool co_frame_set(co_frame_t *frame, uint32_t id, uint8_t flags,
                  const uint8_t *data, size_t n);

#endif
