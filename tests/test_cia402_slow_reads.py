"""CiA 402 `Drive` waits on a loaded host (the VM timeout of issue 18's bench):
a statusword read can come back long after the drive answered it, showing a
state the drive has since left. With 8 drives and a per-frame Python monitor
callback in the qemu VM such reads took up to 3 s, and enable() through the
cyclic RPDO timed out at SWITCHED ON right after sending 0x0F, although the
drive followed each RPDO within a few SYNCs. Here the delay is injected into
the master's reads of 0x6041 (the drive and bus run at full speed): the
walk and the waits must judge the drive by what it did, not by how long the
host took to hear it."""

from __future__ import annotations

import re
import time
from typing import Any

import pytest
from helpers import scaled

from canopenfd.profiles.cia402 import (Drive, DriveState, DriveTimeoutError,
                                       create_simulated_drive, drive_od)

NODE = 5


class SlowStatusword:
    """A remote node whose 0x6041 reads are slow: `before` s until the drive
    is asked (the request on its way), `after` s until the answer reaches the
    caller. Everything else goes to the node unchanged."""

    def __init__(self, node: Any, before: float, after: float) -> None:
        self._node, self._before, self._after = node, before, after
        self.reads = 0

    def __getattr__(self, name: str) -> Any:
        return getattr(self._node, name)

    def read(self, key: Any, **options: Any) -> Any:
        if key != (0x6041, 0):
            return self._node.read(key, **options)
        self.reads += 1
        time.sleep(self._before)
        value = self._node.read(key, **options)
        time.sleep(self._after)
        return value


@pytest.fixture
def slow_drive(net, bus_name):
    def make(before: float, after: float, timeout: float) -> Drive:
        create_simulated_drive(net.open_line(bus_name, mode="classic"), NODE)
        line = net.open_line(bus_name, mode="classic")
        node = SlowStatusword(line.add_node(NODE, od=drive_od("classic")), before, after)
        return Drive(node, timeout=timeout)
    return make


def test_cyclic_enable_with_reads_slower_than_a_third_of_the_timeout(slow_drive):
    """Three steps, each read 0.45 x timeout: the whole walk takes longer than
    one timeout, but the drive follows every controlword at once."""
    timeout = scaled(1.0)
    drive = slow_drive(0.225 * timeout, 0.225 * timeout, timeout)
    drive.cyclic("csp", period=0.005)
    try:
        started = time.monotonic()
        drive.enable()
        took = time.monotonic() - started
        assert drive.state is DriveState.OPERATION_ENABLED
        assert took > timeout          # the injected delay did make the walk long
        assert drive.node.reads >= 4   # each of the 3 steps was read, then the end
    finally:
        drive.stop_cyclic()


def test_a_stale_answer_after_the_deadline_is_asked_again(slow_drive):
    """switch_on() over the cyclic RPDO: the first read is answered before the
    RPDO has reached the drive and comes back after the deadline; the read
    asked after that shows SWITCHED ON."""
    timeout = scaled(0.2)
    drive = slow_drive(0.0, 2 * timeout, timeout)
    # a SYNC every 50 ms: the drive takes each RPDO at a SYNC after it, so
    # the read right after the command sees the old state
    drive.cyclic("csp", period=0.05)
    try:
        drive.shutdown()
        drive.switch_on()
        assert drive.state is DriveState.SWITCHED_ON
    finally:
        drive.stop_cyclic()


def test_progress_heard_after_the_deadline_counts(slow_drive):
    """enable() over the cyclic RPDO with answers coming back 2 x timeout
    late: the read after each command still sees the old state (the RPDO
    waits for a SYNC), the one after that, asked past the deadline, a new
    state: that is progress, and the walk goes on."""
    timeout = scaled(0.2)
    drive = slow_drive(0.0, 2 * timeout, timeout)
    drive.cyclic("csp", period=0.05)
    try:
        drive.enable()
        assert drive.state is DriveState.OPERATION_ENABLED
    finally:
        drive.stop_cyclic()


def test_a_drive_that_does_not_follow_still_times_out(net, bus_name):
    """Slow reads do not hide a drive that never moves: each step has the
    timeout from its controlword on, and the walk ends with the state reached."""
    od = drive_od("classic")
    od.get_variable(0x6041, 0).default = 0x0231       # stuck in Ready to switch on
    net.open_line(bus_name, mode="classic").create_local_node(NODE, od=od)
    line = net.open_line(bus_name, mode="classic")
    timeout = scaled(0.3)
    drive = Drive(SlowStatusword(line.add_node(NODE), 0.05, 0.05), timeout=timeout)
    started = time.monotonic()
    with pytest.raises(DriveTimeoutError, match=r"drive node 5: enable\(\): wanted OPERATION "
                       r"ENABLED, state reached READY TO SWITCH ON "
                       + re.escape(f"{timeout:g}") + r" s after controlword 0x0007 was sent") as caught:
        drive.enable()
    assert caught.value.reached is DriveState.READY_TO_SWITCH_ON
    assert time.monotonic() - started < timeout + scaled(1.0)   # one budget, not more
    assert drive.read(0x6040) == 0x07
