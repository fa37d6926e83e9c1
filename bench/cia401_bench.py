#!/usr/bin/env python3
"""CiA 401 set_inputs calls per second: the core-bound device against the
Python path it replaced, in the same run.

    python3 bench/cia401_bench.py [-s SECONDS] [--inputs N]

One CiA 401 device (node 5, classic, N digital inputs = N/8 groups) on an
in-process bus, pre-operational, so no TPDO is sent by either path and only
the application path is timed. Alternating levels, so every call changes
0x6000.

  core     IoDevice.set_inputs: one runtime call; the core applies polarity,
           filter and masks from the parameters it keeps equal to the OD and
           writes 0x6000
  python   what IoDevice.set_inputs did before the core held the device,
           re-enacted through the public API: per group, read the six
           parameter entries (0x6002, 0x6003, 0x6005..0x6008) from the node's
           OD, run the C channel logic (co_cia401_din_update on a struct of
           its own) and write 0x6000

Printed: calls/s of each and the ratio. Nothing is asserted.
"""

from __future__ import annotations

import argparse
import time

import canopenfd
from canopenfd._binding.core import ffi, lib
from canopenfd.profiles.cia401 import create_io_device


def old_path(node, groups, levels: int) -> None:
    for number, group in enumerate(groups, start=1):
        group.polarity = node[(0x6002, number)].raw
        group.filter = node[(0x6003, number)].raw
        group.interrupt_enable = bool(node[(0x6005, 0)].raw)
        group.any_change = node[(0x6006, number)].raw
        group.rising = node[(0x6007, number)].raw
        group.falling = node[(0x6008, number)].raw
        lib.co_cia401_din_update(group, (levels >> (8 * (number - 1))) & 0xFF)
        node[(0x6000, number)].raw = group.value


def rate(call, seconds: float) -> float:
    count, levels, end = 0, 0, time.perf_counter() + seconds
    while time.perf_counter() < end:
        for _ in range(100):
            levels ^= 0x5A5A5A5A5A5A5A5A
            call(levels)
        count += 100
    return count / seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("-s", "--seconds", type=float, default=3.0)
    parser.add_argument("--inputs", type=int, default=64, help="digital inputs (8..64)")
    args = parser.parse_args()
    with canopenfd.Network() as net:
        device = create_io_device(net.open_line("mem:cia401-bench", mode="classic"), 5,
                                  digital_inputs=args.inputs, digital_outputs=8,
                                  analog_inputs=0, analog_outputs=0)
        mask = (1 << args.inputs) - 1
        groups = [ffi.new("co_cia401_din_t *") for _ in range(device.layout.input_groups)]
        core = rate(lambda levels: device.set_inputs(levels & mask), args.seconds)
        python = rate(lambda levels: old_path(device.node, groups, levels & mask), args.seconds)
    print(f"set_inputs, {args.inputs} digital inputs ({len(groups)} groups), "
          f"{args.seconds:.0f} s each:")
    print(f"  core    {core:10.0f} calls/s")
    print(f"  python  {python:10.0f} calls/s")
    print(f"  ratio   {core / python:10.1f} x")


if __name__ == "__main__":
    main()
