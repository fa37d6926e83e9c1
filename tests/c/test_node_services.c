/* The local node wiring its services together (co_node_attach_services):
 * NMT state to EMCY, SYNC, TIME and PDOs; SYNC (received or produced) to
 * the synchronous TPDOs and the 0x1007 window; the errors the services and
 * the driver side detect to EMCY (exact bytes, classic 8-byte layout and one
 * FD case with the 20-byte layout) and cleared when their cause ends;
 * 0x1029:01 error behaviour; NMT reset communication reloading PDOs,
 * clearing the node's errors and restarting guarding; co_node_deinit
 * leaving no SYNC listener behind.
 *
 * Lines: n (node 5 with its OD and every service), p (the network peer: sends
 * raw frames: NMT commands, SYNC, RPDOs, remote frames). The sniffer records
 * every frame with its fake time. */
#include "test_od_util.h"

#include "co_cob_id.h"

#define ID 5
#define MS(x) ((uint64_t)(x) * TU_MS)
#define MAP(i, s, bits) (((uint32_t)(i) << 16) | ((uint32_t)(s) << 8) | (uint32_t)(bits))
#define BOTH (CO_OD_MAP_TPDO | CO_OD_MAP_RPDO)
#define N_ENTRIES 96
#define POOL 2048
#define SUBS 16
#define EMCY_ID (0x80u + ID)
#define TPDO1_ID 0x185u   /* type 254, maps 0x2000 (U8) */
#define TPDO2_ID 0x285u   /* type 1, maps 0x2001 (U16) */
#define RPDO1_ID 0x205u   /* type 254, maps 0x2002 (U32) */
#define RPDO2_ID 0x305u   /* type 254, maps 0x2004 (U16) */
#define SYNC_ID 0x80u
#define TIME_ID 0x100u
#define NO_1029 0xFF      /* option: the OD has no 0x1029 */

typedef struct fx {
    tu_bus_t tb;
    tu_line_t l[2];
    co_line_t *n, *p;
    co_od_t od;
    co_od_entry_t entries[N_ENTRIES];
    uint8_t pool[POOL];
    co_od_subscription_t subs[SUBS];
    co_node_t node;
    bool node_live;
    co_emcy_t emcy;
    co_emcy_msg_t queue[16];
    co_emcy_active_t active[8];
    co_sync_t sync;
    co_time_t time;
    co_pdo_t pdo;
    co_pdo_channel_t channels[8];
    co_pdo_map_item_t items[16];
    co_guard_slave_t guard;
    bool has_guard;
} fx_t;

/* ------------------------------------------------------------- fixture */

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

static void add_pdo(fx_t *fx, bool rpdo, uint16_t num, uint32_t cob, uint8_t type,
                    uint8_t cap, uint32_t map1)
{
    uint16_t comm = (uint16_t)((rpdo ? 0x1400 : 0x1800) + num - 1);
    uint16_t map = (uint16_t)((rpdo ? 0x1600 : 0x1A00) + num - 1);
    uint8_t s;
    add(fx, comm, 0, REC, U8, RO, 0, rpdo ? 5 : 6);
    add(fx, comm, 1, REC, U32, RW, 0, cob);
    add(fx, comm, 2, REC, U8, RW, 0, type);
    add(fx, comm, 3, REC, U16, RW, 0, 0);
    add(fx, comm, 5, REC, U16, RW, 0, 0);
    if (!rpdo)
        add(fx, comm, 6, REC, U8, RW, 0, 0);
    add(fx, map, 0, REC, U8, RW, 0, 1);
    for (s = 1; s <= cap; s++)
        add(fx, map, s, REC, U32, RW, 0, s == 1 ? map1 : 0);
}

static void build_od(fx_t *fx, uint8_t behaviour)
{
    co_od_init(&fx->od, fx->tb.mode, fx->entries, N_ENTRIES, fx->pool, POOL, fx->subs, SUBS);
    add(fx, 0x1001, 0, VAR, U8, RO, 0, 0);
    add(fx, 0x1005, 0, VAR, U32, RW, 0, SYNC_ID);
    add(fx, 0x1006, 0, VAR, U32, RW, 0, 0);
    add(fx, 0x1007, 0, VAR, U32, RW, 0, 0);
    add(fx, 0x100C, 0, VAR, U16, RW, 0, 0);
    add(fx, 0x100D, 0, VAR, U8, RW, 0, 0);
    add(fx, 0x1012, 0, VAR, U32, RW, 0, 0x40000000u | TIME_ID);
    add(fx, 0x1014, 0, VAR, U32, RW, 0, EMCY_ID);
    add(fx, 0x1015, 0, VAR, U16, RW, 0, 0);
    add(fx, 0x1017, 0, VAR, U16, RW, 0, 0);
    add(fx, 0x1019, 0, VAR, U8, RW, 0, 0);
    if (behaviour != NO_1029) {
        add(fx, 0x1029, 0, ARR, U8, RO, 0, 1);
        add(fx, 0x1029, 1, ARR, U8, RW, 0, behaviour);
    }
    add_pdo(fx, true, 1, RPDO1_ID, 254, 1, MAP(0x2002, 0, 32));
    add_pdo(fx, true, 2, RPDO2_ID, 254, 1, MAP(0x2004, 0, 16));
    add_pdo(fx, false, 1, TPDO1_ID, 254, 2, MAP(0x2000, 0, 8));
    add_pdo(fx, false, 2, TPDO2_ID, 1, 1, MAP(0x2001, 0, 16));
    add(fx, 0x2000, 0, VAR, U8, RW, BOTH, 0x11);
    add(fx, 0x2001, 0, VAR, U16, RW, BOTH, 0x2222);
    add(fx, 0x2002, 0, VAR, U32, RW, BOTH, 0x33333333u);
    add(fx, 0x2004, 0, VAR, U16, RW, BOTH, 0x4444);
    assert_true(co_od_seal(&fx->od, ID));
}

static void step(fx_t *fx) { tu_step(&fx->tb, fx->tb.now); }
static void at(fx_t *fx, uint64_t t) { tu_run_until(&fx->tb, t); }

/* A node with every service on a classic or FD bus, booted (pre-operational). */
static fx_t *fx_new(co_mode_t mode, uint8_t behaviour)
{
    fx_t *fx = calloc(1, sizeof *fx);
    co_emcy_config_t ecfg;
    co_pdo_config_t pcfg;
    co_node_services_t services;
    uint32_t channels = 0, items = 0;
    assert_non_null(fx);
    tu_bus_init(&fx->tb, mode, mode == CO_MODE_FD);
    fx->n = tu_bus_add_line(&fx->tb, &fx->l[0]);
    fx->p = tu_bus_add_line(&fx->tb, &fx->l[1]);
    build_od(fx, behaviour);
    assert_true(co_node_init(&fx->node, fx->n, ID, 0, NULL, NULL));
    fx->node_live = true;
    assert_true(co_node_attach_od(&fx->node, &fx->od, NULL, NULL));

    memset(&ecfg, 0, sizeof ecfg);
    ecfg.queue = fx->queue;
    ecfg.queue_capacity = 16;
    ecfg.active = fx->active;
    ecfg.active_capacity = 8;
    assert_true(co_emcy_init(&fx->emcy, fx->n, ID, &ecfg));
    assert_true(co_emcy_attach_od(&fx->emcy, &fx->od));
    assert_true(co_sync_init(&fx->sync, fx->n));
    assert_true(co_sync_attach_od(&fx->sync, &fx->od));
    co_time_init(&fx->time, fx->n, NULL, NULL);
    assert_true(co_time_attach_od(&fx->time, &fx->od));
    assert_true(co_pdo_need(&fx->od, &channels, &items));
    assert_true(channels <= 8 && items <= 16);
    memset(&pcfg, 0, sizeof pcfg);
    pcfg.channels = fx->channels;
    pcfg.channel_count = channels;
    pcfg.items = fx->items;
    pcfg.item_count = items;
    pcfg.ind = &co_node_pdo_indications;
    pcfg.user = &fx->node;
    assert_true(co_pdo_init(&fx->pdo, fx->n, &fx->od, &pcfg));
    memset(&services, 0, sizeof services);
    services.emcy = &fx->emcy;
    services.sync = &fx->sync;
    services.time = &fx->time;
    services.pdo = &fx->pdo;
    if (mode == CO_MODE_CLASSIC) {
        assert_true(co_guard_slave_init(&fx->guard, fx->n, &fx->node.nmt, co_node_guard_life,
                                        &fx->node));
        assert_true(co_guard_slave_attach_od(&fx->guard, &fx->od));
        fx->has_guard = true;
        services.guard = &fx->guard;
    }
    co_node_attach_services(&fx->node, &services);
    co_node_boot(&fx->node);
    tu_step(&fx->tb, 0);
    assert_int_equal(co_node_state(&fx->node), CO_NMT_PRE_OPERATIONAL);
    return fx;
}

static void fx_free(fx_t *fx)
{
    if (fx->node_live)
        co_node_deinit(&fx->node);
    if (fx->has_guard)
        co_guard_slave_deinit(&fx->guard);
    co_pdo_deinit(&fx->pdo);
    co_time_deinit(&fx->time);
    co_sync_deinit(&fx->sync);
    co_emcy_deinit(&fx->emcy);
    free(fx);
}

/* ------------------------------------------------------------- helpers */

/* The peer sends a frame (with the bus's FD flags), carried at once. */
static void peer(fx_t *fx, uint32_t id, const uint8_t *data, uint8_t len)
{
    co_frame_t f = tu_frame(id, tu_bus_flags(&fx->tb), data, len);
    assert_true(co_line_send_raw(fx->p, &f));
    step(fx);
}

static void nmt(fx_t *fx, co_nmt_command_t cmd)
{
    const uint8_t d[2] = {(uint8_t)cmd, ID};
    peer(fx, 0, d, 2);
}

static void sync_frame(fx_t *fx) { peer(fx, SYNC_ID, NULL, 0); }

static void rpdo(fx_t *fx, uint32_t id, uint8_t len)
{
    static const uint8_t d[8] = {0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x07, 0x08};
    peer(fx, id, d, len);
}

static void rtr(fx_t *fx)
{
    co_frame_t f = tu_frame(0x700 + ID, CO_FRAME_RTR, NULL, 1);
    assert_true(co_line_send_raw(fx->p, &f));
    step(fx);
}

/* Network write (SDO-server path) at the current time. */
static uint32_t net_write(fx_t *fx, uint16_t index, uint8_t sub, uint32_t value, uint32_t len)
{
    uint8_t scratch[8], b[4];
    co_od_xfer_t x;
    uint32_t r;
    co_line_set_time(fx->n, fx->tb.now);
    tu_le_put(b, value, len);
    co_od_xfer_init(&x, scratch, sizeof scratch);
    r = co_od_write_begin(&fx->od, &x, index, sub, len);
    if (r == 0)
        r = co_od_write_chunk(&x, b, len);
    if (r == 0)
        r = co_od_write_end(&x);
    return r;
}

static uint32_t od_u32(fx_t *fx, uint16_t index)
{
    uint32_t v = 0;
    assert_true(co_od_get_u32(&fx->od, index, 0, &v));
    return v;
}

/* Index of the k-th data frame (not a remote frame) on 0x700 + ID: boot-up
 * and guarding answers. */
static long ec_frame(const fx_t *fx, size_t k)
{
    size_t i;
    for (i = 0; i < fx->tb.log_count; i++) {
        const co_frame_t *f = &fx->tb.log[i].frame;
        if (f->id == 0x700 + ID && !(f->flags & CO_FRAME_RTR) && k-- == 0)
            return (long)i;
    }
    return -1;
}

static size_t count(const fx_t *fx, uint32_t id) { return tu_log_count_id(&fx->tb, id); }

static void clear_log(fx_t *fx) { tu_log_clear(&fx->tb); }

/* Classic EMCY k (0-based) in the log: EEC, error register, msef[0..1]. */
static void assert_emcy(const fx_t *fx, size_t k, uint16_t code, uint8_t reg, uint16_t info)
{
    const uint8_t want[8] = {(uint8_t)code, (uint8_t)(code >> 8), reg, (uint8_t)info,
                             (uint8_t)(info >> 8), 0, 0, 0};
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, EMCY_ID, k), EMCY_ID, want, 8);
}

/* The error reset EMCY (classic): EEC 0, register after the clear, msef 0. */
static void assert_reset(const fx_t *fx, size_t k, uint8_t reg) { assert_emcy(fx, k, 0, reg, 0); }

/* The TPDO trigger of the application at the current time. */
static bool trigger(fx_t *fx, uint16_t n)
{
    bool ok;
    co_line_set_time(fx->n, fx->tb.now);
    ok = co_pdo_trigger(&fx->pdo, n);
    step(fx);
    return ok;
}

static void start(fx_t *fx)
{
    nmt(fx, CO_NMT_CMD_START);
    assert_int_equal(co_node_state(&fx->node), CO_NMT_OPERATIONAL);
}

/* ================================================================ 1. NMT */

/* An event TPDO goes out on trigger only in operational; RPDO data are
 * applied only in operational. */
static void test_nmt_pdo_only_operational(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC, 0);
    const uint8_t t1[1] = {0x11};
    clear_log(fx);
    assert_false(trigger(fx, 1));                   /* pre-operational */
    rpdo(fx, RPDO1_ID, 4);
    assert_int_equal(od_u32(fx, 0x2002), 0x33333333u);
    assert_int_equal(count(fx, TPDO1_ID), 0);

    start(fx);
    assert_true(trigger(fx, 1));
    assert_int_equal(count(fx, TPDO1_ID), 1);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, TPDO1_ID, 0), TPDO1_ID, t1, 1);
    rpdo(fx, RPDO1_ID, 4);
    assert_int_equal(od_u32(fx, 0x2002), 0x04030201u);

    nmt(fx, CO_NMT_CMD_STOP);
    assert_int_equal(co_node_state(&fx->node), CO_NMT_STOPPED);
    assert_true(co_od_put(&fx->od, 0x2002, 0, (const uint8_t *)"\0\0\0\0", 4) == 0);
    assert_false(trigger(fx, 1));
    rpdo(fx, RPDO1_ID, 4);
    assert_int_equal(od_u32(fx, 0x2002), 0);
    nmt(fx, CO_NMT_CMD_PRE_OPERATIONAL);
    assert_false(trigger(fx, 1));
    rpdo(fx, RPDO1_ID, 4);
    assert_int_equal(od_u32(fx, 0x2002), 0);
    assert_int_equal(count(fx, TPDO1_ID), 1);
    assert_int_equal(count(fx, EMCY_ID), 0);
    fx_free(fx);
}

/* EMCY goes out in pre-operational and operational; in stopped it waits and
 * leaves when the node leaves stopped. */
static void test_nmt_emcy_states(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC, 1);   /* 1: bus-off changes no state */
    clear_log(fx);
    co_node_comm_event(&fx->node, CO_COMM_ERROR_PASSIVE);
    step(fx);
    assert_int_equal(count(fx, EMCY_ID), 1);
    assert_emcy(fx, 0, 0x8120, 0x11, 0);
    co_node_comm_event(&fx->node, CO_COMM_ERROR_ACTIVE);
    step(fx);
    assert_reset(fx, 1, 0x00);

    start(fx);
    co_node_comm_event(&fx->node, CO_COMM_BUS_OFF);
    step(fx);
    assert_emcy(fx, 2, 0x8140, 0x11, 0);
    assert_int_equal(co_node_state(&fx->node), CO_NMT_OPERATIONAL);

    nmt(fx, CO_NMT_CMD_STOP);
    co_node_comm_event(&fx->node, CO_COMM_BUS_OFF_RECOVERED);
    co_node_comm_event(&fx->node, CO_COMM_ERROR_PASSIVE);
    at(fx, MS(100));
    assert_int_equal(count(fx, EMCY_ID), 3);          /* waiting */
    assert_true(co_emcy_is_active(&fx->emcy, 0x8120, 0));
    assert_false(co_emcy_is_active(&fx->emcy, 0x8140, 0));
    nmt(fx, CO_NMT_CMD_PRE_OPERATIONAL);
    assert_int_equal(count(fx, EMCY_ID), 5);          /* in order */
    assert_reset(fx, 3, 0x00);
    assert_emcy(fx, 4, 0x8120, 0x11, 0);
    fx_free(fx);
}

/* SYNC is produced and TIME can be sent only in pre-operational and
 * operational. */
static void test_nmt_sync_time_states(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC, 0);
    const co_time_of_day_t tod = {0x01020304u, 0x0506};
    const uint8_t time_bytes[6] = {0x04, 0x03, 0x02, 0x01, 0x06, 0x05};
    long i;
    assert_int_equal(net_write(fx, 0x1006, 0, 10000, 4), 0);
    assert_int_equal(net_write(fx, 0x1005, 0, 0x40000000u | SYNC_ID, 4), 0);
    clear_log(fx);
    at(fx, MS(35));
    assert_int_equal(count(fx, SYNC_ID), 3);           /* 10, 20, 30 ms */
    i = tu_log_find_id(&fx->tb, SYNC_ID, 0);
    tu_assert_logged(&fx->tb, i, SYNC_ID, NULL, 0);
    assert_true(fx->tb.log[i].t_us == MS(10));
    assert_true(co_time_send(&fx->time, &tod));
    step(fx);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, TIME_ID, 0), TIME_ID, time_bytes, 6);

    start(fx);
    at(fx, MS(45));
    assert_int_equal(count(fx, SYNC_ID), 4);
    assert_true(co_time_send(&fx->time, &tod));
    step(fx);
    assert_int_equal(count(fx, TIME_ID), 2);

    nmt(fx, CO_NMT_CMD_STOP);
    at(fx, MS(100));
    assert_int_equal(count(fx, SYNC_ID), 4);
    assert_false(co_time_send(&fx->time, &tod));
    step(fx);
    assert_int_equal(count(fx, TIME_ID), 2);

    nmt(fx, CO_NMT_CMD_PRE_OPERATIONAL);   /* production restarts one period later */
    at(fx, MS(109));
    assert_int_equal(count(fx, SYNC_ID), 4);
    at(fx, MS(110));
    assert_int_equal(count(fx, SYNC_ID), 5);
    assert_true(co_time_send(&fx->time, &tod));
    step(fx);
    assert_int_equal(count(fx, TIME_ID), 3);
    fx_free(fx);
}

/* ========================================================== 2. SYNC -> PDO */

/* A received SYNC sends the synchronous TPDO (type 1), right after it, in
 * operational only. */
static void test_sync_received_sends_tpdo(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC, 0);
    const uint8_t t2[2] = {0x22, 0x22};
    clear_log(fx);
    sync_frame(fx);                        /* pre-operational: no PDO */
    assert_int_equal(count(fx, TPDO2_ID), 0);
    start(fx);
    at(fx, MS(5));
    assert_int_equal(count(fx, TPDO2_ID), 0);   /* not without a SYNC */
    sync_frame(fx);
    assert_int_equal(count(fx, TPDO2_ID), 1);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, TPDO2_ID, 0), TPDO2_ID, t2, 2);
    assert_true(tu_log_find_id(&fx->tb, TPDO2_ID, 0) > tu_log_find_id(&fx->tb, SYNC_ID, 1));
    sync_frame(fx);
    assert_int_equal(count(fx, TPDO2_ID), 2);
    fx_free(fx);
}

/* The node's own SYNC (0x1005 bit 30, 0x1006) drives its synchronous TPDO. */
static void test_sync_produced_sends_tpdo(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_FD, 0);
    const uint8_t t2[2] = {0x22, 0x22};
    long i;
    start(fx);
    assert_int_equal(net_write(fx, 0x1006, 0, 10000, 4), 0);
    assert_int_equal(net_write(fx, 0x1005, 0, 0x40000000u | SYNC_ID, 4), 0);
    clear_log(fx);
    at(fx, MS(31));
    assert_int_equal(count(fx, SYNC_ID), 3);
    assert_int_equal(count(fx, TPDO2_ID), 3);
    for (size_t k = 0; k < 3; k++) {
        i = tu_log_find_id(&fx->tb, TPDO2_ID, k);
        tu_assert_logged(&fx->tb, i, TPDO2_ID, t2, 2);
        assert_true(fx->tb.log[i].t_us == MS(10 * (k + 1)));
        assert_true(i == tu_log_find_id(&fx->tb, SYNC_ID, k) + 1);
    }
    fx_free(fx);
}

/* Fill the node's tx queue, hand it a SYNC and process it alone: the
 * synchronous TPDO is sampled but cannot be queued. */
static void sync_with_full_tx(fx_t *fx)
{
    co_frame_t filler = tu_frame(0x7E0, 0, NULL, 0);
    co_frame_t s = tu_frame(SYNC_ID, 0, NULL, 0);
    uint32_t sent = co_pdo_stats(&fx->pdo)->tx_frames;
    while (co_line_send_raw(fx->n, &filler)) {
    }
    assert_true(co_line_receive(fx->n, &s));
    co_line_process(fx->n, fx->tb.now);
    assert_int_equal(co_pdo_stats(&fx->pdo)->tx_frames, sent);
    assert_int_equal(fx->sync.stats.received, 1 + (sent != 0));
}

/* 0x1007: a synchronous TPDO still unsent when the window closes is dropped
 * (counted); sent late while the window is open. */
static void test_sync_window_drops_late_tpdo(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC, 0);
    assert_int_equal(net_write(fx, 0x1007, 0, 1000, 4), 0);   /* 1 ms */
    start(fx);
    at(fx, MS(10));
    clear_log(fx);
    /* the tx queue drains inside the window: the TPDO goes out late */
    sync_with_full_tx(fx);
    at(fx, MS(10));
    assert_int_equal(count(fx, TPDO2_ID), 1);
    assert_int_equal(co_pdo_stats(&fx->pdo)->sync_window_drops, 0);

    /* the window closes first: dropped */
    at(fx, MS(20));
    clear_log(fx);
    sync_with_full_tx(fx);
    co_line_process(fx->n, MS(20) + 1000);   /* window closes, queue still full */
    assert_int_equal(co_pdo_stats(&fx->pdo)->sync_window_drops, 1);
    at(fx, MS(30));
    assert_int_equal(count(fx, TPDO2_ID), 0);
    assert_int_equal(co_pdo_stats(&fx->pdo)->tx_frames, 1);
    fx_free(fx);
}

/* ====================================================== 3. errors to EMCY */

/* RPDO shorter than its mapping: 0x8210 (msef = PDO number, register
 * communication + generic), once; a frame of the right length: error reset. */
static void test_rpdo_short_classic(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC, 0);
    start(fx);
    clear_log(fx);
    rpdo(fx, RPDO1_ID, 3);
    assert_int_equal(count(fx, EMCY_ID), 1);
    assert_emcy(fx, 0, 0x8210, 0x11, 1);
    assert_int_equal(co_emcy_error_register(&fx->emcy), 0x11);
    assert_int_equal(od_u32(fx, 0x2002), 0x33333333u);   /* ignored */
    rpdo(fx, RPDO1_ID, 1);
    assert_int_equal(count(fx, EMCY_ID), 1);
    rpdo(fx, RPDO1_ID, 4);
    assert_int_equal(od_u32(fx, 0x2002), 0x04030201u);
    assert_int_equal(count(fx, EMCY_ID), 2);
    assert_reset(fx, 1, 0x00);
    assert_int_equal(co_emcy_error_register(&fx->emcy), 0);
    rpdo(fx, RPDO1_ID, 4);
    assert_int_equal(count(fx, EMCY_ID), 2);
    fx_free(fx);
}

/* FD 0x8210 of RPDO 1: the 20-byte EMCY raised (spec 301, status occurred)
 * and its "removed" EMCY (status 0, register 0). */
static const uint8_t fd_short_raised[20] = {0x10, 0x82, 0x11, 0x01, 0x00, 0, 0, 0,
                                            0x00, 0x2D, 0x01, 0x10, 0, 0, 0, 0, 0, 0, 0, 0};
static const uint8_t fd_short_removed[20] = {0x10, 0x82, 0x00, 0x00, 0x00, 0, 0, 0,
                                             0x00, 0x2D, 0x01, 0x00, 0, 0, 0, 0, 0, 0, 0, 0};

/* An FD node whose RPDO 1 got a 2-byte frame: 0x8210 raised, exact bytes. */
static fx_t *fd_rpdo_short_raised(void)
{
    fx_t *fx = fx_new(CO_MODE_FD, 0);
    start(fx);
    clear_log(fx);
    rpdo(fx, RPDO1_ID, 2);
    assert_int_equal(count(fx, EMCY_ID), 1);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, EMCY_ID, 0), EMCY_ID, fd_short_raised, 20);
    return fx;
}

/* The same on an FD bus: the 20-byte EMCY (spec 301, status occurred), and
 * its "removed" EMCY (status 0, register 0). */
static void test_rpdo_short_fd(void **state)
{
    (void)state;
    fx_t *fx = fd_rpdo_short_raised();
    rpdo(fx, RPDO1_ID, 4);
    assert_int_equal(count(fx, EMCY_ID), 2);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, EMCY_ID, 1), EMCY_ID, fd_short_removed, 20);
    assert_int_equal(od_u32(fx, 0x2002), 0x04030201u);
    fx_free(fx);
}

/* RPDO deadline (event timer of the RPDO) missed: 0x8250; cleared when the
 * RPDO arrives again. */
static void test_rpdo_deadline(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC, 0);
    long i;
    assert_int_equal(net_write(fx, 0x1400, 5, 100, 2), 0);
    start(fx);
    clear_log(fx);
    at(fx, MS(10));
    rpdo(fx, RPDO1_ID, 4);                 /* monitoring starts */
    at(fx, MS(109));
    assert_int_equal(count(fx, EMCY_ID), 0);
    at(fx, MS(110));
    assert_int_equal(count(fx, EMCY_ID), 1);
    i = tu_log_find_id(&fx->tb, EMCY_ID, 0);
    assert_true(fx->tb.log[i].t_us == MS(110));
    assert_emcy(fx, 0, 0x8250, 0x11, 1);
    at(fx, MS(400));
    assert_int_equal(count(fx, EMCY_ID), 1);     /* once */
    rpdo(fx, RPDO1_ID, 4);
    assert_int_equal(count(fx, EMCY_ID), 2);
    assert_reset(fx, 1, 0x00);
    assert_false(co_emcy_is_active(&fx->emcy, 0x8250, 0));
    fx_free(fx);
}

/* RPDO 1 with a 100 ms deadline, one frame at 0, missed at 100 ms: 0x8250 sent. */
static fx_t *rpdo_deadline_missed(void)
{
    fx_t *fx = fx_new(CO_MODE_CLASSIC, 0);
    assert_int_equal(net_write(fx, 0x1400, 5, 100, 2), 0);
    start(fx);
    clear_log(fx);
    rpdo(fx, RPDO1_ID, 4);
    at(fx, MS(100));
    assert_int_equal(count(fx, EMCY_ID), 1);
    assert_emcy(fx, 0, 0x8250, 0x11, 1);
    return fx;
}

/* The deadline error stays cleared-able across an NMT state change: the RPDO
 * that comes back after pre-operational -> operational ends it too. */
static void test_rpdo_deadline_across_state_change(void **state)
{
    (void)state;
    fx_t *fx = rpdo_deadline_missed();
    nmt(fx, CO_NMT_CMD_PRE_OPERATIONAL);
    start(fx);
    at(fx, MS(150));
    rpdo(fx, RPDO1_ID, 4);
    assert_int_equal(count(fx, EMCY_ID), 2);
    assert_reset(fx, 1, 0x00);
    assert_false(co_emcy_is_active(&fx->emcy, 0x8250, 0));
    fx_free(fx);
}

/* A synchronous RPDO (type 0) whose deadline was missed: the error ends
 * when the frame is received again (co_pdo's RECEIVED_AGAIN), not only when
 * its data are applied at the next SYNC. */
static void test_rpdo_deadline_synchronous(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC, 0);
    assert_int_equal(net_write(fx, 0x1401, 1, 0x80000000u | RPDO2_ID, 4), 0);
    assert_int_equal(net_write(fx, 0x1401, 2, 0, 1), 0);
    assert_int_equal(net_write(fx, 0x1401, 5, 100, 2), 0);
    assert_int_equal(net_write(fx, 0x1401, 1, RPDO2_ID, 4), 0);
    start(fx);
    clear_log(fx);
    rpdo(fx, RPDO2_ID, 2);
    at(fx, MS(100));
    assert_int_equal(count(fx, EMCY_ID), 1);
    assert_emcy(fx, 0, 0x8250, 0x11, 2);
    at(fx, MS(150));
    rpdo(fx, RPDO2_ID, 2);
    assert_int_equal(count(fx, EMCY_ID), 2);
    assert_reset(fx, 1, 0x00);
    {
        uint16_t v = 0;
        assert_true(co_od_get_u16(&fx->od, 0x2004, 0, &v));
        assert_int_equal(v, 0x4444);        /* applied at the next SYNC only */
        assert_int_equal(co_pdo_stats(&fx->pdo)->rx_frames, 0);
        sync_frame(fx);
        assert_int_equal(co_pdo_stats(&fx->pdo)->rx_frames, 1);
        assert_true(co_od_get_u16(&fx->od, 0x2004, 0, &v));
        assert_int_equal(v, 0x0201);
        assert_int_equal(count(fx, EMCY_ID), 2);
    }
    fx_free(fx);
}

/* SYNC of a wrong length (0x1019 = 0 wants 0 bytes): 0x8240 with the length
 * in msef[0], once; the next good SYNC clears it. */
static void test_sync_length_error(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC, 0);
    const uint8_t one[2] = {0x01, 0x02};
    clear_log(fx);
    peer(fx, SYNC_ID, one, 1);
    assert_int_equal(count(fx, EMCY_ID), 1);
    assert_emcy(fx, 0, 0x8240, 0x11, 1);
    peer(fx, SYNC_ID, one, 2);
    assert_int_equal(count(fx, EMCY_ID), 1);
    assert_int_equal(fx->sync.stats.bad_length, 2);
    sync_frame(fx);
    assert_int_equal(count(fx, EMCY_ID), 2);
    assert_reset(fx, 1, 0x00);
    sync_frame(fx);
    assert_int_equal(count(fx, EMCY_ID), 2);
    fx_free(fx);
}

/* RPDO longer than its mapping (classic): 0x8220, the data applied; the
 * same frame's "received" does not end it, the next good-length one does. */
static void test_rpdo_long(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC, 0);
    start(fx);
    clear_log(fx);
    rpdo(fx, RPDO1_ID, 6);
    assert_int_equal(count(fx, EMCY_ID), 1);
    assert_emcy(fx, 0, 0x8220, 0x11, 1);
    assert_int_equal(od_u32(fx, 0x2002), 0x04030201u);
    rpdo(fx, RPDO1_ID, 8);
    assert_int_equal(count(fx, EMCY_ID), 1);
    rpdo(fx, RPDO1_ID, 4);
    assert_int_equal(count(fx, EMCY_ID), 2);
    assert_reset(fx, 1, 0x00);
    fx_free(fx);
}

/* Two RPDOs in 0x8210: one EMCY (classic), cleared only when both got a
 * good frame. */
static void test_two_rpdos_short(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC, 0);
    start(fx);
    clear_log(fx);
    rpdo(fx, RPDO1_ID, 2);
    rpdo(fx, RPDO2_ID, 1);
    assert_int_equal(count(fx, EMCY_ID), 1);
    assert_emcy(fx, 0, 0x8210, 0x11, 1);
    rpdo(fx, RPDO1_ID, 4);
    assert_int_equal(count(fx, EMCY_ID), 1);
    assert_true(co_emcy_is_active(&fx->emcy, 0x8210, 0));
    rpdo(fx, RPDO1_ID, 3);                  /* short again: already active */
    rpdo(fx, RPDO1_ID, 4);
    assert_int_equal(count(fx, EMCY_ID), 1);
    rpdo(fx, RPDO2_ID, 2);
    assert_int_equal(count(fx, EMCY_ID), 2);
    assert_reset(fx, 1, 0x00);
    assert_false(co_emcy_is_active(&fx->emcy, 0x8210, 0));
    fx_free(fx);
}

/* 0x1001, the error register as the network reads it. */
static uint8_t error_register_od(fx_t *fx)
{
    uint8_t v = 0xFF;
    assert_true(co_od_get_u8(&fx->od, 0x1001, 0, &v));
    return v;
}

/* An RPDO in 0x8210 switched off by the network (COB-ID bit 31, as the
 * CiA 301 mapping procedure starts): the error reset goes out at once and
 * 0x1001 drops the bit; re-mapping and validating it tell nothing more, the
 * new mapping's errors are told as before. */
static void test_rpdo_short_cleared_when_disabled(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC, 0);
    start(fx);
    clear_log(fx);
    rpdo(fx, RPDO1_ID, 3);
    assert_int_equal(count(fx, EMCY_ID), 1);
    assert_emcy(fx, 0, 0x8210, 0x11, 1);
    assert_int_equal(error_register_od(fx), 0x11);
    assert_int_equal(net_write(fx, 0x1400, 1, 0x80000000u | RPDO1_ID, 4), 0);
    step(fx);
    assert_int_equal(count(fx, EMCY_ID), 2);
    assert_reset(fx, 1, 0x00);
    assert_int_equal(error_register_od(fx), 0x00);
    assert_false(co_emcy_is_active(&fx->emcy, 0x8210, 0));
    assert_int_equal(co_emcy_active_count(&fx->emcy), 0);
    rpdo(fx, RPDO1_ID, 3);                      /* off: not ours any more */
    assert_int_equal(net_write(fx, 0x1600, 0, 0, 1), 0);
    assert_int_equal(net_write(fx, 0x1600, 1, MAP(0x2004, 0, 16), 4), 0);
    assert_int_equal(net_write(fx, 0x1600, 0, 1, 1), 0);
    assert_int_equal(net_write(fx, 0x1400, 1, RPDO1_ID, 4), 0);
    step(fx);
    assert_int_equal(count(fx, EMCY_ID), 2);
    rpdo(fx, RPDO1_ID, 1);
    assert_int_equal(count(fx, EMCY_ID), 3);
    assert_emcy(fx, 2, 0x8210, 0x11, 1);
    rpdo(fx, RPDO1_ID, 2);
    assert_int_equal(count(fx, EMCY_ID), 4);
    assert_reset(fx, 3, 0x00);
    assert_int_equal(error_register_od(fx), 0x00);
    {
        uint16_t v = 0;
        assert_true(co_od_get_u16(&fx->od, 0x2004, 0, &v));
        assert_int_equal(v, 0x0201);
    }
    fx_free(fx);
}

/* The same on an FD bus: the "removed" EMCY of 0x8210 (status 0, register 0). */
static void test_rpdo_short_cleared_when_disabled_fd(void **state)
{
    (void)state;
    fx_t *fx = fd_rpdo_short_raised();
    assert_int_equal(net_write(fx, 0x1400, 1, 0x80000000u | RPDO1_ID, 4), 0);
    step(fx);
    assert_int_equal(count(fx, EMCY_ID), 2);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, EMCY_ID, 1), EMCY_ID, fd_short_removed, 20);
    assert_int_equal(error_register_od(fx), 0x00);
    fx_free(fx);
}

/* 0x8250: kept when the node goes pre-operational, cleared when the master
 * then switches the RPDO off; validated again, it has no deadline until its
 * first frame. Missed again, switching the deadline off (sub 5 = 0) clears
 * it too. */
static void test_rpdo_deadline_cleared_when_disabled(void **state)
{
    (void)state;
    fx_t *fx = rpdo_deadline_missed();
    assert_int_equal(error_register_od(fx), 0x11);
    nmt(fx, CO_NMT_CMD_PRE_OPERATIONAL);
    assert_int_equal(count(fx, EMCY_ID), 1);
    assert_true(co_emcy_is_active(&fx->emcy, 0x8250, 0));
    at(fx, MS(150));
    assert_int_equal(net_write(fx, 0x1400, 1, 0x80000000u | RPDO1_ID, 4), 0);
    step(fx);
    assert_int_equal(count(fx, EMCY_ID), 2);
    assert_reset(fx, 1, 0x00);
    assert_true(fx->tb.log[tu_log_find_id(&fx->tb, EMCY_ID, 1)].t_us == MS(150));
    assert_int_equal(error_register_od(fx), 0x00);
    assert_false(co_emcy_is_active(&fx->emcy, 0x8250, 0));
    assert_int_equal(net_write(fx, 0x1400, 1, RPDO1_ID, 4), 0);
    start(fx);
    at(fx, MS(500));
    assert_int_equal(count(fx, EMCY_ID), 2);
    rpdo(fx, RPDO1_ID, 4);
    at(fx, MS(600));
    assert_int_equal(count(fx, EMCY_ID), 3);
    assert_emcy(fx, 2, 0x8250, 0x11, 1);
    assert_int_equal(net_write(fx, 0x1400, 5, 0, 2), 0);
    step(fx);
    assert_int_equal(count(fx, EMCY_ID), 4);
    assert_reset(fx, 3, 0x00);
    assert_int_equal(error_register_od(fx), 0x00);
    fx_free(fx);
}

/* Two RPDOs in 0x8210, one switched off: the error stays (no EMCY, 0x1001
 * keeps the bit) until the other gets a good frame. */
static void test_two_rpdos_short_one_disabled(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC, 0);
    start(fx);
    clear_log(fx);
    rpdo(fx, RPDO1_ID, 2);
    rpdo(fx, RPDO2_ID, 1);
    assert_int_equal(count(fx, EMCY_ID), 1);
    assert_emcy(fx, 0, 0x8210, 0x11, 1);
    assert_int_equal(net_write(fx, 0x1400, 1, 0x80000000u | RPDO1_ID, 4), 0);
    step(fx);
    assert_int_equal(count(fx, EMCY_ID), 1);
    assert_true(co_emcy_is_active(&fx->emcy, 0x8210, 0));
    assert_int_equal(error_register_od(fx), 0x11);
    rpdo(fx, RPDO2_ID, 1);
    assert_int_equal(count(fx, EMCY_ID), 1);
    rpdo(fx, RPDO2_ID, 2);
    assert_int_equal(count(fx, EMCY_ID), 2);
    assert_reset(fx, 1, 0x00);
    assert_int_equal(error_register_od(fx), 0x00);
    assert_false(co_emcy_is_active(&fx->emcy, 0x8210, 0));
    fx_free(fx);
}

/* 0x8220 then a short frame: 0x8210 is raised before 0x8220 is cleared (the
 * register keeps its bit in between); a good frame clears 0x8210. */
static void test_rpdo_long_then_short(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC, 0);
    start(fx);
    clear_log(fx);
    rpdo(fx, RPDO1_ID, 6);
    assert_int_equal(count(fx, EMCY_ID), 1);
    assert_emcy(fx, 0, 0x8220, 0x11, 1);
    rpdo(fx, RPDO1_ID, 2);
    assert_int_equal(count(fx, EMCY_ID), 3);
    assert_emcy(fx, 1, 0x8210, 0x11, 1);
    assert_reset(fx, 2, 0x11);
    assert_false(co_emcy_is_active(&fx->emcy, 0x8220, 0));
    assert_true(co_emcy_is_active(&fx->emcy, 0x8210, 0));
    rpdo(fx, RPDO1_ID, 4);
    assert_int_equal(count(fx, EMCY_ID), 4);
    assert_reset(fx, 3, 0x00);
    assert_int_equal(co_emcy_active_count(&fx->emcy), 0);
    fx_free(fx);
}

/* ============================================== 4. heartbeat / life guarding */

/* Lost heartbeat of node 7 in operational with 0x1029:01 = behaviour. */
static fx_t *lost_heartbeat(uint8_t behaviour)
{
    fx_t *fx = fx_new(CO_MODE_CLASSIC, behaviour);
    start(fx);
    assert_true(trigger(fx, 1));
    clear_log(fx);
    co_node_heartbeat_event(&fx->node, 7, true);
    step(fx);
    assert_int_equal(count(fx, EMCY_ID), 1);
    assert_emcy(fx, 0, 0x8130, 0x11, 7);
    return fx;
}

static void test_heartbeat_lost_behaviour_0(void **state)
{
    (void)state;
    fx_t *fx = lost_heartbeat(0);
    assert_int_equal(co_node_state(&fx->node), CO_NMT_PRE_OPERATIONAL);
    assert_false(trigger(fx, 1));
    sync_frame(fx);
    assert_int_equal(count(fx, TPDO1_ID) + count(fx, TPDO2_ID), 0);
    fx_free(fx);
}

static void test_heartbeat_lost_behaviour_1(void **state)
{
    (void)state;
    fx_t *fx = lost_heartbeat(1);
    assert_int_equal(co_node_state(&fx->node), CO_NMT_OPERATIONAL);
    assert_true(trigger(fx, 1));
    assert_int_equal(count(fx, TPDO1_ID), 1);
    fx_free(fx);
}

static void test_heartbeat_lost_behaviour_2(void **state)
{
    (void)state;
    fx_t *fx = lost_heartbeat(2);
    assert_int_equal(co_node_state(&fx->node), CO_NMT_STOPPED);
    assert_false(trigger(fx, 1));
    fx_free(fx);
}

static void test_heartbeat_lost_no_1029(void **state)
{
    (void)state;
    fx_t *fx = lost_heartbeat(NO_1029);
    assert_int_equal(co_node_state(&fx->node), CO_NMT_PRE_OPERATIONAL);
    assert_false(trigger(fx, 1));
    fx_free(fx);
}

/* A second lost node sends no second 0x8130 (classic); the error clears only
 * when both are back. */
static void test_heartbeat_two_lost(void **state)
{
    (void)state;
    fx_t *fx = lost_heartbeat(1);
    co_node_heartbeat_event(&fx->node, 9, true);
    co_node_heartbeat_event(&fx->node, 9, true);   /* repeated: nothing */
    step(fx);
    assert_int_equal(count(fx, EMCY_ID), 1);
    co_node_heartbeat_event(&fx->node, 7, false);
    step(fx);
    assert_int_equal(count(fx, EMCY_ID), 1);
    assert_true(co_emcy_is_active(&fx->emcy, 0x8130, 0));
    co_node_heartbeat_event(&fx->node, 9, false);
    step(fx);
    assert_int_equal(count(fx, EMCY_ID), 2);
    assert_reset(fx, 1, 0x00);
    co_node_heartbeat_event(&fx->node, 9, false);
    co_node_heartbeat_event(&fx->node, 0, true);    /* bad node-ids: ignored */
    co_node_heartbeat_event(&fx->node, 128, true);
    step(fx);
    assert_int_equal(count(fx, EMCY_ID), 2);
    fx_free(fx);
}

/* On FD a second lost node sends 0x8130 again (status "occurred more than
 * once", msef = the new node); the removal EMCY only after both are back. */
static void test_heartbeat_two_lost_fd(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_FD, 1);
    static const uint8_t first[20] = {0x30, 0x81, 0x11, 0x07, 0x00, 0, 0, 0,
                                      0x00, 0x2D, 0x01, 0x10, 0, 0, 0, 0, 0, 0, 0, 0};
    static const uint8_t again[20] = {0x30, 0x81, 0x11, 0x09, 0x00, 0, 0, 0,
                                      0x00, 0x2D, 0x01, 0x30, 0, 0, 0, 0, 0, 0, 0, 0};
    static const uint8_t removed[20] = {0x30, 0x81, 0x00, 0x00, 0x00, 0, 0, 0,
                                        0x00, 0x2D, 0x01, 0x00, 0, 0, 0, 0, 0, 0, 0, 0};
    clear_log(fx);
    co_node_heartbeat_event(&fx->node, 7, true);
    co_node_heartbeat_event(&fx->node, 9, true);
    co_node_heartbeat_event(&fx->node, 7, false);
    step(fx);
    assert_int_equal(count(fx, EMCY_ID), 2);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, EMCY_ID, 0), EMCY_ID, first, 20);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, EMCY_ID, 1), EMCY_ID, again, 20);
    co_node_heartbeat_event(&fx->node, 9, false);
    step(fx);
    assert_int_equal(count(fx, EMCY_ID), 3);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, EMCY_ID, 2), EMCY_ID, removed, 20);
    fx_free(fx);
}

/* Life guarding (0x100C x 0x100D after the first remote frame): LOST raises
 * 0x8130 with the own node-id and applies 0x1029:01; RESOLVED (a remote
 * frame) clears it; a lost heartbeat keeps it active until it is back. */
static void test_life_guarding(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC, 0);
    const uint8_t op[1] = {0x05};
    assert_int_equal(net_write(fx, 0x100C, 0, 100, 2), 0);
    assert_int_equal(net_write(fx, 0x100D, 0, 2, 1), 0);
    start(fx);
    clear_log(fx);
    rtr(fx);
    tu_assert_logged(&fx->tb, ec_frame(fx, 0), 0x700 + ID, op, 1);
    at(fx, MS(199));
    assert_int_equal(count(fx, EMCY_ID), 0);
    at(fx, MS(200));
    assert_int_equal(count(fx, EMCY_ID), 1);
    assert_emcy(fx, 0, 0x8130, 0x11, ID);
    assert_int_equal(co_node_state(&fx->node), CO_NMT_PRE_OPERATIONAL);
    co_node_heartbeat_event(&fx->node, 7, true);   /* same error: nothing */
    step(fx);
    assert_int_equal(count(fx, EMCY_ID), 1);
    rtr(fx);                                        /* life guarding resolved */
    assert_int_equal(count(fx, EMCY_ID), 1);
    co_node_heartbeat_event(&fx->node, 7, false);
    step(fx);
    assert_int_equal(count(fx, EMCY_ID), 2);
    assert_reset(fx, 1, 0x00);

    /* the other order: life guarding lost again, a heartbeat lost; the
     * heartbeat back does not clear while life guarding is still lost */
    start(fx);
    at(fx, MS(500));
    assert_int_equal(count(fx, EMCY_ID), 3);
    assert_emcy(fx, 2, 0x8130, 0x11, ID);
    assert_int_equal(co_node_state(&fx->node), CO_NMT_PRE_OPERATIONAL);
    co_node_heartbeat_event(&fx->node, 9, true);
    co_node_heartbeat_event(&fx->node, 9, false);
    step(fx);
    assert_int_equal(count(fx, EMCY_ID), 3);
    assert_true(co_emcy_is_active(&fx->emcy, 0x8130, 0));
    rtr(fx);
    assert_int_equal(count(fx, EMCY_ID), 4);
    assert_reset(fx, 3, 0x00);
    fx_free(fx);
}

/* ============================================== 5. communication events */

static void test_comm_events(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC, 2);
    start(fx);
    clear_log(fx);
    co_node_comm_event(&fx->node, CO_COMM_BUS_OFF);
    step(fx);
    assert_emcy(fx, 0, 0x8140, 0x11, 0);
    assert_int_equal(co_node_state(&fx->node), CO_NMT_STOPPED);   /* 0x1029:01 = 2 */
    nmt(fx, CO_NMT_CMD_PRE_OPERATIONAL);
    co_node_comm_event(&fx->node, CO_COMM_BUS_OFF_RECOVERED);
    step(fx);
    assert_int_equal(count(fx, EMCY_ID), 2);
    assert_reset(fx, 1, 0x00);

    co_node_comm_event(&fx->node, CO_COMM_ERROR_PASSIVE);
    step(fx);
    assert_emcy(fx, 2, 0x8120, 0x11, 0);
    assert_int_equal(co_node_state(&fx->node), CO_NMT_PRE_OPERATIONAL);   /* no behaviour */
    co_node_comm_event(&fx->node, CO_COMM_ERROR_ACTIVE);
    step(fx);
    assert_int_equal(count(fx, EMCY_ID), 4);
    assert_reset(fx, 3, 0x00);

    at(fx, MS(1000));
    co_node_comm_event(&fx->node, CO_COMM_RX_OVERFLOW);
    step(fx);
    assert_int_equal(count(fx, EMCY_ID), 6);
    assert_emcy(fx, 4, 0x8110, 0x11, 0);
    assert_reset(fx, 5, 0x00);
    at(fx, MS(1999));
    co_node_comm_event(&fx->node, CO_COMM_RX_OVERFLOW);
    co_node_comm_event(&fx->node, CO_COMM_TX_OVERFLOW);
    step(fx);
    assert_int_equal(count(fx, EMCY_ID), 6);
    at(fx, MS(2000));
    co_node_comm_event(&fx->node, CO_COMM_RX_OVERFLOW);
    step(fx);
    assert_int_equal(count(fx, EMCY_ID), 8);
    assert_emcy(fx, 6, 0x8110, 0x11, 0);
    assert_reset(fx, 7, 0x00);
    co_node_comm_event(&fx->node, CO_COMM_TX_OVERFLOW);
    step(fx);
    assert_int_equal(count(fx, EMCY_ID), 8);
    assert_int_equal(co_node_state(&fx->node), CO_NMT_PRE_OPERATIONAL);
    fx_free(fx);
}

/* Error passive then bus-off: ERROR_ACTIVE clears both (one reset EMCY
 * each), the register ends at 0. */
static void test_comm_passive_then_bus_off(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC, 1);
    clear_log(fx);
    co_node_comm_event(&fx->node, CO_COMM_ERROR_PASSIVE);
    co_node_comm_event(&fx->node, CO_COMM_BUS_OFF);
    step(fx);
    assert_emcy(fx, 0, 0x8120, 0x11, 0);
    assert_emcy(fx, 1, 0x8140, 0x11, 0);
    co_node_comm_event(&fx->node, CO_COMM_ERROR_ACTIVE);
    step(fx);
    assert_int_equal(count(fx, EMCY_ID), 4);
    assert_reset(fx, 2, 0x11);
    assert_reset(fx, 3, 0x00);
    fx_free(fx);
}

/* ============================================================= 6. resets */

/* Reset communication: the TPDO mapping changed over the OD write path goes
 * back to its default, the node's detected errors are cleared, the guarding
 * toggle starts at 0 again. */
static void test_reset_communication(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC, 1);
    const uint8_t remapped[2] = {0x22, 0x22};
    const uint8_t dflt[1] = {0x11};
    const uint8_t boot[1] = {0x00};
    const uint8_t pre0[1] = {0x7F};
    const uint8_t op0[1] = {0x05}, op1[1] = {0x85};
    assert_int_equal(net_write(fx, 0x1800, 1, 0x80000000u | TPDO1_ID, 4), 0);
    assert_int_equal(net_write(fx, 0x1A00, 0, 0, 1), 0);
    assert_int_equal(net_write(fx, 0x1A00, 1, MAP(0x2001, 0, 16), 4), 0);
    assert_int_equal(net_write(fx, 0x1A00, 0, 1, 1), 0);
    assert_int_equal(net_write(fx, 0x1800, 1, TPDO1_ID, 4), 0);
    start(fx);
    clear_log(fx);
    assert_true(trigger(fx, 1));
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, TPDO1_ID, 0), TPDO1_ID, remapped, 2);
    rpdo(fx, RPDO1_ID, 2);
    co_node_heartbeat_event(&fx->node, 7, true);
    step(fx);
    assert_emcy(fx, 0, 0x8210, 0x11, 1);
    assert_emcy(fx, 1, 0x8130, 0x11, 7);
    rtr(fx);
    rtr(fx);
    rtr(fx);                              /* three answers: the next toggle is 1 */
    tu_assert_logged(&fx->tb, ec_frame(fx, 0), 0x700 + ID, op0, 1);
    tu_assert_logged(&fx->tb, ec_frame(fx, 1), 0x700 + ID, op1, 1);
    tu_assert_logged(&fx->tb, ec_frame(fx, 2), 0x700 + ID, op0, 1);

    clear_log(fx);
    nmt(fx, CO_NMT_CMD_RESET_COMMUNICATION);
    assert_int_equal(co_node_state(&fx->node), CO_NMT_PRE_OPERATIONAL);
    tu_assert_logged(&fx->tb, ec_frame(fx, 0), 0x700 + ID, boot, 1);
    assert_int_equal(co_emcy_active_count(&fx->emcy), 0);
    assert_int_equal(co_emcy_error_register(&fx->emcy), 0);
    assert_int_equal(count(fx, EMCY_ID), 2);    /* one reset EMCY per error */
    assert_reset(fx, 0, 0x11);
    assert_reset(fx, 1, 0x00);
    rtr(fx);
    tu_assert_logged(&fx->tb, ec_frame(fx, 1), 0x700 + ID, pre0, 1);
    {
        uint8_t n = 0;
        uint32_t m = 0;
        assert_true(co_od_get_u8(&fx->od, 0x1A00, 0, &n));
        assert_true(co_od_get_u32(&fx->od, 0x1A00, 1, &m));
        assert_int_equal(n, 1);
        assert_int_equal(m, MAP(0x2000, 0, 8));
    }
    start(fx);
    assert_true(trigger(fx, 1));
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, TPDO1_ID, 0), TPDO1_ID, dflt, 1);
    /* the errors start over: a new short RPDO and a lost node are told again */
    rpdo(fx, RPDO1_ID, 2);
    co_node_heartbeat_event(&fx->node, 7, true);
    step(fx);
    assert_emcy(fx, 2, 0x8210, 0x11, 1);
    assert_emcy(fx, 3, 0x8130, 0x11, 7);
    fx_free(fx);
}

/* Reset communication also reloads SYNC: a producer set over the OD stops
 * producing (0x1005 default: consumer of 0x80) and consumes SYNC again. */
static void test_reset_communication_sync(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC, 0);
    assert_int_equal(net_write(fx, 0x1006, 0, 10000, 4), 0);
    assert_int_equal(net_write(fx, 0x1005, 0, 0x40000000u | SYNC_ID, 4), 0);
    at(fx, MS(25));
    assert_int_equal(count(fx, SYNC_ID), 2);
    nmt(fx, CO_NMT_CMD_RESET_COMMUNICATION);
    clear_log(fx);
    at(fx, MS(100));
    assert_int_equal(count(fx, SYNC_ID), 0);
    assert_int_equal(od_u32(fx, 0x1005), SYNC_ID);
    start(fx);
    sync_frame(fx);
    assert_int_equal(count(fx, TPDO2_ID), 1);
    fx_free(fx);
}

/* ============================================================= 7. deinit */

static void test_deinit_removes_sync_listener(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC, 0);
    start(fx);
    clear_log(fx);
    sync_frame(fx);
    assert_int_equal(count(fx, TPDO2_ID), 1);
    co_node_deinit(&fx->node);
    fx->node_live = false;
    assert_int_equal(fx->sync.listener_count, 0);
    assert_true(fx->pdo.operational);   /* the PDO would still send at a SYNC */
    co_sync_set_nmt_state(&fx->sync, CO_NMT_OPERATIONAL);
    sync_frame(fx);
    assert_int_equal(fx->sync.stats.received, 2);
    assert_int_equal(count(fx, TPDO2_ID), 1);
    co_pdo_sync(&fx->pdo, 0);           /* (the control: a SYNC reaching it sends) */
    step(fx);
    assert_int_equal(count(fx, TPDO2_ID), 2);
    fx_free(fx);
}

/* ============================================================= robustness */

/* Random frames from the peer (NMT excluded) in operational: no crash, and
 * the wiring still works afterwards. */
static void test_random_frames(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC, 1);
    uint64_t seed = 0x1234567887654321ull;
    int i;
    start(fx);
    for (i = 0; i < 3000; i++) {
        uint8_t d[8];
        uint64_t r = tu_rand(&seed);
        uint32_t id = (uint32_t)(r % 0x7FF) + 1;
        uint8_t len = (uint8_t)((r >> 16) % 9);
        co_frame_t f;
        memcpy(d, &r, 8);
        if (i % 4 == 0)
            id = (i % 8 == 0) ? RPDO1_ID : SYNC_ID;
        f = tu_frame(id, 0, d, len);
        assert_true(co_line_send_raw(fx->p, &f));
        if (i % 16 == 0)
            at(fx, fx->tb.now + 1000);
    }
    at(fx, fx->tb.now + 1000);
    if (co_node_state(&fx->node) != CO_NMT_OPERATIONAL)
        start(fx);
    rpdo(fx, RPDO1_ID, 4);
    rpdo(fx, RPDO2_ID, 2);
    sync_frame(fx);
    clear_log(fx);
    sync_frame(fx);
    assert_int_equal(count(fx, TPDO2_ID), 1);
    assert_false(co_emcy_is_active(&fx->emcy, 0x8210, 0));
    assert_false(co_emcy_is_active(&fx->emcy, 0x8240, 0));
    fx_free(fx);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_nmt_pdo_only_operational),
        cmocka_unit_test(test_nmt_emcy_states),
        cmocka_unit_test(test_nmt_sync_time_states),
        cmocka_unit_test(test_sync_received_sends_tpdo),
        cmocka_unit_test(test_sync_produced_sends_tpdo),
        cmocka_unit_test(test_sync_window_drops_late_tpdo),
        cmocka_unit_test(test_rpdo_short_classic),
        cmocka_unit_test(test_rpdo_short_fd),
        cmocka_unit_test(test_rpdo_deadline),
        cmocka_unit_test(test_rpdo_deadline_across_state_change),
        cmocka_unit_test(test_rpdo_deadline_synchronous),
        cmocka_unit_test(test_sync_length_error),
        cmocka_unit_test(test_rpdo_long),
        cmocka_unit_test(test_two_rpdos_short),
        cmocka_unit_test(test_rpdo_short_cleared_when_disabled),
        cmocka_unit_test(test_rpdo_short_cleared_when_disabled_fd),
        cmocka_unit_test(test_rpdo_deadline_cleared_when_disabled),
        cmocka_unit_test(test_two_rpdos_short_one_disabled),
        cmocka_unit_test(test_rpdo_long_then_short),
        cmocka_unit_test(test_heartbeat_lost_behaviour_0),
        cmocka_unit_test(test_heartbeat_lost_behaviour_1),
        cmocka_unit_test(test_heartbeat_lost_behaviour_2),
        cmocka_unit_test(test_heartbeat_lost_no_1029),
        cmocka_unit_test(test_heartbeat_two_lost),
        cmocka_unit_test(test_heartbeat_two_lost_fd),
        cmocka_unit_test(test_life_guarding),
        cmocka_unit_test(test_comm_events),
        cmocka_unit_test(test_comm_passive_then_bus_off),
        cmocka_unit_test(test_reset_communication),
        cmocka_unit_test(test_reset_communication_sync),
        cmocka_unit_test(test_deinit_removes_sync_listener),
        cmocka_unit_test(test_random_frames),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
