"""`Line`: one CAN line of a network (a SocketCAN interface, an in-process
bus, or a python-can bus), classic or fd, with its NMT master, its local node
and the remote nodes it watches.

A line is composition: it builds the line's services (NMT master, SYNC, TIME,
EMCY consumption, the USDO or SDO client) and its nodes on its line context;
the context's event table routes each runtime event to the service that
subscribed its kind."""

from __future__ import annotations

import logging
from typing import (Callable, Dict, Iterable, Iterator, List, Optional, Protocol, Sequence, Tuple,
                    Union)

from ._binding.constants import CommandKind, CommEvent, EventKind
from ._binding.context import Deferred, FrameHandler, RuntimeLineContext
from ._binding.runtime import Event, status_text
from ._aio import LoopArg
from ._callbacks import CallbackList, Until
from ._checks import check_ms, check_node_id
from .errors import ConfigurationError
from .frame import Frame, fd_len_round
from .node import LocalNode, RemoteNode
from .od import ObjectDictionary, ODVariable, import_od
from .od.fileio import Source
from .services.config import ConfigManager
from .services.emcy import Emcy, LineEmcy
from .services.lss import UNCONFIGURED, LssMaster
from .services.manager import NetworkManager
from .services.nmt import HeartbeatEvent, NmtMaster, NmtState, NodeEvents, remote_state_of
from .services.store import StoreLike, check_store
from .services.store_groups import GroupTable, StoreGroup, declare_groups
from .services.redundancy import BusRedundancy
from .services.sleep import SleepService
from .services.sync import SyncService
from .services.time import TimeService
from .transfer.client import TransferClient, require_protocol
from .transfer.sdo import SdoClient
from .transfer.usdo import UsdoClient

log = logging.getLogger("canopenfd")

#: An object dictionary as create_local_node / add_node take it: the model or a file.
ODLike = Union[ObjectDictionary, Source]


class LineNetwork(Protocol):
    """What a line shows of its network (`line.network`, a Network; a Protocol
    so that this module does not import the one that builds lines)."""

    @property
    def closed(self) -> bool:
        ...

    def close(self) -> None:
        ...


class Line:
    """One CAN line. Create it with `Network.open_line()`.

    Attributes: `channel` (as given), `mode` ('fd' or 'classic'), `brs`,
    `monitor`, `nmt` (the line's NMT master), `nodes` ({node_id: RemoteNode}),
    `local_node` (or None).
    """

    def __init__(self, network: LineNetwork, context: RuntimeLineContext, brs: bool,
                 monitor: bool) -> None:
        self.network = network
        self.index = context.index
        self.channel = context.channel
        self.mode = context.mode
        self.brs = brs
        self.monitor = monitor
        self._context = context
        #: True for a line canopenfd.connect() made: disconnect() (or leaving a
        #: `with line:` block) closes its network, which holds only this line.
        self.own_network = False
        self.nmt = NmtMaster(context)
        self.nodes: Dict[int, RemoteNode] = {}
        self.local_node: Optional[LocalNode] = None
        #: SYNC producer and callbacks (see canopenfd.services.sync).
        self.sync = SyncService(context)
        self._lss: Optional[LssMaster] = None
        #: TIME transmit and callbacks.
        self.time = TimeService(context)
        #: Sleep and wake-up, master or device (see canopenfd.services.sleep).
        self.sleep = SleepService(context)
        #: Bus redundancy over two in-process buses (see canopenfd.services.redundancy).
        self.redundancy = BusRedundancy(context)
        self._emcy = LineEmcy(context)
        self._node_events = NodeEvents(context)
        # USDO on fd lines, SDO on classic lines (C sets it up at the first transfer)
        self._client: TransferClient = \
            UsdoClient(context) if self.mode == "fd" else SdoClient(context)
        #: The network manager: CiA 302-2 start-up run by the local node
        #: (canopenfd.services.manager) and the CiA 302-3 configuration
        #: manager, `manager.configure(node, dcf)` (canopenfd.services.config).
        self.manager = NetworkManager(
            context, ConfigManager(context, f"line {self.channel!r}"),
            lambda: self.local_node.od if self.local_node is not None else None)
        self._comm = CallbackList(f"line {self.channel!r} comm event")
        self._frames = CallbackList(f"line {self.channel!r} frame")
        self._comm_events: List[CommEvent] = []
        context.subscribe(EventKind.COMM, self._event_comm)
        context.subscribe(EventKind.FRAME, self._event_frame)
        context.subscribe(EventKind.COMMAND_FAILED, self._event_command_failed)

    def __repr__(self) -> str:
        kind = "monitor " if self.monitor else ""
        return f"<Line {self.channel!r} {self.mode} {kind}#{self.index}>"

    # ---------------------------------------------------------------- connect()'s line
    def disconnect(self) -> None:
        """Close the network canopenfd.connect() opened for this line
        (python-canopen's network.disconnect()); idempotent. A line of a
        Network you opened closes with that Network."""
        if not self.own_network:
            raise ConfigurationError(f"{self._where} belongs to a Network opened with "
                                     "Network(): close that network (disconnect() is for "
                                     "lines from canopenfd.connect())")
        self.network.close()

    def __enter__(self) -> "Line":
        if not self.own_network:
            raise ConfigurationError(f"`with line:` is for lines from canopenfd.connect(); "
                                     f"{self._where} closes with its Network")
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.disconnect()

    @property
    def _where(self) -> str:
        return self._context.where

    @property
    def network_id(self) -> Optional[int]:
        """The network-id (1..127) this line carries in the network's gateway
        (`network.routing`), None while it has not joined."""
        net = self._context.runtime.gateway_network(self.index, f"{self._where}: network-id")
        return net or None

    @network_id.setter
    def network_id(self, value: Optional[int]) -> None:
        what = f"{self._where}: network-id"
        if value is not None and (isinstance(value, bool) or not isinstance(value, int)
                                  or not 1 <= value <= 127):
            raise ConfigurationError(f"{what} must be 1..127 (None leaves), got {value!r}")
        self._context.runtime.gateway_join(self.index, value or 0, what)

    @property
    def _pdo_watches(self) -> Dict[int, List[FrameHandler]]:
        """{CAN-ID: handlers} of the remote PDOs heard now (tests look at it)."""
        return self._context.pdo_watches.watchers

    # ---------------------------------------------------------------- nodes
    def create_local_node(self, node_id: int, heartbeat_ms: int = 0, *,
                          od: Optional[ODLike] = None, store: Optional[StoreLike] = None,
                          store_groups: Optional[Sequence[StoreGroup]] = None,
                          store_interval_ms: int = 1000, boot: bool = True,
                          od_spare_objects: int = 32, od_spare_bytes: int = 1024) -> LocalNode:
        """Create our node on this line (one per line) and boot it: boot-up
        message, PRE-OPERATIONAL, then a heartbeat every heartbeat_ms (0 = none).

        od: an `ObjectDictionary` (or a path of an EDS/DCF/XDD/XDC file) the node
        serves; its 0x1017/0x1016 drive the heartbeat (a non-zero heartbeat_ms
        replaces the 0x1017 default). store: a file where `save_parameters()`
        and 0x1010 keep parameters across restarts, or an object with load()
        and save(image) for other media (see canopenfd.services.store; needs od).
        store_groups: the parameter groups of 0x1010/0x1011 (StoreGroup list,
        see canopenfd.services.store_groups; default: CiA 301's by index
        range); autonomously saved groups are written by the stack at most
        every store_interval_ms.

        od_spare_objects / od_spare_bytes: room reserved for entries added to
        the running node (`node.od.add_object(...)`): entry slots and value
        bytes (value, default and limits of each entry).

        boot=False leaves it off until node.boot(), so callbacks registered in
        between see its first transition."""
        if node_id != UNCONFIGURED:
            node_id = check_node_id(node_id, f"create_local_node on {self._where}")
        heartbeat_ms = check_ms(heartbeat_ms, "heartbeat_ms",
                                f"create_local_node({node_id}) on {self._where}")
        context = self._context
        with context.cond:
            if self.local_node is not None:
                raise ConfigurationError(
                    f"{self._where} already has local node {self.local_node.node_id}: "
                    f"one local node per line (cannot add node {node_id})")
            if node_id in self.nodes:
                raise ConfigurationError(
                    f"{self._where}: node-id {node_id} is already a remote node watched by "
                    "this line; a local node needs an id of its own")
            context.runtime.require_open(f"create_local_node({node_id}) on {self._where}")
            served = _served_od(od, node_id, store, f"create_local_node({node_id}) on "
                                f"{self._where}")
            if node_id == UNCONFIGURED and (served is None or (0x1018, 4) not in served):
                raise ConfigurationError(
                    f"create_local_node(255) on {self._where}: an unconfigured node needs an "
                    "OD with the serial number 0x1018:04 (its LSS address), else nothing "
                    "could ever give it a node-id")
            checked_store = check_store(store, f"create_local_node({node_id}) on {self._where}")
            groups = _store_groups(store_groups, store_interval_ms, checked_store,
                                   f"create_local_node({node_id}) on {self._where}")
            scope = context.scoped()
            node = LocalNode(self, scope, node_id, heartbeat_ms, served, checked_store, groups,
                             spare=_od_spare(od_spare_objects, od_spare_bytes,
                                             f"create_local_node({node_id}) on {self._where}"))
            self.local_node = node
            context.local_node_id = node_id
            if boot:
                try:
                    node.boot()
                except BaseException:
                    self.local_node = None
                    context.local_node_id = None
                    scope.release()
                    raise
        return node

    def add_node(self, node_id: int, od_or_timeout: Union[int, ODLike, None] = None, *,
                 heartbeat_timeout_ms: Optional[int] = None,
                 od: Optional[ODLike] = None) -> RemoteNode:
        """Watch a remote node (python-canopen's network.add_node): its boot-up,
        states and, with heartbeat_timeout_ms > 0, the loss of its heartbeat.
        od: its ObjectDictionary or EDS/DCF/XDD file, so `node.od[name].raw`
        and `node.usdo` know names and types. The second argument is either:
        python-canopen's `add_node(5, "drive.eds")` (the OD) or
        `add_node(5, 300)` (the timeout), so `add_node(5, "drive.eds",
        heartbeat_timeout_ms=300)` works too. Adding a node already watched
        updates the timeout and OD given (and keeps those not given) and
        returns it."""
        node_id = check_node_id(node_id, f"add_node on {self._where}")
        where = f"add_node({node_id}) on {self._where}"
        if isinstance(od_or_timeout, (int, float)):
            if heartbeat_timeout_ms is not None:
                raise ConfigurationError(
                    f"{where}: two heartbeat timeouts given ({od_or_timeout!r} and "
                    f"heartbeat_timeout_ms={heartbeat_timeout_ms!r})")
            heartbeat_timeout_ms = check_ms(od_or_timeout, "heartbeat_timeout_ms", where)
        elif od_or_timeout is not None:
            if od is not None:
                raise ConfigurationError(f"{where}: two object dictionaries given "
                                         f"({od_or_timeout!r} and od={od!r})")
            od = od_or_timeout
        if heartbeat_timeout_ms is not None:
            heartbeat_timeout_ms = check_ms(heartbeat_timeout_ms, "heartbeat_timeout_ms", where)
        context = self._context
        with context.cond:
            if self.local_node is not None and self.local_node.node_id == node_id:
                raise ConfigurationError(
                    f"{self._where}: node-id {node_id} is this line's local node; "
                    "a remote node needs another id")
            existing = self.nodes.get(node_id)
        remote_od = None if od is None else _remote_od(od, node_id, where)
        if existing is not None:
            if heartbeat_timeout_ms is not None:
                existing.heartbeat_timeout_ms = heartbeat_timeout_ms
            if remote_od is not None:
                existing.object_dictionary = remote_od
            return existing
        if heartbeat_timeout_ms is None:
            heartbeat_timeout_ms = 0
        self._check_consumer_owner(node_id, heartbeat_timeout_ms, f"add_node({node_id})")
        with context.cond:
            scope = context.scoped()
            try:
                node = RemoteNode(self, scope, node_id, heartbeat_timeout_ms, remote_od,
                                  nmt=self.nmt, client=self._client, line_emcy=self._emcy,
                                  check_consumer=self._check_consumer_owner)
            except BaseException:
                scope.release()
                raise
            self.nodes[node_id] = node
        return node

    def remove_node(self, node_id: int) -> None:
        """Stop watching a remote node (its callbacks no longer fire)."""
        node_id = check_node_id(node_id, f"remove_node on {self._where}")
        with self._context.cond:
            if node_id not in self.nodes:
                raise ConfigurationError(f"{self._where}: node {node_id} is not watched")
            self.nodes[node_id].detach(f"remove_node({node_id}) on {self._where}")
            del self.nodes[node_id]

    def __getitem__(self, node_id: int) -> RemoteNode:
        try:
            return self.nodes[node_id]
        except KeyError:
            raise KeyError(f"{self._where} watches no node {node_id!r} (add_node first; "
                           f"watched: {sorted(self.nodes)})") from None

    # python-canopen's Network is a mapping of node-id -> node: so is a line
    # (its remote nodes; the local node is line.local_node).
    def __iter__(self) -> Iterator[int]:
        return iter(sorted(self.nodes))

    def __len__(self) -> int:
        return len(self.nodes)

    def __contains__(self, node_id: object) -> bool:
        return node_id in self.nodes

    def _check_consumer_owner(self, node_id: int, ms: int, what: str) -> None:
        """A consumer time for a node that the local OD's 0x1016 already
        monitors belongs to that entry: refuse instead of changing it behind
        the OD's back (a state-only watch, ms = 0, is fine)."""
        local = self.local_node
        if ms == 0 or local is None or not local.booted:
            return
        owner = _consumer_entry(local, node_id)
        if owner is not None:
            sub, time_ms = owner
            raise ConfigurationError(
                f"{what} on {self._where}: node {node_id} is monitored by the local node's "
                f"0x1016:{sub:02X} ({time_ms} ms); change that entry "
                f"(node[0x1016][{sub}].raw) or add the node with heartbeat_timeout_ms=0")

    # ---------------------------------------------------------------- views
    @property
    def states(self) -> Dict[int, NmtState]:
        """{node_id: NmtState} of every node heard on this line, plus the local
        node. A node that sent its boot-up is PRE-OPERATIONAL."""
        runtime = self._context.runtime
        result = {node_id: remote_state_of(code) for node_id, code
                  in runtime.remote_states(self.index, f"states of {self._where}").items()}
        if self.local_node is not None:
            result[self.local_node.node_id] = self.local_node.state
        return dict(sorted(result.items()))

    @property
    def stats(self) -> Dict[str, int]:
        """The line's counters (co_line_stats_t): frames, overflows and every
        malformed or unhandled frame, by kind; then what the event queue to
        Python did with the line's events (co_rt_event_stats_t): posted,
        coalesced (PDO values merged into a newer one of the same PDO while
        the callbacks lagged; which PDO: `events_behind`) and lost."""
        what = f"stats of {self._where}"
        runtime = self._context.runtime
        stats = runtime.line_stats(self.index, what)
        stats.update(runtime.event_stats(self.index, what))
        return stats

    @property
    def events_behind(self) -> Dict[str, int]:
        """{listener: values it never saw}: PDOs ("node 2 RPDO1", "node 5
        TPDO1" of a remote node) whose callbacks fell behind, so the runtime
        kept only the newest value of each (see PdoMap.skipped)."""
        return self._context.events_behind

    @property
    def pending_awaits(self) -> int:
        """How many `await`s of this line's waits (await_for_state, emcy.await_,
        ...) are registered now; a finished, timed-out or cancelled one
        leaves none behind."""
        with self._context.cond:
            return len(self._context.waiter.async_waits)

    @property
    def driver_stats(self) -> Dict[str, int]:
        """Counters below the core: frames the kernel's socket buffer lost
        (`kernel_drops`), error frames, sends put off or refused, interface
        downs, frames and read/write calls on the socket (frames per call
        tell how well I/O batches) and the runtime thread's wake-ups."""
        return self._context.runtime.driver_stats(self.index, f"driver stats of {self._where}")

    @property
    def service_stats(self) -> Dict[str, Union[int, Dict[str, int]]]:
        """Counters of the process-data and error services: {'pdo': {...},
        'emcy': {...}, 'emcy_consumer', 'sync', 'time', 'guard_slave',
        'guard_master', 'sdo_server', 'usdo_server': {...}, 'usdo_client': {...},
        'pdo_watched': n};
        every frame a service ignored is counted here by reason (zeros for
        services not running)."""
        return self._context.runtime.service_stats(self.index,
                                                   f"service stats of {self._where}")

    @property
    def comm_events(self) -> List[CommEvent]:
        """Communication events seen so far, oldest first (at most 1000 kept)."""
        with self._context.cond:
            return list(self._comm_events)

    def simulate_comm_event(self, event: Union[CommEvent, int]) -> None:
        """In-process ('mem:') lines only: act as if the CAN controller had
        reported `event` (bus-off, interface down, ...), for tests of what
        the stack does then; it is heard like a real one (comm_events)."""
        where = f"simulate_comm_event({event!r}) on {self._where}"
        try:
            code = int(CommEvent(event))
        except ValueError:
            raise ConfigurationError(f"{where}: not a CommEvent") from None
        self._context.runtime.membus_comm_event(self.index, code, where)

    # ---------------------------------------------------------------- callbacks
    def on_comm_event(self, callback: Callable[[CommEvent], None],
                      loop: LoopArg = None) -> Callable[[CommEvent], None]:
        """callback(CommEvent): bus-off, error passive, overflow, interface down/up..."""
        return self._comm.add(callback, loop)

    def remove_comm_event_callback(self, callback: Callable[[CommEvent], None]) -> None:
        """Stop calling a callback on_comm_event registered."""
        self._comm.remove(callback)

    def on_emcy(self, callback: Callable[[Emcy], None],
                nodes: Optional[Iterable[int]] = None,
                loop: LoopArg = None) -> Callable[[Emcy], None]:
        """callback(Emcy) for every EMCY the line consumes: those of the
        nodes whose `node.emcy` was used, of the local node's 0x1028 entries,
        and of `nodes` (node-ids this call starts consuming)."""
        return self._emcy.add_callback(callback, nodes, loop=loop)

    def remove_emcy_callback(self, callback: Callable[[Emcy], None]) -> None:
        """Stop calling a callback on_emcy registered."""
        self._emcy.remove_callback(callback)

    def on_node_event(self, callback: Callable[[int, HeartbeatEvent, NmtState], None],
                      loop: LoopArg = None) -> Callable[[int, HeartbeatEvent, NmtState], None]:
        """callback(node_id, HeartbeatEvent, NmtState) for every node heard on
        this line, watched or not: BOOTUP, STATE_CHANGED, and STARTED / LOST
        for nodes with a heartbeat timeout (add_node)."""
        return self._node_events.add(callback, loop)

    def remove_node_event_callback(self, callback: Callable[[int, HeartbeatEvent, NmtState],
                                                            None]) -> None:
        self._node_events.remove(callback)

    def on_frame(self, callback: Callable[[Frame], None],
                 loop: LoopArg = None) -> Callable[[Frame], None]:
        """callback(Frame) for every frame on the line, ours included (tx=True).
        Monitor lines only: it costs Python code per frame."""
        if not self.monitor:
            raise ConfigurationError(
                f"on_frame needs a monitor line: {self._where} was opened with "
                "monitor=False (open another line with monitor=True)")
        return self._frames.add(callback, loop)

    def _comm_event_until(self, event: Union[CommEvent, int]) -> "Until[bool]":
        wanted = CommEvent(event)
        start = len(self._comm_events)
        return Until(lambda: wanted in self._comm_events[start:],
                     f"{self._where}: wait_for_comm_event({wanted.name})",
                     lambda: f"no {wanted.name}")

    def wait_for_comm_event(self, event: Union[CommEvent, int],
                            timeout: Optional[float] = 10.0) -> None:
        """Block until `event` occurs after this call."""
        self._context.waiter.wait_until(self._comm_event_until(event), timeout)

    async def await_for_comm_event(self, event: Union[CommEvent, int],
                                   timeout: Optional[float] = 10.0) -> None:
        await self._context.waiter.await_until(self._comm_event_until(event), timeout)

    # ---------------------------------------------------------------- raw frames
    def send_frame(self, can_id: int, data: bytes = b"", fd: Optional[bool] = None,
                   brs: Optional[bool] = None, extended: bool = False) -> None:
        """Send one frame as is (tools, tests; no protocol check).

        fd/brs default to the line's mode; an FD payload whose length is not a
        valid FD length is padded with zeros to the next one (12, 16, 20, ...).
        On a python-can line whose bus cannot keep up (3/4 of the line's send
        queue waiting for it) the frame is refused with CommandError instead
        of being lost: send it again later."""
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
        self._context.runtime.command(CommandKind.SEND_FRAME, self.index, frame=frame,
                                      what=where)

    # ---------------------------------------------------------------- USDO / SDO
    @property
    def usdo(self) -> UsdoClient:
        """The USDO client of this fd line: upload/download any node's
        entries (see canopenfd.transfer.usdo). Our client node-id is the local
        node's, else 127 (set `line.usdo.client_id` before the first transfer)."""
        require_protocol(self._context, "USDO")
        assert isinstance(self._client, UsdoClient)   # what fd lines make
        return self._client

    @property
    def sdo(self) -> SdoClient:
        """The SDO client of this classic line (see canopenfd.transfer.sdo)."""
        require_protocol(self._context, "SDO")
        assert isinstance(self._client, SdoClient)    # what classic lines make
        return self._client

    # ---------------------------------------------------------------- LSS
    @property
    def lss(self) -> LssMaster:
        """The LSS master (CiA 305) of this line: switch, configure, inquire,
        identify, fast scan (see canopenfd.services.lss)."""
        with self._context.cond:
            if self._lss is None:
                self._lss = LssMaster(self._context)
            return self._lss

    # ---------------------------------------------------------------- events
    def _event_comm(self, event: Event) -> Deferred:
        """CO_EV_COMM: a = co_comm_event_t."""
        try:
            comm = CommEvent(event.a)
        except ValueError:
            log.warning("%s: unknown communication event %d", self._where, event.a)
            return None
        self._comm_events.append(comm)
        del self._comm_events[:-1000]
        return lambda: self._comm.fire(comm)

    def _event_frame(self, event: Event) -> Deferred:
        """CO_EV_FRAME (monitor lines): a frame on the line."""
        frame = event.frame
        if frame is None or not self._frames:
            return None
        return lambda: self._frames.fire(frame)

    def _event_command_failed(self, event: Event) -> Deferred:
        """CO_EV_COMMAND_FAILED: a = the command, b = -its status."""
        try:
            command = CommandKind(event.a).name
        except ValueError:
            command = str(event.a)
        log.warning("%s: command %s failed in the runtime: %s", self._where, command,
                    status_text(-event.b))
        return None


def _consumer_entry(local: LocalNode, node_id: int) -> Optional[Tuple[int, int]]:
    """(sub-index, ms) of the local node's 0x1016 entry that monitors node_id, if any."""
    od = local.od
    if od is None or 0x1016 not in od:
        return None
    entry = od[0x1016]
    if isinstance(entry, ODVariable):   # a VAR, not the array CiA 301 defines: no consumers
        return None
    for variable in entry.values():
        if variable.subindex == 0:
            continue
        value = local[(0x1016, variable.subindex)].raw
        if isinstance(value, int) and (value >> 16) & 0x7F == node_id and value & 0xFFFF:
            return variable.subindex, value & 0xFFFF
    return None


def _remote_od(od: ODLike, node_id: int, where: str) -> ObjectDictionary:
    """The ObjectDictionary of a remote node: given, or imported from a file."""
    if isinstance(od, (str, bytes)) or hasattr(od, "__fspath__"):
        od = import_od(od, node_id=node_id)
    if not isinstance(od, ObjectDictionary):
        raise ConfigurationError(f"{where}: od must be an ObjectDictionary or a file path, "
                                 f"got {type(od).__name__}")
    return od


def _served_od(od: Optional[ODLike], node_id: int, store: Optional[StoreLike],
               where: str) -> Optional[ObjectDictionary]:
    """The ObjectDictionary a local node serves: given, or imported from a file."""
    if od is None:
        if store is not None:
            raise ConfigurationError(f"{where}: a parameter store needs an object dictionary "
                                     "(od=...)")
        return None
    return _remote_od(od, node_id, where)


def _store_groups(groups: Optional[Sequence[StoreGroup]], interval_ms: int,
                  store: object, where: str) -> Optional[GroupTable]:
    if groups is None:
        return None
    if store is None:
        raise ConfigurationError(f"{where}: store_groups need a store")
    return declare_groups(groups, interval_ms, where)


def _od_spare(objects: int, size: int, what: str) -> Tuple[int, int]:
    """The room for entries added at run time, checked."""
    for name, value in (("od_spare_objects", objects), ("od_spare_bytes", size)):
        if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < 1 << 24:
            raise ConfigurationError(f"{what}: {name} must be 0..16777215, got {value!r}")
    return objects, size
