/* Bus redundancy composed by co_stack: nodes built from co_stack alone on
 * two simulated buses, each line moved between them by its select
 * callback as a driver would. The slave runs from the redundancy record of
 * its OD (SDO reads and writes with the bytes on the bus, Ctoggle and
 * Bdefault kept by the core), follows the master's heartbeat without the
 * application forwarding anything, and a master with switch_on_failure
 * leaves a bus that reports bus-off. */
#include "test_od_util.h"

#include "canopenfd/co_stack.h"

#include <stdlib.h>

enum { MASTER = 1, SLAVE = 2, RECORD = 0x2100, PERIOD_MS = 100 };

typedef struct device {
    co_od_t od;
    co_od_entry_t entries[32];
    uint8_t pool[512];
    co_od_subscription_t subs[CO_STACK_OD_SUBSCRIPTIONS + 1];
} device_t;

typedef struct rig rig_t;

/* One node: its line, stack and arena, and the bus it is on now. */
typedef struct member {
    rig_t *rig;
    tu_line_t line;
    co_stack_t stack;
    co_stack_arena_t arena;
    unsigned char memory[48 * 1024];
    uint8_t bus;
    unsigned switches;
    unsigned no_master;
} member_t;

struct rig {
    tu_bus_t bus[2];                 /* A and B, each with its sniffer */
    tu_line_t tool[2];               /* a raw SDO client on each bus */
    member_t master;
    member_t slave;
    device_t dev;
};

/* ------------------------------------------------------------ the driver */

static void bus_remove(tu_bus_t *tb, tu_line_t *l)
{
    uint8_t kept = 0;
    for (uint8_t i = 0; i < tb->count; i++) {
        if (tb->lines[i] != l) {
            tb->lines[kept++] = tb->lines[i];
        }
    }
    tb->count = kept;
    co_membus_detach(&tb->bus, &l->line);
}

/* co_rdn's select: the line leaves its bus and joins the other. */
static void on_select(co_rdn_t *rdn, uint8_t bus, void *user)
{
    (void)rdn;
    member_t *m = user;
    if (bus == m->bus) {
        return;
    }
    tu_bus_t *to = &m->rig->bus[bus];
    bus_remove(&m->rig->bus[m->bus], &m->line);
    assert_true(co_membus_attach(&to->bus, &m->line.line));
    assert_true(to->count < TU_MAX_LINES);
    to->lines[to->count++] = &m->line;
    m->bus = bus;
}

static void on_event(co_rdn_t *rdn, co_rdn_event_t event, uint8_t bus, void *user)
{
    (void)rdn;
    (void)bus;
    member_t *m = user;
    if (event == CO_RDN_EV_BUS_SWITCH) {
        m->switches++;
    } else {
        m->no_master++;
    }
}

/* Both buses on one clock, every timer at its deadline. */
static void run_until(rig_t *r, uint64_t until_ms)
{
    uint64_t until = until_ms * TU_MS;
    for (long guard = 0; guard < 1000000; guard++) {
        uint64_t a = tu_next_deadline(&r->bus[0]), b = tu_next_deadline(&r->bus[1]);
        uint64_t d = a < b ? a : b;
        if (d > until) {
            break;
        }
        uint64_t now = d > r->bus[0].now ? d : r->bus[0].now;
        tu_step(&r->bus[0], now);
        tu_step(&r->bus[1], now);
    }
    tu_step(&r->bus[0], until);
    tu_step(&r->bus[1], until);
}

/* ------------------------------------------------------------ set-up */

/* The slave's dictionary: heartbeat 0x1017 and the redundancy record at
 * RECORD with Bdefault `bdefault`, Ttoggle 3, Ntoggle `ntoggle`. */
static void slave_od(device_t *d, uint8_t bdefault, uint8_t ntoggle)
{
    const tu_od_row_t rows[] = {
        {0x1000, 0, VAR, U32, RO, 0, 4, 0, NULL, 0, 0},
        {0x1001, 0, VAR, U8, RO, 0, 1, 0, NULL, 0, 0},
        {0x1017, 0, VAR, U16, RW, 0, 2, PERIOD_MS, NULL, 0, 0},
        {0x1018, 0, REC, U8, RO, 0, 1, 1, NULL, 0, 0},
        {0x1018, 1, REC, U32, RO, 0, 4, 0x1234, NULL, 0, 0},
        {RECORD, 0, REC, U8, RO, 0, 1, 4, NULL, 0, 0},
        {RECORD, 1, REC, U8, RW, 0, 1, bdefault, NULL, 0, 0},
        {RECORD, 2, REC, U8, RW, 0, 1, 3, NULL, 0, 0},
        {RECORD, 3, REC, U8, RW, 0, 1, ntoggle, NULL, 0, 0},
        {RECORD, 4, REC, U8, RO, 0, 1, 0, NULL, 0, 0},
    };
    memset(d, 0, sizeof *d);
    co_od_init(&d->od, CO_MODE_CLASSIC, d->entries, 32, d->pool, sizeof d->pool, d->subs,
               CO_STACK_OD_SUBSCRIPTIONS + 1);
    tu_od_add_rows(&d->od, rows, sizeof rows / sizeof rows[0]);
    assert_true(co_od_seal(&d->od, SLAVE));
}

static void member_node(rig_t *r, member_t *m, uint8_t node_id, co_od_t *od)
{
    m->rig = r;
    tu_bus_add_line(&r->bus[0], &m->line);
    co_stack_arena_init(&m->arena, m->memory, sizeof m->memory);
    co_stack_line_config_t lc = {.heartbeat_entries = 4};
    assert_int_equal(co_stack_init(&m->stack, &m->line.line, &lc,
                                   co_stack_arena_allocator(&m->arena)), CO_STACK_OK);
    co_stack_node_config_t nc = {.node_id = node_id, .heartbeat_ms = PERIOD_MS, .od = od};
    assert_int_equal(co_stack_node_init(&m->stack, &nc), CO_STACK_OK);
}

static co_stack_redundancy_config_t rdn_config(member_t *m, co_rdn_role_t role)
{
    co_stack_redundancy_config_t c = {
        .rdn = {.role = role, .master_id = MASTER, .master_period_ms = PERIOD_MS,
                .bdefault = CO_RDN_BUS_A, .ttoggle = 2, .ntoggle = 3},
        .index = RECORD, .select = on_select, .on_event = on_event, .user = m};
    return c;
}

static rig_t *rig_new(uint8_t slave_bdefault, uint8_t slave_ntoggle)
{
    rig_t *r = calloc(1, sizeof *r);
    assert_non_null(r);
    tu_bus_init(&r->bus[0], CO_MODE_CLASSIC, false);
    tu_bus_init(&r->bus[1], CO_MODE_CLASSIC, false);
    tu_bus_add_line(&r->bus[0], &r->tool[0]);
    tu_bus_add_line(&r->bus[1], &r->tool[1]);
    slave_od(&r->dev, slave_bdefault, slave_ntoggle);
    member_node(r, &r->master, MASTER, NULL);
    member_node(r, &r->slave, SLAVE, &r->dev.od);
    return r;
}

static void rig_free(rig_t *r)
{
    co_stack_deinit(&r->slave.stack);
    co_stack_deinit(&r->master.stack);
    free(r);
}

/* The tool on `bus` sends an SDO request to the slave; the answer on that
 * bus must be `answer`. */
static void sdo_exchange(rig_t *r, uint8_t bus, const uint8_t request[8], const uint8_t answer[8])
{
    tu_bus_t *tb = &r->bus[bus];
    tu_log_clear(tb);
    co_line_set_time(&r->tool[bus].line, tb->now);
    assert_true(co_line_send(&r->tool[bus].line, 0x600 + SLAVE, request, 8));
    run_until(r, tb->now / TU_MS + 2);
    tu_assert_logged(tb, tu_log_find_id(tb, 0x580 + SLAVE, 0), 0x580 + SLAVE, answer, 8);
}

static void sdo_read_u8(rig_t *r, uint8_t bus, uint8_t sub, uint8_t value)
{
    const uint8_t request[8] = {0x40, RECORD & 0xFF, RECORD >> 8, sub, 0, 0, 0, 0};
    const uint8_t answer[8] = {0x4F, RECORD & 0xFF, RECORD >> 8, sub, value, 0, 0, 0};
    sdo_exchange(r, bus, request, answer);
}

/* An expedited one-byte download, answered 0x60 (abort 0) or aborted. */
static void sdo_write_u8(rig_t *r, uint8_t bus, uint8_t sub, uint8_t value, uint32_t abort)
{
    const uint8_t request[8] = {0x2F, RECORD & 0xFF, RECORD >> 8, sub, value, 0, 0, 0};
    uint8_t answer[8] = {abort ? 0x80 : 0x60, RECORD & 0xFF, RECORD >> 8, sub,
                         (uint8_t)abort, (uint8_t)(abort >> 8), (uint8_t)(abort >> 16),
                         (uint8_t)(abort >> 24)};
    sdo_exchange(r, bus, request, answer);
}

static size_t heartbeats_of(const tu_bus_t *tb, uint8_t node_id)
{
    return tu_log_count_id(tb, 0x700 + node_id);
}

/* ------------------------------------------------------------ tests */

/* The record's values win over the config's; SDO reads them, writes are
 * checked with the service's rules (clear aborts, nothing changed). */
static void test_slave_record_served_and_checked(void **state)
{
    (void)state;
    rig_t *r = rig_new(CO_RDN_BUS_A, 2);
    co_stack_redundancy_config_t c = rdn_config(&r->slave, CO_RDN_SLAVE);
    c.rdn.bdefault = CO_RDN_BUS_B;   /* the OD says A */
    c.rdn.ttoggle = 0;               /* the OD says 3 */
    assert_int_equal(co_stack_redundancy_init(&r->slave.stack, &c), CO_STACK_OK);
    assert_int_equal(co_stack_boot(&r->slave.stack), CO_STACK_OK);
    co_rdn_t *rdn = co_stack_redundancy(&r->slave.stack);
    assert_non_null(rdn);
    assert_int_equal(co_rdn_read(rdn, CO_RDN_SUB_TTOGGLE), 3);
    assert_int_equal(r->slave.bus, CO_RDN_BUS_A);
    run_until(r, 10);

    sdo_read_u8(r, CO_RDN_BUS_A, 0, 4);
    sdo_read_u8(r, CO_RDN_BUS_A, CO_RDN_SUB_BDEFAULT, 0);
    sdo_read_u8(r, CO_RDN_BUS_A, CO_RDN_SUB_TTOGGLE, 3);
    sdo_read_u8(r, CO_RDN_BUS_A, CO_RDN_SUB_NTOGGLE, 2);
    sdo_read_u8(r, CO_RDN_BUS_A, CO_RDN_SUB_CTOGGLE, 0);
    sdo_write_u8(r, CO_RDN_BUS_A, CO_RDN_SUB_BDEFAULT, 2, CO_ABORT_VALUE_HIGH);
    sdo_write_u8(r, CO_RDN_BUS_A, CO_RDN_SUB_NTOGGLE, 0, CO_ABORT_VALUE_LOW);
    sdo_write_u8(r, CO_RDN_BUS_A, CO_RDN_SUB_CTOGGLE, 1, CO_ABORT_READ_ONLY);
    assert_int_equal(co_rdn_read(rdn, CO_RDN_SUB_BDEFAULT), 0);
    assert_int_equal(co_rdn_read(rdn, CO_RDN_SUB_NTOGGLE), 2);
    sdo_read_u8(r, CO_RDN_BUS_A, CO_RDN_SUB_NTOGGLE, 2);
    /* an accepted write reaches the service */
    sdo_write_u8(r, CO_RDN_BUS_A, CO_RDN_SUB_NTOGGLE, 1, 0);
    assert_int_equal(co_rdn_read(rdn, CO_RDN_SUB_NTOGGLE), 1);
    sdo_write_u8(r, CO_RDN_BUS_A, CO_RDN_SUB_TTOGGLE, 0, 0);
    assert_int_equal(co_rdn_read(rdn, CO_RDN_SUB_TTOGGLE), 0);
    /* the application's own write of a bad value is taken back */
    const uint8_t bad = 7;
    assert_int_equal(co_od_put(&r->dev.od, RECORD, CO_RDN_SUB_BDEFAULT, &bad, 1), 0);
    assert_int_equal(tu_od_value(&r->dev.od, RECORD, CO_RDN_SUB_BDEFAULT, 1), 0);
    rig_free(r);
}

/* No master ever: the slave moves to B after Ttoggle periods (its
 * heartbeat goes from bus A to bus B), gives up after Ntoggle = 1 and the
 * record shows it (Ctoggle 1, Bdefault B) over SDO on B; a reset
 * communication starts it on B again with Ctoggle 0. */
static void test_slave_switch_shown_in_record(void **state)
{
    (void)state;
    rig_t *r = rig_new(CO_RDN_BUS_A, 1);
    co_stack_redundancy_config_t c = rdn_config(&r->slave, CO_RDN_SLAVE);
    assert_int_equal(co_stack_redundancy_init(&r->slave.stack, &c), CO_STACK_OK);
    assert_int_equal(co_stack_boot(&r->slave.stack), CO_STACK_OK);
    run_until(r, 299);
    assert_int_equal(r->slave.bus, CO_RDN_BUS_A);
    assert_true(heartbeats_of(&r->bus[0], SLAVE) >= 3);   /* boot-up and heartbeats */
    assert_int_equal(heartbeats_of(&r->bus[1], SLAVE), 0);
    run_until(r, 300);
    assert_int_equal(r->slave.bus, CO_RDN_BUS_B);
    assert_int_equal(r->slave.switches, 1);
    assert_int_equal(r->slave.no_master, 1);
    size_t on_a = heartbeats_of(&r->bus[0], SLAVE);
    run_until(r, 500);
    assert_int_equal(heartbeats_of(&r->bus[0], SLAVE), on_a);
    assert_true(heartbeats_of(&r->bus[1], SLAVE) >= 2);
    tu_assert_logged(&r->bus[1], tu_log_find_id(&r->bus[1], 0x700 + SLAVE, 0), 0x700 + SLAVE,
                     (const uint8_t[]){0x7F}, 1);

    sdo_read_u8(r, CO_RDN_BUS_B, CO_RDN_SUB_CTOGGLE, 1);
    sdo_read_u8(r, CO_RDN_BUS_B, CO_RDN_SUB_BDEFAULT, 1);
    assert_int_equal(tu_od_value(&r->dev.od, RECORD, CO_RDN_SUB_CTOGGLE, 1), 1);
    /* NMT reset communication from the tool on B */
    co_line_set_time(&r->tool[1].line, r->bus[1].now);
    assert_true(co_line_send(&r->tool[1].line, 0x000, (const uint8_t[]){0x82, SLAVE}, 2));
    run_until(r, r->bus[1].now / TU_MS + 5);
    assert_int_equal(r->slave.bus, CO_RDN_BUS_B);
    assert_int_equal(tu_od_value(&r->dev.od, RECORD, CO_RDN_SUB_CTOGGLE, 1), 0);
    sdo_read_u8(r, CO_RDN_BUS_B, CO_RDN_SUB_CTOGGLE, 0);
    rig_free(r);
}

/* The slave follows the master with nothing forwarded by the application:
 * the master's bus-off moves it to B (switch_on_failure), its heartbeat
 * leaves bus A, and the slave, missing it, follows Ttoggle periods after
 * the last one it heard. */
static void test_master_leaves_bus_off_and_slave_follows(void **state)
{
    (void)state;
    rig_t *r = rig_new(CO_RDN_BUS_A, 3);
    co_stack_redundancy_config_t mc = rdn_config(&r->master, CO_RDN_MASTER);
    mc.switch_on_failure = true;
    assert_int_equal(co_stack_redundancy_init(&r->master.stack, &mc), CO_STACK_OK);
    co_stack_redundancy_config_t sc = rdn_config(&r->slave, CO_RDN_SLAVE);
    assert_int_equal(co_stack_redundancy_init(&r->slave.stack, &sc), CO_STACK_OK);
    assert_int_equal(co_stack_boot(&r->master.stack), CO_STACK_OK);
    assert_int_equal(co_stack_boot(&r->slave.stack), CO_STACK_OK);
    run_until(r, 1000);   /* heard all along: no switch although Ttoggle is 300 ms */
    assert_int_equal(r->slave.bus, CO_RDN_BUS_A);
    assert_int_equal(r->slave.switches, 0);

    co_line_comm_event(&r->master.line.line, CO_COMM_BUS_OFF);
    assert_int_equal(r->master.bus, CO_RDN_BUS_B);
    assert_int_equal(r->master.switches, 1);
    size_t master_on_a = heartbeats_of(&r->bus[0], MASTER);
    run_until(r, 1150);
    assert_int_equal(heartbeats_of(&r->bus[0], MASTER), master_on_a);
    assert_true(heartbeats_of(&r->bus[1], MASTER) >= 1);
    /* last heard at 1000: the slave moves at 1300 (Ttoggle 3), not before */
    run_until(r, 1299);
    assert_int_equal(r->slave.bus, CO_RDN_BUS_A);
    run_until(r, 1300);
    assert_int_equal(r->slave.bus, CO_RDN_BUS_B);
    run_until(r, 2000);
    assert_int_equal(r->slave.switches, 1);
    assert_int_equal(r->slave.no_master, 0);
    sdo_read_u8(r, CO_RDN_BUS_B, CO_RDN_SUB_CTOGGLE, 0);   /* heard again on B */

    /* interface down on B moves it back to A; other comm events do not move it */
    co_line_comm_event(&r->master.line.line, CO_COMM_IFACE_DOWN);
    assert_int_equal(r->master.bus, CO_RDN_BUS_A);
    co_line_comm_event(&r->master.line.line, CO_COMM_ERROR_PASSIVE);
    assert_int_equal(r->master.bus, CO_RDN_BUS_A);
    rig_free(r);
}

/* Without switch_on_failure the master stays where it is on bus-off. */
static void test_master_without_switch_on_failure_stays(void **state)
{
    (void)state;
    rig_t *r = rig_new(CO_RDN_BUS_A, 3);
    co_stack_redundancy_config_t mc = rdn_config(&r->master, CO_RDN_MASTER);
    assert_int_equal(co_stack_redundancy_init(&r->master.stack, &mc), CO_STACK_OK);
    co_line_comm_event(&r->master.line.line, CO_COMM_BUS_OFF);
    assert_int_equal(r->master.bus, CO_RDN_BUS_A);
    assert_int_equal(r->master.switches, 0);
    rig_free(r);
}

/* Redundancy started on a line whose node comes later: the node's record
 * is served and its values taken from then on, and its resets start the
 * service over; the node going leaves it running on its values. */
static void test_node_set_up_after_the_service(void **state)
{
    (void)state;
    rig_t *r = rig_new(CO_RDN_BUS_A, 2);
    co_stack_node_deinit(&r->slave.stack);
    co_stack_redundancy_config_t c = rdn_config(&r->slave, CO_RDN_SLAVE);
    c.rdn.ttoggle = 0;
    assert_int_equal(co_stack_redundancy_init(&r->slave.stack, &c), CO_STACK_OK);
    co_rdn_t *rdn = co_stack_redundancy(&r->slave.stack);
    assert_int_equal(co_rdn_read(rdn, CO_RDN_SUB_TTOGGLE), 0);
    co_stack_node_config_t nc = {.node_id = SLAVE, .heartbeat_ms = PERIOD_MS, .od = &r->dev.od};
    assert_int_equal(co_stack_node_init(&r->slave.stack, &nc), CO_STACK_OK);
    assert_int_equal(co_rdn_read(rdn, CO_RDN_SUB_TTOGGLE), 3);
    assert_int_equal(co_rdn_read(rdn, CO_RDN_SUB_NTOGGLE), 2);
    assert_int_equal(co_stack_boot(&r->slave.stack), CO_STACK_OK);
    run_until(r, 10);
    sdo_write_u8(r, CO_RDN_BUS_A, CO_RDN_SUB_BDEFAULT, 2, CO_ABORT_VALUE_HIGH);
    sdo_write_u8(r, CO_RDN_BUS_A, CO_RDN_SUB_NTOGGLE, 1, 0);
    run_until(r, 310);   /* no master: B at 300, and Ntoggle 1 gives up there */
    assert_int_equal(r->slave.bus, CO_RDN_BUS_B);
    assert_int_equal(r->slave.no_master, 1);
    sdo_read_u8(r, CO_RDN_BUS_B, CO_RDN_SUB_BDEFAULT, 1);
    /* a reset node reloads the record's defaults: back to A */
    co_line_set_time(&r->tool[1].line, r->bus[1].now);
    assert_true(co_line_send(&r->tool[1].line, 0x000, (const uint8_t[]){0x81, SLAVE}, 2));
    run_until(r, r->bus[1].now / TU_MS + 5);
    assert_int_equal(r->slave.bus, CO_RDN_BUS_A);
    assert_int_equal(co_rdn_read(rdn, CO_RDN_SUB_NTOGGLE), 2);
    assert_int_equal(tu_od_value(&r->dev.od, RECORD, CO_RDN_SUB_CTOGGLE, 1), 0);
    assert_int_equal(tu_od_value(&r->dev.od, RECORD, CO_RDN_SUB_BDEFAULT, 1), 0);
    co_stack_node_deinit(&r->slave.stack);
    assert_non_null(co_stack_redundancy(&r->slave.stack));
    run_until(r, r->bus[0].now / TU_MS + 300);   /* still counting: B again */
    assert_int_equal(r->slave.bus, CO_RDN_BUS_B);
    rig_free(r);
}

/* Wrong use is refused and leaves nothing behind. */
static void test_refusals(void **state)
{
    (void)state;
    rig_t *r = rig_new(CO_RDN_BUS_A, 3);
    co_stack_redundancy_config_t c = rdn_config(&r->slave, CO_RDN_SLAVE);
    c.switch_on_failure = true;   /* a slave never decides */
    assert_int_equal(co_stack_redundancy_init(&r->slave.stack, &c), CO_STACK_ERR_ARGUMENT);
    c = rdn_config(&r->slave, CO_RDN_SLAVE);
    c.select = NULL;
    assert_int_equal(co_stack_redundancy_init(&r->slave.stack, &c), CO_STACK_ERR_ARGUMENT);
    /* a record with Bdefault 5: the OD is refused, sub 1 named */
    const uint8_t five = 5;
    assert_int_equal(co_od_put(&r->dev.od, RECORD, CO_RDN_SUB_BDEFAULT, &five, 1), 0);
    uint8_t bad_sub = 0;
    assert_int_equal(co_stack_redundancy_check_od(&r->dev.od, RECORD, &bad_sub), CO_RDN_BAD_BUS);
    assert_int_equal(bad_sub, CO_RDN_SUB_BDEFAULT);
    c = rdn_config(&r->slave, CO_RDN_SLAVE);
    assert_int_equal(co_stack_redundancy_init(&r->slave.stack, &c), CO_STACK_ERR_OD);
    assert_int_equal(co_stack_failed_part(&r->slave.stack), CO_STACK_PART_REDUNDANCY);
    assert_string_equal(co_stack_part_name(CO_STACK_PART_REDUNDANCY), "bus redundancy");
    assert_null(co_stack_redundancy(&r->slave.stack));
    assert_int_equal(co_stack_redundancy_record_index(&r->slave.stack), 0);
    /* an index the OD does not have: the config's values, nothing served; the
     * index is named so a later add of that record can be refused */
    c.index = 0x2200;
    assert_int_equal(co_stack_redundancy_init(&r->slave.stack, &c), CO_STACK_OK);
    assert_int_equal(co_stack_redundancy_record_index(&r->slave.stack), 0x2200);
    assert_int_equal(co_rdn_read(co_stack_redundancy(&r->slave.stack), CO_RDN_SUB_TTOGGLE), 2);
    assert_int_equal(co_stack_redundancy_init(&r->slave.stack, &c), CO_STACK_ERR_STATE);
    co_stack_redundancy_deinit(&r->slave.stack);
    assert_null(co_stack_redundancy(&r->slave.stack));
    assert_int_equal(co_stack_redundancy_record_index(&r->slave.stack), 0);
    /* a record of another type (0x1018:01 is UNSIGNED32) */
    assert_int_equal(co_stack_redundancy_check_od(&r->dev.od, 0x1018, &bad_sub),
                     CO_RDN_BAD_TYPE);
    assert_int_equal(bad_sub, 1);
    rig_free(r);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_slave_record_served_and_checked),
        cmocka_unit_test(test_slave_switch_shown_in_record),
        cmocka_unit_test(test_master_leaves_bus_off_and_slave_follows),
        cmocka_unit_test(test_master_without_switch_on_failure_stays),
        cmocka_unit_test(test_node_set_up_after_the_service),
        cmocka_unit_test(test_refusals),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
