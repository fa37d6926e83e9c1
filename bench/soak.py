#!/usr/bin/env python3
"""Soak: every service at once for a long time, with nothing lost or leaked.

    python3 bench/soak.py [--minutes M] [--interval S] [--fd CHANNEL] [--classic CHANNEL]
                          [--pdo-ms N] [--sync-ms N] [--check]
    (in the test VM: bash bench/vcan_bench.sh --soak [options]; make -C bench soak)

On each of two lines (an fd line, default vcan0, and a classic line, default
vcan2 with MTU 16) a device and a master run in two Networks (two runtime
threads; with "mem:NAME" channels, which live inside one Network, in one):
  - the device (node 5 fd / 6 classic) sends its heartbeat every 100 ms,
    TPDO 1 every --pdo-ms ms (event timer; the 4-byte "Demo UNSIGNED32",
    counting up), raises and clears an EMCY every second, and serves a
    64 KiB domain;
  - the master (node 1 / 2) watches the device's heartbeat (500 ms), receives
    the TPDO as its RPDO 1 (a Python callback per PDO checks the value goes
    up by one), consumes the EMCYs and produces SYNC every --sync-ms ms;
  - a thread per line runs transfers in a loop: identity uploads, 4 KiB
    domain downloads read back and compared (USDO on fd, SDO on classic).
Every --interval seconds one line: process RSS, open descriptors, and per
line PDOs sent/received, PDOs older than the one before ("backwards": the
kernel may reorder two frames of one socket on SMP; more than 1 in 1000
fails --check), SYNCs, EMCYs, transfers ok/failed,
heartbeat losses, then the runtime events lost, queue overflows and kernel
drops. At the end the TPDOs stop and everything sent is compared with
everything received. --check: exit 1 when anything was lost or failed, when a
descriptor leaked between the first interval and the end, or when RSS looks
like a leak: still growing over the last third of the run (by more than 2 %
and 1 MiB), or grown by more than 12 MiB (and 25 %) in all. A one-time step
while the process warms up (allocator arenas, the event ring after a stall)
is no leak: CI's VM showed RSS settle at ~35 MiB, sometimes only after 90 s
(a 2-minute version runs in CI's vcan lane).
"""

from __future__ import annotations

import argparse
import os
import sys
import threading
import time
from typing import Dict, List

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from pdo_bench import VALUE, pdo_od  # noqa: E402  (the demo OD plus RPDO 1 / TPDO 1)

DOMAIN = 0x2100
DOMAIN_SIZE = 64 << 10
CHUNK = 4096
EMCY_CODE = 0x2310


def rss_kib() -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    return 0


def open_fds() -> int:
    return len(os.listdir("/proc/self/fd"))


class LineSoak:
    """One device and one master on one channel, and the transfer loop."""

    def __init__(self, dev_net, master_net, channel: str, mode: str, device_id: int,
                 master_id: int, args: argparse.Namespace) -> None:
        self.name = mode
        self.mode = mode
        self.counts: Dict[str, int] = dict.fromkeys(
            ("pdo_rx", "pdo_backwards", "emcy_raised", "emcy_rx", "xfer_ok", "xfer_failed",
             "hb_lost"), 0)
        self.errors: List[str] = []
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._last_value = None
        self.dev_line = dev_net.open_line(channel, mode=mode)
        self.master_line = master_net.open_line(channel, mode=mode)
        od = pdo_od(mode)
        self.device = self.dev_line.create_local_node(device_id, od=od, boot=False)
        self.device.serve_domain(DOMAIN, DOMAIN_SIZE)
        self.device.boot()
        self.device.heartbeat_ms = 100
        self.master = self.master_line.create_local_node(master_id, od=pdo_od(mode))
        self.remote = self.master_line.add_node(device_id,
                                                heartbeat_timeout_ms=args.hb_timeout_ms)
        self.timeout = args.transfer_timeout
        self.remote.on_heartbeat_lost(lambda: self._count("hb_lost"))
        self.remote.emcy.add_callback(self._on_emcy)
        cob_id = 0x180 + device_id
        self.device[VALUE].raw = 0          # the main loop counts up from here
        self._configure(self.device.tpdo[1], cob_id, event_timer=args.pdo_ms)
        rpdo = self._configure(self.master.rpdo[1], cob_id, event_timer=0)
        rpdo.add_callback(self._on_pdo)
        self.master.apply("start")
        self.master_line.nmt.start(device_id)
        self.remote.nmt.wait_for_state("OPERATIONAL", timeout=5)
        self.master_line.sync.start(args.sync_ms / 1000)
        self._threads = [threading.Thread(target=self._transfers, name=f"soak {mode} transfers",
                                          daemon=True),
                         threading.Thread(target=self._emcys, name=f"soak {mode} emcy",
                                          daemon=True)]
        for thread in self._threads:
            thread.start()

    @staticmethod
    def _configure(pdo, cob_id: int, event_timer: int):
        pdo.read()
        pdo.clear()
        pdo.add_variable(VALUE)
        pdo.cob_id = cob_id
        pdo.trans_type = 255 if event_timer else 254
        pdo.event_timer = event_timer
        pdo.enabled = True
        pdo.save()
        return pdo

    def _count(self, key: str, n: int = 1) -> None:
        with self._lock:
            self.counts[key] += n

    def _fail(self, text: str) -> None:
        with self._lock:
            self.counts["xfer_failed"] += 1
            if len(self.errors) < 10:
                self.errors.append(text)

    def _on_pdo(self, pdo) -> None:
        value = pdo[VALUE].raw
        with self._lock:
            self.counts["pdo_rx"] += 1
            # the main loop counts the device's value up: a PDO must never carry an
            # older value than the one before it (reordered or stale delivery)
            if self._last_value is not None and value < self._last_value:
                self.counts["pdo_backwards"] += 1
                if len(self.errors) < 10:
                    self.errors.append(f"{self.name}: PDO {self.counts['pdo_rx']} carried "
                                       f"{value} after {self._last_value}")
            self._last_value = value

    def _on_emcy(self, emcy) -> None:
        if emcy.code == EMCY_CODE and not emcy.removed:
            self._count("emcy_rx")

    def _emcys(self) -> None:
        while not self._stop.wait(1.0):
            self.device.emcy.raise_error(EMCY_CODE, b"\x01")
            self._count("emcy_raised")
            time.sleep(0.1)
            self.device.emcy.clear(EMCY_CODE)

    def _transfers(self) -> None:
        access = self.remote.usdo if self.mode == "fd" else self.remote.sdo
        n = 0
        while not self._stop.is_set():
            n += 1
            try:
                access.upload((0x1018, 1), timeout=self.timeout)
                data = bytes((n + i) & 0xFF for i in range(CHUNK))
                access.download(DOMAIN, data, timeout=self.timeout)
                back = access.upload(DOMAIN, timeout=self.timeout)
                if back != data:
                    self._fail(f"{self.name}: domain read back {len(back)} bytes that differ")
                    continue
                self._count("xfer_ok", 3)
            except Exception as exc:  # noqa: BLE001 - every failure is counted and shown
                if self._stop.is_set():
                    break
                self._fail(f"{self.name}: {type(exc).__name__}: {exc}")
            time.sleep(0.002)

    def stop(self) -> None:
        self._stop.set()
        for thread in self._threads:
            thread.join(10)
        self.device.tpdo[1].event_timer = 0
        self.device.tpdo[1].save()
        self.master_line.sync.stop()

    def sent_pdos(self) -> int:
        return self.dev_line.service_stats["pdo"]["tx_frames"]

    def received_pdos_c(self) -> int:
        return self.master_line.service_stats["pdo"]["rx_frames"]

    def losses(self) -> Dict[str, int]:
        out: Dict[str, int] = {}
        for side, line in (("device", self.dev_line), ("master", self.master_line)):
            stats, driver = line.stats, line.driver_stats
            out[f"{side}_rx_overflow"] = stats["rx_overflow"]
            out[f"{side}_tx_overflow"] = stats["tx_overflow"]
            out[f"{side}_kernel_drops"] = driver["kernel_drops"]
            out[f"{side}_tx_refused"] = driver["tx_refused"]
        return out

    def line_text(self) -> str:
        with self._lock:
            c = dict(self.counts)
        sync = self.dev_line.service_stats["sync"]["received"]
        return (f"{self.name}: pdo {self.sent_pdos()}/{c['pdo_rx']} backwards {c['pdo_backwards']} "
                f"sync {sync} emcy {c['emcy_raised']}/{c['emcy_rx']} "
                f"xfers {c['xfer_ok']} ok {c['xfer_failed']} failed hb-lost {c['hb_lost']}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--minutes", type=float, default=60.0)
    parser.add_argument("--interval", type=float, default=60.0, help="seconds between lines")
    parser.add_argument("--fd", default="vcan0", help="fd channel ('' = none)")
    parser.add_argument("--classic", default="vcan2", help="classic channel ('' = none)")
    parser.add_argument("--pdo-ms", type=int, default=1, help="TPDO event timer (ms)")
    parser.add_argument("--sync-ms", type=int, default=1, help="SYNC period (ms)")
    parser.add_argument("--hb-timeout-ms", type=int, default=500,
                        help="the master's heartbeat timeout of the device (ms)")
    parser.add_argument("--transfer-timeout", type=float, default=2.0,
                        help="per-frame timeout of the transfers (s)")
    parser.add_argument("--check", action="store_true",
                        help="exit 1 on any loss, failure, RSS growth or descriptor leak")
    args = parser.parse_args()
    import canopenfd

    dev_net = canopenfd.Network()
    # mem: buses live inside one Network: the master shares the device's there
    in_process = any(c.startswith("mem:") for c in (args.fd, args.classic) if c)
    master_net = dev_net if in_process else canopenfd.Network()
    lines: List[LineSoak] = []
    try:
        if args.fd:
            lines.append(LineSoak(dev_net, master_net, args.fd, "fd", 5, 1, args))
        if args.classic:
            lines.append(LineSoak(dev_net, master_net, args.classic, "classic", 6, 2, args))
        print(f"soak: {', '.join(f'{s.name} on {s.dev_line.channel}' for s in lines)}; "
              f"TPDO every {args.pdo_ms} ms, SYNC every {args.sync_ms} ms, "
              f"{args.minutes} min, a line every {args.interval} s", flush=True)
        start = time.monotonic()
        end = start + args.minutes * 60
        first_rss = first_fds = None
        samples: List[int] = []      # RSS (KiB) at every line, then at the end
        # the mapped value counts up every 10 ms: received PDOs must never go back
        counter = 0
        next_line = start + args.interval
        while time.monotonic() < end:
            counter = (counter + 1) & 0xFFFFFFFF
            for soak in lines:
                soak.device[VALUE].raw = counter
            time.sleep(0.01)
            if time.monotonic() >= next_line:
                next_line += args.interval
                rss, fds = rss_kib(), open_fds()
                samples.append(rss)
                if first_rss is None:
                    first_rss, first_fds = rss, fds
                lost = dev_net.events_lost + \
                    (master_net.events_lost if master_net is not dev_net else 0)
                losses = {k: v for s in lines for k, v in s.losses().items() if v}
                print(f"t={time.monotonic() - start:6.0f}s rss={rss / 1024:6.1f} MiB fds={fds} | "
                      + " | ".join(s.line_text() for s in lines)
                      + f" | events lost {lost}" + (f" {losses}" if losses else ""), flush=True)
        for soak in lines:
            soak.stop()
        time.sleep(1.0)   # the last PDOs and callbacks arrive
        rss, fds = rss_kib(), open_fds()
        problems: List[str] = []
        for soak in lines:
            sent, got_c = soak.sent_pdos(), soak.received_pdos_c()
            c = soak.counts
            print(f"end {soak.name}: PDOs sent {sent}, received {got_c} (C) / {c['pdo_rx']} "
                  f"(Python callbacks), backwards {c['pdo_backwards']}; EMCYs {c['emcy_raised']} raised, "
                  f"{c['emcy_rx']} heard; transfers {c['xfer_ok']} ok, {c['xfer_failed']} failed; "
                  f"heartbeat losses {c['hb_lost']}")
            for text in soak.errors:
                print(f"  {text}")
            if sent != got_c or sent != c["pdo_rx"]:
                problems.append(f"{soak.name}: PDOs lost")
            # Our path is FIFO end to end (the tx queue, one socket, the rx queue,
            # the event queue, one dispatcher), but the kernel may hand a socket two
            # frames out of order when the sender ran on two CPUs in turn (its
            # per-CPU receive backlog; seen in the VM: 1 to 3 PDOs in 10^5). A few
            # are reported; more than 1 in 1000 is a fault of ours.
            if c["pdo_backwards"] * 1000 > max(c["pdo_rx"], 1):
                problems.append(f"{soak.name}: {c['pdo_backwards']} PDOs out of order")
            if c["emcy_raised"] != c["emcy_rx"]:
                problems.append(f"{soak.name}: EMCYs lost")
            if c["xfer_failed"] or c["xfer_ok"] == 0:
                problems.append(f"{soak.name}: transfers failed")
            if c["hb_lost"]:
                problems.append(f"{soak.name}: heartbeat lost")
            losses = {k: v for k, v in soak.losses().items() if v}
            if losses:
                problems.append(f"{soak.name}: {losses}")
        lost = dev_net.events_lost + (master_net.events_lost if master_net is not dev_net else 0)
        if lost:
            problems.append(f"{lost} runtime events lost")
        if first_rss is not None:
            samples.append(rss)
            growth = rss - first_rss
            late = samples[(2 * len(samples)) // 3]   # the sample two thirds in
            print(f"end: rss {first_rss / 1024:.1f} -> {rss / 1024:.1f} MiB "
                  f"({late / 1024:.1f} two thirds in), fds {first_fds} -> {fds}")
            if rss - late > max(late // 50, 1024):
                problems.append(f"RSS still growing: {rss - late} KiB over the last third")
            if growth > max(first_rss // 4, 12 * 1024):
                problems.append(f"RSS grew by {growth} KiB")
            if fds > first_fds:
                problems.append(f"{fds - first_fds} descriptors more")
    finally:
        master_net.close()
        dev_net.close()
    print("soak: " + ("; ".join(problems) if problems else "nothing lost, nothing failed"))
    return 1 if problems and args.check else 0


if __name__ == "__main__":
    sys.exit(main())
