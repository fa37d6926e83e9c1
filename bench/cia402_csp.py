#!/usr/bin/env python3
"""Cyclic synchronous position with N simulated CiA 402 drives at a 1 ms SYNC.

    python3 bench/cia402_csp.py [-c CHANNEL] [-n DRIVES] [-p PERIOD_MS] [-s SECONDS]

The drives (canopenfd.profiles.cia402.create_simulated_drive, nodes 1..N, one
line each: their state machine and motion model run in the C runtime) and the
master (one line: `Drive.cyclic("csp")` per drive, one SYNC producer for all),
all in one Network, share CHANNEL (default: the third name of
CANOPENFD_VCAN, else the in-process bus "mem:cia402-bench"). While it runs,
Python writes a new target to every drive's RPDO about once per period. A
monitor line time-stamps every frame (runtime receive time, CLOCK_MONOTONIC).

Figures, per cycle between two SYNCs:
- SYNC -> RPDO latency p50/p99/max: how long after the SYNC each drive's
  RPDO2 (controlword + target) is on the bus; the drive applies it at the
  next SYNC, so an RPDO after the next SYNC is a missed window;
- missed SYNC windows: drive-cycles without that drive's RPDO before the
  next SYNC (a late RPDO is applied one cycle late);
- SYNC period p50/p99/max and TPDO2 answers per drive-cycle;
- monitor events lost (a full event queue), so the figures' coverage is known;
- how long each drive's enable() through the cyclic RPDO took (it runs with
  SYNC and the monitor's per-frame callback already going).
Nothing is asserted: one run's figures.
"""

from __future__ import annotations

import argparse
import os
import statistics
import threading
import time

import canopenfd
from canopenfd.profiles.cia402 import Drive, create_simulated_drive, drive_od


def percentile(values, q):
    if not values:
        return float("nan")
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]


def default_channel() -> str:
    names = [n.strip() for n in os.environ.get("CANOPENFD_VCAN", "").split(",") if n.strip()]
    return names[2] if len(names) >= 3 else "mem:cia402-bench"


def analyse(frames, drives, period_s):
    """frames: (timestamp, can_id) sorted by time."""
    rpdo_ids = {0x300 + node: node for node in drives}
    tpdo_ids = {0x280 + node: node for node in drives}
    syncs = [t for t, can_id in frames if can_id == 0x80]
    latencies, missed, answered, cycles = [], 0, 0, 0
    index = 0
    for k in range(len(syncs) - 1):
        start, end = syncs[k], syncs[k + 1]
        seen_rpdo, seen_tpdo = set(), set()
        while index < len(frames) and frames[index][0] < start:
            index += 1
        j = index
        while j < len(frames) and frames[j][0] < end:
            t, can_id = frames[j]
            if can_id in rpdo_ids and rpdo_ids[can_id] not in seen_rpdo:
                seen_rpdo.add(rpdo_ids[can_id])
                latencies.append((t - start) * 1e6)
            elif can_id in tpdo_ids:
                seen_tpdo.add(tpdo_ids[can_id])
            j += 1
        cycles += 1
        missed += len(drives) - len(seen_rpdo)
        answered += len(seen_tpdo)
    periods = [(b - a) * 1e6 for a, b in zip(syncs, syncs[1:])]
    return {"cycles": cycles, "latencies": latencies, "missed": missed,
            "answered": answered, "periods": periods, "expected": period_s * 1e6}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-c", "--channel", default=default_channel())
    parser.add_argument("-n", "--drives", type=int, default=8)
    parser.add_argument("-p", "--period-ms", type=float, default=1.0)
    parser.add_argument("-s", "--seconds", type=float, default=3.0)
    args = parser.parse_args()
    period = args.period_ms / 1000
    drives = list(range(1, args.drives + 1))
    channel = args.channel

    # one Network (one runtime thread) for drives and master: an in-process bus
    # is per Network, and on SocketCAN each line has its own socket anyway
    with canopenfd.Network() as net:
        device_net = master_net = net
        for node in drives:
            create_simulated_drive(device_net.open_line(channel, mode="classic"), node)
        frames = []
        lock = threading.Lock()
        recording = threading.Event()

        def on_frame(frame) -> None:
            if recording.is_set():
                with lock:
                    frames.append((frame.timestamp, frame.id))
        monitor = master_net.open_line(channel, mode="classic", monitor=True)
        monitor.on_frame(on_frame)     # from here: Python hears every frame
        line = master_net.open_line(channel, mode="classic")
        controls = []
        for node in drives:
            drive = Drive(line.add_node(node, od=drive_od("classic")), timeout=5.0)
            controls.append((drive, drive.cyclic("csp", period=period, sync=False)))
        line.sync.start(period)
        # enabled through the cyclic RPDO, while SYNC runs and the monitor's
        # callback takes every frame (the load that slowed the statusword reads)
        enable_s = []
        for drive, _ in controls:
            started = time.monotonic()
            drive.enable()
            enable_s.append(time.monotonic() - started)
        print(f"{len(drives)} simulated drives on {channel}, CSP, SYNC every "
              f"{args.period_ms:g} ms, {args.seconds:g} s")
        recording.set()
        end = time.monotonic() + args.seconds
        step = 0
        while time.monotonic() < end:
            step += 1
            for _, cyclic in controls:
                cyclic.target = step
            time.sleep(period)
        recording.clear()
        line.sync.stop()
        for drive, _ in controls:
            drive.stop_cyclic()
        lost = master_net.events_lost
        with lock:
            captured = sorted(frames)
    result = analyse(captured, drives, period)
    lat, per = result["latencies"], result["periods"]
    slots = result["cycles"] * len(drives)
    print(f"cycles: {result['cycles']}, drive-cycles: {slots}, frames seen: {len(captured)}")
    print(f"SYNC period us: p50 {percentile(per, 0.5):.0f}  p99 {percentile(per, 0.99):.0f}  "
          f"max {max(per) if per else float('nan'):.0f}  (nominal {result['expected']:.0f})")
    print(f"SYNC -> RPDO latency us: p50 {percentile(lat, 0.5):.0f}  "
          f"p99 {percentile(lat, 0.99):.0f}  max {max(lat) if lat else float('nan'):.0f}  "
          f"mean {statistics.mean(lat) if lat else float('nan'):.0f}")
    print(f"missed SYNC windows: {result['missed']} of {slots} drive-cycles")
    print(f"TPDO2 answers: {result['answered']} of {slots} drive-cycles")
    print(f"monitor events lost: {lost}")
    print(f"enable() through the cyclic RPDO, s per drive: max {max(enable_s):.3f}  "
          f"mean {statistics.mean(enable_s):.3f}")


if __name__ == "__main__":
    main()
