"""The `canopenfd od` command: `od show FILE` and `od check FILE`.

FILE is an EDS, DCF, XDD or XDC file (chosen by extension, else by content),
or ``builtin:fd`` / ``builtin:classic`` for the built-in demo dictionary.

- `od show` prints one line per entry: index:sub, name, type, access,
  default, limits, PDO direction and flags.
- `od check` reads the file (leniently, like every import) and validates the
  dictionary: it prints every problem, including each deviation the lenient
  import recovered (what ``strict=True`` refuses), and exits 1 when there is
  an error (a file that cannot be read counts as one), 0 otherwise (warnings
  are printed, they do not fail).

A FILE that does not exist is a usage error (exit 2, one line on stderr),
like the other commands' bad arguments.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
from typing import Any, List, Optional, Sequence

from ..errors import CanopenFDError
from ..od import (DataType, ODVariable, ObjectDictionary, OdFileError, TimeDifference,
                  TimeOfDay, demo_od, import_od)
from .common import EXIT_FAILED, EXIT_OK, EXIT_USAGE, print_error

_BUILTIN = "builtin:"
_NAME_WIDTH = 40
_VALUE_WIDTH = 26


def add_parsers(subparsers: Any) -> argparse.ArgumentParser:
    """Register `od show FILE` and `od check FILE` on the main parser's
    subparsers; the handler is set as `func` (the main parser's convention)."""
    parser: argparse.ArgumentParser = subparsers.add_parser(
        "od", help="show or check an object dictionary file (EDS, DCF, XDD, XDC)",
        description="Read an EDS/DCF/XDD/XDC file (or builtin:fd, builtin:classic) and "
                    "print its entries or check it.")
    od_sub = parser.add_subparsers(dest="od_cmd", metavar="ACTION")
    od_sub.required = True
    for name, helptext in (("show", "print the entries as a table"),
                           ("check", "validate; exit 1 on errors, 0 when clean")):
        action = od_sub.add_parser(name, help=helptext)
        action.add_argument("file", metavar="FILE",
                            help="EDS, DCF, XDD or XDC file, or builtin:fd / builtin:classic")
        action.add_argument("--node-id", type=int, metavar="N",
                            help="resolve $NODEID with this node-id 1..127 (default: the "
                                 "DCF/XDC's)")
        action.add_argument("--mode", choices=("fd", "classic"),
                            help="the kind of line the device is for (default: guessed from "
                                 "the file; builtin:fd / builtin:classic name it)")
        action.set_defaults(func=cmd_od_show if name == "show" else cmd_od_check)
    return parser


# ------------------------------------------------------------------ loading
def _load(args: argparse.Namespace) -> ObjectDictionary:
    """The dictionary FILE names; OdFileError when it cannot be read."""
    if args.node_id is not None and not 1 <= args.node_id <= 127:
        raise OdFileError(f"--node-id {args.node_id} outside 1..127", args.file)
    if args.file.startswith(_BUILTIN):
        mode = args.file[len(_BUILTIN):]
        if mode not in ("fd", "classic"):
            raise OdFileError("built-in dictionaries are builtin:fd and builtin:classic",
                              args.file)
        od = demo_od(args.mode or mode, node_id=args.node_id)
        od.source = args.file
        return od
    return import_od(args.file, node_id=args.node_id, mode=args.mode)


def _require_file(path: str) -> None:
    """A missing FILE is a usage error (exit 2), not a problem of a file."""
    if path.startswith(_BUILTIN):
        return
    if not os.path.exists(path):
        raise OdFileError("no such file", path)
    if os.path.isdir(path):
        raise OdFileError("is a directory, not a file", path)


# ------------------------------------------------------------------ show
def format_value(var: ODVariable, value: Any, relative: bool = False) -> str:
    """A value for the table: short, unambiguous, '-' when absent."""
    if value is None:
        return "-"
    if relative:
        node_id = var.node_id
        resolved = f" (0x{value + node_id:X})" if node_id else ""
        return f"$NODEID+0x{value:X}{resolved}"
    dtype = var.data_type
    if dtype == DataType.BOOLEAN:
        return "true" if value else "false"
    if dtype.is_integer:
        size = dtype.size or 0
        if dtype.signed or size < 4:
            return str(value)  # counts, times, small numbers: decimal reads best
        return f"0x{value:08X}" if size == 4 else f"0x{value:X}"  # ids, masks, codes
    if dtype.is_real:
        return repr(value)
    if isinstance(value, TimeOfDay):
        return value.to_datetime().strftime("%Y-%m-%d %H:%M:%S.%f")[:-3]
    if isinstance(value, TimeDifference):
        delta = value.to_timedelta()
        hours, rest = divmod(delta.seconds, 3600)
        return (f"{delta.days}d {hours:02d}:{rest // 60:02d}:{rest % 60:02d}"
                f".{delta.microseconds // 1000:03d}")
    if isinstance(value, bytes):
        text = value.hex(" ").upper() if value else "(empty)"
    else:
        text = repr(value)
    return _clip(text, _VALUE_WIDTH)


def _clip(text: str, width: int) -> str:
    return text if len(text) <= width else text[:width - 3] + "..."


def _limits(var: ODVariable) -> str:
    low, high = var.low_limit, var.high_limit
    if low is None and high is None:
        return "-"
    shown = ["" if limit is None else format_value(var, limit) for limit in (low, high)]
    return "..".join(shown)


def _flags(var: ODVariable) -> str:
    flags: List[str] = []
    if var.store:
        flags.append("store")
    if var.line_mode:
        flags.append(f"{var.line_mode}-only")
    if var.max_length is not None:
        flags.append(f"max={var.max_length}")
    if var.value_base is not None:
        flags.append("value=" + format_value(var, var.value_base, var.value_relative_to_node_id))
    if var.denotation:
        flags.append(f"denotation={var.denotation!r}")
    return " ".join(flags) or "-"


def _rows(od: ObjectDictionary) -> List[List[str]]:
    rows: List[List[str]] = []
    for index in od:
        obj = od[index]
        members = [obj] if isinstance(obj, ODVariable) else \
            [obj.subindices[sub] for sub in sorted(obj.subindices)]
        if not isinstance(obj, ODVariable):
            rows.append([f"0x{index:04X}", obj.name, obj.object_type.name, "", "", "", "", ""])
        for var in members:
            where = f"0x{index:04X}" if var is obj else var.where
            name = var.name if var is obj else "  " + var.name
            rows.append([where, _clip(name, _NAME_WIDTH), var.data_type.name, var.access_type,
                         format_value(var, var.default_base, var.relative_to_node_id),
                         _limits(var), var.pdo_mappable or "-", _flags(var)])
    return rows


def _table(rows: List[List[str]]) -> List[str]:
    header = ["index:sub", "name", "type", "access", "default", "limits", "pdo", "flags"]
    widths = [max(len(row[i]) for row in [header] + rows) for i in range(len(header))]
    lines = []
    for row in [header] + rows:
        cells = [cell.ljust(widths[i]) for i, cell in enumerate(row[:-1])] + [row[-1]]
        lines.append("  ".join(cells).rstrip())
    return lines


def cmd_od_show(args: argparse.Namespace) -> int:
    _require_file(args.file)
    od = _load(args)
    entries = sum(1 for _ in od.entries())
    kind = "built-in demo" if args.file.startswith(_BUILTIN) else od.source_format
    node = od.node_id if od.node_id is not None else "-"
    lines = [f"{os.path.basename(args.file)}: {kind + ', ' if kind else ''}"
             f"{od.mode or 'mode unknown'}, node-id {node}, {len(od)} objects, "
             f"{entries} entries"]
    for key in ("VendorName", "ProductName"):
        if od.device_info.get(key):
            lines.append(f"{key}: {od.device_info[key]}")
    lines.append("")
    lines.extend(_table(_rows(od)))
    try:
        print("\n".join(lines), flush=True)
    except BrokenPipeError:  # `canopenfd od show x.eds | head`
        _quiet_stdout()
    return EXIT_OK


def _quiet_stdout() -> None:
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except OSError:
        pass


# ------------------------------------------------------------------ check
class _NoImportLog(logging.Filter):
    """`od check` prints every recovered deviation itself; import_od's log
    line for each would repeat them on stderr."""

    def filter(self, record: logging.LogRecord) -> bool:
        return not record.name.startswith("canopenfd.od")


def cmd_od_check(args: argparse.Namespace) -> int:
    _require_file(args.file)
    name = os.path.basename(args.file)
    quiet = _NoImportLog()
    logging.getLogger("canopenfd.od").addFilter(quiet)
    try:
        od = _load(args)
    except OdFileError as exc:
        print(f"error: {exc}")
        print(f"{name}: cannot be read (1 error)")
        return EXIT_FAILED
    finally:
        logging.getLogger("canopenfd.od").removeFilter(quiet)
    problems = list(od.load_warnings) + od.validate()
    errors = sum(1 for p in problems if p.is_error)
    warnings = len(problems) - errors
    for problem in problems:
        print(problem)
    verdict = "OK" if not errors else "FAILED"
    print(f"{name}: {verdict}: {errors} error{'s' if errors != 1 else ''}, "
          f"{warnings} warning{'s' if warnings != 1 else ''} "
          f"({len(od)} objects, {sum(1 for _ in od.entries())} entries, {od.mode or '?'})")
    return EXIT_FAILED if errors else EXIT_OK


# ------------------------------------------------------------------ on its own
def main(argv: Optional[Sequence[str]] = None) -> int:
    """`od show|check FILE ...` without the rest of the command line (tests):
    argv is what follows `canopenfd od`."""
    parser = argparse.ArgumentParser(prog="canopenfd")
    sub = parser.add_subparsers(dest="cmd", metavar="COMMAND")
    sub.required = True
    add_parsers(sub)
    args = parser.parse_args(["od", *(sys.argv[1:] if argv is None else argv)])
    try:
        status: int = args.func(args)
        return status
    except CanopenFDError as exc:
        print_error(str(exc))
        return EXIT_USAGE
