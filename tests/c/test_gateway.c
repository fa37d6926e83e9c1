/* co_gateway: one device on two lines, a classic line (network 1) and an
 * fd line (network 2), each with its own node (node-id 1) and OD. Checked on
 * the wire: PDO forwarding of 0xB000..0xBFFF both ways (a 6-byte classic
 * RPDO becomes an fd TPDO, a 16-byte fd RPDO two classic TPDOs), the mapping
 * refusals as SDO abort frames, EMCY routing per 0x1F2F re-encoded for the
 * target line, the 0x1F2C route table with its loop refusal and the loop
 * reported when loaded values form one; faults: a lost RPDO, a target line
 * not operational, a network no line carries. */
#include "test_od_util.h"

#include "canopenfd/co_gateway.h"
#include "canopenfd/co_stack.h"

#include <stdlib.h>

enum { GW_NODE = 1, DEV_A = 5, DEV_B = 6, NET_A = 1, NET_B = 2 };

#define MAP TPDO_RPDO
#define TPDO_RPDO (CO_OD_MAP_TPDO | CO_OD_MAP_RPDO)
#define OS CO_TYPE_OCTET_STRING

/* Both lines: identity, EMCY, 0x1028 (nodes 1..7), 0x1F2C (networks
 * 1..10), 0x1F2F (nodes 1..7) and the forwarded objects. */
static const tu_od_row_t common_rows[] = {
    {0x1000, 0, VAR, U32, RO, 0, 4, 0, NULL, 0, 0},
    {0x1001, 0, VAR, U8, RO, 0, 1, 0, NULL, 0, 0},
    {0x1014, 0, VAR, U32, RW, 0, 4, 0x81, NULL, 0, 0},
    {0x1017, 0, VAR, U16, RW, 0, 2, 0, NULL, 0, 0},
    {0x1028, 0, ARR, U8, RO, 0, 1, 7, NULL, 0, 0},
    {0x1028, 1, ARR, U32, RW, 0, 4, 0x80000000, NULL, 0, 0},
    {0x1028, 2, ARR, U32, RW, 0, 4, 0x80000000, NULL, 0, 0},
    {0x1028, 3, ARR, U32, RW, 0, 4, 0x80000000, NULL, 0, 0},
    {0x1028, 4, ARR, U32, RW, 0, 4, 0x80000000, NULL, 0, 0},
    {0x1028, 5, ARR, U32, RW, 0, 4, 0x85, NULL, 0, 0},
    {0x1028, 6, ARR, U32, RW, 0, 4, 0x86, NULL, 0, 0},
    {0x1028, 7, ARR, U32, RW, 0, 4, 0x80000000, NULL, 0, 0},
    {0x1F2C, 0, ARR, U8, RO, 0, 1, 10, NULL, 0, 0},
    {0x1F2C, 1, ARR, U32, RW, 0, 4, 0, NULL, 0, 0},
    {0x1F2C, 2, ARR, U32, RW, 0, 4, 0, NULL, 0, 0},
    {0x1F2C, 3, ARR, U32, RW, 0, 4, 0, NULL, 0, 0},
    {0x1F2C, 4, ARR, U32, RW, 0, 4, 0, NULL, 0, 0},
    {0x1F2C, 5, ARR, U32, RW, 0, 4, 0, NULL, 0, 0},
    {0x1F2C, 6, ARR, U32, RW, 0, 4, 0, NULL, 0, 0},
    {0x1F2C, 7, ARR, U32, RW, 0, 4, 0, NULL, 0, 0},
    {0x1F2C, 8, ARR, U32, RW, 0, 4, 0, NULL, 0, 0},
    {0x1F2C, 9, ARR, U32, RW, 0, 4, 0, NULL, 0, 0},
    {0x1F2C, 10, ARR, U32, RW, 0, 4, 0, NULL, 0, 0},
    {0x1F2F, 0, ARR, U8, RO, 0, 1, 7, NULL, 0, 0},
    {0x1F2F, 1, ARR, U32, RW, 0, 4, 0, NULL, 0, 0},
    {0x1F2F, 2, ARR, U32, RW, 0, 4, 0, NULL, 0, 0},
    {0x1F2F, 3, ARR, U32, RW, 0, 4, 0, NULL, 0, 0},
    {0x1F2F, 4, ARR, U32, RW, 0, 4, 0, NULL, 0, 0},
    {0x1F2F, 5, ARR, U32, RW, 0, 4, 0, NULL, 0, 0},
    {0x1F2F, 6, ARR, U32, RW, 0, 4, 0, NULL, 0, 0},
    {0x1F2F, 7, ARR, U32, RW, 0, 4, 0, NULL, 0, 0},
    {0xB000, 0, ARR, U8, RO, 0, 1, 2, NULL, 0, 0},
    {0xB000, 1, ARR, U16, RW, MAP, 2, 0, NULL, 0, 0},
    {0xB000, 2, ARR, U32, RW, MAP, 4, 0, NULL, 0, 0},
    {0xB001, 0, ARR, U8, RO, 0, 1, 4, NULL, 0, 0},
    {0xB001, 1, ARR, U32, RW, MAP, 4, 0, NULL, 0, 0},
    {0xB001, 2, ARR, U32, RW, MAP, 4, 0, NULL, 0, 0},
    {0xB001, 3, ARR, U32, RW, MAP, 4, 0, NULL, 0, 0},
    {0xB001, 4, ARR, U32, RW, MAP, 4, 0, NULL, 0, 0},
    {0xB004, 0, VAR, U16, RW, MAP, 2, 0, NULL, 0, 0},
    /* TPDO3: disabled, empty: the mapping-refusal tests write it */
    {0x1802, 0, REC, U8, RO, 0, 1, 2, NULL, 0, 0},
    {0x1802, 1, REC, U32, RW, 0, 4, 0x80000381, NULL, 0, 0},
    {0x1802, 2, REC, U8, RW, 0, 1, 255, NULL, 0, 0},
    {0x1A02, 0, REC, U8, RW, 0, 1, 0, NULL, 0, 0},
    {0x1A02, 1, REC, U32, RW, 0, 4, 0, NULL, 0, 0},
    {0x1A02, 2, REC, U32, RW, 0, 4, 0, NULL, 0, 0},
};

/* Classic line: RPDO1 from device 5 (0xB000:01 U16, :02 U32: 6 bytes);
 * TPDO1 and TPDO2 each two U32 of 0xB001 (the fd RPDO's 16 bytes split). */
static const tu_od_row_t classic_rows[] = {
    {0x1400, 0, REC, U8, RO, 0, 1, 2, NULL, 0, 0},
    {0x1400, 1, REC, U32, RW, 0, 4, 0x185, NULL, 0, 0},
    {0x1400, 2, REC, U8, RW, 0, 1, 255, NULL, 0, 0},
    {0x1600, 0, REC, U8, RW, 0, 1, 2, NULL, 0, 0},
    {0x1600, 1, REC, U32, RW, 0, 4, 0xB0000110, NULL, 0, 0},
    {0x1600, 2, REC, U32, RW, 0, 4, 0xB0000220, NULL, 0, 0},
    {0x1800, 0, REC, U8, RO, 0, 1, 2, NULL, 0, 0},
    {0x1800, 1, REC, U32, RW, 0, 4, 0x181, NULL, 0, 0},
    {0x1800, 2, REC, U8, RW, 0, 1, 255, NULL, 0, 0},
    {0x1801, 0, REC, U8, RO, 0, 1, 2, NULL, 0, 0},
    {0x1801, 1, REC, U32, RW, 0, 4, 0x281, NULL, 0, 0},
    {0x1801, 2, REC, U8, RW, 0, 1, 255, NULL, 0, 0},
    {0x1A00, 0, REC, U8, RW, 0, 1, 2, NULL, 0, 0},
    {0x1A00, 1, REC, U32, RW, 0, 4, 0xB0010120, NULL, 0, 0},
    {0x1A00, 2, REC, U32, RW, 0, 4, 0xB0010220, NULL, 0, 0},
    {0x1A01, 0, REC, U8, RW, 0, 1, 2, NULL, 0, 0},
    {0x1A01, 1, REC, U32, RW, 0, 4, 0xB0010320, NULL, 0, 0},
    {0x1A01, 2, REC, U32, RW, 0, 4, 0xB0010420, NULL, 0, 0},
    /* the same object as the fd line, another type: mapping it is refused */
    {0xB003, 0, VAR, U16, RW, MAP, 2, 0, NULL, 0, 0},
    /* bigger than a classic PDO */
    {0xB005, 0, VAR, OS, RW, MAP, 16, 0, "", 0, 0},
};

/* fd line: RPDO1 from device 6 (0xB001:01..04: 16 bytes); TPDO1 0xB000:01
 * and :02 (6 bytes). */
static const tu_od_row_t fd_rows[] = {
    {0x1400, 0, REC, U8, RO, 0, 1, 2, NULL, 0, 0},
    {0x1400, 1, REC, U32, RW, 0, 4, 0x206, NULL, 0, 0},
    {0x1400, 2, REC, U8, RW, 0, 1, 255, NULL, 0, 0},
    {0x1600, 0, REC, U8, RW, 0, 1, 4, NULL, 0, 0},
    {0x1600, 1, REC, U32, RW, 0, 4, 0xB0010120, NULL, 0, 0},
    {0x1600, 2, REC, U32, RW, 0, 4, 0xB0010220, NULL, 0, 0},
    {0x1600, 3, REC, U32, RW, 0, 4, 0xB0010320, NULL, 0, 0},
    {0x1600, 4, REC, U32, RW, 0, 4, 0xB0010420, NULL, 0, 0},
    {0x1800, 0, REC, U8, RO, 0, 1, 2, NULL, 0, 0},
    {0x1800, 1, REC, U32, RW, 0, 4, 0x181, NULL, 0, 0},
    {0x1800, 2, REC, U8, RW, 0, 1, 255, NULL, 0, 0},
    {0x1A00, 0, REC, U8, RW, 0, 1, 2, NULL, 0, 0},
    {0x1A00, 1, REC, U32, RW, 0, 4, 0xB0000110, NULL, 0, 0},
    {0x1A00, 2, REC, U32, RW, 0, 4, 0xB0000220, NULL, 0, 0},
    {0xB003, 0, VAR, U32, RW, MAP, 4, 0, NULL, 0, 0},
};

#define ROWS(r) (sizeof(r) / sizeof((r)[0]))
enum { SUBS = CO_STACK_OD_SUBSCRIPTIONS + 4 };

typedef struct side {
    tu_bus_t tb;
    tu_line_t gw_line;           /* the gateway's line */
    tu_line_t dev_line;          /* the devices: raw frames */
    co_od_t od;
    co_od_entry_t entries[128];
    uint8_t pool[2048];
    co_od_subscription_t subs[SUBS];
    co_stack_t stack;
    co_stack_arena_t arena;
    unsigned char memory[64 * 1024];
} side_t;

typedef struct fx {
    side_t a;                    /* classic, network 1 */
    side_t b;                    /* fd, network 2 */
    co_gateway_t gw;
    unsigned loops;
    uint8_t loop_net;
    unsigned refused;
    bool drop_next_rpdo;
} fx_t;

static void side_init(side_t *s, co_mode_t mode, const tu_od_row_t *rows, size_t n)
{
    tu_bus_init(&s->tb, mode, mode == CO_MODE_FD);
    tu_bus_add_line(&s->tb, &s->gw_line);
    tu_bus_add_line(&s->tb, &s->dev_line);
    co_od_init(&s->od, mode, s->entries, 128, s->pool, sizeof s->pool, s->subs, SUBS);
    tu_od_add_rows(&s->od, common_rows, ROWS(common_rows));
    tu_od_add_rows(&s->od, rows, n);
    assert_true(co_od_seal(&s->od, GW_NODE));
    co_stack_arena_init(&s->arena, s->memory, sizeof s->memory);
    co_stack_line_config_t lc = {.heartbeat_entries = 4};
    assert_int_equal(co_stack_init(&s->stack, &s->gw_line.line, &lc,
                                   co_stack_arena_allocator(&s->arena)), CO_STACK_OK);
    co_stack_node_config_t nc = {.node_id = GW_NODE, .od = &s->od};
    assert_int_equal(co_stack_node_init(&s->stack, &nc), CO_STACK_OK);
    assert_int_equal(co_stack_boot(&s->stack), CO_STACK_OK);
}

static void on_event(co_gateway_t *gw, co_gateway_event_t event, uint8_t net, uint32_t code,
                     void *user)
{
    (void)gw;
    (void)code;
    fx_t *fx = user;
    if (event == CO_GATEWAY_EV_ROUTE_LOOP) {
        fx->loops++;
        fx->loop_net = net;
    } else if (event == CO_GATEWAY_EV_ROUTE_REFUSED) {
        fx->refused++;
    }
}

/* Carry frames on both buses until neither moves (a frame heard on one may
 * make the gateway send on the other). */
static void settle(fx_t *fx)
{
    for (int round = 0; round < 4; round++) {
        tu_step(&fx->a.tb, fx->a.tb.now);
        tu_step(&fx->b.tb, fx->b.tb.now);
    }
}

static void send(side_t *s, uint32_t id, const uint8_t *data, size_t len)
{
    assert_true(co_line_send(&s->dev_line.line, id, data, len));
}

static uint8_t drop_rpdo(const co_frame_t *frame, void *user)
{
    fx_t *fx = user;
    if (fx->drop_next_rpdo && frame->id == 0x185) {
        fx->drop_next_rpdo = false;
        return 0;
    }
    return 1;
}

static fx_t *fx_new(void)
{
    fx_t *fx = calloc(1, sizeof *fx);
    assert_non_null(fx);
    side_init(&fx->a, CO_MODE_CLASSIC, classic_rows, ROWS(classic_rows));
    side_init(&fx->b, CO_MODE_FD, fd_rows, ROWS(fd_rows));
    co_gateway_init(&fx->gw, on_event, fx);
    assert_int_equal(co_gateway_add_port(&fx->gw, &fx->a.stack, NET_A), CO_GATEWAY_OK);
    assert_int_equal(co_gateway_add_port(&fx->gw, &fx->b.stack, NET_B), CO_GATEWAY_OK);
    co_membus_set_fault(&fx->a.tb.bus, drop_rpdo, fx);
    settle(fx);
    /* both gateway nodes operational */
    send(&fx->a, 0x000, (const uint8_t[]){0x01, 0x00}, 2);
    send(&fx->b, 0x000, (const uint8_t[]){0x01, 0x00}, 2);
    settle(fx);
    assert_int_equal(co_node_state(co_stack_node(&fx->a.stack)), CO_NMT_OPERATIONAL);
    assert_int_equal(co_node_state(co_stack_node(&fx->b.stack)), CO_NMT_OPERATIONAL);
    tu_log_clear(&fx->a.tb);
    tu_log_clear(&fx->b.tb);
    return fx;
}

static void fx_free(fx_t *fx)
{
    co_gateway_deinit(&fx->gw);
    co_stack_deinit(&fx->a.stack);
    co_stack_deinit(&fx->b.stack);
    free(fx);
}

/* An expedited SDO download on the classic line to the gateway's node; the
 * answer frame's abort code (0 = the 0x60 confirmation). */
static uint32_t sdo_write(fx_t *fx, uint16_t index, uint8_t sub, uint32_t value, uint8_t size)
{
    uint8_t req[8] = {(uint8_t)(0x23 | ((4 - size) << 2)), (uint8_t)index,
                      (uint8_t)(index >> 8), sub, (uint8_t)value, (uint8_t)(value >> 8),
                      (uint8_t)(value >> 16), (uint8_t)(value >> 24)};
    const co_frame_t *f;
    long at;
    tu_log_clear(&fx->a.tb);
    send(&fx->a, 0x600 + GW_NODE, req, 8);
    settle(fx);
    at = tu_log_find_id(&fx->a.tb, 0x580 + GW_NODE, 0);
    assert_true(at >= 0);
    f = &fx->a.tb.log[at].frame;
    assert_int_equal(f->len, 8);
    assert_int_equal(f->data[1], (uint8_t)index);
    assert_int_equal(f->data[2], (uint8_t)(index >> 8));
    assert_int_equal(f->data[3], sub);
    if (f->data[0] == 0x60) {
        return 0;
    }
    assert_int_equal(f->data[0], 0x80);
    return (uint32_t)tu_le_get(&f->data[4], 4);
}

/* A network write into an OD as a server does it (the check_write path). */
static uint32_t od_write(co_od_t *od, uint16_t index, uint8_t sub, uint32_t value, uint8_t size)
{
    uint8_t scratch[64], bytes[4];
    co_od_xfer_t x;
    uint32_t r;
    tu_le_put(bytes, value, 4);
    co_od_xfer_init(&x, scratch, sizeof scratch);
    r = co_od_write_begin(od, &x, index, sub, size);
    if (r == 0) {
        r = co_od_write_chunk(&x, bytes, size);
    }
    if (r == 0) {
        r = co_od_write_end(&x);
    }
    return r;
}

/* ------------------------------------------------------------ PDO forwarding */

/* A 6-byte classic RPDO (0xB000:01 U16, :02 U32) leaves the fd line as
 * TPDO1 of the gateway with the same 6 bytes, FD flags, at once. */
static void test_classic_rpdo_forwarded_as_fd_tpdo(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    const uint8_t data[6] = {0x34, 0x12, 0x78, 0x56, 0x34, 0x12};
    send(&fx->a, 0x185, data, 6);
    settle(fx);
    assert_int_equal(tu_log_count_id(&fx->b.tb, 0x181), 1);
    tu_assert_logged(&fx->b.tb, tu_log_find_id(&fx->b.tb, 0x181, 0), 0x181, data, 6);
    uint16_t v16 = 0;
    uint32_t v32 = 0;
    assert_true(co_od_get_u16(&fx->b.od, 0xB000, 1, &v16));
    assert_true(co_od_get_u32(&fx->b.od, 0xB000, 2, &v32));
    assert_int_equal(v16, 0x1234);
    assert_int_equal(v32, 0x12345678);
    const co_gateway_stats_t *st = co_gateway_stats(&fx->gw);
    assert_int_equal(st->pdo_forwarded, 1);
    assert_int_equal(st->pdo_values, 2);
    assert_int_equal(st->tpdo_triggered, 1);   /* one TPDO for both objects */
    /* nothing sent back on the classic line but the RPDO itself */
    assert_int_equal(tu_log_count_id(&fx->a.tb, 0x181), 0);
    fx_free(fx);
}

/* A 16-byte fd RPDO (4 x U32 of 0xB001) is split over two classic TPDOs of
 * 8 bytes each, every byte in its place. */
static void test_fd_rpdo_split_over_classic_tpdos(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    uint8_t data[16];
    for (int i = 0; i < 16; i++) {
        data[i] = (uint8_t)(0xA0 + i);
    }
    send(&fx->b, 0x206, data, 16);
    settle(fx);
    assert_int_equal(tu_log_count_id(&fx->a.tb, 0x181), 1);
    assert_int_equal(tu_log_count_id(&fx->a.tb, 0x281), 1);
    tu_assert_logged(&fx->a.tb, tu_log_find_id(&fx->a.tb, 0x181, 0), 0x181, data, 8);
    tu_assert_logged(&fx->a.tb, tu_log_find_id(&fx->a.tb, 0x281, 0), 0x281, data + 8, 8);
    assert_int_equal(co_gateway_stats(&fx->gw)->tpdo_triggered, 2);
    fx_free(fx);
}

/* Faults: a lost RPDO forwards nothing (and the next one does); a target
 * line whose node is not operational copies the values, sends nothing and
 * counts the refused trigger. */
static void test_forwarding_faults(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    const uint8_t first[6] = {1, 0, 2, 0, 0, 0};
    const uint8_t second[6] = {3, 0, 4, 0, 0, 0};
    fx->drop_next_rpdo = true;
    send(&fx->a, 0x185, first, 6);
    settle(fx);
    assert_int_equal(tu_log_count_id(&fx->b.tb, 0x181), 0);
    assert_int_equal(co_gateway_stats(&fx->gw)->pdo_forwarded, 0);
    send(&fx->a, 0x185, second, 6);
    settle(fx);
    tu_assert_logged(&fx->b.tb, tu_log_find_id(&fx->b.tb, 0x181, 0), 0x181, second, 6);

    /* the fd side's gateway node to pre-operational */
    send(&fx->b, 0x000, (const uint8_t[]){0x80, GW_NODE}, 2);
    settle(fx);
    tu_log_clear(&fx->b.tb);
    send(&fx->a, 0x185, first, 6);
    settle(fx);
    assert_int_equal(tu_log_count_id(&fx->b.tb, 0x181), 0);
    assert_int_equal(co_gateway_stats(&fx->gw)->tpdo_refused, 1);
    uint16_t v16 = 0;
    assert_true(co_od_get_u16(&fx->b.od, 0xB000, 1, &v16));
    assert_int_equal(v16, 1);
    fx_free(fx);
}

/* Mapping refusals, as SDO abort frames on the classic line: a forwarded
 * object mapped partly (0x06040043), one the fd line holds with another
 * type (0x06040043), one bigger than a classic PDO (the PDO service's
 * refusal, 0x06040042, when the mapping is enabled); the fd line refuses the type mismatch from its side too, and a
 * whole, matching mapping is accepted. */
static void test_mapping_refusals(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    assert_int_equal(sdo_write(fx, 0x1A02, 1, 0xB0040008, 4), CO_ABORT_PARAM_INCOMPATIBLE);
    assert_int_equal(sdo_write(fx, 0x1A02, 1, 0xB0030010, 4), CO_ABORT_PARAM_INCOMPATIBLE);
    /* the PDO service checks the length when the mapping is enabled */
    assert_int_equal(sdo_write(fx, 0x1A02, 1, 0xB0050080, 4), 0);
    assert_int_equal(sdo_write(fx, 0x1A02, 0, 1, 1), CO_ABORT_MAP_LENGTH);
    assert_int_equal(od_write(&fx->b.od, 0x1A02, 1, 0xB0030020, 4),
                     CO_ABORT_PARAM_INCOMPATIBLE);
    /* accepted: the whole object, same on both lines */
    assert_int_equal(sdo_write(fx, 0x1A02, 1, 0xB0040010, 4), 0);
    assert_int_equal(sdo_write(fx, 0x1A02, 0, 1, 1), 0);
    /* an entry loaded without the check (application write) is refused when
     * the mapping is enabled */
    assert_int_equal(sdo_write(fx, 0x1A02, 0, 0, 1), 0);
    uint8_t bad[4];
    tu_le_put(bad, 0xB0040008, 4);
    assert_int_equal(co_od_put(&fx->a.od, 0x1A02, 2, bad, 4), 0);
    assert_int_equal(sdo_write(fx, 0x1A02, 0, 2, 1), CO_ABORT_PARAM_INCOMPATIBLE);
    fx_free(fx);
}

/* ------------------------------------------------------------ EMCY routing */

/* 0x1F2F sub 5 = network 2: device 5's classic EMCY is re-sent on the fd
 * line as the 20-byte FD EMCY on its CAN-ID; sub 6 of the fd line =
 * network 1: device 6's FD EMCY arrives on the classic line as 8 bytes. A
 * bit for a network no line carries is counted, never sent. */
static void test_emcy_routed_both_ways(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    assert_int_equal(sdo_write(fx, 0x1F2F, 5, 0x2 | 0x8, 4), 0);   /* networks 2 and 4 */
    assert_int_equal(od_write(&fx->b.od, 0x1F2F, 6, 0x1, 4), 0);
    tu_log_clear(&fx->a.tb);
    tu_log_clear(&fx->b.tb);

    const uint8_t classic[8] = {0x10, 0x81, 0x11, 1, 2, 3, 4, 5};
    send(&fx->a, 0x85, classic, 8);
    settle(fx);
    uint8_t fd[20] = {0};
    memcpy(fd, classic, 8);
    assert_int_equal(tu_log_count_id(&fx->b.tb, 0x85), 1);
    tu_assert_logged(&fx->b.tb, tu_log_find_id(&fx->b.tb, 0x85, 0), 0x85, fd, 20);
    assert_int_equal(co_gateway_stats(&fx->gw)->emcy_routed, 1);
    assert_int_equal(co_gateway_stats(&fx->gw)->emcy_no_route, 1);

    uint8_t from_fd[20] = {0x30, 0x42, 0x05, 9, 8, 7, 6, 5, 0x01, 0x15, 0x05, 0x01,
                           1, 2, 3, 4, 5, 6, 0, 0};
    send(&fx->b, 0x86, from_fd, 20);
    settle(fx);
    assert_int_equal(tu_log_count_id(&fx->a.tb, 0x86), 1);
    tu_assert_logged(&fx->a.tb, tu_log_find_id(&fx->a.tb, 0x86, 0), 0x86, from_fd, 8);
    /* not re-sent onto the line it came from */
    assert_int_equal(tu_log_count_id(&fx->b.tb, 0x86), 1);
    assert_int_equal(co_gateway_stats(&fx->gw)->emcy_routed, 2);

    /* no 0x1F2F bit: not routed */
    tu_log_clear(&fx->a.tb);
    assert_int_equal(od_write(&fx->b.od, 0x1F2F, 6, 0, 4), 0);
    send(&fx->b, 0x86, from_fd, 20);
    settle(fx);
    assert_int_equal(tu_log_count_id(&fx->a.tb, 0x86), 0);
    fx_free(fx);
}

/* EMCY ping-pong between gateways: node 5's EMCY re-sent from network 1
 * onto network 2 comes back on network 2 (another gateway routes network
 * 2's node 5 to network 1), then on network 1 (a third one routes it back):
 * neither copy is re-sent (counted as echoes). Another EMCY of node 5 is
 * news; the first one again after CO_GATEWAY_EMCY_ECHO_MS as well. */
static void test_emcy_echo_not_resent(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    assert_int_equal(sdo_write(fx, 0x1F2F, 5, 0x2, 4), 0);         /* 1's node 5 -> 2 */
    assert_int_equal(od_write(&fx->b.od, 0x1F2F, 5, 0x1, 4), 0);   /* 2's node 5 -> 1 */
    tu_log_clear(&fx->a.tb);
    tu_log_clear(&fx->b.tb);
    const co_gateway_stats_t *st = co_gateway_stats(&fx->gw);
    const uint8_t classic[8] = {0x10, 0x81, 0x11, 1, 2, 3, 4, 5};
    uint8_t fd[20] = {0};
    memcpy(fd, classic, 8);
    send(&fx->a, 0x85, classic, 8);
    settle(fx);
    assert_int_equal(tu_log_count_id(&fx->b.tb, 0x85), 1);
    send(&fx->b, 0x85, fd, 20);   /* the echo on the network it went to */
    settle(fx);
    assert_int_equal(tu_log_count_id(&fx->a.tb, 0x85), 1);   /* only the device's own */
    send(&fx->a, 0x85, classic, 8);   /* ... and on the network it came from */
    settle(fx);
    assert_int_equal(tu_log_count_id(&fx->b.tb, 0x85), 2);   /* the two echoes only */
    assert_int_equal(st->emcy_echoes, 2);
    assert_int_equal(st->emcy_routed, 1);

    const uint8_t reset[8] = {0x00, 0x00, 0x00, 0, 0, 0, 0, 0};   /* error reset */
    send(&fx->a, 0x85, reset, 8);
    settle(fx);
    assert_int_equal(tu_log_count_id(&fx->b.tb, 0x85), 3);   /* routed */
    uint64_t later = fx->a.tb.now + (CO_GATEWAY_EMCY_ECHO_MS + 1) * 1000u;
    tu_step(&fx->a.tb, later);
    tu_step(&fx->b.tb, later);
    send(&fx->b, 0x85, fd, 20);
    settle(fx);
    assert_int_equal(tu_log_count_id(&fx->a.tb, 0x85), 4);   /* news again: routed to 1 */
    assert_int_equal(st->emcy_routed, 3);
    assert_int_equal(st->emcy_echoes, 2);
    fx_free(fx);
}

/* A line without 0x1F2F in its OD routes through the API table. */
static void test_emcy_route_api(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    /* node 7 has a 0x1F2F entry (0): the OD wins; node 7's EMCY consumed */
    assert_int_equal(sdo_write(fx, 0x1028, 7, 0x87, 4), 0);
    assert_true(co_gateway_set_emcy_route(&fx->gw, &fx->a.stack, 7, 0x2));
    assert_false(co_gateway_set_emcy_route(&fx->gw, &fx->a.stack, 0, 0x2));
    assert_false(co_gateway_set_emcy_route(&fx->gw, NULL, 7, 0x2));
    send(&fx->a, 0x87, (const uint8_t[]){0, 0x10, 1, 0, 0, 0, 0, 0}, 8);
    settle(fx);
    assert_int_equal(tu_log_count_id(&fx->b.tb, 0x87), 0);
    fx_free(fx);
}

/* ------------------------------------------------------------ routes */

static void test_routes_and_loops(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    co_stack_t *line = NULL;
    uint8_t node = 0xFF;
    /* attached networks */
    assert_int_equal(co_gateway_resolve(&fx->gw, NET_A, &line, &node), CO_GATEWAY_ATTACHED);
    assert_ptr_equal(line, &fx->a.stack);
    assert_int_equal(node, 0);
    assert_ptr_equal(co_gateway_line_of(&fx->gw, NET_B), &fx->b.stack);
    assert_int_equal(co_gateway_network_of(&fx->gw, &fx->b.stack), NET_B);
    assert_int_equal(co_gateway_resolve(&fx->gw, 9, &line, &node), CO_GATEWAY_UNKNOWN);
    assert_null(line);
    /* network 3 behind gateway node 7 on network 2; network 4 behind node 9 on 3 */
    assert_int_equal(co_gateway_set_route(&fx->gw, 3, NET_B, 7), 0);
    assert_int_equal(co_gateway_resolve(&fx->gw, 3, &line, &node), CO_GATEWAY_VIA);
    assert_ptr_equal(line, &fx->b.stack);
    assert_int_equal(node, 7);
    uint32_t v = 0;
    assert_true(co_od_get_u32(&fx->a.od, 0x1F2C, 3, &v));   /* written into both ODs */
    assert_int_equal(v, 0x0702);
    assert_true(co_od_get_u32(&fx->b.od, 0x1F2C, 3, &v));
    assert_int_equal(v, 0x0702);
    assert_int_equal(sdo_write(fx, 0x1F2C, 4, 0x0903, 4), 0);
    assert_int_equal(co_gateway_resolve(&fx->gw, 4, &line, &node), CO_GATEWAY_VIA);
    assert_ptr_equal(line, &fx->b.stack);
    assert_int_equal(node, 7);   /* the first hop: toward network 3 */
    assert_true(co_od_get_u32(&fx->b.od, 0x1F2C, 4, &v));
    assert_int_equal(v, 0x0903);

    /* refusals: a loop 3 -> 4 -> 3 (reported), an attached network, a route
     * through itself, through our own node, a bad value */
    assert_int_equal(sdo_write(fx, 0x1F2C, 3, 0x0904, 4), CO_ABORT_PARAM_INCOMPATIBLE);
    assert_int_equal(fx->loops, 1);
    assert_int_equal(fx->loop_net, 3);
    assert_int_equal(co_gateway_set_route(&fx->gw, NET_B, NET_A, 7),
                     CO_ABORT_PARAM_INCOMPATIBLE);
    assert_int_equal(co_gateway_set_route(&fx->gw, 5, 5, 7), CO_ABORT_PARAM_INCOMPATIBLE);
    assert_int_equal(co_gateway_set_route(&fx->gw, 5, NET_A, GW_NODE),
                     CO_ABORT_PARAM_INCOMPATIBLE);
    assert_int_equal(sdo_write(fx, 0x1F2C, 5, 0x8002, 4), CO_ABORT_INVALID_VALUE);
    assert_int_equal(sdo_write(fx, 0x1F2C, 5, 0x10702, 4), CO_ABORT_INVALID_VALUE);
    assert_int_equal(co_gateway_stats(&fx->gw)->routes_refused, 6);
    assert_int_equal(fx->refused, 6);
    /* the refused writes changed nothing */
    assert_int_equal(co_gateway_resolve(&fx->gw, 3, &line, &node), CO_GATEWAY_VIA);
    assert_int_equal(node, 7);

    /* values loaded without the checks (a store, the application) that form
     * a loop: resolving reports it */
    uint8_t b6[4] = {7, 8, 0, 0}, b7[4] = {6, 8, 0, 0};
    assert_int_equal(co_od_put(&fx->a.od, 0x1F2C, 6, b6, 4), 0);
    assert_int_equal(co_od_put(&fx->a.od, 0x1F2C, 7, b7, 4), 0);
    assert_int_equal(co_gateway_resolve(&fx->gw, 6, &line, &node), CO_GATEWAY_LOOP);
    assert_null(line);
    assert_int_equal(fx->loops, 2);
    assert_int_equal(fx->loop_net, 6);
    assert_int_equal(co_gateway_stats(&fx->gw)->route_loops, 2);
    /* removing a route */
    assert_int_equal(co_gateway_set_route(&fx->gw, 4, 0, 0), 0);
    assert_int_equal(co_gateway_resolve(&fx->gw, 4, &line, &node), CO_GATEWAY_UNKNOWN);
    fx_free(fx);
}

/* Values loaded without the checks whose node byte is no node-id (0, or
 * above 127): such a route leads nowhere. Resolving it must not name the
 * via network as if the target network were attached to it (node 0) nor a
 * hop no node can be. */
static void test_loaded_route_without_a_node_leads_nowhere(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    co_stack_t *line = NULL;
    uint8_t node = 0xFF;
    uint8_t no_node[4] = {NET_B, 0, 0, 0}, big_node[4] = {NET_B, 200, 0, 0};
    uint8_t behind[4] = {8, 9, 0, 0};
    assert_int_equal(co_od_put(&fx->a.od, 0x1F2C, 8, no_node, 4), 0);
    assert_int_equal(co_od_put(&fx->a.od, 0x1F2C, 9, big_node, 4), 0);
    assert_int_equal(co_od_put(&fx->a.od, 0x1F2C, 10, behind, 4), 0);   /* 10 via 8 */
    assert_int_equal(co_gateway_resolve(&fx->gw, 8, &line, &node), CO_GATEWAY_UNKNOWN);
    assert_null(line);
    assert_int_equal(node, 0);
    assert_int_equal(co_gateway_resolve(&fx->gw, 9, &line, &node), CO_GATEWAY_UNKNOWN);
    assert_null(line);
    assert_int_equal(co_gateway_resolve(&fx->gw, 10, &line, &node), CO_GATEWAY_UNKNOWN);
    assert_null(line);
    /* a valid route still resolves */
    assert_int_equal(co_gateway_set_route(&fx->gw, 8, NET_B, 7), 0);
    assert_int_equal(co_gateway_resolve(&fx->gw, 10, &line, &node), CO_GATEWAY_VIA);
    assert_ptr_equal(line, &fx->b.stack);
    assert_int_equal(node, 7);
    fx_free(fx);
}

static void test_ports_refused(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    co_gateway_t gw;
    co_gateway_init(&gw, NULL, NULL);
    assert_int_equal(co_gateway_add_port(&gw, &fx->a.stack, 0), CO_GATEWAY_ERR_ARGUMENT);
    assert_int_equal(co_gateway_add_port(&gw, &fx->a.stack, 128), CO_GATEWAY_ERR_ARGUMENT);
    assert_int_equal(co_gateway_add_port(&gw, NULL, 3), CO_GATEWAY_ERR_ARGUMENT);
    /* the same line twice, another line on a taken network */
    co_gateway_deinit(&fx->gw);
    assert_int_equal(co_gateway_add_port(&gw, &fx->a.stack, 3), CO_GATEWAY_OK);
    assert_int_equal(co_gateway_add_port(&gw, &fx->a.stack, 4), CO_GATEWAY_ERR_ARGUMENT);
    assert_int_equal(co_gateway_add_port(&gw, &fx->b.stack, 3), CO_GATEWAY_ERR_NETWORK);
    /* deinit unhooks: a partial mapping is accepted again */
    co_gateway_deinit(&gw);
    assert_int_equal(sdo_write(fx, 0x1A02, 1, 0xB0040008, 4), 0);
    co_gateway_init(&fx->gw, NULL, NULL);
    fx_free(fx);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_classic_rpdo_forwarded_as_fd_tpdo),
        cmocka_unit_test(test_fd_rpdo_split_over_classic_tpdos),
        cmocka_unit_test(test_forwarding_faults),
        cmocka_unit_test(test_mapping_refusals),
        cmocka_unit_test(test_emcy_routed_both_ways),
        cmocka_unit_test(test_emcy_route_api),
        cmocka_unit_test(test_emcy_echo_not_resent),
        cmocka_unit_test(test_routes_and_loops),
        cmocka_unit_test(test_loaded_route_without_a_node_leads_nowhere),
        cmocka_unit_test(test_ports_refused),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
