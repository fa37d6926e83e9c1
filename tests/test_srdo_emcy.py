"""An SRDO's safe state is an active EMCY error of the node (CiA 301 EMCY
semantics, the codes of docs/protocol-notes.md "SRDO and GFC"): its EMCY
when it enters the safe state, 0x1001 and 0x1003 showing it while it lasts,
the error reset (EEC 0x0000) when it leaves it. Over the in-process bus with
a tool reading the objects by SDO (python-canopen hears the same EMCYs:
tests/test_errors_interop.py)."""

from __future__ import annotations

import struct
import time

from helpers import Recorder, scaled
from test_errors import error_od

from canopenfd.services.srdo import SrdoConfig, SrdoViolation

NODE = 6
# a consumer that never hears its producer: SCT exceeded 100 ms after the start
CONSUME = SrdoConfig("consume", sct_ms=100, srvt_ms=50, cob_id=0x10B,
                     mapping=(0x62000120, 0x62010120))
SCT = SrdoViolation.SCT_EXCEEDED
RAISED = bytes([0x00, 0x82, 0x11, 1, SCT, 0, 0, 0])      # 0x8200, generic + communication
RESET = bytes([0x00, 0x00, 0x00, 1, SCT, 0, 0, 0])       # error reset, register 0


def emcys(frames: Recorder, count: int, mark: int = 0):
    """The data of node 6's first `count` EMCYs after frame `mark`."""
    def enough(calls):
        got = [bytes(f.data) for f in calls[mark:] if f.id == 0x80 + NODE]
        return got if len(got) >= count else None
    return frames.wait_for(enough, 3.0, f"{count} EMCYs of node {NODE}")[:count]


def start_consumer(device) -> None:
    """SRDO 1 of device consumes CONSUME from a producer that never sends."""
    device.srdo.start(1)
    device.srdo.configure(1, CONSUME)
    device.apply("start")


def test_safe_state_raises_an_error_its_end_resets_it(net, bus_name):
    device = net.open_line(bus_name, mode="classic").create_local_node(
        NODE, od=error_od("classic"))
    tool = net.open_line(bus_name, mode="classic")
    remote = tool.add_node(NODE)
    frames = Recorder()
    net.open_line(bus_name, mode="classic", monitor=True).on_frame(frames)
    start_consumer(device)
    assert emcys(frames, 1) == [RAISED]
    assert remote.read((0x1001, 0)) == b"\x11"
    assert remote.read((0x1003, 0)) == b"\x01"
    assert remote.read((0x1003, 1)) == struct.pack("<I", 0x8200 | 1 << 16 | SCT << 24)
    mark = len(frames)
    device.srdo.restart(1)                   # leaves the safe state: the error is over
    assert emcys(frames, 1, mark) == [RESET]
    # waiting again without a producer: the SCT runs out again, a new occurrence
    assert emcys(frames, 2, mark) == [RESET, RAISED]
    assert remote.read((0x1003, 0)) == b"\x02"
    device.apply("pre-operational")          # leaving operational ends it too
    assert emcys(frames, 3, mark) == [RESET, RAISED, RESET]
    assert remote.read((0x1001, 0)) == b"\x00"
    time.sleep(scaled(0.2))                  # stopped: no SCT, nothing more
    assert len([f for f in frames.snapshot()[mark:] if f.id == 0x80 + NODE]) == 3

