"""Many transfers at once from asyncio: one coroutine per device, all on one
CAN FD line; the USDO sessions run side by side in the C runtime while the
event loop only awaits their results.

Eight devices (nodes 2..9) each serve 64 KiB in a domain; the tool reads
every device's identity and its whole domain concurrently, then writes a
parameter to all of them, and reports how long it took in total.

Run:  python3 examples/asyncio_many.py
"""

import asyncio
import os
import time

import canopenfd
from canopenfd.od import demo_od

DEVICES = range(2, 10)
DOMAIN, SIZE = 0x2100, 64 * 1024


async def visit(drive: canopenfd.RemoteNode, expected: bytes) -> str:
    vendor = await drive.usdo.aupload("Identity object.Vendor-ID")
    data = await drive.usdo.aupload(DOMAIN)
    await drive.usdo.adownload("Producer heartbeat time", (200).to_bytes(2, "little"))
    ok = "ok" if data == expected else "DIFFERENT"
    return f"node {drive.node_id}: vendor {vendor.hex()}, {len(data)} bytes {ok}"


async def run(line: canopenfd.Line, contents: dict) -> None:
    drives = [line.add_node(n, demo_od("fd")) for n in DEVICES]
    started = time.monotonic()
    for text in await asyncio.gather(*(visit(d, contents[d.node_id]) for d in drives)):
        print(text)
    took = time.monotonic() - started
    print(f"{len(drives) * 3} transfers, {len(drives)} at a time, in {took:.2f} s")


def main() -> None:
    with canopenfd.Network() as net:
        contents = {}
        for node_id in DEVICES:
            device = net.open_line("mem:many").create_local_node(node_id, od=demo_od("fd"),
                                                                 boot=False)
            device.serve_domain(DOMAIN, SIZE)
            device.boot()
            contents[node_id] = os.urandom(SIZE)
            device[DOMAIN].data = contents[node_id]
        asyncio.run(run(net.open_line("mem:many"), contents))


if __name__ == "__main__":
    main()
