"""line.service_stats: what the process-data and error services ignored is
counted by reason, visible from Python."""
from __future__ import annotations

import time

from canopenfd.od import demo_od
from helpers import scaled


def wait_for(condition, timeout=2.0):
    end = time.monotonic() + scaled(timeout)
    while not condition():
        assert time.monotonic() < end, "condition not met in time"
        time.sleep(0.005)


def test_wrong_length_sync_time_and_emcy_are_counted(net, bus_name):
    node_line = net.open_line(bus_name, mode="classic")
    node_line.create_local_node(5, od=demo_od("classic"))
    tool = net.open_line(bus_name, mode="classic")
    node_line.add_node(9).emcy              # consume node 9's EMCYs
    tool.send_frame(0x080, b"\x01\x02")    # SYNC: 0 or 1 byte
    tool.send_frame(0x100, b"\x00" * 5)    # TIME: 6 bytes
    tool.send_frame(0x089, b"\x00" * 7)    # classic EMCY: 8 bytes
    tool.send_frame(0x080, b"")            # a good SYNC
    wait_for(lambda: node_line.service_stats["sync"]["received"] == 1)
    stats = node_line.service_stats
    assert stats["sync"]["bad_length"] == 1
    assert stats["time"]["bad_length"] == 1
    assert stats["emcy_consumer"]["rx_bad_length"] == 1
    assert stats["emcy_consumer"]["received"] == 0
    assert stats["pdo"]["rx_frames"] == 0
    # the local node raised EMCY 0x8240 for the bad SYNC and cleared it at the good one
    assert stats["emcy"]["sent"] == 2


def test_a_line_without_services_reports_zeros(net, bus_name):
    line = net.open_line(bus_name, mode="fd")
    stats = line.service_stats
    assert stats["pdo"] == {name: 0 for name in stats["pdo"]}
    assert stats["guard_master"]["rtr_sent"] == 0
    assert stats["pdo_watched"] == 0
