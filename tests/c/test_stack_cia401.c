/* CiA 401 generic I/O bound to a node's OD by co_stack (co_cia401_od): a
 * node built from co_stack alone on the simulated bus, a raw tool line
 * sending NMT, SDO and RPDO frames. Checked on the wire: the TPDO bytes
 * after the application's inputs (once per change that passes the masks,
 * none outside operational), parameters written by SDO taking effect, the
 * output indication after SDO and RPDO writes, the error values on NMT
 * stop, the inputs kept over a reset node; and an OD the part refuses. */
#include "test_od_util.h"

#include "canopenfd/co_stack.h"

#include <stdlib.h>

enum { NODE = 5, TPDO1 = 0x180 + NODE, TPDO2 = 0x280 + NODE, RPDO1 = 0x200 + NODE,
       RPDO2 = 0x300 + NODE, SDO_RX = 0x600 + NODE, SDO_TX = 0x580 + NODE };

#define I16 CO_TYPE_INTEGER16
#define I32 CO_TYPE_INTEGER32
#define BOOL CO_TYPE_BOOLEAN
#define TX CO_OD_MAP_TPDO
#define RX CO_OD_MAP_RPDO

typedef struct rig {
    tu_bus_t bus;
    tu_line_t tool;
    tu_line_t dev_line;
    co_stack_t stack;
    co_stack_arena_t arena;
    unsigned char memory[64 * 1024];
    co_od_t od;
    co_od_entry_t entries[96];
    uint8_t pool[1024];
    co_od_subscription_t subs[CO_STACK_OD_SUBSCRIPTIONS];
    /* what the output indication told */
    unsigned told;
    uint8_t kinds;
    uint8_t digital;
    int32_t analog[2];
} rig_t;

/* Two input groups (TPDO1), one output group (RPDO1), one analogue input
 * (TPDO2), two analogue outputs (RPDO2). 0x6003, 0x6007, 0x6008 and the
 * analogue limits are left out: their defaults apply. */
static const tu_od_row_t device_rows[] = {
    {0x1000, 0, VAR, U32, RO, 0, 4, 0x000F0191, NULL, 0, 0},
    {0x1001, 0, VAR, U8, RO, 0, 1, 0, NULL, 0, 0},
    {0x1017, 0, VAR, U16, RW, 0, 2, 0, NULL, 0, 0},
    {0x1400, 0, REC, U8, RO, 0, 1, 2, NULL, 0, 0},
    {0x1400, 1, REC, U32, RW, 0, 4, RPDO1, NULL, 0, 0},
    {0x1400, 2, REC, U8, RW, 0, 1, 255, NULL, 0, 0},
    {0x1401, 0, REC, U8, RO, 0, 1, 2, NULL, 0, 0},
    {0x1401, 1, REC, U32, RW, 0, 4, RPDO2, NULL, 0, 0},
    {0x1401, 2, REC, U8, RW, 0, 1, 255, NULL, 0, 0},
    {0x1600, 0, ARR, U8, RW, 0, 1, 1, NULL, 0, 0},
    {0x1600, 1, ARR, U32, RW, 0, 4, 0x62000108, NULL, 0, 0},
    {0x1601, 0, ARR, U8, RW, 0, 1, 2, NULL, 0, 0},
    {0x1601, 1, ARR, U32, RW, 0, 4, 0x64110110, NULL, 0, 0},
    {0x1601, 2, ARR, U32, RW, 0, 4, 0x64110210, NULL, 0, 0},
    {0x1800, 0, REC, U8, RO, 0, 1, 2, NULL, 0, 0},
    {0x1800, 1, REC, U32, RW, 0, 4, TPDO1, NULL, 0, 0},
    {0x1800, 2, REC, U8, RW, 0, 1, 255, NULL, 0, 0},
    {0x1801, 0, REC, U8, RO, 0, 1, 2, NULL, 0, 0},
    {0x1801, 1, REC, U32, RW, 0, 4, TPDO2, NULL, 0, 0},
    {0x1801, 2, REC, U8, RW, 0, 1, 255, NULL, 0, 0},
    {0x1A00, 0, ARR, U8, RW, 0, 1, 2, NULL, 0, 0},
    {0x1A00, 1, ARR, U32, RW, 0, 4, 0x60000108, NULL, 0, 0},
    {0x1A00, 2, ARR, U32, RW, 0, 4, 0x60000208, NULL, 0, 0},
    {0x1A01, 0, ARR, U8, RW, 0, 1, 1, NULL, 0, 0},
    {0x1A01, 1, ARR, U32, RW, 0, 4, 0x64010110, NULL, 0, 0},
    {0x6000, 0, ARR, U8, RO, 0, 1, 2, NULL, 0, 0},
    {0x6000, 1, ARR, U8, RO, TX, 1, 0, NULL, 0, 0},
    {0x6000, 2, ARR, U8, RO, TX, 1, 0, NULL, 0, 0},
    {0x6002, 0, ARR, U8, RO, 0, 1, 2, NULL, 0, 0},
    {0x6002, 1, ARR, U8, RW, 0, 1, 0, NULL, 0, 0},
    {0x6002, 2, ARR, U8, RW, 0, 1, 0, NULL, 0, 0},
    {0x6005, 0, VAR, BOOL, RW, 0, 1, 1, NULL, 0, 0},
    {0x6006, 0, ARR, U8, RO, 0, 1, 2, NULL, 0, 0},
    {0x6006, 1, ARR, U8, RW, 0, 1, 0xFF, NULL, 0, 0},
    {0x6006, 2, ARR, U8, RW, 0, 1, 0xFF, NULL, 0, 0},
    {0x6200, 0, ARR, U8, RO, 0, 1, 1, NULL, 0, 0},
    {0x6200, 1, ARR, U8, RW, RX, 1, 0, NULL, 0, 0},
    {0x6202, 0, ARR, U8, RO, 0, 1, 1, NULL, 0, 0},
    {0x6202, 1, ARR, U8, RW, 0, 1, 0, NULL, 0, 0},
    {0x6206, 0, ARR, U8, RO, 0, 1, 1, NULL, 0, 0},
    {0x6206, 1, ARR, U8, RW, 0, 1, 0xFF, NULL, 0, 0},
    {0x6207, 0, ARR, U8, RO, 0, 1, 1, NULL, 0, 0},
    {0x6207, 1, ARR, U8, RW, 0, 1, 0, NULL, 0, 0},
    {0x6208, 0, ARR, U8, RO, 0, 1, 1, NULL, 0, 0},
    {0x6208, 1, ARR, U8, RW, 0, 1, 0xFF, NULL, 0, 0},
    {0x6401, 0, ARR, U8, RO, 0, 1, 1, NULL, 0, 0},
    {0x6401, 1, ARR, I16, RO, TX, 2, 0, NULL, 0, 0},
    {0x6411, 0, ARR, U8, RO, 0, 1, 2, NULL, 0, 0},
    {0x6411, 1, ARR, I16, RW, RX, 2, 0, NULL, 0, 0},
    {0x6411, 2, ARR, I16, RW, RX, 2, 0, NULL, 0, 0},
    {0x6421, 0, ARR, U8, RO, 0, 1, 1, NULL, 0, 0},
    {0x6421, 1, ARR, U8, RW, 0, 1, CO_CIA401_AI_DELTA, NULL, 0, 0},
    {0x6423, 0, VAR, BOOL, RW, 0, 1, 1, NULL, 0, 0},
    {0x6426, 0, ARR, U8, RO, 0, 1, 1, NULL, 0, 0},
    {0x6426, 1, ARR, U32, RW, 0, 4, 100, NULL, 0, 0},
    {0x6443, 0, ARR, U8, RO, 0, 1, 2, NULL, 0, 0},
    {0x6443, 1, ARR, U8, RW, 0, 1, 1, NULL, 0, 0},
    {0x6443, 2, ARR, U8, RW, 0, 1, 1, NULL, 0, 0},
    {0x6444, 0, ARR, U8, RO, 0, 1, 2, NULL, 0, 0},
    {0x6444, 1, ARR, I32, RW, 0, 4, 0, NULL, 0, 0},
    {0x6444, 2, ARR, I32, RW, 0, 4, 0, NULL, 0, 0},
};

static void on_outputs(co_cia401_od_t *io, uint8_t kinds, void *user)
{
    rig_t *r = user;
    r->told++;
    r->kinds = kinds;
    r->digital = co_cia401_od_digital_output(io, 1);
    r->analog[0] = co_cia401_od_analog_output(io, 1);
    r->analog[1] = co_cia401_od_analog_output(io, 2);
}

static void run_ms(rig_t *r, uint64_t ms)
{
    tu_run_until(&r->bus, r->bus.now + ms * TU_MS);
}

static void od_build(rig_t *r, const tu_od_row_t *rows, size_t n)
{
    co_od_init(&r->od, CO_MODE_CLASSIC, r->entries, 96, r->pool, sizeof r->pool, r->subs,
               CO_STACK_OD_SUBSCRIPTIONS);
    tu_od_add_rows(&r->od, rows, n);
    assert_true(co_od_seal(&r->od, NODE));
}

static void node_up(rig_t *r)
{
    tu_bus_init(&r->bus, CO_MODE_CLASSIC, false);
    tu_bus_add_line(&r->bus, &r->tool);
    tu_bus_add_line(&r->bus, &r->dev_line);
    co_stack_arena_init(&r->arena, r->memory, sizeof r->memory);
    co_stack_line_config_t lc = {.heartbeat_entries = 1};
    assert_int_equal(co_stack_init(&r->stack, &r->dev_line.line, &lc,
                                   co_stack_arena_allocator(&r->arena)), CO_STACK_OK);
    co_stack_node_config_t nc = {.node_id = NODE, .od = &r->od};
    assert_int_equal(co_stack_node_init(&r->stack, &nc), CO_STACK_OK);
}

/* The device node, its CiA 401 part running and booted (pre-operational). */
static rig_t *rig_new(void)
{
    rig_t *r = calloc(1, sizeof *r);
    assert_non_null(r);
    od_build(r, device_rows, sizeof device_rows / sizeof device_rows[0]);
    node_up(r);
    size_t before = r->arena.used;
    assert_int_equal(co_stack_cia401_init(&r->stack, on_outputs, r), CO_STACK_OK);
    assert_int_equal(r->arena.used - before, co_stack_cia401_need(&r->stack));
    assert_int_equal(co_stack_boot(&r->stack), CO_STACK_OK);
    run_ms(r, 5);
    return r;
}

static void rig_free(rig_t *r)
{
    co_stack_deinit(&r->stack);
    free(r);
}

static void tool_send(rig_t *r, uint32_t id, const uint8_t *data, size_t len)
{
    co_line_set_time(&r->tool.line, r->bus.now);
    assert_true(co_line_send(&r->tool.line, id, data, len));
    run_ms(r, 2);
}

static void nmt(rig_t *r, uint8_t command)
{
    const uint8_t frame[2] = {command, NODE};
    tool_send(r, 0x000, frame, 2);
}

/* An expedited download of `len` bytes, which must be answered 0x60. */
static void sdo_write(rig_t *r, uint16_t index, uint8_t sub, int64_t value, uint8_t len)
{
    uint8_t request[8] = {(uint8_t)(0x23 | (4 - len) << 2), (uint8_t)index,
                          (uint8_t)(index >> 8), sub, 0, 0, 0, 0};
    const uint8_t answer[8] = {0x60, (uint8_t)index, (uint8_t)(index >> 8), sub, 0, 0, 0, 0};
    tu_le_put(request + 4, (uint64_t)value, len);
    tu_log_clear(&r->bus);
    tool_send(r, SDO_RX, request, 8);
    tu_assert_logged(&r->bus, tu_log_find_id(&r->bus, SDO_TX, 0), SDO_TX, answer, 8);
}

static void set_inputs(rig_t *r, uint8_t g1, uint8_t g2)
{
    const uint8_t raw[2] = {g1, g2};
    assert_int_equal(co_cia401_od_set_inputs(co_stack_cia401(&r->stack), 1, raw, 2),
                     CO_CIA401_OD_OK);
    run_ms(r, 2);
}

/* ------------------------------------------------------------ tests */

/* Inputs: TPDO1 carries both groups once per change that passes the masks;
 * none before operational (0x6000 still takes the levels); the polarity
 * written by SDO applies to the next sample. */
static void test_inputs_send_tpdo1_bytes(void **state)
{
    (void)state;
    rig_t *r = rig_new();
    tu_log_clear(&r->bus);
    set_inputs(r, 0x01, 0x80);
    assert_int_equal(tu_log_count_id(&r->bus, TPDO1), 0);   /* pre-operational */
    assert_int_equal(tu_od_value(&r->od, 0x6000, 2, 1), 0x80);

    nmt(r, CO_NMT_CMD_START);
    tu_log_clear(&r->bus);
    set_inputs(r, 0x03, 0x80);
    const uint8_t first[2] = {0x03, 0x80};
    assert_int_equal(tu_log_count_id(&r->bus, TPDO1), 1);
    tu_assert_logged(&r->bus, tu_log_find_id(&r->bus, TPDO1, 0), TPDO1, first, 2);
    set_inputs(r, 0x03, 0x80);                               /* no change: nothing */
    assert_int_equal(tu_log_count_id(&r->bus, TPDO1), 1);

    /* both groups change at once: still one TPDO1 */
    set_inputs(r, 0x00, 0x00);
    assert_int_equal(tu_log_count_id(&r->bus, TPDO1), 2);

    sdo_write(r, 0x6002, 1, 0x0F, 1);                        /* inputs 1..4 inverted */
    tu_log_clear(&r->bus);
    set_inputs(r, 0x01, 0x00);
    const uint8_t inverted[2] = {0x0E, 0x00};
    tu_assert_logged(&r->bus, tu_log_find_id(&r->bus, TPDO1, 0), TPDO1, inverted, 2);

    sdo_write(r, 0x6005, 0, 0, 1);                           /* global enable off */
    tu_log_clear(&r->bus);
    set_inputs(r, 0x00, 0xFF);
    assert_int_equal(tu_log_count_id(&r->bus, TPDO1), 0);
    assert_int_equal(tu_od_value(&r->od, 0x6000, 2, 1), 0xFF);

    /* a group the device does not have is refused, nothing changes */
    const uint8_t raw[2] = {1, 1};
    assert_int_equal(co_cia401_od_set_inputs(co_stack_cia401(&r->stack), 2, raw, 2),
                     CO_CIA401_OD_BAD_CHANNEL);
    assert_int_equal(tu_od_value(&r->od, 0x6000, 2, 1), 0xFF);
    rig_free(r);
}

/* Analogue input: TPDO2 when it moved more than the delta 0x6426 (set by
 * SDO) since the last send. */
static void test_analog_delta_sends_tpdo2(void **state)
{
    (void)state;
    rig_t *r = rig_new();
    co_cia401_od_t *io = co_stack_cia401(&r->stack);
    nmt(r, CO_NMT_CMD_START);
    tu_log_clear(&r->bus);
    assert_int_equal(co_cia401_od_set_analog_input(io, 1, 50), CO_CIA401_OD_OK);
    run_ms(r, 2);
    assert_int_equal(tu_log_count_id(&r->bus, TPDO2), 0);    /* within 100 */
    assert_int_equal(co_cia401_od_set_analog_input(io, 1, -120), CO_CIA401_OD_OK);
    run_ms(r, 2);
    const uint8_t moved[2] = {0x88, 0xFF};                   /* -120: 120 from the start */
    assert_int_equal(tu_log_count_id(&r->bus, TPDO2), 1);
    tu_assert_logged(&r->bus, tu_log_find_id(&r->bus, TPDO2, 0), TPDO2, moved, 2);
    sdo_write(r, 0x6426, 1, 1000, 4);
    tu_log_clear(&r->bus);
    assert_int_equal(co_cia401_od_set_analog_input(io, 1, 500), CO_CIA401_OD_OK);
    run_ms(r, 2);
    assert_int_equal(tu_log_count_id(&r->bus, TPDO2), 0);
    assert_int_equal(co_cia401_od_set_analog_input(io, 2, 0), CO_CIA401_OD_BAD_CHANNEL);
    rig_free(r);
}

/* Outputs: an SDO write of 0x6200 with the polarity 0x6202 written first,
 * then RPDO1 with the filter mask 0x6208 set by SDO, then RPDO2: one
 * indication each, with the physical levels. */
static void test_outputs_follow_sdo_and_rpdo(void **state)
{
    (void)state;
    rig_t *r = rig_new();
    nmt(r, CO_NMT_CMD_START);
    sdo_write(r, 0x6202, 1, 0x01, 1);
    assert_int_equal(r->told, 0);
    sdo_write(r, 0x6200, 1, 0x0F, 1);
    assert_int_equal(r->told, 1);
    assert_int_equal(r->kinds, CO_CIA401_OUT_DIGITAL);
    assert_int_equal(r->digital, 0x0E);

    sdo_write(r, 0x6208, 1, 0xF0, 1);                        /* only outputs 5..8 follow */
    const uint8_t rpdo1[1] = {0x33};
    tool_send(r, RPDO1, rpdo1, 1);
    assert_int_equal(r->told, 2);
    assert_int_equal(r->digital, 0x3E);

    const uint8_t rpdo2[4] = {0xD4, 0xFE, 0x34, 0x12};       /* -300, 0x1234 */
    tool_send(r, RPDO2, rpdo2, 4);
    assert_int_equal(r->told, 3);
    assert_int_equal(r->kinds, CO_CIA401_OUT_ANALOG);
    assert_int_equal(r->analog[0], -300);
    assert_int_equal(r->analog[1], 0x1234);
    tool_send(r, RPDO2, rpdo2, 4);                           /* the same again: no change */
    assert_int_equal(r->told, 3);

    /* the application's own write counts too */
    const uint8_t local[2] = {7, 0};
    assert_int_equal(co_od_put(&r->od, 0x6411, 2, local, 2), 0);
    assert_int_equal(r->told, 4);
    assert_int_equal(r->analog[1], 7);
    rig_free(r);
}

/* NMT stop from operational: outputs with error mode take their error
 * value (0x6206/0x6207, 0x6443/0x6444 written by SDO); the others stay. */
static void test_nmt_stop_applies_error_values(void **state)
{
    (void)state;
    rig_t *r = rig_new();
    nmt(r, CO_NMT_CMD_START);
    sdo_write(r, 0x6206, 1, 0x0F, 1);
    sdo_write(r, 0x6207, 1, 0x05, 1);
    sdo_write(r, 0x6443, 2, 0, 1);
    sdo_write(r, 0x6444, 1, 100000, 4);                      /* saturated to 0x7FFF */
    sdo_write(r, 0x6200, 1, 0xF2, 1);
    sdo_write(r, 0x6411, 1, 100, 2);
    sdo_write(r, 0x6411, 2, 200, 2);
    assert_int_equal(r->told, 3);
    nmt(r, CO_NMT_CMD_STOP);
    assert_int_equal(r->told, 4);
    assert_int_equal(r->kinds, CO_CIA401_OUT_DIGITAL | CO_CIA401_OUT_ANALOG);
    assert_int_equal(r->digital, 0xF5);
    assert_int_equal(r->analog[0], 0x7FFF);
    assert_int_equal(r->analog[1], 200);
    /* an explicit fault changes nothing more: no indication */
    co_cia401_od_fault(co_stack_cia401(&r->stack));
    assert_int_equal(r->told, 4);
    rig_free(r);
}

/* Reset node: the inputs stay in 0x6000 (the levels did not change), the
 * outputs follow the reloaded 0x6200 / 0x6411, digital first. */
static void test_reset_node_keeps_inputs(void **state)
{
    (void)state;
    rig_t *r = rig_new();
    set_inputs(r, 0x01, 0x03);
    sdo_write(r, 0x6200, 1, 0x0F, 1);
    sdo_write(r, 0x6411, 1, 5, 2);
    assert_int_equal(r->told, 2);
    nmt(r, CO_NMT_CMD_RESET_NODE);
    run_ms(r, 5);
    assert_int_equal(r->told, 4);
    assert_int_equal(r->kinds, CO_CIA401_OUT_ANALOG);
    assert_int_equal(r->digital, 0);
    assert_int_equal(r->analog[0], 0);
    assert_int_equal(tu_od_value(&r->od, 0x6000, 1, 1), 0x01);
    assert_int_equal(tu_od_value(&r->od, 0x6000, 2, 1), 0x03);
    rig_free(r);
}

/* An OD the part cannot use: the scan names the entry, the stack refuses
 * with CO_STACK_ERR_OD and says which part. */
static void test_bad_od_is_refused(void **state)
{
    (void)state;
    rig_t *r = calloc(1, sizeof *r);
    assert_non_null(r);
    tu_od_row_t rows[sizeof device_rows / sizeof device_rows[0]];
    memcpy(rows, device_rows, sizeof rows);
    for (size_t i = 0; i < sizeof rows / sizeof rows[0]; i++) {
        if (rows[i].index == 0x6411 && rows[i].sub == 2) {
            rows[i].type = U16;                               /* should be INTEGER16 */
        }
    }
    od_build(r, rows, sizeof rows / sizeof rows[0]);
    co_cia401_od_counts_t counts;
    uint16_t index;
    uint8_t sub;
    assert_int_equal(co_cia401_od_scan(&r->od, &counts, &index, &sub), CO_CIA401_OD_BAD_TYPE);
    assert_int_equal(index, 0x6411);
    assert_int_equal(sub, 2);
    node_up(r);
    size_t before = r->arena.used;
    assert_int_equal(co_stack_cia401_need(&r->stack), 0);
    assert_int_equal(co_stack_cia401_init(&r->stack, on_outputs, r), CO_STACK_ERR_OD);
    assert_int_equal(co_stack_failed_part(&r->stack), CO_STACK_PART_CIA401);
    assert_int_equal(r->arena.used, before);
    assert_null(co_stack_cia401(&r->stack));
    rig_free(r);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_inputs_send_tpdo1_bytes),
        cmocka_unit_test(test_analog_delta_sends_tpdo2),
        cmocka_unit_test(test_outputs_follow_sdo_and_rpdo),
        cmocka_unit_test(test_nmt_stop_applies_error_values),
        cmocka_unit_test(test_reset_node_keeps_inputs),
        cmocka_unit_test(test_bad_od_is_refused),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
