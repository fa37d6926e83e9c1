/* co_manager: the CiA 302-2 network start-up over co_boot (see co_manager.h). */
#include "canopenfd/co_manager.h"

#include "canopenfd/co_stack.h"   /* CO_CONFIG_CLASSIC / CO_CONFIG_FD */
#include "canopenfd/co_usdo.h"

#include <stddef.h>
#include <string.h>

static void emit(co_manager_t *m, co_manager_report_t *r)
{
    if (m->on_event) {
        m->on_event(m, r, m->user);
    }
}

static void emit_simple(co_manager_t *m, co_manager_event_t event, const co_manager_slave_t *s,
                        uint8_t error, uint8_t command)
{
    co_manager_report_t r;
    memset(&r, 0, sizeof r);
    r.event = (uint8_t)event;
    r.node_id = s ? s->node_id : 0;
    r.mandatory = s ? s->mandatory : false;
    r.error = error;
    r.command = command;
    emit(m, &r);
}

static co_manager_slave_t *slave_of(co_manager_t *m, uint8_t node_id)
{
    if (node_id < 1 || node_id > 127 || m->slot_of[node_id] == 0) {
        return NULL;
    }
    return &m->slaves[m->slot_of[node_id] - 1];
}

static co_manager_slave_t *slave_of_boot(co_boot_t *boot)
{
    /* the boot process is a member of its slave */
    return (co_manager_slave_t *)(void *)((char *)boot - offsetof(co_manager_slave_t, boot));
}

static uint32_t od_u32(const co_od_t *od, uint16_t index, uint8_t sub)
{
    uint32_t v = 0;
    return co_od_get_u32(od, index, sub, &v) ? v : 0;
}

static bool send_nmt(co_manager_t *m, co_nmt_command_t command, uint8_t node_id)
{
    /* to node 0 the manager follows too, unless the application switches it */
    bool self = node_id == 0 && !(command == CO_NMT_CMD_START &&
                                  (m->startup & CO_MANAGER_STARTUP_APP_OPERATIONAL));
    return co_nmt_master_send(m->line, m->local, command, node_id, self);
}

/* Node n is a slave of the network list (0x1F81:n bit 0). */
static bool in_network_list(const co_od_t *od, uint8_t node_id)
{
    return (od_u32(od, 0x1F81, node_id) & CO_BOOT_ASSIGN_SLAVE) != 0;
}

/* ------------------------------------------------------------ 0x1F82 request NMT */

enum { OD_REQUEST_NMT = 0x1F82, REQUEST_ALL_NODES = 0x80 };

/* The NMT command a 0x1F82 value asks for (CiA 302-2: the state wanted). */
static bool request_command(uint8_t value, co_nmt_command_t *out)
{
    switch (value) {
    case 4: *out = CO_NMT_CMD_STOP; return true;
    case 5: *out = CO_NMT_CMD_START; return true;
    case 6: *out = CO_NMT_CMD_RESET_NODE; return true;
    case 7: *out = CO_NMT_CMD_RESET_COMMUNICATION; return true;
    case 127: *out = CO_NMT_CMD_PRE_OPERATIONAL; return true;
    default: return false;
    }
}

/* A network write of 0x1F82:n: a state the manager knows a command for, to a
 * node of the network list (0x1F81:n bit 0) or to all (sub 0x80). */
static uint32_t request_check(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e,
                              const uint8_t *value, uint32_t length, void *user)
{
    (void)xfer;
    const co_manager_t *m = user;
    uint8_t sub = co_od_entry_sub(e);
    co_nmt_command_t command;
    if (sub == 0 || length != 1) {
        return CO_ABORT_NONE;          /* the OD's own checks say the rest */
    }
    if (m->passive) {
        return CO_ABORT_DATA_LOCAL;    /* another node is the active master */
    }
    if (!request_command(value[0], &command) ||
        (sub != REQUEST_ALL_NODES && !in_network_list(od, sub))) {
        return CO_ABORT_INVALID_VALUE;
    }
    return CO_ABORT_NONE;
}

static void request_written(co_od_t *od, const co_od_entry_t *e, co_od_origin_t origin,
                            void *user)
{
    uint8_t sub = co_od_entry_sub(e);
    uint8_t value;
    co_nmt_command_t command;
    if (origin != CO_ORIGIN_NETWORK || sub == 0 || !co_od_get_u8(od, OD_REQUEST_NMT, sub, &value) ||
        !request_command(value, &command)) {
        return;                        /* the manager's own state updates come here too */
    }
    co_manager_t *m = user;
    (void)send_nmt(m, command, sub == REQUEST_ALL_NODES ? 0 : sub);
}

static const co_od_handler_t request_handler = {.check_write = request_check,
                                                 .after_write = request_written};

/* 0x1F82:n reads as the last state the manager heard of slave n. */
static void request_show_state(co_manager_t *m, uint8_t node_id, uint8_t state)
{
    uint8_t value = state == CO_NMT_INITIALISING ? (uint8_t)CO_NMT_PRE_OPERATIONAL : state;
    uint8_t shown;
    /* heartbeats come every few ms: the OD (and its handlers) only hears of changes */
    if (m->request_nmt && co_od_get_u8(m->od, OD_REQUEST_NMT, node_id, &shown) &&
        shown != value) {
        (void)co_od_put(m->od, OD_REQUEST_NMT, node_id, &value, 1);
    }
}

/* ------------------------------------------------------------ 0x1F83 request node guarding */

enum { OD_REQUEST_GUARDING = 0x1F83 };

/* The guard time and life time factor 0x1F81:n gives node n (0: none). */
static uint16_t guard_time_of(const co_od_t *od, uint8_t node_id, uint8_t *factor)
{
    uint32_t assignment = od_u32(od, 0x1F81, node_id);
    *factor = (uint8_t)(assignment >> 8);
    return (uint16_t)(assignment >> 16);
}

static uint32_t guarding_check(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e,
                               const uint8_t *value, uint32_t length, void *user)
{
    (void)xfer;
    const co_manager_t *m = user;
    uint8_t sub = co_od_entry_sub(e);
    uint8_t factor;
    if (sub == 0 || length != 1) {
        return CO_ABORT_NONE;          /* the OD's own checks say the rest */
    }
    if (co_line_mode(m->line) != CO_MODE_CLASSIC || !m->guard) {
        return CO_ABORT_UNSUPPORTED_ACCESS;   /* fd: no remote frames, no guarding */
    }
    if (m->passive) {
        return CO_ABORT_DATA_LOCAL;
    }
    if (value[0] > 1 || (sub != REQUEST_ALL_NODES && !in_network_list(od, sub))) {
        return CO_ABORT_INVALID_VALUE;
    }
    if (value[0] == 1 && sub != REQUEST_ALL_NODES && guard_time_of(od, sub, &factor) == 0) {
        return CO_ABORT_DATA_STATE;    /* 0x1F81:n gives it no guard time */
    }
    return CO_ABORT_NONE;
}

static void guard_node(co_manager_t *m, uint8_t node_id, bool on)
{
    uint8_t factor;
    uint16_t guard_ms = guard_time_of(m->od, node_id, &factor);
    if (!on) {
        co_guard_master_unguard(m->guard, node_id);
    } else if (guard_ms != 0) {
        (void)co_guard_master_guard(m->guard, node_id, guard_ms, factor);
    }
}

static void guarding_written(co_od_t *od, const co_od_entry_t *e, co_od_origin_t origin,
                             void *user)
{
    co_manager_t *m = user;
    uint8_t sub = co_od_entry_sub(e);
    uint8_t value;
    if (origin != CO_ORIGIN_NETWORK || sub == 0 || !m->guard ||
        !co_od_get_u8(od, OD_REQUEST_GUARDING, sub, &value)) {
        return;
    }
    if (sub != REQUEST_ALL_NODES) {
        guard_node(m, sub, value == 1);
        return;
    }
    for (uint8_t id = 1; id <= 127; id++) {
        if (id != co_line_node_id(m->line) && in_network_list(od, id)) {
            guard_node(m, id, value == 1);
        }
    }
}

/* A read shows whether the node is guarded now (the manager guards and
 * unguards its slaves itself too). */
static uint32_t guarding_read(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e,
                              void *user)
{
    (void)xfer;
    const co_manager_t *m = user;
    uint8_t sub = co_od_entry_sub(e);
    uint8_t now = 0;
    uint8_t shown;
    if (sub == 0) {
        return CO_ABORT_NONE;
    }
    if (sub == REQUEST_ALL_NODES) {
        /* all: 1 when the list has slaves and every one is guarded */
        bool every = true;
        bool any = false;
        for (uint8_t id = 1; id <= 127; id++) {
            if (id != co_line_node_id(m->line) && in_network_list(od, id)) {
                any = true;
                every = every && co_guard_master_guards(m->guard, id);
            }
        }
        now = any && every ? 1u : 0u;
    } else {
        now = co_guard_master_guards(m->guard, sub) ? 1u : 0u;
    }
    if (co_od_get_u8(od, OD_REQUEST_GUARDING, sub, &shown) && shown != now) {
        (void)co_od_put(od, OD_REQUEST_GUARDING, sub, &now, 1);
    }
    return CO_ABORT_NONE;
}

static const co_od_handler_t guarding_handler = {.before_read = guarding_read,
                                                  .check_write = guarding_check,
                                                  .after_write = guarding_written};

/* ------------------------------------------------------------ 0x1F25 configuration request */

enum { OD_CONFIG_REQUEST = 0x1F25, OD_CONCISE_DCF = 0x1F22 };

static bool config_asked(const co_manager_t *m, uint8_t node_id)
{
    return (m->config_pending[node_id / 8] & (1u << (node_id % 8))) != 0 ||
           m->config_node == node_id;
}

static bool has_concise(const co_od_t *od, uint8_t node_id)
{
    return co_od_find(od, OD_CONCISE_DCF, node_id) != NULL;
}

static uint32_t config_check(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *e,
                             const uint8_t *value, uint32_t length, void *user)
{
    (void)xfer;
    const co_manager_t *m = user;
    uint8_t sub = co_od_entry_sub(e);
    if (sub == 0 || length != 4) {
        return CO_ABORT_NONE;          /* the OD's own checks say the rest */
    }
    if (m->passive) {
        return CO_ABORT_DATA_LOCAL;
    }
    uint32_t signature = (uint32_t)value[0] | (uint32_t)value[1] << 8 |
                         (uint32_t)value[2] << 16 | (uint32_t)value[3] << 24;
    if (signature != CO_MANAGER_CONFIG_SIGNATURE) {
        return CO_ABORT_DATA_STORE;    /* as CiA 301 answers a wrong save/load signature */
    }
    if (sub == REQUEST_ALL_NODES) {
        return co_od_has_index(od, OD_CONCISE_DCF) ? CO_ABORT_NONE : CO_ABORT_NO_DATA;
    }
    if (!in_network_list(od, sub)) {
        return CO_ABORT_INVALID_VALUE;
    }
    if (!has_concise(od, sub)) {
        return CO_ABORT_NO_DATA;
    }
    return config_asked(m, sub) ? CO_ABORT_DATA_STATE : CO_ABORT_NONE;
}

static void config_next(co_manager_t *m);

static void config_report(co_manager_t *m, uint8_t node_id, bool ok, uint16_t index, uint8_t sub,
                          uint32_t abort)
{
    co_manager_report_t r;
    memset(&r, 0, sizeof r);
    r.event = CO_MANAGER_EV_CONFIGURED;
    r.node_id = node_id;
    co_manager_slave_t *s = slave_of(m, node_id);
    r.mandatory = s ? s->mandatory : false;
    r.error = ok ? (uint8_t)CO_BOOT_OK : (uint8_t)CO_BOOT_ERR_J;
    r.boot.node_id = node_id;
    r.boot.index = index;
    r.boot.sub = sub;
    r.boot.abort = abort;
    emit(m, &r);
}

static void config_done(co_config_t *cfg, const co_config_result_t *result, void *user)
{
    (void)cfg;
    co_manager_t *m = user;
    uint8_t node_id = m->config_node;
    m->config_node = 0;
    bool ok = result->outcome == CO_CONFIG_RESULT_OK;
    config_report(m, node_id, ok, result->index, result->sub, result->abort);
    config_next(m);
}

/* Copy 0x1F22:n (a DOMAIN: read through the OD's handlers) into the DCF
 * buffer: 0 or the abort code. */
static uint32_t load_concise(co_manager_t *m, uint8_t node_id, uint32_t *length)
{
    co_od_xfer_t xfer;
    uint8_t scratch[4];   /* domains stream through their handler: no copy kept */
    co_od_xfer_init(&xfer, scratch, sizeof scratch);
    uint32_t abort = co_od_read_begin(m->od, &xfer, OD_CONCISE_DCF, node_id);
    *length = 0;
    while (abort == 0) {
        uint32_t n = 0;
        bool last = false;
        if (*length == m->dcf_capacity) {
            abort = CO_ABORT_OUT_OF_MEMORY;
            break;
        }
        abort = co_od_read_chunk(&xfer, m->dcf + *length, m->dcf_capacity - *length, &n, &last);
        *length += n;
        if (last) {
            break;
        }
        if (abort == 0 && n == 0) {
            /* a reader that gives nothing and does not end would keep
             * this loop (and the runtime thread) here for ever */
            abort = CO_ABORT_GENERAL;
        }
    }
    if (abort == CO_OD_SPLIT) {
        abort = CO_ABORT_DATA_STATE;   /* an application that answers later: not here */
    }
    co_od_xfer_abort(&xfer, abort);
    return abort;
}

/* Start the next asked-for configuration unless one runs. */
static void config_next(co_manager_t *m)
{
    while (m->config_node == 0 && !m->passive) {
        uint8_t node_id = 0;
        for (uint8_t id = 1; id <= 127 && node_id == 0; id++) {
            if (m->config_pending[id / 8] & (1u << (id % 8))) {
                node_id = id;
            }
        }
        if (node_id == 0) {
            return;
        }
        m->config_pending[node_id / 8] &= (uint8_t)~(1u << (node_id % 8));
        uint32_t length = 0;
        uint32_t abort = load_concise(m, node_id, &length);
        if (abort != 0 || length == 0) {
            config_report(m, node_id, false, OD_CONCISE_DCF, node_id,
                          abort ? abort : CO_ABORT_NO_DATA);
            continue;
        }
        uint32_t date = od_u32(m->od, 0x1F26, node_id);
        uint32_t time = od_u32(m->od, 0x1F27, node_id);
        co_config_request_t req = {.node = node_id, .dcf = m->dcf, .dcf_length = length,
                                   .check_stamp = date != 0 && time != 0, .force = true,
                                   .date = date, .time = time, .done = config_done,
                                   .user = m};
        m->config_node = node_id;
        co_config_start_status_t started = co_config_start(&m->config, &req);
        if (started != CO_CONFIG_START_OK) {
            m->config_node = 0;
            config_report(m, node_id, false, OD_CONCISE_DCF, node_id,
                          started == CO_CONFIG_START_REFUSED ? m->config.result.abort
                          : started == CO_CONFIG_START_BAD_DCF ? CO_ABORT_INVALID_VALUE
                                                                : CO_ABORT_NO_DATA);
        }
    }
}

static void config_written(co_od_t *od, const co_od_entry_t *e, co_od_origin_t origin,
                           void *user)
{
    co_manager_t *m = user;
    uint8_t sub = co_od_entry_sub(e);
    if (origin != CO_ORIGIN_NETWORK || sub == 0) {
        return;
    }
    for (uint8_t id = 1; id <= 127; id++) {
        if ((sub == REQUEST_ALL_NODES || id == sub) && id != co_line_node_id(m->line) &&
            in_network_list(od, id) && has_concise(od, id) && !config_asked(m, id)) {
            m->config_pending[id / 8] |= (uint8_t)(1u << (id % 8));
        }
    }
    config_next(m);
}

static const co_od_handler_t config_handler = {.check_write = config_check,
                                                .after_write = config_written};

static void config_stop(co_manager_t *m)
{
    memset(m->config_pending, 0, sizeof m->config_pending);
    if (m->config_node != 0) {
        (void)co_config_cancel(&m->config);   /* its done() reports the node */
    }
}

/* ------------------------------------------------------------ the access */

static void read_done(co_manager_slave_t *s, uint32_t abort)
{
    s->reading = false;
    co_boot_upload_done(&s->boot, abort, s->sink.data, s->sink.size);
}

static void sdo_done(co_sdo_request_t *req)
{
    co_manager_slave_t *s = req->user;
    read_done(s, req->abort);
}

static void usdo_done(co_usdo_request_t *req)
{
    co_manager_slave_t *s = req->user;
    read_done(s, req->abort ? co_usdo_abort_to_co(req->abort) : 0);
}

static uint32_t access_upload(co_boot_t *boot, uint16_t index, uint8_t sub, void *user)
{
    co_manager_t *m = user;
    co_manager_slave_t *s = slave_of_boot(boot);
    s->sink.data = s->data;
    s->sink.size = 0;
    s->sink.capacity = sizeof s->data;
    if (CO_CONFIG_CLASSIC && m->sdo) {
        memset(&s->req.sdo, 0, sizeof s->req.sdo);
        s->req.sdo = (co_sdo_request_t){.server = s->node_id, .index = index, .sub = sub,
                                        .upload = true, .mode = CO_SDO_MODE_SEGMENTED,
                                        .sink = co_sdo_buffer_sink, .ctx = &s->sink,
                                        .done = sdo_done, .user = s};
        uint32_t refused = co_sdo_client_start(m->sdo, &s->req.sdo);
        s->reading = refused == 0;
        return refused;
    }
    if (!CO_CONFIG_FD || !m->usdo) {
        return 0x08000000u;
    }
    memset(&s->req.usdo, 0, sizeof s->req.usdo);
    s->req.usdo = (co_usdo_request_t){.server = s->node_id, .index = index, .sub = sub,
                                      .upload = true, .sink = co_usdo_buffer_sink,
                                      .ctx = &s->sink, .done = usdo_done, .user = s};
    uint8_t refused = co_usdo_client_start(m->usdo, &s->req.usdo);
    s->reading = refused == 0;
    return refused ? co_usdo_abort_to_co(refused) : 0;
}

static bool access_nmt(co_boot_t *boot, co_nmt_command_t command, void *user)
{
    co_manager_t *m = user;
    return send_nmt(m, command, slave_of_boot(boot)->node_id);
}

static bool access_guard(co_boot_t *boot, void *user)
{
    co_manager_t *m = user;
    if (co_line_mode(m->line) != CO_MODE_CLASSIC) {
        return false;   /* no remote frames on fd lines */
    }
    co_frame_t rtr;
    memset(&rtr, 0, sizeof rtr);
    rtr.id = CO_NMT_EC_COB_ID_BASE + slave_of_boot(boot)->node_id;
    rtr.flags = CO_FRAME_RTR;
    rtr.len = 1;
    return co_line_send_frame(m->line, &rtr);
}

/* ------------------------------------------------------------ the start */

static void launch_pending(co_manager_t *m);
static void check_network(co_manager_t *m);

static void cancel_read(co_manager_t *m, co_manager_slave_t *s)
{
    if (!s->reading) {
        return;
    }
    s->reading = false;
    co_boot_cancel(&s->boot);   /* the cancelled read's done() finds nothing running */
    if (CO_CONFIG_CLASSIC && m->sdo) {
        (void)co_sdo_client_cancel(m->sdo, &s->req.sdo, 0);
    } else if (CO_CONFIG_FD && m->usdo) {
        (void)co_usdo_client_cancel(m->usdo, &s->req.usdo, 0);
    }
}

static void stop_slave(co_manager_t *m, co_manager_slave_t *s)
{
    co_timer_cancel(co_line_timers(m->line), &s->retry);
    if (co_boot_running(&s->boot)) {
        cancel_read(m, s);
        co_boot_cancel(&s->boot);
        m->booting--;
    }
}

static void start_slave(co_manager_t *m, co_manager_slave_t *s)
{
    s->started = false;
    s->status = CO_MANAGER_SLAVE_PENDING;
    if (m->guard) {
        /* not guarded while it is reset and checked */
        co_guard_master_unguard(m->guard, s->node_id);
    }
    co_timer_cancel(co_line_timers(m->line), &s->retry);
    launch_pending(m);
}

static void launch_pending(co_manager_t *m)
{
    /* a process that ends inside co_boot_start comes back here: the outer
     * loop goes on instead, so the nesting stays one level deep */
    if (m->launching) {
        return;
    }
    m->launching = true;
    for (uint8_t i = 0; i < m->count && m->booting < m->parallel; i++) {
        co_manager_slave_t *s = &m->slaves[i];
        if (s->status != CO_MANAGER_SLAVE_PENDING) {
            continue;
        }
        s->status = CO_MANAGER_SLAVE_BOOTING;
        m->booting++;
        if (!co_boot_start(&s->boot, &s->expect)) {
            /* cannot happen for a pending slave (its process is not running);
             * kept so a slot is never lost */
            m->booting--;
            s->status = CO_MANAGER_SLAVE_FAILED;
        }
    }
    m->launching = false;
}

static void on_retry(co_timer_t *timer, uint64_t now_us, void *user)
{
    (void)timer;
    (void)now_us;
    co_manager_slave_t *s = user;
    if (s->status == CO_MANAGER_SLAVE_WAITING) {
        start_slave(s->owner, s);
    }
}

static void start_node(co_manager_t *m, co_manager_slave_t *s)
{
    if (s->started || (m->startup & CO_MANAGER_STARTUP_APP_STARTS_SLAVES)) {
        return;
    }
    s->started = true;
    if (s->error == CO_BOOT_ERR_L) {
        return;   /* operational already */
    }
    (void)send_nmt(m, CO_NMT_CMD_START, s->node_id);
    emit_simple(m, CO_MANAGER_EV_SLAVE_STARTED, s, 0, CO_NMT_CMD_START);
}

static void slave_booted(co_manager_t *m, co_manager_slave_t *s)
{
    s->status = CO_MANAGER_SLAVE_BOOTED;
    /* error control: heartbeat consumption runs from 0x1016 by itself; a
     * slave without a heartbeat time but with a guard time is guarded */
    uint16_t guard_ms = (uint16_t)(s->expect.assignment >> 16);
    if (m->guard && s->expect.heartbeat_ms == 0 && guard_ms != 0) {
        uint8_t factor = (uint8_t)(s->expect.assignment >> 8);
        (void)co_guard_master_guard(m->guard, s->node_id, guard_ms, factor);
    }
    emit_simple(m, CO_MANAGER_EV_SLAVE_BOOTED, s, s->error, 0);
    if (m->phase == CO_MANAGER_RUNNING) {
        start_node(m, s);   /* late, or back after an error */
    } else if (!s->mandatory && !(m->startup & CO_MANAGER_STARTUP_START_ALL)) {
        start_node(m, s);   /* optional: as soon as it is ready */
    }
    check_network(m);
}

static void slave_failed(co_manager_t *m, co_manager_slave_t *s)
{
    s->status = CO_MANAGER_SLAVE_FAILED;
    emit_simple(m, CO_MANAGER_EV_SLAVE_FAILED, s, s->error, 0);
    if (s->mandatory && (m->phase == CO_MANAGER_BOOTING || m->phase == CO_MANAGER_READY)) {
        m->phase = CO_MANAGER_HALTED;
        emit_simple(m, CO_MANAGER_EV_HALTED, s, s->error, 0);
    }
}

static void boot_ended(co_manager_t *m, co_manager_slave_t *s, co_boot_error_t error)
{
    m->booting--;
    s->error = (uint8_t)error;
    if (error == CO_BOOT_OK || error == CO_BOOT_ERR_L) {
        slave_booted(m, s);
    } else if (error == CO_BOOT_ERR_B &&
               !(s->mandatory && m->boot_time_ms != 0 &&
                 co_line_now(m->line) - m->started_us >= (uint64_t)m->boot_time_ms * 1000u)) {
        /* silent: ask again later (a mandatory slave until the boot time is over) */
        s->status = CO_MANAGER_SLAVE_WAITING;
        co_timer_start(co_line_timers(m->line), &s->retry,
                       co_line_now(m->line) + (uint64_t)m->retry_ms * 1000u);
    } else {
        slave_failed(m, s);
    }
    launch_pending(m);
}

static void access_report(co_boot_t *boot, const co_boot_report_t *report, void *user)
{
    co_manager_t *m = user;
    co_manager_slave_t *s = slave_of_boot(boot);
    co_manager_report_t r;
    memset(&r, 0, sizeof r);
    r.event = CO_MANAGER_EV_BOOT;
    r.node_id = s->node_id;
    r.mandatory = s->mandatory;
    r.boot = *report;
    emit(m, &r);
    switch ((co_boot_event_t)report->event) {
    case CO_BOOT_EV_UPDATE_SOFTWARE:
        if (m->hooks & CO_MANAGER_HOOK_SOFTWARE) {
            emit_simple(m, CO_MANAGER_EV_UPDATE_SOFTWARE, s, 0, 0);
        } else {
            (void)co_boot_continue_software(boot, false);   /* nobody to update it */
        }
        return;
    case CO_BOOT_EV_UPDATE_CONFIG:
        if (m->hooks & CO_MANAGER_HOOK_CONFIG) {
            emit_simple(m, CO_MANAGER_EV_UPDATE_CONFIG, s, 0, 0);
        } else {
            (void)co_boot_continue_config(boot, true);   /* nothing to configure */
        }
        return;
    case CO_BOOT_EV_DONE:
        boot_ended(m, s, (co_boot_error_t)report->error);
        return;
    case CO_BOOT_EV_STARTED:
    case CO_BOOT_EV_CHECKED:
        return;
    }
}

/* Every mandatory slave booted: on to operational. */
static void go_operational(co_manager_t *m)
{
    m->phase = CO_MANAGER_RUNNING;
    if (!(m->startup & CO_MANAGER_STARTUP_APP_OPERATIONAL)) {
        co_nmt_apply(m->local, CO_NMT_CMD_START);
    }
    if (!(m->startup & CO_MANAGER_STARTUP_APP_STARTS_SLAVES)) {
        if (m->startup & CO_MANAGER_STARTUP_START_ALL) {
            (void)send_nmt(m, CO_NMT_CMD_START, 0);
            for (uint8_t i = 0; i < m->count; i++) {
                if (m->slaves[i].status == CO_MANAGER_SLAVE_BOOTED) {
                    m->slaves[i].started = true;
                }
            }
            emit_simple(m, CO_MANAGER_EV_SLAVE_STARTED, NULL, 0, CO_NMT_CMD_START);
        } else {
            for (uint8_t i = 0; i < m->count; i++) {
                if (m->slaves[i].status == CO_MANAGER_SLAVE_BOOTED) {
                    start_node(m, &m->slaves[i]);
                }
            }
        }
    }
    emit_simple(m, CO_MANAGER_EV_NETWORK_STARTED, NULL, 0, 0);
}

static void check_network(co_manager_t *m)
{
    if (m->phase != CO_MANAGER_BOOTING) {
        return;
    }
    for (uint8_t i = 0; i < m->count; i++) {
        if (m->slaves[i].mandatory && m->slaves[i].status != CO_MANAGER_SLAVE_BOOTED) {
            return;
        }
    }
    m->phase = CO_MANAGER_READY;
    if (m->hooks & CO_MANAGER_HOOK_OPERATIONAL) {
        emit_simple(m, CO_MANAGER_EV_READY_OPERATIONAL, NULL, 0, 0);
    } else {
        go_operational(m);
    }
}

/* ------------------------------------------------------------ API */

uint8_t co_manager_slaves_in(const co_od_t *od, uint8_t own_node_id)
{
    uint8_t n = 0;
    for (uint8_t id = 1; od && id <= 127; id++) {
        if (id != own_node_id && in_network_list(od, id)) {
            n++;
        }
    }
    return n;
}

bool co_manager_init(co_manager_t *m, co_line_t *line, co_od_t *od, co_nmt_t *local,
                     co_sdo_client_t *sdo, co_usdo_client_t *usdo, co_guard_master_t *guard,
                     const co_manager_config_t *config)
{
    if (!m || !line || !od || !local || !config || (!config->slaves && config->capacity)) {
        return false;
    }
    memset(m, 0, sizeof *m);
    m->line = line;
    m->od = od;
    m->local = local;
    m->sdo = sdo;
    m->usdo = usdo;
    m->guard = guard;
    m->slaves = config->slaves;
    m->capacity = config->capacity;
    m->hooks = config->hooks;
    m->retry_ms = config->retry_ms ? config->retry_ms : (uint32_t)CO_MANAGER_DEFAULT_RETRY_MS;
    m->on_event = config->on_event;
    m->user = config->user;
    m->access = (co_boot_access_t){.upload = access_upload, .nmt = access_nmt,
                                   .guard_request = access_guard, .report = access_report,
                                   .user = m};
    if (co_od_has_index(od, OD_REQUEST_NMT)) {
        m->request_nmt = co_od_subscribe(od, OD_REQUEST_NMT, 1, OD_REQUEST_NMT,
                                         REQUEST_ALL_NODES, &request_handler, m);
    }
    if (co_od_has_index(od, OD_REQUEST_GUARDING)) {
        m->request_guard = co_od_subscribe(od, OD_REQUEST_GUARDING, 1, OD_REQUEST_GUARDING,
                                           REQUEST_ALL_NODES, &guarding_handler, m);
    }
    if (CO_CONFIG_CLASSIC && sdo) {
        co_config_init_sdo(&m->config, sdo);
    } else if (CO_CONFIG_FD && usdo) {
        co_config_init_usdo(&m->config, usdo);
    }
    m->dcf = config->dcf_buffer;
    m->dcf_capacity = config->dcf_buffer ? config->dcf_capacity : 0;
    if (m->dcf_capacity && (sdo || usdo) && co_od_has_index(od, OD_CONFIG_REQUEST)) {
        m->request_config = co_od_subscribe(od, OD_CONFIG_REQUEST, 1, OD_CONFIG_REQUEST,
                                            REQUEST_ALL_NODES, &config_handler, m);
    }
    uint8_t sessions = sdo ? sdo->channel_count : usdo ? usdo->session_count : 0;
    m->parallel = config->parallel ? config->parallel : sessions;
    if (m->parallel == 0) {
        m->parallel = 1;
    }
    return true;
}

static void stop_all(co_manager_t *m)
{
    for (uint8_t i = 0; i < m->count; i++) {
        stop_slave(m, &m->slaves[i]);
    }
    m->booting = 0;
}

void co_manager_stop(co_manager_t *m)
{
    if (!m || !m->line) {
        return;
    }
    m->wanted = false;
    stop_all(m);
}

void co_manager_deinit(co_manager_t *m)
{
    co_manager_stop(m);
    if (m && m->line) {
        config_stop(m);
        if (m->request_nmt) {
            co_od_unsubscribe(m->od, &request_handler, m);
            m->request_nmt = false;
        }
        if (m->request_guard) {
            co_od_unsubscribe(m->od, &guarding_handler, m);
            m->request_guard = false;
        }
        if (m->request_config) {
            co_od_unsubscribe(m->od, &config_handler, m);
            m->request_config = false;
        }
        m->line = NULL;
    }
}

void co_manager_set_active(co_manager_t *m, bool active)
{
    if (!m || !m->line) {
        return;
    }
    if (!active) {
        if (m->passive) {
            return;
        }
        /* another master runs the network now: hands off the slaves */
        m->passive = true;
        stop_all(m);
        config_stop(m);
        m->phase = CO_MANAGER_IDLE;
        emit_simple(m, CO_MANAGER_EV_PASSIVE, NULL, 0, 0);
        return;
    }
    bool was_passive = m->passive;
    m->passive = false;
    if (was_passive) {
        emit_simple(m, CO_MANAGER_EV_ACTIVE, NULL, 0, 0);
    }
    if (m->wanted && (was_passive || m->phase == CO_MANAGER_IDLE)) {
        (void)co_manager_start(m);   /* boots every slave: they were reset */
    }
}

/* The 0x1016 consumer time the manager has for node_id (0: none). */
static uint16_t heartbeat_time_of(const co_od_t *od, uint8_t node_id)
{
    for (uint8_t sub = 1; sub <= 127; sub++) {
        uint32_t v;
        if (!co_od_get_u32(od, 0x1016, sub, &v)) {
            break;
        }
        if (((v >> 16) & 0xFFu) == node_id && (v & 0xFFFFu) != 0) {
            return (uint16_t)v;
        }
    }
    return 0;
}

co_manager_status_t co_manager_start(co_manager_t *m)
{
    if (!m || !m->line) {
        return CO_MANAGER_NOT_MANAGER;
    }
    uint32_t startup = od_u32(m->od, 0x1F80, 0);
    if (!(startup & CO_MANAGER_STARTUP_MANAGER)) {
        return CO_MANAGER_NOT_MANAGER;
    }
    if (!m->sdo && !m->usdo) {
        return CO_MANAGER_NO_CLIENT;
    }
    uint8_t own = co_line_node_id(m->line);
    if (co_manager_slaves_in(m->od, own) > m->capacity) {
        return CO_MANAGER_NO_ROOM;
    }
    stop_all(m);
    m->wanted = true;
    if (m->passive) {
        m->phase = CO_MANAGER_IDLE;   /* runs once this node is the active master */
        return CO_MANAGER_OK;
    }
    m->startup = startup;
    m->boot_time_ms = od_u32(m->od, 0x1F89, 0);
    m->started_us = co_line_now(m->line);
    m->count = 0;
    m->booting = 0;
    memset(m->slot_of, 0, sizeof m->slot_of);
    for (uint8_t id = 1; id <= 127; id++) {
        uint32_t assignment = od_u32(m->od, 0x1F81, id);
        if (id == own || !(assignment & CO_BOOT_ASSIGN_SLAVE)) {
            continue;
        }
        co_manager_slave_t *s = &m->slaves[m->count];
        memset(s, 0, sizeof *s);
        s->owner = m;
        s->node_id = id;
        s->mandatory = (assignment & CO_BOOT_ASSIGN_MANDATORY) != 0;
        s->expect = (co_boot_expect_t){
            .assignment = assignment,
            .device_type = od_u32(m->od, 0x1F84, id),
            .vendor_id = od_u32(m->od, 0x1F85, id),
            .product_code = od_u32(m->od, 0x1F86, id),
            .revision = od_u32(m->od, 0x1F87, id),
            .serial = od_u32(m->od, 0x1F88, id),
            .config_date = od_u32(m->od, 0x1F26, id),
            .config_time = od_u32(m->od, 0x1F27, id),
            .software_id = od_u32(m->od, 0x1F55, id),
            .heartbeat_ms = heartbeat_time_of(m->od, id),
            /* CiA 1301: 0x1000 is an ARRAY on fd lines (logical device 1 checked) */
            .device_type_sub = co_line_mode(m->line) == CO_MODE_FD ? 1u : 0u};
        (void)co_boot_init(&s->boot, m->line, id, &m->access);
        co_timer_init(&s->retry, on_retry, s);
        s->status = CO_MANAGER_SLAVE_PENDING;
        m->slot_of[id] = (uint8_t)(m->count + 1u);
        m->count++;
    }
    m->phase = CO_MANAGER_BOOTING;
    launch_pending(m);
    check_network(m);   /* no mandatory slave: nothing to wait for */
    return CO_MANAGER_OK;
}

void co_manager_ec_frame(co_manager_t *m, const co_frame_t *frame)
{
    if (!m || !m->line || !frame || (frame->flags & CO_FRAME_RTR) || frame->len < 1 ||
        frame->id <= CO_NMT_EC_COB_ID_BASE || frame->id > CO_NMT_EC_COB_ID_BASE + 127u) {
        return;
    }
    co_manager_slave_t *s = slave_of(m, (uint8_t)(frame->id - CO_NMT_EC_COB_ID_BASE));
    if (!s) {
        return;
    }
    request_show_state(m, s->node_id, (uint8_t)(frame->data[0] & 0x7Fu));
    if (m->passive) {
        return;   /* another master boots the slaves */
    }
    if (co_boot_running(&s->boot)) {
        co_boot_ec_frame(&s->boot, frame->data, frame->len);
        return;
    }
    if (frame->data[0] != CO_NMT_INITIALISING || m->phase == CO_MANAGER_IDLE) {
        return;
    }
    /* a boot-up outside a boot process: the slave (re)appeared, boot it */
    if (s->status != CO_MANAGER_SLAVE_PENDING) {
        start_slave(m, s);
    }
}

void co_manager_ec_lost(co_manager_t *m, uint8_t node_id)
{
    if (!m || !m->line) {
        return;
    }
    co_manager_slave_t *s = slave_of(m, node_id);
    if (!s || s->status != CO_MANAGER_SLAVE_BOOTED || m->passive) {
        return;
    }
    if (s->mandatory && (m->startup & CO_MANAGER_STARTUP_STOP_ALL)) {
        (void)send_nmt(m, CO_NMT_CMD_STOP, 0);
        emit_simple(m, CO_MANAGER_EV_ERROR_CONTROL, s, 0, CO_NMT_CMD_STOP);
        return;
    }
    if (s->mandatory && (m->startup & CO_MANAGER_STARTUP_RESET_ALL)) {
        emit_simple(m, CO_MANAGER_EV_ERROR_CONTROL, s, 0, CO_NMT_CMD_RESET_NODE);
        (void)send_nmt(m, CO_NMT_CMD_RESET_NODE, 0);
        /* the manager reset itself too: the network boots again */
        (void)co_manager_start(m);
        return;
    }
    emit_simple(m, CO_MANAGER_EV_ERROR_CONTROL, s, 0, CO_NMT_CMD_RESET_NODE);
    (void)send_nmt(m, CO_NMT_CMD_RESET_NODE, node_id);
    start_slave(m, s);
}

bool co_manager_continue_software(co_manager_t *m, uint8_t node_id, bool done)
{
    co_manager_slave_t *s = m ? slave_of(m, node_id) : NULL;
    return s && co_boot_continue_software(&s->boot, done);
}

bool co_manager_continue_config(co_manager_t *m, uint8_t node_id, bool done)
{
    co_manager_slave_t *s = m ? slave_of(m, node_id) : NULL;
    return s && co_boot_continue_config(&s->boot, done);
}

bool co_manager_continue_operational(co_manager_t *m)
{
    if (!m || m->phase != CO_MANAGER_READY) {
        return false;
    }
    go_operational(m);
    return true;
}

co_manager_slave_status_t co_manager_slave_status(const co_manager_t *m, uint8_t node_id)
{
    if (!m || node_id < 1 || node_id > 127 || m->slot_of[node_id] == 0) {
        return CO_MANAGER_SLAVE_NONE;
    }
    return (co_manager_slave_status_t)m->slaves[m->slot_of[node_id] - 1].status;
}

co_boot_error_t co_manager_slave_error(const co_manager_t *m, uint8_t node_id)
{
    if (!m || node_id < 1 || node_id > 127 || m->slot_of[node_id] == 0) {
        return CO_BOOT_OK;
    }
    return (co_boot_error_t)m->slaves[m->slot_of[node_id] - 1].error;
}
