/* libFuzzer harness: the CiA 401 device co_stack binds to its node's OD
 * (co_cia401_od, co_stack_cia401_init). One classic line, one node with two
 * input groups, one output group, one analogue input and two analogue
 * outputs (the parameters of docs/cia401.md, TPDO1/2 and RPDO1/2 mapping
 * them); any frame (NMT, SYNC, RPDO1/2, SDO; raw ids reach the rest), and
 * the application's calls: inputs (groups in and out of range), analogue
 * inputs, faults, SDO downloads and the application's own writes of the
 * profile objects. First input byte: nothing (kept for the record format).
 *
 * Checks after every record: 0x6000 / 0x6401 show the input states the
 * device holds; every parameter the device holds equals its OD entry; the
 * analogue outputs stay INTEGER16; every indication names one kind or
 * both, and each is told with a real change. */
#include "fuzz_input.h"

#include "canopenfd/co_stack.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { SLOTS = 64, ENTRIES = 96, POOL = 1024, NODE = 5, GROUPS = 2, AIS = 1, AOS = 2 };

typedef struct io_world {
    co_line_t line;
    co_frame_t rx[SLOTS], tx[SLOTS];
    co_od_t od;
    co_od_entry_t entries[ENTRIES];
    uint8_t pool[POOL];
    co_od_subscription_t subs[CO_STACK_OD_SUBSCRIPTIONS];
    co_stack_t stack;
    co_stack_arena_t arena;
    unsigned char memory[64 * 1024];
    uint64_t now;
    uint8_t digital;                 /* the levels last told */
    int32_t analog[AOS];
} io_world_t;

static io_world_t W;
static const uint32_t ids[] = {0x000, 0x080, 0x205, 0x305, 0x605};

static void fail(const char *what)
{
    fprintf(stderr, "fuzz invariant broken: %s\n", what);
    abort();
}

#define CHECK(cond, what) do { if (!(cond)) { fail(what); } } while (0)

/* The profile objects: index, type, per channel (count) or global (0), default. */
static const struct {
    uint16_t index;
    uint8_t type;
    uint8_t count;
    uint32_t value;
} objects[] = {
    {0x6000, CO_TYPE_UNSIGNED8, GROUPS, 0}, {0x6002, CO_TYPE_UNSIGNED8, GROUPS, 0},
    {0x6003, CO_TYPE_UNSIGNED8, GROUPS, 0}, {0x6005, CO_TYPE_BOOLEAN, 0, 1},
    {0x6006, CO_TYPE_UNSIGNED8, GROUPS, 0xFF}, {0x6007, CO_TYPE_UNSIGNED8, GROUPS, 0},
    {0x6008, CO_TYPE_UNSIGNED8, GROUPS, 0}, {0x6200, CO_TYPE_UNSIGNED8, 1, 0},
    {0x6202, CO_TYPE_UNSIGNED8, 1, 0}, {0x6206, CO_TYPE_UNSIGNED8, 1, 0xFF},
    {0x6207, CO_TYPE_UNSIGNED8, 1, 0}, {0x6208, CO_TYPE_UNSIGNED8, 1, 0xFF},
    {0x6401, CO_TYPE_INTEGER16, AIS, 0}, {0x6411, CO_TYPE_INTEGER16, AOS, 0},
    {0x6421, CO_TYPE_UNSIGNED8, AIS, 7}, {0x6423, CO_TYPE_BOOLEAN, 0, 1},
    {0x6424, CO_TYPE_INTEGER32, AIS, 0}, {0x6425, CO_TYPE_INTEGER32, AIS, 0},
    {0x6426, CO_TYPE_UNSIGNED32, AIS, 0}, {0x6427, CO_TYPE_UNSIGNED32, AIS, 0},
    {0x6428, CO_TYPE_UNSIGNED32, AIS, 0}, {0x6443, CO_TYPE_UNSIGNED8, AOS, 1},
    {0x6444, CO_TYPE_INTEGER32, AOS, 0},
};
enum { OBJECTS = sizeof objects / sizeof objects[0] };

static void add(uint16_t index, uint8_t sub, uint8_t object, uint8_t type, uint8_t access,
                uint32_t value)
{
    CHECK(fz_od_add(&W.od, index, sub, object, type, access, value), "OD refuses an entry");
}

/* A PDO's communication record and mapping: COB-ID, type 255, the entries. */
static void pdo(uint16_t comm, uint32_t cob_id, const uint32_t *map, uint8_t count)
{
    const uint8_t rec = CO_OBJECT_RECORD, arr = CO_OBJECT_ARRAY;
    add(comm, 0, rec, CO_TYPE_UNSIGNED8, CO_ACCESS_RO, 2);
    add(comm, 1, rec, CO_TYPE_UNSIGNED32, CO_ACCESS_RW, cob_id);
    add(comm, 2, rec, CO_TYPE_UNSIGNED8, CO_ACCESS_RW, 255);
    add((uint16_t)(comm + 0x200), 0, arr, CO_TYPE_UNSIGNED8, CO_ACCESS_RW, count);
    for (uint8_t i = 0; i < count; i++) {
        add((uint16_t)(comm + 0x200), (uint8_t)(i + 1), arr, CO_TYPE_UNSIGNED32, CO_ACCESS_RW,
            map[i]);
    }
}

static void od_build(void)
{
    static const uint32_t tpdo1[] = {0x60000108, 0x60000208}, tpdo2[] = {0x64010110},
                          rpdo1[] = {0x62000108}, rpdo2[] = {0x64110110, 0x64110210};
    co_od_init(&W.od, CO_MODE_CLASSIC, W.entries, ENTRIES, W.pool, POOL, W.subs,
               CO_STACK_OD_SUBSCRIPTIONS);
    add(0x1000, 0, CO_OBJECT_VAR, CO_TYPE_UNSIGNED32, CO_ACCESS_RO, 0x000F0191);
    add(0x1001, 0, CO_OBJECT_VAR, CO_TYPE_UNSIGNED8, CO_ACCESS_RO, 0);
    pdo(0x1400, 0x200 + NODE, rpdo1, 1);
    pdo(0x1401, 0x300 + NODE, rpdo2, 2);
    pdo(0x1800, 0x180 + NODE, tpdo1, 2);
    pdo(0x1801, 0x280 + NODE, tpdo2, 1);
    for (size_t i = 0; i < OBJECTS; i++) {
        uint16_t index = objects[i].index;
        uint8_t access = index == 0x6000 || index == 0x6401 ? CO_ACCESS_RO : CO_ACCESS_RW;
        if (objects[i].count == 0) {
            add(index, 0, CO_OBJECT_VAR, objects[i].type, access, objects[i].value);
            continue;
        }
        add(index, 0, CO_OBJECT_ARRAY, CO_TYPE_UNSIGNED8, CO_ACCESS_RO, objects[i].count);
        for (uint8_t sub = 1; sub <= objects[i].count; sub++) {
            add(index, sub, CO_OBJECT_ARRAY, objects[i].type, access, objects[i].value);
        }
    }
    CHECK(co_od_seal(&W.od, NODE), "OD does not seal");
}

static int64_t od_int(uint16_t index, uint8_t sub)
{
    const co_od_entry_t *e = co_od_find(&W.od, index, sub);
    uint8_t b[4] = {0, 0, 0, 0};
    uint32_t n = 0;
    CHECK(e != NULL && co_od_get(&W.od, index, sub, b, sizeof b, &n) == 0, "entry unreadable");
    uint32_t u = (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 |
                 (uint32_t)b[3] << 24;
    return e->type == CO_TYPE_INTEGER16 ? (int16_t)(uint16_t)u
           : e->type == CO_TYPE_INTEGER32 ? (int32_t)u : (int64_t)u;
}

static void on_outputs(co_cia401_od_t *io, uint8_t kinds, void *user)
{
    (void)user;
    bool changed = false;
    CHECK(kinds != 0 && (kinds & ~(CO_CIA401_OUT_DIGITAL | CO_CIA401_OUT_ANALOG)) == 0,
          "an indication without a kind");
    if (kinds & CO_CIA401_OUT_DIGITAL) {
        changed |= co_cia401_od_digital_output(io, 1) != W.digital;
        W.digital = co_cia401_od_digital_output(io, 1);
    }
    for (uint8_t c = 0; c < AOS && (kinds & CO_CIA401_OUT_ANALOG); c++) {
        changed |= co_cia401_od_analog_output(io, (uint8_t)(c + 1)) != W.analog[c];
        W.analog[c] = co_cia401_od_analog_output(io, (uint8_t)(c + 1));
    }
    CHECK(changed, "an indication without a change");
}

static void check(void)
{
    const co_cia401_od_t *io = co_stack_cia401(&W.stack);
    CHECK(io != NULL, "the device stopped");
    for (uint8_t g = 0; g < GROUPS; g++) {
        const co_cia401_din_t *d = &io->din[g];
        uint8_t sub = (uint8_t)(g + 1);
        CHECK(od_int(0x6000, sub) == d->value, "0x6000 differs from the input state");
        CHECK(od_int(0x6002, sub) == d->polarity && od_int(0x6003, sub) == d->filter &&
              od_int(0x6006, sub) == d->any_change && od_int(0x6007, sub) == d->rising &&
              od_int(0x6008, sub) == d->falling && od_int(0x6005, 0) == d->interrupt_enable,
              "a digital input parameter differs from the OD");
    }
    const co_cia401_dout_t *o = &io->dout[0];
    CHECK(od_int(0x6202, 1) == o->polarity && od_int(0x6206, 1) == o->error_mode &&
          od_int(0x6207, 1) == o->error_value && od_int(0x6208, 1) == o->filter_mask,
          "a digital output parameter differs from the OD");
    const co_cia401_ain_t *a = &io->ain[0];
    CHECK(od_int(0x6401, 1) == a->value, "0x6401 differs from the input state");
    CHECK(od_int(0x6421, 1) == a->trigger && od_int(0x6423, 0) == a->interrupt_enable &&
          od_int(0x6424, 1) == a->upper_limit && od_int(0x6425, 1) == a->lower_limit &&
          od_int(0x6426, 1) == a->delta && od_int(0x6427, 1) == a->negative_delta &&
          od_int(0x6428, 1) == a->positive_delta,
          "an analogue input parameter differs from the OD");
    for (uint8_t c = 0; c < AOS; c++) {
        const co_cia401_aout_t *out = &io->aout[c];
        /* 0x6443 is UNSIGNED8: any value but 0 turns the error mode on */
        CHECK((od_int(0x6443, (uint8_t)(c + 1)) != 0) == out->error_mode &&
              od_int(0x6444, (uint8_t)(c + 1)) == out->error_value,
              "an analogue output parameter differs from the OD");
        CHECK(out->physical >= INT16_MIN && out->physical <= INT16_MAX,
              "an analogue output left INTEGER16");
    }
}

/* An entry of the profile objects, picked by the input. */
static void pick(fz_reader_t *r, uint16_t *index, uint8_t *sub)
{
    uint8_t which = fz_u8(r);
    uint8_t i = (uint8_t)(which % OBJECTS);
    *index = objects[i].index;
    *sub = objects[i].count ? (uint8_t)(1 + (which >> 5) % objects[i].count) : 0;
}

static void receive(uint32_t id, const uint8_t *data, uint8_t len)
{
    co_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = id;
    f.len = len;
    memcpy(f.data, data, len);
    (void)co_line_receive(&W.line, &f);
}

static void act(fz_reader_t *r, uint8_t p)
{
    co_cia401_od_t *io = co_stack_cia401(&W.stack);
    co_line_set_time(&W.line, W.now);
    switch (p % 5) {
    case 0: {
        uint8_t first = fz_u8(r) % 4, count = fz_u8(r) % 4, raw[3];
        fz_bytes(r, raw, sizeof raw);
        (void)co_cia401_od_set_inputs(io, first, raw, count);
        break;
    }
    case 1:
        (void)co_cia401_od_set_analog_input(io, fz_u8(r) % 3, (int16_t)fz_u16(r));
        break;
    case 2:
        co_cia401_od_fault(io);
        break;
    case 3: {   /* an SDO download as a master sends it (expedited, 4 bytes given) */
        uint16_t index;
        uint8_t sub, request[8] = {0x23, 0, 0, 0, 0, 0, 0, 0};
        pick(r, &index, &sub);
        request[1] = (uint8_t)index;
        request[2] = (uint8_t)(index >> 8);
        request[3] = sub;
        fz_bytes(r, request + 4, 4);
        const co_od_entry_t *e = co_od_find(&W.od, index, sub);
        request[0] = (uint8_t)(0x23 | (4u - (e ? e->size : 4u)) << 2);
        receive(0x600 + NODE, request, 8);
        break;
    }
    default: {  /* the application's own write */
        uint16_t index;
        uint8_t sub, value[4];
        pick(r, &index, &sub);
        fz_bytes(r, value, sizeof value);
        const co_od_entry_t *e = co_od_find(&W.od, index, sub);
        if (index != 0x6000 && index != 0x6401 && e != NULL) {
            (void)co_od_put(&W.od, index, sub, value, e->size);
        }
        break;
    }
    }
    (void)co_line_process(&W.line, W.now);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fz_reader_t r;
    fz_record_t rec;
    co_frame_t drop;
    if (size == 0) {
        return 0;
    }
    memset(&W, 0, sizeof W);
    CHECK(fz_line_init(&W.line, CO_MODE_CLASSIC, W.rx, W.tx, SLOTS), "line init");
    od_build();
    co_stack_arena_init(&W.arena, W.memory, sizeof W.memory);
    co_stack_line_config_t slc = {.heartbeat_entries = 1};
    CHECK(co_stack_init(&W.stack, &W.line, &slc, co_stack_arena_allocator(&W.arena)) ==
          CO_STACK_OK, "stack init");
    co_stack_node_config_t nc = {.node_id = NODE, .od = &W.od};
    CHECK(co_stack_node_init(&W.stack, &nc) == CO_STACK_OK, "node init");
    CHECK(co_stack_cia401_init(&W.stack, on_outputs, NULL) == CO_STACK_OK, "device init");
    CHECK(co_stack_boot(&W.stack) == CO_STACK_OK, "boot");
    check();
    fz_reader_init(&r, data + 1, size - 1);
    while (fz_next(&r, &rec, ids, sizeof ids / sizeof ids[0], CO_MODE_CLASSIC)) {
        switch (rec.op) {
        case FZ_OP_TIME:
            W.now += (uint64_t)rec.ms * 1000u;
            (void)co_line_process(&W.line, W.now);
            break;
        case FZ_OP_ACTION:
            act(&r, rec.p);
            break;
        default:
            if (rec.op == FZ_OP_FRAME || rec.op == FZ_OP_FRAME2) {
                (void)co_line_receive(&W.line, &rec.frame);
            }
            (void)co_line_process(&W.line, W.now);
            break;
        }
        while (co_line_tx_pop(&W.line, &drop)) {
        }
        check();
    }
    co_stack_deinit(&W.stack);
    return 0;
}
