"""`Line`: one CAN line of a network (a SocketCAN interface, an in-process
bus, or a python-can bus), classic or fd, with its NMT master, its local node
and the remote nodes it watches."""

from __future__ import annotations

import logging
import threading
from typing import TYPE_CHECKING, Any, Callable, Dict, Iterable, List, Optional, Union

from ._callbacks import CallbackList, Waiter
from ._binding.constants import CommandKind, CommEvent, EventKind
from ._binding.runtime import now_us, status_text
from .errors import ConfigurationError
from .frame import Frame, fd_len_round
from ._checks import check_ms, check_node_id
from .node import LocalNode, RemoteNode, _remote_state
from .services.nmt import NmtCommand, NmtMaster, NmtState
from .services.store import check_store

if TYPE_CHECKING:  # pragma: no cover
    from .network import Network
    from .services.emcy import Emcy
    from .transfer.sdo import SdoClient
    from .transfer.usdo import UsdoClient

log = logging.getLogger("canopenfd")


class Line:
    """One CAN line. Create it with `Network.open_line()`.

    Attributes: `channel` (as given), `mode` ('fd' or 'classic'), `brs`,
    `monitor`, `nmt` (the line's NMT master), `nodes` ({node_id: RemoteNode}),
    `local_node` (or None).
    """

    def __init__(self, network: "Network", index: int, channel: str, mode: str,
                 brs: bool, monitor: bool) -> None:
        self.network = network
        self.index = index
        self.channel = channel
        self.mode = mode
        self.brs = brs
        self.monitor = monitor
        self.nmt = NmtMaster(self)
        self.nodes: Dict[int, RemoteNode] = {}
        self._client: Optional[Any] = None   # UsdoClient / SdoClient
        self.local_node: Optional[LocalNode] = None
        self._cond = threading.Condition()
        self._waiter = Waiter(self._cond, lambda: network.closed, network._on_dispatcher)
        self._comm = CallbackList(f"line {channel!r} comm event")
        self._frames = CallbackList(f"line {channel!r} frame")
        self._comm_events: List[CommEvent] = []
        self._emcys = CallbackList(f"line {channel!r} EMCY")
        self._emcy_nodes: set = set()     # consumed for on_emcy(nodes=...)
        # Remote nodes' PDOs Python hears: CAN-ID (bit 29 = 29-bit) -> PdoMaps.
        self._pdo_watches: Dict[int, List[Any]] = {}
        from .services.sync import SyncService
        from .services.time import TimeService
        #: SYNC producer and callbacks (see canopenfd.services.sync).
        self.sync = SyncService(self)
        #: TIME transmit and callbacks.
        self.time = TimeService(self)

    def __repr__(self) -> str:
        kind = "monitor " if self.monitor else ""
        return f"<Line {self.channel!r} {self.mode} {kind}#{self.index}>"

    @property
    def _where(self) -> str:
        return f"line {self.channel!r}"

    @property
    def _rt(self):
        return self.network._runtime

    # ---------------------------------------------------------------- nodes
    def create_local_node(self, node_id: int, heartbeat_ms: int = 0, *,
                          od: Optional[Any] = None, store: Optional[Any] = None,
                          boot: bool = True) -> LocalNode:
        """Create our node on this line (one per line) and boot it: boot-up
        message, PRE-OPERATIONAL, then a heartbeat every heartbeat_ms (0 = none).

        od: an `ObjectDictionary` (or a path of an EDS/DCF/XDD/XDC file) the node
        serves; its 0x1017/0x1016 drive the heartbeat (a non-zero heartbeat_ms
        replaces the 0x1017 default). store: a file where `save_parameters()`
        and 0x1010 keep parameters across restarts, or an object with load()
        and save(image) for other media (see canopenfd.services.store; needs od).

        boot=False leaves it off until node.boot(), so callbacks registered in
        between see its first transition."""
        node_id = check_node_id(node_id, f"create_local_node on {self._where}")
        heartbeat_ms = check_ms(heartbeat_ms, "heartbeat_ms",
                                f"create_local_node({node_id}) on {self._where}")
        with self._cond:
            if self.local_node is not None:
                raise ConfigurationError(
                    f"{self._where} already has local node {self.local_node.node_id}: "
                    f"one local node per line (cannot add node {node_id})")
            if node_id in self.nodes:
                raise ConfigurationError(
                    f"{self._where}: node-id {node_id} is already a remote node watched by "
                    "this line; a local node needs an id of its own")
            self._rt._live(f"create_local_node({node_id}) on {self._where}")
            od = _served_od(od, self.mode, node_id, store, f"create_local_node({node_id}) on "
                            f"{self._where}")
            store = check_store(store, f"create_local_node({node_id}) on {self._where}")
            node = LocalNode(self, node_id, heartbeat_ms, od, store)
            self.local_node = node
            if boot:
                try:
                    node.boot()
                except BaseException:
                    self.local_node = None
                    raise
        return node

    def add_node(self, node_id: int, heartbeat_timeout_ms: int = 0, *,
                 od: Optional[Any] = None) -> RemoteNode:
        """Watch a remote node (python-canopen's network.add_node): its boot-up,
        states and, with heartbeat_timeout_ms > 0, the loss of its heartbeat.
        od: its ObjectDictionary or EDS/DCF/XDD file, so `node.od[name].raw`
        and `node.usdo` know names and types. Adding a node already watched
        updates its timeout (and OD, when given) and returns it."""
        node_id = check_node_id(node_id, f"add_node on {self._where}")
        heartbeat_timeout_ms = check_ms(heartbeat_timeout_ms, "heartbeat_timeout_ms",
                                        f"add_node({node_id}) on {self._where}")
        with self._cond:
            if self.local_node is not None and self.local_node.node_id == node_id:
                raise ConfigurationError(
                    f"{self._where}: node-id {node_id} is this line's local node; "
                    "a remote node needs another id")
            existing = self.nodes.get(node_id)
        if od is not None:
            od = _remote_od(od, node_id, f"add_node({node_id}) on {self._where}")
        if existing is not None:
            existing.heartbeat_timeout_ms = heartbeat_timeout_ms
            if od is not None:
                existing.object_dictionary = od
            return existing
        self._check_consumer_owner(node_id, heartbeat_timeout_ms, f"add_node({node_id})")
        node = RemoteNode(self, node_id, heartbeat_timeout_ms, od)
        with self._cond:
            self._rt.command(CommandKind.HB_WATCH, self.index, node_id, heartbeat_timeout_ms,
                             what=f"add_node({node_id}) on {self._where}")
            node._tracked = _remote_state(self._rt.remote_state(self.index, node_id,
                                                                self._where))
            self.nodes[node_id] = node
        return node

    def remove_node(self, node_id: int) -> None:
        """Stop watching a remote node (its callbacks no longer fire)."""
        node_id = check_node_id(node_id, f"remove_node on {self._where}")
        with self._cond:
            if node_id not in self.nodes:
                raise ConfigurationError(f"{self._where}: node {node_id} is not watched")
            what = f"remove_node({node_id}) on {self._where}"
            node = self.nodes[node_id]
            self._rt.command(CommandKind.HB_UNWATCH, self.index, node_id, what=what)
            if node._guarded:
                self._rt.guard(self.index, node_id, 0, 0, what)
            if "_emcy" in node.__dict__ and node_id not in self._emcy_nodes:
                self._rt.emcy_watch(self.index, node_id, False, what)
            for maps in node.__dict__.get("_pdo_maps", {}).values():
                for pdo_map in maps.maps.values():
                    pdo_map._stop_watch(what)
            del self.nodes[node_id]

    def __getitem__(self, node_id: int) -> RemoteNode:
        return self.nodes[node_id]

    # ---------------------------------------------------------------- views
    @property
    def states(self) -> Dict[int, NmtState]:
        """{node_id: NmtState} of every node heard on this line, plus the local
        node. A node that sent its boot-up is PRE-OPERATIONAL."""
        result = {node_id: _remote_state(code) for node_id, code
                  in self._rt.remote_states(self.index, f"states of {self._where}").items()}
        if self.local_node is not None:
            result[self.local_node.node_id] = self.local_node.state
        return dict(sorted(result.items()))

    @property
    def stats(self) -> Dict[str, int]:
        """The line's counters (co_line_stats_t): frames, overflows and every
        malformed or unhandled frame, by kind."""
        return self._rt.line_stats(self.index, f"stats of {self._where}")

    @property
    def driver_stats(self) -> Dict[str, int]:
        """Counters below the core: frames the kernel's socket buffer lost
        (`kernel_drops`), error frames, sends put off or refused, interface
        downs, frames and read/write calls on the socket (frames per call
        tell how well I/O batches) and the runtime thread's wake-ups."""
        return self._rt.driver_stats(self.index, f"driver stats of {self._where}")

    @property
    def service_stats(self) -> Dict[str, Any]:
        """Counters of the process-data and error services: {'pdo': {...},
        'emcy': {...}, 'emcy_consumer', 'sync', 'time', 'guard_slave',
        'guard_master': {...}, 'pdo_watched': n}; every frame a service
        ignored is counted here by reason (zeros for services not running)."""
        return self._rt.service_stats(self.index, f"service stats of {self._where}")

    @property
    def comm_events(self) -> List[CommEvent]:
        """Communication events seen so far, oldest first (at most 1000 kept)."""
        with self._cond:
            return list(self._comm_events)

    # ---------------------------------------------------------------- callbacks
    def on_comm_event(self, callback: Callable[[CommEvent], None]):
        """callback(CommEvent): bus-off, error passive, overflow, interface down/up..."""
        return self._comm.add(callback)

    def on_emcy(self, callback: Callable[["Emcy"], None],
                nodes: Optional[Iterable[int]] = None):
        """callback(Emcy) for every EMCY the line consumes: those of the
        nodes whose `node.emcy` was used, of the local node's 0x1028 entries,
        and of `nodes` (node-ids this call starts consuming)."""
        for node_id in (nodes or ()):
            node_id = check_node_id(node_id, f"on_emcy on {self._where}")
            self._rt.emcy_watch(self.index, node_id, True,
                                f"EMCY of node {node_id} on {self._where}")
            self._emcy_nodes.add(node_id)
        return self._emcys.add(callback)

    def on_frame(self, callback: Callable[[Frame], None]):
        """callback(Frame) for every frame on the line, ours included (tx=True).
        Monitor lines only: it costs Python code per frame."""
        if not self.monitor:
            raise ConfigurationError(
                f"on_frame needs a monitor line: {self._where} was opened with "
                "monitor=False (open another line with monitor=True)")
        return self._frames.add(callback)

    def wait_for_comm_event(self, event: Union[CommEvent, int],
                            timeout: Optional[float] = 10.0) -> None:
        """Block until `event` occurs after this call."""
        event = CommEvent(event)
        start = len(self._comm_events)
        self._waiter.wait(lambda: event in self._comm_events[start:], timeout,
                          f"{self._where}: wait_for_comm_event({event.name})",
                          lambda: f"no {event.name}")

    # ---------------------------------------------------------------- raw frames
    def send_frame(self, can_id: int, data: bytes = b"", fd: Optional[bool] = None,
                   brs: Optional[bool] = None, extended: bool = False) -> None:
        """Send one frame as is (tools, tests; no protocol check).

        fd/brs default to the line's mode; an FD payload whose length is not a
        valid FD length is padded with zeros to the next one (12, 16, 20, ...)."""
        where = f"send_frame on {self._where}"
        data = bytes(data)
        fd = (self.mode == "fd") if fd is None else bool(fd)
        if fd and self.mode != "fd":
            raise ConfigurationError(f"{where}: an FD frame cannot go on a classic line")
        brs = (self.brs if fd else False) if brs is None else bool(brs)
        if brs and not fd:
            raise ConfigurationError(f"{where}: bit-rate switch needs an FD frame")
        limit = 0x1FFFFFFF if extended else 0x7FF
        if isinstance(can_id, bool) or not isinstance(can_id, int) or not 0 <= can_id <= limit:
            raise ConfigurationError(
                f"{where}: CAN-ID {can_id!r} outside 0..0x{limit:X} "
                f"({'29' if extended else '11'}-bit)")
        if fd:
            if len(data) > 64:
                raise ConfigurationError(f"{where}: {len(data)} bytes, an FD frame holds 64")
            data = data.ljust(fd_len_round(len(data)), b"\0")
        elif len(data) > 8:
            raise ConfigurationError(f"{where}: {len(data)} bytes, a classic frame holds 8")
        frame = Frame(can_id, data, fd=fd, brs=brs, ext=bool(extended))
        self._rt.command(CommandKind.SEND_FRAME, self.index, frame=frame, what=where)

    # ---------------------------------------------------------------- USDO / SDO
    @property
    def usdo(self) -> "UsdoClient":
        """The USDO client of this fd line: upload/download any node's
        entries (see canopenfd.transfer.usdo). Our client node-id is the local node's,
        else 127 (set `line.usdo.client_id` before the first transfer)."""
        if self.mode != "fd":
            raise ConfigurationError(f"{self._where} is a classic line: USDO needs CAN FD "
                                     "(classic lines use line.sdo)")
        return self._transfer_client()  # type: ignore[return-value]

    @property
    def sdo(self) -> "SdoClient":
        """The SDO client of this classic line (see canopenfd.transfer.sdo)."""
        if self.mode != "classic":
            raise ConfigurationError(f"{self._where} is an fd line: CANopen FD replaces SDO "
                                     "with USDO (use line.usdo)")
        return self._transfer_client()  # type: ignore[return-value]

    def _transfer_client(self) -> Any:
        """The line's client: USDO on fd lines, SDO on classic lines."""
        with self._cond:
            if self._client is None:
                if self.mode == "fd":
                    from .transfer.usdo import UsdoClient
                    self._client = UsdoClient(self)
                else:
                    from .transfer.sdo import SdoClient
                    self._client = SdoClient(self)
            return self._client

    # ---------------------------------------------------------------- for nodes
    def _define_od(self, defs: Any, count: int, store: Optional[str], where: str) -> None:
        self._rt.od_define(self.index, defs, count, store, f"object dictionary of {where}")

    def _od_read(self, index: int, sub: int, what: str) -> "tuple[int, bytes]":
        return self._rt.od_read(self.index, index, sub, f"{what} on {self._where}")

    def _od_write(self, index: int, sub: int, data: bytes, what: str) -> int:
        return self._rt.od_write(self.index, index, sub, data, f"{what} on {self._where}")

    def _od_store(self, group_mask: int, save: bool, what: str) -> int:
        return self._rt.od_store(self.index, group_mask, save, what)

    def _create_node(self, node_id: int, heartbeat_ms: int, where: str) -> None:
        self._rt.command(CommandKind.NODE_CREATE, self.index, node_id, heartbeat_ms,
                         what=f"boot of {where}")
    def _send_nmt(self, command: NmtCommand, node_id: int, include_self: bool) -> None:
        target = "all" if node_id == 0 else f"node {node_id}"
        self._rt.command(CommandKind.NMT_SEND, self.index, int(command), node_id,
                         int(include_self),
                         what=f"NMT {command.label} {target} on {self._where}")

    def _apply_local(self, command: NmtCommand, where: str) -> None:
        self._rt.command(CommandKind.NMT_LOCAL, self.index, int(command),
                         what=f"NMT {command.label} on {where}")

    def _set_heartbeat(self, ms: int, where: str) -> None:
        self._rt.command(CommandKind.HEARTBEAT_TIME, self.index, ms,
                         what=f"heartbeat_ms = {ms} on {where}")

    def _set_allow_operational(self, allowed: bool, where: str) -> None:
        self._rt.command(CommandKind.ALLOW_OPERATIONAL, self.index, int(allowed),
                         what=f"allow_operational = {allowed} on {where}")

    def _check_consumer_owner(self, node_id: int, ms: int, what: str) -> None:
        """A consumer time for a node that the local OD's 0x1016 already
        monitors belongs to that entry: refuse instead of changing it behind
        the OD's back (a state-only watch, ms = 0, is fine)."""
        local = self.local_node
        if ms == 0 or local is None or not local.booted:
            return
        owner = local._consumer_entry(node_id)
        if owner is not None:
            sub, time_ms = owner
            raise ConfigurationError(
                f"{what} on {self._where}: node {node_id} is monitored by the local node's "
                f"0x1016:{sub:02X} ({time_ms} ms); change that entry "
                f"(node[0x1016][{sub}].raw) or add the node with heartbeat_timeout_ms=0")

    def _watch(self, node_id: int, ms: int, where: str) -> None:
        self._check_consumer_owner(node_id, ms, f"heartbeat_timeout_ms = {ms}")
        self._rt.command(CommandKind.HB_WATCH, self.index, node_id, ms,
                         what=f"heartbeat_timeout_ms = {ms} on {where}")

    @staticmethod
    def _now_us() -> int:
        return now_us()

    def _runtime_local_state(self, where: str) -> Optional[int]:
        return self._rt.local_state(self.index, where)

    def _runtime_remote_state(self, node_id: int, where: str) -> int:
        return self._rt.remote_state(self.index, node_id, where)

    # ---------------------------------------------------------------- events
    def _handle(self, kind: int, node: int, a: int, b: int, frame: Optional[Frame],
                time_us: int = 0, data: bytes = b"") -> None:
        """One runtime event for this line (dispatcher thread)."""
        run: Optional[Callable[[], None]] = None
        with self._cond:
            if kind == EventKind.FRAME:
                if frame is not None and self._frames:
                    run = lambda: self._frames.fire(frame)  # noqa: E731
            elif kind == EventKind.HEARTBEAT:
                remote = self.nodes.get(node)
                if remote is not None:
                    run = remote._event(a, b, time_us)
            elif kind == EventKind.NMT_STATE:
                if self.local_node is not None:
                    run = self.local_node._event_state(a, b)
            elif kind == EventKind.COMM:
                try:
                    event = CommEvent(a)
                except ValueError:
                    log.warning("%s: unknown communication event %d", self._where, a)
                else:
                    self._comm_events.append(event)
                    del self._comm_events[:-1000]
                    run = lambda: self._comm.fire(event)  # noqa: E731
            elif kind == EventKind.NMT_VETOED:
                if self.local_node is not None:
                    run = self.local_node._event_vetoed()
            elif kind == EventKind.NMT_RESET:
                if self.local_node is not None:
                    run = self.local_node._event_reset(a)
            elif kind == EventKind.OD_CHANGED:
                if self.local_node is not None:
                    run = self.local_node._event_changed(a, b)
            elif kind == EventKind.OD_REQUEST:
                if self.local_node is not None:
                    run = self.local_node._event_request(a, b)
            elif kind == EventKind.TRANSFER_DONE:
                if self._client is not None:
                    run = self._client._event_done(a)
            elif kind == EventKind.TRANSFER_PROGRESS:
                if self._client is not None:
                    run = self._client._event_progress(a, b)
            elif kind == EventKind.STORE:
                if self.local_node is not None:
                    run = self.local_node._event_store(a, b)
            elif kind == EventKind.EMCY:
                run = self._event_emcy(node, bool(a), data)
            elif kind == EventKind.PDO:
                if self.local_node is not None:
                    run = self.local_node._event_pdo(a, data)
            elif kind == EventKind.PDO_FRAME:
                run = self._event_pdo_frame(a, frame)
            elif kind == EventKind.SYNC:
                run = self.sync._event(a)
            elif kind == EventKind.TIME:
                run = self.time._event(a, b)
            elif kind == EventKind.GUARD:
                remote = self.nodes.get(node)
                if remote is not None:
                    run = remote._event_guard(a, b)
            elif kind == EventKind.COMMAND_FAILED:
                log.warning("%s: command %d failed in the runtime: %s", self._where, a,
                            self._status_text(-b))
            self._cond.notify_all()
        if run is not None:
            run()

    def _pdo_watch(self, pdo_map: Any, can_id: int, what: str) -> None:
        """pdo_map hears the frames on can_id (bit 29: 29-bit); the runtime
        watches the id while at least one map does."""
        with self._cond:
            maps = self._pdo_watches.get(can_id)
            if maps is None:
                self._rt.pdo_watch(self.index, can_id, True, what)
                maps = self._pdo_watches[can_id] = []
            if pdo_map not in maps:
                maps.append(pdo_map)

    def _pdo_unwatch(self, pdo_map: Any, can_id: int, what: str) -> None:
        with self._cond:
            maps = self._pdo_watches.get(can_id)
            if maps is None or pdo_map not in maps:
                return
            maps.remove(pdo_map)
            if not maps:
                del self._pdo_watches[can_id]
                if not self.network.closed:
                    self._rt.pdo_watch(self.index, can_id, False, what)

    def _event_pdo_frame(self, can_id: int,
                         frame: Optional[Frame]) -> Optional[Callable[[], None]]:
        if frame is None:
            return None
        calls = [call for call in (m._event_frame(frame)
                                   for m in list(self._pdo_watches.get(can_id, ())))
                 if call is not None]
        if not calls:
            return None

        def run() -> None:
            for call in calls:
                call()
        return run

    def _event_emcy(self, node: int, fd: bool, data: bytes) -> Optional[Callable[[], None]]:
        from .services.emcy import Emcy
        emcy = Emcy.decode(node, data, fd)
        if emcy is None:
            log.warning("%s: malformed EMCY of node %d ignored: %s", self._where, node,
                        data.hex(" "))
            return None
        calls = [lambda: self._emcys.fire(emcy)]
        remote = self.nodes.get(node)
        consumer = remote.__dict__.get("_emcy") if remote is not None else None
        if consumer is not None:
            calls.insert(0, consumer._event(emcy))

        def run() -> None:
            for call in calls:
                call()
        return run

    def _wake(self) -> None:
        with self._cond:
            self._cond.notify_all()

    @staticmethod
    def _status_text(status: int) -> str:
        return status_text(status)


def _remote_od(od: Any, node_id: int, where: str) -> Any:
    """The ObjectDictionary of a remote node: given, or imported from a file."""
    from .od import ObjectDictionary, import_od
    if isinstance(od, (str, bytes)) or hasattr(od, "__fspath__"):
        od = import_od(od, node_id=node_id)
    if not isinstance(od, ObjectDictionary):
        raise ConfigurationError(f"{where}: od must be an ObjectDictionary or a file path, "
                                 f"got {type(od).__name__}")
    return od


def _served_od(od: Any, mode: str, node_id: int, store: Optional[str], where: str) -> Any:
    """The ObjectDictionary a local node serves: given, or imported from a file."""
    from .od import ObjectDictionary, import_od
    if od is None:
        if store is not None:
            raise ConfigurationError(f"{where}: a parameter store needs an object dictionary "
                                     "(od=...)")
        return None
    if isinstance(od, (str, bytes)) or hasattr(od, "__fspath__"):
        od = import_od(od, node_id=node_id)
    if not isinstance(od, ObjectDictionary):
        raise ConfigurationError(f"{where}: od must be an ObjectDictionary or a file path, "
                                 f"got {type(od).__name__}")
    return od
