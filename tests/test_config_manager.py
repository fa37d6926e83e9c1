"""The configuration manager through Python (line.manager, CO_EV_CONFIG):
over an in-process bus against our own local node (classic SDO and fd USDO:
the frames on the bus, skip when 0x1020 matches, a refused entry, a silent
node, await, cancel), and against python-canopen's LocalNode on a
python-can virtual bus as the configured slave (classic SDO)."""

from __future__ import annotations

import asyncio
import itertools
import os
import time

import pytest

import canopenfd
from canopenfd import ConfigurationError
from canopenfd.od import DataType, ODVariable, demo_od
from canopenfd.od.concise import ConciseDcfError, build_concise
from canopenfd.services.config import ConfigOutcome
from helpers import Recorder, scaled, virtual_bus
from dcf_helpers import device_od, make_dcf, stamp_object

NODE = 5
DATE, TIME = 0x11223344, 0x55667788
_channels = itertools.count(1)


def fd_device_od():
    od = demo_od("fd")
    od.add_object(stamp_object())
    od.add_object(ODVariable("Read only", 0x2F02, 0, DataType.UNSIGNED32, "ro", 7))
    return od


@pytest.fixture(params=["classic", "fd"])
def rig(request, net, bus_name):
    mode = request.param
    node = net.open_line(bus_name, mode=mode).create_local_node(
        NODE, od=device_od() if mode == "classic" else fd_device_od())
    line = net.open_line(bus_name, mode=mode)
    frames = Recorder()
    net.open_line(bus_name, mode=mode, monitor=True).on_frame(frames)
    return mode, node, line, frames


def requests_to_node(frames, mode):
    """Requests our client sent (classic: 0x600 + node; fd: 0x600 + 127 with
    byte 0 = node), aborts left out."""
    out = []
    for call in frames.calls:
        f = call[0] if isinstance(call, tuple) else call
        if mode == "classic" and f.id == 0x600 + NODE and f.data[0] != 0x80:
            out.append(f)
        if mode == "fd" and f.id == 0x600 + 127 and f.data[0] == NODE and f.data[1] != 0x7F:
            out.append(f)
    return out


def test_configures_then_skips(rig):
    mode, node, line, frames = rig
    dcf = build_concise([(0x1017, 0, b"\xfa\x00"), (0x2F00 if mode == "classic" else 0x1017,
                                                   0, b"axis 1" if mode == "classic"
                                                   else b"\xfb\x00")])
    result = line.manager.configure(NODE, dcf, expected=(DATE, TIME)).result(5)
    assert result.outcome is ConfigOutcome.OK and result.ok
    assert result.written == 2 and result.failed == 0
    assert [e[:2] for e in result.entries][-2:] == [(0x1020, 1), (0x1020, 2)]
    assert all(abort == 0 for _, _, abort in result.entries)
    assert node[0x1020][1].raw == DATE and node[0x1020][2].raw == TIME
    assert str(result) == f"node {NODE}: configured, 2 entries written"
    # the monitor hears the frames on the dispatcher thread: wait for the stamp
    stamp = (lambda f: bytes(f.data[:4]) == bytes([0x23, 0x20, 0x10, 0x02])) \
        if mode == "classic" else \
        (lambda f: f.data[1] == 0x01 and bytes(f.data[3:6]) == b"\x02\x20\x10")
    frames.wait_for(lambda _: any(stamp(f) for f in requests_to_node(frames, mode)), 5,
                    "the stamp's download on the bus")
    sent = requests_to_node(frames, mode)
    # first the upload of 0x1020:01, then the downloads, stamp last
    if mode == "classic":
        assert bytes(sent[0].data) == bytes([0x40, 0x20, 0x10, 0x01, 0, 0, 0, 0])
        assert bytes(sent[1].data) == bytes([0x2B, 0x17, 0x10, 0x00, 0xFA, 0x00, 0, 0])
        assert bytes(sent[-1].data) == bytes([0x23, 0x20, 0x10, 0x02]) + TIME.to_bytes(4, "little")
    else:
        assert sent[0].data[1] == 0x11 and bytes(sent[0].data[3:6]) == b"\x01\x20\x10"
        assert sent[1].data[1] == 0x01 and bytes(sent[1].data[3:10]) == \
            b"\x00\x17\x10\x0f\x02\xfa\x00"
    before = len(sent)
    again = line.manager.configure(NODE, dcf, expected=(DATE, TIME)).result(5)
    assert again.outcome is ConfigOutcome.SKIPPED and again.ok and again.entries == []
    frames.wait_for(lambda _: len(requests_to_node(frames, mode)) >= before + 2, 5,
                    "the two uploads of 0x1020")
    time.sleep(scaled(0.05))
    assert len(requests_to_node(frames, mode)) == before + 2     # two uploads, no download


def test_refused_entries_and_silent_node(rig):
    mode, node, line, _ = rig
    ro = 0x1018 if mode == "classic" else 0x2F02
    dcf = build_concise([(0x1017, 0, b"\x10\x00"), (0x3000, 7, b"\x01"), (0x1017, 0, b"\x11\x00")])
    result = line.manager.configure(NODE, dcf).result(5)
    assert result.outcome is ConfigOutcome.FAILED and not result.ok
    assert (result.index, result.subindex, result.abort_code, result.from_node) == \
        (0x3000, 7, 0x06020000, True)
    assert result.entries == [(0x1017, 0, 0), (0x3000, 7, 0x06020000)]
    assert "at 0x3000:07: abort 0x06020000" in str(result)
    assert node[0x1017].raw == 0x10
    result = line.manager.configure(NODE, dcf, continue_on_error=True).result(5)
    assert result.outcome is ConfigOutcome.FAILED and result.written == 2
    assert node[0x1017].raw == 0x11
    sub = 1 if mode == "classic" else 0
    result = line.manager.configure(NODE, build_concise([(ro, sub, b"\x01\x00\x00\x00")])
                                    ).result(5)
    assert (result.index, result.abort_code) == (ro, 0x06010002)
    silent = line.manager.configure(42, dcf, expected=(1, 2), timeout_ms=100).result(5)
    assert silent.outcome is ConfigOutcome.TIMEOUT
    assert (silent.index, silent.subindex, silent.abort_code, silent.from_node) == \
        (0x1020, 1, 0x05040000, False)


def test_await_and_cancel(rig):
    mode, node, line, _ = rig
    dcf = build_concise([(0x1017, 0, b"\x21\x00")])

    async def main():
        return await line.manager.configure(NODE, dcf)
    assert asyncio.run(main()).outcome is ConfigOutcome.OK
    assert node[0x1017].raw == 0x21
    job = line.manager.configure(43, dcf, timeout_ms=5000)
    job.cancel()
    assert job.result(5).outcome is ConfigOutcome.CANCELLED


def test_from_a_dcf_file(net, bus_name, tmp_path):
    """A DCF path: converted on the way, its own 0x1020 values are the stamp."""
    node = net.open_line(bus_name, mode="classic").create_local_node(NODE, od=device_od())
    line = net.open_line(bus_name, mode="classic")
    result = line.manager.configure(NODE, make_dcf(tmp_path)).result(5)
    assert result.outcome is ConfigOutcome.OK and result.written == 10
    assert node[0x1800][1].raw == 0x185 and node[0x1A00][0].raw == 2
    assert node[0x2F00].raw == "axis 1"
    assert (node[0x1020][1].raw, node[0x1020][2].raw) == (0x4A5B, 0x01234567)
    assert line.manager.configure(NODE, make_dcf(tmp_path)).result(5).outcome is \
        ConfigOutcome.SKIPPED
    # expected=False: no stamp, written again
    assert line.manager.configure(NODE, make_dcf(tmp_path), expected=False).result(5).outcome \
        is ConfigOutcome.OK


def test_bad_arguments_are_refused_before_anything_is_sent(net, bus_name, tmp_path):
    line = net.open_line(bus_name, mode="classic")
    good = build_concise([(0x1017, 0, b"\x01\x00")])
    with pytest.raises(ConciseDcfError, match="concise DCF: byte 4: entry 0: header cut short"):
        line.manager.configure(NODE, good[:6])
    with pytest.raises(ConfigurationError, match="node-id"):
        line.manager.configure(0, good)
    with pytest.raises(ConfigurationError, match=r"expected must be \(date, time\)"):
        line.manager.configure(NODE, good, expected=(1,))
    with pytest.raises(ConfigurationError, match="no entry and no stamp"):
        line.manager.configure(NODE, build_concise([]))
    path = tmp_path / "x.cdcf"
    path.write_bytes(good + b"\x00")
    with pytest.raises(ConciseDcfError, match=f"{path}: byte 13: 1 bytes after"):
        line.manager.configure(NODE, str(path))


def test_python_canopen_local_node_is_configured():
    """python-canopen's LocalNode, built from the same DCF, configured by our
    manager over classic SDO on a python-can virtual bus: its data store
    holds every entry and the stamp; a second run is skipped."""
    canopen = pytest.importorskip("canopen")
    import tempfile
    channel = f"config-{os.getpid()}-{next(_channels)}"
    with tempfile.TemporaryDirectory() as tmp:
        path = make_dcf(__import__("pathlib").Path(tmp), node_id=7, relative=False)
        peer = canopen.Network()
        peer.connect(interface="virtual", channel=channel)
        theirs = peer.create_node(canopen.LocalNode(7, canopen.import_od(str(path), node_id=7)))
        try:
            with canopenfd.Network() as net:
                line = net.open_line(bus=virtual_bus(channel), mode="classic")
                result = line.manager.configure(7, str(path), expected=(DATE, TIME)).result(10)
                assert result.outcome is ConfigOutcome.OK, str(result)
                store = theirs.data_store
                assert bytes(store[0x1017][0]) == b"\xfa\x00"
                assert bytes(store[0x1A00][2]) == (0x23000220).to_bytes(4, "little")
                assert bytes(store[0x1800][1]) == (0x180).to_bytes(4, "little")
                assert bytes(store[0x2F00][0]) == b"axis 1"
                assert bytes(store[0x1020][1]) == DATE.to_bytes(4, "little")
                assert bytes(store[0x1020][2]) == TIME.to_bytes(4, "little")
                again = line.manager.configure(7, str(path), expected=(DATE, TIME)).result(10)
                assert again.outcome is ConfigOutcome.SKIPPED
                # a read-only entry of theirs refuses the write with 0x06010002
                bad = line.manager.configure(7, build_concise([(0x1018, 1, b"\x01\x00\x00\x00")])
                                             ).result(10)
                assert (bad.index, bad.abort_code, bad.from_node) == (0x1018, 0x06010002, True)
        finally:
            peer.disconnect()
