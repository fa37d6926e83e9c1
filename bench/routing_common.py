"""What the gateway benches (routing_bench.py, remote_usdo_bench.py) share:
the gateway's lines, the data pattern the devices serve, and the timed loop
that turns back-to-back transfers into transfers/s and kB/s."""

from __future__ import annotations

import time
from typing import Callable, Iterable, Optional, Tuple

from canopenfd.od import demo_od

GATEWAY = 1   # the gateway's node-id on every line


def open_gateway(network, lines: Iterable[Tuple[str, str, int]]) -> None:
    """The gateway's node on each (bus, mode, network-id) line, joined with
    that network-id (the C core routes between them)."""
    for bus, mode, network_id in lines:
        line = network.open_line(bus, mode=mode)
        line.create_local_node(GATEWAY, od=demo_od(mode))
        line.network_id = network_id


def pattern(size: int) -> bytes:
    """Bytes a device serves and the bench checks the length of."""
    return bytes((i * 7 + (i >> 8)) & 0xFF for i in range(size))


def run(transfer: Callable[[], Optional[bytes]], budget_s: float,
        size: int) -> Tuple[float, float]:
    """(transfers/s, kB/s) of `transfer` called back to back for budget_s
    seconds: an upload returning the value (which must be `size` bytes) or a
    download of `size` bytes returning None."""
    count, moved = 0, 0
    end = time.monotonic() + budget_s
    start = time.monotonic()
    while time.monotonic() < end:
        data = transfer()
        assert data is None or len(data) == size, f"read {len(data)} bytes, expected {size}"
        count += 1
        moved += size
    elapsed = time.monotonic() - start
    return count / elapsed, moved / elapsed / 1000
