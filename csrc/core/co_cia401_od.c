/* CiA 401 generic I/O bound to a node's OD (see co_cia401_od.h): the
 * channel structs of co_cia401.h kept equal to the profile objects, the
 * application's inputs written and their TPDOs triggered, the outputs
 * following every write of 0x6200 / 0x6411. */
#include "canopenfd/co_cia401_od.h"

#include <string.h>

enum { KIND_DIN, KIND_DOUT, KIND_AIN, KIND_AOUT };
enum { FIRST_OBJECT = 0x6000, LAST_OBJECT = 0x6444 };

/* A parameter object: which channel kind it configures, the entry type,
 * whether one sub 0 serves every channel, and its value when the OD lacks it. */
typedef struct param {
    uint16_t index;
    uint8_t kind;
    uint8_t type;
    bool global;
    int64_t absent;
} param_t;

static const param_t params[] = {
    {CO_CIA401_OD_INPUT_POLARITY, KIND_DIN, CO_TYPE_UNSIGNED8, false, 0},
    {CO_CIA401_OD_INPUT_FILTER, KIND_DIN, CO_TYPE_UNSIGNED8, false, 0},
    {CO_CIA401_OD_INPUT_INTERRUPT_ENABLE, KIND_DIN, CO_TYPE_BOOLEAN, true, 1},
    {CO_CIA401_OD_INPUT_ANY_CHANGE, KIND_DIN, CO_TYPE_UNSIGNED8, false, 0xFF},
    {CO_CIA401_OD_INPUT_RISING, KIND_DIN, CO_TYPE_UNSIGNED8, false, 0},
    {CO_CIA401_OD_INPUT_FALLING, KIND_DIN, CO_TYPE_UNSIGNED8, false, 0},
    {CO_CIA401_OD_OUTPUT_POLARITY, KIND_DOUT, CO_TYPE_UNSIGNED8, false, 0},
    {CO_CIA401_OD_OUTPUT_ERROR_MODE, KIND_DOUT, CO_TYPE_UNSIGNED8, false, 0xFF},
    {CO_CIA401_OD_OUTPUT_ERROR_VALUE, KIND_DOUT, CO_TYPE_UNSIGNED8, false, 0},
    {CO_CIA401_OD_OUTPUT_FILTER_MASK, KIND_DOUT, CO_TYPE_UNSIGNED8, false, 0xFF},
    {CO_CIA401_OD_ANALOG_TRIGGER, KIND_AIN, CO_TYPE_UNSIGNED8, false,
     CO_CIA401_AI_DEFAULT_TRIGGER},
    {CO_CIA401_OD_ANALOG_INTERRUPT_ENABLE, KIND_AIN, CO_TYPE_BOOLEAN, true, 0},
    {CO_CIA401_OD_ANALOG_UPPER, KIND_AIN, CO_TYPE_INTEGER32, false, 0},
    {CO_CIA401_OD_ANALOG_LOWER, KIND_AIN, CO_TYPE_INTEGER32, false, 0},
    {CO_CIA401_OD_ANALOG_DELTA, KIND_AIN, CO_TYPE_UNSIGNED32, false, 0},
    {CO_CIA401_OD_ANALOG_NEGATIVE_DELTA, KIND_AIN, CO_TYPE_UNSIGNED32, false, 0},
    {CO_CIA401_OD_ANALOG_POSITIVE_DELTA, KIND_AIN, CO_TYPE_UNSIGNED32, false, 0},
    {CO_CIA401_OD_ANALOG_OUTPUT_ERROR_MODE, KIND_AOUT, CO_TYPE_UNSIGNED8, false, 1},
    {CO_CIA401_OD_ANALOG_OUTPUT_ERROR_VALUE, KIND_AOUT, CO_TYPE_INTEGER32, false, 0},
};
enum { PARAM_COUNT = sizeof params / sizeof params[0] };

/* The channel objects of each kind, in KIND_* order. */
static const uint16_t channel_index[] = {CO_CIA401_OD_READ_INPUT, CO_CIA401_OD_WRITE_OUTPUT,
                                         CO_CIA401_OD_READ_ANALOG_INPUT,
                                         CO_CIA401_OD_WRITE_ANALOG_OUTPUT};
static const uint8_t channel_type[] = {CO_TYPE_UNSIGNED8, CO_TYPE_UNSIGNED8,
                                       CO_TYPE_INTEGER16, CO_TYPE_INTEGER16};

static const param_t *param_of(uint16_t index)
{
    for (size_t i = 0; i < PARAM_COUNT; i++) {
        if (params[i].index == index) {
            return &params[i];
        }
    }
    return NULL;
}

static uint8_t count_of(const co_cia401_od_counts_t *c, uint8_t kind)
{
    switch (kind) {
    case KIND_DIN: return c->input_groups;
    case KIND_DOUT: return c->output_groups;
    case KIND_AIN: return c->analog_inputs;
    default: return c->analog_outputs;
    }
}

/* An integer entry's value (little-endian, signed types sign-extended). */
static bool read_int(const co_od_t *od, uint16_t index, uint8_t sub, int64_t *out)
{
    const co_od_entry_t *e = co_od_find(od, index, sub);
    uint8_t raw[4] = {0};
    uint32_t length = 0;
    if (e == NULL || co_od_type_size(e->type) > sizeof raw ||
        co_od_get(od, index, sub, raw, sizeof raw, &length) != CO_ABORT_NONE) {
        return false;
    }
    uint32_t u = (uint32_t)raw[0] | (uint32_t)raw[1] << 8 | (uint32_t)raw[2] << 16 |
                 (uint32_t)raw[3] << 24;
    switch (e->type) {
    case CO_TYPE_INTEGER16: *out = (int16_t)(uint16_t)u; break;
    case CO_TYPE_INTEGER32: *out = (int32_t)u; break;
    default: *out = u; break;
    }
    return true;
}

/* ---------------------------------------------------------------- scan */

static bool type_fits(const param_t *p, uint8_t type)
{
    /* a global enable may be BOOLEAN or UNSIGNED8 (device descriptions use both) */
    return type == p->type || (p->type == CO_TYPE_BOOLEAN && type == CO_TYPE_UNSIGNED8);
}

static co_cia401_od_result_t scan_channels(const co_od_t *od, co_cia401_od_counts_t *counts,
                                           uint16_t *bad_index, uint8_t *bad_sub)
{
    uint8_t *fields[] = {&counts->input_groups, &counts->output_groups,
                         &counts->analog_inputs, &counts->analog_outputs};
    for (uint8_t kind = KIND_DIN; kind <= KIND_AOUT; kind++) {
        uint16_t index = channel_index[kind];
        uint8_t n = 0;
        *bad_index = index;
        *bad_sub = 0;
        if (co_od_has_index(od, index) && !co_od_get_u8(od, index, 0, &n)) {
            return CO_CIA401_OD_BAD_TYPE;
        }
        for (uint8_t sub = 1; sub <= n && sub != 0; sub++) {
            const co_od_entry_t *e = co_od_find(od, index, sub);
            *bad_sub = sub;
            if (e == NULL) {
                return CO_CIA401_OD_MISSING_SUB;
            }
            if (e->type != channel_type[kind]) {
                return CO_CIA401_OD_BAD_TYPE;
            }
        }
        *fields[kind] = n;
    }
    return CO_CIA401_OD_OK;
}

co_cia401_od_result_t co_cia401_od_scan(const co_od_t *od, co_cia401_od_counts_t *counts,
                                        uint16_t *bad_index, uint8_t *bad_sub)
{
    memset(counts, 0, sizeof *counts);
    co_cia401_od_result_t result = scan_channels(od, counts, bad_index, bad_sub);
    if (result != CO_CIA401_OD_OK) {
        return result;
    }
    for (size_t i = 0; i < PARAM_COUNT; i++) {
        const param_t *p = &params[i];
        uint8_t last = p->global ? 0 : count_of(counts, p->kind);
        *bad_index = p->index;
        for (uint16_t sub = p->global ? 0 : 1; sub <= last; sub++) {
            const co_od_entry_t *e = co_od_find(od, p->index, (uint8_t)sub);
            *bad_sub = (uint8_t)sub;
            if (e != NULL && !type_fits(p, e->type)) {
                return CO_CIA401_OD_BAD_TYPE;
            }
        }
    }
    *bad_index = 0;
    *bad_sub = 0;
    return counts->input_groups | counts->output_groups | counts->analog_inputs |
           counts->analog_outputs ? CO_CIA401_OD_OK : CO_CIA401_OD_NO_CHANNELS;
}

static size_t rounded(size_t bytes)
{
    return (bytes + sizeof(int64_t) - 1u) / sizeof(int64_t) * sizeof(int64_t);
}

size_t co_cia401_od_need(const co_cia401_od_counts_t *c)
{
    return rounded(sizeof(co_cia401_din_t) * c->input_groups) +
           rounded(sizeof(co_cia401_dout_t) * c->output_groups) +
           rounded(sizeof(co_cia401_ain_t) * c->analog_inputs) +
           rounded(sizeof(co_cia401_aout_t) * c->analog_outputs);
}

/* ---------------------------------------------------------------- parameters */

/* One parameter value into channel `ch` (0-based) of its kind. */
static void set_param(co_cia401_od_t *io, uint16_t index, uint8_t ch, int64_t v)
{
    switch (index) {
    case CO_CIA401_OD_INPUT_POLARITY: io->din[ch].polarity = (uint8_t)v; break;
    case CO_CIA401_OD_INPUT_FILTER: io->din[ch].filter = (uint8_t)v; break;
    case CO_CIA401_OD_INPUT_INTERRUPT_ENABLE: io->din[ch].interrupt_enable = v != 0; break;
    case CO_CIA401_OD_INPUT_ANY_CHANGE: io->din[ch].any_change = (uint8_t)v; break;
    case CO_CIA401_OD_INPUT_RISING: io->din[ch].rising = (uint8_t)v; break;
    case CO_CIA401_OD_INPUT_FALLING: io->din[ch].falling = (uint8_t)v; break;
    case CO_CIA401_OD_OUTPUT_POLARITY: io->dout[ch].polarity = (uint8_t)v; break;
    case CO_CIA401_OD_OUTPUT_ERROR_MODE: io->dout[ch].error_mode = (uint8_t)v; break;
    case CO_CIA401_OD_OUTPUT_ERROR_VALUE: io->dout[ch].error_value = (uint8_t)v; break;
    case CO_CIA401_OD_OUTPUT_FILTER_MASK: io->dout[ch].filter_mask = (uint8_t)v; break;
    case CO_CIA401_OD_ANALOG_TRIGGER: io->ain[ch].trigger = (uint8_t)v; break;
    case CO_CIA401_OD_ANALOG_INTERRUPT_ENABLE: io->ain[ch].interrupt_enable = v != 0; break;
    case CO_CIA401_OD_ANALOG_UPPER: io->ain[ch].upper_limit = (int32_t)v; break;
    case CO_CIA401_OD_ANALOG_LOWER: io->ain[ch].lower_limit = (int32_t)v; break;
    case CO_CIA401_OD_ANALOG_DELTA: io->ain[ch].delta = (uint32_t)v; break;
    case CO_CIA401_OD_ANALOG_NEGATIVE_DELTA: io->ain[ch].negative_delta = (uint32_t)v; break;
    case CO_CIA401_OD_ANALOG_POSITIVE_DELTA: io->ain[ch].positive_delta = (uint32_t)v; break;
    case CO_CIA401_OD_ANALOG_OUTPUT_ERROR_MODE: io->aout[ch].error_mode = v != 0; break;
    default: io->aout[ch].error_value = (int32_t)v; break;   /* 0x6444 */
    }
}

/* Entry sub of parameter p (written, or read at the attach) into the
 * channels it configures: channel sub, or every channel for a global one. */
static void load_param(co_cia401_od_t *io, const param_t *p, uint8_t sub)
{
    uint8_t count = count_of(&io->counts, p->kind);
    int64_t v;
    if (!read_int(io->od, p->index, sub, &v)) {
        v = p->absent;
    }
    if (p->global) {
        for (uint8_t ch = 0; ch < count && sub == 0; ch++) {
            set_param(io, p->index, ch, v);
        }
    } else if (sub >= 1 && sub <= count) {
        set_param(io, p->index, (uint8_t)(sub - 1), v);
    }
}

static void load_all_params(co_cia401_od_t *io)
{
    for (size_t i = 0; i < PARAM_COUNT; i++) {
        const param_t *p = &params[i];
        uint8_t last = p->global ? 0 : count_of(&io->counts, p->kind);
        for (uint16_t sub = p->global ? 0 : 1; sub <= last; sub++) {
            load_param(io, p, (uint8_t)sub);
        }
    }
}

/* ---------------------------------------------------------------- outputs */

static void tell(co_cia401_od_t *io, uint8_t kinds)
{
    if (kinds != 0 && io->on_outputs) {
        io->on_outputs(io, kinds, io->user);
    }
}

/* Output channel sub of 0x6200 / 0x6411 takes the OD's value; the kind
 * bit when its physical level changed. */
static uint8_t apply_output(co_cia401_od_t *io, uint16_t index, uint8_t sub)
{
    int64_t v;
    if (sub == 0 || !read_int(io->od, index, sub, &v)) {
        return 0;
    }
    if (index == CO_CIA401_OD_WRITE_OUTPUT && sub <= io->counts.output_groups) {
        co_cia401_dout_t *d = &io->dout[sub - 1];
        uint8_t was = d->physical;
        return co_cia401_dout_write(d, (uint8_t)v) != was ? CO_CIA401_OUT_DIGITAL : 0;
    }
    if (index == CO_CIA401_OD_WRITE_ANALOG_OUTPUT && sub <= io->counts.analog_outputs) {
        co_cia401_aout_t *a = &io->aout[sub - 1];
        int32_t was = a->physical;
        return co_cia401_aout_write(a, (int32_t)v) != was ? CO_CIA401_OUT_ANALOG : 0;
    }
    return 0;
}

static uint8_t apply_all(co_cia401_od_t *io, uint16_t index, uint8_t count)
{
    uint8_t kinds = 0;
    for (uint16_t sub = 1; sub <= count; sub++) {
        kinds |= apply_output(io, index, (uint8_t)sub);
    }
    return kinds;
}

void co_cia401_od_fault(co_cia401_od_t *io)
{
    uint8_t kinds = 0;
    if (io == NULL || !io->attached) {
        return;
    }
    for (uint8_t g = 0; g < io->counts.output_groups; g++) {
        uint8_t was = io->dout[g].physical;
        kinds |= co_cia401_dout_fault(&io->dout[g]) != was ? CO_CIA401_OUT_DIGITAL : 0;
    }
    for (uint8_t c = 0; c < io->counts.analog_outputs; c++) {
        int32_t was = io->aout[c].physical;
        kinds |= co_cia401_aout_fault(&io->aout[c]) != was ? CO_CIA401_OUT_ANALOG : 0;
    }
    tell(io, kinds);
}

uint8_t co_cia401_od_digital_output(const co_cia401_od_t *io, uint8_t group)
{
    return io && group >= 1 && group <= io->counts.output_groups ? io->dout[group - 1].physical
                                                                  : 0;
}

int32_t co_cia401_od_analog_output(const co_cia401_od_t *io, uint8_t channel)
{
    return io && channel >= 1 && channel <= io->counts.analog_outputs
               ? io->aout[channel - 1].physical
               : 0;
}

/* ---------------------------------------------------------------- OD handler */

/* Any write that got through: a parameter is taken at once; an output
 * written by the network or the application moves the output. A reset's
 * reload only refreshes parameters: co_cia401_od_reset applies the rest
 * once every value is back. */
static void after_write(co_od_t *od, const co_od_entry_t *e, co_od_origin_t origin, void *user)
{
    (void)od;
    co_cia401_od_t *io = user;
    uint16_t index = co_od_entry_index(e);
    uint8_t sub = co_od_entry_sub(e);
    const param_t *p = param_of(index);
    if (p != NULL) {
        load_param(io, p, sub);
    } else if (origin != CO_ORIGIN_RESTORE && (index == CO_CIA401_OD_WRITE_OUTPUT ||
                                               index == CO_CIA401_OD_WRITE_ANALOG_OUTPUT)) {
        tell(io, apply_output(io, index, sub));
    }
}

static const co_od_handler_t handler = {.after_write = after_write};

bool co_cia401_od_attach(co_cia401_od_t *io, co_od_t *od, co_pdo_t *pdo,
                         const co_cia401_od_counts_t *counts, void *memory,
                         co_cia401_outputs_fn on_outputs, void *user)
{
    unsigned char *m = memory;
    memset(io, 0, sizeof *io);
    io->od = od;
    io->pdo = pdo;
    io->counts = *counts;
    io->din = (co_cia401_din_t *)(void *)m;
    m += rounded(sizeof(co_cia401_din_t) * counts->input_groups);
    io->dout = (co_cia401_dout_t *)(void *)m;
    m += rounded(sizeof(co_cia401_dout_t) * counts->output_groups);
    io->ain = (co_cia401_ain_t *)(void *)m;
    m += rounded(sizeof(co_cia401_ain_t) * counts->analog_inputs);
    io->aout = (co_cia401_aout_t *)(void *)m;
    io->on_outputs = on_outputs;
    io->user = user;
    if (!co_od_subscribe(od, FIRST_OBJECT, 0, LAST_OBJECT, 0xFF, &handler, io)) {
        memset(io, 0, sizeof *io);
        return false;
    }
    load_all_params(io);
    for (uint8_t g = 0; g < counts->input_groups; g++) {
        int64_t v = 0;
        (void)read_int(od, CO_CIA401_OD_READ_INPUT, (uint8_t)(g + 1), &v);
        io->din[g].value = (uint8_t)v;
        io->din[g].last_sample = (uint8_t)v;
    }
    for (uint8_t c = 0; c < counts->analog_inputs; c++) {
        int64_t v = 0;
        (void)read_int(od, CO_CIA401_OD_READ_ANALOG_INPUT, (uint8_t)(c + 1), &v);
        co_cia401_ain_reset(&io->ain[c], (int32_t)v);
    }
    io->attached = true;
    return true;
}

void co_cia401_od_detach(co_cia401_od_t *io)
{
    if (io != NULL && io->attached) {
        co_od_unsubscribe(io->od, &handler, io);
        memset(io, 0, sizeof *io);
    }
}

/* ---------------------------------------------------------------- inputs */

/* The input channels whose change fires a TPDO, for co_pdo_trigger_mapped. */
typedef struct fired {
    uint16_t index;
    uint8_t bits[256 / 8];           /* sub n fired: bit n */
} fired_t;

static bool was_fired(const co_od_entry_t *e, void *user)
{
    const fired_t *f = user;
    uint8_t sub = co_od_entry_sub(e);
    return co_od_entry_index(e) == f->index && (f->bits[sub / 8] >> (sub % 8) & 1u);
}

static void put_input(co_cia401_od_t *io, uint16_t index, uint8_t sub, int32_t value)
{
    uint8_t bytes[2] = {(uint8_t)value, (uint8_t)((uint32_t)value >> 8)};
    (void)co_od_put(io->od, index, sub, bytes, index == CO_CIA401_OD_READ_INPUT ? 1u : 2u);
}

co_cia401_od_result_t co_cia401_od_set_inputs(co_cia401_od_t *io, uint8_t first,
                                              const uint8_t *raw, uint8_t count)
{
    fired_t fired = {.index = CO_CIA401_OD_READ_INPUT, .bits = {0}};
    bool any = false;
    if (io == NULL || !io->attached) {
        return CO_CIA401_OD_NOT_ATTACHED;
    }
    if (raw == NULL || first == 0 || count == 0 ||
        (unsigned)first + count - 1u > io->counts.input_groups) {
        return CO_CIA401_OD_BAD_CHANNEL;
    }
    for (uint8_t i = 0; i < count; i++) {
        uint8_t sub = (uint8_t)(first + i);
        co_cia401_din_t *d = &io->din[sub - 1];
        if (co_cia401_din_update(d, raw[i])) {
            fired.bits[sub / 8] |= (uint8_t)(1u << (sub % 8));
            any = true;
        }
        put_input(io, CO_CIA401_OD_READ_INPUT, sub, d->value);
    }
    if (any && io->pdo) {
        (void)co_pdo_trigger_mapped(io->pdo, was_fired, &fired);
    }
    return CO_CIA401_OD_OK;
}

co_cia401_od_result_t co_cia401_od_set_analog_input(co_cia401_od_t *io, uint8_t channel,
                                                    int16_t value)
{
    if (io == NULL || !io->attached) {
        return CO_CIA401_OD_NOT_ATTACHED;
    }
    if (channel == 0 || channel > io->counts.analog_inputs) {
        return CO_CIA401_OD_BAD_CHANNEL;
    }
    bool fire = co_cia401_ain_update(&io->ain[channel - 1], value);
    put_input(io, CO_CIA401_OD_READ_ANALOG_INPUT, channel, value);
    if (fire && io->pdo) {
        (void)co_pdo_trigger_object(io->pdo, CO_CIA401_OD_READ_ANALOG_INPUT, channel);
    }
    return CO_CIA401_OD_OK;
}

/* ---------------------------------------------------------------- the node */

/* What one RPDO moved, for co_pdo_each_mapped. */
typedef struct received {
    co_cia401_od_t *io;
    uint8_t kinds;
} received_t;

static bool apply_received(const co_od_entry_t *e, void *user)
{
    received_t *r = user;
    r->kinds |= apply_output(r->io, co_od_entry_index(e), co_od_entry_sub(e));
    return true;
}

void co_cia401_od_rpdo_received(co_cia401_od_t *io, uint16_t number)
{
    received_t r = {.io = io, .kinds = 0};
    if (io == NULL || !io->attached || io->pdo == NULL) {
        return;
    }
    /* the RPDO copy tells no after-write handler: its mapping says what moved */
    co_pdo_each_mapped(io->pdo, true, number, apply_received, &r);
    tell(io, r.kinds);
}

void co_cia401_od_nmt_state(co_cia401_od_t *io, co_nmt_state_t old_state,
                            co_nmt_state_t new_state)
{
    if (new_state == CO_NMT_STOPPED && old_state != CO_NMT_STOPPED) {
        co_cia401_od_fault(io);
    }
}

void co_cia401_od_reset(co_cia401_od_t *io, co_nmt_command_t kind)
{
    if (io == NULL || !io->attached || kind != CO_NMT_CMD_RESET_NODE) {
        return;
    }
    /* the levels did not change with the reset: the OD shows them again */
    for (uint8_t g = 0; g < io->counts.input_groups; g++) {
        put_input(io, CO_CIA401_OD_READ_INPUT, (uint8_t)(g + 1), io->din[g].value);
    }
    for (uint8_t c = 0; c < io->counts.analog_inputs; c++) {
        put_input(io, CO_CIA401_OD_READ_ANALOG_INPUT, (uint8_t)(c + 1), io->ain[c].value);
    }
    /* one indication per kind, digital first, as the reload order */
    tell(io, apply_all(io, CO_CIA401_OD_WRITE_OUTPUT, io->counts.output_groups));
    tell(io, apply_all(io, CO_CIA401_OD_WRITE_ANALOG_OUTPUT, io->counts.analog_outputs));
}
