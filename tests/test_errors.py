"""Error-status bits and the EMCY code table of the local node (node.errors,
node.emcy.define / raise_defined / clear_defined / count) over the in-process
bus: the EMCY bytes on the bus, 0x1001, 0x1003 and the bit array 0x2100 as a
tool reads them by SDO/USDO, the stack's own bits (heartbeat lost), the error
behaviour 0x1029:01 for a communication-class bit, and refused use."""

from __future__ import annotations

import time

import pytest
from helpers import Recorder, scaled
from test_services import NODE, Rig, pdo_od

from canopenfd import ConfigurationError, NmtState
from canopenfd.od import DataType, ODArray, ODVariable
from canopenfd.services.errors import ErrorBit, ErrorRegister

EMCY = 0x80 + NODE
U8, U32 = DataType.UNSIGNED8, DataType.UNSIGNED32


def error_od(mode, behaviour=None):
    """The test OD plus 0x1003 (3 entries), 0x2100 (the bits) and, when
    given, 0x1029:01 (error behaviour on a communication error)."""
    od = pdo_od(mode)
    history = ODArray("Pre-defined error field", 0x1003)
    history.add_member(ODVariable("Number of errors", 0x1003, 0, U8, "rw", 0))
    for sub in range(1, 4):
        history.add_member(ODVariable(f"Standard error field {sub}", 0x1003, sub, U32, "ro", 0))
    od.add_object(history)
    od.add_object(ODVariable("Error status bits", 0x2100, 0, DataType.OCTET_STRING, "ro",
                             bytes(16)))
    if behaviour is not None:
        array = ODArray("Error behaviour", 0x1029)
        array.add_member(ODVariable("Highest sub-index supported", 0x1029, 0, U8, "ro", 1))
        array.add_member(ODVariable("Communication error", 0x1029, 1, U8, "rw", behaviour))
        od.add_object(array)
    return od


@pytest.fixture(params=["classic", "fd"])
def mode(request):
    return request.param


def rig_of(net, bus_name, mode, behaviour=None):
    rig = Rig(net, bus_name, mode, od=False)
    rig.me = net.open_line(bus_name, mode=mode).create_local_node(
        NODE + 1, od=error_od(mode, behaviour))
    rig.me.errors.expose(0x2100)
    return rig


def emcy_bytes(fd, code, register, bit, info, occurred=True):
    """EMCY of an error bit: code (classic reset: 0), register, bit, info;
    fd: logical device 0, CiA 301, status occurred / removed, no time stamp."""
    sent = code if occurred or fd else 0
    head = sent.to_bytes(2, "little") + bytes([register, bit]) + info.to_bytes(2, "little")
    head += bytes(2)
    if fd:
        head += bytes([0]) + (301).to_bytes(2, "little") + bytes([0x10 if occurred else 0])
        head += bytes(8)
    return head


def test_report_once_reset_with_wire_bytes_0x1001_0x1003_0x2100(net, bus_name, mode):
    rig = rig_of(net, bus_name, mode)
    me, fd, emcy_id = rig.me, mode == "fd", 0x80 + NODE + 1
    tool = rig.b.add_node(NODE + 1, od=error_od(mode))
    transfer = tool.usdo if fd else tool.sdo
    me.errors.define(20, 0x2310, ErrorRegister.CURRENT)
    me.errors.define(21, 0x4210, ErrorRegister.TEMPERATURE)
    assert me.errors.table[20] == (0x2310, 0x03)
    assert me.errors.table[ErrorBit.BUS_OFF] == (0x8140, 0x11)     # the stack's own
    start = rig.mark()
    assert me.errors.report(20, 0x1234) is True
    assert me.errors.report(20, 0x5555) is False                   # repetition: not sent
    assert me.errors.report(21) is True
    sent = rig.wait_frames(emcy_id, 2, start=start)
    assert [f.data for f in sent] == [emcy_bytes(fd, 0x2310, 0x03, 20, 0x1234),
                                      emcy_bytes(fd, 0x4210, 0x0B, 21, 0)]
    assert (me.errors.count(20), me.errors.count(21), me.errors.count(22)) == (2, 1, 0)
    assert me.errors.set_bits == [20, 21] and me.errors.register == 0x0B
    assert me.emcy.error_register == 0x0B
    # what a tool reads over the network
    bits = bytes([0, 0, 0x30]) + bytes(13)
    assert transfer.upload((0x2100, 0)) == bits == me.errors.bits
    assert transfer.upload((0x1001, 0)) == b"\x0b"
    assert me.emcy.history == [0x00154210, 0x34142310]
    assert transfer.upload((0x1003, 2)) == (0x34142310).to_bytes(4, "little")

    assert me.errors.reset(20, 0x0042) is True
    assert me.errors.reset(20) is False                            # clear already
    reset = rig.wait_frames(emcy_id, 3, start=start)[2]
    assert reset.data == emcy_bytes(fd, 0x2310, 0x09, 20, 0x0042, occurred=False)
    assert transfer.upload((0x1001, 0)) == b"\x09"
    assert me.errors.is_set(21) and not me.errors.is_set(20)
    assert len(rig.wait_frames(emcy_id, 3, start=start)) == 3      # nothing more was sent


def test_emcy_code_table_by_application_id(net, bus_name):
    rig = rig_of(net, bus_name, "classic")
    me = rig.me
    remote = rig.b.add_node(NODE + 1)
    got = Recorder()
    remote.emcy.add_callback(got)
    app_voltage = 17
    me.emcy.define(app_voltage, 0x3110, ErrorRegister.VOLTAGE)
    assert me.emcy.raise_defined(app_voltage, 7) is True
    assert me.emcy.raise_defined(app_voltage) is False
    assert me.emcy.is_raised(app_voltage) and me.emcy.count(app_voltage) == 2
    first = got.wait_count(1)[0]
    assert (first.code, first.register, first.data) == (0x3110, 0x05, b"\x11\x07\x00\x00\x00")
    assert me.emcy.clear_defined(app_voltage) is True
    assert got.wait_count(2)[1].is_reset
    assert not me.emcy.is_raised(app_voltage) and me.emcy.error_register == 0


def test_conditions_decide_the_register(net, bus_name):
    me = rig_of(net, bus_name, "classic").me
    me.errors.define(16, 0x2310, ErrorRegister.CURRENT)
    me.errors.define(17, 0xFF01, ErrorRegister.MANUFACTURER)
    me.errors.set_condition(1, [16, 17])          # "current" also for bit 17
    me.errors.report(17)
    assert me.errors.register == 0x83 and me.emcy.error_register == 0x83
    me.errors.set_condition(0, [])                # generic only from other sources
    assert me.errors.register == 0x82


def test_stack_detected_heartbeat_loss_sets_its_bit(net, bus_name):
    rig = rig_of(net, bus_name, "classic")
    me = rig.me
    tool = rig.b.add_node(NODE + 1, od=error_od("classic"))
    other = net.open_line(bus_name, mode="classic").create_local_node(7, heartbeat_ms=10)
    me[0x1016][1].raw = 7 << 16 | 60
    start = rig.mark()
    rig.wait_frames(0x707, 3, start=start)
    other.heartbeat_ms = 0
    emcy = rig.wait_frames(0x80 + NODE + 1, 1, start=start)[0]
    assert emcy.data[:3] == bytes([0x30, 0x81, 0x11])     # the stack's EMCY, as before
    assert me.errors.set_bits == [ErrorBit.LIFE_GUARD]
    assert me.errors.count(ErrorBit.LIFE_GUARD) == 1
    assert tool.sdo.upload((0x2100, 0)) == bytes([0x04]) + bytes(15)
    # a reset forgets the cause (0x1016 reloads): its bit clears, the count stays
    me.apply("reset-communication")                     # through the runtime's mailbox
    deadline = time.monotonic() + scaled(5)
    while me.errors.set_bits:
        assert time.monotonic() < deadline, "the reset did not clear the bit"
        time.sleep(0.01)
    assert me.errors.count(ErrorBit.LIFE_GUARD) == 1


@pytest.mark.parametrize("behaviour, after", [(None, NmtState.PRE_OPERATIONAL),
                                              (1, NmtState.OPERATIONAL),
                                              (2, NmtState.STOPPED)])
def test_communication_bit_applies_error_behaviour(net, bus_name, behaviour, after):
    me = rig_of(net, bus_name, "classic", behaviour).me
    me.errors.define(30, 0x8100, ErrorRegister.COMMUNICATION)
    me.errors.define(31, 0x5000)
    me.apply("start")
    me.wait_for_state(NmtState.OPERATIONAL)
    me.errors.report(31)                          # not communication: no change
    assert me.state == NmtState.OPERATIONAL
    me.errors.report(30)
    assert me.state == after


def test_wrong_use_is_refused_with_node_and_bit(net, bus_name):
    line = net.open_line(bus_name, mode="classic")
    me = line.create_local_node(NODE, boot=False)
    with pytest.raises(ConfigurationError, match="bit 16 of local node 5.*not booted"):
        me.errors.report(16)
    me.boot()
    with pytest.raises(ConfigurationError, match="bit 16 of local node 5.*not defined"):
        me.errors.report(16)
    with pytest.raises(ConfigurationError, match=r"bit 3 .*stack's own.*are 16\.\.127"):
        me.errors.report(ErrorBit.BUS_OFF)
    with pytest.raises(ConfigurationError, match="got 128"):
        me.errors.define(128, 0x1000)
    with pytest.raises(ConfigurationError, match="code must be an int 1"):
        me.errors.define(16, 0)
    with pytest.raises(ConfigurationError, match="bit 6"):
        me.errors.define(16, 0x1000, 0x40)
    with pytest.raises(ConfigurationError, match="register bit 6 is reserved"):
        me.errors.set_condition(6, [16])
    me.errors.define(16, 0x1000)
    me.errors.report(16)
    with pytest.raises(ConfigurationError, match="bit 16 of local node 5.*is set: reset it"):
        me.errors.define(16, 0x1001)
    with pytest.raises(ConfigurationError, match="code must be an int 0..0xffff"):
        me.errors.reset(16, -1)

def test_expose_needs_an_octet_string_and_happens_once(net, bus_name):
    me = net.open_line(bus_name, mode="fd").create_local_node(NODE, od=error_od("fd"))
    with pytest.raises(ConfigurationError, match="0x2101:00 must be an OCTET_STRING.*None"):
        me.errors.expose(0x2101)
    with pytest.raises(ConfigurationError, match="0x1001:00 must be an OCTET_STRING"):
        me.errors.expose(0x1001)
    me.errors.expose(0x2100)
    with pytest.raises(ConfigurationError, match="cannot be shown in 0x2100:00: .*already"):
        me.errors.expose(0x2100)
    # the demo OD's 0x2100 is a domain: not taken over unless asked (and then refused)
    demo = net.open_line(bus_name + "-demo", mode="fd").create_local_node(
        NODE, od=pdo_od("fd"))
    with pytest.raises(ConfigurationError, match="0x2100:00 must be an OCTET_STRING"):
        demo.errors.expose()
