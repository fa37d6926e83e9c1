/* Fault-injection matrix of every client transfer kind.
 *
 * A device (co_stack node 5 serving its OD: USDO on fd lines, SDO on classic
 * lines) and a tool (co_stack client) are joined by a bus this file carries
 * itself, frame by frame, with a fake clock. A clean run of each transfer
 * kind counts its transfer frames (requests and answers, both ways); then
 * for every k and every fault the k-th transfer frame is dropped,
 * duplicated, delayed past the timeouts, put behind the next frame, or has a
 * protocol header bit flipped. Every case must end:
 *   - done() called exactly once, within bounded time (never a hang);
 *   - a correct result (upload: the entry's bytes; download: the entry holds
 *     the new value), or an abort; a lost or late frame can only end in a
 *     timeout or a sequence error; an aborted download leaves the entry
 *     holding either the old or the new value, never a mix;
 *   - once the timeouts have run, no session or channel left open on either
 *     side;
 *   - and the next transfer of the same kind, without fault, succeeds.
 * Payload bytes are not corrupted: a segmented transfer without CRC cannot
 * tell (the CAN CRC guards them on a real bus); header bytes are. */
#include "test_od_util.h"

#include "canopenfd/co_stack.h"
#include "canopenfd/co_usdo.h"

#include <stdio.h>

enum {
    NODE = 5,
    TOOL = 9,                          /* the USDO client's node-id */
    BIG = 300,                         /* segmented / bulk / block entry 0x2005 */
    TIMEOUT_MS = 1000,                 /* both sides' per-frame timeouts (the defaults) */
    DELAY_MS = 1500,                   /* a delayed frame arrives after both timed out */
    SETTLE_MS = 3000,                  /* after done(): every server timeout has run */
    HANG_MS = 60000                    /* done() later than this after the start: a hang */
};

typedef enum fault {
    F_NONE,
    F_DROP,
    F_DUPLICATE,
    F_DELAY,
    F_REORDER,
    F_TRUNCATE,
    F_GARBLE,
    F_COUNT
} fault_t;

static const char *const fault_name[F_COUNT] = {"none", "drop", "duplicate", "delay",
                                                "reorder", "truncation", "garbled header"};

typedef struct kind {
    const char *name;
    co_mode_t mode;
    bool upload;
    uint8_t xfer_mode;                 /* co_usdo_mode_t / co_sdo_mode_t */
    uint16_t index;                    /* 0x2000 (U32) or 0x2005 (BIG octets) */
    bool broadcast;                    /* USDO broadcast (server 0) */
} kind_t;

static const kind_t kinds[] = {
    {"USDO expedited download", CO_MODE_FD, false, CO_USDO_MODE_EXPEDITED, 0x2000, false},
    {"USDO expedited upload", CO_MODE_FD, true, CO_USDO_MODE_AUTO, 0x2000, false},
    {"USDO segmented download", CO_MODE_FD, false, CO_USDO_MODE_SEGMENTED, 0x2005, false},
    {"USDO segmented upload", CO_MODE_FD, true, CO_USDO_MODE_AUTO, 0x2005, false},
    {"USDO bulk download", CO_MODE_FD, false, CO_USDO_MODE_BULK, 0x2005, false},
    {"USDO broadcast upload", CO_MODE_FD, true, CO_USDO_MODE_AUTO, 0x2000, true},
    {"USDO broadcast download", CO_MODE_FD, false, CO_USDO_MODE_EXPEDITED, 0x2000, true},
    {"SDO expedited download", CO_MODE_CLASSIC, false, CO_SDO_MODE_EXPEDITED, 0x2000, false},
    {"SDO expedited upload", CO_MODE_CLASSIC, true, CO_SDO_MODE_EXPEDITED, 0x2000, false},
    {"SDO segmented download", CO_MODE_CLASSIC, false, CO_SDO_MODE_SEGMENTED, 0x2005, false},
    {"SDO segmented upload", CO_MODE_CLASSIC, true, CO_SDO_MODE_SEGMENTED, 0x2005, false},
    {"SDO block download", CO_MODE_CLASSIC, false, CO_SDO_MODE_BLOCK, 0x2005, false},
    {"SDO block upload", CO_MODE_CLASSIC, true, CO_SDO_MODE_BLOCK, 0x2005, false},
};
#define N_KINDS (sizeof kinds / sizeof kinds[0])

static const tu_od_row_t device_rows[] = {
    {0x1000, 0, VAR, U32, RO, 0, 4, 0x00000191, NULL, 0, 0},
    {0x1001, 0, VAR, U8, RO, 0, 1, 0, NULL, 0, 0},
    {0x1017, 0, VAR, U16, RW, 0, 2, 0, NULL, 0, 0},
    {0x1018, 0, REC, U8, RO, 0, 1, 1, NULL, 0, 0},
    {0x1018, 1, REC, U32, RO, 0, 4, 0x12345678, NULL, 0, 0},
    {0x2000, 0, VAR, U32, RW, 0, 4, 0, NULL, 0, 0},
    {0x2005, 0, VAR, CO_TYPE_OCTET_STRING, RW, 0, BIG, 0, "", 0, 0},
};
#define N_ROWS (sizeof device_rows / sizeof device_rows[0])

/* ------------------------------------------------------------ the rig */

typedef struct rig {
    const kind_t *kind;
    tu_line_t dev_line;
    tu_line_t tool_line;
    co_od_t od;
    co_od_entry_t entries[32];
    uint8_t pool[1024];
    co_od_subscription_t subs[CO_STACK_OD_SUBSCRIPTIONS];
    co_stack_t dev;
    co_stack_arena_t dev_arena;
    unsigned char dev_memory[48 * 1024];
    co_stack_t tool;
    co_stack_arena_t tool_arena;
    unsigned char tool_memory[32 * 1024];
    uint64_t now;
    /* the fault */
    fault_t fault;
    unsigned target;                   /* which transfer frame (0-based) */
    unsigned seen;                     /* transfer frames carried so far */
    bool held;                         /* a delayed / reordered frame waits */
    co_frame_t held_frame;
    co_line_t *held_to;
    uint64_t held_until;               /* delay: due time; reorder: CO_TIME_NEVER */
    /* the request and what it gave */
    union {
        co_usdo_request_t usdo;
        co_sdo_request_t sdo;
    } req;
    co_buffer_t buffer;                /* download source / upload sink */
    uint8_t data[BIG];                 /* the value the run moves */
    uint8_t sink[BIG];                 /* an upload's bytes */
    unsigned done_calls;
    uint32_t abort;
    unsigned answers;                  /* broadcast: answers, data checked as they come */
    bool answer_wrong;
    uint8_t answer_abort;              /* broadcast: the (last) answer's abort code */
} rig_t;

static bool is_transfer_frame(const co_frame_t *f)
{
    return f->id >= 0x580u && f->id <= 0x67Fu;
}

static co_line_t *other_line(rig_t *r, co_line_t *from)
{
    return from == &r->dev_line.line ? &r->tool_line.line : &r->dev_line.line;
}

static void hold(rig_t *r, const co_frame_t *f, co_line_t *to, uint64_t until)
{
    assert_false(r->held);
    r->held = true;
    r->held_frame = *f;
    r->held_to = to;
    r->held_until = until;
}

static void release_held(rig_t *r)
{
    if (r->held) {
        r->held = false;
        (void)co_line_receive(r->held_to, &r->held_frame);
    }
}

/* The next valid frame length below len (CAN FD: 8, 12, 16, 20, 24, 32, 48, 64). */
static uint8_t shorter_len(uint8_t len)
{
    static const uint8_t fd_lengths[] = {8, 12, 16, 20, 24, 32, 48, 64};
    if (len <= 8) {
        return len > 0 ? (uint8_t)(len - 1) : 0;
    }
    uint8_t out = 8;
    for (size_t i = 0; i < sizeof fd_lengths && fd_lengths[i] < len; i++) {
        out = fd_lengths[i];
    }
    return out;
}

/* Carry one frame, applying the fault when it is the target. */
static void carry(rig_t *r, co_frame_t f, co_line_t *to)
{
    if (!is_transfer_frame(&f) || r->seen++ != r->target || r->fault == F_NONE) {
        (void)co_line_receive(to, &f);
        if (r->held && r->held_until == CO_TIME_NEVER && r->held_to == to) {
            release_held(r);           /* reorder: the held frame comes second */
        }
        return;
    }
    switch (r->fault) {
    case F_DROP:
        break;
    case F_DUPLICATE:
        (void)co_line_receive(to, &f);
        (void)co_line_receive(to, &f);
        break;
    case F_DELAY:
        hold(r, &f, to, r->now + (uint64_t)DELAY_MS * TU_MS);
        break;
    case F_REORDER:
        hold(r, &f, to, CO_TIME_NEVER);
        break;
    case F_TRUNCATE:
        /* one valid length shorter (FD: the next lower FD length), or empty */
        f.len = shorter_len(f.len);
        (void)co_line_receive(to, &f);
        break;
    case F_GARBLE: {
        /* a header bit: USDO bytes 0..3 (destination, command, session-ID,
         * sub-index / counter), SDO byte 0 (command, toggle, sequence) */
        unsigned header = r->kind->mode == CO_MODE_FD ? 4u : 1u;
        unsigned pos = (r->target / 8u) % header;
        if (pos < f.len) {
            f.data[pos] ^= (uint8_t)(1u << (r->target % 8u));
        }
        (void)co_line_receive(to, &f);
        break;
    }
    default:
        fail();
    }
}

/* Process both lines at r->now and carry frames until the bus is quiet. */
static void step(rig_t *r)
{
    co_line_t *lines[2] = {&r->dev_line.line, &r->tool_line.line};
    for (int round = 0; round < 1000; round++) {
        bool moved = false;
        for (int i = 0; i < 2; i++) {
            (void)co_line_process(lines[i], r->now);
        }
        for (int i = 0; i < 2; i++) {
            co_frame_t f;
            while (co_line_tx_pop(lines[i], &f)) {
                carry(r, f, other_line(r, lines[i]));
                moved = true;
            }
        }
        if (!moved) {
            if (r->held && r->held_until == CO_TIME_NEVER) {
                release_held(r);       /* nothing came after it: it arrives late anyway */
                continue;
            }
            return;
        }
    }
    fail_msg("%s: the bus did not become quiet at t=%llu ms", r->kind->name,
             (unsigned long long)(r->now / TU_MS));
}

static uint64_t next_deadline(rig_t *r)
{
    uint64_t next = co_timer_list_next(co_line_timers(&r->dev_line.line));
    uint64_t tool = co_timer_list_next(co_line_timers(&r->tool_line.line));
    if (tool < next) {
        next = tool;
    }
    if (r->held && r->held_until < next) {
        next = r->held_until;
    }
    return next;
}

/* Run the fake clock from deadline to deadline until `until`; a held frame
 * is delivered at its due time. */
static void run_until(rig_t *r, uint64_t until)
{
    for (long guard = 0;; guard++) {
        assert_true(guard < 100000);
        step(r);
        if (r->held && r->held_until <= r->now) {
            release_held(r);
            continue;
        }
        uint64_t next = next_deadline(r);
        if (next > until) {
            break;
        }
        r->now = next > r->now ? next : r->now;
    }
    r->now = until;
    step(r);
}

/* ------------------------------------------------------------ set-up */

static void rig_init(rig_t *r, const kind_t *kind)
{
    memset(r, 0, sizeof *r);
    r->kind = kind;
    bool fd = kind->mode == CO_MODE_FD;
    tu_line_init(&r->dev_line, kind->mode, fd);
    tu_line_init(&r->tool_line, kind->mode, fd);
    co_od_init(&r->od, kind->mode, r->entries, 32, r->pool, sizeof r->pool, r->subs,
               CO_STACK_OD_SUBSCRIPTIONS);
    tu_od_add_rows(&r->od, device_rows, N_ROWS);
    assert_true(co_od_seal(&r->od, NODE));
    co_stack_arena_init(&r->dev_arena, r->dev_memory, sizeof r->dev_memory);
    co_stack_arena_init(&r->tool_arena, r->tool_memory, sizeof r->tool_memory);
    co_stack_line_config_t lc = {.heartbeat_entries = 1};
    assert_int_equal(co_stack_init(&r->dev, &r->dev_line.line, &lc,
                                   co_stack_arena_allocator(&r->dev_arena)), CO_STACK_OK);
    co_stack_node_config_t nc = {.node_id = NODE, .od = &r->od};
    assert_int_equal(co_stack_node_init(&r->dev, &nc), CO_STACK_OK);
    assert_int_equal(co_stack_boot(&r->dev), CO_STACK_OK);
    assert_int_equal(co_stack_init(&r->tool, &r->tool_line.line, &lc,
                                   co_stack_arena_allocator(&r->tool_arena)), CO_STACK_OK);
    co_stack_client_config_t cc = {.sessions = 2, .node_id = TOOL, .timeout_ms = TIMEOUT_MS};
    assert_int_equal(co_stack_client_init(&r->tool, &cc), CO_STACK_OK);
    step(r);                           /* the boot-up goes out */
}

static void rig_deinit(rig_t *r)
{
    co_stack_deinit(&r->tool);
    co_stack_deinit(&r->dev);
}

static uint32_t entry_size(const kind_t *kind)
{
    return kind->index == 0x2005 ? BIG : 4u;
}

/* The value a run moves: upload = what the entry holds, download = what is
 * written; every run of a case uses another pattern. */
static void pattern(uint8_t *out, uint32_t n, unsigned seed)
{
    for (uint32_t i = 0; i < n; i++) {
        out[i] = (uint8_t)(seed * 31u + i * 7u + 1u);
    }
}

static void usdo_done(co_usdo_request_t *req)
{
    rig_t *r = req->user;
    r->done_calls++;
    r->abort = req->abort;
}

static void usdo_answer(co_usdo_request_t *req, uint8_t node, uint8_t abort, uint8_t type,
                        const uint8_t *data, uint32_t len)
{
    (void)type;
    rig_t *r = req->user;
    r->answers++;
    /* the server may refuse a damaged request (its abort is its answer); an
     * answer with data must carry the entry's value */
    if (node != NODE || (abort == 0 && req->upload && (len != 4 || memcmp(data, r->data, 4) != 0))) {
        r->answer_wrong = true;
    }
    r->answer_abort = abort;
}

static void sdo_done(co_sdo_request_t *req)
{
    rig_t *r = req->user;
    r->done_calls++;
    r->abort = req->abort;
}

static void start(rig_t *r, unsigned seed)
{
    const kind_t *k = r->kind;
    uint32_t size = entry_size(k);
    uint8_t old[BIG];
    r->done_calls = 0;
    r->abort = 0;
    r->answers = 0;
    r->answer_wrong = false;
    r->answer_abort = 0;
    /* the entry holds `old`; a download writes r->data, an upload reads it back */
    pattern(old, size, seed + 1000u);
    pattern(r->data, size, seed);
    assert_int_equal(co_od_put(&r->od, k->index, 0, k->upload ? r->data : old, size), 0);
    memset(r->sink, 0, sizeof r->sink);
    r->buffer = k->upload ? (co_buffer_t){.data = r->sink, .capacity = BIG}
                          : (co_buffer_t){.data = r->data, .size = size};
    co_line_set_time(&r->tool_line.line, r->now);
    if (k->mode == CO_MODE_FD) {
        co_usdo_request_t *q = &r->req.usdo;
        *q = (co_usdo_request_t){.server = k->broadcast ? 0 : NODE, .index = k->index,
                                 .upload = k->upload, .mode = k->xfer_mode, .size = size,
                                 .done = usdo_done, .user = r, .ctx = &r->buffer,
                                 .answer = usdo_answer};
        if (k->upload) {
            q->sink = co_usdo_buffer_sink;
            q->size = 0;
        } else {
            q->source = co_usdo_buffer_source;
        }
        assert_int_equal(co_usdo_client_start(co_stack_usdo_client(&r->tool), q), 0);
    } else {
        co_sdo_request_t *q = &r->req.sdo;
        *q = (co_sdo_request_t){.server = NODE, .index = k->index, .upload = k->upload,
                                .mode = k->xfer_mode, .size = size, .done = sdo_done,
                                .user = r, .ctx = &r->buffer};
        if (k->upload) {
            q->sink = co_sdo_buffer_sink;
        } else {
            q->source = co_sdo_buffer_source;
        }
        assert_int_equal(co_sdo_client_start(co_stack_sdo_client(&r->tool), q), 0);
    }
}

static bool is_lost_frame_abort(const rig_t *r)
{
    if (r->kind->mode == CO_MODE_FD) {
        /* a lost bulk segment shows as a counter gap, or as a size mismatch
         * when it was the last before the end */
        return r->abort == CO_USDO_ABORT_TIMEOUT || r->abort == CO_USDO_ABORT_COUNTER ||
               r->abort == CO_USDO_ABORT_DATA_SIZE;
    }
    return r->abort == CO_ABORT_TIMEOUT || r->abort == CO_ABORT_SEQUENCE ||
           r->abort == CO_ABORT_TOGGLE;
}

static unsigned open_sessions(rig_t *r)
{
    unsigned open;
    if (r->kind->mode == CO_MODE_FD) {
        open = co_usdo_client_active(co_stack_usdo_client(&r->tool)) +
               co_usdo_server_active(co_stack_usdo_server(&r->dev));
    } else {
        const co_sdo_server_t *s = co_stack_sdo_server(&r->dev);
        open = co_sdo_client_active(co_stack_sdo_client(&r->tool));
        for (uint8_t i = 0; i < s->channel_count; i++) {
            open += s->channels[i].state != CO_SDO_CH_IDLE;
        }
    }
    return open;
}

/* Run the transfer started at r->now to its end and check the outcome;
 * returns true when it succeeded. */
static bool finish(rig_t *r, const char *what)
{
    const kind_t *k = r->kind;
    uint64_t started = r->now;
    while (r->done_calls == 0) {
        uint64_t next = next_deadline(r);
        if (next == CO_TIME_NEVER || next > started + (uint64_t)HANG_MS * TU_MS) {
            fail_msg("%s: never ended (t=%llu ms)", what,
                     (unsigned long long)((r->now - started) / TU_MS));
        }
        run_until(r, next > r->now ? next : r->now);
    }
    run_until(r, r->now + (uint64_t)SETTLE_MS * TU_MS);
    if (r->done_calls != 1) {
        fail_msg("%s: done() called %u times", what, r->done_calls);
    }
    if (open_sessions(r) != 0) {
        fail_msg("%s: %u sessions/channels still open after the timeouts", what,
                 open_sessions(r));
    }
    uint32_t size = entry_size(k);
    uint8_t now_held[BIG];
    uint32_t len = 0;
    assert_int_equal(co_od_get(&r->od, k->index, 0, now_held, sizeof now_held, &len), 0);
    if (k->broadcast) {
        if (r->abort != 0 || r->answer_wrong || r->answers > 1) {
            fail_msg("%s: broadcast ended with abort 0x%X, %u answers%s", what, r->abort,
                     r->answers, r->answer_wrong ? " (a wrong one)" : "");
        }
        return r->answers == 1 && r->answer_abort == 0;
    }
    if (r->abort == 0) {
        if (k->upload) {
            /* A garbled header can make another valid answer (an SDO segmented
             * initiate answer turned expedited gives the size field as data):
             * no protocol without a CRC over the header can tell. */
            if (r->fault == F_GARBLE) {
                return true;
            }
            if (r->buffer.size != size || memcmp(r->sink, r->data, size) != 0) {
                fail_msg("%s: succeeded with wrong data (%u bytes)", what, r->buffer.size);
            }
        } else if (len != size || memcmp(now_held, r->data, size) != 0) {
            fail_msg("%s: succeeded but the entry does not hold the value", what);
        }
        return true;
    }
    if ((r->fault == F_DROP || r->fault == F_DELAY) && !is_lost_frame_abort(r)) {
        fail_msg("%s: a lost frame ended in abort 0x%X (expected a timeout or sequence error)",
                 what, r->abort);
    }
    return false;
}

/* ------------------------------------------------------------ the matrix */

typedef struct tally {
    unsigned cases, ok, aborted;
} tally_t;

static void check_old_or_new(rig_t *r, unsigned seed, const char *what)
{
    const kind_t *k = r->kind;
    if (k->upload || r->abort == 0 || k->broadcast) {
        return;
    }
    uint32_t size = entry_size(k);
    uint8_t held[BIG], old[BIG], new_value[BIG];
    uint32_t len = 0;
    assert_int_equal(co_od_get(&r->od, k->index, 0, held, sizeof held, &len), 0);
    pattern(old, size, seed + 1000u);
    pattern(new_value, size, seed);
    if (len != size || (memcmp(held, old, size) != 0 && memcmp(held, new_value, size) != 0)) {
        fail_msg("%s: aborted download left the entry half written", what);
    }
}

static unsigned clean_frames(const kind_t *kind)
{
    rig_t *r = calloc(1, sizeof *r);
    assert_non_null(r);
    rig_init(r, kind);
    r->fault = F_NONE;
    r->seen = 0;
    start(r, 1);
    char what[96];
    snprintf(what, sizeof what, "%s (no fault)", kind->name);
    assert_true(finish(r, what));
    unsigned n = r->seen;
    rig_deinit(r);
    free(r);
    return n;
}

static void run_case(const kind_t *kind, fault_t fault, unsigned k, tally_t *t)
{
    rig_t *r = calloc(1, sizeof *r);
    assert_non_null(r);
    char what[128];
    snprintf(what, sizeof what, "%s, %s of transfer frame %u", kind->name, fault_name[fault], k);
    rig_init(r, kind);
    r->fault = fault;
    r->target = k;
    r->seen = 0;
    start(r, 2 + k);
    bool ok = finish(r, what);
    check_old_or_new(r, 2 + k, what);
    t->cases++;
    if (ok) {
        t->ok++;
    } else {
        t->aborted++;
    }
    /* the same channel works again, with no fault */
    r->fault = F_NONE;
    r->target = 0;
    r->seen = 1;                       /* never the target again */
    start(r, 500 + k);
    snprintf(what, sizeof what, "%s, the transfer after a %s of frame %u", kind->name,
             fault_name[fault], k);
    if (!finish(r, what)) {
        fail_msg("%s: failed with abort 0x%X", what, r->abort);
    }
    rig_deinit(r);
    free(r);
}

/* Every fault at every transfer frame of one kind (the cmocka state). */
static void test_kind_under_every_fault(void **state)
{
    const kind_t *kind = *state;
    unsigned frames = clean_frames(kind);
    assert_true(frames >= 1);
    tally_t t = {0, 0, 0};
    for (int fault = F_DROP; fault < F_COUNT; fault++) {
        for (unsigned k = 0; k < frames; k++) {
            run_case(kind, (fault_t)fault, k, &t);
        }
    }
    print_message("fault matrix: %-24s %3u frames, %4u cases: %u ended correct, %u aborted\n",
                  kind->name, frames, t.cases, t.ok, t.aborted);
}

int main(void)
{
    struct CMUnitTest tests[N_KINDS];
    for (size_t i = 0; i < N_KINDS; i++) {
        tests[i] = (struct CMUnitTest){.name = kinds[i].name,
                                       .test_func = test_kind_under_every_fault,
                                       .initial_state = (void *)&kinds[i]};
    }
    return _cmocka_run_group_tests("fault matrix", tests, N_KINDS, NULL, NULL);
}
