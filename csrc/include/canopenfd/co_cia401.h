/* CiA 401 generic I/O device profile: the per-change logic of one channel
 * group, independent of any line or object dictionary.
 *
 * An 8-bit digital input group (0x6000 with its polarity 0x6002, filter
 * 0x6003 and interrupt masks 0x6005..0x6008), an 8-bit digital output group
 * (0x6200 with polarity 0x6202, error mode 0x6206, error value 0x6207,
 * filter mask 0x6208), a 16-bit analogue input (0x6401 with trigger
 * selection 0x6421, global enable 0x6423, limits and deltas 0x6424..0x6428)
 * and a 16-bit analogue output (0x6411 with error mode 0x6443 and error value
 * 0x6444). The caller owns each struct, keeps its parameters equal to the
 * OD's and asks: which value goes into the OD, does this change trigger the
 * input's TPDO, which level goes to the physical output. No allocation, no
 * global state, no clock (the filter works on consecutive samples).
 * Behaviour and sources: docs/protocol-notes.md, section "CiA 401". */
#ifndef CO_CIA401_H
#define CO_CIA401_H

#include <stdbool.h>
#include <stdint.h>

/* cffi:begin */
enum {
    CO_CIA401_PROFILE = 0x0191,                  /* 0x1000 bits 0..15 */
    CO_CIA401_HAS_DIGITAL_INPUTS = 0x00010000,   /* 0x1000 I/O functionality bits */
    CO_CIA401_HAS_DIGITAL_OUTPUTS = 0x00020000,
    CO_CIA401_HAS_ANALOG_INPUTS = 0x00040000,
    CO_CIA401_HAS_ANALOG_OUTPUTS = 0x00080000
};

/* 0x6421 trigger selection bits of an analogue input. */
enum {
    CO_CIA401_AI_UPPER = 0x01,          /* value reached the upper limit 0x6424 */
    CO_CIA401_AI_LOWER = 0x02,          /* value fell below the lower limit 0x6425 */
    CO_CIA401_AI_DELTA = 0x04,          /* moved more than 0x6426 since the last trigger */
    CO_CIA401_AI_NEGATIVE_DELTA = 0x08, /* fell more than 0x6427 since the last trigger */
    CO_CIA401_AI_POSITIVE_DELTA = 0x10, /* rose more than 0x6428 since the last trigger */
    CO_CIA401_AI_DEFAULT_TRIGGER = 0x07
};

/* One group of 8 digital inputs. Parameters: the caller's; state: ours. */
typedef struct co_cia401_din {
    uint8_t polarity;          /* 0x6002: 1 = the line is inverted */
    uint8_t filter;            /* 0x6003: 1 = the bit changes after two equal samples */
    bool interrupt_enable;     /* 0x6005 */
    uint8_t any_change;        /* 0x6006 */
    uint8_t rising;            /* 0x6007 */
    uint8_t falling;           /* 0x6008 */
    uint8_t value;             /* state: what 0x6000 holds */
    uint8_t last_sample;       /* state: the previous sample after polarity */
} co_cia401_din_t;

/* One group of 8 digital outputs. */
typedef struct co_cia401_dout {
    uint8_t polarity;          /* 0x6202 */
    uint8_t error_mode;        /* 0x6206: 1 = the bit takes its error value on a fault */
    uint8_t error_value;       /* 0x6207: the output level on a fault */
    uint8_t filter_mask;       /* 0x6208: 1 = the bit follows 0x6200, 0 = it stays */
    uint8_t physical;          /* state: the levels on the output lines */
} co_cia401_dout_t;

/* One 16-bit analogue input channel. */
typedef struct co_cia401_ain {
    uint8_t trigger;           /* 0x6421: CO_CIA401_AI_* */
    bool interrupt_enable;     /* 0x6423 (one for every channel) */
    int32_t upper_limit;       /* 0x6424 */
    int32_t lower_limit;       /* 0x6425 */
    uint32_t delta;            /* 0x6426 */
    uint32_t negative_delta;   /* 0x6427 */
    uint32_t positive_delta;   /* 0x6428 */
    int32_t value;             /* state: what 0x6401 holds */
    int32_t reference;         /* state: the value at the last trigger (deltas) */
} co_cia401_ain_t;

/* One 16-bit analogue output channel. */
typedef struct co_cia401_aout {
    bool error_mode;           /* 0x6443: true = takes the error value on a fault */
    int32_t error_value;       /* 0x6444 (saturated to the 16-bit output range) */
    int32_t physical;          /* state: the level on the output */
} co_cia401_aout_t;

/* New raw levels of a digital input group: applies polarity and filter,
 * stores the result in din->value and tells whether the change triggers
 * the TPDO (global enable and any-change, rising or falling mask). */
bool co_cia401_din_update(co_cia401_din_t *din, uint8_t raw);

/* 0x6200 written: returns the new physical levels (polarity applied, bits
 * outside the filter mask unchanged), kept in dout->physical. */
uint8_t co_cia401_dout_write(co_cia401_dout_t *dout, uint8_t value);

/* A device fault: bits with error mode set go to their error value, the
 * others stay. Returns the new physical levels. */
uint8_t co_cia401_dout_fault(co_cia401_dout_t *dout);

/* Sets both state values (0x6401 and the delta reference) without a trigger:
 * the start value, or after the trigger parameters changed. */
void co_cia401_ain_reset(co_cia401_ain_t *ain, int32_t value);

/* A new analogue input value: stored in ain->value; true when it triggers
 * the TPDO: global enable and one selected condition (a limit crossed into,
 * or a delta since the last trigger exceeded). A trigger moves the reference. */
bool co_cia401_ain_update(co_cia401_ain_t *ain, int32_t value);

/* 0x6411 written: the physical output value (the written value). */
int32_t co_cia401_aout_write(co_cia401_aout_t *aout, int32_t value);

/* A device fault: the error value when error mode is set, else unchanged. */
int32_t co_cia401_aout_fault(co_cia401_aout_t *aout);
/* cffi:end */

#endif
