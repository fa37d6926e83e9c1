/* Sleep and wake-up (co_sleep, CiA 320) on the in-process bus with a fake
 * clock: a master line and two device stacks (nodes 5 and 6, heartbeat
 * 100 ms) built by co_stack. Every command's bytes on the bus, the phase
 * timeline, objections, requests, refusals, the silent line, waking by bus
 * traffic and by the application (wake-up message, reset communication with
 * a boot-up), and malformed frames counted. */
#include "test_util.h"

#include "canopenfd/co_sleep.h"
#include "canopenfd/co_stack.h"

#define CHECK_MS 200u
#define PREPARE_MS 300u
#define SILENT_MS 400u
#define MAX_EV 64

typedef struct ev {
    co_sleep_event_t event;
    uint8_t arg, arg2;
    uint64_t t;
} ev_t;

typedef struct party {
    struct fx *fx;
    co_sleep_t *sleep;
    ev_t ev[MAX_EV];
    int nev;
    uint8_t objection;           /* answer to a query */
    co_sleep_event_t refuse;     /* answer non-zero to this event (0: none) */
} party_t;

typedef struct fx {
    tu_bus_t tb;
    tu_line_t master_line, dev_line[2];
    co_stack_t master;
    co_stack_t dev[2];
    co_stack_arena_t arena[3];
    unsigned char memory[3][8 * 1024];
    party_t pm, pd[2];
} fx_t;

static uint8_t on_event(co_sleep_t *sleep, co_sleep_event_t event, uint8_t arg, uint8_t arg2,
                        void *user)
{
    party_t *p = user;
    assert_ptr_equal(sleep, p->sleep);
    assert_true(p->nev < MAX_EV);
    p->ev[p->nev++] = (ev_t){event, arg, arg2, p->fx->tb.now};
    if (event == CO_SLEEP_EV_QUERY) {
        return p->objection;
    }
    return event == p->refuse ? 1 : 0;
}

/* Index of the k-th event of this kind, or -1. */
static int find_ev(const party_t *p, co_sleep_event_t event, int k)
{
    for (int i = 0; i < p->nev; i++) {
        if (p->ev[i].event == event && k-- == 0) {
            return i;
        }
    }
    return -1;
}

static const uint8_t QUERY[8] = {0x01};
static const uint8_t SLEEP[8] = {0x02};
static const uint8_t REQUEST[8] = {0x03};

static fx_t *fx_new(co_mode_t mode, uint16_t wake_repeat_ms)
{
    fx_t *fx = calloc(1, sizeof *fx);
    assert_non_null(fx);
    tu_bus_init(&fx->tb, mode, mode == CO_MODE_FD);
    tu_bus_add_line(&fx->tb, &fx->master_line);
    co_stack_t *stacks[3] = {&fx->master, &fx->dev[0], &fx->dev[1]};
    party_t *parties[3] = {&fx->pm, &fx->pd[0], &fx->pd[1]};
    for (int i = 0; i < 3; i++) {
        if (i > 0) {
            tu_bus_add_line(&fx->tb, &fx->dev_line[i - 1]);
        }
        co_line_t *line = i == 0 ? &fx->master_line.line : &fx->dev_line[i - 1].line;
        co_stack_arena_init(&fx->arena[i], fx->memory[i], sizeof fx->memory[i]);
        co_stack_line_config_t lc = {.heartbeat_entries = 4};
        assert_int_equal(co_stack_init(stacks[i], line, &lc,
                                       co_stack_arena_allocator(&fx->arena[i])), CO_STACK_OK);
        if (i > 0) {
            co_stack_node_config_t nc = {.node_id = (uint8_t)(4 + i), .heartbeat_ms = 100};
            assert_int_equal(co_stack_node_init(stacks[i], &nc), CO_STACK_OK);
            assert_int_equal(co_stack_boot(stacks[i]), CO_STACK_OK);
        }
        parties[i]->fx = fx;
        co_sleep_config_t sc = {.master = i == 0, .check_ms = CHECK_MS,
                                .prepare_ms = PREPARE_MS, .silent_ms = SILENT_MS,
                                .wake_repeat_ms = wake_repeat_ms, .ind = on_event,
                                .user = parties[i]};
        assert_int_equal(co_stack_sleep_init(stacks[i], &sc), CO_STACK_OK);
        parties[i]->sleep = co_stack_sleep(stacks[i]);
        assert_non_null(parties[i]->sleep);
    }
    tu_run_until(&fx->tb, 50 * TU_MS);   /* boot-ups */
    tu_log_clear(&fx->tb);
    return fx;
}

static void fx_free(fx_t *fx)
{
    for (int i = 0; i < 2; i++) {
        co_stack_deinit(&fx->dev[i]);
    }
    co_stack_deinit(&fx->master);
    free(fx);
}

/* Let the master's line act at the bus's time. */
static co_sleep_t *master_now(fx_t *fx)
{
    co_line_set_time(&fx->master_line.line, fx->tb.now);
    return fx->pm.sleep;
}

static size_t frames_between(const tu_bus_t *tb, uint32_t id, uint64_t from, uint64_t to)
{
    size_t n = 0;
    for (size_t i = 0; i < tb->log_count; i++) {
        if (tb->log[i].frame.id == id && tb->log[i].t_us >= from && tb->log[i].t_us < to) {
            n++;
        }
    }
    return n;
}

/* Index of the first logged frame with this CAN-ID at or after t, or -1. */
static long first_from(const tu_bus_t *tb, uint32_t id, uint64_t t)
{
    for (size_t i = 0; i < tb->log_count; i++) {
        if (tb->log[i].frame.id == id && tb->log[i].t_us >= t) {
            return (long)i;
        }
    }
    return -1;
}

/* ------------------------------------------------------------ tests */

static void run_whole_cycle(co_mode_t mode)
{
    fx_t *fx = fx_new(mode, 0);
    uint64_t t0 = fx->tb.now;
    assert_true(co_sleep_check(master_now(fx)));
    assert_int_equal(co_sleep_phase(fx->pm.sleep), CO_SLEEP_CHECKING);
    assert_false(co_sleep_check(fx->pm.sleep));          /* one check at a time */
    tu_run_until(&fx->tb, t0 + CHECK_MS * TU_MS - 1);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, CO_SLEEP_MASTER_ID, 0),
                     CO_SLEEP_MASTER_ID, QUERY, 8);
    assert_int_equal(find_ev(&fx->pd[0], CO_SLEEP_EV_QUERY, 0), 0);
    assert_int_equal(find_ev(&fx->pd[1], CO_SLEEP_EV_QUERY, 0), 0);
    assert_int_equal(tu_log_count_id(&fx->tb, CO_SLEEP_MASTER_ID), 1);   /* no sleep yet */

    /* the window closes without objection: PREPARE, the sleep command */
    uint64_t t_sleep = t0 + CHECK_MS * TU_MS;
    tu_run_until(&fx->tb, t_sleep);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, CO_SLEEP_MASTER_ID, 1),
                     CO_SLEEP_MASTER_ID, SLEEP, 8);
    assert_int_equal(fx->tb.log[tu_log_find_id(&fx->tb, CO_SLEEP_MASTER_ID, 1)].t_us, t_sleep);
    int prep = find_ev(&fx->pm, CO_SLEEP_EV_PREPARE, 0);
    assert_true(prep >= 0);
    assert_int_equal(fx->pm.ev[prep].t, t_sleep);
    for (int i = 0; i < 2; i++) {
        int d = find_ev(&fx->pd[i], CO_SLEEP_EV_PREPARE, 0);
        assert_true(d >= 0);
        assert_int_equal(fx->pd[i].ev[d].t, t_sleep);
        assert_int_equal(co_sleep_phase(fx->pd[i].sleep), CO_SLEEP_PREPARING);
    }

    /* prepare_ms later silent: the heartbeats stop, receiving goes on */
    uint64_t t_silent = t_sleep + PREPARE_MS * TU_MS;
    tu_run_until(&fx->tb, t_silent);
    for (int i = 0; i < 2; i++) {
        int s = find_ev(&fx->pd[i], CO_SLEEP_EV_SILENT, 0);
        assert_true(s >= 0);
        assert_int_equal(fx->pd[i].ev[s].t, t_silent);
        assert_true(co_line_is_silent(&fx->dev_line[i].line));
    }
    assert_int_equal(co_sleep_phase(fx->pm.sleep), CO_SLEEP_SILENT);
    assert_true(frames_between(&fx->tb, 0x705, t0, t_silent) >= 4);   /* 100 ms heartbeat */
    uint64_t t_asleep = t_silent + SILENT_MS * TU_MS;
    tu_run_until(&fx->tb, t_asleep + 500 * TU_MS);
    assert_int_equal(frames_between(&fx->tb, 0x705, t_silent + 1, t_asleep + 500 * TU_MS), 0);
    assert_int_equal(frames_between(&fx->tb, 0x706, t_silent + 1, t_asleep + 500 * TU_MS), 0);
    assert_true(co_line_stats(&fx->dev_line[0].line)->tx_silenced >= 5);
    for (int i = 0; i < 2; i++) {
        int a = find_ev(&fx->pd[i], CO_SLEEP_EV_ASLEEP, 0);
        assert_true(a >= 0);
        assert_int_equal(fx->pd[i].ev[a].t, t_asleep);
        assert_int_equal(co_sleep_phase(fx->pd[i].sleep), CO_SLEEP_ASLEEP);
    }
    assert_int_equal(co_sleep_stats(fx->pm.sleep)->queries_sent, 1);
    assert_int_equal(co_sleep_stats(fx->pm.sleep)->sleep_commands_sent, 1);

    /* the master wakes (application): its wake-up message wakes the devices
     * (bus traffic), each sends its own and resets communication: boot-up */
    tu_log_clear(&fx->tb);
    uint64_t t_wake = fx->tb.now;
    assert_false(co_sleep_wake(master_now(fx), CO_SLEEP_CMD_SLEEP, 0));  /* reads as a command */
    assert_true(co_sleep_wake(fx->pm.sleep, 0x10, 0x20));
    tu_run_until(&fx->tb, t_wake + 10 * TU_MS);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, CO_SLEEP_MASTER_ID, 0), CO_SLEEP_MASTER_ID,
                     (const uint8_t[8]){0x10, 0x20}, 8);
    int w = find_ev(&fx->pm, CO_SLEEP_EV_WAKE, 0);
    assert_true(w >= 0);
    assert_int_equal(fx->pm.ev[w].arg, CO_SLEEP_BY_APPLICATION);
    assert_int_equal(tu_log_count_id(&fx->tb, CO_SLEEP_DEVICE_ID), 2);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, CO_SLEEP_DEVICE_ID, 0), CO_SLEEP_DEVICE_ID,
                     (const uint8_t[8]){0x00, CO_SLEEP_BY_BUS}, 8);
    for (int i = 0; i < 2; i++) {
        int dw = find_ev(&fx->pd[i], CO_SLEEP_EV_WAKE, 0);
        assert_true(dw >= 0);
        assert_int_equal(fx->pd[i].ev[dw].arg, CO_SLEEP_BY_BUS);
        assert_true(find_ev(&fx->pd[i], CO_SLEEP_EV_WAKE_MESSAGE, 0) > dw);
        assert_int_equal(co_sleep_phase(fx->pd[i].sleep), CO_SLEEP_AWAKE);
        assert_false(co_line_is_silent(&fx->dev_line[i].line));
        /* reset communication: boot-up, pre-operational, heartbeats again */
        uint32_t id = 0x705u + (uint32_t)i;
        tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, id, 0), id, (const uint8_t[]){0x00}, 1);
        assert_int_equal(co_node_state(co_stack_node(&fx->dev[i])), CO_NMT_PRE_OPERATIONAL);
    }
    /* the master heard the devices' wake-up messages */
    assert_int_equal(co_sleep_stats(fx->pm.sleep)->wake_messages_received, 2);
    tu_run_until(&fx->tb, t_wake + 350 * TU_MS);
    assert_true(tu_log_count_id(&fx->tb, 0x705) >= 4);
    fx_free(fx);
}

static void test_whole_cycle_classic(void **state)
{
    (void)state;
    run_whole_cycle(CO_MODE_CLASSIC);
}

static void test_whole_cycle_fd(void **state)
{
    (void)state;
    run_whole_cycle(CO_MODE_FD);
}

/* A device objects: its reason on 0x690, the master stays awake and sends
 * no sleep command; a second check without objection goes on. */
static void test_objection_stops_the_check(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC, 0);
    fx->pd[1].objection = 0x42;
    uint64_t t0 = fx->tb.now;
    assert_true(co_sleep_check(master_now(fx)));
    tu_run_until(&fx->tb, t0 + 2 * CHECK_MS * TU_MS);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, CO_SLEEP_DEVICE_ID, 0), CO_SLEEP_DEVICE_ID,
                     (const uint8_t[8]){0x81, 0x42}, 8);
    assert_int_equal(tu_log_count_id(&fx->tb, CO_SLEEP_DEVICE_ID), 1);  /* node 5 agreed */
    int o = find_ev(&fx->pm, CO_SLEEP_EV_OBJECTION, 0);
    assert_true(o >= 0);
    assert_int_equal(fx->pm.ev[o].arg, 0x42);
    assert_int_equal(co_sleep_phase(fx->pm.sleep), CO_SLEEP_AWAKE);
    assert_int_equal(tu_log_count_id(&fx->tb, CO_SLEEP_MASTER_ID), 1);   /* the query only */
    assert_int_equal(find_ev(&fx->pm, CO_SLEEP_EV_PREPARE, 0), -1);
    assert_int_equal(co_sleep_phase(fx->pd[0].sleep), CO_SLEEP_AWAKE);
    assert_int_equal(co_sleep_stats(fx->pd[1].sleep)->objections_sent, 1);
    fx->pd[1].objection = 0;
    assert_true(co_sleep_check(master_now(fx)));
    tu_run_until(&fx->tb, fx->tb.now + CHECK_MS * TU_MS);
    assert_int_equal(co_sleep_phase(fx->pd[1].sleep), CO_SLEEP_PREPARING);
    fx_free(fx);
}

/* A device asks for sleep (0x692 [03]); the master hears it. The master's
 * own refusal of PREPARE sends no sleep command. */
static void test_request_and_master_refusal(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC, 0);
    co_line_set_time(&fx->dev_line[0].line, fx->tb.now);
    assert_true(co_sleep_request(fx->pd[0].sleep));
    assert_false(co_sleep_request(master_now(fx)));        /* a master does not ask */
    tu_run_until(&fx->tb, fx->tb.now + 5 * TU_MS);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, CO_SLEEP_REQUEST_ID, 0),
                     CO_SLEEP_REQUEST_ID, REQUEST, 8);
    assert_true(find_ev(&fx->pm, CO_SLEEP_EV_REQUEST, 0) >= 0);
    assert_int_equal(co_sleep_stats(fx->pm.sleep)->requests_received, 1);
    assert_int_equal(co_sleep_stats(fx->pd[1].sleep)->rx_ignored, 1);  /* not for a device */

    fx->pm.refuse = CO_SLEEP_EV_PREPARE;
    assert_false(co_sleep_start(master_now(fx)));
    tu_run_until(&fx->tb, fx->tb.now + 5 * TU_MS);
    assert_int_equal(tu_log_count_id(&fx->tb, CO_SLEEP_MASTER_ID), 0);
    int r = find_ev(&fx->pm, CO_SLEEP_EV_REFUSED, 0);
    assert_true(r >= 0);
    assert_int_equal(fx->pm.ev[r].arg, CO_SLEEP_PREPARING);
    assert_int_equal(co_sleep_phase(fx->pm.sleep), CO_SLEEP_AWAKE);
    fx_free(fx);
}

/* A device that refuses the silent phase stays awake (heartbeats go on, no
 * reset); the other one sleeps. */
static void test_device_refuses_silent(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC, 0);
    fx->pd[0].refuse = CO_SLEEP_EV_SILENT;
    uint64_t t0 = fx->tb.now;
    assert_true(co_sleep_start(master_now(fx)));
    tu_run_until(&fx->tb, t0 + (PREPARE_MS + SILENT_MS + 500) * TU_MS);
    int r = find_ev(&fx->pd[0], CO_SLEEP_EV_REFUSED, 0);
    assert_true(r >= 0);
    assert_int_equal(fx->pd[0].ev[r].arg, CO_SLEEP_SILENT);
    assert_int_equal(co_sleep_phase(fx->pd[0].sleep), CO_SLEEP_AWAKE);
    assert_false(co_line_is_silent(&fx->dev_line[0].line));
    assert_int_equal(find_ev(&fx->pd[0], CO_SLEEP_EV_WAKE, 0), -1);
    assert_true(frames_between(&fx->tb, 0x705, t0 + (PREPARE_MS + 100) * TU_MS,
                               fx->tb.now) >= 8);
    /* node 5's heartbeats are bus traffic: node 6 woke at the first one
     * after it fell asleep (silent until then), and booted again */
    assert_int_equal(co_sleep_phase(fx->pd[1].sleep), CO_SLEEP_AWAKE);
    int w = find_ev(&fx->pd[1], CO_SLEEP_EV_WAKE, 0);
    assert_true(w >= 0);
    assert_int_equal(fx->pd[1].ev[w].arg, CO_SLEEP_BY_BUS);
    uint64_t t_woke = fx->pd[1].ev[w].t;
    assert_true(t_woke > t0 + (PREPARE_MS + SILENT_MS) * TU_MS);
    assert_true(t_woke <= t0 + (PREPARE_MS + SILENT_MS + 100) * TU_MS);
    assert_int_equal(frames_between(&fx->tb, 0x706, t0 + (PREPARE_MS + 1) * TU_MS, t_woke), 0);
    tu_assert_logged(&fx->tb, first_from(&fx->tb, 0x706, t_woke), 0x706,
                     (const uint8_t[]){0x00}, 1);
    fx_free(fx);
}

/* The wake-up message goes out once more after wake_repeat_ms; a device's
 * status 0x81 (an objection on 0x690) is refused; waking an awake node too. */
static void test_wake_repeat_and_refused_status(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC, 50);
    co_sleep_t *d = fx->pd[0].sleep;
    co_line_set_time(&fx->dev_line[0].line, fx->tb.now);
    assert_false(co_sleep_wake(d, 0x00, 0x00));           /* awake already */
    assert_true(co_sleep_start(d));                        /* a device sleeps alone */
    tu_run_until(&fx->tb, fx->tb.now + (PREPARE_MS + SILENT_MS) * TU_MS);
    assert_int_equal(co_sleep_phase(d), CO_SLEEP_ASLEEP);
    assert_int_equal(co_sleep_phase(fx->pd[1].sleep), CO_SLEEP_AWAKE);   /* not commanded */
    tu_log_clear(&fx->tb);
    co_line_set_time(&fx->dev_line[0].line, fx->tb.now);
    assert_false(co_sleep_wake(d, CO_SLEEP_CMD_OBJECTION, 1));
    uint64_t t = fx->tb.now;
    assert_true(co_sleep_wake(d, 0x07, 0x09));
    tu_run_until(&fx->tb, t + 200 * TU_MS);
    assert_int_equal(tu_log_count_id(&fx->tb, CO_SLEEP_DEVICE_ID), 2);
    long second = tu_log_find_id(&fx->tb, CO_SLEEP_DEVICE_ID, 1);
    tu_assert_logged(&fx->tb, second, CO_SLEEP_DEVICE_ID, (const uint8_t[8]){0x07, 0x09}, 8);
    assert_int_equal(fx->tb.log[second].t_us, t + 50 * TU_MS);
    assert_int_equal(co_sleep_stats(d)->wake_messages_sent, 2);
    fx_free(fx);
}

/* Frames of other lengths are counted and change nothing; a second master's
 * frames (0x690 from its view is a device's) reach a device as ignored. */
static void test_malformed_frames_counted(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC, 0);
    co_line_t *m = &fx->master_line.line;
    co_line_set_time(m, fx->tb.now);
    co_frame_t f;
    co_frame_set(&f, CO_SLEEP_MASTER_ID, 0, (const uint8_t[7]){0x02}, 7);
    assert_true(co_line_send_raw(m, &f));
    co_frame_set(&f, CO_SLEEP_MASTER_ID, 0, (const uint8_t[1]){0x01}, 1);
    assert_true(co_line_send_raw(m, &f));
    co_frame_set(&f, CO_SLEEP_REQUEST_ID, 0, (const uint8_t[8]){0x7F}, 8);
    assert_true(co_line_send_raw(&fx->dev_line[0].line, &f));
    tu_run_until(&fx->tb, fx->tb.now + 5 * TU_MS);
    for (int i = 0; i < 2; i++) {
        assert_int_equal(co_sleep_stats(fx->pd[i].sleep)->rx_bad_length, 2);
        assert_int_equal(co_sleep_phase(fx->pd[i].sleep), CO_SLEEP_AWAKE);
        assert_int_equal(fx->pd[i].nev, 0);
    }
    assert_int_equal(co_sleep_stats(fx->pm.sleep)->rx_ignored, 1);   /* request byte 0x7F */
    assert_int_equal(co_sleep_stats(fx->pd[1].sleep)->rx_ignored, 1);
    assert_int_equal(fx->pm.nev, 0);
    fx_free(fx);
}

/* The range 0x690..0x692 is one service's: a second sleep service on the
 * line is refused, the stack names the part. */
static void test_second_service_refused(void **state)
{
    (void)state;
    fx_t *fx = fx_new(CO_MODE_CLASSIC, 0);
    co_sleep_config_t sc = {.master = true};
    assert_int_equal(co_stack_sleep_init(&fx->master, &sc), CO_STACK_ERR_STATE);
    assert_int_equal(co_stack_failed_part(&fx->master), CO_STACK_PART_SLEEP);
    co_sleep_t other;
    assert_false(co_sleep_init(&other, &fx->master_line.line, &sc));
    assert_string_equal(co_stack_part_name(CO_STACK_PART_SLEEP), "sleep and wake-up");
    fx_free(fx);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_whole_cycle_classic),
        cmocka_unit_test(test_whole_cycle_fd),
        cmocka_unit_test(test_objection_stops_the_check),
        cmocka_unit_test(test_request_and_master_refusal),
        cmocka_unit_test(test_device_refuses_silent),
        cmocka_unit_test(test_wake_repeat_and_refused_status),
        cmocka_unit_test(test_malformed_frames_counted),
        cmocka_unit_test(test_second_service_refused),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
