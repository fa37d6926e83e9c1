"""Bus redundancy (the ECSS-E-ST-50-15C scheme CiA 302-6 stands for):
`line.redundancy`. A line runs on two buses, its own (A) and a redundant one
(B), and uses one at a time: an in-process line ('mem:NAME') with another
in-process bus, a SocketCAN line with another interface ('vcan1', 'can1').

    line.redundancy.start("mem:busB", "slave", master=1, period=0.1,
                          ttoggle=3, ntoggle=4)     # follow node 1's heartbeat
    line.redundancy.add_callback(print)             # callback(RedundancyNotice)
    line.redundancy.wait_for_bus("B", timeout=2)

A slave starts on its default bus and follows the redundancy master's
heartbeat: after `ttoggle` heartbeat periods without it, it moves to the
other bus, again every `ttoggle` periods, and after `ntoggle` moves it stays
(that bus becomes its default) and reports NO_MASTER. The master chooses the
bus itself (`select`). The C core decides; see docs/protocol-notes.md.
"""

from __future__ import annotations

from typing import Callable, Dict, NamedTuple, Optional

from .._binding.constants import EventKind, RedundancyEvent
from .._binding.context import Deferred, LineContext
from .._binding.runtime import Event
from .._callbacks import CallbackList
from ..errors import ConfigurationError

__all__ = ["BusRedundancy", "RedundancyEvent", "RedundancyNotice"]

_BUSES = ("A", "B")
_ROLES = ("master", "slave")
_OBJECT_SUBS = ("Bdefault", "Ttoggle", "Ntoggle", "Ctoggle")


class RedundancyNotice(NamedTuple):
    """A switch (BUS_SWITCH) or a slave giving up (NO_MASTER): the bus in use
    after it ('A' or 'B') and the switches since the master was last heard."""

    event: RedundancyEvent
    bus: str
    switches: int


def _bus(value: str, where: str) -> int:
    if value not in _BUSES:
        raise ConfigurationError(f"{where}: bus must be 'A' (the line's own) or 'B' "
                                 f"(the redundant one), got {value!r}")
    return _BUSES.index(value)


def _count(value: int, name: str, low: int, where: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= 0xFF:
        raise ConfigurationError(f"{where}: {name} must be an int {low}..255, got {value!r}")
    return value


class BusRedundancy:
    """Bus redundancy of one in-process line, as redundancy master or slave."""

    def __init__(self, context: LineContext) -> None:
        self._context = context
        self._callbacks = CallbackList(f"{context.where} redundancy")
        self._role: Optional[str] = None
        self._bus: Optional[str] = None
        context.subscribe(EventKind.REDUNDANCY, self._event)

    def __repr__(self) -> str:
        return f"<BusRedundancy {self._context.channel!r} {self._role or 'off'}>"

    def _where(self, call: str) -> str:
        return f"redundancy {call} on {self._context.where}"

    def start(self, redundant: str, role: str = "slave", *, master: int = 0,
              period: float = 0.0, default: str = "A", ttoggle: int = 0,
              ntoggle: int = 1) -> None:
        """Run on the line's own bus (A) and `redundant` (B: 'mem:NAME' for an
        in-process line, an interface name for a SocketCAN line), starting on
        `default`. A slave follows node `master`'s heartbeat
        (its period in s); ttoggle: periods without it before a switch
        (0: never switch); ntoggle: switches before it stays (1..255)."""
        where = self._where(f"start({redundant!r}, {role!r})")
        if role not in _ROLES:
            raise ConfigurationError(f"{where}: role must be 'master' or 'slave', got {role!r}")
        in_process = self._context.channel.startswith("mem:")
        if in_process and (not isinstance(redundant, str) or not redundant.startswith("mem:")
                           or len(redundant) == 4):
            raise ConfigurationError(f"{where}: the redundant bus of an in-process line must "
                                     f"be 'mem:NAME', got {redundant!r}")
        if not in_process and (not isinstance(redundant, str) or not redundant.strip()
                               or redundant.startswith("mem:")):
            raise ConfigurationError(f"{where}: the redundant bus of a SocketCAN line must be "
                                     f"an interface name, got {redundant!r}")
        values = {"bdefault": _bus(default, where),
                  "ttoggle": _count(ttoggle, "ttoggle", 0, where),
                  "ntoggle": _count(ntoggle, "ntoggle", 1, where)}
        if role == "slave":
            if isinstance(master, bool) or not isinstance(master, int) or \
                    not 1 <= master <= 127:
                raise ConfigurationError(f"{where}: master must be the redundancy master's "
                                         f"node-id 1..127, got {master!r}")
            if isinstance(period, bool) or not isinstance(period, (int, float)) or \
                    not 0 < period <= 65.535:
                raise ConfigurationError(f"{where}: period must be the master's heartbeat "
                                         f"period in s, 0.001..65.535, got {period!r}")
            values.update(master_id=master, master_period_ms=max(1, round(period * 1000)))
        self._context.runtime.redundancy_start(self._context.index,
                                               redundant[4:] if in_process else redundant,
                                               role == "master", values, where)
        self._role = role
        self._bus = default

    @property
    def role(self) -> Optional[str]:
        """'master', 'slave' or None (not started)."""
        return self._role

    def select(self, bus: str) -> None:
        """Master: use `bus` ('A' or 'B') from now on."""
        where = self._where(f"select({bus!r})")
        self._context.runtime.redundancy_select(self._context.index, _bus(bus, where), where)

    @property
    def active_bus(self) -> str:
        """The bus in use now: 'A' (the line's own) or 'B' (asked of the runtime)."""
        active, _ = self._context.runtime.redundancy_state(self._context.index,
                                                           self._where("active_bus"))
        return _BUSES[active]

    @property
    def object(self) -> Dict[str, int]:
        """The redundancy object: Bdefault (0 A, 1 B), Ttoggle, Ntoggle, Ctoggle."""
        _, subs = self._context.runtime.redundancy_state(self._context.index,
                                                         self._where("object"))
        return dict(zip(_OBJECT_SUBS, subs[1:]))

    def wait_for_bus(self, bus: str, timeout: Optional[float] = None) -> str:
        """Block until a switch to `bus` is reported (or it is in use already);
        TimeoutError names the bus in use."""
        where = self._where(f"wait_for_bus({bus!r})")
        _bus(bus, where)
        self._context.waiter.wait(lambda: self._bus == bus, timeout, where,
                                  lambda: f"still on bus {self._bus}")
        return bus

    def add_callback(self, callback: Callable[[RedundancyNotice], None]
                     ) -> Callable[[RedundancyNotice], None]:
        """callback(RedundancyNotice) for every switch and for NO_MASTER."""
        return self._callbacks.add(callback)

    def remove_callback(self, callback: Callable[[RedundancyNotice], None]) -> None:
        self._callbacks.remove(callback)

    def _event(self, event: Event) -> Deferred:
        """CO_EV_REDUNDANCY: node = the bus now active, a = the event, b = Ctoggle."""
        self._bus = _BUSES[event.node]
        self._context.cond.notify_all()
        notice = RedundancyNotice(RedundancyEvent(event.a), self._bus, event.b)
        return lambda: self._callbacks.fire(notice)
