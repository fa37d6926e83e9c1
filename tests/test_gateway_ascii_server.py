"""The CiA 309-3 ASCII gateway over TCP (canopenfd.gateway.ascii309_server)
against a device node of ours on an in-process bus: answers to real
requests, every data type through a real device, every error code, pushed
events, the SDO bytes on the bus, LSS, bad input (garbage, partial and 1 MB
lines), clients that vanish or never read, and 4 clients x 1000 requests
with every answer matched to its sequence number."""

from __future__ import annotations

import base64
import signal
import socket
import struct
import subprocess
import threading
import time
from typing import Dict, List, Optional

import pytest

from canopenfd.gateway.ascii309_server import AsciiGateway
from canopenfd.od import demo_od
from helpers import NEUTRAL_CWD, Recorder, cli_command, package_env, scaled

DEVICE = 5


class Client:
    """A TCP client of the gateway: answer lines ('[seq] ...') and event
    lines (anything else) kept apart."""

    def __init__(self, port: int, rcvbuf: Optional[int] = None) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        if rcvbuf is not None:
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
        self.sock.settimeout(scaled(10))
        self.sock.connect(("127.0.0.1", port))
        self.buffer = b""
        self.events: List[str] = []

    def send(self, text: str) -> None:
        self.sock.sendall(text.encode("latin-1") + b"\n")

    def line(self) -> str:
        while b"\r\n" not in self.buffer:
            chunk = self.sock.recv(65536)
            if not chunk:
                raise EOFError(f"connection closed; pending {self.buffer!r}")
            self.buffer += chunk
        line, self.buffer = self.buffer.split(b"\r\n", 1)
        return line.decode("latin-1")

    def answer(self) -> str:
        while True:
            line = self.line()
            if line.startswith("[") or line.startswith("#"):
                return line
            self.events.append(line)

    def ask(self, text: str) -> str:
        self.send(text)
        return self.answer()

    def wait_event(self, wanted: str, timeout: float = 5.0) -> None:
        deadline = time.monotonic() + scaled(timeout)
        while wanted not in self.events:
            self.sock.settimeout(max(0.01, deadline - time.monotonic()))
            try:
                self.events.append(self.line())
            except socket.timeout:
                raise AssertionError(f"no event {wanted!r}; got {self.events}") from None
        self.sock.settimeout(scaled(10))

    def close(self) -> None:
        self.sock.close()


@pytest.fixture(params=["fd", "classic"])
def rig(request, net, bus_name):
    """Device node 5 (demo OD, served 1 KiB domain 0x200F) on one line, the
    gateway's line (net 1) and a monitor of every frame; the gateway runs
    on its own thread."""
    mode = request.param
    device = net.open_line(bus_name, mode=mode).create_local_node(
        DEVICE, od=demo_od(mode), boot=False)
    device.serve_domain(0x200F, 1024)
    device.boot()
    line = net.open_line(bus_name, mode=mode)
    frames = Recorder()
    net.open_line(bus_name, mode=mode, monitor=True).on_frame(frames)
    gateway = AsciiGateway({1: line}, sdo_timeout_ms=int(scaled(0.5) * 1000))
    server = gateway.start_in_thread()
    clients: List[Client] = []

    def connect(**options) -> Client:
        client = Client(server.port, **options)
        clients.append(client)
        return client
    yield mode, device, line, frames, gateway, connect
    for client in clients:
        client.close()
    server.close()


# Sources: CANopenNode 309/CO_gateway_ascii.h (its syntax block and the
# example "[1] 4 read 0x1017 0 i16", here to node 5) and its help text for
# the NMT commands and the 'set' commands; the answer forms "[seq] OK",
# "[seq] <value>" and "[seq] ERROR: ..." of CiA 309-3 as both gateways print
# them. Node 5 serves the demo OD (0x1017 starts at 0).
EXAMPLES = [
    ("[1] 5 read 0x1017 0 i16", "[1] 0"),
    ("[2] 5 write 0x1017 0 u16 1000", "[2] OK"),
    ("[3] 5 r 0x1017 0 u16", "[3] 1000"),
    ("[4] set node 5", "[4] OK"),
    ("[5] r 0x1017 0 x16", "[5] 0x03E8"),
    ("[6] 1 5 r 0x1017 0 u16", "[6] 1000"),
    ("[7] w 0x1017 0 u16 0", "[7] OK"),
    ("[8] R 0x1017 0 U16   # a comment", "[8] 0"),
    ("[9] r 0x2009 0 vs", '[9] "canopenfd"'),
    ("[10] w 0x2009 0 vs \"hello world\"", "[10] OK"),
    ("[11] r 0x2009 0 vs", '[11] "hello world"'),
    ("[12] r 0x1018 0 u8", "[12] 4"),
    ("[13] 5 start", "[13] OK"),
    ("[14] 5 stop", "[14] OK"),
    ("[15] 5 preop", "[15] OK"),
    ("[16] 5 preoperational", "[16] OK"),
    ("[17] set sdo_timeout 1000", "[17] OK"),
    ("[18] set network 1", "[18] OK"),
    ("[19] r 0x6000 0", "[19] ERROR: 0x06020000 #object does not exist in the object "
                        "dictionary"),
    ("[20] w 0x1000 0 u32 1", "[20] ERROR: 0x06010002 #attempt to write a read-only object"),
    ("[21] r 0x2006 0", "[21] E8 03"),     # no type: hex pairs (classic); see below for fd
]


def test_examples(rig):
    mode, device, _, _, _, connect = rig
    client = connect()
    for request, expected in EXAMPLES:
        if mode == "fd" and request.startswith("[20]"):
            expected = "[20] ERROR: 0x06010002 #attempt to write a read-only object"
        if mode == "fd" and request.startswith("[21]"):
            expected = "[21] 1000"     # a USDO server names the type: u16
        if mode == "fd" and request.startswith("[12]"):
            expected = "[12] 4"
        assert client.ask(request) == expected, request
    assert device.nmt.state.name == "PRE_OPERATIONAL"
    # A USDO download carries the type the request names, and the server checks it
    # against the entry (0x1017 is UNSIGNED16); SDO has no type field.
    assert client.ask("[22] w 0x1017 0 i16 5") == (
        "[22] ERROR: 0x06070010 #data type does not match, length of service parameter does "
        "not match" if mode == "fd" else "[22] OK")


ROUND_TRIPS = [   # (entry, type, value written and read back)
    (0x2001, "b", "0"), (0x2002, "i8", "-100"), (0x2003, "i16", "-2000"),
    (0x2004, "i32", "-2147483648"), (0x2005, "u8", "255"), (0x2006, "u16", "5000"),
    (0x2007, "u32", "4294967295"), (0x2008, "r32", "-12.25"), (0x2009, "vs", '"a ""b"" c"'),
    (0x200A, "os", "AAECAwQFBgc="), (0x200B, "us", base64.b64encode(b"h\0i\0").decode()),
    (0x200C, "t", "86399999 20000"), (0x200D, "td", "268435455 65535"),
    (0x200F, "d", base64.b64encode(bytes(range(256)) * 2).decode()),
    (0x2011, "r64", "3.141592653589793"), (0x2015, "i64", "-9223372036854775808"),
    (0x201B, "u64", "18446744073709551615"), (0x2005, "x8", "0x7F"),
    (0x2006, "x16", "0x1234"), (0x2007, "x32", "0xDEADBEEF"),
    (0x201B, "x64", "0x0123456789ABCDEF"),
]


def test_every_data_type_round_trip(rig):
    """Each type written through the gateway and read back; the device's own
    dictionary holds the bytes the text means."""
    mode, device, _, _, _, connect = rig
    client = connect()
    client.ask(f"[0] set node {DEVICE}")
    for seq, (index, kind, text) in enumerate(ROUND_TRIPS, start=1):
        assert client.ask(f"[{seq}] w 0x{index:04X} 0 {kind} {text}") == f"[{seq}] OK", kind
        assert client.ask(f"[{seq}] r 0x{index:04X} 0 {kind}") == f"[{seq}] {text}", kind
    assert device[0x2007].raw == 0xDEADBEEF
    assert device[0x2009].raw == 'a "b" c'
    assert device[0x200F].data == bytes(range(256)) * 2      # segmented both ways
    assert device[0x2008].raw == -12.25


def test_sdo_bytes_on_the_bus(rig):
    """Classic line: the SDO frames a read and a write send, and a block
    upload after 'set sdo_block 1'. fd line: the USDO request carries index,
    sub-index and (downloads) the data type named in the request."""
    mode, _, _, frames, _, connect = rig
    client = connect()
    assert client.ask("[1] 5 w 0x1017 0 u16 1000") == "[1] OK"
    assert client.ask("[2] 5 r 0x1017 0 u16") == "[2] 1000"
    if mode == "classic":
        def sdo_frames(can_id, ready):
            """The data of every frame on can_id, once ready(list) holds (the
            monitor delivers them asynchronously)."""
            return frames.wait_for(lambda c: (lambda got: got if ready(got) else None)(
                [bytes(f.data) for f in c if f.id == can_id]), 5, f"frames on 0x{can_id:X}")
        sent = sdo_frames(0x605, lambda got: len(got) >= 2)
        assert sent[0] == bytes([0x2B, 0x17, 0x10, 0x00, 0xE8, 0x03, 0x00, 0x00])
        assert sent[1] == bytes([0x40, 0x17, 0x10, 0x00, 0x00, 0x00, 0x00, 0x00])
        answers = sdo_frames(0x585, lambda got: len(got) >= 2)
        assert answers[:2] == [bytes([0x60, 0x17, 0x10, 0x00, 0, 0, 0, 0]),
                               bytes([0x4B, 0x17, 0x10, 0x00, 0xE8, 0x03, 0, 0])]
        assert client.ask("[3] set sdo_block 1") == "[3] OK"
        assert client.ask("[4] 5 r 0x2009 0 vs") == '[4] "canopenfd"'
        block = sdo_frames(0x605, lambda got: len(got) >= 3)[2]
        assert block[0] & 0xE0 == 0xA0 and block[1:4] == bytes([0x09, 0x20, 0x00])
        assert client.ask("[5] 5 w 0x1017 0 u16 7") == "[5] OK"
        # block download initiate (ccs 6, size indicated), then one segment of 2 bytes
        initiate = bytes([0xC6, 0x17, 0x10, 0x00, 2, 0, 0, 0])
        sent = sdo_frames(0x605, lambda got: initiate in got and got.index(initiate) + 1 <
                          len(got))
        assert sent[sent.index(initiate) + 1][:3] == bytes([0x81, 0x07, 0x00])
        assert client.ask("[6] 5 r 0x1017 0 u16") == "[6] 7"
    else:
        requests = frames.wait_for(
            lambda c: [f for f in c if f.id == 0x600 + 127][:2] if len(
                [f for f in c if f.id == 0x600 + 127]) >= 2 else None, 5, "USDO requests")
        write, read = (bytes(f.data) for f in requests)
        # byte 0 the server, 1 the command, 3 sub-index, 4..5 index (protocol-notes.md, USDO)
        assert write[0] == DEVICE and read[0] == DEVICE
        assert write[1] == 0x01 and read[1] == 0x11          # expedited download, upload
        for data in (write, read):
            assert data[3:6] == bytes([0x00, 0x17, 0x10])
        assert write[6:10] == bytes([0x06, 2, 0xE8, 0x03])  # UNSIGNED16 as 'u16' says, 2 bytes


def test_error_codes(rig, net, bus_name):
    """The CiA 309-3 gateway codes the server gives (the parser's own ones:
    test_gateway_ascii.py) and SDO/USDO aborts."""
    mode, _, line, _, _, connect = rig
    client = connect()
    assert client.ask("[1] r 0x1000 0") == "[1] ERROR: 105 #No default node set"
    assert client.ask("[2] 0 r 0x1000 0") == "[2] ERROR: 107 #Unsupported node: node 0"
    assert client.ask("[3] 7 5 r 0x1000 0") == "[3] ERROR: 106 #Unsupported net: net 7"
    assert client.ask("[4] set network 9") == "[4] ERROR: 106 #Unsupported net: net 9"
    assert client.ask("[5] lss_get_node") == "[5] ERROR: 103 #Time-out: lss.inquire(" \
        f"'node_id') on line {line.channel!r}: no answer"
    assert client.ask("[6] 9 r 0x1000 0") == "[6] ERROR: 0x05040000 #SDO protocol timed out"
    assert client.ask("[7] bogus") == "[7] ERROR: 100 #Request not supported: unknown " \
                                      "command 'bogus'"
    assert client.ask("[8] 5 w 0x1000") == "[8] ERROR: 101 #Syntax error: w[rite] index sub " \
                                           "type value"
    assert client.ask("[9] _lss_fastscan 5") == "[9] ERROR: 103 #Time-out: no unconfigured " \
                                                "device answered"
    # 104: a gateway whose nets do not include net 1 has no default net
    other = AsciiGateway({2: line}).start_in_thread()
    try:
        second = Client(other.port)
        assert second.ask("[1] 5 r 0x1018 0 u8") == "[1] ERROR: 104 #No default net set"
        assert second.ask("[2] 2 5 r 0x1018 0 u8") == "[2] 4"
        assert second.ask("[3] set network 2") == "[3] OK"
        assert second.ask("[4] 5 r 0x1018 0 u8") == "[4] 4"
        second.close()
    finally:
        other.close()
    # 102: the stack refuses the request (here: its network is closed)
    net.close()
    assert client.ask("[10] 5 r 0x1018 0 u8").startswith("[10] ERROR: 102 #Request not "
                                                         "processed due to internal state: ")


def test_events_pushed(rig):
    """Boot-up, NMT state changes, heartbeat lost and started, EMCY: to every
    client, as Lely's gateway words them ('1 5 BOOT_UP', '1 5 EMCY ...')."""
    mode, device, line, _, _, connect = rig
    first, second = connect(), connect()
    line.add_node(DEVICE, heartbeat_timeout_ms=int(scaled(0.2) * 1000))
    assert first.ask("[1] 5 w 0x1017 0 u16 20") == "[1] OK"    # heartbeats every 20 ms
    first.wait_event("1 5 ERROR: 202 #Heartbeat started")
    assert first.ask("[2] 5 reset node") == "[2] OK"
    first.wait_event("1 5 BOOT_UP")
    second.wait_event("1 5 BOOT_UP")
    assert first.ask("[3] 5 w 0x1017 0 u16 20") == "[3] OK"    # reset: back to 0
    assert first.ask("[4] 5 start") == "[4] OK"
    first.wait_event("1 5 STATE OPER")
    device.emcy.raise_error(0x5030, b"\x01\x02\x03\x04\x05")
    first.wait_event("1 5 EMCY 5030 01 1 2 3 4 5")
    second.wait_event("1 5 EMCY 5030 01 1 2 3 4 5")
    assert first.ask("[5] 5 w 0x1017 0 u16 0") == "[5] OK"     # heartbeat off: lost
    first.wait_event("1 5 ERROR: 203 #Heartbeat lost")


def test_bad_input(rig):
    """Garbage, partial lines, a 1 MB line, unknown commands: an error answer
    each (or nothing for an empty line), and the session keeps serving."""
    _, _, _, _, gateway, connect = rig
    client = connect()
    client.sock.sendall(b"\x00\xff\xfe garbage \x01\x02\n")
    assert client.answer() == "[0] ERROR: 101 #Syntax error: a request starts with [sequence]"
    client.sock.sendall(b"\n\r\n   \n# comment only\n")       # nothing to answer
    for piece in (b"[3] 5 r 0x10", b"18 0", b" u8\r", b"\n"):   # one request in pieces
        client.sock.sendall(piece)
        time.sleep(0.01)
    assert client.answer() == "[3] 4"
    client.sock.sendall(b"[4] 5 w 0x2009 0 vs " + b"A" * (1 << 20) + b"\n")
    assert client.answer() == f"[4] ERROR: 101 #Syntax error: line longer than " \
                              f"{gateway.max_line} bytes"
    assert client.ask("[5] 5 r 0x1018 0 u8") == "[5] 4"
    assert client.ask("[6] launch rockets") == "[6] ERROR: 100 #Request not supported: " \
                                               "unknown command 'launch'"
    client.sock.sendall(b"[7] 5 r 0x1018 0 u8")                 # last line without LF
    client.sock.shutdown(socket.SHUT_WR)
    assert client.answer() == "[7] 4"
    assert gateway.stats["lines_too_long"] == 1


def test_client_vanishing_mid_transfer(rig):
    """A client reset while its request waits on a silent node: its transfer
    is cancelled (the abort goes on the bus), the others are served meanwhile."""
    mode, _, _, frames, gateway, connect = rig
    gone, other = connect(), connect()
    assert gone.ask("[1] set sdo_timeout 60000") == "[1] OK"
    gone.send("[2] 9 r 0x1000 0")                              # node 9: nobody answers
    frames.wait_for(lambda c: [f for f in c if f.id in (0x609, 0x67F)] or None, 5,
                    "the request to node 9")
    assert other.ask("[1] 5 r 0x1018 0 u8") == "[1] 4"
    gone.sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
    gone.sock.close()                                          # RST
    if mode == "classic":
        abort = frames.wait_for(lambda c: [f for f in c if f.id == 0x609 and f.data[0] == 0x80]
                                or None, 5, "the abort to node 9")[0]
        assert bytes(abort.data[1:4]) == bytes([0x00, 0x10, 0x00])
    deadline = time.monotonic() + scaled(5)
    while gateway.stats["cancelled_transfers"] < 1 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert gateway.stats["cancelled_transfers"] == 1
    assert other.ask("[2] 5 r 0x1018 0 u8") == "[2] 4"


def test_slow_clients_never_stall_the_others(net, bus_name):
    """A client that reads nothing misses events (counted) and is cut off
    once an answer waits too long; the others keep being answered (one line
    mode: what is tested is the TCP side)."""
    device = net.open_line(bus_name).create_local_node(DEVICE, od=demo_od("fd"))
    line = net.open_line(bus_name)
    gateway = AsciiGateway({1: line}, max_output=4096, write_timeout=0.5)
    server = gateway.start_in_thread()
    try:
        sleeper = Client(server.port, rcvbuf=4096)
        worker = Client(server.port)
        assert worker.ask("[1] 5 r 0x1018 0 u8") == "[1] 4"
        for i in range(300):                                   # about 600 events
            device.emcy.raise_error(0x5000 + i)
            device.emcy.clear(0x5000 + i)
        for i in range(2000):                                  # 2.6 MB of help it never reads
            sleeper.sock.send(b"[1] help\n")
            if i % 200 == 0:
                assert worker.ask(f"[{i}] 5 r 0x1018 0 u8") == f"[{i}] 4"
        deadline = time.monotonic() + scaled(10)
        while gateway.stats["disconnected_slow"] < 1 and time.monotonic() < deadline:
            assert worker.ask("[9] 5 r 0x1018 0 u8") == "[9] 4"
        assert gateway.stats["disconnected_slow"] == 1
        assert gateway.stats["client_events_dropped"] > 0
        worker.close()
        sleeper.close()
    finally:
        server.close()


def test_four_clients_a_thousand_requests_each(rig):
    """4 clients pipelining 1000 requests each (a write of their own entry,
    then a read of it): every answer comes back with its sequence number and
    the value that request must give."""
    _, _, _, _, gateway, connect = rig
    entries = [(0x2003, "i16", -2000), (0x2004, "i32", -100000), (0x2006, "u16", 10),
               (0x2007, "u32", 0)]
    clients = [connect() for _ in entries]
    failures: List[str] = []

    def run(n: int) -> None:
        client = clients[n]
        index, kind, base = entries[n]
        expected: Dict[int, str] = {}
        lines = []
        for i in range(500):
            seq = n * 100000 + 2 * i
            lines.append(f"[{seq}] 5 w 0x{index:04X} 0 {kind} {base + i}")
            lines.append(f"[{seq + 1}] 5 r 0x{index:04X} 0 {kind}")
            expected[seq] = f"[{seq}] OK"
            expected[seq + 1] = f"[{seq + 1}] {base + i}"
        sender = threading.Thread(
            target=lambda: client.sock.sendall("".join(f"{l}\n" for l in lines).encode()))
        sender.start()
        for _ in range(len(lines)):
            answer = client.answer()
            seq = int(answer[1:answer.index("]")])
            if expected.pop(seq, None) != answer:
                failures.append(f"client {n}: {answer!r}")
        sender.join()
        if expected:
            failures.append(f"client {n}: {len(expected)} unanswered")

    threads = [threading.Thread(target=run, args=(n,)) for n in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(scaled(120))
    assert not failures, failures[:5]
    assert gateway.stats["requests"] >= 4000


def lss_rig(net, bus_name):
    """Node 7 (an LSS slave with identity 0x1A2 0xBEEF01 0x20003 0x80000001)
    and the gateway's classic line (LSS timeout 50 ms): (line, frames)."""
    identity = (0x1A2, 0xBEEF01, 0x20003, 0x80000001)
    od = demo_od("classic")
    for sub, value in enumerate(identity, start=1):
        od[0x1018][sub].default = value
    net.open_line(bus_name, mode="classic").create_local_node(7, od=od)
    line = net.open_line(bus_name, mode="classic")
    line.lss.timeout_ms = 50
    frames = Recorder()
    net.open_line(bus_name, mode="classic", monitor=True).on_frame(frames)
    return line, frames


def test_lss_commands(net, bus_name):
    """The lss_* commands through line.lss against our node 7's LSS slave,
    and the LSS frames they send."""
    line, frames = lss_rig(net, bus_name)
    server = AsciiGateway({1: line}).start_in_thread()
    try:
        client = Client(server.port)
        assert client.ask("[1] lss_switch_glob 1") == "[1] OK"
        frames.wait_for(lambda c: [f for f in c if f.id == 0x7E5] or None, 5, "LSS frame")
        assert [bytes(f.data) for f in frames.snapshot() if f.id == 0x7E5][0] == \
            bytes([0x04, 0x01, 0, 0, 0, 0, 0, 0])
        assert client.ask("[2] lss_get_node") == "[2] 0x07"
        assert client.ask("[3] lss_inquire_addr") == \
            "[3] 0x000001A2 0x00BEEF01 0x00020003 0x80000001"
        assert client.ask("[4] lss_inquire_addr 3") == "[4] 0x80000001"
        assert client.ask("[5] lss_conf_bitrate 0 2").startswith(
            "[5] ERROR: 503 #LSS bit-rate not supported")
        assert client.ask("[6] lss_store").startswith("[6] ERROR: 504 #LSS parameter storing "
                                                      "failed")
        assert client.ask("[7] lss_set_node 9") == "[7] OK"
        assert client.ask("[8] lss_switch_glob 0") == "[8] OK"
        assert client.ask("[9] lss_get_node").startswith("[9] ERROR: 103 #Time-out")
        assert client.ask("[10] lss_switch_sel 0x1A2 0xBEEF01 0x20003 0x80000001") == "[10] OK"
        assert client.ask("[11] lss_get_node") == "[11] 0x07"
        assert client.ask("[12] lss_switch_sel 0x1A2 0xBEEF01 0x20003 0x12345") == \
            "[12] ERROR: 103 #Time-out: no slave answered"
        assert client.ask("[13] lss_activate_bitrate 100") == "[13] OK"
        client.close()
    finally:
        server.close()


def test_lss_allnodes_gives_node_ids(net, bus_name):
    """lss_allnodes: a fast scan finds an unconfigured device, gives it the
    start node-id, has it store the node-id and reports it; the device then
    boots with it."""
    identity = (0x1A2, 0xBEEF01, 0x20003, 0x80000042)
    od = demo_od("classic")
    for sub, value in enumerate(identity, start=1):
        od[0x1018][sub].default = value
    device = net.open_line(bus_name, mode="classic").create_local_node(255, od=od)
    stored = Recorder()
    device.lss.on_store(stored)
    line = net.open_line(bus_name, mode="classic")
    server = AsciiGateway({1: line}).start_in_thread()
    try:
        client = Client(server.port)
        client.send("[1] lss_allnodes 20 10 1")
        assert client.answer() == "# Node-ID 10 assigned to: 0x000001A2 0x00BEEF01 " \
                                  "0x00020003 0x80000042"
        assert client.answer() == "# Found 1 nodes, search finished."
        assert client.answer() == "[1] OK"
        client.wait_event("1 10 BOOT_UP")
        assert stored.snapshot() == [10]                    # store asked for: stored
        assert client.ask("[2] 10 r 0x1018 4 x32") == "[2] 0x80000042"
        client.close()
    finally:
        server.close()



def test_lss_allnodes_step_timeout_is_its_own(net, bus_name):
    """lss_allnodes 300 scans with a 300 ms step timeout (no device answers:
    the search takes at least that long) while line.lss.timeout_ms, which
    every other user of the line's LSS master gets, stays 40 throughout."""
    line = net.open_line(bus_name, mode="classic")
    line.lss.timeout_ms = 40
    server = AsciiGateway({1: line}).start_in_thread()
    seen = set()
    done = threading.Event()

    def watch():
        while not done.is_set():
            seen.add(line.lss.timeout_ms)
            time.sleep(0.002)

    watcher = threading.Thread(target=watch)
    watcher.start()
    try:
        client = Client(server.port)
        sent = time.monotonic()
        client.send("[1] lss_allnodes 300")
        assert client.answer() == "# Found 0 nodes, search finished."
        assert client.answer() == "[1] OK"
        assert time.monotonic() - sent >= 0.3
        client.close()
    finally:
        done.set()
        watcher.join()
        server.close()
    assert seen == {40}

def unconfigured_device(net, bus_name, identity):
    od = demo_od("classic")
    for sub, value in enumerate(identity, start=1):
        od[0x1018][sub].default = value
    return net.open_line(bus_name, mode="classic").create_local_node(255, od=od)


def lss_requests(bus: Recorder) -> List[bytes]:
    return [bytes(f.data) for f in bus.snapshot() if f.id == 0x7E5]


def fastscan_frames(address) -> List[bytes]:
    """What CiA 305 has the master send to find `address` alone (reset, 32
    bit checks per part, the bit-0 check naming the next part, a
    confirmation after a part ending in a 1-bit), written out here."""
    frames = [bytes((0x51, 0, 0, 0, 0, 0x80, 0, 0))]
    for part, value in enumerate(address):
        following = (part + 1) % 4
        for bit in range(31, -1, -1):
            above = value & ~((1 << (bit + 1)) - 1) & 0xFFFFFFFF
            frames.append(bytes((0x51,)) + above.to_bytes(4, "little") +
                          bytes((bit, part, following if bit == 0 else part)))
        if value & 1:
            frames.append(bytes((0x51,)) + value.to_bytes(4, "little") +
                          bytes((0, part, following)))
    return frames


def test_lss_fastscan_finds_one_device_and_leaves_it_selected(net, bus_name):
    """_lss_fastscan: the LSS address of an unconfigured device, found bit by
    bit (every frame on the bus as CiA 305 has it) and answered as
    CANopenNode's gateway does; the device stays in the configuration state
    without a node-id, so lss_set_node / lss_store go to it."""
    identity = (0x1A2, 0xBEEF01, 0x20003, 0x80000042)
    device = unconfigured_device(net, bus_name, identity)
    stored = Recorder()
    device.lss.on_store(stored)
    bus = Recorder()
    net.open_line(bus_name, mode="classic", monitor=True).on_frame(bus)
    line = net.open_line(bus_name, mode="classic")
    server = AsciiGateway({1: line}).start_in_thread()
    try:
        client = Client(server.port)
        assert client.ask("[1] _lss_fastscan 20") == \
            "[1] 0x000001A2 0x00BEEF01 0x00020003 0x80000042"
        expected = fastscan_frames(identity)
        assert len(expected) == 1 + 128 + 2     # product and revision end in a 1-bit
        bus.wait_for(lambda calls: len(lss_requests(bus)) >= len(expected),
                     what="the fast scan's frames")
        assert lss_requests(bus) == expected            # nothing configured, nothing else
        assert device.lss.info["state"] == "configuration"
        assert device.lss.info["pending"] == 255
        assert client.ask("[2] lss_set_node 12") == "[2] OK"
        assert client.ask("[3] lss_store") == "[3] OK"
        assert client.ask("[4] lss_switch_glob 0") == "[4] OK"
        client.wait_event("1 12 BOOT_UP")
        assert stored.snapshot() == [12]
        # configured now: nobody is left to find
        assert client.ask("[5] _lss_fastscan 5").startswith("[5] ERROR: 103 #Time-out")
        client.close()
    finally:
        server.close()


def test_lss_allnodes_with_scan_filters(net, bus_name):
    """lss_allnodes with the 11-number form: vendor matched (one frame with
    its value on the bus), revision ignored (reported 0, the product's bit-0
    check names the serial next): only the matching device gets a node-id,
    the other stays unconfigured."""
    wanted = unconfigured_device(net, bus_name, (0x1A2, 0xBEEF01, 0x20003, 0x80000042))
    other = unconfigured_device(net, bus_name, (0x1A3, 0xBEEF01, 0x20003, 0x80000001))
    bus = Recorder()
    net.open_line(bus_name, mode="classic", monitor=True).on_frame(bus)
    line = net.open_line(bus_name, mode="classic")
    server = AsciiGateway({1: line}).start_in_thread()
    try:
        client = Client(server.port)
        client.send("[1] lss_allnodes 20 20 0 2 0x1A2 0 0 1 0 0 0")
        assert client.answer() == "# Node-ID 20 assigned to: 0x000001A2 " \
                                            "0x00BEEF01 0x00000000 0x80000042"
        assert client.answer() == "# Found 1 nodes, search finished."
        assert client.answer() == "[1] OK"
        requests = lss_requests(bus)
        vendor = bytes((0x51, 0xA2, 0x01, 0, 0, 0, 0, 1))       # value, bit 0, part 0 -> 1
        assert requests[:2] == [bytes((0x51, 0, 0, 0, 0, 0x80, 0, 0)), vendor]
        assert bytes((0x51,)) + (0xBEEF01).to_bytes(4, "little") + bytes((0, 1, 3)) \
            in requests                                           # revision skipped
        assert not [r for r in requests if r[0] == 0x51 and r[6] == 2]   # never part 2
        assert bytes((0x11, 20, 0, 0, 0, 0, 0, 0)) in requests    # configure node-id 20
        # the second round: the reset answered by `other`, the vendor match is not
        assert requests[-2:] == [bytes((0x51, 0, 0, 0, 0, 0x80, 0, 0)), vendor]
        client.wait_event("1 20 BOOT_UP")
        assert wanted.lss.info["active"] == 20
        assert other.lss.info["pending"] == 255 and other.lss.info["active"] == 255
        client.close()
    finally:
        server.close()


def test_help_lists_the_commands(rig):
    client = rig[5]()
    client.send("[1] help")
    lines = []
    while not lines or not lines[-1].startswith("[1]"):
        lines.append(client.answer())
    assert lines[-1] == "[1] OK"
    assert any("r[ead] index sub [type]" in line for line in lines)
    client.send("[2] help datatype")
    assert client.answer().startswith("# b boolean")


def test_cli_gateway_until_sigterm(bus_name):
    """`canopenfd gateway --tcp 0`: prints where it listens, serves, and ends
    cleanly on SIGTERM with a status line."""
    process = subprocess.Popen(
        cli_command("gateway", "--channel", "mem:cli-gateway", "--tcp", "0", "--node-id", "3",
                    "--sdo-timeout", "50"),
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=package_env(),
        cwd=NEUTRAL_CWD)
    try:
        assert process.stdout is not None
        first = process.stdout.readline()
        assert "CiA 309-3 ASCII gateway on 127.0.0.1:" in first, first
        port = int(first.split("127.0.0.1:")[1].split(",")[0])
        client = Client(port)
        assert client.ask("[1] info version") == "[1] 0 0 0.0 0 3 3.0 0.1"
        assert client.ask("[2] 5 r 0x1000 0") == "[2] ERROR: 0x05040000 #SDO protocol timed out"
        client.close()
        process.send_signal(signal.SIGTERM)
        out, err = process.communicate(timeout=scaled(20))
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()
    assert process.returncode == 0, err
    assert "gateway stopped: 1 clients, 2 requests, 1 errors" in out


def test_client_limit_and_arguments(net, bus_name):
    """A client past max_clients is told why (600) and closed; wrong
    construction arguments raise naming the problem."""
    line = net.open_line(bus_name)
    server = AsciiGateway({1: line}, max_clients=1).start_in_thread()
    try:
        first = Client(server.port)
        assert first.ask("[1] set node 5") == "[1] OK"
        second = Client(server.port)
        assert second.line() == "[0] ERROR: 600 #Running out of memory: 1 clients already"
        with pytest.raises(EOFError):
            second.line()
        second.close()
        assert first.ask("[2] info version").startswith("[2] 0 0 0.0 0 3 3.0 ")
        first.close()
    finally:
        server.close()
    from canopenfd import CanopenFDError
    with pytest.raises(CanopenFDError, match="net id 0 is not 1..127"):
        AsciiGateway({0: line})
    with pytest.raises(CanopenFDError, match="net 1 is 'x', not a Line"):
        AsciiGateway({1: "x"})  # type: ignore[dict-item]
    with pytest.raises(CanopenFDError, match="no networks"):
        AsciiGateway({})
    with pytest.raises(CanopenFDError, match="sdo_timeout_ms 0 outside 1..65535"):
        AsciiGateway({1: line}, sdo_timeout_ms=0)


@pytest.mark.parametrize("command, status, error, code", [
    ("lss_set_node", "REFUSED", 1, 502),
    ("lss_conf_bitrate", "REFUSED", 1, 503),
    ("lss_store", "REFUSED", 1, 504),
    ("lss_allnodes", "REFUSED", 1, 504),
    ("lss_store", "REFUSED", 2, 505),
    ("lss_set_node", "REFUSED", 0xFF, 501),
    ("lss_get_node", "TIMEOUT", 0, 103),
    ("lss_allnodes", "DUPLICATE", 0, 102),
])
def test_lss_failures_as_cia_309_3_codes(command, status, error, code):
    """The LSS master's outcomes the device-driven tests cannot all provoke
    (media error, manufacturer-specific refusal, duplicate address)."""
    from canopenfd._binding.constants import LssStatus
    from canopenfd.gateway.ascii309_server import lss_error_code
    from canopenfd.services.lss import LssError
    assert lss_error_code(command, LssError("x", LssStatus[status], error)) == code


def test_lss_configuration_belongs_to_one_client(net, bus_name):
    """A client that switched devices into LSS configuration holds the net's
    LSS until it switches them back to waiting or leaves: another client's
    LSS request is refused (102) with nothing sent, so it can never act on
    devices the first one selected (before: its lss_switch_glob 1 went out
    and a following lss_set_node would have renumbered every device); the
    owner leaving switches the devices back to waiting."""
    line, frames = lss_rig(net, bus_name)

    def lss_frames():
        # the command specifier, with its mode for a global switch
        return [bytes(f.data[:2] if f.data[0] == 0x04 else f.data[:1])
                for f in frames.snapshot() if f.id == 0x7E5]

    server = AsciiGateway({1: line}).start_in_thread()
    try:
        owner, other = Client(server.port), Client(server.port)
        assert owner.ask("[1] lss_switch_sel 0x1A2 0xBEEF01 0x20003 0x80000001") == "[1] OK"
        refused = other.ask("[1] lss_switch_glob 1")
        assert refused.startswith("[1] ERROR: 102 #") and "another client" in refused
        assert other.ask("[2] lss_set_node 9").startswith("[2] ERROR: 102 #")
        assert owner.ask("[2] lss_get_node") == "[2] 0x07"
        assert owner.ask("[3] lss_switch_glob 0") == "[3] OK"
        frames.wait_for(lambda c: b"\x04\x00" in lss_frames() or None, 5, "switch to waiting")
        # the selective switch (0x40..0x43), the inquiry (0x5E), back to waiting: no 0x04 01
        assert lss_frames() == [b"\x40", b"\x41", b"\x42", b"\x43", b"\x5e", b"\x04\x00"]
        assert other.ask("[3] lss_switch_glob 1") == "[3] OK"      # free again
        assert owner.ask("[4] lss_switch_glob 0").startswith("[4] ERROR: 102 #")
        other.close()                                   # leaves: devices back to waiting
        frames.wait_for(lambda c: lss_frames()[-1:] == [b"\x04\x00"] and
                        lss_frames().count(b"\x04\x00") == 2 or None, 5, "waiting again")
        assert owner.ask("[5] lss_switch_glob 1") == "[5] OK"
        owner.close()
    finally:
        server.close()
