"""Callback lists and waits shared by lines and nodes.

Callbacks run on the network's dispatcher thread. One that raises is logged
(with its traceback) and the others still run: a user bug must never stop
event delivery.
"""

from __future__ import annotations

import asyncio
import collections
import logging
import threading
import time
from typing import (Awaitable, Callable, Deque, Dict, Generic, List, Optional,
                    Tuple, TypeVar)

from ._aio import AsyncCondition, AsyncWaits, LoopArg, LoopDelivery, await_predicate
from .errors import ClosedError, ConfigurationError

log = logging.getLogger("canopenfd")

#: A callback of any signature (what it returns is ignored).
C = TypeVar("C", bound=Callable[..., object])
T = TypeVar("T")

_BACKLOG = 10_000   # calls kept waiting behind a blocked callback of one list


class CallbackList:
    """Ordered callbacks of one kind of event.

    They run one call at a time and in event order, even when a blocked
    callback made the network hand its events to another dispatcher thread:
    a fire() that finds the list busy on another thread queues its arguments
    (at most _BACKLOG calls; beyond, the oldest are dropped and counted), and
    the busy thread runs them once its call returns."""

    def __init__(self, what: str) -> None:
        self._what = what
        self._callbacks: List[Callable[..., object]] = []
        # what runs for each callback given with loop= (its delivery to that loop)
        self._delivered: Dict[Callable[..., object], Callable[..., object]] = {}
        self._lock = threading.Lock()
        self._runner: Optional[int] = None     # thread ident running the callbacks
        self._backlog: Deque[Tuple[object, ...]] = collections.deque()
        #: Calls dropped because the backlog behind a blocked callback was full.
        self.dropped = 0

    def add(self, callback: C, loop: LoopArg = None) -> C:
        """Run callback on the dispatcher thread, or scheduled on `loop` when
        given (a coroutine function then runs as a task of that loop)."""
        if not callable(callback):
            raise ConfigurationError(f"{self._what} callback must be callable, got {callback!r}")
        runs = callback if loop is None else LoopDelivery(callback, loop)
        with self._lock:
            self._callbacks.append(runs)
            if runs is not callback:
                self._delivered[callback] = runs
        return callback  # so on_xxx() also works as a decorator

    def remove(self, callback: Callable[..., object]) -> None:
        with self._lock:
            runs = self._delivered.pop(callback, callback)
            if runs in self._callbacks:
                self._callbacks.remove(runs)

    def __bool__(self) -> bool:
        return bool(self._callbacks)

    def fire(self, *args: object) -> None:
        me = threading.get_ident()
        with self._lock:
            runner = self._runner
            if runner is not None and runner != me:
                if len(self._backlog) >= _BACKLOG:
                    self._backlog.popleft()
                    self.dropped += 1
                    if self.dropped == 1:
                        log.error("%s callbacks are blocked: calls waiting for them are "
                                  "dropped from now on (%d kept)", self._what, _BACKLOG)
                self._backlog.append(args)
                return
            self._runner = me
            callbacks = list(self._callbacks)
        try:
            self._run(callbacks, args)
        finally:
            if runner is None:            # not a nested fire: run what waited, then free
                self._drain()

    def _drain(self) -> None:
        while True:
            with self._lock:
                if not self._backlog:
                    self._runner = None
                    return
                args = self._backlog.popleft()
                callbacks = list(self._callbacks)
            self._run(callbacks, args)

    def _run(self, callbacks: List[Callable[..., object]], args: Tuple[object, ...]) -> None:
        for callback in callbacks:
            try:
                callback(*args)
            except Exception:  # noqa: BLE001 - logged, never kills the dispatcher
                log.exception("%s callback %r raised", self._what, callback)


class Until(Generic[T]):
    """What a wait waits for: shared by a blocking wait and its `await` form.
    `what` names the wait in messages ("node 5: wait_for_bootup"),
    describe_timeout() tells why it timed out ("no boot-up")."""

    __slots__ = ("predicate", "what", "describe_timeout")

    def __init__(self, predicate: Callable[[], T], what: str,
                 describe_timeout: Callable[[], str]) -> None:
        self.predicate = predicate
        self.what = what
        self.describe_timeout = describe_timeout


class Waiter:
    """Blocking waits on a condition the dispatcher notifies.

    `closed` is a callable telling whether the network was closed, so a wait
    ends with ClosedError instead of running into its timeout.
    """

    def __init__(self, cond: threading.Condition, closed: Callable[[], bool],
                 is_dispatcher: Callable[[], bool]) -> None:
        self.cond = cond
        self._closed = closed
        self._is_dispatcher = is_dispatcher
        #: The awaited predicates (wait_async) the condition's notify_all checks.
        self.async_waits = AsyncWaits(closed)
        if isinstance(cond, AsyncCondition):
            cond.waits = self.async_waits

    def wait(self, predicate: Callable[[], T], timeout: Optional[float],
             what: str, describe_timeout: Callable[[], str]) -> T:
        """Wait until predicate() is true; returns its value.

        Raises TimeoutError with describe_timeout()'s text, ClosedError when the
        network closes meanwhile, ConfigurationError when called from a callback
        (the dispatcher would wait for itself)."""
        if timeout is not None and timeout < 0:
            raise ConfigurationError(f"{what}: timeout must be >= 0 s, got {timeout}")
        if self._is_dispatcher():
            raise ConfigurationError(
                f"{what} called from a callback: callbacks run on the dispatcher thread, "
                "which delivers the very event waited for; wait from another thread")
        deadline = None if timeout is None else time.monotonic() + timeout
        with self.cond:
            while True:
                if self._closed():
                    raise ClosedError(f"{what}: the network was closed")
                result = predicate()
                if result:
                    return result
                remaining = None if deadline is None else deadline - time.monotonic()
                if remaining is not None and remaining <= 0:
                    raise TimeoutError(f"{what}: {describe_timeout()} after {timeout:g} s")
                self.cond.wait(remaining)

    def wait_until(self, until: "Until[T]", timeout: Optional[float]) -> T:
        return self.wait(until.predicate, timeout, until.what, until.describe_timeout)

    def await_until(self, until: "Until[T]", timeout: Optional[float]) -> Awaitable[T]:
        return self.wait_async(until.predicate, timeout, until.what, until.describe_timeout)

    def wait_async(self, predicate: Callable[[], T], timeout: Optional[float],
                   what: str, describe_timeout: Callable[[], str]) -> Awaitable[T]:
        """wait() for `await`: the same value, TimeoutError and ClosedError,
        without a thread per waiter (the condition must be an AsyncCondition).
        Cancelling the await removes its entry from `async_waits`."""
        if timeout is not None and timeout < 0:
            raise ConfigurationError(f"{what}: timeout must be >= 0 s, got {timeout}")
        if not isinstance(self.cond, AsyncCondition):
            raise ConfigurationError(f"{what}: this condition cannot be awaited")
        return await_predicate(self.cond, self.async_waits, predicate, timeout, what,
                               describe_timeout, self._closed)


def loop_waker(collect: Callable[[], T]) -> "Tuple[asyncio.Future[T], Callable[[], None]]":
    """For an `await` of something that ends on another thread: a future of
    the running loop, and wake(), callable from any thread once it ended,
    which settles the future in the loop with collect()'s value or exception
    (nothing happens when the loop closed meanwhile: nobody awaits any more)."""
    loop = asyncio.get_running_loop()
    future: "asyncio.Future[T]" = loop.create_future()

    def settle() -> None:
        if future.done():
            return
        try:
            future.set_result(collect())
        except BaseException as exc:  # noqa: BLE001 - handed to the awaiting task
            future.set_exception(exc)

    def wake() -> None:
        try:
            loop.call_soon_threadsafe(settle)
        except RuntimeError:
            pass

    return future, wake


def chain(calls: List[Callable[[], None]]) -> Callable[[], None]:
    """One callable running calls in order (what an event handler returns)."""
    def run() -> None:
        for call in calls:
            call()
    return run
