"""The object dictionary: `ObjectDictionary` (its structured objects `ODRecord`
and `ODArray` are in objects.py, entries `ODVariable` in variable.py).

This is the *description* of a device's objects (what an EDS/XDD says), not
its runtime values: those live in the node (the C core), which is fed the flat
list `ObjectDictionary.entries()`. Lookups follow python-canopen
(`od[0x1018][1]`, `od["Producer heartbeat time"]`, `add_object`,
`add_member`, `get_variable`).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from typing import Callable, Dict, Iterator, List, Optional, Set, Tuple, Union

from .errors import OdStateError, OdValueError
from .objects import ODArray, ODKey, ODObject, ODRecord, _by_name
from .validate import Problem, validate
from .variable import (ACCESS_TYPES, LINE_MODES, PDO_DIRECTIONS, ODVariable, ObjectType,
                       _check_int, format_index)

__all__ = [
    "ObjectType", "ODVariable", "ODRecord", "ODArray", "ObjectDictionary",
    "ACCESS_TYPES", "LINE_MODES", "PDO_DIRECTIONS", "format_index",
]

_KEY_RE = re.compile(r"^(?:0x)?([0-9a-f]{1,4})(?:(?::|sub)(?:0x)?([0-9a-f]{1,2}))?$",
                     re.IGNORECASE)


class ObjectDictionary(Mapping[ODKey, ODObject]):
    """The objects of one device, by index (iteration in index order).

    Lookups: ``od[0x1017]``, ``od["Producer heartbeat time"]`` (names, exact
    or case-insensitively unique), ``od["0x1018:1"]`` / ``od["1018sub1"]``
    (hex index and sub-index, as `od show` prints them), ``od[(0x1018, 1)]``,
    ``od["Identity object.Vendor-ID"]``, ``od[0x1018][1]``.
    """

    def __init__(self, mode: Optional[str] = None, node_id: Optional[int] = None) -> None:
        self.indices: Dict[int, ODObject] = {}
        if mode is not None and mode not in LINE_MODES:
            raise OdValueError(f"mode must be 'fd', 'classic' or None, got {mode!r}")
        #: 'fd' or 'classic': the kind of line this dictionary describes a node
        #: for (None: unknown). Checked by validate().
        self.mode = mode
        self._node_id: Optional[int] = None
        self.node_id = node_id
        #: Bit rate in bit/s (DCF Baudrate, XDC actualBaudRate), None if unknown.
        self.bitrate: Optional[int] = None
        #: [DeviceInfo] keys as in an EDS (VendorName, VendorNumber, ProductName...).
        self.device_info: Dict[str, str] = {}
        #: [FileInfo] keys (FileName, FileVersion, CreatedBy...).
        self.file_info: Dict[str, str] = {}
        #: DCF [DeviceComissioning] / XDC deviceCommissioning keys.
        self.device_commissioning: Dict[str, str] = {}
        #: [Comments] text.
        self.comments = ""
        #: Data type indices usable as dummy mapping entries ([DummyUsage]).
        self.dummy_usage: Set[int] = set()
        #: Problems the importer noticed but could live with (Problem objects).
        self.load_warnings: List[Problem] = []
        #: The file this dictionary was read from ('' when built in code).
        self.source = ""
        #: 'EDS', 'DCF', 'XDD' or 'XDC' for imported dictionaries, else ''.
        self.source_format = ""
        # Who serves this dictionary from C ('local node 3 on line ...'), set
        # when that node boots: from then on the objects are fixed.
        self._served_by: Optional[str] = None
        self._add_live: Optional[Callable[[ODObject], None]] = None

    @property
    def node_id(self) -> Optional[int]:
        """The node-id `$NODEID` expressions resolve with (None: unknown)."""
        return self._node_id

    @node_id.setter
    def node_id(self, value: Optional[int]) -> None:
        if value is not None:
            _check_int(value, 1, 127, "node_id")
        self._node_id = value

    # ------------------------------------------------------------ served
    def freeze(self, by: Optional[str], add: Optional[Callable[[ODObject], None]] = None
               ) -> None:
        """A local node built its C dictionary from this one (`by` names it):
        objects can no longer be replaced or removed; a new object is added
        only through `add` (the node's C dictionary first, raising OdStateError
        when it refuses). None: that node stopped (its network closed), the
        dictionary is free again."""
        self._served_by = by
        self._add_live = add if by is not None else None

    def __getstate__(self) -> Dict[str, object]:
        """A copy (copy.deepcopy, pickle) is served by no node: free to change."""
        state = dict(self.__dict__)
        state["_served_by"] = state["_add_live"] = None
        return state

    @property
    def frozen_by(self) -> Optional[str]:
        """The running node that serves this dictionary (None: free to change)."""
        return self._served_by

    def check_changeable(self, where: str, change: str) -> None:
        """Raise OdStateError when a running node serves this dictionary:
        the change would not reach its C dictionary."""
        if self._served_by is not None:
            raise OdStateError(
                f"{where}: cannot {change}: {self._served_by} is running with this "
                f"object dictionary and serves only the objects it had when it booted; "
                f"make the change before the node boots (create_local_node(..., boot=False), "
                f"then node.boot())")

    def check_member_change(self, obj: Union[ODRecord, ODArray], variable: ODVariable) -> None:
        """Before `variable` joins `obj` (add_member): while a node serves this
        dictionary a new sub-entry goes to it first; a replaced one raises."""
        if self._served_by is None:
            return
        if self._add_live is None or variable.subindex in obj.subindices:
            self.check_changeable(format_index(obj.index, variable.subindex),
                                  "replace the sub-entry" if variable.subindex in obj.subindices
                                  else "add the sub-entry")
            return
        parent = variable.parent
        variable.parent = obj     # so it is defined as a sub-entry of obj
        try:
            self._add_live(variable)
        finally:
            variable.parent = parent

    # ------------------------------------------------------------ mapping
    def add_object(self, obj: ODObject) -> None:
        """Add (or replace) the object at obj.index. Refused (OdStateError)
        once a local node serving this dictionary booted."""
        if not isinstance(obj, (ODVariable, ODRecord, ODArray)):
            raise OdValueError(f"objects must be ODVariable, ODRecord or ODArray, "
                               f"got {type(obj).__name__}")
        if self._add_live is not None and obj.index not in self.indices:
            self._add_live(obj)   # the running node serves it first, or this raises
        else:
            self.check_changeable(format_index(obj.index),
                                  "replace the object" if obj.index in self.indices
                                  else "add the object")
        obj.parent = self
        self.indices[obj.index] = obj

    def __setitem__(self, key: Union[int, str], obj: ODObject) -> None:
        if key != obj.index and key != obj.name:
            raise OdValueError(f"key {key!r} is neither the index nor the name of {obj!r}")
        self.add_object(obj)

    def __delitem__(self, key: Union[int, str]) -> None:
        obj = self[key]
        if isinstance(obj, ODVariable) and obj.parent is not self:
            raise KeyError(f"{key!r} is a sub-entry; delete from its object")
        self.check_changeable(format_index(obj.index), "remove the object")
        del self.indices[obj.index]
        obj.parent = None

    def __getitem__(self, key: Union[int, str, Tuple[int, int]]) -> ODObject:
        if isinstance(key, int) and not isinstance(key, bool):
            if key in self.indices:
                return self.indices[key]
            raise KeyError(f"{format_index(key) if 0 <= key <= 0xFFFF else key} "
                           f"is not in the object dictionary")
        if isinstance(key, tuple) and len(key) == 2:
            var = self.get_variable(*key)
            if var is None:
                raise KeyError(f"{key!r} is not in the object dictionary")
            return var
        if isinstance(key, str):
            found = self._lookup_text(key)
            if found is not None:
                return found
        raise KeyError(f"{key!r} is not in the object dictionary")

    def _lookup_text(self, text: str) -> Optional[ODObject]:
        found = _by_name(list(self.indices.values()), text, top_level=True)
        if found is not None:
            return found
        match = _KEY_RE.match(text.strip())
        if match:
            index = int(match.group(1), 16)
            if match.group(2) is None:
                return self.indices.get(index)
            return self.get_variable(index, int(match.group(2), 16))
        # "Object name.Sub name", split at each '.' in turn (names may hold dots)
        for pos in [i for i, char in enumerate(text) if char == "."]:
            obj = _by_name(list(self.indices.values()), text[:pos], top_level=True)
            if isinstance(obj, (ODRecord, ODArray)) and text[pos + 1:] in obj:
                return obj[text[pos + 1:]]
        return None

    def __contains__(self, key: object) -> bool:
        if not isinstance(key, (int, str, tuple)):
            return False   # what __getitem__ would refuse with KeyError
        try:
            self[key]
        except KeyError:
            return False
        return True

    def __iter__(self) -> Iterator[int]:
        return iter(sorted(self.indices))

    def __len__(self) -> int:
        return len(self.indices)

    def __repr__(self) -> str:
        return (f"<ObjectDictionary {len(self)} objects, mode={self.mode!r}, "
                f"node_id={self.node_id!r}>")

    @property
    def names(self) -> Dict[str, ODObject]:
        """Objects by name (the first in index order when names repeat)."""
        result: Dict[str, ODObject] = {}
        for index in sorted(self.indices):
            result.setdefault(self.indices[index].name, self.indices[index])
        return result

    def get_variable(self, index: Union[int, str], subindex: int = 0) -> Optional[ODVariable]:
        """The entry at (index, subindex), or None (python-canopen's name)."""
        obj = self.get(index)
        if isinstance(obj, ODVariable):
            return obj if subindex == 0 else None
        if isinstance(obj, (ODRecord, ODArray)):
            return obj.subindices.get(subindex)
        return None

    def entries(self) -> Iterator[ODVariable]:
        """Every entry (VARs and every sub-entry) in (index, sub-index) order:
        the flat list the C object dictionary is built from."""
        for index in sorted(self.indices):
            obj = self.indices[index]
            if isinstance(obj, ODVariable):
                yield obj
            else:
                for sub in sorted(obj.subindices):
                    yield obj.subindices[sub]

    # ------------------------------------------------------------ checks
    def validate(self) -> List[Problem]:
        """Problems of this dictionary (list of `Problem`, errors and warnings);
        see canopenfd.od.validate for the rules."""
        return validate(self)

    def diff(self, other: "ObjectDictionary") -> List[str]:
        """What differs between two dictionaries' objects and entries (and mode);
        [] when they describe the same device. File metadata is not compared."""
        return _diff(self, other)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, ObjectDictionary):
            return NotImplemented
        return not self.diff(other)

    # mutable and compared by content: not hashable (the ignore: typeshed types
    # object.__hash__ as a method, None is how Python spells 'unhashable')
    __hash__ = None  # type: ignore[assignment]


# ------------------------------------------------------------------ comparison
_VAR_FIELDS = ("name", "data_type", "access_type", "default_base", "relative_to_node_id",
               "value_base", "value_relative_to_node_id", "low_limit", "high_limit",
               "pdo_mappable", "store", "line_mode", "max_length", "description", "unit",
               "factor", "denotation", "obj_flags", "object_type")


def _same(a: object, b: object) -> bool:
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return type(a) is type(b) and a == b


def _diff(left: ObjectDictionary, right: ObjectDictionary) -> List[str]:
    out: List[str] = []
    if left.mode != right.mode:
        out.append(f"mode: {left.mode!r} != {right.mode!r}")
    for index in sorted(set(left.indices) | set(right.indices)):
        a, b = left.indices.get(index), right.indices.get(index)
        where = format_index(index)
        if a is None or b is None:
            out.append(f"{where}: only in {'right' if a is None else 'left'}")
            continue
        if type(a) is not type(b):
            out.append(f"{where}: {type(a).__name__} != {type(b).__name__}")
            continue
        if a.name != b.name:
            out.append(f"{where}: name {a.name!r} != {b.name!r}")
        if a.object_links != b.object_links:
            out.append(f"{where}: object links {a.object_links} != {b.object_links}")
        pairs: List[Tuple[ODVariable, ODVariable]] = []
        if isinstance(a, ODVariable) and isinstance(b, ODVariable):
            pairs.append((a, b))
        elif not isinstance(a, ODVariable) and not isinstance(b, ODVariable):
            for sub in sorted(set(a.subindices) | set(b.subindices)):
                left_var, right_var = a.subindices.get(sub), b.subindices.get(sub)
                if left_var is None or right_var is None:
                    out.append(f"{format_index(index, sub)}: only in "
                               f"{'right' if left_var is None else 'left'}")
                else:
                    pairs.append((left_var, right_var))
        for va, vb in pairs:
            for field in _VAR_FIELDS:
                x, y = getattr(va, field), getattr(vb, field)
                if not _same(x, y):
                    out.append(f"{va.where} {field}: {x!r} != {y!r}")
    return out
