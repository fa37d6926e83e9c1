"""The frame decoder and the NMT enums: pure Python."""

from __future__ import annotations

import pytest

from canopenfd import ConfigurationError, Frame, NmtCommand, NmtState
from canopenfd.decode import decode, describe, format_raw


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
