"""LSS master (CiA 305) of a line: give node-ids to devices known only by
their LSS address (0x1018:01..04), find them by fast scan or by ranges.

    line.lss.switch_global("configuration")
    line.lss.inquire("node_id")                       # -> 5
    found = line.lss.fast_scan([10, 11, 12])          # every unconfigured device
    found = await line.lss.afast_scan([10, 11, 12])   # the same, awaited
    device = line.lss.fast_scan_identify()            # one, left in configuration
    found = line.lss.fast_scan([10], match={"vendor_id": 0x1234}, skip=["revision"])

One request at a time per line, run by the runtime's C master; each call
blocks until it ends (or is awaited with the `a...` form).
"""

from __future__ import annotations

import asyncio
import logging
from typing import (Any, Callable, Dict, Generator, Generic, List, Mapping, NamedTuple,
                    Optional, Sequence, Tuple, TypeVar)

from .._binding.constants import EventKind, LssRequest, LssStatus
from .._binding.context import Deferred, LineContext, LocalNodeService
from .._binding.runtime import Event
from .._aio import LoopArg
from .._callbacks import CallbackList, Until
from ..errors import CanopenFDError, ConfigurationError

__all__ = ["LssDevice", "LssError", "LssMaster", "LssSlave"]

log = logging.getLogger(__name__)

SWITCH_GLOBAL = 100            # CO_RT_LSS_SWITCH_GLOBAL
ACTIVATE_BIT_TIMING = 101      # CO_RT_LSS_ACTIVATE_BIT_TIMING
_STATES = {"waiting": 0, "configuration": 1}
_INQUIRE = {"vendor_id": 0x5A, "product_code": 0x5B, "revision": 0x5C, "serial": 0x5D,
            "node_id": 0x5E}
_U32 = (1 << 32) - 1
# fast scan filters per part of the address (co_lss_fastscan_filter_t)
_PARTS = ("vendor_id", "product_code", "revision", "serial")
FS_SCAN, FS_SKIP, FS_MATCH = 0, 1, 2
T = TypeVar("T")
Result = Dict[str, int]


class LssError(CanopenFDError):
    """An LSS request did not succeed: `status` (LssStatus), for REFUSED the
    slave's `error` and `spec_error` codes."""

    def __init__(self, message: str, status: LssStatus, error: int = 0,
                 spec_error: int = 0) -> None:
        super().__init__(message)
        self.status = status
        self.error = error
        self.spec_error = spec_error


class LssDevice(NamedTuple):
    """A device a search found, and the node-id fast scan gave it (0: scan)."""

    vendor_id: int
    product_code: int
    revision: int
    serial: int
    node_id: int


class _Request(Generic[T]):
    """One running request: result() blocks, `await` waits in a task."""

    def __init__(self, context: LineContext, kind: LssRequest, what: str,
                 finish: Callable[[Result, List[LssDevice]], T]) -> None:
        self._context = context
        self.kind = kind
        self.what = what
        self._finish = finish
        self.outcome: Optional[Tuple[Result, List[LssDevice]]] = None

    def ended(self, outcome: Tuple[Result, List[LssDevice]]) -> None:
        """Under the line's condition: keep the outcome (its notify wakes the waits)."""
        self.outcome = outcome

    def _value(self) -> T:
        assert self.outcome is not None
        return self._finish(*self.outcome)

    def _until(self) -> "Until[bool]":
        return Until(lambda: self.outcome is not None, self.what,
                     lambda: "the LSS request has not ended")

    def result(self, timeout: Optional[float] = None) -> T:
        self._context.waiter.wait_until(self._until(), timeout)
        return self._value()

    async def aresult(self, timeout: Optional[float] = None) -> T:
        """result() for `await`. Cancelling the awaiting task cancels the
        request (the master is free for the next one at once)."""
        try:
            await self._context.waiter.await_until(self._until(), timeout)
        except asyncio.CancelledError:
            try:
                self.cancel()
            except CanopenFDError:
                pass    # closed meanwhile: nothing runs any more
            raise
        return self._value()

    def cancel(self) -> None:
        """End the request now: result() then raises LssError (cancelled).
        Nothing goes on the bus; a slave keeps the state the frames sent so
        far gave it."""
        with self._context.cond:
            running = self.outcome is None
        if running:
            self._context.runtime.lss_cancel(self._context.index, f"cancel of {self.what}")

    def __await__(self) -> Generator[Any, None, T]:
        return self.aresult().__await__()


def _check_u32(value: object, name: str, where: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= _U32:
        raise ConfigurationError(f"{where}: {name} must be an int 0..0xFFFFFFFF, got {value!r}")
    return value


def _check_range(value: object, name: str, where: str) -> Tuple[int, int]:
    if not isinstance(value, tuple) or len(value) != 2:
        raise ConfigurationError(f"{where}: {name} must be a (low, high) tuple, got {value!r}")
    low = _check_u32(value[0], f"{name}[0]", where)
    high = _check_u32(value[1], f"{name}[1]", where)
    if low > high:
        raise ConfigurationError(f"{where}: {name} low 0x{low:X} is above high 0x{high:X}")
    return low, high


class LssMaster:
    """The LSS master of one line (`line.lss`)."""

    def __init__(self, context: LineContext) -> None:
        self._context = context
        self._where = context.where
        self._running: Optional[_Request[Any]] = None
        #: Step timeout in ms (an answer must come within it; 0 = 100 ms).
        self.timeout_ms = 100
        #: How long a step several slaves may answer (fast scan checks, scan
        #: ranges) stays open after its first answer, for the answers of
        #: slower slaves, in ms: at most timeout_ms; None = timeout_ms / 8.
        self.settle_ms: Optional[int] = None
        context.subscribe(EventKind.LSS, self._event)

    # ---------------------------------------------------------------- no answer
    def switch_global(self, state: str) -> None:
        """Every slave to "waiting" or "configuration" (no answer)."""
        where = f"lss.switch_global({state!r}) on {self._where}"
        if state not in _STATES:
            raise ConfigurationError(f"{where}: state must be 'waiting' or 'configuration'")
        self._runtime_start(SWITCH_GLOBAL, [_STATES[state]], [], where)

    def activate_bit_timing(self, delay_ms: int) -> None:
        """Slaves switch to their configured bit timing after delay_ms (no answer)."""
        where = f"lss.activate_bit_timing({delay_ms!r}) on {self._where}"
        if isinstance(delay_ms, bool) or not isinstance(delay_ms, int) or \
                not 0 <= delay_ms <= 0xFFFF:
            raise ConfigurationError(f"{where}: delay_ms must be an int 0..65535")
        self._runtime_start(ACTIVATE_BIT_TIMING, [delay_ms], [], where)

    # ---------------------------------------------------------------- requests
    def start_switch_selective(self, vendor_id: int, product_code: int, revision: int,
                               serial: int) -> "_Request[bool]":
        where = f"lss.switch_selective(...) on {self._where}"
        values = [_check_u32(v, n, where) for v, n in
                  ((vendor_id, "vendor_id"), (product_code, "product_code"),
                   (revision, "revision"), (serial, "serial"))]
        return self._start(LssRequest.SWITCH_SELECTIVE, values, [], where, _answered)

    def switch_selective(self, vendor_id: int, product_code: int, revision: int,
                         serial: int) -> bool:
        """The slave with this address to configuration: True when it answered."""
        return self.start_switch_selective(vendor_id, product_code, revision,
                                           serial).result()

    async def aswitch_selective(self, vendor_id: int, product_code: int, revision: int,
                                serial: int) -> bool:
        return await self.start_switch_selective(vendor_id, product_code, revision, serial)

    def start_configure_node_id(self, node_id: int) -> "_Request[None]":
        where = f"lss.configure_node_id({node_id!r}) on {self._where}"
        if isinstance(node_id, bool) or not isinstance(node_id, int) or \
                not (1 <= node_id <= 127 or node_id == 255):
            raise ConfigurationError(f"{where}: node_id must be 1..127 or 255 (unconfigured)")
        return self._start(LssRequest.CONFIGURE_NODE_ID, [node_id], [], where, _confirmed)

    def configure_node_id(self, node_id: int) -> None:
        """The slave in configuration takes node_id as its pending node-id;
        LssError when it refuses or does not answer."""
        self.start_configure_node_id(node_id).result()

    async def aconfigure_node_id(self, node_id: int) -> None:
        await self.start_configure_node_id(node_id)

    def start_configure_bit_timing(self, table_index: int, table_selector: int = 0
                                   ) -> "_Request[None]":
        where = f"lss.configure_bit_timing({table_index!r}) on {self._where}"
        for value, name in ((table_index, "table_index"), (table_selector, "table_selector")):
            if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 255:
                raise ConfigurationError(f"{where}: {name} must be an int 0..255")
        return self._start(LssRequest.CONFIGURE_BIT_TIMING, [table_selector, table_index], [],
                           where, _confirmed)

    def configure_bit_timing(self, table_index: int, table_selector: int = 0) -> None:
        self.start_configure_bit_timing(table_index, table_selector).result()

    async def aconfigure_bit_timing(self, table_index: int, table_selector: int = 0) -> None:
        await self.start_configure_bit_timing(table_index, table_selector)

    def start_store(self) -> "_Request[None]":
        return self._start(LssRequest.STORE, [], [], f"lss.store() on {self._where}",
                           _confirmed)

    def store(self) -> None:
        """The slave in configuration stores its pending node-id (and bit timing)."""
        self.start_store().result()

    async def astore(self) -> None:
        await self.start_store()

    def start_inquire(self, what: str) -> "_Request[int]":
        where = f"lss.inquire({what!r}) on {self._where}"
        if what not in _INQUIRE:
            raise ConfigurationError(f"{where}: what must be one of {', '.join(_INQUIRE)}")
        return self._start(LssRequest.INQUIRE, [_INQUIRE[what]], [], where, _value)

    def inquire(self, what: str) -> int:
        """A number of the slave in configuration: vendor_id, product_code,
        revision, serial or node_id (its active one)."""
        return self.start_inquire(what).result()

    async def ainquire(self, what: str) -> int:
        return await self.start_inquire(what)

    def start_identify_remote(self, vendor_id: int, product_code: int,
                              revisions: Tuple[int, int] = (0, _U32),
                              serials: Tuple[int, int] = (0, _U32)) -> "_Request[int]":
        where = f"lss.identify_remote(...) on {self._where}"
        values = self._address_ranges(vendor_id, product_code, revisions, serials, where)
        return self._start(LssRequest.IDENTIFY_REMOTE, values, [], where, _answers)

    def identify_remote(self, vendor_id: int, product_code: int,
                        revisions: Tuple[int, int] = (0, _U32),
                        serials: Tuple[int, int] = (0, _U32)) -> int:
        """How many slaves with this vendor/product and a revision and serial in
        the ranges answered (0 = none)."""
        return self.start_identify_remote(vendor_id, product_code, revisions,
                                          serials).result()

    async def aidentify_remote(self, vendor_id: int, product_code: int,
                               revisions: Tuple[int, int] = (0, _U32),
                               serials: Tuple[int, int] = (0, _U32)) -> int:
        return await self.start_identify_remote(vendor_id, product_code, revisions, serials)

    def start_identify_non_configured(self) -> "_Request[int]":
        return self._start(LssRequest.IDENTIFY_NON_CONFIGURED, [], [],
                           f"lss.identify_non_configured() on {self._where}", _answers)

    def identify_non_configured(self) -> int:
        """How many slaves without a node-id answered (0 = none)."""
        return self.start_identify_non_configured().result()

    async def aidentify_non_configured(self) -> int:
        return await self.start_identify_non_configured()

    def start_fast_scan(self, node_ids: Sequence[int], *,
                        match: Optional[Mapping[str, int]] = None,
                        skip: Sequence[str] = ()) -> "_Request[List[LssDevice]]":
        where = f"lss.fast_scan({list(node_ids)!r}) on {self._where}"
        ids = list(node_ids)
        if not 1 <= len(ids) <= 127 or any(isinstance(i, bool) or not isinstance(i, int) or
                                           not 1 <= i <= 127 for i in ids):
            raise ConfigurationError(f"{where}: node_ids must be 1..127 ints, 1 to 127 of them")
        return self._start(LssRequest.FASTSCAN, [], ids, where, _found,
                           _fastscan_filter(match, skip, where))

    def fast_scan(self, node_ids: Sequence[int], *, match: Optional[Mapping[str, int]] = None,
                  skip: Sequence[str] = ()) -> List[LssDevice]:
        """Find every device without a node-id, give each the next of node_ids
        and switch it back to waiting (it resets communication with it).
        Filters (CiA 305): `match` {part: value} checks a part of the LSS
        address ('vendor_id', 'product_code', 'revision', 'serial') with one
        frame, only devices with that value are found; `skip` parts are not
        looked at (reported 0; not 'vendor_id')."""
        return self.start_fast_scan(node_ids, match=match, skip=skip).result()

    async def afast_scan(self, node_ids: Sequence[int], *,
                         match: Optional[Mapping[str, int]] = None,
                         skip: Sequence[str] = ()) -> List[LssDevice]:
        return await self.start_fast_scan(node_ids, match=match, skip=skip)

    def start_fast_scan_identify(self, *, match: Optional[Mapping[str, int]] = None,
                                 skip: Sequence[str] = (), timeout_ms: Optional[int] = None
                                 ) -> "_Request[Optional[LssDevice]]":
        where = f"lss.fast_scan_identify() on {self._where}"
        return self._start(LssRequest.FASTSCAN, [], [], where, _identified,
                           _fastscan_filter(match, skip, where), timeout_ms)

    def fast_scan_identify(self, *, match: Optional[Mapping[str, int]] = None,
                           skip: Sequence[str] = (), timeout_ms: Optional[int] = None
                           ) -> Optional[LssDevice]:
        """Find one device without a node-id by fast scan (filters as
        fast_scan) and leave it selected in the configuration state, its
        node-id untouched: the next configure_node_id, store or inquire
        goes to it; switch_global('waiting') lets it go. None when no device
        (passing the filters) is unconfigured. Its node_id is 0.
        `timeout_ms`: this scan's step timeout instead of lss.timeout_ms
        (which stays as it is for the line's other users)."""
        return self.start_fast_scan_identify(match=match, skip=skip,
                                             timeout_ms=timeout_ms).result()

    async def afast_scan_identify(self, *, match: Optional[Mapping[str, int]] = None,
                                  skip: Sequence[str] = (), timeout_ms: Optional[int] = None
                                  ) -> Optional[LssDevice]:
        return await self.start_fast_scan_identify(match=match, skip=skip,
                                                   timeout_ms=timeout_ms)

    def scan(self, vendor_id: int, product_code: int, revisions: Tuple[int, int] = (0, _U32),
             serials: Tuple[int, int] = (0, _U32)) -> List[LssDevice]:
        """Every device of vendor/product (configured or not) whose revision and
        serial lie in the ranges, found by halving them (identify remote slave)."""
        return self.start_scan(vendor_id, product_code, revisions, serials).result()

    def start_scan(self, vendor_id: int, product_code: int,
                   revisions: Tuple[int, int] = (0, _U32),
                   serials: Tuple[int, int] = (0, _U32)) -> "_Request[List[LssDevice]]":
        where = f"lss.scan(...) on {self._where}"
        values = self._address_ranges(vendor_id, product_code, revisions, serials, where)
        return self._start(LssRequest.SCAN, values, [], where, _found)

    async def ascan(self, vendor_id: int, product_code: int,
                    revisions: Tuple[int, int] = (0, _U32),
                    serials: Tuple[int, int] = (0, _U32)) -> List[LssDevice]:
        return await self.start_scan(vendor_id, product_code, revisions, serials)

    @staticmethod
    def _address_ranges(vendor_id: int, product_code: int, revisions: Tuple[int, int],
                        serials: Tuple[int, int], where: str) -> List[int]:
        return [_check_u32(vendor_id, "vendor_id", where),
                _check_u32(product_code, "product_code", where),
                *_check_range(revisions, "revisions", where),
                *_check_range(serials, "serials", where)]

    @property
    def stats(self) -> Dict[str, int]:
        """The master's counters (co_lss_master_stats_t)."""
        return self._context.runtime.lss_stats(self._context.index,
                                               f"lss.stats of {self._where}")

    # ---------------------------------------------------------------- plumbing
    def _runtime_start(self, kind: int, values: List[int], node_ids: List[int],
                       where: str, fastscan_filter: Sequence[Tuple[int, int]] = (),
                       timeout_ms: Optional[int] = None) -> None:
        # a per-call timeout leaves lss.timeout_ms alone: another user of the
        # line's master between two of our requests keeps its own
        timeout, name = (self.timeout_ms, "lss.timeout_ms") if timeout_ms is None \
            else (timeout_ms, "timeout_ms")
        if isinstance(timeout, bool) or not isinstance(timeout, int) or \
                not 0 <= timeout <= 60000:
            raise ConfigurationError(f"{where}: {name} must be an int 0..60000, got "
                                     f"{timeout!r}")
        settle = self.settle_ms
        if settle is not None and (isinstance(settle, bool) or not isinstance(settle, int) or
                                   not 1 <= settle <= (timeout or 100)):
            raise ConfigurationError(f"{where}: lss.settle_ms must be None or an int 1.."
                                     f"{timeout or 100} ({name}), got {settle!r}")
        self._context.runtime.lss_start(self._context.index, kind, values, node_ids,
                                        timeout, where, settle or 0, fastscan_filter)

    def _start(self, kind: LssRequest, values: List[int], node_ids: List[int], where: str,
               finish: Callable[[Result, List[LssDevice], str], T],
               fastscan_filter: Sequence[Tuple[int, int]] = (),
               timeout_ms: Optional[int] = None) -> "_Request[T]":
        request: _Request[T] = _Request(self._context, kind, where,
                                        lambda r, d: finish(r, d, where))
        with self._context.cond:
            if self._running is not None:
                raise ConfigurationError(f"{where}: {self._running.what} is still running "
                                         "(one LSS request at a time per line)")
            self._running = request
        try:
            self._runtime_start(int(kind), values, node_ids, where, fastscan_filter, timeout_ms)
        except BaseException:
            with self._context.cond:
                self._running = None
            raise
        return request

    def _event(self, event: Event) -> Deferred:
        """CO_EV_LSS: a = co_lss_request_t, b = co_lss_status_t."""
        request = self._running
        if request is None or event.a != int(request.kind):
            return None
        self._running = None
        result, devices = self._context.runtime.lss_result(self._context.index, request.what)
        found = [LssDevice(*address, node_id) for address, node_id in devices]
        request.ended((result, found))
        return None


def _fastscan_filter(match: Optional[Mapping[str, int]], skip: Sequence[str], where: str
                     ) -> List[Tuple[int, int]]:
    """(kind, value) per part of the address, for the runtime."""
    parts = [(FS_SCAN, 0)] * 4
    if isinstance(skip, str):
        raise ConfigurationError(f"{where}: skip must be a list of part names, got {skip!r}")
    for name, value in dict(match or {}).items():
        if name not in _PARTS:
            raise ConfigurationError(f"{where}: match {name!r}: the parts are "
                                     f"{', '.join(_PARTS)}")
        parts[_PARTS.index(name)] = (FS_MATCH, _check_u32(value, f"match[{name!r}]", where))
    for name in skip:
        if name not in _PARTS:
            raise ConfigurationError(f"{where}: skip {name!r}: the parts are "
                                     f"{', '.join(_PARTS)}")
        if name == "vendor_id":
            raise ConfigurationError(f"{where}: the vendor_id cannot be skipped (every fast "
                                     "scan starts with it)")
        if parts[_PARTS.index(name)][0] == FS_MATCH:
            raise ConfigurationError(f"{where}: {name} is both matched and skipped")
        parts[_PARTS.index(name)] = (FS_SKIP, 0)
    return parts


# What each request gives back, from the C result.
def _status(result: Result) -> LssStatus:
    try:
        return LssStatus(result["status"])
    except ValueError:
        return LssStatus.LOST


def _fail(result: Result, where: str) -> LssError:
    status = _status(result)
    text = {LssStatus.TIMEOUT: "no answer", LssStatus.CANCELLED: "cancelled",
            LssStatus.TX_FAILED: "the tx queue refused a frame",
            LssStatus.DUPLICATE: "two devices share one LSS address",
            LssStatus.NO_NODE_ID: "more devices than node-ids",
            LssStatus.LOST: "a device stopped answering",
            LssStatus.FULL: "more devices than 127"}.get(status, status.name)
    if status == LssStatus.REFUSED:
        meaning = {1: "not supported / out of range", 2: "storage media access error"}.get(
            result["error"], "implementation specific")
        text = f"refused with error {result['error']} ({meaning}), spec {result['spec_error']}"
    return LssError(f"{where}: {text}", status, result["error"], result["spec_error"])


def _answered(result: Result, devices: List[LssDevice], where: str) -> bool:
    if _status(result) in (LssStatus.OK, LssStatus.TIMEOUT):
        return _status(result) == LssStatus.OK
    raise _fail(result, where)


def _confirmed(result: Result, devices: List[LssDevice], where: str) -> None:
    if _status(result) != LssStatus.OK:
        raise _fail(result, where)


def _value(result: Result, devices: List[LssDevice], where: str) -> int:
    _confirmed(result, devices, where)
    return int(result["value"])


def _answers(result: Result, devices: List[LssDevice], where: str) -> int:
    if _status(result) not in (LssStatus.OK, LssStatus.TIMEOUT):
        raise _fail(result, where)
    return int(result["answers"])


def _found(result: Result, devices: List[LssDevice], where: str) -> List[LssDevice]:
    if _status(result) != LssStatus.OK:
        error = _fail(result, where)
        error.found = devices   # type: ignore[attr-defined]
        raise error
    return devices


def _identified(result: Result, devices: List[LssDevice], where: str
                ) -> Optional[LssDevice]:
    _confirmed(result, devices, where)
    return devices[0] if devices else None


# ---------------------------------------------------------------- the local node's slave
SLAVE_STATE = 110          # CO_RT_LSS_SLAVE_STATE
SLAVE_STORE = 111          # CO_RT_LSS_SLAVE_STORE
SLAVE_ACTIVATE = 112       # CO_RT_LSS_SLAVE_ACTIVATE
SLAVE_BIT_TIMING = 113     # CO_RT_LSS_SLAVE_BIT_TIMING
SLAVE_CONFIGURED = 114     # CO_RT_LSS_SLAVE_CONFIGURED
SLAVE_EVENTS = 255         # the node of the slave's events (the master's: 0)
UNCONFIGURED = 255
STORE_OK, STORE_MEDIA_ERROR = 0, 2


class LssSlave(LocalNodeService):
    """The LSS slave of a local node (`node.lss`; the C stack runs it when the
    node's OD has 0x1018:04). What it decides itself: configure node-id
    (pending until reset communication), inquire, identify, fast scan. What
    the application decides: store (`on_store`) and which bit timings it
    accepts (`accept_bit_timings`); without them both are "not supported"."""

    def __init__(self, context: LineContext, node_id: int) -> None:
        self._context = context
        self._store: Optional[Callable[[int], None]] = None
        self._bit_timings = 0
        self._state_callbacks = CallbackList(f"LSS state on {context.where}")
        self._configured_callbacks = CallbackList(f"LSS node-id on {context.where}")
        self._configured_hooks: List[Callable[[int], None]] = []
        self._activate_callbacks = CallbackList(f"LSS activate bit timing on {context.where}")
        context.subscribe(EventKind.LSS, self._event, node=SLAVE_EVENTS)

    def on_store(self, callback: Optional[Callable[[int], None]]) -> None:
        """callback(node_id) persists the node-id a master stores (the node
        starts with it next time); an exception answers "storage media
        access error". None: store is "not supported" again."""
        self._store = callback
        self._configure(f"node.lss.on_store on {self._where}")

    def accept_bit_timings(self, indexes: Sequence[int]) -> None:
        """The indexes of the CiA standard bit-timing table (0 = 1000 kbit/s ..
        8 = 10 kbit/s) "configure bit timing" accepts."""
        where = f"node.lss.accept_bit_timings({list(indexes)!r}) on {self._where}"
        mask = 0
        for index in indexes:
            if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index <= 31:
                raise ConfigurationError(f"{where}: indexes must be ints 0..31")
            mask |= 1 << index
        self._bit_timings = mask
        self._configure(where)

    def on_state_change(self, callback: Callable[[str], None],
                        loop: LoopArg = None) -> Callable[[str], None]:
        """callback('waiting' or 'configuration') at each LSS state change."""
        return self._state_callbacks.add(callback, loop)

    def on_configured(self, callback: Callable[[int], None],
                      loop: LoopArg = None) -> Callable[[int], None]:
        """callback(node_id): a node created with node-id 255 got node_id from LSS,
        or a configured node took its pending node-id at NMT reset communication
        (CiA 305); it runs (and boots) with it now."""
        return self._configured_callbacks.add(callback, loop)

    def add_configured_hook(self, hook: Callable[[int], None]) -> None:
        """For the node itself: hook(node_id) runs under the line's condition
        as soon as the event is handled, before any waiter wakes."""
        self._configured_hooks.append(hook)

    def on_activate_bit_timing(self, callback: Callable[[int], None],
                               loop: LoopArg = None) -> Callable[[int], None]:
        """callback(delay_ms): switch to the accepted bit timing after delay_ms."""
        return self._activate_callbacks.add(callback, loop)

    @property
    def info(self) -> Dict[str, Any]:
        """{'state': 'waiting' | 'configuration', 'active', 'pending',
        'persistent': node-ids (255 = none)}."""
        state, active, pending, persistent = self._context.runtime.lss_slave_info(
            self._context.index, f"node.lss.info on {self._where}")
        return {"state": "configuration" if state else "waiting", "active": active,
                "pending": pending, "persistent": persistent}

    def _configure(self, where: str) -> None:
        self._context.runtime.lss_slave_config(self._context.index, self._store is not None,
                                               self._bit_timings, where)

    def _event(self, event: Event) -> Deferred:
        """CO_EV_LSS of this node: a = CO_RT_LSS_SLAVE_*, b = its value."""
        if event.a == SLAVE_STATE:
            state = "configuration" if event.b else "waiting"
            return lambda: self._state_callbacks.fire(state)
        if event.a == SLAVE_ACTIVATE:
            delay = event.b
            return lambda: self._activate_callbacks.fire(delay)
        if event.a == SLAVE_CONFIGURED:
            node_id = event.b
            for hook in self._configured_hooks:
                hook(node_id)
            return lambda: self._configured_callbacks.fire(node_id)
        if event.a == SLAVE_STORE:
            store, node_id = self._store, event.b
            return lambda: self._answer_store(store, node_id)
        return None

    def _answer_store(self, store: Optional[Callable[[int], None]], node_id: int) -> None:
        """Dispatcher thread: the application persists, then the slave answers."""
        error = STORE_MEDIA_ERROR
        if store is not None:
            try:
                store(node_id)
                error = STORE_OK
            except Exception:  # noqa: BLE001 - the master hears "media error"
                log.exception("%s: LSS store of node-id %d failed", self._where, node_id)
        self._context.runtime.lss_slave_answer(self._context.index, error,
                                               f"LSS store answer on {self._where}")
