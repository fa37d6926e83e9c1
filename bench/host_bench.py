#!/usr/bin/env python3
"""Host lines (python-can buses) against in-process lines (mem:), side by side.

    python3 bench/host_bench.py [-t SECONDS] [--rate PDO_PER_S] [--pdo-seconds S]
                                [--only mem|virtual] [--no-busy]

Two lines of one Network talk to each other, either over the in-process bus
("mem:") or over two python-can `virtual` buses on one channel ("virtual":
the host-driver path every PCAN/Kvaser/IXXAT/Windows user takes). Each row
runs without and with a busy Python thread (a pure-Python loop competing for
the GIL, like an application's own work):

  USDO expedited 4 B     downloads/s for SECONDS (one at a time, blocking)
  USDO segmented 1 MiB   MB/s of one download into a served DOMAIN, checked
                         (cut after 30 s: the share moved by then is shown)
  USDO bulk 1 MiB        same, bulk (unconfirmed segments)
  SDO block 256 KiB      MB/s of one block download (classic lines), checked
  python-can alone       (virtual only) 64-byte FD frames one way between two
                         virtual buses, no stack: the ceiling of the host path
  PDO stream             a generator thread sends PDOs (COB-ID 0x181, numbered)
                         with send_frame() paced at --rate for --pdo-seconds;
                         node 2's RPDO 1 counts them in C. "delivered" = RPDOs
                         received within 1 s after the last send / sent;
                         "lost" = sent - received after 3 s

Per row also: frames lost (the receiving line's rx overflows + the sending
line's tx overflows), the runtime events the Python side lost, and for
virtual lines how many times the receiving host thread waited for room
(back-pressure; `host_rx_waits`, absent before it existed). A failed transfer
shows its error instead of a rate. Nothing is asserted; exit 0.
"""

from __future__ import annotations

import argparse
import itertools
import os
import sys
import threading
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

SERVER, RECEIVER, SENDER = 2, 2, 1
DOMAIN = 0x2100
U32 = 0x2007
MIB = 1 << 20
_channels = itertools.count(1)


def pattern(size: int) -> bytes:
    return bytes((i * 7 + (i >> 8)) & 0xFF for i in range(size))


class Busy:
    """A Python thread that never blocks (competes for the GIL)."""

    def __init__(self) -> None:
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self.loops = 0

    def _run(self) -> None:
        n = 0
        while not self._stop.is_set():
            for _ in range(1000):
                n += 1
        self.loops = n

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join()


class Pair:
    """Two lines of one Network: `a` (client / sender), `b` (server / receiver)."""

    def __init__(self, kind: str, mode: str) -> None:
        import canopenfd
        self.kind = kind
        self.net = canopenfd.Network()
        self.buses = []
        if kind == "mem":
            name = f"mem:hb{next(_channels)}"
            self.a = self.net.open_line(name, mode=mode)
            self.b = self.net.open_line(name, mode=mode)
        else:
            import can
            channel = f"host-bench-{os.getpid()}-{next(_channels)}"
            self.buses = [can.Bus(interface="virtual", channel=channel,
                                  receive_own_messages=False) for _ in range(2)]
            self.a = self.net.open_line(bus=self.buses[0], mode=mode)
            self.b = self.net.open_line(bus=self.buses[1], mode=mode)

    def losses(self) -> dict:
        sa, sb = self.a.stats, self.b.stats
        drv = [self.a.driver_stats, self.b.driver_stats]
        return {"rx_overflow": sa["rx_overflow"] + sb["rx_overflow"],
                "tx_overflow": sa["tx_overflow"] + sb["tx_overflow"],
                "events_lost": self.net.events_lost,
                "rx_waits": sum(d.get("host_rx_waits", 0) for d in drv)
                if self.kind != "mem" else None}

    def close(self) -> None:
        self.net.close()
        for bus in self.buses:
            bus.shutdown()


def server_node(pair: Pair, mode: str):
    from canopenfd.od import demo_od
    node = pair.b.create_local_node(SERVER, od=demo_od(mode), boot=False)
    node.serve_domain(DOMAIN, 2 * MIB)
    node.boot()
    return node


def row_text(result) -> str:
    if isinstance(result, str):
        return result
    return f"{result:,.2f}"


# ====================================================================== rows
def usdo_expedited(kind: str, seconds: float) -> tuple:
    pair = Pair(kind, "fd")
    try:
        server_node(pair, "fd")
        usdo = pair.a.usdo
        data = b"\x78\x56\x34\x12"
        usdo.download(SERVER, U32, 0, data, mode="expedited", timeout=2.0)
        n = 0
        start = time.perf_counter()
        end = start + seconds
        try:
            while time.perf_counter() < end:
                usdo.download(SERVER, U32, 0, data, mode="expedited", timeout=2.0)
                n += 1
        except Exception as exc:  # noqa: BLE001 - reported in the row
            return f"failed after {n}: {exc}", pair.losses()
        return n / (time.perf_counter() - start), pair.losses()
    finally:
        pair.close()


BUDGET_S = 30.0


def download(kind: str, line_mode: str, mode: str, size: int) -> tuple:
    """One download of size bytes into the served DOMAIN (USDO on fd lines,
    SDO on classic ones), cut after BUDGET_S; MB/s or what went wrong."""
    pair = Pair(kind, line_mode)
    try:
        node = server_node(pair, line_mode)
        client = pair.a.usdo if line_mode == "fd" else pair.a.sdo
        data = pattern(size)
        moved = [0]
        start = time.perf_counter()
        transfer = client.start_download(SERVER, DOMAIN, 0, data, mode=mode, timeout=2.0,
                                         progress=lambda n: moved.__setitem__(0, n))
        try:
            transfer.result(timeout=BUDGET_S)
        except TimeoutError:
            transfer.cancel()
            return f"cut at {BUDGET_S:.0f} s ({100 * moved[0] // size}%)", pair.losses()
        except Exception as exc:  # noqa: BLE001 - reported in the row
            return f"failed: {exc}"[:70], pair.losses()
        used = time.perf_counter() - start
        if node[DOMAIN].data != data:
            return "WRONG DATA", pair.losses()
        return size / used / 1e6, pair.losses()
    finally:
        pair.close()


_NO_LOSS = {"rx_overflow": 0, "tx_overflow": 0, "events_lost": 0, "rx_waits": None}


def python_can_alone(kind: str, frames: int = 20_000) -> tuple:
    """The ceiling of any stack on python-can's virtual interface: frames of
    64 bytes one way, built as `can.Message`s, sent by one thread and taken
    by another with recv(): payload MB/s, with no protocol and no C at all."""
    if kind != "virtual":
        return "-", _NO_LOSS
    import can
    channel = f"host-bench-alone-{os.getpid()}-{next(_channels)}"
    sender, receiver = (can.Bus(interface="virtual", channel=channel,
                                receive_own_messages=False) for _ in range(2))
    got = [0]

    def take():
        while got[0] < frames and receiver.recv(2.0) is not None:
            got[0] += 1
    try:
        payload = bytes(range(64))
        thread = threading.Thread(target=take)
        start = time.perf_counter()
        thread.start()
        for i in range(frames):
            sender.send(can.Message(arbitration_id=0x123, data=payload, is_fd=True,
                                    is_extended_id=False, bitrate_switch=True))
        thread.join()
        used = time.perf_counter() - start
        if got[0] != frames:
            return f"got {got[0]} of {frames}", _NO_LOSS
        return frames * 64 / used / 1e6, _NO_LOSS
    finally:
        sender.shutdown()
        receiver.shutdown()


def pdo_stream(kind: str, rate: int, seconds: float) -> tuple:
    from canopenfd.errors import CommandError
    from pdo_bench import COB_ID, receiver_node as _unused  # noqa: F401 - same OD as pdo_bench
    from pdo_bench import configure, pdo_od
    pair = Pair(kind, "fd")
    try:
        node = pair.b.create_local_node(RECEIVER, od=pdo_od("fd"))
        configure(node.rpdo[1], COB_ID)
        node.apply("start")
        time.sleep(0.1)
        pdo = lambda: node.line.service_stats["pdo"]["rx_frames"]  # noqa: E731
        before = pdo()
        sent = 0
        refused = 0
        send = pair.a.send_frame
        chunk = max(1, rate // 1000)          # frames per millisecond
        start = time.perf_counter()
        end = start + seconds
        while True:
            now = time.perf_counter()
            if now >= end:
                break
            due = int((now - start) * rate) + chunk
            while sent < due:
                try:
                    send(COB_ID, sent.to_bytes(4, "little"))
                    sent += 1
                except CommandError:
                    refused += 1              # mailbox full: the generator waits
                    time.sleep(0.0002)
            time.sleep(0.0005)
        last = time.perf_counter()
        reached = sent / (last - start)
        time.sleep(1.0)
        in_time = pdo() - before
        time.sleep(2.0)
        got = pdo() - before
        losses = pair.losses()
        losses["sent"] = sent
        losses["reached"] = reached
        losses["lost"] = sent - got
        return 100.0 * in_time / sent if sent else 0.0, losses
    finally:
        pair.close()


# ====================================================================== main
def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("-t", type=float, default=1.0, help="seconds of expedited downloads")
    ap.add_argument("--rate", type=int, default=100_000, help="PDOs per second offered")
    ap.add_argument("--pdo-seconds", type=float, default=2.0)
    ap.add_argument("--only", choices=("mem", "virtual"))
    ap.add_argument("--no-busy", action="store_true", help="skip the busy-thread runs")
    args = ap.parse_args()
    import canopenfd
    kinds = [args.only] if args.only else ["mem", "virtual"]
    rows = [
        ("USDO expedited 4 B", "/s", lambda k: usdo_expedited(k, args.t)),
        ("USDO segmented 1 MiB", "MB/s", lambda k: download(k, "fd", "segmented", MIB)),
        ("USDO bulk 1 MiB", "MB/s", lambda k: download(k, "fd", "bulk", MIB)),
        ("SDO block 256 KiB", "MB/s", lambda k: download(k, "classic", "block", 256 << 10)),
        ("python-can alone 64 B one way", "MB/s", python_can_alone),
        (f"PDO stream {args.rate}/s delivered", "%",
         lambda k: pdo_stream(k, args.rate, args.pdo_seconds)),
    ]
    print(f"canopenfd {getattr(canopenfd, '__version__', '?')} from "
          f"{os.path.dirname(canopenfd.__file__)}; python {sys.version.split()[0]}")
    for busy in ([False] if args.no_busy else [False, True]):
        print(f"\n== {'with' if busy else 'without'} a busy Python thread")
        print(f"{'figure':32} {'unit':5} " + " ".join(f"{k:>14}" for k in kinds)
              + "   losses (rx overflow / tx overflow / events lost / rx waits)")
        for name, unit, run in rows:
            cells, notes = [], []
            for kind in kinds:
                if busy:
                    with Busy():
                        value, loss = run(kind)
                else:
                    value, loss = run(kind)
                cells.append(f"{row_text(value):>14}" if not isinstance(value, str)
                             else f"{value:>14}")
                extra = ""
                if "sent" in loss:
                    extra = (f" sent {loss['sent']} ({loss['reached']:,.0f}/s) "
                             f"lost {loss['lost']}")
                notes.append(f"{kind}: {loss['rx_overflow']}/{loss['tx_overflow']}/"
                             f"{loss['events_lost']}/{loss['rx_waits']}{extra}")
            print(f"{name:32} {unit:5} " + " ".join(cells) + "   " + "; ".join(notes),
                  flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
