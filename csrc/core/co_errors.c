#include "canopenfd/co_errors.h"

#include "co_bits.h"

#include <string.h>

enum { RESERVED_REGISTER_BIT = 6, COMM_REGISTER_BIT = 4 };

/* The stack's bits, in bit order (co_node raises these codes). */
static const uint16_t stack_codes[] = {0x8110, 0x8120, 0x8130, 0x8140,
                                       0x8210, 0x8220, 0x8240, 0x8250};

int co_errors_stack_bit(uint16_t code)
{
    for (size_t bit = 0; bit < sizeof stack_codes / sizeof stack_codes[0]; bit++) {
        if (stack_codes[bit] == code) {
            return (int)bit;
        }
    }
    return -1;
}

bool co_errors_is_set(const co_errors_t *e, uint8_t bit)
{
    return bit < CO_ERRORS_BITS && co_bit_test(e->status, bit);
}

/* ------------------------------------------------------------ OD mirror */

static const co_od_entry_t *mirror_entry_of(const co_od_t *od, uint16_t index)
{
    const co_od_entry_t *entry = od ? co_od_find(od, index, 0) : NULL;
    return (entry && entry->type == CO_TYPE_OCTET_STRING && entry->size > 0) ? entry : NULL;
}

static const co_od_entry_t *mirror_entry(const co_errors_t *e)
{
    return mirror_entry_of(e->od, e->od_index);
}

/* Written in place: the service owns the value (no after-write loop). */
static void mirror(co_errors_t *e)
{
    const co_od_entry_t *entry = mirror_entry(e);
    if (entry == NULL) {
        return;
    }
    uint32_t n = entry->size < CO_ERRORS_BYTES ? entry->size : CO_ERRORS_BYTES;
    uint8_t *value = co_od_value(e->od, entry);
    memset(value, 0, entry->size);
    memcpy(value, e->status, n);
}

/* ------------------------------------------------------- error register */

static bool any_common(const uint8_t *a, const uint8_t *b)
{
    for (size_t i = 0; i < CO_ERRORS_BYTES; i++) {
        if (a[i] & b[i]) {
            return true;
        }
    }
    return false;
}

/* Each register bit the application did not set a condition for: the bits
 * whose entry names its class (bit 0, generic: every defined bit). */
static void default_conditions(co_errors_t *e)
{
    for (uint8_t r = 0; r < 8; r++) {
        if (e->custom_conditions & (1u << r)) {
            continue;
        }
        memset(e->condition[r], 0, CO_ERRORS_BYTES);
        for (uint8_t bit = 0; bit < CO_ERRORS_BITS; bit++) {
            const co_errors_entry_t *t = &e->table[bit];
            if (t->code != 0 && (r == 0 || (t->register_bits & (1u << r)))) {
                co_bit_put(e->condition[r], bit, true);
            }
        }
    }
}

static void update(co_errors_t *e)
{
    uint8_t reg = 0;
    for (uint8_t r = 0; r < 8; r++) {
        if (r != RESERVED_REGISTER_BIT && any_common(e->condition[r], e->status)) {
            reg |= (uint8_t)(1u << r);
        }
    }
    e->error_register = reg;
    mirror(e);
    co_emcy_set_extra_register(e->emcy, reg);
}

/* ------------------------------------------------------------- the table */

void co_errors_init(co_errors_t *e, co_emcy_t *emcy)
{
    memset(e, 0, sizeof *e);
    e->emcy = emcy;
    for (size_t bit = 0; bit < sizeof stack_codes / sizeof stack_codes[0]; bit++) {
        e->table[bit].code = stack_codes[bit];
        e->table[bit].register_bits = CO_EMCY_ER_GENERIC | CO_EMCY_ER_COMMUNICATION;
    }
    default_conditions(e);
}

static bool app_bit(uint8_t bit)
{
    return bit >= CO_ERRORS_FIRST_APP_BIT && bit < CO_ERRORS_BITS;
}

co_errors_result_t co_errors_define(co_errors_t *e, uint8_t bit, uint16_t code,
                                    uint8_t register_bits)
{
    if (!app_bit(bit) || code == 0 || (register_bits & (1u << RESERVED_REGISTER_BIT)) ||
        co_bit_test(e->status, bit)) {
        return CO_ERRORS_BAD_ARGUMENT;
    }
    e->table[bit].code = code;
    e->table[bit].register_bits = (uint8_t)(register_bits | CO_EMCY_ER_GENERIC);
    default_conditions(e);
    update(e);
    return CO_ERRORS_OK;
}

co_errors_result_t co_errors_set_condition(co_errors_t *e, uint8_t register_bit,
                                           const uint8_t *mask)
{
    if (register_bit > 7 || register_bit == RESERVED_REGISTER_BIT || mask == NULL) {
        return CO_ERRORS_BAD_ARGUMENT;
    }
    memcpy(e->condition[register_bit], mask, CO_ERRORS_BYTES);
    e->custom_conditions |= (uint8_t)(1u << register_bit);
    update(e);
    return CO_ERRORS_OK;
}

void co_errors_set_comm_indication(co_errors_t *e, co_errors_comm_fn fn, void *user)
{
    e->on_comm = fn;
    e->comm_user = fn ? user : NULL;
}

/* ------------------------------------------------------- report / reset */

/* The EMCY fields of a bit: the bit and the info code in the manufacturer
 * field (EMCY bytes 3, 4-5). */
static co_emcy_error_t error_of(const co_errors_t *e, uint8_t bit, uint16_t info)
{
    co_emcy_error_t err;
    memset(&err, 0, sizeof err);
    err.code = e->table[bit].code;
    err.register_bits = e->table[bit].register_bits;
    err.msef[0] = bit;
    err.msef[1] = (uint8_t)info;
    err.msef[2] = (uint8_t)(info >> 8);
    err.spec_number = 301;
    return err;
}

static co_errors_result_t check_app_bit(const co_errors_t *e, uint8_t bit)
{
    if (!app_bit(bit)) {
        return CO_ERRORS_BAD_ARGUMENT;
    }
    return e->table[bit].code == 0 ? CO_ERRORS_UNDEFINED : CO_ERRORS_OK;
}

co_errors_result_t co_errors_report(co_errors_t *e, uint8_t bit, uint16_t info)
{
    co_errors_result_t r = check_app_bit(e, bit);
    if (r != CO_ERRORS_OK) {
        return r;
    }
    e->count[bit]++;
    if (co_bit_test(e->status, bit)) {
        return CO_ERRORS_REPEATED;   /* reported the first time only */
    }
    co_bit_put(e->status, bit, true);
    update(e);
    co_emcy_error_t err = error_of(e, bit, info);
    (void)co_emcy_signal(e->emcy, &err, true);
    if ((e->table[bit].register_bits & CO_EMCY_ER_COMMUNICATION) && e->on_comm) {
        e->on_comm(e, e->comm_user);
    }
    return CO_ERRORS_OK;
}

co_errors_result_t co_errors_reset(co_errors_t *e, uint8_t bit, uint16_t info)
{
    co_errors_result_t r = check_app_bit(e, bit);
    if (r != CO_ERRORS_OK) {
        return r;
    }
    if (!co_bit_test(e->status, bit)) {
        return CO_ERRORS_NOT_SET;
    }
    co_bit_put(e->status, bit, false);
    update(e);
    co_emcy_error_t err = error_of(e, bit, info);
    (void)co_emcy_signal(e->emcy, &err, false);
    return CO_ERRORS_OK;
}

void co_errors_note(co_errors_t *e, uint8_t bit, bool active)
{
    if (bit >= CO_ERRORS_FIRST_APP_BIT || co_bit_test(e->status, bit) == active) {
        return;
    }
    if (active) {
        e->count[bit]++;
    }
    co_bit_put(e->status, bit, active);
    update(e);
}

/* ------------------------------------------------------------ OD binding */

static uint32_t check_write(co_od_t *od, co_od_xfer_t *xfer, const co_od_entry_t *entry,
                            const uint8_t *value, uint32_t length, void *user)
{
    (void)od;
    (void)xfer;
    (void)value;
    (void)length;
    (void)user;
    /* The bits follow the reports: a written value would be replaced at once. */
    return co_od_entry_sub(entry) == 0 ? CO_ABORT_READ_ONLY : CO_ABORT_NONE;
}

static void after_write(co_od_t *od, const co_od_entry_t *entry, co_od_origin_t origin,
                        void *user)
{
    (void)od;
    (void)entry;
    (void)origin;
    mirror(user);   /* a reset loaded the default: the bits come back */
}

static const co_od_handler_t handler = {.check_write = check_write, .after_write = after_write};

bool co_errors_attach_od(co_errors_t *e, co_od_t *od, uint16_t index)
{
    if (e == NULL || e->od != NULL || mirror_entry_of(od, index) == NULL ||
        !co_od_subscribe(od, index, 0, index, 0, &handler, e)) {
        return false;
    }
    e->od = od;
    e->od_index = index;
    /* One application write gives the entry the bit array's length (a
     * shorter default would cut what a tool reads); its after-write mirrors. */
    const co_od_entry_t *entry = mirror_entry(e);
    uint32_t n = entry->size < CO_ERRORS_BYTES ? entry->size : CO_ERRORS_BYTES;
    if (co_od_put(od, index, 0, e->status, n) != CO_ABORT_NONE) {
        mirror(e);
    }
    return true;
}

void co_errors_detach_od(co_errors_t *e)
{
    if (e->od != NULL) {
        co_od_unsubscribe(e->od, &handler, e);
        e->od = NULL;
    }
}
