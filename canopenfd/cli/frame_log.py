"""Log files of `canopenfd monitor`: frames written with python-can's
`can.Logger` (`--log FILE`) and read back with `can.LogReader` (`--replay
FILE`); the file's extension picks the format (candump .log, .asc, .blf,
.csv, .trc, .mf4, .db as python-can supports them). CAN FD frames keep
their FD, bit-rate switch and ESI flags and their length.

Time stamps: the runtime stamps frames with CLOCK_MONOTONIC; the log gets
wall-clock time (what candump and the other tools write), the offset taken
once when the log opens. A replayed frame keeps the file's time stamp.

python-can's .csv and .trc writers have no CAN FD frames (CSV has no column
for the flags, TRC skips FD frames): those formats are refused for an fd
line, and a replay that would write an FD frame to one stops with an error."""

from __future__ import annotations

import os
import pathlib
import time
from typing import Any, Iterator, List

from ..frame import Frame
from .common import UsageError


def _python_can() -> Any:
    try:
        import can
    except ImportError:
        raise UsageError("--log/--replay need python-can: pip install python-can") from None
    return can


def log_formats(kind: str) -> List[str]:
    """The file extensions python-can writes ('write') or reads ('read')."""
    can = _python_can()
    module = can.io.logger if kind == "write" else can.io.player
    table = getattr(module, "MESSAGE_WRITERS" if kind == "write" else "MESSAGE_READERS", {})
    return sorted(table)


#: log formats whose python-can writer loses CAN FD frames, and how
_NO_FD = {".csv": "has no CAN FD flags (FD frames would read back as classic ones)",
          ".trc": "skips CAN FD frames"}


def _format(path: str) -> str:
    """The extension that picks the format (.log of frames.log.gz)."""
    suffixes = [s.lower() for s in pathlib.Path(path).suffixes]
    if suffixes and suffixes[-1] == ".gz":
        suffixes.pop()
    return suffixes[-1] if suffixes else ""


class FrameLog:
    """Frames written to FILE with can.Logger, in the order given; close()
    flushes (BLF and MF4 write their headers then). fd_line: the frames come
    from a CAN FD line (formats without FD frames are refused)."""

    def __init__(self, path: str, fd_line: bool = False) -> None:
        can = _python_can()
        self.path = path
        self._no_fd = _NO_FD.get(_format(path))
        if fd_line and self._no_fd:
            raise UsageError(f"--log {path}: python-can's {_format(path)} format "
                             f"{self._no_fd}: use .log, .asc or .blf for an fd line")
        self._to_wall = time.time() - time.monotonic()
        self.written = 0
        try:
            self._logger = can.Logger(path)
        except ValueError as exc:       # an extension python-can does not write
            raise UsageError(f"--log {path}: {exc} (python-can writes "
                             f"{', '.join(log_formats('write'))})") from None
        except OSError as exc:
            raise UsageError(f"--log {path}: {exc.strerror or exc}") from None

    def write(self, frame: Frame) -> None:
        if frame.fd and self._no_fd:
            raise UsageError(f"--log {self.path}: frame {self.written + 1} is a CAN FD frame "
                             f"and python-can's {_format(self.path)} format {self._no_fd}: "
                             "use .log, .asc or .blf")
        message = frame.to_message()
        message.timestamp = frame.timestamp + self._to_wall
        message.is_rx = not frame.tx
        self._logger.on_message_received(message)
        self.written += 1

    def close(self) -> None:
        self._logger.stop()


def read_log(path: str) -> Iterator[Frame]:
    """The frames of a log file python-can reads, in file order; error frames
    are left out (they carry no CANopen frame). UsageError naming the file
    (and how many frames were read) for a file that cannot be read."""
    can = _python_can()
    if not os.path.isfile(path):
        raise UsageError(f"--replay {path}: no such file")
    try:
        reader = can.LogReader(path)
    except ValueError as exc:
        raise UsageError(f"--replay {path}: {exc} (python-can reads "
                         f"{', '.join(log_formats('read'))})") from None
    except OSError as exc:
        raise UsageError(f"--replay {path}: {exc.strerror or exc}") from None
    count = 0
    try:
        with reader:
            for message in reader:
                count += 1
                if message.is_error_frame:
                    continue
                frame = Frame.from_message(message)
                yield Frame(frame.id, frame.data, fd=frame.fd, brs=frame.brs, esi=frame.esi,
                            ext=frame.ext, rtr=frame.rtr, timestamp=frame.timestamp,
                            tx=not message.is_rx, rtr_len=frame.rtr_len)
    except UsageError:
        raise
    except Exception as exc:  # python-can's readers raise many kinds for a broken file
        raise UsageError(f"--replay {path}: cannot read frame {count + 1}: {exc}") from None
