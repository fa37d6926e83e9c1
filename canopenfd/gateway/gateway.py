"""The Gateway: lines with their network-ids, the nodes it watches and its
host endpoints, composed from a configuration (issue 16, part 6)."""

from __future__ import annotations

import logging
import pathlib
from typing import Any, Dict, List, Optional, Tuple, Union

from ..errors import CanopenFDError, ConfigurationError
from ..line import Line
from ..network import Network
from ..node import RemoteNode
from ..od import OdFileError, demo_od, import_od
from .ascii309_server import AsciiGateway, BackgroundGateway
from .config import GatewayConfig, GatewayConfigError, KnownNodeConfig, load_config
from .remote_access_server import RemoteAccessServer

log = logging.getLogger(__name__)


class Gateway:
    """Opens the configured lines (on `network`, or a Network of its own),
    creates the gateway's own nodes, watches the configured nodes and starts
    the endpoints (CiA 309-3 ASCII over TCP, MQTT, the seed 001 remote-access
    protocol over a serial port and TCP). `start()` / `close()`, or
    `with Gateway(...)`."""

    def __init__(self, config: Union[GatewayConfig, str, pathlib.Path], *,
                 network: Optional[Network] = None,
                 lines: Optional[Dict[int, Line]] = None) -> None:
        """lines: lines opened by the caller ({net_id: Line}, e.g. on a python-can
        bus), served instead of the configuration's [line] sections."""
        self.config = config if isinstance(config, GatewayConfig) else load_config(config)
        self._own_network = network is None and lines is None
        self.network = network
        self._given_lines = dict(lines) if lines is not None else None
        self.lines: Dict[int, Line] = {}
        self.nodes: Dict[Tuple[int, int], RemoteNode] = {}
        self.ascii: Optional[AsciiGateway] = None
        self._ascii_thread: Optional[BackgroundGateway] = None
        self.mqtt: Optional[Any] = None
        self.remote_access: Optional[RemoteAccessServer] = None
        #: where the remote-access server serves ("serial PATH (BAUD Bd)", "tcp HOST:PORT")
        self.remote_access_on: List[str] = []
        self._started = False

    @property
    def name(self) -> str:
        return self.config.name

    def start(self) -> "Gateway":
        if self._started:
            raise ConfigurationError(f"gateway {self.name}: started already")
        self._started = True
        try:
            self._open_lines()
            self._start_endpoints()
            self._watch_nodes()
            # last: its manager watches every node-id, the configured ones
            # keep the settings _watch_nodes gave them
            self._start_remote_access()
        except BaseException:
            self.close()
            raise
        log.info("%s", self.status())
        return self

    def _open_lines(self) -> None:
        if self._given_lines is not None:
            self.lines = dict(self._given_lines)
            return
        network = self.network = self.network if self.network is not None else Network()
        for cfg in self.config.lines:
            line = network.open_line(cfg.channel, mode=cfg.mode)
            self.lines[cfg.net] = line
            if cfg.node_id is not None:
                od: Any = cfg.od if cfg.od is not None else demo_od(cfg.mode)
                line.create_local_node(cfg.node_id, od=od, heartbeat_ms=cfg.heartbeat_ms)
            if cfg.routing:
                line.network_id = cfg.net
        for route in self.config.routes:
            network.routing.route(route.network, via=route.via, node=route.node)

    def _start_endpoints(self) -> None:
        if self.config.ascii is not None:
            a = self.config.ascii
            self.ascii = AsciiGateway(self.lines, sdo_timeout_ms=a.sdo_timeout_ms)
            self._ascii_thread = self.ascii.start_in_thread(a.host, a.port)
        if self.config.mqtt is not None:
            from .mqtt import MqttBridge   # paho-mqtt is an optional extra
            m = self.config.mqtt
            self.mqtt = MqttBridge(self.lines, m.broker, m.port, gateway=self.name,
                                   value_qos=m.value_qos, event_qos=m.event_qos,
                                   username=m.username, password=m.password).start()

    def _watch_nodes(self) -> None:
        for cfg in self.config.nodes:
            line = self.lines[cfg.net]
            pdos = None if cfg.pdos == "none" else cfg.pdos
            if self.mqtt is not None:
                node = self.mqtt.watch(cfg.net, cfg.node_id, cfg.od,
                                       pdos=pdos if cfg.od is not None else None,
                                       heartbeat_timeout_ms=cfg.heartbeat_timeout_ms)
            else:
                node = line.add_node(cfg.node_id, od=cfg.od,
                                     heartbeat_timeout_ms=cfg.heartbeat_timeout_ms)
            self.nodes[(cfg.net, cfg.node_id)] = node

    def _start_remote_access(self) -> None:
        ra = self.config.remote_access
        if ra is None:
            return
        known: Dict[int, Dict[int, Any]] = {}
        for node in ra.known:
            line = self.lines.get(node.net)
            if line is None:
                raise GatewayConfigError(f"[remote_access] known node {node.net}.{node.node_id}:"
                                         f" the gateway has no line {node.net}",
                                         self.config.path, node.line)
            known.setdefault(node.net, {})[node.node_id] = self._known_od(node, line.mode)
        try:
            server = RemoteAccessServer(self.lines, crc=ra.crc, max_payload=ra.max_payload,
                                        control=ra.manager, heartbeat_ms=ra.heartbeat_ms,
                                        known=known)
        except CanopenFDError as exc:
            raise GatewayConfigError(f"[remote_access] {exc}", self.config.path,
                                     ra.line) from None
        self.remote_access = server
        try:
            if ra.serial is not None:
                server.serve_serial(ra.serial, ra.baud)
                self.remote_access_on.append(f"serial {ra.serial} ({ra.baud} Bd)")
            if ra.tcp is not None:
                port = server.serve_tcp(ra.tcp, ra.host)
                self.remote_access_on.append(f"tcp {ra.host}:{port}")
        except CanopenFDError as exc:
            if not ra.line:      # not from a file: the error names what failed
                raise
            raise GatewayConfigError(f"[remote_access] {exc}", self.config.path,
                                     ra.line) from None

    def _known_od(self, node: KnownNodeConfig, mode: str) -> Any:
        if not isinstance(node.od, str):      # loaded by the caller (the CLI)
            return node.od
        kind = node.od.lower()
        if kind.startswith("builtin:"):
            if kind[len("builtin:"):] not in ("fd", "classic"):
                raise GatewayConfigError(f"[remote_access] known node {node.net}."
                                         f"{node.node_id}: {node.od!r}: the built-in "
                                         "dictionaries are builtin:fd and builtin:classic",
                                         self.config.path, node.line)
            return demo_od(kind[len("builtin:"):])
        try:
            return import_od(node.od, node_id=node.node_id)
        except (OdFileError, OSError) as exc:
            raise GatewayConfigError(f"[remote_access] known node {node.net}.{node.node_id}: "
                                     f"{exc}", self.config.path, node.line) from None

    def status(self) -> str:
        """One line: each network's line and its nodes' states, each endpoint."""
        parts: List[str] = []
        for net, line in sorted(self.lines.items()):
            states: Dict[str, int] = {}
            for (node_net, _), node in self.nodes.items():
                if node_net == net:
                    label = node.state.name
                    states[label] = states.get(label, 0) + 1
            seen = ", ".join(f"{count} {state}" for state, count in sorted(states.items()))
            parts.append(f"net {net} {line.channel} {line.mode}"
                         f"{': ' + seen if seen else ''}")
        if self.ascii is not None and self.config.ascii is not None:
            stats = self.ascii.stats
            parts.append(f"ascii {self.config.ascii.host}:{self.ascii.port} "
                         f"({stats.get('clients', 0)} clients, {stats.get('requests', 0)} "
                         f"requests, {stats.get('errors', 0)} errors)")
        if self.mqtt is not None:
            stats = self.mqtt.stats
            parts.append(f"mqtt {'connected' if self.mqtt.connected else 'reconnecting'} "
                         f"(published {stats['published']}, dropped {stats['dropped']}, "
                         f"commands {stats['commands']})")
        if self.remote_access is not None:
            stats = self.remote_access.stats
            parts.append(f"remote access on {', '.join(self.remote_access_on)} "
                         f"({len(self.remote_access.connections)} hosts, "
                         f"{stats.get('frames', 0)} frames, {stats.get('busy', 0)} busy)")
        return f"gateway {self.name}: " + "; ".join(parts)

    def close(self) -> None:
        if self.remote_access is not None:
            self.remote_access.close()
            self.remote_access = None
        if self._ascii_thread is not None:
            self._ascii_thread.close()
            self._ascii_thread = None
        if self.mqtt is not None:
            self.mqtt.close()
            self.mqtt = None
        if self._own_network and self.network is not None:
            self.network.close()

    def __enter__(self) -> "Gateway":
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()
