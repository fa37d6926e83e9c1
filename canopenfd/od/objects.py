"""The structured objects of an object dictionary: `ODRecord` and `ODArray`
(their entries are `ODVariable`, in variable.py), without the dictionary
itself (model.py), so that validation can know them without importing the
dictionary that calls it."""

from __future__ import annotations

import re
from collections.abc import Mapping
from typing import Dict, Iterator, List, Optional, Protocol, Sequence, Tuple, TypeVar, Union

from .datatypes import DataType
from .errors import OdValueError
from .variable import ODVariable, ObjectType, _check_int, format_index

__all__ = ["ODRecord", "ODArray", "ODObject"]

ODObject = Union[ODVariable, "ODRecord", "ODArray"]
#: What an ObjectDictionary is indexed with: index, name or "0x1018:1" text,
#: (index, sub-index).
ODKey = Union[int, str, Tuple[int, int]]


class _Container(Mapping[Union[int, str], ODVariable]):
    """What ODRecord and ODArray share: sub-entries by sub-index and by name."""

    object_type = ObjectType.RECORD

    def __init__(self, name: str, index: int) -> None:
        #: The ObjectDictionary the object was added to.
        self.parent: Optional["Mapping[ODKey, ODObject]"] = None
        self.index = _check_int(index, 1, 0xFFFF, "index")
        self.name = str(name)
        self.description = ""
        self.subindices: Dict[int, ODVariable] = {}
        #: Object links (CiA 306 [xxxxObjectLinks]): related object indices.
        self.object_links: List[int] = []

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name!r} at {self.where}>"

    @property
    def where(self) -> str:
        return format_index(self.index)

    @property
    def names(self) -> Dict[str, ODVariable]:
        """Sub-entries by name (the first one when names repeat)."""
        result: Dict[str, ODVariable] = {}
        for sub in sorted(self.subindices):
            result.setdefault(self.subindices[sub].name, self.subindices[sub])
        return result

    def add_member(self, variable: ODVariable) -> None:
        """Add (or replace) the entry at variable.subindex."""
        if not isinstance(variable, ODVariable):
            raise OdValueError(f"members must be ODVariable, got {type(variable).__name__}",
                               self.where)
        if variable.index != self.index:
            raise OdValueError(f"member {variable.name!r} has index "
                               f"{format_index(variable.index)}", f"{self.where} {self.name}")
        check = getattr(self.parent, "check_member_change", None)
        if check is not None:    # a running node serves it first, or this raises
            check(self, variable)
        variable.parent = self
        self.subindices[variable.subindex] = variable

    def __getitem__(self, key: Union[int, str]) -> ODVariable:
        if isinstance(key, int) and not isinstance(key, bool):
            if key in self.subindices:
                return self.subindices[key]
        elif isinstance(key, str):
            found = _by_name(list(self.subindices.values()), key)
            if found is not None:
                return found
            sub = _parse_sub(key)
            if sub is not None and sub in self.subindices:
                return self.subindices[sub]
        raise KeyError(f"{self.where} {self.name} has no sub-entry {key!r}")

    def __contains__(self, key: object) -> bool:
        if not isinstance(key, (int, str)):
            return False   # what __getitem__ would refuse with KeyError
        try:
            self[key]
        except KeyError:
            return False
        return True

    def __iter__(self) -> Iterator[int]:
        return iter(sorted(self.subindices))

    def __len__(self) -> int:
        return len(self.subindices)

    @property
    def highest_subindex(self) -> Optional[int]:
        """The default of sub 0 ("highest sub-index supported"), if an int."""
        sub0 = self.subindices.get(0)
        value = sub0.default if sub0 is not None else None
        return value if isinstance(value, int) and not isinstance(value, bool) else None

    @property
    def line_mode(self) -> Optional[str]:
        """The line mode all sub-entries share (None when mixed or unset)."""
        modes = {var.line_mode for var in self.subindices.values()}
        return modes.pop() if len(modes) == 1 else None

    @line_mode.setter
    def line_mode(self, value: Optional[str]) -> None:
        for var in self.subindices.values():
            var.line_mode = value


class ODRecord(_Container):
    """A RECORD object (ObjectType 9): sub-entries of different types."""

    object_type = ObjectType.RECORD


class ODArray(_Container):
    """An ARRAY object (ObjectType 8): sub 0 is the count, subs 1..n share one type."""

    object_type = ObjectType.ARRAY

    @property
    def data_type(self) -> Optional[DataType]:
        """The type of the elements (of the lowest sub-index >= 1)."""
        for sub in sorted(self.subindices):
            if sub >= 1:
                return self.subindices[sub].data_type
        return None


class _Named(Protocol):
    name: str
    index: int

    @property
    def where(self) -> str:
        ...


N = TypeVar("N", bound=_Named)


def _by_name(items: Sequence[N], name: str, top_level: bool = False) -> Optional[N]:
    """The item named `name`: exact match first, then a unique case-insensitive one."""
    exact = [item for item in items if item.name == name]
    if len(exact) == 1:
        return exact[0]
    if len(exact) > 1:
        places = [format_index(item.index) if top_level else item.where for item in exact]
        raise KeyError(f"name {name!r} is ambiguous: {', '.join(places)}")
    folded = [item for item in items if item.name.casefold() == name.casefold()]
    if len(folded) == 1:
        return folded[0]
    return None


def _parse_sub(text: str) -> Optional[int]:
    match = re.match(r"^(?:0x)?([0-9a-f]{1,2})$", text.strip(), re.IGNORECASE)
    return int(match.group(1), 16) if match else None
