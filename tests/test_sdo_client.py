"""Our SDO client through the Python API (line.sdo, remote.sdo, remote.od,
remote.read/write) against our own server over the in-process bus, against
python-canopen's LocalNode SDO server over python-can's virtual bus
(interop), and the CLI on a classic line. The client's frames are checked on
the bus."""

from __future__ import annotations

import asyncio
import itertools
import os
import threading

import pytest

import canopenfd
from canopenfd import ConfigurationError, SdoAbortError
from canopenfd.cli import main
from canopenfd.od import demo_od
from helpers import Recorder, virtual_bus

can = pytest.importorskip("can")
canopen = pytest.importorskip("canopen")

SERVER = 5
DOMAIN = 0x2100
MiB = 1 << 20
_channels = itertools.count(1)


@pytest.fixture
def rig(net, bus_name):
    """Our node 5 (demo OD, 16 MiB domain) on a classic in-process bus, a
    client line, and a monitor of every frame."""
    node = net.open_line(bus_name, mode="classic").create_local_node(
        SERVER, od=demo_od("classic"), boot=False)
    node.serve_domain(DOMAIN, 16 * MiB)
    node.boot()
    line = net.open_line(bus_name, mode="classic")
    frames = Recorder()
    net.open_line(bus_name, mode="classic", monitor=True).on_frame(frames)
    return node, line, frames


def test_expedited_request_bytes_and_typed_values(rig):
    node, line, frames = rig
    node[0x1017].raw = 0x1234
    remote = line.add_node(SERVER, od=demo_od("classic"))
    assert remote.od["Producer heartbeat time"].raw == 0x1234
    request = frames.wait_for(lambda c: [f for f in c if f.id == 0x600 + SERVER], 2, "request")
    # initiate upload: [0x40, index LE, sub, 0 0 0 0], classic 8 bytes
    assert not request[0].fd and request[0].data == bytes([0x40, 0x17, 0x10, 0, 0, 0, 0, 0])
    remote.write("Demo record.Setpoint", -2)
    assert node[0x2200][1].raw == -2
    sent = frames.wait_for(lambda c: [f for f in c if f.id == 0x600 + SERVER][1:], 2, "write")
    # expedited download, size indicated, 2 bytes: 0x2B
    assert sent[0].data == bytes([0x2B, 0x00, 0x22, 0x01, 0xFE, 0xFF, 0, 0])


def test_python_canopen_calls_on_node_sdo(rig):
    """node.sdo.upload(index, sub), download(index, sub, data, force_segment=),
    node.sdo["Name"].raw and node.sdo[index][sub].raw, checked on the wire."""
    node, line, frames = rig
    remote = line.add_node(SERVER, od=demo_od("classic"))
    node[0x1017].raw = 0x1234
    assert remote.sdo.upload(0x1017, 0) == b"\x34\x12"
    remote.sdo.download(0x1017, 0, b"\x64\x00")
    assert node[0x1017].raw == 100
    remote.sdo.download(0x1017, 0, b"\x65\x00", force_segment=True)
    assert node[0x1017].raw == 101
    def initiate_downloads(calls):          # of 0x1017, once both are on the monitor
        got = [f.data[0] for f in calls if f.id == 0x600 + SERVER
               and f.data[0] & 0xE0 == 0x20 and f.data[1:3] == b"\x17\x10"]
        return got if len(got) >= 2 else None
    initiates = frames.wait_for(initiate_downloads, 2, "the downloads")
    assert initiates == [0x2B, 0x21]        # expedited (2 bytes), then segmented, size given
    assert remote.sdo["Producer heartbeat time"].raw == 101
    remote.sdo["Producer heartbeat time"].raw = 250
    assert node[0x1017].raw == 250
    assert remote.sdo[0x1018][1].raw == node[0x1018][1].raw
    with pytest.raises(ConfigurationError,
                       match=r"node 5: 0x1018 \('Identity object'\) is an ARRAY/RECORD; "
                             r"give a sub-index, e.g. \(0x1018, 1\)"):
        remote.sdo.upload(0x1018)
    for call in (lambda: remote.sdo.upload("Producer heartbeat time", 1),
                 lambda: remote.sdo.download(0x1017, "0", b"\x00\x00")):
        with pytest.raises(ConfigurationError, match="node 5: (upload|download)"):
            call()
    # download(index, sub) without data: the sub-index is not taken for the data
    with pytest.raises(ConfigurationError,
                       match=r"node 5: download data must be bytes-like .* got 0 "
                             r"\(python-canopen's order: download\(index, subindex, data\)\)"):
        remote.sdo.download(0x1017, 0)


@pytest.mark.parametrize("size, mode", [(3, "expedited"), (100, "segmented"),
                                        (5000, "block"), (MiB, "block")])
def test_both_ways_byte_for_byte(rig, size, mode):
    node, line, _ = rig
    data = os.urandom(size)
    transfer = line.sdo.start_download(SERVER, DOMAIN, 0, data)
    transfer.result()
    assert transfer.mode == mode and node[DOMAIN].data == data
    assert line.sdo.upload(SERVER, DOMAIN, size_hint=size) == data


def test_forced_segmented_and_block_upload(rig):
    node, line, _ = rig
    data = os.urandom(70000)
    line.sdo.download(SERVER, DOMAIN, 0, data, mode="segmented")
    assert node[DOMAIN].data == data
    transfer = line.sdo.start_upload(SERVER, DOMAIN, 0, size_hint=len(data))
    assert transfer.result() == data and transfer.mode == "block"


def test_abort_carries_the_cia_code(rig):
    _, line, _ = rig
    with pytest.raises(SdoAbortError) as info:
        line.sdo.upload(SERVER, 0x5FFF)
    assert info.value.code == 0x06020000 and info.value.from_server
    assert "object does not exist" in str(info.value)
    with pytest.raises(SdoAbortError) as info:
        line.sdo.upload(42, 0x1000, timeout=0.2)        # nobody answers
    assert info.value.code == 0x05040000 and not info.value.from_server


def test_several_servers_at_once_from_threads(net, bus_name):
    nodes = {}
    for node_id in (3, 4, 6):
        nodes[node_id] = net.open_line(bus_name, mode="classic").create_local_node(
            node_id, od=demo_od("classic"))
        nodes[node_id][0x1017].raw = node_id * 10
    line = net.open_line(bus_name, mode="classic")
    results = {}

    def read(node_id):
        results[node_id] = line.sdo.upload(node_id, 0x1017)

    threads = [threading.Thread(target=read, args=(n,)) for n in nodes]
    for t in threads:
        t.start()
    for t in threads:
        t.join(10)
    assert results == {n: (n * 10).to_bytes(2, "little") for n in nodes}


def test_awaitable_and_unified_read_write(rig):
    node, line, _ = rig
    remote = line.add_node(SERVER, od=demo_od("classic"))

    async def main_():
        await remote.awrite(0x1017, 321)
        return await remote.aread(0x1017)

    assert asyncio.run(main_()) == 321 == node[0x1017].raw


def test_usdo_is_refused_on_classic_lines_and_sdo_on_fd(net, bus_name, rig):
    _, line, _ = rig
    with pytest.raises(ConfigurationError, match="classic line"):
        line.usdo
    fd = net.open_line(bus_name + "-fd", mode="fd")
    with pytest.raises(ConfigurationError, match="USDO"):
        fd.sdo


# ------------------------------------------------------------------ interop
@pytest.fixture
def their_server():
    """python-canopen's LocalNode 7 (its own SDO server) on a virtual bus,
    and our classic line on the same bus (host driver)."""
    channel = f"sdoc-{os.getpid()}-{next(_channels)}"
    peer = canopen.Network()
    peer.connect(interface="virtual", channel=channel)
    od = canopen.ObjectDictionary()
    for index, dtype in ((0x2000, canopen.objectdictionary.UNSIGNED32),
                         (0x2001, canopen.objectdictionary.DOMAIN)):
        var = canopen.objectdictionary.ODVariable(f"v{index:X}", index, 0)
        var.data_type = dtype
        var.access_type = "rw"
        od.add_object(var)
    local = peer.create_node(7, od)
    store = {}
    local.add_write_callback(lambda index, subindex, od, data: store.__setitem__(index, data))
    local.add_read_callback(lambda index, subindex, od: store.get(index))
    with canopenfd.Network() as net:
        line = net.open_line(bus=virtual_bus(channel), mode="classic")
        try:
            yield line, store
        finally:
            peer.disconnect()


# (0 bytes is left out: python-canopen's LocalNode takes an empty value from
# its read callback as "not handled" and aborts 0x08000024; our server's
# 0-byte transfers are covered in test_sdo_server.py)
@pytest.mark.parametrize("size", [1, 4, 5, 7, 100, 20000])
def test_our_client_against_python_canopen_server(their_server, size):
    line, store = their_server
    data = os.urandom(size)
    line.sdo.download(7, 0x2001, 0, data, mode="segmented" if size > 4 else "auto")
    assert bytes(store[0x2001]) == data
    assert line.sdo.upload(7, 0x2001) == data


def test_python_canopen_server_refusal_reaches_us(their_server):
    line, _ = their_server
    with pytest.raises(SdoAbortError) as info:
        line.sdo.upload(7, 0x3000)
    assert info.value.code == 0x06020000


# ------------------------------------------------------------------ CLI
def test_cli_on_a_classic_line(net, bus_name, tmp_path, capsys):
    node = net.open_line(bus_name, mode="classic").create_local_node(
        SERVER, od=demo_od("classic"), boot=False)
    node.serve_domain(DOMAIN, MiB)
    node.boot()

    def cli(*argv):
        capsys.readouterr()
        status = main([*argv, "--channel", bus_name, "--classic"], network=net)
        return status, *capsys.readouterr()

    status, out, _ = cli("write", "5", "0x1017", "250", "--type", "U16")
    assert status == 0 and node[0x1017].raw == 250
    status, out, _ = cli("read", "5", "0x1017", "--type", "U16")
    assert status == 0 and "250" in out
    source = tmp_path / "in.bin"
    source.write_bytes(os.urandom(100000))
    status, out, _ = cli("download", "5", "0x2100", str(source))
    assert status == 0 and "block" in out and node[DOMAIN].data == source.read_bytes()
    status, out, _ = cli("upload", "5", "0x2100", str(tmp_path / "out.bin"))
    assert status == 0 and (tmp_path / "out.bin").read_bytes() == source.read_bytes()
    status, _, err = cli("read", "5", "0x5FFF")
    assert status == 1 and "0x06020000" in err


@pytest.mark.parametrize("mode", ["segmented", "block"])
def test_a_download_announced_beyond_the_domain_is_refused_at_the_initiate(net, bus_name,
                                                                           mode):
    """SDO abort 0x06070012 answers the initiate itself: no segment is sent."""
    node = net.open_line(bus_name, mode="classic").create_local_node(
        SERVER, od=demo_od("classic"), boot=False)
    node.serve_domain(DOMAIN, 1024)
    node.boot()
    line = net.open_line(bus_name, mode="classic")
    frames = Recorder()
    net.open_line(bus_name, mode="classic", monitor=True).on_frame(frames)
    with pytest.raises(SdoAbortError) as info:
        line.sdo.download(SERVER, DOMAIN, 0, bytes(2000), mode=mode)
    assert (info.value.code, info.value.from_server) == (0x06070012, True)
    answer = frames.wait_for(lambda c: [f for f in c if f.id == 0x580 + SERVER] or None, 2,
                             "the abort")[0]
    assert answer.data == bytes([0x80, 0x00, 0x21, 0x00, 0x12, 0x00, 0x07, 0x06])
    assert len([f for f in frames.snapshot() if f.id == 0x600 + SERVER]) == 1   # initiate
    line.sdo.download(SERVER, DOMAIN, 0, b"y" * 1024, mode=mode)
    assert node[DOMAIN].data == b"y" * 1024
