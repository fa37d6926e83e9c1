#!/usr/bin/env python3
"""Remote USDO through the gateway (issue 16, CiA 1301 routed requests) as a
share of direct USDO, over in-process fd lines of one Network (no kernel, no VM):

    python3 bench/remote_usdo_bench.py [-t SECONDS] [--sizes 4,52,1000]

Direct: a client line on network 2 reads device 5 (demo OD, a DOMAIN at
0x2100 served from memory). Routed: a client line on network 1 reads the same
device through the gateway (node 1 on both lines): every request is carried
out by the gateway's own USDO client on network 2 (store and forward) and
answered routed, so a routed transfer is two transfers back to back on one
runtime thread. 4 B is the expedited 0x1000:01 both ways; 53..1024 B go
segmented on the routed side (52 B is the routed expedited limit, 56 B the
local one). Each row runs uploads back to back for a time budget and prints
transfers/s and kB/s side by side with routed/direct. Figures are printed,
nothing is asserted.
"""

from __future__ import annotations

import argparse

import canopenfd
from canopenfd.od import demo_od
from routing_common import GATEWAY, open_gateway, pattern, run

DEVICE = 5
U32, DOMAIN = (0x1000, 1), (0x2100, 0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-t", type=float, default=2.0, help="seconds per row")
    parser.add_argument("--sizes", default="4,52,1000",
                        help="upload sizes in bytes, at most 1024 (4 = the expedited 0x1000:01)")
    args = parser.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]
    with canopenfd.Network() as network:
        open_gateway(network, [("mem:bench-cell", "fd", 1), ("mem:bench-axis", "fd", 2)])
        device = network.open_line("mem:bench-axis", mode="fd").create_local_node(
            DEVICE, od=demo_od("fd"))
        device.serve_domain(DOMAIN[0], max(sizes))
        direct = network.open_line("mem:bench-axis", mode="fd").usdo
        routed = network.open_line("mem:bench-cell", mode="fd").usdo.remote(
            network=2, node=DEVICE, gateway=GATEWAY)
        print(f"{'upload':>10} | {'direct /s':>10} {'kB/s':>9} | {'routed /s':>10} {'kB/s':>9}"
              f" | routed/direct")
        for size in sizes:
            if size != 4:
                device[DOMAIN[0]].data = pattern(size)
                key = DOMAIN
            else:
                key = U32
            d = run(lambda: direct.upload(DEVICE, *key), args.t, size)
            r = run(lambda: routed.upload(*key), args.t, size)
            print(f"{size:>9}B | {d[0]:>10.0f} {d[1]:>9.1f} | {r[0]:>10.0f} {r[1]:>9.1f} |"
                  f" {r[1] / d[1]:>7.0%}")
        print("gateway counters:", {k: v for k, v in network.routing.stats.items()
                                    if k.startswith("usdo_")})


if __name__ == "__main__":
    main()
