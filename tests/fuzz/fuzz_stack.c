/* libFuzzer harness: the whole node as co_stack assembles it, on a classic
 * or fd line (first input byte, bit 0), every service at once: any frame
 * (the table holds one CAN-ID of each service, raw ids reach the rest), every
 * application action, communication events from the driver. */
#include "fuzz_world.h"

static const uint32_t ids[] = {0x000, 0x080, 0x100, 0x085, 0x185, 0x205, 0x305, 0x585,
                               0x605, 0x609, 0x705, 0x703, 0x6A5, 0x081};
static const uint8_t actions[] = {FW_CLIENT_START, FW_CLIENT_CANCEL, FW_SPLIT_MODE, FW_RESUME,
                                  FW_NMT_LOCAL, FW_NMT_MASTER, FW_OD_WRITE, FW_OD_PUT,
                                  FW_PDO_TRIGGER, FW_EMCY, FW_TIME_SEND, FW_WATCH, FW_STORE,
                                  FW_LED};

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static const fw_config_t fd = {.mode = CO_MODE_FD, .ids = ids,
                                   .id_count = sizeof ids / sizeof ids[0], .actions = actions,
                                   .action_count = sizeof actions, .device_client = true};
    fw_config_t cfg = fd;
    if (size == 0) {
        return 0;
    }
    cfg.mode = (data[0] & 1u) ? CO_MODE_CLASSIC : CO_MODE_FD;
    fw_run(&cfg, data + 1, size - 1);
    return 0;
}
