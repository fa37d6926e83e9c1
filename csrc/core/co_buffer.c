/* Memory buffer source/sink (see co_buffer.h). */
#include "canopenfd/co_buffer.h"

#include <string.h>

uint32_t co_buffer_read(const co_buffer_t *b, uint32_t offset, uint8_t *buf, uint32_t want)
{
    uint32_t n;
    if (offset >= b->size) {
        return 0;
    }
    n = b->size - offset;
    if (n > want) {
        n = want;
    }
    memcpy(buf, b->data + offset, n);
    return n;
}

bool co_buffer_put(co_buffer_t *b, uint32_t offset, const uint8_t *data, uint32_t len,
                   uint32_t total, bool total_known)
{
    if (len == 0) {
        if (total_known && total > b->capacity) {
            return false;
        }
        b->size = 0;
        return true;
    }
    if (offset > b->capacity || len > b->capacity - offset) {
        return false;
    }
    memcpy(b->data + offset, data, len);
    b->size = offset + len;
    return true;
}
