"""The `canopenfd` console entry point: the argument parser, gathering the
subcommands of every command group, and `main()`."""

from __future__ import annotations

import argparse
import logging
from typing import List, Optional

from .. import __version__
from ..errors import CanopenFDError
from ..network import Network
from . import concise, demo, device, gateway, lss, monitor, nmt, od, store, transfer
from .common import EXIT_USAGE, UsageError, print_error

#: the command groups in the order `--help` lists their commands
COMMAND_GROUPS = (demo, nmt, monitor, device, od, transfer, concise, lss, gateway, store)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="canopenfd", description="CANopen FD / classic CANopen tools")
    parser.add_argument("--version", action="version", version=f"canopenfd {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true",
                        help="log the stack's messages (debug level) to stderr")
    sub = parser.add_subparsers(dest="cmd", metavar="COMMAND")
    sub.required = True
    for group in COMMAND_GROUPS:
        group.add_parsers(sub)
    return parser


def main(argv: Optional[List[str]] = None, network: Optional[Network] = None) -> int:
    """Run the command line argv (default sys.argv[1:]); the exit status.
    network: run on this Network instead of a new one (its lines stay open
    afterwards): an in-process bus ('mem:NAME') belongs to one Network, so
    tests and embedding programs reach the nodes they run themselves this way."""
    args = build_parser().parse_args(argv)
    args.network = network
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    try:
        status: int = args.func(args)
        return status
    except (CanopenFDError, UsageError) as exc:
        print_error(str(exc))
        return EXIT_USAGE
    except KeyboardInterrupt:
        return 130
