#!/usr/bin/env python3
"""PDO latency and a sustained PDO stream over a SocketCAN interface (vcan):
our stack and python-canopen side by side in one run.

    python3 bench/pdo_bench.py [-n SAMPLES] [-s SECONDS] [--classic] [IFACE]
    (bash bench/vcan_bench.sh --pdo [...] runs it in the VM: make -C bench pdo)

(a) Latency: node 1 (a canopenfd Network of its own) sends TPDO 1 (COB-ID
0x181, the 4-byte "Demo UNSIGNED32", event-driven, transmit() per sample);
node 2 (a second canopenfd Network, i.e. another runtime thread) receives it
as RPDO 1 and its Python callback records the time; python-canopen's Network
(subscribed to 0x181) in the same process records its callback's time. One
receiver listens at a time, in alternating rounds (both at once would race for
the GIL at every PDO). The figure is time.perf_counter() from just before
transmit() to each callback: median and 99th percentile over SAMPLES (one PDO
in flight at a time).

(b) Sustained stream: bench/pdo_flood (C) sends PDOs on 0x181 as fast as the
interface takes them for SECONDS (every frame numbered); two receiver
processes count what they got: ours (node 2's RPDO 1 in the C stack, counted
by the PDO service: line.service_stats; Python sees no frame) and
python-canopen's (a subscribed callback per frame, sequence numbers checked).
Per receiver: frames received, lost (sent - received), CPU seconds of the
receiver process per 1000 PDOs. Nothing is asserted about timing; exit 1 when
our stack lost a frame.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

SENDER, RECEIVER = 1, 2
COB_ID = 0x180 + SENDER
VALUE = "Demo UNSIGNED32"


def pdo_od(mode):
    """The demo OD plus RPDO 1 and TPDO 1 (as an EDS would describe them)."""
    from canopenfd.od import DataType, ODArray, ODRecord, ODVariable, demo_od
    od = demo_od(mode)
    for comm, mapping, base in ((0x1400, 0x1600, 0x200), (0x1800, 0x1A00, 0x180)):
        record = ODRecord(f"PDO communication parameter 0x{comm:X}", comm)
        record.add_member(ODVariable("Highest sub-index supported", comm, 0,
                                     DataType.UNSIGNED8, "ro", 5))
        cob = ODVariable("COB-ID used by PDO", comm, 1, DataType.UNSIGNED32, "rw", 0)
        cob.set_default(0x80000000 + base, relative_to_node_id=True)
        record.add_member(cob)
        record.add_member(ODVariable("Transmission type", comm, 2, DataType.UNSIGNED8, "rw",
                                     255))
        record.add_member(ODVariable("Inhibit time", comm, 3, DataType.UNSIGNED16, "rw", 0))
        record.add_member(ODVariable("Event timer", comm, 5, DataType.UNSIGNED16, "rw", 0))
        od.add_object(record)
        array = ODArray(f"PDO mapping parameter 0x{mapping:X}", mapping)
        array.add_member(ODVariable("Number of mapped objects", mapping, 0,
                                    DataType.UNSIGNED8, "rw", 0))
        for sub in range(1, 9):
            array.add_member(ODVariable(f"Mapped object {sub}", mapping, sub,
                                        DataType.UNSIGNED32, "rw", 0))
        od.add_object(array)
    return od


def configure(pdo, cob_id):
    pdo.read()
    pdo.clear()
    pdo.add_variable(VALUE)
    pdo.cob_id = cob_id
    pdo.trans_type = 254
    pdo.enabled = True
    pdo.save()
    return pdo


def receiver_node(net, iface, mode):
    node = net.open_line(iface, mode=mode).create_local_node(RECEIVER, od=pdo_od(mode))
    rpdo = configure(node.rpdo[1], COB_ID)
    node.apply("start")
    return node, rpdo


# ====================================================================== (a) latency
def latency(iface, mode, samples, native=False):
    """Callback latencies in ms: (ours, python-canopen's, missed per receiver).
    native: ours over the in-process bus mem:, python-canopen over python-can's
    `virtual` interface, its PDO sent by a raw virtual bus (no kernel)."""
    import canopen
    import canopenfd
    fd = mode == "fd"
    send_net = canopenfd.Network()
    # mem: buses live in one Network: there both nodes share its runtime thread
    recv_net = send_net if native else canopenfd.Network()
    theirs = canopen.Network()
    our_channel = "mem:pdo-bench" if native else iface
    their_sender = None
    try:
        me = send_net.open_line(our_channel, mode=mode).create_local_node(
            SENDER, od=pdo_od(mode))
        tpdo = configure(me.tpdo[1], COB_ID)
        me.apply("start")
        _, rpdo = receiver_node(recv_net, our_channel, mode)
        if native:
            import can
            their_sender = can.Bus(interface="virtual", channel="pdo-bench")
        got = {"ours": {}, "theirs": {}}
        events = {"ours": threading.Event(), "theirs": threading.Event()}

        def ours(pdo):
            got["ours"][pdo[VALUE].raw] = time.perf_counter()
            events["ours"].set()

        def their(can_id, data, timestamp):
            got["theirs"][int.from_bytes(bytes(data[:4]), "little")] = time.perf_counter()
            events["theirs"].set()

        def send_ours(i):
            me[VALUE].raw = i
            start = time.perf_counter()
            tpdo.transmit()
            return start

        def send_theirs(i):
            if their_sender is None:
                return send_ours(i)          # vcan: our TPDO, heard by both
            msg = can.Message(arbitration_id=COB_ID, data=i.to_bytes(4, "little"),
                              is_extended_id=False, is_fd=fd)
            start = time.perf_counter()
            their_sender.send(msg)
            return start
        # One receiver at a time, in alternating rounds: both in one process
        # would race for the GIL at every PDO (python-canopen's notifier
        # thread, woken first, would delay our dispatcher and vice versa).
        theirs.subscribe(COB_ID, their)
        ours_ms, theirs_ms, missed = [], [], {"ours": 0, "theirs": 0}
        rounds = 4
        for r in range(2 * rounds):
            name, out, send = (("ours", ours_ms, send_ours),
                               ("theirs", theirs_ms, send_theirs))[r % 2]
            if name == "ours":
                rpdo.add_callback(ours)
            elif native:
                theirs.connect(interface="virtual", channel="pdo-bench",
                               receive_own_messages=False)
            else:
                theirs.connect(interface="socketcan", channel=iface, fd=fd,
                               can_filters=[{"can_id": COB_ID, "can_mask": 0x7FF}])
            time.sleep(0.05)
            first = (r // 2) * (samples // rounds) + 1
            for i in range(first, first + samples // rounds):
                events[name].clear()
                start = send(i)
                if events[name].wait(2.0) and i in got[name]:
                    out.append((got[name][i] - start) * 1000.0)
                else:
                    missed[name] += 1
                time.sleep(0.001)
            if name == "ours":
                rpdo.remove_callback(ours)
            else:
                theirs.disconnect()
        return ours_ms, theirs_ms, missed
    finally:
        if theirs.bus is not None:
            theirs.disconnect()
        if their_sender is not None:
            their_sender.shutdown()
        send_net.close()
        recv_net.close()


def pct(values, p):
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(round(p / 100.0 * (len(ordered) - 1))))]


# ====================================================================== (b) stream
def receive_ours(iface, mode):
    import canopenfd
    with canopenfd.Network() as net:
        node, _ = receiver_node(net, iface, mode)
        before = node.line.service_stats["pdo"]["rx_frames"]
        cpu0 = resource.getrusage(resource.RUSAGE_SELF)
        print("ready", flush=True)
        sys.stdin.read()
        cpu1 = resource.getrusage(resource.RUSAGE_SELF)
        stats, line = node.line.service_stats, node.line.stats
        print(stats["pdo"]["rx_frames"] - before, line["rx_overflow"],
              (cpu1.ru_utime + cpu1.ru_stime) - (cpu0.ru_utime + cpu0.ru_stime), flush=True)


def receive_theirs(iface, mode):
    import canopen
    net = canopen.Network()
    net.connect(interface="socketcan", channel=iface, fd=mode == "fd",
                can_filters=[{"can_id": COB_ID, "can_mask": 0x7FF}])
    count, gaps, last = [0], [0], [None]

    def on_pdo(can_id, data, timestamp):
        seq = int.from_bytes(bytes(data[:4]), "little")
        if last[0] is not None and seq != last[0] + 1:
            gaps[0] += 1
        last[0] = seq
        count[0] += 1
    net.subscribe(COB_ID, on_pdo)
    cpu0 = resource.getrusage(resource.RUSAGE_SELF)
    print("ready", flush=True)
    sys.stdin.read()
    time.sleep(1.0)      # let its notifier thread finish what the socket holds
    cpu1 = resource.getrusage(resource.RUSAGE_SELF)
    net.disconnect()
    print(count[0], gaps[0], (cpu1.ru_utime + cpu1.ru_stime) - (cpu0.ru_utime + cpu0.ru_stime),
          flush=True)


def stream(iface, mode, seconds):
    flood = os.path.join(ROOT, "build", "bench", "pdo_flood")
    procs = {}
    for name in ("ours", "theirs"):
        procs[name] = subprocess.Popen(
            [sys.executable, os.path.abspath(__file__), "--recv", name, "--mode", mode, iface],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        if procs[name].stdout.readline().strip() != "ready":
            raise SystemExit(f"pdo_bench: receiver {name} did not start")
    args = [flood, "-s", str(seconds), "-l", "8"] + (["-c"] if mode == "classic" else [])
    out = subprocess.run(args + [iface, hex(COB_ID)], capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit(f"pdo_bench: pdo_flood failed: {out.stderr.strip()}")
    sent = int(out.stdout.split()[1])
    time.sleep(1.0)
    results = {}
    for name, proc in procs.items():
        reply, _ = proc.communicate("", timeout=120)
        results[name] = [float(x) for x in reply.split()]
    return sent, out.stdout.strip(), results


# ====================================================================== (c) starved
def starved(mode, count):
    """A PDO stream to a slow Python callback (200 us of work a PDO) while
    another Python thread spins (any real application has one). The sender is
    a tool line's send_frame() loop. Returns
    (sent, callbacks, values merged away, events lost, seconds of sending)."""
    import canopenfd
    stop = threading.Event()

    def spin():
        x = 0
        while not stop.is_set():
            x += 1

    with canopenfd.Network() as net:
        _, rpdo = receiver_node(net, "mem:starved", mode)
        tool = net.open_line("mem:starved", mode=mode)
        calls = [0]

        def on_pdo(pdo):        # an application's work: 200 us a PDO
            calls[0] += 1
            until = time.perf_counter() + 200e-6
            while time.perf_counter() < until:
                pass
        rpdo.add_callback(on_pdo)
        busy = threading.Thread(target=spin, daemon=True)
        busy.start()
        start = time.perf_counter()
        data = bytes(4)
        for i in range(count):
            tool.send_frame(COB_ID, i.to_bytes(4, "little") if i % 64 == 0 else data)
        sending = time.perf_counter() - start
        deadline = time.monotonic() + 60
        accounted = 0
        while time.monotonic() < deadline:
            accounted = calls[0] + getattr(rpdo, "skipped_total", 0)
            if accounted + net.events_lost >= count:
                break
            time.sleep(0.01)
        stop.set()
        busy.join()
        return count, calls[0], getattr(rpdo, "skipped_total", 0), net.events_lost, sending


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("iface", nargs="?", default="vcan0")
    ap.add_argument("-n", type=int, default=500, help="latency samples")
    ap.add_argument("-s", type=float, default=60.0, help="seconds of the sustained stream")
    ap.add_argument("--classic", action="store_true", help="classic frames (MTU 16 interface)")
    ap.add_argument("--native", action="store_true",
                    help="latency only, no kernel: ours over mem:, python-canopen over "
                         "python-can's virtual interface")
    ap.add_argument("--starved", type=int, default=200_000,
                    help="--native: PDOs sent to a starved callback")
    ap.add_argument("--recv", choices=("ours", "theirs"), help=argparse.SUPPRESS)
    ap.add_argument("--mode", default="fd", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.recv == "ours":
        receive_ours(args.iface, args.mode)
        return 0
    if args.recv == "theirs":
        receive_theirs(args.iface, args.mode)
        return 0
    import logging
    logging.getLogger("canopen").setLevel(logging.CRITICAL)
    mode = "classic" if args.classic else "fd"
    where = "mem: / python-can virtual" if args.native else args.iface
    print(f"PDO bench over {where} ({mode}), python {sys.version.split()[0]}")
    ours_ms, theirs_ms, missed = latency(args.iface, mode, args.n, args.native)
    print(f"\n(a) latency TPDO transmit() at node {SENDER} -> Python callback, "
          f"{args.n} samples, one PDO in flight")
    print(f"{'receiver':<16} {'median ms':>10} {'p99 ms':>9} {'max ms':>9} {'missed':>7}")
    for name, values in (("ours", ours_ms), ("python-canopen", theirs_ms)):
        key = "ours" if name == "ours" else "theirs"
        if values:
            print(f"{name:<16} {statistics.median(values):10.3f} {pct(values, 99):9.3f} "
                  f"{max(values):9.3f} {missed[key]:7d}")
        else:
            print(f"{name:<16} {'-':>10} {'-':>9} {'-':>9} {missed[key]:7d}")
    if args.native:
        sent, calls, merged, lost, seconds = starved(mode, args.starved)
        print(f"\n(c) {sent} PDOs ({sent / seconds:.0f}/s) to a Python callback doing 200 us "
              f"of work a PDO while another Python thread spins")
        print(f"{'callbacks':>10} {'merged':>8} {'lost':>8}  (callbacks + merged + lost = sent)")
        print(f"{calls:10d} {merged:8d} {lost:8d}")
        return 0
    sent, flood_line, results = stream(args.iface, mode, args.s)
    print(f"\n(b) sustained stream {args.s:g} s: pdo_flood {flood_line}")
    print(f"{'receiver':<16} {'received':>10} {'lost':>8} {'lost %':>8} {'CPU s':>7} "
          f"{'CPU us/PDO':>11}  note")
    ours_rx, overflow, ours_cpu = results["ours"]
    theirs_rx, gaps, theirs_cpu = results["theirs"]
    for name, rx, cpu, note in (
            ("ours", ours_rx, ours_cpu, f"rx queue overflows {int(overflow)}"),
            ("python-canopen", theirs_rx, theirs_cpu, f"sequence gaps {int(gaps)}")):
        lost = sent - int(rx)
        print(f"{name:<16} {int(rx):10d} {lost:8d} {100.0 * lost / max(sent, 1):7.2f}% "
              f"{cpu:7.2f} {1e6 * cpu / max(rx, 1):11.2f}  {note}")
    return 0 if int(ours_rx) == sent else 1


if __name__ == "__main__":
    sys.exit(main())
