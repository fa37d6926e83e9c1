/* Runtime: in-process buses (channel "mem:NAME"), named per runtime, i.e.
 * per Network. The thread moves their frames between its turns' rounds. */
#include "co_rt_internal.h"

#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static rt_line_t *line_of(co_line_t *line)
{
    return (rt_line_t *)(void *)((char *)line - offsetof(rt_line_t, line));
}

static void on_membus_sent(co_line_t *from, const co_frame_t *frame, void *user)
{
    (void)user;
    rt_line_t *l = line_of(from);
    if (l->monitor) {
        rt_post(l, CO_EV_FRAME, 0, 1, 0, frame);
    }
}

uint32_t rt_membus_transfer(co_rt_t *rt)
{
    uint32_t moved = 0;
    for (int i = 0; i < rt->bus_count; i++) {
        moved += co_membus_transfer(&rt->buses[i]->bus, on_membus_sent, rt);
    }
    return moved;
}

static rt_bus_t *find_bus(co_rt_t *rt, const char *name)
{
    for (int i = 0; i < rt->bus_count; i++) {
        if (strcmp(rt->buses[i]->name, name) == 0) {
            return rt->buses[i];
        }
    }
    return NULL;
}

static int new_bus(co_rt_t *rt, const char *name, co_mode_t mode, rt_bus_t **out)
{
    if (rt->bus_count == RT_MAX_BUSES) {
        rt_set_error(rt, "membus %s: already %d buses in this runtime", name, RT_MAX_BUSES);
        return CO_RT_ERR_FULL;
    }
    rt_bus_t *bus = calloc(1, sizeof *bus);
    if (!bus) {
        return CO_RT_ERR_NO_MEMORY;
    }
    snprintf(bus->name, sizeof bus->name, "%s", name);
    bus->mode = mode;
    co_membus_init(&bus->bus);
    rt->buses[rt->bus_count++] = bus;
    *out = bus;
    return CO_RT_OK;
}

int rt_membus_bus(co_rt_t *rt, const char *name, co_mode_t mode, rt_bus_t **out)
{
    static const char *const mode_names[] = {"classic", "fd"};
    rt_bus_t *bus = find_bus(rt, name);
    int status = bus ? CO_RT_OK : new_bus(rt, name, mode, &bus);
    if (status != CO_RT_OK) {
        return status;
    }
    if (bus->mode != mode) {
        rt_set_error(rt, "membus %s: open in %s mode, a %s line cannot join it", bus->name,
                  mode_names[bus->mode], mode_names[mode]);
        return CO_RT_ERR_MODE;
    }
    *out = bus;
    return CO_RT_OK;
}

int rt_membus_join(co_rt_t *rt, rt_line_t *l)
{
    rt_bus_t *bus = NULL;
    int status = rt_membus_bus(rt, l->channel, co_line_mode(&l->line), &bus);
    if (status != CO_RT_OK) {
        return status;
    }
    if (!co_membus_attach(&bus->bus, &l->line)) {
        rt_set_error(rt, "membus %s: already %d lines", bus->name, CO_MEMBUS_MAX_LINES);
        return CO_RT_ERR_FULL;
    }
    return CO_RT_OK;
}

void rt_membus_free_all(co_rt_t *rt)
{
    for (int i = 0; i < rt->bus_count; i++) {
        free(rt->buses[i]);
    }
}

/* A simulated bus has no controller to fail: a test says what a real one
 * would (bus-off, interface down, ...), and the line reacts as it would to
 * its driver's report. */
int co_rt_membus_comm_event(co_rt_t *rt, int line, int event)
{
    rt_mutex_lock(&rt->lock);
    rt_line_t *l = rt_checked_line(rt, line, false);
    if (!l) {
        rt_mutex_unlock(&rt->lock);
        return CO_RT_ERR_ARGUMENT;
    }
    if (l->driver != CO_DRIVER_MEMBUS) {
        rt_set_error(rt, "line %d (%s): comm events are simulated on in-process lines only",
                     line, l->channel);
        rt_mutex_unlock(&rt->lock);
        return CO_RT_ERR_STATE;
    }
    if (event < CO_COMM_BUS_OFF || event > CO_COMM_BUS_OFF_RECOVERED) {
        int status = rt_argument_error(rt, "line %d (%s): comm event must be %d..%d, got %d",
                                       line, l->channel, CO_COMM_BUS_OFF,
                                       CO_COMM_BUS_OFF_RECOVERED, event);
        rt_mutex_unlock(&rt->lock);
        return status;
    }
    co_line_set_time(&l->line, co_rt_now_us());
    co_line_comm_event(&l->line, (co_comm_event_t)event);
    return rt_kick_unlock(rt, CO_RT_OK);
}
