"""Client transfers of a line — the part USDO (fd lines, transfer.usdo) and
SDO (classic lines, transfer.sdo) share: starting, waiting (blocking, with
`await`, or not at all), cancelling, file sources and sinks, progress. The
transfer itself (every frame, toggle, counter, timeout, block or bulk flow)
runs in the C runtime: no Python per frame. The per-node views
(`remote.usdo` / `remote.sdo`, `remote.od[...]`) are in transfer.remote."""

from __future__ import annotations

import asyncio
import math
import logging
import os
import tempfile
import threading
import time
from typing import (TYPE_CHECKING, Any, BinaryIO, Callable, Dict, List, Optional, Tuple,
                    Union)

from .._binding.transfers import TransferRequest, memory_source
from ..errors import (ABORT_TEXT, AbortError, CanopenFDError, ClosedError, ConfigurationError,
                     TransferAbortError)
from ..od import ODVariable
from ..od.datatypes import DataType

if TYPE_CHECKING:  # pragma: no cover
    from ..line import Line

log = logging.getLogger(__name__)

#: Largest answer we accept to an upload of unknown size unless told (bytes).
DEFAULT_MAX_SIZE = 64 << 20
_DOMAIN = int(DataType.DOMAIN)
_WAIT_STEP_S = 0.5     # longest blocking wait in C (Ctrl-C is seen between steps)
_DISPATCHER_POLL_S = 0.002

Key = Union[int, str, Tuple[int, int]]
Progress = Callable[[int], None]


class Transfer:
    """One transfer in flight: wait with `result()`, `await` it, or
    `cancel()` it. Results: bytes (upload), None (download), a dict
    {node: bytes/None or UsdoAbortError} (USDO broadcast)."""

    def __init__(self, client: "TransferClient", handle: int, node: int, index: int, sub: int,
                 upload: bool, keep: Any, progress: Optional[Progress], what: str) -> None:
        self._client = client
        self._handle = handle
        self.node = node
        self.index = index
        self.subindex = sub
        self.upload = upload
        self._keep = keep                  # the download's buffer / file stays alive
        self._progress = progress
        self.what = what
        self._done = threading.Event()
        self._lock = threading.Lock()
        self._outcome: Optional[Tuple[Any, Optional[BaseException]]] = None
        self._callbacks: List[Callable[[], None]] = []
        #: Filled once finished: mode used ('expedited', 'segmented', 'bulk' /
        #: 'block'), bytes moved, the data type byte the server sent (USDO uploads).
        self.mode: Optional[str] = None
        self.transferred = 0
        self.data_type: Optional[int] = None

    def __repr__(self) -> str:
        state = "done" if self._done.is_set() else "running"
        return f"<Transfer {self.what} {state}>"

    # ------------------------------------------------------------ waiting
    def done(self) -> bool:
        return self._done.is_set() or self._client._finished(self._handle)

    def result(self, timeout: Optional[float] = None) -> Any:
        """Block until the transfer ended; its value, or the abort (UsdoAbortError /
        SdoAbortError). The
        transfer's own per-frame timeout ends it if the server goes silent,
        so no timeout is needed here; a given one raises TimeoutError and
        leaves the transfer running."""
        deadline = None if timeout is None else _now() + timeout
        on_dispatcher = self._client._on_dispatcher()
        while not self._done.is_set():
            remaining = None if deadline is None else deadline - _now()
            if remaining is not None and remaining <= 0:
                if self._client._finished(self._handle):
                    break
                raise TimeoutError(f"{self.what}: not finished after {timeout} s")
            step = _WAIT_STEP_S if remaining is None else min(_WAIT_STEP_S, remaining)
            if on_dispatcher:
                # the done event would come through this very thread: poll
                if self._client._finished(self._handle):
                    break
                self._done.wait(min(_DISPATCHER_POLL_S, step))
            elif self._client._wait(self._handle, step):
                break   # woken by the runtime thread itself, not via the event queue
        return self._collect()

    wait = result

    def __await__(self):
        loop = asyncio.get_running_loop()
        future = loop.create_future()

        def settle() -> None:
            if future.done():
                return
            try:
                future.set_result(self._collect())
            except BaseException as exc:  # noqa: BLE001 - handed to the awaiting task
                future.set_exception(exc)

        self._on_done(lambda: loop.call_soon_threadsafe(settle))
        return future.__await__()

    def cancel(self, code: Optional[int] = None) -> None:
        """Abort the transfer (the abort frame goes to the server); result()
        then raises the abort error with `code` (default: general error)."""
        self._client._cancel(self._handle, code, self.what)

    # ------------------------------------------------------------ machinery
    def _on_done(self, callback: Callable[[], None]) -> None:
        with self._lock:
            if not self._done.is_set():
                self._callbacks.append(callback)
                return
        callback()

    def _finish(self) -> None:
        """CO_EV_TRANSFER_DONE (dispatcher thread)."""
        with self._lock:
            self._done.set()
            callbacks, self._callbacks = self._callbacks, []
        for callback in callbacks:
            callback()

    def _collect(self) -> Any:
        with self._lock:
            if self._outcome is None:
                self._outcome = self._client._collect(self)
                self._keep = None
        value, error = self._outcome
        if error is not None:
            raise error
        return value


class TransferClient:
    """What the USDO and SDO clients of a line share (see UsdoClient, SdoClient).
    Every call names the server node; `RemoteNode.usdo` / `.sdo` fix the node
    and add the OD's names and types. Many transfers may run at once, from
    any threads."""

    #: protocol name in messages, mode names (index = the runtime's mode code)
    PROTOCOL = ""
    MODES: Tuple[str, ...] = ()
    #: the cancel code that means "general error"
    GENERAL_ERROR = 0

    def __init__(self, line: "Line") -> None:
        self.line = line
        self._lock = threading.Lock()
        self._transfers: Dict[int, Transfer] = {}

    def __repr__(self) -> str:
        return f"<{type(self).__name__} of {self.line!r}>"

    # ------------------------------------------------------------ per protocol
    def _ensure_client(self) -> None:
        """Set up what the protocol needs before the first transfer."""

    def _abort_error(self, code: int, node: int, index: int, sub: int, from_server: bool,
                     what: str) -> AbortError:
        """The exception for an abort `code` (a CiA 301 code here; USDO and
        SDO clients give their own exception classes)."""
        return TransferAbortError(code, ABORT_TEXT.get(code, "unknown abort code"),
                                  f"0x{code:08X}", self.PROTOCOL, node, index, sub,
                                  from_server, what)

    def _typed_download(self, variable: ODVariable, options: Dict[str, Any]) -> None:
        """Options a download typed by the remote node's OD adds."""

    # ------------------------------------------------------------ starting
    def start_upload(self, node: int, index: int, sub: int = 0, *,
                     timeout: float = 1.0, max_size: Optional[int] = None,
                     file: Optional[BinaryIO] = None,
                     progress: Optional[Progress] = None, size_hint: int = 0) -> Transfer:
        """Start reading index:sub of node; returns at once. `file`: an open
        binary file the data streams into (else memory, at most max_size).
        size_hint (SDO): the bytes expected, so AUTO can pick a block upload."""
        what = f"{self.PROTOCOL} upload 0x{index:04X}:{sub:02X} from node {node}"
        request = self._request(node, index, sub, True, timeout, what)
        if not 0 <= size_hint < 0xFFFFFFFF:
            raise ConfigurationError(f"{what}: size_hint {size_hint} outside 0..2^32-2")
        request.size = size_hint
        if max_size is not None:
            if not 0 < max_size <= 0xFFFFFFFF:
                raise ConfigurationError(f"{what}: max_size {max_size} outside 1..2^32-1")
            request.max_size = max_size
        if file is not None:
            request.fd, request.fd_offset = _file_target(file, what)
        request.progress = progress is not None
        return self._start(request, node, index, sub, True, file, progress, what)

    def start_download(self, node: int, index: int, sub: int, data: Any, *,
                       mode: str = "auto", data_type: Optional[int] = None,
                       timeout: float = 1.0,
                       progress: Optional[Progress] = None) -> Transfer:
        """Start writing `data` (bytes-like, or an open binary file read from
        its position to its end) to index:sub of node. mode: 'auto' (by the
        size), 'expedited', 'segmented', or 'bulk' (USDO) / 'block' (SDO).
        data_type (USDO): the CiA 301 type code sent (default DOMAIN 0x0F =
        raw bytes, accepted for any entry)."""
        what = f"{self.PROTOCOL} download 0x{index:04X}:{sub:02X} to node {node}"
        if mode not in self.MODES:
            raise ConfigurationError(f"{what}: mode {mode!r} is not one of "
                                     f"{', '.join(self.MODES)}")
        request = self._request(node, index, sub, False, timeout, what)
        request.mode = self.MODES.index(mode)
        request.data_type = _DOMAIN if data_type is None else _type_code(data_type, what)
        keep: Any
        if hasattr(data, "fileno") and hasattr(data, "seek"):
            request.fd, request.fd_offset = _file_target(data, what)
            size = os.fstat(request.fd).st_size - request.fd_offset
            keep = data
        else:
            try:
                keep, size = memory_source(data)
            except TypeError:
                raise ConfigurationError(f"{what}: data must be bytes-like or an open binary "
                                         f"file, got {type(data).__name__}") from None
            request.data = keep
        if size > 0xFFFFFFFE:
            raise ConfigurationError(f"{what}: {size} bytes; a transfer moves at most 4 GiB - 2")
        request.size = size
        request.progress = progress is not None
        return self._start(request, node, index, sub, False, keep, progress, what)

    def _request(self, node: int, index: int, sub: int, upload: bool, timeout: float,
                 what: str) -> TransferRequest:
        lowest = 0 if self.PROTOCOL == "USDO" else 1
        if isinstance(node, bool) or not isinstance(node, int) or not lowest <= node <= 127:
            raise ConfigurationError(f"{what}: node must be 1..127"
                                     f"{' (0 = broadcast)' if lowest == 0 else ''}, got {node!r}")
        if not 0 <= index <= 0xFFFF or not 0 <= sub <= 0xFF:
            raise ConfigurationError(f"{what}: 0x{index:X}:{sub:X} outside 0..0xFFFF:0..0xFF")
        if not 0 < timeout <= 3600:
            raise ConfigurationError(f"{what}: timeout {timeout!r} s outside (0, 3600]")
        return TransferRequest(node, index, sub, upload, max(1, int(timeout * 1000)))

    def _start(self, request: TransferRequest, node: int, index: int, sub: int, upload: bool, keep: Any,
               progress: Optional[Progress], what: str) -> Transfer:
        self._ensure_client()
        with self._lock:   # the done event cannot overtake the registration
            handle = self.line._rt.transfer_start(self.line.index, request, what)
            transfer = Transfer(self, handle, node, index, sub, upload, keep, progress, what)
            self._transfers[handle] = transfer
        return transfer

    # ------------------------------------------------------------ blocking / async forms
    def upload(self, node: int, index: int, sub: int = 0, **options: Any) -> bytes:
        return self.start_upload(node, index, sub, **options).result()

    def download(self, node: int, index: int, sub: int, data: Any, **options: Any) -> None:
        self.start_download(node, index, sub, data, **options).result()

    async def aupload(self, node: int, index: int, sub: int = 0, **options: Any) -> bytes:
        return await self.start_upload(node, index, sub, **options)

    async def adownload(self, node: int, index: int, sub: int, data: Any,
                        **options: Any) -> None:
        await self.start_download(node, index, sub, data, **options)

    # ------------------------------------------------------------ runtime side
    def _on_dispatcher(self) -> bool:
        return self.line.network._on_dispatcher()

    def _finished(self, handle: int) -> bool:
        """Ask the runtime directly (a done event may still be queued)."""
        try:
            return not self.line._rt.transfer_result(self.line.index, handle, "poll")["running"]
        except ClosedError:
            raise
        except CanopenFDError:
            return True   # released: _collect reports it

    def _wait(self, handle: int, seconds: float) -> bool:
        """Block in the runtime until the transfer ended (True) or seconds passed."""
        try:
            return self.line._rt.transfer_wait(self.line.index, handle,
                                               max(1, math.ceil(seconds * 1000)), "wait")
        except ClosedError:
            raise
        except CanopenFDError:
            return True   # released: _collect reports it

    def _cancel(self, handle: int, code: Optional[int], what: str) -> None:
        code = self.GENERAL_ERROR if code is None else code
        self.line._rt.transfer_cancel(self.line.index, handle, code, f"cancel of {what}")

    def _collect(self, transfer: Transfer) -> Tuple[Any, Optional[BaseException]]:
        rt, line = self.line._rt, self.line.index
        handle = transfer._handle
        try:
            result = rt.transfer_result(line, handle, transfer.what)
            data = rt.transfer_data(line, handle, result["transferred"], transfer.what) \
                if transfer.upload and transfer.node != 0 and transfer._keep is None \
                else None
            answers = rt.usdo_answers(line, handle, transfer.what) if transfer.node == 0 else []
        finally:
            with self._lock:
                self._transfers.pop(handle, None)
            try:
                rt.transfer_release(line, handle, transfer.what)
            except CanopenFDError:
                pass
        transfer.mode = self.MODES[result["mode"]] if result["mode"] < len(self.MODES) else None
        transfer.transferred = result["transferred"]
        transfer.data_type = result["type"] if transfer.upload else None
        if transfer.node == 0:
            return self._broadcast_result(transfer, answers), None
        if result["abort"]:
            error = self._abort_error(result["abort"], transfer.node, transfer.index,
                                      transfer.subindex, bool(result["abort_from_server"]),
                                      transfer.what)
            if result["error_number"]:  # a file read/write failed under the transfer
                error.__cause__ = OSError(result["error_number"],
                                          os.strerror(result["error_number"]))
            return None, error
        return (data if transfer.upload else None), None

    def _broadcast_result(self, transfer: Transfer, answers: List[Any]) -> Dict[int, Any]:
        out: Dict[int, Any] = {}
        for node, abort, data in answers:
            if abort:
                out[node] = self._abort_error(abort, node, transfer.index, transfer.subindex,
                                              True, transfer.what)
            else:
                out[node] = data if transfer.upload else None
        return out

    def _event_done(self, handle: int) -> Optional[Callable[[], None]]:
        with self._lock:
            transfer = self._transfers.get(handle)
        return transfer._finish if transfer is not None else None

    def _event_progress(self, handle: int, moved: int) -> Optional[Callable[[], None]]:
        with self._lock:
            transfer = self._transfers.get(handle)
        if transfer is None or transfer._progress is None:
            return None
        callback = transfer._progress

        def run() -> None:
            try:
                callback(moved)
            except Exception:  # noqa: BLE001 - a broken progress callback never stops a transfer
                log.exception("%s: progress callback %r raised", transfer.what, callback)
        return run


def _file_target(file: Any, what: str) -> Tuple[int, int]:
    try:
        return file.fileno(), file.tell()
    except (AttributeError, OSError, ValueError) as exc:
        raise ConfigurationError(f"{what}: file must be an open binary file with a "
                                 f"descriptor ({exc})") from None


def _type_code(data_type: Any, what: str) -> int:
    try:
        return int(DataType.parse(data_type))
    except (ValueError, KeyError, TypeError):
        raise ConfigurationError(f"{what}: unknown data type {data_type!r}") from None


def _now() -> float:
    return time.monotonic()
