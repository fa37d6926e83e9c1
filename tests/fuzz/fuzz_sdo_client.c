/* libFuzzer harness: the classic SDO client with transfers in flight
 * (expedited, segmented, block upload/download with and without CRC,
 * protocol switch), against the device's real server, with forged answers
 * on 0x581..0x5FF, losses, duplicates, a held bus, cancels and timeouts.
 * The device also runs its own 0x1280 client channel. */
#include "fuzz_world.h"

static const uint32_t ids[] = {0x585, 0x581, 0x5FF, 0x605, 0x5A5};
static const uint8_t actions[] = {FW_CLIENT_START, FW_CLIENT_START, FW_CLIENT_CANCEL,
                                  FW_SPLIT_MODE, FW_RESUME, FW_NMT_LOCAL, FW_OD_WRITE};

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static const fw_config_t cfg = {.mode = CO_MODE_CLASSIC, .inject_tool = true, .ids = ids,
                                    .id_count = sizeof ids / sizeof ids[0], .actions = actions,
                                    .action_count = sizeof actions, .device_client = true};
    fw_run(&cfg, data, size);
    return 0;
}
