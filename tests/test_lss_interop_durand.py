"""LSS (CiA 305) interop, the other direction: our LSS master (`line.lss`)
drives durand's LSS slave. python-canopen has no LSS slave (its side of
tests/test_lss_interop.py is the master); durand (PyPI, a pure Python
CANopen responder library over python-can, `durand/services/lss.py`) is an
implementation independent of ours and of python-canopen.

Every durand node has its own python-can virtual bus on one channel, our line
another, and a recorder a third: it sees every frame, so the bytes our master
sends are checked against the CiA 305 layouts (8 bytes, byte 0 the command
specifier, numbers little-endian in bytes 1..4, fast scan: IDNumber,
bit checked, LSSSub, LSSNext in bytes 1..7).

Where durand deviates from CiA 305 (docs/protocol-notes.md, LSS section):
- identify remote slave: it answers 0x47 instead of 0x4F, so our master
  (strict) hears no answer and counts the frame as an unknown specifier;
- "non-configured" is its active node-id 255 only: a node with a pending
  node-id still answers identify non-configured (ours: active and pending);
- a node created with node-id 255 sends a boot-up on 0x7FF (0x700 + 255);
- it takes LSS frames of any length and switch state selective in any order.
"""

from __future__ import annotations

import itertools
import os
import threading
import time
from typing import Any, Iterator, List, Optional, Tuple

import pytest

import canopenfd
from canopenfd._binding.constants import LssStatus
from canopenfd.services.lss import LssDevice, LssError
from helpers import Recorder, TIME_SCALE, scaled, virtual_bus

can = pytest.importorskip("can")
durand = pytest.importorskip("durand")
from durand.scheduler import AbstractScheduler, get_scheduler, set_scheduler  # noqa: E402

_channels = itertools.count(1)
Identity = Tuple[int, int, int, int]

# Adversarial LSS addresses: all zeros; the same but for the last serial bit;
# the same vendor, product and revision with an all-ones serial; an all-ones
# vendor-ID. (Each 1-bit costs a step timeout, an all-ones address 128 of
# them: the C tests scan those on a fake clock.)
ZEROS = (0x00000000, 0x00000000, 0x00000000, 0x00000000)
LAST_BIT = (0x00000000, 0x00000000, 0x00000000, 0x00000001)
ONES_SERIAL = (0x00000000, 0x00000000, 0x00000000, 0xFFFFFFFF)
ONES_VENDOR = (0xFFFFFFFF, 0x00000000, 0x00000000, 0x00000000)
ADVERSARIAL = [ZEROS, LAST_BIT, ONES_SERIAL, ONES_VENDOR]

LSS_MASTER, LSS_SLAVE = 0x7E5, 0x7E4
ANSWER_4F = bytes([0x4F, 0, 0, 0, 0, 0, 0, 0])


def frame(*head: int) -> bytes:
    """An LSS frame: the given leading bytes, the rest 0 (8 bytes)."""
    return bytes(head) + bytes(8 - len(head))


def value_frame(cs: int, value: int) -> bytes:
    return bytes([cs]) + value.to_bytes(4, "little") + bytes(3)


class _Wire(can.Listener):  # type: ignore[misc]
    """Every frame of the channel as (CAN-ID, bytes), recorded in order."""

    def __init__(self, recorder: Recorder) -> None:
        self._recorder = recorder

    def on_message_received(self, msg: Any) -> None:
        self._recorder((msg.arbitration_id, bytes(msg.data)))


class _Timers(AbstractScheduler):  # type: ignore[misc]
    """durand's process-wide scheduler while a test runs: every timer it
    asks for is recorded and fired by the test, so nothing runs behind its back."""

    def __init__(self) -> None:
        self.entries = Recorder()
        self._lock = threading.Lock()

    def add(self, delay: float, callback: Any, args: Any = (), kwargs: Any = None) -> Any:
        self.entries((delay, callback, args, kwargs or {}))
        return len(self.entries)

    def cancel(self, entry: Any) -> None:
        pass

    @property
    def lock(self) -> Any:
        return self._lock


class Rig:
    """durand nodes, our master line and a recorder on one virtual channel."""

    def __init__(self, timers: _Timers, vcan: Optional[str] = None) -> None:
        self.timers = timers
        self.channel = vcan or f"durand-{os.getpid()}-{next(_channels)}"
        self._vcan = vcan
        self.frames = Recorder()
        self._notifiers: List[Any] = []
        self._networks: List[Any] = []
        self._buses: List[Any] = []
        self.net = canopenfd.Network()
        # on vcan our line is the stack's own SocketCAN line, durand's python-can's
        self.line = (self.net.open_line(vcan, mode="classic") if vcan else
                     self.net.open_line(bus=virtual_bus(self.channel), mode="classic"))
        # Step timeout and settle time for software slaves on a shared CPU:
        # durand answers within a millisecond unless the machine is loaded
        # (a stall longer than the timeout makes the scan start over).
        self.line.lss.timeout_ms = min(60000, int(100 * TIME_SCALE))
        self.line.lss.settle_ms = min(self.line.lss.timeout_ms, int(20 * TIME_SCALE))
        self._notifiers.append(can.Notifier(self._bus(), [_Wire(self.frames)], 0.1))

    def _bus(self) -> Any:
        if not self._vcan:
            return virtual_bus(self.channel)
        bus = can.Bus(interface="socketcan", channel=self._vcan)
        self._buses.append(bus)
        return bus

    def add(self, identity: Identity, node_id: int = 0xFF) -> Any:
        network = durand.CANBusNetwork(self._bus())
        self._networks.append(network)
        node = durand.MinimalNode(network, node_id)
        for sub, value in enumerate(identity, start=1):
            node.object_dictionary.write(0x1018, sub, value)
        return node

    def since(self, start: int, can_id: Optional[int] = None) -> List[Tuple[int, bytes]]:
        return [f for f in self.frames.snapshot()[start:] if can_id is None or f[0] == can_id]

    def wait(self, start: int, predicate: Any, what: str) -> List[Tuple[int, bytes]]:
        return self.frames.wait_for(lambda c: predicate(c[start:]), 5, what)

    def data(self, start: int, can_id: int, count: int) -> List[bytes]:
        """The payloads of the frames with can_id since start, once count of
        them came (the recorder hears them asynchronously)."""
        self.wait(start, lambda c: len([f for f in c if f[0] == can_id]) >= count,
                  f"{count} frames 0x{can_id:03X}")
        return [d for _, d in self.since(start, can_id)]

    def close(self) -> None:
        self.net.close()
        # Each notifier stops within its 1 s receive timeout: all at once.
        stops = [threading.Thread(target=n.stop) for n in self._networks + self._notifiers]
        for thread in stops:
            thread.start()
        for thread in stops:
            thread.join()
        for bus in self._buses:
            bus.shutdown()


def _rig(vcan: Optional[str] = None) -> Iterator[Rig]:
    # durand times activate bit timing on a process-wide scheduler
    previous = get_scheduler()
    timers = _Timers()
    set_scheduler(timers)
    r = Rig(timers, vcan)
    try:
        yield r
    finally:
        r.close()
        set_scheduler(previous)


@pytest.fixture
def rig() -> Iterator[Rig]:
    yield from _rig()


@pytest.fixture
def vcan_rig(vcan: List[str]) -> Iterator[Rig]:
    yield from _rig(vcan[0])


def check_fastscan_layout(data: bytes) -> Tuple[int, int, int, int]:
    """A fast scan request as CiA 305 lays it out; returns its four fields."""
    assert len(data) == 8 and data[0] == 0x51
    id_number = int.from_bytes(data[1:5], "little")
    bit, sub, nxt = data[5], data[6], data[7]
    assert bit <= 31 or bit == 0x80
    assert sub <= 3 and nxt <= 3
    if bit == 0x80:
        assert id_number == 0 and sub == 0 and nxt == 0   # reset: nothing else set
    else:
        assert id_number & ((1 << bit) - 1) == 0    # bits below the checked one: 0
    return id_number, bit, sub, nxt


def test_fast_scan_one_node_frame_by_frame(rig):
    """One durand node, all-zero address: our master's every frame checked."""
    node = rig.add(ZEROS)
    found = rig.line.lss.fast_scan([42])
    assert found == [LssDevice(*ZEROS, 42)]
    rig.wait(0, lambda c: [f for f in c if f[0] == 0x72A], "the boot-up of node 42")
    sent = rig.data(0, LSS_MASTER, 132)
    expected = [frame(0x51, 0, 0, 0, 0, 0x80, 0, 0)]                 # reset
    for part in range(4):
        for bit in range(31, -1, -1):
            # bit 0 names the next part already (a zero needs no confirmation)
            expected.append(frame(0x51, 0, 0, 0, 0, bit, part, part if bit else (part + 1) % 4))
    expected += [frame(0x11, 42), frame(0x04, 0), frame(0x51, 0, 0, 0, 0, 0x80, 0, 0)]
    assert sent == expected
    answers = rig.data(0, LSS_SLAVE, 130)
    assert answers == [ANSWER_4F] * 129 + [frame(0x11, 0)]
    # The node took 42 when switched back to waiting: boot-up on 0x72A.
    assert node.node_id == 42
    assert (0x72A, b"\x00") in rig.since(0)


@pytest.mark.parametrize("count", [2, 4])
def test_fast_scan_adversarial_nodes(rig, count):
    """Two (differing only in the last serial bit) or four unconfigured
    durand nodes with adversarial addresses: each is found, gets its node-id
    (its boot-up says so) and leaves the next scan."""
    identities = ADVERSARIAL[:count]
    nodes = [rig.add(identity) for identity in identities]
    found = rig.line.lss.fast_scan([10, 11, 12, 13, 14])
    # lower addresses first: the scan prefers 0-bits
    assert found == [LssDevice(*identity, 10 + i) for i, identity in
                     enumerate(sorted(identities))]
    by_identity = {d[:4]: d.node_id for d in found}
    for node, identity in zip(nodes, identities):
        node_id = by_identity[identity]
        assert node.node_id == node_id
        rig.wait(0, lambda c, i=node_id: [f for f in c if f == (0x700 + i, b"\x00")],
                 f"boot-up of node {node_id}")
    # Per node: reset, 128 bit checks, a confirmation per part whose bit 0 is
    # 1 (our check of bit 0 names the next part already), configure node-id,
    # switch to waiting; and the reset nobody answers.
    total = sum(131 + sum(part & 1 for part in identity) for identity in identities) + 1
    sent = rig.data(0, LSS_MASTER, total)
    assert len(sent) == total
    resets = 0
    for data in sent:
        if data[0] == 0x51:
            resets += check_fastscan_layout(data)[1] == 0x80
        elif data[0] == 0x11:
            assert data[1] in range(10, 10 + count) and data[2:] == bytes(6)
        else:
            assert data == frame(0x04, 0)           # switch state global: waiting
    assert resets == count + 1                      # one per node, one nobody answers
    assert rig.line.lss.fast_scan([20]) == []
    assert rig.line.lss.identify_non_configured() == 0


def test_fast_scan_identify_and_match(rig):
    """Identify only: durand's node with the lower address is found and left
    selected (it alone answers inquire, then takes a node-id); a second
    identify matches the other's all-ones serial with one frame."""
    first = rig.add(ZEROS)
    second = rig.add(ONES_SERIAL)
    lss = rig.line.lss
    assert lss.fast_scan_identify() == LssDevice(*ZEROS, 0)
    sent = rig.data(0, LSS_MASTER, 129)
    assert all(data[0] == 0x51 for data in sent)           # nothing but the scan
    assert sent[-1] == frame(0x51, 0, 0, 0, 0, 0, 3, 0)     # the serial: selected
    assert lss.inquire("serial") == 0                       # only the selected one answers
    lss.configure_node_id(42)
    lss.switch_global("waiting")
    rig.wait(0, lambda c: [f for f in c if f == (0x72A, b"\x00")], "the boot-up of node 42")
    assert first.node_id == 42
    start = len(rig.frames)
    assert lss.fast_scan_identify(match={"serial": 0xFFFFFFFF}) == LssDevice(*ONES_SERIAL, 0)
    sent = rig.data(start, LSS_MASTER, 1 + 96 + 1)
    assert sent[-1] == frame(0x51, 0xFF, 0xFF, 0xFF, 0xFF, 0, 3, 0)   # one frame for it
    assert len([d for d in sent if d[0] == 0x51]) == 1 + 96 + 1
    assert second.node_id == 0xFF                           # selected, not configured
    lss.switch_global("waiting")


def test_switch_selective_inquire_configure_store(rig):
    """Configured durand nodes with equal prefixes: switch state selective
    picks one (frames checked), inquire, configure node-id (pending until
    NMT reset communication), store refused without durand's callback."""
    a = rig.add((0x1A2, 0xBEEF01, 0x20003, 0x80000001), node_id=0x20)
    b = rig.add((0x1A2, 0xBEEF01, 0x20003, 0x80000002), node_id=0x21)
    lss = rig.line.lss
    start = len(rig.frames)
    assert lss.switch_selective(0x1A2, 0xBEEF01, 0x20003, 0x80000002) is True
    assert rig.data(start, LSS_MASTER, 4) == [
        value_frame(0x40, 0x1A2), value_frame(0x41, 0xBEEF01), value_frame(0x42, 0x20003),
        value_frame(0x43, 0x80000002)]
    assert rig.data(start, LSS_SLAVE, 1) == [frame(0x44)]   # only the selected one
    assert lss.inquire("node_id") == 0x21
    assert (lss.inquire("vendor_id"), lss.inquire("product_code"), lss.inquire("revision"),
            lss.inquire("serial")) == (0x1A2, 0xBEEF01, 0x20003, 0x80000002)
    start = len(rig.frames)
    lss.configure_node_id(0x30)
    assert rig.data(start, LSS_MASTER, 1) == [frame(0x11, 0x30)]
    assert lss.inquire("node_id") == 0x21            # pending until reset communication
    with pytest.raises(LssError) as info:
        lss.store()                                  # durand without a store callback
    assert info.value.status == LssStatus.REFUSED and info.value.error == 1
    stored: List[Tuple[Optional[int], int]] = []
    b.lss.set_store_configuration_callback(lambda baud, node_id: stored.append((baud, node_id)))
    lss.store()
    assert stored == [(None, 0x30)]
    lss.switch_global("waiting")
    with pytest.raises(LssError, match="no answer"):
        lss.inquire("node_id")
    # The other node was never selected: unchanged. NMT reset communication
    # of 0x21: durand boots as 0x30.
    start = len(rig.frames)
    rig.line.nmt.reset_communication(0x21)
    rig.wait(start, lambda c: [f for f in c if f == (0x730, b"\x00")], "boot-up of 0x30")
    assert (b.node_id, a.node_id) == (0x30, 0x20)


def test_switch_global_both_answer(rig):
    nodes = [rig.add(ONES_SERIAL, node_id=3), rig.add(ONES_VENDOR, node_id=4)]
    lss = rig.line.lss
    start = len(rig.frames)
    lss.switch_global("configuration")
    assert lss.inquire("node_id") in (3, 4)
    assert rig.data(start, LSS_MASTER, 2) == [frame(0x04, 1), frame(0x5E)]
    assert sorted(rig.data(start, LSS_SLAVE, 2)) == [frame(0x5E, 3), frame(0x5E, 4)]
    lss.switch_global("waiting")
    # durand takes frames in its own thread: inquire once both are waiting again
    # (under load one still answered from "configuration" once)
    deadline = time.monotonic() + scaled(5)
    while any(n.lss._state != 0 for n in nodes) and time.monotonic() < deadline:   # WAITING
        time.sleep(0.01)
    with pytest.raises(LssError, match="no answer"):
        lss.inquire("node_id")


def test_bit_timing(rig):
    node = rig.add(ZEROS, node_id=7)
    lss = rig.line.lss
    lss.switch_global("configuration")
    with pytest.raises(LssError) as info:
        lss.configure_bit_timing(2)                  # no bit-rate callback: not supported
    assert info.value.status == LssStatus.REFUSED and info.value.error == 1
    changes: List[Tuple[int, float]] = []
    node.lss.set_baudrate_change_callback(lambda baud, delay: changes.append((baud, delay)))
    with pytest.raises(LssError, match="error 1"):
        lss.configure_bit_timing(5)                  # index 5 is reserved in the CiA table
    start = len(rig.frames)
    lss.configure_bit_timing(2)                      # 500 kbit/s
    lss.activate_bit_timing(100)
    assert rig.data(start, LSS_MASTER, 2) == [frame(0x13, 0, 2), frame(0x15, 100, 0)]
    # durand switches after the delay: its timer, fired here
    delay, callback, args, kwargs = rig.timers.entries.wait_count(1)[0]
    assert delay == 0.1
    callback(*args, **kwargs)
    assert changes == [(500000, 0.1)]
    lss.switch_global("waiting")


def test_identify(rig):
    """identify non-configured counts durand's unconfigured nodes; identify
    remote slave gets durand's answer 0x47 (CiA 305: 0x4F), which our master
    does not take."""
    rig.add(ZEROS)
    rig.add(LAST_BIT)
    rig.add(ONES_SERIAL, node_id=5)
    lss = rig.line.lss
    start = len(rig.frames)
    assert lss.identify_non_configured() == 2
    assert rig.data(start, LSS_MASTER, 1) == [frame(0x4C)]
    assert rig.data(start, LSS_SLAVE, 2) == [frame(0x50)] * 2
    unknown = lss.stats["unknown_cs"]
    start = len(rig.frames)
    assert lss.identify_remote(0, 0) == 0
    assert rig.data(start, LSS_MASTER, 6) == [
        value_frame(0x46, 0), value_frame(0x47, 0), value_frame(0x48, 0),
        value_frame(0x49, 0xFFFFFFFF), value_frame(0x4A, 0), value_frame(0x4B, 0xFFFFFFFF)]
    # all three match (vendor 0, product 0, any revision and serial)
    assert rig.data(start, LSS_SLAVE, 3) == [frame(0x47)] * 3
    assert lss.stats["unknown_cs"] == unknown + 3
    # durand: a node with a pending node-id is still "non-configured".
    assert lss.switch_selective(*ZEROS) is True
    lss.configure_node_id(60)
    assert lss.identify_non_configured() == 2
    lss.switch_global("waiting")                     # now it takes 60
    assert lss.identify_non_configured() == 1


@pytest.mark.vcan
def test_fast_scan_two_durand_nodes_on_vcan(vcan_rig):
    """The same on real SocketCAN: our line on vcan0 (the stack's SocketCAN
    driver), two durand nodes over python-can's socketcan interface."""
    rig = vcan_rig
    nodes = [rig.add(ZEROS), rig.add(LAST_BIT)]
    found = rig.line.lss.fast_scan([10, 11])
    assert found == [LssDevice(*ZEROS, 10), LssDevice(*LAST_BIT, 11)]
    assert [node.node_id for node in nodes] == [10, 11]
    rig.wait(0, lambda c: (0x70A, b"\x00") in c and (0x70B, b"\x00") in c, "both boot-ups")
    sent = rig.data(0, LSS_MASTER, 2 * 131 + 1 + 1)
    for data in sent:
        if data[0] == 0x51:
            check_fastscan_layout(data)
    assert rig.line.lss.identify_non_configured() == 0
