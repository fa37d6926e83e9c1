/* co_stack and LSS: the node's LSS slave set up from 0x1018:04, the line's
 * LSS master, and a node that starts unconfigured (node-id 255): silent but
 * for LSS until a fast scan gives it a node-id, then it boots with it. */
#include "test_od_util.h"

#include "canopenfd/co_stack.h"

#include <stdlib.h>

enum { NODE = 5 };

static const tu_od_row_t rows[] = {
    {0x1000, 0, VAR, U32, RO, 0, 4, 0x00000191, NULL, 0, 0},
    {0x1001, 0, VAR, U8, RO, 0, 1, 0, NULL, 0, 0},
    {0x1014, 0, VAR, U32, RW, CO_OD_NODEID_RELATIVE, 4, 0x80, NULL, 0, 0},
    {0x1017, 0, VAR, U16, RW, 0, 2, 100, NULL, 0, 0},
    {0x1018, 0, REC, U8, RO, 0, 1, 4, NULL, 0, 0},
    {0x1018, 1, REC, U32, RO, 0, 4, 0x12345678, NULL, 0, 0},
    {0x1018, 2, REC, U32, RO, 0, 4, 0x0000ABCD, NULL, 0, 0},
    {0x1018, 3, REC, U32, RO, 0, 4, 0x00010002, NULL, 0, 0},
    {0x1018, 4, REC, U32, RO, 0, 4, 0xFEDC0001, NULL, 0, 0},
};

typedef struct device {
    co_od_t od;
    co_od_entry_t entries[32];
    uint8_t pool[256];
    co_od_subscription_t subs[CO_STACK_OD_SUBSCRIPTIONS];
} device_t;

/* rows without the serial number when `serial` is false */
static void device_od(device_t *d, uint8_t node_id, bool serial)
{
    memset(d, 0, sizeof *d);
    co_od_init(&d->od, CO_MODE_CLASSIC, d->entries, 32, d->pool, sizeof d->pool, d->subs,
               CO_STACK_OD_SUBSCRIPTIONS);
    size_t n = sizeof rows / sizeof rows[0];
    tu_od_add_rows(&d->od, rows, serial ? n : n - 1);
    assert_true(co_od_seal(&d->od, node_id));
}

typedef struct fx {
    tu_bus_t tb;
    tu_line_t dev_line;
    tu_line_t tool_line;
    device_t dev;
    co_stack_t stack;
    co_stack_arena_t arena;
    unsigned char memory[32 * 1024];
    co_stack_t tool;
    co_stack_arena_t tool_arena;
    unsigned char tool_memory[8 * 1024];
    int done;
    co_lss_master_result_t result;
    int resets;
    uint8_t reset_id;
    int stores;
} fx_t;

static void on_done(co_lss_master_t *m, const co_lss_master_result_t *r, void *user)
{
    (void)m;
    fx_t *fx = user;
    fx->done++;
    fx->result = *r;
}

static void on_reset(co_lss_slave_t *slave, uint8_t node_id, void *user)
{
    (void)slave;
    fx_t *fx = user;
    fx->resets++;
    fx->reset_id = node_id;
}

static uint8_t on_store(co_lss_slave_t *slave, uint8_t node_id, void *user)
{
    (void)slave;
    (void)node_id;
    ((fx_t *)user)->stores++;
    return CO_LSS_ERR_OK;
}

static const co_lss_slave_indications_t lss_ind = {.store = on_store,
                                                   .reset_communication = on_reset};

static fx_t *fx_new(void)
{
    fx_t *fx = calloc(1, sizeof *fx);
    assert_non_null(fx);
    tu_bus_init(&fx->tb, CO_MODE_CLASSIC, false);
    tu_bus_add_line(&fx->tb, &fx->dev_line);
    tu_bus_add_line(&fx->tb, &fx->tool_line);
    co_stack_arena_init(&fx->arena, fx->memory, sizeof fx->memory);
    co_stack_arena_init(&fx->tool_arena, fx->tool_memory, sizeof fx->tool_memory);
    co_stack_line_config_t lc = {.heartbeat_entries = 4};
    assert_int_equal(co_stack_init(&fx->tool, &fx->tool_line.line, &lc,
                                   co_stack_arena_allocator(&fx->tool_arena)), CO_STACK_OK);
    assert_int_equal(co_stack_lss_master_init(&fx->tool, 10, on_done, fx), CO_STACK_OK);
    assert_int_equal(co_stack_init(&fx->stack, &fx->dev_line.line, &lc,
                                   co_stack_arena_allocator(&fx->arena)), CO_STACK_OK);
    return fx;
}

static void fx_free(fx_t *fx)
{
    co_stack_deinit(&fx->stack);
    co_stack_deinit(&fx->tool);
    free(fx);
}

static co_stack_node_config_t config_of(fx_t *fx, uint8_t node_id)
{
    co_stack_node_config_t c = {.node_id = node_id, .od = &fx->dev.od, .lss_ind = &lss_ind,
                                .lss_user = fx};
    return c;
}

static co_lss_master_result_t wait_done(fx_t *fx)
{
    int done = fx->done;
    tu_step(&fx->tb, fx->tb.now);
    while (fx->done == done) {
        uint64_t d = tu_next_deadline(&fx->tb);
        assert_true(d != CO_TIME_NEVER);
        tu_step(&fx->tb, d);
    }
    return fx->result;
}

static co_lss_master_t *master(fx_t *fx) { return co_stack_lss_master(&fx->tool); }

/* A configured node with a serial number answers LSS with its identity. */
static void test_configured_node_has_lss(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    device_od(&fx->dev, NODE, true);
    co_stack_node_config_t c = config_of(fx, NODE);
    assert_int_equal(co_stack_node_init(&fx->stack, &c), CO_STACK_OK);
    assert_int_equal(co_stack_boot(&fx->stack), CO_STACK_OK);
    assert_non_null(co_stack_lss_slave(&fx->stack));
    assert_false(co_stack_unconfigured(&fx->stack));
    co_lss_address_t a = {{0x12345678, 0x0000ABCD, 0x00010002, 0xFEDC0001}};
    assert_true(co_lss_master_switch_selective(master(fx), &a));
    assert_int_equal(wait_done(fx).status, CO_LSS_OK);
    assert_true(co_lss_master_inquire(master(fx), CO_LSS_CS_INQUIRE_NODE_ID));
    co_lss_master_result_t r = wait_done(fx);
    assert_int_equal(r.status, CO_LSS_OK);
    assert_int_equal(r.value, NODE);
    /* The application stores through its indication. */
    assert_true(co_lss_master_configure_node_id(master(fx), 7));
    assert_int_equal(wait_done(fx).status, CO_LSS_OK);
    assert_true(co_lss_master_store(master(fx)));
    assert_int_equal(wait_done(fx).status, CO_LSS_OK);
    assert_int_equal(fx->stores, 1);
    assert_int_equal(co_lss_slave_persistent_node_id(co_stack_lss_slave(&fx->stack)), 7);
    /* Configured before: back to waiting changes nothing now. */
    assert_true(co_lss_master_switch_global(master(fx), CO_LSS_STATE_WAITING));
    tu_step(&fx->tb, fx->tb.now + 1000);
    assert_int_equal(fx->resets, 0);
    assert_int_equal(co_line_node_id(&fx->dev_line.line), NODE);
    /* Only one master per line. */
    assert_int_equal(co_stack_lss_master_init(&fx->tool, 10, on_done, fx), CO_STACK_ERR_STATE);
    assert_int_equal(co_stack_failed_part(&fx->tool), CO_STACK_PART_LSS);
    assert_string_equal(co_stack_part_name(CO_STACK_PART_LSS), "LSS");
    fx_free(fx);
}

/* lss_off, or no 0x1018:04: no slave; 0x7E5 goes unhandled. */
static void test_no_lss(void **state)
{
    (void)state;
    for (int variant = 0; variant < 2; variant++) {
        fx_t *fx = fx_new();
        device_od(&fx->dev, NODE, variant == 1);
        co_stack_node_config_t c = config_of(fx, NODE);
        c.lss_off = variant == 1;
        assert_int_equal(co_stack_node_init(&fx->stack, &c), CO_STACK_OK);
        assert_null(co_stack_lss_slave(&fx->stack));
        assert_true(co_lss_master_inquire(master(fx), CO_LSS_CS_INQUIRE_NODE_ID));
        assert_int_equal(wait_done(fx).status, CO_LSS_TIMEOUT);
        assert_true(co_line_stats(&fx->dev_line.line)->rx_unhandled >= 1);
        /* And so no unconfigured start either. */
        co_stack_node_deinit(&fx->stack);
        c.node_id = 255;
        assert_int_equal(co_stack_node_init(&fx->stack, &c), CO_STACK_ERR_ARGUMENT);
        assert_int_equal(co_stack_failed_part(&fx->stack), CO_STACK_PART_LSS);
        fx_free(fx);
    }
}

/* Node-id 255: nothing but LSS until fast scan gives it 9; then boot-up on
 * 0x709, heartbeats, and the OD's $NODEID entries with 9. */
static void test_unconfigured_node(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    device_od(&fx->dev, 255, true);
    co_stack_node_config_t c = config_of(fx, 255);
    size_t need = co_stack_node_need(&fx->dev_line.line, &c);
    size_t line_used = fx->arena.used;
    assert_int_equal(co_stack_node_init(&fx->stack, &c), CO_STACK_OK);
    assert_true(co_stack_unconfigured(&fx->stack));
    assert_false(co_stack_has_node(&fx->stack));
    assert_int_equal(fx->arena.used, line_used);         /* nothing taken yet */
    assert_int_equal(co_stack_boot(&fx->stack), CO_STACK_OK);
    assert_int_equal(co_stack_node_init(&fx->stack, &c), CO_STACK_ERR_STATE);
    tu_run_until(&fx->tb, 1000u * TU_MS);
    assert_int_equal(fx->tb.log_count, 0);                /* no boot-up, no heartbeat */

    /* The tool asks: one non-configured slave. */
    assert_true(co_lss_master_identify_non_configured(master(fx)));
    assert_int_equal(wait_done(fx).status, CO_LSS_OK);
    tu_log_clear(&fx->tb);
    uint8_t ids[] = {9};
    co_lss_device_t found[1];
    assert_true(co_lss_master_fastscan(master(fx), ids, 1, found, 1));
    co_lss_master_result_t r = wait_done(fx);
    assert_int_equal(r.status, CO_LSS_OK);
    assert_int_equal(r.found, 1);
    assert_int_equal(found[0].address.part[CO_LSS_SERIAL], 0xFEDC0001u);
    assert_false(co_stack_unconfigured(&fx->stack));
    assert_true(co_stack_has_node(&fx->stack));
    assert_int_equal(co_line_node_id(&fx->dev_line.line), 9);
    assert_int_equal(fx->resets, 1);
    assert_int_equal(fx->reset_id, 9);
    assert_int_equal(fx->arena.used, line_used + need);   /* exactly what was said */
    /* Boot-up with the new node-id, then heartbeats every 100 ms. */
    long boot = tu_log_find_id(&fx->tb, 0x709, 0);
    const uint8_t zero = 0;
    tu_assert_logged(&fx->tb, boot, 0x709, &zero, 1);
    tu_run_until(&fx->tb, fx->tb.now + 350u * TU_MS);
    assert_true(tu_log_count_id(&fx->tb, 0x709) >= 4);
    uint32_t emcy_cob = 0;
    assert_true(co_od_get_u32(&fx->dev.od, 0x1014, 0, &emcy_cob));
    assert_int_equal(emcy_cob, 0x89);
    /* It no longer takes part in fast scan. */
    assert_true(co_lss_master_fastscan(master(fx), ids, 1, found, 1));
    r = wait_done(fx);
    assert_int_equal(r.status, CO_LSS_OK);
    assert_int_equal(r.found, 0);
    fx_free(fx);
}

/* Configured by LSS before co_stack_boot: set up, booted only when asked. */
static void test_unconfigured_configured_before_boot(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    device_od(&fx->dev, 255, true);
    co_stack_node_config_t c = config_of(fx, 255);
    assert_int_equal(co_stack_node_init(&fx->stack, &c), CO_STACK_OK);
    uint8_t ids[] = {12};
    co_lss_device_t found[1];
    assert_true(co_lss_master_fastscan(master(fx), ids, 1, found, 1));
    assert_int_equal(wait_done(fx).found, 1);
    assert_true(co_stack_has_node(&fx->stack));
    assert_int_equal(tu_log_count_id(&fx->tb, 0x70C), 0);
    assert_int_equal(co_stack_boot(&fx->stack), CO_STACK_OK);
    tu_step(&fx->tb, fx->tb.now + 1);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x70C), 1);
    fx_free(fx);
}

/* The tool sends one raw frame on the bus. */
static void tool_send(fx_t *fx, uint32_t id, const uint8_t *data, uint8_t len)
{
    assert_true(co_line_send(&fx->tool_line.line, id, data, len));
    tu_step(&fx->tb, fx->tb.now + 1);
}

/* CiA 305: a configured node given another node-id keeps its active one
 * until NMT reset communication, then boots with the pending one: boot-up,
 * heartbeat, SDO server, EMCY COB-ID and NMT addressing move to it. */
static void test_configured_node_new_id_at_reset(void **state)
{
    (void)state;
    for (int kind = 0; kind < 2; kind++) {
        const uint8_t command = kind == 0 ? 0x82 : 0x81;   /* reset communication / node */
        fx_t *fx = fx_new();
        device_od(&fx->dev, NODE, true);
        co_stack_node_config_t c = config_of(fx, NODE);
        assert_int_equal(co_stack_node_init(&fx->stack, &c), CO_STACK_OK);
        assert_int_equal(co_stack_boot(&fx->stack), CO_STACK_OK);
        assert_true(co_lss_master_switch_global(master(fx), CO_LSS_STATE_CONFIGURATION));
        assert_true(co_lss_master_configure_node_id(master(fx), 7));
        assert_int_equal(wait_done(fx).status, CO_LSS_OK);
        /* Pending only: the node answers as 5, back in waiting too. */
        assert_true(co_lss_master_inquire(master(fx), CO_LSS_CS_INQUIRE_NODE_ID));
        assert_int_equal(wait_done(fx).value, NODE);
        assert_true(co_lss_master_switch_global(master(fx), CO_LSS_STATE_WAITING));
        tu_log_clear(&fx->tb);
        tu_run_until(&fx->tb, fx->tb.now + 250u * TU_MS);
        assert_true(tu_log_count_id(&fx->tb, 0x705) >= 2);   /* heartbeats as 5 */
        assert_int_equal(tu_log_count_id(&fx->tb, 0x707), 0);
        assert_int_equal(fx->resets, 0);
        /* An NMT command for node 7 is not for it yet. */
        const uint8_t start7[2] = {0x01, 7};
        tool_send(fx, 0x000, start7, 2);
        assert_int_equal(co_stack_node(&fx->stack)->nmt.state, CO_NMT_PRE_OPERATIONAL);

        /* NMT reset to node 5: the boot-up comes from 7. */
        tu_log_clear(&fx->tb);
        const uint8_t reset5[2] = {command, NODE};
        tool_send(fx, 0x000, reset5, 2);
        const uint8_t zero = 0;
        long boot = tu_log_find_id(&fx->tb, 0x707, 0);
        tu_assert_logged(&fx->tb, boot, 0x707, &zero, 1);
        assert_int_equal(tu_log_count_id(&fx->tb, 0x705), 0);
        assert_int_equal(fx->resets, 1);
        assert_int_equal(fx->reset_id, 7);
        assert_int_equal(co_line_node_id(&fx->dev_line.line), 7);
        co_lss_slave_t *slave = co_stack_lss_slave(&fx->stack);
        assert_int_equal(co_lss_slave_active_node_id(slave), 7);
        assert_int_equal(co_lss_slave_pending_node_id(slave), 7);
        uint32_t emcy_cob = 0;
        assert_true(co_od_get_u32(&fx->dev.od, 0x1014, 0, &emcy_cob));
        assert_int_equal(emcy_cob, 0x87);                 /* $NODEID default reloaded */
        /* Heartbeats as 7, SDO on 0x607/0x587, NMT for 7 taken, for 5 not. */
        tu_run_until(&fx->tb, fx->tb.now + 250u * TU_MS);
        assert_true(tu_log_count_id(&fx->tb, 0x707) >= 3);
        assert_int_equal(tu_log_count_id(&fx->tb, 0x705), 0);
        const uint8_t upload[8] = {0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0};
        tool_send(fx, 0x605, upload, 8);
        assert_int_equal(tu_log_count_id(&fx->tb, 0x585), 0);
        tool_send(fx, 0x607, upload, 8);
        const uint8_t answer[8] = {0x43, 0x00, 0x10, 0x00, 0x91, 0x01, 0x00, 0x00};
        tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, 0x587, 0), 0x587, answer, 8);
        const uint8_t start5[2] = {0x01, NODE};
        tool_send(fx, 0x000, start5, 2);
        assert_int_equal(co_stack_node(&fx->stack)->nmt.state, CO_NMT_PRE_OPERATIONAL);
        tool_send(fx, 0x000, start7, 2);
        assert_int_equal(co_stack_node(&fx->stack)->nmt.state, CO_NMT_OPERATIONAL);
        /* A second reset with nothing pending keeps 7. */
        const uint8_t reset7[2] = {command, 7};
        tu_log_clear(&fx->tb);
        tool_send(fx, 0x000, reset7, 2);
        assert_int_equal(tu_log_count_id(&fx->tb, 0x707), 1);
        assert_int_equal(fx->resets, 1);
        fx_free(fx);
    }
}

/* The application's node-id for the next reset (co_stack_set_node_id_at_reset)
 * wins over an LSS pending one; the slave then reports it as active and
 * pending, and the LSS "configured" indication stays silent (not LSS's). */
static void test_application_node_id_at_reset(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    assert_int_equal(co_stack_set_node_id_at_reset(&fx->stack, 9), CO_STACK_ERR_STATE);
    device_od(&fx->dev, NODE, true);
    co_stack_node_config_t c = config_of(fx, NODE);
    assert_int_equal(co_stack_node_init(&fx->stack, &c), CO_STACK_OK);
    assert_int_equal(co_stack_boot(&fx->stack), CO_STACK_OK);
    assert_int_equal(co_stack_set_node_id_at_reset(&fx->stack, 0), CO_STACK_ERR_ARGUMENT);
    assert_int_equal(co_stack_set_node_id_at_reset(&fx->stack, 128), CO_STACK_ERR_ARGUMENT);
    assert_true(co_lss_master_switch_global(master(fx), CO_LSS_STATE_CONFIGURATION));
    assert_true(co_lss_master_configure_node_id(master(fx), 7));
    assert_int_equal(wait_done(fx).status, CO_LSS_OK);
    assert_true(co_lss_master_switch_global(master(fx), CO_LSS_STATE_WAITING));
    assert_int_equal(co_stack_set_node_id_at_reset(&fx->stack, 9), CO_STACK_OK);
    tu_log_clear(&fx->tb);
    const uint8_t reset5[2] = {0x82, NODE};
    tool_send(fx, 0x000, reset5, 2);
    const uint8_t zero = 0;
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, 0x709, 0), 0x709, &zero, 1);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x707), 0);
    assert_int_equal(co_line_node_id(&fx->dev_line.line), 9);
    co_lss_slave_t *slave = co_stack_lss_slave(&fx->stack);
    assert_int_equal(co_lss_slave_active_node_id(slave), 9);
    assert_int_equal(co_lss_slave_pending_node_id(slave), 9);
    assert_int_equal(fx->resets, 0);
    assert_true(co_lss_master_switch_global(master(fx), CO_LSS_STATE_CONFIGURATION));
    assert_true(co_lss_master_inquire(master(fx), CO_LSS_CS_INQUIRE_NODE_ID));
    assert_int_equal(wait_done(fx).value, 9);
    /* used once: the next reset keeps 9 */
    tu_log_clear(&fx->tb);
    const uint8_t reset9[2] = {0x81, 9};
    tool_send(fx, 0x000, reset9, 2);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x709), 1);
    fx_free(fx);
}

/* Configure node-id 0 and 128..254: refused with error 1 (out of range) on
 * the wire, nothing pending; 255 is taken but a configured node keeps its
 * node-id at the reset (leaving for LSS-only operation is not implemented). */
static void test_configure_node_id_out_of_range(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    device_od(&fx->dev, NODE, true);
    co_stack_node_config_t c = config_of(fx, NODE);
    assert_int_equal(co_stack_node_init(&fx->stack, &c), CO_STACK_OK);
    assert_int_equal(co_stack_boot(&fx->stack), CO_STACK_OK);
    assert_true(co_lss_master_switch_global(master(fx), CO_LSS_STATE_CONFIGURATION));
    tu_step(&fx->tb, fx->tb.now + 1);
    const uint8_t bad[] = {0, 128, 200, 254};
    for (size_t i = 0; i < sizeof bad; i++) {
        tu_log_clear(&fx->tb);
        const uint8_t request[8] = {0x11, bad[i], 0, 0, 0, 0, 0, 0};
        tool_send(fx, CO_LSS_ID_MASTER, request, 8);
        const uint8_t refused[8] = {0x11, 0x01, 0, 0, 0, 0, 0, 0};
        tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, CO_LSS_ID_SLAVE, 0), CO_LSS_ID_SLAVE,
                         refused, 8);
        assert_int_equal(co_lss_slave_pending_node_id(co_stack_lss_slave(&fx->stack)), NODE);
    }
    /* Our master does not even send them. */
    assert_false(co_lss_master_configure_node_id(master(fx), 0));
    assert_false(co_lss_master_configure_node_id(master(fx), 128));
    /* 255: accepted, but the configured node stays 5 through a reset. */
    assert_true(co_lss_master_configure_node_id(master(fx), 255));
    assert_int_equal(wait_done(fx).status, CO_LSS_OK);
    tu_log_clear(&fx->tb);
    const uint8_t reset5[2] = {0x82, NODE};
    tool_send(fx, 0x000, reset5, 2);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x705), 1);
    assert_int_equal(co_line_node_id(&fx->dev_line.line), NODE);
    assert_int_equal(fx->resets, 0);
    fx_free(fx);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_configured_node_has_lss),
        cmocka_unit_test(test_no_lss),
        cmocka_unit_test(test_unconfigured_node),
        cmocka_unit_test(test_unconfigured_configured_before_boot),
        cmocka_unit_test(test_configured_node_new_id_at_reset),
        cmocka_unit_test(test_application_node_id_at_reset),
        cmocka_unit_test(test_configure_node_id_out_of_range),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
