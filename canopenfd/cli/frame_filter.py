"""The monitor's frame filters: --node N, --service NAME, --id ID[-ID].

Each option may be given several times: a frame passes an option when it
matches any of its values, and is shown when it passes every option given
(so `--node 5 --service usdo` is node 5's USDO frames)."""

from __future__ import annotations

import argparse
from typing import Any, FrozenSet, List, Optional, Tuple

from ..decode import SERVICE_GROUPS, SERVICES, Decoder, service_names
from .common import UsageError, node_id_arg

_MAX_CAN_ID = 0x1FFFFFFF


def service_help() -> str:
    listed = "; ".join(f"{name}: {text}" for name, text in SERVICES.items())
    groups = "; ".join(f"{name}: {' and '.join(parts)}" for name, parts in SERVICE_GROUPS.items())
    return f"show only frames of service NAME (repeatable): {listed}; {groups}"


def add_filter_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--node", action="append", metavar="N",
                        help="show only frames that concern node N (1..127, repeatable): its "
                             "NMT commands (and those to every node), heartbeat, EMCY, PDOs, "
                             "SDO/USDO to or from it; SYNC and TIME concern no node")
    parser.add_argument("--service", action="append", metavar="NAME", help=service_help())
    parser.add_argument("--id", action="append", metavar="ID[-ID]", dest="can_id",
                        help="show only frames with this CAN-ID or in this range (inclusive), "
                             "0x hex or decimal, e.g. 0x181 or 0x580-0x5FF (repeatable)")


def parse_can_id(text: str, where: str) -> int:
    stripped = text.strip()
    try:
        value = int(stripped, 16) if stripped[:2].lower() == "0x" else int(stripped, 10)
    except ValueError:
        raise UsageError(f"{where}: {text!r} is not a CAN-ID (0x hex or decimal)") from None
    if not 0 <= value <= _MAX_CAN_ID:
        raise UsageError(f"{where}: CAN-ID {text!r} outside 0..0x1FFFFFFF")
    return value


def parse_id_range(text: str) -> Tuple[int, int]:
    """ID or ID-ID (inclusive) of --id."""
    where = f"--id {text}"
    low_text, dash, high_text = text.partition("-")
    low = parse_can_id(low_text, where)
    high = parse_can_id(high_text, where) if dash else low
    if high < low:
        raise UsageError(f"{where}: the range ends (0x{high:X}) before it starts (0x{low:X})")
    return low, high


class FrameFilter:
    """Which frames the monitor shows (every frame when no option was given)."""

    def __init__(self, nodes: Optional[FrozenSet[int]] = None,
                 services: Optional[FrozenSet[str]] = None,
                 ids: Tuple[Tuple[int, int], ...] = ()) -> None:
        self.nodes = nodes
        self.services = services
        self.ids = ids

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> "FrameFilter":
        nodes = frozenset(node_id_arg(_node_number(text), f"--node {text}")
                          for text in args.node) if args.node else None
        services: Optional[FrozenSet[str]] = None
        if args.service:
            names: List[str] = []
            for text in args.service:
                try:
                    names.extend(service_names(text))
                except ValueError as exc:
                    raise UsageError(f"--service: {exc}") from None
            services = frozenset(names)
        ids = tuple(parse_id_range(text) for text in args.can_id or ())
        return cls(nodes, services, ids)

    @property
    def active(self) -> bool:
        return self.nodes is not None or self.services is not None or bool(self.ids)

    def accepts(self, frame: Any, decoder: Decoder) -> bool:
        if self.ids and not any(low <= frame.id <= high for low, high in self.ids):
            return False
        if self.nodes is None and self.services is None:
            return True
        service, nodes = decoder.service(frame)
        if self.services is not None and service not in self.services:
            return False
        if self.nodes is not None:
            if service == "nmt" and 0 in nodes:        # NMT to every node
                return True
            return any(node in self.nodes for node in nodes)
        return True


def _node_number(text: str) -> object:
    stripped = text.strip()
    try:
        return int(stripped, 16) if stripped[:2].lower() == "0x" else int(stripped, 10)
    except ValueError:
        return text
