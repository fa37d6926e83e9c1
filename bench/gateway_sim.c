/* SDO networking through the gateway vs direct SDO, in simulated bus time.
 *
 *   make -C bench gateway-sim        (build/bench/gateway_sim [-t SECONDS])
 *
 * The core's stacks run on modelled CAN buses instead of the host's clock:
 * each frame occupies its bus for its length at the bit rate (47 + 8 x data
 * bits, no stuffing), the bus is given to the lowest CAN-ID waiting, and
 * every node handles a frame a fixed processing latency after it arrived.
 * So the figures say what the protocol costs (round trips, overlap) and do
 * not move with the load of the machine they run on, unlike routing_bench.py
 * on the test VM.
 *
 * Network 1: client node 0x7F (its SDO client) and the gateway's node 1.
 * Network 3: the gateway's node 1 (with its own SDO client, the runtime's
 * 64 KiB buffer) and device 5 (a 4 KiB OCTET_STRING at 0x2100 and a
 * UNSIGNED32 at 0x2000). "direct": a client on network 3 reads / writes
 * device 5; "relayed": the client on network 1 through the gateway with
 * overlapping off (co_gateway_set_sdo_buffering false: every frame waits
 * for the device); "overlapped": the same with it on (downloads pipelined,
 * uploads read ahead). The same on two CAN FD networks (1 Mbit/s
 * arbitration, 5 Mbit/s data) with remote USDO (CiA 1301 routed requests,
 * store and forward in the gateway: one column "routed"). Figures are
 * printed, nothing is asserted. */
#include "canopenfd/co_gateway.h"
#include "canopenfd/co_membus.h"
#include "canopenfd/co_stack.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { QUEUE = 64, MAX_LINES = 4, GW = 1, DEV = 5, CLIENT = 0x7F, NET_A = 1, NET_C = 3,
       VALUE_MAX = 4096, IDX_VALUE = 0x2100, IDX_U32 = 0x2000 };

typedef struct sim_line {
    co_line_t line;
    co_frame_t rx[QUEUE], tx[QUEUE];
    uint64_t latency_us;         /* frame arrived -> handled */
    uint64_t process_at;         /* CO_TIME_NEVER: nothing waiting */
} sim_line_t;

typedef struct sim_bus {
    sim_line_t *lines[MAX_LINES];
    int count;
    uint32_t bit_ns;
    uint32_t data_bit_ns;        /* fd: the data phase's bit time, 0: classic */
    bool on_wire;
    co_frame_t frame;
    sim_line_t *from;
    uint64_t wire_end;
} sim_bus_t;

typedef struct node {
    sim_line_t sl;
    co_od_t od;
    co_od_entry_t entries[8];
    uint8_t pool[VALUE_MAX + 256];
    co_od_subscription_t subs[CO_STACK_OD_SUBSCRIPTIONS + CO_GATEWAY_OD_SUBSCRIPTIONS + 2];
    co_stack_t stack;
    co_stack_arena_t arena;
    unsigned char memory[64 * 1024];
} node_t;

typedef struct world {
    sim_bus_t a, c;
    node_t gw_a, gw_c, dev;
    sim_line_t client_a, client_c;
    co_stack_t tool_a, tool_c;
    co_stack_arena_t arena_a, arena_c;
    unsigned char mem_a[32 * 1024], mem_c[32 * 1024];
    co_gateway_t gw;
    uint8_t gw_buffer[64 * 1024];
    uint64_t now;
} world_t;

static world_t W;

static void die(const char *what)
{
    fprintf(stderr, "gateway_sim: %s\n", what);
    exit(2);
}

/* ------------------------------------------------------------ the model */

static void line_init(sim_line_t *l, sim_bus_t *bus, uint64_t latency_us)
{
    co_line_config_t cfg;
    memset(&cfg, 0, sizeof cfg);
    cfg.mode = bus->data_bit_ns != 0 ? CO_MODE_FD : CO_MODE_CLASSIC;
    cfg.brs = bus->data_bit_ns != 0;
    cfg.rx_slots = l->rx;
    cfg.rx_capacity = QUEUE;
    cfg.tx_slots = l->tx;
    cfg.tx_capacity = QUEUE;
    if (!co_line_init(&l->line, &cfg) || bus->count == MAX_LINES) {
        die("co_line_init");
    }
    l->latency_us = latency_us;
    l->process_at = CO_TIME_NEVER;
    bus->lines[bus->count++] = l;
}

/* Classic: 47 + 8 x data bits. FD with bit-rate switch: about 30 bits at
 * the arbitration rate (identifier, control, ACK, end of frame) and the data
 * with its CRC (21 bits, a few stuff bits) at the data rate. */
static uint64_t frame_ns(const sim_bus_t *b, const co_frame_t *f)
{
    if (b->data_bit_ns == 0) {
        return (uint64_t)(47u + 8u * f->len) * b->bit_ns;
    }
    return 30u * (uint64_t)b->bit_ns + (uint64_t)(8u * f->len + 28u) * b->data_bit_ns;
}

/* One instant: frames whose transmission ended are delivered, nodes whose
 * latency has run out handle what they got (and their timers), idle buses
 * take the waiting frame with the lowest CAN-ID. */
static void sim_step(sim_bus_t *b, uint64_t now_ns)
{
    uint64_t now_us = now_ns / 1000u;
    for (int i = 0; i < b->count; i++) {
        co_line_set_time(&b->lines[i]->line, now_us);   /* what a node sends is stamped now */
    }
    if (b->on_wire && b->wire_end <= now_ns) {
        for (int i = 0; i < b->count; i++) {
            sim_line_t *l = b->lines[i];
            if (l != b->from && co_line_receive(&l->line, &b->frame)) {
                uint64_t at = now_us + l->latency_us;
                l->process_at = at < l->process_at ? at : l->process_at;
            }
        }
        b->on_wire = false;
    }
    for (int i = 0; i < b->count; i++) {
        sim_line_t *l = b->lines[i];
        if (l->process_at <= now_us || co_timer_list_next(co_line_timers(&l->line)) <= now_us) {
            l->process_at = CO_TIME_NEVER;
            (void)co_line_process(&l->line, now_us);
        }
    }
    if (!b->on_wire) {
        sim_line_t *best = NULL;
        for (int i = 0; i < b->count; i++) {
            sim_line_t *l = b->lines[i];
            if (co_line_tx_count(&l->line) != 0 &&
                (best == NULL || co_line_tx_at(&l->line, 0)->id < co_line_tx_at(&best->line, 0)->id)) {
                best = l;
            }
        }
        if (best != NULL) {
            (void)co_line_tx_pop(&best->line, &b->frame);
            b->from = best;
            b->on_wire = true;
            b->wire_end = now_ns + frame_ns(b, &b->frame);
        }
    }
}

static uint64_t next_event_ns(const sim_bus_t *b)
{
    uint64_t next = b->on_wire ? b->wire_end : UINT64_MAX;
    for (int i = 0; i < b->count; i++) {
        const sim_line_t *l = b->lines[i];
        uint64_t t = co_timer_list_next(co_line_timers((co_line_t *)&l->line));
        t = l->process_at < t ? l->process_at : t;
        if (t != CO_TIME_NEVER && t * 1000u < next) {
            next = t * 1000u;
        }
        if (!b->on_wire && co_line_tx_count(&l->line) != 0) {
            next = 0;   /* a frame waits for an idle bus: now */
        }
    }
    return next;
}

/* Run both buses until `until_ns` or until nothing is left to do. */
static void sim_run(uint64_t until_ns)
{
    for (;;) {
        for (int round = 0; round < 3; round++) {
            sim_step(&W.a, W.now);
            sim_step(&W.c, W.now);
        }
        uint64_t a = next_event_ns(&W.a), c = next_event_ns(&W.c);
        uint64_t next = a < c ? a : c;
        if (next == UINT64_MAX || next > until_ns) {
            return;
        }
        W.now = next > W.now ? next : W.now;
    }
}

/* ------------------------------------------------------------ the nodes */

static void od_add(co_od_t *od, uint16_t index, uint8_t type, uint8_t access, uint32_t size)
{
    co_od_def_t d;
    memset(&d, 0, sizeof d);
    d.index = index;
    d.object_code = CO_OBJECT_VAR;
    d.type = type;
    d.access = access;
    d.size = size;
    if (co_od_add(od, &d) != CO_OD_ADDED) {
        die("co_od_add");
    }
}

static void node_init(node_t *n, sim_bus_t *bus, uint8_t node_id, uint64_t latency_us)
{
    line_init(&n->sl, bus, latency_us);
    co_od_init(&n->od, co_line_mode(&n->sl.line), n->entries, 8, n->pool, sizeof n->pool, n->subs,
               sizeof n->subs / sizeof n->subs[0]);
    od_add(&n->od, 0x1000, CO_TYPE_UNSIGNED32, CO_ACCESS_RO, 4);
    od_add(&n->od, 0x1001, CO_TYPE_UNSIGNED8, CO_ACCESS_RO, 1);
    od_add(&n->od, 0x1017, CO_TYPE_UNSIGNED16, CO_ACCESS_RW, 2);
    od_add(&n->od, IDX_U32, CO_TYPE_UNSIGNED32, CO_ACCESS_RW, 4);
    od_add(&n->od, IDX_VALUE, CO_TYPE_OCTET_STRING, CO_ACCESS_RW, VALUE_MAX);
    if (!co_od_seal(&n->od, node_id)) {
        die("co_od_seal");
    }
    co_stack_arena_init(&n->arena, n->memory, sizeof n->memory);
    co_stack_line_config_t lc = {.heartbeat_entries = 1};
    co_stack_node_config_t nc = {.node_id = node_id, .od = &n->od};
    if (co_stack_init(&n->stack, &n->sl.line, &lc, co_stack_arena_allocator(&n->arena)) !=
            CO_STACK_OK ||
        co_stack_node_init(&n->stack, &nc) != CO_STACK_OK ||
        co_stack_boot(&n->stack) != CO_STACK_OK) {
        die("node stack");
    }
}

static void client_init(co_stack_t *s, co_stack_arena_t *arena, unsigned char *mem, size_t size,
                        sim_line_t *l, sim_bus_t *bus, uint64_t latency_us)
{
    line_init(l, bus, latency_us);
    co_stack_arena_init(arena, mem, size);
    co_stack_line_config_t lc = {.heartbeat_entries = 1};
    co_stack_client_config_t cc = {.sessions = 1, .node_id = CLIENT, .timeout_ms = 1000};
    if (co_stack_init(s, &l->line, &lc, co_stack_arena_allocator(arena)) != CO_STACK_OK ||
        co_stack_client_init(s, &cc) != CO_STACK_OK) {
        die("client stack");
    }
}

/* value_size: the bytes of device 5's 0x2100 */
static void world_init(uint32_t bit_ns, uint32_t data_bit_ns, uint64_t device_us,
                       uint64_t gateway_us, uint64_t client_us, uint32_t value_size)
{
    memset(&W, 0, sizeof W);
    W.a.bit_ns = bit_ns;
    W.c.bit_ns = bit_ns;
    W.a.data_bit_ns = data_bit_ns;
    W.c.data_bit_ns = data_bit_ns;
    node_init(&W.gw_a, &W.a, GW, gateway_us);
    node_init(&W.gw_c, &W.c, GW, gateway_us);
    node_init(&W.dev, &W.c, DEV, device_us);
    client_init(&W.tool_a, &W.arena_a, W.mem_a, sizeof W.mem_a, &W.client_a, &W.a, client_us);
    client_init(&W.tool_c, &W.arena_c, W.mem_c, sizeof W.mem_c, &W.client_c, &W.c, client_us);
    co_stack_client_config_t own = {.sessions = 2, .node_id = GW, .timeout_ms = 1000};
    if (co_stack_client_init(&W.gw_c.stack, &own) != CO_STACK_OK) {
        die("the gateway's own client");
    }
    co_gateway_init(&W.gw, NULL, NULL);
    if (co_gateway_add_port(&W.gw, &W.gw_a.stack, NET_A) != CO_GATEWAY_OK ||
        co_gateway_add_port(&W.gw, &W.gw_c.stack, NET_C) != CO_GATEWAY_OK) {
        die("gateway ports");
    }
    co_gateway_set_sdo_buffer(&W.gw, W.gw_buffer, sizeof W.gw_buffer);
    uint8_t value[VALUE_MAX];
    for (unsigned i = 0; i < sizeof value; i++) {
        value[i] = (uint8_t)(i * 7u);
    }
    if (co_od_put(&W.dev.od, IDX_VALUE, 0, value, value_size) != 0) {
        die("co_od_put");
    }
    sim_run(10u * 1000u * 1000u);   /* boot-ups */
}

static void world_deinit(void)
{
    co_gateway_deinit(&W.gw);
    co_stack_deinit(&W.tool_a);
    co_stack_deinit(&W.tool_c);
    co_stack_deinit(&W.gw_a.stack);
    co_stack_deinit(&W.gw_c.stack);
    co_stack_deinit(&W.dev.stack);
}

/* ------------------------------------------------------------ the transfers */

typedef struct run {
    co_sdo_request_t req;            /* classic lines */
    co_usdo_request_t ureq;          /* fd lines */
    bool fd;
    co_sdo_client_t *client;
    co_usdo_client_t *uclient;
    co_line_t *line;
    uint8_t data[VALUE_MAX];
    co_sdo_buffer_t buffer;
    uint64_t end_ns;
    uint64_t last_done_ns;
    uint32_t done, failed;
    uint64_t bytes;
} run_t;

static run_t R;

static void start(run_t *r);

/* A transfer ended: counted, and the next one started while time is left. */
static void ended(run_t *r, uint32_t abort, bool upload, uint32_t size)
{
    if (abort != 0) {
        r->failed++;
        fprintf(stderr, "gateway_sim: %s %s aborted 0x%08X\n", r->fd ? "USDO" : "SDO",
                upload ? "upload" : "download", (unsigned)abort);
        return;
    }
    r->done++;
    r->last_done_ns = W.now;
    r->bytes += upload ? r->buffer.size : size;
    if (W.now < r->end_ns) {
        start(r);
    }
}

static void on_done(co_sdo_request_t *req)
{
    ended(req->user, req->abort, req->upload, req->size);
}

static void on_usdo_done(co_usdo_request_t *req)
{
    ended(req->user, req->abort, req->upload, req->size);
}

static void start(run_t *r)
{
    bool upload = r->fd ? r->ureq.upload : r->req.upload;
    r->buffer.size = upload ? 0 : (r->fd ? r->ureq.size : r->req.size);   /* sink / source */
    co_line_set_time(r->line, W.now / 1000u);
    if (r->fd) {
        r->ureq.abort = 0;
        if (co_usdo_client_start(r->uclient, &r->ureq) != 0) {
            die("co_usdo_client_start");
        }
        return;
    }
    r->req.abort = 0;
    r->req.fell_back = false;
    if (co_sdo_client_start(r->client, &r->req) != 0) {
        die("co_sdo_client_start");
    }
}

/* kB/s of repeated transfers for `seconds` of bus time. */
static double measure(bool routed, bool upload, uint32_t size, uint8_t mode, double seconds)
{
    memset(&R, 0, sizeof R);
    co_stack_t *tool = routed ? &W.tool_a : &W.tool_c;
    R.fd = W.a.data_bit_ns != 0;
    R.client = co_stack_sdo_client(tool);
    R.uclient = co_stack_usdo_client(tool);
    R.line = routed ? &W.client_a.line : &W.client_c.line;
    R.buffer = (co_sdo_buffer_t){.data = R.data, .size = upload ? 0 : size,
                                 .capacity = sizeof R.data};
    uint16_t index = size == 4 ? IDX_U32 : IDX_VALUE;
    if (R.fd) {
        R.ureq = (co_usdo_request_t){
            .server = routed ? GW : DEV, .index = index, .upload = upload, .mode = mode,
            .size = upload ? 0 : size, .source = upload ? NULL : co_usdo_buffer_source,
            .sink = upload ? co_usdo_buffer_sink : NULL, .ctx = &R.buffer,
            .done = on_usdo_done, .user = &R, .timeout_ms = 1000,
            .network = routed ? NET_C : 0, .network_node = routed ? DEV : 0,
            .source_network = routed ? NET_A : 0};
    }
    R.req = (co_sdo_request_t){
        .server = routed ? GW : DEV, .index = index, .upload = upload, .mode = mode,
        .size = upload ? 0 : size, .source = upload ? NULL : co_sdo_buffer_source,
        .sink = upload ? co_sdo_buffer_sink : NULL, .ctx = &R.buffer, .done = on_done,
        .user = &R, .timeout_ms = 1000, .network = routed ? NET_C : 0,
        .network_node = routed ? DEV : 0};
    uint64_t begin = W.now;
    R.end_ns = W.now + (uint64_t)(seconds * 1e9);
    start(&R);
    sim_run(R.end_ns + 5ull * 1000 * 1000 * 1000);
    if (R.failed != 0 || R.done == 0) {
        die("a transfer failed");
    }
    return (double)R.bytes / ((double)(R.last_done_ns - begin) / 1e9) / 1000.0;
}

typedef struct row {
    const char *name;
    bool upload;
    uint32_t size;
    uint8_t mode;
} row_t;

int main(int argc, char **argv)
{
    double seconds = 2.0;
    if (argc == 3 && strcmp(argv[1], "-t") == 0) {
        seconds = atof(argv[2]);
    } else if (argc != 1) {
        fprintf(stderr, "usage: gateway_sim [-t SECONDS of bus time per figure]\n");
        return 2;
    }
    static const row_t rows[] = {
        {"4 B upload (expedited)", true, 4, CO_SDO_MODE_AUTO},
        {"4 B download (expedited)", false, 4, CO_SDO_MODE_AUTO},
        {"4096 B upload segmented", true, 4096, CO_SDO_MODE_SEGMENTED},
        {"4096 B download segmented", false, 4096, CO_SDO_MODE_SEGMENTED},
        {"4096 B upload block", true, 4096, CO_SDO_MODE_BLOCK},
        {"4096 B download block", false, 4096, CO_SDO_MODE_BLOCK},
    };
    static const struct { uint32_t kbit; uint64_t device_us, gateway_us, client_us; } setups[] = {
        {1000, 100, 100, 100},   /* MCU-fast nodes everywhere */
        {1000, 100, 500, 500},   /* a Linux gateway and host client, slower to answer */
        {250, 200, 500, 500},
    };
    printf("SDO through the gateway, simulated bus time (%.1f s per figure), kB/s and share "
           "of direct\n", seconds);
    for (size_t s = 0; s < sizeof setups / sizeof setups[0]; s++) {
        printf("\n%u kbit/s, node latency: device %llu us, gateway %llu us, client %llu us\n",
               (unsigned)setups[s].kbit, (unsigned long long)setups[s].device_us,
               (unsigned long long)setups[s].gateway_us, (unsigned long long)setups[s].client_us);
        printf("%-26s | %9s | %9s %6s | %10s %6s\n", "transfer", "direct", "relayed", "share",
               "overlapped", "share");
        world_init(1000000u / setups[s].kbit, 0, setups[s].device_us, setups[s].gateway_us,
                   setups[s].client_us, VALUE_MAX);
        for (size_t i = 0; i < sizeof rows / sizeof rows[0]; i++) {
            const row_t *r = &rows[i];
            double direct = measure(false, r->upload, r->size, r->mode, seconds);
            co_gateway_set_sdo_buffering(&W.gw, false);
            double relayed = measure(true, r->upload, r->size, r->mode, seconds);
            co_gateway_set_sdo_buffering(&W.gw, true);
            double overlapped = measure(true, r->upload, r->size, r->mode, seconds);
            printf("%-26s | %9.2f | %9.2f %5.0f%% | %10.2f %5.0f%%\n", r->name, direct, relayed,
                   100.0 * relayed / direct, overlapped, 100.0 * overlapped / direct);
        }
        const co_gateway_stats_t *st = co_gateway_stats(&W.gw);
        printf("gateway: %u requests relayed, %u segments answered ahead, %u uploads buffered\n",
               (unsigned)st->sdo_relayed, (unsigned)st->sdo_pipelined,
               (unsigned)st->sdo_translated);
        world_deinit();
    }
    /* remote USDO on CAN FD: always store and forward (co_gateway_usdo.c) */
    static const row_t fd_rows[] = {
        {"4 B upload (expedited)", true, 4, CO_USDO_MODE_AUTO},
        {"4 B download (expedited)", false, 4, CO_USDO_MODE_AUTO},
        {"1000 B upload segmented", true, 1000, CO_USDO_MODE_SEGMENTED},
        {"1000 B download segmented", false, 1000, CO_USDO_MODE_SEGMENTED},
    };
    printf("\nremote USDO, CAN FD 1 Mbit/s / 5 Mbit/s, node latency: device 100 us, "
           "gateway 100 us, client 100 us\n");
    printf("%-26s | %9s | %9s %6s\n", "transfer", "direct", "routed", "share");
    world_init(1000u, 200u, 100, 100, 100, 1000);   /* remote USDO: values up to 1 KiB */
    for (size_t i = 0; i < sizeof fd_rows / sizeof fd_rows[0]; i++) {
        const row_t *r = &fd_rows[i];
        double direct = measure(false, r->upload, r->size, r->mode, seconds);
        double routed = measure(true, r->upload, r->size, r->mode, seconds);
        printf("%-26s | %9.2f | %9.2f %5.0f%%\n", r->name, direct, routed,
               100.0 * routed / direct);
    }
    printf("gateway: %u remote requests answered\n",
           (unsigned)co_gateway_stats(&W.gw)->usdo_answered);
    world_deinit();
    return 0;
}
