#!/usr/bin/env python3
"""SRDO end-to-end reaction time to a violation (issue 18, item 2 "Performance").

    python3 bench/srdo_bench.py [-n ROUNDS] [--sct MS] [--srvt MS] [--bus mem:x|vcan0]

Two local nodes on one bus (mem: by default, or a SocketCAN interface): node 5
produces SRDO 1 every SCT_P ms, node 6 consumes it with its own SCT and SRVT.
The figure is time.perf_counter() from the moment the violation exists to the
consumer's Python safe-state callback (the C core's check, the runtime's event
queue and the dispatcher thread included), per kind:

  mismatch   a tool line sends a good normal frame and a corrupted inverted one;
             measured from just before the corrupted frame is handed to the line
  srvt       a tool line sends a normal frame and no inverted one: the limit is
             SRVT after the normal frame (measured from just before sending it)
  sct        the producer is stopped (NMT stop): the limit is the consumer's SCT
             after the last normal frame; the reference is when a monitor line's
             Python callback heard that frame, itself a little late, so this
             figure can read slightly below the limit
  gfc        node 5 sends a GFC: measured from just before the send

Printed side by side with the configured limit: min / median / max of the
reaction and, for srvt and sct, the overshoot past the limit. Nothing is
asserted on time.
"""

from __future__ import annotations

import argparse
import statistics
import threading
import time

import canopenfd
from canopenfd.services.srdo import SrdoConfig, SrdoViolation

NORMAL = 0x109
MAPPING = (0x62000120, 0x62010120)
DATA = b"\x12\x34\x56\x78"
INVERTED = bytes(b ^ 0xFF for b in DATA)


class Bench:
    def __init__(self, net, bus, sct_p, sct_c, srvt):
        self.p = net.open_line(bus, mode="classic").create_local_node(5)
        self.c = net.open_line(bus, mode="classic").create_local_node(6)
        self.t = net.open_line(bus, mode="classic")
        self.sct_p_ms = sct_p
        self.safe = threading.Event()
        self.safe_at = 0.0
        self.why = None
        self.last_normal = 0.0
        net.open_line(bus, mode="classic", monitor=True).on_frame(self._frame)
        self.c.srdo.add_callback(self._notice)
        self.p.srdo.start(1)
        self.c.srdo.start(1)
        self.p.srdo.configure(1, SrdoConfig("produce", sct_ms=sct_p, srvt_ms=srvt,
                                            cob_id=NORMAL, mapping=MAPPING))
        self.c.srdo.configure(1, SrdoConfig("consume", sct_ms=sct_c, srvt_ms=srvt,
                                            cob_id=NORMAL, mapping=MAPPING))
        self.p.srdo.set_data(1, DATA)
        for node in (self.p, self.c):
            node.srdo.gfc(True)
        self.c.apply("start")
        self.c.wait_for_state("OPERATIONAL")

    def _frame(self, frame):
        if frame.id == NORMAL:
            self.last_normal = time.perf_counter()

    def _notice(self, notice):
        self.safe_at = time.perf_counter()
        self.why = notice.violation
        self.safe.set()

    def _rearm(self):
        """Consumer restarted, fresh pairs from the tool until one checks."""
        self.safe.clear()
        self.c.srdo.restart(1)
        self.t.send_frame(NORMAL, DATA)
        self.t.send_frame(NORMAL + 1, INVERTED)
        deadline = time.monotonic() + 2
        while self.c.srdo.read(1).data is None:
            if time.monotonic() > deadline:
                raise RuntimeError(f"consumer did not run again: {self.c.srdo.read(1)}")
            time.sleep(0.001)

    def _wait(self, want):
        if not self.safe.wait(5) or self.why != want:
            raise RuntimeError(f"expected {want!r}, got {self.why!r}")
        return self.safe_at

    def mismatch(self):
        self._rearm()
        self.t.send_frame(NORMAL, DATA)
        start = time.perf_counter()
        self.t.send_frame(NORMAL + 1, INVERTED[:3] + b"\x00")
        return self._wait(SrdoViolation.INVERTED_MISMATCH) - start

    def srvt(self):
        self._rearm()
        start = time.perf_counter()
        self.t.send_frame(NORMAL, DATA)
        return self._wait(SrdoViolation.SRVT_EXCEEDED) - start

    def sct(self):
        self.safe.clear()
        self.p.apply("start")
        self.c.srdo.restart(1)
        time.sleep(5 * self.sct_p_ms / 1000)
        if self.c.srdo.read(1).data is None:
            raise RuntimeError(f"producer pairs not taken: {self.c.srdo.read(1)}")
        self.p.apply("stop")
        at = self._wait(SrdoViolation.SCT_EXCEEDED)
        return at - self.last_normal

    def gfc(self):
        self._rearm()
        start = time.perf_counter()
        self.p.srdo.send_gfc()
        return self._wait(SrdoViolation.GFC) - start


def row(name, samples, limit_ms):
    ms = sorted(s * 1000 for s in samples)
    limit = f"{limit_ms:7.1f} ms" if limit_ms else "  at once"
    text = (f"{name:9} limit {limit}   reaction min {ms[0]:7.2f}  median "
            f"{statistics.median(ms):7.2f}  max {ms[-1]:7.2f} ms")
    if limit_ms:
        over = [m - limit_ms for m in ms]
        text += f"   past the limit: median {statistics.median(over):6.2f}  max {over[-1]:6.2f} ms"
    print(text, flush=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-n", "--rounds", type=int, default=20)
    parser.add_argument("--sct", type=int, default=20, help="producer SCT, ms (consumer: 2x)")
    parser.add_argument("--srvt", type=int, default=10, help="SRVT, ms")
    parser.add_argument("--bus", default="mem:srdo-bench")
    args = parser.parse_args()
    with canopenfd.Network() as net:
        bench = Bench(net, args.bus, args.sct, 2 * args.sct, args.srvt)
        print(f"SRDO reaction on {args.bus}: producer SCT {args.sct} ms, consumer SCT "
              f"{2 * args.sct} ms, SRVT {args.srvt} ms, {args.rounds} rounds each")
        row("mismatch", [bench.mismatch() for _ in range(args.rounds)], 0)
        row("srvt", [bench.srvt() for _ in range(args.rounds)], args.srvt)
        row("sct", [bench.sct() for _ in range(args.rounds)], 2 * args.sct)
        row("gfc", [bench.gfc() for _ in range(args.rounds)], 0)


if __name__ == "__main__":
    main()
