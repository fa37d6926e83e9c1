/* Concise DCF (CiA 302-3): the binary form of a device configuration that a
 * configuration manager downloads into a node, entry by entry.
 *
 * Layout, every number little-endian:
 *   UNSIGNED32  number of entries
 *   then per entry:
 *     UNSIGNED16  index
 *     UNSIGNED8   sub-index
 *     UNSIGNED32  data size in bytes
 *     data        (size bytes, the value as it goes on the wire)
 * Evidence for the layout: docs/protocol-notes.md, "Concise DCF (CiA 302-3)".
 *
 * The iterator validates as it goes and never reads past the buffer: each
 * malformation is its own status, with the byte offset where it was found.
 * The writer builds a concise DCF into caller memory (tests, tools).
 * Nothing allocates; no globals. */
#ifndef CO_CONCISE_DCF_H
#define CO_CONCISE_DCF_H

#include <stdbool.h>
#include <stdint.h>

enum {
    CO_CONCISE_COUNT_SIZE = 4,      /* the leading number of entries */
    CO_CONCISE_ENTRY_HEADER = 7     /* index, sub-index, size */
};

typedef enum co_concise_status {
    CO_CONCISE_OK = 0,              /* an entry was read (next) / all valid (validate) */
    CO_CONCISE_END = 1,             /* every counted entry read, nothing after them */
    CO_CONCISE_NO_COUNT = 2,        /* fewer than 4 bytes: no number of entries */
    CO_CONCISE_TRUNCATED_HEADER = 3,/* 1..6 bytes where an entry header should be */
    CO_CONCISE_SIZE_PAST_END = 4,   /* an entry's data size goes past the end */
    CO_CONCISE_COUNT_MISMATCH = 5,  /* the data ends after fewer entries than counted */
    CO_CONCISE_TRAILING_BYTES = 6,  /* bytes after the last counted entry */
    CO_CONCISE_NO_ROOM = 7          /* writer: the buffer is too small */
} co_concise_status_t;

/* One entry; data points into the iterated buffer. */
typedef struct co_concise_entry {
    uint16_t index;
    uint8_t sub;
    uint32_t size;
    const uint8_t *data;
    uint32_t offset;                /* byte offset of the entry's header */
    uint32_t number;                /* 0-based position in the DCF */
} co_concise_entry_t;

typedef struct co_concise_iter {
    const uint8_t *data;
    uint32_t length;
    uint32_t count;                 /* the number of entries the DCF announces */
    uint32_t read;                  /* entries returned so far */
    uint32_t pos;                   /* offset of the next entry header */
    uint8_t status;                 /* co_concise_status_t: sticky once not OK */
    uint32_t error_offset;          /* where the error was found */
} co_concise_iter_t;

/* Start reading: OK, or NO_COUNT (then every next() returns it again). */
co_concise_status_t co_concise_iter_init(co_concise_iter_t *it, const uint8_t *data,
                                         uint32_t length);
/* The next entry (OK), END after the last counted one when no byte follows,
 * else an error status; an error is sticky and it->error_offset says where. */
co_concise_status_t co_concise_next(co_concise_iter_t *it, co_concise_entry_t *entry);
/* Walk the whole DCF: OK with *count = entries, or the first error with
 * *error_offset (either pointer may be NULL). */
co_concise_status_t co_concise_validate(const uint8_t *data, uint32_t length, uint32_t *count,
                                        uint32_t *error_offset);
/* A short English name of a status ("size past end", ...). */
const char *co_concise_status_text(co_concise_status_t status);

/* Writer: entries are appended; the count is written by finish. */
typedef struct co_concise_writer {
    uint8_t *buf;
    uint32_t capacity;
    uint32_t length;
    uint32_t count;
    bool overflow;                  /* an add did not fit: finish fails */
} co_concise_writer_t;

void co_concise_writer_init(co_concise_writer_t *w, uint8_t *buf, uint32_t capacity);
/* Append an entry; false (nothing written, overflow set) when it does not fit. */
bool co_concise_add(co_concise_writer_t *w, uint16_t index, uint8_t sub, const uint8_t *data,
                    uint32_t size);
/* Append an unsigned value of 1..4 bytes, little-endian; another size is
 * refused like an overflow (finish then fails). */
bool co_concise_add_u32(co_concise_writer_t *w, uint16_t index, uint8_t sub, uint32_t value,
                        uint8_t size);
/* Write the count; the DCF's length, or 0 after an overflow. */
uint32_t co_concise_finish(co_concise_writer_t *w);

#endif
