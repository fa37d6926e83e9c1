/* Bit sets over caller storage (a bit per PDO number, per node-id, ...):
 * over bytes (co_bit_*) or over 32-bit words (co_bit32_*). */
#ifndef CO_BITS_H
#define CO_BITS_H

#include <stdbool.h>
#include <stdint.h>

static inline bool co_bit_test(const uint8_t *set, uint16_t n)
{
    return ((set[n / 8u] >> (n % 8u)) & 1u) != 0;
}

static inline void co_bit_put(uint8_t *set, uint16_t n, bool on)
{
    if (on) {
        set[n / 8u] = (uint8_t)(set[n / 8u] | (1u << (n % 8u)));
    } else {
        set[n / 8u] = (uint8_t)(set[n / 8u] & ~(1u << (n % 8u)));
    }
}

static inline bool co_bit32_test(const uint32_t *set, uint16_t n)
{
    return ((set[n / 32u] >> (n % 32u)) & 1u) != 0;
}

static inline void co_bit32_put(uint32_t *set, uint16_t n, bool on)
{
    if (on) {
        set[n / 32u] |= (uint32_t)1u << (n % 32u);
    } else {
        set[n / 32u] &= ~((uint32_t)1u << (n % 32u));
    }
}

#endif
