"""The built-in demo object dictionary, built in code.

It holds what a node of this stack needs today (device type, error register,
store/restore, heartbeat consumer and producer, identity, and on CANopen FD
the version information) plus manufacturer objects that exercise every data
type, limits, strings with a maximum length, a large writable DOMAIN and a
RECORD with a gap, so the C side, the CLI and the tests have one complete
example. ``canopenfd od show builtin:fd`` prints it.
"""

from __future__ import annotations

from typing import Optional

from .datatypes import DataType, TimeDifference, TimeOfDay
from .errors import OdValueError
from .model import ODArray, ODRecord, ODVariable, ObjectDictionary

__all__ = ["demo_od", "DOMAIN_MAX_LENGTH", "PROCESS_DATA"]

U8, U16, U32 = DataType.UNSIGNED8, DataType.UNSIGNED16, DataType.UNSIGNED32

#: Size limit of the demo's large DOMAIN 0x2100 (application data behind callbacks).
DOMAIN_MAX_LENGTH = 16 * 1024 * 1024

#: The mappable UNSIGNED32 array of demo_od(pdos=N): 16 entries, one full CAN FD PDO.
PROCESS_DATA = 0x2300
_MAX_DEMO_PDOS = 4      # CiA 301's predefined connection set has 4 RPDOs and 4 TPDOs
_PDO_ENTRIES = 16
_PDO_FIELDS = {1: ("COB-ID used by PDO", U32), 2: ("Transmission type", U8),
               3: ("Inhibit time", U16), 5: ("Event timer", U16), 6: ("SYNC start value", U8)}

# CiA 301 0x1010/0x1011 read value: bit 0 = saves/restores on command.
_ON_COMMAND = 0x00000001
# 0x1030 word: CiA document number 0x515 (1301), part 0, sub-part 0, version 1,
# sub-version 0, class 0 -- the value the EmSA FD example uses (protocol notes §5.5).
_CIA1301_V1_0 = 0x51500100


def _array(name: str, index: int, element: str, dtype: DataType, access: str, count: int,
           default: object = None, count_access: str = "ro") -> ODArray:
    array = ODArray(name, index)
    array.add_member(ODVariable("Highest sub-index supported", index, 0, U8, count_access,
                                count))
    for sub in range(1, count + 1):
        array.add_member(ODVariable(f"{element} {sub}", index, sub, dtype, access, default))
    return array


def _communication(od: ObjectDictionary, mode: str) -> None:
    if mode == "fd":
        # CiA 1301: 0x1000 is an ARRAY, one device type per logical device.
        od.add_object(_array("Device type", 0x1000, "Device type", U32, "ro", 1, 0))
    else:
        od.add_object(ODVariable("Device type", 0x1000, 0, U32, "ro", 0))
    od.add_object(ODVariable("Error register", 0x1001, 0, U8, "ro", 0, pdo_mapping=True))

    for index, verb, object_name in ((0x1010, "Save", "Store parameters"),
                                     (0x1011, "Restore default", "Restore default parameters")):
        array = ODArray(object_name, index)
        array.add_member(ODVariable("Highest sub-index supported", index, 0, U8, "ro", 4))
        for sub, what in ((1, "all parameters"), (2, "communication parameters"),
                          (3, "application parameters"),
                          (4, "manufacturer defined parameters")):
            array.add_member(ODVariable(f"{verb} {what}", index, sub, U32, "rw", _ON_COMMAND))
        od.add_object(array)

    od.add_object(_array("Consumer heartbeat time", 0x1016, "Consumer heartbeat time",
                         U32, "rw", 8, 0))
    od.add_object(ODVariable("Producer heartbeat time", 0x1017, 0, U16, "rw", 0))

    identity = ODRecord("Identity object", 0x1018)
    identity.add_member(ODVariable("Highest sub-index supported", 0x1018, 0, U8, "ro", 4))
    for sub, what in ((1, "Vendor-ID"), (2, "Product code"), (3, "Revision number"),
                      (4, "Serial number")):
        identity.add_member(ODVariable(what, 0x1018, sub, U32, "ro", 0))
    od.add_object(identity)

    if mode == "fd":
        # UNCONFIRMED layout (protocol notes §0 and §5.5): an ARRAY of U32 words
        # (CiA document, part, sub-part, version, sub-version, class), one per
        # specification implemented; only the CiA 1301 word here.
        version = _array("Version information", 0x1030, "Version information", U32,
                         "ro", 1, _CIA1301_V1_0)
        version.line_mode = "fd"
        od.add_object(version)


# One manufacturer entry per data type at 0x2000 + the type's index:
# (type, access, default, low limit, high limit, PDO mapping)
_EVERY_TYPE = (
    (DataType.BOOLEAN, "rw", True, None, None, True),
    (DataType.INTEGER8, "rw", -8, -100, 100, True),
    (DataType.INTEGER16, "rww", -1000, -2000, 2000, True),
    (DataType.INTEGER32, "rw", -100000, None, None, True),
    (DataType.UNSIGNED8, "rwr", 8, None, None, True),
    (DataType.UNSIGNED16, "rw", 1000, 10, 5000, True),
    (DataType.UNSIGNED32, "rw", 0x12345678, None, None, True),
    (DataType.REAL32, "rw", 1.5, -50.0, 150.0, True),
    (DataType.VISIBLE_STRING, "rw", "canopenfd", None, None, False),
    (DataType.OCTET_STRING, "rw", bytes.fromhex("0102030405060708"), None, None, False),
    (DataType.UNICODE_STRING, "rw", "Grüße", None, None, False),
    (DataType.TIME_OF_DAY, "rw", TimeOfDay(12 * 3600 * 1000, 14610), None, None, False),
    (DataType.TIME_DIFFERENCE, "rw", TimeDifference(1500, 1), None, None, False),
    (DataType.DOMAIN, "rw", b"", None, None, False),
    (DataType.INTEGER24, "rw", -(1 << 23), None, None, True),
    (DataType.REAL64, "rw", -0.25, None, None, True),
    (DataType.INTEGER40, "rw", -(1 << 39), None, None, True),
    (DataType.INTEGER48, "rw", (1 << 47) - 1, None, None, True),
    (DataType.INTEGER56, "ro", -1, None, None, True),
    (DataType.INTEGER64, "rw", -(1 << 63), None, None, True),
    (DataType.UNSIGNED24, "rw", 0xABCDEF, None, None, True),
    (DataType.UNSIGNED40, "rw", (1 << 40) - 1, None, None, True),
    (DataType.UNSIGNED48, "rw", 0x123456789ABC, None, None, True),
    (DataType.UNSIGNED56, "rw", 0, None, None, True),
    (DataType.UNSIGNED64, "rw", (1 << 64) - 1, None, None, True),
)
_MAX_LENGTHS = {DataType.VISIBLE_STRING: 32, DataType.OCTET_STRING: 8,
                DataType.UNICODE_STRING: 64, DataType.DOMAIN: 1024}


def _manufacturer(od: ObjectDictionary) -> None:
    for dtype, access, default, low, high, pdo in _EVERY_TYPE:
        od.add_object(ODVariable(
            f"Demo {dtype.name}", 0x2000 + dtype, 0, dtype, access, default,
            low_limit=low, high_limit=high, pdo_mapping=pdo,
            max_length=_MAX_LENGTHS.get(dtype)))

    # Large writable DOMAIN: the data is the application's, reached through
    # callbacks later; the OD only describes it (and never stores it).
    od.add_object(ODVariable("Demo large domain", 0x2100, 0, DataType.DOMAIN, "rw",
                             max_length=DOMAIN_MAX_LENGTH,
                             description="application data up to 16 MiB"))

    record = ODRecord("Demo record", 0x2200)
    record.add_member(ODVariable("Highest sub-index supported", 0x2200, 0, U8, "ro", 4))
    record.add_member(ODVariable("Setpoint", 0x2200, 1, DataType.INTEGER16, "rw", 0,
                                 low_limit=-500, high_limit=500, pdo_mapping=True))
    record.add_member(ODVariable("Gain", 0x2200, 2, DataType.REAL32, "rw", 1.0))
    # sub-index 3 deliberately absent: records may have gaps
    record.add_member(ODVariable("Label", 0x2200, 4, DataType.VISIBLE_STRING, "rw", "axis",
                                 max_length=16))
    od.add_object(record)


def _pdo(od: ObjectDictionary, kind: str, number: int) -> None:
    """RPDO or TPDO `number` (1..4): its communication record (the predefined
    COB-ID + node-id, invalid until configured; type 255) and a mapping array
    of _PDO_ENTRIES entries, nothing mapped."""
    comm, mapping, base, subs = ((0x1400, 0x1600, 0x200, (1, 2, 5)) if kind == "RPDO"
                                 else (0x1800, 0x1A00, 0x180, (1, 2, 3, 5, 6)))
    comm, mapping, base = comm + number - 1, mapping + number - 1, base + 0x100 * (number - 1)
    record = ODRecord(f"{kind} communication parameter {number}", comm)
    record.add_member(ODVariable("Highest sub-index supported", comm, 0, U8, "ro", max(subs)))
    for sub in subs:
        name, dtype = _PDO_FIELDS[sub]
        var = ODVariable(name, comm, sub, dtype, "rw", 255 if sub == 2 else 0)
        if sub == 1:
            var.set_default(0x80000000 + base, relative_to_node_id=True)
        record.add_member(var)
    od.add_object(record)
    array = ODArray(f"{kind} mapping parameter {number}", mapping)
    array.add_member(ODVariable("Number of mapped objects", mapping, 0, U8, "rw", 0))
    for sub in range(1, _PDO_ENTRIES + 1):
        array.add_member(ODVariable(f"Mapped object {sub}", mapping, sub, U32, "rw", 0))
    od.add_object(array)


def _process_data(od: ObjectDictionary, pdos: int) -> None:
    """SYNC objects, `pdos` RPDOs and TPDOs, and PROCESS_DATA to map."""
    od.add_object(ODVariable("COB-ID SYNC message", 0x1005, 0, U32, "rw", 0x80))
    od.add_object(ODVariable("Communication cycle period", 0x1006, 0, U32, "rw", 0))
    od.add_object(ODVariable("Synchronous counter overflow value", 0x1019, 0, U8, "rw", 0))
    for number in range(1, pdos + 1):
        _pdo(od, "RPDO", number)
        _pdo(od, "TPDO", number)
    data = ODArray("Process data", PROCESS_DATA)
    data.add_member(ODVariable("Highest sub-index supported", PROCESS_DATA, 0, U8, "ro",
                               _PDO_ENTRIES))
    for sub in range(1, _PDO_ENTRIES + 1):
        data.add_member(ODVariable(f"Process data {sub}", PROCESS_DATA, sub, U32, "rw", 0,
                                   pdo_mapping=True))
    od.add_object(data)


def demo_od(mode: str = "fd", node_id: Optional[int] = None, *,
            pdos: int = 0) -> ObjectDictionary:
    """The demo object dictionary for an 'fd' or a 'classic' line.

    pdos: also that many RPDOs and TPDOs (0..4; CiA 301's predefined COB-IDs,
    invalid until configured, 16 mapping entries each), the SYNC objects
    0x1005/0x1006/0x1019 and "Process data" PROCESS_DATA (0x2300): 16
    mappable UNSIGNED32 entries, one full CAN FD PDO."""
    if isinstance(pdos, bool) or not isinstance(pdos, int) or not 0 <= pdos <= _MAX_DEMO_PDOS:
        raise OdValueError(f"demo_od: pdos must be an int 0..{_MAX_DEMO_PDOS}, got {pdos!r}")
    od = ObjectDictionary(mode=mode, node_id=node_id)
    _communication(od, mode)
    _manufacturer(od)
    if pdos:
        _process_data(od, pdos)
    od.device_info.update({"VendorName": "canopenfd", "ProductName": "canopenfd demo node"})
    od.file_info["Description"] = f"canopenfd built-in demo object dictionary ({mode})"
    return od
