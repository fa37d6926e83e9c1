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
bus itself (`select`), or, with switch_on_failure, moves on bus-off or
interface down. The C core decides; see docs/protocol-notes.md.

When the local node's OD has the redundancy record (`redundancy_record()`,
at 0x2000 unless `index` says otherwise), its Bdefault / Ttoggle / Ntoggle
are the ones used and a tool reads and writes them by SDO (or USDO); the
core keeps Ctoggle and Bdefault there up to date.
"""

from __future__ import annotations

from typing import Callable, Dict, NamedTuple, Optional

from .._binding.constants import EventKind, RedundancyEvent
from .._binding.context import Deferred, LineContext
from .._binding.runtime import Event
from .._callbacks import CallbackList
from ..errors import ConfigurationError
from ..od import DataType, ODRecord, ODVariable

__all__ = ["BusRedundancy", "RedundancyEvent", "RedundancyNotice", "redundancy_record",
           "RECORD_INDEX"]

RECORD_INDEX = 0x2000   # a manufacturer index: the standard's is not public (CO_RDN_OBJECT_DEFAULT)

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


def redundancy_record(index: int = RECORD_INDEX, default: str = "A", ttoggle: int = 0,
                      ntoggle: int = 1) -> ODRecord:
    """The redundancy record to add to a local node's OD (od.add_object):
    sub 1 Bdefault (0 A, 1 B), 2 Ttoggle, 3 Ntoggle (rw), 4 Ctoggle (ro),
    every one UNSIGNED8."""
    where = f"redundancy_record(0x{index:04X})" if isinstance(index, int) else \
        "redundancy_record"
    if isinstance(index, bool) or not isinstance(index, int) or not 0x2000 <= index <= 0x5FFF:
        raise ConfigurationError(f"{where}: index must be a manufacturer index "
                                 f"0x2000..0x5FFF, got {index!r}")
    values = (_bus(default, where), _count(ttoggle, "ttoggle", 0, where),
              _count(ntoggle, "ntoggle", 1, where), 0)
    u8 = DataType.UNSIGNED8
    record = ODRecord("Bus redundancy", index)
    record.add_member(ODVariable("Highest sub-index supported", index, 0, u8, "ro", 4))
    for sub, (name, value) in enumerate(zip(_OBJECT_SUBS, values), start=1):
        record.add_member(ODVariable(name, index, sub, u8, "ro" if sub == 4 else "rw", value))
    return record


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
              period: float = 0.0, default: Optional[str] = None,
              ttoggle: Optional[int] = None, ntoggle: Optional[int] = None,
              index: int = RECORD_INDEX, switch_on_failure: bool = False) -> None:
        """Run on the line's own bus (A) and `redundant` (B: 'mem:NAME' for an
        in-process line, an interface name for a SocketCAN line), starting on
        the default bus. A slave follows node `master`'s heartbeat
        (its period in s); ttoggle: periods without it before a switch
        (0: never switch); ntoggle: switches before it stays (1..255).

        default / ttoggle / ntoggle (A, 0 and 1 when not given) are for a
        node whose OD has no redundancy record at `index`; when it has one
        they come from there and giving them is an error. A master with
        switch_on_failure moves to the other bus when the line reports
        bus-off or interface down."""
        where = self._where(f"start({redundant!r}, {role!r})")
        if role not in _ROLES:
            raise ConfigurationError(f"{where}: role must be 'master' or 'slave', got {role!r}")
        self._check_redundant(redundant, where)
        if not isinstance(switch_on_failure, bool) or (switch_on_failure and role != "master"):
            raise ConfigurationError(f"{where}: switch_on_failure is for the master (a bool), "
                                     f"got {switch_on_failure!r} for a {role}")
        if isinstance(index, bool) or not isinstance(index, int) or not 0x1000 <= index <= 0xFFFF:
            raise ConfigurationError(f"{where}: index must be 0x1000..0xFFFF, got {index!r}")
        values = {"bdefault": _bus("A" if default is None else default, where),
                  "ttoggle": _count(0 if ttoggle is None else ttoggle, "ttoggle", 0, where),
                  "ntoggle": _count(1 if ntoggle is None else ntoggle, "ntoggle", 1, where),
                  "values_given": int(any(v is not None for v in (default, ttoggle, ntoggle))),
                  "index": index, "switch_on_failure": int(switch_on_failure)}
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
        in_process = self._context.channel.startswith("mem:")
        self._context.runtime.redundancy_start(self._context.index,
                                               redundant[4:] if in_process else redundant,
                                               role == "master", values, where)
        self._role = role
        self._bus = self.active_bus   # the OD's Bdefault when it has the record

    def _check_redundant(self, redundant: str, where: str) -> None:
        in_process = self._context.channel.startswith("mem:")
        if in_process and (not isinstance(redundant, str) or not redundant.startswith("mem:")
                           or len(redundant) == 4):
            raise ConfigurationError(f"{where}: the redundant bus of an in-process line must "
                                     f"be 'mem:NAME', got {redundant!r}")
        if not in_process and (not isinstance(redundant, str) or not redundant.strip()
                               or redundant.startswith("mem:")):
            raise ConfigurationError(f"{where}: the redundant bus of a SocketCAN line must be "
                                     f"an interface name, got {redundant!r}")

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
