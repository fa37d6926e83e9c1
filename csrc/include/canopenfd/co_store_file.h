/* File backend of co_store (POSIX; Windows too): the image lives in one file
 * that is replaced atomically, so after a power cut at any moment a load
 * finds either the old image or the new one, never a mix.
 *
 * save: write "<path>.tmp" (created 0600, truncated), fsync it, close it,
 *       rename it over <path>, fsync the directory. A failure before the rename
 *       leaves <path> untouched and removes the temp file. A failure of the
 *       final directory fsync is reported (CO_STORE_IO) although the new file
 *       may already be in place: after a crash the load finds old or new.
 * load: read <path> whole: missing -> CO_STORE_EMPTY, larger than the
 *       capacity -> CO_STORE_TOO_BIG, any other failure -> CO_STORE_IO. A temp
 *       file left by a cut is ignored (the next save truncates it).
 *
 * Windows: the same sequence over the CRT (_wopen in binary mode, _commit
 * for fsync) and MoveFileExW(REPLACE_EXISTING | WRITE_THROUGH) for the
 * rename, which returns once the move is on disk: there is no directory to
 * fsync, so its ops have no open_dir.
 *
 * Every system call goes through `ops`, so tests can replace them (fault and
 * power-cut simulation). The functions follow the system calls: -1 and errno
 * on failure. */
#ifndef CO_STORE_FILE_H
#define CO_STORE_FILE_H

#include <stddef.h>

#include "canopenfd/co_store.h"

/* The system calls' types: mode_t and ssize_t on POSIX; the Windows CRT
 * (MSVC) has neither. */
#if defined(_WIN32)
#include <stdint.h>
typedef int co_store_file_mode_t;
typedef intptr_t co_store_file_ssize_t;
#else
#include <sys/types.h>
typedef mode_t co_store_file_mode_t;
typedef ssize_t co_store_file_ssize_t;
#endif

enum { CO_STORE_FILE_PATH_MAX = 4096 };

typedef struct co_store_file_ops {
    int (*open)(void *user, const char *path, int flags, co_store_file_mode_t mode);
    /* Open a directory to fsync it (O_RDONLY | O_DIRECTORY); NULL: the
     * rename is durable by itself (Windows), no directory is synced. */
    int (*open_dir)(void *user, const char *path);
    co_store_file_ssize_t (*read)(void *user, int fd, void *buf, size_t n);
    co_store_file_ssize_t (*write)(void *user, int fd, const void *buf, size_t n);
    int (*fsync)(void *user, int fd);
    int (*close)(void *user, int fd);
    int (*rename)(void *user, const char *from, const char *to);
    int (*unlink)(void *user, const char *path);
} co_store_file_ops_t;

typedef struct co_store_file {
    char path[CO_STORE_FILE_PATH_MAX];
    char tmp_path[CO_STORE_FILE_PATH_MAX];   /* path + ".tmp" */
    char dir_path[CO_STORE_FILE_PATH_MAX];   /* the directory holding path */
    const co_store_file_ops_t *ops;          /* co_store_file_system_ops() by default */
    void *ops_user;
    int last_errno;                          /* errno of the last failure, 0 if none */
    const char *last_failed;                 /* name of the call that failed, or NULL */
} co_store_file_t;

/* False when the path is empty or too long (room for ".tmp" is needed). */
bool co_store_file_init(co_store_file_t *f, const char *path);
/* The backend; its `user` is the co_store_file_t. */
const co_store_backend_t *co_store_file_backend(void);
/* The real system calls (POSIX, or their Windows equivalents). */
const co_store_file_ops_t *co_store_file_system_ops(void);
#if !defined(_WIN32)
/* The POSIX calls: the same as co_store_file_system_ops() (older name). */
const co_store_file_ops_t *co_store_file_posix_ops(void);
#endif

#endif
