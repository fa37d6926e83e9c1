"""Node guarding (classic lines): what it tells about a guarded node.

    drive.guard(100, 3)                        # guard node every 100 ms, 3 misses = lost
    drive.add_guard_callback(print)            # callback(GuardEvent, NmtState)
"""

from __future__ import annotations

import enum
import logging
from typing import Callable, List, Optional

from .._binding.constants import EventKind, GuardEventCode, NmtState
from .._binding.context import Deferred, LineContext
from .._binding.runtime import Event
from .._aio import LoopArg
from .._callbacks import CallbackList, chain
from .._checks import check_ms
from ..errors import ConfigurationError
from .nmt import HeartbeatMonitor, remote_state_of

__all__ = ["GuardEvent", "NodeGuard"]

log = logging.getLogger(__name__)


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


class NodeGuard:
    """Node guarding of one remote node (classic lines): the runtime's guarding
    master sends the remote frames; events GUARD of the node come here. Lost
    and regained guarding and the states answered also go to the node's
    HeartbeatMonitor, as heartbeats would."""

    def __init__(self, context: LineContext, node_id: int, where: str,
                 monitor: HeartbeatMonitor) -> None:
        self._context = context
        self.node_id = node_id
        self._where = where
        self._monitor = monitor
        #: The runtime guards the node now.
        self.guarded = False
        self._callbacks = CallbackList(f"node {node_id} guarding")
        context.subscribe(EventKind.GUARD, self._event, node=node_id)

    def guard(self, guard_time_ms: int, life_time_factor: int,
              heartbeat_watched: bool = False) -> None:
        where = f"guard({guard_time_ms!r}, {life_time_factor!r}) of {self._where}"
        if self._context.mode != "classic":
            raise ConfigurationError(f"{where}: node guarding needs a classic line (CAN FD "
                                     "has no remote frames); use the heartbeat "
                                     "(heartbeat_timeout_ms)")
        check_ms(guard_time_ms, "guard_time_ms", where)
        if guard_time_ms == 0:
            raise ConfigurationError(f"{where}: guard_time_ms must be 1..65535 (unguard() "
                                     "stops guarding)")
        if isinstance(life_time_factor, bool) or not isinstance(life_time_factor, int) or \
                not 1 <= life_time_factor <= 255:
            raise ConfigurationError(f"{where}: life_time_factor must be an int 1..255, got "
                                     f"{life_time_factor!r}")
        if not self.guarded and (heartbeat_watched or self._monitor.alive):
            log.warning("%s: node %d %s heartbeats; CiA 301 has a node use one error control "
                        "method, and a device whose heartbeat producer (0x1017) runs does not "
                        "answer guarding: expect false losses (set heartbeat_timeout_ms and "
                        "drop guarding, or switch its heartbeat off)", where, self.node_id,
                        "sends" if self._monitor.alive else "is watched for")
        self._context.runtime.guard(self._context.index, self.node_id, guard_time_ms,
                                    life_time_factor, where)
        self.guarded = True

    def unguard(self) -> None:
        where = f"unguard() of {self._where}"
        if self._context.mode != "classic":
            raise ConfigurationError(f"{where}: node guarding needs a classic line")
        self._stop(where)

    def release(self, what: str) -> None:
        """The node is removed: stop guarding it if it is guarded."""
        if self.guarded:
            self._stop(what)

    def _stop(self, what: str) -> None:
        self._context.runtime.guard(self._context.index, self.node_id, 0, 0, what)
        self.guarded = False

    def add_callback(self, callback: Callable[[GuardEvent, NmtState], None],
                     loop: LoopArg = None) -> Callable[[GuardEvent, NmtState], None]:
        return self._callbacks.add(callback, loop)

    def _event(self, event: Event) -> Deferred:
        """CO_EV_GUARD of this node: a = co_guard_event_t, b = the state answered."""
        kind = GuardEvent.from_code(event.a)
        if kind is None:
            return None
        state = remote_state_of(event.b)
        calls: List[Callable[[], None]] = [lambda: self._callbacks.fire(kind, state)]
        if kind is GuardEvent.LOST:
            calls.append(self._monitor.guard_lost())
        elif kind in (GuardEvent.STARTED, GuardEvent.RESUMED):
            calls.append(self._monitor.guard_alive())
        if kind in (GuardEvent.STARTED, GuardEvent.STATE_CHANGED, GuardEvent.RESUMED):
            changed = self._monitor.state_seen(state)
            if changed is not None:
                calls.append(changed)
        return chain(calls)
