/* Configuration manager (CiA 302-3) over the membus, against our own
 * stack's SDO server (classic) and USDO server (fd): the frames on the bus,
 * the skip when 0x1020 matches, an entry the device lacks (0x06020000), a
 * read-only entry (0x06010002), a silent node (timeout), 200 entries, two
 * nodes at once, a malformed DCF refused before anything is sent, cancel. */
#include "test_od_util.h"

#include "canopenfd/co_concise_dcf.h"
#include "canopenfd/co_config.h"
#include "canopenfd/co_stack.h"

#include <stdio.h>
#include <stdlib.h>

enum { NODE = 5, NODE2 = 6, SILENT = 20, CLIENT = 9, BIG = 200, MAX_IND = 512 };
#define DATE 0x11223344u
#define TIME 0x55667788u

static const tu_od_row_t device_rows[] = {
    {0x1000, 0, VAR, U32, RO, 0, 4, 0x00000191, NULL, 0, 0},
    {0x1001, 0, VAR, U8, RO, 0, 1, 0, NULL, 0, 0},
    {0x1017, 0, VAR, U16, RW, 0, 2, 0, NULL, 0, 0},
    {0x1018, 0, REC, U8, RO, 0, 1, 1, NULL, 0, 0},
    {0x1018, 1, REC, U32, RO, 0, 4, 0x12345678, NULL, 0, 0},
    {0x1020, 0, ARR, U8, RO, 0, 1, 2, NULL, 0, 0},
    {0x1020, 1, ARR, U32, RW, 0, 4, 0, NULL, 0, 0},
    {0x1020, 2, ARR, U32, RW, 0, 4, 0, NULL, 0, 0},
    {0x2000, 0, VAR, U16, RW, 0, 2, 0, NULL, 0, 0},
    {0x2001, 0, VAR, U32, RO, 0, 4, 7, NULL, 0, 0},
    {0x2100, 0, ARR, U8, RO, 0, 1, BIG, NULL, 0, 0},
};
#define N_ROWS (sizeof device_rows / sizeof device_rows[0])

typedef struct device {
    tu_line_t line;
    co_od_t od;
    co_od_entry_t entries[N_ROWS + BIG];
    uint8_t pool[2048];
    co_od_subscription_t subs[CO_STACK_OD_SUBSCRIPTIONS];
    co_stack_t stack;
    co_stack_arena_t arena;
    unsigned char memory[64 * 1024];
} device_t;

typedef struct indication {
    uint16_t index;
    uint8_t sub;
    uint32_t abort;
} indication_t;

typedef struct fx {
    tu_bus_t tb;
    co_mode_t mode;
    device_t dev[2];
    tu_line_t tool_line;
    co_stack_t tool;
    co_stack_arena_t tool_arena;
    unsigned char tool_memory[48 * 1024];
    co_config_t cfg[2];
    co_config_result_t result[2];
    unsigned done[2];
    indication_t ind[MAX_IND];
    unsigned ind_count;
    bool cancel_in_entry;
    uint8_t dcf[8192];
    uint32_t dcf_len;
} fx_t;

static void device_init(fx_t *fx, device_t *d, uint8_t node_id)
{
    uint8_t sub;
    tu_bus_add_line(&fx->tb, &d->line);
    co_od_init(&d->od, fx->mode, d->entries, N_ROWS + BIG, d->pool, sizeof d->pool, d->subs,
               CO_STACK_OD_SUBSCRIPTIONS);
    tu_od_add_rows(&d->od, device_rows, N_ROWS);
    for (sub = 1; sub <= BIG; sub++) {
        tu_od_row_t row = {0x2100, sub, ARR, U8, RW, 0, 1, 0, NULL, 0, 0};
        tu_od_add_rows(&d->od, &row, 1);
    }
    assert_true(co_od_seal(&d->od, node_id));
    co_stack_arena_init(&d->arena, d->memory, sizeof d->memory);
    co_stack_line_config_t lc = {0};
    assert_int_equal(co_stack_init(&d->stack, &d->line.line, &lc,
                                   co_stack_arena_allocator(&d->arena)), CO_STACK_OK);
    co_stack_node_config_t nc = {.node_id = node_id, .od = &d->od};
    assert_int_equal(co_stack_node_init(&d->stack, &nc), CO_STACK_OK);
    assert_int_equal(co_stack_boot(&d->stack), CO_STACK_OK);
}

static fx_t *fx_new(co_mode_t mode, unsigned devices)
{
    unsigned i;
    fx_t *fx = calloc(1, sizeof *fx);
    assert_non_null(fx);
    fx->mode = mode;
    tu_bus_init(&fx->tb, mode, mode == CO_MODE_FD);
    for (i = 0; i < devices; i++)
        device_init(fx, &fx->dev[i], (uint8_t)(i == 0 ? NODE : NODE2));
    tu_bus_add_line(&fx->tb, &fx->tool_line);
    co_stack_arena_init(&fx->tool_arena, fx->tool_memory, sizeof fx->tool_memory);
    co_stack_line_config_t tc = {0};
    assert_int_equal(co_stack_init(&fx->tool, &fx->tool_line.line, &tc,
                                   co_stack_arena_allocator(&fx->tool_arena)), CO_STACK_OK);
    co_stack_client_config_t cc = {.sessions = 4, .node_id = CLIENT};
    assert_int_equal(co_stack_client_init(&fx->tool, &cc), CO_STACK_OK);
    for (i = 0; i < 2; i++) {
        if (mode == CO_MODE_FD)
            co_config_init_usdo(&fx->cfg[i], co_stack_usdo_client(&fx->tool));
        else
            co_config_init_sdo(&fx->cfg[i], co_stack_sdo_client(&fx->tool));
    }
    tu_run_until(&fx->tb, 10 * TU_MS);   /* boot-ups done */
    tu_log_clear(&fx->tb);
    return fx;
}

static void fx_free(fx_t *fx)
{
    unsigned i;
    co_stack_deinit(&fx->tool);
    for (i = 0; i < 2; i++)
        if (fx->dev[i].stack.line != NULL)
            co_stack_deinit(&fx->dev[i].stack);
    free(fx);
}

static void on_entry(co_config_t *cfg, uint16_t index, uint8_t sub, uint32_t abort, void *user)
{
    fx_t *fx = user;
    assert_true(fx->ind_count < MAX_IND);
    fx->ind[fx->ind_count++] = (indication_t){index, sub, abort};
    if (fx->cancel_in_entry)
        assert_true(co_config_cancel(cfg));
}

static void on_done(co_config_t *cfg, const co_config_result_t *r, void *user)
{
    fx_t *fx = user;
    unsigned k = cfg == &fx->cfg[0] ? 0 : 1;
    assert_false(co_config_running(cfg));
    fx->result[k] = *r;
    fx->done[k]++;
}

static co_config_request_t request(fx_t *fx, uint8_t node, bool stamp)
{
    co_config_request_t r = {.node = node, .dcf = fx->dcf, .dcf_length = fx->dcf_len,
                             .check_stamp = stamp, .date = DATE, .time = TIME,
                             .timeout_ms = 100, .entry = on_entry, .done = on_done,
                             .user = fx};
    return r;
}

/* Start configuration k and run the bus until it is done. */
static void run(fx_t *fx, unsigned k, const co_config_request_t *r)
{
    unsigned before = fx->done[k];
    co_line_set_time(&fx->tool_line.line, fx->tb.now);
    assert_int_equal(co_config_start(&fx->cfg[k], r), CO_CONFIG_START_OK);
    assert_true(co_config_running(&fx->cfg[k]));
    tu_step(&fx->tb, fx->tb.now);   /* carry the first request now */
    tu_run_until(&fx->tb, fx->tb.now + 2000 * TU_MS);
    assert_int_equal(fx->done[k], before + 1);
    if (getenv("TRACE")) {
        size_t i;
        for (i = 0; i < fx->tb.log_count; i++) {
            const co_frame_t *f = &fx->tb.log[i].frame;
            printf("%8llu %03x [%u]", (unsigned long long)fx->tb.log[i].t_us, (unsigned)f->id, f->len);
            for (uint8_t j = 0; j < f->len && j < 12; j++) printf(" %02x", f->data[j]);
            printf("\n");
        }
    }
}

static void dcf_build(fx_t *fx, void (*add)(co_concise_writer_t *w))
{
    co_concise_writer_t w;
    co_concise_writer_init(&w, fx->dcf, sizeof fx->dcf);
    add(&w);
    fx->dcf_len = co_concise_finish(&w);
    assert_true(fx->dcf_len >= 4);
}

static void two_good(co_concise_writer_t *w)
{
    assert_true(co_concise_add_u32(w, 0x1017, 0, 1000, 2));
    assert_true(co_concise_add_u32(w, 0x2000, 0, 0x1234, 2));
}

static void missing_in_middle(co_concise_writer_t *w)
{
    assert_true(co_concise_add_u32(w, 0x1017, 0, 1000, 2));
    assert_true(co_concise_add_u32(w, 0x3000, 7, 1, 1));      /* the device lacks it */
    assert_true(co_concise_add_u32(w, 0x2000, 0, 0x1234, 2));
}

static void read_only(co_concise_writer_t *w)
{
    assert_true(co_concise_add_u32(w, 0x2001, 0, 9, 4));
}

static void big(co_concise_writer_t *w)
{
    unsigned sub;
    for (sub = 1; sub <= BIG; sub++)
        assert_true(co_concise_add_u32(w, 0x2100, (uint8_t)sub, sub ^ 0x5A, 1));
}

static uint32_t dev_u32(fx_t *fx, unsigned d, uint16_t index, uint8_t sub)
{
    uint32_t v = 0;
    assert_true(co_od_get_u32(&fx->dev[d].od, index, sub, &v));
    return v;
}

static uint16_t dev_u16(fx_t *fx, unsigned d, uint16_t index, uint8_t sub)
{
    uint16_t v = 0;
    assert_true(co_od_get_u16(&fx->dev[d].od, index, sub, &v));
    return v;
}

/* Requests the tool sent to `node`, in order (classic: 0x600 + node;
 * fd: 0x600 + client id with byte 0 = node), aborts left out. */
static size_t requests(const fx_t *fx, uint8_t node, const co_frame_t **out, size_t max)
{
    size_t i, n = 0;
    for (i = 0; i < fx->tb.log_count; i++) {
        const co_frame_t *f = &fx->tb.log[i].frame;
        bool mine = fx->mode == CO_MODE_FD
                        ? f->id == 0x600u + CLIENT && f->data[0] == node && f->data[1] != 0x7F
                        : f->id == 0x600u + node && f->data[0] != 0x80;
        if (mine && n < max)
            out[n] = f;
        n += mine ? 1 : 0;
    }
    return n;
}

/* Log position of the k-th request to `node` (as counted by requests()). */
static long rq_position(const fx_t *fx, uint8_t node, size_t k)
{
    size_t i;
    for (i = 0; i < fx->tb.log_count; i++) {
        const co_frame_t *f = &fx->tb.log[i].frame;
        bool mine = fx->mode == CO_MODE_FD
                        ? f->id == 0x600u + CLIENT && f->data[0] == node && f->data[1] != 0x7F
                        : f->id == 0x600u + node && f->data[0] != 0x80;
        if (mine && k-- == 0)
            return (long)i;
    }
    fail_msg("no request %zu to node %u", k, node);
    return -1;
}

/* Check a request frame: classic SDO bytes, or the USDO frame's fields. */
static void assert_upload_request(const fx_t *fx, const co_frame_t *f, uint16_t index,
                                  uint8_t sub)
{
    if (fx->mode == CO_MODE_FD) {
        assert_int_equal(f->data[1], 0x11);   /* upload initiate */
        assert_int_equal(f->data[3], sub);
        assert_int_equal(f->data[4] | f->data[5] << 8, index);
    } else {
        uint8_t want[8] = {0x40, (uint8_t)index, (uint8_t)(index >> 8), sub, 0, 0, 0, 0};
        tu_assert_frame(f, 0x600 + NODE, 0, want, 8);
    }
}

static void assert_download(const fx_t *fx, const co_frame_t *f, uint8_t node, uint16_t index,
                            uint8_t sub, uint32_t value, uint8_t size)
{
    uint8_t v[4];
    tu_le_put(v, value, size);
    if (fx->mode == CO_MODE_FD) {
        assert_int_equal(f->data[0], node);
        assert_int_equal(f->data[1], 0x01);   /* expedited download */
        assert_int_equal(f->data[3], sub);
        assert_int_equal(f->data[4] | f->data[5] << 8, index);
        assert_int_equal(f->data[6], CO_TYPE_DOMAIN);   /* a concise DCF has no types */
        assert_int_equal(f->data[7], size);
        assert_memory_equal(f->data + 8, v, size);
    } else {
        uint8_t want[8] = {(uint8_t)(0x23 | (4 - size) << 2), (uint8_t)index,
                           (uint8_t)(index >> 8), sub, 0, 0, 0, 0};
        memcpy(want + 4, v, size);
        tu_assert_frame(f, 0x600u + node, 0, want, 8);
    }
}

/* ------------------------------------------------------------ tests */

/* 0x1020 differs: both stamps read, the entries written in DCF order, then
 * the stamp; every request's bytes checked; the device holds the values. */
static void configures_then_stamps(co_mode_t mode)
{
    fx_t *fx = fx_new(mode, 1);
    const co_frame_t *rq[16];
    dcf_build(fx, two_good);
    co_config_request_t r = request(fx, NODE, true);
    run(fx, 0, &r);
    assert_int_equal(fx->result[0].outcome, CO_CONFIG_RESULT_OK);
    assert_int_equal(fx->result[0].written, 2);
    assert_int_equal(fx->result[0].failed, 0);
    assert_int_equal(fx->result[0].abort, 0);
    assert_int_equal(dev_u16(fx, 0, 0x1017, 0), 1000);
    assert_int_equal(dev_u16(fx, 0, 0x2000, 0), 0x1234);
    assert_int_equal(dev_u32(fx, 0, 0x1020, 1), DATE);
    assert_int_equal(dev_u32(fx, 0, 0x1020, 2), TIME);
    /* 0x1020:01 read (0 differs from DATE: :02 is not read), two entries,
     * the two stamps */
    assert_int_equal(requests(fx, NODE, rq, 16), 5);
    assert_upload_request(fx, rq[0], 0x1020, 1);
    assert_download(fx, rq[1], NODE, 0x1017, 0, 1000, 2);
    assert_download(fx, rq[2], NODE, 0x2000, 0, 0x1234, 2);
    assert_download(fx, rq[3], NODE, 0x1020, 1, DATE, 4);
    assert_download(fx, rq[4], NODE, 0x1020, 2, TIME, 4);
    assert_int_equal(fx->ind_count, 4);
    assert_int_equal(fx->ind[0].index, 0x1017);
    assert_int_equal(fx->ind[1].index, 0x2000);
    assert_int_equal(fx->ind[2].index, 0x1020);
    assert_int_equal(fx->ind[2].sub, 1);
    assert_int_equal(fx->ind[3].sub, 2);

    /* again with the same stamp: both read, both equal, nothing written */
    tu_log_clear(&fx->tb);
    fx->ind_count = 0;
    co_od_put(&fx->dev[0].od, 0x2000, 0, (const uint8_t[]){0x99, 0x00}, 2);
    run(fx, 0, &r);
    assert_int_equal(fx->result[0].outcome, CO_CONFIG_RESULT_SKIPPED);
    assert_int_equal(fx->result[0].written, 0);
    assert_int_equal(requests(fx, NODE, rq, 16), 2);
    assert_upload_request(fx, rq[0], 0x1020, 1);
    assert_upload_request(fx, rq[1], 0x1020, 2);
    assert_int_equal(fx->ind_count, 0);
    assert_int_equal(dev_u16(fx, 0, 0x2000, 0), 0x0099);   /* untouched */

    /* the date matches, the time does not: configured again */
    tu_log_clear(&fx->tb);
    co_od_put(&fx->dev[0].od, 0x1020, 2, (const uint8_t[]){1, 0, 0, 0}, 4);
    run(fx, 0, &r);
    assert_int_equal(fx->result[0].outcome, CO_CONFIG_RESULT_OK);
    assert_int_equal(requests(fx, NODE, rq, 16), 6);
    assert_int_equal(dev_u16(fx, 0, 0x2000, 0), 0x1234);
    fx_free(fx);
}

static void test_classic_configures_then_skips(void **state)
{
    (void)state;
    configures_then_stamps(CO_MODE_CLASSIC);
}

static void test_fd_configures_then_skips(void **state)
{
    (void)state;
    configures_then_stamps(CO_MODE_FD);
}

/* Without a stamp: no 0x1020 traffic at all, only the entries. */
static void test_without_stamp_only_entries(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC, 1);
    const co_frame_t *rq[8];
    dcf_build(fx, two_good);
    co_config_request_t r = request(fx, NODE, false);
    run(fx, 0, &r);
    assert_int_equal(fx->result[0].outcome, CO_CONFIG_RESULT_OK);
    assert_int_equal(requests(fx, NODE, rq, 8), 2);
    assert_download(fx, rq[0], NODE, 0x1017, 0, 1000, 2);
    assert_download(fx, rq[1], NODE, 0x2000, 0, 0x1234, 2);
    assert_int_equal(dev_u32(fx, 0, 0x1020, 1), 0);
    fx_free(fx);
}

/* An entry the device lacks: 0x06020000 from the node, named with its
 * index:sub; by default the configuration stops there and no stamp is
 * written; with continue_on_error the rest is written, still no stamp. */
static void missing_entry(co_mode_t mode)
{
    fx_t *fx = fx_new(mode, 1);
    const co_frame_t *rq[8];
    dcf_build(fx, missing_in_middle);
    co_config_request_t r = request(fx, NODE, true);
    run(fx, 0, &r);
    const co_config_result_t *res = &fx->result[0];
    assert_int_equal(res->outcome, CO_CONFIG_RESULT_FAILED);
    assert_int_equal(res->index, 0x3000);
    assert_int_equal(res->sub, 7);
    assert_int_equal(res->abort, CO_ABORT_NO_OBJECT);
    assert_true(res->from_node);
    assert_int_equal(res->entry, 1);
    assert_int_equal(res->written, 1);
    assert_int_equal(res->failed, 1);
    assert_int_equal(fx->ind_count, 2);
    assert_int_equal(fx->ind[1].index, 0x3000);
    assert_int_equal(fx->ind[1].abort, CO_ABORT_NO_OBJECT);
    assert_int_equal(requests(fx, NODE, rq, 8), 3);   /* 0x1020:01, 0x1017, 0x3000 */
    assert_int_equal(dev_u16(fx, 0, 0x2000, 0), 0);
    assert_int_equal(dev_u32(fx, 0, 0x1020, 1), 0);

    tu_log_clear(&fx->tb);
    fx->ind_count = 0;
    r.continue_on_error = true;
    run(fx, 0, &r);
    assert_int_equal(res->outcome, CO_CONFIG_RESULT_FAILED);
    assert_int_equal(res->index, 0x3000);
    assert_int_equal(res->written, 2);
    assert_int_equal(res->failed, 1);
    assert_int_equal(fx->ind_count, 3);
    assert_int_equal(requests(fx, NODE, rq, 8), 4);   /* no stamp after a failure */
    assert_int_equal(dev_u16(fx, 0, 0x2000, 0), 0x1234);
    assert_int_equal(dev_u32(fx, 0, 0x1020, 1), 0);
    fx_free(fx);
}

static void test_classic_missing_entry(void **state)
{
    (void)state;
    missing_entry(CO_MODE_CLASSIC);
}

static void test_fd_missing_entry(void **state)
{
    (void)state;
    missing_entry(CO_MODE_FD);
}

static void read_only_entry(co_mode_t mode)
{
    fx_t *fx = fx_new(mode, 1);
    dcf_build(fx, read_only);
    co_config_request_t r = request(fx, NODE, false);
    run(fx, 0, &r);
    assert_int_equal(fx->result[0].outcome, CO_CONFIG_RESULT_FAILED);
    assert_int_equal(fx->result[0].index, 0x2001);
    assert_int_equal(fx->result[0].sub, 0);
    assert_int_equal(fx->result[0].abort, CO_ABORT_READ_ONLY);
    assert_true(fx->result[0].from_node);
    assert_int_equal(dev_u32(fx, 0, 0x2001, 0), 7);
    fx_free(fx);
}

static void test_classic_read_only_entry(void **state)
{
    (void)state;
    read_only_entry(CO_MODE_CLASSIC);
}

static void test_fd_read_only_entry(void **state)
{
    (void)state;
    read_only_entry(CO_MODE_FD);
}

/* Nobody answers: TIMEOUT after the per-frame timeout, on the stamp read
 * (with a stamp) or on the first entry (without), never a second request. */
static void silent_node(co_mode_t mode)
{
    fx_t *fx = fx_new(mode, 1);
    const co_frame_t *rq[8];
    dcf_build(fx, two_good);
    co_config_request_t r = request(fx, SILENT, true);
    uint64_t t0 = fx->tb.now;
    run(fx, 0, &r);
    assert_int_equal(fx->result[0].outcome, CO_CONFIG_RESULT_TIMEOUT);
    assert_int_equal(fx->result[0].abort, CO_ABORT_TIMEOUT);
    assert_false(fx->result[0].from_node);
    assert_int_equal(fx->result[0].index, 0x1020);
    assert_int_equal(fx->result[0].sub, 1);
    assert_int_equal(requests(fx, SILENT, rq, 8), 1);
    assert_true(fx->tb.now - t0 >= 100 * TU_MS);

    tu_log_clear(&fx->tb);
    r.check_stamp = false;
    r.continue_on_error = true;   /* a timeout stops even then */
    run(fx, 0, &r);
    assert_int_equal(fx->result[0].outcome, CO_CONFIG_RESULT_TIMEOUT);
    assert_int_equal(fx->result[0].index, 0x1017);
    assert_int_equal(requests(fx, SILENT, rq, 8), 1);
    assert_int_equal(fx->ind_count, 1);
    assert_int_equal(fx->ind[0].abort, CO_ABORT_TIMEOUT);
    fx_free(fx);
}

static void test_classic_silent_node(void **state)
{
    (void)state;
    silent_node(CO_MODE_CLASSIC);
}

static void test_fd_silent_node(void **state)
{
    (void)state;
    silent_node(CO_MODE_FD);
}

/* 200 entries, each its own download in DCF order; every value lands. */
static void many_entries(co_mode_t mode)
{
    fx_t *fx = fx_new(mode, 1);
    static const co_frame_t *rq[BIG + 8];
    unsigned sub;
    dcf_build(fx, big);
    co_config_request_t r = request(fx, NODE, true);
    run(fx, 0, &r);
    assert_int_equal(fx->result[0].outcome, CO_CONFIG_RESULT_OK);
    assert_int_equal(fx->result[0].written, BIG);
    assert_int_equal(requests(fx, NODE, rq, BIG + 8), 1 + BIG + 2);
    for (sub = 1; sub <= BIG; sub++) {
        uint8_t v = 0;
        assert_true(co_od_get_u8(&fx->dev[0].od, 0x2100, (uint8_t)sub, &v));
        assert_int_equal(v, (uint8_t)(sub ^ 0x5A));
        assert_download(fx, rq[sub], NODE, 0x2100, (uint8_t)sub, sub ^ 0x5A, 1);
    }
    assert_int_equal(fx->ind_count, BIG + 2);
    fx_free(fx);
}

static void test_classic_200_entries(void **state)
{
    (void)state;
    many_entries(CO_MODE_CLASSIC);
}

static void test_fd_200_entries(void **state)
{
    (void)state;
    many_entries(CO_MODE_FD);
}

/* Two nodes configured at once over one client (two channels / sessions). */
static void two_nodes(co_mode_t mode)
{
    fx_t *fx = fx_new(mode, 2);
    const co_frame_t *rq[8];
    dcf_build(fx, two_good);
    co_config_request_t r0 = request(fx, NODE, true);
    co_config_request_t r1 = request(fx, NODE2, true);
    co_line_set_time(&fx->tool_line.line, fx->tb.now);
    assert_int_equal(co_config_start(&fx->cfg[0], &r0), CO_CONFIG_START_OK);
    assert_int_equal(co_config_start(&fx->cfg[1], &r1), CO_CONFIG_START_OK);
    tu_step(&fx->tb, fx->tb.now);
    tu_run_until(&fx->tb, fx->tb.now + 500 * TU_MS);
    assert_int_equal(fx->done[0], 1);
    assert_int_equal(fx->done[1], 1);
    assert_int_equal(fx->result[0].outcome, CO_CONFIG_RESULT_OK);
    assert_int_equal(fx->result[1].outcome, CO_CONFIG_RESULT_OK);
    assert_int_equal(fx->result[1].node, NODE2);
    assert_int_equal(dev_u16(fx, 1, 0x2000, 0), 0x1234);
    assert_int_equal(dev_u32(fx, 1, 0x1020, 2), TIME);
    assert_int_equal(requests(fx, NODE, rq, 8), 5);
    assert_int_equal(requests(fx, NODE2, rq, 8), 5);
    /* the two ran at once: node 6's first request before node 5's last */
    assert_true(rq_position(fx, NODE2, 0) < rq_position(fx, NODE, 4));
    fx_free(fx);
}

static void test_classic_two_nodes_at_once(void **state)
{
    (void)state;
    two_nodes(CO_MODE_CLASSIC);
}

static void test_fd_two_nodes_at_once(void **state)
{
    (void)state;
    two_nodes(CO_MODE_FD);
}

/* Refusals at start: nothing on the bus, done() never called. */
static void test_start_refusals(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC, 1);
    dcf_build(fx, two_good);
    co_config_request_t r = request(fx, NODE, true);
    r.dcf_length = fx->dcf_len - 1;   /* the last data byte cut */
    assert_int_equal(co_config_start(&fx->cfg[0], &r), CO_CONFIG_START_BAD_DCF);
    assert_int_equal(fx->cfg[0].dcf_status, CO_CONCISE_SIZE_PAST_END);
    assert_int_equal(fx->cfg[0].dcf_offset, 16);
    r = request(fx, 0, true);
    assert_int_equal(co_config_start(&fx->cfg[0], &r), CO_CONFIG_START_ARGUMENT);
    r = request(fx, 128, true);
    assert_int_equal(co_config_start(&fx->cfg[0], &r), CO_CONFIG_START_ARGUMENT);
    r = request(fx, NODE, true);
    r.done = NULL;
    assert_int_equal(co_config_start(&fx->cfg[0], &r), CO_CONFIG_START_ARGUMENT);
    co_config_t unbound;
    memset(&unbound, 0, sizeof unbound);
    r = request(fx, NODE, true);
    assert_int_equal(co_config_start(&unbound, &r), CO_CONFIG_START_ARGUMENT);
    /* an empty DCF without a stamp: nothing to do */
    const uint8_t empty[4] = {0};
    r = request(fx, NODE, false);
    r.dcf = empty;
    r.dcf_length = 4;
    assert_int_equal(co_config_start(&fx->cfg[0], &r), CO_CONFIG_START_EMPTY);
    tu_run_until(&fx->tb, fx->tb.now + 50 * TU_MS);
    assert_int_equal(fx->tb.log_count, 0);
    assert_int_equal(fx->done[0], 0);
    /* an empty DCF with a stamp only stamps */
    r.check_stamp = true;
    run(fx, 0, &r);
    assert_int_equal(fx->result[0].outcome, CO_CONFIG_RESULT_OK);
    assert_int_equal(dev_u32(fx, 0, 0x1020, 1), DATE);
    /* busy while one runs */
    r = request(fx, NODE, false);
    co_line_set_time(&fx->tool_line.line, fx->tb.now);
    assert_int_equal(co_config_start(&fx->cfg[0], &r), CO_CONFIG_START_OK);
    assert_int_equal(co_config_start(&fx->cfg[0], &r), CO_CONFIG_START_BUSY);
    tu_run_until(&fx->tb, fx->tb.now + 50 * TU_MS);
    assert_int_equal(fx->result[0].outcome, CO_CONFIG_RESULT_OK);
    fx_free(fx);
}

/* Cancel: the open transfer is aborted on the bus, done() says CANCELLED;
 * a cancel from the entry indication ends it there too. */
static void test_cancel(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC, 1);
    dcf_build(fx, two_good);
    co_config_request_t r = request(fx, SILENT, false);
    co_line_set_time(&fx->tool_line.line, fx->tb.now);
    assert_int_equal(co_config_start(&fx->cfg[0], &r), CO_CONFIG_START_OK);
    tu_step(&fx->tb, fx->tb.now + TU_MS);
    assert_true(co_config_cancel(&fx->cfg[0]));
    assert_int_equal(fx->done[0], 1);
    assert_int_equal(fx->result[0].outcome, CO_CONFIG_RESULT_CANCELLED);
    assert_false(co_config_cancel(&fx->cfg[0]));
    tu_step(&fx->tb, fx->tb.now + TU_MS);
    long ab = tu_log_find_id(&fx->tb, 0x600 + SILENT, 1);
    assert_true(ab >= 0);
    assert_int_equal(fx->tb.log[ab].frame.data[0], 0x80);   /* SDO abort */
    assert_int_equal(tu_le_get(fx->tb.log[ab].frame.data + 4, 4), CO_ABORT_GENERAL);

    fx->cancel_in_entry = true;
    r = request(fx, NODE, false);
    run(fx, 0, &r);
    assert_int_equal(fx->result[0].outcome, CO_CONFIG_RESULT_CANCELLED);
    assert_int_equal(fx->ind_count, 1);
    assert_int_equal(dev_u16(fx, 0, 0x2000, 0), 0);   /* the second never went */
    fx_free(fx);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_classic_configures_then_skips),
        cmocka_unit_test(test_fd_configures_then_skips),
        cmocka_unit_test(test_without_stamp_only_entries),
        cmocka_unit_test(test_classic_missing_entry),
        cmocka_unit_test(test_fd_missing_entry),
        cmocka_unit_test(test_classic_read_only_entry),
        cmocka_unit_test(test_fd_read_only_entry),
        cmocka_unit_test(test_classic_silent_node),
        cmocka_unit_test(test_fd_silent_node),
        cmocka_unit_test(test_classic_200_entries),
        cmocka_unit_test(test_fd_200_entries),
        cmocka_unit_test(test_classic_two_nodes_at_once),
        cmocka_unit_test(test_fd_two_nodes_at_once),
        cmocka_unit_test(test_start_refusals),
        cmocka_unit_test(test_cancel),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
