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


# ------------------------------------------------------------------ no frame lost
# The receiving lines get a small rx queue, so every transfer below runs into a
# full queue many times: the host thread must wait (back-pressure into
# python-can's buffer), never drop.

_MIB = 1 << 20
_DOMAIN = 0x2100


class _Busy:
    """A Python thread that never blocks: it competes for the GIL with the
    bridge threads, like an application's own work."""

    def __init__(self, on):
        import threading
        self._on = on
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self):
        n = 0
        while not self._stop.is_set():
            for _ in range(1000):
                n += 1

    def __enter__(self):
        if self._on:
            self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        if self._on:
            self._thread.join()


def _pattern(size):
    return bytes((i * 7 + (i >> 8)) & 0xFF for i in range(size))


def _no_loss(*lines):
    for line in lines:
        stats = line.stats
        assert (stats["rx_overflow"], stats["tx_overflow"]) == (0, 0), line
    return sum(line.driver_stats["host_rx_waits"] for line in lines)


def _server(line, mode):
    from canopenfd.od import demo_od
    node = line.create_local_node(2, od=demo_od(mode), boot=False)
    node.serve_domain(_DOMAIN, 2 * _MIB)
    node.boot()
    return node


@pytest.mark.parametrize("busy", [False, True], ids=["idle", "busy-thread"])
def test_usdo_bulk_1mib_between_host_lines_loses_nothing(buses, networks, busy):
    net = networks()
    client = net.open_line(bus=buses(), mode="fd", rx_queue=32)
    server_line = net.open_line(bus=buses(), mode="fd", rx_queue=32)
    server = _server(server_line, "fd")
    data = _pattern(_MIB)
    with _Busy(busy):
        client.usdo.download(2, _DOMAIN, 0, data, mode="bulk", timeout=scaled(5))
    assert server[_DOMAIN].data == data
    assert _no_loss(client, server_line) > 0   # the small queue filled: back-pressure


@pytest.mark.parametrize("busy", [False, True], ids=["idle", "busy-thread"])
def test_sdo_block_256k_between_host_lines_loses_nothing(buses, networks, busy):
    net = networks()
    client = net.open_line(bus=buses(), mode="classic", rx_queue=32)
    server_line = net.open_line(bus=buses(), mode="classic", rx_queue=32)
    server = _server(server_line, "classic")
    data = _pattern(256 << 10)
    with _Busy(busy):
        client.sdo.download(2, _DOMAIN, 0, data, mode="block", timeout=scaled(5))
    assert server[_DOMAIN].data == data
    _no_loss(client, server_line)


def test_burst_larger_than_the_rx_queue_arrives_whole_and_in_order(buses):
    raw = buses()
    count = 3000
    with canopenfd.Network(event_capacity=2 * count) as net:
        line = net.open_line(bus=buses(), mode="classic", monitor=True, rx_queue=16)
        frames = Recorder()
        line.on_frame(frames)
        for i in range(count):   # sent before the line can drain: a burst
            raw.send(can.Message(arbitration_id=0x181, data=i.to_bytes(4, "little"),
                                 is_extended_id=False))
        got = frames.wait_count(count, timeout=scaled(20))
        received = [int.from_bytes(f.data, "little") for f in got if f.id == 0x181]
        assert received == list(range(count))
        assert (line.stats["rx_overflow"], net.events_lost) == (0, 0)
        assert line.driver_stats["host_rx_waits"] > 0
        drv = line.driver_stats
        assert drv["rx_frames"] == count
        assert drv["rx_calls"] < count // 2         # handed to C in batches


def test_close_ends_a_host_thread_blocked_on_a_full_rx_queue(buses):
    import threading
    import time

    raw = buses()
    net = canopenfd.Network()
    line = net.open_line(bus=buses(), mode="classic", monitor=True, rx_queue=2)
    stop = threading.Event()

    def flood():
        msg = can.Message(arbitration_id=0x181, data=b"\x01", is_extended_id=False)
        while not stop.is_set():
            for _ in range(500):
                raw.send(msg)
            time.sleep(0.001)

    flooder = threading.Thread(target=flood, daemon=True)
    flooder.start()
    try:
        deadline = time.monotonic() + scaled(10)
        while line.driver_stats["host_rx_waits"] < 5 and time.monotonic() < deadline:
            time.sleep(0.01)
        assert line.driver_stats["host_rx_waits"] >= 5   # it keeps running into a full queue
        start = time.monotonic()
        net.close()
        assert time.monotonic() - start < scaled(2)
    finally:
        stop.set()
        flooder.join()
    assert not [t for t in threading.enumerate()
                if t.name.startswith("canopenfd-host") and t.is_alive()]


def test_a_sender_faster_than_the_python_can_bus_is_refused_not_dropped(
        channel, buses):
    import threading

    from can.interfaces.virtual import VirtualBus

    from canopenfd.errors import CommandError

    class StalledBus(VirtualBus):
        """Its sends wait until the test opens the gate, so the line's sender
        outruns the bus on any machine, however fast."""

        gate = threading.Event()

        def send(self, msg, timeout=None):
            self.gate.wait(scaled(10))
            super().send(msg, timeout)

    raw = buses()
    stalled = StalledBus(channel=channel, receive_own_messages=False)
    net = canopenfd.Network()
    try:
        line = net.open_line(bus=stalled, mode="classic", tx_queue=32)
        count, refused, i = 6000, 0, 0
        while i < count:
            try:
                line.send_frame(0x181, i.to_bytes(4, "little"))
                i += 1
            except CommandError as exc:
                assert "python-can bus takes frames slower" in str(exc)
                refused += 1
                StalledBus.gate.set()       # the bus catches up from here on
        _expect_in_order(raw, count)
        assert line.stats["tx_overflow"] == 0
        assert refused > 0          # the line did push back
    finally:
        StalledBus.gate.set()
        net.close()
        stalled.shutdown()


def _expect_in_order(raw, count):
    got = []
    while len(got) < count:
        msg = raw.recv(scaled(5))
        assert msg is not None, f"{len(got)} of {count} frames arrived"
        got.append(int.from_bytes(msg.data, "little"))
    assert got == list(range(count))
