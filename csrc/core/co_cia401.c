/* CiA 401 generic I/O: polarity, filters, interrupt masks and error modes of
 * one channel group (see co_cia401.h; sources in docs/protocol-notes.md). */
#include "canopenfd/co_cia401.h"

#include <stddef.h>

bool co_cia401_din_update(co_cia401_din_t *din, uint8_t raw)
{
    uint8_t sample, settled, value, changed;
    if (din == NULL)
        return false;
    sample = (uint8_t)(raw ^ din->polarity);
    /* an unfiltered bit follows at once; a filtered one only when this sample
     * equals the previous one, so a single-sample glitch never reaches 0x6000 */
    settled = (uint8_t)(~din->filter | ~(sample ^ din->last_sample));
    value = (uint8_t)((din->value & ~settled) | (sample & settled));
    din->last_sample = sample;
    changed = (uint8_t)(value ^ din->value);
    din->value = value;
    if (!din->interrupt_enable || changed == 0)
        return false;
    return ((changed & din->any_change) | (changed & value & din->rising) |
            (changed & (uint8_t)~value & din->falling)) != 0;
}

uint8_t co_cia401_dout_write(co_cia401_dout_t *dout, uint8_t value)
{
    uint8_t level;
    if (dout == NULL)
        return 0;
    level = (uint8_t)(value ^ dout->polarity);
    dout->physical = (uint8_t)((dout->physical & ~dout->filter_mask) |
                               (level & dout->filter_mask));
    return dout->physical;
}

uint8_t co_cia401_dout_fault(co_cia401_dout_t *dout)
{
    if (dout == NULL)
        return 0;
    /* the error value is the level on the line: polarity does not apply */
    dout->physical = (uint8_t)((dout->physical & ~dout->error_mode) |
                               (dout->error_value & dout->error_mode));
    return dout->physical;
}

void co_cia401_ain_reset(co_cia401_ain_t *ain, int32_t value)
{
    if (ain == NULL)
        return;
    ain->value = value;
    ain->reference = value;
}

/* value - reference without overflow: both are 32-bit, the result 64-bit. */
static int64_t moved(const co_cia401_ain_t *ain, int32_t value)
{
    return (int64_t)value - (int64_t)ain->reference;
}

bool co_cia401_ain_update(co_cia401_ain_t *ain, int32_t value)
{
    int32_t previous;
    int64_t step;
    uint8_t hit = 0;
    if (ain == NULL)
        return false;
    previous = ain->value;
    ain->value = value;
    step = moved(ain, value);
    /* limits fire when the value enters the region, not at every sample in it */
    if (value >= ain->upper_limit && previous < ain->upper_limit)
        hit |= CO_CIA401_AI_UPPER;
    if (value < ain->lower_limit && previous >= ain->lower_limit)
        hit |= CO_CIA401_AI_LOWER;
    if (step > (int64_t)ain->delta || -step > (int64_t)ain->delta)
        hit |= CO_CIA401_AI_DELTA;
    if (-step > (int64_t)ain->negative_delta)
        hit |= CO_CIA401_AI_NEGATIVE_DELTA;
    if (step > (int64_t)ain->positive_delta)
        hit |= CO_CIA401_AI_POSITIVE_DELTA;
    if (!ain->interrupt_enable || (hit & ain->trigger) == 0)
        return false;
    ain->reference = value;
    return true;
}

int32_t co_cia401_aout_write(co_cia401_aout_t *aout, int32_t value)
{
    if (aout == NULL)
        return 0;
    aout->physical = value;
    return value;
}

int32_t co_cia401_aout_fault(co_cia401_aout_t *aout)
{
    int32_t level;
    if (aout == NULL)
        return 0;
    if (!aout->error_mode)
        return aout->physical;
    level = aout->error_value;
    if (level > INT16_MAX)
        level = INT16_MAX;
    if (level < INT16_MIN)
        level = INT16_MIN;
    aout->physical = level;
    return level;
}
