/* libFuzzer harness: the PDO service (4 RPDOs, 4 TPDOs: event, SYNC,
 * RTR-only, cyclic and acyclic types) on a classic or fd line (first input
 * byte, bit 0), with RPDOs, SYNCs and remote frames arriving while the
 * communication and mapping parameters change through the OD (checked
 * writes as a server makes them, application writes, SDO/USDO requests on
 * the wire), NMT state changes and store reloads; the same PDOs made MPDOs
 * (DAM and SAM, with the device's scanner and dispatcher lists) receiving
 * MPDO frames and sending them. */
#include "fuzz_world.h"

static const uint32_t ids[] = {0x205, 0x305, 0x405, 0x505, 0x185, 0x285, 0x385, 0x485,
                               0x080, 0x000, 0x605, 0x609};
static const uint8_t actions[] = {FW_OD_WRITE, FW_OD_WRITE, FW_OD_PUT, FW_PDO_TRIGGER,
                                  FW_NMT_LOCAL, FW_NMT_MASTER, FW_EMCY, FW_STORE,
                                  FW_CLIENT_START, FW_MPDO_SEND};

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static const fw_config_t fd = {.mode = CO_MODE_FD, .ids = ids,
                                   .id_count = sizeof ids / sizeof ids[0], .actions = actions,
                                   .action_count = sizeof actions};
    fw_config_t cfg = fd;
    if (size == 0) {
        return 0;
    }
    cfg.mode = (data[0] & 1u) ? CO_MODE_CLASSIC : CO_MODE_FD;
    fw_run(&cfg, data + 1, size - 1);
    return 0;
}
