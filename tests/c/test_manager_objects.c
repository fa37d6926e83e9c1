/* The manager's CiA 302 request objects, written by a tool over the bus
 * (raw SDO frames on a classic line, the USDO client on an fd line), and
 * the flying master deciding which manager runs. Checked on the wire:
 *   0x1F82 request NMT with the wrong length: the SDO abort 0x06070012;
 *   0x1F83 request node guarding: the remote frames start and stop, the
 *          entry reads whether the node is guarded, wrong nodes / values /
 *          no guard time refused with their codes, fd lines refuse it;
 *   0x1F25 configuration request: the SDO downloads of the 0x1F22 concise
 *          DCF and the 0x1020 stamp that follow "conf", one node after the
 *          other for 0x80; a wrong signature, an unknown node, a node still
 *          being configured refused with their codes;
 *   flying master + manager: only the winner boots the slaves (each NMT
 *          command once), the loser stays passive; when the winner dies the
 *          other one becomes master and boots the slaves again. */
#include "test_od_util.h"

#include "canopenfd/co_manager.h"
#include "canopenfd/co_stack.h"

#include <stdlib.h>

enum { MAX_EVENTS = 256, SUBS = CO_STACK_OD_SUBSCRIPTIONS + 8 };

#define DATE 15000u
#define TIME 43200000u

typedef struct od_store {
    co_od_t od;
    co_od_entry_t entries[160];
    uint8_t pool[2048];
    co_od_subscription_t subs[SUBS];
} od_store_t;

typedef struct station {
    tu_line_t tl;
    od_store_t od;
    co_stack_t stack;
    co_stack_arena_t arena;
    unsigned char memory[96 * 1024];
    co_manager_report_t events[MAX_EVENTS];
    unsigned event_count;
    struct fx *fx;
} station_t;

typedef struct fx {
    tu_bus_t tb;
    co_mode_t mode;
    station_t st[5];       /* managers first, then slaves */
    unsigned count;
    tu_line_t tool;        /* raw frames (classic) */
    /* 0x1F22 concise DCFs the managers serve, per node-id (DOMAIN data) */
    uint8_t dcf[128][32];
    uint32_t dcf_len[128];
    bool dcf_stall;        /* the reader gives nothing and does not end */
} fx_t;

static void od_add(od_store_t *d, uint16_t index, uint8_t sub, uint8_t object_code, uint8_t type,
                   uint8_t access, int64_t value)
{
    tu_od_row_t row = {index, sub, object_code, type, access, 0,
                       co_od_type_size(type), value, NULL, 0, 0};
    tu_od_add_rows(&d->od, &row, 1);
}

static void od_begin(od_store_t *d, co_mode_t mode)
{
    memset(d, 0, sizeof *d);
    co_od_init(&d->od, mode, d->entries, 160, d->pool, sizeof d->pool, d->subs, SUBS);
    od_add(d, 0x1000, 0, VAR, U32, RO, 0);
    od_add(d, 0x1001, 0, VAR, U8, RO, 0);
}

/* An array 1..5 (and 0x80 when `all`), sub n from values[n]. */
static void od_nodes(od_store_t *d, uint16_t index, uint8_t type, uint8_t access,
                     const uint32_t *values, bool all)
{
    od_add(d, index, 0, ARR, U8, RO, all ? 0x80 : 5);
    for (uint8_t n = 1; n <= 5; n++) {
        od_add(d, index, n, ARR, type, access, values ? values[n] : 0);
    }
    if (all) {
        od_add(d, index, 0x80, ARR, type, access, 0);
    }
}

/* 0x1F22:n reads the DCF the fixture keeps for node n. */
static uint32_t dcf_size(co_od_t *od, const co_od_entry_t *e, uint32_t *size, void *user)
{
    (void)od;
    *size = ((fx_t *)user)->dcf_len[co_od_entry_sub(e)];
    return 0;
}

static uint32_t dcf_read(co_od_t *od, const co_od_entry_t *e, uint32_t offset, uint8_t *buf,
                         uint32_t cap, uint32_t *n, bool *last, void *user)
{
    (void)od;
    fx_t *fx = user;
    uint8_t sub = co_od_entry_sub(e);
    uint32_t left = fx->dcf_len[sub] - offset;
    if (fx->dcf_stall) {
        *n = 0;
        *last = false;
        return 0;
    }
    *n = left < cap ? left : cap;
    memcpy(buf, fx->dcf[sub] + offset, *n);
    *last = offset + *n == fx->dcf_len[sub];
    return 0;
}

static const co_od_handler_t dcf_handler = {.domain_size = dcf_size, .domain_read = dcf_read};

/* A manager's OD: 0x1F80 = startup, 0x1F81 = assignment[n], the request
 * objects, 0x1F22 (DOMAIN), 0x1F26/0x1F27 for nodes 2 and 3, heartbeat
 * producer 50 ms and a consumer entry per node of `watch`. */
static void manager_od(fx_t *fx, od_store_t *d, uint8_t node_id, uint32_t startup,
                       const uint32_t *assignment, const uint32_t *watch)
{
    static const uint32_t dates[6] = {0, 0, DATE, DATE, 0, 0};
    static const uint32_t times[6] = {0, 0, TIME, TIME, 0, 0};
    od_begin(d, fx->mode);
    od_nodes(d, 0x1016, U32, RW, watch, false);
    od_add(d, 0x1017, 0, VAR, U16, RW, 50);
    od_add(d, 0x1F22, 0, ARR, U8, RO, 5);
    for (uint8_t n = 1; n <= 5; n++) {
        od_add(d, 0x1F22, n, ARR, CO_TYPE_DOMAIN, RW, 0);
    }
    od_nodes(d, 0x1F25, U32, RW, NULL, true);
    od_nodes(d, 0x1F26, U32, RW, dates, false);
    od_nodes(d, 0x1F27, U32, RW, times, false);
    od_add(d, 0x1F80, 0, VAR, U32, RW, startup);
    od_nodes(d, 0x1F81, U32, RW, assignment, false);
    od_nodes(d, 0x1F82, U8, RW, NULL, true);
    od_nodes(d, 0x1F83, U8, RW, NULL, true);
    assert_true(co_od_seal(&d->od, node_id));
    assert_true(co_od_subscribe(&d->od, 0x1F22, 1, 0x1F22, 5, &dcf_handler, fx));
}

static void slave_od(fx_t *fx, od_store_t *d, uint8_t node_id, uint16_t heartbeat_ms)
{
    od_begin(d, fx->mode);
    od_add(d, 0x1017, 0, VAR, U16, RW, heartbeat_ms);
    od_add(d, 0x1020, 0, ARR, U8, RO, 2);
    od_add(d, 0x1020, 1, ARR, U32, RW, 1);
    od_add(d, 0x1020, 2, ARR, U32, RW, 1);
    assert_true(co_od_seal(&d->od, node_id));
}

static void on_event(co_manager_t *m, const co_manager_report_t *r, void *user)
{
    (void)m;
    station_t *st = user;
    assert_true(st->event_count < MAX_EVENTS);
    st->events[st->event_count++] = *r;
}

static fx_t *fx_new(co_mode_t mode)
{
    fx_t *fx = calloc(1, sizeof *fx);
    assert_non_null(fx);
    fx->mode = mode;
    tu_bus_init(&fx->tb, mode, mode == CO_MODE_FD);
    tu_bus_add_line(&fx->tb, &fx->tool);
    return fx;
}

static station_t *station(fx_t *fx, uint8_t node_id)
{
    station_t *st = &fx->st[fx->count++];
    st->fx = fx;
    tu_bus_add_line(&fx->tb, &st->tl);
    co_stack_arena_init(&st->arena, st->memory, sizeof st->memory);
    co_stack_line_config_t lc = {.heartbeat_entries = 8,
                                 .guarded_nodes = fx->mode == CO_MODE_CLASSIC ? 4 : 0};
    assert_int_equal(co_stack_init(&st->stack, &st->tl.line, &lc,
                                   co_stack_arena_allocator(&st->arena)), CO_STACK_OK);
    co_stack_node_config_t nc = {.node_id = node_id, .od = &st->od.od};
    assert_int_equal(co_stack_node_init(&st->stack, &nc), CO_STACK_OK);
    return st;
}

/* A manager (client, manager part; booted, not started). */
static station_t *fx_manager(fx_t *fx, uint8_t node_id, uint32_t startup,
                             const uint32_t *assignment, const uint32_t *watch)
{
    manager_od(fx, &fx->st[fx->count].od, node_id, startup, assignment, watch);
    station_t *st = station(fx, node_id);
    co_stack_client_config_t cc = {.sessions = 4, .node_id = node_id, .timeout_ms = 100};
    assert_int_equal(co_stack_client_init(&st->stack, &cc), CO_STACK_OK);
    co_stack_manager_config_t mc = {.on_event = on_event, .user = st};
    assert_int_equal(co_stack_manager_init(&st->stack, &mc), CO_STACK_OK);
    return st;
}

static station_t *fx_slave(fx_t *fx, uint8_t node_id, uint16_t heartbeat_ms)
{
    slave_od(fx, &fx->st[fx->count].od, node_id, heartbeat_ms);
    station_t *st = station(fx, node_id);
    assert_int_equal(co_stack_boot(&st->stack), CO_STACK_OK);
    return st;
}

static void fx_free(fx_t *fx)
{
    for (unsigned i = 0; i < fx->count; i++) {
        if (fx->st[i].stack.line) {
            co_stack_deinit(&fx->st[i].stack);
        }
    }
    free(fx);
}

static co_manager_t *manager_of(station_t *st)
{
    return co_stack_manager(&st->stack);
}

static void sync_clocks(fx_t *fx)
{
    for (uint8_t i = 0; i < fx->tb.count; i++) {
        co_line_set_time(&fx->tb.lines[i]->line, fx->tb.now);
    }
}

/* The tool's raw SDO request to node 1 (classic), queued; sent at the next step. */
static void tool_sdo(fx_t *fx, uint8_t node, const uint8_t *data8)
{
    co_frame_t f = tu_frame(0x600u + node, 0, data8, 8);
    assert_true(co_line_send_frame(&fx->tool.line, &f));
}

/* Expedited download of n (1..4) bytes of value to index:sub of node. */
static void tool_write(fx_t *fx, uint8_t node, uint16_t index, uint8_t sub, uint32_t value,
                       uint8_t n)
{
    uint8_t d[8] = {(uint8_t)(0x23 | ((4 - n) << 2)), (uint8_t)index, (uint8_t)(index >> 8), sub};
    tu_le_put(&d[4], value, 4);
    tool_sdo(fx, node, d);
}

static void tool_read(fx_t *fx, uint8_t node, uint16_t index, uint8_t sub)
{
    uint8_t d[8] = {0x40, (uint8_t)index, (uint8_t)(index >> 8), sub, 0, 0, 0, 0};
    tool_sdo(fx, node, d);
}

/* The last answer of node on 0x580 + node (after a step). */
static const co_frame_t *last_answer(const fx_t *fx, uint8_t node)
{
    long i = -1;
    for (size_t k = 0; k < fx->tb.log_count; k++) {
        if (fx->tb.log[k].frame.id == 0x580u + node) {
            i = (long)k;
        }
    }
    assert_true(i >= 0);
    return &fx->tb.log[i].frame;
}

static void assert_abort(const co_frame_t *f, uint16_t index, uint8_t sub, uint32_t code)
{
    uint8_t want[8] = {0x80, (uint8_t)index, (uint8_t)(index >> 8), sub};
    tu_le_put(&want[4], code, 4);
    assert_int_equal(f->len, 8);
    assert_memory_equal(f->data, want, 8);
}

static void assert_write_ok(const co_frame_t *f, uint16_t index, uint8_t sub)
{
    const uint8_t want[8] = {0x60, (uint8_t)index, (uint8_t)(index >> 8), sub, 0, 0, 0, 0};
    assert_memory_equal(f->data, want, 8);
}

/* Index of the k-th logged frame with this id and these leading bytes, -1. */
static long find_frame(const tu_bus_t *tb, uint32_t id, const uint8_t *head, uint8_t n, size_t k)
{
    for (size_t i = 0; i < tb->log_count; i++) {
        const co_frame_t *f = &tb->log[i].frame;
        if (f->id == id && !(f->flags & CO_FRAME_RTR) && f->len >= n &&
            (n == 0 || memcmp(f->data, head, n) == 0) && k-- == 0) {
            return (long)i;
        }
    }
    return -1;
}

static size_t count_frames(const tu_bus_t *tb, uint32_t id, const uint8_t *head, uint8_t n)
{
    size_t k = 0;
    while (find_frame(tb, id, head, n, k) >= 0) {
        k++;
    }
    return k;
}

static size_t count_rtr(const tu_bus_t *tb, uint32_t id)
{
    size_t k = 0;
    for (size_t i = 0; i < tb->log_count; i++) {
        k += tb->log[i].frame.id == id && (tb->log[i].frame.flags & CO_FRAME_RTR);
    }
    return k;
}

static unsigned count_event(const station_t *st, co_manager_event_t event, uint8_t node)
{
    unsigned n = 0;
    for (unsigned i = 0; i < st->event_count; i++) {
        n += st->events[i].event == event && (node == 0xFF || st->events[i].node_id == node);
    }
    return n;
}

static const co_manager_report_t *last_event(const station_t *st, co_manager_event_t event)
{
    for (unsigned i = st->event_count; i-- > 0;) {
        if (st->events[i].event == event) {
            return &st->events[i];
        }
    }
    fail_msg("no manager event %d", (int)event);
    return NULL;
}

/* ------------------------------------------------------------ 0x1F82 */

static void test_request_nmt_wrong_length_aborts(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC);
    const uint32_t assign[6] = {0, 0, 0x05, 0x05};
    station_t *m = fx_manager(fx, 1, CO_MANAGER_STARTUP_MANAGER, assign, NULL);
    assert_int_equal(co_stack_boot(&m->stack), CO_STACK_OK);
    tu_run_until(&fx->tb, 10 * TU_MS);
    tu_log_clear(&fx->tb);
    tool_write(fx, 1, 0x1F82, 3, 0x0004, 2);   /* U8 entry, 2 bytes */
    tu_step(&fx->tb, fx->tb.now);
    assert_abort(last_answer(fx, 1), 0x1F82, 3, CO_ABORT_LENGTH_HIGH);
    assert_int_equal(count_frames(&fx->tb, 0x000, NULL, 0), 0);   /* no NMT */
    tool_write(fx, 1, 0x1F82, 3, 0x04, 1);                        /* right length */
    tu_step(&fx->tb, fx->tb.now);
    assert_write_ok(last_answer(fx, 1), 0x1F82, 3);
    tu_assert_logged(&fx->tb, find_frame(&fx->tb, 0x000, NULL, 0, 0), 0x000,
                     (const uint8_t[]){0x02, 3}, 2);
    fx_free(fx);
}

/* 0x1F82:n mirrors the slave's state, but the OD hears of it only when it
 * changes: its after_write handlers see two changes, not every heartbeat. */
static unsigned mirror_writes;

static void count_mirror(co_od_t *od, const co_od_entry_t *e, co_od_origin_t origin, void *user)
{
    (void)od;
    (void)user;
    if (origin == CO_ORIGIN_LOCAL && co_od_entry_sub(e) == 2) {
        mirror_writes++;
    }
}

static const co_od_handler_t mirror_counter = {.after_write = count_mirror};

static void test_request_nmt_mirror_written_on_change(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC);
    const uint32_t assign[6] = {0, 0, 0x05};
    station_t *m = fx_manager(fx, 1, CO_MANAGER_STARTUP_MANAGER, assign, NULL);
    mirror_writes = 0;
    assert_true(co_od_subscribe(&m->od.od, 0x1F82, 1, 0x1F82, 5, &mirror_counter, NULL));
    assert_int_equal(co_stack_boot(&m->stack), CO_STACK_OK);
    station_t *s2 = fx_slave(fx, 2, 20);   /* a heartbeat every 20 ms */
    tu_run_until(&fx->tb, 10 * TU_MS);
    sync_clocks(fx);
    assert_int_equal(co_manager_start(manager_of(m)), CO_MANAGER_OK);
    tu_run_until(&fx->tb, 1000 * TU_MS);
    assert_int_equal(co_node_state(co_stack_node(&s2->stack)), CO_NMT_OPERATIONAL);
    assert_true(tu_log_count_id(&fx->tb, 0x702) > 40);   /* the heartbeats heard */
    uint8_t shown = 0;
    assert_true(co_od_get_u8(&m->od.od, 0x1F82, 2, &shown));
    assert_int_equal(shown, CO_NMT_OPERATIONAL);
    assert_int_equal(mirror_writes, 2);   /* pre-operational (127), then operational (5) */
    fx_free(fx);
}

/* co_stack_manager_need counts the 0x1F25 DCF buffer when the OD has 0x1F25,
 * of the size the config asks for. */
static void test_memory_need_counts_the_dcf_buffer(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC);
    const uint32_t assign[6] = {0, 0, 0x05, 0x05};
    manager_od(fx, &fx->st[0].od, 1, CO_MANAGER_STARTUP_MANAGER, assign, NULL);
    station_t *st = station(fx, 1);
    co_stack_client_config_t cc = {.sessions = 2, .node_id = 1};
    assert_int_equal(co_stack_client_init(&st->stack, &cc), CO_STACK_OK);
    size_t need = co_stack_manager_need(&st->stack, NULL);
    assert_int_equal(need, CO_STACK_BLOCK(2 * sizeof(co_manager_slave_t)) +
                               CO_STACK_BLOCK(CO_MANAGER_DCF_BUFFER));
    size_t before = st->arena.used;
    co_stack_manager_config_t mc = {0};
    assert_int_equal(co_stack_manager_init(&st->stack, &mc), CO_STACK_OK);
    assert_int_equal(st->arena.used - before, need);
    co_stack_manager_deinit(&st->stack);
    assert_int_equal(st->arena.used, before);
    /* a DCF room of the caller's size: the need follows it, larger and smaller */
    const uint32_t rooms[2] = {CO_MANAGER_DCF_BUFFER * 4u, 40u};
    for (int i = 0; i < 2; i++) {
        co_stack_manager_config_t sized = {.dcf_capacity = rooms[i]};
        need = co_stack_manager_need(&st->stack, &sized);
        assert_int_equal(need, CO_STACK_BLOCK(2 * sizeof(co_manager_slave_t)) +
                                   CO_STACK_BLOCK(rooms[i]));
        assert_int_equal(co_stack_manager_init(&st->stack, &sized), CO_STACK_OK);
        assert_int_equal(st->arena.used - before, need);
        co_stack_manager_deinit(&st->stack);
        assert_int_equal(st->arena.used, before);
    }
    fx_free(fx);
}

/* ------------------------------------------------------------ 0x1F83 */

static void test_request_guarding_starts_and_stops_remote_frames(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC);
    /* node 2: guard time 100 ms, factor 3; node 3 in the list without one */
    const uint32_t assign[6] = {0, 0, (100u << 16) | (3u << 8) | 0x05u, 0x05};
    station_t *m = fx_manager(fx, 1, CO_MANAGER_STARTUP_MANAGER, assign, NULL);
    assert_int_equal(co_stack_boot(&m->stack), CO_STACK_OK);
    (void)fx_slave(fx, 2, 0);
    tu_run_until(&fx->tb, 10 * TU_MS);
    tool_read(fx, 1, 0x1F83, 2);
    tu_step(&fx->tb, fx->tb.now);
    assert_memory_equal(last_answer(fx, 1)->data, ((const uint8_t[]){0x4F, 0x83, 0x1F, 2, 0}), 5);
    tu_log_clear(&fx->tb);
    tool_write(fx, 1, 0x1F83, 2, 1, 1);
    tu_step(&fx->tb, fx->tb.now);
    assert_write_ok(last_answer(fx, 1), 0x1F83, 2);
    tu_run_until(&fx->tb, fx->tb.now + 450 * TU_MS);
    /* a remote frame at once, then every 100 ms; the slave answers each */
    assert_int_equal(count_rtr(&fx->tb, 0x702), 5);
    assert_int_equal(count_frames(&fx->tb, 0x702, NULL, 0), 5);
    tool_read(fx, 1, 0x1F83, 2);
    tu_step(&fx->tb, fx->tb.now);
    assert_memory_equal(last_answer(fx, 1)->data, ((const uint8_t[]){0x4F, 0x83, 0x1F, 2, 1}), 5);
    tool_write(fx, 1, 0x1F83, 2, 0, 1);
    tu_step(&fx->tb, fx->tb.now);
    tu_log_clear(&fx->tb);
    tu_run_until(&fx->tb, fx->tb.now + 500 * TU_MS);
    assert_int_equal(count_rtr(&fx->tb, 0x702), 0);
    tool_read(fx, 1, 0x1F83, 2);
    tu_step(&fx->tb, fx->tb.now);
    assert_memory_equal(last_answer(fx, 1)->data, ((const uint8_t[]){0x4F, 0x83, 0x1F, 2, 0}), 5);
    /* refused: not in the list, no such value, no guard time */
    tool_write(fx, 1, 0x1F83, 4, 1, 1);
    tu_step(&fx->tb, fx->tb.now);
    assert_abort(last_answer(fx, 1), 0x1F83, 4, CO_ABORT_INVALID_VALUE);
    tool_write(fx, 1, 0x1F83, 2, 2, 1);
    tu_step(&fx->tb, fx->tb.now);
    assert_abort(last_answer(fx, 1), 0x1F83, 2, CO_ABORT_INVALID_VALUE);
    tool_write(fx, 1, 0x1F83, 3, 1, 1);
    tu_step(&fx->tb, fx->tb.now);
    assert_abort(last_answer(fx, 1), 0x1F83, 3, CO_ABORT_DATA_STATE);
    /* 0x80: every slave with a guard time */
    tu_log_clear(&fx->tb);
    tool_write(fx, 1, 0x1F83, 0x80, 1, 1);
    tu_step(&fx->tb, fx->tb.now);
    assert_write_ok(last_answer(fx, 1), 0x1F83, 0x80);
    assert_int_equal(count_rtr(&fx->tb, 0x702), 1);
    assert_int_equal(count_rtr(&fx->tb, 0x703), 0);
    fx_free(fx);
}

static void usdo_done(co_usdo_request_t *r)
{
    *(uint8_t *)r->user = r->abort ? r->abort : 0xFF;
}

/* On an fd line node guarding does not exist: the write is refused. */
static void test_request_guarding_refused_on_fd(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_FD);
    const uint32_t assign[6] = {0, 0, (100u << 16) | (3u << 8) | 0x05u};
    station_t *m = fx_manager(fx, 1, CO_MANAGER_STARTUP_MANAGER, assign, NULL);
    assert_int_equal(co_stack_boot(&m->stack), CO_STACK_OK);
    /* the tool: node 9's USDO client */
    slave_od(fx, &fx->st[fx->count].od, 9, 0);
    station_t *tool = station(fx, 9);
    co_stack_client_config_t cc = {.sessions = 1, .node_id = 9, .timeout_ms = 100};
    assert_int_equal(co_stack_client_init(&tool->stack, &cc), CO_STACK_OK);
    assert_int_equal(co_stack_boot(&tool->stack), CO_STACK_OK);
    tu_run_until(&fx->tb, 10 * TU_MS);
    sync_clocks(fx);
    uint8_t one = 1;
    uint8_t result = 0;
    co_buffer_t src = {.data = &one, .size = 1, .capacity = 1};
    co_usdo_request_t req = {.server = 1, .index = 0x1F83, .sub = 2, .upload = false,
                             .type = CO_TYPE_UNSIGNED8, .size = 1,
                             .source = co_usdo_buffer_source, .ctx = &src, .done = usdo_done,
                             .user = &result};
    assert_int_equal(co_usdo_client_start(co_stack_usdo_client(&tool->stack), &req), 0);
    tu_run_until(&fx->tb, fx->tb.now + 50 * TU_MS);
    assert_int_equal(co_usdo_abort_to_co(result), CO_ABORT_UNSUPPORTED_ACCESS);
    assert_int_equal(count_rtr(&fx->tb, 0x702), 0);
    fx_free(fx);
}

/* ------------------------------------------------------------ 0x1F25 */

static void test_config_request_downloads_the_concise_dcf(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC);
    const uint32_t assign[6] = {0, 0, 0x05, 0x05};
    station_t *m = fx_manager(fx, 1, CO_MANAGER_STARTUP_MANAGER, assign, NULL);
    assert_int_equal(co_stack_boot(&m->stack), CO_STACK_OK);
    station_t *s2 = fx_slave(fx, 2, 0);
    station_t *s3 = fx_slave(fx, 3, 0);
    /* concise DCFs: node 2 heartbeat 200 ms, node 3 heartbeat 300 ms */
    const uint8_t dcf2[] = {1, 0, 0, 0, 0x17, 0x10, 0x00, 2, 0, 0, 0, 0xC8, 0x00};
    const uint8_t dcf3[] = {1, 0, 0, 0, 0x17, 0x10, 0x00, 2, 0, 0, 0, 0x2C, 0x01};
    memcpy(fx->dcf[2], dcf2, sizeof dcf2);
    fx->dcf_len[2] = sizeof dcf2;
    memcpy(fx->dcf[3], dcf3, sizeof dcf3);
    fx->dcf_len[3] = sizeof dcf3;
    tu_run_until(&fx->tb, 10 * TU_MS);
    tu_log_clear(&fx->tb);
    tool_write(fx, 1, 0x1F25, 2, CO_MANAGER_CONFIG_SIGNATURE, 4);
    tu_step(&fx->tb, fx->tb.now);
    assert_write_ok(last_answer(fx, 1), 0x1F25, 2);
    /* the downloads that follow: the entry, then the stamp (not compared first) */
    uint8_t stamp_date[8] = {0x23, 0x20, 0x10, 1};
    uint8_t stamp_time[8] = {0x23, 0x20, 0x10, 2};
    tu_le_put(&stamp_date[4], DATE, 4);
    tu_le_put(&stamp_time[4], TIME, 4);
    long entry = find_frame(&fx->tb, 0x602, NULL, 0, 0);
    tu_assert_logged(&fx->tb, entry, 0x602,
                     (const uint8_t[]){0x2B, 0x17, 0x10, 0x00, 0xC8, 0x00, 0, 0}, 8);
    tu_assert_logged(&fx->tb, find_frame(&fx->tb, 0x602, NULL, 0, 1), 0x602, stamp_date, 8);
    tu_assert_logged(&fx->tb, find_frame(&fx->tb, 0x602, NULL, 0, 2), 0x602, stamp_time, 8);
    assert_int_equal(count_frames(&fx->tb, 0x602, NULL, 0), 3);
    uint16_t hb = 0;
    assert_true(co_od_get_u16(&s2->od.od, 0x1017, 0, &hb));
    assert_int_equal(hb, 200);
    const co_manager_report_t *done = last_event(m, CO_MANAGER_EV_CONFIGURED);
    assert_int_equal(done->node_id, 2);
    assert_int_equal(done->error, CO_BOOT_OK);

    /* refused: wrong signature, not in the list, no 0x1F22 entry (node 5 has
     * one but is not a slave); a node still being configured */
    tool_write(fx, 1, 0x1F25, 2, 0x65766173, 4);   /* "save" */
    tu_step(&fx->tb, fx->tb.now);
    assert_abort(last_answer(fx, 1), 0x1F25, 2, CO_ABORT_DATA_STORE);
    tool_write(fx, 1, 0x1F25, 5, CO_MANAGER_CONFIG_SIGNATURE, 4);
    tu_step(&fx->tb, fx->tb.now);
    assert_abort(last_answer(fx, 1), 0x1F25, 5, CO_ABORT_INVALID_VALUE);
    tool_write(fx, 1, 0x1F25, 2, CO_MANAGER_CONFIG_SIGNATURE, 4);
    tool_write(fx, 1, 0x1F25, 2, CO_MANAGER_CONFIG_SIGNATURE, 4);   /* same round */
    tu_step(&fx->tb, fx->tb.now);
    assert_abort(last_answer(fx, 1), 0x1F25, 2, CO_ABORT_DATA_STATE);
    assert_int_equal(count_event(m, CO_MANAGER_EV_CONFIGURED, 2), 2);

    /* 0x80: every slave with a DCF, one after the other */
    tu_log_clear(&fx->tb);
    tool_write(fx, 1, 0x1F25, 0x80, CO_MANAGER_CONFIG_SIGNATURE, 4);
    tu_step(&fx->tb, fx->tb.now);
    assert_write_ok(last_answer(fx, 1), 0x1F25, 0x80);
    long last2 = find_frame(&fx->tb, 0x602, NULL, 0, 2);
    long first3 = find_frame(&fx->tb, 0x603, NULL, 0, 0);
    assert_true(last2 >= 0 && first3 > last2);
    tu_assert_logged(&fx->tb, first3, 0x603,
                     (const uint8_t[]){0x2B, 0x17, 0x10, 0x00, 0x2C, 0x01, 0, 0}, 8);
    assert_true(co_od_get_u16(&s3->od.od, 0x1017, 0, &hb));
    assert_int_equal(hb, 300);
    uint32_t date = 0;
    assert_true(co_od_get_u32(&s3->od.od, 0x1020, 1, &date));
    assert_int_equal(date, DATE);
    assert_int_equal(count_event(m, CO_MANAGER_EV_CONFIGURED, 3), 1);
    assert_int_equal(last_event(m, CO_MANAGER_EV_CONFIGURED)->error, CO_BOOT_OK);
    fx_free(fx);
}

/* A slave that refuses an entry: the request ends with J and the entry. */
static void test_config_request_refused_entry_reports_j(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC);
    const uint32_t assign[6] = {0, 0, 0x05};
    station_t *m = fx_manager(fx, 1, CO_MANAGER_STARTUP_MANAGER, assign, NULL);
    assert_int_equal(co_stack_boot(&m->stack), CO_STACK_OK);
    (void)fx_slave(fx, 2, 0);
    const uint8_t dcf2[] = {1, 0, 0, 0, 0x00, 0x30, 0x01, 1, 0, 0, 0, 0x01};   /* 0x3000:01 */
    memcpy(fx->dcf[2], dcf2, sizeof dcf2);
    fx->dcf_len[2] = sizeof dcf2;
    tu_run_until(&fx->tb, 10 * TU_MS);
    tu_log_clear(&fx->tb);
    tool_write(fx, 1, 0x1F25, 2, CO_MANAGER_CONFIG_SIGNATURE, 4);
    tu_step(&fx->tb, fx->tb.now);
    const co_manager_report_t *done = last_event(m, CO_MANAGER_EV_CONFIGURED);
    assert_int_equal(done->error, CO_BOOT_ERR_J);
    assert_int_equal(done->boot.index, 0x3000);
    assert_int_equal(done->boot.sub, 1);
    assert_int_equal(done->boot.abort, CO_ABORT_NO_OBJECT);
    assert_int_equal(count_frames(&fx->tb, 0x602, NULL, 0), 1);   /* no stamp */
    fx_free(fx);
}

/* A 0x1F22 reader that gives no byte and does not end (an application
 * bug, a stalled source): the manager must not loop on it forever; the
 * request ends with J naming 0x1F22:n, nothing is sent to the slave, and
 * the next request works again. */
static void test_config_request_stalled_dcf_reader(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC);
    const uint32_t assign[6] = {0, 0, 0x05};
    station_t *m = fx_manager(fx, 1, CO_MANAGER_STARTUP_MANAGER, assign, NULL);
    assert_int_equal(co_stack_boot(&m->stack), CO_STACK_OK);
    (void)fx_slave(fx, 2, 0);
    const uint8_t dcf2[] = {1, 0, 0, 0, 0x17, 0x10, 0x00, 2, 0, 0, 0, 0xC8, 0x00};
    memcpy(fx->dcf[2], dcf2, sizeof dcf2);
    fx->dcf_len[2] = sizeof dcf2;
    fx->dcf_stall = true;
    tu_run_until(&fx->tb, 10 * TU_MS);
    tu_log_clear(&fx->tb);
    tool_write(fx, 1, 0x1F25, 2, CO_MANAGER_CONFIG_SIGNATURE, 4);
    tu_step(&fx->tb, fx->tb.now);
    assert_write_ok(last_answer(fx, 1), 0x1F25, 2);
    const co_manager_report_t *done = last_event(m, CO_MANAGER_EV_CONFIGURED);
    assert_non_null(done);
    assert_int_equal(done->error, CO_BOOT_ERR_J);
    assert_int_equal(done->boot.index, 0x1F22);
    assert_int_equal(done->boot.sub, 2);
    assert_int_equal(done->boot.abort, CO_ABORT_GENERAL);
    assert_int_equal(count_frames(&fx->tb, 0x602, NULL, 0), 0);
    fx->dcf_stall = false;
    tool_write(fx, 1, 0x1F25, 2, CO_MANAGER_CONFIG_SIGNATURE, 4);
    tu_step(&fx->tb, fx->tb.now);
    assert_int_equal(last_event(m, CO_MANAGER_EV_CONFIGURED)->error, CO_BOOT_OK);
    fx_free(fx);
}

/* ------------------------------------------------------------ flying master */

static void flyma_start(station_t *st, uint8_t priority)
{
    co_stack_flyma_config_t fc = {.flyma = {.priority = priority, .detect_ms = 50,
                                            .delay_ms = 100, .priority_slot_ms = 300,
                                            .device_slot_ms = 5, .multiple_master_ms = 2000,
                                            .capable_ms = 100},
                                  .master_heartbeat_ms = 200};
    assert_int_equal(co_stack_flyma_init(&st->stack, &fc), CO_STACK_OK);
}

static void test_flying_master_runs_only_the_winners_manager(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC);
    const uint32_t assign[6] = {0, 0, 0x05};
    /* candidates 10 (priority 0) and 11 (priority 1), heartbeats 50 ms */
    station_t *a = fx_manager(fx, 10, CO_MANAGER_STARTUP_MANAGER, assign, NULL);
    station_t *b = fx_manager(fx, 11, CO_MANAGER_STARTUP_MANAGER, assign, NULL);
    station_t *s2 = fx_slave(fx, 2, 50);
    sync_clocks(fx);
    flyma_start(a, 0);
    flyma_start(b, 1);
    /* the application starts both managers: each waits for the decision */
    assert_int_equal(co_manager_start(manager_of(a)), CO_MANAGER_OK);
    assert_int_equal(co_manager_start(manager_of(b)), CO_MANAGER_OK);
    assert_true(co_manager_passive(manager_of(a)) && co_manager_passive(manager_of(b)));
    assert_int_equal(co_stack_boot(&a->stack), CO_STACK_OK);
    assert_int_equal(co_stack_boot(&b->stack), CO_STACK_OK);
    tu_run_until(&fx->tb, 3000 * TU_MS);
    assert_int_equal(co_flyma_state(co_stack_flyma(&a->stack)), CO_FLYMA_MASTER);
    assert_int_equal(co_flyma_state(co_stack_flyma(&b->stack)), CO_FLYMA_SLAVE);
    assert_int_equal(co_manager_phase(manager_of(a)), CO_MANAGER_RUNNING);
    assert_int_equal(count_event(a, CO_MANAGER_EV_ACTIVE, 0xFF), 1);
    assert_int_equal(co_manager_phase(manager_of(b)), CO_MANAGER_IDLE);
    assert_int_equal(count_event(b, CO_MANAGER_EV_ACTIVE, 0xFF), 0);
    assert_int_equal(count_event(b, CO_MANAGER_EV_BOOT, 0xFF), 0);
    /* on the wire: each slave reset and started once (a loser's manager
     * would have sent its own) */
    assert_int_equal(count_frames(&fx->tb, 0x000, (const uint8_t[]){0x82, 2}, 2), 1);
    assert_int_equal(count_frames(&fx->tb, 0x000, (const uint8_t[]){0x01, 2}, 2), 1);
    assert_int_equal(co_node_state(co_stack_node(&s2->stack)), CO_NMT_OPERATIONAL);
    /* 0x1F82 of the passive manager refuses: another node runs the network */
    tu_log_clear(&fx->tb);
    tool_write(fx, 11, 0x1F82, 2, 0x04, 1);
    tu_step(&fx->tb, fx->tb.now);
    assert_abort(last_answer(fx, 11), 0x1F82, 2, CO_ABORT_DATA_LOCAL);
    assert_int_equal(count_frames(&fx->tb, 0x000, NULL, 0), 0);

    /* the winner dies: b loses its heartbeat, resets the network, wins and
     * boots the slaves again */
    co_stack_deinit(&a->stack);
    tu_log_clear(&fx->tb);
    tu_run_until(&fx->tb, fx->tb.now + 4000 * TU_MS);
    assert_int_equal(co_flyma_state(co_stack_flyma(&b->stack)), CO_FLYMA_MASTER);
    assert_int_equal(count_event(b, CO_MANAGER_EV_ACTIVE, 0xFF), 1);
    assert_int_equal(co_manager_phase(manager_of(b)), CO_MANAGER_RUNNING);
    assert_true(find_frame(&fx->tb, 0x000, (const uint8_t[]){0x82, 0}, 2, 0) >= 0);
    assert_int_equal(count_frames(&fx->tb, 0x000, (const uint8_t[]){0x01, 2}, 2), 1);
    assert_int_equal(co_manager_slave_status(manager_of(b), 2), CO_MANAGER_SLAVE_BOOTED);
    assert_int_equal(co_node_state(co_stack_node(&s2->stack)), CO_NMT_OPERATIONAL);
    fx_free(fx);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_request_nmt_wrong_length_aborts),
        cmocka_unit_test(test_request_nmt_mirror_written_on_change),
        cmocka_unit_test(test_memory_need_counts_the_dcf_buffer),
        cmocka_unit_test(test_request_guarding_starts_and_stops_remote_frames),
        cmocka_unit_test(test_request_guarding_refused_on_fd),
        cmocka_unit_test(test_config_request_downloads_the_concise_dcf),
        cmocka_unit_test(test_config_request_refused_entry_reports_j),
        cmocka_unit_test(test_config_request_stalled_dcf_reader),
        cmocka_unit_test(test_flying_master_runs_only_the_winners_manager),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
