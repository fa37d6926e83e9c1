/* libFuzzer harness: the classic SDO server of a device (default channel
 * 0x605/0x585 and channel 1 at 0x1201 once configured), expedited,
 * segmented and block transfers with CRC, split answers, the domain, NMT
 * resets and store commands, mixed with the tool's real SDO client. */
#include "fuzz_world.h"

static const uint32_t ids[] = {0x605, 0x600, 0x67F, 0x6A5, 0x000, 0x080, 0x585, 0x625};
static const uint8_t actions[] = {FW_CLIENT_START, FW_CLIENT_CANCEL, FW_SPLIT_MODE, FW_RESUME,
                                  FW_NMT_LOCAL, FW_OD_WRITE, FW_STORE, FW_CLIENT_START};

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static const fw_config_t cfg = {.mode = CO_MODE_CLASSIC, .ids = ids,
                                    .id_count = sizeof ids / sizeof ids[0], .actions = actions,
                                    .action_count = sizeof actions};
    fw_run(&cfg, data, size);
    return 0;
}
