"""SYNC, TIME and node guarding of a line (python-canopen's names).

    line.sync.start(0.01, overflow=16)         # SYNC every 10 ms, counter 1..16
    line.sync.add_callback(print)              # callback(counter), 0 = no counter
    line.sync.stop()
    line.time.transmit()                       # TIME stamp: now (or a datetime)
    line.time.add_callback(print)              # callback(datetime, UTC)
    drive.guard(100, 3)                        # classic lines: guard node every 100 ms

With a local node whose OD has 0x1005/0x1006 (0x1007, 0x1019) the SYNC
producer is configured through those entries, as the network would; without,
the line's own SYNC producer runs. The local node's synchronous PDOs follow
every SYNC of the line, ours included.
"""

from __future__ import annotations

import datetime as _dt
import enum
from typing import TYPE_CHECKING, Callable, Optional, Union

from ._binding.constants import GuardEventCode
from ._callbacks import CallbackList
from .errors import ConfigurationError

if TYPE_CHECKING:  # pragma: no cover
    from .line import Line

__all__ = ["SyncService", "TimeService", "GuardEvent", "TIME_EPOCH"]

#: Day 0 of the CANopen TIME_OF_DAY (CiA 301): 1984-01-01, UTC.
TIME_EPOCH = _dt.datetime(1984, 1, 1, tzinfo=_dt.timezone.utc)
_MAX_US = 0xFFFFFFFF


class GuardEvent(str, enum.Enum):
    """What node guarding tells about a guarded node (co_guard_event_t)."""

    STARTED = "started"                  # first valid answer
    STATE_CHANGED = "state-changed"      # an answer with another state
    LOST = "lost"                        # life time factor answers missed in a row
    RESUMED = "resumed"                  # a valid answer after LOST
    TOGGLE_ERROR = "toggle-error"        # answer with the wrong toggle bit: not taken
    UNEXPECTED_STATE = "unexpected-state"

    @classmethod
    def from_code(cls, code: int) -> Optional["GuardEvent"]:
        """The event of a co_guard_event_t code, None for an unknown one."""
        try:
            return cls[GuardEventCode(code).name]
        except ValueError:
            return None


def _seconds_to_us(value: object, name: str, where: str, allow_zero: bool) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigurationError(f"{where}: {name} must be a number of seconds, got {value!r}")
    us = round(value * 1_000_000)
    low = 0 if allow_zero else 1
    if not low <= us <= _MAX_US:
        raise ConfigurationError(f"{where}: {name} {value!r} s outside "
                                 f"{'0' if allow_zero else '1 µs'}..{_MAX_US / 1e6:g} s "
                                 "(a 32-bit count of µs)")
    return us


class SyncService:
    """The SYNC of a line (`line.sync`): producer and callbacks."""

    def __init__(self, line: "Line") -> None:
        self.line = line
        self._callbacks = CallbackList(f"line {line.channel!r} SYNC")
        self._listening = False
        #: The producer's period in seconds (None: not producing from here).
        self.period: Optional[float] = None

    def __repr__(self) -> str:
        return f"<SyncService {self.line.channel!r} period {self.period}>"

    @property
    def _where(self) -> str:
        return f"SYNC producer of {self.line._where}"

    def start(self, period: Optional[float] = None, *, window: float = 0,
              overflow: int = 0) -> None:
        """Produce SYNC every `period` seconds (python-canopen's
        `network.sync.start(0.1)`; µs resolution). window: synchronous window
        length in seconds (0 = none). overflow: 0 (SYNC without counter) or
        2..240 (counter 1..overflow in byte 0). start(None) stops."""
        if period is None:
            self.stop()
            return
        period_us = _seconds_to_us(period, "period", self._where, False)
        window_us = _seconds_to_us(window, "window", self._where, True)
        if isinstance(overflow, bool) or not isinstance(overflow, int) or \
                not (overflow == 0 or 2 <= overflow <= 240):
            raise ConfigurationError(f"{self._where}: overflow must be 0 (no counter) or "
                                     f"2..240, got {overflow!r}")
        self.line._rt.sync_producer(self.line.index, period_us, window_us, overflow,
                                    f"start({period!r}) of the {self._where}")
        self.period = period_us / 1e6

    def stop(self) -> None:
        """Stop producing SYNC."""
        self.line._rt.sync_producer(self.line.index, 0, 0, 0, f"stop of the {self._where}")
        self.period = None

    def add_callback(self, callback: Callable[[int], None]) -> Callable[[int], None]:
        """callback(counter) for every SYNC on the line (ours included);
        counter 0 when the SYNC has none. Costs one event per SYNC."""
        with self.line._cond:
            self._callbacks.add(callback)
            if not self._listening:
                self.line._rt.sync_listen(self.line.index, True,
                                          f"SYNC callbacks of {self.line._where}")
                self._listening = True
        return callback

    def remove_callback(self, callback: Callable[[int], None]) -> None:
        with self.line._cond:
            self._callbacks.remove(callback)
            if not self._callbacks and self._listening:
                self.line._rt.sync_listen(self.line.index, False,
                                          f"SYNC callbacks of {self.line._where}")
                self._listening = False

    def _event(self, counter: int) -> Callable[[], None]:
        return lambda: self._callbacks.fire(counter)


def time_of_day(ms: int, days: int) -> _dt.datetime:
    """The datetime (UTC) of a TIME_OF_DAY: ms after midnight, days since 1984-01-01."""
    return TIME_EPOCH + _dt.timedelta(days=days, milliseconds=ms)


class TimeService:
    """The TIME stamp of a line (`line.time`)."""

    def __init__(self, line: "Line") -> None:
        self.line = line
        self._callbacks = CallbackList(f"line {line.channel!r} TIME")

    def __repr__(self) -> str:
        return f"<TimeService {self.line.channel!r}>"

    def transmit(self, timestamp: Union[None, float, _dt.datetime] = None) -> None:
        """Send a TIME stamp (python-canopen's `network.time.transmit()`):
        `timestamp` a datetime (naive = local time) or seconds since 1970
        (time.time()); default now. The line becomes TIME producer unless the
        local node's 0x1012 says otherwise (then that entry must have bit 30)."""
        where = f"TIME transmit({timestamp!r}) on {self.line._where}"
        if timestamp is None:
            seconds = _dt.datetime.now(_dt.timezone.utc).timestamp()
        elif isinstance(timestamp, _dt.datetime):
            seconds = timestamp.timestamp()
        elif isinstance(timestamp, (int, float)) and not isinstance(timestamp, bool):
            seconds = float(timestamp)
        else:
            raise ConfigurationError(f"{where}: timestamp must be a datetime or seconds "
                                     f"since 1970, got {type(timestamp).__name__}")
        if seconds < TIME_EPOCH.timestamp():
            raise ConfigurationError(f"{where}: CANopen TIME starts on 1984-01-01")
        self.line._rt.time_send(self.line.index, round(seconds * 1_000_000), where)

    def add_callback(self, callback: Callable[[_dt.datetime], None]) \
            -> Callable[[_dt.datetime], None]:
        """callback(datetime, UTC) for every TIME stamp the line receives."""
        return self._callbacks.add(callback)

    def remove_callback(self, callback: Callable[[_dt.datetime], None]) -> None:
        self._callbacks.remove(callback)

    def _event(self, ms: int, days: int) -> Callable[[], None]:
        when = time_of_day(ms, days)
        return lambda: self._callbacks.fire(when)
