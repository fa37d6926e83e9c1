"""The local node's OD served over classic SDO, with python-canopen (PyPI
`canopen`) as the independent client: expedited, segmented and block
transfers (CRC) both ways, 0 bytes to 1 MiB, and the server's answers checked
byte for byte on the bus. Runs over python-can's virtual bus (our line uses
the host driver), so no kernel CAN is needed; test_interop_canopen.py repeats
the essentials on a classic vcan."""

from __future__ import annotations

import itertools
import os
import time

import pytest

import canopenfd
from canopenfd.od import demo_od
from helpers import scaled, virtual_bus

can = pytest.importorskip("can")
canopen = pytest.importorskip("canopen")

NODE = 5
DOMAIN = 0x2100
_channels = itertools.count(1)


@pytest.fixture
def rig():
    """Our node 5 (demo OD, 16 MiB domain) on a virtual bus, python-canopen's
    client of it, and a raw python-can socket that sees every frame."""
    channel = f"sdo-{os.getpid()}-{next(_channels)}"
    with canopenfd.Network() as net:
        line = net.open_line(bus=virtual_bus(channel), mode="classic")
        node = line.create_local_node(NODE, od=demo_od("classic"), boot=False)
        node.serve_domain(DOMAIN, 16 << 20)
        node.boot()
        peer = canopen.Network()
        peer.connect(interface="virtual", channel=channel)
        sniffer = can.Bus(interface="virtual", channel=channel)
        remote = peer.add_node(NODE, canopen.ObjectDictionary())
        # python-canopen waits 0.3 s per response by default: too short for a
        # loaded CI machine (its client and our host line run in Python threads)
        # generous: python-canopen's 1 MiB block download waited out 3 s once on a CI
        # machine at load average 10 (tests of timeouts set their own)
        remote.sdo.RESPONSE_TIMEOUT = 10.0
        try:
            yield node, remote, sniffer
        finally:
            peer.disconnect()
            sniffer.shutdown()


def frames(sniffer, can_id):
    out = []
    while True:
        msg = sniffer.recv(0.2)
        if msg is None:
            return out
        if msg.arbitration_id == can_id:
            out.append(bytes(msg.data))


def test_expedited_answers_byte_for_byte(rig):
    node, remote, sniffer = rig
    node[0x1017].raw = 0x1234
    assert remote.sdo.upload(0x1017, 0) == b"\x34\x12"
    remote.sdo.download(0x1017, 0, (300).to_bytes(2, "little"))
    assert node[0x1017].raw == 300
    answers = frames(sniffer, 0x580 + NODE)
    # upload response: expedited, size indicated, 2 bytes (n = 2): 0x4B
    assert answers[0] == bytes([0x4B, 0x17, 0x10, 0x00, 0x34, 0x12, 0, 0])
    # download response
    assert answers[1] == bytes([0x60, 0x17, 0x10, 0x00, 0, 0, 0, 0])


def test_refused_write_has_the_cia_abort_code(rig):
    node, remote, sniffer = rig
    with pytest.raises(canopen.SdoAbortedError) as info:
        remote.sdo.download(0x1018, 1, b"\x01\x00\x00\x00")
    assert info.value.code == 0x06010002          # read-only
    assert frames(sniffer, 0x580 + NODE)[-1] == bytes([0x80, 0x18, 0x10, 0x01, 0x02, 0x00,
                                                        0x01, 0x06])


@pytest.mark.parametrize("size", [0, 1, 4, 5, 7, 8, 100, 4096, 16384])
def test_segmented_both_ways(rig, size):
    node, remote, _ = rig
    data = os.urandom(size)
    remote.sdo.download(DOMAIN, 0, data, force_segment=True)
    assert node[DOMAIN].data == data
    assert remote.sdo.upload(DOMAIN, 0) == data


@pytest.mark.parametrize("size", [1, 7, 8, 889, 890, 100_000, 1 << 20])
def test_block_both_ways_with_crc(rig, size):
    node, remote, _ = rig
    data = os.urandom(size)
    with remote.sdo.open(DOMAIN, 0, "wb", size=size, block_transfer=True) as f:
        f.write(data)
    assert node[DOMAIN].data == data
    with remote.sdo.open(DOMAIN, 0, "rb", block_transfer=True) as f:
        assert f.read() == data


def test_python_canopen_types_values_with_our_exported_eds(rig, tmp_path):
    """python-canopen imports the EDS our node exports and decodes what it reads."""
    node, remote, _ = rig
    eds = tmp_path / "node.eds"
    node.export_eds(str(eds))
    their_od = canopen.import_od(str(eds), NODE)
    node["Demo record.Setpoint"].raw = -321
    setpoint = their_od["Demo record"]["Setpoint"]
    assert setpoint.decode_raw(remote.sdo.upload(0x2200, 1)) == -321
    node["Demo record.Label"].raw = "spindle"
    label = their_od["Demo record"]["Label"]
    assert label.decode_raw(remote.sdo.upload(0x2200, 4)) == "spindle"


def _wait(predicate, what: str, timeout: float = 5.0):
    deadline = time.monotonic() + scaled(timeout)
    while not predicate():
        assert time.monotonic() < deadline, f"timed out: {what}"
        time.sleep(0.01)


def test_stopped_node_answers_no_sdo(rig):
    """CiA 301: SDO only in pre-operational and operational. python-canopen
    stops our node over NMT: its upload gets no answer (nothing on 0x580 + id,
    the request counted), and after NMT enter pre-operational it is served."""
    node, remote, sniffer = rig
    line = node.line
    remote.nmt.state = "STOPPED"
    _wait(lambda: node.state == "STOPPED", "node 5 stopped")
    frames(sniffer, 0x580 + NODE)                       # drop what came before
    remote.sdo.RESPONSE_TIMEOUT = scaled(0.5)
    with pytest.raises(canopen.SdoCommunicationError):
        remote.sdo.upload(0x1018, 1)
    assert frames(sniffer, 0x580 + NODE) == []
    assert line.service_stats["sdo_server"]["rx_not_serving"] >= 1
    remote.nmt.state = "PRE-OPERATIONAL"
    _wait(lambda: node.state == "PRE-OPERATIONAL", "node 5 pre-operational")
    remote.sdo.RESPONSE_TIMEOUT = 3.0
    node[0x1017].raw = 0x0102
    assert remote.sdo.upload(0x1017, 0) == b"\x02\x01"
