/* Multiplexed PDOs (see co_mpdo.h). */
#include "canopenfd/co_mpdo.h"

#include <string.h>

#define DAM_BIT 0x80u
#define NODE_MASK 0x7Fu
#define NODE_MAX 127u

/* ------------------------------------------------------------ codec */

bool co_mpdo_decode(const uint8_t *data, uint8_t len, co_mpdo_msg_t *msg)
{
    if (data == NULL || len != CO_MPDO_LEN) {
        return false;
    }
    msg->dam = (data[0] & DAM_BIT) != 0;
    msg->node = (uint8_t)(data[0] & NODE_MASK);
    msg->index = (uint16_t)(data[1] | data[2] << 8);
    msg->sub = data[3];
    memcpy(msg->data, data + 4, CO_MPDO_DATA_MAX);
    return true;
}

void co_mpdo_encode(const co_mpdo_msg_t *msg, uint8_t out[CO_MPDO_LEN])
{
    out[0] = (uint8_t)((msg->dam ? DAM_BIT : 0u) | (msg->node & NODE_MASK));
    out[1] = (uint8_t)msg->index;
    out[2] = (uint8_t)(msg->index >> 8);
    out[3] = msg->sub;
    memcpy(out + 4, msg->data, CO_MPDO_DATA_MAX);
}

/* ------------------------------------------------------------ lists */

/* Whether sub lies in the block of `block` subs starting at first (0 = 1). */
static bool in_block(uint8_t sub, uint8_t first, uint8_t block)
{
    uint32_t last = (uint32_t)first + (block == 0 ? 0u : block - 1u);
    return sub >= first && sub <= last;
}

/* Reads list entry index:sub as a little-endian number of `size` bytes. */
static bool list_entry(const co_od_t *od, uint16_t index, uint8_t sub, uint32_t size,
                       uint64_t *value)
{
    uint8_t buf[8];
    uint32_t got = 0;
    uint32_t i;
    if (co_od_get(od, index, sub, buf, sizeof buf, &got) != 0 || got != size) {
        return false;   /* an entry of another type is not a list entry */
    }
    *value = 0;
    for (i = 0; i < size; i++) {
        *value |= (uint64_t)buf[i] << (8 * i);
    }
    return true;
}

bool co_mpdo_scanner_lists(const co_od_t *od, uint16_t index, uint8_t sub)
{
    uint16_t list;
    for (list = CO_MPDO_SCANNER_FIRST; list <= CO_MPDO_SCANNER_LAST; list++) {
        uint8_t count = 0, s;
        if (!co_od_get_u8(od, list, 0, &count)) {
            continue;
        }
        for (s = 1; s != 0 && s <= count; s++) {
            uint64_t v;
            if (list_entry(od, list, s, 4, &v) && v != 0 && (uint16_t)(v >> 8) == index &&
                in_block(sub, (uint8_t)v, (uint8_t)(v >> 24))) {
                return true;
            }
        }
    }
    return false;
}

bool co_mpdo_dispatch(const co_od_t *od, uint8_t producer, uint16_t index, uint8_t sub,
                      uint16_t *local_index, uint8_t *local_sub)
{
    uint16_t list;
    for (list = CO_MPDO_DISPATCHER_FIRST; list <= CO_MPDO_DISPATCHER_LAST; list++) {
        uint8_t count = 0, s;
        if (!co_od_get_u8(od, list, 0, &count)) {
            continue;
        }
        for (s = 1; s != 0 && s <= count; s++) {
            uint64_t v;
            uint8_t first;
            if (!list_entry(od, list, s, 8, &v) || v == 0 || (uint8_t)v != producer ||
                (uint16_t)(v >> 16) != index) {
                continue;
            }
            first = (uint8_t)(v >> 8);
            if (in_block(sub, first, (uint8_t)(v >> 56))) {
                *local_index = (uint16_t)(v >> 40);
                *local_sub = (uint8_t)((uint8_t)(v >> 32) + (sub - first));
                return true;
            }
        }
    }
    return false;
}

/* ------------------------------------------------------------ consumer */

/* Write the frame's value into local index:sub as an SDO download would;
 * 0 or the abort code (nothing written then). */
static uint32_t write_local(co_mpdo_t *mpdo, uint16_t index, uint8_t sub, const uint8_t *data)
{
    co_od_t *od = mpdo->pdo->od;
    const co_od_entry_t *e = co_od_find(od, index, sub);
    uint32_t size, abort;
    if (e == NULL) {
        return co_od_has_index(od, index) ? CO_ABORT_NO_SUB : CO_ABORT_NO_OBJECT;
    }
    co_od_xfer_init(&mpdo->xfer, mpdo->scratch, sizeof mpdo->scratch);
    size = co_od_type_size(e->type);
    abort = co_od_write_begin(od, &mpdo->xfer, index, sub, size == 0 ? e->size : size);
    if (abort == 0 && (e->flags & CO_OD_MAP_RPDO) == 0) {
        abort = CO_ABORT_NO_MAP;
    }
    if (abort == 0 && (size == 0 || size > CO_MPDO_DATA_MAX)) {
        abort = CO_ABORT_MAP_LENGTH;   /* strings, domains, values beyond 4 bytes */
    }
    if (abort == 0) {
        abort = co_od_write_chunk(&mpdo->xfer, data, size);
    }
    if (abort == 0) {
        abort = co_od_write_end(&mpdo->xfer);
    }
    if (abort == CO_OD_SPLIT) {
        abort = CO_ABORT_DATA_STATE;   /* a frame cannot wait for a deferred answer */
    }
    if (abort != 0) {
        co_od_xfer_abort(&mpdo->xfer, abort);
    }
    return abort;
}

static void refuse(co_mpdo_t *mpdo, uint16_t rpdo, const co_mpdo_msg_t *msg, uint16_t index,
                   uint8_t sub, uint32_t abort)
{
    if (mpdo->ind != NULL && mpdo->ind->refused != NULL) {
        mpdo->ind->refused(mpdo, rpdo, msg, index, sub, abort, mpdo->user);
    }
}

static void on_frame(co_pdo_t *pdo, uint16_t rpdo, uint8_t kind, const co_frame_t *f, void *user)
{
    co_mpdo_t *mpdo = user;
    co_mpdo_msg_t msg;
    uint16_t index;
    uint8_t sub;
    uint32_t abort;
    if (!co_mpdo_decode(f->data, f->len, &msg)) {
        mpdo->stats.rx_bad_length++;
        return;
    }
    if (msg.dam != (kind == CO_PDO_MAP_DAM)) {
        mpdo->stats.rx_wrong_mode++;
        return;
    }
    if (msg.dam) {
        if (msg.node != CO_MPDO_ALL_NODES && msg.node != co_line_node_id(pdo->line)) {
            mpdo->stats.rx_other_node++;
            return;
        }
        index = msg.index;
        sub = msg.sub;
    } else if (!co_mpdo_dispatch(pdo->od, msg.node, msg.index, msg.sub, &index, &sub)) {
        mpdo->stats.rx_not_dispatched++;
        refuse(mpdo, rpdo, &msg, msg.index, msg.sub, CO_ABORT_NO_OBJECT);
        return;
    }
    abort = write_local(mpdo, index, sub, msg.data);
    if (abort != 0) {
        mpdo->stats.rx_refused++;
        refuse(mpdo, rpdo, &msg, index, sub, abort);
        /* CiA 301 names this EMCY for DAM only; a SAM consumer chose its list */
        if (msg.dam && mpdo->ind != NULL && mpdo->ind->error != NULL) {
            mpdo->ind->error(mpdo, CO_MPDO_EMCY_DAM, rpdo, mpdo->user);
        }
        return;
    }
    mpdo->stats.rx_applied++;
    if (mpdo->ind != NULL && mpdo->ind->received != NULL) {
        mpdo->ind->received(mpdo, rpdo, &msg, index, sub, mpdo->user);
    }
}

/* ------------------------------------------------------------ producer */

/* The TPDO if it is an active MPDO of this kind. */
static bool is_mpdo_tpdo(const co_mpdo_t *mpdo, uint16_t number, uint8_t kind)
{
    const co_pdo_channel_t *ch = co_pdo_channel(mpdo->pdo, false, number);
    return ch != NULL && ch->active && ch->mpdo == kind;
}

static co_mpdo_status_t send(co_mpdo_t *mpdo, uint16_t number, const co_mpdo_msg_t *msg)
{
    uint8_t frame[CO_MPDO_LEN];
    co_mpdo_encode(msg, frame);
    if (!co_pdo_send_mpdo(mpdo->pdo, number, frame, sizeof frame)) {
        mpdo->stats.tx_refused++;
        return CO_MPDO_ERR_NOT_SENT;
    }
    mpdo->stats.tx_frames++;
    return CO_MPDO_OK;
}

static co_mpdo_status_t refused_call(co_mpdo_t *mpdo, co_mpdo_status_t status)
{
    mpdo->stats.tx_refused++;
    return status;
}

co_mpdo_status_t co_mpdo_send_dam(co_mpdo_t *mpdo, uint16_t tpdo_number, uint8_t node,
                                  uint16_t index, uint8_t sub, const uint8_t *data, uint8_t len)
{
    co_mpdo_msg_t msg;
    if (node > NODE_MAX || data == NULL || len == 0 || len > CO_MPDO_DATA_MAX) {
        return refused_call(mpdo, CO_MPDO_ERR_ARGUMENT);
    }
    if (!is_mpdo_tpdo(mpdo, tpdo_number, CO_PDO_MAP_DAM)) {
        return refused_call(mpdo, CO_MPDO_ERR_CHANNEL);
    }
    memset(&msg, 0, sizeof msg);
    msg.dam = true;
    msg.node = node;
    msg.index = index;
    msg.sub = sub;
    memcpy(msg.data, data, len);
    return send(mpdo, tpdo_number, &msg);
}

/* Reads a local object as an SDO upload would (access, before_read
 * handlers); true when msg->data holds it. */
static bool read_local(co_mpdo_t *mpdo, uint16_t index, uint8_t sub, co_mpdo_msg_t *msg)
{
    uint32_t n = 0, abort;
    bool last = false;
    co_od_xfer_init(&mpdo->xfer, mpdo->scratch, sizeof mpdo->scratch);
    abort = co_od_read_begin(mpdo->pdo->od, &mpdo->xfer, index, sub);
    if (abort == CO_OD_SPLIT) {
        abort = CO_ABORT_DATA_STATE;   /* a send call cannot wait for a deferred answer */
    }
    if (abort == 0 && (mpdo->xfer.total == 0 || mpdo->xfer.total > CO_MPDO_DATA_MAX)) {
        abort = CO_ABORT_MAP_LENGTH;
    }
    if (abort == 0) {
        abort = co_od_read_chunk(&mpdo->xfer, msg->data, CO_MPDO_DATA_MAX, &n, &last);
    }
    if (abort != 0 || !last) {
        co_od_xfer_abort(&mpdo->xfer, abort != 0 ? abort : CO_ABORT_MAP_LENGTH);
        return false;
    }
    return true;
}

co_mpdo_status_t co_mpdo_send_sam(co_mpdo_t *mpdo, uint16_t tpdo_number, uint16_t index,
                                  uint8_t sub)
{
    co_mpdo_msg_t msg;
    uint8_t own = co_line_node_id(mpdo->pdo->line);
    if (own == 0 || own > NODE_MAX) {
        return refused_call(mpdo, CO_MPDO_ERR_ARGUMENT);   /* an unconfigured node has no source */
    }
    if (!is_mpdo_tpdo(mpdo, tpdo_number, CO_PDO_MAP_SAM)) {
        return refused_call(mpdo, CO_MPDO_ERR_CHANNEL);
    }
    if (!co_mpdo_scanner_lists(mpdo->pdo->od, index, sub)) {
        return refused_call(mpdo, CO_MPDO_ERR_NOT_SCANNED);
    }
    memset(&msg, 0, sizeof msg);
    if (!read_local(mpdo, index, sub, &msg)) {
        return refused_call(mpdo, CO_MPDO_ERR_OBJECT);
    }
    msg.dam = false;
    msg.node = own;
    msg.index = index;
    msg.sub = sub;
    return send(mpdo, tpdo_number, &msg);
}

co_mpdo_status_t co_mpdo_send_dam_mapped(co_mpdo_t *mpdo, uint16_t tpdo_number, uint8_t node)
{
    co_mpdo_msg_t msg;
    uint32_t entry = 0;
    uint8_t bytes;
    if (node > NODE_MAX) {
        return refused_call(mpdo, CO_MPDO_ERR_ARGUMENT);
    }
    if (!is_mpdo_tpdo(mpdo, tpdo_number, CO_PDO_MAP_DAM)) {
        return refused_call(mpdo, CO_MPDO_ERR_CHANNEL);
    }
    memset(&msg, 0, sizeof msg);
    /* is_mpdo_tpdo vouched for the number, so the mapping index exists */
    if (!co_od_get_u32(mpdo->pdo->od, (uint16_t)(CO_PDO_TPDO_MAP + tpdo_number - 1u), 1,
                       &entry)) {
        entry = 0;
    }
    bytes = (uint8_t)((entry & 0xFFu) / 8u);
    msg.index = (uint16_t)(entry >> 16);
    msg.sub = (uint8_t)(entry >> 8);
    if (entry == 0 || (entry & 7u) != 0 || bytes == 0 || bytes > CO_MPDO_DATA_MAX ||
        !read_local(mpdo, msg.index, msg.sub, &msg) || mpdo->xfer.total != bytes) {
        return refused_call(mpdo, CO_MPDO_ERR_OBJECT);
    }
    msg.dam = true;
    msg.node = node;
    return send(mpdo, tpdo_number, &msg);
}

/* ------------------------------------------------------------ life cycle */

void co_mpdo_init(co_mpdo_t *mpdo, co_pdo_t *pdo, const co_mpdo_indications_t *ind, void *user)
{
    memset(mpdo, 0, sizeof *mpdo);
    mpdo->pdo = pdo;
    mpdo->ind = ind;
    mpdo->user = user;
    co_pdo_set_mpdo_rx(pdo, on_frame, mpdo);
}

void co_mpdo_deinit(co_mpdo_t *mpdo)
{
    if (mpdo->pdo != NULL) {
        co_pdo_set_mpdo_rx(mpdo->pdo, NULL, NULL);
        mpdo->pdo = NULL;
    }
}
