"""The minimal manager of seed 001 (CANopenIA-MGR) on one line: every node's
state as [5F04h,n] reports it, and the automation [5F01h,04h] switches on:

- KEEP_OP: when switched on, the local node and all nodes are started (NMT
  start to all); later, every node that boots or falls back to
  pre-operational/stopped is started (NMT start to it);
- HB_RECEIVE_ALL: every node is monitored with the default heartbeat time
  ([5F01h,08h]); a node whose heartbeat is lost is sent an NMT reset node;
- PDO_RECEIVE_ALL: a known node (one given an OD) is scanned when it boots:
  its TPDO configuration is read and each of its TPDOs heard; every mapped
  value received is indicated as D (node, index, sub, data).

States and events go to the host through `indicate` as D on [5F04h,n].
Scans run on the manager's own thread (they are SDO/USDO transfers, never on
the dispatcher).
"""

from __future__ import annotations

import logging
import queue
import threading
from functools import partial
from typing import Callable, Dict, List, Mapping, Optional, Set, Tuple

from ..errors import CanopenFDError
from ..line import Line, ODLike
from ..node import RemoteNode
from ..services.nmt import NmtState
from ..services.pdo import PdoMap
from . import remote_access as ra

log = logging.getLogger(__name__)

#: Nodes the manager watches, handles and maps ([5F01h,04h] bits 16..22 and 24..30).
NODE_COUNT = 127


def node_status_of(state: NmtState) -> int:
    """An NMT state as [5F04h,n] / [5F00h,02h] write it."""
    if state == NmtState.OPERATIONAL:
        return ra.NodeStatus.OPERATIONAL
    if state == NmtState.STOPPED:
        return ra.NodeStatus.STOPPED
    if state == NmtState.PRE_OPERATIONAL:
        return ra.NodeStatus.PREOP
    return ra.NodeStatus.BOOT


class MinimalManager:
    """The automation of one line; `indicate(NewData)` reaches the hosts."""

    def __init__(self, line: Line, indicate: Callable[[ra.NewData], None], *,
                 heartbeat_ms: int = 1000, known: Optional[Mapping[int, ODLike]] = None) -> None:
        self.line = line
        self._indicate = indicate
        self._lock = threading.Lock()
        self.control = 0
        self.heartbeat_ms = heartbeat_ms
        self._known = dict(known or {})
        self._status: Dict[int, int] = {}
        self._nodes: Dict[int, RemoteNode] = {}
        self._own_timeouts: Dict[int, int] = {}   # the application's, left alone
        self._created: Set[int] = set()           # nodes start() added: stop() removes them
        self._heard_pdos: Set[Tuple[int, int]] = set()   # (node, TPDO number) heard
        self._pdo_callbacks: List[Tuple[PdoMap, Callable[[PdoMap], None]]] = []
        self._stopped = False
        self._scans: "queue.Queue[Optional[int]]" = queue.Queue()
        self._thread: Optional[threading.Thread] = None
        #: scans that failed (transfer aborted, no OD)
        self.scans_aborted = 0
        #: NMT reset node commands sent for lost heartbeats
        self.resets_sent = 0

    # ------------------------------------------------------------ life
    def start(self) -> None:
        """Watch every node of the line (states, heartbeats) and start the scan thread."""
        line = self.line
        own = line.local_node.node_id if line.local_node is not None else 0
        for node_id in range(1, NODE_COUNT + 1):
            if node_id == own:
                continue
            od = self._known.get(node_id)
            if node_id not in line.nodes:
                self._created.add(node_id)
            node = line.add_node(node_id, od=od) if od is not None else line.add_node(node_id)
            self._nodes[node_id] = node
            self._own_timeouts[node_id] = node.heartbeat_timeout_ms
            node.on_bootup(partial(self._bootup, node_id))
            node.on_state_change(partial(self._state, node_id))
            node.on_heartbeat_lost(partial(self._lost, node_id))
            node.on_heartbeat_started(partial(self.report, node_id, ra.NodeStatus.HB_ACTIVE))
        self._thread = threading.Thread(target=self._scan_loop, daemon=True,
                                        name=f"ra manager {line.channel}")
        self._thread.start()

    def stop(self) -> None:
        """End the automation and give the line back as start() found it: no
        more NMT commands or indications, PDO callbacks removed, the nodes it
        added removed, the application's own nodes back to their heartbeat
        timeouts (their callbacks cannot be removed: they are silenced)."""
        with self._lock:
            if self._stopped:
                return
            self._stopped = True
            self.control = 0
            callbacks, self._pdo_callbacks = self._pdo_callbacks, []
        for pdo_map, callback in callbacks:
            pdo_map.remove_callback(callback)
        self._scans.put(None)
        if self._thread is not None:
            self._thread.join(5.0)
        for node_id, node in list(self._nodes.items()):
            try:
                if node_id in self._created:
                    if self.line.nodes.get(node_id) is node:
                        self.line.remove_node(node_id)
                elif node.heartbeat_timeout_ms != self._own_timeouts.get(node_id, 0):
                    node.heartbeat_timeout_ms = self._own_timeouts.get(node_id, 0)
            except CanopenFDError as exc:    # the line closed meanwhile
                log.info("remote access manager: node %d left as it is: %s", node_id, exc)
        self._nodes.clear()
        self._created.clear()

    # ------------------------------------------------------------ [5F01h,04h] / [5F01h,08h]
    def control_word(self) -> int:
        with self._lock:
            return self.control | NODE_COUNT << 16 | NODE_COUNT << 24

    def set_control(self, value: int) -> int:
        """Apply a control word; the error bits (0 = taken)."""
        bits = value & 0x1F
        if bits & (ra.ManagerControl.PDO_TRANSMIT_ALL | ra.ManagerControl.USE_SCANNED):
            return int(ra.RaError.NOT_SUPPORTED)
        with self._lock:
            if self._stopped:
                return int(ra.RaError.NOT_SUPPORTED)
            before, self.control = self.control, bits
        if (bits ^ before) & ra.ManagerControl.HB_RECEIVE_ALL:
            self._apply_heartbeat()
        if bits & ~before & ra.ManagerControl.KEEP_OP:
            self._start_all()
        if bits & ~before & ra.ManagerControl.PDO_RECEIVE_ALL:
            for node_id in sorted(self._known):
                self._scans.put(node_id)
        return 0

    def set_heartbeat_ms(self, value: int) -> int:
        with self._lock:
            self.heartbeat_ms = value
        self._apply_heartbeat()
        return 0

    def rescan(self, node_id: int) -> int:
        if not 1 <= node_id <= NODE_COUNT or node_id not in self._nodes:
            return int(ra.RaError.NODE_NOT_AVAILABLE)
        self._scans.put(node_id)
        return 0

    def _on(self, bit: ra.ManagerControl) -> bool:
        with self._lock:
            return bool(self.control & bit)

    def _apply_heartbeat(self) -> None:
        """Monitor every node the application does not monitor itself (its own
        timeouts, kept from the start, come back when the bit is cleared)."""
        on = self._on(ra.ManagerControl.HB_RECEIVE_ALL)
        for node_id, node in self._nodes.items():
            own = self._own_timeouts.get(node_id, 0)
            if own:
                continue
            try:
                node.heartbeat_timeout_ms = self.heartbeat_ms if on else 0
            except CanopenFDError as exc:    # e.g. the local node's 0x1016 monitors it
                log.info("remote access manager: node %d: %s", node_id, exc)

    def _start_all(self) -> None:
        """KEEP_OP switched on: the local node and every node (NMT start to all:
        nodes that booted before the gateway listened are not known by id)."""
        local = self.line.local_node
        if local is not None and local.state != NmtState.OPERATIONAL:
            local.apply("START")
        self.line.nmt.start(0)

    # ------------------------------------------------------------ states ([5F04h,n])
    def status(self, node_id: int) -> int:
        """The last state or event reported, else the state the line knows
        (BOOT = 0 for a node never heard)."""
        with self._lock:
            status = self._status.get(node_id)
        if status is not None:
            return status
        state = self.line.states.get(node_id)
        return ra.NodeStatus.BOOT if state is None else node_status_of(state)

    def report(self, node_id: int, status: int) -> None:
        """Record a node's state or event and tell the hosts."""
        with self._lock:
            if self._stopped:
                return      # the node callbacks stay registered: they end here
            self._status[node_id] = status
        self._indicate(ra.NewData(node_id, ra.NODE_STATE_INDEX, node_id, bytes((status,))))

    def _bootup(self, node_id: int) -> None:
        if self._stopped:
            return
        self.report(node_id, ra.NodeStatus.BOOT)
        if self._on(ra.ManagerControl.KEEP_OP):
            self.line.nmt.start(node_id)
        if self._on(ra.ManagerControl.PDO_RECEIVE_ALL) and node_id in self._known:
            self._scans.put(node_id)

    def _state(self, node_id: int, state: NmtState) -> None:
        if self._stopped:
            return
        if state == NmtState.INITIALISING:
            return      # the boot-up reported it
        self.report(node_id, node_status_of(state))
        if self._on(ra.ManagerControl.KEEP_OP) and state in (NmtState.PRE_OPERATIONAL,
                                                              NmtState.STOPPED):
            self.line.nmt.start(node_id)

    def _lost(self, node_id: int) -> None:
        if self._stopped:
            return
        self.report(node_id, ra.NodeStatus.HB_LOST)
        if self._on(ra.ManagerControl.HB_RECEIVE_ALL):
            # the seed's automated recovery: reset the lost node
            self.resets_sent += 1
            self.line.nmt.reset_node(node_id)

    # ------------------------------------------------------------ PDO scans
    def _scan_loop(self) -> None:
        while True:
            node_id = self._scans.get()
            if node_id is None:
                return
            try:
                self._scan(node_id)
            except Exception:     # a scan must never end the thread
                log.exception("remote access manager: scan of node %d", node_id)

    def _scan(self, node_id: int) -> None:
        node = self._nodes.get(node_id)
        if node is None:
            return
        self.report(node_id, ra.NodeStatus.SCAN_STARTED)
        try:
            maps = node.tpdo
            maps.read()
        except CanopenFDError as exc:
            log.info("remote access manager: scan of node %d aborted: %s", node_id, exc)
            self.scans_aborted += 1
            self.report(node_id, ra.NodeStatus.SCAN_ABORTED)
            return
        for number, pdo_map in maps.items():
            if pdo_map.cob_id is None or not pdo_map.enabled or not len(pdo_map):
                continue
            if (node_id, number) not in self._heard_pdos:      # one callback per TPDO
                self._heard_pdos.add((node_id, number))
                callback = pdo_map.add_callback(partial(self._pdo_received, node_id))
                with self._lock:
                    stopped = self._stopped
                    if not stopped:
                        self._pdo_callbacks.append((pdo_map, callback))
                if stopped:     # stop() came during the scan
                    pdo_map.remove_callback(callback)
        self.report(node_id, ra.NodeStatus.SCAN_COMPLETE)

    def _pdo_received(self, node_id: int, pdo_map: PdoMap) -> None:
        if self._stopped:
            return
        for variable in pdo_map:
            if variable.is_dummy:
                continue
            try:
                data = variable.get_data()
            except CanopenFDError:
                continue
            self._indicate(ra.NewData(node_id, variable.index, variable.subindex, data))
