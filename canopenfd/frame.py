"""`Frame`: one CAN or CAN FD frame as Python sees it (monitor lines,
`Line.send_frame`, the decoder), plus its python-can conversions."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from ._binding.constants import FrameFlag

if TYPE_CHECKING:  # pragma: no cover
    import can

# Flag bits of co_frame_t.flags, as plain ints.
FLAG_FD = int(FrameFlag.FD)
FLAG_BRS = int(FrameFlag.BRS)
FLAG_ESI = int(FrameFlag.ESI)
FLAG_EXT = int(FrameFlag.EXT)
FLAG_RTR = int(FrameFlag.RTR)

FD_LENGTHS = (0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64)


def fd_len_round(n: int) -> int:
    """Smallest valid CAN FD length >= n (n <= 64)."""
    for length in FD_LENGTHS:
        if length >= n:
            return length
    raise ValueError(f"{n} bytes do not fit a CAN FD frame (at most 64)")


@dataclass(frozen=True)
class Frame:
    """A frame seen on (or sent to) a line.

    `timestamp` is time.monotonic() seconds (CLOCK_MONOTONIC, as the runtime
    stamps events); `tx` is True for frames this line sent.
    """

    id: int
    data: bytes = b""
    fd: bool = False
    brs: bool = False
    esi: bool = False
    ext: bool = False
    rtr: bool = False
    timestamp: float = 0.0
    tx: bool = False
    rtr_len: int = 0  # requested length of a remote frame (its data is empty)

    @property
    def flags(self) -> int:
        """co_frame_t flag bits."""
        return ((FLAG_FD if self.fd else 0) | (FLAG_BRS if self.brs else 0)
                | (FLAG_ESI if self.esi else 0) | (FLAG_EXT if self.ext else 0)
                | (FLAG_RTR if self.rtr else 0))

    @property
    def length(self) -> int:
        return self.rtr_len if self.rtr else len(self.data)

    @classmethod
    def from_flags(cls, can_id: int, data: bytes, flags: int, *, timestamp: float = 0.0,
                   tx: bool = False, rtr_len: int = 0) -> "Frame":
        return cls(can_id, bytes(data), fd=bool(flags & FLAG_FD), brs=bool(flags & FLAG_BRS),
                   esi=bool(flags & FLAG_ESI), ext=bool(flags & FLAG_EXT),
                   rtr=bool(flags & FLAG_RTR), timestamp=timestamp, tx=tx, rtr_len=rtr_len)

    # ---------------------------------------------------------------- python-can
    @classmethod
    def from_message(cls, msg: can.Message) -> "Frame":
        """From a python-can `can.Message` (error frames are the caller's business)."""
        rtr = bool(msg.is_remote_frame)
        return cls(int(msg.arbitration_id), b"" if rtr else bytes(msg.data),
                   fd=bool(msg.is_fd), brs=bool(msg.bitrate_switch),
                   esi=bool(msg.error_state_indicator), ext=bool(msg.is_extended_id),
                   rtr=rtr, timestamp=float(msg.timestamp or 0.0),
                   rtr_len=int(msg.dlc) if rtr else 0)

    def to_message(self) -> can.Message:
        """To a python-can `can.Message` (imports python-can)."""
        import can

        return can.Message(arbitration_id=self.id, is_extended_id=self.ext,
                           is_remote_frame=self.rtr, is_fd=self.fd, bitrate_switch=self.brs,
                           error_state_indicator=self.esi,
                           data=None if self.rtr else self.data, dlc=self.length,
                           check=False)
