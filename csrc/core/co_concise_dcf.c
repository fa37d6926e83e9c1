/* Concise DCF codec (CiA 302-3): see co_concise_dcf.h for the layout. Every
 * read checks the bytes left first, with subtractions that cannot wrap, so a
 * hostile size never makes the reader look past the buffer. */
#include "canopenfd/co_concise_dcf.h"

#include <stddef.h>
#include <string.h>

static uint32_t get_le(const uint8_t *p, uint32_t n)
{
    uint32_t v = 0;
    uint32_t i;
    for (i = 0; i < n; i++) {
        v |= (uint32_t)p[i] << (8u * i);
    }
    return v;
}

static void put_le(uint8_t *p, uint32_t v, uint32_t n)
{
    uint32_t i;
    for (i = 0; i < n; i++) {
        p[i] = (uint8_t)(v >> (8u * i));
    }
}

static co_concise_status_t fail(co_concise_iter_t *it, co_concise_status_t status,
                                uint32_t offset)
{
    it->status = (uint8_t)status;
    it->error_offset = offset;
    return status;
}

co_concise_status_t co_concise_iter_init(co_concise_iter_t *it, const uint8_t *data,
                                         uint32_t length)
{
    memset(it, 0, sizeof *it);
    it->data = data;
    it->length = data != NULL ? length : 0;
    if (it->length < CO_CONCISE_COUNT_SIZE) {
        return fail(it, CO_CONCISE_NO_COUNT, 0);
    }
    it->count = get_le(data, CO_CONCISE_COUNT_SIZE);
    it->pos = CO_CONCISE_COUNT_SIZE;
    return CO_CONCISE_OK;
}

co_concise_status_t co_concise_next(co_concise_iter_t *it, co_concise_entry_t *entry)
{
    uint32_t left;
    uint32_t size;
    const uint8_t *p;
    if (it->status != CO_CONCISE_OK) {
        return (co_concise_status_t)it->status;
    }
    left = it->length - it->pos;
    if (it->read == it->count) {
        if (left != 0) {
            return fail(it, CO_CONCISE_TRAILING_BYTES, it->pos);
        }
        it->status = CO_CONCISE_END;
        return CO_CONCISE_END;
    }
    if (left == 0) {
        return fail(it, CO_CONCISE_COUNT_MISMATCH, it->pos);
    }
    if (left < CO_CONCISE_ENTRY_HEADER) {
        return fail(it, CO_CONCISE_TRUNCATED_HEADER, it->pos);
    }
    p = it->data + it->pos;
    size = get_le(p + 3, 4);
    if (size > left - CO_CONCISE_ENTRY_HEADER) {
        return fail(it, CO_CONCISE_SIZE_PAST_END, it->pos + 3);
    }
    entry->index = (uint16_t)get_le(p, 2);
    entry->sub = p[2];
    entry->size = size;
    entry->data = p + CO_CONCISE_ENTRY_HEADER;
    entry->offset = it->pos;
    entry->number = it->read;
    it->pos += CO_CONCISE_ENTRY_HEADER + size;
    it->read++;
    return CO_CONCISE_OK;
}

co_concise_status_t co_concise_validate(const uint8_t *data, uint32_t length, uint32_t *count,
                                        uint32_t *error_offset)
{
    co_concise_iter_t it;
    co_concise_entry_t e;
    co_concise_status_t s = co_concise_iter_init(&it, data, length);
    while (s == CO_CONCISE_OK) {
        s = co_concise_next(&it, &e);
    }
    if (count != NULL) {
        *count = it.read;
    }
    if (error_offset != NULL) {
        *error_offset = s == CO_CONCISE_END ? 0 : it.error_offset;
    }
    return s == CO_CONCISE_END ? CO_CONCISE_OK : s;
}

const char *co_concise_status_text(co_concise_status_t status)
{
    switch (status) {
    case CO_CONCISE_OK: return "ok";
    case CO_CONCISE_END: return "end";
    case CO_CONCISE_NO_COUNT: return "shorter than the 4-byte number of entries";
    case CO_CONCISE_TRUNCATED_HEADER: return "entry header cut short";
    case CO_CONCISE_SIZE_PAST_END: return "entry data size goes past the end";
    case CO_CONCISE_COUNT_MISMATCH: return "fewer entries than the number announced";
    case CO_CONCISE_TRAILING_BYTES: return "bytes after the last announced entry";
    case CO_CONCISE_NO_ROOM: return "no room in the buffer";
    }
    return "unknown status";
}

void co_concise_writer_init(co_concise_writer_t *w, uint8_t *buf, uint32_t capacity)
{
    memset(w, 0, sizeof *w);
    w->buf = buf;
    w->capacity = buf != NULL ? capacity : 0;
    if (w->capacity < CO_CONCISE_COUNT_SIZE) {
        w->overflow = true;
        return;
    }
    w->length = CO_CONCISE_COUNT_SIZE;
}

bool co_concise_add(co_concise_writer_t *w, uint16_t index, uint8_t sub, const uint8_t *data,
                    uint32_t size)
{
    uint8_t *p;
    uint32_t room = w->capacity - w->length;
    if (w->overflow || room < CO_CONCISE_ENTRY_HEADER || size > room - CO_CONCISE_ENTRY_HEADER
        || (size > 0 && data == NULL) || w->count == UINT32_MAX) {
        w->overflow = true;
        return false;
    }
    p = w->buf + w->length;
    put_le(p, index, 2);
    p[2] = sub;
    put_le(p + 3, size, 4);
    if (size > 0) {
        memcpy(p + CO_CONCISE_ENTRY_HEADER, data, size);
    }
    w->length += CO_CONCISE_ENTRY_HEADER + size;
    w->count++;
    return true;
}

bool co_concise_add_u32(co_concise_writer_t *w, uint16_t index, uint8_t sub, uint32_t value,
                        uint8_t size)
{
    uint8_t bytes[4];
    if (size < 1 || size > 4) {
        w->overflow = true;
        return false;
    }
    put_le(bytes, value, size);
    return co_concise_add(w, index, sub, bytes, size);
}

uint32_t co_concise_finish(co_concise_writer_t *w)
{
    if (w->overflow) {
        return 0;
    }
    put_le(w->buf, w->count, CO_CONCISE_COUNT_SIZE);
    return w->length;
}
