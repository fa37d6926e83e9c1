/* libFuzzer harness: the gateway's SDO networking (co_gateway_sdo.c) and
 * route resolution (co_gateway.c). One device joins three classic lines as
 * node 1: network 1 (a raw client line and a tool with a real SDO client),
 * network 2 (a raw client line) and network 3 (device 5, a raw "next
 * gateway" line for node 9, and the gateway's own SDO client, whose idle
 * tap the relay uses). Network 7 is routed via node 9 on network 3.
 *
 * FRAME records go to the current client line (network 1 or 2, switched by
 * an action), with alt set to the raw line on network 3; the CAN-ID table
 * holds the gateway's SDO server, the device's and node 9's answers.
 * Actions: switch the client line; the tool starts a routed upload or
 * download (network, node and gateway from the input); the gateway's own
 * client uploads from a node; a route is set; the relay timeout changes.
 * The gateway has a 96-byte buffer: uploads from device 5 go through it
 * (larger values relayed), segmented downloads are pipelined.
 *
 * Checked: every frame carried is a valid classic frame; after SETTLE (and
 * at the end) every request ended and every gateway connection waits for
 * nothing (no timer left running it); after co_gateway_deinit the lines
 * have exactly the receivers they had before the ports joined, and no
 * filter or idle tap of the gateway is left. */
#include "fuzz_input.h"

#include "canopenfd/co_gateway.h"
#include "canopenfd/co_membus.h"
#include "canopenfd/co_stack.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum {
    QUEUE = 32, GW = 1, DEV = 5, NEXT_GW = 9, TOOL_SLOTS = 2, OWN_SLOTS = 2,
    ENTRIES = 16, SUBS = CO_STACK_OD_SUBSCRIPTIONS + CO_GATEWAY_OD_SUBSCRIPTIONS + 2,
    SETTLE_MS = 70000, STEP_BUDGET = 200000, ROUND_LIMIT = 100000, SLOT_BUF = 64
};
#define MS 1000u
#define CHECK(cond, what) do { if (!(cond)) fail(what); } while (0)

typedef struct line_storage {
    co_line_t line;
    co_frame_t rx[QUEUE];
    co_frame_t tx[QUEUE];
} line_storage_t;

typedef struct node {
    line_storage_t ls;
    co_od_t od;
    co_od_entry_t entries[ENTRIES];
    uint8_t pool[256];
    co_od_subscription_t subs[SUBS];
    co_stack_t stack;
    co_stack_arena_t arena;
    unsigned char memory[40 * 1024];
} node_t;

typedef struct slot {
    co_sdo_request_t req;
    co_buffer_t buf;
    uint8_t data[SLOT_BUF];
    bool running;
} slot_t;

typedef struct world {
    co_membus_t bus[3];
    node_t gw[3];               /* the gateway's node on networks 1, 2, 3 */
    node_t dev;                 /* device 5 on network 3 */
    line_storage_t raw[3];      /* raw frames: client lines on 1 and 2, node 9 on 3 */
    line_storage_t tool_ls;     /* the tool's line on network 1 */
    co_stack_t tool;
    co_stack_arena_t tool_arena;
    unsigned char tool_memory[24 * 1024];
    co_gateway_t gateway;
    uint8_t receivers[3];       /* of the gateway's lines before the ports joined */
    slot_t tool_slots[TOOL_SLOTS];
    slot_t own_slots[OWN_SLOTS];
    co_line_t *client;          /* where FRAME records go */
    uint64_t now;
    uint32_t steps;
    uint8_t sdo_buffer[96];          /* the gateway's (co_gateway_set_sdo_buffer) */
} world_t;

static world_t W;

static void fail(const char *what)
{
    fprintf(stderr, "fuzz_gateway: %s\n", what);
    abort();
}

static void add(co_od_t *od, uint16_t index, uint8_t type, uint8_t access, uint32_t value)
{
    CHECK(fz_od_add(od, index, 0, CO_OBJECT_VAR, type, access, value), "OD refuses an entry");
}

static void line_init(line_storage_t *ls, co_membus_t *bus)
{
    co_line_config_t lc = {.mode = CO_MODE_CLASSIC, .rx_slots = ls->rx, .rx_capacity = QUEUE,
                           .tx_slots = ls->tx, .tx_capacity = QUEUE};
    CHECK(co_line_init(&ls->line, &lc), "line");
    CHECK(co_membus_attach(bus, &ls->line), "membus attach");
}

static void node_init(node_t *n, co_membus_t *bus, uint8_t node_id, bool device)
{
    line_init(&n->ls, bus);
    co_od_init(&n->od, CO_MODE_CLASSIC, n->entries, ENTRIES, n->pool, sizeof n->pool, n->subs,
               SUBS);
    add(&n->od, 0x1000, CO_TYPE_UNSIGNED32, CO_ACCESS_RO, device ? 0x191 : 0x302);
    add(&n->od, 0x1001, CO_TYPE_UNSIGNED8, CO_ACCESS_RO, 0);
    add(&n->od, 0x1017, CO_TYPE_UNSIGNED16, CO_ACCESS_RW, 0);
    if (device) {
        add(&n->od, 0x2000, CO_TYPE_UNSIGNED32, CO_ACCESS_RW, 0x12345678);
    }
    CHECK(co_od_seal(&n->od, node_id), "OD does not seal");
    co_stack_arena_init(&n->arena, n->memory, sizeof n->memory);
    co_stack_line_config_t lc = {.heartbeat_entries = 1};
    CHECK(co_stack_init(&n->stack, &n->ls.line, &lc, co_stack_arena_allocator(&n->arena)) ==
          CO_STACK_OK, "stack");
    co_stack_node_config_t nc = {.node_id = node_id, .od = &n->od};
    CHECK(co_stack_node_init(&n->stack, &nc) == CO_STACK_OK, "node");
    CHECK(co_stack_boot(&n->stack) == CO_STACK_OK, "boot");
}

static void carried(co_line_t *from, const co_frame_t *frame, void *user)
{
    (void)from;
    (void)user;
    CHECK(co_frame_is_valid(frame), "an invalid frame was sent");
    CHECK(!(frame->flags & CO_FRAME_FD), "an FD frame was sent on a classic line");
}

static co_line_t *all_lines(int i)
{
    switch (i) {
    case 0: return &W.gw[0].ls.line;
    case 1: return &W.gw[1].ls.line;
    case 2: return &W.gw[2].ls.line;
    case 3: return &W.dev.ls.line;
    case 4: return &W.raw[0].line;
    case 5: return &W.raw[1].line;
    case 6: return &W.raw[2].line;
    case 7: return &W.tool_ls.line;
    default: return NULL;
    }
}

static void step(uint64_t now)
{
    CHECK(now >= W.now, "clock went backwards");
    W.now = now;
    W.steps++;
    for (uint32_t round = 0;; round++) {
        uint32_t moved = 0;
        CHECK(round < ROUND_LIMIT, "the buses never become quiet at one instant");
        for (int i = 0; all_lines(i) != NULL; i++) {
            (void)co_line_process(all_lines(i), now);
            CHECK(co_line_rx_count(all_lines(i)) <= QUEUE &&
                  co_line_tx_count(all_lines(i)) <= QUEUE, "queue count past capacity");
        }
        for (int b = 0; b < 3; b++) {
            moved += co_membus_transfer(&W.bus[b], carried, NULL);
        }
        if (moved == 0) {
            return;
        }
    }
}

static uint64_t next_deadline(void)
{
    uint64_t next = CO_TIME_NEVER;
    for (int i = 0; all_lines(i) != NULL; i++) {
        uint64_t d = co_timer_list_next(co_line_timers(all_lines(i)));
        next = d < next ? d : next;
    }
    return next;
}

static bool run_until(uint64_t until)
{
    uint32_t same = 0;
    for (;;) {
        uint64_t d = next_deadline();
        if (d > until) {
            break;
        }
        if (W.steps >= STEP_BUDGET) {
            return false;
        }
        uint64_t t = d > W.now ? d : W.now;
        same = t == W.now ? same + 1 : 0;
        CHECK(same < 10000, "timers keep firing at one instant");
        step(t);
    }
    step(until);
    return true;
}

static void done(co_sdo_request_t *req)
{
    slot_t *s = req->user;
    CHECK(s->running, "done() for a request that is not running");
    s->running = false;
}

static slot_t *free_slot(slot_t *slots, uint32_t count)
{
    for (uint32_t i = 0; i < count; i++) {
        if (!slots[i].running) {
            return &slots[i];
        }
    }
    return NULL;
}

static void start(co_sdo_client_t *client, slot_t *s, uint8_t server, uint8_t network,
                  uint8_t node, uint8_t how, uint16_t index)
{
    memset(s, 0, sizeof *s);
    s->buf.data = s->data;
    s->buf.capacity = sizeof s->data;
    s->req.server = server;
    s->req.index = index;
    s->req.upload = !(how & 1u);
    s->req.mode = (uint8_t)((how >> 1) % 4u);   /* AUTO, expedited, segmented, block */
    s->req.network = network;
    s->req.network_node = node;
    s->req.timeout_ms = 100u + 100u * (how >> 3);
    s->req.done = done;
    s->req.user = s;
    if (s->req.upload) {
        s->req.sink = co_sdo_buffer_sink;
        s->req.ctx = &s->buf;
    } else {
        s->buf.size = 4u + (how >> 4);
        s->req.size = s->buf.size;
        s->req.source = co_sdo_buffer_source;
        s->req.ctx = &s->buf;
    }
    s->running = true;
    if (co_sdo_client_start(client, &s->req) != 0) {
        s->running = false;
    }
}

static void action(fz_reader_t *r, uint8_t p)
{
    switch (p % 5u) {
    case 0:
        W.client = W.client == &W.raw[0].line ? &W.raw[1].line : &W.raw[0].line;
        break;
    case 1: {
        slot_t *s = free_slot(W.tool_slots, TOOL_SLOTS);
        uint8_t network = fz_u8(r) % 9u, node = fz_u8(r), how = fz_u8(r);
        if (s != NULL) {
            start(co_stack_sdo_client(&W.tool), s, (how & 0x80u) ? fz_u8(r) % 128u : GW,
                  network, node, how, (how & 0x40u) ? 0x2000 : 0x1000);
        }
        break;
    }
    case 2: {
        slot_t *s = free_slot(W.own_slots, OWN_SLOTS);
        uint8_t node = fz_u8(r) % 128u, how = fz_u8(r);
        if (s != NULL && node != 0) {
            start(co_stack_sdo_client(&W.gw[2].stack), s, node, 0, 0, how, 0x2000);
        }
        break;
    }
    case 3: {
        uint8_t net = fz_u8(r), via = fz_u8(r), node = fz_u8(r);
        (void)co_gateway_set_route(&W.gateway, net, via, node);
        break;
    }
    default:
        co_gateway_set_sdo_timeout(&W.gateway, 1u + fz_u16(r) % 3000u);
        break;
    }
}

static void build(void)
{
    memset(&W, 0, sizeof W);
    for (int b = 0; b < 3; b++) {
        co_membus_init(&W.bus[b]);
    }
    for (int n = 0; n < 3; n++) {
        node_init(&W.gw[n], &W.bus[n], GW, false);
        line_init(&W.raw[n], &W.bus[n]);
    }
    node_init(&W.dev, &W.bus[2], DEV, true);
    line_init(&W.tool_ls, &W.bus[0]);
    co_stack_arena_init(&W.tool_arena, W.tool_memory, sizeof W.tool_memory);
    co_stack_line_config_t tl = {.heartbeat_entries = 1};
    CHECK(co_stack_init(&W.tool, &W.tool_ls.line, &tl,
                        co_stack_arena_allocator(&W.tool_arena)) == CO_STACK_OK, "tool stack");
    co_stack_client_config_t cc = {.sessions = TOOL_SLOTS, .timeout_ms = 300};
    CHECK(co_stack_client_init(&W.tool, &cc) == CO_STACK_OK, "tool client");
    co_stack_client_config_t oc = {.sessions = OWN_SLOTS, .timeout_ms = 300};
    CHECK(co_stack_client_init(&W.gw[2].stack, &oc) == CO_STACK_OK, "gateway's own client");
    for (int n = 0; n < 3; n++) {
        W.receivers[n] = W.gw[n].ls.line.receiver_count;
    }
    co_gateway_init(&W.gateway, NULL, NULL);
    for (int n = 0; n < 3; n++) {
        CHECK(co_gateway_add_port(&W.gateway, &W.gw[n].stack, (uint8_t)(n + 1)) == CO_GATEWAY_OK,
              "gateway port");
    }
    co_gateway_set_sdo_timeout(&W.gateway, 200);
    /* small: uploads to device 5 are buffered, larger values relayed */
    co_gateway_set_sdo_buffer(&W.gateway, W.sdo_buffer, sizeof W.sdo_buffer);
    CHECK(co_gateway_set_route(&W.gateway, 7, 3, NEXT_GW) == 0, "route");
    W.client = &W.raw[0].line;
    step(0);
}

/* Nothing new for a while: every request ends, no connection waits. */
static void settle(void)
{
    step(W.now);
    if (!run_until(W.now + (uint64_t)SETTLE_MS * MS)) {
        return;   /* step budget spent: no conclusion */
    }
    for (uint32_t i = 0; i < TOOL_SLOTS; i++) {
        CHECK(!W.tool_slots[i].running, "a tool request never ended");
    }
    for (uint32_t i = 0; i < OWN_SLOTS; i++) {
        CHECK(!W.own_slots[i].running, "a request of the gateway's own client never ended");
    }
    for (uint32_t i = 0; i < CO_GATEWAY_SDO_CONNECTIONS; i++) {
        const co_gateway_sdo_t *c = &W.gateway.sdo[i];
        CHECK(c->from == NULL || (c->state == 2 && !c->timer.armed),
              "a gateway connection still waits after settling");
        CHECK(c->from == NULL || (!c->xtimer.armed && !c->fetch_running),
              "a buffered transfer still waits after settling");
        CHECK(c->pipe_count <= CO_GATEWAY_SDO_PIPE_DEPTH, "the pipeline overflowed");
    }
}

static void teardown(void)
{
    co_gateway_deinit(&W.gateway);
    for (int n = 0; n < 3; n++) {
        CHECK(W.gw[n].ls.line.receiver_count == W.receivers[n],
              "the gateway left a receiver on a line");
        CHECK(co_stack_sdo_server(&W.gw[n].stack)->filter == NULL,
              "the gateway left its SDO server filter");
    }
    CHECK(co_stack_sdo_client(&W.gw[2].stack)->idle_tap == NULL,
          "the gateway left its idle tap on its own client");
    for (uint32_t i = 0; i < CO_GATEWAY_SDO_CONNECTIONS; i++) {
        CHECK(W.gateway.sdo[i].from == NULL && !W.gateway.sdo[i].timer.armed,
              "a connection outlived the gateway");
    }
    co_stack_deinit(&W.tool);
    co_stack_deinit(&W.dev.stack);
    for (int n = 0; n < 3; n++) {
        co_stack_deinit(&W.gw[n].stack);
    }
    for (uint32_t i = 0; i < TOOL_SLOTS; i++) {
        CHECK(!W.tool_slots[i].running, "a tool request outlived its client");
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    /* 0: the gateway's SDO server; answers of device 5 and of node 9 (the
     * next gateway) and requests to them on network 3 (alt) */
    static const uint32_t ids[] = {0x601, 0x585, 0x589, 0x605, 0x609, 0x581, 0x600, 0x67F};
    fz_reader_t r;
    fz_record_t rec;
    build();
    fz_reader_init(&r, data, size);
    while (fz_next(&r, &rec, ids, sizeof ids / sizeof ids[0], CO_MODE_CLASSIC)) {
        switch (rec.op) {
        case FZ_OP_FRAME:
        case FZ_OP_FRAME2:
            if (co_frame_is_valid(&rec.frame) && !(rec.frame.flags & CO_FRAME_FD)) {
                (void)co_line_send_frame(rec.alt ? &W.raw[2].line : W.client, &rec.frame);
            } else {
                /* malformed: straight into the gateway line's receive queue */
                (void)co_line_receive(rec.alt ? &W.gw[2].ls.line
                                              : W.client == &W.raw[0].line ? &W.gw[0].ls.line
                                                                           : &W.gw[1].ls.line,
                                      &rec.frame);
            }
            break;
        case FZ_OP_TIME:
            if (!run_until(W.now + (uint64_t)rec.ms * MS)) {
                goto out;
            }
            break;
        case FZ_OP_ACTION:
            action(&r, rec.p);
            break;
        case FZ_OP_PROCESS:
            step(W.now);
            break;
        case FZ_OP_SETTLE:
            settle();
            break;
        default:   /* BUS, COMM: not used here */
            break;
        }
        if (W.steps >= STEP_BUDGET) {
            break;
        }
    }
out:
    settle();
    teardown();
    return 0;
}
