"""Client transfers of a line — the part USDO (fd lines, transfer.usdo) and
SDO (classic lines, transfer.sdo) share: starting, waiting (blocking, with
`await`, or not at all), cancelling, file sources and sinks, progress. The
transfer itself (every frame, toggle, counter, timeout, block or bulk flow)
runs in the C runtime: no Python per frame. The per-node views
(`remote.usdo` / `remote.sdo`, `remote.od[...]`) are in transfer.remote."""

from __future__ import annotations

import asyncio
import logging
import math
import os
import threading
import time
from typing import (Any, BinaryIO, Callable, Dict, Generator, List, NamedTuple, Optional,
                    Tuple, Union)

from .._binding.constants import EventKind
from .._binding.context import Deferred, LineContext
from .._binding.runtime import Event
from .._binding.transfers import CBuffer, TransferRequest, memory_source
from .._callbacks import loop_waker
from ..errors import (ABORT_TEXT, AbortError, CanopenFDError, ClosedError, ConfigurationError,
                      TransferAbortError)
from ..od.datatypes import DataType

log = logging.getLogger(__name__)

#: Largest answer we accept to an upload of unknown size unless told (bytes).
DEFAULT_MAX_SIZE = 64 << 20
_DOMAIN = int(DataType.DOMAIN)
_WAIT_STEP_S = 0.5     # longest blocking wait in C (Ctrl-C is seen between steps)
_DISPATCHER_POLL_S = 0.002

Key = Union[int, str, Tuple[int, int]]
Progress = Callable[[int], None]
#: What a transfer gives: bytes (upload), None (download), or for a USDO
#: broadcast {node: bytes / None, or the UsdoAbortError of that node}.
Result = Union[None, bytes, Dict[int, Union[None, bytes, AbortError]]]
#: Builds the abort exception: (code, node, index, sub, from_server, what).
AbortFactory = Callable[[int, int, int, int, bool, str], AbortError]
#: What a download reads: bytes-like data, or an open binary file.
DownloadSource = Union[bytes, bytearray, memoryview, BinaryIO]


class Completion:
    """The end of one transfer as the dispatcher hears it (CO_EV_TRANSFER_DONE),
    with what runs then (an `await`)."""

    def __init__(self) -> None:
        self._done = threading.Event()
        self._lock = threading.Lock()
        self._callbacks: List[Callable[[], None]] = []

    def is_set(self) -> bool:
        return self._done.is_set()

    def wait(self, seconds: float) -> bool:
        return self._done.wait(seconds)

    def add_callback(self, callback: Callable[[], None]) -> None:
        """callback() once done (at once when it is)."""
        with self._lock:
            if not self._done.is_set():
                self._callbacks.append(callback)
                return
        callback()

    def remove_callback(self, callback: Callable[[], None]) -> None:
        with self._lock:
            if callback in self._callbacks:
                self._callbacks.remove(callback)

    def set(self) -> None:
        with self._lock:
            self._done.set()
            callbacks, self._callbacks = self._callbacks, []
        for callback in callbacks:
            callback()


class Transfer:
    """One transfer in flight: wait with `result()`, `await` it, or
    `cancel()` it. Results: bytes (upload), None (download), a dict
    {node: bytes/None or UsdoAbortError} (USDO broadcast)."""

    def __init__(self, engine: "TransferEngine", handle: int, node: int, index: int, sub: int,
                 upload: bool, what: str, completion: Completion) -> None:
        self._engine = engine
        self._handle = handle
        self._completion = completion
        self.node = node
        self.index = index
        self.subindex = sub
        self.upload = upload
        self.what = what
        self._lock = threading.Lock()
        self._outcome: Optional[Tuple[Result, Optional[AbortError]]] = None
        #: Filled once finished: mode used ('expedited', 'segmented', 'bulk' /
        #: 'block'), bytes moved, the data type byte the server sent (USDO uploads).
        self.mode: Optional[str] = None
        self.transferred = 0
        self.data_type: Optional[int] = None

    def __repr__(self) -> str:
        state = "done" if self._completion.is_set() else "running"
        return f"<Transfer {self.what} {state}>"

    # ------------------------------------------------------------ waiting
    def done(self) -> bool:
        return self._completion.is_set() or self._engine.finished(self._handle)

    def result(self, timeout: Optional[float] = None) -> Result:
        """Block until the transfer ended; its value, or the abort (UsdoAbortError /
        SdoAbortError). The
        transfer's own per-frame timeout ends it if the server goes silent,
        so no timeout is needed here; a given one raises TimeoutError and
        leaves the transfer running."""
        deadline = None if timeout is None else _now() + timeout
        on_dispatcher = self._engine.on_dispatcher()
        while not self._completion.is_set():
            remaining = None if deadline is None else deadline - _now()
            if remaining is not None and remaining <= 0:
                if self._engine.finished(self._handle):
                    break
                raise TimeoutError(f"{self.what}: not finished after {timeout} s")
            step = _WAIT_STEP_S if remaining is None else min(_WAIT_STEP_S, remaining)
            if on_dispatcher:
                # the done event would come through this very thread: poll
                if self._engine.finished(self._handle):
                    break
                self._completion.wait(min(_DISPATCHER_POLL_S, step))
            elif self._engine.wait(self._handle, step):
                # Woken by the runtime thread itself; an end heard here posts no
                # TRANSFER_DONE event, so whoever awaits this transfer hears it now.
                self._completion.set()
                break
        return self._collect()

    wait = result

    def __await__(self) -> Generator[Any, None, Result]:
        return self._awaited().__await__()

    async def _awaited(self) -> Result:
        future, wake_loop = loop_waker(self._collect)
        # Transfers start without a done event (a caller blocking in C hears
        # the end directly); an awaiting task needs it, so ask now.
        if self._engine.notify_end(self._handle):
            self._completion.set()   # ended already: no event comes
        self._completion.add_callback(wake_loop)
        try:
            return await future
        except asyncio.CancelledError:
            # The awaiting task gave up: abort the transfer on the bus, so the
            # server and this client's channel are free for the next one.
            self._completion.remove_callback(wake_loop)
            if not self.done():
                try:
                    self.cancel()
                except CanopenFDError as exc:   # ended or closed meanwhile
                    log.debug("%s: cancel after the await's cancellation: %s", self.what, exc)
            raise

    def cancel(self, code: Optional[int] = None) -> None:
        """Abort the transfer (the abort frame goes to the server); result()
        then raises the abort error with `code` (default: general error)."""
        self._engine.cancel(self._handle, code, self.what)

    def _collect(self) -> Result:
        with self._lock:
            if self._outcome is None:
                self._outcome = self._engine.collect(self._handle, self)
        value, error = self._outcome
        if error is not None:
            raise error
        return value


class _Pending(NamedTuple):
    """What the engine keeps of a running transfer."""

    transfer: Transfer
    completion: Completion
    keep: object   # kept alive only: the download's buffer / the file; None: into memory
    progress: Optional[Progress]


class TransferEngine:
    """The runtime side of one line client's transfers: starts them, hears
    their events (TRANSFER_DONE, TRANSFER_PROGRESS), waits, cancels and
    collects their results."""

    def __init__(self, context: LineContext, modes: Tuple[str, ...], general_error: int,
                 abort_error: AbortFactory) -> None:
        self._context = context
        self._modes = modes
        self._general_error = general_error
        self._abort_error = abort_error
        self._lock = threading.Lock()
        self._pending: Dict[int, _Pending] = {}
        context.subscribe(EventKind.TRANSFER_DONE, self._event_done)
        context.subscribe(EventKind.TRANSFER_PROGRESS, self._event_progress)
        context.on_close(self._network_closed)

    def start(self, request: TransferRequest, keep: object,
              progress: Optional[Progress], what: str) -> Transfer:
        context = self._context
        completion = Completion()
        with self._lock:   # the done event cannot overtake the registration
            handle = context.runtime.transfer_start(context.index, request, what)
            transfer = Transfer(self, handle, request.server, request.index, request.sub,
                                request.upload, what, completion)
            self._pending[handle] = _Pending(transfer, completion, keep, progress)
        return transfer

    def on_dispatcher(self) -> bool:
        return self._context.on_dispatcher()

    def finished(self, handle: int) -> bool:
        """Ask the runtime directly (a done event may still be queued)."""
        context = self._context
        try:
            return not context.runtime.transfer_result(context.index, handle, "poll")["running"]
        except ClosedError:
            raise
        except CanopenFDError:
            return True   # released: collect reports it

    def notify_end(self, handle: int) -> bool:
        """Have the runtime post TRANSFER_DONE when the transfer ends; True
        when it ended already (then no event comes)."""
        context = self._context
        try:
            return context.runtime.transfer_notify(context.index, handle, "notify")
        except CanopenFDError:
            return True   # released or closed: collect reports it

    def wait(self, handle: int, seconds: float) -> bool:
        """Block in the runtime until the transfer ended (True) or seconds passed."""
        context = self._context
        try:
            return context.runtime.transfer_wait(context.index, handle,
                                                 max(1, math.ceil(seconds * 1000)), "wait")
        except ClosedError:
            raise
        except CanopenFDError:
            return True   # released: collect reports it

    def cancel(self, handle: int, code: Optional[int], what: str) -> None:
        code = self._general_error if code is None else code
        context = self._context
        context.runtime.transfer_cancel(context.index, handle, code, f"cancel of {what}")

    def collect(self, handle: int, transfer: Transfer) -> Tuple[Result, Optional[AbortError]]:
        """The outcome of an ended transfer (once: the handle is released)."""
        runtime, line = self._context.runtime, self._context.index
        with self._lock:
            pending = self._pending.get(handle)
        to_memory = pending is None or pending.keep is None
        try:
            result = runtime.transfer_result(line, handle, transfer.what)
            data = runtime.transfer_data(line, handle, result["transferred"], transfer.what) \
                if transfer.upload and transfer.node != 0 and to_memory else None
            answers = runtime.usdo_answers(line, handle, transfer.what) \
                if transfer.node == 0 else []
        finally:
            with self._lock:
                self._pending.pop(handle, None)
            try:
                runtime.transfer_release(line, handle, transfer.what)
            except CanopenFDError:
                pass
        mode = result["mode"]
        transfer.mode = self._modes[mode] if mode < len(self._modes) else None
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

    def _broadcast_result(self, transfer: Transfer, answers: List[Tuple[int, int, bytes]]
                          ) -> Dict[int, Union[None, bytes, AbortError]]:
        out: Dict[int, Union[None, bytes, AbortError]] = {}
        for node, abort, data in answers:
            if abort:
                out[node] = self._abort_error(abort, node, transfer.index, transfer.subindex,
                                              True, transfer.what)
            else:
                out[node] = data if transfer.upload else None
        return out

    def _network_closed(self) -> None:
        """No done event comes any more: whoever awaits a running transfer
        collects it now (and gets the ClosedError)."""
        with self._lock:
            completions = [pending.completion for pending in self._pending.values()]
        for completion in completions:
            completion.set()

    def _event_done(self, event: Event) -> Deferred:
        """CO_EV_TRANSFER_DONE: a = the handle."""
        with self._lock:
            pending = self._pending.get(event.a)
        return pending.completion.set if pending is not None else None

    def _event_progress(self, event: Event) -> Deferred:
        """CO_EV_TRANSFER_PROGRESS: a = the handle, b = bytes moved so far."""
        with self._lock:
            pending = self._pending.get(event.a)
        if pending is None or pending.progress is None:
            return None
        callback, what, moved = pending.progress, pending.transfer.what, event.b

        def run() -> None:
            try:
                callback(moved)
            except Exception:  # noqa: BLE001 - a broken progress callback never stops a transfer
                log.exception("%s: progress callback %r raised", what, callback)
        return run


class TransferClient:
    """What the USDO and SDO clients of a line share (see UsdoClient, SdoClient).
    Every call names the server node; `RemoteNode.usdo` / `.sdo` fix the node
    and add the OD's names and types. Many transfers may run at once, from
    any threads."""

    #: protocol name in messages, mode names (index = the runtime's mode code)
    PROTOCOL = ""
    MODES: Tuple[str, ...] = ()
    #: the modes an upload takes (a subset of MODES)
    UPLOAD_MODES: Tuple[str, ...] = ("auto",)
    #: the cancel code that means "general error"
    GENERAL_ERROR = 0
    #: downloads carry the entry's data type (USDO does, SDO has no field for it)
    SENDS_DATA_TYPE = False
    #: uploads through a node's OD take the entry's size as their size hint
    HINTS_UPLOAD_SIZE = False

    def __init__(self, context: LineContext) -> None:
        self._context = context
        self._engine = TransferEngine(context, self.MODES, self.GENERAL_ERROR, self._abort_error)

    def __repr__(self) -> str:
        return f"<{type(self).__name__} of {self._context.where}>"

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

    # ------------------------------------------------------------ starting
    def start_upload(self, node: int, index: int, sub: int = 0, *,
                     timeout: float = 1.0, max_size: Optional[int] = None,
                     file: Optional[BinaryIO] = None,
                     progress: Optional[Progress] = None, size_hint: int = 0,
                     mode: str = "auto", route: Optional["Route"] = None) -> Transfer:
        """Start reading index:sub of node; returns at once. `file`: an open
        binary file the data streams into (else memory, at most max_size).
        size_hint: the bytes expected, so AUTO can pick a block upload (SDO)
        or a bulk upload (USDO, from 4 KiB on; a server without bulk answers
        0x13 and the upload goes on plainly). mode: 'auto', 'bulk' (USDO) /
        'block' (SDO) whatever the size, or for SDO 'expedited' / 'segmented'
        (a normal upload: the server picks which).
        route (SDO): Route(network, node) of a node reached through the
        gateway `node` (see remote())."""
        return self._begin_upload(node, index, sub, timeout=timeout, max_size=max_size,
                                  file=file, progress=progress, size_hint=size_hint,
                                  mode=mode, route=route)

    def _begin_upload(self, node: int, index: int, sub: int, *,
                      timeout: float = 1.0, max_size: Optional[int] = None,
                      file: Optional[BinaryIO] = None,
                      progress: Optional[Progress] = None, size_hint: int = 0,
                      mode: str = "auto", route: Optional["Route"] = None) -> Transfer:
        what = (f"{self.PROTOCOL} upload 0x{index:04X}:{sub:02X} from "
                f"{_target(node, route)}")
        if mode not in self.UPLOAD_MODES:
            raise ConfigurationError(f"{what}: mode {mode!r} is not one of "
                                     f"{', '.join(self.UPLOAD_MODES)}")
        request = self._request(node, index, sub, True, timeout, what, route)
        request.mode = self.MODES.index(mode)
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
        return self._start(request, file, progress, what)

    def start_download(self, node: int, index: int, sub: int, data: DownloadSource, *,
                       mode: str = "auto", data_type: Union[None, int, str] = None,
                       timeout: float = 1.0,
                       progress: Optional[Progress] = None,
                       route: Optional["Route"] = None) -> Transfer:
        """Start writing `data` (bytes-like, or an open binary file read from
        its position to its end) to index:sub of node. mode: 'auto' (by the
        size), 'expedited', 'segmented', or 'bulk' (USDO) / 'block' (SDO).
        data_type (USDO): the CiA 301 type code sent (default DOMAIN 0x0F =
        raw bytes, accepted for any entry). route (SDO): as start_upload's."""
        return self._begin_download(node, index, sub, data, mode=mode,
                                    data_type=data_type, timeout=timeout, progress=progress,
                                    route=route)

    def _begin_download(self, node: int, index: int, sub: int, data: DownloadSource,
                        *, mode: str = "auto",
                        data_type: Union[None, int, str] = None, timeout: float = 1.0,
                        progress: Optional[Progress] = None,
                        route: Optional["Route"] = None) -> Transfer:
        what = f"{self.PROTOCOL} download 0x{index:04X}:{sub:02X} to {_target(node, route)}"
        if mode not in self.MODES:
            raise ConfigurationError(f"{what}: mode {mode!r} is not one of "
                                     f"{', '.join(self.MODES)}")
        request = self._request(node, index, sub, False, timeout, what, route)
        request.mode = self.MODES.index(mode)
        request.data_type = _DOMAIN if data_type is None else _type_code(data_type, what)
        keep: object   # what must stay alive while C reads it
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
        return self._start(request, keep, progress, what)

    def _request(self, node: int, index: int, sub: int, upload: bool, timeout: float,
                 what: str, route: Optional["Route"] = None) -> TransferRequest:
        lowest = 0 if self.PROTOCOL == "USDO" else 1
        if isinstance(node, bool) or not isinstance(node, int) or not lowest <= node <= 127:
            raise ConfigurationError(f"{what}: node must be 1..127"
                                     f"{' (0 = broadcast)' if lowest == 0 else ''}, got {node!r}")
        if not 0 <= index <= 0xFFFF or not 0 <= sub <= 0xFF:
            raise ConfigurationError(f"{what}: 0x{index:X}:{sub:X} outside 0..0xFFFF:0..0xFF")
        if not 0 < timeout <= 3600:
            raise ConfigurationError(f"{what}: timeout {timeout!r} s outside (0, 3600]")
        request = TransferRequest(node, index, sub, upload, max(1, int(timeout * 1000)))
        if route is not None:
            request.network, request.network_node = route
        return request

    def _start(self, request: TransferRequest, keep: object,
               progress: Optional[Progress], what: str) -> Transfer:
        self._ensure_client()
        return self._engine.start(request, keep, progress, what)

    # ------------------------------------------------------------ blocking / async forms
    # Transfers start without a TRANSFER_DONE event: result() waits in C
    # (co_rt_transfer_wait), so the dispatcher thread does not wake to compete
    # with the waking caller for the GIL (that race cost 6-8 % of an expedited
    # round trip); only an `await` asks for the event (Transfer.__await__).
    def upload(self, node: int, index: int, sub: int = 0, **options: Any) -> bytes:
        """Read index:sub of node and wait for the data (options: start_upload;
        with file=, the data goes there and b"" comes back)."""
        _not_broadcast(node, f"{self.PROTOCOL} upload 0x{index:04X}:{sub:02X}")
        transfer = self._begin_upload(node, index, sub, **options)
        return uploaded_bytes(transfer.result())

    def download(self, node: int, index: int, sub: int, data: DownloadSource,
                 **options: Any) -> None:
        """Write data to index:sub of node and wait for the end (options: start_download)."""
        self._begin_download(node, index, sub, data, **options).result()

    def remote(self, network: int, node: int, *, gateway: int) -> "RoutedNode":
        """Node `node` of network `network`, reached through the gateway
        node `gateway` on this line. SDO (classic lines): SDO networking,
        CiA 302-7 style (a network indication, then the gateway relays every
        frame). USDO (fd lines): remote USDO, CiA 1301 (each request carries
        the target network and node; the gateway carries it out and answers;
        values up to 52 bytes expedited, larger ones segmented, bulk not
        routed; the source network is this line's network_id, 0 when
        unset). Its upload/download work as this client's."""
        what = f"{self.PROTOCOL} remote(network={network!r}, node={node!r})"
        for name, value in (("network", network), ("node", node), ("gateway", gateway)):
            if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= 127:
                raise ConfigurationError(f"{what}: {name} must be 1..127, got {value!r}")
        return RoutedNode(self, gateway, Route(network, node))

    async def aupload(self, node: int, index: int, sub: int = 0, **options: Any) -> bytes:
        _not_broadcast(node, f"{self.PROTOCOL} upload 0x{index:04X}:{sub:02X}")
        return uploaded_bytes(await self.start_upload(node, index, sub, **options))

    async def adownload(self, node: int, index: int, sub: int, data: DownloadSource,
                        **options: Any) -> None:
        await self.start_download(node, index, sub, data, **options)


class Route(NamedTuple):
    """A node of another network: what a routed request names."""

    network: int
    node: int


def _target(node: int, route: Optional[Route]) -> str:
    return f"node {node}" if route is None else \
        f"node {route.node} of network {route.network} (gateway {node})"


class RoutedNode:
    """A node of another network reached through a gateway (client.remote())."""

    def __init__(self, client: TransferClient, gateway: int, route: Route) -> None:
        self._client = client
        self.gateway = gateway
        self.network = route.network
        self.node = route.node
        self._route = route

    def __repr__(self) -> str:
        return f"<RoutedNode {_target(self.gateway, self._route)}>"

    def start_upload(self, index: int, sub: int = 0, **options: Any) -> Transfer:
        return self._client.start_upload(self.gateway, index, sub, route=self._route,
                                         **options)

    def start_download(self, index: int, sub: int, data: DownloadSource,
                       **options: Any) -> Transfer:
        return self._client.start_download(self.gateway, index, sub, data,
                                           route=self._route, **options)

    def upload(self, index: int, sub: int = 0, **options: Any) -> bytes:
        """Read index:sub of the routed node and wait for the data."""
        return uploaded_bytes(self.start_upload(index, sub, **options).result())

    def download(self, index: int, sub: int, data: DownloadSource, **options: Any) -> None:
        """Write data to index:sub of the routed node and wait for the end."""
        self.start_download(index, sub, data, **options).result()


def uploaded_bytes(result: Result) -> bytes:
    """What the blocking/async upload forms return: the data, b"" when it went
    into a file (start_upload(file=...)). A broadcast's {node: answer} is
    broadcast_upload()'s; upload() refuses node 0 before it starts."""
    if result is None:
        return b""
    assert isinstance(result, bytes), f"an upload ended with {type(result).__name__}"
    return result


def _not_broadcast(node: object, what: str) -> None:
    if node == 0:
        raise ConfigurationError(f"{what}: node 0 is the USDO broadcast; broadcast_upload() "
                                 "gives each server's answer")


def require_protocol(context: LineContext, protocol: str) -> None:
    """ConfigurationError unless the line runs `protocol` ('USDO': fd lines,
    'SDO': classic lines)."""
    if protocol == "USDO" and context.mode != "fd":
        raise ConfigurationError(f"{context.where} is a classic line: USDO needs CAN FD "
                                 "(classic lines use line.sdo)")
    if protocol == "SDO" and context.mode != "classic":
        raise ConfigurationError(f"{context.where} is an fd line: CANopen FD replaces SDO "
                                 "with USDO (use line.usdo)")


def _file_target(file: object, what: str) -> Tuple[int, int]:
    try:
        # duck-typed on purpose: any object may come in, AttributeError is the check
        return file.fileno(), file.tell()  # type: ignore[attr-defined]
    except (AttributeError, OSError, ValueError) as exc:
        raise ConfigurationError(f"{what}: file must be an open binary file with a "
                                 f"descriptor ({exc})") from None


def _type_code(data_type: Union[int, str], what: str) -> int:
    try:
        return int(DataType.parse(data_type))
    except (ValueError, KeyError, TypeError):
        raise ConfigurationError(f"{what}: unknown data type {data_type!r}") from None


def _now() -> float:
    return time.monotonic()
