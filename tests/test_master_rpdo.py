"""A master drives a remote device's RPDO (issue 14 item 3): the C runtime
produces the frame the device's RPDO consumes (co_rt_rpdo_*), filled with
`pdo["name"].raw = ...`, sent once (transmit), periodically (start), after
SYNCs (start_sync) until stop(). Checked on the wire (CAN-ID and bytes seen
by a monitor line, fd and classic, bit-wise mappings on classic), by our own
device (its RPDO callback), by python-canopen's LocalNode as the device on a
python-can virtual bus, plus the example and the README snippet."""

from __future__ import annotations

import itertools
import os
import re
import subprocess
import sys
import time

import pytest
from helpers import Recorder, package_env, scaled, virtual_bus

import canopenfd
from canopenfd import ConfigurationError, CanopenFDError
from canopenfd.od import DataType, demo_od, export_eds

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DEVICE = 5
RPDO_ID = 0x200 + DEVICE
P1, P2 = "Process data.Process data 1", "Process data.Process data 2"
_channels = itertools.count(1)


@pytest.fixture(params=["classic", "fd"])
def mode(request):
    return request.param


class Rig:
    """Our device node 5 (demo OD with one RPDO), the master's line with its
    view of node 5, a monitor of every frame, and the device's receptions."""

    def __init__(self, net, bus_name, mode, device_od=None, master_od=None):
        self.mode = mode
        self.device_line = net.open_line(bus_name, mode=mode)
        self.device = self.device_line.create_local_node(
            DEVICE, od=device_od or demo_od(mode, pdos=1))
        self.line = net.open_line(bus_name, mode=mode)
        self.frames = Recorder()
        net.open_line(bus_name, mode=mode, monitor=True).on_frame(self.frames)
        self.drive = self.line.add_node(DEVICE, od=master_od or demo_od(mode, pdos=1))
        self.rpdo = self.drive.rpdo[1]
        self.received = Recorder()
        self.device.rpdo[1].add_callback(lambda pdo: self.received([v.raw for v in pdo]))

    def configure(self, entries, trans_type=255):
        """Map `entries` (add_variable arguments) into the device's RPDO 1 over
        USDO/SDO, enable it, start the device."""
        rpdo = self.rpdo
        rpdo.read()
        rpdo.clear()
        for entry in entries:
            rpdo.add_variable(*entry)
        rpdo.trans_type = trans_type
        rpdo.enabled = True
        rpdo.save()
        self.drive.start()
        self.device.nmt.wait_for_state("OPERATIONAL", timeout=scaled(2))

    def pdo_frames(self, start=0):
        return [f for f in self.frames.snapshot()[start:] if f.id == RPDO_ID and not f.rtr]

    def wait_pdo(self, count, start=0, timeout=2.0):
        def enough(_calls):
            got = self.pdo_frames(start)
            return got if len(got) >= count else None
        return self.frames.wait_for(enough, timeout, f"{count} frames on 0x{RPDO_ID:X}")


@pytest.fixture
def rig(net, bus_name, mode):
    return Rig(net, bus_name, mode)


# ------------------------------------------------------------------ once, on the wire
def test_transmit_sends_the_mapped_bytes_on_the_device_rpdo_cob_id(rig):
    rig.configure([(P1,), (P2, None, 16)])
    rig.rpdo[P1].raw = 0x11223344
    rig.rpdo[P2].raw = 0x5566
    start = len(rig.frames)
    rig.rpdo.transmit()
    [frame] = rig.wait_pdo(1, start)
    assert frame.data == bytes.fromhex("44332211 6655")
    assert frame.fd == (rig.mode == "fd") and not frame.ext
    rig.received.wait_value([0x11223344, 0x5566])
    time.sleep(scaled(0.05))
    assert len(rig.pdo_frames(start)) == 1                      # once means once
    assert rig.rpdo.producer_stats == {"sent": 1, "tx_failed": 0, "not_operational": 0,
                                       "writes": 1}


def test_fd_pdo_of_nine_bytes_is_padded_to_twelve(net, bus_name):
    rig = Rig(net, bus_name, "fd")
    rig.configure([(P1,), (P2,), (0x2300, 3, 8)])
    rig.rpdo[P1].raw, rig.rpdo[P2].raw = 1, 2
    rig.rpdo["Process data.Process data 3"].raw = 0xAB
    start = len(rig.frames)
    rig.rpdo.transmit()
    [frame] = rig.wait_pdo(1, start)
    assert frame.fd and frame.data == bytes.fromhex("01000000 02000000 ab 000000")
    rig.received.wait_value([1, 2, 0xAB])


def test_classic_bitwise_mapping_packs_bits(net, bus_name):
    """4 bits, 12 bits, 1 bit of three UNSIGNED32s: the bits land where the
    mapping says, and our device decodes them back."""
    rig = Rig(net, bus_name, "classic")
    rig.configure([(P1, None, 4), (P2, None, 12), (0x2300, 3, 1)])
    rig.rpdo[P1].raw = 0xA
    rig.rpdo[P2].raw = 0x123
    rig.rpdo[2].raw = 1
    start = len(rig.frames)
    rig.rpdo.transmit()
    [frame] = rig.wait_pdo(1, start)
    assert not frame.fd and frame.data == (0xA | 0x123 << 4 | 1 << 16).to_bytes(3, "little")
    rig.received.wait_value([0xA, 0x123, 1])
    with pytest.raises(ConfigurationError, match=r"node 5 RPDO1 'Process data.Process data 1'"
                                                 r": 16 does not fit the 4 mapped bits .*0..15"):
        rig.rpdo[P1].raw = 16
    rig.rpdo[P2].raw = 0                               # the neighbours' bits stay
    start = len(rig.frames)
    rig.rpdo.transmit()
    assert rig.wait_pdo(1, start)[0].data == bytes([0x0A, 0x00, 0x01])


# ------------------------------------------------------------------ periodic
def test_start_sends_periodically_and_stop_really_stops(rig):
    rig.configure([(P1,)])
    rig.rpdo[P1].raw = 7
    start = len(rig.frames)
    began = time.monotonic()
    rig.rpdo.start(0.005)
    time.sleep(0.3)
    rig.rpdo.stop()
    elapsed = time.monotonic() - began
    sent = rig.rpdo.producer_stats["sent"]
    # a count over a window, not a timing assertion: at least a third of the
    # nominal number of frames, never more than the period allows
    assert elapsed / 0.005 / 3 <= sent <= elapsed / 0.005 + 2, (sent, elapsed)
    rig.wait_pdo(sent, start)
    settled = len(rig.pdo_frames(start))
    time.sleep(scaled(0.1))
    assert len(rig.pdo_frames(start)) == settled == sent       # nothing after stop()
    assert all(f.data == bytes([7, 0, 0, 0]) for f in rig.pdo_frames(start))


def test_a_value_set_while_running_is_in_the_next_frames_never_torn(rig):
    """While the runtime sends every 1 ms, a 32-bit entry flips between all
    zeros and all ones: every frame carries one of them whole."""
    rig.configure([(P1,)])
    rig.rpdo.start(0.001)
    try:
        start = len(rig.frames)
        for i in range(300):
            rig.rpdo[P1].raw = 0xFFFFFFFF if i % 2 else 0
        rig.rpdo[P1].raw = 0x01020304
        final = b"\x04\x03\x02\x01"
        rig.frames.wait_for(lambda _: sum(f.data == final for f in rig.pdo_frames(start)) >= 3,
                            2, "3 frames with the last value")
    finally:
        rig.rpdo.stop()
    frames = rig.pdo_frames(start)
    assert all(f.data in (b"\0\0\0\0", b"\xff\xff\xff\xff", final)
               for f in frames), [f.data.hex() for f in frames if len(set(f.data)) > 1][:5]
    first = [f.data for f in frames].index(final)
    assert all(f.data == final for f in frames[first:])    # from then on, only the new value
    rig.received.wait_value([0x01020304])


def test_restarting_with_a_new_period_replaces_the_old_one(rig):
    rig.configure([(P1,)])
    began = time.monotonic()
    rig.rpdo.start(0.002)
    rig.rpdo.start(0.05)                 # one timer per RPDO: the slower period wins
    time.sleep(0.3)
    rig.rpdo.stop()
    elapsed = time.monotonic() - began
    assert rig.rpdo.producer_stats["sent"] <= elapsed / 0.05 + 3


# ------------------------------------------------------------------ SYNC
def test_start_sync_every_second_sync_follows_the_sync(rig):
    rig.configure([(P1,)])
    rig.rpdo[P1].raw = 9
    start = len(rig.frames)
    rig.rpdo.start_sync(every=2)
    rig.line.sync.start(0.01)
    try:
        rig.wait_pdo(5, start)
    finally:
        rig.line.sync.stop()
        rig.rpdo.stop()
    time.sleep(scaled(0.05))
    seen = [f for f in rig.frames.snapshot()[start:] if f.id in (0x80, RPDO_ID)]
    ids = [f.id for f in seen]
    first_sync = ids.index(0x80)
    # SYNC, SYNC, RPDO, SYNC, SYNC, RPDO ...: each RPDO right after every 2nd SYNC
    pairs = ids[first_sync:]
    for i, can_id in enumerate(pairs):
        if can_id == RPDO_ID:
            assert pairs[i - 1] == 0x80 and pairs[i - 2] == 0x80, ids
    syncs, pdos = pairs.count(0x80), pairs.count(RPDO_ID)
    assert syncs // 2 - 1 <= pdos <= syncs // 2 + 1, ids


def test_start_sync_follows_a_sync_another_node_produces(rig):
    """The SYNC comes from the device's line (its OD's 0x1005/0x1006): the
    master's line consumes it and sends the RPDO right after each one."""
    rig.configure([(P1,)])
    start = len(rig.frames)
    rig.rpdo.start_sync(every=1)
    rig.device_line.sync.start(0.01)
    try:
        rig.wait_pdo(4, start)
    finally:
        rig.device_line.sync.stop()
        rig.rpdo.stop()
    ids = [f.id for f in rig.frames.snapshot()[start:] if f.id in (0x80, RPDO_ID)]
    for i, can_id in enumerate(ids):
        if can_id == RPDO_ID:
            assert ids[i - 1] == 0x80, ids
    assert ids.count(RPDO_ID) >= 4


def test_acyclic_type_0_sends_after_the_first_sync_after_a_change(rig):
    rig.configure([(P1,)], trans_type=0)
    rig.rpdo[P1].raw = 1
    start = len(rig.frames)
    rig.rpdo.start_sync()                # type 0 read from the node: acyclic
    rig.line.sync.start(0.01)
    try:
        rig.wait_pdo(1, start)
        time.sleep(0.1)                  # ~10 SYNCs, nothing changed
        assert len(rig.pdo_frames(start)) == 1
        rig.rpdo[P1].raw = 2
        frames = rig.wait_pdo(2, start)
        time.sleep(0.05)
        assert len(rig.pdo_frames(start)) == 2 and frames[1].data == bytes([2, 0, 0, 0])
    finally:
        rig.line.sync.stop()
        rig.rpdo.stop()
    rig.received.wait_value([2])         # the device applied it at its next SYNC


def test_start_sync_with_type_n_sends_after_every_nth_sync(rig):
    rig.configure([(P1,)], trans_type=3)
    start = len(rig.frames)
    rig.rpdo.start_sync()
    rig.line.sync.start(0.005)
    try:
        rig.wait_pdo(3, start)
    finally:
        rig.line.sync.stop()
        rig.rpdo.stop()
    ids = [f.id for f in rig.frames.snapshot()[start:] if f.id in (0x80, RPDO_ID)]
    first = ids.index(RPDO_ID)
    second = ids.index(RPDO_ID, first + 1)
    assert ids[first + 1:second] == [0x80] * 3, ids


# ------------------------------------------------------------------ NMT of the master
def test_a_master_with_a_local_node_sends_only_while_it_is_operational(rig):
    rig.configure([(P1,)])
    me = rig.line.create_local_node(1)
    me.nmt.wait_for_state("PRE-OPERATIONAL", timeout=scaled(2))
    with pytest.raises(CanopenFDError, match=r"node 5 RPDO1: transmit\(\).*not OPERATIONAL"):
        rig.rpdo.transmit()
    rig.rpdo.start(0.005)
    deadline = time.monotonic() + scaled(2)
    while rig.rpdo.producer_stats["not_operational"] < 3 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert rig.rpdo.producer_stats["not_operational"] >= 3     # held back, counted
    assert rig.pdo_frames() == []
    me.nmt.state = "OPERATIONAL"
    rig.wait_pdo(3)
    rig.rpdo.stop()


# ------------------------------------------------------------------ mapping from the EDS
def _enabled_rpdo_od(mode):
    """demo_od(pdos=1) whose RPDO 1 is valid on 0x205 with 0x2300:01 mapped
    (as a DCF would describe the device)."""
    od = demo_od(mode, pdos=1)
    od.get_variable(0x1400, 1).set_default(0x200, relative_to_node_id=True)
    od.get_variable(0x1600, 0).default = 1
    od.get_variable(0x1600, 1).default = 0x23000120
    return od


def test_mapping_from_the_eds_with_read_from_od(net, bus_name, mode):
    rig = Rig(net, bus_name, mode, device_od=_enabled_rpdo_od(mode),
              master_od=_enabled_rpdo_od(mode))
    rig.rpdo.read(from_od=True)          # no transfer: the OD's values
    assert (rig.rpdo.cob_id, rig.rpdo.enabled, [v.name for v in rig.rpdo]) == \
        (RPDO_ID, True, [P1])
    rig.drive.start()
    rig.device.nmt.wait_for_state("OPERATIONAL", timeout=scaled(2))
    rig.rpdo[P1].raw = 0xCAFE
    rig.rpdo.transmit()
    assert rig.wait_pdo(1)[0].data == bytes.fromhex("feca0000")
    rig.received.wait_value([0xCAFE])


def test_a_new_cob_id_moves_a_running_producer(rig):
    rig.configure([(P1,)])
    rig.rpdo[P1].raw = 5
    rig.rpdo.start(0.005)
    rig.wait_pdo(2)
    rig.rpdo.cob_id = 0x305
    mark = len(rig.frames)
    try:
        rig.frames.wait_for(lambda calls: any(f.id == 0x305 for f in calls[mark:]), 2,
                            "frames on the new COB-ID")
    finally:
        rig.rpdo.stop()
    moved = [f for f in rig.frames.snapshot()[mark:] if f.id == 0x305]
    assert moved[0].data == bytes([5, 0, 0, 0])          # the values move along


# ------------------------------------------------------------------ errors
def test_errors_name_node_pdo_variable_and_expected(rig):
    with pytest.raises(KeyError, match=r"node 5 RPDO1: 'Process data.Process data 1': the "
                                       r"mapping is not known yet; read\(\)"):
        rig.rpdo[P1]
    with pytest.raises(ConfigurationError, match=r"node 5 RPDO1: transmit\(\): nothing "
                                                 r"mapped; read\(\)"):
        rig.rpdo.transmit()
    rig.rpdo.read()                      # the demo's RPDO: predefined COB-ID, invalid
    rig.rpdo.add_variable(P1)
    with pytest.raises(ConfigurationError, match=r"node 5 RPDO1: transmit\(\): the PDO is "
                                                 r"disabled \(COB-ID 0x205 with bit 31"):
        rig.rpdo.transmit()
    with pytest.raises(ConfigurationError, match=r"node 5 RPDO1 'Process data.Process data 1'"
                                                 r" \(UNSIGNED32\): .*-1"):
        rig.rpdo[P1].raw = -1
    with pytest.raises(ConfigurationError, match=r"node 5 RPDO1 'Process data.Process data 1'"
                                                 r" \(UNSIGNED32\): .*int"):
        rig.rpdo[P1].raw = "fast"
    with pytest.raises(ConfigurationError, match=r"data must be 4 bytes, got 2"):
        rig.rpdo[P1].data = b"\x01\x02"
    for bad in (0, -0.01, "1", None, True):
        with pytest.raises(ConfigurationError, match=rf"node 5 RPDO1: start\({re.escape(repr(bad))}"
                                                     r"\): the period must be a number of "
                                                     r"seconds > 0"):
            rig.rpdo.start(bad)
    with pytest.raises(ConfigurationError, match=r"0.0001 .. 4294 s, got 1e-05"):
        rig.rpdo.start(0.00001)
    with pytest.raises(ConfigurationError, match=r"start_sync\(0\): every must be 1..240"):
        rig.rpdo.start_sync(0)
    with pytest.raises(ConfigurationError, match=r"transmission type is 255, not synchronous"):
        rig.rpdo.start_sync()
    with pytest.raises(ConfigurationError, match=r"node 5 TPDO1: transmit\(\) sends a remote "
                                                 r"node's RPDOs"):
        rig.drive.tpdo[1].transmit()
    with pytest.raises(ConfigurationError, match=r"node 5 TPDO1: start\(0.01\) is for a remote "
                                                 r"node's RPDOs"):
        rig.drive.tpdo[1].start(0.01)
    rig.drive.tpdo[1].add_variable(P1)
    with pytest.raises(ConfigurationError, match=r"a remote node's TPDO is what it sends"):
        rig.drive.tpdo[1][P1].raw = 1
    assert rig.pdo_frames() == []


def test_values_set_before_the_first_send_are_kept_and_readable(rig):
    rig.configure([(P1,), (P2, None, 16)])
    rig.rpdo[P1].phys = 3                # no factor: phys is raw
    rig.rpdo[P2].data = b"\x34\x12\x00\x00"
    assert (rig.rpdo[P1].raw, rig.rpdo[P2].raw, bytes(rig.rpdo.data)) == \
        (3, 0x1234, bytes.fromhex("03000000 3412"))
    rig.rpdo.transmit()
    assert rig.wait_pdo(1)[0].data == bytes.fromhex("03000000 3412")


def test_phys_uses_the_od_factor(net, bus_name):
    master_od = demo_od("classic", pdos=1)
    master_od.get_variable(0x2300, 1).factor = 0.5       # EDS "Factor": raw 1 = 0.5 units
    rig = Rig(net, bus_name, "classic", master_od=master_od)
    rig.configure([(P1,)])
    rig.rpdo[P1].phys = 10.0
    assert (rig.rpdo[P1].raw, rig.rpdo[P1].phys) == (20, 10.0)
    rig.rpdo.transmit()
    assert rig.wait_pdo(1)[0].data == bytes([20, 0, 0, 0])


def test_local_node_tpdo_variable_set_writes_its_od(net, bus_name, mode):
    me = net.open_line(bus_name, mode=mode).create_local_node(DEVICE, od=demo_od(mode, pdos=1))
    tpdo = me.tpdo[1]
    tpdo.read()
    tpdo.clear()
    tpdo.add_variable(P1)
    tpdo.enabled = True
    tpdo.save()
    tpdo[P1].raw = 77
    assert me[P1].raw == 77              # the local PDO carries its OD's value
    frames = Recorder()
    net.open_line(bus_name, mode=mode, monitor=True).on_frame(frames)
    me.nmt.state = "OPERATIONAL"
    me.nmt.wait_for_state("OPERATIONAL", timeout=scaled(2))
    tpdo.transmit()
    frames.wait_for(lambda calls: [f for f in calls if f.id == 0x185], 2, "TPDO 1")
    assert [f.data for f in frames.snapshot() if f.id == 0x185][0] == bytes([77, 0, 0, 0])


def test_removing_the_node_frees_its_producers(rig):
    rig.configure([(P1,)])
    rig.rpdo.start(0.005)
    rig.wait_pdo(2)
    rig.line.remove_node(DEVICE)
    time.sleep(scaled(0.03))
    mark = len(rig.pdo_frames())
    time.sleep(scaled(0.1))
    assert len(rig.pdo_frames()) == mark


def test_one_runtime_write_per_set_and_32_producers_per_line(net, bus_name):
    """Each `raw =` is one write into the runtime's frame (none per frame);
    a line produces at most 32 RPDOs of other nodes, the 33rd is refused by
    name. No device needed: the frames go out on the bus regardless."""
    line = net.open_line(bus_name, mode="classic")
    frames = Recorder()
    net.open_line(bus_name, mode="classic", monitor=True).on_frame(frames)
    maps = []
    for node_id in range(1, 10):
        drive = line.add_node(node_id, od=demo_od("classic", pdos=4))
        for number in range(1, 5):
            rpdo = drive.rpdo[number]
            rpdo.cob_id = 0x200 + 0x100 * (number - 1) + node_id
            rpdo.enabled = True
            rpdo.add_variable(P1)
            maps.append(rpdo)
    for rpdo in maps[:32]:
        rpdo.transmit()
    with pytest.raises(CanopenFDError, match=r"node 9 RPDO1: transmit\(\): already "
                                             r"32 RPDO producers"):
        maps[32].transmit()
    first = maps[0]
    first.start(0.002)
    for value in range(10):
        first[P1].raw = value
    time.sleep(0.05)
    first.stop()
    stats = first.producer_stats
    assert stats["writes"] == 1 + 10 and stats["sent"] >= 5, stats   # opening + 10 sets
    line.remove_node(1)                  # frees its 4 slots
    maps[32].transmit()
    frames.wait_for(lambda calls: [f for f in calls if f.id == 0x209], 2, "node 9's RPDO 1")


def test_a_new_object_dictionary_stops_the_old_maps_producers(rig):
    rig.configure([(P1,)])
    rig.rpdo.start(0.005)
    rig.wait_pdo(2)
    again = rig.line.add_node(DEVICE, od=demo_od(rig.mode, pdos=1))
    assert again is rig.drive and again.rpdo[1] is not rig.rpdo
    time.sleep(scaled(0.03))
    mark = len(rig.pdo_frames())
    time.sleep(scaled(0.1))
    assert len(rig.pdo_frames()) == mark


# ------------------------------------------------------------------ python-canopen as the device
def _their_od():
    """python-canopen's OD of node 7: RPDO 1 (0x1400/0x1600, 4 slots) and
    two mappable entries, a CiA 402-like Controlword and a target."""
    canopen = pytest.importorskip("canopen")
    od = canopen.ObjectDictionary()
    for index, name, dtype in ((0x6040, "Controlword", canopen.objectdictionary.UNSIGNED16),
                               (0x607A, "Target position", canopen.objectdictionary.INTEGER32)):
        var = canopen.objectdictionary.ODVariable(name, index, 0)
        var.data_type, var.access_type, var.pdo_mappable, var.default = dtype, "rw", True, 0
        od.add_object(var)
    record = canopen.objectdictionary.ODRecord("RPDO1 comm", 0x1400)
    for sub, dtype, default in ((0, canopen.objectdictionary.UNSIGNED8, 5),
                                (1, canopen.objectdictionary.UNSIGNED32, 0x80000207),
                                (2, canopen.objectdictionary.UNSIGNED8, 255),
                                (5, canopen.objectdictionary.UNSIGNED16, 0)):
        var = canopen.objectdictionary.ODVariable(f"sub{sub}", 0x1400, sub)
        var.data_type, var.access_type, var.default = dtype, "ro" if sub == 0 else "rw", default
        record.add_member(var)
    od.add_object(record)
    array = canopen.objectdictionary.ODArray("RPDO1 mapping", 0x1600)
    for sub in range(5):
        var = canopen.objectdictionary.ODVariable(f"sub{sub}", 0x1600, sub)
        var.data_type = canopen.objectdictionary.UNSIGNED8 if sub == 0 else \
            canopen.objectdictionary.UNSIGNED32
        var.access_type, var.default = "rw", 0
        array.add_member(var)
    od.add_object(array)
    return od


def _our_view_of_their_od():
    from canopenfd.od import ODArray, ODRecord, ODVariable
    U8, U16, U32 = DataType.UNSIGNED8, DataType.UNSIGNED16, DataType.UNSIGNED32
    od = canopenfd.ObjectDictionary(mode="classic")
    od.add_object(ODVariable("Controlword", 0x6040, 0, U16, "rw", 0, pdo_mapping=True))
    od.add_object(ODVariable("Target position", 0x607A, 0, DataType.INTEGER32, "rw", 0,
                             pdo_mapping=True))
    record = ODRecord("RPDO1 comm", 0x1400)
    record.add_member(ODVariable("sub0", 0x1400, 0, U8, "ro", 5))
    for sub, dtype in ((1, U32), (2, U8), (5, U16)):
        record.add_member(ODVariable(f"sub{sub}", 0x1400, sub, dtype, "rw", 0))
    od.add_object(record)
    array = ODArray("RPDO1 mapping", 0x1600)
    array.add_member(ODVariable("sub0", 0x1600, 0, U8, "rw", 0))
    for sub in range(1, 5):
        array.add_member(ODVariable(f"sub{sub}", 0x1600, sub, U32, "rw", 0))
    od.add_object(array)
    return od


def test_python_canopen_local_node_receives_what_our_master_drives():
    """The CiA 402 way against python-canopen's LocalNode 7 on a python-can
    virtual bus: our master maps Controlword and Target position into its
    RPDO 1 over SDO, then sends once, periodically and stops; python-canopen
    decodes every frame with its own RPDO map."""
    canopen = pytest.importorskip("canopen")
    channel = f"rpdo-{os.getpid()}-{next(_channels)}"
    peer = canopen.Network()
    peer.connect(interface="virtual", channel=channel)
    theirs = peer.create_node(7, _their_od())
    try:
        with canopenfd.Network() as net:
            line = net.open_line(bus=virtual_bus(channel), mode="classic")
            drive = line.add_node(7, od=_our_view_of_their_od())
            rpdo = drive.rpdo[1]
            rpdo.read()                                  # over SDO from python-canopen
            assert (rpdo.cob_id, rpdo.enabled) == (0x207, False)
            rpdo.clear()
            rpdo.add_variable("Controlword")
            rpdo.add_variable("Target position")
            rpdo.enabled = True
            rpdo.save()
            theirs.rpdo.read()                           # python-canopen reads what we saved
            their_map = theirs.rpdo[1]
            assert (their_map.cob_id, their_map.enabled) == (0x207, True)
            heard = Recorder()
            their_map.add_callback(lambda pdo: heard((pdo["Controlword"].raw,
                                                      pdo["Target position"].raw)))
            rpdo["Controlword"].raw = 15
            rpdo["Target position"].raw = -1000
            rpdo.transmit()
            heard.wait_value((15, -1000))
            rpdo.start(0.01)
            rpdo["Controlword"].raw = 0x1F
            heard.wait_value((0x1F, -1000))
            count = len(heard)
            heard.wait_count(count + 5)                  # it keeps coming, every 10 ms
            rpdo.stop()
            time.sleep(scaled(0.05))
            settled = len(heard)
            time.sleep(scaled(0.1))
            assert len(heard) == settled                 # and stops
    finally:
        peer.disconnect()


# ------------------------------------------------------------------ example and README
def test_example_master_drives_rpdo_runs():
    for extra in ([], ["--classic"]):
        result = subprocess.run([sys.executable, os.path.join(ROOT, "examples",
                                                              "master_drives_rpdo.py"), *extra],
                                capture_output=True, text=True, timeout=scaled(60),
                                env=package_env(), check=False)
        assert result.returncode == 0, result.stderr
        out = result.stdout
        assert "device: RPDO1 received [15, 4660]" in out
        match = re.search(r"periodic: (\d+) frames sent, last value seen by the device "
                          r"\[31, 4660\]", out)
        assert match and int(match.group(1)) >= 5, out
        match = re.search(r"SYNC-driven: (\d+) frames sent", out)
        assert match and int(match.group(1)) >= 3, out


README_MARKER = "<!-- test: master-rpdo -->"


def readme_block() -> str:
    """The python block right after README_MARKER in README.md."""
    with open(os.path.join(ROOT, "README.md"), encoding="utf-8") as f:
        text = f.read()
    assert README_MARKER in text, f"README.md lost its {README_MARKER} block"
    match = re.match(r"\s*```python\n(.*?)```", text.split(README_MARKER, 1)[1], re.S)
    assert match, f"no ```python block right after {README_MARKER}"
    return match.group(1)


def test_readme_driving_a_device_rpdo_block_runs(net, bus_name):
    """The README snippet, with `line` a master line and node 5 our device
    serving demo_od(pdos=1) ("drive.eds" is that OD exported as an EDS)."""
    import tempfile
    device = net.open_line(bus_name, mode="fd").create_local_node(DEVICE,
                                                                  od=demo_od("fd", pdos=1))
    received = Recorder()
    device.rpdo[1].add_callback(lambda pdo: received([v.raw for v in pdo]))
    line = net.open_line(bus_name, mode="fd")
    with tempfile.TemporaryDirectory() as folder:
        export_eds(demo_od("fd", pdos=1), os.path.join(folder, "drive.eds"))
        cwd = os.getcwd()
        os.chdir(folder)
        try:
            exec(compile(readme_block(), "README.md:master-rpdo", "exec"),
                 {"line": line, "time": time})
        finally:
            os.chdir(cwd)
    received.wait_value([15, 0])
