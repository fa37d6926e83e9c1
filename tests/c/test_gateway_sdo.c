/* co_gateway SDO networking: a gateway (node 1 on each line) joins a classic
 * line with a client (network 1), an fd line (network 2) and a classic line
 * with device 5 (network 3). The client's network indication (0xE0, network
 * LE16, node) is confirmed, its requests are relayed to the device and the
 * answers back, byte for byte on both buses (expedited, segmented, a
 * download, an abort of the device, an abort of the client); faults: a
 * silent target, a lost answer (both sides aborted with 0x05040000), the
 * gateway's client busy, an unknown or fd network; a route through a next
 * gateway forwards the indication and relays its confirmation or refusal.
 * A node of the fd network 2 is reached by translation: the gateway serves
 * the client's SDO transfer and moves the value with its USDO client (exact
 * bytes on both buses; faults: silent target, aborts of either side, the
 * buffer busy or too small, block transfer refused, a silent client). */
#include "test_od_util.h"

#include "canopenfd/co_gateway.h"
#include "canopenfd/co_stack.h"

#include <stdlib.h>

enum { GW = 1, DEV = 5, FDEV = 6, NEXT_GW = 9, NET_A = 1, NET_B = 2, NET_C = 3,
       TIMEOUT_MS = 100, FD_BUFFER = 64,
       BIG = 700 /* a block download of 100 segments: the last one's byte 0 is 0xE4 */ };

static const tu_od_row_t gateway_rows[] = {
    {0x1000, 0, VAR, U32, RO, 0, 4, 0x00000302, NULL, 0, 0},
    {0x1001, 0, VAR, U8, RO, 0, 1, 0, NULL, 0, 0},
    {0x1017, 0, VAR, U16, RW, 0, 2, 0, NULL, 0, 0},
    {0x2100, 0, VAR, CO_TYPE_OCTET_STRING, RW, 0, BIG, 0, "-", 0, 0},
};

static const tu_od_row_t device_rows[] = {
    {0x1000, 0, VAR, U32, RO, 0, 4, 0x00000191, NULL, 0, 0},
    {0x1001, 0, VAR, U8, RO, 0, 1, 0, NULL, 0, 0},
    {0x1017, 0, VAR, U16, RW, 0, 2, 0, NULL, 0, 0},
    {0x2000, 0, VAR, U32, RW, 0, 4, 0x12345678, NULL, 0, 0},
    {0x2001, 0, VAR, VS, RO, 0, 14, 0, "hello gateway!", 0, 0},
    {0x2100, 0, VAR, CO_TYPE_OCTET_STRING, RW, 0, BIG, 0, "-", 0, 0},
    {0x2003, 0, VAR, VS, RW, 0, 100, 0, "-", 0, 0},
};

#define ROWS(r) (sizeof(r) / sizeof((r)[0]))

typedef struct node {
    tu_line_t line;
    co_od_t od;
    co_od_entry_t entries[16];
    uint8_t pool[2048];
    co_od_subscription_t subs[CO_STACK_OD_SUBSCRIPTIONS + 4];
    co_stack_t stack;
    co_stack_arena_t arena;
    unsigned char memory[48 * 1024];
} node_t;

typedef struct fx {
    tu_bus_t a, b, c;
    node_t gw_a, gw_b, gw_c, dev;
    node_t fdev;                 /* fd device 6 on network 2 (fd_setup) */
    uint8_t fd_buffer[FD_BUFFER];
    tu_line_t client;            /* raw frames on network 1 */
    tu_line_t peer;              /* raw frames on network 3 (the "next gateway") */
    co_gateway_t gw;
    bool drop_answer;
    bool drop_fd_segments;       /* the fd device's 0x33 / 0x34 answers are lost */
    co_stack_t tool;             /* an SDO client on the client's line */
    co_stack_arena_t tool_arena;
    unsigned char tool_memory[32 * 1024];
} fx_t;

static void node_init(tu_bus_t *tb, node_t *n, co_mode_t mode, uint8_t node_id,
                      const tu_od_row_t *rows, size_t count)
{
    tu_bus_add_line(tb, &n->line);
    co_od_init(&n->od, mode, n->entries, 16, n->pool, sizeof n->pool, n->subs,
               CO_STACK_OD_SUBSCRIPTIONS + 4);
    tu_od_add_rows(&n->od, rows, count);
    assert_true(co_od_seal(&n->od, node_id));
    co_stack_arena_init(&n->arena, n->memory, sizeof n->memory);
    co_stack_line_config_t lc = {.heartbeat_entries = 2};
    assert_int_equal(co_stack_init(&n->stack, &n->line.line, &lc,
                                   co_stack_arena_allocator(&n->arena)), CO_STACK_OK);
    co_stack_node_config_t nc = {.node_id = node_id, .od = &n->od};
    assert_int_equal(co_stack_node_init(&n->stack, &nc), CO_STACK_OK);
    assert_int_equal(co_stack_boot(&n->stack), CO_STACK_OK);
}

static uint8_t drop_answer(const co_frame_t *frame, void *user)
{
    fx_t *fx = user;
    if (fx->drop_answer && frame->id == 0x580 + DEV) {
        fx->drop_answer = false;
        return 0;
    }
    return 1;
}

static uint8_t drop_fd_segments(const co_frame_t *frame, void *user)
{
    fx_t *fx = user;
    return fx->drop_fd_segments && frame->id == 0x580 + FDEV &&
                   (frame->data[1] == 0x33 || frame->data[1] == 0x34)
               ? 0
               : 1;
}

static void step_all(fx_t *fx, uint64_t t)
{
    for (int round = 0; round < 4; round++) {
        tu_step(&fx->a, t);
        tu_step(&fx->b, t);
        tu_step(&fx->c, t);
    }
}

static void settle(fx_t *fx)
{
    step_all(fx, fx->a.now);
}

/* Advance the three buses together to `until`, stopping at each deadline. */
static void advance(fx_t *fx, uint64_t until)
{
    for (int guard = 0; guard < 10000; guard++) {
        uint64_t d = tu_next_deadline(&fx->a), e = tu_next_deadline(&fx->b),
                 f = tu_next_deadline(&fx->c);
        d = e < d ? e : d;
        d = f < d ? f : d;
        if (d > until) {
            break;
        }
        step_all(fx, d > fx->a.now ? d : fx->a.now);
    }
    step_all(fx, until);
}

static fx_t *fx_new(void)
{
    fx_t *fx = calloc(1, sizeof *fx);
    assert_non_null(fx);
    tu_bus_init(&fx->a, CO_MODE_CLASSIC, false);
    tu_bus_init(&fx->b, CO_MODE_FD, true);
    tu_bus_init(&fx->c, CO_MODE_CLASSIC, false);
    node_init(&fx->a, &fx->gw_a, CO_MODE_CLASSIC, GW, gateway_rows, ROWS(gateway_rows));
    node_init(&fx->b, &fx->gw_b, CO_MODE_FD, GW, gateway_rows, ROWS(gateway_rows));
    node_init(&fx->c, &fx->gw_c, CO_MODE_CLASSIC, GW, gateway_rows, ROWS(gateway_rows));
    node_init(&fx->c, &fx->dev, CO_MODE_CLASSIC, DEV, device_rows, ROWS(device_rows));
    tu_bus_add_line(&fx->a, &fx->client);
    tu_bus_add_line(&fx->c, &fx->peer);
    co_gateway_init(&fx->gw, NULL, NULL);
    co_gateway_set_sdo_timeout(&fx->gw, TIMEOUT_MS);
    assert_int_equal(co_gateway_add_port(&fx->gw, &fx->gw_a.stack, NET_A), CO_GATEWAY_OK);
    assert_int_equal(co_gateway_add_port(&fx->gw, &fx->gw_b.stack, NET_B), CO_GATEWAY_OK);
    assert_int_equal(co_gateway_add_port(&fx->gw, &fx->gw_c.stack, NET_C), CO_GATEWAY_OK);
    co_membus_set_fault(&fx->c.bus, drop_answer, fx);
    settle(fx);
    tu_log_clear(&fx->a);
    tu_log_clear(&fx->c);
    return fx;
}

static void fx_free(fx_t *fx)
{
    co_gateway_deinit(&fx->gw);
    if (co_stack_line(&fx->tool) != NULL) {
        co_stack_deinit(&fx->tool);
    }
    co_stack_deinit(&fx->gw_a.stack);
    co_stack_deinit(&fx->gw_b.stack);
    co_stack_deinit(&fx->gw_c.stack);
    co_stack_deinit(&fx->dev.stack);
    if (co_stack_line(&fx->fdev.stack) != NULL) {
        co_stack_deinit(&fx->fdev.stack);
    }
    free(fx);
}

/* The client sends one request to the gateway; the buses settle. */
static void request(fx_t *fx, const uint8_t *data)
{
    assert_true(co_line_send(&fx->client.line, 0x600 + GW, data, 8));
    settle(fx);
}

/* The k-th frame with `id` in a bus log must be exactly these 8 bytes. */
static void expect(const tu_bus_t *tb, uint32_t id, size_t k, const uint8_t *data)
{
    tu_assert_logged(tb, tu_log_find_id(tb, id, k), id, data, 8);
}

static const uint8_t IND_3_5[8] = {0xE0, NET_C, 0x00, DEV, 0, 0, 0, 0};

static void connect_3_5(fx_t *fx)
{
    request(fx, IND_3_5);
    expect(&fx->a, 0x581, 0, IND_3_5);          /* confirmed, the same bytes */
    assert_int_equal(tu_log_count_id(&fx->c, 0x600 + DEV), 0);   /* attached: nothing sent */
    tu_log_clear(&fx->a);
    tu_log_clear(&fx->c);
}

static void test_expedited_read_and_write_relayed(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    connect_3_5(fx);
    const uint8_t up[8] = {0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0};
    const uint8_t up_ok[8] = {0x43, 0x00, 0x20, 0x00, 0x78, 0x56, 0x34, 0x12};
    request(fx, up);
    expect(&fx->c, 0x605, 0, up);               /* relayed unchanged to device 5 */
    expect(&fx->c, 0x585, 0, up_ok);
    expect(&fx->a, 0x581, 0, up_ok);            /* its answer back to the client */
    const uint8_t down[8] = {0x23, 0x00, 0x20, 0x00, 0xBE, 0xBA, 0xFE, 0xCA};
    const uint8_t down_ok[8] = {0x60, 0x00, 0x20, 0x00, 0, 0, 0, 0};
    request(fx, down);
    expect(&fx->c, 0x605, 1, down);
    expect(&fx->a, 0x581, 1, down_ok);
    uint32_t v = 0;
    assert_true(co_od_get_u32(&fx->dev.od, 0x2000, 0, &v));
    assert_int_equal(v, 0xCAFEBABE);
    const co_gateway_stats_t *st = co_gateway_stats(&fx->gw);
    assert_int_equal(st->sdo_connects, 1);
    assert_int_equal(st->sdo_relayed, 2);
    assert_int_equal(st->sdo_answers, 2);
    /* no timeout fires afterwards: answered requests disarm it */
    advance(fx, fx->a.now + 5 * TIMEOUT_MS * TU_MS);
    assert_int_equal(st->sdo_timeouts, 0);
    assert_int_equal(tu_log_count_id(&fx->a, 0x581), 2);
    fx_free(fx);
}

static void test_segmented_upload_relayed(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    connect_3_5(fx);
    request(fx, (const uint8_t[]){0x40, 0x01, 0x20, 0x00, 0, 0, 0, 0});
    expect(&fx->a, 0x581, 0, (const uint8_t[]){0x41, 0x01, 0x20, 0x00, 14, 0, 0, 0});
    request(fx, (const uint8_t[]){0x60, 0, 0, 0, 0, 0, 0, 0});
    expect(&fx->a, 0x581, 1, (const uint8_t[]){0x00, 'h', 'e', 'l', 'l', 'o', ' ', 'g'});
    request(fx, (const uint8_t[]){0x70, 0, 0, 0, 0, 0, 0, 0});
    expect(&fx->a, 0x581, 2, (const uint8_t[]){0x11, 'a', 't', 'e', 'w', 'a', 'y', '!'});
    assert_int_equal(tu_log_count_id(&fx->c, 0x605), 3);
    fx_free(fx);
}

/* Either side's abort reaches the other: the device's (no such object) is
 * relayed to the client; the client's (mid-transfer) to the device, and no
 * timeout follows it. */
static void test_aborts_relayed(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    connect_3_5(fx);
    const uint8_t nothing[8] = {0x80, 0xFF, 0x2F, 0x00, 0x00, 0x00, 0x02, 0x06};
    request(fx, (const uint8_t[]){0x40, 0xFF, 0x2F, 0x00, 0, 0, 0, 0});
    expect(&fx->c, 0x585, 0, nothing);
    expect(&fx->a, 0x581, 0, nothing);
    request(fx, (const uint8_t[]){0x40, 0x01, 0x20, 0x00, 0, 0, 0, 0});
    const uint8_t client_abort[8] = {0x80, 0x01, 0x20, 0x00, 0x00, 0x00, 0x04, 0x05};
    request(fx, client_abort);
    expect(&fx->c, 0x605, 2, client_abort);
    advance(fx, fx->a.now + 3 * TIMEOUT_MS * TU_MS);
    assert_int_equal(co_gateway_stats(&fx->gw)->sdo_timeouts, 0);
    /* the device took the abort: a new upload starts cleanly */
    request(fx, (const uint8_t[]){0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0});
    expect(&fx->a, 0x581, 2, (const uint8_t[]){0x43, 0x00, 0x20, 0x00, 0x78, 0x56, 0x34, 0x12});
    fx_free(fx);
}

/* A silent target and a lost answer: after the timeout both the client and
 * the target hear abort 0x05040000 with the request's multiplexer; the
 * connection stays, the next request goes through. */
static void test_silent_target_and_lost_answer(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    const uint8_t ind_3_7[8] = {0xE0, NET_C, 0x00, 7, 0, 0, 0, 0};
    request(fx, ind_3_7);
    expect(&fx->a, 0x581, 0, ind_3_7);
    request(fx, (const uint8_t[]){0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0});
    const uint8_t timed_out[8] = {0x80, 0x00, 0x20, 0x00, 0x00, 0x00, 0x04, 0x05};
    uint64_t sent = fx->a.now;
    advance(fx, sent + (TIMEOUT_MS - 1) * TU_MS);
    assert_int_equal(tu_log_count_id(&fx->a, 0x581), 1);   /* not before the timeout */
    advance(fx, sent + (TIMEOUT_MS + 1) * TU_MS);
    expect(&fx->a, 0x581, 1, timed_out);
    expect(&fx->c, 0x607, 1, timed_out);
    assert_int_equal(co_gateway_stats(&fx->gw)->sdo_timeouts, 1);

    request(fx, IND_3_5);
    tu_log_clear(&fx->a);
    tu_log_clear(&fx->c);
    fx->drop_answer = true;
    request(fx, (const uint8_t[]){0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0});
    advance(fx, fx->a.now + (TIMEOUT_MS + 1) * TU_MS);
    expect(&fx->a, 0x581, 0, timed_out);
    expect(&fx->c, 0x605, 1, timed_out);
    request(fx, (const uint8_t[]){0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0});
    expect(&fx->a, 0x581, 1, (const uint8_t[]){0x43, 0x00, 0x20, 0x00, 0x78, 0x56, 0x34, 0x12});
    assert_int_equal(co_gateway_stats(&fx->gw)->sdo_timeouts, 2);
    fx_free(fx);
}

/* Refusals, each an abort with the indication's bytes 1..3: a network no
 * route reaches (0x08000000), an fd network whose line has no USDO client
 * (0x060A0023: nothing to translate with), the client's own line
 * (0x060A0023), a bad node-id
 * (0x06090030), the gateway's SDO client on the target line holding the
 * answer CAN-IDs (busy: 0x060A0023). A refused client stays with the
 * gateway's own server. */
static void test_refusals(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    request(fx, (const uint8_t[]){0xE0, 9, 0, DEV, 0, 0, 0, 0});
    expect(&fx->a, 0x581, 0, (const uint8_t[]){0x80, 9, 0, DEV, 0x00, 0x00, 0x00, 0x08});
    request(fx, (const uint8_t[]){0xE0, NET_B, 0, DEV, 0, 0, 0, 0});
    expect(&fx->a, 0x581, 1, (const uint8_t[]){0x80, NET_B, 0, DEV, 0x23, 0x00, 0x0A, 0x06});
    request(fx, (const uint8_t[]){0xE0, NET_A, 0, 7, 0, 0, 0, 0});
    expect(&fx->a, 0x581, 2, (const uint8_t[]){0x80, NET_A, 0, 7, 0x23, 0x00, 0x0A, 0x06});
    request(fx, (const uint8_t[]){0xE0, NET_C, 0, 0, 0, 0, 0, 0});
    expect(&fx->a, 0x581, 3, (const uint8_t[]){0x80, NET_C, 0, 0, 0x30, 0x00, 0x09, 0x06});
    assert_int_equal(co_gateway_stats(&fx->gw)->sdo_refused, 4);
    /* still served by the gateway itself */
    request(fx, (const uint8_t[]){0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0});
    expect(&fx->a, 0x581, 4, (const uint8_t[]){0x43, 0x00, 0x10, 0x00, 0x02, 0x03, 0x00, 0x00});
    assert_int_equal(tu_log_count_id(&fx->c, 0x605), 0);
    fx_free(fx);
}

/* An indication naming the gateway itself ends the connection. */
static void test_back_to_the_gateways_own_server(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    connect_3_5(fx);
    const uint8_t home[8] = {0xE0, NET_A, 0x00, GW, 0, 0, 0, 0};
    request(fx, home);
    expect(&fx->a, 0x581, 0, home);
    request(fx, (const uint8_t[]){0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0});
    expect(&fx->a, 0x581, 1, (const uint8_t[]){0x43, 0x00, 0x10, 0x00, 0x02, 0x03, 0x00, 0x00});
    assert_int_equal(tu_log_count_id(&fx->c, 0x605), 0);
    fx_free(fx);
}

/* Network 4 lies behind gateway node 9 on network 3: the indication goes on
 * to it; its confirmation connects, its refusal is relayed and ends it. */
static void test_indication_forwarded_to_the_next_gateway(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    assert_int_equal(co_gateway_set_route(&fx->gw, 4, NET_C, NEXT_GW), 0);
    const uint8_t ind_4_5[8] = {0xE0, 4, 0x00, DEV, 0, 0, 0, 0};
    request(fx, ind_4_5);
    expect(&fx->c, 0x600 + NEXT_GW, 0, ind_4_5);
    assert_int_equal(tu_log_count_id(&fx->a, 0x581), 0);   /* waits for the next gateway */
    /* a request before the confirmation: busy */
    request(fx, (const uint8_t[]){0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0});
    expect(&fx->a, 0x581, 0, (const uint8_t[]){0x80, 0x00, 0x20, 0x00, 0x23, 0x00, 0x0A, 0x06});
    assert_true(co_line_send(&fx->peer.line, 0x580 + NEXT_GW, ind_4_5, 8));
    settle(fx);
    expect(&fx->a, 0x581, 1, ind_4_5);
    const uint8_t up[8] = {0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0};
    request(fx, up);
    expect(&fx->c, 0x600 + NEXT_GW, 1, up);
    const uint8_t answer[8] = {0x43, 0x00, 0x20, 0x00, 1, 2, 3, 4};
    assert_true(co_line_send(&fx->peer.line, 0x580 + NEXT_GW, answer, 8));
    settle(fx);
    expect(&fx->a, 0x581, 2, answer);

    /* the next gateway refuses another indication */
    request(fx, (const uint8_t[]){0xE0, 4, 0x00, 6, 0, 0, 0, 0});
    const uint8_t refused[8] = {0x80, 4, 0x00, 6, 0x00, 0x00, 0x00, 0x08};
    assert_true(co_line_send(&fx->peer.line, 0x580 + NEXT_GW, refused, 8));
    settle(fx);
    expect(&fx->a, 0x581, 3, refused);
    request(fx, (const uint8_t[]){0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0});   /* own server */
    expect(&fx->a, 0x581, 4, (const uint8_t[]){0x43, 0x00, 0x10, 0x00, 0x02, 0x03, 0x00, 0x00});
    /* a silent next gateway: the indication times out on both sides */
    tu_log_clear(&fx->a);
    request(fx, ind_4_5);
    advance(fx, fx->a.now + (TIMEOUT_MS + 1) * TU_MS);
    expect(&fx->a, 0x581, 0, (const uint8_t[]){0x80, 4, 0x00, DEV, 0x00, 0x00, 0x04, 0x05});
    fx_free(fx);
}

/* ------------------------------------------------------------ the client side */

/* Our SDO client (two channels, 50 ms timeout) on the client's line. */
static void tool_client(fx_t *fx)
{
    co_stack_arena_init(&fx->tool_arena, fx->tool_memory, sizeof fx->tool_memory);
    co_stack_line_config_t lc = {.heartbeat_entries = 1};
    assert_int_equal(co_stack_init(&fx->tool, &fx->client.line, &lc,
                                   co_stack_arena_allocator(&fx->tool_arena)), CO_STACK_OK);
    co_stack_client_config_t cc = {.sessions = 2, .timeout_ms = 50};
    assert_int_equal(co_stack_client_init(&fx->tool, &cc), CO_STACK_OK);
}

typedef struct upload {
    co_sdo_request_t req;
    co_sdo_buffer_t sink;
    uint8_t data[32];
    bool done;
} upload_t;

static void upload_done(co_sdo_request_t *req)
{
    ((upload_t *)req->user)->done = true;
}

static void routed_upload(fx_t *fx, upload_t *u, uint8_t network, uint8_t node, uint16_t index)
{
    memset(u, 0, sizeof *u);
    u->sink.data = u->data;
    u->sink.capacity = sizeof u->data;
    u->req = (co_sdo_request_t){.server = GW, .index = index, .upload = true,
                                .sink = co_sdo_buffer_sink, .ctx = &u->sink,
                                .done = upload_done, .user = u, .network = network,
                                .network_node = node};
    co_line_set_time(&fx->client.line, fx->a.now);
    assert_int_equal(co_sdo_client_start(co_stack_sdo_client(&fx->tool), &u->req), 0);
    advance(fx, fx->a.now + 10 * TU_MS);
    assert_true(u->done);
}

static void own_upload(fx_t *fx, upload_t *u, uint16_t index)
{
    memset(u, 0, sizeof *u);
    u->sink.data = u->data;
    u->sink.capacity = sizeof u->data;
    u->req = (co_sdo_request_t){.server = DEV, .index = index, .upload = true,
                                .sink = co_sdo_buffer_sink, .ctx = &u->sink,
                                .done = upload_done, .user = u, .timeout_ms = 50};
    assert_int_equal(co_sdo_client_start(co_stack_sdo_client(&fx->gw_c.stack), &u->req), 0);
}

/* The gateway device runs an SDO client of its own on the target line (a
 * manager, a CiA 309 gateway does), whose receiver holds 0x581..0x5FF. The
 * seed refuses a connection only while that client is busy: while it talks
 * to the target node the indication is refused (0x060A0023); otherwise the
 * connection stands, the target's answers reach the relay through the
 * client's idle tap, and the client's own transfers keep their answers. */
static void test_relay_beside_the_gateways_own_client(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    upload_t own;
    co_stack_client_config_t cc = {.sessions = 2, .timeout_ms = 50};
    assert_int_equal(co_stack_client_init(&fx->gw_c.stack, &cc), CO_STACK_OK);
    const co_sdo_client_stats_t *cs = &co_stack_sdo_client(&fx->gw_c.stack)->stats;
    /* the client talks to node 5 (its answer lost): busy */
    fx->drop_answer = true;
    own_upload(fx, &own, 0x2000);
    settle(fx);
    assert_false(own.done);
    request(fx, IND_3_5);
    expect(&fx->a, 0x581, 0, (const uint8_t[]){0x80, NET_C, 0, DEV, 0x23, 0x00, 0x0A, 0x06});
    advance(fx, fx->a.now + 60 * TU_MS);
    assert_true(own.done);
    assert_int_equal(own.req.abort, CO_ABORT_TIMEOUT);
    tu_log_clear(&fx->a);
    tu_log_clear(&fx->c);
    /* idle now: the connection stands and the relay gets the answers */
    connect_3_5(fx);
    const uint8_t up[8] = {0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0};
    const uint8_t up_ok[8] = {0x43, 0x00, 0x20, 0x00, 0x78, 0x56, 0x34, 0x12};
    uint32_t idle = cs->rx_idle;
    request(fx, up);
    expect(&fx->c, 0x605, 0, up);
    expect(&fx->c, 0x585, 0, up_ok);
    expect(&fx->a, 0x581, 0, up_ok);
    assert_int_equal(cs->rx_idle, idle);   /* taken by the relay, not "idle" */
    /* the client's own transfer to node 5 meanwhile gets its answer */
    own_upload(fx, &own, 0x2001);
    advance(fx, fx->a.now + 10 * TU_MS);
    assert_true(own.done);
    assert_int_equal(own.req.abort, 0);
    assert_memory_equal(own.data, "hello gateway!", 14);
    assert_int_equal(tu_log_count_id(&fx->a, 0x581), 1);   /* nothing of it relayed */
    /* the relay still works after it */
    request(fx, up);
    expect(&fx->a, 0x581, 1, up_ok);
    assert_int_equal(co_gateway_stats(&fx->gw)->sdo_answers, 2);
    assert_int_equal(co_gateway_stats(&fx->gw)->sdo_timeouts, 0);
    fx_free(fx);
}

/* A block download whose last segment has a sequence number of 96..127:
 * its byte 0 (0x80 | seqno) is 0xE0..0xFF, the same top bits as a network
 * indication. It is a segment, not an indication: to the gateway's own
 * server (no connection) and relayed to the device (connected). */
static void flag_done(co_sdo_request_t *req)
{
    *(bool *)req->user = true;
}

static void block_download(fx_t *fx, uint8_t network, uint8_t node, uint32_t *abort)
{
    static uint8_t data[BIG];
    co_sdo_buffer_t src = {.data = data, .size = BIG};
    bool done = false;
    for (uint32_t i = 0; i < BIG; i++) {
        data[i] = (uint8_t)(i * 7u + network);
    }
    co_sdo_request_t req = {.server = GW, .index = 0x2100, .mode = CO_SDO_MODE_BLOCK,
                            .size = BIG, .source = co_sdo_buffer_source, .ctx = &src,
                            .done = flag_done, .user = &done, .network = network,
                            .network_node = node, .timeout_ms = 50};
    co_line_set_time(&fx->client.line, fx->a.now);
    assert_int_equal(co_sdo_client_start(co_stack_sdo_client(&fx->tool), &req), 0);
    settle(fx);
    advance(fx, fx->a.now + 200 * TU_MS);
    assert_true(done);
    *abort = req.abort;
}

static void test_block_download_last_segment_is_no_indication(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    uint32_t abort = 1;
    tool_client(fx);
    block_download(fx, 0, 0, &abort);
    assert_int_equal(abort, 0);
    assert_true(tu_log_find_id(&fx->a, 0x601, 0) >= 0);
    const co_od_entry_t *e = co_od_find(&fx->gw_a.od, 0x2100, 0);
    assert_non_null(e);
    assert_int_equal(e->length, BIG);
    assert_int_equal(co_od_value(&fx->gw_a.od, e)[BIG - 1], (uint8_t)((BIG - 1) * 7u));
    assert_int_equal(co_gateway_stats(&fx->gw)->sdo_refused, 0);
    /* relayed: the same transfer to device 5 on network 3 */
    block_download(fx, NET_C, DEV, &abort);
    assert_int_equal(abort, 0);
    e = co_od_find(&fx->dev.od, 0x2100, 0);
    assert_int_equal(e->length, BIG);
    assert_int_equal(co_od_value(&fx->dev.od, e)[BIG - 1], (uint8_t)((BIG - 1) * 7u + NET_C));
    assert_int_equal(co_gateway_stats(&fx->gw)->sdo_refused, 0);
    assert_int_equal(co_gateway_stats(&fx->gw)->sdo_connects, 1);
    /* and the connection still relays afterwards */
    block_download(fx, NET_C, DEV, &abort);
    assert_int_equal(abort, 0);
    fx_free(fx);
}

/* A routed request cancelled while its network indication is out: the
 * gateway may well have switched its connection already, so the client
 * must not keep assuming the old one (its next request would reach the
 * wrong node, or the gateway's own OD). */
static void test_cancel_during_indication_forgets_the_connection(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    tool_client(fx);
    co_sdo_client_t *client = co_stack_sdo_client(&fx->tool);
    upload_t u;
    routed_upload(fx, &u, NET_C, DEV, 0x2000);
    assert_int_equal(u.req.abort, 0);
    /* back to the gateway's own OD: the indication goes, then the cancel */
    memset(&u, 0, sizeof u);
    u.sink.data = u.data;
    u.sink.capacity = sizeof u.data;
    u.req = (co_sdo_request_t){.server = GW, .index = 0x1000, .upload = true,
                               .sink = co_sdo_buffer_sink, .ctx = &u.sink,
                               .done = upload_done, .user = &u};
    co_line_set_time(&fx->client.line, fx->a.now);
    assert_int_equal(co_sdo_client_start(client, &u.req), 0);
    assert_true(co_sdo_client_cancel(client, &u.req, 0));
    settle(fx);
    assert_int_equal(co_gateway_stats(&fx->gw)->sdo_connects, 2);   /* it did switch */
    /* device 5 again: the indication must go first, the answer is the device's */
    tu_log_clear(&fx->a);
    routed_upload(fx, &u, NET_C, DEV, 0x2000);
    assert_int_equal(u.req.abort, 0);
    assert_int_equal(tu_le_get(u.data, 4), 0x12345678);
    expect(&fx->a, 0x601, 0, IND_3_5);
    /* the other way round: to device 5, cancelled while its indication is
     * out (the gateway connects); a request for the gateway's own OD then
     * sends the indication of network 0 first and reads the gateway's */
    routed_upload(fx, &u, 0, 0, 0x1000);
    assert_int_equal(tu_le_get(u.data, 4), 0x302);
    memset(&u, 0, sizeof u);
    u.sink.data = u.data;
    u.sink.capacity = sizeof u.data;
    u.req = (co_sdo_request_t){.server = GW, .index = 0x2000, .upload = true,
                               .sink = co_sdo_buffer_sink, .ctx = &u.sink,
                               .done = upload_done, .user = &u, .network = NET_C,
                               .network_node = DEV};
    assert_int_equal(co_sdo_client_start(client, &u.req), 0);
    assert_true(co_sdo_client_cancel(client, &u.req, 0));
    settle(fx);
    tu_log_clear(&fx->a);
    routed_upload(fx, &u, 0, 0, 0x1000);
    assert_int_equal(u.req.abort, 0);
    assert_int_equal(tu_le_get(u.data, 4), 0x302);   /* not device 5's 0x191 */
    expect(&fx->a, 0x601, 0, (const uint8_t[]){0xE0, 0, 0, 0, 0, 0, 0, 0});
    fx_free(fx);
}

/* co_sdo_client with (network, node): the indication goes first, once per
 * connection; network 0 brings the gateway back to its own OD; a refusal
 * ends the request with the gateway's abort. */
static void test_client_reaches_a_node_through_the_gateway(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    tool_client(fx);
    upload_t u;
    routed_upload(fx, &u, NET_C, DEV, 0x2000);
    assert_int_equal(u.req.abort, 0);
    assert_int_equal(u.sink.size, 4);
    assert_int_equal(tu_le_get(u.data, 4), 0x12345678);
    expect(&fx->a, 0x601, 0, IND_3_5);
    expect(&fx->a, 0x601, 1, (const uint8_t[]){0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0});
    expect(&fx->c, 0x605, 0, (const uint8_t[]){0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0});
    /* connected already: no second indication */
    routed_upload(fx, &u, NET_C, DEV, 0x2001);
    assert_int_equal(u.req.abort, 0);
    assert_memory_equal(u.data, "hello gateway!", 14);
    assert_int_equal(tu_log_count_id(&fx->a, 0x601), 2 + 3);
    /* the gateway's own OD again */
    tu_log_clear(&fx->a);
    routed_upload(fx, &u, 0, 0, 0x1000);
    assert_int_equal(u.req.abort, 0);
    assert_int_equal(tu_le_get(u.data, 4), 0x302);
    expect(&fx->a, 0x601, 0, (const uint8_t[]){0xE0, 0, 0, 0, 0, 0, 0, 0});
    expect(&fx->a, 0x581, 0, (const uint8_t[]){0xE0, 0, 0, 0, 0, 0, 0, 0});
    /* a network no route reaches */
    routed_upload(fx, &u, 9, DEV, 0x2000);
    assert_int_equal(u.req.abort, CO_GATEWAY_ABORT_NO_ROUTE);
    assert_true(u.req.abort_from_server);
    /* a routed request without its gateway is refused at the start */
    u.req.server = 0;
    u.req.network = NET_C;
    assert_int_equal(co_sdo_client_start(co_stack_sdo_client(&fx->tool), &u.req),
                     CO_ABORT_GENERAL);
    fx_free(fx);
}

/* ------------------------------------------------------- into an fd network */

/* The gateway's fd line gets a USDO client (node-id GW), the fd device 6
 * joins network 2, and the gateway a buffer of FD_BUFFER bytes. */
static void fd_setup(fx_t *fx)
{
    co_stack_client_config_t cc = {.sessions = 2, .node_id = GW, .timeout_ms = TIMEOUT_MS};
    assert_int_equal(co_stack_client_init(&fx->gw_b.stack, &cc), CO_STACK_OK);
    node_init(&fx->b, &fx->fdev, CO_MODE_FD, FDEV, device_rows, ROWS(device_rows));
    co_gateway_set_sdo_buffer(&fx->gw, fx->fd_buffer, sizeof fx->fd_buffer);
    co_membus_set_fault(&fx->b.bus, drop_fd_segments, fx);
    settle(fx);
    tu_log_clear(&fx->a);
    tu_log_clear(&fx->b);
    tu_log_clear(&fx->c);
}

/* The k-th fd frame with `id` must be exactly these bytes, byte 2 (the
 * session-ID the USDO client picked, never 0) taken from the frame. */
static void expect_fd(const tu_bus_t *tb, uint32_t id, size_t k, const uint8_t *data, uint8_t len)
{
    long i = tu_log_find_id(tb, id, k);
    uint8_t want[64];
    assert_true(i >= 0);
    assert_true(len <= sizeof want);
    memcpy(want, data, len);
    want[2] = tb->log[i].frame.data[2];
    assert_int_not_equal(want[2], 0);
    tu_assert_logged(tb, i, id, want, len);
}

static const uint8_t IND_2_6[8] = {0xE0, NET_B, 0x00, FDEV, 0, 0, 0, 0};

static void connect_2_6(fx_t *fx)
{
    request(fx, IND_2_6);
    expect(&fx->a, 0x581, 0, IND_2_6);
    assert_int_equal(fx->b.log_count, 0);   /* attached: nothing sent */
    tu_log_clear(&fx->a);
}

/* Expedited both ways: the client's upload initiate becomes a USDO upload
 * (0x11), the device's answer an expedited SDO answer; the client's
 * expedited download a USDO expedited download (0x01, DOMAIN, 4 bytes),
 * answered 0x60 once the device confirmed (0x21). */
static void test_fd_expedited_translated(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    fd_setup(fx);
    connect_2_6(fx);
    request(fx, (const uint8_t[]){0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0});
    expect_fd(&fx->b, 0x600 + GW, 0, (const uint8_t[]){FDEV, 0x11, 0, 0x00, 0x00, 0x20}, 6);
    assert_int_equal(tu_log_count_id(&fx->b, 0x580 + FDEV), 1);
    expect(&fx->a, 0x581, 0, (const uint8_t[]){0x43, 0x00, 0x20, 0x00, 0x78, 0x56, 0x34, 0x12});
    request(fx, (const uint8_t[]){0x23, 0x00, 0x20, 0x00, 0xBE, 0xBA, 0xFE, 0xCA});
    expect_fd(&fx->b, 0x600 + GW, 1,
              (const uint8_t[]){FDEV, 0x01, 0, 0x00, 0x00, 0x20, 0x0F, 4, 0xBE, 0xBA, 0xFE, 0xCA},
              12);
    expect_fd(&fx->b, 0x580 + FDEV, 1, (const uint8_t[]){GW, 0x21, 0, 0x00, 0x00, 0x20}, 6);
    expect(&fx->a, 0x581, 1, (const uint8_t[]){0x60, 0x00, 0x20, 0x00, 0, 0, 0, 0});
    uint32_t v = 0;
    assert_true(co_od_get_u32(&fx->fdev.od, 0x2000, 0, &v));
    assert_int_equal(v, 0xCAFEBABE);
    /* two bytes, size indicated (n = 2) */
    request(fx, (const uint8_t[]){0x2B, 0x17, 0x10, 0x00, 0xF4, 0x01, 0, 0});
    expect_fd(&fx->b, 0x600 + GW, 2,
              (const uint8_t[]){FDEV, 0x01, 0, 0x00, 0x17, 0x10, 0x0F, 2, 0xF4, 0x01, 0, 0},
              12);   /* 10 bytes padded to the fd length 12 */
    expect(&fx->a, 0x581, 2, (const uint8_t[]){0x60, 0x17, 0x10, 0x00, 0, 0, 0, 0});
    const co_gateway_stats_t *st = co_gateway_stats(&fx->gw);
    assert_int_equal(st->sdo_translated, 3);
    assert_int_equal(st->sdo_translate_failed, 0);
    advance(fx, fx->a.now + 3 * TIMEOUT_MS * TU_MS);   /* nothing left armed */
    assert_int_equal(tu_log_count_id(&fx->a, 0x581), 3);
    fx_free(fx);
}

/* Segmented on the client's side: a 14-byte upload is served from the
 * buffer after one USDO upload; a 100-byte download (buffer 100 bytes)
 * is collected, then sent as a USDO segmented download (0x02 size 100,
 * 0x03 with 60 bytes, 0x04 with 40), and the client's last segment is
 * answered once the device confirmed it. */
static void test_fd_segmented_translated(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    fd_setup(fx);
    uint8_t big[100];
    co_gateway_set_sdo_buffer(&fx->gw, big, sizeof big);
    connect_2_6(fx);
    request(fx, (const uint8_t[]){0x40, 0x01, 0x20, 0x00, 0, 0, 0, 0});
    expect_fd(&fx->b, 0x600 + GW, 0, (const uint8_t[]){FDEV, 0x11, 0, 0x00, 0x01, 0x20}, 6);
    expect(&fx->a, 0x581, 0, (const uint8_t[]){0x41, 0x01, 0x20, 0x00, 14, 0, 0, 0});
    request(fx, (const uint8_t[]){0x60, 0, 0, 0, 0, 0, 0, 0});
    expect(&fx->a, 0x581, 1, (const uint8_t[]){0x00, 'h', 'e', 'l', 'l', 'o', ' ', 'g'});
    request(fx, (const uint8_t[]){0x70, 0, 0, 0, 0, 0, 0, 0});
    expect(&fx->a, 0x581, 2, (const uint8_t[]){0x11, 'a', 't', 'e', 'w', 'a', 'y', '!'});
    assert_int_equal(tu_log_count_id(&fx->b, 0x600 + GW), 1);   /* one USDO transfer */

    tu_log_clear(&fx->a);
    tu_log_clear(&fx->b);
    uint8_t value[100];
    for (unsigned i = 0; i < sizeof value; i++) {
        value[i] = (uint8_t)('A' + i % 26);
    }
    request(fx, (const uint8_t[]){0x21, 0x03, 0x20, 0x00, 100, 0, 0, 0});
    expect(&fx->a, 0x581, 0, (const uint8_t[]){0x60, 0x03, 0x20, 0x00, 0, 0, 0, 0});
    uint8_t toggle = 0;
    for (unsigned off = 0; off < sizeof value; off += 7) {
        unsigned n = sizeof value - off < 7 ? sizeof value - off : 7;
        bool last = off + n == sizeof value;
        uint8_t seg[8] = {(uint8_t)(toggle << 4 | (7 - n) << 1 | (last ? 1 : 0))};
        memcpy(seg + 1, value + off, n);
        request(fx, seg);
        if (!last) {
            expect(&fx->a, 0x581, 1 + off / 7,
                   (const uint8_t[]){(uint8_t)(0x20 | toggle << 4), 0, 0, 0, 0, 0, 0, 0});
        }
        toggle ^= 1;
    }
    expect_fd(&fx->b, 0x600 + GW, 0,
              (const uint8_t[]){FDEV, 0x02, 0, 0x00, 0x03, 0x20, 0x0F, 0, 100, 0, 0, 0}, 12);
    uint8_t seg1[64] = {FDEV, 0x03, 0, 1};   /* counter of the first segment: 1 */
    memcpy(seg1 + 4, value, 60);
    long i1 = tu_log_find_id(&fx->b, 0x600 + GW, 1);
    assert_true(i1 >= 0);
    seg1[3] = fx->b.log[i1].frame.data[3];
    expect_fd(&fx->b, 0x600 + GW, 1, seg1, 64);
    uint8_t seg2[48] = {FDEV, 0x04, 0, 40};
    memcpy(seg2 + 4, value + 60, 40);
    long i2 = tu_log_find_id(&fx->b, 0x600 + GW, 2);
    assert_true(i2 >= 0);
    assert_true(fx->b.log[i2].frame.len >= 44);   /* 44 bytes, padded to an fd length */
    assert_int_equal(fx->b.log[i2].frame.data[0], FDEV);
    assert_int_equal(fx->b.log[i2].frame.data[1], 0x04);
    assert_memory_equal(fx->b.log[i2].frame.data + 3, seg2 + 3, 41);
    /* 15 segments: the last one (toggle 0) answered after the device's 0x24 */
    expect(&fx->a, 0x581, 15, (const uint8_t[]){0x20, 0, 0, 0, 0, 0, 0, 0});
    assert_int_equal(tu_log_count_id(&fx->a, 0x581), 16);
    uint8_t got[100];
    uint32_t got_len = 0;
    assert_int_equal(co_od_get(&fx->fdev.od, 0x2003, 0, got, sizeof got, &got_len), 0);
    assert_int_equal(got_len, 100);
    assert_memory_equal(got, value, 100);
    assert_int_equal(co_gateway_stats(&fx->gw)->sdo_translated, 2);
    fx_free(fx);
}

/* A silent fd target: the USDO client's timeout aborts it (0x12 on the fd
 * bus) and the client hears 0x05040000; the client's own abort while the
 * USDO upload runs reaches the target mapped (0x05040000 -> 0x12 is the
 * same code here, so a read-only abort 0x06010002 -> 0x32 is used) and no
 * answer follows; the target's abort (no such object, 0x33) reaches the
 * client as 0x06020000. */
static void test_fd_timeouts_and_aborts_mapped(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    fd_setup(fx);
    const uint8_t ind_2_7[8] = {0xE0, NET_B, 0x00, 7, 0, 0, 0, 0};
    request(fx, ind_2_7);
    tu_log_clear(&fx->a);
    request(fx, (const uint8_t[]){0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0});
    uint64_t sent = fx->a.now;
    advance(fx, sent + (TIMEOUT_MS - 1) * TU_MS);
    assert_int_equal(tu_log_count_id(&fx->a, 0x581), 0);   /* not before the timeout */
    advance(fx, sent + (TIMEOUT_MS + 5) * TU_MS);
    expect_fd(&fx->b, 0x600 + GW, 1, (const uint8_t[]){7, 0x7F, 0, 0x00, 0x00, 0x20, 0x12}, 7);
    expect(&fx->a, 0x581, 0, (const uint8_t[]){0x80, 0x00, 0x20, 0x00, 0x00, 0x00, 0x04, 0x05});

    /* the client aborts while the target is silent: the USDO transfer ends
     * with the mapped code, nothing more reaches the client */
    request(fx, (const uint8_t[]){0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0});
    request(fx, (const uint8_t[]){0x80, 0x00, 0x20, 0x00, 0x02, 0x00, 0x01, 0x06});
    expect_fd(&fx->b, 0x600 + GW, 3, (const uint8_t[]){7, 0x7F, 0, 0x00, 0x00, 0x20, 0x32}, 7);
    advance(fx, fx->a.now + 3 * TIMEOUT_MS * TU_MS);
    assert_int_equal(tu_log_count_id(&fx->a, 0x581), 1);
    assert_int_equal(tu_log_count_id(&fx->b, 0x600 + GW), 4);

    /* the target's abort, mapped back */
    request(fx, IND_2_6);
    tu_log_clear(&fx->a);
    request(fx, (const uint8_t[]){0x40, 0xFF, 0x2F, 0x00, 0, 0, 0, 0});
    expect(&fx->a, 0x581, 0, (const uint8_t[]){0x80, 0xFF, 0x2F, 0x00, 0x00, 0x00, 0x02, 0x06});
    const co_gateway_stats_t *st = co_gateway_stats(&fx->gw);
    assert_int_equal(st->sdo_translate_failed, 2);
    assert_int_equal(st->sdo_translated, 0);
    fx_free(fx);
}

/* The buffer (64 bytes): a download announced larger is refused at once,
 * an upload larger is stopped (the gateway's USDO abort 0x16 on the fd
 * bus) and both reach the client as 0x05040005; while a segmented
 * transfer of one client holds the buffer, a client of another line is
 * told busy (0x060A0023); a client silent mid-transfer is aborted with
 * 0x05040000 and the buffer is free again; a block initiate is refused
 * with 0x05040001 (a client then goes segmented). */
static void test_fd_buffer_limits_busy_and_block(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    fd_setup(fx);
    connect_2_6(fx);
    request(fx, (const uint8_t[]){0x21, 0x03, 0x20, 0x00, 100, 0, 0, 0});
    expect(&fx->a, 0x581, 0, (const uint8_t[]){0x80, 0x03, 0x20, 0x00, 0x05, 0x00, 0x04, 0x05});
    assert_int_equal(fx->b.log_count, 0);
    co_gateway_set_sdo_buffer(&fx->gw, fx->fd_buffer, 100);
    request(fx, (const uint8_t[]){0x23, 0x03, 0x20, 0x00, 'a', 'b', 'c', 'd'});   /* "abcd" */
    expect(&fx->a, 0x581, 1, (const uint8_t[]){0x60, 0x03, 0x20, 0x00, 0, 0, 0, 0});
    co_gateway_set_sdo_buffer(&fx->gw, fx->fd_buffer, 3);
    tu_log_clear(&fx->b);
    request(fx, (const uint8_t[]){0x40, 0x03, 0x20, 0x00, 0, 0, 0, 0});   /* 4 bytes > 3 */
    expect(&fx->a, 0x581, 2, (const uint8_t[]){0x80, 0x03, 0x20, 0x00, 0x05, 0x00, 0x04, 0x05});
    assert_int_equal(co_gateway_stats(&fx->gw)->sdo_too_big, 2);
    co_gateway_set_sdo_buffer(&fx->gw, fx->fd_buffer, sizeof fx->fd_buffer);

    /* client 1 holds the buffer (segmented download begun) */
    request(fx, (const uint8_t[]){0x21, 0x03, 0x20, 0x00, 20, 0, 0, 0});
    expect(&fx->a, 0x581, 3, (const uint8_t[]){0x60, 0x03, 0x20, 0x00, 0, 0, 0, 0});
    /* a client on network 3 connects to the same device and uploads */
    assert_true(co_line_send(&fx->peer.line, 0x600 + GW, IND_2_6, 8));
    settle(fx);
    expect(&fx->c, 0x581, 0, IND_2_6);
    assert_true(co_line_send(&fx->peer.line, 0x600 + GW,
                             (const uint8_t[]){0x40, 0x01, 0x20, 0x00, 0, 0, 0, 0}, 8));
    settle(fx);
    expect(&fx->c, 0x581, 1, (const uint8_t[]){0x80, 0x01, 0x20, 0x00, 0x23, 0x00, 0x0A, 0x06});
    assert_int_equal(co_gateway_stats(&fx->gw)->sdo_buffer_busy, 1);
    /* client 1 goes silent: aborted after the timeout, the buffer freed */
    advance(fx, fx->a.now + (TIMEOUT_MS + 1) * TU_MS);
    expect(&fx->a, 0x581, 4, (const uint8_t[]){0x80, 0x03, 0x20, 0x00, 0x00, 0x00, 0x04, 0x05});
    assert_true(co_line_send(&fx->peer.line, 0x600 + GW,
                             (const uint8_t[]){0x40, 0x01, 0x20, 0x00, 0, 0, 0, 0}, 8));
    settle(fx);
    expect(&fx->c, 0x581, 2, (const uint8_t[]){0x41, 0x01, 0x20, 0x00, 14, 0, 0, 0});

    /* block download initiate: not translated */
    request(fx, (const uint8_t[]){0xC6, 0x03, 0x20, 0x00, 20, 0, 0, 0});
    expect(&fx->a, 0x581, 5, (const uint8_t[]){0x80, 0x03, 0x20, 0x00, 0x01, 0x00, 0x04, 0x05});
    fx_free(fx);
}

/* The gateway's upload into a too-small buffer, seen on the fd bus: the
 * device announces 14 bytes, the gateway's USDO client stops it (0x16). */
static void test_fd_upload_larger_than_the_buffer(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    fd_setup(fx);
    co_gateway_set_sdo_buffer(&fx->gw, fx->fd_buffer, 10);
    connect_2_6(fx);
    request(fx, (const uint8_t[]){0x40, 0x01, 0x20, 0x00, 0, 0, 0, 0});
    expect(&fx->a, 0x581, 0, (const uint8_t[]){0x80, 0x01, 0x20, 0x00, 0x05, 0x00, 0x04, 0x05});
    assert_int_equal(co_gateway_stats(&fx->gw)->sdo_too_big, 1);
    expect_fd(&fx->b, 0x600 + GW, 0, (const uint8_t[]){FDEV, 0x11, 0, 0x00, 0x01, 0x20}, 6);
    expect_fd(&fx->b, 0x600 + GW, 1, (const uint8_t[]){FDEV, 0x7F, 0, 0x00, 0x01, 0x20, 0x16}, 7);
    fx_free(fx);
}

/* A 100-byte upload the device sends segmented (0x32 size 100, then 0x33 /
 * 0x34 on the gateway's 0x13 requests): the client's initiate is answered
 * with the size as soon as the device announced it, before the data came;
 * the client's segments carry the value. Then the device goes silent after
 * announcing: the client's segment request waits, the USDO timeout stops
 * the device (0x12) and the client hears 0x05040000. */
static void test_fd_upload_streamed(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    fd_setup(fx);
    uint8_t big[100];
    co_gateway_set_sdo_buffer(&fx->gw, big, sizeof big);
    uint8_t value[100];
    for (unsigned i = 0; i < sizeof value; i++) {
        value[i] = (uint8_t)(0x20 + i);
    }
    assert_int_equal(co_od_put(&fx->fdev.od, 0x2003, 0, value, sizeof value), 0);
    connect_2_6(fx);
    fx->drop_fd_segments = true;   /* hold the data back: only the announcement passes */
    request(fx, (const uint8_t[]){0x40, 0x03, 0x20, 0x00, 0, 0, 0, 0});
    expect_fd(&fx->b, 0x580 + FDEV, 0,
              (const uint8_t[]){GW, 0x32, 0, 0x00, 0x03, 0x20, 0x09, 0, 100, 0, 0, 0}, 12);
    expect(&fx->a, 0x581, 0, (const uint8_t[]){0x41, 0x03, 0x20, 0x00, 100, 0, 0, 0});
    request(fx, (const uint8_t[]){0x60, 0, 0, 0, 0, 0, 0, 0});
    assert_int_equal(tu_log_count_id(&fx->a, 0x581), 1);   /* waits for the data */
    advance(fx, fx->a.now + (TIMEOUT_MS + 5) * TU_MS);
    expect_fd(&fx->b, 0x600 + GW, 2, (const uint8_t[]){FDEV, 0x7F, 0, 0x00, 0x03, 0x20, 0x12}, 7);
    expect(&fx->a, 0x581, 1, (const uint8_t[]){0x80, 0x03, 0x20, 0x00, 0x00, 0x00, 0x04, 0x05});

    fx->drop_fd_segments = false;
    tu_log_clear(&fx->a);
    tu_log_clear(&fx->b);
    request(fx, (const uint8_t[]){0x40, 0x03, 0x20, 0x00, 0, 0, 0, 0});
    expect(&fx->a, 0x581, 0, (const uint8_t[]){0x41, 0x03, 0x20, 0x00, 100, 0, 0, 0});
    uint8_t toggle = 0;
    for (unsigned off = 0; off < sizeof value; off += 7) {
        unsigned n = sizeof value - off < 7 ? sizeof value - off : 7;
        bool last = off + n == sizeof value;
        request(fx, (const uint8_t[]){(uint8_t)(0x60 | toggle << 4), 0, 0, 0, 0, 0, 0, 0});
        uint8_t seg[8] = {(uint8_t)(toggle << 4 | (7 - n) << 1 | (last ? 1 : 0))};
        memcpy(seg + 1, value + off, n);
        expect(&fx->a, 0x581, 1 + off / 7, seg);
        toggle ^= 1;
    }
    /* the device's side: 0x11, 0x32, then 0x13 / 0x33 and the last 0x34 */
    expect_fd(&fx->b, 0x600 + GW, 1, (const uint8_t[]){FDEV, 0x13, 0, 0}, 4);
    assert_int_equal(co_gateway_stats(&fx->gw)->sdo_translated, 1);
    advance(fx, fx->a.now + 3 * TIMEOUT_MS * TU_MS);
    assert_int_equal(tu_log_count_id(&fx->a, 0x581), 16);
    fx_free(fx);
}

/* ------------------------------------------------------- the gateway rebuilt */

/* What the runtime does when a line joins or a node appears: the open
 * connections end, the gateway is made anew over the same lines and keeps
 * its routes, counters and the list of ended connections. */
static void rebuild(fx_t *fx)
{
    co_gateway_end_connections(&fx->gw);
    co_gateway_stats_t stats = fx->gw.stats;
    co_gateway_ended_t ended = fx->gw.ended;
    co_gateway_deinit(&fx->gw);
    co_gateway_init(&fx->gw, NULL, NULL);
    fx->gw.stats = stats;
    fx->gw.ended = ended;
    co_gateway_set_sdo_timeout(&fx->gw, TIMEOUT_MS);
    co_gateway_set_sdo_buffer(&fx->gw, fx->fd_buffer, sizeof fx->fd_buffer);
    assert_int_equal(co_gateway_add_port(&fx->gw, &fx->gw_a.stack, NET_A), CO_GATEWAY_OK);
    assert_int_equal(co_gateway_add_port(&fx->gw, &fx->gw_b.stack, NET_B), CO_GATEWAY_OK);
    assert_int_equal(co_gateway_add_port(&fx->gw, &fx->gw_c.stack, NET_C), CO_GATEWAY_OK);
    settle(fx);
}

static const uint8_t ENDED_2003[8] = {0x80, 0x03, 0x20, 0x00, 0x23, 0x00, 0x0A, 0x06};

/* A relayed segmented download in the middle when the gateway is rebuilt:
 * the client and the device both hear abort 0x060A0023 with the transfer's
 * multiplexer (not the segment's data bytes), no timeout follows; the
 * client's next request on that channel is refused the same way instead of
 * reaching the gateway's own OD; after a new indication it is relayed. */
static void test_rebuild_ends_a_relayed_transfer(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    connect_3_5(fx);
    request(fx, (const uint8_t[]){0x21, 0x03, 0x20, 0x00, 14, 0, 0, 0});
    expect(&fx->a, 0x581, 0, (const uint8_t[]){0x60, 0x03, 0x20, 0x00, 0, 0, 0, 0});
    request(fx, (const uint8_t[]){0x00, 'a', 'b', 'c', 'd', 'e', 'f', 'g'});
    expect(&fx->a, 0x581, 1, (const uint8_t[]){0x20, 0, 0, 0, 0, 0, 0, 0});
    rebuild(fx);
    expect(&fx->a, 0x581, 2, ENDED_2003);
    expect(&fx->c, 0x605, 2, ENDED_2003);
    const co_gateway_stats_t *st = co_gateway_stats(&fx->gw);
    assert_int_equal(st->connections_ended, 1);
    advance(fx, fx->a.now + 3 * TIMEOUT_MS * TU_MS);
    assert_int_equal(st->sdo_timeouts, 0);
    assert_int_equal(tu_log_count_id(&fx->a, 0x581), 3);
    /* the client still thinks it is connected: refused, nothing relayed */
    request(fx, (const uint8_t[]){0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0});
    expect(&fx->a, 0x581, 3, (const uint8_t[]){0x80, 0x00, 0x20, 0x00, 0x23, 0x00, 0x0A, 0x06});
    assert_int_equal(tu_log_count_id(&fx->c, 0x605), 3);
    /* connected anew, relayed again */
    request(fx, IND_3_5);
    expect(&fx->a, 0x581, 4, IND_3_5);
    request(fx, (const uint8_t[]){0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0});
    expect(&fx->a, 0x581, 5, (const uint8_t[]){0x43, 0x00, 0x20, 0x00, 0x78, 0x56, 0x34, 0x12});
    fx_free(fx);
}

/* An idle connection ends too: its client's next request is refused once
 * (0x060A0023), the one after goes to the gateway's own server as for
 * any client without a connection. */
static void test_rebuild_ends_an_idle_connection(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    connect_3_5(fx);
    rebuild(fx);
    assert_int_equal(co_gateway_stats(&fx->gw)->connections_ended, 1);
    tu_log_clear(&fx->a);
    tu_log_clear(&fx->c);
    request(fx, (const uint8_t[]){0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0});
    expect(&fx->a, 0x581, 0, (const uint8_t[]){0x80, 0x00, 0x10, 0x00, 0x23, 0x00, 0x0A, 0x06});
    request(fx, (const uint8_t[]){0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0});
    expect(&fx->a, 0x581, 1, (const uint8_t[]){0x43, 0x00, 0x10, 0x00, 0x02, 0x03, 0x00, 0x00});
    assert_int_equal(tu_log_count_id(&fx->c, 0x605), 0);
    fx_free(fx);
}

/* A translated upload whose USDO transfer runs (node 7 of the fd network
 * is silent) when the gateway is rebuilt: the client hears 0x060A0023,
 * the fd bus the gateway's USDO abort 0x70 (its CiA 1301 counterpart). */
static void test_rebuild_ends_a_translated_transfer(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    fd_setup(fx);
    request(fx, (const uint8_t[]){0xE0, NET_B, 0x00, 7, 0, 0, 0, 0});
    tu_log_clear(&fx->a);
    request(fx, (const uint8_t[]){0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0});
    expect_fd(&fx->b, 0x600 + GW, 0, (const uint8_t[]){7, 0x11, 0, 0x00, 0x00, 0x20}, 6);
    rebuild(fx);
    expect(&fx->a, 0x581, 0, (const uint8_t[]){0x80, 0x00, 0x20, 0x00, 0x23, 0x00, 0x0A, 0x06});
    expect_fd(&fx->b, 0x600 + GW, 1, (const uint8_t[]){7, 0x7F, 0, 0x00, 0x00, 0x20, 0x70}, 7);
    assert_int_equal(co_gateway_stats(&fx->gw)->connections_ended, 1);
    advance(fx, fx->a.now + 3 * TIMEOUT_MS * TU_MS);
    assert_int_equal(tu_log_count_id(&fx->a, 0x581), 1);   /* nothing more */
    assert_int_equal(tu_log_count_id(&fx->b, 0x600 + GW), 2);
    fx_free(fx);
}

/* Our SDO client, connected to network 3 node 5 through the gateway, idle
 * when the gateway is rebuilt: its next routed request is refused
 * 0x060A0023, so it sends the network indication again and the initiate
 * after it; the caller sees the value, not the rebuild. */
static void test_client_reconnects_after_a_rebuild(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    tool_client(fx);
    upload_t u;
    routed_upload(fx, &u, NET_C, DEV, 0x2000);
    assert_int_equal(u.req.abort, 0);
    rebuild(fx);
    tu_log_clear(&fx->a);
    routed_upload(fx, &u, NET_C, DEV, 0x2001);
    assert_int_equal(u.req.abort, 0);
    assert_memory_equal(u.data, "hello gateway!", 14);
    const uint8_t up[8] = {0x40, 0x01, 0x20, 0x00, 0, 0, 0, 0};
    expect(&fx->a, 0x601, 0, up);
    expect(&fx->a, 0x581, 0, (const uint8_t[]){0x80, 0x01, 0x20, 0x00, 0x23, 0x00, 0x0A, 0x06});
    expect(&fx->a, 0x601, 1, IND_3_5);
    expect(&fx->a, 0x581, 1, IND_3_5);
    expect(&fx->a, 0x601, 2, up);
    fx_free(fx);
}

/* ------------------------------------------- buffered, into a classic network */

enum { PEER = 7 };   /* a node on network 3 answered by hand (fx->peer) */

/* The gateway's classic line 3 gets an SDO client (holding 0x581..0x5FF) and
 * the gateway a buffer of `size` bytes: transfers to nodes of network 3 go
 * through the buffer where they can. */
static uint8_t classic_buffer[BIG + 100];

static void classic_setup(fx_t *fx, uint32_t size)
{
    co_stack_client_config_t cc = {.sessions = 2, .timeout_ms = TIMEOUT_MS};
    assert_int_equal(co_stack_client_init(&fx->gw_c.stack, &cc), CO_STACK_OK);
    co_gateway_set_sdo_buffer(&fx->gw, classic_buffer, size);
    settle(fx);
    connect_3_5(fx);
}

/* The client reads the 14-byte string of device 5: the gateway's own client
 * uploads it from the device (normal upload, its segments requested at
 * once, before the client asks for any); the client's initiate is answered
 * with the size the device announced and its segments from the buffer. An
 * expedited value costs one exchange on each side, as relayed. */
static void test_classic_upload_buffered(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    classic_setup(fx, sizeof classic_buffer);
    request(fx, (const uint8_t[]){0x40, 0x01, 0x20, 0x00, 0, 0, 0, 0});
    expect(&fx->c, 0x605, 0, (const uint8_t[]){0x40, 0x01, 0x20, 0x00, 0, 0, 0, 0});
    expect(&fx->c, 0x585, 0, (const uint8_t[]){0x41, 0x01, 0x20, 0x00, 14, 0, 0, 0});
    expect(&fx->a, 0x581, 0, (const uint8_t[]){0x41, 0x01, 0x20, 0x00, 14, 0, 0, 0});
    /* the device's segments are already in the gateway */
    expect(&fx->c, 0x605, 1, (const uint8_t[]){0x60, 0, 0, 0, 0, 0, 0, 0});
    expect(&fx->c, 0x605, 2, (const uint8_t[]){0x70, 0, 0, 0, 0, 0, 0, 0});
    assert_int_equal(tu_log_count_id(&fx->a, 0x581), 1);
    request(fx, (const uint8_t[]){0x60, 0, 0, 0, 0, 0, 0, 0});
    expect(&fx->a, 0x581, 1, (const uint8_t[]){0x00, 'h', 'e', 'l', 'l', 'o', ' ', 'g'});
    request(fx, (const uint8_t[]){0x70, 0, 0, 0, 0, 0, 0, 0});
    expect(&fx->a, 0x581, 2, (const uint8_t[]){0x11, 'a', 't', 'e', 'w', 'a', 'y', '!'});
    assert_int_equal(tu_log_count_id(&fx->c, 0x605), 3);   /* nothing more to the device */
    request(fx, (const uint8_t[]){0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0});
    expect(&fx->c, 0x585, 3, (const uint8_t[]){0x43, 0x00, 0x20, 0x00, 0x78, 0x56, 0x34, 0x12});
    expect(&fx->a, 0x581, 3, (const uint8_t[]){0x43, 0x00, 0x20, 0x00, 0x78, 0x56, 0x34, 0x12});
    /* an object the device lacks: its abort reaches the client */
    request(fx, (const uint8_t[]){0x40, 0xFF, 0x2F, 0x00, 0, 0, 0, 0});
    expect(&fx->a, 0x581, 4, (const uint8_t[]){0x80, 0xFF, 0x2F, 0x00, 0x00, 0x00, 0x02, 0x06});
    assert_int_equal(co_gateway_stats(&fx->gw)->sdo_translated, 2);
    assert_int_equal(co_gateway_stats(&fx->gw)->sdo_translate_failed, 1);
    fx_free(fx);
}

/* A segmented download to node 7 (answered by hand): the initiate is relayed
 * and the node's 0x60 too; from then on the gateway answers each client
 * segment at once and hands the segments to the node one by one as it
 * confirms them (the node sees the client's frames byte for byte); the
 * client's last segment is answered by the node's own confirmation. */
static void peer_answers(fx_t *fx, const uint8_t *data)
{
    assert_true(co_line_send(&fx->peer.line, 0x580 + PEER, data, 8));
    settle(fx);
}

static void connect_3_peer(fx_t *fx)
{
    co_membus_set_fault(&fx->c.bus, NULL, NULL);
    request(fx, (const uint8_t[]){0xE0, NET_C, 0x00, PEER, 0, 0, 0, 0});
    tu_log_clear(&fx->a);
    tu_log_clear(&fx->c);
}

static void test_classic_download_pipelined(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    connect_3_peer(fx);
    const uint8_t init[8] = {0x21, 0x03, 0x20, 0x00, 20, 0, 0, 0};
    const uint8_t seg1[8] = {0x00, 't', 'w', 'e', 'n', 't', 'y', ' '};
    const uint8_t seg2[8] = {0x10, 'b', 'y', 't', 'e', 's', ' ', 'w'};
    const uint8_t seg3[8] = {0x03, 'r', 'i', 't', 't', 'e', 'n', 0};   /* last, 6 bytes */
    const uint8_t ack0[8] = {0x20}, ack1[8] = {0x30};
    request(fx, init);
    expect(&fx->c, 0x607, 0, init);
    assert_int_equal(tu_log_count_id(&fx->a, 0x581), 0);   /* the node decides */
    peer_answers(fx, (const uint8_t[]){0x60, 0x03, 0x20, 0x00, 0, 0, 0, 0});
    expect(&fx->a, 0x581, 0, (const uint8_t[]){0x60, 0x03, 0x20, 0x00, 0, 0, 0, 0});
    request(fx, seg1);
    expect(&fx->a, 0x581, 1, ack0);   /* answered by the gateway */
    expect(&fx->c, 0x607, 1, seg1);
    request(fx, seg2);
    expect(&fx->a, 0x581, 2, ack1);   /* at once, though the node has not confirmed seg1 */
    assert_int_equal(tu_log_count_id(&fx->c, 0x607), 2);   /* seg2 waits for the node */
    peer_answers(fx, ack0);
    expect(&fx->c, 0x607, 2, seg2);
    assert_int_equal(tu_log_count_id(&fx->a, 0x581), 3);   /* the node's 0x20 is not relayed */
    request(fx, seg3);
    assert_int_equal(tu_log_count_id(&fx->a, 0x581), 3);   /* the last one: the node answers */
    assert_int_equal(tu_log_count_id(&fx->c, 0x607), 3);
    peer_answers(fx, ack1);
    expect(&fx->c, 0x607, 3, seg3);
    assert_int_equal(tu_log_count_id(&fx->a, 0x581), 3);
    peer_answers(fx, ack0);
    expect(&fx->a, 0x581, 3, ack0);   /* the node's confirmation of the value */
    assert_int_equal(co_gateway_stats(&fx->gw)->sdo_pipelined, 2);
    assert_int_equal(co_gateway_stats(&fx->gw)->sdo_timeouts, 0);
    fx_free(fx);
}

/* At most CO_GATEWAY_SDO_PIPE_DEPTH segments wait in the gateway: the next
 * client segment's answer is held until the node confirms one. The node's
 * abort reaches the client at once and ends the pipeline; a silent node is
 * aborted on both sides by the relay's timeout. */
static void test_classic_download_pipeline_depth_abort_timeout(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    connect_3_peer(fx);
    request(fx, (const uint8_t[]){0x21, 0x03, 0x20, 0x00, 100, 0, 0, 0});
    peer_answers(fx, (const uint8_t[]){0x60, 0x03, 0x20, 0x00, 0, 0, 0, 0});
    uint8_t seg[8] = {0};
    for (unsigned k = 0; k <= CO_GATEWAY_SDO_PIPE_DEPTH; k++) {
        seg[0] = (uint8_t)((k & 1u) << 4);
        seg[1] = (uint8_t)k;
        request(fx, seg);
    }
    /* seg 0 went to the node, 1..8 wait: the 9th segment's answer is held */
    assert_int_equal(tu_log_count_id(&fx->a, 0x581), 1 + CO_GATEWAY_SDO_PIPE_DEPTH);
    assert_int_equal(tu_log_count_id(&fx->c, 0x607), 2);
    peer_answers(fx, (const uint8_t[8]){0x20});
    expect(&fx->a, 0x581, 1 + CO_GATEWAY_SDO_PIPE_DEPTH, (const uint8_t[8]){0x20});
    expect(&fx->c, 0x607, 2, (const uint8_t[]){0x10, 1, 0, 0, 0, 0, 0, 0});
    const uint8_t no_space[8] = {0x80, 0x03, 0x20, 0x00, 0x00, 0x00, 0x07, 0x06};
    peer_answers(fx, no_space);
    expect(&fx->a, 0x581, 2 + CO_GATEWAY_SDO_PIPE_DEPTH, no_space);   /* at once */
    assert_int_equal(tu_log_count_id(&fx->c, 0x607), 3);   /* the waiting ones are dropped */

    tu_log_clear(&fx->a);
    tu_log_clear(&fx->c);
    request(fx, (const uint8_t[]){0x21, 0x03, 0x20, 0x00, 100, 0, 0, 0});
    peer_answers(fx, (const uint8_t[]){0x60, 0x03, 0x20, 0x00, 0, 0, 0, 0});
    request(fx, (const uint8_t[]){0x00, 1, 2, 3, 4, 5, 6, 7});
    expect(&fx->a, 0x581, 1, (const uint8_t[8]){0x20});
    advance(fx, fx->a.now + (TIMEOUT_MS + 5) * TU_MS);   /* the node stays silent */
    const uint8_t timeout[8] = {0x80, 0x03, 0x20, 0x00, 0x00, 0x00, 0x04, 0x05};
    expect(&fx->a, 0x581, 2, timeout);
    expect(&fx->c, 0x607, 2, timeout);
    assert_int_equal(co_gateway_stats(&fx->gw)->sdo_timeouts, 1);
    fx_free(fx);
}

/* End to end with device 5: 20 bytes written through the pipeline are in
 * its dictionary; with buffering off every segment waits for the device. */
static void test_classic_download_pipelined_to_a_device(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    connect_3_5(fx);
    const char *text = "twenty bytes written";
    for (int pass = 0; pass < 2; pass++) {
        co_gateway_set_sdo_buffering(&fx->gw, pass == 0);
        request(fx, (const uint8_t[]){0x21, 0x03, 0x20, 0x00, 20, 0, 0, 0});
        for (unsigned off = 0; off < 20; off += 7) {
            unsigned n = 20 - off < 7 ? 20 - off : 7;
            uint8_t seg[8] = {(uint8_t)((off / 7 % 2) << 4 | (7 - n) << 1 | (off + n == 20))};
            memcpy(seg + 1, text + off, n);
            request(fx, seg);
        }
        uint8_t got[32];
        uint32_t n = 0;
        assert_int_equal(co_od_get(&fx->dev.od, 0x2003, 0, got, sizeof got, &n), 0);
        assert_int_equal(n, 20);
        assert_memory_equal(got, text, 20);
        assert_int_equal(tu_log_count_id(&fx->a, 0x581), 4 * (pass + 1));
        assert_int_equal(co_gateway_stats(&fx->gw)->sdo_pipelined, 2);   /* pass 0 only */
        assert_int_equal(co_od_put(&fx->dev.od, 0x2003, 0, (const uint8_t *)"-", 1), 0);
    }
    fx_free(fx);
}

/* The client's block transfers pass the gateway as they are, also while it
 * pipelines and buffers: a block download's segments (byte 0 = seqno, so
 * 0x21..0x7F look like initiates) are no requests of their own, and the
 * client's confirmation of a block upload's end (A1) is not answered, so
 * the relay waits for nothing after it: no abort follows a finished
 * transfer. */
static void test_classic_block_transfers_relayed_beside_the_pipeline(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    tool_client(fx);
    classic_setup(fx, sizeof classic_buffer);
    uint32_t abort = 1;
    block_download(fx, NET_C, DEV, &abort);   /* 100 segments: seqno 1..100 */
    assert_int_equal(abort, 0);
    const co_od_entry_t *e = co_od_find(&fx->dev.od, 0x2100, 0);
    assert_int_equal(e->length, BIG);
    static uint8_t back[BIG];
    co_sdo_buffer_t sink = {.data = back, .capacity = sizeof back};
    bool done = false;
    co_sdo_request_t req = {.server = GW, .index = 0x2100, .upload = true,
                            .mode = CO_SDO_MODE_BLOCK, .sink = co_sdo_buffer_sink, .ctx = &sink,
                            .done = flag_done, .user = &done, .network = NET_C,
                            .network_node = DEV, .timeout_ms = 50};
    co_line_set_time(&fx->client.line, fx->a.now);
    assert_int_equal(co_sdo_client_start(co_stack_sdo_client(&fx->tool), &req), 0);
    settle(fx);
    advance(fx, fx->a.now + 50 * TU_MS);
    assert_true(done);
    assert_int_equal(req.abort, 0);
    assert_int_equal(req.result_mode, CO_SDO_MODE_BLOCK);
    assert_int_equal(sink.size, BIG);
    assert_memory_equal(back, co_od_value(&fx->dev.od, e), BIG);
    tu_log_clear(&fx->a);
    tu_log_clear(&fx->c);
    advance(fx, fx->a.now + 3 * TIMEOUT_MS * TU_MS);
    assert_int_equal(tu_log_count_id(&fx->a, 0x581), 0);   /* no late abort */
    assert_int_equal(tu_log_count_id(&fx->c, 0x605), 0);
    const co_gateway_stats_t *st = co_gateway_stats(&fx->gw);
    assert_int_equal(st->sdo_timeouts, 0);
    assert_int_equal(st->sdo_pipelined, 0);
    assert_int_equal(st->sdo_translated + st->sdo_translate_failed, 0);
    fx_free(fx);
}

/* What the buffer does not take is relayed byte for byte: an expedited
 * download, the client's block upload, an upload larger than the buffer
 * (the gateway's own upload stopped with 0x05040005, the client's
 * initiate then relayed), a sized download larger than the buffer. */
static void test_classic_relayed_beside_the_buffer(void **state)
{
    (void)state;
    fx_t *fx = fx_new();
    classic_setup(fx, 64);
    const co_sdo_client_stats_t *cs = &co_stack_sdo_client(&fx->gw_c.stack)->stats;
    const uint8_t exp_dl[8] = {0x23, 0x00, 0x20, 0x00, 0xBE, 0xBA, 0xFE, 0xCA};
    request(fx, exp_dl);
    expect(&fx->c, 0x605, 0, exp_dl);
    expect(&fx->a, 0x581, 0, (const uint8_t[]){0x60, 0x00, 0x20, 0x00, 0, 0, 0, 0});
    assert_int_equal(cs->started, 0);
    const uint8_t block_up[8] = {0xA4, 0x00, 0x21, 0x00, 10, 0, 0, 0};
    request(fx, block_up);

    expect(&fx->c, 0x605, 1, block_up);
    assert_int_equal(fx->c.log[tu_log_find_id(&fx->c, 0x585, 1)].frame.data[0] & 0xE3, 0xC2);
    request(fx, (const uint8_t[]){0x80, 0x00, 0x21, 0x00, 0, 0, 0, 0x08});   /* client aborts it */
    assert_int_equal(cs->started, 0);
    static uint8_t value[BIG];
    memset(value, 0x5A, sizeof value);
    assert_int_equal(co_od_put(&fx->dev.od, 0x2100, 0, value, sizeof value), 0);
    tu_log_clear(&fx->a);
    tu_log_clear(&fx->c);
    request(fx, (const uint8_t[]){0x40, 0x00, 0x21, 0x00, 0, 0, 0, 0});   /* 700 > 64 bytes */
    expect(&fx->c, 0x605, 0, (const uint8_t[]){0x40, 0x00, 0x21, 0x00, 0, 0, 0, 0});
    expect(&fx->c, 0x605, 1, (const uint8_t[]){0x80, 0x00, 0x21, 0x00, 0x05, 0x00, 0x04, 0x05});
    expect(&fx->c, 0x605, 2, (const uint8_t[]){0x40, 0x00, 0x21, 0x00, 0, 0, 0, 0});
    expect(&fx->a, 0x581, 0, (const uint8_t[]){0x41, 0x00, 0x21, 0x00, 0xBC, 0x02, 0, 0});
    request(fx, (const uint8_t[]){0x60, 0, 0, 0, 0, 0, 0, 0});   /* relayed segments */
    expect(&fx->c, 0x605, 3, (const uint8_t[]){0x60, 0, 0, 0, 0, 0, 0, 0});
    request(fx, (const uint8_t[]){0x80, 0x00, 0x21, 0x00, 0, 0, 0, 0x08});
    tu_log_clear(&fx->c);
    const uint8_t big_dl[8] = {0x21, 0x00, 0x21, 0x00, 0xBC, 0x02, 0, 0};
    request(fx, big_dl);
    expect(&fx->c, 0x605, 0, big_dl);
    assert_int_equal(co_gateway_stats(&fx->gw)->sdo_too_big, 0);
    /* buffering off: a small upload is relayed too */
    co_gateway_set_sdo_buffering(&fx->gw, false);
    request(fx, (const uint8_t[]){0x80, 0x00, 0x21, 0x00, 0, 0, 0, 0x08});
    uint32_t started = cs->started;
    const uint8_t up[8] = {0x40, 0x01, 0x20, 0x00, 0, 0, 0, 0};
    request(fx, up);
    expect(&fx->c, 0x605, 2, up);
    assert_int_equal(cs->started, started);
    fx_free(fx);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_expedited_read_and_write_relayed),
        cmocka_unit_test(test_segmented_upload_relayed),
        cmocka_unit_test(test_aborts_relayed),
        cmocka_unit_test(test_silent_target_and_lost_answer),
        cmocka_unit_test(test_refusals),
        cmocka_unit_test(test_back_to_the_gateways_own_server),
        cmocka_unit_test(test_indication_forwarded_to_the_next_gateway),
        cmocka_unit_test(test_client_reaches_a_node_through_the_gateway),
        cmocka_unit_test(test_relay_beside_the_gateways_own_client),
        cmocka_unit_test(test_block_download_last_segment_is_no_indication),
        cmocka_unit_test(test_cancel_during_indication_forgets_the_connection),
        cmocka_unit_test(test_fd_expedited_translated),
        cmocka_unit_test(test_fd_segmented_translated),
        cmocka_unit_test(test_fd_timeouts_and_aborts_mapped),
        cmocka_unit_test(test_fd_buffer_limits_busy_and_block),
        cmocka_unit_test(test_fd_upload_larger_than_the_buffer),
        cmocka_unit_test(test_fd_upload_streamed),
        cmocka_unit_test(test_rebuild_ends_a_relayed_transfer),
        cmocka_unit_test(test_rebuild_ends_an_idle_connection),
        cmocka_unit_test(test_rebuild_ends_a_translated_transfer),
        cmocka_unit_test(test_client_reconnects_after_a_rebuild),
        cmocka_unit_test(test_classic_upload_buffered),
        cmocka_unit_test(test_classic_download_pipelined),
        cmocka_unit_test(test_classic_download_pipeline_depth_abort_timeout),
        cmocka_unit_test(test_classic_download_pipelined_to_a_device),
        cmocka_unit_test(test_classic_relayed_beside_the_buffer),
        cmocka_unit_test(test_classic_block_transfers_relayed_beside_the_pipeline),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
