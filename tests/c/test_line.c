/* co_line: dispatch by CAN-ID, statistics, tx/rx queues and comm events. */
#include "test_util.h"

#define SMALL 4
#define MAX_SEEN 64
#define MAX_EVENTS 64

typedef struct fx {
    co_line_t line;
    co_frame_t rx_slots[TU_QUEUE];
    co_frame_t tx_slots[TU_QUEUE];
    /* frames seen by receive handlers: which handler, which frame */
    int seen_by[MAX_SEEN];
    co_frame_t seen[MAX_SEEN];
    uint64_t seen_at[MAX_SEEN];
    int seen_count;
    co_comm_event_t events[MAX_EVENTS];
    int event_count;
} fx_t;

typedef struct handler {
    fx_t *fx;
    int tag;
} handler_t;

static void on_rx(co_line_t *line, const co_frame_t *frame, void *user)
{
    handler_t *h = user;
    fx_t *fx = h->fx;
    assert_ptr_equal(line, &fx->line);
    assert_true(fx->seen_count < MAX_SEEN);
    fx->seen_by[fx->seen_count] = h->tag;
    fx->seen[fx->seen_count] = *frame;
    fx->seen_at[fx->seen_count] = co_line_now(line);
    fx->seen_count++;
}

static void on_comm(co_line_t *line, co_comm_event_t event, void *user)
{
    fx_t *fx = user;
    assert_ptr_equal(line, &fx->line);
    assert_true(fx->event_count < MAX_EVENTS);
    fx->events[fx->event_count++] = event;
}

static int count_events(const fx_t *fx, co_comm_event_t event)
{
    int i, n = 0;
    for (i = 0; i < fx->event_count; i++)
        n += fx->events[i] == event;
    return n;
}

static int setup(void **state)
{
    *state = calloc(1, sizeof(fx_t));
    return *state == NULL ? -1 : 0;
}

static int teardown(void **state)
{
    free(*state);
    return 0;
}

/* Initialise the fixture's line (storage comes from setup, so that a failing
 * test leaks nothing). */
static fx_t *fx_new(void **state, co_mode_t mode, bool brs, uint32_t rx_cap, uint32_t tx_cap)
{
    fx_t *fx = *state;
    co_line_config_t cfg;
    memset(&cfg, 0, sizeof cfg);
    cfg.mode = mode;
    cfg.brs = brs;
    cfg.rx_slots = fx->rx_slots;
    cfg.rx_capacity = rx_cap;
    cfg.tx_slots = fx->tx_slots;
    cfg.tx_capacity = tx_cap;
    assert_true(co_line_init(&fx->line, &cfg));
    co_line_set_comm_indication(&fx->line, on_comm, fx);
    return fx;
}

static void receive(fx_t *fx, uint32_t id, uint8_t flags, uint8_t len)
{
    co_frame_t f;
    uint8_t data[64];
    uint8_t i;
    for (i = 0; i < 64; i++)
        data[i] = (uint8_t)(id + i);
    f = tu_frame(id, flags, data, len);
    assert_true(co_line_receive(&fx->line, &f));
}

/* ------------------------------------------------------------ init */

static void test_init_refuses_missing_queue_storage(void **state)
{
    co_line_t line;
    co_frame_t slots[4];
    co_line_config_t cfg;
    (void)state;
    memset(&cfg, 0, sizeof cfg);
    cfg.mode = CO_MODE_FD;
    cfg.rx_slots = NULL;
    cfg.rx_capacity = 4;
    cfg.tx_slots = slots;
    cfg.tx_capacity = 4;
    assert_false(co_line_init(&line, &cfg));
    cfg.rx_slots = slots;
    cfg.rx_capacity = 0;
    assert_false(co_line_init(&line, &cfg));
    cfg.rx_capacity = 4;
    cfg.tx_slots = NULL;
    assert_false(co_line_init(&line, &cfg));
    cfg.tx_slots = slots;
    cfg.tx_capacity = 0;
    assert_false(co_line_init(&line, &cfg));
    assert_false(co_line_init(&line, NULL));
}

static void test_init_refuses_unknown_mode(void **state)
{
    co_line_t line;
    co_frame_t rx[4], tx[4];
    co_line_config_t cfg;
    (void)state;
    memset(&cfg, 0, sizeof cfg);
    cfg.mode = (co_mode_t)2;
    cfg.rx_slots = rx;
    cfg.rx_capacity = 4;
    cfg.tx_slots = tx;
    cfg.tx_capacity = 4;
    assert_false(co_line_init(&line, &cfg));
}

static void test_init_starts_clean(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC, false, SMALL, SMALL);
    co_line_stats_t zero;
    memset(&zero, 0, sizeof zero);
    assert_memory_equal(&fx->line.stats, &zero, sizeof zero);
    assert_int_equal(co_line_node_id(&fx->line), 0);
    assert_int_equal(co_line_rx_count(&fx->line), 0);
    assert_int_equal(co_line_tx_count(&fx->line), 0);
    assert_true(co_line_process(&fx->line, 0) == CO_TIME_NEVER);
}

/* ------------------------------------------------------------ dispatch */

static void test_dispatch_by_id_range(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC, false, TU_QUEUE, TU_QUEUE);
    handler_t a = {fx, 1}, b = {fx, 2};
    assert_true(co_line_subscribe(&fx->line, 0x180, 0x1FF, on_rx, &a));
    assert_true(co_line_subscribe(&fx->line, 0x200, 0x200, on_rx, &b));
    receive(fx, 0x180, 0, 8);   /* a: first id */
    receive(fx, 0x1FF, 0, 1);   /* a: last id */
    receive(fx, 0x200, 0, 0);   /* b */
    receive(fx, 0x17F, 0, 2);   /* nobody, just below */
    receive(fx, 0x201, 0, 2);   /* nobody, just above */
    (void)co_line_process(&fx->line, 1000);
    assert_int_equal(fx->seen_count, 3);
    assert_int_equal(fx->seen_by[0], 1);
    assert_int_equal(fx->seen[0].id, 0x180);
    assert_int_equal(fx->seen[0].len, 8);
    assert_int_equal(fx->seen_by[1], 1);
    assert_int_equal(fx->seen[1].id, 0x1FF);
    assert_int_equal(fx->seen_by[2], 2);
    assert_int_equal(fx->seen[2].id, 0x200);
    assert_int_equal(fx->line.stats.rx_frames, 5);
    assert_int_equal(fx->line.stats.rx_unhandled, 2);
}

static void test_dispatch_passes_frame_unchanged(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD, true, SMALL, SMALL);
    handler_t a = {fx, 1};
    uint8_t d[64];
    co_frame_t f;
    int i;
    for (i = 0; i < 64; i++)
        d[i] = (uint8_t)(0xC0 ^ i);
    f = tu_frame(0x305, CO_FRAME_FD | CO_FRAME_BRS | CO_FRAME_ESI, d, 64);
    assert_true(co_line_subscribe(&fx->line, 0x300, 0x30F, on_rx, &a));
    assert_true(co_line_receive(&fx->line, &f));
    (void)co_line_process(&fx->line, 77);
    assert_int_equal(fx->seen_count, 1);
    tu_assert_frame(&fx->seen[0], 0x305, CO_FRAME_FD | CO_FRAME_BRS | CO_FRAME_ESI, d, 64);
    assert_int_equal(fx->seen_at[0], 77);   /* line->now_us set before dispatch */
}

static void test_dispatch_keeps_receive_order(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC, false, TU_QUEUE, TU_QUEUE);
    handler_t a = {fx, 1}, b = {fx, 2};
    const uint32_t ids[] = {0x181, 0x281, 0x182, 0x182, 0x282, 0x181};
    int i;
    assert_true(co_line_subscribe(&fx->line, 0x180, 0x1FF, on_rx, &a));
    assert_true(co_line_subscribe(&fx->line, 0x280, 0x2FF, on_rx, &b));
    for (i = 0; i < 6; i++)
        receive(fx, ids[i], 0, 1);
    (void)co_line_process(&fx->line, 0);
    assert_int_equal(fx->seen_count, 6);
    for (i = 0; i < 6; i++)
        assert_int_equal(fx->seen[i].id, ids[i]);
}

static void test_nothing_dispatched_before_process(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC, false, SMALL, SMALL);
    handler_t a = {fx, 1};
    assert_true(co_line_subscribe(&fx->line, 0x100, 0x100, on_rx, &a));
    receive(fx, 0x100, 0, 1);
    assert_int_equal(fx->seen_count, 0);
    assert_int_equal(co_line_rx_count(&fx->line), 1);
    (void)co_line_process(&fx->line, 0);
    assert_int_equal(fx->seen_count, 1);
    assert_int_equal(co_line_rx_count(&fx->line), 0);
}

static void test_whole_id_space_subscribable(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC, false, SMALL, SMALL);
    handler_t a = {fx, 1};
    assert_true(co_line_subscribe(&fx->line, 0x000, 0x7FF, on_rx, &a));
    receive(fx, 0x000, 0, 0);
    receive(fx, 0x7FF, 0, 0);
    (void)co_line_process(&fx->line, 0);
    assert_int_equal(fx->seen_count, 2);
}

static void test_overlapping_subscribe_refused(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC, false, SMALL, SMALL);
    handler_t a = {fx, 1}, b = {fx, 2};
    assert_true(co_line_subscribe(&fx->line, 0x100, 0x1FF, on_rx, &a));
    assert_false(co_line_subscribe(&fx->line, 0x1FF, 0x2FF, on_rx, &b));  /* tail */
    assert_false(co_line_subscribe(&fx->line, 0x050, 0x100, on_rx, &b));  /* head */
    assert_false(co_line_subscribe(&fx->line, 0x150, 0x160, on_rx, &b));  /* inside */
    assert_false(co_line_subscribe(&fx->line, 0x000, 0x7FF, on_rx, &b));  /* around */
    assert_false(co_line_subscribe(&fx->line, 0x100, 0x1FF, on_rx, &a));  /* same */
    assert_true(co_line_subscribe(&fx->line, 0x200, 0x200, on_rx, &b));   /* adjacent */
    assert_true(co_line_subscribe(&fx->line, 0x0FF, 0x0FF, on_rx, &b));   /* adjacent */
    /* the refused ones changed nothing */
    receive(fx, 0x150, 0, 0);
    receive(fx, 0x050, 0, 0);
    (void)co_line_process(&fx->line, 0);
    assert_int_equal(fx->seen_count, 1);
    assert_int_equal(fx->seen_by[0], 1);
    assert_int_equal(fx->line.stats.rx_unhandled, 1);
}

static void test_invalid_range_refused(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC, false, SMALL, SMALL);
    handler_t a = {fx, 1};
    assert_false(co_line_subscribe(&fx->line, 0x200, 0x100, on_rx, &a));  /* first > last */
    assert_false(co_line_subscribe(&fx->line, 0x700, 0x800, on_rx, &a));  /* beyond 11 bits */
    assert_false(co_line_subscribe(&fx->line, 0x800, 0x800, on_rx, &a));
    assert_true(co_line_subscribe(&fx->line, 0x7FF, 0x7FF, on_rx, &a));
}

static void test_receiver_table_full_refused(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC, false, SMALL, SMALL);
    handler_t a = {fx, 1};
    uint32_t i;
    for (i = 0; i < CO_LINE_MAX_RECEIVERS; i++)
        assert_true(co_line_subscribe(&fx->line, i * 8, i * 8 + 7, on_rx, &a));
    assert_false(co_line_subscribe(&fx->line, 0x700, 0x7FF, on_rx, &a));
    receive(fx, 31 * 8 + 7, 0, 0);
    receive(fx, 0x700, 0, 0);
    (void)co_line_process(&fx->line, 0);
    assert_int_equal(fx->seen_count, 1);
    assert_int_equal(fx->line.stats.rx_unhandled, 1);
}

/* "other" receivers: offered frames no range takes; first taker wins. */
typedef struct other_handler {
    fx_t *fx;
    int tag;
    uint32_t takes_id;     /* the only id this handler uses */
} other_handler_t;

static bool on_other(co_line_t *line, const co_frame_t *frame, void *user)
{
    other_handler_t *h = user;
    if (frame->id != h->takes_id) {
        return false;
    }
    on_rx(line, frame, &(handler_t){h->fx, h->tag});
    return true;
}

static void test_other_receivers_get_unclaimed_ext_and_rtr_frames(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC, false, 16, SMALL);
    handler_t a = {fx, 1};
    other_handler_t pdo = {fx, 2, 0x181}, guard = {fx, 3, 0x705}, ext = {fx, 4, 0x1234567};
    assert_true(co_line_subscribe(&fx->line, 0x700, 0x77F, on_rx, &a));
    assert_true(co_line_subscribe_other(&fx->line, on_other, &pdo));
    assert_true(co_line_subscribe_other(&fx->line, on_other, &guard));
    assert_true(co_line_subscribe_other(&fx->line, on_other, &ext));
    assert_false(co_line_subscribe_other(&fx->line, on_other, &pdo));   /* twice */
    assert_false(co_line_subscribe_other(&fx->line, NULL, &pdo));
    receive(fx, 0x181, 0, 8);                    /* unsubscribed id: pdo */
    receive(fx, 0x705, CO_FRAME_RTR, 1);         /* RTR in a subscribed range: guard */
    receive(fx, 0x705, 0, 1);                    /* data frame: the range's receiver */
    receive(fx, 0x1234567, CO_FRAME_EXT, 2);     /* 29-bit id */
    receive(fx, 0x182, 0, 8);                    /* nobody: unhandled */
    receive(fx, 0x706, CO_FRAME_RTR, 0);         /* nobody: rx_rtr */
    (void)co_line_process(&fx->line, 0);
    assert_int_equal(fx->seen_count, 4);
    assert_int_equal(fx->seen_by[0], 2);
    assert_int_equal(fx->seen_by[1], 3);
    assert_true(fx->seen[1].flags & CO_FRAME_RTR);
    assert_int_equal(fx->seen_by[2], 1);
    assert_int_equal(fx->seen_by[3], 4);
    assert_int_equal(fx->line.stats.rx_unhandled, 1);
    assert_int_equal(fx->line.stats.rx_rtr, 1);
    /* unsubscribed: no longer offered; the table has room again */
    co_line_unsubscribe_other(&fx->line, on_other, &pdo);
    receive(fx, 0x181, 0, 8);
    (void)co_line_process(&fx->line, 0);
    assert_int_equal(fx->seen_count, 4);
    assert_int_equal(fx->line.stats.rx_unhandled, 2);
    assert_true(co_line_subscribe_other(&fx->line, on_other, &pdo));
    other_handler_t extra = {fx, 5, 0}, more = {fx, 6, 0};
    assert_true(co_line_subscribe_other(&fx->line, on_other, &extra));   /* the 4th */
    assert_false(co_line_subscribe_other(&fx->line, on_other, &more));   /* full */
}

static void test_unsubscribe_stops_dispatch_and_frees_range(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC, false, SMALL, SMALL);
    handler_t a = {fx, 1}, b = {fx, 2}, c = {fx, 3};
    assert_true(co_line_subscribe(&fx->line, 0x100, 0x10F, on_rx, &a));
    assert_true(co_line_subscribe(&fx->line, 0x200, 0x20F, on_rx, &b));
    co_line_unsubscribe(&fx->line, on_rx, &a);
    receive(fx, 0x100, 0, 0);
    receive(fx, 0x200, 0, 0);
    (void)co_line_process(&fx->line, 0);
    assert_int_equal(fx->seen_count, 1);
    assert_int_equal(fx->seen_by[0], 2);
    assert_int_equal(fx->line.stats.rx_unhandled, 1);
    /* the range can be taken again, and the remaining receiver still works */
    assert_true(co_line_subscribe(&fx->line, 0x100, 0x10F, on_rx, &c));
    receive(fx, 0x105, 0, 0);
    receive(fx, 0x20F, 0, 0);
    (void)co_line_process(&fx->line, 0);
    assert_int_equal(fx->seen_count, 3);
    assert_int_equal(fx->seen_by[1], 3);
    assert_int_equal(fx->seen_by[2], 2);
}

static void test_unsubscribe_unknown_is_harmless(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC, false, SMALL, SMALL);
    handler_t a = {fx, 1}, b = {fx, 2};
    assert_true(co_line_subscribe(&fx->line, 0x100, 0x10F, on_rx, &a));
    co_line_unsubscribe(&fx->line, on_rx, &b);
    receive(fx, 0x100, 0, 0);
    (void)co_line_process(&fx->line, 0);
    assert_int_equal(fx->seen_count, 1);
}

static void test_unhandled_counted(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD, false, SMALL, SMALL);
    receive(fx, 0x123, CO_FRAME_FD, 12);
    receive(fx, 0x124, CO_FRAME_FD, 0);
    receive(fx, 0x125, 0, 8);
    (void)co_line_process(&fx->line, 0);
    assert_int_equal(fx->line.stats.rx_unhandled, 3);
    assert_int_equal(fx->line.stats.rx_frames, 3);
    assert_int_equal(fx->line.stats.rx_invalid, 0);
}

static void test_fd_frame_on_classic_line_is_wrong_format(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC, false, SMALL, SMALL);
    handler_t a = {fx, 1};
    assert_true(co_line_subscribe(&fx->line, 0x100, 0x1FF, on_rx, &a));
    receive(fx, 0x181, CO_FRAME_FD, 8);
    receive(fx, 0x182, CO_FRAME_FD | CO_FRAME_BRS, 2);
    receive(fx, 0x183, 0, 8);
    (void)co_line_process(&fx->line, 0);
    assert_int_equal(fx->line.stats.rx_wrong_format, 2);
    assert_int_equal(fx->seen_count, 1);
    assert_int_equal(fx->seen[0].id, 0x183);
    assert_int_equal(fx->line.stats.rx_unhandled, 0);
}

static void test_classic_frame_on_fd_line_is_dispatched(void **state)
{
    /* CAN FD controllers receive classic frames too; an fd line accepts them. */
    fx_t *fx = fx_new(state, CO_MODE_FD, true, SMALL, SMALL);
    handler_t a = {fx, 1};
    assert_true(co_line_subscribe(&fx->line, 0x000, 0x000, on_rx, &a));
    receive(fx, 0x000, 0, 2);
    (void)co_line_process(&fx->line, 0);
    assert_int_equal(fx->seen_count, 1);
    assert_int_equal(fx->line.stats.rx_wrong_format, 0);
}

static void test_invalid_frames_counted_not_dispatched(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD, false, TU_QUEUE, SMALL);
    handler_t a = {fx, 1};
    co_frame_t bad[5];
    int i;
    assert_true(co_line_subscribe(&fx->line, 0x000, 0x7FF, on_rx, &a));
    bad[0] = tu_frame(0x800, 0, NULL, 0);                         /* 12-bit id, standard */
    bad[1] = tu_frame(0x100, 0, NULL, 9);                         /* classic 9 bytes */
    bad[2] = tu_frame(0x100, CO_FRAME_FD, NULL, 13);              /* no such FD length */
    bad[3] = tu_frame(0x100, CO_FRAME_FD | CO_FRAME_RTR, NULL, 0);/* RTR on FD */
    bad[4] = tu_frame(0x100, CO_FRAME_BRS, NULL, 8);              /* BRS on classic */
    for (i = 0; i < 5; i++)
        (void)co_line_receive(&fx->line, &bad[i]);
    (void)co_line_process(&fx->line, 0);
    assert_int_equal(fx->line.stats.rx_invalid, 5);
    assert_int_equal(fx->seen_count, 0);
    assert_int_equal(fx->line.stats.rx_unhandled, 0);
}

static void test_extended_frame_not_dispatched_to_11bit_receiver(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC, false, SMALL, SMALL);
    handler_t a = {fx, 1};
    co_line_stats_t *s = &fx->line.stats;
    assert_true(co_line_subscribe(&fx->line, 0x100, 0x100, on_rx, &a));
    receive(fx, 0x100, CO_FRAME_EXT, 8);
    (void)co_line_process(&fx->line, 0);
    assert_int_equal(fx->seen_count, 0);
    /* ignored, but counted somewhere */
    assert_int_equal(s->rx_unhandled + s->rx_invalid + s->rx_wrong_format, 1);
}

static void test_unanswered_rtr_counted(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC, false, SMALL, SMALL);
    receive(fx, 0x705, CO_FRAME_RTR, 1);
    (void)co_line_process(&fx->line, 0);
    assert_int_equal(fx->line.stats.rx_rtr, 1);
    assert_int_equal(fx->line.stats.rx_invalid, 0);
}

/* ------------------------------------------------------------ rx queue */

static void test_rx_overflow_counted_and_reported(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC, false, SMALL, SMALL);
    co_frame_t f = tu_frame(0x100, 0, NULL, 0);
    int i;
    for (i = 0; i < SMALL; i++)
        assert_true(co_line_receive(&fx->line, &f));
    assert_int_equal(fx->event_count, 0);
    assert_false(co_line_receive(&fx->line, &f));
    assert_int_equal(fx->line.stats.rx_overflow, 1);
    assert_int_equal(count_events(fx, CO_COMM_RX_OVERFLOW), 1);
    assert_false(co_line_receive(&fx->line, &f));
    assert_int_equal(fx->line.stats.rx_overflow, 2);
    assert_int_equal(count_events(fx, CO_COMM_RX_OVERFLOW), 2);
    /* the queued frames are intact and processed */
    (void)co_line_process(&fx->line, 0);
    assert_int_equal(fx->line.stats.rx_unhandled, SMALL);
    assert_true(co_line_receive(&fx->line, &f));
}

static void test_comm_event_from_driver_reaches_indication(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD, true, SMALL, SMALL);
    co_line_comm_event(&fx->line, CO_COMM_BUS_OFF);
    co_line_comm_event(&fx->line, CO_COMM_BUS_OFF_RECOVERED);
    assert_int_equal(fx->event_count, 2);
    assert_int_equal(fx->events[0], CO_COMM_BUS_OFF);
    assert_int_equal(fx->events[1], CO_COMM_BUS_OFF_RECOVERED);
}

static void test_no_comm_indication_is_harmless(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC, false, 1, 1);
    co_frame_t f = tu_frame(0x100, 0, NULL, 0);
    co_line_set_comm_indication(&fx->line, NULL, NULL);
    assert_true(co_line_receive(&fx->line, &f));
    assert_false(co_line_receive(&fx->line, &f));
    assert_true(co_line_send(&fx->line, 0x100, NULL, 0));
    assert_false(co_line_send(&fx->line, 0x100, NULL, 0));
    co_line_comm_event(&fx->line, CO_COMM_BUS_OFF);
    assert_int_equal(fx->line.stats.rx_overflow, 1);
    assert_int_equal(fx->line.stats.tx_overflow, 1);
    assert_int_equal(fx->event_count, 0);
}

/* ------------------------------------------------------------ tx */

static void test_tx_fd_line_adds_fd_brs_and_rounds(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD, true, SMALL, SMALL);
    uint8_t d[13];
    uint8_t expected[16];
    co_frame_t out;
    int i;
    for (i = 0; i < 13; i++)
        d[i] = (uint8_t)(i + 1);
    memset(expected, 0, sizeof expected);
    memcpy(expected, d, 13);
    assert_true(co_line_send(&fx->line, 0x581, d, 13));
    assert_true(co_line_tx_pop(&fx->line, &out));
    tu_assert_frame(&out, 0x581, CO_FRAME_FD | CO_FRAME_BRS, expected, 16);
    assert_int_equal(fx->line.stats.tx_frames, 1);
    assert_false(co_line_tx_pop(&fx->line, &out));
    assert_int_equal(fx->line.stats.tx_frames, 1);
}

static void test_tx_fd_line_without_brs_adds_fd_only(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD, false, SMALL, SMALL);
    const uint8_t d[2] = {0x01, 0x05};
    co_frame_t out;
    assert_true(co_line_send(&fx->line, 0x000, d, 2));
    assert_true(co_line_tx_pop(&fx->line, &out));
    tu_assert_frame(&out, 0x000, CO_FRAME_FD, d, 2);
}

static void test_tx_fd_line_rounds_every_length(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD, true, SMALL, SMALL);
    uint8_t d[64];
    size_t n, i;
    memset(d, 0xA5, sizeof d);
    for (n = 0; n <= 64; n++) {
        co_frame_t out;
        assert_true(co_line_send(&fx->line, 0x200, d, n));
        assert_true(co_line_tx_pop(&fx->line, &out));
        assert_int_equal(out.len, co_fd_len_round(n));
        assert_true(co_frame_is_valid(&out));
        for (i = n; i < out.len; i++)
            assert_int_equal(out.data[i], 0);
    }
    assert_false(co_line_send(&fx->line, 0x200, d, 65));
    assert_int_equal(co_line_tx_count(&fx->line), 0);
}

static void test_tx_classic_line_no_flags_no_rounding(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC, true /* ignored on classic */, SMALL, SMALL);
    const uint8_t d[5] = {9, 8, 7, 6, 5};
    co_frame_t out;
    assert_true(co_line_send(&fx->line, 0x181, d, 5));
    assert_true(co_line_tx_pop(&fx->line, &out));
    tu_assert_frame(&out, 0x181, 0, d, 5);
}

static void test_tx_classic_line_refuses_more_than_8_bytes(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC, false, SMALL, SMALL);
    uint8_t d[9] = {0};
    assert_false(co_line_send(&fx->line, 0x181, d, 9));
    assert_int_equal(co_line_tx_count(&fx->line), 0);
    assert_int_equal(fx->line.stats.tx_overflow, 0);   /* not an overflow */
    assert_int_equal(count_events(fx, CO_COMM_TX_OVERFLOW), 0);
}

static void test_tx_refuses_id_beyond_11_bits(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD, true, SMALL, SMALL);
    assert_false(co_line_send(&fx->line, 0x800, NULL, 0));
    assert_int_equal(co_line_tx_count(&fx->line), 0);
}

/* co_line_send's own checks (it does not go through co_line_send_raw): the id
 * and the length for the line's mode, each refusal counted in tx_invalid and
 * nothing queued; the limits themselves accepted. */
static void test_tx_send_checks_id_and_length_per_mode(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC, false, SMALL, SMALL);
    uint8_t d[65] = {0};
    co_frame_t out;
    assert_false(co_line_send(&fx->line, 0x800, d, 1));
    assert_false(co_line_send(&fx->line, 0xFFFFFFFFu, d, 1));
    assert_false(co_line_send(&fx->line, 0x7FF, d, 9));
    assert_int_equal(fx->line.stats.tx_invalid, 3);
    assert_int_equal(co_line_tx_count(&fx->line), 0);
    assert_true(co_line_send(&fx->line, 0x7FF, d, 8));
    assert_true(co_line_tx_pop(&fx->line, &out));
    assert_int_equal(out.len, 8);
    assert_int_equal(out.flags, 0);

    fx = fx_new(state, CO_MODE_FD, false, SMALL, SMALL);
    assert_false(co_line_send(&fx->line, 0x800, d, 64));
    assert_false(co_line_send(&fx->line, 0x7FF, d, 65));
    assert_int_equal(fx->line.stats.tx_invalid, 2);
    assert_int_equal(co_line_tx_count(&fx->line), 0);
    assert_true(co_line_send(&fx->line, 0x7FF, d, 9));
    assert_true(co_line_tx_pop(&fx->line, &out));
    assert_int_equal(out.len, 12);
    assert_int_equal(out.flags, CO_FRAME_FD);
    assert_int_equal(count_events(fx, CO_COMM_TX_OVERFLOW), 0);
}

static void test_tx_send_frame_on_fd_line_adds_flags_keeps_ext(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD, true, SMALL, SMALL);
    const uint8_t d[3] = {1, 2, 3};
    const uint8_t expected[3] = {1, 2, 3};
    co_frame_t f = tu_frame(0x1234567, CO_FRAME_EXT, d, 3), out;
    assert_true(co_line_send_frame(&fx->line, &f));
    assert_true(co_line_tx_pop(&fx->line, &out));
    tu_assert_frame(&out, 0x1234567, CO_FRAME_EXT | CO_FRAME_FD | CO_FRAME_BRS, expected, 3);
}

static void test_tx_send_frame_on_fd_line_rounds_and_pads(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD, false, SMALL, SMALL);
    uint8_t d[64];
    co_frame_t f, out;
    int i;
    memset(d, 0x11, sizeof d);
    f = tu_frame(0x300, 0, d, 20);
    f.len = 17;
    memset(f.data + 17, 0xEE, 47);   /* garbage behind the payload */
    assert_true(co_line_send_frame(&fx->line, &f));
    assert_true(co_line_tx_pop(&fx->line, &out));
    assert_int_equal(out.len, 20);
    assert_int_equal(out.flags, CO_FRAME_FD);
    assert_memory_equal(out.data, d, 17);
    for (i = 17; i < 20; i++)
        assert_int_equal(out.data[i], 0);
}

static void test_tx_send_frame_on_classic_line_keeps_rtr(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC, false, SMALL, SMALL);
    co_frame_t f = tu_frame(0x705, CO_FRAME_RTR, NULL, 1), out;
    assert_true(co_line_send_frame(&fx->line, &f));
    assert_true(co_line_tx_pop(&fx->line, &out));
    assert_int_equal(out.id, 0x705);
    assert_int_equal(out.flags, CO_FRAME_RTR);
    assert_int_equal(out.len, 1);
}

static void test_tx_send_frame_invalid_refused(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC, false, SMALL, SMALL);
    co_frame_t f = tu_frame(0x100, 0, NULL, 0);
    f.len = 9;
    assert_false(co_line_send_frame(&fx->line, &f));
    f = tu_frame(0x100, CO_FRAME_FD, NULL, 8);        /* FD frame on a classic line */
    assert_false(co_line_send_frame(&fx->line, &f));
    assert_int_equal(co_line_tx_count(&fx->line), 0);
    assert_int_equal(fx->line.stats.tx_overflow, 0);
}

static void test_tx_keeps_fifo_order(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC, false, SMALL, SMALL);
    co_frame_t out;
    uint8_t i;
    for (i = 0; i < SMALL; i++)
        assert_true(co_line_send(&fx->line, 0x100u + i, &i, 1));
    for (i = 0; i < SMALL; i++) {
        assert_true(co_line_tx_pop(&fx->line, &out));
        assert_int_equal(out.id, 0x100u + i);
        assert_int_equal(out.data[0], i);
    }
    assert_int_equal(fx->line.stats.tx_frames, SMALL);
}

static void test_tx_overflow_counted_refused_and_reported(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD, true, SMALL, SMALL);
    const uint8_t d[1] = {0x42};
    co_frame_t out;
    int i;
    for (i = 0; i < SMALL; i++)
        assert_true(co_line_send(&fx->line, 0x100u + (unsigned)i, d, 1));
    assert_int_equal(count_events(fx, CO_COMM_TX_OVERFLOW), 0);
    assert_false(co_line_send(&fx->line, 0x1FF, d, 1));
    assert_int_equal(fx->line.stats.tx_overflow, 1);
    assert_int_equal(count_events(fx, CO_COMM_TX_OVERFLOW), 1);
    assert_false(co_line_send(&fx->line, 0x1FF, d, 1));
    assert_int_equal(fx->line.stats.tx_overflow, 2);
    assert_int_equal(count_events(fx, CO_COMM_TX_OVERFLOW), 2);   /* one per lost frame */
    /* nothing overwritten */
    for (i = 0; i < SMALL; i++) {
        assert_true(co_line_tx_pop(&fx->line, &out));
        assert_int_equal(out.id, 0x100u + (unsigned)i);
    }
    assert_false(co_line_tx_pop(&fx->line, &out));
}

static void test_tx_queue_full_reported_once_when_it_fills(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC, false, SMALL, SMALL);
    int i;
    for (i = 0; i < SMALL - 1; i++)
        assert_true(co_line_send(&fx->line, 0x100, NULL, 0));
    assert_int_equal(count_events(fx, CO_COMM_TX_QUEUE_FULL), 0);
    assert_true(co_line_send(&fx->line, 0x100, NULL, 0));          /* now full */
    assert_false(co_line_send(&fx->line, 0x100, NULL, 0));
    assert_false(co_line_send(&fx->line, 0x100, NULL, 0));
    assert_int_equal(count_events(fx, CO_COMM_TX_QUEUE_FULL), 1);
    assert_int_equal(count_events(fx, CO_COMM_TX_QUEUE_EMPTY), 0);
}

static void test_tx_queue_empty_reported_once_after_full(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC, false, SMALL, SMALL);
    co_frame_t out;
    int i;
    for (i = 0; i < SMALL; i++)
        assert_true(co_line_send(&fx->line, 0x100, NULL, 0));
    for (i = 0; i < SMALL - 1; i++)
        assert_true(co_line_tx_pop(&fx->line, &out));
    assert_int_equal(count_events(fx, CO_COMM_TX_QUEUE_EMPTY), 0);
    assert_true(co_line_tx_pop(&fx->line, &out));                  /* now empty */
    assert_false(co_line_tx_pop(&fx->line, &out));
    assert_int_equal(count_events(fx, CO_COMM_TX_QUEUE_EMPTY), 1);
    /* the next ordinary send/pop cycle reports nothing */
    assert_true(co_line_send(&fx->line, 0x100, NULL, 0));
    assert_true(co_line_tx_pop(&fx->line, &out));
    assert_int_equal(count_events(fx, CO_COMM_TX_QUEUE_EMPTY), 1);
    assert_int_equal(count_events(fx, CO_COMM_TX_QUEUE_FULL), 1);
    /* a second fill/drain cycle reports again, once each */
    for (i = 0; i < SMALL; i++)
        assert_true(co_line_send(&fx->line, 0x100, NULL, 0));
    while (co_line_tx_pop(&fx->line, &out))
        ;
    assert_int_equal(count_events(fx, CO_COMM_TX_QUEUE_FULL), 2);
    assert_int_equal(count_events(fx, CO_COMM_TX_QUEUE_EMPTY), 2);
}

static void test_tx_no_queue_events_without_filling(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC, false, SMALL, SMALL);
    co_frame_t out;
    int i;
    for (i = 0; i < 100; i++) {
        assert_true(co_line_send(&fx->line, 0x100, NULL, 0));
        assert_true(co_line_send(&fx->line, 0x100, NULL, 0));
        assert_true(co_line_tx_pop(&fx->line, &out));
        assert_true(co_line_tx_pop(&fx->line, &out));
    }
    assert_int_equal(fx->event_count, 0);
}

/* ------------------------------------------------------------ tx space */

typedef struct space {
    fx_t *fx;
    int calls;
    uint32_t count_seen[8];   /* tx queue count at each call */
    int send_more;            /* push a frame from inside the next calls */
} space_t;

static void on_space(co_line_t *line, void *user)
{
    space_t *sp = user;
    assert_ptr_equal(line, &sp->fx->line);
    if (sp->calls < 8)
        sp->count_seen[sp->calls] = co_line_tx_count(line);
    sp->calls++;
    if (sp->send_more > 0) {
        sp->send_more--;
        assert_true(co_line_send(line, 0x222, NULL, 0));
    }
}

static void on_space_other(co_line_t *line, void *user)
{
    on_space(line, user);
}

static void fill_tx(fx_t *fx, uint32_t n)
{
    uint32_t i;
    for (i = 0; i < n; i++)
        assert_true(co_line_send(&fx->line, 0x100, NULL, 0));
}

static void pop_tx(fx_t *fx, uint32_t n)
{
    co_frame_t out;
    uint32_t i;
    for (i = 0; i < n; i++)
        assert_true(co_line_tx_pop(&fx->line, &out));
}

static void test_tx_space_register_bounded(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD, true, SMALL, 8);
    space_t sp[CO_LINE_MAX_TX_SPACE + 1];
    int i;
    memset(sp, 0, sizeof sp);
    assert_false(co_line_tx_space_register(&fx->line, NULL, &sp[0]));
    for (i = 0; i < CO_LINE_MAX_TX_SPACE; i++)
        assert_true(co_line_tx_space_register(&fx->line, on_space, &sp[i]));
    assert_false(co_line_tx_space_register(&fx->line, on_space, &sp[CO_LINE_MAX_TX_SPACE]));
    /* the same (fn, user) twice: refused (it would be called twice) */
    co_line_tx_space_unregister(&fx->line, on_space, &sp[1]);
    assert_false(co_line_tx_space_register(&fx->line, on_space, &sp[0]));
    assert_true(co_line_tx_space_register(&fx->line, on_space_other, &sp[0]));
    /* unregistering what is not there: harmless */
    co_line_tx_space_unregister(&fx->line, on_space, &sp[CO_LINE_MAX_TX_SPACE]);
    assert_int_equal(fx->line.tx_space_count, CO_LINE_MAX_TX_SPACE);
}

static void test_tx_space_called_when_queue_drains_to_half(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD, true, SMALL, 8);
    space_t a, b;
    memset(&a, 0, sizeof a);
    memset(&b, 0, sizeof b);
    a.fx = b.fx = fx;
    assert_true(co_line_tx_space_register(&fx->line, on_space, &a));
    assert_true(co_line_tx_space_register(&fx->line, on_space, &b));
    fill_tx(fx, 8);
    pop_tx(fx, 3);                 /* 8 -> 5: above half */
    assert_int_equal(a.calls, 0);
    pop_tx(fx, 1);                 /* 5 -> 4: half */
    assert_int_equal(a.calls, 1);
    assert_int_equal(b.calls, 1);
    assert_int_equal(a.count_seen[0], 4);
    pop_tx(fx, 4);                 /* further down: no more calls */
    assert_int_equal(a.calls, 1);
    /* below half and back up to it by sending: no call (only pops count) */
    fill_tx(fx, 4);
    assert_int_equal(a.calls, 1);
    /* each crossing from above half is reported once */
    fill_tx(fx, 1);
    pop_tx(fx, 1);
    assert_int_equal(a.calls, 2);
    fill_tx(fx, 1);
    pop_tx(fx, 1);
    assert_int_equal(a.calls, 3);
    /* unregistered: not called any more */
    co_line_tx_space_unregister(&fx->line, on_space, &a);
    fill_tx(fx, 1);
    pop_tx(fx, 1);
    assert_int_equal(a.calls, 3);
    assert_int_equal(b.calls, 4);
}

/* Small and odd capacities: a queue filled above half always reports on its
 * way down (capacity 1: at empty). */
static void test_tx_space_small_and_odd_capacities(void **state)
{
    static const uint32_t caps[] = { 1, 2, 3, 5, 7 };
    size_t k;
    for (k = 0; k < sizeof caps / sizeof caps[0]; k++) {
        fx_t *fx = fx_new(state, CO_MODE_FD, true, SMALL, caps[k]);
        space_t sp;
        memset(&sp, 0, sizeof sp);
        sp.fx = fx;
        assert_true(co_line_tx_space_register(&fx->line, on_space, &sp));
        fill_tx(fx, caps[k]);
        pop_tx(fx, caps[k]);
        assert_int_equal(sp.calls, 1);
        assert_int_equal(sp.count_seen[0], caps[k] / 2);
    }
}

/* The callback may queue a frame from inside co_line_tx_pop (a callback
 * that refilled at every call would keep a draining loop going: services
 * only note the call and send from co_line_process). */
static void test_tx_space_callback_may_send(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD, true, SMALL, 8);
    space_t sp;
    co_frame_t out;
    int popped = 0;
    memset(&sp, 0, sizeof sp);
    sp.fx = fx;
    sp.send_more = 1;
    assert_true(co_line_tx_space_register(&fx->line, on_space, &sp));
    fill_tx(fx, 6);
    while (co_line_tx_pop(&fx->line, &out))
        popped++;
    assert_int_equal(sp.calls, 2);   /* the pushed frame made it cross once more */
    assert_int_equal(popped, 7);
    assert_int_equal(out.id, 0x222);
}

/* Nobody registered: pops report nothing and cost one test. */
static void test_tx_space_nobody_registered(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD, true, SMALL, 8);
    fill_tx(fx, 8);
    pop_tx(fx, 8);
    assert_int_equal(fx->line.tx_space_count, 0);
    assert_int_equal(fx->line.stats.tx_frames, 8);
}

/* ------------------------------------------------------------ accessors */

static void test_id_owner_accessors(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC, false, SMALL, SMALL);
    handler_t a = {fx, 1}, b = {fx, 2};
    assert_false(co_line_id_taken(&fx->line, 0x150));
    assert_true(co_line_subscribe(&fx->line, 0x100, 0x1FF, on_rx, &a));
    assert_true(co_line_id_taken(&fx->line, 0x100));
    assert_true(co_line_id_taken(&fx->line, 0x1FF));
    assert_false(co_line_id_taken(&fx->line, 0x200));
    assert_true(co_line_id_taken_by(&fx->line, 0x150, on_rx, &a));
    assert_false(co_line_id_taken_by(&fx->line, 0x150, on_rx, &b));
    assert_false(co_line_id_taken_by(&fx->line, 0x200, on_rx, &a));
    co_line_unsubscribe(&fx->line, on_rx, &a);
    assert_false(co_line_id_taken(&fx->line, 0x150));
    assert_false(co_line_id_taken_by(&fx->line, 0x150, on_rx, &a));
}

static void test_receiver_free_until_table_full(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC, false, SMALL, SMALL);
    handler_t a = {fx, 1};
    uint32_t i;
    for (i = 0; i < CO_LINE_MAX_RECEIVERS; i++) {
        assert_true(co_line_receiver_free(&fx->line));
        assert_true(co_line_subscribe(&fx->line, i, i, on_rx, &a));
    }
    assert_false(co_line_receiver_free(&fx->line));
}

/* The room for bursts keeps the last quarter of the tx queue free. */
static void test_tx_room_keeps_a_quarter(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC, false, SMALL, 8);
    const uint8_t d[1] = {1};
    uint32_t sent;
    co_frame_t out;
    assert_int_equal(co_line_tx_room(&fx->line), 6);
    for (sent = 1; sent <= 8; sent++) {
        assert_true(co_line_send(&fx->line, 0x100, d, 1));
        assert_int_equal(co_line_tx_count(&fx->line), sent);
        assert_int_equal(co_line_tx_room(&fx->line), sent < 6 ? 6 - sent : 0);
    }
    for (sent = 0; sent < 3; sent++)
        assert_true(co_line_tx_pop(&fx->line, &out));
    assert_int_equal(co_line_tx_room(&fx->line), 1);
}

static void test_queue_accessors_show_frames_in_order(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC, false, SMALL, SMALL);
    handler_t a = {fx, 1};
    const uint8_t d[1] = {1};
    co_frame_t out;
    assert_true(co_line_subscribe(&fx->line, 0x000, 0x7FF, on_rx, &a));
    receive(fx, 0x101, 0, 1);
    receive(fx, 0x102, 0, 1);
    receive(fx, 0x103, 0, 1);
    assert_int_equal(co_line_rx_count(&fx->line), 3);
    assert_int_equal(co_line_rx_free(&fx->line), SMALL - 3);
    assert_int_equal(co_line_rx_at(&fx->line, 0)->id, 0x101);
    assert_int_equal(co_line_rx_at(&fx->line, 2)->id, 0x103);
    /* a capture line takes frames raw: nothing is dispatched */
    assert_true(co_line_rx_pop(&fx->line, &out));
    assert_int_equal(out.id, 0x101);
    assert_int_equal(co_line_rx_at(&fx->line, 0)->id, 0x102);
    (void)co_line_process(&fx->line, 0);
    assert_int_equal(fx->seen_count, 2);
    assert_false(co_line_rx_pop(&fx->line, &out));
    assert_true(co_line_send(&fx->line, 0x201, d, 1));
    assert_true(co_line_send(&fx->line, 0x202, d, 1));
    assert_int_equal(co_line_tx_at(&fx->line, 1)->id, 0x202);
    assert_true(co_line_tx_pop(&fx->line, &out));
    assert_int_equal(co_line_tx_at(&fx->line, 0)->id, 0x202);
    assert_int_equal(co_line_stats(&fx->line)->rx_frames, 3);
    assert_int_equal(co_line_stats(&fx->line)->tx_frames, 1);
    assert_int_equal(co_line_mode(&fx->line), CO_MODE_CLASSIC);
}

/* A driver that sent a frame from co_line_tx_at takes it with out = NULL: the
 * same as a pop into a frame (order, statistics, queue-empty event). */
static void test_tx_pop_without_out_takes_the_frame(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD, true, SMALL, SMALL);
    const uint8_t d[1] = {1};
    uint32_t i;
    for (i = 0; i < SMALL; i++)
        assert_true(co_line_send(&fx->line, 0x300 + i, d, 1));
    assert_int_equal(count_events(fx, CO_COMM_TX_QUEUE_FULL), 1);
    for (i = 0; i < SMALL; i++) {
        assert_int_equal(co_line_tx_at(&fx->line, 0)->id, 0x300 + i);
        assert_true(co_line_tx_pop(&fx->line, NULL));
        assert_int_equal(co_line_tx_count(&fx->line), SMALL - 1 - i);
        assert_int_equal(count_events(fx, CO_COMM_TX_QUEUE_EMPTY), i == SMALL - 1);
    }
    assert_false(co_line_tx_pop(&fx->line, NULL));
    assert_int_equal(co_line_stats(&fx->line)->tx_frames, SMALL);
}

/* Handlers get their frame in place (no copy): frames a handler feeds back
 * into the same line while the queue fills never overwrite it, and wait for
 * the next process call. */
typedef struct feeder {
    fx_t *fx;
    int calls;
    int fed;
    bool intact;
} feeder_t;

static void on_rx_feed(co_line_t *line, const co_frame_t *frame, void *user)
{
    feeder_t *f = user;
    co_frame_t before = *frame;
    const uint8_t d[8] = {9, 9, 9, 9, 9, 9, 9, 9};
    co_frame_t fed = tu_frame(0x1FF, 0, d, 8);
    f->calls++;
    if (frame->id != 0x1FF) {
        while (co_line_receive(line, &fed))
            f->fed++;
        f->intact = f->intact && memcmp(&before, frame, sizeof before) == 0;
    }
}

static void test_handler_feeding_its_line_cannot_overwrite_its_frame(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC, false, SMALL, SMALL);
    feeder_t f = {fx, 0, 0, true};
    assert_true(co_line_subscribe(&fx->line, 0x100, 0x1FF, on_rx_feed, &f));
    receive(fx, 0x101, 0, 8);
    receive(fx, 0x102, 0, 8);
    (void)co_line_process(&fx->line, 0);
    assert_true(f.intact);
    assert_int_equal(f.calls, 2);                   /* the fed frames wait */
    /* first handler: the 2 free slots; second: the slot the first freed */
    assert_int_equal(f.fed, 3);
    assert_int_equal(co_line_rx_count(&fx->line), 3);
    assert_int_equal(co_line_stats(&fx->line)->rx_overflow, 2);
    (void)co_line_process(&fx->line, 1);
    assert_int_equal(f.calls, 2 + 3);
    assert_int_equal(co_line_rx_count(&fx->line), 0);
}

static void test_node_id_and_rejected_counters(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD, true, SMALL, SMALL);
    const co_line_stats_t *s = co_line_stats(&fx->line);
    co_line_set_node_id(&fx->line, 5);
    assert_int_equal(co_line_node_id(&fx->line), 5);
    co_line_count_rejected(&fx->line, CO_LINE_NMT_BAD_LENGTH);
    co_line_count_rejected(&fx->line, CO_LINE_NMT_BAD_COMMAND);
    co_line_count_rejected(&fx->line, CO_LINE_NMT_BAD_COMMAND);
    co_line_count_rejected(&fx->line, CO_LINE_NMT_BAD_NODE);
    co_line_count_rejected(&fx->line, CO_LINE_HB_BAD_LENGTH);
    co_line_count_rejected(&fx->line, CO_LINE_HB_BAD_STATE);
    co_line_count_rejected(&fx->line, CO_LINE_HB_BAD_NODE);
    co_line_count_rejected(&fx->line, CO_LINE_HB_BAD_NODE);
    assert_int_equal(s->nmt_bad_length, 1);
    assert_int_equal(s->nmt_bad_command, 2);
    assert_int_equal(s->nmt_bad_node, 1);
    assert_int_equal(s->hb_bad_length, 1);
    assert_int_equal(s->hb_bad_state, 1);
    assert_int_equal(s->hb_bad_node, 2);
    assert_int_equal(s->rx_unhandled + s->rx_invalid, 0);
}

/* ------------------------------------------------------------ process */

typedef struct tick {
    int fired;
    uint64_t at;
    uint64_t line_now;
    co_line_t *line;
} tick_t;

static void tick_fn(co_timer_t *timer, uint64_t now_us, void *user)
{
    tick_t *t = user;
    (void)timer;
    t->fired++;
    t->at = now_us;
    t->line_now = co_line_now(t->line);
}

static void test_process_returns_never_without_timers(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD, true, SMALL, SMALL);
    assert_true(co_line_process(&fx->line, 0) == CO_TIME_NEVER);
    assert_true(co_line_process(&fx->line, 123456) == CO_TIME_NEVER);
    assert_int_equal(co_line_now(&fx->line), 123456);
}

static void test_process_runs_due_timers_and_returns_next_deadline(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD, true, SMALL, SMALL);
    co_timer_t t1, t2;
    tick_t k1 = {0, 0, 0, NULL}, k2 = {0, 0, 0, NULL};
    k1.line = k2.line = &fx->line;
    co_timer_init(&t1, tick_fn, &k1);
    co_timer_init(&t2, tick_fn, &k2);
    co_timer_start(co_line_timers(&fx->line), &t1, 5000);
    co_timer_start(co_line_timers(&fx->line), &t2, 9000);
    assert_int_equal(co_line_process(&fx->line, 1000), 5000);
    assert_int_equal(k1.fired, 0);
    assert_int_equal(co_line_process(&fx->line, 5000), 9000);
    assert_int_equal(k1.fired, 1);
    assert_int_equal(k1.at, 5000);
    assert_int_equal(k1.line_now, 5000);
    assert_true(co_line_process(&fx->line, 10000) == CO_TIME_NEVER);
    assert_int_equal(k2.fired, 1);
    assert_int_equal(k2.at, 10000);
}

static void rearm_fn(co_timer_t *timer, uint64_t now_us, void *user)
{
    co_line_t *line = user;
    co_timer_start(co_line_timers(line), timer, now_us + 250);
}

static void test_process_returns_deadline_set_by_timer_callback(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_CLASSIC, false, SMALL, SMALL);
    co_timer_t t;
    co_timer_init(&t, rearm_fn, &fx->line);
    co_timer_start(co_line_timers(&fx->line), &t, 100);
    assert_int_equal(co_line_process(&fx->line, 100), 350);
    assert_int_equal(co_line_process(&fx->line, 350), 600);
}

/* A receive handler that answers: the answer is queued for transmission. */
static void echo_rx(co_line_t *line, const co_frame_t *frame, void *user)
{
    (void)user;
    assert_true(co_line_send(line, frame->id + 1, frame->data, frame->len));
}

static void test_handler_may_send_during_process(void **state)
{
    fx_t *fx = fx_new(state, CO_MODE_FD, true, SMALL, SMALL);
    const uint8_t d[3] = {1, 2, 3};
    co_frame_t f = tu_frame(0x600, CO_FRAME_FD | CO_FRAME_BRS, d, 3), out;
    assert_true(co_line_subscribe(&fx->line, 0x600, 0x600, echo_rx, NULL));
    assert_true(co_line_receive(&fx->line, &f));
    (void)co_line_process(&fx->line, 0);
    assert_true(co_line_tx_pop(&fx->line, &out));
    tu_assert_frame(&out, 0x601, CO_FRAME_FD | CO_FRAME_BRS, d, 3);
}

/* ------------------------------------------------------------ membus */

typedef struct bus_fx {
    tu_bus_t tb;
    tu_line_t a, b;
} bus_fx_t;

static int setup_bus(void **state)
{
    *state = calloc(1, sizeof(bus_fx_t));
    return *state == NULL ? -1 : 0;
}

static void test_membus_delivers_to_all_others_not_sender(void **state)
{
    bus_fx_t *bx = *state;
    const uint8_t d[1] = {0x7F};
    co_frame_t out;
    tu_bus_init(&bx->tb, CO_MODE_FD, true);
    (void)tu_bus_add_line(&bx->tb, &bx->a);
    (void)tu_bus_add_line(&bx->tb, &bx->b);
    assert_true(co_line_send(&bx->a.line, 0x705, d, 1));
    assert_int_equal(co_membus_transfer(&bx->tb.bus, NULL, NULL), 1);
    assert_int_equal(bx->tb.bus.frames, 1);
    assert_int_equal(co_line_rx_count(&bx->a.line), 0);
    assert_true(co_line_rx_pop(&bx->b.line, &out));
    tu_assert_frame(&out, 0x705, CO_FRAME_FD | CO_FRAME_BRS, d, 1);
    assert_true(co_line_rx_pop(&bx->tb.sniffer.line, &out));
    tu_assert_frame(&out, 0x705, CO_FRAME_FD | CO_FRAME_BRS, d, 1);
    assert_int_equal(bx->a.line.stats.tx_frames, 1);
}

static uint8_t fault_by_id(const co_frame_t *frame, void *user)
{
    (void)user;
    if (frame->id == 0x101)
        return 0;             /* lost */
    if (frame->id == 0x102)
        return 2;             /* duplicated */
    return 1;
}

typedef struct sent_log {
    co_line_t *from[8];
    uint32_t id[8];
    int count;
} sent_log_t;

static void on_sent(co_line_t *from, const co_frame_t *frame, void *user)
{
    sent_log_t *log = user;
    assert_true(log->count < 8);
    log->from[log->count] = from;
    log->id[log->count] = frame->id;
    log->count++;
}

static void test_membus_fault_hook_drops_and_duplicates(void **state)
{
    bus_fx_t *bx = *state;
    co_frame_t out;
    tu_bus_init(&bx->tb, CO_MODE_CLASSIC, false);
    (void)tu_bus_add_line(&bx->tb, &bx->a);
    (void)tu_bus_add_line(&bx->tb, &bx->b);
    co_membus_set_fault(&bx->tb.bus, fault_by_id, NULL);
    assert_true(co_line_send(&bx->a.line, 0x100, NULL, 0));
    assert_true(co_line_send(&bx->a.line, 0x101, NULL, 0));
    assert_true(co_line_send(&bx->a.line, 0x102, NULL, 0));
    (void)co_membus_transfer(&bx->tb.bus, NULL, NULL);
    assert_int_equal(co_line_rx_count(&bx->b.line), 3);
    assert_true(co_line_rx_pop(&bx->b.line, &out));
    assert_int_equal(out.id, 0x100);
    assert_true(co_line_rx_pop(&bx->b.line, &out));
    assert_int_equal(out.id, 0x102);
    assert_true(co_line_rx_pop(&bx->b.line, &out));
    assert_int_equal(out.id, 0x102);
}

static void test_membus_sent_callback_sees_every_frame_in_attach_order(void **state)
{
    bus_fx_t *bx = *state;
    sent_log_t log;
    memset(&log, 0, sizeof log);
    tu_bus_init(&bx->tb, CO_MODE_FD, false);
    (void)tu_bus_add_line(&bx->tb, &bx->a);
    (void)tu_bus_add_line(&bx->tb, &bx->b);
    assert_true(co_line_send(&bx->b.line, 0x200, NULL, 0));
    assert_true(co_line_send(&bx->a.line, 0x100, NULL, 0));
    assert_true(co_line_send(&bx->a.line, 0x101, NULL, 0));
    assert_int_equal(co_membus_transfer(&bx->tb.bus, on_sent, &log), 3);
    assert_int_equal(log.count, 3);
    assert_ptr_equal(log.from[0], &bx->a.line);
    assert_int_equal(log.id[0], 0x100);
    assert_int_equal(log.id[1], 0x101);
    assert_ptr_equal(log.from[2], &bx->b.line);
    assert_int_equal(log.id[2], 0x200);
}

static void test_membus_full_receiver_counts_rx_overflow(void **state)
{
    bus_fx_t *bx = *state;
    int i;
    tu_bus_init(&bx->tb, CO_MODE_CLASSIC, false);
    (void)tu_bus_add_line(&bx->tb, &bx->a);
    (void)tu_bus_add_line(&bx->tb, &bx->b);
    for (i = 0; i < TU_QUEUE; i++)
        assert_true(co_line_send(&bx->a.line, 0x100, NULL, 0));
    (void)co_membus_transfer(&bx->tb.bus, NULL, NULL);
    for (i = 0; i < 3; i++)
        assert_true(co_line_send(&bx->a.line, 0x100, NULL, 0));
    assert_int_equal(co_membus_transfer(&bx->tb.bus, NULL, NULL), 3);
    assert_int_equal(bx->b.line.stats.rx_overflow, 3);
    assert_int_equal(co_line_rx_count(&bx->b.line), TU_QUEUE);
}

static void test_membus_attach_twice_refused(void **state)
{
    bus_fx_t *bx = *state;
    tu_bus_init(&bx->tb, CO_MODE_CLASSIC, false);
    (void)tu_bus_add_line(&bx->tb, &bx->a);
    assert_false(co_membus_attach(&bx->tb.bus, &bx->a.line));
}

static void test_membus_detached_line_receives_nothing(void **state)
{
    bus_fx_t *bx = *state;
    tu_bus_init(&bx->tb, CO_MODE_CLASSIC, false);
    (void)tu_bus_add_line(&bx->tb, &bx->a);
    (void)tu_bus_add_line(&bx->tb, &bx->b);
    co_membus_detach(&bx->tb.bus, &bx->b.line);
    assert_true(co_line_send(&bx->a.line, 0x100, NULL, 0));
    assert_int_equal(co_membus_transfer(&bx->tb.bus, NULL, NULL), 1);
    assert_int_equal(co_line_rx_count(&bx->b.line), 0);
    assert_int_equal(co_line_rx_count(&bx->tb.sniffer.line), 1);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_init_refuses_missing_queue_storage),
        cmocka_unit_test(test_init_refuses_unknown_mode),
        cmocka_unit_test_setup_teardown(test_init_starts_clean, setup, teardown),
        cmocka_unit_test_setup_teardown(test_dispatch_by_id_range, setup, teardown),
        cmocka_unit_test_setup_teardown(test_dispatch_passes_frame_unchanged, setup, teardown),
        cmocka_unit_test_setup_teardown(test_dispatch_keeps_receive_order, setup, teardown),
        cmocka_unit_test_setup_teardown(test_nothing_dispatched_before_process, setup, teardown),
        cmocka_unit_test_setup_teardown(test_whole_id_space_subscribable, setup, teardown),
        cmocka_unit_test_setup_teardown(test_id_owner_accessors, setup, teardown),
        cmocka_unit_test_setup_teardown(test_receiver_free_until_table_full, setup, teardown),
        cmocka_unit_test_setup_teardown(test_tx_room_keeps_a_quarter, setup, teardown),
        cmocka_unit_test_setup_teardown(test_queue_accessors_show_frames_in_order, setup, teardown),
        cmocka_unit_test_setup_teardown(test_tx_pop_without_out_takes_the_frame, setup, teardown),
        cmocka_unit_test_setup_teardown(test_tx_send_checks_id_and_length_per_mode, setup, teardown),
        cmocka_unit_test_setup_teardown(test_handler_feeding_its_line_cannot_overwrite_its_frame,
                                        setup, teardown),
        cmocka_unit_test_setup_teardown(test_node_id_and_rejected_counters, setup, teardown),
        cmocka_unit_test_setup_teardown(test_overlapping_subscribe_refused, setup, teardown),
        cmocka_unit_test_setup_teardown(test_invalid_range_refused, setup, teardown),
        cmocka_unit_test_setup_teardown(test_receiver_table_full_refused, setup, teardown),
        cmocka_unit_test_setup_teardown(test_other_receivers_get_unclaimed_ext_and_rtr_frames, setup, teardown),
        cmocka_unit_test_setup_teardown(test_unsubscribe_stops_dispatch_and_frees_range, setup, teardown),
        cmocka_unit_test_setup_teardown(test_unsubscribe_unknown_is_harmless, setup, teardown),
        cmocka_unit_test_setup_teardown(test_unhandled_counted, setup, teardown),
        cmocka_unit_test_setup_teardown(test_fd_frame_on_classic_line_is_wrong_format, setup, teardown),
        cmocka_unit_test_setup_teardown(test_classic_frame_on_fd_line_is_dispatched, setup, teardown),
        cmocka_unit_test_setup_teardown(test_invalid_frames_counted_not_dispatched, setup, teardown),
        cmocka_unit_test_setup_teardown(test_extended_frame_not_dispatched_to_11bit_receiver, setup, teardown),
        cmocka_unit_test_setup_teardown(test_unanswered_rtr_counted, setup, teardown),
        cmocka_unit_test_setup_teardown(test_rx_overflow_counted_and_reported, setup, teardown),
        cmocka_unit_test_setup_teardown(test_comm_event_from_driver_reaches_indication, setup, teardown),
        cmocka_unit_test_setup_teardown(test_no_comm_indication_is_harmless, setup, teardown),
        cmocka_unit_test_setup_teardown(test_tx_fd_line_adds_fd_brs_and_rounds, setup, teardown),
        cmocka_unit_test_setup_teardown(test_tx_fd_line_without_brs_adds_fd_only, setup, teardown),
        cmocka_unit_test_setup_teardown(test_tx_fd_line_rounds_every_length, setup, teardown),
        cmocka_unit_test_setup_teardown(test_tx_classic_line_no_flags_no_rounding, setup, teardown),
        cmocka_unit_test_setup_teardown(test_tx_classic_line_refuses_more_than_8_bytes, setup, teardown),
        cmocka_unit_test_setup_teardown(test_tx_refuses_id_beyond_11_bits, setup, teardown),
        cmocka_unit_test_setup_teardown(test_tx_send_frame_on_fd_line_adds_flags_keeps_ext, setup, teardown),
        cmocka_unit_test_setup_teardown(test_tx_send_frame_on_fd_line_rounds_and_pads, setup, teardown),
        cmocka_unit_test_setup_teardown(test_tx_send_frame_on_classic_line_keeps_rtr, setup, teardown),
        cmocka_unit_test_setup_teardown(test_tx_send_frame_invalid_refused, setup, teardown),
        cmocka_unit_test_setup_teardown(test_tx_keeps_fifo_order, setup, teardown),
        cmocka_unit_test_setup_teardown(test_tx_overflow_counted_refused_and_reported, setup, teardown),
        cmocka_unit_test_setup_teardown(test_tx_queue_full_reported_once_when_it_fills, setup, teardown),
        cmocka_unit_test_setup_teardown(test_tx_queue_empty_reported_once_after_full, setup, teardown),
        cmocka_unit_test_setup_teardown(test_tx_no_queue_events_without_filling, setup, teardown),
        cmocka_unit_test_setup_teardown(test_tx_space_register_bounded, setup, teardown),
        cmocka_unit_test_setup_teardown(test_tx_space_called_when_queue_drains_to_half, setup, teardown),
        cmocka_unit_test_setup_teardown(test_tx_space_small_and_odd_capacities, setup, teardown),
        cmocka_unit_test_setup_teardown(test_tx_space_callback_may_send, setup, teardown),
        cmocka_unit_test_setup_teardown(test_tx_space_nobody_registered, setup, teardown),
        cmocka_unit_test_setup_teardown(test_process_returns_never_without_timers, setup, teardown),
        cmocka_unit_test_setup_teardown(test_process_runs_due_timers_and_returns_next_deadline, setup, teardown),
        cmocka_unit_test_setup_teardown(test_process_returns_deadline_set_by_timer_callback, setup, teardown),
        cmocka_unit_test_setup_teardown(test_handler_may_send_during_process, setup, teardown),
        cmocka_unit_test_setup_teardown(test_membus_delivers_to_all_others_not_sender, setup_bus, teardown),
        cmocka_unit_test_setup_teardown(test_membus_fault_hook_drops_and_duplicates, setup_bus, teardown),
        cmocka_unit_test_setup_teardown(test_membus_sent_callback_sees_every_frame_in_attach_order, setup_bus, teardown),
        cmocka_unit_test_setup_teardown(test_membus_full_receiver_counts_rx_overflow, setup_bus, teardown),
        cmocka_unit_test_setup_teardown(test_membus_attach_twice_refused, setup_bus, teardown),
        cmocka_unit_test_setup_teardown(test_membus_detached_line_receives_nothing, setup_bus, teardown),
    };
    return cmocka_run_group_tests_name("line", tests, NULL, NULL);
}
