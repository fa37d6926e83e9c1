/* board.h for the footprint build: the Cortex-M SysTick as the clock and a
 * CAN controller seen as two frame mailboxes in memory (the linker places
 * them; a hardware CAN FD controller such as an M_CAN has message RAM much
 * like it). It links a whole firmware so its size can be measured; a real
 * board replaces this file with its HAL's CAN driver. */
#include "board.h"

#include <string.h>

#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)
#define CPU_MHZ 48u
#define SYSTICK_RELOAD 0x00FFFFFFu

typedef struct mailbox {
    volatile uint32_t full;       /* set by the side that filled it */
    co_frame_t frame;
} mailbox_t;

mailbox_t can_rx_mailbox;
mailbox_t can_tx_mailbox;

static uint32_t last_tick;
static uint64_t ticks;

void board_init(void)
{
    SYST_RVR = SYSTICK_RELOAD;
    SYST_CVR = 0;
    SYST_CSR = 5u;                /* processor clock, enabled, no interrupt */
    last_tick = SYST_CVR;
}

/* Polled often enough (well under one SysTick wrap) by the main loop. */
uint64_t board_micros(void)
{
    uint32_t now = SYST_CVR;      /* counts down */
    ticks += (last_tick - now) & SYSTICK_RELOAD;
    last_tick = now;
    return ticks / CPU_MHZ;
}

bool board_can_receive(co_frame_t *out)
{
    if (!can_rx_mailbox.full) {
        return false;
    }
    memcpy(out, (const void *)&can_rx_mailbox.frame, sizeof *out);
    can_rx_mailbox.full = 0;
    return true;
}

bool board_can_send(const co_frame_t *frame)
{
    if (can_tx_mailbox.full) {
        return false;
    }
    memcpy((void *)&can_tx_mailbox.frame, frame, sizeof *frame);
    can_tx_mailbox.full = 1;
    return true;
}
