"""CiA 301 static data types: sizes, ranges, and the wire encoding.

Every value on the wire is little-endian (CiA 301, and CiA 1301 unchanged).
Python types per data type:

=================================  ===========================================
BOOLEAN                            bool (1 byte, 0 or 1)
INTEGERn / UNSIGNEDn               int (n = 8..64, incl. the 24/40/48/56 ones)
REAL32 / REAL64                    float (IEEE 754; inf and nan allowed)
VISIBLE_STRING                     str (see below)
UNICODE_STRING                     str, UTF-16LE on the wire
OCTET_STRING / DOMAIN              bytes
TIME_OF_DAY / TIME_DIFFERENCE      `TimeOfDay` / `TimeDifference` (ms, days)
=================================  ===========================================

VISIBLE_STRING: CiA 301 builds it from ISO 646 visible characters, so `encode`
refuses anything outside 0x20..0x7E (a clear error beats a device that shows
garbage). `decode` is lenient because real devices send Latin-1 names: it drops
trailing NUL padding and decodes the rest as Latin-1, which never fails.
UNICODE_STRING: `decode` drops trailing NUL code units too.

TIME_OF_DAY / TIME_DIFFERENCE: 6 bytes, milliseconds in the low 28 bits of a
U32 (the upper 4 bits are reserved: sent as 0, ignored on receipt) then a U16
number of days (since 1984-01-01 for TIME_OF_DAY). A time of day has
ms < 86 400 000; a time difference may use all 28 bits.

Errors are `OdValueError` without an entry name; the model adds it.
"""

from __future__ import annotations

import datetime as _dt
import enum
import math
import operator
import struct
from dataclasses import dataclass
from typing import Dict, NamedTuple, Optional, SupportsIndex, Union, cast

from .errors import OdValueError

__all__ = [
    "DataType", "TimeOfDay", "TimeDifference", "Value",
    "check", "encode", "decode", "zero_value", "real32_text", "TIME_EPOCH",
]


class DataType(enum.IntEnum):
    """The CiA 301 data type indices (also the USDO data-type byte)."""

    BOOLEAN = 0x01
    INTEGER8 = 0x02
    INTEGER16 = 0x03
    INTEGER32 = 0x04
    UNSIGNED8 = 0x05
    UNSIGNED16 = 0x06
    UNSIGNED32 = 0x07
    REAL32 = 0x08
    VISIBLE_STRING = 0x09
    OCTET_STRING = 0x0A
    UNICODE_STRING = 0x0B
    TIME_OF_DAY = 0x0C
    TIME_DIFFERENCE = 0x0D
    DOMAIN = 0x0F
    INTEGER24 = 0x10
    REAL64 = 0x11
    INTEGER40 = 0x12
    INTEGER48 = 0x13
    INTEGER56 = 0x14
    INTEGER64 = 0x15
    UNSIGNED24 = 0x16
    UNSIGNED40 = 0x18
    UNSIGNED48 = 0x19
    UNSIGNED56 = 0x1A
    UNSIGNED64 = 0x1B

    # -- properties (from the table below)
    @property
    def size(self) -> Optional[int]:
        """Fixed size in bytes; None for strings and DOMAIN (variable length)."""
        return _INFO[self].size

    @property
    def signed(self) -> bool:
        return _INFO[self].kind in ("int", "real")

    @property
    def is_integer(self) -> bool:
        """Integer types (INTEGERn, UNSIGNEDn); BOOLEAN is not one."""
        return _INFO[self].kind in ("int", "uint")

    @property
    def is_real(self) -> bool:
        return _INFO[self].kind == "real"

    @property
    def is_numeric(self) -> bool:
        """Types with an order, so limits (LowLimit/HighLimit) apply."""
        return _INFO[self].kind in ("int", "uint", "real")

    @property
    def is_variable_length(self) -> bool:
        return _INFO[self].size is None

    @property
    def min(self) -> Union[int, float, None]:
        """Smallest value (None for non-numeric types)."""
        return _INFO[self].low

    @property
    def max(self) -> Union[int, float, None]:
        """Largest value (None for non-numeric types)."""
        return _INFO[self].high

    @property
    def range_text(self) -> str:
        """'0..65535', '-128..127', '±3.4028235e+38', '' for non-numeric types."""
        info = _INFO[self]
        if info.kind == "real":
            return f"±{info.high:.8g}"
        if info.low is None:
            return ""
        return f"{info.low}..{info.high}"

    @classmethod
    def parse(cls, value: object) -> "DataType":
        """A DataType from itself, its index (int) or its name ('UNSIGNED16')."""
        if isinstance(value, cls):
            return value
        if isinstance(value, str):
            try:
                return cls[value.strip().upper()]
            except KeyError:
                raise OdValueError(f"{value!r} is not a CiA 301 data type name") from None
        if isinstance(value, int) and not isinstance(value, bool):
            try:
                return cls(value)
            except ValueError:
                raise OdValueError(f"data type 0x{value:04X} is not a CiA 301 data type") \
                    from None
        raise OdValueError(f"expected a data type, got {type(value).__name__} {value!r}")


class _Info(NamedTuple):
    size: Optional[int]
    kind: str  # bool int uint real vstring ustring octets time
    low: Union[int, float, None] = None
    high: Union[int, float, None] = None


def _int(size: int) -> _Info:
    bits = 8 * size
    return _Info(size, "int", -(1 << (bits - 1)), (1 << (bits - 1)) - 1)


def _uint(size: int) -> _Info:
    return _Info(size, "uint", 0, (1 << (8 * size)) - 1)


_REAL32_MAX = struct.unpack("<f", b"\xff\xff\x7f\x7f")[0]  # 3.4028234663852886e+38

_INFO: Dict[DataType, _Info] = {
    DataType.BOOLEAN: _Info(1, "bool"),
    DataType.INTEGER8: _int(1),
    DataType.INTEGER16: _int(2),
    DataType.INTEGER24: _int(3),
    DataType.INTEGER32: _int(4),
    DataType.INTEGER40: _int(5),
    DataType.INTEGER48: _int(6),
    DataType.INTEGER56: _int(7),
    DataType.INTEGER64: _int(8),
    DataType.UNSIGNED8: _uint(1),
    DataType.UNSIGNED16: _uint(2),
    DataType.UNSIGNED24: _uint(3),
    DataType.UNSIGNED32: _uint(4),
    DataType.UNSIGNED40: _uint(5),
    DataType.UNSIGNED48: _uint(6),
    DataType.UNSIGNED56: _uint(7),
    DataType.UNSIGNED64: _uint(8),
    DataType.REAL32: _Info(4, "real", -_REAL32_MAX, _REAL32_MAX),
    DataType.REAL64: _Info(8, "real", -1.7976931348623157e308, 1.7976931348623157e308),
    DataType.VISIBLE_STRING: _Info(None, "vstring"),
    DataType.UNICODE_STRING: _Info(None, "ustring"),
    DataType.OCTET_STRING: _Info(None, "octets"),
    DataType.DOMAIN: _Info(None, "octets"),
    DataType.TIME_OF_DAY: _Info(6, "time"),
    DataType.TIME_DIFFERENCE: _Info(6, "time"),
}

# ------------------------------------------------------------------ time types
#: Day 0 of TIME_OF_DAY (CiA 301): 1984-01-01 00:00 (taken as UTC here).
TIME_EPOCH = _dt.datetime(1984, 1, 1, tzinfo=_dt.timezone.utc)
_MS_PER_DAY = 86_400_000
_MS_MASK = 0x0FFFFFFF


def _check_time_fields(kind: str, ms: object, days: object, ms_limit: int) -> None:
    for field, value, limit in (("ms", ms, ms_limit), ("days", days, 0xFFFF)):
        if isinstance(value, bool) or not isinstance(value, int):
            raise OdValueError(f"{kind}.{field} must be an int, got {value!r}")
        if not 0 <= value <= limit:
            raise OdValueError(f"{kind}.{field} {value} outside 0..{limit}")


@dataclass(frozen=True, order=True)
class TimeOfDay:
    """A TIME_OF_DAY value: ms after midnight and days since 1984-01-01.

    Time zone: CiA 301 names none; `from_datetime` converts aware datetimes to
    UTC and takes naive ones as UTC, `to_datetime` returns an aware UTC datetime.
    """

    ms: int = 0
    days: int = 0

    def __post_init__(self) -> None:
        _check_time_fields("TimeOfDay", self.ms, self.days, _MS_PER_DAY - 1)

    @classmethod
    def from_datetime(cls, when: _dt.datetime) -> "TimeOfDay":
        if when.tzinfo is None:
            when = when.replace(tzinfo=_dt.timezone.utc)
        delta = when - TIME_EPOCH
        if delta < _dt.timedelta(0):
            raise OdValueError(f"TIME_OF_DAY cannot hold {when.isoformat()} (before 1984-01-01)")
        ms = delta.seconds * 1000 + delta.microseconds // 1000
        if delta.days > 0xFFFF:
            raise OdValueError(f"TIME_OF_DAY cannot hold {when.isoformat()} "
                               f"(more than 65535 days after 1984-01-01)")
        return cls(ms, delta.days)

    def to_datetime(self) -> _dt.datetime:
        return TIME_EPOCH + _dt.timedelta(days=self.days, milliseconds=self.ms)


@dataclass(frozen=True, order=True)
class TimeDifference:
    """A TIME_DIFFERENCE value: days + ms (ms may use all 28 bits)."""

    ms: int = 0
    days: int = 0

    def __post_init__(self) -> None:
        _check_time_fields("TimeDifference", self.ms, self.days, _MS_MASK)

    @classmethod
    def from_timedelta(cls, delta: _dt.timedelta) -> "TimeDifference":
        if delta < _dt.timedelta(0):
            raise OdValueError(f"TIME_DIFFERENCE cannot be negative, got {delta}")
        if delta.days > 0xFFFF:
            raise OdValueError(f"TIME_DIFFERENCE cannot hold {delta} (more than 65535 days)")
        return cls(delta.seconds * 1000 + delta.microseconds // 1000, delta.days)

    def to_timedelta(self) -> _dt.timedelta:
        return _dt.timedelta(days=self.days, milliseconds=self.ms)


Value = Union[bool, int, float, str, bytes, TimeOfDay, TimeDifference]


def real32_text(value: float) -> str:
    """The shortest decimal text that reads back as the same REAL32 (what a
    terminal, a monitor or a gateway shows of a single-precision value)."""
    if not math.isfinite(value):
        return repr(value)
    packed = struct.pack("<f", value)
    for digits in range(1, 10):
        text = f"{value:.{digits}g}"
        if struct.pack("<f", float(text)) == packed:
            return text
    return repr(value)


# ------------------------------------------------------------------ checks
def _describe(value: object) -> str:
    text = repr(value)
    if len(text) > 40:
        text = text[:37] + "..."
    return f"{type(value).__name__} {text}"


def _check_visible(text: str) -> None:
    for pos, char in enumerate(text):
        if not 0x20 <= ord(char) <= 0x7E:
            raise OdValueError(
                f"VISIBLE_STRING allows only visible ASCII 0x20..0x7E, got {char!r} "
                f"(U+{ord(char):04X}) at position {pos}")


def check(dtype: DataType, value: object) -> Value:
    """`value` as the Python type of `dtype`, range-checked; OdValueError if it
    does not fit. REAL32 values come back rounded to single precision, so what
    is stored equals what a round trip over the wire gives."""
    dtype = DataType.parse(dtype)
    info = _INFO[dtype]
    kind = info.kind
    if kind == "bool":
        if isinstance(value, bool):
            return value
        if isinstance(value, int) and value in (0, 1):
            return bool(value)
        raise OdValueError(f"BOOLEAN expects True/False or 0/1, got {_describe(value)}")
    if kind in ("int", "uint"):
        if isinstance(value, (bool, float, str, bytes)):
            raise OdValueError(f"{dtype.name} expects an int, got {_describe(value)}")
        try:
            # cast: whatever lacks __index__ raises the TypeError handled here
            number = operator.index(cast(SupportsIndex, value))
        except TypeError:
            raise OdValueError(f"{dtype.name} expects an int, got {_describe(value)}") from None
        assert info.low is not None and info.high is not None   # integer kinds have bounds
        if not info.low <= number <= info.high:
            raise OdValueError(f"{number} outside {dtype.name} {info.low}..{info.high}")
        return number
    if kind == "real":
        if isinstance(value, (bool, str, bytes)) or not isinstance(value, (int, float)):
            raise OdValueError(f"{dtype.name} expects a float, got {_describe(value)}")
        real = float(value)
        if dtype == DataType.REAL32 and math.isfinite(real):
            try:
                real = struct.unpack("<f", struct.pack("<f", real))[0]
            except OverflowError:
                raise OdValueError(f"{value!r} outside REAL32 range {dtype.range_text}") \
                    from None
        return real
    if kind == "vstring":
        if not isinstance(value, str):
            raise OdValueError(f"VISIBLE_STRING expects a str, got {_describe(value)}")
        _check_visible(value)
        return value
    if kind == "ustring":
        if not isinstance(value, str):
            raise OdValueError(f"UNICODE_STRING expects a str, got {_describe(value)}")
        try:
            value.encode("utf-16-le")
        except UnicodeEncodeError as exc:
            raise OdValueError(f"UNICODE_STRING cannot encode {value!r}: {exc.reason}") \
                from None
        return value
    if kind == "octets":
        if isinstance(value, (bytes, bytearray, memoryview)):
            return bytes(value)
        raise OdValueError(f"{dtype.name} expects bytes, got {_describe(value)}")
    # time
    if dtype == DataType.TIME_OF_DAY:
        if isinstance(value, TimeOfDay):
            return value
        if isinstance(value, _dt.datetime):
            return TimeOfDay.from_datetime(value)
        raise OdValueError(f"TIME_OF_DAY expects a TimeOfDay or datetime, got {_describe(value)}")
    if isinstance(value, TimeDifference):
        return value
    if isinstance(value, _dt.timedelta):
        return TimeDifference.from_timedelta(value)
    raise OdValueError(
        f"TIME_DIFFERENCE expects a TimeDifference or timedelta, got {_describe(value)}")


def zero_value(dtype: DataType) -> Value:
    """The value an entry has when its file gives no default: 0, 0.0, False,
    empty string/bytes, or time 0."""
    dtype = DataType.parse(dtype)
    if dtype == DataType.TIME_OF_DAY:
        return TimeOfDay()
    if dtype == DataType.TIME_DIFFERENCE:
        return TimeDifference()
    return _ZEROS[_INFO[dtype].kind]


_ZEROS: Dict[str, Value] = {
    "bool": False, "int": 0, "uint": 0, "real": 0.0, "vstring": "", "ustring": "", "octets": b"",
}


# ------------------------------------------------------------------ wire format
def encode(dtype: DataType, value: object) -> bytes:
    """The little-endian wire bytes of `value` (checked with `check`)."""
    dtype = DataType.parse(dtype)
    checked = check(dtype, value)
    info = _INFO[dtype]
    # check() gives each kind its one Python type: dispatch on that type
    if isinstance(checked, bool):
        return b"\x01" if checked else b"\x00"
    if isinstance(checked, int):
        return checked.to_bytes(info.size or 0, "little", signed=info.kind == "int")
    if isinstance(checked, float):
        return struct.pack("<f" if info.size == 4 else "<d", checked)
    if isinstance(checked, str):
        return checked.encode("ascii" if info.kind == "vstring" else "utf-16-le")
    if isinstance(checked, bytes):
        return checked
    return (checked.ms & _MS_MASK).to_bytes(4, "little") + checked.days.to_bytes(2, "little")


def decode(dtype: DataType, data: Union[bytes, bytearray, memoryview]) -> Value:
    """The Python value of wire bytes; fixed-size types need exactly their size."""
    dtype = DataType.parse(dtype)
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise OdValueError(f"{dtype.name}: decode expects bytes, got {_describe(data)}")
    data = bytes(data)
    info = _INFO[dtype]
    if info.size is not None and len(data) != info.size:
        raise OdValueError(f"{dtype.name} needs {info.size} byte{'s' if info.size > 1 else ''}, "
                           f"got {len(data)}")
    if info.kind == "bool":
        if data[0] > 1:
            raise OdValueError(f"BOOLEAN byte must be 0 or 1, got 0x{data[0]:02X}")
        return bool(data[0])
    if info.kind in ("int", "uint"):
        return int.from_bytes(data, "little", signed=info.kind == "int")
    if info.kind == "real":
        real: float = struct.unpack("<f" if info.size == 4 else "<d", data)[0]
        return real
    if info.kind == "vstring":
        return data.rstrip(b"\x00").decode("latin-1")
    if info.kind == "ustring":
        if len(data) % 2:
            raise OdValueError(f"UNICODE_STRING needs an even number of bytes, got {len(data)}")
        while data.endswith(b"\x00\x00"):
            data = data[:-2]
        try:
            return data.decode("utf-16-le")
        except UnicodeDecodeError as exc:
            raise OdValueError(f"UNICODE_STRING bytes are not UTF-16LE: {exc.reason}") from None
    if info.kind == "octets":
        return data
    ms = int.from_bytes(data[:4], "little") & _MS_MASK
    days = int.from_bytes(data[4:], "little")
    if dtype == DataType.TIME_OF_DAY:
        if ms >= _MS_PER_DAY:
            raise OdValueError(f"TIME_OF_DAY ms {ms} is not a time of day (>= 86400000)")
        return TimeOfDay(ms, days)
    return TimeDifference(ms, days)
