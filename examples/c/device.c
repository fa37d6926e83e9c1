/* The example device: a static object dictionary and the application. */
#include "device.h"

#include <string.h>

/* Little-endian default values of the table below. */
static const uint8_t u8_0[] = {0};
static const uint8_t device_type[] = {0x91, 0x01, 0x00, 0x00};   /* CiA 401 */
static const uint8_t heartbeat_ms[] = {0xE8, 0x03};               /* 1000 ms */
static const uint8_t vendor_id[] = {0x78, 0x56, 0x34, 0x12};
static const uint8_t product_code[] = {0x01, 0x00, 0x00, 0x00};
static const uint8_t revision[] = {0x00, 0x00, 0x01, 0x00};
static const uint8_t serial[] = {0x2A, 0x00, 0x00, 0x00};
static const uint8_t count_4[] = {4};
static const uint8_t count_5[] = {5};
static const uint8_t count_1[] = {1};
static const uint8_t rpdo_cob_id[] = {0x00, 0x02, 0x00, 0x00};    /* 0x200 + $NODEID */
static const uint8_t tpdo_cob_id[] = {0x80, 0x01, 0x00, 0x00};    /* 0x180 + $NODEID */
static const uint8_t emcy_cob_id[] = {0x80, 0x00, 0x00, 0x00};    /* 0x80 + $NODEID */
static const uint8_t type_254[] = {254};
static const uint8_t event_ms[] = {0xE8, 0x03};                   /* 1000 ms */
static const uint8_t map_setpoint[] = {0x20, 0x00, 0x01, 0x20};   /* 0x2001:00, 32 bits */
static const uint8_t map_counter[] = {0x20, 0x00, 0x00, 0x20};    /* 0x2000:00, 32 bits */
static const char name[] = "canopenfd C example";

#define ENTRY(i, s, oc, t, acc, fl, sz, def)                                             \
    {.index = (i), .sub = (s), .object_code = (oc), .type = (t), .access = (acc),        \
     .flags = (fl), .size = (sz), .default_value = (def), .default_length = sizeof(def)}
#define EMPTY(i, s, oc, t, acc, fl, sz)                                                  \
    {.index = (i), .sub = (s), .object_code = (oc), .type = (t), .access = (acc),        \
     .flags = (fl), .size = (sz)}
#define VAR CO_OBJECT_VAR
#define REC CO_OBJECT_RECORD
#define ARR CO_OBJECT_ARRAY
#define U8 CO_TYPE_UNSIGNED8
#define U16 CO_TYPE_UNSIGNED16
#define U32 CO_TYPE_UNSIGNED32
#define RO CO_ACCESS_RO
#define RW CO_ACCESS_RW
#define NODEID CO_OD_NODEID_RELATIVE
#define MAP (CO_OD_MAP_TPDO | CO_OD_MAP_RPDO)

static const co_od_def_t od_table[] = {
    ENTRY(0x1000, 0, VAR, U32, RO, 0, 4, device_type),
    EMPTY(0x1001, 0, VAR, U8, RO, 0, 1),
    {.index = 0x1008, .sub = 0, .object_code = VAR, .type = CO_TYPE_VISIBLE_STRING,
     .access = CO_ACCESS_CONST, .size = DEVICE_LARGEST_ENTRY,
     .default_value = (const uint8_t *)name, .default_length = sizeof name - 1},
    ENTRY(0x1014, 0, VAR, U32, RW, NODEID, 4, emcy_cob_id),
    ENTRY(0x1017, 0, VAR, U16, RW, 0, 2, heartbeat_ms),
    ENTRY(0x1018, 0, REC, U8, RO, 0, 1, count_4),
    ENTRY(0x1018, 1, REC, U32, RO, 0, 4, vendor_id),
    ENTRY(0x1018, 2, REC, U32, RO, 0, 4, product_code),
    ENTRY(0x1018, 3, REC, U32, RO, 0, 4, revision),
    ENTRY(0x1018, 4, REC, U32, RO, 0, 4, serial),
    ENTRY(0x1400, 0, REC, U8, RO, 0, 1, count_5),
    ENTRY(0x1400, 1, REC, U32, RW, NODEID, 4, rpdo_cob_id),
    ENTRY(0x1400, 2, REC, U8, RW, 0, 1, type_254),
    EMPTY(0x1400, 3, REC, U16, RW, 0, 2),
    EMPTY(0x1400, 5, REC, U16, RW, 0, 2),
    ENTRY(0x1600, 0, REC, U8, RW, 0, 1, count_1),
    ENTRY(0x1600, 1, REC, U32, RW, 0, 4, map_setpoint),
    EMPTY(0x1600, 2, REC, U32, RW, 0, 4),
    EMPTY(0x1600, 3, REC, U32, RW, 0, 4),
    EMPTY(0x1600, 4, REC, U32, RW, 0, 4),
    ENTRY(0x1800, 0, REC, U8, RO, 0, 1, count_5),
    ENTRY(0x1800, 1, REC, U32, RW, NODEID, 4, tpdo_cob_id),
    ENTRY(0x1800, 2, REC, U8, RW, 0, 1, type_254),
    EMPTY(0x1800, 3, REC, U16, RW, 0, 2),
    ENTRY(0x1800, 5, REC, U16, RW, 0, 2, event_ms),
    ENTRY(0x1A00, 0, REC, U8, RW, 0, 1, count_1),
    ENTRY(0x1A00, 1, REC, U32, RW, 0, 4, map_counter),
    EMPTY(0x1A00, 2, REC, U32, RW, 0, 4),
    EMPTY(0x1A00, 3, REC, U32, RW, 0, 4),
    EMPTY(0x1A00, 4, REC, U32, RW, 0, 4),
    /* the application's data: a counter it sends, a setpoint it receives */
    EMPTY(0x2000, 0, VAR, U32, RO, MAP, 4),
    EMPTY(0x2001, 0, VAR, U32, RW, MAP, 4),
    ENTRY(0x2002, 0, VAR, U8, RW, 0, 1, u8_0),
};

/* Every DEVICE_COUNTER_PERIOD_US the counter goes up and TPDO 1 is
 * triggered (it goes out in NMT operational, and by its event timer). */
static void counter_tick(co_timer_t *timer, uint64_t now_us, void *user)
{
    device_t *d = user;
    uint32_t value = 0;
    (void)co_od_get_u32(&d->od, 0x2000, 0, &value);
    value++;
    const uint8_t bytes[4] = {(uint8_t)value, (uint8_t)(value >> 8), (uint8_t)(value >> 16),
                              (uint8_t)(value >> 24)};
    (void)co_od_put(&d->od, 0x2000, 0, bytes, sizeof bytes);
    co_pdo_t *pdo = co_stack_pdo(&d->stack);
    if (pdo) {
        (void)co_pdo_trigger_object(pdo, 0x2000, 0);
    }
    co_timer_start(co_line_timers(&d->line), timer, now_us + DEVICE_COUNTER_PERIOD_US);
}

const char *device_init(device_t *d, co_mode_t mode, uint8_t node_id)
{
    memset(d, 0, sizeof *d);
    co_line_config_t lc = {.mode = mode, .brs = mode == CO_MODE_FD,
                           .rx_slots = d->rx, .rx_capacity = DEVICE_QUEUE,
                           .tx_slots = d->tx, .tx_capacity = DEVICE_QUEUE};
    if (!co_line_init(&d->line, &lc)) {
        return "line";
    }
    co_od_init(&d->od, mode, d->entries, DEVICE_OD_ENTRIES, d->pool, sizeof d->pool, d->subs,
               CO_STACK_OD_SUBSCRIPTIONS);
    for (size_t i = 0; i < sizeof od_table / sizeof od_table[0]; i++) {
        co_od_add_result_t r = co_od_add(&d->od, &od_table[i]);
        if (r != CO_OD_ADDED && r != CO_OD_SKIPPED_MODE) {
            return "object dictionary table";
        }
    }
    if (!co_od_seal(&d->od, node_id)) {
        return "object dictionary (sub 0 of a record)";
    }
    co_stack_line_config_t line_config = {.heartbeat_entries = DEVICE_HB_ENTRIES};
    co_stack_node_config_t node_config = {.node_id = node_id, .od = &d->od,
                                          .server_sessions = DEVICE_SERVER_SESSIONS};
    /* the static memory must be what the stack asks for */
    if (co_stack_line_need(&d->line, &line_config) +
            co_stack_node_need(&d->line, &node_config) > sizeof d->memory) {
        return "memory (DEVICE_MEMORY too small for this OD)";
    }
    co_stack_arena_init(&d->arena, d->memory, sizeof d->memory);
    if (co_stack_init(&d->stack, &d->line, &line_config,
                      co_stack_arena_allocator(&d->arena)) != CO_STACK_OK ||
        co_stack_node_init(&d->stack, &node_config) != CO_STACK_OK) {
        return co_stack_part_name(co_stack_failed_part(&d->stack));
    }
    co_timer_init(&d->counter_timer, counter_tick, d);
    co_timer_start(co_line_timers(&d->line), &d->counter_timer, DEVICE_COUNTER_PERIOD_US);
    co_stack_boot(&d->stack);
    return NULL;
}

uint64_t device_process(device_t *d, uint64_t now_us)
{
    return co_line_process(&d->line, now_us);
}
