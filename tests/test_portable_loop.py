"""The portable loop (what Windows and macOS run) on Linux: CANOPENFD_PORTABLE_LOOP=1
makes each new Network's thread wait on a condition variable until the next deadline
instead of epoll. tests/run_all.sh runs the mem:/python-can subset again under it; these
tests set the variable themselves, so they check it in every run."""

from __future__ import annotations

import time

import pytest
from helpers import Recorder, scaled

import canopenfd
from canopenfd import InterfaceError, NmtState

ENV = "CANOPENFD_PORTABLE_LOOP"


@pytest.fixture
def portable_net(monkeypatch):
    # Read by the C runtime when the Network is created.
    monkeypatch.setenv(ENV, "1")
    network = canopenfd.Network()
    try:
        yield network
    finally:
        network.close()


@pytest.mark.parametrize("mode", ["fd", "classic"])
def test_socketcan_channel_refused_naming_the_variable(portable_net, mode):
    with pytest.raises(InterfaceError, match=f"vcan0: SocketCAN lines need the epoll loop, "
                                             f"but {ENV}=1 selects the portable loop"):
        portable_net.open_line("vcan0", mode=mode)
    # The network stays usable for the lines the portable loop serves.
    portable_net.open_line("mem:after-refusal", mode=mode).create_local_node(1)


def test_heartbeats_keep_their_period(portable_net, bus_name):
    """Timers drive the wait: heartbeats of 20 ms arrive at about that period."""
    monitor = portable_net.open_line(bus_name, monitor=True)
    beats = Recorder()
    monitor.on_frame(lambda frame: frame.id == 0x707 and beats(frame))
    portable_net.open_line(bus_name).create_local_node(7, heartbeat_ms=20)
    beats.wait_count(12, timeout=scaled(5.0))
    times = [frame.timestamp for frame in beats.snapshot()[1:12]]   # after the boot-up
    period = (times[-1] - times[0]) / (len(times) - 1)
    assert 0.015 < period < 0.040 * max(1.0, scaled(1.0))


def test_woken_at_once_by_a_command_and_closes_fast(portable_net, bus_name):
    """No deadline armed: an NMT command from Python wakes the thread (rt_wake)."""
    master = portable_net.open_line(bus_name)
    remote = master.add_node(9, heartbeat_timeout_ms=0)
    bootups = Recorder()
    remote.on_bootup(bootups)
    device = portable_net.open_line(bus_name).create_local_node(9, heartbeat_ms=0)
    bootups.wait_count(1, timeout=scaled(5.0))
    start = time.monotonic()
    master.nmt.send(canopenfd.NmtCommand.START, 9)
    device.nmt.wait_for_state(NmtState.OPERATIONAL, timeout=scaled(5.0))
    assert time.monotonic() - start < scaled(0.5)
    start = time.monotonic()
    portable_net.close()
    assert time.monotonic() - start < scaled(2.0)
