"""CiA 402 on real kernel SocketCAN (vcan): the simulated drive in one
Network, the master's `Drive` in another, every frame captured by a raw
python-can socket: the enable sequence (SDO controlword writes and the
drive's TPDO1 statusword at each change) and a CSP exchange (SYNC, RPDO2
controlword + target, TPDO2 statusword + position). Needs CANOPENFD_VCAN."""

from __future__ import annotations

import time

import pytest
from helpers import scaled

import canopenfd
from canopenfd.profiles.cia402 import Drive, DriveState, create_simulated_drive, drive_od

pytestmark = pytest.mark.vcan
can = pytest.importorskip("can")

NODE = 5


@pytest.fixture
def rig(vcan):
    """(drive Network, master Network, raw capture bus) on the classic vcan."""
    channel = vcan[2]
    raw = can.Bus(interface="socketcan", channel=channel, fd=False)
    device, master = canopenfd.Network(), canopenfd.Network()
    try:
        create_simulated_drive(device.open_line(channel, mode="classic"), NODE)
        line = master.open_line(channel, mode="classic")
        drive = Drive(line.add_node(NODE, od=drive_od("classic")), timeout=scaled(2))
        yield drive, raw
    finally:
        master.close()
        device.close()
        raw.shutdown()


def captured(raw, until, timeout=5.0):
    """Frames (id, bytes) read until until(frames) is true (or the deadline)."""
    frames = []
    deadline = time.monotonic() + scaled(timeout)
    while not until(frames):
        remaining = deadline - time.monotonic()
        assert remaining > 0, f"no match in {scaled(timeout)} s; last frames {frames[-12:]}"
        msg = raw.recv(min(0.05, remaining))
        if msg is not None and not msg.is_error_frame:
            frames.append((msg.arbitration_id, bytes(msg.data)))
    return frames


def test_enable_sequence_on_the_wire(rig):
    drive, raw = rig
    drive.node.start()
    drive.enable()
    words = [bytes([0x2B, 0x40, 0x60, 0, cw, 0, 0, 0]) for cw in (0x06, 0x07, 0x0F)]
    statuswords = [bytes([sw, 0x02]) for sw in (0x31, 0x33, 0x37)]

    def complete(frames):
        sdo = [data for can_id, data in frames if can_id == 0x600 + NODE and data in words]
        tpdo = [data for can_id, data in frames if can_id == 0x180 + NODE
                and data in statuswords]
        return sdo == words and tpdo[-3:] == statuswords
    frames = captured(raw, complete)
    # each controlword's SDO request comes before the statusword it causes
    order = [data for _, data in frames if data in words or data in statuswords]
    assert order.index(words[0]) < order.index(statuswords[0]) < order.index(words[1]) \
        < order.index(statuswords[1]) < order.index(words[2]) < order.index(statuswords[2])
    assert drive.state is DriveState.OPERATION_ENABLED


def test_csp_exchange_on_the_wire(rig):
    drive, raw = rig
    cyclic = drive.cyclic("csp", period=0.01)
    try:
        drive.enable()
        cyclic.target = 1234
        target = bytes([0x0F, 0, 0xD2, 0x04, 0, 0])            # controlword, 1234

        def answered(frames):
            return any(can_id == 0x285 and data == bytes([0x37, 0x12, 0xD2, 0x04, 0, 0])
                       for can_id, data in frames)
        frames = captured(raw, answered)
    finally:
        drive.stop_cyclic()
    ids = [can_id for can_id, _ in frames]
    assert 0x80 in ids                                         # SYNC from the master
    first_rpdo = next(i for i, (can_id, data) in enumerate(frames)
                      if can_id == 0x305 and data == target)
    first_tpdo = next(i for i, (can_id, data) in enumerate(frames)
                      if can_id == 0x285 and data[2:] == bytes([0xD2, 0x04, 0, 0]))
    # the target goes out after a SYNC, is taken at the next one, reported at a later one
    assert first_rpdo < first_tpdo
    assert 0x80 in ids[first_rpdo:first_tpdo]
    assert drive.position == 1234
