"""asyncio forms of the API's waits and callbacks: one mechanism for all.

Waits: every blocking wait of a line is "until predicate() is true under the
line's condition" (Waiter.wait). Its awaitable form registers the predicate
in the condition's `AsyncWaits`; each notify_all() of the condition (the
dispatcher ran an event, or the network closed) checks the registered
predicates on the notifying thread, under the condition, and settles the
future of each one that became true with loop.call_soon_threadsafe. No
thread waits per waiter; a cancelled or timed-out await removes its entry.

Callbacks: `LoopDelivery(callback, loop)` is the callable a CallbackList
keeps when a registration got `loop=`: it schedules the callback on that
loop (a coroutine function runs as a task there) instead of running it on
the dispatcher thread.
"""

from __future__ import annotations

import asyncio
import logging
import threading
from typing import Any, Callable, Generic, Optional, Set, Tuple, TypeVar

from .errors import ClosedError, ConfigurationError

T = TypeVar("T")

log = logging.getLogger("canopenfd")

#: The `loop=` argument of every callback registration.
LoopArg = Optional[asyncio.AbstractEventLoop]


class _Pending(Generic[T]):
    """One awaited predicate: the future to settle on its loop."""

    __slots__ = ("predicate", "loop", "future")

    def __init__(self, predicate: Callable[[], T], loop: asyncio.AbstractEventLoop,
                 future: "asyncio.Future[T]") -> None:
        self.predicate = predicate
        self.loop = loop
        self.future = future

    def settle(self, value: Any = None, error: Optional[BaseException] = None) -> None:
        """From any thread: the future gets value (or error) on its loop."""
        def apply() -> None:
            if self.future.done():       # cancelled or timed out meanwhile
                return
            if error is not None:
                self.future.set_exception(error)
            else:
                self.future.set_result(value)
        try:
            self.loop.call_soon_threadsafe(apply)
        except RuntimeError:
            pass    # the loop closed: nobody awaits any more


class AsyncWaits:
    """The awaited predicates of one condition (held while `len()` > 0)."""

    def __init__(self, closed: Callable[[], bool]) -> None:
        self._closed = closed
        self._pending: Set[_Pending[Any]] = set()

    def __len__(self) -> int:
        return len(self._pending)

    def add(self, pending: "_Pending[Any]") -> None:
        self._pending.add(pending)

    def discard(self, pending: "_Pending[Any]") -> None:
        self._pending.discard(pending)

    def check(self) -> None:
        """Under the condition: settle every wait whose predicate holds now
        (or fail them all once the network closed)."""
        if not self._pending:
            return
        closed = self._closed()
        for pending in list(self._pending):
            if closed:
                self._pending.discard(pending)
                pending.settle(error=ClosedError("the network was closed"))
                continue
            try:
                value = pending.predicate()
            except Exception as exc:  # noqa: BLE001 - handed to the awaiting task
                self._pending.discard(pending)
                pending.settle(error=exc)
                continue
            if value:
                self._pending.discard(pending)
                pending.settle(value)


class AsyncCondition(threading.Condition):
    """The line's condition: notify_all() also settles the awaited predicates
    registered on it (`waits`, set by the Waiter that owns it)."""

    def __init__(self) -> None:
        super().__init__()
        self.waits: Optional[AsyncWaits] = None

    def notify_all(self) -> None:
        super().notify_all()
        if self.waits is not None:
            self.waits.check()


async def await_predicate(cond: threading.Condition, waits: AsyncWaits,
                          predicate: Callable[[], T], timeout: Optional[float],
                          what: str, describe_timeout: Callable[[], str],
                          closed: Callable[[], bool]) -> T:
    """The body of Waiter.wait_async (see there)."""
    loop = asyncio.get_running_loop()
    future: "asyncio.Future[T]" = loop.create_future()
    pending = _Pending(predicate, loop, future)
    with cond:
        if closed():
            raise ClosedError(f"{what}: the network was closed")
        value = predicate()
        if value:
            return value
        waits.add(pending)
    timer = None
    if timeout is not None:
        def expire() -> None:
            if not pending.future.done():
                with cond:
                    text = describe_timeout()
                pending.future.set_exception(TimeoutError(f"{what}: {text} after {timeout:g} s"))
        timer = loop.call_later(timeout, expire)
    try:
        return await future
    except ClosedError:
        raise ClosedError(f"{what}: the network was closed") from None
    finally:
        if timer is not None:
            timer.cancel()
        with cond:
            waits.discard(pending)


#: Calls of one loop= callback waiting on its loop at most (a stalled loop).
LOOP_BACKLOG = 10_000


def _log_failure(task: "asyncio.Task[Any]") -> None:
    if not task.cancelled() and task.exception() is not None:
        log.error("callback task %r raised", task, exc_info=task.exception())


class LoopDelivery:
    """What a CallbackList runs for a callback registered with `loop=`: the
    call is scheduled on `loop` (call_soon_threadsafe); a coroutine it
    returns runs as a task there. While `backlog` calls already wait on a
    stalled loop, newer ones are dropped and counted in `dropped` (the
    dispatcher must never wait for a loop, nor memory grow without end)."""

    def __init__(self, callback: Callable[..., object], loop: asyncio.AbstractEventLoop,
                 backlog: int = LOOP_BACKLOG) -> None:
        if not isinstance(loop, asyncio.AbstractEventLoop):
            raise ConfigurationError(f"loop= must be an asyncio event loop, got {loop!r}")
        self._callback = callback
        self._loop = loop
        self._backlog = backlog
        self._lock = threading.Lock()
        self._waiting = 0
        self.dropped = 0

    def __call__(self, *args: object) -> None:
        with self._lock:
            if self._waiting >= self._backlog:
                self.dropped += 1
                if self.dropped == 1:
                    log.error("callback %r: its loop is not taking the calls; calls beyond "
                              "%d waiting are dropped from now on", self._callback, self._backlog)
                return
            self._waiting += 1
        try:
            self._loop.call_soon_threadsafe(self._run, args)
        except RuntimeError:
            with self._lock:        # the loop closed: nobody listens there any more
                self._waiting -= 1

    def _run(self, args: Tuple[object, ...]) -> None:
        with self._lock:
            self._waiting -= 1
        try:
            result = self._callback(*args)
            if asyncio.iscoroutine(result):
                self._loop.create_task(result).add_done_callback(_log_failure)
        except Exception:  # noqa: BLE001 - logged like a dispatcher callback
            log.exception("callback %r raised", self._callback)
