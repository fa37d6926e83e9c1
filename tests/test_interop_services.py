"""TIME, node/life guarding and RTR PDOs (transmission types 252 and 253)
against python-canopen (PyPI `canopen`) on the classic vcan, with every
frame checked on the wire through a raw python-can socket. Needs
CANOPENFD_VCAN (see tests/test_vcan.py); tests/vm/run_in_vm.sh provides it."""

from __future__ import annotations

import datetime as dt
import time

import pytest
from helpers import Recorder, scaled
from test_services import pdo_od
from test_vcan_services import NODE, classic, eds, ifaces, map_pdo, networks, peer, start

from canopenfd import NmtState
from canopenfd.od import DataType, ODVariable

pytestmark = pytest.mark.vcan
can = pytest.importorskip("can")
canopen = pytest.importorskip("canopen")

__all__ = ["classic", "eds", "ifaces", "networks", "peer"]   # fixtures used here

UTC = dt.timezone.utc
EPOCH = dt.date(1984, 1, 1)
GUARD = 0x700 + NODE
EMCY = 0x80 + NODE
TPDO = 0x180 + NODE


class RawLog:
    """Every frame of a raw classic socket, recorded by a python-can Notifier
    (the kernel's receive time stamps in msg.timestamp)."""

    def __init__(self, channel: str) -> None:
        self.bus = can.Bus(interface="socketcan", channel=channel, fd=False)
        self.frames = Recorder()
        self.notifier = can.Notifier(self.bus, [self.frames], timeout=0.05)

    def close(self) -> None:
        self.notifier.stop()
        self.bus.shutdown()

    def mark(self) -> int:
        return len(self.frames)

    def select(self, can_id: int, start: int = 0, rtr=None) -> list:
        return [m for m in self.frames.snapshot()[start:]
                if m.arbitration_id == can_id and not m.is_error_frame
                and (rtr is None or m.is_remote_frame == rtr)]

    def wait(self, can_id: int, count: int, start: int = 0, rtr=None, timeout: float = 5.0):
        """The first `count` frames with can_id (data, remote or both) from `start`."""
        def enough(_calls):
            got = self.select(can_id, start, rtr)
            return got[:count] if len(got) >= count else None
        return self.frames.wait_for(enough, timeout, f"{count} frames 0x{can_id:X} (rtr={rtr})")


@pytest.fixture
def raw(ifaces):
    log = RawLog(ifaces["classic"])
    yield log
    log.close()


def wait_until(predicate, timeout: float = 5.0, what: str = "condition"):
    """Poll `predicate` (for counters the stack has no event for)."""
    deadline = time.monotonic() + scaled(timeout)
    while True:
        value = predicate()
        if value:
            return value
        assert time.monotonic() < deadline, f"timed out after {scaled(timeout):g} s: {what}"
        time.sleep(0.01)


def time_of_day_bytes(when: dt.datetime) -> bytes:
    """CiA 301 TIME_OF_DAY by hand: ms after midnight (28 bits LE, upper 4
    bits of byte 3 reserved = 0), then days since 1984-01-01 (U16 LE)."""
    when = when.astimezone(UTC)
    ms = ((when.hour * 60 + when.minute) * 60 + when.second) * 1000 + when.microsecond // 1000
    days = (when.date() - EPOCH).days
    return ms.to_bytes(4, "little") + days.to_bytes(2, "little")


def decode_time_of_day(data: bytes) -> tuple:
    raw_ms = int.from_bytes(data[0:4], "little")
    assert raw_ms >> 28 == 0, f"reserved bits 28..31 set: {data.hex(' ')}"
    return raw_ms, int.from_bytes(data[4:6], "little")


# ------------------------------------------------------------------ TIME
def test_python_canopen_time_producer_reaches_our_time_callback(classic, peer, raw):
    """python-canopen's network.time.transmit(unix seconds) -> our line's
    callback gets the same datetime (to the ms); the frame is checked too."""
    got = Recorder()
    classic.time.add_callback(got)
    # .375 / .875 s are exact binary fractions: python-canopen truncates
    # seconds * 1000 to int, so an inexact fraction could lose a ms on its side.
    stamps = [dt.datetime(2024, 2, 29, 23, 59, 58, 375000, tzinfo=UTC),
              dt.datetime(1984, 1, 1, 0, 0, 0, 0, tzinfo=UTC),        # day 0, ms 0
              dt.datetime(2031, 7, 4, 12, 34, 56, 875000, tzinfo=UTC)]
    for n, when in enumerate(stamps, 1):
        peer.time.transmit(when.timestamp())
        frame = raw.wait(0x100, n)[-1]
        assert bytes(frame.data) == time_of_day_bytes(when) and not frame.is_remote_frame
        assert got.wait_count(n)[n - 1] == when
    assert all(w.tzinfo is not None and w.utcoffset() == dt.timedelta(0)
               for w in got.snapshot())
    assert classic.service_stats["time"]["received"] == len(stamps)


def test_our_time_transmit_exact_bytes_on_the_wire(classic, raw):
    """line.time.transmit(datetime) -> the 6 bytes CiA 301 defines, decoded by hand."""
    cases = [
        # (sent, the ms-exact time the frame must carry)
        (dt.datetime(2024, 5, 6, 7, 8, 9, 123000, tzinfo=UTC), None),
        (dt.datetime(2024, 12, 31, 23, 59, 59, 999999, tzinfo=UTC),     # sub-ms truncated
         dt.datetime(2024, 12, 31, 23, 59, 59, 999000, tzinfo=UTC)),
        (dt.datetime(1984, 1, 1, tzinfo=UTC), None),                      # day 0, ms 0
        (dt.datetime(2100, 3, 1, 0, 0, 0, 1000, tzinfo=UTC), None),       # after 2100-02-28
        # another time zone: the frame carries UTC (14:30:15.5 +02:00 = 12:30:15.5 UTC)
        (dt.datetime(2020, 6, 1, 14, 30, 15, 500000,
                     tzinfo=dt.timezone(dt.timedelta(hours=2))),
         dt.datetime(2020, 6, 1, 12, 30, 15, 500000, tzinfo=UTC)),
    ]
    for n, (sent, expected) in enumerate(cases, 1):
        expected = expected or sent
        classic.time.transmit(sent)
        frame = raw.wait(0x100, n)[-1]
        assert len(frame.data) == 6 and not frame.is_remote_frame and not frame.is_fd
        ms, days = decode_time_of_day(bytes(frame.data))
        utc = expected.astimezone(UTC)
        assert days == (utc.date() - EPOCH).days, (sent, bytes(frame.data).hex(" "))
        assert ms == ((utc.hour * 60 + utc.minute) * 60 + utc.second) * 1000 + \
            utc.microsecond // 1000, (sent, bytes(frame.data).hex(" "))
        assert bytes(frame.data) == time_of_day_bytes(expected)
    # spot check against literal bytes: 2024-05-06 07:08:09.123 = ms 25 689 123
    # (0x0187FC23), day 14 736 (0x3990)
    assert bytes(raw.select(0x100)[0].data).hex(" ") == "23 fc 87 01 90 39"


# ------------------------------------------------------------------ node guarding
def guarded_od(guard_time_ms: int, life_time_factor: int):
    """pdo_od('classic') plus guard time 0x100C and life time factor 0x100D
    (0x1017 stays 0: node guarding, not heartbeat)."""
    od = pdo_od("classic")
    od.add_object(ODVariable("Guard time", 0x100C, 0, DataType.UNSIGNED16, "rw",
                             guard_time_ms))
    od.add_object(ODVariable("Life time factor", 0x100D, 0, DataType.UNSIGNED8, "rw",
                             life_time_factor))
    return od


def guard_answers(raw: RawLog, start: int = 0) -> list:
    """The guarding answers (1-byte data frames on 0x700 + NODE, boot-ups
    0x00 left out) at positions >= `start` of the raw log; the whole log is
    checked to go RTR, answer, RTR, answer, ... (a boot-up queued before an
    answer may follow the remote frame on the wire)."""
    answers, pending = [], False
    for pos, msg in enumerate(raw.frames.snapshot()):
        if msg.arbitration_id != GUARD or msg.is_error_frame:
            continue
        if msg.is_remote_frame:
            assert not pending, f"remote frame at {pos} before the last was answered"
            pending = True
        elif bytes(msg.data) != b"\x00":
            assert pending, f"answer {msg} at {pos} without a request"
            assert len(msg.data) == 1, msg
            pending = False
            if pos >= start:
                answers.append(msg)
    return answers


def wait_answers(raw: RawLog, count: int, start: int = 0, timeout: float = 5.0) -> list:
    def enough(_calls):
        answers = guard_answers(raw, start)
        return answers if len(answers) >= count else None
    return raw.frames.wait_for(enough, timeout, f"{count} guarding answers")


def assert_toggles(answers: list) -> None:
    toggles = [msg.data[0] & 0x80 for msg in answers]
    assert all(a != b for a, b in zip(toggles, toggles[1:])), \
        [bytes(m.data).hex() for m in answers]


def canopen_state(remote) -> str:
    """python-canopen's nmt.state once its heartbeat handler is done (it calls
    the callbacks before it stores the state, both under state_update)."""
    with remote.nmt.state_update:
        return remote.nmt.state


def test_python_canopen_guards_our_node_state_toggle_and_life_guarding(classic, peer, raw):
    guard_ms = round(scaled(0.05) * 1000)        # 50 ms; 500 ms in the VM
    factor = 3
    me = classic.create_local_node(NODE, od=guarded_od(guard_ms, factor))
    theirs = peer.add_node(NODE)
    seen, emcys = Recorder(), Recorder()
    theirs.nmt.add_heartbeat_callback(seen)      # python-canopen: state, toggle masked
    theirs.emcy.add_callback(emcys)
    our_states = Recorder()
    me.on_state_change(lambda old, new: our_states(new))
    try:
        # (a) answers: pre-operational 0x7F, toggle from 0 and alternating
        theirs.nmt.start_node_guarding(guard_ms / 1000)
        answers = wait_answers(raw, 4)
        assert [bytes(m.data) for m in answers[:4]] == [b"\x7f", b"\xff", b"\x7f", b"\xff"]
        requests = raw.select(GUARD, rtr=True)
        assert all(m.arbitration_id == GUARD and not m.is_extended_id for m in requests)
        seen.wait_value(0x7F)
        assert canopen_state(theirs) == "PRE-OPERATIONAL"

        # (b) state changes show in the answers (the toggle goes on alternating)
        mark = raw.mark()
        start(me)
        n = seen.wait_value(0x05, timeout=10)
        assert canopen_state(theirs) == "OPERATIONAL"
        me.apply("stop")
        me.wait_for_state("STOPPED", timeout=scaled(5))
        n = seen.wait_value(0x04, timeout=10, start=n + 1)
        assert canopen_state(theirs) == "STOPPED"
        start(me)
        seen.wait_value(0x05, timeout=10, start=n + 1)
        assert canopen_state(theirs) == "OPERATIONAL"
        answers = wait_answers(raw, len(guard_answers(raw, mark)) + 2, mark)
        assert_toggles(guard_answers(raw))
        states = [m.data[0] & 0x7F for m in answers]
        assert {0x04, 0x05} <= set(states) and set(states) <= {0x04, 0x05, 0x7F}
        assert states[-1] == 0x05
        assert classic.service_stats["guard_slave"]["life_lost"] == 0
        assert emcys.snapshot() == []

        # (c) life guarding: no remote frame for guard time x life time factor
        # -> EMCY 0x8130 (node-id in the first manufacturer byte), and 0x1029
        # absent = error behaviour 0: OPERATIONAL -> PRE-OPERATIONAL
        assert me.state == NmtState.OPERATIONAL
        since = len(our_states)
        theirs.nmt.stop_node_guarding()
        lost = emcys.wait_count(1, timeout=10)[0]
        assert (lost.code, lost.register, bytes(lost.data)) == \
            (0x8130, 0x11, bytes([NODE, 0, 0, 0, 0]))
        emcy = raw.wait(EMCY, 1)[0]
        assert bytes(emcy.data).hex(" ") == f"30 81 11 {NODE:02x} 00 00 00 00"
        before = [m for m in raw.frames.snapshot()
                  if m.arbitration_id == GUARD and m.is_remote_frame
                  and m.timestamp <= emcy.timestamp]
        silent = emcy.timestamp - before[-1].timestamp
        life = guard_ms * factor / 1000
        assert life - 0.005 <= silent <= life + scaled(0.2), (silent, life)
        our_states.wait_value(NmtState.PRE_OPERATIONAL, timeout=10, start=since)
        assert me.state == NmtState.PRE_OPERATIONAL
        assert me.emcy.error_register == 0x11 and me.emcy.active == 1
        assert classic.service_stats["guard_slave"]["life_lost"] == 1
        last_toggle = guard_answers(raw)[-1].data[0] & 0x80

        # (d) guarding comes back: the condition ends (reset EMCY), answers go
        # on with the next toggle (only reset communication restarts it at 0)
        mark, heard = raw.mark(), len(seen)
        theirs.nmt.start_node_guarding(guard_ms / 1000)
        reset = emcys.wait_count(2, timeout=10)[1]
        assert (reset.code, reset.register, bytes(reset.data)) == (0, 0, bytes(5))
        assert bytes(raw.wait(EMCY, 2)[1].data) == bytes(8)
        answers = wait_answers(raw, 2, mark)
        assert [bytes(m.data) for m in answers[:2]] == \
            [bytes([0x7F | (last_toggle ^ 0x80)]), bytes([0x7F | last_toggle])]
        seen.wait_value(0x7F, timeout=10, start=heard)
        assert canopen_state(theirs) == "PRE-OPERATIONAL"
        assert me.emcy.error_register == 0 and me.emcy.active == 0
    finally:
        theirs.nmt.stop_node_guarding()


def all_answered(raw: RawLog) -> list:
    """Wait until every remote frame on 0x700 + NODE has its answer; the answers."""
    def settled(_calls):
        answers = guard_answers(raw)
        return answers if len(answers) == len(raw.select(GUARD, rtr=True)) else None
    return raw.frames.wait_for(settled, 5.0, "every guarding request answered")


def test_reset_communication_restarts_the_guarding_toggle(classic, peer, raw):
    """NMT reset communication (from python-canopen) brings the toggle back to
    0: the last answer before the reset has toggle 0, so a toggle that went on
    would answer 0xFF first."""
    guard_ms = round(scaled(0.05) * 1000)
    me = classic.create_local_node(NODE, od=guarded_od(guard_ms, 0))   # no life guarding
    theirs = peer.add_node(NODE)
    try:
        theirs.nmt.start_node_guarding(guard_ms / 1000)
        answers = wait_answers(raw, 3)
        assert [bytes(m.data) for m in answers[:3]] == [b"\x7f", b"\xff", b"\x7f"]
        theirs.nmt.stop_node_guarding()
        answers = all_answered(raw)
        if answers[-1].data[0] & 0x80:              # one more request: last toggle 0
            peer.send_message(GUARD, b"", remote=True)
            answers = wait_answers(raw, len(answers) + 1)
        assert_toggles(answers)
        assert bytes(answers[-1].data) == b"\x7f"
        resets = Recorder()
        me.on_reset(resets)
        theirs.nmt.state = "RESET COMMUNICATION"
        resets.wait_count(1, timeout=10)
        me.wait_for_state("PRE_OPERATIONAL", timeout=scaled(5))

        def bootups(_calls):                        # the first boot-up, then the reset's
            found = [m for m in raw.select(GUARD, rtr=False) if bytes(m.data) == b"\x00"]
            return found if len(found) >= 2 else None
        second = raw.frames.wait_for(bootups, 10, "the boot-up after the reset")[1]
        boot_index = raw.frames.snapshot().index(second)
        theirs.nmt.start_node_guarding(guard_ms / 1000)
        after = wait_answers(raw, 2, boot_index + 1)
        assert [bytes(m.data) for m in after[:2]] == [b"\x7f", b"\xff"]
    finally:
        theirs.nmt.stop_node_guarding()


# ------------------------------------------------------------------ RTR PDOs
def rtr_pdo_setup(classic, peer, eds, trans_type):
    """Our node's TPDO 1 (UNSIGNED16, Setpoint INTEGER16, UNSIGNED32 = 8 bytes)
    with `trans_type`, and python-canopen's view of it read through SDO."""
    me = classic.create_local_node(NODE, od=pdo_od("classic"))
    map_pdo(me.tpdo[1], [("Demo UNSIGNED16",), ("Demo record.Setpoint",),
                         ("Demo UNSIGNED32",)], TPDO, trans_type=trans_type)
    theirs = peer.add_node(NODE, eds)
    theirs.sdo.RESPONSE_TIMEOUT = scaled(1.0)
    theirs.tpdo.read()
    pdo = theirs.tpdo[1]
    assert (pdo.cob_id, pdo.trans_type, pdo.enabled, pdo.rtr_allowed) == \
        (TPDO, trans_type, True, True)              # else remote_request() sends nothing
    heard = Recorder()
    pdo.add_callback(lambda p: heard([v.raw for v in p.map]))
    return me, pdo, heard


def set_values(me, values):
    for name, value in zip(("Demo UNSIGNED16", "Demo record.Setpoint", "Demo UNSIGNED32"),
                           values):
        me[name].raw = value


def pdo_bytes(values) -> bytes:
    u16, setpoint, u32 = values
    return u16.to_bytes(2, "little") + setpoint.to_bytes(2, "little", signed=True) + \
        u32.to_bytes(4, "little")


def test_rtr_only_tpdo_253_answers_python_canopen_remote_request(classic, peer, eds, raw):
    me, pdo, heard = rtr_pdo_setup(classic, peer, eds, 253)
    first = (0x0102, -5, 0xA1B2C3D4)
    set_values(me, first)
    # pre-operational: the remote frame is taken but not answered
    pdo.remote_request()
    raw.wait(TPDO, 1, rtr=True)
    wait_until(lambda: classic.service_stats["pdo"]["rx_not_operational"] >= 1,
               what="RTR counted as not operational")
    start(me)
    pdo.remote_request()
    answer = raw.wait(TPDO, 1, rtr=False, timeout=10)[0]
    assert bytes(answer.data).hex(" ") == "02 01 fb ff d4 c3 b2 a1"
    assert bytes(answer.data) == pdo_bytes(first) and not answer.is_remote_frame
    assert heard.wait_count(1, timeout=10)[0] == list(first)
    # sampled at the request: new values, new answer
    second = (4321, 500, 0x12345678)
    set_values(me, second)
    pdo.remote_request()
    answer = raw.wait(TPDO, 2, rtr=False, timeout=10)[1]
    assert bytes(answer.data) == pdo_bytes(second)
    assert heard.wait_count(2, timeout=10)[1] == list(second)
    # exactly one answer per request, each right after its request; nothing
    # sent on its own (no event, no SYNC type)
    frames = raw.select(TPDO)
    assert [m.is_remote_frame for m in frames] == [True, True, False, True, False]
    stats = classic.service_stats["pdo"]
    assert (stats["rtr_answered"], stats["rtr_refused"]) == (2, 0)


def test_rtr_sync_tpdo_252_samples_at_python_canopen_sync(classic, peer, eds, raw):
    me, pdo, heard = rtr_pdo_setup(classic, peer, eds, 252)
    syncs = Recorder()
    classic.sync.add_callback(syncs)                # SYNC handled by our runtime
    first, second, third = ((1000, -1, 0x01020304), (2000, -2, 0x05060708),
                            (3000, 300, 0xFFFFFFFF))
    set_values(me, first)
    start(me)
    # no SYNC yet: nothing sampled, the request is refused (no answer)
    pdo.remote_request()
    wait_until(lambda: classic.service_stats["pdo"]["rtr_refused"] == 1,
               what="RTR before any SYNC refused")
    assert raw.select(TPDO, rtr=False) == []
    # python-canopen's SYNC producer: sampled now, sent only on request
    peer.sync.transmit()
    syncs.wait_count(1, timeout=10)
    set_values(me, second)                          # after the SYNC: not in the sample
    pdo.remote_request()
    answer = raw.wait(TPDO, 1, rtr=False, timeout=10)[0]
    assert bytes(answer.data) == pdo_bytes(first)
    assert bytes(answer.data).hex(" ") == "e8 03 ff ff 04 03 02 01"
    assert heard.wait_count(1, timeout=10)[0] == list(first)
    pdo.remote_request()                            # the same sample again
    assert bytes(raw.wait(TPDO, 2, rtr=False, timeout=10)[1].data) == pdo_bytes(first)
    assert heard.wait_count(2, timeout=10)[1] == list(first)
    # the next SYNCs sample `second`, then `third`; a SYNC alone sends nothing
    peer.sync.transmit()
    syncs.wait_count(2, timeout=10)
    set_values(me, third)
    pdo.remote_request()
    assert bytes(raw.wait(TPDO, 3, rtr=False, timeout=10)[2].data) == pdo_bytes(second)
    assert heard.wait_count(3, timeout=10)[2] == list(second)
    peer.sync.transmit()
    syncs.wait_count(3, timeout=10)
    pdo.remote_request()
    answer = raw.wait(TPDO, 4, rtr=False, timeout=10)[3]
    assert bytes(answer.data).hex(" ") == "b8 0b 2c 01 ff ff ff ff"
    assert heard.wait_count(4, timeout=10)[3] == list(third)
    kinds = [("rtr" if m.is_remote_frame else "pdo") if m.arbitration_id == TPDO else "sync"
             for m in raw.frames.snapshot() if m.arbitration_id in (TPDO, 0x80)]
    assert kinds == ["rtr", "sync", "rtr", "pdo", "rtr", "pdo", "sync", "rtr", "pdo",
                     "sync", "rtr", "pdo"]
    stats = classic.service_stats["pdo"]
    assert (stats["rtr_answered"], stats["rtr_refused"]) == (4, 1)
