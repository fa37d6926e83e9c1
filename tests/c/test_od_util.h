/* Shared helpers of the C unit tests that build an object dictionary or store
 * it: little-endian bytes, short names and entry definitions (one by one or
 * from a table of rows), and an in-memory store backend.
 *
 * Header-only (static functions), like test_util.h. */
#ifndef TEST_OD_UTIL_H
#define TEST_OD_UTIL_H

#include "test_util.h"

#include "canopenfd/co_od.h"
#include "canopenfd/co_store.h"

/* ------------------------------------------------------------------ bytes */

static inline void tu_le_put(uint8_t *p, uint64_t v, uint32_t n)
{
    uint32_t i;
    for (i = 0; i < n; i++)
        p[i] = (uint8_t)(v >> (8 * i));
}

static inline uint64_t tu_le_get(const uint8_t *p, uint32_t n)
{
    uint64_t v = 0;
    uint32_t i;
    for (i = 0; i < n; i++)
        v |= (uint64_t)p[i] << (8 * i);
    return v;
}

/* ------------------------------------------------------------ definitions */

/* Short names for OD tables. */
#define VAR CO_OBJECT_VAR
#define ARR CO_OBJECT_ARRAY
#define REC CO_OBJECT_RECORD
#define U8 CO_TYPE_UNSIGNED8
#define U16 CO_TYPE_UNSIGNED16
#define U32 CO_TYPE_UNSIGNED32
#define I64 CO_TYPE_INTEGER64
#define VS CO_TYPE_VISIBLE_STRING
#define RO CO_ACCESS_RO
#define RW CO_ACCESS_RW
#define AC_CONST CO_ACCESS_CONST
#define ST CO_OD_STORE
#define MINMAX (CO_OD_HAS_MIN | CO_OD_HAS_MAX)

/* A definition without default and limits. */
static inline co_od_def_t tu_od_def(uint16_t index, uint8_t sub, uint8_t object_code,
                                    uint8_t type, uint8_t access, uint16_t flags, uint32_t size)
{
    co_od_def_t d;
    memset(&d, 0, sizeof d);
    d.index = index;
    d.sub = sub;
    d.object_code = object_code;
    d.type = type;
    d.access = access;
    d.flags = flags;
    d.size = size;
    return d;
}

/* One row of an OD table: a string default when `text` is not NULL, else the
 * numeric default `value` and the limits `min` / `max` (which count only with
 * CO_OD_HAS_MIN / CO_OD_HAS_MAX in `flags`). */
typedef struct tu_od_row {
    uint16_t index;
    uint8_t sub;
    uint8_t object_code;
    uint8_t type;
    uint8_t access;
    uint16_t flags;
    uint32_t size;
    int64_t value;                /* numeric default */
    const char *text;             /* string default */
    int64_t min, max;
} tu_od_row_t;

/* The definition of row `t`; a numeric default is put into `store8` (8 bytes),
 * which must live until the definition is added. */
static inline void tu_od_def_from(co_od_def_t *d, const tu_od_row_t *t, uint8_t *store8)
{
    *d = tu_od_def(t->index, t->sub, t->object_code, t->type, t->access, t->flags, t->size);
    if (t->text != NULL) {
        d->default_value = (const uint8_t *)t->text;
        d->default_length = (uint32_t)strlen(t->text);
    } else {
        tu_le_put(store8, (uint64_t)t->value, t->size);
        d->default_value = store8;
        d->default_length = t->size;
        tu_le_put(d->min, (uint64_t)t->min, t->size);
        tu_le_put(d->max, (uint64_t)t->max, t->size);
    }
}

/* Add one entry with a fixed-size type and its default value; it must be added. */
static inline void tu_od_add_value(co_od_t *od, uint16_t index, uint8_t sub, uint8_t obj,
                                   uint8_t type, uint8_t access, uint16_t flags, uint64_t value)
{
    co_od_def_t d;
    uint8_t v[8];
    uint32_t size = co_od_type_size(type);
    d = tu_od_def(index, sub, obj, type, access, flags, size);
    tu_le_put(v, value, size);
    d.default_value = v;
    d.default_length = size;
    assert_int_equal(co_od_add(od, &d), CO_OD_ADDED);
}

/* The value of index:sub, which must be readable and len bytes long. */
static inline uint64_t tu_od_value(const co_od_t *od, uint16_t index, uint8_t sub, uint32_t len)
{
    uint8_t buf[8] = {0};
    uint32_t got = 0;
    assert_int_equal(co_od_get(od, index, sub, buf, sizeof buf, &got), 0);
    assert_int_equal(got, len);
    return tu_le_get(buf, len);
}

/* Add every row; each one must be added. */
static inline void tu_od_add_rows(co_od_t *od, const tu_od_row_t *rows, size_t n)
{
    size_t i;
    for (i = 0; i < n; i++) {
        co_od_def_t d;
        uint8_t v[8];
        tu_od_def_from(&d, &rows[i], v);
        assert_int_equal(co_od_add(od, &d), CO_OD_ADDED);
    }
}

/* ------------------------------------------------- network access (U32) */

/* A network download of len (1..8) bytes of v through a transfer (begin,
 * one chunk, end, as a server makes it): 0 or the abort code. */
static inline uint32_t tu_od_net_write(co_od_t *od, uint16_t index, uint8_t sub, uint64_t v,
                                       uint32_t len)
{
    co_od_xfer_t x;
    uint8_t scratch[64], b[8];
    uint32_t r;
    co_od_xfer_init(&x, scratch, sizeof scratch);
    tu_le_put(b, v, len);
    r = co_od_write_begin(od, &x, index, sub, len);
    if (r != 0)
        return r;
    r = co_od_write_chunk(&x, b, len);
    if (r != 0)
        return r;
    return co_od_write_end(&x);
}

/* A network download of 4 bytes through a transfer: 0 or the abort code. */
static inline uint32_t tu_od_net_write_u32(co_od_t *od, uint16_t index, uint8_t sub,
                                           uint32_t v)
{
    return tu_od_net_write(od, index, sub, v, 4);
}

/* A network upload of a 4-byte value: 0 (value in *out) or the abort code. */
static inline uint32_t tu_od_net_read_u32(co_od_t *od, uint16_t index, uint8_t sub,
                                          uint32_t *out)
{
    co_od_xfer_t x;
    uint8_t scratch[64], b[16];
    uint32_t r, n = 0;
    bool last = false;
    co_od_xfer_init(&x, scratch, sizeof scratch);
    r = co_od_read_begin(od, &x, index, sub);
    if (r != 0)
        return r;
    r = co_od_read_chunk(&x, b, sizeof b, &n, &last);
    if (r != 0)
        return r;
    assert_true(last);
    assert_int_equal(n, 4);
    *out = (uint32_t)tu_le_get(b, 4);
    return 0;
}

/* ------------------------------------------------------ in-memory backend */

typedef struct tu_mem_backend {
    uint8_t data[8192];
    uint32_t length;
    bool has;
    bool fail_save;               /* save answers CO_STORE_IO */
    bool force_load;              /* load answers load_status */
    co_store_status_t load_status;
    bool lie_length;              /* load claims more than the capacity */
    unsigned saves;
    unsigned loads;
} tu_mem_backend_t;

static inline co_store_status_t tu_mem_save(void *user, const uint8_t *image, uint32_t length)
{
    tu_mem_backend_t *m = user;
    m->saves++;
    if (m->fail_save || length > sizeof m->data)
        return CO_STORE_IO;
    memcpy(m->data, image, length);
    m->length = length;
    m->has = true;
    return CO_STORE_OK;
}

static inline co_store_status_t tu_mem_load(void *user, uint8_t *image, uint32_t capacity,
                                            uint32_t *length)
{
    tu_mem_backend_t *m = user;
    m->loads++;
    if (m->force_load)
        return m->load_status;
    if (!m->has)
        return CO_STORE_EMPTY;
    if (m->length > capacity)
        return CO_STORE_TOO_BIG;
    memcpy(image, m->data, m->length);
    *length = m->lie_length ? capacity + 1 : m->length;
    return CO_STORE_OK;
}

static const co_store_backend_t tu_mem_ops = { tu_mem_save, tu_mem_load };

/* Put an image into the backend as if it had been saved. */
static inline void tu_mem_set(tu_mem_backend_t *m, const uint8_t *image, uint32_t length)
{
    assert_true(length <= sizeof m->data);
    memcpy(m->data, image, length);
    m->length = length;
    m->has = true;
}

#endif
