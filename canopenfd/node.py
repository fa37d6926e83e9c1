"""Nodes of a line: our own `LocalNode` and the `RemoteNode`s we watch."""

from __future__ import annotations

import collections
import logging
from typing import TYPE_CHECKING, Any, Callable, Deque, Dict, Optional, Tuple, Union

from ._callbacks import CallbackList
from ._checks import check_ms, check_node_id
from ._binding.constants import AbortCode, HeartbeatEvent, OdOrigin, ParameterGroup, StoreStatus
from .services.indications import READ, WRITE, Indications, ODRequest
from .errors import AbortError, ConfigurationError
from .services.nmt import LocalNmt, NmtCommand, NmtState, RemoteNmt
from .od import ObjectDictionary, ODVariable
from .od.datatypes import DataType

log = logging.getLogger(__name__)

#: 0x1010 / 0x1011 parameter groups by name: (group mask, CiA 301 sub-index).
PARAMETER_GROUPS = {
    "all": (ParameterGroup.ALL, 1),
    "communication": (ParameterGroup.COMMUNICATION, 2),
    "application": (ParameterGroup.APPLICATION, 3),
    "manufacturer": (ParameterGroup.MANUFACTURER, 4),
}

#: What a parameter load found (co_store_status_t), as the texts callbacks get:
#: the C name in lower case with dashes ('too-big'); IO says what failed.
STORE_STATUS = {int(status): {"IO": "io-error"}.get(status.name,
                                                   status.name.lower().replace("_", "-"))
                for status in StoreStatus}

#: The writers on_object_changed names (the runtime reports no others).
_ORIGIN_NAMES = {int(OdOrigin.NETWORK): "network", int(OdOrigin.PDO): "pdo"}

if TYPE_CHECKING:  # pragma: no cover
    from .line import Line
    from .services.emcy import EmcyConsumer, EmcyProducer
    from .services.pdo import PdoMaps
    from .transfer import RemoteAccess, RemoteObjects

StateLike = Union[NmtState, str, int]

# How many recent states a node remembers, so a wait that starts a little
# late still sees a short-lived state (INITIALISING during a reset).
_HISTORY = 64


class _StateHistory:
    """Recent states of a node with a sequence number, for waits."""

    def __init__(self) -> None:
        self.seq = 0
        self._states: Deque[Tuple[int, NmtState]] = collections.deque(maxlen=_HISTORY)

    def push(self, state: NmtState) -> None:
        self.seq += 1
        self._states.append((self.seq, state))

    def seen_since(self, seq: int, state: NmtState) -> bool:
        return any(s == state for n, s in self._states if n > seq)


class LocalNode:
    """The node this process runs on a line (NMT slave + heartbeat producer).

    Created by `Line.create_local_node()`: it boots at once (boot-up message,
    then PRE-OPERATIONAL) and produces its heartbeat every `heartbeat_ms`.
    With boot=False it waits for `boot()`, so callbacks registered first see
    the very first transition.
    """

    def __init__(self, line: "Line", node_id: int, heartbeat_ms: int,
                 od: Optional[ObjectDictionary] = None, store: Optional[str] = None) -> None:
        self.line = line
        self.node_id = node_id
        #: The object dictionary this node serves (None: NMT and heartbeat only).
        self.od = od
        #: Where saved parameters (0x1010) live: a file path, an object with
        #: load()/save() (see canopenfd.services.store), or None.
        self.store = store
        self._store_problems = CallbackList(f"node {node_id} store problem")
        self._changed = CallbackList(f"node {node_id} object changed")
        self._indications = Indications(self)
        self._domains: Dict[Tuple[int, int], int] = {}
        self._booted = False
        self.nmt = LocalNmt(self)
        self._heartbeat_default_ms = heartbeat_ms
        self._heartbeat_ms = heartbeat_ms
        self._allow_operational = True
        self._history = _StateHistory()
        self._state_changed = CallbackList(f"node {node_id} state change")
        self._vetoed = CallbackList(f"node {node_id} veto")
        self._reset = CallbackList(f"node {node_id} reset")

    def __repr__(self) -> str:
        return f"<LocalNode {self.node_id} on {self.line.channel!r}>"

    @property
    def _where(self) -> str:
        return f"local node {self.node_id} on line {self.line.channel!r}"

    # ---------------------------------------------------------------- boot
    @property
    def booted(self) -> bool:
        return self._booted

    def boot(self) -> None:
        """Power the node on: boot-up message, PRE-OPERATIONAL, heartbeat.
        Only once; later restarts are NMT resets (`apply('reset-node')`)."""
        with self.line._cond:
            if self._booted:
                raise ConfigurationError(
                    f"{self._where} is already booted (restart it with apply('reset-node'))")
            if self.od is not None:
                self._define_od()
                self._indications.register_all()
                for (index, sub), capacity in self._domains.items():
                    self._give_domain(index, sub, capacity)
            self.line._create_node(self.node_id, self._heartbeat_ms, self._where)
            self._booted = True

    def _define_od(self) -> None:
        from ._binding.od_tables import definitions
        overrides: Dict[Tuple[int, int], Any] = {}
        if self._heartbeat_ms and self._has_1017:
            overrides[(0x1017, 0)] = self._heartbeat_ms
        defs, count, _keep = definitions(self.od, self.node_id, overrides)
        path = self.store if isinstance(self.store, str) else None
        self.line._define_od(defs, count, path, self._where)
        if self.store is not None and path is None:
            self._open_application_store()

    def _open_application_store(self) -> None:
        what = f"parameter store {self.store!r} of {self._where}"
        try:
            image = self.store.load()
            status = StoreStatus.OK if image else StoreStatus.EMPTY
            image = bytes(image or b"")
        except Exception:  # noqa: BLE001 - an unreadable medium: run on defaults, say so
            log.exception("%s: load() failed; the node starts from defaults", what)
            image, status = b"", StoreStatus.IO
        self.line._rt.store_application(self.line.index, image, status, what)

    def _persist(self, what: str) -> Optional[int]:
        """Give the staged image to the application store: 0, the CiA abort
        0x08000020 (data cannot be stored) when its save() raised, None when
        no image was staged."""
        rt = self.line._rt
        image = rt.store_staged(self.line.index, what)
        if image is None:
            return None
        try:
            self.store.save(image)
        except Exception:  # noqa: BLE001 - reported as the CiA abort, logged with the cause
            log.exception("%s: the parameter store's save() failed", what)
            return int(AbortCode.DATA_STORE)
        return 0

    def _event_persist(self, token: int) -> Callable[[], None]:
        """A network save/restore waits until the image is on the medium."""
        what = f"0x1010/0x1011 over the network on {self._where}"

        def persist() -> None:
            code = self._persist(what)
            self.line._rt.od_answer(self.line.index, token, code or 0, what)
        return persist

    @property
    def _has_1017(self) -> bool:
        return self.od is not None and isinstance(self.od.get_variable(0x1017, 0), ODVariable)

    # ---------------------------------------------------------------- values
    def __getitem__(self, key: Any) -> Union["LocalValue", "LocalObject"]:
        """The value of an entry of the served OD, by index, "index:sub",
        (index, sub), name or "Object.Sub": `node["Producer heartbeat time"].raw`;
        an ARRAY/RECORD gives a LocalObject: `node[0x1018][1].raw`."""
        entry = self._entry(key)
        if isinstance(entry, ODVariable):
            return LocalValue(self, entry)
        return LocalObject(self, entry)

    def _entry(self, key: Any) -> Any:
        if self.od is None:
            raise ConfigurationError(f"{self._where} serves no object dictionary "
                                     "(create it with od=...)")
        return self.od[key]

    def serve_domain(self, key: Any, capacity: int) -> None:
        """Keep the data of DOMAIN entry `key` in the stack's memory (up to
        `capacity` bytes, allocated once): the network then uploads and
        downloads it (any size up to capacity, in chunks, no Python per
        frame) and `node[key].data` reads or replaces it. A download that
        fails leaves it empty, never half old and half new."""
        entry = self._entry(key)
        what = f"serve_domain({key!r}) on {self._where}"
        if not isinstance(entry, ODVariable) or entry.data_type != DataType.DOMAIN:
            raise ConfigurationError(f"{what}: {entry!r} is not a DOMAIN entry")
        if isinstance(capacity, bool) or not isinstance(capacity, int) or \
                not 0 < capacity < 1 << 32:
            raise ConfigurationError(f"{what}: capacity must be 1..2^32-1 bytes, got "
                                     f"{capacity!r}")
        where = (entry.index, entry.subindex)
        if where in self._domains:
            raise ConfigurationError(f"{what}: the domain already has memory")
        self._domains[where] = capacity
        if self._booted:
            self._give_domain(entry.index, entry.subindex, capacity)

    def _give_domain(self, index: int, sub: int, capacity: int) -> None:
        self.line._rt.od_domain(self.line.index, index, sub, capacity,
                                f"memory domain 0x{index:04X}:{sub:02X} of {self._where}")

    # ---------------------------------------------------------------- indications
    def on_read(self, key: Any, callback: Optional[Callable[[ODRequest], Any]] = None):
        """callback(request) before the network (SDO/USDO upload) reads the
        entry `key` (an ARRAY/RECORD: any of its sub-indices). It may refresh
        the value (`node[key].raw = ...`), refuse the read (return an abort
        code or raise AbortError) or `request.defer()` and answer later."""
        return self._indications.add(key, READ, callback)

    def on_write(self, key: Any, callback: Optional[Callable[[ODRequest], Any]] = None):
        """callback(request) before a network write of `key` changes anything:
        `request.value` is the new value (type, length and limits already
        checked). Return None to accept, an abort code (or raise AbortError)
        to refuse, or `request.defer()` and answer later. Without callback: a
        decorator."""
        return self._indications.add(key, WRITE, callback)

    def remove_indication(self, callback: Callable[[ODRequest], Any]) -> None:
        """Forget an on_read/on_write callback."""
        self._indications.remove(callback)

    def _event_request(self, key: int, token: int) -> Optional[Callable[[], None]]:
        return self._indications.event(key, token)

    def export_eds(self, dest: Any = None) -> Optional[str]:
        """The served OD as an EDS (CiA 306): written to dest (a path or a
        text file), or returned as text when dest is None."""
        from .od import export_eds
        return export_eds(self._entry_od(), dest)

    def export_dcf(self, dest: Any = None) -> Optional[str]:
        """The served OD as a DCF: the EDS plus this node's id and every
        entry's current value as its ParameterValue (domains left out)."""
        import copy

        from .od import export_dcf
        snapshot = copy.deepcopy(self._entry_od())
        snapshot.node_id = self.node_id
        for variable in snapshot.entries():
            if variable.data_type == DataType.DOMAIN or not self._booted:
                continue
            variable.value = self[(variable.index, variable.subindex)].raw
        return export_dcf(snapshot, dest)

    def _entry_od(self) -> ObjectDictionary:
        if self.od is None:
            raise ConfigurationError(f"{self._where} serves no object dictionary")
        return self.od

    def save_parameters(self, group: str = "all") -> None:
        """What writing "save" to 0x1010 does: the stored entries of `group`
        ('all', 'communication', 'application', 'manufacturer') go to the store
        file, atomically; they come back at the next boot or reset."""
        self._store_call(group, True)

    def restore_defaults(self, group: str = "all") -> None:
        """What writing "load" to 0x1011 does: forget the saved values of
        `group`, so the next reset loads the defaults."""
        self._store_call(group, False)

    def _store_call(self, group: str, save: bool) -> None:
        what = f"{'save_parameters' if save else 'restore_defaults'}({group!r}) on {self._where}"
        if group not in PARAMETER_GROUPS:
            raise ConfigurationError(f"{what}: group must be one of {', '.join(PARAMETER_GROUPS)}")
        if not self._booted:
            raise ConfigurationError(f"{what}: the node is not booted yet")
        mask, sub = PARAMETER_GROUPS[group]
        code = self.line._od_store(mask, save, what)
        if code == 0 and self.store is not None and not isinstance(self.store, str):
            persisted = self._persist(what)
            if persisted is not None:
                self.line._rt.store_finish(self.line.index, persisted == 0, what)
                code = persisted
        if code:
            raise AbortError(code, self.node_id, 0x1010 if save else 0x1011, sub, what)

    def _consumer_entry(self, node_id: int) -> Optional[Tuple[int, int]]:
        """(sub-index, ms) of the 0x1016 entry that monitors node_id, if any."""
        if self.od is None or 0x1016 not in self.od:
            return None
        consumers = self[0x1016]
        for variable in self.od[0x1016].values():
            if variable.subindex == 0:
                continue
            value = consumers[variable.subindex].raw
            if (value >> 16) & 0x7F == node_id and value & 0xFFFF:
                return variable.subindex, value & 0xFFFF
        return None

    def on_object_changed(self, callback: Callable[["LocalValue", str], None]):
        """callback(value, origin) after an entry was written by the network
        (USDO/SDO download: origin 'network') or a received PDO ('pdo'); the
        application's own writes are not echoed. `value.raw` reads the new
        value."""
        return self._changed.add(callback)

    def _event_changed(self, key: int, origin: int) -> Optional[Callable[[], None]]:
        var = self.od.get_variable(key >> 8, key & 0xFF) if self.od is not None else None
        if var is None:
            return None
        value = LocalValue(self, var)
        name = _ORIGIN_NAMES.get(origin, str(origin))
        return lambda: self._changed.fire(value, name)

    def on_store_problem(self, callback: Callable[[str, int], None]):
        """callback(status, records_skipped) when saved parameters could not be
        used at boot or reset ('damaged', 'foreign', 'io-error', 'too-big'):
        the node then runs on its defaults."""
        return self._store_problems.add(callback)

    @property
    def store_status(self) -> Optional[str]:
        """What the last parameter load (boot or reset) found in the store:
        'ok', 'empty', 'damaged', 'foreign', 'io-error', 'too-big'; None
        without a store or before boot."""
        if self.store is None or not self._booted:
            return None
        code = self.line._rt.store_status(self.line.index, f"store status of {self._where}")
        return STORE_STATUS.get(code, str(code))

    def _event_store(self, status: int, skipped: int) -> Optional[Callable[[], None]]:
        text = STORE_STATUS.get(status, str(status))
        if text in ("ok", "empty"):
            return None
        log.warning("%s: saved parameters in %s are %s; running on defaults",
                    self._where, self.store, text)
        return lambda: self._store_problems.fire(text, skipped)

    # ---------------------------------------------------------------- state
    @property
    def state(self) -> NmtState:
        """Current NMT state (read from the runtime, so always up to date);
        INITIALISING until the node has booted."""
        code = self.line._runtime_local_state(self._where)
        return NmtState.INITIALISING if code is None else NmtState(code)

    def apply(self, command: Union[NmtCommand, int, str]) -> None:
        """Apply an NMT command to this node as if the master had sent it."""
        command = NmtCommand.parse(command)
        if not self._booted:
            raise ConfigurationError(f"{self._where} is not booted yet: call boot() first")
        self.line._apply_local(command, self._where)

    def wait_for_state(self, state: StateLike, timeout: Optional[float] = 10.0) -> None:
        """Block until the node is (or has passed through) `state`."""
        target = NmtState.parse(state)
        start = self._history.seq
        self.line._waiter.wait(
            lambda: self._history.seen_since(start, target) or self.state == target,
            timeout, f"{self._where}: wait_for_state({target.label})",
            lambda: f"still {self.state.label}, not {target.label}")

    # ---------------------------------------------------------------- 0x1017
    @property
    def heartbeat_ms(self) -> int:
        """Heartbeat producer time (0x1017) in ms; 0 = no heartbeat.

        Setting it takes effect at once: the next heartbeat goes out one new
        period from now. A reset (node or communication) restores the value
        given to create_local_node() (with an OD: its default or saved value)."""
        if self._booted and self._has_1017:
            return self[0x1017].raw
        return self._heartbeat_ms

    @heartbeat_ms.setter
    def heartbeat_ms(self, value: int) -> None:
        value = check_ms(value, "heartbeat_ms", self._where)
        if self._booted and self._has_1017:
            self[0x1017].raw = value   # the OD's after-write re-arms at once
            return
        with self.line._cond:
            if self._booted:
                self.line._set_heartbeat(value, self._where)
            else:
                self._heartbeat_default_ms = value  # becomes the node's 0x1017 default
            self._heartbeat_ms = value

    # ---------------------------------------------------------------- veto
    @property
    def allow_operational(self) -> bool:
        """When False, "start" (to OPERATIONAL) is refused and on_veto fires."""
        return self._allow_operational

    @allow_operational.setter
    def allow_operational(self, allowed: bool) -> None:
        self.line._set_allow_operational(bool(allowed), self._where)
        self._allow_operational = bool(allowed)

    # ---------------------------------------------------------------- callbacks
    def on_state_change(self, callback: Callable[[NmtState, NmtState], None]):
        """callback(old_state, new_state) after every transition."""
        return self._state_changed.add(callback)

    def on_veto(self, callback: Callable[[], None]):
        """callback() when a start was refused (allow_operational is False)."""
        return self._vetoed.add(callback)

    def on_reset(self, callback: Callable[[NmtCommand], None]):
        """callback(kind) when a reset runs (RESET_NODE or RESET_COMMUNICATION),
        before the node's new boot-up message."""
        return self._reset.add(callback)

    # ---------------------------------------------------------------- PDO configuration
    @property
    def tpdo(self) -> "PdoMaps":
        """The TPDOs of the served OD (0x1800../0x1A00..), by number:
        `node.tpdo[1].trans_type = 255`, `.add_variable(...)`, `.save()`
        (see canopenfd.services.pdo)."""
        from .services.pdo import pdo_maps
        return pdo_maps(self, "tpdo")

    @property
    def rpdo(self) -> "PdoMaps":
        """The RPDOs of the served OD (0x1400../0x1600..), as `tpdo`."""
        from .services.pdo import pdo_maps
        return pdo_maps(self, "rpdo")

    def trigger_pdo(self, key: Any) -> int:
        """Tell the PDO service that entry `key` (index, (index, sub), name...)
        changed: every event-driven TPDO (types 0, 254, 255) mapping it is
        sent (respecting its inhibit time; in OPERATIONAL only). Returns how
        many TPDOs map it."""
        entry = self._entry(key)
        where = f"trigger_pdo({key!r}) on {self._where}"
        if not isinstance(entry, ODVariable):
            raise ConfigurationError(f"{where}: {entry!r} is not a single entry; give the "
                                     "sub-index")
        if not self._booted:
            raise ConfigurationError(f"{where}: the node is not booted yet")
        return self.line._rt.pdo_trigger_object(self.line.index, entry.index, entry.subindex,
                                                where)

    # ---------------------------------------------------------------- EMCY
    @property
    def emcy(self) -> "EmcyProducer":
        """The node's EMCY producer: `raise_error(code, ...)`, `clear(code)`,
        `error_register`, `active`, `history` (see canopenfd.services.emcy)."""
        producer = self.__dict__.get("_emcy")
        if producer is None:
            from .services.emcy import EmcyProducer
            producer = self.__dict__["_emcy"] = EmcyProducer(self)
        return producer

    # ---------------------------------------------------------------- events
    def _event_pdo(self, number: int, data: bytes) -> Optional[Callable[[], None]]:
        maps = self.__dict__.get("_pdo_maps", {}).get("rpdo")
        pdo_map = maps.maps.get(number) if maps is not None else None
        if pdo_map is None:
            return None
        return pdo_map._event_received(data)

    def _event_state(self, old: int, new: int) -> Callable[[], None]:
        old_s, new_s = _state(old), _state(new)
        self._history.push(new_s)
        return lambda: self._state_changed.fire(old_s, new_s)

    def _event_vetoed(self) -> Callable[[], None]:
        return self._vetoed.fire

    def _event_reset(self, kind: int) -> Callable[[], None]:
        # The runtime restored 0x1017 to its default (CiA 301 reset of the
        # communication parameters); mirror it (with an OD it is read there).
        self._heartbeat_ms = self._heartbeat_default_ms
        try:
            command = NmtCommand(kind)
        except ValueError:
            command = kind  # type: ignore[assignment]
        return lambda: self._reset.fire(command)


class LocalObject:
    """An ARRAY or RECORD of a local node's OD: index it by sub-index or name."""

    def __init__(self, node: LocalNode, obj: Any) -> None:
        self.node = node
        self.object = obj

    def __repr__(self) -> str:
        return f"<LocalObject 0x{self.object.index:04X} {self.object.name!r} of {self.node!r}>"

    def __getitem__(self, sub: Union[int, str]) -> "LocalValue":
        return LocalValue(self.node, self.object[sub])

    @property
    def raw(self) -> Any:
        raise ConfigurationError(
            f"{self.node._where}: 0x{self.object.index:04X} {self.object.name!r} is an "
            f"{type(self.object).__name__[2:].upper()}; give a sub-index, e.g. "
            f"node[0x{self.object.index:04X}][1].raw")


class LocalValue:
    """One entry of a local node's object dictionary: `.raw` is the typed value
    (checked against type, length and limits), `.data` the wire bytes.

    Reads and writes are atomic with respect to the stack's thread. A refused
    write raises AbortError with the CiA abort code, or OdValueError when the
    value cannot even be encoded; either way nothing changes."""

    def __init__(self, node: LocalNode, variable: ODVariable) -> None:
        self.node = node
        self.variable = variable

    def __repr__(self) -> str:
        return f"<LocalValue {self.variable.where} {self.variable.qualname!r} of {self.node!r}>"

    def _what(self, verb: str) -> str:
        return f"{verb} {self.variable.where} {self.variable.qualname!r}"

    @property
    def data(self) -> bytes:
        var = self.variable
        code, data = self.node.line._od_read(var.index, var.subindex, self._what("read"))
        if code:
            raise AbortError(code, self.node.node_id, var.index, var.subindex, self._what("read"))
        return data

    @data.setter
    def data(self, data: bytes) -> None:
        var = self.variable
        code = self.node.line._od_write(var.index, var.subindex, bytes(data), self._what("write"))
        if code:
            raise AbortError(code, self.node.node_id, var.index, var.subindex, self._what("write"))

    @property
    def raw(self) -> Any:
        return self.variable.decode_raw(self.data)

    @raw.setter
    def raw(self, value: Any) -> None:
        self.data = self.variable.encode_raw(value)


class RemoteNode:
    """A node on the bus that this line watches (python-canopen's RemoteNode
    for NMT and heartbeat).

    Its state comes from its boot-up and heartbeat messages. With a heartbeat
    consumer time (`heartbeat_timeout_ms` > 0) the line reports when they stop
    (`on_heartbeat_lost`) and come back (`on_heartbeat_started`).
    """

    def __init__(self, line: "Line", node_id: int, heartbeat_timeout_ms: int,
                 od: Optional[ObjectDictionary] = None) -> None:
        self.line = line
        self.node_id = node_id
        #: The node's object dictionary (names and types of its entries), or None.
        self.object_dictionary = od
        self.nmt = RemoteNmt(self)
        self._heartbeat_timeout_ms = heartbeat_timeout_ms
        self._history = _StateHistory()
        # Event times (CLOCK_MONOTONIC µs, as the runtime stamps them): waits
        # accept only events that happened after the wait began.
        self._last_bootup_us = -1
        self._last_heartbeat_us = -1   # first heartbeat, state change, resumption
        self._alive: Optional[bool] = None
        self._tracked = NmtState.UNKNOWN
        self._bootup = CallbackList(f"node {node_id} boot-up")
        self._state_changed = CallbackList(f"node {node_id} state change")
        self._lost = CallbackList(f"node {node_id} heartbeat lost")
        self._started = CallbackList(f"node {node_id} heartbeat started")
        self._heartbeat = CallbackList(f"node {node_id} heartbeat")
        self._guard_events = CallbackList(f"node {node_id} guarding")
        self._guarded = False

    def __repr__(self) -> str:
        return f"<RemoteNode {self.node_id} on {self.line.channel!r}>"

    # ---------------------------------------------------------------- USDO / SDO
    @property
    def usdo(self) -> "RemoteAccess":
        """USDO access (fd lines): upload/download by index, (index, sub),
        "INDEX:SUB" or OD name, blocking, awaitable or started in the
        background (see canopenfd.transfer.remote)."""
        from .transfer import RemoteAccess
        return RemoteAccess(self, self.line.usdo)

    @property
    def sdo(self) -> "RemoteAccess":
        """SDO access (classic lines), the same calls as `usdo`."""
        from .transfer import RemoteAccess
        return RemoteAccess(self, self.line.sdo)

    @property
    def _access(self) -> "RemoteAccess":
        """USDO on fd lines, SDO on classic lines."""
        return self.usdo if self.line.mode == "fd" else self.sdo

    def read(self, key: Any, **options: Any) -> Any:
        """Read an entry (USDO on fd lines, SDO on classic lines): the typed
        value when the node's OD knows the entry, else the bytes."""
        variable = self._variable(key)
        data = self._access.upload(key, **options)
        return variable.decode_raw(data) if variable is not None else data

    def write(self, key: Any, value: Any, **options: Any) -> None:
        """Write an entry (typed by the node's OD when it knows the entry,
        else `value` must be bytes)."""
        self._access.download(key, self._encoded(key, value), **options)

    async def aread(self, key: Any, **options: Any) -> Any:
        variable = self._variable(key)
        data = await self._access.aupload(key, **options)
        return variable.decode_raw(data) if variable is not None else data

    async def awrite(self, key: Any, value: Any, **options: Any) -> None:
        await self._access.adownload(key, self._encoded(key, value), **options)

    def _variable(self, key: Any) -> Optional[ODVariable]:
        from .transfer import resolve
        return resolve(key, self.object_dictionary, f"node {self.node_id}")[2]

    def _encoded(self, key: Any, value: Any) -> Any:
        variable = self._variable(key)
        if variable is not None:
            return variable.encode_raw(value)
        if not isinstance(value, (bytes, bytearray, memoryview)):
            raise ConfigurationError(
                f"node {self.node_id}: write({key!r}): without an OD entry the value must be "
                f"bytes, got {type(value).__name__} (add the node with od=...)")
        return value

    @property
    def od(self) -> "RemoteObjects":
        """Typed values by the node's OD: `remote.od["Producer heartbeat
        time"].raw = 100`, `remote.od[0x1018][1].raw`."""
        from .transfer import RemoteObjects
        return RemoteObjects(self)

    @property
    def id(self) -> int:  # python-canopen spelling
        return self.node_id

    @property
    def _where(self) -> str:
        return f"node {self.node_id} on line {self.line.channel!r}"

    # ---------------------------------------------------------------- state
    @property
    def state(self) -> NmtState:
        """Last state the node reported; PRE-OPERATIONAL right after its
        boot-up (it enters it by itself), UNKNOWN when never heard of."""
        return _remote_state(self.line._runtime_remote_state(self.node_id, self._where))

    @property
    def heartbeat_alive(self) -> Optional[bool]:
        """True while heartbeats arrive, False after a loss or a boot-up,
        None before the first heartbeat."""
        return self._alive

    @property
    def heartbeat_timeout_ms(self) -> int:
        """Heartbeat consumer time (0x1016 entry) in ms; 0 = states only, no
        loss detection. A change on a node heard in time keeps monitoring it,
        the new time counting from now; otherwise monitoring starts with the
        next heartbeat."""
        return self._heartbeat_timeout_ms

    @heartbeat_timeout_ms.setter
    def heartbeat_timeout_ms(self, value: int) -> None:
        value = check_ms(value, "heartbeat_timeout_ms", self._where)
        self.line._watch(self.node_id, value, self._where)
        self._heartbeat_timeout_ms = value

    # ---------------------------------------------------------------- waits
    def wait_for_bootup(self, timeout: Optional[float] = 10.0) -> None:
        """Block until the node's next boot-up message (one sent after this
        call: start waiting before the node boots, or use on_bootup)."""
        start = self.line._now_us()
        self.line._waiter.wait(lambda: self._last_bootup_us >= start, timeout,
                               f"{self._where}: wait_for_bootup", lambda: "no boot-up")

    def wait_for_heartbeat(self, timeout: Optional[float] = 10.0) -> NmtState:
        """Block until the node is heard heartbeating; returns its state.

        Returns at once while heartbeats arrive in time (the consumer is
        active); otherwise waits for the next one. Per-frame events do not
        exist by design (no Python per frame), so an unchanged heartbeat is
        only seen through the consumer's monitoring."""
        start = self.line._now_us()
        self.line._waiter.wait(
            lambda: self._last_heartbeat_us >= start or self._alive is True, timeout,
            f"{self._where}: wait_for_heartbeat", lambda: "no heartbeat")
        return self.state

    def wait_for_state(self, state: StateLike, timeout: Optional[float] = 10.0) -> None:
        """Block until the node reports `state` (or has reported it since the call)."""
        target = NmtState.parse(state)
        start = self._history.seq
        self.line._waiter.wait(
            lambda: self._history.seen_since(start, target) or self.state == target,
            timeout, f"{self._where}: wait_for_state({target.label})",
            lambda: f"last state {self.state.label}, not {target.label}")

    # ---------------------------------------------------------------- NMT shortcuts
    def start(self) -> None:
        self.nmt.start()

    def stop(self) -> None:
        self.nmt.stop()

    def pre_operational(self) -> None:
        self.nmt.pre_operational()

    def reset_node(self) -> None:
        self.nmt.reset_node()

    def reset_communication(self) -> None:
        self.nmt.reset_communication()

    # ---------------------------------------------------------------- callbacks
    def on_bootup(self, callback: Callable[[], None]):
        """callback() when the node sends its boot-up message."""
        return self._bootup.add(callback)

    def on_state_change(self, callback: Callable[[NmtState], None]):
        """callback(new_state) when the node reports another state."""
        return self._state_changed.add(callback)

    def on_heartbeat_lost(self, callback: Callable[[], None]):
        """callback() when no heartbeat came within heartbeat_timeout_ms."""
        return self._lost.add(callback)

    def on_heartbeat_started(self, callback: Callable[[], None]):
        """callback() at the first heartbeat, and when heartbeats resume."""
        return self._started.add(callback)

    def add_heartbeat_callback(self, callback: Callable[[NmtState], None]) -> None:
        """python-canopen's callback(state), called when a heartbeat brings news:
        boot-up, the first heartbeat, a state change, resumption after loss
        (not for every unchanged heartbeat: no Python code per frame)."""
        self._heartbeat.add(callback)

    # ---------------------------------------------------------------- EMCY
    @property
    def emcy(self) -> "EmcyConsumer":
        """The node's EMCYs (python-canopen's `node.emcy`): `add_callback(cb)`,
        `log`, `active`, `wait(code, timeout)`. The line consumes them from
        the first use on (see canopenfd.services.emcy)."""
        with self.line._cond:
            consumer = self.__dict__.get("_emcy")
            if consumer is None:
                from .services.emcy import EmcyConsumer
                consumer = self.__dict__["_emcy"] = EmcyConsumer(self)
            return consumer

    # ---------------------------------------------------------------- guarding
    def guard(self, guard_time_ms: int, life_time_factor: int) -> None:
        """Node guarding (classic lines; CAN FD has no remote frames): a
        remote frame on 0x700 + node-id every guard_time_ms, answered with the
        node's state and a toggle bit; life_time_factor answers missed in a
        row is "lost" (add_guard_callback). Guarding again changes the times."""
        where = f"guard({guard_time_ms!r}, {life_time_factor!r}) of {self._where}"
        if self.line.mode != "classic":
            raise ConfigurationError(f"{where}: node guarding needs a classic line (CAN FD "
                                     "has no remote frames); use the heartbeat "
                                     "(heartbeat_timeout_ms)")
        check_ms(guard_time_ms, "guard_time_ms", where)
        if guard_time_ms == 0:
            raise ConfigurationError(f"{where}: guard_time_ms must be 1..65535 (unguard() "
                                     "stops guarding)")
        if isinstance(life_time_factor, bool) or not isinstance(life_time_factor, int) or \
                not 1 <= life_time_factor <= 255:
            raise ConfigurationError(f"{where}: life_time_factor must be an int 1..255, got "
                                     f"{life_time_factor!r}")
        self.line._rt.guard(self.line.index, self.node_id, guard_time_ms, life_time_factor,
                            where)
        self._guarded = True

    def unguard(self) -> None:
        """Stop guarding the node."""
        where = f"unguard() of {self._where}"
        if self.line.mode != "classic":
            raise ConfigurationError(f"{where}: node guarding needs a classic line")
        self.line._rt.guard(self.line.index, self.node_id, 0, 0, where)
        self._guarded = False

    def add_guard_callback(self, callback: Callable[[str, NmtState], None]):
        """callback(event, state): event a GuardEvent (a str: 'started',
        'state-changed', 'lost', 'resumed', 'toggle-error', 'unexpected-state'),
        state the NmtState the node answered (its last one for 'lost').
        'lost' and 'resumed' also fire on_heartbeat_lost / on_heartbeat_started."""
        return self._guard_events.add(callback)

    def _event_guard(self, code: int, state_code: int) -> Optional[Callable[[], None]]:
        from .services.guard import GuardEvent
        event = GuardEvent.from_code(code)
        if event is None:
            return None
        state = _remote_state(state_code)
        calls = [lambda: self._guard_events.fire(event, state)]
        if event is GuardEvent.LOST:
            self._alive = False
            calls.append(self._lost.fire)
        elif event in (GuardEvent.STARTED, GuardEvent.RESUMED):
            self._alive = True
            calls.append(self._started.fire)
        if event in (GuardEvent.STARTED, GuardEvent.STATE_CHANGED, GuardEvent.RESUMED):
            self._history.push(state)
            if state != self._tracked:
                self._tracked = state
                calls.append(lambda: self._state_changed.fire(state))
        return _chain(calls)

    # ---------------------------------------------------------------- PDO configuration
    @property
    def tpdo(self) -> "PdoMaps":
        """The TPDOs of the node's OD (0x1800../0x1A00..), by number:
        `node.tpdo[1].trans_type = 255`, `.add_variable(...)`, `.save()`
        through USDO (fd lines) or SDO (classic lines); see canopenfd.services.pdo."""
        from .services.pdo import pdo_maps
        return pdo_maps(self, "tpdo")

    @property
    def rpdo(self) -> "PdoMaps":
        """The RPDOs of the node's OD (0x1400../0x1600..), as `tpdo`."""
        from .services.pdo import pdo_maps
        return pdo_maps(self, "rpdo")

    # ---------------------------------------------------------------- events
    def _event(self, hb_event: int, code: int, time_us: int = 0) -> Callable[[], None]:
        """Update from a CO_EV_HEARTBEAT event (under the line's condition);
        returns the callbacks to run once the lock is released."""
        state = _remote_state(code)
        calls = []
        if hb_event == HeartbeatEvent.BOOTUP:
            self._last_bootup_us = max(self._last_bootup_us, time_us)
            self._alive = False
            self._history.push(NmtState.INITIALISING)
            self._history.push(NmtState.PRE_OPERATIONAL)
            calls.append(self._bootup.fire)
            calls.append(lambda: self._heartbeat.fire(NmtState.INITIALISING))
        elif hb_event == HeartbeatEvent.LOST:
            self._alive = False
            calls.append(self._lost.fire)
            return _chain(calls)
        else:
            self._last_heartbeat_us = max(self._last_heartbeat_us, time_us)
            self._history.push(state)
            if hb_event == HeartbeatEvent.STARTED:
                self._alive = True
                calls.append(self._started.fire)
            calls.append(lambda: self._heartbeat.fire(state))
        if state != self._tracked:
            self._tracked = state
            calls.append(lambda: self._state_changed.fire(state))
        return _chain(calls)


def _chain(calls) -> Callable[[], None]:
    def run() -> None:
        for call in calls:
            call()
    return run


def _state(code: int) -> NmtState:
    try:
        return NmtState(code)
    except ValueError:
        return NmtState.UNKNOWN


def _remote_state(code: int) -> NmtState:
    """A boot-up (0) means the node is now PRE-OPERATIONAL (CiA 301; python-canopen
    reports it that way too)."""
    state = _state(code)
    return NmtState.PRE_OPERATIONAL if state is NmtState.INITIALISING else state
