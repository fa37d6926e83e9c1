"""The local node's object dictionary served over USDO on fd lines, checked
byte for byte on the bus. The requests are raw frames (our USDO client comes
with its own issue); the layouts are those of docs/protocol-notes.md."""

import os
import time

import pytest

from canopenfd.od import demo_od
from helpers import Recorder, scaled

SERVER, CLIENT = 5, 2
REQUEST, RESPONSE = 0x600 + CLIENT, 0x580 + SERVER


@pytest.fixture
def rig(net, bus_name, tmp_path):
    """A server node with the demo OD and a store, and a client line that
    monitors the bus and sends raw USDO requests."""
    store = str(tmp_path / "params.bin")
    node = net.open_line(bus_name, mode="fd").create_local_node(SERVER, od=demo_od("fd"),
                                                                store=store)
    client = net.open_line(bus_name, mode="fd", monitor=True)
    answers = Recorder()
    client.on_frame(lambda f: answers(f) if f.id == RESPONSE else None)
    return node, client, answers, store


def ask(client, answers, data: bytes):
    """Send one request and return the server's answer frame."""
    before = len(answers)
    client.send_frame(REQUEST, data)
    return answers.wait_count(before + 1)[before]


def test_expedited_upload_answers_with_the_exact_bytes(rig):
    node, client, answers, _ = rig
    node[0x1017].raw = 0x1234
    # [server, 0x11 upload, session 7, sub 0, index 0x1017 LE]
    frame = ask(client, answers, bytes([SERVER, 0x11, 7, 0x00, 0x17, 0x10]))
    # [client, 0x31, session, sub, index, type UNSIGNED16, size 2, value LE] padded to 12
    assert frame.fd and frame.brs
    assert frame.data == bytes([CLIENT, 0x31, 7, 0x00, 0x17, 0x10, 0x06, 2, 0x34, 0x12,
                                0, 0])


def test_expedited_download_writes_the_entry_and_rearms_the_heartbeat(rig):
    node, client, answers, _ = rig
    frame = ask(client, answers, bytes([SERVER, 0x01, 3, 0x00, 0x17, 0x10, 0x06, 2, 0x2C, 0x01]))
    assert frame.data == bytes([CLIENT, 0x21, 3, 0x00, 0x17, 0x10])
    assert node[0x1017].raw == 300
    assert node.heartbeat_ms == 300


def test_write_to_a_read_only_entry_is_aborted_and_changes_nothing(rig):
    node, client, answers, _ = rig
    before = node["0x1018:1"].raw
    frame = ask(client, answers, bytes([SERVER, 0x01, 4, 0x01, 0x18, 0x10, 0x07, 4, 1, 2, 3, 4]))
    # abort: [client, 0x7F, session, sub, index, code 0x32 "read only"]
    assert frame.data[:7] == bytes([CLIENT, 0x7F, 4, 0x01, 0x18, 0x10, 0x32])
    assert node["0x1018:1"].raw == before


def test_missing_object_is_aborted(rig):
    _, client, answers, _ = rig
    frame = ask(client, answers, bytes([SERVER, 0x11, 9, 0x00, 0x00, 0x5F]))
    assert frame.data[:7] == bytes([CLIENT, 0x7F, 9, 0x00, 0x00, 0x5F, 0x33])   # no object


def test_save_over_the_network_writes_the_store_file(rig):
    node, client, answers, store = rig
    node[0x1017].raw = 250
    # "save" (0x65766173) to 0x1010 sub 1: store every parameter group
    frame = ask(client, answers, bytes([SERVER, 0x01, 5, 0x01, 0x10, 0x10, 0x07, 4])
                + (0x65766173).to_bytes(4, "little"))
    assert frame.data == bytes([CLIENT, 0x21, 5, 0x01, 0x10, 0x10])
    assert os.path.getsize(store) > 0
    resets = Recorder()
    node.on_reset(resets)
    node.apply("reset-communication")
    resets.wait_count(1)            # the reset ran: parameters are loaded
    assert node[0x1017].raw == 250


def test_requests_for_another_node_are_not_answered(rig):
    node, client, answers, _ = rig
    client.send_frame(REQUEST, bytes([SERVER + 1, 0x11, 1, 0x00, 0x17, 0x10]))
    frame = ask(client, answers, bytes([SERVER, 0x11, 2, 0x00, 0x17, 0x10]))
    assert frame.data[2] == 2                       # only the request for us was answered


def test_object_changed_callback_sees_network_writes_only(rig):
    node, client, answers, _ = rig
    changes = Recorder()
    node.on_object_changed(lambda value, origin: changes((value.variable.index, origin,
                                                          value.raw)))
    node[0x1017].raw = 20                             # the application's own write: not told
    ask(client, answers, bytes([SERVER, 0x01, 3, 0x00, 0x17, 0x10, 0x06, 2, 0x2C, 0x01]))
    assert changes.wait_count(1) == [(0x1017, "network", 300)]


def test_cob_id_of_an_active_object_cannot_change(net, bus_name):
    """CiA 301: a COB-ID changes only while its object is invalid; otherwise
    abort 0x40 (0x06090030, invalid value) and the entry stays."""
    from canopenfd.od import ODRecord, ODVariable
    from canopenfd.od.datatypes import DataType
    od = demo_od("fd")
    od.add_object(ODVariable("COB-ID EMCY", 0x1014, 0, DataType.UNSIGNED32, "rw", 0x85))
    tpdo = ODRecord("TPDO 1 communication parameter", 0x1800)
    tpdo.add_member(ODVariable("Highest sub-index supported", 0x1800, 0, DataType.UNSIGNED8,
                               "ro", 1))
    tpdo.add_member(ODVariable("COB-ID used by TPDO", 0x1800, 1, DataType.UNSIGNED32, "rw",
                               0x185))
    od.add_object(tpdo)
    node = net.open_line(bus_name, mode="fd").create_local_node(SERVER, od=od)
    client = net.open_line(bus_name, mode="fd", monitor=True)
    answers = Recorder()
    client.on_frame(lambda f: answers(f) if f.id == RESPONSE else None)

    def write(session, sub, index, value):
        return ask(client, answers, bytes([SERVER, 0x01, session, sub]) +
                   index.to_bytes(2, "little") + bytes([0x07, 4]) + value.to_bytes(4, "little"))

    assert write(1, 1, 0x1800, 0x186).data[:7] == bytes([CLIENT, 0x7F, 1, 1, 0x00, 0x18, 0x40])
    assert node[0x1800][1].raw == 0x185
    assert write(2, 0, 0x1014, 0x86).data[:7] == bytes([CLIENT, 0x7F, 2, 0, 0x14, 0x10, 0x40])
    # disable, change, enable: each answered 0x21 (EMCY: a TPDO without a
    # mapping object could not be enabled again)
    for session, value in ((3, 0x80000085), (4, 0x80000086), (5, 0x86)):
        assert write(session, 0, 0x1014, value).data[:2] == bytes([CLIENT, 0x21])
    assert node[0x1014].raw == 0x86
    # the TPDO: disabled and changed while invalid
    for session, value in ((6, 0x80000185), (7, 0x80000186)):
        assert write(session, 1, 0x1800, value).data[:2] == bytes([CLIENT, 0x21])
    assert node[0x1800][1].raw == 0x80000186


def test_stopped_node_answers_no_usdo(rig):
    """USDO, like SDO in CiA 301, only in pre-operational and operational: in
    stopped a request gets no answer (counted), after NMT enter
    pre-operational the same request is answered."""
    node, client, answers, _ = rig
    client.send_frame(0x000, bytes([0x02, SERVER]))                 # NMT stop node 5
    deadline = time.monotonic() + scaled(5)
    while node.state != "STOPPED":
        assert time.monotonic() < deadline, "node 5 did not stop"
        time.sleep(0.01)
    before = len(answers)
    client.send_frame(REQUEST, bytes([SERVER, 0x11, 7, 0x01, 0x18, 0x10]))
    deadline = time.monotonic() + scaled(5)
    while node.line.service_stats["usdo_server"]["rx_not_serving"] < 1:
        assert time.monotonic() < deadline, "request not counted"
        time.sleep(0.01)
    time.sleep(0.2)
    assert len(answers) == before
    client.send_frame(0x000, bytes([0x80, SERVER]))                 # enter pre-operational
    deadline = time.monotonic() + scaled(5)
    while node.state != "PRE-OPERATIONAL":
        assert time.monotonic() < deadline, "node 5 not pre-operational"
        time.sleep(0.01)
    frame = ask(client, answers, bytes([SERVER, 0x11, 8, 0x01, 0x18, 0x10]))
    assert frame.data[:3] == bytes([CLIENT, 0x31, 8])


@pytest.mark.parametrize("mode", ["fd", "classic"])
def test_node_without_od_answers_no_such_object(net, bus_name, mode):
    """A local node created without od= (NMT and heartbeat only) answers
    every request at once with "object does not exist" (USDO 0x33, SDO
    0x06020000) and the request's multiplexer, so a client is told well
    before its timeout instead of waiting for it."""
    from canopenfd import SdoAbortError, UsdoAbortError

    net.open_line(bus_name, mode=mode).create_local_node(SERVER)
    seen = Recorder()
    net.open_line(bus_name, mode=mode, monitor=True).on_frame(
        lambda f: seen(f) if f.id == RESPONSE else None)
    line = net.open_line(bus_name, mode=mode)
    client = line.usdo if mode == "fd" else line.sdo
    started = time.monotonic()
    with pytest.raises(UsdoAbortError if mode == "fd" else SdoAbortError) as refused:
        client.upload(SERVER, 0x1000, 0, timeout=5.0)
    assert time.monotonic() - started < scaled(1.0)    # an answer, not the 5 s timeout
    assert refused.value.from_server
    (frame,) = seen.wait_count(1)
    if mode == "fd":
        assert refused.value.usdo_code == 0x33 and refused.value.code == 0x06020000
        assert frame.data[1:2] == b"\x7F" and frame.data[3:7] == bytes([0x00, 0x00, 0x10, 0x33])
    else:
        assert refused.value.code == 0x06020000
        assert frame.data == bytes([0x80, 0x00, 0x10, 0x00, 0x00, 0x00, 0x02, 0x06])
