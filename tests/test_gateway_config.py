"""The gateway's configuration file and the Gateway it builds: every mistake
named with file and line; a configured gateway opens its lines, watches its
nodes and publishes them to MQTT."""

from __future__ import annotations

import pathlib
import textwrap

import pytest

from canopenfd import Network
from canopenfd.gateway.config import GatewayConfigError, load_config, parse_config
from canopenfd.gateway.gateway import Gateway
from canopenfd.od import demo_od

GOOD = textwrap.dedent("""\
    [gateway]
    name = plant-gw

    [line 1]            ; the fd line
    channel = mem:gwcfg-1
    mode = fd
    node_id = 1
    heartbeat_ms = 100

    [line 2]
    channel = mem:gwcfg-2
    mode = classic
    routing = off

    [routes]
    3 = 1:7

    [node 2.9]
    heartbeat_timeout_ms = 300
    pdos = none

    [node 1.5]
    od = drive.eds
    """)


def test_a_good_file_is_read(tmp_path: pathlib.Path) -> None:
    path = tmp_path / "gw.ini"
    path.write_text(GOOD, encoding="utf-8")
    config = load_config(path)
    assert config.name == "plant-gw"
    assert [(c.net, c.channel, c.mode, c.node_id, c.heartbeat_ms, c.routing)
            for c in config.lines] == [(1, "mem:gwcfg-1", "fd", 1, 100, True),
                                       (2, "mem:gwcfg-2", "classic", None, 0, False)]
    assert [(r.network, r.via, r.node) for r in config.routes] == [(3, 1, 7)]
    assert [(n.net, n.node_id, n.heartbeat_timeout_ms, n.pdos) for n in config.nodes] == [
        (2, 9, 300, "none"), (1, 5, 0, "od")]
    assert config.nodes[1].od == str(tmp_path.resolve() / "drive.eds")   # beside the file
    assert config.mqtt is None


@pytest.mark.parametrize("text, line, problem", [
    ("[line 1]\nchannel = can0\nmdoe = fd\n", 3, "unknown key 'mdoe'"),
    ("[line 1]\nchannel = can0\nmode = fdx\n", 3, "expected one of fd, classic"),
    ("[line 1]\nchannel = can0\nnode_id = 200\n", 3, "node_id = 200 is not 1..127"),
    ("[line 1]\nchannel = can0\nnode_id = five\n", 3, "not a number"),
    ("[line 1]\nmode = fd\n", 1, "channel is missing"),
    ("[line 1]\nchanel = can0\n", 2, "unknown key 'chanel'"),
    ("[line 0]\nchannel = can0\n", 1, "network-id 0 is not 1..127"),
    ("[line 1]\nchannel = can0\n[line 1]\nchannel = can1\n", 3, "appears again"),
    ("[line 1]\nchannel = can0\nchannel = can1\n", 3, "duplicate key"),
    ("[line 1]\nchannel = can0\n[node 2.5]\n", 3, "no [line 2]"),
    ("[line 1]\nchannel = can0\nnode_id = 5\n[node 1.5]\n", 4, "gateway's own node"),
    ("[line 1]\nchannel = can0\n[node 5]\n", 3, "[node NET.NODE]"),
    ("[line 1]\nchannel = can0\n[bridge]\n", 3, "unknown section"),
    ("[gateway]\nname = a/b\n[line 1]\nchannel = can0\n", 1, "may not hold"),
    ("[gateway]\nname = gw\n", None, "no [line NET] section"),
    ("[line 1]\nchannel = can0\n[mqtt]\nport = 70000\n", 4, "port = 70000 is not 1..65535"),
    ("[line 1]\nchannel = can0\nrouting = maybe\n", 3, "expected one of on, off"),
    ("[line 1]\nchannel = can0\n[routes]\n3 = 1\n", 4, "expected NETWORK = VIA:NODE"),
    ("[line 1]\nchannel = can0\n[routes]\n3 = 1:200\n", 4, "expected NETWORK = VIA:NODE"),
    ("[line 1]\nchannel = can0\n[routes]\n1 = 1:7\n", 4, "is a line of this gateway"),
    ("[line 1]\nchannel = can0\n[routes]\n3 = 2:7\n", 4, "has no [line 2]"),
    ("[line 1]\nchannel = can0\n[remote_access]\nbaud = 9600\n", 3,
     "serial or tcp is missing"),
    ("[line 1]\nchannel = can0\n[remote_access]\ntcp = 0\ncrc = md5\n", 5,
     "expected one of seed, xmodem"),
    ("[line 1]\nchannel = can0\n[remote_access]\ntcp = 0\nmanager = 0x8\n", 5,
     "bits 8 and 16"),
    ("[line 1]\nchannel = can0\n[remote_access]\ntcp = 0\nmanager = 0x20\n", 5,
     "manager = 32 is not 0..31"),
    ("[line 1]\nchannel = can0\n[remote_access]\ntcp = 0\nmax_payload = 0\n", 5,
     "max_payload = 0 is not 1..65535"),
    ("[line 1]\nchannel = can0\n[remote_access]\ntcp = 0\nport = 5\n", 5,
     "unknown key 'port'"),
    ("[line 1]\nchannel = can0\n[remote_access]\ntcp = 0\n1.200 = a.eds\n", 5,
     "expected NET.NODE = FILE"),
    ("[line 1]\nchannel = can0\n[remote_access]\ntcp = 0\n5 = a.eds\n", 5,
     "expected NET.NODE = FILE"),
    ("[line 1]\nchannel = can0\n[remote_access]\ntcp = 0\n2.5 = a.eds\n", 5,
     "no [line 2]"),
    ("[line 1]\nchannel = can0\nnode_id = 5\n[remote_access]\ntcp = 0\n1.5 = a.eds\n", 6,
     "gateway's own node"),
    ("channel = can0\n", 1, "before the first [section]"),
    ("[line 1\n", 1, "bad section header"),
    ("", None, "empty"),
])
def test_mistakes_name_file_and_line(text: str, line: int, problem: str) -> None:
    with pytest.raises(GatewayConfigError) as caught:
        parse_config(text, "site/gw.ini")
    assert caught.value.path == "site/gw.ini"
    assert caught.value.line == line, str(caught.value)
    assert problem in str(caught.value)
    assert str(caught.value).startswith("site/gw.ini" + (f":{line}" if line else ""))


def test_an_unreadable_file_is_named(tmp_path: pathlib.Path) -> None:
    with pytest.raises(GatewayConfigError, match="missing.ini: cannot read it"):
        load_config(tmp_path / "missing.ini")


def test_the_gateway_opens_lines_and_watches_nodes() -> None:
    config = parse_config(GOOD.replace("[node 1.5]\nod = drive.eds\n", ""), "gw.ini")
    with Network() as net:
        device = net.open_line("mem:gwcfg-2", mode="classic").create_local_node(
            9, od=demo_od("classic"), heartbeat_ms=50)
        with Gateway(config, network=net) as gateway:
            assert sorted(gateway.lines) == [1, 2]
            assert gateway.lines[1].mode == "fd" and gateway.lines[2].mode == "classic"
            assert gateway.lines[1].local_node is not None
            assert gateway.lines[1].local_node.node_id == 1
            assert (gateway.lines[1].network_id, gateway.lines[2].network_id) == (1, None)
            route = net.routing.resolve(3)
            assert (route.line, route.node) == (gateway.lines[1], 7)
            node = gateway.nodes[(2, 9)]
            node.nmt.wait_for_heartbeat(timeout=5)
            assert node.read("0x1017:0") == (50).to_bytes(2, "little")
            assert gateway.status() == ("gateway plant-gw: net 1 mem:gwcfg-1 fd; "
                                        "net 2 mem:gwcfg-2 classic: 1 PRE_OPERATIONAL")
        assert device.nmt.state == "PRE_OPERATIONAL"


def test_the_gateway_publishes_to_mqtt(tmp_path: pathlib.Path) -> None:
    from mqtt_broker import MOSQUITTO, Broker, Subscriber
    if MOSQUITTO is None:
        pytest.skip("mosquitto is not installed")
    broker = Broker(tmp_path)
    try:
        config = parse_config(textwrap.dedent(f"""\
            [gateway]
            name = cfg-gw
            [line 3]
            channel = mem:gwcfg-mqtt
            [node 3.5]
            heartbeat_timeout_ms = 300
            pdos = none
            [mqtt]
            broker = 127.0.0.1
            port = {broker.port}
            """), "gw.ini")
        sub = Subscriber(broker.port, ["canopen/cfg-gw/#"])
        with Network() as net:
            net.open_line("mem:gwcfg-mqtt").create_local_node(5, od=demo_od("fd"),
                                                               heartbeat_ms=50)
            with Gateway(config, network=net) as gateway:
                state = sub.wait("canopen/cfg-gw/3/5/state")[-1]
                assert state.text == "PRE_OPERATIONAL"
                assert gateway.status().endswith("mqtt connected (published "
                                                 f"{gateway.mqtt.stats['published']}, "
                                                 "dropped 0, commands 0)")
        assert sub.wait("canopen/cfg-gw/status", 2)[-1].text == "offline"
        sub.close()
    finally:
        broker.stop()


REMOTE_ACCESS = textwrap.dedent("""\
    [line 1]
    channel = mem:gwcfg-ra
    node_id = 1
    [remote_access]
    tcp = 0
    host = 127.0.0.1
    crc = xmodem
    max_payload = 200
    manager = 0x5
    heartbeat_ms = 300
    1.5 = builtin:fd
    1.6 = drive.eds
    """)


def test_the_remote_access_section_is_read(tmp_path: pathlib.Path) -> None:
    path = tmp_path / "gw.ini"
    path.write_text(REMOTE_ACCESS + "serial = /dev/ttyUSB1\nbaud = 57600\n", encoding="utf-8")
    ra = load_config(path).remote_access
    assert ra is not None
    assert (ra.serial, ra.baud, ra.tcp, ra.host, ra.crc, ra.max_payload, ra.manager,
            ra.heartbeat_ms) == ("/dev/ttyUSB1", 57600, 0, "127.0.0.1", "xmodem", 200, 5, 300)
    assert [(k.net, k.node_id, k.od, k.line) for k in ra.known] == [
        (1, 5, "builtin:fd", 11), (1, 6, str(tmp_path.resolve() / "drive.eds"), 12)]


def test_a_broken_known_dictionary_is_named_at_start(tmp_path: pathlib.Path) -> None:
    (tmp_path / "drive.eds").write_text("[FileInfo\n", encoding="utf-8")
    path = tmp_path / "gw.ini"
    path.write_text(REMOTE_ACCESS, encoding="utf-8")
    with Network() as net:
        gateway = Gateway(load_config(path), network=net)
        with pytest.raises(GatewayConfigError) as caught:
            gateway.start()
    assert caught.value.path == str(path) and caught.value.line == 12
    assert "[remote_access] known node 1.6" in str(caught.value)
    assert "drive.eds:1: bad section header" in str(caught.value)   # the dictionary's own


def test_the_gateway_serves_remote_access(tmp_path: pathlib.Path) -> None:
    from canopenfd.gateway import remote_access as ra
    from canopenfd.gateway.remote_access_client import RemoteAccessClient

    config = parse_config(REMOTE_ACCESS.replace("1.6 = drive.eds\n", ""), "gw.ini")
    with Network() as net:
        device = net.open_line("mem:gwcfg-ra").create_local_node(5, od=demo_od("fd"))
        with Gateway(config, network=net) as gateway:
            server = gateway.remote_access
            assert server is not None and server.crc == ra.CrcVariant.XMODEM
            assert server.max_payload == 200
            port = int(gateway.remote_access_on[0].rpartition(":")[2])
            assert gateway.remote_access_on == [f"tcp 127.0.0.1:{port}"]
            with RemoteAccessClient.connect("127.0.0.1", port, crc="xmodem") as client:
                assert client.own_node_id() == 1
                assert client.manager_control() & 0x1F == (ra.ManagerControl.KEEP_OP
                                                           | ra.ManagerControl.PDO_RECEIVE_ALL)
                device[0x1018][3].raw = 0x0102
                assert client.read_remote(5, 0x1018, 3) == b"\x02\x01\x00\x00"
                device.wait_for_state("OPERATIONAL", timeout=5)     # KEEP_OP started it
                status = gateway.status()
            assert status.endswith(f"; remote access on tcp 127.0.0.1:{port} (1 hosts, "
                                   f"{server.stats['frames']} frames, 0 busy)"), status
            assert server.stats["frames"] >= 3
        assert gateway.remote_access is None


def test_a_port_in_use_is_named_with_the_section() -> None:
    import socket
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        config = parse_config(f"[line 1]\nchannel = mem:gwcfg-busy\n[remote_access]\n"
                              f"tcp = {port}\n", "site/gw.ini")
        with Network() as net:
            gateway = Gateway(config, network=net)
            with pytest.raises(GatewayConfigError) as caught:
                gateway.start()
            assert (caught.value.path, caught.value.line) == ("site/gw.ini", 3)
            assert str(caught.value).startswith("site/gw.ini:3: [remote_access] ")
            # closed on the way out: the server's watches are gone from the line
            assert gateway.remote_access is None and not gateway.lines[1].nodes
