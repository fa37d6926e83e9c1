"""The CANopen API of seed 004 over a byte stream (a pty and a Unix socket),
byte for byte: every request and its answer, every indication, refused
frames NAKed and counted, accesses past the image; the task serves a node
on a `mem:` line, so PDOs and SDO writes reach the image through the stack.
Then the `ProcessImage` host object over the same link."""

from __future__ import annotations

import os
import socket
import time
import tty
from typing import Any, Iterator, List, NamedTuple

import pytest
from helpers import Recorder, scaled
from processimage_helpers import setup_text

import canopenfd
from canopenfd.gateway.remote_access_stream import FdStream
from canopenfd.processimage.host import ProcessImage
from canopenfd.processimage.setup_file import parse_setup_text
from canopenfd.processimage.task import ProcessImageTask

NODE = 0x40


class RawHost:
    """The host end as bytes: what the task sends is read with a deadline."""

    def __init__(self, fd: int, owner: Any = None) -> None:
        self.fd = fd
        self.owner = owner
        self.buffer = bytearray()

    def send(self, data: bytes) -> None:
        os.write(self.fd, data)

    def expect(self, data: bytes, timeout: float = 3.0) -> None:
        deadline = time.monotonic() + scaled(timeout)
        while len(self.buffer) < len(data) and time.monotonic() < deadline:
            import select
            ready, _, _ = select.select([self.fd], [], [], 0.05)
            if ready:
                self.buffer += os.read(self.fd, 4096)
        got, self.buffer = bytes(self.buffer[:len(data)]), self.buffer[len(data):]
        assert got == data, f"expected {data!r}, got {got!r}"

    def quiet(self, seconds: float = 0.2) -> None:
        """Nothing more arrives within `seconds`."""
        import select
        ready, _, _ = select.select([self.fd], [], [], seconds)
        extra = os.read(self.fd, 4096) if ready else b""
        assert not self.buffer and not extra, f"unexpected {bytes(self.buffer) + extra!r}"

    def close(self) -> None:
        if self.owner is not None:
            self.owner.close()
        else:
            os.close(self.fd)


class World(NamedTuple):
    net: Any
    line: Any
    peer: Any                # another line on the bus (the network side)
    bus: Recorder            # every frame
    task: ProcessImageTask
    host: RawHost


def link_pair(kind: str) -> Any:
    """(task stream, host fd, host owner) of a pty or a Unix socket pair."""
    if kind == "pty":
        master, slave = os.openpty()
        tty.setraw(master)
        tty.setraw(slave)
        return FdStream(master, "pty master"), slave, None
    task_sock, host_sock = socket.socketpair(socket.AF_UNIX, socket.SOCK_STREAM)
    return FdStream(task_sock.fileno(), "unix", owner=task_sock), host_sock.fileno(), host_sock


@pytest.fixture(params=["pty", "unix"])
def world(request: pytest.FixtureRequest, net: Any, bus_name: str) -> Iterator[World]:
    line = net.open_line(bus_name, mode="classic")
    peer = net.open_line(bus_name, mode="classic")
    bus = Recorder()
    net.open_line(bus_name, mode="classic", monitor=True).on_frame(bus)
    stream, fd, owner = link_pair(request.param)
    task = ProcessImageTask(line, parse_setup_text(setup_text(), "dev.txt"), stream,
                            frame_timeout=0.3)
    host = RawHost(fd, owner)
    try:
        yield World(net, line, peer, bus, task, host)
    finally:
        task.close()
        host.close()


def frames(bus: Recorder, can_id: int) -> List[bytes]:
    return [bytes(f.data) for f in bus.snapshot() if f.id == can_id]


def init(w: World) -> None:
    w.host.send(b"I\x00\x00;")
    w.host.expect(b".")
    w.host.expect(b"n\x00.")                  # NMTChange: initialising
    w.host.expect(b"n\x7f.")                  # then pre-operational
    w.bus.wait_for(lambda calls: frames(w.bus, 0x700 + NODE) == [b"\x00"], what="boot-up")


def start(w: World) -> None:
    init(w)
    w.peer.nmt.send("START", NODE)
    w.host.expect(b"n\x05.")


def test_get_id_and_status_before_init(world: World) -> None:
    world.host.send(b"V;")
    world.host.expect(b"\x34\x12\x02\x01.")   # [ID] as configured
    world.host.send(b"S;")
    world.host.expect(b"\x01.")               # ready, waiting for InitCANopen; 32-byte class
    assert world.bus.snapshot() == []         # nothing on the bus before InitCANopen


def test_read_and_write_with_counts(world: World) -> None:
    h = world.host
    h.send(b"R\x00\x08;")
    h.expect(b"\x08\x00\x11\x22\x33\x44\x55\x66\x77.")     # [PIMG]
    h.send(b"R\x06\x05;")
    h.expect(b"\x02\x66\x77.")                # only 2 bytes left in the image
    h.send(b"R\x08\x01;")
    h.expect(b"\x00!")                        # past the end: 0 bytes, NAK
    h.send(b"R\xff\xff;")
    h.expect(b"\x00!")
    h.send(b"W\x07\x02\xaa\xbb;")
    h.expect(b"\x01.")                        # one byte fitted
    h.send(b"W\x09\x01\x3b;")                 # (';' as data is data)
    h.expect(b"\x00!")
    h.send(b"R\x04\x04;")
    h.expect(b"\x04\x44\x55\x66\xaa.")
    assert world.task.stats["accepted"] == 7


def test_init_reports_nmt_and_keeps_written_bytes(world: World) -> None:
    world.host.send(b"W\x02\x02\x3b\x3c;")   # before InitCANopen, into [6200,01..02]
    world.host.expect(b"\x02.")
    init(world)
    world.host.send(b"S;")
    world.host.expect(b"\x02.")               # operating
    world.host.send(b"R\x00\x04;")
    world.host.expect(b"\x04\x00\x11\x3b\x3c.")
    assert world.task.node[(0x6200, 1)].raw == 0x3B


def test_init_refuses_out_of_range(world: World) -> None:
    world.host.send(b"I\x09\x00;")            # bps 1..8 or 0
    world.host.expect(b"!")
    world.host.send(b"I\x00\x80;")            # node-id 1..127 or 0
    world.host.expect(b"!")
    init(world)
    world.host.send(b"I\x00\x80;")
    world.host.expect(b"!")
    world.host.quiet()


def test_init_again_with_a_new_node_id(world: World) -> None:
    """Seed 004 §4.1.3: InitCANopen on a running task re-initialises it, with
    the new node-id: boot-up, PDO COB-IDs ($NODEID) and SDO server follow."""
    start(world)
    world.host.send(b"I\x00\x05;")            # node 0x40 runs: re-initialise as 5
    world.host.expect(b".")
    world.host.expect(b"n\x00.n\x7f.")         # no 81h: the host asked for this reset
    world.bus.wait_for(lambda calls: frames(world.bus, 0x705) == [b"\x00"],
                       what="boot-up of node 5")
    assert world.task.node is not None and world.task.node.node_id == 5
    assert world.task.node_id == 5
    assert world.peer.sdo.upload(5, 0x1000, 0) == b"\x91\x01\x0f\x00"
    world.peer.nmt.send("START", 5)
    world.host.expect(b"n\x05.")
    world.peer.send_frame(0x205, b"\xb1\xb2")   # RPDO 1 under the new node-id
    world.host.expect(b"d\x02\x02.")
    world.host.send(b"W\x00\x02\x10\x20;")
    world.host.expect(b"\x02.")
    world.bus.wait_for(lambda calls: b"\x10\x20" in frames(world.bus, 0x185),
                       what="TPDO 1 under the new node-id")
    assert b"\x10\x20" not in frames(world.bus, 0x180 + NODE)


def test_nmt_changes_from_the_network(world: World) -> None:
    start(world)
    world.peer.nmt.send("STOP", NODE)
    world.host.expect(b"n\x04.")
    world.peer.nmt.send("PRE_OPERATIONAL", NODE)
    world.host.expect(b"n\x7f.")
    world.peer.nmt.send("RESET_COMMUNICATION", NODE)
    world.host.expect(b"n\x00.n\x82.n\x7f.")      # initialising, the reset, boot-up
    world.peer.nmt.send("RESET_NODE", NODE)
    world.host.expect(b"n\x00.n\x81.n\x7f.")


def test_reinit_resets_the_node_and_the_image(world: World) -> None:
    start(world)
    world.host.send(b"W\x02\x06\x01\x02\x03\x04\x05\x06;")
    world.host.expect(b"\x06.")
    world.host.send(b"I\x04\x00;")            # again: re-initialise
    world.host.expect(b".")
    world.host.expect(b"n\x00.n\x7f.")         # no 81h: the host asked for this reset
    world.host.send(b"R\x00\x08;")
    world.host.expect(b"\x08\x00\x11\x22\x33\x44\x55\x66\x77.")   # [PIMG] again
    assert world.task.bps == 4


def test_rpdo_gives_one_received_data_indication(world: World) -> None:
    start(world)
    world.peer.send_frame(0x200 + NODE, b"\xa1\xa2")
    world.host.expect(b"d\x02\x02.")          # bytes 2..3 in one indication
    world.host.send(b"R\x02\x02;")
    world.host.expect(b"\x02\xa1\xa2.")


def test_sdo_write_gives_received_data(world: World) -> None:
    init(world)
    world.peer.sdo.download(NODE, 0x6200, 2, b"\x5a")
    world.host.expect(b"d\x03\x01.")
    world.host.send(b"R\x03\x01;")
    world.host.expect(b"\x01\x5a.")


def test_write_sends_the_tpdo_once_with_every_byte(world: World) -> None:
    start(world)
    before = len(frames(world.bus, 0x180 + NODE))
    world.host.send(b"W\x00\x02\x10\x20;")      # two entries of TPDO 1 change
    world.host.expect(b"\x02.")
    world.bus.wait_for(lambda calls: b"\x10\x20" in frames(world.bus, 0x180 + NODE),
                       what="TPDO 1 with the written bytes")
    time.sleep(scaled(0.2))
    assert frames(world.bus, 0x180 + NODE)[before:] == [b"\x10\x20"]


def test_bad_frames_are_naked_and_counted(world: World) -> None:
    h = world.host
    h.send(b"X12;")
    h.expect(b"!")                            # unknown code
    h.send(b"R\x01;V;")                       # cut short: NAK, then V is served
    h.expect(b"\x00!")
    h.expect(b"\x34\x12\x02\x01.")
    h.send(b"S5;")                            # S takes no parameters
    h.expect(b"!")
    h.send(b"W\x00\x03\x01")                  # no more bytes: refused after the timeout
    h.expect(b"\x00!", timeout=3.0)
    h.send(b"S;")
    h.expect(b"\x01.")
    stats = world.task.stats
    assert (stats["refused unknown code"], stats["refused no terminator"],
            stats["refused incomplete"]) == (1, 2, 1)
    assert stats["accepted"] == 2


def test_fatal_error_when_the_stack_closes(world: World) -> None:
    init(world)
    world.net.close()
    world.host.send(b"R\x02\x01;")
    world.host.expect(b"\x00!")
    world.host.expect(b"f\x03.")


def test_host_object_drives_the_task(world: World) -> None:
    fd = os.dup(world.host.fd)
    with ProcessImage(FdStream(fd, "host")) as image:
        received = Recorder()
        states = Recorder()
        image.on_received_data(lambda offset, length: received((offset, length)))
        image.on_nmt_change(states)
        assert image.get_id() == b"\x34\x12\x02\x01"
        assert image.get_status() == 0x01
        assert image.read(6, 4) == b"\x66\x77"
        assert image.read(8, 1) == b""
        assert image.write(4, b"\x64\x66\x6e") == 3     # bytes that look like 'd', 'f', 'n'
        assert image.read(4, 3) == b"\x64\x66\x6e"
        assert image.init_canopen(0, 0) is True
        states.wait_value(0x7F)
        world.peer.nmt.send("START", NODE)
        states.wait_value(0x05)
        world.peer.send_frame(0x200 + NODE, b"\x01\x02")
        received.wait_value((2, 2))
        assert image.read(2, 2) == b"\x01\x02"
        assert image.init_canopen(9, 0) is False
        with pytest.raises(ValueError, match=r"ProcessImage.write: length of data 256 is not "
                                             r"a byte 0..255"):
            image.write(0, bytes(256))
        with pytest.raises(ValueError, match=r"ProcessImage.read: offset -1"):
            image.read(-1, 1)
        assert image.dropped == 0


def test_rpdo_to_scattered_bytes_gives_one_indication_per_run(net: Any, bus_name: str) -> None:
    """Seed 004 §4.2.2 NOTE: an RPDO whose bytes land apart in the image gives
    an indication per consecutive run (here 6200:01 at byte 2, 6200:02 at 5)."""
    text = setup_text(RWOD=["0060015100", "0060025101", "006201F102", "006202F105",
                            "FFFFFFFFFF"])
    line = net.open_line(bus_name, mode="classic")
    peer = net.open_line(bus_name, mode="classic")
    stream, fd, owner = link_pair("unix")
    task = ProcessImageTask(line, parse_setup_text(text, "scattered.txt"), stream)
    host = RawHost(fd, owner)
    try:
        host.send(b"I\x00\x00;")
        host.expect(b".n\x00.n\x7f.")
        peer.nmt.send("START", NODE)
        host.expect(b"n\x05.")
        peer.send_frame(0x200 + NODE, b"\x0b\x0e")
        host.expect(b"d\x02\x01.d\x05\x01.")
        host.send(b"R\x02\x04;")
        host.expect(b"\x04\x0b\x33\x44\x0e.")
        assert task.stats["indications"] == 5
    finally:
        task.close()
        host.close()
