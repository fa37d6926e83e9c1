"""Replace a file so that after a power cut at any moment it holds the old
bytes or the new ones, never a mix: the same sequence as the C file backend
(csrc/port/store/co_store_file.c): write "<path>.tmp", fsync it, rename it over
the path, fsync the directory. A failure before the rename leaves the path
untouched and removes the temporary file; a reader ignores a ".tmp" a cut left.
"""

from __future__ import annotations

import os

__all__ = ["replace_file"]


def replace_file(path: str, data: bytes) -> None:
    """Write data to path atomically and durably; OSError when it could not."""
    tmp = path + ".tmp"
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | getattr(os, "O_CLOEXEC", 0),
                     0o600)
        try:
            view = memoryview(data)
            while view:
                written = os.write(fd, view)
                view = view[written:]
            # before the rename: else the new name may point at blocks never written
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
    _sync_directory(os.path.dirname(path) or ".")


def _sync_directory(directory: str) -> None:
    """Make the rename itself durable (POSIX; Windows has no directory handle
    to sync: its rename goes through the file system journal)."""
    if os.name != "posix":
        return
    fd = os.open(directory, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    try:
        os.fsync(fd)
    finally:
        os.close(fd)
