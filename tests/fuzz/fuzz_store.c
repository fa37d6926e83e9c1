/* libFuzzer harness: the store image loader (co_store_load) over an image
 * the input provides, as a damaged or hostile medium would.
 *
 * Input: [options][image bytes]. options bit 0: fix the CRC-32 after the
 * other fixes, bit 1: fix magic, version, header length and payload length,
 * so records are parsed instead of stopping at the header checks; bits 4..6:
 * the groups loaded (0 = all).
 *
 * Checks: the status is one of the store's; after a load every entry holds
 * a value its own checks accept (type, length, limits) and no longer than
 * its size; a save of what was loaded then a load gives CO_STORE_OK and the
 * same values (the loader and the writer agree on the format). */
#include "fuzz_input.h"

#include "canopenfd/co_od.h"
#include "canopenfd/co_store.h"
#include "co_crc.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { ENTRIES = 64, POOL = 4096, SUBS = 4, IMAGE_MAX = 4096, NODE = 7 };

typedef struct store_world {
    co_od_t od;
    co_od_entry_t entries[ENTRIES];
    uint8_t pool[POOL];
    co_od_subscription_t subs[SUBS];
    co_store_t store;
    uint8_t buffer[2 * IMAGE_MAX];
    uint8_t medium[IMAGE_MAX];
    uint32_t medium_len;
    bool medium_has;
    uint8_t snapshot[POOL];
    uint32_t lengths[ENTRIES];
} store_world_t;

static store_world_t S;

static void fail(const char *what)
{
    fprintf(stderr, "fuzz invariant broken: %s\n", what);
    abort();
}

static co_store_status_t save(void *user, const uint8_t *image, uint32_t length)
{
    (void)user;
    if (length > sizeof S.medium) {
        return CO_STORE_IO;
    }
    memcpy(S.medium, image, length);
    S.medium_len = length;
    S.medium_has = true;
    return CO_STORE_OK;
}

static co_store_status_t load(void *user, uint8_t *image, uint32_t capacity, uint32_t *length)
{
    (void)user;
    if (!S.medium_has) {
        return CO_STORE_EMPTY;
    }
    if (S.medium_len > capacity) {
        return CO_STORE_TOO_BIG;
    }
    memcpy(image, S.medium, S.medium_len);
    *length = S.medium_len;
    return CO_STORE_OK;
}

static const co_store_backend_t ops = {save, load};

typedef struct row {
    uint16_t index;
    uint8_t sub;
    uint8_t object_code;
    uint8_t type;
    uint16_t flags;
    uint32_t size;
    uint32_t value;
} row_t;

#define ST CO_OD_STORE
#define LIM (CO_OD_HAS_MIN | CO_OD_HAS_MAX)

static const row_t rows[] = {
    {0x1010, 0, CO_OBJECT_ARRAY, CO_TYPE_UNSIGNED8, 0, 1, 4},
    {0x1010, 1, CO_OBJECT_ARRAY, CO_TYPE_UNSIGNED32, 0, 4, 1},
    {0x1010, 2, CO_OBJECT_ARRAY, CO_TYPE_UNSIGNED32, 0, 4, 1},
    {0x1010, 3, CO_OBJECT_ARRAY, CO_TYPE_UNSIGNED32, 0, 4, 1},
    {0x1010, 4, CO_OBJECT_ARRAY, CO_TYPE_UNSIGNED32, 0, 4, 1},
    {0x1017, 0, CO_OBJECT_VAR, CO_TYPE_UNSIGNED16, ST, 2, 100},
    {0x1400, 0, CO_OBJECT_RECORD, CO_TYPE_UNSIGNED8, 0, 1, 2},
    {0x1400, 1, CO_OBJECT_RECORD, CO_TYPE_UNSIGNED32, ST | CO_OD_NODEID_RELATIVE, 4, 0x200},
    {0x1400, 2, CO_OBJECT_RECORD, CO_TYPE_UNSIGNED8, ST, 1, 254},
    {0x2000, 0, CO_OBJECT_VAR, CO_TYPE_BOOLEAN, ST, 1, 1},
    {0x2001, 0, CO_OBJECT_VAR, CO_TYPE_INTEGER16, ST | LIM, 2, 5},
    {0x2002, 0, CO_OBJECT_VAR, CO_TYPE_REAL32, ST | LIM, 4, 0},
    {0x2003, 0, CO_OBJECT_VAR, CO_TYPE_VISIBLE_STRING, ST, 16, 0},
    {0x2004, 0, CO_OBJECT_VAR, CO_TYPE_UNICODE_STRING, ST, 8, 0},
    {0x2005, 0, CO_OBJECT_VAR, CO_TYPE_OCTET_STRING, ST, 40, 0},
    {0x2006, 0, CO_OBJECT_VAR, CO_TYPE_UNSIGNED64, ST, 8, 9},
    {0x2007, 0, CO_OBJECT_VAR, CO_TYPE_DOMAIN, ST, 0, 0},
    {0x2008, 0, CO_OBJECT_VAR, CO_TYPE_UNSIGNED8, 0, 1, 3},
    {0x6000, 0, CO_OBJECT_VAR, CO_TYPE_INTEGER24, ST, 3, 0},
    {0x6001, 0, CO_OBJECT_VAR, CO_TYPE_UNSIGNED32, ST | LIM, 4, 50},
    {0xA000, 0, CO_OBJECT_VAR, CO_TYPE_UNSIGNED8, ST, 1, 0},
};

static void build(void)
{
    memset(&S, 0, sizeof S);
    co_od_init(&S.od, CO_MODE_FD, S.entries, ENTRIES, S.pool, POOL, S.subs, SUBS);
    for (size_t i = 0; i < sizeof rows / sizeof rows[0]; i++) {
        const row_t *r = &rows[i];
        co_od_def_t d;
        uint8_t v[8] = {0};
        memset(&d, 0, sizeof d);
        d.index = r->index;
        d.sub = r->sub;
        d.object_code = r->object_code;
        d.type = r->type;
        d.access = CO_ACCESS_RW;
        d.flags = r->flags;
        d.size = r->size;
        if (co_od_type_size(r->type) != 0) {
            for (uint32_t k = 0; k < 4 && k < r->size; k++) {
                v[k] = (uint8_t)(r->value >> (8 * k));
            }
            d.default_value = v;
            d.default_length = r->size;
        }
        if (r->index == 0x2001) {          /* -100 .. 100 */
            d.min[0] = 0x9C; d.min[1] = 0xFF;
            d.max[0] = 100;
        } else if (r->index == 0x2002) {   /* -1.0 .. 1.0 */
            d.min[2] = 0x80; d.min[3] = 0xBF;
            d.max[2] = 0x80; d.max[3] = 0x3F;
        } else if (r->index == 0x6001) {   /* 10 .. 100000 */
            d.min[0] = 10;
            d.max[0] = 0xA0; d.max[1] = 0x86; d.max[2] = 0x01;
        }
        if (co_od_add(&S.od, &d) != CO_OD_ADDED) {
            fail("store OD refuses an entry");
        }
    }
    if (!co_od_seal(&S.od, NODE)) {
        fail("store OD does not seal");
    }
    if (!co_store_init(&S.store, &S.od, &ops, NULL, S.buffer, sizeof S.buffer)) {
        fail("co_store_init");
    }
}

static void put_u32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; i++) {
        p[i] = (uint8_t)(v >> (8 * i));
    }
}

/* Every entry's value as its own checks would accept it. */
static void check_values(void)
{
    for (uint32_t i = 0; i < S.od.count; i++) {
        const co_od_entry_t *e = &S.od.entries[i];
        if (e->type == CO_TYPE_DOMAIN) {
            continue;
        }
        if (e->length > e->size) {
            fail("an entry holds more than its size");
        }
        if (co_od_check_value(&S.od, e, co_od_value(&S.od, e), e->length) != 0) {
            fail("the loader put a value the entry refuses");
        }
    }
}

static void snapshot(void)
{
    memcpy(S.snapshot, S.pool, POOL);
    for (uint32_t i = 0; i < S.od.count; i++) {
        S.lengths[i] = S.od.entries[i].length;
    }
}

static void same_as_snapshot(void)
{
    for (uint32_t i = 0; i < S.od.count; i++) {
        const co_od_entry_t *e = &S.od.entries[i];
        if (e->type == CO_TYPE_DOMAIN) {
            continue;
        }
        if (e->length != S.lengths[i] ||
            memcmp(co_od_value(&S.od, e), S.snapshot + e->value, e->length) != 0) {
            fail("save then load does not give the same values");
        }
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static const uint8_t magic[8] = {'C', 'o', 'F', 'D', 'p', 'a', 'r', 0};
    uint8_t opt;
    uint8_t groups;
    if (size == 0) {
        return 0;
    }
    build();
    opt = data[0];
    groups = (uint8_t)((opt >> 4) & 7u);
    if (groups == 0) {
        groups = CO_GROUP_ALL;
    }
    size--;
    data++;
    if (size > IMAGE_MAX) {
        size = IMAGE_MAX;
    }
    memcpy(S.medium, data, size);
    S.medium_len = (uint32_t)size;
    S.medium_has = true;
    if (size >= 28 && (opt & 2u)) {
        memcpy(S.medium, magic, 8);
        S.medium[8] = 1; S.medium[9] = 0;
        S.medium[10] = 28; S.medium[11] = 0;
        put_u32(S.medium + 20, (uint32_t)size - 28u);
    }
    if (size >= 28 && (opt & 1u)) {
        uint32_t crc = co_crc32(0, S.medium, 24);
        crc = co_crc32(crc, S.medium + 28, size - 28);
        put_u32(S.medium + 24, crc);
    }
    co_store_status_t st = co_store_load(&S.store, groups);
    if (st > CO_STORE_TOO_BIG) {
        fail("co_store_load returned an unknown status");
    }
    check_values();
    snapshot();
    /* what was loaded survives a save and a load */
    if (co_store_save(&S.store, CO_GROUP_ALL) != 0) {
        fail("co_store_save of a loaded OD failed");
    }
    if (co_store_load(&S.store, CO_GROUP_ALL) != CO_STORE_OK) {
        fail("an image the store wrote does not load");
    }
    check_values();
    same_as_snapshot();
    co_store_deinit(&S.store);
    return 0;
}
