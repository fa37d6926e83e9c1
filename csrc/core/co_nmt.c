#include "canopenfd/co_nmt.h"

bool co_nmt_command_is_valid(uint8_t command)
{
    switch (command) {
    case CO_NMT_CMD_START:
    case CO_NMT_CMD_STOP:
    case CO_NMT_CMD_PRE_OPERATIONAL:
    case CO_NMT_CMD_RESET_NODE:
    case CO_NMT_CMD_RESET_COMMUNICATION:
        return true;
    default:
        return false;
    }
}

co_nmt_state_t co_nmt_command_target(co_nmt_command_t command)
{
    switch (command) {
    case CO_NMT_CMD_START:
        return CO_NMT_OPERATIONAL;
    case CO_NMT_CMD_STOP:
        return CO_NMT_STOPPED;
    case CO_NMT_CMD_PRE_OPERATIONAL:
        return CO_NMT_PRE_OPERATIONAL;
    default:
        return CO_NMT_INITIALISING;
    }
}

static void set_state(co_nmt_t *nmt, co_nmt_state_t new_state)
{
    co_nmt_state_t old_state = nmt->state;
    if (old_state == new_state) {
        return;
    }
    nmt->state = new_state;
    if (nmt->ind && nmt->ind->state_changed) {
        nmt->ind->state_changed(nmt, old_state, new_state, nmt->user);
    }
}

void co_nmt_boot(co_nmt_t *nmt)
{
    /* Boot-up: the heartbeat frame with state 0 (CiA 301 error control). */
    static const uint8_t bootup = CO_NMT_INITIALISING;
    set_state(nmt, CO_NMT_INITIALISING);
    co_line_send(nmt->line, CO_NMT_EC_COB_ID_BASE + nmt->node_id, &bootup, 1);
    set_state(nmt, CO_NMT_PRE_OPERATIONAL);
}

static void reset(co_nmt_t *nmt, co_nmt_command_t kind)
{
    set_state(nmt, CO_NMT_INITIALISING);
    if (nmt->ind && nmt->ind->reset) {
        nmt->ind->reset(nmt, kind, nmt->user);
    }
    co_nmt_boot(nmt);
}

static bool operational_allowed(co_nmt_t *nmt)
{
    if (nmt->ind && nmt->ind->allow_operational &&
        !nmt->ind->allow_operational(nmt, nmt->user)) {
        nmt->vetoed++;
        return false;
    }
    return true;
}

void co_nmt_apply(co_nmt_t *nmt, co_nmt_command_t command)
{
    if (nmt->state == CO_NMT_INITIALISING) {
        return;   /* not booted yet: the node does not take part in NMT */
    }
    switch (command) {
    case CO_NMT_CMD_START:
        if (nmt->state != CO_NMT_OPERATIONAL && operational_allowed(nmt)) {
            set_state(nmt, CO_NMT_OPERATIONAL);
        }
        break;
    case CO_NMT_CMD_STOP:
        set_state(nmt, CO_NMT_STOPPED);
        break;
    case CO_NMT_CMD_PRE_OPERATIONAL:
        set_state(nmt, CO_NMT_PRE_OPERATIONAL);
        break;
    case CO_NMT_CMD_RESET_NODE:
    case CO_NMT_CMD_RESET_COMMUNICATION:
        reset(nmt, command);
        break;
    }
}

static void on_nmt_frame(co_line_t *line, const co_frame_t *frame, void *user)
{
    co_nmt_t *nmt = user;
    if (frame->len != 2) {
        co_line_count_rejected(line, CO_LINE_NMT_BAD_LENGTH);
        return;
    }
    uint8_t command = frame->data[0];
    uint8_t node_id = frame->data[1];
    if (!co_nmt_command_is_valid(command)) {
        co_line_count_rejected(line, CO_LINE_NMT_BAD_COMMAND);
        return;
    }
    if (node_id > 127) {
        co_line_count_rejected(line, CO_LINE_NMT_BAD_NODE);
        return;
    }
    if (node_id == 0 || node_id == nmt->node_id) {
        co_nmt_apply(nmt, (co_nmt_command_t)command);
    }
}

bool co_nmt_init(co_nmt_t *nmt, co_line_t *line, uint8_t node_id,
                 const co_nmt_indications_t *ind, void *user)
{
    if (node_id < 1 || node_id > 127) {
        return false;
    }
    nmt->line = line;
    nmt->node_id = node_id;
    nmt->state = CO_NMT_INITIALISING;
    nmt->ind = ind;
    nmt->user = user;
    nmt->vetoed = 0;
    return co_line_subscribe(line, CO_NMT_COB_ID, CO_NMT_COB_ID, on_nmt_frame, nmt);
}

void co_nmt_deinit(co_nmt_t *nmt)
{
    co_line_unsubscribe(nmt->line, on_nmt_frame, nmt);
}

bool co_nmt_master_send(co_line_t *line, co_nmt_t *local, co_nmt_command_t command,
                        uint8_t node_id, bool include_self)
{
    if (!co_nmt_command_is_valid((uint8_t)command) || node_id > 127) {
        return false;
    }
    const uint8_t data[2] = {(uint8_t)command, node_id};
    bool queued = co_line_send(line, CO_NMT_COB_ID, data, sizeof data);
    /* Our own frame is not echoed back by CAN: apply it locally here. */
    if (local && (node_id == local->node_id || (node_id == 0 && include_self))) {
        co_nmt_apply(local, command);
    }
    return queued;
}
