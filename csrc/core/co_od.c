/* Object dictionary (CiA 301): a sorted array of sub-entries over caller
 * storage, values as little-endian byte arrays in a caller pool.
 *
 * Choices where CiA 301 and the header leave room (also listed in co_od.h):
 *  - Adds keep the array sorted (binary search + memmove), so adds in
 *    ascending order cost O(log n) and lookups work at any time; network and
 *    application access still need a sealed OD (else CO_ABORT_NO_OD).
 *  - A numeric entry without a default (default_length 0) defaults to 0.
 *  - Wrong length of a fixed-size value: longer than the type = LENGTH_HIGH
 *    (0x06070012), shorter = LENGTH_LOW (0x06070013); an odd length of a
 *    UNICODE_STRING = TYPE_MISMATCH (0x06070010). BOOLEAN takes 0 and 1 only
 *    (else INVALID_VALUE).
 *  - A begin on a busy transfer aborts the old one first (a domain writer is
 *    told CO_ABORT_GENERAL), as an SDO server restarts on a new initiate.
 *  - Domains: no domain_read handler = CO_ABORT_NO_DATA on upload, no
 *    domain_size handler = size unknown, no domain_write handler =
 *    CO_ABORT_UNSUPPORTED_ACCESS on download. Domains have no check_write
 *    pass (the data streams); after_write runs once a download completed.
 *
 * Values are byte arrays: nothing here casts a pool pointer to a wider type,
 * numbers go through the explicit little-endian helpers below. */
#include "canopenfd/co_od.h"

#include "canopenfd/co_assert.h"

#include <string.h>

#define FLAGS_KNOWN 0x00FFu      /* CO_OD_MAP_TPDO .. CO_OD_HAS_MAX */
#define FLAG_RESTORED 0x8000u    /* internal: co_od_load_defaults changed it */
#define FLAGS_LIMITS (CO_OD_HAS_MIN | CO_OD_HAS_MAX)

/* REAL32/REAL64 are converted with memcpy: the host must use 32/64-bit IEEE. */
typedef char co_od_float_is_32_bits[sizeof(float) == 4 ? 1 : -1];
typedef char co_od_double_is_64_bits[sizeof(double) == 8 ? 1 : -1];

/* ------------------------------------------------------------ helpers */

static void copy_bytes(uint8_t *dst, const uint8_t *src, uint32_t n)
{
    if (n > 0) {
        memcpy(dst, src, n);
    }
}

static uint64_t load_le(const uint8_t *p, uint32_t n)
{
    uint64_t v = 0;
    while (n > 0) {
        n--;
        v = (v << 8) | (uint64_t)p[n];
    }
    return v;
}

/* Sign-extend an n-byte two's complement number (n = 1..8). */
static int64_t to_signed(uint64_t v, uint32_t n)
{
    if (n < 8 && ((v >> (8u * n - 1u)) & 1u)) {
        v |= ~(uint64_t)0 << (8u * n);
    }
    if (v <= (uint64_t)INT64_MAX) {
        return (int64_t)v;
    }
    return -(int64_t)(~v) - 1;
}

static float load_f32(const uint8_t *p)
{
    uint32_t bits = (uint32_t)load_le(p, 4);
    float f;
    memcpy(&f, &bits, sizeof f);
    return f;
}

static double load_f64(const uint8_t *p)
{
    uint64_t bits = load_le(p, 8);
    double d;
    memcpy(&d, &bits, sizeof d);
    return d;
}

typedef enum kind {
    K_NONE = 0,
    K_BOOL,
    K_UNSIGNED,   /* also TIME_OF_DAY / TIME_DIFFERENCE (ordered as 48-bit LE) */
    K_SIGNED,
    K_REAL32,
    K_REAL64,
    K_STRING,     /* VISIBLE_STRING, OCTET_STRING */
    K_UNICODE,
    K_DOMAIN
} kind_t;

static kind_t kind_of(uint8_t type)
{
    switch (type) {
    case CO_TYPE_BOOLEAN:
        return K_BOOL;
    case CO_TYPE_UNSIGNED8:
    case CO_TYPE_UNSIGNED16:
    case CO_TYPE_UNSIGNED24:
    case CO_TYPE_UNSIGNED32:
    case CO_TYPE_UNSIGNED40:
    case CO_TYPE_UNSIGNED48:
    case CO_TYPE_UNSIGNED56:
    case CO_TYPE_UNSIGNED64:
    case CO_TYPE_TIME_OF_DAY:
    case CO_TYPE_TIME_DIFFERENCE:
        return K_UNSIGNED;
    case CO_TYPE_INTEGER8:
    case CO_TYPE_INTEGER16:
    case CO_TYPE_INTEGER24:
    case CO_TYPE_INTEGER32:
    case CO_TYPE_INTEGER40:
    case CO_TYPE_INTEGER48:
    case CO_TYPE_INTEGER56:
    case CO_TYPE_INTEGER64:
        return K_SIGNED;
    case CO_TYPE_REAL32:
        return K_REAL32;
    case CO_TYPE_REAL64:
        return K_REAL64;
    case CO_TYPE_VISIBLE_STRING:
    case CO_TYPE_OCTET_STRING:
        return K_STRING;
    case CO_TYPE_UNICODE_STRING:
        return K_UNICODE;
    case CO_TYPE_DOMAIN:
        return K_DOMAIN;
    default:
        return K_NONE;
    }
}

uint32_t co_od_type_size(uint8_t type)
{
    switch (type) {
    case CO_TYPE_BOOLEAN:
    case CO_TYPE_INTEGER8:
    case CO_TYPE_UNSIGNED8:
        return 1;
    case CO_TYPE_INTEGER16:
    case CO_TYPE_UNSIGNED16:
        return 2;
    case CO_TYPE_INTEGER24:
    case CO_TYPE_UNSIGNED24:
        return 3;
    case CO_TYPE_INTEGER32:
    case CO_TYPE_UNSIGNED32:
    case CO_TYPE_REAL32:
        return 4;
    case CO_TYPE_INTEGER40:
    case CO_TYPE_UNSIGNED40:
        return 5;
    case CO_TYPE_INTEGER48:
    case CO_TYPE_UNSIGNED48:
    case CO_TYPE_TIME_OF_DAY:
    case CO_TYPE_TIME_DIFFERENCE:
        return 6;
    case CO_TYPE_INTEGER56:
    case CO_TYPE_UNSIGNED56:
        return 7;
    case CO_TYPE_INTEGER64:
    case CO_TYPE_UNSIGNED64:
    case CO_TYPE_REAL64:
        return 8;
    default:
        return 0;
    }
}

static bool is_integer(kind_t k, uint8_t type)
{
    return k == K_SIGNED ||
           (k == K_UNSIGNED && type != CO_TYPE_TIME_OF_DAY && type != CO_TYPE_TIME_DIFFERENCE);
}

#define CMP_UNORDERED 2

/* a <=> b in the type's own order: -1, 0, 1, or CMP_UNORDERED (NaN). */
static int compare_values(uint8_t type, uint32_t size, const uint8_t *a, const uint8_t *b)
{
    switch (kind_of(type)) {
    case K_SIGNED: {
        int64_t x = to_signed(load_le(a, size), size), y = to_signed(load_le(b, size), size);
        return (x > y) - (x < y);
    }
    case K_REAL32: {
        float x = load_f32(a), y = load_f32(b);
        if (x != x || y != y) {
            return CMP_UNORDERED;
        }
        return (x > y) - (x < y);
    }
    case K_REAL64: {
        double x = load_f64(a), y = load_f64(b);
        if (x != x || y != y) {
            return CMP_UNORDERED;
        }
        return (x > y) - (x < y);
    }
    default: {
        uint64_t x = load_le(a, size), y = load_le(b, size);
        return (x > y) - (x < y);
    }
    }
}

static bool is_nan(uint8_t type, const uint8_t *v)
{
    switch (kind_of(type)) {
    case K_REAL32:
        return compare_values(type, 4, v, v) == CMP_UNORDERED;
    case K_REAL64:
        return compare_values(type, 8, v, v) == CMP_UNORDERED;
    default:
        return false;
    }
}

/* Value check of a fixed-size value against the type rule and the limits. */
static uint32_t check_fixed(uint8_t type, uint32_t size, uint16_t flags, const uint8_t *min,
                            const uint8_t *max, const uint8_t *v)
{
    if (type == CO_TYPE_BOOLEAN && v[0] > 1) {
        return CO_ABORT_INVALID_VALUE;
    }
    if ((flags & FLAGS_LIMITS) == 0) {
        return 0;
    }
    if (is_nan(type, v)) {
        return CO_ABORT_INVALID_VALUE;
    }
    if ((flags & CO_OD_HAS_MIN) && compare_values(type, size, v, min) < 0) {
        return CO_ABORT_VALUE_LOW;
    }
    if ((flags & CO_OD_HAS_MAX) && compare_values(type, size, v, max) > 0) {
        return CO_ABORT_VALUE_HIGH;
    }
    return 0;
}

static uint32_t check_length(uint8_t type, uint32_t size, uint32_t length)
{
    kind_t k = kind_of(type);
    if (k == K_DOMAIN) {
        return 0;
    }
    if (length > size) {
        return CO_ABORT_LENGTH_HIGH;
    }
    if (co_od_type_size(type) != 0 && length < size) {
        return CO_ABORT_LENGTH_LOW;
    }
    if (k == K_UNICODE && (length & 1u)) {
        return CO_ABORT_TYPE_MISMATCH;
    }
    return 0;
}

static bool covers(const co_od_subscription_t *s, uint32_t key)
{
    return s->first_key <= key && key <= s->last_key;
}

static co_od_entry_t *mutable_entry(co_od_t *od, const co_od_entry_t *e)
{
    return &od->entries[e - od->entries];
}

static void notify_after_write(co_od_t *od, const co_od_entry_t *e, co_od_origin_t origin)
{
    uint8_t i;
    for (i = 0; i < od->sub_count; i++) {
        const co_od_subscription_t *s = &od->subs[i];
        if (covers(s, e->key) && s->handler->after_write) {
            s->handler->after_write(od, e, origin, s->user);
        }
    }
}

/* Index of the first entry with key >= key. Branch-free halving: the
 * comparison picks the half with a conditional move, not a jump the CPU has
 * to guess (random lookups would mispredict about every other step). */
static uint32_t lower_bound(const co_od_t *od, uint32_t key)
{
    uint32_t base = 0, n = od->sorted_count;
    if (n == 0) {
        return 0;
    }
    while (n > 1) {
        uint32_t half = n / 2u;
        base = od->entries[base + half - 1u].key < key ? base + half : base;
        n -= half;
    }
    return base + (od->entries[base].key < key ? 1u : 0u);
}

/* ------------------------------------------------------------ building */

void co_od_init(co_od_t *od, co_mode_t mode, co_od_entry_t *entries, uint32_t capacity,
                uint8_t *pool, uint32_t pool_size, co_od_subscription_t *subs,
                uint8_t sub_capacity)
{
    memset(od, 0, sizeof *od);
    od->mode = mode;
    od->entries = entries;
    od->capacity = entries ? capacity : 0;
    od->pool = pool;
    od->pool_size = pool ? pool_size : 0;
    od->subs = subs;
    od->sub_capacity = subs ? sub_capacity : 0;
}

uint32_t co_od_pool_need(const co_od_def_t *def)
{
    uint64_t need = (uint64_t)def->size + def->default_length;
    if (def->flags & FLAGS_LIMITS) {
        need += 2u * (uint64_t)def->size;
    }
    return need > UINT32_MAX ? UINT32_MAX : (uint32_t)need;
}

static co_od_add_result_t validate(const co_od_def_t *def)
{
    kind_t k = kind_of(def->type);
    uint32_t fixed = co_od_type_size(def->type);
    static const uint8_t zero[8] = {0, 0, 0, 0, 0, 0, 0, 0};

    if (k == K_NONE || (def->flags & ~FLAGS_KNOWN) != 0 || def->access < CO_ACCESS_RO ||
        def->access > CO_ACCESS_CONST) {
        return CO_OD_ERR_TYPE;
    }
    /* size: the type's size; even for UNICODE_STRING; 0 for domains */
    if ((fixed != 0 && def->size != fixed) || (k == K_DOMAIN && def->size != 0) ||
        (k == K_UNICODE && (def->size & 1u))) {
        return CO_OD_ERR_TYPE;
    }
    if ((def->flags & CO_OD_NODEID_RELATIVE) && !is_integer(k, def->type)) {
        return CO_OD_ERR_TYPE;
    }
    if (def->default_length > 0 && def->default_value == NULL) {
        return CO_OD_ERR_DEFAULT;
    }
    /* default: exactly the size for numbers (or none = 0), at most the size
     * for strings (even for UNICODE_STRING), nothing for domains */
    if ((fixed != 0 && def->default_length != 0 && def->default_length != fixed) ||
        def->default_length > def->size || (k == K_UNICODE && (def->default_length & 1u))) {
        return CO_OD_ERR_DEFAULT;
    }
    if (def->flags & FLAGS_LIMITS) {
        if (fixed == 0) {
            return CO_OD_ERR_LIMITS;
        }
        if (((def->flags & CO_OD_HAS_MIN) && is_nan(def->type, def->min)) ||
            ((def->flags & CO_OD_HAS_MAX) && is_nan(def->type, def->max))) {
            return CO_OD_ERR_LIMITS;
        }
        if ((def->flags & FLAGS_LIMITS) == FLAGS_LIMITS &&
            compare_values(def->type, fixed, def->min, def->max) > 0) {
            return CO_OD_ERR_LIMITS;
        }
    }
    /* A $NODEID-relative default depends on the node-id (known at seal, changed
     * by LSS), so only absolute defaults are checked here. */
    if (fixed != 0 && !(def->flags & CO_OD_NODEID_RELATIVE) &&
        check_fixed(def->type, fixed, def->flags, def->min, def->max,
                    def->default_length ? def->default_value : zero) != 0) {
        return CO_OD_ERR_DEFAULT;
    }
    return CO_OD_ADDED;
}

/* What every add checks first: the definition itself, then the line mode. */
static co_od_add_result_t check_definition(const co_od_t *od, const co_od_def_t *def)
{
    if (def == NULL) {
        return CO_OD_ERR_TYPE;
    }
    co_od_add_result_t r = validate(def);
    if (r != CO_OD_ADDED) {
        return r;
    }
    if (((def->flags & CO_OD_FD_ONLY) && od->mode != CO_MODE_FD) ||
        ((def->flags & CO_OD_CLASSIC_ONLY) && od->mode == CO_MODE_FD)) {
        return CO_OD_SKIPPED_MODE;
    }
    return CO_OD_ADDED;
}

static bool has_room(const co_od_t *od, uint32_t need)
{
    return od->count < od->capacity && need <= od->pool_size - od->pool_used;
}

/* Fill slot e from def and take its pool bytes (the caller checked the room). */
static void fill_entry(co_od_t *od, co_od_entry_t *e, const co_od_def_t *def, bool in_image,
                       uint32_t offset, uint32_t need)
{
    uint32_t key = (uint32_t)def->index << 8 | def->sub;
    memset(e, 0, sizeof *e);
    e->key = key;
    e->object_code = def->object_code;
    e->type = def->type;
    e->access = def->access;
    e->flags = def->flags;
    e->size = def->size;
    e->length = 0;
    e->value = in_image ? offset : od->pool_used;
    e->default_value = in_image ? od->pool_used : e->value + def->size;
    e->default_length = def->default_length;
    e->limits = e->default_value + def->default_length;
    if (need > 0) {   /* (no pool pointer arithmetic when there is no pool) */
        memset(od->pool + od->pool_used, 0, need);
        copy_bytes(od->pool + e->default_value, def->default_value, def->default_length);
        if (def->flags & FLAGS_LIMITS) {
            copy_bytes(od->pool + e->limits, def->min, def->size);
            copy_bytes(od->pool + e->limits + def->size, def->max, def->size);
        }
    }
    od->pool_used += need;
    od->count++;
}

/* Add one entry before seal, in key order; with in_image its value lives at
 * image byte `offset` (the caller checked the range), only default and limits
 * take pool room. */
static co_od_add_result_t add_entry(co_od_t *od, const co_od_def_t *def, bool in_image,
                                    uint32_t offset)
{
    if (od->sealed) {
        return CO_OD_ERR_SEALED;
    }
    co_od_add_result_t r = check_definition(od, def);
    if (r != CO_OD_ADDED) {
        return r;
    }
    uint32_t key = (uint32_t)def->index << 8 | def->sub;
    uint32_t pos = lower_bound(od, key);
    if (pos < od->count && od->entries[pos].key == key) {
        return CO_OD_ERR_DUPLICATE;
    }
    uint32_t need = co_od_pool_need(def) - (in_image ? def->size : 0u);
    if (!has_room(od, need)) {
        return CO_OD_ERR_FULL;
    }
    if (pos < od->count) {
        memmove(&od->entries[pos + 1u], &od->entries[pos],
                (size_t)(od->count - pos) * sizeof od->entries[0]);
    }
    fill_entry(od, &od->entries[pos], def, in_image, offset, need);
    od->sorted_count = od->count;   /* before seal the whole table is sorted */
    return CO_OD_ADDED;
}

co_od_add_result_t co_od_add(co_od_t *od, const co_od_def_t *def)
{
    return add_entry(od, def, false, 0);
}

static bool load_default(co_od_t *od, co_od_entry_t *e);

static bool is_structured(uint8_t object_code)
{
    return object_code == CO_OBJECT_ARRAY || object_code == CO_OBJECT_RECORD;
}

/* The seal's ARRAY/RECORD rule for one live entry: sub 0 first, UNSIGNED8. */
static bool live_structure_ok(const co_od_t *od, const co_od_def_t *def)
{
    if (def->sub == 0) {
        return !is_structured(def->object_code) || def->type == CO_TYPE_UNSIGNED8;
    }
    const co_od_entry_t *sub0 = co_od_find(od, def->index, 0);
    return sub0 != NULL && sub0->type == CO_TYPE_UNSIGNED8 &&
           (is_structured(sub0->object_code) || is_structured(def->object_code));
}

co_od_add_result_t co_od_add_live(co_od_t *od, const co_od_def_t *def)
{
    if (!od->sealed) {
        return CO_OD_ERR_NOT_SEALED;
    }
    co_od_add_result_t r = check_definition(od, def);
    if (r != CO_OD_ADDED) {
        return r;
    }
    if (co_od_find(od, def->index, def->sub) != NULL) {
        return CO_OD_ERR_DUPLICATE;
    }
    if (def->index >= 0x1000u && def->index <= 0x1FFFu) {
        return CO_OD_ERR_COMMUNICATION;
    }
    if (def->size > od->live_size_max) {
        return CO_OD_ERR_TOO_LARGE;
    }
    if (!live_structure_ok(od, def)) {
        return CO_OD_ERR_STRUCTURE;
    }
    uint32_t need = co_od_pool_need(def);
    if (!has_room(od, need)) {
        return CO_OD_ERR_FULL;
    }
    co_od_entry_t *e = &od->entries[od->count];   /* appended: nothing moves */
    fill_entry(od, e, def, false, 0, need);
    (void)load_default(od, e);
    return CO_OD_ADDED;
}

co_od_add_result_t co_od_add_live_all(co_od_t *od, const co_od_def_t *defs, uint32_t count,
                                      uint32_t *refused)
{
    uint32_t count_before = od->count, pool_before = od->pool_used;
    for (uint32_t i = 0; i < count; i++) {
        co_od_add_result_t r = co_od_add_live(od, &defs[i]);
        if (r != CO_OD_ADDED && r != CO_OD_SKIPPED_MODE) {
            od->count = count_before;     /* live entries are the table's tail */
            od->pool_used = pool_before;
            *refused = i;
            return r;
        }
    }
    return CO_OD_ADDED;
}

bool co_od_reserve_image(co_od_t *od, uint32_t size)
{
    if (od->sealed || od->count > 0 || od->pool_used > 0 || size > od->pool_size) {
        return false;
    }
    if (size > 0) {
        memset(od->pool, 0, size);
    }
    od->image_size = size;
    od->pool_used = size;
    return true;
}

co_od_add_result_t co_od_add_in_image(co_od_t *od, const co_od_def_t *def, uint32_t offset)
{
    if (od->sealed) {
        return CO_OD_ERR_SEALED;
    }
    if (def == NULL) {
        return CO_OD_ERR_TYPE;
    }
    /* a fixed-size value only: strings and domains change length */
    if (co_od_type_size(def->type) == 0 || def->size != co_od_type_size(def->type) ||
        offset >= od->image_size || def->size > od->image_size - offset) {
        return CO_OD_ERR_IMAGE;
    }
    for (uint32_t i = 0; i < od->count; i++) {   /* no two entries share a byte */
        const co_od_entry_t *e = &od->entries[i];
        if (co_od_in_image(od, e) && e->value < offset + def->size &&
            offset < e->value + e->size) {
            return CO_OD_ERR_IMAGE;
        }
    }
    return add_entry(od, def, true, offset);
}

/* Load the default of one entry into its value; true when anything changed.
 * $NODEID-relative defaults get the node-id added (with carry, in the
 * entry's width). */
static bool load_default(co_od_t *od, co_od_entry_t *e)
{
    if (e->type == CO_TYPE_DOMAIN) {
        return false;
    }
    bool changed = false;
    uint32_t carry = (e->flags & CO_OD_NODEID_RELATIVE) ? od->node_id : 0u;
    uint32_t i;
    for (i = 0; i < e->size; i++) {
        uint32_t b = carry + (i < e->default_length ? od->pool[e->default_value + i] : 0u);
        carry = b >> 8;
        if (od->pool[e->value + i] != (uint8_t)b) {
            changed = true;
            od->pool[e->value + i] = (uint8_t)b;
        }
    }
    uint32_t length = co_od_type_size(e->type) != 0 ? e->size : e->default_length;
    if (e->length != length) {
        changed = true;
        e->length = length;
    }
    return changed;
}

void co_od_set_node_id(co_od_t *od, uint8_t node_id)
{
    od->node_id = node_id;
}

bool co_od_seal(co_od_t *od, uint8_t node_id)
{
    uint32_t i, j;
    if (od->sealed) {
        return false;
    }
    od->node_id = node_id;
    od->live_size_max = 0;
    for (i = 0; i < od->count; i++) {
        (void)load_default(od, &od->entries[i]);
        if (od->entries[i].size > od->live_size_max) {
            od->live_size_max = od->entries[i].size;
        }
    }
    /* ARRAY / RECORD objects need sub 0 as UNSIGNED8. Its value is not
     * checked against the sub-indices present: 0x1003 counts the errors
     * logged, a PDO mapping counts the mapped entries, both below the subs
     * that exist. */
    for (i = 0; i < od->count; i = j) {
        uint16_t index = co_od_entry_index(&od->entries[i]);
        bool structured = false;
        for (j = i; j < od->count && co_od_entry_index(&od->entries[j]) == index; j++) {
            structured = structured || is_structured(od->entries[j].object_code);
        }
        if (!structured) {
            continue;
        }
        const co_od_entry_t *sub0 = &od->entries[i];
        if (co_od_entry_sub(sub0) != 0 || sub0->type != CO_TYPE_UNSIGNED8) {
            od->refused_index = index;
            return false;
        }
    }
    od->sealed = true;
    return true;
}

bool co_od_subscribe(co_od_t *od, uint16_t first_index, uint8_t first_sub, uint16_t last_index,
                     uint8_t last_sub, const co_od_handler_t *handler, void *user)
{
    uint32_t first = (uint32_t)first_index << 8 | first_sub;
    uint32_t last = (uint32_t)last_index << 8 | last_sub;
    if (handler == NULL || first > last || od->sub_count >= od->sub_capacity) {
        return false;
    }
    co_od_subscription_t *s = &od->subs[od->sub_count++];
    s->first_key = first;
    s->last_key = last;
    s->handler = handler;
    s->user = user;
    return true;
}

void co_od_unsubscribe(co_od_t *od, const co_od_handler_t *handler, void *user)
{
    uint8_t kept = 0;
    for (uint8_t i = 0; i < od->sub_count; i++) {
        if (od->subs[i].handler != handler || od->subs[i].user != user) {
            od->subs[kept++] = od->subs[i];
        }
    }
    od->sub_count = kept;
}

/* ------------------------------------------------------------ lookup */

const co_od_entry_t *co_od_find(const co_od_t *od, uint16_t index, uint8_t sub)
{
    uint32_t key = (uint32_t)index << 8 | sub;
    uint32_t pos = lower_bound(od, key);
    if (pos < od->sorted_count && od->entries[pos].key == key) {
        return &od->entries[pos];
    }
    for (pos = od->sorted_count; pos < od->count; pos++) {   /* added live */
        if (od->entries[pos].key == key) {
            return &od->entries[pos];
        }
    }
    return NULL;
}

bool co_od_has_index(const co_od_t *od, uint16_t index)
{
    uint32_t pos = lower_bound(od, (uint32_t)index << 8);
    if (pos < od->sorted_count && co_od_entry_index(&od->entries[pos]) == index) {
        return true;
    }
    for (pos = od->sorted_count; pos < od->count; pos++) {
        if (co_od_entry_index(&od->entries[pos]) == index) {
            return true;
        }
    }
    return false;
}

/* Entry of a sealed OD, or the abort code that says why there is none. */
static const co_od_entry_t *lookup(const co_od_t *od, uint16_t index, uint8_t sub,
                                   uint32_t *abort)
{
    const co_od_entry_t *e = NULL;
    if (!od->sealed) {
        *abort = CO_ABORT_NO_OD;
    } else if ((e = co_od_find(od, index, sub)) == NULL) {
        *abort = co_od_has_index(od, index) ? CO_ABORT_NO_SUB : CO_ABORT_NO_OBJECT;
    } else {
        *abort = 0;
    }
    return e;
}

/* ------------------------------------------------------------ application access */

uint32_t co_od_check_value(const co_od_t *od, const co_od_entry_t *e, const uint8_t *data,
                           uint32_t length)
{
    uint32_t r = check_length(e->type, e->size, length);
    if (r != 0 || co_od_type_size(e->type) == 0) {
        return r;
    }
    const uint8_t *limits = od->pool + e->limits;
    return check_fixed(e->type, e->size, e->flags, limits, limits + e->size, data);
}

uint32_t co_od_get(const co_od_t *od, uint16_t index, uint8_t sub, uint8_t *buf, uint32_t cap,
                   uint32_t *length)
{
    uint32_t abort;
    const co_od_entry_t *e = lookup(od, index, sub, &abort);
    if (length) {
        *length = 0;
    }
    if (e == NULL) {
        return abort;
    }
    if (e->type == CO_TYPE_DOMAIN) {
        return CO_ABORT_UNSUPPORTED_ACCESS;
    }
    if (length) {
        *length = e->length;
    }
    if (cap < e->length) {
        return CO_ABORT_OUT_OF_MEMORY;
    }
    copy_bytes(buf, e->length ? od->pool + e->value : NULL, e->length);
    return 0;
}

/* Store a checked value: one copy, the rest of a string zeroed. */
static void store_value(co_od_t *od, co_od_entry_t *e, const uint8_t *data, uint32_t length)
{
    copy_bytes(length ? od->pool + e->value : NULL, data, length);
    if (e->size > length) {
        memset(od->pool + e->value + length, 0, e->size - length);
    }
    e->length = length;
}

uint32_t co_od_put(co_od_t *od, uint16_t index, uint8_t sub, const uint8_t *data, uint32_t length)
{
    uint32_t abort;
    const co_od_entry_t *e = lookup(od, index, sub, &abort);
    if (e == NULL) {
        return abort;
    }
    if (e->type == CO_TYPE_DOMAIN) {
        return CO_ABORT_UNSUPPORTED_ACCESS;
    }
    if (length > 0 && data == NULL) {
        return CO_ABORT_GENERAL;
    }
    abort = co_od_check_value(od, e, data, length);
    if (abort != 0) {
        return abort;
    }
    store_value(od, mutable_entry(od, e), data, length);
    notify_after_write(od, e, CO_ORIGIN_LOCAL);
    return 0;
}

static bool get_fixed(const co_od_t *od, uint16_t index, uint8_t sub, uint32_t size,
                      uint64_t *out)
{
    uint32_t abort;
    const co_od_entry_t *e = lookup(od, index, sub, &abort);
    if (e == NULL || co_od_type_size(e->type) != size) {
        return false;
    }
    *out = load_le(od->pool + e->value, size);
    return true;
}

bool co_od_get_u8(const co_od_t *od, uint16_t index, uint8_t sub, uint8_t *out)
{
    uint64_t v;
    if (!get_fixed(od, index, sub, 1, &v)) {
        return false;
    }
    *out = (uint8_t)v;
    return true;
}

bool co_od_get_u16(const co_od_t *od, uint16_t index, uint8_t sub, uint16_t *out)
{
    uint64_t v;
    if (!get_fixed(od, index, sub, 2, &v)) {
        return false;
    }
    *out = (uint16_t)v;
    return true;
}

bool co_od_get_u32(const co_od_t *od, uint16_t index, uint8_t sub, uint32_t *out)
{
    uint64_t v;
    if (!get_fixed(od, index, sub, 4, &v)) {
        return false;
    }
    *out = (uint32_t)v;
    return true;
}

uint8_t co_od_group_of(uint16_t index)
{
    if (index >= 0x6000u && index <= 0x9FFFu) {   /* the standardized profile area */
        return CO_GROUP_APPLICATION;
    }
    if (index >= 0x2000u) {
        return CO_GROUP_MANUFACTURER;
    }
    if (index >= 0x1000u) {
        return CO_GROUP_COMMUNICATION;
    }
    return 0;
}

static bool in_groups(const co_od_entry_t *e, void *user)
{
    return (co_od_group_of(co_od_entry_index(e)) & *(const uint8_t *)user) != 0;
}

void co_od_load_defaults(co_od_t *od, uint8_t group_mask)
{
    co_od_load_defaults_if(od, in_groups, &group_mask);
}

void co_od_load_defaults_if(co_od_t *od, co_od_pick_fn pick, void *user)
{
    uint32_t i;
    /* Load everything first, then tell: handlers see the restored OD whole. */
    for (i = 0; i < od->count; i++) {
        co_od_entry_t *e = &od->entries[i];
        if (pick(e, user) && load_default(od, e)) {
            e->flags |= FLAG_RESTORED;
        }
    }
    for (i = 0; i < od->count; i++) {
        co_od_entry_t *e = &od->entries[i];
        if (e->flags & FLAG_RESTORED) {
            e->flags &= (uint16_t)~FLAG_RESTORED;
            notify_after_write(od, e, CO_ORIGIN_RESTORE);
        }
    }
}

uint32_t co_od_check_cob_id_change(uint32_t old_value, uint32_t new_value)
{
    const uint32_t invalid = 0x80000000u;
    const uint32_t can_id = 0x3FFFFFFFu;   /* bits 0..28 CAN-ID, bit 29 frame format */
    if (!(old_value & invalid) && !(new_value & invalid) &&
        ((old_value ^ new_value) & can_id) != 0) {
        return CO_ABORT_INVALID_VALUE;
    }
    return 0;
}

/* ------------------------------------------------------------ network access */

enum { H_DOMAIN_SIZE, H_DOMAIN_READ, H_DOMAIN_WRITE };

/* The first subscription covering the entry that has this domain callback. */
static const co_od_subscription_t *domain_sub(const co_od_t *od, const co_od_entry_t *e,
                                              int which)
{
    uint8_t i;
    for (i = 0; i < od->sub_count; i++) {
        const co_od_subscription_t *s = &od->subs[i];
        const co_od_handler_t *h = s->handler;
        if (covers(s, e->key) &&
            ((which == H_DOMAIN_SIZE && h->domain_size) ||
             (which == H_DOMAIN_READ && h->domain_read) ||
             (which == H_DOMAIN_WRITE && h->domain_write))) {
            return s;
        }
    }
    return NULL;
}

static bool is_domain_write(const co_od_xfer_t *x)
{
    return x->state == CO_XFER_WRITE && x->entry != NULL && x->entry->type == CO_TYPE_DOMAIN;
}

/* End the transfer with an abort code (the domain writer is told when it
 * knows of the transfer and did not refuse it itself). */
static uint32_t finish(co_od_xfer_t *x, uint32_t abort, bool tell_writer)
{
    if (tell_writer && is_domain_write(x)) {
        const co_od_subscription_t *s = domain_sub(x->od, x->entry, H_DOMAIN_WRITE);
        if (s != NULL) {
            const uint8_t none = 0;
            x->state = CO_XFER_DONE;   /* no second notification from inside */
            (void)s->handler->domain_write(x->od, x->entry, x->offset, &none, 0, x->total, true,
                                           abort, s->user);
        }
    }
    x->state = CO_XFER_DONE;
    x->abort = abort;
    return abort;
}

void co_od_xfer_init(co_od_xfer_t *xfer, uint8_t *scratch, uint32_t scratch_size)
{
    memset(xfer, 0, sizeof *xfer);
    xfer->state = CO_XFER_IDLE;
    xfer->scratch = scratch;
    xfer->scratch_size = scratch ? scratch_size : 0;
}

static bool busy(const co_od_xfer_t *x)
{
    return x->state != CO_XFER_IDLE && x->state != CO_XFER_DONE;
}

void co_od_xfer_abort(co_od_xfer_t *xfer, uint32_t abort)
{
    if (!busy(xfer)) {
        return;
    }
    (void)finish(xfer, (abort == 0 || abort == CO_OD_SPLIT) ? CO_ABORT_GENERAL : abort, true);
}

static void start(co_od_t *od, co_od_xfer_t *x, const co_od_entry_t *e, uint32_t total)
{
    if (busy(x)) {
        co_od_xfer_abort(x, CO_ABORT_GENERAL);
    }
    x->od = od;
    x->entry = e;
    x->offset = 0;
    x->total = total;
    x->next_handler = 0;
    x->abort = 0;
}

/* All before_read handlers agreed: take the snapshot (or the domain size). */
static uint32_t read_ready(co_od_xfer_t *x)
{
    co_od_t *od = x->od;
    const co_od_entry_t *e = x->entry;
    if (e->type == CO_TYPE_DOMAIN) {
        const co_od_subscription_t *s;
        if (domain_sub(od, e, H_DOMAIN_READ) == NULL) {
            return finish(x, CO_ABORT_NO_DATA, false);
        }
        x->total = CO_OD_SIZE_UNKNOWN;
        if ((s = domain_sub(od, e, H_DOMAIN_SIZE)) != NULL) {
            uint32_t size = CO_OD_SIZE_UNKNOWN;
            uint32_t r = s->handler->domain_size(od, e, &size, s->user);
            if (r != 0) {
                return finish(x, r == CO_OD_SPLIT ? CO_ABORT_GENERAL : r, false);
            }
            x->total = size;
        }
    } else {
        x->total = e->length;
        copy_bytes(x->scratch, e->length ? od->pool + e->value : NULL, e->length);
    }
    x->state = CO_XFER_READ;
    return 0;
}

static uint32_t run_read_chain(co_od_xfer_t *x)
{
    co_od_t *od = x->od;
    const co_od_entry_t *e = x->entry;
    x->state = CO_XFER_PENDING_READ;
    while (x->next_handler < od->sub_count) {
        const co_od_subscription_t *s = &od->subs[x->next_handler++];
        if (!covers(s, e->key) || s->handler->before_read == NULL) {
            continue;
        }
        uint32_t r = s->handler->before_read(od, x, e, s->user);
        if (x->state != CO_XFER_PENDING_READ) {
            return x->abort;   /* the handler aborted the transfer itself */
        }
        if (r == CO_OD_SPLIT) {
            x->state = CO_XFER_PENDING_READ;
            return CO_OD_SPLIT;
        }
        if (r != 0) {
            return finish(x, r, false);
        }
    }
    return read_ready(x);
}

uint32_t co_od_read_begin(co_od_t *od, co_od_xfer_t *xfer, uint16_t index, uint8_t sub)
{
    uint32_t abort;
    const co_od_entry_t *e = lookup(od, index, sub, &abort);
    start(od, xfer, e, 0);
    if (e == NULL) {
        return finish(xfer, abort, false);
    }
    if (e->access == CO_ACCESS_WO) {
        return finish(xfer, CO_ABORT_WRITE_ONLY, false);
    }
    if (e->type != CO_TYPE_DOMAIN && xfer->scratch_size < e->size) {
        return finish(xfer, CO_ABORT_OUT_OF_MEMORY, false);
    }
    return run_read_chain(xfer);
}

uint32_t co_od_read_chunk(co_od_xfer_t *xfer, uint8_t *buf, uint32_t cap, uint32_t *n, bool *last)
{
    *n = 0;
    *last = true;
    if (xfer->state != CO_XFER_READ) {
        return CO_ABORT_GENERAL;
    }
    const co_od_entry_t *e = xfer->entry;
    CO_ASSERT(xfer->od != NULL && e != NULL);   /* set when the read began */
    bool known = xfer->total != CO_OD_SIZE_UNKNOWN;
    uint32_t room = known ? xfer->total - xfer->offset : UINT32_MAX - xfer->offset;
    if (cap > room) {
        cap = room;
    }
    if (e->type != CO_TYPE_DOMAIN) {
        /* the snapshot taken at begin fits the scratch (checked there) */
        CO_ASSERT(xfer->offset + cap <= xfer->scratch_size);
        copy_bytes(buf, cap ? xfer->scratch + xfer->offset : NULL, cap);
        *n = cap;
        xfer->offset += cap;
        if (xfer->offset == xfer->total) {
            xfer->state = CO_XFER_DONE;
        } else {
            *last = false;
        }
        return 0;
    }
    const co_od_subscription_t *s = domain_sub(xfer->od, e, H_DOMAIN_READ);
    if (s == NULL) {   /* (checked at begin; subscriptions are never removed) */
        return finish(xfer, CO_ABORT_NO_DATA, false);
    }
    uint32_t got = 0;
    bool end = false;
    uint32_t r = s->handler->domain_read(xfer->od, e, xfer->offset, buf, cap, &got, &end,
                                         s->user);
    if (r != 0) {
        return finish(xfer, r == CO_OD_SPLIT ? CO_ABORT_GENERAL : r, false);
    }
    if (got > cap) {
        /* more than asked for: a reader bug, or more data than announced */
        return finish(xfer, known ? CO_ABORT_GENERAL : CO_ABORT_LENGTH_HIGH, false);
    }
    xfer->offset += got;
    if (known && xfer->offset == xfer->total) {
        end = true;
    } else if (known && end) {
        return finish(xfer, CO_ABORT_GENERAL, false);   /* less data than announced */
    }
    *n = got;
    *last = end;
    if (end) {
        xfer->state = CO_XFER_DONE;
    }
    return 0;
}

uint32_t co_od_write_begin(co_od_t *od, co_od_xfer_t *xfer, uint16_t index, uint8_t sub,
                           uint32_t total)
{
    uint32_t abort;
    const co_od_entry_t *e = lookup(od, index, sub, &abort);
    start(od, xfer, e, total);
    if (e == NULL) {
        return finish(xfer, abort, false);
    }
    if (e->access == CO_ACCESS_RO || e->access == CO_ACCESS_CONST) {
        return finish(xfer, CO_ABORT_READ_ONLY, false);
    }
    if (e->type == CO_TYPE_DOMAIN) {
        const co_od_subscription_t *s = domain_sub(od, e, H_DOMAIN_WRITE);
        if (s == NULL) {
            return finish(xfer, CO_ABORT_UNSUPPORTED_ACCESS, false);
        }
        uint32_t refused = s->handler->domain_begin != NULL
                               ? s->handler->domain_begin(od, e, total, s->user) : 0;
        if (refused != 0) {
            return finish(xfer, refused, false);   /* the writer refused: nothing to tell it */
        }
    } else {
        if (xfer->scratch_size < e->size) {
            return finish(xfer, CO_ABORT_OUT_OF_MEMORY, false);
        }
        if (total != CO_OD_SIZE_UNKNOWN) {
            /* announced length: too long = LENGTH_HIGH, a fixed-size value
             * announced too short = LENGTH_LOW (CiA 301 abort codes) */
            if (total > e->size) {
                return finish(xfer, CO_ABORT_LENGTH_HIGH, false);
            }
            if (co_od_type_size(e->type) != 0 && total < e->size) {
                return finish(xfer, CO_ABORT_LENGTH_LOW, false);
            }
        }
    }
    xfer->state = CO_XFER_WRITE;
    return 0;
}

uint32_t co_od_write_chunk(co_od_xfer_t *xfer, const uint8_t *data, uint32_t n)
{
    if (xfer->state != CO_XFER_WRITE) {
        return CO_ABORT_GENERAL;
    }
    const co_od_entry_t *e = xfer->entry;
    CO_ASSERT(xfer->od != NULL && e != NULL);   /* set when the write began */
    uint32_t limit = xfer->total != CO_OD_SIZE_UNKNOWN ? xfer->total : UINT32_MAX;
    if (e->type != CO_TYPE_DOMAIN && e->size < limit) {
        limit = e->size;
    }
    if (n > limit - xfer->offset) {
        return finish(xfer, CO_ABORT_LENGTH_HIGH, true);
    }
    if (n > 0 && data == NULL) {
        return finish(xfer, CO_ABORT_GENERAL, true);
    }
    if (e->type != CO_TYPE_DOMAIN) {
        /* n is within the entry's size, which begin checked against the scratch */
        CO_ASSERT(xfer->offset + n <= xfer->scratch_size);
        copy_bytes(n ? xfer->scratch + xfer->offset : NULL, data, n);
        xfer->offset += n;
        return 0;
    }
    const co_od_subscription_t *s = domain_sub(xfer->od, e, H_DOMAIN_WRITE);
    if (s == NULL) {   /* (checked at begin; subscriptions are never removed) */
        return finish(xfer, CO_ABORT_UNSUPPORTED_ACCESS, false);
    }
    uint32_t r = s->handler->domain_write(xfer->od, e, xfer->offset, data, n, xfer->total, false,
                                          0, s->user);
    if (r != 0) {
        return finish(xfer, r == CO_OD_SPLIT ? CO_ABORT_GENERAL : r, false);
    }
    xfer->offset += n;
    return 0;
}

/* Every check_write agreed: one copy into the value, then tell everyone. */
static uint32_t write_commit(co_od_xfer_t *x)
{
    co_od_t *od = x->od;
    co_od_entry_t *e = mutable_entry(od, x->entry);
    uint32_t length = x->offset;
    if (e->size > length) {
        memset(x->scratch + length, 0, e->size - length);
    }
    copy_bytes(e->size ? od->pool + e->value : NULL, x->scratch, e->size);
    e->length = length;
    x->state = CO_XFER_DONE;
    x->abort = 0;
    notify_after_write(od, e, CO_ORIGIN_NETWORK);
    return 0;
}

static uint32_t run_write_chain(co_od_xfer_t *x)
{
    co_od_t *od = x->od;
    const co_od_entry_t *e = x->entry;
    x->state = CO_XFER_PENDING_WRITE;
    while (x->next_handler < od->sub_count) {
        const co_od_subscription_t *s = &od->subs[x->next_handler++];
        if (!covers(s, e->key) || s->handler->check_write == NULL) {
            continue;
        }
        uint32_t r = s->handler->check_write(od, x, e, x->scratch, x->offset, s->user);
        if (x->state != CO_XFER_PENDING_WRITE) {
            return x->abort;   /* the handler aborted the transfer itself */
        }
        if (r == CO_OD_SPLIT) {
            x->state = CO_XFER_PENDING_WRITE;
            return CO_OD_SPLIT;
        }
        if (r != 0) {
            return finish(x, r, false);
        }
    }
    return write_commit(x);
}

uint32_t co_od_write_end(co_od_xfer_t *xfer)
{
    if (xfer->state != CO_XFER_WRITE) {
        return CO_ABORT_GENERAL;
    }
    const co_od_entry_t *e = xfer->entry;
    if (xfer->total != CO_OD_SIZE_UNKNOWN && xfer->offset != xfer->total) {
        return finish(xfer, CO_ABORT_LENGTH_LOW, true);   /* less than announced */
    }
    if (e->type == CO_TYPE_DOMAIN) {
        const co_od_subscription_t *s = domain_sub(xfer->od, e, H_DOMAIN_WRITE);
        const uint8_t none = 0;
        if (s == NULL) {
            return finish(xfer, CO_ABORT_UNSUPPORTED_ACCESS, false);
        }
        uint32_t r = s->handler->domain_write(xfer->od, e, xfer->offset, &none, 0, xfer->total,
                                              true, 0, s->user);
        if (r != 0) {
            return finish(xfer, r == CO_OD_SPLIT ? CO_ABORT_GENERAL : r, false);
        }
        xfer->state = CO_XFER_DONE;
        xfer->abort = 0;
        notify_after_write(xfer->od, e, CO_ORIGIN_NETWORK);
        return 0;
    }
    uint32_t r = co_od_check_value(xfer->od, e, xfer->scratch, xfer->offset);
    if (r != 0) {
        return finish(xfer, r, false);
    }
    xfer->next_handler = 0;
    return run_write_chain(xfer);
}

uint32_t co_od_resume(co_od_xfer_t *xfer, uint32_t abort)
{
    if (xfer->state != CO_XFER_PENDING_READ && xfer->state != CO_XFER_PENDING_WRITE) {
        return CO_ABORT_GENERAL;
    }
    if (abort == CO_OD_SPLIT) {
        return CO_OD_SPLIT;   /* still waiting */
    }
    if (abort != 0) {
        return finish(xfer, abort, false);
    }
    return xfer->state == CO_XFER_PENDING_READ ? run_read_chain(xfer) : run_write_chain(xfer);
}
