"""CiA 302-2 network start-up from Python (`line.manager`): our local node 1,
whose OD lists its slaves in 0x1F81, boots our slave nodes on an in-process
bus (fd and classic), checked on the wire by a monitor line (identity read,
NMT reset communication, NMT start), through the events, the hooks with their
continue calls, the blocking and the awaitable wait; a wrong device type halts
the start with error C. Against python-canopen's LocalNode as the slave on a
python-can virtual bus (classic): the manager reads its identity over SDO and
finds it operational by its heartbeat (keep-alive: error L, no reset)."""

from __future__ import annotations

import asyncio
import itertools
import os
import time
from typing import Dict

import pytest
from helpers import Recorder, scaled, virtual_bus

import canopenfd
from canopenfd import ConfigurationError
from canopenfd.od import DataType, ODArray, ODVariable, add_manager_requests, demo_od
from canopenfd.services import ManagerEvent, NetworkStartError
from canopenfd.services.manager import ManagerPhase, SlaveStatus
from canopenfd.services.store import MemoryStore

MANAGER = 1
_channels = itertools.count(1)


@pytest.fixture(params=["classic", "fd"])
def mode(request):
    return request.param


def manager_od(mode: str, startup: int, slaves: Dict[int, int],
               device_types: Dict[int, int] = None, heartbeats: Dict[int, int] = None,
               boot_time_ms: int = 0, vendors: Dict[int, int] = None,
               serials: Dict[int, int] = None, software: Dict[int, int] = None):
    """The demo OD plus the manager's objects: 0x1F80, 0x1F81/0x1F84/0x1F85/
    0x1F88/0x1F55 for nodes 1..5, 0x1F89 and consumer heartbeat times
    (0x1016:1.. = the nodes given)."""
    od = demo_od(mode)
    od.add_object(ODVariable("NMT startup", 0x1F80, 0, DataType.UNSIGNED32, "rw", startup))
    for index, name, values in ((0x1F81, "Slave assignment", slaves),
                                (0x1F84, "Device type identification", device_types or {}),
                                (0x1F85, "Vendor identification", vendors or {}),
                                (0x1F88, "Serial number", serials or {}),
                                (0x1F55, "Expected software identification", software or {})):
        array = ODArray(name, index)
        array.add_member(ODVariable("Highest sub-index supported", index, 0,
                                    DataType.UNSIGNED8, "ro", 5))
        for node in range(1, 6):
            array.add_member(ODVariable(f"{name} {node}", index, node, DataType.UNSIGNED32,
                                        "rw", values.get(node, 0)))
        od.add_object(array)
    od.add_object(ODVariable("Boot time", 0x1F89, 0, DataType.UNSIGNED32, "rw", boot_time_ms))
    for sub, (node, ms) in enumerate(sorted((heartbeats or {}).items()), start=1):
        od[0x1016][sub].default = (node << 16) | ms
    return od


def software_od(mode: str, software_id: int):
    """A slave's demo OD with its program software identification 0x1F56:01
    (stored: a reset communication reloads it from the store)."""
    od = demo_od(mode)
    array = ODArray("Program software identification", 0x1F56)
    array.add_member(ODVariable("Highest sub-index supported", 0x1F56, 0, DataType.UNSIGNED8,
                                "ro", 1))
    program = ODVariable("Program 1", 0x1F56, 1, DataType.UNSIGNED32, "rw", software_id)
    program.store = True
    array.add_member(program)
    od.add_object(array)
    return od


class Rig:
    """Manager node 1 and slave nodes on one in-process bus, a monitor of
    every frame and the manager's events."""

    def __init__(self, net, bus_name, mode, od, slaves=(2, 3), slave_heartbeat_ms=0,
                 slave_od=None, slave_store=None):
        self.mode = mode
        self.frames = Recorder()
        net.open_line(bus_name, mode=mode, monitor=True).on_frame(self.frames)
        self.slaves = {}
        for node in slaves:
            line = net.open_line(bus_name, mode=mode)
            self.slaves[node] = line.create_local_node(node, slave_heartbeat_ms,
                                                       od=slave_od or demo_od(mode),
                                                       store=slave_store)
        self.line = net.open_line(bus_name, mode=mode)
        self.node = self.line.create_local_node(MANAGER, od=od)
        self.manager = self.line.manager
        self.events = Recorder()
        self.manager.add_callback(self.events)

    def nmt_frames(self):
        return [bytes(f.data) for f in self.frames.snapshot() if f.id == 0 and not f.rtr]

    def wait_nmt(self, *wanted):
        """The NMT frames once the monitor delivered every one of `wanted` (it
        delivers asynchronously, after the slaves may have acted on them)."""
        self.frames.wait_for(lambda _: all(f in self.nmt_frames() for f in wanted), 5,
                             f"NMT frames {[f.hex() for f in wanted]}")
        return self.nmt_frames()


def kinds(events):
    return [(e.kind, e.node_id) for e in events]


def test_network_starts_mandatory_and_optional_slaves(net, bus_name, mode):
    rig = Rig(net, bus_name, mode, manager_od(mode, 0x01, {2: 0x0D, 3: 0x05}))
    assert rig.manager.phase is None
    rig.manager.start()
    rig.manager.wait_started(scaled(5))
    for node in (2, 3):
        rig.slaves[node].nmt.wait_for_state("OPERATIONAL", timeout=scaled(2))
    assert rig.node.nmt.state == "OPERATIONAL"
    assert rig.manager.phase == ManagerPhase.RUNNING
    assert rig.manager.slave(2) == (SlaveStatus.BOOTED, "")
    assert rig.manager.slave(4) == (SlaveStatus.NONE, "")
    nmt = rig.wait_nmt(bytes([0x82, 2]), bytes([0x82, 3]), bytes([0x01, 2]), bytes([0x01, 3]))
    assert bytes([0x82, 2]) in nmt and bytes([0x82, 3]) in nmt     # reset communication
    assert nmt.index(bytes([0x82, 2])) < nmt.index(bytes([0x01, 2]))   # then the start
    assert bytes([0x01, 0]) not in nmt                               # one per node
    seen = kinds(rig.manager.events)
    assert ("slave-booted", 2) in seen and ("slave-booted", 3) in seen
    assert seen.index(("slave-booted", 2)) < seen.index(("network-started", 0))
    # the device type read went out first, to each slave (classic: SDO 0x40 on
    # 0x600 + node; fd: USDO on 0x600 + our node-id, byte 0 = the server)
    if mode == "classic":
        reads = [bytes(f.data[:4]) for f in rig.frames.snapshot() if f.id == 0x602]
        assert reads[0] == bytes([0x40, 0x00, 0x10, 0x00])
    else:
        reads = [f for f in rig.frames.snapshot() if f.id == 0x600 + MANAGER]
        assert {f.data[0] for f in reads} == {2, 3}
    checked = [e for e in rig.manager.events if e.boot_event == "checked"]
    assert {(e.node_id, e.od_index, e.od_sub) for e in checked} == \
        {(2, 0x1000, 1 if mode == "fd" else 0), (3, 0x1000, 1 if mode == "fd" else 0)}
    assert all(e.matched and e.got_length == 4 for e in checked)


def test_start_all_with_one_command(net, bus_name):
    rig = Rig(net, bus_name, "classic", manager_od("classic", 0x03, {2: 0x0D, 3: 0x0D}))
    rig.manager.start()
    rig.manager.wait_started(scaled(5))
    rig.slaves[3].nmt.wait_for_state("OPERATIONAL", timeout=scaled(2))
    starts = [f for f in rig.wait_nmt(bytes([0x01, 0x00])) if f[0] == 0x01]
    assert starts == [bytes([0x01, 0x00])]


def test_wrong_device_type_halts_with_c(net, bus_name, mode):
    od = manager_od(mode, 0x01, {2: 0x0D}, device_types={2: 0x00020192})
    rig = Rig(net, bus_name, mode, od, slaves=(2,))
    rig.manager.start()
    with pytest.raises(NetworkStartError) as caught:
        rig.manager.wait_started(scaled(5))
    assert (caught.value.node_id, caught.value.error) == (2, "C")
    assert "mandatory slave 2 failed with error 'C'" in str(caught.value)
    with pytest.raises(NetworkStartError, match="error 'C'"):       # the awaited form too
        asyncio.run(rig.manager.await_started(scaled(5)))
    assert rig.manager.phase == ManagerPhase.HALTED
    assert rig.manager.slave(2)[1] == "C"
    check = next(e for e in rig.manager.events if e.boot_event == "checked")
    assert (check.expected, check.got, check.matched) == (0x00020192, 0, False)
    assert "0x1000:0" in str(check) and "expected 0x00020192" in str(check)
    assert rig.node.nmt.state == "PRE-OPERATIONAL"
    assert bytes([0x82, 2]) not in rig.nmt_frames()     # never reset


def test_hooks_answered_from_callbacks_and_awaited(net, bus_name):
    rig = Rig(net, bus_name, "fd", manager_od("fd", 0x01, {2: 0x0D}), slaves=(2,))
    answered = Recorder()

    def answer(event: ManagerEvent) -> None:
        if event.kind == "update-config":
            rig.manager.continue_config(event.node_id)
            answered(event.kind)
        elif event.kind == "ready-operational":
            rig.manager.continue_operational()
            answered(event.kind)

    rig.manager.add_callback(answer)

    async def run() -> None:
        rig.manager.start(config_hook=True, operational_hook=True)
        await asyncio.wait_for(rig.manager.started(), scaled(5))

    asyncio.run(run())
    # answer() records after its continue_operational(): the start may end first
    answered.wait_count(2)
    assert answered.snapshot() == ["update-config", "ready-operational"]
    asyncio.run(rig.manager.await_started(timeout=0))     # started already: at once
    rig.slaves[2].nmt.wait_for_state("OPERATIONAL", timeout=scaled(2))
    with pytest.raises(canopenfd.CanopenFDError, match="does not wait"):
        rig.manager.continue_operational()      # nothing waits for it any more


def test_software_update_hook_then_checked_again(net, bus_name, mode):
    """0x1F81:2 = 0x6D (check the software, update allowed): the slave's
    0x1F56:01 = 0x0101 differs from 0x1F55:2 = 0x0102, the application is asked,
    "updates" it and says done; the process checks the node again from its
    device type on and boots it. Without the hook the manager answers
    "failed": error I."""
    od = manager_od(mode, 0x01, {2: 0x6D}, software={2: 0x0102})
    rig = Rig(net, bus_name, mode, od, slaves=(2,), slave_od=software_od(mode, 0x0101),
              slave_store=MemoryStore())

    def update(event: ManagerEvent) -> None:
        if event.kind == "update-software":
            slave = rig.slaves[event.node_id]
            slave[0x1F56, 1].raw = 0x0102              # the new program, kept across
            slave.save_parameters()                    # the reset the manager sends
            rig.manager.continue_software(event.node_id)

    rig.manager.add_callback(update)
    rig.manager.start(software_hook=True)
    rig.manager.wait_started(scaled(5))
    software = [(e.got, e.matched) for e in rig.manager.events
                if e.boot_event == "checked" and e.od_index == 0x1F56]
    assert software == [(0x0101, False), (0x0102, True)]
    device_type_reads = [e for e in rig.manager.events
                         if e.boot_event == "checked" and e.od_index == 0x1000]
    assert len(device_type_reads) == 2                   # checked again after the update
    assert rig.manager.slave(2) == (SlaveStatus.BOOTED, "")
    # the same without the hook: nobody updates, I
    rig.slaves[2][0x1F56, 1].raw = 0x0101
    rig.slaves[2].save_parameters()
    rig.manager.start()
    with pytest.raises(NetworkStartError) as caught:
        rig.manager.wait_started(scaled(5))
    assert caught.value.error == "I"


def test_wrong_use_is_refused(net, bus_name):
    line = net.open_line(bus_name, mode="classic")
    with pytest.raises(ConfigurationError, match="no local node"):
        line.manager.start()
    with pytest.raises(ConfigurationError, match="start"):
        line.manager.wait_started(0.1)
    with pytest.raises(ConfigurationError, match="start"):
        asyncio.run(line.manager.await_started(0.1))
    line.create_local_node(MANAGER, od=manager_od("classic", 0x00, {2: 0x0D}))
    with pytest.raises(canopenfd.CanopenFDError, match="0x1F80 bit 0 is clear"):
        line.manager.start()
    with pytest.raises(ConfigurationError, match="parallel"):
        line.manager.start(parallel=200)
    with pytest.raises(ConfigurationError):
        line.manager.slave(0)


def _their_od(canopen):
    od = canopen.ObjectDictionary()
    device_type = canopen.objectdictionary.ODVariable("Device type", 0x1000)
    device_type.data_type = canopen.objectdictionary.UNSIGNED32
    device_type.access_type = "ro"
    device_type.default = 0x00020191
    od.add_object(device_type)
    identity = canopen.objectdictionary.ODRecord("Identity object", 0x1018)
    for sub, value in enumerate((4, 0x0000ABCD, 0x1234, 0x10002, 0x5005)):
        var = canopen.objectdictionary.ODVariable(f"sub{sub}", 0x1018, sub)
        var.data_type = (canopen.objectdictionary.UNSIGNED8 if sub == 0 else
                         canopen.objectdictionary.UNSIGNED32)
        var.access_type = "ro"
        var.default = value
        identity.add_member(var)
    od.add_object(identity)
    heartbeat = canopen.objectdictionary.ODVariable("Producer heartbeat time", 0x1017)
    heartbeat.data_type = canopen.objectdictionary.UNSIGNED16
    heartbeat.access_type = "rw"
    heartbeat.default = 50
    od.add_object(heartbeat)
    return od


def test_python_canopen_slave_kept_alive(net):
    """python-canopen's LocalNode 5, operational with 50 ms heartbeats: our
    manager (keep-alive, 0x1F81:5 = 0x1D, heartbeat consumer 300 ms) checks
    its device type, vendor-ID and serial number over SDO (python-canopen's
    server answers; product and revision are not expected, so not read),
    then sees it operational: L, no reset, no start."""
    canopen = pytest.importorskip("canopen")
    channel = f"manager-{os.getpid()}-{next(_channels)}"
    peer = canopen.Network()
    peer.connect(interface="virtual", channel=channel)
    theirs = canopen.LocalNode(5, _their_od(canopen))
    peer.add_node(theirs)
    try:
        theirs.nmt.state = "OPERATIONAL"
        theirs.nmt.start_heartbeat(50)
        od = manager_od("classic", 0x01, {5: 0x1D}, device_types={5: 0x00020191},
                        heartbeats={5: 300}, vendors={5: 0x0000ABCD}, serials={5: 0x5005})
        frames = Recorder()
        line = net.open_line(bus=virtual_bus(channel), mode="classic")
        line.create_local_node(MANAGER, od=od)
        watch = net.open_line(bus=virtual_bus(channel), mode="classic", monitor=True)
        watch.on_frame(frames)
        time.sleep(scaled(0.1))
        line.manager.start()
        line.manager.wait_started(scaled(5))
        assert line.manager.slave(5)[1] == "L"
        checked = [e for e in line.manager.events if e.boot_event == "checked"]
        assert [(e.od_index, e.od_sub, e.got, e.matched) for e in checked] == [
            (0x1000, 0, 0x00020191, True), (0x1018, 1, 0x0000ABCD, True),
            (0x1018, 4, 0x5005, True)]
        assert theirs.nmt.state == "OPERATIONAL"
        # the monitor hears the last read and answer after the start ended: wait
        frames.wait_for(lambda calls: sum(1 for f in calls if f.id == 0x605) >= 3 and
                        sum(1 for f in calls if f.id == 0x585) >= 3, 5,
                        "the three reads and their answers")
        assert not [f for f in frames.snapshot() if f.id == 0]     # no NMT at all
        reads = [bytes(f.data) for f in frames.snapshot() if f.id == 0x605]
        assert reads == [bytes([0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]),
                         bytes([0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0]),
                         bytes([0x40, 0x18, 0x10, 0x04, 0, 0, 0, 0])]
        answers = [bytes(f.data) for f in frames.snapshot() if f.id == 0x585]
        assert answers == [bytes([0x43, 0x00, 0x10, 0x00, 0x91, 0x01, 0x02, 0x00]),
                           bytes([0x43, 0x18, 0x10, 0x01, 0xCD, 0xAB, 0x00, 0x00]),
                           bytes([0x43, 0x18, 0x10, 0x04, 0x05, 0x50, 0x00, 0x00])]
    finally:
        theirs.nmt.stop_heartbeat()
        peer.disconnect()


# ------------------------------------------------------------------ configurations
def configured_rig(net, bus_name, mode, slaves_mandatory=0x0D, concise_in_od=None):
    """Manager 1 expecting stamp (DATE, TIME) on slaves 2 and 3 (both outdated:
    their 0x1020 is (1, 1)); concise_in_od: {node: bytes} in its 0x1F22."""
    from canopenfd.cli.demo_manager import DATE, TIME
    from canopenfd.od import add_node_array, add_stamp
    from canopenfd.od import ODArray
    slave_od = demo_od(mode)
    add_stamp(slave_od, (1, 1))
    od = manager_od(mode, 0x01, {2: slaves_mandatory, 3: slaves_mandatory})
    add_node_array(od, 0x1F26, "Expected configuration date", {2: DATE, 3: DATE}, highest=5)
    add_node_array(od, 0x1F27, "Expected configuration time", {2: TIME, 3: TIME}, highest=5)
    if concise_in_od:
        array = ODArray("Concise DCF", 0x1F22)
        array.add_member(ODVariable("Highest sub-index supported", 0x1F22, 0,
                                    DataType.UNSIGNED8, "ro", 5))
        for node in range(1, 6):
            array.add_member(ODVariable(f"Concise DCF {node}", 0x1F22, node, DataType.DOMAIN,
                                        "rw", concise_in_od.get(node, b"")))
        od.add_object(array)
    return Rig(net, bus_name, mode, od, slave_od=slave_od), (DATE, TIME)


def test_start_up_writes_the_configurations_it_was_given(net, bus_name, mode):
    """start(configurations=...) and 0x1F22: the manager writes each outdated
    slave's concise DCF itself and stamps 0x1020 with 0x1F26/0x1F27."""
    from canopenfd.od.concise import build_concise
    rig, stamp = configured_rig(net, bus_name, mode, concise_in_od={
        2: build_concise([(0x1017, 0, (300).to_bytes(2, "little"))])})
    rig.manager.start(configurations={3: build_concise([(0x1017, 0, (400).to_bytes(2, "little"))])})
    rig.manager.wait_started(scaled(10))
    assert rig.slaves[2][0x1017].raw == 300 and rig.slaves[3][0x1017].raw == 400
    for node in (2, 3):
        assert (rig.slaves[node][0x1020][1].raw, rig.slaves[node][0x1020][2].raw) == stamp
    rig.events.wait_for(lambda calls: "update-config" in [e.kind for e in calls], 5,
                        "the update-config event (its callback may run after the start)")


def test_a_refused_configuration_ends_the_boot_with_j(net, bus_name, mode):
    from canopenfd.od.concise import build_concise
    from canopenfd.services.manager import NetworkStartError
    rig, _ = configured_rig(net, bus_name, mode)
    rig.manager.start(configurations={2: build_concise([(0x3000, 1, b"\x01")]),
                                      3: build_concise([(0x1017, 0, b"\x10\x00")])})
    with pytest.raises(NetworkStartError, match="slave 2 failed with error 'J'"):
        rig.manager.wait_started(scaled(10))
    assert rig.slaves[2][0x1020][1].raw == 1      # not stamped


# ------------------------------------------------------------------ 0x1F82 request NMT
def test_request_nmt_object_commands_slaves(net, bus_name, mode):
    """A tool writes the manager's 0x1F82:n over SDO/USDO: the manager sends
    that NMT command (bytes checked on the bus); 0x80 = all nodes; a node
    outside the network list or an unknown state is refused with 0x06090030;
    the entry reads as the slave's last state heard."""
    from canopenfd import AbortError
    od = manager_od(mode, 0x01, {2: 0x05, 3: 0x05})
    array = ODArray("Request NMT", 0x1F82)
    array.add_member(ODVariable("Highest sub-index supported", 0x1F82, 0, DataType.UNSIGNED8,
                                "ro", 0x80))
    for sub in (*range(1, 6), 0x80):
        array.add_member(ODVariable(f"Request NMT {sub}", 0x1F82, sub, DataType.UNSIGNED8,
                                    "rw", 0))
    od.add_object(array)
    rig = Rig(net, bus_name, mode, od, slave_heartbeat_ms=50)
    rig.manager.start()
    rig.manager.wait_started(scaled(10))
    tool = net.open_line(bus_name, mode=mode).add_node(MANAGER, od=od)
    tool.write("Request NMT.Request NMT 3", 4)              # stop node 3
    rig.slaves[3].nmt.wait_for_state("STOPPED", timeout=scaled(2))
    tool.write("Request NMT.Request NMT 128", 127)          # all nodes pre-operational
    rig.slaves[2].nmt.wait_for_state("PRE-OPERATIONAL", timeout=scaled(2))
    wanted = [bytes([0x02, 3]), bytes([0x80, 0])]            # the start-up sent neither
    # the monitor hears the frames on the dispatcher thread: wait for both
    rig.frames.wait_for(lambda _: all(f in rig.nmt_frames() for f in wanted), 5,
                        "the two NMT commands")
    sent = [f for f in rig.nmt_frames() if f in wanted]
    assert sent == wanted
    with pytest.raises(AbortError) as refused:
        tool.write("Request NMT.Request NMT 4", 5)          # not in the network list
    assert refused.value.code == 0x06090030
    with pytest.raises(AbortError) as refused:
        tool.write("Request NMT.Request NMT 2", 9)          # no such state
    assert refused.value.code == 0x06090030
    deadline = time.monotonic() + scaled(2)
    while tool.read("Request NMT.Request NMT 3") != 0x7F and time.monotonic() < deadline:
        time.sleep(0.02)                                    # its heartbeat says pre-op
    assert tool.read("Request NMT.Request NMT 3") == 0x7F


CONF = 0x666E6F63   # "conf"


def test_python_canopen_tool_writes_request_nmt(net):
    """python-canopen's SDO client (a real tool, classic, python-can virtual
    bus) writes our manager's 0x1F82:2: the NMT stop for node 2 goes on the
    wire; written with two bytes instead of one, the CiA 301 abort
    0x06070012 (length too high) comes back on 0x581, and no NMT."""
    canopen = pytest.importorskip("canopen")
    channel = f"manager-1f82-{os.getpid()}-{next(_channels)}"
    od = manager_od("classic", 0x01, {2: 0x05})
    add_manager_requests(od, 5, dcf_nodes=3, dcf_room=64)
    frames = Recorder()
    watch = net.open_line(bus=virtual_bus(channel), mode="classic", monitor=True)
    watch.on_frame(frames)
    slave = net.open_line(bus=virtual_bus(channel), mode="classic").create_local_node(
        2, 50, od=demo_od("classic"))
    line = net.open_line(bus=virtual_bus(channel), mode="classic")
    line.create_local_node(MANAGER, od=od)
    line.manager.start()
    line.manager.wait_started(scaled(5))
    slave.nmt.wait_for_state("OPERATIONAL", timeout=scaled(2))
    tool = canopen.Network()
    tool.connect(interface="virtual", channel=channel)
    try:
        manager = canopen.RemoteNode(MANAGER, canopen.ObjectDictionary())
        tool.add_node(manager)
        manager.sdo.RESPONSE_TIMEOUT = scaled(1)
        manager.sdo.download(0x1F82, 2, b"\x04")                  # stop node 2
        slave.nmt.wait_for_state("STOPPED", timeout=scaled(2))
        frames.wait_for(lambda calls: any(f.id == 0 and bytes(f.data) == b"\x02\x02"
                                          for f in calls), 5, "NMT stop node 2")
        before = [bytes(f.data) for f in frames.snapshot() if f.id == 0]
        with pytest.raises(canopen.SdoAbortedError) as refused:
            manager.sdo.download(0x1F82, 2, b"\x05\x00")         # U8 written as 2 bytes
        assert refused.value.code == 0x06070012
        abort = bytes([0x80, 0x82, 0x1F, 0x02, 0x12, 0x00, 0x07, 0x06])
        frames.wait_for(lambda calls: any(f.id == 0x581 and bytes(f.data) == abort
                                          for f in calls), 5, "the abort frame")
        assert [bytes(f.data) for f in frames.snapshot() if f.id == 0] == before
        assert slave.nmt.state.label == "STOPPED"
    finally:
        tool.disconnect()


def test_request_node_guarding_object(net, bus_name, mode):
    """A tool writes 0x1F83:2 = 1: the manager guards node 2 (its 0x1F81 guard
    time 100 ms): remote frames on 0x702 on the wire, the entry reads 1; 0
    stops them. On fd lines (no remote frames) the write is refused with
    0x06010000."""
    from canopenfd import AbortError
    od = manager_od(mode, 0x01, {2: (100 << 16) | (3 << 8) | 0x05, 3: 0x05})
    add_manager_requests(od, 5, dcf_nodes=3, dcf_room=64)
    rig = Rig(net, bus_name, mode, od, slaves=(2,))
    rig.manager.start()
    rig.manager.wait_started(scaled(10))
    tool = net.open_line(bus_name, mode=mode).add_node(MANAGER, od=od)
    if mode == "fd":
        with pytest.raises(AbortError) as refused:
            tool.write("Request node guarding.Request node guarding 2", 1)
        assert refused.value.code == 0x06010000
        return
    # the start-up guards node 2 itself (a guard time, no heartbeat) once its
    # boot process ends: node 2 is optional, so that may come after the start
    deadline = time.monotonic() + scaled(5)
    while (tool.read("Request node guarding.Request node guarding 2") != 1
           and time.monotonic() < deadline):
        time.sleep(0.02)
    assert tool.read("Request node guarding.Request node guarding 2") == 1
    tool.write("Request node guarding.Request node guarding 2", 0)
    assert tool.read("Request node guarding.Request node guarding 2") == 0
    time.sleep(scaled(0.05))     # a request on its way is still carried
    sent = sum(1 for f in rig.frames.snapshot() if f.id == 0x702 and f.rtr)
    time.sleep(scaled(0.35))     # > 3 guard times: none more
    assert sum(1 for f in rig.frames.snapshot() if f.id == 0x702 and f.rtr) <= sent + 1
    tool.write("Request node guarding.Request node guarding 2", 1)
    rig.frames.wait_for(lambda calls: sum(1 for f in calls if f.id == 0x702 and f.rtr)
                        >= sent + 3, 5, "three more guarding requests to node 2")
    assert tool.read("Request node guarding.Request node guarding 2") == 1
    answers = [f for f in rig.frames.snapshot() if f.id == 0x702 and not f.rtr]
    assert answers and all(len(f.data) == 1 for f in answers)   # node 2 answers each
    with pytest.raises(AbortError) as refused:
        tool.write("Request node guarding.Request node guarding 3", 1)   # no guard time
    assert refused.value.code == 0x08000022
    with pytest.raises(AbortError) as refused:
        tool.write("Request node guarding.Request node guarding 4", 1)   # not a slave
    assert refused.value.code == 0x06090030


def test_configuration_request_object(net, bus_name, mode):
    """CiA 302-3 configuration request: a tool downloads a concise DCF into the
    manager's 0x1F22:2, then writes "conf" to 0x1F25:2: the manager downloads
    it to node 2 (the SDO/USDO request carrying 0x1017 = 250 on the wire)
    and stamps 0x1020 from 0x1F26/0x1F27; event 'configured'. A wrong
    signature is refused with 0x08000020, a node without a slave entry with
    0x06090030."""
    from canopenfd import AbortError
    from canopenfd.cli.demo_manager import DATE, TIME
    from canopenfd.od import add_node_array, add_stamp
    from canopenfd.od.concise import build_concise
    slave_od = demo_od(mode)
    add_stamp(slave_od, (1, 1))
    od = manager_od(mode, 0x01, {2: 0x05})
    add_node_array(od, 0x1F26, "Expected configuration date", {2: DATE}, highest=5)
    add_node_array(od, 0x1F27, "Expected configuration time", {2: TIME}, highest=5)
    add_manager_requests(od, 5, dcf_nodes=3, dcf_room=64)
    rig = Rig(net, bus_name, mode, od, slaves=(2,), slave_od=slave_od)
    rig.manager.start()
    rig.manager.wait_started(scaled(10))
    tool = net.open_line(bus_name, mode=mode).add_node(MANAGER, od=od)
    tool.write("Concise DCF.Concise DCF 2", build_concise([(0x1017, 0, (250).to_bytes(2, "little"))]))
    with pytest.raises(AbortError) as refused:
        tool.write("Configuration request.Configuration request 2", 0x65766173)   # "save"
    assert refused.value.code == 0x08000020
    with pytest.raises(AbortError) as refused:
        tool.write("Configuration request.Configuration request 3", CONF)
    assert refused.value.code == 0x06090030
    tool.write("Configuration request.Configuration request 2", CONF)
    done = rig.events.wait_for(lambda calls: [e for e in calls if e.kind == "configured"], 5,
                               "the configuration request's end")
    assert done[0].node_id == 2 and done[0].error == ""
    assert rig.slaves[2][0x1017].raw == 250
    assert (rig.slaves[2][0x1020][1].raw, rig.slaves[2][0x1020][2].raw) == (DATE, TIME)
    # the monitor may hear the download after the manager reported it: wait
    if mode == "classic":
        download = bytes([0x2B, 0x17, 0x10, 0x00, 0xFA, 0x00, 0, 0])
        rig.frames.wait_for(lambda calls: any(f.id == 0x602 and bytes(f.data) == download
                                              for f in calls), 5, "the 0x1017 download")
        requests = [bytes(f.data) for f in rig.frames.snapshot() if f.id == 0x602]
        assert download in requests
    else:
        # USDO expedited download from client node 1 (CAN-ID 0x601) to node 2:
        # 0 dest, 1 cs 0x01, 2 session, 3 sub, 4-5 index, 6 type, 7 N, 8.. data
        def usdo_downloads(calls):
            return [bytes(f.data) for f in calls if f.id == 0x601 and
                    bytes(f.data)[:2] == b"\x02\x01" and bytes(f.data)[3:6] == b"\x00\x17\x10"]
        rig.frames.wait_for(usdo_downloads, 5, "the USDO download of 0x1017")
        usdo = usdo_downloads(rig.frames.snapshot())
        assert [(d[7], d[8:10]) for d in usdo] == [(2, b"\xfa\x00")]


def test_configuration_request_takes_a_dcf_as_large_as_its_domain(net, bus_name):
    """The runtime gives the manager room for the largest 0x1F22 domain: a
    concise DCF of 170 entries (1534 bytes, more than the core's 1024-byte
    default) is downloaded whole, entry by entry."""
    from canopenfd.od.concise import build_concise
    od = manager_od("classic", 0x01, {2: 0x05})
    add_manager_requests(od, 5, dcf_nodes=2, dcf_room=2048)
    rig = Rig(net, bus_name, "classic", od, slaves=(2,))
    rig.manager.start()
    rig.manager.wait_started(scaled(10))
    entries = [(0x1017, 0, (100 + i).to_bytes(2, "little")) for i in range(170)]
    dcf = build_concise(entries)
    assert len(dcf) > 1024
    tool = net.open_line(bus_name, mode="classic").add_node(MANAGER, od=od)
    tool.write("Concise DCF.Concise DCF 2", dcf)
    tool.write("Configuration request.Configuration request 2", CONF)
    done = rig.events.wait_for(lambda calls: [e for e in calls if e.kind == "configured"], 10,
                               "the configuration request's end")
    assert done[0].error == "", str(done[0])
    assert rig.slaves[2][0x1017].raw == 269
    rig.frames.wait_for(lambda calls: sum(1 for f in calls if f.id == 0x602 and
                                          bytes(f.data)[:4] == b"\x2b\x17\x10\x00") == 170,
                        5, "170 downloads of 0x1017 to node 2")
