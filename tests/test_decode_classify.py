"""canopenfd.decode.classify: the service and node-ids of a frame (what the
monitor's --service and --node filters look at)."""

from __future__ import annotations

import pytest

from canopenfd.decode import SERVICES, Decoder, frame_service, service_names
from canopenfd.frame import Frame
from canopenfd.od import DataType, ODVariable, demo_od


@pytest.mark.parametrize("frame, expected", [
    (Frame(0x000, bytes([0x01, 0x05])), ("nmt", (5,))),
    (Frame(0x000, bytes([0x81, 0x00])), ("nmt", (0,))),
    (Frame(0x000, bytes([0x01])), ("nmt", ())),                       # malformed: no node
    (Frame(0x080, b""), ("sync", ())),
    (Frame(0x080, b"\x03"), ("sync", ())),
    (Frame(0x100, bytes(6)), ("time", ())),
    (Frame(0x085, bytes(8)), ("emcy", (5,))),
    (Frame(0x0FF, bytes(20), fd=True), ("emcy", (127,))),
    (Frame(0x705, b"\x05"), ("heartbeat", (5,))),
    (Frame(0x77F, b"\x00"), ("heartbeat", (127,))),
    (Frame(0x70A, rtr=True, rtr_len=1), ("heartbeat", (10,))),         # guarding request
    (Frame(0x7E5, bytes(8)), ("lss", ())),
    (Frame(0x7E4, bytes(8)), ("lss", ())),
    (Frame(0x691, bytes([1]) + bytes(7)), ("sleep", ())),
    (Frame(0x690, bytes([0x81, 2]) + bytes(6)), ("sleep", ())),
    (Frame(0x692, bytes([3]) + bytes(7)), ("sleep", ())),
    (Frame(0x071, bytes([0, 11])), ("flyma", ())),
    (Frame(0x076, b""), ("flyma", ())),
    (Frame(0x605, bytes(8)), ("sdo", (5,))),
    (Frame(0x585, bytes(8)), ("sdo", (5,))),
    (Frame(0x67F, bytes([5, 1, 1, 0]), fd=True), ("usdo", (127, 5))),  # client 127 -> node 5
    (Frame(0x585, bytes([0x7F, 0x21]), fd=True), ("usdo", (5, 127))),
    (Frame(0x605, bytes([5, 0x21]), fd=True), ("usdo", (5,))),
    (Frame(0x605, b"", fd=True), ("usdo", (5,))),
    (Frame(0x185, b"\x01"), ("tpdo", (5,))),
    (Frame(0x4FF, b"\x01"), ("tpdo", (127,))),
    (Frame(0x205, b"\x01"), ("rpdo", (5,))),
    (Frame(0x50A, b"\x01"), ("rpdo", (10,))),
    (Frame(0x181, rtr=True, rtr_len=2), ("tpdo", (1,))),
    (Frame(0x700, b"\x00"), ("other", ())),
    (Frame(0x123, b"\x00"), ("other", ())),
    (Frame(0x085, bytes(8), ext=True), ("other", ())),              # 29-bit: no default id
])
def test_frame_service_by_the_default_can_ids(frame, expected):
    assert frame_service(frame) == expected
    assert Decoder().service(frame) == expected
    assert expected[0] in SERVICES


def test_a_decoders_dictionaries_come_first_and_service_takes_no_frame_as_seen():
    od = demo_od("fd", node_id=5, pdos=1)
    od[0x1800][1].set_default(0x2A0)           # TPDO1 of node 5 on 0x2A0
    od[0x1400][1].set_default(0x321)           # RPDO1 of node 5 on 0x321
    od.add_object(ODVariable("COB-ID EMCY", 0x1014, 0, DataType.UNSIGNED32, "rw", 0x0AB))
    decoder = Decoder([(od, 5)])
    assert decoder.service(Frame(0x2A0, b"\x01")) == ("tpdo", (5,))
    assert decoder.service(Frame(0x321, b"\x01")) == ("rpdo", (5,))
    assert decoder.service(Frame(0x0AB, bytes(20), fd=True)) == ("emcy", (5,))
    assert frame_service(Frame(0x321, b"\x01")) == ("rpdo", (0x21,))   # default ids alone


def test_service_names():
    assert service_names("PDO") == ("tpdo", "rpdo")
    assert service_names(" usdo ") == ("usdo",)
    with pytest.raises(ValueError, match="unknown service 'x'.*nmt.*lss.*pdo"):
        service_names("x")
