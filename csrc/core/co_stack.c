/* co_stack: sizing, set-up and wiring of a line's services and its local
 * node over caller memory (see co_stack.h). */
#include "canopenfd/co_stack.h"
#include "co_stack_blocks.h"
#include "co_stack_rdn.h"

#include "canopenfd/co_assert.h"

#include <string.h>

enum { OWNER_LINE = 0, OWNER_NODE = 1, OWNER_CLIENT = 2, OWNER_MANAGER = 3, OWNER_SRDO = 4 };

/* ---------------------------------------------------------------- arena */

static void *arena_allocate(void *user, size_t size)
{
    co_stack_arena_t *a = user;
    size_t block = CO_STACK_BLOCK(size);
    if (block < size || block > a->size - a->used) {
        return NULL;
    }
    void *memory = a->base + a->used;
    a->used += block;
    if (a->used > a->peak) {
        a->peak = a->used;
    }
    return memory;
}

static void arena_release(void *user, void *memory, size_t size)
{
    co_stack_arena_t *a = user;
    size_t block = CO_STACK_BLOCK(size);
    if ((unsigned char *)memory + block == a->base + a->used) {
        a->used -= block;   /* only the last block comes back */
    }
}

void co_stack_arena_init(co_stack_arena_t *arena, void *memory, size_t size)
{
    /* the first block starts aligned: skip to the boundary */
    size_t skip = (size_t)(-(uintptr_t)memory) & (CO_STACK_ALIGN - 1u);
    arena->base = (unsigned char *)memory + (skip < size ? skip : size);
    arena->size = skip < size ? size - skip : 0;
    arena->used = 0;
    arena->peak = 0;
}

co_stack_allocator_t co_stack_arena_allocator(co_stack_arena_t *arena)
{
    co_stack_allocator_t a = {.allocate = arena_allocate, .release = arena_release,
                              .user = arena};
    return a;
}

/* ---------------------------------------------------------------- blocks */

/* A block for `owner`, zeroed; NULL when the allocator or the table is out. */
static void *take(co_stack_t *s, uint8_t owner, size_t size)
{
    if (s->block_count >= CO_STACK_MAX_BLOCKS) {
        return NULL;
    }
    size_t bytes = size ? size : 1u;
    void *memory = s->alloc.allocate(s->alloc.user, bytes);
    if (!memory) {
        return NULL;
    }
    memset(memory, 0, bytes);
    s->blocks[s->block_count++] = (co_stack_block_t){.memory = memory, .size = bytes,
                                                     .owner = owner};
    return memory;
}

/* Give back every block of `owner`, the newest first. */
static void give_back(co_stack_t *s, uint8_t owner)
{
    uint8_t kept = 0;
    for (uint8_t i = s->block_count; i-- > 0;) {
        co_stack_block_t b = s->blocks[i];
        if (b.owner == owner && s->alloc.release) {
            s->alloc.release(s->alloc.user, b.memory, b.size);
        }
    }
    for (uint8_t i = 0; i < s->block_count; i++) {
        if (s->blocks[i].owner != owner) {
            s->blocks[kept++] = s->blocks[i];
        }
    }
    s->block_count = kept;
}

static co_stack_status_t fail(co_stack_t *s, co_stack_part_t part, co_stack_status_t status)
{
    s->failed = part;
    return status;
}

void *co_stack_take(co_stack_t *s, uint8_t owner, size_t size)
{
    return take(s, owner, size);
}

void co_stack_give_back(co_stack_t *s, uint8_t owner)
{
    give_back(s, owner);
}

co_stack_status_t co_stack_fail(co_stack_t *s, co_stack_part_t part, co_stack_status_t status)
{
    return fail(s, part, status);
}

/* ---------------------------------------------------------------- sizing */

/* What one part-group asks of the allocator, in the order it asks. */
enum { PLAN_MAX = 12 };   /* blocks one part-group asks for at most (node: 10) */

typedef struct plan {
    size_t sizes[PLAN_MAX];
    uint8_t count;
} plan_t;

static void plan_add(plan_t *p, size_t size)
{
    CO_ASSERT(p->count < PLAN_MAX);
    p->sizes[p->count++] = size ? size : 1u;
}

static size_t plan_total(const plan_t *p)
{
    size_t total = 0;
    for (uint8_t i = 0; i < p->count; i++) {
        total += CO_STACK_BLOCK(p->sizes[i]);
    }
    return total;
}

static uint8_t hb_entries_of(const co_stack_line_config_t *c)
{
    return (c && c->heartbeat_entries) ? c->heartbeat_entries
                                       : (uint8_t)CO_STACK_DEFAULT_HB_ENTRIES;
}

/* Whether this build runs lines of that kind (co_stack.h: CO_CONFIG_*); the
 * constant conditions let a one-kind build drop the other kind's services. */
static bool mode_built(co_mode_t mode)
{
    return mode == CO_MODE_FD ? CO_CONFIG_FD != 0 : CO_CONFIG_CLASSIC != 0;
}

static bool is_fd(const co_line_t *line)
{
    return CO_CONFIG_FD && (!CO_CONFIG_CLASSIC || co_line_mode(line) == CO_MODE_FD);
}

static uint8_t guarded_of(const co_line_t *line, const co_stack_line_config_t *c)
{
    return (c && !is_fd(line)) ? c->guarded_nodes : 0;
}

static void line_plan(const co_line_t *line, const co_stack_line_config_t *c, plan_t *p)
{
    p->count = 0;
    plan_add(p, sizeof(co_hb_entry_t) * hb_entries_of(c));
    if (guarded_of(line, c)) {
        plan_add(p, sizeof(co_guard_node_t) * guarded_of(line, c));
    }
}

size_t co_stack_line_need(const co_line_t *line, const co_stack_line_config_t *config)
{
    plan_t p;
    line_plan(line, config, &p);
    return plan_total(&p);
}

/* The node's sizes, resolved from its configuration and OD. */
typedef struct node_sizes {
    uint16_t emcy_queue;
    uint16_t emcy_active;
    uint8_t emcy_history;
    uint32_t pdo_channels;
    uint32_t pdo_items;
    uint32_t store_capacity;     /* per image; 0 = no store */
    uint32_t servers;            /* USDO sessions or SDO channels */
    uint32_t server_scratch;     /* per session / channel */
} node_sizes_t;

/* SDO channels a classic node serves: the default one plus 0x1201..0x127F. */
static uint32_t sdo_channel_count(const co_od_t *od)
{
    uint32_t count = 1;
    for (uint32_t index = CO_SDO_SERVER_PARAM + 1; index <= CO_SDO_SERVER_PARAM_LAST; index++) {
        count += co_od_has_index(od, (uint16_t)index) ? 1u : 0u;
    }
    return count;
}

static bool node_sizes(const co_line_t *line, const co_stack_node_config_t *c, node_sizes_t *n)
{
    memset(n, 0, sizeof *n);
    n->emcy_queue = c->emcy_queue ? c->emcy_queue : (uint16_t)CO_STACK_DEFAULT_EMCY_QUEUE;
    n->emcy_active = c->emcy_active ? c->emcy_active : (uint16_t)CO_STACK_DEFAULT_EMCY_ACTIVE;
    n->emcy_history = c->emcy_history ? c->emcy_history
                                      : (uint8_t)CO_STACK_DEFAULT_EMCY_HISTORY;
    if (is_fd(line)) {
        n->servers = c->server_sessions ? c->server_sessions
                                        : (uint32_t)CO_STACK_DEFAULT_SERVER_SESSIONS;
    }
    if (!c->od) {
        /* the server of an empty OD: one SDO channel, no USDO scratch */
        n->servers = is_fd(line) ? n->servers : 1u;
        n->server_scratch = is_fd(line) ? 0u : (uint32_t)CO_SDO_SERVER_BUFFER;
        return true;
    }
    if (!co_pdo_need(c->od, &n->pdo_channels, &n->pdo_items)) {
        return false;
    }
    if (c->store_backend) {
        n->store_capacity = c->store_image_capacity ? c->store_image_capacity
                                                    : co_store_image_need(c->od);
    }
    if (is_fd(line)) {
        n->server_scratch = co_usdo_server_scratch_need(c->od);
    } else {
        n->servers = sdo_channel_count(c->od);
        n->server_scratch = co_sdo_server_scratch_need(c->od);
    }
    return true;
}

static size_t server_entry_size(const co_line_t *line)
{
    return is_fd(line) ? sizeof(co_usdo_session_t) : sizeof(co_sdo_channel_t);
}

static void node_plan(const co_line_t *line, const node_sizes_t *n, bool has_od, plan_t *p)
{
    p->count = 0;
    plan_add(p, sizeof(co_emcy_msg_t) * n->emcy_queue);
    plan_add(p, sizeof(co_emcy_active_t) * n->emcy_active);
    plan_add(p, sizeof(uint32_t) * n->emcy_history);
    plan_add(p, server_entry_size(line) * n->servers);
    plan_add(p, (size_t)n->server_scratch * n->servers + 1u);
    if (!has_od) {
        return;
    }
    if (n->store_capacity) {
        plan_add(p, 2u * (size_t)n->store_capacity);
    }
    plan_add(p, sizeof(co_pdo_channel_t) * n->pdo_channels);
    plan_add(p, sizeof(co_pdo_map_item_t) * n->pdo_items);
    if (n->pdo_channels > CO_PDO_SCAN_MAX) {
        plan_add(p, 2u * CO_LINE_ID_MAP_SIZE * sizeof(uint16_t));   /* rx and rtr tables */
    }
}

size_t co_stack_node_need(const co_line_t *line, const co_stack_node_config_t *config)
{
    node_sizes_t n;
    plan_t p;
    if (!line || !config || !node_sizes(line, config, &n)) {
        return 0;
    }
    node_plan(line, &n, config->od != NULL, &p);
    return plan_total(&p);
}

static size_t client_entry_size(const co_line_t *line)
{
    return is_fd(line) ? sizeof(co_usdo_client_session_t) : sizeof(co_sdo_client_channel_t);
}

size_t co_stack_client_need(const co_line_t *line, const co_stack_client_config_t *config)
{
    return (line && config) ? CO_STACK_BLOCK(client_entry_size(line) * config->sessions) : 0;
}

/* ---------------------------------------------------------------- wiring */

static void on_heartbeat(co_hb_consumer_t *c, uint8_t node_id, co_hb_event_t event,
                         co_nmt_state_t state, void *user)
{
    (void)c;
    co_stack_t *s = user;
    if (s->ind && s->ind->heartbeat) {
        s->ind->heartbeat(s, node_id, event, state, s->user);
    }
    if (s->has_node && (event == CO_HB_LOST || event == CO_HB_STARTED)) {
        co_node_heartbeat_event(&s->node, node_id, event == CO_HB_LOST);
    }
    if (s->has_manager && event == CO_HB_LOST) {
        co_manager_ec_lost(&s->manager, node_id);
    }
    if (s->has_flyma && event == CO_HB_LOST) {
        co_flyma_node_lost(&s->flyma, node_id);
    }
    co_stack_rdn_heartbeat(s, node_id, event);
}

static void on_comm(co_line_t *line, co_comm_event_t event, void *user)
{
    (void)line;
    co_stack_t *s = user;
    if (s->ind && s->ind->comm) {
        s->ind->comm(s, event, s->user);
    }
    if (s->has_node) {
        co_node_comm_event(&s->node, event);   /* EMCY, error behaviour */
    }
    co_stack_rdn_comm(s, event);
}

static void on_emcy(co_emcy_consumer_t *c, uint8_t node_id, const co_emcy_msg_t *msg,
                    void *user)
{
    (void)c;
    co_stack_t *s = user;
    if (s->ind && s->ind->emcy) {
        s->ind->emcy(s, node_id, msg, s->user);
    }
}

static void on_time(co_time_t *t, const co_time_of_day_t *tod, void *user)
{
    (void)t;
    co_stack_t *s = user;
    if (s->ind && s->ind->time) {
        s->ind->time(s, tod, s->user);
    }
}

static void on_guard(co_guard_master_t *m, uint8_t node_id, co_guard_event_t event,
                     co_nmt_state_t state, void *user)
{
    (void)m;
    co_stack_t *s = user;
    if (s->ind && s->ind->guard) {
        s->ind->guard(s, node_id, event, state, s->user);
    }
    if (s->has_node && (event == CO_GUARD_LOST || event == CO_GUARD_RESUMED)) {
        /* a guarded node is a monitored node: its loss is a communication error */
        co_node_heartbeat_event(&s->node, node_id, event == CO_GUARD_LOST);
    }
    if (s->has_manager && event == CO_GUARD_LOST) {
        co_manager_ec_lost(&s->manager, node_id);
    }
    if (s->has_flyma && event == CO_GUARD_LOST) {
        co_flyma_node_lost(&s->flyma, node_id);
    }
}

/* ---------------------------------------------------------------- the line */

static void line_undo(co_stack_t *s)
{
    if (s->has_lss_master) {
        co_lss_master_deinit(&s->lss_master);
        s->has_lss_master = false;
    }
    if (CO_CONFIG_CLASSIC && s->has_guard_master) {
        co_hb_consumer_set_filter(&s->hb_consumer, NULL, NULL);
        co_guard_master_deinit(&s->guard_master);
        s->has_guard_master = false;
    }
    co_emcy_consumer_deinit(&s->emcy_consumer);
    co_time_deinit(&s->time);
    co_sync_deinit(&s->sync);
    co_line_set_comm_indication(s->line, NULL, NULL);
    co_hb_consumer_deinit(&s->hb_consumer);
    give_back(s, OWNER_LINE);
}

co_stack_status_t co_stack_init(co_stack_t *stack, co_line_t *line,
                                const co_stack_line_config_t *config,
                                co_stack_allocator_t allocator)
{
    if (!stack || !line || !allocator.allocate || !mode_built(co_line_mode(line))) {
        return CO_STACK_ERR_ARGUMENT;
    }
    memset(stack, 0, sizeof *stack);
    co_stack_t *s = stack;
    s->line = line;
    s->alloc = allocator;
    s->ind = config ? config->ind : NULL;
    s->user = config ? config->user : NULL;
    uint8_t entries = hb_entries_of(config);
    co_hb_entry_t *hb_entries = take(s, OWNER_LINE, sizeof *hb_entries * entries);
    if (!hb_entries) {
        return fail(s, CO_STACK_PART_HEARTBEAT, CO_STACK_ERR_NO_MEMORY);
    }
    if (!co_hb_consumer_init(&s->hb_consumer, line, hb_entries, entries, on_heartbeat, s)) {
        give_back(s, OWNER_LINE);
        return fail(s, CO_STACK_PART_HEARTBEAT, CO_STACK_ERR_TAKEN);
    }
    co_line_set_comm_indication(line, on_comm, s);
    co_stack_part_t part = CO_STACK_PART_SYNC;
    co_stack_status_t status = CO_STACK_ERR_TAKEN;
    if (co_sync_init(&s->sync, line)) {
        /* Without a local node the line is a tool's: it hears SYNC, TIME and
         * EMCYs as a pre-operational node would, SYNC with or without counter. */
        co_sync_set_nmt_state(&s->sync, CO_NMT_PRE_OPERATIONAL);
        co_sync_accept_any_counter(&s->sync, true);
        co_time_init(&s->time, line, on_time, s);
        (void)co_time_set_cob_id(&s->time, CO_TIME_CONSUMER_BIT | CO_TIME_DEFAULT_COB_ID);
        co_time_set_nmt_state(&s->time, CO_NMT_PRE_OPERATIONAL);
        part = CO_STACK_PART_EMCY_CONSUMER;
        if (co_emcy_consumer_init(&s->emcy_consumer, line, on_emcy, s)) {
            uint8_t guarded = guarded_of(line, config);
            part = CO_STACK_PART_GUARD_MASTER;
            co_guard_node_t *nodes = guarded ? take(s, OWNER_LINE, sizeof *nodes * guarded)
                                             : NULL;
            if (guarded && !nodes) {
                status = CO_STACK_ERR_NO_MEMORY;
            } else if (!guarded || (CO_CONFIG_CLASSIC && co_guard_master_init(&s->guard_master, line, nodes, guarded,
                                                        on_guard, s))) {
                if (guarded) {
                    /* the master takes its nodes' answers before the consumer */
                    co_hb_consumer_set_filter(&s->hb_consumer, co_guard_master_receive,
                                              &s->guard_master);
                    s->has_guard_master = true;
                }
                return CO_STACK_OK;
            }
        }
    }
    line_undo(s);
    return fail(s, part, status);
}

/* ---------------------------------------------------------------- the node */

static bool od_has(const co_stack_t *s, uint16_t index)
{
    return s->od && co_od_has_index(s->od, index);
}

/* Undo co_stack_node_init, part by part (each flag says what is running). */
static void node_undo(co_stack_t *s)
{
    co_stack_manager_deinit(s);   /* it runs over the node */
    co_stack_srdo_deinit(s);   /* they run for the node */
    co_stack_cia401_deinit(s);   /* it runs over the node's OD */
    co_stack_flyma_deinit(s);   /* it runs for the node */
    co_stack_rdn_node_gone(s);   /* it runs for the line, served by the node's OD */
    if (CO_CONFIG_CLASSIC && s->has_sdo_client && s->sdo_client.od) {
        co_stack_client_deinit(s);   /* bound to the node's OD */
    }
    if (CO_CONFIG_CLASSIC && s->has_guard_slave) {
        co_guard_slave_deinit(&s->guard_slave);
        s->has_guard_slave = false;
    }
    if (s->has_mpdo) {
        co_mpdo_deinit(&s->mpdo);
        s->has_mpdo = false;
    }
    if (s->has_pdo) {
        co_pdo_deinit(&s->pdo);
        s->has_pdo = false;
    }
    if (s->has_errors) {
        co_errors_detach_od(&s->errors);
        s->has_errors = false;
    }
    if (s->has_emcy) {
        co_emcy_deinit(&s->emcy);
        s->has_emcy = false;
    }
    co_sync_detach_od(&s->sync);
    co_sync_accept_any_counter(&s->sync, true);
    co_sync_set_nmt_state(&s->sync, CO_NMT_PRE_OPERATIONAL);
    co_time_detach_od(&s->time);
    co_time_set_nmt_state(&s->time, CO_NMT_PRE_OPERATIONAL);
    co_emcy_consumer_detach_od(&s->emcy_consumer);
    if (CO_CONFIG_FD && s->has_usdo_server) {
        co_usdo_server_deinit(&s->usdo_server);
        s->has_usdo_server = false;
    }
    if (CO_CONFIG_CLASSIC && s->has_sdo_server) {
        co_sdo_server_deinit(&s->sdo_server);
        s->has_sdo_server = false;
    }
    if (s->has_store) {
        co_store_deinit(&s->store);
        s->has_store = false;
    }
    if (s->has_node) {
        co_node_deinit(&s->node);
        s->has_node = false;
    }
    if (s->has_led) {
        co_led_deinit(&s->led);
        s->has_led = false;
    }
    s->od = NULL;
    give_back(s, OWNER_NODE);
}

/* The node's OD, or for a node without one an empty OD: a request gets
 * "object does not exist" (0x06020000 / 0x33) at once instead of no answer,
 * which would keep the client waiting for its timeout. */
static co_od_t *served_od(co_stack_t *s)
{
    if (s->od) {
        return s->od;
    }
    co_od_init(&s->no_od, co_line_mode(s->line), NULL, 0, NULL, 0, NULL, 0);
    (void)co_od_seal(&s->no_od, s->node.nmt.node_id);
    return &s->no_od;
}

static co_stack_status_t serve_od(co_stack_t *s, const node_sizes_t *n)
{
    co_od_t *od = served_od(s);
    void *table = take(s, OWNER_NODE, server_entry_size(s->line) * n->servers);
    uint8_t *scratch = take(s, OWNER_NODE, (size_t)n->server_scratch * n->servers + 1u);
    if (!table || !scratch) {
        return fail(s, CO_STACK_PART_SERVER, CO_STACK_ERR_NO_MEMORY);
    }
    if (is_fd(s->line)) {
        co_usdo_server_config_t config = {.sessions = table,
                                          .session_count = (uint8_t)n->servers,
                                          .scratch = scratch,
                                          .scratch_size = n->server_scratch};
        s->has_usdo_server = co_usdo_server_init(&s->usdo_server, s->line, od, &config);
    } else if (CO_CONFIG_CLASSIC) {
        co_sdo_server_config_t config = {.channels = table,
                                         .channel_count = (uint8_t)n->servers,
                                         .scratch = scratch,
                                         .scratch_size = n->server_scratch};
        s->has_sdo_server = co_sdo_server_init(&s->sdo_server, s->line, od, &config);
        if (s->has_sdo_server) {
            co_sdo_server_refresh(&s->sdo_server);   /* the node-id is set by now */
        }
    }
    return (s->has_usdo_server || s->has_sdo_server)
               ? CO_STACK_OK : fail(s, CO_STACK_PART_SERVER, CO_STACK_ERR_TAKEN);
}

static co_stack_status_t start_emcy(co_stack_t *s, const node_sizes_t *n)
{
    co_emcy_config_t config = {
        .queue = take(s, OWNER_NODE, sizeof(co_emcy_msg_t) * n->emcy_queue),
        .queue_capacity = n->emcy_queue,
        .active = take(s, OWNER_NODE, sizeof(co_emcy_active_t) * n->emcy_active),
        .active_capacity = n->emcy_active,
        .history = take(s, OWNER_NODE, sizeof(uint32_t) * n->emcy_history),
        .history_capacity = n->emcy_history};
    if (!config.queue || !config.active || !config.history) {
        return fail(s, CO_STACK_PART_EMCY, CO_STACK_ERR_NO_MEMORY);
    }
    s->has_emcy = co_emcy_init(&s->emcy, s->line, s->node.nmt.node_id, &config);
    if (!s->has_emcy) {
        return fail(s, CO_STACK_PART_EMCY, CO_STACK_ERR_ARGUMENT);
    }
    if (s->od && !co_emcy_attach_od(&s->emcy, s->od)) {
        return fail(s, CO_STACK_PART_EMCY, CO_STACK_ERR_TAKEN);
    }
    /* the error-status bits sit in front of the producer (their 0x1001 part);
     * the application shows them in its OD when it asks (co_errors_attach_od) */
    co_errors_init(&s->errors, &s->emcy);
    s->has_errors = true;
    return CO_STACK_OK;
}

static co_stack_status_t start_pdo(co_stack_t *s, const node_sizes_t *n)
{
    co_pdo_config_t config = {
        .channels = take(s, OWNER_NODE, sizeof(co_pdo_channel_t) * n->pdo_channels),
        .channel_count = n->pdo_channels,
        .items = take(s, OWNER_NODE, sizeof(co_pdo_map_item_t) * n->pdo_items),
        .item_count = n->pdo_items,
        .ind = &co_node_pdo_indications,
        .user = &s->node};
    if (n->pdo_channels > CO_PDO_SCAN_MAX) {
        /* many PDOs: a received frame finds its RPDO by table, not by a scan */
        config.rx_map = take(s, OWNER_NODE, 2u * CO_LINE_ID_MAP_SIZE * sizeof(uint16_t));
        config.rtr_map = config.rx_map ? config.rx_map + CO_LINE_ID_MAP_SIZE : NULL;
    }
    if (!config.channels || !config.items ||
        (n->pdo_channels > CO_PDO_SCAN_MAX && !config.rx_map)) {
        return fail(s, CO_STACK_PART_PDO, CO_STACK_ERR_NO_MEMORY);
    }
    s->has_pdo = co_pdo_init(&s->pdo, s->line, s->od, &config);
    if (!s->has_pdo) {
        return fail(s, CO_STACK_PART_PDO, CO_STACK_ERR_TAKEN);
    }
    co_mpdo_init(&s->mpdo, &s->pdo, &co_node_mpdo_indications, &s->node);
    s->has_mpdo = true;
    return CO_STACK_OK;
}

/* The OD now says what SYNC, TIME and the EMCY consumer of the line do. */
static co_stack_status_t bind_line_services(co_stack_t *s)
{
    co_sync_accept_any_counter(&s->sync, false);   /* the node's 0x1019 rules */
    if (od_has(s, 0x1005) && !co_sync_attach_od(&s->sync, s->od)) {
        return fail(s, CO_STACK_PART_SYNC, CO_STACK_ERR_TAKEN);
    }
    if (od_has(s, 0x1012) && !co_time_attach_od(&s->time, s->od)) {
        return fail(s, CO_STACK_PART_TIME, CO_STACK_ERR_TAKEN);
    }
    if (od_has(s, 0x1028) && !co_emcy_consumer_attach_od(&s->emcy_consumer, s->od)) {
        return fail(s, CO_STACK_PART_EMCY_CONSUMER, CO_STACK_ERR_TAKEN);
    }
    return CO_STACK_OK;
}

static co_stack_status_t start_od_parts(co_stack_t *s, const co_stack_node_config_t *c,
                                        const node_sizes_t *n)
{
    if (n->store_capacity) {
        uint32_t size = 2u * n->store_capacity;
        uint8_t *buffer = take(s, OWNER_NODE, size);
        if (!buffer) {
            return fail(s, CO_STACK_PART_STORE, CO_STACK_ERR_NO_MEMORY);
        }
        co_store_config_t groups = { c->store_groups, c->store_group_rows, s->line,
                                     c->store_min_interval_ms, c->store_saved, c->user };
        s->has_store = co_store_init_config(&s->store, s->od, c->store_backend, c->store_user,
                                            buffer, size, &groups);
        if (!s->has_store) {
            return fail(s, CO_STACK_PART_STORE, CO_STACK_ERR_TAKEN);
        }
    }
    if (!co_node_attach_od(&s->node, s->od, s->has_store ? &s->store : NULL, &s->hb_consumer)) {
        return fail(s, CO_STACK_PART_NODE, CO_STACK_ERR_TAKEN);
    }
    return serve_od(s, n);
}

/* The node tells its server the NMT state through these. */
static void sdo_server_state(void *server, co_nmt_state_t state)
{
    co_sdo_server_set_nmt_state(server, state);
}

static void usdo_server_state(void *server, co_nmt_state_t state)
{
    co_usdo_server_set_nmt_state(server, state);
}

static co_stack_status_t start_node_parts(co_stack_t *s, const co_stack_node_config_t *c,
                                          const node_sizes_t *n)
{
    co_node_services_t services = {.sync = &s->sync, .time = &s->time,
                                   .led = s->has_led ? &s->led : NULL};
    co_stack_status_t status = s->od ? start_od_parts(s, c, n) : serve_od(s, n);
    if (status == CO_STACK_OK) {
        status = start_emcy(s, n);
    }
    services.emcy = &s->emcy;
    services.errors = s->has_errors ? &s->errors : NULL;
    if (status == CO_STACK_OK && s->od) {
        status = bind_line_services(s);
        if (status == CO_STACK_OK) {
            status = start_pdo(s, n);
            services.pdo = &s->pdo;
        }
        if (CO_CONFIG_CLASSIC && status == CO_STACK_OK && !is_fd(s->line)) {
            s->has_guard_slave = co_guard_slave_init(&s->guard_slave, s->line, &s->node.nmt,
                                                     co_node_guard_life, &s->node);
            if (!s->has_guard_slave || !co_guard_slave_attach_od(&s->guard_slave, s->od)) {
                status = fail(s, CO_STACK_PART_GUARD_SLAVE, CO_STACK_ERR_TAKEN);
            }
            services.guard = &s->guard_slave;
        }
    }
    if (CO_CONFIG_CLASSIC && s->has_sdo_server) {
        services.server = &s->sdo_server;
        services.server_state = sdo_server_state;
    }
    if (CO_CONFIG_FD && s->has_usdo_server) {
        services.server = &s->usdo_server;
        services.server_state = usdo_server_state;
    }
    if (status == CO_STACK_OK) {
        co_node_attach_services(&s->node, &services);
    }
    return status;
}

/* ---------------------------------------------------------------- LSS slave */

enum { OD_IDENTITY = 0x1018 };

static bool lss_wanted(const co_stack_node_config_t *c)
{
    return !c->lss_off && c->od && co_od_find(c->od, OD_IDENTITY, 4) != NULL;
}

/* The application's indications, reached through the stack's own. */
static bool lss_check_bit_timing(co_lss_slave_t *slave, uint8_t selector, uint8_t index,
                                 void *user)
{
    co_stack_t *s = user;
    return s->lss_app && s->lss_app->check_bit_timing &&
           s->lss_app->check_bit_timing(slave, selector, index, s->lss_user);
}

static void lss_activate_bit_timing(co_lss_slave_t *slave, uint16_t delay_ms, void *user)
{
    co_stack_t *s = user;
    if (s->lss_app && s->lss_app->activate_bit_timing) {
        s->lss_app->activate_bit_timing(slave, delay_ms, s->lss_user);
    }
}

static uint8_t lss_store(co_lss_slave_t *slave, uint8_t node_id, void *user)
{
    co_stack_t *s = user;
    if (s->lss_app && s->lss_app->store) {
        return s->lss_app->store(slave, node_id, s->lss_user);
    }
    return CO_LSS_ERR_STORE_NOT_SUPPORTED;
}

static void lss_state_changed(co_lss_slave_t *slave, co_lss_state_t state, void *user)
{
    co_stack_t *s = user;
    if (s->lss_app && s->lss_app->state_changed) {
        s->lss_app->state_changed(slave, state, s->lss_user);
    }
}

/* An unconfigured node got its node-id: set it up outside the frame's
 * handler (a timer due now, run once this co_line_process drained rx). */
static void lss_reset_communication(co_lss_slave_t *slave, uint8_t node_id, void *user)
{
    (void)slave;
    (void)node_id;
    co_stack_t *s = user;
    if (s->unconfigured) {
        co_timer_start(co_line_timers(s->line), &s->lss_timer, co_line_now(s->line));
    }
}

static void node_id_changed(co_stack_t *s, uint8_t node_id)
{
    if (s->ind && s->ind->node_id_changed) {
        s->ind->node_id_changed(s, node_id, s->user);
    }
}

/* The node-id a reset (communication or node) activates: the application's
 * (co_stack_set_node_id_at_reset), else an LSS slave's pending one (CiA 305).
 * Another valid one renumbers the running node (co_node_set_node_id, called
 * by the node before its parameters reload), the default SDO channel
 * follows, the application is told before the boot-up. A pending 255 keeps
 * the node-id: a configured node leaving the network for LSS-only
 * operation is not implemented. */
static uint8_t node_id_at_reset(co_node_t *node, co_nmt_command_t kind, void *user)
{
    (void)kind;
    co_stack_t *s = user;
    uint8_t id = node->nmt.node_id;
    bool by_lss = false;
    if (s->node_id_at_reset != 0u) {
        id = s->node_id_at_reset;
        s->node_id_at_reset = 0;
        if (s->has_lss_slave) {
            co_lss_slave_follow_node_id(&s->lss_slave, id);
        }
    } else if (s->has_lss_slave) {
        uint8_t pending = co_lss_slave_pending_node_id(&s->lss_slave);
        if (pending >= 1u && pending <= 127u && pending != id) {
            id = co_lss_slave_reset_communication(&s->lss_slave);
            by_lss = true;
        }
    }
    if (id == node->nmt.node_id) {
        return id;
    }
    (void)co_node_set_node_id(node, id);
    if (CO_CONFIG_CLASSIC && s->has_sdo_server) {
        co_sdo_server_refresh(&s->sdo_server);   /* channel 0: 0x600/0x580 + node-id */
    }
    node_id_changed(s, id);
    if (by_lss && s->lss_app && s->lss_app->reset_communication) {
        s->lss_app->reset_communication(&s->lss_slave, id, s->lss_user);
    }
    return id;
}

co_stack_status_t co_stack_set_node_id_at_reset(co_stack_t *stack, uint8_t node_id)
{
    if (!stack || !stack->has_node) {
        return CO_STACK_ERR_STATE;
    }
    if (node_id < 1u || node_id > 127u) {
        return CO_STACK_ERR_ARGUMENT;
    }
    stack->node_id_at_reset = node_id;
    return CO_STACK_OK;
}

static co_stack_status_t node_create(co_stack_t *s, const co_stack_node_config_t *config,
                                     const node_sizes_t *n);

static void lss_configured(co_timer_t *timer, uint64_t now_us, void *user)
{
    (void)timer;
    (void)now_us;
    co_stack_t *s = user;
    uint8_t id = co_lss_slave_reset_communication(&s->lss_slave);
    if (!s->unconfigured || id < 1u || id > 127u) {
        return;
    }
    co_stack_node_config_t c = s->node_config;
    c.node_id = id;
    /* As sealing with the node-id would have: $NODEID defaults with it. */
    co_od_set_node_id(c.od, id);
    co_od_load_defaults(c.od, CO_GROUP_ALL);
    node_sizes_t n;
    (void)node_sizes(s->line, &c, &n);   /* checked by co_stack_node_init */
    if (node_create(s, &c, &n) != CO_STACK_OK) {
        return;                          /* co_stack_failed_part says which part */
    }
    s->unconfigured = false;
    node_id_changed(s, id);
    /* told before the boot-up, so the application knows the new node-id by the
     * time the node's first state change reaches it */
    if (s->lss_app && s->lss_app->reset_communication) {
        s->lss_app->reset_communication(&s->lss_slave, id, s->lss_user);
    }
    if (s->boot_requested) {
        co_node_boot(&s->node);
    }
}

static co_stack_status_t lss_start(co_stack_t *s, const co_stack_node_config_t *c)
{
    co_lss_address_t address;
    for (uint8_t part = 0; part < 4u; part++) {
        if (!co_od_get_u32(c->od, OD_IDENTITY, (uint8_t)(part + 1u), &address.part[part])) {
            address.part[part] = 0;   /* an identity sub-entry the OD lacks */
        }
    }
    s->lss_app = c->lss_ind;
    s->lss_user = c->lss_user;
    s->lss_wiring = (co_lss_slave_indications_t){lss_check_bit_timing, lss_activate_bit_timing,
                                                 lss_store, lss_state_changed,
                                                 lss_reset_communication};
    co_timer_init(&s->lss_timer, lss_configured, s);
    if (!co_lss_slave_init(&s->lss_slave, s->line, &address, c->node_id, &s->lss_wiring, s)) {
        return fail(s, CO_STACK_PART_LSS, CO_STACK_ERR_TAKEN);
    }
    s->has_lss_slave = true;
    return CO_STACK_OK;
}

static void lss_undo(co_stack_t *s)
{
    if (s->has_lss_slave) {
        co_timer_cancel(co_line_timers(s->line), &s->lss_timer);
        co_lss_slave_deinit(&s->lss_slave);
        s->has_lss_slave = false;
    }
    s->unconfigured = false;
    s->boot_requested = false;
}

/* ---------------------------------------------------------------- node set-up */

/* The node itself, its node-id known (1..127). */
static co_stack_status_t node_create(co_stack_t *s, const co_stack_node_config_t *config,
                                     const node_sizes_t *n)
{
    if (!co_node_init(&s->node, s->line, config->node_id, config->heartbeat_ms, config->ind,
                      config->user)) {
        return fail(s, CO_STACK_PART_NODE, CO_STACK_ERR_STATE);
    }
    s->has_node = true;
    s->od = config->od;
    s->node_id_at_reset = 0;
    co_node_set_reset_node_id(&s->node, node_id_at_reset, s);
    if (config->leds) {
        co_led_config_t led = {.same_phase = config->led_same_phase,
                               .changed = config->led_changed,
                               .user = config->user};
        co_led_init(&s->led, s->line, &led);
        s->has_led = true;
    }
    co_stack_status_t status = start_node_parts(s, config, n);
    if (status != CO_STACK_OK) {
        co_stack_part_t part = s->failed;
        node_undo(s);
        s->failed = part;
    } else {
        co_stack_rdn_node_added(s);   /* redundancy started before the node */
    }
    return status;
}

co_stack_status_t co_stack_node_init(co_stack_t *stack, const co_stack_node_config_t *config)
{
    if (!stack || !stack->line || !config) {
        return CO_STACK_ERR_ARGUMENT;
    }
    co_stack_t *s = stack;
    s->failed = CO_STACK_PART_NONE;
    if (s->has_node || s->unconfigured) {
        return fail(s, CO_STACK_PART_NODE, CO_STACK_ERR_STATE);
    }
    bool unconfigured = config->node_id == CO_LSS_NODE_ID_UNCONFIGURED;
    if ((!unconfigured && (config->node_id < 1 || config->node_id > 127)) ||
        (config->store_backend && !config->od)) {
        return fail(s, CO_STACK_PART_NODE, CO_STACK_ERR_ARGUMENT);
    }
    if (unconfigured && !lss_wanted(config)) {
        /* nothing could ever give it a node-id */
        return fail(s, CO_STACK_PART_LSS, CO_STACK_ERR_ARGUMENT);
    }
    if (config->od && !config->od->sealed) {
        return fail(s, CO_STACK_PART_NODE, CO_STACK_ERR_STATE);
    }
    if ((config->led_changed || config->led_same_phase) && !config->leds) {
        return fail(s, CO_STACK_PART_LED, CO_STACK_ERR_ARGUMENT);
    }
    node_sizes_t n;
    if (config->od && (config->od->mode != co_line_mode(s->line) ||
                       !node_sizes(s->line, config, &n))) {
        return fail(s, CO_STACK_PART_NODE, CO_STACK_ERR_OD);
    }
    if (!config->od) {
        (void)node_sizes(s->line, config, &n);
    }
    if (unconfigured) {
        co_stack_status_t status = lss_start(s, config);
        if (status == CO_STACK_OK) {
            s->unconfigured = true;
            s->node_config = *config;
        }
        return status;
    }
    co_stack_status_t status = node_create(s, config, &n);
    if (status == CO_STACK_OK && lss_wanted(config)) {
        status = lss_start(s, config);
        if (status != CO_STACK_OK) {
            node_undo(s);
            s->failed = CO_STACK_PART_LSS;
        }
    }
    return status;
}

co_stack_status_t co_stack_boot(co_stack_t *stack)
{
    if (stack && stack->unconfigured) {
        stack->boot_requested = true;   /* boots once LSS gives it a node-id */
        return CO_STACK_OK;
    }
    if (!stack || !stack->has_node) {
        return CO_STACK_ERR_STATE;
    }
    co_node_boot(&stack->node);
    if (stack->has_flyma) {
        co_flyma_boot(&stack->flyma);
    }
    /* After the parameters loaded (a stored Bdefault counts); the boot-up
     * is still queued, so it goes out on that bus. */
    co_stack_rdn_boot(stack);
    return CO_STACK_OK;
}

void co_stack_node_deinit(co_stack_t *stack)
{
    if (stack && stack->line) {
        lss_undo(stack);
        if (stack->has_node) {
            node_undo(stack);
        }
    }
}

/* ---------------------------------------------------------------- LSS master */

co_stack_status_t co_stack_lss_master_init(co_stack_t *stack, uint32_t timeout_ms,
                                           co_lss_done_fn on_done, void *user)
{
    if (!stack || !stack->line) {
        return CO_STACK_ERR_ARGUMENT;
    }
    stack->failed = CO_STACK_PART_NONE;
    if (stack->has_lss_master) {
        return fail(stack, CO_STACK_PART_LSS, CO_STACK_ERR_STATE);
    }
    if (!co_lss_master_init(&stack->lss_master, stack->line, timeout_ms, on_done, user)) {
        return fail(stack, CO_STACK_PART_LSS, CO_STACK_ERR_TAKEN);
    }
    stack->has_lss_master = true;
    return CO_STACK_OK;
}

void co_stack_lss_master_deinit(co_stack_t *stack)
{
    if (stack && stack->has_lss_master) {
        co_lss_master_deinit(&stack->lss_master);
        stack->has_lss_master = false;
    }
}

/* ---------------------------------------------------------------- the client */

co_stack_status_t co_stack_client_init(co_stack_t *stack, const co_stack_client_config_t *config)
{
    if (!stack || !stack->line || !config || config->sessions < 1 || config->sessions > 128) {
        return CO_STACK_ERR_ARGUMENT;
    }
    co_stack_t *s = stack;
    s->failed = CO_STACK_PART_NONE;
    if (s->has_usdo_client || s->has_sdo_client) {
        return fail(s, CO_STACK_PART_CLIENT, CO_STACK_ERR_STATE);
    }
    bool fd = is_fd(s->line);
    if (fd && (config->node_id < 1 || config->node_id > 127)) {
        return fail(s, CO_STACK_PART_CLIENT, CO_STACK_ERR_ARGUMENT);
    }
    void *table = take(s, OWNER_CLIENT, client_entry_size(s->line) * config->sessions);
    if (!table) {
        return fail(s, CO_STACK_PART_CLIENT, CO_STACK_ERR_NO_MEMORY);
    }
    if (fd) {
        co_usdo_client_config_t c = {.sessions = table,
                                     .session_count = config->sessions,
                                     .node_id = config->node_id,
                                     .timeout_ms = config->timeout_ms};
        s->has_usdo_client = co_usdo_client_init(&s->usdo_client, s->line, &c);
    } else if (CO_CONFIG_CLASSIC) {
        /* a local node's 0x1280.. channels come with it */
        co_sdo_client_config_t c = {.channels = table,
                                    .channel_count = config->sessions,
                                    .od = s->has_node ? s->od : NULL,
                                    .timeout_ms = config->timeout_ms};
        s->has_sdo_client = co_sdo_client_init(&s->sdo_client, s->line, &c);
    }
    if (!s->has_usdo_client && !s->has_sdo_client) {
        give_back(s, OWNER_CLIENT);
        return fail(s, CO_STACK_PART_CLIENT, CO_STACK_ERR_TAKEN);
    }
    return CO_STACK_OK;
}

void co_stack_client_deinit(co_stack_t *stack)
{
    if (!stack || !stack->line) {
        return;
    }
    co_stack_manager_deinit(stack);   /* it reads through the client */
    if (CO_CONFIG_FD && stack->has_usdo_client) {
        co_usdo_client_deinit(&stack->usdo_client);
        stack->has_usdo_client = false;
    }
    if (CO_CONFIG_CLASSIC && stack->has_sdo_client) {
        co_sdo_client_deinit(&stack->sdo_client);
        stack->has_sdo_client = false;
    }
    give_back(stack, OWNER_CLIENT);
}

/* ---------------------------------------------------------------- sleep */

/* The application hears every phase first; waking up then resets the local
 * node's communication (CiA 320: a node awake again starts over). */
static uint8_t on_sleep(co_sleep_t *sleep, co_sleep_event_t event, uint8_t arg, uint8_t arg2,
                        void *user)
{
    co_stack_t *s = user;
    uint8_t answer = s->sleep_ind ? s->sleep_ind(sleep, event, arg, arg2, s->sleep_user) : 0;
    if (event == CO_SLEEP_EV_WAKE && s->has_node) {
        co_nmt_apply(&s->node.nmt, CO_NMT_CMD_RESET_COMMUNICATION);
    }
    return answer;
}

co_stack_status_t co_stack_sleep_init(co_stack_t *stack, const co_sleep_config_t *config)
{
    if (!stack || !stack->line || !config) {
        return CO_STACK_ERR_ARGUMENT;
    }
    if (stack->has_sleep) {
        return fail(stack, CO_STACK_PART_SLEEP, CO_STACK_ERR_STATE);
    }
    co_sleep_config_t own = *config;
    own.ind = on_sleep;
    own.user = stack;
    stack->sleep_ind = config->ind;
    stack->sleep_user = config->user;
    if (!co_sleep_init(&stack->sleep, stack->line, &own)) {
        return fail(stack, CO_STACK_PART_SLEEP, CO_STACK_ERR_TAKEN);
    }
    stack->has_sleep = true;
    return CO_STACK_OK;
}

void co_stack_sleep_deinit(co_stack_t *stack)
{
    if (stack && stack->has_sleep) {
        co_sleep_deinit(&stack->sleep);
        stack->has_sleep = false;
    }
}

/* ---------------------------------------------------------------- flying master */

/* A slave watches the active master's heartbeat, a master nobody's. */
static void flyma_watch(co_stack_t *s, uint8_t master)
{
    if (s->flyma_watched && s->flyma_watched != master) {
        co_hb_consumer_unwatch(&s->hb_consumer, s->flyma_watched);
        s->flyma_watched = 0;
    }
    if (master && s->flyma_watch_ms && s->flyma_watched != master &&
        co_hb_consumer_watch(&s->hb_consumer, master, s->flyma_watch_ms) == CO_HB_CONFIG_OK) {
        s->flyma_watched = master;
        /* the master may be gone already: do not wait for a first heartbeat */
        (void)co_hb_consumer_expect(&s->hb_consumer, master);
    }
}

static void on_flyma(co_flyma_t *flyma, co_flyma_event_t event, co_flyma_state_t state,
                     uint8_t master, uint8_t priority, void *user)
{
    co_stack_t *s = user;
    if (event == CO_FLYMA_EV_STATE) {
        flyma_watch(s, state == CO_FLYMA_SLAVE ? master : 0);
        if (s->has_manager) {
            /* only the active master manages the network */
            co_manager_set_active(&s->manager, state == CO_FLYMA_MASTER);
        }
    }
    if (s->flyma_ind) {
        s->flyma_ind(flyma, event, state, master, priority, s->flyma_user);
    }
    if (event == CO_FLYMA_EV_RESET_ALL) {
        /* every node, this one included: its reset starts the flying master over */
        (void)co_nmt_master_send(s->line, &s->node.nmt, CO_NMT_CMD_RESET_COMMUNICATION, 0,
                                 true);
    }
}

co_stack_status_t co_stack_flyma_init(co_stack_t *stack, const co_stack_flyma_config_t *config)
{
    if (!stack || !stack->line || !config) {
        return CO_STACK_ERR_ARGUMENT;
    }
    co_stack_t *s = stack;
    if (!s->has_node || s->has_flyma) {
        return fail(s, CO_STACK_PART_FLYMA, CO_STACK_ERR_STATE);
    }
    co_flyma_config_t c = config->flyma;
    if (s->od) {
        co_flyma_config_from_od(&c, s->od);
    }
    s->flyma_ind = c.ind;
    s->flyma_user = c.user;
    c.ind = on_flyma;
    c.user = s;
    if (!co_flyma_init(&s->flyma, s->line, &c)) {
        return fail(s, CO_STACK_PART_FLYMA, CO_STACK_ERR_TAKEN);
    }
    s->has_flyma = true;
    s->flyma_watch_ms = config->master_heartbeat_ms;
    s->flyma_watched = 0;
    co_node_attach_flyma(&s->node, &s->flyma);
    if (s->has_manager) {
        co_manager_set_active(&s->manager, false);   /* until the negotiation says */
    }
    if (co_node_state(&s->node) != CO_NMT_INITIALISING) {
        co_flyma_boot(&s->flyma);   /* the node runs already */
    }
    return CO_STACK_OK;
}

void co_stack_flyma_deinit(co_stack_t *stack)
{
    if (!stack || !stack->has_flyma) {
        return;
    }
    co_node_attach_flyma(&stack->node, NULL);
    flyma_watch(stack, 0);
    co_flyma_deinit(&stack->flyma);
    stack->has_flyma = false;
    if (stack->has_manager) {
        co_manager_set_active(&stack->manager, true);   /* no other master to defer to */
    }
}

/* ---------------------------------------------------------------- the manager */

/* The manager peeks at every frame of 0x700..0x77F (boot-ups, heartbeats,
 * guarding answers), then the guarding master takes its nodes' answers. */
static bool manager_ec_filter(co_line_t *line, const co_frame_t *frame, void *user)
{
    co_stack_t *s = user;
    co_manager_ec_frame(&s->manager, frame);
    return CO_CONFIG_CLASSIC && s->has_guard_master &&
           co_guard_master_receive(line, frame, &s->guard_master);
}

static uint8_t manager_slaves(co_stack_t *s)
{
    uint8_t n = co_manager_slaves_in(s->od, co_line_node_id(s->line));
    return n ? n : 1u;
}

/* Room for a 0x1F22 DCF when the OD serves 0x1F25 (0: none taken). */
static uint32_t manager_dcf_room(const co_stack_t *s, uint32_t asked)
{
    if (!co_od_has_index(s->od, 0x1F25)) {
        return 0;
    }
    return asked ? asked : (uint32_t)CO_MANAGER_DCF_BUFFER;
}

size_t co_stack_manager_need(co_stack_t *stack, const co_stack_manager_config_t *config)
{
    if (!stack || !stack->has_node || !stack->od) {
        return 0;
    }
    /* the same room co_stack_manager_init takes for this config */
    uint32_t dcf = manager_dcf_room(stack, config ? config->dcf_capacity : 0u);
    return CO_STACK_BLOCK(sizeof(co_manager_slave_t) * manager_slaves(stack)) +
           (dcf ? CO_STACK_BLOCK(dcf) : 0u);
}

co_stack_status_t co_stack_manager_init(co_stack_t *stack,
                                        const co_stack_manager_config_t *config)
{
    if (!stack || !stack->line || !config) {
        return CO_STACK_ERR_ARGUMENT;
    }
    co_stack_t *s = stack;
    s->failed = CO_STACK_PART_NONE;
    if (!s->has_node || !s->od || s->has_manager || (!s->has_sdo_client && !s->has_usdo_client)) {
        return fail(s, CO_STACK_PART_MANAGER, CO_STACK_ERR_STATE);
    }
    uint32_t startup = 0;
    if (!co_od_get_u32(s->od, 0x1F80, 0, &startup) || !(startup & CO_MANAGER_STARTUP_MANAGER)) {
        return fail(s, CO_STACK_PART_MANAGER, CO_STACK_ERR_OD);
    }
    uint8_t capacity = manager_slaves(s);
    co_manager_slave_t *slaves = take(s, OWNER_MANAGER, sizeof *slaves * capacity);
    if (!slaves) {
        return fail(s, CO_STACK_PART_MANAGER, CO_STACK_ERR_NO_MEMORY);
    }
    uint32_t dcf_room = manager_dcf_room(s, config->dcf_capacity);
    uint8_t *dcf = dcf_room ? take(s, OWNER_MANAGER, dcf_room) : NULL;
    if (dcf_room && !dcf) {
        give_back(s, OWNER_MANAGER);
        return fail(s, CO_STACK_PART_MANAGER, CO_STACK_ERR_NO_MEMORY);
    }
    co_manager_config_t c = {.slaves = slaves, .capacity = capacity,
                             .parallel = config->parallel, .hooks = config->hooks,
                             .retry_ms = config->retry_ms, .on_event = config->on_event,
                             .user = config->user, .dcf_buffer = dcf,
                             .dcf_capacity = dcf_room};
    if (!co_manager_init(&s->manager, s->line, s->od, &s->node.nmt,
                         s->has_sdo_client ? &s->sdo_client : NULL,
                         s->has_usdo_client ? &s->usdo_client : NULL,
                         s->has_guard_master ? &s->guard_master : NULL, &c)) {
        give_back(s, OWNER_MANAGER);
        return fail(s, CO_STACK_PART_MANAGER, CO_STACK_ERR_ARGUMENT);
    }
    s->has_manager = true;
    co_hb_consumer_set_filter(&s->hb_consumer, manager_ec_filter, s);
    if (s->has_flyma) {
        /* a flying master decides whether this node manages the network */
        co_manager_set_active(&s->manager, co_flyma_state(&s->flyma) == CO_FLYMA_MASTER);
    }
    return CO_STACK_OK;
}

void co_stack_manager_deinit(co_stack_t *stack)
{
    if (!stack || !stack->has_manager) {
        return;
    }
    co_manager_deinit(&stack->manager);
    stack->has_manager = false;
    /* the guarding master gets the frames first again */
    co_hb_consumer_set_filter(&stack->hb_consumer,
                              stack->has_guard_master ? co_guard_master_receive : NULL,
                              stack->has_guard_master ? &stack->guard_master : NULL);
    give_back(stack, OWNER_MANAGER);
}

/* ---------------------------------------------------------------- SRDO and GFC */

/* The EMCY error code of a safe-state entry; 0: none (a GFC or the
 * application's own reason are commands, not errors). See
 * docs/protocol-notes.md, "SRDO and GFC", for the sources and the choice. */
static uint16_t srdo_emcy_code(co_srdo_violation_t why)
{
    switch (why) {
    case CO_SRDO_CONFIG_INVALID:
    case CO_SRDO_CRC_MISMATCH:
    case CO_SRDO_BAD_PARAMETER: return CO_SRDO_EMCY_CONFIG;
    case CO_SRDO_WRONG_LENGTH: return CO_SRDO_EMCY_LENGTH;
    case CO_SRDO_GFC:
    case CO_SRDO_APPLICATION:
    case CO_SRDO_NONE: return 0;
    default: return CO_SRDO_EMCY_PROTOCOL;
    }
}

/* SRDO n's safe-state error: its own active error (source key per SRDO,
 * so two SRDOs with the same code stay two errors); byte 3 the SRDO
 * number, byte 4 the violation. */
static co_emcy_error_t srdo_error(const co_stack_t *s, const co_srdo_t *srdo,
                                  co_srdo_violation_t why)
{
    uint8_t number = (uint8_t)(srdo - s->srdo + 1);
    co_emcy_error_t err;
    memset(&err, 0, sizeof err);
    err.code = srdo_emcy_code(why);
    err.msef[0] = number;
    err.msef[1] = (uint8_t)why;
    err.spec_number = 304;
    err.source = (uint16_t)(CO_EMCY_SOURCE_SRDO + number);
    return err;
}

static uint64_t srdo_bit(const co_stack_t *s, const co_srdo_t *srdo)
{
    return (uint64_t)1u << (srdo - s->srdo);
}

static void on_srdo_safe(co_srdo_t *srdo, co_srdo_violation_t why, void *user)
{
    co_stack_t *s = user;
    co_emcy_error_t err = srdo_error(s, srdo, why);
    /* raised once: a start that fails again at once keeps the error active */
    if (err.code != 0 && s->has_emcy && (s->srdo_errors & srdo_bit(s, srdo)) == 0 &&
        co_emcy_raise(&s->emcy, &err) == CO_EMCY_OK) {
        s->srdo_errors |= srdo_bit(s, srdo);
    }
    if (s->srdo_ind) {
        s->srdo_ind(srdo, why, s->srdo_user);
    }
}

/* The SRDO left the safe state (or is gone): its error is over (error
 * reset EMCY). */
static void on_srdo_leave(co_srdo_t *srdo, co_srdo_violation_t had, void *user)
{
    co_stack_t *s = user;
    if ((s->srdo_errors & srdo_bit(s, srdo)) == 0) {
        return;
    }
    s->srdo_errors &= ~srdo_bit(s, srdo);
    co_emcy_error_t err = srdo_error(s, srdo, had);
    if (s->has_emcy) {
        (void)co_emcy_clear(&s->emcy, &err);   /* not active: the application cleared it */
    }
}

/* A GFC puts every SRDO of the node in the safe state at once. */
static void on_gfc(co_gfc_t *gfc, void *user)
{
    (void)gfc;
    co_stack_t *s = user;
    for (uint8_t i = 0; i < s->srdo_count; i++) {
        co_srdo_fail(&s->srdo[i], CO_SRDO_GFC);
    }
}

co_stack_status_t co_stack_srdo_init(co_stack_t *stack, uint8_t count, co_srdo_fn on_safe,
                                     void *user)
{
    if (!stack || !stack->line || count == 0 || count > 64) {
        return CO_STACK_ERR_ARGUMENT;
    }
    if (!stack->has_node || stack->has_srdo) {
        return fail(stack, CO_STACK_PART_SRDO, CO_STACK_ERR_STATE);
    }
    co_srdo_t *srdo = take(stack, OWNER_SRDO, sizeof *srdo * count);
    if (!srdo) {
        return fail(stack, CO_STACK_PART_SRDO, CO_STACK_ERR_NO_MEMORY);
    }
    stack->srdo = srdo;
    stack->srdo_count = count;
    stack->srdo_ind = on_safe;
    stack->srdo_user = user;
    stack->srdo_errors = 0;
    for (uint8_t i = 0; i < count; i++) {
        co_srdo_init(&srdo[i], stack->line, on_srdo_safe, stack);
        co_srdo_set_leave_fn(&srdo[i], on_srdo_leave);
    }
    co_gfc_init(&stack->gfc, stack->line, on_gfc, stack);
    bool guarded = false;
    if (stack->od && co_od_find(stack->od, CO_SRDO_OD_VALID, 0)) {
        guarded = co_srdo_od_attach(&stack->srdo_od, stack->od, srdo, count, &stack->gfc,
                                    stack->node.nmt.state);
        if (!guarded) {
            stack->srdo = NULL;
            stack->srdo_count = 0;
            give_back(stack, OWNER_SRDO);
            return fail(stack, CO_STACK_PART_SRDO, CO_STACK_ERR_NO_MEMORY);
        }
    }
    co_node_attach_srdo(&stack->node, srdo, count, guarded ? &stack->srdo_od : NULL);
    stack->has_srdo = true;
    return CO_STACK_OK;
}

void co_stack_srdo_deinit(co_stack_t *stack)
{
    if (!stack || !stack->has_srdo) {
        return;
    }
    co_node_attach_srdo(&stack->node, NULL, 0, NULL);
    co_srdo_od_detach(&stack->srdo_od);
    co_gfc_deinit(&stack->gfc);
    for (uint8_t i = 0; i < stack->srdo_count; i++) {
        co_srdo_t *srdo = &stack->srdo[i];
        on_srdo_leave(srdo, co_srdo_violation(srdo), stack);   /* no owner left for it */
        co_srdo_deinit(srdo);
    }
    stack->has_srdo = false;
    stack->srdo = NULL;
    stack->srdo_count = 0;
    give_back(stack, OWNER_SRDO);
}

/* ---------------------------------------------------------------- all */

void co_stack_deinit(co_stack_t *stack)
{
    if (!stack || !stack->line) {
        return;
    }
    co_stack_redundancy_deinit(stack);
    co_stack_sleep_deinit(stack);
    co_stack_client_deinit(stack);
    co_stack_node_deinit(stack);
    line_undo(stack);
    stack->line = NULL;
}

co_stack_part_t co_stack_failed_part(const co_stack_t *stack)
{
    return stack->failed;
}

const char *co_stack_part_name(co_stack_part_t part)
{
    switch (part) {
    case CO_STACK_PART_NONE: return "nothing";
    case CO_STACK_PART_HEARTBEAT: return "heartbeat consumer";
    case CO_STACK_PART_SYNC: return "SYNC";
    case CO_STACK_PART_TIME: return "TIME";
    case CO_STACK_PART_EMCY_CONSUMER: return "EMCY consumer";
    case CO_STACK_PART_GUARD_MASTER: return "node guarding master";
    case CO_STACK_PART_NODE: return "local node";
    case CO_STACK_PART_STORE: return "parameter store";
    case CO_STACK_PART_EMCY: return "EMCY producer";
    case CO_STACK_PART_PDO: return "PDO service";
    case CO_STACK_PART_GUARD_SLAVE: return "node guarding slave";
    case CO_STACK_PART_SERVER: return "SDO/USDO server";
    case CO_STACK_PART_CLIENT: return "SDO/USDO client";
    case CO_STACK_PART_LSS: return "LSS";
    case CO_STACK_PART_MANAGER: return "network manager";
    case CO_STACK_PART_SLEEP: return "sleep and wake-up";
    case CO_STACK_PART_FLYMA: return "flying master";
    case CO_STACK_PART_LED: return "LED indicators";
    case CO_STACK_PART_SRDO: return "SRDO and GFC";
    case CO_STACK_PART_REDUNDANCY: return "bus redundancy";
    case CO_STACK_PART_CIA401: return "CiA 401 I/O device";
    }
    return "unknown part";
}
