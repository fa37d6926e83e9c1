/* libFuzzer harness: the USDO server of an fd device (co_usdo_server inside
 * a co_stack node). Frames are client requests (0x601..0x67F, byte 0 the
 * server's node-id or 0), mixed with the tool's real USDO client transfers,
 * split answers of 0x2100 resumed later (or never, until SETTLE), a domain
 * streamed through application callbacks, NMT resets and store commands. */
#include "fuzz_world.h"

static const uint32_t ids[] = {0x609, 0x601, 0x67F, 0x605, 0x000, 0x080, 0x585};
static const uint8_t actions[] = {FW_CLIENT_START, FW_CLIENT_CANCEL, FW_SPLIT_MODE, FW_RESUME,
                                  FW_NMT_LOCAL, FW_OD_WRITE, FW_STORE, FW_CLIENT_START};

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static const fw_config_t cfg = {.mode = CO_MODE_FD, .ids = ids,
                                    .id_count = sizeof ids / sizeof ids[0], .actions = actions,
                                    .action_count = sizeof actions};
    fw_run(&cfg, data, size);
    return 0;
}
