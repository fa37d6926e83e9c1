/* co_stack built for fd lines only (-DCO_CONFIG_CLASSIC=0, as a minimal fd
 * device is): a classic line is refused with CO_STACK_ERR_ARGUMENT, an fd
 * line gets its USDO server and client. */
#include "test_util.h"

#include "canopenfd/co_stack.h"

static uint64_t memory[8192];

static void test_classic_line_refused(void **state)
{
    (void)state;
    tu_line_t classic;
    co_stack_t stack;
    co_stack_arena_t arena;
    tu_line_init(&classic, CO_MODE_CLASSIC, false);
    co_stack_arena_init(&arena, memory, sizeof memory);
    assert_int_equal(co_stack_init(&stack, &classic.line, NULL, co_stack_arena_allocator(&arena)),
                     CO_STACK_ERR_ARGUMENT);
    assert_int_equal(arena.used, 0);
}

static void test_fd_line_served(void **state)
{
    (void)state;
    tu_line_t fd;
    co_stack_t stack;
    co_stack_arena_t arena;
    tu_line_init(&fd, CO_MODE_FD, true);
    co_stack_arena_init(&arena, memory, sizeof memory);
    assert_int_equal(co_stack_init(&stack, &fd.line, NULL, co_stack_arena_allocator(&arena)),
                     CO_STACK_OK);
    co_stack_client_config_t client = {.sessions = 2, .node_id = 9};
    assert_int_equal(co_stack_client_init(&stack, &client), CO_STACK_OK);
    assert_non_null(co_stack_usdo_client(&stack));
    assert_null(co_stack_sdo_client(&stack));
    assert_null(co_stack_guard_master(&stack));
    co_stack_deinit(&stack);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_classic_line_refused),
        cmocka_unit_test(test_fd_line_served),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
