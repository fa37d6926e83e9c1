/* co_stack's CiA 401 part: the node's OD bound as a generic I/O device
 * (co_cia401_od), fed the node's RPDOs, NMT states and resets. */
#include "canopenfd/co_stack.h"
#include "co_stack_blocks.h"

static void on_state(co_node_t *node, co_nmt_state_t old_state, co_nmt_state_t new_state,
                     void *user)
{
    (void)node;
    co_cia401_od_nmt_state(user, old_state, new_state);
}

static void on_rpdo(co_node_t *node, uint16_t rpdo_number, void *user)
{
    (void)node;
    co_cia401_od_rpdo_received(user, rpdo_number);
}

static void on_reset(co_node_t *node, co_nmt_command_t kind, void *user)
{
    (void)node;
    co_cia401_od_reset(user, kind);
}

static const co_node_indications_t wiring = {
    .state_changed = on_state,
    .pdo_received = on_rpdo,
    .reset = on_reset,
};

size_t co_stack_cia401_need(co_stack_t *stack)
{
    co_cia401_od_counts_t counts;
    uint16_t index;
    uint8_t sub;
    if (!stack || !stack->has_node || !stack->od ||
        co_cia401_od_scan(stack->od, &counts, &index, &sub) != CO_CIA401_OD_OK) {
        return 0;
    }
    return CO_STACK_BLOCK(co_cia401_od_need(&counts));
}

co_stack_status_t co_stack_cia401_init(co_stack_t *stack, co_cia401_outputs_fn on_outputs,
                                       void *user)
{
    co_cia401_od_counts_t counts;
    uint16_t index;
    uint8_t sub;
    if (!stack || !stack->line) {
        return CO_STACK_ERR_ARGUMENT;
    }
    if (!stack->has_node || stack->has_cia401) {
        return co_stack_fail(stack, CO_STACK_PART_CIA401, CO_STACK_ERR_STATE);
    }
    if (!stack->od || co_cia401_od_scan(stack->od, &counts, &index, &sub) != CO_CIA401_OD_OK) {
        return co_stack_fail(stack, CO_STACK_PART_CIA401, CO_STACK_ERR_OD);
    }
    void *memory = co_stack_take(stack, CO_STACK_OWNER_CIA401, co_cia401_od_need(&counts));
    if (!memory) {
        return co_stack_fail(stack, CO_STACK_PART_CIA401, CO_STACK_ERR_NO_MEMORY);
    }
    if (!co_cia401_od_attach(&stack->cia401, stack->od, co_stack_pdo(stack), &counts, memory,
                             on_outputs, user)) {
        co_stack_give_back(stack, CO_STACK_OWNER_CIA401);
        return co_stack_fail(stack, CO_STACK_PART_CIA401, CO_STACK_ERR_TAKEN);
    }
    co_node_set_part_indications(&stack->node, &wiring, &stack->cia401);
    stack->has_cia401 = true;
    return CO_STACK_OK;
}

void co_stack_cia401_deinit(co_stack_t *stack)
{
    if (!stack || !stack->has_cia401) {
        return;
    }
    co_node_set_part_indications(&stack->node, NULL, NULL);
    co_cia401_od_detach(&stack->cia401);
    stack->has_cia401 = false;
    co_stack_give_back(stack, CO_STACK_OWNER_CIA401);
}
