"""`canopenfd lss ...`: the LSS master (CiA 305) from the command line.

    canopenfd lss fastscan --node-ids 10-20 --channel can0 --classic
    canopenfd lss scan VENDOR PRODUCT --channel can0
    canopenfd lss inquire [--address V:P:R:S] --channel can0
    canopenfd lss set-id NODE [--address V:P:R:S] [--store] --channel can0
    canopenfd lss store [--address V:P:R:S] --channel can0

Without --address a command puts every slave into configuration (switch
global): only right when exactly one device is on the bus. Every command
leaves the slaves waiting again."""

from __future__ import annotations

import argparse
import contextlib
from typing import Any, Iterator, List, Optional, Tuple

from ..errors import CanopenFDError
from ..line import Line
from ..services.lss import LssDevice
from .common import EXIT_FAILED, EXIT_OK, UsageError, add_line_options, command_line

_PARTS = ("vendor_id", "product_code", "revision", "serial")
_U32 = 0xFFFFFFFF


def _u32(text: str, what: str) -> int:
    try:
        value = int(text, 0)
    except ValueError:
        raise UsageError(f"{what} {text!r} is not a number (decimal or 0x hex)") from None
    if not 0 <= value <= _U32:
        raise UsageError(f"{what} {text!r} outside 0..0xFFFFFFFF")
    return value


def parse_address(text: str) -> Tuple[int, int, int, int]:
    """'VENDOR:PRODUCT:REVISION:SERIAL' (decimal or 0x hex each)."""
    fields = text.split(":")
    if len(fields) != 4:
        raise UsageError(f"--address {text!r}: expected VENDOR:PRODUCT:REVISION:SERIAL")
    a, b, c, d = (_u32(f, f"--address {name}") for f, name in zip(fields, _PARTS))
    return a, b, c, d


def parse_node_ids(text: str) -> List[int]:
    """'10-20', '10,11,14' or a mix ('10-12,20'): node-ids 1..127 in the order given."""
    ids: List[int] = []
    for item in text.split(","):
        low, _, high = item.strip().partition("-")
        try:
            first, last = int(low), int(high or low)
        except ValueError:
            raise UsageError(f"--node-ids {text!r}: expected numbers like 10-20 or 10,11") \
                from None
        if not 1 <= first <= last <= 127:
            raise UsageError(f"--node-ids {text!r}: node-ids must be 1..127, low to high")
        ids.extend(range(first, last + 1))
    if len(set(ids)) != len(ids):
        raise UsageError(f"--node-ids {text!r} names a node-id twice")
    return ids


def _range(text: Optional[str], what: str) -> Tuple[int, int]:
    if text is None:
        return 0, _U32
    low, sep, high = text.partition("-")
    if not sep:
        raise UsageError(f"{what} {text!r}: expected LOW-HIGH")
    first, last = _u32(low, what), _u32(high, what)
    if first > last:
        raise UsageError(f"{what} {text!r}: LOW above HIGH")
    return first, last


def _device_line(device: LssDevice) -> str:
    text = (f"vendor 0x{device.vendor_id:08X} product 0x{device.product_code:08X} "
            f"revision 0x{device.revision:08X} serial 0x{device.serial:08X}")
    return f"{text} -> node {device.node_id}" if device.node_id else text


def add_parsers(subparsers: Any) -> None:
    p = subparsers.add_parser("lss", help="LSS master (CiA 305): find devices, give node-ids")
    sub = p.add_subparsers(dest="lss_cmd", metavar="LSS_COMMAND")
    sub.required = True

    def command(name: str, help_text: str) -> argparse.ArgumentParser:
        q: argparse.ArgumentParser = sub.add_parser(name, help=help_text)
        add_line_options(q)
        q.add_argument("--step-timeout", type=float, default=0.1, metavar="SECONDS",
                       help="how long each answer is awaited (default 0.1)")
        return q

    q = command("fastscan", "find every device without a node-id and give each one")
    q.add_argument("--node-ids", required=True, metavar="IDS",
                   help="node-ids to hand out in order: 10-20, 10,11,14 or a mix")
    q.set_defaults(func=cmd_fastscan)
    q = command("scan", "find devices of a vendor and product (configured or not)")
    q.add_argument("vendor", help="vendor-ID (0x1018:01)")
    q.add_argument("product", help="product code (0x1018:02)")
    q.add_argument("--revisions", metavar="LOW-HIGH", help="revision range (default all)")
    q.add_argument("--serials", metavar="LOW-HIGH", help="serial number range (default all)")
    q.set_defaults(func=cmd_scan)
    for name, help_text, func in (
            ("inquire", "print a device's LSS address and node-id", cmd_inquire),
            ("store", "make a device store its pending node-id", cmd_store)):
        q = command(name, help_text)
        q.add_argument("--address", metavar="V:P:R:S",
                       help="the device's LSS address (default: the only device on the bus)")
        q.set_defaults(func=func)
    q = command("set-id", "give a device a node-id (used after its next reset communication)")
    q.add_argument("node_id", type=int, help="node-id 1..127")
    q.add_argument("--address", metavar="V:P:R:S",
                   help="the device's LSS address (default: the only device on the bus)")
    q.add_argument("--store", action="store_true", help="also store it in the device")
    q.set_defaults(func=cmd_set_id)


@contextlib.contextmanager
def _master(args: argparse.Namespace) -> Iterator[Line]:
    if not 0 < args.step_timeout <= 60:
        raise UsageError(f"--step-timeout {args.step_timeout:g}: expected 0 < SECONDS <= 60")
    with command_line(args) as line:
        line.lss.timeout_ms = max(1, round(args.step_timeout * 1000))
        yield line


@contextlib.contextmanager
def _selected(args: argparse.Namespace) -> Iterator[Line]:
    """The line, with the device of --address (or every device) in configuration;
    the slaves back to waiting at the end."""
    address = parse_address(args.address) if args.address else None
    with _master(args) as line:
        if address is None:
            line.lss.switch_global("configuration")
        elif not line.lss.switch_selective(*address):
            raise CanopenFDError(f"no device answered LSS address {args.address}")
        try:
            yield line
        finally:
            line.lss.switch_global("waiting")


def cmd_fastscan(args: argparse.Namespace) -> int:
    ids = parse_node_ids(args.node_ids)
    with _master(args) as line:
        found = line.lss.fast_scan(ids)
    for device in found:
        print(_device_line(device))
    print(f"{len(found)} device(s) without a node-id found" if found
          else "no device without a node-id answered")
    return EXIT_OK


def cmd_scan(args: argparse.Namespace) -> int:
    vendor, product = _u32(args.vendor, "vendor"), _u32(args.product, "product")
    revisions = _range(args.revisions, "--revisions")
    serials = _range(args.serials, "--serials")
    with _master(args) as line:
        found = line.lss.scan(vendor, product, revisions, serials)
    for device in found:
        print(_device_line(device))
    print(f"{len(found)} device(s) found")
    return EXIT_OK if found else EXIT_FAILED


def cmd_inquire(args: argparse.Namespace) -> int:
    with _selected(args) as line:
        values = {part: line.lss.inquire(part) for part in (*_PARTS, "node_id")}
    print(" ".join(f"{part} 0x{values[part]:08X}" for part in _PARTS) +
          f" node-id {values['node_id']}")
    return EXIT_OK


def cmd_set_id(args: argparse.Namespace) -> int:
    if not 1 <= args.node_id <= 127:
        raise UsageError(f"node-id {args.node_id} outside 1..127")
    with _selected(args) as line:
        line.lss.configure_node_id(args.node_id)
        if args.store:
            line.lss.store()
    print(f"node-id {args.node_id} configured" + (" and stored" if args.store else "") +
          " (active after the device's next reset communication)")
    return EXIT_OK


def cmd_store(args: argparse.Namespace) -> int:
    with _selected(args) as line:
        line.lss.store()
    print("stored")
    return EXIT_OK
