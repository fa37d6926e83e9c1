"""Process data and error services from Python: EMCY (producer on the local
node, consumer per remote node and per line), PDOs of the local node
(RPDO callbacks, TPDO transmit, synchronous TPDOs), SYNC, TIME and node
guarding. Everything runs over the in-process bus; the bytes on the bus are
checked through a monitor line."""

from __future__ import annotations

import datetime as dt
import itertools
import logging
import threading
import time

import pytest

import canopenfd
from canopenfd import ConfigurationError, NmtState, SdoAbortError
from canopenfd.services.emcy import Emcy
from canopenfd.od import DataType, ODArray, ODRecord, ODVariable, demo_od
from canopenfd.services import GuardEvent
from helpers import Recorder, scaled

NODE = 5
U8, U16, U32 = DataType.UNSIGNED8, DataType.UNSIGNED16, DataType.UNSIGNED32
_ids = itertools.count(1)


def pdo_od(mode):
    """The demo OD plus RPDO 1 / TPDO 1 (invalid predefined COB-IDs, type 255,
    8 mapping entries), as a device's EDS would describe them."""
    od = demo_od(mode)
    for kind, comm, mapping, base, subs in (("RPDO", 0x1400, 0x1600, 0x200, (1, 2, 5)),
                                            ("TPDO", 0x1800, 0x1A00, 0x180, (1, 2, 3, 5, 6))):
        record = ODRecord(f"{kind} communication parameter 1", comm)
        record.add_member(ODVariable("Highest sub-index supported", comm, 0, U8, "ro",
                                     max(subs)))
        names = {1: ("COB-ID used by PDO", U32), 2: ("Transmission type", U8),
                 3: ("Inhibit time", U16), 5: ("Event timer", U16),
                 6: ("SYNC start value", U8)}
        for sub in subs:
            name, dtype = names[sub]
            var = ODVariable(name, comm, sub, dtype, "rw", 0)
            if sub == 1:
                var.set_default(0x80000000 + base, relative_to_node_id=True)
            elif sub == 2:
                var.default = 255
            record.add_member(var)
        od.add_object(record)
        array = ODArray(f"{kind} mapping parameter 1", mapping)
        array.add_member(ODVariable("Number of mapped objects", mapping, 0, U8, "rw", 0))
        for sub in range(1, 9):
            array.add_member(ODVariable(f"Mapped object {sub}", mapping, sub, U32, "rw", 0))
        od.add_object(array)
    return od


@pytest.fixture(params=["classic", "fd"])
def mode(request):
    return request.param


class Rig:
    """Our node 5 (line `a`), a tool line `b` on the same bus, a monitor."""

    def __init__(self, net, bus, mode, od=True, **node_args):
        self.net, self.bus, self.mode = net, bus, mode
        self.a = net.open_line(bus, mode=mode)
        self.me = self.a.create_local_node(NODE, od=pdo_od(mode) if od else None, **node_args)
        self.b = net.open_line(bus, mode=mode)
        self.frames = Recorder()
        net.open_line(bus, mode=mode, monitor=True).on_frame(self.frames)

    def wait_frames(self, can_id, count, timeout=2.0, start=0, rtr=None):
        def enough(calls):
            got = [f for f in calls[start:] if f.id == can_id and (rtr is None or f.rtr == rtr)]
            return got if len(got) >= count else None
        return self.frames.wait_for(enough, timeout, f"{count} frames 0x{can_id:X}")

    def mark(self):
        return len(self.frames)


@pytest.fixture
def rig(net, bus_name, mode):
    return Rig(net, bus_name, mode)


# ------------------------------------------------------------------ EMCY
def test_emcy_classic_every_field_exact_bytes_and_reset(net, bus_name):
    rig = Rig(net, bus_name, "classic")
    remote = rig.b.add_node(NODE)
    got, on_line = Recorder(), Recorder()
    remote.emcy.add_callback(got)
    rig.b.on_emcy(on_line)
    me = rig.me
    assert me.emcy.raise_error(0x2310, b"\x01\x02", register_bits=0x80) is True
    assert me.emcy.raise_error(0x2310, b"\x01\x02") is False      # active: nothing sent
    assert me.emcy.raise_error(0x3210) is True
    assert (me.emcy.error_register, me.emcy.active) == (0x87, 2)
    sent = rig.wait_frames(0x80 + NODE, 2)
    # code LE, error register (generic + current + manufacturer), 5 bytes msef
    assert [f.data.hex(" ") for f in sent] == ["10 23 83 01 02 00 00 00",
                                               "10 32 87 00 00 00 00 00"]
    assert not sent[0].fd
    first, second = got.wait_count(2)[:2]
    assert isinstance(first, Emcy) and canopenfd.Emcy is Emcy
    assert (first.node, first.code, first.register, first.data, first.fd) == \
        (NODE, 0x2310, 0x83, b"\x01\x02\x00\x00\x00", False)
    assert first.occurred and not first.is_reset and not first.removed
    assert (first.logical_device, first.spec_number, first.priority, first.time_stamp) == \
        (0, 0, 0, 0)
    assert first.text.startswith("0x2310 current") and second.code == 0x3210
    assert remote.emcy.active == [0x2310, 0x3210]
    assert me.emcy.clear(0x2310) is True
    assert me.emcy.clear(0x2310) is False                          # no longer active
    reset = rig.wait_frames(0x80 + NODE, 3)[2]
    assert reset.data.hex(" ") == "00 00 05 00 00 00 00 00"      # reset, 0x3210 still active
    third = got.wait_count(3)[2]
    assert third.is_reset and third.removed and third.register == 0x05
    assert third.text == "error reset"
    assert remote.emcy.active == []          # a classic reset does not say which went away
    assert [e.code for e in remote.emcy.log] == [0x2310, 0x3210, 0]
    assert on_line.wait_count(3) == got.snapshot()
    assert (me.emcy.error_register, me.emcy.active) == (0x05, 1)


def test_emcy_history_0x1003_newest_first_and_cleared_over_the_network(net, bus_name):
    """me.emcy.history reads 0x1003 as the producer keeps it (code | msef[0..1]
    << 16, newest first, at most the entries the OD has); a network write of 0
    to 0x1003:00 clears it, anything else is refused."""
    od = pdo_od("classic")
    history = ODArray("Pre-defined error field", 0x1003)
    history.add_member(ODVariable("Number of errors", 0x1003, 0, U8, "rw", 0))
    for sub in range(1, 4):
        history.add_member(ODVariable(f"Standard error field {sub}", 0x1003, sub, U32, "ro", 0))
    od.add_object(history)
    a = net.open_line(bus_name, mode="classic")
    me = a.create_local_node(NODE, od=od)
    tool = net.open_line(bus_name, mode="classic").add_node(NODE)
    assert me.emcy.history == []
    me.emcy.raise_error(0x2310, b"\x01\x02")
    me.emcy.raise_error(0x3210)
    me.emcy.clear(0x2310)                      # clearing adds nothing to the history
    assert me.emcy.history == [0x3210, 0x02012310]
    for code in (0x4210, 0x5000):
        me.emcy.raise_error(code, b"\xAA")
    assert me.emcy.history == [0x00AA5000, 0x00AA4210, 0x3210]   # three entries in this OD
    assert tool.sdo.upload((0x1003, 1)) == (0x00AA5000).to_bytes(4, "little")
    with pytest.raises(SdoAbortError) as caught:
        tool.sdo.download((0x1003, 0), b"\x02")
    assert caught.value.code == 0x06090030
    tool.sdo.download((0x1003, 0), b"\x00")
    assert me.emcy.history == []
    bare = net.open_line(bus_name, mode="classic").create_local_node(NODE + 1)   # no OD
    assert bare.od is None and bare.emcy.history == []


def test_emcy_fd_every_field_repeated_and_removal(net, bus_name):
    rig = Rig(net, bus_name, "fd")
    remote = rig.b.add_node(NODE)
    got = Recorder()
    remote.emcy.add_callback(got)
    fields = dict(register_bits=0x80, logical_device=2, spec_number=0x012D, priority=3,
                  non_recoverable=True, time_stamp=0x123456789A)
    assert rig.me.emcy.raise_error(0x2310, b"\x01\x02\x03\x04\x05", **fields) is True
    assert rig.me.emcy.raise_error(0x2310, b"\x01\x02\x03\x04\x05", **fields) is False
    sent = rig.wait_frames(0x80 + NODE, 2)
    assert sent[0].fd and len(sent[0].data) == 20
    # 0-7 classic part, 8 logical device, 9-10 spec, 11 status, 12-17 time stamp, 18-19 0
    assert sent[0].data.hex(" ") == ("10 23 83 01 02 03 04 05 02 2d 01 1b "
                                     "9a 78 56 34 12 00 00 00")
    assert sent[1].data[11] == 0x3B                                   # + repeated
    emcy = got.wait_count(1)[0]
    assert (emcy.node, emcy.code, emcy.register, emcy.data, emcy.logical_device,
            emcy.spec_number, emcy.priority, emcy.non_recoverable, emcy.occurred,
            emcy.repeated, emcy.time_stamp, emcy.fd) == \
        (NODE, 0x2310, 0x83, b"\x01\x02\x03\x04\x05", 2, 0x12D, 3, True, True, False,
         0x123456789A, True)
    assert got.wait_count(2)[1].repeated
    assert remote.emcy.active == [0x2310]
    assert rig.me.emcy.clear(0x2310) is False           # logical device 0: not that error
    assert rig.me.emcy.clear(0x2310, logical_device=2, time_stamp=7) is True
    removal = rig.wait_frames(0x80 + NODE, 3)[2]
    assert removal.data.hex(" ") == ("10 23 00 00 00 00 00 00 02 2d 01 0b "
                                     "07 00 00 00 00 00 00 00")
    gone = got.wait_count(3)[2]
    assert gone.removed and not gone.occurred and not gone.is_reset
    assert remote.emcy.active == [] and rig.me.emcy.error_register == 0


def test_emcy_wait_returns_the_matching_emcy(net, bus_name):
    rig = Rig(net, bus_name, "fd", od=False)
    remote = rig.b.add_node(NODE)
    assert not remote.emcy.log          # the first use: consumed from now on
    timer = threading.Timer(0.05, lambda: (rig.me.emcy.raise_error(0x1000),
                                           rig.me.emcy.raise_error(0x5000)))
    timer.start()
    try:
        emcy = remote.emcy.wait(0x5000, timeout=scaled(2))
    finally:
        timer.join()
    assert emcy.code == 0x5000 and emcy.register & 0x01
    with pytest.raises(TimeoutError, match="EMCY 0x6000"):
        remote.emcy.wait(0x6000, timeout=0.05)


def test_heartbeat_lost_raises_emcy_8130_from_the_local_node(net, bus_name):
    rig = Rig(net, bus_name, "classic")
    other = net.open_line(bus_name, mode="classic").create_local_node(7, heartbeat_ms=10)
    got = Recorder()
    rig.b.add_node(NODE).emcy.add_callback(got)
    rig.me[0x1016][1].raw = 7 << 16 | 60               # consume node 7, 60 ms
    start = rig.mark()
    rig.wait_frames(0x707, 3, start=start)              # monitoring has begun
    other.heartbeat_ms = 0                              # node 7 falls silent
    emcy = got.wait_for(lambda calls: [e for e in calls if e.code == 0x8130], 2.0,
                        "EMCY 0x8130")[0]
    assert emcy.node == NODE and emcy.register & 0x11 == 0x11    # generic + communication
    assert "heartbeat" in emcy.text
    frame = rig.wait_frames(0x80 + NODE, 1)[0]
    assert frame.data[:3] == bytes([0x30, 0x81, emcy.register])


def test_emcy_wrong_use_is_refused_with_node_and_code(net, bus_name):
    line = net.open_line(bus_name, mode="classic")
    me = line.create_local_node(NODE, boot=False)
    with pytest.raises(ConfigurationError, match="0x1000 on local node 5.*not booted"):
        me.emcy.raise_error(0x1000)
    me.boot()
    cases = [((0,), {}, "code must be an int 1"),
             ((0x10000,), {}, "code must be"),
             ((0x2310, b"123456"), {}, "0x2310 .*data .*0..5"),
             ((0x2310,), {"priority": 3}, "0x2310 .*priority exist only in the CANopen FD"),
             ((0x2310,), {"register_bits": 256}, "register_bits"),
             ((0x2310, "text"), {}, "must be bytes")]
    for args, kwargs, pattern in cases:
        with pytest.raises(ConfigurationError, match=pattern):
            me.emcy.raise_error(*args, **kwargs)
    fd = net.open_line(bus_name + "-fd", mode="fd").create_local_node(NODE)
    with pytest.raises(ValueError, match="0x2310 on local node 5 .*priority must be"):
        fd.emcy.raise_error(0x2310, priority=8)
    with pytest.raises(ValueError, match="time_stamp"):
        fd.emcy.raise_error(0x2310, time_stamp=1 << 48)
    with pytest.raises(ConfigurationError, match="node-id"):
        line.on_emcy(print, nodes=[0])


# ------------------------------------------------------------------ PDOs
def _configure(me):
    tpdo = me.tpdo[1]
    tpdo.read()
    tpdo.clear()
    tpdo.add_variable("Demo UNSIGNED16")
    tpdo.add_variable("Demo record.Setpoint")
    tpdo.cob_id = 0x180 + NODE
    tpdo.enabled = True
    return tpdo


def test_rpdo_callback_gets_the_decoded_values(rig):
    rpdo = rig.me.rpdo[1]
    rpdo.read()
    rpdo.clear()
    rpdo.add_variable("Demo record.Setpoint")           # INTEGER16
    rpdo.add_variable("Demo UNSIGNED16")
    rpdo.add_variable("Demo UNSIGNED32")
    rpdo.cob_id = 0x200 + NODE
    rpdo.enabled = True
    rpdo.save()
    got = Recorder()
    rig.me.rpdo[1].add_callback(
        lambda pdo: got((pdo["Demo record.Setpoint"].raw, [v.raw for v in pdo],
                         bytes(pdo.data), pdo is rpdo)))
    rig.me.apply("start")
    payload = bytes.fromhex("feff3412785634 12".replace(" ", ""))
    rig.b.send_frame(0x200 + NODE, payload)
    assert got.wait_count(1)[0] == (-2, [-2, 0x1234, 0x12345678], payload, True)
    assert rig.me["Demo UNSIGNED32"].raw == 0x12345678
    timer = threading.Timer(0.05, rig.b.send_frame, (0x200 + NODE, bytes(8)))
    timer.start()
    try:
        when = rpdo.wait_for_reception(timeout=scaled(2))
    finally:
        timer.join()
    assert abs(when - time.time()) < scaled(2) and [v.raw for v in rpdo] == [0, 0, 0]


def test_tpdo_transmit_and_trigger_put_the_exact_bytes_on_the_bus(rig):
    tpdo = _configure(rig.me)
    tpdo.trans_type = 254
    tpdo.save()
    rig.me["Demo UNSIGNED16"].raw = 5000
    rig.me["Demo record.Setpoint"].raw = -3
    with pytest.raises(ConfigurationError, match="TPDO1.*not operational"):
        tpdo.transmit()
    rig.me.apply("start")
    rig.me.wait_for_state("OPERATIONAL")
    start = rig.mark()
    tpdo.transmit()
    frame = rig.wait_frames(0x180 + NODE, 1, start=start)[-1]
    expected = bytes.fromhex("8813fdff")
    assert frame.data[:4] == expected and frame.fd == (rig.mode == "fd")
    assert len(frame.data) == 4                          # 4 bytes is a valid FD length too
    rig.me["Demo UNSIGNED16"].raw = 0x0102
    start = rig.mark()
    assert rig.me.trigger_pdo("Demo UNSIGNED16") == 1
    assert rig.wait_frames(0x180 + NODE, 1, start=start)[-1].data == bytes.fromhex("0201fdff")
    assert rig.me.trigger_pdo("Demo UNSIGNED32") == 0     # mapped nowhere


def test_remote_tpdo_and_rpdo_callbacks_hear_another_nodes_pdos(net, bus_name, rig):
    """Line b hears node 5's TPDO (configuration read from the node) and the
    RPDO others send to node 5 (which node 5's own RPDO still applies)."""
    tpdo = _configure(rig.me)
    tpdo.trans_type = 254
    tpdo.save()
    rpdo = rig.me.rpdo[1]
    rpdo.read()
    rpdo.clear()
    rpdo.add_variable("Demo UNSIGNED32")
    rpdo.add_variable("Demo record.Setpoint")
    rpdo.cob_id = 0x200 + NODE
    rpdo.enabled = True
    rpdo.save()
    rig.me.apply("start")
    rig.me.wait_for_state("OPERATIONAL")
    remote = rig.b.add_node(NODE, od=pdo_od(rig.mode))
    remote.tpdo.read()                                   # over SDO / USDO from node 5
    remote.rpdo.read()
    heard, sent_to = Recorder(), Recorder()
    remote.tpdo[1].add_callback(lambda pdo: heard(([v.raw for v in pdo], bytes(pdo.data),
                                                   pdo["Demo UNSIGNED16"].raw)))
    remote.rpdo[1].add_callback(lambda pdo: sent_to([v.raw for v in pdo]))
    rig.me["Demo UNSIGNED16"].raw = 4660
    rig.me["Demo record.Setpoint"].raw = -300
    tpdo.transmit()
    assert heard.wait_count(1)[0] == ([4660, -300], bytes.fromhex("3412d4fe"), 4660)
    other = net.open_line(bus_name, mode=rig.mode)      # a third party writes node 5's RPDO
    other.send_frame(0x200 + NODE, bytes.fromhex("78563412 feff"))
    assert sent_to.wait_count(1)[0] == [0x12345678, -2]
    deadline = time.monotonic() + scaled(2)
    while rig.me["Demo record.Setpoint"].raw != -2 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert rig.me["Demo record.Setpoint"].raw == -2      # the local RPDO still got it
    # wait_for_reception, period; too short frames are not delivered
    remote_tpdo = remote.tpdo[1]
    timer = threading.Timer(0.05, tpdo.transmit)
    timer.start()
    try:
        when = remote_tpdo.wait_for_reception(timeout=scaled(2))
    finally:
        timer.join()
    assert abs(when - time.time()) < scaled(2) and remote_tpdo.period is not None
    other.send_frame(0x180 + NODE, b"\x01")
    other.send_frame(0x180 + NODE, bytes.fromhex("01020304"))
    assert heard.wait_count(3)[2][0] == [0x0201, 0x0403]
    assert remote_tpdo.short_frames == 1
    # the last callback removed: the CAN-ID is no longer watched
    for maps in (remote.tpdo, remote.rpdo):
        for callback in list(maps[1]._callbacks._callbacks):
            maps[1].remove_callback(callback)
    assert rig.b._pdo_watches == {}
    other.send_frame(0x180 + NODE, bytes.fromhex("05060708"))
    rig.wait_frames(0x180 + NODE, 5)
    time.sleep(scaled(0.05))
    assert len(heard) == 3


def test_remote_pdo_from_od_defaults_29_bit_and_remove_node(net, bus_name, mode):
    """Without read(): the OD's COB-ID ($NODEID) and mapping; a COB-ID set
    later is followed (29-bit here); remove_node stops hearing."""
    line = net.open_line(bus_name, mode=mode)
    sender = net.open_line(bus_name, mode=mode)
    remote = line.add_node(NODE, od=pdo_od(mode))
    raw = Recorder()
    remote.tpdo[1].add_callback(lambda pdo: raw(bytes(pdo.data)))
    assert remote.tpdo[1].cob_id == 0x180 + NODE and not remote.tpdo[1].enabled
    sender.send_frame(0x180 + NODE, b"\xaa\xbb")
    assert raw.wait_count(1)[0] == b"\xaa\xbb"           # nothing mapped: the whole frame
    remote.tpdo[1].extended = True
    remote.tpdo[1].cob_id = 0x1234567
    assert list(line._pdo_watches) == [0x1234567 | (1 << 29)]
    sender.send_frame(0x180 + NODE, b"\x01")                # not heard any more
    sender.send_frame(0x1234567, b"\x11\x22\x33", extended=True)
    assert raw.wait_count(2)[1] == b"\x11\x22\x33"
    second = Recorder()
    twin = net.open_line(bus_name, mode=mode).add_node(NODE, od=pdo_od(mode))
    twin.tpdo[1].add_variable("Demo UNSIGNED8")          # a mapping made here, COB-ID from the OD
    twin.tpdo[1].add_callback(lambda pdo: second(pdo["Demo UNSIGNED8"].raw))
    sender.send_frame(0x180 + NODE, b"\x2a\x00")
    assert second.wait_count(1)[0] == 0x2A
    line.remove_node(NODE)
    assert line._pdo_watches == {}
    sender.send_frame(0x1234567, b"\x44", extended=True)
    sender.send_frame(0x180 + NODE, b"\x2b")
    assert second.wait_count(2)[1] == 0x2B
    assert len(raw) == 2


def test_remote_pdo_wait_alone_watches_only_while_waiting(net, bus_name):
    line = net.open_line(bus_name, mode="fd")
    sender = net.open_line(bus_name, mode="fd")
    pdo = line.add_node(NODE, od=pdo_od("fd")).rpdo[1]
    with pytest.raises(TimeoutError, match="node 5 RPDO1: wait_for_reception"):
        pdo.wait_for_reception(timeout=0.05)
    assert line._pdo_watches == {}
    timer = threading.Timer(0.05, sender.send_frame, (0x200 + NODE, b"\x07" * 12))
    timer.start()
    try:
        pdo.wait_for_reception(timeout=scaled(2))
    finally:
        timer.join()
    assert bytes(pdo.data) == b"\x07" * 12 and line._pdo_watches == {}


def test_sync_producer_counter_and_synchronous_tpdo_only_in_operational(rig):
    tpdo = _configure(rig.me)
    tpdo.trans_type = 1                                  # every SYNC
    tpdo.save()
    rig.me["Demo UNSIGNED16"].raw = 0x1234
    counters = Recorder()
    rig.a.sync.add_callback(counters)                    # our own SYNCs too
    start = rig.mark()
    rig.a.sync.start(0.01, overflow=4)                   # our node's line produces
    assert rig.a.sync.period == 0.01
    syncs = rig.wait_frames(0x80, 6, start=start)
    assert [f.data for f in syncs[:6]] == [bytes([n]) for n in (1, 2, 3, 4, 1, 2)]
    assert not [f for f in rig.frames.snapshot()[start:] if f.id == 0x180 + NODE]  # pre-op
    rig.me.apply("start")
    rig.me.wait_for_state("OPERATIONAL")
    start = rig.mark()
    pdos = rig.wait_frames(0x180 + NODE, 4, start=start)
    assert all(f.data == bytes.fromhex("34120000") for f in pdos)
    seen = rig.frames.snapshot()[start:]
    for pdo in pdos[:3]:                                 # each follows a SYNC
        before = [f for f in seen[:seen.index(pdo)] if f.id in (0x80, 0x180 + NODE)]
        assert before and before[-1].id == 0x80
    # about one SYNC per 10 ms (generous window for loaded machines)
    later = rig.wait_frames(0x80, 20, start=start)
    span = later[19].timestamp - later[0].timestamp
    assert 0.12 <= span <= scaled(1.0), span
    values = counters.wait_count(8)
    assert {(b - a) % 4 for a, b in zip(values, values[1:8])} == {1}
    assert set(values) <= {1, 2, 3, 4}
    rig.a.sync.stop()
    assert rig.a.sync.period is None


def test_sync_with_a_counter_the_node_does_not_expect_is_emcy_8240(rig):
    """CiA 301: a SYNC whose length does not match the consumer's 0x1019
    (here none: no counter expected) is not taken and raises EMCY 0x8240."""
    tpdo = _configure(rig.me)
    tpdo.trans_type = 1
    tpdo.save()
    rig.me.apply("start")
    rig.me.wait_for_state("OPERATIONAL")
    got = Recorder()
    rig.b.add_node(NODE).emcy.add_callback(got)
    start = rig.mark()
    rig.b.sync.start(0.01, overflow=4)
    assert got.wait_count(1)[0].code == 0x8240
    rig.wait_frames(0x80, 5, start=start)
    assert not [f for f in rig.frames.snapshot()[start:] if f.id == 0x180 + NODE]
    rig.b.sync.stop()


def test_sync_without_counter_and_start_none_stops(net, bus_name):
    rig = Rig(net, bus_name, "classic", od=False)
    counters = Recorder()
    rig.b.sync.add_callback(counters)
    start = rig.mark()
    rig.b.sync.start(0.005)
    assert all(f.data == b"" for f in rig.wait_frames(0x80, 3, start=start))
    assert counters.wait_count(3)[:3] == [0, 0, 0]
    rig.b.sync.start(None)
    assert rig.b.sync.period is None


def test_time_transmit_exact_bytes_and_callback_datetime(rig):
    got = Recorder()
    rig.a.time.add_callback(got)
    when = dt.datetime(2024, 5, 6, 7, 8, 9, 123000, tzinfo=dt.timezone.utc)
    rig.b.time.transmit(when)
    ms = (7 * 3600 + 8 * 60 + 9) * 1000 + 123
    days = (dt.date(2024, 5, 6) - dt.date(1984, 1, 1)).days
    frame = rig.wait_frames(0x100, 1)[0]
    assert frame.data[:6] == ms.to_bytes(4, "little") + days.to_bytes(2, "little")
    assert len(frame.data) == 6                          # 6 is a valid FD length too
    assert got.wait_count(1)[0] == when
    rig.b.time.transmit(when.timestamp() + 1.5)            # float seconds
    assert got.wait_count(2)[1] == when + dt.timedelta(seconds=1.5)
    before = dt.datetime.now(dt.timezone.utc)
    rig.b.time.transmit()                                  # now
    now = got.wait_count(3)[2]
    assert before - dt.timedelta(seconds=1) <= now <= before + dt.timedelta(seconds=scaled(5))


# ------------------------------------------------------------------ guarding
def test_guarding_rtr_toggle_started_and_lost(net, bus_name):
    rig = Rig(net, bus_name, "classic")                 # our node 5 answers (0x1017 = 0)
    guarded = rig.b.add_node(NODE)
    events, lost = Recorder(), Recorder()
    guarded.add_guard_callback(events)
    guarded.guard(10, 3)
    events.wait_for(lambda calls: (GuardEvent.STARTED, NmtState.PRE_OPERATIONAL) in calls,
                    2.0, "STARTED")
    assert "started" in [event for event, _ in events.snapshot()]
    requests = rig.wait_frames(0x700 + NODE, 3, rtr=True)
    assert all(f.rtr and f.rtr_len == 1 for f in requests)
    first = rig.frames.snapshot().index(requests[0])
    answers = rig.wait_frames(0x700 + NODE, 4, start=first, rtr=False)   # not the boot-up
    # state 0x7F (pre-operational) with the toggle bit alternating from 0
    assert [f.data for f in answers[:4]] == [b"\x7f", b"\xff", b"\x7f", b"\xff"]
    guarded.unguard()
    absent = rig.b.add_node(9)
    absent.on_heartbeat_lost(lost)
    absent.add_guard_callback(events)
    absent.guard(10, 2)
    events.wait_for(lambda calls: [c for c in calls if c[0] == GuardEvent.LOST], 2.0, "LOST")
    lost.wait_count(1)
    assert rig.wait_frames(0x709, 2, rtr=True)
    assert absent.heartbeat_alive is False
    # node 9 appears (a node with an OD answers guarding while its 0x1017 is 0)
    net.open_line(bus_name, mode="classic").create_local_node(9, od=demo_od("classic"))
    events.wait_for(lambda calls: (GuardEvent.RESUMED, NmtState.PRE_OPERATIONAL) in calls,
                    2.0, "RESUMED")
    assert absent.heartbeat_alive is True
    rig.b.remove_node(9)                                # stops guarding it
    start = rig.mark()
    rig.b.send_frame(0x123, b"marker")
    rig.wait_frames(0x123, 1, start=start)
    time.sleep(scaled(0.05))                            # five guard times: no request
    after = rig.frames.snapshot()[start:]
    after = after[after.index(next(f for f in after if f.id == 0x123)):]
    assert not [f for f in after if f.id == 0x709 and f.rtr]


def test_guarding_wrong_use(net, bus_name):
    fd = net.open_line(bus_name, mode="fd").add_node(NODE)
    with pytest.raises(ConfigurationError, match="classic line"):
        fd.guard(100, 3)
    classic = net.open_line(bus_name + "-c", mode="classic").add_node(NODE)
    with pytest.raises(ConfigurationError, match="life_time_factor"):
        classic.guard(100, 0)
    with pytest.raises(ConfigurationError, match="guard_time_ms"):
        classic.guard(0, 3)


# ------------------------------------------------------------------ wrong use
def test_wrong_use_of_sync_time_and_pdos(rig):
    with pytest.raises(ConfigurationError, match="period"):
        rig.b.sync.start(0)
    with pytest.raises(ConfigurationError, match="period"):
        rig.b.sync.start("fast")
    with pytest.raises(ConfigurationError, match="overflow must be 0 .*or 2..240"):
        rig.b.sync.start(0.1, overflow=1)
    with pytest.raises(ConfigurationError, match="timestamp must be"):
        rig.b.time.transmit("now")
    with pytest.raises(ConfigurationError, match="1984"):
        rig.b.time.transmit(dt.datetime(1980, 1, 1, tzinfo=dt.timezone.utc))
    with pytest.raises(ConfigurationError, match="is a TPDO"):
        rig.me.tpdo[1].add_callback(print)
    with pytest.raises(ConfigurationError, match="for TPDOs"):
        rig.me.rpdo[1].transmit()
    with pytest.raises(ConfigurationError, match="not valid"):
        rig.me.apply("start")
        rig.me.wait_for_state("OPERATIONAL")
        rig.me.tpdo[1].transmit()                        # COB-ID still invalid
    remote = rig.b.add_node(NODE, od=pdo_od(rig.mode))
    remote.tpdo[1].cob_id = 0x800                        # 12 bits, not extended
    with pytest.raises(ConfigurationError, match="not an 11-bit CAN-ID"):
        remote.tpdo[1].add_callback(print)
    with pytest.raises(ConfigurationError, match="local node's TPDOs"):
        remote.tpdo[1].transmit()
    with pytest.raises(ConfigurationError, match="not a single entry"):
        rig.me.trigger_pdo(0x2200)
    with pytest.raises(KeyError):
        rig.me.trigger_pdo("No such entry")


def test_a_line_without_local_node_hears_sync_with_and_without_counter(net, bus_name):
    producer = net.open_line(bus_name, mode="fd")
    tool = net.open_line(bus_name, mode="fd")
    got = Recorder()
    tool.sync.add_callback(got)
    producer.sync.start(0.01, overflow=4)
    try:
        counters = got.wait_count(3)
    finally:
        producer.sync.stop()
    assert all(1 <= c <= 4 for c in counters[:3]), counters
    assert tool.service_stats["sync"]["bad_length"] == 0


def test_guarding_a_node_that_sends_heartbeats_warns(net, bus_name, caplog):
    """A device whose heartbeat producer runs does not answer guarding (CiA
    301: one error control method): guard() says so instead of leaving the
    user with false losses; a node not heard heartbeating gives no warning."""
    line = net.open_line(bus_name, mode="classic")
    beating = line.add_node(NODE)
    net.open_line(bus_name, mode="classic").create_local_node(NODE, 20, od=demo_od("classic"))
    beating.wait_for_heartbeat(scaled(5))
    quiet = line.add_node(9)
    with caplog.at_level(logging.WARNING):
        quiet.guard(100, 3)
        assert not [r for r in caplog.records if "heartbeat" in r.getMessage()]
        beating.guard(100, 3)
        warned = [r.getMessage() for r in caplog.records if "heartbeat" in r.getMessage()]
    assert len(warned) == 1 and f"node {NODE} sends heartbeats" in warned[0], warned
    assert "false losses" in warned[0]
    watched = line.add_node(11, heartbeat_timeout_ms=500)
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        watched.guard(100, 3)
    assert any("node 11 is watched for heartbeats" in r.getMessage() for r in caplog.records)
