"""CallbackList when a callback blocks and another dispatcher thread fires
the same list meanwhile: calls wait behind the busy one, run one at a time and
in order, and a bounded backlog drops (and counts) only the oldest."""

from __future__ import annotations

import threading

from helpers import scaled

from canopenfd import _callbacks
from canopenfd._callbacks import CallbackList


def test_fires_from_another_thread_wait_behind_a_blocked_call_in_order(monkeypatch):
    monkeypatch.setattr(_callbacks, "_BACKLOG", 100)
    calls, running, overlap = [], [0], []
    release, entered = threading.Event(), threading.Event()

    def callback(value):
        running[0] += 1
        overlap.append(running[0])
        calls.append((value, threading.current_thread().name))
        if value == 0:
            entered.set()
            release.wait(scaled(10))
        running[0] -= 1

    callbacks = CallbackList("test")
    callbacks.add(callback)
    blocked = threading.Thread(target=callbacks.fire, args=(0,), name="blocked")
    blocked.start()
    assert entered.wait(scaled(5))
    for value in range(1, 106):           # another dispatcher thread: 105 calls, 100 kept
        callbacks.fire(value)
    assert [v for v, _ in calls] == [0]   # none ran beside the blocked call
    assert callbacks.dropped == 5
    release.set()
    blocked.join(scaled(5))
    assert [v for v, _ in calls] == [0] + list(range(6, 106))   # the oldest 5 dropped
    assert {name for _, name in calls} == {"blocked"}           # run by the busy thread
    assert max(overlap) == 1
    callbacks.fire(200)                   # free again: runs at once on the caller
    assert calls[-1] == (200, threading.current_thread().name)


def test_a_raising_callback_does_not_keep_the_list_busy():
    callbacks = CallbackList("test")
    seen = []

    def bad(value):
        seen.append(value)
        raise RuntimeError("user bug")
    callbacks.add(bad)
    callbacks.fire(1)
    other = threading.Thread(target=callbacks.fire, args=(2,))
    other.start()
    other.join(scaled(5))
    assert seen == [1, 2]
