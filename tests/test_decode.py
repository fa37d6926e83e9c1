"""The frame decoder (NMT, heartbeat, USDO) and the NMT enums: pure Python."""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest

from canopenfd import ConfigurationError, Frame, NmtCommand, NmtState
from canopenfd.decode import USDO_COMMANDS, decode, describe, format_raw, meaning, usdo_type_name
from canopenfd.errors import USDO_ABORT_TEXT
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
    (Frame(0x181, bytes(range(1, 9))), "0x181 [8] 01 02 03 04 05 06 07 08"),
    (Frame(0x080, b""), "0x080 [0]"),
    (Frame(0x1ABCDEF0, b"\x01", ext=True), "0x1ABCDEF0 [1] 01"),
    (Frame(0x705, b"", rtr=True, rtr_len=1), "node guarding request node 5"),
    (Frame(0x123, b"", rtr=True, rtr_len=8), "0x123 [8] RTR"),
    (fd(0x705, b"\x00"), "boot-up node 5 [FD BRS]"),
    (fd(0x000, b"\x01\x05", brs=False), "NMT start node 5 [FD]"),
    (fd(0x201, bytes(12)), "0x201 [12] " + " ".join(["00"] * 12) + " [FD BRS]"),
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
    (Frame(0x705, b"\x80"), "heartbeat node 5 malformed: state 0x80"),
    (Frame(0x700, b"\x05"), "heartbeat malformed: CAN-ID 0x700 (node-id 0)"),
])
def test_decode_marks_malformed_frames(frame, text):
    assert decode(frame) == text
    assert "malformed" in decode(frame)


def test_describe_and_raw():
    assert format_raw(Frame(0x705, b"\x7f")) == "0x705 [1] 7F"
    assert describe(fd(0x705, b"\x7f")).split() == [
        "0x705", "[1]", "7F", "heartbeat", "node", "5", "PRE-OPERATIONAL", "[FD", "BRS]"]
    assert describe(Frame(0x181, b"\x01")) == "0x181 [1] 01"


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
    (usdo(0x583, 5, 0xFF, 7, 0, 0, 0x20, 0x10), "USDO 3->5 sid 7 unknown command 0xFF"),
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
    (usdo(0x605, 3, 0x03, 7, 0, SEG[:44]),
     "USDO 5->3 sid 7 download segment malformed: 48 bytes, expected 64"),
    (usdo(0x605, 3, 0x07, 7, pad=False),
     "USDO 5->3 sid 7 bulk segment malformed: 3 bytes, expected 64"),
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


def test_classic_and_other_frames_on_usdo_ids_stay_raw():
    # USDO is CAN FD only: a classic frame on a USDO CAN-ID is shown as before.
    classic = Frame(0x605, bytes([3, 0x01, 7, 0x01, 0x00, 0x20, 0x07, 4]))
    assert meaning(classic) == ""
    assert decode(classic) == "0x605 [8] 03 01 07 01 00 20 07 04"
    assert describe(classic) == "0x605 [8] 03 01 07 01 00 20 07 04"
    assert decode(Frame(0x583, bytes([5, 0x7F, 7, 0, 0, 0x30, 0x33]))) == \
        "0x583 [7] 05 7F 07 00 00 30 33"
    assert decode((0x605, bytes([3, 0x11, 7, 0, 0, 0x20]))) == "0x605 [6] 03 11 07 00 00 20"
    # FD frames just outside the ranges, and 29-bit ids, are not USDO
    for can_id in (0x580, 0x600, 0x680, 0x57F):
        assert meaning(usdo(can_id, 3, 0x11, 7, 0, 0, 0x20)) == ""
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
    unknown = fd(0x201, bytes(20))                                  # undecoded: every byte
    assert describe(unknown) == "0x201 [20] " + " ".join(["00"] * 20) + " [FD BRS]"
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
_HEADER = Path(__file__).resolve().parents[1] / "csrc" / "core" / "co_usdo.h"
_LAYOUT_NAMES = {"MUX": "mux", "EXPEDITED": "expedited", "INITIATE": "initiate",
                 "SEGMENT": "segment", "LAST": "last", "COUNTER": "counter", "END": "end",
                 "ABORT": "abort", "BULK_ACCEPT": "bulk accept"}


def _c_enum(prefix):
    text = _HEADER.read_text()
    return {name: int(value, 16)
            for name, value in re.findall(rf"\b{prefix}(\w+)\s*=\s*(0x[0-9A-Fa-f]+)", text)}


@pytest.mark.skipif(not _HEADER.exists(), reason="needs the source tree (csrc/core/co_usdo.h)")
def test_usdo_tables_match_the_c_codec():
    decode_module = importlib.import_module("canopenfd.decode")

    commands = _c_enum("CO_USDO_CS_")
    assert commands, "no command specifiers found in co_usdo.h"
    unsupported = {commands.pop("REMOTE_ABORT")}       # remote USDO: no layout in the codec
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
            if len(data) >= 3 and data[1] not in USDO_COMMANDS:
                assert f"unknown command 0x{data[1]:02X}" in text
        else:
            assert text == format_raw(frame)           # classic: raw, as before
