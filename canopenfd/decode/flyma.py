"""Flying master frames (CiA 302-2, see csrc/include/canopenfd/co_flyma.h):
'FLYMA active master node 11 priority 0', 'FLYMA negotiation request', ...
0x71 carries [priority, node-id]; 0x72..0x76 carry no data."""

from __future__ import annotations

from .raw import with_bytes

FLYMA_IDS = range(0x71, 0x77)
_EMPTY = {0x72: "negotiation request", 0x73: "active master request",
          0x74: "master capable", 0x75: "master capable request",
          0x76: "force negotiation"}


def flyma_text(can_id: int, data: bytes) -> str:
    """The text of a frame on 0x71..0x76; other lengths than the protocol's are malformed."""
    if can_id == 0x71:
        if len(data) != 2:
            return with_bytes(f"FLYMA active master malformed: {len(data)} bytes, expected 2",
                              data)
        return f"FLYMA active master node {data[1]} priority {data[0]}"
    name = _EMPTY[can_id]
    if data:
        return with_bytes(f"FLYMA {name} malformed: {len(data)} bytes, expected 0", data)
    return f"FLYMA {name}"
