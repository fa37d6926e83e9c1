/* Runtime: commands. co_rt_command checks a command in the caller's thread
 * (so a wrong argument raises at once), creates the local node right away
 * (co_rt_node.c) and posts everything else to the mailbox; the thread
 * applies them at its next turn and posts CO_EV_COMMAND_FAILED for those
 * the line refuses. */
#include "co_rt_internal.h"

/* ================================================================ checking */

static const char *command_name(int kind)
{
    static const char *const names[] = {
        "?", "NODE_CREATE", "NMT_SEND", "NMT_LOCAL", "HEARTBEAT_TIME",
        "HB_WATCH", "HB_UNWATCH", "ALLOW_OPERATIONAL", "SEND_FRAME", "HB_TICK"};
    return kind > 0 && kind < (int)(sizeof names / sizeof names[0]) ? names[kind] : names[0];
}

static int check_node_id(co_rt_t *rt, uint32_t node_id, bool all_allowed)
{
    uint32_t lowest = all_allowed ? 0 : 1;
    if (node_id >= lowest && node_id <= 127) {
        return CO_RT_OK;
    }
    return rt_argument_error(rt, "node-id %u outside %u..127%s", (unsigned)node_id,
                          (unsigned)lowest, all_allowed ? " (0 = all nodes)" : "");
}

static int check_ms(co_rt_t *rt, const char *what, uint32_t ms)
{
    if (ms <= 65535u) {
        return CO_RT_OK;
    }
    return rt_argument_error(rt, "%s %u ms above 65535", what, (unsigned)ms);
}

static int check_nmt_command(co_rt_t *rt, uint32_t command)
{
    if (command <= 0xFFu && co_nmt_command_is_valid((uint8_t)command)) {
        return CO_RT_OK;
    }
    return rt_argument_error(rt, "NMT command 0x%02X unknown (0x01 start, 0x02 stop, "
                              "0x80 pre-operational, 0x81 reset node, 0x82 reset communication)",
                          (unsigned)command);
}

static int check_frame(co_rt_t *rt, const rt_line_t *l, const co_frame_t *f)
{
    if (!co_frame_is_valid(f)) {
        return rt_argument_error(rt, "malformed frame (id 0x%X, len %u, flags 0x%02X)",
                              (unsigned)f->id, f->len, f->flags);
    }
    if ((f->flags & CO_FRAME_FD) && co_line_mode(&l->line) == CO_MODE_CLASSIC) {
        return rt_argument_error(rt, "line %d is classic: it cannot send FD frames", l->index);
    }
    return CO_RT_OK;
}

static int first_error(int a, int b) { return a != CO_RT_OK ? a : b; }

static int check_command_args(co_rt_t *rt, const rt_line_t *l, const co_rt_command_t *cmd)
{
    switch (cmd->kind) {
    case CO_CMD_NODE_CREATE:
        /* 255: an unconfigured node, which only LSS can give a node-id */
        return first_error(cmd->args.node_create.node_id == CO_LSS_NODE_ID_UNCONFIGURED
                               ? CO_RT_OK
                               : check_node_id(rt, cmd->args.node_create.node_id, false),
                           check_ms(rt, "heartbeat time", cmd->args.node_create.heartbeat_ms));
    case CO_CMD_NMT_SEND:
        return first_error(check_nmt_command(rt, cmd->args.nmt_send.command),
                           check_node_id(rt, cmd->args.nmt_send.node_id, true));
    case CO_CMD_NMT_LOCAL:
        return check_nmt_command(rt, cmd->args.nmt_local.command);
    case CO_CMD_HEARTBEAT_TIME:
        return check_ms(rt, "heartbeat time", cmd->args.heartbeat_time.time_ms);
    case CO_CMD_HB_WATCH:
        return first_error(check_node_id(rt, cmd->args.hb_watch.node_id, false),
                           check_ms(rt, "heartbeat consumer time", cmd->args.hb_watch.time_ms));
    case CO_CMD_HB_UNWATCH:
        return check_node_id(rt, cmd->args.hb_unwatch.node_id, false);
    case CO_CMD_ALLOW_OPERATIONAL:
        return cmd->args.allow_operational.allow <= 1
                   ? CO_RT_OK
                   : rt_argument_error(rt, "allow-operational flag %u is not 0 or 1",
                                       (unsigned)cmd->args.allow_operational.allow);
    case CO_CMD_SEND_FRAME:
        return check_frame(rt, l, &cmd->args.send_frame);
    case CO_CMD_HB_TICK:
        return first_error(check_node_id(rt, cmd->args.hb_tick.node_id, false),
                           check_ms(rt, "heartbeat tick interval",
                                    cmd->args.hb_tick.interval_ms));
    default:
        return rt_argument_error(rt, "command kind %d unknown", cmd->kind);
    }
}

static int validate_command(co_rt_t *rt, const co_rt_command_t *cmd)
{
    int count = rt_atomic_load_acquire(&rt->line_count);
    if (cmd->line < 0 || cmd->line >= count) {
        return rt_argument_error(rt, "line %d does not exist (%d open)", cmd->line, count);
    }
    return check_command_args(rt, rt->lines[cmd->line], cmd);
}

static int apply_to_line(co_rt_t *rt, rt_line_t *l, const co_rt_command_t *cmd);

/* A command applied in the caller's thread, under the runtime lock, before
 * co_rt_command returns: the local node exists, or its own NMT state is
 * what the caller set (a PDO it sends next sees it), and a refusal is the
 * return value, not a later CO_EV_COMMAND_FAILED. */
static int apply_now(co_rt_t *rt, const co_rt_command_t *cmd)
{
    rt_line_t *l = rt->lines[cmd->line];
    rt_mutex_lock(&rt->lock);
    int status = CO_RT_ERR_CLOSED;
    if (!rt->stopping) {
        rt_line_step(l, co_rt_now_us());
        status = apply_to_line(rt, l, cmd);
    }
    rt_mutex_unlock(&rt->lock);
    rt_wake(rt);   /* frames it queued (a boot-up after a reset) go out */
    return status;
}

int co_rt_command(co_rt_t *rt, const co_rt_command_t *command)
{
    if (!rt || !command) {
        return CO_RT_ERR_ARGUMENT;
    }
    int status = validate_command(rt, command);
    if (status != CO_RT_OK) {
        return status;
    }
    if (command->kind == CO_CMD_NODE_CREATE || command->kind == CO_CMD_NMT_LOCAL) {
        return apply_now(rt, command);
    }
    rt_line_t *l = rt->lines[command->line];
    bool send = command->kind == CO_CMD_SEND_FRAME;
    if (send && !rt_host_reserve_send(l)) {
        /* Refused here, where the caller hears it, rather than lost as a tx
         * overflow once the mailbox reaches the line's full tx queue. */
        rt_set_error(rt, "line %d: its python-can bus takes frames slower than they are sent "
                     "(host tx queue full); send again later", command->line);
        return CO_RT_ERR_FULL;
    }
    status = rt_mailbox_post(&rt->mail, command);
    if (send && status != CO_RT_OK) {
        rt_host_send_unreserve(l);
    }
    if (status == CO_RT_ERR_FULL) {
        rt_set_error(rt, "command mailbox full (%d commands pending)", RT_MAILBOX_SIZE);
    }
    if (status == CO_RT_OK) {
        rt_wake(rt);
    }
    return status;
}

/* ================================================================ applying */

static int need_node(co_rt_t *rt, const rt_line_t *l, int kind)
{
    if (rt_has_node(l)) {
        return CO_RT_OK;
    }
    rt_set_error(rt, "line %d has no local node (%s needs one)", l->index, command_name(kind));
    return CO_RT_ERR_STATE;
}

static int cmd_queued(co_rt_t *rt, const rt_line_t *l, bool queued)
{
    if (queued) {
        return CO_RT_OK;
    }
    rt_set_error(rt, "line %d: tx queue full, frame not sent", l->index);
    return CO_RT_ERR_FULL;
}

static int cmd_hb_watch(co_rt_t *rt, rt_line_t *l, const co_rt_command_t *cmd)
{
    uint32_t node_id = cmd->args.hb_watch.node_id;
    co_hb_config_result_t r = co_hb_consumer_watch(co_stack_hb_consumer(&l->stack),
                                                   (uint8_t)node_id,
                                                   (uint16_t)cmd->args.hb_watch.time_ms);
    if (r == CO_HB_CONFIG_OK) {
        return CO_RT_OK;
    }
    rt_set_error(rt, "line %d: cannot watch node %u (heartbeat config result %d)", l->index,
              (unsigned)node_id, (int)r);
    return r == CO_HB_CONFIG_NO_ROOM ? CO_RT_ERR_FULL : CO_RT_ERR_ARGUMENT;
}

static int cmd_hb_tick(co_rt_t *rt, rt_line_t *l, const co_rt_command_t *cmd)
{
    co_hb_consumer_t *consumer = co_stack_hb_consumer(&l->stack);
    uint8_t node_id = (uint8_t)cmd->args.hb_tick.node_id;
    if (!cmd->args.hb_tick.on) {
        co_hb_consumer_untick(consumer, node_id);
        return CO_RT_OK;
    }
    if (co_hb_consumer_tick(consumer, node_id, (uint16_t)cmd->args.hb_tick.interval_ms) ==
        CO_HB_CONFIG_OK) {
        return CO_RT_OK;
    }
    rt_set_error(rt, "line %d: cannot tell node %u's heartbeats: %d nodes do already",
                 l->index, (unsigned)node_id, CO_HB_TICKS);
    return CO_RT_ERR_FULL;
}

/* Consumer entries that mirror 0x1016 sub 1.. of the local node's OD. */
static uint8_t od_consumer_entries(const rt_line_t *l)
{
    uint8_t count = 0;
    if (rt_has_node(l) && l->has_od) {
        co_od_get_u8(&l->od, 0x1016, 0, &count);
    }
    return count;
}

/* Python stops watching: entries that mirror 0x1016 belong to the OD and
 * keep monitoring (the line just stops telling Python). */
static void hb_unwatch(rt_line_t *l, uint8_t node_id)
{
    for (uint8_t i = od_consumer_entries(l); i < co_stack_hb_consumer(&l->stack)->capacity; i++) {
        if (co_stack_hb_consumer(&l->stack)->entries[i].node_id == node_id) {
            co_hb_consumer_set_entry(co_stack_hb_consumer(&l->stack), i, 0);
        }
    }
}

static int apply_to_line(co_rt_t *rt, rt_line_t *l, const co_rt_command_t *cmd)
{
    co_nmt_t *local = rt_has_node(l) ? &co_stack_node(&l->stack)->nmt : NULL;
    switch (cmd->kind) {
    case CO_CMD_NODE_CREATE:
        return rt_node_create(rt, l, cmd);
    case CO_CMD_NMT_SEND:
        return cmd_queued(rt, l, co_nmt_master_send(&l->line, local,
                                                    (co_nmt_command_t)cmd->args.nmt_send.command,
                                                    (uint8_t)cmd->args.nmt_send.node_id,
                                                    cmd->args.nmt_send.include_self != 0));
    case CO_CMD_NMT_LOCAL:
        if (local) {
            co_nmt_apply(local, (co_nmt_command_t)cmd->args.nmt_local.command);
        }
        return need_node(rt, l, cmd->kind);
    case CO_CMD_HEARTBEAT_TIME:
        if (local) {
            co_node_set_heartbeat(co_stack_node(&l->stack),
                                  (uint16_t)cmd->args.heartbeat_time.time_ms);
        }
        return need_node(rt, l, cmd->kind);
    case CO_CMD_HB_WATCH:
        return cmd_hb_watch(rt, l, cmd);
    case CO_CMD_HB_UNWATCH:
        hb_unwatch(l, (uint8_t)cmd->args.hb_unwatch.node_id);
        return CO_RT_OK;
    case CO_CMD_HB_TICK:
        return cmd_hb_tick(rt, l, cmd);
    case CO_CMD_ALLOW_OPERATIONAL:
        l->allow_operational = cmd->args.allow_operational.allow != 0;
        return CO_RT_OK;
    case CO_CMD_SEND_FRAME:
    {
        bool queued = co_line_send_raw(&l->line, &cmd->args.send_frame);
        rt_host_send_applied(l, queued);
        return cmd_queued(rt, l, queued);
    }
    default:
        return CO_RT_ERR_ARGUMENT;   /* validated in co_rt_command */
    }
}

void rt_command_apply(co_rt_t *rt, const co_rt_command_t *cmd, uint64_t now)
{
    rt_line_t *l = rt->lines[cmd->line];
    /* The core reads the line's clock when arming timers: bring it to now. */
    rt_line_step(l, now);
    int status = apply_to_line(rt, l, cmd);
    if (status != CO_RT_OK) {
        rt_post(l, CO_EV_COMMAND_FAILED, 0, (uint32_t)cmd->kind, (uint32_t)-status, NULL);
    }
}
