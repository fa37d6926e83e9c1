"""Firmware download with progress: a 1 MiB image goes to a device's program
domain (USDO bulk download on CAN FD, SDO block download on classic CAN),
with a progress line fed by the C runtime, then the device checks it.

Run:  python3 examples/firmware_download.py [--classic] [--size BYTES]
"""

import argparse
import hashlib
import os
import sys
import time

import canopenfd
from canopenfd.od import demo_od

PROGRAM = 0x2100            # the demo's large DOMAIN stands in for 0x1F50 program data


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--classic", action="store_true", help="SDO block instead of USDO bulk")
    parser.add_argument("--size", type=int, default=1 << 20)
    args = parser.parse_args()
    mode = "classic" if args.classic else "fd"
    image = os.urandom(args.size)

    with canopenfd.Network() as net:
        device = net.open_line("mem:flash", mode=mode).create_local_node(
            5, od=demo_od(mode), boot=False)
        device.serve_domain(PROGRAM, 4 << 20)
        device.boot()
        drive = net.open_line("mem:flash", mode=mode).add_node(5, demo_od(mode))
        client = drive.usdo if mode == "fd" else drive.sdo

        started = time.monotonic()
        last = [0.0]

        def progress(done: int) -> None:           # called by the runtime's progress events
            now = time.monotonic()
            if now - last[0] >= 0.1:                # a terminal line, 10 times a second
                last[0] = now
                print(f"\r{done:>9} / {len(image)} bytes ({100 * done // len(image):3}%)",
                      end="", file=sys.stderr)

        client.download(PROGRAM, image, progress=progress)
        took = time.monotonic() - started
        print(f"\r{len(image):>9} / {len(image)} bytes (100%)", file=sys.stderr)
        kind = "bulk" if mode == "fd" else "block"
        print(f"downloaded {len(image)} bytes ({kind}) in {took * 1000:.1f} ms")
        same = hashlib.sha256(device[PROGRAM].data).digest() == hashlib.sha256(image).digest()
        print("device: image verified" if same else "device: image DIFFERENT")


if __name__ == "__main__":
    main()
