"""One-line, human-readable text for a CAN frame: NMT, boot-up and heartbeat
decoded (malformed ones marked), anything else shown raw. Used by the CLI
monitor and the demo; pure Python, no runtime needed."""

from __future__ import annotations

from typing import Any

from .nmt import NmtCommand, NmtState

_FD = 0x01
_BRS = 0x02
_ESI = 0x04
_EXT = 0x08
_RTR = 0x10


def _fields(frame: Any):
    """(id, data, flags) of a Frame, a python-can Message or an (id, data[, flags]) tuple."""
    if isinstance(frame, tuple):
        can_id, data = frame[0], bytes(frame[1])
        return can_id, data, (frame[2] if len(frame) > 2 else 0)
    if hasattr(frame, "arbitration_id"):  # python-can Message
        flags = ((_FD if frame.is_fd else 0) | (_BRS if frame.bitrate_switch else 0)
                 | (_ESI if frame.error_state_indicator else 0)
                 | (_EXT if frame.is_extended_id else 0)
                 | (_RTR if frame.is_remote_frame else 0))
        return frame.arbitration_id, bytes(frame.data), flags
    return frame.id, bytes(frame.data), frame.flags


def hex_bytes(data: bytes) -> str:
    return " ".join(f"{b:02X}" for b in data)


def format_raw(frame: Any) -> str:
    """'0x181 [8] 01 02 03 04 05 06 07 08' (29-bit ids with 8 digits, RTR marked)."""
    can_id, data, flags = _fields(frame)
    ident = f"0x{can_id:08X}" if flags & _EXT else f"0x{can_id:03X}"
    if flags & _RTR:
        length = getattr(frame, "length", len(data))
        return f"{ident} [{length}] RTR"
    text = f"{ident} [{len(data)}]"
    return f"{text} {hex_bytes(data)}" if data else text


def format_flags(frame: Any) -> str:
    """'[FD]', '[FD BRS]', '[FD BRS ESI]' or '' for classic frames."""
    _, _, flags = _fields(frame)
    if not flags & _FD:
        return ""
    parts = ["FD"] + (["BRS"] if flags & _BRS else []) + (["ESI"] if flags & _ESI else [])
    return "[" + " ".join(parts) + "]"


def meaning(frame: Any) -> str:
    """What the frame means in CANopen terms, '' when it is no NMT/boot-up/heartbeat."""
    can_id, data, flags = _fields(frame)
    if flags & (_EXT | _RTR):
        if flags & _RTR and 0x701 <= can_id <= 0x77F and not flags & _EXT:
            return f"node guarding request node {can_id - 0x700}"
        return ""
    if can_id == 0x000:
        return _nmt(data)
    if 0x700 <= can_id <= 0x77F:
        return _heartbeat(can_id - 0x700, data)
    return ""


def decode(frame: Any) -> str:
    """Readable one-line text: the meaning when known, else the raw frame;
    FD frames end with their marker ('[FD BRS]')."""
    text = meaning(frame) or format_raw(frame)
    marker = format_flags(frame)
    return f"{text} {marker}" if marker else text


def describe(frame: Any, width: int = 30) -> str:
    """Raw frame, then its meaning: the CLI monitor's line."""
    raw = format_raw(frame)
    text = meaning(frame)
    marker = format_flags(frame)
    line = f"{raw:<{width}} {text}".rstrip() if text else raw
    return f"{line} {marker}" if marker else line


def _nmt(data: bytes) -> str:
    if len(data) != 2:
        return f"NMT malformed: {len(data)} bytes, expected 2" + (
            f" ({hex_bytes(data)})" if data else "")
    command, node_id = data
    target = "all" if node_id == 0 else f"node {node_id}"
    try:
        label = NmtCommand(command).label
    except ValueError:
        return f"NMT malformed: unknown command 0x{command:02X} for {target}"
    if node_id > 127:
        return f"NMT {label} node {node_id} malformed: node-id outside 0..127"
    return f"NMT {label} {target}"


def _heartbeat(node_id: int, data: bytes) -> str:
    if node_id == 0:
        return "heartbeat malformed: CAN-ID 0x700 (node-id 0)"
    if len(data) != 1:
        return f"heartbeat node {node_id} malformed: {len(data)} bytes, expected 1"
    code = data[0]
    if code == NmtState.INITIALISING:
        return f"boot-up node {node_id}"
    if code & 0x7F in (NmtState.STOPPED, NmtState.OPERATIONAL, NmtState.PRE_OPERATIONAL) \
            and code & 0x80:
        # Node-guarding reply: state in bits 0..6, toggle bit 7.
        return (f"node guarding reply node {node_id} {NmtState(code & 0x7F).label} "
                "toggle 1")
    try:
        state = NmtState(code)
    except ValueError:
        state = None
    if state is None or state is NmtState.UNKNOWN:
        return f"heartbeat node {node_id} malformed: state 0x{code:02X}"
    return f"heartbeat node {node_id} {state.label}"
