/* Configuration manager (CiA 302-3): see co_config.h for the sequence. The
 * two clients are driven through one pair of helpers (start a transfer, take
 * its result) so the sequence itself is written once. */
#include "canopenfd/co_config.h"

#include <stddef.h>
#include <string.h>

#include "canopenfd/co_od.h"
#include "canopenfd/co_usdo.h"

enum { STAMP_INDEX = 0x1020, STAMP_DATE_SUB = 1, STAMP_TIME_SUB = 2 };

static void sdo_done(co_sdo_request_t *r);
static void usdo_done(co_usdo_request_t *r);

void co_config_init_sdo(co_config_t *cfg, co_sdo_client_t *client)
{
    memset(cfg, 0, sizeof *cfg);
    cfg->sdo = client;
}

void co_config_init_usdo(co_config_t *cfg, co_usdo_client_t *client)
{
    memset(cfg, 0, sizeof *cfg);
    cfg->usdo = client;
}

static uint32_t get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static void put_u32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

/* Start one transfer with the bound client: 0 or the client's refusal as a
 * CiA 301 code. Uploads land in cfg->word (4 bytes at most). */
static uint32_t transfer(co_config_t *cfg, bool upload, uint16_t index, uint8_t sub,
                         const uint8_t *data, uint32_t size)
{
    cfg->buffer.data = upload ? cfg->word : (uint8_t *)(uintptr_t)data;
    cfg->buffer.size = upload ? 0 : size;
    cfg->buffer.capacity = upload ? sizeof cfg->word : size;
    if (cfg->sdo != NULL) {
        co_sdo_request_t *r = &cfg->sdo_req;
        memset(r, 0, sizeof *r);
        r->server = cfg->req.node;
        r->index = index;
        r->sub = sub;
        r->upload = upload;
        r->mode = CO_SDO_MODE_AUTO;
        r->size = upload ? 0 : size;
        r->source = co_sdo_buffer_source;
        r->sink = co_sdo_buffer_sink;
        r->ctx = &cfg->buffer;
        r->done = sdo_done;
        r->user = cfg;
        r->timeout_ms = cfg->req.timeout_ms;
        return co_sdo_client_start(cfg->sdo, r);
    } else {
        co_usdo_request_t *r = &cfg->usdo_req;
        uint8_t refused;
        memset(r, 0, sizeof *r);
        r->server = cfg->req.node;
        r->index = index;
        r->sub = sub;
        r->upload = upload;
        r->mode = CO_USDO_MODE_AUTO;
        r->type = 0;   /* DOMAIN: a concise DCF carries no data types */
        r->size = upload ? 0 : size;
        r->source = co_usdo_buffer_source;
        r->sink = co_usdo_buffer_sink;
        r->ctx = &cfg->buffer;
        r->done = usdo_done;
        r->user = cfg;
        r->timeout_ms = cfg->req.timeout_ms;
        refused = co_usdo_client_start(cfg->usdo, r);
        return refused == 0 ? 0 : co_usdo_abort_to_co(refused);
    }
}

static void finish(co_config_t *cfg, co_config_outcome_t outcome)
{
    co_config_result_t result = cfg->result;
    co_config_done_fn done = cfg->req.done;
    void *user = cfg->req.user;
    result.outcome = (uint8_t)outcome;
    cfg->state = CO_CONFIG_IDLE;
    cfg->cancelling = false;
    cfg->run++;   /* whatever the callbacks start is a new run */
    done(cfg, &result, user);
}

static void note_failure(co_config_t *cfg, uint16_t index, uint8_t sub, uint32_t abort,
                         bool from_node, uint32_t entry)
{
    if (cfg->result.abort != 0) {
        return;   /* the first failure stays */
    }
    cfg->result.index = index;
    cfg->result.sub = sub;
    cfg->result.abort = abort;
    cfg->result.from_node = from_node;
    cfg->result.entry = entry;
}

static void tell_entry(co_config_t *cfg, uint16_t index, uint8_t sub, uint32_t abort)
{
    if (cfg->req.entry != NULL) {
        cfg->req.entry(cfg, index, sub, abort, cfg->req.user);
    }
}

/* Upload the node's stamp 0x1020:sub (date, then time): 0 or the refusal. */
static uint32_t read_stamp(co_config_t *cfg, uint8_t sub)
{
    cfg->state = sub == STAMP_DATE_SUB ? CO_CONFIG_READ_DATE : CO_CONFIG_READ_TIME;
    return transfer(cfg, true, STAMP_INDEX, sub, NULL, 0);
}

/* Write the stamp 0x1020:sub, or end when its start is refused. */
static void write_stamp(co_config_t *cfg, uint8_t sub)
{
    uint32_t refused;
    put_u32(cfg->word, sub == STAMP_DATE_SUB ? cfg->req.date : cfg->req.time);
    cfg->state = sub == STAMP_DATE_SUB ? CO_CONFIG_WRITE_DATE : CO_CONFIG_WRITE_TIME;
    refused = transfer(cfg, false, STAMP_INDEX, sub, cfg->word, 4);
    if (refused != 0) {
        tell_entry(cfg, STAMP_INDEX, sub, refused);
        note_failure(cfg, STAMP_INDEX, sub, refused, false, cfg->it.count);
        finish(cfg, CO_CONFIG_RESULT_FAILED);
    }
}

/* Start the next DCF entry; after the last one the stamp or the end. Entries
 * whose start the client refuses count as failed ones. */
static void next_entry(co_config_t *cfg)
{
    for (;;) {
        uint32_t refused;
        co_concise_status_t s = co_concise_next(&cfg->it, &cfg->current);
        if (s != CO_CONCISE_OK) {
            /* END: the DCF was validated before, so nothing else comes */
            if (cfg->result.failed > 0) {
                finish(cfg, CO_CONFIG_RESULT_FAILED);
            } else if (cfg->req.check_stamp) {
                write_stamp(cfg, STAMP_DATE_SUB);
            } else {
                finish(cfg, CO_CONFIG_RESULT_OK);
            }
            return;
        }
        cfg->state = CO_CONFIG_WRITE_ENTRY;
        refused = transfer(cfg, false, cfg->current.index, cfg->current.sub, cfg->current.data,
                           cfg->current.size);
        if (refused == 0) {
            return;
        }
        cfg->result.failed++;
        note_failure(cfg, cfg->current.index, cfg->current.sub, refused, false,
                     cfg->current.number);
        tell_entry(cfg, cfg->current.index, cfg->current.sub, refused);
        if (!cfg->req.continue_on_error) {
            finish(cfg, CO_CONFIG_RESULT_FAILED);
            return;
        }
    }
}

/* A transfer ended (either client). */
static void transfer_done(co_config_t *cfg, uint32_t abort, bool from_node, uint32_t got)
{
    bool timeout = abort == CO_ABORT_TIMEOUT && !from_node;
    uint32_t run = cfg->run;
    uint16_t index = STAMP_INDEX;
    uint8_t sub = STAMP_DATE_SUB;
    if (cfg->cancelling) {
        finish(cfg, CO_CONFIG_RESULT_CANCELLED);
        return;
    }
    switch ((co_config_state_t)cfg->state) {
    case CO_CONFIG_READ_DATE:
    case CO_CONFIG_READ_TIME: {
        bool date = cfg->state == CO_CONFIG_READ_DATE;
        bool equal = abort == 0 && got == 4
                     && get_u32(cfg->word) == (date ? cfg->req.date : cfg->req.time);
        if (timeout) {
            note_failure(cfg, STAMP_INDEX, date ? STAMP_DATE_SUB : STAMP_TIME_SUB, abort,
                         false, 0);
            finish(cfg, CO_CONFIG_RESULT_TIMEOUT);
        } else if (equal && date) {
            uint32_t refused = read_stamp(cfg, STAMP_TIME_SUB);
            if (refused != 0) {
                note_failure(cfg, STAMP_INDEX, STAMP_TIME_SUB, refused, false, 0);
                finish(cfg, CO_CONFIG_RESULT_FAILED);
            }
        } else if (equal) {
            finish(cfg, CO_CONFIG_RESULT_SKIPPED);
        } else {
            next_entry(cfg);   /* differs, or the node has no 0x1020: configure */
        }
        return;
    }
    case CO_CONFIG_WRITE_ENTRY:
        index = cfg->current.index;
        sub = cfg->current.sub;
        if (abort == 0) {
            cfg->result.written++;
        } else {
            cfg->result.failed++;
            note_failure(cfg, index, sub, abort, from_node, cfg->current.number);
        }
        tell_entry(cfg, index, sub, abort);
        if (cfg->run != run) {
            return;   /* the indication cancelled: finished already */
        }
        if (timeout) {
            finish(cfg, CO_CONFIG_RESULT_TIMEOUT);
        } else if (abort != 0 && !cfg->req.continue_on_error) {
            finish(cfg, CO_CONFIG_RESULT_FAILED);
        } else {
            next_entry(cfg);
        }
        return;
    case CO_CONFIG_WRITE_DATE:
    case CO_CONFIG_WRITE_TIME:
        sub = cfg->state == CO_CONFIG_WRITE_DATE ? STAMP_DATE_SUB : STAMP_TIME_SUB;
        tell_entry(cfg, STAMP_INDEX, sub, abort);
        if (cfg->run != run) {
            return;   /* the indication cancelled: finished already */
        }
        if (abort != 0) {
            note_failure(cfg, STAMP_INDEX, sub, abort, from_node, cfg->it.count);
            finish(cfg, timeout ? CO_CONFIG_RESULT_TIMEOUT : CO_CONFIG_RESULT_FAILED);
        } else if (sub == STAMP_DATE_SUB) {
            write_stamp(cfg, STAMP_TIME_SUB);
        } else {
            finish(cfg, CO_CONFIG_RESULT_OK);
        }
        return;
    case CO_CONFIG_IDLE:
        return;
    }
}

static void sdo_done(co_sdo_request_t *r)
{
    co_config_t *cfg = r->user;
    transfer_done(cfg, r->abort, r->abort_from_server, r->upload ? r->transferred : 0);
}

static void usdo_done(co_usdo_request_t *r)
{
    co_config_t *cfg = r->user;
    uint32_t abort = r->abort == 0 ? 0 : co_usdo_abort_to_co(r->abort);
    transfer_done(cfg, abort, r->abort_from_server, r->upload ? r->transferred : 0);
}

co_config_start_status_t co_config_start(co_config_t *cfg, const co_config_request_t *req)
{
    co_concise_status_t s;
    uint32_t refused;
    uint32_t offset = 0;
    if (cfg == NULL || req == NULL) {
        return CO_CONFIG_START_ARGUMENT;
    }
    if (cfg->state != CO_CONFIG_IDLE) {
        return CO_CONFIG_START_BUSY;
    }
    if ((cfg->sdo == NULL) == (cfg->usdo == NULL) || req->node < 1 || req->node > 127
        || req->done == NULL || req->dcf == NULL) {
        return CO_CONFIG_START_ARGUMENT;
    }
    s = co_concise_validate(req->dcf, req->dcf_length, NULL, &offset);
    cfg->dcf_status = (uint8_t)s;
    cfg->dcf_offset = offset;
    if (s != CO_CONCISE_OK) {
        return CO_CONFIG_START_BAD_DCF;
    }
    cfg->req = *req;
    memset(&cfg->result, 0, sizeof cfg->result);
    cfg->result.node = req->node;
    cfg->cancelling = false;
    (void)co_concise_iter_init(&cfg->it, req->dcf, req->dcf_length);
    if (req->check_stamp && !req->force) {
        refused = read_stamp(cfg, STAMP_DATE_SUB);
        if (refused != 0) {
            cfg->state = CO_CONFIG_IDLE;
            cfg->result.abort = refused;
            return CO_CONFIG_START_REFUSED;
        }
        return CO_CONFIG_START_OK;
    }
    /* No stamp to compare (or forced): the first entry must start now, or
     * nothing runs. */
    {
        co_concise_iter_t probe = cfg->it;
        co_concise_entry_t first;
        if (co_concise_next(&probe, &first) == CO_CONCISE_OK) {
            cfg->it = probe;
            cfg->current = first;
            cfg->state = CO_CONFIG_WRITE_ENTRY;
            refused = transfer(cfg, false, first.index, first.sub, first.data, first.size);
            if (refused != 0) {
                cfg->state = CO_CONFIG_IDLE;
                cfg->result.abort = refused;
                cfg->result.index = first.index;
                cfg->result.sub = first.sub;
                return CO_CONFIG_START_REFUSED;
            }
            return CO_CONFIG_START_OK;
        }
    }
    /* An empty DCF and no stamp: nothing to write (refused rather than a
     * done() from inside the start call). */
    cfg->state = CO_CONFIG_IDLE;
    return CO_CONFIG_START_EMPTY;
}

bool co_config_cancel(co_config_t *cfg)
{
    if (cfg == NULL || cfg->state == CO_CONFIG_IDLE) {
        return false;
    }
    cfg->cancelling = true;
    if (cfg->sdo != NULL) {
        if (co_sdo_client_cancel(cfg->sdo, &cfg->sdo_req, 0)) {
            return true;
        }
    } else if (co_usdo_client_cancel(cfg->usdo, &cfg->usdo_req, 0)) {
        return true;
    }
    /* nothing in flight (cannot happen while a state is set): end here */
    finish(cfg, CO_CONFIG_RESULT_CANCELLED);
    return true;
}

bool co_config_running(const co_config_t *cfg)
{
    return cfg != NULL && cfg->state != CO_CONFIG_IDLE;
}

const char *co_config_outcome_text(co_config_outcome_t outcome)
{
    switch (outcome) {
    case CO_CONFIG_RESULT_OK: return "configured";
    case CO_CONFIG_RESULT_SKIPPED: return "skipped (0x1020 matches)";
    case CO_CONFIG_RESULT_FAILED: return "failed";
    case CO_CONFIG_RESULT_TIMEOUT: return "timeout";
    case CO_CONFIG_RESULT_CANCELLED: return "cancelled";
    }
    return "unknown outcome";
}
