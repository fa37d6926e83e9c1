"""The stack on real kernel SocketCAN (vcan). Needs CANOPENFD_VCAN, e.g.
"vcan0,vcan1,vcan2" with vcan0/vcan1 at MTU 72 (CAN FD) and vcan2 at MTU 16
(classic); tests/vm/run_in_vm.sh provides them on kernels without CAN."""

from __future__ import annotations

import subprocess

import pytest
from helpers import NEUTRAL_CWD, Recorder, cli_command, package_env, run_cli, scaled

import canopenfd
from canopenfd import CommEvent, InterfaceError, NmtState

pytestmark = pytest.mark.vcan
can = pytest.importorskip("can")



@pytest.fixture
def ifaces(vcan):
    return {"fd": vcan[0], "fd2": vcan[1], "classic": vcan[2]}


@pytest.fixture
def networks():
    made = []

    def make():
        made.append(canopenfd.Network())
        return made[-1]

    yield make
    for net in made:
        net.close()


@pytest.fixture
def raw_buses():
    made = []

    def make(channel, fd=True):
        bus = can.Bus(interface="socketcan", channel=channel, fd=fd)
        made.append(bus)
        return bus

    yield make
    for bus in made:
        bus.shutdown()


def recv_until(bus, predicate, timeout=5.0):
    """The first message on a raw python-can bus matching predicate."""
    import time

    deadline = time.monotonic() + scaled(timeout)
    while time.monotonic() < deadline:
        msg = bus.recv(max(0.01, deadline - time.monotonic()))
        if msg is not None and not msg.is_error_frame and predicate(msg):
            return msg
    raise AssertionError(f"no matching frame within {scaled(timeout):g} s")


cli = run_cli


# ------------------------------------------------------------------ two networks
def test_two_fd_lines_see_each_other(ifaces, networks):
    manager = networks().open_line(ifaces["fd"], mode="fd")
    device_line = networks().open_line(ifaces["fd"], mode="fd")
    manager.create_local_node(1, heartbeat_ms=100)
    remote = manager.add_node(5, heartbeat_timeout_ms=300)
    bootups, started, lost = Recorder(), Recorder(), Recorder()
    remote.on_bootup(bootups)
    remote.on_heartbeat_started(started)
    remote.on_heartbeat_lost(lost)
    back = device_line.add_node(1)

    device = device_line.create_local_node(5, heartbeat_ms=50)
    bootups.wait_count(1, timeout=10)
    started.wait_count(1, timeout=10)
    back.wait_for_heartbeat(timeout=scaled(10))
    assert manager.states == {1: NmtState.PRE_OPERATIONAL, 5: NmtState.PRE_OPERATIONAL}
    assert device_line.states == {1: NmtState.PRE_OPERATIONAL, 5: NmtState.PRE_OPERATIONAL}

    manager.nmt.start(5)
    device.wait_for_state(NmtState.OPERATIONAL, timeout=scaled(10))
    remote.wait_for_state(NmtState.OPERATIONAL, timeout=scaled(10))
    manager.nmt.stop("all", include_self=True)
    remote.wait_for_state(NmtState.STOPPED, timeout=scaled(10))
    back.wait_for_state(NmtState.STOPPED, timeout=scaled(10))
    manager.nmt.reset_node(5)
    bootups.wait_count(2, timeout=10)
    device.wait_for_state(NmtState.PRE_OPERATIONAL, timeout=scaled(10))
    started.wait_count(2, timeout=10)      # after a boot-up, monitoring restarts here

    device.heartbeat_ms = 0
    lost.wait_count(1, timeout=10)
    assert manager.stats["rx_frames"] > 3 and device_line.stats["tx_frames"] > 3


@pytest.mark.parametrize("brs", [True, False])
def test_exact_bytes_on_the_wire(ifaces, networks, raw_buses, brs):
    raw = raw_buses(ifaces["fd"])
    line = networks().open_line(ifaces["fd"], mode="fd", brs=brs)
    line.create_local_node(5, heartbeat_ms=100)
    boot = recv_until(raw, lambda m: m.arbitration_id == 0x705)
    assert (bytes(boot.data), boot.dlc, boot.is_fd, boot.bitrate_switch, boot.is_extended_id,
            boot.is_remote_frame) == (b"\x00", 1, True, brs, False, False)
    beat = recv_until(raw, lambda m: m.arbitration_id == 0x705)
    assert (bytes(beat.data), beat.dlc, beat.is_fd, beat.bitrate_switch) == (b"\x7f", 1, True,
                                                                           brs)
    line.nmt.start("all")
    nmt = recv_until(raw, lambda m: m.arbitration_id == 0)
    assert (bytes(nmt.data), nmt.dlc, nmt.is_fd, nmt.bitrate_switch) == (b"\x01\x00", 2, True,
                                                                        brs)
    line.send_frame(0x181, bytes(range(1, 11)))
    pdo = recv_until(raw, lambda m: m.arbitration_id == 0x181)
    assert (bytes(pdo.data), pdo.dlc, pdo.is_fd) == (bytes(range(1, 11)) + b"\0\0", 12, True)


def test_usdo_expedited_upload_and_download_on_the_wire(ifaces, networks, raw_buses):
    """A raw python-can socket plays the USDO client (node 2) of our node 5."""
    from canopenfd.od import demo_od
    raw = raw_buses(ifaces["fd"])
    node = networks().open_line(ifaces["fd"], mode="fd").create_local_node(5, od=demo_od("fd"))
    node[0x1017].raw = 0x1234
    request = can.Message(arbitration_id=0x602, is_extended_id=False, is_fd=True,
                          bitrate_switch=True, data=bytes([5, 0x11, 7, 0x00, 0x17, 0x10]))
    raw.send(request)
    answer = recv_until(raw, lambda m: m.arbitration_id == 0x585)
    assert (answer.is_fd, answer.bitrate_switch, answer.dlc) == (True, True, 12)
    assert bytes(answer.data) == bytes([2, 0x31, 7, 0x00, 0x17, 0x10, 0x06, 2, 0x34, 0x12, 0, 0])
    write = bytes([5, 0x01, 8, 0x00, 0x17, 0x10, 0x06, 2, 0x2C, 0x01])
    raw.send(can.Message(arbitration_id=0x602, is_extended_id=False, is_fd=True,
                         bitrate_switch=True, data=write + b"\0\0"))
    answer = recv_until(raw, lambda m: m.arbitration_id == 0x585)
    assert bytes(answer.data) == bytes([2, 0x21, 8, 0x00, 0x17, 0x10])
    assert node.heartbeat_ms == 300


def _usdo_device(networks, iface, node_id=5, domain=16 << 20):
    from canopenfd.od import demo_od
    node = networks().open_line(iface, mode="fd").create_local_node(node_id, od=demo_od("fd"),
                                                                    boot=False)
    if domain:
        node.serve_domain(0x2100, domain)
    node.boot()
    return node


def test_usdo_client_frames_on_the_wire(ifaces, networks, raw_buses):
    """Our client (node 2) and our server (node 5) on vcan, every request the
    client puts on the wire captured by a raw socket and checked byte for byte."""
    raw = raw_buses(ifaces["fd"])
    device = _usdo_device(networks, ifaces["fd"])
    line = networks().open_line(ifaces["fd"], mode="fd")
    line.usdo.client_id = 2
    device[0x1017].raw = 0x1234
    assert line.usdo.upload(5, 0x1017, timeout=scaled(1)) == b"\x34\x12"
    seen = []   # both frames, whichever order the capturing socket sees them in
    recv_until(raw, lambda m: seen.append(m) or {f.arbitration_id for f in seen} >= {0x602,
                                                                                   0x585})
    request = next(m for m in seen if m.arbitration_id == 0x602)
    answer = next(m for m in seen if m.arbitration_id == 0x585)
    sid = request.data[2]
    assert (request.is_fd, request.bitrate_switch) == (True, True)
    assert bytes(request.data[:6]) == bytes([5, 0x11, sid, 0x00, 0x17, 0x10])
    assert bytes(answer.data[:10]) == bytes([2, 0x31, sid, 0, 0x17, 0x10, 0x06, 2, 0x34, 0x12])

    for size, first_cs, segment_cs, last_cs in ((1000, 0x02, 0x03, 0x04),
                                                (6010, 0x06, 0x07, 0x08)):
        data = bytes((i * 7) & 0xFF for i in range(size))
        transfer = line.usdo.start_download(5, 0x2100, 0, data, timeout=scaled(1))
        transfer.result()
        initiate = recv_until(raw, lambda m: m.arbitration_id == 0x602 and m.data[1] == first_cs)
        sid = initiate.data[2]
        assert bytes(initiate.data[:12]) == bytes([5, first_cs, sid, 0, 0x00, 0x21, 0x0F, 0]) + \
            size.to_bytes(4, "little")
        for number in range(size // 60):
            segment = recv_until(raw, lambda m: m.arbitration_id == 0x602)
            assert (segment.dlc, bytes(segment.data[:4])) == (64, bytes([5, segment_cs, sid,
                                                                         number & 0xFF]))
            assert bytes(segment.data[4:]) == data[number * 60:(number + 1) * 60]
        last = recv_until(raw, lambda m: m.arbitration_id == 0x602)
        rest = size % 60
        assert bytes(last.data[:4 + rest]) == bytes([5, last_cs, sid, rest]) + data[-rest:]
        assert device[0x2100].data == data

    # segmented upload of the last 6010 bytes: 0x11, the server's 0x32 with the size,
    # then 0x13 requests (counter from 0) answered by 0x33 segments and a last 0x34.
    # Each sender's frames are checked in their own order: the capturing socket may
    # see the two senders' frames interleaved differently (per-CPU loopback queues).
    assert line.usdo.upload(5, 0x2100, timeout=scaled(1)) == data
    seen = []
    recv_until(raw, lambda m: seen.append(m) or (m.arbitration_id == 0x585 and m.data[1] == 0x34))
    requests = [bytes(m.data) for m in seen if m.arbitration_id == 0x602]
    answers = [bytes(m.data) for m in seen if m.arbitration_id == 0x585]
    upload = next(i for i, r in enumerate(requests) if r[1] == 0x11)
    sid = requests[upload][2]
    asks = [r for r in requests[upload + 1:] if r[2] == sid]
    assert [r[:4] for r in asks] == [bytes([5, 0x13, sid, n & 0xFF])
                                     for n in range(len(data) // 60 + 1)]
    mine = [a for a in answers if a[2] == sid]
    assert mine[0][:12] == bytes([2, 0x32, sid, 0, 0x00, 0x21, 0x0F, 0]) + \
        len(data).to_bytes(4, "little")
    for number, segment in enumerate(mine[1:-1]):
        assert segment[:4] == bytes([2, 0x33, sid, number & 0xFF])
        assert segment[4:] == data[number * 60:(number + 1) * 60]
    rest = len(data) % 60
    assert mine[-1][:4 + rest] == bytes([2, 0x34, sid, rest]) + data[-rest:]


def test_usdo_large_transfers_over_vcan(ifaces, networks):
    """1 MiB bulk download, then a segmented upload back (128 KiB: in the
    emulated VM every segment round trip costs two thread wake-ups, ~2 ms;
    1 MiB both ways runs over the in-process bus in test_usdo_client.py)."""
    import os
    device = _usdo_device(networks, ifaces["fd"])
    line = networks().open_line(ifaces["fd"], mode="fd")
    data = os.urandom(1 << 20)
    transfer = line.usdo.start_download(5, 0x2100, 0, data, timeout=scaled(1))
    transfer.result()
    assert transfer.mode == "bulk" and device[0x2100].data == data
    device[0x2100].data = data[:128 << 10]
    back = line.usdo.start_upload(5, 0x2100, 0, timeout=scaled(1))
    assert back.result() == data[:128 << 10] and back.mode == "segmented"


def test_driver_stats_count_the_socket_io(ifaces, networks):
    """line.driver_stats: every frame of a bulk download written and read
    through the socket, in batched calls, none lost by the kernel."""
    import os
    device = _usdo_device(networks, ifaces["fd"])
    line = networks().open_line(ifaces["fd"], mode="fd")
    before = line.driver_stats
    data = os.urandom(64 << 10)
    line.usdo.start_download(5, 0x2100, 0, data, mode="bulk", timeout=scaled(1)).result()
    assert device[0x2100].data == data
    sent, heard = line.driver_stats, device.line.driver_stats
    segments = -(-len(data) // 60)
    assert sent["tx_frames"] - before["tx_frames"] >= segments
    assert 0 < sent["tx_calls"] - before["tx_calls"] <= sent["tx_frames"] - before["tx_frames"]
    assert heard["rx_frames"] >= segments and 0 < heard["rx_calls"] <= heard["rx_frames"]
    assert sent["loop_wakeups"] > before["loop_wakeups"]
    assert sent["kernel_drops"] == heard["kernel_drops"] == 0
    assert sent["tx_refused"] == heard["tx_refused"] == 0


def test_usdo_broadcast_over_vcan(ifaces, networks):
    for node_id in (3, 4, 6):
        _usdo_device(networks, ifaces["fd"], node_id, domain=0)[0x1017].raw = node_id
    line = networks().open_line(ifaces["fd"], mode="fd")
    answers = line.usdo.broadcast_upload(0x1017, window=scaled(0.5))
    assert answers == {3: b"\x03\x00", 4: b"\x04\x00", 6: b"\x06\x00"}


# ------------------------------------------------------------------ interface errors
def test_fd_line_on_classic_mtu_raises(ifaces, networks):
    net = networks()
    with pytest.raises(InterfaceError, match="MTU") as info:
        net.open_line(ifaces["classic"], mode="fd")
    assert ifaces["classic"] in str(info.value)


def test_unknown_interface_raises(networks):
    with pytest.raises(InterfaceError, match="vcan97.*no such interface"):
        networks().open_line("vcan97", mode="fd")


def test_classic_line_on_classic_mtu(ifaces, networks, raw_buses):
    raw = raw_buses(ifaces["classic"], fd=False)
    watcher = networks().open_line(ifaces["classic"], mode="classic")
    remote = watcher.add_node(9)
    bootups = Recorder()
    remote.on_bootup(bootups)
    line = networks().open_line(ifaces["classic"], mode="classic")
    node = line.create_local_node(9, heartbeat_ms=50)
    bootups.wait_count(1, timeout=10)
    boot = recv_until(raw, lambda m: m.arbitration_id == 0x709)
    assert (bytes(boot.data), boot.is_fd, boot.bitrate_switch) == (b"\x00", False, False)
    watcher.nmt.start(9)
    node.wait_for_state(NmtState.OPERATIONAL, timeout=scaled(10))
    nmt = recv_until(raw, lambda m: m.arbitration_id == 0)
    assert (bytes(nmt.data), nmt.is_fd) == (b"\x01\x09", False)


# ------------------------------------------------------------------ CLI
def test_cli_nmt_and_monitor(ifaces, raw_buses):
    raw = raw_buses(ifaces["fd"])
    monitor = subprocess.Popen(
        cli_command("monitor", "--channel", ifaces["fd"], "--count", "2",
                    "--duration", str(scaled(60))),
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=NEUTRAL_CWD,
        env=package_env())
    try:
        banner = monitor.stderr.readline()         # printed once the line is open
        assert "monitoring" in banner, banner
        result = cli("nmt", "start", "5", "--channel", ifaces["fd"])
        assert result.returncode == 0, result.stderr
        assert f"sent NMT start to node 5 on {ifaces['fd']} (fd)" in result.stdout
        sent = recv_until(raw, lambda m: m.arbitration_id == 0)
        assert (bytes(sent.data), sent.is_fd, sent.bitrate_switch) == (b"\x01\x05", True, True)
        raw.send(can.Message(arbitration_id=0x705, data=b"\x05", is_extended_id=False,
                             is_fd=True, bitrate_switch=False))
        out, err = monitor.communicate(timeout=scaled(60))
    finally:
        if monitor.poll() is None:
            monitor.kill()
            monitor.wait()
    assert monitor.returncode == 0, err
    lines = out.strip().splitlines()
    assert len(lines) == 2, out
    assert lines[0].split()[1:] == ["RX", "0x000", "[2]", "01", "05", "NMT", "start", "node",
                                    "5", "[FD", "BRS]"]
    assert lines[1].split()[1:] == ["RX", "0x705", "[1]", "05", "heartbeat", "node", "5",
                                    "OPERATIONAL", "[FD]"]


def test_cli_errors_on_vcan(ifaces):
    result = cli("monitor", "--channel", ifaces["classic"], "--duration", "0.1")
    assert result.returncode == 2 and "MTU" in result.stderr and "Traceback" not in result.stderr
    result = cli("monitor", "--channel", ifaces["classic"], "--classic", "--duration", "0.1")
    assert result.returncode == 0, result.stderr


# ------------------------------------------------------------------ malformed input
def test_malformed_frames_from_outside_are_counted(ifaces, networks, raw_buses):
    raw = raw_buses(ifaces["fd"])
    line = networks().open_line(ifaces["fd"], mode="fd")
    node = line.create_local_node(5)
    sentinel = line.add_node(10)
    node.wait_for_state(NmtState.PRE_OPERATIONAL, timeout=scaled(10))
    before = line.stats

    def send(can_id, data, fd=True):
        raw.send(can.Message(arbitration_id=can_id, data=data, is_extended_id=False, is_fd=fd,
                             bitrate_switch=fd))

    send(0x000, b"\x01")                 # NMT, 1 byte
    send(0x000, b"\x01\x05\x00")         # NMT, 3 bytes
    send(0x000, b"\x55\x05")             # unknown command
    send(0x000, b"\x01\xc8")             # node-id 200
    send(0x709, b"\x05\x00")             # heartbeat of 2 bytes
    send(0x709, b"\x33")                 # invalid state byte
    send(0x000, b"\x01\x05\x00", fd=False)   # classic frame, still 3 bytes
    send(0x70A, b"\x05")                 # sentinel
    sentinel.wait_for_state(NmtState.OPERATIONAL, timeout=scaled(10))
    after = line.stats
    delta = {k: after[k] - before[k] for k in after}
    assert (delta["nmt_bad_length"], delta["nmt_bad_command"], delta["nmt_bad_node"],
            delta["hb_bad_length"], delta["hb_bad_state"]) == (3, 1, 1, 1, 1)
    assert node.state == NmtState.PRE_OPERATIONAL
    assert 9 not in line.states


# ------------------------------------------------------------------ interface down/up
def test_interface_down_and_up(ifaces, networks):
    iface = ifaces["fd2"]
    device_line = networks().open_line(iface, mode="fd")
    watcher = networks().open_line(iface, mode="fd")
    events = Recorder()
    device_line.on_comm_event(events)
    remote = watcher.add_node(5, heartbeat_timeout_ms=300)
    started = Recorder()
    remote.on_heartbeat_started(started)
    device_line.create_local_node(5, heartbeat_ms=50)
    started.wait_count(1, timeout=10)

    def ip(state):
        subprocess.run(["ip", "link", "set", iface, state], check=True, timeout=scaled(30))

    ip("down")
    try:
        events.wait_value(CommEvent.IFACE_DOWN, timeout=10)
    finally:
        ip("up")
    up_at = events.wait_value(CommEvent.IFACE_UP, timeout=10)
    assert up_at > events.snapshot().index(CommEvent.IFACE_DOWN)
    assert CommEvent.IFACE_UP in device_line.comm_events
    started.wait_count(2, timeout=10)              # heartbeats flow again
    remote.wait_for_heartbeat(timeout=scaled(10))


def test_interface_down_up_storm_during_transfers(ifaces, networks):
    """20 down/up cycles of the interface while a USDO client loops transfers
    and the device sends heartbeats: nothing hangs or crashes, every transfer
    ends (done or failed with an error), and afterwards the line works again
    with no descriptor left behind."""
    import os
    import threading
    import time

    from canopenfd.errors import CanopenFDError
    from canopenfd.od import demo_od
    iface = ifaces["fd2"]
    fds_before = len(os.listdir("/proc/self/fd"))
    storm_nets = [networks() for _ in range(2)]
    device = storm_nets[0].open_line(iface, mode="fd").create_local_node(
        5, od=demo_od("fd"), boot=False, heartbeat_ms=50)
    device.serve_domain(0x2100, 1 << 20)
    device.boot()
    data = os.urandom(64 << 10)
    device[0x2100].data = data
    line = storm_nets[1].open_line(iface, mode="fd")
    events = Recorder()
    line.on_comm_event(events)
    remote = line.add_node(5, heartbeat_timeout_ms=500)
    outcomes = {"done": 0, "failed": 0}
    stop = threading.Event()

    def transfers():
        while not stop.is_set():
            try:
                assert line.usdo.upload(5, 0x2100, timeout=scaled(0.5)) == data
                outcomes["done"] += 1
            except (CanopenFDError, TimeoutError):   # timed out or aborted by the storm
                outcomes["failed"] += 1

    def ip(state):
        subprocess.run(["ip", "link", "set", iface, state], check=True, timeout=scaled(30))

    worker = threading.Thread(target=transfers)
    worker.start()
    try:
        for _ in range(20):
            ip("down")
            time.sleep(0.02)
            ip("up")
            time.sleep(0.05)
    finally:
        ip("up")
        stop.set()
        worker.join(scaled(30))
    assert not worker.is_alive(), "a transfer never ended"
    events.wait_value(CommEvent.IFACE_DOWN, timeout=10)     # (told on the dispatcher thread)
    assert CommEvent.IFACE_DOWN in events.snapshot()
    events.wait_value(CommEvent.IFACE_UP, timeout=scaled(10))
    assert line.driver_stats["iface_down"] >= 1
    try:
        remote.wait_for_heartbeat(timeout=scaled(10))       # heartbeats flow again
    except TimeoutError as exc:
        raise AssertionError(
            f"{exc}; device line: {device.line.driver_stats} {device.line.stats} "
            f"{device.line.comm_events[-6:]}; watcher: {line.driver_stats} {line.stats} "
            f"{line.comm_events[-6:]}") from None
    assert line.usdo.upload(5, 0x2100, timeout=scaled(2)) == data
    for net in storm_nets:
        net.close()
    assert len(os.listdir("/proc/self/fd")) == fds_before    # no socket or eventfd left open
    assert outcomes["done"] + outcomes["failed"] >= 1
