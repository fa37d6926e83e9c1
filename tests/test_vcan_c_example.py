"""The C-only example device (examples/c/main_linux.c) on vcan: our Python
client reads its object dictionary over USDO, starts it, and hears its TPDO 1
counting up (a device built from co_stack alone, another process)."""

from __future__ import annotations

import os
import subprocess
import time

import pytest
from helpers import scaled

import canopenfd

pytestmark = pytest.mark.vcan

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BINARY = os.path.join(ROOT, "build", "examples", "fd_device")
NODE = 23


@pytest.fixture
def device(vcan):
    # Built before the vcan lane (tests/test_c_example.py, or make -C examples/c):
    # inside the VM the source tree is read-only.
    assert os.path.exists(BINARY), f"{BINARY} missing: run make -C examples/c first"
    proc = subprocess.Popen([BINARY, vcan[0], str(NODE)], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().startswith(f"node {NODE} serving on {vcan[0]}")
        yield vcan[0]
    finally:
        proc.terminate()
        assert proc.wait(timeout=scaled(5)) == 0


def test_python_client_reads_the_c_device_and_its_tpdo_counts(device):
    can = pytest.importorskip("can")
    raw = can.Bus(interface="socketcan", channel=device, fd=True)
    try:
        with canopenfd.Network() as net:
            line = net.open_line(device, mode="fd")
            node = line.add_node(NODE)
            assert node.usdo.upload("1018:01") == bytes.fromhex("78563412")
            assert node.usdo.upload("1008:00") == b"canopenfd C example"
            node.usdo.download("2001:00", (1234).to_bytes(4, "little"))
            assert node.usdo.upload("2001:00") == (1234).to_bytes(4, "little")
            line.nmt.start(NODE)
            counts = []
            deadline = time.monotonic() + scaled(5)
            while len(counts) < 3 and time.monotonic() < deadline:
                msg = raw.recv(0.1)
                if msg is not None and msg.arbitration_id == 0x180 + NODE:
                    # TPDO 1: the 32-bit counter, an FD frame with bit-rate switch
                    assert msg.is_fd and msg.bitrate_switch and len(msg.data) == 4
                    counts.append(int.from_bytes(msg.data, "little"))
            assert len(counts) >= 3, counts
            assert counts == sorted(counts) and counts[-1] > counts[0]
    finally:
        raw.shutdown()
