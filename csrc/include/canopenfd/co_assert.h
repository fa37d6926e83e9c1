/* CO_ASSERT(x): the stack's check of its own invariants — a pointer set at
 * init, an index the code itself keeps in bounds, a queue's counts, a
 * documented precondition of an internal call. Never used for network input
 * or an application's arguments: those are refused with a return value.
 *
 * Defaults to the C standard assert (so NDEBUG turns it off). An application
 * or a test may define CO_ASSERT itself, on the compiler's command line or
 * before the first canopenfd header, e.g. to log and trap on a target without
 * stdio:  -D'CO_ASSERT(x)=((x) ? (void)0 : my_fault(__FILE__, __LINE__))'
 * x must not have side effects: with NDEBUG it is not evaluated at all. */
#ifndef CO_ASSERT_H
#define CO_ASSERT_H

#ifndef CO_ASSERT
#include <assert.h>
#define CO_ASSERT(x) assert(x)
#endif

#endif
