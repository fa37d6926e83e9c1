"""The object dictionary of the simulated CiA 402 drive: the demo node's
communication objects and 4 RPDOs/TPDOs, device type 0x00020192 (profile
402, servo drive), the 402 objects the simulator needs, and the default PDO
mappings a real drive ships with (RPDO1 controlword, TPDO1 statusword)."""

from __future__ import annotations

from typing import Optional, Tuple

from ...od import ODRecord, ODVariable, ObjectDictionary
from ...od.datatypes import DataType
from ...od.demo import demo_od

__all__ = ["drive_od", "DEVICE_TYPE_402", "SUPPORTED_MODES_ALL", "TPDO_EVENT_TIMER_MS"]

DEVICE_TYPE_402 = 0x00020192
#: 0x6502 bits (mode - 1): PP, PV, homing, CSP, CSV, CST.
TPDO_EVENT_TIMER_MS = 100
SUPPORTED_MODES_ALL = (1 << 0) | (1 << 2) | (1 << 5) | (1 << 7) | (1 << 8) | (1 << 9)

I8, I16, I32 = DataType.INTEGER8, DataType.INTEGER16, DataType.INTEGER32
U8, U16, U32 = DataType.UNSIGNED8, DataType.UNSIGNED16, DataType.UNSIGNED32

# index, name, type, access, default, PDO-mappable
_OBJECTS = (
    (0x603F, "Error code", U16, "ro", 0, True),
    (0x6040, "Controlword", U16, "rw", 0, True),
    (0x6041, "Statusword", U16, "ro", 0, True),
    (0x6060, "Modes of operation", I8, "rw", 0, True),
    (0x6061, "Modes of operation display", I8, "ro", 0, True),
    (0x6064, "Position actual value", I32, "ro", 0, True),
    (0x606C, "Velocity actual value", I32, "ro", 0, True),
    (0x6071, "Target torque", I16, "rw", 0, True),
    (0x6077, "Torque actual value", I16, "ro", 0, True),
    (0x607A, "Target position", I32, "rw", 0, True),
    (0x6081, "Profile velocity", U32, "rw", 1000, True),
    (0x6083, "Profile acceleration", U32, "rw", 10000, True),
    (0x6084, "Profile deceleration", U32, "rw", 10000, True),
    (0x6098, "Homing method", I8, "rw", 35, False),
    (0x609A, "Homing acceleration", U32, "rw", 10000, False),
    (0x60FF, "Target velocity", I32, "rw", 0, True),
)


def _set(od: ObjectDictionary, index: int, sub: int, value: int) -> None:
    variable = od.get_variable(index, sub)
    assert variable is not None, f"0x{index:04X}:{sub:02X} is in demo_od"
    variable.default = value


def _map(od: ObjectDictionary, kind: str, number: int,
         entries: Tuple[Tuple[int, int], ...]) -> None:
    """A default mapping: valid COB-ID (predefined + node-id), type 255; a
    TPDO also every TPDO_EVENT_TIMER_MS, so a master's view never stays stale."""
    comm, mapping = (0x1400, 0x1600) if kind == "RPDO" else (0x1800, 0x1A00)
    base = (0x200 if kind == "RPDO" else 0x180) + 0x100 * (number - 1)
    cob_id = od.get_variable(comm + number - 1, 1)
    assert cob_id is not None, "demo_od(pdos=4) has the PDO's COB-ID"
    cob_id.set_default(base, relative_to_node_id=True)
    for sub, (index, bits) in enumerate(entries, 1):
        _set(od, mapping + number - 1, sub, index << 16 | bits)
    _set(od, mapping + number - 1, 0, len(entries))
    if kind == "TPDO":
        _set(od, comm + number - 1, 5, TPDO_EVENT_TIMER_MS)


def drive_od(mode: str = "classic", node_id: Optional[int] = None, *,
             supported_modes: int = SUPPORTED_MODES_ALL) -> ObjectDictionary:
    """The simulated drive's OD for an 'fd' or 'classic' line."""
    od = demo_od(mode, node_id, pdos=4)
    _set(od, 0x1000, 1 if mode == "fd" else 0, DEVICE_TYPE_402)
    for index, name, dtype, access, default, mappable in _OBJECTS:
        od.add_object(ODVariable(name, index, 0, dtype, access, default,
                                 pdo_mapping=mappable))
    homing = ODRecord("Homing speeds", 0x6099)
    homing.add_member(ODVariable("Highest sub-index supported", 0x6099, 0, U8, "ro", 2))
    homing.add_member(ODVariable("Speed during search for switch", 0x6099, 1, U32, "rw", 100))
    homing.add_member(ODVariable("Speed during search for zero", 0x6099, 2, U32, "rw", 10))
    od.add_object(homing)
    period = ODRecord("Interpolation time period", 0x60C2)
    period.add_member(ODVariable("Highest sub-index supported", 0x60C2, 0, U8, "ro", 2))
    period.add_member(ODVariable("Interpolation time period value", 0x60C2, 1, U8, "rw", 1))
    period.add_member(ODVariable("Interpolation time index", 0x60C2, 2, I8, "rw", -3))
    od.add_object(period)
    od.add_object(ODVariable("Supported drive modes", 0x6502, 0, U32, "ro", supported_modes))
    _map(od, "RPDO", 1, ((0x6040, 16),))
    _map(od, "TPDO", 1, ((0x6041, 16),))
    od.device_info.update({"ProductName": "canopenfd simulated CiA 402 drive"})
    return od
