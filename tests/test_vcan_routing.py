"""Routing on real kernel SocketCAN (vcan): two vcan interfaces as two
classic networks (vcan0 = network 1, vcan1 = network 2), the gateway in its
own process (node 1 on both), the client and the devices' raw frames in this
one. A client on network 1 reads and writes device 5 of network 2 through the
gateway (SDO networking); device 5's EMCY on network 2 arrives on network 1;
its RPDO's 0xB000 value leaves network 1 as the gateway's TPDO. Needs
CANOPENFD_VCAN (see tests/test_vcan.py); tests/vm/run_in_vm.sh provides it."""

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
from canopenfd.od import DataType, ODArray, ODVariable, demo_od

def od(rpdo, tpdo):
    od = demo_od("classic", pdos=1)
    data = ODArray("Forwarded", 0xB000)
    data.add_member(ODVariable("Highest sub-index", 0xB000, 0, DataType.UNSIGNED8, "ro", 1))
    data.add_member(ODVariable("Value", 0xB000, 1, DataType.UNSIGNED32, "rw", 0,
                               pdo_mapping=True))
    od.add_object(data)
    for comm, cob_id in ((0x1400, rpdo), (0x1800, tpdo)):
        od[comm][1].default = cob_id
        od[comm][2].default = 255
        od[comm + 0x200][0].default = 1
        od[comm + 0x200][1].default = 0xB0000120
    return od

net1, net2 = sys.argv[1], sys.argv[2]
with canopenfd.Network() as network:
    one = network.open_line(net1, mode="classic")
    two = network.open_line(net2, mode="classic")
    one.create_local_node(1, od=od(0x80000201, 0x181))
    two.create_local_node(1, od=od(0x185, 0x80000181))
    one.network_id, two.network_id = 1, 2
    two.on_emcy(lambda emcy: None, nodes=[5])    # network 2 consumes node 5's EMCY
    network.routing.emcy_route(two, 5, [1])
    for line in (one, two):
        line.local_node.nmt.state = "OPERATIONAL"
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


def recv(bus, can_id, timeout=5.0):
    deadline = time.monotonic() + scaled(timeout)
    while time.monotonic() < deadline:
        msg = bus.recv(0.05)
        if msg is not None and msg.arbitration_id == can_id and not msg.is_remote_frame:
            return msg
    raise AssertionError(f"no frame 0x{can_id:X} within {timeout} s")


def test_client_device_emcy_and_pdo_across_two_vcan_networks(vcan, gateway):
    with canopenfd.Network() as net:
        device = net.open_line(vcan[1], mode="classic").create_local_node(
            5, od=demo_od("classic"))
        client = net.open_line(vcan[0], mode="classic")
        one = can.Bus(interface="socketcan", channel=vcan[0])
        two = can.Bus(interface="socketcan", channel=vcan[1])
        try:
            remote = client.sdo.remote(network=2, node=5, gateway=1)
            assert remote.upload(0x1000, timeout=scaled(2)) == device[0x1000].data
            remote.download(0x1017, 0, (300).to_bytes(2, "little"), timeout=scaled(2))
            assert device[0x1017].raw == 300
            # device 5's EMCY on network 2 reaches network 1 unchanged (classic 8 bytes)
            emcy = bytes([0x10, 0x81, 0x11, 1, 2, 3, 4, 5])
            two.send(can.Message(arbitration_id=0x85, data=emcy, is_extended_id=False))
            assert bytes(recv(one, 0x85).data) == emcy
            # its RPDO's 0xB000:01 leaves network 1 as the gateway's TPDO1
            value = (0xC0FFEE).to_bytes(4, "little")
            two.send(can.Message(arbitration_id=0x185, data=value, is_extended_id=False))
            assert bytes(recv(one, 0x181).data) == value
        finally:
            one.shutdown()
            two.shutdown()
