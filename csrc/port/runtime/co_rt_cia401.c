/* Runtime glue of the local node as a CiA 401 generic I/O device: co_stack
 * runs it over the node's OD (co_stack_cia401_init), so inputs, parameters,
 * TPDO triggers, outputs and faults are all handled in C; every change of
 * the physical outputs is posted to the application (CO_EV_CIA401). No
 * state of its own. */
#include "co_rt_internal.h"

#include <string.h>

/* What one CO_EV_CIA401 event carries: a byte per digital output group, an
 * INTEGER16 per analogue output (a start refuses an OD with more). */
enum { OUTPUT_GROUPS_MAX = CO_FRAME_MAX_DATA, ANALOG_OUTPUTS_MAX = CO_FRAME_MAX_DATA / 2 };

/* One event per kind that changed, carrying every level of that kind, so
 * the application sees each write's result even when it reads late. */
static void post_kind(rt_line_t *l, const co_cia401_od_t *io, uint8_t kind, uint8_t kinds)
{
    co_frame_t frame;
    memset(&frame, 0, sizeof frame);
    uint8_t count;
    if (kind == CO_CIA401_OUT_DIGITAL) {
        count = io->counts.output_groups;
        for (uint8_t g = 1; g <= count; g++) {
            frame.data[g - 1] = co_cia401_od_digital_output(io, g);
        }
        frame.len = count;
    } else {
        count = io->counts.analog_outputs;
        for (uint8_t c = 1; c <= count; c++) {
            uint16_t v = (uint16_t)(int16_t)co_cia401_od_analog_output(io, c);
            frame.data[2 * (c - 1)] = (uint8_t)v;
            frame.data[2 * (c - 1) + 1] = (uint8_t)(v >> 8);
        }
        frame.len = (uint8_t)(2 * count);
    }
    rt_post(l, CO_EV_CIA401, kind, kinds, count, &frame);
}

static void on_outputs(co_cia401_od_t *io, uint8_t kinds, void *user)
{
    rt_line_t *l = user;
    if (kinds & CO_CIA401_OUT_DIGITAL) {
        post_kind(l, io, CO_CIA401_OUT_DIGITAL, kinds);
    }
    if (kinds & CO_CIA401_OUT_ANALOG) {
        post_kind(l, io, CO_CIA401_OUT_ANALOG, kinds);
    }
}

static const char *scan_text(co_cia401_od_result_t result)
{
    switch (result) {
    case CO_CIA401_OD_NO_CHANNELS: return "holds none of 0x6000, 0x6200, 0x6401, 0x6411";
    case CO_CIA401_OD_MISSING_SUB: return "lacks channel entry";
    case CO_CIA401_OD_BAD_TYPE: return "has the wrong type at";
    default: return "cannot be used at";
    }
}

int co_rt_cia401_start(co_rt_t *rt, int line)
{
    rt_line_t *l = rt_node_line(rt, line, "a CiA 401 I/O device");
    if (!l) {
        return CO_RT_ERR_STATE;
    }
    co_line_set_time(&l->line, co_rt_now_us());
    co_stack_status_t status = co_stack_cia401_init(&l->stack, on_outputs, l);
    if (status == CO_STACK_ERR_OD && co_stack_od(&l->stack)) {
        co_cia401_od_counts_t counts;
        uint16_t index = 0;
        uint8_t sub = 0;
        co_cia401_od_result_t why = co_cia401_od_scan(co_stack_od(&l->stack), &counts, &index,
                                                      &sub);
        rt_set_error(rt, "line %d: the node's OD %s 0x%04X:%02X (CiA 401 channels: 0x6000/0x6200 "
                     "UNSIGNED8, 0x6401/0x6411 INTEGER16, sub 1..sub 0)", line,
                     scan_text(why), (unsigned)index, (unsigned)sub);
        return rt_kick_unlock(rt, CO_RT_ERR_ARGUMENT);
    }
    const co_cia401_od_t *io = co_stack_cia401(&l->stack);
    if (status == CO_STACK_OK && (io->counts.output_groups > OUTPUT_GROUPS_MAX ||
                                  io->counts.analog_outputs > ANALOG_OUTPUTS_MAX)) {
        rt_set_error(rt, "line %d: the node's OD has %u digital output groups (0x6200) and %u "
                     "analogue outputs (0x6411); the runtime reports at most %d and %d",
                     line, (unsigned)io->counts.output_groups,
                     (unsigned)io->counts.analog_outputs, OUTPUT_GROUPS_MAX, ANALOG_OUTPUTS_MAX);
        co_stack_cia401_deinit(&l->stack);   /* its outputs would not fit one event */
        return rt_kick_unlock(rt, CO_RT_ERR_ARGUMENT);
    }
    if (status != CO_STACK_OK) {
        rt_set_error(rt, "line %d: CiA 401 device not started: %s", line,
                     status == CO_STACK_ERR_STATE ? "it runs already (or the node has no OD)"
                     : status == CO_STACK_ERR_TAKEN ? "the OD handler table is full"
                                                   : "no memory for its channels");
        return rt_kick_unlock(rt, CO_RT_ERR_STATE);
    }
    return rt_kick_unlock(rt, CO_RT_OK);
}

/* The running device under rt->lock, or NULL (no lock held, error set). */
static co_cia401_od_t *locked_device(co_rt_t *rt, int line, const char *what)
{
    rt_line_t *l = rt_node_line(rt, line, what);
    if (!l) {
        return NULL;
    }
    co_cia401_od_t *io = co_stack_cia401(&l->stack);
    if (!io) {
        rt_mutex_unlock(&rt->lock);
        rt_set_error(rt, "line %d: %s needs co_rt_cia401_start first", line, what);
        return NULL;
    }
    co_line_set_time(&l->line, co_rt_now_us());
    return io;
}

/* After a call on the device: its refusal named, the loop kicked (TPDOs). */
static int finish(co_rt_t *rt, int line, co_cia401_od_result_t result, unsigned have)
{
    if (result == CO_CIA401_OD_OK) {
        return rt_kick_unlock(rt, CO_RT_OK);
    }
    rt_set_error(rt, "line %d: the CiA 401 device has %u such channels", line, have);
    return rt_kick_unlock(rt, CO_RT_ERR_ARGUMENT);
}

int co_rt_cia401_set_inputs(co_rt_t *rt, int line, uint8_t first, const uint8_t *raw,
                            uint8_t count)
{
    co_cia401_od_t *io = locked_device(rt, line, "set_inputs");
    if (!io) {
        return CO_RT_ERR_STATE;
    }
    return finish(rt, line, co_cia401_od_set_inputs(io, first, raw, count),
                  io->counts.input_groups);
}

int co_rt_cia401_set_analog_input(co_rt_t *rt, int line, uint8_t channel, int16_t value)
{
    co_cia401_od_t *io = locked_device(rt, line, "set_analog_input");
    if (!io) {
        return CO_RT_ERR_STATE;
    }
    return finish(rt, line, co_cia401_od_set_analog_input(io, channel, value),
                  io->counts.analog_inputs);
}

int co_rt_cia401_fault(co_rt_t *rt, int line)
{
    co_cia401_od_t *io = locked_device(rt, line, "a CiA 401 fault");
    if (!io) {
        return CO_RT_ERR_STATE;
    }
    co_cia401_od_fault(io);
    return rt_kick_unlock(rt, CO_RT_OK);
}

int co_rt_cia401_outputs(co_rt_t *rt, int line, uint8_t *digital, uint8_t groups,
                         int32_t *analog, uint8_t channels)
{
    co_cia401_od_t *io = locked_device(rt, line, "the CiA 401 outputs");
    if (!io) {
        return CO_RT_ERR_STATE;
    }
    for (uint8_t g = 1; digital && g <= groups; g++) {
        digital[g - 1] = co_cia401_od_digital_output(io, g);
    }
    for (uint8_t c = 1; analog && c <= channels; c++) {
        analog[c - 1] = co_cia401_od_analog_output(io, c);
    }
    rt_mutex_unlock(&rt->lock);
    return CO_RT_OK;
}
