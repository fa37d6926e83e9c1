/* co_store_file: the Linux file backend of co_store.
 *
 * Two halves:
 *  - a fake file system behind the backend's ops table, which models what a
 *    power cut keeps: file data not yet fsynced may be lost (a random prefix
 *    survives, possibly with a zeroed tail), directory changes not yet fsynced
 *    may be lost in order (any prefix of them survives). The save sequence is
 *    cut at every step, and a fresh load must find exactly the old image or
 *    exactly the new one;
 *  - the real system calls in a temporary directory: round trip, permissions,
 *    damaged / truncated / foreign / other-layout / too-big files, I/O errors,
 *    and every status reported. */
#define _GNU_SOURCE

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <stdio.h>
#include <sys/stat.h>
#include <unistd.h>

#include "test_od_util.h"

#include "canopenfd/co_store_file.h"

/* ------------------------------------------------------ fake file system */

#define FS_FILE_MAX 1024
#define FS_INODES 16
#define FS_NAMES 4
#define FS_FDS 8
#define FS_SNAPS 32
#define FS_LOG 256
#define FS_NONE UINT_MAX

#define DIR_PATH "/d"
#define MAIN_PATH "/d/p.bin"
#define TMP_PATH "/d/p.bin.tmp"

typedef struct fs_inode {
    bool used;
    uint8_t data[FS_FILE_MAX];       /* what reads see (the page cache) */
    uint32_t len;
    uint8_t durable[FS_FILE_MAX];    /* what the disk surely has */
    uint32_t durable_len;
    bool dirty;                      /* written since the last fsync */
} fs_inode_t;

typedef struct fs_dir {
    char name[FS_NAMES][16];         /* "" = free slot */
    int inode[FS_NAMES];
} fs_dir_t;

typedef struct fs_fd {
    bool used;
    bool is_dir;
    int inode;
    uint32_t pos;
} fs_fd_t;

typedef struct fake_fs {
    fs_inode_t inodes[FS_INODES];
    fs_dir_t dir;                    /* the directory as processes see it */
    fs_dir_t snaps[FS_SNAPS];        /* [0] durable, then one per later change */
    unsigned snap_count;
    fs_fd_t fds[FS_FDS];
    unsigned step;                   /* calls made */
    unsigned cut_at;                 /* calls from this one on fail: power is gone */
    unsigned fail_at;                /* this one call fails, the machine goes on */
    int fail_errno;
    uint32_t max_write;              /* short writes (0 = no limit) */
    bool eintr;                      /* every other write is interrupted */
    bool write_zero;                 /* write makes no progress */
    unsigned writes;
    int open_flags;                  /* of the last open with O_CREAT */
    mode_t open_mode;
    const char *log[FS_LOG];         /* call names in order */
    unsigned log_count;
} fake_fs_t;

static void fs_init(fake_fs_t *fs)
{
    memset(fs, 0, sizeof *fs);
    fs->snap_count = 1;
    fs->cut_at = FS_NONE;
    fs->fail_at = FS_NONE;
}

/* Every call goes through here: false = it fails (errno set) and does nothing. */
static bool fs_enter(fake_fs_t *fs, const char *name)
{
    unsigned k = fs->step++;
    if (fs->log_count < FS_LOG)
        fs->log[fs->log_count++] = name;
    if (k >= fs->cut_at) {
        errno = EIO;
        return false;
    }
    if (k == fs->fail_at) {
        errno = fs->fail_errno;
        return false;
    }
    return true;
}

static const char *fs_base(const char *path)
{
    if (strncmp(path, DIR_PATH "/", sizeof DIR_PATH) != 0)
        return NULL;
    return path + sizeof DIR_PATH;
}

static int fs_lookup(const fs_dir_t *dir, const char *name)
{
    int i;
    for (i = 0; i < FS_NAMES; i++)
        if (dir->name[i][0] != '\0' && strcmp(dir->name[i], name) == 0)
            return i;
    return -1;
}

static void fs_dir_changed(fake_fs_t *fs)
{
    assert_true(fs->snap_count < FS_SNAPS);
    fs->snaps[fs->snap_count++] = fs->dir;
}

static int fs_new_fd(fake_fs_t *fs, bool is_dir, int inode)
{
    int i;
    for (i = 0; i < FS_FDS; i++) {
        if (!fs->fds[i].used) {
            fs->fds[i].used = true;
            fs->fds[i].is_dir = is_dir;
            fs->fds[i].inode = inode;
            fs->fds[i].pos = 0;
            return 100 + i;
        }
    }
    errno = EMFILE;
    return -1;
}

static fs_fd_t *fs_fd(fake_fs_t *fs, int fd)
{
    if (fd < 100 || fd >= 100 + FS_FDS || !fs->fds[fd - 100].used)
        return NULL;
    return &fs->fds[fd - 100];
}

static int fake_open(void *user, const char *path, int flags, mode_t mode)
{
    fake_fs_t *fs = user;
    const char *name;
    int slot, ino;
    if (!fs_enter(fs, "open"))
        return -1;
    name = fs_base(path);
    if (name == NULL || strlen(name) >= sizeof fs->dir.name[0]) {
        errno = ENOENT;
        return -1;
    }
    slot = fs_lookup(&fs->dir, name);
    if (slot < 0) {
        if (!(flags & O_CREAT)) {
            errno = ENOENT;
            return -1;
        }
        for (ino = 0; ino < FS_INODES && fs->inodes[ino].used; ino++)
            ;
        assert_true(ino < FS_INODES);
        memset(&fs->inodes[ino], 0, sizeof fs->inodes[ino]);
        fs->inodes[ino].used = true;
        for (slot = 0; slot < FS_NAMES && fs->dir.name[slot][0] != '\0'; slot++)
            ;
        assert_true(slot < FS_NAMES);
        strcpy(fs->dir.name[slot], name);
        fs->dir.inode[slot] = ino;
        fs_dir_changed(fs);
    }
    ino = fs->dir.inode[slot];
    if (flags & O_CREAT) {
        fs->open_flags = flags;
        fs->open_mode = mode;
    }
    if (flags & O_TRUNC) {
        fs->inodes[ino].len = 0;
        fs->inodes[ino].dirty = true;
    }
    return fs_new_fd(fs, false, ino);
}

static int fake_open_dir(void *user, const char *path)
{
    fake_fs_t *fs = user;
    if (!fs_enter(fs, "open_dir"))
        return -1;
    if (strcmp(path, DIR_PATH) != 0) {
        errno = ENOENT;
        return -1;
    }
    return fs_new_fd(fs, true, -1);
}

static ssize_t fake_read(void *user, int fd, void *buf, size_t n)
{
    fake_fs_t *fs = user;
    fs_fd_t *f;
    fs_inode_t *ino;
    size_t m;
    if (!fs_enter(fs, "read"))
        return -1;
    f = fs_fd(fs, fd);
    if (f == NULL || f->is_dir) {
        errno = f == NULL ? EBADF : EISDIR;
        return -1;
    }
    ino = &fs->inodes[f->inode];
    m = f->pos < ino->len ? ino->len - f->pos : 0;
    if (m > n)
        m = n;
    memcpy(buf, ino->data + f->pos, m);
    f->pos += (uint32_t)m;
    return (ssize_t)m;
}

static ssize_t fake_write(void *user, int fd, const void *buf, size_t n)
{
    fake_fs_t *fs = user;
    fs_fd_t *f;
    fs_inode_t *ino;
    if (!fs_enter(fs, "write"))
        return -1;
    fs->writes++;
    if (fs->eintr && (fs->writes & 1)) {
        errno = EINTR;
        return -1;
    }
    if (fs->write_zero)
        return 0;
    f = fs_fd(fs, fd);
    if (f == NULL || f->is_dir) {
        errno = EBADF;
        return -1;
    }
    ino = &fs->inodes[f->inode];
    if (fs->max_write != 0 && n > fs->max_write)
        n = fs->max_write;
    if (f->pos + n > FS_FILE_MAX) {
        errno = ENOSPC;
        return -1;
    }
    memcpy(ino->data + f->pos, buf, n);
    f->pos += (uint32_t)n;
    if (f->pos > ino->len)
        ino->len = f->pos;
    ino->dirty = true;
    return (ssize_t)n;
}

static int fake_fsync(void *user, int fd)
{
    fake_fs_t *fs = user;
    fs_fd_t *f = fs_fd(fs, fd);
    if (!fs_enter(fs, f != NULL && f->is_dir ? "fsync_dir" : "fsync"))
        return -1;
    if (f == NULL) {
        errno = EBADF;
        return -1;
    }
    if (f->is_dir) {
        fs->snaps[0] = fs->dir;
        fs->snap_count = 1;
    } else {
        fs_inode_t *ino = &fs->inodes[f->inode];
        memcpy(ino->durable, ino->data, ino->len);
        ino->durable_len = ino->len;
        ino->dirty = false;
    }
    return 0;
}

static int fake_close(void *user, int fd)
{
    fake_fs_t *fs = user;
    fs_fd_t *f = fs_fd(fs, fd);
    if (!fs_enter(fs, f != NULL && f->is_dir ? "close_dir" : "close"))
        return -1;
    if (f == NULL) {
        errno = EBADF;
        return -1;
    }
    f->used = false;
    return 0;
}

static int fake_rename(void *user, const char *from, const char *to)
{
    fake_fs_t *fs = user;
    const char *a, *b;
    int sa, sb;
    if (!fs_enter(fs, "rename"))
        return -1;
    a = fs_base(from);
    b = fs_base(to);
    if (a == NULL || b == NULL || (sa = fs_lookup(&fs->dir, a)) < 0) {
        errno = ENOENT;
        return -1;
    }
    sb = fs_lookup(&fs->dir, b);
    if (sb >= 0)
        fs->dir.name[sb][0] = '\0';   /* the old inode stays for older snapshots */
    strcpy(fs->dir.name[sa], b);
    fs_dir_changed(fs);
    return 0;
}

static int fake_unlink(void *user, const char *path)
{
    fake_fs_t *fs = user;
    const char *name;
    int slot;
    if (!fs_enter(fs, "unlink"))
        return -1;
    name = fs_base(path);
    if (name == NULL || (slot = fs_lookup(&fs->dir, name)) < 0) {
        errno = ENOENT;
        return -1;
    }
    fs->dir.name[slot][0] = '\0';
    fs_dir_changed(fs);
    return 0;
}

static const co_store_file_ops_t fake_ops = {
    fake_open, fake_open_dir, fake_read, fake_write,
    fake_fsync, fake_close, fake_rename, fake_unlink
};

/* What the disk holds after the power went at this moment: directory state
 * `snap` (0 = the last fsynced one; later ones = some of the later changes
 * made it, in order), and for each file written since its last fsync a random
 * prefix of the data, sometimes with a zero-filled tail (blocks allocated but
 * never written). The result is a quiet, fully durable file system. */
static void fs_crash(const fake_fs_t *fs, unsigned snap, uint64_t seed, fake_fs_t *out)
{
    uint64_t rng = seed * 0x9E3779B97F4A7C15ull + 1;
    int i;
    assert_true(snap < fs->snap_count);
    fs_init(out);
    out->dir = fs->snaps[snap];
    out->snaps[0] = out->dir;
    for (i = 0; i < FS_INODES; i++) {
        const fs_inode_t *a = &fs->inodes[i];
        fs_inode_t *b = &out->inodes[i];
        if (!a->used)
            continue;
        b->used = true;
        if (a->dirty) {
            uint32_t keep = (uint32_t)(tu_rand(&rng) % (a->len + 1u));
            memcpy(b->data, a->data, keep);
            if (keep > 0 && (tu_rand(&rng) & 1)) {
                uint32_t from = (uint32_t)(tu_rand(&rng) % keep);
                memset(b->data + from, 0, keep - from);
            }
            b->len = keep;
        } else {
            memcpy(b->data, a->durable, a->durable_len);
            b->len = a->durable_len;
        }
        memcpy(b->durable, b->data, b->len);
        b->durable_len = b->len;
    }
}

/* The current content of a name: its length, or -1 when there is none. */
static long fs_content(const fake_fs_t *fs, const char *name, const uint8_t **data)
{
    int slot = fs_lookup(&fs->dir, name);
    if (slot < 0)
        return -1;
    *data = fs->inodes[fs->dir.inode[slot]].data;
    return (long)fs->inodes[fs->dir.inode[slot]].len;
}

/* dst = src with fresh counters and no faults planned. */
static void fs_copy(fake_fs_t *dst, const fake_fs_t *src)
{
    *dst = *src;
    dst->step = 0;
    dst->log_count = 0;
    dst->writes = 0;
    dst->cut_at = FS_NONE;
    dst->fail_at = FS_NONE;
}

/* A durable file (as if written and fsynced long ago). */
static void fs_add_file(fake_fs_t *fs, const char *name, const uint8_t *data, uint32_t len)
{
    int ino, slot;
    for (ino = 0; ino < FS_INODES && fs->inodes[ino].used; ino++)
        ;
    for (slot = 0; slot < FS_NAMES && fs->dir.name[slot][0] != '\0'; slot++)
        ;
    assert_true(ino < FS_INODES && slot < FS_NAMES && len <= FS_FILE_MAX);
    fs->inodes[ino].used = true;
    memcpy(fs->inodes[ino].data, data, len);
    memcpy(fs->inodes[ino].durable, data, len);
    fs->inodes[ino].len = fs->inodes[ino].durable_len = len;
    strcpy(fs->dir.name[slot], name);
    fs->dir.inode[slot] = ino;
    fs->snaps[0] = fs->dir;
    fs->snap_count = 1;
}

static bool fs_quiet(const fake_fs_t *fs)
{
    int i;
    for (i = 0; i < FS_INODES; i++)
        if (fs->inodes[i].used && fs->inodes[i].dirty)
            return false;
    for (i = 0; i < FS_FDS; i++)
        if (fs->fds[i].used)
            return false;
    return fs->snap_count == 1;
}

/* ----------------------------------------------------------- test OD */

static const tu_od_row_t layout_a[] = {
    { 0x1010, 0, CO_OBJECT_ARRAY, CO_TYPE_UNSIGNED8, CO_ACCESS_RO, 0, 1, 4, NULL, 0, 0 },
    { 0x1010, 1, CO_OBJECT_ARRAY, CO_TYPE_UNSIGNED32, CO_ACCESS_RW, 0, 4, 1, NULL, 0, 0 },
    { 0x1010, 2, CO_OBJECT_ARRAY, CO_TYPE_UNSIGNED32, CO_ACCESS_RW, 0, 4, 1, NULL, 0, 0 },
    { 0x1010, 3, CO_OBJECT_ARRAY, CO_TYPE_UNSIGNED32, CO_ACCESS_RW, 0, 4, 1, NULL, 0, 0 },
    { 0x1010, 4, CO_OBJECT_ARRAY, CO_TYPE_UNSIGNED32, CO_ACCESS_RW, 0, 4, 1, NULL, 0, 0 },
    { 0x1011, 0, CO_OBJECT_ARRAY, CO_TYPE_UNSIGNED8, CO_ACCESS_RO, 0, 1, 4, NULL, 0, 0 },
    { 0x1011, 1, CO_OBJECT_ARRAY, CO_TYPE_UNSIGNED32, CO_ACCESS_RW, 0, 4, 1, NULL, 0, 0 },
    { 0x1011, 2, CO_OBJECT_ARRAY, CO_TYPE_UNSIGNED32, CO_ACCESS_RW, 0, 4, 1, NULL, 0, 0 },
    { 0x1011, 3, CO_OBJECT_ARRAY, CO_TYPE_UNSIGNED32, CO_ACCESS_RW, 0, 4, 1, NULL, 0, 0 },
    { 0x1011, 4, CO_OBJECT_ARRAY, CO_TYPE_UNSIGNED32, CO_ACCESS_RW, 0, 4, 1, NULL, 0, 0 },
    { 0x1017, 0, CO_OBJECT_VAR, CO_TYPE_UNSIGNED16, CO_ACCESS_RW, CO_OD_STORE, 2, 1000, NULL,
      0, 0 },
    { 0x2000, 0, CO_OBJECT_VAR, CO_TYPE_UNSIGNED8, CO_ACCESS_RW, CO_OD_STORE | CO_OD_HAS_MAX, 1,
      5, NULL, 0, 200 },
    { 0x2001, 0, CO_OBJECT_VAR, CO_TYPE_VISIBLE_STRING, CO_ACCESS_RW, CO_OD_STORE, 16, 0, "abc",
      0, 0 },
    { 0x2002, 0, CO_OBJECT_VAR, CO_TYPE_UNSIGNED32, CO_ACCESS_RW, 0, 4, 7, NULL, 0, 0 },
    { 0x6000, 0, CO_OBJECT_VAR, CO_TYPE_UNSIGNED32, CO_ACCESS_RW, CO_OD_STORE, 4, 100, NULL, 0, 0 },
};

/* Next firmware: 0x2000 became INTEGER8, 0x2001 is gone, 0x6001 is new. */
static const tu_od_row_t layout_b[] = {
    { 0x1017, 0, CO_OBJECT_VAR, CO_TYPE_UNSIGNED16, CO_ACCESS_RW, CO_OD_STORE, 2, 1000, NULL,
      0, 0 },
    { 0x2000, 0, CO_OBJECT_VAR, CO_TYPE_INTEGER8, CO_ACCESS_RW, CO_OD_STORE, 1, 6, NULL, 0, 0 },
    { 0x6000, 0, CO_OBJECT_VAR, CO_TYPE_UNSIGNED32, CO_ACCESS_RW, CO_OD_STORE, 4, 100, NULL, 0, 0 },
    { 0x6001, 0, CO_OBJECT_VAR, CO_TYPE_UNSIGNED32, CO_ACCESS_RW, CO_OD_STORE, 4, 55, NULL, 0, 0 },
};

#define N_ENTRIES 32
#define POOL 1024
#define BUF 1024

typedef struct fixture {
    co_od_t od;
    co_od_entry_t entries[N_ENTRIES];
    uint8_t pool[POOL];
    co_od_subscription_t subs[4];
    co_store_t store;
    uint8_t buf[BUF];
    co_store_file_t file;
    char dir[64];                 /* real temporary directory, "" if none */
    char path[128];
} fixture_t;

static fixture_t *fixture_new(const tu_od_row_t *defs, size_t n, const char *path)
{
    fixture_t *fx = calloc(1, sizeof *fx);
    assert_non_null(fx);
    co_od_init(&fx->od, CO_MODE_CLASSIC, fx->entries, N_ENTRIES, fx->pool, POOL, fx->subs, 4);
    tu_od_add_rows(&fx->od, defs, n);
    assert_true(co_od_seal(&fx->od, 1));
    assert_true(co_store_file_init(&fx->file, path));
    assert_true(co_store_init(&fx->store, &fx->od, co_store_file_backend(), &fx->file, fx->buf,
                              BUF));
    return fx;
}

static fixture_t *fixture_fake(fake_fs_t *fs)
{
    fixture_t *fx = fixture_new(layout_a, sizeof layout_a / sizeof layout_a[0], MAIN_PATH);
    fx->file.ops = &fake_ops;
    fx->file.ops_user = fs;
    return fx;
}

typedef struct vset {
    int64_t hb, m8;
    const char *str;
    int64_t unstored, a32;
} vset_t;

static const vset_t DEF = { 1000, 5, "abc", 7, 100 };
static const vset_t VA = { 1500, 150, "hello", 70, 0xA5A5A5A5 };
static const vset_t VB = { 2000, 151, "world, again", 71, 0x5A5A5A5A };

static void put_num(fixture_t *fx, uint16_t index, int64_t v)
{
    const co_od_entry_t *e = co_od_find(&fx->od, index, 0);
    uint8_t b[8];
    assert_non_null(e);
    tu_le_put(b, (uint64_t)v, e->size);
    assert_int_equal(co_od_put(&fx->od, index, 0, b, e->size), 0);
}

static int64_t get_num(fixture_t *fx, uint16_t index)
{
    uint8_t b[8];
    uint32_t n = 0;
    assert_int_equal(co_od_get(&fx->od, index, 0, b, sizeof b, &n), 0);
    return (int64_t)tu_le_get(b, n);
}

static void set_values(fixture_t *fx, const vset_t *v)
{
    put_num(fx, 0x1017, v->hb);
    put_num(fx, 0x2000, v->m8);
    assert_int_equal(co_od_put(&fx->od, 0x2001, 0, (const uint8_t *)v->str,
                               (uint32_t)strlen(v->str)), 0);
    put_num(fx, 0x2002, v->unstored);
    put_num(fx, 0x6000, v->a32);
}

static bool has_values(fixture_t *fx, const vset_t *v)
{
    uint8_t b[16];
    uint32_t n = 0;
    assert_int_equal(co_od_get(&fx->od, 0x2001, 0, b, sizeof b, &n), 0);
    return get_num(fx, 0x1017) == v->hb && get_num(fx, 0x2000) == v->m8 &&
           n == strlen(v->str) && memcmp(b, v->str, n) == 0 && get_num(fx, 0x6000) == v->a32;
}

static void expect_values(fixture_t *fx, const vset_t *v)
{
    assert_true(has_values(fx, v));
}

/* ------------------------------------------------ tests: fake file system */

static void test_file_init(void **state)
{
    co_store_file_t f;
    char longp[CO_STORE_FILE_PATH_MAX];
    (void)state;
    assert_false(co_store_file_init(&f, ""));
    assert_false(co_store_file_init(&f, "/var/lib/x/"));
    assert_false(co_store_file_init(&f, NULL));
    memset(longp, 'a', sizeof longp - 1);
    longp[sizeof longp - 1] = '\0';
    assert_false(co_store_file_init(&f, longp));
    longp[CO_STORE_FILE_PATH_MAX - 5] = '\0';   /* room for ".tmp" and the NUL */
    assert_true(co_store_file_init(&f, longp));
    longp[CO_STORE_FILE_PATH_MAX - 5] = 'a';
    longp[CO_STORE_FILE_PATH_MAX - 4] = '\0';
    assert_false(co_store_file_init(&f, longp));
    assert_true(co_store_file_init(&f, "p.bin"));
    assert_string_equal(f.dir_path, ".");
    assert_string_equal(f.tmp_path, "p.bin.tmp");
    assert_true(co_store_file_init(&f, "/p.bin"));
    assert_string_equal(f.dir_path, "/");
    assert_true(co_store_file_init(&f, "/var/lib/node/p.bin"));
    assert_string_equal(f.path, "/var/lib/node/p.bin");
    assert_string_equal(f.tmp_path, "/var/lib/node/p.bin.tmp");
    assert_string_equal(f.dir_path, "/var/lib/node");
    assert_ptr_equal(f.ops, co_store_file_posix_ops());
}

/* The exact call sequence of a save and of a load. */
static void test_save_sequence(void **state)
{
    static const char *const save_calls[] = { "open", "write", "fsync", "close", "rename",
                                              "open_dir", "fsync_dir", "close_dir" };
    static const char *const load_calls[] = { "open", "read", "read", "close" };
    fake_fs_t *fs = calloc(1, sizeof *fs);
    fixture_t *fx;
    const uint8_t *data = NULL;
    size_t i;
    (void)state;
    assert_non_null(fs);
    fs_init(fs);
    fx = fixture_fake(fs);
    set_values(fx, &VA);
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_ALL), 0);
    assert_int_equal(fs->log_count, 8);
    for (i = 0; i < 8; i++)
        assert_string_equal(fs->log[i], save_calls[i]);
    assert_int_equal(fs->open_flags, O_CREAT | O_TRUNC | O_WRONLY | O_CLOEXEC);
    assert_int_equal(fs->open_mode, 0600);
    assert_true(fs_quiet(fs));
    assert_int_equal(fs_content(fs, "p.bin.tmp", &data), -1);
    /* header, 4 records: 0x1017 (2 bytes), 0x2000 (1), 0x2001 ("hello"), 0x6000 (4) */
    assert_int_equal(fs_content(fs, "p.bin", &data), 28 + 4 * 9 + 2 + 1 + 5 + 4);
    assert_memory_equal(data, fx->store.image, 28 + 4 * 9 + 2 + 1 + 5 + 4);
    fs->log_count = 0;
    set_values(fx, &VB);
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_OK);
    expect_values(fx, &VA);
    assert_int_equal(fs->log_count, 4);
    for (i = 0; i < 4; i++)
        assert_string_equal(fs->log[i], load_calls[i]);
    assert_null(fx->file.last_failed);
    free(fx);
    free(fs);
}

/* Short writes and EINTR are continued; a write without progress fails. */
static void test_short_writes_and_eintr(void **state)
{
    fake_fs_t *fs = calloc(1, sizeof *fs);
    fixture_t *fx;
    const uint8_t *data = NULL;
    long len;
    (void)state;
    assert_non_null(fs);
    fs_init(fs);
    fx = fixture_fake(fs);
    set_values(fx, &VB);
    fs->max_write = 5;
    fs->eintr = true;
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_ALL), 0);
    assert_true(fs->writes > 20);
    len = fs_content(fs, "p.bin", &data);
    assert_true(len > 28);
    assert_memory_equal(data, fx->store.image, (size_t)len);
    set_values(fx, &VA);
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_OK);
    expect_values(fx, &VB);
    /* no progress: IO, the old file stays, the temp file goes */
    fs->eintr = false;
    fs->write_zero = true;
    set_values(fx, &VA);
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_ALL), CO_ABORT_HARDWARE);
    assert_string_equal(fx->file.last_failed, "write");
    assert_int_equal(fx->file.last_errno, EIO);
    assert_int_equal(fs_content(fs, "p.bin.tmp", &data), -1);
    fs->write_zero = false;
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_OK);
    expect_values(fx, &VB);
    free(fx);
    free(fs);
}

/* Each call of the save failing once while the machine goes on: IO, and the
 * old file untouched unless the rename already happened. */
static void test_single_failures(void **state)
{
    static const char *const failed_name[] = { "open", "write", "fsync", "close", "rename",
                                               "open_dir", "fsync_dir", NULL };
    fake_fs_t *base = calloc(1, sizeof *base), *fs = calloc(1, sizeof *fs);
    fixture_t *fx;
    unsigned k;
    (void)state;
    assert_non_null(base);
    assert_non_null(fs);
    fs_init(base);
    fx = fixture_fake(base);
    set_values(fx, &VA);
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_ALL), 0);
    for (k = 0; k < 8; k++) {
        const uint8_t *data;
        uint32_t r;
        fs_copy(fs, base);
        fs->fail_at = k;
        fs->fail_errno = k == 1 ? ENOSPC : EIO;
        fx->file.ops_user = fs;
        set_values(fx, &VB);
        r = co_store_save(&fx->store, CO_GROUP_ALL);
        if (failed_name[k] == NULL) {
            assert_int_equal(r, 0);   /* closing the fsynced directory may fail */
            assert_null(fx->file.last_failed);
        } else {
            assert_int_equal(r, CO_ABORT_HARDWARE);
            assert_string_equal(fx->file.last_failed, failed_name[k]);
            assert_int_equal(fx->file.last_errno, fs->fail_errno);
        }
        assert_int_equal(fs_content(fs, "p.bin.tmp", &data), -1);   /* never left behind */
        fs->fail_at = FS_NONE;
        set_values(fx, &DEF);
        assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_OK);
        /* before the rename (call 4) the old image stays */
        expect_values(fx, k <= 4 ? &VA : &VB);
    }
    free(fx);
    free(fs);
    free(base);
}

typedef struct cut_stats {
    unsigned scenarios, found_old, found_new, found_none;
} cut_stats_t;

/* Cut the power at every call of a save of VB over `base` (VA saved or
 * nothing), crash with every directory outcome and several data outcomes,
 * then load on the rebooted machine: exactly old or exactly new. */
static void cut_everywhere(fake_fs_t *base, bool old_exists, uint32_t max_write, bool eintr,
                           cut_stats_t *st)
{
    fake_fs_t *fs = calloc(1, sizeof *fs), *after = calloc(1, sizeof *after);
    fixture_t *fx;
    uint8_t old_img[BUF], new_img[BUF];
    long old_len = -1, new_len;
    const uint8_t *data = NULL;
    unsigned steps, k;

    assert_non_null(fs);
    assert_non_null(after);
    fx = fixture_fake(fs);
    if (old_exists) {
        old_len = fs_content(base, "p.bin", &data);
        assert_true(old_len > 0);
        memcpy(old_img, data, (size_t)old_len);
    }
    /* the complete save, to know its calls and its image */
    fs_copy(fs, base);
    fs->max_write = max_write;
    fs->eintr = eintr;
    set_values(fx, &VB);
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_ALL), 0);
    steps = fs->step;
    new_len = fs_content(fs, "p.bin", &data);
    assert_true(new_len > 0);
    memcpy(new_img, data, (size_t)new_len);
    assert_true(old_len != new_len || memcmp(old_img, new_img, (size_t)new_len) != 0);

    for (k = 0; k <= steps; k++) {
        uint32_t r;
        unsigned snap;
        fs_copy(fs, base);
        fs->max_write = max_write;
        fs->eintr = eintr;
        fs->cut_at = k;
        set_values(fx, &VB);
        r = co_store_save(&fx->store, CO_GROUP_ALL);
        /* only the directory's close may fail unnoticed: it comes last */
        if (k + 1 < steps)
            assert_int_equal(r, CO_ABORT_HARDWARE);
        else
            assert_int_equal(r, 0);
        for (snap = 0; snap < fs->snap_count; snap++) {
            uint64_t seed;
            for (seed = 0; seed < 6; seed++) {
                long len;
                co_store_status_t ls;
                fs_crash(fs, snap, seed + 1000u * k + 100000u * snap, after);
                st->scenarios++;
                len = fs_content(after, "p.bin", &data);
                if (len < 0) {
                    assert_false(old_exists);   /* a saved file never vanishes */
                    assert_int_not_equal(r, 0);
                    st->found_none++;
                } else if (old_exists && len == old_len && memcmp(data, old_img, (size_t)len) == 0) {
                    assert_int_not_equal(r, 0);   /* a save that said OK is durable */
                    st->found_old++;
                } else {
                    if (len != new_len || memcmp(data, new_img, (size_t)len) != 0)
                        fail_msg("cut at call %u (%s), snapshot %u: p.bin is neither old nor "
                                 "new (%ld bytes)", k, k < fs->log_count ? fs->log[k] : "-",
                                 snap, len);
                    st->found_new++;
                }
                /* the rebooted node */
                fx->file.ops_user = after;
                set_values(fx, &DEF);
                ls = co_store_load(&fx->store, CO_GROUP_ALL);
                if (len < 0) {
                    assert_int_equal(ls, CO_STORE_EMPTY);
                    expect_values(fx, &DEF);
                } else {
                    assert_int_equal(ls, CO_STORE_OK);
                    assert_true(has_values(fx, &VB) || (old_exists && has_values(fx, &VA)));
                }
                fx->file.ops_user = fs;
            }
        }
    }
    free(fx);
    free(after);
    free(fs);
}

static void test_power_cut_everywhere(void **state)
{
    fake_fs_t *empty = calloc(1, sizeof *empty), *saved = calloc(1, sizeof *saved);
    fake_fs_t *stale = calloc(1, sizeof *stale), *scratch = calloc(1, sizeof *scratch);
    fixture_t *fx;
    cut_stats_t st;
    uint8_t junk[300];
    const uint8_t *data = NULL;
    long len;
    (void)state;
    assert_non_null(empty);
    assert_non_null(saved);
    assert_non_null(stale);
    assert_non_null(scratch);
    fs_init(empty);
    /* a machine where the VA image was written long ago (built directly, so
     * this test does not lean on the save it tests) */
    fs_init(scratch);
    fx = fixture_fake(scratch);
    set_values(fx, &VA);
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_ALL), 0);
    free(fx);
    len = fs_content(scratch, "p.bin", &data);
    assert_true(len > 0);
    fs_init(saved);
    fs_add_file(saved, "p.bin", data, (uint32_t)len);
    free(scratch);
    /* ... and one that also has a stale temp file, longer than any image,
     * from a cut long ago (the save truncates it) */
    fs_copy(stale, saved);
    memset(junk, 0xC3, sizeof junk);
    fs_add_file(stale, "p.bin.tmp", junk, sizeof junk);

    memset(&st, 0, sizeof st);
    cut_everywhere(empty, false, 0, false, &st);
    cut_everywhere(saved, true, 0, false, &st);
    cut_everywhere(saved, true, 7, false, &st);      /* many small writes */
    cut_everywhere(saved, true, 11, true, &st);      /* ... interrupted ones too */
    cut_everywhere(stale, true, 0, false, &st);
    print_message("power cuts: %u crash outcomes, old %u, new %u, none %u\n", st.scenarios,
                  st.found_old, st.found_new, st.found_none);
    /* every outcome happened somewhere */
    assert_true(st.found_old > 0);
    assert_true(st.found_new > 0);
    assert_true(st.found_none > 0);
    free(stale);
    free(saved);
    free(empty);
}

/* A temp file left by a cut is ignored by the load and replaced by a save. */
static void test_stale_temp_file(void **state)
{
    fake_fs_t *fs = calloc(1, sizeof *fs), *after = calloc(1, sizeof *after);
    fixture_t *fx;
    const uint8_t *data = NULL;
    (void)state;
    assert_non_null(fs);
    assert_non_null(after);
    fs_init(fs);
    fx = fixture_fake(fs);
    set_values(fx, &VA);
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_ALL), 0);
    set_values(fx, &VB);
    fs->cut_at = fs->step + 3;   /* after open, write, fsync of the temp file */
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_ALL), CO_ABORT_HARDWARE);
    fs_crash(fs, fs->snap_count - 1, 1, after);
    assert_true(fs_content(after, "p.bin.tmp", &data) > 0);
    fx->file.ops_user = after;
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_OK);
    expect_values(fx, &VA);
    set_values(fx, &VB);
    put_num(fx, 0x1017, 3000);
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_ALL), 0);
    assert_int_equal(fs_content(after, "p.bin.tmp", &data), -1);
    set_values(fx, &DEF);
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_OK);
    assert_int_equal(get_num(fx, 0x1017), 3000);
    free(fx);
    free(after);
    free(fs);
}

/* ---------------------------------------------- tests: real file system */

static int setup_real(void **state)
{
    fixture_t *fx;
    char dir[64];
    const char *tmp = getenv("TMPDIR");
    snprintf(dir, sizeof dir, "%s/co_store_test.XXXXXX",
             tmp != NULL && strlen(tmp) < 32 ? tmp : "/tmp");
    assert_non_null(mkdtemp(dir));
    {
        char path[128];
        snprintf(path, sizeof path, "%s/params.bin", dir);
        fx = fixture_new(layout_a, sizeof layout_a / sizeof layout_a[0], path);
        memcpy(fx->path, path, sizeof path);
    }
    memcpy(fx->dir, dir, sizeof dir);
    *state = fx;
    return 0;
}

static int teardown_real(void **state)
{
    fixture_t *fx = *state;
    char p[160];
    (void)unlink(fx->path);
    snprintf(p, sizeof p, "%s.tmp", fx->path);
    (void)unlink(p);
    (void)rmdir(fx->path);   /* a test may have made a directory there */
    (void)rmdir(fx->dir);
    free(fx);
    return 0;
}

static void write_file(const char *path, const uint8_t *data, size_t n)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(data, 1, n, f), n);
    assert_int_equal(fclose(f), 0);
}

static size_t read_file(const char *path, uint8_t *buf, size_t cap)
{
    FILE *f = fopen(path, "rb");
    size_t n;
    assert_non_null(f);
    n = fread(buf, 1, cap, f);
    assert_int_equal(fclose(f), 0);
    return n;
}

static size_t save_va(fixture_t *fx, uint8_t *img)
{
    set_values(fx, &VA);
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_ALL), 0);
    return read_file(fx->path, img, BUF);
}

static void test_real_roundtrip(void **state)
{
    fixture_t *fx = *state;
    struct stat sb;
    char tmp[160];
    uint8_t img[BUF];
    size_t n;
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_EMPTY);
    n = save_va(fx, img);
    assert_int_equal(stat(fx->path, &sb), 0);
    assert_int_equal(sb.st_mode & 0777, 0600);
    assert_int_equal((size_t)sb.st_size, n);
    assert_memory_equal(img, fx->store.image, n);
    snprintf(tmp, sizeof tmp, "%s.tmp", fx->path);
    assert_int_not_equal(access(tmp, F_OK), 0);
    set_values(fx, &VB);
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_OK);
    expect_values(fx, &VA);
    assert_int_equal(get_num(fx, 0x2002), DEF.unstored);
    /* replaced by a newer save */
    set_values(fx, &VB);
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_ALL), 0);
    set_values(fx, &DEF);
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_OK);
    expect_values(fx, &VB);
}

static void test_real_damaged(void **state)
{
    fixture_t *fx = *state;
    uint8_t img[BUF];
    size_t n = save_va(fx, img);
    img[n - 3] ^= 0x10;   /* a payload byte */
    write_file(fx->path, img, n);
    set_values(fx, &VB);
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_DAMAGED);
    assert_int_equal(fx->store.last_load, CO_STORE_DAMAGED);
    expect_values(fx, &DEF);
    /* truncated */
    img[n - 3] ^= 0x10;
    write_file(fx->path, img, n - 1);
    set_values(fx, &VB);
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_DAMAGED);
    expect_values(fx, &DEF);
    write_file(fx->path, img, 0);
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_DAMAGED);
    /* intact again */
    write_file(fx->path, img, n);
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_OK);
    expect_values(fx, &VA);
}

static void test_real_foreign(void **state)
{
    fixture_t *fx = *state;
    uint8_t img[BUF];
    size_t n = save_va(fx, img);
    img[1] = 'x';
    write_file(fx->path, img, n);
    set_values(fx, &VB);
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_FOREIGN);
    expect_values(fx, &DEF);
    write_file(fx->path, (const uint8_t *)"[DeviceInfo]\nVendorName=x\n", 26);
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_FOREIGN);
}

/* A file from another OD layout: what still fits loads, the rest is counted. */
static void test_real_other_layout(void **state)
{
    fixture_t *fa = *state;
    fixture_t *fb = fixture_new(layout_b, sizeof layout_b / sizeof layout_b[0], fa->path);
    uint8_t img[BUF];
    (void)save_va(fa, img);
    put_num(fb, 0x6001, 1);
    assert_int_equal(co_store_load(&fb->store, CO_GROUP_ALL), CO_STORE_OK);
    assert_int_equal(fb->store.records_skipped, 2);   /* 0x2000 other type, 0x2001 gone */
    assert_int_equal(get_num(fb, 0x1017), VA.hb);
    assert_int_equal(get_num(fb, 0x6000), VA.a32);
    assert_int_equal(get_num(fb, 0x2000), 6);
    assert_int_equal(get_num(fb, 0x6001), 55);
    free(fb);
}

static void test_real_too_big(void **state)
{
    fixture_t *fx = *state;
    uint8_t junk[BUF];
    memset(junk, 'j', sizeof junk);
    write_file(fx->path, junk, fx->store.image_capacity + 1u);
    set_values(fx, &VB);
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_TOO_BIG);
    assert_int_equal(fx->store.last_load, CO_STORE_TOO_BIG);
    expect_values(fx, &DEF);
    /* exactly the capacity is read (and then judged) */
    write_file(fx->path, junk, fx->store.image_capacity);
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_FOREIGN);
    /* a partial save over a too-big file keeps nothing of it */
    set_values(fx, &VA);
    write_file(fx->path, junk, fx->store.image_capacity + 1u);
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_APPLICATION), 0);
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_OK);
    assert_int_equal(get_num(fx, 0x6000), VA.a32);
    assert_int_equal(get_num(fx, 0x1017), DEF.hb);
}

static void test_real_io_errors(void **state)
{
    fixture_t *fx = *state;
    fixture_t *gone;
    char p[160];
    /* the path is a directory: open works, read fails */
    assert_int_equal(mkdir(fx->path, 0700), 0);
    set_values(fx, &VB);
    assert_int_equal(co_store_load(&fx->store, CO_GROUP_ALL), CO_STORE_IO);
    assert_int_equal(fx->store.last_load, CO_STORE_IO);
    assert_string_equal(fx->file.last_failed, "read");
    assert_int_equal(fx->file.last_errno, EISDIR);
    expect_values(fx, &DEF);
    /* ... and a save cannot rename over it: IO, the temp file removed */
    set_values(fx, &VA);
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_ALL), CO_ABORT_HARDWARE);
    assert_string_equal(fx->file.last_failed, "rename");
    snprintf(p, sizeof p, "%s.tmp", fx->path);
    assert_int_not_equal(access(p, F_OK), 0);
    /* a partial save must read the old image first: refused */
    assert_int_equal(co_store_save(&fx->store, CO_GROUP_COMMUNICATION), CO_ABORT_HARDWARE);
    assert_string_equal(fx->file.last_failed, "read");
    assert_int_equal(rmdir(fx->path), 0);
    /* a directory that does not exist */
    snprintf(p, sizeof p, "%s/missing/params.bin", fx->dir);
    gone = fixture_new(layout_a, sizeof layout_a / sizeof layout_a[0], p);
    assert_int_equal(co_store_load(&gone->store, CO_GROUP_ALL), CO_STORE_EMPTY);
    assert_int_equal(co_store_save(&gone->store, CO_GROUP_ALL), CO_ABORT_HARDWARE);
    assert_string_equal(gone->file.last_failed, "open");
    assert_int_equal(gone->file.last_errno, ENOENT);
    free(gone);
}

/* Every status of co_store_status_t comes out of the file backend, and
 * last_load always says what the last load found. */
static void test_real_every_status(void **state)
{
    fixture_t *fx = *state;
    bool seen[6] = { false, false, false, false, false, false };
    uint8_t img[BUF], junk[BUF];
    size_t n, i;
    co_store_status_t st;

    st = co_store_load(&fx->store, CO_GROUP_ALL);
    seen[st] = true;
    assert_int_equal(st, CO_STORE_EMPTY);
    n = save_va(fx, img);
    st = co_store_load(&fx->store, CO_GROUP_ALL);
    seen[st] = true;
    assert_int_equal(st, CO_STORE_OK);
    img[n / 2] ^= 1;
    write_file(fx->path, img, n);
    st = co_store_load(&fx->store, CO_GROUP_ALL);
    seen[st] = true;
    assert_int_equal(st, CO_STORE_DAMAGED);
    img[0] = 0;
    write_file(fx->path, img, n);
    st = co_store_load(&fx->store, CO_GROUP_ALL);
    seen[st] = true;
    assert_int_equal(st, CO_STORE_FOREIGN);
    memset(junk, 0, sizeof junk);
    write_file(fx->path, junk, sizeof junk);
    st = co_store_load(&fx->store, CO_GROUP_ALL);
    seen[st] = true;
    assert_int_equal(st, CO_STORE_TOO_BIG);
    assert_int_equal(unlink(fx->path), 0);
    assert_int_equal(mkdir(fx->path, 0700), 0);
    st = co_store_load(&fx->store, CO_GROUP_ALL);
    seen[st] = true;
    assert_int_equal(st, CO_STORE_IO);
    assert_int_equal(fx->store.last_load, CO_STORE_IO);
    assert_int_equal(rmdir(fx->path), 0);
    for (i = 0; i < 6; i++)
        assert_true(seen[i]);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_file_init),
        cmocka_unit_test(test_save_sequence),
        cmocka_unit_test(test_short_writes_and_eintr),
        cmocka_unit_test(test_single_failures),
        cmocka_unit_test(test_power_cut_everywhere),
        cmocka_unit_test(test_stale_temp_file),
        cmocka_unit_test_setup_teardown(test_real_roundtrip, setup_real, teardown_real),
        cmocka_unit_test_setup_teardown(test_real_damaged, setup_real, teardown_real),
        cmocka_unit_test_setup_teardown(test_real_foreign, setup_real, teardown_real),
        cmocka_unit_test_setup_teardown(test_real_other_layout, setup_real, teardown_real),
        cmocka_unit_test_setup_teardown(test_real_too_big, setup_real, teardown_real),
        cmocka_unit_test_setup_teardown(test_real_io_errors, setup_real, teardown_real),
        cmocka_unit_test_setup_teardown(test_real_every_status, setup_real, teardown_real),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
