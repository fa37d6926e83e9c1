"""USDO frames (CiA 1301, CAN FD frames on 0x601..0x67F and 0x581..0x5FF):
'USDO 3->5 sid 7 upload request 0x1018:01'.

Wire format: csrc/core/co_usdo.h (the codec, source of truth) and
docs/protocol-notes.md. The CAN-ID's low 7 bits name the sender, byte 0 the
addressee (0 = broadcast), byte 1 is the command specifier, byte 2 the
session-ID; sub-index (byte 3) comes before the index (bytes 4-5, LE)."""

from __future__ import annotations

from typing import Dict, Optional, Tuple

from ..errors import USDO_ABORT_TEXT
from ..od.datatypes import DataType
from .raw import hex_bytes

_USDO_REQUEST = 0x600    # + client node-id
_USDO_RESPONSE = 0x580   # + server node-id
_USDO_EXPEDITED_MAX = 56
_USDO_SEGMENT_DATA = 60

# Layouts (co_usdo_layout_t): bytes the frame needs before any data.
_MUX = "mux"                  # dest cs sid sub index(2)                 6
_EXPEDITED = "expedited"      # mux type N data[N]                       8 + N
_INITIATE = "initiate"        # mux type reserved size(4)                12
_SEGMENT = "segment"          # dest cs sid counter data[60]             64 (5..63: len - 4)
_LAST = "last"                # dest cs sid n data[n]                    4 + n
_COUNTER = "counter"          # dest cs sid counter                      4
_END = "end"                  # dest cs sid                              3
_ABORT = "abort"              # mux code                                 7
_BULK_ACCEPT = "bulk accept"  # mux pacing(2), 100 us units, 0 = none    8
_BULK_REQUEST = "bulk request"  # mux window(1) reserved(1)              8

_HEAD_LEN = {_MUX: 6, _EXPEDITED: 8, _INITIATE: 12, _SEGMENT: 64, _LAST: 4, _COUNTER: 4,
             _END: 3, _ABORT: 7, _BULK_ACCEPT: 8, _BULK_REQUEST: 8}
# A segment has no size field: 64 bytes carry 60, a shorter frame (a sender
# with a smaller MTU, taken by our receivers) its length - 4, at least 1.
_SEGMENT_MIN = 5
_HAS_MUX = (_MUX, _EXPEDITED, _INITIATE, _ABORT, _BULK_ACCEPT, _BULK_REQUEST)

#: Command specifier -> (text, layout), as co_usdo_cs_t / co_usdo_layout_of.
#: Data-carrying frames are named after the data ("upload segment" is the
#: server's 0x33), confirmations "... response".
USDO_COMMANDS: Dict[int, Tuple[str, str]] = {
    0x01: ("download expedited", _EXPEDITED),
    0x02: ("download initiate", _INITIATE),
    0x03: ("download segment", _SEGMENT),
    0x04: ("download last segment", _LAST),
    0x06: ("bulk download initiate", _INITIATE),
    0x07: ("bulk segment", _SEGMENT),
    0x08: ("bulk last segment", _LAST),
    0x11: ("upload request", _MUX),
    0x13: ("upload segment request", _COUNTER),
    # bulk upload: our layout (docs/protocol-notes.md, "Bulk upload")
    0x16: ("bulk upload request", _BULK_REQUEST),
    0x17: ("bulk upload ack", _COUNTER),
    0x21: ("download expedited response", _MUX),
    0x22: ("download initiate response", _MUX),
    0x23: ("download segment response", _COUNTER),
    0x24: ("download last segment response", _END),
    0x26: ("bulk accept", _BULK_ACCEPT),
    0x28: ("bulk last segment response", _END),
    0x31: ("upload expedited", _EXPEDITED),
    0x32: ("upload initiate", _INITIATE),
    0x33: ("upload segment", _SEGMENT),
    0x34: ("upload last segment", _LAST),
    0x36: ("bulk upload initiate", _INITIATE),
    0x37: ("bulk upload segment", _SEGMENT),
    0x38: ("bulk upload last segment", _LAST),
    0x7F: ("ABORT", _ABORT),
}

_SHORT_TYPE_PREFIXES = (("UNSIGNED", "U"), ("INTEGER", "I"), ("REAL", "R"))


def usdo_type_name(code: int) -> str:
    """Name of a USDO data-type byte (CiA 301 type index): 'U32', 'I16', 'R64',
    'BOOLEAN', 'VISIBLE_STRING', 'DOMAIN'...; 'type 0xNN' when it is none."""
    try:
        name = DataType(code).name
    except ValueError:
        return f"type 0x{code:02X}"
    for long, short in _SHORT_TYPE_PREFIXES:
        if name.startswith(long) and name[len(long):].isdigit():
            return short + name[len(long):]
    return name


def usdo_abort_text(code: int) -> str:
    """'0x33 object does not exist', '0x99 unknown abort code'."""
    return f"0x{code:02X} {USDO_ABORT_TEXT.get(code, 'unknown abort code')}"


def _pacing(units: int) -> str:
    if units == 0:
        return "pacing 0 (none)"
    micros = units * 100
    shown = f"{micros} us" if micros < 1000 else f"{micros / 1000:g} ms"
    return f"pacing {units} ({shown})"


def usdo_text(can_id: int, data: bytes) -> str:
    sender = can_id - (_USDO_REQUEST if can_id > _USDO_REQUEST else _USDO_RESPONSE)
    if len(data) < 3:
        return (f"USDO {sender} malformed: {len(data)} bytes, expected at least 3"
                + (f" ({hex_bytes(data)})" if data else ""))
    if data[1] & _REMOTE_BIT:
        return _remote_text(sender, data)
    return _local_text(sender, data, "")


# Remote (routed) USDO, layout UNCONFIRMED (docs/protocol-notes.md "Remote
# USDO"): cs | 0x80; the frames with a multiplexer carry 4 bytes after the
# session-ID (destination network, node, source network, node), the local
# layout follows shifted by 4.
_REMOTE_BIT = 0x80
_REMOTE_EXT = 4


def _remote_text(sender: int, data: bytes) -> str:
    """'USDO 7->1 sid 17 routed 1:7->2:5 download expedited 0x2000:00 ...'
    (source network:node -> destination network:node)."""
    cs = data[1] & ~_REMOTE_BIT
    command = USDO_COMMANDS.get(cs)
    if command is None:
        dest = "bcast" if data[0] == 0 else str(data[0])
        return f"USDO {sender}->{dest} sid {data[2]} routed unknown command 0x{data[1]:02X}"
    if command[1] not in _HAS_MUX:
        return _local_text(sender, bytes([data[0], cs]) + data[2:], " routed")
    if len(data) < 3 + _REMOTE_EXT:
        dest = "bcast" if data[0] == 0 else str(data[0])
        return (f"USDO {sender}->{dest} sid {data[2]} routed {command[0]} malformed: "
                f"{len(data)} bytes, expected {3 + _REMOTE_EXT} or more")
    route = f" routed {data[5]}:{data[6]}->{data[3]}:{data[4]}"
    return _local_text(sender, bytes([data[0], cs, data[2]]) + data[3 + _REMOTE_EXT:], route)


def _local_text(sender: int, data: bytes, routed: str) -> str:
    """A local frame (routed: the remote frame without its extension; lengths
    in messages are then those of the local layout)."""
    dest = "bcast" if data[0] == 0 else str(data[0])
    head = f"USDO {sender}->{dest} sid {data[2]}{routed}"
    cs = data[1]
    command = USDO_COMMANDS.get(cs)
    if command is None:
        return f"{head} unknown command 0x{cs:02X}"
    name, layout = command
    mux: Optional[str] = None
    if layout in _HAS_MUX and len(data) >= 6:
        mux = f"0x{data[4] | data[5] << 8:04X}:{data[3]:02X}"
    what = f"{head} {name}" + (f" {mux}" if mux else "")

    def malformed(why: str) -> str:
        return f"{what} malformed: {why}"

    need = _SEGMENT_MIN if layout == _SEGMENT else _HEAD_LEN[layout]
    if len(data) < need:
        return malformed(f"{len(data)} bytes, expected {need}"
                         + (" or more" if layout in (_EXPEDITED, _LAST, _SEGMENT) else ""))
    if layout == _EXPEDITED:
        n = data[7]
        if n > _USDO_EXPEDITED_MAX:
            return malformed(f"N={n} > {_USDO_EXPEDITED_MAX}")
        if len(data) < 8 + n:
            return malformed(f"{len(data)} bytes, N={n} needs {8 + n}")
        text = f"{what} {usdo_type_name(data[6])} N={n}"
        return f"{text} {hex_bytes(data[8:8 + n])}" if n else text
    if layout == _INITIATE:
        size = int.from_bytes(data[8:12], "little")
        shown = "0xFFFFFFFF (unknown)" if size == 0xFFFFFFFF else str(size)
        return f"{what} {usdo_type_name(data[6])} size {shown}"
    if layout == _SEGMENT:
        n = min(len(data) - 4, _USDO_SEGMENT_DATA)
        return f"{what} #{data[3]} {n} B" + (" (short)" if n < _USDO_SEGMENT_DATA else "")
    if layout == _LAST:
        n = data[3]
        if n > _USDO_SEGMENT_DATA:
            return malformed(f"n={n} > {_USDO_SEGMENT_DATA}")
        if len(data) < 4 + n:
            return malformed(f"{len(data)} bytes, n={n} needs {4 + n}")
        return f"{what} {n} B"
    if layout == _COUNTER:
        return f"{what} #{data[3]}"
    if layout == _ABORT:
        return f"{what} {usdo_abort_text(data[6])}"
    if layout == _BULK_ACCEPT:
        return f"{what} {_pacing(data[6] | data[7] << 8)}"
    if layout == _BULK_REQUEST:
        return f"{what} window {data[6]}" + (" (invalid: 0)" if data[6] == 0 else "")
    return what  # _MUX, _END: nothing more


