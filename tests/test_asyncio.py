"""The asyncio forms of the API's waits and callbacks (canopenfd/_aio.py):
each `await_...` / `a...` form gives what its blocking form gives, raises the
same TimeoutError text and ClosedError, and leaves no registered wait behind
when it ends, times out or is cancelled; callbacks registered with loop= run
on that loop's thread (coroutine functions as tasks); 100 nodes' waits run
concurrently in one loop. All over in-process `mem:` buses."""

from __future__ import annotations

import asyncio
import threading
import time

import pytest

from canopenfd import ClosedError, NmtState
from canopenfd.od import demo_od
from helpers import Recorder, scaled
from test_services import pdo_od

NODE = 5


def run(coro):
    """Run a test coroutine, never longer than 30 s (scaled)."""
    return asyncio.run(asyncio.wait_for(coro, scaled(30)))


async def registered(line, count):
    """Let the loop run until `count` awaits are registered on the line."""
    deadline = time.monotonic() + scaled(5)
    while line.pending_awaits < count:
        assert time.monotonic() < deadline, f"{line.pending_awaits} of {count} registered"
        await asyncio.sleep(0.001)


def test_bootup_state_heartbeat_and_emcy_awaited(net, bus_name):
    master = net.open_line(bus_name)
    remote = master.add_node(NODE, heartbeat_timeout_ms=int(scaled(0.5) * 1000))
    frames = Recorder()
    net.open_line(bus_name, monitor=True).on_frame(frames)

    async def main():
        bootup = asyncio.ensure_future(remote.await_for_bootup(timeout=scaled(5)))
        await registered(master, 1)
        me = net.open_line(bus_name).create_local_node(NODE, heartbeat_ms=20)
        await bootup
        assert await remote.await_for_heartbeat(timeout=scaled(5)) == NmtState.PRE_OPERATIONAL
        me.nmt.state = "OPERATIONAL"
        await me.await_for_state("OPERATIONAL", timeout=scaled(5))
        await remote.nmt.await_for_state(NmtState.OPERATIONAL, timeout=scaled(5))
        emcy = asyncio.ensure_future(remote.emcy.await_(0x3210, timeout=scaled(5)))
        await registered(master, 1)
        me.emcy.raise_error(0x2310)                    # another code: still waiting
        me.emcy.raise_error(0x3210, b"\x07")
        got = await emcy
        assert (got.code, got.node, got.data[:1]) == (0x3210, NODE, b"\x07")
        return me
    run(main())
    assert master.pending_awaits == 0
    # what the waits saw is what went on the bus (the monitor hears it on its
    # own line, maybe after the waits ended: wait for the EMCY, sent last)
    frames.wait_for(lambda c: any(f.id == 0x80 + NODE and bytes(f.data[:2]) == b"\x10\x32"
                                  for f in c), 5, "the EMCY 0x3210")
    heard = [(f.id, bytes(f.data)) for f in frames.snapshot()]
    assert (0x700 + NODE, b"\x00") in heard                        # boot-up
    assert (0x700 + NODE, b"\x05") in heard                        # heartbeat OPERATIONAL


def test_timeout_gives_the_blocking_forms_error_and_frees_the_wait(net, bus_name):
    master = net.open_line(bus_name)
    remote = master.add_node(NODE)
    with pytest.raises(TimeoutError) as blocking:
        remote.wait_for_bootup(timeout=0.05)

    async def main():
        with pytest.raises(TimeoutError) as awaited:
            await remote.await_for_bootup(timeout=0.05)
        assert str(awaited.value) == str(blocking.value)
        with pytest.raises(TimeoutError, match=r"wait for EMCY 0x1000: no EMCY 0x1000"):
            await remote.emcy.await_(0x1000, timeout=0.05)
        with pytest.raises(TimeoutError, match=r"wait_for_state\(OPERATIONAL\)"):
            await remote.await_for_state("OPERATIONAL", timeout=0.05)
        with pytest.raises(TimeoutError, match="no heartbeat"):
            await remote.nmt.await_for_heartbeat(timeout=0.05)
        from canopenfd import CommEvent
        with pytest.raises(TimeoutError, match="wait_for_comm_event"):
            await master.await_for_comm_event(CommEvent.BUS_OFF, timeout=0.05)
    run(main())
    assert master.pending_awaits == 0


def test_bad_timeout_is_refused_like_the_blocking_form(net, bus_name):
    remote = net.open_line(bus_name).add_node(NODE)
    with pytest.raises(Exception) as blocking:
        remote.wait_for_bootup(timeout=-1)

    async def main():
        with pytest.raises(type(blocking.value), match="timeout must be >= 0 s"):
            await remote.await_for_bootup(timeout=-1)
    run(main())


def test_a_thousand_cancelled_waits_leave_nothing_behind(net, bus_name):
    master = net.open_line(bus_name)
    remote = master.add_node(NODE)

    async def main():
        waits = [asyncio.ensure_future(remote.await_for_bootup(timeout=None))
                 for _ in range(1000)]
        await registered(master, 1000)
        for wait in waits:
            wait.cancel()
        outcomes = await asyncio.gather(*waits, return_exceptions=True)
        assert all(isinstance(o, asyncio.CancelledError) for o in outcomes)
        assert master.pending_awaits == 0
        # the line still serves new waits after the cancellations
        bootup = asyncio.ensure_future(remote.await_for_bootup(timeout=scaled(5)))
        await registered(master, 1)
        net.open_line(bus_name).create_local_node(NODE)
        await bootup
    run(main())
    assert master.pending_awaits == 0


def test_closing_the_network_ends_awaits_with_closed_error(net, bus_name):
    master = net.open_line(bus_name)
    remote = master.add_node(NODE)

    async def main():
        wait = asyncio.ensure_future(remote.await_for_bootup(timeout=None))
        await registered(master, 1)
        net.close()
        with pytest.raises(ClosedError, match="wait_for_bootup: the network was closed"):
            await wait
        with pytest.raises(ClosedError):
            await remote.await_for_state("OPERATIONAL")
    run(main())


def test_callbacks_given_a_loop_run_on_its_thread(net, bus_name):
    master = net.open_line(bus_name)
    remote = master.add_node(NODE, heartbeat_timeout_ms=int(scaled(0.5) * 1000))

    async def main():
        loop = asyncio.get_running_loop()
        threads, states, emcys = [], [], []
        bootup = asyncio.Event()
        emcy_seen = asyncio.Event()

        def on_bootup():
            threads.append(threading.get_ident())
            bootup.set()                   # an asyncio.Event: only safe on the loop thread

        async def on_state(state):         # a coroutine function runs as a task
            await asyncio.sleep(0)
            states.append((threading.get_ident(), state))

        def on_emcy(emcy):
            emcys.append((threading.get_ident(), emcy.code))
            emcy_seen.set()

        remote.on_bootup(on_bootup, loop=loop)
        remote.on_state_change(on_state, loop=loop)
        remote.emcy.add_callback(on_emcy, loop=loop)
        dispatcher = Recorder()
        remote.on_bootup(lambda: dispatcher(threading.get_ident()))
        me = net.open_line(bus_name).create_local_node(NODE, heartbeat_ms=20)
        await asyncio.wait_for(bootup.wait(), scaled(5))
        me.nmt.state = "OPERATIONAL"
        await remote.await_for_state("OPERATIONAL", timeout=scaled(5))
        me.emcy.raise_error(0x4210)
        await asyncio.wait_for(emcy_seen.wait(), scaled(5))
        deadline = time.monotonic() + scaled(5)
        while NmtState.OPERATIONAL not in [s for _, s in states]:
            assert time.monotonic() < deadline, states
            await asyncio.sleep(0.005)
        me_thread = threading.get_ident()
        assert threads == [me_thread]
        assert {t for t, _ in states} == {me_thread}
        assert emcys == [(me_thread, 0x4210)]
        assert dispatcher.wait_count(1)[0] != me_thread     # without loop=: dispatcher
        # remove_callback finds a callback registered with loop=
        remote.emcy.remove_callback(on_emcy)
        later = asyncio.ensure_future(remote.emcy.await_(0x4220, timeout=scaled(5)))
        await registered(master, 1)
        me.emcy.raise_error(0x4220)
        await later
        await asyncio.sleep(0.05)
        assert emcys == [(me_thread, 0x4210)]
    run(main())


def test_loop_must_be_an_event_loop(net, bus_name):
    from canopenfd import ConfigurationError
    remote = net.open_line(bus_name).add_node(NODE)
    with pytest.raises(ConfigurationError, match="loop= must be an asyncio event loop"):
        remote.on_bootup(lambda: None, loop="main")


def test_pdo_reception_and_configuration_awaited(net, bus_name):
    """A remote node's TPDO configuration read and saved over awaited SDO
    transfers, then its reception awaited; cancelling the reception wait
    stops hearing the PDO like the blocking wait's end."""
    me = net.open_line(bus_name, mode="classic").create_local_node(NODE, od=pdo_od("classic"))
    master = net.open_line(bus_name, mode="classic")
    remote = master.add_node(NODE, od=pdo_od("classic"))
    frames = Recorder()
    net.open_line(bus_name, mode="classic", monitor=True).on_frame(frames)
    tpdo = remote.tpdo[1]

    def sdo_requests():
        return [bytes(f.data) for f in frames.snapshot() if f.id == 0x600 + NODE]

    async def main():
        await tpdo.aread()
        assert (tpdo.cob_id, tpdo.enabled) == (0x180 + NODE, False)
        frames.wait_for(lambda c: any(f.id == 0x600 + NODE and bytes(f.data) ==
                                      b"\x40\x00\x18\x01\x00\x00\x00\x00" for f in c),
                        5, "the upload of 0x1800:01")
        tpdo.clear()
        tpdo.add_variable("Demo UNSIGNED16")
        tpdo.trans_type = 254
        tpdo.enabled = True
        await tpdo.asave()
        valid = b"\x23\x00\x18\x01\x85\x01\x00\x00"
        # the monitor hears the frames after the stacks acted: wait for the last
        frames.wait_for(lambda c: any(f.id == 0x600 + NODE and bytes(f.data) == valid
                                      for f in c), 5, "the valid COB-ID written")
        sent = sdo_requests()
        assert b"\x2f\x00\x18\x02\xfe\x00\x00\x00" in sent                # 0x1800:02 = 254
        assert sent[-1] == b"\x23\x00\x18\x01\x85\x01\x00\x00"             # valid COB-ID last
        await tpdo.aread()
        assert (tpdo.enabled, tpdo.trans_type, len(tpdo.map)) == (True, 254, 1)
        me.apply("start")
        await me.await_for_state("OPERATIONAL", timeout=scaled(5))
        local = me.tpdo[1]
        local.read()
        me["Demo UNSIGNED16"].raw = 0x1234
        reception = asyncio.ensure_future(tpdo.await_for_reception(timeout=scaled(5)))
        await registered(master, 1)
        local.transmit()
        when = await reception
        assert abs(when - time.time()) < scaled(5)
        assert tpdo["Demo UNSIGNED16"].raw == 0x1234
        cancelled = asyncio.ensure_future(tpdo.await_for_reception(timeout=None))
        await registered(master, 1)
        cancelled.cancel()
        with pytest.raises(asyncio.CancelledError):
            await cancelled
        assert master.pending_awaits == 0
    run(main())
    assert master._pdo_watches == {}           # nothing listens to the PDO any more


def test_hundred_nodes_boot_state_and_emcy_awaited_in_one_loop(net, bus_name):
    """A master awaits 100 nodes' boot-ups, heartbeats, OPERATIONAL state and
    an EMCY each, all at once in one event loop. The nodes are played by a
    line sending their frames (a runtime holds 64 lines, a mem: bus 32, so
    not 100 local nodes); the frames are checked on a monitor."""
    master = net.open_line(bus_name, mode="classic")
    sim = net.open_line(bus_name, mode="classic")
    monitor = Recorder()
    net.open_line(bus_name, mode="classic", monitor=True).on_frame(monitor)
    ids = range(1, 101)
    remotes = [master.add_node(node_id) for node_id in ids]

    async def all_of(make, send):
        waits = [asyncio.ensure_future(make(r)) for r in remotes]
        await registered(master, len(remotes))
        for node_id in ids:
            send(node_id)
        return await asyncio.gather(*waits)

    async def main():
        started = time.monotonic()
        await all_of(lambda r: r.await_for_bootup(timeout=scaled(20)),
                     lambda n: sim.send_frame(0x700 + n, b"\x00"))
        states = await all_of(lambda r: r.await_for_heartbeat(timeout=scaled(20)),
                              lambda n: sim.send_frame(0x700 + n, b"\x7f"))
        assert set(states) == {NmtState.PRE_OPERATIONAL}
        await all_of(lambda r: r.await_for_state("OPERATIONAL", timeout=scaled(20)),
                     lambda n: sim.send_frame(0x700 + n, b"\x05"))
        emcys = await all_of(lambda r: r.emcy.await_(0x8130, timeout=scaled(20)),
                             lambda n: sim.send_frame(0x80 + n, bytes([0x30, 0x81, 0x11, n, 0, 0, 0, 0])))
        assert [(e.node, e.code, e.register, e.data[:1]) for e in emcys] == \
            [(n, 0x8130, 0x11, bytes([n])) for n in ids]
        return time.monotonic() - started
    took = run(main())
    assert took < scaled(20)
    assert master.pending_awaits == 0
    assert {r.nmt.state for r in remotes} == {NmtState.OPERATIONAL}
    heard = {(f.id, bytes(f.data)) for f in monitor.wait_for(
        lambda c: c if len(c) >= 400 else None, scaled(5), "the 400 frames")}
    assert all((0x700 + n, b"\x00") in heard and (0x700 + n, b"\x05") in heard for n in ids)


async def cancel_once_requested(awaitable, frames, node_id):
    """Await in a task until the first SDO request to node_id is on the bus,
    then cancel the task."""
    task = asyncio.ensure_future(awaitable)
    await asyncio.sleep(0)           # a task cancelled before its first step never ran
    deadline = time.monotonic() + scaled(2)
    while not any(f.id == 0x600 + node_id for f in frames.snapshot()):
        assert time.monotonic() < deadline, f"no request to node {node_id}"
        await asyncio.sleep(0.001)
    task.cancel()
    with pytest.raises(asyncio.CancelledError):
        await task


def abort_sent(frames, node_id):
    """The client's frame to node_id after its request: the abort."""
    return frames.wait_for(lambda c: [bytes(f.data) for f in c if f.id == 0x600 + node_id][1:]
                           or None, scaled(2), "the abort")[0]


def test_cancelling_an_awaited_transfer_aborts_it_on_the_bus(net, bus_name):
    """Nobody serves node 5: the upload waits for its answer; cancelling the
    awaiting task sends the SDO abort (general error 0x08000000) at once."""
    master = net.open_line(bus_name, mode="classic")
    remote = master.add_node(NODE, od=demo_od("classic"))
    frames = Recorder()
    net.open_line(bus_name, mode="classic", monitor=True).on_frame(frames)

    run(cancel_once_requested(remote.aread(0x1017), frames, NODE))
    assert abort_sent(frames, NODE) == b"\x80\x17\x10\x00\x00\x00\x00\x08"


def test_cancelling_an_awaited_configuration_cancels_it(net, bus_name):
    """manager.configure's job awaited for a silent node: cancelling the
    awaiting task ends the configuration (CANCELLED) and aborts its open
    transfer on the bus instead of leaving it to its 5 s timeout."""
    from canopenfd.od.concise import build_concise
    from canopenfd.services.config import ConfigOutcome
    master = net.open_line(bus_name, mode="classic")
    frames = Recorder()
    net.open_line(bus_name, mode="classic", monitor=True).on_frame(frames)
    job = master.manager.configure(43, build_concise([(0x1017, 0, b"\x21\x00")]),
                                   timeout_ms=5000)

    run(cancel_once_requested(job, frames, 43))
    assert job.result(scaled(2)).outcome is ConfigOutcome.CANCELLED
    assert abort_sent(frames, 43)[0] == 0x80


def test_a_stalled_loop_gets_at_most_the_backlog_and_the_rest_is_counted():
    """loop= delivery never blocks the dispatcher: while `backlog` calls
    wait on a loop that does not run, newer calls are dropped and counted;
    once it runs it gets the waiting ones in order, and later ones again;
    a closed loop gets nothing and raises nothing."""
    from canopenfd._aio import LoopDelivery
    loop = asyncio.new_event_loop()
    got = []
    deliver = LoopDelivery(got.append, loop, backlog=3)
    try:
        for n in range(5):
            deliver(n)
        assert deliver.dropped == 2
        loop.run_until_complete(asyncio.sleep(0))
        assert got == [0, 1, 2]
        deliver(5)
        loop.run_until_complete(asyncio.sleep(0))
        assert got == [0, 1, 2, 5] and deliver.dropped == 2
    finally:
        loop.close()
    deliver(6)
    assert got == [0, 1, 2, 5]
