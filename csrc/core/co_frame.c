#include "canopenfd/co_frame.h"

#include <string.h>

static const uint8_t dlc_to_len[16] = {0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64};

/* DLC code of the smallest valid CAN FD length >= n, for n = 0..64: one load
 * instead of a scan of dlc_to_len (the send and dispatch paths ask per frame). */
static const uint8_t round_dlc[CO_FRAME_MAX_DATA + 1] = {
    0,  1,  2,  3,  4,  5,  6,  7,  8,                          /* 0..8: themselves */
    9,  9,  9,  9,                                              /* 9..12 -> 12 */
    10, 10, 10, 10,                                             /* 13..16 -> 16 */
    11, 11, 11, 11,                                             /* 17..20 -> 20 */
    12, 12, 12, 12,                                             /* 21..24 -> 24 */
    13, 13, 13, 13, 13, 13, 13, 13,                             /* 25..32 -> 32 */
    14, 14, 14, 14, 14, 14, 14, 14, 14, 14, 14, 14, 14, 14, 14, 14, /* 33..48 -> 48 */
    15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15  /* 49..64 -> 64 */
};

uint8_t co_fd_len_round(size_t n)
{
    return n <= CO_FRAME_MAX_DATA ? dlc_to_len[round_dlc[n]] : 0xFF;
}

bool co_fd_len_valid(size_t len)
{
    return len <= CO_FRAME_MAX_DATA && dlc_to_len[round_dlc[len]] == len;
}

uint8_t co_fd_len_to_dlc(size_t len)
{
    return co_fd_len_valid(len) ? round_dlc[len] : 0xFF;
}

uint8_t co_fd_dlc_to_len(uint8_t dlc)
{
    return dlc < 16 ? dlc_to_len[dlc] : 0xFF;
}

bool co_frame_is_valid(const co_frame_t *frame)
{
    uint32_t id_limit = (frame->flags & CO_FRAME_EXT) ? 0x1FFFFFFFu : 0x7FFu;
    if (frame->id > id_limit) {
        return false;
    }
    if (frame->flags & CO_FRAME_FD) {
        return !(frame->flags & CO_FRAME_RTR) && co_fd_len_valid(frame->len);
    }
    if (frame->flags & (CO_FRAME_BRS | CO_FRAME_ESI)) {
        return false;
    }
    return frame->len <= CO_FRAME_CLASSIC_MAX;
}

bool co_frame_set(co_frame_t *frame, uint32_t id, uint8_t flags,
                  const uint8_t *data, size_t n)
{
    size_t len = n;
    if (flags & CO_FRAME_FD) {
        len = co_fd_len_round(n);
        if (len == 0xFF) {
            return false;
        }
    } else if (n > CO_FRAME_CLASSIC_MAX) {
        return false;
    }
    frame->id = id;
    frame->flags = flags;
    frame->len = (uint8_t)len;
    if (n > 0) {
        memcpy(frame->data, data, n);
    }
    /* Padding value for CANopen FD is unconfirmed (protocol notes §1.1); zero
     * is the neutral choice and receivers use in-protocol sizes anyway. Only
     * the padding is written: bytes past len are not part of the frame. */
    if (len > n) {
        memset(frame->data + n, 0, len - n);
    }
    return true;
}
