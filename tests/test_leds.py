"""CiA 303-3 LEDs of the local node from Python, over the in-process bus:
the callbacks follow NMT commands from another line's master, a lost
heartbeat and the application's configuration error, with the patterns'
timing measured on the callbacks' arrival."""

from __future__ import annotations

import time

import pytest

from canopenfd import ConfigurationError
from canopenfd._binding.constants import LedPattern
from canopenfd.services.leds import LED_PATTERNS, LedIndicator
from helpers import Recorder, scaled

NODE, PEER = 5, 9


def changes_of(recorder, led, start=0):
    return [(on, pattern) for (which, on, pattern) in recorder.snapshot()[start:]
            if which == led]


def test_pattern_names_come_from_the_c_enum():
    assert LED_PATTERNS == ("off", "on", "flickering", "blinking", "single_flash",
                            "double_flash", "triple_flash", "quadruple_flash")
    assert [p.value for p in LedPattern] == list(range(8))


def test_leds_follow_the_nmt_state(net, bus_name):
    master = net.open_line(bus_name, mode="fd")
    line = net.open_line(bus_name, mode="fd")
    node = line.create_local_node(NODE, boot=False)
    assert node.leds.run == LedIndicator("off", False)
    leds = Recorder()
    stamps = []
    node.on_led(lambda led, on, pattern: (stamps.append(time.monotonic()),
                                          leds(led, on, pattern)))
    node.boot()
    # PRE-OPERATIONAL: blinking, dark for the first 200 ms slot (the run LED
    # runs one slot behind the error LED's), then lit 200 ms, dark 200 ms
    leds.wait_count(4, timeout=scaled(5))
    run = changes_of(leds, "run")
    assert run[:4] == [(False, "blinking"), (True, "blinking"), (False, "blinking"),
                       (True, "blinking")]
    gaps = [b - a for a, b in zip(stamps, stamps[1:4])]
    assert all(0.1 < gap < 0.2 + scaled(0.25) for gap in gaps), gaps
    assert node.leds.run.pattern == "blinking"
    assert node.leds.error == LedIndicator("off", False)
    assert not changes_of(leds, "error")

    mark = len(leds)
    master.nmt.start(NODE)
    leds.wait_for(lambda calls: ("run", True, "on") in calls[mark:], timeout=scaled(5))
    assert node.leds.run == LedIndicator("on", True)
    # steady: the stack stops its LED tick, nothing more comes
    time.sleep(scaled(0.3))
    assert changes_of(leds, "run", mark)[-1] == (True, "on")
    settled = len(leds)
    time.sleep(scaled(0.5))
    assert len(leds) == settled

    master.nmt.stop(NODE)
    leds.wait_for(lambda calls: any(c[0] == "run" and c[2] == "single_flash"
                                    for c in calls[settled:]), timeout=scaled(5))
    assert node.leds.run.pattern == "single_flash"
    # a single flash: lit 200 ms out of every 1200
    leds.wait_for(lambda calls: sum(1 for c in calls[settled:] if c == ("run", True,
                                                                      "single_flash")) >= 2,
                  timeout=scaled(5))


def test_heartbeat_lost_double_flashes_the_error_led(net, bus_name):
    line = net.open_line(bus_name, mode="classic")
    node = line.create_local_node(NODE)
    peer_line = net.open_line(bus_name, mode="classic")
    peer = peer_line.create_local_node(PEER, heartbeat_ms=50)
    line.add_node(PEER, heartbeat_timeout_ms=200)
    leds = Recorder()
    node.on_led(leds)
    time.sleep(scaled(0.3))
    assert node.leds.error.pattern == "off"

    mark = len(leds)
    peer.heartbeat_ms = 0
    leds.wait_for(lambda calls: ("error", True, "double_flash") in calls[mark:],
                  timeout=scaled(5))
    assert node.leds.error.pattern == "double_flash"
    assert node.leds.causes == frozenset({"error_control"})
    # the run LED kept blinking, never lit together with the error LED (a
    # LED turning off is told before one turning on at the same moment)
    lit = {"run": False, "error": False}
    for which, on, _pattern in leds.snapshot():
        lit[which] = on
        assert not (lit["run"] and lit["error"])
    mark = len(leds)
    peer.heartbeat_ms = 50
    leds.wait_for(lambda calls: any(c[0] == "error" and c[2] == "off" for c in calls[mark:]),
                  timeout=scaled(5))
    assert node.leds.error == LedIndicator("off", False)
    assert node.leds.causes == frozenset()


def test_configuration_error_blinks_below_communication_errors(net, bus_name):
    line = net.open_line(bus_name, mode="fd")
    node = line.create_local_node(NODE, boot=False)
    with pytest.raises(ConfigurationError, match="not booted"):
        node.set_configuration_error(True)
    node.boot()
    node.set_configuration_error(True)
    assert node.leds.error.pattern == "blinking"
    assert node.leds.causes == frozenset({"config"})
    # no callback: the patterns are still readable, the lit state follows the clock
    seen = set()
    deadline = time.monotonic() + scaled(2)
    while len(seen) < 2 and time.monotonic() < deadline:
        seen.add(node.leds.error.on)
        time.sleep(0.03)
    assert seen == {True, False}
    node.set_configuration_error(False)
    assert node.leds.error == LedIndicator("off", False)


def test_removing_the_last_callback_stops_the_events(net, bus_name):
    line = net.open_line(bus_name, mode="fd")
    node = line.create_local_node(NODE)
    leds = Recorder()
    node.on_led(leds)
    leds.wait_count(2, timeout=scaled(5))
    node.remove_led_callback(leds)
    time.sleep(scaled(0.1))
    count = len(leds)
    time.sleep(scaled(0.6))
    assert len(leds) == count


def test_sync_timeout_triple_flashes_the_error_led(net, bus_name):
    from canopenfd.od import DataType, ODVariable, demo_od

    od = demo_od("fd")
    od.add_object(ODVariable("COB-ID SYNC message", 0x1005, 0, DataType.UNSIGNED32, "rw", 0x80))
    od.add_object(ODVariable("Communication cycle period", 0x1006, 0, DataType.UNSIGNED32,
                             "rw", 0))
    line = net.open_line(bus_name, mode="fd")
    node = line.create_local_node(NODE, od=od)
    node[0x1006].raw = 50_000                  # a SYNC is expected every 50 ms
    producer = net.open_line(bus_name, mode="fd")
    producer.sync.start(0.05)
    leds = Recorder()
    node.on_led(leds)
    time.sleep(scaled(0.3))
    assert node.leds.error.pattern == "off"
    producer.sync.stop()                       # 75 ms after the last SYNC: a SYNC error
    leds.wait_for(lambda calls: ("error", True, "triple_flash") in calls, timeout=scaled(5))
    assert node.leds.causes == frozenset({"sync"})
    mark = len(leds)
    producer.sync.start(0.05)
    leds.wait_for(lambda calls: ("error", False, "off") in calls[mark:], timeout=scaled(5))
    assert node.leds.causes == frozenset()
