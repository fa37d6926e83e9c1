"""NMT command frames (CAN-ID 0x000): 'NMT start node 5', 'NMT stop all'."""

from __future__ import annotations

from .._binding.constants import NmtCommand
from .raw import hex_bytes

NMT_ID = 0x000


def nmt_text(data: bytes) -> str:
    """'NMT reset-comm all'; a length other than 2, an unknown command or a
    node-id above 127 is malformed."""
    if len(data) != 2:
        return f"NMT malformed: {len(data)} bytes, expected 2" + (
            f" ({hex_bytes(data)})" if data else "")
    command, node_id = data
    target = "all" if node_id == 0 else f"node {node_id}"
    try:
        label = NmtCommand(command).label
    except ValueError:
        return f"NMT malformed: unknown command 0x{command:02X} for {target}"
    if node_id > 127:
        return f"NMT {label} node {node_id} malformed: node-id outside 0..127"
    return f"NMT {label} {target}"
