/* Error state of the local node, in front of its EMCY producer: an array of
 * error-status bits and a code table saying what each bit stands for.
 *
 * A bit is one error situation. The code table gives each bit its EMCY
 * error code and error register (0x1001) class bits: bits 0..15 belong to
 * the errors the stack detects (predefined below), the application declares
 * bits 16..127 once (co_errors_define) and then reports and resets them by
 * bit number, which doubles as its application error id. A report sets the
 * bit and sends one EMCY only the first time (repetitions are counted, not
 * sent); a reset clears it and sends the reset EMCY. The service derives its
 * part of 0x1001 from one condition per register bit: "any of these status
 * bits is set" (by default the bits whose table entry names that class,
 * generic for every defined bit); co_errors_set_condition replaces one.
 *
 * The EMCY of a reported bit: bytes 0-1 its code, 2 the error register,
 * 3 the bit, 4-5 the report's info code (LE), 6-7 zero (application). On fd
 * lines the same fields in the extended EMCY (manufacturer field bytes 3-7),
 * status occurred / removed. The stack's own bits follow its detectors
 * (co_node): their EMCYs stay those co_node sends through the producer.
 *
 * On request (co_errors_attach_od) the bit array is mirrored into an OD
 * entry index:00 of type OCTET_STRING (CANopenNode uses 0x2100), bit n in
 * byte n / 8 at bit n % 8, read-only. Only on request: an OCTET_STRING at
 * that index may well be an application's own entry.
 * Choices and sources: docs/protocol-notes.md ("Error-report bits"). */
#ifndef CO_ERRORS_H
#define CO_ERRORS_H

#include "canopenfd/co_emcy.h"

/* cffi:begin */
enum {
    CO_ERRORS_BITS = 128,             /* error-status bits 0..127 */
    CO_ERRORS_BYTES = 16,             /* the bit array: CO_ERRORS_BITS / 8 */
    CO_ERRORS_FIRST_APP_BIT = 16,     /* 0..15: errors the stack detects */
    CO_ERRORS_OD_INDEX = 0x2100       /* where CANopenNode shows the bit array */
};

/* The bits of the errors the stack detects (code, class: communication). */
enum {
    CO_ERRORS_BIT_CAN_OVERRUN = 0,    /* 0x8110 received frames lost */
    CO_ERRORS_BIT_ERROR_PASSIVE = 1,  /* 0x8120 */
    CO_ERRORS_BIT_LIFE_GUARD = 2,     /* 0x8130 heartbeat consumer or life guarding */
    CO_ERRORS_BIT_BUS_OFF = 3,        /* 0x8140 */
    CO_ERRORS_BIT_RPDO_SHORT = 4,     /* 0x8210 RPDO shorter than its mapping */
    CO_ERRORS_BIT_RPDO_LONG = 5,      /* 0x8220 RPDO longer than its mapping */
    CO_ERRORS_BIT_SYNC_LENGTH = 6,    /* 0x8240 */
    CO_ERRORS_BIT_RPDO_TIMEOUT = 7    /* 0x8250 RPDO deadline */
};

typedef enum co_errors_result {
    CO_ERRORS_OK = 0,                 /* set (or cleared): EMCY sent or queued */
    CO_ERRORS_REPEATED = 1,           /* already set: counted, nothing sent */
    CO_ERRORS_NOT_SET = 2,            /* reset of a bit that is clear: nothing sent */
    CO_ERRORS_UNDEFINED = 3,          /* the bit has no code table entry */
    CO_ERRORS_BAD_ARGUMENT = 4        /* bit out of range, a stack bit, code 0, bit 6 of
                                         the register, redefining a bit that is set */
} co_errors_result_t;
/* cffi:end */

typedef struct co_errors_entry {
    uint16_t code;                    /* EMCY error code, 0 = not defined */
    uint8_t register_bits;            /* 0x1001 class bits (generic added) */
} co_errors_entry_t;

struct co_errors;
/* A communication-class bit was set by a report (the node applies 0x1029:01). */
typedef void (*co_errors_comm_fn)(struct co_errors *errors, void *user);

typedef struct co_errors {
    co_emcy_t *emcy;                  /* sends the EMCYs, holds 0x1001 and 0x1003 */
    co_od_t *od;                      /* bound OD or NULL */
    uint16_t od_index;                /* its entry showing the bits (sub 0) */
    uint8_t status[CO_ERRORS_BYTES];
    co_errors_entry_t table[CO_ERRORS_BITS];
    uint32_t count[CO_ERRORS_BITS];   /* reports of each bit, repetitions included */
    uint8_t condition[8][CO_ERRORS_BYTES];   /* per 0x1001 bit: the status bits it ORs */
    uint8_t custom_conditions;        /* register bits whose condition the application set */
    uint8_t error_register;           /* this service's part of 0x1001 */
    co_errors_comm_fn on_comm;
    void *comm_user;
} co_errors_t;

/* The stack bits defined, application bits undefined, nothing set. */
void co_errors_init(co_errors_t *e, co_emcy_t *emcy);
/* Declare application bit `bit` (16..127): its EMCY code (not 0) and 0x1001
 * class bits (CO_EMCY_ER_*, bit 6 reserved). Redefining a bit is allowed
 * while it is clear. */
co_errors_result_t co_errors_define(co_errors_t *e, uint8_t bit, uint16_t code,
                                    uint8_t register_bits);
/* The condition of 0x1001 bit `register_bit` (0..7 but 6): set while any
 * status bit of mask (CO_ERRORS_BYTES bytes, bit n in byte n / 8) is set.
 * Replaces the table's default for that bit from now on. */
co_errors_result_t co_errors_set_condition(co_errors_t *e, uint8_t register_bit,
                                           const uint8_t *mask);
/* Application report / reset of a defined bit with an info code (EMCY
 * bytes 4-5). Stack bits are refused here (their detectors own them). */
co_errors_result_t co_errors_report(co_errors_t *e, uint8_t bit, uint16_t info);
co_errors_result_t co_errors_reset(co_errors_t *e, uint8_t bit, uint16_t info);
/* The stack's detectors: a stack bit's state, without an EMCY (co_node
 * sends the stack's own EMCYs). */
void co_errors_note(co_errors_t *e, uint8_t bit, bool active);
/* The stack bit of a code co_node raises, or -1. */
int co_errors_stack_bit(uint16_t code);

void co_errors_set_comm_indication(co_errors_t *e, co_errors_comm_fn fn, void *user);
bool co_errors_is_set(const co_errors_t *e, uint8_t bit);
static inline uint32_t co_errors_count(const co_errors_t *e, uint8_t bit)
{
    return bit < CO_ERRORS_BITS ? e->count[bit] : 0;
}
static inline uint8_t co_errors_register(const co_errors_t *e) { return e->error_register; }

/* Mirror the bits into index:00 of a sealed OD, an OCTET_STRING (fewer
 * than CO_ERRORS_BYTES bytes: the first ones); network writes are refused
 * (0x06010002), application writes replaced. False when already attached,
 * the entry is missing or of another type, or the OD cannot take the
 * subscription. */
bool co_errors_attach_od(co_errors_t *e, co_od_t *od, uint16_t index);
void co_errors_detach_od(co_errors_t *e);

#endif
