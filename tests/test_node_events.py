"""line.on_node_event: every node's boot-up, state changes and heartbeat
loss/start on a line, watched with add_node or not, without taking the
events from the watched node's own callbacks (the context's observers)."""

from __future__ import annotations

from canopenfd import NmtState
from canopenfd.services.nmt import HeartbeatEvent
from helpers import Recorder, scaled


def test_every_node_heard_and_watched_nodes_keep_their_callbacks(net, bus_name):
    line = net.open_line(bus_name)
    events = Recorder()
    line.on_node_event(events)
    watched = line.add_node(6, heartbeat_timeout_ms=int(scaled(0.3) * 1000))
    bootups = Recorder()
    watched.on_bootup(bootups)
    unwatched = net.open_line(bus_name).create_local_node(5, heartbeat_ms=20)
    other = net.open_line(bus_name).create_local_node(6, heartbeat_ms=20)
    events.wait_for(lambda c: {(5, HeartbeatEvent.BOOTUP), (6, HeartbeatEvent.BOOTUP)} <=
                    {(n, k) for n, k, _ in c}, 5, "both boot-ups")
    bootups.wait_count(1)                          # node 6's own callback still fires
    events.wait_for(lambda c: (6, HeartbeatEvent.STARTED) in {(n, k) for n, k, _ in c}, 5,
                    "heartbeat of watched node 6 started")
    unwatched.nmt.state = "OPERATIONAL"
    events.wait_for(lambda c: (5, HeartbeatEvent.STATE_CHANGED, NmtState.OPERATIONAL) in c, 5,
                    "node 5 operational")
    other.heartbeat_ms = 0                         # watched node 6 goes silent
    events.wait_for(lambda c: (6, HeartbeatEvent.LOST) in {(n, k) for n, k, _ in c}, 5,
                    "node 6 lost")
    assert all(k != HeartbeatEvent.TICK for _, k, _ in events.snapshot())
    line.remove_node_event_callback(events)
    seen = len(events)
    restarted = Recorder()
    watched.on_heartbeat_started(restarted)
    other.heartbeat_ms = 20
    restarted.wait_count(1)                        # the event came, to the node only
    assert len(events) == seen
