/* TIME (CiA 301 time stamp object): producer and consumer of the 6-byte
 * TIME_OF_DAY frame, configured by 0x1012 (bit 31 consume, bit 30 produce,
 * bits 0..10 CAN-ID, default 0x100), on classic and fd lines, plus the
 * codec and conversions to and from Unix time. The core has no clock: the
 * application says what time it is when it sends. TIME is produced and
 * consumed in NMT pre-operational and operational only. */
#ifndef CO_TIME_H
#define CO_TIME_H

#include "canopenfd/co_nmt.h"
#include "canopenfd/co_od.h"

enum {
    CO_TIME_DEFAULT_COB_ID = 0x100,
    CO_TIME_FRAME_LENGTH = 6
};

#define CO_TIME_CONSUMER_BIT 0x80000000u    /* 0x1012 bit 31 */
#define CO_TIME_PRODUCER_BIT 0x40000000u    /* 0x1012 bit 30 */
#define CO_TIME_MS_PER_DAY 86400000u
/* 1984-01-01 00:00:00 UTC, the TIME_OF_DAY epoch, in Unix seconds. */
#define CO_TIME_EPOCH_UNIX_S 441763200u

/* TIME_OF_DAY: milliseconds after midnight and days since 1984-01-01. */
typedef struct co_time_of_day {
    uint32_t ms;      /* 0..86 399 999 when encoded; a decoded value may be up to 2^28 - 1 */
    uint16_t days;
} co_time_of_day_t;

/* Codec. Bytes 0..3: ms after midnight, little-endian, 28 bits used (the
 * upper 4 bits of byte 3 reserved, sent as 0); bytes 4..5: days, LE.
 * encode: false when ms >= CO_TIME_MS_PER_DAY (not a time of day).
 * decode: false unless len == 6; the reserved bits are ignored. */
bool co_time_encode(const co_time_of_day_t *tod, uint8_t out[CO_TIME_FRAME_LENGTH]);
bool co_time_decode(const uint8_t *data, size_t len, co_time_of_day_t *out);

/* Unix time in µs <-> TIME_OF_DAY (UTC, no leap seconds, sub-ms truncated).
 * from: false before 1984-01-01 or after day 65535 (2163-06-06).
 * to: any decoded value (ms beyond a day simply adds). */
bool co_time_from_unix_us(uint64_t unix_us, co_time_of_day_t *out);
uint64_t co_time_to_unix_us(const co_time_of_day_t *tod);

typedef struct co_time co_time_t;

/* A time stamp was received (already decoded). */
typedef void (*co_time_fn)(co_time_t *time, const co_time_of_day_t *tod, void *user);

/* cffi:begin */
typedef struct co_time_stats {
    uint32_t produced;          /* TIME frames queued */
    uint32_t received;          /* TIME frames delivered */
    uint32_t bad_length;        /* received with a length other than 6 */
    uint32_t ignored_state;     /* received outside pre-operational / operational */
    uint32_t send_refused;      /* co_time_send refused: not producer, NMT state, bad time, tx full */
    uint32_t subscribe_failed;  /* the TIME CAN-ID could not be subscribed */
} co_time_stats_t;
/* cffi:end */

struct co_time {
    co_line_t *line;
    co_od_t *od;                  /* bound by co_time_attach_od, or NULL */
    uint32_t cob_id;              /* 0x1012 */
    bool nmt_active;
    bool subscribed;
    uint32_t rx_id;
    co_time_fn on_time;
    void *user;
    co_time_stats_t stats;
};

/* Defaults: COB-ID 0x100, neither consumer nor producer, NMT not active. */
void co_time_init(co_time_t *time, co_line_t *line, co_time_fn on_time, void *user);
void co_time_deinit(co_time_t *time);
/* 0 or CiA abort for a 0x1012 value: bits 11..29 set (29-bit ids are not
 * supported) or a restricted CAN-ID: 0x06090030. The CAN-ID change rule is
 * co_cob_id's. */
uint32_t co_time_check_cob_id(uint32_t value);
/* Set 0x1012 without an OD (taken as given); the consumer (re)subscribes
 * at once. False when the consumer could not subscribe. */
bool co_time_set_cob_id(co_time_t *time, uint32_t cob_id);
/* Bind to a sealed OD: reads 0x1012 (required) and hooks it (checks as
 * co_time_check_cob_id; accepted writes and reloads apply at once). */
bool co_time_attach_od(co_time_t *time, co_od_t *od);
void co_time_detach_od(co_time_t *time);
void co_time_set_nmt_state(co_time_t *time, co_nmt_state_t state);

/* Producer: send this time stamp now. False (counted in send_refused) when
 * 0x1012 bit 30 is clear, the NMT state is not pre-operational/operational,
 * the time does not encode, or the tx queue is full. */
bool co_time_send(co_time_t *time, const co_time_of_day_t *tod);
bool co_time_send_unix_us(co_time_t *time, uint64_t unix_us);

#endif
