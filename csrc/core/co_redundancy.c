/* Bus redundancy: the slave's bus selection driven by the redundancy
 * master's heartbeat, and the master's own choice (co_redundancy.h). */
#include "canopenfd/co_redundancy.h"

#include <stddef.h>

#define RDN_MS 1000u                  /* microseconds per millisecond */
#define RDN_HIGHEST_SUB 4u

static uint8_t other_bus(uint8_t bus) { return bus == CO_RDN_BUS_A ? CO_RDN_BUS_B : CO_RDN_BUS_A; }

/* A slave with Ttoggle 0 never switches: it stays on Bdefault. */
static bool may_switch(const co_rdn_t *rdn)
{
    return rdn->config.role == CO_RDN_SLAVE && rdn->config.ttoggle != 0;
}

static void tell(co_rdn_t *rdn, co_rdn_event_t event)
{
    if (rdn->on_event != NULL)
        rdn->on_event(rdn, event, rdn->active, rdn->user);
}

static void use_bus(co_rdn_t *rdn, uint8_t bus)
{
    rdn->active = bus;
    rdn->select(rdn, bus, rdn->user);
}

static void arm_after_periods(co_rdn_t *rdn, uint32_t periods)
{
    uint64_t delay = (uint64_t)periods * rdn->config.master_period_ms * RDN_MS;
    co_timer_start(co_line_timers(rdn->line), &rdn->toggle_timer,
                   co_line_now(rdn->line) + delay);
}

/* Ttoggle periods without the master: try the other bus, or give up. */
static void on_toggle(co_timer_t *timer, uint64_t now_us, void *user)
{
    co_rdn_t *rdn = user;
    (void)timer;
    (void)now_us;
    use_bus(rdn, other_bus(rdn->active));
    if (rdn->ctoggle < UINT8_MAX)
        rdn->ctoggle++;
    tell(rdn, CO_RDN_EV_BUS_SWITCH);
    if (rdn->ctoggle < rdn->config.ntoggle) {
        arm_after_periods(rdn, rdn->config.ttoggle);
        return;
    }
    /* The bus it gave up on is where it starts next time too. */
    rdn->config.bdefault = rdn->active;
    tell(rdn, CO_RDN_EV_NO_MASTER);
}

co_rdn_result_t co_rdn_check_sub(uint8_t sub, uint16_t data_type, uint8_t value)
{
    if (sub > RDN_HIGHEST_SUB)
        return CO_RDN_NO_SUB;
    if (data_type != CO_RDN_TYPE_UNSIGNED8)
        return CO_RDN_BAD_TYPE;
    if (sub == CO_RDN_SUB_BDEFAULT && value > CO_RDN_BUS_B)
        return CO_RDN_BAD_BUS;
    if (sub == CO_RDN_SUB_NTOGGLE && value == 0)
        return CO_RDN_BAD_NTOGGLE;
    return CO_RDN_OK;
}

co_rdn_result_t co_rdn_check_config(const co_rdn_config_t *config)
{
    if (config->bdefault > CO_RDN_BUS_B)
        return CO_RDN_BAD_BUS;
    if (config->ntoggle == 0)
        return CO_RDN_BAD_NTOGGLE;
    if (config->role == CO_RDN_SLAVE) {
        if (config->master_id < 1 || config->master_id > 127)
            return CO_RDN_BAD_MASTER;
        if (config->ttoggle != 0 && config->master_period_ms == 0)
            return CO_RDN_BAD_PERIOD;
    }
    return CO_RDN_OK;
}

const char *co_rdn_result_text(co_rdn_result_t result)
{
    switch (result) {
    case CO_RDN_OK: return "ok";
    case CO_RDN_BAD_TYPE: return "every sub-index of the redundancy object must be UNSIGNED8";
    case CO_RDN_BAD_BUS: return "Bdefault must be 0 (bus A) or 1 (bus B)";
    case CO_RDN_BAD_NTOGGLE: return "Ntoggle must be 1..255 (switches before giving up)";
    case CO_RDN_READ_ONLY: return "Ctoggle and the sub-index count are read-only";
    case CO_RDN_NO_SUB: return "the redundancy object has sub-indices 0..4 only";
    case CO_RDN_BAD_MASTER: return "the redundancy master's node-id must be 1..127";
    case CO_RDN_BAD_PERIOD:
        return "a slave that may switch (Ttoggle > 0) needs the master's heartbeat period > 0 ms";
    case CO_RDN_NOT_MASTER: return "only the redundancy master selects the bus";
    case CO_RDN_MISSING_SUB:
        return "the redundancy record needs sub-indices 1..4 (Bdefault, Ttoggle, Ntoggle, Ctoggle)";
    }
    return "unknown redundancy result";
}

bool co_rdn_init(co_rdn_t *rdn, co_line_t *line, const co_rdn_config_t *config,
                 co_rdn_select_fn select, co_rdn_event_fn on_event, void *user)
{
    if (line == NULL || config == NULL || select == NULL || co_rdn_check_config(config) != CO_RDN_OK)
        return false;
    rdn->line = line;
    rdn->config = *config;
    rdn->active = config->bdefault;
    rdn->ctoggle = 0;
    rdn->select = select;
    rdn->on_event = on_event;
    rdn->user = user;
    co_timer_init(&rdn->toggle_timer, on_toggle, rdn);
    return true;
}

void co_rdn_deinit(co_rdn_t *rdn)
{
    co_timer_cancel(co_line_timers(rdn->line), &rdn->toggle_timer);
}

void co_rdn_start(co_rdn_t *rdn)
{
    uint8_t was = rdn->active;
    co_timer_cancel(co_line_timers(rdn->line), &rdn->toggle_timer);
    rdn->ctoggle = 0;
    use_bus(rdn, rdn->config.bdefault);
    /* A reset that takes the node off the bus it was on is a switch too. */
    if (was != rdn->active)
        tell(rdn, CO_RDN_EV_BUS_SWITCH);
    if (may_switch(rdn))
        arm_after_periods(rdn, rdn->config.ttoggle);
}

void co_rdn_master_heard(co_rdn_t *rdn)
{
    if (rdn->config.role != CO_RDN_SLAVE)
        return;
    co_timer_cancel(co_line_timers(rdn->line), &rdn->toggle_timer);
    rdn->ctoggle = 0;
}

void co_rdn_master_lost(co_rdn_t *rdn)
{
    if (!may_switch(rdn))
        return;
    arm_after_periods(rdn, rdn->config.ttoggle - 1u);
}

co_rdn_result_t co_rdn_master_select(co_rdn_t *rdn, uint8_t bus)
{
    if (rdn->config.role != CO_RDN_MASTER)
        return CO_RDN_NOT_MASTER;
    if (bus > CO_RDN_BUS_B)
        return CO_RDN_BAD_BUS;
    if (bus != rdn->active) {
        use_bus(rdn, bus);
        tell(rdn, CO_RDN_EV_BUS_SWITCH);
    }
    return CO_RDN_OK;
}

uint8_t co_rdn_read(const co_rdn_t *rdn, uint8_t sub)
{
    switch (sub) {
    case CO_RDN_SUB_COUNT: return RDN_HIGHEST_SUB;
    case CO_RDN_SUB_BDEFAULT: return rdn->config.bdefault;
    case CO_RDN_SUB_TTOGGLE: return rdn->config.ttoggle;
    case CO_RDN_SUB_NTOGGLE: return rdn->config.ntoggle;
    case CO_RDN_SUB_CTOGGLE: return rdn->ctoggle;
    default: return 0;
    }
}

co_rdn_result_t co_rdn_write(co_rdn_t *rdn, uint8_t sub, uint8_t value)
{
    co_rdn_result_t result = co_rdn_check_sub(sub, CO_RDN_TYPE_UNSIGNED8, value);
    if (result != CO_RDN_OK)
        return result;
    switch (sub) {
    case CO_RDN_SUB_BDEFAULT:
        rdn->config.bdefault = value;
        return CO_RDN_OK;
    case CO_RDN_SUB_TTOGGLE:
        if (value != 0 && rdn->config.role == CO_RDN_SLAVE && rdn->config.master_period_ms == 0)
            return CO_RDN_BAD_PERIOD;
        rdn->config.ttoggle = value;
        if (value == 0)
            co_timer_cancel(co_line_timers(rdn->line), &rdn->toggle_timer);
        return CO_RDN_OK;
    case CO_RDN_SUB_NTOGGLE:
        rdn->config.ntoggle = value;
        return CO_RDN_OK;
    default:
        return CO_RDN_READ_ONLY;
    }
}
