"""USDO bulk upload, empty values and short segments through the Python API
over the in-process bus: the frames on the bus byte for byte (layouts and
their evidence: docs/protocol-notes.md, "Bulk upload"), the counters the
client and the server expose, and a scripted server for what our own
server never sends (segments shorter than 64 bytes, a segmented empty
value)."""

import os

import pytest

from canopenfd import ConfigurationError, UsdoAbortError
from canopenfd.od import demo_od
from helpers import Recorder, scaled

SERVER, CLIENT = 5, 0x7F        # a tool without a local node is client 127
SCRIPTED = 0x40                 # the scripted server's node-id
DOMAIN = 0x2100
MiB = 1 << 20
WINDOW = 64                     # the client's window with the runtime's 1024-frame queue


@pytest.fixture
def rig(net, bus_name):
    """Server node 5 (demo OD, a 16 MiB domain), a client line (client 127)
    and a monitor of every frame."""
    server_line = net.open_line(bus_name, mode="fd")
    node = server_line.create_local_node(SERVER, od=demo_od("fd"), boot=False)
    node.serve_domain(DOMAIN, 16 * MiB)
    node.boot()
    line = net.open_line(bus_name, mode="fd")
    frames = Recorder()
    net.open_line(bus_name, mode="fd", monitor=True).on_frame(frames)
    return node, line, frames, server_line


def on_id(frames, can_id):
    return [f for f in frames.snapshot() if f.id == can_id]


def test_bulk_upload_frames_on_the_bus(rig):
    server, line, frames, server_line = rig
    data = bytes(range(256)) * 40          # 10 240 bytes: 170 segments and 40 bytes
    server[DOMAIN].data = data
    transfer = line.usdo.start_upload(SERVER, DOMAIN, 0, mode="bulk")
    assert transfer.result(timeout=scaled(10)) == data
    assert transfer.mode == "bulk" and transfer.transferred == len(data)
    answers = frames.wait_for(
        lambda c: [f for f in c if f.id == 0x580 + SERVER] if any(
            f.id == 0x580 + SERVER and f.data[1] == 0x38 for f in c) else None, 5, "0x38")
    requests = on_id(frames, 0x600 + CLIENT)
    sid = requests[0].data[2]
    # [server, 0x16, sid, sub 0, index LE, window, 0]
    assert requests[0].data[:8] == bytes([SERVER, 0x16, sid, 0, 0x00, 0x21, WINDOW, 0])
    # 0x36: as 0x32, [client, 0x36, sid, sub, index LE, type DOMAIN, 0, size LE]
    assert answers[0].data[:12] == bytes([CLIENT, 0x36, sid, 0, 0x00, 0x21, 0x0F, 0]) + \
        len(data).to_bytes(4, "little")
    segments = answers[1:-1]
    assert len(segments) == len(data) // 60
    for number, frame in enumerate(segments):   # not confirmed one by one, counter from 0
        assert len(frame.data) == 64
        assert frame.data[:4] == bytes([CLIENT, 0x37, sid, number & 0xFF])
        assert frame.data[4:] == data[number * 60:(number + 1) * 60]
    rest = len(data) % 60
    assert answers[-1].data[:4 + rest] == bytes([CLIENT, 0x38, sid, rest]) + data[-rest:]
    # acknowledgements every half window naming the last segment taken, until the
    # server's credit (a window beyond) covers the rest: 171 segments, acks after
    # 32, 64, 96, 128; after 160 the credit up to 192 covers them
    acks = [f for f in requests if f.data[1] == 0x17]
    assert [bytes(a.data[:4]) for a in acks] == [
        bytes([SERVER, 0x17, sid, n - 1]) for n in (32, 64, 96, 128)]
    assert len(requests) == 1 + len(acks)
    assert server_line.service_stats["usdo_server"]["rx_stray_ack"] == 0
    stats = line.service_stats["usdo_client"]
    assert stats["bulk_uploads"] == 1 and stats["acks_sent"] == len(acks)
    assert server_line.service_stats["usdo_server"]["bulk_uploads"] == 1


@pytest.mark.parametrize("size", [0, 1, 60, 61, 4096, MiB + 7])
def test_bulk_upload_sizes_byte_for_byte(rig, size):
    server, line, _, server_line = rig
    data = os.urandom(size)
    server[DOMAIN].data = data
    transfer = line.usdo.start_upload(SERVER, DOMAIN, 0, mode="bulk", max_size=max(size, 1))
    assert transfer.result(timeout=scaled(30)) == data
    assert transfer.mode == "bulk"
    assert line.stats["rx_overflow"] == 0


def test_auto_picks_bulk_for_a_big_size_hint_or_a_big_od_entry(rig):
    server, line, _, server_line = rig
    data = os.urandom(5000)
    server[DOMAIN].data = data
    small = line.usdo.start_upload(SERVER, DOMAIN, 0)
    assert small.result(timeout=scaled(10)) == data and small.mode == "segmented"
    hinted = line.usdo.start_upload(SERVER, DOMAIN, 0, size_hint=5000)
    assert hinted.result(timeout=scaled(10)) == data and hinted.mode == "bulk"
    low = line.usdo.start_upload(SERVER, DOMAIN, 0, size_hint=4095)
    assert low.result(timeout=scaled(10)) == data and low.mode == "segmented"
    # through the node's OD: the domain's 16 MiB max length is the hint
    remote = line.add_node(SERVER, od=demo_od("fd"))
    through_od = remote.usdo.start_upload("Demo large domain")
    assert through_od.result(timeout=scaled(10)) == data and through_od.mode == "bulk"
    assert remote.usdo.upload("Demo large domain") == data


def test_upload_modes_are_checked(rig):
    _, line, _, _ = rig
    with pytest.raises(ConfigurationError, match="'block' is not one of auto, bulk"):
        line.usdo.start_upload(SERVER, DOMAIN, 0, mode="block")
    with pytest.raises(ConfigurationError, match="'segmented' is not one of auto, bulk"):
        line.usdo.start_upload(SERVER, DOMAIN, 0, mode="segmented")


def test_empty_value_is_uploaded_expedited_with_n_0(rig):
    server, line, frames, server_line = rig
    server["Demo record.Label"].raw = ""
    assert line.usdo.upload(SERVER, 0x2200, 4) == b""
    answer = frames.wait_for(lambda c: [f for f in c if f.id == 0x580 + SERVER], 5,
                             "the answer")[0]
    sid = answer.data[2]
    # [client, 0x31, sid, sub 4, index 0x2200, VISIBLE_STRING, N = 0], padded to 8
    assert bytes(answer.data) == bytes([CLIENT, 0x31, sid, 4, 0x00, 0x22, 0x09, 0])
    # bulk: 0x36 size 0, then 0x38 with n = 0
    transfer = line.usdo.start_upload(SERVER, 0x2200, 4, mode="bulk")
    assert transfer.result(timeout=scaled(5)) == b""
    frames.wait_for(lambda c: any(f.id == 0x580 + SERVER and f.data[1] == 0x38 for f in c), 5,
                    "0x38")
    last = on_id(frames, 0x580 + SERVER)[-1]
    assert last.data[:4] == bytes([CLIENT, 0x38, transfer_sid(frames), 0])


def transfer_sid(frames):
    return [f for f in on_id(frames, 0x600 + CLIENT) if f.data[1] == 0x16][-1].data[2]


@pytest.fixture
def scripted(net, bus_name):
    """A client line, a raw line playing server 0x40 frame by frame and a
    monitor recording the client's frames."""
    line = net.open_line(bus_name, mode="fd")
    raw = net.open_line(bus_name, mode="fd")
    requests = Recorder()
    monitor = net.open_line(bus_name, mode="fd", monitor=True)
    monitor.on_frame(lambda f: requests(f) if f.id == 0x600 + CLIENT else None)
    return line, raw, requests


def next_request(requests, count):
    return requests.wait_count(count, timeout=scaled(5))[count - 1]


def test_short_segments_and_a_segmented_empty_value_are_taken(scripted):
    line, raw, requests = scripted
    data = os.urandom(80)
    transfer = line.usdo.start_upload(SCRIPTED, 0x2009, 0)
    sid = next_request(requests, 1).data[2]
    answer = 0x580 + SCRIPTED
    raw.send_frame(answer, bytes([CLIENT, 0x32, sid, 0, 0x09, 0x20, 0x0F, 0]) +
                   (80).to_bytes(4, "little"))
    assert next_request(requests, 2).data[:4] == bytes([SCRIPTED, 0x13, sid, 0])
    raw.send_frame(answer, bytes([CLIENT, 0x33, sid, 0]) + data[:28])      # a 32-byte frame
    assert next_request(requests, 3).data[:4] == bytes([SCRIPTED, 0x13, sid, 1])
    raw.send_frame(answer, bytes([CLIENT, 0x33, sid, 1]) + data[28:72])    # a 48-byte frame
    assert next_request(requests, 4).data[:4] == bytes([SCRIPTED, 0x13, sid, 2])
    raw.send_frame(answer, bytes([CLIENT, 0x34, sid, 8]) + data[72:])
    assert transfer.result(timeout=scaled(5)) == data
    assert line.service_stats["usdo_client"]["rx_short_segment"] == 2
    # an empty value sent segmented (size 0, then n = 0) is taken as well
    transfer = line.usdo.start_upload(SCRIPTED, 0x2009, 0)
    sid = next_request(requests, 5).data[2]
    raw.send_frame(answer, bytes([CLIENT, 0x32, sid, 0, 0x09, 0x20, 0x0F, 0, 0, 0, 0, 0]))
    assert next_request(requests, 6).data[:4] == bytes([SCRIPTED, 0x13, sid, 0])
    raw.send_frame(answer, bytes([CLIENT, 0x34, sid, 0]))
    assert transfer.result(timeout=scaled(5)) == b""


def test_a_server_without_bulk(scripted):
    line, raw, requests = scripted
    answer = 0x580 + SCRIPTED
    # forced bulk: the server's 0x13 is the error, naming the entry and the meaning
    transfer = line.usdo.start_upload(SCRIPTED, 0x2009, 0, mode="bulk")
    request = next_request(requests, 1)
    sid = request.data[2]
    assert request.data[:8] == bytes([SCRIPTED, 0x16, sid, 0, 0x09, 0x20, WINDOW, 0])
    raw.send_frame(answer, bytes([CLIENT, 0x7F, sid, 0, 0x09, 0x20, 0x13]))
    with pytest.raises(UsdoAbortError) as info:
        transfer.result(timeout=scaled(5))
    assert info.value.usdo_code == 0x13 and info.value.from_server
    assert "command specifier unknown" in str(info.value) and "0x2009:00" in str(info.value)
    # AUTO with a big hint: asked bulk, refused, asked again plainly (fresh session-ID)
    transfer = line.usdo.start_upload(SCRIPTED, 0x2009, 0, size_hint=10000)
    sid = next_request(requests, 2).data[2]
    raw.send_frame(answer, bytes([CLIENT, 0x7F, sid, 0, 0x09, 0x20, 0x13]))
    plain = next_request(requests, 3)
    assert plain.data[1] == 0x11 and plain.data[2] != sid
    raw.send_frame(answer, bytes([CLIENT, 0x31, plain.data[2], 0, 0x09, 0x20, 0x0F, 2, 7, 8]))
    assert transfer.result(timeout=scaled(5)) == b"\x07\x08"
    assert transfer.mode == "expedited"
    assert line.service_stats["usdo_client"]["bulk_fallback"] == 1
