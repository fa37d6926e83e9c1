"""`ObjectDictionary.validate()`: what is wrong with a dictionary.

Errors are things a node cannot run with (a type that cannot hold the
default, sub 0 missing, 0x1000 of the wrong shape for the line, duplicated
COB-IDs); warnings are things CiA asks for that a node can live without
(mandatory objects missing, names repeated) or suspicious settings.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, Iterable, Iterator, List, Optional, Protocol, Tuple, Union

from .datatypes import DataType, Value, zero_value
from .errors import OdValueError
from .objects import ODArray, ODObject, ODRecord, _Container
from .variable import ODVariable, format_index


class ObjectDictionary(Protocol):
    """What validation reads of an ObjectDictionary (model.py, whose validate()
    calls this module: a Protocol keeps the import one way)."""

    indices: Dict[int, ODObject]

    @property
    def mode(self) -> Optional[str]:
        ...

    @property
    def node_id(self) -> Optional[int]:
        ...

    def get_variable(self, index: int, subindex: int = 0) -> Optional[ODVariable]:
        ...

    def entries(self) -> Iterator[ODVariable]:
        ...

__all__ = ["Problem", "validate"]

ERROR = "error"
WARNING = "warning"

U8, U16, U32 = DataType.UNSIGNED8, DataType.UNSIGNED16, DataType.UNSIGNED32

# Sub 0 of these counts the valid entries (it may be below the largest sub-index).
_COUNT_RANGES = ((0x1003, 0x1003), (0x1032, 0x1032), (0x1600, 0x17FF), (0x1A00, 0x1BFF))

# Types CiA 301 fixes for communication objects the stack itself uses:
# index -> (object kind, type of the VAR or of subs >= 1)
_KNOWN_TYPES: Dict[int, Tuple[str, DataType]] = {
    0x1001: ("var", U8), 0x1005: ("var", U32), 0x1014: ("var", U32),
    0x1017: ("var", U16), 0x1019: ("var", U8),
    0x1010: ("array", U32), 0x1011: ("array", U32), 0x1016: ("array", U32),
    0x1030: ("array", U32), 0x1018: ("record", U32),
}
_MANDATORY = ((0x1000, "device type"), (0x1001, "error register"), (0x1018, "identity"))
_COB_ID_ENTRIES = [(0x1014, 0)] + [(i, 1) for i in range(0x1400, 0x1600)] + \
    [(i, 1) for i in range(0x1800, 0x1A00)]


@dataclass(frozen=True)
class Problem:
    """One finding: severity 'error' or 'warning', where (entry or object,
    '' for the whole dictionary) and what."""

    severity: str
    where: str
    message: str

    @property
    def is_error(self) -> bool:
        return self.severity == ERROR

    def __str__(self) -> str:
        return f"{self.severity}: {self.where}: {self.message}" if self.where \
            else f"{self.severity}: {self.message}"


class _Report:
    def __init__(self) -> None:
        self.problems: List[Problem] = []

    def error(self, where: str, message: str) -> None:
        self.problems.append(Problem(ERROR, where, message))

    def warning(self, where: str, message: str) -> None:
        self.problems.append(Problem(WARNING, where, message))


def _label(obj: Union[ODVariable, _Container]) -> str:
    if isinstance(obj, ODVariable):
        return f"{obj.where} {obj.qualname}"
    return f"{obj.where} {obj.name}"


def validate(od: ObjectDictionary) -> List[Problem]:
    """Every problem found in `od`, errors and warnings, in index order."""
    report = _Report()
    for key in sorted(od.indices):
        obj = od.indices[key]
        if obj.index != key:
            report.error(_label(obj), f"registered at {format_index(key)} but its index is "
                                      f"{format_index(obj.index)}")
        if isinstance(obj, ODVariable):
            if obj.subindex != 0:
                report.error(_label(obj), f"a VAR object must have sub-index 0, "
                                          f"not {obj.subindex}")
        else:
            _check_container(obj, report)
        _check_known_type(obj, report)
    for var in od.entries():
        _check_entry(od, var, report)
    _check_mandatory(od, report)
    _check_mode(od, report)
    _check_names(od, report)
    _check_links(od, report)
    _check_cob_ids(od, report)
    # index order ("0x1018" / "0x1018:02" prefixes sort as text), whole-dictionary ones first
    return sorted(report.problems, key=lambda problem: problem.where[:9])


# ------------------------------------------------------------------ objects
def _is_count_object(obj: _Container) -> bool:
    sub0 = obj.subindices.get(0)
    if sub0 is not None and sub0.writable:
        return True
    return any(low <= obj.index <= high for low, high in _COUNT_RANGES)


def _check_container(obj: _Container, report: _Report) -> None:
    label = _label(obj)
    for sub, var in obj.subindices.items():
        if var.subindex != sub or var.index != obj.index:
            report.error(_label(var), f"registered at {format_index(obj.index, sub)} but "
                                      f"says {var.where}")
    sub0 = obj.subindices.get(0)
    if sub0 is None:
        report.error(label, "sub-index 0 (highest sub-index supported) is missing")
        return
    if sub0.data_type != U8:
        report.error(_label(sub0), f"sub-index 0 must be UNSIGNED8, is {sub0.data_type.name}")
        return
    largest = max(obj.subindices)
    highest = obj.highest_subindex
    if highest is None:
        report.warning(_label(sub0), "sub-index 0 has no default")
    elif _is_count_object(obj):
        if highest > largest:
            report.error(_label(sub0), f"counts {highest} entries but the largest "
                                       f"sub-index defined is {largest}")
    elif highest < largest:
        report.error(_label(sub0), f"highest sub-index supported is {highest}, but "
                                   f"sub-index {largest} (0x{largest:02X}) exists")
    elif highest > largest:
        report.warning(_label(sub0), f"highest sub-index supported is {highest}, but "
                                     f"the largest sub-index defined is {largest}")
    if len(obj.subindices) == 1:
        report.warning(label, "has no entries besides sub-index 0")
    if isinstance(obj, ODArray):
        element = obj.data_type
        for sub in sorted(obj.subindices):
            var = obj.subindices[sub]
            if sub >= 1 and element is not None and var.data_type != element:
                report.error(_label(var), f"ARRAY elements share one type: this one is "
                                          f"{var.data_type.name}, sub-index 1 "
                                          f"is {element.name}")


def _check_known_type(obj: ODObject, report: _Report) -> None:
    index = obj.index
    if index not in _KNOWN_TYPES:
        return
    kind, dtype = _KNOWN_TYPES[index]
    if kind == "var":
        if not isinstance(obj, ODVariable):
            report.error(_label(obj), f"must be a VAR of {dtype.name}")
        elif obj.data_type != dtype:
            report.error(_label(obj), f"must be {dtype.name}, is {obj.data_type.name}")
        return
    if isinstance(obj, ODVariable):
        report.error(_label(obj), f"must be an {'ARRAY' if kind == 'array' else 'RECORD'} "
                                  f"with {dtype.name} entries")
        return
    for sub, var in obj.subindices.items():
        if sub >= 1 and (index != 0x1018 or sub <= 4) and var.data_type != dtype:
            report.error(_label(var), f"must be {dtype.name}, is {var.data_type.name}")


# ------------------------------------------------------------------ entries
def _candidates(od: ObjectDictionary, var: ODVariable, base: Optional[Value],
                relative: bool) -> List[Value]:
    """The values to check a (possibly node-id relative) default/value with."""
    if base is None:
        return []
    if not relative:
        return [base]
    if isinstance(base, bool) or not isinstance(base, (int, float)):
        return []   # relative, but not a number: reported by _check_entry
    if od.node_id is not None:
        return [base + od.node_id]
    return [base + 1, base + 127]


def _check_entry(od: ObjectDictionary, var: ODVariable, report: _Report) -> None:
    label = _label(var)
    if not var.name.strip():
        report.error(label, "has no name")
    low, high = var.low_limit, var.high_limit
    if low is not None and high is not None and low > high:
        report.error(label, f"LowLimit {low!r} is above HighLimit {high!r}")
    for what, base, relative in (
            ("default", var.default_base, var.relative_to_node_id),
            ("value", var.value_base, var.value_relative_to_node_id)):
        if relative and not var.data_type.is_numeric:
            report.error(label, f"{what} is node-id relative, but {var.data_type.name} "
                                f"is not a numeric type")
        for candidate in _candidates(od, var, base, relative):
            try:
                var.check_value(candidate)
            except OdValueError as exc:
                suffix = " (with node-id)" if relative else ""
                report.error(label, f"{what}{suffix}: {exc.problem}")
                break
    if var.default_base is None and var.data_type.is_numeric:
        try:
            var.check_value(zero_value(var.data_type))
        except OdValueError:
            report.warning(label, "has no default and 0 is outside its limits")
    if var.max_length is not None and var.size is not None:
        report.warning(label, f"max_length {var.max_length} is ignored for "
                              f"{var.data_type.name} (fixed size {var.size})")
    mappable = var.pdo_mappable
    if mappable is not None:
        if var.size is None:
            report.warning(label, f"PDO mapping of {var.data_type.name} (variable length)")
        if mappable in ("tpdo", "both") and not var.readable:
            report.warning(label, f"mappable into TPDOs but access is {var.access_type}")
        if mappable in ("rpdo", "both") and not var.writable:
            report.warning(label, f"mappable into RPDOs but access is {var.access_type}")
    if var.store and not var.writable:
        report.warning(label, f"store is set but access is {var.access_type}")
    if var.line_mode is not None and od.mode is not None and var.line_mode != od.mode:
        report.warning(label, f"exists on {var.line_mode} lines only, "
                              f"but this dictionary is for a {od.mode} line")


# ------------------------------------------------------------------ dictionary
def _check_mandatory(od: ObjectDictionary, report: _Report) -> None:
    for index, what in _MANDATORY:
        if index not in od.indices:
            report.warning(format_index(index), f"mandatory object ({what}) is missing")
    identity = od.indices.get(0x1018)
    if isinstance(identity, (ODRecord, ODArray)) and 1 not in identity.subindices:
        report.warning(_label(identity), "vendor-ID (sub-index 1) is missing")


def _check_mode(od: ObjectDictionary, report: _Report) -> None:
    device_type = od.indices.get(0x1000)
    if od.mode == "fd" and device_type is not None and not isinstance(device_type, ODArray):
        report.error(_label(device_type), "must be an ARRAY of UNSIGNED32 on CANopen FD "
                                          "(CiA 1301: one device type per logical device)")
    if od.mode == "classic" and device_type is not None and not isinstance(device_type,
                                                                            ODVariable):
        report.error(_label(device_type), "must be a VAR of UNSIGNED32 on classic CANopen")
    if isinstance(device_type, ODVariable) and device_type.data_type != U32:
        report.error(_label(device_type), f"must be UNSIGNED32, is "
                                          f"{device_type.data_type.name}")
    if isinstance(device_type, ODArray):
        for sub, var in device_type.subindices.items():
            if sub >= 1 and var.data_type != U32:
                report.error(_label(var), f"must be UNSIGNED32, is {var.data_type.name}")
    if od.mode == "classic" and 0x1030 in od.indices:
        report.warning(_label(od.indices[0x1030]), "version information exists on "
                                                   "CANopen FD only")


def _duplicates(items: Iterable[Tuple[str, str]]) -> Dict[str, List[str]]:
    seen: Dict[str, List[str]] = {}
    for name, where in items:
        seen.setdefault(name, []).append(where)
    return {name: places for name, places in seen.items() if len(places) > 1}


def _check_names(od: ObjectDictionary, report: _Report) -> None:
    clashes = _duplicates((obj.name, obj.where) for _, obj in sorted(od.indices.items()))
    for name, places in clashes.items():
        report.warning(places[0], f"name {name!r} is also used by {', '.join(places[1:])} "
                                  f"(lookups by name need a unique one)")
    for _, obj in sorted(od.indices.items()):
        if isinstance(obj, (ODRecord, ODArray)):
            subs = _duplicates((var.name, var.where)
                               for _, var in sorted(obj.subindices.items()))
            for name, places in subs.items():
                report.warning(places[0], f"sub-entry name {name!r} repeats at "
                                          f"{', '.join(places[1:])}")


def _check_links(od: ObjectDictionary, report: _Report) -> None:
    for index in sorted(od.indices):
        obj = od.indices[index]
        for target in obj.object_links:
            if target == index:
                report.error(_label(obj), "ObjectLinks links the object to itself")
            elif target not in od.indices:
                report.error(_label(obj), f"ObjectLinks names {format_index(target)}, "
                                          f"which does not exist")
    cycle = find_link_cycle({i: o.object_links for i, o in od.indices.items()})
    if cycle:
        report.error(format_index(cycle[0]), "ObjectLinks form a cycle: "
                     + " -> ".join(format_index(i) for i in cycle))


def find_link_cycle(links: Dict[int, List[int]]) -> Optional[List[int]]:
    """A cycle (first index repeated at the end) in the link graph, or None.
    Iterative, so hostile files cannot exhaust the stack."""
    state: Dict[int, int] = {}  # 1 = on the current path, 2 = done
    for start in sorted(links):
        if state.get(start):
            continue
        path: List[int] = [start]
        iters = [iter(links.get(start, []))]
        state[start] = 1
        while iters:
            nxt = next(iters[-1], None)
            if nxt is None:
                state[path.pop()] = 2
                iters.pop()
                continue
            if nxt == path[-1] or nxt not in links:
                continue  # self links and dangling links are reported on their own
            if state.get(nxt) == 1:
                return path[path.index(nxt):] + [nxt]
            if not state.get(nxt):
                state[nxt] = 1
                path.append(nxt)
                iters.append(iter(links.get(nxt, [])))
    return None


def _check_cob_ids(od: ObjectDictionary, report: _Report) -> None:
    users: Dict[Tuple[bool, int], List[str]] = {}
    for index, sub in _COB_ID_ENTRIES:
        var = od.get_variable(index, sub) if index in od.indices else None
        if var is None or not isinstance(var.default_base, int) or var.data_type != U32:
            continue
        base = var.default_base
        if base & 0x80000000:
            continue  # not valid: the PDO/EMCY is off
        relative = var.relative_to_node_id
        if relative and od.node_id is not None:
            base, relative = base + od.node_id, False
        users.setdefault((relative, base & 0x1FFFFFFF), []).append(_label(var))
    for (relative, cob_id), places in sorted(users.items()):
        if len(places) > 1:
            shown = f"$NODEID+0x{cob_id:X}" if relative else f"0x{cob_id:X}"
            report.error(places[0], f"COB-ID {shown} is also used by {', '.join(places[1:])}")
