#include "canopenfd/co_emcy.h"

#include <string.h>

enum {
    OD_ERROR_REGISTER = 0x1001,
    OD_ERROR_FIELD = 0x1003,
    OD_COB_ID_EMCY = 0x1014,
    OD_INHIBIT_EMCY = 0x1015,
    OD_EMCY_CONSUMER = 0x1028,
    OD_ACTIVE_HISTORY = 0x1031,
    OD_ACTIVE_LIST = 0x1032,
    HISTORY_DOMAIN_SUB = 4,       /* 0x1031 sub 4: the history records (DOMAIN) */
    HISTORY_STATUS_SUB = 1,       /* 0x1031 sub 1: status (U32) */
    MAX_ARRAY_SUB = 254
};

#define CAN_ID_11_MASK 0x7FFu
#define CAN_ID_29_MASK 0x1FFFFFFFu

uint32_t co_emcy_list_value(const co_emcy_msg_t *msg)
{
    return (uint32_t)msg->code | ((uint32_t)msg->msef[0] << 16) | ((uint32_t)msg->msef[1] << 24);
}

/* ------------------------------------------------------ OD values in place */

/* The producer owns 0x1001/0x1003/0x1031:1/0x1032: it writes their values
 * directly (little-endian, as the OD stores them), so its own updates do not
 * come back to it as after-write indications. Entries of another size are
 * left alone. */
static void put_in_place(co_od_t *od, uint16_t index, uint8_t sub, uint32_t value,
                         uint32_t size)
{
    const co_od_entry_t *entry = co_od_find(od, index, sub);
    if (entry == NULL || co_od_type_size(entry->type) != size) {
        return;
    }
    uint8_t *p = co_od_value(od, entry);
    for (uint32_t i = 0; i < size; i++) {
        p[i] = (uint8_t)(value >> (8 * i));
    }
}

/* Number of consecutive sub-indices 1..n an ARRAY has. */
static uint8_t array_length(const co_od_t *od, uint16_t index)
{
    uint8_t n = 0;
    while (n < MAX_ARRAY_SUB && co_od_find(od, index, (uint8_t)(n + 1)) != NULL) {
        n++;
    }
    return n;
}

static const co_emcy_active_t *newest(const co_emcy_t *e, uint16_t k)
{
    return &e->active[e->active_count - 1u - k];
}

static void mirror(co_emcy_t *e)
{
    co_od_t *od = e->od;
    if (od == NULL) {
        return;
    }
    put_in_place(od, OD_ERROR_REGISTER, 0, e->error_register, 1);

    if (co_od_has_index(od, OD_ERROR_FIELD)) {
        uint8_t subs = array_length(od, OD_ERROR_FIELD);
        put_in_place(od, OD_ERROR_FIELD, 0, e->history_count, 1);
        for (uint8_t i = 0; i < subs; i++) {
            put_in_place(od, OD_ERROR_FIELD, (uint8_t)(i + 1),
                         i < e->history_count ? e->history[i] : 0, 4);
        }
    }
    if (co_od_has_index(od, OD_ACTIVE_LIST)) {
        /* Newest first, as many as the array holds. */
        uint8_t subs = array_length(od, OD_ACTIVE_LIST);
        uint8_t shown = e->active_count < subs ? (uint8_t)e->active_count : subs;
        put_in_place(od, OD_ACTIVE_LIST, 0, shown, 1);
        for (uint8_t i = 0; i < subs; i++) {
            put_in_place(od, OD_ACTIVE_LIST, (uint8_t)(i + 1),
                         i < shown ? co_emcy_list_value(&newest(e, i)->msg) : 0, 4);
        }
    }
    put_in_place(od, OD_ACTIVE_HISTORY, HISTORY_STATUS_SUB, e->active_count, 4);
}

/* ---------------------------------------------------------------- sending */

static bool cob_id_valid(uint32_t cob_id)
{
    return (cob_id & CO_EMCY_COB_ID_INVALID) == 0;
}

static void transmit(co_emcy_t *e, const co_emcy_msg_t *msg)
{
    uint8_t data[CO_EMCY_FD_LEN];
    size_t len = co_line_mode(e->line) == CO_MODE_FD ? co_emcy_encode_fd(msg, data, sizeof data)
                                             : co_emcy_encode_classic(msg, data, sizeof data);
    co_frame_t frame;
    bool ext = (e->cob_id & CO_EMCY_COB_ID_FRAME) != 0;
    uint32_t id = e->cob_id & (ext ? CAN_ID_29_MASK : CAN_ID_11_MASK);
    if (len == 0) {
        e->stats.tx_failed++;
        return;
    }
    /* Built by hand: co_line_send_frame adds the line's FD flags and length rounding. */
    memset(&frame, 0, sizeof frame);
    frame.id = id;
    frame.flags = ext ? CO_FRAME_EXT : 0;
    frame.len = (uint8_t)len;
    memcpy(frame.data, data, len);
    if (!co_line_send_frame(e->line, &frame)) {
        e->stats.tx_failed++;
        return;
    }
    e->stats.sent++;
    e->has_sent = true;
    e->last_sent_us = co_line_now(e->line);
}

static uint64_t next_allowed(const co_emcy_t *e)
{
    return e->has_sent ? e->last_sent_us + (uint64_t)e->inhibit_100us * 100u : 0;
}

static void discard_queue(co_emcy_t *e)
{
    e->stats.suppressed += e->queue_count;
    e->queue_count = 0;
    e->queue_head = 0;
    co_timer_cancel(co_line_timers(e->line), &e->timer);
}

/* Send what waits, in order, as far as NMT state and inhibit time allow;
 * arm the timer for the rest. */
static void pump(co_emcy_t *e)
{
    if (!cob_id_valid(e->cob_id)) {
        discard_queue(e);
        return;
    }
    while (e->queue_count > 0 && e->may_send) {
        uint64_t at = next_allowed(e);
        if (at > co_line_now(e->line)) {
            co_timer_start(co_line_timers(e->line), &e->timer, at);
            return;
        }
        co_emcy_msg_t msg = e->queue[e->queue_head];
        e->queue_head = (uint16_t)((e->queue_head + 1u) % e->queue_capacity);
        e->queue_count--;
        transmit(e, &msg);
    }
    co_timer_cancel(co_line_timers(e->line), &e->timer);
}

static void on_inhibit_over(co_timer_t *timer, uint64_t now_us, void *user)
{
    (void)timer;
    (void)now_us;
    pump(user);
}

static void submit(co_emcy_t *e, const co_emcy_msg_t *msg)
{
    if (!cob_id_valid(e->cob_id)) {
        e->stats.suppressed++;
        return;
    }
    if (e->queue_count == 0 && e->may_send && next_allowed(e) <= co_line_now(e->line)) {
        transmit(e, msg);
        return;
    }
    if (e->queue_count >= e->queue_capacity) {
        e->stats.dropped++;
        e->overflow = true;
        return;
    }
    e->queue[(e->queue_head + e->queue_count) % e->queue_capacity] = *msg;
    e->queue_count++;
    e->stats.queued++;
    pump(e);
}

/* ------------------------------------------------------------ error state */

static void update_register(co_emcy_t *e)
{
    uint8_t reg = e->extra_register;
    for (uint16_t i = 0; i < e->active_count; i++) {
        reg |= (uint8_t)(CO_EMCY_ER_GENERIC | e->active[i].register_bits);
    }
    e->error_register = reg;
}

static co_emcy_active_t *find_active(const co_emcy_t *e, uint16_t code, uint8_t logical_device,
                                     uint16_t source)
{
    for (uint16_t i = 0; i < e->active_count; i++) {
        if (e->active[i].msg.code == code && e->active[i].msg.logical_device == logical_device &&
            e->active[i].source == source) {
            return &e->active[i];
        }
    }
    return NULL;
}

static void remove_active(co_emcy_t *e, co_emcy_active_t *a)
{
    size_t at = (size_t)(a - e->active);
    memmove(&e->active[at], &e->active[at + 1], (e->active_count - at - 1u) * sizeof *a);
    e->active_count--;
}

static void history_push(co_emcy_t *e, uint32_t value)
{
    if (e->history_limit == 0) {
        return;
    }
    if (e->history_count < e->history_limit) {
        e->history_count++;
    }
    memmove(&e->history[1], &e->history[0], (size_t)(e->history_count - 1u) * sizeof(uint32_t));
    e->history[0] = value;
}

static bool is_fd(const co_emcy_t *e)
{
    return co_line_mode(e->line) == CO_MODE_FD;
}

static bool error_ok(const co_emcy_error_t *err)
{
    return err != NULL && err->code != 0 && err->priority <= CO_EMCY_STATUS_PRIORITY_MASK &&
           err->time_stamp <= CO_EMCY_TIME_MAX;
}

/* The EMCY of an error as it stands, with the register as it is now. */
static co_emcy_msg_t message_of(const co_emcy_t *e, const co_emcy_active_t *a)
{
    co_emcy_msg_t msg = a->msg;
    msg.error_register = e->error_register;
    return msg;
}

/* An active-table entry for err, its EMCY occurred (repeated: again). */
static void fill_active(const co_emcy_t *e, co_emcy_active_t *a, const co_emcy_error_t *err,
                        bool repeated)
{
    memset(&a->msg, 0, sizeof a->msg);
    a->msg.code = err->code;
    memcpy(a->msg.msef, err->msef, CO_EMCY_MSEF_LEN);
    a->register_bits = (uint8_t)((co_emcy_code_register_bits(err->code) | err->register_bits) &
                                 ~0x40u);   /* bit 6 is reserved */
    a->source = err->source;
    if (is_fd(e)) {
        a->msg.logical_device = err->logical_device;
        a->msg.spec_number = err->spec_number;
        a->msg.time_stamp = err->time_stamp;
        a->msg.status = (uint8_t)(err->priority | CO_EMCY_STATUS_OCCURRED |
                                  (err->non_recoverable ? CO_EMCY_STATUS_NON_RECOVERABLE : 0) |
                                  (repeated ? CO_EMCY_STATUS_REPEATED : 0));
    }
}

co_emcy_result_t co_emcy_raise(co_emcy_t *e, const co_emcy_error_t *err)
{
    if (e == NULL || !error_ok(err)) {
        return CO_EMCY_BAD_ARGUMENT;
    }
    bool fd = is_fd(e);
    uint8_t logical_device = fd ? err->logical_device : 0;
    co_emcy_active_t *a = find_active(e, err->code, logical_device, err->source);
    co_emcy_result_t result = CO_EMCY_OK;
    if (a != NULL) {
        e->stats.repeated++;
        if (!fd) {
            return CO_EMCY_REPEATED;   /* once per error event (CiA 301) */
        }
        result = CO_EMCY_REPEATED;
    } else {
        if (e->active_count >= e->active_capacity) {
            e->stats.table_full++;
            return CO_EMCY_TABLE_FULL;
        }
        a = &e->active[e->active_count++];
    }
    fill_active(e, a, err, result == CO_EMCY_REPEATED);
    update_register(e);
    if (result == CO_EMCY_OK) {
        history_push(e, co_emcy_list_value(&a->msg));
    }
    mirror(e);
    co_emcy_msg_t msg = message_of(e, a);
    submit(e, &msg);
    return result;
}

/* The EMCY telling that error a went away (a still in the table). */
static co_emcy_msg_t removal_of(const co_emcy_t *e, const co_emcy_active_t *a,
                                const uint8_t msef[CO_EMCY_MSEF_LEN], uint64_t time_stamp)
{
    co_emcy_msg_t msg;
    if (is_fd(e)) {
        msg = a->msg;
        msg.status &= (uint8_t)~(CO_EMCY_STATUS_OCCURRED | CO_EMCY_STATUS_REPEATED);
        msg.time_stamp = time_stamp;
    } else {
        memset(&msg, 0, sizeof msg);   /* EEC 0x0000: error reset / no error */
    }
    memcpy(msg.msef, msef, CO_EMCY_MSEF_LEN);
    return msg;
}

co_emcy_result_t co_emcy_clear(co_emcy_t *e, const co_emcy_error_t *err)
{
    if (e == NULL || err == NULL || err->code == 0 || err->time_stamp > CO_EMCY_TIME_MAX) {
        return CO_EMCY_BAD_ARGUMENT;
    }
    co_emcy_active_t *a = find_active(e, err->code, is_fd(e) ? err->logical_device : 0,
                                      err->source);
    if (a == NULL) {
        return CO_EMCY_NOT_ACTIVE;
    }
    co_emcy_msg_t msg = removal_of(e, a, err->msef, err->time_stamp);
    remove_active(e, a);
    update_register(e);
    mirror(e);
    msg.error_register = e->error_register;
    submit(e, &msg);
    return CO_EMCY_OK;
}

uint16_t co_emcy_clear_all(co_emcy_t *e)
{
    static const uint8_t zero[CO_EMCY_MSEF_LEN] = {0};
    uint16_t cleared = e->active_count;
    if (cleared == 0) {
        return 0;
    }
    if (!is_fd(e)) {
        e->active_count = 0;
        update_register(e);
        mirror(e);
        co_emcy_msg_t msg = removal_of(e, NULL, zero, 0);
        submit(e, &msg);
        return cleared;
    }
    while (e->active_count > 0) {
        co_emcy_active_t *a = &e->active[0];
        co_emcy_msg_t msg = removal_of(e, a, a->msg.msef, a->msg.time_stamp);
        remove_active(e, a);
        update_register(e);
        msg.error_register = e->error_register;
        submit(e, &msg);
    }
    mirror(e);
    return cleared;
}

void co_emcy_set_extra_register(co_emcy_t *e, uint8_t bits)
{
    e->extra_register = (uint8_t)(bits & ~0x40u);
    update_register(e);
    mirror(e);
}

co_emcy_result_t co_emcy_signal(co_emcy_t *e, const co_emcy_error_t *err, bool occurred)
{
    if (e == NULL || !error_ok(err)) {
        return CO_EMCY_BAD_ARGUMENT;
    }
    co_emcy_active_t a;
    fill_active(e, &a, err, false);
    co_emcy_msg_t msg;
    if (occurred) {
        history_push(e, co_emcy_list_value(&a.msg));
        mirror(e);
        msg = message_of(e, &a);
    } else {
        msg = removal_of(e, &a, err->msef, err->time_stamp);
        msg.error_register = e->error_register;
    }
    submit(e, &msg);
    return CO_EMCY_OK;
}

bool co_emcy_is_active(const co_emcy_t *e, uint16_t code, uint8_t logical_device)
{
    return find_active(e, code, is_fd(e) ? logical_device : 0, 0) != NULL;
}

bool co_emcy_take_overflow(co_emcy_t *e)
{
    bool was = e->overflow;
    e->overflow = false;
    return was;
}

/* ------------------------------------------------------------- parameters */

static void apply_cob_id(co_emcy_t *e, uint32_t cob_id)
{
    e->cob_id = cob_id;
    pump(e);   /* invalid: what waits is discarded */
}

static void apply_inhibit(co_emcy_t *e, uint16_t inhibit_100us)
{
    e->inhibit_100us = inhibit_100us;
    pump(e);   /* re-times (or sends) what waits */
}

void co_emcy_set_cob_id(co_emcy_t *e, uint32_t cob_id)
{
    uint8_t v[4] = {(uint8_t)cob_id, (uint8_t)(cob_id >> 8), (uint8_t)(cob_id >> 16),
                    (uint8_t)(cob_id >> 24)};
    if (e->od == NULL || co_od_put(e->od, OD_COB_ID_EMCY, 0, v, 4) != CO_ABORT_NONE) {
        apply_cob_id(e, cob_id);
    }
}

void co_emcy_set_inhibit(co_emcy_t *e, uint16_t inhibit_100us)
{
    uint8_t v[2] = {(uint8_t)inhibit_100us, (uint8_t)(inhibit_100us >> 8)};
    if (e->od == NULL || co_od_put(e->od, OD_INHIBIT_EMCY, 0, v, 2) != CO_ABORT_NONE) {
        apply_inhibit(e, inhibit_100us);
    }
}

void co_emcy_set_node_id(co_emcy_t *e, uint8_t node_id)
{
    /* Without 0x1014 the COB-ID is the default one, 0x80 + node-id; with it
     * the OD's $NODEID default is reloaded by the reset that renumbers. */
    bool own_default = (e->cob_id & ~CO_EMCY_COB_ID_INVALID) ==
                       CO_EMCY_COB_ID_BASE + (uint32_t)e->node_id;
    e->node_id = node_id;
    if (own_default && (e->od == NULL || !co_od_has_index(e->od, OD_COB_ID_EMCY))) {
        apply_cob_id(e, (e->cob_id & CO_EMCY_COB_ID_INVALID) |
                            (CO_EMCY_COB_ID_BASE + (uint32_t)node_id));
    }
}

void co_emcy_set_nmt_state(co_emcy_t *e, co_nmt_state_t state)
{
    e->may_send = state == CO_NMT_PRE_OPERATIONAL || state == CO_NMT_OPERATIONAL;
    pump(e);
}

bool co_emcy_init(co_emcy_t *e, co_line_t *line, uint8_t node_id, const co_emcy_config_t *cfg)
{
    if (e == NULL || line == NULL || cfg == NULL || node_id < 1 || node_id > 127 ||
        cfg->queue == NULL || cfg->queue_capacity == 0 || cfg->active == NULL ||
        cfg->active_capacity == 0 || cfg->history_capacity > MAX_ARRAY_SUB ||
        (cfg->history_capacity > 0 && cfg->history == NULL)) {
        return false;
    }
    memset(e, 0, sizeof *e);
    e->line = line;
    e->node_id = node_id;
    e->cob_id = CO_EMCY_COB_ID_BASE + (uint32_t)node_id;
    e->queue = cfg->queue;
    e->queue_capacity = cfg->queue_capacity;
    e->active = cfg->active;
    e->active_capacity = cfg->active_capacity;
    e->history = cfg->history;
    e->history_capacity = cfg->history_capacity;
    e->history_limit = cfg->history_capacity;
    co_timer_init(&e->timer, on_inhibit_over, e);
    return true;
}

void co_emcy_deinit(co_emcy_t *e)
{
    co_emcy_detach_od(e);
    co_timer_cancel(co_line_timers(e->line), &e->timer);
    e->queue_count = 0;
}

/* ------------------------------------------------------------- OD binding */

static uint32_t producer_check_write(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *entry,
                                     const uint8_t *value, uint32_t length, void *user)
{
    (void)od;
    (void)xfer;
    (void)user;
    uint16_t index = co_od_entry_index(entry);
    uint8_t sub = co_od_entry_sub(entry);
    /* 0x1003:00: only 0 may be written (clears the history). */
    if (index == OD_ERROR_FIELD && sub == 0 && length == 1 && value[0] != 0) {
        return CO_ABORT_INVALID_VALUE;
    }
    /* The values the producer keeps (error register, history entries, the
     * FD active list and count) follow the active errors: a write by the
     * application would be replaced at once, so it is refused instead
     * (raise or clear an error to change them). Resets loading defaults do
     * not come here. */
    if (index == OD_ERROR_REGISTER || (index == OD_ERROR_FIELD && sub != 0) ||
        index == OD_ACTIVE_LIST || (index == OD_ACTIVE_HISTORY && sub == HISTORY_STATUS_SUB)) {
        return CO_ABORT_READ_ONLY;
    }
    return CO_ABORT_NONE;
}

static void producer_after_write(co_od_t *od, const co_od_entry_t *entry, co_od_origin_t origin,
                                 void *user)
{
    co_emcy_t *e = user;
    uint16_t index = co_od_entry_index(entry);
    uint8_t sub = co_od_entry_sub(entry);
    if (index == OD_COB_ID_EMCY && sub == 0) {
        uint32_t cob_id;
        if (co_od_get_u32(od, index, 0, &cob_id)) {
            apply_cob_id(e, cob_id);
        }
    } else if (index == OD_INHIBIT_EMCY && sub == 0) {
        uint16_t inhibit;
        if (co_od_get_u16(od, index, 0, &inhibit)) {
            apply_inhibit(e, inhibit);
        }
    } else if (index == OD_ERROR_FIELD || index == OD_ERROR_REGISTER ||
               index == OD_ACTIVE_LIST ||
               (index == OD_ACTIVE_HISTORY && sub == HISTORY_STATUS_SUB)) {
        uint8_t count;
        /* Writing 0 to 0x1003:00 clears the history; anything else written
         * into the producer's entries (a reset loading defaults, the
         * application) is replaced by the producer's values. */
        if (index == OD_ERROR_FIELD && sub == 0 && origin != CO_ORIGIN_RESTORE &&
            co_od_get_u8(od, index, 0, &count) && count == 0) {
            e->history_count = 0;
        }
        mirror(e);
    }
}

/* 0x1031:04: the active error history, one 20-byte FD EMCY record per
 * active error, newest first. */
static uint32_t history_size(co_od_t *od, const co_od_entry_t *entry, uint32_t *size, void *user)
{
    (void)od;
    const co_emcy_t *e = user;
    if (co_od_entry_index(entry) != OD_ACTIVE_HISTORY || co_od_entry_sub(entry) != HISTORY_DOMAIN_SUB) {
        return CO_ABORT_NO_DATA;
    }
    *size = (uint32_t)e->active_count * CO_EMCY_FD_LEN;
    return CO_ABORT_NONE;
}

static uint32_t history_read(co_od_t *od, const co_od_entry_t *entry, uint32_t offset,
                             uint8_t *buf, uint32_t cap, uint32_t *n, bool *last, void *user)
{
    uint32_t total;
    uint32_t abort = history_size(od, entry, &total, user);
    if (abort != CO_ABORT_NONE) {
        return abort;
    }
    const co_emcy_t *e = user;
    uint32_t given = 0;
    while (given < cap && offset + given < total) {
        uint32_t at = offset + given;
        uint8_t record[CO_EMCY_FD_LEN];
        co_emcy_msg_t msg = message_of(e, newest(e, (uint16_t)(at / CO_EMCY_FD_LEN)));
        if (co_emcy_encode_fd(&msg, record, sizeof record) == 0) {
            return CO_ABORT_GENERAL;
        }
        uint32_t from = at % CO_EMCY_FD_LEN;
        uint32_t take = CO_EMCY_FD_LEN - from;
        if (take > cap - given) {
            take = cap - given;
        }
        memcpy(buf + given, record + from, take);
        given += take;
    }
    *n = given;
    *last = offset + given >= total;
    return CO_ABORT_NONE;
}

static const co_od_handler_t producer_handler = {
    .check_write = producer_check_write,
    .after_write = producer_after_write,
};

static const co_od_handler_t fd_history_handler = {
    .after_write = producer_after_write,
    .domain_size = history_size,
    .domain_read = history_read,
};

bool co_emcy_attach_od(co_emcy_t *e, co_od_t *od)
{
    if (e == NULL || od == NULL || !od->sealed || e->od != NULL) {
        return false;
    }
    /* Two ranges: 0x1001..0x1015 (register, history, COB-ID, inhibit) and
     * 0x1031..0x1032; other entries inside are ignored by the handlers. The
     * domain callbacks stay out of the first range (0x1001..0x1015 has no
     * EMCY domain; another service's would be shadowed). */
    if (!co_od_subscribe(od, OD_ERROR_REGISTER, 0, OD_INHIBIT_EMCY, 0xFF, &producer_handler, e)) {
        return false;
    }
    if (!co_od_subscribe(od, OD_ACTIVE_HISTORY, 0, OD_ACTIVE_LIST, 0xFF, &fd_history_handler, e)) {
        co_od_unsubscribe(od, &producer_handler, e);
        return false;
    }
    e->od = od;
    uint32_t cob_id;
    uint16_t inhibit;
    if (co_od_get_u32(od, OD_COB_ID_EMCY, 0, &cob_id)) {
        e->cob_id = cob_id;
    }
    if (co_od_get_u16(od, OD_INHIBIT_EMCY, 0, &inhibit)) {
        e->inhibit_100us = inhibit;
    }
    if (co_od_has_index(od, OD_ERROR_FIELD)) {
        uint8_t subs = array_length(od, OD_ERROR_FIELD);
        e->history_limit = subs < e->history_capacity ? subs : e->history_capacity;
        if (e->history_count > e->history_limit) {
            e->history_count = e->history_limit;
        }
    }
    mirror(e);
    pump(e);
    return true;
}

void co_emcy_detach_od(co_emcy_t *e)
{
    if (e->od != NULL) {
        co_od_unsubscribe(e->od, &producer_handler, e);
        co_od_unsubscribe(e->od, &fd_history_handler, e);
        e->od = NULL;
        e->history_limit = e->history_capacity;
    }
}

/* ---------------------------------------------------------------- consumer */

static bool entry_matches(uint32_t cob_id, const co_frame_t *frame)
{
    if (!cob_id_valid(cob_id)) {
        return false;
    }
    bool ext = (cob_id & CO_EMCY_COB_ID_FRAME) != 0;
    if (ext != ((frame->flags & CO_FRAME_EXT) != 0)) {
        return false;
    }
    return frame->id == (cob_id & (ext ? CAN_ID_29_MASK : CAN_ID_11_MASK));
}

static void rebuild_id_map(co_emcy_consumer_t *c)
{
    memset(c->id_used, 0, sizeof c->id_used);
    for (unsigned node = 1; node < CO_EMCY_MAX_NODES; node++) {
        uint32_t cob_id = c->cob_id[node];
        if (cob_id_valid(cob_id) && !(cob_id & CO_EMCY_COB_ID_FRAME)) {
            uint32_t id = cob_id & CAN_ID_11_MASK;
            c->id_used[id / 32] |= 1u << (id % 32);
        }
    }
}

static bool on_other_frame(co_line_t *line, const co_frame_t *frame, void *user)
{
    co_emcy_consumer_t *c = user;
    if (frame->flags & CO_FRAME_RTR) {
        return false;
    }
    if (!(frame->flags & CO_FRAME_EXT) &&
        (frame->id > CAN_ID_11_MASK || !(c->id_used[frame->id / 32] & (1u << (frame->id % 32))))) {
        return false;
    }
    /* The lowest node-id whose entry names the CAN-ID gets it. */
    for (unsigned node = 1; node < CO_EMCY_MAX_NODES; node++) {
        if (!entry_matches(c->cob_id[node], frame)) {
            continue;
        }
        co_emcy_msg_t msg;
        bool ok = co_line_mode(line) == CO_MODE_FD
                      ? co_emcy_decode_fd(frame->data, frame->len, &msg)
                      : co_emcy_decode_classic(frame->data, frame->len, &msg);
        if (!ok) {
            c->stats.rx_bad_length++;
            return true;
        }
        c->stats.received++;
        if (c->on_emcy) {
            c->on_emcy(c, (uint8_t)node, &msg, c->user);
        }
        if (c->tap) {
            c->tap(c, (uint8_t)node, &msg, c->tap_user);
        }
        return true;
    }
    return false;
}

bool co_emcy_consumer_init(co_emcy_consumer_t *c, co_line_t *line, co_emcy_rx_fn on_emcy,
                           void *user)
{
    if (c == NULL || line == NULL) {
        return false;
    }
    memset(c, 0, sizeof *c);
    c->line = line;
    c->on_emcy = on_emcy;
    c->user = user;
    for (unsigned node = 0; node < CO_EMCY_MAX_NODES; node++) {
        c->cob_id[node] = CO_EMCY_COB_ID_INVALID;
    }
    return co_line_subscribe_other(line, on_other_frame, c);
}

void co_emcy_consumer_set_tap(co_emcy_consumer_t *c, co_emcy_rx_fn fn, void *user)
{
    c->tap = fn;
    c->tap_user = fn ? user : NULL;
}

void co_emcy_consumer_deinit(co_emcy_consumer_t *c)
{
    co_emcy_consumer_detach_od(c);
    co_line_unsubscribe_other(c->line, on_other_frame, c);
}

bool co_emcy_consumer_set_entry(co_emcy_consumer_t *c, uint8_t node_id, uint32_t cob_id)
{
    if (node_id < 1 || node_id >= CO_EMCY_MAX_NODES) {
        return false;
    }
    c->cob_id[node_id] = cob_id;
    rebuild_id_map(c);
    return true;
}

bool co_emcy_consumer_watch(co_emcy_consumer_t *c, uint8_t node_id)
{
    return co_emcy_consumer_set_entry(c, node_id, CO_EMCY_COB_ID_BASE + (uint32_t)node_id);
}

void co_emcy_consumer_unwatch(co_emcy_consumer_t *c, uint8_t node_id)
{
    (void)co_emcy_consumer_set_entry(c, node_id, CO_EMCY_COB_ID_INVALID);
}

uint32_t co_emcy_consumer_get_entry(const co_emcy_consumer_t *c, uint8_t node_id)
{
    return node_id < CO_EMCY_MAX_NODES ? c->cob_id[node_id] : CO_EMCY_COB_ID_INVALID;
}

static uint32_t consumer_check_write(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *entry,
                                     const uint8_t *value, uint32_t length, void *user)
{
    (void)od;
    (void)xfer;
    (void)entry;
    (void)user;
    if (length != 4) {
        return CO_ABORT_NONE;   /* the OD's own type check answers */
    }
    uint32_t v = (uint32_t)value[0] | ((uint32_t)value[1] << 8) | ((uint32_t)value[2] << 16) |
                 ((uint32_t)value[3] << 24);
    /* An 11-bit entry must not use bits 11..28. */
    if (!(v & CO_EMCY_COB_ID_FRAME) && (v & CAN_ID_29_MASK & ~CAN_ID_11_MASK)) {
        return CO_ABORT_INVALID_VALUE;
    }
    return CO_ABORT_NONE;
}

static void consumer_after_write(co_od_t *od, const co_od_entry_t *entry, co_od_origin_t origin,
                                 void *user)
{
    (void)origin;
    uint32_t cob_id;
    uint8_t node_id = co_od_entry_sub(entry);
    if (co_od_get_u32(od, OD_EMCY_CONSUMER, node_id, &cob_id)) {
        (void)co_emcy_consumer_set_entry(user, node_id, cob_id);
    }
}

static const co_od_handler_t consumer_handler = {
    .check_write = consumer_check_write,
    .after_write = consumer_after_write,
};

bool co_emcy_consumer_attach_od(co_emcy_consumer_t *c, co_od_t *od)
{
    if (c == NULL || od == NULL || !od->sealed || c->od != NULL) {
        return false;
    }
    if (!co_od_subscribe(od, OD_EMCY_CONSUMER, 1, OD_EMCY_CONSUMER, CO_EMCY_MAX_NODES - 1,
                         &consumer_handler, c)) {
        return false;
    }
    c->od = od;
    for (unsigned node = 1; node < CO_EMCY_MAX_NODES; node++) {
        uint32_t cob_id;
        if (co_od_get_u32(od, OD_EMCY_CONSUMER, (uint8_t)node, &cob_id)) {
            c->cob_id[node] = cob_id;
        }
    }
    rebuild_id_map(c);
    return true;
}

void co_emcy_consumer_detach_od(co_emcy_consumer_t *c)
{
    if (c->od != NULL) {
        co_od_unsubscribe(c->od, &consumer_handler, c);
        c->od = NULL;
    }
}
