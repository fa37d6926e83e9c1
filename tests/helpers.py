"""Helpers shared by the pytest files: time scaling and callback recorders."""

from __future__ import annotations

import os
import threading
import time
from typing import Any, Callable, List, Optional

TIME_SCALE = float(os.environ.get("CANOPENFD_TIME_SCALE", "1") or "1")


def scaled(seconds: float) -> float:
    """A timeout stretched by CANOPENFD_TIME_SCALE (slow VMs)."""
    return seconds * TIME_SCALE


class Recorder:
    """A callback that records its calls; tests wait on it (no polling)."""

    def __init__(self) -> None:
        self.calls: List[Any] = []
        self.times: List[float] = []
        self._cond = threading.Condition()

    def __call__(self, *args: Any) -> None:
        with self._cond:
            self.calls.append(args[0] if len(args) == 1 else args)
            self.times.append(time.monotonic())
            self._cond.notify_all()

    def __len__(self) -> int:
        with self._cond:
            return len(self.calls)

    def snapshot(self) -> List[Any]:
        with self._cond:
            return list(self.calls)

    def wait_for(self, predicate: Callable[[List[Any]], Any], timeout: float = 5.0,
                 what: str = "condition") -> Any:
        """Wait (scaled timeout) until predicate(calls) is true; AssertionError if not."""
        deadline = time.monotonic() + scaled(timeout)
        with self._cond:
            while True:
                result = predicate(self.calls)
                if result:
                    return result
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise AssertionError(
                        f"timed out after {scaled(timeout):g} s waiting for {what}; "
                        f"calls: {self.calls[-20:]!r}")
                self._cond.wait(remaining)

    def wait_count(self, n: int, timeout: float = 5.0) -> List[Any]:
        self.wait_for(lambda calls: len(calls) >= n, timeout, f"{n} calls")
        return self.snapshot()

    def wait_value(self, value: Any, timeout: float = 5.0, start: int = 0) -> int:
        """Wait until `value` is recorded (at index >= start); returns its index."""
        def found(calls: List[Any]) -> Optional[int]:
            for i in range(start, len(calls)):
                if calls[i] == value:
                    return i + 1
            return None
        return self.wait_for(found, timeout, f"{value!r}") - 1


def wait_flood_drained(got: Recorder, gate: Any, drained: Callable[[], bool],
                       total: int) -> list:
    """A slow callback held by `gate` while `total` values (0..total - 1)
    flooded in: once `drained()` (or after scaled(20) s), let it go and wait
    for the last value. The calls, (value, merged), are checked: in order,
    none twice, every value counted once (itself or merged into a later
    one), and fewer than half delivered (it did fall behind)."""
    deadline = time.monotonic() + scaled(20)
    while not drained() and time.monotonic() < deadline:
        time.sleep(0.01)
    gate.set()
    calls = got.wait_for(lambda c: c if c and c[-1][0] == total - 1 else None,
                         scaled(20), f"the last value {total - 1}")
    values = [value for value, _ in calls]
    assert values == sorted(set(values))                       # in order, none twice
    assert sum(1 + merged for _, merged in calls) == total     # every value counted
    assert len(calls) < total / 2                              # it did fall behind
    return calls


def frames_of(recorder: Recorder, can_id: int) -> list:
    return [f for f in recorder.snapshot() if f.id == can_id]


def package_env() -> dict:
    """Environment for a subprocess that must import the very canopenfd these
    tests import (installed in a venv, or the source tree with an in-place build)."""
    import canopenfd

    env = dict(os.environ)
    where = os.path.dirname(os.path.dirname(os.path.abspath(canopenfd.__file__)))
    env["PYTHONPATH"] = where + os.pathsep + env.get("PYTHONPATH", "")
    return env


# A neutral working directory: with the source tree as cwd, `python -m` would
# import its canopenfd/ (no compiled core there when the package is installed).
NEUTRAL_CWD = os.path.dirname(os.path.abspath(__file__))


def cli_command(*args: str) -> list:
    import sys

    return [sys.executable, "-m", "canopenfd", *args]


def run_cli(*args: str, timeout: float = 60):
    """Run `python -m canopenfd ARGS`; returns the CompletedProcess."""
    import subprocess

    return subprocess.run(cli_command(*args), capture_output=True, text=True,
                          timeout=scaled(timeout), env=package_env(), cwd=NEUTRAL_CWD,
                          check=False)


_virtual_buses: List[Any] = []


def virtual_bus(channel: str) -> Any:
    """A python-can virtual bus for a line (a Network never shuts down the
    user's bus): shut down by conftest after the test and its fixtures."""
    import can
    bus = can.Bus(interface="virtual", channel=channel)
    _virtual_buses.append(bus)
    return bus


def shutdown_virtual_buses() -> None:
    while _virtual_buses:
        _virtual_buses.pop().shutdown()
