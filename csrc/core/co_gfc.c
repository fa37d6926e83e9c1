/* GFC producer and consumer (see co_gfc.h). */
#include "canopenfd/co_gfc.h"

#include <string.h>

static void on_frame(co_line_t *line, const co_frame_t *frame, void *user)
{
    (void)line;
    co_gfc_t *g = user;
    if (frame->len != 0) {
        g->stats.bad_length++;
        return;
    }
    g->stats.received++;
    if (g->on_gfc) {
        g->on_gfc(g, g->user);
    }
}

void co_gfc_init(co_gfc_t *gfc, co_line_t *line, co_gfc_fn on_gfc, void *user)
{
    memset(gfc, 0, sizeof *gfc);
    gfc->line = line;
    gfc->on_gfc = on_gfc;
    gfc->user = user;
}

void co_gfc_deinit(co_gfc_t *gfc)
{
    (void)co_gfc_set_enabled(gfc, false);
}

bool co_gfc_set_enabled(co_gfc_t *gfc, bool enabled)
{
    if (!enabled && gfc->subscribed) {
        co_line_unsubscribe(gfc->line, on_frame, gfc);
        gfc->subscribed = false;
    }
    if (enabled && !gfc->subscribed) {
        if (!co_line_subscribe(gfc->line, CO_GFC_COB_ID, CO_GFC_COB_ID, on_frame, gfc)) {
            return false;
        }
        gfc->subscribed = true;
    }
    gfc->enabled = enabled;
    return true;
}

bool co_gfc_send(co_gfc_t *gfc)
{
    if (!gfc->enabled || !co_line_send(gfc->line, CO_GFC_COB_ID, NULL, 0)) {
        gfc->stats.send_refused++;
        return false;
    }
    gfc->stats.sent++;
    return true;
}
