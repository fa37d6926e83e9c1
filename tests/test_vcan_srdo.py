"""SRDO (CiA 304) on real kernel SocketCAN (vcan, classic): the producer and
the consumer in two Networks (two runtime threads, as two devices), the pair
captured with a raw socket: exact bytes, the inverted frame right after its
normal frame, the cycle near SCT (kernel timestamps); a corrupted inverted
frame sent from the raw socket drives the consumer into the safe state.
Needs CANOPENFD_VCAN (see tests/test_vcan.py); tests/vm/run_in_vm.sh provides it."""

from __future__ import annotations

import time

import pytest
from helpers import Recorder, scaled

import canopenfd
from canopenfd.services.srdo import SrdoConfig, SrdoNotice, SrdoState, SrdoViolation

pytestmark = pytest.mark.vcan
can = pytest.importorskip("can")

NORMAL = 0x10B
MAPPING = (0x62000120, 0x62010120)
SCT_MS, SRVT_MS = 50, 20
DATA = bytes([0x12, 0x34, 0x56, 0x78])
INVERTED = bytes(b ^ 0xFF for b in DATA)


def test_srdo_pair_bytes_timing_and_safe_state_on_vcan(vcan):
    iface = vcan[2]                                   # the classic interface
    producer_net, consumer_net = canopenfd.Network(), canopenfd.Network()
    raw = can.Bus(interface="socketcan", channel=iface, fd=False)
    try:
        p = producer_net.open_line(iface, mode="classic").create_local_node(5)
        c = consumer_net.open_line(iface, mode="classic").create_local_node(6)
        p.srdo.start(1)
        c.srdo.start(1)
        p.srdo.configure(1, SrdoConfig("produce", sct_ms=SCT_MS, srvt_ms=SRVT_MS,
                                       cob_id=NORMAL, mapping=MAPPING))
        c.srdo.configure(1, SrdoConfig("consume", sct_ms=min(65535, round(scaled(4 * SCT_MS))),
                                       srvt_ms=min(255, round(scaled(5 * SRVT_MS))),
                                       cob_id=NORMAL, mapping=MAPPING))
        p.srdo.set_data(1, DATA)
        notices = Recorder()
        c.srdo.add_callback(notices)
        c.apply("start")
        c.wait_for_state("OPERATIONAL")
        p.apply("start")
        got = []
        deadline = time.monotonic() + scaled(5)
        while len(got) < 12:
            assert time.monotonic() < deadline, f"{len(got)} SRDO frames seen"
            msg = raw.recv(0.1)
            if msg is not None and msg.arbitration_id in (NORMAL, NORMAL + 1):
                got.append(msg)
        if got[0].arbitration_id != NORMAL:           # joined between the two frames
            got = got[1:11]
        normals = got[0::2]
        for normal, inverse in zip(normals, got[1::2]):
            assert (normal.arbitration_id, bytes(normal.data)) == (NORMAL, DATA)
            assert (inverse.arbitration_id, bytes(inverse.data)) == (NORMAL + 1, INVERTED)
            assert not normal.is_fd and not inverse.is_fd
            assert inverse.timestamp - normal.timestamp < scaled(SRVT_MS / 1000)
        periods = [b.timestamp - a.timestamp for a, b in zip(normals, normals[1:])]
        mean = sum(periods) / len(periods)
        assert SCT_MS / 2000 < mean < scaled(2 * SCT_MS / 1000), periods
        # the consumer took them
        deadline = time.monotonic() + scaled(3)
        while c.srdo.read(1).data != DATA:
            assert time.monotonic() < deadline, c.srdo.read(1)
            time.sleep(0.01)
        # a corrupted pair from another device: the consumer goes safe, naming it
        p.apply("stop")
        time.sleep(scaled(0.05))
        c.srdo.restart(1)
        raw.send(can.Message(arbitration_id=NORMAL, data=DATA, is_extended_id=False))
        raw.send(can.Message(arbitration_id=NORMAL + 1, data=INVERTED[:3] + b"\x00",
                             is_extended_id=False))
        notices.wait_for(lambda calls: SrdoNotice(1, SrdoViolation.INVERTED_MISMATCH)
                         in calls, 3.0, "safe state for the corrupted pair")
        assert c.srdo.read(1).state == SrdoState.SAFE
    finally:
        raw.shutdown()
        producer_net.close()
        consumer_net.close()
