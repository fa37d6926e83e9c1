/* Runtime glue of the CiA 303-3 LEDs: the local node's co_led (run by its
 * co_stack) tells Python each change while it listens (rt_led_t; asked for
 * before the node exists too, so a node booted later is heard from its
 * boot); its state and the application's own causes are reached under the
 * lock. */
#include "co_rt_internal.h"

void rt_led_changed(co_led_t *led, co_led_which_t which, bool on, co_led_pattern_t pattern,
                    void *user)
{
    (void)led;
    rt_post(user, CO_EV_LED, (uint8_t)pattern, (uint32_t)which, on ? 1u : 0u, NULL);
}

int co_rt_led_listen(co_rt_t *rt, int line, int listen)
{
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        return CO_RT_ERR_ARGUMENT;
    }
    rt_mutex_lock(&rt->lock);
    l->led.events = listen != 0;
    co_led_t *led = co_stack_led(&l->stack);
    if (led) {
        co_line_set_time(&l->line, co_rt_now_us());
        co_led_set_indication(led, listen ? rt_led_changed : NULL, listen ? l : NULL);
    }
    return rt_kick_unlock(rt, CO_RT_OK);   /* the LED tick may be the next deadline now */
}

/* Under rt->lock (rt_node_line took it): the node's LEDs at the current
 * time, or NULL with the lock released and the error set. */
static co_led_t *node_led(co_rt_t *rt, rt_line_t *l)
{
    co_led_t *led = co_stack_led(&l->stack);
    if (!led) {
        rt_mutex_unlock(&rt->lock);
        rt_set_error(rt, "line %d: the local node runs no LED indicators", l->index);
        return NULL;
    }
    co_line_set_time(&l->line, co_rt_now_us());
    return led;
}

int co_rt_led_state(co_rt_t *rt, int line, co_rt_led_state_t *out)
{
    if (!out) {
        return rt_argument_error(rt, "line %d: LED state: no output", line);
    }
    rt_line_t *l = rt_node_line(rt, line, "LED state");
    co_led_t *led = l ? node_led(rt, l) : NULL;
    if (!led) {
        return CO_RT_ERR_STATE;
    }
    for (int which = 0; which < 2; which++) {
        out->pattern[which] = (int)co_led_pattern(led, (co_led_which_t)which);
        out->on[which] = co_led_is_on(led, (co_led_which_t)which) ? 1 : 0;
    }
    out->causes = co_led_causes(led);
    rt_mutex_unlock(&rt->lock);
    return CO_RT_OK;
}

int co_rt_led_causes(co_rt_t *rt, int line, int mask, int active)
{
    if (mask <= 0 || (mask & ~CO_LED_CAUSES) != 0) {
        return rt_argument_error(rt, "line %d: LED causes 0x%X: bits of 0x%X expected", line,
                                 (unsigned)mask, (unsigned)CO_LED_CAUSES);
    }
    rt_line_t *l = rt_node_line(rt, line, "LED causes");
    co_led_t *led = l ? node_led(rt, l) : NULL;
    if (!led) {
        return CO_RT_ERR_STATE;
    }
    co_led_set_causes(led, (uint8_t)mask, (uint8_t)active);
    return rt_kick_unlock(rt, CO_RT_OK);
}
