"""The facade over the in-process bus (membus): fast, no kernel CAN needed."""

from __future__ import annotations

import logging
import threading
import time

import pytest
from helpers import Recorder, frames_of, scaled

import canopenfd
from canopenfd import ClosedError, ConfigurationError, NmtCommand, NmtState

T = 5.0  # default wait, scaled by CANOPENFD_TIME_SCALE


def wait(x) -> float:
    return scaled(x)


# ------------------------------------------------------------------ boot-up, states
def test_bootup_seen_by_another_line(net, bus_name):
    watcher = net.open_line(bus_name)
    device_line = net.open_line(bus_name)
    node = watcher.add_node(5)
    bootups = Recorder()
    node.on_bootup(bootups)
    assert node.state == NmtState.UNKNOWN

    device = device_line.create_local_node(5)
    bootups.wait_count(1)
    assert node.state == NmtState.PRE_OPERATIONAL
    assert node.state == "PRE-OPERATIONAL"          # python-canopen style comparison
    assert device.state == NmtState.PRE_OPERATIONAL
    assert device.nmt.state == NmtState.PRE_OPERATIONAL


def test_wait_for_bootup_blocks_until_the_bootup(net, bus_name):
    watcher = net.open_line(bus_name)
    device_line = net.open_line(bus_name)
    node = watcher.add_node(7)
    timer = threading.Timer(0.1, lambda: device_line.create_local_node(7))
    timer.start()
    try:
        node.nmt.wait_for_bootup(timeout=wait(T))
    finally:
        timer.join()
    assert node.nmt.state == "PRE-OPERATIONAL"


def test_state_table(net, bus_name):
    table_line = net.open_line(bus_name)
    me = table_line.create_local_node(1)
    lines = [net.open_line(bus_name) for _ in range(2)]
    watched = [table_line.add_node(n) for n in (5, 6)]
    lines[0].create_local_node(5, heartbeat_ms=50)
    lines[1].create_local_node(6, heartbeat_ms=50)
    for node in watched:
        node.wait_for_heartbeat(timeout=wait(T))
    assert table_line.states == {1: NmtState.PRE_OPERATIONAL, 5: NmtState.PRE_OPERATIONAL,
                                 6: NmtState.PRE_OPERATIONAL}
    table_line.nmt.start(6)
    watched[1].wait_for_state("OPERATIONAL", timeout=wait(T))
    states = table_line.states
    assert states[6] == NmtState.OPERATIONAL and states[5] == NmtState.PRE_OPERATIONAL
    assert me.state == NmtState.PRE_OPERATIONAL


def test_states_lists_unwatched_nodes_too(net, bus_name):
    observer = net.open_line(bus_name)
    device_line = net.open_line(bus_name)
    watched = observer.add_node(9)
    device_line.create_local_node(8, heartbeat_ms=30)
    device_line2 = net.open_line(bus_name)
    device_line2.create_local_node(9, heartbeat_ms=30)
    watched.wait_for_heartbeat(timeout=wait(T))
    deadline = time.monotonic() + wait(T)
    while 8 not in observer.states and time.monotonic() < deadline:
        time.sleep(0.02)  # no event exists for an unwatched node's heartbeat
    assert observer.states[8] == NmtState.PRE_OPERATIONAL


# ------------------------------------------------------------------ NMT
@pytest.fixture
def pair(net, bus_name):
    """A master line (local node 1) watching device node 5 (heartbeat 30 ms)."""
    master = net.open_line(bus_name)
    master.create_local_node(1)
    remote = master.add_node(5, heartbeat_timeout_ms=0)
    device_line = net.open_line(bus_name)
    bootups = Recorder()
    remote.on_bootup(bootups)
    device = device_line.create_local_node(5, heartbeat_ms=30)
    bootups.wait_count(1)
    return master, remote, device


@pytest.mark.parametrize("command, target", [
    ("start", NmtState.OPERATIONAL),
    ("stop", NmtState.STOPPED),
    ("pre_operational", NmtState.PRE_OPERATIONAL),
])
def test_nmt_command_to_one_node(pair, command, target):
    master, remote, device = pair
    if target == NmtState.PRE_OPERATIONAL:
        master.nmt.stop(5)
        device.wait_for_state(NmtState.STOPPED, timeout=wait(T))
    changes = Recorder()
    device.on_state_change(changes)
    getattr(master.nmt, command)(5)
    device.wait_for_state(target, timeout=wait(T))
    remote.wait_for_state(target, timeout=wait(T))
    assert device.state == target
    assert remote.nmt.state == target
    # Events of earlier transitions may still be on their way to the
    # callback (state reads above come straight from the runtime).
    changes.wait_for(lambda calls: calls and calls[-1][1] == target, what=f"-> {target}")


def test_nmt_send_with_codes_names_and_python_canopen_setter(pair):
    master, remote, device = pair
    master.nmt.send(0x01, 5)
    device.wait_for_state("OPERATIONAL", timeout=wait(T))
    master.nmt.send("stop", "5")
    device.wait_for_state("STOPPED", timeout=wait(T))
    remote.nmt.state = "PRE-OPERATIONAL"          # python-canopen: sends the command
    device.wait_for_state("PRE-OPERATIONAL", timeout=wait(T))
    remote.nmt.send_command(NmtCommand.START)
    remote.wait_for_state(NmtState.OPERATIONAL, timeout=wait(T))


def test_nmt_to_all_nodes(net, bus_name):
    master = net.open_line(bus_name)
    devices = []
    for node_id in (5, 6, 7):
        devices.append(net.open_line(bus_name).create_local_node(node_id, heartbeat_ms=0))
    for device in devices:
        device.wait_for_state(NmtState.PRE_OPERATIONAL, timeout=wait(T))
    master.nmt.start("all")
    for device in devices:
        device.wait_for_state(NmtState.OPERATIONAL, timeout=wait(T))
    master.nmt.stop(0)
    for device in devices:
        device.wait_for_state(NmtState.STOPPED, timeout=wait(T))
    master.nmt.send_command("PRE-OPERATIONAL")    # python-canopen network.nmt style
    for device in devices:
        device.wait_for_state(NmtState.PRE_OPERATIONAL, timeout=wait(T))


def test_include_self(pair):
    master, _remote, device = pair
    me = master.local_node
    master.nmt.start("all")
    device.wait_for_state(NmtState.OPERATIONAL, timeout=wait(T))
    assert me.state == NmtState.PRE_OPERATIONAL   # not echoed back, not included
    master.nmt.stop("all", include_self=True)
    device.wait_for_state(NmtState.STOPPED, timeout=wait(T))
    me.wait_for_state(NmtState.STOPPED, timeout=wait(T))
    master.nmt.start(1)                            # its own id: applied locally
    me.wait_for_state(NmtState.OPERATIONAL, timeout=wait(T))


def test_local_nmt_state_setter(pair):
    _master, remote, device = pair
    device.nmt.state = "OPERATIONAL"
    device.wait_for_state(NmtState.OPERATIONAL, timeout=wait(T))
    remote.wait_for_state(NmtState.OPERATIONAL, timeout=wait(T))  # its heartbeat tells


def test_veto_of_operational(pair):
    master, _remote, device = pair
    vetoes = Recorder()
    device.on_veto(vetoes)
    device.allow_operational = False
    assert device.allow_operational is False
    master.nmt.start(5)
    vetoes.wait_count(1)
    assert device.state == NmtState.PRE_OPERATIONAL
    master.nmt.stop(5)                              # other transitions still work
    device.wait_for_state(NmtState.STOPPED, timeout=wait(T))
    device.allow_operational = True
    master.nmt.start(5)
    device.wait_for_state(NmtState.OPERATIONAL, timeout=wait(T))
    assert len(vetoes) == 1


@pytest.mark.parametrize("reset, kind", [
    ("reset_node", NmtCommand.RESET_NODE),
    ("reset_communication", NmtCommand.RESET_COMMUNICATION),
])
def test_reset_gives_new_bootup_and_restores_default_heartbeat(net, bus_name, reset, kind):
    monitor = net.open_line(bus_name, monitor=True)
    frames = Recorder()
    monitor.on_frame(frames)
    master = net.open_line(bus_name)
    remote = master.add_node(5)
    bootups, resets, changes = Recorder(), Recorder(), Recorder()
    remote.on_bootup(bootups)
    device = net.open_line(bus_name).create_local_node(5, heartbeat_ms=40)
    device.on_reset(resets)
    device.on_state_change(changes)
    bootups.wait_count(1)
    master.nmt.start(5)
    device.wait_for_state(NmtState.OPERATIONAL, timeout=wait(T))
    device.heartbeat_ms = 1000                      # changed, then reset restores 40
    assert device.heartbeat_ms == 1000

    getattr(master.nmt, reset)(5)
    bootups.wait_count(2)
    assert resets.wait_count(1) == [kind]
    device.wait_for_state(NmtState.PRE_OPERATIONAL, timeout=wait(T))
    assert device.heartbeat_ms == 40
    # the state callbacks run on the dispatcher thread, maybe after the wait above
    reset_seen = changes.wait_value((NmtState.OPERATIONAL, NmtState.INITIALISING))
    changes.wait_value((NmtState.INITIALISING, NmtState.PRE_OPERATIONAL), start=reset_seen)
    assert (NmtState.OPERATIONAL, NmtState.INITIALISING) in changes.snapshot()
    assert changes.snapshot()[-1] == (NmtState.INITIALISING, NmtState.PRE_OPERATIONAL)
    # The default period is back: several heartbeats within half a second.
    reset_at = time.monotonic()
    frames.wait_for(lambda fs: sum(1 for f in fs if f.id == 0x705 and f.data == b"\x7f"
                                   and f.timestamp > reset_at) >= 4,
                    timeout=2.0, what="heartbeats at the default period")


def test_wait_for_state_timeout_message(pair):
    _master, remote, device = pair
    with pytest.raises(TimeoutError, match=r"node 5 .*still PRE-OPERATIONAL, not OPERATIONAL"):
        device.wait_for_state("OPERATIONAL", timeout=0.05)
    with pytest.raises(TimeoutError, match=r"node 5 on line .*STOPPED"):
        remote.wait_for_state("STOPPED", timeout=0.05)


# ------------------------------------------------------------------ heartbeat
def _count_heartbeats(frames: Recorder, node_id: int, since: float, until: float) -> int:
    return sum(1 for f in frames.snapshot()
               if f.id == 0x700 + node_id and len(f.data) == 1 and f.data != b"\0"
               and since <= f.timestamp < until)


def test_heartbeat_producer_period(net, bus_name):
    monitor = net.open_line(bus_name, monitor=True)
    frames = Recorder()
    monitor.on_frame(frames)
    net.open_line(bus_name).create_local_node(5, heartbeat_ms=50)
    start = time.monotonic()
    time.sleep(1.0)                              # let protocol time pass
    count = _count_heartbeats(frames, 5, start, start + 1.0)
    assert 5 <= count <= 40, f"{count} heartbeats in 1 s at 50 ms (expected about 20)"


def test_heartbeat_change_takes_effect(net, bus_name):
    monitor = net.open_line(bus_name, monitor=True)
    frames = Recorder()
    monitor.on_frame(frames)
    device = net.open_line(bus_name).create_local_node(5, heartbeat_ms=500)
    frames.wait_for(lambda fs: any(f.id == 0x705 for f in fs), what="boot-up")
    start = time.monotonic()
    time.sleep(0.6)
    slow = _count_heartbeats(frames, 5, start, start + 0.6)
    device.heartbeat_ms = 20
    assert device.heartbeat_ms == 20
    changed = time.monotonic()
    time.sleep(0.6)
    fast = _count_heartbeats(frames, 5, changed, changed + 0.6)
    assert slow <= 3, f"{slow} heartbeats in 0.6 s at 500 ms"
    assert fast >= 8, f"{fast} heartbeats in 0.6 s at 20 ms (expected about 30)"
    device.heartbeat_ms = 0
    off = time.monotonic()
    time.sleep(0.3)
    assert _count_heartbeats(frames, 5, off + 0.05, off + 0.3) == 0


def test_heartbeat_lost_and_started(net, bus_name):
    watcher = net.open_line(bus_name)
    remote = watcher.add_node(5, heartbeat_timeout_ms=150)
    assert remote.heartbeat_timeout_ms == 150
    started, lost, beats = Recorder(), Recorder(), Recorder()
    remote.on_heartbeat_started(started)
    remote.on_heartbeat_lost(lost)
    remote.nmt.add_heartbeat_callback(beats)
    device = net.open_line(bus_name).create_local_node(5, heartbeat_ms=40)
    started.wait_count(1)
    assert remote.heartbeat_alive is True
    assert remote.nmt.wait_for_heartbeat(timeout=wait(T)) == NmtState.PRE_OPERATIONAL
    # the heartbeat callback runs on the dispatcher thread, maybe after that wait
    beats.wait_value(NmtState.PRE_OPERATIONAL)
    assert NmtState.PRE_OPERATIONAL in beats.snapshot()

    stopped_at = time.monotonic()
    device.heartbeat_ms = 0
    lost.wait_count(1, timeout=3.0)
    elapsed = lost.times[0] - stopped_at
    assert elapsed >= 0.1, f"lost after {elapsed:.3f} s, consumer time is 0.15 s"
    assert remote.heartbeat_alive is False
    assert len(started) == 1

    device.heartbeat_ms = 40
    started.wait_count(2)
    assert remote.heartbeat_alive is True
    assert len(lost) == 1


def test_heartbeat_timeout_change_and_remove_node(net, bus_name):
    watcher = net.open_line(bus_name)
    remote = watcher.add_node(5)
    lost, started = Recorder(), Recorder()
    remote.on_heartbeat_lost(lost)
    remote.on_heartbeat_started(started)
    device = net.open_line(bus_name).create_local_node(5, heartbeat_ms=30)
    started.wait_count(1)
    again = watcher.add_node(5, heartbeat_timeout_ms=100)   # same node: timeout updated
    assert again is remote and remote.heartbeat_timeout_ms == 100
    assert remote.heartbeat_alive is True         # monitoring goes on, no new "started"
    device.heartbeat_ms = 0
    lost.wait_count(1, timeout=3.0)
    assert len(started) == 1
    watcher.remove_node(5)
    assert 5 not in watcher.nodes
    with pytest.raises(ConfigurationError, match="node 5 is not watched"):
        watcher.remove_node(5)


# ------------------------------------------------------------------ wrong use
def test_wrong_use_raises_configuration_errors(net, bus_name):
    line = net.open_line(bus_name)
    with pytest.raises(ConfigurationError, match="node-id 200 outside 1..127"):
        line.create_local_node(200)
    with pytest.raises(ConfigurationError, match="node-id 0 outside 1..127"):
        line.create_local_node(0)
    with pytest.raises(ConfigurationError, match="heartbeat_ms -1 ms outside 0..65535"):
        line.create_local_node(5, heartbeat_ms=-1)
    with pytest.raises(ConfigurationError, match="heartbeat_ms 70000 ms outside 0..65535"):
        line.create_local_node(5, heartbeat_ms=70000)
    node = line.create_local_node(5)
    with pytest.raises(ConfigurationError, match=f"line '{bus_name}' already has local node 5"):
        line.create_local_node(6)
    with pytest.raises(ConfigurationError, match="heartbeat_ms 65536 ms"):
        node.heartbeat_ms = 65536
    with pytest.raises(ConfigurationError, match="node-id 128 outside 1..127"):
        line.add_node(128)
    with pytest.raises(ConfigurationError, match="node-id 5 is this line's local node"):
        line.add_node(5)
    with pytest.raises(ConfigurationError, match="heartbeat_timeout_ms -5 ms"):
        line.add_node(6, heartbeat_timeout_ms=-5)
    with pytest.raises(ConfigurationError, match="node-id 200 outside 0..127"):
        line.nmt.start(200)
    with pytest.raises(ConfigurationError, match="NMT command 0x55 unknown"):
        line.nmt.send(0x55, 5)
    with pytest.raises(ConfigurationError, match="NMT command 'jump' unknown"):
        line.nmt.send("jump", 5)
    with pytest.raises(ConfigurationError, match="NMT target 'some' invalid"):
        line.nmt.start("some")
    with pytest.raises(ConfigurationError, match="NMT state 'RUNNING' unknown"):
        node.wait_for_state("RUNNING", timeout=0.1)
    with pytest.raises(ConfigurationError, match="monitor=False"):
        line.on_frame(print)
    with pytest.raises(ConfigurationError, match="callable"):
        line.on_comm_event(42)
    with pytest.raises(ConfigurationError, match="timeout must be >= 0"):
        node.wait_for_state("STOPPED", timeout=-1)


def test_wrong_line_options(net, bus_name):
    with pytest.raises(ConfigurationError, match="line mode 'turbo' unknown"):
        net.open_line(bus_name, mode="turbo")
    with pytest.raises(ConfigurationError, match="exactly one of channel"):
        net.open_line()
    with pytest.raises(ConfigurationError, match="needs a name"):
        net.open_line("mem:")
    with pytest.raises(ConfigurationError, match="rx_queue"):
        net.open_line(bus_name, rx_queue=-1)
    with pytest.raises(ConfigurationError, match="python-can Bus"):
        net.open_line(bus=object())
    net.open_line(bus_name, mode="fd")
    with pytest.raises(ConfigurationError):
        net.open_line(bus_name, mode="classic")     # that bus already runs FD


def test_send_frame_checks(net, bus_name):
    fd = net.open_line(bus_name)
    classic = net.open_line(bus_name + "-c", mode="classic")
    with pytest.raises(ConfigurationError, match="CAN-ID 2048 outside 0..0x7FF"):
        fd.send_frame(0x800, b"")
    with pytest.raises(ConfigurationError, match="65 bytes, an FD frame holds 64"):
        fd.send_frame(0x100, bytes(65))
    with pytest.raises(ConfigurationError, match="9 bytes, a classic frame holds 8"):
        classic.send_frame(0x100, bytes(9))
    with pytest.raises(ConfigurationError, match="FD frame cannot go on a classic line"):
        classic.send_frame(0x100, b"", fd=True)
    with pytest.raises(ConfigurationError, match="bit-rate switch needs an FD frame"):
        fd.send_frame(0x100, b"", fd=False, brs=True)
    fd.send_frame(0x1ABCDEF0, b"\1", extended=True)


# ------------------------------------------------------------------ close
def test_use_after_close_raises_closed_error(bus_name):
    net = canopenfd.Network()
    line = net.open_line(bus_name)
    node = line.create_local_node(5)
    remote = line.add_node(6)
    net.close()
    assert net.closed
    for call in (lambda: line.states, lambda: line.stats, lambda: line.nmt.start(6),
                 lambda: node.state, lambda: remote.state, lambda: line.add_node(7),
                 lambda: setattr(node, "heartbeat_ms", 10), lambda: net.open_line(bus_name),
                 lambda: line.send_frame(0x100, b""), lambda: remote.wait_for_bootup(1)):
        with pytest.raises(ClosedError, match="closed"):
            call()
    net.close()                                     # idempotent


def test_close_is_idempotent_and_quick(bus_name):
    start = time.monotonic()
    with canopenfd.Network() as net:
        for i in range(3):
            net.open_line(bus_name).create_local_node(i + 1, heartbeat_ms=10)
        net.close()
        net.close()
    assert time.monotonic() - start < wait(5)
    assert not net._active.is_alive()


def test_close_wakes_waiters_with_closed_error(bus_name):
    net = canopenfd.Network()
    line = net.open_line(bus_name)
    remote = line.add_node(9)
    errors = Recorder()

    def waiter():
        try:
            remote.wait_for_bootup(timeout=30)
        except Exception as exc:  # noqa: BLE001
            errors(exc)

    thread = threading.Thread(target=waiter)
    thread.start()
    time.sleep(0.05)
    net.close()
    thread.join(wait(5))
    assert not thread.is_alive()
    assert isinstance(errors.wait_count(1)[0], ClosedError)


def test_close_with_transfers_waits_and_callbacks_in_flight(bus_name):
    """close() while transfers run (waited for in C, awaited, polled), a
    blocking wait waits and a callback runs on the dispatcher: every waiter
    gets ClosedError (or its transfer's end), every thread ends, nothing hangs
    (daemon threads: a waiter left hanging fails the test, not the suite)."""
    import asyncio

    from canopenfd.od import DataType, ODVariable, demo_od

    net = canopenfd.Network()
    line = net.open_line(bus_name, mode="fd")
    od = demo_od("fd")
    domains = range(0x2300, 0x2304)    # one per transfer: a server refuses two at once (0x20)
    for index in domains:
        od.add_object(ODVariable(f"Domain {index:X}", index, 0, DataType.DOMAIN, "rw",
                                 max_length=4 << 20))
    device = line.create_local_node(5, od=od, boot=False)
    for index in domains:
        device.serve_domain(index, 4 << 20)
    device.boot()
    for index in domains:
        device[index].data = bytes(4 << 20)        # long segmented uploads
    tool = net.open_line(bus_name, mode="fd")
    remote = tool.add_node(5)
    outcomes = Recorder()
    in_callback = threading.Event()

    def record(call):
        try:
            call()
            outcomes("ended")
        except ClosedError:
            outcomes("closed")
        except Exception as exc:  # noqa: BLE001 - anything else fails the test below
            outcomes(exc)

    def slow_callback():
        in_callback.set()
        time.sleep(0.3)                             # the dispatcher is busy at the close

    tool.add_node(9).on_bootup(slow_callback)
    transfers = [remote.usdo.start_upload(index) for index in domains[:3]]
    threads = [threading.Thread(target=record, args=(t.result,), daemon=True) for t in transfers[:2]]
    threads.append(threading.Thread(target=record, args=(
        lambda: asyncio.run(_awaited(transfers[2])),), daemon=True))
    threads.append(threading.Thread(target=record, args=(
        lambda: tool.add_node(10).wait_for_bootup(timeout=30),), daemon=True))
    threads.append(threading.Thread(target=record, args=(
        lambda: remote.usdo.upload(domains[3]),), daemon=True))  # waits in C, no event
    for thread in threads:
        thread.start()
    net.open_line(bus_name).create_local_node(9)    # node 9's boot-up: the slow callback
    assert in_callback.wait(wait(5))
    time.sleep(0.02)
    start = time.monotonic()
    net.close()
    for thread in threads:
        thread.join(wait(10))
    assert not any(thread.is_alive() for thread in threads), "a waiter still waits"
    assert time.monotonic() - start < wait(10)
    results = outcomes.snapshot()
    assert len(results) == len(threads)
    assert all(r in ("closed", "ended") for r in results), results
    assert results.count("closed") >= 1
    net._active.join(wait(5))
    assert not net._active.is_alive()


async def _awaited(transfer):
    return await transfer


def test_close_from_a_callback(bus_name):
    net = canopenfd.Network()
    watcher = net.open_line(bus_name)
    remote = watcher.add_node(5)
    closed = threading.Event()

    def close_now():
        net.close()
        closed.set()

    remote.on_bootup(close_now)
    net.open_line(bus_name).create_local_node(5)
    assert closed.wait(wait(5))
    assert net.closed
    net._active.join(wait(5))
    assert not net._active.is_alive()


def test_wait_from_a_callback_is_refused(pair):
    master, _remote, device = pair
    errors = Recorder()

    def bad(old, new):
        try:
            device.wait_for_state("STOPPED", timeout=1)
        except ConfigurationError as exc:
            errors(exc)

    device.on_state_change(bad)
    master.nmt.start(5)
    assert "called from a callback" in str(errors.wait_count(1)[0])


def test_callback_exception_is_logged_and_dispatch_goes_on(pair, caplog):
    master, _remote, device = pair
    good = Recorder()

    def broken(old, new):
        raise RuntimeError("boom in user code")

    device.on_state_change(broken)
    device.on_state_change(good)
    with caplog.at_level(logging.ERROR, logger="canopenfd"):
        master.nmt.start(5)
        good.wait_count(1)
        master.nmt.stop(5)
        good.wait_count(2)
    assert "boom in user code" in caplog.text
    assert [c[1] for c in good.snapshot()] == [NmtState.OPERATIONAL, NmtState.STOPPED]


# ------------------------------------------------------------------ malformed frames
def test_malformed_frames_are_counted_and_change_nothing(net, bus_name):
    receiver = net.open_line(bus_name)
    node = receiver.create_local_node(5, heartbeat_ms=0)
    sentinel = receiver.add_node(10)
    sender = net.open_line(bus_name)
    node.wait_for_state(NmtState.PRE_OPERATIONAL, timeout=wait(T))
    before = receiver.stats

    sender.send_frame(0x000, b"\x01")               # NMT, 1 byte
    sender.send_frame(0x000, b"\x01\x05\x00")       # NMT, 3 bytes
    sender.send_frame(0x000, b"\x55\x05")           # unknown command
    sender.send_frame(0x000, b"\x01\xc8")           # node-id 200
    sender.send_frame(0x709, b"\x05\x00")           # heartbeat of 2 bytes
    sender.send_frame(0x709, b"\x33")               # invalid state byte
    sender.send_frame(0x700, b"\x05")               # heartbeat of node-id 0
    sender.send_frame(0x70A, b"\x05")               # sentinel: a good heartbeat
    sentinel.wait_for_state(NmtState.OPERATIONAL, timeout=wait(T))

    after = receiver.stats
    delta = {k: after[k] - before[k] for k in after}
    assert delta["nmt_bad_length"] == 2
    assert delta["nmt_bad_command"] == 1
    assert delta["nmt_bad_node"] == 1
    assert delta["hb_bad_length"] == 1
    assert delta["hb_bad_state"] == 1
    assert delta["hb_bad_node"] == 1
    assert delta["rx_frames"] >= 8
    assert node.state == NmtState.PRE_OPERATIONAL
    assert 9 not in receiver.states
    assert receiver.states[10] == NmtState.OPERATIONAL


# ------------------------------------------------------------------ monitor
@pytest.mark.parametrize("mode, brs", [("fd", True), ("fd", False), ("classic", False)])
def test_monitor_sees_exact_bytes(net, bus_name, mode, brs):
    monitor = net.open_line(bus_name, mode=mode, monitor=True)
    frames = Recorder()
    monitor.on_frame(frames)
    master = net.open_line(bus_name, mode=mode, brs=brs)
    device = net.open_line(bus_name, mode=mode, brs=brs).create_local_node(5, heartbeat_ms=50)
    frames.wait_for(lambda fs: len(frames_of_list(fs, 0x705)) >= 2, what="boot-up + heartbeat")
    master.nmt.start(5)
    device.wait_for_state(NmtState.OPERATIONAL, timeout=wait(T))
    frames.wait_for(lambda fs: any(f.id == 0x705 and f.data == b"\x05" for f in fs),
                    what="an OPERATIONAL heartbeat")
    # the NMT command is the master's frame, not the device's: wait for it too
    frames.wait_for(lambda fs: frames_of_list(fs, 0x000), what="the NMT start")

    fd = mode == "fd"
    boot = frames_of(frames, 0x705)[0]
    assert (boot.data, boot.fd, boot.brs, boot.ext, boot.rtr, boot.tx) == (
        b"\x00", fd, brs and fd, False, False, False)
    heartbeat = frames_of(frames, 0x705)[1]
    assert (heartbeat.data, heartbeat.fd, heartbeat.brs) == (b"\x7f", fd, brs and fd)
    nmt = frames_of(frames, 0x000)[0]
    assert (nmt.data, nmt.fd, nmt.brs) == (b"\x01\x05", fd, brs and fd)
    assert all(f.timestamp > 0 for f in frames.snapshot())


def frames_of_list(frames, can_id):
    return [f for f in frames if f.id == can_id]


def test_monitor_sees_its_own_frames_as_tx(net, bus_name):
    monitor = net.open_line(bus_name, monitor=True)
    other = net.open_line(bus_name, monitor=True)
    mine, theirs = Recorder(), Recorder()
    monitor.on_frame(mine)
    other.on_frame(theirs)
    monitor.send_frame(0x181, bytes(range(9)))      # FD: padded to 12 bytes
    expected = bytes(range(9)) + bytes(3)
    got = theirs.wait_count(1)[0]
    assert (got.id, got.data, got.fd, got.brs, got.tx) == (0x181, expected, True, True, False)
    own = mine.wait_count(1)[0]
    assert (own.id, own.data, own.tx) == (0x181, expected, True)
    assert canopenfd.decode(got) == "TPDO1 node 1 00 01 02 03 04 05 06 07 08 00 00 00 [FD BRS]"


def test_boot_later_lets_callbacks_see_the_first_transition(net, bus_name):
    watcher = net.open_line(bus_name)
    remote = watcher.add_node(5)
    line = net.open_line(bus_name)
    node = line.create_local_node(5, heartbeat_ms=20, boot=False)
    assert not node.booted and node.state == NmtState.INITIALISING
    changes, vetoes = Recorder(), Recorder()
    node.on_state_change(changes)
    node.on_veto(vetoes)
    node.allow_operational = False                  # works before boot too
    node.heartbeat_ms = 30                          # becomes the default 0x1017
    with pytest.raises(ConfigurationError, match="not booted yet"):
        node.apply("start")
    node.boot()
    assert changes.wait_count(1)[0] == (NmtState.INITIALISING, NmtState.PRE_OPERATIONAL)
    remote.wait_for_heartbeat(timeout=wait(T))
    node.apply("start")
    vetoes.wait_count(1)
    with pytest.raises(ConfigurationError, match="already booted"):
        node.boot()
    seen = len(changes)
    node.apply("reset-node")
    changes.wait_value((NmtState.INITIALISING, NmtState.PRE_OPERATIONAL), start=seen)
    assert changes.snapshot()[seen] == (NmtState.PRE_OPERATIONAL, NmtState.INITIALISING)
    assert node.heartbeat_ms == 30


def test_driver_stats_of_an_in_process_line(net, bus_name):
    """line.driver_stats on a membus line: no socket, so its socket counters
    stay zero, while the runtime thread's wake-ups are counted."""
    line = net.open_line(bus_name)
    other = net.open_line(bus_name)
    before = line.driver_stats
    assert set(before) == {"kernel_drops", "error_frames", "tx_deferred", "tx_refused",
                           "iface_down", "host_pending", "rx_frames", "rx_calls", "tx_frames",
                           "tx_calls", "loop_wakeups", "host_rx_waits"}
    other.send_frame(0x123, b"\x01")
    deadline = time.monotonic() + wait(T)
    while line.stats["rx_frames"] == 0 and time.monotonic() < deadline:
        time.sleep(0.01)
    after = line.driver_stats
    assert after["loop_wakeups"] > before["loop_wakeups"]
    assert line.stats["rx_frames"] >= 1
    assert [k for k in after if k != "loop_wakeups" and after[k] != 0] == []


def test_a_blocking_callback_is_reported_and_the_other_events_go_on(bus_name, caplog):
    net = canopenfd.Network(stall_report_s=0.3)
    try:
        line = net.open_line(bus_name)
        slow = line.add_node(5)
        others = Recorder()
        line.add_node(6).on_bootup(lambda: others("6"))
        line.add_node(7).on_bootup(lambda: others("7"))
        release, calls, running, overlap = threading.Event(), Recorder(), [0], []

        def blocking():
            running[0] += 1
            overlap.append(running[0])
            calls(threading.current_thread().name)
            release.wait(wait(10))                # blocks its dispatcher thread
            running[0] -= 1
        slow.on_bootup(blocking)
        with caplog.at_level("WARNING", logger="canopenfd"):
            node5 = net.open_line(bus_name).create_local_node(5)
            calls.wait_count(1)
            for node_id in (6, 7):
                net.open_line(bus_name).create_local_node(node_id)
            # a new dispatcher thread delivers them while node 5's callback blocks
            assert sorted(others.wait_count(2, wait(5))) == ["6", "7"]
            assert (net.dispatcher_stalls, net.blocked_dispatchers) == (1, 1)
            node5.apply("reset-node")             # node 5 boots again: its callback is busy,
            time.sleep(0.3)                       # so that call waits for the first one
            assert len(calls) == 1
            release.set()
            calls.wait_count(2)
            assert overlap == [1, 1]              # one call at a time
        deadline = time.monotonic() + wait(5)
        while net.blocked_dispatchers and time.monotonic() < deadline:
            time.sleep(0.02)
        assert net.blocked_dispatchers == 0       # the blocked thread ended once released
        text = " ".join(r.getMessage() for r in caplog.records)
        assert "HEARTBEAT event of line" in text and "held the dispatcher" in text
        assert "a new dispatcher thread delivers the other events meanwhile" in text
        assert net.dispatcher_stalls == 1                # reported once per stall
    finally:
        net.close()
    with pytest.raises(ConfigurationError, match="stall_report_s"):
        canopenfd.Network(stall_report_s=0)


def test_callbacks_that_never_return_leave_close_quick_and_relief_bounded(bus_name, caplog):
    net = canopenfd.Network(stall_report_s=0.2)
    release = threading.Event()
    blocked = Recorder()
    try:
        line = net.open_line(bus_name)
        for node_id in range(1, 7):
            line.add_node(node_id).on_bootup(
                lambda n=node_id: (blocked(n), release.wait(wait(30))))
        with caplog.at_level("WARNING", logger="canopenfd"):
            for node_id in range(1, 7):
                net.open_line(bus_name).create_local_node(node_id)
            # 4 blocked threads are relieved; the 5th blocked dispatcher is the last
            assert sorted(blocked.wait_count(5, wait(10))) == [1, 2, 3, 4, 5]
            deadline = time.monotonic() + wait(5)
            while net.dispatcher_stalls < 5 and time.monotonic() < deadline:
                time.sleep(0.02)
            time.sleep(0.5)
            assert len(blocked) == 5 and net.blocked_dispatchers == 4
        text = " ".join(r.getMessage() for r in caplog.records)
        assert "every other event of the network waits (5 dispatcher threads" in text
        start = time.monotonic()
        with caplog.at_level("ERROR", logger="canopenfd"):
            net.close()
        assert time.monotonic() - start < wait(2)
        assert "runtime not freed" not in caplog.text     # no thread is inside it
    finally:
        release.set()
        net.close()
    deadline = time.monotonic() + wait(5)
    while any(t.name == "canopenfd-dispatch" and t.is_alive() for t in threading.enumerate()) \
            and time.monotonic() < deadline:
        time.sleep(0.02)


def test_events_lost_in_a_sustained_overload_are_reported_once_per_burst(bus_name, caplog):
    net = canopenfd.Network(event_capacity=16)
    try:
        monitor = net.open_line(bus_name, monitor=True)
        monitor.on_frame(lambda frame: time.sleep(0.001))   # slower than the sender
        sender = net.open_line(bus_name)
        with caplog.at_level("WARNING", logger="canopenfd"):
            for i in range(3000):
                sender.send_frame(0x100, bytes([i & 0xFF]))
                if i % 100 == 0:
                    time.sleep(0.005)    # the dispatcher reads meanwhile: losses at many reads
            deadline = time.monotonic() + wait(10)
            while not any("lost in" in r.getMessage() for r in caplog.records) and \
                    time.monotonic() < deadline:
                time.sleep(0.05)
        lost = [r.getMessage() for r in caplog.records if "runtime events lost" in r.getMessage()]
        assert net.events_lost > 0
        assert len(lost) == 2, lost                      # the start, then the total
        assert "the event queue is full" in lost[0]
        assert f"({net.events_lost} lost since the network opened)" in lost[1]
    finally:
        net.close()


def test_python_canopen_habits_on_a_line(net, bus_name, tmp_path):
    """add_node(id, od) positional, a line as a mapping of its remote nodes,
    line.nmt.state = ... broadcasting, and a typo on line.nmt raising."""
    from canopenfd.od import DataType, demo_od, export_eds
    master = net.open_line(bus_name)
    devices = [net.open_line(bus_name).create_local_node(i, heartbeat_ms=0) for i in (5, 6)]
    eds = tmp_path / "device.eds"
    eds.write_text(export_eds(demo_od("fd")))
    remote = master.add_node(5, str(eds))                  # python-canopen's order
    assert remote.object_dictionary["Demo UNSIGNED16"].data_type == DataType.UNSIGNED16
    assert master.add_node(6, 300).heartbeat_timeout_ms == 300
    assert (list(master), len(master), 5 in master, 7 in master) == ([5, 6], 2, True, False)
    with pytest.raises(KeyError, match="watches no node 7"):
        master[7]
    with pytest.raises(ConfigurationError, match="two object dictionaries"):
        master.add_node(6, str(eds), od=str(eds))
    for device in devices:
        device.wait_for_state(NmtState.PRE_OPERATIONAL, timeout=wait(T))
    master.nmt.state = "OPERATIONAL"                       # to all, as python-canopen does
    for device in devices:
        device.wait_for_state(NmtState.OPERATIONAL, timeout=wait(T))
    with pytest.raises(ConfigurationError, match="read line\\[node_id\\].nmt.state"):
        master.nmt.state
    with pytest.raises(AttributeError):
        master.nmt.stat = "OPERATIONAL"                    # a typo is not silently kept


def test_heartbeat_callback_for_every_heartbeat_bounded_and_removable(net, bus_name):
    """python-canopen's add_heartbeat_callback: a call per heartbeat (state
    given), from the C runtime only while callbacks exist, at most one per
    min_interval_ms; removing the last one stops them."""
    watcher = net.open_line(bus_name)
    remote = watcher.add_node(5)
    beats, slow = Recorder(), Recorder()
    remote.nmt.add_heartbeat_callback(beats, min_interval_ms=0)
    device = net.open_line(bus_name).create_local_node(5, heartbeat_ms=10)
    beats.wait_count(12, timeout=wait(2.0))           # boot-up + every heartbeat
    assert beats.snapshot()[0] == NmtState.INITIALISING
    assert set(beats.snapshot()[1:]) == {NmtState.PRE_OPERATIONAL}
    device.nmt.state = "OPERATIONAL"
    beats.wait_for(lambda calls: NmtState.OPERATIONAL in calls, wait(2.0), "OPERATIONAL")
    # a 100 ms bound: over a window, at most one call per 100 ms (+1 at its start)
    remote.nmt.remove_heartbeat_callback(beats)
    remote.add_heartbeat_callback(slow, min_interval_ms=100)
    slow.wait_count(2, timeout=wait(2.0))
    first = slow.times[0]
    time.sleep(0.5)
    window = slow.times[-1] - first
    assert len(slow) <= window / 0.1 + 1.5, (len(slow), window)
    remote.remove_heartbeat_callback(slow)
    time.sleep(0.05)
    stopped = len(slow)
    time.sleep(0.2)
    assert len(slow) == stopped                       # 20 heartbeats later: no call
    assert len(beats) > 12 and beats.snapshot()[-1] == NmtState.OPERATIONAL
    with pytest.raises(ConfigurationError, match="min_interval_ms"):
        remote.add_heartbeat_callback(print, min_interval_ms=-1)


def test_add_node_takes_the_od_second_and_the_timeout_by_keyword(net, bus_name):
    """python-canopen's add_node(5, od) and ours (timeout second, or keyword)
    together; a node added again keeps what is not given again."""
    from canopenfd.od import demo_od
    line = net.open_line(bus_name)
    drive = line.add_node(5, demo_od("fd"), heartbeat_timeout_ms=300)
    assert drive.heartbeat_timeout_ms == 300 and drive.object_dictionary is not None
    assert line.add_node(5, demo_od("fd")) is drive
    assert drive.heartbeat_timeout_ms == 300                  # kept
    assert line.add_node(5, 150) is drive and drive.heartbeat_timeout_ms == 150
    with pytest.raises(ConfigurationError, match="two heartbeat timeouts"):
        line.add_node(6, 100, heartbeat_timeout_ms=200)
    with pytest.raises(ConfigurationError, match="two object dictionaries"):
        line.add_node(6, demo_od("fd"), od=demo_od("fd"))
    with pytest.raises(ConfigurationError, match="heartbeat_timeout_ms must be an int"):
        line.add_node(6, True)


def test_local_nmt_state_is_set_when_the_setter_returns(net, bus_name):
    """node.nmt.state = ... is applied before it returns (in the caller's
    thread, under the runtime lock): the next call already sees the state,
    e.g. a TPDO sent right after entering OPERATIONAL."""
    node = net.open_line(bus_name).create_local_node(1)
    for _ in range(50):
        node.nmt.state = "OPERATIONAL"
        assert node.state == NmtState.OPERATIONAL
        node.nmt.state = "PRE-OPERATIONAL"
        assert node.state == NmtState.PRE_OPERATIONAL
    node.nmt.state = "STOPPED"
    assert node.state == NmtState.STOPPED
