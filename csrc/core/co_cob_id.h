/* CiA 301 rules for COB-ID entries, enforced on network writes whether or
 * not the service that uses the COB-ID runs yet: the CAN-ID (bits 0..28)
 * and the frame bit (29) may change only while the object is not active,
 * otherwise the write is refused with CO_ABORT_INVALID_VALUE (0x06090030)
 * and nothing changes.
 *
 *   0x1005:00          SYNC       active while bit 30 (gen) is 1
 *   0x1012:00          TIME       active while bit 30 (produce) or 31 (consume) is 1
 *   0x1014:00          EMCY       active while bit 31 (invalid) is 0
 *   0x1028:01..7F      EMCY consumer
 *   0x1200..0x12FF:01..02   SDO server / client COB-IDs
 *   0x1400..0x15FF:01  RPDO, 0x1800..0x19FF:01 TPDO
 *
 * (The "invalid" entries: co_od_check_cob_id_change; a change that also
 * sets or clears the active bit in the same write is allowed, CiA 301's
 * "disable, change, enable" done in one step.) Only UNSIGNED32 entries are
 * checked; other entries in the range are left to their own handlers. */
#ifndef CO_COB_ID_H
#define CO_COB_ID_H

#include "canopenfd/co_od.h"

/* Which rule an entry follows. */
typedef enum co_cob_id_kind {
    CO_COB_ID_NONE = 0,          /* not a COB-ID entry */
    CO_COB_ID_VALID_BIT31,       /* active while bit 31 is 0 (EMCY, SDO, PDO) */
    CO_COB_ID_SYNC,              /* active while bit 30 is 1 */
    CO_COB_ID_TIME               /* active while bit 30 or 31 is 1 */
} co_cob_id_kind_t;

co_cob_id_kind_t co_cob_id_kind(uint16_t index, uint8_t sub);
/* 0 or CO_ABORT_INVALID_VALUE for a change from old to new of that kind. */
uint32_t co_cob_id_check(co_cob_id_kind_t kind, uint32_t old_value, uint32_t new_value);
/* CiA 301 restricted CAN-IDs, which SDO, SYNC, TIME, EMCY and PDO COB-IDs
 * may not use: 0x000..0x07F, 0x101..0x180, 0x581..0x5FF, 0x601..0x67F,
 * 0x6E0..0x6FF, 0x701..0x7FF (CANopenNode's CO_IS_RESTRICTED_CAN_ID). */
bool co_cob_id_restricted(uint32_t can_id);
/* Hook the rule into od (one subscription over 0x1005..0x19FF). */
bool co_cob_id_attach(co_od_t *od);
void co_cob_id_detach(co_od_t *od);

#endif
