"""TIME frames (CiA 301, default CAN-ID 0x100): 'TIME 2024-01-01 12:34:56.789'.
Wire format as csrc/core/co_time.c (6-byte TIME_OF_DAY)."""

from __future__ import annotations

from ..od.datatypes import TimeOfDay
from .raw import with_bytes

TIME_ID = 0x100
TIME_LEN = 6
_MS_MASK = 0x0FFFFFFF
_MS_PER_DAY = 86_400_000


def format_time_of_day(value: TimeOfDay) -> str:
    """'2024-01-01 12:34:56.789' (ISO 8601 date and time, the epoch taken as UTC)."""
    return value.to_datetime().strftime("%Y-%m-%d %H:%M:%S.%f")[:-3]


def time_text(data: bytes) -> str:
    """'TIME 2024-01-01 12:34:56.789': bytes 0..3 ms after midnight (28 bits, the
    upper 4 reserved), bytes 4..5 days since 1984-01-01 (as co_time.c). Reserved
    bits set, ms beyond a day and lengths other than 6 are malformed."""
    if len(data) != TIME_LEN:
        return with_bytes(f"TIME malformed: {len(data)} bytes, expected {TIME_LEN}", data)
    word = int.from_bytes(data[0:4], "little")
    ms, days, reserved = word & _MS_MASK, data[4] | data[5] << 8, word >> 28
    if ms >= _MS_PER_DAY:
        return (f"TIME day {days} ms {ms} malformed: ms outside 0..{_MS_PER_DAY - 1}"
                + (f", reserved bits 0x{reserved:X}" if reserved else ""))
    text = f"TIME {format_time_of_day(TimeOfDay(ms, days))}"
    if reserved:
        return f"{text} malformed: reserved bits 31..28 = 0x{reserved:X}"
    return text

