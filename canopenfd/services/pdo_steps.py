"""PDO configuration procedures written once, run blocking or awaited.

PdoMap.read and .save are generators of steps: each `yield` hands out one
object access, (index, sub, None) to read it or (index, sub, data) to write
it, and gets the bytes read back (or the transfer's AbortError thrown in at
the yield, where the procedure adds its context). `run` performs the steps
with the blocking transfers, `arun` with the awaitable ones, so read/save
and aread/asave cannot drift apart.
"""

from __future__ import annotations

from typing import Awaitable, Callable, Generator, Optional, Protocol, Tuple, TypeVar

from ..errors import AbortError

T = TypeVar("T")

#: One object access: (index, sub, None) reads, (index, sub, data) writes.
Step = Tuple[int, int, Optional[bytes]]
#: A procedure: yields steps, is sent the bytes read (b"" after a write).
Steps = Generator[Step, bytes, T]


class StepAccess(Protocol):
    remote: bool

    def read(self, index: int, sub: int) -> bytes:
        ...

    def write(self, index: int, sub: int, data: bytes) -> None:
        ...


class AsyncStepAccess(Protocol):
    async def aread(self, index: int, sub: int) -> bytes:
        ...

    async def awrite(self, index: int, sub: int, data: bytes) -> None:
        ...


def done(value: T) -> Steps[T]:
    """A procedure of no step that gives value (an OD read in a step's place)."""
    yield from ()   # makes this a generator
    return value


async def _perform(steps: "Steps[T]", read: Callable[[int, int], Awaitable[bytes]],
                   write: Callable[[int, int, bytes], Awaitable[None]]) -> T:
    """The one walk through a procedure, over awaitable read/write."""
    answer: Optional[bytes] = None    # a generator's first send() must be None
    error: Optional[AbortError] = None
    while True:
        try:
            step = steps.throw(error) if error is not None else \
                steps.send(answer)  # type: ignore[arg-type]
        except StopIteration as end:
            return end.value  # type: ignore[no-any-return]
        answer, error = b"", None
        index, sub, data = step
        try:
            if data is None:
                answer = await read(index, sub)
            else:
                await write(index, sub, data)
        except AbortError as exc:
            error = exc


def run(steps: Steps[T], access: StepAccess) -> T:
    """Perform the steps with the blocking access: _perform over read/write
    that never suspend, so one send() runs it to its end."""
    async def read(index: int, sub: int) -> bytes:
        return access.read(index, sub)

    async def write(index: int, sub: int, data: bytes) -> None:
        access.write(index, sub, data)

    walk = _perform(steps, read, write)
    try:
        walk.send(None)
    except StopIteration as end:
        return end.value  # type: ignore[no-any-return]
    walk.close()
    raise RuntimeError("a blocking PDO access suspended")  # cannot happen: nothing awaits


async def arun(steps: Steps[T], access: StepAccess) -> T:
    """Perform the steps with the access' awaitable transfers (a local
    node's OD is read and written at once: nothing to await)."""
    if not access.remote:
        return run(steps, access)
    remote: AsyncStepAccess = access  # type: ignore[assignment]
    return await _perform(steps, remote.aread, remote.awrite)
