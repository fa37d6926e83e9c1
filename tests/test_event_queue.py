"""The event queue between the runtime thread and Python under a slow consumer:
PDO values are coalesced per source (the newest kept, the skipped ones
counted and reported with the next delivery) instead of dropped at random,
and the events that cannot be merged (EMCY here) still all arrive."""

from __future__ import annotations

import threading
import time

import pytest
from helpers import Recorder, scaled
from test_services import pdo_od

import canopenfd

LOCAL, REMOTE, PRODUCER = 5, 7, 9
VALUES = 4000
EMCYS = 80


def _map_one_value(pdo, cob_id, remote=False):
    """Map "Demo UNSIGNED32" alone; a remote node's PDO only as we hear it
    (there is no node 7 to read it from or save it to)."""
    if not remote:
        pdo.read()
    pdo.clear()
    pdo.add_variable("Demo UNSIGNED32")
    pdo.cob_id = cob_id
    pdo.enabled = True
    if not remote:
        pdo.save()
    return pdo


@pytest.mark.parametrize("source", ["local RPDO", "remote TPDO"])
def test_a_slow_pdo_callback_gets_the_newest_values_and_the_count_it_missed(bus_name, source):
    # 1024 events: from 768 queued on, PDO events coalesce; 256 stay for the rest
    net = canopenfd.Network(event_capacity=1024, stall_report_s=3600)
    try:
        line = net.open_line(bus_name, mode="classic")
        me = line.create_local_node(LOCAL, od=pdo_od("classic"))
        if source == "local RPDO":
            pdo = _map_one_value(me.rpdo[1], 0x200 + LOCAL)
        else:
            pdo = _map_one_value(line.add_node(REMOTE, od=pdo_od("classic")).tpdo[1],
                                 0x180 + REMOTE, remote=True)
        cob_id = pdo.cob_id
        gate = threading.Event()
        got = Recorder()

        def slow(p):
            gate.wait(scaled(30))          # the first call holds the dispatcher
            got((p["Demo UNSIGNED32"].raw, p.skipped))
        pdo.add_callback(slow)
        emcys = Recorder()
        line.add_node(PRODUCER).emcy.add_callback(lambda e: emcys(e.code))
        me.apply("start")
        me.wait_for_state("OPERATIONAL")
        tool = net.open_line(bus_name, mode="classic")
        for i in range(VALUES):
            tool.send_frame(cob_id, i.to_bytes(4, "little"))
            if i % (VALUES // EMCYS) == 0:
                tool.send_frame(0x80 + PRODUCER, (0x1000 + i).to_bytes(2, "little") + bytes(6))
            if i % 100 == 99:
                time.sleep(0.002)           # let the runtime thread move the frames
        deadline = time.monotonic() + scaled(20)
        while line.stats["rx_frames"] < VALUES + EMCYS and time.monotonic() < deadline:
            time.sleep(0.01)
        gate.set()
        calls = got.wait_for(lambda c: c if c and c[-1][0] == VALUES - 1 else None,
                             scaled(20), f"the last value {VALUES - 1}")
        values = [value for value, _ in calls]
        assert values == sorted(set(values))               # in order, none twice
        assert sum(1 + skipped for _, skipped in calls) == VALUES   # every value counted
        assert len(calls) < VALUES / 2                     # it did fall behind
        stats = line.stats
        assert (stats["rx_overflow"], stats["events_lost"], net.events_lost) == (0, 0, 0)
        assert pdo.skipped_total == VALUES - len(calls) == stats["events_coalesced"]
        assert line.events_behind == {pdo.where: pdo.skipped_total}
        assert emcys.wait_count(EMCYS) == [0x1000 + i for i in range(0, VALUES,
                                                                      VALUES // EMCYS)]
    finally:
        net.close()


def test_a_pdo_callback_that_keeps_up_sees_every_value_and_no_skips(net, bus_name):
    line = net.open_line(bus_name, mode="classic")
    me = line.create_local_node(LOCAL, od=pdo_od("classic"))
    pdo = _map_one_value(me.rpdo[1], 0x200 + LOCAL)
    got = Recorder()
    pdo.add_callback(lambda p: got((p["Demo UNSIGNED32"].raw, p.skipped)))
    me.apply("start")
    me.wait_for_state("OPERATIONAL")
    tool = net.open_line(bus_name, mode="classic")
    for i in range(200):
        tool.send_frame(0x200 + LOCAL, i.to_bytes(4, "little"))
    assert got.wait_count(200, scaled(10)) == [(i, 0) for i in range(200)]
    assert line.stats["events_coalesced"] == 0 and line.events_behind == {}
    assert line.stats["events_posted"] >= 200
