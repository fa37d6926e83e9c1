/* Error-status bits and the EMCY code table (co_errors) in front of the EMCY
 * producer: the EMCY of a report and of a reset byte for byte on a classic
 * and an FD bus, repetitions counted but not sent, the error register from
 * the table's classes and from conditions the application sets, the 0x1003
 * entry, the stack's own bits (no EMCY of their own), the communication
 * indication, refused arguments, and the 0x2100 mirror on request (read-only).
 *
 * Lines: a (node 5, producer), b (silent second line). */
#include "test_od_util.h"

#include "canopenfd/co_errors.h"

#define NODE 5
#define EMCY_ID (0x80u + NODE)
#define N_ENTRIES 16
#define POOL 256
#define SUBS 4

typedef struct fx {
    tu_bus_t tb;
    tu_line_t l[2];
    co_line_t *a;
    co_emcy_t emcy;
    co_emcy_msg_t queue[4];
    co_emcy_active_t active[4];
    uint32_t history[4];
    co_errors_t errors;
    int comm_calls;
    co_od_t od;
    co_od_entry_t entries[N_ENTRIES];
    uint8_t pool[POOL];
    co_od_subscription_t subs[SUBS];
} fx_t;

static int setup(void **state, co_mode_t mode, bool brs)
{
    fx_t *fx = calloc(1, sizeof *fx);
    assert_non_null(fx);
    tu_bus_init(&fx->tb, mode, brs);
    fx->a = tu_bus_add_line(&fx->tb, &fx->l[0]);
    (void)tu_bus_add_line(&fx->tb, &fx->l[1]);
    co_emcy_config_t cfg = {.queue = fx->queue, .queue_capacity = 4, .active = fx->active,
                            .active_capacity = 4, .history = fx->history,
                            .history_capacity = 4};
    assert_true(co_emcy_init(&fx->emcy, fx->a, NODE, &cfg));
    co_emcy_set_nmt_state(&fx->emcy, CO_NMT_PRE_OPERATIONAL);
    co_errors_init(&fx->errors, &fx->emcy);
    tu_run_until(&fx->tb, 1000);
    *state = fx;
    return 0;
}

static int setup_classic(void **state) { return setup(state, CO_MODE_CLASSIC, false); }
static int setup_fd(void **state) { return setup(state, CO_MODE_FD, true); }

static int teardown(void **state)
{
    fx_t *fx = *state;
    co_errors_detach_od(&fx->errors);
    co_emcy_deinit(&fx->emcy);
    free(fx);
    return 0;
}

static bool fd_bus(const fx_t *fx) { return fx->tb.mode == CO_MODE_FD; }
static void carry(fx_t *fx) { tu_step(&fx->tb, fx->tb.now); }

/* The EMCY a bit's report (occurred) or reset sends: classic 8 bytes, FD the
 * same first 8 bytes, logical device 0, CiA 301, status, no time stamp. */
static void assert_emcy(fx_t *fx, long index, uint16_t code, uint8_t reg, uint8_t bit,
                        uint16_t info, bool occurred)
{
    uint8_t want[CO_EMCY_FD_LEN] = {0};
    uint16_t sent_code = (occurred || fd_bus(fx)) ? code : 0;
    want[0] = (uint8_t)sent_code;
    want[1] = (uint8_t)(sent_code >> 8);
    want[2] = reg;
    want[3] = bit;
    want[4] = (uint8_t)info;
    want[5] = (uint8_t)(info >> 8);
    if (fd_bus(fx)) {
        want[9] = 0x2D;           /* 301, LE */
        want[10] = 0x01;
        want[11] = occurred ? CO_EMCY_STATUS_OCCURRED : 0;
    }
    tu_assert_logged(&fx->tb, index, EMCY_ID, want,
                     fd_bus(fx) ? CO_EMCY_FD_LEN : CO_EMCY_CLASSIC_LEN);
}

static void test_report_once_reset_exact_bytes(void **state)
{
    fx_t *fx = *state;
    assert_int_equal(co_errors_define(&fx->errors, 16, 0x2310, CO_EMCY_ER_CURRENT), CO_ERRORS_OK);
    tu_log_clear(&fx->tb);

    assert_int_equal(co_errors_report(&fx->errors, 16, 0x1234), CO_ERRORS_OK);
    carry(fx);
    assert_int_equal(fx->tb.log_count, 1);
    assert_emcy(fx, 0, 0x2310, 0x03, 16, 0x1234, true);
    assert_true(co_errors_is_set(&fx->errors, 16));
    assert_int_equal(co_emcy_error_register(&fx->emcy), 0x03);
    /* 0x1003: code, then EMCY bytes 3-4 (the bit, the info's low byte) */
    assert_int_equal(fx->emcy.history_count, 1);
    assert_int_equal(fx->history[0], 0x34102310u);

    /* repetitions: counted, nothing on the bus, the register unchanged */
    assert_int_equal(co_errors_report(&fx->errors, 16, 0x9999), CO_ERRORS_REPEATED);
    assert_int_equal(co_errors_report(&fx->errors, 16, 0x9999), CO_ERRORS_REPEATED);
    carry(fx);
    assert_int_equal(fx->tb.log_count, 1);
    assert_int_equal(co_errors_count(&fx->errors, 16), 3);
    assert_int_equal(fx->emcy.history_count, 1);

    assert_int_equal(co_errors_reset(&fx->errors, 16, 0x0042), CO_ERRORS_OK);
    carry(fx);
    assert_int_equal(fx->tb.log_count, 2);
    assert_emcy(fx, 1, 0x2310, 0x00, 16, 0x0042, false);
    assert_false(co_errors_is_set(&fx->errors, 16));
    assert_int_equal(co_emcy_error_register(&fx->emcy), 0);
    assert_int_equal(co_errors_reset(&fx->errors, 16, 0), CO_ERRORS_NOT_SET);
    /* set again after the reset: reported again */
    assert_int_equal(co_errors_report(&fx->errors, 16, 1), CO_ERRORS_OK);
    carry(fx);
    assert_int_equal(fx->tb.log_count, 3);
    assert_int_equal(co_errors_count(&fx->errors, 16), 4);
}

static void test_register_from_table_and_conditions(void **state)
{
    fx_t *fx = *state;
    uint8_t mask[CO_ERRORS_BYTES] = {0};
    assert_int_equal(co_errors_define(&fx->errors, 16, 0x2310, CO_EMCY_ER_CURRENT), CO_ERRORS_OK);
    assert_int_equal(co_errors_define(&fx->errors, 17, 0x3110, CO_EMCY_ER_VOLTAGE), CO_ERRORS_OK);
    assert_int_equal(co_errors_define(&fx->errors, 18, 0x4210, CO_EMCY_ER_TEMPERATURE),
                     CO_ERRORS_OK);
    assert_int_equal(co_errors_report(&fx->errors, 17, 0), CO_ERRORS_OK);
    assert_int_equal(co_errors_register(&fx->errors), 0x05);
    assert_int_equal(co_errors_report(&fx->errors, 18, 0), CO_ERRORS_OK);
    assert_int_equal(co_errors_register(&fx->errors), 0x0D);

    /* the current bit now follows bit 18 only; the voltage bit keeps its default */
    mask[18 / 8] = (uint8_t)(1u << (18 % 8));
    assert_int_equal(co_errors_set_condition(&fx->errors, 1, mask), CO_ERRORS_OK);
    assert_int_equal(co_errors_register(&fx->errors), 0x0F);
    assert_int_equal(co_emcy_error_register(&fx->emcy), 0x0F);
    assert_int_equal(co_errors_reset(&fx->errors, 18, 0), CO_ERRORS_OK);
    assert_int_equal(co_errors_register(&fx->errors), 0x05);
    /* a later definition leaves the custom condition alone */
    assert_int_equal(co_errors_define(&fx->errors, 19, 0x2100, CO_EMCY_ER_CURRENT), CO_ERRORS_OK);
    assert_int_equal(co_errors_report(&fx->errors, 19, 0), CO_ERRORS_OK);
    assert_int_equal(co_errors_register(&fx->errors), 0x05);
    /* an empty generic condition: generic follows the other sources only */
    memset(mask, 0, sizeof mask);
    assert_int_equal(co_errors_set_condition(&fx->errors, 0, mask), CO_ERRORS_OK);
    assert_int_equal(co_errors_register(&fx->errors), 0x04);
    assert_int_equal(co_emcy_error_register(&fx->emcy), 0x04);
}

static void test_refused_arguments(void **state)
{
    fx_t *fx = *state;
    uint8_t mask[CO_ERRORS_BYTES] = {0};
    assert_int_equal(co_errors_report(&fx->errors, 20, 0), CO_ERRORS_UNDEFINED);
    assert_int_equal(co_errors_reset(&fx->errors, 20, 0), CO_ERRORS_UNDEFINED);
    assert_int_equal(co_errors_report(&fx->errors, CO_ERRORS_BIT_BUS_OFF, 0),
                     CO_ERRORS_BAD_ARGUMENT);
    assert_int_equal(co_errors_report(&fx->errors, CO_ERRORS_BITS, 0), CO_ERRORS_BAD_ARGUMENT);
    assert_int_equal(co_errors_define(&fx->errors, 3, 0x1000, 0), CO_ERRORS_BAD_ARGUMENT);
    assert_int_equal(co_errors_define(&fx->errors, 200, 0x1000, 0), CO_ERRORS_BAD_ARGUMENT);
    assert_int_equal(co_errors_define(&fx->errors, 20, 0, 0), CO_ERRORS_BAD_ARGUMENT);
    assert_int_equal(co_errors_define(&fx->errors, 20, 0x1000, 0x40), CO_ERRORS_BAD_ARGUMENT);
    assert_int_equal(co_errors_set_condition(&fx->errors, 6, mask), CO_ERRORS_BAD_ARGUMENT);
    assert_int_equal(co_errors_set_condition(&fx->errors, 8, mask), CO_ERRORS_BAD_ARGUMENT);
    assert_int_equal(co_errors_set_condition(&fx->errors, 1, NULL), CO_ERRORS_BAD_ARGUMENT);
    assert_int_equal(co_errors_define(&fx->errors, 20, 0x1000, 0), CO_ERRORS_OK);
    assert_int_equal(co_errors_report(&fx->errors, 20, 0), CO_ERRORS_OK);
    /* redefining a set bit would break its reset EMCY: refused */
    assert_int_equal(co_errors_define(&fx->errors, 20, 0x1001, 0), CO_ERRORS_BAD_ARGUMENT);
    assert_int_equal(co_errors_reset(&fx->errors, 20, 0), CO_ERRORS_OK);
    assert_int_equal(co_errors_define(&fx->errors, 20, 0x1001, 0), CO_ERRORS_OK);
    carry(fx);
    assert_int_equal(tu_log_count_id(&fx->tb, EMCY_ID), 2);
}

static void on_comm(co_errors_t *errors, void *user)
{
    fx_t *fx = user;
    assert_ptr_equal(errors, &fx->errors);
    fx->comm_calls++;
}

static void test_stack_bits_and_comm_indication(void **state)
{
    fx_t *fx = *state;
    co_errors_set_comm_indication(&fx->errors, on_comm, fx);
    tu_log_clear(&fx->tb);
    /* a detector's bit: the register, no EMCY from here, no indication */
    assert_int_equal(co_errors_stack_bit(0x8140), CO_ERRORS_BIT_BUS_OFF);
    assert_int_equal(co_errors_stack_bit(0x8250), CO_ERRORS_BIT_RPDO_TIMEOUT);
    assert_int_equal(co_errors_stack_bit(0x2310), -1);
    co_errors_note(&fx->errors, CO_ERRORS_BIT_BUS_OFF, true);
    co_errors_note(&fx->errors, CO_ERRORS_BIT_BUS_OFF, true);
    co_errors_note(&fx->errors, 40, true);      /* not a stack bit: ignored */
    carry(fx);
    assert_int_equal(fx->tb.log_count, 0);
    assert_true(co_errors_is_set(&fx->errors, CO_ERRORS_BIT_BUS_OFF));
    assert_false(co_errors_is_set(&fx->errors, 40));
    assert_int_equal(co_errors_count(&fx->errors, CO_ERRORS_BIT_BUS_OFF), 1);
    assert_int_equal(co_emcy_error_register(&fx->emcy), 0x11);
    assert_int_equal(fx->comm_calls, 0);
    co_errors_note(&fx->errors, CO_ERRORS_BIT_BUS_OFF, false);
    assert_int_equal(co_emcy_error_register(&fx->emcy), 0);

    /* an application bit of the communication class tells the node */
    assert_int_equal(co_errors_define(&fx->errors, 30, 0x8100, CO_EMCY_ER_COMMUNICATION),
                     CO_ERRORS_OK);
    assert_int_equal(co_errors_define(&fx->errors, 31, 0x5000, 0), CO_ERRORS_OK);
    assert_int_equal(co_errors_report(&fx->errors, 31, 0), CO_ERRORS_OK);
    assert_int_equal(fx->comm_calls, 0);
    assert_int_equal(co_errors_report(&fx->errors, 30, 0), CO_ERRORS_OK);
    assert_int_equal(co_errors_report(&fx->errors, 30, 0), CO_ERRORS_REPEATED);
    assert_int_equal(fx->comm_calls, 1);
    assert_int_equal(co_emcy_error_register(&fx->emcy), 0x11);
}

/* The producer's own errors (raised by code) and the bits share 0x1001. */
static void test_register_shared_with_raised_errors(void **state)
{
    fx_t *fx = *state;
    co_emcy_error_t err;
    memset(&err, 0, sizeof err);
    err.code = 0x4210;
    assert_int_equal(co_errors_define(&fx->errors, 16, 0x2310, CO_EMCY_ER_CURRENT), CO_ERRORS_OK);
    assert_int_equal(co_emcy_raise(&fx->emcy, &err), CO_EMCY_OK);
    assert_int_equal(co_errors_report(&fx->errors, 16, 0), CO_ERRORS_OK);
    assert_int_equal(co_emcy_error_register(&fx->emcy), 0x0B);
    assert_int_equal(co_emcy_clear(&fx->emcy, &err), CO_EMCY_OK);
    assert_int_equal(co_emcy_error_register(&fx->emcy), 0x03);
    assert_int_equal(co_errors_reset(&fx->errors, 16, 0), CO_ERRORS_OK);
    assert_int_equal(co_emcy_error_register(&fx->emcy), 0x00);
    assert_int_equal(co_emcy_active_count(&fx->emcy), 0);
}

static void build_od(fx_t *fx, uint32_t mirror_size)
{
    co_od_init(&fx->od, fx->tb.mode, fx->entries, N_ENTRIES, fx->pool, POOL, fx->subs, SUBS);
    /* rw in the description: the service's handler is what refuses writes */
    co_od_def_t d = tu_od_def(CO_ERRORS_OD_INDEX, 0, VAR, CO_TYPE_OCTET_STRING, RW, 0,
                              mirror_size);
    uint8_t zero[CO_ERRORS_BYTES + 4] = {0};
    d.default_value = zero;
    d.default_length = mirror_size;
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ADDED);
    assert_true(co_od_seal(&fx->od, NODE));
    assert_false(co_errors_attach_od(&fx->errors, &fx->od, 0x2101));   /* no such entry */
    assert_true(co_errors_attach_od(&fx->errors, &fx->od, CO_ERRORS_OD_INDEX));
}

static const uint8_t *mirror_bytes(fx_t *fx)
{
    const co_od_entry_t *entry = co_od_find(&fx->od, CO_ERRORS_OD_INDEX, 0);
    assert_non_null(entry);
    return co_od_value(&fx->od, entry);
}

static void test_od_mirror_read_only(void **state)
{
    fx_t *fx = *state;
    uint8_t want[CO_ERRORS_BYTES] = {0};
    uint8_t v[CO_ERRORS_BYTES] = {0xFF};
    build_od(fx, CO_ERRORS_BYTES);
    assert_false(co_errors_attach_od(&fx->errors, &fx->od, CO_ERRORS_OD_INDEX));   /* once */
    assert_int_equal(co_errors_define(&fx->errors, 17, 0x2310, CO_EMCY_ER_CURRENT), CO_ERRORS_OK);
    assert_int_equal(co_errors_report(&fx->errors, 17, 0), CO_ERRORS_OK);
    co_errors_note(&fx->errors, CO_ERRORS_BIT_LIFE_GUARD, true);
    want[0] = 0x04;               /* bit 2 */
    want[2] = 0x02;               /* bit 17 */
    assert_memory_equal(mirror_bytes(fx), want, CO_ERRORS_BYTES);
    /* a network write is refused; an application write is replaced at once */
    co_od_xfer_t x;
    uint8_t scratch[CO_ERRORS_BYTES];
    co_od_xfer_init(&x, scratch, sizeof scratch);
    uint32_t r = co_od_write_begin(&fx->od, &x, CO_ERRORS_OD_INDEX, 0, CO_ERRORS_BYTES);
    if (r == CO_ABORT_NONE) {
        r = co_od_write_chunk(&x, v, CO_ERRORS_BYTES);
    }
    if (r == CO_ABORT_NONE) {
        r = co_od_write_end(&x);
    }
    assert_int_equal(r, CO_ABORT_READ_ONLY);
    assert_memory_equal(mirror_bytes(fx), want, CO_ERRORS_BYTES);
    assert_int_equal(co_od_put(&fx->od, CO_ERRORS_OD_INDEX, 0, v, CO_ERRORS_BYTES), 0);
    assert_memory_equal(mirror_bytes(fx), want, CO_ERRORS_BYTES);
    assert_int_equal(co_errors_reset(&fx->errors, 17, 0), CO_ERRORS_OK);
    want[2] = 0;
    assert_memory_equal(mirror_bytes(fx), want, CO_ERRORS_BYTES);
}

/* An entry declared with an empty default still shows all 16 bytes. */
static void test_od_mirror_takes_its_length(void **state)
{
    fx_t *fx = *state;
    uint8_t buf[CO_ERRORS_BYTES + 8];
    uint32_t length = 0;
    co_od_init(&fx->od, fx->tb.mode, fx->entries, N_ENTRIES, fx->pool, POOL, fx->subs, SUBS);
    co_od_def_t d = tu_od_def(CO_ERRORS_OD_INDEX, 0, VAR, CO_TYPE_OCTET_STRING, RO, 0,
                              CO_ERRORS_BYTES + 8);
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ADDED);
    assert_true(co_od_seal(&fx->od, NODE));
    co_errors_note(&fx->errors, 9, true);
    assert_true(co_errors_attach_od(&fx->errors, &fx->od, CO_ERRORS_OD_INDEX));
    assert_int_equal(co_od_get(&fx->od, CO_ERRORS_OD_INDEX, 0, buf, sizeof buf, &length), 0);
    assert_int_equal(length, CO_ERRORS_BYTES);
    assert_int_equal(buf[1], 0x02);   /* bit 9 */
}

static void test_od_mirror_shorter_entry(void **state)
{
    fx_t *fx = *state;
    static const uint8_t want[2] = {0x00, 0x80};   /* bit 15 */
    build_od(fx, 2);
    co_errors_note(&fx->errors, 15, true);
    assert_memory_equal(mirror_bytes(fx), want, 2);
}

/* An entry of another type (the demo OD's domain at 0x2100) cannot show
 * the bits: refused, nothing subscribed. */
static void test_od_other_type_refused(void **state)
{
    fx_t *fx = *state;
    co_od_init(&fx->od, fx->tb.mode, fx->entries, N_ENTRIES, fx->pool, POOL, fx->subs, SUBS);
    co_od_def_t d = tu_od_def(CO_ERRORS_OD_INDEX, 0, VAR, CO_TYPE_DOMAIN, RW, 0, 0);
    assert_int_equal(co_od_add(&fx->od, &d), CO_OD_ADDED);
    assert_true(co_od_seal(&fx->od, NODE));
    assert_false(co_errors_attach_od(&fx->errors, &fx->od, CO_ERRORS_OD_INDEX));
    assert_null(fx->errors.od);
    assert_int_equal(fx->od.sub_count, 0);
}

#define BOTH(t) cmocka_unit_test_setup_teardown(t, setup_classic, teardown), \
                cmocka_unit_test_setup_teardown(t, setup_fd, teardown)

int main(void)
{
    const struct CMUnitTest tests[] = {
        BOTH(test_report_once_reset_exact_bytes),
        BOTH(test_register_from_table_and_conditions),
        BOTH(test_refused_arguments),
        BOTH(test_stack_bits_and_comm_indication),
        BOTH(test_register_shared_with_raised_errors),
        BOTH(test_od_mirror_read_only),
        BOTH(test_od_mirror_shorter_entry),
        BOTH(test_od_mirror_takes_its_length),
        BOTH(test_od_other_type_refused),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
