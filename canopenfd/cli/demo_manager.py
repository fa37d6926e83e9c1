"""`canopenfd demo --manager`: a network manager bringing up three devices on
an in-process bus: one factory-fresh (no node-id) found by LSS fast scan and
given node-id 4, one whose configuration is outdated (its 0x1020 differs from
what the manager expects) re-configured from a DCF, one up to date; then the
CiA 302-2 start-up checks each, configures where needed and starts them all."""

from __future__ import annotations

import os
import queue
import time
from typing import Any, Callable, Dict, Tuple

from ..line import Line
from ..network import Network
from ..od import DataType, ODVariable, ObjectDictionary, add_node_array, add_stamp, demo_od
from ..od.concise import build_concise
from ..services.manager import ManagerEvent
from .common import EXIT_FAILED, EXIT_OK

VENDOR, PRODUCT, REVISION = 0x000001A2, 0x00DE0001, 0x00010000
#: The configuration the manager expects (0x1F26 date in days, 0x1F27 time in ms).
DATE, TIME = 15000, 43_200_000
#: node-id (0: factory-fresh) -> (name, serial, the 0x1020 it carries)
DEVICES: Dict[int, Tuple[str, int, Tuple[int, int]]] = {
    2: ("drive", 0x1002, (DATE, TIME)),        # configured and current
    3: ("io module", 0x1003, (14000, 1000)),   # configured, outdated
    0: ("sensor", 0x1004, (0, 0)),             # factory-fresh: node-id 255
}
FRESH_ID = 4
#: what the outdated device gets: heartbeat 200 ms (0x1017)
NEW_CONFIG = [(0x1017, 0, (200).to_bytes(2, "little"))]


def device_od(mode: str, serial: int, stamp: Tuple[int, int]) -> ObjectDictionary:
    od = demo_od(mode)
    for sub, value in enumerate((VENDOR, PRODUCT, REVISION, serial), start=1):
        identity = od.get_variable(0x1018, sub)
        assert identity is not None   # the demo dictionary has 0x1018:01..04
        identity.default = value
    add_stamp(od, stamp)
    return od


def manager_od(mode: str) -> ObjectDictionary:
    """Node 1: manager (0x1F80 bit 0), slaves 2, 3, 4 mandatory and booted
    (0x1F81 = 0x0D), their vendor checked (0x1F85), the configuration stamp
    expected for 2 and 3 (0x1F26/0x1F27; 0 for 4: it is configured anyway)."""
    od = demo_od(mode)
    od.add_object(ODVariable("NMT startup", 0x1F80, 0, DataType.UNSIGNED32, "rw", 0x01))
    slaves = {node: 0x0D for node in (2, 3, FRESH_ID)}
    add_node_array(od, 0x1F81, "Slave assignment", slaves, highest=FRESH_ID)
    add_node_array(od, 0x1F85, "Vendor identification", {node: VENDOR for node in slaves},
                   highest=FRESH_ID)
    add_node_array(od, 0x1F26, "Expected configuration date", {2: DATE, 3: DATE},
                   highest=FRESH_ID)
    add_node_array(od, 0x1F27, "Expected configuration time", {2: TIME, 3: TIME},
                   highest=FRESH_ID)
    return od


def run(classic: bool, say: Callable[[str], None]) -> int:
    mode = "classic" if classic else "fd"
    bus = f"mem:demo-manager-{os.getpid()}"
    with Network() as net:
        nodes: Dict[int, Any] = {}
        for node_id, (name, serial, stamp) in DEVICES.items():
            line = net.open_line(bus, mode=mode)
            nodes[node_id] = line.create_local_node(node_id or 255,
                                                    od=device_od(mode, serial, stamp))
            say(f"{name:9} serial 0x{serial:04X}: " +
                (f"node {node_id}, configuration of day {stamp[0]}" if node_id
                 else "factory-fresh, no node-id (255): only LSS answers"))
        manager: Line = net.open_line(bus, mode=mode)
        manager.create_local_node(1, od=manager_od(mode))
        say(f"manager  node 1 on {bus} ({mode}), slaves 2, 3, {FRESH_ID} mandatory")

        manager.lss.timeout_ms = 20
        found = manager.lss.fast_scan([FRESH_ID])
        for device in found:
            say(f"manager  LSS fast scan: serial 0x{device.serial:04X} -> node {device.node_id}")
        fresh = nodes[0]
        deadline = time.monotonic() + 5
        while fresh.node_id != FRESH_ID and time.monotonic() < deadline:
            time.sleep(0.01)
        if fresh.node_id != FRESH_ID:
            say("sensor   did not take its node-id")
            return EXIT_FAILED
        say(f"sensor   runs as node {FRESH_ID}")

        events: "queue.Queue[ManagerEvent]" = queue.Queue()
        manager.manager.add_callback(events.put)
        manager.manager.start(config_hook=True)
        say("manager  CiA 302-2 start-up: identity, configuration, start")
        while True:
            event = events.get(timeout=10)
            if event.kind == "boot" and event.boot_event == "checked" and event.od_index == 0x1020:
                say(f"manager  node {event.node_id}: 0x1020:{event.od_sub:02X} "
                    f"{'current' if event.matched else 'outdated'}")
            elif event.kind == "update-config":
                result = None
                if event.node_id == 3:
                    dcf = build_concise(NEW_CONFIG)
                    result = manager.manager.configure(3, dcf, expected=(DATE, TIME)).result()
                    say(f"manager  {result}")
                else:
                    say(f"manager  node {event.node_id}: nothing to configure")
                manager.manager.continue_config(event.node_id, result is None or result.ok)
            elif event.kind in ("slave-booted", "slave-failed", "halted"):
                say(f"manager  {event}")
            if event.kind in ("network-started", "halted"):
                break
        if event.kind == "halted":
            return EXIT_FAILED
        for node_id, node in nodes.items():
            node.nmt.wait_for_state("OPERATIONAL", timeout=5)
        states = ", ".join(f"node {node.node_id} {node.nmt.state.label}"
                           for node in nodes.values())
        say(f"manager  network started: {states}")
        heartbeat = nodes[3][0x1017].raw
        say(f"io module heartbeat now {heartbeat} ms, 0x1020 = "
            f"({nodes[3][0x1020][1].raw}, {nodes[3][0x1020][2].raw})")
        return EXIT_OK if heartbeat == 200 else EXIT_FAILED
