"""Sleep and wake-up of a network (CiA 320, the sleep mode of battery powered
CiA 454 and CiA 447 networks): `line.sleep`.

    line.sleep.start("master")                 # or "device" (objection=reason)
    line.sleep.add_callback(print)             # callback(SleepNotice)
    line.sleep.check()                         # ask the devices, then sleep unless one objects
    line.sleep.wait_for("asleep", timeout=5)
    line.sleep.wake(status=0x10, reason=0x01)  # wake-up message, reset communication

The C core runs the phases (prepare, silent, asleep) on its own clock; a
device answers the master's query with the standing `objection` (0 = agree),
since the answer is due while the frame is handled, without Python.
"""

from __future__ import annotations

from typing import Callable, Dict, NamedTuple, Optional, Tuple, Union

from .._binding.constants import EventKind, SleepAction, SleepCause, SleepEvent, SleepPhase
from .._binding.context import Deferred, LineContext
from .._binding.runtime import Event
from .._aio import LoopArg
from .._callbacks import CallbackList, Until
from .._checks import enum_member
from ..errors import ConfigurationError

__all__ = ["SleepCause", "SleepEvent", "SleepNotice", "SleepPhase", "SleepService"]

_ROLES = ("master", "device")


class SleepNotice(NamedTuple):
    """One event of the sleep service: what happened, the phase after it, and
    its values: the objection's reason (OBJECTION), the cause (WAKE,
    a SleepCause), another node's wake-up status and reason (WAKE_MESSAGE),
    the phase refused (REFUSED)."""

    event: SleepEvent
    phase: SleepPhase
    value: int
    reason: int


def _ms(value: float, name: str, where: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or \
            not 0 <= value <= 60:
        raise ConfigurationError(f"{where}: {name} must be 0..60 s, got {value!r}")
    return round(value * 1000)


def _byte(value: int, name: str, where: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 0xFF:
        raise ConfigurationError(f"{where}: {name} must be 0..255, got {value!r}")
    return value


class SleepService:
    """Sleep and wake-up on one line, as power management master or device."""

    def __init__(self, context: LineContext) -> None:
        self._context = context
        self._callbacks = CallbackList(f"{context.where} sleep")
        self._role: Optional[str] = None
        self._objection = 0
        self._phase = SleepPhase.AWAKE
        context.subscribe(EventKind.SLEEP, self._event)

    def __repr__(self) -> str:
        return f"<SleepService {self._context.channel!r} {self._role or 'off'}>"

    def _where(self, call: str) -> str:
        return f"sleep {call} on {self._context.where}"

    # ------------------------------------------------------------ set-up
    def start(self, role: str = "device", *, check: float = 1.0, prepare: float = 1.0,
              silent: float = 1.0, wake_repeat: float = 0.0, objection: int = 0) -> None:
        """Take part in sleep and wake-up: as 'master' (asks, commands) or
        'device'. check: how long the master waits for objections; prepare:
        from the sleep command to silent; silent: from silent to asleep (s);
        wake_repeat: send the wake-up message once more after this (0: once);
        objection (device): the reason answered to queries, 0 = agree."""
        where = self._where(f"start({role!r})")
        if role not in _ROLES:
            raise ConfigurationError(f"{where}: role must be 'master' or 'device'")
        check_ms, prepare_ms, silent_ms = (_ms(value, name, where) for name, value in
                                           (("check", check), ("prepare", prepare),
                                            ("silent", silent)))
        if 0 in (check_ms, prepare_ms, silent_ms):
            raise ConfigurationError(f"{where}: check, prepare and silent must be > 0 s")
        self._context.runtime.sleep_start(self._context.index, role == "master", check_ms,
                                          prepare_ms, silent_ms,
                                          _ms(wake_repeat, "wake_repeat", where),
                                          _byte(objection, "objection", where), where)
        self._role = role
        self._objection = objection

    def stop(self) -> None:
        """Leave sleep and wake-up (a silent line sends again)."""
        self._context.runtime.sleep_stop(self._context.index, self._where("stop"))
        self._role = None

    @property
    def role(self) -> Optional[str]:
        """'master', 'device' or None (not started)."""
        return self._role

    @property
    def objection(self) -> int:
        """The device's answer to the master's queries: a reason 1..255
        objects, 0 agrees."""
        return self._objection

    @objection.setter
    def objection(self, reason: int) -> None:
        where = self._where("objection")
        self._context.runtime.sleep_objection(self._context.index,
                                              _byte(reason, "objection", where), where)
        self._objection = reason

    # ------------------------------------------------------------ actions
    def _act(self, action: SleepAction, call: str, status: int = 0, reason: int = 0) -> None:
        where = self._where(call)
        self._context.runtime.sleep_act(self._context.index, int(action),
                                        _byte(status, "status", where),
                                        _byte(reason, "reason", where), where)

    def check(self) -> None:
        """Master: ask every device; without an objection within `check`,
        the sleep command goes out and the network sleeps."""
        self._act(SleepAction.CHECK, "check()")

    def sleep(self) -> None:
        """Master: the sleep command now, without asking. Device: sleep alone."""
        self._act(SleepAction.START, "sleep()")

    def request(self) -> None:
        """Device: ask the master for sleep."""
        self._act(SleepAction.REQUEST, "request()")

    def wake(self, status: int = 0, reason: int = 0) -> None:
        """Wake up: the line sends again, the wake-up message [status, reason]
        goes out and the local node resets its communication."""
        self._act(SleepAction.WAKE, f"wake({status}, {reason})", status, reason)

    # ------------------------------------------------------------ state
    @property
    def phase(self) -> SleepPhase:
        """The phase now (asked of the runtime)."""
        phase, _ = self._context.runtime.sleep_state(self._context.index, self._where("phase"))
        return SleepPhase(phase)

    @property
    def stats(self) -> Dict[str, int]:
        """Frames sent and received by kind, malformed and ignored ones."""
        _, stats = self._context.runtime.sleep_state(self._context.index, self._where("stats"))
        return stats

    def _phase_until(self, phase: Union[SleepPhase, str]
                     ) -> "Tuple[Until[bool], SleepPhase]":
        where = self._where(f"wait_for({phase!r})")
        wanted = enum_member(SleepPhase, phase, "phase", where)
        return Until(lambda: self._phase == wanted, where,
                     lambda: f"still {self._phase.name.lower()}"), wanted

    def wait_for(self, phase: Union[SleepPhase, str], timeout: Optional[float] = None
                 ) -> SleepPhase:
        """Block until the service reports `phase` (a SleepPhase or its name,
        e.g. 'asleep'); TimeoutError names the phase last heard."""
        until, wanted = self._phase_until(phase)
        self._context.waiter.wait_until(until, timeout)
        return wanted

    async def await_for(self, phase: Union[SleepPhase, str], timeout: Optional[float] = None
                        ) -> SleepPhase:
        until, wanted = self._phase_until(phase)
        await self._context.waiter.await_until(until, timeout)
        return wanted

    def add_callback(self, callback: Callable[[SleepNotice], None],
                     loop: LoopArg = None) -> Callable[[SleepNotice], None]:
        """callback(SleepNotice) for every event of the line's sleep service."""
        return self._callbacks.add(callback, loop)

    def remove_callback(self, callback: Callable[[SleepNotice], None]) -> None:
        self._callbacks.remove(callback)

    def _event(self, event: Event) -> Deferred:
        """CO_EV_SLEEP: node = the phase after it, a = the event, b = arg | arg2 << 8."""
        kind = SleepEvent(event.a)
        self._phase = SleepPhase(event.node)
        value, reason = event.b & 0xFF, event.b >> 8
        if kind == SleepEvent.WAKE:
            value = SleepCause(value)
        self._context.cond.notify_all()
        notice = SleepNotice(kind, self._phase, value, reason)
        return lambda: self._callbacks.fire(notice)
