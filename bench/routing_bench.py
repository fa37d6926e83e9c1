#!/usr/bin/env python3
"""SDO through the gateway (SDO networking, issue 16) as a share of direct SDO,
over in-process classic lines of one Network (no kernel, no VM):

    python3 bench/routing_bench.py [-t SECONDS] [--sizes 4,4096,65536]

Direct: a client line on network 3 reads device 5 (demo OD, a DOMAIN at
0x2100 served from memory). Routed: a client line on network 1 reads the same
device through the gateway (node 1 on both lines, the C core relaying every
frame in the runtime thread). Each row runs uploads back to back for a time
budget and prints transfers/s and kB/s side by side with routed/direct. The
issue's target (routed >= 80 % of direct) is for the vcan setup; here both
sides share one runtime thread, so the relay's cost shows in full. Figures
are printed, nothing is asserted.
"""

from __future__ import annotations

import argparse
import time

import canopenfd
from canopenfd.od import demo_od

DEVICE, GATEWAY = 5, 1
U32, DOMAIN = 0x1000, 0x2100


def pattern(size: int) -> bytes:
    return bytes((i * 7 + (i >> 8)) & 0xFF for i in range(size))


def run(read, budget_s: float, size: int) -> tuple:
    count, moved = 0, 0
    end = time.monotonic() + budget_s
    start = time.monotonic()
    while time.monotonic() < end:
        data = read()
        assert len(data) == size, f"read {len(data)} bytes, expected {size}"
        count += 1
        moved += len(data)
    elapsed = time.monotonic() - start
    return count / elapsed, moved / elapsed / 1000


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-t", type=float, default=2.0, help="seconds per row")
    parser.add_argument("--sizes", default="4,4096,65536",
                        help="upload sizes in bytes (4 = the expedited 0x1000)")
    args = parser.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]
    with canopenfd.Network() as network:
        for bus, network_id in (("mem:bench-office", 1), ("mem:bench-machine", 3)):
            gateway = network.open_line(bus, mode="classic")
            gateway.create_local_node(GATEWAY, od=demo_od("classic"))
            gateway.network_id = network_id
        device = network.open_line("mem:bench-machine", mode="classic").create_local_node(
            DEVICE, od=demo_od("classic"))
        device.serve_domain(DOMAIN, max(sizes))
        direct = network.open_line("mem:bench-machine", mode="classic").sdo
        routed = network.open_line("mem:bench-office", mode="classic").sdo.remote(
            network=3, node=DEVICE, gateway=GATEWAY)
        print(f"{'upload':>10} | {'direct /s':>10} {'kB/s':>9} | {'routed /s':>10} {'kB/s':>9}"
              f" | routed/direct")
        for size in sizes:
            if size != 4:
                device[DOMAIN].data = pattern(size)
                key = (DOMAIN, 0)
            else:
                key = (U32, 0)
            d = run(lambda: direct.upload(DEVICE, *key), args.t, size)
            r = run(lambda: routed.upload(*key), args.t, size)
            print(f"{size:>9}B | {d[0]:>10.0f} {d[1]:>9.1f} | {r[0]:>10.0f} {r[1]:>9.1f} |"
                  f" {r[1] / d[1]:>7.0%}")
        print("gateway counters:", {k: v for k, v in network.routing.stats.items()
                                    if k.startswith("sdo_")})


if __name__ == "__main__":
    main()
