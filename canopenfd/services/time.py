"""TIME stamps of a line (python-canopen's `network.time`).

    line.time.transmit()                       # TIME stamp: now (or a datetime)
    line.time.add_callback(print)              # callback(datetime, UTC)
"""

from __future__ import annotations

import datetime as _dt
from typing import Callable, Union

from .._binding.constants import EventKind
from .._binding.context import Deferred, LineContext
from .._binding.runtime import Event
from .._aio import LoopArg
from .._callbacks import CallbackList
from ..errors import ConfigurationError

__all__ = ["TimeService", "TIME_EPOCH", "time_of_day"]

#: Day 0 of the CANopen TIME_OF_DAY (CiA 301): 1984-01-01, UTC.
TIME_EPOCH = _dt.datetime(1984, 1, 1, tzinfo=_dt.timezone.utc)


def time_of_day(ms: int, days: int) -> _dt.datetime:
    """The datetime (UTC) of a TIME_OF_DAY: ms after midnight, days since 1984-01-01."""
    return TIME_EPOCH + _dt.timedelta(days=days, milliseconds=ms)


class TimeService:
    """The TIME stamp of a line (`line.time`)."""

    def __init__(self, context: LineContext) -> None:
        self._context = context
        self._callbacks = CallbackList(f"{context.where} TIME")
        context.subscribe(EventKind.TIME, self._event)

    def __repr__(self) -> str:
        return f"<TimeService {self._context.channel!r}>"

    def transmit(self, timestamp: Union[None, float, _dt.datetime] = None) -> None:
        """Send a TIME stamp (python-canopen's `network.time.transmit()`):
        `timestamp` a datetime (naive = local time) or seconds since 1970
        (time.time()); default now. The line becomes TIME producer unless the
        local node's 0x1012 says otherwise (then that entry must have bit 30)."""
        where = f"TIME transmit({timestamp!r}) on {self._context.where}"
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
        self._context.runtime.time_send(self._context.index, round(seconds * 1_000_000), where)

    def add_callback(self, callback: Callable[[_dt.datetime], None], loop: LoopArg = None) \
            -> Callable[[_dt.datetime], None]:
        """callback(datetime, UTC) for every TIME stamp the line receives."""
        return self._callbacks.add(callback, loop)

    def remove_callback(self, callback: Callable[[_dt.datetime], None]) -> None:
        self._callbacks.remove(callback)

    def _event(self, event: Event) -> Deferred:
        """CO_EV_TIME: a = ms after midnight, b = days since 1984-01-01."""
        when = time_of_day(event.a, event.b)
        return lambda: self._callbacks.fire(when)
