"""`canopenfd nmt COMMAND NODE|all`: send one NMT command."""

from __future__ import annotations

import argparse
import threading
from typing import Any

from ..errors import CanopenFDError
from ..services.nmt import NmtCommand, parse_node_target
from .common import (EXIT_FAILED, EXIT_OK, UsageError, add_line_options, command_line,
                     print_error)

_NMT_CHOICES = {
    "start": NmtCommand.START,
    "stop": NmtCommand.STOP,
    "preop": NmtCommand.PRE_OPERATIONAL,
    "reset-node": NmtCommand.RESET_NODE,
    "reset-comm": NmtCommand.RESET_COMMUNICATION,
}


def add_parsers(subparsers: Any) -> None:
    p = subparsers.add_parser("nmt", help="send one NMT command")
    p.add_argument("command", choices=list(_NMT_CHOICES),
                   help="start (operational), stop, preop (pre-operational), reset-node "
                        "or reset-comm (reset communication)")
    p.add_argument("target", metavar="NODE|all",
                   help="node-id 1..127, or all (or 0) for every node")
    add_line_options(p)
    p.add_argument("--timeout", type=float, default=2.0, metavar="SECONDS",
                   help="how long to wait for the frame to go out (default 2)")
    p.set_defaults(func=cmd_nmt)


def cmd_nmt(args: argparse.Namespace) -> int:
    command = _NMT_CHOICES[args.command]
    try:
        target = parse_node_target(args.target)
    except CanopenFDError as exc:
        raise UsageError(str(exc)) from None
    # A monitor line reports our own frame once it went out, so we close
    # only after the command really left.
    with command_line(args, monitor=True) as line:
        sent = threading.Event()
        line.on_frame(lambda f: sent.set() if f.tx and f.id == 0 else None)
        line.nmt.send(command, target)
        if not sent.wait(args.timeout):
            print_error(f"the NMT frame was not sent on {args.channel} within "
                        f"{args.timeout:g} s (bus off, or no other node acknowledging?)")
            return EXIT_FAILED
        who = "all nodes" if target == 0 else f"node {target}"
        print(f"sent NMT {command.label} to {who} on {args.channel} "
              f"({'classic' if args.classic else 'fd'})")
        return EXIT_OK
