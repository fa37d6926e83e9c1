#!/usr/bin/env python3
"""SDO through the gateway (SDO networking, issue 16) as a share of direct SDO:

    python3 bench/routing_bench.py [-t SECONDS] [--sizes 4,4096,65536]
    python3 bench/routing_bench.py --vcan OFFICE,MACHINE,CELL [-t ...] [--sizes ...]

Direct: a classic client line on the device's bus reads (and writes)
classic device 5 (demo OD plus one memory DOMAIN per size at 0x2110 + k).
Through the gateway (node 1 on every line) a classic client line on network
1 ("office") reaches the same device on network 3 ("machine") twice:
"relayed" with routing.sdo_buffering off (the C core relays every frame),
"buffered" with it on (the default: the gateway answers the client's
segments from its buffer while its own SDO client works the device,
co_gateway_sdo_buffered.c); "routed fd": the same client reaches fd device 6 (the
same DOMAINs) on the fd network 2 ("cell"), the gateway translating the
client's SDO transfer into USDO. Every routed column is given as a share of
the direct classic one: what reaching the device through the gateway costs
the client. "direct USDO" (an fd client on device 6's own bus, uploads) is
printed for reference.

Without --vcan every line is an in-process mem: bus of one Network (one
runtime thread: the relay's cost shows in full). With --vcan the three
interfaces (OFFICE and MACHINE classic, CELL with MTU 72) are real SocketCAN,
the gateway runs in its own process and the two devices in another, as on a
real bus (the client's process holds only client lines). Each size above 4
bytes is read twice: segmented (the client's default) and "block" (a size
hint: AUTO asks for a block upload, which the gateway relays; the fd
translation refuses it with 0x05040001 and the client goes segmented), then
written segmented. Figures are printed, nothing is asserted.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys

import canopenfd
from canopenfd.od import DataType, ODVariable, demo_od
from routing_common import GATEWAY, open_gateway, pattern, run

DEVICE, FD_DEVICE = 5, 6
U32, DOMAIN = 0x1018, 0x2110   # U32: identity, vendor-ID (sub 1); DOMAIN + k: size k
U32_RW = 0x2007                 # the demo OD's writable UNSIGNED32
OFFICE, CELL, MACHINE = 1, 2, 3      # network-ids


def gateway_lines(office: str, machine: str, cell: str) -> list:
    """The gateway's three lines: (bus, mode, network-id)."""
    return [(office, "classic", OFFICE), (machine, "classic", MACHINE), (cell, "fd", CELL)]


def open_devices(network, machine: str, cell: str, sizes: list) -> None:
    """Classic device 5 and fd device 6, DOMAIN + k holding pattern(sizes[k])."""
    for bus, mode, node in ((machine, "classic", DEVICE), (cell, "fd", FD_DEVICE)):
        od = demo_od(mode)
        for k, size in enumerate(sizes):
            od.add_object(ODVariable(f"Bench {size}", DOMAIN + k, 0, DataType.DOMAIN, "rw",
                                     max_length=max(size, 1)))
        device = network.open_line(bus, mode=mode).create_local_node(node, od=od, boot=False)
        for k, size in enumerate(sizes):
            device.serve_domain(DOMAIN + k, max(size, 1))
        device.boot()
        for k, size in enumerate(sizes):
            device[DOMAIN + k].data = pattern(size)


def serve(role: str, lines: list, sizes: list) -> None:
    """--process: the gateway or the devices alone, until our stdin closes."""
    office, machine, cell = lines
    with canopenfd.Network() as network:
        if role == "gateway":
            open_gateway(network, gateway_lines(office, machine, cell))
        else:
            open_devices(network, machine, cell, sizes)
        print("ready", flush=True)
        for command in sys.stdin:   # "buffer on|off" from the client's process
            if role == "gateway" and command.startswith("buffer "):
                network.routing.sdo_buffering = command.split()[1] == "on"
            print("ok", flush=True)
        if role == "gateway":
            print("gateway counters:", {k: v for k, v in network.routing.stats.items()
                                        if k.startswith("sdo_") and v}, flush=True)


def spawn(role: str, lines: str, sizes: str) -> subprocess.Popen:
    env = dict(os.environ)
    here = os.path.dirname(os.path.dirname(os.path.abspath(canopenfd.__file__)))
    env["PYTHONPATH"] = here + os.pathsep + env.get("PYTHONPATH", "")
    proc = subprocess.Popen([sys.executable, os.path.abspath(__file__), "--process", role,
                             "--vcan", lines, "--sizes", sizes],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env)
    assert proc.stdout is not None
    assert proc.stdout.readline().strip() == "ready", f"the {role} process failed"
    return proc


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-t", type=float, default=2.0, help="seconds per row")
    parser.add_argument("--sizes", default="4,4096,65536",
                        help="upload sizes in bytes (4 = the expedited 0x1018 sub 1)")
    parser.add_argument("--vcan", metavar="OFFICE,MACHINE,CELL",
                        help="three SocketCAN interfaces (CELL CAN FD); the gateway and the "
                             "devices in their own processes, instead of in-process mem: lines")
    parser.add_argument("--process", choices=("gateway", "devices"),
                        help="(internal, with --vcan) run only the gateway or the devices")
    args = parser.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]
    if args.process:
        serve(args.process, args.vcan.split(","), sizes)
        return
    if args.vcan:
        office, machine, cell = args.vcan.split(",")
    else:
        office, machine, cell = "mem:bench-office", "mem:bench-machine", "mem:bench-cell"
    helpers = []
    with canopenfd.Network() as network:
        if args.vcan:
            helpers = [spawn(role, args.vcan, args.sizes) for role in ("gateway", "devices")]
        else:
            open_gateway(network, gateway_lines(office, machine, cell))
            open_devices(network, machine, cell, sizes)
        direct = network.open_line(machine, mode="classic").sdo
        direct_usdo = network.open_line(cell, mode="fd").usdo
        client = network.open_line(office, mode="classic").sdo
        routed = client.remote(network=MACHINE, node=DEVICE, gateway=GATEWAY)
        routed_fd = client.remote(network=CELL, node=FD_DEVICE, gateway=GATEWAY)
        def buffering(on: bool) -> None:
            if args.vcan:
                gateway = helpers[0]
                assert gateway.stdin is not None and gateway.stdout is not None
                gateway.stdin.write(f"buffer {'on' if on else 'off'}\n")
                gateway.stdin.flush()
                assert gateway.stdout.readline().strip() == "ok"
            else:
                network.routing.sdo_buffering = on

        print(f"{'transfer':>19} | {'direct kB/s':>11} | {'relayed kB/s':>12} {'share':>5} |"
              f" {'buffered kB/s':>13} {'share':>5} | {'routed fd kB/s':>14} {'share':>5} |"
              f" {'direct USDO kB/s':>16}")
        for k, size in enumerate(sizes):
            key = (U32, 1) if size == 4 else (DOMAIN + k, 0)
            value = pattern(size)
            rows = [("upload segmented", "upload", {}),
                    ("upload block", "upload", {"size_hint": size}),
                    ("download segmented", "download", {"mode": "segmented"})]
            for label, kind, options in rows:
                if size == 4 and kind == "upload" and options:
                    continue
                if size == 4:
                    label = f"{kind} expedited"
                    options = {}

                def transfer(node, *target):
                    if kind == "upload":
                        return lambda: node.upload(*target, *key, **options)
                    where = (U32_RW, 0) if size == 4 else key
                    return lambda: node.download(*target, *where, value, **options)

                d = run(transfer(direct, DEVICE), args.t, size)
                buffering(False)
                r = run(transfer(routed), args.t, size)
                buffering(True)
                b = run(transfer(routed), args.t, size)
                f = run(transfer(routed_fd), args.t, size)
                u = run(transfer(direct_usdo, FD_DEVICE), args.t, size) \
                    if kind == "upload" else (0.0, float("nan"))
                name = f"{size}B {label}"
                print(f"{name:>19} | {d[1]:>11.1f} | {r[1]:>12.1f} {r[1] / d[1]:>5.0%} |"
                      f" {b[1]:>13.1f} {b[1] / d[1]:>5.0%} | {f[1]:>14.1f} {f[1] / d[1]:>5.0%} |"
                      f" {u[1]:>16.1f}", flush=True)
        if not args.vcan:
            print("gateway counters:", {k: v for k, v in network.routing.stats.items()
                                        if k.startswith("sdo_") and v})
    for proc in helpers:
        assert proc.stdin is not None and proc.stdout is not None
        proc.stdin.close()
        tail = proc.stdout.read().strip()
        if tail:
            print(tail)
        proc.wait(timeout=30)


if __name__ == "__main__":
    main()
