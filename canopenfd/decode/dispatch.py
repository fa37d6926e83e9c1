"""Which protocol a frame belongs to, and its one-line text: `meaning()`,
`decode()` and `describe()` read a frame alone (PDOs by the CiA 301 default
CAN-IDs); the stateful `Decoder` hands in a `DecoderState` that also follows
what needs earlier frames and knows the PDOs and CAN-IDs of object
dictionaries."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Optional

from ..frame import FLAG_EXT, FLAG_FD, FLAG_RTR
from .emcy import EMCY_BASE, emcy_text
from .flyma import FLYMA_IDS, flyma_text
from .heartbeat import ERROR_CONTROL_BASE, GuardingTracker, guarding_request_text, heartbeat_text
from .lss import LSS_MASTER_ID, LSS_SLAVE_ID, lss_text
from .mpdo import mpdo_text
from .nmt import NMT_ID, nmt_text
from .pdo import PdoMap, default_pdo, default_pdo_text, format_pdo_value, pdo_text
from .raw import format_flags, format_raw, frame_fields
from .sdo import SdoBlockTracker, sdo_text
from .service_ids import ServiceIds, service_text
from .sleep import SLEEP_IDS, sleep_text
from .sync import SYNC_ID, sync_text
from .time import TIME_ID, time_text
from .usdo import usdo_text

#: describe() shows at most this many raw bytes of a frame it decodes (a USDO
#: segment's 60 data bytes would drown the line); undecoded frames show all.
DESCRIBE_RAW_BYTES = 12


@dataclass
class DecoderState:
    """What a `Decoder` keeps between frames: the PDOs and SYNC/TIME/EMCY
    CAN-IDs of its object dictionaries, open guarding requests, SDO block
    transfers."""

    pdos: PdoMap = field(default_factory=PdoMap)
    services: ServiceIds = field(default_factory=ServiceIds)
    guarding: GuardingTracker = field(default_factory=GuardingTracker)
    sdo_blocks: SdoBlockTracker = field(default_factory=SdoBlockTracker)


def is_sdo_id(can_id: int) -> bool:
    """0x581..0x5FF or 0x601..0x67F: (U)SDO server->client or client->server."""
    return 0x581 <= can_id <= 0x5FF or 0x601 <= can_id <= 0x67F


def meaning(frame: Any) -> str:
    """What the frame means in CANopen terms, '' when it is nothing this package
    knows. On 0x581..0x5FF and 0x601..0x67F a CAN FD frame is USDO and a
    classic frame is SDO, read alone: byte 0 is taken as a command specifier, so a
    block transfer's sub-block segment reads as the command its byte 0 spells, or
    as 'unknown command 0xNN or block segment #N' (a `Decoder` knows which).
    PDOs are named by the default CAN-IDs only (a `Decoder` with an object
    dictionary decodes their values)."""
    return frame_meaning(frame, None)


def frame_meaning(frame: Any, state: Optional[DecoderState]) -> str:
    """meaning(), with a Decoder's state when given (the frame is then taken
    as the next one seen)."""
    can_id, data, flags = frame_fields(frame)
    rtr, fd, extended = bool(flags & FLAG_RTR), bool(flags & FLAG_FD), bool(flags & FLAG_EXT)
    if state is not None:
        service = state.services.lookup(can_id, extended)
        if service is not None and not rtr:
            return service_text(service[0], service[1], data, fd)
        pdo = state.pdos.lookup(can_id, extended)
        if pdo is not None and pdo.mpdo and not rtr:
            return mpdo_text(f"{pdo.name} node {pdo.node_id}", pdo.mpdo, data,
                             state.pdos.variable, format_pdo_value)
        if pdo is not None:
            return pdo_text(pdo, data, fd, rtr)
    if extended:
        return ""
    if rtr:
        if ERROR_CONTROL_BASE + 1 <= can_id <= ERROR_CONTROL_BASE + 0x7F:
            if state is not None:
                state.guarding.requested(can_id - ERROR_CONTROL_BASE)
            return guarding_request_text(can_id - ERROR_CONTROL_BASE)
        found = default_pdo(can_id)
        return default_pdo_text(can_id, data, rtr=True) if found and found[0][0] == "T" else ""
    if can_id == NMT_ID:
        return nmt_text(data)
    if can_id == SYNC_ID:
        return sync_text(data)
    if EMCY_BASE < can_id <= EMCY_BASE + 0x7F:
        return emcy_text(can_id - EMCY_BASE, data, fd)
    if can_id == TIME_ID:
        return time_text(data)
    if can_id in SLEEP_IDS:
        return sleep_text(can_id, data)
    if can_id in FLYMA_IDS:
        return flyma_text(can_id, data)
    if can_id in (LSS_MASTER_ID, LSS_SLAVE_ID):
        return lss_text(can_id, data)
    if ERROR_CONTROL_BASE <= can_id <= ERROR_CONTROL_BASE + 0x7F:
        node = can_id - ERROR_CONTROL_BASE
        guarded = state is not None and state.guarding.is_reply(node, data)
        return heartbeat_text(node, data, guarded)
    if is_sdo_id(can_id):
        if fd:
            return usdo_text(can_id, data)
        return state.sdo_blocks.text(can_id, data) if state is not None else sdo_text(can_id, data)
    return default_pdo_text(can_id, data)


def decode(frame: Any) -> str:
    """Readable one-line text: the meaning when known, else the raw frame;
    FD frames end with their marker ('[FD BRS]')."""
    return decoded_line(frame, meaning(frame))


def decoded_line(frame: Any, text: str) -> str:
    """decode()'s line for a frame whose meaning is text."""
    text = text or format_raw(frame)
    marker = format_flags(frame)
    return f"{text} {marker}" if marker else text


def describe(frame: Any, width: int = 30) -> str:
    """Raw frame, then its meaning: the CLI monitor's line."""
    return described_line(frame, meaning(frame), width)


def described_line(frame: Any, text: str, width: int) -> str:
    """describe()'s line for a frame whose meaning is text."""
    raw = format_raw(frame, DESCRIBE_RAW_BYTES if text else None)
    marker = format_flags(frame)
    line = f"{raw:<{width}} {text}".rstrip() if text else raw
    return f"{line} {marker}" if marker else line
