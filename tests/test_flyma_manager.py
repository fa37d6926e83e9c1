"""The flying master decides which network manager runs (CiA 302-2): three
stack instances (three Networks) on one python-can virtual bus, each a
master-capable node whose OD makes it a manager of slaves 2 and 3 (a fourth
Network). Every candidate starts its manager; only the winner of the
negotiation boots the slaves ('active'), the others stay 'passive'. On the
wire (a plain python-can listener): every NMT command addressed to a slave
is one the winner's manager reported sending. The winner's Network closes:
the next winner's manager boots the slaves again (they were reset by the
network reset), the third candidate never manages anything."""

from __future__ import annotations

import threading
import time
from typing import List

import pytest

import canopenfd
from canopenfd.od import demo_od
from helpers import Recorder, scaled, virtual_bus
from test_manager import manager_od

can = pytest.importorskip("can")

TIMING = dict(detect=0.05, delay=0.1, priority_slot=0.3, device_slot=0.005,
              multiple_master=2.0, capable=0.1)
SLAVES = (2, 3)


class Sniffer(can.Listener):
    def __init__(self) -> None:
        self.frames: List[can.Message] = []
        self._lock = threading.Lock()

    def on_message_received(self, msg: can.Message) -> None:
        with self._lock:
            self.frames.append(msg)

    def nmt_to(self, node: int) -> List[int]:
        """The command specifiers of the NMT frames addressed to node."""
        with self._lock:
            return [m.data[0] for m in self.frames
                    if m.arbitration_id == 0 and len(m.data) == 2 and m.data[1] == node]


def started(events: Recorder, node: int) -> int:
    return sum(1 for e in events.snapshot() if e.kind == "slave-started" and e.node_id == node)


def eventually(check, what: str, timeout: float = 5.0) -> None:
    """The listener and the event dispatcher deliver on their own threads:
    wait (scaled) until check() holds."""
    deadline = time.monotonic() + scaled(timeout)
    while not check():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.01)


def test_only_the_active_master_manages_the_network():
    channel = f"flyma-manager-{time.monotonic_ns()}"
    sniffer = Sniffer()
    notifier = can.Notifier(virtual_bus(channel), [sniffer])
    networks = []
    try:
        slaves_net = canopenfd.Network()
        networks.append(slaves_net)
        slaves = {n: slaves_net.open_line(bus=virtual_bus(channel), mode="classic")
                  .create_local_node(n, 50, od=demo_od("classic")) for n in SLAVES}
        candidates, events = {}, {}
        for node_id, priority in ((10, 1), (11, 0), (12, 1)):
            net = canopenfd.Network()
            networks.append(net)
            line = net.open_line(bus=virtual_bus(channel), mode="classic")
            node = line.create_local_node(node_id, heartbeat_ms=50,
                                          od=manager_od("classic", 0x01, {2: 0x05, 3: 0x05}))
            node.flying_master.start(priority, master_heartbeat=0.3, **TIMING)
            events[node_id] = Recorder()
            line.manager.add_callback(events[node_id])
            line.manager.start()          # runs only while this node is the active master
            candidates[node_id] = (net, node, line.manager)

        assert candidates[11][1].flying_master.wait_for("master", timeout=scaled(5)) == 11
        candidates[11][2].wait_started(scaled(10))
        for n, slave in slaves.items():
            slave.nmt.wait_for_state("OPERATIONAL", timeout=scaled(5))
        for loser in (10, 12):
            assert candidates[loser][1].flying_master.wait_for("slave", timeout=scaled(5)) == 11
            kinds = {e.kind for e in events[loser].snapshot()}
            assert "active" not in kinds and "boot" not in kinds and "slave-started" not in kinds
        # its callbacks run on the dispatcher thread, maybe after wait_started returned
        events[11].wait_for(lambda calls: "active" in {e.kind for e in calls}, 5,
                            "node 11's manager becoming active")
        # on the wire: each start of a slave is one the winner reported
        for n in SLAVES:   # optional slaves: started as each one booted
            events[11].wait_for(lambda calls, n=n: any(e.kind == "slave-started" and
                                                       e.node_id == n for e in calls), 10,
                                f"node 11 starting slave {n}")
            eventually(lambda n=n: sniffer.nmt_to(n).count(0x01) == started(events[11], n),
                       f"the NMT starts of node {n} on the wire")

        candidates[11][0].close()                 # the active master dies
        networks.remove(candidates[11][0])
        assert candidates[10][1].flying_master.wait_for("master", timeout=scaled(5)) == 10
        events[10].wait_for(lambda calls: any(e.kind == "network-started" for e in calls), 10,
                            "node 10's network start")
        for n in SLAVES:
            events[10].wait_for(lambda calls, n=n: any(e.kind == "slave-started" and
                                                       e.node_id == n for e in calls), 10,
                                f"node 10 starting slave {n}")
            slaves[n].nmt.wait_for_state("OPERATIONAL", timeout=scaled(5))
            eventually(lambda n=n: sniffer.nmt_to(n).count(0x01) ==
                       started(events[11], n) + started(events[10], n),
                       f"the NMT starts of node {n} on the wire")
        kinds = {e.kind for e in events[12].snapshot()}
        assert "active" not in kinds and "slave-started" not in kinds
        assert candidates[12][2].phase.name == "IDLE"
    finally:
        notifier.stop()
        for net in networks:
            net.close()
