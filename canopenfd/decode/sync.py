"""SYNC frames (CiA 301, default CAN-ID 0x080): 'SYNC', 'SYNC counter 7'.
Wire format as csrc/core/co_sync.c."""

from __future__ import annotations

from .raw import with_bytes

SYNC_ID = 0x080
SYNC_COUNTER_MAX = 240   # 0x1019: 2..240; the counter runs 1..0x1019


def sync_text(data: bytes) -> str:
    """'SYNC', 'SYNC counter 7'; a length other than 0/1 or a counter outside
    1..240 is malformed."""
    if len(data) == 0:
        return "SYNC"
    if len(data) > 1:
        return with_bytes(f"SYNC malformed: {len(data)} bytes, expected 0 or 1", data)
    counter = data[0]
    if not 1 <= counter <= SYNC_COUNTER_MAX:
        return f"SYNC counter {counter} malformed: counter outside 1..{SYNC_COUNTER_MAX}"
    return f"SYNC counter {counter}"

