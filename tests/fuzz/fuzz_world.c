/* The shared world of the harnesses (see fuzz_world.h). One world at a time
 * (libFuzzer runs inputs one after another). Building it (two OD-backed
 * stacks) costs far more than most inputs, so it is built once per line mode
 * and copied back before every input: see fw_run. */
#include "fuzz_world.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum {
    QUEUE = 32,                    /* rx/tx slots per line: small, so overflows happen */
    OD_ENTRIES = 192,
    OD_POOL = 12 * 1024,
    OD_SUBS = CO_STACK_OD_SUBSCRIPTIONS + 4,
    ARENA = 48 * 1024,             /* the stacks take ~16 KB; the world is copied per input */
    SLOTS = 4,                     /* client requests at once */
    SLOT_BUF = 6000,               /* bytes a request sends or receives */
    DOMAIN_MAX = 8192,
    PENDING = 8,                   /* split accesses waiting */
    STEP_BUDGET = 60000,           /* process steps per input (timers firing), settles included */
    SETTLE_BUDGET = 40000,         /* steps of one settle (the final one's come on top) */
    ROUND_LIMIT = 100000,          /* bus rounds at one instant before "livelock" */
    SETTLE_MS = 15000
};
#define MS 1000u

typedef struct slot {
    bool running;
    unsigned done;
    co_usdo_request_t usdo;
    co_sdo_request_t sdo;
    co_buffer_t buf;
    uint8_t data[SLOT_BUF];
} slot_t;

typedef struct line_storage {
    co_line_t line;
    co_frame_t rx[QUEUE];
    co_frame_t tx[QUEUE];
} line_storage_t;

typedef struct world {
    const fw_config_t *cfg;
    co_membus_t bus;
    line_storage_t dev_line, tool_line;
    co_line_t *target;
    uint64_t now;
    uint32_t steps;
    uint32_t budget;
    bool held;
    uint8_t fate_mask;
    uint8_t fate_left;
    bool fate_dup;
    /* device */
    co_od_t od;
    co_od_entry_t entries[OD_ENTRIES];
    uint8_t pool[OD_POOL];
    co_od_subscription_t subs[OD_SUBS];
    co_stack_t dev;
    co_stack_arena_t dev_arena;
    unsigned char dev_mem[ARENA];
    uint8_t store_image[8192];
    uint32_t store_len;
    bool store_has;
    /* split answers and the domain */
    bool split_mode;
    co_od_xfer_t *pending[PENDING];
    uint8_t pending_count;
    uint8_t domain[DOMAIN_MAX];
    uint32_t domain_len;
    uint32_t domain_next;          /* where the next chunk of a download must start */
    /* an application write through the OD */
    co_od_xfer_t xfer;
    uint8_t xfer_scratch[2048];
    /* tool */
    co_stack_t tool;
    co_stack_arena_t tool_arena;
    unsigned char tool_mem[ARENA];
    slot_t slots[SLOTS];
} world_t;

static world_t W;

void fw_fail(const char *what)
{
    fprintf(stderr, "fuzz invariant broken: %s (t=%llu ms)\n", what,
            (unsigned long long)(W.now / MS));
    abort();
}

#define CHECK(cond, what) do { if (!(cond)) fw_fail(what); } while (0)

/* ------------------------------------------------------------ the device OD */

typedef struct row {
    uint16_t index;
    uint8_t sub;
    uint8_t object_code;
    uint8_t type;
    uint8_t access;
    uint16_t flags;
    uint32_t size;
    uint32_t value;
} row_t;

#define VAR CO_OBJECT_VAR
#define ARR CO_OBJECT_ARRAY
#define REC CO_OBJECT_RECORD
#define U8 CO_TYPE_UNSIGNED8
#define U16 CO_TYPE_UNSIGNED16
#define U32 CO_TYPE_UNSIGNED32
#define RO CO_ACCESS_RO
#define RW CO_ACCESS_RW
#define ST CO_OD_STORE
#define REL CO_OD_NODEID_RELATIVE
#define CL CO_OD_CLASSIC_ONLY
#define MAPB (CO_OD_MAP_TPDO | CO_OD_MAP_RPDO)
#define MAP(i, s, bits) (((uint32_t)(i) << 16) | ((uint32_t)(s) << 8) | (bits))

static const row_t rows[] = {
    {0x1000, 0, VAR, U32, RO, 0, 4, 0x00000191},
    {0x1001, 0, VAR, U8, RO, 0, 1, 0},
    {0x1003, 0, ARR, U8, RW, 0, 1, 0},
    {0x1003, 1, ARR, U32, RO, 0, 4, 0},
    {0x1003, 2, ARR, U32, RO, 0, 4, 0},
    {0x1003, 3, ARR, U32, RO, 0, 4, 0},
    {0x1005, 0, VAR, U32, RW, ST, 4, 0x80},
    {0x1006, 0, VAR, U32, RW, ST, 4, 0},
    {0x1007, 0, VAR, U32, RW, 0, 4, 0},
    {0x100C, 0, VAR, U16, RW, CL, 2, 0},
    {0x100D, 0, VAR, U8, RW, CL, 1, 0},
    {0x1010, 0, ARR, U8, RO, 0, 1, 4},
    {0x1010, 1, ARR, U32, RW, 0, 4, 1},
    {0x1010, 2, ARR, U32, RW, 0, 4, 1},
    {0x1010, 3, ARR, U32, RW, 0, 4, 1},
    {0x1010, 4, ARR, U32, RW, 0, 4, 1},
    {0x1011, 0, ARR, U8, RO, 0, 1, 4},
    {0x1011, 1, ARR, U32, RW, 0, 4, 1},
    {0x1011, 2, ARR, U32, RW, 0, 4, 1},
    {0x1011, 3, ARR, U32, RW, 0, 4, 1},
    {0x1011, 4, ARR, U32, RW, 0, 4, 1},
    {0x1012, 0, VAR, U32, RW, ST, 4, 0x80000100u},
    {0x1014, 0, VAR, U32, RW, REL | ST, 4, 0x80},
    {0x1015, 0, VAR, U16, RW, ST, 2, 0},
    {0x1016, 0, ARR, U8, RO, 0, 1, 2},
    {0x1016, 1, ARR, U32, RW, ST, 4, 0},
    {0x1016, 2, ARR, U32, RW, ST, 4, 0},
    {0x1017, 0, VAR, U16, RW, ST, 2, 0},
    {0x1018, 0, REC, U8, RO, 0, 1, 2},
    {0x1018, 1, REC, U32, RO, 0, 4, 0x12345678},
    {0x1018, 2, REC, U32, RO, 0, 4, 0x0000ABCD},
    {0x1019, 0, VAR, U8, RW, ST, 1, 0},
    {0x1028, 0, ARR, U8, RO, 0, 1, 2},
    {0x1028, 1, ARR, U32, RW, ST, 4, 0x81},
    {0x1028, 2, ARR, U32, RW, ST, 4, 0x80000082u},
    {0x1029, 0, ARR, U8, RO, 0, 1, 2},
    {0x1029, 1, ARR, U8, RW, ST, 1, 0},
    {0x1029, 2, ARR, U8, RW, ST, 1, 1},
    {0x1201, 0, REC, U8, CO_ACCESS_CONST, CL, 1, 3},
    {0x1201, 1, REC, U32, RW, CL, 4, 0x80000000u},
    {0x1201, 2, REC, U32, RW, CL, 4, 0x80000000u},
    {0x1201, 3, REC, U8, RW, CL, 1, 0},
    {0x1280, 0, REC, U8, CO_ACCESS_CONST, CL, 1, 3},
    {0x1280, 1, REC, U32, RW, CL, 4, 0x80000000u},
    {0x1280, 2, REC, U32, RW, CL, 4, 0x80000000u},
    {0x1280, 3, REC, U8, RW, CL, 1, 0},
    {0x2000, 0, VAR, U8, RW, MAPB | ST, 1, 0x11},
    {0x2001, 0, VAR, U16, RW, MAPB | ST, 2, 0x2222},
    {0x2002, 0, VAR, U32, RW, MAPB, 4, 0x33333333u},
    {0x2003, 0, VAR, CO_TYPE_INTEGER64, RW, MAPB, 8, 0x44},
    {0x2004, 0, VAR, U16, RW, MAPB | CO_OD_HAS_MIN | CO_OD_HAS_MAX, 2, 100},
    {0x2005, 0, VAR, CO_TYPE_VISIBLE_STRING, RW, ST, 32, 0},
    {0x2006, 0, VAR, CO_TYPE_OCTET_STRING, RW, MAPB, 200, 0},
    {0x2007, 0, VAR, CO_TYPE_DOMAIN, RW, 0, 0, 0},
    {0x2008, 0, VAR, CO_TYPE_BOOLEAN, RW, MAPB, 1, 0},
    {0x2009, 0, VAR, CO_TYPE_REAL32, RW, MAPB | CO_OD_HAS_MIN | CO_OD_HAS_MAX, 4, 0},
    {0x200A, 0, VAR, CO_TYPE_UNICODE_STRING, RW, ST, 16, 0},
    {0x2100, 0, VAR, U32, RW, MAPB, 4, 0x5A5A},
    {0x2101, 0, VAR, CO_TYPE_OCTET_STRING, RW, ST, 1024, 0},
    {0x2102, 0, VAR, U32, CO_ACCESS_WO, 0, 4, 0},
    {0x2103, 0, VAR, U32, RO, MAPB, 4, 7},
};

/* PDO k (1..4): RPDO on 0x200 + 0x100 * (k-1) + node, TPDO on 0x180 + ... */
static void add_row(const row_t *r)
{
    co_od_def_t d;
    uint8_t v[8];
    memset(&d, 0, sizeof d);
    d.index = r->index;
    d.sub = r->sub;
    d.object_code = r->object_code;
    d.type = r->type;
    d.access = r->access;
    d.flags = r->flags;
    d.size = r->size;
    for (uint32_t i = 0; i < 8; i++) {
        v[i] = i < 4 ? (uint8_t)(r->value >> (8 * i)) : 0;
    }
    if (r->type != CO_TYPE_DOMAIN && r->type != CO_TYPE_VISIBLE_STRING &&
        r->type != CO_TYPE_OCTET_STRING && r->type != CO_TYPE_UNICODE_STRING) {
        d.default_value = v;
        d.default_length = r->size;
    }
    if (r->index == 0x2004) {          /* 10 .. 1000 */
        d.min[0] = 10;
        d.max[0] = 0xE8;
        d.max[1] = 0x03;
    } else if (r->index == 0x2009) {   /* -100.0 .. 100.0 */
        static const uint8_t lo[4] = {0x00, 0x00, 0xC8, 0xC2}, hi[4] = {0x00, 0x00, 0xC8, 0x42};
        memcpy(d.min, lo, 4);
        memcpy(d.max, hi, 4);
    }
    co_od_add_result_t rc = co_od_add(&W.od, &d);
    CHECK(rc == CO_OD_ADDED || rc == CO_OD_SKIPPED_MODE, "device OD refuses an entry");
}

static void add(uint16_t index, uint8_t sub, uint8_t type, uint16_t flags, uint32_t value)
{
    /* sub 0 of a communication parameter is read-only, of a mapping writable */
    bool comm = (index & 0xFF00u) == 0x1400u || (index & 0xFF00u) == 0x1800u;
    row_t r = {index, sub, REC, type, sub == 0 && comm ? RO : RW, flags,
               co_od_type_size(type), value};
    add_row(&r);
}

/* MPDO (co_mpdo): the object scanner list names what a SAM TPDO of this node
 * sends, the object dispatcher list where SAMs of other nodes go, so the SAM
 * producer and consumer paths run past their list look-ups. */
#define SCAN(i, s) ((1u << 24) | ((uint32_t)(i) << 8) | (s))
static void add_dispatch(uint8_t sub, uint16_t local, uint16_t remote, uint8_t remote_sub,
                         uint8_t node)
{
    uint64_t entry = (uint64_t)1 << 56 | (uint64_t)local << 40 | (uint64_t)remote << 16 |
                     (uint64_t)remote_sub << 8 | node;   /* block 1, local sub 0 */
    uint8_t value[8];
    for (uint32_t i = 0; i < 8; i++) {
        value[i] = (uint8_t)(entry >> (8 * i));
    }
    co_od_def_t d;
    memset(&d, 0, sizeof d);
    d.index = 0x1FD0;
    d.sub = sub;
    d.object_code = ARR;
    d.type = CO_TYPE_UNSIGNED64;
    d.access = RW;
    d.size = 8;
    d.default_value = value;
    d.default_length = 8;
    CHECK(co_od_add(&W.od, &d) == CO_OD_ADDED, "device OD refuses a dispatcher entry");
}

static void add_mpdo_lists(void)
{
    static const row_t lists[] = {
        {0x1FA0, 0, ARR, U8, RO, 0, 1, 2},
        {0x1FA0, 1, ARR, U32, RW, 0, 4, SCAN(0x2002, 0)},
        {0x1FA0, 2, ARR, U32, RW, 0, 4, SCAN(0x2001, 0)},
        {0x1FD0, 0, ARR, U8, RO, 0, 1, 2},
    };
    for (size_t i = 0; i < sizeof lists / sizeof lists[0]; i++) {
        add_row(&lists[i]);
    }
    add_dispatch(1, 0x2100, 0x2002, 0, 7);   /* node 7's 0x2002:00 -> our 0x2100:00 */
    add_dispatch(2, 0x2001, 0x2001, 0, 7);   /* 16 bits: a 4-byte SAM is too long */
}

static void build_od(co_mode_t mode)
{
    co_od_init(&W.od, mode, W.entries, OD_ENTRIES, W.pool, OD_POOL, W.subs, OD_SUBS);
    for (size_t i = 0; i < sizeof rows / sizeof rows[0]; i++) {
        add_row(&rows[i]);
    }
    static const uint32_t rmap[4] = {MAP(0x2001, 0, 16), MAP(0x2002, 0, 32), MAP(0x2000, 0, 8),
                                     MAP(0x2006, 0, 64)};
    static const uint32_t tmap[4] = {MAP(0x2000, 0, 8), MAP(0x2001, 0, 16), MAP(0x2103, 0, 32),
                                     MAP(0x2003, 0, 64)};
    static const uint8_t ttype[4] = {254, 1, 0xFD, 255};
    static const uint8_t rtype[4] = {254, 1, 255, 0};
    for (uint16_t k = 0; k < 4; k++) {
        uint32_t r_cob = (0x200u + 0x100u * k) | (k == 3 ? 0x80000000u : 0);
        uint32_t t_cob = (0x180u + 0x100u * k) | (k == 2 ? 0x40000000u : 0);
        add((uint16_t)(0x1400 + k), 0, U8, 0, 5);
        add((uint16_t)(0x1400 + k), 1, U32, REL | ST, r_cob);
        add((uint16_t)(0x1400 + k), 2, U8, ST, rtype[k]);
        add((uint16_t)(0x1400 + k), 3, U16, 0, 0);
        add((uint16_t)(0x1400 + k), 5, U16, 0, k == 1 ? 500 : 0);
        add((uint16_t)(0x1600 + k), 0, U8, ST, 1);
        for (uint8_t s = 1; s <= 4; s++) {
            add((uint16_t)(0x1600 + k), s, U32, ST, s == 1 ? rmap[k] : 0);
        }
        add((uint16_t)(0x1800 + k), 0, U8, 0, 6);
        add((uint16_t)(0x1800 + k), 1, U32, REL | ST, t_cob);
        add((uint16_t)(0x1800 + k), 2, U8, ST, ttype[k]);
        add((uint16_t)(0x1800 + k), 3, U16, 0, k == 0 ? 10 : 0);
        add((uint16_t)(0x1800 + k), 5, U16, 0, k == 3 ? 200 : 0);
        add((uint16_t)(0x1800 + k), 6, U8, 0, 0);
        add((uint16_t)(0x1A00 + k), 0, U8, ST, 1);
        for (uint8_t s = 1; s <= 4; s++) {
            add((uint16_t)(0x1A00 + k), s, U32, ST, s == 1 ? tmap[k] : 0);
        }
    }
    add_mpdo_lists();
    CHECK(co_od_seal(&W.od, FW_NODE), "device OD does not seal");
}

/* 0x2100 answers later while split mode is on. */
static void note_pending(co_od_xfer_t *xfer)
{
    for (uint8_t i = 0; i < W.pending_count; i++) {
        if (W.pending[i] == xfer) {
            return;
        }
    }
    W.pending[W.pending_count++] = xfer;
}

static uint32_t split_read(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e, void *user)
{
    (void)od; (void)e; (void)user;
    if (!W.split_mode || W.pending_count >= PENDING) {
        return 0;
    }
    note_pending(xfer);
    return CO_OD_SPLIT;
}

static uint32_t split_check(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e,
                            const uint8_t *value, uint32_t length, void *user)
{
    (void)value; (void)length;
    if (xfer == &W.xfer) {
        return 0;   /* the application's own write does not wait on itself */
    }
    return split_read(od, xfer, e, user);
}

static const co_od_handler_t split_handler = {.before_read = split_read,
                                              .check_write = split_check};

static uint32_t domain_size(co_od_t *od, const co_od_entry_t *e, uint32_t *size, void *user)
{
    (void)od; (void)e; (void)user;
    *size = W.domain_len;
    return 0;
}

static uint32_t domain_read(co_od_t *od, const co_od_entry_t *e, uint32_t offset, uint8_t *buf,
                            uint32_t cap, uint32_t *n, bool *last, void *user)
{
    (void)od; (void)e; (void)user;
    CHECK(offset <= W.domain_len, "domain read past its end");
    uint32_t left = W.domain_len - offset;
    uint32_t take = left < cap ? left : cap;
    memcpy(buf, W.domain + offset, take);
    *n = take;
    *last = offset + take == W.domain_len;
    return 0;
}

static uint32_t domain_write(co_od_t *od, const co_od_entry_t *e, uint32_t offset,
                             const uint8_t *data, uint32_t n, uint32_t total, bool last,
                             uint32_t abort_code, void *user)
{
    (void)od; (void)e; (void)user; (void)total;
    if (abort_code != 0) {
        W.domain_next = 0;
        return 0;
    }
    CHECK(offset == 0 || offset == W.domain_next, "domain chunk out of order");
    if (offset == 0) {
        W.domain_len = 0;
    }
    if ((uint64_t)offset + n > DOMAIN_MAX) {
        W.domain_next = 0;
        return CO_ABORT_OUT_OF_MEMORY;
    }
    if (n > 0) {
        memcpy(W.domain + offset, data, n);
    }
    W.domain_next = offset + n;
    W.domain_len = offset + n;
    if (last) {
        W.domain_next = 0;
    }
    return 0;
}

static const co_od_handler_t domain_handler = {.domain_size = domain_size,
                                               .domain_read = domain_read,
                                               .domain_write = domain_write};

/* ------------------------------------------------------------ store backend */

static co_store_status_t mem_save(void *user, const uint8_t *image, uint32_t length)
{
    (void)user;
    if (length > sizeof W.store_image) {
        return CO_STORE_IO;
    }
    memcpy(W.store_image, image, length);
    W.store_len = length;
    W.store_has = true;
    return CO_STORE_OK;
}

static co_store_status_t mem_load(void *user, uint8_t *image, uint32_t capacity, uint32_t *length)
{
    (void)user;
    if (!W.store_has) {
        return CO_STORE_EMPTY;
    }
    if (W.store_len > capacity) {
        return CO_STORE_TOO_BIG;
    }
    memcpy(image, W.store_image, W.store_len);
    *length = W.store_len;
    return CO_STORE_OK;
}

static const co_store_backend_t mem_ops = {mem_save, mem_load};

/* ------------------------------------------------------------ indications */

static void on_heartbeat(co_stack_t *s, uint8_t node_id, co_hb_event_t event,
                         co_nmt_state_t state, void *user)
{
    (void)s; (void)event; (void)state; (void)user;
    CHECK(node_id >= 1 && node_id <= 127, "heartbeat indication for node-id 0 or > 127");
}

static void on_emcy(co_stack_t *s, uint8_t node_id, const co_emcy_msg_t *msg, void *user)
{
    (void)s; (void)user;
    CHECK(node_id >= 1 && node_id <= 127 && msg != NULL, "EMCY indication for a bad node-id");
}

static void on_guard(co_stack_t *s, uint8_t node_id, co_guard_event_t event,
                     co_nmt_state_t state, void *user)
{
    (void)s; (void)event; (void)state; (void)user;
    CHECK(node_id >= 1 && node_id <= 127, "guarding indication for a bad node-id");
}

static const co_stack_indications_t tool_ind = {.heartbeat = on_heartbeat, .emcy = on_emcy,
                                                .guard = on_guard};

/* The device's CiA 303-3 LEDs: every change names a LED and a pattern the
 * LED really shows, its lit state is the timeline's, and the LED tick runs
 * only while a pattern is not steady. */
static void on_led(co_led_t *led, co_led_which_t which, bool on, co_led_pattern_t pattern,
                   void *user)
{
    (void)user;
    CHECK(which == CO_LED_RUN || which == CO_LED_ERROR, "LED indication for no LED");
    CHECK(pattern >= CO_LED_OFF && pattern <= CO_LED_QUADRUPLE_FLASH &&
          co_led_pattern(led, which) == pattern, "LED indication with a foreign pattern");
    CHECK(co_led_is_on(led, which) == on, "LED indication off the pattern's timeline");
    bool steady = (co_led_pattern(led, CO_LED_RUN) <= CO_LED_ON) &&
                  (co_led_pattern(led, CO_LED_ERROR) <= CO_LED_ON);
    CHECK(!steady || !co_timer_is_armed(&led->timer), "LED tick runs with both LEDs steady");
}

/* ------------------------------------------------------------ client slots */

static slot_t *slot_of(void *user)
{
    slot_t *s = user;
    CHECK(s >= W.slots && s < W.slots + SLOTS, "done() with a foreign request");
    return s;
}

static void slot_done(slot_t *s)
{
    CHECK(s->running, "done() for a request that is not running");
    CHECK(s->done == 0, "done() twice");
    s->done++;
    s->running = false;
}

static void usdo_done(co_usdo_request_t *req) { slot_done(slot_of(req->user)); }
static void sdo_done(co_sdo_request_t *req) { slot_done(slot_of(req->user)); }

/* Index/sub pairs the client asks for (existing, missing, special). */
static const uint32_t targets[] = {
    0x101801, 0x100000, 0x101700, 0x200000, 0x200100, 0x200200, 0x200300, 0x200400,
    0x200500, 0x200600, 0x200700, 0x200800, 0x200900, 0x200A00, 0x210000, 0x210100,
    0x210200, 0x210300, 0x101001, 0x101101, 0x160001, 0x180001, 0x140001, 0x300000,
    0x101805, 0x100300, 0x101601, 0x102901,
};

static void client_start(fz_reader_t *r)
{
    uint8_t f = fz_u8(r);
    uint8_t tsel = fz_u8(r);
    uint8_t sub = fz_u8(r);
    uint16_t size = (uint16_t)(fz_u16(r) % (SLOT_BUF + 1u));
    uint8_t to = fz_u8(r);
    uint8_t which = (uint8_t)(f >> 5) % SLOTS;
    slot_t *s = &W.slots[which];
    uint32_t key = targets[tsel % (sizeof targets / sizeof targets[0])];
    if (s->running) {
        return;
    }
    s->done = 0;
    s->buf.data = s->data;
    s->buf.size = f & 1u ? 0 : size;
    s->buf.capacity = SLOT_BUF;
    for (uint32_t i = 0; i < size; i++) {
        s->data[i] = (uint8_t)(i * 7u + tsel);
    }
    uint8_t server = (f & 0x10u) ? 0x7E : FW_NODE;
    co_line_set_time(&W.tool_line.line, W.now);
    if (W.cfg->mode == CO_MODE_FD) {
        co_usdo_client_t *c = co_stack_usdo_client(&W.tool);
        co_usdo_request_t *q = &s->usdo;
        memset(q, 0, sizeof *q);
        q->server = (f & 0x08u) ? 0 : server;
        q->index = (uint16_t)(key >> 8);
        q->sub = (tsel & 0x80u) ? sub : (uint8_t)key;
        q->upload = f & 1u;
        q->mode = (uint8_t)((f >> 1) & 3u);
        q->type = (uint8_t)(sub & 0x1Fu);
        q->size = size;
        q->source = co_usdo_buffer_source;
        q->sink = co_usdo_buffer_sink;
        q->ctx = &s->buf;
        q->done = usdo_done;
        q->user = s;
        q->timeout_ms = (uint32_t)to * 10u;
        s->running = true;
        if (c == NULL || co_usdo_client_start(c, q) != 0) {
            s->running = false;
        }
    } else {
        co_sdo_client_t *c = co_stack_sdo_client(&W.tool);
        co_sdo_request_t *q = &s->sdo;
        uint8_t blk = fz_u8(r);
        memset(q, 0, sizeof *q);
        q->server = server;
        q->index = (uint16_t)(key >> 8);
        q->sub = (tsel & 0x80u) ? sub : (uint8_t)key;
        q->upload = f & 1u;
        q->mode = (uint8_t)((f >> 1) & 3u);
        q->size = size;
        q->source = co_sdo_buffer_source;
        q->sink = co_sdo_buffer_sink;
        q->ctx = &s->buf;
        q->done = sdo_done;
        q->user = s;
        q->timeout_ms = (uint32_t)to * 10u;
        q->block_threshold = (f & 0x08u) ? 16 : 0;
        q->blksize = (uint8_t)(blk & 0x7Fu);
        q->pst = (blk & 0x80u) ? (uint8_t)(sub & 0x0Fu) : 0;
        q->no_crc = (to & 1u) != 0;
        s->running = true;
        if (c == NULL || co_sdo_client_start(c, q) != 0) {
            s->running = false;
        }
    }
}

static void client_cancel(fz_reader_t *r)
{
    uint8_t b = fz_u8(r);
    slot_t *s = &W.slots[b % SLOTS];
    co_line_set_time(&W.tool_line.line, W.now);
    if (W.cfg->mode == CO_MODE_FD) {
        co_usdo_client_t *c = co_stack_usdo_client(&W.tool);
        bool was = s->running;
        bool ok = c != NULL && co_usdo_client_cancel(c, &s->usdo, (uint8_t)(b >> 2));
        CHECK(ok == was, "USDO cancel disagrees with the request's state");
    } else {
        co_sdo_client_t *c = co_stack_sdo_client(&W.tool);
        bool was = s->running;
        bool ok = c != NULL && co_sdo_client_cancel(c, &s->sdo, (b & 4u) ? 0x08000020u : 0);
        CHECK(ok == was, "SDO cancel disagrees with the request's state");
    }
}

/* ------------------------------------------------------------ device actions */

static bool resume_one(uint8_t i, uint32_t abort_code)
{
    co_od_xfer_t *x = W.pending[i];
    bool ok;
    co_line_set_time(&W.dev_line.line, W.now);
    if (W.cfg->mode == CO_MODE_FD) {
        ok = co_usdo_server_resume(co_stack_usdo_server(&W.dev), x, abort_code);
    } else {
        ok = co_sdo_server_resume(co_stack_sdo_server(&W.dev), x, abort_code);
    }
    if (!ok || (x->state != CO_XFER_PENDING_READ && x->state != CO_XFER_PENDING_WRITE)) {
        W.pending[i] = W.pending[--W.pending_count];
        return true;
    }
    return false;
}

static void resume(fz_reader_t *r)
{
    uint8_t b = fz_u8(r);
    static const uint32_t codes[4] = {0, CO_ABORT_GENERAL, CO_OD_SPLIT, CO_ABORT_VALUE_HIGH};
    if (W.pending_count == 0) {
        return;
    }
    (void)resume_one((uint8_t)(b % W.pending_count), codes[(b >> 4) & 3u]);
}

/* Entries an application writes: the services' configuration. */
static const uint32_t config_keys[] = {
    0x100500, 0x100600, 0x100700, 0x100C00, 0x100D00, 0x101200, 0x101400, 0x101500,
    0x101601, 0x101602, 0x101700, 0x101900, 0x102801, 0x102901, 0x140001, 0x140002,
    0x140003, 0x140005, 0x160000, 0x160001, 0x160002, 0x180001, 0x180002, 0x180003,
    0x180005, 0x180006, 0x1A0000, 0x1A0001, 0x1A0002, 0x120101, 0x128001, 0x100300,
    0x1FA001,
};

static void od_write(fz_reader_t *r, bool put)
{
    uint8_t k = fz_u8(r);
    uint8_t pdo = fz_u8(r);
    uint32_t value = fz_u32(r);
    uint32_t key = config_keys[k % (sizeof config_keys / sizeof config_keys[0])];
    uint16_t index = (uint16_t)(key >> 8);
    uint8_t sub = (uint8_t)key;
    uint8_t bytes[4];
    if (index >= 0x1400u && index <= 0x1A00u && (index & 0xFFu) == 0) {
        index = (uint16_t)(index + (pdo & 3u));   /* PDO 1..4 */
    }
    if (pdo & 0x80u) {
        sub = (uint8_t)((pdo >> 2) & 7u);
    }
    const co_od_entry_t *e = co_od_find(&W.od, index, sub);
    uint32_t len = e != NULL && e->size <= 4 ? e->size : 4;
    if (pdo & 0x40u) {
        len = (uint32_t)(pdo >> 4) & 3u;
    }
    for (uint32_t i = 0; i < 4; i++) {
        bytes[i] = (uint8_t)(value >> (8 * i));
    }
    co_line_set_time(&W.dev_line.line, W.now);
    if (put) {
        (void)co_od_put(&W.od, index, sub, bytes, len);
        return;
    }
    uint32_t rc = co_od_write_begin(&W.od, &W.xfer, index, sub, len);
    if (rc == 0) {
        rc = co_od_write_chunk(&W.xfer, bytes, len);
    }
    if (rc == 0) {
        rc = co_od_write_end(&W.xfer);
    }
    CHECK(rc != CO_OD_SPLIT, "an application write split on its own xfer");
    co_od_xfer_abort(&W.xfer, 0);
}

static void nmt_local(fz_reader_t *r)
{
    static const co_nmt_command_t cmds[5] = {CO_NMT_CMD_START, CO_NMT_CMD_STOP,
                                             CO_NMT_CMD_PRE_OPERATIONAL,
                                             CO_NMT_CMD_RESET_NODE, CO_NMT_CMD_RESET_COMMUNICATION};
    uint8_t b = fz_u8(r);
    co_line_set_time(&W.dev_line.line, W.now);
    co_nmt_apply(&co_stack_node(&W.dev)->nmt, cmds[b % 5u]);
}

static void nmt_master(fz_reader_t *r)
{
    static const co_nmt_command_t cmds[5] = {CO_NMT_CMD_START, CO_NMT_CMD_STOP,
                                             CO_NMT_CMD_PRE_OPERATIONAL,
                                             CO_NMT_CMD_RESET_NODE, CO_NMT_CMD_RESET_COMMUNICATION};
    uint8_t b = fz_u8(r);
    co_line_set_time(&W.tool_line.line, W.now);
    (void)co_nmt_master_send(&W.tool_line.line, NULL, cmds[b % 5u],
                             (b & 0x80u) ? 0 : FW_NODE, false);
}

static void pdo_trigger(fz_reader_t *r)
{
    uint8_t b = fz_u8(r);
    co_pdo_t *pdo = co_stack_pdo(&W.dev);
    co_line_set_time(&W.dev_line.line, W.now);
    if (pdo == NULL) {
        return;
    }
    if (b & 0x80u) {
        (void)co_pdo_trigger_object(pdo, (uint16_t)(0x2000u + (b & 0x07u)), 0);
    } else {
        (void)co_pdo_trigger(pdo, (uint16_t)(b % 6u));
    }
}

static void emcy(fz_reader_t *r)
{
    uint8_t b = fz_u8(r);
    uint16_t code = fz_u16(r);
    co_emcy_t *e = co_stack_emcy(&W.dev);
    co_emcy_error_t err;
    co_line_set_time(&W.dev_line.line, W.now);
    if (e == NULL) {
        return;
    }
    memset(&err, 0, sizeof err);
    err.code = code;
    err.register_bits = (uint8_t)(b & 0xF0u);
    err.priority = (uint8_t)(b & 7u);
    err.logical_device = (uint8_t)(b >> 6);
    if ((b & 0x18u) == 0x18u) {
        (void)co_emcy_clear_all(e);
    } else if (b & 0x08u) {
        (void)co_emcy_clear(e, &err);
    } else {
        (void)co_emcy_raise(e, &err);
    }
}

static void time_send(fz_reader_t *r)
{
    uint8_t b = fz_u8(r);
    uint32_t t = fz_u32(r);
    co_stack_t *s = (b & 1u) ? &W.tool : &W.dev;
    co_line_set_time(co_stack_line(s), W.now);
    (void)co_time_send_unix_us(co_stack_time(s), (uint64_t)t * 1000000u + (uint64_t)b * 1000u);
}

static void watch(fz_reader_t *r)
{
    uint8_t b = fz_u8(r);
    uint8_t node = (uint8_t)(fz_u8(r) & 0x7Fu);
    uint8_t ms = fz_u8(r);
    co_line_set_time(&W.tool_line.line, W.now);
    switch (b & 7u) {
    case 0:
        (void)co_hb_consumer_watch(co_stack_hb_consumer(&W.tool), node, (uint16_t)(ms * 4u));
        break;
    case 1:
        co_hb_consumer_unwatch(co_stack_hb_consumer(&W.tool), node);
        break;
    case 2:
        (void)co_emcy_consumer_watch(co_stack_emcy_consumer(&W.tool), node);
        break;
    case 3:
        co_emcy_consumer_unwatch(co_stack_emcy_consumer(&W.tool), node);
        break;
    case 4:
        if (co_stack_guard_master(&W.tool) != NULL) {
            (void)co_guard_master_guard(co_stack_guard_master(&W.tool), node, ms,
                                        (uint8_t)(b >> 4));
        }
        break;
    case 5:
        if (co_stack_guard_master(&W.tool) != NULL) {
            co_guard_master_unguard(co_stack_guard_master(&W.tool), node);
        }
        break;
    case 6:
        if (co_stack_guard_master(&W.tool) != NULL) {
            co_guard_master_expect_state(co_stack_guard_master(&W.tool), node,
                                         (co_nmt_state_t)(ms & 0x7Fu));
        }
        break;
    default:
        co_sync_accept_any_counter(co_stack_sync(&W.tool), (ms & 1u) != 0);
        break;
    }
}

static void store(fz_reader_t *r)
{
    uint8_t b = fz_u8(r);
    co_store_t *s = co_stack_store(&W.dev);
    if (s == NULL) {
        return;
    }
    co_line_set_time(&W.dev_line.line, W.now);
    if (b & 0x80u) {
        (void)co_store_restore_defaults(s, (uint8_t)(b & 7u));
    } else if (b & 0x40u) {
        (void)co_store_load(s, (uint8_t)(b & 7u));
    } else {
        (void)co_store_save(s, (uint8_t)(b & 7u));
    }
}

/* b bit 7: LSS configuration in progress (bit 0) or not; else the cause
 * bits of b's low 6 bits take those of the next byte. */
static void led_input(fz_reader_t *r)
{
    uint8_t b = fz_u8(r);
    co_led_t *led = co_stack_led(&W.dev);
    if (!led) {
        return;
    }
    co_line_set_time(&W.dev_line.line, W.now);
    if (b & 0x80u) {
        co_led_set_lss(led, (b & 1u) != 0);
    } else {
        co_led_set_causes(led, (uint8_t)(b & 0x3Fu), fz_u8(r));
    }
}

/* The application sends an MPDO through TPDO 1..4, whatever that TPDO is:
 * a SAM of a listed or unlisted object, a DAM of its mapped object, or a
 * DAM with its own value (1..4 bytes) to index:sub of a node. */
static void mpdo_send(fz_reader_t *r)
{
    static const uint16_t sam_objects[4] = {0x2002, 0x2001, 0x2100, 0x2103};
    uint8_t b = fz_u8(r);
    uint8_t c = fz_u8(r);
    uint32_t value = fz_u32(r);
    co_mpdo_t *mpdo = co_stack_mpdo(&W.dev);
    uint16_t tpdo = (uint16_t)((b & 3u) + 1u);
    uint8_t node = (uint8_t)(c & 0x7Fu);
    co_line_set_time(&W.dev_line.line, W.now);
    if (mpdo == NULL) {
        return;
    }
    if (b & 0x80u) {
        (void)co_mpdo_send_sam(mpdo, tpdo, sam_objects[(b >> 2) & 3u], 0);
    } else if (b & 0x40u) {
        (void)co_mpdo_send_dam_mapped(mpdo, tpdo, node);
    } else {
        uint8_t data[4];
        for (uint32_t i = 0; i < 4; i++) {
            data[i] = (uint8_t)(value >> (8 * i));
        }
        (void)co_mpdo_send_dam(mpdo, tpdo, node, (uint16_t)(0x2000u + ((b >> 2) & 7u)),
                               (uint8_t)(c >> 7), data, (uint8_t)(((b >> 5) & 1u) * 3u + 1u));
    }
}

static void action(uint8_t p, fz_reader_t *r)
{
    if (W.cfg->action_count == 0) {
        return;
    }
    switch ((fw_action_t)W.cfg->actions[p % W.cfg->action_count]) {
    case FW_CLIENT_START: client_start(r); break;
    case FW_CLIENT_CANCEL: client_cancel(r); break;
    case FW_SPLIT_MODE: W.split_mode = (fz_u8(r) & 1u) != 0; break;
    case FW_RESUME: resume(r); break;
    case FW_NMT_LOCAL: nmt_local(r); break;
    case FW_NMT_MASTER: nmt_master(r); break;
    case FW_OD_WRITE: od_write(r, false); break;
    case FW_OD_PUT: od_write(r, true); break;
    case FW_PDO_TRIGGER: pdo_trigger(r); break;
    case FW_EMCY: emcy(r); break;
    case FW_TIME_SEND: time_send(r); break;
    case FW_WATCH: watch(r); break;
    case FW_STORE: store(r); break;
    case FW_LED: led_input(r); break;
    case FW_MPDO_SEND: mpdo_send(r); break;
    default: break;
    }
}

/* ------------------------------------------------------------ running */

/* The run loop's own functions run at every step (thousands per input):
 * their comparisons would feed libFuzzer nothing about the core but cost
 * a coverage callback each, so they are not instrumented for coverage
 * (ASan and UBSan still check them). */
#define PLUMBING __attribute__((no_sanitize("coverage")))

PLUMBING static uint8_t fate(const co_frame_t *frame, void *user)
{
    (void)frame; (void)user;
    if (W.fate_left == 0) {
        return 1;
    }
    W.fate_left--;
    bool hit = (W.fate_mask >> W.fate_left) & 1u;
    return hit ? (W.fate_dup ? 2 : 0) : 1;
}

static bool trace;   /* FUZZ_TRACE set: every record and frame on stderr */

PLUMBING static void trace_frame(const char *what, const co_frame_t *f)
{
    if (!trace) {
        return;
    }
    fprintf(stderr, "%8llu.%03u %s %03X [%u]%s", (unsigned long long)(W.now / MS),
            (unsigned)(W.now % MS), what, (unsigned)f->id, f->len,
            (f->flags & CO_FRAME_RTR) ? " RTR" : "");
    for (uint8_t i = 0; i < f->len && !(f->flags & CO_FRAME_RTR) && i < CO_FRAME_MAX_DATA; i++) {
        fprintf(stderr, " %02X", f->data[i]);
    }
    fprintf(stderr, "\n");
}

PLUMBING static void carried(co_line_t *from, const co_frame_t *frame, void *user)
{
    (void)user;
    trace_frame(from == &W.dev_line.line ? "dev ->" : "tool->", frame);
    CHECK(co_frame_is_valid(frame), "an invalid frame was sent");
    if (co_line_mode(from) == CO_MODE_CLASSIC) {
        CHECK(!(frame->flags & CO_FRAME_FD), "an FD frame was sent on a classic line");
    }
}

PLUMBING static void check_queues(const co_line_t *l)
{
    CHECK(co_line_rx_count(l) <= QUEUE && co_line_tx_count(l) <= QUEUE &&
          co_line_rx_count(l) + co_line_rx_free(l) == QUEUE, "queue counts inconsistent");
}

/* co_line_process when it has something to do: a frame queued or a timer
 * due. Otherwise it would only move the line's clock (most calls: a step
 * usually concerns one line, and its last round finds both idle). */
PLUMBING static void process_line(co_line_t *l, uint64_t now)
{
    if (co_line_rx_count(l) == 0 && co_timer_list_next(co_line_timers(l)) > now) {
        co_line_set_time(l, now);
    } else {
        (void)co_line_process(l, now);
    }
}

/* Process both lines at `now` and carry frames until the bus is quiet. */
PLUMBING static void step(uint64_t now)
{
    CHECK(now >= W.now, "clock went backwards");
    W.now = now;
    W.steps++;
    for (uint32_t round = 0;; round++) {
        CHECK(round < ROUND_LIMIT, "the bus never becomes quiet at one instant");
        process_line(&W.dev_line.line, now);
        process_line(&W.tool_line.line, now);
        check_queues(&W.dev_line.line);
        check_queues(&W.tool_line.line);
        if (W.held || co_membus_transfer(&W.bus, carried, NULL) == 0) {
            return;
        }
    }
}

PLUMBING static uint64_t next_deadline(void)
{
    uint64_t a = co_timer_list_next(co_line_timers(&W.dev_line.line));
    uint64_t b = co_timer_list_next(co_line_timers(&W.tool_line.line));
    return a < b ? a : b;
}

/* Let time pass to `until`, stopping at every deadline. False when the step
 * budget ran out. */
PLUMBING static bool run_until(uint64_t until)
{
    uint32_t same = 0;
    for (;;) {
        uint64_t d = next_deadline();
        if (d > until) {
            break;
        }
        if (W.steps >= W.budget) {
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

static uint8_t client_active(void)
{
    if (W.cfg->mode == CO_MODE_FD) {
        return co_usdo_client_active(co_stack_usdo_client(&W.tool));
    }
    return co_sdo_client_active(co_stack_sdo_client(&W.tool));
}

static uint8_t server_active(void)
{
    if (W.cfg->mode == CO_MODE_FD) {
        return co_usdo_server_active(co_stack_usdo_server(&W.dev));
    }
    return co_sdo_server_active(co_stack_sdo_server(&W.dev));
}

/* Everything answered, no new input for a while: every transfer must end.
 * At most SETTLE_BUDGET steps, and never past `cap`. */
static void settle(uint32_t cap)
{
    W.held = false;
    W.fate_left = 0;
    W.split_mode = false;
    W.budget = W.steps + SETTLE_BUDGET;
    if (W.budget > cap) {
        W.budget = cap;
    }
    for (int n = 0; n < 64 && W.pending_count > 0; n++) {
        (void)resume_one(0, 0);
    }
    CHECK(W.pending_count == 0, "a split access cannot be resumed");
    step(W.now);   /* frames still queued are handled now, not at the end of the wait */
    if (!run_until(W.now + (uint64_t)SETTLE_MS * MS)) {
        return;   /* busy (short periods): no conclusion */
    }
    CHECK(W.pending_count == 0, "a split access appeared while settling");
    for (uint32_t i = 0; i < SLOTS; i++) {
        CHECK(!W.slots[i].running, "a client request never ended");
    }
    CHECK(client_active() == 0, "a client session is still busy after settling");
    CHECK(server_active() == 0, "a server session is still busy after settling");
}

static void build(const fw_config_t *cfg)
{
    memset(&W, 0, sizeof W);
    W.cfg = cfg;
    co_line_config_t lc = {.mode = cfg->mode, .brs = cfg->mode == CO_MODE_FD};
    co_membus_init(&W.bus);
    lc.rx_slots = W.dev_line.rx;
    lc.rx_capacity = QUEUE;
    lc.tx_slots = W.dev_line.tx;
    lc.tx_capacity = QUEUE;
    CHECK(co_line_init(&W.dev_line.line, &lc), "device line");
    lc.rx_slots = W.tool_line.rx;
    lc.tx_slots = W.tool_line.tx;
    CHECK(co_line_init(&W.tool_line.line, &lc), "tool line");
    CHECK(co_membus_attach(&W.bus, &W.dev_line.line) &&
          co_membus_attach(&W.bus, &W.tool_line.line), "membus attach");
    co_membus_set_fault(&W.bus, fate, NULL);

    build_od(cfg->mode);
    CHECK(co_od_subscribe(&W.od, 0x2100, 0, 0x2100, 0, &split_handler, NULL) &&
          co_od_subscribe(&W.od, 0x2007, 0, 0x2007, 0, &domain_handler, NULL),
          "OD subscriptions");
    co_od_xfer_init(&W.xfer, W.xfer_scratch, sizeof W.xfer_scratch);

    co_stack_arena_init(&W.dev_arena, W.dev_mem, sizeof W.dev_mem);
    co_stack_line_config_t dl = {.heartbeat_entries = 4};
    CHECK(co_stack_init(&W.dev, &W.dev_line.line, &dl, co_stack_arena_allocator(&W.dev_arena)) ==
          CO_STACK_OK, "device stack");
    co_stack_node_config_t nc = {.node_id = FW_NODE, .od = &W.od, .store_backend = &mem_ops,
                                 .server_sessions = 4, .leds = true, .led_changed = on_led};
    CHECK(co_stack_node_init(&W.dev, &nc) == CO_STACK_OK, "device node");
    if (cfg->device_client && cfg->mode == CO_MODE_CLASSIC) {
        co_stack_client_config_t dc = {.sessions = 2};
        CHECK(co_stack_client_init(&W.dev, &dc) == CO_STACK_OK, "device client");
    }

    co_stack_arena_init(&W.tool_arena, W.tool_mem, sizeof W.tool_mem);
    co_stack_line_config_t tl = {.heartbeat_entries = 8, .guarded_nodes = 4, .ind = &tool_ind};
    CHECK(co_stack_init(&W.tool, &W.tool_line.line, &tl,
                        co_stack_arena_allocator(&W.tool_arena)) == CO_STACK_OK, "tool stack");
    co_stack_client_config_t cc = {.sessions = SLOTS, .node_id = FW_CLIENT, .timeout_ms = 300};
    CHECK(co_stack_client_init(&W.tool, &cc) == CO_STACK_OK, "tool client");
    CHECK(co_stack_boot(&W.dev) == CO_STACK_OK, "device boot");
    W.target = cfg->inject_tool ? &W.tool_line.line : &W.dev_line.line;
}

static void teardown(void)
{
    co_stack_deinit(&W.tool);
    co_stack_deinit(&W.dev);
    for (uint32_t i = 0; i < SLOTS; i++) {
        CHECK(!W.slots[i].running, "a request outlived its client");
    }
}

/* The world as built and booted (after the first step at t = 0), one per
 * line mode. Every pointer the world holds points into W itself, to static
 * data or to code, never to the stack (checked below), and W never moves: a
 * byte copy of the snapshot back into W is the world build() makes. The core
 * keeps no state outside the structures it is given. */
typedef struct snapshot {
    bool made;
    fw_config_t cfg;
    world_t world;
} snapshot_t;

static snapshot_t snaps[2];

static bool same_config(const fw_config_t *a, const fw_config_t *b)
{
    return a->mode == b->mode && a->inject_tool == b->inject_tool && a->ids == b->ids &&
           a->id_count == b->id_count && a->actions == b->actions &&
           a->action_count == b->action_count && a->device_client == b->device_client;
}

/* Bytes past a frame's length are no part of it (co_frame_set leaves them
 * as they were: stack bytes of the sender, copied into the queue slot). */
static void clear_past_len(co_frame_t *slots)
{
    for (uint32_t i = 0; i < QUEUE; i++) {
        co_frame_t *f = &slots[i];
        uint32_t len = f->len < CO_FRAME_MAX_DATA ? f->len : CO_FRAME_MAX_DATA;
        memset(f->data + len, 0, CO_FRAME_MAX_DATA - len);
    }
}

/* No word of the world may hold an address near `here` (a local of the caller):
 * such a pointer would name a stack frame of build() that is gone, and the
 * copy would carry it into every later input. The queue slots' bytes past
 * each frame's length are cleared first (they are garbage, not pointers). */
static void check_no_stack_pointers(uintptr_t here)
{
    clear_past_len(W.dev_line.rx);
    clear_past_len(W.dev_line.tx);
    clear_past_len(W.tool_line.rx);
    clear_past_len(W.tool_line.tx);
    const unsigned char *p = (const unsigned char *)&W;
    /* build()'s frames lie below `here`, the callers' just above */
    const uintptr_t low = here - ((uintptr_t)256 << 10), high = here + ((uintptr_t)4 << 10);
    for (size_t off = 0; off + sizeof(uintptr_t) <= sizeof W; off += sizeof(uintptr_t)) {
        uintptr_t v;
        memcpy(&v, p + off, sizeof v);
        if (v >= low && v <= high) {
            fprintf(stderr, "world offset %zu (of %zu) holds %#llx, near the stack (%#llx)\n",
                    off, sizeof W, (unsigned long long)v, (unsigned long long)here);
            fw_fail("the built world points into the stack");
        }
    }
}

/* W as build(config) followed by step(0) leaves it. FUZZ_FRESH set: rebuild
 * for every input (to compare against the copy, e.g. with FUZZ_TRACE).
 * `keep` false: build without keeping the copy. libFuzzer's first call, with
 * an empty input, counts no coverage, so the copy is made from the first
 * non-empty input: the build's code then counts as covered. */
static void fresh_world(const fw_config_t *config, bool keep)
{
    snapshot_t *s = &snaps[config->mode == CO_MODE_FD ? 1 : 0];
    if (s->made && same_config(&s->cfg, config) && getenv("FUZZ_FRESH") == NULL) {
        memcpy(&W, &s->world, sizeof W);
        W.cfg = config;   /* may live in the caller's frame: the same values */
        return;
    }
    build(config);
    W.budget = STEP_BUDGET;
    step(0);
    if (!keep) {
        return;
    }
    int here = 0;
    W.cfg = NULL;   /* the one pointer allowed to name the caller's frame */
    check_no_stack_pointers((uintptr_t)&here);
    s->cfg = *config;
    memcpy(&s->world, &W, sizeof W);
    s->made = true;
    W.cfg = config;
}

void fw_run(const fw_config_t *config, const uint8_t *data, size_t size)
{
    fz_reader_t r;
    fz_record_t rec;
    trace = false;   /* the boot is not traced (the copy does not replay it) */
    fresh_world(config, size > 0);
    fz_reader_init(&r, data, size);
    trace = getenv("FUZZ_TRACE") != NULL;
    while (fz_next(&r, &rec, config->ids, config->id_count, config->mode)) {
        if (trace && rec.op != FZ_OP_FRAME) {
            fprintf(stderr, "%8llu.%03u record op %u p %u\n", (unsigned long long)(W.now / MS),
                    (unsigned)(W.now % MS), rec.op, rec.p);
        }
        switch (rec.op) {
        case FZ_OP_FRAME: {
            trace_frame(rec.alt == (W.target == &W.dev_line.line) ? "in tool" : "in dev ",
                        &rec.frame);
            co_line_t *to = rec.alt ? (W.target == &W.dev_line.line ? &W.tool_line.line
                                                                     : &W.dev_line.line)
                                    : W.target;
            co_line_set_time(to, W.now);
            (void)co_line_receive(to, &rec.frame);
            break;
        }
        case FZ_OP_TIME:
            if (!run_until(W.now + (uint64_t)rec.ms * MS)) {
                teardown();
                return;
            }
            break;
        case FZ_OP_ACTION:
            action(rec.p, &r);
            break;
        case FZ_OP_BUS:
            if (rec.p & 1u) {
                W.held = !W.held;
            }
            if (rec.has_mask) {
                W.fate_mask = rec.mask;
                W.fate_left = 8;
                W.fate_dup = (rec.p & 4u) != 0;
            }
            break;
        case FZ_OP_PROCESS:
            step(W.now);
            break;
        case FZ_OP_COMM:
            co_line_comm_event(W.target, (co_comm_event_t)(rec.p % 11u + 1u));
            break;
        case FZ_OP_SETTLE: {
            /* from the input's budget: N settle records cannot cost N x 40000 steps */
            uint32_t keep = W.budget;
            settle(keep);
            W.budget = keep;
            break;
        }
        default:
            break;
        }
    }
    settle(UINT32_MAX);
    teardown();
}
