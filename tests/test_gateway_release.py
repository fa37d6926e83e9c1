"""A gateway endpoint gives its line back as it found it when it closes:
the EMCYs it made the line consume are no longer consumed (seen by what the
line counts of the EMCY frames a device sends), the nodes it started watching
are no longer watched, the application's own nodes keep their settings."""

from __future__ import annotations

from typing import Any, Tuple

import canopenfd
from canopenfd.gateway.ascii309_server import AsciiGateway
from canopenfd.gateway.remote_access_server import RemoteAccessServer
from canopenfd.od import demo_od

DEV, APP_NODE = 5, 7


class Bus:
    """The gateway's line and a device node DEV on another line of the same
    mem: bus."""

    def __init__(self, net: canopenfd.Network, bus_name: str) -> None:
        self.line = net.open_line(bus_name, mode="fd")
        self.dev = net.open_line(bus_name, mode="fd").create_local_node(DEV, od=demo_od("fd"))
        self.code = 0x5000

    def consumed_dev_emcy(self) -> bool:
        """DEV sends an EMCY, then the line reads an entry of DEV: DEV's
        answer leaves after its EMCY, so once the read is done the line has
        handled the EMCY. Did it count it?"""
        before = self.received()
        self.code += 1
        self.dev.emcy.raise_error(self.code)
        self.line.usdo.upload(DEV, 0x1000, 0)
        delta = self.received() - before
        assert delta in (0, 1), delta
        return delta == 1

    def received(self) -> int:
        stats: Any = self.line.service_stats["emcy_consumer"]
        return int(stats["received"])

    def state(self) -> Tuple[Any, ...]:
        return (sorted(self.line.nodes),
                {n: node.heartbeat_timeout_ms for n, node in self.line.nodes.items()})


def test_ascii_gateway_stops_consuming_emcys_when_closed(net, bus_name):
    bus = Bus(net, bus_name)
    assert not bus.consumed_dev_emcy()
    before = bus.state()
    gateway = AsciiGateway({1: bus.line}).start_in_thread("127.0.0.1", 0)
    assert bus.consumed_dev_emcy()
    gateway.close()
    assert not bus.consumed_dev_emcy()
    assert bus.state() == before


def test_remote_access_server_gives_the_line_back(net, bus_name):
    bus = Bus(net, bus_name)
    app_node = bus.line.add_node(APP_NODE)     # the application's: it stays, unchanged
    before = bus.state()
    # bit 2: monitor every heartbeat (it sets the timeouts of nodes without one)
    server = RemoteAccessServer({1: bus.line}, control=2, heartbeat_ms=400)
    assert bus.consumed_dev_emcy()
    assert sorted(bus.line.nodes) == [n for n in range(1, 128)]
    assert app_node.heartbeat_timeout_ms == 400
    server.close()
    assert not bus.consumed_dev_emcy()
    assert bus.state() == before
    assert bus.line.nodes[APP_NODE] is app_node


def test_two_endpoints_share_a_node_until_both_closed(net, bus_name):
    bus = Bus(net, bus_name)
    first = AsciiGateway({1: bus.line}).start_in_thread("127.0.0.1", 0)
    second = RemoteAccessServer({1: bus.line})
    first.close()
    assert bus.consumed_dev_emcy()      # the remote-access server still asks for it
    second.close()
    assert not bus.consumed_dev_emcy()


def test_a_watched_nodes_consumer_outlives_an_endpoint(net, bus_name):
    bus = Bus(net, bus_name)
    node = bus.line.add_node(DEV)
    node.emcy.add_callback(lambda emcy: None)   # the application consumes DEV's EMCYs
    assert bus.consumed_dev_emcy()
    gateway = AsciiGateway({1: bus.line}).start_in_thread("127.0.0.1", 0)
    gateway.close()
    assert bus.consumed_dev_emcy()
