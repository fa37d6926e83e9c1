/* LSS master (see co_lss_master.h). */
#include "canopenfd/co_lss_master.h"

#include <string.h>

/* What the current step is. */
enum {
    STEP_ANSWER = 0,      /* a single service waits for its answer */
    FS_RESET,             /* fast scan: reset, does any non-configured slave answer? */
    FS_BIT,               /* fast scan: one bit checked */
    FS_CONFIRM,           /* fast scan: bit 0 was 1: the part confirmed */
    FS_CONFIGURE,         /* fast scan: the selected slave gets its node-id */
    FS_UNASSIGN,          /* fast scan: slaves sharing one address lose it again */
    SCAN_IDENTIFY         /* scan: identify remote slave over one range */
};

static bool send(co_lss_master_t *m, const uint8_t data[8])
{
    if (!co_line_send(m->line, CO_LSS_ID_MASTER, data, CO_LSS_FRAME_LEN)) {
        return false;
    }
    m->stats.frames_sent++;
    m->frames++;
    return true;
}

static void finish(co_lss_master_t *m, co_lss_status_t status, uint32_t value)
{
    co_timer_cancel(co_line_timers(m->line), &m->timer);
    co_lss_master_result_t r;
    memset(&r, 0, sizeof r);
    r.request = m->request;
    r.status = status;
    if (status == CO_LSS_REFUSED) {
        r.error = m->first.byte1;
        r.spec_error = m->first.byte2;
    }
    r.value = value;
    r.answers = m->answers;
    r.found = m->found;
    r.frames = m->frames;
    m->request = CO_LSS_REQ_NONE;
    m->waiting = false;
    m->expected_cs = 0;
    if (m->on_done) {
        m->on_done(m, &r, m->user);
    }
}

/* Send the step's last frame and wait for its answer. */
static void send_and_wait(co_lss_master_t *m, uint8_t step, const uint8_t data[8],
                          uint8_t expected_cs)
{
    m->step = step;
    m->answers = 0;
    memset(&m->first, 0, sizeof m->first);
    if (!send(m, data)) {
        finish(m, CO_LSS_TX_FAILED, 0);
        return;
    }
    m->expected_cs = expected_cs;
    m->waiting = true;
    co_timer_start(co_line_timers(m->line), &m->timer, co_line_now(m->line) + m->timeout_us);
}

/* Steps after which any number of slaves may answer. */
static bool many_may_answer(const co_lss_master_t *m)
{
    return m->step == FS_RESET || m->step == FS_BIT || m->step == FS_CONFIRM ||
           m->step == SCAN_IDENTIFY || m->request == CO_LSS_REQ_IDENTIFY_REMOTE ||
           m->request == CO_LSS_REQ_IDENTIFY_NON_CONFIGURED;
}

/* When a step that got its first answer ends. Slaves answer one request
 * with separate frames when their latencies differ (a software slave, a
 * busy one): a frame that comes after its step ended would be taken as the
 * next step's answer and corrupt a fast scan bit. So:
 * - the fast scan reset and the identify requests wait their whole timeout:
 *   they count every slave that answers;
 * - fast scan checks end a settle time after the first answer while more
 *   than one slave answered the last reset, at once when one did (the last
 *   slave, or a single one, runs at full speed);
 * - scan ranges (how many answer is unknown) end a settle time after;
 * - a single slave's answer ends its step at once.
 * "At once" is after this call's frames are all in: the timer list runs
 * after the rx queue is drained. CO_TIME_NEVER: the running timer stays. */
static uint64_t step_end_after_answer(const co_lss_master_t *m)
{
    uint64_t now = co_line_now(m->line);
    if (m->step == FS_RESET || m->request == CO_LSS_REQ_IDENTIFY_REMOTE ||
        m->request == CO_LSS_REQ_IDENTIFY_NON_CONFIGURED) {
        return CO_TIME_NEVER;
    }
    if (((m->step == FS_BIT || m->step == FS_CONFIRM) && m->reset_answers > 1u) ||
        m->step == SCAN_IDENTIFY) {
        return now + m->settle_us;
    }
    return now;
}

static void on_answer(co_line_t *line, const co_frame_t *frame, void *user)
{
    (void)line;
    co_lss_master_t *m = user;
    co_lss_msg_t msg;
    co_lss_decode_t r = co_lss_decode_answer(frame->data, frame->len, &msg);
    if (r == CO_LSS_DECODE_BAD_LENGTH || (frame->flags & CO_FRAME_RTR)) {
        m->stats.bad_length++;
        return;
    }
    if (r == CO_LSS_DECODE_UNKNOWN_CS) {
        m->stats.unknown_cs++;
        return;
    }
    m->stats.answers++;
    if (!m->waiting || msg.cs != m->expected_cs) {
        m->stats.unexpected++;
        return;
    }
    m->answers++;
    if (m->answers == 1u) {
        m->first = msg;
        uint64_t end = step_end_after_answer(m);
        if (end != CO_TIME_NEVER) {
            co_timer_start(co_line_timers(m->line), &m->timer, end);
        }
    } else if (!many_may_answer(m)) {
        m->stats.duplicates++;
    }
}

/* ---------------------------------------------------------------- fast scan */

static void fastscan_reset(co_lss_master_t *m)
{
    uint8_t data[8];
    co_lss_encode_fastscan(data, 0, CO_LSS_FASTSCAN_CONFIRM, 0, 0);
    send_and_wait(m, FS_RESET, data, CO_LSS_CS_IDENTIFY_ANSWER);
}

/* The part after `sub` the filter does not skip; 0 (the vendor-ID) after
 * the last one: a slave told so with its part matched is selected. */
static uint8_t fastscan_next_part(const co_lss_master_t *m, uint8_t sub)
{
    for (uint8_t next = (uint8_t)(sub + 1u); next < 4u; next++) {
        if (m->filter.kind[next] != CO_LSS_FS_SKIP) {
            return next;
        }
    }
    return 0;
}

/* Check the bits bit..31 of the current part, bit `bit` as 0. The check of
 * bit 0 already names the next part: a slave whose whole part matches moves
 * on with it, which saves the confirmation when bit 0 is 0. */
static void fastscan_bit(co_lss_master_t *m, uint8_t step)
{
    uint8_t next = m->bit == 0u ? fastscan_next_part(m, m->sub) : m->sub;
    uint8_t data[8];
    co_lss_encode_fastscan(data, m->id.part[m->sub], m->bit, m->sub, next);
    send_and_wait(m, step, data, CO_LSS_CS_IDENTIFY_ANSWER);
}

/* Start finding part m->sub: bit by bit, or its given value at once (the
 * confirmation step: slaves with another value stay silent). */
static void fastscan_part(co_lss_master_t *m)
{
    if (m->filter.kind[m->sub] == CO_LSS_FS_MATCH) {
        m->id.part[m->sub] = m->filter.match[m->sub];
        m->bit = 0;
        fastscan_bit(m, FS_CONFIRM);
        return;
    }
    m->bit = 31;
    fastscan_bit(m, FS_BIT);
}

static void fastscan_part_done(co_lss_master_t *m)
{
    uint8_t next = fastscan_next_part(m, m->sub);
    if (next != 0u) {
        m->sub = next;
        fastscan_part(m);
        return;
    }
    /* The slave is in the configuration state now. */
    if (m->node_id_count == 0u) {
        /* identify only: it stays selected for the caller */
        m->devices[0].address = m->id;
        m->devices[0].node_id = 0;
        m->found = 1;
        finish(m, CO_LSS_OK, 0);
        return;
    }
    uint8_t data[8];
    co_lss_encode_bytes(data, CO_LSS_CS_CONFIGURE_NODE_ID, m->node_ids[m->found], 0);
    send_and_wait(m, FS_CONFIGURE, data, CO_LSS_CS_CONFIGURE_NODE_ID);
}

static bool switch_waiting(co_lss_master_t *m)
{
    uint8_t data[8];
    co_lss_encode_bytes(data, CO_LSS_CS_SWITCH_GLOBAL, CO_LSS_STATE_WAITING, 0);
    return send(m, data);
}

/* No slave has the address found (a part did not confirm, or the address
 * selected nobody to configure): a slower slave's late answer was taken for
 * a 0-bit, or the slave is gone. Start over: every slave back to waiting,
 * the reset puts every non-configured one back to the vendor-ID; LOST after
 * CO_LSS_FASTSCAN_RESTARTS tries for one slave. */
static void fastscan_restart(co_lss_master_t *m)
{
    if (m->restarts >= CO_LSS_FASTSCAN_RESTARTS) {
        finish(m, CO_LSS_LOST, 0);
        return;
    }
    m->restarts++;
    m->stats.fastscan_restarts++;
    if (!switch_waiting(m)) {
        finish(m, CO_LSS_TX_FAILED, 0);
        return;
    }
    fastscan_reset(m);
}

static void fastscan_step_end(co_lss_master_t *m, bool answered)
{
    uint8_t data[8];
    switch (m->step) {
    case FS_RESET:
        m->reset_answers = m->answers;
        if (!answered) {
            /* after a restart: the slave that failed to confirm is gone */
            finish(m, m->restarts ? CO_LSS_LOST : CO_LSS_OK, 0);
        } else if (m->node_id_count != 0u && m->found >= m->node_id_count) {
            finish(m, CO_LSS_NO_NODE_ID, 0);
        } else if (m->found >= m->capacity) {
            finish(m, CO_LSS_FULL, 0);
        } else {
            memset(&m->id, 0, sizeof m->id);
            m->sub = 0;
            fastscan_part(m);
        }
        break;
    case FS_BIT:
        if (!answered) {
            m->id.part[m->sub] |= (uint32_t)1u << m->bit;   /* no slave has a 0 there */
        }
        if (m->bit > 0u) {
            m->bit--;
            fastscan_bit(m, FS_BIT);
        } else if (answered) {
            fastscan_part_done(m);
        } else {
            fastscan_bit(m, FS_CONFIRM);
        }
        break;
    case FS_CONFIRM:
        if (answered) {
            fastscan_part_done(m);
        } else if (m->filter.kind[m->sub] == CO_LSS_FS_MATCH) {
            /* no slave left has the value asked for: the others stay
             * unconfigured, the scan is over (nobody was selected) */
            finish(m, CO_LSS_OK, 0);
        } else {
            fastscan_restart(m);
        }
        break;
    case FS_CONFIGURE:
        if (!answered) {
            fastscan_restart(m);
        } else if (m->answers > 1u) {
            /* Two slaves took the same node-id: take it back from both. */
            co_lss_encode_bytes(data, CO_LSS_CS_CONFIGURE_NODE_ID, CO_LSS_NODE_ID_UNCONFIGURED,
                                0);
            send_and_wait(m, FS_UNASSIGN, data, CO_LSS_CS_CONFIGURE_NODE_ID);
        } else if (m->first.byte1 != CO_LSS_ERR_OK) {
            (void)switch_waiting(m);
            finish(m, CO_LSS_REFUSED, 0);
        } else {
            m->devices[m->found].address = m->id;
            m->devices[m->found].node_id = m->node_ids[m->found];
            m->found++;
            m->restarts = 0;
            if (!switch_waiting(m)) {
                finish(m, CO_LSS_TX_FAILED, 0);
                return;
            }
            fastscan_reset(m);
        }
        break;
    case FS_UNASSIGN:
    default:
        (void)switch_waiting(m);
        finish(m, CO_LSS_DUPLICATE, 0);
        break;
    }
}

/* --------------------------------------------------------------------- scan */

static bool identify_frames(co_lss_master_t *m, uint32_t rev_low, uint32_t rev_high,
                            uint32_t ser_low, uint32_t ser_high)
{
    const uint32_t values[5] = {m->vendor, m->product, rev_low, rev_high, ser_low};
    uint8_t data[8];
    for (uint8_t i = 0; i < 5u; i++) {
        co_lss_encode_value(data, (uint8_t)(CO_LSS_CS_IDENTIFY_VENDOR + i), values[i]);
        if (!send(m, data)) {
            return false;
        }
    }
    co_lss_encode_value(data, CO_LSS_CS_IDENTIFY_SERIAL_HIGH, ser_high);
    return send(m, data);
}

static bool push_range(co_lss_master_t *m, uint8_t level, uint32_t low, uint32_t high)
{
    if (m->depth >= CO_LSS_SCAN_STACK) {
        return false;
    }
    m->stack[m->depth++] = (co_lss_range_t){.low = low, .high = high, .level = level};
    return true;
}

/* Identify over the next range on the stack, or finish. */
static void scan_next(co_lss_master_t *m)
{
    if (m->depth == 0u) {
        finish(m, CO_LSS_OK, 0);
        return;
    }
    m->current = m->stack[--m->depth];
    const co_lss_range_t *c = &m->current;
    bool sent = c->level == 0u
                    ? identify_frames(m, m->revision_low, m->revision_high, c->low, c->high)
                    : identify_frames(m, c->low, c->high, m->serial, m->serial);
    if (!sent) {
        finish(m, CO_LSS_TX_FAILED, 0);
        return;
    }
    /* The sixth frame went out with identify_frames: only wait here. */
    m->step = SCAN_IDENTIFY;
    m->answers = 0;
    m->expected_cs = CO_LSS_CS_IDENTIFY_ANSWER;
    m->waiting = true;
    co_timer_start(co_line_timers(m->line), &m->timer, co_line_now(m->line) + m->timeout_us);
}

static void scan_step_end(co_lss_master_t *m, bool answered)
{
    co_lss_range_t c = m->current;
    if (answered) {
        bool ok = true;
        if (c.low != c.high) {
            /* Halve; the lower half is looked at first. */
            uint32_t mid = c.low + (c.high - c.low) / 2u;
            ok = push_range(m, c.level, mid + 1u, c.high) && push_range(m, c.level, c.low, mid);
        } else if (c.level == 0u) {
            m->serial = c.low;   /* a serial number: now its revisions */
            ok = push_range(m, 1, m->revision_low, m->revision_high);
        } else if (m->found < m->capacity) {
            co_lss_device_t *d = &m->devices[m->found++];
            d->address.part[CO_LSS_VENDOR] = m->vendor;
            d->address.part[CO_LSS_PRODUCT] = m->product;
            d->address.part[CO_LSS_REVISION] = c.low;
            d->address.part[CO_LSS_SERIAL] = m->serial;
            d->node_id = 0;
        } else {
            ok = false;
        }
        if (!ok) {
            finish(m, CO_LSS_FULL, 0);
            return;
        }
    }
    scan_next(m);
}

/* ------------------------------------------------------------- step's end */

static void on_timer(co_timer_t *timer, uint64_t now_us, void *user)
{
    (void)timer;
    (void)now_us;
    co_lss_master_t *m = user;
    if (!m->waiting) {
        return;
    }
    m->waiting = false;
    bool answered = m->answers > 0u;
    if (!answered) {
        m->stats.timeouts++;
    }
    if (m->request == CO_LSS_REQ_FASTSCAN) {
        fastscan_step_end(m, answered);
        return;
    }
    if (m->request == CO_LSS_REQ_SCAN) {
        scan_step_end(m, answered);
        return;
    }
    if (!answered) {
        finish(m, CO_LSS_TIMEOUT, 0);
        return;
    }
    switch (m->request) {
    case CO_LSS_REQ_CONFIGURE_NODE_ID:
    case CO_LSS_REQ_CONFIGURE_BIT_TIMING:
    case CO_LSS_REQ_STORE:
        finish(m, m->first.byte1 == CO_LSS_ERR_OK ? CO_LSS_OK : CO_LSS_REFUSED, 0);
        break;
    case CO_LSS_REQ_INQUIRE:
        finish(m, CO_LSS_OK,
               m->first.cs == CO_LSS_CS_INQUIRE_NODE_ID ? m->first.byte1 : m->first.value);
        break;
    default:
        finish(m, CO_LSS_OK, 0);
        break;
    }
}

/* ------------------------------------------------------------------- API */

bool co_lss_master_init(co_lss_master_t *master, co_line_t *line, uint32_t timeout_ms,
                        co_lss_done_fn on_done, void *user)
{
    memset(master, 0, sizeof *master);
    master->line = line;
    master->timeout_us = (uint64_t)(timeout_ms ? timeout_ms : 100u) * 1000u;
    master->settle_us = master->timeout_us / 8u;
    master->on_done = on_done;
    master->user = user;
    co_timer_init(&master->timer, on_timer, master);
    return co_line_subscribe(line, CO_LSS_ID_SLAVE, CO_LSS_ID_SLAVE, on_answer, master);
}

bool co_lss_master_set_timeout(co_lss_master_t *master, uint32_t timeout_ms)
{
    if (co_lss_master_busy(master)) {
        return false;
    }
    master->timeout_us = (uint64_t)(timeout_ms ? timeout_ms : 100u) * 1000u;
    master->settle_us = master->timeout_us / 8u;
    return true;
}

bool co_lss_master_set_settle(co_lss_master_t *master, uint32_t settle_us)
{
    if (co_lss_master_busy(master) || settle_us > master->timeout_us) {
        return false;
    }
    master->settle_us = settle_us;
    return true;
}

void co_lss_master_deinit(co_lss_master_t *master)
{
    co_timer_cancel(co_line_timers(master->line), &master->timer);
    co_line_unsubscribe(master->line, on_answer, master);
    master->request = CO_LSS_REQ_NONE;
}

void co_lss_master_cancel(co_lss_master_t *master)
{
    if (master->request != CO_LSS_REQ_NONE) {
        finish(master, CO_LSS_CANCELLED, 0);
    }
}

/* Take the master for a request. */
static bool begin(co_lss_master_t *m, co_lss_request_t request)
{
    if (m->request != CO_LSS_REQ_NONE) {
        return false;
    }
    m->request = request;
    m->frames = 0;
    m->found = 0;
    m->answers = 0;
    m->reset_answers = 0;
    m->restarts = 0;
    return true;
}

/* A single frame and its answer. */
static bool single(co_lss_master_t *m, co_lss_request_t request, const uint8_t data[8],
                   uint8_t expected_cs)
{
    if (!begin(m, request)) {
        return false;
    }
    send_and_wait(m, STEP_ANSWER, data, expected_cs);
    return true;
}

bool co_lss_master_switch_global(co_lss_master_t *master, co_lss_state_t state)
{
    if (co_lss_master_busy(master) ||
        (state != CO_LSS_STATE_WAITING && state != CO_LSS_STATE_CONFIGURATION)) {
        return false;
    }
    uint8_t data[8];
    co_lss_encode_bytes(data, CO_LSS_CS_SWITCH_GLOBAL, (uint8_t)state, 0);
    return send(master, data);
}

bool co_lss_master_activate_bit_timing(co_lss_master_t *master, uint16_t delay_ms)
{
    if (co_lss_master_busy(master)) {
        return false;
    }
    uint8_t data[8];
    co_lss_encode_delay(data, delay_ms);
    return send(master, data);
}

bool co_lss_master_switch_selective(co_lss_master_t *master, const co_lss_address_t *address)
{
    if (!begin(master, CO_LSS_REQ_SWITCH_SELECTIVE)) {
        return false;
    }
    uint8_t data[8];
    for (uint8_t i = 0; i < 3u; i++) {
        co_lss_encode_value(data, (uint8_t)(CO_LSS_CS_SELECT_VENDOR + i), address->part[i]);
        if (!send(master, data)) {
            finish(master, CO_LSS_TX_FAILED, 0);
            return true;
        }
    }
    co_lss_encode_value(data, CO_LSS_CS_SELECT_SERIAL, address->part[CO_LSS_SERIAL]);
    send_and_wait(master, STEP_ANSWER, data, CO_LSS_CS_SELECT_ANSWER);
    return true;
}

bool co_lss_master_configure_node_id(co_lss_master_t *master, uint8_t node_id)
{
    if (!co_lss_node_id_valid(node_id)) {
        return false;
    }
    uint8_t data[8];
    co_lss_encode_bytes(data, CO_LSS_CS_CONFIGURE_NODE_ID, node_id, 0);
    return single(master, CO_LSS_REQ_CONFIGURE_NODE_ID, data, CO_LSS_CS_CONFIGURE_NODE_ID);
}

bool co_lss_master_configure_bit_timing(co_lss_master_t *master, uint8_t table_selector,
                                        uint8_t table_index)
{
    uint8_t data[8];
    co_lss_encode_bytes(data, CO_LSS_CS_CONFIGURE_BIT_TIMING, table_selector, table_index);
    return single(master, CO_LSS_REQ_CONFIGURE_BIT_TIMING, data,
                  CO_LSS_CS_CONFIGURE_BIT_TIMING);
}

bool co_lss_master_store(co_lss_master_t *master)
{
    uint8_t data[8];
    co_lss_encode_bytes(data, CO_LSS_CS_STORE_CONFIGURATION, 0, 0);
    return single(master, CO_LSS_REQ_STORE, data, CO_LSS_CS_STORE_CONFIGURATION);
}

bool co_lss_master_inquire(co_lss_master_t *master, uint8_t what)
{
    if (what < CO_LSS_CS_INQUIRE_VENDOR || what > CO_LSS_CS_INQUIRE_NODE_ID) {
        return false;
    }
    uint8_t data[8];
    co_lss_encode_bytes(data, what, 0, 0);
    return single(master, CO_LSS_REQ_INQUIRE, data, what);
}

bool co_lss_master_identify_remote(co_lss_master_t *master, uint32_t vendor, uint32_t product,
                                   uint32_t revision_low, uint32_t revision_high,
                                   uint32_t serial_low, uint32_t serial_high)
{
    if (revision_low > revision_high || serial_low > serial_high ||
        !begin(master, CO_LSS_REQ_IDENTIFY_REMOTE)) {
        return false;
    }
    master->vendor = vendor;
    master->product = product;
    master->step = STEP_ANSWER;
    if (!identify_frames(master, revision_low, revision_high, serial_low, serial_high)) {
        finish(master, CO_LSS_TX_FAILED, 0);
        return true;
    }
    master->expected_cs = CO_LSS_CS_IDENTIFY_ANSWER;
    master->waiting = true;
    co_timer_start(co_line_timers(master->line), &master->timer,
                   co_line_now(master->line) + master->timeout_us);
    return true;
}

bool co_lss_master_identify_non_configured(co_lss_master_t *master)
{
    uint8_t data[8];
    co_lss_encode_bytes(data, CO_LSS_CS_IDENTIFY_NON_CONFIGURED, 0, 0);
    return single(master, CO_LSS_REQ_IDENTIFY_NON_CONFIGURED, data,
                  CO_LSS_CS_NON_CONFIGURED_ANSWER);
}

bool co_lss_master_fastscan(co_lss_master_t *master, const uint8_t *node_ids, uint32_t count,
                            co_lss_device_t *devices, uint32_t capacity)
{
    if (count == 0u) {
        return false;
    }
    return co_lss_master_fastscan_filtered(master, NULL, node_ids, count, devices, capacity);
}

bool co_lss_master_fastscan_filtered(co_lss_master_t *master,
                                     const co_lss_fastscan_filter_t *filter,
                                     const uint8_t *node_ids, uint32_t count,
                                     co_lss_device_t *devices, uint32_t capacity)
{
    if ((count != 0u && node_ids == NULL) || devices == NULL || capacity == 0u) {
        return false;
    }
    for (uint32_t i = 0; i < count; i++) {
        if (node_ids[i] < 1u || node_ids[i] > 127u) {
            return false;
        }
    }
    if (filter != NULL) {
        if (filter->kind[0] == CO_LSS_FS_SKIP) {
            return false;
        }
        for (int i = 0; i < 4; i++) {
            if (filter->kind[i] > CO_LSS_FS_MATCH) {
                return false;
            }
        }
    }
    if (!begin(master, CO_LSS_REQ_FASTSCAN)) {
        return false;
    }
    if (filter != NULL) {
        master->filter = *filter;
    } else {
        memset(&master->filter, 0, sizeof master->filter);
    }
    master->node_ids = node_ids;
    master->node_id_count = count;
    master->devices = devices;
    master->capacity = capacity;
    fastscan_reset(master);
    return true;
}

bool co_lss_master_scan(co_lss_master_t *master, uint32_t vendor, uint32_t product,
                        uint32_t revision_low, uint32_t revision_high, uint32_t serial_low,
                        uint32_t serial_high, co_lss_device_t *devices, uint32_t capacity)
{
    if (devices == NULL || capacity == 0u || revision_low > revision_high ||
        serial_low > serial_high || !begin(master, CO_LSS_REQ_SCAN)) {
        return false;
    }
    master->vendor = vendor;
    master->product = product;
    master->revision_low = revision_low;
    master->revision_high = revision_high;
    master->devices = devices;
    master->capacity = capacity;
    master->depth = 0;
    (void)push_range(master, 0, serial_low, serial_high);
    scan_next(master);
    return true;
}
