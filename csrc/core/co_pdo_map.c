/* PDO mapping: validation and compiled copy lists (see co_pdo_map.h). */
#include "canopenfd/co_pdo_map.h"

#include <string.h>

enum { DUMMY_FIRST = 0x0002, DUMMY_LAST = 0x0007 };

uint16_t co_pdo_map_max_bits(const co_od_t *od)
{
    return od->mode == CO_MODE_FD ? CO_PDO_FD_BYTES * 8u : CO_PDO_CLASSIC_BYTES * 8u;
}

static bool readable(uint8_t access)
{
    return access == CO_ACCESS_RO || access == CO_ACCESS_RW || access == CO_ACCESS_RWR ||
           access == CO_ACCESS_CONST;
}

static bool writable(uint8_t access)
{
    return access == CO_ACCESS_WO || access == CO_ACCESS_RW || access == CO_ACCESS_RWW;
}

uint32_t co_pdo_map_check_entry(const co_od_t *od, bool is_rpdo, uint32_t mapping,
                                co_pdo_map_item_t *item)
{
    uint16_t index = (uint16_t)(mapping >> 16);
    uint8_t sub = (uint8_t)(mapping >> 8);
    uint8_t bits = (uint8_t)mapping;
    co_pdo_map_item_t it = {0, 0, 0, bits, 0};
    if (bits == 0 || (od->mode == CO_MODE_FD && bits % 8u != 0)) {
        return CO_ABORT_NO_MAP;
    }
    if (index >= DUMMY_FIRST && index <= DUMMY_LAST && sub == 0) {
        /* dummy: the data type's index, its exact size, receivers only */
        if (!is_rpdo || bits != co_od_type_size((uint8_t)index) * 8u) {
            return CO_ABORT_NO_MAP;
        }
        it.flags = CO_PDO_ITEM_DUMMY;
    } else {
        const co_od_entry_t *e = co_od_find(od, index, sub);
        uint32_t size_bits;
        if (e == NULL || e->type == CO_TYPE_DOMAIN || e->size == 0 ||
            !(e->flags & (is_rpdo ? CO_OD_MAP_RPDO : CO_OD_MAP_TPDO)) ||
            !(is_rpdo ? writable(e->access) : readable(e->access))) {
            return CO_ABORT_NO_MAP;
        }
        size_bits = e->size * 8u;
        if (bits > size_bits) {
            return CO_ABORT_NO_MAP;
        }
        it.value = e->value;
        it.entry = (uint32_t)(e - od->entries);
        if (bits < size_bits) {
            it.flags |= CO_PDO_ITEM_PARTIAL;
        }
        if (co_od_type_size(e->type) == 0) {
            it.flags |= CO_PDO_ITEM_STRING;
        }
    }
    if (item != NULL) {
        *item = it;
    }
    return 0;
}

uint32_t co_pdo_map_compile(const co_od_t *od, uint16_t map_index, bool is_rpdo, uint8_t count,
                            uint8_t capacity, co_pdo_map_item_t *items, uint16_t *bits)
{
    uint32_t total = 0;
    uint8_t i;
    if (count > capacity || count > CO_PDO_MAX_ENTRIES) {
        return CO_ABORT_VALUE_HIGH;
    }
    for (i = 0; i < count; i++) {
        uint32_t mapping;
        co_pdo_map_item_t it;
        uint32_t abort;
        if (!co_od_get_u32(od, map_index, (uint8_t)(i + 1u), &mapping) || mapping == 0) {
            return CO_ABORT_NO_MAP;
        }
        abort = co_pdo_map_check_entry(od, is_rpdo, mapping, &it);
        if (abort != 0) {
            return abort;
        }
        it.bit = (uint16_t)total;
        total += it.bits;
        if (total > co_pdo_map_max_bits(od)) {
            return CO_ABORT_MAP_LENGTH;
        }
        /* one memcpy when the item starts on a byte and is whole bytes */
        if (it.bit % 8u == 0 && it.bits % 8u == 0) {
            it.flags |= CO_PDO_ITEM_BYTES;
        }
        if (items != NULL) {
            items[i] = it;
        }
    }
    *bits = (uint16_t)total;
    return 0;
}

/* Copy n bits, LSB first (CANopen's little-endian bit order). */
static void copy_bits(uint8_t *dst, uint32_t dst_bit, const uint8_t *src, uint32_t src_bit,
                      uint32_t n)
{
    uint32_t k;
    for (k = 0; k < n; k++) {
        uint32_t s = src_bit + k, d = dst_bit + k;
        uint8_t mask = (uint8_t)(1u << (d % 8u));
        if (src[s / 8u] & (1u << (s % 8u))) {
            dst[d / 8u] |= mask;
        } else {
            dst[d / 8u] &= (uint8_t)~mask;
        }
    }
}

void co_pdo_map_pack(const co_od_t *od, const co_pdo_map_item_t *items, uint8_t count,
                     uint16_t bits, uint8_t *data)
{
    uint8_t i;
    memset(data, 0, (bits + 7u) / 8u);
    for (i = 0; i < count; i++) {
        const co_pdo_map_item_t *it = &items[i];
        const uint8_t *value = od->pool + it->value;
        if (it->flags & CO_PDO_ITEM_DUMMY) {
            continue;   /* (never compiled for a TPDO) */
        }
        if (it->flags & CO_PDO_ITEM_BYTES) {
            memcpy(data + it->bit / 8u, value, it->bits / 8u);
        } else {
            copy_bits(data, it->bit, value, 0, it->bits);
        }
    }
}

void co_pdo_map_unpack(co_od_t *od, const co_pdo_map_item_t *items, uint8_t count,
                       const uint8_t *data)
{
    uint8_t i;
    for (i = 0; i < count; i++) {
        const co_pdo_map_item_t *it = &items[i];
        uint8_t *value = od->pool + it->value;
        co_od_entry_t *e = &od->entries[it->entry];
        if (it->flags & CO_PDO_ITEM_DUMMY) {
            continue;
        }
        if (it->flags & CO_PDO_ITEM_PARTIAL) {
            memset(value, 0, e->size);   /* the unmapped part reads as 0 */
        }
        if (it->flags & CO_PDO_ITEM_BYTES) {
            memcpy(value, data + it->bit / 8u, it->bits / 8u);
        } else {
            copy_bits(value, 0, data, it->bit, it->bits);
        }
        if (it->flags & CO_PDO_ITEM_STRING) {
            e->length = (it->bits + 7u) / 8u;
        }
    }
}
