/* The SRDO objects of a node's object dictionary (CiA 304): 0x1301+n
 * (communication), 0x1381+n (mapping), 0x13FE (configuration valid) and
 * 0x13FF sub n (signature) guarded by OD handlers and run by the SRDOs;
 * 0x1300 (GFC parameter, 0 or 1, any NMT state) switches the GFC.
 *
 * - Writes to them are refused with 0x08000022 (data cannot be stored in
 *   the present device state) while the node is operational: CiA 304
 *   changes a safety configuration only outside operational.
 * - Out-of-range values are refused (0x06090030; a mapping count that is
 *   odd or above 16: 0x06040042); a mapping entry or count changes only
 *   while the SRDO's direction is 0 (0x06010000) and a mapping entry only
 *   while the count is 0 (0x06010000), the order CiA 301 sets for PDOs.
 * - Any accepted write to a communication or mapping entry or to 0x13FF
 *   sets 0x13FE to 0 (not valid): a changed configuration never runs
 *   before a tool has validated it again (0xA5). The application's own
 *   writes (co_od_put) pass the checks above, even in operational, but
 *   count as a change too. Loading defaults or stored values at a reset is
 *   no change.
 * - Outside operational every SRDO follows these objects: configured from
 *   them and its mapping bound to the OD's variables (co_srdo_bind_od) at
 *   the attach, after every accepted write and after a reset loads them;
 *   on the transition to operational once more, then started: a configuration that is not valid, whose signature is not
 *   its CRC, or whose values or mapping do not hold enters the safe state
 *   saying so (co_srdo.h).
 * An SRDO whose communication object 0x1301+n the OD lacks keeps the
 * configuration the application gave it (co_srdo_configure). */
#ifndef CO_SRDO_OD_H
#define CO_SRDO_OD_H

#include "canopenfd/co_gfc.h"
#include "canopenfd/co_od.h"
#include "canopenfd/co_srdo.h"

enum {
    CO_SRDO_OD_GFC = 0x1300,             /* sub 0: 1 = GFC on */
    CO_SRDO_OD_COMMUNICATION = 0x1300,   /* + n, n = 1..64 */
    CO_SRDO_OD_MAPPING = 0x1380,         /* + n */
    CO_SRDO_OD_VALID = 0x13FE,
    CO_SRDO_OD_SIGNATURE = 0x13FF,       /* sub n */
    /* CiA 304's default COB-IDs of SRDO 1: these base values in 0x1301 sub 5
     * and 6 stand for base + 2 x node-id (node-ids 1..64: 0x101..0x180) */
    CO_SRDO_OD_DEFAULT_COB_ID = 0x0FF,
    CO_SRDO_OD_DEFAULT_LAST_NODE = 64
};

typedef struct co_srdo_od {
    co_od_t *od;
    co_srdo_t *srdo;
    uint8_t count;
    co_gfc_t *gfc;                       /* follows 0x1300, when the OD has it */
    bool operational;
} co_srdo_od_t;

/* Guard and run `count` SRDOs from od (sealed), configuring them from it
 * now unless state is operational; gfc (may be NULL) follows 0x1300 from
 * now on. False when the OD has no
 * 0x13FE (nothing to guard: g stays detached) or no room for the
 * subscription. */
bool co_srdo_od_attach(co_srdo_od_t *g, co_od_t *od, co_srdo_t *srdo, uint8_t count,
                       co_gfc_t *gfc, co_nmt_state_t state);
void co_srdo_od_detach(co_srdo_od_t *g);
/* The node's NMT state, before the SRDOs hear it: entering operational
 * configures every SRDO from the OD (co_srdo_od_load). */
void co_srdo_od_set_nmt_state(co_srdo_od_t *g, co_nmt_state_t state);
/* Configure SRDO `number` (1..count) from the OD now (not while
 * operational). False when the OD lacks 0x1300+number (the SRDO keeps its
 * configuration) or the SRDO refused it (operational, CAN-IDs taken). */
bool co_srdo_od_load(co_srdo_od_t *g, uint8_t number);
/* Write a configuration, its 0x13FE value and 0x13FF signature into the
 * OD (the application's own configure, so the next start keeps it): 0, or
 * the abort of the first entry the OD refused (0x06020000 / 0x06090011:
 * it lacks one). */
uint32_t co_srdo_od_store(co_srdo_od_t *g, uint8_t number, const co_srdo_config_t *config,
                          uint8_t valid, uint16_t signature);

#endif
