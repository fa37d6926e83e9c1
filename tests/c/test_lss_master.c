/* LSS master against LSS slaves on an in-process bus: the bytes of every
 * request, results, timeouts on the fake clock, answers counted, fast scan
 * over 1, 2, 8 and 32 non-configured slaves with adversarial addresses,
 * slaves sharing one address, scan by identify remote slave, the fast
 * scan's filters (match, skip) and its identify-only form.
 *
 * The bus here is the test's own (co_membus carries at most 32 lines; the
 * master plus 32 slaves are 33): each round processes every line, then hands
 * every sent frame to every other line, as co_membus does. */
#include "test_util.h"

#include "canopenfd/co_lss.h"
#include "canopenfd/co_lss_master.h"

#include <stdio.h>

enum { MAX_SLAVES = 33, TIMEOUT_MS = 10, LOG_MAX = 160 };

typedef struct sim {
    tu_line_t master_line;
    co_lss_master_t master;
    tu_line_t *slave_lines;          /* MAX_SLAVES of them (heap: they are large) */
    co_lss_slave_t slaves[MAX_SLAVES];
    co_lss_slave_indications_t ind;
    uint32_t n;
    uint64_t now;
    int done;
    co_lss_master_result_t result;
    uint64_t done_at;
    uint32_t master_frames;          /* frames the master put on the bus */
    co_frame_t log[LOG_MAX];         /* the first master frames since sim_log_clear */
    uint32_t log_count;
    uint32_t late;                   /* a slave (1..n) whose frames arrive late_us later; 0: none */
    uint64_t late_us;
    co_frame_t held[LOG_MAX];        /* its frames on their way ... */
    uint64_t held_at[LOG_MAX];       /* ... and when they arrive */
    uint32_t held_from[LOG_MAX];     /* ... from which line */
    uint32_t held_count;
} sim_t;

static void on_done(co_lss_master_t *m, const co_lss_master_result_t *r, void *user)
{
    sim_t *s = user;
    s->done++;
    s->result = *r;
    s->done_at = co_line_now(m->line);
}

/* The node of a slave resets communication: the pending node-id is active. */
static void reset_communication(co_lss_slave_t *slave, uint8_t node_id, void *user)
{
    (void)user;
    assert_int_equal(co_lss_slave_reset_communication(slave), node_id);
}

static sim_t *sim_new(void)
{
    sim_t *s = test_calloc(1, sizeof *s);
    s->slave_lines = test_calloc(MAX_SLAVES, sizeof *s->slave_lines);
    tu_line_init(&s->master_line, CO_MODE_CLASSIC, false);
    assert_true(co_lss_master_init(&s->master, &s->master_line.line, TIMEOUT_MS, on_done, s));
    s->ind.reset_communication = reset_communication;
    return s;
}

static co_lss_slave_t *sim_add(sim_t *s, co_lss_address_t address, uint8_t node_id)
{
    assert_true(s->n < MAX_SLAVES);
    tu_line_t *l = &s->slave_lines[s->n];
    tu_line_init(l, CO_MODE_CLASSIC, false);
    co_line_set_time(&l->line, s->now);
    co_lss_slave_t *slave = &s->slaves[s->n++];
    assert_true(co_lss_slave_init(slave, &l->line, &address, node_id, &s->ind, s));
    return slave;
}

static void sim_free(sim_t *s)
{
    for (uint32_t i = 0; i < s->n; i++) {
        co_lss_slave_deinit(&s->slaves[i]);
    }
    co_lss_master_deinit(&s->master);
    test_free(s->slave_lines);
    test_free(s);
}

static co_line_t *line_of(sim_t *s, uint32_t i)
{
    return i == 0 ? &s->master_line.line : &s->slave_lines[i - 1].line;
}

static void sim_log_clear(sim_t *s) { s->log_count = 0; }

/* Process every line at `now` and carry frames until the bus is quiet. */
static void sim_step(sim_t *s, uint64_t now)
{
    assert_true(now >= s->now);
    s->now = now;
    /* The late slave's frames that are due now reach everyone else. */
    uint32_t kept = 0;
    for (uint32_t h = 0; h < s->held_count; h++) {
        if (s->held_at[h] > now) {
            s->held[kept] = s->held[h];
            s->held_from[kept] = s->held_from[h];
            s->held_at[kept++] = s->held_at[h];
            continue;
        }
        for (uint32_t k = 0; k <= s->n; k++) {
            if (k != s->held_from[h]) {
                assert_true(co_line_receive(line_of(s, k), &s->held[h]));
            }
        }
    }
    s->held_count = kept;
    for (int round = 0; round < 100000; round++) {
        for (uint32_t i = 0; i <= s->n; i++) {
            (void)co_line_process(line_of(s, i), now);
        }
        uint32_t moved = 0;
        for (uint32_t i = 0; i <= s->n; i++) {
            co_frame_t f;
            while (co_line_tx_pop(line_of(s, i), &f)) {
                if (s->late != 0 && i == s->late) {
                    assert_true(s->held_count < LOG_MAX);
                    s->held[s->held_count] = f;
                    s->held_from[s->held_count] = i;
                    s->held_at[s->held_count++] = now + s->late_us;
                    continue;
                }
                moved++;
                if (i == 0) {
                    s->master_frames++;
                    if (s->log_count < LOG_MAX) {
                        s->log[s->log_count++] = f;
                    }
                }
                for (uint32_t k = 0; k <= s->n; k++) {
                    if (k != i) {
                        assert_true(co_line_receive(line_of(s, k), &f));
                    }
                }
            }
        }
        if (moved == 0) {
            return;
        }
    }
    fail_msg("bus did not become quiet");
}

static uint64_t sim_next_deadline(sim_t *s)
{
    uint64_t next = CO_TIME_NEVER;
    for (uint32_t i = 0; i <= s->n; i++) {
        uint64_t d = co_timer_list_next(co_line_timers(line_of(s, i)));
        next = d < next ? d : next;
    }
    for (uint32_t h = 0; h < s->held_count; h++) {
        next = s->held_at[h] < next ? s->held_at[h] : next;
    }
    return next;
}

/* Run until the master's callback ran once more; returns its result. */
static co_lss_master_result_t sim_wait(sim_t *s)
{
    int done = s->done;
    sim_step(s, s->now);
    for (long guard = 0; s->done == done; guard++) {
        uint64_t d = sim_next_deadline(s);
        assert_true(d != CO_TIME_NEVER);       /* the master always keeps a timer */
        assert_true(guard < 10000000);
        sim_step(s, d > s->now ? d : s->now);
    }
    assert_int_equal(s->done, done + 1);
    return s->result;
}

static void assert_request(const co_frame_t *f, const uint8_t expected[8])
{
    tu_assert_frame(f, CO_LSS_ID_MASTER, 0, expected, 8);
}

static co_lss_address_t addr(uint32_t v, uint32_t p, uint32_t r, uint32_t sn)
{
    co_lss_address_t a = {{v, p, r, sn}};
    return a;
}

/* ------------------------------------------------------- single services */

static void test_services_on_the_wire(void **state)
{
    (void)state;
    sim_t *s = sim_new();
    co_lss_slave_t *slave = sim_add(s, addr(0x123, 0x4567, 0x89AB, 0xCDEF0011u), 0x20);

    /* Switch state selective: four frames, the answer 0x44. */
    sim_log_clear(s);
    co_lss_address_t a = slave->address;
    assert_true(co_lss_master_switch_selective(&s->master, &a));
    co_lss_master_result_t r = sim_wait(s);
    assert_int_equal(r.request, CO_LSS_REQ_SWITCH_SELECTIVE);
    assert_int_equal(r.status, CO_LSS_OK);
    assert_int_equal(r.frames, 4);
    assert_int_equal(s->log_count, 4);
    const uint8_t sel[4][8] = {{0x40, 0x23, 0x01, 0, 0}, {0x41, 0x67, 0x45, 0, 0},
                               {0x42, 0xAB, 0x89, 0, 0}, {0x43, 0x11, 0x00, 0xEF, 0xCD}};
    for (int i = 0; i < 4; i++) {
        assert_request(&s->log[i], sel[i]);
    }
    assert_int_equal(co_lss_slave_state(slave), CO_LSS_STATE_CONFIGURATION);
    assert_int_equal(s->done_at, s->now);      /* answered: no waiting for the timeout */

    /* Inquire each number and the node-id. */
    for (uint8_t cs = 0x5A; cs <= 0x5E; cs++) {
        sim_log_clear(s);
        assert_true(co_lss_master_inquire(&s->master, cs));
        r = sim_wait(s);
        const uint8_t q[8] = {cs};
        assert_request(&s->log[0], q);
        assert_int_equal(r.status, CO_LSS_OK);
        assert_int_equal(r.value, cs == 0x5E ? 0x20u : a.part[cs - 0x5A]);
    }
    assert_false(co_lss_master_inquire(&s->master, 0x59));
    assert_false(co_lss_master_inquire(&s->master, 0x5F));

    /* Configure node-id. */
    sim_log_clear(s);
    assert_true(co_lss_master_configure_node_id(&s->master, 5));
    r = sim_wait(s);
    const uint8_t cfg[8] = {0x11, 5};
    assert_request(&s->log[0], cfg);
    assert_int_equal(r.status, CO_LSS_OK);
    assert_int_equal(co_lss_slave_pending_node_id(slave), 5);
    assert_false(co_lss_master_configure_node_id(&s->master, 0));
    assert_false(co_lss_master_configure_node_id(&s->master, 128));

    /* Bit timing and store: the slave has no indications: refused, error 1. */
    sim_log_clear(s);
    assert_true(co_lss_master_configure_bit_timing(&s->master, 0, 4));
    r = sim_wait(s);
    const uint8_t bt[8] = {0x13, 0, 4};
    assert_request(&s->log[0], bt);
    assert_int_equal(r.status, CO_LSS_REFUSED);
    assert_int_equal(r.error, 1);
    sim_log_clear(s);
    assert_true(co_lss_master_store(&s->master));
    r = sim_wait(s);
    const uint8_t st[8] = {0x17};
    assert_request(&s->log[0], st);
    assert_int_equal(r.status, CO_LSS_REFUSED);
    assert_int_equal(r.error, 1);

    /* Activate bit timing and switch global: sent at once, no answer. */
    sim_log_clear(s);
    assert_true(co_lss_master_activate_bit_timing(&s->master, 0x0102));
    assert_true(co_lss_master_switch_global(&s->master, CO_LSS_STATE_WAITING));
    assert_false(co_lss_master_switch_global(&s->master, (co_lss_state_t)2));
    sim_step(s, s->now);
    const uint8_t act[8] = {0x15, 0x02, 0x01};
    const uint8_t sw[8] = {0x04, 0x00};
    assert_int_equal(s->log_count, 2);
    assert_request(&s->log[0], act);
    assert_request(&s->log[1], sw);
    assert_int_equal(co_lss_slave_state(slave), CO_LSS_STATE_WAITING);

    /* Identify remote slave: six frames; inside the range answers. */
    sim_log_clear(s);
    assert_true(co_lss_master_identify_remote(&s->master, 0x123, 0x4567, 0x1000, 0x9000,
                                              0xCDEF0000u, 0xCDEFFFFFu));
    r = sim_wait(s);
    assert_int_equal(r.status, CO_LSS_OK);
    assert_int_equal(r.answers, 1);
    const uint8_t idf[6][8] = {{0x46, 0x23, 0x01}, {0x47, 0x67, 0x45}, {0x48, 0x00, 0x10},
                               {0x49, 0x00, 0x90}, {0x4A, 0, 0, 0xEF, 0xCD},
                               {0x4B, 0xFF, 0xFF, 0xEF, 0xCD}};
    assert_int_equal(s->log_count, 6);
    for (int i = 0; i < 6; i++) {
        assert_request(&s->log[i], idf[i]);
    }
    assert_true(co_lss_master_identify_remote(&s->master, 0x123, 0x4567, 0x1000, 0x9000,
                                              0, 0xCDEF0010u));
    r = sim_wait(s);
    assert_int_equal(r.status, CO_LSS_TIMEOUT);
    assert_int_equal(r.answers, 0);
    assert_false(co_lss_master_identify_remote(&s->master, 1, 1, 2, 1, 0, 0));

    /* Identify non-configured: a configured slave stays silent. */
    sim_log_clear(s);
    assert_true(co_lss_master_identify_non_configured(&s->master));
    r = sim_wait(s);
    const uint8_t nc[8] = {0x4C};
    assert_request(&s->log[0], nc);
    assert_int_equal(r.status, CO_LSS_TIMEOUT);
    sim_free(s);
}

/* No slave: every request ends with TIMEOUT exactly one timeout later. */
static void test_timeouts(void **state)
{
    (void)state;
    sim_t *s = sim_new();
    sim_step(s, 5000);
    assert_true(co_lss_master_inquire(&s->master, CO_LSS_CS_INQUIRE_NODE_ID));
    assert_true(co_lss_master_busy(&s->master));
    /* One request at a time. */
    assert_false(co_lss_master_store(&s->master));
    assert_false(co_lss_master_switch_global(&s->master, CO_LSS_STATE_WAITING));
    co_lss_master_result_t r = sim_wait(s);
    assert_int_equal(r.status, CO_LSS_TIMEOUT);
    assert_int_equal(s->done_at, 5000u + TIMEOUT_MS * 1000u);
    assert_false(co_lss_master_busy(&s->master));
    assert_int_equal(co_lss_master_stats(&s->master)->timeouts, 1);

    /* Fast scan with nobody there: one reset frame, then done. */
    uint8_t ids[] = {1};
    co_lss_device_t dev[1];
    assert_true(co_lss_master_fastscan(&s->master, ids, 1, dev, 1));
    r = sim_wait(s);
    assert_int_equal(r.status, CO_LSS_OK);
    assert_int_equal(r.found, 0);
    assert_int_equal(r.frames, 1);
    /* Bad arguments: nothing starts. */
    uint8_t bad_ids[] = {1, 0};
    assert_false(co_lss_master_fastscan(&s->master, bad_ids, 2, dev, 1));
    assert_false(co_lss_master_fastscan(&s->master, ids, 0, dev, 1));
    assert_false(co_lss_master_fastscan(&s->master, ids, 1, dev, 0));
    assert_false(co_lss_master_scan(&s->master, 1, 1, 0, 0, 5, 4, dev, 1));

    /* Cancel. */
    assert_true(co_lss_master_store(&s->master));
    int before = s->done;
    co_lss_master_cancel(&s->master);
    assert_int_equal(s->done, before + 1);
    assert_int_equal(s->result.status, CO_LSS_CANCELLED);
    assert_false(co_lss_master_busy(&s->master));
    assert_int_equal(sim_next_deadline(s), CO_TIME_NEVER);
    co_lss_master_cancel(&s->master);          /* idle: nothing */
    assert_int_equal(s->done, before + 1);
    sim_free(s);
}

/* Two answers where one is expected are counted; stray and malformed
 * answers too; the master carries on. */
static void test_answers_counted(void **state)
{
    (void)state;
    sim_t *s = sim_new();
    sim_add(s, addr(1, 2, 3, 4), 10);
    sim_add(s, addr(1, 2, 3, 5), 11);
    assert_true(co_lss_master_switch_global(&s->master, CO_LSS_STATE_CONFIGURATION));
    sim_step(s, s->now);
    assert_true(co_lss_master_inquire(&s->master, CO_LSS_CS_INQUIRE_NODE_ID));
    co_lss_master_result_t r = sim_wait(s);
    assert_int_equal(r.status, CO_LSS_OK);
    assert_int_equal(r.answers, 2);
    assert_int_equal(r.value, 10);                 /* the first */
    assert_int_equal(co_lss_master_stats(&s->master)->duplicates, 1);

    /* Stray answers while idle, malformed ones. */
    co_line_t *ml = &s->master_line.line;
    const uint8_t stray[8] = {0x4F};
    co_frame_t f = tu_frame(CO_LSS_ID_SLAVE, 0, stray, 8);
    assert_true(co_line_receive(ml, &f));
    f = tu_frame(CO_LSS_ID_SLAVE, 0, stray, 5);
    assert_true(co_line_receive(ml, &f));
    const uint8_t unknown[8] = {0x51};
    f = tu_frame(CO_LSS_ID_SLAVE, 0, unknown, 8);
    assert_true(co_line_receive(ml, &f));
    sim_step(s, s->now + 1);
    const co_lss_master_stats_t *st = co_lss_master_stats(&s->master);
    assert_int_equal(st->unexpected, 1);
    assert_int_equal(st->bad_length, 1);
    assert_int_equal(st->unknown_cs, 1);

    /* An answer of another command while waiting is not taken. */
    assert_true(co_lss_master_store(&s->master));
    f = tu_frame(CO_LSS_ID_SLAVE, 0, stray, 8);
    assert_true(co_line_receive(ml, &f));
    r = sim_wait(s);
    assert_int_equal(r.status, CO_LSS_REFUSED);    /* both slaves: store not supported */
    assert_int_equal(st->unexpected, 2);
    sim_free(s);
}

/* ------------------------------------------------------------- fast scan */

/* Adversarial addresses: all zeros, zeros but the last serial bit, all
 * ones, ones but the last serial bit, then pairs with one vendor and
 * product that differ only in the last serial bit. */
static co_lss_address_t adversarial(uint32_t i)
{
    switch (i) {
    case 0:
        return addr(0, 0, 0, 0);
    case 1:
        return addr(0, 0, 0, 1);
    case 2:
        return addr(UINT32_MAX, UINT32_MAX, UINT32_MAX, UINT32_MAX);
    case 3:
        return addr(UINT32_MAX, UINT32_MAX, UINT32_MAX, UINT32_MAX - 1u);
    default:
        return addr(0x0000ABCDu, 0x00000001u, 0x00010000u | (i % 3u),
                    0xCAFE0000u | ((i / 2u) << 8) | (i & 1u));
    }
}

static void fastscan_n(uint32_t n)
{
    sim_t *s = sim_new();
    for (uint32_t i = 0; i < n; i++) {
        sim_add(s, adversarial(i), CO_LSS_NODE_ID_UNCONFIGURED);
    }
    /* A configured slave is on the line too and takes no part. */
    sim_add(s, addr(0x0000ABCDu, 0x00000001u, 0x00010000u, 0xCAFE0000u), 100);
    uint8_t ids[MAX_SLAVES];
    for (uint32_t i = 0; i < MAX_SLAVES; i++) {
        ids[i] = (uint8_t)(i + 1u);
    }
    co_lss_device_t found[MAX_SLAVES];
    uint32_t frames_before = s->master_frames;
    uint64_t t0 = s->now;
    assert_true(co_lss_master_fastscan(&s->master, ids, MAX_SLAVES, found, MAX_SLAVES));
    co_lss_master_result_t r = sim_wait(s);
    assert_int_equal(r.status, CO_LSS_OK);
    assert_int_equal(r.found, n);
    assert_int_equal(r.frames, s->master_frames - frames_before);
    /* Every slave got the node-id the master reported for its address,
     * and every node-id is different. */
    uint8_t seen[128] = {0};
    for (uint32_t i = 0; i < n; i++) {
        const co_lss_slave_t *slave = &s->slaves[i];
        uint8_t id = co_lss_slave_active_node_id(slave);
        assert_true(id >= 1 && id <= n);
        assert_int_equal(seen[id], 0);
        seen[id] = 1;
        assert_int_equal(found[id - 1u].node_id, id);
        assert_memory_equal(&found[id - 1u].address, &slave->address, sizeof slave->address);
        assert_int_equal(co_lss_slave_state(slave), CO_LSS_STATE_WAITING);
    }
    assert_int_equal(co_lss_slave_active_node_id(&s->slaves[n]), 100);
    /* Frames against the protocol's minimum: per slave one reset, 128 bit
     * checks, configure node-id and switch to waiting, plus the final
     * reset nobody answers. Ours adds one confirmation per part whose bit 0
     * is 1 (the bit-0 check names the next part already); the plain method
     * confirms every part (4 per slave). */
    uint32_t minimum = n * 131u + 1u;
    uint32_t confirmations = 0;
    for (uint32_t i = 0; i < n; i++) {
        for (int p = 0; p < 4; p++) {
            confirmations += s->slaves[i].address.part[p] & 1u;
        }
    }
    assert_int_equal(r.frames, minimum + confirmations);
    printf("fast scan %2u slaves: %5u frames, minimum %5u, plain method %5u, "
           "%4u timeouts, %.2f s at %d ms per step\n",
           n, r.frames, minimum, n * 135u + 1u, co_lss_master_stats(&s->master)->timeouts,
           (double)(s->done_at - t0) / 1e6, TIMEOUT_MS);
    /* Nothing left to find. */
    assert_true(co_lss_master_identify_non_configured(&s->master));
    r = sim_wait(s);
    assert_int_equal(r.status, CO_LSS_TIMEOUT);
    sim_free(s);
}

static void test_fastscan_1(void **state)
{
    (void)state;
    fastscan_n(1);
}

static void test_fastscan_2(void **state)
{
    (void)state;
    fastscan_n(2);
}

static void test_fastscan_8(void **state)
{
    (void)state;
    fastscan_n(8);
}

static void test_fastscan_32(void **state)
{
    (void)state;
    fastscan_n(32);
}

/* Two slaves with one address answer together: the scan ends with
 * DUPLICATE (not a hang), both lose the node-id again; the others found
 * before keep theirs. */
static void test_fastscan_same_address(void **state)
{
    (void)state;
    sim_t *s = sim_new();
    sim_add(s, addr(7, 7, 7, 7), CO_LSS_NODE_ID_UNCONFIGURED);
    sim_add(s, addr(7, 7, 7, 7), CO_LSS_NODE_ID_UNCONFIGURED);
    sim_add(s, addr(1, 7, 7, 7), CO_LSS_NODE_ID_UNCONFIGURED);   /* found first */
    uint8_t ids[] = {20, 21, 22};
    co_lss_device_t found[3];
    assert_true(co_lss_master_fastscan(&s->master, ids, 3, found, 3));
    co_lss_master_result_t r = sim_wait(s);
    assert_int_equal(r.status, CO_LSS_DUPLICATE);
    assert_int_equal(r.found, 1);
    assert_int_equal(found[0].node_id, 20);
    assert_int_equal(found[0].address.part[0], 1);
    assert_int_equal(co_lss_slave_active_node_id(&s->slaves[2]), 20);
    for (int i = 0; i < 2; i++) {
        assert_int_equal(co_lss_slave_active_node_id(&s->slaves[i]), 255);
        assert_int_equal(co_lss_slave_pending_node_id(&s->slaves[i]), 255);
        assert_int_equal(co_lss_slave_state(&s->slaves[i]), CO_LSS_STATE_WAITING);
    }
    assert_true(co_lss_master_stats(&s->master)->duplicates >= 1);
    sim_free(s);
}

/* More slaves than node-ids (or table entries): the scan stops and says so. */
static void test_fastscan_runs_out(void **state)
{
    (void)state;
    sim_t *s = sim_new();
    for (uint32_t i = 0; i < 3; i++) {
        sim_add(s, adversarial(i), CO_LSS_NODE_ID_UNCONFIGURED);
    }
    uint8_t ids[] = {5, 6};
    co_lss_device_t found[3];
    assert_true(co_lss_master_fastscan(&s->master, ids, 2, found, 3));
    co_lss_master_result_t r = sim_wait(s);
    assert_int_equal(r.status, CO_LSS_NO_NODE_ID);
    assert_int_equal(r.found, 2);
    uint8_t more[] = {7, 8};
    assert_true(co_lss_master_fastscan(&s->master, more, 2, found, 0 + 1));
    r = sim_wait(s);
    assert_int_equal(r.status, CO_LSS_OK);
    assert_int_equal(r.found, 1);
    assert_int_equal(found[0].node_id, 7);
    sim_free(s);
}

/* A slave that vanishes half-way: the scan ends with LOST. */
static void test_fastscan_slave_vanishes(void **state)
{
    (void)state;
    sim_t *s = sim_new();
    sim_add(s, addr(0xFF, 0, 0, 0), CO_LSS_NODE_ID_UNCONFIGURED);
    uint8_t ids[] = {1};
    co_lss_device_t found[1];
    assert_true(co_lss_master_fastscan(&s->master, ids, 1, found, 1));
    /* Run the first few steps, then cut the slave off the bus. */
    sim_step(s, s->now);
    for (int i = 0; i < 3; i++) {
        sim_step(s, sim_next_deadline(s));
    }
    co_lss_slave_deinit(&s->slaves[0]);
    assert_int_equal(s->done, 0);
    co_lss_master_result_t r = sim_wait(s);
    assert_int_equal(r.status, CO_LSS_LOST);
    assert_true(co_lss_slave_init(&s->slaves[0], &s->slave_lines[0].line, &s->slaves[0].address,
                                  255, NULL, NULL));
    sim_free(s);
}

/* ------------------------------------------------------------------- scan */

static void test_scan(void **state)
{
    (void)state;
    sim_t *s = sim_new();
    /* One vendor/product; two slaves share a serial with different
     * revisions; one configured; one of another product; one outside. */
    sim_add(s, addr(0x77, 0x10, 3, 1000), 1);
    sim_add(s, addr(0x77, 0x10, 4, 1000), 2);
    sim_add(s, addr(0x77, 0x10, 3, 1001), CO_LSS_NODE_ID_UNCONFIGURED);
    sim_add(s, addr(0x77, 0x10, 9, 0x7FFFFFFFu), 3);
    sim_add(s, addr(0x77, 0x11, 3, 1002), 4);       /* other product */
    sim_add(s, addr(0x77, 0x10, 3, 5), 5);          /* serial below the range */
    co_lss_device_t found[8];
    assert_true(co_lss_master_scan(&s->master, 0x77, 0x10, 0, 100, 10, UINT32_MAX, found, 8));
    co_lss_master_result_t r = sim_wait(s);
    assert_int_equal(r.status, CO_LSS_OK);
    assert_int_equal(r.found, 4);
    const uint32_t expect[4][2] = {{1000, 3}, {1000, 4}, {1001, 3}, {0x7FFFFFFFu, 9}};
    for (int i = 0; i < 4; i++) {
        assert_int_equal(found[i].address.part[CO_LSS_VENDOR], 0x77);
        assert_int_equal(found[i].address.part[CO_LSS_PRODUCT], 0x10);
        assert_int_equal(found[i].address.part[CO_LSS_SERIAL], expect[i][0]);
        assert_int_equal(found[i].address.part[CO_LSS_REVISION], expect[i][1]);
    }
    printf("scan of a 2^32-10 serial range, 4 slaves: %u frames\n", r.frames);
    /* A table too small: FULL with what fits. */
    assert_true(co_lss_master_scan(&s->master, 0x77, 0x10, 0, 100, 10, UINT32_MAX, found, 2));
    r = sim_wait(s);
    assert_int_equal(r.status, CO_LSS_FULL);
    assert_int_equal(r.found, 2);
    sim_free(s);
}

/* -------------------------------------------------- slaves with different latencies */

/* Two non-configured slaves, one of them answering every request 2 ms
 * after the other (a slower device; found with durand's software slaves):
 * each answer must count for the request it answers. Before the settle
 * time a step ended at the first answer and the late one was taken by the
 * next check, which then read a 1-bit as 0: the scan ended LOST. */
static void test_fastscan_late_slave(void **state)
{
    (void)state;
    sim_t *s = sim_new();
    /* equal prefixes, differing in the last serial bit; vendor bit 0 is 1 */
    sim_add(s, addr(0x00000001u, 0x00000002u, 0x00000003u, 0x00000010u), 255);
    sim_add(s, addr(0x00000001u, 0x00000002u, 0x00000003u, 0x00000011u), 255);
    s->late = 2;
    s->late_us = 2000;      /* under the settle time set here */
    assert_true(co_lss_master_set_settle(&s->master, 3000));
    assert_false(co_lss_master_set_settle(&s->master, TIMEOUT_MS * 1000u + 1u));
    const uint8_t ids[2] = {10, 11};
    co_lss_device_t found[2];
    assert_true(co_lss_master_fastscan(&s->master, ids, 2, found, 2));
    co_lss_master_result_t r = sim_wait(s);
    assert_int_equal(r.status, CO_LSS_OK);
    assert_int_equal(r.found, 2);
    assert_int_equal(co_lss_slave_active_node_id(&s->slaves[0]), 10);   /* serial 0x10 first */
    assert_int_equal(co_lss_slave_active_node_id(&s->slaves[1]), 11);
    assert_int_equal(found[1].address.part[CO_LSS_SERIAL], 0x11);
    /* No answer was taken by a step it did not answer. */
    assert_int_equal(s->held_count, 0);
    sim_free(s);
}

/* The same slower slave, settle time shorter than its latency: the late
 * answers are still attributed wrongly; the scan must end in a defined
 * state (never wedge), and only with a result the slaves agree with. */
static void test_fastscan_slave_later_than_settle(void **state)
{
    (void)state;
    sim_t *s = sim_new();
    sim_add(s, addr(0x00000001u, 0x00000002u, 0x00000003u, 0x00000010u), 255);
    sim_add(s, addr(0x00000001u, 0x00000002u, 0x00000003u, 0x00000011u), 255);
    s->late = 2;
    s->late_us = 5000;
    assert_true(co_lss_master_set_settle(&s->master, 1000));
    const uint8_t ids[2] = {10, 11};
    co_lss_device_t found[2];
    assert_true(co_lss_master_fastscan(&s->master, ids, 2, found, 2));
    co_lss_master_result_t r = sim_wait(s);
    assert_true(r.status == CO_LSS_OK || r.status == CO_LSS_LOST);
    for (uint32_t i = 0; i < r.found; i++) {
        uint8_t id = found[i].node_id;
        const co_lss_slave_t *slave = id == co_lss_slave_active_node_id(&s->slaves[0])
                                          ? &s->slaves[0] : &s->slaves[1];
        assert_int_equal(co_lss_slave_active_node_id(slave), id);
        assert_memory_equal(&found[i].address, &slave->address, sizeof slave->address);
    }
    sim_free(s);
}

/* A slave later than the settle time makes a part fail to confirm: the
 * scan starts over with a reset (CO_LSS_FASTSCAN_RESTARTS times) and finds
 * both once the slave is quick again; a slave late every time ends LOST. */
static void test_fastscan_restarts(void **state)
{
    (void)state;
    sim_t *s = sim_new();
    /* serials 2 and 3: at serial bit 1 nobody answers, but the late
     * slave's answer to bit 2 comes then and reads as a 0-bit */
    sim_add(s, addr(0x00000000u, 0x00000000u, 0x00000000u, 0x00000002u), 255);
    sim_add(s, addr(0x00000000u, 0x00000000u, 0x00000000u, 0x00000003u), 255);
    s->late = 2;
    s->late_us = 5000;
    assert_true(co_lss_master_set_settle(&s->master, 1000));
    const uint8_t ids[2] = {10, 11};
    co_lss_device_t found[2];
    assert_true(co_lss_master_fastscan(&s->master, ids, 2, found, 2));
    const co_lss_master_stats_t *st = co_lss_master_stats(&s->master);
    sim_step(s, s->now);
    for (long guard = 0; st->fastscan_restarts == 0; guard++) {
        assert_true(guard < 1000000 && s->done == 0);
        uint64_t d = sim_next_deadline(s);
        sim_step(s, d > s->now ? d : s->now);
    }
    s->late = 0;                     /* quick from now on */
    co_lss_master_result_t r = sim_wait(s);
    assert_int_equal(r.status, CO_LSS_OK);
    assert_int_equal(r.found, 2);
    assert_int_equal(co_lss_slave_active_node_id(&s->slaves[0]), 10);
    assert_int_equal(co_lss_slave_active_node_id(&s->slaves[1]), 11);
    assert_int_equal(st->fastscan_restarts, 1);
    sim_free(s);

    s = sim_new();
    /* serials 2 and 3: at serial bit 1 nobody answers, but the late
     * slave's answer to bit 2 comes then and reads as a 0-bit */
    sim_add(s, addr(0x00000000u, 0x00000000u, 0x00000000u, 0x00000002u), 255);
    sim_add(s, addr(0x00000000u, 0x00000000u, 0x00000000u, 0x00000003u), 255);
    s->late = 2;
    s->late_us = 5000;
    assert_true(co_lss_master_set_settle(&s->master, 1000));
    assert_true(co_lss_master_fastscan(&s->master, ids, 2, found, 2));
    r = sim_wait(s);
    assert_int_equal(r.status, CO_LSS_LOST);
    assert_int_equal(r.found, 0);
    assert_int_equal(co_lss_master_stats(&s->master)->fastscan_restarts,
                     CO_LSS_FASTSCAN_RESTARTS);
    sim_free(s);
}

/* Identify requests count every slave that answers within the timeout. */
static void test_identify_counts_late_answers(void **state)
{
    (void)state;
    sim_t *s = sim_new();
    sim_add(s, addr(0x77, 0x10, 3, 1000), 255);
    sim_add(s, addr(0x77, 0x10, 3, 1001), 255);
    s->late = 2;
    s->late_us = 4000;
    assert_true(co_lss_master_identify_non_configured(&s->master));
    co_lss_master_result_t r = sim_wait(s);
    assert_int_equal(r.status, CO_LSS_OK);
    assert_int_equal(r.answers, 2);
    assert_true(co_lss_master_identify_remote(&s->master, 0x77, 0x10, 0, 10, 0, 2000));
    r = sim_wait(s);
    assert_int_equal(r.status, CO_LSS_OK);
    assert_int_equal(r.answers, 2);
    /* A scan with the late slave finds both, and nothing else. */
    assert_true(co_lss_master_set_settle(&s->master, 5000));
    co_lss_device_t found[4];
    assert_true(co_lss_master_scan(&s->master, 0x77, 0x10, 0, 10, 0, 2000, found, 4));
    r = sim_wait(s);
    assert_int_equal(r.status, CO_LSS_OK);
    assert_int_equal(r.found, 2);
    assert_int_equal(found[0].address.part[CO_LSS_SERIAL], 1000);
    assert_int_equal(found[1].address.part[CO_LSS_SERIAL], 1001);
    sim_free(s);
}

/* ------------------------------------------- fast scan: identify, filters */

/* The frames CiA 305 prescribes to find `a` when it is the only slave that
 * takes part, written out independently of the master: the reset, then per
 * part not skipped the checks of bit 31 down to 0 (the bits found so far,
 * the checked bit as 0; a slave answers when its bits from the checked one
 * up match), the bit-0 check naming the next part, and a confirmation when
 * the last bit is 1 (nobody answered its 0). A matched part is checked with
 * its whole value at once. Returns the count written to out. */
static uint32_t expected_fastscan(co_lss_address_t a, const co_lss_fastscan_filter_t *f,
                                  uint8_t out[][8], uint32_t max)
{
    uint32_t n = 0;
    co_lss_encode_fastscan(out[n++], 0, CO_LSS_FASTSCAN_CONFIRM, 0, 0);
    for (uint8_t p = 0; p < 4u; p++) {
        if (f->kind[p] == CO_LSS_FS_SKIP) {
            continue;
        }
        uint8_t next = 0;
        for (uint8_t q = (uint8_t)(p + 1u); q < 4u; q++) {
            if (f->kind[q] != CO_LSS_FS_SKIP) {
                next = q;
                break;
            }
        }
        if (f->kind[p] == CO_LSS_FS_MATCH) {
            assert_true(n < max);
            co_lss_encode_fastscan(out[n++], f->match[p], 0, p, next);
            continue;
        }
        for (int bit = 31; bit >= 0; bit--) {
            uint32_t above = bit == 31 ? 0u : a.part[p] & (UINT32_MAX << (bit + 1));
            assert_true(n < max);
            co_lss_encode_fastscan(out[n++], above, (uint8_t)bit, p, bit == 0 ? next : p);
        }
        if (a.part[p] & 1u) {
            assert_true(n < max);
            co_lss_encode_fastscan(out[n++], a.part[p], 0, p, next);
        }
    }
    return n;
}

static void assert_log(sim_t *s, uint8_t expected[][8], uint32_t n)
{
    assert_int_equal(s->log_count, n);
    for (uint32_t i = 0; i < n; i++) {
        assert_request(&s->log[i], expected[i]);
    }
}

/* Identify only: the slave with the lowest address among the unconfigured
 * ones is found bit by bit and left selected in the configuration state,
 * its node-id untouched; no configure, no switch back to waiting. */
static void test_fastscan_identify(void **state)
{
    (void)state;
    sim_t *s = sim_new();
    co_lss_address_t low = addr(0x12345678u, 0x9ABCDEF1u, 0x00010002u, 0x80000007u);
    co_lss_slave_t *first = sim_add(s, low, CO_LSS_NODE_ID_UNCONFIGURED);
    co_lss_slave_t *second = sim_add(s, addr(0x12345678u, 0x9ABCDEF1u, 0x00010003u, 0),
                                     CO_LSS_NODE_ID_UNCONFIGURED);
    co_lss_slave_t *configured = sim_add(s, addr(0, 0, 0, 0), 9);
    co_lss_device_t found[1];
    sim_log_clear(s);
    uint64_t t0 = s->now;
    assert_true(co_lss_master_fastscan_filtered(&s->master, NULL, NULL, 0, found, 1));
    co_lss_master_result_t r = sim_wait(s);
    assert_int_equal(r.request, CO_LSS_REQ_FASTSCAN);
    assert_int_equal(r.status, CO_LSS_OK);
    assert_int_equal(r.found, 1);
    assert_memory_equal(&found[0].address, &low, sizeof low);
    assert_int_equal(found[0].node_id, 0);
    co_lss_fastscan_filter_t all = {{0}, {0}};
    uint8_t expected[LOG_MAX][8];
    uint32_t n = expected_fastscan(low, &all, expected, LOG_MAX);
    assert_int_equal(n, 1u + 128u + 2u);    /* the product and serial end with a 1-bit */
    assert_int_equal(r.frames, n);
    assert_log(s, expected, n);
    assert_int_equal(co_lss_slave_state(first), CO_LSS_STATE_CONFIGURATION);
    assert_int_equal(co_lss_slave_pending_node_id(first), CO_LSS_NODE_ID_UNCONFIGURED);
    assert_int_equal(co_lss_slave_state(second), CO_LSS_STATE_WAITING);
    assert_int_equal(co_lss_slave_state(configured), CO_LSS_STATE_WAITING);
    /* every unanswered check waited its whole timeout */
    assert_true(s->done_at - t0 >= (uint64_t)co_lss_master_stats(&s->master)->timeouts *
                                       TIMEOUT_MS * 1000u);
    /* the caller goes on with the selected slave: it answers as the one */
    assert_true(co_lss_master_configure_node_id(&s->master, 42));
    r = sim_wait(s);
    assert_int_equal(r.status, CO_LSS_OK);
    assert_int_equal(r.answers, 1);
    assert_int_equal(co_lss_slave_pending_node_id(first), 42);

    /* Its node resets communication: node-id 42 is active, `second` is the
     * one left to find; once it has a node-id too, nobody: the reset only. */
    assert_true(co_lss_master_switch_global(&s->master, CO_LSS_STATE_WAITING));
    sim_step(s, s->now);
    assert_int_equal(co_lss_slave_reset_communication(first), 42);
    assert_true(co_lss_master_fastscan_filtered(&s->master, NULL, NULL, 0, found, 1));
    r = sim_wait(s);
    assert_int_equal(r.found, 1);
    assert_int_equal(found[0].address.part[2], 0x00010003u);
    assert_int_equal(co_lss_slave_state(second), CO_LSS_STATE_CONFIGURATION);
    assert_true(co_lss_master_configure_node_id(&s->master, 43));
    (void)sim_wait(s);
    assert_true(co_lss_master_switch_global(&s->master, CO_LSS_STATE_WAITING));
    sim_step(s, s->now);
    assert_int_equal(co_lss_slave_reset_communication(second), 43);
    sim_log_clear(s);
    assert_true(co_lss_master_fastscan_filtered(&s->master, NULL, NULL, 0, found, 1));
    r = sim_wait(s);
    assert_int_equal(r.status, CO_LSS_OK);
    assert_int_equal(r.found, 0);
    assert_int_equal(r.frames, 1);
    sim_free(s);
}

/* Filters: a matched vendor-ID is checked with one frame; a skipped part
 * is jumped over (the part before names the one after it); a match nobody
 * has ends the scan at once, OK with nothing found. */
static void test_fastscan_filters(void **state)
{
    (void)state;
    sim_t *s = sim_new();
    co_lss_address_t want = addr(0x22u, 0x0000F00Du, 0x00050001u, 0x00000300u);
    co_lss_slave_t *other = sim_add(s, addr(0x11u, 0x0000F00Du, 0x00050001u, 0x00000100u),
                                    CO_LSS_NODE_ID_UNCONFIGURED);
    co_lss_slave_t *wanted = sim_add(s, want, CO_LSS_NODE_ID_UNCONFIGURED);
    co_lss_fastscan_filter_t filter = {{CO_LSS_FS_MATCH, CO_LSS_FS_SCAN, CO_LSS_FS_SKIP,
                                        CO_LSS_FS_SCAN}, {0x22u, 0, 0, 0}};
    co_lss_device_t found[1];
    sim_log_clear(s);
    assert_true(co_lss_master_fastscan_filtered(&s->master, &filter, NULL, 0, found, 1));
    co_lss_master_result_t r = sim_wait(s);
    assert_int_equal(r.status, CO_LSS_OK);
    assert_int_equal(r.found, 1);
    co_lss_address_t seen = {{0x22u, 0x0000F00Du, 0, 0x00000300u}};   /* revision skipped */
    assert_memory_equal(&found[0].address, &seen, sizeof seen);
    uint8_t expected[LOG_MAX][8];
    uint32_t n = expected_fastscan(want, &filter, expected, LOG_MAX);
    assert_int_equal(n, 1u + 1u + 64u + 1u);     /* reset, vendor, 2 x 32 bits, product's 1 */
    assert_log(s, expected, n);
    /* the vendor's one frame: its value, bit 0, part 0, next part 1 */
    const uint8_t vendor[8] = {0x51, 0x22, 0, 0, 0, 0, 0, 1};
    assert_request(&s->log[1], vendor);
    /* the product's bit-0 check names the serial (3): the revision is skipped */
    const uint8_t product_bit0[8] = {0x51, 0x0C, 0xF0, 0, 0, 0, 1, 3};
    assert_request(&s->log[33], product_bit0);
    assert_int_equal(co_lss_slave_state(wanted), CO_LSS_STATE_CONFIGURATION);
    assert_int_equal(co_lss_slave_state(other), CO_LSS_STATE_WAITING);

    /* A vendor nobody has: reset (answered by both), the match (silent), done. */
    assert_true(co_lss_master_switch_global(&s->master, CO_LSS_STATE_WAITING));
    sim_step(s, s->now);
    filter.match[0] = 0x33u;
    sim_log_clear(s);
    assert_true(co_lss_master_fastscan_filtered(&s->master, &filter, NULL, 0, found, 1));
    r = sim_wait(s);
    assert_int_equal(r.status, CO_LSS_OK);
    assert_int_equal(r.found, 0);
    assert_int_equal(r.frames, 2);
    const uint8_t vendor33[8] = {0x51, 0x33, 0, 0, 0, 0, 0, 1};
    assert_request(&s->log[1], vendor33);

    /* With node-ids: every slave of vendor 0x11 or 0x22 ... only 0x11 here:
     * it is configured, 0x22's slave (configured by nobody) stays as it is. */
    filter.match[0] = 0x11u;
    uint8_t ids[] = {5, 6};
    co_lss_device_t devices[2];
    assert_true(co_lss_master_fastscan_filtered(&s->master, &filter, ids, 2, devices, 2));
    r = sim_wait(s);
    assert_int_equal(r.status, CO_LSS_OK);
    assert_int_equal(r.found, 1);
    assert_int_equal(devices[0].node_id, 5);
    assert_int_equal(co_lss_slave_pending_node_id(other), 5);
    assert_int_equal(co_lss_slave_pending_node_id(wanted), CO_LSS_NODE_ID_UNCONFIGURED);

    /* Bad filters: the vendor-ID cannot be skipped, kinds are 0..2. */
    filter.kind[0] = CO_LSS_FS_SKIP;
    assert_false(co_lss_master_fastscan_filtered(&s->master, &filter, NULL, 0, found, 1));
    filter.kind[0] = CO_LSS_FS_SCAN;
    filter.kind[3] = 3;
    assert_false(co_lss_master_fastscan_filtered(&s->master, &filter, NULL, 0, found, 1));
    assert_false(co_lss_master_fastscan_filtered(&s->master, NULL, NULL, 0, found, 0));
    assert_false(co_lss_master_fastscan_filtered(&s->master, NULL, NULL, 1, found, 1));
    assert_false(co_lss_master_busy(&s->master));
    sim_free(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_services_on_the_wire),
        cmocka_unit_test(test_timeouts),
        cmocka_unit_test(test_answers_counted),
        cmocka_unit_test(test_fastscan_1),
        cmocka_unit_test(test_fastscan_2),
        cmocka_unit_test(test_fastscan_8),
        cmocka_unit_test(test_fastscan_32),
        cmocka_unit_test(test_fastscan_same_address),
        cmocka_unit_test(test_fastscan_runs_out),
        cmocka_unit_test(test_fastscan_slave_vanishes),
        cmocka_unit_test(test_scan),
        cmocka_unit_test(test_fastscan_late_slave),
        cmocka_unit_test(test_fastscan_slave_later_than_settle),
        cmocka_unit_test(test_fastscan_restarts),
        cmocka_unit_test(test_identify_counts_late_answers),
        cmocka_unit_test(test_fastscan_identify),
        cmocka_unit_test(test_fastscan_filters),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
