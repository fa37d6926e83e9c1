/* COB-ID entry rules (see co_cob_id.h). */
#include "co_cob_id.h"

enum { FIRST_INDEX = 0x1005, LAST_INDEX = 0x19FF };

#define ID_BITS 0x3FFFFFFFu   /* CAN-ID (bits 0..28) and frame format (bit 29) */
#define GEN_BIT 0x40000000u
#define VALID_BIT 0x80000000u

co_cob_id_kind_t co_cob_id_kind(uint16_t index, uint8_t sub)
{
    if (index == 0x1005 && sub == 0) {
        return CO_COB_ID_SYNC;
    }
    if (index == 0x1012 && sub == 0) {
        return CO_COB_ID_TIME;
    }
    if ((index == 0x1014 && sub == 0) || (index == 0x1028 && sub >= 1 && sub <= 0x7F) ||
        (index >= 0x1200 && index <= 0x12FF && (sub == 1 || sub == 2)) ||
        (((index >= 0x1400 && index <= 0x15FF) || (index >= 0x1800 && index <= 0x19FF)) &&
         sub == 1)) {
        return CO_COB_ID_VALID_BIT31;
    }
    return CO_COB_ID_NONE;
}

/* Whether the object uses its COB-ID with this value. */
static bool active(co_cob_id_kind_t kind, uint32_t value)
{
    switch (kind) {
    case CO_COB_ID_VALID_BIT31:
        return (value & VALID_BIT) == 0;
    case CO_COB_ID_SYNC:
        return (value & GEN_BIT) != 0;
    case CO_COB_ID_TIME:
        return (value & (GEN_BIT | VALID_BIT)) != 0;
    default:
        return false;
    }
}

uint32_t co_cob_id_check(co_cob_id_kind_t kind, uint32_t old_value, uint32_t new_value)
{
    if (kind == CO_COB_ID_VALID_BIT31) {
        return co_od_check_cob_id_change(old_value, new_value);
    }
    if (kind != CO_COB_ID_NONE && active(kind, old_value) && active(kind, new_value) &&
        ((old_value ^ new_value) & ID_BITS) != 0) {
        return CO_ABORT_INVALID_VALUE;
    }
    return 0;
}

static uint32_t get_le32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static uint32_t check_write(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e,
                            const uint8_t *value, uint32_t length, void *user)
{
    (void)xfer;
    (void)user;
    co_cob_id_kind_t kind = co_cob_id_kind(co_od_entry_index(e), co_od_entry_sub(e));
    if (kind == CO_COB_ID_NONE || e->type != CO_TYPE_UNSIGNED32 || length != 4 ||
        e->length != 4) {
        return 0;
    }
    return co_cob_id_check(kind, get_le32(co_od_value(od, e)), get_le32(value));
}

static const co_od_handler_t cob_id_handler = {.check_write = check_write};

bool co_cob_id_attach(co_od_t *od)
{
    return co_od_subscribe(od, FIRST_INDEX, 0, LAST_INDEX, 0xFF, &cob_id_handler, NULL);
}

void co_cob_id_detach(co_od_t *od)
{
    co_od_unsubscribe(od, &cob_id_handler, NULL);
}

bool co_cob_id_restricted(uint32_t can_id)
{
    return can_id <= 0x07Fu || (can_id >= 0x101u && can_id <= 0x180u) ||
           (can_id >= 0x581u && can_id <= 0x5FFu) || (can_id >= 0x601u && can_id <= 0x67Fu) ||
           (can_id >= 0x6E0u && can_id <= 0x6FFu) || can_id >= 0x701u;
}
