"""Bus redundancy on real kernel SocketCAN: two FD vcan interfaces (A =
vcan0, the lines' own, B = vcan1), each watched by its own monitor line: the
redundancy master moves to B, the slave misses its heartbeat on A and follows
after Ttoggle periods; only the interface in use carries the slave's frames.
Needs CANOPENFD_VCAN (see tests/test_vcan.py); tests/vm/run_in_vm.sh gives it."""

from __future__ import annotations

import time

import pytest

import canopenfd
from canopenfd import CanopenFDError, RedundancyEvent, RedundancyNotice
from helpers import Recorder, scaled

pytestmark = pytest.mark.vcan

PERIOD_S = 0.2


@pytest.fixture
def net():
    network = canopenfd.Network()
    yield network
    network.close()


def _heartbeats(frames, node_id, start=0):
    return [bytes(f.data) for f in frames.snapshot()[start:] if f.id == 0x700 + node_id]


def test_slave_follows_the_master_to_the_other_interface(net, vcan):
    a, b = vcan[0], vcan[1]
    on_a, on_b = Recorder(), Recorder()
    net.open_line(a, mode="fd", monitor=True).on_frame(on_a)
    net.open_line(b, mode="fd", monitor=True).on_frame(on_b)
    master = net.open_line(a, mode="fd")
    master.create_local_node(1, heartbeat_ms=50)
    master.redundancy.start(b, "master")
    slave = net.open_line(a, mode="fd")
    slave.create_local_node(2, heartbeat_ms=50)
    notices = Recorder()
    slave.redundancy.add_callback(notices)
    slave.redundancy.start(b, "slave", master=1, period=PERIOD_S, ttoggle=3, ntoggle=4)

    on_a.wait_for(lambda c: len([f for f in c if f.id == 0x702]) >= 3, scaled(3), "0x702 on A")
    assert _heartbeats(on_a, 2)[-1] == b"\x7f"
    time.sleep(scaled(0.9))
    assert notices.snapshot() == []
    assert _heartbeats(on_b, 2) == [] and _heartbeats(on_b, 1) == []

    moved = time.monotonic()
    master.redundancy.select("B")
    assert slave.redundancy.wait_for_bus("B", timeout=scaled(5)) == "B"
    assert time.monotonic() - moved >= 3 * PERIOD_S * 0.9
    # the notice runs on the dispatcher thread, maybe after wait_for_bus returned
    notices.wait_count(1, scaled(3))
    assert notices.snapshot()[0] == RedundancyNotice(RedundancyEvent.BUS_SWITCH, "B", 1)
    mark_a = len(on_a)
    on_b.wait_for(lambda c: len([f for f in c if f.id == 0x702]) >= 3, scaled(3), "0x702 on B")
    # the master's heartbeats are another sender's: wait for them too
    on_b.wait_for(lambda c: [f for f in c if f.id == 0x701], scaled(3), "0x701 on B")
    assert set(_heartbeats(on_b, 2)) == {b"\x7f"} and set(_heartbeats(on_b, 1)) == {b"\x7f"}
    time.sleep(scaled(0.9))
    assert len(notices) == 1 and slave.redundancy.object["Ctoggle"] == 0
    assert _heartbeats(on_a, 2, mark_a) == [] and _heartbeats(on_a, 1, mark_a) == []


def test_missing_redundant_interface_is_named(net, vcan):
    line = net.open_line(vcan[0], mode="fd")
    with pytest.raises(CanopenFDError, match="nosuchcan9"):
        line.redundancy.start("nosuchcan9", "master")
    with pytest.raises(CanopenFDError, match="must be an interface name"):
        line.redundancy.start("mem:x", "master")
