"""Multiplexed PDOs on real kernel SocketCAN (vcan), classic (MTU 16) and fd
(MTU 72): two local nodes in separate Networks exchange DAM and SAM MPDOs;
a raw python-can socket checks every frame's CAN-ID, flags and 8 bytes, and
a DAM for a missing object brings EMCY 0x8230 on the wire. Needs
CANOPENFD_VCAN (tests/vm/run_in_vm.sh provides it). python-canopen has no
MPDO service, so no interop peer exists."""

from __future__ import annotations

import time

import pytest
from helpers import scaled
from test_mpdo import A, B, DATA, make_pair_mpdos, mpdo_od, wait_value

import canopenfd

pytestmark = pytest.mark.vcan
can = pytest.importorskip("can")


@pytest.fixture(params=["classic", "fd"])
def wire(request, vcan):
    mode = request.param
    iface = vcan[0] if mode == "fd" else vcan[2]
    nets, raw = [], can.Bus(interface="socketcan", channel=iface, fd=mode == "fd")
    try:
        nodes = {}
        for me in (A, B):
            nets.append(canopenfd.Network())
            node = nets[-1].open_line(iface, mode=mode).create_local_node(
                me, od=mpdo_od(mode, A + B - me))
            make_pair_mpdos(node, me, A + B - me)
            nodes[me] = node
        yield mode, nodes, raw
    finally:
        raw.shutdown()
        for net in nets:
            net.close()


def recv(raw, can_id, timeout=3.0):
    deadline = time.monotonic() + scaled(timeout)
    while True:
        remaining = deadline - time.monotonic()
        assert remaining > 0, f"no frame 0x{can_id:X} within {scaled(timeout)} s"
        msg = raw.recv(max(0.01, remaining))
        if msg is not None and not msg.is_error_frame and msg.arbitration_id == can_id:
            return msg


def test_mpdo_bytes_on_the_wire(wire):
    mode, nodes, raw = wire
    nodes[A].tpdo[1].send_dam(B, DATA, 3, bytes([0x44, 0x33, 0x22, 0x11]))
    msg = recv(raw, 0x180 + A)
    assert bytes(msg.data) == bytes([0x86, 0x00, 0x23, 0x03, 0x44, 0x33, 0x22, 0x11])
    assert msg.is_fd == (mode == "fd")
    wait_value(nodes[B], DATA, 3, 0x11223344)

    nodes[B][DATA][2].raw = 0xCAFE0042
    nodes[B].tpdo[2].send_sam(DATA, 2)
    msg = recv(raw, 0x280 + B)
    assert bytes(msg.data) == bytes([B, 0x00, 0x23, 0x02, 0x42, 0x00, 0xFE, 0xCA])
    assert msg.is_fd == (mode == "fd")
    wait_value(nodes[A], DATA, 10, 0xCAFE0042)

    nodes[A].tpdo[1].send_dam(B, 0x2FFF, 0, bytes([1]))
    emcy = recv(raw, 0x80 + B)
    if mode == "classic":
        assert bytes(emcy.data[:2]) == bytes([0x30, 0x82]) and bytes(emcy.data[3:5]) == b"\x01\x00"
    assert nodes[B].mpdo_stats()["rx_refused"] == 1
