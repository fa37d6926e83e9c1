"""CiA 401 I/O device on real kernel SocketCAN (vcan): the TPDO bytes its
inputs send and the outputs a raw RPDO sets, on an fd and a classic vcan,
captured and sent with raw python-can sockets. Needs CANOPENFD_VCAN (see
tests/test_vcan.py); tests/vm/run_in_vm.sh provides it."""

from __future__ import annotations

import pytest
from helpers import Recorder, scaled
from test_vcan_services import recv_all

import canopenfd
from canopenfd.profiles.cia401 import Outputs, create_io_device

pytestmark = pytest.mark.vcan
can = pytest.importorskip("can")

NODE = 5


@pytest.mark.parametrize("mode", ["fd", "classic"])
def test_tpdo_and_rpdo_bytes_on_vcan(vcan, mode):
    channel = vcan[0] if mode == "fd" else vcan[2]
    raw = can.Bus(interface="socketcan", channel=channel, fd=mode == "fd")
    try:
        with canopenfd.Network() as net:
            outputs = Recorder()
            dev = create_io_device(net.open_line(channel, mode=mode), NODE,
                                   on_outputs=outputs)
            dev.node.apply("start")
            dev.node.wait_for_state("OPERATIONAL")
            dev.set_inputs(0x8001)
            tpdo = recv_all(raw, 0x180 + NODE, 1)[0]
            assert bytes(tpdo.data) == bytes.fromhex("0180")
            assert tpdo.is_fd == (mode == "fd")
            raw.send(can.Message(arbitration_id=0x200 + NODE, data=b"\x5a",
                                 is_extended_id=False, is_fd=mode == "fd"))
            raw.send(can.Message(arbitration_id=0x300 + NODE,
                                 data=(-2).to_bytes(2, "little", signed=True) + b"\x10\x00",
                                 is_extended_id=False, is_fd=mode == "fd"))
            seen = outputs.wait_count(2, timeout=scaled(5))
            assert seen[:2] == [Outputs(0x5A, (0, 0)), Outputs(0x5A, (-2, 16))]
    finally:
        raw.shutdown()
