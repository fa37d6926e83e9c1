"""Flying master (CiA 302-2) through the Python API: three stack instances
(three Networks, each one local node) on one python-can virtual bus agree
on the active master; the frames are checked by a plain python-can
listener; the active master's network is closed and the two others
negotiate a new one. Also: detection of master-capable nodes, errors that
name the problem."""

from __future__ import annotations

import asyncio
import threading
import time
from typing import List

import pytest

import canopenfd
from canopenfd import ConfigurationError, FlymaEvent, FlymaNotice, FlymaState
from canopenfd.errors import CanopenFDError
from helpers import Recorder, scaled, virtual_bus

can = pytest.importorskip("can")

TIMING = dict(detect=0.05, delay=0.1, priority_slot=0.3, device_slot=0.005,
              multiple_master=2.0, capable=0.1)


class Sniffer(can.Listener):
    """Every frame on the virtual bus, with the time it was seen."""

    def __init__(self) -> None:
        self.frames: List[can.Message] = []
        self._lock = threading.Condition()

    def on_message_received(self, msg: can.Message) -> None:
        with self._lock:
            self.frames.append(msg)
            self._lock.notify_all()

    def wait(self, can_id: int, found, what: str, timeout: float = 5.0) -> List[bytes]:
        """The frames of can_id once found(frames) holds (the bus's notifier
        delivers after the stacks acted on a frame)."""
        deadline = time.monotonic() + scaled(timeout)
        with self._lock:
            while True:
                frames = [bytes(m.data) for m in self.frames if m.arbitration_id == can_id]
                if found(frames):
                    return frames
                left = deadline - time.monotonic()
                assert left > 0, f"timed out waiting for {what}: {frames[-5:]}"
                self._lock.wait(left)

    def of(self, can_id: int) -> List[bytes]:
        with self._lock:
            return [bytes(m.data) for m in self.frames if m.arbitration_id == can_id]


@pytest.fixture
def candidates():
    """Three networks on one virtual channel: nodes 10 (priority 1), 11
    (priority 0) and 12 (priority 1), heartbeat 50 ms, flying master started."""
    channel = f"flyma-{time.monotonic_ns()}"
    sniffer = Sniffer()
    notifier = can.Notifier(virtual_bus(channel), [sniffer])
    networks, nodes = [], []
    for node_id in (10, 11, 12):
        net = canopenfd.Network()
        networks.append(net)
        line = net.open_line(bus=virtual_bus(channel), mode="classic")
        nodes.append(line.create_local_node(node_id, heartbeat_ms=50))
    notices = [Recorder() for _ in nodes]
    for node, notice, priority in zip(nodes, notices, (1, 0, 1)):
        node.flying_master.add_callback(notice)
        node.flying_master.start(priority, master_heartbeat=0.3, **TIMING)
    yield networks, nodes, notices, sniffer
    notifier.stop()
    for net in networks:
        net.close()


def test_three_instances_agree_then_survive_the_master(candidates):
    networks, nodes, notices, sniffer = candidates
    assert nodes[1].flying_master.wait_for("master", timeout=scaled(5)) == 11
    for i in (0, 2):
        assert nodes[i].flying_master.wait_for("slave", timeout=scaled(5)) == 11
        assert nodes[i].flying_master.active_master == 11
    assert nodes[1].flying_master.is_master
    # on the wire: the detection requests (no data), the power-on network
    # reset, a negotiation request and node 11's announcement [priority, id]
    # (the sniffer and the notice callbacks hear them after the stacks acted: wait)
    sniffer.wait(0x73, lambda frames: b"" in frames, "a detection request")
    sniffer.wait(0x000, lambda frames: bytes([0x82, 0x00]) in frames, "the network reset")
    assert set(sniffer.wait(0x72, bool, "a negotiation request")) == {b""}
    assert sniffer.wait(0x71, bool, "node 11's announcement")[0] == bytes([0x00, 11])
    slave = FlymaNotice(FlymaEvent.STATE, FlymaState.SLAVE, 11, 0)
    told = notices[0].wait_for(lambda calls: calls and calls[-1] == slave and list(calls),
                               5, "node 10's notice that it is a slave of 11")
    assert any(n.event == FlymaEvent.RESET_ALL for n in told)
    assert told[-1] == slave

    mark = len(sniffer.of(0x000))
    networks[1].close()                       # the active master dies
    assert nodes[0].flying_master.wait_for("master", timeout=scaled(5)) == 10
    assert nodes[2].flying_master.wait_for("slave", timeout=scaled(5)) == 10
    sniffer.wait(0x000, lambda frames: bytes([0x82, 0x00]) in frames[mark:],
                 "the network reset")
    sniffer.wait(0x71, lambda frames: frames and frames[-1] == bytes([0x01, 10]),
                 "node 10's announcement")
    assert nodes[2].flying_master.stats["rx_bad_length"] == 0


def assert_capable_frames(sniffer: Sniffer) -> None:
    """One detection request, two answers (the sniffer may hear the answers
    after the detecting node counted them: wait for both)."""
    assert sniffer.wait(0x75, bool, "the detection request") == [b""]
    assert sniffer.wait(0x74, lambda frames: len(frames) >= 2, "two answers") == [b"", b""]


def test_detect_capable_counts_the_others(candidates):
    _, nodes, _, sniffer = candidates
    nodes[1].flying_master.wait_for("master", timeout=scaled(5))
    assert nodes[0].flying_master.detect_capable(timeout=scaled(2)) == 2
    assert_capable_frames(sniffer)


def test_detect_capable_and_wait_for_awaited(candidates):
    _, nodes, _, sniffer = candidates

    async def main():
        master = await nodes[1].flying_master.await_for("master", timeout=scaled(5))
        assert master == nodes[1].node_id
        return await nodes[0].flying_master.adetect_capable(timeout=scaled(2))
    assert asyncio.run(main()) == 2
    assert_capable_frames(sniffer)


def test_wrong_use_names_the_problem(net, bus_name):
    line = net.open_line(bus_name, mode="classic")
    node = line.create_local_node(3, boot=False)
    with pytest.raises(ConfigurationError, match="priority must be 0..255"):
        node.flying_master.start(300)
    with pytest.raises(ConfigurationError, match="unknown timing"):
        node.flying_master.start(1, slot=1)
    with pytest.raises(ConfigurationError, match="delay must be 0.001..65.535 s"):
        node.flying_master.start(1, delay=0)
    with pytest.raises(CanopenFDError, match="no local node|not started"):
        node.flying_master.force()
    node.boot()
    node.flying_master.start(1, **TIMING)
    with pytest.raises(CanopenFDError, match="runs on this line already"):
        node.flying_master.start(1)
    with pytest.raises(ConfigurationError, match="state must be one of"):
        node.flying_master.wait_for("boss")
    # alone on the bus it becomes the master after its own slot
    assert node.flying_master.wait_for("master", timeout=scaled(5)) == 3
    node.flying_master.stop()
    assert node.flying_master.state == FlymaState.IDLE
