"""Process data and errors on real kernel SocketCAN (vcan): exact FD PDO,
EMCY and SYNC frames captured with a raw socket, and interop with
python-canopen (PyPI `canopen`) on the classic vcan. Needs CANOPENFD_VCAN
(see tests/test_vcan.py); tests/vm/run_in_vm.sh provides it."""

from __future__ import annotations

import time

import pytest
from helpers import Recorder, scaled
from test_services import pdo_od

import canopenfd
from canopenfd.od import DataType, ODArray, ODVariable

pytestmark = pytest.mark.vcan
can = pytest.importorskip("can")

NODE = 5
U8, U32, U64 = DataType.UNSIGNED8, DataType.UNSIGNED32, DataType.UNSIGNED64


@pytest.fixture
def ifaces(vcan):
    return {"fd": vcan[0], "classic": vcan[2]}


@pytest.fixture
def networks():
    made = []

    def make():
        made.append(canopenfd.Network())
        return made[-1]

    yield make
    for net in made:
        net.close()


@pytest.fixture
def raw_buses():
    made = []

    def make(channel, fd=True):
        bus = can.Bus(interface="socketcan", channel=channel, fd=fd)
        made.append(bus)
        return bus

    yield make
    for bus in made:
        bus.shutdown()


def recv_all(bus, can_id, count, timeout=5.0):
    """The first `count` data frames with can_id on a raw python-can bus."""
    deadline = time.monotonic() + scaled(timeout)
    got = []
    while len(got) < count:
        remaining = deadline - time.monotonic()
        assert remaining > 0, f"{len(got)} of {count} frames 0x{can_id:X} in {scaled(timeout)} s"
        msg = bus.recv(max(0.01, remaining))
        if msg is not None and not msg.is_error_frame and msg.arbitration_id == can_id:
            got.append(msg)
    return got


def fd_od():
    """pdo_od('fd') plus 8 x UNSIGNED64 (0x2100), an UNSIGNED8 (0x2101) and an
    UNSIGNED32 (0x2102), mappable both ways."""
    od = pdo_od("fd")
    wide = ODArray("Wide values", 0x2100)
    wide.add_member(ODVariable("Highest sub-index supported", 0x2100, 0, U8, "ro", 8))
    for sub in range(1, 9):
        wide.add_member(ODVariable(f"Wide {sub}", 0x2100, sub, U64, "rw", 0, pdo_mapping=True))
    od.add_object(wide)
    od.add_object(ODVariable("Small", 0x2101, 0, U8, "rw", 0, pdo_mapping=True))
    od.add_object(ODVariable("Middle", 0x2102, 0, U32, "rw", 0, pdo_mapping=True))
    return od


def map_pdo(pdo, entries, cob_id, trans_type=254):
    pdo.read()
    pdo.clear()
    for entry in entries:
        pdo.add_variable(*entry)
    pdo.cob_id = cob_id
    pdo.trans_type = trans_type
    pdo.enabled = True
    pdo.save()
    return pdo


def start(node):
    node.apply("start")
    node.wait_for_state("OPERATIONAL", timeout=scaled(5))


# ------------------------------------------------------------------ CAN FD wire
def test_fd_64_byte_tpdo_exact_bytes_and_heard_by_a_remote_tpdo(ifaces, networks, raw_buses):
    raw = raw_buses(ifaces["fd"])
    me = networks().open_line(ifaces["fd"], mode="fd").create_local_node(NODE, od=fd_od())
    tpdo = map_pdo(me.tpdo[1], [(0x2100, sub) for sub in range(1, 9)], 0x180 + NODE)
    values = [int.from_bytes(bytes(range(8 * sub - 8, 8 * sub)), "little") for sub in range(1, 9)]
    for sub, value in enumerate(values, 1):
        me[(0x2100, sub)].raw = value
    listener = networks().open_line(ifaces["fd"], mode="fd").add_node(NODE, od=fd_od())
    listener.tpdo[1].read()                               # over USDO on the wire
    heard = Recorder()
    listener.tpdo[1].add_callback(lambda pdo: heard([v.raw for v in pdo]))
    start(me)
    tpdo.transmit()
    msg = recv_all(raw, 0x180 + NODE, 1)[0]
    assert bytes(msg.data) == bytes(range(64))
    assert msg.is_fd and msg.bitrate_switch and not msg.is_extended_id
    assert heard.wait_count(1)[0] == values


def test_fd_13_byte_mapping_is_padded_to_16_and_applied_by_an_rpdo(ifaces, networks, raw_buses):
    raw = raw_buses(ifaces["fd"])
    entries = [(0x2100, 1), (0x2102, 0), (0x2101, 0)]      # 8 + 4 + 1 bytes
    me = networks().open_line(ifaces["fd"], mode="fd").create_local_node(NODE, od=fd_od())
    tpdo = map_pdo(me.tpdo[1], entries, 0x180 + NODE)
    receiver = networks().open_line(ifaces["fd"], mode="fd").create_local_node(6, od=fd_od())
    rpdo = map_pdo(receiver.rpdo[1], entries, 0x180 + NODE, trans_type=255)
    got = Recorder()
    rpdo.add_callback(lambda pdo: got((len(pdo.data), [v.raw for v in pdo])))
    values = [0x1122334455667788, 0xA1B2C3D4, 0x7E]
    for (index, sub), value in zip(entries, values):
        me[(index, sub)].raw = value
    start(receiver)
    start(me)
    tpdo.transmit()
    msg = recv_all(raw, 0x180 + NODE, 1)[0]
    assert bytes(msg.data).hex(" ") == ("88 77 66 55 44 33 22 11 d4 c3 b2 a1 7e "
                                        "00 00 00") and msg.is_fd
    assert got.wait_count(1)[0] == (13, values)
    assert [receiver[entry].raw for entry in entries] == values


def test_fd_emcy_raise_and_clear_exact_20_byte_frames(ifaces, networks, raw_buses):
    raw = raw_buses(ifaces["fd"])
    me = networks().open_line(ifaces["fd"], mode="fd").create_local_node(NODE)
    assert me.emcy.raise_error(0x2310, b"\x01\x02\x03\x04\x05", register_bits=0x80,
                               logical_device=2, spec_number=0x012D, priority=3,
                               non_recoverable=True, time_stamp=0x123456789A)
    assert me.emcy.clear(0x2310, logical_device=2, time_stamp=7)
    raised, cleared = recv_all(raw, 0x80 + NODE, 2)
    assert raised.is_fd and len(raised.data) == 20 and len(cleared.data) == 20
    assert bytes(raised.data).hex(" ") == ("10 23 83 01 02 03 04 05 02 2d 01 1b "
                                           "9a 78 56 34 12 00 00 00")
    assert bytes(cleared.data).hex(" ") == ("10 23 00 00 00 00 00 00 02 2d 01 0b "
                                            "07 00 00 00 00 00 00 00")


def test_fd_sync_with_counter_on_the_wire(ifaces, networks, raw_buses):
    raw = raw_buses(ifaces["fd"])
    producer = networks().open_line(ifaces["fd"], mode="fd")
    counters = Recorder()
    # the producer's own callbacks (a line without a local node expects no counter:
    # 0x1019 = 0, so it refuses counter SYNCs of others as CiA 301 says)
    producer.sync.add_callback(counters)
    producer.sync.start(0.01, overflow=4)
    try:
        frames = recv_all(raw, 0x80, 6)
    finally:
        producer.sync.stop()
    values = [msg.data[0] for msg in frames]
    assert all(len(msg.data) == 1 for msg in frames) and set(values) <= {1, 2, 3, 4}
    assert {(b - a) % 4 for a, b in zip(values, values[1:])} == {1}
    heard = counters.wait_count(6)
    assert {(b - a) % 4 for a, b in zip(heard, heard[1:6])} == {1} and set(heard) <= {1, 2, 3, 4}


# ------------------------------------------------------------------ python-canopen, classic
canopen = pytest.importorskip("canopen")


@pytest.fixture
def peer(ifaces):
    network = canopen.Network()
    network.connect(interface="socketcan", channel=ifaces["classic"])
    yield network
    network.disconnect()


@pytest.fixture
def classic(ifaces, networks):
    return networks().open_line(ifaces["classic"], mode="classic")


@pytest.fixture
def eds(tmp_path):
    """Our node's OD as an EDS python-canopen imports."""
    from canopenfd.od.eds import export_eds

    path = tmp_path / "node.eds"
    export_eds(pdo_od("classic"), str(path))
    return str(path)


def test_python_canopen_reads_our_pdos_and_exchanges_process_data(classic, peer, eds):
    me = classic.create_local_node(NODE, od=pdo_od("classic"))
    map_pdo(me.rpdo[1], [("Demo UNSIGNED32",), ("Demo record.Setpoint",)], 0x200 + NODE,
            trans_type=255)
    tpdo = map_pdo(me.tpdo[1], [("Demo UNSIGNED16",), ("Demo record.Setpoint",)], 0x180 + NODE)
    ours = Recorder()
    me.rpdo[1].add_callback(lambda pdo: ours([v.raw for v in pdo]))
    start(me)
    theirs = peer.add_node(NODE, eds)
    theirs.rpdo.read()                                   # SDO from our node
    theirs.tpdo.read()
    heard = Recorder()
    theirs.tpdo[1].add_callback(lambda pdo: heard([v.raw for v in pdo.map]))
    # (a) python-canopen's PDO -> our RPDO
    theirs.rpdo[1].map[0].raw = 0x12345678
    theirs.rpdo[1].map[1].raw = -1234
    theirs.rpdo[1].transmit()
    assert ours.wait_count(1)[0] == [0x12345678, -1234]
    assert me["Demo UNSIGNED32"].raw == 0x12345678
    # (b) our TPDO -> python-canopen's RemoteNode.tpdo[1]
    me["Demo UNSIGNED16"].raw = 4321
    me["Demo record.Setpoint"].raw = -5
    tpdo.transmit()
    assert heard.wait_count(1)[0] == [4321, -5]


def test_python_canopen_sync_drives_our_synchronous_tpdo(classic, peer, raw_buses, ifaces):
    raw = raw_buses(ifaces["classic"], fd=False)
    me = classic.create_local_node(NODE, od=pdo_od("classic"))
    map_pdo(me.tpdo[1], [("Demo UNSIGNED16",)], 0x180 + NODE, trans_type=1)
    me["Demo UNSIGNED16"].raw = 0x0102
    start(me)
    peer.sync.start(0.05)
    try:
        seen = []
        deadline = time.monotonic() + scaled(5)
        while len([m for m in seen if m.arbitration_id == 0x180 + NODE]) < 4:
            assert time.monotonic() < deadline, [hex(m.arbitration_id) for m in seen]
            msg = raw.recv(0.1)
            if msg is not None and msg.arbitration_id in (0x80, 0x180 + NODE):
                seen.append(msg)
    finally:
        peer.sync.stop()
    pdos = [i for i, m in enumerate(seen) if m.arbitration_id == 0x180 + NODE]
    assert all(bytes(seen[i].data) == b"\x02\x01" for i in pdos)
    # each TPDO follows a SYNC, one TPDO per SYNC
    assert all(i > 0 and seen[i - 1].arbitration_id == 0x80 for i in pdos)
    syncs = [m for m in seen[pdos[0]:] if m.arbitration_id == 0x80]
    assert len(syncs) <= len(pdos) + 1


def test_python_canopen_emcy_consumer_gets_ours(classic, peer):
    me = classic.create_local_node(NODE)
    theirs = peer.add_node(NODE)
    got = Recorder()
    theirs.emcy.add_callback(got)            # python-canopen's wait() misses an early EMCY
    assert me.emcy.raise_error(0x2310, b"\x01\x02", register_bits=0x80)
    error = got.wait_count(1)[0]
    assert (error.code, error.register, bytes(error.data)) == \
        (0x2310, 0x83, b"\x01\x02\x00\x00\x00")
    assert theirs.emcy.active[0].code == 0x2310
    assert me.emcy.clear(0x2310)
    reset = got.wait_count(2)[1]
    assert (reset.code, reset.register, bytes(reset.data)) == (0, 0, bytes(5))
    assert theirs.emcy.active == []
