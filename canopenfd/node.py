"""Nodes of a line: our own `LocalNode` and the `RemoteNode`s we watch.

A node is composition: its constructor builds its services (canopenfd.services,
canopenfd.transfer), each on the node's scope of the line context, and its
methods hand over to them.
"""

from __future__ import annotations

from typing import Any, Callable, Dict, List, Optional, Protocol, Tuple, Union

from ._aio import LoopArg
from ._binding.context import RuntimeLineContext
from ._checks import check_ms, check_node_id
from .errors import ConfigurationError
from .od import ODVariable, ObjectDictionary
from .od.datatypes import Value
from .services.cia402_sim import DriveSimulation
from .services.generic_io import GenericIo
from .services.emcy import EmcyConsumer, EmcyProducer, LineEmcy
from .services.errors import ErrorBits
from .services.flyma import FlyingMaster
from .services.guard import GuardEvent, NodeGuard
from .services.indications import READ, WRITE, Answer, Indications, ODRequest
from .services.leds import LedStates, LocalLeds
from .services.lss import LssSlave
from .services.mpdo import LocalMpdo, MpdoCallback
from .services.nmt import (DEFAULT_TICK_MS, HeartbeatMonitor, LocalNmt, NmtCommand,
                           NmtMaster, NmtSlave, NmtState, RemoteNmt, StateLike)
from .services.pdo import LocalPdoAccess, PdoMaps, RemotePdoAccess
from .services.served_od import Key, LocalObject, LocalValue, ServedDictionary
from .services.srdo import SrdoService
from .services.store import STORE_STATUS, StoreMedium, ParameterStore
from .services.store_groups import GroupTable
from .od.fileio import Source
from .transfer.client import TransferClient, require_protocol
from .transfer.remote import RemoteAccess, RemoteObjects, resolve

__all__ = ["LocalNode", "RemoteNode", "LocalValue", "LocalObject", "check_node_id",
           "check_ms", "STORE_STATUS"]

IndicationCallback = Callable[[ODRequest], Answer]


class NodeLine(Protocol):
    """What a node shows of its line (`node.line`, a Line)."""

    channel: str
    mode: str

    def __contains__(self, node_id: object) -> bool:
        """node_id is a remote node the line watches."""
        ...


class LocalNode:
    """The node this process runs on a line (NMT slave + heartbeat producer).

    Created by `Line.create_local_node()`: it boots at once (boot-up message,
    then PRE-OPERATIONAL) and produces its heartbeat every `heartbeat_ms`.
    With boot=False it waits for `boot()`, so callbacks registered first see
    the very first transition.
    """

    def __init__(self, line: NodeLine, context: RuntimeLineContext, node_id: int,
                 heartbeat_ms: int, od: Optional[ObjectDictionary] = None,
                 store: Union[None, str, StoreMedium] = None,
                 store_groups: Optional[GroupTable] = None, spare: Tuple[int, int] = (0, 0)
                 ) -> None:
        self.line = line
        self._od_spare = spare   # (entries, bytes) reserved for objects added at run time
        self.node_id = node_id
        #: The object dictionary this node serves (None: NMT and heartbeat only).
        self.od = od
        #: Where saved parameters (0x1010) live: a file path, an object with
        #: load()/save() (see canopenfd.services.store), or None.
        self.store = store
        self._context = context
        # The services name the node in messages through context.node_where, which
        # follows the node-id when LSS or a reset renumbers the node.
        self._slave = NmtSlave(context, node_id, heartbeat_ms)
        self.nmt = LocalNmt(self._slave)
        self._served = ServedDictionary(context, self)
        self._store = ParameterStore(context, self, store, store_groups)
        self._indications = Indications(context, self, self._served,
                                        self._store.persist_request)
        self._errors = ErrorBits(context, self)
        self._emcy = EmcyProducer(context, self, self._served, self._errors)
        #: Flying master (CiA 302-2): start() once the node booted.
        self.flying_master = FlyingMaster(context)
        self._leds = LocalLeds(context, self)
        self._mpdo = LocalMpdo(context)
        #: SRDOs and GFC (CiA 304): start(count) first.
        self.srdo = SrdoService(context, self._entry_value)
        #: The LSS slave (CiA 305): runs when the OD has the serial number 0x1018:04.
        self.lss = LssSlave(context, node_id)
        self.lss.add_configured_hook(self._renumbered)
        self._slave.add_renumber_hook(self._renumbered)
        #: A simulated CiA 402 drive over this node's OD (canopenfd.profiles.cia402).
        self.drive_simulation = DriveSimulation(context)
        #: CiA 401 generic I/O device run by the C core (profiles.cia401 uses it).
        self.generic_io = GenericIo(context)
        self._tpdo: Optional[PdoMaps] = None
        self._rpdo: Optional[PdoMaps] = None
        self._frozen_as: Optional[str] = None   # how self.od names us while we serve it
        if od is not None:
            access = LocalPdoAccess(self, self._served)
            self._tpdo = PdoMaps(context, self, "tpdo", od, access)
            self._rpdo = PdoMaps(context, self, "rpdo", od, access)

    def __repr__(self) -> str:
        return f"<LocalNode {self.node_id} on {self.line.channel!r}>"

    def _entry_value(self, index: int, sub: int) -> int:
        """An integer entry of the OD this node serves (KeyError: none)."""
        if self.od is None:
            raise KeyError(f"0x{index:04X} sub {sub} (the node serves no OD)")
        try:
            value = self[(index, sub)]
        except KeyError:
            raise KeyError(f"0x{index:04X} sub {sub}") from None
        if not isinstance(value, LocalValue):
            raise KeyError(f"0x{index:04X} sub {sub}")
        raw = value.raw
        if not isinstance(raw, int):
            raise KeyError(f"0x{index:04X} sub {sub} is not an integer")
        return raw

    def _renumbered(self, node_id: int) -> None:
        """LSS gave the node node_id (created unconfigured, or its pending one at a
        reset), or a reset activated set_node_id_at_reset's: it runs with it."""
        self.node_id = node_id
        self._slave.node_id = node_id
        self._context.local_node_id = node_id

    @property
    def _where(self) -> str:
        return f"local node {self.node_id} on line {self.line.channel!r}"

    # ---------------------------------------------------------------- boot
    @property
    def booted(self) -> bool:
        return self._slave.booted

    def boot(self) -> None:
        """Power the node on: boot-up message, PRE-OPERATIONAL, heartbeat.
        Only once; later restarts are NMT resets (`apply('reset-node')`)."""
        with self._context.cond:
            if self.booted:
                raise ConfigurationError(
                    f"{self._where} is already booted (restart it with apply('reset-node'))")
            if self.od is not None:
                heartbeat_ms = self._slave.heartbeat_ms
                overrides = {(0x1017, 0): heartbeat_ms} \
                    if heartbeat_ms and self._served.has_1017 else {}
                self._served.define(overrides, self._store.path, self._od_spare)
                self._frozen_as = self._where
                # from now on an added object goes to the C OD first; other changes raise
                self.od.freeze(self._frozen_as, self._served.add_live)
                self._store.open()
                self._indications.register_all()
                self._served.give_domains()
            self._slave.create()

    def release_od(self) -> None:
        """The network closed: the node serves nothing any more, so its
        object dictionary model may change again (unless another node took it)."""
        if self.od is not None and self._frozen_as is not None \
                and self.od.frozen_by == self._frozen_as:
            self.od.freeze(None)
        self._frozen_as = None

    # ---------------------------------------------------------------- values
    def __getitem__(self, key: Key) -> Union[LocalValue, LocalObject]:
        """The value of an entry of the served OD, by index, "index:sub",
        (index, sub), name or "Object.Sub": `node["Producer heartbeat time"].raw`;
        an ARRAY/RECORD gives a LocalObject: `node[0x1018][1].raw`."""
        return self._served.value(key)

    def serve_domain(self, key: Key, capacity: int) -> None:
        """Keep the data of DOMAIN entry `key` in the stack's memory (up to
        `capacity` bytes, allocated once): the network then uploads and
        downloads it (any size up to capacity, in chunks, no Python per
        frame) and `node[key].data` reads or replaces it. A download that
        fails leaves it empty, never half old and half new."""
        self._served.serve_domain(key, capacity)

    @property
    def unserved_domains(self) -> List[ODVariable]:
        """DOMAIN entries without memory (larger than 64 KiB or unbounded, and
        not given memory by serve_domain): the network's reads and writes of
        them are refused."""
        return self._served.unserved_domains()

    def export_eds(self, dest: Optional[Source] = None) -> Optional[str]:
        """The served OD as an EDS (CiA 306): written to dest (a path or a
        text file), or returned as text when dest is None."""
        return self._served.export_eds(dest)

    def export_dcf(self, dest: Optional[Source] = None) -> Optional[str]:
        """The served OD as a DCF: the EDS plus this node's id and every
        entry's current value as its ParameterValue (domains left out)."""
        return self._served.export_dcf(dest)

    def on_object_changed(self, callback: Callable[[LocalValue, str], None],
                          loop: LoopArg = None) -> Callable[[LocalValue, str], None]:
        """callback(value, origin) after an entry was written by the network
        (USDO/SDO download: origin 'network'); the application's own writes
        are not echoed. `value.raw` reads the new value. What a received RPDO
        writes is not told entry by entry (that would put Python on every
        frame): `node.rpdo[n].add_callback` hears each RPDO once."""
        return self._served.on_changed(callback, loop=loop)

    # ---------------------------------------------------------------- indications
    def on_read(self, key: Key, callback: Optional[IndicationCallback] = None
                ) -> Union[IndicationCallback, Callable[[IndicationCallback], IndicationCallback]]:
        """callback(request) before the network (SDO/USDO upload) reads the
        entry `key` (an ARRAY/RECORD: any of its sub-indices). It may refresh
        the value (`node[key].raw = ...`), refuse the read (return an abort
        code or raise AbortError) or `request.defer()` and answer later."""
        return self._indications.add(key, READ, callback)

    def on_write(self, key: Key, callback: Optional[IndicationCallback] = None
                 ) -> Union[IndicationCallback, Callable[[IndicationCallback], IndicationCallback]]:
        """callback(request) before a network write of `key` changes anything:
        `request.value` is the new value (type, length and limits already
        checked). Return None to accept, an abort code (or raise AbortError)
        to refuse, or `request.defer()` and answer later. Without callback: a
        decorator."""
        return self._indications.add(key, WRITE, callback)

    def remove_indication(self, callback: IndicationCallback) -> None:
        """Forget an on_read/on_write callback."""
        self._indications.remove(callback)

    # ---------------------------------------------------------------- parameter store
    def save_parameters(self, group: str = "all") -> None:
        """What writing "save" to 0x1010 does: the stored entries of `group`
        ('all', 'communication', 'application', 'manufacturer', or the names
        of the node's declared store_groups) go to the store
        file, atomically; they come back at the next boot or reset."""
        self._store.save_or_restore(group, True)

    def restore_defaults(self, group: str = "all") -> None:
        """What writing "load" to 0x1011 does: forget the saved values of
        `group`, so the next reset loads the defaults."""
        self._store.save_or_restore(group, False)

    def on_store_problem(self, callback: Callable[[str, int], None],
                         loop: LoopArg = None) -> Callable[[str, int], None]:
        """callback(status, records_skipped) when saved parameters could not be
        used at boot or reset ('damaged', 'foreign', 'io-error', 'too-big'):
        the node then runs on its defaults."""
        return self._store.on_problem(callback, loop=loop)

    @property
    def store_status(self) -> Optional[str]:
        """What the last parameter load (boot or reset) found in the store:
        'ok', 'empty', 'damaged', 'foreign', 'io-error', 'too-big'; None
        without a store or before boot."""
        return self._store.status

    # ---------------------------------------------------------------- state
    @property
    def state(self) -> NmtState:
        """Current NMT state (read from the runtime, so always up to date);
        INITIALISING until the node has booted."""
        return self._slave.state

    def apply(self, command: Union[NmtCommand, int, str]) -> None:
        """Apply an NMT command to this node as if the master had sent it."""
        self._slave.apply(command)

    def wait_for_state(self, state: StateLike, timeout: Optional[float] = 10.0) -> None:
        """Block until the node is (or has passed through) `state`."""
        self._slave.wait_for_state(state, timeout)

    async def await_for_state(self, state: StateLike, timeout: Optional[float] = 10.0) -> None:
        await self._slave.await_for_state(state, timeout)

    def set_node_id_at_reset(self, node_id: int) -> None:
        """Run with `node_id` from the next reset (communication or node) on,
        as a pending LSS node-id would: the boot-up carries it and the
        $NODEID defaults reload with it. `node.node_id` changes at that reset.
        The node must be booted; an id the line watches as a remote node is
        refused."""
        where = f"set_node_id_at_reset on {self._where}"
        node_id = check_node_id(node_id, where)
        if node_id in self.line:
            raise ConfigurationError(f"{where}: node-id {node_id} is a remote node this line "
                                     "watches; the local node needs an id of its own")
        if not self.booted:
            raise ConfigurationError(f"{where}: the node is not booted yet (create it with "
                                     f"node-id {node_id} instead)")
        self._context.runtime.node_id_at_reset(self._context.index, node_id, where)

    # ---------------------------------------------------------------- 0x1017
    @property
    def heartbeat_ms(self) -> int:
        """Heartbeat producer time (0x1017) in ms; 0 = no heartbeat.

        Setting it takes effect at once: the next heartbeat goes out one new
        period from now. A reset (node or communication) restores the value
        given to create_local_node() (with an OD: its default or saved value)."""
        if self.booted and self._served.has_1017:
            value = self._served.variable_value(0x1017, 0).raw
            if isinstance(value, int):   # else an OD with a non-integer 0x1017: not a time
                return value
        return self._slave.heartbeat_ms

    @heartbeat_ms.setter
    def heartbeat_ms(self, value: int) -> None:
        value = check_ms(value, "heartbeat_ms", self._where)
        if self.booted and self._served.has_1017:
            self._served.variable_value(0x1017, 0).raw = value  # the OD's after-write re-arms
            return
        self._slave.set_heartbeat(value)

    # ---------------------------------------------------------------- veto
    @property
    def allow_operational(self) -> bool:
        """When False, "start" (to OPERATIONAL) is refused and on_veto fires."""
        return self._slave.allow_operational

    @allow_operational.setter
    def allow_operational(self, allowed: bool) -> None:
        self._slave.allow_operational = bool(allowed)

    # ---------------------------------------------------------------- callbacks
    def on_state_change(self, callback: Callable[[NmtState, NmtState], None],
                        loop: LoopArg = None) -> Callable[[NmtState, NmtState], None]:
        """callback(old_state, new_state) after every transition."""
        return self._slave.on_state_change(callback, loop=loop)

    def on_veto(self, callback: Callable[[], None], loop: LoopArg = None) -> Callable[[], None]:
        """callback() when a start was refused (allow_operational is False)."""
        return self._slave.on_veto(callback, loop=loop)

    def on_reset(self, callback: Callable[[NmtCommand], None],
                 loop: LoopArg = None) -> Callable[[NmtCommand], None]:
        """callback(kind) when a reset runs (RESET_NODE or RESET_COMMUNICATION),
        before the node's new boot-up message."""
        return self._slave.on_reset(callback, loop=loop)

    # ---------------------------------------------------------------- PDO configuration
    @property
    def tpdo(self) -> PdoMaps:
        """The TPDOs of the served OD (0x1800../0x1A00..), by number:
        `node.tpdo[1].trans_type = 255`, `.add_variable(...)`, `.save()`
        (see canopenfd.services.pdo)."""
        return _pdo_maps(self._tpdo, f"local node {self.node_id}", "create_local_node(N, od=...)")

    @property
    def rpdo(self) -> PdoMaps:
        """The RPDOs of the served OD (0x1400../0x1600..), as `tpdo`."""
        return _pdo_maps(self._rpdo, f"local node {self.node_id}", "create_local_node(N, od=...)")

    def trigger_pdo(self, key: Key) -> int:
        """Tell the PDO service that entry `key` (index, (index, sub), name...)
        changed: every event-driven TPDO (types 0, 254, 255) mapping it is
        sent (respecting its inhibit time; in OPERATIONAL only). Returns how
        many TPDOs map it."""
        entry = self._served.entry(key)
        where = f"trigger_pdo({key!r}) on {self._where}"
        if not isinstance(entry, ODVariable):
            raise ConfigurationError(f"{where}: {entry!r} is not a single entry; give the "
                                     "sub-index")
        if not self.booted:
            raise ConfigurationError(f"{where}: the node is not booted yet")
        context = self._context
        return context.runtime.pdo_trigger_object(context.index, entry.index, entry.subindex,
                                                  where)

    def mpdo_stats(self) -> Dict[str, int]:
        """The node's MPDO counters (co_mpdo_stats_t): frames sent and send
        calls refused, values applied, frames ignored (bad length, wrong
        mode, another node's DAM, a SAM the dispatcher list does not name)
        and refused (the target object missing or refusing the value: a
        DAM one also sends EMCY 0x8230)."""
        where = f"mpdo_stats() on {self._where}"
        if not self.booted:
            raise ConfigurationError(f"{where}: the node is not booted yet")
        context = self._context
        return context.runtime.mpdo_stats(context.index, where)

    def on_mpdo(self, callback: MpdoCallback, loop: LoopArg = None) -> MpdoCallback:
        """callback(notice) for each MPDO addressed to this node, applied or
        refused: an MpdoNotice (mode, node, frame_index, frame_sub,
        local_index, local_sub, data, abort, rpdo, coalesced; see
        canopenfd.services.mpdo)."""
        return self._mpdo.add_callback(callback, loop=loop)

    def remove_mpdo_callback(self, callback: MpdoCallback) -> None:
        """Forget an on_mpdo callback (without any, no MPDO events are posted)."""
        self._mpdo.remove_callback(callback)

    # ---------------------------------------------------------------- EMCY
    @property
    def emcy(self) -> EmcyProducer:
        """The node's EMCY producer: `raise_error(code, ...)`, `clear(code)`,
        `error_register`, `active`, `history`, and the code table by
        application error id: `define(error_id, code, register_bits)`,
        `raise_defined(error_id)`, `clear_defined(error_id)`, `count(error_id)`
        (see canopenfd.services.emcy)."""
        return self._emcy

    @property
    def errors(self) -> ErrorBits:
        """The node's error-status bits and EMCY code table: `define(bit, code,
        register_bits)`, `report(bit, code)`, `reset(bit, code)`, `count(bit)`,
        `bits` (as 0x2100 shows them), `set_condition(register_bit, bits)`
        (see canopenfd.services.errors)."""
        return self._errors

    # ---------------------------------------------------------------- LEDs (CiA 303-3)
    def on_led(self, callback: Callable[[str, bool, str], None],
               loop: LoopArg = None) -> Callable[[str, bool, str], None]:
        """callback(led, on, pattern) for every change of the node's CiA 303-3
        indicators: led 'run' (green) or 'error' (red), on: lit now, pattern
        'off', 'on', 'flickering', 'blinking', 'single_flash', 'double_flash',
        'triple_flash' or 'quadruple_flash'. Enough to drive two GPIOs; the
        stack times the patterns (see canopenfd.services.leds)."""
        return self._leds.add_callback(callback, loop=loop)

    def remove_led_callback(self, callback: Callable[[str, bool, str], None]) -> None:
        """Forget an on_led callback (without any, no LED events are posted)."""
        self._leds.remove_callback(callback)

    @property
    def leds(self) -> LedStates:
        """What the LEDs show now: `leds.run.pattern`, `leds.error.on`,
        `leds.causes` (the error causes active)."""
        return self._leds.states

    def set_configuration_error(self, active: bool) -> None:
        """Show "invalid configuration" on the error LED (blinking) until
        set_configuration_error(False); communication errors take precedence."""
        self._leds.set_configuration_error(active)


class RemoteNode:
    """A node on the bus that this line watches (python-canopen's RemoteNode
    for NMT and heartbeat).

    Its state comes from its boot-up and heartbeat messages. With a heartbeat
    consumer time (`heartbeat_timeout_ms` > 0) the line reports when they stop
    (`on_heartbeat_lost`) and come back (`on_heartbeat_started`).
    """

    def __init__(self, line: NodeLine, context: RuntimeLineContext, node_id: int,
                 heartbeat_timeout_ms: int, od: Optional[ObjectDictionary] = None, *,
                 nmt: NmtMaster, client: TransferClient, line_emcy: LineEmcy,
                 check_consumer: Callable[[int, int, str], None]) -> None:
        self.line = line
        self.node_id = node_id
        self._context = context
        self._heartbeat_timeout_ms = heartbeat_timeout_ms
        self._check_consumer = check_consumer
        self._line_emcy = line_emcy
        where = self._where
        self._monitor = HeartbeatMonitor(context, node_id, where)
        self.nmt = RemoteNmt(self._monitor, nmt)
        self._guard = NodeGuard(context, node_id, where, self._monitor)
        self._emcy = EmcyConsumer(context, self, where, line_emcy)
        # USDO on fd lines, SDO on classic lines: what usdo / sdo / od / read use
        self._access = RemoteAccess(self, client)
        self._objects = RemoteObjects(self, self._access)
        self._tpdo: Optional[PdoMaps] = None
        self._rpdo: Optional[PdoMaps] = None
        self._object_dictionary: Optional[ObjectDictionary] = None
        self.object_dictionary = od
        # Watched from now on: its boot-up, states and (timeout > 0) heartbeat loss.
        self._monitor.watch(heartbeat_timeout_ms, f"add_node({node_id}) on {context.where}")
        self._monitor.track_runtime_state()

    def __repr__(self) -> str:
        return f"<RemoteNode {self.node_id} on {self.line.channel!r}>"

    @property
    def object_dictionary(self) -> Optional[ObjectDictionary]:
        """The node's object dictionary (names and types of its entries), or None."""
        return self._object_dictionary

    @object_dictionary.setter
    def object_dictionary(self, od: Optional[ObjectDictionary]) -> None:
        # The PDO objects are those of the OD: another OD, other PDO maps (the
        # RPDOs the master was sending with the old ones stop).
        if self._rpdo is not None:
            self._rpdo.stop_producing(f"node {self.node_id}: a new object dictionary")
        self._object_dictionary = od
        if od is None:
            self._tpdo = self._rpdo = None
        else:
            access = RemotePdoAccess(self._access)
            self._tpdo = PdoMaps(self._context, self, "tpdo", od, access)
            self._rpdo = PdoMaps(self._context, self, "rpdo", od, access)

    def detach(self, what: str) -> None:
        """Stop everything this node asked of the line: heartbeat monitoring,
        guarding, its EMCYs, its PDOs' CAN-IDs, its event handlers (the line
        calls it in remove_node; the node's callbacks no longer fire)."""
        self._monitor.unwatch(what)
        self._guard.release(what)
        self._line_emcy.release(self.node_id, what)
        for maps in (self._tpdo, self._rpdo):
            if maps is not None:
                maps.stop_watching(what)
        self._context.release()

    # ---------------------------------------------------------------- USDO / SDO
    @property
    def usdo(self) -> RemoteAccess:
        """USDO access (fd lines): upload/download by index, (index, sub),
        "INDEX:SUB" or OD name, blocking, awaitable or started in the
        background (see canopenfd.transfer.remote)."""
        require_protocol(self._context, "USDO")
        return self._access

    @property
    def sdo(self) -> RemoteAccess:
        """SDO access (classic lines), the same calls as `usdo`."""
        require_protocol(self._context, "SDO")
        return self._access

    def read(self, key: Key, **options: Any) -> Union[Value, bytes]:
        """Read an entry (USDO on fd lines, SDO on classic lines): the typed
        value when the node's OD knows the entry, else the bytes."""
        variable = self._variable(key)
        data = self._access.upload(key, **options)
        return variable.decode_raw(data) if variable is not None else data

    def write(self, key: Key, value: Union[Value, bytes], **options: Any) -> None:
        """Write an entry (typed by the node's OD when it knows the entry,
        else `value` must be bytes)."""
        self._access.download(key, self._encoded(key, value), **options)

    async def aread(self, key: Key, **options: Any) -> Union[Value, bytes]:
        variable = self._variable(key)
        data = await self._access.aupload(key, **options)
        return variable.decode_raw(data) if variable is not None else data

    async def awrite(self, key: Key, value: Union[Value, bytes], **options: Any) -> None:
        await self._access.adownload(key, self._encoded(key, value), **options)

    def _variable(self, key: Key) -> Optional[ODVariable]:
        return resolve(key, self.object_dictionary, f"node {self.node_id}")[2]

    def _encoded(self, key: Key, value: Union[Value, bytes]) -> bytes:
        variable = self._variable(key)
        if variable is not None:
            return variable.encode_raw(value)
        if not isinstance(value, (bytes, bytearray, memoryview)):
            raise ConfigurationError(
                f"node {self.node_id}: write({key!r}): without an OD entry the value must be "
                f"bytes, got {type(value).__name__} (add the node with od=...)")
        return bytes(value)

    @property
    def od(self) -> RemoteObjects:
        """Typed values by the node's OD: `remote.od["Producer heartbeat
        time"].raw = 100`, `remote.od[0x1018][1].raw`."""
        return self._objects

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
        return self._monitor.state

    @property
    def heartbeat_alive(self) -> Optional[bool]:
        """True while heartbeats arrive, False after a loss or a boot-up,
        None before the first heartbeat."""
        return self._monitor.alive

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
        self._check_consumer(self.node_id, value, f"heartbeat_timeout_ms = {value}")
        self._monitor.watch(value, f"heartbeat_timeout_ms = {value} on {self._where}")
        self._heartbeat_timeout_ms = value

    # ---------------------------------------------------------------- waits
    def wait_for_bootup(self, timeout: Optional[float] = 10.0) -> None:
        """Block until the node's next boot-up message (one sent after this
        call: start waiting before the node boots, or use on_bootup)."""
        self._monitor.wait_for_bootup(timeout)

    def wait_for_heartbeat(self, timeout: Optional[float] = 10.0) -> NmtState:
        """Block until the node is heard heartbeating; returns its state.

        Returns at once while heartbeats arrive in time (the consumer is
        active); otherwise waits for the next one. Per-frame events do not
        exist by design (no Python per frame), so an unchanged heartbeat is
        only seen through the consumer's monitoring."""
        return self._monitor.wait_for_heartbeat(timeout)

    def wait_for_state(self, state: StateLike, timeout: Optional[float] = 10.0) -> None:
        """Block until the node reports `state` (or has reported it since the call)."""
        self._monitor.wait_for_state(state, timeout)

    # The waits above for `await` (same results and errors; no thread each).
    async def await_for_bootup(self, timeout: Optional[float] = 10.0) -> None:
        await self._monitor.await_for_bootup(timeout)

    async def await_for_heartbeat(self, timeout: Optional[float] = 10.0) -> NmtState:
        return await self._monitor.await_for_heartbeat(timeout)

    async def await_for_state(self, state: StateLike, timeout: Optional[float] = 10.0) -> None:
        await self._monitor.await_for_state(state, timeout)

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
    def on_bootup(self, callback: Callable[[], None], loop: LoopArg = None) -> Callable[[], None]:
        """callback() when the node sends its boot-up message."""
        return self._monitor.on_bootup(callback, loop=loop)

    def on_state_change(self, callback: Callable[[NmtState], None],
                        loop: LoopArg = None) -> Callable[[NmtState], None]:
        """callback(new_state) when the node reports another state."""
        return self._monitor.on_state_change(callback, loop=loop)

    def on_heartbeat_lost(self, callback: Callable[[], None],
                          loop: LoopArg = None) -> Callable[[], None]:
        """callback() when no heartbeat came within heartbeat_timeout_ms."""
        return self._monitor.on_heartbeat_lost(callback, loop=loop)

    def on_heartbeat_started(self, callback: Callable[[], None],
                             loop: LoopArg = None) -> Callable[[], None]:
        """callback() at the first heartbeat, and when heartbeats resume."""
        return self._monitor.on_heartbeat_started(callback, loop=loop)

    def add_heartbeat_callback(self, callback: Callable[[NmtState], None],
                               min_interval_ms: int = DEFAULT_TICK_MS,
                               loop: LoopArg = None) -> None:
        """python-canopen's callback(state) for every heartbeat of the node and
        its boot-up (state INITIALISING): a liveness tick. The C runtime tells
        at most one heartbeat per min_interval_ms (default 10), and only while
        callbacks exist, so no Python runs per frame when nobody asked; at most
        8 nodes of a line tick at once."""
        self._monitor.add_heartbeat_callback(callback, min_interval_ms, loop=loop)

    def remove_heartbeat_callback(self, callback: Callable[[NmtState], None]) -> None:
        """Remove a heartbeat callback (the last one stops the ticks)."""
        self._monitor.remove_heartbeat_callback(callback)

    # ---------------------------------------------------------------- EMCY
    @property
    def emcy(self) -> EmcyConsumer:
        """The node's EMCYs (python-canopen's `node.emcy`): `add_callback(cb)`,
        `log`, `active`, `wait(code, timeout)`. The line consumes them from
        the first use on (see canopenfd.services.emcy)."""
        self._line_emcy.consume(self.node_id, f"EMCY consumer of {self._where}")
        return self._emcy

    # ---------------------------------------------------------------- guarding
    def guard(self, guard_time_ms: int, life_time_factor: int) -> None:
        """Node guarding (classic lines; CAN FD has no remote frames): a
        remote frame on 0x700 + node-id every guard_time_ms, answered with the
        node's state and a toggle bit; life_time_factor answers missed in a
        row is "lost" (add_guard_callback). Guarding again changes the times.
        Guarding a node that sends heartbeats logs a warning (it would not
        answer: false losses)."""
        self._guard.guard(guard_time_ms, life_time_factor, self._heartbeat_timeout_ms > 0)

    def unguard(self) -> None:
        """Stop guarding the node."""
        self._guard.unguard()

    def add_guard_callback(self, callback: Callable[[GuardEvent, NmtState], None],
                           loop: LoopArg = None) -> Callable[[GuardEvent, NmtState], None]:
        """callback(event, state): event a GuardEvent (a str: 'started',
        'state-changed', 'lost', 'resumed', 'toggle-error', 'unexpected-state'),
        state the NmtState the node answered (its last one for 'lost').
        'lost' and 'resumed' also fire on_heartbeat_lost / on_heartbeat_started."""
        return self._guard.add_callback(callback, loop=loop)

    # ---------------------------------------------------------------- PDO configuration
    @property
    def tpdo(self) -> PdoMaps:
        """The TPDOs of the node's OD (0x1800../0x1A00..), by number:
        `node.tpdo[1].trans_type = 255`, `.add_variable(...)`, `.save()`
        through USDO (fd lines) or SDO (classic lines); see canopenfd.services.pdo."""
        return _pdo_maps(self._tpdo, f"node {self.node_id}", "line.add_node(N, od=...)")

    @property
    def rpdo(self) -> PdoMaps:
        """The RPDOs of the node's OD (0x1400../0x1600..), as `tpdo`."""
        return _pdo_maps(self._rpdo, f"node {self.node_id}", "line.add_node(N, od=...)")


def _pdo_maps(maps: Optional[PdoMaps], where: str, how: str) -> PdoMaps:
    if maps is None:
        raise ConfigurationError(f"{where}: no object dictionary, so no PDO objects are known "
                                 f"({how})")
    return maps
