/* Decoder of the fuzz input format (see fuzz_input.h). */
#include "fuzz_input.h"

#include <string.h>

void fz_reader_init(fz_reader_t *r, const uint8_t *data, size_t size)
{
    r->data = data;
    r->size = size;
    r->pos = 0;
    r->records = 0;
}

bool fz_done(const fz_reader_t *r) { return r->pos >= r->size; }

uint8_t fz_u8(fz_reader_t *r)
{
    if (r->pos >= r->size) {
        return 0;
    }
    return r->data[r->pos++];
}

uint16_t fz_u16(fz_reader_t *r)
{
    uint16_t lo = fz_u8(r);
    return (uint16_t)(lo | (uint16_t)fz_u8(r) << 8);
}

uint32_t fz_u32(fz_reader_t *r)
{
    uint32_t lo = fz_u16(r);
    return lo | (uint32_t)fz_u16(r) << 16;
}

void fz_bytes(fz_reader_t *r, uint8_t *out, size_t n)
{
    size_t have = r->pos < r->size ? r->size - r->pos : 0;
    size_t take = n < have ? n : have;
    if (take > 0) {
        memcpy(out, r->data + r->pos, take);
        r->pos += take;
    }
    if (take < n) {
        memset(out + take, 0, n - take);
    }
}

uint32_t fz_time_ms(uint8_t p)
{
    p &= 31u;
    if (p < 16u) {
        return p;
    }
    if (p < 24u) {
        return (uint32_t)(p - 15u) * 50u;
    }
    return (uint32_t)(p - 23u) * 1000u;
}

static void read_frame(fz_reader_t *r, fz_record_t *rec, const uint32_t *ids, uint8_t id_count,
                       co_mode_t mode)
{
    co_frame_t *f = &rec->frame;
    uint8_t fl = fz_u8(r);
    uint8_t len = fz_u8(r);
    memset(f, 0, sizeof *f);
    rec->alt = (fl & 0xC0u) == 0x40u;
    if (fl & 0x80u) {
        f->flags = (uint8_t)(fl & 0x1Fu);
        f->len = (uint8_t)(len % (CO_FRAME_MAX_DATA + 1u));
    } else if (mode == CO_MODE_FD) {
        f->flags = CO_FRAME_FD | CO_FRAME_BRS;
        f->len = co_fd_len_round(len % (CO_FRAME_MAX_DATA + 1u));
    } else {
        f->flags = 0;
        f->len = (uint8_t)(len % (CO_FRAME_CLASSIC_MAX + 1u));
    }
    if (rec->p < id_count && rec->p < 31u) {
        f->id = ids[rec->p];
    } else if (f->flags & CO_FRAME_EXT) {
        f->id = fz_u32(r) & 0x1FFFFFFFu;
    } else {
        f->id = fz_u16(r) & 0x7FFu;
    }
    /* An RTR frame carries no data bytes in the input (its length is a DLC). */
    if (!(f->flags & CO_FRAME_RTR)) {
        fz_bytes(r, f->data, f->len);
    }
}

bool fz_next(fz_reader_t *r, fz_record_t *rec, const uint32_t *ids, uint8_t id_count,
             co_mode_t mode)
{
    uint8_t b;
    if (fz_done(r) || r->records >= FZ_MAX_RECORDS) {
        return false;
    }
    r->records++;
    b = fz_u8(r);
    rec->op = (uint8_t)(b & 7u);
    rec->p = (uint8_t)(b >> 3);
    rec->has_mask = false;
    switch (rec->op) {
    case FZ_OP_FRAME:
    case FZ_OP_FRAME2:
        read_frame(r, rec, ids, id_count, mode);
        rec->op = FZ_OP_FRAME;
        break;
    case FZ_OP_TIME:
        rec->ms = fz_time_ms(rec->p);
        break;
    case FZ_OP_BUS:
        if (rec->p & 2u) {
            rec->mask = fz_u8(r);
            rec->has_mask = true;
        }
        break;
    default:
        break;
    }
    return true;
}

bool fz_od_add(co_od_t *od, uint16_t index, uint8_t sub, uint8_t object_code, uint8_t type,
               uint8_t access, uint32_t value)
{
    co_od_def_t d;
    uint8_t v[4] = {(uint8_t)value, (uint8_t)(value >> 8), (uint8_t)(value >> 16),
                    (uint8_t)(value >> 24)};
    memset(&d, 0, sizeof d);
    d.index = index;
    d.sub = sub;
    d.object_code = object_code;
    d.type = type;
    d.access = access;
    d.size = co_od_type_size(type);
    d.default_value = v;
    d.default_length = d.size;
    return co_od_add(od, &d) == CO_OD_ADDED;
}

bool fz_line_init(co_line_t *line, co_mode_t mode, co_frame_t *rx, co_frame_t *tx,
                  uint16_t slots)
{
    co_line_config_t lc;
    memset(&lc, 0, sizeof lc);
    lc.mode = mode;
    lc.rx_slots = rx;
    lc.rx_capacity = slots;
    lc.tx_slots = tx;
    lc.tx_capacity = slots;
    return co_line_init(line, &lc);
}
