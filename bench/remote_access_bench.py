"""Remote-access gateway (seed 001) figures, side by side: the frame codec's
speed, and requests per second through the gateway over a pty and over loopback
TCP against the same request made directly from Python on the line.

    .venv/bin/python bench/remote_access_bench.py [--seconds S]

Nothing is asserted; the figures depend on the machine and its load.
"""

from __future__ import annotations

import argparse
import os
import time
import tty
from typing import Callable, Tuple

import canopenfd
from canopenfd.gateway import remote_access as ra
from canopenfd.gateway.remote_access_client import RemoteAccessClient
from canopenfd.gateway.remote_access_server import RemoteAccessServer
from canopenfd.gateway.remote_access_stream import FdStream
from canopenfd.od import demo_od


def rate(action: Callable[[], object], seconds: float) -> Tuple[float, int]:
    """(calls per second, calls) of `action` run for about `seconds`."""
    count = 0
    start = time.perf_counter()
    end = start + seconds
    while time.perf_counter() < end:
        action()
        count += 1
    return count / (time.perf_counter() - start), count


def codec(seconds: float) -> None:
    payload = ra.encode_command(ra.RemoteWrite(5, 0x2006, 0, bytes(28)))   # a full frame
    frame = ra.encode_frame(payload)
    stream = frame * 1000
    decoder = ra.FrameDecoder()
    per_s, _ = rate(lambda: decoder.feed(stream), seconds)
    print(f"decode  {per_s * 1000:12,.0f} frames/s  ({per_s * len(stream) / 1e6:6.2f} MB/s, "
          f"{len(frame)}-byte frames)")
    per_s, _ = rate(lambda: ra.encode_frame(payload), seconds)
    print(f"encode  {per_s:12,.0f} frames/s")


def round_trips(seconds: float) -> None:
    with canopenfd.Network() as net:
        line = net.open_line("mem:bench-ra", mode="fd")
        line.create_local_node(1, od=demo_od("fd"))
        net.open_line("mem:bench-ra").create_local_node(5, od=demo_od("fd"))
        with RemoteAccessServer({1: line}) as server:
            master, slave = os.openpty()
            tty.setraw(master)
            tty.setraw(slave)
            server.serve(FdStream(master, "pty"))
            port = server.serve_tcp(0)
            with RemoteAccessClient(FdStream(slave, "pty")) as pty_host, \
                    RemoteAccessClient.connect("127.0.0.1", port) as tcp_host:
                local = line.local_node
                assert local is not None
                rows = [
                    ("local read, Python API", lambda: local[0x1017].data),
                    ("local read R, pty", lambda: pty_host.read_local(0x1017)),
                    ("local read R, tcp", lambda: tcp_host.read_local(0x1017)),
                    ("USDO upload, Python API", lambda: line.usdo.upload(5, 0x1018, 1)),
                    ("remote read U, pty", lambda: pty_host.read_remote(5, 0x1018, 1)),
                    ("remote read U, tcp", lambda: tcp_host.read_remote(5, 0x1018, 1)),
                ]
                for name, action in rows:
                    per_s, count = rate(action, seconds)
                    print(f"{name:26} {per_s:10,.0f} requests/s  ({count} in {seconds:g} s)")
                print("server counters:", server.stats)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=2.0,
                        help="how long each figure is measured (default 2)")
    args = parser.parse_args()
    codec(args.seconds)
    round_trips(args.seconds)


if __name__ == "__main__":
    main()
