"""A gateway's configuration file (INI, read with line numbers): its lines
with their network-ids, the nodes it watches, and its host endpoints.

    [gateway]
    name = plant-gw                 ; the topic level / label of this gateway

    [line 1]                        ; network-id 1
    channel = can0                  ; SocketCAN interface, or mem:NAME
    mode = fd                       ; fd | classic
    node_id = 1                     ; optional: the gateway's own node on this line
    od = gateway.eds                ; its dictionary (default: the demo dictionary)
    heartbeat_ms = 100
    routing = on                    ; join the routing (SDO networking, EMCY routing,
                                    ; PDO forwarding) with this network-id: on | off

    [routes]                        ; networks behind other gateways (0x1F2C)
    3 = 2:7                         ; network 3 through gateway node 7 on network 2

    [node 1.5]                      ; node 5 on network 1
    od = drive.eds                  ; names and types of its entries
    heartbeat_timeout_ms = 300      ; 0: no heartbeat supervision
    pdos = od                       ; publish its TPDO values: od | node | none

    [ascii]                         ; CiA 309-3 ASCII over TCP
    tcp = 5000                      ; port (0: any free one)
    host = 127.0.0.1                ; 0.0.0.0: every interface (no authentication!)
    sdo_timeout_ms = 500

    [mqtt]
    broker = localhost
    port = 1883
    value_qos = 0
    event_qos = 1

    [remote_access]                 ; the seed 001 binary protocol (serial and/or TCP)
    serial = /dev/ttyUSB0           ; a serial port (needs pyserial)
    baud = 115200
    tcp = 5001                      ; a TCP port (0: any free one)
    host = 127.0.0.1
    crc = seed                      ; seed | xmodem
    max_payload = 35                ; longest frame payload, 1..65535
    manager = 0x5                   ; minimal-manager bits at start: 1 keep nodes
                                    ; operational, 2 monitor heartbeats, 4 scan PDOs
    heartbeat_ms = 1000             ; the heartbeat time bit 2 monitors with
    1.5 = drive.eds                 ; a known node NET.NODE and its dictionary (or
                                    ; builtin:fd / builtin:classic): bit 4 scans it

Every problem is reported with the file and line (`GatewayConfigError`).
Relative file names (od=) are taken from the configuration file's folder.
"""

from __future__ import annotations

import pathlib
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional, Set, Tuple, Union

from ..errors import ConfigurationError
from ..od.errors import OdFileError
from ..od.ini import IniFile, Key, Section, parse_ini

_MODES = ("fd", "classic")
_PDO_SOURCES = ("od", "node", "none")


class GatewayConfigError(ConfigurationError):
    """A gateway configuration that cannot be used: `path`, `line`, problem."""

    def __init__(self, problem: str, path: str, line: Optional[int] = None) -> None:
        self.path = path
        self.line = line
        self.problem = problem
        super().__init__(f"{path}{':' + str(line) if line else ''}: {problem}")


@dataclass
class LineConfig:
    net: int
    channel: str
    mode: str = "fd"
    node_id: Optional[int] = None
    od: Optional[str] = None
    heartbeat_ms: int = 0
    routing: bool = True


@dataclass
class RouteConfig:
    network: int
    via: int
    node: int
    line: int = 0      # where it is written, for messages


@dataclass
class NodeConfig:
    net: int
    node_id: int
    od: Optional[str] = None
    heartbeat_timeout_ms: int = 0
    pdos: str = "od"


@dataclass
class AsciiConfig:
    port: int
    host: str = "127.0.0.1"
    sdo_timeout_ms: int = 500


@dataclass
class MqttConfig:
    broker: str = "localhost"
    port: int = 1883
    value_qos: int = 0
    event_qos: int = 1
    username: Optional[str] = None
    password: Optional[str] = None


@dataclass
class KnownNodeConfig:
    net: int
    node_id: int
    od: Any            # a file, builtin:fd / builtin:classic, or an ObjectDictionary
    line: int = 0      # where it is written, for messages


@dataclass
class RemoteAccessConfig:
    serial: Optional[str] = None
    baud: int = 115200
    tcp: Optional[int] = None
    host: str = "127.0.0.1"
    crc: str = "seed"
    max_payload: int = 35
    manager: int = 0
    heartbeat_ms: int = 1000
    known: List[KnownNodeConfig] = field(default_factory=list)
    line: int = 0      # the section's line, for messages


@dataclass
class GatewayConfig:
    name: str = "gateway"
    lines: List[LineConfig] = field(default_factory=list)
    nodes: List[NodeConfig] = field(default_factory=list)
    routes: List[RouteConfig] = field(default_factory=list)
    ascii: Optional[AsciiConfig] = None
    mqtt: Optional[MqttConfig] = None
    remote_access: Optional[RemoteAccessConfig] = None
    path: str = "<config>"


class _Reader:
    """Typed values out of one section, errors with file and line."""

    def __init__(self, section: Section, path: str, folder: pathlib.Path) -> None:
        self.section = section
        self.path = path
        self.folder = folder
        self.used: Set[str] = set()

    def error(self, problem: str, key: Optional[Key] = None) -> GatewayConfigError:
        line = key.line if key is not None else self.section.line
        return GatewayConfigError(f"[{self.section.name}] {problem}", self.path, line)

    def _key(self, name: str) -> Optional[Key]:
        self.used.add(name)
        return self.section.get(name)

    def text(self, name: str, default: Optional[str] = None) -> Optional[str]:
        key = self._key(name)
        if key is None:
            return default
        if not key.value:
            raise self.error(f"{name} is empty", key)
        return key.value

    def number(self, name: str, default: Optional[int], low: int, high: int) -> Optional[int]:
        key = self._key(name)
        if key is None:
            return default
        try:
            value = int(key.value, 0)
        except ValueError:
            raise self.error(f"{name} = {key.value!r} is not a number", key) from None
        if not low <= value <= high:
            raise self.error(f"{name} = {value} is not {low}..{high}", key)
        return value

    def choice(self, name: str, default: str, choices: Tuple[str, ...]) -> str:
        key = self._key(name)
        if key is None:
            return default
        if key.value.lower() not in choices:
            raise self.error(f"{name} = {key.value!r}: expected one of {', '.join(choices)}",
                             key)
        return key.value.lower()

    def path_value(self, name: str) -> Optional[str]:
        value = self.text(name)
        if value is None:
            return None
        path = pathlib.Path(value)
        return str(path if path.is_absolute() else self.folder / path)

    def finish(self) -> None:
        for lower, key in self.section.keys.items():
            if lower not in self.used:
                raise self.error(f"unknown key {key.name!r}", key)


def load_config(source: Union[str, pathlib.Path]) -> GatewayConfig:
    """Read a gateway configuration file (see the module text for its keys)."""
    path = str(source)
    try:
        data = pathlib.Path(path).read_bytes()
    except OSError as exc:
        raise GatewayConfigError(f"cannot read it: {exc.strerror or exc}", path) from None
    return parse_config(data, path)


def parse_config(data: Union[bytes, str], path: str = "<config>") -> GatewayConfig:
    try:
        ini = parse_ini(data, path, strict=True)
    except OdFileError as exc:
        problem = exc.problem.replace("an EDS/DCF file", "a gateway configuration")
        raise GatewayConfigError(problem.replace("EDS/DCF", "INI"), path, exc.line) from None
    _refuse_repeats(ini, path)
    folder = pathlib.Path(path).resolve().parent
    config = GatewayConfig(path=path)
    nets: Dict[int, LineConfig] = {}
    for section in ini.sections.values():
        reader = _Reader(section, path, folder)
        kind, _, tail = section.name.strip().lower().partition(" ")
        tail = tail.strip()
        if kind == "gateway" and not tail:
            config.name = reader.text("name", config.name) or config.name
            if "/" in config.name or "+" in config.name or "#" in config.name:
                raise reader.error(f"name {config.name!r} may not hold '/', '+' or '#'")
        elif kind == "line":
            net = _number(tail, 1, 127, reader, "network-id")
            if net in nets:
                raise reader.error(f"network {net} is configured twice")
            line_config = LineConfig(
                net, reader.text("channel") or "", reader.choice("mode", "fd", _MODES),
                reader.number("node_id", None, 1, 127), reader.path_value("od"),
                reader.number("heartbeat_ms", 0, 0, 65535) or 0,
                reader.choice("routing", "on", ("on", "off")) == "on")
            reader.finish()      # a misspelt key ("chanel") before the missing one
            if not line_config.channel:
                raise reader.error("channel is missing (e.g. channel = can0)")
            nets[net] = line_config
        elif kind == "routes" and not tail:
            for key in section.keys.values():
                config.routes.append(_route(key, reader))
                reader.used.add(key.name.lower())
        elif kind == "node":
            net_text, dot, node_text = tail.partition(".")
            if not dot:
                raise reader.error("a node section is [node NET.NODE], e.g. [node 1.5]")
            config.nodes.append(NodeConfig(
                _number(net_text, 1, 127, reader, "network-id"),
                _number(node_text, 1, 127, reader, "node-id"),
                reader.path_value("od"),
                reader.number("heartbeat_timeout_ms", 0, 0, 65535) or 0,
                reader.choice("pdos", "od", _PDO_SOURCES)))
        elif kind == "ascii" and not tail:
            port = reader.number("tcp", None, 0, 65535)
            if port is None:
                raise reader.error("tcp is missing (the TCP port, e.g. tcp = 5000)")
            config.ascii = AsciiConfig(port, reader.text("host", "127.0.0.1") or "127.0.0.1",
                                       _or(reader.number("sdo_timeout_ms", 500, 1, 65535), 500))
        elif kind == "mqtt" and not tail:
            config.mqtt = MqttConfig(
                reader.text("broker", "localhost") or "localhost",
                reader.number("port", 1883, 1, 65535) or 1883,
                reader.number("value_qos", 0, 0, 2) or 0,
                _or(reader.number("event_qos", 1, 0, 2), 1),
                reader.text("username"), reader.text("password"))
        elif kind == "remote_access" and not tail:
            config.remote_access = _remote_access(section, reader)
        else:
            raise reader.error("unknown section (expected [gateway], [line NET], "
                               "[node NET.NODE], [routes], [ascii], [mqtt] or "
                               "[remote_access])")
        reader.finish()
    if not nets:
        raise GatewayConfigError("no [line NET] section: a gateway needs a line", path)
    config.lines = [nets[net] for net in sorted(nets)]
    for route in config.routes:
        if route.network in nets:
            raise GatewayConfigError(f"[routes] network {route.network} is a line of this "
                                     "gateway, not behind another one", path, route.line)
        if route.via not in nets:
            raise GatewayConfigError(f"[routes] network {route.via} (the way to network "
                                     f"{route.network}) has no [line {route.via}]", path,
                                     route.line)
    for known in config.remote_access.known if config.remote_access is not None else []:
        line = nets.get(known.net)
        if line is None:
            raise GatewayConfigError(f"[remote_access] known node {known.net}.{known.node_id}: "
                                     f"no [line {known.net}]", path, known.line)
        if line.node_id == known.node_id:
            raise GatewayConfigError(
                f"[remote_access] known node {known.net}.{known.node_id}: node-id "
                f"{known.node_id} is the gateway's own node on line {known.net}", path,
                known.line)
    for node in config.nodes:
        line = nets.get(node.net)
        if line is None:
            raise GatewayConfigError(f"[node {node.net}.{node.node_id}]: no [line {node.net}]",
                                     path, _section_line(ini, f"node {node.net}.{node.node_id}"))
        if line.node_id == node.node_id:
            raise GatewayConfigError(
                f"[node {node.net}.{node.node_id}]: node-id {node.node_id} is the gateway's "
                f"own node on line {node.net}", path,
                _section_line(ini, f"node {node.net}.{node.node_id}"))
    return config


# manager bits the remote-access server refuses (PDO_TRANSMIT_ALL, USE_SCANNED)
_MANAGER_REFUSED = 0x18


def _remote_access(section: Section, reader: _Reader) -> RemoteAccessConfig:
    config = RemoteAccessConfig(line=section.line)
    config.serial = reader.text("serial")
    config.baud = _or(reader.number("baud", 115200, 50, 10_000_000), 115200)
    config.tcp = reader.number("tcp", None, 0, 65535)
    config.host = reader.text("host", "127.0.0.1") or "127.0.0.1"
    config.crc = reader.choice("crc", "seed", ("seed", "xmodem"))
    config.max_payload = _or(reader.number("max_payload", 35, 1, 0xFFFF), 35)
    config.manager = _or(reader.number("manager", 0, 0, 0x1F), 0)
    if config.manager & _MANAGER_REFUSED:
        raise reader.error(f"manager = 0x{config.manager:X}: bits 8 and 16 (send every PDO, "
                           "use scanned configurations) are not served",
                           section.get("manager"))
    config.heartbeat_ms = _or(reader.number("heartbeat_ms", 1000, 0, 65535), 1000)
    for key in section.keys.values():
        if not key.name[:1].isdigit():
            continue
        reader.used.add(key.name.lower())
        net_text, dot, node_text = key.name.partition(".")
        try:
            net, node = int(net_text, 0), int(node_text, 0)
        except ValueError:
            net = node = -1
        if not dot or not 1 <= net <= 127 or not 1 <= node <= 127:
            raise reader.error(f"known node {key.name!r}: expected NET.NODE = FILE (network-id "
                               "and node-id 1..127), e.g. 1.5 = drive.eds", key)
        if not key.value:
            raise reader.error(f"known node {key.name}: the dictionary file is missing", key)
        od = key.value if key.value.lower().startswith("builtin:") else \
            reader.path_value(key.name)
        assert od is not None
        config.known.append(KnownNodeConfig(net, node, od, key.line))
    if config.serial is None and config.tcp is None:
        raise reader.error("serial or tcp is missing (where hosts connect: serial = "
                           "/dev/ttyUSB0 and/or tcp = 5001)")
    return config


def _route(key: Key, reader: _Reader) -> RouteConfig:
    via_text, colon, node_text = key.value.partition(":")
    try:
        network, via, node = int(key.name, 0), int(via_text, 0), int(node_text, 0)
    except ValueError:
        network = via = node = -1
    if not colon or not 1 <= network <= 127 or not 1 <= via <= 127 or not 1 <= node <= 127:
        raise reader.error(f"route {key.name} = {key.value!r}: expected NETWORK = VIA:NODE "
                           "(network-ids and node-id 1..127), e.g. 3 = 2:7", key)
    return RouteConfig(network, via, node, key.line)


def _or(value: Optional[int], default: int) -> int:
    return default if value is None else value


def _number(text: str, low: int, high: int, reader: _Reader, what: str) -> int:
    try:
        value = int(text.strip(), 0)
    except ValueError:
        raise reader.error(f"{what} {text.strip()!r} is not a number") from None
    if not low <= value <= high:
        raise reader.error(f"{what} {value} is not {low}..{high}")
    return value


def _refuse_repeats(ini: IniFile, path: str) -> None:
    # the INI reader merges repeated sections and keys with a warning; in a
    # gateway's configuration a repeat is a mistake
    if ini.warnings:
        line, _, text = ini.warnings[0]
        raise GatewayConfigError(text, path, line)


def _section_line(ini: IniFile, name: str) -> Optional[int]:
    for section in ini.sections.values():
        if " ".join(section.name.lower().split()) == name:
            return section.line
    return None
