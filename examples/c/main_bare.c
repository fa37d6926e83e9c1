/* The example device on a microcontroller: a polling loop over board.h.
 * Everything is static; the stack's memory is the device's arena. */
#include "board.h"
#include "device.h"

#ifndef EXAMPLE_MODE
#define EXAMPLE_MODE CO_MODE_FD
#endif
#ifndef EXAMPLE_NODE_ID
#define EXAMPLE_NODE_ID 5
#endif

static device_t device;

int main(void)
{
    board_init();
    if (device_init(&device, EXAMPLE_MODE, EXAMPLE_NODE_ID) != NULL) {
        for (;;) {
            /* the configuration does not fit the memory: stop here, as a
             * watchdog-less device would, rather than run half set up */
        }
    }
    for (;;) {
        co_frame_t frame;
        while (board_can_receive(&frame)) {
            (void)co_line_receive(&device.line, &frame);
        }
        (void)device_process(&device, board_micros());
        while (co_line_tx_count(&device.line) > 0 &&
               board_can_send(co_line_tx_at(&device.line, 0))) {
            (void)co_line_tx_pop(&device.line, &frame);
        }
    }
}
