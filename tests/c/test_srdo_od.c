/* The SRDO objects in the OD (co_srdo_od) and the data of mapped variables
 * (co_srdo_bind_od), on the in-process bus with the fake clock: device p
 * (line 1) produces SRDO 1 on 0x103/0x104, device c (line 2) consumes it;
 * m (line 0) is the configuration tool's and the injector's line. Writes
 * go through OD transfers as an SDO server makes them. */
#include "test_od_util.h"

#include "canopenfd/co_gfc.h"
#include "canopenfd/co_srdo.h"
#include "canopenfd/co_srdo_od.h"

#define NORMAL 0x103u
#define INVERTED 0x104u
#define COMM 0x1301u
#define MAP 0x1381u
/* two data: a 16-bit value (0x6000, inverted copy 0x6001) and an 8-bit one
 * (0x6002, inverted copy 0x6003): 3 bytes per frame */
#define A 0x6000u
#define A_INV 0x6001u
#define B 0x6002u
#define B_INV 0x6003u
static const uint32_t mapping[4] = {0x60000010u, 0x60010010u, 0x60020008u, 0x60030008u};

enum { ENTRIES = 40, POOL = 1024, SUBS = 2 };

typedef struct dev {
    co_od_t od;
    co_od_entry_t entries[ENTRIES];
    uint8_t pool[POOL];
    co_od_subscription_t subs[SUBS];
    co_srdo_t srdo;
    co_gfc_t gfc;
    co_srdo_od_t guard;
    co_srdo_violation_t why[4];
    int events;
} dev_t;

typedef struct fx {
    tu_bus_t tb;
    tu_line_t l[3];
    co_line_t *m;
    dev_t p, c;
} fx_t;

static void on_safe(co_srdo_t *srdo, co_srdo_violation_t why, void *user)
{
    dev_t *d = user;
    assert_ptr_equal(srdo, &d->srdo);
    assert_true(d->events < 4);
    d->why[d->events++] = why;
}

/* cob_default: the defaults of 0x1301 sub 5 / 6 (base, base + 1; 0: both 0). */
static void dev_init_with(dev_t *d, co_line_t *line, uint32_t cob_default, uint8_t node_id)
{
    co_od_init(&d->od, CO_MODE_CLASSIC, d->entries, ENTRIES, d->pool, POOL, d->subs, SUBS);
    tu_od_add_value(&d->od, CO_SRDO_OD_GFC, 0, VAR, U8, RW, 0, 0);
    tu_od_add_value(&d->od, COMM, 0, REC, U8, RO, 0, 6);
    tu_od_add_value(&d->od, COMM, 1, REC, U8, RW, 0, 0);
    tu_od_add_value(&d->od, COMM, 2, REC, CO_TYPE_UNSIGNED16, RW, 0, 0);
    tu_od_add_value(&d->od, COMM, 3, REC, U8, RW, 0, 0);
    tu_od_add_value(&d->od, COMM, 4, REC, U8, RW, 0, 0);
    tu_od_add_value(&d->od, COMM, 5, REC, U32, RW, 0, cob_default);
    tu_od_add_value(&d->od, COMM, 6, REC, U32, RW, 0, cob_default ? cob_default + 1u : 0u);
    tu_od_add_value(&d->od, MAP, 0, ARR, U8, RW, 0, 0);
    for (uint8_t s = 1; s <= 4; s++) {
        tu_od_add_value(&d->od, MAP, s, ARR, U32, RW, 0, 0);
    }
    tu_od_add_value(&d->od, CO_SRDO_OD_VALID, 0, VAR, U8, RW, 0, 0);
    tu_od_add_value(&d->od, CO_SRDO_OD_SIGNATURE, 0, ARR, U8, RO, 0, 1);
    tu_od_add_value(&d->od, CO_SRDO_OD_SIGNATURE, 1, ARR, CO_TYPE_UNSIGNED16, RW, 0, 0);
    const uint16_t both = CO_OD_MAP_TPDO | CO_OD_MAP_RPDO;
    tu_od_add_value(&d->od, A, 0, VAR, CO_TYPE_UNSIGNED16, RW, both, 0);
    tu_od_add_value(&d->od, A_INV, 0, VAR, CO_TYPE_UNSIGNED16, RW, both, 0xFFFF);
    tu_od_add_value(&d->od, B, 0, VAR, U8, RW, both, 0);
    tu_od_add_value(&d->od, B_INV, 0, VAR, U8, RW, both, 0xFF);
    assert_true(co_od_seal(&d->od, node_id));
    co_srdo_init(&d->srdo, line, on_safe, d);
    co_gfc_init(&d->gfc, line, NULL, NULL);
    assert_true(co_srdo_od_attach(&d->guard, &d->od, &d->srdo, 1, &d->gfc,
                                  CO_NMT_PRE_OPERATIONAL));
}

static void dev_init(dev_t *d, co_line_t *line)
{
    dev_init_with(d, line, 0, 5);
}

static int setup(void **state)
{
    fx_t *fx = calloc(1, sizeof *fx);
    if (fx == NULL)
        return -1;
    tu_bus_init(&fx->tb, CO_MODE_CLASSIC, false);
    fx->m = tu_bus_add_line(&fx->tb, &fx->l[0]);
    dev_init(&fx->p, tu_bus_add_line(&fx->tb, &fx->l[1]));
    dev_init(&fx->c, tu_bus_add_line(&fx->tb, &fx->l[2]));
    *state = fx;
    return 0;
}

static int teardown(void **state)
{
    fx_t *fx = *state;
    co_srdo_od_detach(&fx->p.guard);
    co_srdo_od_detach(&fx->c.guard);
    co_srdo_deinit(&fx->p.srdo);
    co_srdo_deinit(&fx->c.srdo);
    co_gfc_deinit(&fx->p.gfc);
    co_gfc_deinit(&fx->c.gfc);
    free(fx);
    return 0;
}

/* The NMT state as the node hands it on: the guard first, then the SRDO. */
static void set_state(fx_t *fx, dev_t *d, co_nmt_state_t state)
{
    co_line_set_time(d->srdo.line, fx->tb.now);
    co_srdo_od_set_nmt_state(&d->guard, state);
    co_srdo_set_nmt_state(&d->srdo, state);
}

static co_srdo_config_t config(uint8_t direction)
{
    co_srdo_config_t c;
    memset(&c, 0, sizeof c);
    c.direction = direction;
    c.sct_ms = direction == CO_SRDO_PRODUCE ? 20 : 25;
    c.srvt_ms = 5;
    c.transmission_type = CO_SRDO_TRANSMISSION_TYPE;
    c.cob_id_normal = NORMAL;
    c.cob_id_inverted = INVERTED;
    c.map_count = 4;
    memcpy(c.map, mapping, sizeof mapping);
    return c;
}

/* A configuration tool's downloads, in write_srdo_config's order (the
 * COB-IDs left out unless cob_ids: the device's defaults then stay). */
static void tool_writes_cob_ids(dev_t *d, const co_srdo_config_t *c, uint8_t valid,
                                uint16_t signature, bool cob_ids)
{
    assert_int_equal(tu_od_net_write(&d->od, COMM, 1, 0, 1), 0);
    assert_int_equal(tu_od_net_write(&d->od, MAP, 0, 0, 1), 0);
    for (uint8_t s = 1; s <= c->map_count; s++) {
        assert_int_equal(tu_od_net_write(&d->od, MAP, s, c->map[s - 1], 4), 0);
    }
    assert_int_equal(tu_od_net_write(&d->od, MAP, 0, c->map_count, 1), 0);
    assert_int_equal(tu_od_net_write(&d->od, COMM, 2, c->sct_ms, 2), 0);
    assert_int_equal(tu_od_net_write(&d->od, COMM, 3, c->srvt_ms, 1), 0);
    assert_int_equal(tu_od_net_write(&d->od, COMM, 4, c->transmission_type, 1), 0);
    if (cob_ids) {
        assert_int_equal(tu_od_net_write(&d->od, COMM, 5, c->cob_id_normal, 4), 0);
        assert_int_equal(tu_od_net_write(&d->od, COMM, 6, c->cob_id_inverted, 4), 0);
    }
    assert_int_equal(tu_od_net_write(&d->od, COMM, 1, c->direction, 1), 0);
    assert_int_equal(tu_od_net_write(&d->od, CO_SRDO_OD_SIGNATURE, 1, signature, 2), 0);
    assert_int_equal(tu_od_net_write(&d->od, CO_SRDO_OD_VALID, 0, valid, 1), 0);
}

static void tool_writes(dev_t *d, const co_srdo_config_t *c, uint8_t valid, uint16_t signature)
{
    tool_writes_cob_ids(d, c, valid, signature, true);
}

static void configure_valid(dev_t *d, uint8_t direction)
{
    co_srdo_config_t c = config(direction);
    tool_writes(d, &c, CO_SRDO_CONFIG_VALID, co_srdo_crc(&c));
    assert_int_equal(tu_od_value(&d->od, CO_SRDO_OD_VALID, 0, 1), CO_SRDO_CONFIG_VALID);
}

static void inject(fx_t *fx, uint32_t id, const uint8_t *data, uint8_t len, uint64_t at)
{
    tu_run_until(&fx->tb, at);
    assert_true(co_line_send(fx->m, id, data, len));
    tu_step(&fx->tb, at);
}

/* The application's own write (co_od_put: no write checks). */
static void put_sub(dev_t *d, uint16_t index, uint8_t sub, uint64_t value, uint32_t size)
{
    uint8_t b[8];
    tu_le_put(b, value, size);
    assert_int_equal(co_od_put(&d->od, index, sub, b, size), 0);
}

static void put(dev_t *d, uint16_t index, uint64_t value, uint32_t size)
{
    put_sub(d, index, 0, value, size);
}

/* The producer's variables a and b with their complements, then operational
 * (the first pair goes out at once). */
static void produce_from(fx_t *fx, dev_t *p, uint16_t a, uint8_t b)
{
    put(p, A, a, 2);
    put(p, A_INV, (uint16_t)~a, 2);
    put(p, B, b, 1);
    put(p, B_INV, (uint8_t)~b, 1);
    set_state(fx, p, CO_NMT_OPERATIONAL);
    tu_step(&fx->tb, 0);
}

/* ------------------------------------------------------------- the guard */

static void test_writes_refused_while_operational(void **state)
{
    fx_t *fx = *state;
    dev_t *c = &fx->c;
    configure_valid(c, CO_SRDO_CONSUME);
    set_state(fx, c, CO_NMT_OPERATIONAL);
    assert_int_equal(tu_od_net_write(&c->od, COMM, 2, 50, 2), CO_ABORT_DATA_STATE);
    assert_int_equal(tu_od_net_write(&c->od, COMM, 1, 0, 1), CO_ABORT_DATA_STATE);
    assert_int_equal(tu_od_net_write(&c->od, MAP, 0, 0, 1), CO_ABORT_DATA_STATE);
    assert_int_equal(tu_od_net_write(&c->od, CO_SRDO_OD_VALID, 0, 0, 1), CO_ABORT_DATA_STATE);
    assert_int_equal(tu_od_net_write(&c->od, CO_SRDO_OD_SIGNATURE, 1, 1, 2),
                     CO_ABORT_DATA_STATE);
    assert_int_equal(CO_ABORT_DATA_STATE, 0x08000022u);
    /* nothing changed, and the mapped data stay writable */
    assert_int_equal(tu_od_value(&c->od, COMM, 2, 2), 25);
    assert_int_equal(tu_od_value(&c->od, CO_SRDO_OD_VALID, 0, 1), CO_SRDO_CONFIG_VALID);
    assert_int_equal(tu_od_net_write(&c->od, A, 0, 7, 2), 0);
    /* the application's own write is not refused, but still invalidates */
    put_sub(c, COMM, 3, 7, 1);
    assert_int_equal(tu_od_value(&c->od, CO_SRDO_OD_VALID, 0, 1), 0);
    set_state(fx, c, CO_NMT_PRE_OPERATIONAL);
    assert_int_equal(tu_od_net_write(&c->od, COMM, 2, 50, 2), 0);
}

static void test_accepted_write_clears_valid(void **state)
{
    fx_t *fx = *state;
    dev_t *c = &fx->c;
    const struct { uint16_t index; uint8_t sub; uint32_t value; uint32_t len; } writes[] = {
        {COMM, 2, 30, 2}, {COMM, 3, 6, 1}, {COMM, 5, 0x105, 4}, {CO_SRDO_OD_SIGNATURE, 1, 7, 2},
        {COMM, 1, 0, 1}, {MAP, 0, 0, 1}, {MAP, 1, mapping[0], 4},
    };
    configure_valid(c, CO_SRDO_CONSUME);
    for (size_t i = 0; i < sizeof writes / sizeof writes[0]; i++) {
        assert_int_equal(tu_od_net_write(&c->od, CO_SRDO_OD_VALID, 0, 0xA5, 1), 0);
        assert_int_equal(tu_od_net_write(&c->od, writes[i].index, writes[i].sub,
                                         writes[i].value, writes[i].len), 0);
        assert_int_equal(tu_od_value(&c->od, CO_SRDO_OD_VALID, 0, 1), 0);
    }
    /* writing the flag itself, or a mapped variable, is no configuration change */
    assert_int_equal(tu_od_net_write(&c->od, CO_SRDO_OD_VALID, 0, 0xA5, 1), 0);
    assert_int_equal(tu_od_net_write(&c->od, A, 0, 1, 2), 0);
    assert_int_equal(tu_od_value(&c->od, CO_SRDO_OD_VALID, 0, 1), 0xA5);
}

static void test_out_of_range_and_out_of_order_refused(void **state)
{
    fx_t *fx = *state;
    dev_t *c = &fx->c;
    assert_int_equal(tu_od_net_write(&c->od, COMM, 1, 3, 1), CO_ABORT_INVALID_VALUE);
    assert_int_equal(tu_od_net_write(&c->od, COMM, 2, 0, 2), CO_ABORT_INVALID_VALUE);
    assert_int_equal(tu_od_net_write(&c->od, COMM, 3, 0, 1), CO_ABORT_INVALID_VALUE);
    assert_int_equal(tu_od_net_write(&c->od, COMM, 4, 253, 1), CO_ABORT_INVALID_VALUE);
    assert_int_equal(tu_od_net_write(&c->od, COMM, 5, 0x102, 4), CO_ABORT_INVALID_VALUE);
    assert_int_equal(tu_od_net_write(&c->od, COMM, 5, 0x181, 4), CO_ABORT_INVALID_VALUE);
    assert_int_equal(tu_od_net_write(&c->od, COMM, 6, 0x103, 4), CO_ABORT_INVALID_VALUE);
    assert_int_equal(tu_od_net_write(&c->od, MAP, 0, 3, 1), CO_ABORT_MAP_LENGTH);
    assert_int_equal(tu_od_net_write(&c->od, MAP, 0, 18, 1), CO_ABORT_MAP_LENGTH);
    assert_int_equal(tu_od_net_write(&c->od, MAP, 0, 2, 1), 0);
    /* an entry only while the count is 0, any mapping change only while off */
    assert_int_equal(tu_od_net_write(&c->od, MAP, 1, mapping[0], 4),
                     CO_ABORT_UNSUPPORTED_ACCESS);
    assert_int_equal(tu_od_net_write(&c->od, COMM, 1, CO_SRDO_CONSUME, 1), 0);
    assert_int_equal(tu_od_net_write(&c->od, MAP, 0, 0, 1), CO_ABORT_UNSUPPORTED_ACCESS);
    assert_int_equal(tu_od_value(&c->od, MAP, 0, 1), 2);
}

/* 0x1300 switches the GFC in any NMT state; 0 and 1 only. */
static void test_gfc_parameter_switches_the_gfc(void **state)
{
    fx_t *fx = *state;
    dev_t *c = &fx->c;
    assert_false(c->gfc.enabled);
    assert_false(co_gfc_send(&c->gfc));
    assert_int_equal(tu_od_net_write(&c->od, CO_SRDO_OD_GFC, 0, 2, 1), CO_ABORT_INVALID_VALUE);
    assert_int_equal(tu_od_net_write(&c->od, CO_SRDO_OD_GFC, 0, 1, 1), 0);
    assert_true(c->gfc.enabled);
    assert_true(co_gfc_send(&c->gfc));
    tu_step(&fx->tb, 1 * TU_MS);
    const uint8_t none[1] = {0};
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, 0x001, 0), 0x001, none, 0);
    set_state(fx, c, CO_NMT_OPERATIONAL);
    assert_int_equal(tu_od_net_write(&c->od, CO_SRDO_OD_GFC, 0, 0, 1), 0);
    assert_false(c->gfc.enabled);
    assert_int_equal(tu_od_value(&c->od, CO_SRDO_OD_VALID, 0, 1), 0);   /* untouched */
}

/* ------------------------------------------------------ start from the OD */

static void test_start_runs_what_the_od_holds(void **state)
{
    fx_t *fx = *state;
    dev_t *c = &fx->c;
    configure_valid(c, CO_SRDO_CONSUME);
    assert_int_equal(c->srdo.config.direction, CO_SRDO_CONSUME);   /* follows the OD at once */
    assert_int_equal(co_srdo_state(&c->srdo), CO_SRDO_STOPPED);
    set_state(fx, c, CO_NMT_OPERATIONAL);
    assert_int_equal(co_srdo_state(&c->srdo), CO_SRDO_WAITING);
    assert_int_equal(c->srdo.config.cob_id_normal, NORMAL);
    assert_int_equal(c->srdo.length, 3);
    /* a valid pair lands in the mapped variables: normal bytes in the odd
     * entries' variables, inverted bytes in the even ones' */
    const uint8_t normal[3] = {0x34, 0x12, 0x56}, inverted[3] = {0xCB, 0xED, 0xA9};
    inject(fx, NORMAL, normal, 3, 1 * TU_MS);
    inject(fx, INVERTED, inverted, 3, 2 * TU_MS);
    assert_int_equal(co_srdo_state(&c->srdo), CO_SRDO_RUNNING);
    assert_int_equal(tu_od_value(&c->od, A, 0, 2), 0x1234);
    assert_int_equal(tu_od_value(&c->od, A_INV, 0, 2), 0xEDCB);
    assert_int_equal(tu_od_value(&c->od, B, 0, 1), 0x56);
    assert_int_equal(tu_od_value(&c->od, B_INV, 0, 1), 0xA9);
    /* a pair that fails never reaches them */
    const uint8_t next[3] = {0x00, 0x00, 0x77}, bad[3] = {0xFF, 0xFF, 0x00};
    inject(fx, NORMAL, next, 3, 10 * TU_MS);
    inject(fx, INVERTED, bad, 3, 11 * TU_MS);
    assert_int_equal(co_srdo_state(&c->srdo), CO_SRDO_SAFE);
    assert_int_equal(c->why[0], CO_SRDO_INVERTED_MISMATCH);
    assert_int_equal(tu_od_value(&c->od, A, 0, 2), 0x1234);
    assert_int_equal(tu_od_value(&c->od, B, 0, 1), 0x56);
}

static void test_start_checks_valid_flag_crc_and_mapping(void **state)
{
    fx_t *fx = *state;
    dev_t *c = &fx->c;
    co_srdo_config_t cfg = config(CO_SRDO_CONSUME);
    tool_writes(c, &cfg, CO_SRDO_CONFIG_VALID, (uint16_t)(co_srdo_crc(&cfg) ^ 1u));
    set_state(fx, c, CO_NMT_OPERATIONAL);
    assert_int_equal(c->why[0], CO_SRDO_CRC_MISMATCH);
    set_state(fx, c, CO_NMT_PRE_OPERATIONAL);
    /* a write after validation clears 0x13FE: the next start refuses it */
    configure_valid(c, CO_SRDO_CONSUME);
    assert_int_equal(tu_od_net_write(&c->od, COMM, 3, 9, 1), 0);
    set_state(fx, c, CO_NMT_OPERATIONAL);
    assert_int_equal(c->why[1], CO_SRDO_CONFIG_INVALID);
    set_state(fx, c, CO_NMT_PRE_OPERATIONAL);
    /* a mapped object the OD does not have: the CRC holds, the mapping not */
    cfg.map[2] = 0x60040008u;
    tool_writes(c, &cfg, CO_SRDO_CONFIG_VALID, co_srdo_crc(&cfg));
    set_state(fx, c, CO_NMT_OPERATIONAL);
    assert_int_equal(c->why[2], CO_SRDO_BAD_PARAMETER);
    assert_int_equal(c->events, 3);
}

/* --------------------------------------------------- data of the producer */

static void test_producer_sends_the_mapped_variables(void **state)
{
    fx_t *fx = *state;
    dev_t *p = &fx->p;
    configure_valid(p, CO_SRDO_PRODUCE);
    produce_from(fx, p, 0xBEEF, 0x01);
    const uint8_t normal[3] = {0xEF, 0xBE, 0x01}, inverted[3] = {0x10, 0x41, 0xFE};
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, NORMAL, 0), NORMAL, normal, 3);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, INVERTED, 0), INVERTED, inverted, 3);
    /* set_data writes both halves at once: the next pair carries them */
    const uint8_t data[3] = {0x11, 0x22, 0x33}, data_inv[3] = {0xEE, 0xDD, 0xCC};
    assert_true(co_srdo_set_data(&p->srdo, data, 3));
    assert_int_equal(tu_od_value(&p->od, A, 0, 2), 0x2211);
    assert_int_equal(tu_od_value(&p->od, B_INV, 0, 1), 0xCC);
    tu_run_until(&fx->tb, 20 * TU_MS);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, NORMAL, 1), NORMAL, data, 3);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, INVERTED, 1), INVERTED, data_inv, 3);
    /* two variables that disagree: the producer goes safe and sends nothing */
    put(p, B_INV, 0x00, 1);
    tu_run_until(&fx->tb, 60 * TU_MS);
    assert_int_equal(tu_log_count_id(&fx->tb, NORMAL), 2);
    assert_int_equal(p->events, 1);
    assert_int_equal(p->why[0], CO_SRDO_INVERTED_MISMATCH);
}

/* A reset communication as co_node runs it: initialising, the new node-id,
 * the communication defaults reloaded, pre-operational. */
static void reset_with_node_id(fx_t *fx, dev_t *d, uint8_t node_id)
{
    set_state(fx, d, CO_NMT_INITIALISING);
    co_od_set_node_id(&d->od, node_id);
    co_od_load_defaults(&d->od, CO_GROUP_COMMUNICATION);
    set_state(fx, d, CO_NMT_PRE_OPERATIONAL);
}

/* SRDO 1's default COB-IDs (CiA 304): 0x0FF / 0x100 in the OD stand for
 * 0x0FF + 2 x node-id / 0x100 + 2 x node-id, resolved as the OD loads (so
 * reads, the CRC and the frames use them) and again for another node-id at
 * a reset's reload; node-ids above 64 have none. */
static void test_default_cob_ids_follow_the_node_id(void **state)
{
    fx_t *fx = *state;
    dev_t *p = &fx->p;
    co_line_t *line = p->srdo.line;
    co_srdo_od_detach(&p->guard);
    co_srdo_deinit(&p->srdo);
    co_gfc_deinit(&p->gfc);
    dev_init_with(p, line, 0x0FF, 5);
    assert_int_equal(tu_od_value(&p->od, COMM, 5, 4), 0x109);   /* 0x0FF + 2 x 5 */
    assert_int_equal(tu_od_value(&p->od, COMM, 6, 4), 0x10A);
    /* a tool configures everything but the COB-IDs, signing the CAN-IDs used */
    co_srdo_config_t c = config(CO_SRDO_PRODUCE);
    c.cob_id_normal = 0x109;
    c.cob_id_inverted = 0x10A;
    tool_writes_cob_ids(p, &c, CO_SRDO_CONFIG_VALID, co_srdo_crc(&c), false);
    produce_from(fx, p, 0x0102, 0x03);
    assert_int_equal(co_srdo_state(&p->srdo), CO_SRDO_RUNNING);
    const uint8_t normal[3] = {0x02, 0x01, 0x03}, inverted[3] = {0xFD, 0xFE, 0xFC};
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, 0x109, 0), 0x109, normal, 3);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, 0x10A, 0), 0x10A, inverted, 3);
    /* a reset with node-id 6: the defaults reload and resolve to 0x10B / 0x10C */
    reset_with_node_id(fx, p, 6);
    assert_int_equal(tu_od_value(&p->od, COMM, 5, 4), 0x10B);
    assert_int_equal(tu_od_value(&p->od, COMM, 6, 4), 0x10C);
    assert_int_equal(p->srdo.config.cob_id_normal, 0x10B);
    reset_with_node_id(fx, p, 65);              /* beyond 0x180: no default */
    assert_int_equal(tu_od_value(&p->od, COMM, 5, 4), 0x0FF);
    assert_int_equal(tu_od_value(&p->od, COMM, 6, 4), 0x100);
    reset_with_node_id(fx, p, 64);              /* the last one: 0x17F / 0x180 */
    assert_int_equal(p->srdo.config.cob_id_inverted, 0x180);
    assert_int_equal(tu_od_value(&p->od, COMM, 5, 4), 0x17F);
    assert_int_equal(tu_od_value(&p->od, COMM, 6, 4), 0x180);
    /* a written CAN-ID is the tool's: kept as written */
    assert_int_equal(tu_od_net_write(&p->od, COMM, 5, 0x111, 4), 0);
    assert_int_equal(tu_od_net_write(&p->od, COMM, 6, 0x112, 4), 0);
    co_srdo_od_set_nmt_state(&p->guard, CO_NMT_OPERATIONAL);
    assert_int_equal(tu_od_value(&p->od, COMM, 5, 4), 0x111);
    assert_int_equal(p->srdo.config.cob_id_normal, 0x111);
}

/* The producer's pairs, through both devices' OD: p's variables reach c's. */
static void test_variables_travel_from_producer_to_consumer(void **state)
{
    fx_t *fx = *state;
    configure_valid(&fx->p, CO_SRDO_PRODUCE);
    configure_valid(&fx->c, CO_SRDO_CONSUME);
    const uint8_t data[3] = {0xCD, 0xAB, 0x42};
    set_state(fx, &fx->c, CO_NMT_OPERATIONAL);
    set_state(fx, &fx->p, CO_NMT_OPERATIONAL);
    assert_true(co_srdo_set_data(&fx->p.srdo, data, 3));
    tu_run_until(&fx->tb, 100 * TU_MS);
    assert_int_equal(fx->c.events, 0);
    assert_int_equal(co_srdo_state(&fx->c.srdo), CO_SRDO_RUNNING);
    assert_int_equal(tu_od_value(&fx->c.od, A, 0, 2), 0xABCD);
    assert_int_equal(tu_od_value(&fx->c.od, A_INV, 0, 2), 0x5432);
    assert_int_equal(tu_od_value(&fx->c.od, B, 0, 1), 0x42);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
#define T(name) cmocka_unit_test_setup_teardown(name, setup, teardown)
        T(test_writes_refused_while_operational),
        T(test_accepted_write_clears_valid),
        T(test_out_of_range_and_out_of_order_refused),
        T(test_gfc_parameter_switches_the_gfc),
        T(test_start_runs_what_the_od_holds),
        T(test_start_checks_valid_flag_crc_and_mapping),
        T(test_producer_sends_the_mapped_variables),
        T(test_variables_travel_from_producer_to_consumer),
        T(test_default_cob_ids_follow_the_node_id),
#undef T
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
