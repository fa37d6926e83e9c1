"""Lines over python-can buses (the host driver), with python-can's `virtual`
interface: two networks talk through two bus objects on one virtual channel."""

from __future__ import annotations

import itertools

import pytest
from helpers import Recorder, scaled

import canopenfd
from canopenfd import NmtState

can = pytest.importorskip("can")

_channels = itertools.count(1)


@pytest.fixture
def channel(request):
    return f"canopenfd-{request.node.name[:30]}-{next(_channels)}"


@pytest.fixture
def buses(channel):
    """A factory of virtual buses on one channel; all shut down at the end."""
    made = []

    def make():
        bus = can.Bus(interface="virtual", channel=channel, receive_own_messages=False)
        made.append(bus)
        return bus

    yield make
    for bus in made:
        bus.shutdown()


@pytest.fixture
def networks():
    made = []

    def make():
        made.append(canopenfd.Network())
        return made[-1]

    yield make
    for net in made:
        net.close()


@pytest.mark.parametrize("mode", ["fd", "classic"])
def test_nmt_and_heartbeat_between_two_host_lines(buses, networks, mode):
    manager = networks().open_line(bus=buses(), mode=mode)
    device_line = networks().open_line(bus=buses(), mode=mode)
    manager.create_local_node(1)
    remote = manager.add_node(5, heartbeat_timeout_ms=200)
    bootups, started, lost = Recorder(), Recorder(), Recorder()
    remote.on_bootup(bootups)
    remote.on_heartbeat_started(started)
    remote.on_heartbeat_lost(lost)

    device = device_line.create_local_node(5, heartbeat_ms=40)
    bootups.wait_count(1)
    started.wait_count(1)
    manager.nmt.start(5)
    device.wait_for_state(NmtState.OPERATIONAL, timeout=scaled(5))
    remote.wait_for_state(NmtState.OPERATIONAL, timeout=scaled(5))
    manager.nmt.stop("all")
    remote.wait_for_state(NmtState.STOPPED, timeout=scaled(5))
    assert manager.states == {1: NmtState.PRE_OPERATIONAL, 5: NmtState.STOPPED}

    device.heartbeat_ms = 0
    lost.wait_count(1)
    assert device_line.stats["tx_frames"] >= 4
    assert manager.stats["rx_frames"] >= 4


def test_exact_bytes_on_a_raw_python_can_bus(buses, networks):
    raw = buses()
    line = networks().open_line(bus=buses(), mode="fd", brs=True)
    line.create_local_node(5, heartbeat_ms=50)
    boot = raw.recv(scaled(5))
    assert boot is not None
    assert (boot.arbitration_id, bytes(boot.data), boot.dlc, boot.is_fd, boot.bitrate_switch,
            boot.is_extended_id, boot.is_remote_frame) == (0x705, b"\x00", 1, True, True,
                                                          False, False)
    heartbeat = raw.recv(scaled(5))
    assert (heartbeat.arbitration_id, bytes(heartbeat.data), heartbeat.is_fd) == (
        0x705, b"\x7f", True)
    line.nmt.reset_communication("all")
    for _ in range(50):
        msg = raw.recv(scaled(5))
        if msg.arbitration_id == 0:
            break
    assert (bytes(msg.data), msg.dlc, msg.is_fd, msg.bitrate_switch) == (b"\x82\x00", 2, True,
                                                                         True)
    line.send_frame(0x181, bytes(range(10)))                  # padded to 12 on FD
    for _ in range(50):
        msg = raw.recv(scaled(5))
        if msg.arbitration_id == 0x181:
            break
    assert (bytes(msg.data), msg.dlc) == (bytes(range(10)) + b"\0\0", 12)


def test_classic_line_sends_classic_frames(buses, networks):
    raw = buses()
    line = networks().open_line(bus=buses(), mode="classic")
    line.create_local_node(9)
    boot = raw.recv(scaled(5))
    assert (boot.arbitration_id, bytes(boot.data), boot.is_fd, boot.bitrate_switch) == (
        0x709, b"\x00", False, False)


def test_frames_from_python_can_drive_our_node(buses, networks):
    raw = buses()
    line = networks().open_line(bus=buses(), mode="classic")
    node = line.create_local_node(9)
    watched = line.add_node(20)
    node.wait_for_state(NmtState.PRE_OPERATIONAL, timeout=scaled(5))
    raw.send(can.Message(arbitration_id=0, data=[1, 9], is_extended_id=False))
    node.wait_for_state(NmtState.OPERATIONAL, timeout=scaled(5))
    # Malformed frames from outside are counted; a good heartbeat follows as sentinel.
    raw.send(can.Message(arbitration_id=0, data=[1, 9, 0], is_extended_id=False))
    raw.send(can.Message(arbitration_id=0x714, data=[5, 0], is_extended_id=False))
    raw.send(can.Message(arbitration_id=0x714, data=[0x42], is_extended_id=False))
    raw.send(can.Message(arbitration_id=0x714, data=[0x04], is_extended_id=False))
    watched.wait_for_state(NmtState.STOPPED, timeout=scaled(5))
    stats = line.stats
    assert (stats["nmt_bad_length"], stats["hb_bad_length"], stats["hb_bad_state"]) == (1, 1, 1)
    # An FD frame on a classic line is counted, not processed.
    raw.send(can.Message(arbitration_id=0, data=[2, 9], is_extended_id=False, is_fd=True))
    raw.send(can.Message(arbitration_id=0x714, data=[0x05], is_extended_id=False))
    watched.wait_for_state(NmtState.OPERATIONAL, timeout=scaled(5))
    assert line.stats["rx_wrong_format"] == 1
    assert node.state == NmtState.OPERATIONAL


def test_monitor_on_a_host_line(buses, networks):
    raw = buses()
    monitor = networks().open_line(bus=buses(), monitor=True)
    frames = Recorder()
    monitor.on_frame(frames)
    raw.send(can.Message(arbitration_id=0x705, data=[0x05], is_extended_id=False, is_fd=True,
                         bitrate_switch=True))
    monitor.send_frame(0x706, b"\x7f")
    got = frames.wait_count(2)
    by_id = {f.id: f for f in got}
    assert (by_id[0x705].data, by_id[0x705].fd, by_id[0x705].tx) == (b"\x05", True, False)
    assert (by_id[0x706].data, by_id[0x706].tx) == (b"\x7f", True)


def test_close_stops_the_bridge_threads(buses):
    import threading

    net = canopenfd.Network()
    net.open_line(bus=buses()).create_local_node(3, heartbeat_ms=10)
    net.close()
    assert not [t for t in threading.enumerate()
                if t.name.startswith("canopenfd-host") and t.is_alive()]
