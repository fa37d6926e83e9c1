"""A simulated CiA 402 drive on a line: a local node serving `drive_od` whose
drive (state machine and motion model) runs in C in the runtime thread."""

from __future__ import annotations

from typing import Any, Optional

from ...od import ObjectDictionary
from .objects import SUPPORTED_MODES_ALL, drive_od

__all__ = ["create_simulated_drive"]


def create_simulated_drive(line: Any, node_id: int, *, tick_ms: float = 1.0,
                           heartbeat_ms: int = 0,
                           supported_modes: int = SUPPORTED_MODES_ALL,
                           od: Optional[ObjectDictionary] = None) -> Any:
    """Create local node `node_id` on `line` as a simulated drive and start it.

    Returns the LocalNode; `node.drive_simulation.fault(code)` injects a
    device fault. od: another OD holding the 402 objects (default
    `drive_od(line.mode, supported_modes=...)`)."""
    node = line.create_local_node(node_id, heartbeat_ms,
                                  od=od if od is not None else
                                  drive_od(line.mode, supported_modes=supported_modes))
    node.drive_simulation.start(tick_ms)
    return node
