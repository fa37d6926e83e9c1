"""Requests for one node of a classic line take turns, whichever host
protocol of the process brings them (CiA 309-3 ASCII sessions, MQTT
commands, remote-access hosts).

The SDO client runs one transfer per server on its default channel and
refuses a second one at once ("busy", 0x060A0023); a gateway's hosts know
nothing of each other, so a request meeting another one for the same node
waits for its turn instead. Fd lines need no turns: the USDO client runs
several sessions.

    with taking_turn(line, node, timeout):          # threads
        ...
    async with taking_turn_async(line, node):       # an event loop (polls)
        ...
"""

from __future__ import annotations

import asyncio
import contextlib
import threading
import weakref
from typing import AsyncIterator, Dict, Iterator, Optional

from ..errors import CanopenFDError
from ..line import Line

__all__ = ["TurnTimeout", "turn_lock", "taking_turn", "taking_turn_async"]

#: How often an event loop looks whether the node's turn came (s): short
#: against an SDO transfer, and nothing is polled while nobody waits.
POLL_S = 0.002

_guard = threading.Lock()
# {line: {node: lock}}; a closed line that nobody holds goes with its entry
_turns: "weakref.WeakKeyDictionary[Line, Dict[int, threading.Lock]]" = \
    weakref.WeakKeyDictionary()


class TurnTimeout(CanopenFDError):
    """Another request held the node longer than the caller would wait."""


def turn_lock(line: Line, node: int) -> Optional[threading.Lock]:
    """The lock requests for `node` on `line` take (None on fd lines)."""
    if line.mode == "fd":
        return None
    with _guard:
        locks = _turns.setdefault(line, {})
        lock = locks.get(node)
        if lock is None:
            lock = locks[node] = threading.Lock()
        return lock


@contextlib.contextmanager
def taking_turn(line: Line, node: int, timeout: float) -> Iterator[None]:
    """Hold node's turn (a thread), waiting at most `timeout` s for it."""
    lock = turn_lock(line, node)
    if lock is None:
        yield
        return
    if not lock.acquire(timeout=timeout):
        raise TurnTimeout(f"node {node} on {line.channel}: another request held it "
                          f"for {timeout} s")
    try:
        yield
    finally:
        lock.release()


@contextlib.asynccontextmanager
async def taking_turn_async(line: Line, node: int) -> AsyncIterator[None]:
    """Hold node's turn in a coroutine without blocking its event loop (a
    cancelled wait never took the turn)."""
    lock = turn_lock(line, node)
    if lock is None:
        yield
        return
    while not lock.acquire(blocking=False):
        await asyncio.sleep(POLL_S)
    try:
        yield
    finally:
        lock.release()
