/* The local node serving an object dictionary (co_node_attach_od): the
 * communication parameters 0x1016 (heartbeat consumer) and 0x1017 (heartbeat
 * producer) loaded from defaults or the store at boot and at resets, network
 * (SDO-server-like) and application writes taking effect at once, 0x1010 /
 * 0x1011 save and restore across NMT resets, a damaged store image, and the
 * node without an OD as before. Every bus test runs twice: on a classic bus
 * and on an FD bus with bit-rate switch; the sniffer checks every heartbeat
 * frame's CAN-ID, flags, length and byte.
 *
 * Lines: a (node A, id 5, with the OD, the store and its heartbeat consumer),
 * b (node B, id 6, a plain co_node without OD: the heartbeat peer). */
#include "test_od_util.h"

#define ID_A 5
#define ID_B 6
#define MS(x) ((uint64_t)(x) * TU_MS)
#define MAX_EV 256
#define N_ENTRIES 32
#define POOL 1024
#define SUBS 4
#define STORE_BUF 2048
#define HB_ENTRIES 4

/* 0x1016 value: node-id in bits 23..16, time in ms in bits 15..0. */
#define HB_CONS(node, ms) (((uint32_t)(node) << 16) | (uint32_t)(ms))

#define DEF_1017 100u
#define DEF_2000 0x12345678u
#define DEF_6000 0x0007u
#define SAVED_1017 200u
#define SAVED_2000 0xA1A1A1A1u
#define CHANGED_1017 300u
#define CHANGED_2000 0xB2B2B2B2u

/* ------------------------------------------------------------- fixture */

typedef struct ev {
    uint8_t node;
    co_hb_event_t event;
    uint64_t t;
} ev_t;

typedef struct fx {
    tu_bus_t tb;
    tu_line_t l[2];
    co_line_t *a, *b;
    co_od_t od;
    co_od_entry_t entries[N_ENTRIES];
    uint8_t pool[POOL];
    co_od_subscription_t subs[SUBS];
    co_store_t store;
    uint8_t store_buf[STORE_BUF];
    tu_mem_backend_t mem;
    co_node_t na, nb;
    co_hb_consumer_t cons;
    co_hb_entry_t hb_entries[HB_ENTRIES];
    ev_t ev[MAX_EV];
    int nev;
} fx_t;

static void on_hb(co_hb_consumer_t *c, uint8_t node_id, co_hb_event_t event,
                  co_nmt_state_t state, void *user)
{
    fx_t *fx = user;
    (void)state;
    assert_ptr_equal(c, &fx->cons);
    assert_true(fx->nev < MAX_EV);
    fx->ev[fx->nev].node = node_id;
    fx->ev[fx->nev].event = event;
    fx->ev[fx->nev].t = fx->tb.now;
    fx->nev++;
}

static int count_ev(const fx_t *fx, uint8_t node, co_hb_event_t event)
{
    int i, n = 0;
    for (i = 0; i < fx->nev; i++)
        if (fx->ev[i].node == node && fx->ev[i].event == event)
            n++;
    return n;
}

/* Time of the first event of a kind about a node (fails if none). */
static uint64_t ev_time(const fx_t *fx, uint8_t node, co_hb_event_t event)
{
    int i;
    for (i = 0; i < fx->nev; i++)
        if (fx->ev[i].node == node && fx->ev[i].event == event)
            return fx->ev[i].t;
    fail_msg("no event %d about node %u", (int)event, (unsigned)node);
    return 0;
}

/* ----------------------------------------------------------- the OD */

static void add(fx_t *fx, uint16_t index, uint8_t sub, uint8_t object_code, uint8_t type,
                uint8_t access, uint16_t flags, uint32_t value)
{
    co_od_def_t d = tu_od_def(index, sub, object_code, type, access, flags, co_od_type_size(type));
    uint8_t v[4];
    tu_le_put(v, value, d.size);
    d.default_value = v;
    d.default_length = d.size;
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ADDED);
}

/* cons_sub1: default of 0x1016 sub 1. */
static void build_od(fx_t *fx, uint32_t cons_sub1)
{
    uint8_t sub;
    co_od_init(&fx->od, fx->tb.mode, fx->entries, N_ENTRIES, fx->pool, POOL, fx->subs, SUBS);
    add(fx, 0x1000, 0, VAR, U32, RO, 0, 0x00000000u);
    add(fx, 0x1010, 0, ARR, U8, RO, 0, 4);
    add(fx, 0x1011, 0, ARR, U8, RO, 0, 4);
    for (sub = 1; sub <= 4; sub++) {
        add(fx, 0x1010, sub, ARR, U32, RW, 0, 1);
        add(fx, 0x1011, sub, ARR, U32, RW, 0, 1);
    }
    add(fx, 0x1016, 0, ARR, U8, RO, 0, 4);
    add(fx, 0x1016, 1, ARR, U32, RW, ST, cons_sub1);
    for (sub = 2; sub <= 4; sub++)
        add(fx, 0x1016, sub, ARR, U32, RW, ST, 0);
    add(fx, 0x1017, 0, VAR, U16, RW, ST, DEF_1017);
    add(fx, 0x1018, 0, REC, U8, RO, 0, 4);
    add(fx, 0x1018, 1, REC, U32, RO, 0, 0x00000ABCu);   /* vendor-id */
    add(fx, 0x1018, 2, REC, U32, RO, 0, 0x00000002u);   /* product code */
    add(fx, 0x1018, 3, REC, U32, RO, 0, 0x00010000u);   /* revision */
    add(fx, 0x1018, 4, REC, U32, RO, 0, 0x00001234u);   /* serial number */
    add(fx, 0x2000, 0, VAR, U32, RW, ST, DEF_2000);
    add(fx, 0x6000, 0, VAR, U16, RW, 0, DEF_6000);
    assert_true(co_od_seal(&fx->od, ID_A));
    assert_true(co_store_init(&fx->store, &fx->od, &tu_mem_ops, &fx->mem, fx->store_buf,
                              sizeof fx->store_buf));
}

static int setup(void **state, co_mode_t mode, bool brs, uint32_t cons_sub1)
{
    fx_t *fx = calloc(1, sizeof *fx);
    if (fx == NULL)
        return -1;
    tu_bus_init(&fx->tb, mode, brs);
    fx->a = tu_bus_add_line(&fx->tb, &fx->l[0]);
    fx->b = tu_bus_add_line(&fx->tb, &fx->l[1]);
    build_od(fx, cons_sub1);
    *state = fx;
    return 0;
}

static int setup_classic(void **state) { return setup(state, CO_MODE_CLASSIC, false, 0); }
static int setup_fd(void **state) { return setup(state, CO_MODE_FD, true, 0); }
/* 0x1016 sub 1 defaults to "node B, 150 ms". */
static int setup_classic_watch_b(void **state)
{
    return setup(state, CO_MODE_CLASSIC, false, HB_CONS(ID_B, 150));
}
static int setup_fd_watch_b(void **state)
{
    return setup(state, CO_MODE_FD, true, HB_CONS(ID_B, 150));
}

static int teardown(void **state)
{
    free(*state);
    return 0;
}

/* ------------------------------------------------------------ helpers */

static void run_until(fx_t *fx, uint64_t t) { tu_run_until(&fx->tb, t); }

/* An NMT reset of a local node (as from the master), its boot-up carried at
 * the current time. */
static void nmt_reset(fx_t *fx, co_nmt_t *nmt, co_nmt_command_t cmd)
{
    co_nmt_apply(nmt, cmd);
    tu_step(&fx->tb, fx->tb.now);
}

/* Boot a node and carry its boot-up at the current time. */
static void boot(fx_t *fx, co_node_t *node)
{
    co_node_boot(node);
    tu_step(&fx->tb, fx->tb.now);
}

/* Node A (OD, store, consumer; 0 as init heartbeat so that only the OD can
 * start it) and node B (plain, heartbeat b_hb_ms) booted at the current time. */
static void start(fx_t *fx, uint16_t b_hb_ms)
{
    assert_true(co_node_init(&fx->na, fx->a, ID_A, 0, NULL, NULL));
    assert_true(co_hb_consumer_init(&fx->cons, fx->a, fx->hb_entries, HB_ENTRIES, on_hb, fx));
    assert_true(co_node_attach_od(&fx->na, &fx->od, &fx->store, &fx->cons));
    assert_true(co_node_init(&fx->nb, fx->b, ID_B, b_hb_ms, NULL, NULL));
    co_node_boot(&fx->na);
    co_node_boot(&fx->nb);
    tu_step(&fx->tb, fx->tb.now);
}

/* A network download as the SDO server does it: begin with the size, the
 * data in two chunks, end. Returns the abort code (0 = written). */
static uint32_t net_write(fx_t *fx, uint16_t index, uint8_t sub, const uint8_t *data,
                          uint32_t len)
{
    co_od_xfer_t x;
    uint8_t scratch[8];
    uint32_t r, half = len / 2;
    co_od_xfer_init(&x, scratch, sizeof scratch);
    r = co_od_write_begin(&fx->od, &x, index, sub, len);
    if (r != 0)
        return r;
    r = co_od_write_chunk(&x, data, half);
    if (r != 0)
        return r;
    r = co_od_write_chunk(&x, data + half, len - half);
    if (r != 0)
        return r;
    r = co_od_write_end(&x);
    assert_int_not_equal(r, CO_OD_SPLIT);
    assert_int_equal(x.state, CO_XFER_DONE);
    assert_int_equal(x.abort, r);
    return r;
}

static uint32_t net_write_u32(fx_t *fx, uint16_t index, uint8_t sub, uint32_t value)
{
    uint8_t b[4];
    tu_le_put(b, value, 4);
    return net_write(fx, index, sub, b, 4);
}

static uint32_t net_write_u16(fx_t *fx, uint16_t index, uint8_t sub, uint16_t value)
{
    uint8_t b[2];
    tu_le_put(b, value, 2);
    return net_write(fx, index, sub, b, 2);
}

static uint32_t put_u16(fx_t *fx, uint16_t index, uint8_t sub, uint16_t value)
{
    uint8_t b[2];
    tu_le_put(b, value, 2);
    return co_od_put(&fx->od, index, sub, b, 2);
}

static uint32_t put_u32(fx_t *fx, uint16_t index, uint8_t sub, uint32_t value)
{
    uint8_t b[4];
    tu_le_put(b, value, 4);
    return co_od_put(&fx->od, index, sub, b, 4);
}

static uint16_t od_u16(const fx_t *fx, uint16_t index, uint8_t sub)
{
    uint16_t v = 0;
    assert_true(co_od_get_u16(&fx->od, index, sub, &v));
    return v;
}

static uint32_t od_u32(const fx_t *fx, uint16_t index, uint8_t sub)
{
    uint32_t v = 0;
    assert_true(co_od_get_u32(&fx->od, index, sub, &v));
    return v;
}

/* Every entry of the OD holds its default (fixed-size entries only here). */
static void assert_all_defaults(const fx_t *fx)
{
    uint32_t i;
    for (i = 0; i < fx->od.count; i++) {
        const co_od_entry_t *e = &fx->od.entries[i];
        assert_int_equal(e->length, e->size);
        if (memcmp(fx->od.pool + e->value, fx->od.pool + e->default_value, e->size) != 0)
            fail_msg("0x%04X sub %u is not its default", co_od_entry_index(e),
                     co_od_entry_sub(e));
    }
}

/* Expected heartbeat / boot-up frames of a node in the log: exactly n, at
 * these times (ms) with these state bytes; every frame checked whole. */
static void expect_hb(const fx_t *fx, uint8_t node_id, const uint64_t *at_ms,
                      const uint8_t *st, size_t n)
{
    size_t i, k = 0;
    for (i = 0; i < fx->tb.log_count; i++) {
        const tu_logged_t *e = &fx->tb.log[i];
        if (e->frame.id != 0x700u + node_id)
            continue;
        if (k >= n)
            fail_msg("node %u: unexpected frame #%zu at %llu us", (unsigned)node_id, k,
                     (unsigned long long)e->t_us);
        tu_assert_frame(&e->frame, 0x700u + node_id, tu_bus_flags(&fx->tb), &st[k], 1);
        if (e->t_us != MS(at_ms[k]))
            fail_msg("node %u: frame #%zu at %llu us, expected %llu ms", (unsigned)node_id, k,
                     (unsigned long long)e->t_us, (unsigned long long)at_ms[k]);
        k++;
    }
    if (k != n)
        fail_msg("node %u: %zu frames, expected %zu", (unsigned)node_id, k, n);
}

#define BOOT 0x00
#define PREOP 0x7F


/* Save (network write of "save" to 0x1010 sub 1) with 0x1017 = SAVED_1017
 * and 0x2000 = SAVED_2000, then change them to CHANGED_* (and 0x6000). */
static void save_then_change(fx_t *fx)
{
    assert_int_equal(net_write_u16(fx, 0x1017, 0, SAVED_1017), 0);
    assert_int_equal(net_write_u32(fx, 0x2000, 0, SAVED_2000), 0);
    assert_int_equal(net_write_u32(fx, 0x1010, 1, CO_STORE_SAVE_SIGNATURE), 0);
    assert_int_equal(fx->mem.saves, 1);
    assert_true(fx->mem.has);
    assert_int_equal(net_write_u16(fx, 0x1017, 0, CHANGED_1017), 0);
    assert_int_equal(net_write_u32(fx, 0x2000, 0, CHANGED_2000), 0);
    assert_int_equal(net_write_u16(fx, 0x6000, 0, 0x4242), 0);
}

/* Before any node exists: non-default values saved in the backend. */
static void prepare_saved_image(fx_t *fx)
{
    assert_int_equal(put_u16(fx, 0x1017, 0, SAVED_1017), 0);
    assert_int_equal(put_u32(fx, 0x2000, 0, SAVED_2000), 0);
    assert_int_equal(put_u32(fx, 0x1016, 1, HB_CONS(7, 100)), 0);
    assert_int_equal(put_u16(fx, 0x6000, 0, 0x4242), 0);   /* not stored */
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_ALL), 0);
    assert_true(fx->mem.has);
    assert_true(fx->mem.length > 28);
}

/* ================================================= boot */

static void test_boot_loads_defaults_heartbeat_every_100ms(void **state)
{
    fx_t *fx = *state;
    const uint64_t at[] = { 3, 103, 203, 303, 403, 503 };
    const uint8_t st[] = { BOOT, PREOP, PREOP, PREOP, PREOP, PREOP };
    run_until(fx, MS(3));
    start(fx, 0);
    assert_int_equal(fx->na.store_status, CO_STORE_EMPTY);
    assert_all_defaults(fx);
    assert_int_equal(fx->na.heartbeat.time_ms, DEF_1017);
    assert_int_equal(co_hb_consumer_get_entry(&fx->cons, 0), 0);
    run_until(fx, MS(550));
    expect_hb(fx, ID_A, at, st, 6);
}

static void test_boot_loads_saved_image(void **state)
{
    /* Control for the damaged-image test: the same image, intact, loads. */
    fx_t *fx = *state;
    const uint64_t at[] = { 0, 200, 400 };
    const uint8_t st[] = { BOOT, PREOP, PREOP };
    prepare_saved_image(fx);
    start(fx, 0);
    assert_int_equal(fx->na.store_status, CO_STORE_OK);
    assert_int_equal(od_u16(fx, 0x1017, 0), SAVED_1017);
    assert_int_equal(od_u32(fx, 0x2000, 0), SAVED_2000);
    assert_int_equal(od_u32(fx, 0x1016, 1), HB_CONS(7, 100));
    assert_int_equal(co_hb_consumer_get_entry(&fx->cons, 0), HB_CONS(7, 100));
    assert_int_equal(od_u16(fx, 0x6000, 0), DEF_6000);
    run_until(fx, MS(450));
    expect_hb(fx, ID_A, at, st, 3);
}

static void test_boot_damaged_image_loads_defaults(void **state)
{
    fx_t *fx = *state;
    const uint64_t at[] = { 0, 100, 200, 300 };
    const uint8_t st[] = { BOOT, PREOP, PREOP, PREOP };
    prepare_saved_image(fx);
    fx->mem.data[fx->mem.length - 1] ^= 0x5A;   /* last byte of the last record */
    start(fx, 0);
    assert_int_equal(fx->na.store_status, CO_STORE_DAMAGED);
    assert_all_defaults(fx);
    assert_int_equal(fx->na.heartbeat.time_ms, DEF_1017);
    assert_int_equal(co_hb_consumer_get_entry(&fx->cons, 0), 0);
    run_until(fx, MS(350));
    expect_hb(fx, ID_A, at, st, 4);
}

/* ================================================= 0x1017 */

static void test_network_write_1017_rearms_heartbeat_at_once(void **state)
{
    fx_t *fx = *state;
    /* Old period would give 300; the new one counts from the write at 250. */
    const uint64_t at[] = { 0, 100, 200, 550, 850 };
    const uint8_t st[] = { BOOT, PREOP, PREOP, PREOP, PREOP };
    start(fx, 0);
    run_until(fx, MS(250));
    assert_int_equal(net_write_u16(fx, 0x1017, 0, 300), 0);
    assert_int_equal(od_u16(fx, 0x1017, 0), 300);
    assert_int_equal(fx->na.heartbeat.time_ms, 300);
    run_until(fx, MS(900));
    expect_hb(fx, ID_A, at, st, 5);
}

static void test_network_write_1017_zero_stops_heartbeat(void **state)
{
    fx_t *fx = *state;
    const uint64_t at[] = { 0, 100, 200 };
    const uint8_t st[] = { BOOT, PREOP, PREOP };
    start(fx, 0);
    run_until(fx, MS(250));
    assert_int_equal(net_write_u16(fx, 0x1017, 0, 0), 0);
    assert_int_equal(od_u16(fx, 0x1017, 0), 0);
    assert_int_equal(fx->na.heartbeat.time_ms, 0);
    run_until(fx, MS(3000));
    expect_hb(fx, ID_A, at, st, 3);
}

static void test_put_1017_rearms_heartbeat_at_once(void **state)
{
    fx_t *fx = *state;
    const uint64_t at[] = { 0, 100, 200, 250 + 40, 250 + 80, 250 + 120 };
    const uint8_t st[] = { BOOT, PREOP, PREOP, PREOP, PREOP, PREOP };
    start(fx, 0);
    run_until(fx, MS(250));
    assert_int_equal(put_u16(fx, 0x1017, 0, 40), 0);
    assert_int_equal(fx->na.heartbeat.time_ms, 40);
    run_until(fx, MS(380));
    expect_hb(fx, ID_A, at, st, 6);
}

static void test_put_1017_zero_stops_heartbeat(void **state)
{
    fx_t *fx = *state;
    const uint64_t at[] = { 0, 100 };
    const uint8_t st[] = { BOOT, PREOP };
    start(fx, 0);
    run_until(fx, MS(150));
    assert_int_equal(put_u16(fx, 0x1017, 0, 0), 0);
    assert_int_equal(fx->na.heartbeat.time_ms, 0);
    run_until(fx, MS(3000));
    expect_hb(fx, ID_A, at, st, 2);
}

/* ================================================= 0x1016 */

/* Node B sends heartbeats every 50 ms from 0 and stops after the one at
 * 500 ms: A's consumer (150 ms) reports LOST at exactly 650 ms, once. */
static void expect_b_lost_at_650(fx_t *fx)
{
    run_until(fx, MS(500));
    co_node_set_heartbeat(&fx->nb, 0);
    run_until(fx, MS(649));
    assert_int_equal(co_hb_consumer_monitor(&fx->cons, ID_B), CO_HB_MONITOR_ACTIVE);
    assert_int_equal(count_ev(fx, ID_B, CO_HB_LOST), 0);
    run_until(fx, MS(2000));
    assert_int_equal(co_hb_consumer_monitor(&fx->cons, ID_B), CO_HB_MONITOR_LOST);
    assert_int_equal(count_ev(fx, ID_B, CO_HB_LOST), 1);
    assert_int_equal(ev_time(fx, ID_B, CO_HB_LOST), MS(650));
}

static void test_1016_default_watches_node_b(void **state)
{
    fx_t *fx = *state;
    start(fx, 50);
    assert_int_equal(co_hb_consumer_get_entry(&fx->cons, 0), HB_CONS(ID_B, 150));
    expect_b_lost_at_650(fx);
    assert_int_equal(count_ev(fx, ID_B, CO_HB_STARTED), 1);
    assert_int_equal(ev_time(fx, ID_B, CO_HB_STARTED), MS(50));
}

static void test_1016_network_write_watches_node_b(void **state)
{
    fx_t *fx = *state;
    start(fx, 50);
    run_until(fx, MS(120));
    assert_int_equal(co_hb_consumer_get_entry(&fx->cons, 0), 0);
    assert_int_equal(net_write_u32(fx, 0x1016, 1, HB_CONS(ID_B, 150)), 0);
    assert_int_equal(od_u32(fx, 0x1016, 1), HB_CONS(ID_B, 150));
    assert_int_equal(co_hb_consumer_get_entry(&fx->cons, 0), HB_CONS(ID_B, 150));
    expect_b_lost_at_650(fx);
    /* Monitoring starts with B's first heartbeat after the write. */
    assert_int_equal(count_ev(fx, ID_B, CO_HB_STARTED), 1);
    assert_int_equal(ev_time(fx, ID_B, CO_HB_STARTED), MS(150));
}

static void test_1016_duplicate_node_refused_changes_nothing(void **state)
{
    fx_t *fx = *state;
    uint8_t i;
    start(fx, 50);
    run_until(fx, MS(100));
    assert_int_equal(net_write_u32(fx, 0x1016, 2, HB_CONS(ID_B, 200)),
                     CO_ABORT_PARAM_INCOMPATIBLE);
    assert_int_equal(CO_ABORT_PARAM_INCOMPATIBLE, 0x06040043);
    assert_int_equal(od_u32(fx, 0x1016, 1), HB_CONS(ID_B, 150));
    assert_int_equal(od_u32(fx, 0x1016, 2), 0);
    assert_int_equal(co_hb_consumer_get_entry(&fx->cons, 0), HB_CONS(ID_B, 150));
    for (i = 1; i < HB_ENTRIES; i++)
        assert_int_equal(co_hb_consumer_get_entry(&fx->cons, i), 0);
    /* Monitoring goes on with sub 1's 150 ms, not the refused 200 ms. */
    expect_b_lost_at_650(fx);
}

static void test_1016_same_entry_new_time_accepted(void **state)
{
    /* Not a duplicate: the entry that already watches B gets a new time. */
    fx_t *fx = *state;
    start(fx, 50);
    run_until(fx, MS(100));
    assert_int_equal(net_write_u32(fx, 0x1016, 1, HB_CONS(ID_B, 300)), 0);
    assert_int_equal(od_u32(fx, 0x1016, 1), HB_CONS(ID_B, 300));
    assert_int_equal(co_hb_consumer_get_entry(&fx->cons, 0), HB_CONS(ID_B, 300));
    run_until(fx, MS(500));
    co_node_set_heartbeat(&fx->nb, 0);
    run_until(fx, MS(2000));
    assert_int_equal(count_ev(fx, ID_B, CO_HB_LOST), 1);
    assert_int_equal(ev_time(fx, ID_B, CO_HB_LOST), MS(800));
}

static void test_1016_node_zero_frees_entry(void **state)
{
    fx_t *fx = *state;
    start(fx, 50);
    run_until(fx, MS(200));
    assert_int_equal(co_hb_consumer_monitor(&fx->cons, ID_B), CO_HB_MONITOR_ACTIVE);
    assert_int_equal(net_write_u32(fx, 0x1016, 1, 0), 0);
    assert_int_equal(od_u32(fx, 0x1016, 1), 0);
    assert_int_equal(co_hb_consumer_get_entry(&fx->cons, 0), 0);
    assert_int_equal(co_hb_consumer_monitor(&fx->cons, ID_B), CO_HB_MONITOR_OFF);
    /* B stops: nobody watches it any more. */
    run_until(fx, MS(500));
    co_node_set_heartbeat(&fx->nb, 0);
    run_until(fx, MS(2000));
    assert_int_equal(count_ev(fx, ID_B, CO_HB_LOST), 0);
    /* And B may now go into another entry. */
    assert_int_equal(net_write_u32(fx, 0x1016, 2, HB_CONS(ID_B, 150)), 0);
    assert_int_equal(co_hb_consumer_get_entry(&fx->cons, 1), HB_CONS(ID_B, 150));
}

static void test_attach_refused_when_handler_table_full(void **state)
{
    static const co_od_handler_t dummy = {.before_read = NULL};
    fx_t *fx = *state;
    /* The store took 2 of the 4 subscriptions; fill the rest. */
    assert_true(co_od_subscribe(&fx->od, 0x6000, 0, 0x6000, 0, &dummy, NULL));
    assert_true(co_od_subscribe(&fx->od, 0x6000, 0, 0x6000, 0, &dummy, NULL));
    assert_true(co_node_init(&fx->na, fx->a, ID_A, 0, NULL, NULL));
    assert_false(co_node_attach_od(&fx->na, &fx->od, &fx->store, NULL));
}

/* co_node_set_heartbeat() is "write 0x1017": with an OD attached, the OD
 * must say what the producer does (an SDO upload of 0x1017, a later save). */
static void test_set_heartbeat_api_updates_od_1017(void **state)
{
    fx_t *fx = *state;
    const uint64_t at[] = { 0, 100, 200, 250 + 250 };
    const uint8_t st[] = { BOOT, PREOP, PREOP, PREOP };
    start(fx, 0);
    run_until(fx, MS(250));
    co_node_set_heartbeat(&fx->na, 250);
    run_until(fx, MS(600));
    expect_hb(fx, ID_A, at, st, 4);
    assert_int_equal(fx->na.heartbeat.time_ms, 250);
    assert_true(od_u16(fx, 0x1017, 0) == 250);
}

/* After co_node_deinit() the node is gone: an OD write to 0x1017 must not
 * bring its heartbeat back. */
static void test_deinit_then_od_write_sends_nothing(void **state)
{
    fx_t *fx = *state;
    start(fx, 0);
    run_until(fx, MS(150));
    co_node_deinit(&fx->na);
    tu_log_clear(&fx->tb);
    assert_int_equal(put_u16(fx, 0x1017, 0, 50), 0);
    run_until(fx, MS(1000));
    assert_true(tu_log_count_id(&fx->tb, 0x700u + ID_A) == 0);
}

/* ================================================= store / restore */

static void test_store_reset_communication_restores_saved_communication(void **state)
{
    fx_t *fx = *state;
    const uint64_t at[] = { 1000, 1200, 1400 };
    const uint8_t st[] = { BOOT, PREOP, PREOP };
    start(fx, 0);
    run_until(fx, MS(50));
    save_then_change(fx);
    run_until(fx, MS(1000));
    tu_log_clear(&fx->tb);
    nmt_reset(fx, &fx->na.nmt, CO_NMT_CMD_RESET_COMMUNICATION);
    assert_int_equal(fx->na.store_status, CO_STORE_OK);
    assert_int_equal(od_u16(fx, 0x1017, 0), SAVED_1017);   /* communication: saved */
    assert_int_equal(fx->na.heartbeat.time_ms, SAVED_1017);
    assert_int_equal(od_u32(fx, 0x2000, 0), CHANGED_2000); /* manufacturer: kept */
    assert_int_equal(od_u16(fx, 0x6000, 0), 0x4242);       /* application: kept */
    run_until(fx, MS(1450));
    expect_hb(fx, ID_A, at, st, 3);
}

static void test_store_reset_node_restores_saved_all(void **state)
{
    fx_t *fx = *state;
    const uint64_t at[] = { 1000, 1200, 1400 };
    const uint8_t st[] = { BOOT, PREOP, PREOP };
    start(fx, 0);
    run_until(fx, MS(50));
    save_then_change(fx);
    run_until(fx, MS(1000));
    tu_log_clear(&fx->tb);
    nmt_reset(fx, &fx->na.nmt, CO_NMT_CMD_RESET_NODE);
    assert_int_equal(fx->na.store_status, CO_STORE_OK);
    assert_int_equal(od_u16(fx, 0x1017, 0), SAVED_1017);
    assert_int_equal(od_u32(fx, 0x2000, 0), SAVED_2000);
    assert_int_equal(od_u16(fx, 0x6000, 0), DEF_6000);     /* not stored: default */
    run_until(fx, MS(1450));
    expect_hb(fx, ID_A, at, st, 3);
}

static void test_store_reset_comm_then_reset_node(void **state)
{
    /* The brief's sequence in one go: comm reset first, node reset after. */
    fx_t *fx = *state;
    start(fx, 0);
    run_until(fx, MS(50));
    save_then_change(fx);
    run_until(fx, MS(500));
    nmt_reset(fx, &fx->na.nmt, CO_NMT_CMD_RESET_COMMUNICATION);
    assert_int_equal(od_u16(fx, 0x1017, 0), SAVED_1017);
    assert_int_equal(od_u32(fx, 0x2000, 0), CHANGED_2000);
    run_until(fx, MS(700));
    nmt_reset(fx, &fx->na.nmt, CO_NMT_CMD_RESET_NODE);
    assert_int_equal(od_u16(fx, 0x1017, 0), SAVED_1017);
    assert_int_equal(od_u32(fx, 0x2000, 0), SAVED_2000);
    assert_int_equal(fx->na.store_status, CO_STORE_OK);
}

static void test_store_load_signature_then_reset_node_gives_defaults(void **state)
{
    fx_t *fx = *state;
    const uint64_t at[] = { 1000, 1100, 1200, 1300 };
    const uint8_t st[] = { BOOT, PREOP, PREOP, PREOP };
    start(fx, 0);
    run_until(fx, MS(50));
    save_then_change(fx);
    run_until(fx, MS(600));
    assert_int_equal(net_write_u32(fx, 0x1011, 1, CO_STORE_LOAD_SIGNATURE), 0);
    /* Nothing changes before the reset. */
    assert_int_equal(od_u16(fx, 0x1017, 0), CHANGED_1017);
    assert_int_equal(od_u32(fx, 0x2000, 0), CHANGED_2000);
    run_until(fx, MS(1000));
    tu_log_clear(&fx->tb);
    nmt_reset(fx, &fx->na.nmt, CO_NMT_CMD_RESET_NODE);
    assert_int_equal(od_u16(fx, 0x1017, 0), DEF_1017);
    assert_int_equal(od_u32(fx, 0x2000, 0), DEF_2000);
    assert_int_equal(od_u16(fx, 0x6000, 0), DEF_6000);
    assert_int_equal(fx->na.heartbeat.time_ms, DEF_1017);
    run_until(fx, MS(1350));
    expect_hb(fx, ID_A, at, st, 4);
}

/* ================================================= without OD */

static void test_plain_node_reset_node_uses_init_heartbeat(void **state)
{
    fx_t *fx = *state;
    const uint64_t at[] = { 0, 100, 200, 550, 600, 700, 800 };
    const uint8_t st[] = { BOOT, PREOP, PREOP, PREOP, BOOT, PREOP, PREOP };
    assert_true(co_node_init(&fx->na, fx->a, ID_A, 100, NULL, NULL));
    assert_null(fx->na.od);
    assert_null(fx->na.store);
    assert_null(fx->na.consumer);
    boot(fx, &fx->na);
    run_until(fx, MS(250));
    co_node_set_heartbeat(&fx->na, 300);   /* next at 550 */
    run_until(fx, MS(600));
    nmt_reset(fx, &fx->na.nmt, CO_NMT_CMD_RESET_NODE);
    assert_int_equal(fx->na.heartbeat.time_ms, 100);
    assert_int_equal(fx->na.store_status, CO_STORE_EMPTY);
    run_until(fx, MS(850));
    expect_hb(fx, ID_A, at, st, 7);
    assert_int_equal(fx->mem.loads, 0);
}

static void test_plain_node_reset_comm_uses_init_heartbeat(void **state)
{
    fx_t *fx = *state;
    const uint64_t at[] = { 0, 100, 200, 550, 600, 700, 800 };
    const uint8_t st[] = { BOOT, PREOP, PREOP, PREOP, BOOT, PREOP, PREOP };
    assert_true(co_node_init(&fx->nb, fx->b, ID_B, 100, NULL, NULL));
    boot(fx, &fx->nb);
    run_until(fx, MS(250));
    co_node_set_heartbeat(&fx->nb, 300);
    run_until(fx, MS(600));
    nmt_reset(fx, &fx->nb.nmt, CO_NMT_CMD_RESET_COMMUNICATION);
    assert_int_equal(fx->nb.heartbeat.time_ms, 100);
    run_until(fx, MS(850));
    expect_hb(fx, ID_B, at, st, 7);
}

static void test_plain_node_boot_uses_time_set_before_boot(void **state)
{
    fx_t *fx = *state;
    const uint64_t at[] = { 0, 70, 140 };
    const uint8_t st[] = { BOOT, PREOP, PREOP };
    assert_true(co_node_init(&fx->nb, fx->b, ID_B, 100, NULL, NULL));
    co_node_set_heartbeat(&fx->nb, 70);
    boot(fx, &fx->nb);
    run_until(fx, MS(200));
    expect_hb(fx, ID_B, at, st, 3);
}

/* ================================================= runner */

#define BOTH(t) \
    {"classic: " #t, t, setup_classic, teardown, NULL}, \
    {"fd: " #t, t, setup_fd, teardown, NULL}
#define BOTH_WATCH_B(t) \
    {"classic: " #t, t, setup_classic_watch_b, teardown, NULL}, \
    {"fd: " #t, t, setup_fd_watch_b, teardown, NULL}

int main(void)
{
    const struct CMUnitTest tests[] = {
        BOTH(test_boot_loads_defaults_heartbeat_every_100ms),
        BOTH(test_boot_loads_saved_image),
        BOTH(test_boot_damaged_image_loads_defaults),
        BOTH(test_network_write_1017_rearms_heartbeat_at_once),
        BOTH(test_network_write_1017_zero_stops_heartbeat),
        BOTH(test_put_1017_rearms_heartbeat_at_once),
        BOTH(test_put_1017_zero_stops_heartbeat),
        BOTH_WATCH_B(test_1016_default_watches_node_b),
        BOTH(test_1016_network_write_watches_node_b),
        BOTH_WATCH_B(test_1016_duplicate_node_refused_changes_nothing),
        BOTH_WATCH_B(test_1016_same_entry_new_time_accepted),
        BOTH_WATCH_B(test_1016_node_zero_frees_entry),
        BOTH(test_attach_refused_when_handler_table_full),
        BOTH(test_set_heartbeat_api_updates_od_1017),
        BOTH(test_deinit_then_od_write_sends_nothing),
        BOTH(test_store_reset_communication_restores_saved_communication),
        BOTH(test_store_reset_node_restores_saved_all),
        BOTH(test_store_reset_comm_then_reset_node),
        BOTH(test_store_load_signature_then_reset_node_gives_defaults),
        BOTH(test_plain_node_reset_node_uses_init_heartbeat),
        BOTH(test_plain_node_reset_comm_uses_init_heartbeat),
        BOTH(test_plain_node_boot_uses_time_set_before_boot),
    };
    return cmocka_run_group_tests_name("node_od", tests, NULL, NULL);
}
