#!/usr/bin/env python3
"""CiA 309-3 ASCII gateway: requests per second over loopback TCP against a
local device, next to the same reads through the Python API directly.

    .venv/bin/python bench/gateway_ascii_bench.py [-t SECONDS] [--modes fd,classic]

Processes: a child process runs the gateway (asyncio, its main thread) and
the device (our node 5, demo OD, on the same in-process bus, served by the C
runtime); this process runs the TCP clients, so client and gateway Python do
not share one GIL. Rows, each for -t seconds:

- "info version": answered by the gateway alone (no bus): the protocol's cost;
- "r 0x1017 0 u16", 1 client, one request at a time: a read's round trip;
- the same, 1 client with 16 requests in flight (pipelined on the socket);
- the same, 4 clients with 16 in flight each;
- "w 0x1017 0 u16 N" the same ways;
- the direct API in the child (line.usdo / line.sdo .upload(5, 0x1017, 0),
  blocking, one at a time), for comparison.

Figures are printed; nothing is asserted about timing.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import socket
import subprocess
import sys
import threading
import time
from typing import List, Tuple

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def serve(mode: str, seconds: float) -> None:
    """The child: device + gateway; prints the port, then the direct-API rate
    when asked on stdin ('direct'), exits on 'quit'."""
    import canopenfd
    from canopenfd.gateway.ascii309_server import AsciiGateway
    from canopenfd.od import demo_od

    net = canopenfd.Network()
    net.open_line("mem:bench", mode=mode).create_local_node(5, od=demo_od(mode))
    line = net.open_line("mem:bench", mode=mode)
    gateway = AsciiGateway({1: line})
    client = line.usdo if mode == "fd" else line.sdo

    async def main() -> None:
        await gateway.start("127.0.0.1", 0)
        print(gateway.port, flush=True)
        loop = asyncio.get_running_loop()
        while True:
            command = (await loop.run_in_executor(None, sys.stdin.readline)).strip()
            if command == "direct":
                def direct() -> Tuple[int, float]:
                    count, start = 0, time.perf_counter()
                    while time.perf_counter() - start < seconds:
                        client.upload(5, 0x1017, 0)
                        count += 1
                    return count, time.perf_counter() - start
                count, elapsed = await loop.run_in_executor(None, direct)
                print(f"{count} {elapsed}", flush=True)
            else:
                break
        await gateway.aclose()

    asyncio.run(main())
    net.close()


def run_clients(port: int, clients: int, window: int, request: str,
                seconds: float) -> Tuple[int, float, int]:
    """(answers, seconds, errors) of `clients` connections each keeping
    `window` requests in flight for `seconds`."""
    counts = [0] * clients
    errors = [0] * clients
    start = time.perf_counter()
    stop = start + seconds

    def one(n: int) -> None:
        sock = socket.create_connection(("127.0.0.1", port))
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        buffer = b""
        seq = 0
        in_flight = 0
        while True:
            now = time.perf_counter()
            while in_flight < window and now < stop:
                text = request.replace("N", str(seq % 5000 + 10))
                sock.sendall(f"[{seq}] {text}\n".encode())
                seq += 1
                in_flight += 1
            if in_flight == 0:
                break
            while b"\r\n" not in buffer:
                buffer += sock.recv(65536)
            while b"\r\n" in buffer:
                line, buffer = buffer.split(b"\r\n", 1)
                in_flight -= 1
                counts[n] += 1
                if b"ERROR" in line:
                    errors[n] += 1
        sock.close()

    threads = [threading.Thread(target=one, args=(n,)) for n in range(clients)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    return sum(counts), time.perf_counter() - start, sum(errors)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("-t", "--seconds", type=float, default=3.0,
                        help="time per row (default 3 s)")
    parser.add_argument("--modes", default="fd,classic", help="line modes (default fd,classic)")
    parser.add_argument("--serve", metavar="MODE", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.serve:
        serve(args.serve, args.seconds)
        return 0
    rows: List[Tuple[str, str, float, int]] = []
    for mode in args.modes.split(","):
        child = subprocess.Popen([sys.executable, __file__, "--serve", mode, "-t",
                                  str(args.seconds)], stdin=subprocess.PIPE,
                                 stdout=subprocess.PIPE, text=True, cwd=os.path.join(ROOT, "bench"))
        assert child.stdout is not None and child.stdin is not None
        port = int(child.stdout.readline())
        for name, request, clients, window in (
                ("info version (no bus)", "info version", 1, 1),
                ("read, 1 client, 1 in flight", "5 r 0x1017 0 u16", 1, 1),
                ("read, 1 client, 16 in flight", "5 r 0x1017 0 u16", 1, 16),
                ("read, 4 clients, 16 in flight each", "5 r 0x1017 0 u16", 4, 16),
                ("write, 1 client, 1 in flight", "5 w 0x1017 0 u16 N", 1, 1),
                ("write, 4 clients, 16 in flight each", "5 w 0x1017 0 u16 N", 4, 16)):
            count, elapsed, errors = run_clients(port, clients, window, request, args.seconds)
            rows.append((mode, name, count / elapsed, errors))
        child.stdin.write("direct\n")
        child.stdin.flush()
        count, elapsed = child.stdout.readline().split()
        rows.append((mode, "direct API upload (no gateway), 1 at a time",
                     int(count) / float(elapsed), 0))
        child.stdin.write("quit\n")
        child.stdin.flush()
        child.wait(30)
    print(f"{'line':8} {'row':46} {'requests/s':>11} {'errors':>7}")
    for mode, name, rate, errors in rows:
        print(f"{mode:8} {name:46} {rate:11.0f} {errors:7d}")
    return 1 if any(errors for *_, errors in rows) else 0


if __name__ == "__main__":
    sys.exit(main())
