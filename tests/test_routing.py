"""Routing between the lines of one Network (line.network_id, network.routing;
the C core's co_gateway running in the runtime thread): a classic line
(network 1) and an fd line (network 2), each with the gateway's local node 1,
and a device line on each bus sending raw frames. Checked on the wire by a
monitor line per bus: a classic RPDO leaves the fd line as a TPDO with the
same bytes, an fd RPDO is split over two classic TPDOs, EMCYs are routed
per 0x1F2F (OD) and per the API (no 0x1F2F) re-encoded for the target line,
and the 0x1F2C routes with their refusals as exceptions naming the abort."""

from __future__ import annotations

import itertools
import time

import pytest

import canopenfd

from canopenfd import ConfigurationError, SdoAbortError, UsdoAbortError
from canopenfd.od import DataType, ODArray, ODVariable, demo_od
from canopenfd.services.routing import GatewayRouteKind
from helpers import Recorder, scaled, virtual_bus

GW = 1
U16, U32 = DataType.UNSIGNED16, DataType.UNSIGNED32
_buses = itertools.count(1)


def _array(od, index, name, dtype, values, mappable=False):
    array = ODArray(name, index)
    array.add_member(ODVariable("Highest sub-index supported", index, 0, DataType.UNSIGNED8,
                                "ro", max(values)))
    for sub in range(1, max(values) + 1):
        array.add_member(ODVariable(f"{name} {sub}", index, sub, dtype[sub - 1]
                                    if isinstance(dtype, list) else dtype, "rw",
                                    values.get(sub, 0), pdo_mapping=mappable))
    od.add_object(array)


def _pdo(od, comm, number, cob_id, mapping):
    od[comm + number - 1][1].default = cob_id
    od[comm + number - 1][2].default = 255
    maps = od[comm + 0x200 + number - 1]
    maps[0].default = len(mapping)
    for sub, value in enumerate(mapping, 1):
        maps[sub].default = value


def gateway_od(mode):
    """0xB000: U16 + U32 (classic -> fd), 0xB001: 4 x U32 (fd -> classic);
    0x1028 consumes nodes 5 and 6; the classic side has 0x1F2F and 0x1F2C."""
    od = demo_od(mode, pdos=2)
    _array(od, 0xB000, "to fd", [U16, U32], {1: 0, 2: 0}, mappable=True)
    _array(od, 0xB001, "to classic", U32, {1: 0, 2: 0, 3: 0, 4: 0}, mappable=True)
    _array(od, 0x1028, "Emergency consumer", U32,
           {**{n: 0x80000000 for n in range(1, 8)}, 5: 0x85, 6: 0x86})
    if mode == "classic":
        _array(od, 0x1F2F, "EMCY routing", U32, {n: 0 for n in range(1, 8)} | {5: 0x2})
        _array(od, 0x1F2C, "Network routes", U32, {n: 0 for n in range(1, 11)})
        _pdo(od, 0x1400, 1, 0x185, [0xB0000110, 0xB0000220])
        _pdo(od, 0x1800, 1, 0x181, [0xB0010120, 0xB0010220])
        _pdo(od, 0x1800, 2, 0x281, [0xB0010320, 0xB0010420])
    else:
        _pdo(od, 0x1400, 1, 0x206, [0xB0010120, 0xB0010220, 0xB0010320, 0xB0010420])
        _pdo(od, 0x1800, 1, 0x181, [0xB0000110, 0xB0000220])
    return od


class Rig:
    def __init__(self, net):
        n = next(_buses)
        self.net = net
        self.buses = {mode: f"mem:routing-{mode}-{n}" for mode in ("classic", "fd")}
        self.gw = {}
        self.dev = {}
        self.seen = {}
        for mode, bus in self.buses.items():
            self.gw[mode] = net.open_line(bus, mode=mode)
            self.gw[mode].create_local_node(GW, od=gateway_od(mode))
            self.dev[mode] = net.open_line(bus, mode=mode)
            self.seen[mode] = Recorder()
            net.open_line(bus, mode=mode, monitor=True).on_frame(self.seen[mode])
        self.gw["classic"].network_id = 1
        self.gw["fd"].network_id = 2
        for mode in self.buses:
            self.dev[mode].nmt.start(GW)
            self.gw[mode].local_node.nmt.wait_for_state("OPERATIONAL", timeout=5)

    def frames(self, mode, can_id, count, what):
        def enough(calls):
            got = [f for f in calls if f.id == can_id]
            return got if len(got) >= count else None
        return self.seen[mode].wait_for(enough, 5.0, what)


@pytest.fixture
def rig(net):
    return Rig(net)


def test_network_ids_and_refusals(rig):
    classic, fd = rig.gw["classic"], rig.gw["fd"]
    assert (classic.network_id, fd.network_id) == (1, 2)
    assert rig.dev["classic"].network_id is None
    with pytest.raises(ConfigurationError, match="carries network 1 already"):
        rig.dev["classic"].network_id = 1
    with pytest.raises(ConfigurationError, match=r"network-id must be 1\.\.127"):
        rig.dev["classic"].network_id = 128


def test_classic_rpdo_leaves_the_fd_line_as_a_tpdo(rig):
    data = bytes([0x34, 0x12, 0x78, 0x56, 0x34, 0x12])
    rig.dev["classic"].send_frame(0x185, data)
    (frame,) = rig.frames("fd", 0x181, 1, "the forwarded TPDO on the fd line")
    assert frame.data == data and frame.fd
    assert rig.gw["fd"].local_node[0xB000][2].raw == 0x12345678   # the fd node's copy
    stats = rig.net.routing.stats
    assert stats["pdo_forwarded"] == 1 and stats["pdo_values"] == 2
    assert stats["tpdo_triggered"] == 1


def test_fd_rpdo_is_split_over_two_classic_tpdos(rig):
    data = bytes(range(0xA0, 0xB0))
    rig.dev["fd"].send_frame(0x206, data)
    (first,) = rig.frames("classic", 0x181, 1, "classic TPDO1")
    (second,) = rig.frames("classic", 0x281, 1, "classic TPDO2")
    assert (first.data, second.data) == (data[:8], data[8:])
    assert not first.fd and rig.net.routing.stats["tpdo_triggered"] == 2


def test_emcy_routed_by_0x1f2f_and_by_the_api(rig):
    classic_emcy = bytes([0x10, 0x81, 0x11, 1, 2, 3, 4, 5])
    rig.dev["classic"].send_frame(0x85, classic_emcy)
    (frame,) = rig.frames("fd", 0x85, 1, "node 5's EMCY on the fd line")
    assert frame.data == classic_emcy + bytes(12)        # the 20-byte FD EMCY
    # the fd side has no 0x1F2F: the API routes node 6 to network 1
    rig.net.routing.emcy_route(rig.gw["fd"], 6, [1])
    fd_emcy = bytes([0x30, 0x42, 0x05, 9, 8, 7, 6, 5, 1, 0x15, 0x05, 1, 1, 2, 3, 4, 5, 6,
                     0, 0])
    rig.dev["fd"].send_frame(0x86, fd_emcy)
    (frame,) = rig.frames("classic", 0x86, 1, "node 6's EMCY on the classic line")
    assert frame.data == fd_emcy[:8]
    assert rig.net.routing.stats["emcy_routed"] == 2
    with pytest.raises(ConfigurationError, match="networks 1..32"):
        rig.net.routing.emcy_route(rig.gw["fd"], 6, [33])



def test_two_gateways_do_not_bounce_an_emcy(net):
    """Gateway A (this Network, node 1) re-sends network 2's node 5 EMCY on
    network 1, gateway B (a second Network, node 2; the two share python-can
    virtual buses) network 1's node 5 EMCY on network 2. Device 5's EMCY passes A once and
    B once, then stops: A takes B's copy on network 2 for the echo of the
    EMCY it re-sent (counted), instead of the two bouncing it for ever."""
    n = next(_buses)
    buses = {1: f"routing-echo-x-{n}", 2: f"routing-echo-y-{n}"}
    seen = {net_id: Recorder() for net_id in buses}
    for net_id, bus in buses.items():
        net.open_line(bus=virtual_bus(bus), mode="classic", monitor=True).on_frame(
            seen[net_id])

    def join(network, node_id):
        lines = {}
        for net_id, bus in buses.items():
            od = demo_od("classic")
            _array(od, 0x1028, "Emergency consumer", U32,
                   {**{k: 0x80000000 for k in range(1, 8)}, 5: 0x85})
            lines[net_id] = network.open_line(bus=virtual_bus(bus), mode="classic")
            lines[net_id].create_local_node(node_id, od=od)
            lines[net_id].network_id = net_id
        return lines

    with canopenfd.Network() as other:
        a, b = join(net, 1), join(other, 2)
        net.routing.emcy_route(a[2], 5, [1])     # A: network 2's node 5 -> network 1
        other.routing.emcy_route(b[1], 5, [2])   # B: network 1's node 5 -> network 2
        emcy = bytes([0x10, 0x81, 0x11, 1, 2, 3, 4, 5])
        net.open_line(bus=virtual_bus(buses[2]), mode="classic").send_frame(0x85, emcy)

        def count(net_id):
            return sum(f.id == 0x85 for f in seen[net_id].snapshot())

        seen[1].wait_for(lambda calls: count(1) >= 1 or None, 5.0, "A's copy on network 1")
        seen[2].wait_for(lambda calls: count(2) >= 2 or None, 5.0, "B's copy on network 2")
        deadline = time.monotonic() + scaled(5.0)
        while net.routing.stats["emcy_echoes"] < 1 and time.monotonic() < deadline:
            time.sleep(0.01)
        time.sleep(scaled(0.3))                  # a bounce would have gone on by now
        assert (count(1), count(2)) == (1, 2)
        assert all(f.data == emcy for net_id in buses for f in seen[net_id].snapshot()
                   if f.id == 0x85)
        assert net.routing.stats["emcy_routed"] == 1
        assert net.routing.stats["emcy_echoes"] == 1
        assert other.routing.stats["emcy_routed"] == 1

def test_routes_resolve_refuse_and_report_loops(rig):
    routing = rig.net.routing
    notices = Recorder()
    routing.add_callback(notices)
    assert routing.resolve(1).kind == GatewayRouteKind.ATTACHED
    assert routing.resolve(1).line is rig.gw["classic"]
    assert routing.resolve(9).kind == GatewayRouteKind.UNKNOWN
    routing.route(3, via=2, node=7)
    routing.route(4, via=3, node=9)
    route = routing.resolve(4)
    assert (route.kind, route.line, route.node) == (GatewayRouteKind.VIA, rig.gw["fd"], 7)
    with pytest.raises(ConfigurationError, match="0x06040043"):
        routing.route(3, via=4, node=9)                  # 3 -> 4 -> 3
    with pytest.raises(ConfigurationError, match="0x06040043"):
        routing.route(2, via=1, node=7)                  # attached
    with pytest.raises(ConfigurationError, match="0x06040043"):
        routing.route(5, via=1, node=GW)                 # through our own node
    notices.wait_for(lambda calls: len(calls) >= 4 or None, 5.0, "loop + 3 refusals")
    events = [(n.event.name, n.network, n.abort) for n in notices.snapshot()]
    assert ("ROUTE_LOOP", 3, 0x06040043) in events
    assert events.count(("ROUTE_REFUSED", 3, 0x06040043)) == 1
    assert routing.stats["routes_refused"] == 3 and routing.stats["route_loops"] == 1
    routing.remove_route(4)
    assert routing.resolve(4).kind == GatewayRouteKind.UNKNOWN


def _relay_rig(net, name, od=None):
    """The gateway's node 1 joining classic networks 1 (bus a) and 3 (bus
    c), device 5 on network 3 (the demo OD unless `od`), a monitor on each
    bus: (a client line on network 1, device 5, frames seen on a, frames
    seen on c)."""
    n = next(_buses)
    a, c = f"mem:routing-{name}-a-{n}", f"mem:routing-{name}-c-{n}"
    for bus, network_id in ((a, 1), (c, 3)):
        gateway = net.open_line(bus, mode="classic")
        gateway.create_local_node(GW, od=demo_od("classic"))
        gateway.network_id = network_id
    target = net.open_line(c, mode="classic").create_local_node(
        5, od=od if od is not None else demo_od("classic"))
    seen_a, seen_c = Recorder(), Recorder()
    net.open_line(a, mode="classic", monitor=True).on_frame(seen_a)
    net.open_line(c, mode="classic", monitor=True).on_frame(seen_c)
    return net.open_line(a, mode="classic"), target, seen_a, seen_c


def test_sdo_networking_reaches_a_node_of_another_network(net):
    """A client on network 1 reads and writes device 5 of network 3 through
    the gateway (node 1 on both classic lines): the network indication, then
    every frame relayed; a network no route reaches is the gateway's abort."""
    client, target, seen_a, seen_c = _relay_rig(net, "sdo")

    device = client.sdo.remote(network=3, node=5, gateway=GW)
    assert device.upload(0x1000) == target[0x1000].data     # device 5's own value
    device.download(0x1017, 0, (250).to_bytes(2, "little"))
    assert target[0x1017].raw == 250
    indication = bytes([0xE0, 3, 0, 5, 0, 0, 0, 0])
    requests = seen_a.wait_for(
        lambda calls: [f for f in calls if f.id == 0x601] or None, 5.0, "client requests")
    assert requests[0].data == indication
    relayed = seen_c.wait_for(
        lambda calls: [f for f in calls if f.id == 0x605] or None, 5.0, "relayed request")
    assert relayed[0].data == bytes([0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0])
    stats = net.routing.stats
    assert stats["sdo_connects"] == 1 and stats["sdo_relayed"] >= 1

    with pytest.raises(SdoAbortError, match="0x08000000") as refused:
        client.sdo.remote(network=9, node=5, gateway=GW).upload(0x1000)
    assert refused.value.from_server
    with pytest.raises(ConfigurationError, match="network must be 1..127"):
        client.sdo.remote(network=0, node=5, gateway=GW)


def test_sdo_networking_overlaps_the_hops_into_a_classic_network(net):
    """A 300-byte value written and read segmented through the gateway into
    classic network 3. Download: device 5 sees the client's own frames, the
    gateway answers the client's segments ahead of the device (pipelined);
    upload: the gateway's own client reads the device (its segment requests
    run ahead of the client's). Then routing.sdo_buffering off: every frame
    relayed, nothing answered ahead."""
    od = demo_od("classic")
    od.add_object(ODVariable("Blob", 0x2400, 0, DataType.OCTET_STRING, "rw",
                             default=b"", max_length=300))
    client, target, _, seen_c = _relay_rig(net, "buf", od)
    device = client.sdo.remote(network=3, node=5, gateway=GW)
    assert net.routing.sdo_buffering is True

    blob = bytes(range(256)) + bytes(44)
    device.download(0x2400, 0, blob, mode="segmented")
    assert target[0x2400].data == blob
    to_device = seen_c.wait_for(
        lambda calls: [f.data for f in calls if f.id == 0x605][43:] and
        [f.data for f in calls if f.id == 0x605], 5.0, "the 44 requests")
    assert to_device[0] == bytes([0x21, 0x00, 0x24, 0x00, 44, 1, 0, 0])   # the client's own
    assert to_device[1][0] == 0x00 and to_device[1][1:] == blob[:7]
    assert net.routing.stats["sdo_pipelined"] == 42     # 43 segments, the last one waits
    assert device.upload(0x2400, mode="segmented") == blob
    assert net.routing.stats["sdo_translated"] == 1

    net.routing.sdo_buffering = False
    start = len(seen_c)
    device.download(0x2400, 0, blob[::-1], mode="segmented")
    assert target[0x2400].data == blob[::-1]
    assert device.upload(0x2400, mode="segmented") == blob[::-1]
    initiate = bytes([0x21, 0x00, 0x24, 0x00, 44, 1, 0, 0])
    seen_c.wait_for(lambda calls: [f for f in calls[start:] if f.id == 0x605 and
                                   f.data == initiate] or None, 5.0, "the relayed initiate")
    stats = net.routing.stats
    assert stats["sdo_pipelined"] == 42 and stats["sdo_translated"] == 1
    with pytest.raises(ConfigurationError, match="True or False"):
        net.routing.sdo_buffering = 1


def test_remote_usdo_reaches_a_node_of_another_fd_network(net):
    """A USDO client on fd network 1 reads and writes device 5 of fd network
    2 through the gateway (node 1 on both lines): each request is a routed
    frame (cs | 0x80, destination network and node, source network and
    node) the gateway carries out with its own USDO client on network 2."""
    n = next(_buses)
    a, b = f"mem:routing-usdo-a-{n}", f"mem:routing-usdo-b-{n}"
    for bus, network_id in ((a, 1), (b, 2)):
        gateway = net.open_line(bus, mode="fd")
        gateway.create_local_node(GW, od=demo_od("fd"))
        gateway.network_id = network_id
    target = net.open_line(b, mode="fd").create_local_node(5, od=demo_od("fd"))
    seen_a, seen_b = Recorder(), Recorder()
    net.open_line(a, mode="fd", monitor=True).on_frame(seen_a)
    net.open_line(b, mode="fd", monitor=True).on_frame(seen_b)
    client = net.open_line(a, mode="fd")

    device = client.usdo.remote(network=2, node=5, gateway=GW)
    value = int(target[0x1017].raw).to_bytes(2, "little")
    assert device.upload(0x1017) == value
    device.download(0x1017, 0, (250).to_bytes(2, "little"))
    assert target[0x1017].raw == 250
    # on network 1: the routed upload request, addressed to the gateway;
    # the client's line has no network-id: source network 0
    requests = seen_a.wait_for(
        lambda calls: [f for f in calls if f.id == 0x67F] or None, 5.0, "client requests")
    first = requests[0].data
    assert first[0:2] == bytes([GW, 0x91])
    assert first[3:10] == bytes([2, 5, 0, 0x7F, 0x00, 0x17, 0x10])
    answers = seen_a.wait_for(
        lambda calls: [f for f in calls if f.id == 0x580 + GW] or None, 5.0, "answers")
    assert answers[0].data[0:2] == bytes([0x7F, 0xB1])
    assert answers[0].data[3:10] == bytes([0, 0x7F, 2, 5, 0x00, 0x17, 0x10])
    assert answers[0].data[11:14] == bytes([2]) + value
    # on network 2: a local upload from the gateway's node to device 5
    forwarded = seen_b.wait_for(
        lambda calls: [f for f in calls if f.id == 0x600 + GW] or None, 5.0, "forwarded")
    assert forwarded[0].data[0:2] == bytes([5, 0x11])
    assert forwarded[0].data[3:6] == bytes([0x00, 0x17, 0x10])
    stats = net.routing.stats
    assert stats["usdo_forwarded"] == 2 and stats["usdo_answered"] == 2

    with pytest.raises(UsdoAbortError, match="0x1A") as refused:
        client.usdo.remote(network=9, node=5, gateway=GW).upload(0x1017)
    assert refused.value.from_server
    with pytest.raises(UsdoAbortError, match="0x34|0x33"):
        device.upload(0x1017, 0x77)


def test_remote_usdo_segmented_both_ways(net):
    """A 300-byte value through the gateway: the client's routed segmented
    download (0x82, then 0x83 / 0x84 without the extension) is collected by
    the gateway and sent on; the upload comes back routed and segmented
    (0xB2, 0xB3 ..., 0xB4)."""
    n = next(_buses)
    a, b = f"mem:routing-usdo-seg-a-{n}", f"mem:routing-usdo-seg-b-{n}"
    for bus, network_id in ((a, 1), (b, 2)):
        gateway = net.open_line(bus, mode="fd")
        gateway.create_local_node(GW, od=demo_od("fd"))
        gateway.network_id = network_id
    target = net.open_line(b, mode="fd").create_local_node(5, od=demo_od("fd"))
    seen_a = Recorder()
    net.open_line(a, mode="fd", monitor=True).on_frame(seen_a)
    client = net.open_line(a, mode="fd")
    value = bytes(range(256)) + bytes(44)
    device = client.usdo.remote(network=2, node=5, gateway=GW)
    device.download(0x200F, 0, value)
    assert target[0x200F].raw == value
    assert device.upload(0x200F) == value

    def both(calls):
        found = {(f.id, f.data[1]) for f in calls if f.id in (0x67F, 0x580 + GW)}
        return found if (0x581, 0xB4) in found else None
    commands = seen_a.wait_for(both, 5.0, "the routed frames")
    assert {(0x67F, 0x82), (0x67F, 0x83), (0x67F, 0x84), (0x67F, 0x91), (0x67F, 0x93)} <= commands
    assert {(0x581, 0xA2), (0x581, 0xA3), (0x581, 0xA4), (0x581, 0xB2), (0x581, 0xB3)} <= commands
    assert net.routing.stats["usdo_answered"] == 2
    with pytest.raises(ConfigurationError, match="bulk transfers are not routed"):
        device.download(0x200F, 0, value, mode="bulk")


def test_sdo_networking_reaches_a_node_of_an_fd_network(net):
    """A classic client on network 1 reads and writes device 6 of the fd
    network 2: the gateway serves the client's SDO transfer and moves the
    value with a USDO transfer on the fd bus (checked on both buses); a
    value of 3000 bytes goes segmented (the client's block initiate is
    refused 0x05040001, it falls back), and a device abort comes back
    mapped to its CiA 301 code."""
    n = next(_buses)
    a, b = f"mem:routing-sdofd-a-{n}", f"mem:routing-sdofd-b-{n}"
    for bus, mode, network_id in ((a, "classic", 1), (b, "fd", 2)):
        gateway = net.open_line(bus, mode=mode)
        gateway.create_local_node(GW, od=demo_od(mode))
        gateway.network_id = network_id
    od = demo_od("fd")
    od.add_object(ODVariable("Blob", 0x2400, 0, DataType.OCTET_STRING, "rw",
                             default=b"", max_length=3000))
    target = net.open_line(b, mode="fd").create_local_node(6, od=od)
    seen_a, seen_b = Recorder(), Recorder()
    net.open_line(a, mode="classic", monitor=True).on_frame(seen_a)
    net.open_line(b, mode="fd", monitor=True).on_frame(seen_b)
    client = net.open_line(a, mode="classic")

    device = client.sdo.remote(network=2, node=6, gateway=GW)
    assert int.from_bytes(device.upload(0x1017), "little") == target[0x1017].raw
    # on the fd bus: the gateway's USDO upload (client node-id 1) of 0x1017
    usdo = seen_b.wait_for(lambda calls: [f for f in calls if f.id == 0x601] or None,
                           5.0, "the gateway's USDO request")
    assert usdo[0].data[:2] == bytes([6, 0x11]) and usdo[0].data[3:6] == bytes([0, 0x17, 0x10])
    device.download(0x1017, 0, (250).to_bytes(2, "little"))
    assert target[0x1017].raw == 250
    usdo = seen_b.wait_for(lambda calls: [f for f in calls if f.id == 0x601][1:] or None,
                           5.0, "the gateway's USDO download")
    assert usdo[0].data[:2] == bytes([6, 0x01])
    assert usdo[0].data[3:10] == bytes([0, 0x17, 0x10, 0x0F, 2, 250, 0])

    blob = bytes(range(256)) * 11 + bytes(184)
    device.download(0x2400, 0, blob)
    assert target[0x2400].data == blob
    assert device.upload(0x2400) == blob
    refused = seen_a.wait_for(
        lambda calls: [f for f in calls if f.id == 0x581 and f.data[0] == 0x80] or None,
        5.0, "the refused block initiate")
    assert refused[0].data[4:] == bytes([0x01, 0x00, 0x04, 0x05])

    with pytest.raises(SdoAbortError, match="0x06020000"):
        device.upload(0x2FFF)
    stats = net.routing.stats
    assert stats["sdo_connects"] == 1 and stats["sdo_translated"] == 4
    assert stats["sdo_translate_failed"] == 2    # the block initiate, 0x2FFF


def test_a_rebuilt_gateway_ends_its_sdo_connections(net):
    """A line joining rebuilds the gateway: its open SDO networking
    connection ends with abort 0x060A0023 to the client and to the device
    (counted); the client's next routed request is refused so, the client
    sends the network indication again and the request after it, and the
    caller gets the value."""
    client, target, seen_a, seen_c = _relay_rig(net, "rebuild")
    device = client.sdo.remote(network=3, node=5, gateway=GW)
    assert device.upload(0x1000) == target[0x1000].data

    def frames(seen, can_id, count, what):
        return seen.wait_for(
            lambda calls: [f.data for f in calls if f.id == can_id][:count]
            if sum(f.id == can_id for f in calls) >= count else None, 5.0, what)

    joining = net.open_line(f"mem:routing-rebuild-d-{next(_buses)}", mode="classic")
    joining.create_local_node(GW, od=demo_od("classic"))
    joining.network_id = 4                              # the gateway is rebuilt
    ended = bytes([0x80, 0x00, 0x10, 0x00, 0x23, 0x00, 0x0A, 0x06])
    assert frames(seen_a, 0x581, 3, "the client's abort")[2] == ended   # after E0, 43
    assert frames(seen_c, 0x605, 2, "the device's abort")[1] == ended
    assert net.routing.stats["connections_ended"] == 1

    assert device.upload(0x1018, 1) == target[0x1018][1].data
    up = bytes([0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0])
    indication = bytes([0xE0, 3, 0, 5, 0, 0, 0, 0])
    assert frames(seen_a, 0x601, 5, "the requests")[2:] == [up, indication, up]
    answers = frames(seen_a, 0x581, 6, "the answers")[3:]
    assert answers[:2] == [bytes([0x80, 0x18, 0x10, 0x01, 0x23, 0x00, 0x0A, 0x06]), indication]
    assert answers[2][:4] == bytes([0x43, 0x18, 0x10, 0x01])
