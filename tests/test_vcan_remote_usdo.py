"""Remote USDO on real kernel SocketCAN (vcan, CAN FD): vcan0 = fd network 1,
vcan1 = fd network 2, the gateway in its own process (node 1 on both). A
USDO client on network 1 writes and reads device 5 of network 2 through it,
expedited and segmented; the routed request is checked on the wire (cs 0x91,
the extension: destination network 2, node 5, source network 0, node 0x7F).
Needs CANOPENFD_VCAN (see tests/test_vcan.py); tests/vm/run_in_vm.sh
provides it."""

from __future__ import annotations

import subprocess
import sys
import time

import pytest
from helpers import NEUTRAL_CWD, package_env, scaled

import canopenfd
from canopenfd.od import demo_od

pytestmark = pytest.mark.vcan
can = pytest.importorskip("can")

GATEWAY = r'''
import sys
import canopenfd
from canopenfd.od import demo_od

with canopenfd.Network() as network:
    for bus, network_id in ((sys.argv[1], 1), (sys.argv[2], 2)):
        line = network.open_line(bus, mode="fd")
        line.create_local_node(1, od=demo_od("fd"))
        line.network_id = network_id
    print("ready", flush=True)
    sys.stdin.read()          # until the test closes our stdin
'''


@pytest.fixture
def gateway(vcan):
    """The gateway process between vcan0 (network 1) and vcan1 (network 2)."""
    proc = subprocess.Popen([sys.executable, "-c", GATEWAY, vcan[0], vcan[1]],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                            env=package_env(), cwd=NEUTRAL_CWD)
    try:
        assert proc.stdout is not None
        assert proc.stdout.readline().strip() == "ready", "the gateway process did not start"
        yield proc
    finally:
        assert proc.stdin is not None
        proc.stdin.close()
        proc.wait(timeout=scaled(10))


def recv(bus, can_id, first, timeout=5.0):
    """The next frame on can_id whose command specifier is `first`."""
    deadline = time.monotonic() + scaled(timeout)
    while time.monotonic() < deadline:
        msg = bus.recv(0.05)
        if msg is not None and msg.arbitration_id == can_id and msg.data[1] == first:
            return msg
    raise AssertionError(f"no frame 0x{can_id:X} with cs 0x{first:02X} within {timeout} s")


def test_remote_usdo_across_two_vcan_fd_networks(vcan, gateway):
    with canopenfd.Network() as net:
        device = net.open_line(vcan[1], mode="fd").create_local_node(5, od=demo_od("fd"))
        client = net.open_line(vcan[0], mode="fd")
        one = can.Bus(interface="socketcan", channel=vcan[0], fd=True)   # before any frame
        try:
            remote = client.usdo.remote(network=2, node=5, gateway=1)
            remote.download(0x1017, 0, (300).to_bytes(2, "little"), timeout=scaled(2))
            assert device[0x1017].raw == 300
            assert remote.upload(0x1017, timeout=scaled(2)) == (300).to_bytes(2, "little")
            request = recv(one, 0x67F, 0x91)
            assert bytes(request.data[:10]) == bytes([1, 0x91, request.data[2], 2, 5, 0, 0x7F,
                                                      0x00, 0x17, 0x10])
            answer = recv(one, 0x581, 0xB1)
            assert bytes(answer.data[3:14]) == bytes([0, 0x7F, 2, 5, 0x00, 0x17, 0x10, 0x06,
                                                      2, 0x2C, 0x01])
            blob = bytes(range(200))
            remote.download(0x200F, 0, blob, timeout=scaled(2))
            assert remote.upload(0x200F, timeout=scaled(2)) == blob
        finally:
            one.shutdown()
