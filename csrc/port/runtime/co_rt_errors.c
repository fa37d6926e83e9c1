/* Runtime glue of the local node's error-status bits and EMCY code table
 * (co_errors, inside the stack): define, report / reset, conditions, state.
 * Refusals name the line, the bit and why. */
#include "co_rt_internal.h"

#include <string.h>

/* The line's error bits, locked (NULL with the error set, unlocked); the
 * line too when od is not NULL (the node's OD). */
static co_errors_t *locked_errors(co_rt_t *rt, int line, const char *what, co_od_t **od)
{
    rt_line_t *l = rt_node_line(rt, line, what);
    if (!l) {
        return NULL;
    }
    if (od) {
        *od = l->stack.od;
    }
    co_errors_t *e = co_stack_errors(&l->stack);
    if (!e) {
        rt_set_error(rt, "line %d: %s: the local node runs no EMCY producer yet", line, what);
        rt_mutex_unlock(&rt->lock);
    }
    return e;
}

int co_rt_errors_define(co_rt_t *rt, int line, int bit, int code, int register_bits)
{
    if (bit < CO_ERRORS_FIRST_APP_BIT || bit >= CO_ERRORS_BITS || code < 1 || code > 0xFFFF ||
        register_bits < 0 || register_bits > 0xFF || (register_bits & 0x40)) {
        return rt_argument_error(rt, "line %d: error bit %d, code 0x%X, register bits 0x%X: "
                                 "bits are %d..%d, codes 0x0001..0xFFFF, register bits "
                                 "0x00..0xFF without bit 6 (reserved)", line, bit, code,
                                 register_bits, CO_ERRORS_FIRST_APP_BIT, CO_ERRORS_BITS - 1);
    }
    co_errors_t *e = locked_errors(rt, line, "defining an error bit", NULL);
    if (!e) {
        return CO_RT_ERR_STATE;
    }
    if (co_errors_define(e, (uint8_t)bit, (uint16_t)code, (uint8_t)register_bits) !=
        CO_ERRORS_OK) {
        rt_set_error(rt, "line %d: error bit %d is set: reset it before redefining it", line,
                     bit);
        return rt_kick_unlock(rt, CO_RT_ERR_STATE);
    }
    return rt_kick_unlock(rt, CO_RT_OK);
}

int co_rt_errors_report(co_rt_t *rt, int line, int bit, int info, int reset)
{
    if (bit < CO_ERRORS_FIRST_APP_BIT || bit >= CO_ERRORS_BITS || info < 0 || info > 0xFFFF) {
        return rt_argument_error(rt, "line %d: error bit %d, info 0x%X: the application's "
                                 "bits are %d..%d (0..%d are the stack's), info 0..0xFFFF",
                                 line, bit, info, CO_ERRORS_FIRST_APP_BIT, CO_ERRORS_BITS - 1,
                                 CO_ERRORS_FIRST_APP_BIT - 1);
    }
    co_errors_t *e = locked_errors(rt, line, reset ? "resetting an error bit"
                                                   : "reporting an error bit", NULL);
    if (!e) {
        return CO_RT_ERR_STATE;
    }
    co_line_set_time(e->emcy->line, co_rt_now_us());   /* the inhibit time counts from now */
    co_errors_result_t r = reset ? co_errors_reset(e, (uint8_t)bit, (uint16_t)info)
                                 : co_errors_report(e, (uint8_t)bit, (uint16_t)info);
    if (r == CO_ERRORS_UNDEFINED) {
        rt_set_error(rt, "line %d: error bit %d is not defined (no EMCY code for it yet)",
                     line, bit);
        return rt_kick_unlock(rt, CO_RT_ERR_STATE);
    }
    return rt_kick_unlock(rt, (int)r);
}

int co_rt_errors_condition(co_rt_t *rt, int line, int register_bit, const uint8_t *mask)
{
    if (!mask || register_bit < 0 || register_bit > 7 || register_bit == 6) {
        return rt_argument_error(rt, "line %d: error register bit %d: 0..7 without 6 "
                                 "(reserved), with a mask of %d bytes", line, register_bit,
                                 CO_ERRORS_BYTES);
    }
    co_errors_t *e = locked_errors(rt, line, "an error register condition", NULL);
    if (!e) {
        return CO_RT_ERR_STATE;
    }
    (void)co_errors_set_condition(e, (uint8_t)register_bit, mask);
    return rt_kick_unlock(rt, CO_RT_OK);
}

int co_rt_errors_state(co_rt_t *rt, int line, co_rt_errors_state_t *out)
{
    if (!out) {
        return CO_RT_ERR_ARGUMENT;
    }
    const co_errors_t *e = locked_errors(rt, line, "the error bits", NULL);
    if (!e) {
        return CO_RT_ERR_STATE;
    }
    memcpy(out->bits, e->status, sizeof out->bits);
    out->error_register = co_emcy_error_register(e->emcy);
    out->bits_register = co_errors_register(e);
    for (int bit = 0; bit < CO_ERRORS_BITS; bit++) {
        out->codes[bit] = e->table[bit].code;
        out->classes[bit] = e->table[bit].register_bits;
        out->counts[bit] = e->count[bit];
    }
    rt_mutex_unlock(&rt->lock);
    return CO_RT_OK;
}

int co_rt_errors_expose(co_rt_t *rt, int line, int index)
{
    if (index < 1 || index > 0xFFFF) {
        return rt_argument_error(rt, "line %d: OD index 0x%X for the error bits: 0x0001..0xFFFF",
                                 line, index);
    }
    co_od_t *od = NULL;
    co_errors_t *e = locked_errors(rt, line, "showing the error bits in the OD", &od);
    if (!e) {
        return CO_RT_ERR_STATE;
    }
    if (!co_errors_attach_od(e, od, (uint16_t)index)) {
        rt_set_error(rt, "line %d: the error bits cannot be shown in 0x%04X:00: %s", line, index,
                     e->od ? "they are shown in an entry already"
                           : "the node's OD has no OCTET_STRING there (or no room for the hook)");
        rt_mutex_unlock(&rt->lock);
        return CO_RT_ERR_STATE;
    }
    rt_mutex_unlock(&rt->lock);
    return CO_RT_OK;
}
