"""Concise DCF (CiA 302-3): the binary configuration a configuration manager
downloads into a node, and its conversion from a DCF.

Layout (little-endian; evidence in docs/protocol-notes.md, "Concise DCF"):
an UNSIGNED32 number of entries, then per entry UNSIGNED16 index, UNSIGNED8
sub-index, UNSIGNED32 data size and the data. `parse_concise` reads it with
the same checks as the C iterator (csrc/core/co_concise_dcf.c), each error
naming the byte offset; `build_concise` writes it.

`concise_from_od` picks the entries a DCF configures:

- an entry goes in when the DCF gives it a configured value (ParameterValue;
  XDC actualValue). CiA 306 keeps the device's reset value in DefaultValue
  and the configuration in ParameterValue, so ParameterValue is what a
  configuration manager has to write; an entry without one is left as the
  device has it.
- ``changed_only=True`` also leaves out values equal to the entry's default
  for this node: shorter, but right only for a node that was reset to its
  defaults (restore 0x1011, or new), since a value written by an earlier
  configuration stays otherwise.
- left out, and listed in ``skipped`` with the reason: read-only and const
  entries (a node refuses them: 0x06010002), 0x1010/0x1011 (their values are
  commands, not parameters), 0x1020 (the configuration stamp: the manager
  compares it and writes it last; its DCF values are returned as ``stamp``),
  and values that depend on the node-id when none is known (an error instead,
  naming file and line).
- PDOs are written the way CiA 301 lets a node accept them: for each PDO with
  configured entries, its COB-ID (when configured) first with bit 31 set
  (PDO invalid), then the other communication parameters, the mapping count
  0, the mapping entries, the mapping count, and last the COB-ID's own value.
  Every other entry goes in (index, sub-index) order.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from typing import Dict, Iterable, Iterator, List, Optional, Tuple, Union

from .datatypes import encode
from .errors import OdError, OdFileError, OdValueError
from .model import ObjectDictionary
from .variable import ODVariable, format_index

__all__ = ["ConciseEntry", "ConciseDcfError", "ConciseConversion", "parse_concise",
           "build_concise", "concise_from_od"]

_COUNT = struct.Struct("<I")
_HEADER = struct.Struct("<HBI")
_STAMP_INDEX = 0x1020
_COMMANDS = (0x1010, 0x1011)
_PDO_INVALID = 0x80000000
# (communication base, mapping base) of RPDOs and TPDOs, 512 each
_PDO_RANGES = ((0x1400, 0x1600), (0x1800, 0x1A00))


@dataclass(frozen=True)
class ConciseEntry:
    """One entry: index, sub-index and the bytes written; unpacks as
    ``index, subindex, data = entry``."""

    index: int
    subindex: int
    data: bytes

    def __iter__(self) -> Iterator[Union[int, bytes]]:
        return iter((self.index, self.subindex, self.data))

    @property
    def where(self) -> str:
        return format_index(self.index, self.subindex)


class ConciseDcfError(OdError):
    """A malformed concise DCF; `offset` is the byte where it was found."""

    def __init__(self, problem: str, offset: int, source: str = "") -> None:
        self.problem = problem
        self.offset = offset
        prefix = f"{source}: " if source else ""
        super().__init__(f"{prefix}byte {offset}: {problem}")


def parse_concise(data: bytes, source: str = "") -> List[ConciseEntry]:
    """The entries of a concise DCF, in order. ConciseDcfError (naming the
    byte offset, and `source` when given) when it is shorter than its count,
    an entry header or data is cut, fewer entries than announced follow, or
    bytes follow the last one."""
    view = memoryview(bytes(data))
    if len(view) < _COUNT.size:
        raise ConciseDcfError(f"{len(view)} bytes: shorter than the 4-byte number of "
                              f"entries", 0, source)
    (count,) = _COUNT.unpack_from(view, 0)
    pos = _COUNT.size
    entries: List[ConciseEntry] = []
    while len(entries) < count:
        left = len(view) - pos
        if left == 0:
            raise ConciseDcfError(f"{len(entries)} entries where {count} were announced",
                                  pos, source)
        if left < _HEADER.size:
            raise ConciseDcfError(f"entry {len(entries)}: header cut short ({left} of "
                                  f"{_HEADER.size} bytes)", pos, source)
        index, sub, size = _HEADER.unpack_from(view, pos)
        if size > left - _HEADER.size:
            raise ConciseDcfError(
                f"entry {len(entries)} ({format_index(index, sub)}): data size {size} goes "
                f"past the end ({left - _HEADER.size} bytes left)", pos + 3, source)
        start = pos + _HEADER.size
        entries.append(ConciseEntry(index, sub, bytes(view[start:start + size])))
        pos = start + size
    if pos != len(view):
        raise ConciseDcfError(f"{len(view) - pos} bytes after the last of the {count} "
                              f"announced entries", pos, source)
    return entries


def build_concise(entries: Iterable[Union[ConciseEntry, Tuple[int, int, bytes]]]) -> bytes:
    """A concise DCF of (index, sub-index, data) entries, in the given order."""
    body = bytearray()
    count = 0
    for item in entries:
        index, sub, data = ((item.index, item.subindex, item.data)
                            if isinstance(item, ConciseEntry) else item)
        if not 0 <= index <= 0xFFFF or not 0 <= sub <= 0xFF:
            raise OdValueError(f"index {index:#x} / sub-index {sub:#x} outside "
                               f"0..0xFFFF / 0..0xFF")
        body += _HEADER.pack(index, sub, len(data)) + bytes(data)
        count += 1
    return _COUNT.pack(count) + bytes(body)


@dataclass
class ConciseConversion:
    """What `concise_from_od` chose: the entries in write order, the entries
    left out with the reason, the DCF's 0x1020 stamp (date, time) if any."""

    entries: List[ConciseEntry] = field(default_factory=list)
    skipped: List[Tuple[str, str]] = field(default_factory=list)
    stamp: Optional[Tuple[int, int]] = None
    source: str = ""

    @property
    def data(self) -> bytes:
        """The concise DCF bytes."""
        return build_concise(self.entries)

    def summary(self) -> str:
        """One line: entries, bytes, skipped, stamp."""
        text = f"{len(self.entries)} entries, {len(self.data)} bytes"
        if self.skipped:
            text += f", {len(self.skipped)} configured entries left out"
        if self.stamp is not None:
            text += f", 0x1020 date {self.stamp[0]:#010x} time {self.stamp[1]:#010x}"
        return text


def _locate(var: ODVariable, od: ObjectDictionary) -> Tuple[str, Optional[int]]:
    return (od.source or "<dictionary>", var.value_line)


def _value_bytes(var: ODVariable, od: ObjectDictionary) -> bytes:
    if var.value_relative_to_node_id and not od.node_id:
        source, line = _locate(var, od)
        raise OdFileError(f"the value {var.value_expr or var.value_base!r} depends on the "
                          f"node-id and none is known (give --node-id N, or NodeID in "
                          f"[DeviceComissioning])", source, line,
                          f"{var.where} {var.qualname}")
    try:
        return encode(var.data_type, var.value)
    except OdValueError as exc:
        source, line = _locate(var, od)
        raise OdFileError(exc.problem, source, line, f"{var.where} {var.qualname}") from None


def _pdo_of(index: int) -> Optional[Tuple[int, int, bool]]:
    """(direction 0/1, number, is mapping) of a PDO parameter index, else None."""
    for direction, (comm, mapping) in enumerate(_PDO_RANGES):
        if comm <= index < comm + 0x200:
            return direction, index - comm, False
        if mapping <= index < mapping + 0x200:
            return direction, index - mapping, True
    return None


def _pdo_sequence(direction: int, number: int, comm: Dict[int, bytes],
                  mapping: Dict[int, bytes]) -> List[ConciseEntry]:
    comm_index = _PDO_RANGES[direction][0] + number
    map_index = _PDO_RANGES[direction][1] + number
    out: List[ConciseEntry] = []
    cob = comm.get(1)
    if cob is not None and len(cob) == 4:
        value = int.from_bytes(cob, "little")
        if not value & _PDO_INVALID:
            out.append(ConciseEntry(comm_index, 1, (value | _PDO_INVALID).to_bytes(4, "little")))
    out += [ConciseEntry(comm_index, sub, data) for sub, data in sorted(comm.items())
            if sub != 1]
    count = mapping.get(0)
    if count is not None:
        out.append(ConciseEntry(map_index, 0, bytes(len(count))))
    out += [ConciseEntry(map_index, sub, data) for sub, data in sorted(mapping.items())
            if sub != 0]
    if count is not None:
        out.append(ConciseEntry(map_index, 0, count))
    if cob is not None:
        out.append(ConciseEntry(comm_index, 1, cob))
    return out


def concise_from_od(od: ObjectDictionary, changed_only: bool = False) -> ConciseConversion:
    """The concise DCF of a DCF (or XDC) read with `import_od`: see the module
    docstring for which entries go in and their order. The node-id of
    node-id relative values is the dictionary's (import_od's node_id, or the
    DCF's NodeID)."""
    result = ConciseConversion(source=od.source)
    before: List[ConciseEntry] = []
    after: List[ConciseEntry] = []
    pdos: Dict[Tuple[int, int], Tuple[Dict[int, bytes], Dict[int, bytes]]] = {}
    stamp: Dict[int, int] = {}
    for var in od.entries():
        if var.value_base is None:
            continue
        where = var.where
        if var.index == _STAMP_INDEX and var.subindex in (1, 2):
            value = var.value
            if isinstance(value, int):
                stamp[var.subindex] = value
            result.skipped.append((where, "configuration stamp: compared first, written last"))
            continue
        if var.index in _COMMANDS:
            result.skipped.append((where, "a command (save / restore), not a parameter"))
            continue
        if not var.writable:
            result.skipped.append((where, f"{var.access_type}: the node refuses writes"))
            continue
        data = _value_bytes(var, od)
        if changed_only and data == var.default_bytes(od.node_id):
            result.skipped.append((where, "equal to the default (--changed-only)"))
            continue
        pdo = _pdo_of(var.index)
        if pdo is not None:
            comm, mapping = pdos.setdefault((pdo[0], pdo[1]), ({}, {}))
            (mapping if pdo[2] else comm)[var.subindex] = data
        elif var.index < _PDO_RANGES[0][0]:
            before.append(ConciseEntry(var.index, var.subindex, data))
        else:
            after.append(ConciseEntry(var.index, var.subindex, data))
    result.entries = before
    for (direction, number), (comm, mapping) in sorted(pdos.items()):
        result.entries += _pdo_sequence(direction, number, comm, mapping)
    result.entries += after
    if 1 in stamp and 2 in stamp:
        result.stamp = (stamp[1], stamp[2])
    return result
