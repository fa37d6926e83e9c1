"""The line context: what a service gets from its line, and nothing more.

Services (NMT, EMCY, PDO, SYNC, TIME, guarding, indications, stores, the
transfer clients) never see a `Line`: they get a `LineContext` with the
runtime and the line's index to call it with, the line's mode and name for
messages, the condition and waiter of its blocking calls, the event table
they subscribe their event kinds in, and the registry of watched PDO CAN-IDs.

`RuntimeLineContext` is the one implementation: the Network makes one per
line and hands it every event of that line (`dispatch`). Events go through a
table keyed by (kind, node): a handler subscribed for one node (a remote
node's heartbeat or guarding) wins over one subscribed for the kind. A
handler runs on the dispatcher thread under the line's condition and returns
what to run once the condition is released (user callbacks never run under
it), or None.
"""

from __future__ import annotations

import threading
from typing import Callable, Dict, List, Optional, Protocol, Tuple

from .._aio import AsyncCondition
from .._callbacks import Waiter
from ..frame import Frame
from .constants import EventKind
from .runtime import Event, Runtime

__all__ = ["Deferred", "EventHandler", "FrameHandler", "LineContext", "PdoWatches",
           "RuntimeLineContext"]

#: What a handler returns: the callbacks to run after the line's condition is released.
Deferred = Optional[Callable[[], None]]
#: A service's handler of one event kind.
EventHandler = Callable[[Event], Deferred]
#: A watcher of one PDO CAN-ID: called with each frame heard on it and the
#: count of older frames on that id the runtime merged into it (a slow consumer).
FrameHandler = Callable[[Frame, int], Deferred]

_HandlerKey = Tuple[int, Optional[int]]


class PdoWatches:
    """The PDO CAN-IDs Python hears on a line (other nodes' PDOs): CAN-ID (bit 29
    set: a 29-bit id) -> the handlers of the PDO maps listening to it. The
    runtime watches an id while at least one handler does."""

    def __init__(self, runtime: Runtime, index: int, cond: threading.Condition,
                 closed: Callable[[], bool]) -> None:
        self._runtime = runtime
        self._index = index
        self._cond = cond
        self._closed = closed
        #: {CAN-ID: handlers}, the ids watched now.
        self.watchers: Dict[int, List[FrameHandler]] = {}

    def watch(self, can_id: int, handler: FrameHandler, what: str) -> None:
        with self._cond:
            handlers = self.watchers.get(can_id)
            if handlers is None:
                self._runtime.pdo_watch(self._index, can_id, True, what)
                handlers = self.watchers[can_id] = []
            if handler not in handlers:
                handlers.append(handler)

    def unwatch(self, can_id: int, handler: FrameHandler, what: str) -> None:
        with self._cond:
            handlers = self.watchers.get(can_id)
            if handlers is None or handler not in handlers:
                return
            handlers.remove(handler)
            if not handlers:
                del self.watchers[can_id]
                if not self._closed():
                    self._runtime.pdo_watch(self._index, can_id, False, what)

    def event(self, event: Event) -> Deferred:
        """CO_EV_PDO_FRAME: a frame on a watched CAN-ID (a = the id)."""
        frame = event.frame
        if frame is None:
            return None
        calls = [call for call in (handler(frame, event.coalesced)
                                   for handler in list(self.watchers.get(event.a, ())))
                 if call is not None]
        if not calls:
            return None

        def run() -> None:
            for call in calls:
                call()
        return run


class LineContext(Protocol):
    """What services may use of their line."""

    #: The runtime; every call takes `index`, the line's index in it.
    runtime: Runtime
    index: int
    #: 'fd' or 'classic'.
    mode: str
    #: As given to open_line ('vcan0', 'mem:NAME', a python-can bus' label).
    channel: str
    #: "line 'vcan0'": how messages name the line.
    where: str
    #: The condition event handlers run under; blocking calls wait on it.
    cond: AsyncCondition
    waiter: Waiter
    pdo_watches: PdoWatches

    @property
    def closed(self) -> bool:
        """The network was closed."""
        ...

    @property
    def local_node_id(self) -> Optional[int]:
        """The id of the line's local node, None while it has none."""
        ...

    @property
    def node_where(self) -> str:
        """"local node 5 on line 'vcan0'": how messages name the line's local
        node, with its node-id as it is now (LSS and a reset change it)."""
        ...

    def on_dispatcher(self) -> bool:
        """True on the thread that runs event handlers and callbacks."""
        ...

    def subscribe(self, kind: EventKind, handler: EventHandler,
                  node: Optional[int] = None) -> None:
        """Events of `kind` (of remote node `node` only, when given) go to handler."""
        ...

    def unsubscribe(self, kind: EventKind, node: Optional[int] = None) -> None:
        ...

    def observe(self, kind: EventKind, handler: EventHandler) -> None:
        """Every event of `kind` (whichever node it names) also goes to handler,
        after the one subscribe() gave it: a line-wide view (a gateway hearing
        every node's boot-up) that leaves the per-node handlers in place."""
        ...

    def on_close(self, hook: Callable[[], None]) -> None:
        """hook() once the network closed (the runtime stopped): for what waits
        on events that will never come now."""
        ...

    def fell_behind(self, listener: str, skipped: int) -> None:
        """The runtime merged `skipped` values for `listener` (e.g. "node 5
        RPDO1") into later ones: its consumer was too slow. Counted per
        listener in line.events_behind."""
        ...



class LocalNodeService:
    """Base of the local node's services: `_where` names the node in messages
    by its node-id as it is now (LSS or a reset may renumber it while it runs)."""

    _context: LineContext

    @property
    def _where(self) -> str:
        return self._context.node_where

class _LineShare:
    """What the contexts of one line share: the condition, the waiter, the
    event table, the PDO watches and the local node's id."""

    def __init__(self, runtime: Runtime, index: int, closed: Callable[[], bool],
                 on_dispatcher: Callable[[], bool]) -> None:
        self.cond = AsyncCondition()
        self.waiter = Waiter(self.cond, closed, on_dispatcher)
        self.pdo_watches = PdoWatches(runtime, index, self.cond, closed)
        self.handlers: Dict[_HandlerKey, EventHandler] = {}
        #: {kind: handlers that see every event of that kind} (observe)
        self.observers: Dict[int, List[EventHandler]] = {}
        self.close_hooks: List[Callable[[], None]] = []
        self.local_node_id: Optional[int] = None
        #: {listener: values merged away before it saw them} (fell_behind)
        self.behind: Dict[str, int] = {}


class RuntimeLineContext:
    """The LineContext of one line of a Runtime.

    `scoped()` gives a context of the same line that remembers what it
    subscribed, so `release()` removes exactly that: a node's services
    subscribe through their node's scope and leave with it."""

    def __init__(self, runtime: Runtime, index: int, mode: str, channel: str, *,
                 closed: Callable[[], bool], on_dispatcher: Callable[[], bool],
                 share: Optional[_LineShare] = None) -> None:
        self.runtime = runtime
        self.index = index
        self.mode = mode
        self.channel = channel
        self.where = f"line {channel!r}"
        self._closed = closed
        self._on_dispatcher = on_dispatcher
        self._line = share if share is not None else \
            _LineShare(runtime, index, closed, on_dispatcher)
        self.cond = self._line.cond
        self.waiter = self._line.waiter
        self.pdo_watches = self._line.pdo_watches
        self._subscribed: List[_HandlerKey] = []
        self._observed: List[Tuple[int, EventHandler]] = []
        self._close_hooks: List[Callable[[], None]] = []
        if share is None:
            self.subscribe(EventKind.PDO_FRAME, self.pdo_watches.event)

    def __repr__(self) -> str:
        return f"<RuntimeLineContext {self.where} #{self.index}>"

    @property
    def closed(self) -> bool:
        return self._closed()

    @property
    def local_node_id(self) -> Optional[int]:
        return self._line.local_node_id

    @local_node_id.setter
    def local_node_id(self, node_id: Optional[int]) -> None:
        self._line.local_node_id = node_id

    @property
    def node_where(self) -> str:
        node_id = self._line.local_node_id
        if node_id is None:
            return f"the local node on {self.where}"
        return f"local node {node_id} on {self.where}"

    def on_dispatcher(self) -> bool:
        return self._on_dispatcher()

    def scoped(self) -> "RuntimeLineContext":
        """A context of the same line whose subscriptions `release()` removes."""
        return RuntimeLineContext(self.runtime, self.index, self.mode, self.channel,
                                  closed=self._closed, on_dispatcher=self._on_dispatcher,
                                  share=self._line)

    # ------------------------------------------------------------ the event table
    def subscribe(self, kind: EventKind, handler: EventHandler,
                  node: Optional[int] = None) -> None:
        key = (int(kind), node)
        with self.cond:
            if key in self._line.handlers:
                # One handler per kind (and node): a second one is a wiring bug.
                raise RuntimeError(f"{self.where}: {EventKind(kind).name} events"
                                   f"{'' if node is None else f' of node {node}'} "
                                   "already have a handler")
            self._line.handlers[key] = handler
            self._subscribed.append(key)

    def observe(self, kind: EventKind, handler: EventHandler) -> None:
        with self.cond:
            self._line.observers.setdefault(int(kind), []).append(handler)
            self._observed.append((int(kind), handler))

    def unsubscribe(self, kind: EventKind, node: Optional[int] = None) -> None:
        key = (int(kind), node)
        with self.cond:
            self._line.handlers.pop(key, None)
            if key in self._subscribed:
                self._subscribed.remove(key)

    def on_close(self, hook: Callable[[], None]) -> None:
        with self.cond:
            self._line.close_hooks.append(hook)
            self._close_hooks.append(hook)

    def fell_behind(self, listener: str, skipped: int) -> None:
        behind = self._line.behind
        behind[listener] = behind.get(listener, 0) + skipped

    @property
    def events_behind(self) -> Dict[str, int]:
        with self.cond:
            return dict(self._line.behind)

    def release(self) -> None:
        """Remove every subscription and close hook made through this context."""
        with self.cond:
            for key in self._subscribed:
                self._line.handlers.pop(key, None)
            self._subscribed = []
            for kind, handler in self._observed:
                observers = self._line.observers.get(kind, [])
                if handler in observers:
                    observers.remove(handler)
            self._observed = []
            for hook in self._close_hooks:
                if hook in self._line.close_hooks:
                    self._line.close_hooks.remove(hook)
            self._close_hooks = []

    def dispatch(self, event: Event) -> None:
        """One runtime event of this line (dispatcher thread)."""
        run: Deferred = None
        later: List[Callable[[], None]] = []
        handlers = self._line.handlers
        with self.cond:
            handler = handlers.get((event.kind, event.node)) or handlers.get((event.kind, None))
            if handler is not None:
                run = handler(event)
            for observer in self._line.observers.get(event.kind, ()):
                seen = observer(event)
                if seen is not None:
                    later.append(seen)
            self.cond.notify_all()
        if run is not None:
            run()
        for call in later:
            call()

    def wake(self) -> None:
        """Wake every blocking call of the line and run the close hooks (the
        network closed: no event comes any more)."""
        with self.cond:
            self.cond.notify_all()
            hooks = list(self._line.close_hooks)
        for hook in hooks:
            hook()
