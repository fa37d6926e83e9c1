"""`canopenfd gateway [CONFIG] [--tcp PORT] [--mqtt BROKER] [--serial PATH]`: serve
lines to host programs until SIGINT/SIGTERM — CiA 309-3 ASCII requests over TCP,
process data and commands through an MQTT broker, the seed 001 remote-access
protocol over a serial port or TCP (canopenfd.gateway). With CONFIG (an INI
file, see canopenfd.gateway.config) the gateway has every line, node and
endpoint the file names; without it, the one line of the line options. Each
host protocol adds its options in its own block."""

from __future__ import annotations

import argparse
import signal
import sys
import threading
import time
from typing import Any, List, Optional

from ..gateway.config import (AsciiConfig, GatewayConfig, GatewayConfigError, KnownNodeConfig,
                              MqttConfig, RemoteAccessConfig, load_config)
from ..gateway import remote_access as ra
from ..gateway.gateway import Gateway
from .common import (EXIT_OK, Printer, UsageError, add_line_options, od_arg,
                     command_line, ms_arg, node_id_arg)


def add_parsers(subparsers: Any) -> None:
    p = subparsers.add_parser(
        "gateway", help="serve lines to host programs (CiA 309-3 ASCII over TCP, MQTT)",
        description="Run a gateway until SIGINT/SIGTERM: host programs reach every node of "
                    "the lines without speaking CAN. CONFIG names lines, nodes and "
                    "endpoints; without it the line options give one line.")
    p.add_argument("config", nargs="?", metavar="CONFIG",
                   help="gateway configuration (INI: [gateway], [line NET], "
                        "[node NET.NODE], [routes], [ascii], [mqtt], [remote_access]); "
                        "--tcp/--mqtt/--serial/--remote-access-tcp add to it")
    add_line_options(p, channel_required=False)
    p.add_argument("--net", type=int, default=1, metavar="N",
                   help="without CONFIG: the network id hosts give the line (1..127, "
                        "default 1)")
    p.add_argument("--node-id", type=int, metavar="N",
                   help="without CONFIG: run a local node with this id on the line (boot-up, "
                        "NMT state; on fd lines the gateway's USDO client uses it as its id, "
                        "else 127)")
    p.add_argument("--od", metavar="FILE",
                   help="without CONFIG: the gateway node's object dictionary: an EDS, DCF, "
                        "XDD or XDC file, or builtin:fd / builtin:classic (default: the "
                        "built-in demo dictionary of the line's mode)")
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
    add_remote_access_options(p)
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


def _endpoints(args: argparse.Namespace, config: GatewayConfig, first_net: int) -> None:
    """The endpoint options fill the configuration (first_net: the network the
    --remote-access-node nodes are on)."""
    if args.tcp is not None:
        if not 0 <= args.tcp <= 65535:
            raise UsageError(f"--tcp {args.tcp}: a TCP port is 0..65535")
        sdo_timeout = ms_arg(args.sdo_timeout, "--sdo-timeout", "gateway")
        if sdo_timeout == 0:
            raise UsageError("--sdo-timeout 0: give 1..65535 ms")
        config.ascii = AsciiConfig(args.tcp, args.host, sdo_timeout)
    if args.mqtt is not None:
        config.mqtt = _mqtt_arg(args.mqtt)
    if remote_access_wanted(args):
        config.remote_access = remote_access_config(args, first_net)
    if args.name is not None:
        config.name = args.name
    if config.ascii is None and config.mqtt is None and config.remote_access is None:
        raise UsageError("gateway: no host endpoint given (--tcp PORT, --mqtt BROKER, "
                         "--serial PATH or --remote-access-tcp PORT, or a CONFIG with "
                         "[ascii] / [mqtt] / [remote_access])")


def cmd_gateway(args: argparse.Namespace) -> int:
    printer = Printer()
    if args.config is not None:
        for option in ("channel", "interface", "node_id", "od"):
            if getattr(args, option, None) is not None:
                raise UsageError(f"gateway: --{option.replace('_', '-')} is for the one line "
                                 "without CONFIG; the configuration's [line] sections name "
                                 "the lines")
        try:
            config = load_config(args.config)
        except GatewayConfigError as exc:
            raise UsageError(str(exc)) from None
        _endpoints(args, config, config.lines[0].net)
        _run(Gateway(config), args, printer)
        return EXIT_OK
    if args.channel is None:
        raise UsageError("gateway: give CONFIG or --channel (the line to serve)")
    if not 1 <= args.net <= 127:
        raise UsageError(f"--net {args.net}: a network id is 1..127")
    config = GatewayConfig()
    _endpoints(args, config, args.net)
    node_id = None if args.node_id is None else node_id_arg(args.node_id, "--node-id")
    mode = "classic" if args.classic else "fd"
    with command_line(args) as line:
        if node_id is not None:
            line.create_local_node(node_id, od=od_arg(args.od, mode, node_id))
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
            remote_access = gateway.remote_access
            if remote_access is not None:
                line = gateway.lines[min(gateway.lines)]
                print(f"gateway on {line.channel} ({line.mode}): remote access on "
                      f"{', '.join(gateway.remote_access_on)}; Ctrl-C or SIGTERM to stop",
                      file=sys.stderr, flush=True)
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
        if remote_access is not None:    # closed now: its counters include every host
            printer.line("remote access: " + ", ".join(
                f"{key} {value}" for key, value in remote_access.stats.items()))
        if gateway.ascii is not None:
            stats = gateway.ascii.stats
            printer.line(f"gateway stopped: {stats.get('clients', 0)} clients, "
                         f"{stats.get('requests', 0)} requests, {stats.get('errors', 0)} errors")
    finally:
        for signum, handler in previous:
            signal.signal(signum, handler)


# ------------------------------------------------------------------ seed 001 remote access
# (issue 16 part 4: the CANopenIA binary protocol over a serial port and TCP)

def add_remote_access_options(p: argparse.ArgumentParser) -> None:
    group = p.add_argument_group("remote access (seed 001 binary protocol; they replace "
                                 "CONFIG's [remote_access], known nodes on its lowest "
                                 "network)")
    group.add_argument("--serial", metavar="PATH",
                       help="serve the remote-access protocol on this serial port (needs "
                            "pyserial: pip install 'canopenfd[serial]')")
    group.add_argument("--baud", type=int, default=115200, metavar="N",
                       help="the serial port's bit rate (default 115200)")
    group.add_argument("--remote-access-tcp", type=int, metavar="PORT",
                       help="serve the remote-access protocol on TCP PORT (0: any free port, "
                            "printed at start)")
    group.add_argument("--remote-access-host", default="127.0.0.1", metavar="ADDRESS",
                       help="the address --remote-access-tcp listens on (default 127.0.0.1; "
                            "0.0.0.0 for every interface)")
    group.add_argument("--remote-access-crc", choices=("seed", "xmodem"), default="seed",
                       help="frame checksum: seed = x^16+x^15+x^2+1 as the manual writes "
                            "(default), xmodem = what ESAcademy's host code computes")
    group.add_argument("--remote-access-max-payload", type=int, default=35, metavar="BYTES",
                       help="longest frame payload taken and sent (default 35, the seed's; "
                            "raise it only when the host allows longer frames)")
    group.add_argument("--remote-access-manager", default="0", metavar="BITS",
                       help="minimal-manager automation at start, [5F01h,04h] bits: 1 keep "
                            "nodes operational, 2 monitor every heartbeat and reset lost "
                            "nodes, 4 scan known nodes' PDOs (decimal or 0x hex; default 0)")
    group.add_argument("--remote-access-heartbeat", type=int, default=1000, metavar="MS",
                       help="heartbeat time the manager monitors nodes with (default 1000)")
    group.add_argument("--remote-access-node", action="append", metavar="NODE=FILE",
                       help="a known node and its object dictionary (EDS, DCF, XDD, XDC or "
                            "builtin:fd / builtin:classic): the manager scans its PDOs "
                            "(bit 4); repeatable")


def remote_access_wanted(args: argparse.Namespace) -> bool:
    return args.serial is not None or args.remote_access_tcp is not None


def remote_access_config(args: argparse.Namespace, net: int) -> RemoteAccessConfig:
    """The remote-access options as a [remote_access] section (known nodes on `net`)."""
    try:
        control = int(args.remote_access_manager, 0)
    except ValueError:
        raise UsageError(f"--remote-access-manager {args.remote_access_manager!r}: not a "
                         "number (like 3 or 0x7)") from None
    if not 0 <= control <= 0x1F:
        raise UsageError(f"--remote-access-manager {args.remote_access_manager}: the bits "
                         "are 0..0x1F")
    if control & (ra.ManagerControl.PDO_TRANSMIT_ALL | ra.ManagerControl.USE_SCANNED):
        raise UsageError(f"gateway: manager control 0x{control:08X} refused "
                         f"({ra.error_text(ra.RaError.NOT_SUPPORTED)}: bits 3 and 4 are not "
                         "served)")
    heartbeat = ms_arg(args.remote_access_heartbeat, "--remote-access-heartbeat", "gateway")
    if not 1 <= args.remote_access_max_payload <= 0xFFFF:
        raise UsageError(f"--remote-access-max-payload {args.remote_access_max_payload}: "
                         "expected 1..65535")
    if args.remote_access_tcp is not None and not 0 <= args.remote_access_tcp <= 65535:
        raise UsageError(f"--remote-access-tcp {args.remote_access_tcp}: a TCP port is "
                         "0..65535")
    known = []
    for spec in args.remote_access_node or []:
        node_text, sep, path = spec.partition("=")
        try:
            node = int(node_text, 0)
        except ValueError:
            node = -1
        if not sep or not path or not 1 <= node <= 127:
            raise UsageError(f"--remote-access-node {spec!r}: expected NODE=FILE with a "
                             "node-id 1..127")
        # loaded here, so a file that cannot be read names the option
        mode = "classic" if args.classic else "fd"
        known.append(KnownNodeConfig(net, node, od_arg(path, mode, node,
                                                       f"--remote-access-node {node_text}:")))
    return RemoteAccessConfig(args.serial, args.baud, args.remote_access_tcp,
                              args.remote_access_host, args.remote_access_crc,
                              args.remote_access_max_payload, control, heartbeat, known)
