/* co_led: CiA 303-3 run and error indicators (see co_led.h). */
#include "canopenfd/co_led.h"

#include <string.h>

enum { SLOTS_PER_CYCLE = CO_LED_CYCLE_TICKS / CO_LED_SLOT_TICKS };

bool co_led_lit(co_led_pattern_t pattern, co_led_which_t which, bool same_phase,
                uint32_t tick)
{
    tick %= (uint32_t)CO_LED_CYCLE_TICKS;
    switch (pattern) {
    case CO_LED_OFF:
        return false;
    case CO_LED_ON:
        return true;
    case CO_LED_FLICKERING:
        /* always in antiphase: the error LED takes the even ticks */
        return (tick % 2u) == (which == CO_LED_ERROR ? 0u : 1u);
    default:
        break;
    }
    uint32_t slot = tick / (uint32_t)CO_LED_SLOT_TICKS;
    if (which == CO_LED_RUN && !same_phase) {
        /* one slot behind: the run LED lights only in odd slots, the error
         * LED's blinks and flashes only in even ones */
        slot = (slot + SLOTS_PER_CYCLE - 1u) % SLOTS_PER_CYCLE;
    }
    if (pattern == CO_LED_BLINKING) {
        return slot % 2u == 0u;
    }
    if (pattern < CO_LED_SINGLE_FLASH || pattern > CO_LED_QUADRUPLE_FLASH) {
        return false;
    }
    /* n flashes: on, off, ..., on (2n - 1 slots), then 1000 ms = 5 slots off */
    uint32_t flashes = (uint32_t)pattern - (uint32_t)CO_LED_SINGLE_FLASH + 1u;
    uint32_t in_cycle = slot % (2u * flashes + 4u);
    return in_cycle < 2u * flashes && in_cycle % 2u == 0u;
}

static bool steady(co_led_pattern_t pattern)
{
    return pattern == CO_LED_OFF || pattern == CO_LED_ON;
}

/* The precedence rules of co_led.h. */
static co_led_pattern_t run_pattern(const co_led_t *led)
{
    if (led->lss) {
        return CO_LED_FLICKERING;
    }
    switch (led->nmt_state) {
    case CO_NMT_STOPPED:
        return CO_LED_SINGLE_FLASH;
    case CO_NMT_PRE_OPERATIONAL:
        return CO_LED_BLINKING;
    case CO_NMT_OPERATIONAL:
        return CO_LED_ON;
    default:
        return CO_LED_OFF;
    }
}

static co_led_pattern_t error_pattern(const co_led_t *led)
{
    uint8_t c = led->causes;
    if (c & CO_LED_CAUSE_BUS_OFF) {
        return CO_LED_ON;
    }
    if (led->lss) {
        return CO_LED_FLICKERING;
    }
    if (c & CO_LED_CAUSE_EVENT_TIMER) {
        return CO_LED_QUADRUPLE_FLASH;
    }
    if (c & CO_LED_CAUSE_SYNC) {
        return CO_LED_TRIPLE_FLASH;
    }
    if (c & CO_LED_CAUSE_ERROR_CONTROL) {
        return CO_LED_DOUBLE_FLASH;
    }
    if (c & CO_LED_CAUSE_WARNING) {
        return CO_LED_SINGLE_FLASH;
    }
    if (c & CO_LED_CAUSE_CONFIG) {
        return CO_LED_BLINKING;
    }
    return CO_LED_OFF;
}

/* The timebase tick (50 ms units, modulo the common cycle) at `now_us`. */
static uint32_t tick_at(const co_led_t *led, uint64_t now_us)
{
    if (!led->timebase || now_us < led->timebase_us) {
        return 0;
    }
    uint64_t ticks = (now_us - led->timebase_us) / (uint64_t)CO_LED_TICK_US;
    return (uint32_t)(ticks % (uint64_t)CO_LED_CYCLE_TICKS);
}

/* The timer runs while a pattern is not steady and someone listens. It
 * fires on the timebase's 50 ms grid, at the next tick where a LED changes
 * (a blinking LED wakes the line 5 times a second, not 20), and always
 * after now, so a late call does not fire a burst of catch-up ticks. */
static void arm(co_led_t *led, uint64_t now_us)
{
    co_timer_list_t *timers = co_line_timers(led->line);
    if (!led->timebase || !led->changed) {
        co_timer_cancel(timers, &led->timer);
        return;
    }
    uint64_t elapsed = now_us > led->timebase_us ? now_us - led->timebase_us : 0;
    uint64_t tick = elapsed / (uint64_t)CO_LED_TICK_US;
    uint32_t at = (uint32_t)(tick % (uint64_t)CO_LED_CYCLE_TICKS);
    bool now_lit[2];
    for (int which = 0; which < 2; which++) {
        now_lit[which] = co_led_lit(led->pattern[which], (co_led_which_t)which,
                                    led->same_phase, at);
    }
    uint32_t ahead = 1;
    for (; ahead < (uint32_t)CO_LED_CYCLE_TICKS; ahead++) {
        bool change = false;
        for (int which = 0; which < 2; which++) {
            change |= co_led_lit(led->pattern[which], (co_led_which_t)which, led->same_phase,
                                 at + ahead) != now_lit[which];
        }
        if (change) {
            break;
        }
    }
    co_timer_start(timers, &led->timer,
                   led->timebase_us + (tick + ahead) * (uint64_t)CO_LED_TICK_US);
}

/* Recompute both LEDs at now_us and tell what changed (all state is
 * updated before the indication runs). */
static void refresh(co_led_t *led, uint64_t now_us)
{
    co_led_pattern_t patterns[2] = {run_pattern(led), error_pattern(led)};
    bool timed = !steady(patterns[0]) || !steady(patterns[1]);
    if (timed && !led->timebase) {
        led->timebase = true;   /* both LEDs' patterns start here, together */
        led->timebase_us = now_us;
    } else if (!timed) {
        led->timebase = false;
    }
    uint32_t tick = tick_at(led, now_us);
    bool changed[2];
    for (int which = 0; which < 2; which++) {
        bool on = co_led_lit(patterns[which], (co_led_which_t)which, led->same_phase, tick);
        changed[which] = on != led->on[which] || patterns[which] != led->pattern[which];
        led->on[which] = on;
        led->pattern[which] = patterns[which];
    }
    arm(led, now_us);
    /* a LED going dark is told before one lighting up, so a bi-colour LED
     * driven from the indication never shows both colours at once */
    for (int lit = 0; lit < 2; lit++) {
        for (int which = 0; which < 2; which++) {
            if (changed[which] && led->on[which] == (lit != 0) && led->changed) {
                led->changed(led, (co_led_which_t)which, led->on[which], led->pattern[which],
                             led->user);
            }
        }
    }
}

static void on_tick(co_timer_t *timer, uint64_t now_us, void *user)
{
    (void)timer;
    refresh(user, now_us);
}

void co_led_init(co_led_t *led, co_line_t *line, const co_led_config_t *config)
{
    memset(led, 0, sizeof *led);
    led->line = line;
    led->nmt_state = CO_NMT_INITIALISING;
    led->pattern[CO_LED_RUN] = CO_LED_OFF;
    led->pattern[CO_LED_ERROR] = CO_LED_OFF;
    if (config) {
        led->same_phase = config->same_phase;
        led->changed = config->changed;
        led->user = config->user;
    }
    co_timer_init(&led->timer, on_tick, led);
}

void co_led_deinit(co_led_t *led)
{
    co_timer_cancel(co_line_timers(led->line), &led->timer);
    led->changed = NULL;
}

void co_led_set_indication(co_led_t *led, co_led_fn changed, void *user)
{
    led->changed = changed;
    led->user = user;
    /* what the LEDs show now, as the new listener would have seen it */
    uint64_t now_us = co_line_now(led->line);
    uint32_t tick = tick_at(led, now_us);
    for (int which = 0; which < 2; which++) {
        led->on[which] = co_led_lit(led->pattern[which], (co_led_which_t)which,
                                    led->same_phase, tick);
    }
    arm(led, now_us);
}

void co_led_set_nmt_state(co_led_t *led, co_nmt_state_t state)
{
    if (led->nmt_state != state) {
        led->nmt_state = state;
        refresh(led, co_line_now(led->line));
    }
}

void co_led_set_lss(co_led_t *led, bool configuring)
{
    if (led->lss != configuring) {
        led->lss = configuring;
        refresh(led, co_line_now(led->line));
    }
}

void co_led_set_cause(co_led_t *led, uint8_t cause, bool active)
{
    co_led_set_causes(led, cause, active ? cause : 0u);
}

void co_led_set_causes(co_led_t *led, uint8_t mask, uint8_t active)
{
    uint8_t bits = (uint8_t)(mask & CO_LED_CAUSES);
    uint8_t causes = (uint8_t)((led->causes & ~bits) | (active & bits));
    if (causes != led->causes) {
        led->causes = causes;
        refresh(led, co_line_now(led->line));
    }
}

co_led_pattern_t co_led_pattern(const co_led_t *led, co_led_which_t which)
{
    return which == CO_LED_ERROR ? led->pattern[CO_LED_ERROR] : led->pattern[CO_LED_RUN];
}

bool co_led_is_on(const co_led_t *led, co_led_which_t which)
{
    int index = which == CO_LED_ERROR ? CO_LED_ERROR : CO_LED_RUN;
    return co_led_lit(led->pattern[index], (co_led_which_t)index, led->same_phase,
                      tick_at(led, co_line_now(led->line)));
}

const char *co_led_pattern_name(co_led_pattern_t pattern)
{
    switch (pattern) {
    case CO_LED_OFF: return "off";
    case CO_LED_ON: return "on";
    case CO_LED_FLICKERING: return "flickering";
    case CO_LED_BLINKING: return "blinking";
    case CO_LED_SINGLE_FLASH: return "single flash";
    case CO_LED_DOUBLE_FLASH: return "double flash";
    case CO_LED_TRIPLE_FLASH: return "triple flash";
    case CO_LED_QUADRUPLE_FLASH: return "quadruple flash";
    }
    return "unknown";
}
