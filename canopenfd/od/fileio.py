"""Reading device description files safely, and picking the right reader.

Files come from vendors and from the internet: a size cap (16 MiB, far above
any real EDS/XDD, which are kilobytes to a few MiB) stops a runaway file or
/dev/zero before it is read, and every failure becomes an `OdFileError`
naming the file.
"""

from __future__ import annotations

import os
from typing import IO, Optional, Tuple, Union

from .errors import OdFileError

MAX_FILE_SIZE = 16 * 1024 * 1024

Source = Union[str, "os.PathLike[str]", IO[str], IO[bytes]]

EDS_SUFFIXES = (".eds", ".dcf")
XDD_SUFFIXES = (".xdd", ".xdc")


def source_name(source: Source) -> str:
    """The name used in messages: the file's path as given (a user with a
    folder of vendor files needs to know which one), or '<stream>'."""
    if isinstance(source, (str, os.PathLike)):
        return os.fspath(source)
    name = getattr(source, "name", None)
    return name if isinstance(name, str) else "<stream>"


def read_source(source: Source, limit: int = MAX_FILE_SIZE) -> Tuple[Union[bytes, str], str]:
    """(content, name): bytes from a path or binary stream, str from a text stream."""
    name = source_name(source)
    if isinstance(source, (str, os.PathLike)):
        path = os.fspath(source)
        try:
            if os.path.isdir(path):
                raise OdFileError("is a directory, not a file", name)
            size = os.path.getsize(path)
            if size > limit:
                raise OdFileError(_too_big(size, limit), name)
            with open(path, "rb") as handle:
                data: Union[bytes, str] = handle.read(limit + 1)
        except FileNotFoundError:
            raise OdFileError("no such file", name) from None
        except OSError as exc:
            raise OdFileError(f"cannot read: {exc.strerror or exc}", name) from None
    else:
        try:
            data = source.read(limit + 1)
        except (OSError, UnicodeDecodeError, ValueError) as exc:
            raise OdFileError(f"cannot read: {exc}", name) from None
        if not isinstance(data, (bytes, str)):
            raise OdFileError(f"read() returned {type(data).__name__}, "
                              f"expected bytes or str", name)
    if len(data) > limit:
        raise OdFileError(_too_big(None, limit), name)
    return data, name


def _too_big(size: Optional[int], limit: int) -> str:
    what = f"{size / 1048576:.1f} MiB" if size is not None else "more than that"
    return (f"file is {what}; device description files are limited to "
            f"{limit // 1048576} MiB")


def detect_format(name: str, data: Union[bytes, str]) -> str:
    """'eds' or 'xdd', by extension (.eds/.dcf, .xdd/.xdc), else by content:
    XML starts with '<' (after a BOM and blanks), an INI file with '[' or ';'."""
    lowered = name.lower()
    if lowered.endswith(EDS_SUFFIXES):
        return "eds"
    if lowered.endswith(XDD_SUFFIXES):
        return "xdd"
    head = data[:4096]
    if isinstance(head, bytes):
        if head.startswith((b"\xff\xfe", b"\xfe\xff")):
            head = head.decode("utf-16", errors="replace")
        else:
            head = head.decode("latin-1")
    head = head.lstrip("\ufeff \t\r\n")
    if head.startswith("<"):
        return "xdd"
    if head.startswith(("[", ";", "#")):
        return "eds"
    if not head:
        raise OdFileError("the file is empty", name)
    raise OdFileError("unknown file kind: expected an EDS/DCF (INI text) or an XDD/XDC "
                      "(XML); name it .eds, .dcf, .xdd or .xdc", name)
