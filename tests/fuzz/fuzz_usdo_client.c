/* libFuzzer harness: the USDO client with transfers in flight. The tool's
 * client runs up to four requests (expedited, segmented, bulk, broadcast;
 * uploads and downloads) against the device's real server; the input adds
 * forged or replayed server answers on 0x581..0x5FF, losses and duplicates
 * on the bus, a held bus (tx queue full during bulk sending), cancels and
 * timeouts. */
#include "fuzz_world.h"

static const uint32_t ids[] = {0x585, 0x581, 0x5FF, 0x589, 0x605, 0x609};
static const uint8_t actions[] = {FW_CLIENT_START, FW_CLIENT_START, FW_CLIENT_CANCEL,
                                  FW_SPLIT_MODE, FW_RESUME, FW_NMT_LOCAL};

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static const fw_config_t cfg = {.mode = CO_MODE_FD, .inject_tool = true, .ids = ids,
                                    .id_count = sizeof ids / sizeof ids[0], .actions = actions,
                                    .action_count = sizeof actions};
    fw_run(&cfg, data, size);
    return 0;
}
