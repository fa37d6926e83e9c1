"""Transfers to one remote node, typed by its object dictionary:
`remote.usdo` / `remote.sdo` (RemoteAccess: keys by index, (index, sub),
"INDEX:SUB" or name; file-like streams) and `remote.od[key].raw` (RemoteValue).
"""

from __future__ import annotations

import tempfile
from types import TracebackType
from typing import Any, BinaryIO, Dict, Literal, Optional, Tuple, Type, Union, overload

from ..errors import ConfigurationError
from ..od import ODArray, ODRecord, ODVariable, ObjectDictionary
from ..od.datatypes import Value
from ..services.views import RemoteNodeView
from .client import DownloadSource, Key, Progress, Transfer, TransferClient, uploaded_bytes

__all__ = ["RemoteAccess", "RemoteObjects", "RemoteValue", "DownloadStream", "resolve"]

_NO_DATA = object()   # download(key, data) vs python-canopen's download(index, sub, data)


def resolve(key: Key, od: Optional[ObjectDictionary], where: str
            ) -> Tuple[int, int, Optional[ODVariable]]:
    """(index, sub, variable or None) of an index, (index, sub), "index:sub"
    text or (with an OD) a name."""
    if od is not None:
        try:
            entry = od[key]
        except KeyError:
            entry = None
        if isinstance(entry, ODVariable):
            return entry.index, entry.subindex, entry
        if entry is not None:
            shown = f"0x{key:04X}" if isinstance(key, int) else repr(key)
            raise ConfigurationError(f"{where}: {shown} ({entry.name!r}) is an ARRAY/RECORD; "
                                     f"give a sub-index, e.g. (0x{entry.index:04X}, 1)")
    if isinstance(key, tuple) and len(key) == 2 and all(isinstance(k, int) for k in key):
        index, sub = key
    elif isinstance(key, int) and not isinstance(key, bool):
        index, sub = key, 0
    elif isinstance(key, str) and ":" in key:
        text_index, _, text_sub = key.partition(":")
        try:
            index, sub = int(text_index, 16), int(text_sub, 16)
        except ValueError:
            raise ConfigurationError(f"{where}: {key!r} is not INDEX:SUB (hex)") from None
    else:
        raise ConfigurationError(
            f"{where}: {key!r} is not an index, (index, sub), 'INDEX:SUB'"
            + ("" if od is None else " or a name in the object dictionary"))
    if not 0 <= index <= 0xFFFF or not 0 <= sub <= 0xFF:
        raise ConfigurationError(f"{where}: 0x{index:X}:{sub:X} outside 0..0xFFFF:0..0xFF")
    variable = od.get_variable(index, sub) if od is not None else None
    return index, sub, variable


class RemoteAccess:
    """Transfers to one remote node (`remote.usdo` on fd lines, `remote.sdo`
    on classic lines): keys are an index, (index, sub), "INDEX:SUB" or, with
    the node's OD, a name."""

    def __init__(self, node: RemoteNodeView, client: TransferClient) -> None:
        self._node = node
        self._client = client

    def _key(self, key: Key) -> Tuple[int, int, Optional[ODVariable]]:
        return resolve(key, self._node.object_dictionary, f"node {self._node.node_id}")

    def start_upload(self, key: Key, **options: Any) -> Transfer:
        index, sub = self._upload_options(key, options)
        return self._client.start_upload(self._node.node_id, index, sub, **options)

    def start_download(self, key: Key, data: DownloadSource, **options: Any) -> Transfer:
        index, sub = self._download_options(key, options)
        return self._client.start_download(self._node.node_id, index, sub, data, **options)

    def upload(self, key: Key, subindex: Optional[int] = None, **options: Any) -> bytes:
        """The entry's bytes; `upload(0x1018, 1)` (python-canopen's order) works too."""
        index, sub = self._upload_options(self._with_sub(key, subindex, "upload"), options)
        return self._client.upload(self._node.node_id, index, sub, **options)

    def download(self, key: Key, data: Union[DownloadSource, int],
                 python_canopen_data: Any = _NO_DATA, **options: Any) -> None:
        """Write the entry; python-canopen's `download(index, subindex, data,
        force_segment=False)` works too."""
        if python_canopen_data is not _NO_DATA:
            if not isinstance(data, int) or isinstance(data, bool):
                raise ConfigurationError(
                    f"node {self._node.node_id}: download(index, subindex, data) needs an int "
                    f"sub-index second, got {data!r}")
            key, data = self._with_sub(key, data, "download"), python_canopen_data
        if isinstance(data, int):
            raise ConfigurationError(
                f"node {self._node.node_id}: download data must be bytes-like or an open "
                f"binary file, got {data!r} (python-canopen's order: download(index, "
                f"subindex, data))")
        if options.pop("force_segment", False):
            options.setdefault("mode", "segmented")
        index, sub = self._download_options(key, options)
        self._client.download(self._node.node_id, index, sub, data, **options)

    def _with_sub(self, key: Key, subindex: Optional[int], what: str) -> Key:
        if subindex is None:
            return key
        if not isinstance(key, int) or isinstance(key, bool) or \
                not isinstance(subindex, int) or isinstance(subindex, bool):
            raise ConfigurationError(
                f"node {self._node.node_id}: {what}(index, subindex) takes two ints, "
                f"got {key!r}, {subindex!r}")
        return (key, subindex)

    def __getitem__(self, key: Key) -> Union["RemoteValue", "_RemoteObject"]:
        """python-canopen's `node.sdo["Name"].raw`, `node.sdo[0x1018][1].raw`:
        the same as `node.od[key]` (needs the node's object dictionary)."""
        return RemoteObjects(self._node, self)[key]

    def _upload_options(self, key: Key, options: Dict[str, Any]) -> Tuple[int, int]:
        """index, sub of key; with the node's OD the entry's size (its largest,
        for strings and domains) goes into options as the size hint, so AUTO
        can pick a bulk upload for a big entry (USDO)."""
        index, sub, variable = self._key(key)
        if variable is not None and self._client.HINTS_UPLOAD_SIZE:
            size = variable.storage_size
            if 0 < size < 0xFFFFFFFF:
                options.setdefault("size_hint", size)
        return index, sub

    def _download_options(self, key: Key, options: Dict[str, Any]) -> Tuple[int, int]:
        """index, sub of key; with the node's OD the entry's data type goes into options."""
        index, sub, variable = self._key(key)
        if variable is not None and self._client.SENDS_DATA_TYPE:
            options.setdefault("data_type", int(variable.data_type))
        return index, sub

    async def aupload(self, key: Key, **options: Any) -> bytes:
        return uploaded_bytes(await self.start_upload(key, **options))

    async def adownload(self, key: Key, data: DownloadSource, **options: Any) -> None:
        await self.start_download(key, data, **options)

    @overload
    def open(self, key: Key, mode: Literal["rb"] = "rb", *,
             progress: Optional[Progress] = None, timeout: float = 1.0) -> BinaryIO: ...

    @overload
    def open(self, key: Key, mode: Literal["wb"], *, progress: Optional[Progress] = None,
             timeout: float = 1.0) -> DownloadStream: ...

    @overload
    def open(self, key: Key, mode: str, *, progress: Optional[Progress] = None,
             timeout: float = 1.0) -> Union[BinaryIO, DownloadStream]: ...

    def open(self, key: Key, mode: str = "rb", *, progress: Optional[Progress] = None,
             timeout: float = 1.0) -> Union[BinaryIO, DownloadStream]:
        """A file-like stream of a (large) entry. 'rb': the entry is uploaded
        into a temporary file first (never whole in memory), which is
        returned at offset 0. 'wb': writes go to a temporary file that is
        downloaded when the stream is closed (an abort raises from close())."""
        if mode == "rb":
            spool = tempfile.TemporaryFile()
            try:
                self.start_upload(key, file=spool, progress=progress, timeout=timeout).result()
            except BaseException:
                spool.close()
                raise
            spool.seek(0)
            return spool
        if mode == "wb":
            return DownloadStream(self, key, progress, timeout)
        raise ConfigurationError(f"node {self._node.node_id}: open() mode {mode!r} is not "
                                 "'rb' or 'wb'")


class DownloadStream:
    """Writer of RemoteAccess.open(key, 'wb'): spooled to disk, sent at close()."""

    def __init__(self, access: RemoteAccess, key: Key, progress: Optional[Progress],
                 timeout: float) -> None:
        self._access = access
        self._key = key
        self._progress = progress
        self._timeout = timeout
        self._spool = tempfile.TemporaryFile()
        self.closed = False

    def write(self, data: bytes) -> int:
        return self._spool.write(data)

    def writable(self) -> bool:
        return True

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        try:
            self._spool.seek(0)
            self._access.start_download(self._key, self._spool, progress=self._progress,
                                      timeout=self._timeout).result()
        finally:
            self._spool.close()

    def __enter__(self) -> "DownloadStream":
        return self

    def __exit__(self, kind: Optional[Type[BaseException]], value: Optional[BaseException],
                 traceback: Optional[TracebackType]) -> None:
        if kind is None:
            self.close()
        else:
            self.closed = True
            self._spool.close()


class RemoteValue:
    """One entry of a remote node, typed by its OD: `.raw` reads/writes the
    value (USDO on fd lines, SDO on classic lines), `.data` the bytes."""

    def __init__(self, node: RemoteNodeView, variable: ODVariable,
                 access: RemoteAccess) -> None:
        self.node = node
        self.variable = variable
        self._access = access

    def __repr__(self) -> str:
        return f"<RemoteValue {self.variable.where} {self.variable.qualname!r} of node " \
               f"{self.node.node_id}>"

    @property
    def data(self) -> bytes:
        return self._access.upload((self.variable.index, self.variable.subindex))

    @data.setter
    def data(self, data: bytes) -> None:
        self._access.download((self.variable.index, self.variable.subindex), data)

    @property
    def raw(self) -> Value:
        return self.variable.decode_raw(self.data)

    @raw.setter
    def raw(self, value: Value) -> None:
        self.data = self.variable.encode_raw(value)

    async def aget(self) -> Value:
        return self.variable.decode_raw(
            await self._access.aupload((self.variable.index, self.variable.subindex)))

    async def aset(self, value: Value) -> None:
        await self._access.adownload((self.variable.index, self.variable.subindex),
                                          self.variable.encode_raw(value))


class RemoteObjects:
    """`remote.od[key]`: RemoteValue of an entry of the node's OD."""

    def __init__(self, node: RemoteNodeView, access: RemoteAccess) -> None:
        self._node = node
        self._access = access

    def __getitem__(self, key: Key) -> Union["RemoteValue", "_RemoteObject"]:
        od = self._node.object_dictionary
        if od is None:
            raise ConfigurationError(
                f"node {self._node.node_id} has no object dictionary: add it with "
                f"line.add_node({self._node.node_id}, od=...) or read by index:sub "
                "(node.read / node.usdo / node.sdo)")
        entry = od[key]
        if isinstance(entry, ODVariable):
            return RemoteValue(self._node, entry, self._access)
        return _RemoteObject(self._node, entry, self._access)


class _RemoteObject:
    def __init__(self, node: RemoteNodeView, obj: Union[ODRecord, ODArray],
                 access: RemoteAccess) -> None:
        self._node = node
        self._object = obj
        self._access = access

    def __getitem__(self, sub: Union[int, str]) -> RemoteValue:
        return RemoteValue(self._node, self._object[sub], self._access)
