"""One entry of the object dictionary: `ODVariable` (a VAR object, or one
sub-index of an ARRAY/RECORD), with the object codes and the access types.

Names follow python-canopen (`access_type`, `default`, `min`/`max`,
`relative`, `pdo_mappable`, `writable`) so its users feel at home; what
python-canopen lacks (line mode, store flag, PDO direction, string limits) is
added with new names. Runtime values are not here: they live in the node.

Choices where CiA 301/306 are silent:

- `store` (saved by 0x1010): True for every writable entry, except DOMAIN
  entries (application data, possibly megabytes, backed by callbacks) and the
  store/restore commands 0x1010/0x1011 themselves. Set it explicitly to change.
- `pdo_mappable` is derived from the file's PDOMapping flag and the access
  type: ro/const/rwr → 'tpdo', wo/rww → 'rpdo', rw → 'both'; an explicit
  direction (XDD ``TPDO``/``RPDO``) wins.
- A node-id relative default (``$NODEID+0x180``) keeps its offset;
  `default` adds the dictionary's `node_id` when it is known. Only numeric
  types can be relative (set_default refuses the others, naming the entry).
"""

from __future__ import annotations

import enum
from typing import Any, List, Optional, Union

from .datatypes import DataType, Value, check, decode, encode, zero_value
from .errors import OdValueError

__all__ = ["ObjectType", "ODVariable", "ACCESS_TYPES", "LINE_MODES", "PDO_DIRECTIONS",
           "format_index"]

ACCESS_TYPES = ("ro", "wo", "rw", "rwr", "rww", "const")
LINE_MODES = ("fd", "classic")
PDO_DIRECTIONS = ("tpdo", "rpdo", "both")

_TPDO_ACCESS = ("ro", "const", "rwr")
_RPDO_ACCESS = ("wo", "rww")
_NOT_STORED = (0x1010, 0x1011)  # writes there are commands, not parameters


class ObjectType(enum.IntEnum):
    """CiA 301 object codes (EDS ObjectType, XDD objectType)."""

    NULL = 0
    DOMAIN = 2
    DEFTYPE = 5
    DEFSTRUCT = 6
    VAR = 7
    ARRAY = 8
    RECORD = 9


def format_index(index: int, subindex: Optional[int] = None) -> str:
    """'0x1018' or '0x1018:02' (sub-index in hex, as everywhere in this package)."""
    return f"0x{index:04X}" if subindex is None else f"0x{index:04X}:{subindex:02X}"


def _check_int(value: object, low: int, high: int, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise OdValueError(f"{what} must be an int {low}..{high}, got {value!r}")
    return value


class ODVariable:
    """One entry: a VAR object, or one sub-index of an ARRAY/RECORD.

    `default` is the value after a reset (None: the file gives none, the entry
    starts at the type's zero); `value` is a DCF ParameterValue / XDC
    actualValue (a configured value, None when absent).
    """

    def __init__(self, name: str, index: int, subindex: int = 0,
                 data_type: Union[DataType, int, str] = DataType.UNSIGNED32,
                 access_type: str = "rw", default: object = None, *,
                 relative_to_node_id: bool = False,
                 low_limit: object = None, high_limit: object = None,
                 pdo_mapping: bool = False, pdo_direction: Optional[str] = None,
                 store: Optional[bool] = None, line_mode: Optional[str] = None,
                 max_length: Optional[int] = None, description: str = "",
                 unit: str = "", factor: float = 1.0) -> None:
        #: The ObjectDictionary, ODRecord or ODArray owning this entry (Any: those
        #: classes are built on this module; it tells them apart by their attributes).
        self.parent: Any = None
        self.index = _check_int(index, 1, 0xFFFF, "index")
        self.subindex = _check_int(subindex, 0, 0xFF, "sub-index")
        self.name = str(name)
        self._data_type = DataType.parse(data_type)
        self.access_type = access_type
        #: The default as written in the file (``$NODEID+0x180``, ``017``...), for
        #: display and export; cleared when `default` is assigned.
        self.default_expr: Optional[str] = None
        self._default: Optional[Value] = None
        if default is not None:
            self._default = self._checked(default)
        self.relative_to_node_id = self._checked_relative(relative_to_node_id, "default")
        self.value_expr: Optional[str] = None
        self.value_relative_to_node_id = False
        #: The file line of the configured value (DCF ParameterValue), None when
        #: unknown: messages about the value name it.
        self.value_line: Optional[int] = None
        self._value: Optional[Value] = None
        self._low_limit: Union[int, float, None] = None
        self._high_limit: Union[int, float, None] = None
        self.low_limit = low_limit
        self.high_limit = high_limit
        #: The file's PDOMapping flag: may this entry be mapped into a PDO?
        self.pdo_mapping = bool(pdo_mapping)
        self._pdo_direction: Optional[str] = None
        self.pdo_direction = pdo_direction
        self._store = store
        self.line_mode = line_mode
        self.max_length = max_length
        self.description = description
        self.unit = unit
        self.factor = factor
        #: DCF Denotation (a user-given name), '' when none.
        self.denotation = ""
        #: ObjFlags (CiA 306): bit 0 = do not read at boot, bit 1 = do not write.
        self.obj_flags = 0
        #: Object links (top-level objects only; see ObjectDictionary.object_links).
        self.object_links: List[int] = []

    # ------------------------------------------------------------ identity
    def __repr__(self) -> str:
        return f"<ODVariable {self.qualname!r} at {self.where}>"

    @property
    def where(self) -> str:
        """'0x1018:02' — the place named in messages."""
        return format_index(self.index, self.subindex)

    @property
    def qualname(self) -> str:
        """'Identity object.Vendor-ID' for sub-entries, the name for VARs."""
        if self.in_object:
            return f"{self.parent.name}.{self.name}"
        return self.name

    @property
    def in_object(self) -> bool:
        """True for a sub-entry of an ARRAY/RECORD (its parent has sub-indices)."""
        return hasattr(self.parent, "subindices")

    @property
    def od(self) -> Any:
        """The ObjectDictionary this entry belongs to, or None (Any: see `parent`)."""
        parent = self.parent.parent if self.in_object else self.parent
        return parent if hasattr(parent, "indices") else None

    @property
    def node_id(self) -> Optional[int]:
        od = self.od
        return od.node_id if od is not None else None

    @property
    def object_type(self) -> ObjectType:
        """DOMAIN for a top-level DOMAIN entry (EDS ObjectType 0x2), else VAR."""
        if self.data_type == DataType.DOMAIN and not self.in_object:
            return ObjectType.DOMAIN
        return ObjectType.VAR

    def _error(self, exc: OdValueError) -> OdValueError:
        return exc.at(f"{self.where} {self.qualname}")

    # ------------------------------------------------------------ type, access
    @property
    def data_type(self) -> DataType:
        return self._data_type

    @data_type.setter
    def data_type(self, value: Union[DataType, int, str]) -> None:
        try:
            self._data_type = DataType.parse(value)
        except OdValueError as exc:
            raise self._error(exc) from None

    @property
    def access_type(self) -> str:
        """'ro', 'wo', 'rw', 'rwr' (rw, read by TPDO), 'rww' (rw, written by RPDO), 'const'."""
        return self._access_type

    @access_type.setter
    def access_type(self, value: str) -> None:
        text = str(value).strip().lower()
        if text not in ACCESS_TYPES:
            raise OdValueError(f"access type must be one of {', '.join(ACCESS_TYPES)}, "
                               f"got {value!r}", f"{self.where} {self.name}")
        self._access_type = text

    @property
    def writable(self) -> bool:
        return "w" in self._access_type

    @property
    def readable(self) -> bool:
        return self._access_type != "wo"

    @property
    def size(self) -> Optional[int]:
        """Fixed size in bytes; None for strings and DOMAIN."""
        return self._data_type.size

    @property
    def storage_size(self) -> int:
        """Bytes the node needs for the value: the fixed size, else `max_length`,
        else the length of the default (the CiA 306 convention for strings)."""
        if self.size is not None:
            return self.size
        if self.max_length is not None:
            return self.max_length
        return len(self.default_bytes())

    # ------------------------------------------------------------ default / value
    def _checked(self, value: object) -> Value:
        try:
            return check(self._data_type, value)
        except OdValueError as exc:
            raise self._error(exc) from None

    def _checked_relative(self, relative: bool, what: str) -> bool:
        """`relative` as a bool; True only for a numeric type, the node-id being
        added to it (integers in the node at each reset, a REAL once when served)."""
        if relative and not self._data_type.is_numeric:
            raise self._error(OdValueError(
                f"a node-id relative {what} needs a numeric type, not {self._data_type.name}"))
        return bool(relative)

    def _resolve(self, base: Optional[Value], relative: bool,
                 node_id: Optional[int] = None) -> Optional[Value]:
        if relative and base is not None:
            node = self.node_id if node_id is None else node_id
            if node:
                # `relative_to_node_id` is a plain attribute and the type can be
                # changed after: refuse here too rather than fail on the `+`
                if isinstance(base, bool) or not isinstance(base, (int, float)):
                    raise self._error(OdValueError(
                        f"a node-id relative value needs a numeric type, "
                        f"not {self._data_type.name} ({base!r})"))
                return base + node
        return base

    @property
    def default(self) -> Optional[Value]:
        """The default; node-id relative ones include the dictionary's node_id
        when it is set (else their offset). See `default_for`."""
        return self._resolve(self._default, self.relative_to_node_id)

    @default.setter
    def default(self, value: object) -> None:
        self._default = None if value is None else self._checked(value)
        self.relative_to_node_id = False
        self.default_expr = None

    @property
    def default_base(self) -> Optional[Value]:
        """The default without the node-id (the offset of a relative default)."""
        return self._default

    def set_default(self, value: object, relative_to_node_id: bool = False,
                    expr: Optional[str] = None) -> None:
        """Set the default, optionally as an offset added to the node-id."""
        checked = None if value is None else self._checked(value)
        self.relative_to_node_id = self._checked_relative(relative_to_node_id, "default")
        self._default = checked
        self.default_expr = expr

    def default_for(self, node_id: Optional[int]) -> Optional[Value]:
        """The default on a node with this node-id."""
        return self._resolve(self._default, self.relative_to_node_id, node_id)

    def default_bytes(self, node_id: Optional[int] = None) -> bytes:
        """Wire bytes of the default (the type's zero when there is none); this
        is what the node starts with."""
        value = self.default_for(node_id)
        try:
            return encode(self._data_type, zero_value(self._data_type) if value is None else value)
        except OdValueError as exc:
            raise self._error(exc) from None

    @property
    def value(self) -> Optional[Value]:
        """The configured value (DCF ParameterValue, XDC actualValue), or None."""
        return self._resolve(self._value, self.value_relative_to_node_id)

    @value.setter
    def value(self, value: object) -> None:
        self._value = None if value is None else self._checked(value)
        self.value_relative_to_node_id = False
        self.value_expr = None

    @property
    def value_base(self) -> Optional[Value]:
        return self._value

    def set_value(self, value: object, relative_to_node_id: bool = False,
                  expr: Optional[str] = None) -> None:
        checked = None if value is None else self._checked(value)
        self.value_relative_to_node_id = self._checked_relative(relative_to_node_id, "value")
        self._value = checked
        self.value_expr = expr

    # python-canopen names
    @property
    def relative(self) -> bool:
        """python-canopen's name for `relative_to_node_id`."""
        return self.relative_to_node_id

    @property
    def default_raw(self) -> Optional[str]:
        """python-canopen's name for the default text (`default_expr`)."""
        return self.default_expr

    # ------------------------------------------------------------ limits
    def _checked_limit(self, value: object, which: str) -> Union[int, float, None]:
        if value is None:
            return None
        if not self._data_type.is_numeric:
            raise OdValueError(f"{which} needs a numeric type, not {self._data_type.name}",
                               f"{self.where} {self.qualname}")
        checked = self._checked(value)
        assert isinstance(checked, (int, float))   # what check() gives numeric types
        return checked

    @property
    def low_limit(self) -> Union[int, float, None]:
        """LowLimit (inclusive), None when unlimited."""
        return self._low_limit

    @low_limit.setter
    def low_limit(self, value: object) -> None:
        self._low_limit = self._checked_limit(value, "low_limit")

    @property
    def high_limit(self) -> Union[int, float, None]:
        """HighLimit (inclusive), None when unlimited."""
        return self._high_limit

    @high_limit.setter
    def high_limit(self, value: object) -> None:
        self._high_limit = self._checked_limit(value, "high_limit")

    min = low_limit  # python-canopen names
    max = high_limit

    @property
    def max_length(self) -> Optional[int]:
        """Most bytes a string/octet string/domain may hold (wire bytes, so
        2 per UTF-16 code unit); None when not limited."""
        return self._max_length

    @max_length.setter
    def max_length(self, value: Optional[int]) -> None:
        if value is not None:
            try:
                _check_int(value, 0, 0xFFFFFFFF, "max_length")
            except OdValueError as exc:
                raise self._error(exc) from None
        self._max_length = value

    # ------------------------------------------------------------ flags
    @property
    def pdo_direction(self) -> Optional[str]:
        """An explicit PDO direction ('tpdo', 'rpdo', 'both') overriding the
        one derived from the access type; None = derive."""
        return self._pdo_direction

    @pdo_direction.setter
    def pdo_direction(self, value: Optional[str]) -> None:
        if value is not None and value not in PDO_DIRECTIONS:
            raise OdValueError(f"pdo direction must be one of {', '.join(PDO_DIRECTIONS)} "
                               f"or None, got {value!r}", f"{self.where} {self.qualname}")
        self._pdo_direction = value

    @property
    def pdo_mappable(self) -> Optional[str]:
        """'tpdo', 'rpdo', 'both' or None (not mappable)."""
        if not self.pdo_mapping:
            return None
        if self._pdo_direction is not None:
            return self._pdo_direction
        if self._access_type in _TPDO_ACCESS:
            return "tpdo"
        if self._access_type in _RPDO_ACCESS:
            return "rpdo"
        return "both"

    @pdo_mappable.setter
    def pdo_mappable(self, value: Union[str, bool, None]) -> None:
        if value is None or value is False:
            self.pdo_mapping, self.pdo_direction = False, None
        elif value is True:
            self.pdo_mapping, self.pdo_direction = True, None
        else:
            self.pdo_direction = value
            self.pdo_mapping = True

    @property
    def store_auto(self) -> bool:
        """What `store` is when not set explicitly (see the module doc)."""
        return (self.writable and self._data_type != DataType.DOMAIN
                and self.index not in _NOT_STORED)

    @property
    def store(self) -> bool:
        """Whether 0x1010 "store parameters" saves this entry."""
        return self.store_auto if self._store is None else self._store

    @store.setter
    def store(self, value: Optional[bool]) -> None:
        self._store = None if value is None else bool(value)

    @property
    def store_explicit(self) -> Optional[bool]:
        return self._store

    @property
    def store_group(self) -> str:
        """Which 0x1010 sub-index saves it: 'communication' (0x1000-0x1FFF, sub 2),
        'application' (0x6000-0x9FFF, sub 3), 'manufacturer' (others, sub 4)."""
        if 0x1000 <= self.index <= 0x1FFF:
            return "communication"
        if 0x6000 <= self.index <= 0x9FFF:
            return "application"
        return "manufacturer"

    @property
    def line_mode(self) -> Optional[str]:
        """'fd' or 'classic' for entries that exist on one kind of line only."""
        return self._line_mode

    @line_mode.setter
    def line_mode(self, value: Optional[str]) -> None:
        if value is not None and value not in LINE_MODES:
            raise OdValueError(f"line mode must be 'fd', 'classic' or None, got {value!r}",
                               f"{self.where} {self.qualname}")
        self._line_mode = value

    # ------------------------------------------------------------ values
    def check_value(self, value: object) -> Value:
        """`value` checked against the type, the limits and `max_length`."""
        return self._check_limits(self._checked(value))

    def _check_limits(self, checked: Value) -> Value:
        low, high = self._low_limit, self._high_limit
        # limits are set on numeric types only (see _checked_limit)
        if isinstance(checked, (int, float)):
            if low is not None and checked < low:
                raise self._error(OdValueError(f"{checked!r} below LowLimit {low!r}"))
            if high is not None and checked > high:
                raise self._error(OdValueError(f"{checked!r} above HighLimit {high!r}"))
        # variable-length types hold str (the strings) or bytes (OCTET_STRING, DOMAIN)
        if self._max_length is not None and isinstance(checked, (str, bytes)):
            length = len(checked.encode("utf-16-le")) if isinstance(checked, str) and \
                self._data_type == DataType.UNICODE_STRING else len(checked)
            if length > self._max_length:
                raise self._error(OdValueError(
                    f"{length} bytes, more than the {self._max_length} allowed"))
        return checked

    def encode_raw(self, value: object) -> bytes:
        """Wire bytes of `value`, refused when it breaks type, limits or length."""
        return encode(self._data_type, self.check_value(value))

    def decode_raw(self, data: Union[bytes, bytearray, memoryview]) -> Value:
        """The value of wire bytes, refused when it breaks type, limits or length.
        A VISIBLE_STRING from the bus is not refused for its characters (see
        `datatypes.decode`)."""
        try:
            value = decode(self._data_type, data)
        except OdValueError as exc:
            raise self._error(exc) from None
        return self._check_limits(value)

    def copy(self) -> "ODVariable":
        """An unattached copy (the importers build compact arrays with it)."""
        clone = object.__new__(ODVariable)
        clone.__dict__.update(self.__dict__)
        clone.parent = None
        clone.object_links = list(self.object_links)
        return clone
