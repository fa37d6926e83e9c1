"""The frame decoder (NMT, heartbeat, USDO, classic SDO) and the NMT enums: pure
Python (but for the monitor command test). SYNC, TIME, EMCY, PDOs and node guarding:
test_decode_services.py."""

from __future__ import annotations

import importlib
import re
import threading
import time
from pathlib import Path

import pytest
from helpers import scaled

from canopenfd import ConfigurationError, Frame, NmtCommand, NmtState
from canopenfd.decode import (
    USDO_COMMANDS,
    Decoder,
    decode,
    describe,
    format_raw,
    hex_bytes,
    meaning,
    usdo_type_name,
)
from canopenfd.errors import ABORT_TEXT, USDO_ABORT_TEXT
from canopenfd.frame import fd_len_round


def fd(can_id, data, brs=True):
    return Frame(can_id, bytes(data), fd=True, brs=brs)


@pytest.mark.parametrize("frame, text", [
    (Frame(0x000, b"\x01\x05"), "NMT start node 5"),
    (Frame(0x000, b"\x02\x00"), "NMT stop all"),
    (Frame(0x000, b"\x80\x7f"), "NMT pre-operational node 127"),
    (Frame(0x000, b"\x81\x00"), "NMT reset-node all"),
    (Frame(0x000, b"\x82\x00"), "NMT reset-comm all"),
    (Frame(0x705, b"\x00"), "boot-up node 5"),
    (Frame(0x705, b"\x05"), "heartbeat node 5 OPERATIONAL"),
    (Frame(0x77F, b"\x7f"), "heartbeat node 127 PRE-OPERATIONAL"),
    (Frame(0x705, b"\x04"), "heartbeat node 5 STOPPED"),
    (Frame(0x705, b"\x85"), "node guarding reply node 5 OPERATIONAL toggle 1"),
    (Frame(0x181, bytes(range(1, 9))), "TPDO1 node 1 01 02 03 04 05 06 07 08"),
    (Frame(0x080, b""), "SYNC"),
    (Frame(0x6E0, bytes(range(1, 9))), "0x6E0 [8] 01 02 03 04 05 06 07 08"),
    (Frame(0x1ABCDEF0, b"\x01", ext=True), "0x1ABCDEF0 [1] 01"),
    (Frame(0x705, b"", rtr=True, rtr_len=1), "node guarding request node 5"),
    (Frame(0x123, b"", rtr=True, rtr_len=8), "0x123 [8] RTR"),
    (fd(0x705, b"\x00"), "boot-up node 5 [FD BRS]"),
    (fd(0x000, b"\x01\x05", brs=False), "NMT start node 5 [FD]"),
    (fd(0x201, bytes(12)), "RPDO1 node 1 " + " ".join(["00"] * 12) + " [FD BRS]"),
    (fd(0x6E1, bytes(12)), "0x6E1 [12] " + " ".join(["00"] * 12) + " [FD BRS]"),
])
def test_decode(frame, text):
    assert decode(frame) == text


@pytest.mark.parametrize("frame, text", [
    (Frame(0x000, b"\x01"), "NMT malformed: 1 bytes, expected 2 (01)"),
    (Frame(0x000, b"\x01\x05\x00"), "NMT malformed: 3 bytes, expected 2 (01 05 00)"),
    (Frame(0x000, b"\x55\x05"), "NMT malformed: unknown command 0x55 for node 5"),
    (Frame(0x000, b"\x01\xc8"), "NMT start node 200 malformed: node-id outside 0..127"),
    (Frame(0x705, b"\x05\x00"), "heartbeat node 5 malformed: 2 bytes, expected 1"),
    (Frame(0x705, b"\x33"), "heartbeat node 5 malformed: state 0x33"),
    (Frame(0x705, b"\x80"), "node guarding reply node 5 toggle 1 malformed: state 0x00"),
    (Frame(0x705, b"\xb3"), "node guarding reply node 5 toggle 1 malformed: state 0x33"),
    (Frame(0x700, b"\x05"), "heartbeat malformed: CAN-ID 0x700 (node-id 0)"),
])
def test_decode_marks_malformed_frames(frame, text):
    assert decode(frame) == text
    assert "malformed" in decode(frame)


def test_describe_and_raw():
    assert format_raw(Frame(0x705, b"\x7f")) == "0x705 [1] 7F"
    assert describe(fd(0x705, b"\x7f")).split() == [
        "0x705", "[1]", "7F", "heartbeat", "node", "5", "PRE-OPERATIONAL", "[FD", "BRS]"]
    assert describe(Frame(0x6E1, b"\x01")) == "0x6E1 [1] 01"
    assert describe(Frame(0x181, b"\x01")) == "0x181 [1] 01".ljust(30) + " TPDO1 node 1 01"


def test_decode_accepts_python_can_messages_and_tuples():
    can = pytest.importorskip("can")
    msg = can.Message(arbitration_id=0x705, data=b"\x05", is_extended_id=False, is_fd=True,
                      bitrate_switch=True)
    assert decode(msg) == "heartbeat node 5 OPERATIONAL [FD BRS]"
    assert decode((0x000, b"\x02\x05")) == "NMT stop node 5"


def test_nmt_state_names():
    assert NmtState.parse("OPERATIONAL") is NmtState.OPERATIONAL
    assert NmtState.parse("PRE-OPERATIONAL") is NmtState.PRE_OPERATIONAL
    assert NmtState.parse("pre operational") is NmtState.PRE_OPERATIONAL
    assert NmtState.parse("preop") is NmtState.PRE_OPERATIONAL
    assert NmtState.parse("Initializing") is NmtState.INITIALISING
    assert NmtState.parse(0x7F) is NmtState.PRE_OPERATIONAL
    assert NmtState.PRE_OPERATIONAL.label == "PRE-OPERATIONAL"
    assert str(NmtState.STOPPED) == "STOPPED"
    assert NmtState.OPERATIONAL == "OPERATIONAL" and NmtState.OPERATIONAL != "STOPPED"
    assert NmtState.OPERATIONAL == 5 and NmtState.OPERATIONAL != "bogus"
    assert {NmtState.STOPPED: 1}[4] == 1                  # still hashes like an int
    with pytest.raises(ConfigurationError, match="NMT state 'RUNNING' unknown"):
        NmtState.parse("RUNNING")
    with pytest.raises(ConfigurationError, match="NMT state 0x12 unknown"):
        NmtState.parse(0x12)
    with pytest.raises(ValueError):                        # ConfigurationError is a ValueError
        NmtState.parse(True)


def test_nmt_command_names():
    assert [c.value for c in NmtCommand] == [0x01, 0x02, 0x80, 0x81, 0x82]
    assert NmtCommand.parse("start") is NmtCommand.START
    assert NmtCommand.parse("reset-comm") is NmtCommand.RESET_COMMUNICATION
    assert NmtCommand.parse("RESET COMMUNICATION") is NmtCommand.RESET_COMMUNICATION
    assert NmtCommand.parse("RESET") is NmtCommand.RESET_NODE
    assert NmtCommand.parse("OPERATIONAL") is NmtCommand.START          # python-canopen
    assert NmtCommand.parse("PRE-OPERATIONAL") is NmtCommand.PRE_OPERATIONAL
    assert NmtCommand.parse("STOPPED") is NmtCommand.STOP
    assert NmtCommand.parse(0x81) is NmtCommand.RESET_NODE
    assert NmtCommand.START.target is NmtState.OPERATIONAL
    assert NmtCommand.RESET_NODE.label == "reset-node"
    with pytest.raises(ConfigurationError, match="NMT command 0x55 unknown"):
        NmtCommand.parse(0x55)


# ------------------------------------------------------------------ USDO


def usdo(can_id, *parts, pad=True):
    """An FD+BRS frame of the concatenated parts (ints and bytes), padded with
    zeros to a valid CAN FD length as a line sends it."""
    data = b"".join(bytes([p]) if isinstance(p, int) else bytes(p) for p in parts)
    if pad:
        data += bytes(fd_len_round(len(data)) - len(data))
    return Frame(can_id, data, fd=True, brs=True)


SEG = bytes(range(60))


@pytest.mark.parametrize("frame, text", [
    # 0x01 / 0x21 / 0x11 / 0x31: expedited both ways
    (usdo(0x605, 3, 0x01, 7, 0x01, 0x00, 0x20, 0x07, 4, b"\x01\x02\x03\x04"),
     "USDO 5->3 sid 7 download expedited 0x2000:01 U32 N=4 01 02 03 04"),
    (usdo(0x605, 3, 0x01, 7, 0x02, 0x00, 0x20, 0x05, 1, 0xAB),        # padded to 12
     "USDO 5->3 sid 7 download expedited 0x2000:02 U8 N=1 AB"),
    (usdo(0x605, 3, 0x01, 7, 0x00, 0x17, 0x10, 0x06, 0),
     "USDO 5->3 sid 7 download expedited 0x1017:00 U16 N=0"),
    (usdo(0x583, 5, 0x21, 7, 0x01, 0x00, 0x20),
     "USDO 3->5 sid 7 download expedited response 0x2000:01"),
    (usdo(0x605, 3, 0x11, 9, 0x00, 0x08, 0x10),
     "USDO 5->3 sid 9 upload request 0x1008:00"),
    (usdo(0x583, 5, 0x31, 9, 0x00, 0x08, 0x10, 0x09, 5, b"hello"),
     "USDO 3->5 sid 9 upload expedited 0x1008:00 VISIBLE_STRING N=5 68 65 6C 6C 6F"),
    (usdo(0x583, 5, 0x31, 9, 0x00, 0x08, 0x10, 0x03, 2, b"\xff\xff"),
     "USDO 3->5 sid 9 upload expedited 0x1008:00 I16 N=2 FF FF"),
    (usdo(0x583, 5, 0x31, 9, 0x00, 0x08, 0x10, 0x11, 56, bytes(56)),
     "USDO 3->5 sid 9 upload expedited 0x1008:00 R64 N=56 " + " ".join(["00"] * 56)),
    # 0x02 / 0x22 / 0x03 / 0x23 / 0x04 / 0x24: segmented download
    (usdo(0x605, 3, 0x02, 7, 0x00, 0x00, 0x30, 0x0F, 0, (1000).to_bytes(4, "little")),
     "USDO 5->3 sid 7 download initiate 0x3000:00 DOMAIN size 1000"),
    (usdo(0x583, 5, 0x22, 7, 0x00, 0x00, 0x30),
     "USDO 3->5 sid 7 download initiate response 0x3000:00"),
    (usdo(0x605, 3, 0x03, 7, 0, SEG), "USDO 5->3 sid 7 download segment #0 60 B"),
    (usdo(0x583, 5, 0x23, 7, 0), "USDO 3->5 sid 7 download segment response #0"),
    (usdo(0x605, 3, 0x04, 7, 40, SEG[:40]), "USDO 5->3 sid 7 download last segment 40 B"),
    (usdo(0x583, 5, 0x24, 7), "USDO 3->5 sid 7 download last segment response"),
    # 0x32 / 0x13 / 0x33 / 0x34: segmented upload
    (usdo(0x583, 5, 0x32, 8, 0x00, 0x00, 0x30, 0x0F, 0, b"\xff\xff\xff\xff"),
     "USDO 3->5 sid 8 upload initiate 0x3000:00 DOMAIN size 0xFFFFFFFF (unknown)"),
    (usdo(0x583, 5, 0x32, 8, 0x00, 0x08, 0x10, 0x09, 0, (0).to_bytes(4, "little")),
     "USDO 3->5 sid 8 upload initiate 0x1008:00 VISIBLE_STRING size 0"),
    (usdo(0x605, 3, 0x13, 8, 12), "USDO 5->3 sid 8 upload segment request #12"),
    (usdo(0x583, 5, 0x33, 7, 12, SEG), "USDO 3->5 sid 7 upload segment #12 60 B"),
    (usdo(0x583, 5, 0x34, 8, 0), "USDO 3->5 sid 8 upload last segment 0 B"),
    (usdo(0x583, 5, 0x34, 8, 60, SEG), "USDO 3->5 sid 8 upload last segment 60 B"),
    # 0x06 / 0x26 / 0x07 / 0x08 / 0x28: bulk download
    (usdo(0x605, 3, 0x06, 7, 0x00, 0x00, 0x30, 0x0F, 0, (65536).to_bytes(4, "little")),
     "USDO 5->3 sid 7 bulk download initiate 0x3000:00 DOMAIN size 65536"),
    (usdo(0x583, 5, 0x26, 7, 0x00, 0x00, 0x30, 5, 0),
     "USDO 3->5 sid 7 bulk accept 0x3000:00 pacing 5 (500 us)"),
    (usdo(0x583, 5, 0x26, 7, 0x00, 0x00, 0x30, 0, 0),
     "USDO 3->5 sid 7 bulk accept 0x3000:00 pacing 0 (none)"),
    (usdo(0x583, 5, 0x26, 7, 0x00, 0x00, 0x30, 0x02, 0x01),           # 258 = 25.8 ms
     "USDO 3->5 sid 7 bulk accept 0x3000:00 pacing 258 (25.8 ms)"),
    (usdo(0x605, 3, 0x07, 7, 255, SEG), "USDO 5->3 sid 7 bulk segment #255 60 B"),
    (usdo(0x605, 3, 0x08, 7, 60, SEG), "USDO 5->3 sid 7 bulk last segment 60 B"),
    (usdo(0x605, 3, 0x08, 7, 1, 0xEE), "USDO 5->3 sid 7 bulk last segment 1 B"),
    (usdo(0x583, 5, 0x28, 7), "USDO 3->5 sid 7 bulk last segment response"),
    # 0x16 / 0x36 / 0x37 / 0x38 / 0x17: bulk upload (our layout)
    (usdo(0x605, 3, 0x16, 9, 0x00, 0x00, 0x21, 64, 0),
     "USDO 5->3 sid 9 bulk upload request 0x2100:00 window 64"),
    (usdo(0x605, 3, 0x16, 9, 0x00, 0x00, 0x21, 0, 0),
     "USDO 5->3 sid 9 bulk upload request 0x2100:00 window 0 (invalid: 0)"),
    (usdo(0x583, 5, 0x36, 9, 0x00, 0x00, 0x21, 0x0F, 0, (70000).to_bytes(4, "little")),
     "USDO 3->5 sid 9 bulk upload initiate 0x2100:00 DOMAIN size 70000"),
    (usdo(0x583, 5, 0x37, 9, 31, SEG), "USDO 3->5 sid 9 bulk upload segment #31 60 B"),
    (usdo(0x605, 3, 0x17, 9, 31), "USDO 5->3 sid 9 bulk upload ack #31"),
    (usdo(0x583, 5, 0x38, 9, 10, SEG[:10]), "USDO 3->5 sid 9 bulk upload last segment 10 B"),
    # a segment shorter than 64 bytes (a sender with a smaller MTU): len - 4 data bytes
    (usdo(0x583, 5, 0x33, 7, 3, SEG[:28]), "USDO 3->5 sid 7 upload segment #3 28 B (short)"),
    (usdo(0x605, 3, 0x03, 7, 0, SEG[:44]), "USDO 5->3 sid 7 download segment #0 44 B (short)"),
    # 0x7F: aborts both ways, known and unknown codes
    (usdo(0x605, 3, 0x7F, 7, 0x01, 0x00, 0x20, 0x33),
     "USDO 5->3 sid 7 ABORT 0x2000:01 0x33 object does not exist"),
    (usdo(0x583, 5, 0x7F, 7, 0x00, 0x00, 0x30, 0x70),
     "USDO 3->5 sid 7 ABORT 0x3000:00 0x70 USDO server busy"),
    (usdo(0x583, 5, 0x7F, 7, 0x00, 0x00, 0x30, 0x14),
     "USDO 3->5 sid 7 ABORT 0x3000:00 0x14 invalid segment counter"),
    (usdo(0x583, 5, 0x7F, 7, 0x00, 0x00, 0x30, 0x99),
     "USDO 3->5 sid 7 ABORT 0x3000:00 0x99 unknown abort code"),
    (usdo(0x583, 5, 0x7F, 7, 0x00, 0x00, 0x30, 0x00),
     "USDO 3->5 sid 7 ABORT 0x3000:00 0x00 unknown abort code"),
    # broadcast, node-id limits, session-ID 0 and 255
    (usdo(0x601, 0, 0x11, 1, 0x00, 0x18, 0x10), "USDO 1->bcast sid 1 upload request 0x1018:00"),
    (usdo(0x67F, 0, 0x01, 0, 0x00, 0x17, 0x10, 0x06, 2, b"\x64\x00"),
     "USDO 127->bcast sid 0 download expedited 0x1017:00 U16 N=2 64 00"),
    (usdo(0x5FF, 127, 0x21, 255, 0x00, 0x17, 0x10),
     "USDO 127->127 sid 255 download expedited response 0x1017:00"),
    (usdo(0x581, 0, 0x7F, 2, 0x00, 0x00, 0x10, 0x33),
     "USDO 1->bcast sid 2 ABORT 0x1000:00 0x33 object does not exist"),
    # trailing bytes beyond the in-frame size (padding) are not data
    (usdo(0x583, 5, 0x34, 8, 2, b"\x01\x02\xff\xff", pad=False),
     "USDO 3->5 sid 8 upload last segment 2 B"),
])
def test_usdo_frames(frame, text):
    assert meaning(frame) == text
    assert decode(frame) == text + " [FD BRS]"


@pytest.mark.parametrize("frame, text", [
    (usdo(0x605, pad=False), "USDO 5 malformed: 0 bytes, expected at least 3"),
    (usdo(0x605, 3, 0x01, pad=False), "USDO 5 malformed: 2 bytes, expected at least 3 (03 01)"),
    (usdo(0x605, 3, 0x55, 7), "USDO 5->3 sid 7 unknown command 0x55"),
    (usdo(0x605, 3, 0x05, 7, 0, 0, 0x20), "USDO 5->3 sid 7 unknown command 0x05"),  # multi sub
    # a routed abort (0x7F | 0x80) too short for its extension and mux
    (usdo(0x583, 5, 0xFF, 7, 0, 0, 0x20, 0x10),
     "USDO 3->5 sid 7 routed 32:16->0:0 ABORT malformed: 3 bytes, expected 7"),
    (usdo(0x605, 3, 0x01, 7, 0x01, 0x00, pad=False),
     "USDO 5->3 sid 7 download expedited malformed: 5 bytes, expected 8 or more"),
    (usdo(0x605, 3, 0x01, 7, 0x01, 0x00, 0x20, pad=False),          # mux there, no type/N
     "USDO 5->3 sid 7 download expedited 0x2000:01 malformed: 6 bytes, expected 8 or more"),
    (usdo(0x605, 3, 0x01, 7, 0x01, 0x00, 0x20, 0x07, 57, bytes(56)),
     "USDO 5->3 sid 7 download expedited 0x2000:01 malformed: N=57 > 56"),
    (usdo(0x583, 5, 0x31, 7, 0x01, 0x00, 0x20, 0x07, 255, bytes(56)),
     "USDO 3->5 sid 7 upload expedited 0x2000:01 malformed: N=255 > 56"),
    (usdo(0x605, 3, 0x01, 7, 0x01, 0x00, 0x20, 0x07, 8, b"\x01\x02\x03\x04"),
     "USDO 5->3 sid 7 download expedited 0x2000:01 malformed: 12 bytes, N=8 needs 16"),
    (usdo(0x605, 3, 0x02, 7, 0x00, 0x00, 0x30, 0x0F, 0),
     "USDO 5->3 sid 7 download initiate 0x3000:00 malformed: 8 bytes, expected 12"),
    (usdo(0x605, 3, 0x06, 7, 0x00, 0x00, 0x30, pad=False),
     "USDO 5->3 sid 7 bulk download initiate 0x3000:00 malformed: 6 bytes, expected 12"),
    (usdo(0x605, 3, 0x03, 7, 0, pad=False),
     "USDO 5->3 sid 7 download segment malformed: 4 bytes, expected 5 or more"),
    (usdo(0x605, 3, 0x07, 7, pad=False),
     "USDO 5->3 sid 7 bulk segment malformed: 3 bytes, expected 5 or more"),
    (usdo(0x605, 3, 0x16, 7, 0x00, 0x00, 0x21, 4, pad=False),
     "USDO 5->3 sid 7 bulk upload request 0x2100:00 malformed: 7 bytes, expected 8"),
    (usdo(0x605, 3, 0x04, 7, 61, SEG),
     "USDO 5->3 sid 7 download last segment malformed: n=61 > 60"),
    (usdo(0x605, 3, 0x08, 7, 200, SEG),
     "USDO 5->3 sid 7 bulk last segment malformed: n=200 > 60"),
    (usdo(0x583, 5, 0x34, 7, 10, b"\x01\x02", pad=False),
     "USDO 3->5 sid 7 upload last segment malformed: 6 bytes, n=10 needs 14"),
    (usdo(0x583, 5, 0x34, 7, pad=False),
     "USDO 3->5 sid 7 upload last segment malformed: 3 bytes, expected 4 or more"),
    (usdo(0x605, 3, 0x13, 7, pad=False),
     "USDO 5->3 sid 7 upload segment request malformed: 3 bytes, expected 4"),
    (usdo(0x605, 3, 0x11, 7, 0, pad=False),
     "USDO 5->3 sid 7 upload request malformed: 4 bytes, expected 6"),
    (usdo(0x605, 3, 0x7F, 7, 0x00, 0x00, 0x30, pad=False),
     "USDO 5->3 sid 7 ABORT 0x3000:00 malformed: 6 bytes, expected 7"),
    (usdo(0x583, 5, 0x26, 7, 0x00, 0x00, 0x30, 5, pad=False),
     "USDO 3->5 sid 7 bulk accept 0x3000:00 malformed: 7 bytes, expected 8"),
])
def test_usdo_malformed_frames(frame, text):
    assert meaning(frame) == text
    assert "malformed" in text or "unknown command" in text


def test_usdo_type_names_come_from_the_od_data_types():
    assert [usdo_type_name(c) for c in (0x01, 0x02, 0x07, 0x08, 0x0A, 0x0C, 0x0F, 0x16, 0x1B)] == [
        "BOOLEAN", "I8", "U32", "R32", "OCTET_STRING", "TIME_OF_DAY", "DOMAIN", "U24", "U64"]
    assert usdo_type_name(0x00) == "type 0x00"
    assert usdo_type_name(0x0E) == "type 0x0E"
    frame = usdo(0x605, 3, 0x01, 7, 0, 0, 0x20, 0x0E, 1, 1)
    assert meaning(frame) == "USDO 5->3 sid 7 download expedited 0x2000:00 type 0x0E N=1 01"


def test_classic_frames_on_usdo_ids_are_classic_sdo():
    # USDO is CAN FD only: a classic frame on a USDO CAN-ID is a CiA 301 SDO frame.
    classic = Frame(0x605, bytes([3, 0x01, 7, 0x01, 0x00, 0x20, 0x07, 4]))
    assert meaning(classic) == "SDO 5 rx download segment t=0 last 6 B 01 07 01 00 20 07"
    assert describe(classic) == ("0x605 [8] 03 01 07 01 00 20 07 04 "
                                 "SDO 5 rx download segment t=0 last 6 B 01 07 01 00 20 07")
    assert decode(Frame(0x583, bytes([5, 0x7F, 7, 0, 0, 0x30, 0x33]))) == \
        "SDO 3 tx malformed: 7 bytes, expected 8 (05 7F 07 00 00 30 33)"
    assert decode((0x605, bytes([3, 0x11, 7, 0, 0, 0x20]))) == \
        "SDO 5 rx malformed: 6 bytes, expected 8 (03 11 07 00 00 20)"
    # FD frames just outside the ranges, and 29-bit ids, are not USDO
    for can_id in (0x580, 0x600, 0x680):
        assert meaning(usdo(can_id, 3, 0x11, 7, 0, 0, 0x20)) == ""
    assert meaning(usdo(0x57F, 3, 0x11, 7, 0, 0, 0x20)) == "RPDO4 node 127 03 11 07 00 00 20"
    ext = Frame(0x605, bytes([3, 0x11, 7, 0, 0, 0x20]), fd=True, ext=True)
    assert decode(ext) == "0x00000605 [6] 03 11 07 00 00 20 [FD]"


def test_usdo_describe_keeps_the_monitor_line_short():
    frame = usdo(0x583, 5, 0x33, 7, 12, SEG)
    assert describe(frame) == ("0x583 [64] 05 33 07 0C 00 01 02 03 04 05 06 07 ... "
                               "USDO 3->5 sid 7 upload segment #12 60 B [FD BRS]")
    short = usdo(0x583, 5, 0x31, 7, 0x01, 0x00, 0x20, 0x07, 4, b"\x01\x02\x03\x04")  # 12: all
    assert describe(short) == ("0x583 [12] 05 31 07 01 00 20 07 04 01 02 03 04 "
                               "USDO 3->5 sid 7 upload expedited 0x2000:01 U32 N=4 01 02 03 04 "
                               "[FD BRS]")
    unknown = fd(0x6E1, bytes(20))                                  # undecoded: every byte
    assert describe(unknown) == "0x6E1 [20] " + " ".join(["00"] * 20) + " [FD BRS]"
    assert format_raw(frame, 2) == "0x583 [64] 05 33 ..."


def test_usdo_python_can_message():
    can = pytest.importorskip("can")
    msg = can.Message(arbitration_id=0x605, is_extended_id=False, is_fd=True, bitrate_switch=False,
                      data=bytes([3, 0x7F, 7, 0x01, 0x00, 0x20, 0x33, 0]))
    assert decode(msg) == "USDO 5->3 sid 7 ABORT 0x2000:01 0x33 object does not exist [FD]"
    assert decode((0x605, bytes([3, 0x13, 7, 1]), 0x01)) == \
        "USDO 5->3 sid 7 upload segment request #1 [FD]"


# The C codec is the source of truth: its command specifiers, layouts (with
# their minimum lengths) and abort codes must all be known here.
_HEADER = Path(__file__).resolve().parents[1] / "csrc" / "include" / "canopenfd" / "co_usdo.h"
_LAYOUT_NAMES = {"MUX": "mux", "EXPEDITED": "expedited", "INITIATE": "initiate",
                 "SEGMENT": "segment", "LAST": "last", "COUNTER": "counter", "END": "end",
                 "ABORT": "abort", "BULK_ACCEPT": "bulk accept", "BULK_REQUEST": "bulk request"}


def _c_enum(prefix):
    text = _HEADER.read_text()
    return {name: int(value, 16)
            for name, value in re.findall(rf"\b{prefix}(\w+)\s*=\s*(0x[0-9A-Fa-f]+)", text)}


@pytest.mark.skipif(not _HEADER.exists(), reason="needs the source tree (csrc/include/canopenfd/co_usdo.h)")
def test_usdo_tables_match_the_c_codec():
    decode_module = importlib.import_module("canopenfd.decode.usdo")

    commands = _c_enum("CO_USDO_CS_")
    assert commands, "no command specifiers found in co_usdo.h"
    unsupported = {commands.pop("REMOTE_ABORT")}       # remote: 0x7F | 0x80, decoded as 0x7F
    assert set(USDO_COMMANDS) == set(commands.values())
    assert not unsupported & set(USDO_COMMANDS)

    aborts = _c_enum("CO_USDO_ABORT_")
    assert aborts.pop("NONE") == 0
    assert set(USDO_ABORT_TEXT) == set(aborts.values())

    layouts = re.findall(r"CO_USDO_LAYOUT_(\w+),?\s*/\*\s*(\d+)(?:\+[Nn])?:([^*]*)\*/",
                         _HEADER.read_text())
    assert {name for name, _, _ in layouts} == set(_LAYOUT_NAMES)
    for name, length, comment in layouts:
        layout = _LAYOUT_NAMES[name]
        assert decode_module._HEAD_LEN[layout] == int(length), name
        for cs in re.findall(r"\b0x([0-9A-Fa-f]{2})\b", comment):
            assert USDO_COMMANDS[int(cs, 16)][1] == layout, (name, cs)
    assert {layout for _, layout in USDO_COMMANDS.values()} == set(_LAYOUT_NAMES.values())


try:
    import hypothesis
except ImportError:  # pragma: no cover - the test extra brings it
    hypothesis = None

if hypothesis is not None:
    import atexit
    import shutil
    import tempfile

    from hypothesis import given, settings
    from hypothesis import strategies as st
    from hypothesis.configuration import set_hypothesis_home_dir

    # Nothing written into the working directory (./.hypothesis).
    _HOME = tempfile.mkdtemp(prefix="canopenfd-hypothesis-")
    atexit.register(shutil.rmtree, _HOME, True)
    set_hypothesis_home_dir(_HOME)

    _USDO_IDS = st.one_of(st.integers(0x581, 0x5FF), st.integers(0x601, 0x67F))
    # Fully random bytes, and frames whose command specifier is a known one
    # (so every layout sees short, long and nonsense bodies).
    _BODIES = st.one_of(
        st.binary(max_size=64),
        st.tuples(st.integers(0, 255), st.sampled_from(sorted(USDO_COMMANDS)),
                  st.binary(max_size=62)).map(lambda t: bytes([t[0], t[1]]) + t[2]),
    )

    @settings(max_examples=500, deadline=None, database=None)
    @given(can_id=_USDO_IDS, data=_BODIES, fd_frame=st.booleans(), brs=st.booleans())
    def test_usdo_random_frames_never_raise(can_id, data, fd_frame, brs):
        frame = Frame(can_id, data, fd=fd_frame, brs=brs and fd_frame)
        text = decode(frame)
        line = describe(frame)
        assert isinstance(text, str) and isinstance(line, str) and "\n" not in text
        if fd_frame:
            assert text.startswith("USDO ")
            if len(data) >= 3 and data[1] & 0x7F not in USDO_COMMANDS:
                assert f"unknown command 0x{data[1]:02X}" in text   # routed: 0x80 set
        else:
            assert text.startswith("SDO ")              # classic: CiA 301 SDO
            if len(data) != 8:
                assert f"malformed: {len(data)} bytes, expected 8" in text


# ------------------------------------------------------------------ classic SDO


def sdo(can_id, *parts, pad=True):
    """A classic frame of the concatenated parts (ints and bytes), padded with
    zeros to the 8 bytes of an SDO frame."""
    data = b"".join(bytes([p]) if isinstance(p, int) else bytes(p) for p in parts)
    if pad:
        data += bytes(8 - len(data))
    return Frame(can_id, data)


def le32(value):
    return value.to_bytes(4, "little")


SEVEN = bytes(range(1, 8))


@pytest.mark.parametrize("frame, text", [
    # client -> server (0x600 + server node-id): "rx"
    # ccs 1: initiate download, expedited with 4/3/2/1 bytes, without size, segmented
    (sdo(0x605, 0x23, 0x00, 0x20, 0x01, 1, 2, 3, 4),
     "SDO 5 rx initiate download expedited 0x2000:01 4 B 01 02 03 04"),
    (sdo(0x605, 0x27, 0x00, 0x20, 0x01, 1, 2, 3, 0xEE),
     "SDO 5 rx initiate download expedited 0x2000:01 3 B 01 02 03"),
    (sdo(0x605, 0x2B, 0x17, 0x10, 0x00, 0x2C, 0x01),
     "SDO 5 rx initiate download expedited 0x1017:00 2 B 2C 01"),
    (sdo(0x605, 0x2F, 0x00, 0x20, 0xFF, 0x7F),
     "SDO 5 rx initiate download expedited 0x2000:FF 1 B 7F"),
    (sdo(0x605, 0x22, 0x00, 0x20, 0x01, 1, 2, 3, 4),
     "SDO 5 rx initiate download expedited 0x2000:01 size not indicated 01 02 03 04"),
    (sdo(0x605, 0x21, 0x00, 0x30, 0x00, le32(1000)),
     "SDO 5 rx initiate download 0x3000:00 size 1000"),
    (sdo(0x605, 0x20, 0x00, 0x30, 0x00), "SDO 5 rx initiate download 0x3000:00 size not indicated"),
    # ccs 0: download segment (t, n unused bytes, c last)
    (sdo(0x605, 0x00, SEVEN), "SDO 5 rx download segment t=0 7 B 01 02 03 04 05 06 07"),
    (sdo(0x605, 0x10, SEVEN), "SDO 5 rx download segment t=1 7 B 01 02 03 04 05 06 07"),
    (sdo(0x605, 0x0B, SEVEN), "SDO 5 rx download segment t=0 last 2 B 01 02"),
    (sdo(0x605, 0x1F, SEVEN), "SDO 5 rx download segment t=1 last 0 B"),
    # ccs 2 / 3: initiate upload, upload segment request
    (sdo(0x605, 0x40, 0x08, 0x10, 0x00), "SDO 5 rx initiate upload 0x1008:00"),
    (sdo(0x605, 0x60), "SDO 5 rx upload segment request t=0"),
    (sdo(0x605, 0x70), "SDO 5 rx upload segment request t=1"),
    # ccs / scs 7: SDO networking through a gateway (layout: docs/protocol-notes.md)
    (sdo(0x601, 0xE0, 3, 0, 5),
     "SDO 1 rx network indication: network 3 node 5 or block segment #96 last"),
    (sdo(0x581, 0xE0, 3, 0, 5),
     "SDO 1 tx network indication confirmed: network 3 node 5 or block segment #96 last"),
    (sdo(0x601, 0xE0),
     "SDO 1 rx network indication: back to the gateway itself or block segment #96 last"),
    # ccs 4: abort
    (sdo(0x605, 0x80, 0x00, 0x21, 0x00, le32(0x05040000)),
     "SDO 5 rx ABORT 0x2100:00 0x05040000 SDO protocol timed out"),
    # ccs 5: block upload (initiate, end response, ack, start)
    (sdo(0x605, 0xA4, 0x00, 0x21, 0x00, 127, 0),
     "SDO 5 rx initiate block upload 0x2100:00 blksize 127 pst 0 crc"),
    (sdo(0x605, 0xA0, 0x00, 0x21, 0x03, 10, 21),
     "SDO 5 rx initiate block upload 0x2100:03 blksize 10 pst 21"),
    (sdo(0x605, 0xA1), "SDO 5 rx end block upload response"),
    (sdo(0x605, 0xA2, 127, 127), "SDO 5 rx block upload ack seqno 127 blksize 127"),
    (sdo(0x605, 0xA2, 0, 1), "SDO 5 rx block upload ack seqno 0 blksize 1"),
    (sdo(0x605, 0xA3), "SDO 5 rx start block upload"),
    # ccs 6: block download (initiate, end)
    (sdo(0x605, 0xC6, 0x00, 0x21, 0x00, le32(100000)),
     "SDO 5 rx initiate block download 0x2100:00 size 100000 crc"),
    (sdo(0x605, 0xC0, 0x00, 0x21, 0x00),
     "SDO 5 rx initiate block download 0x2100:00 size not indicated"),
    (sdo(0x605, 0xCD, 0x2B, 0x1A), "SDO 5 rx end block download n=3 crc 0x1A2B"),
    (sdo(0x605, 0xC1), "SDO 5 rx end block download n=0 crc 0x0000"),
    # ccs 7: none; alone it may still be a block segment (c=1)
    (sdo(0x605, 0xE0),
     "SDO 5 rx network indication: back to the gateway itself or block segment #96 last"),
    (sdo(0x605, 0xFF), "SDO 5 rx unknown command 0xFF or block segment #127 last"),

    # server -> client (0x580 + server node-id): "tx"
    # scs 3 / 1: download responses
    (sdo(0x585, 0x60, 0x17, 0x10, 0x00), "SDO 5 tx initiate download response 0x1017:00"),
    (sdo(0x585, 0x20), "SDO 5 tx download segment response t=0"),
    (sdo(0x585, 0x30), "SDO 5 tx download segment response t=1"),
    # scs 2: initiate upload response, expedited or with size
    (sdo(0x585, 0x43, 0x18, 0x10, 0x01, le32(0x12345678)),
     "SDO 5 tx initiate upload response expedited 0x1018:01 4 B 78 56 34 12"),
    (sdo(0x585, 0x4F, 0x01, 0x10, 0x00, 0x05),
     "SDO 5 tx initiate upload response expedited 0x1001:00 1 B 05"),
    (sdo(0x585, 0x42, 0x01, 0x10, 0x00, 1, 2, 3, 4),
     "SDO 5 tx initiate upload response expedited 0x1001:00 size not indicated 01 02 03 04"),
    (sdo(0x585, 0x41, 0x08, 0x10, 0x00, le32(20)),
     "SDO 5 tx initiate upload response 0x1008:00 size 20"),
    (sdo(0x585, 0x40, 0x08, 0x10, 0x00),
     "SDO 5 tx initiate upload response 0x1008:00 size not indicated"),
    # scs 0: upload segment
    (sdo(0x585, 0x00, SEVEN), "SDO 5 tx upload segment t=0 7 B 01 02 03 04 05 06 07"),
    (sdo(0x585, 0x15, SEVEN), "SDO 5 tx upload segment t=1 last 5 B 01 02 03 04 05"),
    # scs 4: abort
    (sdo(0x585, 0x80, 0x18, 0x10, 0x01, le32(0x06010002)),
     "SDO 5 tx ABORT 0x1018:01 0x06010002 attempt to write a read-only object"),
    # scs 5: block download (initiate response, end response, ack; ss 3 is none)
    (sdo(0x585, 0xA4, 0x00, 0x21, 0x00, 127),
     "SDO 5 tx initiate block download response 0x2100:00 blksize 127 crc"),
    (sdo(0x585, 0xA0, 0x00, 0x21, 0x00, 1),
     "SDO 5 tx initiate block download response 0x2100:00 blksize 1"),
    (sdo(0x585, 0xA1), "SDO 5 tx end block download response"),
    (sdo(0x585, 0xA2, 127, 127), "SDO 5 tx block download ack seqno 127 blksize 127"),
    (sdo(0x585, 0xA3), "SDO 5 tx unknown command 0xA3 or block segment #35 last"),
    # scs 6: block upload (initiate response, end)
    (sdo(0x585, 0xC6, 0x00, 0x21, 0x00, le32(100000)),
     "SDO 5 tx initiate block upload response 0x2100:00 size 100000 crc"),
    (sdo(0x585, 0xC0, 0x00, 0x21, 0x00),
     "SDO 5 tx initiate block upload response 0x2100:00 size not indicated"),
    (sdo(0x585, 0xCD, 0x2B, 0x1A), "SDO 5 tx end block upload n=3 crc 0x1A2B"),
    (sdo(0x585, 0xF0), "SDO 5 tx unknown command 0xF0 or block segment #112 last"),
    # node-id limits
    (sdo(0x601, 0x40, 0x00, 0x10, 0x00), "SDO 1 rx initiate upload 0x1000:00"),
    (sdo(0x67F, 0x40, 0x00, 0x10, 0x00), "SDO 127 rx initiate upload 0x1000:00"),
    (sdo(0x581, 0x60, 0x00, 0x10, 0x00), "SDO 1 tx initiate download response 0x1000:00"),
    (sdo(0x5FF, 0x60, 0x00, 0x10, 0x00), "SDO 127 tx initiate download response 0x1000:00"),
])
def test_sdo_frames(frame, text):
    assert meaning(frame) == text
    assert decode(frame) == text                       # classic: no [FD] marker
    assert Decoder().decode(frame) == text             # nothing in progress: the same


@pytest.mark.parametrize("code, text", [
    (0x05030000, "toggle bit not alternated"),
    (0x05040001, "client/server command specifier not valid or unknown"),
    (0x06020000, "object does not exist in the object dictionary"),
    (0x08000024, "no data available"),
    (0x12345678, "unknown abort code"),
    (0x00000000, "unknown abort code"),
])
def test_sdo_aborts_name_known_and_unknown_codes(code, text):
    for can_id, head in ((0x60A, "SDO 10 rx"), (0x58A, "SDO 10 tx")):
        frame = sdo(can_id, 0x80, 0x00, 0x20, 0x02, le32(code))
        assert decode(frame) == f"{head} ABORT 0x2000:02 0x{code:08X} {text}"
    for known, meaning_text in ABORT_TEXT.items():            # every CiA 301 code
        assert decode(sdo(0x605, 0x80, 0, 0x20, 0, le32(known))).endswith(meaning_text)


@pytest.mark.parametrize("frame, text", [
    (sdo(0x605, pad=False), "SDO 5 rx malformed: 0 bytes, expected 8"),
    (sdo(0x585, 0x60, 0x17, 0x10, 0x00, pad=False),
     "SDO 5 tx malformed: 4 bytes, expected 8 (60 17 10 00)"),
    (sdo(0x605, 0x2B, 0x17, 0x10, 0x00, 0x2C, 0x01, pad=False),
     "SDO 5 rx malformed: 6 bytes, expected 8 (2B 17 10 00 2C 01)"),
    (Frame(0x605, bytes(9)),
     "SDO 5 rx malformed: 9 bytes, expected 8 (00 00 00 00 00 00 00 00 00)"),
    (sdo(0x585, 0xA4, 0x00, 0x21, 0x00, 0),
     ("SDO 5 tx initiate block download response 0x2100:00 blksize 0 crc "
      "malformed: blksize 0 outside 1..127")),
    (sdo(0x605, 0xA0, 0x00, 0x21, 0x00, 128, 0),
     ("SDO 5 rx initiate block upload 0x2100:00 blksize 128 pst 0 "
      "malformed: blksize 128 outside 1..127")),
    (sdo(0x605, 0xA2, 200, 128),
     ("SDO 5 rx block upload ack seqno 200 blksize 128 "
      "malformed: seqno 200 outside 0..127, blksize 128 outside 1..127")),
    (sdo(0x585, 0xA2, 5, 0),
     "SDO 5 tx block download ack seqno 5 blksize 0 malformed: blksize 0 outside 1..127"),
    (sdo(0x605, 0xE5), "SDO 5 rx unknown command 0xE5 or block segment #101 last"),
    (sdo(0x585, 0xB7), "SDO 5 tx unknown command 0xB7 or block segment #55 last"),
])
def test_sdo_malformed_frames(frame, text):
    assert meaning(frame) == text
    assert Decoder().meaning(frame) == text
    assert "malformed" in text or "unknown command" in text


def test_sdo_only_on_classic_11_bit_data_frames():
    # FD frames on the SDO ids stay USDO; RTR, 29-bit and neighbour ids are no SDO.
    assert decode(fd(0x605, bytes([3, 0x11, 7, 0x00, 0x08, 0x10]))) == \
        "USDO 5->3 sid 7 upload request 0x1008:00 [FD BRS]"
    assert Decoder().decode(fd(0x605, bytes([3, 0x11, 7, 0x00, 0x08, 0x10]))) == \
        "USDO 5->3 sid 7 upload request 0x1008:00 [FD BRS]"
    for frame in (Frame(0x605, bytes([0x40, 0x08, 0x10, 0, 0, 0, 0, 0]), ext=True),
                  Frame(0x605, b"", rtr=True, rtr_len=8),
                  sdo(0x580, 0x60), sdo(0x600, 0x40), sdo(0x680, 0x40)):
        assert meaning(frame) == "" and Decoder().meaning(frame) == ""
        assert decode(frame) == format_raw(frame)


def test_sdo_describe_shows_every_byte_then_the_meaning():
    frame = sdo(0x605, 0x2B, 0x17, 0x10, 0x00, 0x2C, 0x01)
    line = ("0x605 [8] 2B 17 10 00 2C 01 00 00 "
            "SDO 5 rx initiate download expedited 0x1017:00 2 B 2C 01")
    assert describe(frame) == line
    assert Decoder().describe(frame) == line


# A block transfer's sub-block segments have no command specifier: alone they
# read as whatever byte 0 spells; a Decoder that saw the transfer start knows.


def feed(decoder, frames):
    return [decoder.decode(frame) for frame in frames]


def test_block_download_through_the_decoder():
    d = Decoder()
    data = bytes(range(200, 231))                        # 31 bytes: 5 segments, last has 3
    segs = [data[i:i + 7].ljust(7, b"\0") for i in range(0, 31, 7)]
    assert feed(d, [
        sdo(0x605, 0xC6, 0x00, 0x21, 0x00, le32(31)),
        sdo(0x585, 0xA4, 0x00, 0x21, 0x00, 4),
    ]) == [
        "SDO 5 rx initiate block download 0x2100:00 size 31 crc",
        "SDO 5 tx initiate block download response 0x2100:00 blksize 4 crc",
    ]
    assert d.transfer(5) == "block download"
    assert d.transfer(6) is None
    # First sub-block (#1..#4), of which the server got only #1, #2: it repeats
    # from the third segment, renumbered from #1, in a sub-block of 4 again.
    first = [sdo(0x605, n, segs[n - 1]) for n in (1, 2, 3, 4)]
    assert feed(d, first) == [f"SDO 5 rx block segment #{n}" for n in (1, 2, 3, 4)]
    # (alone, the same frames read as commands)
    assert [decode(f) for f in first[:2]] == [
        f"SDO 5 rx download segment t=0 last 7 B {hex_bytes(segs[0])}",
        f"SDO 5 rx download segment t=0 6 B {hex_bytes(segs[1][:6])}",
    ]
    assert feed(d, [sdo(0x585, 0xA2, 2, 4)]) == [
        "SDO 5 tx block download ack seqno 2 blksize 4 (partial, 4 sent)"]
    assert d.transfer(5) == "block download"
    # Another server's transfer meanwhile: its own state.
    assert feed(d, [sdo(0x606, 0x40, 0x08, 0x10, 0x00), Frame(0x705, b"\x05"),
                    sdo(0x586, 0x4F, 0x08, 0x10, 0x00, 0x41)]) == [
        "SDO 6 rx initiate upload 0x1008:00", "heartbeat node 5 OPERATIONAL",
        "SDO 6 tx initiate upload response expedited 0x1008:00 1 B 41"]
    second = [sdo(0x605, 1, segs[2]), sdo(0x605, 2, segs[3]), sdo(0x605, 0x83, segs[4])]
    assert feed(d, second) == ["SDO 5 rx block segment #1", "SDO 5 rx block segment #2",
                               "SDO 5 rx block segment #3 last"]
    # The last segment acked: the end frames have command specifiers again.
    assert feed(d, [sdo(0x585, 0xA2, 3, 4)]) == ["SDO 5 tx block download ack seqno 3 blksize 4"]
    assert d.transfer(5) is None
    assert feed(d, [sdo(0x605, 0xC1 | 4 << 2, 0x2B, 0x1A), sdo(0x585, 0xA1)]) == [
        "SDO 5 rx end block download n=4 crc 0x1A2B", "SDO 5 tx end block download response"]
    # and what follows is read by command specifier
    assert feed(d, [sdo(0x605, 0x01, SEVEN)]) == [
        "SDO 5 rx download segment t=0 last 7 B 01 02 03 04 05 06 07"]


def test_block_download_with_a_partial_ack_of_the_last_sub_block():
    d = Decoder()
    feed(d, [sdo(0x605, 0xC2, 0x00, 0x21, 0x00, le32(14)), sdo(0x585, 0xA0, 0x00, 0x21, 0x00, 127)])
    assert feed(d, [sdo(0x605, 0x01, SEVEN), sdo(0x605, 0x82, SEVEN),
                    sdo(0x585, 0xA2, 1, 127),                  # the last segment got lost
                    sdo(0x605, 0x81, SEVEN),                   # again, as #1
                    sdo(0x585, 0xA2, 1, 127),
                    sdo(0x605, 0xC1, 0, 0)]) == [
        "SDO 5 rx block segment #1", "SDO 5 rx block segment #2 last",
        "SDO 5 tx block download ack seqno 1 blksize 127 (partial, 2 sent)",
        "SDO 5 rx block segment #1 last",
        "SDO 5 tx block download ack seqno 1 blksize 127",
        "SDO 5 rx end block download n=0 crc 0x0000"]


def test_block_upload_through_the_decoder():
    d = Decoder()
    assert feed(d, [
        sdo(0x60C, 0xA4, 0x00, 0x21, 0x00, 127, 0),
        sdo(0x58C, 0xC6, 0x00, 0x21, 0x00, le32(1000)),
    ]) == [
        "SDO 12 rx initiate block upload 0x2100:00 blksize 127 pst 0 crc",
        "SDO 12 tx initiate block upload response 0x2100:00 size 1000 crc",
    ]
    assert d.transfer(12) is None                        # segments come after the start
    assert feed(d, [sdo(0x60C, 0xA3)]) == ["SDO 12 rx start block upload"]
    assert d.transfer(12) == "block upload"
    # 1000 bytes = 142 full segments + one of 6: a sub-block of 127, whose byte 0
    # runs through every command specifier of the server...
    full = [sdo(0x58C, n, bytes([n] * 7)) for n in range(1, 128)]
    assert feed(d, full) == [f"SDO 12 tx block segment #{n}" for n in range(1, 128)]
    assert feed(d, [sdo(0x60C, 0xA2, 127, 127)]) == [
        "SDO 12 rx block upload ack seqno 127 blksize 127"]
    # ... then 16 with the last one, of which the client got 10: #11..#16 again as #1..#6.
    rest = [sdo(0x58C, n | (0x80 if n == 16 else 0), bytes(7)) for n in range(1, 17)]
    assert feed(d, rest)[-2:] == ["SDO 12 tx block segment #15", "SDO 12 tx block segment #16 last"]
    assert feed(d, [sdo(0x60C, 0xA2, 10, 127)]) == [
        "SDO 12 rx block upload ack seqno 10 blksize 127 (partial, 16 sent)"]
    again = [sdo(0x58C, n | (0x80 if n == 6 else 0), bytes(7)) for n in range(1, 7)]
    assert feed(d, again) == [f"SDO 12 tx block segment #{n}" for n in range(1, 6)] + [
        "SDO 12 tx block segment #6 last"]
    assert feed(d, [sdo(0x60C, 0xA2, 6, 127),
                    sdo(0x58C, 0xC1 | 1 << 2, 0xEF, 0xBE),
                    sdo(0x60C, 0xA1)]) == [
        "SDO 12 rx block upload ack seqno 6 blksize 127",
        "SDO 12 tx end block upload n=1 crc 0xBEEF",
        "SDO 12 rx end block upload response"]
    assert d.transfer(12) is None


def test_block_upload_protocol_switch_is_a_normal_upload():
    # Under pst bytes, the server may answer a block upload with a normal one.
    d = Decoder()
    assert feed(d, [sdo(0x605, 0xA4, 0x08, 0x10, 0x00, 127, 20),
                    sdo(0x585, 0x41, 0x08, 0x10, 0x00, le32(9)),
                    sdo(0x605, 0x60), sdo(0x585, 0x00, b"abcdefg"),
                    sdo(0x605, 0x70), sdo(0x585, 0x1B, b"hi")]) == [
        "SDO 5 rx initiate block upload 0x1008:00 blksize 127 pst 20 crc",
        "SDO 5 tx initiate upload response 0x1008:00 size 9",
        "SDO 5 rx upload segment request t=0",
        "SDO 5 tx upload segment t=0 7 B 61 62 63 64 65 66 67",
        "SDO 5 rx upload segment request t=1",
        "SDO 5 tx upload segment t=1 last 2 B 68 69"]
    assert d.transfer(5) is None


def test_aborts_end_block_transfers():
    d = Decoder()
    start = [sdo(0x605, 0xC4, 0x00, 0x21, 0x00), sdo(0x585, 0xA4, 0x00, 0x21, 0x00, 8),
             sdo(0x605, 0x01)]
    # the client aborts (0x80 is no segment: seqno 0)
    feed(d, start)
    assert feed(d, [sdo(0x605, 0x80, 0x00, 0x21, 0x00, le32(0x05040003)),
                    sdo(0x605, 0x40, 0x00, 0x21, 0x00)]) == [
        "SDO 5 rx ABORT 0x2100:00 0x05040003 invalid sequence number",
        "SDO 5 rx initiate upload 0x2100:00"]
    # the server aborts
    feed(d, start)
    assert feed(d, [sdo(0x585, 0x80, 0x00, 0x21, 0x00, le32(0x05040004)),
                    sdo(0x605, 0x00, SEVEN)]) == [
        "SDO 5 tx ABORT 0x2100:00 0x05040004 CRC error",
        "SDO 5 rx download segment t=0 7 B 01 02 03 04 05 06 07"]
    assert d.transfer(5) is None
    # a block upload: the server (sending segments) or the client aborts
    for abort in (sdo(0x585, 0x80, 0x00, 0x21, 0x00, le32(0xDEADBEEF)),
                  sdo(0x605, 0x80, 0x00, 0x21, 0x00, le32(0xDEADBEEF))):
        feed(d, [sdo(0x605, 0xA3), sdo(0x585, 0x01)])
        assert d.transfer(5) == "block upload"
        assert d.decode(abort).endswith("ABORT 0x2100:00 0xDEADBEEF unknown abort code")
        assert d.transfer(5) is None
    d.reset()


def test_decoder_marks_sequence_errors_and_recovers_from_missed_frames():
    d = Decoder()
    feed(d, [sdo(0x585, 0xA4, 0x00, 0x21, 0x00, 8)])   # its initiate was not seen
    assert feed(d, [sdo(0x605, 0x01), sdo(0x605, 0x03), sdo(0x605, 0x00), sdo(0x605, 0x04)]) == [
        "SDO 5 rx block segment #1", "SDO 5 rx block segment #3 (expected #2)",
        "SDO 5 rx block segment #0 malformed: sequence number 0", "SDO 5 rx block segment #4"]
    assert d.decode(sdo(0x605, 0x2B, 0, 0, 0, pad=False)) == \
        "SDO 5 rx malformed: 4 bytes, expected 8 (2B 00 00 00)"       # state unchanged
    assert d.transfer(5) == "block download"
    # The server's ack of the last segment was missed: the client's end frame
    # still reads as a segment, but the server's end response is no ack, so
    # the decoder lets the transfer go.
    assert feed(d, [sdo(0x605, 0x85), sdo(0x605, 0xCD, 0x2B, 0x1A), sdo(0x585, 0xA1)]) == [
        "SDO 5 rx block segment #5 last", "SDO 5 rx block segment #77 last (expected #6)",
        "SDO 5 tx end block download response"]
    assert d.transfer(5) is None
    assert d.decode(sdo(0x605, 0xCD, 0x2B, 0x1A)) == "SDO 5 rx end block download n=3 crc 0x1A2B"
    # A monitor started in the middle of a block upload reads its segments
    # alone until the next start.
    assert d.decode(sdo(0x585, 0x05)) == "SDO 5 tx upload segment t=0 last 5 B 00 00 00 00 00"
    assert feed(d, [sdo(0x605, 0xA3), sdo(0x585, 0x05)]) == [
        "SDO 5 rx start block upload", "SDO 5 tx block segment #5 (expected #1)"]
    d.reset()
    assert d.transfer(5) is None



class ScriptedServer:
    """SDO server 5 for python-canopen's SdoClient (an independent CiA 301
    client): answers each request as the transfers below need, and logs every
    frame in bus order. Stands in for the client's network."""

    def __init__(self, client, upload_data, blksize):
        self.client, self.upload_data, self.blksize = client, upload_data, blksize
        self.log = []
        self.in_block_download = False
        self.client_blksize = 0
        self.pos = 0

    def send_message(self, can_id, data):            # the client sends
        self.log.append(Frame(can_id, bytes(data)))
        for response in self.respond(bytes(data)):
            response = response.ljust(8, b"\0")
            self.log.append(Frame(0x585, response))
            self.client.on_response(0x585, response, 0.0)

    def respond(self, req):
        cmd, mux = req[0], req[1:4]
        if self.in_block_download:                   # sub-block segments
            if (cmd & 0x7F) == self.blksize or cmd & 0x80:
                self.in_block_download = not cmd & 0x80
                return [bytes([0xA2, cmd & 0x7F, self.blksize])]
            return []
        ccs = cmd >> 5
        if ccs == 1:                                  # initiate download
            return [b"\x60" + mux]
        if ccs == 0:                                  # download segment
            return [bytes([0x20 | cmd & 0x10])]
        if ccs == 2:                                  # initiate upload: expedited 2 B
            return [b"\x4B" + mux + b"\x2C\x01"]
        if ccs == 6:                                  # initiate / end block download
            self.in_block_download = not cmd & 1
            return [b"\xA1"] if cmd & 1 else [b"\xA0" + mux + bytes([self.blksize])]
        if ccs == 5 and cmd & 3 == 0:                 # initiate block upload: no CRC
            self.pos, self.client_blksize = 0, req[4]
            return [b"\xC2" + mux + len(self.upload_data).to_bytes(4, "little")]
        if ccs == 5 and cmd & 3 in (2, 3):            # ack or start: the next sub-block
            if cmd & 3 == 2:
                self.client_blksize = req[2]
                if self.pos >= len(self.upload_data):
                    return [bytes([0xC1 | (-len(self.upload_data) % 7) << 2])]
            frames = []
            for seqno in range(1, self.client_blksize + 1):
                chunk = self.upload_data[self.pos:self.pos + 7]
                self.pos += len(chunk)
                last = self.pos >= len(self.upload_data)
                frames.append(bytes([seqno | (0x80 if last else 0)]) + chunk)
                if last:
                    break
            return frames
        return []                                     # end block upload response


def test_python_canopen_client_frames_decode(monkeypatch):
    canopen = pytest.importorskip("canopen")
    from canopen.sdo.client import BlockUploadStream, SdoClient

    monkeypatch.setattr(BlockUploadStream, "blksize", 4)    # two sub-blocks
    client = SdoClient(0x605, 0x585, canopen.ObjectDictionary())
    server = ScriptedServer(client, bytes(range(30)), blksize=4)
    client.network = server
    client.download(0x1017, 0, b"\x2c\x01")
    client.download(0x2000, 1, bytes(range(10)), force_segment=True)
    assert client.upload(0x1017, 0) == b"\x2c\x01"
    with client.open(0x2100, 0, "wb", size=31, block_transfer=True) as stream:
        stream.write(bytes(range(31)))
    with client.open(0x2101, 0, "rb", block_transfer=True) as stream:
        assert stream.read() == bytes(range(30))
    d = Decoder()
    followed = [d.meaning(frame) for frame in server.log]
    assert followed == [
        "SDO 5 rx initiate download expedited 0x1017:00 2 B 2C 01",
        "SDO 5 tx initiate download response 0x1017:00",
        "SDO 5 rx initiate download 0x2000:01 size 10",
        "SDO 5 tx initiate download response 0x2000:01",
        "SDO 5 rx download segment t=0 7 B 00 01 02 03 04 05 06",
        "SDO 5 tx download segment response t=0",
        "SDO 5 rx download segment t=1 last 3 B 07 08 09",
        "SDO 5 tx download segment response t=1",
        "SDO 5 rx initiate upload 0x1017:00",
        "SDO 5 tx initiate upload response expedited 0x1017:00 2 B 2C 01",
        "SDO 5 rx initiate block download 0x2100:00 size 31 crc",
        "SDO 5 tx initiate block download response 0x2100:00 blksize 4",
        "SDO 5 rx block segment #1",
        "SDO 5 rx block segment #2",
        "SDO 5 rx block segment #3",
        "SDO 5 rx block segment #4",
        "SDO 5 tx block download ack seqno 4 blksize 4",
        "SDO 5 rx block segment #1 last",
        "SDO 5 tx block download ack seqno 1 blksize 4",
        "SDO 5 rx end block download n=4 crc 0x0000",      # the server declined CRCs
        "SDO 5 tx end block download response",
        "SDO 5 rx initiate block upload 0x2101:00 blksize 4 pst 0 crc",
        "SDO 5 tx initiate block upload response 0x2101:00 size 30",
        "SDO 5 rx start block upload",
        "SDO 5 tx block segment #1",
        "SDO 5 tx block segment #2",
        "SDO 5 tx block segment #3",
        "SDO 5 tx block segment #4",
        "SDO 5 rx block upload ack seqno 4 blksize 4",
        "SDO 5 tx block segment #1 last",
        "SDO 5 rx block upload ack seqno 1 blksize 4",
        "SDO 5 tx end block upload n=5 crc 0x0000",
        "SDO 5 rx end block upload response",
    ]
    # Alone, only the block segments read otherwise (#1 last as an abort).
    for frame, text in zip(server.log, followed):
        assert (meaning(frame) == text) == ("block segment" not in text)
    assert meaning(server.log[17]) == "SDO 5 rx ABORT 0x1D1C:1E 0x00000000 unknown abort code"


def test_monitor_command_follows_block_transfers(capsys):
    from canopenfd import Network
    from canopenfd.cli import main

    frames = [(0x605, bytes([0xC6, 0x00, 0x21, 0x00, 14, 0, 0, 0])),
              (0x585, bytes([0xA4, 0x00, 0x21, 0x00, 127, 0, 0, 0])),
              (0x605, bytes([0x01]) + bytes(range(7))),   # alone: a download segment
              (0x605, bytes([0x82]) + bytes(range(7))),   # alone: an abort
              (0x585, bytes([0xA2, 2, 127, 0, 0, 0, 0, 0])),
              (0x605, bytes([0xC1 | 2 << 2, 0x34, 0x12, 0, 0, 0, 0, 0])),
              (0x585, bytes([0xA1]) + bytes(7))]
    done = {}
    with Network() as net:
        sender = net.open_line("mem:sdo-monitor", mode="classic")
        thread = threading.Thread(target=lambda: done.setdefault("rc", main(
            ["monitor", "--channel", "mem:sdo-monitor", "--classic", "--count",
             str(len(frames)), "--duration", str(scaled(30))], network=net)))
        thread.start()
        out, err = "", ""
        deadline = time.monotonic() + scaled(10)
        while "monitoring" not in err and time.monotonic() < deadline:   # on_frame is set
            time.sleep(0.01)
            captured = capsys.readouterr()
            out, err = out + captured.out, err + captured.err
        for can_id, data in frames:
            sender.send_frame(can_id, data)
        thread.join(scaled(30))
    assert done.get("rc") == 0, err
    out += capsys.readouterr().out
    lines = out.splitlines()
    assert lines[3].endswith("RX  0x605 [8] 82 00 01 02 03 04 05 06 SDO 5 rx block segment #2 last")
    assert [line[line.index("SDO "):] for line in lines] == [
        "SDO 5 rx initiate block download 0x2100:00 size 14 crc",
        "SDO 5 tx initiate block download response 0x2100:00 blksize 127 crc",
        "SDO 5 rx block segment #1",
        "SDO 5 rx block segment #2 last",
        "SDO 5 tx block download ack seqno 2 blksize 127",
        "SDO 5 rx end block download n=2 crc 0x1234",
        "SDO 5 tx end block download response",
    ], out


if hypothesis is not None:
    _SDO_IDS = st.one_of(st.integers(0x581, 0x5FF), st.integers(0x601, 0x67F),
                         st.sampled_from([0x585, 0x605]))    # often the same server
    # Random frames, and pieces of block transfers of server 5 (starts, runs of
    # segments from either side, acks, ends, aborts) so the sequences get deep.
    _SDO_RANDOM = st.tuples(_SDO_IDS, st.binary(max_size=8))
    _TAIL = st.binary(min_size=7, max_size=7)
    _SDO_PIECES = st.one_of(
        _SDO_RANDOM.map(lambda f: [f]),
        _TAIL.map(lambda t: [(0x585, bytes([0xA4]) + t)]),              # block download on
        _TAIL.map(lambda t: [(0x605, bytes([0xA3]) + t)]),              # block upload on
        st.tuples(st.sampled_from([0x585, 0x605]), st.integers(1, 8), st.booleans(), _TAIL)
        .map(lambda t: [(t[0], bytes([n | (0x80 if t[2] and n == t[1] else 0)]) + t[3])
                        for n in range(1, t[1] + 1)]),                  # segments #1..#k
        st.tuples(st.sampled_from([0x585, 0x605]), st.integers(0, 9), st.integers(0, 255),
                  st.binary(min_size=5, max_size=5))
        .map(lambda t: [(t[0], bytes([0xA2, t[1], t[2]]) + t[3])]),     # acks
        st.tuples(st.sampled_from([0x585, 0x605]), st.sampled_from([0x80, 0xA1, 0xC1, 0xCD]), _TAIL)
        .map(lambda t: [(t[0], bytes([t[1]]) + t[2])]),                 # ends, aborts
    )
    _SDO_SEQUENCES = st.lists(_SDO_PIECES, max_size=30).map(
        lambda pieces: [frame for piece in pieces for frame in piece])

    @settings(max_examples=400, deadline=None, database=None)
    @given(can_id=_SDO_IDS, data=st.binary(max_size=8))
    def test_sdo_random_frames_never_raise(can_id, data):
        frame = Frame(can_id, data)
        node = can_id - (0x600 if can_id > 0x600 else 0x580)
        head = f"SDO {node} {'rx' if can_id > 0x600 else 'tx'} "
        for text in (decode(frame), describe(frame), Decoder().decode(frame)):
            assert isinstance(text, str) and "\n" not in text
            assert head in text
        if len(data) == 8 and data[0] >> 5 == 7:
            assert ("network indication" if data[0] == 0xE0 else "unknown command") \
                in decode(frame)

    @settings(max_examples=300, deadline=None, database=None)
    @given(frames=_SDO_SEQUENCES)
    def test_sdo_decoder_random_sequences_never_raise(frames):
        d = Decoder()
        for can_id, data in frames:
            frame = Frame(can_id, data)
            node = can_id - (0x600 if can_id > 0x600 else 0x580)
            before = d.transfer(node)
            text = d.decode(frame)
            assert isinstance(text, str) and "\n" not in text
            assert text.startswith(f"SDO {node} ")
            segment_side = (before == "block download") == (can_id > 0x600)
            if before is None or len(data) != 8:
                assert text == decode(frame)              # nothing followed: as alone
            elif segment_side and data[0] != 0x80:
                assert "block segment #" in text
            assert d.transfer(node) in (None, "block download", "block upload")
            assert isinstance(d.describe(frame), str)


def test_usdo_remote_frames_decoded():
    """Routed USDO frames (layout UNCONFIRMED, docs/protocol-notes.md): the
    route (source -> destination network:node), then the local frame."""
    from canopenfd.decode.usdo import usdo_text

    request = bytes([1, 0x81, 0x11, 2, 5, 1, 7, 0x00, 0x00, 0x20, 0x07, 0x04,
                     0xEF, 0xBE, 0xAD, 0xDE])
    assert usdo_text(0x607, request) == \
        "USDO 7->1 sid 17 routed 1:7->2:5 download expedited 0x2000:00 U32 N=4 EF BE AD DE"
    answer = bytes([7, 0xFF, 0x11, 1, 7, 2, 5, 0x00, 0x00, 0x20, 0x1A, 0])
    assert usdo_text(0x581, answer).startswith(
        "USDO 1->7 sid 17 routed 2:5->1:7 ABORT 0x2000:00 0x1A")
    segment = bytes([1, 0x93, 0x03, 0x09])
    assert usdo_text(0x607, segment) == "USDO 7->1 sid 3 routed upload segment request #9"
    assert usdo_text(0x607, bytes([1, 0x91, 3, 2, 5])) == \
        "USDO 7->1 sid 3 routed upload request malformed: 5 bytes, expected 7 or more"
    assert usdo_text(0x607, bytes([1, 0x85, 3, 2, 5, 1, 7])) == \
        "USDO 7->1 sid 3 routed unknown command 0x85"

