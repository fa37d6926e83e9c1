/* PDO service (see co_pdo.h). */
#include "canopenfd/co_pdo.h"

#include "canopenfd/co_assert.h"
#include "co_cob_id.h"   /* co_cob_id_restricted: CiA 301's restricted CAN-IDs */

#include <string.h>

#define COB_INVALID 0x80000000u
#define COB_NO_RTR 0x40000000u
#define COB_EXT 0x20000000u
#define COB_ID_29 0x1FFFFFFFu
#define COB_ID_11 0x7FFu

enum {
    SUB_COB_ID = 1,
    SUB_TYPE = 2,
    SUB_INHIBIT = 3,
    SUB_EVENT = 5,
    SUB_SYNC_START = 6,
    SYNC_START_MAX = 240
};

/* ------------------------------------------------------------ helpers */

static uint16_t comm_index(const co_pdo_channel_t *ch)
{
    return (uint16_t)((ch->is_rpdo ? CO_PDO_RPDO_COMM : CO_PDO_TPDO_COMM) + ch->number - 1u);
}

static uint16_t map_index(const co_pdo_channel_t *ch)
{
    return (uint16_t)((ch->is_rpdo ? CO_PDO_RPDO_MAP : CO_PDO_TPDO_MAP) + ch->number - 1u);
}

/* Channel + 1 of PDO number (1..512), 0 when there is none: a binary search
 * in the RPDO or the TPDO part of the channel table (both sorted). */
static uint16_t slot_of(const co_pdo_t *pdo, bool is_rpdo, uint16_t number)
{
    uint16_t lo = is_rpdo ? 0 : pdo->rpdo_count;
    uint16_t hi = is_rpdo ? pdo->rpdo_count : pdo->channel_count;
    while (lo < hi) {
        uint16_t mid = (uint16_t)(lo + (hi - lo) / 2u);
        uint16_t n = pdo->channels[mid].number;
        if (n == number) {
            return (uint16_t)(mid + 1u);
        }
        if (n < number) {
            lo = (uint16_t)(mid + 1u);
        } else {
            hi = mid;
        }
    }
    return 0;
}

/* Channel + 1 of the RPDO (rtr: the TPDO answering remote frames) that takes
 * an 11-bit CAN-ID, 0 when none: the table when there is one, else a scan. */
static uint16_t id_slot(const co_pdo_t *pdo, bool rtr, uint32_t id)
{
    const uint16_t *map = rtr ? pdo->rtr_map : pdo->rx_map;
    uint16_t i;
    CO_ASSERT(id < CO_LINE_ID_MAP_SIZE);
    if (map != NULL) {
        return map[id];
    }
    for (i = 0; i < pdo->channel_count; i++) {
        const co_pdo_channel_t *ch = &pdo->channels[i];
        if (ch->takes_id && ch->can_id == id && ch->is_rpdo != rtr) {
            return (uint16_t)(i + 1u);
        }
    }
    return 0;
}

/* The channel starts or stops taking its 11-bit CAN-ID. */
static void take_id(co_pdo_t *pdo, co_pdo_channel_t *ch, bool take)
{
    uint16_t *map = ch->is_rpdo ? pdo->rx_map : pdo->rtr_map;
    ch->takes_id = take;
    if (map != NULL) {
        map[ch->can_id] = take ? (uint16_t)(ch - pdo->channels + 1) : 0u;
    }
}

/* The channel of a slot taken from the number or CAN-ID tables (0 = none). */
static co_pdo_channel_t *channel_at(const co_pdo_t *pdo, uint16_t slot)
{
    CO_ASSERT(slot <= pdo->channel_count);
    return slot != 0 ? &pdo->channels[slot - 1u] : NULL;
}

static co_pdo_channel_t *channel_of(co_pdo_t *pdo, bool is_rpdo, uint16_t number)
{
    return channel_at(pdo, slot_of(pdo, is_rpdo, number));
}

/* The channel an index of 0x1400..0x1BFF belongs to. */
static co_pdo_channel_t *channel_of_index(co_pdo_t *pdo, uint16_t index, bool *is_map)
{
    bool is_rpdo = index < CO_PDO_TPDO_COMM;
    uint16_t base = is_rpdo ? CO_PDO_RPDO_COMM : CO_PDO_TPDO_COMM;
    uint16_t offset = (uint16_t)(index - base);
    *is_map = offset >= CO_PDO_MAX_NUMBER;
    return channel_of(pdo, is_rpdo, (uint16_t)(offset % CO_PDO_MAX_NUMBER + 1u));
}

static bool is_sync_type(uint8_t type)
{
    return type <= CO_PDO_TYPE_SYNC_MAX;
}

static bool is_event_type(uint8_t type)
{
    return type >= CO_PDO_TYPE_EVENT_MANUFACTURER;
}

/* Mapping sub 0 values that make the PDO an MPDO (CiA 301). */
static bool is_mpdo_count(uint8_t count)
{
    return count == CO_PDO_MAP_SAM || count == CO_PDO_MAP_DAM;
}

/* 0 or the abort code for a transmission type on this kind of PDO/line. */
static uint32_t check_type(const co_pdo_t *pdo, bool is_rpdo, uint8_t type)
{
    if (type > CO_PDO_TYPE_SYNC_MAX && type < CO_PDO_TYPE_RTR_SYNC) {
        return CO_ABORT_INVALID_VALUE;   /* reserved */
    }
    if ((type == CO_PDO_TYPE_RTR_SYNC || type == CO_PDO_TYPE_RTR_EVENT) &&
        (is_rpdo || co_line_mode(pdo->line) == CO_MODE_FD)) {
        return CO_ABORT_INVALID_VALUE;   /* RTR-only: classic TPDOs only */
    }
    return 0;
}

/* 0 or the abort code for a valid COB-ID value (bit 31 clear). */
static uint32_t check_cob_id_value(uint32_t cob)
{
    if (cob & COB_EXT) {
        return 0;
    }
    if ((cob & (COB_ID_29 & ~COB_ID_11)) != 0 || co_cob_id_restricted(cob & COB_ID_11)) {
        return CO_ABORT_INVALID_VALUE;
    }
    return 0;
}

static void report(co_pdo_t *pdo, const co_pdo_channel_t *ch, uint16_t code)
{
    if (pdo->ind != NULL && pdo->ind->error != NULL) {
        pdo->ind->error(pdo, code, ch->is_rpdo, ch->number, pdo->user);
    }
}

static void tell_rx_error(co_pdo_t *pdo, const co_pdo_channel_t *ch, uint16_t code, bool active,
                          co_pdo_rx_cause_t cause)
{
    if (pdo->ind != NULL && pdo->ind->rx_error_changed != NULL) {
        pdo->ind->rx_error_changed(pdo, ch->number, code, active, cause, pdo->user);
    }
}

/* The state is cleared before telling, so a callback sees it ended. */
static void end_length_error(co_pdo_t *pdo, co_pdo_channel_t *ch, co_pdo_rx_cause_t cause)
{
    uint16_t code = ch->rx_error;
    if (code != 0) {
        ch->rx_error = 0;
        tell_rx_error(pdo, ch, code, false, cause);
    }
}

static void end_timeout(co_pdo_t *pdo, co_pdo_channel_t *ch, co_pdo_rx_cause_t cause)
{
    if (ch->timed_out) {
        ch->timed_out = false;
        tell_rx_error(pdo, ch, CO_PDO_EMCY_RPDO_TIMEOUT, false, cause);
    }
}

static uint64_t ms_to_us(uint16_t ms)
{
    return (uint64_t)ms * 1000u;
}

/* ------------------------------------------------------------ sending */

/* False when the before-send callback disabled the PDO (it may write the
 * OD, PDO parameters included). */
static bool sample(co_pdo_t *pdo, co_pdo_channel_t *ch)
{
    if (pdo->ind != NULL && pdo->ind->before_send != NULL) {
        ch->sampling = true;   /* a trigger from inside the callback is refused */
        pdo->ind->before_send(pdo, ch->number, pdo->user);
        ch->sampling = false;
        if (!ch->active || !pdo->operational) {
            return false;
        }
    }
    co_pdo_map_pack(pdo->od, ch->map, ch->map_count, ch->bits, ch->buf);
    ch->len = (uint8_t)((ch->bits + 7u) / 8u);
    ch->has_data = true;
    return true;
}

/* Queue buf; the line rounds the length up on fd (zero padding). */
static bool transmit(co_pdo_t *pdo, co_pdo_channel_t *ch)
{
    co_frame_t f;
    f.id = ch->can_id;
    f.flags = ch->ext ? CO_FRAME_EXT : 0;
    f.len = ch->len;
    memcpy(f.data, ch->buf, ch->len);
    if (!co_line_send_frame(pdo->line, &f)) {
        pdo->stats.tx_failed++;
        return false;
    }
    pdo->stats.tx_frames++;
    return true;
}

static void arm_event_timer(co_pdo_t *pdo, co_pdo_channel_t *ch)
{
    /* an MPDO has no values of its own to send again */
    if (ch->event_ms != 0 && is_event_type(ch->type) && ch->mpdo == 0) {
        co_timer_start(co_line_timers(pdo->line), &ch->timer,
                       co_line_now(pdo->line) + ms_to_us(ch->event_ms));
    }
}

/* Event-driven TPDO: sample and send now; the inhibit time and the event
 * timer start over. */
static void send_event(co_pdo_t *pdo, co_pdo_channel_t *ch)
{
    ch->event_pending = false;
    if (!sample(pdo, ch)) {
        return;
    }
    transmit(pdo, ch);
    ch->inhibit_end_us = co_line_now(pdo->line) + (uint64_t)ch->inhibit_100us * 100u;
    arm_event_timer(pdo, ch);
}

/* An event for a 254/255 TPDO: sent now, or when the inhibit time ends. */
static void tpdo_event(co_pdo_t *pdo, co_pdo_channel_t *ch)
{
    if (ch->inhibit_100us != 0 && co_line_now(pdo->line) < ch->inhibit_end_us) {
        if (!ch->event_pending) {
            ch->event_pending = true;
            pdo->stats.tx_inhibited++;
            co_timer_start(co_line_timers(pdo->line), &ch->inhibit_timer, ch->inhibit_end_us);
        }
        return;
    }
    send_event(pdo, ch);
}

static void on_inhibit_end(co_timer_t *timer, uint64_t now_us, void *user)
{
    co_pdo_channel_t *ch = user;
    (void)timer;
    (void)now_us;
    if (ch->event_pending && ch->active && ch->owner->operational) {
        send_event(ch->owner, ch);
    }
}

/* TPDO: event timer expired. RPDO: reception deadline missed. */
static void on_channel_timer(co_timer_t *timer, uint64_t now_us, void *user)
{
    co_pdo_channel_t *ch = user;
    co_pdo_t *pdo = ch->owner;
    (void)timer;
    (void)now_us;
    if (!ch->active || !pdo->operational) {
        return;
    }
    if (!ch->is_rpdo) {
        tpdo_event(pdo, ch);
        return;
    }
    ch->monitoring = false;   /* restarts with the next reception */
    ch->timed_out = true;
    pdo->stats.rx_timeouts++;
    report(pdo, ch, CO_PDO_EMCY_RPDO_TIMEOUT);
    tell_rx_error(pdo, ch, CO_PDO_EMCY_RPDO_TIMEOUT, true, CO_PDO_RX_DEADLINE);
}

/* Queue every synchronous TPDO sampled at SYNC; the ones the tx queue
 * refuses stay due (retried when it drains, dropped when the window closes). */
static void flush_sync(co_pdo_t *pdo)
{
    uint16_t i;
    for (i = 0; i < pdo->channel_count; i++) {
        co_pdo_channel_t *ch = &pdo->channels[i];
        if (ch->sync_due && transmit(pdo, ch)) {
            ch->sync_due = false;
        }
    }
}

static void on_retry(co_timer_t *timer, uint64_t now_us, void *user)
{
    co_pdo_t *pdo = user;
    (void)timer;
    (void)now_us;
    if (pdo->operational) {
        flush_sync(pdo);
    }
}

/* The tx queue drained to half (driver context): retry from a timer. */
static void on_tx_space(co_line_t *line, void *user)
{
    co_pdo_t *pdo = user;
    co_timer_start(co_line_timers(line), &pdo->retry_timer, co_line_now(line));
}

/* ------------------------------------------------------------ runtime state */

/* Forget timers and buffered data of a channel; its reception errors stay
 * (they end by frames or reconfiguration, see rx_error_changed). */
static void stop_channel(co_pdo_t *pdo, co_pdo_channel_t *ch)
{
    co_timer_cancel(co_line_timers(pdo->line), &ch->timer);
    co_timer_cancel(co_line_timers(pdo->line), &ch->inhibit_timer);
    ch->sync_count = 0;
    ch->wait_start = true;
    ch->event_pending = false;
    ch->sync_due = false;
    ch->has_data = false;
    ch->rx_pending = false;
    ch->monitoring = false;
    ch->len = 0;
}

/* Entering operational (or configured while operational). */
static void start_channel(co_pdo_t *pdo, co_pdo_channel_t *ch)
{
    if (!ch->is_rpdo) {
        arm_event_timer(pdo, ch);
    }
}

/* ------------------------------------------------------------ configuration */

static void unmap(co_pdo_t *pdo, co_pdo_channel_t *ch)
{
    if (!ch->active) {
        return;
    }
    if (ch->is_rpdo && ch->ext) {
        pdo->ext_rpdos--;
    }
    if (ch->takes_id) {
        take_id(pdo, ch, false);
    }
    ch->active = false;
}

static uint8_t mapping_count(const co_pdo_t *pdo, const co_pdo_channel_t *ch)
{
    uint8_t n = 0;
    co_od_get_u8(pdo->od, map_index(ch), 0, &n);
    return n;
}

/* Read the channel's parameters from the OD and (de)activate it. */
/* CiA 301 allows one SAM producer per device: whether a TPDO other than ch
 * is one (in_od: its mapping sub 0 says 0xFE; else: it runs as one). */
static bool other_sam_tpdo(co_pdo_t *pdo, const co_pdo_channel_t *ch, bool in_od)
{
    uint16_t i;
    for (i = pdo->rpdo_count; i < pdo->channel_count; i++) {
        const co_pdo_channel_t *other = &pdo->channels[i];
        if (other != ch && (in_od ? mapping_count(pdo, other) == CO_PDO_MAP_SAM
                                  : other->mpdo == CO_PDO_MAP_SAM)) {
            return true;
        }
    }
    return false;
}

static void configure(co_pdo_t *pdo, co_pdo_channel_t *ch)
{
    uint16_t comm = comm_index(ch);
    uint32_t cob = COB_INVALID;
    uint8_t type = CO_PDO_TYPE_EVENT_MANUFACTURER;
    uint8_t count;
    uint16_t bits = 0;

    unmap(pdo, ch);
    stop_channel(pdo, ch);
    ch->map_count = 0;
    ch->bits = 0;
    ch->mpdo = 0;
    ch->inhibit_100us = 0;
    ch->event_ms = 0;
    ch->sync_start = 0;
    co_od_get_u32(pdo->od, comm, SUB_COB_ID, &cob);
    co_od_get_u8(pdo->od, comm, SUB_TYPE, &type);
    co_od_get_u16(pdo->od, comm, SUB_EVENT, &ch->event_ms);
    if (!ch->is_rpdo) {
        co_od_get_u16(pdo->od, comm, SUB_INHIBIT, &ch->inhibit_100us);
        co_od_get_u8(pdo->od, comm, SUB_SYNC_START, &ch->sync_start);
        if (ch->sync_start > SYNC_START_MAX) {
            ch->sync_start = 0;
        }
    }
    ch->type = type;
    count = mapping_count(pdo, ch);
    if (cob & COB_INVALID) {
        return;
    }
    if (is_mpdo_count(count)) {
        /* our choice: MPDOs are event-driven only (see protocol-notes "MPDO") */
        if (!is_event_type(type) || check_cob_id_value(cob) != 0 ||
            (!ch->is_rpdo && count == CO_PDO_MAP_SAM && other_sam_tpdo(pdo, ch, false))) {
            pdo->stats.config_invalid++;   /* the application wrote it (no check runs) */
            return;
        }
        ch->mpdo = count;
        count = 0;
    } else if (count == 0 || check_type(pdo, ch->is_rpdo, type) != 0 ||
               check_cob_id_value(cob) != 0 ||
               co_pdo_map_compile(pdo->od, map_index(ch), ch->is_rpdo, count, ch->map_capacity,
                                  ch->map, &bits) != 0) {
        pdo->stats.config_invalid++;
        return;
    }
    ch->map_count = count;
    ch->bits = bits;
    ch->ext = (cob & COB_EXT) != 0;
    ch->can_id = cob & (ch->ext ? COB_ID_29 : COB_ID_11);
    if (ch->is_rpdo) {
        if (ch->ext) {
            pdo->ext_rpdos++;
        } else if (id_slot(pdo, false, ch->can_id) != 0 ||
                   co_line_id_taken(pdo->line, ch->can_id)) {
            pdo->stats.id_conflicts++;
            return;
        } else {
            take_id(pdo, ch, true);
        }
    } else {
        ch->rtr_allowed = (cob & COB_NO_RTR) == 0 && co_line_mode(pdo->line) == CO_MODE_CLASSIC &&
                          ch->mpdo == 0;
        if (ch->rtr_allowed && !ch->ext && id_slot(pdo, true, ch->can_id) == 0) {
            take_id(pdo, ch, true);
        }
    }
    ch->active = true;
    if (pdo->operational) {
        start_channel(pdo, ch);
    }
}

/* ------------------------------------------------------------ OD write path */

/* Whether the OD says the PDO exists (COB-ID bit 31 clear). */
static bool od_valid(const co_pdo_t *pdo, const co_pdo_channel_t *ch)
{
    uint32_t cob = COB_INVALID;
    co_od_get_u32(pdo->od, comm_index(ch), SUB_COB_ID, &cob);
    return (cob & COB_INVALID) == 0;
}

static uint32_t get_le32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static uint32_t check_comm(co_pdo_t *pdo, co_pdo_channel_t *ch, const co_od_entry_t *e,
                           const uint8_t *value, uint32_t length)
{
    uint8_t sub = co_od_entry_sub(e);
    uint32_t abort;
    if (sub == SUB_COB_ID && e->type == CO_TYPE_UNSIGNED32 && length == 4) {
        uint32_t cob = get_le32(value);
        uint16_t bits;
        uint32_t id;
        if (cob & COB_INVALID) {
            return 0;
        }
        abort = check_cob_id_value(cob);
        if (abort != 0) {
            return abort;
        }
        /* enabling needs a usable mapping and transmission type */
        if (is_mpdo_count(mapping_count(pdo, ch))) {
            if (!is_event_type(ch->type)) {
                return CO_ABORT_INVALID_VALUE;
            }
        } else if (mapping_count(pdo, ch) == 0 ||
                   co_pdo_map_compile(pdo->od, map_index(ch), ch->is_rpdo, mapping_count(pdo, ch),
                                      ch->map_capacity, NULL, &bits) != 0 ||
                   check_type(pdo, ch->is_rpdo, ch->type) != 0) {
            return CO_ABORT_INVALID_VALUE;
        }
        id = cob & COB_ID_11;
        if (ch->is_rpdo && !(cob & COB_EXT)) {
            uint16_t slot = (uint16_t)(ch - pdo->channels + 1);
            uint16_t holder = id_slot(pdo, false, id);
            if ((holder != 0 && holder != slot) || co_line_id_taken(pdo->line, id)) {
                return CO_ABORT_INVALID_VALUE;   /* another RPDO or service takes it */
            }
        }
        return 0;
    }
    if (sub == SUB_TYPE && e->type == CO_TYPE_UNSIGNED8 && length == 1) {
        return check_type(pdo, ch->is_rpdo, value[0]);
    }
    if (ch->is_rpdo) {
        return 0;
    }
    if (sub == SUB_INHIBIT && e->type == CO_TYPE_UNSIGNED16 && length == 2) {
        uint16_t old = 0;
        co_od_get_u16(pdo->od, comm_index(ch), SUB_INHIBIT, &old);
        if (od_valid(pdo, ch) && old != (uint16_t)(value[0] | value[1] << 8)) {
            return CO_ABORT_INVALID_VALUE;   /* only while the PDO does not exist */
        }
    }
    if (sub == SUB_SYNC_START && e->type == CO_TYPE_UNSIGNED8 && length == 1) {
        uint8_t old = 0;
        co_od_get_u8(pdo->od, comm_index(ch), SUB_SYNC_START, &old);
        if (value[0] > SYNC_START_MAX || (od_valid(pdo, ch) && old != value[0])) {
            return CO_ABORT_INVALID_VALUE;
        }
    }
    return 0;
}

/* CiA 301 mapping procedure: invalidate the PDO, sub 0 = 0, entries,
 * sub 0 = n (checked whole), validate. Writing a value equal to the current
 * one is always accepted (configuration tools write whole DCFs). */
static uint32_t check_map(co_pdo_t *pdo, co_pdo_channel_t *ch, const co_od_entry_t *e,
                          const uint8_t *value, uint32_t length)
{
    uint8_t sub = co_od_entry_sub(e);
    if (sub == 0 && e->type == CO_TYPE_UNSIGNED8 && length == 1) {
        uint16_t bits;
        if (value[0] == mapping_count(pdo, ch)) {
            return 0;
        }
        if (od_valid(pdo, ch)) {
            return CO_ABORT_INVALID_VALUE;
        }
        if (!ch->is_rpdo && value[0] == CO_PDO_MAP_SAM && other_sam_tpdo(pdo, ch, true)) {
            return CO_ABORT_PARAM_INCOMPATIBLE;
        }
        if (value[0] == 0 || is_mpdo_count(value[0])) {
            return 0;   /* an MPDO's entries are not used */
        }
        return co_pdo_map_compile(pdo->od, map_index(ch), ch->is_rpdo, value[0],
                                  ch->map_capacity, NULL, &bits);
    }
    if (sub >= 1 && e->type == CO_TYPE_UNSIGNED32 && length == 4) {
        uint32_t mapping = get_le32(value);
        uint32_t old = 0;
        co_od_get_u32(pdo->od, map_index(ch), sub, &old);
        if (mapping == old) {
            return 0;
        }
        if (od_valid(pdo, ch) || mapping_count(pdo, ch) != 0) {
            return CO_ABORT_INVALID_VALUE;
        }
        return mapping == 0 ? 0 : co_pdo_map_check_entry(pdo->od, ch->is_rpdo, mapping, NULL);
    }
    return 0;
}

static uint32_t check_write(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e,
                            const uint8_t *value, uint32_t length, void *user)
{
    co_pdo_t *pdo = user;
    bool is_map;
    co_pdo_channel_t *ch = channel_of_index(pdo, co_od_entry_index(e), &is_map);
    (void)od;
    (void)xfer;
    if (ch == NULL) {
        return 0;
    }
    return is_map ? check_map(pdo, ch, e, value, length) : check_comm(pdo, ch, e, value, length);
}

/* After a write to a PDO's parameters: re-read it; an RPDO's reception
 * errors end where they no longer apply (see rx_error_changed). Errors
 * exist only while active, so "was active" needs no check. */
static void reconfigure(co_pdo_t *pdo, co_pdo_channel_t *ch)
{
    uint32_t old_can_id = ch->can_id;
    bool old_ext = ch->ext;
    uint16_t old_bits = ch->bits;
    bool same_frames;
    configure(pdo, ch);
    same_frames = ch->active && ch->can_id == old_can_id && ch->ext == old_ext;
    if (!same_frames || ch->bits != old_bits) {
        end_length_error(pdo, ch, CO_PDO_RX_RECONFIGURED);
    }
    if (!same_frames || ch->event_ms == 0) {
        end_timeout(pdo, ch, CO_PDO_RX_RECONFIGURED);
    }
}

static void after_write(co_od_t *od, const co_od_entry_t *e, co_od_origin_t origin, void *user)
{
    co_pdo_t *pdo = user;
    bool is_map;
    co_pdo_channel_t *ch = channel_of_index(pdo, co_od_entry_index(e), &is_map);
    (void)od;
    if (ch == NULL || origin == CO_ORIGIN_RESTORE) {
        return;   /* a reset re-reads everything: co_pdo_reload */
    }
    reconfigure(pdo, ch);
}

static const co_od_handler_t pdo_handler = {
    .check_write = check_write,
    .after_write = after_write,
};

/* ------------------------------------------------------------ reception */

static void apply(co_pdo_t *pdo, co_pdo_channel_t *ch, const uint8_t *data)
{
    co_pdo_map_unpack(pdo->od, ch->map, ch->map_count, data);
    pdo->stats.rx_frames++;
    if (pdo->ind != NULL && pdo->ind->received != NULL) {
        pdo->ind->received(pdo, ch->number, pdo->user);
    }
    if (pdo->rx_tap != NULL) {
        pdo->rx_tap(pdo, ch->number, pdo->rx_tap_user);
    }
}

/* A frame's length error (0 = none), told only when it differs from the
 * one in force; a new error is told before the old one ends, so an error
 * register fed from it does not drop in between. */
static void length_seen(co_pdo_t *pdo, co_pdo_channel_t *ch, uint16_t code)
{
    uint16_t old = ch->rx_error;
    if (code == old) {
        return;
    }
    if (code == 0) {
        end_length_error(pdo, ch, CO_PDO_RX_FRAME);
        return;
    }
    ch->rx_error = code;
    report(pdo, ch, code);
    tell_rx_error(pdo, ch, code, true, CO_PDO_RX_FRAME);
    if (old != 0) {
        tell_rx_error(pdo, ch, old, false, CO_PDO_RX_FRAME);
    }
}

static void on_rpdo(co_pdo_t *pdo, co_pdo_channel_t *ch, const co_frame_t *f)
{
    uint8_t need = (uint8_t)((ch->bits + 7u) / 8u);
    /* fd lines send the mapped bytes rounded up to an FD length */
    uint8_t allowed = co_line_mode(pdo->line) == CO_MODE_FD ? co_fd_len_round(need) : need;
    if (!pdo->operational) {
        pdo->stats.rx_not_operational++;
        return;
    }
    if (ch->mpdo != 0) {
        if (pdo->mpdo_rx != NULL) {
            pdo->mpdo_rx(pdo, ch->number, ch->mpdo, f, pdo->mpdo_rx_user);
        } else {
            pdo->stats.rx_not_ours++;
        }
        return;
    }
    if (f->len < need) {
        pdo->stats.rx_short++;
        length_seen(pdo, ch, CO_PDO_EMCY_LENGTH);
        return;
    }
    if (f->len > allowed) {
        pdo->stats.rx_long++;
        length_seen(pdo, ch, CO_PDO_EMCY_LENGTH_EXCEEDED);
    } else {
        length_seen(pdo, ch, 0);
    }
    if (ch->event_ms != 0) {
        ch->monitoring = true;
        co_timer_start(co_line_timers(pdo->line), &ch->timer,
                       co_line_now(pdo->line) + ms_to_us(ch->event_ms));
    }
    if (ch->timed_out) {
        report(pdo, ch, CO_PDO_EMCY_RECEIVED_AGAIN);
        end_timeout(pdo, ch, CO_PDO_RX_FRAME);
    }
    if (is_sync_type(ch->type)) {
        memcpy(ch->buf, f->data, need);   /* the latest frame before the SYNC wins */
        ch->rx_pending = true;
        return;
    }
    apply(pdo, ch, f->data);
}

static co_pdo_channel_t *find_ext(co_pdo_t *pdo, bool is_rpdo, uint32_t id)
{
    uint16_t i;
    for (i = 0; i < pdo->channel_count; i++) {
        co_pdo_channel_t *ch = &pdo->channels[i];
        if (ch->active && ch->ext && ch->is_rpdo == is_rpdo && ch->can_id == id &&
            (is_rpdo || ch->rtr_allowed)) {
            return ch;
        }
    }
    return NULL;
}

static bool on_rtr(co_pdo_t *pdo, const co_frame_t *f)
{
    co_pdo_channel_t *ch;
    if (co_line_mode(pdo->line) != CO_MODE_CLASSIC) {
        return false;   /* fd lines have no remote frames for PDOs */
    }
    if (f->flags & CO_FRAME_EXT) {
        ch = find_ext(pdo, false, f->id);
    } else {
        ch = channel_at(pdo, id_slot(pdo, true, f->id));
    }
    if (ch == NULL) {
        return false;
    }
    if (!pdo->operational) {
        pdo->stats.rx_not_operational++;
        return true;
    }
    if (ch->type == CO_PDO_TYPE_RTR_EVENT || is_event_type(ch->type)) {
        if (!sample(pdo, ch)) {   /* sampled now */
            return true;
        }
    } else if (!ch->has_data) {
        pdo->stats.rtr_refused++;   /* nothing sampled at a SYNC yet */
        return true;
    }
    if (transmit(pdo, ch)) {
        pdo->stats.rtr_answered++;   /* a full tx queue counts in tx_failed instead */
    }
    if (is_event_type(ch->type)) {
        ch->inhibit_end_us = co_line_now(pdo->line) + (uint64_t)ch->inhibit_100us * 100u;
        arm_event_timer(pdo, ch);
    }
    return true;
}

static bool on_other(co_line_t *line, const co_frame_t *f, void *user)
{
    co_pdo_t *pdo = user;
    co_pdo_channel_t *ch;
    (void)line;
    if (f->flags & CO_FRAME_RTR) {
        return on_rtr(pdo, f);
    }
    if (f->flags & CO_FRAME_EXT) {
        ch = pdo->ext_rpdos != 0 ? find_ext(pdo, true, f->id) : NULL;
    } else {
        ch = channel_at(pdo, id_slot(pdo, false, f->id));
    }
    if (ch == NULL) {
        pdo->stats.rx_not_ours++;
        return false;
    }
    on_rpdo(pdo, ch, f);
    return true;
}

/* ------------------------------------------------------------ SYNC */

/* Whether a cyclic synchronous TPDO (1..240) is due at this SYNC. Without
 * a start value the first SYNC counts as 1 (sent at the n-th); with one
 * (and a SYNC counter) it is sent at the SYNC carrying the start value and
 * every n-th after it (as CANopenNode). */
static bool cyclic_due(co_pdo_channel_t *ch, uint8_t counter)
{
    if (ch->wait_start) {
        if (ch->sync_start != 0 && counter != 0) {
            if (counter != ch->sync_start) {
                return false;
            }
            ch->wait_start = false;
            ch->sync_count = ch->type;
            return true;
        }
        ch->wait_start = false;
        ch->sync_count = ch->type;
    }
    if (--ch->sync_count == 0) {
        ch->sync_count = ch->type;
        return true;
    }
    return false;
}

void co_pdo_sync(co_pdo_t *pdo, uint8_t counter)
{
    uint16_t i;
    bool any = false;
    if (!pdo->operational) {
        return;
    }
    /* RPDOs received before this SYNC first, then the TPDOs sample */
    for (i = 0; i < pdo->channel_count; i++) {
        co_pdo_channel_t *ch = &pdo->channels[i];
        if (ch->is_rpdo && ch->active && ch->rx_pending) {
            ch->rx_pending = false;
            apply(pdo, ch, ch->buf);
        }
    }
    for (i = 0; i < pdo->channel_count; i++) {
        co_pdo_channel_t *ch = &pdo->channels[i];
        if (ch->is_rpdo || !ch->active) {
            continue;
        }
        if (ch->type == CO_PDO_TYPE_SYNC_ACYCLIC) {
            if (ch->event_pending) {
                ch->event_pending = false;
                ch->sync_due = sample(pdo, ch);
                any = true;
            }
        } else if (ch->type <= CO_PDO_TYPE_SYNC_MAX) {
            if (cyclic_due(ch, counter)) {
                ch->sync_due = sample(pdo, ch);
                any = true;
            }
        } else if (ch->type == CO_PDO_TYPE_RTR_SYNC) {
            (void)sample(pdo, ch);   /* answered at the next RTR */
        }
    }
    if (any && pdo->operational) {   /* (a callback may have left operational) */
        flush_sync(pdo);
    }
}

void co_pdo_sync_window_closed(co_pdo_t *pdo)
{
    uint16_t i;
    for (i = 0; i < pdo->channel_count; i++) {
        co_pdo_channel_t *ch = &pdo->channels[i];
        if (ch->sync_due) {
            ch->sync_due = false;
            pdo->stats.sync_window_drops++;
        }
    }
}

/* ------------------------------------------------------------ API */

/* Calls fn(user, is_rpdo, number, map_capacity) for every PDO of the OD. */
static void each_pdo(const co_od_t *od, void (*fn)(void *, bool, uint16_t, uint8_t), void *user)
{
    uint16_t n;
    int dir;
    for (dir = 0; dir < 2; dir++) {
        bool is_rpdo = dir == 0;
        uint16_t comm = is_rpdo ? CO_PDO_RPDO_COMM : CO_PDO_TPDO_COMM;
        uint16_t map = is_rpdo ? CO_PDO_RPDO_MAP : CO_PDO_TPDO_MAP;
        for (n = 0; n < CO_PDO_MAX_NUMBER; n++) {
            uint8_t capacity = 0, sub;
            if (!co_od_has_index(od, (uint16_t)(comm + n)) ||
                co_od_find(od, (uint16_t)(comm + n), SUB_COB_ID) == NULL) {
                continue;
            }
            if (co_od_has_index(od, (uint16_t)(map + n))) {
                for (sub = 1; sub <= CO_PDO_MAX_ENTRIES; sub++) {
                    if (co_od_find(od, (uint16_t)(map + n), sub) != NULL) {
                        capacity = sub;
                    }
                }
            }
            fn(user, is_rpdo, (uint16_t)(n + 1u), capacity);
        }
    }
}

typedef struct need_count {
    uint32_t channels;
    uint32_t items;
} need_count_t;

static void count_pdo(void *user, bool is_rpdo, uint16_t number, uint8_t capacity)
{
    need_count_t *c = user;
    (void)is_rpdo;
    (void)number;
    c->channels++;
    c->items += capacity;
}

bool co_pdo_need(const co_od_t *od, uint32_t *channel_count, uint32_t *item_count)
{
    need_count_t c = {0, 0};
    if (od == NULL || !od->sealed) {
        return false;
    }
    each_pdo(od, count_pdo, &c);
    *channel_count = c.channels;
    *item_count = c.items;
    return true;
}

typedef struct setup {
    co_pdo_t *pdo;
    co_pdo_map_item_t *items;
    uint32_t used;
} setup_t;

static void setup_pdo(void *user, bool is_rpdo, uint16_t number, uint8_t capacity)
{
    setup_t *s = user;
    co_pdo_t *pdo = s->pdo;
    co_pdo_channel_t *ch = &pdo->channels[pdo->channel_count++];
    memset(ch, 0, sizeof *ch);
    ch->owner = pdo;
    ch->is_rpdo = is_rpdo;
    ch->number = number;
    ch->map = s->items + s->used;
    ch->map_capacity = capacity;
    s->used += capacity;
    co_timer_init(&ch->timer, on_channel_timer, ch);
    co_timer_init(&ch->inhibit_timer, on_inhibit_end, ch);
    if (is_rpdo) {
        pdo->rpdo_count = pdo->channel_count;   /* RPDOs come first (each_pdo) */
    }
    /* each direction by ascending number: slot_of searches it */
    CO_ASSERT(pdo->channel_count == 1 || ch[-1].is_rpdo != is_rpdo || ch[-1].number < number);
}

bool co_pdo_init(co_pdo_t *pdo, co_line_t *line, co_od_t *od, const co_pdo_config_t *config)
{
    uint32_t channels, items;
    setup_t s;
    if (pdo == NULL || line == NULL || config == NULL || !co_pdo_need(od, &channels, &items) ||
        od->mode != co_line_mode(line) || config->channel_count < channels ||
        config->item_count < items || (channels > 0 && config->channels == NULL) ||
        (items > 0 && config->items == NULL)) {
        return false;
    }
    memset(pdo, 0, sizeof *pdo);
    pdo->line = line;
    pdo->od = od;
    pdo->ind = config->ind;
    pdo->user = config->user;
    pdo->channels = config->channels;
    pdo->rx_map = config->rx_map;
    pdo->rtr_map = config->rtr_map;
    if (pdo->rx_map != NULL) {
        memset(pdo->rx_map, 0, CO_LINE_ID_MAP_SIZE * sizeof *pdo->rx_map);
    }
    if (pdo->rtr_map != NULL) {
        memset(pdo->rtr_map, 0, CO_LINE_ID_MAP_SIZE * sizeof *pdo->rtr_map);
    }
    co_timer_init(&pdo->retry_timer, on_retry, pdo);
    s.pdo = pdo;
    s.items = config->items;
    s.used = 0;
    each_pdo(od, setup_pdo, &s);
    if (!co_od_subscribe(od, CO_PDO_RPDO_COMM, 0, CO_PDO_TPDO_MAP + CO_PDO_MAX_NUMBER - 1u, 0xFF,
                         &pdo_handler, pdo)) {
        return false;
    }
    if (!co_line_subscribe_other(line, on_other, pdo)) {
        co_od_unsubscribe(od, &pdo_handler, pdo);
        return false;
    }
    if (!co_line_tx_space_register(line, on_tx_space, pdo)) {
        co_line_unsubscribe_other(line, on_other, pdo);
        co_od_unsubscribe(od, &pdo_handler, pdo);
        return false;
    }
    pdo->hooked = true;
    co_pdo_reload(pdo);
    return true;
}

void co_pdo_deinit(co_pdo_t *pdo)
{
    uint16_t i;
    if (!pdo->hooked) {
        return;
    }
    for (i = 0; i < pdo->channel_count; i++) {
        co_pdo_channel_t *ch = &pdo->channels[i];
        unmap(pdo, ch);
        stop_channel(pdo, ch);
        ch->rx_error = 0;   /* forgotten untold: the integration is going too */
        ch->timed_out = false;
    }
    co_timer_cancel(co_line_timers(pdo->line), &pdo->retry_timer);
    co_line_tx_space_unregister(pdo->line, on_tx_space, pdo);
    co_line_unsubscribe_other(pdo->line, on_other, pdo);
    co_od_unsubscribe(pdo->od, &pdo_handler, pdo);
    pdo->hooked = false;
}

void co_pdo_reload(co_pdo_t *pdo)
{
    uint16_t i;
    /* everything off first, so a COB-ID another PDO gave up is free */
    for (i = 0; i < pdo->channel_count; i++) {
        unmap(pdo, &pdo->channels[i]);
    }
    for (i = 0; i < pdo->channel_count; i++) {
        configure(pdo, &pdo->channels[i]);
    }
    /* a reload starts every RPDO over: errors under the old values end */
    for (i = 0; i < pdo->channel_count; i++) {
        end_length_error(pdo, &pdo->channels[i], CO_PDO_RX_RECONFIGURED);
        end_timeout(pdo, &pdo->channels[i], CO_PDO_RX_RECONFIGURED);
    }
}

void co_pdo_set_operational(co_pdo_t *pdo, bool operational)
{
    uint16_t i;
    if (operational == pdo->operational) {
        return;
    }
    pdo->operational = operational;
    co_timer_cancel(co_line_timers(pdo->line), &pdo->retry_timer);
    for (i = 0; i < pdo->channel_count; i++) {
        co_pdo_channel_t *ch = &pdo->channels[i];
        stop_channel(pdo, ch);
        if (operational && ch->active) {
            start_channel(pdo, ch);
        }
    }
}

bool co_pdo_trigger(co_pdo_t *pdo, uint16_t tpdo_number)
{
    co_pdo_channel_t *ch = channel_of(pdo, false, tpdo_number);
    if (ch == NULL || !ch->active || !pdo->operational || ch->sampling || ch->mpdo != 0) {
        return false;
    }
    if (ch->type == CO_PDO_TYPE_SYNC_ACYCLIC) {
        ch->event_pending = true;   /* sent at the next SYNC */
        return true;
    }
    if (!is_event_type(ch->type)) {
        return false;
    }
    tpdo_event(pdo, ch);
    return true;
}

uint32_t co_pdo_trigger_mapped(co_pdo_t *pdo, co_pdo_pick_fn pick, void *user)
{
    uint32_t triggered = 0;
    uint16_t i;
    if (pick == NULL || !pdo->operational) {
        return 0;
    }
    for (i = 0; i < pdo->channel_count; i++) {
        co_pdo_channel_t *ch = &pdo->channels[i];
        uint8_t k;
        if (ch->is_rpdo || !ch->active ||
            !(ch->type == CO_PDO_TYPE_SYNC_ACYCLIC || is_event_type(ch->type))) {
            continue;
        }
        for (k = 0; k < ch->map_count; k++) {
            if (!(ch->map[k].flags & CO_PDO_ITEM_DUMMY) &&
                pick(&pdo->od->entries[ch->map[k].entry], user)) {
                co_pdo_trigger(pdo, ch->number);
                triggered++;
                break;   /* once per TPDO, however many of its entries changed */
            }
        }
    }
    return triggered;
}

static bool is_entry(const co_od_entry_t *e, void *user)
{
    return e == user;
}

uint32_t co_pdo_trigger_object(co_pdo_t *pdo, uint16_t index, uint8_t sub)
{
    const co_od_entry_t *e = co_od_find(pdo->od, index, sub);
    return e == NULL ? 0 : co_pdo_trigger_mapped(pdo, is_entry, (void *)(uintptr_t)e);
}

void co_pdo_each_mapped(const co_pdo_t *pdo, bool is_rpdo, uint16_t number,
                        co_pdo_pick_fn fn, void *user)
{
    const co_pdo_channel_t *ch = co_pdo_channel(pdo, is_rpdo, number);
    for (uint8_t k = 0; ch != NULL && k < ch->map_count; k++) {
        if (!(ch->map[k].flags & CO_PDO_ITEM_DUMMY)) {
            (void)fn(&pdo->od->entries[ch->map[k].entry], user);
        }
    }
}

bool co_pdo_is_active(const co_pdo_t *pdo, bool is_rpdo, uint16_t number)
{
    const co_pdo_channel_t *ch = channel_at(pdo, slot_of(pdo, is_rpdo, number));
    return ch != NULL && ch->active;
}

bool co_pdo_pack_values(const co_pdo_t *pdo, bool is_rpdo, uint16_t number, uint8_t *data,
                        uint8_t *len)
{
    const co_pdo_channel_t *ch = channel_at(pdo, slot_of(pdo, is_rpdo, number));
    if (ch == NULL) {
        return false;
    }
    memset(data, 0, CO_FRAME_MAX_DATA);
    co_pdo_map_pack(pdo->od, ch->map, ch->map_count, ch->bits, data);
    *len = (uint8_t)((ch->bits + 7u) / 8u);
    return true;
}

const co_pdo_channel_t *co_pdo_channel(const co_pdo_t *pdo, bool is_rpdo, uint16_t number)
{
    return channel_at(pdo, slot_of(pdo, is_rpdo, number));
}

void co_pdo_set_rx_tap(co_pdo_t *pdo, co_pdo_rx_tap_fn fn, void *user)
{
    pdo->rx_tap = fn;
    pdo->rx_tap_user = fn != NULL ? user : NULL;
}

void co_pdo_set_mpdo_rx(co_pdo_t *pdo, co_pdo_mpdo_rx_fn fn, void *user)
{
    pdo->mpdo_rx = fn;
    pdo->mpdo_rx_user = fn != NULL ? user : NULL;
}

bool co_pdo_send_mpdo(co_pdo_t *pdo, uint16_t tpdo_number, const uint8_t *data, uint8_t len)
{
    co_pdo_channel_t *ch = channel_of(pdo, false, tpdo_number);
    uint64_t now = co_line_now(pdo->line);
    if (ch == NULL || !ch->active || ch->mpdo == 0 || !pdo->operational ||
        len > sizeof ch->buf) {
        return false;
    }
    if (ch->has_data && now < ch->inhibit_end_us) {
        pdo->stats.tx_inhibited++;   /* refused, not queued: each MPDO is its own message */
        return false;
    }
    memcpy(ch->buf, data, len);
    ch->len = len;
    if (!transmit(pdo, ch)) {
        return false;
    }
    ch->has_data = true;
    ch->inhibit_end_us = now + (uint64_t)ch->inhibit_100us * 100u;
    return true;
}
