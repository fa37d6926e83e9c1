"""The raw side of a frame, whatever holds it (a canopenfd `Frame`, a
python-can `Message`, an (id, data[, flags]) tuple): its fields, its bytes in
hex, '0x181 [8] 01 02' and the FD marker '[FD BRS]'."""

from __future__ import annotations

from typing import Any, Optional, Tuple

from ..frame import FLAG_BRS, FLAG_ESI, FLAG_EXT, FLAG_FD, FLAG_RTR


def frame_fields(frame: Any) -> Tuple[int, bytes, int]:
    """(id, data, flags) of a Frame, a python-can Message or an (id, data[, flags]) tuple."""
    if isinstance(frame, tuple):
        can_id, data = frame[0], bytes(frame[1])
        return can_id, data, (frame[2] if len(frame) > 2 else 0)
    if hasattr(frame, "arbitration_id"):  # python-can Message
        flags = ((FLAG_FD if frame.is_fd else 0) | (FLAG_BRS if frame.bitrate_switch else 0)
                 | (FLAG_ESI if frame.error_state_indicator else 0)
                 | (FLAG_EXT if frame.is_extended_id else 0)
                 | (FLAG_RTR if frame.is_remote_frame else 0))
        return frame.arbitration_id, bytes(frame.data), flags
    return frame.id, bytes(frame.data), frame.flags


def hex_bytes(data: bytes) -> str:
    return " ".join(f"{b:02X}" for b in data)


def with_bytes(text: str, data: bytes) -> str:
    """text, then the frame's bytes in parentheses (malformed frames show them)."""
    return f"{text} ({hex_bytes(data)})" if data else text


def format_raw(frame: Any, max_bytes: Optional[int] = None) -> str:
    """'0x181 [8] 01 02 03 04 05 06 07 08' (29-bit ids with 8 digits, RTR marked);
    with max_bytes, longer data is cut there and ends with '...'."""
    can_id, data, flags = frame_fields(frame)
    ident = f"0x{can_id:08X}" if flags & FLAG_EXT else f"0x{can_id:03X}"
    if flags & FLAG_RTR:
        length = getattr(frame, "length", len(data))
        return f"{ident} [{length}] RTR"
    text = f"{ident} [{len(data)}]"
    if max_bytes is not None and len(data) > max_bytes:
        return f"{text} {hex_bytes(data[:max_bytes])} ..."
    return f"{text} {hex_bytes(data)}" if data else text


def format_flags(frame: Any) -> str:
    """'[FD]', '[FD BRS]', '[FD BRS ESI]' or '' for classic frames."""
    _, _, flags = frame_fields(frame)
    if not flags & FLAG_FD:
        return ""
    parts = ["FD"] + (["BRS"] if flags & FLAG_BRS else []) + (["ESI"] if flags & FLAG_ESI else [])
    return "[" + " ".join(parts) + "]"
