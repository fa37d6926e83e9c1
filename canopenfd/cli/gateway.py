"""`canopenfd gateway --tcp PORT`: serve the line to host programs until
SIGINT/SIGTERM — CiA 309-3 ASCII requests over TCP (canopenfd.gateway)."""

from __future__ import annotations

import argparse
import asyncio
import signal
import threading
from typing import Any, Optional

from ..gateway.ascii309_server import AsciiGateway
from .common import (EXIT_OK, Printer, UsageError, add_line_options, command_line, ms_arg,
                     node_id_arg)


def add_parsers(subparsers: Any) -> None:
    p = subparsers.add_parser(
        "gateway", help="serve the line to host programs (CiA 309-3 ASCII over TCP)",
        description="Run a gateway until SIGINT/SIGTERM: host programs reach every node of "
                    "the line without speaking CAN.")
    add_line_options(p)
    p.add_argument("--net", type=int, default=1, metavar="N",
                   help="the network id hosts give this line (1..127, default 1)")
    p.add_argument("--node-id", type=int, metavar="N",
                   help="run a local node with this id on the line (boot-up, NMT state; "
                        "on fd lines the gateway's USDO client uses it as its id, else 127)")
    p.add_argument("--duration", type=float, metavar="SECONDS",
                   help="stop after SECONDS (default: until SIGINT/SIGTERM)")
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
    p.set_defaults(func=cmd_gateway)


def cmd_gateway(args: argparse.Namespace) -> int:
    if args.tcp is None:
        raise UsageError("gateway: give --tcp PORT (the CiA 309-3 ASCII server)")
    if not 0 <= args.tcp <= 65535:
        raise UsageError(f"--tcp {args.tcp}: a TCP port is 0..65535")
    if not 1 <= args.net <= 127:
        raise UsageError(f"--net {args.net}: a network id is 1..127")
    sdo_timeout = ms_arg(args.sdo_timeout, "--sdo-timeout", "gateway")
    if sdo_timeout == 0:
        raise UsageError("--sdo-timeout 0: give 1..65535 ms")
    node_id = None if args.node_id is None else node_id_arg(args.node_id, "--node-id")
    printer = Printer()
    with command_line(args) as line:
        if node_id is not None:
            line.create_local_node(node_id)
        server = AsciiGateway({args.net: line}, sdo_timeout_ms=sdo_timeout)
        asyncio.run(_serve(server, args, printer))
    return EXIT_OK


async def _serve(server: AsciiGateway, args: argparse.Namespace, printer: Printer) -> None:
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    if threading.current_thread() is threading.main_thread():
        for signum in (signal.SIGINT, signal.SIGTERM):
            try:
                loop.add_signal_handler(signum, stop.set)
            except (NotImplementedError, RuntimeError):   # Windows: Ctrl-C still ends it
                pass
    await server.start(args.host, args.tcp)
    printer.line(f"CiA 309-3 ASCII gateway on {args.host}:{server.port}, net {args.net} = "
                 f"{args.channel} ({'classic' if args.classic else 'fd'})")
    try:
        timeout: Optional[float] = args.duration
        try:
            await asyncio.wait_for(stop.wait(), timeout)
        except asyncio.TimeoutError:
            pass
    finally:
        stats = dict(server.stats)
        await server.aclose()
        printer.line(f"gateway stopped: {stats.get('clients', 0)} clients, "
                     f"{stats.get('requests', 0)} requests, {stats.get('errors', 0)} errors")
