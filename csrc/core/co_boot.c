/* co_boot: the CiA 302-2 "boot slave" process of one node (see co_boot.h). */
#include "canopenfd/co_boot.h"

#include <string.h>

static void enter(co_boot_t *b, co_boot_step_t step);

static void report(co_boot_t *b, co_boot_report_t *r)
{
    r->node_id = b->node_id;
    b->access->report(b, r, b->access->user);
}

static void arm(co_boot_t *b, uint32_t ms)
{
    co_timer_start(co_line_timers(b->line), &b->timer,
                   co_line_now(b->line) + (uint64_t)ms * 1000u);
}

static void finish(co_boot_t *b, co_boot_error_t error)
{
    co_timer_cancel(co_line_timers(b->line), &b->timer);
    b->reading = false;
    /* a node found operational by the keep-alive check was left as it was */
    if (error == CO_BOOT_OK && (b->state & 0x7Fu) == CO_NMT_OPERATIONAL) {
        error = CO_BOOT_ERR_L;
    }
    b->step = CO_BOOT_STEP_DONE;
    b->error = (uint8_t)error;
    co_boot_report_t r;
    memset(&r, 0, sizeof r);
    r.event = CO_BOOT_EV_DONE;
    r.step = CO_BOOT_STEP_DONE;
    r.error = (uint8_t)error;
    r.state = b->state;
    report(b, &r);
}

/* Start a read for the current step; a refused start ends the read at once
 * (through the same path as a completion). */
static void read_entry(co_boot_t *b, uint16_t index, uint8_t sub, bool first)
{
    if (first) {
        b->retries = CO_BOOT_UPLOAD_RETRIES;
    }
    b->index = index;
    b->sub = sub;
    b->reading = true;
    uint8_t step = b->step;
    uint32_t abort = b->access->upload(b, index, sub, b->access->user);
    if (abort != 0 && b->reading && b->step == step) {
        co_boot_upload_done(b, abort, NULL, 0);
    }
}

static void enter_identity(co_boot_t *b, co_boot_step_t step, uint32_t expected,
                           co_boot_error_t error, uint8_t sub, co_boot_step_t next)
{
    if (expected == 0) {
        enter(b, next);
        return;
    }
    b->step = (uint8_t)step;
    b->error = (uint8_t)error;
    read_entry(b, 0x1018, sub, true);
}

static void enter(co_boot_t *b, co_boot_step_t step)
{
    const co_boot_expect_t *e = &b->expect;
    switch (step) {
    case CO_BOOT_STEP_DEVICE_TYPE:
        b->step = (uint8_t)step;
        b->error = CO_BOOT_ERR_B;
        read_entry(b, 0x1000, e->device_type_sub, true);
        return;
    case CO_BOOT_STEP_VENDOR:
        enter_identity(b, step, e->vendor_id, CO_BOOT_ERR_D, 1, CO_BOOT_STEP_PRODUCT);
        return;
    case CO_BOOT_STEP_PRODUCT:
        enter_identity(b, step, e->product_code, CO_BOOT_ERR_M, 2, CO_BOOT_STEP_REVISION);
        return;
    case CO_BOOT_STEP_REVISION:
        enter_identity(b, step, e->revision, CO_BOOT_ERR_N, 3, CO_BOOT_STEP_SERIAL);
        return;
    case CO_BOOT_STEP_SERIAL:
        enter_identity(b, step, e->serial, CO_BOOT_ERR_O, 4, CO_BOOT_STEP_NODE_STATE);
        return;
    case CO_BOOT_STEP_NODE_STATE:
        if (!(e->assignment & CO_BOOT_ASSIGN_KEEP_ALIVE)) {
            enter(b, CO_BOOT_STEP_RESET_COMM);
            return;
        }
        b->step = (uint8_t)step;
        if (e->heartbeat_ms != 0) {
            /* the node's next heartbeat tells its state */
            b->error = CO_BOOT_ERR_E;
            arm(b, e->heartbeat_ms);
        } else {
            /* not consumed: ask once with a guarding remote frame */
            b->error = CO_BOOT_ERR_F;
            if (b->access->guard_request) {
                (void)b->access->guard_request(b, b->access->user);
            }
            arm(b, e->guard_timeout_ms ? e->guard_timeout_ms
                                       : (uint32_t)CO_BOOT_DEFAULT_GUARD_TIMEOUT_MS);
        }
        return;
    case CO_BOOT_STEP_RESET_COMM:
        b->step = (uint8_t)step;
        b->error = CO_BOOT_ERR_B;
        b->state = CO_NMT_UNKNOWN;
        arm(b, e->reset_timeout_ms ? e->reset_timeout_ms
                                   : (uint32_t)CO_BOOT_DEFAULT_RESET_TIMEOUT_MS);
        if (!b->access->nmt(b, CO_NMT_CMD_RESET_COMMUNICATION, b->access->user)) {
            finish(b, CO_BOOT_ERR_B);
        }
        return;
    case CO_BOOT_STEP_SOFTWARE:
        if (!(e->assignment & CO_BOOT_ASSIGN_CHECK_SOFTWARE)) {
            enter(b, CO_BOOT_STEP_CONFIG_DATE);
            return;
        }
        b->step = (uint8_t)step;
        b->error = CO_BOOT_ERR_G;
        if (e->software_id == 0) {
            finish(b, CO_BOOT_ERR_G);
            return;
        }
        read_entry(b, 0x1F56, 1, true);
        return;
    case CO_BOOT_STEP_UPDATE_SOFTWARE:
    case CO_BOOT_STEP_UPDATE_CONFIG: {
        b->step = (uint8_t)step;
        b->error = step == CO_BOOT_STEP_UPDATE_SOFTWARE ? CO_BOOT_ERR_I : CO_BOOT_ERR_J;
        co_boot_report_t r;
        memset(&r, 0, sizeof r);
        r.event = step == CO_BOOT_STEP_UPDATE_SOFTWARE ? CO_BOOT_EV_UPDATE_SOFTWARE
                                                       : CO_BOOT_EV_UPDATE_CONFIG;
        r.step = (uint8_t)step;
        report(b, &r);   /* may answer at once (co_boot_continue_*) */
        return;
    }
    case CO_BOOT_STEP_CONFIG_DATE:
        if (e->config_date == 0 || e->config_time == 0) {
            enter(b, CO_BOOT_STEP_UPDATE_CONFIG);
            return;
        }
        b->step = (uint8_t)step;
        b->error = CO_BOOT_ERR_J;
        read_entry(b, 0x1020, 1, true);
        return;
    case CO_BOOT_STEP_CONFIG_TIME:
        b->step = (uint8_t)step;
        read_entry(b, 0x1020, 2, true);
        return;
    case CO_BOOT_STEP_ERROR_CONTROL:
        b->step = (uint8_t)step;
        if (e->heartbeat_ms != 0) {
            b->error = CO_BOOT_ERR_K;
            arm(b, e->heartbeat_ms);
            return;
        }
        finish(b, CO_BOOT_OK);
        return;
    case CO_BOOT_STEP_IDLE:
    case CO_BOOT_STEP_DONE:
        break;
    }
}

static void on_timeout(co_timer_t *timer, uint64_t now_us, void *user)
{
    (void)timer;
    (void)now_us;
    co_boot_t *b = user;
    if (co_boot_running(b)) {
        finish(b, (co_boot_error_t)b->error);
    }
}

bool co_boot_init(co_boot_t *boot, co_line_t *line, uint8_t node_id,
                  const co_boot_access_t *access)
{
    if (!boot || !line || node_id < 1 || node_id > 127 || !access || !access->upload ||
        !access->nmt || !access->report) {
        return false;
    }
    memset(boot, 0, sizeof *boot);
    boot->line = line;
    boot->access = access;
    boot->node_id = node_id;
    boot->state = CO_NMT_UNKNOWN;
    co_timer_init(&boot->timer, on_timeout, boot);
    return true;
}

bool co_boot_start(co_boot_t *boot, const co_boot_expect_t *expect)
{
    if (!boot || !boot->line || !expect || co_boot_running(boot)) {
        return false;
    }
    boot->expect = *expect;
    boot->state = CO_NMT_UNKNOWN;
    boot->reading = false;
    boot->updated = false;
    boot->step = CO_BOOT_STEP_DEVICE_TYPE;   /* running while STARTED is told */
    co_boot_report_t r;
    memset(&r, 0, sizeof r);
    r.event = CO_BOOT_EV_STARTED;
    r.step = CO_BOOT_STEP_IDLE;
    report(boot, &r);
    if (boot->step != CO_BOOT_STEP_DEVICE_TYPE || boot->reading) {
        return true;   /* cancelled or restarted from the report */
    }
    if (!(expect->assignment & CO_BOOT_ASSIGN_SLAVE)) {
        finish(boot, CO_BOOT_ERR_A);
    } else if (!(expect->assignment & CO_BOOT_ASSIGN_BOOT)) {
        enter(boot, CO_BOOT_STEP_ERROR_CONTROL);
    } else {
        enter(boot, CO_BOOT_STEP_DEVICE_TYPE);
    }
    return true;
}

void co_boot_cancel(co_boot_t *boot)
{
    if (!boot || !boot->line) {
        return;
    }
    co_timer_cancel(co_line_timers(boot->line), &boot->timer);
    boot->reading = false;
    boot->step = CO_BOOT_STEP_IDLE;
}

static uint32_t le32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) |
           ((uint32_t)p[3] << 24);
}

/* The expected value of the read of the current step. */
static uint32_t expected_value(const co_boot_t *b)
{
    const co_boot_expect_t *e = &b->expect;
    switch ((co_boot_step_t)b->step) {
    case CO_BOOT_STEP_DEVICE_TYPE: return e->device_type;
    case CO_BOOT_STEP_VENDOR: return e->vendor_id;
    case CO_BOOT_STEP_PRODUCT: return e->product_code;
    case CO_BOOT_STEP_REVISION: return e->revision;
    case CO_BOOT_STEP_SERIAL: return e->serial;
    case CO_BOOT_STEP_SOFTWARE: return e->software_id;
    case CO_BOOT_STEP_CONFIG_DATE: return e->config_date;
    case CO_BOOT_STEP_CONFIG_TIME: return e->config_time;
    default: return 0;
    }
}

void co_boot_upload_done(co_boot_t *boot, uint32_t abort, const uint8_t *data, uint32_t len)
{
    if (!boot || !boot->reading || !co_boot_running(boot)) {
        return;
    }
    boot->reading = false;
    if (abort == CO_BOOT_ABORT_TIMEOUT && boot->retries > 0) {
        boot->retries--;
        read_entry(boot, boot->index, boot->sub, false);
        return;
    }
    co_boot_step_t step = (co_boot_step_t)boot->step;
    uint32_t expected = expected_value(boot);
    /* every value checked here is an UNSIGNED32: exactly 4 bytes */
    bool have = abort == 0 && data != NULL && len == 4;
    uint32_t got = have ? le32(data) : 0;
    /* the device type is compared only when one is expected */
    bool matched = have && (got == expected ||
                            (step == CO_BOOT_STEP_DEVICE_TYPE && expected == 0));
    co_boot_report_t r;
    memset(&r, 0, sizeof r);
    r.event = CO_BOOT_EV_CHECKED;
    r.step = (uint8_t)step;
    r.index = boot->index;
    r.sub = boot->sub;
    r.matched = matched;
    r.expected = expected;
    r.got = got;
    r.got_length = abort == 0 ? len : 0;
    r.abort = abort;
    report(boot, &r);
    if (boot->step != (uint8_t)step || boot->reading) {
        return;   /* cancelled or restarted from the report */
    }
    switch (step) {
    case CO_BOOT_STEP_DEVICE_TYPE:
        if (abort != 0) {
            finish(boot, CO_BOOT_ERR_B);
        } else if (!matched) {
            finish(boot, CO_BOOT_ERR_C);
        } else {
            enter(boot, CO_BOOT_STEP_VENDOR);
        }
        return;
    case CO_BOOT_STEP_VENDOR:
    case CO_BOOT_STEP_PRODUCT:
    case CO_BOOT_STEP_REVISION:
    case CO_BOOT_STEP_SERIAL:
        if (!matched) {
            finish(boot, (co_boot_error_t)boot->error);
        } else {
            enter(boot, (co_boot_step_t)(step + 1));   /* the next identity entry */
        }
        return;
    case CO_BOOT_STEP_SOFTWARE:
        if (abort != 0) {
            finish(boot, CO_BOOT_ERR_G);
        } else if (matched) {
            enter(boot, CO_BOOT_STEP_CONFIG_DATE);
        } else if (boot->updated) {
            /* an update that did not take: asking again could loop for ever */
            finish(boot, CO_BOOT_ERR_I);
        } else if ((boot->expect.assignment &
                    (CO_BOOT_ASSIGN_UPDATE_SOFTWARE | CO_BOOT_ASSIGN_KEEP_ALIVE)) ==
                   CO_BOOT_ASSIGN_UPDATE_SOFTWARE) {
            enter(boot, CO_BOOT_STEP_UPDATE_SOFTWARE);
        } else {
            finish(boot, CO_BOOT_ERR_H);
        }
        return;
    case CO_BOOT_STEP_CONFIG_DATE:
        enter(boot, matched ? CO_BOOT_STEP_CONFIG_TIME : CO_BOOT_STEP_UPDATE_CONFIG);
        return;
    case CO_BOOT_STEP_CONFIG_TIME:
        enter(boot, matched ? CO_BOOT_STEP_ERROR_CONTROL : CO_BOOT_STEP_UPDATE_CONFIG);
        return;
    default:
        return;
    }
}

void co_boot_ec_frame(co_boot_t *boot, const uint8_t *data, uint8_t len)
{
    if (!boot || !co_boot_running(boot) || !data || len < 1) {
        return;
    }
    uint8_t state = (uint8_t)(data[0] & 0x7Fu);   /* guarding answers carry a toggle */
    switch ((co_boot_step_t)boot->step) {
    case CO_BOOT_STEP_NODE_STATE:
        co_timer_cancel(co_line_timers(boot->line), &boot->timer);
        boot->state = state;
        if (state == CO_NMT_OPERATIONAL) {
            /* running already: no reset, no software or configuration step */
            enter(boot, CO_BOOT_STEP_ERROR_CONTROL);
        } else {
            enter(boot, CO_BOOT_STEP_RESET_COMM);
        }
        return;
    case CO_BOOT_STEP_RESET_COMM:
        if (data[0] == CO_NMT_INITIALISING) {   /* its boot-up */
            co_timer_cancel(co_line_timers(boot->line), &boot->timer);
            boot->state = CO_NMT_PRE_OPERATIONAL;
            enter(boot, CO_BOOT_STEP_SOFTWARE);
        }
        return;   /* heartbeats from before the reset do not count */
    case CO_BOOT_STEP_ERROR_CONTROL:
        if (boot->expect.heartbeat_ms != 0 && data[0] != CO_NMT_INITIALISING) {
            boot->state = state;
            finish(boot, CO_BOOT_OK);
        }
        return;
    default:
        if (data[0] != CO_NMT_INITIALISING) {
            boot->state = state;
        }
        return;
    }
}

static bool continue_step(co_boot_t *boot, co_boot_step_t step, bool done,
                          co_boot_step_t next, co_boot_error_t error)
{
    if (!boot || boot->step != (uint8_t)step) {
        return false;
    }
    if (done) {
        enter(boot, next);
    } else {
        finish(boot, error);
    }
    return true;
}

bool co_boot_continue_software(co_boot_t *boot, bool done)
{
    /* new software: the node is checked again from its identity on */
    if (boot && boot->step == CO_BOOT_STEP_UPDATE_SOFTWARE && done) {
        boot->updated = true;
    }
    return continue_step(boot, CO_BOOT_STEP_UPDATE_SOFTWARE, done, CO_BOOT_STEP_DEVICE_TYPE,
                         CO_BOOT_ERR_I);
}

bool co_boot_continue_config(co_boot_t *boot, bool done)
{
    return continue_step(boot, CO_BOOT_STEP_UPDATE_CONFIG, done, CO_BOOT_STEP_ERROR_CONTROL,
                         CO_BOOT_ERR_J);
}

const char *co_boot_error_text(co_boot_error_t error)
{
    switch (error) {
    case CO_BOOT_OK: return "OK";
    case CO_BOOT_ERR_A: return "A: not in the network list";
    case CO_BOOT_ERR_B: return "B: no answer from the node";
    case CO_BOOT_ERR_C: return "C: device type differs";
    case CO_BOOT_ERR_D: return "D: vendor-ID differs";
    case CO_BOOT_ERR_E: return "E: no heartbeat in the keep-alive check";
    case CO_BOOT_ERR_F: return "F: no guarding answer in the keep-alive check";
    case CO_BOOT_ERR_G: return "G: software identification not configured or not readable";
    case CO_BOOT_ERR_H: return "H: software differs, update not allowed";
    case CO_BOOT_ERR_I: return "I: software update failed";
    case CO_BOOT_ERR_J: return "J: configuration update failed";
    case CO_BOOT_ERR_K: return "K: no heartbeat at the start of error control";
    case CO_BOOT_ERR_L: return "L: node was operational";
    case CO_BOOT_ERR_M: return "M: product code differs";
    case CO_BOOT_ERR_N: return "N: revision number differs";
    case CO_BOOT_ERR_O: return "O: serial number differs";
    }
    return "unknown boot error";
}
