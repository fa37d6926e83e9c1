"""`canopenfd gateway [CONFIG] [--tcp PORT] [--mqtt BROKER]`: serve lines to host
programs until SIGINT/SIGTERM — CiA 309-3 ASCII requests over TCP, process data
and commands through an MQTT broker (canopenfd.gateway). With CONFIG (an INI
file, see canopenfd.gateway.config) the gateway has every line, node and
endpoint the file names; without it, the one line of the line options."""

from __future__ import annotations

import argparse
import signal
import threading
import time
from typing import Any, List, Optional

from ..gateway.config import (AsciiConfig, GatewayConfig, GatewayConfigError, MqttConfig,
                              load_config)
from ..gateway.gateway import Gateway
from .common import (EXIT_OK, Printer, UsageError, add_line_options, command_line, ms_arg,
                     node_id_arg)


def add_parsers(subparsers: Any) -> None:
    p = subparsers.add_parser(
        "gateway", help="serve lines to host programs (CiA 309-3 ASCII over TCP, MQTT)",
        description="Run a gateway until SIGINT/SIGTERM: host programs reach every node of "
                    "the lines without speaking CAN. CONFIG names lines, nodes and "
                    "endpoints; without it the line options give one line.")
    p.add_argument("config", nargs="?", metavar="CONFIG",
                   help="gateway configuration (INI: [gateway], [line NET], "
                        "[node NET.NODE], [ascii], [mqtt]); --tcp/--mqtt add to it")
    add_line_options(p)
    p.add_argument("--net", type=int, default=1, metavar="N",
                   help="without CONFIG: the network id hosts give the line (1..127, "
                        "default 1)")
    p.add_argument("--node-id", type=int, metavar="N",
                   help="without CONFIG: run a local node with this id on the line (boot-up, "
                        "NMT state; on fd lines the gateway's USDO client uses it as its id, "
                        "else 127)")
    p.add_argument("--name", metavar="NAME",
                   help="the gateway's name (MQTT topic level; default: CONFIG's or "
                        "'gateway')")
    p.add_argument("--duration", type=float, metavar="SECONDS",
                   help="stop after SECONDS (default: until SIGINT/SIGTERM)")
    p.add_argument("--status-interval", type=float, default=60.0, metavar="SECONDS",
                   help="print the status line every SECONDS (default 60; 0: only at start "
                        "and stop)")
    # ---- CiA 309-3 ASCII over TCP
    p.add_argument("--tcp", type=int, metavar="PORT",
                   help="serve CiA 309-3 ASCII requests on TCP PORT (0: any free port, "
                        "printed at start)")
    p.add_argument("--host", default="127.0.0.1",
                   help="--tcp: the address to listen on (default 127.0.0.1; 0.0.0.0 for "
                        "every interface: the protocol has no authentication)")
    p.add_argument("--sdo-timeout", type=int, default=500, metavar="MS",
                   help="--tcp: the sessions' SDO/USDO timeout until 'set sdo_timeout' "
                        "(default 500)")
    # ---- MQTT
    p.add_argument("--mqtt", metavar="BROKER[:PORT]",
                   help="publish watched nodes to this MQTT broker and take commands from "
                        "it (needs paho-mqtt: pip install 'canopenfd[mqtt]')")
    p.set_defaults(func=cmd_gateway)


def _mqtt_arg(text: str) -> MqttConfig:
    host, _, port = text.rpartition(":") if ":" in text else (text, "", "")
    if not host:
        raise UsageError(f"--mqtt {text!r}: give BROKER or BROKER:PORT")
    try:
        number = int(port) if port else 1883
    except ValueError:
        raise UsageError(f"--mqtt {text!r}: the port {port!r} is not a number") from None
    if not 1 <= number <= 65535:
        raise UsageError(f"--mqtt {text!r}: a TCP port is 1..65535")
    return MqttConfig(host, number)


def _endpoints(args: argparse.Namespace, config: GatewayConfig) -> None:
    if args.tcp is not None:
        if not 0 <= args.tcp <= 65535:
            raise UsageError(f"--tcp {args.tcp}: a TCP port is 0..65535")
        sdo_timeout = ms_arg(args.sdo_timeout, "--sdo-timeout", "gateway")
        if sdo_timeout == 0:
            raise UsageError("--sdo-timeout 0: give 1..65535 ms")
        config.ascii = AsciiConfig(args.tcp, args.host, sdo_timeout)
    if args.mqtt is not None:
        config.mqtt = _mqtt_arg(args.mqtt)
    if args.name is not None:
        config.name = args.name
    if config.ascii is None and config.mqtt is None:
        raise UsageError("gateway: no endpoint: give --tcp PORT, --mqtt BROKER or a CONFIG "
                         "with [ascii] / [mqtt]")


def cmd_gateway(args: argparse.Namespace) -> int:
    printer = Printer()
    if args.config is not None:
        try:
            config = load_config(args.config)
        except GatewayConfigError as exc:
            raise UsageError(str(exc)) from None
        _endpoints(args, config)
        _run(Gateway(config), args, printer)
        return EXIT_OK
    if not 1 <= args.net <= 127:
        raise UsageError(f"--net {args.net}: a network id is 1..127")
    config = GatewayConfig()
    _endpoints(args, config)
    node_id = None if args.node_id is None else node_id_arg(args.node_id, "--node-id")
    with command_line(args) as line:
        if node_id is not None:
            line.create_local_node(node_id)
        _run(Gateway(config, lines={args.net: line}), args, printer)
    return EXIT_OK


def _run(gateway: Gateway, args: argparse.Namespace, printer: Printer) -> None:
    """Serve until SIGINT/SIGTERM or --duration, a status line every interval."""
    stop = threading.Event()
    previous: List[Any] = []
    if threading.current_thread() is threading.main_thread():
        for signum in (signal.SIGINT, signal.SIGTERM):
            previous.append((signum, signal.signal(signum, lambda *_: stop.set())))
    try:
        with gateway:
            ascii_config = gateway.config.ascii
            if gateway.ascii is not None and ascii_config is not None:
                served = ", ".join(f"net {net} = {line.channel} ({line.mode})"
                                   for net, line in sorted(gateway.lines.items()))
                printer.line(f"CiA 309-3 ASCII gateway on {ascii_config.host}:"
                             f"{gateway.ascii.port}, {served}")
            printer.line(gateway.status())
            started = time.monotonic()
            while True:
                timeout: Optional[float] = args.status_interval or None
                if args.duration is not None:
                    left = args.duration - (time.monotonic() - started)
                    if left <= 0:
                        break
                    timeout = left if timeout is None else min(timeout, left)
                if stop.wait(timeout):
                    break
                if args.duration is not None and \
                        time.monotonic() - started >= args.duration:
                    break
                printer.line(gateway.status())
            final = gateway.status()
        printer.line(final.replace("gateway ", "gateway stopped: ", 1))
        if gateway.ascii is not None:
            stats = gateway.ascii.stats
            printer.line(f"gateway stopped: {stats.get('clients', 0)} clients, "
                         f"{stats.get('requests', 0)} requests, {stats.get('errors', 0)} errors")
    finally:
        for signum, handler in previous:
            signal.signal(signum, handler)
