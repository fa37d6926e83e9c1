/* The example device on Linux.
 *
 *   fd_device IFACE NODE-ID [--classic]   serve on a SocketCAN interface until
 *                                         SIGINT/SIGTERM
 *   fd_device --selftest [--classic]      the device and a client on an
 *                                         in-process bus: the client reads the
 *                                         device's OD and prints it
 *
 * One thread, no allocation: wait for the socket or the next deadline, feed
 * frames in, process, hand the tx queue to the socket. */
#define _GNU_SOURCE
#include "canopenfd/co_membus.h"
#include "canopenfd/co_socketcan.h"
#include "device.h"

#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static volatile sig_atomic_t stop;

static void on_signal(int sig)
{
    (void)sig;
    stop = 1;
}

static uint64_t now_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

static device_t device;   /* static: an MCU would place it the same way */

/* Hand queued frames to the socket; those it cannot take wait. */
static void flush(co_socketcan_t *sc)
{
    co_frame_t frame;
    while (co_line_tx_count(&device.line) > 0) {
        unsigned sent = 0;
        if (co_sc_write(sc, co_line_tx_at(&device.line, 0), 1, &sent) != CO_SC_DONE ||
            sent != 1) {
            return;
        }
        (void)co_line_tx_pop(&device.line, &frame);
    }
}

static int serve(const char *iface, int node_id, co_mode_t mode)
{
    const char *failed = device_init(&device, mode, (uint8_t)node_id);
    if (failed) {
        fprintf(stderr, "fd_device: %s could not be set up\n", failed);
        return 1;
    }
    co_socketcan_t sc;
    char err[160];
    co_sc_init(&sc);
    if (co_sc_open(&sc, iface, mode, err, sizeof err) != CO_SC_OPEN_OK) {
        fprintf(stderr, "fd_device: %s\n", err);
        return 1;
    }
    signal(SIGINT, on_signal);
    signal(SIGTERM, on_signal);
    printf("node %d serving on %s (%s)\n", node_id, iface, mode == CO_MODE_FD ? "fd" : "classic");
    fflush(stdout);
    uint64_t start = now_us();
    while (!stop) {
        uint64_t next = device_process(&device, now_us() - start);
        flush(&sc);
        uint64_t now = now_us() - start;
        int timeout = next == CO_TIME_NEVER ? 1000 : next <= now ? 0 : (int)((next - now + 999) / 1000);
        struct pollfd p = {.fd = sc.fd, .events = POLLIN};
        if (co_line_tx_count(&device.line) > 0) {
            p.events |= POLLOUT;
        }
        if (poll(&p, 1, timeout > 1000 ? 1000 : timeout) <= 0) {
            continue;
        }
        co_sc_rx_t items[CO_SC_BATCH];
        unsigned count = 0;
        if (co_sc_read(&sc, items, CO_SC_BATCH, &count) == CO_SC_DONE) {
            for (unsigned i = 0; i < count; i++) {
                for (unsigned e = 0; e < items[i].event_count; e++) {
                    co_line_comm_event(&device.line, items[i].events[e]);
                }
                if (items[i].has_frame) {
                    (void)co_line_receive(&device.line, &items[i].frame);
                }
            }
        }
    }
    co_sc_close(&sc);
    return 0;
}

/* ---------------------------------------------------------------- self-test */

typedef struct reading {
    co_buffer_t sink;
    uint8_t data[64];
    bool done;
    uint32_t abort;
} reading_t;

static void usdo_done(co_usdo_request_t *req) { ((reading_t *)req->user)->done = true; }
static void sdo_done(co_sdo_request_t *req) { ((reading_t *)req->user)->done = true; }

/* Read index:sub of the device with the client of `tool`, moving frames
 * over the in-process bus until the answer is in. */
static bool read_entry(co_membus_t *bus, co_line_t *tool_line, co_stack_t *tool, uint8_t node,
                       uint16_t index, uint8_t sub, reading_t *r)
{
    memset(r, 0, sizeof *r);
    r->sink.data = r->data;
    r->sink.capacity = sizeof r->data;
    co_usdo_request_t ureq = {.server = node, .index = index, .sub = sub, .upload = true,
                              .sink = co_usdo_buffer_sink, .ctx = &r->sink, .done = usdo_done,
                              .user = r};
    co_sdo_request_t sreq = {.server = node, .index = index, .sub = sub, .upload = true,
                             .sink = co_sdo_buffer_sink, .ctx = &r->sink, .done = sdo_done,
                             .user = r};
    bool started = co_stack_usdo_client(tool)
                       ? co_usdo_client_start(co_stack_usdo_client(tool), &ureq) == 0
                       : co_sdo_client_start(co_stack_sdo_client(tool), &sreq) == 0;
    uint64_t t = co_line_now(tool_line);
    for (int round = 0; started && !r->done && round < 10000; round++) {
        t += 100;
        (void)device_process(&device, t);
        (void)co_line_process(tool_line, t);
        (void)co_membus_transfer(bus, NULL, NULL);
    }
    r->abort = co_stack_usdo_client(tool) ? ureq.abort : sreq.abort;
    return started && r->done && r->abort == 0;
}

static uint32_t le32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static int selftest(co_mode_t mode)
{
    enum { NODE = 5, CLIENT = 9 };
    const char *failed = device_init(&device, mode, NODE);
    if (failed) {
        fprintf(stderr, "fd_device: %s could not be set up\n", failed);
        return 1;
    }
    static co_line_t tool_line;
    static co_frame_t rx[64], tx[64];
    static co_stack_t tool;
    static co_stack_arena_t arena;
    static uint64_t memory[4096];
    co_line_config_t lc = {.mode = mode, .brs = mode == CO_MODE_FD, .rx_slots = rx,
                           .rx_capacity = 64, .tx_slots = tx, .tx_capacity = 64};
    co_membus_t bus;
    co_membus_init(&bus);
    co_stack_arena_init(&arena, memory, sizeof memory);
    co_stack_client_config_t cc = {.sessions = 1, .node_id = CLIENT};
    if (!co_line_init(&tool_line, &lc) || !co_membus_attach(&bus, &device.line) ||
        !co_membus_attach(&bus, &tool_line) ||
        co_stack_init(&tool, &tool_line, NULL, co_stack_arena_allocator(&arena)) != CO_STACK_OK ||
        co_stack_client_init(&tool, &cc) != CO_STACK_OK) {
        fprintf(stderr, "fd_device: the self-test client could not be set up\n");
        return 1;
    }
    reading_t r;
    static const struct { uint16_t index; uint8_t sub; const char *what; } entries[] = {
        {0x1000, 0, "device type"}, {0x1018, 1, "vendor-id"}, {0x1018, 2, "product code"},
        {0x1018, 4, "serial number"}, {0x1008, 0, "device name"}};
    for (size_t i = 0; i < sizeof entries / sizeof entries[0]; i++) {
        if (!read_entry(&bus, &tool_line, &tool, NODE, entries[i].index, entries[i].sub, &r)) {
            fprintf(stderr, "fd_device: reading 0x%04X:%02X failed (abort 0x%08X)\n",
                    entries[i].index, entries[i].sub, (unsigned)r.abort);
            return 1;
        }
        if (entries[i].index == 0x1008) {
            printf("%s 0x%04X:%02X = \"%.*s\"\n", entries[i].what, entries[i].index,
                   entries[i].sub, (int)r.sink.size, (const char *)r.data);
        } else {
            printf("%s 0x%04X:%02X = 0x%08X\n", entries[i].what, entries[i].index,
                   entries[i].sub, (unsigned)le32(r.data));
        }
    }
    printf("self-test passed (%s, node %d, client %s)\n", mode == CO_MODE_FD ? "fd" : "classic",
           NODE, mode == CO_MODE_FD ? "USDO" : "SDO");
    return 0;
}

int main(int argc, char **argv)
{
    co_mode_t mode = CO_MODE_FD;
    const char *args[2] = {NULL, NULL};
    int n = 0;
    bool self = false;
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--classic") == 0) {
            mode = CO_MODE_CLASSIC;
        } else if (strcmp(argv[i], "--selftest") == 0) {
            self = true;
        } else if (n < 2) {
            args[n++] = argv[i];
        }
    }
    if (self) {
        return selftest(mode);
    }
    int node_id = n == 2 ? atoi(args[1]) : 0;
    if (n != 2 || node_id < 1 || node_id > 127) {
        fprintf(stderr, "usage: fd_device IFACE NODE-ID [--classic] | fd_device --selftest "
                        "[--classic]\n");
        return 2;
    }
    return serve(args[0], node_id, mode);
}
