/* SRDO (co_srdo) and GFC (co_gfc) on the in-process bus with the fake
 * clock: p (index 1) produces SRDO 0x103/0x104, c (index 2) consumes it,
 * m (index 0) injects raw frames and the GFC. Every violation the consumer
 * checks is driven here and must end in the safe state naming it. */
#include "test_util.h"

#include "canopenfd/co_gfc.h"
#include "canopenfd/co_srdo.h"
#include "canopenfd/co_stack.h"

#define NORMAL 0x103u
#define INVERTED 0x104u
#define SCT_MS 20u
#define CONSUMER_SCT_MS 25u   /* the consumer allows the producer's cycle some slack */
#define SRVT_MS 5u
/* CRC-16/XMODEM of the two configurations' bytes, computed apart from the
 * core with Python's binascii.crc_hqx (see docs/protocol-notes.md, SRDO). */
#define PRODUCER_CRC 0xB7EEu
#define CONSUMER_CRC 0x8CC9u

typedef struct fx {
    tu_bus_t tb;
    tu_line_t l[3];
    co_line_t *m, *p, *c;
    co_srdo_t sp, sc;
    co_gfc_t gm, gc;
    co_srdo_violation_t why[8];
    uint64_t when[8];
    int events;
} fx_t;

static void on_safe(co_srdo_t *srdo, co_srdo_violation_t why, void *user)
{
    fx_t *fx = user;
    assert_ptr_equal(srdo, &fx->sc);
    assert_true(fx->events < 8);
    fx->why[fx->events] = why;
    fx->when[fx->events] = fx->tb.now;
    fx->events++;
}

static void on_gfc(co_gfc_t *gfc, void *user)
{
    fx_t *fx = user;
    assert_ptr_equal(gfc, &fx->gc);
    co_srdo_fail(&fx->sc, CO_SRDO_GFC);
}

static co_srdo_config_t config(uint8_t direction)
{
    co_srdo_config_t c;
    memset(&c, 0, sizeof c);
    c.direction = direction;
    c.sct_ms = direction == CO_SRDO_PRODUCE ? SCT_MS : CONSUMER_SCT_MS;
    c.srvt_ms = SRVT_MS;
    c.transmission_type = CO_SRDO_TRANSMISSION_TYPE;
    c.cob_id_normal = NORMAL;
    c.cob_id_inverted = INVERTED;
    c.map_count = 2;
    c.map[0] = 0x20000120u;   /* 4 bytes normal */
    c.map[1] = 0x20010120u;   /* 4 bytes inverted */
    return c;
}

static int setup(void **state)
{
    fx_t *fx = calloc(1, sizeof *fx);
    if (fx == NULL)
        return -1;
    tu_bus_init(&fx->tb, CO_MODE_CLASSIC, false);
    fx->m = tu_bus_add_line(&fx->tb, &fx->l[0]);
    fx->p = tu_bus_add_line(&fx->tb, &fx->l[1]);
    fx->c = tu_bus_add_line(&fx->tb, &fx->l[2]);
    co_srdo_init(&fx->sp, fx->p, NULL, NULL);
    co_srdo_init(&fx->sc, fx->c, on_safe, fx);
    co_gfc_init(&fx->gm, fx->m, NULL, NULL);
    co_gfc_init(&fx->gc, fx->c, on_gfc, fx);
    co_srdo_config_t pc = config(CO_SRDO_PRODUCE), cc = config(CO_SRDO_CONSUME);
    assert_true(co_srdo_configure(&fx->sp, &pc, CO_SRDO_CONFIG_VALID, PRODUCER_CRC));
    assert_true(co_srdo_configure(&fx->sc, &cc, CO_SRDO_CONFIG_VALID, CONSUMER_CRC));
    *state = fx;
    return 0;
}

static int teardown(void **state)
{
    fx_t *fx = *state;
    co_srdo_deinit(&fx->sp);
    co_srdo_deinit(&fx->sc);
    co_gfc_deinit(&fx->gm);
    co_gfc_deinit(&fx->gc);
    free(fx);
    return 0;
}

static void operational(fx_t *fx, co_srdo_t *srdo)
{
    co_line_set_time(srdo->line, fx->tb.now);
    co_srdo_set_nmt_state(srdo, CO_NMT_OPERATIONAL);
}

static void inject(fx_t *fx, uint32_t id, const uint8_t *data, uint8_t len, uint64_t at)
{
    tu_run_until(&fx->tb, at);
    assert_true(co_line_send(fx->m, id, data, len));
    tu_step(&fx->tb, at);
}

static const uint8_t good[4] = {0x12, 0x34, 0x56, 0x78};
static const uint8_t good_inv[4] = {0xED, 0xCB, 0xA9, 0x87};

static void inject_pair(fx_t *fx, uint64_t at)
{
    inject(fx, NORMAL, good, 4, at);
    inject(fx, INVERTED, good_inv, 4, at + 1 * TU_MS);
}

static void assert_safe(fx_t *fx, co_srdo_violation_t why, uint64_t at)
{
    uint8_t out[CO_SRDO_MAX_DATA];
    assert_int_equal(fx->events, 1);
    assert_int_equal(fx->why[0], why);
    assert_int_equal(fx->when[0], at);
    assert_int_equal(co_srdo_state(&fx->sc), CO_SRDO_SAFE);
    assert_int_equal(co_srdo_violation(&fx->sc), why);
    assert_int_equal(co_srdo_data(&fx->sc, out), 0);
}

/* ------------------------------------------------------ configuration */

static void test_crc_matches_independent_value(void **state)
{
    (void)state;
    co_srdo_config_t pc = config(CO_SRDO_PRODUCE), cc = config(CO_SRDO_CONSUME);
    assert_int_equal(co_srdo_crc(&pc), PRODUCER_CRC);
    assert_int_equal(co_srdo_crc(&cc), CONSUMER_CRC);
    pc.transmission_type = 0;            /* not part of the signature */
    assert_int_equal(co_srdo_crc(&pc), PRODUCER_CRC);
    pc.map[1] ^= 1u;
    assert_int_not_equal(co_srdo_crc(&pc), PRODUCER_CRC);
}

static void test_check_names_the_bad_parameter(void **state)
{
    (void)state;
    uint8_t length = 0;
    co_srdo_config_t c = config(CO_SRDO_CONSUME);
    assert_int_equal(co_srdo_check(&c, &length), CO_SRDO_PARAM_OK);
    assert_int_equal(length, 4);
    c = config(2); c.direction = 3;
    assert_int_equal(co_srdo_check(&c, NULL), CO_SRDO_PARAM_DIRECTION);
    c = config(2); c.sct_ms = 0;
    assert_int_equal(co_srdo_check(&c, NULL), CO_SRDO_PARAM_SCT);
    c = config(2); c.srvt_ms = 0;
    assert_int_equal(co_srdo_check(&c, NULL), CO_SRDO_PARAM_SRVT);
    c = config(2); c.transmission_type = 1;
    assert_int_equal(co_srdo_check(&c, NULL), CO_SRDO_PARAM_TRANSMISSION_TYPE);
    c = config(2); c.cob_id_normal = 0x104; c.cob_id_inverted = 0x105;
    assert_int_equal(co_srdo_check(&c, NULL), CO_SRDO_PARAM_COB_ID_NORMAL);
    c = config(2); c.cob_id_normal = 0x181; c.cob_id_inverted = 0x182;
    assert_int_equal(co_srdo_check(&c, NULL), CO_SRDO_PARAM_COB_ID_NORMAL);
    c = config(2); c.cob_id_inverted = 0x106;
    assert_int_equal(co_srdo_check(&c, NULL), CO_SRDO_PARAM_COB_ID_INVERTED);
    c = config(2); c.map_count = 3;
    assert_int_equal(co_srdo_check(&c, NULL), CO_SRDO_PARAM_MAP_COUNT);
    c = config(2); c.map_count = 0;
    assert_int_equal(co_srdo_check(&c, NULL), CO_SRDO_PARAM_MAP_COUNT);
    c = config(2); c.map[1] = 0x20010110u;       /* halves of 4 and 2 bytes */
    assert_int_equal(co_srdo_check(&c, NULL), CO_SRDO_PARAM_MAP_LENGTH);
    c = config(2); c.map[0] = 0x20000104u;       /* half a byte */
    assert_int_equal(co_srdo_check(&c, NULL), CO_SRDO_PARAM_MAP_LENGTH);
    c = config(2); c.map_count = 4; c.map[2] = 0x20020140u; c.map[3] = 0x20030140u;
    assert_int_equal(co_srdo_check(&c, NULL), CO_SRDO_PARAM_MAP_LENGTH);   /* 12 bytes */
    c = config(0); c.sct_ms = 0;                   /* off: nothing else matters */
    assert_int_equal(co_srdo_check(&c, NULL), CO_SRDO_PARAM_OK);
}

static void test_configure_refused_while_operational(void **state)
{
    fx_t *fx = *state;
    co_srdo_config_t cc = config(CO_SRDO_CONSUME);
    operational(fx, &fx->sc);
    assert_false(co_srdo_configure(&fx->sc, &cc, CO_SRDO_CONFIG_VALID, CONSUMER_CRC));
    co_srdo_set_nmt_state(&fx->sc, CO_NMT_PRE_OPERATIONAL);
    assert_true(co_srdo_configure(&fx->sc, &cc, CO_SRDO_CONFIG_VALID, CONSUMER_CRC));
}

/* ----------------------------------------------------- producer, wire */

static void test_producer_sends_pair_every_sct(void **state)
{
    fx_t *fx = *state;
    assert_true(co_srdo_set_data(&fx->sp, good, 4));
    assert_false(co_srdo_set_data(&fx->sp, good, 3));
    tu_run_until(&fx->tb, 100 * TU_MS);
    assert_int_equal(fx->tb.log_count, 0);          /* pre-operational: silent */
    operational(fx, &fx->sp);
    tu_run_until(&fx->tb, 100 * TU_MS + 3 * SCT_MS * TU_MS);
    assert_int_equal(fx->tb.log_count, 8);          /* at 0, 1, 2 and 3 SCT */
    for (size_t k = 0; k < 4; k++) {
        long n = tu_log_find_id(&fx->tb, NORMAL, k), i = tu_log_find_id(&fx->tb, INVERTED, k);
        tu_assert_logged(&fx->tb, n, NORMAL, good, 4);
        tu_assert_logged(&fx->tb, i, INVERTED, good_inv, 4);
        assert_int_equal(i, n + 1);                 /* the inverted one right after */
        assert_int_equal(fx->tb.log[n].t_us, 100 * TU_MS + k * SCT_MS * TU_MS);
        assert_int_equal(fx->tb.log[i].t_us, fx->tb.log[n].t_us);
    }
    assert_int_equal(co_srdo_stats(&fx->sp)->pairs_sent, 4);
}

static void test_consumer_takes_producer_pairs(void **state)
{
    fx_t *fx = *state;
    uint8_t out[CO_SRDO_MAX_DATA];
    static const uint8_t next[4] = {0, 0xFF, 0xA5, 1};
    assert_true(co_srdo_set_data(&fx->sp, good, 4));
    operational(fx, &fx->sc);
    operational(fx, &fx->sp);
    assert_int_equal(co_srdo_data(&fx->sc, out), 0);   /* nothing checked yet */
    assert_int_equal(co_srdo_state(&fx->sc), CO_SRDO_WAITING);
    tu_run_until(&fx->tb, 1 * TU_MS);
    assert_int_equal(co_srdo_data(&fx->sc, out), 4);
    assert_memory_equal(out, good, 4);
    assert_true(co_srdo_set_data(&fx->sp, next, 4));
    tu_run_until(&fx->tb, 1000 * TU_MS);
    assert_int_equal(co_srdo_data(&fx->sc, out), 4);
    assert_memory_equal(out, next, 4);
    assert_int_equal(co_srdo_state(&fx->sc), CO_SRDO_RUNNING);
    assert_int_equal(co_srdo_stats(&fx->sc)->pairs_valid, 51);
    assert_int_equal(fx->events, 0);
}

/* ------------------------------------------------------- violations */

static void test_inverted_mismatch(void **state)
{
    fx_t *fx = *state;
    static const uint8_t bad_inv[4] = {0xED, 0xCB, 0xA9, 0x86};
    operational(fx, &fx->sc);
    inject_pair(fx, 10 * TU_MS);
    assert_int_equal(co_srdo_state(&fx->sc), CO_SRDO_RUNNING);
    inject(fx, NORMAL, good, 4, 30 * TU_MS);
    inject(fx, INVERTED, bad_inv, 4, 31 * TU_MS);
    assert_safe(fx, CO_SRDO_INVERTED_MISMATCH, 31 * TU_MS);
    /* the line goes on: frames after it are counted, never block anything */
    inject_pair(fx, 40 * TU_MS);
    assert_int_equal(co_srdo_stats(&fx->sc)->ignored, 2);
    tu_run_until(&fx->tb, 500 * TU_MS);
    assert_int_equal(fx->events, 1);                   /* latched: told once */
}

static void test_srvt_exceeded_without_inverted(void **state)
{
    fx_t *fx = *state;
    operational(fx, &fx->sc);
    inject(fx, NORMAL, good, 4, 10 * TU_MS);
    tu_run_until(&fx->tb, 10 * TU_MS + SRVT_MS * TU_MS);
    assert_int_equal(fx->events, 0);
    tu_run_until(&fx->tb, 100 * TU_MS);
    assert_safe(fx, CO_SRDO_SRVT_EXCEEDED, 10 * TU_MS + SRVT_MS * TU_MS + 1);
}

/* A frame that waited in the consumer's rx queue and is handled at `at`
 * (rx runs before the timers in a line's turn). */
static void deliver_late(fx_t *fx, uint32_t id, const uint8_t *data, uint64_t at)
{
    co_frame_t f = tu_frame(id, 0, data, 4);
    assert_true(co_line_receive(fx->c, &f));
    fx->tb.now = at;
    (void)co_line_process(fx->c, at);
}

static void test_late_inverted_judged_on_arrival(void **state)
{
    fx_t *fx = *state;
    co_line_set_time(fx->c, 0);
    co_srdo_set_nmt_state(&fx->sc, CO_NMT_OPERATIONAL);
    deliver_late(fx, NORMAL, good, 1 * TU_MS);
    deliver_late(fx, INVERTED, good_inv, 1 * TU_MS + SRVT_MS * TU_MS + 1);
    assert_safe(fx, CO_SRDO_SRVT_EXCEEDED, fx->tb.now);
}

static void test_inverted_in_time_at_srvt_edge(void **state)
{
    fx_t *fx = *state;
    uint8_t out[CO_SRDO_MAX_DATA];
    operational(fx, &fx->sc);
    inject(fx, NORMAL, good, 4, 10 * TU_MS);
    inject(fx, INVERTED, good_inv, 4, 10 * TU_MS + SRVT_MS * TU_MS);
    assert_int_equal(fx->events, 0);
    assert_int_equal(co_srdo_data(&fx->sc, out), 4);
}

static void test_missing_inverted(void **state)
{
    fx_t *fx = *state;
    operational(fx, &fx->sc);
    inject(fx, NORMAL, good, 4, 10 * TU_MS);
    inject(fx, NORMAL, good, 4, 12 * TU_MS);
    assert_safe(fx, CO_SRDO_INVERTED_MISSING, 12 * TU_MS);
}

static void test_inverted_without_normal(void **state)
{
    fx_t *fx = *state;
    operational(fx, &fx->sc);
    inject(fx, INVERTED, good_inv, 4, 10 * TU_MS);
    assert_safe(fx, CO_SRDO_INVERTED_UNEXPECTED, 10 * TU_MS);
}

static void test_sct_exceeded_after_pairs(void **state)
{
    fx_t *fx = *state;
    operational(fx, &fx->sc);
    inject_pair(fx, 10 * TU_MS);
    inject_pair(fx, 30 * TU_MS);
    tu_run_until(&fx->tb, 30 * TU_MS + CONSUMER_SCT_MS * TU_MS);
    assert_int_equal(fx->events, 0);
    tu_run_until(&fx->tb, 200 * TU_MS);
    assert_safe(fx, CO_SRDO_SCT_EXCEEDED, 30 * TU_MS + CONSUMER_SCT_MS * TU_MS + 1);
}

static void test_sct_exceeded_without_first_pair(void **state)
{
    fx_t *fx = *state;
    operational(fx, &fx->sc);
    tu_run_until(&fx->tb, 200 * TU_MS);
    assert_safe(fx, CO_SRDO_SCT_EXCEEDED, CONSUMER_SCT_MS * TU_MS + 1);
}

static void test_late_normal_judged_on_arrival(void **state)
{
    fx_t *fx = *state;
    co_line_set_time(fx->c, 0);
    co_srdo_set_nmt_state(&fx->sc, CO_NMT_OPERATIONAL);
    deliver_late(fx, NORMAL, good, CONSUMER_SCT_MS * TU_MS + 1);
    assert_safe(fx, CO_SRDO_SCT_EXCEEDED, fx->tb.now);
}

static void test_wrong_length_normal(void **state)
{
    fx_t *fx = *state;
    operational(fx, &fx->sc);
    inject(fx, NORMAL, good, 3, 10 * TU_MS);
    assert_safe(fx, CO_SRDO_WRONG_LENGTH, 10 * TU_MS);
}

static void test_wrong_length_inverted(void **state)
{
    fx_t *fx = *state;
    static const uint8_t long_inv[5] = {0xED, 0xCB, 0xA9, 0x87, 0xFF};
    operational(fx, &fx->sc);
    inject(fx, NORMAL, good, 4, 10 * TU_MS);
    inject(fx, INVERTED, long_inv, 5, 11 * TU_MS);
    assert_safe(fx, CO_SRDO_WRONG_LENGTH, 11 * TU_MS);
}

static void test_crc_mismatch_never_runs(void **state)
{
    fx_t *fx = *state;
    co_srdo_config_t pc = config(CO_SRDO_PRODUCE), cc = config(CO_SRDO_CONSUME);
    co_srdo_deinit(&fx->sp);
    co_srdo_init(&fx->sp, fx->p, NULL, NULL);
    assert_true(co_srdo_configure(&fx->sp, &pc, CO_SRDO_CONFIG_VALID, PRODUCER_CRC ^ 1u));
    assert_true(co_srdo_configure(&fx->sc, &cc, CO_SRDO_CONFIG_VALID, CONSUMER_CRC ^ 0x100u));
    operational(fx, &fx->sp);
    operational(fx, &fx->sc);
    assert_int_equal(co_srdo_state(&fx->sp), CO_SRDO_SAFE);
    assert_int_equal(co_srdo_violation(&fx->sp), CO_SRDO_CRC_MISMATCH);
    assert_safe(fx, CO_SRDO_CRC_MISMATCH, 0);
    tu_run_until(&fx->tb, 100 * TU_MS);
    assert_int_equal(fx->tb.log_count, 0);              /* the producer sent nothing */
    inject_pair(fx, 110 * TU_MS);
    assert_int_equal(co_srdo_stats(&fx->sc)->pairs_valid, 0);
}

static void test_config_not_valid_never_runs(void **state)
{
    fx_t *fx = *state;
    co_srdo_config_t cc = config(CO_SRDO_CONSUME);
    assert_true(co_srdo_configure(&fx->sc, &cc, 0x00, CONSUMER_CRC));
    operational(fx, &fx->sc);
    assert_safe(fx, CO_SRDO_CONFIG_INVALID, 0);
    cc.sct_ms = 0;
    co_srdo_set_nmt_state(&fx->sc, CO_NMT_PRE_OPERATIONAL);
    assert_true(co_srdo_configure(&fx->sc, &cc, CO_SRDO_CONFIG_VALID, co_srdo_crc(&cc)));
    operational(fx, &fx->sc);
    assert_int_equal(fx->events, 2);
    assert_int_equal(fx->why[1], CO_SRDO_BAD_PARAMETER);
}

static void test_gfc_enters_safe_state_at_once(void **state)
{
    fx_t *fx = *state;
    assert_false(co_gfc_send(&fx->gm));                 /* 0x1300 = 0: off */
    assert_int_equal(fx->gm.stats.send_refused, 1);
    assert_true(co_gfc_set_enabled(&fx->gm, true));
    assert_true(co_gfc_set_enabled(&fx->gc, true));
    operational(fx, &fx->sc);
    inject_pair(fx, 10 * TU_MS);
    /* a frame on 0x001 with data is no GFC */
    inject(fx, CO_GFC_COB_ID, good, 1, 12 * TU_MS);
    assert_int_equal(fx->gc.stats.bad_length, 1);
    assert_int_equal(fx->events, 0);
    tu_log_clear(&fx->tb);
    tu_run_until(&fx->tb, 15 * TU_MS);
    assert_true(co_gfc_send(&fx->gm));
    tu_step(&fx->tb, 15 * TU_MS);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, CO_GFC_COB_ID, 0), CO_GFC_COB_ID, NULL, 0);
    assert_safe(fx, CO_SRDO_GFC, 15 * TU_MS);
    assert_int_equal(fx->gc.stats.received, 1);
}

static void test_restart_after_safe_state(void **state)
{
    fx_t *fx = *state;
    uint8_t out[CO_SRDO_MAX_DATA];
    operational(fx, &fx->sc);
    inject(fx, INVERTED, good_inv, 4, 10 * TU_MS);
    assert_safe(fx, CO_SRDO_INVERTED_UNEXPECTED, 10 * TU_MS);
    co_line_set_time(fx->c, 20 * TU_MS);
    co_srdo_restart(&fx->sc);
    assert_int_equal(co_srdo_state(&fx->sc), CO_SRDO_WAITING);
    assert_int_equal(co_srdo_violation(&fx->sc), CO_SRDO_NONE);
    inject_pair(fx, 30 * TU_MS);
    assert_int_equal(co_srdo_data(&fx->sc, out), 4);
    co_srdo_set_nmt_state(&fx->sc, CO_NMT_PRE_OPERATIONAL);
    assert_int_equal(co_srdo_state(&fx->sc), CO_SRDO_STOPPED);
    assert_int_equal(co_srdo_data(&fx->sc, out), 0);
}

static void test_producer_tx_full(void **state)
{
    fx_t *fx = *state;
    size_t k = 0;
    while (co_line_tx_room(fx->p) > 1) {
        assert_true(co_line_send(fx->p, 0x300, good, 1));
        k++;
    }
    assert_true(k > 0);
    co_srdo_fail(&fx->sp, CO_SRDO_NONE);                /* no reason: nothing happens */
    assert_int_equal(co_srdo_state(&fx->sp), CO_SRDO_STOPPED);
    co_srdo_fail(&fx->sp, CO_SRDO_APPLICATION);
    assert_int_equal(co_srdo_state(&fx->sp), CO_SRDO_SAFE);
    assert_int_equal(co_srdo_violation(&fx->sp), CO_SRDO_APPLICATION);
    co_line_set_time(fx->p, 0);
    co_srdo_set_nmt_state(&fx->sp, CO_NMT_OPERATIONAL);
    (void)co_line_process(fx->p, 0);
    assert_int_equal(co_srdo_violation(&fx->sp), CO_SRDO_TX_FAILED);
    assert_int_equal(co_srdo_stats(&fx->sp)->pairs_sent, 0);
}

/* ------------------------------------------------ in the node assembly */

typedef struct stack_fx {
    co_stack_t stack;
    co_stack_arena_t arena;
    unsigned char memory[32 * 1024];
    co_srdo_t *told[4];
    co_srdo_violation_t why[4];
    int events;
} stack_fx_t;

static void on_stack_safe(co_srdo_t *srdo, co_srdo_violation_t why, void *user)
{
    stack_fx_t *sf = user;
    assert_true(sf->events < 4);
    sf->told[sf->events] = srdo;
    sf->why[sf->events++] = why;
}

static void nmt(fx_t *fx, uint8_t command, uint8_t node, uint64_t at)
{
    const uint8_t data[2] = {command, node};
    inject(fx, 0x000, data, 2, at);
}

/* A stack on line c (the fixture's consumer and GFC there are gone), no node yet. */
static stack_fx_t *stack_on_line_c(fx_t *fx)
{
    stack_fx_t *sf = calloc(1, sizeof *sf);
    assert_non_null(sf);
    co_srdo_deinit(&fx->sc);
    co_gfc_deinit(&fx->gc);
    co_stack_arena_init(&sf->arena, sf->memory, sizeof sf->memory);
    co_stack_line_config_t lc = {0};
    assert_int_equal(co_stack_init(&sf->stack, fx->c, &lc, co_stack_arena_allocator(&sf->arena)),
                     CO_STACK_OK);
    return sf;
}

/* co_stack runs the SRDOs with the node's NMT state and hands a GFC to every
 * one of them; the memory goes back with the node. */
static void test_stack_wires_nmt_and_gfc(void **state)
{
    fx_t *fx = *state;
    stack_fx_t *sf = stack_on_line_c(fx);
    co_stack_node_config_t nc = {.node_id = 7};
    assert_int_equal(co_stack_srdo_init(&sf->stack, 2, on_stack_safe, sf), CO_STACK_ERR_STATE);
    assert_int_equal(co_stack_failed_part(&sf->stack), CO_STACK_PART_SRDO);
    assert_int_equal(co_stack_node_init(&sf->stack, &nc), CO_STACK_OK);
    assert_int_equal(co_stack_boot(&sf->stack), CO_STACK_OK);
    size_t before = sf->arena.used;
    assert_int_equal(co_stack_srdo_init(&sf->stack, 0, NULL, NULL), CO_STACK_ERR_ARGUMENT);
    assert_int_equal(co_stack_srdo_init(&sf->stack, 2, on_stack_safe, sf), CO_STACK_OK);
    assert_null(co_stack_srdo(&sf->stack, 3));
    co_srdo_t *one = co_stack_srdo(&sf->stack, 1), *two = co_stack_srdo(&sf->stack, 2);
    co_srdo_config_t c1 = config(CO_SRDO_CONSUME), c2 = config(CO_SRDO_CONSUME);
    c2.cob_id_normal = 0x105;
    c2.cob_id_inverted = 0x106;
    assert_true(co_srdo_configure(one, &c1, CO_SRDO_CONFIG_VALID, co_srdo_crc(&c1)));
    assert_true(co_srdo_configure(two, &c2, CO_SRDO_CONFIG_VALID, co_srdo_crc(&c2)));
    assert_true(co_gfc_set_enabled(co_stack_gfc(&sf->stack), true));
    assert_true(co_gfc_set_enabled(&fx->gm, true));
    assert_int_equal(co_srdo_state(one), CO_SRDO_STOPPED);     /* pre-operational */
    nmt(fx, 0x01, 7, 1 * TU_MS);                                /* start remote node */
    assert_int_equal(co_srdo_state(one), CO_SRDO_WAITING);
    assert_int_equal(co_srdo_state(two), CO_SRDO_WAITING);
    inject_pair(fx, 2 * TU_MS);
    assert_int_equal(co_srdo_state(one), CO_SRDO_RUNNING);
    assert_true(co_gfc_send(&fx->gm));
    tu_step(&fx->tb, 4 * TU_MS);
    assert_int_equal(sf->events, 2);
    assert_ptr_equal(sf->told[0], one);
    assert_ptr_equal(sf->told[1], two);
    assert_int_equal(sf->why[0], CO_SRDO_GFC);
    assert_int_equal(sf->why[1], CO_SRDO_GFC);
    nmt(fx, 0x80, 7, 5 * TU_MS);                                /* pre-operational */
    assert_int_equal(co_srdo_state(one), CO_SRDO_STOPPED);
    nmt(fx, 0x01, 7, 6 * TU_MS);                                /* starts over */
    assert_int_equal(co_srdo_state(one), CO_SRDO_WAITING);
    co_stack_node_deinit(&sf->stack);
    assert_null(co_stack_srdo(&sf->stack, 1));
    assert_true(sf->arena.used <= before);
    co_stack_deinit(&sf->stack);
    free(sf);
}

/* The k-th EMCY of node 7 (0x87) since the log was cleared is `data`. */
static void assert_emcy(fx_t *fx, size_t k, const uint8_t data[8])
{
    assert_true(tu_log_count_id(&fx->tb, 0x87) > k);
    tu_assert_logged(&fx->tb, tu_log_find_id(&fx->tb, 0x87, k), 0x87, data, 8);
}

/* A stack on line c with node 7 booted and two consumer SRDOs: SRDO 1 on
 * 0x103/0x104, SRDO 2 on 0x105/0x106 (signed right unless told), GFC on. */
static stack_fx_t *stack_with_two_consumers(fx_t *fx, bool two_signed)
{
    stack_fx_t *sf = stack_on_line_c(fx);
    co_stack_node_config_t nc = {.node_id = 7};
    assert_int_equal(co_stack_node_init(&sf->stack, &nc), CO_STACK_OK);
    assert_int_equal(co_stack_boot(&sf->stack), CO_STACK_OK);
    assert_int_equal(co_stack_srdo_init(&sf->stack, 2, on_stack_safe, sf), CO_STACK_OK);
    co_srdo_t *one = co_stack_srdo(&sf->stack, 1), *two = co_stack_srdo(&sf->stack, 2);
    co_srdo_config_t c1 = config(CO_SRDO_CONSUME), c2 = config(CO_SRDO_CONSUME);
    c2.cob_id_normal = 0x105;
    c2.cob_id_inverted = 0x106;
    uint16_t crc2 = two_signed ? co_srdo_crc(&c2) : (uint16_t)~co_srdo_crc(&c2);
    assert_true(co_srdo_configure(one, &c1, CO_SRDO_CONFIG_VALID, co_srdo_crc(&c1)));
    assert_true(co_srdo_configure(two, &c2, CO_SRDO_CONFIG_VALID, crc2));
    assert_true(co_gfc_set_enabled(co_stack_gfc(&sf->stack), true));
    assert_true(co_gfc_set_enabled(&fx->gm, true));
    tu_run_until(&fx->tb, 1 * TU_MS);
    tu_log_clear(&fx->tb);
    return sf;
}

static void stack_done(stack_fx_t *sf)
{
    co_stack_node_deinit(&sf->stack);
    co_stack_deinit(&sf->stack);
    free(sf);
}

/* A stack's SRDO in the safe state is an active EMCY error (CiA 301): its
 * EMCY once (code of the violation, SRDO number and violation in bytes 3
 * and 4), 0x1001 and 0x1003 show it while it lasts; leaving the safe state
 * sends the error reset (0x0000, the register left, the same bytes 3/4).
 * A start that fails again at once sends nothing; a GFC is a command and
 * no error. */
static void test_stack_safe_state_is_an_active_emcy_error(void **state)
{
    fx_t *fx = *state;
    stack_fx_t *sf = stack_with_two_consumers(fx, false);
    co_emcy_t *emcy = co_stack_emcy(&sf->stack);
    co_srdo_t *one = co_stack_srdo(&sf->stack, 1), *two = co_stack_srdo(&sf->stack, 2);
    nmt(fx, 0x01, 7, 2 * TU_MS);               /* SRDO 2: its signature is wrong */
    tu_run_until(&fx->tb, 3 * TU_MS);
    const uint8_t crc[8] = {0x00, 0x63, 0x01, 2, CO_SRDO_CRC_MISMATCH, 0, 0, 0};
    assert_emcy(fx, 0, crc);
    assert_int_equal(co_emcy_error_register(emcy), 0x01);
    inject_pair(fx, 4 * TU_MS);                 /* SRDO 1 runs, then its pairs stop */
    tu_run_until(&fx->tb, 40 * TU_MS);
    const uint8_t sct[8] = {0x00, 0x82, 0x11, 1, CO_SRDO_SCT_EXCEEDED, 0, 0, 0};
    assert_emcy(fx, 1, sct);
    assert_int_equal(co_emcy_error_register(emcy), 0x11);   /* generic + communication */
    assert_int_equal(co_emcy_active_count(emcy), 2);
    assert_int_equal(emcy->history_count, 2);               /* 0x1003, newest first */
    assert_int_equal(emcy->history[0], 0x03018200u);
    assert_int_equal(emcy->history[1], 0x08026300u);
    co_srdo_restart(two);                       /* fails again at once: still the error */
    assert_int_equal(co_srdo_state(two), CO_SRDO_SAFE);
    assert_int_equal(sf->events, 3);
    co_srdo_restart(one);                       /* SRDO 1's error is over */
    assert_int_equal(co_srdo_state(one), CO_SRDO_WAITING);
    tu_run_until(&fx->tb, 41 * TU_MS);
    const uint8_t reset_one[8] = {0x00, 0x00, 0x01, 1, CO_SRDO_SCT_EXCEEDED, 0, 0, 0};
    assert_int_equal(tu_log_count_id(&fx->tb, 0x87), 3);
    assert_emcy(fx, 2, reset_one);
    assert_int_equal(co_emcy_error_register(emcy), 0x01);   /* SRDO 2's is left */
    assert_true(co_gfc_send(&fx->gm));          /* SRDO 1 safe by command: no error */
    tu_run_until(&fx->tb, 45 * TU_MS);
    assert_int_equal(sf->events, 4);
    assert_int_equal(sf->why[3], CO_SRDO_GFC);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x87), 3);
    nmt(fx, 0x80, 7, 46 * TU_MS);               /* leaving operational ends SRDO 2's */
    tu_run_until(&fx->tb, 47 * TU_MS);
    const uint8_t reset_two[8] = {0x00, 0x00, 0x00, 2, CO_SRDO_CRC_MISMATCH, 0, 0, 0};
    assert_int_equal(tu_log_count_id(&fx->tb, 0x87), 4);   /* none for SRDO 1's GFC */
    assert_emcy(fx, 3, reset_two);
    assert_int_equal(co_emcy_error_register(emcy), 0x00);
    assert_int_equal(co_emcy_active_count(emcy), 0);
    assert_int_equal(emcy->history_count, 2);   /* the history keeps what occurred */
    stack_done(sf);
}

/* Two SRDOs failing with the same code are two errors: two EMCYs, and each
 * has its own reset; a reset communication ends both (the SRDOs stop with
 * the node leaving operational; their resets go out in pre-operational), so
 * does taking the SRDOs away. */
static void test_stack_same_code_two_srdos_and_reset_communication(void **state)
{
    fx_t *fx = *state;
    stack_fx_t *sf = stack_with_two_consumers(fx, true);
    co_emcy_t *emcy = co_stack_emcy(&sf->stack);
    nmt(fx, 0x01, 7, 2 * TU_MS);
    tu_run_until(&fx->tb, 40 * TU_MS);          /* no pairs: both exceed their SCT */
    const uint8_t sct1[8] = {0x00, 0x82, 0x11, 1, CO_SRDO_SCT_EXCEEDED, 0, 0, 0};
    const uint8_t sct2[8] = {0x00, 0x82, 0x11, 2, CO_SRDO_SCT_EXCEEDED, 0, 0, 0};
    assert_int_equal(tu_log_count_id(&fx->tb, 0x87), 2);
    assert_emcy(fx, 0, sct1);
    assert_emcy(fx, 1, sct2);
    assert_int_equal(co_emcy_active_count(emcy), 2);
    assert_false(co_emcy_is_active(emcy, 0x8200, 0));   /* not the application's */
    nmt(fx, 0x82, 7, 41 * TU_MS);               /* reset communication */
    tu_run_until(&fx->tb, 45 * TU_MS);
    const uint8_t reset1[8] = {0x00, 0x00, 0x11, 1, CO_SRDO_SCT_EXCEEDED, 0, 0, 0};
    const uint8_t reset2[8] = {0x00, 0x00, 0x00, 2, CO_SRDO_SCT_EXCEEDED, 0, 0, 0};
    assert_int_equal(tu_log_count_id(&fx->tb, 0x87), 4);
    assert_emcy(fx, 2, reset1);
    assert_emcy(fx, 3, reset2);
    long boot_up = tu_log_find_id(&fx->tb, 0x707, 0);
    assert_true(boot_up >= 0 && boot_up < tu_log_find_id(&fx->tb, 0x87, 2));
    assert_int_equal(co_emcy_error_register(emcy), 0x00);
    assert_int_equal(co_srdo_state(co_stack_srdo(&sf->stack, 1)), CO_SRDO_STOPPED);
    /* SRDOs taken away while safe: nothing is left to end their errors */
    nmt(fx, 0x01, 7, 46 * TU_MS);
    tu_run_until(&fx->tb, 80 * TU_MS);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x87), 6);
    assert_int_equal(co_emcy_active_count(emcy), 2);
    co_stack_srdo_deinit(&sf->stack);
    tu_run_until(&fx->tb, 81 * TU_MS);
    assert_int_equal(co_emcy_active_count(emcy), 0);
    assert_int_equal(tu_log_count_id(&fx->tb, 0x87), 8);
    assert_emcy(fx, 7, reset2);
    stack_done(sf);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_crc_matches_independent_value),
        cmocka_unit_test(test_check_names_the_bad_parameter),
#define T(name) cmocka_unit_test_setup_teardown(name, setup, teardown)
        T(test_configure_refused_while_operational),
        T(test_producer_sends_pair_every_sct),
        T(test_consumer_takes_producer_pairs),
        T(test_inverted_mismatch),
        T(test_srvt_exceeded_without_inverted),
        T(test_late_inverted_judged_on_arrival),
        T(test_inverted_in_time_at_srvt_edge),
        T(test_missing_inverted),
        T(test_inverted_without_normal),
        T(test_sct_exceeded_after_pairs),
        T(test_sct_exceeded_without_first_pair),
        T(test_late_normal_judged_on_arrival),
        T(test_wrong_length_normal),
        T(test_wrong_length_inverted),
        T(test_crc_mismatch_never_runs),
        T(test_config_not_valid_never_runs),
        T(test_gfc_enters_safe_state_at_once),
        T(test_restart_after_safe_state),
        T(test_producer_tx_full),
        T(test_stack_wires_nmt_and_gfc),
        T(test_stack_safe_state_is_an_active_emcy_error),
        T(test_stack_same_code_two_srdos_and_reset_communication),
#undef T
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
