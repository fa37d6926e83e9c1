/* Runtime: adding a line. Its queues, the services the core's co_stack
 * assembles for it (heartbeat consumer, SYNC, TIME, EMCY consumer, guarding
 * master), the glue that posts their events, and its driver: an in-process
 * bus, a SocketCAN socket or a host line. Lines are published with a
 * release store and never removed while the runtime lives. */
#include "co_rt_internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Boot-ups, states and heartbeat losses of every node (local node or not);
 * the stack tells the node itself. */
static void on_heartbeat(co_stack_t *stack, uint8_t node_id, co_hb_event_t event,
                         co_nmt_state_t state, void *user)
{
    (void)stack;
    rt_post(user, CO_EV_HEARTBEAT, node_id, (uint32_t)event, (uint32_t)state, NULL);
}

static void on_comm(co_stack_t *stack, co_comm_event_t event, void *user)
{
    (void)stack;
    rt_post(user, CO_EV_COMM, 0, (uint32_t)event, 0, NULL);
}

/* The local node runs with a new node-id (LSS, or co_rt_node_id_at_reset at
 * a reset): a gateway port answers under the node-id, so its table is
 * rebuilt. Python learns it from the LSS or the reset event. */
static void on_node_id_changed(co_stack_t *stack, uint8_t node_id, void *user)
{
    (void)stack;
    (void)node_id;
    rt_line_t *l = user;
    if (l->network_id != 0) {
        (void)rt_gateway_rebuild(l->rt);
    }
}

/* What the line's services tell Python; each service's glue file posts its own. */
static const co_stack_indications_t line_indications = {
    .heartbeat = on_heartbeat,
    .emcy = rt_emcy_on_received,
    .time = rt_time_on_received,
    .guard = rt_guard_on_event,
    .comm = on_comm,
    .node_id_changed = on_node_id_changed,
};

rt_line_t *rt_checked_line(co_rt_t *rt, int line, bool host_only)
{
    int count = rt_atomic_load_acquire(&rt->line_count);
    if (line < 0 || line >= count) {
        rt_argument_error(rt, "line %d does not exist (%d open)", line, count);
        return NULL;
    }
    rt_line_t *l = rt->lines[line];
    if (host_only && l->driver != CO_DRIVER_HOST) {
        rt_argument_error(rt, "line %d (%s) is not a host-driver line", line, l->channel);
        return NULL;
    }
    return l;
}

static int check_line_config(co_rt_t *rt, const co_rt_line_config_t *c)
{
    if (!c) {
        rt_set_error(rt, "no line configuration given");
    } else if (c->driver < CO_DRIVER_SOCKETCAN || c->driver > CO_DRIVER_HOST) {
        rt_set_error(rt, "driver %d unknown (1 socketcan, 2 membus, 3 host)", c->driver);
    } else if (c->mode != CO_MODE_CLASSIC && c->mode != CO_MODE_FD) {
        rt_set_error(rt, "mode %d unknown (0 classic, 1 fd)", c->mode);
    } else if (!c->channel || c->channel[0] == '\0') {
        rt_set_error(rt, "a line needs a channel name");
    } else if (strlen(c->channel) >= RT_CHANNEL_SIZE) {
        rt_set_error(rt, "channel name longer than %d characters", RT_CHANNEL_SIZE - 1);
    } else if (c->rx_queue > RT_MAX_QUEUE || c->tx_queue > RT_MAX_QUEUE) {
        rt_set_error(rt, "%s: queue of %u frames above the limit of %d", c->channel,
                  (unsigned)(c->rx_queue > RT_MAX_QUEUE ? c->rx_queue : c->tx_queue),
                  RT_MAX_QUEUE);
    } else {
        return CO_RT_OK;
    }
    return CO_RT_ERR_ARGUMENT;
}

static bool line_init_core(rt_line_t *l, const co_rt_line_config_t *c, uint32_t tx)
{
    uint32_t rx = c->rx_queue ? c->rx_queue : RT_DEFAULT_QUEUE;
    l->rx_slots = calloc(rx, sizeof *l->rx_slots);
    l->tx_slots = calloc(tx, sizeof *l->tx_slots);
    if (!l->rx_slots || !l->tx_slots) {
        return false;
    }
    co_line_config_t lc = {.mode = (co_mode_t)c->mode, .brs = c->brs != 0,
                           .rx_slots = l->rx_slots, .rx_capacity = rx,
                           .tx_slots = l->tx_slots, .tx_capacity = tx};
    co_line_init(&l->line, &lc);
    /* Watched PDO frames are offered before any service takes them. */
    if (!rt_pdo_line_init(l)) {
        return false;
    }
    co_stack_line_config_t config = {
        .guarded_nodes = c->mode == CO_MODE_CLASSIC ? RT_GUARD_NODES : 0,
        .ind = &line_indications,
        .user = l};
    /* Every line watches boot-ups and heartbeats, local node or not. */
    return co_stack_init(&l->stack, &l->line, &config, rt_heap) == CO_STACK_OK &&
           rt_sync_line_init(l) && rt_rpdo_out_line_init(l);
}

void rt_line_free(rt_line_t *l)
{
    /* the services first: their deinit still sees the OD and the domains */
    rt_config_free(l);   /* before the client its configurations use */
    rt_cia402_free(l);   /* before the node whose OD, SYNC and EMCY it uses */
    rt_client_free(l);
    co_stack_deinit(&l->stack);
    rt_socket_close(l);
    rt_host_free(l);
    free(l->od_entries);
    free(l->od_pool);
    free(l->store_path);
    free(l->store_groups);
    free(l->store_file);
    rt_app_store_free(l);
    rt_od_free_domains(l);
    free(l->rx_slots);
    free(l->tx_slots);
    free(l);
}

static rt_line_t *line_new(co_rt_t *rt, const co_rt_line_config_t *c)
{
    rt_line_t *l = calloc(1, sizeof *l);
    if (!l) {
        return NULL;
    }
    uint32_t tx = c->tx_queue ? c->tx_queue : RT_DEFAULT_QUEUE;
    bool host_ok = rt_host_init(l, c->driver == CO_DRIVER_HOST ? tx : 0);
    rt_socket_init(l);
    l->rt = rt;
    l->index = -1;
    l->driver = c->driver;
    l->monitor = c->monitor != 0;
    l->allow_operational = true;
    snprintf(l->channel, sizeof l->channel, "%s", c->channel);
    if (!host_ok || !line_init_core(l, c, tx)) {
        rt_line_free(l);
        return NULL;
    }
    return l;
}

/* SocketCAN lines exist on Linux under the epoll loop only; elsewhere the
 * refusal names what to use instead. */
static int open_socketcan(co_rt_t *rt, rt_line_t *l)
{
#if CO_RT_HAVE_SOCKETCAN
    if (!rt->portable_loop) {
        return rt_socket_open(rt, l);
    }
    rt_set_error(rt, "%s: SocketCAN lines need the epoll loop, but %s=1 selects the portable "
                 "loop (mem: and python-can lines only); unset it to open SocketCAN interfaces",
                 l->channel, RT_PORTABLE_LOOP_ENV);
#else
    rt_set_error(rt, "%s: SocketCAN exists only on Linux; open an in-process bus ('mem:NAME') "
                 "or a python-can Bus instead", l->channel);
#endif
    return CO_RT_ERR_SOCKET;
}

/* Under rt->lock: hook the line into its driver and publish it. */
static int register_line(co_rt_t *rt, rt_line_t *l)
{
    if (rt->line_count == RT_MAX_LINES) {
        rt_set_error(rt, "%s: already %d lines in this runtime", l->channel, RT_MAX_LINES);
        return CO_RT_ERR_FULL;
    }
    int status = CO_RT_OK;
    if (l->driver == CO_DRIVER_MEMBUS) {
        status = rt_membus_join(rt, l);
    } else if (l->driver == CO_DRIVER_SOCKETCAN) {
        status = rt_socket_register(rt, l);
    }
    if (status != CO_RT_OK) {
        return status;
    }
    l->index = rt->line_count;
    rt->lines[l->index] = l;
    rt_atomic_store_release(&rt->line_count, l->index + 1);
    return CO_RT_OK;
}

int co_rt_add_line(co_rt_t *rt, const co_rt_line_config_t *config)
{
    if (!rt) {
        return CO_RT_ERR_ARGUMENT;
    }
    int status = check_line_config(rt, config);
    if (status != CO_RT_OK) {
        return status;
    }
    rt_line_t *l = line_new(rt, config);
    if (!l) {
        rt_set_error(rt, "%s: out of memory for the line's queues", config->channel);
        return CO_RT_ERR_NO_MEMORY;
    }
    rt_mutex_lock(&rt->life_lock);
    status = rt->closed ? CO_RT_ERR_CLOSED : CO_RT_OK;
    if (status == CO_RT_OK && l->driver == CO_DRIVER_SOCKETCAN) {
        status = open_socketcan(rt, l);
    }
    if (status == CO_RT_OK) {
        rt_mutex_lock(&rt->lock);
        status = register_line(rt, l);
        rt_mutex_unlock(&rt->lock);
    }
    rt_mutex_unlock(&rt->life_lock);
    if (status != CO_RT_OK) {
        rt_line_free(l);
        return status;
    }
    rt_wake(rt);
    return l->index;
}
