/* libFuzzer harness: the SRDO consumer's pair checks and the producer, with
 * the GFC. Line P produces SRDO 0x103/0x104, line C consumes it; every frame
 * P sends is carried to C, and the input adds frames of its own to C (on
 * 0x103, 0x104, 0x001 or raw ids), lets time pass, switches the NMT state,
 * reconfigures either side with input values, restarts, sets data and sends
 * GFCs. First input byte bit 0: classic or fd lines.
 *
 * Checks after every record: the state and the violation agree (SAFE with a
 * reason, NONE otherwise); a
 * consumer gives data only while RUNNING and never more than its length; an
 * SRDO that is not running has no timer armed; every pair P sends is the
 * normal frame on the normal COB-ID immediately followed by its exact
 * bit-inverse on the next COB-ID, both of the configured length. */
#include "fuzz_input.h"

#include "canopenfd/co_gfc.h"
#include "canopenfd/co_srdo.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { SLOTS = 64 };

typedef struct srdo_world {
    co_line_t p, c;
    co_frame_t p_rx[SLOTS], p_tx[SLOTS], c_rx[SLOTS], c_tx[SLOTS];
    co_srdo_t sp, sc;
    co_gfc_t gp, gc;
    uint64_t now;
} srdo_world_t;

static srdo_world_t W;
static const uint32_t ids[] = {0x103, 0x104, 0x001, 0x105, 0x102};

static void fail(const char *what)
{
    fprintf(stderr, "fuzz invariant broken: %s\n", what);
    abort();
}

static void line_init(co_line_t *line, co_mode_t mode, co_frame_t *rx, co_frame_t *tx)
{
    co_line_config_t cfg;
    memset(&cfg, 0, sizeof cfg);
    cfg.mode = mode;
    cfg.rx_slots = rx;
    cfg.rx_capacity = SLOTS;
    cfg.tx_slots = tx;
    cfg.tx_capacity = SLOTS;
    if (!co_line_init(line, &cfg)) {
        fail("line init");
    }
}

static co_srdo_config_t base_config(uint8_t direction)
{
    co_srdo_config_t c;
    memset(&c, 0, sizeof c);
    c.direction = direction;
    c.sct_ms = direction == CO_SRDO_PRODUCE ? 20 : 30;
    c.srvt_ms = 5;
    c.transmission_type = CO_SRDO_TRANSMISSION_TYPE;
    c.cob_id_normal = 0x103;
    c.cob_id_inverted = 0x104;
    c.map_count = 2;
    c.map[0] = 0x20000120u;
    c.map[1] = 0x20010120u;
    return c;
}

static void on_gfc(co_gfc_t *gfc, void *user)
{
    (void)gfc;
    co_srdo_fail(user, CO_SRDO_GFC);
}

/* P's frames go to C, checked as pairs on the way. */
static void carry(void)
{
    co_frame_t f, inv;
    while (co_line_tx_pop(&W.p, &f)) {
        if (f.id == W.sp.config.cob_id_normal && W.sp.config.direction == CO_SRDO_PRODUCE) {
            if (!co_line_tx_pop(&W.p, &inv) || inv.id != W.sp.config.cob_id_inverted ||
                inv.len != f.len || f.len != W.sp.length) {
                fail("a normal frame not followed by its inverted frame of the same length");
            }
            for (uint8_t i = 0; i < f.len; i++) {
                if ((f.data[i] ^ inv.data[i]) != 0xFFu) {
                    fail("the inverted frame is not the complement");
                }
            }
            (void)co_line_receive(&W.c, &f);
            (void)co_line_receive(&W.c, &inv);
        } else {
            (void)co_line_receive(&W.c, &f);
        }
    }
    co_frame_t drop;
    while (co_line_tx_pop(&W.c, &drop)) {
    }
}

static void process(void)
{
    (void)co_line_process(&W.p, W.now);
    carry();
    (void)co_line_process(&W.c, W.now);
    carry();
}

static void check(const co_srdo_t *s)
{
    uint8_t out[CO_SRDO_MAX_DATA];
    co_srdo_state_t st = co_srdo_state(s);
    if (st > CO_SRDO_SAFE || s->length > CO_SRDO_MAX_DATA) {
        fail("state or length out of range");
    }
    if ((st == CO_SRDO_SAFE) != (co_srdo_violation(s) != CO_SRDO_NONE)) {
        fail("the violation does not match the state");
    }
    size_t n = co_srdo_data(s, out);
    if (n > s->length || (n > 0 && st != CO_SRDO_RUNNING)) {
        fail("data given out while not running");
    }
    bool running = st == CO_SRDO_WAITING || st == CO_SRDO_RUNNING;
    if (!running && (co_timer_is_armed(&s->cycle_timer) || co_timer_is_armed(&s->srvt_timer))) {
        fail("a timer armed while not running");
    }
}

static void configure(fz_reader_t *r, co_srdo_t *s, uint8_t direction)
{
    co_srdo_config_t c = base_config(direction);
    uint8_t what = fz_u8(r);
    if (what & 1u) {
        c.sct_ms = fz_u16(r);
    }
    if (what & 2u) {
        c.srvt_ms = fz_u8(r);
    }
    if (what & 4u) {
        c.map_count = fz_u8(r);
        for (uint8_t i = 0; i < CO_SRDO_MAX_MAPPED; i++) {
            c.map[i] = 0x20000000u | fz_u8(r);
        }
    }
    if (what & 8u) {
        c.direction = fz_u8(r);
    }
    uint8_t valid = (what & 16u) ? fz_u8(r) : CO_SRDO_CONFIG_VALID;
    uint16_t crc = co_srdo_crc(&c) ^ ((what & 32u) ? fz_u16(r) : 0u);
    (void)co_srdo_configure(s, &c, valid, crc);
}

static void act(fz_reader_t *r, uint8_t p)
{
    co_srdo_t *s = (p & 1u) ? &W.sp : &W.sc;
    co_line_set_time(&W.p, W.now);
    co_line_set_time(&W.c, W.now);
    switch ((p >> 1) % 7) {
    case 0:
        co_srdo_set_nmt_state(s, (fz_u8(r) & 1u) ? CO_NMT_OPERATIONAL : CO_NMT_PRE_OPERATIONAL);
        break;
    case 1:
        configure(r, s, s == &W.sp ? CO_SRDO_PRODUCE : CO_SRDO_CONSUME);
        break;
    case 2: {
        uint8_t data[CO_SRDO_MAX_DATA];
        fz_bytes(r, data, sizeof data);
        (void)co_srdo_set_data(s, data, fz_u8(r) % (CO_SRDO_MAX_DATA + 1));
        break;
    }
    case 3:
        co_srdo_restart(s);
        break;
    case 4:
        (void)co_gfc_set_enabled((p & 1u) ? &W.gp : &W.gc, fz_u8(r) & 1u);
        break;
    case 5:
        (void)co_gfc_send((p & 1u) ? &W.gp : &W.gc);
        break;
    default:
        co_srdo_fail(s, (co_srdo_violation_t)(fz_u8(r) % (CO_SRDO_APPLICATION + 1)));
        break;
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size == 0) {
        return 0;
    }
    co_mode_t mode = (data[0] & 1u) ? CO_MODE_CLASSIC : CO_MODE_FD;
    memset(&W, 0, sizeof W);
    line_init(&W.p, mode, W.p_rx, W.p_tx);
    line_init(&W.c, mode, W.c_rx, W.c_tx);
    co_srdo_init(&W.sp, &W.p, NULL, NULL);
    co_srdo_init(&W.sc, &W.c, NULL, NULL);
    co_gfc_init(&W.gp, &W.p, NULL, NULL);
    co_gfc_init(&W.gc, &W.c, on_gfc, &W.sc);
    co_srdo_config_t pc = base_config(CO_SRDO_PRODUCE), cc = base_config(CO_SRDO_CONSUME);
    (void)co_srdo_configure(&W.sp, &pc, CO_SRDO_CONFIG_VALID, co_srdo_crc(&pc));
    (void)co_srdo_configure(&W.sc, &cc, CO_SRDO_CONFIG_VALID, co_srdo_crc(&cc));
    fz_reader_t r;
    fz_reader_init(&r, data + 1, size - 1);
    fz_record_t rec;
    while (fz_next(&r, &rec, ids, sizeof ids / sizeof ids[0], mode)) {
        switch (rec.op) {
        case FZ_OP_FRAME:
        case FZ_OP_FRAME2:
            (void)co_line_receive(rec.alt ? &W.p : &W.c, &rec.frame);
            break;
        case FZ_OP_TIME: {
            /* every timer at its own time: step to each deadline on the way */
            uint64_t until = W.now + (uint64_t)rec.ms * 1000u;
            for (;;) {
                uint64_t next = co_timer_list_next(co_line_timers(&W.p));
                uint64_t nc = co_timer_list_next(co_line_timers(&W.c));
                next = nc < next ? nc : next;
                if (next > until) {
                    break;
                }
                W.now = next > W.now ? next : W.now;
                process();
            }
            W.now = until;
            process();
            break;
        }
        case FZ_OP_ACTION:
            act(&r, rec.p);
            carry();
            break;
        default:
            process();
            break;
        }
        check(&W.sp);
        check(&W.sc);
    }
    co_srdo_deinit(&W.sp);
    co_srdo_deinit(&W.sc);
    co_gfc_deinit(&W.gp);
    co_gfc_deinit(&W.gc);
    return 0;
}
