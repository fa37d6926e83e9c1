"""Values as written in EDS/DCF/XDD files: parsing and formatting.

Shared by the EDS and XDD readers and the EDS writer so both file formats
read numbers the same way. Rules (CiA 306, where it says something):

- integers: ``0x1A`` hex, ``017`` **octal** (CiA 306: a leading 0 means octal,
  so ``010`` is 8; python-canopen issue #313 is about exactly this), else
  decimal; an optional sign. For signed types a hex value above the positive
  range is read as two's complement of the type's width (``0xFFFF`` as
  INTEGER16 is -1), as vendor tools write it.
- node-id relative values: ``$NODEID+0x180``, ``$NODEID + 0x180``,
  ``0x180+$NODEID`` and plain ``$NODEID`` (case-insensitive), integers only.
- BOOLEAN: 0/1 or true/false.
- REAL32/REAL64: decimal notation (``1.5``, ``-2e3``, ``inf``, ``nan``).
- VISIBLE_STRING / UNICODE_STRING: the text itself.
- OCTET_STRING / DOMAIN: hex digits, spaces between bytes allowed (``01 02 FF``).
- TIME_OF_DAY / TIME_DIFFERENCE: the 48-bit integer the 6 wire bytes make
  (ms in bits 0..27, days in bits 32..47).
- empty text: no value for numbers (None), empty string/bytes otherwise.
"""

from __future__ import annotations

import re
from typing import Optional, Tuple

from .datatypes import DataType, TimeDifference, TimeOfDay, Value, check
from .errors import OdValueError

_MAX_NUMBER_TEXT = 80  # longer "numbers" are garbage; int() on them would be slow
_INT_RE = re.compile(r"^([+-]?)(0[xX][0-9A-Fa-f]+|0[0-7]*|0[0-9]+|[1-9][0-9]*)$")
_FLOAT_RE = re.compile(
    r"^[+-]?((\d+\.?\d*|\.\d+)([eE][+-]?\d+)?|inf|infinity|nan)$", re.IGNORECASE)
_NODEID_RE = re.compile(
    r"^(?:\$NODEID(?:\s*\+\s*(?P<after>[^$]+?))?|(?P<before>[^$]+?)\s*\+\s*\$NODEID)$",
    re.IGNORECASE)
_HEX_BYTES_RE = re.compile(r"^(0[xX])?[0-9A-Fa-f\s]*$")


def parse_int(text: str) -> int:
    """An integer in CiA 306 notation (hex 0x.., octal with a leading 0, decimal)."""
    text = text.strip()
    if len(text) > _MAX_NUMBER_TEXT:
        raise OdValueError(f"{text[:20]!r}... is too long for a number")
    match = _INT_RE.match(text)
    if not match:
        raise OdValueError(f"{text!r} is not an integer (decimal, 0x hex or 0 octal)")
    sign, digits = match.groups()
    if digits[:2] in ("0x", "0X"):
        number = int(digits[2:], 16)
    elif len(digits) > 1 and digits[0] == "0":
        if any(d in "89" for d in digits):
            raise OdValueError(f"{text!r} is not a valid octal number "
                               f"(CiA 306: a leading 0 means octal)")
        number = int(digits, 8)
    else:
        number = int(digits)
    return -number if sign == "-" else number


def _parse_typed_int(dtype: DataType, text: str) -> int:
    number = parse_int(text)
    stripped = text.strip()
    high, size = dtype.max, dtype.size   # both set for integer types
    if (dtype.is_integer and dtype.signed and stripped[:2].lower() == "0x"
            and high is not None and size is not None and high < number < (1 << (8 * size))):
        number -= 1 << (8 * size)
    return number


def parse_value(dtype: DataType, text: Optional[str],
                allow_node_id: bool = True) -> Tuple[Optional[Value], bool]:
    """(value, relative_to_node_id) of a file value for `dtype`.

    A node-id relative value comes back as its offset with relative True.
    Empty text gives (None, False) for numbers and times, ("" / b"", False)
    for strings. Raises OdValueError naming the problem."""
    dtype = DataType.parse(dtype)
    if text is None:
        return None, False
    stripped = text.strip()
    if dtype in (DataType.VISIBLE_STRING, DataType.UNICODE_STRING):
        return check(dtype, text), False
    if dtype in (DataType.OCTET_STRING, DataType.DOMAIN):
        return parse_hex_bytes(stripped), False
    if not stripped:
        return None, False
    if "$" in stripped:
        if not allow_node_id:
            raise OdValueError(f"{stripped!r}: $NODEID is not allowed here")
        match = _NODEID_RE.match(stripped)
        if not match:
            raise OdValueError(f"{stripped!r} is not a node-id expression "
                               f"($NODEID+offset or offset+$NODEID)")
        if not dtype.is_integer:
            raise OdValueError(f"{stripped!r}: $NODEID works only with integer types, "
                               f"not {dtype.name}")
        offset_text = match.group("after") or match.group("before")
        offset = _parse_typed_int(dtype, offset_text) if offset_text else 0
        return check(dtype, offset), True
    if dtype == DataType.BOOLEAN:
        lowered = stripped.lower()
        if lowered in ("true", "false"):
            return lowered == "true", False
        return check(dtype, parse_int(stripped)), False
    if dtype.is_integer:
        return check(dtype, _parse_typed_int(dtype, stripped)), False
    if dtype.is_real:
        if len(stripped) > _MAX_NUMBER_TEXT or not _FLOAT_RE.match(stripped):
            raise OdValueError(f"{stripped[:40]!r} is not a decimal number for {dtype.name}")
        return check(dtype, float(stripped)), False
    raw = parse_int(stripped)  # TIME_OF_DAY / TIME_DIFFERENCE
    if not 0 <= raw < (1 << 48) or raw & 0xF0000000:
        raise OdValueError(f"{stripped!r} is not a 48-bit {dtype.name} value "
                           f"(ms in bits 0..27, days in bits 32..47)")
    cls = TimeOfDay if dtype == DataType.TIME_OF_DAY else TimeDifference
    return cls(raw & 0x0FFFFFFF, raw >> 32), False


def parse_hex_bytes(text: str) -> bytes:
    """Bytes from hex digits ('0102FF', '01 02 FF', '0x0102FF')."""
    if not _HEX_BYTES_RE.match(text):
        raise OdValueError(f"{text[:40]!r} is not hex bytes (like 01 02 FF)")
    digits = "".join(text[2:].split() if text[:2].lower() == "0x" else text.split())
    if len(digits) % 2:
        raise OdValueError(f"{text[:40]!r} has an odd number of hex digits")
    return bytes.fromhex(digits)


def format_value(dtype: DataType, value: Optional[Value], relative: bool = False) -> str:
    """The file text of a value, read back to the same value by `parse_value`."""
    dtype = DataType.parse(dtype)
    if value is None:
        return ""
    if relative:
        # a negative offset of a signed type as its two's complement (0xFFFF
        # for -1 in an INTEGER16), which parse_value reads back as negative
        if isinstance(value, float):   # a REAL offset (ODVariable allows one): as it is
            return f"$NODEID+{value!r}"
        if isinstance(value, bool) or not isinstance(value, int):
            raise OdValueError(f"a node-id relative value is a numeric offset, "
                               f"got {value!r} for {dtype.name}")
        offset = value
        if offset < 0 and dtype.is_integer and dtype.size is not None:
            offset += 1 << (8 * dtype.size)
        return f"$NODEID+0x{offset:X}"
    if dtype == DataType.BOOLEAN:
        return "1" if value else "0"
    # checked values: int for integer types, float (or an int limit) for reals
    if dtype.is_integer and isinstance(value, (int, float)):
        number = int(value)
        if dtype.signed:
            return str(number)
        return f"0x{number:X}"
    if dtype.is_real and isinstance(value, (int, float)):
        return repr(float(value))
    if isinstance(value, (TimeOfDay, TimeDifference)):
        return f"0x{(value.days << 32) | value.ms:X}"
    if isinstance(value, bytes):
        return value.hex().upper()
    return str(value)

