"""EMCY frames (CiA 301, 0x080 + node-id): the classic 8-byte EMCY and the
20-byte CANopen FD one, error codes and error register bits in words.
Layouts as csrc/core/co_emcy_codec.c (the FD one UNCONFIRMED, see
docs/protocol-notes.md "EMCY"). The EMCY service (`canopenfd.emcy`) names
codes with `emcy_code_text` too."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, Optional

from .raw import hex_bytes, with_bytes

EMCY_BASE = 0x080
EMCY_CLASSIC_LEN = 8
EMCY_FD_LEN = 20

#: Error code -> CiA 301 meaning, most specific first when looked up: the
#: exact code, then xx00 (a group), then x000 (a class).
EMCY_CODES: Dict[int, str] = {
    0x1000: "generic error",
    0x2000: "current", 0x2100: "current, device input side",
    0x2200: "current inside the device", 0x2300: "current, device output side",
    0x3000: "voltage", 0x3100: "mains voltage", 0x3200: "voltage inside the device",
    0x3300: "output voltage",
    0x4000: "temperature", 0x4100: "ambient temperature", 0x4200: "device temperature",
    0x5000: "device hardware",
    0x6000: "device software", 0x6100: "internal software", 0x6200: "user software",
    0x6300: "data set",
    0x7000: "additional modules",
    0x8000: "monitoring", 0x8100: "communication",
    0x8110: "CAN overrun (objects lost)", 0x8120: "CAN in error passive mode",
    0x8130: "life guard error or heartbeat error", 0x8140: "recovered from bus off",
    0x8150: "CAN-ID collision",
    0x8200: "protocol error", 0x8210: "PDO not processed due to length error",
    0x8220: "PDO length exceeded", 0x8230: "DAM MPDO not processed, destination object "
    "not available", 0x8240: "unexpected SYNC data length", 0x8250: "RPDO timeout",
    0x9000: "external error",
    0xF000: "additional functions",
    0xFF00: "device specific",
}

#: Error register (0x1001) bits by name, bit 0 first.
ERROR_REGISTER_BITS = ("generic", "current", "voltage", "temperature", "communication",
                       "device profile", "reserved bit 6", "manufacturer")


def emcy_code_text(code: int) -> str:
    """'0x8130 life guard error or heartbeat error (monitoring)', 'error reset'
    for 0x0000, '0xA123 unknown class' outside the CiA 301 classes."""
    if code == 0:
        return "error reset"
    if code >> 8 == 0:
        return f"0x{code:04X} error reset or no error"
    klass = EMCY_CODES.get(code & 0xFF00 if code >> 8 == 0xFF else code & 0xF000)
    specific = EMCY_CODES.get(code) or EMCY_CODES.get(code & 0xFF00) or klass
    if specific is None:
        return f"0x{code:04X} unknown class"
    if klass is not None and specific != klass:
        return f"0x{code:04X} {specific} ({klass})"
    return f"0x{code:04X} {specific}"


def error_register_text(register: int) -> str:
    """'register 0x11 (generic, communication)', 'register 0x00'."""
    names = [name for bit, name in enumerate(ERROR_REGISTER_BITS) if register >> bit & 1]
    return f"register 0x{register:02X}" + (f" ({', '.join(names)})" if names else "")


def emcy_status_text(status: int) -> str:
    """The FD status byte (co_emcy_codec.h): 'priority 4 non-recoverable occurred
    repeated'; bits 6..7 (unknown) shown when set."""
    text = (f"priority {status & 0x07} "
            f"{'non-recoverable' if status & 0x08 else 'recoverable'} "
            f"{'occurred' if status & 0x10 else 'removed'}"
            f"{' repeated' if status & 0x20 else ''}")
    return text + (f" unknown status bits 0x{status & 0xC0:02X}" if status & 0xC0 else "")


@dataclass
class EmcyFields:
    """The fields of an EMCY (co_emcy_msg_t); the FD-only ones are None in a
    classic one."""

    code: int
    error_register: int
    msef: bytes
    logical_device: Optional[int] = None
    spec_number: Optional[int] = None
    status: Optional[int] = None
    time_stamp: Optional[int] = None


def parse_emcy(data: bytes, fd: bool) -> Optional[EmcyFields]:
    """The fields as co_emcy_decode_classic / co_emcy_decode_fd read them, None
    for a length they refuse (classic: exactly 8; fd: at least 20)."""
    if (len(data) < EMCY_FD_LEN) if fd else (len(data) != EMCY_CLASSIC_LEN):
        return None
    msg = EmcyFields(data[0] | data[1] << 8, data[2], bytes(data[3:8]))
    if fd:
        msg.logical_device = data[8]
        msg.spec_number = data[9] | data[10] << 8
        msg.status = data[11]
        msg.time_stamp = int.from_bytes(data[12:18], "little")
    return msg


def emcy_text(node_id: int, data: bytes, fd: bool) -> str:
    """'EMCY node 5 0x3210 voltage inside the device (voltage), register 0x03
    (generic, current), msef 01 02 03 04 05' (msef left out when all zero); FD
    frames add logical device, CiA specification number, status and time."""
    head = f"EMCY node {node_id}"
    msg = parse_emcy(data, fd)
    if msg is None:
        expected = f"at least {EMCY_FD_LEN}" if fd else f"{EMCY_CLASSIC_LEN}"
        return with_bytes(f"{head} malformed: {len(data)} bytes, expected {expected}", data)
    parts = [f"{head} {emcy_code_text(msg.code)}", error_register_text(msg.error_register)]
    if any(msg.msef):
        parts.append(f"msef {hex_bytes(msg.msef)}")
    if fd:
        parts.append(f"logical device {msg.logical_device}")
        parts.append(f"CiA {msg.spec_number}")
        parts.append(emcy_status_text(msg.status or 0))
        parts.append(f"time 0x{msg.time_stamp:012X}" if msg.time_stamp else "no time stamp")
    return ", ".join(parts)

