"""PDO configuration (canopenfd.services.pdo): node.tpdo / node.rpdo with python-canopen's
names. save() is checked frame by frame on the bus (the CiA 301 procedure over
SDO on classic lines, USDO on fd lines), read() against what was saved on our
own server and on python-canopen's LocalNode, and every check that must refuse
before anything is sent."""

from __future__ import annotations

import itertools
import os
import time

import pytest

import canopenfd
from canopenfd import AbortError, ConfigurationError, SdoAbortError, UsdoAbortError
from canopenfd.od import DataType, ODArray, ODRecord, ODVariable, demo_od
from canopenfd.services.pdo import PdoMap, PdoMaps, PdoVariable
from helpers import Recorder, scaled, virtual_bus

can = pytest.importorskip("can")
canopen = pytest.importorskip("canopen")

SERVER = 5
CLIENT = 0x7F           # a line without a local node is USDO client 127
U8, U16, U32 = DataType.UNSIGNED8, DataType.UNSIGNED16, DataType.UNSIGNED32
_channels = itertools.count(1)

# Communication sub-entries per direction: sub -> (name, type).
_COMM_ENTRIES = {1: ("COB-ID used by PDO", U32), 2: ("Transmission type", U8),
                 3: ("Inhibit time", U16), 5: ("Event timer", U16),
                 6: ("SYNC start value", U8)}
_SUBS = {"RPDO": (1, 2, 5), "TPDO": (1, 2, 3, 5, 6)}


def add_pdo_objects(od, count=2, slots=8):
    """PDO 1..count of both directions, as a device's EDS would describe them:
    invalid predefined COB-IDs ($NODEID relative), type 255, `slots` mapping
    entries."""
    for kind, comm, mapping, base in (("RPDO", 0x1400, 0x1600, 0x200),
                                      ("TPDO", 0x1800, 0x1A00, 0x180)):
        for n in range(1, count + 1):
            index = comm + n - 1
            record = ODRecord(f"{kind} communication parameter {n}", index)
            record.add_member(ODVariable("Highest sub-index supported", index, 0, U8, "ro",
                                         max(_SUBS[kind])))
            for sub in _SUBS[kind]:
                name, dtype = _COMM_ENTRIES[sub]
                var = ODVariable(name, index, sub, dtype, "rw", 0)
                if sub == 1:
                    var.set_default(0x80000000 + base + (n - 1) * 0x100, relative_to_node_id=True)
                elif sub == 2:
                    var.default = 255
                record.add_member(var)
            od.add_object(record)
            index = mapping + n - 1
            array = ODArray(f"{kind} mapping parameter {n}", index)
            array.add_member(ODVariable("Number of mapped objects", index, 0, U8, "rw", 0))
            for sub in range(1, slots + 1):
                array.add_member(ODVariable(f"Mapped object {sub}", index, sub, U32, "rw", 0))
            od.add_object(array)
    return od


def pdo_od(mode, count=2, slots=8):
    return add_pdo_objects(demo_od(mode), count, slots)


@pytest.fixture(params=["classic", "fd"])
def mode(request):
    return request.param


def make_rig(net, bus_name, mode, slots=8):
    """Our node 5 serving a demo OD with PDO objects, a tool line watching it
    (same OD) and a monitor of every frame."""
    node = net.open_line(bus_name, mode=mode).create_local_node(SERVER,
                                                                od=pdo_od(mode, slots=slots))
    line = net.open_line(bus_name, mode=mode)
    frames = Recorder()
    net.open_line(bus_name, mode=mode, monitor=True).on_frame(frames)
    remote = line.add_node(SERVER, od=pdo_od(mode, slots=slots))
    return node, line, remote, frames


@pytest.fixture
def classic(net, bus_name):
    return make_rig(net, bus_name, "classic")


@pytest.fixture
def fd(net, bus_name):
    return make_rig(net, bus_name, "fd", slots=64)


def wait_frames(frames, count, keep, what, timeout=2.0):
    """The recorded frames `keep(frame)` accepts, once there are `count` of them."""
    def enough(calls):
        got = [f for f in calls if keep(f)]
        return got if len(got) >= count else None
    return frames.wait_for(enough, timeout, what)


def settings(pdo):
    """What a PDO's configuration is, for comparisons."""
    return (pdo.cob_id, pdo.enabled, pdo.rtr_allowed, pdo.extended, pdo.trans_type,
            pdo.inhibit_time, pdo.event_timer, pdo.sync_start_value,
            [(v.index, v.subindex, v.length, v.offset, v.name) for v in pdo.map])


def fresh(line, node_id, od):
    """The same remote node with new PdoMaps (a new OD object drops the old ones)."""
    return line.add_node(node_id, od=od)


# ------------------------------------------------------------------ the procedure on the bus
def test_save_sends_the_cia_301_procedure_in_order_and_nothing_else(classic):
    node, _, remote, frames = classic
    tpdo = remote.tpdo[1]
    tpdo.cob_id = 0x185
    tpdo.trans_type = 254
    tpdo.inhibit_time = 10
    tpdo.event_timer = 100
    tpdo.clear()
    tpdo.add_variable("Demo UNSIGNED16")              # 0x2006, 16 bits
    tpdo.add_variable(0x2200, 1)                      # Setpoint, INTEGER16
    tpdo.add_variable("Error register")               # 0x1001, 8 bits
    tpdo.enabled = True
    tpdo.save()
    sent = wait_frames(frames, 10, lambda f: f.id == 0x600 + SERVER, "10 SDO requests")
    assert all(not f.fd and len(f.data) == 8 for f in sent)
    # expedited downloads: 0x23 = 4 bytes, 0x2B = 2 bytes, 0x2F = 1 byte; index LE, sub, value LE
    expected = [
        "23 00 18 01 85 01 00 80",   # COB-ID 0x185 with bit 31: invalid first
        "2f 00 18 02 fe 00 00 00",   # transmission type 254
        "2b 00 18 03 0a 00 00 00",   # inhibit time 10 x 100 us
        "2b 00 18 05 64 00 00 00",   # event timer 100 ms
        "2f 00 1a 00 00 00 00 00",   # mapping count 0
        "23 00 1a 01 10 00 06 20",   # 0x2006:00, 16 bits
        "23 00 1a 02 10 01 00 22",   # 0x2200:01, 16 bits
        "23 00 1a 03 08 00 01 10",   # 0x1001:00, 8 bits
        "2f 00 1a 00 03 00 00 00",   # mapping count 3
        "23 00 18 01 85 01 00 00",   # COB-ID valid again
    ]
    time.sleep(scaled(0.05))
    assert [f.data.hex(" ") for f in frames.snapshot() if f.id == 0x600 + SERVER] == expected
    # the SYNC start value was never set: not written (10 requests, not 11)
    assert node[0x1800][1].raw == 0x185 and node[0x1800][2].raw == 254
    assert node[0x1A00][0].raw == 3 and node[0x1A00][2].raw == 0x22000110


def test_disabled_pdo_stays_invalid_and_unchanged_mapping_is_not_rewritten(classic):
    node, _, remote, frames = classic
    tpdo = remote.tpdo[2]
    tpdo.read()                                   # COB-ID 0x80000285 from the defaults
    assert (tpdo.cob_id, tpdo.enabled, tpdo.trans_type) == (0x285, False, 255)
    tpdo.event_timer = 500
    tpdo.save()
    wait_frames(frames, 5, lambda f: f.id == 0x600 + SERVER and f.data[0] & 0xE0 == 0x20,
                "5 downloads")
    time.sleep(scaled(0.05))
    sent = [f.data.hex(" ") for f in frames.snapshot()
            if f.id == 0x600 + SERVER and f.data[0] & 0xE0 == 0x20]     # downloads only
    assert sent == ["23 01 18 01 85 02 00 80",   # invalid
                    "2f 01 18 02 ff 00 00 00",   # type 255 (read back, written again)
                    "2b 01 18 03 00 00 00 00",   # inhibit time 0
                    "2b 01 18 05 f4 01 00 00",   # event timer 500
                    "2f 01 18 06 00 00 00 00"]   # SYNC start value 0; no mapping, no enable
    assert node[0x1801][1].raw == 0x80000285 and node[0x1801][5].raw == 500


def test_fd_line_uses_usdo_and_takes_a_64_byte_mapping(fd):
    node, _, remote, frames = fd
    tpdo = remote.tpdo[1]
    tpdo.read()
    tpdo.clear()
    for _ in range(8):
        tpdo.add_variable("Demo UNSIGNED64")                  # 8 x 64 bits = 64 bytes
    assert tpdo.length == 512 and len(tpdo.data) == 64
    tpdo.trans_type = 1
    tpdo.enabled = True
    tpdo.save()
    sent = wait_frames(frames, 16, lambda f: f.id == 0x600 + CLIENT and f.data[1] == 0x01,
                       "16 USDO downloads")
    assert not [f for f in frames.snapshot() if 0x600 <= f.id <= 0x67F and not f.fd]
    # sub-index and index of each write: the procedure, every parameter read() found
    assert [(f.data[3], int.from_bytes(f.data[4:6], "little")) for f in sent] == \
        [(1, 0x1800), (2, 0x1800), (3, 0x1800), (5, 0x1800), (6, 0x1800), (0, 0x1A00)] + \
        [(sub, 0x1A00) for sub in range(1, 9)] + [(0, 0x1A00), (1, 0x1800)]
    first = sent[0]
    # USDO expedited download: [server, 0x01, session, sub 1, index 0x1800 LE, type U32, 4, value]
    assert first.fd and first.data[:12] == bytes([SERVER, 0x01, first.data[2], 0x01, 0x00, 0x18,
                                                  0x07, 4]) + (0x80000185).to_bytes(4, "little")
    count_zero = next(f for f in sent if f.data[3:6] == bytes([0x00, 0x00, 0x1A]))
    assert count_zero.data[6:9] == bytes([0x05, 1, 0])        # U8, 1 byte, 0
    assert node[0x1A00][0].raw == 8
    assert [node[0x1A00][s].raw for s in range(1, 9)] == [0x201B0040] * 8
    assert node[0x1800][1].raw == 0x185 and node[0x1800][2].raw == 1
    again = fresh(remote.line, SERVER, pdo_od("fd", slots=64)).tpdo[1]
    again.read()
    assert settings(again) == settings(tpdo)


def test_fd_65_bytes_are_refused_before_anything_is_sent(fd):
    _, _, remote, frames = fd
    tpdo = remote.tpdo[1]
    tpdo.clear()
    for _ in range(8):
        tpdo.add_variable(0x201B)
    with pytest.raises(ConfigurationError) as info:
        tpdo.add_variable("Demo UNSIGNED8")
    text = str(info.value)
    assert "node 5 TPDO1" in text and "65 bytes" in text and "64 bytes" in text
    assert "fd line" in text and len(tpdo.map) == 8
    # a mapping grown behind add_variable's back is refused by save() too, before any frame
    tpdo.cob_id = 0x185
    tpdo._append(PdoVariable(0x2005, 0, 8, remote.object_dictionary.get_variable(0x2005)))
    with pytest.raises(ConfigurationError, match="65 bytes"):
        tpdo.save()
    time.sleep(scaled(0.1))
    assert not [f for f in frames.snapshot() if 0x600 <= f.id <= 0x67F]


def test_classic_9_bytes_are_refused_and_bit_lengths_allowed(classic):
    _, _, remote, frames = classic
    tpdo = remote.tpdo[1]
    tpdo.add_variable("Demo UNSIGNED64")
    with pytest.raises(ConfigurationError) as info:
        tpdo.add_variable("Demo UNSIGNED8")
    assert "node 5 TPDO1" in str(info.value) and "72 bits (9 bytes)" in str(info.value)
    assert "8 bytes" in str(info.value)
    tpdo.clear()
    flag = tpdo.add_variable("Demo BOOLEAN", length=1)       # bit-wise mapping on classic
    low = tpdo.add_variable("Demo UNSIGNED32", length=12)    # low-order 12 bits
    assert (flag.offset, low.offset, tpdo.length) == (0, 1, 13)
    with pytest.raises(ConfigurationError, match="object holds 16"):
        tpdo.add_variable("Demo UNSIGNED16", length=17)
    time.sleep(scaled(0.05))
    assert not [f for f in frames.snapshot() if f.id == 0x600 + SERVER]


def test_fd_lines_map_whole_bytes_only(fd):
    _, _, remote, _ = fd
    with pytest.raises(ConfigurationError, match="whole bytes"):
        remote.tpdo[1].add_variable("Demo BOOLEAN", length=1)
    assert remote.tpdo[1].add_variable("Demo UNSIGNED32", length=16).length == 16


# ------------------------------------------------------------------ checks
def test_transmission_types_are_checked_with_node_pdo_field_expected_got(net, bus_name, mode):
    _, _, remote, _ = make_rig(net, bus_name, mode)
    tpdo, rpdo = remote.tpdo[1], remote.rpdo[2]
    for value in (0, 1, 240, 254, 255):
        tpdo.trans_type = value
        rpdo.trans_type = value
    with pytest.raises(ConfigurationError) as info:
        tpdo.trans_type = 241
    text = str(info.value)
    assert text.startswith("node 5 TPDO1: trans_type must be 0, 1..240, ")
    assert text.endswith("got 241")
    with pytest.raises(ConfigurationError) as info:
        rpdo.trans_type = 252
    assert "node 5 RPDO2" in str(info.value) and "not RPDOs" in str(info.value)
    assert "got 252" in str(info.value)
    if mode == "classic":
        tpdo.trans_type = 252
        tpdo.trans_type = 253
        assert "252, 253" in text
    else:
        with pytest.raises(ConfigurationError, match=r"not fd lines\), got 253"):
            tpdo.trans_type = 253
    for bad in (-1, 256, "255", 254.0, True, []):
        with pytest.raises(ConfigurationError, match="trans_type"):
            tpdo.trans_type = bad
    assert tpdo.trans_type in (253, 255)


def test_other_fields_are_checked(classic):
    _, _, remote, _ = classic
    tpdo = remote.tpdo[1]
    for field, bad, expected in (("inhibit_time", 65536, "0..65535"),
                                 ("event_timer", -1, "0..65535 ms"),
                                 ("sync_start_value", 241, "0..240"),
                                 ("cob_id", 0x80000185, "CAN-ID")):
        with pytest.raises(ConfigurationError) as info:
            setattr(tpdo, field, bad)
        assert f"node 5 TPDO1: {field} must be" in str(info.value)
        assert expected in str(info.value) and f"got {bad!r}" in str(info.value)
    tpdo.cob_id = 0x12345
    with pytest.raises(ConfigurationError, match="11-bit"):
        tpdo.save()
    remote.tpdo[2].cob_id = None
    with pytest.raises(ConfigurationError, match="node 5 TPDO2: cob_id is not known"):
        remote.tpdo[2].save()


def test_mapping_by_name_and_by_index_sub_give_the_same_entry(classic):
    _, _, remote, _ = classic
    rpdo = remote.rpdo[1]
    ways = [("Demo record.Setpoint",), (0x2200, 1), ("0x2200:01",), ((0x2200, 1),),
            ("Demo record", "Setpoint"), ("Demo record", 1)]
    values = set()
    for way in ways:
        rpdo.clear()
        var = rpdo.add_variable(*way)
        values.add((var.mapping_value, var.name, var.od.where))
    assert values == {(0x22000110, "Demo record.Setpoint", "0x2200:01")}
    assert rpdo["Demo record.Setpoint"] is rpdo[0] is rpdo[0x2200] is rpdo["0x2200:01"]
    with pytest.raises(ConfigurationError, match="not in the object dictionary"):
        rpdo.add_variable("No such thing")
    with pytest.raises(ConfigurationError, match="not in the object dictionary"):
        rpdo.add_variable(0x1017, 1)                     # a VAR has sub 0 only
    unknown = rpdo.add_variable(0x3000, 2, 16)           # not in the OD: explicit length
    assert unknown.od is None and unknown.name == "0x3000:02"


def test_mappability_dummies_and_room(classic):
    _, _, remote, _ = classic
    tpdo, rpdo = remote.tpdo[1], remote.rpdo[1]
    with pytest.raises(ConfigurationError, match="into a RPDO .PDO mapping: tpdo"):
        rpdo.add_variable("Demo INTEGER56")              # ro: TPDO only
    with pytest.raises(ConfigurationError, match="PDO mapping: no"):
        tpdo.add_variable("Demo VISIBLE_STRING")
    with pytest.raises(ConfigurationError, match="DOMAIN"):
        tpdo.add_variable("Demo large domain", length=8)
    with pytest.raises(ConfigurationError, match="RPDOs only"):
        tpdo.add_variable(0x0005, 0)
    dummy = rpdo.add_variable(0x0006, 0)                 # UNSIGNED16 dummy: 16 bits
    assert dummy.is_dummy and dummy.length == 16 and dummy.name == "Dummy UNSIGNED16"
    with pytest.raises(ConfigurationError, match="exactly 8 bits"):
        rpdo.add_variable(0x0002, 0, 16)
    rpdo.clear()
    for _ in range(8):
        rpdo.add_variable(0x0005, 0)
    assert rpdo.length == 64
    small = add_pdo_objects(demo_od("classic"), count=1, slots=2)
    tight = fresh(remote.line, SERVER, small).tpdo[1]
    tight.add_variable("Error register")
    tight.add_variable("Error register")
    with pytest.raises(ConfigurationError, match="has room for 2"):
        tight.add_variable("Error register")


def test_sub_entries_the_node_lacks_are_none_and_not_written(net, bus_name):
    served = pdo_od("classic")
    served[0x1800].subindices.pop(6)                     # this device has no SYNC start value
    served[0x1800][0].default = 5
    node = net.open_line(bus_name, mode="classic").create_local_node(SERVER, od=served)
    line = net.open_line(bus_name, mode="classic")
    frames = Recorder()
    net.open_line(bus_name, mode="classic", monitor=True).on_frame(frames)
    remote = line.add_node(SERVER, od=pdo_od("classic"))
    rpdo = remote.rpdo[1]                                # RPDOs have subs 1, 2, 5 only
    rpdo.read()
    assert (rpdo.inhibit_time, rpdo.sync_start_value) == (None, None)
    rpdo.inhibit_time, rpdo.sync_start_value = 3, 4      # not in the OD: kept, not written
    rpdo.save()
    downloads = wait_frames(frames, 3, lambda f: f.id == 0x600 + SERVER and
                            f.data[0] & 0xE0 == 0x20, "3 downloads")
    assert [(f.data[2], f.data[3]) for f in downloads] == [(0x14, 1), (0x14, 2), (0x14, 5)]
    tpdo = remote.tpdo[1]                                # its EDS claims sub 6
    tpdo.read()                                          # the 0x06090011 abort is tolerated
    assert tpdo.sync_start_value is None and tpdo.trans_type == 255
    tpdo.event_timer = 7
    tpdo.save()
    downloads = wait_frames(frames, 3 + 4, lambda f: f.id == 0x600 + SERVER and
                            f.data[0] & 0xE0 == 0x20, "4 more downloads")
    time.sleep(scaled(0.05))
    assert [(f.data[2], f.data[3]) for f in downloads[3:]] == [(0x18, 1), (0x18, 2), (0x18, 3),
                                                               (0x18, 5)]
    # the server's last answer may reach the monitor after the save returned: wait
    # for every request to have its answer
    frames.wait_for(lambda calls: len([f for f in calls if f.id == 0x600 + SERVER]) ==
                    len([f for f in calls if f.id == 0x580 + SERVER]), 5,
                    "an answer to every request")
    assert len([f for f in frames.snapshot() if f.id == 0x600 + SERVER]) == \
        len([f for f in frames.snapshot() if f.id == 0x580 + SERVER])
    assert node[0x1800][5].raw == 7


def test_read_only_parameters_are_left_alone_unless_changed(net, bus_name):
    od = pdo_od("classic")
    od[0x1800][2].access_type = "ro"                     # a device with a fixed type 255
    node = net.open_line(bus_name, mode="classic").create_local_node(SERVER, od=od)
    line = net.open_line(bus_name, mode="classic")
    frames = Recorder()
    net.open_line(bus_name, mode="classic", monitor=True).on_frame(frames)
    remote = line.add_node(SERVER, od=od)
    tpdo = remote.tpdo[1]
    tpdo.read()
    tpdo.event_timer = 9
    tpdo.save()                                          # type 255 as read: not written
    downloads = wait_frames(frames, 4, lambda f: f.id == 0x600 + SERVER and
                            f.data[0] & 0xE0 == 0x20, "4 downloads")
    time.sleep(scaled(0.05))
    assert [f.data[3] for f in downloads] == [1, 3, 5, 6] and node[0x1800][5].raw == 9
    tpdo.trans_type = 1
    with pytest.raises(ConfigurationError) as info:
        tpdo.save()
    assert str(info.value).startswith("node 5 TPDO1: trans_type 1 cannot be written: "
                                      "0x1800:02 is read-only in the OD (the node has 255")
    time.sleep(scaled(0.05))
    assert len([f for f in frames.snapshot() if f.id == 0x600 + SERVER and
                f.data[0] & 0xE0 == 0x20]) == 4


def test_numbers_come_from_the_od(net, bus_name):
    node, line, remote, _ = make_rig(net, bus_name, "classic")
    assert list(remote.tpdo) == [1, 2] == list(remote.rpdo) and len(node.tpdo) == 2
    assert remote.tpdo[0x1A01] is remote.tpdo[2] is remote.tpdo[0x1801]
    assert remote.tpdo is remote.tpdo                    # settings stay on the node
    with pytest.raises(KeyError, match="no TPDO 3 .*it has: 1, 2"):
        remote.tpdo[3]
    bare = line.add_node(9)
    with pytest.raises(ConfigurationError, match="node 9: no object dictionary"):
        _ = bare.tpdo
    assert len(line.add_node(10, od=demo_od("classic")).rpdo) == 0


# ------------------------------------------------------------------ read back
def test_read_back_equals_saved_on_our_server(net, bus_name, mode):
    node, line, remote, _ = make_rig(net, bus_name, mode)
    tpdo = remote.tpdo[2]
    tpdo.cob_id = 0x2A0
    tpdo.trans_type = 5
    tpdo.inhibit_time = 0
    tpdo.event_timer = 0
    tpdo.sync_start_value = 3
    tpdo.rtr_allowed = False
    tpdo.add_variable("Demo INTEGER32", length=16)
    tpdo.add_variable("Demo REAL32")
    tpdo.add_variable("Demo INTEGER8")
    tpdo.enabled = True
    rpdo = remote.rpdo[1]
    rpdo.cob_id = 0x205
    rpdo.trans_type = 255
    rpdo.event_timer = 250
    rpdo.add_variable("Demo UNSIGNED16")
    rpdo.add_variable(0x0005, 0)                         # skip one byte
    rpdo.add_variable("Demo record.Setpoint")
    remote.tpdo.save()                                   # TPDO2 (TPDO1 was never set)
    remote.rpdo.save()
    assert node[0x1801][1].raw == 0x400002A0 and node[0x1A01][0].raw == 3
    assert node[0x1800][1].raw == 0x80000185             # untouched
    again = fresh(line, SERVER, pdo_od(mode))
    again.tpdo.read()
    again.rpdo.read()
    assert settings(again.tpdo[2]) == settings(tpdo)
    assert settings(again.rpdo[1]) == settings(rpdo)
    assert again.rpdo[1][1].is_dummy and again.rpdo[1].enabled is False
    assert (again.tpdo[1].cob_id, again.tpdo[1].enabled) == (0x185, False)
    # the local node sees the same through its own OD
    node.tpdo[2].read()
    assert settings(node.tpdo[2]) == settings(tpdo)


def test_an_eds_file_gives_numbers_defaults_and_mapped_variables(net, bus_name):
    eds = os.path.join(os.path.dirname(__file__), "data", "od", "classic_vendor.eds")
    node = net.open_line(bus_name, mode="classic").create_local_node(SERVER, od=eds)
    remote = net.open_line(bus_name, mode="classic").add_node(SERVER, od=eds)
    assert list(remote.tpdo) == [1] and list(remote.rpdo) == [1]
    offline = remote.tpdo[1]
    offline.read(from_od=True)                           # 0x180+$NODEID, type 254
    assert (offline.cob_id, offline.enabled, offline.trans_type) == (0x185, True, 254)
    assert [(v.name, v.offset, v.length) for v in offline.map] == [
        ("Read analog input 16-bit.Read analog input 16-bit1", 0, 16),
        ("Read analog input 16-bit.Read analog input 16-bit2", 16, 16)]
    snapshot = settings(offline)
    online = remote.tpdo[1]
    online.read()                                        # the served values over SDO
    assert settings(online) == snapshot
    rpdo = remote.rpdo[1]
    rpdo.read()                                          # 0x6200:01 is not in this EDS
    assert (rpdo.cob_id, rpdo.trans_type) == (0x205, 255)
    assert [(v.name, v.od, v.length) for v in rpdo.map] == [("0x6200:01", None, 8)]
    assert node[0x1600][1].raw == 0x62000108


def test_local_node_configures_its_own_pdos(net, bus_name, mode):
    node, line, _, _ = make_rig(net, bus_name, mode)
    defaults = node.tpdo[1]
    defaults.read(from_od=True)                          # the OD's defaults, no access
    assert (defaults.cob_id, defaults.enabled, defaults.trans_type) == (0x185, False, 255)
    tpdo = node.tpdo[1]
    tpdo.clear()
    tpdo.add_variable("Demo UNSIGNED16")
    tpdo.trans_type = 254
    tpdo.event_timer = 20
    tpdo.enabled = True
    tpdo.save()
    assert node[0x1800][1].raw == 0x185 and node[0x1A00][1].raw == 0x20060010
    remote = fresh(line, SERVER, pdo_od(mode))
    remote.tpdo[1].read()
    assert settings(remote.tpdo[1]) == settings(tpdo)
    unbooted = net.open_line(bus_name + "-2", mode=mode).create_local_node(
        3, od=pdo_od(mode), boot=False)
    with pytest.raises(ConfigurationError, match="local node 3 is not booted"):
        unbooted.tpdo[1].read()


def test_decoding_a_pdo_from_its_bytes(classic):
    _, _, remote, _ = classic
    rpdo = remote.rpdo[1]
    rpdo.add_variable("Demo BOOLEAN", length=1)
    rpdo.add_variable("Demo INTEGER16")
    rpdo.add_variable("Demo UNSIGNED32", length=12)
    rpdo.add_variable("Demo INTEGER32", length=8)
    # bit 0 = 1; bits 1..16 = -2 (0xFFFE); bits 17..28 = 0xABC; bits 29..36 = 0xFF
    whole = 1 | (0xFFFE << 1) | (0xABC << 17) | (0xFF << 29)
    rpdo.data[:] = whole.to_bytes(5, "little")
    # a partly mapped object gets the low-order bits, the rest 0 (as the receiving node)
    assert [v.raw for v in rpdo.map] == [True, -2, 0xABC, 0xFF]
    assert rpdo["Demo UNSIGNED32"].get_data() == bytes([0xBC, 0x0A, 0, 0])


# ------------------------------------------------------------------ aborts
def test_abort_from_our_server_names_pdo_and_step(net, bus_name, mode):
    node, line, remote, _ = make_rig(net, bus_name, mode)
    node.on_write((0x1A00, 2), lambda request: 0x06040041)
    tpdo = remote.tpdo[1]
    tpdo.cob_id = 0x185
    tpdo.add_variable("Demo UNSIGNED8")
    tpdo.add_variable("Demo UNSIGNED16")
    tpdo.enabled = True
    error = SdoAbortError if mode == "classic" else UsdoAbortError
    with pytest.raises(error) as info:
        tpdo.save()
    exc = info.value
    assert exc.code == 0x06040041 and exc.from_server
    assert exc.pdo == "node 5 TPDO1" and exc.step.startswith("writing mapping entry 2 ")
    assert str(exc).startswith("node 5 TPDO1, writing mapping entry 2 (0x1A00:02 = 0x20060010")
    # the procedure stopped there: the PDO stays invalid, the count 0
    assert node[0x1800][1].raw == 0x80000185 and node[0x1A00][0].raw == 0
    node.on_read((0x1800, 2), lambda request: 0x08000022)
    with pytest.raises(error) as info:
        fresh(line, SERVER, pdo_od(mode)).tpdo[1].read()
    assert "node 5 TPDO1, reading the transmission type (0x1800:02)" in str(info.value)


def test_local_abort_names_pdo_and_step(net, bus_name):
    od = pdo_od("classic")
    od[0x1800][2].default = 1
    od[0x1800][2].high_limit = 240                   # this device sends synchronously only
    node = net.open_line(bus_name, mode="classic").create_local_node(SERVER, od=od)
    tpdo = node.tpdo[1]
    tpdo.read()
    tpdo.trans_type = 254
    with pytest.raises(AbortError) as info:
        tpdo.save()
    assert info.value.code == 0x06090031
    assert str(info.value).startswith(
        "local node 5 TPDO1, writing the transmission type (0x1800:02 = 254): ")
    assert info.value.step.startswith("writing the transmission type")
    tpdo.trans_type = 240
    tpdo.save()
    assert node[0x1800][2].raw == 240


# ------------------------------------------------------------------ python-canopen as the peer
def _their_od():
    """python-canopen's OD of node 7: TPDO 1 and RPDO 1 with 4 mapping
    slots, and two mappable entries."""
    od = canopen.ObjectDictionary()
    for index, name, dtype in ((0x2000, "Speed", canopen.objectdictionary.UNSIGNED16),
                               (0x2001, "Mode", canopen.objectdictionary.UNSIGNED8)):
        var = canopen.objectdictionary.ODVariable(name, index, 0)
        var.data_type, var.access_type, var.pdo_mappable = dtype, "rw", True
        var.default = 0
        od.add_object(var)
    for comm, mapping, base in ((0x1400, 0x1600, 0x200), (0x1800, 0x1A00, 0x180)):
        record = canopen.objectdictionary.ODRecord(f"comm {comm:X}", comm)
        for sub, dtype, default in ((0, canopen.objectdictionary.UNSIGNED8, 6),
                                    (1, canopen.objectdictionary.UNSIGNED32,
                                     0x80000000 + base + 7),
                                    (2, canopen.objectdictionary.UNSIGNED8, 255),
                                    (3, canopen.objectdictionary.UNSIGNED16, 0),
                                    (5, canopen.objectdictionary.UNSIGNED16, 0),
                                    (6, canopen.objectdictionary.UNSIGNED8, 0)):
            var = canopen.objectdictionary.ODVariable(f"sub{sub}", comm, sub)
            var.data_type, var.access_type, var.default = dtype, "ro" if sub == 0 else "rw", \
                default
            record.add_member(var)
        od.add_object(record)
        array = canopen.objectdictionary.ODArray(f"map {mapping:X}", mapping)
        for sub in range(5):
            var = canopen.objectdictionary.ODVariable(f"sub{sub}", mapping, sub)
            var.data_type = canopen.objectdictionary.UNSIGNED8 if sub == 0 else \
                canopen.objectdictionary.UNSIGNED32
            var.access_type, var.default = "rw", 0
            array.add_member(var)
        od.add_object(array)
    return od


def _our_view_of_their_od():
    od = canopenfd.ObjectDictionary(mode="classic")
    od.add_object(ODVariable("Speed", 0x2000, 0, U16, "rw", 0, pdo_mapping=True))
    od.add_object(ODVariable("Mode", 0x2001, 0, U8, "rw", 0, pdo_mapping=True))
    for comm, mapping, base in ((0x1400, 0x1600, 0x200), (0x1800, 0x1A00, 0x180)):
        record = ODRecord(f"comm {comm:X}", comm)
        record.add_member(ODVariable("sub0", comm, 0, U8, "ro", 6))
        for sub in (1, 2, 3, 5, 6):
            record.add_member(ODVariable(f"sub{sub}", comm, sub, _COMM_ENTRIES[sub][1], "rw", 0))
        od.add_object(record)
        array = ODArray(f"map {mapping:X}", mapping)
        array.add_member(ODVariable("sub0", mapping, 0, U8, "rw", 0))
        for sub in range(1, 5):
            array.add_member(ODVariable(f"sub{sub}", mapping, sub, U32, "rw", 0))
        od.add_object(array)
    return od


@pytest.fixture
def their_node():
    """python-canopen's LocalNode 7 on a virtual bus, our classic line on it."""
    channel = f"pdo-{os.getpid()}-{next(_channels)}"
    peer = canopen.Network()
    peer.connect(interface="virtual", channel=channel)
    theirs = peer.create_node(7, _their_od())
    with canopenfd.Network() as net:
        line = net.open_line(bus=virtual_bus(channel), mode="classic")
        try:
            yield theirs, line.add_node(7, od=_our_view_of_their_od()), line
        finally:
            peer.disconnect()


def test_python_canopen_peer_reads_what_we_saved(their_node):
    theirs, remote, line = their_node
    tpdo = remote.tpdo[1]
    tpdo.read()
    assert (tpdo.cob_id, tpdo.enabled, tpdo.trans_type, tpdo.map) == (0x187, False, 255, [])
    tpdo.clear()
    tpdo.add_variable("Speed")
    tpdo.add_variable(0x2001, 0)
    tpdo.trans_type = 1
    tpdo.sync_start_value = 2
    tpdo.enabled = True
    tpdo.save()
    store = theirs.data_store
    assert store[0x1800][1] == (0x187).to_bytes(4, "little")
    assert store[0x1A00][0] == b"\x02" and store[0x1A00][1] == (0x20000010).to_bytes(4, "little")
    # python-canopen decodes the configuration independently
    theirs.tpdo.read()
    mine = theirs.tpdo[1]
    assert (mine.cob_id, mine.enabled, mine.trans_type) == (0x187, True, 1)
    assert [(v.index, v.subindex, v.length) for v in mine.map] == [(0x2000, 0, 16), (0x2001, 0, 8)]
    again = fresh(line, 7, _our_view_of_their_od()).tpdo[1]
    again.read()
    assert settings(again) == settings(tpdo)


def test_python_canopen_refusal_names_pdo_and_step(their_node):
    theirs, remote, _ = their_node

    def refuse(index, subindex, od, data):
        if index == 0x1600 and subindex == 1:
            raise canopen.sdo.SdoAbortedError(0x06040041)

    theirs.add_write_callback(refuse)
    rpdo = remote.rpdo[1]
    rpdo.cob_id = 0x207
    rpdo.add_variable("Mode")
    rpdo.enabled = True
    with pytest.raises(SdoAbortError) as info:
        rpdo.save()
    assert info.value.code == 0x06040041 and info.value.from_server
    assert "node 7 RPDO1, writing mapping entry 1 (0x1600:01 = 0x20010008, Mode)" \
        in str(info.value)
    assert info.value.pdo == "node 7 RPDO1"
    assert theirs.data_store[0x1400][1] == (0x80000207).to_bytes(4, "little")
    assert 1 not in theirs.data_store.get(0x1600, {})


def test_python_canopen_attribute_names(classic):
    _, _, remote, _ = classic
    theirs = canopen.LocalNode(7, _their_od())
    their_map, my_map = theirs.tpdo[1], remote.tpdo[1]
    names = ["cob_id", "enabled", "rtr_allowed", "trans_type", "inhibit_time", "event_timer",
             "sync_start_value", "predefined_cob_id", "map", "length", "data", "name",
             "is_periodic", "clear", "add_variable", "read", "save"]
    for name in names:
        assert hasattr(their_map, name), name          # the names really are python-canopen's
        assert hasattr(my_map, name), name
    for name in ("map", "read", "save"):
        assert hasattr(theirs.tpdo, name) and hasattr(remote.tpdo, name)
    assert remote.tpdo.map[1] is remote.tpdo[1]
    with pytest.raises(KeyError):
        remote.tpdo["Demo UNSIGNED8"]
    assert my_map.predefined_cob_id == 0x185 and my_map.name == "TxPDO1_node5"
    var = my_map.add_variable("Demo UNSIGNED8")
    for name in ("index", "subindex", "offset", "length", "name", "od", "raw", "get_data"):
        assert hasattr(var, name), name
    assert remote.tpdo["Demo UNSIGNED8"] is var is my_map["Demo UNSIGNED8"] is my_map[0]
    assert my_map.variables is my_map.map and isinstance(remote.tpdo, PdoMaps)
    assert isinstance(my_map, PdoMap)


def test_read_from_an_od_without_the_pdo_entries_names_the_missing_entry(net, bus_name):
    """read(from_od=True) of a PDO whose mapping count names an entry the
    node's OD lacks (a vendor file's slip): ConfigurationError naming the
    entry, not an AttributeError; a record key without a sub-index is
    refused by name too."""
    od = demo_od("fd", pdos=1)
    U8, U32 = DataType.UNSIGNED8, DataType.UNSIGNED32
    comm = ODRecord("RPDO 2 communication parameter", 0x1401)   # and no 0x1601
    comm.add_member(ODVariable("Highest sub-index supported", 0x1401, 0, U8, "ro", 2))
    comm.add_member(ODVariable("COB-ID used by RPDO", 0x1401, 1, U32, "rw", 0x305))
    comm.add_member(ODVariable("Transmission type", 0x1401, 2, U8, "rw", 255))
    od.add_object(comm)
    mapping = ODArray("RPDO 2 mapping parameter", 0x1601)   # says 2 entries, has 1
    mapping.add_member(ODVariable("Number of mapped objects", 0x1601, 0, U8, "rw", 2))
    mapping.add_member(ODVariable("Mapped object 1", 0x1601, 1, U32, "rw", 0x23000120))
    od.add_object(mapping)
    drive = net.open_line(bus_name).add_node(5, od)
    with pytest.raises(ConfigurationError, match=r"0x1601:02 is not in the object dictionary"):
        drive.rpdo[2].read(from_od=True)
    tpdo = drive.tpdo[1]
    tpdo.read(from_od=True)
    with pytest.raises(ConfigurationError, match="'Process data' sub None is not in"):
        tpdo.add_variable("Process data", None)
