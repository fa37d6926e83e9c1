#!/usr/bin/env python3
"""The monitor's receive path: a USDO bulk download (1 MiB by default) in
this process, with `canopenfd monitor` on the same in-process bus (mem:),
its output going to a file. Prints the frames on the bus, the frames the
monitor printed, the frames lost (the runtime's count, must be 0) and the
frames per second the monitor decoded and printed.

    .venv/bin/python bench/monitor_bench.py [--size BYTES] [--out FILE]

The monitor runs as the CLI runs it (`canopenfd.cli.main(["monitor", ...],
network=net)`, in the main thread, stdout redirected to the file); the
transfer runs in a second thread, and once the monitor's output stops
growing the bench ends the monitor with a Ctrl-C (KeyboardInterrupt).
"Frames on the bus" is the client line's C counters (rx + tx frames) over
the transfer; "printed" the monitor's USDO lines (a boot-up the monitor may
see before is not counted). "decoded/s" is printed lines / (time of the
monitor's last write to its stdout - transfer start).
Nothing is asserted about timing; the exit status is 1 when frames were
lost or the transfer failed.
"""

from __future__ import annotations

import _thread
import argparse
import os
import sys
import tempfile
import threading
import time
from typing import Any

SERVER = 5
DOMAIN = 0x2100


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=1 << 20, help="bytes downloaded")
    parser.add_argument("--out", help="monitor output file (default: a temporary file)")
    args = parser.parse_args()

    import canopenfd
    from canopenfd.cli import main as cli_main
    from canopenfd.od import demo_od

    out_path = args.out or os.path.join(tempfile.mkdtemp(), "monitor.txt")
    bus = "mem:monitor-bench"
    data = os.urandom(args.size)
    result = {}
    # the event queue the monitor gives its own Network (main before it: the default)
    from canopenfd.cli import monitor as cli_monitor
    net = canopenfd.Network(getattr(cli_monitor, "MONITOR_EVENT_CAPACITY", 0))
    server = net.open_line(bus, mode="fd").create_local_node(SERVER, od=demo_od("fd"),
                                                             boot=False)
    server.serve_domain(DOMAIN, args.size)
    server.boot()
    client = net.open_line(bus, mode="fd")

    class TimedFile:
        """The output file, noting when the monitor last wrote to it (so the
        rate does not depend on when the monitor flushes)."""

        def __init__(self, file: Any) -> None:
            self.file = file
            self.last_write = time.monotonic()

        def write(self, text: str) -> int:
            self.last_write = time.monotonic()
            return self.file.write(text)

        def flush(self) -> None:
            self.file.flush()

        def isatty(self) -> bool:
            return False

    def transfer() -> None:
        time.sleep(0.5)                       # the monitor is up
        before = client.stats
        result["start"] = time.monotonic()
        try:
            client.usdo.download(SERVER, DOMAIN, 0, data, mode="bulk")
            result["ok"] = bytes(server[DOMAIN].data) == data
        except Exception as exc:  # noqa: BLE001 - reported below
            result["error"] = exc
        result["end"] = time.monotonic()
        after = client.stats
        result["on_bus"] = sum(after[k] - before[k] for k in ("rx_frames", "tx_frames"))

    def watch() -> None:
        """Ends the monitor once it wrote nothing for a second after the
        transfer; the time of its last write."""
        while "end" not in result or time.monotonic() - timed.last_write < 1.0:
            time.sleep(0.05)
        result["drained"] = timed.last_write
        _thread.interrupt_main()

    stdout = sys.stdout
    with open(out_path, "w") as out:
        timed = TimedFile(out)
        sys.stdout = timed  # type: ignore[assignment]
        worker = threading.Thread(target=transfer)
        watcher = threading.Thread(target=watch)
        worker.start()
        watcher.start()
        try:
            status = cli_main(["monitor", "--channel", bus], network=net)
        except KeyboardInterrupt:
            status = 0
        finally:
            sys.stdout = stdout
        worker.join()
        watcher.join()
    on_bus = result["on_bus"]
    monitor_stats = next(line.stats for line in net.lines if line.monitor)
    printed = sum(1 for text in open(out_path) if text[10:12] in ("RX", "TX")
                  and text.rstrip().endswith("[FD BRS]") and " USDO " in text)
    lost = monitor_stats["events_lost"] + monitor_stats["rx_overflow"]
    events_lost = net.events_lost
    net.close()
    elapsed = result["drained"] - result["start"]
    transfer_s = result["end"] - result["start"]
    print(f"USDO bulk download of {args.size} bytes: "
          f"{'ok' if result.get('ok') else result.get('error', 'data differ')}, "
          f"{transfer_s:.2f} s ({args.size / transfer_s / 1e6:.2f} MB/s)")
    print(f"frames on the bus       {on_bus}")
    print(f"frames printed          {printed}")
    print(f"frames lost (runtime)   {lost}  (network events lost: {events_lost})")
    print(f"decoded+printed         {printed / max(elapsed, 1e-9):,.0f} frames/s "
          f"(last line {elapsed:.2f} s after the transfer started)")
    print(f"monitor exit status     {status}; output: {out_path}")
    return 0 if result.get("ok") and lost == 0 and events_lost == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
