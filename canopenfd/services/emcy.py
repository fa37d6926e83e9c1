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
import logging
from typing import Callable, Deque, Dict, Iterable, List, Optional, Set, Tuple, Union

from .._binding.constants import EmcyStatus, EventKind
from .._binding.context import Deferred, LineContext, LocalNodeService
from .._binding.runtime import Event, decode_emcy
from .._aio import LoopArg
from .._callbacks import CallbackList, Until, chain
from .._checks import check_int as _int
from .._checks import check_node_id
from ..decode.emcy import emcy_code_text, emcy_status_text, error_register_text
from ..errors import ClosedError, ConfigurationError
from .errors import ErrorBits
from .served_od import ServedDictionary
from .views import LocalNodeView, NodeView

__all__ = ["Emcy", "EmcyProducer", "EmcyConsumer", "LineEmcy", "LOG_SIZE"]

log = logging.getLogger("canopenfd")

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
        return cls(node, fields.code, fields.error_register, fields.msef,
                   logical_device=fields.logical_device,
                   spec_number=fields.spec_number, status=fields.status,
                   time_stamp=fields.time_stamp, fd=fd,
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


#: What the producer's fields accept (checked one by one, with a message each).
FieldValue = Union[int, bool, bytes]


class EmcyProducer(LocalNodeService):
    """The EMCY producer of our local node (`local_node.emcy`).

    The stack keeps the active errors: the error register (0x1001) follows
    them, a repeated raise sends nothing on classic lines (fd: sent again
    marked "repeated"), and EMCYs leave only in PRE-OPERATIONAL and
    OPERATIONAL (queued meanwhile). The stack raises its own errors too
    (heartbeat or life guarding lost 0x8130, bus-off 0x8140, error passive
    0x8120, RPDO length 0x8210/0x8220, ...)."""

    def __init__(self, context: LineContext, node: LocalNodeView, served: ServedDictionary,
                 errors: ErrorBits) -> None:
        self._context = context
        self.node = node
        self._served = served
        self._errors = errors

    def __repr__(self) -> str:
        return f"<EmcyProducer of {self.node!r}>"

    def _what(self, verb: str, code: object) -> str:
        code_text = f"0x{code:04X}" if isinstance(code, int) and not isinstance(code, bool) \
            else repr(code)
        return f"{verb} EMCY {code_text} on {self._where}"

    def _fields(self, code: object, data: object, register_bits: object,
                logical_device: object, spec_number: object, priority: object,
                non_recoverable: object, time_stamp: object,
                where: str) -> Dict[str, FieldValue]:
        checked_code = _int(code, "code", 1, 0xFFFF, where)
        if not isinstance(data, (bytes, bytearray, memoryview)) or len(data) > 5:
            raise ConfigurationError(f"{where}: data (manufacturer-specific error field) must "
                                     f"be bytes of length 0..5, got {data!r}")
        fields: Dict[str, FieldValue] = {
                  "code": checked_code, "msef": bytes(data),
                  "register_bits": _int(register_bits, "register_bits", 0, 0xFF, where),
                  "logical_device": _int(logical_device, "logical_device", 0, 0xFF, where),
                  "spec_number": _int(spec_number, "spec_number", 0, 0xFFFF, where),
                  "priority": _int(priority, "priority", 0, 7, where),
                  "non_recoverable": int(bool(non_recoverable)),
                  "time_stamp": _int(time_stamp, "time_stamp", 0, _TIME_MAX, where)}
        if self._context.mode != "fd":
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
        return self._context.runtime.emcy(self._context.index, fields, False, where) == 0

    def clear(self, code: int, data: bytes = b"", *, logical_device: int = 0,
              time_stamp: int = 0) -> bool:
        """Clear error `code`: classic lines send the reset EMCY (code 0x0000,
        the remaining error register), fd lines the code with "occurred"
        clear. Returns False (nothing sent) when it was not active."""
        where = self._what("clear", code)
        fields = self._fields(code, data, 0, logical_device, 0, 0, False, time_stamp, where)
        return self._context.runtime.emcy(self._context.index, fields, True, where) == 0

    # The code table (Embedded Office style): application error ids are the
    # node's error-status bits 16..127 (canopenfd.services.errors).
    def define(self, error_id: int, code: int, register_bits: int = 0) -> None:
        """Declare application error `error_id` (16..127) once: its EMCY code
        and 0x1001 class bits (`ErrorRegister.CURRENT`, `.VOLTAGE`,
        `.TEMPERATURE`, ...)."""
        self._errors.define(error_id, code, register_bits)

    def raise_defined(self, error_id: int, info: int = 0) -> bool:
        """Raise a declared error: its EMCY the first time (bytes 3 the id,
        4-5 info); True when new, False when it was raised already."""
        return self._errors.report(error_id, info)

    def clear_defined(self, error_id: int, info: int = 0) -> bool:
        """Clear a declared error (reset EMCY); False when it was not raised."""
        return self._errors.reset(error_id, info)

    def is_raised(self, error_id: int) -> bool:
        return self._errors.is_set(error_id)

    def count(self, error_id: int) -> int:
        """How often `error_id` was raised (repetitions included)."""
        return self._errors.count(error_id)

    def _state(self) -> Dict[str, int]:
        where = f"EMCY state of {self._where}"
        if not self.node.booted:
            raise ConfigurationError(f"{where}: the node is not booted yet")
        return self._context.runtime.emcy_state(self._context.index, where)

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
        count = self._integer(0x1003, 0)
        return [self._integer(0x1003, sub) for sub in range(1, count + 1)]

    def _integer(self, index: int, sub: int) -> int:
        value = self._served.variable_value(index, sub).raw
        if not isinstance(value, int):   # the OD gives the entry a non-integer type
            raise ConfigurationError(f"{self._served.where}: 0x{index:04X}:{sub:02X} must be "
                                     f"an integer entry, got {type(value).__name__} {value!r}")
        return value

    @property
    def dropped(self) -> int:
        """EMCYs lost because the wait queue was full."""
        return self._state()["dropped"]


class EmcyConsumer:
    """The EMCYs of one remote node (`remote_node.emcy`): the line consumes
    them from the first use of `remote_node.emcy` on (CAN-ID 0x80 + node-id)."""

    def __init__(self, context: LineContext, node: NodeView, where: str,
                 line_emcy: "LineEmcy") -> None:
        self._context = context
        self.node = node
        self._where = where
        self._callbacks = CallbackList(f"node {node.node_id} EMCY")
        #: The recent EMCYs, oldest first (at most LOG_SIZE).
        self.log: Deque[Emcy] = collections.deque(maxlen=LOG_SIZE)
        self._active: Dict[Tuple[int, int], Emcy] = {}
        self._seq = 0
        line_emcy.add_consumer(node.node_id, self._event)

    def __repr__(self) -> str:
        return f"<EmcyConsumer of {self.node!r}>"

    def add_callback(self, callback: Callable[[Emcy], None],
                     loop: LoopArg = None) -> Callable[[Emcy], None]:
        """callback(Emcy) for every EMCY of the node (dispatcher thread)."""
        return self._callbacks.add(callback, loop)

    def remove_callback(self, callback: Callable[[Emcy], None]) -> None:
        self._callbacks.remove(callback)

    @property
    def active(self) -> List[int]:
        """Codes active as the EMCYs seen say (oldest first): a code joins
        when it occurs and leaves with its fd removal; a classic reset
        (0x0000) clears them all (the EMCY does not say which went away)."""
        with self._context.cond:
            return [key[0] for key in self._active]

    @property
    def active_emcys(self) -> List[Emcy]:
        """The last EMCY of each active error."""
        with self._context.cond:
            return list(self._active.values())

    def reset(self) -> None:
        """Forget the log and the active errors (python-canopen)."""
        with self._context.cond:
            self.log.clear()
            self._active.clear()

    def _until(self, code: Optional[int]) -> "Until[Optional[Emcy]]":
        """An EMCY (of `code`) arriving after this call; the predicate gives it."""
        with self._context.cond:
            start = self._seq

        def arrived() -> Optional[Emcy]:
            fresh = list(self.log)[-(self._seq - start):] if self._seq > start else []
            for emcy in fresh:
                if code is None or emcy.code == code:
                    return emcy
            return None

        what = "an EMCY" if code is None else f"EMCY 0x{code:04X}"
        return Until(arrived, f"{self._where}: wait for {what}", lambda: f"no {what}")

    def wait(self, code: Optional[int] = None, timeout: Optional[float] = 10.0) -> Emcy:
        """Block until an EMCY (of `code`, when given) arrives after this call;
        returns it. TimeoutError when none came in time."""
        found = self._context.waiter.wait_until(self._until(code), timeout)
        assert found is not None    # the wait ends only once one arrived
        return found

    async def await_(self, code: Optional[int] = None, timeout: Optional[float] = 10.0) -> Emcy:
        """wait() for `await` (`await` is a keyword: PEP 8's trailing underscore)."""
        found = await self._context.waiter.await_until(self._until(code), timeout)
        assert found is not None
        return found

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


class LineEmcy:
    """The EMCYs a line consumes (events EMCY): `line.on_emcy` callbacks and
    the remote nodes' consumers. The runtime hears a node's EMCYs while its
    consumer is in use or `on_emcy(nodes=...)` asked for them (or the local
    node's 0x1028 lists it)."""

    def __init__(self, context: LineContext) -> None:
        self._context = context
        self._callbacks = CallbackList(f"{context.where} EMCY")
        self._nodes: Dict[int, int] = {}     # node-id: on_emcy(nodes=...) calls asking for it
        # each on_emcy(nodes=...) call: its callback and the nodes it asked
        # for, released again by remove_callback
        self._asked: List[Tuple[Callable[[Emcy], None], Tuple[int, ...]]] = []
        self._consumers: Dict[int, Callable[[Emcy], Callable[[], None]]] = {}
        self._consuming: Set[int] = set()    # nodes whose consumer is in use
        context.subscribe(EventKind.EMCY, self._event)

    def add_callback(self, callback: Callable[[Emcy], None],
                     nodes: Optional[Iterable[int]] = None,
                     loop: LoopArg = None) -> Callable[[Emcy], None]:
        """line.on_emcy: callback(Emcy) for every EMCY consumed; start
        consuming those of `nodes`."""
        context = self._context
        wanted = tuple(check_node_id(node_id, f"on_emcy on {context.where}")
                       for node_id in (nodes or ()))
        self._callbacks.add(callback, loop)    # checks it is callable before anything is watched
        with context.cond:
            for node_id in wanted:
                if node_id not in self._nodes and node_id not in self._consuming:
                    context.runtime.emcy_watch(context.index, node_id, True,
                                               f"EMCY of node {node_id} on {context.where}")
                self._nodes[node_id] = self._nodes.get(node_id, 0) + 1
            self._asked.append((callback, wanted))
        return callback

    def remove_callback(self, callback: Callable[[Emcy], None]) -> None:
        """Undo add_callback: the nodes it asked for are no longer consumed
        unless another on_emcy call or a node's consumer still needs them."""
        self._callbacks.remove(callback)
        context = self._context
        with context.cond:
            for position, (asked, wanted) in enumerate(self._asked):
                if asked == callback:
                    del self._asked[position]
                    break
            else:
                return
            for node_id in wanted:
                left = self._nodes[node_id] - 1
                if left:
                    self._nodes[node_id] = left
                    continue
                del self._nodes[node_id]
                if node_id not in self._consuming:
                    try:
                        context.runtime.emcy_watch(context.index, node_id, False,
                                                   f"EMCY of node {node_id} on {context.where}")
                    except ClosedError:
                        pass    # the network closed first: nothing is consumed any more

    def add_consumer(self, node_id: int, record: Callable[[Emcy], Callable[[], None]]) -> None:
        """A remote node's consumer: gets its node's EMCYs once `consume` ran."""
        with self._context.cond:
            self._consumers[node_id] = record

    def consume(self, node_id: int, what: str) -> None:
        """The node's consumer is used: the runtime hears its EMCYs from now on."""
        context = self._context
        with context.cond:
            if node_id not in self._consuming:
                if node_id not in self._nodes:
                    context.runtime.emcy_watch(context.index, node_id, True, what)
                self._consuming.add(node_id)

    def release(self, node_id: int, what: str) -> None:
        """The node is removed: stop hearing it unless on_emcy(nodes=) asked for it."""
        context = self._context
        with context.cond:
            if node_id in self._consuming and node_id not in self._nodes:
                context.runtime.emcy_watch(context.index, node_id, False, what)
            self._consuming.discard(node_id)
            self._consumers.pop(node_id, None)

    def _event(self, event: Event) -> Deferred:
        """CO_EV_EMCY: node = producer, a = 1 FD / 0 classic, data = the EMCY."""
        emcy = Emcy.decode(event.node, event.data, bool(event.a))
        if emcy is None:
            log.warning("%s: malformed EMCY of node %d ignored: %s", self._context.where,
                        event.node, event.data.hex(" "))
            return None
        calls = [lambda: self._callbacks.fire(emcy)]
        record = self._consumers.get(event.node) if event.node in self._consuming else None
        if record is not None:
            calls.insert(0, record(emcy))
        return chain(calls)
