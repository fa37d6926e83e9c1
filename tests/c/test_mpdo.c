/* Multiplexed PDOs (co_mpdo over co_pdo) on the in-process bus, fake clock.
 *
 * Lines: a (node 5, producer: TPDO1 = DAM on 0x185, TPDO2 = SAM on 0x285,
 * scanner list 0x1FA0), b (node 6, consumer: RPDO1 = DAM on 0x185, RPDO2 =
 * SAM on 0x285, dispatcher list 0x1FD0), r (no services: raw frames). The
 * sniffer checks the CAN-ID, flags, length and every byte on the bus. */
#include "test_od_util.h"

#include "co_cob_id.h"
#include "canopenfd/co_mpdo.h"

#define ID_A 5
#define ID_B 6
#define MS(x) ((uint64_t)(x) * TU_MS)
#define INVALID 0x80000000u
#define BOTH (CO_OD_MAP_TPDO | CO_OD_MAP_RPDO)
#define DAM_ID 0x185u
#define SAM_ID 0x285u
#define MAX_REC 64
/* dispatcher entry: block, local index:sub, producer index:sub, producer node */
#define DISPATCH(blk, li, ls, pi, ps, node)                                                    \
    (((uint64_t)(blk) << 56) | ((uint64_t)(li) << 40) | ((uint64_t)(ls) << 32) |               \
     ((uint64_t)(pi) << 16) | ((uint64_t)(ps) << 8) | (uint64_t)(node))
/* scanner entry: block, index, sub */
#define SCAN(blk, i, s) (((uint32_t)(blk) << 24) | ((uint32_t)(i) << 8) | (uint32_t)(s))

typedef struct event_rec {
    uint16_t rpdo;
    co_mpdo_msg_t msg;
    uint16_t index;                 /* received, refused: the local object */
    uint8_t sub;
    uint32_t abort;                 /* refused */
    uint16_t emcy;                  /* error */
} event_rec_t;

typedef struct node {
    co_od_t od;
    co_od_entry_t entries[600];
    uint8_t pool[8192];
    co_od_subscription_t subs[4];
    co_pdo_t pdo;
    co_pdo_channel_t *channels;
    co_pdo_map_item_t *items;
    co_mpdo_t mpdo;
    co_line_t *line;
    bool ready;
    event_rec_t received[MAX_REC], refused[MAX_REC], errors[MAX_REC];
    int nreceived, nrefused, nerrors;
} node_t;

typedef struct fx {
    tu_bus_t tb;
    tu_line_t l[3];
    co_line_t *r;
    node_t a, b;
    uint64_t t;
} fx_t;

static void on_received(co_mpdo_t *m, uint16_t rpdo, const co_mpdo_msg_t *msg, uint16_t index,
                        uint8_t sub, void *user)
{
    node_t *n = user;
    (void)m;
    assert_true(n->nreceived < MAX_REC);
    n->received[n->nreceived++] = (event_rec_t){rpdo, *msg, index, sub, 0, 0};
}

static void on_refused(co_mpdo_t *m, uint16_t rpdo, const co_mpdo_msg_t *msg, uint16_t index,
                       uint8_t sub, uint32_t abort, void *user)
{
    node_t *n = user;
    (void)m;
    assert_true(n->nrefused < MAX_REC);
    n->refused[n->nrefused++] = (event_rec_t){rpdo, *msg, index, sub, abort, 0};
}

static void on_error(co_mpdo_t *m, uint16_t code, uint16_t rpdo, void *user)
{
    node_t *n = user;
    co_mpdo_msg_t none;
    (void)m;
    memset(&none, 0, sizeof none);
    assert_true(n->nerrors < MAX_REC);
    n->errors[n->nerrors++] = (event_rec_t){rpdo, none, 0, 0, 0, code};
}

static const co_mpdo_indications_t indications = {on_received, on_refused, on_error};

static void def(node_t *n, uint16_t index, uint8_t sub, uint8_t obj, uint8_t type,
                uint8_t access, uint16_t flags, uint64_t value)
{
    tu_od_add_value(&n->od, index, sub, obj, type, access, flags, value);
}

/* An MPDO: communication (COB-ID, type, inhibit, event timer) and a
 * mapping object with sub 0 = kind (0xFE / 0xFF) and one unused entry. */
static void add_mpdo(node_t *n, bool rpdo, uint16_t num, uint32_t cob, uint8_t type,
                     uint16_t inhibit, uint8_t kind)
{
    uint16_t comm = (uint16_t)((rpdo ? 0x1400 : 0x1800) + num - 1);
    uint16_t map = (uint16_t)((rpdo ? 0x1600 : 0x1A00) + num - 1);
    def(n, comm, 0, REC, U8, RO, 0, 5);
    def(n, comm, 1, REC, U32, RW, 0, cob);
    def(n, comm, 2, REC, U8, RW, 0, type);
    def(n, comm, 3, REC, U16, RW, 0, inhibit);
    def(n, comm, 5, REC, U16, RW, 0, 0);
    def(n, map, 0, REC, U8, RW, 0, kind);
    def(n, map, 1, REC, U32, RW, 0, 0);
}

/* Application objects of both nodes: 0x2000 U8, 0x2001 U16, 0x2002 U32,
 * 0x2003 U8[16], 0x2004 U8 read-only, 0x2005 U32 not mappable, 0x2006
 * INTEGER64 (too long for an MPDO). */
static void node_begin(node_t *n, co_mode_t mode)
{
    memset(n, 0, sizeof *n);
    co_od_init(&n->od, mode, n->entries, 600, n->pool, sizeof n->pool, n->subs, 4);
    def(n, 0x2000, 0, VAR, U8, RW, BOTH, 0x11);
    def(n, 0x2001, 0, VAR, U16, RW, BOTH, 0x2222);
    def(n, 0x2002, 0, VAR, U32, RW, BOTH, 0x33333333);
    def(n, 0x2003, 0, ARR, U8, RO, 0, 16);
    for (uint8_t s = 1; s <= 16; s++) {
        def(n, 0x2003, s, ARR, U8, RW, BOTH, s);
    }
    def(n, 0x2004, 0, VAR, U8, RO, BOTH, 0x44);
    def(n, 0x2005, 0, VAR, U32, RW, 0, 0x55555555);
    def(n, 0x2006, 0, VAR, I64, RW, BOTH, 0x66);
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
    assert_true(co_pdo_init(&n->pdo, line, &n->od, &cfg));
    co_mpdo_init(&n->mpdo, &n->pdo, &indications, n);
    co_pdo_set_operational(&n->pdo, true);
    n->ready = true;
}

static void node_free(node_t *n)
{
    if (n->ready) {
        co_mpdo_deinit(&n->mpdo);
        co_pdo_deinit(&n->pdo);
    }
    free(n->channels);
    free(n->items);
}

/* The standard pair: a produces DAM and SAM MPDOs, b consumes them. */
static fx_t *pair(co_mode_t mode)
{
    fx_t *fx = calloc(1, sizeof *fx);
    assert_non_null(fx);
    tu_bus_init(&fx->tb, mode, mode == CO_MODE_FD);
    tu_bus_add_line(&fx->tb, &fx->l[0]);
    tu_bus_add_line(&fx->tb, &fx->l[1]);
    fx->r = tu_bus_add_line(&fx->tb, &fx->l[2]);
    co_line_set_node_id(&fx->l[0].line, ID_A);
    co_line_set_node_id(&fx->l[1].line, ID_B);
    node_begin(&fx->a, mode);
    node_begin(&fx->b, mode);
    add_mpdo(&fx->a, false, 1, DAM_ID, 254, 0, CO_PDO_MAP_DAM);
    add_mpdo(&fx->a, false, 2, SAM_ID, 255, 0, CO_PDO_MAP_SAM);
    def(&fx->a, 0x1FA0, 0, ARR, U8, RW, 0, 3);
    def(&fx->a, 0x1FA0, 1, ARR, U32, RW, 0, SCAN(0, 0x2000, 0));
    def(&fx->a, 0x1FA0, 2, ARR, U32, RW, 0, SCAN(3, 0x2003, 1));   /* subs 1..3 */
    def(&fx->a, 0x1FA0, 3, ARR, U32, RW, 0, SCAN(0, 0x2006, 0));   /* listed, too long */
    add_mpdo(&fx->b, true, 1, DAM_ID, 254, 0, CO_PDO_MAP_DAM);
    add_mpdo(&fx->b, true, 2, SAM_ID, 254, 0, CO_PDO_MAP_SAM);
    def(&fx->b, 0x1FD0, 0, ARR, U8, RW, 0, 3);
    def(&fx->b, 0x1FD0, 1, ARR, CO_TYPE_UNSIGNED64, RW, 0, DISPATCH(0, 0x2001, 0, 0x2000, 0, ID_A));
    def(&fx->b, 0x1FD0, 2, ARR, CO_TYPE_UNSIGNED64, RW, 0,
        DISPATCH(3, 0x2003, 10, 0x2003, 1, ID_A));   /* a's subs 1..3 -> b's 10..12 */
    def(&fx->b, 0x1FD0, 3, ARR, CO_TYPE_UNSIGNED64, RW, 0,
        DISPATCH(0, 0x2004, 0, 0x2002, 0, ID_A));    /* onto a read-only object */
    node_finish(&fx->a, &fx->l[0].line, ID_A);
    node_finish(&fx->b, &fx->l[1].line, ID_B);
    fx->t = MS(1);
    tu_step(&fx->tb, fx->t);
    return fx;
}

static void fx_free(fx_t *fx)
{
    node_free(&fx->a);
    node_free(&fx->b);
    free(fx);
}

/* Let the bus carry what was queued, 1 ms later. */
static void carry(fx_t *fx)
{
    fx->t += MS(1);
    tu_step(&fx->tb, fx->t);
}

static uint64_t get(node_t *n, uint16_t index, uint8_t sub, uint32_t len)
{
    return tu_od_value(&n->od, index, sub, len);
}

static void inject(fx_t *fx, uint32_t id, const uint8_t *data, uint8_t len)
{
    co_frame_t f = tu_frame(id, tu_bus_flags(&fx->tb), data, len);
    assert_true(co_line_send_raw(fx->r, &f));
    carry(fx);
}

/* The last frame on the bus is id with these 8 bytes. */
static void assert_last(fx_t *fx, uint32_t id, const uint8_t *bytes)
{
    assert_true(fx->tb.log_count > 0);
    tu_assert_logged(&fx->tb, (long)fx->tb.log_count - 1, id, bytes, 8);
}

static co_mpdo_status_t dam(fx_t *fx, uint8_t node, uint16_t index, uint8_t sub, uint32_t value,
                            uint8_t len)
{
    uint8_t data[4];
    tu_le_put(data, value, 4);
    return co_mpdo_send_dam(&fx->a.mpdo, 1, node, index, sub, data, len);
}

/* ------------------------------------------------------------- codec */

static void test_codec(void **state)
{
    static const uint8_t dam_bytes[8] = {0x86, 0x02, 0x20, 0x00, 0xD4, 0xC3, 0xB2, 0xA1};
    uint8_t out[8];
    co_mpdo_msg_t m;
    uint64_t seed = 0x1234;
    (void)state;
    assert_true(co_mpdo_decode(dam_bytes, 8, &m));
    assert_true(m.dam);
    assert_int_equal(m.node, 6);
    assert_int_equal(m.index, 0x2002);
    assert_int_equal(m.sub, 0);
    co_mpdo_encode(&m, out);
    assert_memory_equal(out, dam_bytes, 8);
    /* SAM: bit 7 clear, the producer's node-id */
    m.dam = false;
    m.node = 0x7F;
    co_mpdo_encode(&m, out);
    assert_int_equal(out[0], 0x7F);
    /* only 8 bytes decode; every other length is refused without reading
     * past it (exact-size heap buffers: ASan checks) */
    for (uint8_t len = 0; len <= CO_FRAME_MAX_DATA; len++) {
        uint8_t *buf = malloc(len == 0 ? 1 : len);
        assert_non_null(buf);
        for (uint8_t i = 0; i < len; i++) {
            buf[i] = (uint8_t)tu_rand(&seed);
        }
        assert_int_equal(co_mpdo_decode(buf, len, &m), len == 8);
        if (len == 8) {
            co_mpdo_encode(&m, out);
            assert_memory_equal(out, buf, 8);
        }
        free(buf);
    }
    assert_false(co_mpdo_decode(NULL, 8, &m));
}

/* ------------------------------------------------------------- DAM */

static void check_dam(co_mode_t mode)
{
    fx_t *fx = pair(mode);
    static const uint8_t to_b[8] = {0x86, 0x02, 0x20, 0x00, 0xD4, 0xC3, 0xB2, 0xA1};
    static const uint8_t to_all[8] = {0x80, 0x01, 0x20, 0x00, 0x34, 0x12, 0x00, 0x00};
    static const uint8_t to_7[8] = {0x87, 0x00, 0x20, 0x00, 0x99, 0x00, 0x00, 0x00};

    assert_int_equal(dam(fx, ID_B, 0x2002, 0, 0xA1B2C3D4, 4), CO_MPDO_OK);
    carry(fx);
    assert_last(fx, DAM_ID, to_b);
    assert_int_equal(get(&fx->b, 0x2002, 0, 4), 0xA1B2C3D4);
    assert_int_equal(fx->b.nreceived, 1);
    assert_int_equal(fx->b.received[0].rpdo, 1);
    assert_int_equal(fx->b.received[0].index, 0x2002);
    assert_true(fx->b.received[0].msg.dam);

    /* node 0 = every consumer */
    assert_int_equal(dam(fx, CO_MPDO_ALL_NODES, 0x2001, 0, 0x1234, 2), CO_MPDO_OK);
    carry(fx);
    assert_last(fx, DAM_ID, to_all);
    assert_int_equal(get(&fx->b, 0x2001, 0, 2), 0x1234);

    /* another node's DAM: ignored, nothing told */
    assert_int_equal(dam(fx, 7, 0x2000, 0, 0x99, 1), CO_MPDO_OK);
    carry(fx);
    assert_last(fx, DAM_ID, to_7);
    assert_int_equal(get(&fx->b, 0x2000, 0, 1), 0x11);
    assert_int_equal(co_mpdo_stats(&fx->b.mpdo)->rx_other_node, 1);
    assert_int_equal(co_mpdo_stats(&fx->b.mpdo)->rx_applied, 2);
    assert_int_equal(fx->b.nreceived, 2);
    assert_int_equal(fx->b.nrefused, 0);
    assert_int_equal(fx->b.nerrors, 0);
    assert_int_equal(co_mpdo_stats(&fx->a.mpdo)->tx_frames, 3);
    fx_free(fx);
}

static void test_dam_classic(void **state)
{
    (void)state;
    check_dam(CO_MODE_CLASSIC);
}

static void test_dam_fd(void **state)
{
    (void)state;
    check_dam(CO_MODE_FD);
}

/* Each refused DAM: nothing written, counted, told with its abort code and
 * the EMCY 0x8230; the next good frame is applied (nothing wedges). */
static void put_u32(node_t *n, uint16_t index, uint8_t sub, uint32_t value)
{
    uint8_t le[4] = {(uint8_t)value, (uint8_t)(value >> 8), (uint8_t)(value >> 16),
                     (uint8_t)(value >> 24)};
    assert_int_equal(co_od_put(&n->od, index, sub, le, 4), 0);
}

/* DAM the CiA 301 way: TPDO 1's mapping sub 1 names a's 0x2002 (32 bits);
 * its value goes to the same index:sub of the node given. */
static void test_dam_mapped(void **state)
{
    static const uint8_t to_b[8] = {0x86, 0x02, 0x20, 0x00, 0xD4, 0xC3, 0xB2, 0xA1};
    fx_t *fx = pair(CO_MODE_CLASSIC);
    (void)state;
    assert_int_equal(co_mpdo_send_dam_mapped(&fx->a.mpdo, 1, ID_B), CO_MPDO_ERR_OBJECT);
    put_u32(&fx->a, 0x1A00, 1, 0x20020020);
    put_u32(&fx->a, 0x2002, 0, 0xA1B2C3D4);
    assert_int_equal(co_mpdo_send_dam_mapped(&fx->a.mpdo, 1, ID_B), CO_MPDO_OK);
    carry(fx);
    assert_last(fx, DAM_ID, to_b);
    assert_int_equal(get(&fx->b, 0x2002, 0, 4), 0xA1B2C3D4);
    put_u32(&fx->a, 0x1A00, 1, 0x20020010);   /* 16 bits mapped: not the object's 32 */
    assert_int_equal(co_mpdo_send_dam_mapped(&fx->a.mpdo, 1, ID_B), CO_MPDO_ERR_OBJECT);
    put_u32(&fx->a, 0x1A00, 1, 0x20060040);   /* 64 bits: no MPDO carries them */
    assert_int_equal(co_mpdo_send_dam_mapped(&fx->a.mpdo, 1, ID_B), CO_MPDO_ERR_OBJECT);
    assert_int_equal(co_mpdo_send_dam_mapped(&fx->a.mpdo, 2, ID_B), CO_MPDO_ERR_CHANNEL);
    assert_int_equal(co_mpdo_send_dam_mapped(&fx->a.mpdo, 1, 128), CO_MPDO_ERR_ARGUMENT);
    assert_int_equal(co_mpdo_stats(&fx->a.mpdo)->tx_frames, 1);
    assert_int_equal(co_mpdo_stats(&fx->a.mpdo)->tx_refused, 5);
    fx_free(fx);
}

/* One SAM producer per device (CiA 301): a second TPDO is refused 0xFE. */
static void test_one_sam_producer(void **state)
{
    fx_t *fx = pair(CO_MODE_CLASSIC);
    co_od_t *od = &fx->a.od;
    (void)state;
    assert_int_equal(tu_od_net_write(od, 0x1800, 1, INVALID | DAM_ID, 4), 0);
    assert_int_equal(tu_od_net_write(od, 0x1A00, 0, 0, 1), 0);
    assert_int_equal(tu_od_net_write(od, 0x1A00, 0, CO_PDO_MAP_SAM, 1),
                     CO_ABORT_PARAM_INCOMPATIBLE);     /* TPDO 2 is the SAM producer */
    assert_int_equal(get(&fx->a, 0x1A00, 0, 1), 0);
    assert_int_equal(tu_od_net_write(od, 0x1A00, 0, CO_PDO_MAP_DAM, 1), 0);
    /* the application's own writes are not checked: the PDO stays inactive */
    assert_int_equal(tu_od_net_write(od, 0x1A00, 0, 0, 1), 0);
    {
        static const uint8_t sam = CO_PDO_MAP_SAM;
        uint32_t before = co_pdo_stats(&fx->a.pdo)->config_invalid;
        assert_int_equal(co_od_put(od, 0x1A00, 0, &sam, 1), 0);
        put_u32(&fx->a, 0x1800, 1, DAM_ID);
        assert_false(co_pdo_is_active(&fx->a.pdo, false, 1));
        assert_int_equal(co_pdo_stats(&fx->a.pdo)->config_invalid, before + 1);
        assert_true(co_pdo_is_active(&fx->a.pdo, false, 2));
        put_u32(&fx->a, 0x1800, 1, INVALID | DAM_ID);
    }
    assert_int_equal(tu_od_net_write(od, 0x1801, 1, INVALID | SAM_ID, 4), 0);
    assert_int_equal(tu_od_net_write(od, 0x1A01, 0, 0, 1), 0);   /* TPDO 2 stops */
    assert_int_equal(tu_od_net_write(od, 0x1A00, 0, 0, 1), 0);
    assert_int_equal(tu_od_net_write(od, 0x1A00, 0, CO_PDO_MAP_SAM, 1), 0);
    assert_int_equal(tu_od_net_write(od, 0x1800, 1, DAM_ID, 4), 0);
    assert_true(co_pdo_is_active(&fx->a.pdo, false, 1));   /* now the only SAM producer */
    fx_free(fx);
}

static void test_dam_refused(void **state)
{
    static const struct {
        uint16_t index;
        uint8_t sub;
        uint32_t abort;
    } cases[] = {
        {0x2FFF, 0, CO_ABORT_NO_OBJECT},    /* the device lacks the object */
        {0x2003, 0x40, CO_ABORT_NO_SUB},    /* ... or the sub-index */
        {0x2004, 0, CO_ABORT_READ_ONLY},
        {0x2005, 0, CO_ABORT_NO_MAP},       /* not RPDO-mappable */
        {0x2006, 0, CO_ABORT_MAP_LENGTH},   /* 8 bytes do not fit an MPDO */
    };
    fx_t *fx = pair(CO_MODE_CLASSIC);
    (void)state;
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        assert_int_equal(dam(fx, ID_B, cases[k].index, cases[k].sub, 0x77, 1), CO_MPDO_OK);
        carry(fx);
        assert_int_equal(fx->b.nrefused, (int)k + 1);
        assert_int_equal(fx->b.refused[k].abort, cases[k].abort);
        assert_int_equal(fx->b.refused[k].msg.index, cases[k].index);
        assert_int_equal(fx->b.refused[k].index, cases[k].index);   /* DAM: local = frame's */
        assert_int_equal(fx->b.refused[k].sub, cases[k].sub);
        assert_int_equal(fx->b.refused[k].rpdo, 1);
        assert_int_equal(fx->b.nerrors, (int)k + 1);
        assert_int_equal(fx->b.errors[k].emcy, CO_MPDO_EMCY_DAM);
    }
    assert_int_equal(get(&fx->b, 0x2004, 0, 1), 0x44);
    assert_int_equal(get(&fx->b, 0x2005, 0, 4), 0x55555555);
    assert_int_equal(co_mpdo_stats(&fx->b.mpdo)->rx_refused, 5);
    assert_int_equal(fx->b.nreceived, 0);
    assert_int_equal(dam(fx, ID_B, 0x2000, 0, 0x5A, 1), CO_MPDO_OK);
    carry(fx);
    assert_int_equal(get(&fx->b, 0x2000, 0, 1), 0x5A);
    fx_free(fx);
}

/* Malformed frames on the DAM consumer's COB-ID: ignored and counted,
 * no EMCY (they name no object). */
static void test_dam_bad_frames(void **state)
{
    static const uint8_t good[8] = {0x86, 0x00, 0x20, 0x00, 0x42, 0, 0, 0};
    static const uint8_t sam[8] = {0x05, 0x00, 0x20, 0x00, 0x43, 0, 0, 0};
    fx_t *fx = pair(CO_MODE_CLASSIC);
    (void)state;
    inject(fx, DAM_ID, good, 7);   /* short */
    inject(fx, DAM_ID, good, 0);
    assert_int_equal(co_mpdo_stats(&fx->b.mpdo)->rx_bad_length, 2);
    inject(fx, DAM_ID, sam, 8);    /* a SAM frame on a DAM consumer */
    assert_int_equal(co_mpdo_stats(&fx->b.mpdo)->rx_wrong_mode, 1);
    assert_int_equal(get(&fx->b, 0x2000, 0, 1), 0x11);
    assert_int_equal(fx->b.nerrors, 0);
    assert_int_equal(fx->b.nrefused, 0);
    inject(fx, DAM_ID, good, 8);
    assert_int_equal(get(&fx->b, 0x2000, 0, 1), 0x42);
    fx_free(fx);
}

/* ------------------------------------------------------------- SAM */

static void check_sam(co_mode_t mode)
{
    static const uint8_t obj[8] = {0x05, 0x00, 0x20, 0x00, 0x11, 0, 0, 0};
    static const uint8_t block[8] = {0x05, 0x03, 0x20, 0x02, 0x02, 0, 0, 0};
    fx_t *fx = pair(mode);

    assert_int_equal(co_mpdo_send_sam(&fx->a.mpdo, 2, 0x2000, 0), CO_MPDO_OK);
    carry(fx);
    assert_last(fx, SAM_ID, obj);
    /* dispatched: a's 0x2000:00 -> b's 0x2001:00 (U16, the padding's 0 on top) */
    assert_int_equal(get(&fx->b, 0x2001, 0, 2), 0x0011);
    assert_int_equal(fx->b.received[0].index, 0x2001);
    assert_int_equal(fx->b.received[0].sub, 0);
    assert_false(fx->b.received[0].msg.dam);
    assert_int_equal(fx->b.received[0].msg.node, ID_A);

    /* a block: a's 0x2003:02 -> b's 0x2003:11 */
    assert_int_equal(co_mpdo_send_sam(&fx->a.mpdo, 2, 0x2003, 2), CO_MPDO_OK);
    carry(fx);
    assert_last(fx, SAM_ID, block);
    assert_int_equal(get(&fx->b, 0x2003, 11, 1), 2);
    assert_int_equal(get(&fx->b, 0x2003, 2, 1), 2);   /* b's own sub 2 untouched */
    assert_int_equal(co_mpdo_stats(&fx->b.mpdo)->rx_applied, 2);

    /* the scanner list decides what a may send */
    assert_int_equal(co_mpdo_send_sam(&fx->a.mpdo, 2, 0x2003, 4), CO_MPDO_ERR_NOT_SCANNED);
    assert_int_equal(co_mpdo_send_sam(&fx->a.mpdo, 2, 0x2001, 0), CO_MPDO_ERR_NOT_SCANNED);
    assert_int_equal(co_mpdo_send_sam(&fx->a.mpdo, 2, 0x2006, 0), CO_MPDO_ERR_OBJECT);
    /* a DAM call on the SAM TPDO, a SAM call on the DAM TPDO, no TPDO */
    assert_int_equal(co_mpdo_send_sam(&fx->a.mpdo, 1, 0x2000, 0), CO_MPDO_ERR_CHANNEL);
    assert_int_equal(co_mpdo_send_dam(&fx->a.mpdo, 2, ID_B, 0x2000, 0, obj, 1),
                     CO_MPDO_ERR_CHANNEL);
    assert_int_equal(co_mpdo_send_sam(&fx->a.mpdo, 9, 0x2000, 0), CO_MPDO_ERR_CHANNEL);
    carry(fx);
    assert_int_equal(co_mpdo_stats(&fx->a.mpdo)->tx_frames, 2);
    assert_int_equal(co_mpdo_stats(&fx->a.mpdo)->tx_refused, 6);
    fx_free(fx);
}

static void test_sam_classic(void **state)
{
    (void)state;
    check_sam(CO_MODE_CLASSIC);
}

static void test_sam_fd(void **state)
{
    (void)state;
    check_sam(CO_MODE_FD);
}

/* SAM frames the dispatcher list does not name, or whose local object
 * refuses the value: nothing written, told, counted, no EMCY. */
static void test_sam_refused(void **state)
{
    static const uint8_t stranger[8] = {0x09, 0x00, 0x20, 0x00, 0x77, 0, 0, 0};
    static const uint8_t to_ro[8] = {0x05, 0x02, 0x20, 0x00, 0x78, 0, 0, 0};
    static const uint8_t dam[8] = {0x86, 0x00, 0x20, 0x00, 0x79, 0, 0, 0};
    fx_t *fx = pair(CO_MODE_CLASSIC);
    (void)state;
    inject(fx, SAM_ID, stranger, 8);   /* producer 9 is not listed */
    assert_int_equal(co_mpdo_stats(&fx->b.mpdo)->rx_not_dispatched, 1);
    assert_int_equal(fx->b.nrefused, 1);
    assert_int_equal(fx->b.refused[0].abort, CO_ABORT_NO_OBJECT);
    assert_int_equal(fx->b.refused[0].msg.node, 9);
    inject(fx, SAM_ID, to_ro, 8);      /* a's 0x2002 -> b's read-only 0x2004 */
    assert_int_equal(fx->b.nrefused, 2);
    assert_int_equal(fx->b.refused[1].abort, CO_ABORT_READ_ONLY);
    assert_int_equal(fx->b.refused[1].index, 0x2004);   /* the dispatched local object */
    assert_int_equal(get(&fx->b, 0x2004, 0, 1), 0x44);
    inject(fx, SAM_ID, dam, 8);        /* a DAM frame on a SAM consumer */
    assert_int_equal(co_mpdo_stats(&fx->b.mpdo)->rx_wrong_mode, 1);
    assert_int_equal(get(&fx->b, 0x2000, 0, 1), 0x11);
    assert_int_equal(fx->b.nerrors, 0);
    assert_int_equal(fx->b.nreceived, 0);
    fx_free(fx);
}

/* ------------------------------------------------------------- service rules */

static void test_arguments_and_nmt(void **state)
{
    static const uint8_t v[5] = {1, 2, 3, 4, 5};
    static const uint8_t frame[8] = {0x86, 0x00, 0x20, 0x00, 0x42, 0, 0, 0};
    fx_t *fx = pair(CO_MODE_CLASSIC);
    (void)state;
    assert_int_equal(co_mpdo_send_dam(&fx->a.mpdo, 1, 128, 0x2000, 0, v, 1),
                     CO_MPDO_ERR_ARGUMENT);
    assert_int_equal(co_mpdo_send_dam(&fx->a.mpdo, 1, ID_B, 0x2000, 0, v, 5),
                     CO_MPDO_ERR_ARGUMENT);
    assert_int_equal(co_mpdo_send_dam(&fx->a.mpdo, 1, ID_B, 0x2000, 0, v, 0),
                     CO_MPDO_ERR_ARGUMENT);
    assert_int_equal(co_mpdo_send_dam(&fx->a.mpdo, 1, ID_B, 0x2000, 0, NULL, 1),
                     CO_MPDO_ERR_ARGUMENT);
    /* a plain trigger of an MPDO TPDO has nothing to send */
    assert_false(co_pdo_trigger(&fx->a.pdo, 1));
    /* not operational: nothing sent, nothing applied */
    co_pdo_set_operational(&fx->a.pdo, false);
    assert_int_equal(co_mpdo_send_dam(&fx->a.mpdo, 1, ID_B, 0x2000, 0, v, 1),
                     CO_MPDO_ERR_NOT_SENT);
    co_pdo_set_operational(&fx->b.pdo, false);
    inject(fx, DAM_ID, frame, 8);
    assert_int_equal(get(&fx->b, 0x2000, 0, 1), 0x11);
    assert_int_equal(co_pdo_stats(&fx->b.pdo)->rx_not_operational, 1);
    assert_int_equal(tu_log_count_id(&fx->tb, DAM_ID), 1);   /* the injected one only */
    co_pdo_set_operational(&fx->b.pdo, true);
    inject(fx, DAM_ID, frame, 8);
    assert_int_equal(get(&fx->b, 0x2000, 0, 1), 0x42);
    fx_free(fx);
}

/* The inhibit time (sub 3, 100 µs units) refuses a second MPDO too soon. */
static void test_inhibit(void **state)
{
    static const uint8_t v[1] = {7};
    fx_t *fx = pair(CO_MODE_CLASSIC);
    uint8_t inhibit[2] = {20, 0};   /* 2 ms */
    (void)state;
    co_pdo_set_operational(&fx->a.pdo, false);
    /* sub 3 changes only while the PDO does not exist: invalidate, write, validate */
    {
        uint8_t cob[4];
        tu_le_put(cob, INVALID | DAM_ID, 4);
        assert_int_equal(co_od_put(&fx->a.od, 0x1800, 1, cob, 4), 0);
        assert_int_equal(co_od_put(&fx->a.od, 0x1800, 3, inhibit, 2), 0);
        tu_le_put(cob, DAM_ID, 4);
        assert_int_equal(co_od_put(&fx->a.od, 0x1800, 1, cob, 4), 0);
    }
    co_pdo_set_operational(&fx->a.pdo, true);
    assert_int_equal(co_mpdo_send_dam(&fx->a.mpdo, 1, ID_B, 0x2000, 0, v, 1), CO_MPDO_OK);
    assert_int_equal(co_mpdo_send_dam(&fx->a.mpdo, 1, ID_B, 0x2000, 0, v, 1),
                     CO_MPDO_ERR_NOT_SENT);
    assert_int_equal(co_pdo_stats(&fx->a.pdo)->tx_inhibited, 1);
    fx->t += MS(2);
    tu_step(&fx->tb, fx->t);
    assert_int_equal(co_mpdo_send_dam(&fx->a.mpdo, 1, ID_B, 0x2000, 0, v, 1), CO_MPDO_OK);
    carry(fx);
    assert_int_equal(tu_log_count_id(&fx->tb, DAM_ID), 2);
    fx_free(fx);
}

/* Configuring an MPDO over the network as CiA 301's mapping procedure
 * does: invalidate, sub 0 = 0xFE/0xFF, validate; a type other than
 * 254/255 is refused (our choice: MPDOs are event-driven). */
static void test_configure_over_od(void **state)
{
    fx_t *fx = pair(CO_MODE_CLASSIC);
    (void)state;
    /* while valid, the kind cannot change */
    assert_int_equal(tu_od_net_write(&fx->b.od, 0x1600, 0, CO_PDO_MAP_SAM, 1),
                     CO_ABORT_INVALID_VALUE);
    assert_int_equal(tu_od_net_write(&fx->b.od, 0x1400, 1, INVALID | DAM_ID, 4), 0);
    assert_false(co_pdo_is_active(&fx->b.pdo, true, 1));
    assert_int_equal(tu_od_net_write(&fx->b.od, 0x1600, 0, 0, 1), 0);
    assert_int_equal(tu_od_net_write(&fx->b.od, 0x1600, 0, CO_PDO_MAP_SAM, 1), 0);
    assert_int_equal(tu_od_net_write(&fx->b.od, 0x1400, 2, 1, 1), 0);
    assert_int_equal(tu_od_net_write(&fx->b.od, 0x1400, 1, DAM_ID, 4), CO_ABORT_INVALID_VALUE);
    assert_int_equal(tu_od_net_write(&fx->b.od, 0x1400, 2, 255, 1), 0);
    assert_int_equal(tu_od_net_write(&fx->b.od, 0x1400, 1, DAM_ID, 4), 0);
    assert_true(co_pdo_is_active(&fx->b.pdo, true, 1));
    assert_int_equal(co_pdo_channel(&fx->b.pdo, true, 1)->mpdo, CO_PDO_MAP_SAM);
    /* RPDO1 now takes a's SAM MPDOs if they come on 0x185: a DAM frame is the wrong mode */
    assert_int_equal(dam(fx, ID_B, 0x2000, 0, 0x42, 1), CO_MPDO_OK);
    carry(fx);
    assert_int_equal(co_mpdo_stats(&fx->b.mpdo)->rx_wrong_mode, 1);
    assert_int_equal(get(&fx->b, 0x2000, 0, 1), 0x11);
    fx_free(fx);
}

/* Without the MPDO service an MPDO's frames are counted, never unpacked. */
static void test_without_service(void **state)
{
    static const uint8_t frame[8] = {0x86, 0x00, 0x20, 0x00, 0x42, 0, 0, 0};
    fx_t *fx = pair(CO_MODE_CLASSIC);
    uint32_t before;
    (void)state;
    co_mpdo_deinit(&fx->b.mpdo);
    before = co_pdo_stats(&fx->b.pdo)->rx_not_ours;
    inject(fx, DAM_ID, frame, 8);
    assert_int_equal(co_pdo_stats(&fx->b.pdo)->rx_not_ours, before + 1);
    assert_int_equal(get(&fx->b, 0x2000, 0, 1), 0x11);
    co_mpdo_init(&fx->b.mpdo, &fx->b.pdo, &indications, &fx->b);
    inject(fx, DAM_ID, frame, 8);
    assert_int_equal(get(&fx->b, 0x2000, 0, 1), 0x42);
    fx_free(fx);
}

/* The lists alone: blocks, the end of the sub-index range, entry 0. */
static void test_lists(void **state)
{
    fx_t *fx = pair(CO_MODE_CLASSIC);
    uint16_t li = 0;
    uint8_t ls = 0;
    (void)state;
    assert_true(co_mpdo_scanner_lists(&fx->a.od, 0x2003, 1));
    assert_true(co_mpdo_scanner_lists(&fx->a.od, 0x2003, 3));
    assert_false(co_mpdo_scanner_lists(&fx->a.od, 0x2003, 0));
    assert_false(co_mpdo_scanner_lists(&fx->a.od, 0x2003, 4));
    assert_false(co_mpdo_scanner_lists(&fx->b.od, 0x2000, 0));   /* b has no list */
    assert_true(co_mpdo_dispatch(&fx->b.od, ID_A, 0x2003, 3, &li, &ls));
    assert_int_equal(li, 0x2003);
    assert_int_equal(ls, 12);
    assert_false(co_mpdo_dispatch(&fx->b.od, ID_A, 0x2003, 4, &li, &ls));
    assert_false(co_mpdo_dispatch(&fx->b.od, ID_B, 0x2000, 0, &li, &ls));
    assert_false(co_mpdo_dispatch(&fx->a.od, ID_A, 0x2000, 0, &li, &ls));
    fx_free(fx);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_codec),
        cmocka_unit_test(test_dam_classic),
        cmocka_unit_test(test_dam_fd),
        cmocka_unit_test(test_dam_refused),
        cmocka_unit_test(test_dam_mapped),
        cmocka_unit_test(test_one_sam_producer),
        cmocka_unit_test(test_dam_bad_frames),
        cmocka_unit_test(test_sam_classic),
        cmocka_unit_test(test_sam_fd),
        cmocka_unit_test(test_sam_refused),
        cmocka_unit_test(test_arguments_and_nmt),
        cmocka_unit_test(test_inhibit),
        cmocka_unit_test(test_configure_over_od),
        cmocka_unit_test(test_without_service),
        cmocka_unit_test(test_lists),
    };
    return cmocka_run_group_tests_name("mpdo", tests, NULL, NULL);
}
