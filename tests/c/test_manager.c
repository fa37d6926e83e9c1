/* co_manager: the CiA 302-2 network start-up on an in-process bus. A manager
 * stack (node 1, its OD with 0x1F80/0x1F81/0x1F84../0x1F89/0x1016, SDO or
 * USDO client) boots real slave stacks (nodes 2..4) under a fake clock; the
 * sniffer checks the SDO requests and answers of the identity checks byte
 * for byte, the NMT commands (reset communication, start per node or to
 * all), a missing mandatory slave (B until 0x1F89 passed, start halted), an
 * optional slave appearing later, keep-alive with an operational slave (L,
 * no reset), the application hooks with their continue calls, and a lost
 * heartbeat (the slave is reset and booted again). */
#include "test_od_util.h"

#include "canopenfd/co_manager.h"
#include "canopenfd/co_stack.h"

#include <stdlib.h>

enum { MANAGER = 1, MAX_SLAVES = 3, MAX_EVENTS = 256 };

#define DEVICE_TYPE 0x00020191u
#define VENDOR 0x000000AAu
#define PRODUCT 0x00001234u

/* ------------------------------------------------------------ ODs */

typedef struct od_store {
    co_od_t od;
    co_od_entry_t entries[128];
    uint8_t pool[2048];
    co_od_subscription_t subs[CO_STACK_OD_SUBSCRIPTIONS + 4];
} od_store_t;

static void od_begin(od_store_t *d, co_mode_t mode)
{
    memset(d, 0, sizeof *d);
    co_od_init(&d->od, mode, d->entries, 128, d->pool, sizeof d->pool, d->subs,
               CO_STACK_OD_SUBSCRIPTIONS + 4);
}

static void od_add(od_store_t *d, uint16_t index, uint8_t sub, uint8_t object_code, uint8_t type,
                   uint8_t access, int64_t value)
{
    tu_od_row_t row = {index, sub, object_code, type, access, 0,
                       co_od_type_size(type), value, NULL, 0, 0};
    tu_od_add_rows(&d->od, &row, 1);
}

/* An array with sub 0 = count and subs 1..count from `values`. */
static void od_array(od_store_t *d, uint16_t index, uint8_t count, const uint32_t *values)
{
    od_add(d, index, 0, ARR, U8, RO, count);
    for (uint8_t i = 1; i <= count; i++) {
        od_add(d, index, i, ARR, U32, RW, values[i - 1]);
    }
}

/* A slave: device type, identity, heartbeat producer time, error register. */
static void slave_od(od_store_t *d, co_mode_t mode, uint8_t node_id, uint32_t serial,
                     uint16_t heartbeat_ms)
{
    od_begin(d, mode);
    if (mode == CO_MODE_FD) {   /* CiA 1301: one device type per logical device */
        od_add(d, 0x1000, 0, ARR, U8, RO, 1);
        od_add(d, 0x1000, 1, ARR, U32, RO, DEVICE_TYPE);
    } else {
        od_add(d, 0x1000, 0, VAR, U32, RO, DEVICE_TYPE);
    }
    od_add(d, 0x1001, 0, VAR, U8, RO, 0);
    od_add(d, 0x1017, 0, VAR, U16, RW, heartbeat_ms);
    od_add(d, 0x1018, 0, REC, U8, RO, 4);
    od_add(d, 0x1018, 1, REC, U32, RO, VENDOR);
    od_add(d, 0x1018, 2, REC, U32, RO, PRODUCT);
    od_add(d, 0x1018, 3, REC, U32, RO, 0x00010002);
    od_add(d, 0x1018, 4, REC, U32, RO, serial);
    assert_true(co_od_seal(&d->od, node_id));
}

/* What the manager's OD says (index = node-id - 1 in the arrays). */
typedef struct plan {
    uint32_t startup;            /* 0x1F80 */
    uint32_t assignment[4];      /* 0x1F81:1..4 */
    uint32_t device_type[4];     /* 0x1F84 */
    uint32_t vendor[4];          /* 0x1F85 */
    uint32_t serial[4];          /* 0x1F88 */
    uint32_t heartbeat[2];       /* 0x1016:1..2 */
    uint32_t boot_time_ms;       /* 0x1F89 */
} plan_t;

static void manager_od(od_store_t *d, co_mode_t mode, const plan_t *p)
{
    od_begin(d, mode);
    od_add(d, 0x1000, 0, VAR, U32, RO, 0x00000000);
    od_add(d, 0x1001, 0, VAR, U8, RO, 0);
    od_array(d, 0x1016, 2, p->heartbeat);
    od_add(d, 0x1017, 0, VAR, U16, RW, 0);
    od_array(d, 0x1F81, 4, p->assignment);
    od_array(d, 0x1F84, 4, p->device_type);
    od_array(d, 0x1F85, 4, p->vendor);
    od_array(d, 0x1F88, 4, p->serial);
    od_add(d, 0x1F80, 0, VAR, U32, RW, p->startup);
    od_add(d, 0x1F89, 0, VAR, U32, RW, p->boot_time_ms);
    assert_true(co_od_seal(&d->od, MANAGER));
}

/* ------------------------------------------------------------ fixture */

typedef struct station {
    tu_line_t tl;
    od_store_t od;
    co_stack_t stack;
    co_stack_arena_t arena;
    unsigned char memory[96 * 1024];
} station_t;

typedef struct fx {
    tu_bus_t tb;
    co_mode_t mode;
    station_t manager;
    station_t slaves[MAX_SLAVES];   /* node-ids 2, 3, 4 */
    co_manager_report_t events[MAX_EVENTS];
    unsigned event_count;
    bool answer_config;             /* answer UPDATE_CONFIG at once with config_ok */
    bool config_ok;
} fx_t;

static void on_event(co_manager_t *m, const co_manager_report_t *r, void *user)
{
    (void)m;
    fx_t *fx = user;
    assert_true(fx->event_count < MAX_EVENTS);
    fx->events[fx->event_count++] = *r;
    if (r->event == CO_MANAGER_EV_UPDATE_CONFIG && fx->answer_config) {
        assert_true(co_manager_continue_config(m, r->node_id, fx->config_ok));
    }
}

static fx_t *fx_new(co_mode_t mode)
{
    fx_t *fx = calloc(1, sizeof *fx);
    assert_non_null(fx);
    fx->mode = mode;
    tu_bus_init(&fx->tb, mode, mode == CO_MODE_FD);
    return fx;
}

static void station_stack(station_t *st, uint8_t guarded)
{
    co_stack_arena_init(&st->arena, st->memory, sizeof st->memory);
    co_stack_line_config_t lc = {.heartbeat_entries = 8, .guarded_nodes = guarded};
    assert_int_equal(co_stack_init(&st->stack, &st->tl.line, &lc,
                                   co_stack_arena_allocator(&st->arena)), CO_STACK_OK);
}

/* The manager station (not started yet). */
static co_manager_t *fx_manager(fx_t *fx, const plan_t *p, uint8_t hooks)
{
    station_t *st = &fx->manager;
    tu_bus_add_line(&fx->tb, &st->tl);
    manager_od(&st->od, fx->mode, p);
    station_stack(st, fx->mode == CO_MODE_CLASSIC ? 4 : 0);
    co_stack_node_config_t nc = {.node_id = MANAGER, .od = &st->od.od};
    assert_int_equal(co_stack_node_init(&st->stack, &nc), CO_STACK_OK);
    co_stack_client_config_t cc = {.sessions = 4, .node_id = MANAGER, .timeout_ms = 100};
    assert_int_equal(co_stack_client_init(&st->stack, &cc), CO_STACK_OK);
    co_stack_manager_config_t mc = {.hooks = hooks, .on_event = on_event, .user = fx};
    assert_int_equal(co_stack_manager_init(&st->stack, &mc), CO_STACK_OK);
    assert_int_equal(co_stack_boot(&st->stack), CO_STACK_OK);
    return co_stack_manager(&st->stack);
}

/* A slave station, booted when `boot`. */
static station_t *fx_slave(fx_t *fx, uint8_t node_id, uint32_t serial, uint16_t hb_ms, bool boot)
{
    station_t *st = &fx->slaves[node_id - 2];
    tu_bus_add_line(&fx->tb, &st->tl);
    slave_od(&st->od, fx->mode, node_id, serial, hb_ms);
    station_stack(st, 0);
    co_stack_node_config_t nc = {.node_id = node_id, .od = &st->od.od};
    assert_int_equal(co_stack_node_init(&st->stack, &nc), CO_STACK_OK);
    if (boot) {
        assert_int_equal(co_stack_boot(&st->stack), CO_STACK_OK);
    }
    return st;
}

static void fx_free(fx_t *fx)
{
    co_stack_deinit(&fx->manager.stack);
    for (unsigned i = 0; i < MAX_SLAVES; i++) {
        if (fx->slaves[i].stack.line) {
            co_stack_deinit(&fx->slaves[i].stack);
        }
    }
    free(fx);
}

static co_nmt_state_t state_of(station_t *st)
{
    return co_node_state(co_stack_node(&st->stack));
}

static void start(fx_t *fx, co_manager_t *m)
{
    for (uint8_t i = 0; i < fx->tb.count; i++) {
        co_line_set_time(&fx->tb.lines[i]->line, fx->tb.now);
    }
    assert_int_equal(co_manager_start(m), CO_MANAGER_OK);
    tu_step(&fx->tb, fx->tb.now);   /* what the start queued goes out now */
}

/* Index of the k-th event of a kind (for node, 0xFF = any), -1 when none. */
static long find_event(const fx_t *fx, co_manager_event_t event, uint8_t node, unsigned k)
{
    for (unsigned i = 0; i < fx->event_count; i++) {
        if (fx->events[i].event == event && (node == 0xFF || fx->events[i].node_id == node) &&
            k-- == 0) {
            return (long)i;
        }
    }
    return -1;
}

static unsigned count_event(const fx_t *fx, co_manager_event_t event, uint8_t node)
{
    unsigned n = 0;
    while (find_event(fx, event, node, n) >= 0) {
        n++;
    }
    return n;
}

/* Index of the k-th logged frame with this id and these leading bytes. */
static long find_frame(const tu_bus_t *tb, uint32_t id, const uint8_t *head, uint8_t n,
                       size_t k)
{
    for (size_t i = 0; i < tb->log_count; i++) {
        const co_frame_t *f = &tb->log[i].frame;
        if (f->id == id && f->len >= n && memcmp(f->data, head, n) == 0 && k-- == 0) {
            return (long)i;
        }
    }
    return -1;
}

static const uint8_t NMT_RESET_COMM_2[] = {0x82, 2};
static const uint8_t NMT_START_2[] = {0x01, 2};
static const uint8_t NMT_START_3[] = {0x01, 3};

/* ------------------------------------------------------------ tests */

/* Two slaves, 2 mandatory, 3 optional: identity read over SDO (exact bytes),
 * reset communication, boot-up, then the manager goes operational and
 * starts each slave with its own NMT start. */
static void test_classic_network_boots_with_exact_frames(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC);
    plan_t p = {.startup = CO_MANAGER_STARTUP_MANAGER,
                .assignment = {0, 0x0D, 0x05, 0},
                .device_type = {0, DEVICE_TYPE, DEVICE_TYPE, 0},
                .vendor = {0, VENDOR, VENDOR, 0},
                .serial = {0, 0x5002, 0, 0}};
    co_manager_t *m = fx_manager(fx, &p, 0);
    station_t *s2 = fx_slave(fx, 2, 0x5002, 0, true);
    station_t *s3 = fx_slave(fx, 3, 0x5003, 0, true);
    tu_run_until(&fx->tb, 10 * TU_MS);
    tu_log_clear(&fx->tb);
    start(fx, m);
    tu_run_until(&fx->tb, 200 * TU_MS);

    /* the device type read of node 2 and its answer, byte for byte */
    long rq = find_frame(&fx->tb, 0x602, (const uint8_t[]){0x40, 0x00, 0x10, 0x00}, 4, 0);
    tu_assert_logged(&fx->tb, rq, 0x602,
                     (const uint8_t[]){0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}, 8);
    long an = find_frame(&fx->tb, 0x582, (const uint8_t[]){0x43, 0x00, 0x10, 0x00}, 4, 0);
    tu_assert_logged(&fx->tb, an, 0x582,
                     (const uint8_t[]){0x43, 0x00, 0x10, 0x00, 0x91, 0x01, 0x02, 0x00}, 8);
    assert_true(an > rq);
    /* vendor and serial of node 2 (product and revision are not expected:
     * not read); node 3 has no serial expected */
    long vendor = find_frame(&fx->tb, 0x602, (const uint8_t[]){0x40, 0x18, 0x10, 0x01}, 4, 0);
    tu_assert_logged(&fx->tb, vendor, 0x602,
                     (const uint8_t[]){0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0}, 8);
    tu_assert_logged(&fx->tb,
                     find_frame(&fx->tb, 0x582, (const uint8_t[]){0x43, 0x18, 0x10, 0x04}, 4, 0),
                     0x582, (const uint8_t[]){0x43, 0x18, 0x10, 0x04, 0x02, 0x50, 0, 0}, 8);
    assert_int_equal(find_frame(&fx->tb, 0x602, (const uint8_t[]){0x40, 0x18, 0x10, 0x02}, 4,
                                0), -1);
    assert_int_equal(find_frame(&fx->tb, 0x603, (const uint8_t[]){0x40, 0x18, 0x10, 0x04}, 4,
                                0), -1);
    /* reset communication, boot-up, start: in that order */
    long reset = find_frame(&fx->tb, 0x000, NMT_RESET_COMM_2, 2, 0);
    tu_assert_logged(&fx->tb, reset, 0x000, NMT_RESET_COMM_2, 2);
    long bootup = find_frame(&fx->tb, 0x702, (const uint8_t[]){0x00}, 1, 0);
    long start2 = find_frame(&fx->tb, 0x000, NMT_START_2, 2, 0);
    tu_assert_logged(&fx->tb, start2, 0x000, NMT_START_2, 2);
    assert_true(vendor < reset && reset < bootup && bootup < start2);
    assert_true(find_frame(&fx->tb, 0x000, NMT_START_3, 2, 0) >= 0);
    assert_int_equal(find_frame(&fx->tb, 0x000, (const uint8_t[]){0x01, 0x00}, 2, 0), -1);

    assert_int_equal(co_manager_phase(m), CO_MANAGER_RUNNING);
    assert_int_equal(state_of(&fx->manager), CO_NMT_OPERATIONAL);
    assert_int_equal(state_of(s2), CO_NMT_OPERATIONAL);
    assert_int_equal(state_of(s3), CO_NMT_OPERATIONAL);
    assert_int_equal(co_manager_slave_status(m, 2), CO_MANAGER_SLAVE_BOOTED);
    assert_int_equal(co_manager_slave_status(m, 4), CO_MANAGER_SLAVE_NONE);
    long booted2 = find_event(fx, CO_MANAGER_EV_SLAVE_BOOTED, 2, 0);
    long started = find_event(fx, CO_MANAGER_EV_NETWORK_STARTED, 0xFF, 0);
    assert_true(booted2 >= 0 && started > booted2);
    assert_int_equal(count_event(fx, CO_MANAGER_EV_NETWORK_STARTED, 0xFF), 1);
    fx_free(fx);
}

/* 0x1F80 bit 1: one NMT start to all nodes, none per node (both slaves
 * mandatory: an optional one booted after the start would get its own). */
static void test_start_all_with_one_command(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC);
    plan_t p = {.startup = CO_MANAGER_STARTUP_MANAGER | CO_MANAGER_STARTUP_START_ALL,
                .assignment = {0, 0x0D, 0x0D, 0}};
    co_manager_t *m = fx_manager(fx, &p, 0);
    station_t *s2 = fx_slave(fx, 2, 1, 0, true);
    station_t *s3 = fx_slave(fx, 3, 1, 0, true);
    tu_run_until(&fx->tb, 10 * TU_MS);
    tu_log_clear(&fx->tb);
    start(fx, m);
    tu_run_until(&fx->tb, 200 * TU_MS);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x000), 3);   /* 2 resets + 1 start */
    tu_assert_logged(&fx->tb, find_frame(&fx->tb, 0x000, (const uint8_t[]){0x01}, 1, 0), 0x000,
                     (const uint8_t[]){0x01, 0x00}, 2);
    assert_int_equal(find_frame(&fx->tb, 0x000, NMT_START_2, 2, 0), -1);
    assert_int_equal(find_frame(&fx->tb, 0x000, NMT_START_3, 2, 0), -1);
    assert_int_equal(state_of(s2), CO_NMT_OPERATIONAL);
    assert_int_equal(state_of(s3), CO_NMT_OPERATIONAL);
    assert_int_equal(state_of(&fx->manager), CO_NMT_OPERATIONAL);
    fx_free(fx);
}

/* 0x1F80 bits 2 and 3: the manager neither enters operational nor starts
 * the slaves itself. */
static void test_application_starts(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC);
    plan_t p = {.startup = CO_MANAGER_STARTUP_MANAGER | CO_MANAGER_STARTUP_APP_OPERATIONAL |
                           CO_MANAGER_STARTUP_APP_STARTS_SLAVES,
                .assignment = {0, 0x0D, 0, 0}};
    co_manager_t *m = fx_manager(fx, &p, 0);
    station_t *s2 = fx_slave(fx, 2, 1, 0, true);
    tu_run_until(&fx->tb, 10 * TU_MS);
    tu_log_clear(&fx->tb);
    start(fx, m);
    tu_run_until(&fx->tb, 200 * TU_MS);
    assert_int_equal(co_manager_phase(m), CO_MANAGER_RUNNING);
    assert_int_equal(find_frame(&fx->tb, 0x000, (const uint8_t[]){0x01}, 1, 0), -1);
    assert_int_equal(state_of(&fx->manager), CO_NMT_PRE_OPERATIONAL);
    assert_int_equal(state_of(s2), CO_NMT_PRE_OPERATIONAL);
    fx_free(fx);
}

/* A mandatory slave that never answers: B, asked again every second until
 * 0x1F89 = 3 s passed, then the start is halted and said so. */
static void test_missing_mandatory_slave_halts_after_boot_time(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC);
    plan_t p = {.startup = CO_MANAGER_STARTUP_MANAGER, .assignment = {0, 0x0D, 0x05, 0},
                .boot_time_ms = 3000};
    co_manager_t *m = fx_manager(fx, &p, 0);
    station_t *s3 = fx_slave(fx, 3, 1, 0, true);   /* node 2 is not there */
    tu_run_until(&fx->tb, 10 * TU_MS);
    tu_log_clear(&fx->tb);
    start(fx, m);
    tu_run_until(&fx->tb, 2500 * TU_MS);
    assert_int_equal(co_manager_phase(m), CO_MANAGER_BOOTING);
    assert_int_equal(co_manager_slave_status(m, 2), CO_MANAGER_SLAVE_WAITING);
    assert_int_equal(co_manager_slave_error(m, 2), CO_BOOT_ERR_B);
    tu_run_until(&fx->tb, 6000 * TU_MS);
    assert_int_equal(co_manager_phase(m), CO_MANAGER_HALTED);
    long halted = find_event(fx, CO_MANAGER_EV_HALTED, 2, 0);
    assert_true(halted >= 0);
    assert_int_equal(fx->events[halted].error, CO_BOOT_ERR_B);
    assert_true(fx->events[halted].mandatory);
    /* each attempt: the first read plus its 3 repeats, 100 ms apart (each
     * timeout aborted with 0x05040000 on the bus); an attempt every second
     * after the last one ended, until 3 s passed: 0, 1.4, 2.8 s */
    const uint8_t read_1000[] = {0x40, 0x00, 0x10, 0x00};
    size_t reads = 0;
    while (find_frame(&fx->tb, 0x602, read_1000, 4, reads) >= 0) {
        reads++;
    }
    assert_int_equal(reads % (1 + CO_BOOT_UPLOAD_RETRIES), 0);
    assert_int_equal(reads, 3 * (1 + CO_BOOT_UPLOAD_RETRIES));
    tu_assert_logged(&fx->tb, find_frame(&fx->tb, 0x602, (const uint8_t[]){0x80}, 1, 0), 0x602,
                     (const uint8_t[]){0x80, 0x00, 0x10, 0x00, 0x00, 0x00, 0x04, 0x05}, 8);
    assert_int_equal(fx->tb.log[find_frame(&fx->tb, 0x602, read_1000, 4, 4)].t_us,
                     fx->tb.log[find_frame(&fx->tb, 0x602, read_1000, 4, 0)].t_us + 1400 * TU_MS);
    size_t before = tu_log_count_id(&fx->tb, 0x602);
    tu_run_until(&fx->tb, 9000 * TU_MS);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x602), before);   /* given up */
    /* the optional slave was booted and started on its own */
    assert_int_equal(co_manager_slave_status(m, 3), CO_MANAGER_SLAVE_BOOTED);
    assert_int_equal(state_of(s3), CO_NMT_OPERATIONAL);
    assert_int_equal(state_of(&fx->manager), CO_NMT_PRE_OPERATIONAL);
    assert_int_equal(count_event(fx, CO_MANAGER_EV_NETWORK_STARTED, 0xFF), 0);
    fx_free(fx);
}

/* An optional slave that powers on after the network started: booted at
 * its boot-up message and started then. */
static void test_optional_slave_appearing_later(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC);
    plan_t p = {.startup = CO_MANAGER_STARTUP_MANAGER, .assignment = {0, 0x0D, 0x05, 0}};
    co_manager_t *m = fx_manager(fx, &p, 0);
    station_t *s2 = fx_slave(fx, 2, 1, 0, true);
    station_t *s3 = fx_slave(fx, 3, 1, 0, false);   /* powered off */
    tu_run_until(&fx->tb, 10 * TU_MS);
    start(fx, m);
    tu_run_until(&fx->tb, 600 * TU_MS);
    assert_int_equal(co_manager_phase(m), CO_MANAGER_RUNNING);
    assert_int_equal(state_of(s2), CO_NMT_OPERATIONAL);
    assert_int_equal(co_manager_slave_status(m, 3), CO_MANAGER_SLAVE_WAITING);
    tu_log_clear(&fx->tb);
    co_line_set_time(&s3->tl.line, fx->tb.now);
    assert_int_equal(co_stack_boot(&s3->stack), CO_STACK_OK);   /* powers on */
    tu_run_until(&fx->tb, 700 * TU_MS);   /* well before the next 1 s retry */
    assert_int_equal(co_manager_slave_status(m, 3), CO_MANAGER_SLAVE_BOOTED);
    assert_int_equal(state_of(s3), CO_NMT_OPERATIONAL);
    long bootup = find_frame(&fx->tb, 0x703, (const uint8_t[]){0x00}, 1, 0);
    long read = find_frame(&fx->tb, 0x603, (const uint8_t[]){0x40, 0x00, 0x10, 0x00}, 4, 0);
    long start3 = find_frame(&fx->tb, 0x000, NMT_START_3, 2, 0);
    assert_true(bootup >= 0 && read > bootup && start3 > read);
    assert_int_equal(count_event(fx, CO_MANAGER_EV_SLAVE_STARTED, 3), 1);
    fx_free(fx);
}

/* Keep-alive (0x1F81 bit 4) with a slave that is operational already and
 * sends heartbeats the manager consumes: no reset, ends with L, the network
 * starts with it, and it gets no NMT start (it runs). */
static void test_keep_alive_operational_slave_ends_l(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC);
    plan_t p = {.startup = CO_MANAGER_STARTUP_MANAGER, .assignment = {0, 0x1D, 0, 0},
                .heartbeat = {(2u << 16) | 300u, 0}};
    co_manager_t *m = fx_manager(fx, &p, 0);
    station_t *s2 = fx_slave(fx, 2, 1, 100, true);
    tu_run_until(&fx->tb, 10 * TU_MS);
    co_nmt_apply(&co_stack_node(&s2->stack)->nmt, CO_NMT_CMD_START);
    tu_run_until(&fx->tb, 250 * TU_MS);
    tu_log_clear(&fx->tb);
    start(fx, m);
    tu_run_until(&fx->tb, 800 * TU_MS);
    assert_int_equal(co_manager_slave_error(m, 2), CO_BOOT_ERR_L);
    assert_int_equal(co_manager_slave_status(m, 2), CO_MANAGER_SLAVE_BOOTED);
    assert_int_equal(co_manager_phase(m), CO_MANAGER_RUNNING);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x000), 0);   /* no reset, no start */
    assert_int_equal(state_of(s2), CO_NMT_OPERATIONAL);
    fx_free(fx);
}

/* The hooks: configuration asked (failed: J, a mandatory slave halts the
 * start), then done; "ready for operational" waits for its continue call. */
static void test_hooks_and_continue_calls(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC);
    plan_t p = {.startup = CO_MANAGER_STARTUP_MANAGER, .assignment = {0, 0x0D, 0, 0}};
    co_manager_t *m = fx_manager(fx, &p, CO_MANAGER_HOOK_CONFIG | CO_MANAGER_HOOK_OPERATIONAL);
    fx_slave(fx, 2, 1, 0, true);
    tu_run_until(&fx->tb, 10 * TU_MS);
    fx->answer_config = true;
    fx->config_ok = false;
    start(fx, m);
    tu_run_until(&fx->tb, 200 * TU_MS);
    assert_int_equal(co_manager_slave_error(m, 2), CO_BOOT_ERR_J);
    assert_int_equal(co_manager_phase(m), CO_MANAGER_HALTED);
    assert_true(find_event(fx, CO_MANAGER_EV_UPDATE_CONFIG, 2, 0) >= 0);
    /* again; the configuration is answered later this time */
    fx->answer_config = false;
    fx->event_count = 0;
    start(fx, m);
    tu_run_until(&fx->tb, 400 * TU_MS);
    assert_true(find_event(fx, CO_MANAGER_EV_UPDATE_CONFIG, 2, 0) >= 0);
    assert_int_equal(co_manager_slave_status(m, 2), CO_MANAGER_SLAVE_BOOTING);
    assert_false(co_manager_continue_config(m, 3, true));   /* not in the list */
    assert_false(co_manager_continue_operational(m));       /* not asked yet */
    assert_true(co_manager_continue_config(m, 2, true));
    assert_int_equal(co_manager_slave_status(m, 2), CO_MANAGER_SLAVE_BOOTED);
    assert_int_equal(co_manager_phase(m), CO_MANAGER_READY);
    assert_true(find_event(fx, CO_MANAGER_EV_READY_OPERATIONAL, 0xFF, 0) >= 0);
    tu_run_until(&fx->tb, 600 * TU_MS);
    assert_int_equal(state_of(&fx->manager), CO_NMT_PRE_OPERATIONAL);   /* still waits */
    assert_true(co_manager_continue_operational(m));
    assert_int_equal(co_manager_phase(m), CO_MANAGER_RUNNING);
    assert_int_equal(state_of(&fx->manager), CO_NMT_OPERATIONAL);
    tu_run_until(&fx->tb, 700 * TU_MS);
    assert_int_equal(state_of(&fx->slaves[0]), CO_NMT_OPERATIONAL);
    fx_free(fx);
}

/* A wrong device type halts the start with C; the process's CHECKED report
 * names what was expected and what came. */
static void test_device_type_mismatch_reported(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC);
    plan_t p = {.startup = CO_MANAGER_STARTUP_MANAGER, .assignment = {0, 0x0D, 0, 0},
                .device_type = {0, DEVICE_TYPE + 1, 0, 0}};
    co_manager_t *m = fx_manager(fx, &p, 0);
    fx_slave(fx, 2, 1, 0, true);
    tu_run_until(&fx->tb, 10 * TU_MS);
    start(fx, m);
    tu_run_until(&fx->tb, 200 * TU_MS);
    assert_int_equal(co_manager_phase(m), CO_MANAGER_HALTED);
    assert_int_equal(co_manager_slave_error(m, 2), CO_BOOT_ERR_C);
    bool seen = false;
    for (unsigned i = 0; i < fx->event_count; i++) {
        const co_manager_report_t *r = &fx->events[i];
        if (r->event == CO_MANAGER_EV_BOOT && r->boot.event == CO_BOOT_EV_CHECKED &&
            r->boot.index == 0x1000) {
            assert_false(r->boot.matched);
            assert_int_equal(r->boot.expected, DEVICE_TYPE + 1);
            assert_int_equal(r->boot.got, DEVICE_TYPE);
            seen = true;
        }
    }
    assert_true(seen);
    fx_free(fx);
}

/* A booted slave's heartbeat stops: the manager resets that node alone and
 * boots it again; it comes back operational. */
static void test_heartbeat_lost_reboots_the_slave(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC);
    plan_t p = {.startup = CO_MANAGER_STARTUP_MANAGER, .assignment = {0, 0x0D, 0, 0},
                .heartbeat = {(2u << 16) | 300u, 0}};
    co_manager_t *m = fx_manager(fx, &p, 0);
    station_t *s2 = fx_slave(fx, 2, 1, 100, true);
    tu_run_until(&fx->tb, 10 * TU_MS);
    start(fx, m);
    tu_run_until(&fx->tb, 500 * TU_MS);
    assert_int_equal(co_manager_phase(m), CO_MANAGER_RUNNING);
    assert_int_equal(co_manager_slave_error(m, 2), CO_BOOT_OK);
    assert_int_equal(state_of(s2), CO_NMT_OPERATIONAL);
    /* the slave falls silent (its heartbeat stops) for a while */
    co_line_set_time(&s2->tl.line, fx->tb.now);
    co_node_set_heartbeat(co_stack_node(&s2->stack), 0);
    tu_log_clear(&fx->tb);
    tu_run_until(&fx->tb, 1000 * TU_MS);
    long lost = find_event(fx, CO_MANAGER_EV_ERROR_CONTROL, 2, 0);
    assert_true(lost >= 0);
    assert_int_equal(fx->events[lost].command, CO_NMT_CMD_RESET_NODE);
    long reset = find_frame(&fx->tb, 0x000, (const uint8_t[]){0x81, 2}, 2, 0);
    tu_assert_logged(&fx->tb, reset, 0x000, (const uint8_t[]){0x81, 2}, 2);
    /* reset node reloads 0x1017 = 100 ms: heartbeats again, booted, started */
    tu_run_until(&fx->tb, 1500 * TU_MS);
    assert_int_equal(co_manager_slave_status(m, 2), CO_MANAGER_SLAVE_BOOTED);
    assert_int_equal(count_event(fx, CO_MANAGER_EV_SLAVE_BOOTED, 2), 2);
    assert_true(find_frame(&fx->tb, 0x000, NMT_START_2, 2, 0) > reset);
    assert_int_equal(state_of(s2), CO_NMT_OPERATIONAL);
    fx_free(fx);
}

/* 0x1F80 bit 6 with a mandatory slave: its loss stops every node. */
static void test_heartbeat_lost_stop_all(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC);
    plan_t p = {.startup = CO_MANAGER_STARTUP_MANAGER | CO_MANAGER_STARTUP_STOP_ALL |
                           CO_MANAGER_STARTUP_RESET_ALL,
                .assignment = {0, 0x0D, 0x05, 0},
                .heartbeat = {(2u << 16) | 300u, 0}};
    co_manager_t *m = fx_manager(fx, &p, 0);
    station_t *s2 = fx_slave(fx, 2, 1, 100, true);
    station_t *s3 = fx_slave(fx, 3, 1, 0, true);
    tu_run_until(&fx->tb, 10 * TU_MS);
    start(fx, m);
    tu_run_until(&fx->tb, 500 * TU_MS);
    assert_int_equal(state_of(s3), CO_NMT_OPERATIONAL);
    co_line_set_time(&s2->tl.line, fx->tb.now);
    co_node_set_heartbeat(co_stack_node(&s2->stack), 0);
    tu_log_clear(&fx->tb);
    tu_run_until(&fx->tb, 1000 * TU_MS);
    tu_assert_logged(&fx->tb, find_frame(&fx->tb, 0x000, (const uint8_t[]){0x02}, 1, 0), 0x000,
                     (const uint8_t[]){0x02, 0x00}, 2);
    assert_int_equal(state_of(s3), CO_NMT_STOPPED);
    assert_int_equal(state_of(&fx->manager), CO_NMT_STOPPED);
    fx_free(fx);
}

/* An fd line: the same boot through the USDO client. */
static void test_fd_network_boots_over_usdo(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_FD);
    plan_t p = {.startup = CO_MANAGER_STARTUP_MANAGER, .assignment = {0, 0x0D, 0, 0},
                .device_type = {0, DEVICE_TYPE, 0, 0}, .vendor = {0, VENDOR, 0, 0},
                .heartbeat = {(2u << 16) | 300u, 0}};
    co_manager_t *m = fx_manager(fx, &p, 0);
    station_t *s2 = fx_slave(fx, 2, 1, 100, true);
    tu_run_until(&fx->tb, 10 * TU_MS);
    tu_log_clear(&fx->tb);
    start(fx, m);
    tu_run_until(&fx->tb, 500 * TU_MS);
    assert_int_equal(co_manager_slave_error(m, 2), CO_BOOT_OK);
    assert_int_equal(state_of(s2), CO_NMT_OPERATIONAL);
    /* USDO requests to node 2 went out on 0x600 + our client id, addressed
     * to node 2 in byte 0 (CiA 1301 layout, see test_usdo_client.c) */
    assert_true(tu_log_count_id(&fx->tb, 0x600 + MANAGER) >= 2);
    assert_int_equal(fx->tb.log[tu_log_find_id(&fx->tb, 0x600 + MANAGER, 0)].frame.data[0], 2);
    tu_assert_logged(&fx->tb, find_frame(&fx->tb, 0x000, NMT_START_2, 2, 0), 0x000, NMT_START_2,
                     2);
    fx_free(fx);
}

/* 0x1F80 bit 4 with a mandatory slave: its loss resets every node (the
 * manager too) and the start-up runs again. */
static void test_heartbeat_lost_reset_all(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC);
    plan_t p = {.startup = CO_MANAGER_STARTUP_MANAGER | CO_MANAGER_STARTUP_RESET_ALL,
                .assignment = {0, 0x0D, 0, 0},
                .heartbeat = {(2u << 16) | 300u, 0}};
    co_manager_t *m = fx_manager(fx, &p, 0);
    station_t *s2 = fx_slave(fx, 2, 1, 100, true);
    tu_run_until(&fx->tb, 10 * TU_MS);
    start(fx, m);
    tu_run_until(&fx->tb, 500 * TU_MS);
    assert_int_equal(count_event(fx, CO_MANAGER_EV_NETWORK_STARTED, 0xFF), 1);
    co_line_set_time(&s2->tl.line, fx->tb.now);
    co_node_set_heartbeat(co_stack_node(&s2->stack), 0);
    tu_log_clear(&fx->tb);
    tu_run_until(&fx->tb, 2000 * TU_MS);
    long reset = find_frame(&fx->tb, 0x000, (const uint8_t[]){0x81}, 1, 0);
    tu_assert_logged(&fx->tb, reset, 0x000, (const uint8_t[]){0x81, 0x00}, 2);
    /* the manager reset itself (its boot-up) and booted the network again */
    assert_true(find_frame(&fx->tb, 0x700 + MANAGER, (const uint8_t[]){0x00}, 1, 0) > reset);
    assert_true(find_frame(&fx->tb, 0x000, NMT_RESET_COMM_2, 2, 0) > reset);
    assert_int_equal(count_event(fx, CO_MANAGER_EV_NETWORK_STARTED, 0xFF), 2);
    assert_int_equal(state_of(&fx->manager), CO_NMT_OPERATIONAL);
    assert_int_equal(state_of(s2), CO_NMT_OPERATIONAL);
    fx_free(fx);
}

/* An optional slave that fails (here: software check asked, 0x1F55 not
 * set: G) is reported, not started, and does not halt the start. */
static void test_optional_failure_does_not_halt(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC);
    plan_t p = {.startup = CO_MANAGER_STARTUP_MANAGER, .assignment = {0, 0x0D, 0x25, 0}};
    co_manager_t *m = fx_manager(fx, &p, 0);
    fx_slave(fx, 2, 1, 0, true);
    station_t *s3 = fx_slave(fx, 3, 1, 0, true);
    tu_run_until(&fx->tb, 10 * TU_MS);
    start(fx, m);
    tu_run_until(&fx->tb, 300 * TU_MS);
    /* 0x1F81:3 asks for the software check (bit 5) without 0x1F55: G */
    assert_int_equal(co_manager_slave_status(m, 3), CO_MANAGER_SLAVE_FAILED);
    assert_int_equal(co_manager_slave_error(m, 3), CO_BOOT_ERR_G);
    long failed = find_event(fx, CO_MANAGER_EV_SLAVE_FAILED, 3, 0);
    assert_true(failed >= 0);
    assert_false(fx->events[failed].mandatory);
    assert_int_equal(count_event(fx, CO_MANAGER_EV_HALTED, 0xFF), 0);
    assert_int_equal(co_manager_phase(m), CO_MANAGER_RUNNING);
    assert_int_equal(state_of(s3), CO_NMT_PRE_OPERATIONAL);   /* never started */
    fx_free(fx);
}

/* co_stack_manager_need says what co_stack_manager_init takes. */
static void test_manager_memory_need(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC);
    plan_t p = {.startup = CO_MANAGER_STARTUP_MANAGER, .assignment = {0, 0x0D, 0x05, 0x05}};
    station_t *st = &fx->manager;
    tu_bus_add_line(&fx->tb, &st->tl);
    manager_od(&st->od, CO_MODE_CLASSIC, &p);
    station_stack(st, 0);
    co_stack_node_config_t nc = {.node_id = MANAGER, .od = &st->od.od};
    assert_int_equal(co_stack_node_init(&st->stack, &nc), CO_STACK_OK);
    co_stack_client_config_t cc = {.sessions = 2};
    assert_int_equal(co_stack_client_init(&st->stack, &cc), CO_STACK_OK);
    assert_int_equal(co_manager_slaves_in(&st->od.od, MANAGER), 3);
    size_t need = co_stack_manager_need(&st->stack, NULL);
    assert_int_equal(need, CO_STACK_BLOCK(3 * sizeof(co_manager_slave_t)));
    size_t before = st->arena.used;
    co_stack_manager_config_t mc = {0};
    assert_int_equal(co_stack_manager_init(&st->stack, &mc), CO_STACK_OK);
    assert_int_equal(st->arena.used - before, need);
    co_stack_manager_deinit(&st->stack);
    assert_int_equal(st->arena.used, before);   /* given back */
    fx_free(fx);
}

static void test_wrong_use_is_refused(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC);
    plan_t p = {.startup = 0, .assignment = {0, 0x0D, 0, 0}};
    station_t *st = &fx->manager;
    tu_bus_add_line(&fx->tb, &st->tl);
    manager_od(&st->od, CO_MODE_CLASSIC, &p);
    station_stack(st, 0);
    co_stack_manager_config_t mc = {.on_event = on_event, .user = fx};
    /* no node yet */
    assert_int_equal(co_stack_manager_init(&st->stack, &mc), CO_STACK_ERR_STATE);
    assert_int_equal(co_stack_failed_part(&st->stack), CO_STACK_PART_MANAGER);
    co_stack_node_config_t nc = {.node_id = MANAGER, .od = &st->od.od};
    assert_int_equal(co_stack_node_init(&st->stack, &nc), CO_STACK_OK);
    /* no client */
    assert_int_equal(co_stack_manager_init(&st->stack, &mc), CO_STACK_ERR_STATE);
    co_stack_client_config_t cc = {.sessions = 2};
    assert_int_equal(co_stack_client_init(&st->stack, &cc), CO_STACK_OK);
    /* 0x1F80 bit 0 clear: not a manager */
    assert_int_equal(co_stack_manager_init(&st->stack, &mc), CO_STACK_ERR_OD);
    assert_null(co_stack_manager(&st->stack));
    /* set, fine; a second one is refused; a start reads 0x1F80 again */
    uint8_t one[4] = {1, 0, 0, 0};
    assert_int_equal(co_od_put(&st->od.od, 0x1F80, 0, one, 4), 0);
    assert_int_equal(co_stack_manager_init(&st->stack, &mc), CO_STACK_OK);
    assert_int_equal(co_stack_manager_init(&st->stack, &mc), CO_STACK_ERR_STATE);
    co_manager_t *m = co_stack_manager(&st->stack);
    uint8_t zero[4] = {0};
    assert_int_equal(co_od_put(&st->od.od, 0x1F80, 0, zero, 4), 0);
    assert_int_equal(co_manager_start(m), CO_MANAGER_NOT_MANAGER);
    assert_int_equal(co_od_put(&st->od.od, 0x1F80, 0, one, 4), 0);
    /* more slaves than the table holds */
    uint8_t slave[4] = {0x05, 0, 0, 0};
    assert_int_equal(co_od_put(&st->od.od, 0x1F81, 3, slave, 4), 0);
    assert_int_equal(co_manager_start(m), CO_MANAGER_NO_ROOM);
    /* stray input is ignored */
    co_frame_t rtr = {.id = 0x702, .len = 1, .flags = CO_FRAME_RTR};
    co_manager_ec_frame(m, &rtr);
    co_manager_ec_lost(m, 0);
    co_manager_ec_lost(m, 200);
    assert_false(co_manager_continue_software(m, 2, true));
    /* the node going takes the manager along */
    co_stack_node_deinit(&st->stack);
    assert_null(co_stack_manager(&st->stack));
    fx_free(fx);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_classic_network_boots_with_exact_frames),
        cmocka_unit_test(test_start_all_with_one_command),
        cmocka_unit_test(test_application_starts),
        cmocka_unit_test(test_missing_mandatory_slave_halts_after_boot_time),
        cmocka_unit_test(test_optional_slave_appearing_later),
        cmocka_unit_test(test_keep_alive_operational_slave_ends_l),
        cmocka_unit_test(test_hooks_and_continue_calls),
        cmocka_unit_test(test_device_type_mismatch_reported),
        cmocka_unit_test(test_heartbeat_lost_reboots_the_slave),
        cmocka_unit_test(test_heartbeat_lost_stop_all),
        cmocka_unit_test(test_heartbeat_lost_reset_all),
        cmocka_unit_test(test_optional_failure_does_not_halt),
        cmocka_unit_test(test_manager_memory_need),
        cmocka_unit_test(test_fd_network_boots_over_usdo),
        cmocka_unit_test(test_wrong_use_is_refused),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
