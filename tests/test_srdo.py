"""SRDOs and the GFC (CiA 304) of local nodes from Python, over the
in-process bus: a producer node and a consumer node, the frame pair's bytes
checked on a monitor line, violations injected as raw frames from a tool
line driving the consumer into the safe state with an event that names
them; the 0x13FF signature against an independent CRC (binascii)."""

from __future__ import annotations

import binascii
import struct
import time

import pytest

from canopenfd import ConfigurationError
from canopenfd.errors import AbortError
from canopenfd.services.srdo import (CONFIG_VALID, GFC_COB_ID, SrdoConfig, SrdoNotice,
                                     SrdoState, SrdoViolation, srdo_config_writes,
                                     srdo_signature, write_srdo_config)
from helpers import Recorder, scaled

PRODUCER, CONSUMER = 5, 6
NORMAL = 0x10B                        # any odd CAN-ID 0x101..0x17F; inverted: NORMAL + 1
MAPPING = (0x62000120, 0x62010120)    # 4 bytes, normal and inverted half
PRODUCE = SrdoConfig("produce", sct_ms=20, srvt_ms=10, cob_id=NORMAL, mapping=MAPPING)
# the consumer's SCT leaves the producer's cycle some slack for a loaded machine
CONSUME = SrdoConfig("consume", sct_ms=200, srvt_ms=100, cob_id=NORMAL, mapping=MAPPING)
DATA = bytes([0x12, 0x34, 0x56, 0x78])


def inverted(data: bytes) -> bytes:
    return bytes(b ^ 0xFF for b in data)


def wait_srdo(node, accept, what, timeout=3.0):
    """Poll SRDO 1 of node until accept(status) holds; its status then."""
    deadline = time.monotonic() + scaled(timeout)
    while True:
        status = node.srdo.read(1)
        if accept(status):
            return status
        assert time.monotonic() < deadline, f"SRDO 1 stayed {status} (waited for {what})"
        time.sleep(0.005)


class Pair:
    """Producer node 5 (line p), consumer node 6 (line c), tool line t, monitor."""

    def __init__(self, net, bus):
        self.p = net.open_line(bus, mode="classic").create_local_node(PRODUCER)
        self.c = net.open_line(bus, mode="classic").create_local_node(CONSUMER)
        self.t = net.open_line(bus, mode="classic")
        self.frames = Recorder()
        net.open_line(bus, mode="classic", monitor=True).on_frame(self.frames)
        self.notices = Recorder()
        self.c.srdo.add_callback(self.notices)

    def consumer(self, config=CONSUME, **kwargs):
        self.c.srdo.start(1)
        self.c.srdo.configure(1, config, **kwargs)
        self.c.apply("start")
        self.c.wait_for_state("OPERATIONAL")

    def wait_status(self, node, state):
        return wait_srdo(node, lambda status: status.state == state, repr(state))

    def wait_notice(self, violation):
        return self.notices.wait_for(lambda calls: SrdoNotice(1, violation) in calls, 3.0,
                                     f"safe state for {violation!r}")


@pytest.fixture
def pair(net, bus_name):
    return Pair(net, bus_name)


def test_signature_is_the_crc16_of_the_parameters():
    # worked by hand: the parameter bytes little-endian, then CRC-16/XMODEM
    raw = struct.pack("<BHBIIB", 1, 20, 10, NORMAL, NORMAL + 1, 2) + \
        struct.pack("<BI", 1, MAPPING[0]) + struct.pack("<BI", 2, MAPPING[1])
    assert srdo_signature(PRODUCE) == binascii.crc_hqx(raw, 0)
    assert srdo_signature(PRODUCE) != srdo_signature(PRODUCE._replace(srvt_ms=11))
    assert PRODUCE.length == 4


def test_producer_pair_bytes_and_consumer_data(pair):
    pair.p.srdo.start(1)
    pair.p.srdo.configure(1, PRODUCE)
    pair.p.srdo.set_data(1, DATA)
    pair.consumer()
    assert pair.c.srdo.read(1).data is None           # nothing checked yet
    mark = len(pair.frames)
    pair.p.apply("start")
    got = pair.frames.wait_for(
        lambda calls: [f for f in calls[mark:] if f.id in (NORMAL, NORMAL + 1)][:6]
        if len([f for f in calls[mark:] if f.id in (NORMAL, NORMAL + 1)]) >= 6 else None,
        3.0, "three SRDO pairs")
    for k in range(0, 6, 2):
        assert (got[k].id, bytes(got[k].data)) == (NORMAL, DATA)
        assert (got[k + 1].id, bytes(got[k + 1].data)) == (NORMAL + 1, inverted(DATA))
    status = pair.wait_status(pair.c, SrdoState.RUNNING)
    assert status.data == DATA
    assert status.violation == SrdoViolation.NONE
    pair.p.srdo.set_data(1, b"\x00\xff\xa5\x01")
    wait_srdo(pair.c, lambda status: status.data == b"\x00\xff\xa5\x01", "the new data")
    assert pair.p.srdo.read(1).stats["pairs_sent"] >= 3
    assert len(pair.notices) == 0


def test_corrupted_inverted_frame_ends_in_the_safe_state(pair):
    pair.consumer()
    pair.t.send_frame(NORMAL, DATA)
    pair.t.send_frame(NORMAL + 1, inverted(DATA))
    assert pair.wait_status(pair.c, SrdoState.RUNNING).data == DATA
    pair.t.send_frame(NORMAL, DATA)
    pair.t.send_frame(NORMAL + 1, inverted(DATA)[:3] + b"\x00")
    pair.wait_notice(SrdoViolation.INVERTED_MISMATCH)
    status = pair.c.srdo.read(1)
    assert (status.state, status.violation, status.data) == \
        (SrdoState.SAFE, SrdoViolation.INVERTED_MISMATCH, None)
    # nothing wedges: the line still serves, later pairs are counted and ignored
    pair.t.send_frame(NORMAL, DATA)
    pair.t.send_frame(NORMAL + 1, inverted(DATA))
    wait_srdo(pair.c, lambda status: status.stats["ignored"] >= 2, "2 ignored frames")
    pair.c.srdo.restart(1)
    pair.t.send_frame(NORMAL, DATA)
    pair.t.send_frame(NORMAL + 1, inverted(DATA))
    assert pair.wait_status(pair.c, SrdoState.RUNNING).data == DATA


@pytest.mark.parametrize("frames, violation", [
    ([(NORMAL, DATA[:3])], SrdoViolation.WRONG_LENGTH),
    ([(NORMAL + 1, inverted(DATA))], SrdoViolation.INVERTED_UNEXPECTED),
    ([(NORMAL, DATA), (NORMAL, DATA)], SrdoViolation.INVERTED_MISSING),
    ([(NORMAL, DATA)], SrdoViolation.SRVT_EXCEEDED),
    ([], SrdoViolation.SCT_EXCEEDED),
])
def test_each_violation_is_named(pair, frames, violation):
    pair.consumer()
    for can_id, data in frames:
        pair.t.send_frame(can_id, data)
    pair.wait_notice(violation)
    assert pair.c.srdo.read(1).violation == violation


@pytest.mark.parametrize("kwargs, violation", [
    ({"valid": 0}, SrdoViolation.CONFIG_INVALID),
    ({"signature": srdo_signature(CONSUME) ^ 1}, SrdoViolation.CRC_MISMATCH),
])
def test_configuration_not_valid_never_runs(pair, kwargs, violation):
    pair.consumer(**kwargs)
    pair.wait_notice(violation)
    pair.t.send_frame(NORMAL, DATA)
    pair.t.send_frame(NORMAL + 1, inverted(DATA))
    time.sleep(scaled(0.05))
    assert pair.c.srdo.read(1).stats["pairs_valid"] == 0


def test_gfc_puts_the_consumer_in_the_safe_state(pair):
    pair.consumer()
    pair.c.srdo.gfc(True)
    pair.p.srdo.start(1)
    with pytest.raises(Exception, match="GFC is off"):
        pair.p.srdo.send_gfc()
    pair.p.srdo.gfc(True)
    mark = len(pair.frames)
    pair.p.srdo.send_gfc()
    frame = pair.frames.wait_for(
        lambda calls: next((f for f in calls[mark:] if f.id == GFC_COB_ID), None), 3.0, "GFC")
    assert bytes(frame.data) == b""
    pair.wait_notice(SrdoViolation.GFC)
    assert pair.c.srdo.gfc_stats["received"] == 1


def test_wrong_use_is_refused_with_a_clear_error(pair):
    with pytest.raises(ConfigurationError, match=r"SRDO number must be 1\.\.0 \(start\(\) first\)"):
        pair.c.srdo.configure(1, CONSUME)
    pair.c.srdo.start(1)
    with pytest.raises(ConfigurationError, match="0x1301 sub 5 .normal COB-ID.: odd"):
        pair.c.srdo.configure(1, CONSUME._replace(cob_id=0x10C))
    with pytest.raises(ConfigurationError, match="direction must be"):
        pair.c.srdo.configure(1, CONSUME._replace(direction="both"))
    with pytest.raises(ConfigurationError, match="0x1381 mapping: whole bytes"):
        pair.c.srdo.configure(1, CONSUME._replace(mapping=(0x62000120, 0x62010110)))
    pair.c.srdo.configure(1, CONSUME)
    with pytest.raises(ConfigurationError, match="SRDO 1 is not a producer"):
        pair.c.srdo.set_data(1, DATA)
    pair.c.apply("start")
    pair.c.wait_for_state("OPERATIONAL")
    with pytest.raises(Exception, match="node is operational"):
        pair.c.srdo.configure(1, CONSUME)
    assert CONFIG_VALID == 0xA5


def srdo_od(cob_default: int = 0):
    """A safety device's SRDO objects (SRDO 1, 0x13FE, 0x13FF) on the demo OD;
    cob_default: the defaults of 0x1301 sub 5 / 6 (it and it + 1; 0: both 0)."""
    from canopenfd.od import DataType, ODArray, ODRecord, ODVariable, demo_od
    U8, U16, U32 = DataType.UNSIGNED8, DataType.UNSIGNED16, DataType.UNSIGNED32
    od = demo_od("classic")
    comm = ODRecord("SRDO 1 communication parameter", 0x1301)
    comm.add_member(ODVariable("Highest sub-index supported", 0x1301, 0, U8, "ro", 6))
    for sub, name, dtype in ((1, "Direction", U8), (2, "SCT", U16), (3, "SRVT", U8),
                             (4, "Transmission type", U8), (5, "COB-ID 1", U32),
                             (6, "COB-ID 2", U32)):
        default = cob_default + sub - 5 if sub >= 5 and cob_default else 0
        comm.add_member(ODVariable(name, 0x1301, sub, dtype, "rw", default))
    od.add_object(comm)
    mapping = ODArray("SRDO 1 mapping parameter", 0x1381)
    mapping.add_member(ODVariable("Number of mapped objects", 0x1381, 0, U8, "rw", 0))
    for sub in range(1, 17):
        mapping.add_member(ODVariable(f"Mapped object {sub}", 0x1381, sub, U32, "rw", 0))
    od.add_object(mapping)
    od.add_object(ODVariable("Configuration valid", 0x13FE, 0, U8, "rw", 0))
    od.add_object(ODVariable("GFC parameter", 0x1300, 0, U8, "rw", 0))
    signature = ODArray("Safety configuration signature", 0x13FF)
    signature.add_member(ODVariable("Highest sub-index supported", 0x13FF, 0, U8, "ro", 1))
    signature.add_member(ODVariable("Signature of SRDO 1", 0x13FF, 1, U16, "rw", 0))
    od.add_object(signature)
    for index, name in ((0x6200, "Safe input"), (0x6201, "Safe input, inverted")):
        data = ODArray(name, index)      # the variables MAPPING maps (sub 1, 32 bits)
        data.add_member(ODVariable("Highest sub-index supported", index, 0, U8, "ro", 1))
        data.add_member(ODVariable(f"{name} 1", index, 1, U32, "rw", 0, pdo_mapping=True))
        od.add_object(data)
    return od


def test_config_writes_are_in_order_with_signature_and_valid_flag_last():
    writes = srdo_config_writes(1, CONSUME)
    assert writes == [
        (0x1301, 1, b"\x00"), (0x1381, 0, b"\x00"),
        (0x1381, 1, struct.pack("<I", MAPPING[0])), (0x1381, 2, struct.pack("<I", MAPPING[1])),
        (0x1381, 0, b"\x02"), (0x1301, 2, struct.pack("<H", 200)), (0x1301, 3, b"\x64"),
        (0x1301, 4, b"\xfe"), (0x1301, 5, struct.pack("<I", NORMAL)),
        (0x1301, 6, struct.pack("<I", NORMAL + 1)), (0x1301, 1, b"\x02"),
        (0x13FF, 1, struct.pack("<H", srdo_signature(CONSUME))), (0x13FE, 0, b"\xa5")]
    with pytest.raises(ConfigurationError, match="SRDO number must be 1..64"):
        srdo_config_writes(65, CONSUME)


def device_and_tool(net, bus_name):
    """A consumer device with the SRDO objects, a tool line with its remote
    node and a monitor of every frame."""
    device = net.open_line(bus_name, mode="classic").create_local_node(CONSUMER, od=srdo_od())
    tool = net.open_line(bus_name, mode="classic")
    frames = Recorder()
    net.open_line(bus_name, mode="classic", monitor=True).on_frame(frames)
    device.srdo.start(1)
    return device, tool, tool.add_node(CONSUMER), frames


def test_a_tool_writes_the_configuration_and_the_device_runs_it(net, bus_name):
    device, tool, remote, _ = device_and_tool(net, bus_name)
    signature = write_srdo_config(remote, 1, CONSUME)
    assert device[(0x13FF, 1)].raw == signature == srdo_signature(CONSUME)
    assert device[(0x13FE, 0)].raw == CONFIG_VALID
    # configure_from_od reads what the start will run, and leaves it valid
    assert device.srdo.configure_from_od(1) == CONSUME
    assert device[(0x13FE, 0)].raw == CONFIG_VALID
    device.apply("start")                 # the start configures the SRDO from the OD
    device.wait_for_state("OPERATIONAL")
    tool.send_frame(NORMAL, DATA)
    tool.send_frame(NORMAL + 1, inverted(DATA))
    wait_srdo(device, lambda status: status.data == DATA, "the tool's pair")
    # the valid pair is in the mapped variables: normal half, inverted half
    assert device[(0x6200, 1)].raw == struct.unpack("<I", DATA)[0]
    assert device[(0x6201, 1)].raw == struct.unpack("<I", inverted(DATA))[0]


def test_the_producer_sends_its_variables_into_the_consumer_s(net, bus_name):
    device, tool, remote, frames = device_and_tool(net, bus_name)       # the consumer
    sensor = net.open_line(bus_name, mode="classic").create_local_node(PRODUCER, od=srdo_od())
    sensor.srdo.start(1)
    sensor_remote = tool.add_node(PRODUCER)
    write_srdo_config(remote, 1, CONSUME)
    write_srdo_config(sensor_remote, 1, PRODUCE)
    value = 0x0BADCAFE
    sensor_remote.write((0x6200, 1), struct.pack("<I", value))
    sensor_remote.write((0x6201, 1), struct.pack("<I", value ^ 0xFFFFFFFF))
    device.apply("start")
    device.wait_for_state("OPERATIONAL")
    mark = len(frames)
    sensor.apply("start")
    pair = frames.wait_for(
        lambda calls: [f for f in calls[mark:] if f.id in (NORMAL, NORMAL + 1)][:2]
        if len([f for f in calls[mark:] if f.id in (NORMAL, NORMAL + 1)]) >= 2 else None,
        3.0, "the first pair")
    assert [(f.id, bytes(f.data)) for f in pair] == [
        (NORMAL, struct.pack("<I", value)), (NORMAL + 1, struct.pack("<I", value ^ 0xFFFFFFFF))]
    wait_srdo(device, lambda status: status.data == struct.pack("<I", value), "the pair")
    assert device[(0x6200, 1)].raw == value
    assert device[(0x6201, 1)].raw == value ^ 0xFFFFFFFF
    # set_data writes both of the producer's variables at once
    sensor.srdo.set_data(1, DATA)
    assert sensor[(0x6201, 1)].raw == struct.unpack("<I", inverted(DATA))[0]
    wait_srdo(device, lambda status: status.data == DATA, "the new data")
    deadline = time.monotonic() + scaled(3.0)
    while device[(0x6200, 1)].raw != struct.unpack("<I", DATA)[0]:
        assert time.monotonic() < deadline, "the consumer's 0x6200:01 kept its old value"
        time.sleep(0.005)


def test_0x1300_switches_the_gfc_and_gfc_writes_it(net, bus_name):
    device, tool, remote, frames = device_and_tool(net, bus_name)
    with pytest.raises(ConfigurationError, match="GFC is off"):
        device.srdo.send_gfc()
    remote.write((0x1300, 0), b"\x01")             # a tool switches it on
    mark = len(frames)
    device.srdo.send_gfc()
    got = frames.wait_for(lambda calls: [f for f in calls[mark:] if f.id == GFC_COB_ID],
                          3.0, "the GFC")
    assert bytes(got[0].data) == b""
    with pytest.raises(AbortError) as refused:
        remote.write((0x1300, 0), b"\x02")
    assert refused.value.code == 0x06090030
    device.srdo.gfc(False)                         # the application's switch is 0x1300 too
    assert device[(0x1300, 0)].raw == 0


def test_configure_on_a_node_with_the_objects_writes_them(net, bus_name):
    device, tool, remote, _ = device_and_tool(net, bus_name)
    signature = device.srdo.configure(1, CONSUME)
    assert device[(0x1301, 5)].raw == NORMAL and device[(0x1381, 2)].raw == MAPPING[1]
    assert (device[(0x13FF, 1)].raw, device[(0x13FE, 0)].raw) == (signature, CONFIG_VALID)
    with pytest.raises(ConfigurationError,
                       match=r"SRDO 1: mapping 0x1381 does not resolve .*abort 0x06040041"):
        device.srdo.configure(1, CONSUME._replace(mapping=(0x62020120, 0x62030120)))
    notices = Recorder()
    device.srdo.add_callback(notices)
    device.apply("start")
    notices.wait_for(lambda calls: SrdoNotice(1, SrdoViolation.BAD_PARAMETER) in calls, 3.0,
                     "bad parameter")


def test_the_objects_are_refused_while_operational(net, bus_name):
    device, tool, remote, _ = device_and_tool(net, bus_name)
    write_srdo_config(remote, 1, CONSUME)
    device.apply("start")
    device.wait_for_state("OPERATIONAL")
    for key, value in (((0x1301, 2), struct.pack("<H", 300)), ((0x13FE, 0), b"\x00"),
                       ((0x13FF, 1), b"\x01\x00"), ((0x1381, 0), b"\x00")):
        with pytest.raises(AbortError) as refused:
            remote.write(key, value)
        assert refused.value.code == 0x08000022, key
    assert device[(0x1301, 2)].raw == 200 and device[(0x13FE, 0)].raw == CONFIG_VALID


def test_a_changed_configuration_needs_validating_again(net, bus_name):
    device, tool, remote, frames = device_and_tool(net, bus_name)
    write_srdo_config(remote, 1, CONSUME)
    remote.write((0x1301, 3), b"\x63")              # SRVT 99 ms: 0x13FE drops to 0
    assert device[(0x13FE, 0)].raw == 0
    notices = Recorder()
    device.srdo.add_callback(notices)
    device.apply("start")
    notices.wait_for(lambda calls: SrdoNotice(1, SrdoViolation.CONFIG_INVALID) in calls, 3.0,
                     "configuration not valid")
    # validated again with a signature that is not the CRC: CRC mismatch, and
    # its EMCY on the bus (0x6300, register: generic, SRDO 1, CRC_MISMATCH)
    device.apply("pre-operational")
    device.wait_for_state("PRE-OPERATIONAL")
    remote.write((0x13FF, 1), struct.pack("<H", srdo_signature(CONSUME)))
    remote.write((0x13FE, 0), bytes([CONFIG_VALID]))
    assert device[(0x13FE, 0)].raw == CONFIG_VALID
    # the first start's EMCY (configuration not valid) must be in before the
    # mark, or a late one would be taken for the CRC mismatch's
    frames.wait_for(lambda calls: [f for f in calls if f.id == 0x80 + CONSUMER and
                                   f.data[4] == SrdoViolation.CONFIG_INVALID],
                    3.0, "the EMCY of the invalid configuration")
    mark = len(frames)
    device.apply("start")
    notices.wait_for(lambda calls: SrdoNotice(1, SrdoViolation.CRC_MISMATCH) in calls, 3.0,
                     "CRC mismatch")
    emcy = frames.wait_for(lambda calls: [f for f in calls[mark:] if f.id == 0x80 + CONSUMER],
                           3.0, "the EMCY of the CRC mismatch")
    assert bytes(emcy[0].data) == bytes([0x00, 0x63, 0x01, 1, SrdoViolation.CRC_MISMATCH,
                                         0, 0, 0])


def test_configure_from_od_without_the_objects_is_refused(pair):
    pair.c.srdo.start(1)
    with pytest.raises(ConfigurationError, match="lacks an SRDO object"):
        pair.c.srdo.configure_from_od(1)
