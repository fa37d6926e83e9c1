"""Which CANopen service a frame belongs to and which nodes it concerns:
what the monitor's --service and --node filters look at. The same CAN-ID
rules as `dispatch.frame_meaning` (a Decoder's object dictionaries first,
then the CiA 301 default CAN-IDs), without taking the frame as seen: a
filter may look at a frame the decoder then skips."""

from __future__ import annotations

from typing import Any, Dict, Optional, Tuple

from ..frame import FLAG_EXT, FLAG_FD
from .dispatch import DecoderState, is_sdo_id
from .emcy import EMCY_BASE
from .flyma import FLYMA_IDS
from .heartbeat import ERROR_CONTROL_BASE
from .nmt import NMT_ID
from .pdo import default_pdo
from .raw import frame_fields
from .sleep import SLEEP_IDS
from .sync import SYNC_ID
from .time import TIME_ID

#: LSS (CiA 305): master requests and slave responses (not decoded, only named).
LSS_MASTER_ID, LSS_SLAVE_ID = 0x7E5, 0x7E4

#: Every service a frame is classified as, with what it covers (the monitor's help).
SERVICES: Dict[str, str] = {
    "nmt": "NMT commands (0x000)",
    "sync": "SYNC",
    "time": "TIME",
    "emcy": "EMCY",
    "tpdo": "TPDOs (sent by the node they name)",
    "rpdo": "RPDOs (received by the node they name)",
    "sdo": "classic SDO (classic frames on 0x581..0x5FF, 0x601..0x67F)",
    "usdo": "USDO (CAN FD frames on the same CAN-IDs)",
    "heartbeat": "heartbeat, boot-up and node guarding (0x700 + node-id)",
    "lss": "LSS (0x7E4, 0x7E5)",
    "sleep": "sleep and wake-up (0x690..0x692)",
    "flyma": "flying master negotiation (0x071..0x076)",
    "other": "every other frame",
}
#: Names that stand for several services.
SERVICE_GROUPS: Dict[str, Tuple[str, ...]] = {"pdo": ("tpdo", "rpdo")}

#: (service, node-ids the frame concerns: () for none or all)
Classified = Tuple[str, Tuple[int, ...]]


def frame_service(frame: Any, state: Optional[DecoderState] = None) -> Classified:
    """(service name from SERVICES, the node-ids the frame concerns). NMT: the
    addressed node (0 = every node); SDO: the server; USDO: both ends (the
    CAN-ID names the sender, byte 0 the destination); SYNC, TIME, LSS, other: ()."""
    can_id, data, flags = frame_fields(frame)
    extended, fd = bool(flags & FLAG_EXT), bool(flags & FLAG_FD)
    if state is not None:
        service = state.services.lookup(can_id, extended)
        if service is not None:
            name = service[0].lower()
            return name, (service[1],) if name == "emcy" else ()
        pdo = state.pdos.lookup(can_id, extended)
        if pdo is not None:
            return pdo.name[:4].lower(), (pdo.node_id,)
    if extended:
        return "other", ()
    if can_id == NMT_ID:
        return "nmt", (data[1],) if len(data) >= 2 else ()
    if can_id == SYNC_ID:
        return "sync", ()
    if EMCY_BASE < can_id <= EMCY_BASE + 0x7F:
        return "emcy", (can_id - EMCY_BASE,)
    if can_id == TIME_ID:
        return "time", ()
    if can_id in (LSS_MASTER_ID, LSS_SLAVE_ID):
        return "lss", ()
    if can_id in SLEEP_IDS:
        return "sleep", ()
    if can_id in FLYMA_IDS:
        return "flyma", ()
    if ERROR_CONTROL_BASE < can_id <= ERROR_CONTROL_BASE + 0x7F:
        return "heartbeat", (can_id - ERROR_CONTROL_BASE,)
    if is_sdo_id(can_id):
        sender = can_id & 0x7F
        if not fd:
            return "sdo", (sender,)
        other = data[0] if data and 1 <= data[0] <= 0x7F else None
        return "usdo", (sender,) if other is None or other == sender else (sender, other)
    found = default_pdo(can_id)
    if found is not None:
        return found[0][:4].lower(), (found[1],)
    return "other", ()


def service_names(text: str) -> Tuple[str, ...]:
    """The services one --service NAME stands for (pdo: tpdo and rpdo);
    ValueError naming the known ones."""
    name = text.strip().lower()
    if name in SERVICE_GROUPS:
        return SERVICE_GROUPS[name]
    if name in SERVICES:
        return (name,)
    known = ", ".join([*SERVICES, *SERVICE_GROUPS])
    raise ValueError(f"unknown service {text!r}: expected one of {known}")
