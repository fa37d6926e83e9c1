"""The `canopenfd dcf2concise FILE [-o OUT] [--node-id N] [--changed-only]`
command: a DCF (or XDC) turned into the concise DCF (CiA 302-3) a
configuration manager downloads (see canopenfd.od.concise for which entries
go in and in which order).

It prints one line per entry in write order (index:sub, bytes) and each
configured entry it left out with the reason, then a summary; with ``-o OUT``
it writes the concise DCF there. A file that cannot be read, or a value that
needs a node-id nobody gave, is an error naming the file and line (exit 2).
"""

from __future__ import annotations

import argparse
import os
import sys
from typing import Any, List

from ..od import OdFileError, import_od
from ..od.concise import concise_from_od
from .common import EXIT_OK


def add_parsers(subparsers: Any) -> argparse.ArgumentParser:
    """Register `dcf2concise` on the main parser's subparsers."""
    parser: argparse.ArgumentParser = subparsers.add_parser(
        "dcf2concise", help="convert a DCF to a concise DCF (CiA 302-3)",
        description="Convert a DCF (or XDC) into the concise DCF a configuration manager "
                    "downloads: the entries with a configured value (ParameterValue), "
                    "writable ones only, PDOs in the CiA 301 order.")
    parser.add_argument("file", metavar="FILE", help="DCF or XDC file")
    parser.add_argument("-o", "--output", metavar="OUT",
                        help="write the concise DCF to OUT (else only print)")
    parser.add_argument("--node-id", type=int, metavar="N",
                        help="resolve $NODEID with this node-id 1..127 (default: the DCF's)")
    parser.add_argument("--changed-only", action="store_true",
                        help="leave out values equal to the default (right only for a node "
                             "that was reset to its defaults)")
    parser.set_defaults(func=cmd_dcf2concise)
    return parser


def cmd_dcf2concise(args: argparse.Namespace) -> int:
    if args.node_id is not None and not 1 <= args.node_id <= 127:
        raise OdFileError(f"--node-id {args.node_id} outside 1..127", args.file)
    if not os.path.isfile(args.file):
        raise OdFileError("no such file", args.file)
    od = import_od(args.file, node_id=args.node_id)
    conversion = concise_from_od(od, changed_only=args.changed_only)
    data = conversion.data
    lines: List[str] = [f"{entry.where}  {entry.data.hex(' ')}" for entry in conversion.entries]
    lines += [f"left out {where}: {reason}" for where, reason in conversion.skipped]
    if args.output:
        try:
            with open(args.output, "wb") as out:
                out.write(data)
        except OSError as exc:
            raise OdFileError(f"cannot write: {exc.strerror}", args.output) from None
        lines.append(f"{os.path.basename(args.file)} -> {args.output}: {conversion.summary()}")
    else:
        lines.append(f"{os.path.basename(args.file)}: {conversion.summary()} (not written: "
                     f"no -o)")
    print("\n".join(lines), file=sys.stdout, flush=True)
    return EXIT_OK
