"""Routing between the lines of one network (CiA 302-7 style, the C core's
co_gateway): `line.network_id` and `network.routing`.

    classic.network_id = 1                 # each joined line is one network
    fd.network_id = 2
    network.routing.route(3, via=2, node=7)     # network 3: behind node 7 on network 2
    network.routing.resolve(3)                  # Route(VIA, <line fd>, 7)
    network.routing.emcy_route(classic, node=5, networks=[2])   # 0x1F2F without an OD
    network.routing.add_callback(print)         # RoutingNotice: loops, refusals
    network.routing.sdo_buffering = False       # relay every SDO frame (default True)

The C core does the per-frame work in the runtime thread: EMCYs of the nodes
0x1F2F names are re-sent on the target networks' lines (re-encoded classic
8 bytes / fd 20 bytes), and objects 0xB000..0xBFFF an RPDO of one joined
line's local node writes are copied to the other joined lines' local nodes,
whose TPDOs mapping them are sent at once. The routes are 0x1F2C's (one
table for all joined lines; a local node's OD with 0x1F2C shows it).
"""

from __future__ import annotations

from typing import Callable, Dict, Iterable, NamedTuple, Optional, Protocol

from .._binding.constants import EventKind, GatewayEvent, GatewayRouteKind
from .._binding.context import Deferred, LineContext
from .._binding.runtime import Event, Runtime
from .._aio import LoopArg
from .._callbacks import CallbackList
from ..errors import ConfigurationError

__all__ = ["GatewayEvent", "GatewayRouteKind", "Route", "RoutingNotice", "RoutingService"]

_EMCY_NETWORKS = 32   # 0x1F2F is UNSIGNED32: one bit per network 1..32


class RoutedLine(Protocol):
    """What routing needs of a line (a canopenfd.Line)."""

    index: int
    channel: str


class Route(NamedTuple):
    """How a network is reached: ATTACHED (`line` carries it), VIA (hand
    requests to gateway `node` on `line`), UNKNOWN or LOOP (line None)."""

    kind: GatewayRouteKind
    line: Optional[RoutedLine]
    node: int


class RoutingNotice(NamedTuple):
    """A route loop met while resolving `network` (abort 0 when found at
    use), or a route to `network` refused (its CiA 301 abort code)."""

    event: GatewayEvent
    network: int
    abort: int


def _network_id(value: object, what: str, allow_zero: bool = False) -> int:
    low = 0 if allow_zero else 1
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= 127:
        raise ConfigurationError(f"{what}: network-ids are {low}..127, got {value!r}")
    return value


class RoutingService:
    """The gateway between the lines of one network; the network makes it."""

    def __init__(self, runtime: Runtime, line_of: Callable[[int], Optional[RoutedLine]]) -> None:
        self._runtime = runtime
        self._line_of = line_of
        self._callbacks = CallbackList("routing notice")
        self._sdo_buffering = True

    def attach(self, context: LineContext) -> None:
        """Hear the gateway's reports on this line (the network calls it for
        every line it opens: reports come on the first joined line)."""
        context.subscribe(EventKind.GATEWAY, self._event)

    def _event(self, ev: Event) -> Deferred:
        notice = RoutingNotice(GatewayEvent(ev.a), ev.node, ev.b)
        return lambda: self._callbacks.fire(notice)

    def add_callback(self, callback: Callable[[RoutingNotice], None],
                     loop: LoopArg = None) -> None:
        self._callbacks.add(callback, loop)

    def remove_callback(self, callback: Callable[[RoutingNotice], None]) -> None:
        self._callbacks.remove(callback)

    # ---------------------------------------------------------------- routes
    def route(self, network: int, *, via: int, node: int) -> None:
        """Network `network` is reached through gateway `node` on network
        `via` (0x1F2C sub network). Refused (ConfigurationError naming the
        abort code) for an attached network, a route through itself or our
        own node, a loop, values out of range."""
        what = f"route to network {network!r} via network {via!r} node {node!r}"
        _network_id(network, what)
        _network_id(via, what)
        if isinstance(node, bool) or not isinstance(node, int) or not 1 <= node <= 127:
            raise ConfigurationError(f"{what}: node-ids are 1..127, got {node!r}")
        self._runtime.gateway_route(network, via, node, what)

    def remove_route(self, network: int) -> None:
        what = f"remove route to network {network!r}"
        self._runtime.gateway_route(_network_id(network, what), 0, 0, what)

    def resolve(self, network: int) -> Route:
        """Where requests for network `network` go now."""
        what = f"resolve network {network!r}"
        kind, index, node = self._runtime.gateway_resolve(_network_id(network, what), what)
        return Route(GatewayRouteKind(kind), self._line_of(index) if index >= 0 else None, node)

    # ---------------------------------------------------------------- EMCY
    def emcy_route(self, line: RoutedLine, node: int, networks: Iterable[int]) -> None:
        """0x1F2F sub `node` of a line whose local node's OD has no such
        entry: EMCYs of `node` heard on `line` are re-sent on `networks`
        (1..32; empty: none)."""
        what = f"line {line.channel!r}: EMCY route of node {node!r}"
        if isinstance(node, bool) or not isinstance(node, int) or not 1 <= node <= 127:
            raise ConfigurationError(f"{what}: node-ids are 1..127")
        mask = 0
        for net in networks:
            if isinstance(net, bool) or not isinstance(net, int) or \
                    not 1 <= net <= _EMCY_NETWORKS:
                raise ConfigurationError(
                    f"{what}: EMCY routes name networks 1..{_EMCY_NETWORKS}, got {net!r}")
            mask |= 1 << (net - 1)
        self._runtime.gateway_emcy_route(line.index, node, mask, what)

    # ---------------------------------------------------------------- SDO networking
    @property
    def sdo_buffering(self) -> bool:
        """True (the default): segmented SDO transfers into a classic network
        keep the two hops running side by side (downloads pipelined: the
        gateway answers the client's segments ahead of the node; uploads
        read ahead by the gateway's own client into its buffer); False:
        every frame relayed as it came, each waiting for the node. fd
        networks are always reached by translation."""
        return self._sdo_buffering

    @sdo_buffering.setter
    def sdo_buffering(self, on: bool) -> None:
        if not isinstance(on, bool):
            raise ConfigurationError(f"routing.sdo_buffering is True or False, got {on!r}")
        self._runtime.gateway_sdo_buffering(on, "routing.sdo_buffering")
        self._sdo_buffering = on

    @property
    def stats(self) -> Dict[str, int]:
        """Counters: EMCYs routed, PDO values forwarded, TPDOs triggered,
        routes refused, loops met (co_gateway_stats_t)."""
        return self._runtime.gateway_stats("routing stats")
