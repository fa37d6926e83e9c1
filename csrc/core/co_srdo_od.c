/* The SRDO objects of a node's OD (see co_srdo_od.h). */
#include "canopenfd/co_srdo_od.h"

#include <string.h>

enum { LAST_SRDO = 64, VALID_SUB = 0 };

typedef enum object_kind { OTHER, GFC, COMMUNICATION, MAPPING, VALID, SIGNATURE } object_kind_t;

/* Which SRDO object index is, and for 0x1301.. / 0x1381.. its SRDO number. */
static object_kind_t kind_of(uint16_t index, uint8_t *number)
{
    *number = 0;
    if (index == CO_SRDO_OD_GFC) {
        return GFC;
    }
    if (index > CO_SRDO_OD_COMMUNICATION && index <= CO_SRDO_OD_COMMUNICATION + LAST_SRDO) {
        *number = (uint8_t)(index - CO_SRDO_OD_COMMUNICATION);
        return COMMUNICATION;
    }
    if (index > CO_SRDO_OD_MAPPING && index <= CO_SRDO_OD_MAPPING + LAST_SRDO) {
        *number = (uint8_t)(index - CO_SRDO_OD_MAPPING);
        return MAPPING;
    }
    return index == CO_SRDO_OD_VALID ? VALID : index == CO_SRDO_OD_SIGNATURE ? SIGNATURE : OTHER;
}

static uint32_t le_value(const uint8_t *value, uint32_t length)
{
    uint32_t v = 0;
    for (uint32_t i = 0; i < length && i < 4u; i++) {
        v |= (uint32_t)value[i] << (8u * i);
    }
    return v;
}

/* 0x1301+n: the ranges co_srdo_check applies to the whole configuration. */
static uint32_t check_communication(uint8_t sub, uint32_t v)
{
    bool ok;
    switch (sub) {
    case 1: ok = v <= CO_SRDO_CONSUME; break;
    case 2: ok = v >= 1u; break;
    case 3: ok = v >= 1u; break;
    case 4: ok = v == CO_SRDO_TRANSMISSION_TYPE; break;
    case 5: ok = v >= CO_SRDO_COB_ID_FIRST && v < CO_SRDO_COB_ID_LAST && (v & 1u) != 0; break;
    case 6: ok = v > CO_SRDO_COB_ID_FIRST && v <= CO_SRDO_COB_ID_LAST && (v & 1u) == 0; break;
    default: ok = true; break;
    }
    return ok ? 0 : CO_ABORT_INVALID_VALUE;
}

/* 0x1381+n: the SRDO off, entries only while the count is 0 (CiA 301's PDO
 * mapping order), an even count of at most 16. */
static uint32_t check_mapping(const co_od_t *od, uint8_t number, uint8_t sub, uint32_t v)
{
    uint8_t direction = CO_SRDO_OFF, count = 0;
    (void)co_od_get_u8(od, (uint16_t)(CO_SRDO_OD_COMMUNICATION + number), 1, &direction);
    (void)co_od_get_u8(od, (uint16_t)(CO_SRDO_OD_MAPPING + number), 0, &count);
    if (direction != CO_SRDO_OFF || (sub != 0 && count != 0)) {
        return CO_ABORT_UNSUPPORTED_ACCESS;
    }
    if (sub == 0 && (v > CO_SRDO_MAX_MAPPED || (v & 1u) != 0)) {
        return CO_ABORT_MAP_LENGTH;
    }
    return 0;
}

static uint32_t check_write(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e,
                            const uint8_t *value, uint32_t length, void *user)
{
    (void)xfer;
    const co_srdo_od_t *g = user;
    uint8_t number;
    object_kind_t kind = kind_of(co_od_entry_index(e), &number);
    if (kind == OTHER) {
        return 0;
    }
    uint32_t v = le_value(value, length);
    if (kind == GFC) {
        return v <= 1u ? 0 : CO_ABORT_INVALID_VALUE;   /* switched in any state */
    }
    if (g->operational) {
        return CO_ABORT_DATA_STATE;
    }
    if (kind == COMMUNICATION) {
        return check_communication(co_od_entry_sub(e), v);
    }
    if (kind == MAPPING) {
        return check_mapping(od, number, co_od_entry_sub(e), v);
    }
    return 0;
}

/* SRDO 1's default COB-IDs: when 0x1301 sub 5 / 6 hold exactly the base
 * values 0x0FF / 0x100 (the OD's defaults, or loaded at a reset), they are
 * resolved in place to base + 2 x node-id, as a $NODEID default is at
 * loading: reads and the CRC see the CAN-IDs used, and a reset with another
 * node-id resolves them again. Written in place: a resolution is no change
 * (0x13FE stays). Node-ids above 64 leave them unresolved, out of range.
 * True when it resolved them. */
static bool resolve_default_cob_ids(co_od_t *od)
{
    const uint16_t comm = CO_SRDO_OD_COMMUNICATION + 1;
    const co_od_entry_t *normal = co_od_find(od, comm, 5);
    const co_od_entry_t *inverted = co_od_find(od, comm, 6);
    uint32_t n = 0, i = 0;
    uint8_t node_id = co_od_node_id(od);
    if (!normal || !inverted || normal->size != 4 || inverted->size != 4 ||
        !co_od_get_u32(od, comm, 5, &n) || !co_od_get_u32(od, comm, 6, &i) ||
        n != CO_SRDO_OD_DEFAULT_COB_ID || i != CO_SRDO_OD_DEFAULT_COB_ID + 1u ||
        node_id < 1u || node_id > CO_SRDO_OD_DEFAULT_LAST_NODE) {
        return false;
    }
    uint32_t add = 2u * node_id;
    const co_od_entry_t *entries[2] = {normal, inverted};
    const uint32_t values[2] = {n + add, i + add};
    for (int k = 0; k < 2; k++) {
        uint8_t *p = co_od_value(od, entries[k]);
        for (uint32_t b = 0; b < 4u; b++) {
            p[b] = (uint8_t)(values[k] >> (8u * b));
        }
    }
    return true;
}

static void load_all(co_srdo_od_t *g)
{
    (void)resolve_default_cob_ids(g->od);
    for (uint8_t n = 1; n <= g->count; n++) {
        (void)co_srdo_od_load(g, n);
    }
}

/* 0x1300 = 1: the GFC is sent and heard (a CAN-ID 0x001 another service
 * holds leaves it off; co_gfc counts nothing then). */
static void follow_gfc(co_srdo_od_t *g)
{
    uint8_t on = 0;
    if (g->gfc && co_od_get_u8(g->od, CO_SRDO_OD_GFC, 0, &on)) {
        (void)co_gfc_set_enabled(g->gfc, on == 1u);
    }
}

/* Outside operational the SRDOs follow their objects at once (so a
 * producer takes set_data before the start); a change also clears 0x13FE,
 * whose own after-write then reloads them. */
static void after_write(co_od_t *od, const co_od_entry_t *e, co_od_origin_t origin, void *user)
{
    co_srdo_od_t *g = user;
    uint8_t number;
    object_kind_t kind = kind_of(co_od_entry_index(e), &number);
    if (kind == GFC) {
        follow_gfc(g);
        return;
    }
    if (kind == OTHER) {
        return;
    }
    if (kind == VALID || origin == CO_ORIGIN_RESTORE) {
        if (!g->operational) {
            load_all(g);   /* loading defaults or stored values is no change */
        }
        return;
    }
    /* a changed configuration runs only once a tool has validated it again
     * (the application's own writes pass the guard, even in operational) */
    const uint8_t invalid = 0;
    (void)co_od_put(od, CO_SRDO_OD_VALID, VALID_SUB, &invalid, 1);
}

static const co_od_handler_t handler = {NULL, check_write, after_write, NULL, NULL, NULL, NULL};

bool co_srdo_od_attach(co_srdo_od_t *g, co_od_t *od, co_srdo_t *srdo, uint8_t count,
                       co_gfc_t *gfc, co_nmt_state_t state)
{
    memset(g, 0, sizeof *g);
    if (!co_od_find(od, CO_SRDO_OD_VALID, VALID_SUB) ||
        !co_od_subscribe(od, CO_SRDO_OD_GFC, 0, CO_SRDO_OD_SIGNATURE, 0xFF, &handler, g)) {
        return false;
    }
    g->od = od;
    g->srdo = srdo;
    g->count = count;
    g->gfc = gfc;
    follow_gfc(g);
    g->operational = state == CO_NMT_OPERATIONAL;
    if (!g->operational) {
        load_all(g);
    }
    return true;
}

void co_srdo_od_detach(co_srdo_od_t *g)
{
    if (g->od) {
        co_od_unsubscribe(g->od, &handler, g);
    }
    memset(g, 0, sizeof *g);
}

void co_srdo_od_set_nmt_state(co_srdo_od_t *g, co_nmt_state_t state)
{
    if (!g->od) {
        return;
    }
    bool operational = state == CO_NMT_OPERATIONAL;
    if (operational && !g->operational) {
        load_all(g);
    } else if (!operational && resolve_default_cob_ids(g->od)) {
        load_all(g);   /* a reset's reload that changed no value, with a new node-id */
    }
    g->operational = operational;
}

/* A missing sub-entry leaves its field 0: the range check then names it. */
static co_srdo_config_t read_config(const co_od_t *od, uint8_t number)
{
    uint16_t comm = (uint16_t)(CO_SRDO_OD_COMMUNICATION + number);
    uint16_t mapping = (uint16_t)(CO_SRDO_OD_MAPPING + number);
    co_srdo_config_t c;
    memset(&c, 0, sizeof c);
    (void)co_od_get_u8(od, comm, 1, &c.direction);
    (void)co_od_get_u16(od, comm, 2, &c.sct_ms);
    (void)co_od_get_u8(od, comm, 3, &c.srvt_ms);
    (void)co_od_get_u8(od, comm, 4, &c.transmission_type);
    (void)co_od_get_u32(od, comm, 5, &c.cob_id_normal);
    (void)co_od_get_u32(od, comm, 6, &c.cob_id_inverted);
    (void)co_od_get_u8(od, mapping, 0, &c.map_count);
    uint8_t count = c.map_count <= CO_SRDO_MAX_MAPPED ? c.map_count : CO_SRDO_MAX_MAPPED;
    for (uint8_t i = 0; i < count; i++) {
        (void)co_od_get_u32(od, mapping, (uint8_t)(i + 1u), &c.map[i]);
    }
    return c;
}

bool co_srdo_od_load(co_srdo_od_t *g, uint8_t number)
{
    if (!g->od || number == 0 || number > g->count ||
        !co_od_has_index(g->od, (uint16_t)(CO_SRDO_OD_COMMUNICATION + number))) {
        return false;
    }
    co_srdo_config_t config = read_config(g->od, number);
    uint8_t valid = 0;
    uint16_t signature = 0;
    (void)co_od_get_u8(g->od, CO_SRDO_OD_VALID, VALID_SUB, &valid);
    (void)co_od_get_u16(g->od, CO_SRDO_OD_SIGNATURE, number, &signature);
    co_srdo_t *srdo = &g->srdo[number - 1];
    if (!co_srdo_configure(srdo, &config, valid, signature)) {
        return false;
    }
    (void)co_srdo_bind_od(srdo, g->od);   /* a mapping that fails is latched in the SRDO */
    return true;
}

static uint32_t put_le(co_od_t *od, uint16_t index, uint8_t sub, uint32_t value, uint32_t size)
{
    uint8_t b[4];
    for (uint32_t i = 0; i < size; i++) {
        b[i] = (uint8_t)(value >> (8u * i));
    }
    return co_od_put(od, index, sub, b, size);
}

uint32_t co_srdo_od_store(co_srdo_od_t *g, uint8_t number, const co_srdo_config_t *config,
                          uint8_t valid, uint16_t signature)
{
    if (!g->od || number == 0 || number > g->count) {
        return CO_ABORT_NO_OBJECT;
    }
    uint16_t comm = (uint16_t)(CO_SRDO_OD_COMMUNICATION + number);
    uint16_t mapping = (uint16_t)(CO_SRDO_OD_MAPPING + number);
    /* the valid flag last: every write before it clears 0x13FE */
    struct { uint16_t index; uint8_t sub; uint32_t value; uint8_t size; } writes[] = {
        {comm, 1, config->direction, 1}, {comm, 2, config->sct_ms, 2},
        {comm, 3, config->srvt_ms, 1}, {comm, 4, config->transmission_type, 1},
        {comm, 5, config->cob_id_normal, 4}, {comm, 6, config->cob_id_inverted, 4},
        {mapping, 0, config->map_count, 1}, {CO_SRDO_OD_SIGNATURE, number, signature, 2},
    };
    for (size_t i = 0; i < sizeof writes / sizeof writes[0]; i++) {
        uint32_t abort = put_le(g->od, writes[i].index, writes[i].sub, writes[i].value,
                                writes[i].size);
        if (abort != 0) {
            return abort;
        }
    }
    uint8_t count = config->map_count <= CO_SRDO_MAX_MAPPED ? config->map_count
                                                            : CO_SRDO_MAX_MAPPED;
    for (uint8_t i = 0; i < count; i++) {
        uint32_t abort = put_le(g->od, mapping, (uint8_t)(i + 1u), config->map[i], 4);
        if (abort != 0) {
            return abort;
        }
    }
    return put_le(g->od, CO_SRDO_OD_VALID, VALID_SUB, valid, 1);
}
