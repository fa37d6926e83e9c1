"""Sleep and wake-up frames (CiA 320, see csrc/include/canopenfd/co_sleep.h):
'SLEEP query', 'SLEEP objection reason 0x42', 'SLEEP wake-up from a device
status 0x00 reason 0x01'. 8 bytes, byte 0 a command."""

from __future__ import annotations

from .raw import with_bytes

DEVICE_ID, MASTER_ID, REQUEST_ID = 0x690, 0x691, 0x692
SLEEP_IDS = (DEVICE_ID, MASTER_ID, REQUEST_ID)
FRAME_LEN = 8


def sleep_text(can_id: int, data: bytes) -> str:
    """The text of a frame on 0x690..0x692; other lengths than 8 are malformed."""
    if len(data) != FRAME_LEN:
        return with_bytes(f"SLEEP malformed: {len(data)} bytes, expected {FRAME_LEN}", data)
    command, value = data[0], data[1]
    if can_id == REQUEST_ID:
        return "SLEEP request" if command == 0x03 else \
            with_bytes(f"SLEEP request malformed: command 0x{command:02X}", data)
    if can_id == MASTER_ID and command == 0x01:
        return "SLEEP query"
    if can_id == MASTER_ID and command == 0x02:
        return "SLEEP command"
    if can_id == DEVICE_ID and command == 0x81:
        return f"SLEEP objection reason 0x{value:02X}"
    sender = "the master" if can_id == MASTER_ID else "a device"
    return f"SLEEP wake-up from {sender} status 0x{command:02X} reason 0x{value:02X}"
