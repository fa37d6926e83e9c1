"""Multiplexed PDO frames, on a CAN-ID an object dictionary makes an MPDO
(mapping sub 0 = 0xFF DAM / 0xFE SAM): "TPDO1 node 5 DAM to node 6
0x2300:03 = 1234", "TPDO2 node 5 SAM from node 5 0x2300:01 = 77". Frame
layout as csrc/core/co_mpdo.c: byte 0 bit 7 DAM, bits 0..6 node-id, bytes
1..2 index (little-endian), byte 3 sub, bytes 4..7 the value. The value is
decoded by its type when the OD of the node it belongs to was given (DAM:
the destination's, SAM: the producer's), else shown in hex."""

from __future__ import annotations

from typing import Any, Callable, Optional

from ..od.datatypes import decode as decode_value
from ..od.errors import OdValueError
from .raw import hex_bytes, with_bytes

MPDO_LEN = 8
_DAM_BIT = 0x80

#: (node, index, sub) -> the OD variable, or None when no OD of that node names it
VariableLookup = Callable[[int, int, int], Optional[Any]]


def _value_text(variable: Optional[Any], value: bytes,
                format_value: Callable[[Any, Any], str]) -> str:
    dtype = variable.data_type if variable is not None else None
    size = dtype.size if dtype is not None else None
    if dtype is None or size is None or not 1 <= size <= len(value):
        return hex_bytes(value)
    try:
        return format_value(dtype, decode_value(dtype, value[:size]))
    except OdValueError:
        return f"{hex_bytes(value)}?"


def mpdo_text(head: str, mode: str, data: bytes, lookup: VariableLookup,
              format_value: Callable[[Any, Any], str]) -> str:
    """head ('TPDO1 node 5') and what the frame says; mode is the mapping's
    ('DAM' or 'SAM'): a frame of the other mode or not 8 bytes long is
    malformed."""
    if len(data) != MPDO_LEN:
        return with_bytes(f"{head} {mode} malformed: {len(data)} bytes, an MPDO has "
                          f"{MPDO_LEN}", data)
    dam = bool(data[0] & _DAM_BIT)
    node = data[0] & 0x7F
    index = int.from_bytes(data[1:3], "little")
    sub = data[3]
    value = bytes(data[4:8])
    if dam:
        whom = "to all nodes" if node == 0 else f"to node {node}"
        variable = lookup(node, index, sub) if node != 0 else None
    else:
        whom = f"from node {node}"
        variable = lookup(node, index, sub)
    text = (f"{head} {'DAM' if dam else 'SAM'} {whom} 0x{index:04X}:{sub:02X} = "
            f"{_value_text(variable, value, format_value)}")
    if dam != (mode == "DAM"):
        text += f" malformed: the mapping makes it a {mode} MPDO"
    return text
