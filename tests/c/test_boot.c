/* co_boot: the CiA 302-2 boot-slave process of one node, driven through a
 * scripted access: every read it asks for (index:sub, in order), every NMT
 * command, every guarding request, every report; the fake clock runs its
 * timeouts. Each error status A..O is provoked, and the paths that end OK
 * or L. (The bytes on the bus through a real SDO client: test_manager.c.) */
#include "test_util.h"

#include "canopenfd/co_boot.h"

enum { NODE = 7, MAX_LOG = 64 };

typedef struct fake {
    tu_line_t tl;
    co_boot_t boot;
    co_boot_access_t access;
    /* reads asked for: index << 8 | sub */
    uint32_t reads[MAX_LOG];
    unsigned read_count;
    uint8_t nmt[MAX_LOG];
    unsigned nmt_count;
    unsigned guard_requests;
    co_boot_report_t reports[MAX_LOG];
    unsigned report_count;
    /* answers given at once from the report callback */
    int answer_software;   /* -1 = wait, 0 failed, 1 done */
    int answer_config;
    uint32_t refuse_upload;   /* returned by upload() when not 0 */
} fake_t;

static uint32_t fake_upload(co_boot_t *boot, uint16_t index, uint8_t sub, void *user)
{
    (void)boot;
    fake_t *f = user;
    assert_true(f->read_count < MAX_LOG);
    f->reads[f->read_count++] = (uint32_t)index << 8 | sub;
    return f->refuse_upload;
}

static bool fake_nmt(co_boot_t *boot, co_nmt_command_t command, void *user)
{
    (void)boot;
    fake_t *f = user;
    assert_true(f->nmt_count < MAX_LOG);
    f->nmt[f->nmt_count++] = (uint8_t)command;
    return true;
}

static bool fake_guard(co_boot_t *boot, void *user)
{
    (void)boot;
    ((fake_t *)user)->guard_requests++;
    return true;
}

static void fake_report(co_boot_t *boot, const co_boot_report_t *r, void *user)
{
    fake_t *f = user;
    assert_int_equal(r->node_id, NODE);
    assert_true(f->report_count < MAX_LOG);
    f->reports[f->report_count++] = *r;
    if (r->event == CO_BOOT_EV_UPDATE_SOFTWARE && f->answer_software >= 0) {
        assert_true(co_boot_continue_software(boot, f->answer_software == 1));
    }
    if (r->event == CO_BOOT_EV_UPDATE_CONFIG && f->answer_config >= 0) {
        assert_true(co_boot_continue_config(boot, f->answer_config == 1));
    }
}

static fake_t *fake_new(void)
{
    fake_t *f = calloc(1, sizeof *f);
    assert_non_null(f);
    tu_line_init(&f->tl, CO_MODE_CLASSIC, false);
    f->access = (co_boot_access_t){.upload = fake_upload, .nmt = fake_nmt,
                                   .guard_request = fake_guard, .report = fake_report,
                                   .user = f};
    f->answer_software = -1;
    f->answer_config = 1;
    assert_true(co_boot_init(&f->boot, &f->tl.line, NODE, &f->access));
    return f;
}

/* Run the line's timers up to `ms` of fake time. */
static void advance(fake_t *f, uint32_t ms)
{
    (void)co_line_process(&f->tl.line, co_line_now(&f->tl.line) + (uint64_t)ms * TU_MS);
}

static void answer(fake_t *f, uint32_t value)
{
    uint8_t b[4] = {(uint8_t)value, (uint8_t)(value >> 8), (uint8_t)(value >> 16),
                    (uint8_t)(value >> 24)};
    co_boot_upload_done(&f->boot, 0, b, 4);
}

static void frame(fake_t *f, uint8_t state)
{
    co_boot_ec_frame(&f->boot, &state, 1);
}

static uint32_t last_read(const fake_t *f)
{
    assert_true(f->read_count > 0);
    return f->reads[f->read_count - 1];
}

static const co_boot_report_t *last_report(const fake_t *f)
{
    assert_true(f->report_count > 0);
    return &f->reports[f->report_count - 1];
}

static void assert_done(const fake_t *f, co_boot_error_t error)
{
    const co_boot_report_t *r = last_report(f);
    assert_int_equal(r->event, CO_BOOT_EV_DONE);
    if (r->error != error) {
        fail_msg("node %u ended with '%c' (%s), expected '%c'", NODE, r->error ? r->error : '0',
                 co_boot_error_text((co_boot_error_t)r->error), error ? error : '0');
    }
    assert_false(co_boot_running(&f->boot));
}

/* Every identity value expected, keep-alive off, checks on. */
static co_boot_expect_t full_expect(void)
{
    co_boot_expect_t e;
    memset(&e, 0, sizeof e);
    e.assignment = CO_BOOT_ASSIGN_SLAVE | CO_BOOT_ASSIGN_BOOT;
    e.device_type = 0x00020191;
    e.vendor_id = 0x11;
    e.product_code = 0x22;
    e.revision = 0x33;
    e.serial = 0x44;
    return e;
}

/* Answer the identity reads with the expected values; returns after 1018:04. */
static void pass_identity(fake_t *f, const co_boot_expect_t *e)
{
    assert_int_equal(last_read(f), 0x100000);
    answer(f, e->device_type);
    assert_int_equal(last_read(f), 0x101801);
    answer(f, e->vendor_id);
    assert_int_equal(last_read(f), 0x101802);
    answer(f, e->product_code);
    assert_int_equal(last_read(f), 0x101803);
    answer(f, e->revision);
    assert_int_equal(last_read(f), 0x101804);
    answer(f, e->serial);
}

/* ------------------------------------------------------------------ tests */

static void test_full_boot_ends_ok(void **state)
{
    (void)state;
    fake_t *f = fake_new();
    co_boot_expect_t e = full_expect();
    assert_true(co_boot_start(&f->boot, &e));
    assert_int_equal(f->reports[0].event, CO_BOOT_EV_STARTED);
    pass_identity(f, &e);
    /* no keep-alive: reset communication, wait for the boot-up */
    assert_int_equal(f->nmt_count, 1);
    assert_int_equal(f->nmt[0], CO_NMT_CMD_RESET_COMMUNICATION);
    assert_int_equal(co_boot_step(&f->boot), CO_BOOT_STEP_RESET_COMM);
    frame(f, CO_NMT_PRE_OPERATIONAL);   /* a heartbeat from before the reset: ignored */
    assert_int_equal(co_boot_step(&f->boot), CO_BOOT_STEP_RESET_COMM);
    frame(f, 0x00);
    /* no configuration date: the application is asked (and answers at once) */
    assert_done(f, CO_BOOT_OK);
    assert_int_equal(last_report(f)->state, CO_NMT_PRE_OPERATIONAL);
    assert_int_equal(f->reports[f->report_count - 2].event, CO_BOOT_EV_UPDATE_CONFIG);
    /* every read was reported with what was expected and got */
    const co_boot_report_t *vendor = &f->reports[2];
    assert_int_equal(vendor->event, CO_BOOT_EV_CHECKED);
    assert_int_equal(vendor->index, 0x1018);
    assert_int_equal(vendor->sub, 1);
    assert_true(vendor->matched);
    assert_int_equal(vendor->expected, 0x11);
    assert_int_equal(vendor->got, 0x11);
    free(f);
}

static void test_a_not_in_network_list(void **state)
{
    (void)state;
    fake_t *f = fake_new();
    co_boot_expect_t e = full_expect();
    e.assignment = CO_BOOT_ASSIGN_BOOT;
    assert_true(co_boot_start(&f->boot, &e));
    assert_done(f, CO_BOOT_ERR_A);
    assert_int_equal(f->read_count, 0);
    assert_int_equal(f->nmt_count, 0);
    free(f);
}

static void test_b_device_type_retried_then_b(void **state)
{
    (void)state;
    fake_t *f = fake_new();
    co_boot_expect_t e = full_expect();
    assert_true(co_boot_start(&f->boot, &e));
    for (unsigned i = 0; i < CO_BOOT_UPLOAD_RETRIES; i++) {
        co_boot_upload_done(&f->boot, CO_BOOT_ABORT_TIMEOUT, NULL, 0);
        assert_true(co_boot_running(&f->boot));
    }
    assert_int_equal(f->read_count, 1 + CO_BOOT_UPLOAD_RETRIES);
    co_boot_upload_done(&f->boot, CO_BOOT_ABORT_TIMEOUT, NULL, 0);
    assert_done(f, CO_BOOT_ERR_B);
    /* a refused start of the read ends the same way, without retries */
    f->refuse_upload = 0x060A0023u;
    assert_true(co_boot_start(&f->boot, &e));
    assert_done(f, CO_BOOT_ERR_B);
    free(f);
}

static void test_b_no_bootup_after_reset(void **state)
{
    (void)state;
    fake_t *f = fake_new();
    co_boot_expect_t e = full_expect();
    e.reset_timeout_ms = 500;
    assert_true(co_boot_start(&f->boot, &e));
    pass_identity(f, &e);
    advance(f, 499);
    assert_true(co_boot_running(&f->boot));
    advance(f, 1);
    assert_done(f, CO_BOOT_ERR_B);
    free(f);
}

static void test_c_device_type_differs(void **state)
{
    (void)state;
    fake_t *f = fake_new();
    co_boot_expect_t e = full_expect();
    assert_true(co_boot_start(&f->boot, &e));
    answer(f, 0x00020192);
    assert_false(last_report(f)->matched);   /* the CHECKED report came before DONE */
    assert_int_equal(f->reports[f->report_count - 2].got, 0x00020192);
    assert_int_equal(f->reports[f->report_count - 2].expected, 0x00020191);
    assert_done(f, CO_BOOT_ERR_C);
    /* 1F84 = 0: any device type passes */
    e.device_type = 0;
    e.vendor_id = e.product_code = e.revision = e.serial = 0;
    assert_true(co_boot_start(&f->boot, &e));
    answer(f, 0x12345678);
    assert_int_equal(co_boot_step(&f->boot), CO_BOOT_STEP_RESET_COMM);
    free(f);
}

/* One identity entry differs (or the read aborts): its letter. */
static void identity_case(uint8_t sub, co_boot_error_t error, bool abort)
{
    fake_t *f = fake_new();
    co_boot_expect_t e = full_expect();
    const uint32_t values[] = {e.vendor_id, e.product_code, e.revision, e.serial};
    assert_true(co_boot_start(&f->boot, &e));
    answer(f, e.device_type);
    for (uint8_t s = 1; s < sub; s++) {
        answer(f, values[s - 1]);
    }
    assert_int_equal(last_read(f), 0x101800u | sub);
    if (abort) {
        co_boot_upload_done(&f->boot, 0x06020000u, NULL, 0);
    } else {
        answer(f, values[sub - 1] + 1);
    }
    assert_done(f, error);
    free(f);
}

static void test_d_m_n_o_identity_differs(void **state)
{
    (void)state;
    identity_case(1, CO_BOOT_ERR_D, false);
    identity_case(2, CO_BOOT_ERR_M, false);
    identity_case(3, CO_BOOT_ERR_N, false);
    identity_case(4, CO_BOOT_ERR_O, false);
    identity_case(1, CO_BOOT_ERR_D, true);
    identity_case(4, CO_BOOT_ERR_O, true);
}

static void test_identity_skips_zero_expectations(void **state)
{
    (void)state;
    fake_t *f = fake_new();
    co_boot_expect_t e = full_expect();
    e.vendor_id = 0;
    e.revision = 0;
    assert_true(co_boot_start(&f->boot, &e));
    answer(f, e.device_type);
    assert_int_equal(last_read(f), 0x101802);
    answer(f, e.product_code);
    assert_int_equal(last_read(f), 0x101804);
    answer(f, e.serial);
    assert_int_equal(f->read_count, 3);
    free(f);
}

static void test_e_keep_alive_without_heartbeat(void **state)
{
    (void)state;
    fake_t *f = fake_new();
    co_boot_expect_t e = full_expect();
    e.assignment |= CO_BOOT_ASSIGN_KEEP_ALIVE;
    e.heartbeat_ms = 300;
    assert_true(co_boot_start(&f->boot, &e));
    pass_identity(f, &e);
    assert_int_equal(co_boot_step(&f->boot), CO_BOOT_STEP_NODE_STATE);
    assert_int_equal(f->guard_requests, 0);   /* its heartbeat is awaited instead */
    advance(f, 299);
    assert_true(co_boot_running(&f->boot));
    advance(f, 1);
    assert_done(f, CO_BOOT_ERR_E);
    assert_int_equal(f->nmt_count, 0);
    free(f);
}

static void test_f_keep_alive_without_guarding_answer(void **state)
{
    (void)state;
    fake_t *f = fake_new();
    co_boot_expect_t e = full_expect();
    e.assignment |= CO_BOOT_ASSIGN_KEEP_ALIVE;
    assert_true(co_boot_start(&f->boot, &e));
    pass_identity(f, &e);
    assert_int_equal(f->guard_requests, 1);
    advance(f, CO_BOOT_DEFAULT_GUARD_TIMEOUT_MS);
    assert_done(f, CO_BOOT_ERR_F);
    free(f);
}

static void test_l_keep_alive_operational_not_reset(void **state)
{
    (void)state;
    fake_t *f = fake_new();
    co_boot_expect_t e = full_expect();
    e.assignment |= CO_BOOT_ASSIGN_KEEP_ALIVE | CO_BOOT_ASSIGN_CHECK_SOFTWARE;
    e.software_id = 5;
    e.heartbeat_ms = 300;
    assert_true(co_boot_start(&f->boot, &e));
    pass_identity(f, &e);
    frame(f, CO_NMT_OPERATIONAL);
    /* no reset, no software or configuration step: error control waits for
     * the next heartbeat */
    assert_int_equal(co_boot_step(&f->boot), CO_BOOT_STEP_ERROR_CONTROL);
    frame(f, CO_NMT_OPERATIONAL);
    assert_done(f, CO_BOOT_ERR_L);
    assert_int_equal(f->nmt_count, 0);
    assert_int_equal(f->read_count, 5);
    free(f);
}

static void test_keep_alive_guarded_preoperational_is_reset(void **state)
{
    (void)state;
    fake_t *f = fake_new();
    co_boot_expect_t e = full_expect();
    e.assignment |= CO_BOOT_ASSIGN_KEEP_ALIVE;
    assert_true(co_boot_start(&f->boot, &e));
    pass_identity(f, &e);
    frame(f, 0x80 | CO_NMT_PRE_OPERATIONAL);   /* guarding answer, toggle set */
    assert_int_equal(f->nmt_count, 1);
    assert_int_equal(f->nmt[0], CO_NMT_CMD_RESET_COMMUNICATION);
    frame(f, 0x00);
    assert_done(f, CO_BOOT_OK);
    free(f);
}

static void software_expect(co_boot_expect_t *e, uint32_t extra)
{
    *e = full_expect();
    e->assignment |= CO_BOOT_ASSIGN_CHECK_SOFTWARE | extra;
    e->software_id = 0x0102;
}

static void to_software(fake_t *f, const co_boot_expect_t *e)
{
    assert_true(co_boot_start(&f->boot, e));
    pass_identity(f, e);
    frame(f, 0x00);
    assert_int_equal(last_read(f), 0x1F5601);
}

static void test_g_h_software(void **state)
{
    (void)state;
    co_boot_expect_t e;
    /* G: asked to check, nothing to check against */
    fake_t *f = fake_new();
    software_expect(&e, 0);
    e.software_id = 0;
    assert_true(co_boot_start(&f->boot, &e));
    pass_identity(f, &e);
    frame(f, 0x00);
    assert_done(f, CO_BOOT_ERR_G);
    free(f);
    /* G: the node has no 1F56:01 */
    f = fake_new();
    software_expect(&e, 0);
    to_software(f, &e);
    co_boot_upload_done(&f->boot, 0x06020000u, NULL, 0);
    assert_done(f, CO_BOOT_ERR_G);
    free(f);
    /* H: differs, update not allowed */
    f = fake_new();
    software_expect(&e, 0);
    to_software(f, &e);
    answer(f, 0x0101);
    assert_done(f, CO_BOOT_ERR_H);
    free(f);
    /* H: update allowed, but keep-alive forbids it */
    f = fake_new();
    software_expect(&e, CO_BOOT_ASSIGN_UPDATE_SOFTWARE | CO_BOOT_ASSIGN_KEEP_ALIVE);
    e.heartbeat_ms = 100;
    assert_true(co_boot_start(&f->boot, &e));
    pass_identity(f, &e);
    frame(f, CO_NMT_PRE_OPERATIONAL);
    frame(f, 0x00);
    answer(f, 0x0101);
    assert_done(f, CO_BOOT_ERR_H);
    free(f);
    /* same software: on to the configuration */
    f = fake_new();
    software_expect(&e, 0);
    to_software(f, &e);
    answer(f, 0x0102);
    assert_done(f, CO_BOOT_OK);
    free(f);
}

static void test_i_software_update_hook(void **state)
{
    (void)state;
    co_boot_expect_t e;
    fake_t *f = fake_new();
    software_expect(&e, CO_BOOT_ASSIGN_UPDATE_SOFTWARE);
    to_software(f, &e);
    answer(f, 0x0101);
    assert_int_equal(last_report(f)->event, CO_BOOT_EV_UPDATE_SOFTWARE);
    assert_int_equal(co_boot_step(&f->boot), CO_BOOT_STEP_UPDATE_SOFTWARE);
    assert_false(co_boot_continue_config(&f->boot, true));   /* not the question asked */
    /* the update worked: checked again from the device type on */
    unsigned reads = f->read_count;
    assert_true(co_boot_continue_software(&f->boot, true));
    assert_int_equal(f->read_count, reads + 1);
    assert_int_equal(last_read(f), 0x100000);
    pass_identity(f, &e);
    frame(f, 0x00);
    answer(f, 0x0102);
    assert_done(f, CO_BOOT_OK);
    assert_false(co_boot_continue_software(&f->boot, true));
    free(f);
    /* the update "worked" but the node still has the old software: I, not
     * a second question (that could go on for ever) */
    f = fake_new();
    software_expect(&e, CO_BOOT_ASSIGN_UPDATE_SOFTWARE);
    to_software(f, &e);
    answer(f, 0x0101);
    assert_true(co_boot_continue_software(&f->boot, true));
    pass_identity(f, &e);
    frame(f, 0x00);
    answer(f, 0x0101);
    assert_done(f, CO_BOOT_ERR_I);
    unsigned asked = 0;
    for (unsigned i = 0; i < f->report_count; i++) {
        asked += f->reports[i].event == CO_BOOT_EV_UPDATE_SOFTWARE;
    }
    assert_int_equal(asked, 1);
    free(f);
    /* the update failed: I */
    f = fake_new();
    software_expect(&e, CO_BOOT_ASSIGN_UPDATE_SOFTWARE);
    f->answer_software = 0;
    to_software(f, &e);
    answer(f, 0x0101);
    assert_done(f, CO_BOOT_ERR_I);
    free(f);
}

static void test_j_configuration(void **state)
{
    (void)state;
    co_boot_expect_t e = full_expect();
    e.config_date = 9000;
    e.config_time = 1234;
    /* current configuration: no update asked */
    fake_t *f = fake_new();
    assert_true(co_boot_start(&f->boot, &e));
    pass_identity(f, &e);
    frame(f, 0x00);
    assert_int_equal(last_read(f), 0x102001);
    answer(f, 9000);
    assert_int_equal(last_read(f), 0x102002);
    answer(f, 1234);
    assert_done(f, CO_BOOT_OK);
    for (unsigned i = 0; i < f->report_count; i++) {
        assert_int_not_equal(f->reports[i].event, CO_BOOT_EV_UPDATE_CONFIG);
    }
    free(f);
    /* another time: update asked, failed: J */
    f = fake_new();
    f->answer_config = 0;
    assert_true(co_boot_start(&f->boot, &e));
    pass_identity(f, &e);
    frame(f, 0x00);
    answer(f, 9000);
    answer(f, 1235);
    assert_done(f, CO_BOOT_ERR_J);
    free(f);
    /* no 0x1020 on the node: update asked, answered later */
    f = fake_new();
    f->answer_config = -1;
    assert_true(co_boot_start(&f->boot, &e));
    pass_identity(f, &e);
    frame(f, 0x00);
    co_boot_upload_done(&f->boot, 0x06020000u, NULL, 0);
    assert_int_equal(last_report(f)->event, CO_BOOT_EV_UPDATE_CONFIG);
    advance(f, 5000);   /* the application takes its time: no timeout here */
    assert_true(co_boot_continue_config(&f->boot, true));
    assert_done(f, CO_BOOT_OK);
    free(f);
}

static void test_k_no_first_heartbeat(void **state)
{
    (void)state;
    fake_t *f = fake_new();
    co_boot_expect_t e = full_expect();
    e.heartbeat_ms = 200;
    assert_true(co_boot_start(&f->boot, &e));
    pass_identity(f, &e);
    frame(f, 0x00);
    assert_int_equal(co_boot_step(&f->boot), CO_BOOT_STEP_ERROR_CONTROL);
    advance(f, 200);
    assert_done(f, CO_BOOT_ERR_K);
    /* and with the heartbeat in time: OK */
    assert_true(co_boot_start(&f->boot, &e));
    pass_identity(f, &e);
    frame(f, 0x00);
    advance(f, 150);
    frame(f, CO_NMT_PRE_OPERATIONAL);
    assert_done(f, CO_BOOT_OK);
    free(f);
}

static void test_no_boot_bit_goes_to_error_control(void **state)
{
    (void)state;
    fake_t *f = fake_new();
    co_boot_expect_t e = full_expect();
    e.assignment = CO_BOOT_ASSIGN_SLAVE;
    assert_true(co_boot_start(&f->boot, &e));
    assert_done(f, CO_BOOT_OK);
    assert_int_equal(f->read_count, 0);
    assert_int_equal(f->nmt_count, 0);
    free(f);
}

static void test_wrong_use_is_refused(void **state)
{
    (void)state;
    fake_t *f = fake_new();
    co_boot_t b;
    assert_false(co_boot_init(&b, &f->tl.line, 0, &f->access));
    assert_false(co_boot_init(&b, &f->tl.line, 128, &f->access));
    assert_false(co_boot_init(&b, NULL, 1, &f->access));
    co_boot_access_t no_report = f->access;
    no_report.report = NULL;
    assert_false(co_boot_init(&b, &f->tl.line, 1, &no_report));
    co_boot_expect_t e = full_expect();
    assert_true(co_boot_start(&f->boot, &e));
    assert_false(co_boot_start(&f->boot, &e));   /* running */
    /* wrong lengths and stray input never crash and never pass a check */
    uint8_t three[3] = {0x91, 0x01, 0x02};
    co_boot_upload_done(&f->boot, 0, three, 3);
    assert_done(f, CO_BOOT_ERR_C);
    assert_int_equal(f->reports[f->report_count - 2].got_length, 3);
    co_boot_upload_done(&f->boot, 0, three, 3);   /* no read runs: ignored */
    co_boot_ec_frame(&f->boot, NULL, 0);
    assert_int_equal(last_report(f)->event, CO_BOOT_EV_DONE);
    /* cancel: no report, the late answer is ignored */
    assert_true(co_boot_start(&f->boot, &e));
    unsigned n = f->report_count;
    co_boot_cancel(&f->boot);
    answer(f, e.device_type);
    assert_int_equal(f->report_count, n);
    assert_false(co_boot_running(&f->boot));
    free(f);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_full_boot_ends_ok),
        cmocka_unit_test(test_a_not_in_network_list),
        cmocka_unit_test(test_b_device_type_retried_then_b),
        cmocka_unit_test(test_b_no_bootup_after_reset),
        cmocka_unit_test(test_c_device_type_differs),
        cmocka_unit_test(test_d_m_n_o_identity_differs),
        cmocka_unit_test(test_identity_skips_zero_expectations),
        cmocka_unit_test(test_e_keep_alive_without_heartbeat),
        cmocka_unit_test(test_f_keep_alive_without_guarding_answer),
        cmocka_unit_test(test_l_keep_alive_operational_not_reset),
        cmocka_unit_test(test_keep_alive_guarded_preoperational_is_reset),
        cmocka_unit_test(test_g_h_software),
        cmocka_unit_test(test_i_software_update_hook),
        cmocka_unit_test(test_j_configuration),
        cmocka_unit_test(test_k_no_first_heartbeat),
        cmocka_unit_test(test_no_boot_bit_goes_to_error_control),
        cmocka_unit_test(test_wrong_use_is_refused),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
