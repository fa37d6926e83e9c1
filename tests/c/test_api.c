/* co_api: the CANopen API of seed 004 over co_stack on a mem bus. Every
 * request (GetID, GetStatus, InitCANopen, ReadProcessData, WriteProcessData)
 * with its edge values, every indication (NMTChange, ReceivedData from an
 * RPDO and from an SDO download, FatalError), the TPDO a host write sends,
 * and the OD's process image refusing entries that do not fit. */
#include "test_od_util.h"

#include "canopenfd/co_api.h"

#include <stdlib.h>

enum { NODE = 0x40, IMAGE = 8 };

static const tu_od_row_t comm_rows[] = {
    {0x1000, 0, VAR, U32, RO, 0, 4, 0x000F0191, NULL, 0, 0},
    {0x1001, 0, VAR, U8, RO, 0, 1, 0, NULL, 0, 0},
    {0x1017, 0, VAR, U16, RW, 0, 2, 0, NULL, 0, 0},
    {0x1400, 0, REC, U8, RO, 0, 1, 2, NULL, 0, 0},
    {0x1400, 1, REC, U32, RW, CO_OD_NODEID_RELATIVE, 4, 0x200, NULL, 0, 0},
    {0x1400, 2, REC, U8, RW, 0, 1, 255, NULL, 0, 0},
    {0x1600, 0, REC, U8, RW, 0, 1, 2, NULL, 0, 0},
    {0x1600, 1, REC, U32, RW, 0, 4, 0x62000108, NULL, 0, 0},
    {0x1600, 2, REC, U32, RW, 0, 4, 0x62000208, NULL, 0, 0},
    {0x1800, 0, REC, U8, RO, 0, 1, 2, NULL, 0, 0},
    {0x1800, 1, REC, U32, RW, CO_OD_NODEID_RELATIVE, 4, 0x180, NULL, 0, 0},
    {0x1800, 2, REC, U8, RW, 0, 1, 254, NULL, 0, 0},
    {0x1A00, 0, REC, U8, RW, 0, 1, 1, NULL, 0, 0},
    {0x1A00, 1, REC, U32, RW, 0, 4, 0x60000110, NULL, 0, 0},
    {0x6000, 0, REC, U8, AC_CONST, 0, 1, 1, NULL, 0, 0},
    {0x6200, 0, REC, U8, AC_CONST, 0, 1, 2, NULL, 0, 0},
};

static const uint8_t initial[IMAGE] = {0x00, 0x11, 0x22, 0x33, 0x44, 0x55, 0x66, 0x77};

typedef struct fx {
    tu_bus_t tb;
    tu_line_t dev_line, tool_line;
    co_od_t od;
    co_od_entry_t entries[32];
    uint8_t pool[512];
    co_od_subscription_t subs[CO_STACK_OD_SUBSCRIPTIONS];
    co_stack_t stack;
    co_stack_arena_t arena;
    unsigned char memory[48 * 1024];
    co_api_t api;
    uint8_t nmt[16];
    unsigned nmt_count;
    uint8_t received[8][2];
    unsigned received_count;
    uint8_t fatal;
    uint8_t bps_seen;
} fx_t;

static void on_nmt(uint8_t state, void *user)
{
    fx_t *fx = user;
    assert_true(fx->nmt_count < 16);
    fx->nmt[fx->nmt_count++] = state;
}

static void on_received(uint8_t offset, uint8_t length, void *user)
{
    fx_t *fx = user;
    assert_true(fx->received_count < 8);
    fx->received[fx->received_count][0] = offset;
    fx->received[fx->received_count++][1] = length;
}

static void on_fatal(uint8_t code, void *user)
{
    ((fx_t *)user)->fatal = code;
}

static bool on_bit_rate(uint8_t bps, void *user)
{
    ((fx_t *)user)->bps_seen = bps;
    return bps != 7;      /* this "driver" cannot do 800 kbit/s */
}

static const co_api_callbacks_t callbacks = {.nmt_change = on_nmt, .received_data = on_received,
                                             .fatal_error = on_fatal,
                                             .set_bit_rate = on_bit_rate};

/* [6000,01] U16 at bytes 0..1 (TPDO), [6200,01..02] U8 at 2 and 3 (RPDO). */
static void add_image_entry(fx_t *fx, uint16_t index, uint8_t sub, uint8_t type, uint32_t size,
                            uint16_t map, uint32_t offset)
{
    co_od_def_t d = tu_od_def(index, sub, CO_OBJECT_RECORD, type, CO_ACCESS_RW, map, size);
    d.default_value = initial + offset;
    d.default_length = size;
    assert_int_equal(co_od_add_in_image(&fx->od, &d, offset), CO_OD_ADDED);
}

/* second: the image byte of [6200,02] (3 follows [6200,01] at 2; 5 lies apart) */
static fx_t *fx_new_at(uint32_t second)
{
    fx_t *fx = calloc(1, sizeof *fx);
    assert_non_null(fx);
    tu_bus_init(&fx->tb, CO_MODE_CLASSIC, false);
    tu_bus_add_line(&fx->tb, &fx->dev_line);
    tu_bus_add_line(&fx->tb, &fx->tool_line);
    co_od_init(&fx->od, CO_MODE_CLASSIC, fx->entries, 32, fx->pool, sizeof fx->pool, fx->subs,
               CO_STACK_OD_SUBSCRIPTIONS);
    assert_true(co_od_reserve_image(&fx->od, IMAGE));
    tu_od_add_rows(&fx->od, comm_rows, sizeof comm_rows / sizeof comm_rows[0]);
    add_image_entry(fx, 0x6000, 1, U16, 2, CO_OD_MAP_TPDO, 0);
    add_image_entry(fx, 0x6200, 1, U8, 1, CO_OD_MAP_RPDO, 2);
    add_image_entry(fx, 0x6200, 2, U8, 1, CO_OD_MAP_RPDO, second);
    assert_true(co_od_seal(&fx->od, NODE));
    co_stack_arena_init(&fx->arena, fx->memory, sizeof fx->memory);
    co_stack_line_config_t line_config = {.heartbeat_entries = 4};
    assert_int_equal(co_stack_init(&fx->stack, &fx->dev_line.line, &line_config,
                                   co_stack_arena_allocator(&fx->arena)), CO_STACK_OK);
    co_api_config_t config = {.id = {0x34, 0x12, 0x02, 0x01}, .default_bps = 4,
                              .node = {.node_id = NODE, .od = &fx->od},
                              .initial_image = initial, .cb = &callbacks, .user = fx};
    assert_true(co_api_init(&fx->api, &fx->stack, &config));
    return fx;
}

static fx_t *fx_new(void)
{
    return fx_new_at(3);
}

static void fx_free(fx_t *fx)
{
    co_api_deinit(&fx->api);
    co_stack_deinit(&fx->stack);
    free(fx);
}

static void fx_start(fx_t *fx)
{
    assert_int_equal(co_api_init_canopen(&fx->api, 0, 0), CO_API_TRUE);
    tu_run_until(&fx->tb, fx->tb.now + 5 * TU_MS);
    assert_true(co_nmt_master_send(&fx->tool_line.line, NULL, CO_NMT_CMD_START, NODE, false));
    tu_run_until(&fx->tb, fx->tb.now + 5 * TU_MS);
    assert_int_equal(fx->nmt[fx->nmt_count - 1], CO_NMT_OPERATIONAL);
}

static void test_id_and_status_before_init(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    uint8_t id[4];
    co_api_get_id(&fx->api, id);
    assert_memory_equal(id, ((const uint8_t[]){0x34, 0x12, 0x02, 0x01}), 4);
    assert_int_equal(co_api_get_status(&fx->api), CO_API_STATE_READY);   /* 32-byte class */
    tu_run_until(&fx->tb, 10 * TU_MS);
    assert_int_equal(fx->tb.log_count, 0);             /* silent until InitCANopen */
    fx_free(fx);
}

static void test_read_and_write_stay_in_the_image(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    uint8_t buf[16];
    memset(buf, 0xEE, sizeof buf);
    assert_int_equal(co_api_read(&fx->api, 0, 8, buf), 8);
    assert_memory_equal(buf, initial, 8);
    memset(buf, 0xEE, sizeof buf);
    assert_int_equal(co_api_read(&fx->api, 6, 5, buf), 2);
    assert_memory_equal(buf, ((const uint8_t[]){0x66, 0x77, 0xEE}), 3);
    assert_int_equal(co_api_read(&fx->api, 8, 1, buf), 0);
    assert_int_equal(co_api_read(&fx->api, 255, 255, buf), 0);
    assert_int_equal(co_api_write(&fx->api, 7, 2, (const uint8_t[]){0xAA, 0xBB}), 1);
    assert_int_equal(co_api_write(&fx->api, 9, 1, (const uint8_t[]){0x01}), 0);
    assert_int_equal(fx->pool[IMAGE], 0x91);            /* the byte after the image: 0x1000's
                                                          default, untouched */
    assert_int_equal(co_api_read(&fx->api, 4, 4, buf), 4);
    assert_memory_equal(buf, ((const uint8_t[]){0x44, 0x55, 0x66, 0xAA}), 4);
    assert_int_equal(fx->api.refused_reads, 2);
    assert_int_equal(fx->api.refused_writes, 1);
    fx_free(fx);
}

static void test_init_canopen_and_nmt_changes(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    assert_int_equal(co_api_init_canopen(&fx->api, 9, 0), CO_API_FALSE);
    assert_int_equal(co_api_init_canopen(&fx->api, 0, 128), CO_API_FALSE);
    assert_int_equal(co_api_init_canopen(&fx->api, 7, 0), CO_API_FALSE);   /* driver said no */
    assert_int_equal(fx->nmt_count, 0);
    assert_int_equal(co_api_init_canopen(&fx->api, 0, 0), CO_API_TRUE);
    assert_int_equal(fx->bps_seen, 4);                  /* the default */
    tu_run_until(&fx->tb, 5 * TU_MS);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, 0x700 + NODE, 0), 0x700 + NODE,
                     (const uint8_t[]){0x00}, 1);
    assert_int_equal(fx->nmt_count, 2);
    assert_int_equal(fx->nmt[0], 0x00);
    assert_int_equal(fx->nmt[1], 0x7F);
    assert_int_equal(co_api_get_status(&fx->api), CO_API_STATE_OPERATING);
    /* a network reset: 81h; InitCANopen again: a reset without 81h */
    assert_true(co_nmt_master_send(&fx->tool_line.line, NULL, CO_NMT_CMD_RESET_NODE, NODE, false));
    tu_run_until(&fx->tb, 10 * TU_MS);
    unsigned after_network = fx->nmt_count;
    assert_int_equal(co_api_init_canopen(&fx->api, 5, 0), CO_API_TRUE);
    tu_run_until(&fx->tb, 15 * TU_MS);
    bool reset_told = false;
    for (unsigned i = 2; i < after_network; i++) {
        reset_told = reset_told || fx->nmt[i] == CO_API_NMT_RESET_NODE;
    }
    assert_true(reset_told);
    for (unsigned i = after_network; i < fx->nmt_count; i++) {
        assert_int_not_equal(fx->nmt[i], CO_API_NMT_RESET_NODE);
    }
    assert_int_equal(fx->nmt[fx->nmt_count - 1], 0x7F);
    assert_int_equal(fx->api.bps, 5);
    fx_free(fx);
}

static void test_rpdo_gives_one_received_data(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    fx_start(fx);
    assert_true(co_line_send(&fx->tool_line.line, 0x200 + NODE,
                             (const uint8_t[]){0xA1, 0xA2}, 2));
    tu_run_until(&fx->tb, fx->tb.now + 5 * TU_MS);
    assert_int_equal(fx->received_count, 1);
    assert_int_equal(fx->received[0][0], 2);
    assert_int_equal(fx->received[0][1], 2);
    uint8_t buf[2];
    assert_int_equal(co_api_read(&fx->api, 2, 2, buf), 2);
    assert_memory_equal(buf, ((const uint8_t[]){0xA1, 0xA2}), 2);
    fx_free(fx);
}

/* Seed 004 §4.2.2 NOTE: bytes that land apart give one indication each. */
static void test_rpdo_to_scattered_bytes(void **state)
{
    (void)state;
    fx_t *fx = fx_new_at(5);
    fx_start(fx);
    assert_true(co_line_send(&fx->tool_line.line, 0x200 + NODE,
                             (const uint8_t[]){0x0B, 0x0E}, 2));
    tu_run_until(&fx->tb, fx->tb.now + 5 * TU_MS);
    assert_int_equal(fx->received_count, 2);
    assert_int_equal(fx->received[0][0], 2);
    assert_int_equal(fx->received[0][1], 1);
    assert_int_equal(fx->received[1][0], 5);
    assert_int_equal(fx->received[1][1], 1);
    uint8_t buf[4];
    assert_int_equal(co_api_read(&fx->api, 2, 4, buf), 4);
    assert_memory_equal(buf, ((const uint8_t[]){0x0B, 0x33, 0x44, 0x0E}), 4);
    fx_free(fx);
}

static void test_sdo_download_gives_received_data(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    assert_int_equal(co_api_init_canopen(&fx->api, 0, 0), CO_API_TRUE);
    tu_run_until(&fx->tb, 5 * TU_MS);
    /* expedited download of one byte to 6200:02 */
    assert_true(co_line_send(&fx->tool_line.line, 0x600 + NODE,
                             (const uint8_t[]){0x2F, 0x00, 0x62, 0x02, 0x5A, 0, 0, 0}, 8));
    tu_run_until(&fx->tb, 10 * TU_MS);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, 0x580 + NODE, 0), 0x580 + NODE,
                     (const uint8_t[]){0x60, 0x00, 0x62, 0x02, 0, 0, 0, 0}, 8);
    assert_int_equal(fx->received_count, 1);
    assert_int_equal(fx->received[0][0], 3);
    assert_int_equal(fx->received[0][1], 1);
    uint8_t b;
    assert_int_equal(co_api_read(&fx->api, 3, 1, &b), 1);
    assert_int_equal(b, 0x5A);
    fx_free(fx);
}

/* InitCANopen again with another node-id re-initialises under it (seed 004
 * §4.1.3): boot-up, SDO server and $NODEID COB-IDs all follow. */
static void test_init_canopen_again_takes_the_new_node_id(void **state)
{
    (void)state;
    enum { NEW = 0x05 };
    fx_t *fx = fx_new();
    fx_start(fx);
    assert_int_equal(co_api_init_canopen(&fx->api, 0, 128), CO_API_FALSE);
    assert_int_equal(co_api_init_canopen(&fx->api, 0, NEW), CO_API_TRUE);
    tu_run_until(&fx->tb, fx->tb.now + 5 * TU_MS);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, 0x700 + NEW, 0), 0x700 + NEW,
                     (const uint8_t[]){0x00}, 1);
    assert_int_equal(co_stack_node(&fx->stack)->nmt.node_id, NEW);
    uint32_t cob_id = 0;
    assert_true(co_od_get_u32(&fx->od, 0x1800, 1, &cob_id));
    assert_int_equal(cob_id, 0x180 + NEW);
    assert_int_equal(fx->nmt[fx->nmt_count - 1], 0x7F);
    /* the server answers under the new node-id, no longer under the old one */
    size_t old_answers = tu_log_count_id(&fx->tb, 0x580 + NODE);
    assert_true(co_line_send(&fx->tool_line.line, 0x600 + NODE,
                             (const uint8_t[]){0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}, 8));
    assert_true(co_line_send(&fx->tool_line.line, 0x600 + NEW,
                             (const uint8_t[]){0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}, 8));
    tu_run_until(&fx->tb, fx->tb.now + 5 * TU_MS);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x580 + NODE), old_answers);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, 0x580 + NEW, 0), 0x580 + NEW,
                     (const uint8_t[]){0x43, 0x00, 0x10, 0x00, 0x91, 0x01, 0x0F, 0x00}, 8);
    /* the same node-id again: a plain re-initialisation */
    assert_int_equal(co_api_init_canopen(&fx->api, 0, NEW), CO_API_TRUE);
    tu_run_until(&fx->tb, fx->tb.now + 5 * TU_MS);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x700 + NEW), 2);
    fx_free(fx);
}

static void test_write_sends_the_tpdo(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    fx_start(fx);
    size_t before = tu_log_count_id(&fx->tb, 0x180 + NODE);
    assert_int_equal(co_api_write(&fx->api, 0, 2, (const uint8_t[]){0x00, 0x11}), 2);
    tu_run_until(&fx->tb, fx->tb.now + 5 * TU_MS);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x180 + NODE), before);   /* unchanged: no event */
    assert_int_equal(co_api_write(&fx->api, 0, 2, (const uint8_t[]){0x10, 0x20}), 2);
    tu_run_until(&fx->tb, fx->tb.now + 5 * TU_MS);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, 0x180 + NODE, before), 0x180 + NODE,
                     (const uint8_t[]){0x10, 0x20}, 2);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x180 + NODE), before + 1);   /* once */
    fx_free(fx);
}

static void test_fatal_error(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    co_api_comm_event(&fx->api, CO_COMM_ERROR_PASSIVE);
    assert_int_equal(fx->fatal, 0);
    co_api_comm_event(&fx->api, CO_COMM_BUS_OFF);
    assert_int_equal(fx->fatal, CO_API_FATAL_BUS_OFF);
    co_api_comm_event(&fx->api, CO_COMM_IFACE_DOWN);
    assert_int_equal(fx->fatal, CO_API_FATAL_INTERFACE_DOWN);
    fx_free(fx);
}

static void test_image_refuses_what_does_not_fit(void **state)
{
    (void)state;
    co_od_t od;
    co_od_entry_t entries[8];
    uint8_t pool[64];
    co_od_init(&od, CO_MODE_CLASSIC, entries, 8, pool, sizeof pool, NULL, 0);
    assert_false(co_od_reserve_image(&od, 65));          /* larger than the pool */
    assert_true(co_od_reserve_image(&od, 4));
    co_od_def_t u16 = tu_od_def(0x6000, 0, VAR, U16, RW, 0, 2);
    co_od_def_t u32 = tu_od_def(0x6001, 0, VAR, U32, RW, 0, 4);
    co_od_def_t vs = tu_od_def(0x6002, 0, VAR, VS, RW, 0, 2);
    assert_int_equal(co_od_add_in_image(&od, &u16, 3), CO_OD_ERR_IMAGE);   /* past the end */
    assert_int_equal(co_od_add_in_image(&od, &u16, 4), CO_OD_ERR_IMAGE);
    assert_int_equal(co_od_add_in_image(&od, &vs, 0), CO_OD_ERR_IMAGE);    /* not fixed-size */
    assert_int_equal(co_od_add_in_image(&od, &u16, 1), CO_OD_ADDED);
    assert_int_equal(co_od_add_in_image(&od, &u32, 0), CO_OD_ERR_IMAGE);   /* overlaps */
    assert_false(co_od_reserve_image(&od, 4));           /* entries exist already */
    co_od_def_t outside = tu_od_def(0x1017, 0, VAR, U16, RW, 0, 2);
    assert_int_equal(co_od_add(&od, &outside), CO_OD_ADDED);
    assert_true(co_od_seal(&od, 1));
    assert_true(co_od_in_image(&od, co_od_find(&od, 0x6000, 0)));
    assert_false(co_od_in_image(&od, co_od_find(&od, 0x1017, 0)));
    assert_int_equal(co_od_put(&od, 0x6000, 0, (const uint8_t[]){0x34, 0x12}, 2), 0);
    assert_memory_equal(co_od_image(&od) + 1, ((const uint8_t[]){0x34, 0x12}), 2);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_id_and_status_before_init),
        cmocka_unit_test(test_read_and_write_stay_in_the_image),
        cmocka_unit_test(test_init_canopen_and_nmt_changes),
        cmocka_unit_test(test_rpdo_gives_one_received_data),
        cmocka_unit_test(test_rpdo_to_scattered_bytes),
        cmocka_unit_test(test_sdo_download_gives_received_data),
        cmocka_unit_test(test_init_canopen_again_takes_the_new_node_id),
        cmocka_unit_test(test_write_sends_the_tpdo),
        cmocka_unit_test(test_fatal_error),
        cmocka_unit_test(test_image_refuses_what_does_not_fit),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
