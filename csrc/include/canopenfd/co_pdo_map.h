/* PDO mapping (CiA 301 / CiA 1301): validation of mapping entries against
 * the object dictionary, and the compiled copy list a PDO uses per frame.
 *
 * A mapping entry is index << 16 | sub << 8 | length in bits. A compiled
 * item holds where the value lives in the OD's pool and where it sits in the
 * PDO, so sending and receiving copy bytes without looking anything up.
 *
 *   classic OD (CO_MODE_CLASSIC): up to 8 bytes, bit-wise mapping allowed
 *   fd OD (CO_MODE_FD):           up to 64 bytes, byte-wise mapping only
 *                                 (a length that is not a multiple of 8 is
 *                                 refused with 0x06040041)
 *   both: up to 64 entries; dummy entries 0x0002..0x0007 sub 0 (the
 *   INTEGER8..UNSIGNED32 type indices, with their exact size) in RPDOs only.
 *
 * An entry may map fewer bits than the object holds: the low-order bits (a
 * number) or the first bytes (a string). A receiver then sets the rest of
 * the object to 0 and a string's length to the mapped bytes.
 *
 * Pure functions over a sealed OD; nothing allocates. */
#ifndef CO_PDO_MAP_H
#define CO_PDO_MAP_H

#include "canopenfd/co_od.h"

enum {
    CO_PDO_MAX_ENTRIES = 64,        /* mapping entries per PDO (sub 1..64) */
    CO_PDO_CLASSIC_BYTES = 8,
    CO_PDO_FD_BYTES = 64
};

enum co_pdo_item_flags {
    CO_PDO_ITEM_DUMMY = 0x01,       /* RPDO dummy entry: the bits are skipped */
    CO_PDO_ITEM_BYTES = 0x02,       /* byte-aligned whole bytes: one memcpy */
    CO_PDO_ITEM_PARTIAL = 0x04,     /* fewer bits than the object holds */
    CO_PDO_ITEM_STRING = 0x08       /* variable-length type: a receiver sets the length */
};

typedef struct co_pdo_map_item {
    uint32_t value;                 /* offset of the value in the OD's pool */
    uint32_t entry;                 /* position of the entry in od->entries */
    uint16_t bit;                   /* first bit in the PDO (bit 0 = LSB of byte 0) */
    uint8_t bits;                   /* mapped length in bits, 1..248 */
    uint8_t flags;                  /* co_pdo_item_flags */
} co_pdo_map_item_t;

/* Largest PDO payload of an OD's kind of line, in bits. */
uint16_t co_pdo_map_max_bits(const co_od_t *od);
/* Check one mapping entry value for an RPDO (is_rpdo) or a TPDO: 0 or the
 * CiA 301 abort code (0x06040041 for everything that cannot be mapped: no
 * such object, not mappable that way, not readable/writable, longer than the
 * object, 0 bits, a non-byte length on fd). On success *item (may be NULL)
 * is filled with bit = 0. */
uint32_t co_pdo_map_check_entry(const co_od_t *od, bool is_rpdo, uint32_t mapping,
                                co_pdo_map_item_t *item);
/* Compile mapping object map_index with `count` entries (sub 1..count, as
 * they are in the OD now) into items[0..count-1]. Aborts: count above
 * capacity or 64 = 0x06090031; an entry missing, 0 or not mappable =
 * 0x06040041; the total above the PDO's size = 0x06040042. *bits = total
 * mapped length. items may be NULL to only check. */
uint32_t co_pdo_map_compile(const co_od_t *od, uint16_t map_index, bool is_rpdo, uint8_t count,
                            uint8_t capacity, co_pdo_map_item_t *items, uint16_t *bits);
/* TPDO: copy the mapped values into data (bytes beyond the mapped bits up
 * to (bits + 7) / 8 are 0). */
void co_pdo_map_pack(const co_od_t *od, const co_pdo_map_item_t *items, uint8_t count,
                     uint16_t bits, uint8_t *data);
/* RPDO: copy data (at least (bits + 7) / 8 bytes) into the mapped values. */
void co_pdo_map_unpack(co_od_t *od, const co_pdo_map_item_t *items, uint8_t count,
                       const uint8_t *data);

#endif
