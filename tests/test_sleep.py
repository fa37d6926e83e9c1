"""Sleep and wake-up (CiA 320) through the Python API on the in-process bus:
a master line and two devices with local nodes (heartbeat 50 ms); every
frame checked on the bus by a monitor line; the phases as callbacks and
waits; a device's objection; errors that name the problem; and a device
answering a query sent by plain python-can (an independent sender)."""

from __future__ import annotations

import asyncio
import time

import pytest

from canopenfd import (CanopenFDError, ConfigurationError, SleepCause, SleepEvent, SleepNotice,
                       SleepPhase)
from canopenfd.od import demo_od
from helpers import Recorder, scaled, virtual_bus

PHASE_S = 0.15


def _device(net, bus_name, node_id, mode="classic"):
    line = net.open_line(bus_name, mode=mode)
    node = line.create_local_node(node_id, od=demo_od(mode))
    node[0x1017].raw = 50
    return line, node


@pytest.fixture
def network(net, bus_name):
    """master line, devices 5 and 6 (started as sleep devices), a monitor."""
    frames = Recorder()
    net.open_line(bus_name, mode="classic", monitor=True).on_frame(frames)
    master = net.open_line(bus_name, mode="classic")
    devices = [_device(net, bus_name, n) for n in (5, 6)]
    notices = {name: Recorder() for name in ("master", 5, 6)}
    master.sleep.start("master", check=PHASE_S, prepare=PHASE_S, silent=PHASE_S)
    master.sleep.add_callback(notices["master"])
    for (line, node), name in zip(devices, (5, 6)):
        line.sleep.start("device", prepare=PHASE_S, silent=PHASE_S)
        line.sleep.add_callback(notices[name])
    return master, devices, frames, notices


def _data(frames, can_id, start=0):
    return [bytes(f.data) for f in frames.snapshot()[start:] if f.id == can_id]


def _wait_data(frames, can_id, count, start=0):
    """_data once `count` frames of can_id arrived: the monitor hears them
    after the nodes acted on them (a wait on a phase is no wait for it)."""
    frames.wait_for(lambda c: len([f for f in c[start:] if f.id == can_id]) >= count, 3,
                    f"{count} frames on 0x{can_id:X}")
    return _data(frames, can_id, start)


def test_sleep_phases_awaited_together(network):
    """The master and both devices awaited asleep in one loop; the sleep
    command on the wire as with the blocking waits."""
    master, devices, frames, _ = network
    frames.wait_for(lambda c: [f for f in c if f.id == 0x706], 2, "heartbeats")

    async def main():
        waits = [line.sleep.await_for("asleep", timeout=scaled(3)) for line, _ in devices]
        master.sleep.check()
        return await asyncio.gather(master.sleep.await_for(SleepPhase.ASLEEP,
                                                            timeout=scaled(3)), *waits)
    assert asyncio.run(main()) == [SleepPhase.ASLEEP] * 3
    assert _wait_data(frames, 0x691, 2) == [bytes([0x01]) + bytes(7), bytes([0x02]) + bytes(7)]

    async def too_soon():
        await master.sleep.await_for("awake", timeout=0.05)
    with pytest.raises(TimeoutError, match="still asleep"):
        asyncio.run(too_soon())


def test_check_sleep_and_wake_on_the_wire(network):
    master, devices, frames, notices = network
    frames.wait_for(lambda c: [f for f in c if f.id == 0x706], 2, "heartbeats")
    master.sleep.check()
    for line, _ in devices:
        assert line.sleep.wait_for("asleep", timeout=scaled(3)) == SleepPhase.ASLEEP
    assert master.sleep.wait_for(SleepPhase.ASLEEP, timeout=scaled(3)) == SleepPhase.ASLEEP
    assert master.sleep.phase == SleepPhase.ASLEEP
    # query, then the sleep command: 0x691, 8 bytes each
    assert _wait_data(frames, 0x691, 2) == [bytes([0x01]) + bytes(7), bytes([0x02]) + bytes(7)]
    # the notices run on the dispatcher thread, maybe after the phase wait returned
    notices[5].wait_for(lambda c: [n for n in c if n.event == SleepEvent.ASLEEP], 3,
                        "node 5's ASLEEP notice")
    events = [n.event for n in notices[5].snapshot()]
    assert events == [SleepEvent.QUERY, SleepEvent.PREPARE, SleepEvent.SILENT,
                      SleepEvent.ASLEEP]
    assert [n.phase for n in notices[5].snapshot()][1:] == [
        SleepPhase.PREPARING, SleepPhase.SILENT, SleepPhase.ASLEEP]
    # silent: no heartbeat of the devices any more
    mark = len(frames)
    time.sleep(scaled(0.3))
    assert not [f for f in frames.snapshot()[mark:] if f.id in (0x705, 0x706)]
    assert devices[0][0].stats["tx_silenced"] > 0

    # the master wakes: its wake-up message, each device's, their boot-ups
    mark = len(frames)
    master.sleep.wake(status=0x10, reason=0x20)
    frames.wait_for(lambda c: [f for f in c[mark:] if f.id == 0x706 and f.data[0] == 0], 3,
                    "boot-up of node 6")
    # (node 6's boot-up is no wait for the frames of the master and node 5)
    assert _wait_data(frames, 0x691, 1, mark) == [bytes([0x10, 0x20]) + bytes(6)]
    assert _wait_data(frames, 0x690, 2, mark) == [bytes([0x00, SleepCause.BUS]) + bytes(6)] * 2
    assert _wait_data(frames, 0x705, 1, mark)[0] == b"\x00"
    wake = notices[5].wait_for(lambda c: [n for n in c if n.event == SleepEvent.WAKE], 3)[0]
    assert wake == SleepNotice(SleepEvent.WAKE, SleepPhase.AWAKE, SleepCause.BUS, 0)
    woke = notices["master"].wait_for(
        lambda c: [n for n in c if n.event == SleepEvent.WAKE_MESSAGE], 3)
    assert {(n.value, n.reason) for n in woke} == {(0, SleepCause.BUS)}
    assert devices[0][1].nmt.state == "PRE-OPERATIONAL"
    assert master.sleep.stats["wake_messages_received"] == 2


def test_a_device_objects(network):
    master, devices, frames, notices = network
    devices[1][0].sleep.objection = 0x42
    assert devices[1][0].sleep.objection == 0x42
    master.sleep.check()
    notice = notices["master"].wait_for(
        lambda c: [n for n in c if n.event == SleepEvent.OBJECTION], 3)[0]
    assert notice.value == 0x42 and notice.phase == SleepPhase.AWAKE
    assert _wait_data(frames, 0x690, 1) == [bytes([0x81, 0x42]) + bytes(6)]
    time.sleep(scaled(2 * PHASE_S))
    assert _data(frames, 0x691) == [bytes([0x01]) + bytes(7)]     # no sleep command
    assert master.sleep.phase == SleepPhase.AWAKE
    assert devices[0][0].sleep.phase == SleepPhase.AWAKE


def test_a_device_requests_sleep(network):
    master, devices, frames, notices = network
    devices[0][0].sleep.request()
    notices["master"].wait_for(lambda c: [n for n in c if n.event == SleepEvent.REQUEST], 3)
    assert _wait_data(frames, 0x692, 1) == [bytes([0x03]) + bytes(7)]


def test_wrong_use_names_the_problem(net, bus_name, network):
    master, devices, _, _ = network
    with pytest.raises(CanopenFDError, match="awake"):
        master.sleep.wake()
    with pytest.raises(CanopenFDError, match="only the master checks"):
        devices[0][0].sleep.check()
    with pytest.raises(CanopenFDError, match="runs on this line already"):
        master.sleep.start("master")
    with pytest.raises(ConfigurationError, match="role must be"):
        net.open_line(bus_name, mode="classic").sleep.start("boss")
    with pytest.raises(ConfigurationError, match="prepare must be 0..60 s"):
        net.open_line(bus_name, mode="classic").sleep.start(prepare=-1)
    with pytest.raises(ConfigurationError, match="objection must be 0..255"):
        devices[0][0].sleep.objection = 256
    with pytest.raises(CanopenFDError, match="not started"):
        net.open_line(bus_name, mode="classic").sleep.sleep()
    with pytest.raises(ConfigurationError, match="phase must be one of"):
        master.sleep.wait_for("dozing", timeout=0)
    with pytest.raises(TimeoutError, match="still awake"):
        master.sleep.wait_for("asleep", timeout=0.05)


def test_fd_line_frames(net, bus_name):
    frames = Recorder()
    net.open_line(bus_name, mode="fd", monitor=True).on_frame(frames)
    master = net.open_line(bus_name, mode="fd")
    device, _ = _device(net, bus_name, 7, mode="fd")
    master.sleep.start("master", check=PHASE_S, prepare=PHASE_S, silent=PHASE_S)
    device.sleep.start("device", prepare=PHASE_S, silent=PHASE_S, objection=9)
    master.sleep.check()
    frames.wait_for(lambda c: [f for f in c if f.id == 0x690], 3, "objection")
    objection = [f for f in frames.snapshot() if f.id == 0x690][0]
    assert objection.fd and bytes(objection.data) == bytes([0x81, 9]) + bytes(6)


def test_a_query_from_plain_python_can(net):
    """python-can, not our master, sends the query; our device objects on 0x690."""
    import can
    channel = f"sleep-{time.monotonic_ns()}"
    sender = virtual_bus(channel)
    device = net.open_line(bus=virtual_bus(channel), mode="classic")
    device.sleep.start("device", objection=0x33)
    sender.send(can.Message(arbitration_id=0x691, data=bytes([1]) + bytes(7),
                            is_extended_id=False))
    deadline = time.monotonic() + scaled(3)
    while time.monotonic() < deadline:
        message = sender.recv(timeout=0.1)
        if message is not None and message.arbitration_id == 0x690:
            assert bytes(message.data) == bytes([0x81, 0x33]) + bytes(6)
            break
    else:
        pytest.fail("no objection on 0x690")
    assert device.sleep.stats["objections_sent"] == 1
