"""Flying master (CiA 302-2): several nodes able to be the NMT master agree on
one; `node.flying_master` of a local node.

    me.flying_master.start(priority=0)        # after me booted
    me.flying_master.wait_for("master", timeout=5)   # or "slave"
    me.flying_master.active_master            # node-id of the active master
    me.flying_master.add_callback(print)      # callback(FlymaNotice)

The negotiation runs in C (time slots of a few ms to seconds); a slave that
loses the active master's heartbeat resets the network and a new one is
negotiated.
"""

from __future__ import annotations

from typing import Callable, Dict, NamedTuple, Optional, Union

from .._binding.constants import EventKind, FlymaAction, FlymaEvent, FlymaState
from .._binding.context import Deferred, LineContext
from .._binding.runtime import Event
from .._aio import LoopArg
from .._callbacks import CallbackList, Until
from .._checks import enum_member
from ..errors import ConfigurationError

__all__ = ["FlymaEvent", "FlymaNotice", "FlymaState", "FlyingMaster"]

#: start()'s timing arguments (seconds) -> co_rt_flyma_config_t field, default.
_TIMING = {"detect": ("detect_ms", 0.1), "delay": ("delay_ms", 0.5),
           "priority_slot": ("priority_slot_ms", 1.5), "device_slot": ("device_slot_ms", 0.01),
           "multiple_master": ("multiple_master_ms", 4.0), "capable": ("capable_ms", 0.1)}


class FlymaNotice(NamedTuple):
    """One event: what happened, the state after it, the active master's
    node-id (0: none) and priority; for CAPABLE / CAPABLE_DONE `answers` is
    the number of master-capable nodes that answered."""

    event: FlymaEvent
    state: FlymaState
    master: int
    priority: int

    @property
    def answers(self) -> int:
        return self.priority


class FlyingMaster:
    """The flying-master negotiation of one local node."""

    def __init__(self, context: LineContext) -> None:
        self._context = context
        self._callbacks = CallbackList(f"{context.where} flying master")
        self._state = FlymaState.IDLE
        self._master = 0
        self._capable: Optional[int] = None
        self._capable_asked = 0
        self._capable_done = 0
        context.subscribe(EventKind.FLYMA, self._event)

    def __repr__(self) -> str:
        return f"<FlyingMaster of {self._context.node_where}: {self._state.name.lower()}>"

    def _where(self, call: str) -> str:
        return f"flying master {call} of {self._context.node_where}"

    def start(self, priority: int = 1, *, master_heartbeat: float = 0.0,
              **timing: float) -> None:
        """Take part: priority 0 (highest) .. 255; master_heartbeat: how long a
        slave waits for the active master's heartbeat before it negotiates
        anew (s; 0 = only what 0x1016 says). Timing in seconds: detect (0.1),
        delay (0.5), priority_slot (1.5), device_slot (0.01), multiple_master
        (4.0), capable (0.1); where the node's OD has 0x1F90 / 0x1F91 those
        values are used instead."""
        where = self._where(f"start(priority={priority!r})")
        if isinstance(priority, bool) or not isinstance(priority, int) or \
                not 0 <= priority <= 0xFF:
            raise ConfigurationError(f"{where}: priority must be 0..255, got {priority!r}")
        unknown = set(timing) - set(_TIMING)
        if unknown:
            raise ConfigurationError(f"{where}: unknown timing {sorted(unknown)}; "
                                     f"known: {', '.join(_TIMING)}")
        fields: Dict[str, int] = {}
        for name, (field, default) in _TIMING.items():
            fields[field] = _ms(timing.get(name, default), name, where, allow_zero=False)
        fields["master_heartbeat_ms"] = _ms(master_heartbeat, "master_heartbeat", where,
                                            allow_zero=True)
        self._context.runtime.flyma_start(self._context.index, priority, fields, where)

    def stop(self) -> None:
        self._context.runtime.flyma_stop(self._context.index, self._where("stop"))
        with self._context.cond:
            self._state, self._master = FlymaState.IDLE, 0

    def force(self) -> None:
        """Force a new negotiation (0x76, then 0x72)."""
        self._context.runtime.flyma_act(self._context.index, int(FlymaAction.FORCE),
                                        self._where("force()"))

    def detect_capable(self, timeout: Optional[float] = None) -> int:
        """Ask which nodes can be master (0x75) and wait for the answer window
        (0x1F91:1) to close; the number of nodes that answered (0x74)."""
        self._context.waiter.wait_until(self._ask_capable(), timeout)
        return self._capable or 0

    async def adetect_capable(self, timeout: Optional[float] = None) -> int:
        await self._context.waiter.await_until(self._ask_capable(), timeout)
        return self._capable or 0

    def _ask_capable(self) -> "Until[bool]":
        """Send 0x75; the Until of its answer window closing."""
        where = self._where("detect_capable()")
        with self._context.cond:
            asked = self._capable_asked = self._capable_asked + 1
        self._context.runtime.flyma_act(self._context.index, int(FlymaAction.DETECT_CAPABLE),
                                        where)
        return Until(lambda: self._capable_done >= asked, where,
                     lambda: "the answer window did not close")

    @property
    def state(self) -> FlymaState:
        state, _, _, _ = self._context.runtime.flyma_state(self._context.index,
                                                           self._where("state"))
        return FlymaState(state)

    @property
    def active_master(self) -> Optional[int]:
        """The active master's node-id (this node's own when it is the master), None."""
        _, master, _, _ = self._context.runtime.flyma_state(self._context.index,
                                                            self._where("active_master"))
        return master or None

    @property
    def is_master(self) -> bool:
        return self.state == FlymaState.MASTER

    @property
    def stats(self) -> Dict[str, int]:
        _, _, _, stats = self._context.runtime.flyma_state(self._context.index,
                                                           self._where("stats"))
        return stats

    def wait_for(self, state: Union[FlymaState, str], timeout: Optional[float] = None
                 ) -> Optional[int]:
        """Block until the negotiation reports `state` ('master', 'slave', ...);
        the active master's node-id then. TimeoutError names the state last heard."""
        self._context.waiter.wait_until(self._state_until(state), timeout)
        return self._master or None

    async def await_for(self, state: Union[FlymaState, str], timeout: Optional[float] = None
                        ) -> Optional[int]:
        await self._context.waiter.await_until(self._state_until(state), timeout)
        return self._master or None

    def _state_until(self, state: Union[FlymaState, str]) -> "Until[bool]":
        where = self._where(f"wait_for({state!r})")
        wanted = enum_member(FlymaState, state, "state", where)
        return Until(lambda: self._state == wanted, where,
                     lambda: f"still {self._state.name.lower()}")

    def add_callback(self, callback: Callable[[FlymaNotice], None],
                     loop: LoopArg = None) -> Callable[[FlymaNotice], None]:
        """callback(FlymaNotice) for every event of the negotiation."""
        return self._callbacks.add(callback, loop)

    def remove_callback(self, callback: Callable[[FlymaNotice], None]) -> None:
        self._callbacks.remove(callback)

    def _event(self, event: Event) -> Deferred:
        """CO_EV_FLYMA: node = the state, a = the event, b = master | priority << 8."""
        kind = FlymaEvent(event.a)
        notice = FlymaNotice(kind, FlymaState(event.node), event.b & 0xFF, event.b >> 8)
        self._state = notice.state
        if kind == FlymaEvent.STATE:
            self._master = notice.master
        elif kind == FlymaEvent.CAPABLE_DONE:
            self._capable = notice.answers
            self._capable_done += 1
        self._context.cond.notify_all()
        return lambda: self._callbacks.fire(notice)


def _ms(value: float, name: str, where: str, allow_zero: bool) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or \
            not (0 if allow_zero else 0.001) <= value <= 65.535:
        low = "0" if allow_zero else "0.001"
        raise ConfigurationError(f"{where}: {name} must be {low}..65.535 s, got {value!r}")
    return round(value * 1000)
