/* Store and restore of parameters (see co_store.h).
 *
 * Image format, version 1 (integers little-endian, no padding, no alignment):
 *
 *   offset size  field
 *        0    8  magic "CoFDpar\0"
 *        8    2  format version: 1
 *       10    2  header length: 28 (a later version may append fields; the
 *                records start at this offset)
 *       12    4  OD signature: CRC-32 over (key u32, type u8, size u32) of
 *                every CO_OD_STORE entry of the OD that wrote the image, in
 *                key order (information only, see "choices")
 *       16    4  record count
 *       20    4  payload length: bytes of records after the header; the image
 *                is exactly header length + payload length bytes
 *       24    4  CRC-32 (co_crc32) over bytes 0..23, then over bytes from 28
 *                to the end: every byte of the image but the CRC itself
 *       28       records, strictly ascending by key, each
 *                  key u32 (index << 8 | sub, below 2^24), type u8 (co_od_type_t),
 *                  length u32, value[length] (the entry's bytes as in the OD)
 *
 * Statuses: wrong magic or version -> FOREIGN; any other inconsistency (short
 * image, header length, payload length, CRC, count, a record running past the
 * end, keys not ascending) -> DAMAGED. The image is checked whole before any
 * record is applied, so a damaged image changes nothing but the defaults.
 *
 * Choices:
 * - The OD layout does not make an image FOREIGN: a record is applied when
 *   its entry exists, is CO_OD_STORE, has the same type, the length fits and
 *   co_od_check_value accepts the value; otherwise it is skipped and counted
 *   (records_skipped). So a firmware update that adds, removes or retypes
 *   entries keeps every value that still means the same, and never loads one
 *   that does not. The signature stays in the header for tools.
 * - The CRC covers the header too, so every byte flip is DAMAGED (or FOREIGN
 *   when it hits magic or version), not only flips in the records.
 * - Keys strictly ascending: one canonical form, no duplicate records, and a
 *   save merges the previous image with the OD (both sorted) in one pass.
 * - A save keeps the previous records of the other groups only when they would
 *   be applied to this OD; records of entries the OD no longer has vanish at
 *   the next save, which bounds the image by co_store_image_need().
 * - Domains (size 0) are never stored: their data lives with the application.
 * - Restoring a value is a raw write of the entry (no access check: stored
 *   parameters may be read-only on the network), then, once every record is
 *   in place, the after_write handlers of each applied record with
 *   CO_ORIGIN_RESTORE. co_od_load_defaults has told the defaults before, so
 *   an entry may hear RESTORE twice in one load (default, then stored value);
 *   handlers take the last word.
 */
#include "canopenfd/co_store.h"

#include "co_crc.h"

#include <string.h>

enum {
    IMG_VERSION = 1,
    IMG_HEADER = 28,
    OFF_VERSION = 8,
    OFF_HEADER_LENGTH = 10,
    OFF_SIGNATURE = 12,
    OFF_COUNT = 16,
    OFF_PAYLOAD_LENGTH = 20,
    OFF_CRC = 24,
    REC_HEADER = 9               /* key u32, type u8, length u32 */
};

static const uint8_t img_magic[8] = { 'C', 'o', 'F', 'D', 'p', 'a', 'r', 0 };

/* The default declaration: CiA 301's groups by index range (co_od_group_of),
 * so the group masks are the CO_GROUP_* ones. */
static const co_store_group_t default_groups[] = {
    { 0x100000u, 0x1FFFFFu, 2, CO_STORE_MODE_ON_COMMAND, CO_STORE_RESET_COMMUNICATION },
    { 0x200000u, 0x5FFFFFu, 4, CO_STORE_MODE_ON_COMMAND, CO_STORE_RESET_NODE },
    { 0x600000u, 0x9FFFFFu, 3, CO_STORE_MODE_ON_COMMAND, CO_STORE_RESET_NODE },
    { 0xA00000u, 0xFFFFFFu, 4, CO_STORE_MODE_ON_COMMAND, CO_STORE_RESET_NODE },
};

/* ------------------------------------------------------------ byte order */

static uint16_t get_u16(const uint8_t *p)
{
    return (uint16_t)(p[0] | (p[1] << 8));
}

static uint32_t get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) |
           ((uint32_t)p[3] << 24);
}

static void put_u16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}

static void put_u32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

/* --------------------------------------------------------------- decoding */

typedef struct img_view {
    const uint8_t *records;      /* the payload */
    uint32_t length;             /* payload bytes */
    uint32_t count;              /* records in it */
} img_view_t;

typedef struct img_record {
    uint32_t key;
    uint8_t type;
    uint32_t length;
    const uint8_t *data;
} img_record_t;

/* The record at *pos of payload[0..length), *pos moved past it. False when it
 * does not fit in what is left: every length is checked before use. */
static bool record_next(const uint8_t *payload, uint32_t length, uint32_t *pos, img_record_t *r)
{
    uint32_t at = *pos;
    if (at > length || length - at < REC_HEADER)
        return false;
    r->key = get_u32(payload + at);
    r->type = payload[at + 4];
    r->length = get_u32(payload + at + 5);
    at += REC_HEADER;
    if (r->length > length - at)
        return false;
    r->data = payload + at;
    *pos = at + r->length;
    return true;
}

static uint32_t image_crc(const uint8_t *img, uint32_t length)
{
    uint32_t crc = co_crc32(0, img, OFF_CRC);
    return co_crc32(crc, img + OFF_CRC + 4, length - (OFF_CRC + 4));
}

/* The decoder: checks a whole image of `length` bytes (any bytes at all) and
 * reads nothing outside img[0..length). On CO_STORE_OK *view is the payload. */
static co_store_status_t image_parse(const uint8_t *img, uint32_t length, img_view_t *view)
{
    uint32_t header, payload, count, pos, i, last_key = 0;
    img_record_t r;

    if (length < sizeof img_magic)
        return CO_STORE_DAMAGED;
    if (memcmp(img, img_magic, sizeof img_magic) != 0)
        return CO_STORE_FOREIGN;
    if (length < OFF_VERSION + 2)
        return CO_STORE_DAMAGED;
    if (get_u16(img + OFF_VERSION) != IMG_VERSION)
        return CO_STORE_FOREIGN;
    if (length < IMG_HEADER)
        return CO_STORE_DAMAGED;
    header = get_u16(img + OFF_HEADER_LENGTH);
    payload = get_u32(img + OFF_PAYLOAD_LENGTH);
    count = get_u32(img + OFF_COUNT);
    if (header < IMG_HEADER || header > length || payload != length - header)
        return CO_STORE_DAMAGED;
    if (image_crc(img, length) != get_u32(img + OFF_CRC))
        return CO_STORE_DAMAGED;
    /* Each record takes REC_HEADER bytes at least: a count that cannot fit is
     * refused before the walk (which would refuse it too, only later). */
    if (count > payload / REC_HEADER)
        return CO_STORE_DAMAGED;
    pos = 0;
    for (i = 0; i < count; i++) {
        if (!record_next(img + header, payload, &pos, &r))
            return CO_STORE_DAMAGED;
        if (r.key > 0xFFFFFFu || (i > 0 && r.key <= last_key))
            return CO_STORE_DAMAGED;
        last_key = r.key;
    }
    if (pos != payload)
        return CO_STORE_DAMAGED;
    view->records = img + header;
    view->length = payload;
    view->count = count;
    return CO_STORE_OK;
}

/* The backend's image in buf, checked. */
static co_store_status_t image_read(co_store_t *s, uint8_t *buf, img_view_t *view)
{
    uint32_t length = 0;
    co_store_status_t st = s->backend->load(s->user, buf, s->image_capacity, &length);
    switch (st) {
    case CO_STORE_OK:
        /* A backend claiming more than it may have written is broken: its
         * bytes are not read. */
        if (length > s->image_capacity)
            return CO_STORE_IO;
        return image_parse(buf, length, view);
    case CO_STORE_EMPTY:
    case CO_STORE_TOO_BIG:
        return st;
    case CO_STORE_IO:
    case CO_STORE_DAMAGED:
    case CO_STORE_FOREIGN:
    default:
        return CO_STORE_IO;   /* statuses a backend may not give */
    }
}

/* ---------------------------------------------------------------- entries */

static bool entry_is_stored(const co_od_entry_t *e)
{
    return (e->flags & CO_OD_STORE) != 0 && e->size > 0;
}

static uint8_t group_bit(uint8_t sub)
{
    return (uint8_t)(1u << (sub - 2u));
}

uint8_t co_store_group_of(const co_store_t *s, uint32_t key)
{
    uint8_t i;
    for (i = 0; i < s->group_rows; i++) {
        const co_store_group_t *g = &s->groups[i];
        if (key >= g->first_key && key <= g->last_key)
            return group_bit(g->sub);
    }
    return 0;
}

/* The groups whose mode has any of these bits (0: the disabled ones too). */
static uint8_t groups_with_mode(const co_store_t *s, uint8_t mode_bits)
{
    uint8_t i, mask = 0;
    for (i = 0; i < s->group_rows; i++) {
        if (mode_bits == 0 || (s->groups[i].mode & mode_bits) != 0)
            mask |= group_bit(s->groups[i].sub);
    }
    return mask;
}

static uint8_t all_groups(const co_store_t *s)
{
    return groups_with_mode(s, 0);
}

/* The groups that are saved at all: a disabled group's values are not kept. */
static uint8_t enabled_groups(const co_store_t *s)
{
    return groups_with_mode(s, CO_STORE_MODE_BOTH);
}

/* The mode bits of the groups in mask, OR-ed (0x1010 sub 1 reports them all). */
static uint8_t mode_of(const co_store_t *s, uint8_t mask)
{
    uint8_t i, mode = 0;
    for (i = 0; i < s->group_rows; i++) {
        if ((group_bit(s->groups[i].sub) & mask) != 0)
            mode |= s->groups[i].mode;
    }
    return mode;
}

uint8_t co_store_reset_groups(const co_store_t *s, bool reset_node)
{
    uint8_t i, mask = 0;
    for (i = 0; i < s->group_rows; i++) {
        const co_store_group_t *g = &s->groups[i];
        if (reset_node || g->reset == CO_STORE_RESET_COMMUNICATION)
            mask |= group_bit(g->sub);
    }
    return mask;
}

/* The entry a record may be applied to, or NULL: then it is skipped. */
static const co_od_entry_t *record_target(const co_od_t *od, const img_record_t *r)
{
    const co_od_entry_t *e = co_od_find(od, (uint16_t)(r->key >> 8), (uint8_t)(r->key & 0xFFu));
    if (e == NULL || !entry_is_stored(e) || e->type != r->type || r->length > e->size)
        return NULL;
    if (co_od_check_value(od, e, r->data, r->length) != 0)
        return NULL;
    return e;
}

/* Raw write of a checked value (the rest of a string zeroed, as co_od does). */
static void restore_value(co_od_t *od, const co_od_entry_t *e, const uint8_t *data,
                          uint32_t length)
{
    co_od_entry_t *w = &od->entries[e - od->entries];   /* e is one of od->entries */
    uint8_t *value = co_od_value(od, e);
    memcpy(value, data, length);
    if (length < e->size)
        memset(value + length, 0, e->size - length);
    w->length = length;
}

/* The after_write handlers of an entry, in subscription order. */
static void notify_restored(co_od_t *od, const co_od_entry_t *e)
{
    uint8_t i;
    for (i = 0; i < od->sub_count; i++) {
        const co_od_subscription_t *sub = &od->subs[i];
        if (e->key >= sub->first_key && e->key <= sub->last_key && sub->handler != NULL &&
            sub->handler->after_write != NULL)
            sub->handler->after_write(od, e, CO_ORIGIN_RESTORE, sub->user);
    }
}

/* Apply the records of the groups in mask (pass 1), or tell the handlers of
 * the applied ones (pass 2). Like co_od_load_defaults, every value is in
 * place before any handler runs, so handlers see the restored OD whole.
 * record_target depends only on the record and the OD's layout, so both
 * passes pick the same entries even if a handler writes values. */
static uint32_t restore_records(co_store_t *s, const img_view_t *view, uint8_t mask, bool notify)
{
    uint32_t pos = 0, i, skipped = 0;
    img_record_t r;
    for (i = 0; i < view->count; i++) {
        const co_od_entry_t *e;
        if (!record_next(view->records, view->length, &pos, &r))
            break;   /* cannot happen after image_parse */
        if ((co_store_group_of(s, r.key) & mask) == 0)
            continue;
        e = record_target(s->od, &r);
        if (e == NULL)
            skipped++;
        else if (notify)
            notify_restored(s->od, e);
        else
            restore_value(s->od, e, r.data, r.length);
    }
    return skipped;
}

uint32_t co_store_image_need(const co_od_t *od)
{
    uint64_t need = IMG_HEADER;
    uint32_t i;
    for (i = 0; i < od->count; i++) {
        const co_od_entry_t *e = &od->entries[i];
        if (entry_is_stored(e))
            need += REC_HEADER + (uint64_t)e->size;
    }
    return need > UINT32_MAX ? UINT32_MAX : (uint32_t)need;
}

uint32_t co_store_image_need_grown(const co_od_t *od)
{
    /* a live entry's stored bytes are at most its pool bytes */
    uint64_t need = (uint64_t)co_store_image_need(od) +
                    (uint64_t)(od->capacity - od->count) * REC_HEADER +
                    (od->pool_size - od->pool_used);
    return need > UINT32_MAX ? UINT32_MAX : (uint32_t)need;
}

static uint32_t od_signature(const co_od_t *od)
{
    uint32_t crc = 0, i;
    uint8_t b[9];
    for (i = 0; i < od->count; i++) {
        const co_od_entry_t *e = &od->entries[i];
        if (!entry_is_stored(e))
            continue;
        put_u32(b, e->key);
        b[4] = e->type;
        put_u32(b + 5, e->size);
        crc = co_crc32(crc, b, sizeof b);
    }
    return crc;
}

/* ---------------------------------------------------------------- writing */

typedef struct img_writer {
    uint8_t *buf;
    uint32_t capacity;
    uint32_t pos;
    uint32_t count;
} img_writer_t;

static bool append_record(img_writer_t *w, uint32_t key, uint8_t type, const uint8_t *data,
                          uint32_t length)
{
    /* Cannot fail when capacity >= co_store_image_need(); checked anyway. */
    if (w->pos > w->capacity || w->capacity - w->pos < REC_HEADER ||
        w->capacity - w->pos - REC_HEADER < length)
        return false;
    put_u32(w->buf + w->pos, key);
    w->buf[w->pos + 4] = type;
    put_u32(w->buf + w->pos + 5, length);
    if (length > 0)
        memcpy(w->buf + w->pos + REC_HEADER, data, length);
    w->pos += REC_HEADER + length;
    w->count++;
    return true;
}

/* Build and save a new image: the current values of the groups in `current`
 * plus the previous records of the groups in `keep`. */
static uint32_t rewrite(co_store_t *s, uint8_t current, uint8_t keep, const img_view_t *prev)
{
    co_od_t *od = s->od;
    img_writer_t w;
    uint32_t i, prev_pos = 0, prev_left = prev != NULL ? prev->count : 0;
    img_record_t r;
    bool have_r = false;

    w.buf = s->image;
    w.capacity = s->image_capacity;
    w.pos = IMG_HEADER;
    w.count = 0;
    if (w.capacity < IMG_HEADER)
        return CO_ABORT_OUT_OF_MEMORY;
    for (i = 0; i < od->count; i++) {
        const co_od_entry_t *e = &od->entries[i];
        uint8_t group;
        if (!entry_is_stored(e))
            continue;
        group = co_store_group_of(s, e->key);
        if ((group & current) != 0) {
            if (!append_record(&w, e->key, e->type, co_od_value(od, e), e->length))
                return CO_ABORT_OUT_OF_MEMORY;
            continue;
        }
        if ((group & keep) == 0)
            continue;
        /* Both sorted: move the previous image's cursor up to this key. */
        while (prev_left > 0 && (!have_r || r.key < e->key)) {
            have_r = record_next(prev->records, prev->length, &prev_pos, &r);
            prev_left--;
            if (!have_r)
                prev_left = 0;   /* cannot happen after image_parse */
        }
        if (have_r && r.key == e->key && record_target(od, &r) == e) {
            if (!append_record(&w, r.key, r.type, r.data, r.length))
                return CO_ABORT_OUT_OF_MEMORY;
        }
    }
    memcpy(w.buf, img_magic, sizeof img_magic);
    put_u16(w.buf + OFF_VERSION, IMG_VERSION);
    put_u16(w.buf + OFF_HEADER_LENGTH, IMG_HEADER);
    put_u32(w.buf + OFF_SIGNATURE, od_signature(od));
    put_u32(w.buf + OFF_COUNT, w.count);
    put_u32(w.buf + OFF_PAYLOAD_LENGTH, w.pos - IMG_HEADER);
    put_u32(w.buf + OFF_CRC, image_crc(w.buf, w.pos));
    if (s->backend->save(s->user, w.buf, w.pos) != CO_STORE_OK)
        return CO_ABORT_HARDWARE;
    return 0;
}

uint32_t co_store_save(co_store_t *s, uint8_t group_mask)
{
    img_view_t prev;
    co_store_status_t st;
    uint8_t keep;

    group_mask &= enabled_groups(s);
    keep = (uint8_t)(enabled_groups(s) & ~group_mask);
    if (keep == 0)   /* saving everything needs nothing old: works over any file */
        return rewrite(s, group_mask, 0, NULL);
    st = image_read(s, s->previous, &prev);
    if (st == CO_STORE_IO)
        return CO_ABORT_HARDWARE;   /* the other groups' values may be there: keep them */
    /* EMPTY, DAMAGED, FOREIGN, TOO_BIG: nothing of it could ever load, so
     * there is nothing to keep. */
    return rewrite(s, group_mask, keep, st == CO_STORE_OK ? &prev : NULL);
}

uint32_t co_store_restore_defaults(co_store_t *s, uint8_t group_mask)
{
    img_view_t prev;
    co_store_status_t st;

    group_mask &= enabled_groups(s);
    st = image_read(s, s->previous, &prev);
    if (st == CO_STORE_IO)
        return CO_ABORT_HARDWARE;
    if (st == CO_STORE_EMPTY)
        return 0;   /* nothing saved: defaults load already; spare the medium */
    /* A damaged or foreign image is replaced by an empty one (zero records):
     * the backend has no "erase", and the next load then says OK, not DAMAGED. */
    return rewrite(s, 0, (uint8_t)(enabled_groups(s) & ~group_mask),
                   st == CO_STORE_OK ? &prev : NULL);
}

/* Which entries a load gives their defaults: the members of the loaded
 * groups, and the entries of no group in the index ranges of `areas`. */
typedef struct default_pick {
    const co_store_t *s;
    uint8_t groups;
    uint8_t areas;
} default_pick_t;

static bool pick_default(const co_od_entry_t *e, void *user)
{
    const default_pick_t *p = user;
    uint8_t group = co_store_group_of(p->s, e->key);
    if (group != 0)
        return (group & p->groups) != 0;
    return (co_od_group_of(co_od_entry_index(e)) & p->areas) != 0;
}

/* Disabled groups load their defaults but never saved values (nothing of
 * theirs is saved from now on, so an old value would come back for ever). */
static co_store_status_t load(co_store_t *s, uint8_t groups, uint8_t areas)
{
    img_view_t view;
    co_store_status_t st;
    default_pick_t pick;

    pick.s = s;
    pick.groups = groups;
    pick.areas = areas;
    /* the loaded values are the saved ones (or defaults): nothing to save */
    s->changed &= (uint8_t)~groups;
    groups &= enabled_groups(s);
    s->records_skipped = 0;
    co_od_load_defaults_if(s->od, pick_default, &pick);
    st = image_read(s, s->image, &view);
    if (st == CO_STORE_OK) {
        s->records_skipped = restore_records(s, &view, groups, false);
        (void)restore_records(s, &view, groups, true);
    }
    s->last_load = st;
    return st;
}

co_store_status_t co_store_load(co_store_t *s, uint8_t group_mask)
{
    return load(s, group_mask, group_mask);
}

co_store_status_t co_store_load_at_reset(co_store_t *s, bool reset_node)
{
    return load(s, co_store_reset_groups(s, reset_node),
                reset_node ? CO_GROUP_ALL : CO_GROUP_COMMUNICATION);
}

/* ------------------------------------------------------ autonomous saves */

/* Saves the changed groups; a refused save keeps them changed and retries
 * one interval later (the previous image stays whole meanwhile). */
static void on_autonomous_timer(co_timer_t *timer, uint64_t now_us, void *user)
{
    co_store_t *s = user;
    uint8_t changed = s->changed;
    uint32_t abort;
    (void)timer;
    if (changed == 0)
        return;   /* a load since the change put the saved values back */
    s->last_autonomous_us = now_us;
    s->autonomous_ran = true;
    s->changed = 0;
    abort = co_store_save(s, changed);
    if (abort == 0) {
        s->autonomous_saves++;
    } else {
        s->autonomous_failures++;
        s->changed |= changed;
        co_timer_start(co_line_timers(s->line), &s->autonomous_timer,
                       now_us + s->min_interval_us);
    }
    if (s->autonomous_saved != NULL)
        s->autonomous_saved(s, abort, s->autonomous_user);
}

void co_store_changed(co_store_t *s, uint8_t groups)
{
    uint64_t due, now;
    groups &= groups_with_mode(s, CO_STORE_MODE_AUTONOMOUS);
    if (groups == 0 || s->line == NULL)
        return;
    s->changed |= groups;
    if (co_timer_is_armed(&s->autonomous_timer))
        return;
    now = co_line_now(s->line);
    due = s->autonomous_ran ? s->last_autonomous_us + s->min_interval_us : now;
    co_timer_start(co_line_timers(s->line), &s->autonomous_timer, due > now ? due : now);
}

static void on_member_written(co_od_t *od, const co_od_entry_t *e, co_od_origin_t origin,
                              void *user)
{
    co_store_t *s = user;
    (void)od;
    if (origin == CO_ORIGIN_RESTORE || !entry_is_stored(e))
        return;   /* a load is no change to save */
    co_store_changed(s, co_store_group_of(s, e->key));
}

static const co_od_handler_t member_handler = {
    .after_write = on_member_written,
};

/* ------------------------------------------------------ 0x1010 and 0x1011 */

static uint8_t group_of_sub(const co_store_t *s, uint8_t sub)
{
    return sub == 1 ? all_groups(s) : group_bit(sub);   /* the subscription: 1..last_sub */
}

/* A read reports the mode bits of the sub's groups, whatever was written
 * last: 0x1010 "saves on command" (bit 0) and "autonomously" (bit 1); 0x1011
 * bit 0 "restores defaults" for an enabled group. */
static uint32_t on_before_read(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e,
                               void *user)
{
    const co_store_t *s = user;
    uint8_t mode = mode_of(s, group_of_sub(s, co_od_entry_sub(e)));
    (void)xfer;
    if (co_od_entry_index(e) == 0x1011)
        mode = mode != 0 ? CO_STORE_MODE_ON_COMMAND : 0;
    if (e->type == CO_TYPE_UNSIGNED32 && e->size >= 4)
        put_u32(co_od_value(od, e), mode);
    return 0;
}

/* The work happens in the test pass, so the writer gets its result as the
 * answer (CiA 301: the SDO answer follows the save). */
static uint32_t on_check_save(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e,
                              const uint8_t *value, uint32_t length, void *user)
{
    (void)od;
    (void)xfer;
    co_store_t *s = user;
    uint8_t groups = group_of_sub(s, co_od_entry_sub(e)) &
                     groups_with_mode(s, CO_STORE_MODE_ON_COMMAND);
    if (length != 4 || get_u32(value) != CO_STORE_SAVE_SIGNATURE || groups == 0)
        return CO_ABORT_DATA_STORE;   /* also: a group not saved on command */
    return co_store_save(s, groups);
}

static uint32_t on_check_restore(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e,
                                 const uint8_t *value, uint32_t length, void *user)
{
    (void)od;
    (void)xfer;
    co_store_t *s = user;
    uint8_t groups = group_of_sub(s, co_od_entry_sub(e)) & enabled_groups(s);
    if (length != 4 || get_u32(value) != CO_STORE_LOAD_SIGNATURE || groups == 0)
        return CO_ABORT_DATA_STORE;   /* also: a disabled group */
    return co_store_restore_defaults(s, groups);
}

static const co_od_handler_t save_handler = {
    .before_read = on_before_read,
    .check_write = on_check_save,
};
static const co_od_handler_t restore_handler = {
    .before_read = on_before_read,
    .check_write = on_check_restore,
};

/* The highest group sub-index when the declaration is valid (see
 * co_store_init_config), else 0. */
static uint8_t check_groups(const co_store_group_t *g, uint8_t rows)
{
    uint8_t i, j, last_sub = 1;
    unsigned subs_seen = 0;
    if (rows == 0 || rows > CO_STORE_MAX_GROUP_ROWS)
        return 0;
    for (i = 0; i < rows; i++) {
        if (g[i].first_key < 0x100000u || g[i].last_key > 0xFFFFFFu ||
            g[i].first_key > g[i].last_key || g[i].sub < 2 ||
            g[i].sub >= 2 + CO_STORE_MAX_GROUPS || g[i].mode > CO_STORE_MODE_BOTH ||
            g[i].reset > CO_STORE_RESET_COMMUNICATION)
            return 0;
        for (j = 0; j < i; j++) {
            if (g[i].first_key <= g[j].last_key && g[j].first_key <= g[i].last_key)
                return 0;   /* overlap: an entry in two groups */
            if (g[j].sub == g[i].sub &&
                (g[j].mode != g[i].mode || g[j].reset != g[i].reset))
                return 0;   /* one group, two behaviours */
        }
        subs_seen |= 1u << (g[i].sub - 2u);
        if (g[i].sub > last_sub)
            last_sub = g[i].sub;
    }
    /* 2..last_sub without gaps: each 0x1010 sub of a group names one */
    return subs_seen == (1u << (last_sub - 1u)) - 1u ? last_sub : 0;
}

bool co_store_groups_valid(const co_store_group_t *groups, uint8_t rows)
{
    return groups != NULL && check_groups(groups, rows) != 0;
}

bool co_store_init(co_store_t *s, co_od_t *od, const co_store_backend_t *backend, void *user,
                   uint8_t *buffer, uint32_t buffer_size)
{
    return co_store_init_config(s, od, backend, user, buffer, buffer_size, NULL);
}

bool co_store_init_config(co_store_t *s, co_od_t *od, const co_store_backend_t *backend,
                          void *user, uint8_t *buffer, uint32_t buffer_size,
                          const co_store_config_t *config)
{
    bool declared = config != NULL && config->groups != NULL;
    const co_store_group_t *groups = declared ? config->groups : default_groups;
    uint8_t rows = declared ? config->group_rows
                            : (uint8_t)(sizeof default_groups / sizeof default_groups[0]);
    uint32_t need, half;
    bool has_save, has_restore, autonomous = false;
    unsigned subs_needed;
    uint8_t last_sub, i;

    if (s == NULL || od == NULL || backend == NULL || backend->save == NULL ||
        backend->load == NULL || buffer == NULL || !od->sealed)
        return false;
    last_sub = check_groups(groups, rows);
    if (last_sub == 0)
        return false;
    for (i = 0; i < rows; i++)
        autonomous = autonomous || (groups[i].mode & CO_STORE_MODE_AUTONOMOUS) != 0;
    if (autonomous && config->line == NULL)
        return false;
    need = co_store_image_need(od);
    half = buffer_size / 2;
    if (half < need)
        return false;
    has_save = co_od_has_index(od, 0x1010);
    has_restore = co_od_has_index(od, 0x1011);
    /* All or nothing: no half-hooked OD when the subscription table is full. */
    subs_needed = (unsigned)has_save + (unsigned)has_restore + (unsigned)autonomous;
    if ((unsigned)od->sub_capacity - od->sub_count < subs_needed)
        return false;
    memset(s, 0, sizeof *s);
    s->od = od;
    s->backend = backend;
    s->user = user;
    s->image = buffer;
    s->previous = buffer + half;
    s->image_capacity = half;
    s->last_load = CO_STORE_EMPTY;
    s->records_skipped = 0;
    s->groups = groups;
    s->group_rows = rows;
    s->last_sub = last_sub;
    if (autonomous) {
        s->line = config->line;
        s->min_interval_us = (uint64_t)config->min_interval_ms * 1000u;
        s->autonomous_saved = config->autonomous_saved;
        s->autonomous_user = config->autonomous_user;
    }
    co_timer_init(&s->autonomous_timer, on_autonomous_timer, s);
    /* Sub 1..last_sub only: sub 0 is the OD's, higher manufacturer subs stay plain. */
    if (has_save && !co_od_subscribe(od, 0x1010, 1, 0x1010, last_sub, &save_handler, s))
        return false;
    if (has_restore && !co_od_subscribe(od, 0x1011, 1, 0x1011, last_sub, &restore_handler, s))
        return false;
    /* every key: a member of an autonomous group may be anywhere */
    if (autonomous && !co_od_subscribe(od, 0x1000, 0, 0xFFFF, 0xFF, &member_handler, s))
        return false;
    return true;
}

void co_store_deinit(co_store_t *s)
{
    if (s->od) {
        co_od_unsubscribe(s->od, &save_handler, s);
        co_od_unsubscribe(s->od, &restore_handler, s);
        co_od_unsubscribe(s->od, &member_handler, s);
        if (s->line != NULL)
            co_timer_cancel(co_line_timers(s->line), &s->autonomous_timer);
        s->od = NULL;
    }
}
