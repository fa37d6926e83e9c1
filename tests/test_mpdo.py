"""Multiplexed PDOs (CiA 301 MPDO, issue 18 item 1) between two local nodes
over `mem:`, classic and fd: DAM and SAM both ways, configured through the
OD (mapping sub 0 = 0xFF / 0xFE, scanner list 0x1FA0, dispatcher list
0x1FD0), every frame's CAN-ID and bytes checked on a monitor line; a DAM
for an object the device lacks writes nothing and brings EMCY 0x8230, the
line going on. python-canopen has no MPDO service: no interop test."""

from __future__ import annotations

import asyncio
import threading
import time

import pytest
from helpers import Recorder, scaled, wait_flood_drained

import canopenfd
from canopenfd import CanopenFDError, ConfigurationError
from canopenfd.od import DataType, demo_od
from canopenfd.od.model import ODArray, ODVariable
from canopenfd.services.mpdo import MpdoNotice

A, B = 5, 6
DATA = 0x2300          # demo_od's "Process data": 16 UNSIGNED32, mappable
EMCY_DAM = 0x8230


def mpdo_od(mode: str, producer: int) -> object:
    """demo_od with 2 RPDOs/TPDOs, a scanner list naming 0x2300:01..04 and a
    dispatcher list taking `producer`'s 0x2300:01..04 into 0x2300:09..12."""
    od = demo_od(mode, pdos=2)
    scan = ODArray("Object scanner list", 0x1FA0)
    scan.add_member(ODVariable("Highest sub-index supported", 0x1FA0, 0, DataType.UNSIGNED8,
                               "ro", 1))
    scan.add_member(ODVariable("Scan 1", 0x1FA0, 1, DataType.UNSIGNED32, "rw",
                               (4 << 24) | (DATA << 8) | 1))
    od.add_object(scan)
    dispatch = ODArray("Object dispatching list", 0x1FD0)
    dispatch.add_member(ODVariable("Highest sub-index supported", 0x1FD0, 0,
                                   DataType.UNSIGNED8, "ro", 1))
    dispatch.add_member(ODVariable("Dispatch 1", 0x1FD0, 1, DataType.UNSIGNED64, "rw",
                                   (4 << 56) | (DATA << 40) | (9 << 32) | (DATA << 16)
                                   | (1 << 8) | producer))
    od.add_object(dispatch)
    return od


def make_mpdo(node, kind: str, number: int, marker: int, cob_id: int) -> None:
    """The CiA 301 procedure on the node's own OD: COB-ID invalid, mapping
    sub 0 = marker, COB-ID valid."""
    comm, mapping = (0x1400, 0x1600) if kind == "rpdo" else (0x1800, 0x1A00)
    node[comm + number - 1][1].raw = 0x80000000 | cob_id
    node[mapping + number - 1][0].raw = marker
    node[comm + number - 1][1].raw = cob_id


def make_pair_mpdos(node, me: int, other: int) -> None:
    """DAM (TPDO 1 on 0x180 + me) and SAM (TPDO 2 on 0x280 + me) producers,
    consumers of the other node's (RPDO 1 / 2), then OPERATIONAL."""
    make_mpdo(node, "tpdo", 1, 0xFF, 0x180 + me)
    make_mpdo(node, "tpdo", 2, 0xFE, 0x280 + me)
    make_mpdo(node, "rpdo", 1, 0xFF, 0x180 + other)
    make_mpdo(node, "rpdo", 2, 0xFE, 0x280 + other)
    node.nmt.state = "OPERATIONAL"
    node.nmt.wait_for_state("OPERATIONAL", timeout=scaled(2))


@pytest.fixture(params=["classic", "fd"])
def mode(request):
    return request.param


class Pair:
    """Nodes 5 and 6 on one bus, each producing a DAM (TPDO 1 on 0x180 +
    id) and a SAM MPDO (TPDO 2 on 0x280 + id) that the other consumes
    (RPDO 1 / RPDO 2), and a monitor of every frame."""

    def __init__(self, net, bus_name, mode):
        self.mode = mode
        self.frames = Recorder()
        net.open_line(bus_name, mode=mode, monitor=True).on_frame(self.frames)
        self.lines = {n: net.open_line(bus_name, mode=mode) for n in (A, B)}
        self.nodes = {n: self.lines[n].create_local_node(n, od=mpdo_od(mode, A + B - n))
                      for n in (A, B)}
        for me, other in ((A, B), (B, A)):
            make_pair_mpdos(self.nodes[me], me, other)

    def wait_frame(self, can_id: int, start: int):
        def found(calls):
            hits = [f for f in calls[start:] if f.id == can_id]
            return hits[0] if hits else None
        return self.frames.wait_for(found, scaled(2), f"a frame on 0x{can_id:X}")

    def check_frame(self, can_id: int, start: int, data: bytes) -> None:
        frame = self.wait_frame(can_id, start)
        assert frame.data == data
        assert frame.fd == (self.mode == "fd")


@pytest.fixture
def pair(net, bus_name, mode):
    return Pair(net, bus_name, mode)


def wait_value(node, index, sub, value):
    deadline = time.monotonic() + scaled(2)
    while node[index][sub].raw != value:
        assert time.monotonic() < deadline, f"{index:04X}:{sub:02X} never became {value:#x}"
        time.sleep(0.005)


@pytest.mark.parametrize("producer,consumer", [(A, B), (B, A)])
def test_dam_writes_the_consumer(pair, producer, consumer):
    start = len(pair.frames)
    pair.nodes[producer].tpdo[1].send_dam(consumer, DATA, 3, bytes([0x44, 0x33, 0x22, 0x11]))
    pair.check_frame(0x180 + producer, start,
                     bytes([0x80 | consumer, 0x00, 0x23, 0x03, 0x44, 0x33, 0x22, 0x11]))
    wait_value(pair.nodes[consumer], DATA, 3, 0x11223344)
    # node 0 = every consumer
    start = len(pair.frames)
    pair.nodes[producer].tpdo[1].send_dam(0, DATA, 4, bytes([7]))
    pair.check_frame(0x180 + producer, start, bytes([0x80, 0x00, 0x23, 0x04, 7, 0, 0, 0]))
    wait_value(pair.nodes[consumer], DATA, 4, 7)
    # another node's DAM changes nothing here
    start = len(pair.frames)
    pair.nodes[producer].tpdo[1].send_dam(42, DATA, 3, bytes([1]))
    pair.check_frame(0x180 + producer, start, bytes([0x80 | 42, 0x00, 0x23, 0x03, 1, 0, 0, 0]))
    stats = pair.nodes[consumer].mpdo_stats()
    assert stats["rx_other_node"] == 1 and stats["rx_applied"] == 2
    assert pair.nodes[consumer][DATA][3].raw == 0x11223344


@pytest.mark.parametrize("producer,consumer", [(A, B), (B, A)])
def test_sam_goes_through_the_lists(pair, producer, consumer):
    pair.nodes[producer][DATA][2].raw = 0xCAFE0042
    start = len(pair.frames)
    pair.nodes[producer].tpdo[2].send_sam(DATA, 2)
    pair.check_frame(0x280 + producer, start,
                     bytes([producer, 0x00, 0x23, 0x02, 0x42, 0x00, 0xFE, 0xCA]))
    wait_value(pair.nodes[consumer], DATA, 10, 0xCAFE0042)   # the dispatcher's 0x2300:0A
    assert pair.nodes[consumer][DATA][2].raw == 0
    with pytest.raises(CanopenFDError, match="scanner list"):
        pair.nodes[producer].tpdo[2].send_sam(DATA, 5)


def test_dam_to_a_missing_object_sends_emcy_8230(pair):
    emcys = Recorder()
    pair.lines[A].add_node(B).emcy.add_callback(emcys)
    start = len(pair.frames)
    pair.nodes[A].tpdo[1].send_dam(B, 0x2FFF, 0, bytes([1, 2]))
    emcy = emcys.wait_count(1, scaled(2))[0]
    assert emcy.code == EMCY_DAM and emcy.node == B
    if pair.mode == "classic":
        frame = pair.wait_frame(0x80 + B, start)
        assert frame.data[:2] == bytes([0x30, 0x82]) and frame.data[3:5] == bytes([1, 0])
    stats = pair.nodes[B].mpdo_stats()
    assert stats["rx_refused"] == 1 and stats["rx_applied"] == 0
    # the line goes on: the next DAM is applied
    pair.nodes[A].tpdo[1].send_dam(B, DATA, 1, bytes([9]))
    wait_value(pair.nodes[B], DATA, 1, 9)


def test_refusals_name_the_cause(pair):
    node = pair.nodes[A]
    with pytest.raises(ConfigurationError, match="1..4 bytes"):
        node.tpdo[1].send_dam(B, DATA, 1, bytes(5))
    with pytest.raises(CanopenFDError, match="no valid DAM MPDO"):
        node.tpdo[2].send_dam(B, DATA, 1, bytes([1]))
    with pytest.raises(CanopenFDError, match="node-id 0..127"):
        node.tpdo[1].send_dam(128, DATA, 1, bytes([1]))
    with pytest.raises(ConfigurationError, match="TPDO of the local node"):
        node.rpdo[1].send_sam(DATA, 1)
    node.nmt.state = "PRE-OPERATIONAL"
    node.nmt.wait_for_state("PRE-OPERATIONAL", timeout=scaled(2))
    with pytest.raises(CanopenFDError, match="not operational"):
        node.tpdo[1].send_dam(B, DATA, 1, bytes([1]))


def test_configured_over_the_network(net, bus_name, mode):
    """A master makes the device's RPDO 1 a DAM MPDO with `rpdo.mpdo = 'DAM'`
    and save() (SDO/USDO, the CiA 301 procedure), reads it back, and its own
    DAM MPDO then writes the device."""
    device = net.open_line(bus_name, mode=mode).create_local_node(B, od=mpdo_od(mode, A))
    line = net.open_line(bus_name, mode=mode)
    me = line.create_local_node(A, od=mpdo_od(mode, B))
    make_mpdo(me, "tpdo", 1, 0xFF, 0x180 + A)
    drive = line.add_node(B, od=mpdo_od(mode, A))
    rpdo = drive.rpdo[1]
    rpdo.read()
    assert rpdo.mpdo is None
    rpdo.mpdo = "DAM"
    rpdo.cob_id = 0x180 + A
    rpdo.trans_type = 1
    with pytest.raises(ConfigurationError, match="MPDO .DAM. needs trans_type 254 or 255"):
        rpdo.save()
    rpdo.trans_type = 254
    rpdo.enabled = True
    rpdo.save()
    assert device[0x1600][0].raw == 0xFF
    drive.rpdo[1].read()
    assert drive.rpdo[1].mpdo == "DAM" and drive.rpdo[1].enabled and not drive.rpdo[1].map
    with pytest.raises(ConfigurationError, match="'DAM', 'SAM' or None"):
        rpdo.mpdo = "BOTH"
    for node in (me, device):
        node.nmt.state = "OPERATIONAL"
        node.nmt.wait_for_state("OPERATIONAL", timeout=scaled(2))
    me.tpdo[1].send_dam(B, DATA, 5, bytes([0x5A]))
    wait_value(device, DATA, 5, 0x5A)


def test_on_mpdo_tells_applied_and_refused(pair):
    """node.on_mpdo: one MpdoNotice per MPDO addressed to the node, DAM and
    SAM, applied or refused (abort code), nothing for another node's DAM."""
    notices = Recorder()
    pair.nodes[B].on_mpdo(notices)
    pair.nodes[A].tpdo[1].send_dam(B, DATA, 3, bytes([0x44, 0x33, 0x22, 0x11]))
    pair.nodes[A].tpdo[1].send_dam(42, DATA, 3, bytes([1]))          # not for B: no notice
    pair.nodes[A].tpdo[1].send_dam(B, 0x2FFF, 0, bytes([1, 2]))      # refused
    pair.nodes[A][DATA][2].raw = 0xCAFE0042
    pair.nodes[A].tpdo[2].send_sam(DATA, 2)
    got = notices.wait_count(3, scaled(2))
    assert got[0] == MpdoNotice("DAM", B, DATA, 3, DATA, 3, bytes([0x44, 0x33, 0x22, 0x11]),
                                0, 1, 0)
    assert got[0].applied
    assert got[1] == MpdoNotice("DAM", B, 0x2FFF, 0, 0x2FFF, 0, bytes([1, 2, 0, 0]),
                                0x06020000, 1, 0)
    assert not got[1].applied
    assert got[2] == MpdoNotice("SAM", A, DATA, 2, DATA, 10, bytes([0x42, 0x00, 0xFE, 0xCA]),
                                0, 2, 0)
    assert len(notices) == 3
    pair.nodes[B].remove_mpdo_callback(notices)
    pair.nodes[A].tpdo[1].send_dam(B, DATA, 4, bytes([5]))
    wait_value(pair.nodes[B], DATA, 4, 5)
    assert len(notices) == 3


def test_dam_sends_the_mapped_object(pair):
    """send_dam(node): the object the DAM TPDO's mapping sub 1 names goes to
    the same index:sub of the node (CiA 301's DAM producer)."""
    node = pair.nodes[A]
    with pytest.raises(CanopenFDError, match="mapping sub 1 names no readable object"):
        node.tpdo[1].send_dam(B)
    node[0x1800][1].raw = 0x80000000 | (0x180 + A)    # the mapping changes only while
    node[0x1A00][0].raw = 0                           # the PDO is invalid and sub 0 = 0
    node[0x1A00][1].raw = (DATA << 16) | (6 << 8) | 32
    node[0x1A00][0].raw = 0xFF
    node[0x1800][1].raw = 0x180 + A
    node[DATA][6].raw = 0x01020304
    start = len(pair.frames)
    node.tpdo[1].send_dam(B)
    pair.check_frame(0x180 + A, start, bytes([0x80 | B, 0x00, 0x23, 0x06, 4, 3, 2, 1]))
    wait_value(pair.nodes[B], DATA, 6, 0x01020304)
    with pytest.raises(ConfigurationError, match="give index, sub and data"):
        node.tpdo[1].send_dam(B, DATA)


def test_one_sam_producer_per_device(net, bus_name, mode):
    """CiA 301: a device has at most one SAM producer. Making a second TPDO
    SAM (save() over SDO/USDO) is refused with abort 0x06040043 and leaves
    its mapping as it was; the application's own OD writes are not checked,
    but such a TPDO does not run."""
    device = net.open_line(bus_name, mode=mode).create_local_node(B, od=mpdo_od(mode, A))
    make_mpdo(device, "tpdo", 2, 0xFE, 0x280 + B)
    line = net.open_line(bus_name, mode=mode)
    line.create_local_node(A, od=mpdo_od(mode, B))
    tpdo = line.add_node(B, od=mpdo_od(mode, A)).tpdo[1]
    tpdo.read()
    tpdo.mpdo = "SAM"
    tpdo.trans_type = 254
    with pytest.raises(CanopenFDError, match=r"SAM MPDO \(0x1A00:00 = 0xFE\).*(0x06040043|"
                       "general parameter incompatibility)"):
        tpdo.save()
    assert device[0x1A00][0].raw != 0xFE
    make_mpdo(device, "tpdo", 1, 0xFE, 0x180 + B)
    device.nmt.state = "OPERATIONAL"
    device.nmt.wait_for_state("OPERATIONAL", timeout=scaled(2))
    with pytest.raises(CanopenFDError, match="no valid SAM MPDO"):
        device.tpdo[1].send_sam(DATA, 1)
    device.tpdo[2].send_sam(DATA, 1)


def test_a_flood_of_mpdos_is_coalesced_per_multiplexer(bus_name):
    """A slow on_mpdo callback under a flood of DAMs to one object: from 3/4
    of the event queue on, notices of the same multiplexer merge (the newest
    kept, `coalesced` counting the older ones), so none is lost and the
    counters still see every frame; the entry's OD-changed events merge
    the same way instead of filling the queue."""
    frames = 1500
    net = canopenfd.Network(event_capacity=256, stall_report_s=3600)
    try:
        line = net.open_line(bus_name, mode="classic")
        node = line.create_local_node(B, od=mpdo_od("classic", A))
        make_mpdo(node, "rpdo", 1, 0xFF, 0x180 + A)
        node.nmt.state = "OPERATIONAL"
        node.nmt.wait_for_state("OPERATIONAL", timeout=scaled(2))
        gate = threading.Event()
        got = Recorder()

        def slow(notice):
            gate.wait(scaled(30))          # the first call holds the dispatcher
            got((int.from_bytes(notice.data, "little"), notice.coalesced))
        node.on_mpdo(slow)
        tool = net.open_line(bus_name, mode="classic")
        dam_to_b = bytes([0x80 | B, 0x00, 0x23, 0x03])       # to 0x2300:03 of node B
        for i in range(frames):
            tool.send_frame(0x180 + A, dam_to_b + i.to_bytes(4, "little"))
            if i % 100 == 99:
                time.sleep(0.002)           # let the runtime thread move the frames
        calls = wait_flood_drained(got, gate,
                                   lambda: node.mpdo_stats()["rx_applied"] >= frames, frames)
        assert node.mpdo_stats()["rx_applied"] == frames
        assert (line.stats["events_lost"], net.events_lost) == (0, 0)
        # the MPDO notices merged, and the OD-changed events of 0x2300:03 (one a frame)
        assert line.stats["events_coalesced"] > frames - len(calls)
    finally:
        net.close()


def test_on_mpdo_with_a_loop_runs_on_the_loop(pair):
    """on_mpdo(callback, loop=loop): the callback runs on that asyncio loop's thread."""
    async def main():
        seen = asyncio.Event()
        threads = []

        def on_notice(notice):
            threads.append((threading.get_ident(), notice.frame_sub))
            seen.set()                         # an asyncio.Event: only safe on the loop thread
        pair.nodes[B].on_mpdo(on_notice, loop=asyncio.get_running_loop())
        pair.nodes[A].tpdo[1].send_dam(B, DATA, 7, bytes([1]))
        await asyncio.wait_for(seen.wait(), scaled(5))
        assert threads == [(threading.get_ident(), 7)]
        pair.nodes[B].remove_mpdo_callback(on_notice)
    asyncio.run(main())
