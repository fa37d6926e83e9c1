"""The seed 001 remote-access gateway over a pty (and TCP, and pyserial on the
pty's path), serving `mem:` lines: every command byte for byte (frames built
and checked here with an independent bitwise CRC), what reaches the bus
(NMT, SDO bytes), indications, bad frames counted with the next one served,
and the minimal-manager automation seen on the bus."""

from __future__ import annotations

import os
import queue
import threading
import time
import tty
from typing import Any, Iterator, List, NamedTuple, Optional, Tuple

import pytest

import canopenfd
from canopenfd.errors import ConfigurationError
from canopenfd.gateway import remote_access as ra
from canopenfd.gateway.remote_access_client import RemoteAccessClient, RemoteAccessError
from canopenfd.gateway.remote_access_server import RemoteAccessServer
from canopenfd.gateway.remote_access_stream import FdStream
from canopenfd.decode.dispatch import meaning
from canopenfd.od import demo_od

from helpers import Recorder, scaled

GW, DEV = 1, 5


def reference_crc(data: bytes, poly: int = 0x8005) -> int:
    """Bit by bit, MSB first, initial value 0 (independent of the codec)."""
    crc = 0
    for byte in data:
        for bit in range(7, -1, -1):
            top = (crc >> 15) & 1
            crc = (crc << 1) & 0xFFFF
            if top ^ ((byte >> bit) & 1):
                crc ^= poly
    return crc


def frame(payload: bytes, start: int = 0x11) -> bytes:
    body = bytes((len(payload),)) + payload
    return bytes((start,)) + body + reference_crc(body).to_bytes(2, "little")


class Host:
    """The host end of the pty, frames parsed by hand: responses queued,
    indications D recorded."""

    def __init__(self, fd: int) -> None:
        self.stream = FdStream(fd, "test host")
        self.responses: "queue.Queue[bytes]" = queue.Queue()
        self.indications = Recorder()
        self.raw = bytearray()
        self._stop = False
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        buf = bytearray()
        while not self._stop:
            try:
                buf += self.stream.read(0.05)
            except EOFError:
                return
            while len(buf) >= 2 and len(buf) >= buf[1] + 4:
                assert buf[0] == 0x11, f"gateway sent start byte 0x{buf[0]:02X}"
                size = buf[1]
                body, crc = bytes(buf[1:2 + size]), int.from_bytes(buf[2 + size:4 + size], "little")
                assert reference_crc(body) == crc, f"gateway frame with a bad CRC: {buf.hex()}"
                payload = body[1:]
                self.raw += buf[:4 + size]
                del buf[:4 + size]
                if payload[:1] == b"D":
                    self.indications(payload)
                else:
                    self.responses.put(payload)

    def send(self, data: bytes) -> None:
        self.stream.write(data)

    def ask(self, payload: bytes, timeout: float = 5.0) -> bytes:
        self.send(frame(payload))
        return self.response(timeout)

    def response(self, timeout: float = 5.0) -> bytes:
        return self.responses.get(timeout=scaled(timeout))

    def close(self) -> None:
        self._stop = True
        self.stream.close()


class World(NamedTuple):
    net: canopenfd.Network
    line: Any            # the gateway's line
    gw: Any              # its local node
    dev_line: Any
    dev: Any             # node 5 on the other line
    bus: Recorder        # every frame (a monitor line)
    server: RemoteAccessServer
    host: Host


def nmt_frames(bus: Recorder) -> List[bytes]:
    return [bytes(f.data) for f in bus.snapshot() if f.id == 0]


@pytest.fixture(params=["fd", "classic"])
def mode(request: pytest.FixtureRequest) -> str:
    return str(request.param)


def make_world(net: canopenfd.Network, bus_name: str, mode: str = "fd", **server_options: Any
               ) -> Tuple[World, int]:
    line = net.open_line(bus_name, mode=mode)
    gw = line.create_local_node(GW, od=demo_od(mode))
    dev_line = net.open_line(bus_name, mode=mode)
    dev = dev_line.create_local_node(DEV, od=demo_od(mode, pdos=1), heartbeat_ms=50)
    bus = Recorder()
    net.open_line(bus_name, mode=mode, monitor=True).on_frame(bus)
    server = RemoteAccessServer({1: line}, **server_options)
    master, slave = os.openpty()
    tty.setraw(master)
    tty.setraw(slave)
    server.serve(FdStream(master, "pty master"))
    return World(net, line, gw, dev_line, dev, bus, server, Host(slave)), slave


@pytest.fixture
def world(net: canopenfd.Network, bus_name: str) -> Iterator[World]:
    w, _ = make_world(net, bus_name)
    try:
        yield w
    finally:
        w.host.close()
        w.server.close()


# ------------------------------------------------------------ local OD (W, R)

def test_local_write_and_read_byte_for_byte(world: World) -> None:
    host = world.host
    assert host.ask(b"W\x17\x10\x00\xc8\x00") == b"W\x17\x10\x00\x00\x00"
    assert world.gw[0x1017].raw == 200
    assert host.ask(b"R\x17\x10\x00") == b"R\x17\x10\x00\x00\x00\xc8\x00"
    world.gw[0x2003].raw = -2
    assert host.ask(b"R\x03\x20\x00") == b"R\x03\x20\x00\x00\x00\xfe\xff"


def test_local_errors(world: World) -> None:
    host = world.host
    assert host.ask(b"R\x99\x29\x00") == b"R\x99\x29\x00\x01\x00"           # OD_NOT_FOUND
    assert host.ask(b"W\x17\x10\x00\x01\x02\x03") == b"W\x17\x10\x00\x02\x00"  # length
    # the host is the node's application: it writes entries read-only to the
    # network (inputs a TPDO maps), as the local API does
    assert host.ask(b"W\x18\x10\x01\x01\x00\x00\x00") == b"W\x18\x10\x01\x00\x00"
    assert world.gw[0x1018][1].raw == 1
    # a value the entry's limits refuse: 'transfer aborted'
    assert host.ask(b"W\x03\x20\x00\x01\x80") == b"W\x03\x20\x00\x40\x00"


# ------------------------------------------------------------ remote OD (S, U)

def test_remote_read_and_write(net: canopenfd.Network, bus_name: str, mode: str) -> None:
    w, _ = make_world(net, bus_name, mode)
    try:
        w.dev[0x1018][1].raw = 0x12345678
        assert w.host.ask(b"U\x05\x18\x10\x01") == b"U\x05\x18\x10\x01\x00\x00\x78\x56\x34\x12"
        assert w.host.ask(b"S\x05\x17\x10\x00\x96\x00") == b"S\x05\x17\x10\x00\x00\x00"
        assert w.dev[0x1017].raw == 150
        # the monitor may hear the last request after the answer came back: wait
        request_id = 0x600 + (DEV if mode == "classic" else GW)
        w.bus.wait_for(lambda calls: len([f for f in calls if f.id == request_id]) >= 2,
                       what="the two requests")
        requests = [bytes(f.data) for f in w.bus.snapshot() if f.id == 0x600 + DEV]
        if mode == "classic":
            # CiA 301 expedited SDO: upload request, then a 2-byte download
            assert requests == [b"\x40\x18\x10\x01\x00\x00\x00\x00",
                                b"\x2b\x17\x10\x00\x96\x00\x00\x00"]
        else:
            # USDO (CiA 1301): requests on 0x600 + client node-id, byte 0 the server
            requests = [f for f in w.bus.snapshot() if f.id == 0x600 + GW]
            assert [f.data[0] for f in requests] == [DEV, DEV]
            texts = [meaning(f) for f in requests]
            assert "upload request 0x1018:01" in texts[0], texts
            assert "0x1017:00" in texts[1] and "download" in texts[1], texts
        # the gateway's own node-id: its local OD, nothing on the bus
        before = len(w.bus)
        assert w.host.ask(b"U\x01\x17\x10\x00") == b"U\x01\x17\x10\x00\x00\x00\x00\x00"
        assert not [f for f in w.bus.snapshot()[before:] if 0x600 <= f.id <= 0x67F]
    finally:
        w.host.close()
        w.server.close()


def test_remote_errors_and_busy(net: canopenfd.Network, bus_name: str) -> None:
    world, _ = make_world(net, bus_name, sdo_timeout=3.0)
    try:
        remote_errors_and_busy(world)
    finally:
        world.host.close()
        world.server.close()


def remote_errors_and_busy(world: World) -> None:
    host = world.host
    assert host.ask(b"U\x05\x99\x29\x00") == b"U\x05\x99\x29\x00\x01\x00"    # no such object
    assert host.ask(b"U\x00\x00\x10\x00") == b"U\x00\x00\x10\x00\x00\x10"    # node 0
    assert host.ask(b"S\x80\x00\x10\x00\x01") == b"S\x80\x00\x10\x00\x00\x10"  # node 128
    # node 9 is silent: its transfer runs until the per-frame timeout (3 s
    # here); a second remote command meanwhile is refused BUSY at once, a
    # local one is served
    host.send(frame(b"U\x09\x00\x10\x00"))
    assert host.ask(b"U\x05\x18\x10\x01") == b"U\x05\x18\x10\x01\x08\x00"
    assert host.ask(b"S\x05\x17\x10\x00\x01\x00") == b"S\x05\x17\x10\x00\x08\x00"
    assert host.ask(b"R\x17\x10\x00") == b"R\x17\x10\x00\x00\x00\x00\x00"
    assert host.response(10) == b"U\x09\x00\x10\x00\x00\x02"        # SDO timeout
    assert world.server.stats["busy"] == 2
    # free again
    assert host.ask(b"U\x05\x18\x10\x01") == b"U\x05\x18\x10\x01\x00\x00\x00\x00\x00\x00"


def test_remote_timeout(world: World) -> None:
    # node 9 is silent: the SDO/USDO timeout (1 s per frame by default)
    assert world.host.ask(b"U\x09\x00\x10\x00", timeout=10) == b"U\x09\x00\x10\x00\x00\x02"


# ------------------------------------------------------------ NMT and status entries

def test_nmt_through_5F0A(world: World) -> None:
    host, bus = world.host, world.bus
    assert host.ask(b"W\x0a\x5f\x01\x01\x05") == b"W\x0a\x5f\x01\x00\x00"    # start node 5
    bus.wait_for(lambda calls: b"\x01\x05" in nmt_frames(bus), what="NMT start 5")
    world.dev.wait_for_state("OPERATIONAL", timeout=scaled(2))
    assert host.ask(b"W\x0a\x5f\x01\x82\x00") == b"W\x0a\x5f\x01\x00\x00"    # reset comm all
    bus.wait_for(lambda calls: b"\x82\x00" in nmt_frames(bus), what="NMT reset comm all")
    assert host.ask(b"W\x0a\x5f\x01\x03\x05") == b"W\x0a\x5f\x01\x04\x00"    # no command 3
    assert host.ask(b"W\x0a\x5f\x01\x01") == b"W\x0a\x5f\x01\x02\x00"        # 1 byte
    assert nmt_frames(bus) == [b"\x01\x05", b"\x82\x00"]


def test_status_entries(world: World) -> None:
    host = world.host
    assert host.ask(b"R\x00\x5f\x01") == b"R\x00\x5f\x01\x00\x00\x01"        # own node-id
    assert host.ask(b"R\x00\x5f\x02") == b"R\x00\x5f\x02\x00\x00\x7f"        # pre-operational
    assert host.ask(b"R\x00\x5f\x03") == b"R\x00\x5f\x03\x00\x00\x21"        # INIT | CANFD
    kind = host.ask(b"R\x00\x5f\x04")
    assert kind[:6] == b"R\x00\x5f\x04\x00\x00" and kind[7] == 0x02          # a manager
    assert host.ask(b"W\x00\x5f\x01\x07") == b"W\x00\x5f\x01\x00\x08"        # read-only
    world.dev.wait_for_state("PRE-OPERATIONAL", timeout=scaled(2))
    world.line[DEV].wait_for_heartbeat(timeout=scaled(2))
    state = host.ask(b"R\x04\x5f\x05")
    assert state[:6] == b"R\x04\x5f\x05\x00\x00" and state[6] in (0x7F, 0x90)
    assert host.ask(b"R\x04\x5f\x09") == b"R\x04\x5f\x09\x00\x00\x00"        # never heard
    assert host.ask(b"R\x01\x5f\x04") == b"R\x01\x5f\x04\x00\x00\x00\x00\x7f\x7f"


# ------------------------------------------------------------ bad input

def test_bad_frames_counted_and_next_one_served(world: World) -> None:
    host, server = world.host, world.server
    good = frame(b"R\x17\x10\x00")
    bad_crc = bytearray(good)
    bad_crc[-2] ^= 0xFF
    host.send(bytes(bad_crc) + good)
    assert host.response() == b"R\x17\x10\x00\x00\x00\x00\x00"
    host.send(bytes((0x11, 0x00)) + bytes((0x11, 0x64)) + good)      # length 0, 100 > 35
    assert host.response() == b"R\x17\x10\x00\x00\x00\x00\x00"
    host.send(b"\x00\xff\x42garbage\x00" + good)
    assert host.response() == b"R\x17\x10\x00\x00\x00\x00\x00"
    host.send(good[:4])                                               # truncated
    time.sleep(0.7)                  # the server's idle timeout is 0.5 s: the point here
    host.send(good)
    assert host.response() == b"R\x17\x10\x00\x00\x00\x00\x00"
    host.send(frame(b"R\x17\x10", 0x01))                            # no checksum
    assert host.ask(b"X\x01\x02") == b"X\x04\x00"                    # unknown command
    assert host.ask(b"R\x17\x10") == b"R\x17\x10\x00\x02\x00"        # too short
    stats = server.stats
    assert stats["bad_crc"] == 1 and stats["bad_length"] >= 2 and stats["truncated"] == 1
    assert stats["garbage_bytes"] >= 10 and stats["no_checksum"] == 1
    assert stats["unknown_command"] == 1 and stats["invalid_length"] == 1
    assert stats["frames"] == 6


# ------------------------------------------------------------ indications

def test_indications(world: World) -> None:
    host = world.host
    # the device writes the gateway's local OD: D with sender 0 (unknown)
    world.dev_line.usdo.download(GW, 0x2003, 0, (1234).to_bytes(2, "little", signed=True))
    host.indications.wait_value(b"D\x00\x03\x20\x00\xd2\x04")
    # node 5 started by someone else: D on [5F04h,5] with its state
    world.line.nmt.start(DEV)
    host.indications.wait_value(b"D\x05\x04\x5f\x05\x05")
    # an EMCY of node 5, then its reset
    world.dev.emcy.raise_error(0x5000)
    host.indications.wait_value(b"D\x05\x04\x5f\x05\x80")
    world.dev.emcy.clear(0x5000)
    host.indications.wait_value(b"D\x05\x04\x5f\x05\x81")
    # the gateway's own state: [5F00h,02h]
    world.gw.apply("START")
    host.indications.wait_value(b"D\x01\x00\x5f\x02\x05")


def test_slow_host_drops_indications_counts_them(net: canopenfd.Network, bus_name: str) -> None:
    w, _ = make_world(net, bus_name, indication_queue=2)
    try:
        w.host._stop = True          # nobody reads: the pty fills, then the queue
        for value in range(2000):
            w.server.indicate(1, ra.NewData(0, 0x2000, 0, bytes(20)))
        assert w.server.stats["indications_dropped"] > 0
        w.server.indicate(1, ra.NewData(0, 0x2000, 0, bytes(31)))   # 36 > 35 bytes
        assert w.server.stats["indications_too_long"] == 1
    finally:
        w.host.close()
        w.server.close()


# ------------------------------------------------------------ the minimal manager

def test_keep_op_starts_a_booting_node(world: World) -> None:
    host, bus = world.host, world.bus
    assert host.ask(b"W\x01\x5f\x04\x01\x00\x00\x00") == b"W\x01\x5f\x04\x00\x00"
    world.gw.wait_for_state("OPERATIONAL", timeout=scaled(2))     # the gateway starts itself
    bus.wait_for(lambda calls: b"\x01\x00" in nmt_frames(bus), what="start of all nodes")
    world.line[DEV].wait_for_state("OPERATIONAL", timeout=scaled(2))  # as the gateway saw it
    world.dev.apply("PRE_OPERATIONAL")          # falls back: started again, by node-id
    bus.wait_for(lambda calls: b"\x01\x05" in nmt_frames(bus), what="start of node 5")
    late = world.net.open_line(world.line.channel).create_local_node(7, heartbeat_ms=50)
    bus.wait_for(lambda calls: b"\x01\x07" in nmt_frames(bus), what="start of booted node 7")
    late.wait_for_state("OPERATIONAL", timeout=scaled(2))
    host.indications.wait_value(b"D\x07\x04\x5f\x07\x00")
    # the unsupported automation bits are refused
    assert host.ask(b"W\x01\x5f\x04\x08\x00\x00\x00") == b"W\x01\x5f\x04\x00\x08"


def test_lost_heartbeat_resets_the_node(world: World) -> None:
    host, bus = world.host, world.bus
    assert host.ask(b"W\x01\x5f\x08\x2c\x01") == b"W\x01\x5f\x08\x00\x00"    # 300 ms
    assert host.ask(b"W\x01\x5f\x04\x02\x00\x00\x00") == b"W\x01\x5f\x04\x00\x00"
    # (heartbeat active, 0x90, was told at the first heartbeat the manager heard,
    # maybe before this host connected: not waited for)
    world.line[DEV].wait_for_heartbeat(timeout=scaled(2))
    world.dev.heartbeat_ms = 0                       # node 5 falls silent
    bus.wait_for(lambda calls: b"\x81\x05" in nmt_frames(bus), timeout=5,
                 what="NMT reset node 5")
    host.indications.wait_value(b"D\x05\x04\x5f\x05\x91")
    # the reset node boots again (and is told as boot-up)
    host.indications.wait_value(b"D\x05\x04\x5f\x05\x00")


def test_pdo_receive_all_scans_known_nodes(net: canopenfd.Network, bus_name: str) -> None:
    w, _ = make_world(net, bus_name, known={1: {DEV: demo_od("fd", pdos=1)}})
    try:
        tpdo = w.dev.tpdo[1]
        tpdo.clear()
        tpdo.add_variable(0x2006, 0)
        tpdo.cob_id = 0x180 + DEV
        tpdo.trans_type = 255
        tpdo.enabled = True
        tpdo.save()
        host = w.host
        # KEEP_OP | PDO_RECEIVE_ALL: the known node is scanned and started
        assert host.ask(b"W\x01\x5f\x04\x05\x00\x00\x00") == b"W\x01\x5f\x04\x00\x00"
        host.indications.wait_value(b"D\x05\x04\x5f\x05\x9f")
        host.indications.wait_value(b"D\x05\x04\x5f\x05\xa0")
        w.dev.wait_for_state("OPERATIONAL", timeout=scaled(2))
        w.dev[0x2006].raw = 0x1234
        w.dev.trigger_pdo(0x2006)
        w.bus.wait_for(lambda calls: any(f.id == 0x185 for f in calls), what="TPDO 1")
        host.indications.wait_value(b"D\x05\x06\x20\x00\x34\x12")
        # [5F01h,0Ah]: scan again on request
        start = len(host.indications)
        assert host.ask(b"W\x01\x5f\x0a\x05") == b"W\x01\x5f\x0a\x00\x00"
        host.indications.wait_value(b"D\x05\x04\x5f\x05\xa0", start=start)
    finally:
        w.host.close()
        w.server.close()


# ------------------------------------------------------------ the client, TCP, serial

def test_client_api_over_tcp(world: World) -> None:
    port = world.server.serve_tcp(0)
    with RemoteAccessClient.connect("127.0.0.1", port) as client:
        states = Recorder()
        client.on_node_state(lambda net, node, status: states((net, node, status)))
        data = Recorder()
        client.on_data(lambda net, d: data((net, d)))
        client.write_local(0x1017, 0, (100).to_bytes(2, "little"))
        assert client.read_local(0x1017) == b"\x64\x00"
        world.dev[0x1018][2].raw = 77
        assert client.read_remote(DEV, 0x1018, 2) == (77).to_bytes(4, "little")
        client.write_remote(DEV, 0x2003, 0, (-5).to_bytes(2, "little", signed=True))
        assert world.dev[0x2003].raw == -5
        assert client.own_node_id() == GW and client.own_state() == ra.NodeStatus.PREOP
        assert client.hardware_status() == ra.HwStatus.INIT | ra.HwStatus.CAN_FD
        client.nmt("start", DEV)
        states.wait_value((1, DEV, ra.NodeStatus.OPERATIONAL))
        assert client.node_state(DEV) in (ra.NodeStatus.OPERATIONAL, ra.NodeStatus.HB_ACTIVE)
        client.set_manager(ra.ManagerControl.KEEP_OP, heartbeat_ms=500)
        assert client.manager_control() & 0x1F == ra.ManagerControl.KEEP_OP
        with pytest.raises(RemoteAccessError, match=r"read local 0x2999:00 on network 1: "
                                                    r"OD_NOT_FOUND \(0x0001\)") as info:
            client.read_local(0x2999)
        assert info.value.error == ra.RaError.OD_NOT_FOUND
        with pytest.raises(ConfigurationError, match="unknown command 'go'"):
            client.nmt("go")
        with pytest.raises(ConfigurationError, match="at most 35"):
            client.write_local(0x2000, 0, bytes(40))
        assert client.stats["bad_crc"] == 0 and client.stats["unexpected"] == 0
        # a raising callback is logged and counted; the client goes on
        client.on_data(lambda net, d: 1 / 0)
        world.line.nmt.stop(DEV)
        states.wait_value((1, DEV, ra.NodeStatus.STOPPED))
        assert client.read_local(0x1017) == b"\x64\x00"
        assert client.stats["callback_errors"] >= 1


def test_serial_port_through_pyserial(net: canopenfd.Network, bus_name: str) -> None:
    pytest.importorskip("serial")
    line = net.open_line(bus_name)
    line.create_local_node(GW, od=demo_od("fd"))
    master, slave = os.openpty()
    tty.setraw(master)
    with RemoteAccessServer({1: line}) as server:
        server.serve_serial(os.ttyname(slave), 115200)
        os.close(slave)
        with RemoteAccessClient(FdStream(master, "pty master")) as client:
            assert client.own_node_id() == GW
            assert client.read_local(0x1018, 1) == b"\x00\x00\x00\x00"


def test_longer_payloads_when_both_ends_allow(net: canopenfd.Network, bus_name: str) -> None:
    line = net.open_line(bus_name)
    gw = line.create_local_node(GW, od=demo_od("fd"))
    gw[0x2009].raw = "x" * 30
    with RemoteAccessServer({1: line}) as seed_sized:
        master, slave = os.openpty()
        tty.setraw(master)
        tty.setraw(slave)
        seed_sized.serve(FdStream(master, "pty master"))
        with RemoteAccessClient(FdStream(slave, "pty slave")) as client:
            # 6 + 30 bytes do not fit the seed's 35: 'receive buffer too small'
            with pytest.raises(RemoteAccessError, match="RX_TOO_SMALL"):
                client.read_local(0x2009)
            with pytest.raises(ConfigurationError, match="at most 35"):
                client.write_local(0x2009, 0, b"y" * 40)
    with RemoteAccessServer({1: line}, max_payload=200) as larger:
        master, slave = os.openpty()
        tty.setraw(master)
        tty.setraw(slave)
        larger.serve(FdStream(master, "pty master"))
        with RemoteAccessClient(FdStream(slave, "pty slave"), max_payload=200) as client:
            assert client.read_local(0x2009) == b"x" * 30
            client.write_local(0x2009, 0, b"y" * 32)
            assert gw[0x2009].raw == "y" * 32


def test_server_refuses_wrong_setup(net: canopenfd.Network, bus_name: str) -> None:
    line = net.open_line(bus_name)
    with pytest.raises(ConfigurationError, match="no network to serve"):
        RemoteAccessServer({})
    with pytest.raises(ConfigurationError, match="network number must be 1..15"):
        RemoteAccessServer({16: line})
    with pytest.raises(ConfigurationError, match="unknown CRC variant"):
        RemoteAccessServer({1: line}, crc="crc32")


def test_heartbeat_receive_all_leaves_the_applications_monitoring(
        net: canopenfd.Network, bus_name: str) -> None:
    line = net.open_line(bus_name)
    od = demo_od("fd")
    od[0x1016][1].value = DEV << 16 | 700          # the gateway node's own 0x1016 entry
    line.create_local_node(GW, od=od)
    watched = line.add_node(9, heartbeat_timeout_ms=900)   # the application's own watch
    master, slave = os.openpty()
    tty.setraw(master)
    tty.setraw(slave)
    with RemoteAccessServer({1: line}) as server:
        server.serve(FdStream(master, "pty master"))
        host = Host(slave)
        try:
            assert host.ask(b"W\x01\x5f\x04\x02\x00\x00\x00") == b"W\x01\x5f\x04\x00\x00"
            assert line[11].heartbeat_timeout_ms == 1000         # the manager's default
            assert watched.heartbeat_timeout_ms == 900           # left alone
            assert host.ask(b"W\x01\x5f\x04\x00\x00\x00\x00") == b"W\x01\x5f\x04\x00\x00"
            assert line[11].heartbeat_timeout_ms == 0
            assert watched.heartbeat_timeout_ms == 900
            assert server.stats["internal_errors"] == 0
        finally:
            host.close()


def test_node_view_typed_by_the_od(world: World) -> None:
    port = world.server.serve_tcp(0)
    with RemoteAccessClient.connect("127.0.0.1", port) as client:
        drive = client.node(DEV, od=demo_od("fd", pdos=1))
        drive.write("Demo UNSIGNED16", 1234)                      # typed, by name
        assert world.dev[0x2006].raw == 1234
        world.dev[0x2008].raw = 2.5
        assert drive.read("Demo REAL32") == 2.5
        assert drive.read((0x2006, 0)) == 1234
        drive.start()
        world.bus.wait_for(lambda calls: b"\x01\x05" in nmt_frames(world.bus),
                           what="NMT start 5")
        world.dev.wait_for_state("OPERATIONAL", timeout=scaled(2))
        bare = client.node(DEV)                                   # no OD: bytes
        assert bare.read(0x2006) == b"\xd2\x04"
        with pytest.raises(ConfigurationError, match="without an OD entry the value must be "
                                                     "bytes, got int"):
            bare.write(0x2006, 5)
        with pytest.raises(ConfigurationError, match="node-id must be 1..127"):
            client.node(0)
        own = client.node(GW, od=demo_od("fd"))                  # the gateway's own OD
        own.write("Producer heartbeat time", 250)
        assert world.gw[0x1017].raw == 250


def test_tcp_hosts_garbage_disconnects_and_several_at_once(world: World) -> None:
    import random
    import socket as socketlib

    port = world.server.serve_tcp(0)
    # 1 MB of noise without a start byte of network 1, then a good frame: served
    rng = random.Random(3)
    noise = bytes(b for b in rng.randbytes(1 << 20) if b not in (0x11, 0x31))
    raw = socketlib.create_connection(("127.0.0.1", port))
    raw.sendall(noise + frame(b"R\x17\x10\x00"))
    raw.settimeout(scaled(10))
    answer = frame(b"R\x17\x10\x00\x00\x00\x00\x00")
    got = b""
    while len(got) < len(answer):
        got += raw.recv(64)
    assert got == answer
    # a host that disconnects while its remote command runs (node 9 is silent)
    raw.sendall(frame(b"U\x09\x00\x10\x00"))
    raw.close()
    # two hosts at once: each gets its own answers, both get the indications
    with RemoteAccessClient.connect("127.0.0.1", port) as one, \
            RemoteAccessClient.connect("127.0.0.1", port) as two:
        seen_one, seen_two = Recorder(), Recorder()
        one.on_data(lambda net, d: seen_one(d))
        two.on_data(lambda net, d: seen_two(d))
        for value in range(1000, 1020):
            one.write_local(0x2006, 0, value.to_bytes(2, "little"))
            assert two.read_local(0x2006) == value.to_bytes(2, "little")
        world.line.nmt.start(DEV)
        wanted = ra.NewData(DEV, ra.NODE_STATE_INDEX, DEV, bytes((ra.NodeStatus.OPERATIONAL,)))
        seen_one.wait_value(wanted)
        seen_two.wait_value(wanted)
        assert one.stats["unexpected"] == 0 and two.stats["unexpected"] == 0
    stats = world.server.stats
    # the noise's 0x01 / 0x21 bytes look like starts of network 1 without a checksum
    assert stats["garbage_bytes"] > 1_000_000 and stats["no_checksum"] > 100
    assert stats["internal_errors"] == 0


def test_hardware_status_follows_the_line(net: canopenfd.Network, bus_name: str) -> None:
    # a 2-frame tx queue: a burst fills it (tx busy) and overflows it (tx overrun)
    line = net.open_line(bus_name, tx_queue=2)
    line.create_local_node(GW, od=demo_od("fd"))
    master, slave = os.openpty()
    tty.setraw(master)
    tty.setraw(slave)
    with RemoteAccessServer({1: line}) as server:
        server.serve(FdStream(master, "pty master"))
        host = Host(slave)
        try:
            assert host.ask(b"R\x00\x5f\x03") == b"R\x00\x5f\x03\x00\x00\x21"    # INIT | CANFD
            for _ in range(3000):             # the runtime refuses (and logs) what overflows
                line.send_frame(0x181, b"\x01")
            # INIT | TX_OVERRUN | CANFD (| TX_BUSY while the queue is full)
            host.indications.wait_for(
                lambda calls: any(c[:5] == b"D\x01\x00\x5f\x03" and c[5] & 0x10 for c in calls),
                what="hardware status with the tx overrun")
            status = host.ask(b"R\x00\x5f\x03")
            assert status[:6] == b"R\x00\x5f\x03\x00\x00" and status[6] & 0x31 == 0x31
        finally:
            host.close()


def test_two_networks_by_start_byte(net: canopenfd.Network, bus_name: str) -> None:
    first = net.open_line(bus_name, mode="fd")
    first.create_local_node(1, od=demo_od("fd"))
    second = net.open_line(bus_name + "-b", mode="classic")
    second.create_local_node(2, od=demo_od("classic"))
    device = net.open_line(bus_name + "-b", mode="classic").create_local_node(
        6, od=demo_od("classic"))
    master, slave = os.openpty()
    tty.setraw(master)
    tty.setraw(slave)
    with RemoteAccessServer({1: first, 2: second}) as server:
        server.serve(FdStream(master, "pty master"))
        raw = FdStream(slave, "host")
        try:
            # network 2 (start byte 0x12): its own local node, answered on network 2
            body = bytes((4,)) + b"R\x00\x5f\x01"
            raw.write(b"\x12" + body + reference_crc(body).to_bytes(2, "little"))
            answer = b""
            deadline = time.monotonic() + scaled(5)
            while len(answer) < 11 and time.monotonic() < deadline:
                answer += raw.read(0.1)
            reply = bytes((7,)) + b"R\x00\x5f\x01\x00\x00\x02"
            assert answer == b"\x12" + reply + reference_crc(reply).to_bytes(2, "little")
            with RemoteAccessClient(raw, net=2) as client:
                device[0x1018][2].raw = 66
                assert client.read_remote(6, 0x1018, 2) == (66).to_bytes(4, "little")  # SDO
                assert client.own_node_id(net=1) == 1
                assert client.hardware_status() == ra.HwStatus.INIT      # classic: no CANFD
        finally:
            raw.close()


def test_xmodem_checksums_as_esacademys_host_code(net: canopenfd.Network, bus_name: str) -> None:
    """crc='xmodem': frames as ESAcademy's published host code builds them
    (CRC-16/XMODEM over length and payload, low byte first)."""
    line = net.open_line(bus_name)
    line.create_local_node(GW, od=demo_od("fd"))
    master, slave = os.openpty()
    tty.setraw(master)
    tty.setraw(slave)
    with RemoteAccessServer({1: line}, crc="xmodem") as server:
        server.serve(FdStream(master, "pty master"))
        raw = FdStream(slave, "host")
        try:
            body = bytes((4,)) + b"R\x00\x5f\x01"
            raw.write(b"\x11" + body + reference_crc(body, 0x1021).to_bytes(2, "little"))
            answer = b""
            deadline = time.monotonic() + scaled(5)
            while len(answer) < 11 and time.monotonic() < deadline:
                answer += raw.read(0.1)
            reply = bytes((7,)) + b"R\x00\x5f\x01\x00\x00\x01"
            assert answer == b"\x11" + reply + reference_crc(reply, 0x1021).to_bytes(2, "little")
            # a frame with the seed's CRC is a bad CRC here (and not answered)
            raw.write(frame(b"R\x00\x5f\x01") + b"\x11" + body
                      + reference_crc(body, 0x1021).to_bytes(2, "little"))
            answer = b""
            deadline = time.monotonic() + scaled(5)
            while len(answer) < 11 and time.monotonic() < deadline:
                answer += raw.read(0.1)
            assert answer == b"\x11" + reply + reference_crc(reply, 0x1021).to_bytes(2, "little")
            assert server.stats["bad_crc"] == 1
        finally:
            raw.close()


def test_closed_server_leaves_the_bus_alone(net: canopenfd.Network, bus_name: str) -> None:
    """After close() the manager's automation is off: a node falling back to
    pre-operational is not started again (KEEP_OP), the heartbeat monitoring
    HB_RECEIVE_ALL switched on is the application's again (0), and the PDO
    values of a scanned node no longer reach the server."""
    w, _ = make_world(net, bus_name)
    host, bus = w.host, w.bus
    try:
        assert host.ask(b"W\x01\x5f\x04\x03\x00\x00\x00") == b"W\x01\x5f\x04\x00\x00"
        bus.wait_for(lambda calls: b"\x01\x00" in nmt_frames(bus), what="start of all nodes")
        w.line[DEV].wait_for_state("OPERATIONAL", timeout=scaled(2))
        assert w.line[DEV].heartbeat_timeout_ms == 1000
    finally:
        host.close()
        w.server.close()
    assert DEV not in w.line.nodes     # the node the manager added is given back
    node = w.line.add_node(DEV)
    # the state change reaches the gateway line's callbacks: ours comes after
    # the manager's (registered first), so once it ran the manager had its turn
    seen = Recorder()
    node.on_state_change(seen)
    before = len(nmt_frames(bus))
    w.dev.apply("PRE_OPERATIONAL")
    seen.wait_value(canopenfd.NmtState.PRE_OPERATIONAL)
    w.line.nmt.start(99)           # a marker sent after anything the manager sent
    bus.wait_for(lambda calls: b"\x01\x63" in nmt_frames(bus), what="the marker NMT frame")
    assert nmt_frames(bus)[before:] == [b"\x01\x63"]


class _StuckHost:
    """A host stream that sends `data` at once and takes nothing back until
    `release` is set (then records what it was sent)."""

    name = "stuck host"

    def __init__(self, data: bytes) -> None:
        self._data = data
        self.release = threading.Event()
        self.sent = Recorder()
        self.closed = False

    def read(self, timeout: float) -> bytes:
        if self.closed:
            raise EOFError("closed")
        data, self._data = self._data, b""
        if not data:
            time.sleep(min(timeout, 0.05))
        return data

    def write(self, data: bytes) -> None:
        while not self.release.wait(0.05):
            if self.closed:
                raise EOFError("closed")
        self.sent(data)

    def close(self) -> None:
        self.closed = True


def test_a_host_that_does_not_read_holds_its_own_requests(world: World) -> None:
    """Responses are never dropped, so a host sending requests without reading
    the answers is not read any further once RESPONSE_QUEUE answers wait
    (before: every answer queued, without bound); once it reads, every answer
    comes, in order."""
    from canopenfd.gateway import remote_access_server as ras

    count = ras.RESPONSE_QUEUE * 4
    stuck = _StuckHost(b"".join(frame(b"R\x00\x5f\x01") for _ in range(count)))
    connection = world.server.serve(stuck)
    try:
        deadline = time.monotonic() + scaled(5)
        while connection.stats["output_waits"] == 0:
            assert time.monotonic() < deadline, "the reader never waited for the host"
            time.sleep(0.01)
        stuck.release.set()
        def answers(calls: List[bytes]) -> List[bytes]:     # indications D aside
            return [data for data in calls if data[2:3] != b"D"]

        stuck.sent.wait_for(lambda calls: len(answers(calls)) >= count,
                            what=f"{count} answers")
        assert answers(stuck.sent.snapshot()) == \
            [frame(b"R\x00\x5f\x01\x00\x00" + bytes((GW,)))] * count
    finally:
        connection.close()


def test_hosts_reading_one_classic_node_take_turns(net: canopenfd.Network, bus_name: str
                                                    ) -> None:
    """Three hosts read one node of a classic line at once: every read
    succeeds (the SDO client runs one transfer per server; before, the one
    meeting a running transfer was refused MISC), each a plain SDO upload on
    the bus."""
    w, _ = make_world(net, bus_name, mode="classic")
    port = w.server.serve_tcp(0)
    errors: List[BaseException] = []
    answers = Recorder()

    def host() -> None:
        try:
            with RemoteAccessClient.connect("127.0.0.1", port) as client:
                for _ in range(20):
                    answers(client.read_remote(DEV, 0x1018, 1))
        except BaseException as exc:    # noqa: BLE001 - handed to the test
            errors.append(exc)

    try:
        threads = [threading.Thread(target=host) for _ in range(3)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join(scaled(30))
        assert errors == []
        vendor = w.dev[0x1018][1].data
        assert answers.snapshot() == [vendor] * 60
        # the recorder hears the frames after the stacks acted: wait for all 60
        w.bus.wait_for(lambda c: len([f for f in c if f.id == 0x600 + DEV]) >= 60, 5,
                       "the 60 SDO requests")
        requests = [bytes(f.data) for f in w.bus.snapshot() if f.id == 0x600 + DEV]
        assert requests == [bytes([0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0])] * 60
    finally:
        w.host.close()
        w.server.close()


def test_tcp_hosts_beyond_max_connections_are_closed(net: canopenfd.Network, bus_name: str
                                                     ) -> None:
    """Each connection costs three threads: past max_connections a new TCP
    host is closed at once and counted (before: accepted without bound);
    the hosts already served go on, and a place freed is taken again."""
    import socket

    w, _ = make_world(net, bus_name, max_connections=2)   # the pty host is one
    try:
        port = w.server.serve_tcp(0)
        with RemoteAccessClient.connect("127.0.0.1", port) as second:
            extra = socket.create_connection(("127.0.0.1", port), timeout=scaled(5))
            try:
                assert extra.recv(16) == b""            # closed by the gateway
            finally:
                extra.close()
            assert w.server.stats["refused_connections"] == 1
            assert second.own_node_id() == GW
            assert w.host.ask(b"R\x00\x5f\x01") == b"R\x00\x5f\x01\x00\x00\x01"
        deadline = time.monotonic() + scaled(5)
        while len(w.server.connections) > 1:      # the second host's end is seen
            assert time.monotonic() < deadline
            time.sleep(0.01)
        with RemoteAccessClient.connect("127.0.0.1", port) as third:
            assert third.own_node_id() == GW
    finally:
        w.host.close()
        w.server.close()


def test_a_host_leaving_aborts_its_transfer_on_the_bus(net: canopenfd.Network,
                                                        bus_name: str) -> None:
    """A host that goes away while its remote read waits for a silent node:
    the transfer is aborted on the bus at once (general error 0x08000000),
    not left running in the name of nobody until the SDO timeout (20 s)."""
    w, _ = make_world(net, bus_name, mode="classic", sdo_timeout=20.0)
    try:
        w.host.send(frame(b"U\x09\x00\x10\x00"))       # node 9: nobody answers
        w.bus.wait_for(lambda fs: [f for f in fs if f.id == 0x609], what="the SDO request")
        w.host.close()
        aborts = w.bus.wait_for(lambda fs: [f for f in fs if f.id == 0x609
                                            and f.data[0] == 0x80], what="the SDO abort")
        assert bytes(aborts[0].data) == bytes([0x80, 0x00, 0x10, 0x00, 0, 0, 0, 0x08])
    finally:
        w.server.close()


def test_client_fails_at_once_when_the_gateway_hangs_up() -> None:
    """A gateway that closes the connection: the waiting call raises at once
    naming it (before: it waited its whole timeout, then said 'no response')."""
    import socket

    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen(1)
    port = listener.getsockname()[1]

    def hang_up() -> None:
        conn, _ = listener.accept()
        conn.recv(64)          # the request, then goodbye
        conn.close()

    thread = threading.Thread(target=hang_up, daemon=True)
    thread.start()
    try:
        with RemoteAccessClient.connect("127.0.0.1", port, timeout=60.0) as client:
            started = time.monotonic()
            with pytest.raises(RemoteAccessError, match="closed the connection"):
                client.read_local(0x1017)
            assert time.monotonic() - started < scaled(10)
            with pytest.raises(RemoteAccessError, match="closed the connection"):
                client.read_local(0x1017)
    finally:
        thread.join(5)
        listener.close()


def test_a_server_that_cannot_start_leaves_nothing_running(net: canopenfd.Network,
                                                           bus_name: str) -> None:
    """The second network's line is closed (its Network is): the server
    refuses to start and
    the first network's manager, already started with KEEP_OP, is stopped
    again (before: its automation went on starting nodes, with no server
    left to close it)."""
    first = net.open_line(bus_name, mode="classic")
    first.create_local_node(GW, od=demo_od("classic"))
    dev = net.open_line(bus_name, mode="classic").create_local_node(
        DEV, od=demo_od("classic"), heartbeat_ms=50)
    bus = Recorder()
    net.open_line(bus_name, mode="classic", monitor=True).on_frame(bus)
    other = canopenfd.Network()
    second = other.open_line(bus_name + "-2", mode="classic")
    other.close()
    with pytest.raises(canopenfd.errors.CanopenFDError):
        RemoteAccessServer({1: first, 2: second}, control=int(ra.ManagerControl.KEEP_OP))
    node = first.add_node(DEV)      # the stopped manager gave its node back
    node.wait_for_state("OPERATIONAL", timeout=scaled(2))   # KEEP_OP started it
    seen = Recorder()
    node.on_state_change(seen)
    before = len(nmt_frames(bus))
    dev.apply("PRE_OPERATIONAL")
    seen.wait_value(canopenfd.NmtState.PRE_OPERATIONAL)
    first.nmt.start(99)            # a marker after anything a manager would send
    bus.wait_for(lambda calls: b"\x01\x63" in nmt_frames(bus), what="the marker NMT frame")
    assert [f for f in nmt_frames(bus)[before:] if f != b"\x01\x00"] == [b"\x01\x63"]
