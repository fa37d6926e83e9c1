/* File backend of co_store (Linux/POSIX): the image lives in one file that is
 * replaced atomically, so after a power cut at any moment a load finds either
 * the old image or the new one, never a mix.
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
 * Every system call goes through `ops`, so tests can replace them (fault and
 * power-cut simulation). The functions follow the system calls: -1 and errno
 * on failure. */
#ifndef CO_STORE_FILE_H
#define CO_STORE_FILE_H

#include <stddef.h>
#include <sys/types.h>

#include "canopenfd/co_store.h"

enum { CO_STORE_FILE_PATH_MAX = 4096 };

typedef struct co_store_file_ops {
    int (*open)(void *user, const char *path, int flags, mode_t mode);
    /* Open a directory to fsync it (O_RDONLY | O_DIRECTORY). */
    int (*open_dir)(void *user, const char *path);
    ssize_t (*read)(void *user, int fd, void *buf, size_t n);
    ssize_t (*write)(void *user, int fd, const void *buf, size_t n);
    int (*fsync)(void *user, int fd);
    int (*close)(void *user, int fd);
    int (*rename)(void *user, const char *from, const char *to);
    int (*unlink)(void *user, const char *path);
} co_store_file_ops_t;

typedef struct co_store_file {
    char path[CO_STORE_FILE_PATH_MAX];
    char tmp_path[CO_STORE_FILE_PATH_MAX];   /* path + ".tmp" */
    char dir_path[CO_STORE_FILE_PATH_MAX];   /* the directory holding path */
    const co_store_file_ops_t *ops;          /* co_store_file_posix_ops() by default */
    void *ops_user;
    int last_errno;                          /* errno of the last failure, 0 if none */
    const char *last_failed;                 /* name of the call that failed, or NULL */
} co_store_file_t;

/* False when the path is empty or too long (room for ".tmp" is needed). */
bool co_store_file_init(co_store_file_t *f, const char *path);
/* The backend; its `user` is the co_store_file_t. */
const co_store_backend_t *co_store_file_backend(void);
/* The real system calls. */
const co_store_file_ops_t *co_store_file_posix_ops(void);

#endif
