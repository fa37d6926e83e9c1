/* TIME producer and consumer (see co_time.h). */
#include "canopenfd/co_time.h"

#include "co_cob_id.h"

#include <string.h>

enum { OD_COB_ID = 0x1012 };

#define CAN_ID_MASK 0x7FFu
#define EXTENDED_BITS 0x3FFFF800u     /* bits 11..29: 29-bit id and frame bit */
#define MS_MASK 0x0FFFFFFFu           /* 28 bits; the upper 4 are reserved */
#define US_PER_DAY ((uint64_t)CO_TIME_MS_PER_DAY * 1000u)
#define EPOCH_US ((uint64_t)CO_TIME_EPOCH_UNIX_S * 1000000u)

/* ------------------------------------------------------------------ codec */

bool co_time_encode(const co_time_of_day_t *tod, uint8_t out[CO_TIME_FRAME_LENGTH])
{
    if (tod->ms >= CO_TIME_MS_PER_DAY) {
        return false;
    }
    out[0] = (uint8_t)tod->ms;
    out[1] = (uint8_t)(tod->ms >> 8);
    out[2] = (uint8_t)(tod->ms >> 16);
    out[3] = (uint8_t)(tod->ms >> 24);   /* < 2^27: the reserved nibble stays 0 */
    out[4] = (uint8_t)tod->days;
    out[5] = (uint8_t)(tod->days >> 8);
    return true;
}

bool co_time_decode(const uint8_t *data, size_t len, co_time_of_day_t *out)
{
    if (len != CO_TIME_FRAME_LENGTH) {
        return false;
    }
    uint32_t ms = (uint32_t)data[0] | (uint32_t)data[1] << 8 | (uint32_t)data[2] << 16 |
                  (uint32_t)data[3] << 24;
    out->ms = ms & MS_MASK;
    out->days = (uint16_t)(data[4] | data[5] << 8);
    return true;
}

bool co_time_from_unix_us(uint64_t unix_us, co_time_of_day_t *out)
{
    if (unix_us < EPOCH_US) {
        return false;
    }
    uint64_t since = unix_us - EPOCH_US;
    uint64_t days = since / US_PER_DAY;
    if (days > 0xFFFFu) {
        return false;
    }
    out->days = (uint16_t)days;
    out->ms = (uint32_t)((since % US_PER_DAY) / 1000u);
    return true;
}

uint64_t co_time_to_unix_us(const co_time_of_day_t *tod)
{
    return EPOCH_US + (uint64_t)tod->days * US_PER_DAY + (uint64_t)tod->ms * 1000u;
}

/* --------------------------------------------------------------- service */

static void on_time_frame(co_line_t *line, const co_frame_t *frame, void *user)
{
    (void)line;
    co_time_t *t = user;
    if (!t->nmt_active) {
        t->stats.ignored_state++;
        return;
    }
    co_time_of_day_t tod;
    if (!co_time_decode(frame->data, frame->len, &tod)) {
        t->stats.bad_length++;
        return;
    }
    t->stats.received++;
    if (t->on_time) {
        t->on_time(t, &tod, t->user);
    }
}

static bool update_subscription(co_time_t *t)
{
    bool want = (t->cob_id & CO_TIME_CONSUMER_BIT) != 0;
    uint32_t id = t->cob_id & CAN_ID_MASK;
    if (t->subscribed && (!want || id != t->rx_id)) {
        co_line_unsubscribe(t->line, on_time_frame, t);
        t->subscribed = false;
    }
    if (want && !t->subscribed) {
        if (!co_line_subscribe(t->line, id, id, on_time_frame, t)) {
            t->stats.subscribe_failed++;
            return false;
        }
        t->subscribed = true;
        t->rx_id = id;
    }
    return true;
}

void co_time_init(co_time_t *time, co_line_t *line, co_time_fn on_time, void *user)
{
    memset(time, 0, sizeof *time);
    time->line = line;
    time->cob_id = CO_TIME_DEFAULT_COB_ID;
    time->on_time = on_time;
    time->user = user;
}

void co_time_deinit(co_time_t *time)
{
    co_time_detach_od(time);
    if (time->subscribed) {
        co_line_unsubscribe(time->line, on_time_frame, time);
        time->subscribed = false;
    }
}

uint32_t co_time_check_cob_id(uint32_t value)
{
    if ((value & EXTENDED_BITS) != 0 || co_cob_id_restricted(value & CAN_ID_MASK)) {
        return CO_ABORT_INVALID_VALUE;
    }
    return 0;
}

bool co_time_set_cob_id(co_time_t *time, uint32_t cob_id)
{
    time->cob_id = cob_id;
    return update_subscription(time);
}

void co_time_set_nmt_state(co_time_t *time, co_nmt_state_t state)
{
    time->nmt_active = state == CO_NMT_PRE_OPERATIONAL || state == CO_NMT_OPERATIONAL;
}

bool co_time_send(co_time_t *time, const co_time_of_day_t *tod)
{
    uint8_t data[CO_TIME_FRAME_LENGTH];
    if (!(time->cob_id & CO_TIME_PRODUCER_BIT) || !time->nmt_active ||
        !co_time_encode(tod, data) ||
        !co_line_send(time->line, time->cob_id & CAN_ID_MASK, data, sizeof data)) {
        time->stats.send_refused++;
        return false;
    }
    time->stats.produced++;
    return true;
}

bool co_time_send_unix_us(co_time_t *time, uint64_t unix_us)
{
    co_time_of_day_t tod;
    if (!co_time_from_unix_us(unix_us, &tod)) {
        time->stats.send_refused++;
        return false;
    }
    return co_time_send(time, &tod);
}

/* ------------------------------------------------------------------ OD */

static uint32_t check_write(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e,
                            const uint8_t *value, uint32_t length, void *user)
{
    (void)od;
    (void)xfer;
    (void)user;
    if (co_od_entry_sub(e) != 0 || length != 4) {
        return 0;
    }
    return co_time_check_cob_id((uint32_t)value[0] | (uint32_t)value[1] << 8 |
                                (uint32_t)value[2] << 16 | (uint32_t)value[3] << 24);
}

static void after_write(co_od_t *od, const co_od_entry_t *e, co_od_origin_t origin, void *user)
{
    (void)e;
    (void)origin;
    uint32_t cob_id;
    if (co_od_get_u32(od, OD_COB_ID, 0, &cob_id)) {
        co_time_set_cob_id(user, cob_id);
    }
}

static const co_od_handler_t time_handler = {
    .check_write = check_write,
    .after_write = after_write,
};

bool co_time_attach_od(co_time_t *time, co_od_t *od)
{
    uint32_t cob_id;
    if (!co_od_get_u32(od, OD_COB_ID, 0, &cob_id) ||
        !co_od_subscribe(od, OD_COB_ID, 0, OD_COB_ID, 0, &time_handler, time)) {
        return false;
    }
    time->od = od;
    co_time_set_cob_id(time, cob_id);
    return true;
}

void co_time_detach_od(co_time_t *time)
{
    if (time->od) {
        co_od_unsubscribe(time->od, &time_handler, time);
        time->od = NULL;
    }
}
