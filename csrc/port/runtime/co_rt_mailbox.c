/* Runtime: the command mailbox in from the application. A bounded ring with
 * a lock of its own (a leaf), so posting a command never waits for a turn
 * of the thread; co_rt_command (co_rt_commands.c) checks a command before
 * it lands here. */
#include "co_rt_internal.h"

int rt_mailbox_post(rt_mailbox_t *m, const co_rt_command_t *command)
{
    int status = CO_RT_OK;
    rt_mutex_lock(&m->lock);
    if (m->closed) {
        status = CO_RT_ERR_CLOSED;
    } else if (m->count == RT_MAILBOX_SIZE) {
        status = CO_RT_ERR_FULL;
    } else {
        m->ring[(m->head + m->count) % RT_MAILBOX_SIZE] = *command;
        m->count++;
    }
    rt_mutex_unlock(&m->lock);
    return status;
}

uint32_t rt_mailbox_take(rt_mailbox_t *m, co_rt_command_t *out, uint32_t max)
{
    uint32_t n = 0;
    rt_mutex_lock(&m->lock);
    for (; n < max && m->count > 0; n++) {
        out[n] = m->ring[m->head];
        m->head = (m->head + 1) % RT_MAILBOX_SIZE;
        m->count--;
    }
    rt_mutex_unlock(&m->lock);
    return n;
}

void rt_mailbox_close(rt_mailbox_t *m)
{
    rt_mutex_lock(&m->lock);
    m->closed = true;
    rt_mutex_unlock(&m->lock);
}
