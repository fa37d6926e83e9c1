#!/usr/bin/env python3
"""Network start-up of many slaves, each configured from a large concise DCF
(issue 15, "Performance"): the CiA 302-2 manager boots SLAVES slaves on an
in-process bus and, in its configuration hook, writes ENTRIES entries into
each through the line's client (SDO on classic lines, USDO on fd lines).

    python3 bench/manager_bench.py [-n SLAVES] [-e ENTRIES] [--classic]

Printed: the wall time from `manager.start()` to "network started", the
frames on the bus (a monitor line counts them), and the least time those
frames take on a real bus: classic 1 Mbit/s, or CAN FD 1 Mbit/s arbitration
with 5 Mbit/s data, each frame's bits counted without stuff bits (classic:
47 + 8 x bytes; FD: 30 bits at the nominal rate + 8 x bytes + 26 + CRC 17/21
at the data rate; intermission and ACK included in those constants). The
share "bus time / wall time" above 1 means the stack outruns that bus: the
bus, not the stack, sets the pace. Nothing is asserted; one run's figures
compare.
"""

from __future__ import annotations

import argparse
import queue
import threading
import time

NOMINAL, DATA = 1_000_000, 5_000_000


def frame_bits_s(fd: bool, length: int) -> float:
    """The least seconds one frame takes (no stuff bits)."""
    if not fd:
        return (47 + 8 * length) / NOMINAL
    crc = 17 if length <= 16 else 21
    return 30 / NOMINAL + (8 * length + 26 + crc) / DATA


def run(slaves: int, entries: int, mode: str) -> None:
    import canopenfd
    from canopenfd.cli.demo_manager import DATE, TIME
    from canopenfd.od import add_node_array, add_stamp
    from canopenfd.od import DataType, ODVariable, demo_od
    from canopenfd.od.concise import build_concise

    # what every slave gets: writable entries of the demo dictionary, in turn
    writable = [(0x1017, 0, (100).to_bytes(2, "little")),
                (0x2200, 1, (7).to_bytes(2, "little"))]
    dcf = build_concise([writable[i % len(writable)] for i in range(entries)])
    ids = list(range(2, 2 + slaves))
    with canopenfd.Network(event_capacity=1 << 18) as net:
        bus = f"mem:manager-bench-{mode}"
        frames = {"count": 0, "seconds": 0.0}
        lock = threading.Lock()

        def on_frame(frame) -> None:
            with lock:
                frames["count"] += 1
                frames["seconds"] += frame_bits_s(mode == "fd", len(frame.data))

        net.open_line(bus, mode=mode, monitor=True).on_frame(on_frame)
        for node_id in ids:
            od = demo_od(mode)
            add_stamp(od, (1, 1))                    # outdated: every slave is configured
            net.open_line(bus, mode=mode).create_local_node(node_id, od=od)
        od = demo_od(mode)
        od.add_object(ODVariable("NMT startup", 0x1F80, 0, DataType.UNSIGNED32, "rw", 0x01))
        for index, name, value in ((0x1F81, "Slave assignment", 0x0D),
                                   (0x1F26, "Expected configuration date", DATE),
                                   (0x1F27, "Expected configuration time", TIME)):
            add_node_array(od, index, name, {node: value for node in ids}, highest=max(ids))
        line = net.open_line(bus, mode=mode)
        line.create_local_node(1, od=od)
        events: "queue.Queue" = queue.Queue()
        line.manager.add_callback(events.put)
        configured = 0
        started = time.perf_counter()
        line.manager.start(config_hook=True)
        jobs = {}
        while True:
            event = events.get(timeout=120)
            if event.kind == "update-config":
                jobs[event.node_id] = line.manager.configure(event.node_id, dcf,
                                                             expected=(DATE, TIME))
                threading.Thread(target=lambda n=event.node_id: (
                    line.manager.continue_config(n, jobs[n].result().ok))).start()
                configured += 1
            if event.kind in ("network-started", "halted"):
                break
        wall = time.perf_counter() - started
        time.sleep(0.2)                           # the monitor catches up
        with lock:
            count, bus_s = frames["count"], frames["seconds"]
    proto = "USDO" if mode == "fd" else "SDO"
    rate = "1/5 Mbit/s" if mode == "fd" else "1 Mbit/s"
    print(f"{mode:7} {slaves} slaves x {entries} entries over {proto}: {event.kind} after "
          f"{wall * 1000:.0f} ms; {count} frames, at least {bus_s * 1000:.0f} ms on a "
          f"{rate} bus; bus time / wall time = {bus_s / wall:.1f}; {configured} configured")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-n", "--slaves", type=int, default=16)
    parser.add_argument("-e", "--entries", type=int, default=200)
    parser.add_argument("--classic", action="store_true", help="only classic (default both)")
    parser.add_argument("--fd", action="store_true", help="only fd (default both)")
    args = parser.parse_args()
    modes = ["classic"] if args.classic else ["fd"] if args.fd else ["classic", "fd"]
    for mode in modes:
        run(args.slaves, args.entries, mode)


if __name__ == "__main__":
    main()
