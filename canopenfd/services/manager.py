"""CiA 302-2 network manager: the line's local node boots the network its
object dictionary describes (0x1F80 start-up, 0x1F81 slave list, 0x1F84..0x1F88
expected identity, 0x1F89 boot time, 0x1016 heartbeat times) and starts it.

    manager = line.manager
    manager.add_callback(print)          # callback(ManagerEvent)
    manager.start()
    manager.wait_started(timeout=10)     # or: await manager.started()

Every slave's boot process runs in C (co_boot/co_manager); what it does and
finds comes here as ManagerEvent. With a hook asked for at start(), the
manager waits for the application: continue_software(node, done),
continue_config(node, done), continue_operational(). The configuration
manager (CiA 302-3) is `line.manager.configure(node, dcf)`: see
canopenfd.services.config.
"""

from __future__ import annotations

import logging
import struct
import threading
from typing import Callable, Dict, List, Mapping, NamedTuple, Optional, Tuple

from .._binding.constants import (BootError, BootEvent, BootStep, EventKind, ManagerEventCode,
                                  ManagerPhase, NmtCommand, SlaveStatus)
from .._binding.context import Deferred, LineContext
from .._binding.runtime import Event
from .._aio import LoopArg
from .._callbacks import CallbackList, Until, chain
from .._checks import check_node_id
from ..errors import CanopenFDError, ConfigurationError
from ..od import ObjectDictionary
from .config import ConfigManager, Configuration, DcfSource, Stamp

__all__ = ["ManagerEvent", "ManagerPhase", "NetworkManager", "NetworkStartError",
           "SlaveStatus"]

log = logging.getLogger(__name__)

#: co_manager.h's CO_MANAGER_HOOK_* bits.
_HOOK_SOFTWARE, _HOOK_CONFIG, _HOOK_OPERATIONAL = 1, 2, 4


def _name(member: object) -> str:
    return str(getattr(member, "name", member)).lower().replace("_", "-")


def _letter(code: int) -> str:
    """'' for OK, else the CiA 302-2 error letter."""
    return "" if code == int(BootError.OK) else chr(code)


class NetworkStartError(Exception):
    """A mandatory slave failed: the network start halted."""

    def __init__(self, node_id: int, error: str) -> None:
        super().__init__(f"network start halted: mandatory slave {node_id} failed with "
                         f"error {error!r} (CiA 302-2)")
        self.node_id = node_id
        self.error = error


class ManagerEvent(NamedTuple):
    """One report of the network manager (CO_EV_MANAGER).

    kind: 'boot' (a boot process report, see boot_event), 'slave-booted',
    'slave-failed', 'update-software', 'update-config', 'ready-operational',
    'network-started', 'halted', 'slave-started', 'error-control',
    'configured' (a 0x1F25 configuration request of node_id ended: error ''
    or 'J' with the first refused entry in od_index, od_sub and abort),
    'active' (the flying master made this node the active master: the
    start-up runs again), 'passive' (another node is, or may become, the
    active master: this manager stopped and sends nothing).
    error: '' or the CiA 302-2 letter 'A'..'O'. For kind 'boot': boot_event
    ('started', 'checked', 'update-software', 'update-config', 'done'), step,
    and for 'checked' the entry read (index, sub), whether it matched, the
    expected and received values, the byte count and the SDO abort code
    (od_index, od_sub, matched, expected, got, got_length, abort)."""

    kind: str
    node_id: int
    error: str
    mandatory: bool
    command: Optional[NmtCommand] = None
    boot_event: str = ""
    step: str = ""
    od_index: int = 0
    od_sub: int = 0
    matched: bool = False
    expected: int = 0
    got: int = 0
    got_length: int = 0
    abort: int = 0

    def __str__(self) -> str:
        where = f"node {self.node_id}" if self.node_id else "network"
        if self.kind == "boot" and self.boot_event == "checked":
            value = (f"abort 0x{self.abort:08X}" if self.abort else
                     f"got 0x{self.got:08X} ({self.got_length} bytes)")
            verdict = "ok" if self.matched else "differs"
            return (f"{where}: 0x{self.od_index:04X}:{self.od_sub:02X} expected "
                    f"0x{self.expected:08X}, {value}: {verdict}")
        if self.kind == "configured" and self.error:
            return (f"{where}: configuration request failed at 0x{self.od_index:04X}:"
                    f"{self.od_sub:02X} (abort 0x{self.abort:08X})")
        if self.kind == "boot":
            text = f"{where}: boot {self.boot_event}"
            return text + (f" with error {self.error}" if self.error else "")
        return f"{where}: {self.kind}" + (f" (error {self.error})" if self.error else "")


def _event_of(event: Event) -> Optional[ManagerEvent]:
    try:
        code = ManagerEventCode(event.a & 0xFF)
    except ValueError:
        return None
    error = _letter((event.a >> 8) & 0xFF)
    mandatory = bool((event.a >> 16) & 1)
    command_code = (event.a >> 24) & 0xFF
    command = NmtCommand(command_code) if command_code else None
    if code not in (ManagerEventCode.BOOT, ManagerEventCode.CONFIGURED):
        return ManagerEvent(_name(code), event.node, error, mandatory, command)
    boot_event = _name(BootEvent(event.b & 0xFF)) if event.b & 0xFF else ""
    step = _name(BootStep((event.b >> 8) & 0xFF)) if code == ManagerEventCode.BOOT else ""
    details = event.data if len(event.data) >= 16 else bytes(16)
    index, _state, got_length, expected, got, abort = struct.unpack_from("<HBBIII", details)
    return ManagerEvent(_name(code), event.node, error, mandatory, command,
                        boot_event=boot_event, step=step, od_index=index,
                        od_sub=(event.b >> 16) & 0xFF, matched=bool((event.b >> 24) & 1),
                        expected=expected, got=got, got_length=got_length, abort=abort)


class NetworkManager:
    """The CiA 302-2 network start-up run by the line's local node (`line.manager`).

    The local node needs an object dictionary with 0x1F80 bit 0 set and its
    slaves in 0x1F81 (sub-index = node-id)."""

    def __init__(self, context: LineContext, configurator: ConfigManager,
                 local_od: Callable[[], Optional[ObjectDictionary]]) -> None:
        self._context = context
        self._configurator = configurator
        self._local_od = local_od
        # start(): the slaves configured here (node -> DCF) and whether the
        # application answers the configuration hook of the others
        self._dcfs: Dict[int, DcfSource] = {}
        self._app_configures = False
        self._where = f"network manager of {context.where}"
        self._callbacks = CallbackList(self._where)
        self._events: List[ManagerEvent] = []
        # network start: None while running, else (started, halting event)
        self._outcome: Optional[Tuple[bool, Optional[ManagerEvent]]] = None
        self._running = False
        context.subscribe(EventKind.MANAGER, self._event)

    def configure(self, node: int, dcf: DcfSource, expected: Stamp = None, *,
                  continue_on_error: bool = False, timeout_ms: int = 0) -> Configuration:
        """Configure `node` with a concise DCF or a DCF / XDC file (CiA 302-3
        configuration manager, see ConfigManager.configure); `result()` blocks,
        `await` works. The network start-up's configuration hook
        (continue_config) is where an application calls it."""
        return self._configurator.configure(node, dcf, expected,
                                            continue_on_error=continue_on_error,
                                            timeout_ms=timeout_ms)

    def start(self, *, software_hook: bool = False, config_hook: bool = False,
              operational_hook: bool = False, parallel: int = 0, retry_ms: int = 0,
              configurations: Optional[Mapping[int, DcfSource]] = None) -> None:
        """(Re)start the network boot-up. A hook set here makes the manager wait
        for the matching continue_*() call; without it the manager answers
        itself (software update: failed, configuration: done, operational: go).
        parallel: boot processes at once (0: the client's channels); retry_ms:
        a silent slave is asked again after (0: 1 s).

        configurations: {node: concise DCF bytes or a DCF / XDC / concise file}
        written by the manager itself when the start-up finds that node's
        configuration outdated (0x1020 against 0x1F26/0x1F27, which are
        written as its stamp); a concise DCF in the local OD's 0x1F22:node
        (a DOMAIN's default) counts too. A refused entry ends the node's boot
        with error J. The hook (config_hook) then comes only for the others."""
        where = f"start() of the {self._where}"
        if self._context.local_node_id is None:
            raise ConfigurationError(f"{where}: the line has no local node; create one with "
                                     "an object dictionary holding 0x1F80 and 0x1F81")
        for name, value, top in (("parallel", parallel, 127), ("retry_ms", retry_ms, 3600000)):
            if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= top:
                raise ConfigurationError(f"{where}: {name} must be an int 0..{top}, got "
                                         f"{value!r}")
        dcfs = self._concise_in_od()
        dcfs.update(configurations or {})
        for node in dcfs:
            check_node_id(node, f"{where}: configurations")
        hooks = ((_HOOK_SOFTWARE if software_hook else 0)
                 | (_HOOK_CONFIG if config_hook or dcfs else 0)
                 | (_HOOK_OPERATIONAL if operational_hook else 0))
        with self._context.cond:
            self._outcome = None
            self._events.clear()
            self._dcfs = dcfs
            self._app_configures = config_hook
        self._context.runtime.manager_start(self._context.index, hooks, parallel, retry_ms,
                                            where)
        self._running = True

    def stop(self) -> None:
        """Stop every boot process (slaves stay as they are)."""
        self._context.runtime.manager_stop(self._context.index, f"stop() of the {self._where}")

    def add_callback(self, callback: Callable[[ManagerEvent], None],
                     loop: LoopArg = None) -> Callable[[ManagerEvent], None]:
        """callback(ManagerEvent) for every report (on the dispatcher thread)."""
        return self._callbacks.add(callback, loop)

    @property
    def events(self) -> List[ManagerEvent]:
        """The reports since the last start()."""
        with self._context.cond:
            return list(self._events)

    # ---------------------------------------------------------------- answers
    def continue_software(self, node_id: int, done: bool = True) -> None:
        """The software of node_id was updated (done) or could not be (error I)."""
        self._answer(ManagerEventCode.UPDATE_SOFTWARE, node_id, done, "continue_software")

    def continue_config(self, node_id: int, done: bool = True) -> None:
        """The configuration of node_id was written (done) or not (error J)."""
        self._answer(ManagerEventCode.UPDATE_CONFIG, node_id, done, "continue_config")

    def continue_operational(self) -> None:
        """Go on with "ready for operational": the manager enters operational and
        starts the slaves (as 0x1F80 says)."""
        self._answer(ManagerEventCode.READY_OPERATIONAL, 0, True, "continue_operational")

    def _answer(self, what: ManagerEventCode, node_id: int, done: bool, name: str) -> None:
        where = f"{name}({node_id if node_id else ''}) of the {self._where}"
        if what != ManagerEventCode.READY_OPERATIONAL:
            node_id = check_node_id(node_id, where)
        self._context.runtime.manager_continue(self._context.index, int(what), node_id, done,
                                               where)

    # ---------------------------------------------------------------- state
    @property
    def phase(self) -> Optional[ManagerPhase]:
        """IDLE, BOOTING, READY, RUNNING or HALTED; None before start()."""
        value = self._context.runtime.manager_state(self._context.index, 0,
                                                    f"phase of the {self._where}")
        return None if value is None else ManagerPhase(value)

    def slave(self, node_id: int) -> Tuple[SlaveStatus, str]:
        """(status, error letter or '') of a slave of the network list."""
        where = f"slave({node_id!r}) of the {self._where}"
        node_id = check_node_id(node_id, where)
        value = self._context.runtime.manager_state(self._context.index, node_id, where)
        if value is None:
            raise ConfigurationError(f"{where}: the manager was not started")
        return SlaveStatus(value & 0xFF), _letter((value >> 8) & 0xFF)

    def _started_until(self, name: str) -> "Until[Optional[Tuple[bool, Optional[ManagerEvent]]]]":
        where = f"{name} of the {self._where}"
        if not self._running:
            raise ConfigurationError(f"{where}: start() first")
        return Until(lambda: self._outcome, where, self._not_started)

    def wait_started(self, timeout: Optional[float] = 10.0) -> None:
        """Block until the network started; NetworkStartError when a mandatory
        slave failed, TimeoutError when neither happened in time."""
        until = self._started_until("wait_started()")
        self._raise_halt(self._context.waiter.wait_until(until, timeout))

    async def await_started(self, timeout: Optional[float] = 10.0) -> None:
        """wait_started() for `await`."""
        until = self._started_until("await_started()")
        self._raise_halt(await self._context.waiter.await_until(until, timeout))

    def _not_started(self) -> str:
        """Why the network is not started yet (under the line's condition)."""
        waiting = sorted({e.node_id for e in self._events if e.kind == "boot"} -
                         {e.node_id for e in self._events if e.kind == "slave-booted"})
        return (f"network not started (slaves not booted: {waiting})" if waiting else
                "network not started")

    async def started(self) -> None:
        """Await the network start, however long it takes (NetworkStartError
        when it halted): await_started(timeout=None)."""
        if not self._running:
            raise ConfigurationError(f"started() of the {self._where}: start() first")
        await self.await_started(None)

    @staticmethod
    def _raise_halt(outcome: Optional[Tuple[bool, Optional[ManagerEvent]]]) -> None:
        if outcome is None:
            return
        started, halted = outcome
        if not started and halted is not None:
            raise NetworkStartError(halted.node_id, halted.error)

    # ---------------------------------------------------------------- events
    # ---------------------------------------------------------------- configurations
    def _concise_in_od(self) -> Dict[int, DcfSource]:
        """{node: concise DCF} of the local OD's 0x1F22 (non-empty DOMAIN defaults)."""
        od = self._local_od()
        found: Dict[int, DcfSource] = {}
        for node in range(1, 128):
            entry = od.get_variable(0x1F22, node) if od is not None else None
            value = entry.default if entry is not None else None
            if isinstance(value, (bytes, bytearray)) and value:
                found[node] = bytes(value)
        return found

    def _stamp_of(self, node: int) -> Stamp:
        """(0x1F26:node, 0x1F27:node) of the local OD when both are set, else False."""
        od = self._local_od()
        values = []
        for index in (0x1F26, 0x1F27):
            entry = od.get_variable(index, node) if od is not None else None
            value = None if entry is None else \
                entry.value if entry.value is not None else entry.default
            values.append(value)
        date, time = values
        if isinstance(date, int) and isinstance(time, int) and date and time:
            return (date, time)
        return False

    def _configure_in_start_up(self, node: int, dcf: Optional[DcfSource]) -> None:
        """Answer the configuration hook of node: write dcf (none: nothing to
        write), then continue, on a thread of its own (the dispatcher must
        not wait for the transfers' ends)."""
        def run() -> None:
            done = True
            if dcf is not None:
                try:
                    result = self.configure(node, dcf, self._stamp_of(node)).result()
                    done = result.ok
                    if not done:
                        log.warning("%s: %s", self._where, result)
                except CanopenFDError as exc:
                    log.warning("%s: configuring node %d: %s", self._where, node, exc)
                    done = False
            try:
                self.continue_config(node, done)
            except CanopenFDError as exc:   # closed or stopped meanwhile
                log.debug("%s: %s", self._where, exc)

        threading.Thread(target=run, name=f"canopenfd configure node {node}",
                         daemon=True).start()

    def _event(self, event: Event) -> Deferred:
        """CO_EV_MANAGER (under the line's condition): record, then callbacks."""
        report = _event_of(event)
        if report is None:
            return None
        self._events.append(report)
        calls: List[Callable[[], None]] = []
        if report.kind == "update-config" and (report.node_id in self._dcfs
                                               or not self._app_configures):
            dcf = self._dcfs.get(report.node_id)
            calls.append(lambda: self._configure_in_start_up(report.node_id, dcf))
        if report.kind == "active":
            self._outcome = None   # the flying master's new start-up: wait for it
        if report.kind in ("network-started", "halted") and self._outcome is None:
            self._outcome = (report.kind == "network-started",
                             report if report.kind == "halted" else None)
        if report.kind == "slave-failed":
            log.warning("%s: %s", self._where, report)
        calls.append(lambda: self._callbacks.fire(report))
        return chain(calls)
