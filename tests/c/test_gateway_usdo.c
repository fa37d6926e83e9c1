/* co_gateway remote USDO: a gateway (node 1 on both lines) joins fd line A
 * (network 1, a raw client, node 7) and fd line B (network 2, device 5, a
 * raw "next gateway" node 9 that also stands for a silent node). Network 4
 * lies behind node 9. A routed request (cs | 0x80, extension: destination
 * network, node, source network, node) is carried out on B by the
 * gateway's USDO client; the answer goes back routed. Every frame is
 * checked byte for byte on both buses: expedited download and upload, an
 * abort of the target, the client's abort, a silent target, an unknown
 * network, a busy gateway client, a wrong source network, a bulk request
 * (refused), the route through a next gateway; a segmented download and
 * upload of 130 bytes (each streamed: the target's side starts before the
 * client's has ended), a client silent in the middle of one. */
#include "test_od_util.h"

#include "canopenfd/co_gateway.h"
#include "canopenfd/co_stack.h"

#include <stdlib.h>

enum { GW = 1, CLIENT = 7, DEV = 5, NEXT_GW = 9, NET_A = 1, NET_B = 2, NET_FAR = 4,
       TIMEOUT_MS = 100, GW_SESSIONS = 2 };

static const tu_od_row_t gateway_rows[] = {
    {0x1000, 0, VAR, U32, RO, 0, 4, 0x00000302, NULL, 0, 0},
    {0x1001, 0, VAR, U8, RO, 0, 1, 0, NULL, 0, 0},
    {0x1017, 0, VAR, U16, RW, 0, 2, 0, NULL, 0, 0},
};

static const tu_od_row_t device_rows[] = {
    {0x1000, 0, VAR, U32, RO, 0, 4, 0x00000191, NULL, 0, 0},
    {0x1001, 0, VAR, U8, RO, 0, 1, 0, NULL, 0, 0},
    {0x1017, 0, VAR, U16, RW, 0, 2, 0, NULL, 0, 0},
    {0x2000, 0, VAR, U32, RW, 0, 4, 0x12345678, NULL, 0, 0},
    {0x2001, 0, VAR, VS, RO, 0, 14, 0, "hello gateway!", 0, 0},
    {0x2002, 0, VAR, VS, RW, 0, 130, 0,
     "................................................................."
     ".................................................................", 0, 0},
};

#define ROWS(r) (sizeof(r) / sizeof((r)[0]))

typedef struct node {
    tu_line_t line;
    co_od_t od;
    co_od_entry_t entries[16];
    uint8_t pool[512];
    co_od_subscription_t subs[CO_STACK_OD_SUBSCRIPTIONS + 4];
    co_stack_t stack;
    co_stack_arena_t arena;
    unsigned char memory[64 * 1024];
} node_t;

typedef struct fx {
    tu_bus_t a, b;
    node_t gw_a, gw_b, dev;
    tu_line_t client;   /* raw frames on network 1 */
    tu_line_t peer;     /* raw frames on network 2: node 9 */
    co_gateway_t gw;
    co_stack_t tool;    /* a USDO client (node 7) on the client's line */
    co_stack_arena_t tool_arena;
    unsigned char tool_memory[32 * 1024];
} fx_t;

static void node_init(tu_bus_t *tb, node_t *n, uint8_t node_id, const tu_od_row_t *rows,
                      size_t count)
{
    tu_bus_add_line(tb, &n->line);
    co_od_init(&n->od, CO_MODE_FD, n->entries, 16, n->pool, sizeof n->pool, n->subs,
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

static void step_all(fx_t *fx, uint64_t t)
{
    for (int round = 0; round < 4; round++) {
        tu_step(&fx->a, t);
        tu_step(&fx->b, t);
    }
}

static void settle(fx_t *fx)
{
    step_all(fx, fx->a.now);
}

static void advance(fx_t *fx, uint64_t until)
{
    for (int guard = 0; guard < 10000; guard++) {
        uint64_t d = tu_next_deadline(&fx->a), e = tu_next_deadline(&fx->b);
        d = e < d ? e : d;
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
    tu_bus_init(&fx->a, CO_MODE_FD, true);
    tu_bus_init(&fx->b, CO_MODE_FD, true);
    node_init(&fx->a, &fx->gw_a, GW, gateway_rows, ROWS(gateway_rows));
    node_init(&fx->b, &fx->gw_b, GW, gateway_rows, ROWS(gateway_rows));
    node_init(&fx->b, &fx->dev, DEV, device_rows, ROWS(device_rows));
    /* the gateway's USDO client on B, node-id 1, two sessions */
    co_stack_client_config_t cc = {.sessions = GW_SESSIONS, .node_id = GW};
    assert_int_equal(co_stack_client_init(&fx->gw_b.stack, &cc), CO_STACK_OK);
    tu_bus_add_line(&fx->a, &fx->client);
    tu_bus_add_line(&fx->b, &fx->peer);
    co_gateway_init(&fx->gw, NULL, NULL);
    co_gateway_set_sdo_timeout(&fx->gw, TIMEOUT_MS);
    assert_int_equal(co_gateway_add_port(&fx->gw, &fx->gw_a.stack, NET_A), CO_GATEWAY_OK);
    assert_int_equal(co_gateway_add_port(&fx->gw, &fx->gw_b.stack, NET_B), CO_GATEWAY_OK);
    assert_int_equal(co_gateway_set_route(&fx->gw, NET_FAR, NET_B, NEXT_GW), 0);
    settle(fx);
    tu_log_clear(&fx->a);
    tu_log_clear(&fx->b);
    return fx;
}

static int setup(void **state)
{
    *state = fx_new();
    return 0;
}

static int teardown(void **state)
{
    fx_t *fx = *state;
    co_gateway_deinit(&fx->gw);
    if (co_stack_line(&fx->tool) != NULL) {
        co_stack_deinit(&fx->tool);
    }
    co_stack_deinit(&fx->gw_a.stack);
    co_stack_deinit(&fx->gw_b.stack);
    co_stack_deinit(&fx->dev.stack);
    free(fx);
    return 0;
}

static uint8_t fd_len(uint8_t n)
{
    static const uint8_t sizes[] = {8, 12, 16, 20, 24, 32, 48, 64};
    if (n <= 8) {
        return n;
    }
    for (size_t i = 0; i < sizeof sizes; i++) {
        if (n <= sizes[i]) {
            return sizes[i];
        }
    }
    return 64;
}

/* The k-th frame with `id` on a bus: exactly these n bytes, padded with 0
 * to the FD length. */
static void expect(const tu_bus_t *tb, uint32_t id, size_t k, const uint8_t *data, uint8_t n)
{
    uint8_t padded[64] = {0};
    memcpy(padded, data, n);
    tu_assert_logged(tb, tu_log_find_id(tb, id, k), id, padded, fd_len(n));
}

static const uint8_t *logged(const tu_bus_t *tb, uint32_t id, size_t k)
{
    long i = tu_log_find_id(tb, id, k);
    assert_true(i >= 0);
    return tb->log[i].frame.data;
}

static void client_sends(fx_t *fx, const uint8_t *data, uint8_t n)
{
    uint8_t padded[64] = {0};
    memcpy(padded, data, n);
    assert_true(co_line_send(&fx->client.line, 0x600 + CLIENT, padded, fd_len(n)));
    settle(fx);
}

static void peer_sends(fx_t *fx, const uint8_t *data, uint8_t n)
{
    uint8_t padded[64] = {0};
    memcpy(padded, data, n);
    assert_true(co_line_send(&fx->peer.line, 0x580 + NEXT_GW, padded, fd_len(n)));
    settle(fx);
}

static void test_codec_remote_frames(void **state)
{
    (void)state;
    static const uint8_t data[4] = {0xEF, 0xBE, 0xAD, 0xDE};
    co_usdo_msg_t m;
    uint8_t out[64];
    memset(&m, 0, sizeof m);
    m.dest = GW;
    m.cs = CO_USDO_CS_DOWNLOAD_EXPEDITED;
    m.session = 0x11;
    m.index = 0x2000;
    m.type = 0x07;
    m.length = 4;
    m.data = data;
    m.remote = true;
    m.dst_net = 2;
    m.dst_node = 5;
    m.src_net = 1;
    m.src_node = 7;
    static const uint8_t want[16] = {0x01, 0x81, 0x11, 0x02, 0x05, 0x01, 0x07, 0x00,
                                     0x00, 0x20, 0x07, 0x04, 0xEF, 0xBE, 0xAD, 0xDE};
    assert_int_equal(co_usdo_encode(&m, out), 16);
    assert_memory_equal(out, want, 16);
    co_usdo_msg_t d;
    assert_int_equal(co_usdo_decode(out, 16, &d), CO_USDO_DECODE_OK);
    assert_true(d.remote);
    assert_int_equal(d.cs, 0x01);
    assert_int_equal(d.dst_net, 2);
    assert_int_equal(d.dst_node, 5);
    assert_int_equal(d.src_net, 1);
    assert_int_equal(d.src_node, 7);
    assert_int_equal(d.index, 0x2000);
    assert_int_equal(d.length, 4);
    assert_ptr_equal(d.data, out + 12);   /* into the caller's buffer */
    /* every truncation refused, never read beyond */
    for (size_t n = 3; n < 16; n++) {
        assert_int_equal(co_usdo_decode(out, n, &d), CO_USDO_DECODE_SHORT);
        assert_true(d.remote);
    }
    /* 53 bytes expedited do not fit a routed frame; 52 do */
    uint8_t big[56] = {0};
    m.data = big;
    m.length = 53;
    assert_int_equal(co_usdo_encode(&m, out), 0);
    m.length = 52;
    assert_int_equal(co_usdo_encode(&m, out), 64);
    /* a routed segment has no extension: cs | 0x80 only */
    memset(&m, 0, sizeof m);
    m.dest = GW;
    m.cs = CO_USDO_CS_UPLOAD_SEGMENT;
    m.session = 3;
    m.counter = 9;
    m.remote = true;
    m.dst_net = 2;   /* not written: no multiplexer in this layout */
    assert_int_equal(co_usdo_encode(&m, out), 4);
    static const uint8_t seg[4] = {0x01, 0x93, 0x03, 0x09};
    assert_memory_equal(out, seg, 4);
    /* the routed abort: 0xFF, extension, mux, code */
    memset(&m, 0, sizeof m);
    m.dest = 7;
    m.cs = CO_USDO_CS_ABORT;
    m.session = 3;
    m.index = 0x2001;
    m.abort_code = 0x1A;
    m.remote = true;
    m.dst_net = 1;
    m.dst_node = 7;
    m.src_net = 9;
    m.src_node = 5;
    static const uint8_t abo[11] = {0x07, 0xFF, 0x03, 0x01, 0x07, 0x09, 0x05,
                                    0x00, 0x01, 0x20, 0x1A};
    assert_int_equal(co_usdo_encode(&m, out), 11);
    assert_memory_equal(out, abo, 11);
    assert_int_equal(co_usdo_decode(abo, 11, &d), CO_USDO_DECODE_OK);
    assert_int_equal(d.cs, CO_USDO_CS_ABORT);
    assert_int_equal(d.abort_code, 0x1A);
}

static void test_expedited_download_forwarded(void **state)
{
    fx_t *fx = *state;
    static const uint8_t req[16] = {GW, 0x81, 0x11, NET_B, DEV, NET_A, CLIENT, 0x00,
                                    0x00, 0x20, 0x07, 0x04, 0xEF, 0xBE, 0xAD, 0xDE};
    client_sends(fx, req, 16);
    /* on B: a local expedited download from the gateway's client (node 1) */
    const uint8_t *fwd = logged(&fx->b, 0x600 + GW, 0);
    uint8_t sid = fwd[2];
    uint8_t want_b[12] = {DEV, 0x01, sid, 0x00, 0x00, 0x20, 0x07, 0x04, 0xEF, 0xBE, 0xAD, 0xDE};
    expect(&fx->b, 0x600 + GW, 0, want_b, 12);
    uint8_t rsp_b[6] = {GW, 0x21, sid, 0x00, 0x00, 0x20};
    expect(&fx->b, 0x580 + DEV, 0, rsp_b, 6);
    /* on A: the routed response, source = the node asked for */
    static const uint8_t rsp_a[10] = {CLIENT, 0xA1, 0x11, NET_A, CLIENT, NET_B, DEV,
                                      0x00, 0x00, 0x20};
    expect(&fx->a, 0x580 + GW, 0, rsp_a, 10);
    uint32_t v = 0;
    assert_true(co_od_get_u32(&fx->dev.od, 0x2000, 0, &v));
    assert_int_equal(v, 0xDEADBEEF);
    assert_int_equal(co_gateway_stats(&fx->gw)->usdo_forwarded, 1);
    assert_int_equal(co_gateway_stats(&fx->gw)->usdo_answered, 1);
}

static void test_expedited_upload_forwarded(void **state)
{
    fx_t *fx = *state;
    static const uint8_t req[10] = {GW, 0x91, 0x12, NET_B, DEV, NET_A, CLIENT, 0x00, 0x01, 0x20};
    client_sends(fx, req, 10);
    const uint8_t *fwd = logged(&fx->b, 0x600 + GW, 0);
    uint8_t sid = fwd[2];
    uint8_t want_b[6] = {DEV, 0x11, sid, 0x00, 0x01, 0x20};
    expect(&fx->b, 0x600 + GW, 0, want_b, 6);
    uint8_t rsp_a[26] = {CLIENT, 0xB1, 0x12, NET_A, CLIENT, NET_B, DEV, 0x00, 0x01, 0x20,
                         0x09, 14};
    memcpy(rsp_a + 12, "hello gateway!", 14);
    expect(&fx->a, 0x580 + GW, 0, rsp_a, 26);
}

static void test_abort_of_the_target_forwarded(void **state)
{
    fx_t *fx = *state;
    /* a write of a read-only entry: the device aborts 0x32 */
    static const uint8_t req[13] = {GW, 0x81, 0x13, NET_B, DEV, NET_A, CLIENT, 0x00,
                                    0x01, 0x20, 0x09, 0x01, 0x41};
    client_sends(fx, req, 13);
    uint8_t sid = logged(&fx->b, 0x600 + GW, 0)[2];
    uint8_t abort_b[7] = {GW, 0x7F, sid, 0x00, 0x01, 0x20, 0x32};
    expect(&fx->b, 0x580 + DEV, 0, abort_b, 7);
    static const uint8_t abort_a[11] = {CLIENT, 0xFF, 0x13, NET_A, CLIENT, NET_B, DEV,
                                        0x00, 0x01, 0x20, 0x32};
    expect(&fx->a, 0x580 + GW, 0, abort_a, 11);
}

/* The client's routed upload of 0x2000 from node 9 on B (silent: no
 * answer is sent for it); the session-ID the gateway's request took. */
static uint8_t upload_from_silent_peer(fx_t *fx, uint8_t session)
{
    const uint8_t req[10] = {GW, 0x91, session, NET_B, NEXT_GW, NET_A, CLIENT, 0x00, 0x00, 0x20};
    client_sends(fx, req, 10);
    return logged(&fx->b, 0x600 + GW, 0)[2];
}

static void test_silent_target_times_out_both_sides(void **state)
{
    fx_t *fx = *state;
    uint8_t sid = upload_from_silent_peer(fx, 0x14);
    assert_int_equal(tu_log_count_id(&fx->a, 0x580 + GW), 0);
    advance(fx, fx->a.now + (TIMEOUT_MS + 5) * 1000u);
    uint8_t abort_b[7] = {NEXT_GW, 0x7F, sid, 0x00, 0x00, 0x20, 0x12};
    expect(&fx->b, 0x600 + GW, 1, abort_b, 7);
    static const uint8_t abort_a[11] = {CLIENT, 0xFF, 0x14, NET_A, CLIENT, NET_B, NEXT_GW,
                                        0x00, 0x00, 0x20, 0x12};
    expect(&fx->a, 0x580 + GW, 0, abort_a, 11);
}

static void test_client_abort_reaches_the_target(void **state)
{
    fx_t *fx = *state;
    uint8_t sid = upload_from_silent_peer(fx, 0x15);
    static const uint8_t abo[11] = {GW, 0xFF, 0x15, NET_B, NEXT_GW, NET_A, CLIENT,
                                    0x00, 0x00, 0x20, 0x10};
    client_sends(fx, abo, 11);
    uint8_t abort_b[7] = {NEXT_GW, 0x7F, sid, 0x00, 0x00, 0x20, 0x10};
    expect(&fx->b, 0x600 + GW, 1, abort_b, 7);
    assert_int_equal(tu_log_count_id(&fx->a, 0x580 + GW), 0);   /* an abort is not answered */
    assert_int_equal(co_gateway_stats(&fx->gw)->usdo_client_aborts, 1);
    /* a stray abort: counted, nothing sent */
    client_sends(fx, abo, 11);
    assert_int_equal(co_gateway_stats(&fx->gw)->usdo_stray, 1);
    assert_int_equal(tu_log_count_id(&fx->b, 0x600 + GW), 2);
    /* nothing left running: the timeout sends nothing more */
    advance(fx, fx->a.now + (TIMEOUT_MS + 5) * 1000u);
    assert_int_equal(tu_log_count_id(&fx->a, 0x580 + GW), 0);
    assert_int_equal(tu_log_count_id(&fx->b, 0x600 + GW), 2);
}

/* A forwarded upload (node 9 on B silent) when the gateway is rebuilt
 * (ended, made anew over the same lines as the runtime does): the client
 * hears the routed abort 0x70 (the CiA 1301 counterpart of 0x060A0023),
 * the target the gateway's local abort 0x70; nothing follows. */
static void test_rebuild_ends_a_forwarded_request(void **state)
{
    fx_t *fx = *state;
    uint8_t sid = upload_from_silent_peer(fx, 0x16);
    co_gateway_end_connections(&fx->gw);
    co_gateway_stats_t stats = fx->gw.stats;
    co_gateway_deinit(&fx->gw);
    co_gateway_init(&fx->gw, NULL, NULL);
    fx->gw.stats = stats;
    assert_int_equal(co_gateway_add_port(&fx->gw, &fx->gw_a.stack, NET_A), CO_GATEWAY_OK);
    assert_int_equal(co_gateway_add_port(&fx->gw, &fx->gw_b.stack, NET_B), CO_GATEWAY_OK);
    settle(fx);
    uint8_t abort_b[7] = {NEXT_GW, 0x7F, sid, 0x00, 0x00, 0x20, 0x70};
    expect(&fx->b, 0x600 + GW, 1, abort_b, 7);
    static const uint8_t abort_a[11] = {CLIENT, 0xFF, 0x16, NET_A, CLIENT, NET_B, NEXT_GW,
                                        0x00, 0x00, 0x20, 0x70};
    expect(&fx->a, 0x580 + GW, 0, abort_a, 11);
    assert_int_equal(co_gateway_stats(&fx->gw)->connections_ended, 1);
    advance(fx, fx->a.now + (TIMEOUT_MS + 5) * 1000u);
    assert_int_equal(tu_log_count_id(&fx->a, 0x580 + GW), 1);
    assert_int_equal(tu_log_count_id(&fx->b, 0x600 + GW), 2);
}

static void test_refusals(void **state)
{
    fx_t *fx = *state;
    /* unknown network 9 */
    static const uint8_t unknown[10] = {GW, 0x91, 0x20, 9, DEV, NET_A, CLIENT, 0x00, 0x00, 0x20};
    client_sends(fx, unknown, 10);
    static const uint8_t a1[11] = {CLIENT, 0xFF, 0x20, NET_A, CLIENT, 9, DEV, 0x00, 0x00, 0x20,
                                   0x1A};
    expect(&fx->a, 0x580 + GW, 0, a1, 11);
    /* a wrong source network */
    static const uint8_t src[10] = {GW, 0x91, 0x21, NET_B, DEV, 3, CLIENT, 0x00, 0x00, 0x20};
    client_sends(fx, src, 10);
    static const uint8_t a2[11] = {CLIENT, 0xFF, 0x21, 3, CLIENT, NET_B, DEV, 0x00, 0x00, 0x20,
                                   0x1C};
    expect(&fx->a, 0x580 + GW, 1, a2, 11);
    /* the network it came from */
    static const uint8_t back[10] = {GW, 0x91, 0x22, NET_A, 3, NET_A, CLIENT, 0x00, 0x00, 0x20};
    client_sends(fx, back, 10);
    static const uint8_t a3[11] = {CLIENT, 0xFF, 0x22, NET_A, CLIENT, NET_A, 3, 0x00, 0x00, 0x20,
                                   0x19};
    expect(&fx->a, 0x580 + GW, 2, a3, 11);
    /* a routed bulk download: not forwarded, 0x13 */
    static const uint8_t seg[16] = {GW, 0x86, 0x23, NET_B, DEV, NET_A, CLIENT, 0x00, 0x00, 0x20,
                                    0x0F, 0x00, 100, 0, 0, 0};
    client_sends(fx, seg, 16);
    static const uint8_t a4[11] = {CLIENT, 0xFF, 0x23, NET_A, CLIENT, NET_B, DEV, 0x00, 0x00,
                                   0x20, 0x13};
    expect(&fx->a, 0x580 + GW, 3, a4, 11);
    assert_int_equal(tu_log_count_id(&fx->b, 0x600 + GW), 0);   /* nothing reached B */
    assert_int_equal(co_gateway_stats(&fx->gw)->usdo_refused, 4);
}

static void test_busy_gateway_client(void **state)
{
    fx_t *fx = *state;
    /* the gateway's client has two sessions: two silent requests take them */
    uint8_t req[10] = {GW, 0x91, 0x30, NET_B, NEXT_GW, NET_A, CLIENT, 0x00, 0x00, 0x20};
    client_sends(fx, req, 10);
    req[2] = 0x31;
    client_sends(fx, req, 10);
    assert_int_equal(tu_log_count_id(&fx->b, 0x600 + GW), 2);
    req[2] = 0x32;
    client_sends(fx, req, 10);
    static const uint8_t busy[11] = {CLIENT, 0xFF, 0x32, NET_A, CLIENT, NET_B, NEXT_GW, 0x00,
                                     0x00, 0x20, 0x70};
    expect(&fx->a, 0x580 + GW, 0, busy, 11);
    /* the same session-ID again while it runs: 0x21 */
    req[2] = 0x31;
    client_sends(fx, req, 10);
    static const uint8_t dup[11] = {CLIENT, 0xFF, 0x31, NET_A, CLIENT, NET_B, NEXT_GW, 0x00,
                                    0x00, 0x20, 0x21};
    expect(&fx->a, 0x580 + GW, 1, dup, 11);
    assert_int_equal(tu_log_count_id(&fx->b, 0x600 + GW), 2);
}

static void test_through_the_next_gateway(void **state)
{
    fx_t *fx = *state;
    /* network 4 is behind node 9 of network 2: routed again, from us */
    static const uint8_t req[10] = {GW, 0x91, 0x40, NET_FAR, DEV, NET_A, CLIENT, 0x00, 0x00,
                                    0x20};
    client_sends(fx, req, 10);
    uint8_t sid = logged(&fx->b, 0x600 + GW, 0)[2];
    uint8_t fwd[10] = {NEXT_GW, 0x91, sid, NET_FAR, DEV, NET_B, GW, 0x00, 0x00, 0x20};
    expect(&fx->b, 0x600 + GW, 0, fwd, 10);
    /* the next gateway's routed answer */
    uint8_t ans[16] = {GW, 0xB1, sid, NET_B, GW, NET_FAR, DEV, 0x00, 0x00, 0x20, 0x07, 0x04,
                       0x01, 0x02, 0x03, 0x04};
    peer_sends(fx, ans, 16);
    static const uint8_t rsp_a[16] = {CLIENT, 0xB1, 0x40, NET_A, CLIENT, NET_FAR, DEV, 0x00,
                                      0x00, 0x20, 0x07, 0x04, 0x01, 0x02, 0x03, 0x04};
    expect(&fx->a, 0x580 + GW, 0, rsp_a, 16);
}

static void test_without_gateway_still_0x13(void **state)
{
    fx_t *fx = *state;
    /* the device has no gateway: a routed request to it is answered 0x13 */
    uint8_t req[12] = {DEV, 0x91, 0x50, NET_B, DEV, NET_B, NEXT_GW, 0x00, 0x00, 0x20};
    assert_true(co_line_send(&fx->peer.line, 0x600 + NEXT_GW, req, 12));
    settle(fx);
    static const uint8_t a[7] = {NEXT_GW, 0x7F, 0x50, 0, 0, 0, 0x13};
    expect(&fx->b, 0x580 + DEV, 0, a, 7);
}

static void test_segmented_download_and_upload_forwarded(void **state)
{
    fx_t *fx = *state;
    uint8_t value[130];
    for (size_t i = 0; i < sizeof value; i++) {
        value[i] = (uint8_t)('A' + i % 26);
    }
    /* the client's segmented download: initiate (size 130), 60 + 60 + 10 */
    static const uint8_t init[16] = {GW, 0x82, 0x60, NET_B, DEV, NET_A, CLIENT, 0x00,
                                     0x02, 0x20, 0x09, 0x00, 130, 0, 0, 0};
    client_sends(fx, init, 16);
    static const uint8_t init_rsp[10] = {CLIENT, 0xA2, 0x60, NET_A, CLIENT, NET_B, DEV,
                                         0x00, 0x02, 0x20};
    expect(&fx->a, 0x580 + GW, 0, init_rsp, 10);
    assert_int_equal(tu_log_count_id(&fx->b, 0x600 + GW), 1);   /* started at once */
    for (uint8_t k = 0; k < 2; k++) {
        uint8_t seg[64] = {GW, 0x83, 0x60, k};
        memcpy(seg + 4, value + 60 * k, 60);
        client_sends(fx, seg, 64);
        uint8_t ack[4] = {CLIENT, 0xA3, 0x60, k};
        expect(&fx->a, 0x580 + GW, 1 + k, ack, 4);
    }
    uint8_t last[14] = {GW, 0x84, 0x60, 10};
    memcpy(last + 4, value + 120, 10);
    client_sends(fx, last, 14);
    /* on B: a local segmented download of the whole value */
    uint8_t sid = logged(&fx->b, 0x600 + GW, 0)[2];
    uint8_t b_init[12] = {DEV, 0x02, sid, 0x00, 0x02, 0x20, 0x09, 0x00, 130, 0, 0, 0};
    expect(&fx->b, 0x600 + GW, 0, b_init, 12);
    assert_int_equal(tu_log_count_id(&fx->b, 0x600 + GW), 4);   /* init, 2 segments, last */
    static const uint8_t end[3] = {CLIENT, 0xA4, 0x60};
    expect(&fx->a, 0x580 + GW, 3, end, 3);
    uint8_t held[130];
    uint32_t got = 0;
    assert_int_equal(co_od_get(&fx->dev.od, 0x2002, 0, held, sizeof held, &got), 0);
    assert_int_equal(got, 130);
    assert_memory_equal(held, value, 130);
    tu_log_clear(&fx->a);

    /* the upload: fetched whole, then served in segments the client asks */
    static const uint8_t up[10] = {GW, 0x91, 0x61, NET_B, DEV, NET_A, CLIENT, 0x00, 0x02, 0x20};
    client_sends(fx, up, 10);
    static const uint8_t up_init[16] = {CLIENT, 0xB2, 0x61, NET_A, CLIENT, NET_B, DEV, 0x00,
                                        0x02, 0x20, 0x09, 0x00, 130, 0, 0, 0};
    expect(&fx->a, 0x580 + GW, 0, up_init, 16);
    for (uint8_t k = 0; k < 3; k++) {
        uint8_t ask[4] = {GW, 0x93, 0x61, k};
        client_sends(fx, ask, 4);
        if (k < 2) {
            uint8_t seg[64] = {CLIENT, 0xB3, 0x61, k};
            memcpy(seg + 4, value + 60 * k, 60);
            expect(&fx->a, 0x580 + GW, 1 + k, seg, 64);
        } else {
            uint8_t fin[14] = {CLIENT, 0xB4, 0x61, 10};
            memcpy(fin + 4, value + 120, 10);
            expect(&fx->a, 0x580 + GW, 3, fin, 14);
        }
    }
    assert_int_equal(co_gateway_stats(&fx->gw)->usdo_answered, 2);
    /* the relay is free: a further segment request is stray */
    uint8_t again[4] = {GW, 0x93, 0x61, 3};
    client_sends(fx, again, 4);
    assert_int_equal(co_gateway_stats(&fx->gw)->usdo_stray, 1);
    assert_int_equal(tu_log_count_id(&fx->a, 0x580 + GW), 4);
}

/* An upload too long for a routed expedited answer is answered as soon as
 * the target announced its size, and each segment the client asks is served
 * as soon as it came from the target: the two hops overlap (node 9
 * answered by hand, so the order is seen). */
static void test_upload_streamed_while_the_target_sends(void **state)
{
    fx_t *fx = *state;
    uint8_t value[130];
    for (size_t i = 0; i < sizeof value; i++) {
        value[i] = (uint8_t)('a' + i % 26);
    }
    uint8_t sid = upload_from_silent_peer(fx, 0x15);
    const uint8_t announce[12] = {GW, 0x32, sid, 0x00, 0x00, 0x20, 0x09, 0x00, 130, 0, 0, 0};
    peer_sends(fx, announce, 12);
    static const uint8_t up_init[16] = {CLIENT, 0xB2, 0x15, NET_A, CLIENT, NET_B, NEXT_GW,
                                        0x00, 0x00, 0x20, 0x09, 0x00, 130, 0, 0, 0};
    expect(&fx->a, 0x580 + GW, 0, up_init, 16);   /* before any data came */
    const uint8_t ask0_b[4] = {NEXT_GW, 0x13, sid, 0};
    expect(&fx->b, 0x600 + GW, 1, ask0_b, 4);
    for (uint8_t k = 0; k < 3; k++) {
        const uint8_t ask[4] = {GW, 0x93, 0x15, k};
        client_sends(fx, ask, 4);
        assert_int_equal(tu_log_count_id(&fx->a, 0x580 + GW), 1 + k);   /* waits for the data */
        bool last = k == 2;
        uint8_t n = last ? 10 : 60;
        uint8_t seg[64] = {GW, (uint8_t)(last ? 0x34 : 0x33), sid, (uint8_t)(last ? n : k)};
        memcpy(seg + 4, value + 60 * k, n);
        peer_sends(fx, seg, (uint8_t)(4 + n));
        uint8_t out[64] = {CLIENT, (uint8_t)(last ? 0xB4 : 0xB3), 0x15, (uint8_t)(last ? n : k)};
        memcpy(out + 4, value + 60 * k, n);
        expect(&fx->a, 0x580 + GW, 1 + k, out, (uint8_t)(4 + n));   /* served at once */
    }
    assert_int_equal(co_gateway_stats(&fx->gw)->usdo_answered, 1);
    /* the relay is free again */
    const uint8_t again[4] = {GW, 0x93, 0x15, 3};
    client_sends(fx, again, 4);
    assert_int_equal(co_gateway_stats(&fx->gw)->usdo_stray, 1);

    /* the target aborts in the middle: the client, already served the size,
     * hears the target's code while it waits for a segment */
    tu_log_clear(&fx->a);
    tu_log_clear(&fx->b);
    sid = upload_from_silent_peer(fx, 0x16);
    const uint8_t announce2[12] = {GW, 0x32, sid, 0x00, 0x00, 0x20, 0x09, 0x00, 130, 0, 0, 0};
    peer_sends(fx, announce2, 12);
    const uint8_t ask[4] = {GW, 0x93, 0x16, 0};
    client_sends(fx, ask, 4);
    const uint8_t target_abort[7] = {GW, 0x7F, sid, 0x00, 0x00, 0x20, 0x21};
    peer_sends(fx, target_abort, 7);
    static const uint8_t abort_a[11] = {CLIENT, 0xFF, 0x16, NET_A, CLIENT, NET_B, NEXT_GW,
                                        0x00, 0x00, 0x20, 0x21};
    expect(&fx->a, 0x580 + GW, 1, abort_a, 11);
    assert_int_equal(co_gateway_stats(&fx->gw)->usdo_answered, 2);
}

/* A segmented download the target takes segmented goes on as the client's
 * segments come: the gateway starts its own download at the client's
 * initiate and sends each segment on once the client sent it (node 9
 * answered by hand); the client's segments are answered at once, its last
 * one only when the target confirmed the value (0xA4). */
static void test_download_streamed_as_the_client_sends(void **state)
{
    fx_t *fx = *state;
    uint8_t value[130];
    for (size_t i = 0; i < sizeof value; i++) {
        value[i] = (uint8_t)('A' + i % 26);
    }
    static const uint8_t init[16] = {GW, 0x82, 0x17, NET_B, NEXT_GW, NET_A, CLIENT, 0x00,
                                     0x02, 0x20, 0x09, 0x00, 130, 0, 0, 0};
    client_sends(fx, init, 16);
    static const uint8_t init_rsp[10] = {CLIENT, 0xA2, 0x17, NET_A, CLIENT, NET_B, NEXT_GW,
                                         0x00, 0x02, 0x20};
    expect(&fx->a, 0x580 + GW, 0, init_rsp, 10);
    uint8_t sid = logged(&fx->b, 0x600 + GW, 0)[2];
    const uint8_t b_init[12] = {NEXT_GW, 0x02, sid, 0x00, 0x02, 0x20, 0x09, 0x00, 130, 0, 0, 0};
    expect(&fx->b, 0x600 + GW, 0, b_init, 12);   /* at once, before any data came */
    const uint8_t b_init_rsp[6] = {GW, 0x22, sid, 0x00, 0x02, 0x20};
    peer_sends(fx, b_init_rsp, 6);
    assert_int_equal(tu_log_count_id(&fx->b, 0x600 + GW), 1);   /* waits for the client */
    for (uint8_t k = 0; k < 3; k++) {
        bool last = k == 2;
        uint8_t n = last ? 10 : 60;
        uint8_t seg[64] = {GW, (uint8_t)(last ? 0x84 : 0x83), 0x17, (uint8_t)(last ? n : k)};
        memcpy(seg + 4, value + 60 * k, n);
        client_sends(fx, seg, (uint8_t)(4 + n));
        if (!last) {
            const uint8_t ack[4] = {CLIENT, 0xA3, 0x17, k};
            expect(&fx->a, 0x580 + GW, 1 + k, ack, 4);   /* answered at once */
        }
        uint8_t on_b[64] = {NEXT_GW, (uint8_t)(last ? 0x04 : 0x03), sid, (uint8_t)(last ? n : k)};
        memcpy(on_b + 4, value + 60 * k, n);
        expect(&fx->b, 0x600 + GW, 1 + k, on_b, (uint8_t)(4 + n));   /* sent on at once */
        if (!last) {
            const uint8_t b_ack[4] = {GW, 0x23, sid, k};
            peer_sends(fx, b_ack, 4);
        }
    }
    assert_int_equal(tu_log_count_id(&fx->a, 0x580 + GW), 3);   /* 0xA4 waits for the target */
    const uint8_t b_last_rsp[3] = {GW, 0x24, sid};
    peer_sends(fx, b_last_rsp, 3);
    static const uint8_t end[3] = {CLIENT, 0xA4, 0x17};
    expect(&fx->a, 0x580 + GW, 3, end, 3);
    assert_int_equal(co_gateway_stats(&fx->gw)->usdo_answered, 1);

    /* the target refuses in the middle: the client hears its code at once */
    tu_log_clear(&fx->a);
    tu_log_clear(&fx->b);
    static const uint8_t init2[16] = {GW, 0x82, 0x18, NET_B, NEXT_GW, NET_A, CLIENT, 0x00,
                                      0x02, 0x20, 0x09, 0x00, 130, 0, 0, 0};
    client_sends(fx, init2, 16);
    sid = logged(&fx->b, 0x600 + GW, 0)[2];
    const uint8_t b_init_rsp2[6] = {GW, 0x22, sid, 0x00, 0x02, 0x20};
    peer_sends(fx, b_init_rsp2, 6);
    uint8_t seg0[64] = {GW, 0x83, 0x18, 0};
    client_sends(fx, seg0, 64);
    const uint8_t b_abort[7] = {GW, 0x7F, sid, 0x00, 0x02, 0x20, 0x24};
    peer_sends(fx, b_abort, 7);
    static const uint8_t abort_a[11] = {CLIENT, 0xFF, 0x18, NET_A, CLIENT, NET_B, NEXT_GW,
                                        0x00, 0x02, 0x20, 0x24};
    expect(&fx->a, 0x580 + GW, 2, abort_a, 11);
    advance(fx, fx->a.now + 3 * TIMEOUT_MS * 1000u);   /* no timer left for the relay */
    assert_int_equal(tu_log_count_id(&fx->a, 0x580 + GW), 3);
}

static void test_client_silent_in_a_segmented_download(void **state)
{
    fx_t *fx = *state;
    static const uint8_t init[16] = {GW, 0x82, 0x62, NET_B, DEV, NET_A, CLIENT, 0x00,
                                     0x02, 0x20, 0x09, 0x00, 130, 0, 0, 0};
    client_sends(fx, init, 16);
    advance(fx, fx->a.now + (TIMEOUT_MS + 5) * 1000u);
    static const uint8_t abort_a[11] = {CLIENT, 0xFF, 0x62, NET_A, CLIENT, NET_B, DEV,
                                        0x00, 0x02, 0x20, 0x12};
    expect(&fx->a, 0x580 + GW, 1, abort_a, 11);
    /* the streamed download to device 5 had started: it is stopped too */
    uint8_t sid = logged(&fx->b, 0x600 + GW, 0)[2];
    const uint8_t abort_b[7] = {DEV, 0x7F, sid, 0x00, 0x02, 0x20, 0x12};
    expect(&fx->b, 0x600 + GW, 1, abort_b, 7);
    assert_int_equal(tu_log_count_id(&fx->b, 0x600 + GW), 2);
    assert_int_equal(co_gateway_stats(&fx->gw)->usdo_timeouts, 1);
    /* a value above CO_GATEWAY_USDO_VALUE_MAX: 0x16 at once */
    static const uint8_t big[16] = {GW, 0x82, 0x63, NET_B, DEV, NET_A, CLIENT, 0x00,
                                    0x02, 0x20, 0x09, 0x00, 0x01, 0x04, 0, 0};
    client_sends(fx, big, 16);
    static const uint8_t abort_big[11] = {CLIENT, 0xFF, 0x63, NET_A, CLIENT, NET_B, DEV,
                                          0x00, 0x02, 0x20, 0x16};
    expect(&fx->a, 0x580 + GW, 2, abort_big, 11);
}

typedef struct routed {
    co_usdo_request_t req;
    co_buffer_t buf;
    uint8_t data[200];
    bool done;
} routed_t;

static void routed_done(co_usdo_request_t *req)
{
    ((routed_t *)req->user)->done = true;
}

/* One request of the co_usdo_client on line A to (network, node) through
 * the gateway, run to its end. */
static void routed_run(fx_t *fx, routed_t *u, bool upload, uint8_t network, uint16_t index,
                       const uint8_t *value, uint32_t size, uint8_t mode)
{
    memset(u, 0, sizeof *u);
    u->buf.data = u->data;
    u->buf.capacity = sizeof u->data;
    if (!upload) {
        memcpy(u->data, value, size);
        u->buf.size = size;
    }
    u->req = (co_usdo_request_t){.server = GW, .index = index, .upload = upload,
                                 .mode = mode, .type = index == 0x2000 ? 0x07 : 0x09,
                                 .size = upload ? 0 : size,
                                 .source = upload ? NULL : co_usdo_buffer_source,
                                 .sink = upload ? co_usdo_buffer_sink : NULL,
                                 .ctx = &u->buf, .done = routed_done, .user = u,
                                 .network = network, .network_node = DEV,
                                 .source_network = NET_A};
    co_line_set_time(&fx->client.line, fx->a.now);
    assert_int_equal(co_usdo_client_start(co_stack_usdo_client(&fx->tool), &u->req), 0);
    advance(fx, fx->a.now + 20 * TU_MS);
    assert_true(u->done);
}

/* co_usdo_client with (network, network_node, source_network): routed
 * frames out, routed answers taken, segmented both ways. */
static void test_usdo_client_through_the_gateway(void **state)
{
    fx_t *fx = *state;
    co_stack_arena_init(&fx->tool_arena, fx->tool_memory, sizeof fx->tool_memory);
    co_stack_line_config_t lc = {.heartbeat_entries = 1};
    assert_int_equal(co_stack_init(&fx->tool, &fx->client.line, &lc,
                                   co_stack_arena_allocator(&fx->tool_arena)), CO_STACK_OK);
    co_stack_client_config_t cc = {.sessions = 2, .node_id = CLIENT, .timeout_ms = 50};
    assert_int_equal(co_stack_client_init(&fx->tool, &cc), CO_STACK_OK);
    uint8_t value[130];
    for (size_t i = 0; i < sizeof value; i++) {
        value[i] = (uint8_t)('a' + i % 26);
    }
    routed_t u;
    routed_run(fx, &u, false, NET_B, 0x2002, value, 130, CO_USDO_MODE_AUTO);
    assert_int_equal(u.req.abort, 0);
    assert_int_equal(u.req.result_mode, CO_USDO_MODE_SEGMENTED);   /* above 52 bytes */
    uint8_t sid = logged(&fx->a, 0x600 + CLIENT, 0)[2];
    uint8_t init[16] = {GW, 0x82, sid, NET_B, DEV, NET_A, CLIENT, 0x00, 0x02, 0x20, 0x09, 0x00,
                        130, 0, 0, 0};
    expect(&fx->a, 0x600 + CLIENT, 0, init, 16);
    uint8_t seg0[64] = {GW, 0x83, sid, 0};
    memcpy(seg0 + 4, value, 60);
    expect(&fx->a, 0x600 + CLIENT, 1, seg0, 64);
    uint8_t held[130];
    uint32_t got = 0;
    assert_int_equal(co_od_get(&fx->dev.od, 0x2002, 0, held, sizeof held, &got), 0);
    assert_memory_equal(held, value, 130);
    /* read back: segmented from the gateway */
    routed_run(fx, &u, true, NET_B, 0x2002, NULL, 0, CO_USDO_MODE_AUTO);
    assert_int_equal(u.req.abort, 0);
    assert_int_equal(u.buf.size, 130);
    assert_memory_equal(u.data, value, 130);
    /* expedited both ways: 4 bytes */
    static const uint8_t four[4] = {1, 2, 3, 4};
    routed_run(fx, &u, false, NET_B, 0x2000, four, 4, CO_USDO_MODE_AUTO);
    assert_int_equal(u.req.abort, 0);
    assert_int_equal(u.req.result_mode, CO_USDO_MODE_EXPEDITED);
    routed_run(fx, &u, true, NET_B, 0x2000, NULL, 0, CO_USDO_MODE_AUTO);
    assert_int_equal(u.req.abort, 0);
    assert_memory_equal(u.data, four, 4);
    /* a network no route reaches: the gateway's routed abort */
    routed_run(fx, &u, true, 9, 0x2000, NULL, 0, CO_USDO_MODE_AUTO);
    assert_int_equal(u.req.abort, CO_USDO_ABORT_DEST_NETWORK);
    assert_true(u.req.abort_from_server);
    /* refused at the start: bulk, no gateway, expedited above 52 bytes */
    u.req.mode = CO_USDO_MODE_BULK;
    u.req.upload = false;
    u.req.size = 100;
    u.req.source = co_usdo_buffer_source;
    u.req.network = NET_B;
    assert_int_equal(co_usdo_client_start(co_stack_usdo_client(&fx->tool), &u.req),
                     CO_USDO_ABORT_UNKNOWN);
    u.req.mode = CO_USDO_MODE_EXPEDITED;
    u.req.size = 53;
    assert_int_equal(co_usdo_client_start(co_stack_usdo_client(&fx->tool), &u.req),
                     CO_USDO_ABORT_DLC);
    u.req.size = 4;
    u.req.server = 0;
    assert_int_equal(co_usdo_client_start(co_stack_usdo_client(&fx->tool), &u.req),
                     CO_USDO_ABORT_UNKNOWN);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_codec_remote_frames),
        cmocka_unit_test_setup_teardown(test_expedited_download_forwarded, setup, teardown),
        cmocka_unit_test_setup_teardown(test_expedited_upload_forwarded, setup, teardown),
        cmocka_unit_test_setup_teardown(test_abort_of_the_target_forwarded, setup, teardown),
        cmocka_unit_test_setup_teardown(test_silent_target_times_out_both_sides, setup,
                                        teardown),
        cmocka_unit_test_setup_teardown(test_client_abort_reaches_the_target, setup, teardown),
        cmocka_unit_test_setup_teardown(test_rebuild_ends_a_forwarded_request, setup, teardown),
        cmocka_unit_test_setup_teardown(test_refusals, setup, teardown),
        cmocka_unit_test_setup_teardown(test_busy_gateway_client, setup, teardown),
        cmocka_unit_test_setup_teardown(test_through_the_next_gateway, setup, teardown),
        cmocka_unit_test_setup_teardown(test_without_gateway_still_0x13, setup, teardown),
        cmocka_unit_test_setup_teardown(test_segmented_download_and_upload_forwarded, setup,
                                        teardown),
        cmocka_unit_test_setup_teardown(test_upload_streamed_while_the_target_sends, setup,
                                        teardown),
        cmocka_unit_test_setup_teardown(test_download_streamed_as_the_client_sends, setup,
                                        teardown),
        cmocka_unit_test_setup_teardown(test_client_silent_in_a_segmented_download, setup,
                                        teardown),
        cmocka_unit_test_setup_teardown(test_usdo_client_through_the_gateway, setup, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
