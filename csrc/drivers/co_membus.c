#include "canopenfd/co_membus.h"

#include <string.h>

void co_membus_init(co_membus_t *bus)
{
    memset(bus, 0, sizeof *bus);
}

bool co_membus_attach(co_membus_t *bus, co_line_t *line)
{
    if (bus->count >= CO_MEMBUS_MAX_LINES) {
        return false;
    }
    for (uint8_t i = 0; i < bus->count; i++) {
        if (bus->lines[i] == line) {
            return false;
        }
    }
    bus->lines[bus->count++] = line;
    return true;
}

void co_membus_detach(co_membus_t *bus, co_line_t *line)
{
    uint8_t kept = 0;
    for (uint8_t i = 0; i < bus->count; i++) {
        if (bus->lines[i] != line) {
            bus->lines[kept++] = bus->lines[i];
        }
    }
    bus->count = kept;
}

void co_membus_set_fault(co_membus_t *bus, co_membus_fault_fn fn, void *user)
{
    bus->fault = fn;
    bus->fault_user = user;
}

static void deliver(co_membus_t *bus, const co_line_t *from, const co_frame_t *frame)
{
    uint8_t copies = bus->fault ? bus->fault(frame, bus->fault_user) : 1;
    for (uint8_t n = 0; n < copies; n++) {
        for (uint8_t i = 0; i < bus->count; i++) {
            if (bus->lines[i] != from) {
                co_line_receive(bus->lines[i], frame);
            }
        }
    }
}

uint32_t co_membus_transfer(co_membus_t *bus, co_membus_sent_fn sent, void *user)
{
    uint32_t moved = 0;
    for (uint8_t i = 0; i < bus->count; i++) {
        co_line_t *from = bus->lines[i];
        /* Delivered from the sender's tx slot, then taken: no copy. The
         * receivers only queue it (co_line_receive); nothing pops the
         * sender's tx queue meanwhile, and pushes go to its tail. */
        while (co_line_tx_count(from) != 0) {
            const co_frame_t *frame = co_line_tx_at(from, 0);
            if (sent) {
                sent(from, frame, user);
            }
            deliver(bus, from, frame);
            (void)co_line_tx_pop(from, NULL);
            moved++;
        }
    }
    bus->frames += moved;
    return moved;
}
