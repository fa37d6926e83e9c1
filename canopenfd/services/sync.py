"""SYNC of a line (python-canopen's `network.sync`).

    line.sync.start(0.01, overflow=16)         # SYNC every 10 ms, counter 1..16
    line.sync.add_callback(print)              # callback(counter), 0 = no counter
    line.sync.stop()

With a local node whose OD has 0x1005/0x1006 (0x1007, 0x1019) the SYNC
producer is configured through those entries, as the network would; without,
the line's own SYNC producer runs. The local node's synchronous PDOs follow
every SYNC of the line, ours included.
"""

from __future__ import annotations

from typing import Callable, Optional

from .._binding.constants import EventKind
from .._binding.context import Deferred, LineContext
from .._binding.runtime import Event
from .._aio import LoopArg
from .._callbacks import CallbackList
from ..errors import ConfigurationError

__all__ = ["SyncService"]

_MAX_US = 0xFFFFFFFF


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

    def __init__(self, context: LineContext) -> None:
        self._context = context
        self._callbacks = CallbackList(f"{context.where} SYNC")
        self._listening = False
        #: The producer's period in seconds (None: not producing from here).
        self.period: Optional[float] = None
        context.subscribe(EventKind.SYNC, self._event)

    def __repr__(self) -> str:
        return f"<SyncService {self._context.channel!r} period {self.period}>"

    @property
    def _where(self) -> str:
        return f"SYNC producer of {self._context.where}"

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
        self._context.runtime.sync_producer(self._context.index, period_us, window_us, overflow,
                                            f"start({period!r}) of the {self._where}")
        self.period = period_us / 1e6

    def stop(self) -> None:
        """Stop producing SYNC."""
        self._context.runtime.sync_producer(self._context.index, 0, 0, 0,
                                            f"stop of the {self._where}")
        self.period = None

    def add_callback(self, callback: Callable[[int], None],
                     loop: LoopArg = None) -> Callable[[int], None]:
        """callback(counter) for every SYNC on the line (ours included);
        counter 0 when the SYNC has none. Costs one event per SYNC."""
        context = self._context
        with context.cond:
            self._callbacks.add(callback, loop)
            if not self._listening:
                context.runtime.sync_listen(context.index, True,
                                            f"SYNC callbacks of {context.where}")
                self._listening = True
        return callback

    def remove_callback(self, callback: Callable[[int], None]) -> None:
        context = self._context
        with context.cond:
            self._callbacks.remove(callback)
            if not self._callbacks and self._listening:
                context.runtime.sync_listen(context.index, False,
                                            f"SYNC callbacks of {context.where}")
                self._listening = False

    def _event(self, event: Event) -> Deferred:
        """CO_EV_SYNC: a = the counter (0 = none)."""
        counter = event.a
        return lambda: self._callbacks.fire(counter)
