"""LSS frames (CiA 305, see csrc/include/canopenfd/co_lss.h): 0x7E5 master to
slaves, 0x7E4 slaves to master, 8 bytes, byte 0 the command specifier:
'LSS switch global configuration', 'LSS fast scan id 0x00000000 bit 128 sub
vendor next vendor', 'LSS answer inquire node-id 5'."""

from __future__ import annotations

from .raw import with_bytes

LSS_MASTER_ID, LSS_SLAVE_ID = 0x7E5, 0x7E4
FRAME_LEN = 8
PARTS = ("vendor", "product", "revision", "serial")
_SELECT = {0x40: "vendor", 0x41: "product", 0x42: "revision", 0x43: "serial"}
_IDENTIFY = {0x46: "vendor", 0x47: "product", 0x48: "revision low", 0x49: "revision high",
             0x4A: "serial low", 0x4B: "serial high"}
_INQUIRE = {0x5A: "vendor", 0x5B: "product", 0x5C: "revision", 0x5D: "serial",
            0x5E: "node-id"}
_CONFIGURE = {0x11: "configure node-id", 0x13: "configure bit timing",
              0x17: "store configuration"}


def _u32(data: bytes) -> int:
    return int.from_bytes(data[1:5], "little")


def _part(value: int) -> str:
    return PARTS[value] if value < len(PARTS) else f"part {value}"


def _master_text(cs: int, data: bytes) -> str:
    if cs == 0x04:
        mode = {0: "waiting", 1: "configuration"}.get(data[1], f"mode {data[1]}")
        return f"LSS switch global {mode}"
    if cs == 0x11:
        return f"LSS configure node-id {data[1]}"
    if cs == 0x13:
        return f"LSS configure bit timing table {data[1]} index {data[2]}"
    if cs == 0x15:
        return f"LSS activate bit timing delay {data[1] | data[2] << 8} ms"
    if cs == 0x17:
        return "LSS store configuration"
    if cs in _SELECT:
        return f"LSS switch selective {_SELECT[cs]} 0x{_u32(data):08X}"
    if cs in _IDENTIFY:
        return f"LSS identify remote slave {_IDENTIFY[cs]} 0x{_u32(data):08X}"
    if cs == 0x4C:
        return "LSS identify non-configured remote slave"
    if cs == 0x51:
        return (f"LSS fast scan id 0x{_u32(data):08X} bit {data[5]} sub {_part(data[6])} "
                f"next {_part(data[7])}")
    if cs in _INQUIRE:
        return f"LSS inquire {_INQUIRE[cs]}"
    return with_bytes(f"LSS request malformed: unknown command 0x{cs:02X}", data)


def _slave_text(cs: int, data: bytes) -> str:
    if cs in _CONFIGURE:
        error = data[1]
        outcome = "ok" if error == 0 else f"error {error}" + \
            (f" (specific 0x{data[2]:02X})" if error == 0xFF else "")
        return f"LSS answer {_CONFIGURE[cs]} {outcome}"
    if cs == 0x44:
        return "LSS answer switch selective: configuration"
    if cs == 0x4F:
        return "LSS answer identify / fast scan"
    if cs == 0x50:
        return "LSS answer non-configured slave"
    if cs == 0x5E:
        return f"LSS answer inquire node-id {data[1]}"
    if cs in _INQUIRE:
        return f"LSS answer inquire {_INQUIRE[cs]} 0x{_u32(data):08X}"
    return with_bytes(f"LSS answer malformed: unknown command 0x{cs:02X}", data)


def lss_text(can_id: int, data: bytes) -> str:
    """The text of a frame on 0x7E5 (requests) or 0x7E4 (answers)."""
    if len(data) != FRAME_LEN:
        return with_bytes(f"LSS malformed: {len(data)} bytes, expected {FRAME_LEN}", data)
    return _master_text(data[0], data) if can_id == LSS_MASTER_ID else _slave_text(data[0], data)
