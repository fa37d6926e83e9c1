"""MPDOs received by the local node, told to the application
(`node.on_mpdo`): one `MpdoNotice` per MPDO addressed to the node, applied
to its OD or refused.

    node.on_mpdo(lambda notice: print(notice))

The C runtime posts CO_EV_MPDO only while a callback exists. Under a flood
the event queue merges the notices of one multiplexer (address byte,
index, sub) once it is 3/4 full, as it does for PDOs: the latest notice is
kept and `coalesced` counts the older ones it replaced, so Python never
falls behind the bus; the counters (`node.mpdo_stats()`) still count every
frame.
"""

from __future__ import annotations

from typing import Callable, NamedTuple, Optional

from .._aio import LoopArg
from .._binding.constants import EventKind
from .._binding.context import Deferred, LineContext, LocalNodeService
from .._binding.runtime import Event
from .._callbacks import CallbackList

__all__ = ["MpdoNotice", "LocalMpdo"]

_DAM_BIT = 0x80


class MpdoNotice(NamedTuple):
    """One MPDO addressed to the local node. mode 'DAM' (node = the
    destination in the frame: ours or 0 = all) or 'SAM' (node = the
    producer); frame_index:frame_sub as the frame names them,
    local_index:local_sub the object written here (a SAM's from the dispatcher list; the frame's when
    no list entry names it); data the frame's 4 value bytes; abort 0 when
    applied, else the CiA 301 abort code of the refused write (0x06020000:
    no such object, or a SAM no dispatcher entry names); rpdo the RPDO that
    carried it; coalesced how many older notices of the same multiplexer
    this one replaced."""

    mode: str
    node: int
    frame_index: int
    frame_sub: int
    local_index: int
    local_sub: int
    data: bytes
    abort: int
    rpdo: int
    coalesced: int = 0

    @property
    def applied(self) -> bool:
        return self.abort == 0


MpdoCallback = Callable[[MpdoNotice], None]


def notice_from_event(event: Event) -> Optional[MpdoNotice]:
    """CO_EV_MPDO: a = address byte << 24 | index << 8 | sub, b = abort,
    data = the 8 frame bytes, RPDO (2 LE), local index (2 LE), local sub."""
    data = event.data
    if len(data) < 13:
        return None          # not laid out as co_rt_mpdo.c posts it
    address = event.a >> 24
    return MpdoNotice("DAM" if address & _DAM_BIT else "SAM", address & 0x7F,
                      (event.a >> 8) & 0xFFFF, event.a & 0xFF,
                      int.from_bytes(data[10:12], "little"), data[12], bytes(data[4:8]),
                      event.b, int.from_bytes(data[8:10], "little"), event.coalesced)


class LocalMpdo(LocalNodeService):
    """The local node's received MPDOs (events CO_EV_MPDO while a callback exists)."""

    def __init__(self, context: LineContext) -> None:
        self._context = context
        self._callbacks = CallbackList(f"{context.where} MPDO callbacks")
        self._listening = False
        context.subscribe(EventKind.MPDO, self._event)

    def add_callback(self, callback: MpdoCallback, loop: LoopArg = None) -> MpdoCallback:
        context = self._context
        with context.cond:
            self._callbacks.add(callback, loop)
            if not self._listening:
                context.runtime.mpdo_listen(context.index, True,
                                            f"MPDO callbacks of {self._where}")
                self._listening = True
        return callback

    def remove_callback(self, callback: MpdoCallback) -> None:
        context = self._context
        with context.cond:
            self._callbacks.remove(callback)
            if not self._callbacks and self._listening:
                context.runtime.mpdo_listen(context.index, False,
                                            f"MPDO callbacks of {self._where}")
                self._listening = False

    def _event(self, event: Event) -> Deferred:
        notice = notice_from_event(event)
        return (lambda: self._callbacks.fire(notice)) if notice is not None else None
