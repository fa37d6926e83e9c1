"""Bus redundancy through the Python API on two in-process buses (A = the
line's own, B = the redundant one), every frame checked on each bus by its
own monitor line: a slave follows the redundancy master from A to B after
Ttoggle missed heartbeat periods; a slave that never hears a master switches
Ntoggle times and gives up; errors that name the problem."""

from __future__ import annotations

import time

import pytest

from canopenfd import (AbortError, CanopenFDError, CommEvent, ConfigurationError, RedundancyEvent,
                       RedundancyNotice)
from canopenfd.od import OdStateError, demo_od
from canopenfd.services.redundancy import RECORD_INDEX, redundancy_record
from helpers import Recorder, scaled

HB_MS = 50            # heartbeat of every local node here
PERIOD_S = 0.2        # the master's heartbeat period as the slave watches it


@pytest.fixture
def buses(net, bus_name):
    """(name of A, name of B, monitor of A, monitor of B)."""
    other = bus_name + "-B"
    monitors = []
    for name in (bus_name, other):
        frames = Recorder()
        net.open_line(name, mode="classic", monitor=True).on_frame(frames)
        monitors.append(frames)
    return bus_name, other, monitors[0], monitors[1]


def _node(net, bus, node_id):
    line = net.open_line(bus, mode="classic")
    node = line.create_local_node(node_id, od=demo_od("classic"))
    node[0x1017].raw = HB_MS
    return line


def _heartbeats(frames, node_id, start=0):
    return [bytes(f.data) for f in frames.snapshot()[start:] if f.id == 0x700 + node_id]


def test_slave_follows_the_master_to_bus_b(net, buses):
    a, b, on_a, on_b = buses
    master = _node(net, a, 1)
    master.redundancy.start(b, "master")
    slave = _node(net, a, 2)
    notices = Recorder()
    slave.redundancy.add_callback(notices)
    slave.redundancy.start(b, "slave", master=1, period=PERIOD_S, ttoggle=3, ntoggle=4)
    assert slave.redundancy.active_bus == "A"
    assert slave.redundancy.object == {"Bdefault": 0, "Ttoggle": 3, "Ntoggle": 4, "Ctoggle": 0}

    # both on A: the slave's heartbeat (pre-operational, 0x7F) only there
    on_a.wait_for(lambda c: len([f for f in c if f.id == 0x702]) >= 3, scaled(3), "0x702 on A")
    # the master's heartbeats are another sender's: wait for them too
    on_a.wait_for(lambda c: [f for f in c if f.id == 0x701], scaled(3), "0x701 on A")
    assert _heartbeats(on_a, 2)[-1] == b"\x7f"
    assert _heartbeats(on_a, 1)[-1] == b"\x7f"
    time.sleep(scaled(0.9))            # longer than Ttoggle periods: the master was heard
    assert notices.snapshot() == []
    assert _heartbeats(on_b, 2) == [] and _heartbeats(on_b, 1) == []

    # the master moves to B: the slave misses it on A and follows
    moved = time.monotonic()
    master.redundancy.select("B")
    assert master.redundancy.active_bus == "B"
    assert slave.redundancy.wait_for_bus("B", timeout=scaled(3)) == "B"
    waited = time.monotonic() - moved
    assert waited >= 3 * PERIOD_S * 0.9, f"switched after {waited:.3f} s"
    # the notice runs on the dispatcher thread, maybe after wait_for_bus returned
    notices.wait_count(1, scaled(3))
    assert notices.snapshot()[0] == RedundancyNotice(RedundancyEvent.BUS_SWITCH, "B", 1)
    mark_a = len(on_a)
    on_b.wait_for(lambda c: len([f for f in c if f.id == 0x702]) >= 3, scaled(3), "0x702 on B")
    on_b.wait_for(lambda c: [f for f in c if f.id == 0x701], scaled(3), "0x701 on B")
    assert set(_heartbeats(on_b, 2)) == {b"\x7f"} and set(_heartbeats(on_b, 1)) == {b"\x7f"}
    time.sleep(scaled(0.9))            # heard on B: no further switch, counting reset
    assert len(notices) == 1
    assert slave.redundancy.active_bus == "B"
    assert slave.redundancy.object["Ctoggle"] == 0
    assert _heartbeats(on_a, 2, mark_a) == [] and _heartbeats(on_a, 1, mark_a) == []

    # reset communication (sent by the master on B): the slave restarts on its
    # default bus A (told as a switch), its boot-up goes out there, and it
    # finds the master on B again after Ttoggle periods
    mark_a, mark_b = len(on_a), len(on_b)
    master.nmt.reset_communication(2)
    back = notices.wait_for(lambda c: c[1:], scaled(3), "switch back to A")
    assert back[0] == RedundancyNotice(RedundancyEvent.BUS_SWITCH, "A", 0)
    on_a.wait_for(lambda c: [f for f in c[mark_a:] if f.id == 0x702 and f.data[0] == 0],
                  scaled(3), "boot-up of node 2 on A")
    assert slave.redundancy.wait_for_bus("B", timeout=scaled(3)) == "B"
    notices.wait_count(3, scaled(3))
    assert notices.snapshot()[2] == RedundancyNotice(RedundancyEvent.BUS_SWITCH, "B", 1)
    assert b"\x00" not in _heartbeats(on_b, 2, mark_b)


def test_slave_without_master_gives_up(net, buses):
    a, b, on_a, on_b = buses
    slave = _node(net, a, 3)
    notices = Recorder()
    slave.redundancy.add_callback(notices)
    slave.redundancy.start(b, "slave", master=1, period=0.05, ttoggle=2, ntoggle=3)
    got = notices.wait_for(lambda c: [n for n in c if n.event == RedundancyEvent.NO_MASTER],
                           scaled(3), "no master")
    assert notices.snapshot() == [
        RedundancyNotice(RedundancyEvent.BUS_SWITCH, "B", 1),
        RedundancyNotice(RedundancyEvent.BUS_SWITCH, "A", 2),
        RedundancyNotice(RedundancyEvent.BUS_SWITCH, "B", 3),
        RedundancyNotice(RedundancyEvent.NO_MASTER, "B", 3)]
    assert got
    assert slave.redundancy.object == {"Bdefault": 1, "Ttoggle": 2, "Ntoggle": 3, "Ctoggle": 3}
    mark = len(on_b)
    on_b.wait_for(lambda c: [f for f in c[mark:] if f.id == 0x703], scaled(3), "0x703 on B")
    mark_a = len(on_a)
    time.sleep(scaled(0.3))            # it stays on B
    assert len(notices) == 4
    assert _heartbeats(on_a, 3, mark_a) == []


def test_errors_name_the_problem(net, buses):
    a, b, _, _ = buses
    line = _node(net, a, 4)
    with pytest.raises(CanopenFDError, match="not started"):
        line.redundancy.active_bus
    with pytest.raises(ConfigurationError, match="role must be 'master' or 'slave'"):
        line.redundancy.start(b, "boss")
    with pytest.raises(ConfigurationError, match="in-process line must be 'mem:NAME'"):
        line.redundancy.start("vcan1", "master")
    with pytest.raises(ConfigurationError, match="bus must be 'A'"):
        line.redundancy.start(b, "master", default="C")
    with pytest.raises(ConfigurationError, match="ntoggle must be an int 1..255"):
        line.redundancy.start(b, "master", ntoggle=0)
    with pytest.raises(ConfigurationError, match="node-id 1..127, got 0"):
        line.redundancy.start(b, "slave", period=0.1, ttoggle=3)
    with pytest.raises(ConfigurationError, match="period must be"):
        line.redundancy.start(b, "slave", master=1, ttoggle=3)
    with pytest.raises(CanopenFDError, match="another in-process bus"):
        line.redundancy.start(a, "master")
    line.redundancy.start(b, "slave", master=1, period=0.1)   # ttoggle 0: never switches
    with pytest.raises(CanopenFDError, match="runs on this line already"):
        line.redundancy.start(b, "slave", master=1, period=0.1)
    with pytest.raises(CanopenFDError, match="only the redundancy master selects the bus"):
        line.redundancy.select("B")
    assert line.redundancy.active_bus == "A"


def test_switch_to_a_full_bus_reports_interface_down(net, buses):
    a, b, _, _ = buses                  # b has its monitor line
    for _ in range(30):
        net.open_line(b, mode="classic")
    slave = _node(net, a, 5)
    comm = Recorder()
    slave.on_comm_event(comm)
    slave.redundancy.start(b, "slave", master=1, period=PERIOD_S, ttoggle=3, ntoggle=1)
    net.open_line(b, mode="classic")    # the 32nd line: B is full now
    got = comm.wait_for(lambda c: [e for e in c if e == CommEvent.IFACE_DOWN], scaled(3),
                        "interface down")
    assert got == [CommEvent.IFACE_DOWN]
    assert slave.redundancy.active_bus == "B"


# ------------------------------------------------ the record in the local OD

def _sdo_frames(frames, start=0):
    """(id, data) of the SDO requests to node 2 and its answers."""
    return [(f.id, bytes(f.data)) for f in frames.snapshot()[start:] if f.id in (0x602, 0x582)]


def test_record_in_the_od_is_served_on_the_bus_in_use(net, buses):
    a, b, on_a, on_b = buses
    od = demo_od("classic")
    od.add_object(redundancy_record(ttoggle=0, ntoggle=1))
    line = net.open_line(a, mode="classic")
    line.create_local_node(2, od=od)[0x1017].raw = HB_MS
    with pytest.raises(ConfigurationError, match="has the redundancy record 0x2000.*not from start"):
        line.redundancy.start(b, "slave", master=1, period=0.05, ttoggle=3)
    line.redundancy.start(b, "slave", master=1, period=0.05)
    assert line.redundancy.object == {"Bdefault": 0, "Ttoggle": 0, "Ntoggle": 1, "Ctoggle": 0}
    tool_a, tool_b = net.open_line(a, mode="classic"), net.open_line(b, mode="classic")

    # on A: reads, refused writes with their abort codes, accepted writes
    assert tool_a.sdo.upload(2, RECORD_INDEX, 3) == b"\x01"
    for sub, value, code in ((1, 2, 0x06090031), (3, 0, 0x06090032), (4, 1, 0x06010002)):
        with pytest.raises(AbortError) as refused:
            tool_a.sdo.download(2, RECORD_INDEX, sub, bytes([value]))
        assert refused.value.code == code
    assert line.redundancy.object == {"Bdefault": 0, "Ttoggle": 0, "Ntoggle": 1, "Ctoggle": 0}
    tool_a.sdo.download(2, RECORD_INDEX, 2, b"\x02")      # Ttoggle 2: from the next start
    assert line.redundancy.object["Ttoggle"] == 2
    on_a.wait_for(lambda c: len(_sdo_frames(on_a)) >= 10, scaled(3), "SDO on A")
    assert _sdo_frames(on_a)[:4] == [
        (0x602, bytes([0x40, 0x00, 0x20, 0x03, 0, 0, 0, 0])),
        (0x582, bytes([0x4F, 0x00, 0x20, 0x03, 0x01, 0, 0, 0])),
        (0x602, bytes([0x2F, 0x00, 0x20, 0x01, 0x02, 0, 0, 0])),
        (0x582, bytes([0x80, 0x00, 0x20, 0x01, 0x31, 0x00, 0x09, 0x06]))]
    assert _sdo_frames(on_a)[-1] == (0x582, bytes([0x60, 0x00, 0x20, 0x02, 0, 0, 0, 0]))
    assert _sdo_frames(on_b) == []

    # a reset communication starts the countdown: no master, so after 2
    # periods the node moves to B, gives up there (Ntoggle 1) and B becomes
    # its default; the tool on B reads that, nothing of it reaches A
    notices = Recorder()
    line.redundancy.add_callback(notices)
    tool_a.nmt.reset_communication(2)
    notices.wait_for(lambda c: [n for n in c if n.event == RedundancyEvent.NO_MASTER],
                     scaled(3), "no master")
    mark_a = len(on_a)
    assert tool_b.sdo.upload(2, RECORD_INDEX, 4) == b"\x01"      # Ctoggle
    assert tool_b.sdo.upload(2, RECORD_INDEX, 1) == b"\x01"      # Bdefault: B
    on_b.wait_for(lambda c: len(_sdo_frames(on_b)) >= 4, scaled(3), "SDO on B")
    assert _sdo_frames(on_b) == [
        (0x602, bytes([0x40, 0x00, 0x20, 0x04, 0, 0, 0, 0])),
        (0x582, bytes([0x4F, 0x00, 0x20, 0x04, 0x01, 0, 0, 0])),
        (0x602, bytes([0x40, 0x00, 0x20, 0x01, 0, 0, 0, 0])),
        (0x582, bytes([0x4F, 0x00, 0x20, 0x01, 0x01, 0, 0, 0]))]
    assert _sdo_frames(on_a, mark_a) == []
    assert line.local_node[(RECORD_INDEX, 1)].raw == 1          # the local OD says so too


def test_master_leaves_a_bus_that_goes_bus_off(net, buses):
    a, b, on_a, on_b = buses
    master = _node(net, a, 1)
    master.redundancy.start(b, "master", switch_on_failure=True)
    slave = _node(net, a, 2)
    slave.redundancy.start(b, "slave", master=1, period=PERIOD_S, ttoggle=3, ntoggle=4)
    notices = Recorder()
    master.redundancy.add_callback(notices)
    on_a.wait_for(lambda c: len([f for f in c if f.id == 0x701]) >= 3, scaled(3), "0x701 on A")
    assert _heartbeats(on_b, 1) == []

    comm = Recorder()
    master.on_comm_event(comm)
    master.simulate_comm_event(CommEvent.BUS_OFF)
    assert notices.wait_count(1, scaled(3)) == [
        RedundancyNotice(RedundancyEvent.BUS_SWITCH, "B", 0)]
    assert comm.wait_count(1, scaled(3)) == [CommEvent.BUS_OFF]
    mark_a = len(on_a)
    on_b.wait_for(lambda c: len([f for f in c if f.id == 0x701]) >= 3, scaled(3), "0x701 on B")
    assert set(_heartbeats(on_b, 1)) == {b"\x7f"}
    assert _heartbeats(on_a, 1, mark_a) == []
    assert slave.redundancy.wait_for_bus("B", timeout=scaled(3)) == "B"


def test_master_without_switch_on_failure_stays(net, buses):
    a, b, _, _ = buses
    master = _node(net, a, 1)
    with pytest.raises(ConfigurationError, match="switch_on_failure is for the master"):
        master.redundancy.start(b, "slave", master=3, period=0.1, switch_on_failure=True)
    master.redundancy.start(b, "master")
    comm = Recorder()
    master.on_comm_event(comm)
    master.simulate_comm_event(CommEvent.BUS_OFF)
    assert comm.wait_count(1, scaled(3)) == [CommEvent.BUS_OFF]
    assert master.redundancy.active_bus == "A"
    with pytest.raises(ConfigurationError, match="not a CommEvent"):
        master.simulate_comm_event(99)
    with pytest.raises(ConfigurationError, match="index must be a manufacturer index"):
        redundancy_record(index=0x1000)


def test_record_over_usdo_on_an_fd_line(net, bus_name):
    a, b = bus_name + "-fd", bus_name + "-fdB"
    od = demo_od("fd")
    od.add_object(redundancy_record(index=0x2F00, default="B", ttoggle=0, ntoggle=2))
    line = net.open_line(a, mode="fd")
    line.create_local_node(2, od=od)
    line.redundancy.start(b, "slave", master=1, period=0.1, index=0x2F00)
    assert line.redundancy.active_bus == "B"                  # the record's Bdefault
    tool = net.open_line(b, mode="fd")
    assert tool.usdo.upload(2, 0x2F00, 1) == b"\x01"
    with pytest.raises(AbortError) as refused:
        tool.usdo.download(2, 0x2F00, 3, b"\x00")
    assert refused.value.code == 0x06090032
    tool.usdo.download(2, 0x2F00, 3, b"\x05")
    assert line.redundancy.object == {"Bdefault": 1, "Ttoggle": 0, "Ntoggle": 5, "Ctoggle": 0}


def test_node_created_after_start_serves_its_record(net, buses):
    a, b, _, on_b = buses
    line = net.open_line(a, mode="classic")
    line.redundancy.start(b, "slave", master=1, period=0.05)    # no node yet: never switches
    assert line.redundancy.object["Ttoggle"] == 0
    od = demo_od("classic")
    od.add_object(redundancy_record(default="B", ttoggle=0, ntoggle=7))
    line.create_local_node(2, od=od)
    assert line.redundancy.object == {"Bdefault": 1, "Ttoggle": 0, "Ntoggle": 7, "Ctoggle": 0}
    # its boot started it over on the record's Bdefault: B
    assert line.redundancy.wait_for_bus("B", timeout=scaled(3)) == "B"
    on_b.wait_for(lambda c: [f for f in c if f.id == 0x702 and f.data[0] == 0], scaled(3),
                  "boot-up of node 2 on B")
    tool = net.open_line(b, mode="classic")
    assert tool.sdo.upload(2, RECORD_INDEX, 3) == b"\x07"


def test_record_added_to_a_running_node_after_start_is_refused(net, buses):
    """The record is read when the service starts: one added to the running node
    later would look configured while the service ignores it, so the node refuses
    it (and keeps serving everything else added)."""
    a, b, _, _ = buses
    line = net.open_line(a, mode="classic")
    od = demo_od("classic")
    line.create_local_node(2, od=od)
    line.redundancy.start(b, "slave", master=1, period=0.05)
    with pytest.raises(OdStateError) as refused:
        od.add_object(redundancy_record(ttoggle=0, ntoggle=7))
    text = str(refused.value)
    assert f"0x{RECORD_INDEX:04X}:00" in text and "redundancy record" in text
    assert "before starting" in text and RECORD_INDEX not in od
    tool = net.open_line(a, mode="classic")
    with pytest.raises(AbortError) as missing:                 # nothing half-added
        tool.sdo.upload(2, RECORD_INDEX, 0)
    assert missing.value.code == 0x06020000
    od.add_object(redundancy_record(index=0x2F00, ttoggle=0, ntoggle=7))   # another index
    assert tool.sdo.upload(2, 0x2F00, 3) == b"\x07"
