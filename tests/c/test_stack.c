/* co_stack: the node assembly of the core. A device built only from
 * co_stack over a static arena boots, serves its OD (USDO on fd lines, SDO
 * on classic lines: bytes on the bus), runs its PDOs, EMCY and guarding
 * wired together; the sizing functions match what it takes; wrong use is
 * refused with a status and the part named, leaving nothing behind. */
#include "test_od_util.h"

#include "canopenfd/co_stack.h"
#include "canopenfd/co_usdo.h"

#include <stdlib.h>

enum { NODE = 5, CLIENT = 9 };

/* A small device dictionary: identity, heartbeat, store, SYNC, EMCY, one
 * RPDO and one TPDO mapping 0x2000 (U16), and a guarding pair. */
static const tu_od_row_t device_rows[] = {
    {0x1000, 0, VAR, U32, RO, 0, 4, 0x00000191, NULL, 0, 0},
    {0x1001, 0, VAR, U8, RO, 0, 1, 0, NULL, 0, 0},
    {0x1005, 0, VAR, U32, RW, 0, 4, 0x80, NULL, 0, 0},
    {0x100C, 0, VAR, U16, RW, 0, 2, 0, NULL, 0, 0},
    {0x100D, 0, VAR, U8, RW, 0, 1, 0, NULL, 0, 0},
    {0x1010, 0, ARR, U8, RO, 0, 1, 1, NULL, 0, 0},
    {0x1010, 1, ARR, U32, RW, 0, 4, 1, NULL, 0, 0},
    {0x1014, 0, VAR, U32, RW, CO_OD_NODEID_RELATIVE, 4, 0x80, NULL, 0, 0},
    {0x1017, 0, VAR, U16, RW, ST, 2, 0, NULL, 0, 0},
    {0x1018, 0, REC, U8, RO, 0, 1, 2, NULL, 0, 0},
    {0x1018, 1, REC, U32, RO, 0, 4, 0x12345678, NULL, 0, 0},
    {0x1018, 2, REC, U32, RO, 0, 4, 0x0000ABCD, NULL, 0, 0},
    {0x1400, 0, REC, U8, RO, 0, 1, 2, NULL, 0, 0},
    {0x1400, 1, REC, U32, RW, CO_OD_NODEID_RELATIVE, 4, 0x200, NULL, 0, 0},
    {0x1400, 2, REC, U8, RW, 0, 1, 255, NULL, 0, 0},
    {0x1600, 0, REC, U8, RW, 0, 1, 1, NULL, 0, 0},
    {0x1600, 1, REC, U32, RW, 0, 4, 0x20000010, NULL, 0, 0},
    {0x1800, 0, REC, U8, RO, 0, 1, 2, NULL, 0, 0},
    {0x1800, 1, REC, U32, RW, CO_OD_NODEID_RELATIVE, 4, 0x180, NULL, 0, 0},
    {0x1800, 2, REC, U8, RW, 0, 1, 255, NULL, 0, 0},
    {0x1A00, 0, REC, U8, RW, 0, 1, 1, NULL, 0, 0},
    {0x1A00, 1, REC, U32, RW, 0, 4, 0x20010010, NULL, 0, 0},
    {0x2000, 0, VAR, U16, RW, CO_OD_MAP_TPDO | CO_OD_MAP_RPDO, 2, 0, NULL, 0, 0},
    {0x2001, 0, VAR, U16, RW, CO_OD_MAP_TPDO | CO_OD_MAP_RPDO | ST, 2, 0x1234, NULL, 0, 0},
};

#define N_ROWS (sizeof device_rows / sizeof device_rows[0])

typedef struct device {
    co_od_t od;
    co_od_entry_t entries[64];
    uint8_t pool[1024];
    co_od_subscription_t subs[CO_STACK_OD_SUBSCRIPTIONS];
} device_t;

static void device_od(device_t *d, co_mode_t mode, uint8_t node_id)
{
    memset(d, 0, sizeof *d);
    co_od_init(&d->od, mode, d->entries, 64, d->pool, sizeof d->pool, d->subs,
               CO_STACK_OD_SUBSCRIPTIONS);
    tu_od_add_rows(&d->od, device_rows, N_ROWS);
    assert_true(co_od_seal(&d->od, node_id));
}

/* ------------------------------------------------------------ fixture */

typedef struct fx {
    tu_bus_t tb;
    tu_line_t dev_line;
    tu_line_t tool_line;
    device_t dev;
    co_stack_t stack;
    co_stack_arena_t arena;
    unsigned char memory[64 * 1024];   /* the arena aligns its start */
    co_stack_t tool;             /* the other end: a line with a client only */
    co_stack_arena_t tool_arena;
    unsigned char tool_memory[48 * 1024];
    tu_mem_backend_t store;
    unsigned hb_events[8];
    unsigned emcy_count;
    uint16_t last_emcy;
    unsigned pdo_received;
} fx_t;

static void on_tool_heartbeat(co_stack_t *s, uint8_t node_id, co_hb_event_t event,
                              co_nmt_state_t state, void *user)
{
    (void)s;
    (void)node_id;
    (void)state;
    fx_t *fx = user;
    if ((unsigned)event < 8) {
        fx->hb_events[event]++;
    }
}

static void on_tool_emcy(co_stack_t *s, uint8_t node_id, const co_emcy_msg_t *msg, void *user)
{
    (void)s;
    (void)node_id;
    fx_t *fx = user;
    fx->emcy_count++;
    fx->last_emcy = msg->code;
}

static const co_stack_indications_t tool_ind = {.heartbeat = on_tool_heartbeat,
                                                .emcy = on_tool_emcy};

static void on_pdo_received(co_node_t *node, uint16_t number, void *user)
{
    (void)node;
    (void)number;
    ((fx_t *)user)->pdo_received++;
}

static fx_t *fx_new(co_mode_t mode)
{
    fx_t *fx = calloc(1, sizeof *fx);
    assert_non_null(fx);
    tu_bus_init(&fx->tb, mode, mode == CO_MODE_FD);
    tu_bus_add_line(&fx->tb, &fx->dev_line);
    tu_bus_add_line(&fx->tb, &fx->tool_line);
    device_od(&fx->dev, mode, NODE);
    co_stack_arena_init(&fx->arena, fx->memory, sizeof fx->memory);
    co_stack_arena_init(&fx->tool_arena, fx->tool_memory, sizeof fx->tool_memory);
    co_stack_line_config_t tool_config = {.ind = &tool_ind, .user = fx,
                                          .guarded_nodes = 4};
    assert_int_equal(co_stack_init(&fx->tool, &fx->tool_line.line, &tool_config,
                                   co_stack_arena_allocator(&fx->tool_arena)), CO_STACK_OK);
    return fx;
}

static void fx_free(fx_t *fx)
{
    co_stack_deinit(&fx->stack);
    co_stack_deinit(&fx->tool);
    free(fx);
}

static co_node_indications_t node_ind = {.pdo_received = on_pdo_received};

static co_stack_node_config_t node_config(fx_t *fx)
{
    co_stack_node_config_t c = {.node_id = NODE, .od = &fx->dev.od,
                                .store_backend = &tu_mem_ops, .store_user = &fx->store,
                                .ind = &node_ind, .user = fx};
    return c;
}

/* The device: a line with a node serving the OD, booted. */
static void fx_device(fx_t *fx)
{
    co_stack_line_config_t config = {.heartbeat_entries = 4};
    assert_int_equal(co_stack_init(&fx->stack, &fx->dev_line.line, &config,
                                   co_stack_arena_allocator(&fx->arena)), CO_STACK_OK);
    co_stack_node_config_t nc = node_config(fx);
    assert_int_equal(co_stack_node_init(&fx->stack, &nc), CO_STACK_OK);
    assert_int_equal(co_stack_boot(&fx->stack), CO_STACK_OK);
}

/* ------------------------------------------------------------ USDO client */

typedef struct upload {
    co_usdo_request_t req;
    co_usdo_buffer_t sink;
    uint8_t data[64];
    bool done;
} upload_t;

static void upload_done(co_usdo_request_t *req)
{
    ((upload_t *)req->user)->done = true;
}

static void usdo_upload(fx_t *fx, upload_t *u, uint16_t index, uint8_t sub)
{
    memset(u, 0, sizeof *u);
    u->sink.data = u->data;
    u->sink.capacity = sizeof u->data;
    u->req = (co_usdo_request_t){.server = NODE, .index = index, .sub = sub, .upload = true,
                                 .sink = co_usdo_buffer_sink, .ctx = &u->sink,
                                 .done = upload_done, .user = u};
    co_line_set_time(&fx->tool_line.line, fx->tb.now);
    assert_int_equal(co_usdo_client_start(co_stack_usdo_client(&fx->tool), &u->req), 0);
    tu_run_until(&fx->tb, fx->tb.now + 10 * TU_MS);
    assert_true(u->done);
}

/* ------------------------------------------------------------ tests */

/* An fd device from co_stack alone: boot-up on the bus, a USDO client on
 * another line reads its identity, the answer's bytes are the CiA 1301 ones. */
static void test_fd_device_boots_and_serves_its_od(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_FD);
    fx_device(fx);
    tu_run_until(&fx->tb, 5 * TU_MS);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, 0x700 + NODE, 0), 0x700 + NODE,
                     (const uint8_t[]){0x00}, 1);
    assert_int_equal(fx->hb_events[CO_HB_BOOTUP], 1);
    assert_int_equal(co_node_state(co_stack_node(&fx->stack)), CO_NMT_PRE_OPERATIONAL);

    co_stack_client_config_t cc = {.sessions = 4, .node_id = CLIENT};
    assert_int_equal(co_stack_client_init(&fx->tool, &cc), CO_STACK_OK);
    tu_log_clear(&fx->tb);
    upload_t u;
    usdo_upload(fx, &u, 0x1018, 1);
    assert_int_equal(u.req.abort, 0);
    assert_int_equal(u.sink.size, 4);
    assert_int_equal(tu_le_get(u.data, 4), 0x12345678);
    /* the request went to 0x600 + client id with the server's node-id in byte 0,
     * the answer came on 0x580 + the server's node-id */
    long rq = tu_log_find_id(&fx->tb, 0x600 + CLIENT, 0);
    long an = tu_log_find_id(&fx->tb, 0x580 + NODE, 0);
    assert_true(rq >= 0 && an > rq);
    assert_int_equal(fx->tb.log[rq].frame.data[0], NODE);
    assert_int_equal(fx->tb.log[an].frame.data[0], CLIENT);
    fx_free(fx);
}

/* The sizing functions say exactly what the arena gave, and the
 * compile-time bound covers it. */
static void test_sizing_matches_what_is_taken(void **state)
{
    (void)state;
    for (int m = 0; m < 2; m++) {
        co_mode_t mode = m ? CO_MODE_FD : CO_MODE_CLASSIC;
        fx_t *fx = fx_new(mode);
        co_stack_line_config_t config = {.heartbeat_entries = 4, .guarded_nodes = 2};
        size_t line_need = co_stack_line_need(&fx->dev_line.line, &config);
        assert_int_equal(co_stack_init(&fx->stack, &fx->dev_line.line, &config,
                                       co_stack_arena_allocator(&fx->arena)), CO_STACK_OK);
        assert_int_equal(fx->arena.used, line_need);
        co_stack_node_config_t nc = node_config(fx);
        size_t node_need = co_stack_node_need(&fx->dev_line.line, &nc);
        assert_int_equal(co_stack_node_init(&fx->stack, &nc), CO_STACK_OK);
        assert_int_equal(fx->arena.used, line_need + node_need);
        uint32_t channels = 0, items = 0;
        assert_true(co_pdo_need(&fx->dev.od, &channels, &items));
        assert_int_equal(channels, 2);
        size_t bound = CO_STACK_NODE_MEMORY(2, items, 4, co_store_image_need(&fx->dev.od),
                                            m ? CO_STACK_DEFAULT_SERVER_SESSIONS : 1);
        assert_true(node_need <= bound);
        co_stack_client_config_t cc = {.sessions = 3, .node_id = CLIENT};
        size_t client_need = co_stack_client_need(&fx->dev_line.line, &cc);
        assert_int_equal(co_stack_client_init(&fx->stack, &cc), CO_STACK_OK);
        assert_int_equal(fx->arena.used, line_need + node_need + client_need);
        fx_free(fx);
    }
}

/* Out of memory half way: the status and the part say so, the line is as
 * before (no node-id, no OD hooks, arena back), and a later try works. */
static void test_no_memory_leaves_nothing_behind(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_FD);
    co_stack_line_config_t config = {.heartbeat_entries = 4};
    size_t line_need = co_stack_line_need(&fx->dev_line.line, &config);
    co_stack_node_config_t nc = node_config(fx);
    size_t node_need = co_stack_node_need(&fx->dev_line.line, &nc);
    co_stack_arena_init(&fx->arena, fx->memory, line_need + node_need - 8);
    assert_int_equal(co_stack_init(&fx->stack, &fx->dev_line.line, &config,
                                   co_stack_arena_allocator(&fx->arena)), CO_STACK_OK);
    uint8_t subs_before = fx->dev.od.sub_count;
    assert_int_equal(co_stack_node_init(&fx->stack, &nc), CO_STACK_ERR_NO_MEMORY);
    assert_int_equal(co_stack_failed_part(&fx->stack), CO_STACK_PART_PDO);
    assert_string_equal(co_stack_part_name(CO_STACK_PART_PDO), "PDO service");
    assert_null(co_stack_node(&fx->stack));
    assert_null(co_stack_usdo_server(&fx->stack));
    assert_int_equal(co_line_node_id(&fx->dev_line.line), 0);
    assert_int_equal(fx->dev.od.sub_count, subs_before);
    assert_int_equal(fx->arena.used, line_need);
    /* without a store the node fits */
    nc.store_backend = NULL;
    assert_int_equal(co_stack_node_init(&fx->stack, &nc), CO_STACK_OK);
    assert_non_null(co_stack_pdo(&fx->stack));
    fx_free(fx);
}

/* Wrong use is refused with a status naming the problem. */
static void test_wrong_use_is_refused(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_FD);
    co_stack_allocator_t none = {0};
    assert_int_equal(co_stack_init(&fx->stack, &fx->dev_line.line, NULL, none),
                     CO_STACK_ERR_ARGUMENT);
    assert_int_equal(co_stack_init(&fx->stack, &fx->dev_line.line, NULL,
                                   co_stack_arena_allocator(&fx->arena)), CO_STACK_OK);
    assert_int_equal(co_stack_boot(&fx->stack), CO_STACK_ERR_STATE);   /* no node yet */
    co_stack_node_config_t nc = node_config(fx);
    nc.node_id = 0;
    assert_int_equal(co_stack_node_init(&fx->stack, &nc), CO_STACK_ERR_ARGUMENT);
    nc = node_config(fx);
    nc.od = NULL;                 /* a store needs an OD */
    assert_int_equal(co_stack_node_init(&fx->stack, &nc), CO_STACK_ERR_ARGUMENT);
    device_t classic;
    device_od(&classic, CO_MODE_CLASSIC, NODE);
    nc = node_config(fx);
    nc.od = &classic.od;          /* a classic OD on an fd line */
    assert_int_equal(co_stack_node_init(&fx->stack, &nc), CO_STACK_ERR_OD);
    device_t unsealed;
    memset(&unsealed, 0, sizeof unsealed);
    co_od_init(&unsealed.od, CO_MODE_FD, unsealed.entries, 64, unsealed.pool,
               sizeof unsealed.pool, unsealed.subs, CO_STACK_OD_SUBSCRIPTIONS);
    nc.od = &unsealed.od;
    assert_int_equal(co_stack_node_init(&fx->stack, &nc), CO_STACK_ERR_STATE);
    nc = node_config(fx);
    assert_int_equal(co_stack_node_init(&fx->stack, &nc), CO_STACK_OK);
    assert_int_equal(co_stack_node_init(&fx->stack, &nc), CO_STACK_ERR_STATE);
    assert_int_equal(co_stack_failed_part(&fx->stack), CO_STACK_PART_NODE);
    co_stack_client_config_t cc = {.sessions = 2, .node_id = 0};   /* fd needs a client id */
    assert_int_equal(co_stack_client_init(&fx->stack, &cc), CO_STACK_ERR_ARGUMENT);
    cc.node_id = CLIENT;
    assert_int_equal(co_stack_client_init(&fx->stack, &cc), CO_STACK_OK);
    assert_int_equal(co_stack_client_init(&fx->stack, &cc), CO_STACK_ERR_STATE);
    fx_free(fx);
}

/* The wiring: operational starts the PDOs (a TPDO on its event, an RPDO
 * applied to the OD), a lost heartbeat of a consumed node raises EMCY 0x8130
 * that the tool hears. */
static void test_services_are_wired(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_FD);
    fx_device(fx);
    co_od_t *od = co_stack_od(&fx->stack);
    /* consume the tool's heartbeat: 0x1016 is not in this OD, so by the API */
    assert_int_equal(co_hb_consumer_watch(co_stack_hb_consumer(&fx->stack), 3, 50),
                     CO_HB_CONFIG_OK);
    assert_true(co_emcy_consumer_watch(co_stack_emcy_consumer(&fx->tool), NODE));
    tu_run_until(&fx->tb, 2 * TU_MS);
    co_nmt_apply(&co_stack_node(&fx->stack)->nmt, CO_NMT_CMD_START);
    tu_log_clear(&fx->tb);
    tu_run_until(&fx->tb, 4 * TU_MS);
    /* TPDO 1 (0x180 + node) carries 0x2001 = 0x1234 when triggered */
    assert_int_equal(co_pdo_trigger_object(co_stack_pdo(&fx->stack), 0x2001, 0), 1);
    tu_run_until(&fx->tb, 6 * TU_MS);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, 0x180 + NODE, 0), 0x180 + NODE,
                     (const uint8_t[]){0x34, 0x12}, 2);
    /* RPDO 1 (0x200 + node) writes 0x2000 */
    co_line_set_time(&fx->tool_line.line, fx->tb.now);
    assert_true(co_line_send(&fx->tool_line.line, 0x200 + NODE, (const uint8_t[]){0x22, 0x11},
                             2));
    tu_run_until(&fx->tb, 8 * TU_MS);
    uint16_t value = 0;
    assert_true(co_od_get_u16(od, 0x2000, 0, &value));
    assert_int_equal(value, 0x1122);
    assert_int_equal(fx->pdo_received, 1);
    /* node 3 boots, sends one heartbeat, then falls silent: 0x8130 */
    co_line_set_time(&fx->tool_line.line, fx->tb.now);
    assert_true(co_line_send(&fx->tool_line.line, 0x703, (const uint8_t[]){0x00}, 1));
    assert_true(co_line_send(&fx->tool_line.line, 0x703, (const uint8_t[]){0x05}, 1));
    tu_step(&fx->tb, fx->tb.now);   /* delivered now: the loss counts from here */
    tu_run_until(&fx->tb, 100 * TU_MS);
    assert_int_equal(fx->emcy_count, 1);
    assert_int_equal(fx->last_emcy, 0x8130);
    fx_free(fx);
}

/* A classic device: the SDO server answers on the default channel (bytes),
 * the guarding slave answers a remote frame, the master of the tool guards it. */
static void test_classic_device_serves_sdo_and_guarding(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC);
    fx_device(fx);
    assert_non_null(co_stack_sdo_server(&fx->stack));
    assert_non_null(co_stack_guard_slave(&fx->stack));
    assert_null(co_stack_guard_master(&fx->stack));   /* none asked for */
    assert_non_null(co_stack_guard_master(&fx->tool));
    tu_run_until(&fx->tb, 2 * TU_MS);
    tu_log_clear(&fx->tb);
    /* expedited upload request of 0x1018:02 */
    co_line_set_time(&fx->tool_line.line, fx->tb.now);
    assert_true(co_line_send(&fx->tool_line.line, 0x600 + NODE,
                             (const uint8_t[]){0x40, 0x18, 0x10, 0x02, 0, 0, 0, 0}, 8));
    tu_run_until(&fx->tb, 4 * TU_MS);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, 0x580 + NODE, 0), 0x580 + NODE,
                     (const uint8_t[]){0x43, 0x18, 0x10, 0x02, 0xCD, 0xAB, 0, 0}, 8);
    /* the tool guards the device: remote frame, answer with state 127 | toggle 0 */
    tu_log_clear(&fx->tb);
    co_line_set_time(&fx->tool_line.line, fx->tb.now);
    assert_int_equal(co_guard_master_guard(co_stack_guard_master(&fx->tool), NODE, 50, 3),
                     CO_GUARD_OK);
    tu_run_until(&fx->tb, fx->tb.now + 2 * TU_MS);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, 0x700 + NODE, 1), 0x700 + NODE,
                     (const uint8_t[]){0x7F}, 1);
    fx_free(fx);
}

/* The tool sends one frame to the device and the bus runs 2 ms. */
static void tool_send(fx_t *fx, uint32_t id, const uint8_t *data, uint8_t len)
{
    co_line_set_time(&fx->tool_line.line, fx->tb.now);
    assert_true(co_line_send(&fx->tool_line.line, id, data, len));
    tu_run_until(&fx->tb, fx->tb.now + 2 * TU_MS);
}

static void tool_nmt(fx_t *fx, uint8_t command)
{
    tool_send(fx, 0x000, (const uint8_t[]){command, NODE}, 2);
}

/* RPDO 1 turned into a DAM MPDO through its OD (the mapping procedure): a
 * DAM frame for the node writes 0x2000; one for an object the device
 * lacks writes nothing and reaches the tool as EMCY 0x8230 (RPDO 1 in the
 * manufacturer bytes) followed by its error reset, the line still working. */
static void put_u32(co_od_t *od, uint16_t index, uint8_t sub, uint32_t v)
{
    uint8_t b[4] = {(uint8_t)v, (uint8_t)(v >> 8), (uint8_t)(v >> 16), (uint8_t)(v >> 24)};
    assert_int_equal(co_od_put(od, index, sub, b, 4), 0);
}

static void test_mpdo_dam_on_a_stack_node(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC);
    fx_device(fx);
    co_od_t *od = co_stack_od(&fx->stack);
    assert_non_null(co_stack_mpdo(&fx->stack));
    assert_true(co_emcy_consumer_watch(co_stack_emcy_consumer(&fx->tool), NODE));
    put_u32(od, 0x1400, 1, 0x80000000u | (0x200 + NODE));
    assert_int_equal(co_od_put(od, 0x1600, 0, (const uint8_t[]){CO_PDO_MAP_DAM}, 1), 0);
    put_u32(od, 0x1400, 1, 0x200 + NODE);
    assert_int_equal(co_pdo_channel(co_stack_pdo(&fx->stack), true, 1)->mpdo, CO_PDO_MAP_DAM);
    tu_run_until(&fx->tb, 2 * TU_MS);
    co_nmt_apply(&co_stack_node(&fx->stack)->nmt, CO_NMT_CMD_START);
    tu_run_until(&fx->tb, 4 * TU_MS);
    tu_log_clear(&fx->tb);
    tool_send(fx, 0x200 + NODE, (const uint8_t[]){0x80 | NODE, 0x00, 0x20, 0x00, 0x22, 0x11, 0, 0},
              8);
    uint16_t value = 0;
    assert_true(co_od_get_u16(od, 0x2000, 0, &value));
    assert_int_equal(value, 0x1122);
    assert_int_equal(fx->emcy_count, 0);
    tool_send(fx, 0x200 + NODE, (const uint8_t[]){0x80, 0x00, 0x30, 0x00, 0x01, 0, 0, 0}, 8);
    tu_run_until(&fx->tb, fx->tb.now + 2 * TU_MS);
    long k = tu_log_find_id(&fx->tb, 0x80 + NODE, 0);
    /* EMCY: code 0x8230, error register 0x11 (generic | communication), RPDO 1 */
    tu_assert_logged(&fx->tb, k, 0x80 + NODE,
                     (const uint8_t[]){0x30, 0x82, 0x11, 0x01, 0x00, 0, 0, 0}, 8);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, 0x80 + NODE, 1), 0x80 + NODE,
                     (const uint8_t[]){0x00, 0x00, 0x00, 0, 0, 0, 0, 0}, 8);
    assert_int_equal(fx->emcy_count, 2);
    assert_int_equal(co_mpdo_stats(co_stack_mpdo(&fx->stack))->rx_refused, 1);
    /* nothing wedged: the next DAM is applied */
    tool_send(fx, 0x200 + NODE, (const uint8_t[]){0x80, 0x00, 0x20, 0x00, 0x44, 0x33, 0, 0}, 8);
    assert_true(co_od_get_u16(od, 0x2000, 0, &value));
    assert_int_equal(value, 0x3344);
    fx_free(fx);
}

/* A node made without an OD (NMT and heartbeat only) still answers every
 * SDO / USDO request at once, "object does not exist" (0x06020000 / 0x33)
 * with the request's multiplexer, instead of leaving the client to its
 * timeout; the memory its server takes is in co_stack_node_need and
 * within CO_STACK_NODE_MEMORY. */
static void test_node_without_od_answers_no_such_object(void **state)
{
    (void)state;
    for (int m = 0; m < 2; m++) {
        co_mode_t mode = m ? CO_MODE_FD : CO_MODE_CLASSIC;
        fx_t *fx = fx_new(mode);
        assert_int_equal(co_stack_init(&fx->stack, &fx->dev_line.line, NULL,
                                       co_stack_arena_allocator(&fx->arena)), CO_STACK_OK);
        co_stack_node_config_t nc = {.node_id = NODE};
        size_t before = fx->arena.used;
        size_t need = co_stack_node_need(&fx->dev_line.line, &nc);
        assert_int_equal(co_stack_node_init(&fx->stack, &nc), CO_STACK_OK);
        assert_int_equal(fx->arena.used - before, need);
        assert_true(need <= CO_STACK_NODE_MEMORY(0, 0, 0, 0,
                                                 m ? CO_STACK_DEFAULT_SERVER_SESSIONS : 1));
        assert_null(co_stack_od(&fx->stack));
        assert_int_equal(co_stack_boot(&fx->stack), CO_STACK_OK);
        tu_run_until(&fx->tb, 2 * TU_MS);
        tu_log_clear(&fx->tb);
        if (mode == CO_MODE_CLASSIC) {
            tool_send(fx, 0x600 + NODE, (const uint8_t[]){0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}, 8);
            tool_send(fx, 0x600 + NODE,
                      (const uint8_t[]){0x2B, 0x17, 0x10, 0x00, 0xE8, 0x03, 0, 0}, 8);
            tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, 0x580 + NODE, 0), 0x580 + NODE,
                             (const uint8_t[]){0x80, 0x00, 0x10, 0x00, 0x00, 0x00, 0x02, 0x06},
                             8);
            tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, 0x580 + NODE, 1), 0x580 + NODE,
                             (const uint8_t[]){0x80, 0x17, 0x10, 0x00, 0x00, 0x00, 0x02, 0x06},
                             8);
        } else {
            /* [dest, 0x11 upload, session 5, sub 0, index 0x1000] */
            tool_send(fx, 0x600 + CLIENT, (const uint8_t[]){NODE, 0x11, 5, 0x00, 0x00, 0x10}, 6);
            tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, 0x580 + NODE, 0), 0x580 + NODE,
                             (const uint8_t[]){CLIENT, 0x7F, 5, 0x00, 0x00, 0x10, 0x33}, 7);
        }
        assert_int_equal(tu_log_count_id(&fx->tb, 0x580 + NODE), m ? 1 : 2);
        fx_free(fx);
    }
}

/* CiA 301: no SDO in stopped. A stopped classic device ignores SDO requests
 * (no frame on 0x580 + id, counted), a segmented download open when it
 * stopped ends without an abort frame, and back in pre-operational it serves
 * again: the segment of the ended transfer gets 0x05040001, a new request its
 * answer. */
static void test_stopped_classic_device_serves_no_sdo(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC);
    fx_device(fx);
    tu_run_until(&fx->tb, 2 * TU_MS);
    co_sdo_server_t *server = co_stack_sdo_server(&fx->stack);
    /* segmented download of 2 bytes to 0x2000 opened: answered 0x60 */
    tu_log_clear(&fx->tb);
    tool_send(fx, 0x600 + NODE, (const uint8_t[]){0x21, 0x00, 0x20, 0x00, 2, 0, 0, 0}, 8);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, 0x580 + NODE, 0), 0x580 + NODE,
                     (const uint8_t[]){0x60, 0x00, 0x20, 0x00, 0, 0, 0, 0}, 8);
    tool_nmt(fx, 0x02);   /* stop */
    assert_int_equal(co_node_state(co_stack_node(&fx->stack)), CO_NMT_STOPPED);
    assert_int_equal(server->stats.closed_by_state, 1);
    assert_int_equal(co_sdo_server_active(server), 0);
    tu_log_clear(&fx->tb);
    tool_send(fx, 0x600 + NODE, (const uint8_t[]){0x40, 0x18, 0x10, 0x02, 0, 0, 0, 0}, 8);
    tool_send(fx, 0x600 + NODE, (const uint8_t[]){0x0B, 0x34, 0x12, 0, 0, 0, 0, 0}, 8);
    tu_run_until(&fx->tb, fx->tb.now + 2000 * TU_MS);   /* past any idle timeout */
    assert_int_equal(tu_log_count_id(&fx->tb, 0x580 + NODE), 0);
    assert_int_equal(server->stats.rx_not_serving, 2);
    assert_int_equal(server->stats.timeouts, 0);
    tool_nmt(fx, 0x80);   /* enter pre-operational */
    tu_log_clear(&fx->tb);
    tool_send(fx, 0x600 + NODE, (const uint8_t[]){0x0B, 0x34, 0x12, 0, 0, 0, 0, 0}, 8);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, 0x580 + NODE, 0), 0x580 + NODE,
                     (const uint8_t[]){0x80, 0, 0, 0, 0x01, 0x00, 0x04, 0x05}, 8);
    tool_send(fx, 0x600 + NODE, (const uint8_t[]){0x40, 0x18, 0x10, 0x02, 0, 0, 0, 0}, 8);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, 0x580 + NODE, 1), 0x580 + NODE,
                     (const uint8_t[]){0x43, 0x18, 0x10, 0x02, 0xCD, 0xAB, 0, 0}, 8);
    fx_free(fx);
}

/* The same for USDO on an fd device: a segmented download (0x02) open when it
 * stopped ends silently, requests while stopped are not answered, and in
 * pre-operational the stale segment gets abort 0x21 (no session) and a new
 * upload its answer. */
static void test_stopped_fd_device_serves_no_usdo(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_FD);
    fx_device(fx);
    tu_run_until(&fx->tb, 2 * TU_MS);
    co_usdo_server_t *server = co_stack_usdo_server(&fx->stack);
    tu_log_clear(&fx->tb);
    /* [dest, 0x02 initiate, session 4, sub 0, index 0x2000, UNSIGNED16, 0, size 2] */
    tool_send(fx, 0x600 + CLIENT, (const uint8_t[]){NODE, 0x02, 4, 0x00, 0x00, 0x20, 0x06, 0,
                                                    2, 0, 0, 0}, 12);
    long answer = tu_log_find_id(&fx->tb, 0x580 + NODE, 0);
    assert_true(answer >= 0);
    assert_int_equal(fx->tb.log[answer].frame.data[1], 0x22);
    tool_nmt(fx, 0x02);
    assert_int_equal(co_node_state(co_stack_node(&fx->stack)), CO_NMT_STOPPED);
    assert_int_equal(server->stats.closed_by_state, 1);
    assert_int_equal(co_usdo_server_active(server), 0);
    tu_log_clear(&fx->tb);
    tool_send(fx, 0x600 + CLIENT, (const uint8_t[]){NODE, 0x11, 5, 0x01, 0x18, 0x10}, 6);
    /* [dest, 0x04 last segment, session 4, 2 bytes, data] */
    tool_send(fx, 0x600 + CLIENT, (const uint8_t[]){NODE, 0x04, 4, 2, 0x34, 0x12}, 6);
    tu_run_until(&fx->tb, fx->tb.now + 2000 * TU_MS);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x580 + NODE), 0);
    assert_int_equal(server->stats.rx_not_serving, 2);
    assert_int_equal(server->stats.timeouts, 0);
    tool_nmt(fx, 0x80);
    tu_log_clear(&fx->tb);
    tool_send(fx, 0x600 + CLIENT, (const uint8_t[]){NODE, 0x04, 4, 2, 0x34, 0x12}, 6);
    answer = tu_log_find_id(&fx->tb, 0x580 + NODE, 0);
    assert_true(answer >= 0);
    assert_int_equal(fx->tb.log[answer].frame.data[1], 0x7F);
    assert_int_equal(fx->tb.log[answer].frame.data[6], 0x21);
    tool_send(fx, 0x600 + CLIENT, (const uint8_t[]){NODE, 0x11, 5, 0x01, 0x18, 0x10}, 6);
    answer = tu_log_find_id(&fx->tb, 0x580 + NODE, 1);
    assert_true(answer >= 0);
    assert_int_equal(fx->tb.log[answer].frame.data[1], 0x31);
    assert_int_equal(tu_le_get(fx->tb.log[answer].frame.data + 8, 4), 0x12345678);
    fx_free(fx);
}

/* A run-time allocator (malloc-backed) gets every block back. */
typedef struct counting {
    long live;
    long calls;
} counting_t;

static void *counting_allocate(void *user, size_t size)
{
    counting_t *c = user;
    c->calls++;
    c->live++;
    return malloc(size);
}

static void counting_release(void *user, void *memory, size_t size)
{
    (void)size;
    ((counting_t *)user)->live--;
    free(memory);
}

static void test_allocator_hook_gets_everything_back(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC);
    counting_t counting = {0};
    co_stack_allocator_t hook = {counting_allocate, counting_release, &counting};
    co_stack_line_config_t config = {.guarded_nodes = 8};
    assert_int_equal(co_stack_init(&fx->stack, &fx->dev_line.line, &config, hook), CO_STACK_OK);
    co_stack_node_config_t nc = node_config(fx);
    assert_int_equal(co_stack_node_init(&fx->stack, &nc), CO_STACK_OK);
    co_stack_client_config_t cc = {.sessions = 4};
    assert_int_equal(co_stack_client_init(&fx->stack, &cc), CO_STACK_OK);
    assert_true(counting.live > 5);
    co_stack_node_deinit(&fx->stack);   /* takes the OD-bound client along */
    assert_null(co_stack_sdo_client(&fx->stack));
    co_stack_deinit(&fx->stack);
    assert_int_equal(counting.live, 0);
    fx_free(fx);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_fd_device_boots_and_serves_its_od),
        cmocka_unit_test(test_sizing_matches_what_is_taken),
        cmocka_unit_test(test_node_without_od_answers_no_such_object),
        cmocka_unit_test(test_no_memory_leaves_nothing_behind),
        cmocka_unit_test(test_wrong_use_is_refused),
        cmocka_unit_test(test_services_are_wired),
        cmocka_unit_test(test_mpdo_dam_on_a_stack_node),
        cmocka_unit_test(test_classic_device_serves_sdo_and_guarding),
        cmocka_unit_test(test_stopped_classic_device_serves_no_sdo),
        cmocka_unit_test(test_stopped_fd_device_serves_no_usdo),
        cmocka_unit_test(test_allocator_hook_gets_everything_back),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
