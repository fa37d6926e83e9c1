"""`canopenfd monitor`: print every frame of a line, raw and decoded."""

from __future__ import annotations

import argparse
import sys
import threading
from typing import Any, Tuple

from ..decode import Decoder
from ..frame import Frame
from .common import (EXIT_OK, Printer, UsageError, add_line_options, command_line, node_id_arg,
                     wait_until_done)


def add_parsers(subparsers: Any) -> None:
    p = subparsers.add_parser("monitor", help="print every frame, decoded")
    add_line_options(p)
    p.add_argument("--od", action="append", metavar="FILE[@NODE]",
                   help="object dictionary (EDS, DCF, XDD or XDC) of node NODE: its PDOs "
                        "are shown as name=value by their mapping; NODE may be left out when "
                        "the file names its node-id (DCF, XDC); repeatable, one per node")
    p.add_argument("--duration", type=float, metavar="SECONDS",
                   help="stop after SECONDS (default: run until Ctrl-C)")
    p.add_argument("--count", type=int, metavar="N", help="stop after N frames")
    p.set_defaults(func=cmd_monitor)


def _monitor_od(spec: str) -> Tuple[Any, int]:
    """`monitor --od FILE[@NODE]`: the dictionary and the node-id it describes
    (NODE, else the node-id the DCF/XDC names)."""
    path, node = spec, None
    head, at, tail = spec.rpartition("@")
    if at and head and tail.strip().isdigit():
        path = head
        node = node_id_arg(int(tail), f"--od {spec}: NODE")
    from ..od import OdFileError, import_od

    try:
        od = import_od(path, node_id=node)
    except OdFileError as exc:
        raise UsageError(f"--od {exc}") from None
    except OSError as exc:
        raise UsageError(f"--od {path}: {exc.strerror or exc}") from None
    node = node if node is not None else od.node_id
    if node is None:
        raise UsageError(f"--od {spec}: give the node-id it describes as FILE@NODE "
                         "(the file names none)")
    return od, node


def cmd_monitor(args: argparse.Namespace) -> int:
    if args.count is not None and args.count < 1:
        raise UsageError(f"--count must be >= 1, got {args.count}")
    # Follows SDO block transfers and guarding requests across frames; decodes
    # the PDOs of the --od dictionaries by their mappings.
    decoder = Decoder()
    for spec in args.od or ():
        od, node = _monitor_od(spec)
        count = decoder.add_od(od, node)
        print(f"node {node}: {count} PDO{'' if count == 1 else 's'} from {od.source or spec}",
              file=sys.stderr)
    with command_line(args, monitor=True) as line:
        printer = Printer()
        done = threading.Event()
        seen = [0]

        def on_frame(frame: Frame) -> None:
            if done.is_set():
                return
            printer.line(f"{'TX' if frame.tx else 'RX'}  {decoder.describe(frame)}",
                         frame.timestamp)
            seen[0] += 1
            if args.count is not None and seen[0] >= args.count:
                done.set()

        line.on_frame(on_frame)
        line.on_comm_event(lambda ev: printer.line(f"--  {ev.name.lower().replace('_', ' ')}"))
        print(f"monitoring {args.channel} ({line.mode}); Ctrl-C to stop", file=sys.stderr)
        try:
            wait_until_done(done, printer, args.duration)
        except KeyboardInterrupt:
            pass
        return EXIT_OK
