"""The CiA 303-3 indicators of the local node: a green run LED and a red
error LED (`node.on_led`, `node.leds`).

    node.on_led(lambda led, on, pattern: print(led, on, pattern))
    node.leds.run.pattern          # 'blinking' while PRE-OPERATIONAL

The C stack computes both LEDs from the node's NMT state, the line's
communication events (bus-off: error LED on; warning limit or error passive:
single flash), heartbeat or guarding lost (double flash), SYNC errors (triple
flash), an RPDO past its deadline (quadruple flash) and LSS (flickering), and
times their patterns on its own clock; Python hears each change (on/off or
pattern) while a callback exists: one event per change, about 5 a second
while a LED blinks.
"""

from __future__ import annotations

from typing import Callable, FrozenSet, NamedTuple

from .._binding.constants import EventKind, LedCause, LedPattern, LedWhich
from .._binding.context import Deferred, LineContext, LocalNodeService
from .._binding.runtime import Event
from .._aio import LoopArg
from .._callbacks import CallbackList
from ..errors import ConfigurationError
from .views import LocalNodeView

__all__ = ["LedIndicator", "LedStates", "LocalLeds", "LED_PATTERNS"]

#: Every pattern's name, as callbacks and `LedIndicator.pattern` give it.
LED_PATTERNS = tuple(pattern.name.lower() for pattern in LedPattern)

LedCallback = Callable[[str, bool, str], None]


def _pattern_name(code: int) -> str:
    try:
        return LedPattern(code).name.lower()
    except ValueError:   # a pattern newer than this module: still say which
        return f"pattern {code}"


class LedIndicator(NamedTuple):
    """One LED now: its pattern ('off', 'on', 'flickering', 'blinking',
    'single_flash', 'double_flash', 'triple_flash', 'quadruple_flash') and
    whether it is lit at this moment."""

    pattern: str
    on: bool


class LedStates(NamedTuple):
    """Both LEDs, and the error causes active ('bus_off', 'warning',
    'error_control', 'sync', 'event_timer', 'config')."""

    run: LedIndicator
    error: LedIndicator
    causes: FrozenSet[str]


_DARK = LedStates(LedIndicator("off", False), LedIndicator("off", False), frozenset())


class LocalLeds(LocalNodeService):
    """The LEDs of our local node (events CO_EV_LED while a callback exists)."""

    def __init__(self, context: LineContext, node: LocalNodeView) -> None:
        self._context = context
        self.node = node
        self._callbacks = CallbackList(f"{context.where} LED callbacks")
        self._listening = False
        context.subscribe(EventKind.LED, self._event)

    def __repr__(self) -> str:
        return f"<LocalLeds of {self.node!r}>"

    def add_callback(self, callback: LedCallback, loop: LoopArg = None) -> LedCallback:
        """callback(led, on, pattern) for every change of either LED: led is
        'run' or 'error', on whether it is lit now, pattern its pattern's
        name (see LedIndicator). Registered before boot, it hears the boot."""
        context = self._context
        with context.cond:
            self._callbacks.add(callback, loop)
            if not self._listening:
                context.runtime.led_listen(context.index, True, f"LED callbacks of {self._where}")
                self._listening = True
        return callback

    def remove_callback(self, callback: LedCallback) -> None:
        context = self._context
        with context.cond:
            self._callbacks.remove(callback)
            if not self._callbacks and self._listening:
                context.runtime.led_listen(context.index, False,
                                           f"LED callbacks of {self._where}")
                self._listening = False

    @property
    def states(self) -> LedStates:
        """What both LEDs show now (both off before the node booted)."""
        if not self.node.booted:
            return _DARK
        context = self._context
        patterns, lit, causes = context.runtime.led_state(context.index,
                                                          f"LED state of {self._where}")
        return LedStates(LedIndicator(_pattern_name(patterns[LedWhich.RUN]), lit[LedWhich.RUN]),
                         LedIndicator(_pattern_name(patterns[LedWhich.ERROR]),
                                      lit[LedWhich.ERROR]),
                         frozenset(cause.name.lower() for cause in LedCause if causes & cause))

    def set_configuration_error(self, active: bool) -> None:
        """Show (or stop showing) "invalid configuration" on the error LED:
        blinking, below every communication error."""
        if not self.node.booted:
            raise ConfigurationError(f"{self._where}: the node is not booted yet")
        context = self._context
        context.runtime.led_causes(context.index, int(LedCause.CONFIG),
                                   int(LedCause.CONFIG) if active else 0,
                                   f"configuration error LED of {self._where}")

    def _event(self, event: Event) -> Deferred:
        """CO_EV_LED: a = which LED, b = lit, node = its pattern."""
        led = "error" if event.a == LedWhich.ERROR else "run"
        on = bool(event.b)
        pattern = _pattern_name(event.node)
        return lambda: self._callbacks.fire(led, on, pattern)
