"""Parameter groups a local node declares for 0x1010 / 0x1011: each group is
one or more blocks of entries (contiguous key ranges), a mode (saved on
command, autonomously by the stack, both, or disabled) and a reset type (its
saved values come back at every reset communication, or only at a reset
node). The groups take sub-indices 2, 3, ... in the order given (sub 1 is
"all"); 0x1010 reads report each group's mode as CiA 301 bits 0 and 1.

    StoreGroup("calibration", [(0x2000, 0x20FF)], mode="autonomous")

Without a declaration a node has CiA 301's groups by index range:
communication (sub 2), application (sub 3), manufacturer (sub 4), on command.
The C core (co_store.c) does the work, autonomous saves included: a written
member marks its group, the stack saves it at most once per interval.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, List, Sequence, Tuple, Union

from .._binding.constants import ParameterGroup
from ..errors import ConfigurationError

__all__ = ["StoreGroup", "GroupTable", "DEFAULT_GROUPS", "MODES", "RESETS", "declare_groups"]

#: co_store mode bits (CiA 301 0x1010 read bits: 0 on command, 1 autonomously).
MODES = {"disabled": 0, "on-command": 1, "autonomous": 2, "both": 3}
#: co_store reset types.
RESETS = {"node": 0, "communication": 1}
MAX_GROUPS = 8
MAX_BLOCKS = 32

#: An entry key of a block: an index (every sub-index of it) or (index, sub).
BlockKey = Union[int, Tuple[int, int]]

#: The default groups by name: (group mask, CiA 301 sub-index).
DEFAULT_GROUPS = {
    "all": (0xFF, 1),
    "communication": (int(ParameterGroup.COMMUNICATION), 2),
    "application": (int(ParameterGroup.APPLICATION), 3),
    "manufacturer": (int(ParameterGroup.MANUFACTURER), 4),
}


@dataclass(frozen=True)
class StoreGroup:
    name: str
    blocks: Sequence[Tuple[BlockKey, BlockKey]]
    mode: str = "on-command"
    reset: str = "node"


@dataclass(frozen=True)
class GroupTable:
    """A checked declaration: the C rows and the names save_parameters takes."""
    rows: List[Tuple[int, int, int, int, int]]   # first_key, last_key, sub, mode, reset
    names: Dict[str, Tuple[int, int]]            # name -> (group mask, sub-index)
    min_interval_ms: int


def _key(value: BlockKey, last: bool, where: str) -> int:
    if isinstance(value, tuple) and len(value) == 2:
        index, sub = value
    elif isinstance(value, int) and not isinstance(value, bool):
        index, sub = value, 0xFF if last else 0
    else:
        raise ConfigurationError(f"{where}: block key {value!r} must be an index or "
                                 "(index, sub)")
    if not (isinstance(index, int) and 0x1000 <= index <= 0xFFFF and isinstance(sub, int)
            and 0 <= sub <= 0xFF):
        raise ConfigurationError(f"{where}: block key {value!r} outside 0x1000:00..0xFFFF:FF")
    return index << 8 | sub


def _key_text(key: int) -> str:
    return f"0x{key >> 8:04X}:{key & 0xFF:02X}"


def declare_groups(groups: Sequence[StoreGroup], min_interval_ms: int,
                   where: str) -> GroupTable:
    """Check a declaration; ConfigurationError names the group and block."""
    if not groups or len(groups) > MAX_GROUPS:
        raise ConfigurationError(f"{where}: 1..{MAX_GROUPS} store groups, got {len(groups)}")
    if not isinstance(min_interval_ms, int) or not 0 <= min_interval_ms <= 0xFFFFFFFF:
        raise ConfigurationError(f"{where}: store_interval_ms {min_interval_ms!r} outside "
                                 "0..4294967295")
    rows: List[Tuple[int, int, int, int, int]] = []
    names: Dict[str, Tuple[int, int]] = {"all": (0xFF, 1)}
    owners: List[Tuple[int, int, str]] = []
    for sub, group in enumerate(groups, 2):
        what = f"{where}: store group {getattr(group, 'name', group)!r}"
        if not isinstance(group, StoreGroup):
            raise ConfigurationError(f"{what} is not a StoreGroup")
        if group.name in names:
            raise ConfigurationError(f"{what}: the name is taken (names are unique, 'all' "
                                     "is sub 1)")
        if group.mode not in MODES or group.reset not in RESETS:
            raise ConfigurationError(f"{what}: mode {group.mode!r} (one of {', '.join(MODES)})"
                                     f" / reset {group.reset!r} (one of {', '.join(RESETS)})")
        if not group.blocks:
            raise ConfigurationError(f"{what} has no block")
        for block in group.blocks:
            first, last = _key(block[0], False, what), _key(block[1], True, what)
            if first > last:
                raise ConfigurationError(f"{what}: block {_key_text(first)}.."
                                         f"{_key_text(last)} is empty (first after last)")
            for other_first, other_last, owner in owners:
                if first <= other_last and other_first <= last:
                    raise ConfigurationError(
                        f"{what}: block {_key_text(first)}..{_key_text(last)} overlaps "
                        f"{_key_text(other_first)}..{_key_text(other_last)} of group "
                        f"{owner!r}: an entry belongs to one group at most")
            owners.append((first, last, group.name))
            rows.append((first, last, sub, MODES[group.mode], RESETS[group.reset]))
        names[group.name] = (1 << (sub - 2), sub)
    if len(rows) > MAX_BLOCKS:
        raise ConfigurationError(f"{where}: {len(rows)} store group blocks, at most "
                                 f"{MAX_BLOCKS}")
    return GroupTable(rows, names, min_interval_ms)
