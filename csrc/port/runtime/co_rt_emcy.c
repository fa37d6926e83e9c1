/* Runtime glue of EMCY: the local node's producer (raise, clear, state) and
 * the line's consumer (nodes the application watches, 0x1028 of the node's
 * OD), whose EMCYs reach Python re-encoded as a frame (decoded by the C
 * codec through cffi). No state of its own: the stack holds both. */
#include "co_rt_internal.h"

#include <string.h>

void rt_emcy_on_received(co_stack_t *stack, uint8_t node_id, const co_emcy_msg_t *msg,
                         void *user)
{
    (void)stack;
    rt_line_t *l = user;
    co_frame_t frame;
    memset(&frame, 0, sizeof frame);
    bool fd = co_line_mode(&l->line) == CO_MODE_FD;
    frame.len = (uint8_t)(fd ? co_emcy_encode_fd(msg, frame.data, sizeof frame.data)
                             : co_emcy_encode_classic(msg, frame.data, sizeof frame.data));
    rt_post(l, CO_EV_EMCY, node_id, fd ? 1u : 0u, msg->code, &frame);
}

int co_rt_emcy(co_rt_t *rt, int line, const co_rt_emcy_t *error, int clear)
{
    if (!error) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_line_t *l = rt_node_line(rt, line, clear ? "clearing an EMCY" : "raising an EMCY");
    if (!l) {
        return CO_RT_ERR_STATE;
    }
    co_emcy_t *emcy = co_stack_emcy(&l->stack);
    co_emcy_error_t err = {.code = error->code,
                           .register_bits = error->register_bits,
                           .logical_device = error->logical_device,
                           .spec_number = error->spec_number,
                           .priority = error->priority,
                           .non_recoverable = error->non_recoverable != 0,
                           .time_stamp = error->time_stamp};
    memcpy(err.msef, error->msef, sizeof err.msef);
    co_line_set_time(&l->line, co_rt_now_us());
    co_emcy_result_t r = clear ? co_emcy_clear(emcy, &err) : co_emcy_raise(emcy, &err);
    if (r == CO_EMCY_BAD_ARGUMENT) {
        rt_set_error(rt, "line %d: EMCY 0x%04X refused: code 0, priority %u > 7 or time "
                     "stamp above 48 bits", line, error->code, (unsigned)error->priority);
        return rt_kick_unlock(rt, CO_RT_ERR_ARGUMENT);
    }
    if (r == CO_EMCY_TABLE_FULL) {
        rt_set_error(rt, "line %d: EMCY 0x%04X refused: %u errors are active already", line,
                     error->code, (unsigned)emcy->active_capacity);
        return rt_kick_unlock(rt, CO_RT_ERR_FULL);
    }
    return rt_kick_unlock(rt, (int)r);
}

int co_rt_emcy_state(co_rt_t *rt, int line, co_rt_emcy_state_t *out)
{
    if (!out) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_line_t *l = rt_node_line(rt, line, "the EMCY state");
    if (!l) {
        return CO_RT_ERR_STATE;
    }
    co_emcy_t *emcy = co_stack_emcy(&l->stack);
    *out = (co_rt_emcy_state_t){.error_register = co_emcy_error_register(emcy),
                                .active = co_emcy_active_count(emcy),
                                .sent = emcy->stats.sent,
                                .dropped = emcy->stats.dropped};
    rt_mutex_unlock(&rt->lock);
    return CO_RT_OK;
}

int co_rt_emcy_watch(co_rt_t *rt, int line, int node_id, int watch)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    if (node_id < 1 || node_id > 127) {
        return rt_argument_error(rt, "line %d: EMCY of node %d: node-ids are 1..127", line,
                                 node_id);
    }
    rt_mutex_lock(&rt->lock);
    int status = CO_RT_OK;
    if (!watch) {
        co_emcy_consumer_unwatch(co_stack_emcy_consumer(&l->stack), (uint8_t)node_id);
    } else if (!co_emcy_consumer_watch(co_stack_emcy_consumer(&l->stack), (uint8_t)node_id)) {
        rt_set_error(rt, "line %d: cannot consume the EMCY of node %d (CAN-ID 0x%X taken?)",
                     line, node_id, 0x80 + node_id);
        status = CO_RT_ERR_STATE;
    }
    rt_mutex_unlock(&rt->lock);
    return status;
}
