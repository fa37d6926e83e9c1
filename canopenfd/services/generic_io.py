"""The runtime side of a CiA 401 generic I/O device: `node.generic_io`.

The device is C (csrc/core/co_cia401_od.c, run by co_stack over the local
node's OD): it keeps its channels equal to the OD's profile objects, writes
the inputs the application reports and triggers their TPDOs, moves the
outputs on every write of 0x6200/0x6411 (SDO, USDO, RPDO, local) and
applies the error values on NMT stop or a fault, all in the runtime thread.
This service starts it, hands it the application's inputs (one runtime call
each) and tells every change of the physical outputs (CO_EV_CIA401). The
profile's application API is `canopenfd.profiles.cia401.IoDevice`.
"""

from __future__ import annotations

from typing import Callable, NamedTuple, Tuple

from .._binding.constants import EventKind
from .._binding.context import Deferred, LineContext, LocalNodeService
from .._binding.runtime import Event
from .._callbacks import CallbackList

__all__ = ["GenericIo", "OutputChange"]

_DIGITAL, _ANALOG = 0x01, 0x02   # CO_CIA401_OUT_*


class OutputChange(NamedTuple):
    """One kind of output after a write: kind 'digital' (levels: one int per
    group of 8, bit n = output 8 * group + n + 1) or 'analog' (one value per
    channel); last is False when the same write also changed the other
    kind, whose change follows."""

    kind: str
    levels: Tuple[int, ...]
    last: bool


def _change(event: Event) -> OutputChange:
    if event.node == _DIGITAL:
        levels = tuple(event.data[:event.b])
    else:
        levels = tuple(int.from_bytes(event.data[2 * i:2 * i + 2], "little", signed=True)
                       for i in range(event.b))
    last = event.node == _ANALOG or not event.a & _ANALOG
    return OutputChange("digital" if event.node == _DIGITAL else "analog", levels, last)


class GenericIo(LocalNodeService):
    """Start (once) the CiA 401 device of a local node and drive it."""

    def __init__(self, context: LineContext) -> None:
        self._context = context
        self._changes = CallbackList(f"{context.where} generic I/O outputs")
        self.running = False

    def start(self) -> None:
        """Run the device over the node's OD (booted, holding the profile
        objects: a wrong one is named in the ConfigurationError)."""
        where = f"{self._where}: CiA 401 device start()"
        self._context.runtime.cia401_start(self._context.index, where)
        if not self.running:
            self._context.subscribe(EventKind.CIA401, self._event)
        self.running = True

    def set_inputs(self, first: int, raw: bytes) -> None:
        """Raw levels of input groups first.. (1-based), one byte each."""
        self._context.runtime.cia401_set_inputs(self._context.index, first, raw,
                                                f"{self._where}: set_inputs")

    def set_analog_input(self, channel: int, value: int) -> None:
        self._context.runtime.cia401_set_analog_input(self._context.index, channel, value,
                                                      f"{self._where}: set_analog_input")

    def fault(self) -> None:
        """A device fault: outputs with an error mode take their error value."""
        self._context.runtime.cia401_fault(self._context.index, f"{self._where}: fault()")

    def outputs(self, groups: int, channels: int) -> Tuple[bytes, Tuple[int, ...]]:
        """The physical outputs now: `groups` digital bytes, `channels` values."""
        return self._context.runtime.cia401_outputs(self._context.index, groups, channels,
                                                    f"{self._where}: outputs")

    def on_change(self, callback: Callable[[OutputChange], None]
                  ) -> Callable[[OutputChange], None]:
        """callback(OutputChange) after every write that moved an output."""
        return self._changes.add(callback)

    def _event(self, event: Event) -> Deferred:
        change = _change(event)
        return lambda: self._changes.fire(change)
