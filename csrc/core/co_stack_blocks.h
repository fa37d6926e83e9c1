/* The stack's memory blocks, for the node-assembly parts that live in
 * files of their own (co_stack_cia401.c): private to the stack's files. */
#ifndef CO_STACK_BLOCKS_H
#define CO_STACK_BLOCKS_H

#include "canopenfd/co_stack.h"

/* The owner of the blocks of a part in its own file (co_stack.c's owners
 * are 0..4). */
enum { CO_STACK_OWNER_CIA401 = 5 };

/* A zeroed block for `owner`, NULL when the allocator or the table is out. */
void *co_stack_take(co_stack_t *s, uint8_t owner, size_t size);
/* Every block of `owner` given back, the newest first. */
void co_stack_give_back(co_stack_t *s, uint8_t owner);
/* Records the failing part and returns status. */
co_stack_status_t co_stack_fail(co_stack_t *s, co_stack_part_t part, co_stack_status_t status);

#endif
