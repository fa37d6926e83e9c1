/* What the example device needs from a microcontroller board: a free-running
 * microsecond clock and a CAN (FD) controller that takes and gives frames
 * without blocking. A port implements these three with its HAL. */
#ifndef EXAMPLE_BOARD_H
#define EXAMPLE_BOARD_H

#include "canopenfd/co_frame.h"

#include <stdbool.h>
#include <stdint.h>

void board_init(void);
uint64_t board_micros(void);
/* A received frame, false when none is waiting. */
bool board_can_receive(co_frame_t *out);
/* Queue a frame for sending, false when the controller is full (try later). */
bool board_can_send(const co_frame_t *frame);

#endif
