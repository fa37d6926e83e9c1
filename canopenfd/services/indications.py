"""Indications of a local node's object dictionary, answered in Python.

A network read (before-read) or write (check-write) of a watched entry waits
in the C stack until Python answers it, so a callback can refresh a value
before it is read, refuse a write with a CiA abort code before anything
changes, or answer later from another thread (split indication). The C
runtime never calls Python: it parks the access and posts an event; the
answer resumes the access and sends the SDO/USDO answer.
"""

from __future__ import annotations

import logging
import threading
from typing import Callable, Dict, List, Optional, Tuple, Union

from .._binding.constants import AbortCode, EventKind, Indicate
from .._binding.context import Deferred, LineContext, LocalNodeService
from .._binding.runtime import Event
from ..errors import AbortError, ConfigurationError
from ..od import ODVariable
from ..od.datatypes import Value
from .served_od import Key, ServedDictionary
from .views import LocalNodeView

log = logging.getLogger(__name__)

#: CiA 301 "general error": what a callback that raised anything but AbortError answers.
GENERAL_ERROR = int(AbortCode.GENERAL)

READ = int(Indicate.READ)
WRITE = int(Indicate.WRITE)
_KIND_NAMES = {READ: "read", WRITE: "write"}

#: What a callback returns: None (accept), an abort code, or the deferred request.
Answer = Union[None, int, "ODRequest"]
Callback = Callable[["ODRequest"], Answer]


class ODRequest:
    """One network access waiting on the application.

    Callbacks get it as their only argument. Returning None accepts (the next
    callback of the entry runs, then the access goes on); returning an int or
    raising AbortError refuses it with that CiA abort code; any other
    exception refuses it with 0x08000000 (and is logged). `defer()` keeps the
    access waiting after the callback returned: answer it later, from any
    thread, with `accept()` or `refuse(code)`. Several callbacks on one entry
    run in registration order and the first refusal wins (test, then execute).
    """

    def __init__(self, context: LineContext, served: ServedDictionary, variable: ODVariable,
                 kind: int, token: int, callbacks: List[Callback]) -> None:
        self._context = context
        self._served = served
        self.node = served.node
        #: The ODVariable accessed.
        self.variable = variable
        #: 'read' or 'write'.
        self.kind = _KIND_NAMES.get(kind, str(kind))
        self._token = token
        self._callbacks = callbacks
        self._next = 0
        self._deferred = False
        self._answered = False
        self._lock = threading.Lock()
        self._data: Optional[bytes] = None

    def __repr__(self) -> str:
        return (f"<ODRequest {self.kind} {self.variable.where} {self.variable.qualname!r} "
                f"on node {self.node.node_id}>")

    @property
    def index(self) -> int:
        return self.variable.index

    @property
    def subindex(self) -> int:
        return self.variable.subindex

    @property
    def data(self) -> bytes:
        """A write: the bytes the network wants to write. A read: the entry's
        current bytes (what will be sent unless a callback changes the value)."""
        if self.kind == "read":
            return self._served.variable_value(self.index, self.subindex).data
        if self._data is None:
            context = self._context
            self._data = context.runtime.od_request_value(context.index, self._token,
                                                          f"value of {self!r}")
        return self._data

    @property
    def value(self) -> Value:
        """`data` decoded by the entry's type (what `.raw` would give)."""
        return self.variable.decode_raw(self.data)

    # ------------------------------------------------------------ answers
    def defer(self) -> "ODRequest":
        """Keep the access waiting after the callback returns; answer it later
        with accept() or refuse(). The client sees a timeout if that takes
        longer than its SDO/USDO timeout."""
        self._deferred = True
        return self

    def accept(self) -> None:
        """Go on: the remaining callbacks run, then the access completes."""
        with self._lock:
            self._deferred = False
        self._run()

    def refuse(self, code: Union[int, AbortError] = GENERAL_ERROR) -> None:
        """Refuse the access with a CiA 301 abort code (an int or an AbortError)."""
        if isinstance(code, AbortError):
            code = code.code
        if isinstance(code, bool) or not isinstance(code, int) or not 0 < code < 0xFFFFFFFF:
            raise ConfigurationError(f"{self!r}: refuse() needs a CiA abort code "
                                     f"0x00000001..0xFFFFFFFE, got {code!r}")
        self._answer(code)

    # ------------------------------------------------------------ machinery
    def _run(self) -> None:
        """Run callbacks from where the chain stopped until one refuses or defers."""
        while True:
            with self._lock:
                if self._answered or self._deferred:
                    return
                if self._next >= len(self._callbacks):
                    break
                callback = self._callbacks[self._next]
                self._next += 1
            code = self._call(callback)
            if code:
                self._answer(code)
                return
        self._answer(0)

    def _call(self, callback: Callback) -> int:
        try:
            result = callback(self)
        except AbortError as exc:
            return exc.code
        except Exception:  # noqa: BLE001 - a broken callback refuses, never hangs the access
            log.exception("%r: callback %r raised; refused with 0x%08X", self, callback,
                          GENERAL_ERROR)
            return GENERAL_ERROR
        if result is None or result is self:
            return 0
        if isinstance(result, bool) or not isinstance(result, int):
            log.error("%r: callback %r returned %r (None, an abort code or the deferred "
                      "request expected); refused with 0x%08X", self, callback, result,
                      GENERAL_ERROR)
            return GENERAL_ERROR
        return result

    def _answer(self, code: int) -> None:
        with self._lock:
            if self._answered:
                raise ConfigurationError(f"{self!r} was answered already")
            self._answered = True
        context = self._context
        context.runtime.od_answer(context.index, self._token, code, f"answer to {self!r}")


class Indications(LocalNodeService):
    """The before-read / check-write callbacks of one local node."""

    def __init__(self, context: LineContext, node: LocalNodeView, served: ServedDictionary,
                 persist: Callable[[int], Callable[[], None]]) -> None:
        self._context = context
        self._node = node
        self._served = served
        # the answer to a network save / restore into an application store
        self._persist = persist
        self._lock = threading.Lock()
        # (first key, last key) -> kinds registered in the runtime
        self._ranges: Dict[Tuple[int, int], int] = {}
        # (index, sub or None for the whole object, kind) -> callbacks
        self._callbacks: Dict[Tuple[int, Optional[int], int], List[Callback]] = {}
        context.subscribe(EventKind.OD_REQUEST, self._event)

    def add(self, key: Key, kind: int, callback: Optional[Callback]
            ) -> Union[Callback, Callable[[Callback], Callback]]:
        if callback is None:   # used as a decorator
            return lambda function: self._add(key, kind, function)
        return self._add(key, kind, callback)

    def _add(self, key: Key, kind: int, callback: Callback) -> Callback:
        if not callable(callback):
            raise ConfigurationError(f"{self._where}: {_KIND_NAMES[kind]} callback must be "
                                     f"callable, got {callback!r}")
        entry = self._served.entry(key)
        index = entry.index
        sub = entry.subindex if isinstance(entry, ODVariable) else None
        first = index << 8 | (sub if sub is not None else 0)
        last = index << 8 | (sub if sub is not None else 0xFF)
        with self._lock:
            self._callbacks.setdefault((index, sub, kind), []).append(callback)
            known = self._ranges.get((first, last), 0)
            self._ranges[(first, last)] = known | kind
        if not known & kind and self._node.booted:
            self._register(first, last, kind)
        return callback

    def remove(self, callback: Callback) -> None:
        """Forget a callback (its range stays watched; accesses then go on at once)."""
        with self._lock:
            for callbacks in self._callbacks.values():
                while callback in callbacks:
                    callbacks.remove(callback)

    def register_all(self) -> None:
        """At boot, after the OD is defined: every range registered so far."""
        with self._lock:
            ranges = list(self._ranges.items())
        for (first, last), kinds in ranges:
            self._register(first, last, kinds)

    def _register(self, first: int, last: int, kinds: int) -> None:
        context = self._context
        context.runtime.od_indicate(context.index, first, last, kinds,
                                    f"indication 0x{first >> 8:04X} on {self._where}")

    def _event(self, event: Event) -> Deferred:
        """CO_EV_OD_REQUEST: the access to answer (a = index << 8 | sub, b = token)."""
        key, token = event.a, event.b
        index, sub, kind = key >> 8, key & 0xFF, token >> 24
        if kind == Indicate.STORE:
            return self._persist(token)
        od = self._node.od
        variable = od.get_variable(index, sub) if od is not None else None
        with self._lock:
            callbacks = (list(self._callbacks.get((index, sub, kind), [])) +
                         list(self._callbacks.get((index, None, kind), [])))
        if variable is None:
            log.error("%s: request for unknown entry 0x%04X:%02X refused", self._where, index,
                      sub)
            context = self._context
            return lambda: context.runtime.od_answer(context.index, token, GENERAL_ERROR,
                                                     "refuse")
        # accept() starts the callback chain (as a deferred request goes on)
        return ODRequest(self._context, self._served, variable, kind, token, callbacks).accept
