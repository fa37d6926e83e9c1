"""Objects added to a running local node's dictionary.

`node.od.add_object(obj)` (or `record.add_member` of a new sub-entry) on a booted node goes to the node's C dictionary
first (co_rt_od_add: served at once, by SDO/USDO, the application and PDOs)
and only then into the model; when the node refuses it (no room left, a
communication object, ...) OdStateError names the node, the index and the
reason, and neither the model nor the node changes. Replacing or removing an
object of a running node raises the same way.
"""

from __future__ import annotations

import copy

import pytest
from helpers import Recorder

import canopenfd
from canopenfd.errors import AbortError
from canopenfd.od import DataType, ODRecord, ODVariable, OdStateError, demo_od

NODE = 3
MODES = pytest.mark.parametrize("mode", ["fd", "classic"])


def rig(net, bus, mode, boot=True, **options):
    """Our node NODE (demo OD), a client line and a monitor of every frame."""
    od = demo_od(mode, pdos=1)
    node = net.open_line(bus, mode=mode).create_local_node(NODE, od=od, boot=boot, **options)
    frames = Recorder()
    net.open_line(bus, mode=mode, monitor=True).on_frame(frames)
    client_line = net.open_line(bus, mode=mode)
    client = client_line.usdo if mode == "fd" else client_line.sdo
    return node, od, client, frames


def answers(frames, mode, what):
    """Wait for the server's answers (0x580 + node-id) and give their data."""
    def found(calls):
        got = [bytes(f.data) for f in calls if f.id == 0x580 + NODE]
        return got or None
    return frames.wait_for(found, 5, what)


@MODES
def test_an_object_added_to_a_running_node_is_served_at_once(net, bus_name, mode):
    node, od, client, frames = rig(net, bus_name, mode)
    od.add_object(ODVariable("Added late", 0x2F01, 0, DataType.UNSIGNED16, "rw", 0x1234,
                             pdo_mapping=True))
    assert 0x2F01 in od
    assert node[0x2F01].raw == 0x1234                  # the application, through C
    assert client.upload(NODE, 0x2F01, 0) == b"\x34\x12"
    answer = answers(frames, mode, "the upload's answer")[-1]
    if mode == "classic":   # expedited upload response, 2 bytes: 0x4B
        assert answer == bytes([0x4B, 0x01, 0x2F, 0x00, 0x34, 0x12, 0, 0])
    else:                   # USDO 0x31: sub, index LE, type, N, data
        assert answer[1] == 0x31 and answer[3:6] == bytes([0x00, 0x01, 0x2F])
        assert answer[6] == DataType.UNSIGNED16 and answer[7] == 2
        assert answer[8:10] == b"\x34\x12"
    client.download(NODE, 0x2F01, 0, b"\xCD\xAB")
    assert node[0x2F01].raw == 0xABCD
    with pytest.raises(AbortError) as caught:          # the C entry's type is checked
        client.download(NODE, 0x2F01, 0, b"\x01\x02\x03")
    assert caught.value.code == 0x06070012
    # mapped into a TPDO afterwards: the PDO carries its bytes
    tpdo = node.tpdo[1]
    tpdo.read()
    tpdo.clear()
    tpdo.add_variable(0x2F01, 0)
    tpdo.trans_type = 254
    tpdo.event_timer = 20
    tpdo.enabled = True
    tpdo.save()
    assert node[0x1A00][1].raw == 0x2F010010             # 0x2F01:00, 16 bits
    node.nmt.state = "OPERATIONAL"
    cob = 0x180 + NODE
    sent = frames.wait_for(lambda c: [f for f in c if f.id == cob], 5, "the TPDO")
    assert bytes(sent[-1].data) == b"\xCD\xAB"


@MODES
def test_a_record_is_added_with_all_its_sub_entries(net, bus_name, mode):
    node, od, client, _ = rig(net, bus_name, mode)
    record = ODRecord("Late record", 0x2F10)
    record.add_member(ODVariable("Highest sub-index supported", 0x2F10, 0, DataType.UNSIGNED8,
                                 "ro", 2))
    record.add_member(ODVariable("First", 0x2F10, 1, DataType.UNSIGNED32, "rw", 7))
    record.add_member(ODVariable("Second", 0x2F10, 2, DataType.INTEGER8, "rw", -1))
    od.add_object(record)
    assert client.upload(NODE, 0x2F10, 0) == b"\x02"
    assert client.upload(NODE, 0x2F10, 1) == b"\x07\x00\x00\x00"
    assert node[0x2F10][2].raw == -1
    third = ODVariable("Third", 0x2F10, 3, DataType.UNSIGNED16, "rw", 3)
    record.add_member(third)                           # a sub-entry joins it while it runs
    assert client.upload(NODE, 0x2F10, 3) == b"\x03\x00"
    assert od[0x2F10][3] is third


@MODES
def test_a_refused_object_changes_neither_the_model_nor_the_node(net, bus_name, mode):
    node, od, client, _ = rig(net, bus_name, mode, od_spare_objects=1)
    before = sorted(od)
    late = ODVariable("Sync window", 0x1FF0, 0, DataType.UNSIGNED32, "rw", 1)
    with pytest.raises(OdStateError) as caught:        # the services' objects
        od.add_object(late)
    text = str(caught.value)
    assert "0x1FF0:00" in text and f"local node {NODE}" in text and "0x1000..0x1FFF" in text
    record = ODRecord("Two entries", 0x2F20)           # 2 entries, room for 1: all or none
    record.add_member(ODVariable("Count", 0x2F20, 0, DataType.UNSIGNED8, "ro", 1))
    record.add_member(ODVariable("Value", 0x2F20, 1, DataType.UNSIGNED8, "rw", 5))
    with pytest.raises(OdStateError) as caught:
        od.add_object(record)
    text = str(caught.value)
    assert "0x2F20:01" in text and "no room left" in text and "od_spare_objects=" in text
    assert sorted(od) == before and record.parent is None and late.parent is None
    with pytest.raises(AbortError) as caught:          # nor did the node keep half of it
        client.upload(NODE, 0x2F20, 0)
    assert caught.value.code == 0x06020000
    od.add_object(ODVariable("Fits", 0x2F21, 0, DataType.UNSIGNED8, "rw", 9))
    assert client.upload(NODE, 0x2F21, 0) == b"\x09"


@MODES
def test_replacing_deleting_or_growing_objects_after_boot_raises(net, bus_name, mode):
    node, od, _, _ = rig(net, bus_name, mode)
    heartbeat = od[0x1017]
    with pytest.raises(OdStateError, match="0x1017"):
        od[0x1017] = ODVariable("Producer heartbeat time", 0x1017, 0, DataType.UNSIGNED16)
    with pytest.raises(OdStateError, match="0x1018"):
        del od[0x1018]
    identity = od[0x1018]
    assert isinstance(identity, ODRecord)
    extra = ODVariable("Extra", 0x1018, 9, DataType.UNSIGNED32, "ro")
    with pytest.raises(OdStateError, match="0x1018:09.*0x1000..0x1FFF"):
        identity.add_member(extra)                     # refused by the node: a service's
    with pytest.raises(OdStateError, match="0x1018:01: cannot replace the sub-entry"):
        identity.add_member(ODVariable("Vendor-ID", 0x1018, 1, DataType.UNSIGNED32, "ro"))
    assert od[0x1017] is heartbeat and 9 not in identity and 0x1018 in od
    assert extra.parent is None
    node[0x1017].raw = 250                             # the node still serves what it had
    assert node[0x1017].raw == 250


@MODES
def test_objects_added_before_boot_are_served(net, bus_name, mode):
    node, od, client, _ = rig(net, bus_name, mode, boot=False)
    od.add_object(ODVariable("Added early", 0x2F01, 0, DataType.UNSIGNED16, "rw", 7))
    node.boot()
    assert client.upload(NODE, 0x2F01, 0) == b"\x07\x00"


def test_a_dictionary_used_by_no_node_stays_editable():
    od = demo_od("fd")
    od.add_object(ODVariable("Free", 0x2F01, 0, DataType.UNSIGNED8))
    del od[0x2F01]
    assert 0x2F01 not in od


def test_the_dictionary_is_free_again_once_the_network_closed(bus_name):
    network = canopenfd.Network()
    try:
        node, od, _, _ = rig(network, bus_name, "fd")
        with pytest.raises(OdStateError):
            del od[0x2006]
    finally:
        network.close()
    assert od.frozen_by is None
    del od[0x2006]
    assert 0x2006 not in od


def test_the_reserved_room_is_checked(net, bus_name):
    line = net.open_line(bus_name)
    with pytest.raises(canopenfd.ConfigurationError, match="od_spare_objects must be"):
        line.create_local_node(NODE, od=demo_od("fd"), od_spare_objects=-1)
    assert line.local_node is None


def test_a_copy_of_a_served_dictionary_is_free(net, bus_name):
    _, od, _, _ = rig(net, bus_name, "fd")
    twin = copy.deepcopy(od)
    assert od.frozen_by is not None and twin.frozen_by is None
    del twin[0x2006]
    assert 0x2006 in od and 0x2006 not in twin


def test_stored_objects_added_live_are_saved_and_loaded(bus_name, tmp_path):
    """The store image has room for what the reserved entries can store."""
    path = str(tmp_path / "params.bin")

    def late_objects(od):
        for i in range(20):
            od.add_object(ODVariable(f"Late {i}", 0x2F40 + i, 0, DataType.UNSIGNED32, "rw", i,
                                     store=True))

    with canopenfd.Network() as network:
        node, od, _, _ = rig(network, bus_name, "classic", store=path)
        late_objects(od)                               # while it runs
        node[0x2F53].raw = 0xC0FFEE
        node.save_parameters()
    with canopenfd.Network() as network:
        node, od, _, _ = rig(network, bus_name, "classic", boot=False, store=path)
        late_objects(od)                               # before it boots this time
        node.boot()
        assert node.store_status == "ok"
        assert node[0x2F53].raw == 0xC0FFEE and node[0x2F40].raw == 0



def upload_by_hand(line, frames, mode, index, size, meanwhile):
    """Upload index:00 one request at a time from a raw client (node 0x22), calling
    meanwhile() once half of it has been served: the server is then certainly in the
    middle of the transfer, whatever the machine's load."""
    heard = [0]

    def ask(data):
        line.send_frame(0x600 + (0x22 if mode == "fd" else NODE), bytes(data))
        got = frames.wait_for(lambda calls: [bytes(f.data) for f in calls
                                             if f.id == 0x580 + NODE][heard[0]:] or None,
                              5, f"answer {heard[0] + 1}")[0]
        heard[0] += 1
        return got

    received = bytearray()
    if mode == "fd":                                   # USDO 0x11, then 0x13 per segment
        sid = 7
        first = ask([NODE, 0x11, sid, 0, index & 0xFF, index >> 8])
        assert first[:8] == bytes([0x22, 0x32, sid, 0, index & 0xFF, index >> 8, 0x0F, 0])
        assert int.from_bytes(first[8:12], "little") == size
        counter = 0
        while True:
            if len(received) >= size // 2 and meanwhile:
                meanwhile()
                meanwhile = None
            segment = ask([NODE, 0x13, sid, counter & 0xFF])
            assert segment[:3] == bytes([0x22, 0x33, sid]) and segment[3] == counter & 0xFF \
                or segment[:3] == bytes([0x22, 0x34, sid]), segment[:4].hex()
            if segment[1] == 0x34:
                received += segment[4:4 + segment[3]]
                return bytes(received)
            received += segment[4:64]
            counter += 1
    first = ask([0x40, index & 0xFF, index >> 8, 0, 0, 0, 0, 0])   # SDO, 0x60|t per segment
    assert first == bytes([0x41, index & 0xFF, index >> 8, 0]) + size.to_bytes(4, "little")
    toggle = 0
    while True:
        if len(received) >= size // 2 and meanwhile:
            meanwhile()
            meanwhile = None
        segment = ask([0x60 | toggle << 4, 0, 0, 0, 0, 0, 0, 0])
        assert segment[0] & 0xE0 == 0 and (segment[0] >> 4) & 1 == toggle, segment.hex()
        received += segment[1:8 - ((segment[0] >> 1) & 7)]
        if segment[0] & 1:
            return bytes(received)
        toggle ^= 1


@MODES
def test_a_transfer_in_progress_survives_objects_added_meanwhile(net, bus_name, mode):
    """Objects added in the middle of an upload, at indices below and above its
    object's (live entries are appended behind the sorted table: nothing the
    transfer holds may move): the upload goes on with the same object."""
    node, od, _, frames = rig(net, bus_name, mode, boot=False)
    node.serve_domain(0x2100, 4096)
    node.boot()
    data = bytes((i * 7 + 3) & 0xFF for i in range(1000))
    node[0x2100].data = data
    raw = net.open_line(bus_name, mode=mode)

    def add_objects():
        for i in range(4):
            od.add_object(ODVariable(f"Before {i}", 0x2020 + i, 0, DataType.UNSIGNED8, "rw", i))
            od.add_object(ODVariable(f"After {i}", 0x2F30 + i, 0, DataType.UNSIGNED8, "rw",
                                     0x10 + i))

    assert upload_by_hand(raw, frames, mode, 0x2100, len(data), add_objects) == data
    assert node[0x2023].raw == 3 and node[0x2F33].raw == 0x13
    client = raw.usdo if mode == "fd" else raw.sdo
    assert client.upload(NODE, 0x2023, 0) == b"\x03"
    assert client.upload(NODE, 0x2F31, 0) == b"\x11"
    assert client.upload(NODE, 0x2100, 0) == data
