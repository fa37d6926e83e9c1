"""USDO bulk upload of 1 MiB on real SocketCAN (vcan, FD): the server and
the client on two sockets of one interface, every byte compared, no frame
lost in the kernel or in the client's receive queue (the client's window
keeps the server's stream within it). The time of a bulk and a segmented
upload and of a bulk download are printed side by side, never asserted."""

from __future__ import annotations

import os
import time

import pytest
from helpers import scaled

import canopenfd
from canopenfd.od import demo_od

pytestmark = pytest.mark.vcan

SERVER = 5
DOMAIN = 0x2100
MiB = 1 << 20


def test_bulk_upload_of_1_mib_on_vcan(vcan, capsys):
    data = os.urandom(MiB)
    with canopenfd.Network() as net:
        device_line = net.open_line(vcan[0], mode="fd")
        device = device_line.create_local_node(SERVER, od=demo_od("fd"), boot=False)
        device.serve_domain(DOMAIN, 2 * MiB)
        device.boot()
        device[DOMAIN].data = data
        line = net.open_line(vcan[0], mode="fd")
        times = {}
        for mode in ("bulk", "auto"):
            started = time.monotonic()
            transfer = line.usdo.start_upload(SERVER, DOMAIN, 0, mode=mode, max_size=MiB,
                                              timeout=scaled(2))
            assert transfer.result(timeout=scaled(120)) == data
            times[transfer.mode] = time.monotonic() - started
        assert set(times) == {"bulk", "segmented"}
        started = time.monotonic()
        down = line.usdo.start_download(SERVER, DOMAIN, 0, data[::-1], mode="bulk",
                                        timeout=scaled(2))
        down.result(timeout=scaled(120))
        times["bulk download"] = time.monotonic() - started
        assert device[DOMAIN].data == data[::-1]
        client = line.service_stats["usdo_client"]
        server = device_line.service_stats["usdo_server"]
        assert client["bulk_uploads"] == 1 and server["bulk_uploads"] == 1
        # an acknowledgement every 32 segments until the server's credit (a
        # window of 64 beyond) covers the rest: none crosses the end
        segments = -(-MiB // 60)
        assert client["acks_sent"] == sum(1 for k in range(1, segments)
                                          if 32 * k + 32 < segments)
        assert server["rx_stray_ack"] == 0
        assert line.stats["rx_overflow"] == 0
        assert line.driver_stats["kernel_drops"] == 0
    with capsys.disabled():
        print("\n1 MiB on " + vcan[0] + ": " + ", ".join(
            f"{name} {seconds:.2f} s ({MiB / seconds / 1e6:.2f} MB/s)"
            for name, seconds in times.items()))
