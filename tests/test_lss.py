"""line.lss, the Python LSS master (the runtime's C master), against our own
local nodes' LSS slaves on an in-process bus: the bytes it sends, results,
refusals, timeouts, identify and scan, awaitable forms. Fast scan of
unconfigured devices is covered by the C tests (tests/c/test_lss_master.c,
test_stack_lss.c); interop with python-canopen in test_lss_interop.py."""

from __future__ import annotations

import asyncio
import time

import pytest

from canopenfd import ConfigurationError
from canopenfd.od import demo_od
from canopenfd.services.lss import LssDevice, LssError
from canopenfd._binding.constants import LssStatus
from helpers import Recorder, scaled

IDENTITY = (0x000001A2, 0x00BEEF01, 0x00020003, 0x80000001)


def identity_od(serial: int):
    od = demo_od("classic")
    for sub, value in enumerate(IDENTITY[:3] + (serial,), start=1):
        od[0x1018][sub].default = value
    return od


@pytest.fixture
def rig(net, bus_name):
    """Our nodes 5 and 6 (same vendor/product/revision, serials 1 and 2) and
    a master line; a monitor records every frame."""
    for node_id, serial in ((5, 0x80000001), (6, 0x80000002)):
        net.open_line(bus_name, mode="classic").create_local_node(node_id,
                                                                   od=identity_od(serial))
    line = net.open_line(bus_name, mode="classic")
    frames = Recorder()
    net.open_line(bus_name, mode="classic", monitor=True).on_frame(frames)
    line.lss.timeout_ms = 50
    return line, frames


def lss_frames(frames, can_id):
    return [bytes(f.data) for f in frames.snapshot() if f.id == can_id]


def wait_lss_frames(frames, can_id, *wanted):
    """The frames of can_id once every one of `wanted` is among them (the
    monitor hears them after the master and the slave acted on them)."""
    return frames.wait_for(lambda _calls: all(w in lss_frames(frames, can_id) for w in wanted)
                           and lss_frames(frames, can_id), 2,
                           f"frames 0x{can_id:X} {[w.hex() for w in wanted]}")


def test_select_inquire_configure(rig):
    line, frames = rig
    lss = line.lss
    assert lss.switch_selective(*IDENTITY) is True
    sent = frames.wait_for(lambda c: lss_frames(frames, 0x7E5)[:4] if len(
        lss_frames(frames, 0x7E5)) >= 4 else None, 2, "selective frames")
    assert sent[0] == bytes([0x40, 0xA2, 0x01, 0, 0, 0, 0, 0])
    assert sent[3] == bytes([0x43, 0x01, 0, 0, 0x80, 0, 0, 0])
    answer = bytes([0x44, 0, 0, 0, 0, 0, 0, 0])        # the slave's, after the master's 4
    assert answer in wait_lss_frames(frames, 0x7E4, answer)
    assert lss.inquire("node_id") == 5
    assert lss.inquire("serial") == 0x80000001
    assert asyncio.run(lss.ainquire("product_code")) == IDENTITY[1]
    lss.configure_node_id(9)
    assert lss.inquire("node_id") == 5          # pending until reset communication
    with pytest.raises(LssError) as info:
        lss.store()                               # this node has no store indication
    assert info.value.status == LssStatus.REFUSED and info.value.error == 1
    assert "not supported" in str(info.value)
    with pytest.raises(LssError, match="error 1"):
        lss.configure_bit_timing(2)
    lss.switch_global("waiting")
    # Nobody in configuration: no answer.
    with pytest.raises(LssError, match="no answer") as info:
        lss.inquire("node_id")
    assert info.value.status == LssStatus.TIMEOUT
    assert lss.switch_selective(IDENTITY[0], IDENTITY[1], IDENTITY[2], 0x12345) is False


def test_both_in_configuration_answers_counted(rig):
    line, _ = rig
    line.lss.switch_global("configuration")
    assert line.lss.inquire("node_id") in (5, 6)
    assert line.lss.stats["duplicates"] == 1
    line.lss.switch_global("waiting")


def test_identify_and_scan(rig):
    line, _ = rig
    lss = line.lss
    assert lss.identify_remote(IDENTITY[0], IDENTITY[1]) >= 1
    assert lss.identify_remote(IDENTITY[0], IDENTITY[1], serials=(0x80000002, 0xFFFFFFFF)) == 1
    assert lss.identify_remote(IDENTITY[0] + 1, IDENTITY[1]) == 0
    assert lss.identify_non_configured() == 0      # both have node-ids
    found = lss.scan(IDENTITY[0], IDENTITY[1], serials=(0x80000000, 0x8000FFFF))
    assert found == [LssDevice(*IDENTITY[:3], 0x80000001, 0),
                     LssDevice(*IDENTITY[:3], 0x80000002, 0)]
    # Configured nodes take no part in fast scan.
    assert lss.fast_scan([20, 21]) == []


def test_wrong_use(rig):
    line, _ = rig
    lss = line.lss
    with pytest.raises(ConfigurationError, match="node_id must be 1..127 or 255"):
        lss.configure_node_id(0)
    with pytest.raises(ConfigurationError, match="what must be one of"):
        lss.inquire("colour")
    with pytest.raises(ConfigurationError, match="state must be"):
        lss.switch_global("sleeping")
    with pytest.raises(ConfigurationError, match="low 0x5 is above high 0x4"):
        lss.scan(1, 2, serials=(5, 4))
    with pytest.raises(ConfigurationError, match="node_ids must be"):
        lss.fast_scan([0])
    with pytest.raises(ConfigurationError, match="vendor_id must be an int"):
        lss.identify_remote(-1, 0)
    # One request at a time.
    running = lss.start_inquire("node_id")
    with pytest.raises(ConfigurationError, match="still running"):
        lss.start_inquire("serial")
    with pytest.raises(LssError):
        running.result()


# ---------------------------------------------------------------- our node's slave
def test_local_node_store_and_bit_timing(net, bus_name):
    node = net.open_line(bus_name, mode="classic").create_local_node(7, od=identity_od(7))
    line = net.open_line(bus_name, mode="classic")
    line.lss.timeout_ms = 500
    states, stored, activations = Recorder(), Recorder(), Recorder()
    node.lss.on_state_change(states)
    node.lss.on_activate_bit_timing(activations)
    assert node.lss.info == {"state": "waiting", "active": 7, "pending": 7, "persistent": 7}
    line.lss.switch_global("configuration")
    states.wait_for(lambda c: c == ["configuration"], 2, "state")
    line.lss.configure_node_id(12)
    assert node.lss.info["pending"] == 12
    # Not supported until the application says how.
    with pytest.raises(LssError, match="error 1"):
        line.lss.store()
    with pytest.raises(LssError, match="error 1"):
        line.lss.configure_bit_timing(3)
    node.lss.on_store(stored)
    node.lss.accept_bit_timings([2, 3])
    line.lss.store()                              # answered once the callback returned
    assert stored.snapshot() == [12]
    assert node.lss.info["persistent"] == 12
    line.lss.configure_bit_timing(3)
    with pytest.raises(LssError, match="error 1"):
        line.lss.configure_bit_timing(4)
    line.lss.activate_bit_timing(250)
    activations.wait_for(lambda c: c == [250], 2, "activation")

    def broken(node_id):
        raise OSError("EEPROM gone")

    node.lss.on_store(broken)
    with pytest.raises(LssError, match="error 2") as info:
        line.lss.store()
    assert info.value.error == 2
    line.lss.switch_global("waiting")
    states.wait_for(lambda c: c == ["configuration", "waiting"], 2, "state")
    with pytest.raises(ConfigurationError, match="ints 0..31"):
        node.lss.accept_bit_timings([32])


def test_unconfigured_local_node_gets_its_node_id(net, bus_name):
    device = net.open_line(bus_name, mode="classic").create_local_node(
        255, 50, od=identity_od(0x42))
    line = net.open_line(bus_name, mode="classic")
    configured, frames = Recorder(), Recorder()
    net.open_line(bus_name, mode="classic", monitor=True).on_frame(frames)
    assert device.state.label == "INITIALISING"
    time.sleep(scaled(0.3))                           # silent: no boot-up, no heartbeat
    assert [f for f in frames.snapshot() if 0x700 <= f.id <= 0x77F] == []
    device.lss.on_configured(configured)
    assert line.lss.identify_non_configured() == 1
    with pytest.raises(ConfigurationError, match="needs an OD with the serial number"):
        net.open_line(bus_name, mode="classic").create_local_node(255)
    found = line.lss.fast_scan([20, 21])
    assert found == [LssDevice(*IDENTITY[:3], 0x42, 20)]
    configured.wait_for(lambda c: c == [20], 2, "configured")
    assert device.node_id == 20
    device.nmt.wait_for_state("PRE-OPERATIONAL", timeout=2)
    assert line.states[20] == "PRE-OPERATIONAL"       # boot-up heard with node-id 20
    assert line.lss.identify_non_configured() == 0
    with pytest.raises(ConfigurationError, match="node-id 0 outside"):
        net.open_line(bus_name, mode="classic").create_local_node(0)


def test_configured_node_takes_the_pending_node_id_at_reset_communication(net, bus_name):
    """CiA 305: a configured node keeps its active node-id until NMT reset
    communication, then boots with the pending one (and a store persists the
    pending one). Checked on the wire: boot-up, heartbeat and SDO CAN-IDs."""
    device = net.open_line(bus_name, mode="classic").create_local_node(
        5, 50, od=identity_od(0x42))
    line = net.open_line(bus_name, mode="classic")
    frames, configured, stored = Recorder(), Recorder(), []
    net.open_line(bus_name, mode="classic", monitor=True).on_frame(frames)
    device.lss.on_configured(configured)
    device.lss.on_store(stored.append)
    line.lss.timeout_ms = 50
    line.lss.switch_global("configuration")
    line.lss.configure_node_id(9)
    line.lss.store()
    assert stored == [9]                              # the pending node-id persisted
    assert device.lss.info == {"state": "configuration", "active": 5, "pending": 9,
                               "persistent": 9}
    line.lss.switch_global("waiting")
    device_type = device[0x1000].raw
    sdo_of = lambda node_id: int.from_bytes(line.add_node(node_id).read(0x1000), "little")
    assert sdo_of(5) == device_type                   # still node 5 on SDO
    assert device.node_id == 5
    # the monitor hears frames after the stacks acted: take the mark only once
    # node 5's SDO answer is in (it reached the mark late once under load)
    frames.wait_for(lambda c: [f for f in c if f.id == 0x585], 2, "node 5's SDO answer")
    start = len(frames)
    line.nmt.reset_communication(5)
    configured.wait_for(lambda c: c == [9], 2, "the node renumbered")
    boot = frames.wait_for(lambda c: [f for f in c[start:] if f.id == 0x709], 2, "boot-up")
    assert bytes(boot[0].data) == b"\x00"
    device.nmt.wait_for_state("PRE-OPERATIONAL", timeout=2)
    assert device.node_id == 9
    assert device.lss.info["active"] == 9
    frames.wait_for(lambda c: len([f for f in c[start:] if f.id == 0x709]) >= 3, 2,
                    "heartbeats of node 9")
    after_boot = frames.snapshot()[start:]
    assert [f for f in after_boot if f.id == 0x705 and bytes(f.data) != b"\x7f"] == []
    assert sdo_of(9) == device_type                   # SDO on 0x609 / 0x589
    frames.wait_for(lambda c: [f for f in c[start:] if f.id == 0x589], 2, "the SDO answer")
    assert [f for f in frames.snapshot()[start:] if f.id == 0x585] == []
    device.emcy.raise_error(0x5000)                   # EMCY on 0x80 + the new node-id
    emcy = frames.wait_for(lambda c: [f for f in c[start:] if f.id in (0x85, 0x89)], 2, "EMCY")
    assert emcy[0].id == 0x89 and bytes(emcy[0].data[:2]) == b"\x00\x50"


def test_configure_node_id_out_of_range_is_refused_on_the_wire(net, bus_name):
    """Node-ids 0 and 128..254 are answered with error 1 (out of range):
    our master does not send them, so the request is a raw frame."""
    device = net.open_line(bus_name, mode="classic").create_local_node(
        5, od=identity_od(0x42))
    line = net.open_line(bus_name, mode="classic")
    frames = Recorder()
    net.open_line(bus_name, mode="classic", monitor=True).on_frame(frames)
    line.lss.switch_global("configuration")
    for bad in (0, 128, 254):
        with pytest.raises(ConfigurationError, match="node_id must be 1..127 or 255"):
            line.lss.configure_node_id(bad)
        start = len(frames)
        line.send_frame(0x7E5, bytes([0x11, bad, 0, 0, 0, 0, 0, 0]))
        answer = frames.wait_for(lambda c: [f for f in c[start:] if f.id == 0x7E4], 2,
                                 f"the answer to node-id {bad}")
        assert bytes(answer[0].data) == bytes([0x11, 0x01, 0, 0, 0, 0, 0, 0])
        assert device.lss.info["pending"] == 5


# ---------------------------------------------------------------- identify-only fast scan
def test_fast_scan_identify_leaves_the_device_selected(net, bus_name):
    """fast_scan_identify finds one unconfigured device (the lower address of
    two), returns its address with node_id 0 and leaves it alone in the
    configuration state: no configure node-id or switch frame on the bus.
    With match/skip filters (CiA 305) it finds the other one."""
    first = net.open_line(bus_name, mode="classic").create_local_node(
        255, od=identity_od(0x80000001))
    second = net.open_line(bus_name, mode="classic").create_local_node(
        255, od=identity_od(0x80000002))
    line = net.open_line(bus_name, mode="classic")
    frames = Recorder()
    net.open_line(bus_name, mode="classic", monitor=True).on_frame(frames)
    lss = line.lss
    lss.timeout_ms = 50   # a step nobody answers costs this; 20 ms was missed under load

    def scan_frames(count: int) -> list:
        """The fast scan frames (0x51) on the bus, once `count` arrived."""
        def arrived(calls: list) -> list:
            found = [bytes(f.data) for f in calls if f.id == 0x7E5 and f.data[0] == 0x51]
            return found if len(found) >= count else []
        return frames.wait_for(arrived, what=f"{count} fast scan frames")

    device = lss.fast_scan_identify()
    assert device == LssDevice(*IDENTITY[:3], 0x80000001, 0)
    # reset, 4 x 32 bit checks, confirmations of the product's, revision's
    # and serial's 1-bits
    sent = scan_frames(1 + 128 + 3)
    assert len(sent) == 1 + 128 + 3
    assert sent[-1] == bytes((0x51, 0x01, 0, 0, 0x80, 0, 3, 0))  # serial confirmed: selected
    assert {bytes(f.data)[0] for f in frames.snapshot() if f.id == 0x7E5} == {0x51}
    assert first.lss.info["state"] == "configuration" and first.lss.info["pending"] == 255
    assert second.lss.info["state"] == "waiting"
    assert lss.inquire("serial") == 0x80000001               # it is the one selected
    lss.switch_global("waiting")
    # the serial matched at once, the revision skipped: the second device
    device = lss.fast_scan_identify(match={"serial": 0x80000002}, skip=["revision"])
    assert device == LssDevice(*IDENTITY[:2], 0, 0x80000002, 0)
    # reset, 2 x 32 bits, the product's 1-bit confirmed, one frame for the serial
    sent = scan_frames(132 + 1 + 64 + 1 + 1)[132:]
    assert len(sent) == 1 + 64 + 1 + 1
    assert sent[-1] == bytes((0x51, 0x02, 0, 0, 0x80, 0, 3, 0))
    assert sent[-2] == bytes((0x51,)) + IDENTITY[1].to_bytes(4, "little") + bytes((0, 1, 3))
    assert second.lss.info["state"] == "configuration"
    lss.switch_global("waiting")
    # nobody with this serial: None after the reset, the vendor, product and
    # revision found (answered by both) and the one serial frame nobody answers
    assert lss.fast_scan_identify(match={"serial": 0x12345678}) is None
    sent = scan_frames(199 + 1 + 96 + 2 + 1)[199:]
    assert len(sent) == 1 + 96 + 2 + 1
    assert sent[-1] == bytes((0x51, 0x78, 0x56, 0x34, 0x12, 0, 3, 0))


def test_fast_scan_filters_are_checked(rig):
    line, _ = rig
    lss = line.lss
    with pytest.raises(ConfigurationError, match="vendor_id cannot be skipped"):
        lss.fast_scan_identify(skip=["vendor_id"])
    with pytest.raises(ConfigurationError, match="match 'colour': the parts are"):
        lss.fast_scan_identify(match={"colour": 1})
    with pytest.raises(ConfigurationError, match="serial is both matched and skipped"):
        lss.fast_scan([5], match={"serial": 1}, skip=["serial"])
    with pytest.raises(ConfigurationError, match=r"match\['serial'\] must be an int"):
        lss.fast_scan_identify(match={"serial": -1})
    with pytest.raises(ConfigurationError, match="skip must be a list"):
        lss.fast_scan_identify(skip="revision")
    # configured devices take no part: nothing found
    assert lss.fast_scan_identify() is None


def test_every_request_awaited(net, bus_name):
    """The a-forms of the requests answer as the blocking ones do, bytes on
    the bus included; an LssError and the refusal come through `await`;
    cancelling an awaited request cancels it (no wait left behind, the
    master free for the next one at once, long before the step timeout)."""
    node = net.open_line(bus_name, mode="classic").create_local_node(7, od=identity_od(7))
    line = net.open_line(bus_name, mode="classic")
    frames = Recorder()
    net.open_line(bus_name, mode="classic", monitor=True).on_frame(frames)
    lss = line.lss
    lss.timeout_ms = 200
    stored, states = Recorder(), Recorder()
    node.lss.on_store(stored)
    node.lss.accept_bit_timings([3])
    node.lss.on_state_change(states)

    async def main():
        assert await lss.aidentify_remote(IDENTITY[0], IDENTITY[1]) == 1
        assert await lss.aidentify_non_configured() == 0
        assert await lss.ascan(IDENTITY[0], IDENTITY[1], serials=(7, 7)) == \
            [LssDevice(*IDENTITY[:3], 7, 0)]
        assert await lss.aswitch_selective(*IDENTITY[:3], 7) is True
        await lss.aconfigure_node_id(12)
        await lss.aconfigure_bit_timing(3)
        await lss.astore()
        with pytest.raises(LssError, match="error 1"):
            await lss.aconfigure_bit_timing(4)
        lss.switch_global("waiting")
        states.wait_for(lambda c: c[-1:] == ["waiting"], 2, "waiting")
        lss.timeout_ms = int(scaled(5) * 1000)                    # far beyond this test
        request = lss.start_inquire("node_id")                     # nobody answers
        pending = asyncio.ensure_future(request.aresult())
        while not line.pending_awaits:
            await asyncio.sleep(0.001)
        started = time.monotonic()
        pending.cancel()
        with pytest.raises(asyncio.CancelledError):
            await pending
        assert line.pending_awaits == 0
        with pytest.raises(LssError) as info:                       # the request ended too
            await request
        assert info.value.status == LssStatus.CANCELLED
        assert await lss.aswitch_selective(*IDENTITY[:3], 7) is True   # the master is free
        assert time.monotonic() - started < scaled(5) / 2
    asyncio.run(asyncio.wait_for(main(), scaled(20)))
    assert stored.snapshot() == [12]
    configure, bit_timing, store = (bytes([0x11, 12, 0, 0, 0, 0, 0, 0]),
                                    bytes([0x13, 0, 3, 0, 0, 0, 0, 0]),
                                    bytes([0x17, 0, 0, 0, 0, 0, 0, 0]))
    sent = wait_lss_frames(frames, 0x7E5, configure, bit_timing, store)
    assert configure in sent                                           # configure node-id 12
    assert bit_timing in sent                                          # bit timing table 0 idx 3
    assert store in sent                                               # store
    assert store in wait_lss_frames(frames, 0x7E4, store)              # store confirmed
