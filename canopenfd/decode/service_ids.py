"""The SYNC, TIME and EMCY CAN-IDs object dictionaries configure (0x1005,
0x1012, 0x1014), for ids other than the defaults, and the text of a frame on
one of them."""

from __future__ import annotations

from typing import Any, Dict, Optional, Tuple

from .emcy import emcy_text
from .od_values import COB_11_BITS, COB_29_BITS, COB_EXT, COB_INVALID, configured_int
from .sync import sync_text
from .time import time_text


class ServiceIds:
    """The SYNC (0x1005), TIME (0x1012) and EMCY (0x1014) CAN-IDs object
    dictionaries configure, for ids other than the defaults: `Decoder` asks
    here before the default ids. add_od() once per node."""

    def __init__(self) -> None:
        self._by_id: Dict[Tuple[int, bool], Tuple[str, int]] = {}

    def add_od(self, od: Any, node_id: int) -> None:
        """Take the ids of `od` on node node_id (the OD's value, else its
        default, $NODEID resolved). An EMCY COB-ID with bit 31 (invalid) set
        is left out; bit 29 is a 29-bit CAN-ID (EMCY only: SYNC and TIME are
        11-bit in this stack)."""
        for index, service in ((0x1005, "SYNC"), (0x1012, "TIME"), (0x1014, "EMCY")):
            cob = configured_int(od, index, 0, node_id)
            if cob is None or (service == "EMCY" and cob & COB_INVALID):
                continue
            extended = service == "EMCY" and bool(cob & COB_EXT)
            can_id = cob & (COB_29_BITS if extended else COB_11_BITS)
            self._by_id.setdefault((can_id, extended), (service, node_id))

    def lookup(self, can_id: int, extended: bool = False) -> Optional[Tuple[str, int]]:
        """('SYNC' / 'TIME' / 'EMCY', node-id of the OD) or None; the first OD
        added wins."""
        return self._by_id.get((can_id, extended))


def service_text(service: str, node_id: int, data: bytes, fd: bool) -> str:
    """The text of a SYNC, TIME or EMCY frame (ServiceIds.lookup's service)."""
    if service == "SYNC":
        return sync_text(data)
    if service == "TIME":
        return time_text(data)
    return emcy_text(node_id, data, fd)
