"""The USDO client through the Python API (line.usdo, remote.usdo,
remote.od[...].raw) against our server over the in-process bus, with the
client's frames checked byte for byte on the bus (layouts:
docs/protocol-notes.md)."""

import asyncio
import io
import os
import threading
import time

import pytest

import canopenfd
from canopenfd import ConfigurationError, UsdoAbortError
from canopenfd.od import demo_od
from helpers import Recorder, scaled

SERVER, CLIENT = 5, 0x7F        # a tool without a local node is client 127
DOMAIN = 0x2100
MiB = 1 << 20


def make_server(net, bus, node_id=SERVER, domain=16 * MiB):
    node = net.open_line(bus, mode="fd").create_local_node(node_id, od=demo_od("fd"),
                                                           boot=False)
    if domain:
        node.serve_domain(DOMAIN, domain)
    node.boot()
    return node


@pytest.fixture
def rig(net, bus_name):
    """Server node 5 with the demo OD and a 16 MiB domain, a client line
    (no local node: client 127) and a monitor of every frame on the bus."""
    server = make_server(net, bus_name)
    line = net.open_line(bus_name, mode="fd")
    frames = Recorder()
    net.open_line(bus_name, mode="fd", monitor=True).on_frame(frames)
    return server, line, frames


def usdo_frames(frames, can_id):
    return [f for f in frames.snapshot() if f.id == can_id]


def test_expedited_upload_request_bytes_and_typed_values(rig):
    server, line, frames = rig
    server[0x1017].raw = 0x1234
    remote = line.add_node(SERVER, od=demo_od("fd"))
    assert remote.od["Producer heartbeat time"].raw == 0x1234
    request = frames.wait_for(lambda c: [f for f in c if f.id == 0x600 + CLIENT], 2,
                              "the request")[0]
    sid = request.data[2]
    assert sid != 0
    # [server, 0x11 upload, session, sub 0, index 0x1017 LE], FD with BRS, padded with 0
    assert request.fd and request.brs
    assert request.data[:6] == bytes([SERVER, 0x11, sid, 0x00, 0x17, 0x10])
    assert set(request.data[6:]) <= {0}
    answer = frames.wait_for(lambda c: [f for f in c if f.id == 0x580 + SERVER], 2,
                             "answer")[0]
    assert answer.data[:10] == bytes([CLIENT, 0x31, sid, 0x00, 0x17, 0x10, 0x06, 2, 0x34, 0x12])


def test_expedited_download_bytes_carry_the_od_type(rig):
    server, line, frames = rig
    remote = line.add_node(SERVER, od=demo_od("fd"))
    remote.od["Demo record.Setpoint"].raw = -2
    request = frames.wait_for(lambda c: [f for f in c if f.id == 0x600 + CLIENT], 2,
                              "the request")[0]
    # [server, 0x01, sid, sub 1, index 0x2200, type INTEGER16 (3), N=2, -2 LE]
    assert request.data[:10] == bytes([SERVER, 0x01, request.data[2], 0x01, 0x00, 0x22, 0x03, 2,
                                       0xFE, 0xFF])
    assert server[0x2200][1].raw == -2


def test_raw_bytes_by_index_without_an_od(rig):
    server, line, _ = rig
    server["Demo record.Label"].raw = "axis-7"
    assert line.usdo.upload(SERVER, 0x2200, 4) == b"axis-7"
    line.usdo.download(SERVER, 0x2200, 4, b"spindle")   # sent as DOMAIN: raw bytes
    assert server["Demo record.Label"].raw == "spindle"
    remote = line.add_node(SERVER)
    assert remote.usdo.upload("2200:04") == b"spindle"
    with pytest.raises(ConfigurationError, match="no object dictionary"):
        remote.od["Demo record.Label"]


@pytest.mark.parametrize("size, mode", [(40, "expedited"), (1000, "segmented"),
                                        (60 * 300, "bulk"), (MiB, "bulk")])
def test_transfers_both_ways_byte_for_byte(rig, size, mode):
    server, line, frames = rig
    data = os.urandom(size)
    transfer = line.usdo.start_download(SERVER, DOMAIN, 0, data)
    assert transfer.result(timeout=scaled(30)) is None
    assert transfer.mode == mode and transfer.transferred == size
    assert server[DOMAIN].data == data
    assert line.usdo.upload(SERVER, DOMAIN) == data


def test_bulk_frames_on_the_bus(rig):
    server, line, frames = rig
    data = bytes(range(256)) * 40          # 10 240 bytes: 171 segments, bulk
    line.usdo.download(SERVER, DOMAIN, 0, data)
    # the monitor line hears the final confirmation a moment after the client
    frames.wait_for(lambda c: any(f.id == 0x580 + SERVER and f.data[1] == 0x28 for f in c), 5,
                    "0x28")
    requests = usdo_frames(frames, 0x600 + CLIENT)
    sid = requests[0].data[2]
    # initiate: [server, 0x06, sid, sub, index LE, type DOMAIN, 0, size LE]
    assert requests[0].data[:12] == bytes([SERVER, 0x06, sid, 0, 0x00, 0x21, 0x0F, 0]) + \
        len(data).to_bytes(4, "little")
    segments = [f for f in requests if f.data[1] == 0x07]
    assert len(segments) == len(data) // 60
    for number, frame in enumerate(segments):          # unconfirmed, counter from 0
        assert frame.data[:4] == bytes([SERVER, 0x07, sid, number & 0xFF])
        assert frame.data[4:] == data[number * 60:(number + 1) * 60]
    last = requests[-1]
    rest = len(data) % 60
    assert last.data[:4 + rest] == bytes([SERVER, 0x08, sid, rest]) + data[-rest:]
    answers = usdo_frames(frames, 0x580 + SERVER)
    assert [a.data[1] for a in answers] == [0x26, 0x28]   # accept + final confirmation
    assert server[DOMAIN].data == data


def test_an_abort_names_node_entry_code_and_meaning(rig):
    _, line, _ = rig
    with pytest.raises(UsdoAbortError) as info:
        line.usdo.upload(SERVER, 0x5FFF, 0)
    error = info.value
    assert (error.usdo_code, error.code) == (0x33, 0x06020000)
    assert (error.node, error.index, error.subindex, error.from_server) == (SERVER, 0x5FFF, 0,
                                                                          True)
    assert "object does not exist" in str(error) and "0x5FFF:00" in str(error)
    assert isinstance(error, canopenfd.AbortError)


def test_a_silent_server_times_out_and_the_abort_goes_on_the_bus(net, bus_name):
    line = net.open_line(bus_name, mode="fd")
    frames = Recorder()
    net.open_line(bus_name, mode="fd", monitor=True).on_frame(frames)
    started = time.monotonic()
    with pytest.raises(UsdoAbortError) as info:
        line.usdo.upload(42, 0x1000, timeout=0.2)
    assert time.monotonic() - started < scaled(3)
    assert info.value.usdo_code == 0x12 and not info.value.from_server
    sent = frames.wait_count(2)
    assert sent[1].data[:7] == bytes([42, 0x7F, sent[0].data[2], 0, 0x00, 0x10, 0x12])


def test_cancel_sends_the_abort_frame(net, bus_name):
    line = net.open_line(bus_name, mode="fd")
    frames = Recorder()
    net.open_line(bus_name, mode="fd", monitor=True).on_frame(frames)
    transfer = line.usdo.start_upload(42, 0x1018, 1, timeout=scaled(5))   # nobody answers
    request = frames.wait_count(1)[0]
    transfer.cancel(0x61)
    with pytest.raises(UsdoAbortError) as info:
        transfer.result()
    assert info.value.usdo_code == 0x61 and not info.value.from_server
    abort = frames.wait_count(2)[1]
    assert abort.data[:7] == bytes([42, 0x7F, request.data[2], 0x01, 0x18, 0x10, 0x61])


def test_cancel_mid_bulk_frees_everything(net, bus_name):
    """Cancel right after the start: the C stack may finish the 4 MiB first
    (the bytes-on-the-bus check of a cancel is the silent-server test above;
    mid-stream cancels are timed exactly in tests/c/test_usdo_client.c).
    Either way the domain holds all or nothing and nothing leaks."""
    server = make_server(net, bus_name)
    line = net.open_line(bus_name, mode="fd")
    data = os.urandom(4 * MiB)
    transfer = line.usdo.start_download(SERVER, DOMAIN, 0, data)
    transfer.cancel()
    try:
        transfer.result(timeout=scaled(10))
    except UsdoAbortError as error:
        assert error.usdo_code == 0x10 and not error.from_server
    # the domain never holds a half-written image, and the next transfer works
    assert server[DOMAIN].data in (b"", data)
    line.usdo.download(SERVER, DOMAIN, 0, b"after")
    assert server[DOMAIN].data == b"after"


def test_broadcast_collects_every_server(net, bus_name):
    for node_id in (3, 4, 6):
        node = make_server(net, bus_name, node_id, domain=0)
        node[0x1017].raw = node_id * 10
    line = net.open_line(bus_name, mode="fd")
    answers = line.usdo.broadcast_upload(0x1017, window=scaled(0.3))
    assert answers == {3: b"\x1e\x00", 4: b"\x28\x00", 6: b"\x3c\x00"}
    refused = line.usdo.broadcast_upload(0x5FFF, window=scaled(0.3))
    assert sorted(refused) == [3, 4, 6]
    assert all(isinstance(e, UsdoAbortError) and e.usdo_code == 0x33 for e in refused.values())
    acks = line.usdo.broadcast_download(0x1017, 0, (250).to_bytes(2, "little"),
                                        window=scaled(0.3))
    assert acks == {3: None, 4: None, 6: None}
    # upload() gives one entry's bytes: node 0 (the broadcast) is broadcast_upload()'s
    with pytest.raises(ConfigurationError, match="node 0 is the USDO broadcast"):
        line.usdo.upload(0, 0x1017)


def test_32_transfers_at_once_from_several_threads(rig):
    server, line, _ = rig
    results, errors = {}, []

    def worker(n):
        try:
            results[n] = line.usdo.upload(SERVER, 0x1018, 1 + n % 4)
        except Exception as exc:  # noqa: BLE001
            errors.append(exc)

    threads = [threading.Thread(target=worker, args=(n,)) for n in range(32)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(scaled(20))
    assert not errors
    expected = {sub: server[0x1018][sub].data for sub in (1, 2, 3, 4)}
    assert all(results[n] == expected[1 + n % 4] for n in range(32))


def test_awaitable_transfers(rig):
    server, line, _ = rig
    remote = line.add_node(SERVER, od=demo_od("fd"))

    async def main():
        await remote.usdo.adownload(DOMAIN, b"x" * 5000)
        values = await asyncio.gather(*(remote.od[0x1018][sub].aget() for sub in (1, 2, 3, 4)))
        return values, await remote.usdo.aupload(DOMAIN)

    values, data = asyncio.run(main())
    assert values == [server[0x1018][sub].raw for sub in (1, 2, 3, 4)]
    assert data == b"x" * 5000


def test_file_streams_with_progress(rig, tmp_path):
    server, line, _ = rig
    remote = line.add_node(SERVER)
    payload = os.urandom(3 * MiB + 17)
    progress = Recorder()
    with remote.usdo.open(DOMAIN, "wb", progress=progress) as stream:
        stream.write(payload)
    assert server[DOMAIN].data == payload
    progress.wait_count(1)          # progress calls run on the dispatcher thread
    assert progress.snapshot() and progress.snapshot()[-1] <= len(payload)
    source = tmp_path / "image.bin"
    source.write_bytes(payload[::-1])
    with open(source, "rb") as f:
        remote.usdo.download(DOMAIN, f)
    with remote.usdo.open(DOMAIN, "rb") as f:
        assert f.read() == payload[::-1]
    with open(tmp_path / "copy.bin", "wb") as f:
        line.usdo.start_upload(SERVER, DOMAIN, 0, file=f).result()
    assert (tmp_path / "copy.bin").read_bytes() == payload[::-1]
    with open(tmp_path / "again.bin", "wb") as f:   # the blocking form: the data is in f
        assert line.usdo.upload(SERVER, DOMAIN, 0, file=f) == b""
    assert (tmp_path / "again.bin").read_bytes() == payload[::-1]


def test_upload_larger_than_max_size_is_refused(rig):
    server, line, frames = rig
    server[DOMAIN].data = bytes(10000)
    with pytest.raises(UsdoAbortError) as info:
        line.usdo.upload(SERVER, DOMAIN, max_size=1000)
    assert info.value.usdo_code == 0x16 and not info.value.from_server


def test_wrong_use_is_refused_with_a_clear_error(net, bus_name, rig):
    _, line, _ = rig
    classic = net.open_line(bus_name + "-classic", mode="classic")
    with pytest.raises(ConfigurationError, match="classic line"):
        classic.usdo
    with pytest.raises(ConfigurationError, match="node must be"):
        line.usdo.upload(300, 0x1000)
    with pytest.raises(ConfigurationError, match="mode"):
        line.usdo.download(SERVER, DOMAIN, 0, b"x", mode="fast")
    with pytest.raises(ConfigurationError, match="bytes-like"):
        line.usdo.download(SERVER, DOMAIN, 0, 12345)
    with pytest.raises(canopenfd.CanopenFDError, match="56 bytes"):
        line.usdo.download(SERVER, DOMAIN, 0, bytes(100), mode="expedited")
    remote = line.add_node(SERVER, od=demo_od("fd"))
    with pytest.raises(ConfigurationError, match="RECORD"):
        remote.usdo.upload(0x1018)


def test_read_and_write_pick_the_type_from_the_od(rig):
    server, line, _ = rig
    typed = line.add_node(SERVER, od=demo_od("fd"))
    typed.write("Demo record.Gain", 2.5)
    assert typed.read("Demo record.Gain") == 2.5 == server["Demo record.Gain"].raw
    assert asyncio.run(typed.aread(0x1017)) == server[0x1017].raw
    asyncio.run(typed.awrite(0x1017, 77))
    assert server[0x1017].raw == 77
    line.remove_node(SERVER)
    raw = line.add_node(SERVER)
    assert raw.read((0x1017, 0)) == (77).to_bytes(2, "little")
    with pytest.raises(ConfigurationError, match="must be bytes"):
        raw.write(0x1017, 5)


@pytest.fixture
def done_events(monkeypatch):
    """The handles of the TRANSFER_DONE events the dispatcher delivers."""
    from canopenfd._binding.constants import EventKind
    from canopenfd.network import Network
    seen = []
    deliver = Network._deliver

    def counting(self, event):
        if event.kind == EventKind.TRANSFER_DONE:
            seen.append(event.a)
        deliver(self, event)

    monkeypatch.setattr(Network, "_deliver", counting)
    return seen


def test_waiting_forms_wait_in_c_without_a_done_event(rig, done_events):
    """upload()/download() and start_*().result() block in the runtime
    (co_rt_transfer_wait); transfers ask for no TRANSFER_DONE event unless
    awaited, so the dispatcher thread does not wake and compete for the GIL."""
    server, line, _ = rig
    remote = line.add_node(SERVER)
    for _ in range(5):
        remote.usdo.download(0x1017, (100).to_bytes(2, "little"))
        assert remote.usdo.upload(0x1017) == (100).to_bytes(2, "little")
        remote.usdo.start_download(0x1017, (100).to_bytes(2, "little")).result()
        assert remote.usdo.start_upload(0x1017).result() == (100).to_bytes(2, "little")
    line.usdo.download(SERVER, DOMAIN, 0, b"y" * 3000)                  # segmented
    assert line.usdo.upload(SERVER, DOMAIN) == b"y" * 3000
    ended = line.usdo.start_upload(SERVER, DOMAIN)
    time.sleep(scaled(0.2))                 # ends unheard: nobody waits or awaits
    assert ended.done()
    assert ended.result() == b"y" * 3000
    time.sleep(scaled(0.05))
    assert done_events == []


def test_an_awaited_transfer_is_told_by_its_done_event(net, bus_name, done_events):
    """An `await` asks the runtime for the TRANSFER_DONE event: the server
    holds the upload until the task awaits, so the end comes through the
    event (exactly one); a transfer that ended before it was awaited posts
    none and the await returns at once."""
    server = make_server(net, bus_name)
    line = net.open_line(bus_name, mode="fd")
    server[DOMAIN].data = b"held"
    held = Recorder()
    hold = server.on_read(DOMAIN, lambda request: (held(request), request.defer())[1])
    transfer = line.usdo.start_upload(SERVER, DOMAIN, 0, timeout=scaled(10))
    request = held.wait_count(1)[0]

    async def main():
        asyncio.get_running_loop().call_later(scaled(0.1), request.accept)
        return await transfer

    assert asyncio.run(main()) == b"held"
    assert done_events == [transfer._handle]
    server.remove_indication(hold)
    early = line.usdo.start_upload(SERVER, DOMAIN, 0)
    while not early.done():
        time.sleep(0.001)

    async def late():
        return await early

    assert asyncio.run(late()) == b"held"
    time.sleep(scaled(0.05))
    assert done_events == [transfer._handle]


def test_an_await_and_a_blocking_wait_on_one_transfer_both_end(net, bus_name, done_events):
    """A transfer that ends while a thread waits for it in C posts no
    TRANSFER_DONE event; that thread tells the awaiting task. The server holds
    the upload (a deferred before-read) until the blocking wait has begun, so
    a loaded machine cannot end the transfer before anyone waits in C."""
    server = make_server(net, bus_name)
    line = net.open_line(bus_name, mode="fd")
    payload = os.urandom(64 << 10)
    server[DOMAIN].data = payload
    held = Recorder()
    server.on_read(DOMAIN, lambda request: (held(request), request.defer())[1])
    transfer = line.usdo.start_upload(SERVER, DOMAIN, 0, timeout=scaled(10))
    awaited, blocked = Recorder(), Recorder()

    async def main():
        awaited(await transfer)

    waiter = threading.Thread(target=lambda: asyncio.run(main()))
    waiter.start()
    blocking = threading.Thread(target=lambda: blocked(transfer.result()))
    blocking.start()
    request = held.wait_count(1)[0]
    time.sleep(scaled(0.3))                 # the blocking thread waits in C by now
    request.accept()
    blocking.join(scaled(10))
    waiter.join(scaled(10))
    assert blocked.snapshot() == [payload]
    assert awaited.snapshot() == [payload]
    assert done_events == []


def test_a_blocking_upload_from_a_callback_completes(net, bus_name):
    """Callbacks run on the dispatcher thread, which cannot also deliver the
    transfer's end: the blocking form polls the runtime instead."""
    line = net.open_line(bus_name, mode="fd")
    remote = line.add_node(SERVER)
    got = Recorder()

    def read_identity():
        try:
            got(remote.usdo.upload((0x1018, 1)))
        except Exception as exc:  # noqa: BLE001 - handed to the test
            got(exc)

    remote.on_bootup(read_identity)
    server = make_server(net, bus_name)
    assert got.wait_count(1, scaled(5))[0] == server[0x1018][1].data


@pytest.mark.parametrize("mode", ["segmented", "bulk"])
def test_a_download_announced_beyond_the_domain_is_refused_at_the_initiate(net, bus_name,
                                                                           mode):
    """CiA 301 0x06070012 (USDO 0x37) in answer to the initiate itself: no
    segment goes on the bus, and what fits is still taken."""
    server = make_server(net, bus_name, domain=1024)
    line = net.open_line(bus_name, mode="fd")
    frames = Recorder()
    net.open_line(bus_name, mode="fd", monitor=True).on_frame(frames)
    with pytest.raises(UsdoAbortError) as info:
        line.usdo.download(SERVER, DOMAIN, 0, bytes(2000), mode=mode)
    assert (info.value.usdo_code, info.value.code, info.value.from_server) == \
        (0x37, 0x06070012, True)
    aborts = frames.wait_for(lambda c: [f for f in c if f.data[1:2] == b"\x7f"] or None, 2,
                             "the abort")
    requests = usdo_frames(frames, 0x600 + CLIENT)
    assert len(requests) == 1                                # the initiate alone
    # [client, 0x7F abort, session, sub 0, index 0x2100 LE, 0x37 length too high]
    assert aborts[0].data[:7] == bytes([CLIENT, 0x7F, requests[0].data[2], 0, 0x00, 0x21, 0x37])
    line.usdo.download(SERVER, DOMAIN, 0, b"x" * 1024, mode=mode)
    assert server[DOMAIN].data == b"x" * 1024
