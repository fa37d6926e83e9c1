"""`canopenfd gateway`: serve a CAN line to host programs until stopped
(Ctrl-C, SIGTERM or --duration). Each host protocol adds its options in its
own block below."""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from typing import Any, Callable, List, Optional

from ..errors import CanopenFDError
from ..line import Line
from .common import (EXIT_OK, Printer, UsageError, add_line_options, builtin_od_kind,
                     command_line, ms_arg, node_id_arg, wait_until_done)


def add_parsers(subparsers: Any) -> None:
    p = subparsers.add_parser("gateway", help="serve a CAN line to host programs until stopped")
    add_line_options(p)
    p.add_argument("--node-id", type=int, metavar="N",
                   help="the gateway's own node on the line (1..127), serving --od; "
                        "without it the gateway has no local object dictionary")
    p.add_argument("--od", metavar="FILE",
                   help="the gateway node's object dictionary: an EDS, DCF, XDD or XDC "
                        "file, or builtin:fd / builtin:classic (default: the built-in demo "
                        "dictionary of the line's mode)")
    p.add_argument("--duration", type=float, metavar="SECONDS",
                   help="stop after SECONDS (default: run until Ctrl-C or SIGTERM)")
    add_remote_access_options(p)
    p.set_defaults(func=cmd_gateway)


def cmd_gateway(args: argparse.Namespace) -> int:
    if not remote_access_wanted(args):
        raise UsageError("gateway: no host endpoint given (--serial PATH or "
                         "--remote-access-tcp PORT)")
    node_id = None if args.node_id is None else node_id_arg(args.node_id, "--node-id")
    mode = "classic" if args.classic else "fd"
    done = threading.Event()
    # before the status line says we run: a SIGTERM from then on stops cleanly
    previous = _on_sigterm(done)
    try:
        with command_line(args) as line:
            if node_id is not None:
                line.create_local_node(node_id, od=_gateway_od(args.od, mode, node_id))
            printer = Printer()
            stops: List[Callable[[], None]] = []
            try:
                stops.append(start_remote_access(args, line, printer))
                try:
                    wait_until_done(done, printer, args.duration)
                except KeyboardInterrupt:
                    pass
            finally:
                for stop in reversed(stops):
                    stop()
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
    return EXIT_OK


def _gateway_od(spec: Optional[str], mode: str, node_id: int) -> Any:
    from ..od import OdFileError, demo_od, import_od

    if spec is None:
        return demo_od(mode)
    kind = builtin_od_kind(spec)
    if kind is not None:
        return demo_od(kind)
    try:
        return import_od(spec, node_id=node_id)
    except OdFileError as exc:
        raise UsageError(f"--od {exc}") from None


def _on_sigterm(done: threading.Event) -> Any:
    """SIGTERM ends the gateway cleanly (only the main thread may set handlers)."""
    if threading.current_thread() is not threading.main_thread():
        return None
    return signal.signal(signal.SIGTERM, lambda signum, frame: done.set())


# ------------------------------------------------------------------ seed 001 remote access
# (issue 16 part 4: the CANopenIA binary protocol over a serial port and TCP)

def add_remote_access_options(p: argparse.ArgumentParser) -> None:
    group = p.add_argument_group("remote access (seed 001 binary protocol; network 1 = "
                                 "the line)")
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


def start_remote_access(args: argparse.Namespace, line: Line, printer: Printer
                        ) -> Callable[[], None]:
    """Start the remote-access server on the line; the function that stops it."""
    from ..gateway.remote_access_server import RemoteAccessServer

    try:
        control = int(args.remote_access_manager, 0)
    except ValueError:
        raise UsageError(f"--remote-access-manager {args.remote_access_manager!r}: not a "
                         "number (like 3 or 0x7)") from None
    heartbeat = ms_arg(args.remote_access_heartbeat, "--remote-access-heartbeat", "gateway")
    if not 1 <= args.remote_access_max_payload <= 0xFFFF:
        raise UsageError(f"--remote-access-max-payload {args.remote_access_max_payload}: "
                         "expected 1..65535")
    known = {}
    for spec in args.remote_access_node or []:
        node_text, sep, path = spec.partition("=")
        try:
            node = int(node_text, 0)
        except ValueError:
            node = -1
        if not sep or not path or not 1 <= node <= 127:
            raise UsageError(f"--remote-access-node {spec!r}: expected NODE=FILE with a "
                             "node-id 1..127")
        known[node] = _gateway_od(path, line.mode, node)
    try:
        server = RemoteAccessServer({1: line}, crc=args.remote_access_crc,
                                    max_payload=args.remote_access_max_payload,
                                    control=control, heartbeat_ms=heartbeat,
                                    known={1: known})
    except CanopenFDError as exc:
        raise UsageError(f"gateway: {exc}") from None
    where = []
    try:
        if args.serial is not None:
            server.serve_serial(args.serial, args.baud)
            where.append(f"serial {args.serial} ({args.baud} Bd)")
        if args.remote_access_tcp is not None:
            port = server.serve_tcp(args.remote_access_tcp, args.remote_access_host)
            where.append(f"tcp {args.remote_access_host}:{port}")
    except CanopenFDError:
        server.close()
        raise
    print(f"gateway on {args.channel} ({line.mode}): remote access on {', '.join(where)}; "
          "Ctrl-C or SIGTERM to stop", file=sys.stderr, flush=True)

    def stop() -> None:
        server.close()
        stats = server.stats
        printer.line("remote access: " + ", ".join(f"{key} {value}" for key, value
                                                    in stats.items()))
    return stop
