/* co_gateway SDO networking: segmented downloads relayed with early answers.
 * A relayed segment costs the client two round trips (client -> gateway ->
 * target and back). Once the target has accepted a segmented download's
 * initiate (its 0x60 relayed to the client as usual), the gateway answers
 * each of the client's segments itself at once and passes the segments on
 * to the target one by one as it confirms them, so the two hops run side
 * by side. The target still sees the client's frames byte for byte; the
 * client's last segment is answered by the target's own confirmation, so a
 * success still means the target took the value. At most
 * CO_GATEWAY_SDO_PIPE_DEPTH segments wait in the gateway: the client's last
 * answer never waits for more than that many exchanges with the target,
 * well inside its timeout. The target's abort ends the pipeline and reaches
 * the client at once (CiA 301 lets a server abort at any time); the
 * client's abort goes to the target; the relay's timeout covers a silent
 * target. Uploads and fd targets: co_gateway_sdo_buffered.c. */
#include "canopenfd/co_gateway.h"

#include <string.h>

enum { FRAME = 8, SEG_ACK = 0x20, TOGGLE = 0x10, LAST = 0x01, EXPEDITED = 0x02,
       CCS_SEGMENT = 0, CCS_INITIATE = 1, CCS_ABORT = 4, INITIATE_RSP = 0x60 };

enum pipe_state { PIPE_OFF = 0, PIPE_INITIATE, PIPE_RUNNING };

static void ack_client(co_gateway_sdo_t *c, uint8_t toggle)
{
    uint8_t f[FRAME] = {(uint8_t)(SEG_ACK | toggle), 0, 0, 0, 0, 0, 0, 0};
    c->gw->stats.sdo_answers++;
    if (!co_line_send(co_stack_line(c->from->stack), c->reply_id, f, FRAME)) {
        c->gw->stats.sdo_tx_failed++;
    }
}

static void end(co_gateway_sdo_t *c)
{
    c->pipe = PIPE_OFF;
    c->pipe_count = 0;
}

/* The oldest waiting segment goes to the target; a client held back for
 * room hears its answer now. */
static void send_next(co_gateway_sdo_t *c)
{
    uint8_t *f = c->pipe_frames[c->pipe_head];
    c->pipe_head = (uint8_t)((c->pipe_head + 1u) % CO_GATEWAY_SDO_PIPE_DEPTH);
    c->pipe_count--;
    c->pipe_target_busy = true;
    c->pipe_last_sent = (f[0] & LAST) != 0;
    co_gateway_sdo_relay(c, f);
    if (c->pipe_ack_held) {
        c->pipe_ack_held = false;
        ack_client(c, c->pipe_held_toggle);
    }
}

bool co_gateway_sdo_pipe_request(co_gateway_sdo_t *c, const uint8_t *d)
{
    uint8_t ccs = d[0] >> 5;
    if (c->fd) {
        return false;
    }
    if (c->pipe == PIPE_OFF) {
        if (ccs != CCS_INITIATE || (d[0] & EXPEDITED) != 0 || c->gw->sdo_relay_only) {
            return false;
        }
        c->pipe = PIPE_INITIATE;   /* relayed; running once the target takes it */
        c->pipe_count = 0;
        c->pipe_head = 0;
        c->pipe_ack_held = false;
        c->pipe_last_in = false;
        c->pipe_last_sent = false;
        c->pipe_target_busy = true;
        co_gateway_sdo_relay(c, d);
        return true;
    }
    if (c->pipe == PIPE_INITIATE || ccs != CCS_SEGMENT || c->pipe_last_in) {
        end(c);   /* an abort, a new transfer, a client out of turn: relayed as it is */
        return false;
    }
    uint8_t slot = (uint8_t)((c->pipe_head + c->pipe_count) % CO_GATEWAY_SDO_PIPE_DEPTH);
    memcpy(c->pipe_frames[slot], d, FRAME);
    c->pipe_count++;
    c->pipe_last_in = (d[0] & LAST) != 0;
    if (!c->pipe_target_busy) {
        send_next(c);
    }
    if (c->pipe_last_in) {
        return true;   /* answered by the target's confirmation */
    }
    c->gw->stats.sdo_pipelined++;
    if (c->pipe_count < CO_GATEWAY_SDO_PIPE_DEPTH) {
        ack_client(c, d[0] & TOGGLE);
    } else {
        c->pipe_ack_held = true;   /* full: the client waits for room */
        c->pipe_held_toggle = d[0] & TOGGLE;
    }
    return true;
}

bool co_gateway_sdo_pipe_answer(co_gateway_sdo_t *c, const uint8_t *d)
{
    if (c->pipe == PIPE_INITIATE) {
        if (d[0] == INITIATE_RSP) {
            c->pipe = PIPE_RUNNING;
            c->pipe_target_busy = false;
        } else {
            end(c);
        }
        return false;   /* the client hears the target's answer */
    }
    if (c->pipe != PIPE_RUNNING) {
        return false;
    }
    if ((d[0] & ~TOGGLE) != SEG_ACK || c->pipe_last_sent) {
        end(c);   /* the last segment's confirmation, or an abort: to the client */
        return false;
    }
    c->pipe_target_busy = false;   /* taken here: the client had its answer already */
    if (c->pipe_count > 0) {
        send_next(c);
    }
    return true;
}

void co_gateway_sdo_pipe_close(co_gateway_sdo_t *c)
{
    end(c);
}
