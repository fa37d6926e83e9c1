/* PDO service (co_pdo) over the in-process bus on the fake clock.
 *
 * Lines: a (node 5, TPDOs), b (node 6, RPDOs: a's TPDOs are b's RPDOs),
 * r (no services: injects raw frames, RTRs, SYNC-less traffic). Each node
 * has its own OD (application objects 0x2000..0x2005 and the PDOs a test
 * adds), the COB-ID rule (co_cob_id) and a co_pdo. The sniffer checks the
 * CAN-ID, flags, length and every byte of each PDO on the bus. */
#include "test_od_util.h"

#include "co_cob_id.h"
#include "canopenfd/co_pdo.h"

#define ID_A 5
#define ID_B 6
#define MS(x) ((uint64_t)(x) * TU_MS)
#define MAP(i, s, bits) (((uint32_t)(i) << 16) | ((uint32_t)(s) << 8) | (uint32_t)(bits))
#define INVALID 0x80000000u
#define NO_RTR 0x40000000u
#define EXT 0x20000000u
#define MAX_REC 2048
#define BIG_ENTRIES 12000
#define SMALL_ENTRIES 400

#define BOTH (CO_OD_MAP_TPDO | CO_OD_MAP_RPDO)

/* ------------------------------------------------------------- fixture */

typedef struct err_rec {
    uint16_t code;
    bool is_rpdo;
    uint16_t number;
    uint64_t t;
} err_rec_t;

typedef struct rx_rec {
    uint16_t number;
    uint16_t code;
    bool active;
    co_pdo_rx_cause_t cause;
    bool rpdo_active;               /* co_pdo_is_active inside the callback */
    uint64_t t;
} rx_rec_t;

typedef struct node {
    co_od_t od;
    co_od_entry_t *entries;
    uint8_t *pool;
    co_od_subscription_t subs[4];
    co_pdo_t pdo;
    co_pdo_channel_t *channels;
    co_pdo_map_item_t *items;
    uint16_t *id_maps;              /* rx and rtr CAN-ID tables, when the group gives them */
    co_line_t *line;
    bool ready;
    err_rec_t err[MAX_REC];
    int nerr;
    rx_rec_t rx[MAX_REC];           /* rx_error_changed */
    int nrx;
    uint16_t received[MAX_REC];
    uint64_t received_t[MAX_REC];
    int nreceived;
    int before_send;
    uint16_t refresh_number;        /* before_send writes 0x2000 = refresh_value for it */
    uint8_t refresh_value;
} node_t;

typedef struct fx {
    tu_bus_t tb;
    tu_line_t l[3];
    co_line_t *r;
    node_t a, b;
    co_mode_t mode;
} fx_t;

static void on_error(co_pdo_t *pdo, uint16_t code, bool is_rpdo, uint16_t number, void *user)
{
    node_t *n = user;
    (void)pdo;
    if (n->nerr < MAX_REC) {   /* (the random test makes more: counted only) */
        n->err[n->nerr] = (err_rec_t){code, is_rpdo, number, co_line_now(n->line)};
    }
    n->nerr++;
}

static void on_received(co_pdo_t *pdo, uint16_t number, void *user)
{
    node_t *n = user;
    (void)pdo;
    if (n->nreceived < MAX_REC) {
        n->received_t[n->nreceived] = co_line_now(n->line);
        n->received[n->nreceived] = number;
    }
    n->nreceived++;
}

static void on_before_send(co_pdo_t *pdo, uint16_t number, void *user)
{
    node_t *n = user;
    n->before_send++;
    if (n->refresh_number == number) {
        assert_int_equal(co_od_put(&n->od, 0x2000, 0, &n->refresh_value, 1), 0);
        assert_false(co_pdo_trigger(pdo, number));   /* refused from inside */
    }
}

static void on_rx_error(co_pdo_t *pdo, uint16_t number, uint16_t code, bool active,
                        co_pdo_rx_cause_t cause, void *user)
{
    node_t *n = user;
    if (n->nrx < MAX_REC) {
        n->rx[n->nrx] = (rx_rec_t){number, code, active, cause, co_pdo_is_active(pdo, true, number),
                                   co_line_now(n->line)};
    }
    n->nrx++;
}

static const co_pdo_indications_t indications = {on_error, on_received, on_before_send,
                                                 on_rx_error};

static void def(node_t *n, uint16_t index, uint8_t sub, uint8_t obj, uint8_t type,
                uint8_t access, uint16_t flags, uint64_t value)
{
    tu_od_add_value(&n->od, index, sub, obj, type, access, flags, value);
}

/* Every test runs twice: the RPDO / RTR lookup by CAN-ID tables, then by a
 * scan of the channels (co_pdo_config without tables). */
static bool with_id_maps;

static int group_with_id_maps(void **state)
{
    (void)state;
    with_id_maps = true;
    return 0;
}

static int group_with_scan(void **state)
{
    (void)state;
    with_id_maps = false;
    return 0;
}

static void node_begin(node_t *n, co_mode_t mode, uint32_t capacity)
{
    uint32_t pool = capacity * 24u;
    memset(n, 0, sizeof *n);
    n->entries = calloc(capacity, sizeof *n->entries);
    n->pool = calloc(pool, 1);
    assert_non_null(n->entries);
    assert_non_null(n->pool);
    co_od_init(&n->od, mode, n->entries, capacity, n->pool, pool, n->subs, 4);
    def(n, 0x2000, 0, VAR, U8, RW, BOTH, 0x11);
    def(n, 0x2001, 0, VAR, U16, RW, BOTH, 0x2222);
    def(n, 0x2002, 0, VAR, U32, RW, BOTH, 0x33333333);
    def(n, 0x2003, 0, ARR, U8, RO, 0, 64);
    for (uint8_t s = 1; s <= 64; s++) {
        def(n, 0x2003, s, ARR, U8, RW, BOTH, s);
    }
    def(n, 0x2004, 0, VAR, U8, RO, CO_OD_MAP_TPDO, 0x44);
    def(n, 0x2005, 0, VAR, U32, RW, 0, 0x55555555);
}

/* A PDO: communication (COB-ID, type, inhibit, event timer, SYNC start for
 * TPDOs) and a mapping object with `cap` entries, the first `count` given. */
static void add_pdo(node_t *n, bool rpdo, uint16_t num, uint32_t cob, uint8_t type,
                    uint16_t inhibit, uint16_t event, uint8_t start, uint8_t cap,
                    const uint32_t *maps, uint8_t count)
{
    uint16_t comm = (uint16_t)((rpdo ? 0x1400 : 0x1800) + num - 1);
    uint16_t map = (uint16_t)((rpdo ? 0x1600 : 0x1A00) + num - 1);
    def(n, comm, 0, REC, U8, RO, 0, rpdo ? 5 : 6);
    def(n, comm, 1, REC, U32, RW, 0, cob);
    def(n, comm, 2, REC, U8, RW, 0, type);
    def(n, comm, 3, REC, CO_TYPE_UNSIGNED16, RW, 0, inhibit);
    def(n, comm, 5, REC, CO_TYPE_UNSIGNED16, RW, 0, event);
    if (!rpdo) {
        def(n, comm, 6, REC, U8, RW, 0, start);
    }
    def(n, map, 0, REC, U8, RW, 0, count);
    for (uint8_t s = 1; s <= cap; s++) {
        def(n, map, s, REC, U32, RW, 0, s <= count ? maps[s - 1] : 0);
    }
}

static void node_finish(node_t *n, co_line_t *line, uint8_t node_id)
{
    uint32_t channels = 0, items = 0;
    co_pdo_config_t cfg;
    assert_true(co_od_seal(&n->od, node_id));
    assert_true(co_cob_id_attach(&n->od));
    assert_true(co_pdo_need(&n->od, &channels, &items));
    n->channels = calloc(channels + 1, sizeof *n->channels);
    n->items = calloc(items + 1, sizeof *n->items);
    n->line = line;
    memset(&cfg, 0, sizeof cfg);
    cfg.channels = n->channels;
    cfg.channel_count = channels;
    cfg.items = n->items;
    cfg.item_count = items;
    cfg.ind = &indications;
    cfg.user = n;
    if (with_id_maps) {
        n->id_maps = calloc(2 * CO_LINE_ID_MAP_SIZE, sizeof *n->id_maps);
        cfg.rx_map = n->id_maps;
        cfg.rtr_map = n->id_maps + CO_LINE_ID_MAP_SIZE;
    }
    /* too little storage is refused */
    if (items > 0) {
        cfg.item_count = items - 1;
        assert_false(co_pdo_init(&n->pdo, line, &n->od, &cfg));
        cfg.item_count = items;
    }
    assert_true(co_pdo_init(&n->pdo, line, &n->od, &cfg));
    n->ready = true;
}

static void node_free(node_t *n)
{
    if (n->ready) {
        co_pdo_deinit(&n->pdo);
    }
    free(n->entries);
    free(n->pool);
    free(n->channels);
    free(n->id_maps);
    free(n->items);
}

static fx_t *fx_new(co_mode_t mode, uint32_t capacity)
{
    fx_t *fx = calloc(1, sizeof *fx);
    assert_non_null(fx);
    fx->mode = mode;
    tu_bus_init(&fx->tb, mode, mode == CO_MODE_FD);
    tu_bus_add_line(&fx->tb, &fx->l[0]);
    tu_bus_add_line(&fx->tb, &fx->l[1]);
    fx->r = tu_bus_add_line(&fx->tb, &fx->l[2]);
    co_line_set_node_id(&fx->l[0].line, ID_A);
    co_line_set_node_id(&fx->l[1].line, ID_B);
    node_begin(&fx->a, mode, capacity);
    node_begin(&fx->b, mode, capacity);
    return fx;
}

static void fx_finish(fx_t *fx)
{
    node_finish(&fx->a, &fx->l[0].line, ID_A);
    node_finish(&fx->b, &fx->l[1].line, ID_B);
}

static void fx_operational(fx_t *fx)
{
    co_pdo_set_operational(&fx->a.pdo, true);
    co_pdo_set_operational(&fx->b.pdo, true);
}

static void fx_free(fx_t *fx)
{
    node_free(&fx->a);
    node_free(&fx->b);
    free(fx);
}

/* A network write (SDO/USDO server path): begin, one chunk, end. */
static uint32_t net_write(node_t *n, uint16_t index, uint8_t sub, uint64_t value, uint32_t len)
{
    return tu_od_net_write(&n->od, index, sub, value, len);
}

static void put(node_t *n, uint16_t index, uint8_t sub, uint64_t value, uint32_t len)
{
    uint8_t buf[8];
    tu_le_put(buf, value, len);
    assert_int_equal(co_od_put(&n->od, index, sub, buf, len), 0);
}

static uint64_t get(node_t *n, uint16_t index, uint8_t sub, uint32_t len)
{
    return tu_od_value(&n->od, index, sub, len);
}

/* Application call at time t: the lines' clocks first, then frames carried. */
static void trigger_at(fx_t *fx, node_t *n, uint16_t num, uint64_t t, bool expect)
{
    tu_step(&fx->tb, t);
    assert_int_equal(co_pdo_trigger(&n->pdo, num), expect);
    tu_step(&fx->tb, t);
}

static void sync_at(fx_t *fx, uint64_t t, uint8_t counter)
{
    tu_step(&fx->tb, t);
    co_pdo_sync(&fx->a.pdo, counter);
    co_pdo_sync(&fx->b.pdo, counter);
    tu_step(&fx->tb, t);
}

/* Inject a raw frame from line r at time t. */
static void inject(fx_t *fx, uint32_t id, uint8_t flags, const uint8_t *data, uint8_t len,
                   uint64_t t)
{
    co_frame_t f = tu_frame(id, flags, data, len);
    tu_step(&fx->tb, t);
    assert_true(co_line_send_raw(fx->r, &f));
    tu_step(&fx->tb, t);
}

/* The standard pair: a's TPDO1 (0x185) -> b's RPDO1, 8 bytes U8 U16 U32 U8. */
static const uint32_t map8[4] = {MAP(0x2000, 0, 8), MAP(0x2001, 0, 16), MAP(0x2002, 0, 32),
                                 MAP(0x2004, 0, 8)};
static const uint32_t rmap8[4] = {MAP(0x2000, 0, 8), MAP(0x2001, 0, 16), MAP(0x2002, 0, 32),
                                  MAP(0x0005, 0, 8)};

static fx_t *pair(co_mode_t mode, uint8_t ttype, uint16_t inhibit, uint16_t event,
                  uint8_t rtype, uint16_t deadline)
{
    fx_t *fx = fx_new(mode, SMALL_ENTRIES);
    add_pdo(&fx->a, false, 1, 0x185, ttype, inhibit, event, 0, 8, map8, 4);
    add_pdo(&fx->b, true, 1, 0x185, rtype, 0, deadline, 0, 8, rmap8, 4);
    fx_finish(fx);
    fx_operational(fx);
    return fx;
}

/* ------------------------------------------------------------- tests */

static void check_event_pair(co_mode_t mode)
{
    fx_t *fx = pair(mode, 254, 0, 0, 254, 0);
    const uint8_t expect[8] = {0xA1, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12, 0x44};
    put(&fx->a, 0x2000, 0, 0xA1, 1);
    put(&fx->a, 0x2001, 0, 0x1234, 2);
    put(&fx->a, 0x2002, 0, 0x12345678, 4);
    assert_true(co_pdo_is_active(&fx->a.pdo, false, 1));
    assert_true(co_pdo_is_active(&fx->b.pdo, true, 1));
    assert_false(co_pdo_is_active(&fx->b.pdo, true, 2));
    trigger_at(fx, &fx->a, 1, MS(1), true);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x185), 1);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, 0x185, 0), 0x185, expect, 8);
    assert_int_equal(fx->tb.log[0].t_us, MS(1));
    /* b applied it (dummy skipped the last byte) and said so */
    assert_int_equal(get(&fx->b, 0x2000, 0, 1), 0xA1);
    assert_int_equal(get(&fx->b, 0x2001, 0, 2), 0x1234);
    assert_int_equal(get(&fx->b, 0x2002, 0, 4), 0x12345678);
    assert_int_equal(fx->b.nreceived, 1);
    assert_int_equal(fx->b.received[0], 1);
    assert_int_equal(fx->a.before_send, 1);
    assert_int_equal(co_pdo_stats(&fx->a.pdo)->tx_frames, 1);
    assert_int_equal(co_pdo_stats(&fx->b.pdo)->rx_frames, 1);
    assert_int_equal(fx->b.nerr, 0);
    /* the values as each OD holds them, laid out by the mapping: b's dummy
     * byte reads 0, a's TPDO is what went out */
    {
        uint8_t data[CO_FRAME_MAX_DATA], len = 0;
        const uint8_t applied[8] = {0xA1, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12, 0x00};
        memset(data, 0xEE, sizeof data);
        assert_true(co_pdo_pack_values(&fx->b.pdo, true, 1, data, &len));
        assert_int_equal(len, 8);
        assert_memory_equal(data, applied, 8);
        assert_int_equal(data[8], 0);
        assert_true(co_pdo_pack_values(&fx->a.pdo, false, 1, data, &len));
        assert_int_equal(len, 8);
        assert_memory_equal(data, expect, 8);
        assert_false(co_pdo_pack_values(&fx->b.pdo, true, 2, data, &len));
        assert_false(co_pdo_pack_values(&fx->b.pdo, false, 1, data, &len));
    }
    /* an unknown TPDO number or an RPDO number is refused */
    assert_false(co_pdo_trigger(&fx->a.pdo, 2));
    assert_false(co_pdo_trigger(&fx->a.pdo, 0));
    assert_false(co_pdo_trigger(&fx->a.pdo, 513));
    assert_false(co_pdo_trigger(&fx->b.pdo, 1));
    fx_free(fx);
}

static void test_event_classic(void **state)
{
    (void)state;
    check_event_pair(CO_MODE_CLASSIC);
}

static void test_event_fd(void **state)
{
    (void)state;
    check_event_pair(CO_MODE_FD);
}

/* 13 mapped bytes go out as 16 with zero padding; the receiver takes them. */
static void test_fd_13_bytes_padded(void **state)
{
    const uint32_t m[4] = {MAP(0x2002, 0, 32), MAP(0x2002, 0, 32), MAP(0x2002, 0, 32),
                           MAP(0x2000, 0, 8)};
    const uint32_t rm[4] = {MAP(0x0007, 0, 32), MAP(0x0007, 0, 32), MAP(0x2002, 0, 32),
                            MAP(0x2000, 0, 8)};
    const uint8_t expect[16] = {0x78, 0x56, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12,
                                0x78, 0x56, 0x34, 0x12, 0x9C, 0, 0, 0};
    fx_t *fx = fx_new(CO_MODE_FD, SMALL_ENTRIES);
    (void)state;
    add_pdo(&fx->a, false, 1, 0x40000185, 255, 0, 0, 0, 8, m, 4);
    add_pdo(&fx->b, true, 1, 0x185, 255, 0, 0, 0, 8, rm, 4);
    fx_finish(fx);
    fx_operational(fx);
    put(&fx->a, 0x2002, 0, 0x12345678, 4);
    put(&fx->a, 0x2000, 0, 0x9C, 1);
    trigger_at(fx, &fx->a, 1, MS(2), true);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x185), 1);
    tu_assert_frame(&fx->tb.log[0].frame, 0x185, CO_FRAME_FD | CO_FRAME_BRS, expect, 16);
    assert_int_equal(get(&fx->b, 0x2002, 0, 4), 0x12345678);
    assert_int_equal(get(&fx->b, 0x2000, 0, 1), 0x9C);
    assert_int_equal(fx->b.nerr, 0);
    assert_int_equal(co_pdo_stats(&fx->b.pdo)->rx_long, 0);
    fx_free(fx);
}

/* 64 one-byte entries: the full 64-byte FD PDO, both ways. */
static void test_fd_64_entries(void **state)
{
    uint32_t m[64];
    uint8_t expect[64];
    fx_t *fx = fx_new(CO_MODE_FD, SMALL_ENTRIES);
    (void)state;
    for (uint8_t i = 0; i < 64; i++) {
        m[i] = MAP(0x2003, 64 - i, 8);   /* reversed order */
        expect[i] = (uint8_t)(64 - i + 0x80);
    }
    add_pdo(&fx->a, false, 7, 0x2C5, 254, 0, 0, 0, 64, m, 64);
    add_pdo(&fx->b, true, 9, 0x2C5, 254, 0, 0, 0, 64, m, 64);
    fx_finish(fx);
    fx_operational(fx);
    for (uint8_t s = 1; s <= 64; s++) {
        put(&fx->a, 0x2003, s, (uint8_t)(s + 0x80), 1);
    }
    trigger_at(fx, &fx->a, 7, MS(1), true);
    tu_assert_logged(&fx->tb, 0, 0x2C5, expect, 64);
    for (uint8_t s = 1; s <= 64; s++) {
        assert_int_equal(get(&fx->b, 0x2003, s, 1), (uint8_t)(s + 0x80));
    }
    assert_int_equal(fx->b.received[0], 9);
    fx_free(fx);
}

/* Inhibit 1 ms: an event 50 µs after a transmission goes out when the
 * inhibit time ends, not lost; several events in it make one frame. */
static void test_inhibit(void **state)
{
    fx_t *fx = pair(CO_MODE_CLASSIC, 254, 10, 0, 254, 0);
    (void)state;
    trigger_at(fx, &fx->a, 1, MS(10), true);
    put(&fx->a, 0x2000, 0, 0x77, 1);
    trigger_at(fx, &fx->a, 1, MS(10) + 50, true);
    trigger_at(fx, &fx->a, 1, MS(10) + 60, true);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x185), 1);
    tu_run_until(&fx->tb, MS(10) + 999);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x185), 1);
    tu_run_until(&fx->tb, MS(12));
    assert_int_equal(tu_log_count_id(&fx->tb, 0x185), 2);
    assert_int_equal(fx->tb.log[tu_log_find_id(&fx->tb, 0x185, 1)].t_us, MS(11));
    assert_int_equal(fx->tb.log[tu_log_find_id(&fx->tb, 0x185, 1)].frame.data[0], 0x77);
    assert_int_equal(co_pdo_stats(&fx->a.pdo)->tx_inhibited, 1);
    assert_int_equal(get(&fx->b, 0x2000, 0, 1), 0x77);
    /* after the inhibit time an event goes out at once */
    trigger_at(fx, &fx->a, 1, MS(13), true);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x185), 3);
    assert_int_equal(fx->tb.log[tu_log_find_id(&fx->tb, 0x185, 2)].t_us, MS(13));
    fx_free(fx);
}

/* Event timer 10 ms: periodic from entering operational, restarted by an event. */
static void test_event_timer(void **state)
{
    fx_t *fx = fx_new(CO_MODE_CLASSIC, SMALL_ENTRIES);
    (void)state;
    add_pdo(&fx->a, false, 1, 0x185, 255, 0, 10, 0, 8, map8, 4);
    fx_finish(fx);
    tu_step(&fx->tb, MS(5));
    fx_operational(fx);
    tu_run_until(&fx->tb, MS(36));
    assert_int_equal(tu_log_count_id(&fx->tb, 0x185), 3);
    assert_int_equal(fx->tb.log[0].t_us, MS(15));
    assert_int_equal(fx->tb.log[1].t_us, MS(25));
    assert_int_equal(fx->tb.log[2].t_us, MS(35));
    trigger_at(fx, &fx->a, 1, MS(40), true);
    tu_run_until(&fx->tb, MS(55));
    assert_int_equal(tu_log_count_id(&fx->tb, 0x185), 5);
    assert_int_equal(fx->tb.log[3].t_us, MS(40));
    assert_int_equal(fx->tb.log[4].t_us, MS(50));
    /* a network write of the event time takes effect at once */
    assert_int_equal(net_write(&fx->a, 0x1800, 5, 3, 2), 0);
    tu_run_until(&fx->tb, MS(59));
    assert_int_equal(tu_log_count_id(&fx->tb, 0x185), 6);
    assert_int_equal(fx->tb.log[5].t_us, MS(58));
    /* leaving operational stops it */
    co_pdo_set_operational(&fx->a.pdo, false);
    tu_run_until(&fx->tb, MS(100));
    assert_int_equal(tu_log_count_id(&fx->tb, 0x185), 6);
    fx_free(fx);
}

/* Type 0: sent at the SYNC after a trigger; type 3: every third SYNC;
 * type 1 with start value 3 and type 2 with start value 3 on counters. */
static void test_sync_tpdo_types(void **state)
{
    const uint32_t m[1] = {MAP(0x2000, 0, 8)};
    fx_t *fx = fx_new(CO_MODE_CLASSIC, SMALL_ENTRIES);
    size_t i;
    (void)state;
    add_pdo(&fx->a, false, 1, 0x181, 0, 0, 0, 0, 1, m, 1);
    add_pdo(&fx->a, false, 2, 0x182, 3, 0, 0, 0, 1, m, 1);
    add_pdo(&fx->a, false, 3, 0x183, 1, 0, 0, 3, 1, m, 1);
    add_pdo(&fx->a, false, 4, 0x184, 2, 0, 0, 3, 1, m, 1);
    fx_finish(fx);
    fx_operational(fx);
    sync_at(fx, MS(1), 1);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x181), 0);
    trigger_at(fx, &fx->a, 1, MS(2), true);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x181), 0);   /* waits for the SYNC */
    for (i = 2; i <= 8; i++) {
        sync_at(fx, MS(i + 1), (uint8_t)i);
    }
    /* type 0: once, at the SYNC of 3 ms */
    assert_int_equal(tu_log_count_id(&fx->tb, 0x181), 1);
    assert_int_equal(fx->tb.log[tu_log_find_id(&fx->tb, 0x181, 0)].t_us, MS(3));
    /* type 3: SYNCs 3 and 6 (counters 3 and 6) of the 8 */
    assert_int_equal(tu_log_count_id(&fx->tb, 0x182), 2);
    assert_int_equal(fx->tb.log[tu_log_find_id(&fx->tb, 0x182, 0)].t_us, MS(4));
    assert_int_equal(fx->tb.log[tu_log_find_id(&fx->tb, 0x182, 1)].t_us, MS(7));
    /* type 1 from counter 3: counters 3..8 */
    assert_int_equal(tu_log_count_id(&fx->tb, 0x183), 6);
    assert_int_equal(fx->tb.log[tu_log_find_id(&fx->tb, 0x183, 0)].t_us, MS(4));
    /* type 2 from counter 3: counters 3, 5, 7 */
    assert_int_equal(tu_log_count_id(&fx->tb, 0x184), 3);
    assert_int_equal(fx->tb.log[tu_log_find_id(&fx->tb, 0x184, 0)].t_us, MS(4));
    assert_int_equal(fx->tb.log[tu_log_find_id(&fx->tb, 0x184, 1)].t_us, MS(6));
    assert_int_equal(fx->tb.log[tu_log_find_id(&fx->tb, 0x184, 2)].t_us, MS(8));
    /* types 1..240 take no application events */
    assert_false(co_pdo_trigger(&fx->a.pdo, 2));
    fx_free(fx);
}

/* Without a counter in the SYNC the start value is ignored. */
static void test_sync_start_without_counter(void **state)
{
    const uint32_t m[1] = {MAP(0x2000, 0, 8)};
    fx_t *fx = fx_new(CO_MODE_CLASSIC, SMALL_ENTRIES);
    (void)state;
    add_pdo(&fx->a, false, 1, 0x181, 2, 0, 0, 3, 1, m, 1);
    fx_finish(fx);
    fx_operational(fx);
    sync_at(fx, MS(1), 0);
    sync_at(fx, MS(2), 0);
    sync_at(fx, MS(3), 0);
    sync_at(fx, MS(4), 0);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x181), 2);
    assert_int_equal(fx->tb.log[0].t_us, MS(2));
    assert_int_equal(fx->tb.log[1].t_us, MS(4));
    fx_free(fx);
}

/* A synchronous RPDO is applied only at the next SYNC (the latest frame). */
static void test_sync_rpdo(void **state)
{
    fx_t *fx = pair(CO_MODE_FD, 254, 0, 0, 5, 0);
    (void)state;
    put(&fx->a, 0x2002, 0, 0xCAFE0001, 4);
    trigger_at(fx, &fx->a, 1, MS(1), true);
    put(&fx->a, 0x2002, 0, 0xCAFE0002, 4);
    trigger_at(fx, &fx->a, 1, MS(2), true);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x185), 2);
    assert_int_equal(get(&fx->b, 0x2002, 0, 4), 0x33333333);
    assert_int_equal(fx->b.nreceived, 0);
    tu_step(&fx->tb, MS(3));
    co_pdo_sync(&fx->b.pdo, 0);
    assert_int_equal(get(&fx->b, 0x2002, 0, 4), 0xCAFE0002);
    assert_int_equal(fx->b.nreceived, 1);
    assert_int_equal(fx->b.received_t[0], MS(3));
    /* nothing new: the next SYNC applies nothing */
    co_pdo_sync(&fx->b.pdo, 0);
    assert_int_equal(fx->b.nreceived, 1);
    fx_free(fx);
}

/* The synchronous window closes on TPDOs the tx queue refused; the next
 * one goes out when the queue drains. */
static void test_sync_window_and_retry(void **state)
{
    const uint32_t m[1] = {MAP(0x2000, 0, 8)};
    fx_t *fx = fx_new(CO_MODE_CLASSIC, SMALL_ENTRIES);
    co_frame_t filler = tu_frame(0x7FF, 0, NULL, 0), out;
    co_line_t *a = &fx->l[0].line;
    int k;
    (void)state;
    add_pdo(&fx->a, false, 1, 0x181, 1, 0, 0, 0, 1, m, 1);
    fx_finish(fx);
    fx_operational(fx);
    for (k = 0; k < TU_QUEUE; k++) {
        assert_true(co_line_send_raw(a, &filler));
    }
    co_pdo_sync(&fx->a.pdo, 0);
    assert_int_equal(co_pdo_stats(&fx->a.pdo)->tx_failed, 1);
    co_pdo_sync_window_closed(&fx->a.pdo);
    assert_int_equal(co_pdo_stats(&fx->a.pdo)->sync_window_drops, 1);
    /* next SYNC: refused again, then the driver drains half the queue */
    co_pdo_sync(&fx->a.pdo, 0);
    assert_int_equal(co_pdo_stats(&fx->a.pdo)->tx_failed, 2);
    for (k = 0; k < TU_QUEUE / 2; k++) {
        assert_true(co_line_tx_pop(a, &out));
    }
    tu_step(&fx->tb, MS(1));
    assert_int_equal(tu_log_count_id(&fx->tb, 0x181), 1);
    assert_int_equal(co_pdo_stats(&fx->a.pdo)->tx_frames, 1);
    co_pdo_sync_window_closed(&fx->a.pdo);
    assert_int_equal(co_pdo_stats(&fx->a.pdo)->sync_window_drops, 1);
    fx_free(fx);
}

/* RPDO event timer = reception deadline, from the first reception. */
static void test_rpdo_deadline(void **state)
{
    fx_t *fx = pair(CO_MODE_CLASSIC, 254, 0, 0, 254, 100);
    (void)state;
    tu_run_until(&fx->tb, MS(500));
    assert_int_equal(fx->b.nerr, 0);   /* no reception yet: no monitoring */
    trigger_at(fx, &fx->a, 1, MS(501), true);   /* deadline 601 ms */
    tu_run_until(&fx->tb, MS(550));
    assert_int_equal(fx->b.nerr, 0);
    trigger_at(fx, &fx->a, 1, MS(550), true);   /* re-armed: deadline 650 ms */
    tu_run_until(&fx->tb, MS(650) - 1);
    assert_int_equal(fx->b.nerr, 0);
    tu_run_until(&fx->tb, MS(900));
    assert_int_equal(fx->b.nerr, 1);
    assert_int_equal(fx->b.err[0].code, 0x8250);
    assert_true(fx->b.err[0].is_rpdo);
    assert_int_equal(fx->b.err[0].number, 1);
    assert_int_equal(fx->b.err[0].t, MS(650));
    assert_int_equal(co_pdo_stats(&fx->b.pdo)->rx_timeouts, 1);
    /* received again */
    trigger_at(fx, &fx->a, 1, MS(901), true);
    assert_int_equal(fx->b.nerr, 2);
    assert_int_equal(fx->b.err[1].code, CO_PDO_EMCY_RECEIVED_AGAIN);
    assert_int_equal(fx->b.err[1].t, MS(901));
    tu_run_until(&fx->tb, MS(1001));
    assert_int_equal(fx->b.nerr, 3);
    assert_int_equal(fx->b.err[2].code, 0x8250);
    assert_int_equal(fx->b.err[2].t, MS(1001));
    fx_free(fx);
}

/* Short RPDO: 0x8210 once, ignored; long: 0x8220, applied. */
static void test_length_errors_classic(void **state)
{
    const uint32_t rm[2] = {MAP(0x2001, 0, 16), MAP(0x2000, 0, 8)};
    const uint8_t d[8] = {0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x07, 0x08};
    fx_t *fx = fx_new(CO_MODE_CLASSIC, SMALL_ENTRIES);
    (void)state;
    add_pdo(&fx->b, true, 3, 0x206, 254, 0, 0, 0, 2, rm, 2);
    fx_finish(fx);
    fx_operational(fx);
    inject(fx, 0x206, 0, d, 2, MS(1));
    inject(fx, 0x206, 0, d, 1, MS(2));
    assert_int_equal(fx->b.nerr, 1);
    assert_int_equal(fx->b.err[0].code, 0x8210);
    assert_int_equal(fx->b.err[0].number, 3);
    assert_int_equal(co_pdo_stats(&fx->b.pdo)->rx_short, 2);
    assert_int_equal(get(&fx->b, 0x2001, 0, 2), 0x2222);
    assert_int_equal(fx->b.nreceived, 0);
    inject(fx, 0x206, 0, d, 3, MS(3));
    assert_int_equal(get(&fx->b, 0x2001, 0, 2), 0x0201);
    assert_int_equal(get(&fx->b, 0x2000, 0, 1), 0x03);
    inject(fx, 0x206, 0, d + 1, 5, MS(4));
    assert_int_equal(fx->b.nerr, 2);
    assert_int_equal(fx->b.err[1].code, 0x8220);
    assert_int_equal(co_pdo_stats(&fx->b.pdo)->rx_long, 1);
    assert_int_equal(get(&fx->b, 0x2001, 0, 2), 0x0302);
    assert_int_equal(fx->b.nreceived, 2);
    inject(fx, 0x206, 0, d, 1, MS(5));
    assert_int_equal(fx->b.nerr, 3);
    assert_int_equal(fx->b.err[2].code, 0x8210);
    fx_free(fx);
}

/* FD: 13 mapped bytes accept 13..16; 20 is too long, 12 too short. */
static void test_length_errors_fd(void **state)
{
    const uint32_t rm[4] = {MAP(0x2002, 0, 32), MAP(0x2002, 0, 32), MAP(0x2002, 0, 32),
                            MAP(0x2000, 0, 8)};
    uint8_t d[20];
    fx_t *fx = fx_new(CO_MODE_FD, SMALL_ENTRIES);
    (void)state;
    for (int i = 0; i < 20; i++) {
        d[i] = (uint8_t)(i + 1);
    }
    add_pdo(&fx->b, true, 1, 0x206, 254, 0, 0, 0, 4, rm, 4);
    fx_finish(fx);
    fx_operational(fx);
    inject(fx, 0x206, CO_FRAME_FD, d, 16, MS(1));
    inject(fx, 0x206, CO_FRAME_FD | CO_FRAME_BRS, d, 16, MS(1));
    assert_int_equal(fx->b.nerr, 0);
    assert_int_equal(fx->b.nreceived, 2);
    assert_int_equal(get(&fx->b, 0x2000, 0, 1), 13);
    inject(fx, 0x206, CO_FRAME_FD, d, 20, MS(2));
    assert_int_equal(fx->b.nerr, 1);
    assert_int_equal(fx->b.err[0].code, 0x8220);
    assert_int_equal(fx->b.nreceived, 3);
    inject(fx, 0x206, CO_FRAME_FD, d, 12, MS(3));
    assert_int_equal(fx->b.nerr, 2);
    assert_int_equal(fx->b.err[1].code, 0x8210);
    assert_int_equal(fx->b.nreceived, 3);
    fx_free(fx);
}

/* rx_error_changed record k of node n. */
static void assert_rx(const node_t *n, int k, uint16_t number, uint16_t code, bool active,
                      co_pdo_rx_cause_t cause)
{
    assert_true(k < n->nrx);
    assert_int_equal(n->rx[k].number, number);
    assert_int_equal(n->rx[k].code, code);
    assert_int_equal(n->rx[k].active, active);
    assert_int_equal(n->rx[k].cause, cause);
}

/* rx_error_changed for length errors: frames start and end them; disabling
 * the RPDO ends its error (told once, the RPDO already off), re-mapping
 * and re-enabling tell nothing more; leaving operational, writes that keep
 * the RPDO's CAN-ID and length, refused writes and writes to another RPDO
 * end nothing. A changed length error is told before the old one ends. */
static void test_rx_error_ends_when_disabled(void **state)
{
    const uint8_t d[8] = {1, 2, 3, 4, 5, 6, 7, 8};
    fx_t *fx = fx_new(CO_MODE_CLASSIC, SMALL_ENTRIES);
    node_t *b = &fx->b;
    (void)state;
    add_pdo(b, true, 1, 0x206, 254, 0, 0, 0, 8, rmap8, 4);
    add_pdo(b, true, 2, 0x207, 254, 0, 0, 0, 8, rmap8, 4);
    fx_finish(fx);
    fx_operational(fx);
    inject(fx, 0x206, 0, d, 5, MS(1));
    assert_int_equal(b->nrx, 1);
    assert_rx(b, 0, 1, CO_PDO_EMCY_LENGTH, true, CO_PDO_RX_FRAME);
    assert_true(b->rx[0].rpdo_active);
    assert_int_equal(b->rx[0].t, MS(1));
    inject(fx, 0x206, 0, d, 5, MS(2));
    /* none of these ends it */
    co_pdo_set_operational(&b->pdo, false);
    co_pdo_set_operational(&b->pdo, true);
    assert_int_equal(net_write(b, 0x1600, 1, MAP(0x2002, 0, 32), 4), CO_ABORT_INVALID_VALUE);
    assert_int_equal(net_write(b, 0x1400, 1, 0x206, 4), 0);
    assert_int_equal(net_write(b, 0x1400, 2, 255, 1), 0);
    assert_int_equal(net_write(b, 0x1400, 5, 500, 2), 0);
    assert_int_equal(net_write(b, 0x1401, 1, INVALID | 0x207, 4), 0);
    inject(fx, 0x206, 0, d, 5, MS(3));   /* still in force: not told again */
    assert_int_equal(b->nrx, 1);
    assert_int_equal(b->nerr, 1);
    /* the CiA 301 procedure: invalidate ... */
    assert_int_equal(net_write(b, 0x1400, 1, INVALID | 0x206, 4), 0);
    assert_int_equal(b->nrx, 2);
    assert_rx(b, 1, 1, CO_PDO_EMCY_LENGTH, false, CO_PDO_RX_RECONFIGURED);
    assert_false(b->rx[1].rpdo_active);
    /* ... re-map (2 bytes) and validate: nothing more to tell */
    assert_int_equal(net_write(b, 0x1600, 0, 0, 1), 0);
    assert_int_equal(net_write(b, 0x1600, 1, MAP(0x2001, 0, 16), 4), 0);
    assert_int_equal(net_write(b, 0x1600, 0, 1, 1), 0);
    assert_int_equal(net_write(b, 0x1400, 1, 0x206, 4), 0);
    assert_int_equal(net_write(b, 0x1401, 1, 0x207, 4), 0);
    assert_true(co_pdo_is_active(&b->pdo, true, 1));
    assert_int_equal(b->nrx, 2);
    /* the new length: short, long (the new error first), right */
    inject(fx, 0x206, 0, d, 1, MS(4));
    inject(fx, 0x206, 0, d, 3, MS(5));
    inject(fx, 0x206, 0, d, 2, MS(6));
    assert_int_equal(b->nrx, 6);
    assert_rx(b, 2, 1, CO_PDO_EMCY_LENGTH, true, CO_PDO_RX_FRAME);
    assert_rx(b, 3, 1, CO_PDO_EMCY_LENGTH_EXCEEDED, true, CO_PDO_RX_FRAME);
    assert_rx(b, 4, 1, CO_PDO_EMCY_LENGTH, false, CO_PDO_RX_FRAME);
    assert_rx(b, 5, 1, CO_PDO_EMCY_LENGTH_EXCEEDED, false, CO_PDO_RX_FRAME);
    assert_int_equal(get(b, 0x2001, 0, 2), 0x0201);
    /* an application write (no checks) that changes the mapped length of
     * the working RPDO ends its length error too */
    inject(fx, 0x206, 0, d, 3, MS(7));
    assert_int_equal(b->nrx, 7);
    put(b, 0x1600, 1, MAP(0x2002, 0, 32), 4);
    assert_int_equal(b->nrx, 8);
    assert_rx(b, 7, 1, CO_PDO_EMCY_LENGTH_EXCEEDED, false, CO_PDO_RX_RECONFIGURED);
    assert_true(b->rx[7].rpdo_active);
    /* RPDO 2 never was in error: disabling it tells nothing */
    assert_int_equal(net_write(b, 0x1401, 1, INVALID | 0x207, 4), 0);
    assert_int_equal(b->nrx, 8);
    for (int k = 0; k < b->nrx; k++) {
        assert_int_equal(b->rx[k].number, 1);
    }
    fx_free(fx);
}

/* rx_error_changed for the deadline: missed (DEADLINE), kept across leaving
 * operational and a longer deadline, ended by the next frame (with
 * RECEIVED_AGAIN on the error callback), by switching the deadline off and
 * by disabling the RPDO. */
static void test_rx_timeout_ends_when_disabled(void **state)
{
    const uint8_t d[8] = {1, 2, 3, 4, 5, 6, 7, 8};
    fx_t *fx = fx_new(CO_MODE_CLASSIC, SMALL_ENTRIES);
    node_t *b = &fx->b;
    (void)state;
    add_pdo(b, true, 1, 0x206, 254, 0, 100, 0, 8, rmap8, 4);
    fx_finish(fx);
    fx_operational(fx);
    inject(fx, 0x206, 0, d, 8, MS(1));
    tu_run_until(&fx->tb, MS(101) - 1);
    assert_int_equal(b->nrx, 0);
    tu_run_until(&fx->tb, MS(101));
    assert_int_equal(b->nrx, 1);
    assert_rx(b, 0, 1, CO_PDO_EMCY_RPDO_TIMEOUT, true, CO_PDO_RX_DEADLINE);
    assert_int_equal(b->rx[0].t, MS(101));
    /* kept: pre-operational and back, a longer deadline */
    co_pdo_set_operational(&b->pdo, false);
    assert_int_equal(net_write(b, 0x1400, 5, 200, 2), 0);
    co_pdo_set_operational(&b->pdo, true);
    tu_run_until(&fx->tb, MS(400));
    assert_int_equal(b->nrx, 1);
    /* the next frame ends it */
    inject(fx, 0x206, 0, d, 8, MS(400));
    assert_int_equal(b->nrx, 2);
    assert_rx(b, 1, 1, CO_PDO_EMCY_RPDO_TIMEOUT, false, CO_PDO_RX_FRAME);
    assert_int_equal(b->nerr, 2);
    assert_int_equal(b->err[1].code, CO_PDO_EMCY_RECEIVED_AGAIN);
    tu_run_until(&fx->tb, MS(600));
    assert_int_equal(b->nrx, 3);
    assert_rx(b, 2, 1, CO_PDO_EMCY_RPDO_TIMEOUT, true, CO_PDO_RX_DEADLINE);
    assert_int_equal(b->rx[2].t, MS(600));
    /* no deadline any more: nothing to miss */
    assert_int_equal(net_write(b, 0x1400, 5, 0, 2), 0);
    assert_int_equal(b->nrx, 4);
    assert_rx(b, 3, 1, CO_PDO_EMCY_RPDO_TIMEOUT, false, CO_PDO_RX_RECONFIGURED);
    assert_true(b->rx[3].rpdo_active);
    /* missed again, then the RPDO is disabled */
    assert_int_equal(net_write(b, 0x1400, 5, 100, 2), 0);
    inject(fx, 0x206, 0, d, 8, MS(601));
    tu_run_until(&fx->tb, MS(701));
    assert_int_equal(b->nrx, 5);
    assert_rx(b, 4, 1, CO_PDO_EMCY_RPDO_TIMEOUT, true, CO_PDO_RX_DEADLINE);
    assert_int_equal(net_write(b, 0x1400, 1, INVALID | 0x206, 4), 0);
    assert_int_equal(b->nrx, 6);
    assert_rx(b, 5, 1, CO_PDO_EMCY_RPDO_TIMEOUT, false, CO_PDO_RX_RECONFIGURED);
    assert_false(b->rx[5].rpdo_active);
    assert_int_equal(net_write(b, 0x1400, 1, 0x206, 4), 0);
    tu_run_until(&fx->tb, MS(1000));
    assert_int_equal(b->nrx, 6);
    assert_int_equal(b->nerr, 4);   /* the error callback: no RECEIVED_AGAIN for it */
    fx_free(fx);
}

/* co_pdo_reload ends every reception error (the RPDO working again);
 * co_pdo_deinit forgets them untold. */
static void test_rx_errors_end_at_reload(void **state)
{
    const uint8_t d[8] = {1, 2, 3, 4, 5, 6, 7, 8};
    fx_t *fx = fx_new(CO_MODE_CLASSIC, SMALL_ENTRIES);
    node_t *b = &fx->b;
    (void)state;
    add_pdo(b, true, 1, 0x206, 254, 0, 100, 0, 8, rmap8, 4);
    fx_finish(fx);
    fx_operational(fx);
    inject(fx, 0x206, 0, d, 8, MS(1));
    tu_run_until(&fx->tb, MS(101));
    inject(fx, 0x206, 0, d, 4, MS(102));   /* short: no reception for the deadline */
    assert_int_equal(b->nrx, 2);
    assert_rx(b, 0, 1, CO_PDO_EMCY_RPDO_TIMEOUT, true, CO_PDO_RX_DEADLINE);
    assert_rx(b, 1, 1, CO_PDO_EMCY_LENGTH, true, CO_PDO_RX_FRAME);
    co_pdo_reload(&b->pdo);
    assert_int_equal(b->nrx, 4);
    assert_rx(b, 2, 1, CO_PDO_EMCY_LENGTH, false, CO_PDO_RX_RECONFIGURED);
    assert_rx(b, 3, 1, CO_PDO_EMCY_RPDO_TIMEOUT, false, CO_PDO_RX_RECONFIGURED);
    assert_true(b->rx[3].rpdo_active);
    co_pdo_reload(&b->pdo);
    assert_int_equal(b->nrx, 4);
    inject(fx, 0x206, 0, d, 4, MS(103));   /* told again: the reload forgot it */
    assert_int_equal(b->nrx, 5);
    assert_rx(b, 4, 1, CO_PDO_EMCY_LENGTH, true, CO_PDO_RX_FRAME);
    co_pdo_deinit(&b->pdo);
    b->ready = false;
    assert_int_equal(b->nrx, 5);
    fx_free(fx);
}

/* The CiA 301 mapping procedure over the OD write path, with every abort. */
static void check_mapping_procedure(co_mode_t mode)
{
    fx_t *fx = pair(mode, 254, 0, 0, 254, 0);
    node_t *a = &fx->a, *b = &fx->b;
    uint8_t expect[8] = {0x99, 0x11, 0x33, 0x33, 0x33, 0x33};
    /* while valid: neither entries nor sub 0 change; equal values pass */
    assert_int_equal(net_write(a, 0x1A00, 1, MAP(0x2002, 0, 32), 4), CO_ABORT_INVALID_VALUE);
    assert_int_equal(net_write(a, 0x1A00, 0, 0, 1), CO_ABORT_INVALID_VALUE);
    assert_int_equal(net_write(a, 0x1A00, 1, map8[0], 4), 0);
    assert_int_equal(net_write(a, 0x1A00, 0, 4, 1), 0);
    /* invalidate */
    assert_int_equal(net_write(a, 0x1800, 1, INVALID | 0x185, 4), 0);
    assert_false(co_pdo_is_active(&a->pdo, false, 1));
    assert_false(co_pdo_trigger(&a->pdo, 1));
    /* entries only while sub 0 = 0 */
    assert_int_equal(net_write(a, 0x1A00, 1, MAP(0x2002, 0, 32), 4), CO_ABORT_INVALID_VALUE);
    assert_int_equal(net_write(a, 0x1A00, 0, 0, 1), 0);
    /* enabling an empty mapping is refused */
    assert_int_equal(net_write(a, 0x1800, 1, 0x185, 4), CO_ABORT_INVALID_VALUE);
    /* entries that cannot be mapped */
    assert_int_equal(net_write(a, 0x1A00, 1, MAP(0x2F00, 0, 8), 4), CO_ABORT_NO_MAP);
    assert_int_equal(net_write(a, 0x1A00, 1, MAP(0x2005, 0, 32), 4), CO_ABORT_NO_MAP);
    assert_int_equal(net_write(a, 0x1A00, 1, MAP(0x2002, 0, 40), 4), CO_ABORT_NO_MAP);
    assert_int_equal(net_write(a, 0x1A00, 1, MAP(0x0005, 0, 8), 4), CO_ABORT_NO_MAP);
    assert_int_equal(net_write(b, 0x1600, 1, MAP(0x2004, 0, 8), 4), CO_ABORT_INVALID_VALUE);
    /* new mapping: 3 x U32 exceeds 8 bytes on classic */
    assert_int_equal(net_write(a, 0x1A00, 1, MAP(0x2000, 0, 8), 4), 0);
    assert_int_equal(net_write(a, 0x1A00, 2, MAP(0x2003, 1, 8), 4), 0);
    assert_int_equal(net_write(a, 0x1A00, 3, MAP(0x2002, 0, 32), 4), 0);
    assert_int_equal(net_write(a, 0x1A00, 4, MAP(0x2002, 0, 32), 4), 0);
    assert_int_equal(net_write(a, 0x1A00, 5, MAP(0x2002, 0, 32), 4), 0);
    assert_int_equal(net_write(a, 0x1A00, 0, 9, 1), CO_ABORT_VALUE_HIGH);
    if (mode == CO_MODE_CLASSIC) {
        assert_int_equal(net_write(a, 0x1A00, 0, 4, 1), CO_ABORT_MAP_LENGTH);
    } else {
        assert_int_equal(net_write(a, 0x1A00, 0, 8, 1), CO_ABORT_NO_MAP);   /* entry 6 is 0 */
    }
    assert_int_equal(net_write(a, 0x1A00, 0, 3, 1), 0);
    assert_int_equal(net_write(a, 0x1A00, 0, 3, 1), 0);
    /* re-enable: the new layout goes out */
    assert_int_equal(net_write(a, 0x1800, 1, 0x185, 4), 0);
    assert_true(co_pdo_is_active(&a->pdo, false, 1));
    put(a, 0x2000, 0, 0x99, 1);
    put(a, 0x2003, 1, 0x11, 1);
    trigger_at(fx, a, 1, MS(1), true);
    tu_assert_logged(&fx->tb, 0, 0x185, expect, 6);
    /* b's mapping (8 bytes) finds 6 too short */
    assert_int_equal(b->nerr, 1);
    assert_int_equal(b->err[0].code, 0x8210);
    /* dummy entries are fine in RPDOs */
    assert_int_equal(net_write(b, 0x1400, 1, INVALID | 0x185, 4), 0);
    assert_int_equal(net_write(b, 0x1600, 0, 0, 1), 0);
    assert_int_equal(net_write(b, 0x1600, 1, MAP(0x0005, 0, 8), 4), 0);
    assert_int_equal(net_write(b, 0x1600, 2, MAP(0x0005, 0, 8), 4), 0);
    assert_int_equal(net_write(b, 0x1600, 3, MAP(0x2002, 0, 32), 4), 0);
    assert_int_equal(net_write(b, 0x1600, 0, 3, 1), 0);
    assert_int_equal(net_write(b, 0x1400, 1, 0x185, 4), 0);
    put(a, 0x2002, 0, 0x44332211, 4);
    trigger_at(fx, a, 1, MS(2), true);
    assert_int_equal(get(b, 0x2002, 0, 4), 0x44332211);
    assert_int_equal(get(b, 0x2000, 0, 1), 0x11);   /* under a dummy: unchanged */
    assert_int_equal(b->nreceived, 1);
    assert_int_equal(b->nerr, 1);
    fx_free(fx);
}

static void test_mapping_procedure_classic(void **state)
{
    (void)state;
    check_mapping_procedure(CO_MODE_CLASSIC);
}

static void test_mapping_procedure_fd(void **state)
{
    (void)state;
    check_mapping_procedure(CO_MODE_FD);
}

/* Communication parameters: types, inhibit / SYNC start only while invalid,
 * COB-ID values, conflicts. */
static void test_comm_parameter_aborts(void **state)
{
    fx_t *fx = fx_new(CO_MODE_CLASSIC, SMALL_ENTRIES);
    node_t *a = &fx->a, *b = &fx->b;
    (void)state;
    add_pdo(a, false, 1, 0x185, 254, 0, 0, 0, 8, map8, 4);
    add_pdo(b, true, 1, 0x185, 254, 0, 0, 0, 8, rmap8, 4);
    add_pdo(b, true, 2, INVALID | 0x285, 254, 0, 0, 0, 8, rmap8, 4);
    fx_finish(fx);
    for (unsigned t = 241; t <= 251; t++) {
        assert_int_equal(net_write(a, 0x1800, 2, t, 1), CO_ABORT_INVALID_VALUE);
    }
    assert_int_equal(net_write(a, 0x1800, 2, 252, 1), 0);
    assert_int_equal(net_write(a, 0x1800, 2, 253, 1), 0);
    assert_int_equal(net_write(a, 0x1800, 2, 0, 1), 0);
    assert_int_equal(net_write(a, 0x1800, 2, 240, 1), 0);
    assert_int_equal(net_write(a, 0x1800, 2, 255, 1), 0);
    assert_int_equal(net_write(b, 0x1400, 2, 252, 1), CO_ABORT_INVALID_VALUE);
    assert_int_equal(net_write(b, 0x1400, 2, 253, 1), CO_ABORT_INVALID_VALUE);
    assert_int_equal(net_write(b, 0x1400, 2, 0, 1), 0);
    /* inhibit time and SYNC start: only while invalid */
    assert_int_equal(net_write(a, 0x1800, 3, 10, 2), CO_ABORT_INVALID_VALUE);
    assert_int_equal(net_write(a, 0x1800, 3, 0, 2), 0);
    assert_int_equal(net_write(a, 0x1800, 6, 5, 1), CO_ABORT_INVALID_VALUE);
    assert_int_equal(net_write(a, 0x1800, 1, INVALID | 0x185, 4), 0);
    assert_int_equal(net_write(a, 0x1800, 3, 10, 2), 0);
    assert_int_equal(net_write(a, 0x1800, 6, 241, 1), CO_ABORT_INVALID_VALUE);
    assert_int_equal(net_write(a, 0x1800, 6, 240, 1), 0);
    /* event timer: at any time */
    assert_int_equal(net_write(b, 0x1400, 5, 100, 2), 0);
    /* COB-ID values: restricted ids, bits 11..28 of an 11-bit id */
    assert_int_equal(net_write(a, 0x1800, 1, 0x701, 4), CO_ABORT_INVALID_VALUE);
    assert_int_equal(net_write(a, 0x1800, 1, 0x000, 4), CO_ABORT_INVALID_VALUE);
    assert_int_equal(net_write(a, 0x1800, 1, 0x10185, 4), CO_ABORT_INVALID_VALUE);
    assert_int_equal(net_write(a, 0x1800, 1, EXT | 0x10185, 4), 0);
    /* the CAN-ID changes only while invalid (co_cob_id) */
    assert_int_equal(net_write(a, 0x1800, 1, EXT | 0x10186, 4), CO_ABORT_INVALID_VALUE);
    /* an RPDO COB-ID another RPDO uses */
    assert_int_equal(net_write(b, 0x1401, 1, 0x185, 4), CO_ABORT_INVALID_VALUE);
    assert_int_equal(net_write(b, 0x1401, 1, 0x285, 4), 0);
    assert_true(co_pdo_is_active(&b->pdo, true, 2));
    fx_free(fx);
}

/* Not operational: nothing sent, nothing applied; timers start on entry. */
static void test_not_operational(void **state)
{
    fx_t *fx = fx_new(CO_MODE_CLASSIC, SMALL_ENTRIES);
    const uint8_t d[8] = {1, 2, 3, 4, 5, 6, 7, 8};
    (void)state;
    add_pdo(&fx->a, false, 1, 0x185, 254, 0, 10, 0, 8, map8, 4);
    add_pdo(&fx->a, false, 2, 0x186, 1, 0, 0, 0, 8, map8, 4);
    add_pdo(&fx->b, true, 1, 0x185, 254, 0, 0, 0, 8, rmap8, 4);
    add_pdo(&fx->b, true, 2, 0x186, 1, 0, 0, 0, 8, rmap8, 4);
    fx_finish(fx);
    assert_false(co_pdo_trigger(&fx->a.pdo, 1));
    assert_int_equal(co_pdo_trigger_object(&fx->a.pdo, 0x2000, 0), 0);
    sync_at(fx, MS(1), 0);
    tu_run_until(&fx->tb, MS(50));
    assert_int_equal(fx->tb.log_count, 0);
    inject(fx, 0x185, 0, d, 8, MS(51));
    assert_int_equal(get(&fx->b, 0x2000, 0, 1), 0x11);
    assert_int_equal(co_pdo_stats(&fx->b.pdo)->rx_not_operational, 1);
    assert_int_equal(fx->b.nreceived, 0);
    /* a buffered synchronous RPDO is dropped when leaving operational */
    fx_operational(fx);
    inject(fx, 0x186, 0, d, 8, MS(52));
    co_pdo_set_operational(&fx->b.pdo, false);
    co_pdo_set_operational(&fx->b.pdo, true);
    co_pdo_sync(&fx->b.pdo, 0);
    assert_int_equal(fx->b.nreceived, 0);
    tu_run_until(&fx->tb, MS(62));
    /* the frame injected at 51 ms, then the event timer's from 61 ms */
    assert_int_equal(tu_log_count_id(&fx->tb, 0x185), 2);
    assert_int_equal(fx->tb.log[tu_log_find_id(&fx->tb, 0x185, 1)].t_us, MS(61));
    fx_free(fx);
}

/* trigger by object: every event-driven TPDO (0, 254, 255) mapping it. */
static void test_trigger_object_and_before_send(void **state)
{
    const uint32_t m1[1] = {MAP(0x2001, 0, 16)};
    const uint32_t m2[2] = {MAP(0x2000, 0, 8), MAP(0x2001, 0, 16)};
    const uint8_t e2[3] = {0x5D, 0x22, 0x22};
    fx_t *fx = fx_new(CO_MODE_FD, SMALL_ENTRIES);
    (void)state;
    add_pdo(&fx->a, false, 1, 0x181, 254, 0, 0, 0, 1, m1, 1);
    add_pdo(&fx->a, false, 2, 0x182, 255, 0, 0, 0, 2, m2, 2);
    add_pdo(&fx->a, false, 3, 0x183, 1, 0, 0, 0, 1, m1, 1);
    add_pdo(&fx->a, false, 4, 0x184, 0, 0, 0, 0, 1, m1, 1);
    add_pdo(&fx->a, false, 5, 0x188, 254, 0, 0, 0, 2, m2, 2);
    fx_finish(fx);
    fx_operational(fx);
    fx->a.refresh_number = 2;
    fx->a.refresh_value = 0x5D;
    tu_step(&fx->tb, MS(1));
    assert_int_equal(co_pdo_trigger_object(&fx->a.pdo, 0x2001, 0), 4);
    assert_int_equal(co_pdo_trigger_object(&fx->a.pdo, 0x2005, 0), 0);
    assert_int_equal(co_pdo_trigger_object(&fx->a.pdo, 0x2F00, 0), 0);
    tu_step(&fx->tb, MS(1));
    assert_int_equal(tu_log_count_id(&fx->tb, 0x181), 1);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x182), 1);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x183), 0);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x184), 0);   /* type 0: at the SYNC */
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, 0x182, 0), 0x182, e2, 3);
    sync_at(fx, MS(2), 0);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x184), 1);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x183), 1);
    fx_free(fx);
}

/* RTR on classic lines: 253 sampled at the RTR, 252 sampled at the SYNC,
 * bit 30 set = no answer; FD lines refuse 252/253. */
static void test_rtr(void **state)
{
    const uint32_t m[1] = {MAP(0x2000, 0, 8)};
    fx_t *fx = fx_new(CO_MODE_CLASSIC, SMALL_ENTRIES);
    (void)state;
    add_pdo(&fx->a, false, 1, 0x181, 253, 0, 0, 0, 1, m, 1);
    add_pdo(&fx->a, false, 2, 0x182, 252, 0, 0, 0, 1, m, 1);
    add_pdo(&fx->a, false, 3, NO_RTR | 0x183, 254, 0, 0, 0, 1, m, 1);
    add_pdo(&fx->a, false, 4, EXT | 0x1234567, 253, 0, 0, 0, 1, m, 1);
    fx_finish(fx);
    fx_operational(fx);
    assert_false(co_pdo_trigger(&fx->a.pdo, 1));
    put(&fx->a, 0x2000, 0, 0x21, 1);
    inject(fx, 0x181, CO_FRAME_RTR, NULL, 1, MS(1));
    assert_int_equal(tu_log_count_id(&fx->tb, 0x181), 2);   /* RTR + answer */
    {
        long i = tu_log_find_id(&fx->tb, 0x181, 1);
        const uint8_t e[1] = {0x21};
        tu_assert_logged(&fx->tb, i, 0x181, e, 1);
    }
    /* 252 before any SYNC: nothing sampled, no answer */
    inject(fx, 0x182, CO_FRAME_RTR, NULL, 1, MS(2));
    assert_int_equal(tu_log_count_id(&fx->tb, 0x182), 1);
    assert_int_equal(co_pdo_stats(&fx->a.pdo)->rtr_refused, 1);
    sync_at(fx, MS(3), 0);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x182), 1);   /* sampled, not sent */
    put(&fx->a, 0x2000, 0, 0x22, 1);
    inject(fx, 0x182, CO_FRAME_RTR, NULL, 1, MS(4));
    assert_int_equal(tu_log_count_id(&fx->tb, 0x182), 3);
    assert_int_equal(fx->tb.log[tu_log_find_id(&fx->tb, 0x182, 2)].frame.data[0], 0x21);
    /* bit 30 set: not answered (the line counts it) */
    inject(fx, 0x183, CO_FRAME_RTR, NULL, 1, MS(5));
    assert_int_equal(tu_log_count_id(&fx->tb, 0x183), 1);
    assert_int_equal(fx->l[0].line.stats.rx_rtr, 1);
    /* 29-bit */
    inject(fx, 0x1234567, CO_FRAME_RTR | CO_FRAME_EXT, NULL, 1, MS(6));
    assert_int_equal(tu_log_count_id(&fx->tb, 0x1234567), 2);
    assert_int_equal(fx->tb.log[tu_log_find_id(&fx->tb, 0x1234567, 1)].frame.flags,
                     CO_FRAME_EXT);
    assert_int_equal(co_pdo_stats(&fx->a.pdo)->rtr_answered, 3);
    fx_free(fx);
}

static void test_rtr_types_refused_on_fd(void **state)
{
    const uint32_t m[1] = {MAP(0x2000, 0, 8)};
    fx_t *fx = fx_new(CO_MODE_FD, SMALL_ENTRIES);
    (void)state;
    add_pdo(&fx->a, false, 1, 0x181, 254, 0, 0, 0, 1, m, 1);
    add_pdo(&fx->a, false, 2, 0x182, 252, 0, 0, 0, 1, m, 1);   /* default: never active */
    fx_finish(fx);
    assert_int_equal(net_write(&fx->a, 0x1800, 2, 252, 1), CO_ABORT_INVALID_VALUE);
    assert_int_equal(net_write(&fx->a, 0x1800, 2, 253, 1), CO_ABORT_INVALID_VALUE);
    assert_false(co_pdo_is_active(&fx->a.pdo, false, 2));
    assert_int_equal(co_pdo_stats(&fx->a.pdo)->config_invalid, 1);
    fx_free(fx);
}

/* A reset loads defaults without re-reading; co_pdo_reload applies them. */
static void test_reload(void **state)
{
    fx_t *fx = pair(CO_MODE_CLASSIC, 254, 0, 0, 254, 0);
    (void)state;
    assert_int_equal(net_write(&fx->a, 0x1800, 1, INVALID | 0x185, 4), 0);
    assert_false(co_pdo_is_active(&fx->a.pdo, false, 1));
    co_od_load_defaults(&fx->a.od, CO_GROUP_COMMUNICATION);
    assert_false(co_pdo_is_active(&fx->a.pdo, false, 1));
    co_pdo_reload(&fx->a.pdo);
    assert_true(co_pdo_is_active(&fx->a.pdo, false, 1));
    trigger_at(fx, &fx->a, 1, MS(1), true);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x185), 1);
    /* an application write (co_od_put) takes effect at once */
    put(&fx->a, 0x1800, 1, INVALID | 0x185, 4);
    assert_false(co_pdo_is_active(&fx->a.pdo, false, 1));
    fx_free(fx);
}

/* 512 TPDOs on a, 512 RPDOs on b (the last 16 with 29-bit COB-IDs). */
static uint32_t big_cob(uint16_t n)
{
    return n > 496 ? (EXT | (0x100000u + n)) : (uint32_t)(0x180u + n);
}

static void test_512_each(void **state)
{
    fx_t *fx = fx_new(CO_MODE_FD, BIG_ENTRIES);
    uint32_t channels = 0, items = 0;
    uint16_t n;
    (void)state;
    for (n = 1; n <= 512; n++) {
        const uint32_t m[1] = {MAP(0x2003, (n % 64) + 1, 8)};
        add_pdo(&fx->a, false, n, big_cob(n), 254, 0, 0, 0, 1, m, 1);
        add_pdo(&fx->b, true, n, big_cob(n), 254, 0, 0, 0, 1, m, 1);
    }
    fx_finish(fx);
    assert_true(co_pdo_need(&fx->a.od, &channels, &items));
    assert_int_equal(channels, 512);
    assert_int_equal(items, 512);
    fx_operational(fx);
    for (n = 1; n <= 512; n++) {
        assert_true(co_pdo_is_active(&fx->a.pdo, false, n));
        assert_true(co_pdo_is_active(&fx->b.pdo, true, n));
        put(&fx->a, 0x2003, (uint8_t)((n % 64) + 1), (uint8_t)(0xA0 + n % 64), 1);
        put(&fx->b, 0x2003, (uint8_t)((n % 64) + 1), 0, 1);
    }
    for (n = 1; n <= 512; n++) {
        assert_true(co_pdo_trigger(&fx->a.pdo, n));
        if (n % 128 == 0) {
            tu_step(&fx->tb, MS(n));
        }
    }
    tu_step(&fx->tb, MS(600));
    assert_int_equal(co_pdo_stats(&fx->a.pdo)->tx_frames, 512);
    assert_int_equal(co_pdo_stats(&fx->b.pdo)->rx_frames, 512);
    assert_int_equal(fx->b.nreceived, 512);
    for (n = 1; n <= 512; n++) {
        assert_int_equal(fx->b.received[n - 1], n);
        assert_int_equal(get(&fx->b, 0x2003, (uint8_t)((n % 64) + 1), 1), 0xA0 + n % 64);
    }
    assert_int_equal(tu_log_count_id(&fx->tb, 0x100000u + 512), 1);
    assert_int_equal(fx->tb.log[fx->tb.log_count - 1].frame.flags,
                     CO_FRAME_FD | CO_FRAME_BRS | CO_FRAME_EXT);
    assert_int_equal(co_pdo_stats(&fx->b.pdo)->config_invalid, 0);
    fx_free(fx);
}

/* 10 000 random frames (ids, lengths, RTR, 29-bit) at both nodes with
 * SYNCs and window closes in between: no crash, everything accounted. */
static void check_random(co_mode_t mode)
{
    fx_t *fx = fx_new(mode, SMALL_ENTRIES);
    uint64_t seed = 0x1234567u + (uint64_t)mode, t = MS(1);
    const co_pdo_stats_t *sb;
    uint32_t taken;
    int i;
    add_pdo(&fx->a, false, 1, 0x185, mode == CO_MODE_FD ? 254 : 253, 0, 0, 0, 8, map8, 4);
    add_pdo(&fx->a, false, 2, 0x186, 254, 5, 7, 0, 8, map8, 4);
    add_pdo(&fx->a, false, 3, 0x187, 3, 0, 0, 2, 8, map8, 4);
    add_pdo(&fx->b, true, 1, 0x205, 254, 0, 3, 0, 8, rmap8, 4);
    add_pdo(&fx->b, true, 2, 0x206, 7, 0, 0, 0, 8, rmap8, 2);
    add_pdo(&fx->b, true, 3, EXT | 0x207, 255, 0, 0, 0, 8, rmap8, 1);
    fx_finish(fx);
    fx_operational(fx);
    for (i = 0; i < 10000; i++) {
        uint64_t r = tu_rand(&seed);
        co_frame_t f;
        uint8_t data[64];
        uint8_t len, flags = 0;
        uint32_t id;
        for (int k = 0; k < 64; k++) {
            data[k] = (uint8_t)tu_rand(&seed);
        }
        switch (r % 4) {
        case 0: id = 0x205 + (uint32_t)(r >> 8) % 3; break;
        case 1: id = 0x185 + (uint32_t)(r >> 8) % 3; break;
        case 2: id = (uint32_t)(r >> 8) & 0x7FF; break;
        default: id = (uint32_t)(r >> 8) & 0x1FFFFFFF; flags |= CO_FRAME_EXT; break;
        }
        if ((r >> 40) % 4 == 0) {
            id = 0x207;
            flags |= CO_FRAME_EXT;
        }
        if (mode == CO_MODE_FD && (r >> 44) % 2) {
            flags |= CO_FRAME_FD;
            len = (uint8_t)co_fd_len_round((r >> 48) % 65);
        } else {
            len = (uint8_t)((r >> 48) % 9);
            if ((r >> 56) % 8 == 0) {
                flags |= CO_FRAME_RTR;
            }
        }
        if ((flags & CO_FRAME_EXT) == 0) {
            id &= 0x7FF;
        }
        f = tu_frame(id, flags, data, len);
        assert_true(co_line_send_raw(fx->r, &f));
        if (i % 7 == 0) {
            assert_true(co_pdo_trigger(&fx->a.pdo, 2));
        }
        if (i % 13 == 0) {
            co_pdo_sync(&fx->a.pdo, (uint8_t)(i % 5));
            co_pdo_sync(&fx->b.pdo, (uint8_t)(i % 5));
        }
        if (i % 17 == 0) {
            co_pdo_sync_window_closed(&fx->a.pdo);
        }
        if (i % 1000 == 999) {
            co_pdo_set_operational(&fx->b.pdo, false);
            co_pdo_set_operational(&fx->b.pdo, true);
        }
        t += 100 + (r >> 20) % 900;
        tu_run_until(&fx->tb, t);
        if (fx->tb.log_count > TU_LOG_MAX - 100) {
            tu_log_clear(&fx->tb);
        }
    }
    sb = co_pdo_stats(&fx->b.pdo);
    assert_int_equal((uint32_t)fx->b.nreceived, sb->rx_frames);
    assert_true(sb->rx_timeouts > 10);
    assert_true(fx->b.nerr > 10);
    taken = sb->rx_frames + sb->rx_short + sb->rx_not_ours;
    assert_true(sb->rx_frames > 100);
    assert_true(sb->rx_short > 100);
    assert_true(sb->rx_not_ours > 1000);
    assert_true(taken > 5000);
    assert_true(co_pdo_stats(&fx->a.pdo)->tx_frames > 500);
    if (mode == CO_MODE_CLASSIC) {
        assert_true(co_pdo_stats(&fx->a.pdo)->rtr_answered > 10);
    } else {
        assert_int_equal(co_pdo_stats(&fx->a.pdo)->rtr_answered, 0);
    }
    fx_free(fx);
}

static void test_random_classic(void **state)
{
    (void)state;
    check_random(CO_MODE_CLASSIC);
}

static void test_random_fd(void **state)
{
    (void)state;
    check_random(CO_MODE_FD);
}

/* 29-bit RPDO on a classic line; deinit unhooks everything. */
static void test_ext_rpdo_and_deinit(void **state)
{
    const uint32_t rm[1] = {MAP(0x2002, 0, 32)};
    const uint8_t d[4] = {0xEF, 0xBE, 0xAD, 0xDE};
    fx_t *fx = fx_new(CO_MODE_CLASSIC, SMALL_ENTRIES);
    co_line_t *b = &fx->l[1].line;
    (void)state;
    add_pdo(&fx->b, true, 4, EXT | 0x1ABCDE, 255, 0, 0, 0, 1, rm, 1);
    fx_finish(fx);
    fx_operational(fx);
    inject(fx, 0x1ABCDE & 0x7FF, 0, d, 4, MS(1));   /* the same low bits, 11-bit: not it */
    assert_int_equal(get(&fx->b, 0x2002, 0, 4), 0x33333333);
    assert_int_equal(co_pdo_stats(&fx->b.pdo)->rx_not_ours, 1);
    inject(fx, 0x1ABCDE, CO_FRAME_EXT, d, 4, MS(2));
    assert_int_equal(get(&fx->b, 0x2002, 0, 4), 0xDEADBEEF);
    assert_int_equal(fx->b.received[0], 4);
    assert_int_equal(b->other_count, 1);
    co_pdo_deinit(&fx->b.pdo);
    fx->b.ready = false;
    assert_int_equal(b->other_count, 0);
    assert_int_equal(fx->b.od.sub_count, 1);   /* only co_cob_id's */
    inject(fx, 0x1ABCDE, CO_FRAME_EXT, d, 4, MS(3));
    assert_int_equal(b->stats.rx_unhandled, 2);
    fx_free(fx);
}

/* A before-send callback that disables its own TPDO: nothing is sent. */
static void disable_self(co_pdo_t *pdo, uint16_t number, void *user)
{
    node_t *n = user;
    uint8_t v[4] = {0x85, 0x01, 0x00, 0x80};
    (void)pdo;
    (void)number;
    n->before_send++;
    assert_int_equal(co_od_put(&n->od, 0x1800, 1, v, 4), 0);
}

static const co_pdo_indications_t disabling = {on_error, on_received, disable_self, on_rx_error};

static void test_before_send_disables(void **state)
{
    fx_t *fx = pair(CO_MODE_CLASSIC, 254, 0, 0, 254, 0);
    (void)state;
    fx->a.pdo.ind = &disabling;
    trigger_at(fx, &fx->a, 1, MS(1), true);
    assert_int_equal(fx->a.before_send, 1);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x185), 0);
    assert_false(co_pdo_is_active(&fx->a.pdo, false, 1));
    assert_int_equal(co_pdo_stats(&fx->a.pdo)->tx_frames, 0);
    fx_free(fx);
}

/* Wrong API use. */
static void test_api_misuse(void **state)
{
    fx_t *fx = fx_new(CO_MODE_CLASSIC, SMALL_ENTRIES);
    co_pdo_t p;
    co_pdo_config_t cfg;
    uint32_t c = 0, i = 0;
    co_od_t unsealed;
    co_od_entry_t e[4];
    uint8_t pool[64];
    co_od_subscription_t subs[1];
    (void)state;
    add_pdo(&fx->a, false, 1, 0x185, 254, 0, 0, 0, 8, map8, 4);
    fx_finish(fx);
    co_od_init(&unsealed, CO_MODE_CLASSIC, e, 4, pool, sizeof pool, subs, 1);
    assert_false(co_pdo_need(&unsealed, &c, &i));
    memset(&cfg, 0, sizeof cfg);
    assert_false(co_pdo_init(&p, &fx->l[1].line, &unsealed, &cfg));
    assert_false(co_pdo_init(&p, &fx->l[1].line, &fx->a.od, NULL));
    assert_false(co_pdo_init(&p, &fx->l[1].line, &fx->a.od, &cfg));   /* no storage */
    fx_free(fx);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_event_classic),
        cmocka_unit_test(test_event_fd),
        cmocka_unit_test(test_fd_13_bytes_padded),
        cmocka_unit_test(test_fd_64_entries),
        cmocka_unit_test(test_inhibit),
        cmocka_unit_test(test_event_timer),
        cmocka_unit_test(test_sync_tpdo_types),
        cmocka_unit_test(test_sync_start_without_counter),
        cmocka_unit_test(test_sync_rpdo),
        cmocka_unit_test(test_sync_window_and_retry),
        cmocka_unit_test(test_rpdo_deadline),
        cmocka_unit_test(test_length_errors_classic),
        cmocka_unit_test(test_length_errors_fd),
        cmocka_unit_test(test_rx_error_ends_when_disabled),
        cmocka_unit_test(test_rx_timeout_ends_when_disabled),
        cmocka_unit_test(test_rx_errors_end_at_reload),
        cmocka_unit_test(test_mapping_procedure_classic),
        cmocka_unit_test(test_mapping_procedure_fd),
        cmocka_unit_test(test_comm_parameter_aborts),
        cmocka_unit_test(test_not_operational),
        cmocka_unit_test(test_trigger_object_and_before_send),
        cmocka_unit_test(test_rtr),
        cmocka_unit_test(test_rtr_types_refused_on_fd),
        cmocka_unit_test(test_reload),
        cmocka_unit_test(test_512_each),
        cmocka_unit_test(test_random_classic),
        cmocka_unit_test(test_random_fd),
        cmocka_unit_test(test_ext_rpdo_and_deinit),
        cmocka_unit_test(test_before_send_disables),
        cmocka_unit_test(test_api_misuse),
    };
    int failed = cmocka_run_group_tests_name("CAN-ID tables", tests, group_with_id_maps, NULL);
    return failed + cmocka_run_group_tests_name("channel scan", tests, group_with_scan, NULL);
}
