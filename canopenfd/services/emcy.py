"""Emergency messages (EMCY, CiA 301 / CiA 1301).

    me = line.create_local_node(1, od=demo_od("fd"))
    me.emcy.raise_error(0x2310, b"\\x01", priority=2)     # sent at once
    me.emcy.error_register, me.emcy.active                # 0x03, 1
    me.emcy.clear(0x2310)                                 # the removal EMCY

    drive = line.add_node(5)
    drive.emcy.add_callback(lambda emcy: print(emcy))     # python-canopen's name
    drive.emcy.wait(0x8130, timeout=2)
    drive.emcy.active                                     # codes active now
    line.on_emcy(print)                                   # every EMCY the line hears

Classic lines carry the 8-byte CiA 301 EMCY (code, error register, 5 bytes
of manufacturer-specific data); a cleared error is told by an EMCY with code
0x0000 ("error reset"). fd lines carry the 20-byte CANopen FD EMCY with the
logical device, the CiA specification number, a status byte (priority 0..7,
non-recoverable, occurred/removed, repeated) and a 48-bit time stamp; a
cleared error is the same code with "occurred" clear.
"""

from __future__ import annotations

import collections
import time
from typing import TYPE_CHECKING, Any, Callable, Deque, Dict, List, Optional, Tuple

from .._callbacks import CallbackList
from .._binding.runtime import decode_emcy
from ..decode_services import emcy_code_text, emcy_status_text, error_register_text
from .._binding.constants import EmcyStatus
from ..errors import ConfigurationError

if TYPE_CHECKING:  # pragma: no cover
    from ..node import LocalNode, RemoteNode

__all__ = ["Emcy", "EmcyProducer", "EmcyConsumer", "LOG_SIZE"]

#: EMCYs a RemoteNode keeps in `emcy.log`.
LOG_SIZE = 100

_PRIORITY_MASK = int(EmcyStatus.PRIORITY_MASK)
_NON_RECOVERABLE = int(EmcyStatus.NON_RECOVERABLE)
_OCCURRED = int(EmcyStatus.OCCURRED)
_REPEATED = int(EmcyStatus.REPEATED)
_TIME_MAX = (1 << 48) - 1


class Emcy:
    """One received EMCY, every field decoded.

    `node` (producer), `code`, `register` (0x1001 copy), `data` (the 5
    manufacturer-specific bytes), and on fd lines `logical_device`,
    `spec_number`, `status` (priority, non_recoverable, occurred, repeated
    as properties) and `time_stamp` (48 bits, 0 = none). `fd` tells the
    format; `timestamp` is the reception time (time.time(), as python-canopen).
    """

    __slots__ = ("node", "code", "register", "data", "logical_device", "spec_number",
                 "status", "time_stamp", "fd", "timestamp")

    def __init__(self, node: int, code: int, register: int, data: bytes, *,
                 logical_device: int = 0, spec_number: int = 0, status: int = 0,
                 time_stamp: int = 0, fd: bool = False, timestamp: float = 0.0) -> None:
        self.node = node
        self.code = code
        self.register = register
        self.data = bytes(data)
        self.logical_device = logical_device
        self.spec_number = spec_number
        self.status = status
        self.time_stamp = time_stamp
        self.fd = fd
        self.timestamp = timestamp

    @classmethod
    def decode(cls, node: int, data: bytes, fd: bool,
               timestamp: Optional[float] = None) -> Optional["Emcy"]:
        """The EMCY in `data` (8 bytes classic, >= 20 bytes fd), None when malformed."""
        fields = decode_emcy(bytes(data), fd)
        if fields is None:
            return None
        return cls(node, fields["code"], fields["error_register"], fields["msef"],
                   logical_device=fields["logical_device"],
                   spec_number=fields["spec_number"], status=fields["status"],
                   time_stamp=fields["time_stamp"], fd=fd,
                   timestamp=time.time() if timestamp is None else timestamp)

    # python-canopen's EmcyError names
    @property
    def error_register(self) -> int:
        return self.register

    @property
    def priority(self) -> int:
        return self.status & _PRIORITY_MASK

    @property
    def non_recoverable(self) -> bool:
        return bool(self.status & _NON_RECOVERABLE)

    @property
    def occurred(self) -> bool:
        """fd: the error occurred (False: it was removed). Classic: code != 0."""
        return bool(self.status & _OCCURRED) if self.fd else self.code != 0

    @property
    def repeated(self) -> bool:
        return bool(self.status & _REPEATED)

    @property
    def is_reset(self) -> bool:
        """Code 0x0000: "error reset or no error" (classic clears use it)."""
        return self.code == 0

    @property
    def removed(self) -> bool:
        """The EMCY tells an error went away (a reset, or fd "occurred" clear)."""
        return self.is_reset or (self.fd and not self.occurred)

    @property
    def text(self) -> str:
        """The CiA meaning: '0x8130 life guard error or heartbeat error (...)'."""
        return emcy_code_text(self.code)

    def get_desc(self) -> str:  # python-canopen
        return self.text

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Emcy):
            return NotImplemented
        return all(getattr(self, k) == getattr(other, k) for k in self.__slots__
                   if k != "timestamp")

    def __hash__(self) -> int:
        return hash((self.node, self.code, self.register, self.data, self.status))

    def __str__(self) -> str:
        text = f"EMCY node {self.node}: {self.text}, {error_register_text(self.register)}"
        if any(self.data):
            text += f", data {self.data.hex(' ')}"
        if self.fd:
            text += (f", logical device {self.logical_device}, spec {self.spec_number}, "
                     f"{emcy_status_text(self.status)}")
            if self.time_stamp:
                text += f", time stamp {self.time_stamp}"
        return text

    def __repr__(self) -> str:
        return f"<Emcy {self}>"


def _int(value: Any, name: str, low: int, high: int, where: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise ConfigurationError(f"{where}: {name} must be an int {low}..{high:#x}, "
                                 f"got {value!r}")
    return value


class EmcyProducer:
    """The EMCY producer of our local node (`local_node.emcy`).

    The stack keeps the active errors: the error register (0x1001) follows
    them, a repeated raise sends nothing on classic lines (fd: sent again
    marked "repeated"), and EMCYs leave only in PRE-OPERATIONAL and
    OPERATIONAL (queued meanwhile). The stack raises its own errors too
    (heartbeat or life guarding lost 0x8130, bus-off 0x8140, error passive
    0x8120, RPDO length 0x8210/0x8220, ...)."""

    def __init__(self, node: "LocalNode") -> None:
        self.node = node

    def __repr__(self) -> str:
        return f"<EmcyProducer of {self.node!r}>"

    def _what(self, verb: str, code: Any) -> str:
        code_text = f"0x{code:04X}" if isinstance(code, int) and not isinstance(code, bool) \
            else repr(code)
        return f"{verb} EMCY {code_text} on {self.node._where}"

    def _fields(self, code: Any, data: Any, register_bits: Any, logical_device: Any,
                spec_number: Any, priority: Any, non_recoverable: Any, time_stamp: Any,
                where: str) -> dict:
        _int(code, "code", 1, 0xFFFF, where)
        if not isinstance(data, (bytes, bytearray, memoryview)) or len(data) > 5:
            raise ConfigurationError(f"{where}: data (manufacturer-specific error field) must "
                                     f"be bytes of length 0..5, got {data!r}")
        fields = {"code": code, "msef": bytes(data),
                  "register_bits": _int(register_bits, "register_bits", 0, 0xFF, where),
                  "logical_device": _int(logical_device, "logical_device", 0, 0xFF, where),
                  "spec_number": _int(spec_number, "spec_number", 0, 0xFFFF, where),
                  "priority": _int(priority, "priority", 0, 7, where),
                  "non_recoverable": int(bool(non_recoverable)),
                  "time_stamp": _int(time_stamp, "time_stamp", 0, _TIME_MAX, where)}
        if self.node.line.mode != "fd":
            fd_only = [name for name in ("logical_device", "spec_number", "priority",
                                         "non_recoverable", "time_stamp") if fields[name]]
            if fd_only:
                raise ConfigurationError(f"{where}: {', '.join(fd_only)} exist only in the "
                                         "CANopen FD EMCY; this is a classic line")
        if not self.node.booted:
            raise ConfigurationError(f"{where}: the node is not booted yet")
        return fields

    def raise_error(self, code: int, data: bytes = b"", *, register_bits: int = 0,
                    logical_device: int = 0, spec_number: int = 0, priority: int = 0,
                    non_recoverable: bool = False, time_stamp: int = 0) -> bool:
        """Raise error `code` (1..0xFFFF): its EMCY goes out (or waits for the
        inhibit time / an NMT state that allows it). data: up to 5 bytes of
        manufacturer-specific error field. register_bits: 0x1001 bits besides
        the code's own class bit. fd lines only: logical_device, spec_number
        (CiA document defining the code), priority 0..7, non_recoverable,
        time_stamp (48 bits). Returns True for a new error, False when it was
        already active."""
        where = self._what("raise", code)
        fields = self._fields(code, data, register_bits, logical_device, spec_number, priority,
                              non_recoverable, time_stamp, where)
        return self.node.line._rt.emcy(self.node.line.index, fields, False, where) == 0

    def clear(self, code: int, data: bytes = b"", *, logical_device: int = 0,
              time_stamp: int = 0) -> bool:
        """Clear error `code`: classic lines send the reset EMCY (code 0x0000,
        the remaining error register), fd lines the code with "occurred"
        clear. Returns False (nothing sent) when it was not active."""
        where = self._what("clear", code)
        fields = self._fields(code, data, 0, logical_device, 0, 0, False, time_stamp, where)
        return self.node.line._rt.emcy(self.node.line.index, fields, True, where) == 0

    def _state(self) -> dict:
        where = f"EMCY state of {self.node._where}"
        if not self.node.booted:
            raise ConfigurationError(f"{where}: the node is not booted yet")
        return self.node.line._rt.emcy_state(self.node.line.index, where)

    @property
    def error_register(self) -> int:
        """0x1001 as the active errors make it."""
        return self._state()["error_register"]

    @property
    def active(self) -> int:
        """How many errors are active."""
        return self._state()["active"]

    @property
    def sent(self) -> int:
        return self._state()["sent"]

    @property
    def history(self) -> List[int]:
        """0x1003, the pre-defined error field, newest first: the error code in
        the low 16 bits, the first two manufacturer-specific bytes above it
        (what a network read of 0x1003 gives). Empty when the OD has no 0x1003;
        a network write of 0 to 0x1003:00 clears it."""
        if self.node.od is None or 0x1003 not in self.node.od:
            return []
        count = self.node[(0x1003, 0)].raw
        return [self.node[(0x1003, sub)].raw for sub in range(1, count + 1)]

    @property
    def dropped(self) -> int:
        """EMCYs lost because the wait queue was full."""
        return self._state()["dropped"]


class EmcyConsumer:
    """The EMCYs of one remote node (`remote_node.emcy`): the line consumes
    them from the first use of `remote_node.emcy` on (CAN-ID 0x80 + node-id)."""

    def __init__(self, node: "RemoteNode") -> None:
        self.node = node
        self._callbacks = CallbackList(f"node {node.node_id} EMCY")
        #: The recent EMCYs, oldest first (at most LOG_SIZE).
        self.log: Deque[Emcy] = collections.deque(maxlen=LOG_SIZE)
        self._active: Dict[Tuple[int, int], Emcy] = {}
        self._seq = 0
        node.line._rt.emcy_watch(node.line.index, node.node_id, True,
                                 f"EMCY consumer of {node._where}")

    def __repr__(self) -> str:
        return f"<EmcyConsumer of {self.node!r}>"

    def add_callback(self, callback: Callable[[Emcy], None]) -> Callable[[Emcy], None]:
        """callback(Emcy) for every EMCY of the node (dispatcher thread)."""
        return self._callbacks.add(callback)

    def remove_callback(self, callback: Callable[[Emcy], None]) -> None:
        self._callbacks.remove(callback)

    @property
    def active(self) -> List[int]:
        """Codes active as the EMCYs seen say (oldest first): a code joins
        when it occurs and leaves with its fd removal; a classic reset
        (0x0000) clears them all (the EMCY does not say which went away)."""
        with self.node.line._cond:
            return [key[0] for key in self._active]

    @property
    def active_emcys(self) -> List[Emcy]:
        """The last EMCY of each active error."""
        with self.node.line._cond:
            return list(self._active.values())

    def reset(self) -> None:
        """Forget the log and the active errors (python-canopen)."""
        with self.node.line._cond:
            self.log.clear()
            self._active.clear()

    def wait(self, code: Optional[int] = None, timeout: Optional[float] = 10.0) -> Emcy:
        """Block until an EMCY (of `code`, when given) arrives after this call;
        returns it. TimeoutError when none came in time."""
        line = self.node.line
        with line._cond:
            start = self._seq
        found: List[Emcy] = []

        def arrived() -> bool:
            fresh = list(self.log)[-(self._seq - start):] if self._seq > start else []
            for emcy in fresh:
                if code is None or emcy.code == code:
                    found.append(emcy)
                    return True
            return False

        what = "an EMCY" if code is None else f"EMCY 0x{code:04X}"
        line._waiter.wait(arrived, timeout, f"{self.node._where}: wait for {what}",
                          lambda: f"no {what}")
        return found[0]

    def _event(self, emcy: Emcy) -> Callable[[], None]:
        """Record (under the line's condition); returns the callbacks to run."""
        self.log.append(emcy)
        self._seq += 1
        if emcy.is_reset:
            self._active.clear()
        elif emcy.fd and not emcy.occurred:
            self._active.pop((emcy.code, emcy.logical_device), None)
        else:
            key = (emcy.code, emcy.logical_device)
            self._active.pop(key, None)
            self._active[key] = emcy
        return lambda: self._callbacks.fire(emcy)

