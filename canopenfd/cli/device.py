"""`canopenfd device`: run a local node serving an object dictionary until
interrupted."""

from __future__ import annotations

import argparse
import os
import re
import sys
import threading
from typing import Any, Dict, Optional, Tuple

from ..errors import CanopenFDError
from ..od import DataType, ObjectDictionary
from .common import (EXIT_OK, Printer, UsageError, add_line_options, od_arg,
                     command_line, ms_arg, node_id_arg, parse_key, wait_until_done)
from .device_setup import add_options as add_setup_options
from .device_setup import cmd_setup_device

_SIZE_RE = re.compile(r"^(0x[0-9a-f]+|\d+)\s*(k|kib|m|mib|g|gib|b)?$", re.IGNORECASE)
_SIZE_UNITS = {None: 1, "b": 1, "k": 1 << 10, "kib": 1 << 10, "m": 1 << 20, "mib": 1 << 20,
               "g": 1 << 30, "gib": 1 << 30}


def add_parsers(subparsers: Any) -> None:
    p = subparsers.add_parser("device", help="run a local node until interrupted")
    add_line_options(p)
    p.add_argument("--node-id", type=int, metavar="N",
                   help="the node's node-id 1..127, or 255: factory-fresh, only its LSS "
                        "slave answers until an LSS master gives it a node-id (the "
                        "dictionary needs 0x1018:04; see --serial)")
    p.add_argument("--serial", metavar="N",
                   help="serial number 0x1018:04 of the LSS address (decimal or 0x hex), "
                        "replacing the dictionary's; devices on one bus need different ones")
    p.add_argument("--od", metavar="FILE",
                   help="object dictionary to serve: an EDS, DCF, XDD or XDC file, or "
                        "builtin:fd / builtin:classic (default: the built-in demo dictionary "
                        "of the line's mode)")
    p.add_argument("--store", metavar="FILE",
                   help="parameter store: values saved with 0x1010 load at boot and at "
                        "resets (the device saves nothing by itself)")
    p.add_argument("--heartbeat", type=int, default=None, metavar="MS",
                   help="heartbeat producer time, replacing the dictionary's 0x1017 "
                        "(0 = off; default: 0x1017 of the dictionary or the store)")
    p.add_argument("--domain", action="append", metavar="INDEX[:SUB]=BYTES",
                   help="keep DOMAIN entry INDEX[:SUB] (hex, or a name) in memory of BYTES "
                        "(like 16M, 512K, 0x100000), so USDO/SDO uploads and downloads reach "
                        "it; repeatable (the built-in fd dictionary has 0x2100 = 16M already; "
                        "a DOMAIN whose maximum length is at most 64K has its memory "
                        "by itself)")
    p.add_argument("--duration", type=float, metavar="SECONDS",
                   help="stop after SECONDS (default: run until Ctrl-C)")
    add_setup_options(p)
    p.set_defaults(func=cmd_device)


# ------------------------------------------------------------------ arguments
def parse_size(text: str, what: str) -> int:
    """BYTES: decimal or 0x hex, optional K/KiB, M/MiB, G/GiB (powers of 1024)."""
    match = _SIZE_RE.match(text.strip())
    if not match:
        raise UsageError(f"{what}: {text!r} is not a size (like 1048576, 0x100000, 512K or 16M)")
    number = int(match.group(1), 0)
    unit = match.group(2).lower() if match.group(2) else None
    return number * _SIZE_UNITS[unit]


def parse_domain(text: str, od: ObjectDictionary) -> Tuple[int, int, int]:
    """--domain INDEX[:SUB]=BYTES: (index, sub, capacity) of a DOMAIN entry of od."""
    key, sep, size_text = text.rpartition("=")
    if not sep or not key.strip():
        raise UsageError(f"--domain {text!r}: expected INDEX[:SUB]=BYTES, like 0x2100=16M")
    index, sub, variable = parse_key(key, od, "--domain")
    if variable is None:
        raise UsageError(f"--domain {text}: 0x{index:04X}:{sub:02X} is not in the object "
                         "dictionary")
    if variable.data_type != DataType.DOMAIN:
        raise UsageError(f"--domain {text}: {variable.where} {variable.qualname} is "
                         f"{variable.data_type.name}, not a DOMAIN")
    capacity = parse_size(size_text, f"--domain {text}")
    if not 0 < capacity < 1 << 32:
        raise UsageError(f"--domain {text}: {capacity} bytes outside 1..4 GiB - 1")
    return index, sub, capacity


def _set_serial(od: ObjectDictionary, text: Optional[str], unconfigured: bool) -> None:
    """--serial: 0x1018:04 of the dictionary (an unconfigured node needs it)."""
    serial = od.get_variable(0x1018, 4)
    if text is not None:
        try:
            value = int(text, 0)
        except ValueError:
            raise UsageError(f"--serial {text!r} is not a number (decimal or 0x hex)") from None
        if serial is None:
            raise UsageError("--serial: the dictionary has no 0x1018:04 (serial number)")
        try:
            serial.value = value
        except CanopenFDError as exc:
            raise UsageError(f"--serial {text}: {exc}") from None
    if unconfigured and serial is None:
        raise UsageError("--node-id 255 (factory-fresh, LSS only) needs a dictionary with the "
                         "serial number 0x1018:04")


def _check_store_path(path: Optional[str]) -> None:
    """--store FILE: its directory must exist (the file is created at the first save)."""
    if path is None:
        return
    if not path or os.path.isdir(path):
        raise UsageError(f"--store {path!r}: give a file name, not a directory")
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise UsageError(f"--store {path}: directory {folder} does not exist")


def _bytes_text(count: int) -> str:
    for unit, shift in (("GiB", 30), ("MiB", 20), ("KiB", 10)):
        if count >= 1 << shift and count % (1 << shift) == 0:
            return f"{count >> shift} {unit}"
    return f"{count} bytes"


def _device_domains(args: argparse.Namespace, od: Any, mode: str) -> Dict[Tuple[int, int], int]:
    """{(index, sub): capacity} of the DOMAIN entries the device keeps in
    memory: 0x2100 of the built-in fd dictionary (its DOMAIN_MAX_LENGTH,
    16 MiB, so the device can be the far end of large USDO transfers), then
    every --domain INDEX[:SUB]=BYTES (replacing a default for the same entry)."""
    from ..od.demo import DOMAIN_MAX_LENGTH

    domains: Dict[Tuple[int, int], int] = {}
    if mode == "fd" and (args.od is None or args.od == "builtin:fd"):
        domains[(0x2100, 0)] = max(DOMAIN_MAX_LENGTH, 16 << 20)
    for spec in args.domain or ():
        index, sub, capacity = parse_domain(spec, od)
        domains[(index, sub)] = capacity
    return domains


# ------------------------------------------------------------------ command
def cmd_device(args: argparse.Namespace) -> int:
    if args.setup is not None:
        return cmd_setup_device(args)
    if args.host_link is not None:
        raise UsageError("--host-link serves a process image: it needs --setup FILE")
    if args.node_id is None:
        raise UsageError("device: --node-id N is required (or --setup FILE)")
    mode = "classic" if args.classic else "fd"
    unconfigured = args.node_id == 255
    node_id = args.node_id if unconfigured else node_id_arg(args.node_id, "--node-id")
    if args.heartbeat is not None:
        ms_arg(args.heartbeat, "--heartbeat", "device")
    _check_store_path(args.store)
    # a factory-fresh node's $NODEID values follow the node-id LSS gives it
    od = od_arg(args.od, mode, None if unconfigured else node_id)
    _set_serial(od, args.serial, unconfigured)
    # An explicit --heartbeat replaces 0x1017's start value (0 = off), so resets
    # come back to it; a value saved in --store is overwritten once after boot
    # (later resets load the saved one, as 0x1010 promises). Without it the
    # OD's value, or the saved one, rules.
    producer = od.get_variable(0x1017, 0)
    has_1017 = producer is not None
    if args.heartbeat is not None and has_1017:
        try:
            producer.value = args.heartbeat
        except CanopenFDError as exc:
            raise UsageError(f"--heartbeat {args.heartbeat}: {exc}") from None
    domains = _device_domains(args, od, mode)
    with command_line(args) as line:
        printer = Printer()
        done = threading.Event()
        line.on_comm_event(lambda ev: printer.line(f"line {ev.name.lower().replace('_', ' ')}"))
        heartbeat = args.heartbeat if args.heartbeat is not None and not has_1017 else 0
        node = line.create_local_node(node_id, heartbeat_ms=heartbeat, od=od,
                                      store=args.store, boot=False)
        # node.node_id: LSS may give a factory-fresh node its id meanwhile
        node.on_state_change(lambda old, new: printer.line(
            f"node {node.node_id}: {old.label} -> {new.label}"))
        node.on_reset(lambda kind: printer.line(f"node {node.node_id}: {kind.label}"))
        node.on_veto(lambda: printer.line(f"node {node.node_id}: start refused"))
        node.lss.on_configured(lambda new_id: printer.line(
            f"node {new_id}: node-id given by LSS (was 255)"))
        node.on_store_problem(lambda status, skipped: printer.line(
            f"node {node_id}: saved parameters in {args.store} are {status}; "
            "running on defaults"))
        for (index, sub), capacity in domains.items():
            node.serve_domain((index, sub), capacity)
        node.boot()
        if args.heartbeat is not None and has_1017 and not unconfigured and \
                node.heartbeat_ms != args.heartbeat:
            node.heartbeat_ms = args.heartbeat   # a saved 0x1017 loaded at boot: override it
        source = args.od or f"builtin:{mode}"
        store = f", parameters in {args.store}" if args.store else ""
        for (index, sub), capacity in domains.items():
            name = od.get_variable(index, sub).qualname
            print(f"node {node_id}: 0x{index:04X}:{sub:02X} {name} in {_bytes_text(capacity)} "
                  "of memory", file=sys.stderr)
        for var in node.unserved_domains:
            print(f"node {node_id}: {var.where} {var.qualname} is a DOMAIN without memory: "
                  f"the network's reads and writes are refused (give it some with --domain "
                  f"0x{var.index:04X}:{var.subindex:02X}=SIZE)", file=sys.stderr)
        if unconfigured:
            print(f"node 255 (factory-fresh) on {args.channel} ({line.mode}) waits for an LSS "
                  f"master to give it a node-id, object dictionary {source}{store}; Ctrl-C "
                  "to stop", file=sys.stderr)
        else:
            print(f"node {node_id} running on {args.channel} ({line.mode}), heartbeat "
                  f"{node.heartbeat_ms} ms, object dictionary {source}{store}; Ctrl-C to "
                  "stop", file=sys.stderr)
        try:
            wait_until_done(done, printer, args.duration)
        except KeyboardInterrupt:
            pass
        return EXIT_OK
