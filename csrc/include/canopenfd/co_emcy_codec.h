/* EMCY wire format: the classic CiA 301 emergency message (8 bytes) and the
 * extended CANopen FD (CiA 1301) emergency message, one encoder/decoder pair
 * each, plus the CiA 301 mapping of an emergency error code to its error
 * register (0x1001) bit.
 *
 * The FD byte layout is not published in a public source; the layout used
 * here and its evidence are in docs/protocol-notes.md (section "EMCY"). A
 * layout found wrong later is changed here, in one place. Decoders take
 * (data, len), never read beyond len and refuse a frame shorter than the
 * layout; they are pure functions. */
#ifndef CO_EMCY_CODEC_H
#define CO_EMCY_CODEC_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* cffi:begin */
enum {
    CO_EMCY_COB_ID_BASE = 0x080,    /* default producer CAN-ID: 0x80 + node-id */
    CO_EMCY_MSEF_LEN = 5,           /* manufacturer-specific error field bytes */
    CO_EMCY_CLASSIC_LEN = 8,        /* classic EMCY: exactly 8 bytes */
    CO_EMCY_FD_LEN = 20             /* FD EMCY: 18 content bytes + 2 reserved, a valid FD length */
};

/* Status byte of the FD EMCY (EmSA ERST_*): bits 2..0 priority (0 highest),
 * bit 3 class, bit 4 state, bit 5 repeated; bits 6..7 unknown, kept as read. */
enum {
    CO_EMCY_STATUS_PRIORITY_MASK = 0x07,
    CO_EMCY_STATUS_NON_RECOVERABLE = 0x08,   /* 0 = recoverable */
    CO_EMCY_STATUS_OCCURRED = 0x10,          /* 0 = removed */
    CO_EMCY_STATUS_REPEATED = 0x20           /* occurred more than once */
};

/* Error register (0x1001) bits, CiA 301. */
enum {
    CO_EMCY_ER_GENERIC = 0x01,
    CO_EMCY_ER_CURRENT = 0x02,
    CO_EMCY_ER_VOLTAGE = 0x04,
    CO_EMCY_ER_TEMPERATURE = 0x08,
    CO_EMCY_ER_COMMUNICATION = 0x10,
    CO_EMCY_ER_DEVICE_PROFILE = 0x20,
    CO_EMCY_ER_MANUFACTURER = 0x80
};

/* Every field of an EMCY; the FD-only fields are 0 in a classic one. */
typedef struct co_emcy_msg {
    uint16_t code;                /* emergency error code (EEC); 0x0000 = error reset */
    uint8_t error_register;       /* copy of 0x1001 */
    uint8_t msef[5];              /* manufacturer-specific error field */
    uint8_t logical_device;       /* FD: part of the device the error belongs to */
    uint16_t spec_number;         /* FD: CiA specification defining the EEC (1301 = 0x0515) */
    uint8_t status;               /* FD: CO_EMCY_STATUS_* */
    uint64_t time_stamp;          /* FD: 48 bits, 0 when not supported */
} co_emcy_msg_t;
/* cffi:end */

/* The FD time stamp has 48 bits. */
#define CO_EMCY_TIME_MAX 0xFFFFFFFFFFFFull

/* cffi:begin */
/* Classic: bytes 0-1 EEC (LE), 2 error register, 3-7 msef. Returns 8, or 0
 * when cap < 8. Only the classic fields are used. */
size_t co_emcy_encode_classic(const co_emcy_msg_t *msg, uint8_t *out, size_t cap);
/* Refuses (false) every length other than 8; fills out only on success
 * (FD-only fields 0). */
bool co_emcy_decode_classic(const uint8_t *data, size_t len, co_emcy_msg_t *out);

/* FD: bytes 0-7 as classic, 8 logical device, 9-10 CiA specification number
 * (LE), 11 status, 12-17 time stamp (48 bits, LE), 18-19 reserved (0).
 * Returns 20, or 0 when cap < 20 or the time stamp needs more than 48 bits. */
size_t co_emcy_encode_fd(const co_emcy_msg_t *msg, uint8_t *out, size_t cap);
/* Refuses (false) a frame shorter than 20 bytes; bytes beyond the layout
 * (a longer FD length, padding) are ignored. Fills out only on success. */
bool co_emcy_decode_fd(const uint8_t *data, size_t len, co_emcy_msg_t *out);
/* cffi:end */

/* The error register bits (besides generic) that an error code stands for:
 * 0x2xxx current, 0x3xxx voltage, 0x4xxx temperature, 0x80xx..0x82xx
 * communication (monitoring, CAN, protocol), 0xFFxx manufacturer; every
 * other class (generic, hardware, software, modules, external, additional
 * functions, device profile ranges) only the generic bit, which the producer
 * sets for every active error anyway. 0x0000 (error reset) gives 0. */
uint8_t co_emcy_code_register_bits(uint16_t code);

#endif
