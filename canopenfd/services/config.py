"""The configuration manager (CiA 302-3) of a line: a node's configuration
(a concise DCF, or a DCF converted on the way) downloaded by the C runtime
through the line's client (SDO on classic lines, USDO on fd lines)::

    job = line.manager.configure(5, "axis.dcf")            # or concise bytes
    result = job.result()                                  # or: await job
    print(result)                 # node 5: configured, 12 entries written

With a stamp (the expected 0x1020 date and time, CiA 302-3's 0x1F26/0x1F27),
the node's 0x1020 is compared first (equal: SKIPPED, nothing written) and
written last, only after every entry. A DCF's own 0x1020 values are the
stamp unless `expected` says otherwise (False: no stamp). The first refused
entry stops the configuration unless `continue_on_error`; see co_config.h.
"""

from __future__ import annotations

import asyncio
import enum
import os
import threading
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, Generator, List, Optional, Tuple, Union

from .._binding.constants import EventKind
from .._binding.context import Deferred, LineContext
from .._binding.runtime import Event
from .._callbacks import loop_waker
from .._checks import check_node_id
from ..errors import ABORT_TEXT, CanopenFDError, ConfigurationError
from ..od import import_od
from ..od.concise import concise_from_od, parse_concise

__all__ = ["ConfigOutcome", "ConfigResult", "Configuration", "ConfigManager"]

_DCF_SUFFIXES = (".dcf", ".xdc", ".eds", ".xdd")
_WAIT_STEP_S = 0.02
#: Source of a configuration: concise DCF bytes, or a file path (DCF / XDC
#: converted, anything else read as a concise DCF).
DcfSource = Union[bytes, bytearray, memoryview, str, "os.PathLike[str]"]
#: Expected 0x1020 (date, time); None: the DCF's own, False: none.
Stamp = Union[Tuple[int, int], None, bool]


class ConfigOutcome(str, enum.Enum):
    """How a configuration ended (co_config_outcome_t, in its order)."""

    OK = "configured"
    SKIPPED = "skipped"          # 0x1020 equals the expected date and time
    FAILED = "failed"            # an entry (or the stamp) was refused
    TIMEOUT = "timeout"          # the node did not answer
    CANCELLED = "cancelled"

    @classmethod
    def from_code(cls, code: int) -> "ConfigOutcome":
        members = list(cls)
        return members[code] if 0 <= code < len(members) else cls.FAILED


@dataclass
class ConfigResult:
    """The outcome, the entries written and refused, each entry's abort code
    ((index, sub, abort), 0 = written, in the order they were written; the
    0x1020 stamp included), and the first failure (FAILED: the refused
    entry; TIMEOUT: the unanswered one)."""

    node: int
    outcome: ConfigOutcome
    written: int = 0
    failed: int = 0
    entries: List[Tuple[int, int, int]] = field(default_factory=list)
    index: Optional[int] = None
    subindex: Optional[int] = None
    abort_code: int = 0
    from_node: bool = False

    @property
    def ok(self) -> bool:
        """Configured, or skipped because the node holds this configuration."""
        return self.outcome in (ConfigOutcome.OK, ConfigOutcome.SKIPPED)

    def __str__(self) -> str:
        text = f"node {self.node}: {self.outcome.value}"
        if self.outcome is ConfigOutcome.OK:
            text += f", {self.written} entries written"
        if self.abort_code and self.index is not None and self.subindex is not None:
            meaning = ABORT_TEXT.get(self.abort_code, "unknown abort code")
            origin = "from the node" if self.from_node else "ours"
            text += (f" at 0x{self.index:04X}:{self.subindex:02X}: abort "
                     f"0x{self.abort_code:08X} ({meaning}) {origin}")
        return text


class Configuration:
    """One configuration in flight: `result()` blocks, `await` it, `cancel()`."""

    def __init__(self, manager: "ConfigManager", handle: int, node: int, what: str) -> None:
        self._manager = manager
        self._handle = handle
        self.node = node
        self.what = what
        self._done = threading.Event()
        self._lock = threading.Lock()
        self._result: Optional[ConfigResult] = None
        self._wakers: List[Callable[[], None]] = []    # of awaiting tasks (loop_waker)

    def __repr__(self) -> str:
        return f"<Configuration {self.what} {'done' if self.done() else 'running'}>"

    def done(self) -> bool:
        return self._done.is_set() or self._poll() is not None

    def result(self, timeout: Optional[float] = None) -> ConfigResult:
        """Block until the configuration ended (each transfer has its own
        per-frame timeout, so it ends); a `timeout` here raises TimeoutError
        and leaves it running."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            finished = self._poll()
            if finished is not None:
                return finished
            if deadline is not None and time.monotonic() >= deadline:
                raise TimeoutError(f"{self.what}: not finished after {timeout} s")
            self._done.wait(_WAIT_STEP_S)

    wait = result

    def __await__(self) -> Generator[Any, None, ConfigResult]:
        return self._awaited().__await__()

    async def _awaited(self) -> ConfigResult:
        future, wake = loop_waker(self._finished)
        with self._lock:
            self._wakers.append(wake)
        self._wake()
        try:
            return await future
        except asyncio.CancelledError:
            # The awaiting task gave up: end the configuration (its open
            # transfer is aborted on the bus), as cancel() does.
            with self._lock:
                if wake in self._wakers:
                    self._wakers.remove(wake)
            try:
                self.cancel()
            except CanopenFDError:
                pass    # ended or closed meanwhile: nothing left to free
            raise

    def _finished(self) -> ConfigResult:
        assert self._result is not None    # woken only once it is there
        return self._result

    def cancel(self) -> None:
        """End the configuration: the open transfer is aborted on the bus,
        the result says CANCELLED."""
        if not self.done():
            self._manager.cancel(self._handle, self.what)

    # ------------------------------------------------------------ internals
    def _poll(self) -> Optional[ConfigResult]:
        """The result once ended (collected from C once, handle released)."""
        with self._lock:
            if self._result is None:
                self._result = self._manager.collect(self._handle, self.node, self.what)
            finished = self._result
        if finished is not None:
            self._done.set()
            self._wake()
        return finished

    def _wake(self) -> None:
        """Wake the awaiting tasks once the result is there."""
        with self._lock:
            if self._result is None:
                return
            wakers, self._wakers = self._wakers, []
        for wake in wakers:
            wake()

    def notify_ended(self) -> None:
        """CO_EV_CONFIG heard (dispatcher thread)."""
        self._poll()


class ConfigManager:
    """The configuration manager of a line (`line.manager`)."""

    def __init__(self, context: LineContext, where: str) -> None:
        self._context = context
        self._where = where
        self._lock = threading.Lock()
        self._running: Dict[int, Configuration] = {}
        context.subscribe(EventKind.CONFIG, self._event)

    def configure(self, node: int, dcf: DcfSource, expected: Stamp = None, *,
                  continue_on_error: bool = False, timeout_ms: int = 0) -> Configuration:
        """Start configuring `node` with a concise DCF (bytes) or a file (DCF /
        XDC: converted with canopenfd.od.concise, $NODEID = node; other
        suffixes: read as a concise DCF). `expected` = (date, time) of 0x1020;
        None takes a converted DCF's own 0x1020 values (none for concise
        bytes), False compares and writes none."""
        what = f"configure node {node!r} on {self._where}"
        check_node_id(node, what)
        data, stamp = self._load(dcf, node, what)
        if expected is False:
            stamp = None
        elif expected is not None and expected is not True:
            stamp = self._check_stamp(expected, what)
        if isinstance(timeout_ms, bool) or not isinstance(timeout_ms, int) or \
                not 0 <= timeout_ms <= 0xFFFFFFFF:
            raise ConfigurationError(f"{what}: timeout_ms must be an int >= 0, got "
                                     f"{timeout_ms!r}")
        runtime = self._context.runtime
        # Registered before CO_EV_CONFIG can be handled: a short configuration
        # may end before config_start returns (the handler waits for the lock).
        with self._lock:
            handle = runtime.config_start(self._context.index, node, data, stamp,
                                          bool(continue_on_error), timeout_ms, what)
            job = Configuration(self, handle, node, what)
            self._running[handle] = job
        return job

    # ------------------------------------------------------------ for Configuration
    def collect(self, handle: int, node: int, what: str) -> Optional[ConfigResult]:
        """The result of an ended configuration (its handle released), None
        while it runs."""
        runtime, line = self._context.runtime, self._context.index
        raw = runtime.config_result(line, handle, what)
        if raw["running"]:
            return None
        entries = runtime.config_entries(line, handle, raw["reported"], what)
        runtime.config_release(line, handle, what)
        with self._lock:
            self._running.pop(handle, None)
        outcome = ConfigOutcome.from_code(raw["outcome"])
        failure = raw["abort"] != 0
        return ConfigResult(node=node, outcome=outcome, written=raw["written"],
                            failed=raw["failed"], entries=entries,
                            index=raw["index"] if failure else None,
                            subindex=raw["sub"] if failure else None,
                            abort_code=raw["abort"], from_node=bool(raw["from_node"]))

    def cancel(self, handle: int, what: str) -> None:
        self._context.runtime.config_cancel(self._context.index, handle, what)

    # ------------------------------------------------------------ internals
    @staticmethod
    def _check_stamp(expected: object, what: str) -> Tuple[int, int]:
        if isinstance(expected, tuple) and len(expected) == 2 and all(
                isinstance(v, int) and not isinstance(v, bool) and 0 <= v <= 0xFFFFFFFF
                for v in expected):
            return (expected[0], expected[1])
        raise ConfigurationError(f"{what}: expected must be (date, time), two UNSIGNED32 "
                                 f"values (0x1020:01, 0x1020:02), got {expected!r}")

    @staticmethod
    def _load(dcf: DcfSource, node: int, what: str) -> Tuple[bytes, Optional[Tuple[int, int]]]:
        if isinstance(dcf, (bytes, bytearray, memoryview)):
            data = bytes(dcf)
            parse_concise(data, "concise DCF")   # a clear error before the runtime's
            return data, None
        if not isinstance(dcf, (str, os.PathLike)):
            raise ConfigurationError(f"{what}: the DCF must be concise DCF bytes or a file "
                                     f"path, got {type(dcf).__name__}")
        path = os.fspath(dcf)
        if path.lower().endswith(_DCF_SUFFIXES):
            conversion = concise_from_od(import_od(path, node_id=node))
            return conversion.data, conversion.stamp
        try:
            with open(path, "rb") as source:
                data = source.read()
        except OSError as exc:
            raise ConfigurationError(f"{what}: {path}: {exc.strerror}") from None
        parse_concise(data, path)
        return data, None

    def _event(self, event: Event) -> Deferred:
        """CO_EV_CONFIG: a = handle, b = outcome."""
        with self._lock:
            job = self._running.get(event.a)
        return job.notify_ended if job is not None else None
