/* libFuzzer harness: the concise DCF iterator (co_concise_*) over any bytes,
 * as a damaged file or a hostile 0x1F22 download would give it.
 *
 * Input: the concise DCF itself (no records).
 *
 * Checks: the iterator never reads past the input (ASan: the input is
 * libFuzzer's exactly sized buffer); every entry's data lies inside it, in
 * order, without overlap; an error offset is inside the input; validate and
 * a walk with next() agree on the status and the entries read; a DCF that
 * validates is rebuilt byte for byte by the writer from its entries. */
#include "canopenfd/co_concise_dcf.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { REBUILD_MAX = 1 << 16 };

static uint8_t rebuilt[REBUILD_MAX];

static void fail(const char *what)
{
    fprintf(stderr, "fuzz invariant broken: %s\n", what);
    abort();
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    co_concise_iter_t it;
    co_concise_entry_t e;
    co_concise_writer_t w;
    co_concise_status_t walk, valid;
    uint32_t len = size > UINT32_MAX ? UINT32_MAX : (uint32_t)size;
    uint32_t count = 0, offset = 0, end_of_last = CO_CONCISE_COUNT_SIZE;
    bool rebuild = len <= REBUILD_MAX;

    co_concise_writer_init(&w, rebuilt, sizeof rebuilt);
    walk = co_concise_iter_init(&it, data, len);
    while (walk == CO_CONCISE_OK) {
        walk = co_concise_next(&it, &e);
        if (walk != CO_CONCISE_OK) {
            break;
        }
        if (e.offset != end_of_last || e.data != data + e.offset + CO_CONCISE_ENTRY_HEADER
            || e.size > len - e.offset - CO_CONCISE_ENTRY_HEADER) {
            fail("entry outside the input or out of order");
        }
        end_of_last = e.offset + CO_CONCISE_ENTRY_HEADER + e.size;
        if (rebuild && !co_concise_add(&w, e.index, e.sub, e.data, e.size)) {
            fail("the writer refused an entry that fits");
        }
    }
    if (walk != CO_CONCISE_END && it.error_offset > len) {
        fail("error offset past the input");
    }
    valid = co_concise_validate(data, len, &count, &offset);
    if ((valid == CO_CONCISE_OK) != (walk == CO_CONCISE_END)
        || (valid != CO_CONCISE_OK && (valid != walk || offset != it.error_offset))
        || count != it.read) {
        fail("validate and the walk disagree");
    }
    if (valid == CO_CONCISE_OK && rebuild) {
        uint32_t n = co_concise_finish(&w);
        if (n != len || memcmp(rebuilt, data, len) != 0) {
            fail("the writer does not rebuild a valid DCF");
        }
    }
    return 0;
}
