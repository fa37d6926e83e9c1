"""`Network`: one C runtime (one thread running every line) plus the Python
dispatcher thread that turns its events into callbacks: each event goes to
the line context of its line, whose event table hands it to a service.

A callback that blocks must not hold every other event of the network: when
one holds the dispatcher longer than stall_report_s, the watchdog reports it
and hands the events still to come to a new dispatcher thread (at most
_MAX_BLOCKED of them wait in callbacks at once). The blocked thread ends once
its callback returns; a CallbackList keeps its own callbacks one at a time
and in order meanwhile (what comes for it waits for it)."""

from __future__ import annotations

import atexit
import collections
import logging
import threading
import time
import weakref
from types import TracebackType
from typing import Deque, Dict, List, Optional, Set, Tuple, Type

from ._binding.constants import Driver, EventKind, Mode
from ._binding.context import RuntimeLineContext
from ._binding.hostbus import HostBridge, PythonCanBus
from ._binding.runtime import Event, Runtime
from .errors import ClosedError, ConfigurationError
from .line import Line
from .services.routing import RoutingService

log = logging.getLogger("canopenfd")

_WAIT_MS = 200          # dispatcher wake-up period (to notice close())
_JOIN_TIMEOUT_S = 5.0   # generous: close() must never hang, but slow VMs exist
_MAX_QUEUE = 1 << 20
_MODES = ("fd", "classic")
_EV_EVENTS_LOST = int(EventKind.EVENTS_LOST)   # a plain int: compared on every event
_BURST_END_S = 1.0     # no event lost for this long: the burst of losses is over
_MAX_BLOCKED = 4       # dispatcher threads left waiting in callbacks before no more relief


def _event_name(kind: int) -> str:
    try:
        return EventKind(kind).name
    except ValueError:
        return f"kind {kind}"

# Networks still open at interpreter exit are closed then, so the C thread
# never outlives the interpreter that owns its callbacks.
_open_networks: "weakref.WeakSet[Network]" = weakref.WeakSet()


@atexit.register
def _close_open_networks() -> None:
    for network in list(_open_networks):
        network.close()


class Network:
    """A set of CAN lines run by one C thread.

    Usable as a context manager; close() is idempotent. Callbacks of every line
    run on this network's dispatcher thread, one at a time, in event order; a
    callback blocked longer than stall_report_s is reported and left behind
    (the others go on; its own later calls wait for it).
    """

    def __init__(self, event_capacity: int = 0, *, stall_report_s: float = 1.0) -> None:
        """event_capacity: runtime events queued for the dispatcher (0 = default).
        stall_report_s: a callback (or other event handling) holding the
        dispatcher longer than this is logged as a warning and counted in
        `dispatcher_stalls`, and a new dispatcher thread takes the other
        events over meanwhile."""
        if isinstance(event_capacity, bool) or not isinstance(event_capacity, int) \
                or not 0 <= event_capacity <= _MAX_QUEUE:
            raise ConfigurationError(
                f"event_capacity must be an int 0..{_MAX_QUEUE} (0 = default), "
                f"got {event_capacity!r}")
        if isinstance(stall_report_s, bool) or not isinstance(stall_report_s, (int, float)) \
                or not 0 < stall_report_s <= 3600:
            raise ConfigurationError(
                f"stall_report_s must be a number of seconds in (0, 3600], got {stall_report_s!r}")
        self._runtime = Runtime(event_capacity)
        self._lock = threading.RLock()     # lines table, close()
        self._lines: Dict[int, Line] = {}
        self._contexts: Dict[int, RuntimeLineContext] = {}
        self._bridges: List[HostBridge] = []
        self._owned_buses: List[PythonCanBus] = []   # shut down once the bridges ended
        self._closed = False
        self._events_lost = 0
        self._free_on_exit = False  # close() ran in a callback: the dispatcher frees
        self._finished = False
        # Events read but not delivered yet: whichever dispatcher is active takes
        # them in order (a blocked one's successor goes on from there).
        self._pending: Deque[Event] = collections.deque()
        self._dispatch_lock = threading.Lock()    # _active, _handling, _threads
        # What the active dispatcher handles now (monotonic start, the event), for the watchdog.
        self._handling: Optional[Tuple[float, Event]] = None
        self._stall_report_s = float(stall_report_s)
        self._stalls = 0
        self._burst: Optional[List[float]] = None   # events lost: [first, last, count]
        self._stop_watch = threading.Event()
        #: Routing between the lines (line.network_id, 0x1F2C routes, EMCY
        #: routing, PDO forwarding): see canopenfd.services.routing.
        self.routing = RoutingService(self._runtime, self._lines.get)
        self._active = self._new_dispatcher()
        #: every dispatcher thread still running: the active one and those blocked
        self._threads: Set[threading.Thread] = {self._active}
        self._watchdog = threading.Thread(target=self._watch_dispatcher,
                                          name="canopenfd-watchdog", daemon=True)
        self._active.start()
        self._watchdog.start()
        _open_networks.add(self)

    def __enter__(self) -> "Network":
        return self

    def __exit__(self, kind: Optional[Type[BaseException]], value: Optional[BaseException],
                 traceback: Optional[TracebackType]) -> None:
        self.close()

    def __repr__(self) -> str:
        state = "closed" if self._closed else f"{len(self._lines)} lines"
        return f"<canopenfd.Network {state}>"

    @property
    def closed(self) -> bool:
        return self._closed

    @property
    def lines(self) -> List[Line]:
        with self._lock:
            return [self._lines[i] for i in sorted(self._lines)]

    @property
    def events_lost(self) -> int:
        """Events the runtime dropped because the Python side fell behind."""
        return self._events_lost

    @property
    def dispatcher_stalls(self) -> int:
        """Times one event's handling (a callback) held the dispatcher longer
        than stall_report_s (each is logged as a warning)."""
        return self._stalls

    @property
    def blocked_dispatchers(self) -> int:
        """Dispatcher threads still waiting in a callback that blocked (their
        events went to a new dispatcher thread)."""
        with self._dispatch_lock:
            return len(self._threads) - (1 if self._active in self._threads else 0)

    # ---------------------------------------------------------------- lines
    def open_line(self, channel: Optional[str] = None, *, bus: Optional[PythonCanBus] = None,
                  mode: str = "fd", brs: bool = True, monitor: bool = False,
                  rx_queue: int = 0, tx_queue: int = 0) -> Line:
        """Open a line and return it.

        channel: "mem:NAME" for the in-process bus NAME, otherwise a SocketCAN
        interface name ("vcan0", "can0"). Or bus=: a python-can Bus (the line
        then runs over it through two bridge threads; channel is only a label).
        mode: 'fd' or 'classic'. brs: bit-rate switch on frames sent (fd).
        monitor: report every frame on the line to on_frame callbacks.
        rx_queue/tx_queue: queue sizes in frames (0 = runtime default).
        """
        if self._closed:
            raise ClosedError(f"open_line({channel!r}): the network is closed")
        if mode not in _MODES:
            raise ConfigurationError(
                f"line mode {mode!r} unknown: expected 'fd' or 'classic'")
        for name, value in (("rx_queue", rx_queue), ("tx_queue", tx_queue)):
            if isinstance(value, bool) or not isinstance(value, int) \
                    or not 0 <= value <= _MAX_QUEUE:
                raise ConfigurationError(
                    f"{name} must be an int 0..{_MAX_QUEUE} frames (0 = default), "
                    f"got {value!r}")
        if (channel is None) == (bus is None):
            raise ConfigurationError(
                "open_line needs exactly one of channel (an interface name or 'mem:NAME') "
                "and bus (a python-can Bus)" + ("" if channel is None else
                                                f"; got both channel={channel!r} and a bus"))
        if bus is not None:
            if not (callable(getattr(bus, "recv", None)) and callable(getattr(bus, "send", None))):
                raise ConfigurationError(f"bus must be a python-can Bus, got {bus!r}")
            driver = Driver.HOST
            label = str(getattr(bus, "channel_info", None) or type(bus).__name__)
        else:
            if not isinstance(channel, str) or not channel.strip():
                raise ConfigurationError(
                    f"channel must be an interface name or 'mem:NAME', got {channel!r}")
            if channel.startswith("mem:"):
                driver = Driver.MEMBUS
                label = channel[4:]
                if not label:
                    raise ConfigurationError(
                        f"channel {channel!r}: the in-process bus needs a name ('mem:NAME')")
            else:
                driver = Driver.SOCKETCAN
                label = channel
        fd = mode == "fd"
        brs = bool(brs) and fd
        name = channel if channel is not None else label
        with self._lock:
            if self._closed:
                raise ClosedError(f"open_line({name!r}): the network is closed")
            index = self._runtime.add_line(
                driver, label, Mode.FD if fd else Mode.CLASSIC, brs,
                rx_queue, tx_queue, monitor, what=f"cannot open {mode} line {name!r}")
            context = RuntimeLineContext(self._runtime, index, mode, name,
                                         closed=lambda: self._closed,
                                         on_dispatcher=self._on_dispatcher)
            line = Line(self, context, brs, bool(monitor))
            self.routing.attach(context)
            self._contexts[index] = context
            self._lines[index] = line
            if bus is not None:
                bridge = HostBridge(self._runtime, index, bus, name)
                self._bridges.append(bridge)
                bridge.start()
        return line

    # ---------------------------------------------------------------- close
    def close(self) -> None:
        """Stop the runtime and every thread; idempotent, never hangs.

        Waits in other threads end with ClosedError. Called from a callback,
        the runtime is freed by the dispatcher once the callback returns."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
        _open_networks.discard(self)
        for bridge in self._bridges:
            bridge.stop()
        self._runtime.stop()
        self._stop_watch.set()
        for line in self.lines:   # their nodes serve nothing now: the models are free
            if line.local_node is not None:
                line.local_node.release_od()
        with self._lock:
            contexts = list(self._contexts.values())
        for context in contexts:
            context.wake()
        if self._on_dispatcher():
            self._free_on_exit = True  # the dispatcher frees once the callback returns
            return
        self._finish()

    def _finish(self) -> None:
        """Join the bridge threads and the active dispatcher, then free the
        runtime if nothing still waits in it. Dispatchers blocked in a
        callback are not waited for: they never call into the runtime again."""
        with self._dispatch_lock:
            if self._finished:
                return
            self._finished = True
            active = self._active
        stuck: List[object] = [b for b in self._bridges if not b.join(_JOIN_TIMEOUT_S)]
        if not stuck:
            self._shut_owned_buses()
        if active is not threading.current_thread() and not self._left_behind(active):
            stuck.append(active)
        if stuck:
            # Freeing now could crash a thread still inside the runtime: leak it instead.
            log.error("network close: %d thread(s) did not end in %.0f s; runtime not freed",
                      len(stuck), _JOIN_TIMEOUT_S)
            return
        self._runtime.free()

    def shutdown_with(self, bus: PythonCanBus) -> None:
        """Shut the python-can bus down when the network closes (after its
        line's bridge threads ended): for buses the network's user made only
        for it, like canopenfd.connect's."""
        with self._lock:
            if self._closed:
                raise ClosedError("shutdown_with: the network is closed")
            self._owned_buses.append(bus)

    def _shut_owned_buses(self) -> None:
        for bus in self._owned_buses:
            try:
                bus.shutdown()
            except Exception:  # a driver's own failure must not stop the close
                log.exception("network close: shutting down python-can bus %r failed", bus)
        self._owned_buses.clear()

    def _left_behind(self, active: threading.Thread) -> bool:
        """Wait for the active dispatcher to end (the network is closed); True
        when it did, or when it is stalled in an event's handling (a callback
        blocked for stall_report_s): from there it goes back to see the
        network closed and ends without entering the runtime again, so it is
        left behind."""
        deadline = time.monotonic() + _JOIN_TIMEOUT_S
        while active.is_alive() and time.monotonic() < deadline:
            with self._dispatch_lock:
                handling = self._handling if self._active is active else None
            if handling is not None and \
                    time.monotonic() - handling[0] >= self._stall_report_s:
                return True
            active.join(0.05)
        return not active.is_alive()

    def _on_dispatcher(self) -> bool:
        return threading.current_thread() in self._threads

    # ---------------------------------------------------------------- dispatch
    def _new_dispatcher(self) -> threading.Thread:
        return threading.Thread(target=self._dispatch, name="canopenfd-dispatch", daemon=True)

    def _next_event(self, me: threading.Thread) -> Optional[Event]:
        """The next event for dispatcher `me`, None when it is no longer the
        active one (or the network closed). Reads a batch when none is pending."""
        pending = self._pending
        while not self._closed:
            with self._dispatch_lock:
                if self._active is not me:
                    return None
                if pending:
                    event = pending.popleft()
                    self._handling = (time.monotonic(), event)
                    return event
            events = self._runtime.read_events(_WAIT_MS)
            if events is None:
                return None  # the runtime stopped
            pending.extend(events)   # only the active dispatcher reads
        return None

    def _dispatch(self) -> None:
        me = threading.current_thread()
        try:
            while True:
                event = self._next_event(me)
                if event is None:
                    break
                try:
                    self._deliver(event)
                except Exception:  # noqa: BLE001 - one bad event must not stop the rest
                    log.exception("canopenfd: event %d of line %d could not be delivered",
                                  event.kind, event.line)
                with self._dispatch_lock:
                    if self._active is me:
                        self._handling = None
        finally:
            with self._dispatch_lock:
                self._threads.discard(me)
                if self._active is me:
                    self._handling = None
                    self._stop_watch.set()
            if self._free_on_exit:
                self._finish()

    def _relieve(self, handling: Tuple[float, Event]) -> bool:
        """The active dispatcher is blocked in `handling`: hand the events to
        come to a new dispatcher thread. False when it moved on meanwhile, the
        network closed, or _MAX_BLOCKED threads already wait in callbacks."""
        with self._dispatch_lock:
            if self._closed or self._handling is not handling \
                    or len(self._threads) > _MAX_BLOCKED:
                return False
            fresh = self._new_dispatcher()
            self._active = fresh
            self._threads.add(fresh)
            self._handling = None
        fresh.start()
        return True

    def _loss_burst(self, lost: int) -> None:
        """Events the runtime dropped (its queue was full): one warning when a
        burst starts, one with its total when it ended (no loss for 1 s), not
        one per report: a sustained overload reports at every read."""
        now = time.monotonic()
        with self._lock:
            burst = self._burst
            if burst is None:
                self._burst = [now, now, lost]
            else:
                burst[1] = now
                burst[2] += lost
        if burst is None:
            log.warning("canopenfd: %d runtime events lost: the event queue is full (callbacks "
                        "too slow?); the total follows when the losses stop", lost)

    def _loss_burst_end(self, now: float) -> None:
        with self._lock:
            burst = self._burst
            if burst is None or now - burst[1] < _BURST_END_S:
                return
            self._burst = None
        log.warning("canopenfd: %d runtime events lost in %.1f s (%d lost since the network "
                    "opened)", burst[2], burst[1] - burst[0], self._events_lost)

    def _watch_dispatcher(self) -> None:
        """Report a callback that holds the dispatcher (every other event waits)."""
        reported: Optional[Tuple[float, Event]] = None
        step = min(0.25, self._stall_report_s / 4)
        while not self._stop_watch.wait(step):
            self._loss_burst_end(time.monotonic())
            handling = self._handling
            if handling is None or handling is reported:
                continue
            held = time.monotonic() - handling[0]
            if held >= self._stall_report_s:
                reported = handling
                self._stalls += 1
                event = handling[1]
                with self._lock:
                    line = self._lines.get(event.line)
                relieved = self._relieve(handling)
                log.warning("canopenfd: the handling of a %s event of %s has held the dispatcher "
                            "for %.1f s (a blocking callback?): %s", _event_name(event.kind),
                            f"line {line.channel!r}" if line is not None
                            else f"line {event.line}", held,
                            "a new dispatcher thread delivers the other events meanwhile"
                            if relieved else "every other event of the network waits "
                            f"({len(self._threads)} dispatcher threads are blocked already)"
                            if not self._closed else "the network is closing")

    def _deliver(self, ev: Event) -> None:
        kind = ev.kind
        if kind == _EV_EVENTS_LOST:
            self._events_lost += ev.a
            self._loss_burst(ev.a)
            return
        with self._lock:
            context = self._contexts.get(ev.line)
        if context is None:
            log.debug("event %d for unknown line %d ignored", kind, ev.line)
            return
        context.dispatch(ev)
