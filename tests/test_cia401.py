"""CiA 401 generic I/O device (canopenfd.profiles.cia401) over the in-process
bus: its objects read by a master, TPDOs only when the interrupt masks,
limits or deltas say so (bytes checked through a monitor line), outputs
written by SDO/USDO and RPDO with polarity and filter mask, error values on
NMT stop and on a fault; python-canopen reads, writes and receives the
device's PDOs over python-can's virtual bus."""

from __future__ import annotations

import itertools
import os
import time

import pytest

import canopenfd
from canopenfd import ConfigurationError
from canopenfd.profiles.cia401 import Outputs, create_io_device
from helpers import Recorder, scaled, virtual_bus

NODE = 5
TPDO1, TPDO2, RPDO1, RPDO2 = 0x180 + NODE, 0x280 + NODE, 0x200 + NODE, 0x300 + NODE
_channels = itertools.count(1)


@pytest.fixture(params=["classic", "fd"])
def mode(request):
    return request.param


class Rig:
    """The I/O device (node 5, line `a`), a master line `b`, a monitor."""

    def __init__(self, net, bus, mode, **layout):
        self.mode = mode
        self.a = net.open_line(bus, mode=mode)
        self.outputs = Recorder()
        self.dev = create_io_device(self.a, NODE, on_outputs=self.outputs, **layout)
        self.b = net.open_line(bus, mode=mode)
        self.master = self.b.add_node(NODE)
        self.frames = Recorder()
        net.open_line(bus, mode=mode, monitor=True).on_frame(self.frames)

    def mark(self):
        return len(self.frames)

    def wait_frame(self, can_id, start):
        """The first frame with can_id after `start` (waits for it)."""
        def found(calls):
            got = [f for f in calls[start:] if f.id == can_id]
            return got[0] if got else None
        return self.frames.wait_for(found, scaled(3), f"a frame 0x{can_id:X}")

    def write(self, index, sub, value, size):
        self.master.write((index, sub), value.to_bytes(size, "little", signed=value < 0))

    def start(self):
        self.master.start()
        self.dev.node.wait_for_state("OPERATIONAL")


@pytest.fixture
def rig(net, bus_name, mode):
    return Rig(net, bus_name, mode)


def test_device_type_and_predefined_pdos_as_a_master_reads_them(net, bus_name):
    rig = Rig(net, bus_name, "classic", digital_inputs=12, digital_outputs=0,
              analog_inputs=0, analog_outputs=3)
    read = rig.master.read
    # profile 401, digital inputs (bit 16) and analogue outputs (bit 19) only
    assert read(0x1000) == (0x00090191).to_bytes(4, "little")
    assert read((0x6000, 0)) == b"\x02"                      # 12 inputs: 2 groups
    assert read((0x1800, 1)) == TPDO1.to_bytes(4, "little")  # valid, predefined
    assert read((0x1800, 2)) == b"\xff"
    assert [read((0x1A00, s)) for s in (0, 1, 2)] == [
        b"\x02", bytes.fromhex("08010060"), bytes.fromhex("08020060")]
    assert read((0x1401, 1)) == RPDO2.to_bytes(4, "little")
    assert read((0x1601, 3)) == bytes.fromhex("10031164")   # 0x6411:03, 16 bits
    for absent in (0x1400, 0x1801, 0x6200, 0x6401):
        with pytest.raises(canopenfd.SdoAbortError):
            read((absent, 0))


def test_any_change_and_edge_masks_decide_the_tpdo(rig):
    rig.start()
    rig.write(0x6006, 1, 0x00, 1)          # group 1: no any-change ...
    rig.write(0x6007, 1, 0x01, 1)          # ... but input 1 rising
    rig.write(0x6008, 1, 0x80, 1)          # ... and input 8 falling
    start = rig.mark()
    rig.dev.set_inputs(0x0002)             # input 2 rises: not selected
    rig.dev.set_inputs(0x0003)             # input 1 rises: TPDO1
    assert rig.wait_frame(TPDO1, start).data[:2] == bytes.fromhex("0300")
    start = rig.mark()
    rig.dev.set_inputs(0x0082)             # input 1 falls, input 8 rises: nothing
    rig.dev.set_inputs(0x0102)             # input 8 falls (and input 9: group 2, any change)
    assert rig.wait_frame(TPDO1, start).data[:2] == bytes.fromhex("0201")
    assert [f.data[:2] for f in rig.frames.snapshot()[start:] if f.id == TPDO1] == \
        [bytes.fromhex("0201")]
    assert rig.master.read((0x6000, 2)) == b"\x01"


def test_polarity_and_global_enable(rig):
    rig.start()
    rig.write(0x6002, 1, 0x0F, 1)          # inputs 1..4 inverted
    start = rig.mark()
    rig.dev.set_inputs(0x0001)
    assert rig.wait_frame(TPDO1, start).data[:2] == bytes.fromhex("0e00")
    assert rig.master.read((0x6000, 1)) == b"\x0e"
    rig.write(0x6005, 0, 0, 1)             # global interrupt enable off
    start = rig.mark()
    rig.dev.set_inputs(0xFF01)
    assert rig.master.read((0x6000, 2)) == b"\xff"       # stored all the same
    rig.write(0x6005, 0, 1, 1)
    rig.dev.set_inputs(0xFF00)             # the next change sends again
    assert rig.wait_frame(TPDO1, start).data[:2] == bytes.fromhex("0fff")


def test_analogue_limits_and_delta_fire_tpdo2(rig):
    rig.start()
    rig.write(0x6424, 1, 1000, 4)          # upper limit
    rig.write(0x6426, 1, 500, 4)           # delta
    start = rig.mark()
    rig.dev.set_analog_input(1, 1200)      # global enable off (the default): stored only
    assert rig.master.read((0x6401, 1)) == (1200).to_bytes(2, "little")
    rig.write(0x6423, 0, 1, 1)
    rig.dev.set_analog_input(1, 1400)      # 1400 from the last sent value (none: 0) > delta
    assert rig.wait_frame(TPDO2, start).data[:4] == bytes.fromhex("78050000")
    start = rig.mark()
    rig.dev.set_analog_input(1, 1700)      # 300 from 1400: nothing
    rig.dev.set_analog_input(1, 2000)      # 600 from 1400
    assert rig.wait_frame(TPDO2, start).data[:4] == bytes.fromhex("d0070000")
    rig.write(0x6421, 1, 0x01, 1)          # channel 1: upper limit only
    rig.write(0x6421, 2, 0x02, 1)          # channel 2: lower limit only
    start = rig.mark()
    rig.dev.set_analog_input(1, 900)       # leaves the region, delta not selected
    rig.dev.set_analog_input(1, 1000)      # reaches the upper limit again
    assert rig.wait_frame(TPDO2, start).data[:4] == bytes.fromhex("e8030000")
    start = rig.mark()
    rig.dev.set_analog_input(2, 0)         # not below the lower limit 0
    rig.dev.set_analog_input(2, -5)        # below it
    assert rig.wait_frame(TPDO2, start).data[:4] == bytes.fromhex("e803fbff")


def test_outputs_by_sdo_and_rpdo_with_polarity_and_filter_mask(rig):
    rig.start()
    rig.write(0x6202, 1, 0x01, 1)          # output 1 inverted
    rig.write(0x6200, 1, 0x0F, 1)
    assert rig.outputs.wait_count(1)[0] == Outputs(0x0E, (0, 0))
    rig.write(0x6208, 1, 0xF0, 1)          # only outputs 5..8 follow
    rig.b.send_frame(RPDO1, b"\x33")
    assert rig.outputs.wait_count(2)[1] == Outputs(0x3E, (0, 0))
    payload = (-300).to_bytes(2, "little", signed=True) + (0x1234).to_bytes(2, "little")
    rig.b.send_frame(RPDO2, payload)
    assert rig.outputs.wait_count(3)[2] == Outputs(0x3E, (-300, 0x1234))
    assert rig.dev.outputs == Outputs(0x3E, (-300, 0x1234))


def test_nmt_stop_sets_the_error_values(rig):
    digital, analog = Recorder(), Recorder()
    rig.dev.on_digital_outputs(digital)
    rig.dev.on_analog_output(analog)
    rig.start()
    rig.write(0x6206, 1, 0x0F, 1)          # error mode: outputs 1..4
    rig.write(0x6207, 1, 0x05, 1)          # error value 1 and 3 on
    rig.write(0x6443, 2, 0, 1)             # analogue 2 keeps its value
    rig.write(0x6444, 1, -7, 4)
    rig.write(0x6200, 1, 0xF2, 1)
    rig.write(0x6411, 1, 100, 2)
    rig.write(0x6411, 2, 200, 2)
    assert rig.outputs.wait_count(3)[2] == Outputs(0xF2, (100, 200))
    rig.master.stop()
    assert rig.outputs.wait_count(4)[3] == Outputs(0xF5, (-7, 200))
    # another callback list: its call may come after the outputs' one
    digital.wait_for(lambda calls: calls[-1:] == [0xF5], 5, "the digital outputs 0xF5")
    assert digital.snapshot()[-1] == 0xF5
    assert analog.wait_value((1, -7))


def test_fault_saturates_the_analogue_error_value(rig):
    rig.write(0x6444, 1, 100000, 4)
    rig.dev.fault()
    assert rig.dev.outputs == Outputs(0, (0x7FFF, 0))
    assert rig.outputs.wait_count(1)[0] == Outputs(0, (0x7FFF, 0))


def test_wrong_arguments_are_refused_with_the_reason(net, bus_name):
    line = net.open_line(bus_name, mode="classic")
    with pytest.raises(ConfigurationError, match=r"analog_inputs must be an int 0\.\.4 .*got 5"):
        create_io_device(line, NODE, analog_inputs=5)
    with pytest.raises(ConfigurationError, match="at least one channel"):
        create_io_device(line, NODE, digital_inputs=0, digital_outputs=0, analog_inputs=0,
                         analog_outputs=0)
    dev = create_io_device(line, NODE)
    with pytest.raises(ConfigurationError, match=r"analogue input channel must be 1\.\.2, got 3"):
        dev.set_analog_input(3, 0)
    with pytest.raises(ConfigurationError, match=r"INTEGER16 -32768\.\.32767, got 40000"):
        dev.set_analog_input(1, 40000)
    with pytest.raises(ConfigurationError, match=r"0\.\.0xFFFF \(16 digital inputs\), got 65536"):
        dev.set_inputs(0x10000)
    assert dev.outputs == Outputs(0, (0, 0))



def test_more_outputs_than_one_event_carries_are_refused_at_start(net, bus_name):
    """The core reports each output change in one event (a byte per digital
    group, an INTEGER16 per analogue channel): an OD with more is refused by
    name, and a fitting one still starts afterwards."""
    from canopenfd.od import DataType, ODArray, ODVariable, demo_od

    def od_with(groups):
        od = demo_od("classic")
        outputs = ODArray("Write output 8-bit", 0x6200)
        outputs.add_member(ODVariable("Highest sub-index supported", 0x6200, 0,
                                      DataType.UNSIGNED8, "ro", groups))
        for sub in range(1, groups + 1):
            outputs.add_member(ODVariable(f"Output group {sub}", 0x6200, sub,
                                          DataType.UNSIGNED8, "rw", 0))
        od.add_object(outputs)
        return od

    node = net.open_line(bus_name, mode="classic").create_local_node(NODE, od=od_with(65))
    with pytest.raises(ConfigurationError,
                       match=r"65 digital output groups \(0x6200\).*at most 64"):
        node.generic_io.start()
    assert not node.generic_io.running
    other = net.open_line(bus_name + "-b", mode="classic").create_local_node(NODE, od=od_with(64))
    other.generic_io.start()
    assert other.generic_io.running

# ------------------------------------------------------------------ python-canopen
canopen = pytest.importorskip("canopen")


def test_python_canopen_reads_writes_and_receives_the_pdos(tmp_path):
    channel = f"cia401-{os.getpid()}-{next(_channels)}"
    with canopenfd.Network() as net:
        line = net.open_line(bus=virtual_bus(channel), mode="classic")
        outputs = Recorder()
        dev = create_io_device(line, NODE, on_outputs=outputs)
        eds = tmp_path / "io.eds"
        dev.node.export_eds(str(eds))
        peer = canopen.Network()
        peer.connect(interface="virtual", channel=channel)
        try:
            remote = peer.add_node(NODE, canopen.import_od(str(eds), NODE))
            remote.sdo.RESPONSE_TIMEOUT = 10.0
            assert remote.sdo[0x1000].raw == 0x000F0191
            remote.tpdo.read()
            received = Recorder()
            remote.tpdo[1].add_callback(lambda m: received(bytes(m.data)))
            remote.nmt.state = "OPERATIONAL"
            dev.node.wait_for_state("OPERATIONAL")
            dev.set_inputs(0x8001)
            assert received.wait_count(1)[0] == bytes.fromhex("0180")
            assert remote.sdo[0x6000][2].raw == 0x80
            remote.sdo[0x6200][1].raw = 0xA5
            assert outputs.wait_count(1)[0] == Outputs(0xA5, (0, 0))
            remote.rpdo.read()
            remote.rpdo[2]["Write analogue output 16-bit.Write analogue output 16-bit 2"].raw = -2
            remote.rpdo[2].transmit()
            assert outputs.wait_count(2)[1] == Outputs(0xA5, (0, -2))
        finally:
            peer.disconnect()
    time.sleep(0)   # the virtual bus is shut down by conftest


def test_a_lost_master_heartbeat_sets_the_error_values(net, bus_name):
    """The communication error of the docs: the application hands fault() to
    the line's heartbeat watch of its master."""
    rig = Rig(net, bus_name, "classic")
    watch = rig.a.add_node(1, heartbeat_timeout_ms=300)
    watch.on_heartbeat_lost(rig.dev.fault)
    master = rig.b.create_local_node(1, heartbeat_ms=50)   # monitored from its boot-up
    watch.wait_for_heartbeat(timeout=scaled(5))
    rig.start()
    rig.write(0x6206, 1, 0x80, 1)          # only output 8 has an error mode ...
    rig.write(0x6207, 1, 0x80, 1)          # ... and goes on
    rig.write(0x6200, 1, 0x01, 1)
    assert rig.outputs.wait_count(1)[0] == Outputs(0x01, (0, 0))
    master.heartbeat_ms = 0                # the master falls silent
    assert rig.outputs.wait_count(2, timeout=scaled(5))[1] == Outputs(0x81, (0, 0))


def test_reset_node_keeps_the_inputs_and_outputs_follow_the_defaults(rig):
    rig.dev.set_inputs(0x0301)
    rig.dev.set_analog_input(2, -42)
    rig.write(0x6200, 1, 0x0F, 1)
    rig.write(0x6411, 1, 5, 2)
    assert rig.outputs.wait_count(2)[1] == Outputs(0x0F, (5, 0))
    booted = Recorder()
    rig.master.on_bootup(booted)
    rig.master.reset_node()
    booted.wait_count(1)
    assert rig.outputs.wait_count(3)[2] == Outputs(0, (5, 0))    # 0x6200 back to 0 ...
    assert rig.outputs.wait_count(4)[3] == Outputs(0, (0, 0))    # ... then 0x6411
    assert rig.master.read((0x6000, 1)) == b"\x01"
    assert rig.master.read((0x6000, 2)) == b"\x03"
    assert rig.master.read((0x6401, 2)) == (-42).to_bytes(2, "little", signed=True)


def test_set_inputs_is_one_runtime_call_and_reads_no_od_entry(rig, monkeypatch):
    """The channel logic and the parameters live in the core: Python makes one
    runtime call per set_inputs / set_analog_input, whatever the group count
    (every public Runtime method is counted on the calling thread; the
    dispatcher's own calls run on its thread)."""
    import threading
    from canopenfd._binding.runtime import Runtime
    rig.start()
    me, calls = threading.get_ident(), []
    for name, method in list(vars(Runtime).items()):
        if callable(method) and not name.startswith("_"):
            def counted(*args, _name=name, _method=method, **kwargs):
                if threading.get_ident() == me:
                    calls.append(_name)
                return _method(*args, **kwargs)
            monkeypatch.setattr(Runtime, name, counted)
    start = rig.mark()
    rig.dev.set_inputs(0x8001)             # two groups
    rig.dev.set_analog_input(1, 2000)
    assert calls == ["cia401_set_inputs", "cia401_set_analog_input"]
    monkeypatch.undo()
    assert rig.wait_frame(TPDO1, start).data[:2] == b"\x01\x80"
