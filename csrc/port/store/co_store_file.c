/* File backend of co_store (see co_store_file.h).
 *
 * Why this sequence: rename() replaces the name atomically, but only data
 * that reached the disk can be trusted after a crash. So the temp file is
 * fsynced before the rename (otherwise the new name could point at a file
 * whose blocks never made it: a truncated or zero-filled image), and the
 * directory is fsynced after it (otherwise the rename itself may be lost and a
 * "successful" save comes back as the old image after a power cut). */
#if defined(__linux__)
#define _GNU_SOURCE   /* O_CLOEXEC, O_DIRECTORY, fsync under -std=c99 */
#endif

#include "canopenfd/co_store_file.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <string.h>

#if defined(_WIN32)
#ifndef WIN32_LEAN_AND_MEAN
#define WIN32_LEAN_AND_MEAN
#endif
#include <windows.h>
#include <io.h>
#include <sys/stat.h>
#else
#include <sys/stat.h>
#include <unistd.h>
#endif

/* The CRT spells the open flags with a leading underscore only. */
#ifndef O_CREAT
#define O_CREAT _O_CREAT
#define O_TRUNC _O_TRUNC
#define O_WRONLY _O_WRONLY
#define O_RDONLY _O_RDONLY
#endif
#ifndef O_CLOEXEC
#define O_CLOEXEC 0   /* Windows: _O_NOINHERIT is added by system_open */
#endif

#if !defined(_WIN32)
/* ------------------------------------------------------- real system calls */

static int posix_open(void *user, const char *path, int flags, mode_t mode)
{
    (void)user;
    return open(path, flags, mode);
}

static int posix_open_dir(void *user, const char *path)
{
    (void)user;
    return open(path, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
}

static ssize_t posix_read(void *user, int fd, void *buf, size_t n)
{
    (void)user;
    return read(fd, buf, n);
}

static ssize_t posix_write(void *user, int fd, const void *buf, size_t n)
{
    (void)user;
    return write(fd, buf, n);
}

static int posix_fsync(void *user, int fd)
{
    (void)user;
    return fsync(fd);
}

static int posix_close(void *user, int fd)
{
    (void)user;
    return close(fd);
}

static int posix_rename(void *user, const char *from, const char *to)
{
    (void)user;
    return rename(from, to);
}

static int posix_unlink(void *user, const char *path)
{
    (void)user;
    return unlink(path);
}

static const co_store_file_ops_t system_ops = {
    posix_open, posix_open_dir, posix_read, posix_write,
    posix_fsync, posix_close, posix_rename, posix_unlink
};

const co_store_file_ops_t *co_store_file_posix_ops(void)
{
    return &system_ops;
}

#else
/* -------------------------------------------- real system calls (Windows) */

/* Paths come as UTF-8 (Python's str); Windows takes them as UTF-16. */
static bool wide_path(const char *path, wchar_t *out, int capacity)
{
    if (MultiByteToWideChar(CP_UTF8, MB_ERR_INVALID_CHARS, path, -1, out, capacity) == 0) {
        errno = ENAMETOOLONG;
        return false;
    }
    return true;
}

static int win_open(void *user, const char *path, int flags, co_store_file_mode_t mode)
{
    (void)user;
    wchar_t wide[CO_STORE_FILE_PATH_MAX];
    if (!wide_path(path, wide, CO_STORE_FILE_PATH_MAX)) {
        return -1;
    }
    /* binary: text mode would rewrite the image's 0x0A bytes */
    return _wopen(wide, flags | _O_BINARY | _O_NOINHERIT,
                  (mode & 0200) ? (_S_IREAD | _S_IWRITE) : _S_IREAD);
}

static co_store_file_ssize_t win_read(void *user, int fd, void *buf, size_t n)
{
    (void)user;
    return _read(fd, buf, n > 0x7FFFFFFFu ? 0x7FFFFFFFu : (unsigned)n);
}

static co_store_file_ssize_t win_write(void *user, int fd, const void *buf, size_t n)
{
    (void)user;
    return _write(fd, buf, n > 0x7FFFFFFFu ? 0x7FFFFFFFu : (unsigned)n);
}

static int win_fsync(void *user, int fd)
{
    (void)user;
    return _commit(fd);   /* FlushFileBuffers on the file's handle */
}

static int win_close(void *user, int fd)
{
    (void)user;
    return _close(fd);
}

static int win_rename(void *user, const char *from, const char *to)
{
    (void)user;
    wchar_t wide_from[CO_STORE_FILE_PATH_MAX];
    wchar_t wide_to[CO_STORE_FILE_PATH_MAX];
    if (!wide_path(from, wide_from, CO_STORE_FILE_PATH_MAX) ||
        !wide_path(to, wide_to, CO_STORE_FILE_PATH_MAX)) {
        return -1;
    }
    /* rename() refuses an existing target on Windows; WRITE_THROUGH returns
     * only once the move is on disk (what the directory fsync does on POSIX) */
    if (!MoveFileExW(wide_from, wide_to, MOVEFILE_REPLACE_EXISTING | MOVEFILE_WRITE_THROUGH)) {
        errno = GetLastError() == ERROR_ACCESS_DENIED ? EACCES : EIO;
        return -1;
    }
    return 0;
}

static int win_unlink(void *user, const char *path)
{
    (void)user;
    wchar_t wide[CO_STORE_FILE_PATH_MAX];
    if (!wide_path(path, wide, CO_STORE_FILE_PATH_MAX)) {
        return -1;
    }
    return _wunlink(wide);
}

static const co_store_file_ops_t system_ops = {
    win_open, NULL, win_read, win_write,
    win_fsync, win_close, win_rename, win_unlink
};
#endif

const co_store_file_ops_t *co_store_file_system_ops(void)
{
    return &system_ops;
}

/* ------------------------------------------------------------------- init */

bool co_store_file_init(co_store_file_t *f, const char *path)
{
    size_t n;
    const char *slash;

    if (f == NULL || path == NULL)
        return false;
    n = strlen(path);
    if (n == 0 || path[n - 1] == '/' || n + sizeof ".tmp" > CO_STORE_FILE_PATH_MAX)
        return false;
    memset(f, 0, sizeof *f);
    memcpy(f->path, path, n + 1);
    memcpy(f->tmp_path, path, n);
    memcpy(f->tmp_path + n, ".tmp", sizeof ".tmp");
    slash = strrchr(path, '/');
    if (slash == NULL) {
        memcpy(f->dir_path, ".", 2);
    } else if (slash == path) {
        memcpy(f->dir_path, "/", 2);
    } else {
        memcpy(f->dir_path, path, (size_t)(slash - path));
        f->dir_path[slash - path] = '\0';
    }
    f->ops = &system_ops;
    f->ops_user = NULL;
    return true;
}

/* ---------------------------------------------------------------- backend */

static co_store_status_t failed(co_store_file_t *f, const char *call, int err)
{
    f->last_errno = err != 0 ? err : EIO;
    f->last_failed = call;
    return CO_STORE_IO;
}

/* write() until everything is written: short writes go on, EINTR retries. */
static bool write_all(co_store_file_t *f, int fd, const uint8_t *data, uint32_t length, int *err)
{
    uint32_t done = 0;
    while (done < length) {
        co_store_file_ssize_t n = f->ops->write(f->ops_user, fd, data + done, length - done);
        if (n < 0) {
            if (errno == EINTR)
                continue;
            *err = errno;
            return false;
        }
        if (n == 0 || (size_t)n > length - done) {
            *err = EIO;   /* no progress (or nonsense): do not spin */
            return false;
        }
        done += (uint32_t)n;
    }
    return true;
}

static co_store_status_t file_save(void *user, const uint8_t *image, uint32_t length)
{
    co_store_file_t *f = user;
    const co_store_file_ops_t *ops = f->ops;
    int fd, dir, err = 0;

    f->last_errno = 0;
    f->last_failed = NULL;
    fd = ops->open(f->ops_user, f->tmp_path, O_CREAT | O_TRUNC | O_WRONLY | O_CLOEXEC, 0600);
    if (fd < 0)
        return failed(f, "open", errno);
    if (!write_all(f, fd, image, length, &err)) {
        (void)ops->close(f->ops_user, fd);
        (void)ops->unlink(f->ops_user, f->tmp_path);
        return failed(f, "write", err);
    }
    if (ops->fsync(f->ops_user, fd) != 0) {
        err = errno;
        (void)ops->close(f->ops_user, fd);
        (void)ops->unlink(f->ops_user, f->tmp_path);
        return failed(f, "fsync", err);
    }
    /* close can report a deferred write error (NFS): count it. Never retried:
     * on Linux the descriptor is gone even after EINTR. */
    if (ops->close(f->ops_user, fd) != 0) {
        err = errno;
        (void)ops->unlink(f->ops_user, f->tmp_path);
        return failed(f, "close", err);
    }
    if (ops->rename(f->ops_user, f->tmp_path, f->path) != 0) {
        err = errno;
        (void)ops->unlink(f->ops_user, f->tmp_path);
        return failed(f, "rename", err);
    }
    if (ops->open_dir == NULL)
        return CO_STORE_OK;   /* the rename is durable by itself (Windows) */
    dir = ops->open_dir(f->ops_user, f->dir_path);
    if (dir < 0)
        return failed(f, "open_dir", errno);
    if (ops->fsync(f->ops_user, dir) != 0) {
        err = errno;
        (void)ops->close(f->ops_user, dir);
        return failed(f, "fsync_dir", err);
    }
    (void)ops->close(f->ops_user, dir);   /* durable already: a close error changes nothing */
    return CO_STORE_OK;
}

/* read() until EOF or cap bytes into *got; false with *err on failure. */
static bool read_up_to(co_store_file_t *f, int fd, uint8_t *buf, uint32_t cap, uint32_t *got,
                       int *err)
{
    uint32_t done = 0;
    while (done < cap) {
        co_store_file_ssize_t n = f->ops->read(f->ops_user, fd, buf + done, cap - done);
        if (n < 0) {
            if (errno == EINTR)
                continue;
            *err = errno;
            return false;
        }
        if (n == 0)
            break;
        if ((size_t)n > cap - done) {
            *err = EIO;
            return false;
        }
        done += (uint32_t)n;
    }
    *got = done;
    return true;
}

static co_store_status_t file_load(void *user, uint8_t *image, uint32_t capacity,
                                   uint32_t *length)
{
    co_store_file_t *f = user;
    const co_store_file_ops_t *ops = f->ops;
    uint8_t extra;
    uint32_t got = 0, more = 0;
    bool ok;
    int fd, err = 0;

    f->last_errno = 0;
    f->last_failed = NULL;
    fd = ops->open(f->ops_user, f->path, O_RDONLY | O_CLOEXEC, 0);
    if (fd < 0) {
        if (errno == ENOENT)
            return CO_STORE_EMPTY;
        return failed(f, "open", errno);
    }
    ok = read_up_to(f, fd, image, capacity, &got, &err);
    /* Full: one more byte tells "exactly capacity" from "larger". */
    if (ok && got == capacity)
        ok = read_up_to(f, fd, &extra, 1, &more, &err);
    (void)ops->close(f->ops_user, fd);   /* read-only: nothing to lose */
    if (!ok)
        return failed(f, "read", err);
    if (more > 0)
        return CO_STORE_TOO_BIG;
    *length = got;
    return CO_STORE_OK;
}

static const co_store_backend_t file_backend = { file_save, file_load };

const co_store_backend_t *co_store_file_backend(void)
{
    return &file_backend;
}
