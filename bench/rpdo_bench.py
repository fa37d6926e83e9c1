#!/usr/bin/env python3
"""A master driving many devices' RPDOs periodically: our C producers against
python-canopen's `map.start(period)` (one python-can periodic send task, a
Python thread, per PDO), side by side in one run.

    python3 bench/rpdo_bench.py [-n PDOS] [-p PERIOD_MS] [-s SECONDS] [--classic]

Ours: PDOS remote RPDOs (8 nodes x 4, the demo dictionary with pdos=4, each
RPDO's COB-ID set and one 32-bit value mapped) started with
`rpdo.start(period)` on an in-process line; frames counted by the line's
tx counter (the C runtime sends them; Python does nothing per frame).
python-canopen: the same PDOs from the same dictionary (exported as an EDS)
on a python-can `virtual` bus, `map.start(period)`; frames counted in
`bus.send` (an integer increment per frame). Per side: frames sent per second
against the nominal PDOS / PERIOD, and the process's CPU seconds per 1000
frames over the window. Nothing is asserted; figures of one run compare.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time

NODES = range(2, 10)


def pdo_slots(count: int):
    """(node, rpdo number, COB-ID) of `count` PDOs: 4 per node."""
    slots = [(node, number, 0x200 + 0x100 * (number - 1) + node)
             for node in NODES for number in range(1, 5)]
    return slots[:count]


def cpu() -> float:
    t = os.times()
    return t.user + t.system


def run_ours(count: int, period: float, seconds: float, mode: str):
    import canopenfd
    from canopenfd.od import demo_od
    with canopenfd.Network() as net:
        line = net.open_line("mem:rpdo-bench", mode=mode)
        maps = []
        for node_id, number, cob_id in pdo_slots(count):
            drive = line.add_node(node_id, od=demo_od(mode, pdos=4))
            rpdo = drive.rpdo[number]
            rpdo.read(from_od=True)
            rpdo.cob_id = cob_id
            rpdo.enabled = True
            rpdo.clear()
            rpdo.add_variable("Process data", f"Process data {number}")
            rpdo[f"Process data {number}"].raw = cob_id
            maps.append(rpdo)
        before_frames, before_cpu = line.stats["tx_frames"], cpu()
        started = time.monotonic()
        for rpdo in maps:
            rpdo.start(period)
        time.sleep(seconds)
        frames, used = line.stats["tx_frames"] - before_frames, cpu() - before_cpu
        took = time.monotonic() - started
        for rpdo in maps:
            rpdo.stop()
    return frames / took, used, frames


def run_python_canopen(count: int, period: float, seconds: float, mode: str):
    import canopen
    from canopenfd.od import demo_od, export_eds
    eds = os.path.join(tempfile.mkdtemp(), "demo.eds")
    export_eds(demo_od(mode, pdos=4), eds)
    network = canopen.Network()
    network.connect(interface="virtual", channel="rpdo-bench", fd=(mode == "fd"))
    sent = [0]
    send = network.bus.send

    def counting_send(msg, timeout=None):
        sent[0] += 1
        return send(msg, timeout)

    network.bus.send = counting_send
    maps = []
    try:
        nodes = {}
        for node_id, number, cob_id in pdo_slots(count):
            if node_id not in nodes:              # adding it again would orphan its maps
                nodes[node_id] = network.add_node(node_id, eds)
                nodes[node_id].rpdo.read(from_od=True)
            rpdo = nodes[node_id].rpdo[number]
            rpdo.clear()
            rpdo.add_variable("Process data", f"Process data {number}")
            rpdo.cob_id = cob_id
            rpdo.enabled = True
            rpdo[f"Process data.Process data {number}"].raw = cob_id
            maps.append(rpdo)
        before_cpu = cpu()
        started = time.monotonic()
        for rpdo in maps:
            rpdo.start(period)
        time.sleep(seconds)
        frames, used = sent[0], cpu() - before_cpu
        took = time.monotonic() - started
        for rpdo in maps:
            rpdo.stop()
    finally:
        network.disconnect()
    return frames / took, used, frames


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-n", "--pdos", type=int, default=32, help="PDOs (1..32)")
    parser.add_argument("-p", "--period-ms", type=float, default=1.0)
    parser.add_argument("-s", "--seconds", type=float, default=5.0)
    parser.add_argument("--classic", action="store_true")
    args = parser.parse_args()
    mode = "classic" if args.classic else "fd"
    period = args.period_ms / 1000
    nominal = args.pdos / period
    print(f"{args.pdos} RPDOs every {args.period_ms:g} ms on a {mode} line, "
          f"{args.seconds:g} s each; nominal {nominal:.0f} frames/s")
    print(f"{'':26} {'frames/s':>10} {'of nominal':>11} {'CPU s / 1000 frames':>20}")
    for name, run in (("ours (C producers)", run_ours),
                      ("python-canopen (threads)", run_python_canopen)):
        rate, used, frames = run(args.pdos, period, args.seconds, mode)
        per_k = used / frames * 1000 if frames else float("nan")
        print(f"{name:26} {rate:10.0f} {100 * rate / nominal:10.1f}% {per_k:20.4f}")


if __name__ == "__main__":
    main()
