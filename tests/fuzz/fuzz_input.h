/* The input format every harness of tests/fuzz shares: a byte stream read
 * as a sequence of records, so one input can send frames, let time pass,
 * and act as the application would, in any order.
 *
 * A record starts with one byte: op = b & 7, p = b >> 3 (0..31).
 *
 *   0, 1  FRAME    [fl][len][data: len bytes]   (two op codes: frames are the
 *                  common case). The CAN-ID is the harness's table entry p
 *                  when p < its table size, else raw: 2 more bytes (11-bit),
 *                  or 4 (29-bit) when the flags carry EXT.
 *                  fl bit 7 clear: the line's own format (FD+BRS on fd lines,
 *                  classic otherwise), len taken modulo 65 (FD, rounded up to
 *                  a valid FD length) or 9 (classic). fl bit 7 set: flags =
 *                  fl & 0x1F exactly as given and len = len % 65 as given,
 *                  so malformed frames (RTR on FD, 13 bytes, ...) reach the
 *                  line. The frame is queued on the harness's target line
 *                  as a driver would (processed at the next TIME/PROCESS);
 *                  fl bit 6 (with bit 7 clear) queues it on the other line.
 *   2      TIME     advance the clock: p 0..15 = p ms, 16..23 = (p-15)*50 ms,
 *                  24..31 = (p-23) s; every timer fires at its own time.
 *   3      ACTION   application action number p; its arguments follow, read
 *                  by the harness with the fz_* readers.
 *   4      BUS      bit 0 of p: hold/release the bus (while held nothing is
 *                  carried and tx queues fill); bit 1: one more byte, a mask
 *                  of the fate of the next 8 frames carried (bit set = lost,
 *                  or duplicated when bit 2 of p is set).
 *   5      PROCESS  process the lines now (no time passes).
 *   6      COMM     a communication event (p % 11 + 1) from the target's driver.
 *   7      SETTLE   resume every split answer, release the bus, let 70 s
 *                  pass, then check that every transfer ended and every
 *                  session is free (also done at the end of every input).
 *
 * The reader never reads past the input: a read past the end gives zeros
 * and marks the input as consumed. At most FZ_MAX_RECORDS records are read. */
#ifndef FUZZ_INPUT_H
#define FUZZ_INPUT_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "canopenfd/co_frame.h"
#include "canopenfd/co_line.h"
#include "canopenfd/co_od.h"

enum {
    FZ_MAX_RECORDS = 4096,
    FZ_OP_FRAME = 0, FZ_OP_FRAME2 = 1, FZ_OP_TIME = 2, FZ_OP_ACTION = 3,
    FZ_OP_BUS = 4, FZ_OP_PROCESS = 5, FZ_OP_COMM = 6, FZ_OP_SETTLE = 7
};

typedef struct fz_reader {
    const uint8_t *data;
    size_t size;
    size_t pos;
    uint32_t records;
} fz_reader_t;

/* One decoded record. */
typedef struct fz_record {
    uint8_t op;
    uint8_t p;
    co_frame_t frame;        /* FRAME */
    uint32_t ms;             /* TIME */
    uint8_t mask;            /* BUS */
    bool has_mask;
    bool alt;                /* FRAME: queued on the harness's other line */
} fz_record_t;

void fz_reader_init(fz_reader_t *r, const uint8_t *data, size_t size);
bool fz_done(const fz_reader_t *r);
uint8_t fz_u8(fz_reader_t *r);
uint16_t fz_u16(fz_reader_t *r);
uint32_t fz_u32(fz_reader_t *r);
/* Copy n bytes (zeros past the end). */
void fz_bytes(fz_reader_t *r, uint8_t *out, size_t n);

/* Next record; false at the end of the input or after FZ_MAX_RECORDS.
 * ids/id_count: the harness's CAN-ID table (at most 31 entries);
 * mode: the target line's mode (a FRAME in the line's own format). */
bool fz_next(fz_reader_t *r, fz_record_t *rec, const uint32_t *ids, uint8_t id_count,
             co_mode_t mode);

/* Adds one fixed-size entry of a harness's own OD with its default value
 * (up to 4 bytes, little-endian); false when the OD refuses it. */
bool fz_od_add(co_od_t *od, uint16_t index, uint8_t sub, uint8_t object_code, uint8_t type,
               uint8_t access, uint32_t value);

/* A harness's own line of `mode` over rx/tx arrays of `slots` frames each;
 * false when co_line_init refuses it. */
bool fz_line_init(co_line_t *line, co_mode_t mode, co_frame_t *rx, co_frame_t *tx,
                  uint16_t slots);

/* Milliseconds a TIME record with parameter p advances. */
uint32_t fz_time_ms(uint8_t p);

#endif
