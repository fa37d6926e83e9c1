/* LSS wire format and LSS slave (see co_lss.h). */
#include "canopenfd/co_lss.h"

#include <string.h>

/* ================================================================== codec */

static uint32_t get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) |
           ((uint32_t)p[3] << 24);
}

static void put_u32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

static bool is_request_cs(uint8_t cs)
{
    switch (cs) {
    case CO_LSS_CS_SWITCH_GLOBAL:
    case CO_LSS_CS_CONFIGURE_NODE_ID:
    case CO_LSS_CS_CONFIGURE_BIT_TIMING:
    case CO_LSS_CS_ACTIVATE_BIT_TIMING:
    case CO_LSS_CS_STORE_CONFIGURATION:
    case CO_LSS_CS_IDENTIFY_NON_CONFIGURED:
    case CO_LSS_CS_FASTSCAN:
        return true;
    default:
        return (cs >= CO_LSS_CS_SELECT_VENDOR && cs <= CO_LSS_CS_SELECT_SERIAL) ||
               (cs >= CO_LSS_CS_IDENTIFY_VENDOR && cs <= CO_LSS_CS_IDENTIFY_SERIAL_HIGH) ||
               (cs >= CO_LSS_CS_INQUIRE_VENDOR && cs <= CO_LSS_CS_INQUIRE_NODE_ID);
    }
}

static bool is_answer_cs(uint8_t cs)
{
    switch (cs) {
    case CO_LSS_CS_CONFIGURE_NODE_ID:
    case CO_LSS_CS_CONFIGURE_BIT_TIMING:
    case CO_LSS_CS_STORE_CONFIGURATION:
    case CO_LSS_CS_SELECT_ANSWER:
    case CO_LSS_CS_IDENTIFY_ANSWER:
    case CO_LSS_CS_NON_CONFIGURED_ANSWER:
        return true;
    default:
        return cs >= CO_LSS_CS_INQUIRE_VENDOR && cs <= CO_LSS_CS_INQUIRE_NODE_ID;
    }
}

static co_lss_decode_t decode(const uint8_t *data, size_t len, co_lss_msg_t *msg, bool request)
{
    memset(msg, 0, sizeof *msg);
    if (len != CO_LSS_FRAME_LEN) {
        return CO_LSS_DECODE_BAD_LENGTH;
    }
    msg->cs = data[0];
    if (!(request ? is_request_cs(msg->cs) : is_answer_cs(msg->cs))) {
        return CO_LSS_DECODE_UNKNOWN_CS;
    }
    msg->byte1 = data[1];
    msg->byte2 = data[2];
    msg->delay_ms = (uint16_t)(data[1] | (data[2] << 8));
    msg->value = get_u32(&data[1]);
    msg->bit_checked = data[5];
    msg->sub = data[6];
    msg->next = data[7];
    return CO_LSS_DECODE_OK;
}

co_lss_decode_t co_lss_decode_request(const uint8_t *data, size_t len, co_lss_msg_t *msg)
{
    return decode(data, len, msg, true);
}

co_lss_decode_t co_lss_decode_answer(const uint8_t *data, size_t len, co_lss_msg_t *msg)
{
    return decode(data, len, msg, false);
}

void co_lss_encode_bytes(uint8_t out[8], uint8_t cs, uint8_t byte1, uint8_t byte2)
{
    memset(out, 0, CO_LSS_FRAME_LEN);
    out[0] = cs;
    out[1] = byte1;
    out[2] = byte2;
}

void co_lss_encode_value(uint8_t out[8], uint8_t cs, uint32_t value)
{
    memset(out, 0, CO_LSS_FRAME_LEN);
    out[0] = cs;
    put_u32(&out[1], value);
}

void co_lss_encode_delay(uint8_t out[8], uint16_t delay_ms)
{
    co_lss_encode_bytes(out, CO_LSS_CS_ACTIVATE_BIT_TIMING, (uint8_t)delay_ms,
                        (uint8_t)(delay_ms >> 8));
}

void co_lss_encode_fastscan(uint8_t out[8], uint32_t id_number, uint8_t bit_checked,
                            uint8_t sub, uint8_t next)
{
    co_lss_encode_value(out, CO_LSS_CS_FASTSCAN, id_number);
    out[5] = bit_checked;
    out[6] = sub;
    out[7] = next;
}

/* ================================================================== slave */

static void answer(co_lss_slave_t *s, const uint8_t data[8])
{
    if (co_line_send(s->line, CO_LSS_ID_SLAVE, data, CO_LSS_FRAME_LEN)) {
        s->stats.answers++;
    } else {
        s->stats.tx_failed++;
    }
}

static void answer_bytes(co_lss_slave_t *s, uint8_t cs, uint8_t byte1, uint8_t byte2)
{
    uint8_t data[8];
    co_lss_encode_bytes(data, cs, byte1, byte2);
    answer(s, data);
}

static void set_state(co_lss_slave_t *s, co_lss_state_t state)
{
    s->select_step = 0;
    s->identify_seen = 0;
    if (s->state == state) {
        return;
    }
    s->state = state;
    if (s->ind && s->ind->state_changed) {
        s->ind->state_changed(s, state, s->user);
    }
}

/* "Non-configured": neither an active nor a pending node-id. Such slaves
 * take part in fast scan and answer "identify non-configured". */
static bool non_configured(const co_lss_slave_t *s)
{
    return s->active_node_id == CO_LSS_NODE_ID_UNCONFIGURED &&
           s->pending_node_id == CO_LSS_NODE_ID_UNCONFIGURED;
}

static void switch_global(co_lss_slave_t *s, uint8_t mode)
{
    if (mode == CO_LSS_STATE_CONFIGURATION) {
        set_state(s, CO_LSS_STATE_CONFIGURATION);
        return;
    }
    if (mode != CO_LSS_STATE_WAITING) {
        s->stats.bad_argument++;
        return;
    }
    /* An unconfigured slave that got a node-id starts using it now. */
    bool activate = s->state == CO_LSS_STATE_CONFIGURATION &&
                    s->active_node_id == CO_LSS_NODE_ID_UNCONFIGURED &&
                    s->pending_node_id != CO_LSS_NODE_ID_UNCONFIGURED;
    set_state(s, CO_LSS_STATE_WAITING);
    if (activate && s->ind && s->ind->reset_communication) {
        s->ind->reset_communication(s, s->pending_node_id, s->user);
    }
}

/* The four frames of switch state selective, in order: each must match for
 * the next to count; a vendor-ID frame always starts over; the serial
 * completes it. */
static void select_part(co_lss_slave_t *s, uint8_t part, uint32_t value)
{
    bool match = value == s->address.part[part] && (part == 0u || s->select_step == part);
    s->select_step = match ? (uint8_t)(part + 1u) : 0u;
    if (match && part == CO_LSS_SERIAL) {
        set_state(s, CO_LSS_STATE_CONFIGURATION);
        answer_bytes(s, CO_LSS_CS_SELECT_ANSWER, 0, 0);
    }
}

/* Identify remote slave: six frames (vendor, product, revision low/high,
 * serial low/high) in any order; the serial high frame asks for the
 * answer, given when all six were received and the address lies inside. */
static void identify_part(co_lss_slave_t *s, uint8_t which, uint32_t value)
{
    s->identify[which] = value;
    s->identify_seen |= (uint8_t)(1u << which);
    if (which != 5u) {
        return;
    }
    bool all = s->identify_seen == 0x3Fu;
    s->identify_seen = 0;
    const uint32_t *v = s->identify;
    const uint32_t *a = s->address.part;
    if (all && v[0] == a[CO_LSS_VENDOR] && v[1] == a[CO_LSS_PRODUCT] &&
        v[2] <= a[CO_LSS_REVISION] && a[CO_LSS_REVISION] <= v[3] &&
        v[4] <= a[CO_LSS_SERIAL] && a[CO_LSS_SERIAL] <= v[5]) {
        answer_bytes(s, CO_LSS_CS_IDENTIFY_ANSWER, 0, 0);
    }
}

/* Fast scan step: the bits bit_checked..31 of part `sub` are compared;
 * a match answers and moves the scan to `next`; a full match of the serial
 * (bit 0 checked, next < sub) selects the slave. */
static void fastscan(co_lss_slave_t *s, const co_lss_msg_t *m)
{
    if ((m->bit_checked > 31u && m->bit_checked != CO_LSS_FASTSCAN_CONFIRM) ||
        m->sub > CO_LSS_SERIAL || m->next > CO_LSS_SERIAL) {
        s->stats.bad_argument++;
        return;
    }
    if (!non_configured(s)) {
        return;
    }
    if (m->bit_checked == CO_LSS_FASTSCAN_CONFIRM) {
        s->fastscan_pos = CO_LSS_VENDOR;
        answer_bytes(s, CO_LSS_CS_IDENTIFY_ANSWER, 0, 0);
        return;
    }
    if (s->fastscan_pos != m->sub) {
        return;
    }
    uint32_t mask = UINT32_MAX << m->bit_checked;   /* bit_checked <= 31 here */
    if (((s->address.part[m->sub] ^ m->value) & mask) != 0) {
        return;
    }
    s->fastscan_pos = m->next;
    if (m->bit_checked == 0u && m->next < m->sub) {
        set_state(s, CO_LSS_STATE_CONFIGURATION);
    }
    answer_bytes(s, CO_LSS_CS_IDENTIFY_ANSWER, 0, 0);
}

static void configure_bit_timing(co_lss_slave_t *s, uint8_t selector, uint8_t index)
{
    bool ok = s->ind && s->ind->check_bit_timing &&
              s->ind->check_bit_timing(s, selector, index, s->user);
    if (ok) {
        s->bit_timing_selector = selector;
        s->bit_timing_index = index;
        s->bit_timing_pending = true;
    }
    answer_bytes(s, CO_LSS_CS_CONFIGURE_BIT_TIMING, ok ? CO_LSS_ERR_OK : CO_LSS_ERR_BIT_TIMING,
                 0);
}

static void store_answered(co_lss_slave_t *s, uint8_t node_id, uint8_t error)
{
    if (error == CO_LSS_ERR_OK) {
        s->persistent_node_id = node_id;
    } else if (error != CO_LSS_ERR_STORE_MEDIA) {
        error = CO_LSS_ERR_STORE_NOT_SUPPORTED;   /* nothing else is defined */
    }
    answer_bytes(s, CO_LSS_CS_STORE_CONFIGURATION, error, 0);
}

static void store_configuration(co_lss_slave_t *s)
{
    if (s->store_waiting) {
        s->stats.store_busy++;   /* the application still writes the last one */
        return;
    }
    uint8_t error = CO_LSS_ERR_STORE_NOT_SUPPORTED;
    uint8_t node_id = s->pending_node_id;
    if (s->ind && s->ind->store) {
        error = s->ind->store(s, node_id, s->user);
    }
    if (error == CO_LSS_ERR_LATER) {
        s->store_waiting = true;
        s->store_node_id = node_id;
        return;
    }
    store_answered(s, node_id, error);
}

bool co_lss_slave_store_answer(co_lss_slave_t *slave, uint8_t error)
{
    if (!slave->store_waiting) {
        return false;
    }
    slave->store_waiting = false;
    store_answered(slave, slave->store_node_id, error);
    return true;
}

static void inquire(co_lss_slave_t *s, uint8_t cs)
{
    uint8_t data[8];
    if (cs == CO_LSS_CS_INQUIRE_NODE_ID) {
        co_lss_encode_bytes(data, cs, s->active_node_id, 0);
    } else {
        co_lss_encode_value(data, cs, s->address.part[cs - CO_LSS_CS_INQUIRE_VENDOR]);
    }
    answer(s, data);
}

/* The services of the configuration state; false when m is not one. */
static bool configuration_service(co_lss_slave_t *s, const co_lss_msg_t *m)
{
    switch (m->cs) {
    case CO_LSS_CS_CONFIGURE_NODE_ID:
        if (co_lss_node_id_valid(m->byte1)) {
            s->pending_node_id = m->byte1;
            answer_bytes(s, m->cs, CO_LSS_ERR_OK, 0);
        } else {
            s->stats.bad_argument++;
            answer_bytes(s, m->cs, CO_LSS_ERR_NODE_ID_RANGE, 0);
        }
        return true;
    case CO_LSS_CS_CONFIGURE_BIT_TIMING:
        configure_bit_timing(s, m->byte1, m->byte2);
        return true;
    case CO_LSS_CS_ACTIVATE_BIT_TIMING:
        if (s->ind && s->ind->activate_bit_timing) {
            s->ind->activate_bit_timing(s, m->delay_ms, s->user);
        }
        return true;
    case CO_LSS_CS_STORE_CONFIGURATION:
        store_configuration(s);
        return true;
    default:
        if (m->cs >= CO_LSS_CS_INQUIRE_VENDOR && m->cs <= CO_LSS_CS_INQUIRE_NODE_ID) {
            inquire(s, m->cs);
            return true;
        }
        return false;
    }
}

/* The services of the waiting state; false when m is not one. */
static bool waiting_service(co_lss_slave_t *s, const co_lss_msg_t *m)
{
    if (m->cs >= CO_LSS_CS_SELECT_VENDOR && m->cs <= CO_LSS_CS_SELECT_SERIAL) {
        select_part(s, (uint8_t)(m->cs - CO_LSS_CS_SELECT_VENDOR), m->value);
        return true;
    }
    if (m->cs == CO_LSS_CS_FASTSCAN) {
        fastscan(s, m);
        return true;
    }
    return false;
}

static void on_request(co_line_t *line, const co_frame_t *frame, void *user)
{
    (void)line;
    co_lss_slave_t *s = user;
    co_lss_msg_t m;
    co_lss_decode_t r = co_lss_decode_request(frame->data, frame->len, &m);
    if (r == CO_LSS_DECODE_BAD_LENGTH || (frame->flags & CO_FRAME_RTR)) {
        s->stats.bad_length++;
        return;
    }
    if (r == CO_LSS_DECODE_UNKNOWN_CS) {
        s->stats.unknown_cs++;
        return;
    }
    s->stats.requests++;
    /* Served in both states. */
    if (m.cs == CO_LSS_CS_SWITCH_GLOBAL) {
        switch_global(s, m.byte1);
        return;
    }
    if (m.cs >= CO_LSS_CS_IDENTIFY_VENDOR && m.cs <= CO_LSS_CS_IDENTIFY_SERIAL_HIGH) {
        identify_part(s, (uint8_t)(m.cs - CO_LSS_CS_IDENTIFY_VENDOR), m.value);
        return;
    }
    if (m.cs == CO_LSS_CS_IDENTIFY_NON_CONFIGURED) {
        if (non_configured(s)) {
            answer_bytes(s, CO_LSS_CS_NON_CONFIGURED_ANSWER, 0, 0);
        }
        return;
    }
    bool served = s->state == CO_LSS_STATE_CONFIGURATION ? configuration_service(s, &m)
                                                         : waiting_service(s, &m);
    if (!served) {
        s->stats.not_in_state++;
    }
}

bool co_lss_slave_init(co_lss_slave_t *slave, co_line_t *line, const co_lss_address_t *address,
                       uint8_t node_id, const co_lss_slave_indications_t *ind, void *user)
{
    memset(slave, 0, sizeof *slave);
    if (!co_lss_node_id_valid(node_id)) {
        return false;
    }
    slave->line = line;
    slave->address = *address;
    slave->state = CO_LSS_STATE_WAITING;
    slave->active_node_id = node_id;
    slave->pending_node_id = node_id;
    slave->persistent_node_id = node_id;
    slave->ind = ind;
    slave->user = user;
    return co_line_subscribe(line, CO_LSS_ID_MASTER, CO_LSS_ID_MASTER, on_request, slave);
}

void co_lss_slave_deinit(co_lss_slave_t *slave)
{
    co_line_unsubscribe(slave->line, on_request, slave);
}

uint8_t co_lss_slave_reset_communication(co_lss_slave_t *slave)
{
    slave->active_node_id = slave->pending_node_id;
    return slave->active_node_id;
}

void co_lss_slave_follow_node_id(co_lss_slave_t *slave, uint8_t node_id)
{
    slave->active_node_id = node_id;
    slave->pending_node_id = node_id;
}
