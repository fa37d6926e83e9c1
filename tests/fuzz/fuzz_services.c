/* libFuzzer harness: EMCY (producer and consumers), SYNC, TIME, heartbeat
 * (producer and consumers), NMT (slave and master) and node guarding
 * (master and slave, classic lines) on a classic or fd line (first input
 * byte, bit 0). Frames reach the tool line's consumers by default, the
 * device's with the FRAME record's "other line" bit. */
#include "fuzz_world.h"

static const uint32_t ids[] = {0x000, 0x080, 0x100, 0x081, 0x082, 0x085, 0x703, 0x705,
                               0x701, 0x77F, 0x709, 0x0FF};
static const uint8_t actions[] = {FW_NMT_LOCAL, FW_NMT_MASTER, FW_EMCY, FW_TIME_SEND,
                                  FW_WATCH, FW_WATCH, FW_OD_WRITE, FW_OD_PUT, FW_STORE};

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static const fw_config_t fd = {.mode = CO_MODE_FD, .inject_tool = true, .ids = ids,
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
