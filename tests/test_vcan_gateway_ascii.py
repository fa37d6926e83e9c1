"""The CiA 309-3 ASCII gateway on real kernel SocketCAN (vcan): the device
and the gateway in two processes' worth of Networks on one interface, a TCP
client reading, writing and hearing the device's boot-up and EMCY (fd on
vcan0, classic on vcan2). Needs CANOPENFD_VCAN (see tests/test_vcan.py);
tests/vm/run_in_vm.sh provides it."""

from __future__ import annotations

import pytest
from test_gateway_ascii_server import Client

import canopenfd
from canopenfd.gateway.ascii309_server import AsciiGateway
from canopenfd.od import demo_od

pytestmark = pytest.mark.vcan


@pytest.mark.parametrize("mode, iface_index", [("fd", 0), ("classic", 2)])
def test_gateway_over_vcan(vcan, mode, iface_index):
    iface = vcan[iface_index]
    with canopenfd.Network() as device_net, canopenfd.Network() as gateway_net:
        line = gateway_net.open_line(iface, mode=mode)
        with AsciiGateway({1: line}).start_in_thread() as server:
            client = Client(server.port)
            device = device_net.open_line(iface, mode=mode).create_local_node(
                5, od=demo_od(mode))
            client.wait_event("1 5 BOOT_UP", timeout=10)
            assert client.ask("[1] 5 w 0x2009 0 vs \"over vcan\"") == "[1] OK"
            assert client.ask("[2] 5 r 0x2009 0 vs") == '[2] "over vcan"'
            assert client.ask("[3] 5 r 0x1018 0 u8") == "[3] 4"
            device.emcy.raise_error(0x5030, b"\x01\x02\x03\x04\x05")
            client.wait_event("1 5 EMCY 5030 01 1 2 3 4 5", timeout=10)
            assert client.ask("[4] 5 start") == "[4] OK"
            device.nmt.wait_for_state("OPERATIONAL")
            client.close()
