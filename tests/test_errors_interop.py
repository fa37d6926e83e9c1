"""Error-report bits as a classic peer sees them: python-canopen (PyPI
`canopen`, an independent implementation) consumes our node's EMCYs with its
EMCY consumer and reads 0x1001, 0x1003 and the bit array 0x2100 with its SDO
client, over python-can's virtual bus; its raw subscription checks the bytes.
An SRDO's safe state is heard the same way: raised, then reset."""

from __future__ import annotations

import itertools
import os
import threading
import time

import pytest
from helpers import scaled, virtual_bus
from test_errors import error_od

import canopenfd
from canopenfd.services.errors import ErrorRegister

canopen = pytest.importorskip("canopen")

NODE = 5
_channels = itertools.count(1)


class Frames:
    """Frames python-canopen's network hands a subscriber (its own thread)."""

    def __init__(self) -> None:
        self.data = []
        self.cond = threading.Condition()

    def __call__(self, can_id, data, timestamp) -> None:
        with self.cond:
            self.data.append(bytes(data))
            self.cond.notify_all()

    def wait(self, count: int, timeout: float = 5.0):
        deadline = time.monotonic() + scaled(timeout)
        with self.cond:
            while len(self.data) < count:
                remaining = deadline - time.monotonic()
                assert remaining > 0, f"{len(self.data)} EMCY frames, not {count}"
                self.cond.wait(remaining)
            return list(self.data)


def logged(remote, count: int, timeout: float = 5.0):
    """python-canopen's EMCY log once it holds `count` entries (its wait()
    hears only EMCYs arriving after the call: polling avoids that race)."""
    deadline = time.monotonic() + scaled(timeout)
    while len(remote.emcy.log) < count:
        assert time.monotonic() < deadline, f"python-canopen logged {remote.emcy.log}"
        time.sleep(0.01)
    return list(remote.emcy.log)


@pytest.fixture
def rig():
    channel = f"errors-{os.getpid()}-{next(_channels)}"
    peer = canopen.Network()
    peer.connect(interface="virtual", channel=channel)
    try:
        with canopenfd.Network() as net:
            line = net.open_line(bus=virtual_bus(channel), mode="classic")
            me = line.create_local_node(NODE, od=error_od("classic"))
            me.errors.expose(0x2100)
            yield peer, me
    finally:
        peer.disconnect()


def test_python_canopen_sees_error_bits_emcy_register_history(rig):
    peer, me = rig
    remote = peer.add_node(NODE, canopen.ObjectDictionary())
    frames = Frames()
    peer.subscribe(0x80 + NODE, frames)
    me.errors.define(18, 0x3210, ErrorRegister.VOLTAGE)

    assert me.errors.report(18, 0xBEEF) is True
    assert me.errors.report(18, 0xBEEF) is False        # not sent again
    error = logged(remote, 1)[0]
    assert (error.code, error.register, error.data) == (0x3210, 0x05, b"\x12\xef\xbe\x00\x00")
    assert [e.code for e in remote.emcy.active] == [0x3210]
    assert remote.sdo.upload(0x1001, 0) == b"\x05"
    assert remote.sdo.upload(0x1003, 0) == b"\x01"
    assert remote.sdo.upload(0x1003, 1) == (0xEF123210).to_bytes(4, "little")
    assert remote.sdo.upload(0x2100, 0) == bytes([0, 0, 0x04]) + bytes(13)

    assert me.errors.reset(18, 1) is True
    reset = logged(remote, 2)[1]
    assert (reset.code, reset.register, reset.data) == (0, 0, b"\x12\x01\x00\x00\x00")
    assert remote.emcy.active == []                      # python-canopen: code 0 clears
    assert frames.wait(2) == [bytes.fromhex("10 32 05 12 ef be 00 00"),
                              bytes.fromhex("00 00 00 12 01 00 00 00")]
    assert remote.sdo.upload(0x1001, 0) == b"\x00"
    assert remote.sdo.upload(0x2100, 0) == bytes(16)
    assert len(frames.data) == 2


def test_python_canopen_hears_an_srdo_safe_state_raised_and_reset(rig):
    from test_srdo_emcy import SCT, start_consumer
    peer, me = rig
    remote = peer.add_node(NODE, canopen.ObjectDictionary())
    start_consumer(me)                                   # its SCT runs out: safe state
    error = logged(remote, 1)[0]
    assert (error.code, error.register, error.data) == (0x8200, 0x11, bytes([1, SCT, 0, 0, 0]))
    assert [e.code for e in remote.emcy.active] == [0x8200]
    assert remote.sdo.upload(0x1001, 0) == b"\x11"
    me.apply("pre-operational")                          # leaving OPERATIONAL ends it
    reset = logged(remote, 2)[1]
    assert (reset.code, reset.register, reset.data) == (0, 0, bytes([1, SCT, 0, 0, 0]))
    assert remote.emcy.active == []                      # python-canopen: code 0 clears
    assert remote.sdo.upload(0x1001, 0) == b"\x00"
