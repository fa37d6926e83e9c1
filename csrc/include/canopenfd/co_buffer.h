/* A caller's memory buffer as the source of a download or the sink of an
 * upload, shared by the USDO and SDO clients (each wraps the sink to give
 * its own "out of memory" abort code). */
#ifndef CO_BUFFER_H
#define CO_BUFFER_H

#include <stdbool.h>
#include <stdint.h>

typedef struct co_buffer {
    uint8_t *data;
    uint32_t size;        /* source: bytes to send; sink: bytes held */
    uint32_t capacity;    /* sink: room in data */
} co_buffer_t;

/* Copy up to want bytes from offset; returns the bytes given. */
uint32_t co_buffer_read(const co_buffer_t *b, uint32_t offset, uint8_t *buf, uint32_t want);
/* Sink step: len 0 announces total (total_known false: unknown) and empties
 * the buffer; else the chunk is stored at offset. False when the announced
 * total or the chunk does not fit. */
bool co_buffer_put(co_buffer_t *b, uint32_t offset, const uint8_t *data, uint32_t len,
                   uint32_t total, bool total_known);

#endif
