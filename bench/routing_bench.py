#!/usr/bin/env python3
"""SDO through the gateway (SDO networking, issue 16) as a share of direct SDO:

    python3 bench/routing_bench.py [-t SECONDS] [--sizes 4,4096,65536]
    python3 bench/routing_bench.py --vcan OFFICE,MACHINE,CELL [-t ...] [--sizes ...]

Direct: a classic client line on the device's bus reads classic device 5
(demo OD, a DOMAIN at 0x2100 served from memory). Routed: a classic client
line on network 1 ("office") reads the same device through the gateway (node
1 on every line, the C core relaying every frame) on network 3 ("machine");
"routed fd": the same client reads fd device 6 (the same DOMAIN) on the fd
network 2 ("cell") through the gateway, which translates the client's SDO
transfer into USDO (co_gateway_sdo_fd.c). Both routed rows are given as a
share of the direct classic row: what reaching the device through the
gateway costs the client. "direct USDO" (an fd client reading device 6 on
its own bus) is printed for reference.

Without --vcan every line is an in-process mem: bus of one Network (one
runtime thread: the relay's cost shows in full). With --vcan the three
interfaces (OFFICE and MACHINE classic, CELL with MTU 72) are real SocketCAN
and the gateway runs in its own process, as a gateway would. Figures are
printed, nothing is asserted.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time

import canopenfd
from canopenfd.od import demo_od

DEVICE, FD_DEVICE, GATEWAY = 5, 6, 1
U32, DOMAIN = 0x1018, 0x2100   # U32: identity, vendor-ID (sub 1)
OFFICE, CELL, MACHINE = 1, 2, 3      # network-ids


def open_gateway(network, office: str, machine: str, cell: str) -> None:
    """The gateway's node 1 on the three lines, joined with their network-ids."""
    for bus, mode, network_id in ((office, "classic", OFFICE), (machine, "classic", MACHINE),
                                  (cell, "fd", CELL)):
        line = network.open_line(bus, mode=mode)
        line.create_local_node(GATEWAY, od=demo_od(mode))
        line.network_id = network_id


def serve_gateway(office: str, machine: str, cell: str) -> None:
    """--gateway-process: the gateway alone, until our stdin closes."""
    with canopenfd.Network() as network:
        open_gateway(network, office, machine, cell)
        print("ready", flush=True)
        sys.stdin.read()
        print("gateway counters:", {k: v for k, v in network.routing.stats.items()
                                    if k.startswith("sdo_") and v}, flush=True)


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
                        help="upload sizes in bytes (4 = the expedited 0x1018 sub 1)")
    parser.add_argument("--vcan", metavar="OFFICE,MACHINE,CELL",
                        help="three SocketCAN interfaces (CELL CAN FD) and the gateway in "
                             "its own process, instead of in-process mem: lines")
    parser.add_argument("--gateway-process", metavar="OFFICE,MACHINE,CELL",
                        help="(internal) run only the gateway on these lines")
    args = parser.parse_args()
    if args.gateway_process:
        serve_gateway(*args.gateway_process.split(","))
        return
    sizes = [int(s) for s in args.sizes.split(",")]
    if args.vcan:
        office, machine, cell = args.vcan.split(",")
    else:
        office, machine, cell = "mem:bench-office", "mem:bench-machine", "mem:bench-cell"
    gateway = None
    with canopenfd.Network() as network:
        if args.vcan:
            env = dict(os.environ)
            here = os.path.dirname(os.path.dirname(os.path.abspath(canopenfd.__file__)))
            env["PYTHONPATH"] = here + os.pathsep + env.get("PYTHONPATH", "")
            gateway = subprocess.Popen(
                [sys.executable, os.path.abspath(__file__), "--gateway-process", args.vcan],
                stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env)
            assert gateway.stdout is not None
            assert gateway.stdout.readline().strip() == "ready", "gateway process failed"
        else:
            open_gateway(network, office, machine, cell)
        device = network.open_line(machine, mode="classic").create_local_node(
            DEVICE, od=demo_od("classic"))
        device.serve_domain(DOMAIN, max(sizes))
        fd_device = network.open_line(cell, mode="fd").create_local_node(
            FD_DEVICE, od=demo_od("fd"))
        fd_device.serve_domain(DOMAIN, max(sizes))
        direct = network.open_line(machine, mode="classic").sdo
        direct_usdo = network.open_line(cell, mode="fd").usdo
        client = network.open_line(office, mode="classic").sdo
        routed = client.remote(network=MACHINE, node=DEVICE, gateway=GATEWAY)
        routed_fd = client.remote(network=CELL, node=FD_DEVICE, gateway=GATEWAY)
        print(f"{'upload':>10} | {'direct /s':>10} {'kB/s':>9} | {'routed /s':>10} {'kB/s':>9}"
              f" {'share':>5} | {'routed fd /s':>12} {'kB/s':>9} {'share':>5} |"
              f" {'direct USDO kB/s':>16}")
        for size in sizes:
            if size != 4:
                device[DOMAIN].data = pattern(size)
                fd_device[DOMAIN].data = pattern(size)
                key = (DOMAIN, 0)
            else:
                key = (U32, 1)
            d = run(lambda: direct.upload(DEVICE, *key), args.t, size)
            r = run(lambda: routed.upload(*key), args.t, size)
            f = run(lambda: routed_fd.upload(*key), args.t, size)
            u = run(lambda: direct_usdo.upload(FD_DEVICE, *key), args.t, size)
            print(f"{size:>9}B | {d[0]:>10.0f} {d[1]:>9.1f} | {r[0]:>10.0f} {r[1]:>9.1f}"
                  f" {r[1] / d[1]:>5.0%} | {f[0]:>12.0f} {f[1]:>9.1f} {f[1] / d[1]:>5.0%} |"
                  f" {u[1]:>16.1f}", flush=True)
        if gateway is not None:
            assert gateway.stdin is not None and gateway.stdout is not None
            gateway.stdin.close()
            print(gateway.stdout.read().strip())
            gateway.wait(timeout=30)
        else:
            print("gateway counters:", {k: v for k, v in network.routing.stats.items()
                                        if k.startswith("sdo_") and v})


if __name__ == "__main__":
    main()
