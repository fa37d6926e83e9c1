/* SRDO producer and consumer (see co_srdo.h). */
#include "canopenfd/co_srdo.h"

#include "co_crc.h"

#include <string.h>

#define US_PER_MS 1000u

/* ------------------------------------------------------ configuration */

static uint16_t crc_le(uint16_t crc, uint32_t value, size_t bytes)
{
    uint8_t b[4];
    for (size_t i = 0; i < bytes; i++) {
        b[i] = (uint8_t)(value >> (8u * i));
    }
    return co_crc16_ccitt(crc, b, bytes);
}

uint16_t co_srdo_crc(const co_srdo_config_t *config)
{
    uint16_t crc = crc_le(0, config->direction, 1);
    crc = crc_le(crc, config->sct_ms, 2);
    crc = crc_le(crc, config->srvt_ms, 1);
    crc = crc_le(crc, config->cob_id_normal, 4);
    crc = crc_le(crc, config->cob_id_inverted, 4);
    crc = crc_le(crc, config->map_count, 1);
    uint8_t count = config->map_count <= CO_SRDO_MAX_MAPPED ? config->map_count
                                                            : CO_SRDO_MAX_MAPPED;
    for (uint8_t i = 0; i < count; i++) {
        crc = crc_le(crc, (uint32_t)i + 1u, 1);
        crc = crc_le(crc, config->map[i], 4);
    }
    return crc;
}

/* Odd sub-indices map the normal frame, even ones the inverted frame: both
 * halves must be whole bytes and add up to the same 1..8 bytes. */
static co_srdo_param_t check_mapping(const co_srdo_config_t *config, uint8_t *length)
{
    if (config->map_count == 0 || config->map_count > CO_SRDO_MAX_MAPPED ||
        (config->map_count & 1u) != 0) {
        return CO_SRDO_PARAM_MAP_COUNT;
    }
    unsigned bytes[2] = {0, 0};
    for (uint8_t i = 0; i < config->map_count; i++) {
        uint8_t bits = (uint8_t)config->map[i];
        if (bits == 0 || (bits & 7u) != 0) {
            return CO_SRDO_PARAM_MAP_LENGTH;
        }
        bytes[i & 1u] += bits / 8u;
    }
    if (bytes[0] != bytes[1] || bytes[0] > CO_SRDO_MAX_DATA) {
        return CO_SRDO_PARAM_MAP_LENGTH;
    }
    if (length) {
        *length = (uint8_t)bytes[0];
    }
    return CO_SRDO_PARAM_OK;
}

co_srdo_param_t co_srdo_check(const co_srdo_config_t *config, uint8_t *length)
{
    if (length) {
        *length = 0;
    }
    if (config->direction > CO_SRDO_CONSUME) {
        return CO_SRDO_PARAM_DIRECTION;
    }
    if (config->direction == CO_SRDO_OFF) {
        return CO_SRDO_PARAM_OK;
    }
    if (config->sct_ms == 0) {
        return CO_SRDO_PARAM_SCT;
    }
    if (config->srvt_ms == 0) {
        return CO_SRDO_PARAM_SRVT;
    }
    if (config->transmission_type != CO_SRDO_TRANSMISSION_TYPE) {
        return CO_SRDO_PARAM_TRANSMISSION_TYPE;
    }
    uint32_t normal = config->cob_id_normal;
    if (normal < CO_SRDO_COB_ID_FIRST || normal >= CO_SRDO_COB_ID_LAST || (normal & 1u) == 0) {
        return CO_SRDO_PARAM_COB_ID_NORMAL;
    }
    if (config->cob_id_inverted != normal + 1u) {
        return CO_SRDO_PARAM_COB_ID_INVERTED;
    }
    return check_mapping(config, length);
}

const char *co_srdo_violation_name(co_srdo_violation_t why)
{
    switch (why) {
    case CO_SRDO_NONE: return "none";
    case CO_SRDO_INVERTED_MISMATCH: return "inverted frame does not match";
    case CO_SRDO_SRVT_EXCEEDED: return "SRVT exceeded";
    case CO_SRDO_SCT_EXCEEDED: return "SCT exceeded";
    case CO_SRDO_WRONG_LENGTH: return "wrong length";
    case CO_SRDO_INVERTED_MISSING: return "inverted frame missing";
    case CO_SRDO_INVERTED_UNEXPECTED: return "inverted frame without normal frame";
    case CO_SRDO_CONFIG_INVALID: return "configuration not valid (0x13FE)";
    case CO_SRDO_CRC_MISMATCH: return "configuration CRC mismatch (0x13FF)";
    case CO_SRDO_BAD_PARAMETER: return "parameter out of range";
    case CO_SRDO_GFC: return "global fail-safe command";
    case CO_SRDO_TX_FAILED: return "tx queue full";
    case CO_SRDO_APPLICATION: return "the application's reason";
    }
    return "unknown";
}

/* ------------------------------------------------------------ running */

static bool running(const co_srdo_t *s)
{
    return s->state == CO_SRDO_WAITING || s->state == CO_SRDO_RUNNING;
}

static void stop_timers(co_srdo_t *s)
{
    co_timer_cancel(co_line_timers(s->line), &s->cycle_timer);
    co_timer_cancel(co_line_timers(s->line), &s->srvt_timer);
    s->inverted_due = false;
}

void co_srdo_fail(co_srdo_t *srdo, co_srdo_violation_t why)
{
    if (srdo->state == CO_SRDO_SAFE || why == CO_SRDO_NONE) {
        return;   /* latched: the first cause is the one reported */
    }
    stop_timers(srdo);
    srdo->state = CO_SRDO_SAFE;
    srdo->violation = why;
    srdo->stats.violations++;
    if (srdo->on_safe) {
        srdo->on_safe(srdo, why, srdo->user);
    }
}

/* The mapped variables' bytes: the normal frame's into s->data, the
 * inverted frame's into inverted. */
static void pack_od(co_srdo_t *s, uint8_t *inverted)
{
    uint16_t bits = (uint16_t)(s->length * 8u);
    co_pdo_map_pack(s->od, s->items, s->normal_items, bits, s->data);
    co_pdo_map_pack(s->od, s->items + s->normal_items, s->inverted_items, bits, inverted);
}

static bool complements(const uint8_t *normal, const uint8_t *inverted, uint8_t length)
{
    for (uint8_t i = 0; i < length; i++) {
        if ((normal[i] ^ inverted[i]) != 0xFFu) {
            return false;
        }
    }
    return true;
}

static void send_pair(co_srdo_t *s)
{
    uint8_t inverted[CO_SRDO_MAX_DATA];
    if (s->od) {
        pack_od(s, inverted);
        /* two variables that disagree never reach the bus as a pair */
        if (!complements(s->data, inverted, s->length)) {
            co_srdo_fail(s, CO_SRDO_INVERTED_MISMATCH);
            return;
        }
    } else {
        for (uint8_t i = 0; i < s->length; i++) {
            inverted[i] = (uint8_t)(~s->data[i]);
        }
    }
    /* Both frames queued together: the inverted one follows at once, well
     * within any SRVT, and the line keeps their order. */
    if (co_line_tx_room(s->line) < 2 ||
        !co_line_send(s->line, s->config.cob_id_normal, s->data, s->length) ||
        !co_line_send(s->line, s->config.cob_id_inverted, inverted, s->length)) {
        co_srdo_fail(s, CO_SRDO_TX_FAILED);
        return;
    }
    s->stats.pairs_sent++;
    s->state = CO_SRDO_RUNNING;
}

/* Normal bytes into the odd sub-indices' variables, inverted into the even. */
static void unpack_od(co_srdo_t *s, const uint8_t *normal, const uint8_t *inverted)
{
    co_pdo_map_unpack(s->od, s->items, s->normal_items, normal);
    co_pdo_map_unpack(s->od, s->items + s->normal_items, s->inverted_items, inverted);
}

static void on_cycle(co_timer_t *timer, uint64_t now_us, void *user)
{
    (void)now_us;
    co_srdo_t *s = user;
    if (s->config.direction == CO_SRDO_CONSUME) {
        co_srdo_fail(s, CO_SRDO_SCT_EXCEEDED);
        return;
    }
    send_pair(s);
    if (running(s)) {
        co_timer_start(co_line_timers(s->line), timer,
                       timer->deadline_us + (uint64_t)s->config.sct_ms * US_PER_MS);
    }
}

static void on_srvt(co_timer_t *timer, uint64_t now_us, void *user)
{
    (void)timer;
    (void)now_us;
    co_srdo_fail(user, CO_SRDO_SRVT_EXCEEDED);
}

static void arm_sct(co_srdo_t *s, uint64_t from_us)
{
    s->sct_deadline_us = from_us + (uint64_t)s->config.sct_ms * US_PER_MS;
    /* a frame at the deadline itself is in time: the timer fires just after */
    co_timer_start(co_line_timers(s->line), &s->cycle_timer, s->sct_deadline_us + 1u);
}

static void on_normal(co_srdo_t *s, const co_frame_t *frame, uint64_t now)
{
    /* rx runs before the timers in a line's turn: late frames are judged here */
    if (now > s->sct_deadline_us) {
        co_srdo_fail(s, CO_SRDO_SCT_EXCEEDED);
    } else if (s->inverted_due) {
        co_srdo_fail(s, CO_SRDO_INVERTED_MISSING);
    } else if (frame->len != s->length) {
        co_srdo_fail(s, CO_SRDO_WRONG_LENGTH);
    } else {
        memcpy(s->normal, frame->data, s->length);
        s->inverted_due = true;
        s->normal_at_us = now;
        co_timer_start(co_line_timers(s->line), &s->srvt_timer,
                       now + (uint64_t)s->config.srvt_ms * US_PER_MS + 1u);
        arm_sct(s, now);
    }
}

static void on_inverted(co_srdo_t *s, const co_frame_t *frame, uint64_t now)
{
    if (!s->inverted_due) {
        co_srdo_fail(s, CO_SRDO_INVERTED_UNEXPECTED);
        return;
    }
    if (now > s->normal_at_us + (uint64_t)s->config.srvt_ms * US_PER_MS) {
        co_srdo_fail(s, CO_SRDO_SRVT_EXCEEDED);
        return;
    }
    if (frame->len != s->length) {
        co_srdo_fail(s, CO_SRDO_WRONG_LENGTH);
        return;
    }
    if (!complements(s->normal, frame->data, s->length)) {
        co_srdo_fail(s, CO_SRDO_INVERTED_MISMATCH);
        return;
    }
    co_timer_cancel(co_line_timers(s->line), &s->srvt_timer);
    s->inverted_due = false;
    memcpy(s->data, s->normal, s->length);
    if (s->od) {
        unpack_od(s, s->normal, frame->data);
    }
    s->state = CO_SRDO_RUNNING;
    s->stats.pairs_valid++;
}

static void on_frame(co_line_t *line, const co_frame_t *frame, void *user)
{
    co_srdo_t *s = user;
    if (!running(s)) {
        s->stats.ignored++;
        return;
    }
    uint64_t now = co_line_now(line);
    if (frame->id == s->config.cob_id_normal) {
        on_normal(s, frame, now);
    } else {
        on_inverted(s, frame, now);
    }
}

/* The state leaves SAFE (it was SAFE with `had` as its violation). */
static void left_safe(co_srdo_t *s, co_srdo_violation_t had)
{
    if (s->on_leave) {
        s->on_leave(s, had, s->user);
    }
}

/* Entry into operational, or a restart. */
static void start_from(co_srdo_t *s)
{
    stop_timers(s);
    s->violation = CO_SRDO_NONE;
    if (!s->operational || s->config.direction == CO_SRDO_OFF) {
        s->state = CO_SRDO_STOPPED;
        return;
    }
    s->state = CO_SRDO_WAITING;
    if (s->config_fault != CO_SRDO_NONE) {
        co_srdo_fail(s, s->config_fault);
        return;
    }
    uint64_t now = co_line_now(s->line);
    if (s->config.direction == CO_SRDO_PRODUCE) {
        co_timer_start(co_line_timers(s->line), &s->cycle_timer, now);
    } else {
        arm_sct(s, now);
    }
}

static void start(co_srdo_t *s)
{
    bool was_safe = s->state == CO_SRDO_SAFE;
    co_srdo_violation_t had = s->violation;
    start_from(s);
    /* a configuration fault fails again at once: still safe, nothing left */
    if (was_safe && s->state != CO_SRDO_SAFE) {
        left_safe(s, had);
    }
}

void co_srdo_init(co_srdo_t *srdo, co_line_t *line, co_srdo_fn on_safe, void *user)
{
    memset(srdo, 0, sizeof *srdo);
    srdo->line = line;
    srdo->on_safe = on_safe;
    srdo->user = user;
    co_timer_init(&srdo->cycle_timer, on_cycle, srdo);
    co_timer_init(&srdo->srvt_timer, on_srvt, srdo);
}

static void unsubscribe(co_srdo_t *s)
{
    if (s->subscribed) {
        co_line_unsubscribe(s->line, on_frame, s);
        s->subscribed = false;
    }
}

void co_srdo_deinit(co_srdo_t *srdo)
{
    stop_timers(srdo);
    unsubscribe(srdo);
    srdo->state = CO_SRDO_STOPPED;
}

bool co_srdo_configure(co_srdo_t *srdo, const co_srdo_config_t *config, uint8_t valid,
                       uint16_t signature)
{
    if (srdo->operational) {
        return false;
    }
    unsubscribe(srdo);
    srdo->config = *config;
    srdo->param_error = co_srdo_check(config, &srdo->length);
    srdo->config_fault = valid != CO_SRDO_CONFIG_VALID              ? CO_SRDO_CONFIG_INVALID
                         : srdo->param_error != CO_SRDO_PARAM_OK    ? CO_SRDO_BAD_PARAMETER
                         : co_srdo_crc(config) != signature         ? CO_SRDO_CRC_MISMATCH
                                                                    : CO_SRDO_NONE;
    memset(srdo->data, 0, sizeof srdo->data);
    srdo->od = NULL;   /* a new mapping is bound again (co_srdo_bind_od) */
    co_srdo_violation_t had = srdo->violation;
    bool was_safe = srdo->state == CO_SRDO_SAFE;
    srdo->state = CO_SRDO_STOPPED;
    srdo->violation = CO_SRDO_NONE;
    if (was_safe) {
        left_safe(srdo, had);   /* a GFC heard outside operational */
    }
    if (config->direction == CO_SRDO_CONSUME && srdo->param_error == CO_SRDO_PARAM_OK) {
        if (!co_line_subscribe(srdo->line, config->cob_id_normal, config->cob_id_inverted,
                               on_frame, srdo)) {
            return false;
        }
        srdo->subscribed = true;
    }
    return true;
}

void co_srdo_set_nmt_state(co_srdo_t *srdo, co_nmt_state_t state)
{
    bool operational = state == CO_NMT_OPERATIONAL;
    if (operational == srdo->operational) {
        return;
    }
    srdo->operational = operational;
    start(srdo);
}

bool co_srdo_set_data(co_srdo_t *srdo, const uint8_t *data, size_t length)
{
    if (srdo->config.direction != CO_SRDO_PRODUCE || srdo->param_error != CO_SRDO_PARAM_OK ||
        length != srdo->length) {
        return false;
    }
    memcpy(srdo->data, data, length);
    if (srdo->od) {
        uint8_t inverted[CO_SRDO_MAX_DATA];
        for (size_t i = 0; i < length; i++) {
            inverted[i] = (uint8_t)(~data[i]);
        }
        unpack_od(srdo, data, inverted);
    }
    return true;
}

/* Items of one half (odd or even sub-indices), placed one after another. */
static uint32_t bind_half(co_srdo_t *s, co_od_t *od, uint8_t first, co_pdo_map_item_t *items,
                          uint8_t *count)
{
    bool consumer = s->config.direction == CO_SRDO_CONSUME;
    uint16_t bit = 0;
    *count = 0;
    for (uint8_t i = first; i < s->config.map_count; i = (uint8_t)(i + 2u)) {
        co_pdo_map_item_t it;
        uint32_t abort = co_pdo_map_check_entry(od, consumer, s->config.map[i], &it);
        if (abort != 0) {
            return abort;
        }
        if (it.flags & CO_PDO_ITEM_DUMMY) {
            return CO_ABORT_NO_MAP;   /* a safety datum is never skipped */
        }
        it.bit = bit;
        it.flags |= CO_PDO_ITEM_BYTES;   /* check_mapping allows whole bytes only */
        bit = (uint16_t)(bit + it.bits);
        items[(*count)++] = it;
    }
    return 0;
}

uint32_t co_srdo_bind_od(co_srdo_t *srdo, co_od_t *od)
{
    srdo->od = NULL;
    if (od == NULL || srdo->config.direction == CO_SRDO_OFF) {
        return 0;
    }
    if (srdo->operational) {
        return CO_ABORT_DATA_STATE;
    }
    if (srdo->param_error != CO_SRDO_PARAM_OK) {
        return CO_ABORT_PARAM_INCOMPATIBLE;   /* already latched as BAD_PARAMETER */
    }
    uint32_t abort = bind_half(srdo, od, 0, srdo->items, &srdo->normal_items);
    if (abort == 0) {
        abort = bind_half(srdo, od, 1, srdo->items + srdo->normal_items,
                          &srdo->inverted_items);
    }
    if (abort != 0) {
        if (srdo->config_fault == CO_SRDO_NONE) {
            srdo->config_fault = CO_SRDO_BAD_PARAMETER;
        }
        return abort;
    }
    srdo->od = od;
    return 0;
}

size_t co_srdo_data(const co_srdo_t *srdo, uint8_t *out)
{
    if (srdo->state != CO_SRDO_RUNNING || srdo->config.direction != CO_SRDO_CONSUME) {
        return 0;
    }
    memcpy(out, srdo->data, srdo->length);
    return srdo->length;
}

void co_srdo_restart(co_srdo_t *srdo)
{
    start(srdo);
}

void co_srdo_set_leave_fn(co_srdo_t *srdo, co_srdo_fn on_leave)
{
    srdo->on_leave = on_leave;
}
