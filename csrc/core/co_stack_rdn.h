/* What co_stack.c tells the bus redundancy part (co_stack_redundancy.c):
 * private to the stack's two files. */
#ifndef CO_STACK_RDN_H
#define CO_STACK_RDN_H

#include "canopenfd/co_stack.h"

/* The heartbeat consumer's events: the slave's master heard or lost. */
void co_stack_rdn_heartbeat(co_stack_t *s, uint8_t node_id, co_hb_event_t event);
/* The line's comm events: a master may move off a failed bus. */
void co_stack_rdn_comm(co_stack_t *s, co_comm_event_t event);
/* A node set up while the service runs: its resets, and its OD's record
 * when valid (served from now on, its values taken). */
void co_stack_rdn_node_added(co_stack_t *s);
/* The node (and its OD) goes: the service keeps running on its values. */
void co_stack_rdn_node_gone(co_stack_t *s);
/* Power-on of the node: Bdefault again. */
void co_stack_rdn_boot(co_stack_t *s);

#endif
