"""Error-report bits and the EMCY code table on real kernel SocketCAN (vcan).

Classic line: python-canopen (PyPI `canopen`, over python-can's socketcan
interface) consumes our node's EMCYs and reads 0x1001, 0x1003 and the bit
array 0x2100 by SDO; a raw python-can socket checks the 8 bytes. FD line: our
own fd peer line consumes the extended EMCYs and reads the same entries by
USDO; a raw FD socket checks the 20 bytes. Needs CANOPENFD_VCAN (see
tests/conftest.py); tests/vm/run_in_vm.sh provides it."""

from __future__ import annotations

import time

import pytest
from helpers import Recorder, scaled
from test_errors import emcy_bytes, error_od
from test_errors_interop import logged
from test_vcan_services import networks, raw_buses, recv_all  # noqa: F401 (fixtures)

from canopenfd.services.errors import ErrorRegister

pytestmark = pytest.mark.vcan
canopen = pytest.importorskip("canopen")

NODE = 5
EMCY = 0x80 + NODE
OVER_CURRENT, UNDER_VOLTAGE = 20, 18        # the application's error ids (bits)


@pytest.fixture
def ifaces(vcan):
    return {"fd": vcan[0], "classic": vcan[2]}


def device_on(networks, channel, mode):
    """Our local node with the error OD, its code table and the exposed bits."""
    me = networks().open_line(channel, mode=mode).create_local_node(NODE, od=error_od(mode))
    me.errors.expose(0x2100)
    me.errors.define(OVER_CURRENT, 0x2310, ErrorRegister.CURRENT)
    me.emcy.define(UNDER_VOLTAGE, 0x3220, ErrorRegister.VOLTAGE)
    return me


def quiet(bus, can_id, seconds=0.3):
    """True when no frame with can_id arrives on the raw bus for `seconds`."""
    deadline = time.monotonic() + scaled(seconds)
    while (remaining := deadline - time.monotonic()) > 0:
        msg = bus.recv(remaining)
        assert msg is None or msg.arbitration_id != can_id, f"unexpected {msg}"
    return True


def test_classic_python_canopen_sees_bits_emcy_register_history(ifaces, networks, raw_buses):
    raw = raw_buses(ifaces["classic"], fd=False)
    peer = canopen.Network()
    peer.connect(interface="socketcan", channel=ifaces["classic"])
    try:
        me = device_on(networks, ifaces["classic"], "classic")
        remote = peer.add_node(NODE, canopen.ObjectDictionary())

        assert me.errors.report(OVER_CURRENT, 0xBEEF) is True
        assert me.errors.report(OVER_CURRENT, 0x1111) is False       # repeat: counted only
        assert me.emcy.raise_defined(UNDER_VOLTAGE, 0x0007) is True
        first, second = logged(remote, 2)
        assert (first.code, first.register, first.data) == (0x2310, 0x03, b"\x14\xef\xbe\x00\x00")
        assert (second.code, second.register, second.data) == \
            (0x3220, 0x07, b"\x12\x07\x00\x00\x00")
        assert sorted(e.code for e in remote.emcy.active) == [0x2310, 0x3220]
        assert remote.sdo.upload(0x1001, 0) == b"\x07"
        assert remote.sdo.upload(0x1003, 0) == b"\x02"
        assert remote.sdo.upload(0x1003, 1) == (0x07123220).to_bytes(4, "little")   # newest
        assert remote.sdo.upload(0x1003, 2) == (0xEF142310).to_bytes(4, "little")
        assert remote.sdo.upload(0x2100, 0) == bytes([0, 0, 0x14]) + bytes(13)
        assert me.errors.count(OVER_CURRENT) == 2

        assert me.errors.reset(OVER_CURRENT, 0x0042) is True
        assert me.errors.reset(OVER_CURRENT) is False                 # clear already
        reset = logged(remote, 3)[2]
        assert (reset.code, reset.register, reset.data) == (0, 0x05, b"\x14\x42\x00\x00\x00")
        assert remote.sdo.upload(0x1001, 0) == b"\x05"
        assert remote.sdo.upload(0x2100, 0) == bytes([0, 0, 0x04]) + bytes(13)

        wire = [bytes(msg.data) for msg in recv_all(raw, EMCY, 3)]
        assert wire == [emcy_bytes(False, 0x2310, 0x03, OVER_CURRENT, 0xBEEF),
                        emcy_bytes(False, 0x3220, 0x07, UNDER_VOLTAGE, 0x0007),
                        emcy_bytes(False, 0x2310, 0x05, OVER_CURRENT, 0x0042, occurred=False)]
        assert wire[0].hex(" ") == "10 23 03 14 ef be 00 00"
        assert quiet(raw, EMCY) and len(remote.emcy.log) == 3        # nothing more sent
    finally:
        peer.disconnect()


def test_fd_peer_line_sees_extended_emcy_and_reads_by_usdo(ifaces, networks, raw_buses):
    raw = raw_buses(ifaces["fd"])
    me = device_on(networks, ifaces["fd"], "fd")
    tool = networks().open_line(ifaces["fd"], mode="fd").add_node(NODE, od=error_od("fd"))
    heard = Recorder()
    tool.emcy.add_callback(heard)

    assert me.errors.report(OVER_CURRENT, 0xBEEF) is True
    assert me.errors.report(OVER_CURRENT) is False
    assert me.emcy.raise_defined(UNDER_VOLTAGE, 0x0007) is True
    assert me.errors.reset(OVER_CURRENT, 0x0042) is True

    frames = recv_all(raw, EMCY, 3)
    assert all(msg.is_fd and len(msg.data) == 20 for msg in frames)
    assert [bytes(msg.data) for msg in frames] == [
        emcy_bytes(True, 0x2310, 0x03, OVER_CURRENT, 0xBEEF),
        emcy_bytes(True, 0x3220, 0x07, UNDER_VOLTAGE, 0x0007),
        emcy_bytes(True, 0x2310, 0x05, OVER_CURRENT, 0x0042, occurred=False)]
    assert bytes(frames[2].data).hex(" ") == ("10 23 05 14 42 00 00 00 00 2d 01 00 "
                                              "00 00 00 00 00 00 00 00")
    got = heard.wait_count(3)
    assert [(e.code, e.register, e.data, e.fd, e.spec_number, e.occurred) for e in got] == [
        (0x2310, 0x03, b"\x14\xef\xbe\x00\x00", True, 301, True),
        (0x3220, 0x07, b"\x12\x07\x00\x00\x00", True, 301, True),
        (0x2310, 0x05, b"\x14\x42\x00\x00\x00", True, 301, False)]
    assert got[2].removed

    assert tool.usdo.upload((0x1001, 0)) == b"\x05"
    assert tool.usdo.upload((0x1003, 0)) == b"\x02"
    assert tool.usdo.upload((0x1003, 1)) == (0x07123220).to_bytes(4, "little")
    assert tool.usdo.upload((0x2100, 0)) == bytes([0, 0, 0x04]) + bytes(13)
    assert me.errors.set_bits == [UNDER_VOLTAGE]
    assert quiet(raw, EMCY) and len(heard) == 3                  # nothing more sent
