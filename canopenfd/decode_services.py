"""Decoding of the process-data and error services for `canopenfd.decode`:
SYNC, TIME, EMCY (classic 8-byte and CANopen FD 20-byte) and PDOs, the
latter either by the CiA 301 default CAN-IDs ("TPDO1 node 5 01 02") or by
the mapping of an object dictionary (`PdoMap`: "TPDO1 node 5 Speed=1200,
Enabled=true"); `ServiceIds` holds the SYNC/TIME/EMCY CAN-IDs dictionaries
configure. Pure Python; each function returns the text after the
CAN-ID, '... malformed: why' for frames that break the format.

Wire formats follow the C core, the source of truth: `co_sync.c`,
`co_time.c` (6-byte TIME_OF_DAY), `co_emcy_codec.c` (EMCY layouts, the FD one
UNCONFIRMED, see docs/protocol-notes.md "EMCY") and `co_pdo_map.c` (mapping
entries index << 16 | sub << 8 | bits, bits packed LSB first; dummies
0x0002..0x0007)."""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional, Tuple

from .frame import fd_len_round
from .od.datatypes import DataType, TimeDifference, TimeOfDay, decode as decode_value
from .od.errors import OdValueError


def hex_bytes(data: bytes) -> str:
    return " ".join(f"{b:02X}" for b in data)


def _with_bytes(text: str, data: bytes) -> str:
    return f"{text} ({hex_bytes(data)})" if data else text


# ------------------------------------------------------------------ SYNC
SYNC_ID = 0x080
SYNC_COUNTER_MAX = 240   # 0x1019: 2..240; the counter runs 1..0x1019


def sync_text(data: bytes) -> str:
    """'SYNC', 'SYNC counter 7'; a length other than 0/1 or a counter outside
    1..240 is malformed."""
    if len(data) == 0:
        return "SYNC"
    if len(data) > 1:
        return _with_bytes(f"SYNC malformed: {len(data)} bytes, expected 0 or 1", data)
    counter = data[0]
    if not 1 <= counter <= SYNC_COUNTER_MAX:
        return f"SYNC counter {counter} malformed: counter outside 1..{SYNC_COUNTER_MAX}"
    return f"SYNC counter {counter}"


# ------------------------------------------------------------------ TIME
TIME_ID = 0x100
TIME_LEN = 6
_MS_MASK = 0x0FFFFFFF
_MS_PER_DAY = 86_400_000


def format_time_of_day(value: TimeOfDay) -> str:
    """'2024-01-01 12:34:56.789' (ISO 8601 date and time, the epoch taken as UTC)."""
    return value.to_datetime().strftime("%Y-%m-%d %H:%M:%S.%f")[:-3]


def time_text(data: bytes) -> str:
    """'TIME 2024-01-01 12:34:56.789': bytes 0..3 ms after midnight (28 bits, the
    upper 4 reserved), bytes 4..5 days since 1984-01-01 (as co_time.c). Reserved
    bits set, ms beyond a day and lengths other than 6 are malformed."""
    if len(data) != TIME_LEN:
        return _with_bytes(f"TIME malformed: {len(data)} bytes, expected {TIME_LEN}", data)
    word = int.from_bytes(data[0:4], "little")
    ms, days, reserved = word & _MS_MASK, data[4] | data[5] << 8, word >> 28
    if ms >= _MS_PER_DAY:
        return (f"TIME day {days} ms {ms} malformed: ms outside 0..{_MS_PER_DAY - 1}"
                + (f", reserved bits 0x{reserved:X}" if reserved else ""))
    text = f"TIME {format_time_of_day(TimeOfDay(ms, days))}"
    if reserved:
        return f"{text} malformed: reserved bits 31..28 = 0x{reserved:X}"
    return text


# ------------------------------------------------------------------ EMCY
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
class Emcy:
    """The fields of an EMCY (co_emcy_msg_t); the FD-only ones are None in a
    classic one."""

    code: int
    error_register: int
    msef: bytes
    logical_device: Optional[int] = None
    spec_number: Optional[int] = None
    status: Optional[int] = None
    time_stamp: Optional[int] = None


def parse_emcy(data: bytes, fd: bool) -> Optional[Emcy]:
    """The fields as co_emcy_decode_classic / co_emcy_decode_fd read them, None
    for a length they refuse (classic: exactly 8; fd: at least 20)."""
    if (len(data) < EMCY_FD_LEN) if fd else (len(data) != EMCY_CLASSIC_LEN):
        return None
    msg = Emcy(data[0] | data[1] << 8, data[2], bytes(data[3:8]))
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
        return _with_bytes(f"{head} malformed: {len(data)} bytes, expected {expected}", data)
    parts = [f"{head} {emcy_code_text(msg.code)}", error_register_text(msg.error_register)]
    if any(msg.msef):
        parts.append(f"msef {hex_bytes(msg.msef)}")
    if fd:
        parts.append(f"logical device {msg.logical_device}")
        parts.append(f"CiA {msg.spec_number}")
        parts.append(emcy_status_text(msg.status or 0))
        parts.append(f"time 0x{msg.time_stamp:012X}" if msg.time_stamp else "no time stamp")
    return ", ".join(parts)


# ------------------------------------------------------------------ PDO defaults
#: CiA 301 pre-defined connection set: (base, name) of the default PDO CAN-IDs.
DEFAULT_PDO_BASES = ((0x180, "TPDO1"), (0x200, "RPDO1"), (0x280, "TPDO2"), (0x300, "RPDO2"),
                     (0x380, "TPDO3"), (0x400, "RPDO3"), (0x480, "TPDO4"), (0x500, "RPDO4"))


def default_pdo(can_id: int) -> Optional[Tuple[str, int]]:
    """('TPDO1', node) for 0x181..0x1FF and the other default ranges, else None."""
    for base, name in DEFAULT_PDO_BASES:
        if base + 1 <= can_id <= base + 0x7F:
            return name, can_id - base
    return None


def default_pdo_text(can_id: int, data: bytes, rtr: bool = False) -> str:
    """'TPDO1 node 5 01 02 03', 'TPDO1 node 5 remote request', '' off the ranges."""
    found = default_pdo(can_id)
    if found is None:
        return ""
    head = f"{found[0]} node {found[1]}"
    if rtr:
        return f"{head} remote request"
    return f"{head} {hex_bytes(data)}" if data else head


# ------------------------------------------------------------------ PDO by an OD
_RPDO_COMM, _RPDO_MAP, _TPDO_COMM, _TPDO_MAP = 0x1400, 0x1600, 0x1800, 0x1A00
_PDO_COUNT = 512
_COB_INVALID = 1 << 31
_COB_EXT = 1 << 29
_COB_11_BITS = 0x7FF
_COB_29_BITS = 0x1FFFFFFF
#: Dummy mapping entries: index 0x0002..0x0007, sub 0, the type's size.
DUMMY_TYPES = {0x0002: DataType.INTEGER8, 0x0003: DataType.INTEGER16,
               0x0004: DataType.INTEGER32, 0x0005: DataType.UNSIGNED8,
               0x0006: DataType.UNSIGNED16, 0x0007: DataType.UNSIGNED32}


@dataclass
class MappedObject:
    """One mapping entry: where its bits are and what they hold."""

    index: int
    subindex: int
    bits: int
    offset: int                     # bit position in the PDO
    name: str                       # qualname, or '0xIIII:SS' when not in the OD
    data_type: Optional[DataType]   # None: shown as hex
    dummy: bool = False


@dataclass
class PdoDefinition:
    """A PDO as an object dictionary describes it."""

    name: str                       # 'TPDO1', 'RPDO12'
    node_id: int
    can_id: int
    extended: bool
    objects: List[MappedObject] = field(default_factory=list)
    problem: str = ""               # a mapping that cannot be right (shown with each frame)

    @property
    def bits(self) -> int:
        return sum(obj.bits for obj in self.objects)

    @property
    def size(self) -> int:
        """Bytes the mapping fills."""
        return (self.bits + 7) // 8


def _configured(var: Any, node_id: int) -> Any:
    """An entry's value on node node_id: the DCF/XDC value, else the default,
    $NODEID resolved."""
    if var is None:
        return None
    if var.value_base is not None:
        base, relative = var.value_base, var.value_relative_to_node_id
    else:
        base, relative = var.default_base, var.relative_to_node_id
    if base is None:
        return None
    return base + node_id if relative else base


def _int_entry(od: Any, index: int, sub: int, node_id: int) -> Optional[int]:
    value = _configured(od.get_variable(index, sub), node_id)
    return value if isinstance(value, int) and not isinstance(value, bool) else None


def _mapping(od: Any, map_index: int, node_id: int) -> Tuple[List[MappedObject], str]:
    count = _int_entry(od, map_index, 0, node_id) or 0
    if count == 0:
        return [], f"no mapping in 0x{map_index:04X}"
    objects: List[MappedObject] = []
    offset = 0
    for sub in range(1, min(count, 64) + 1):
        entry = _int_entry(od, map_index, sub, node_id)
        if not entry:
            return objects, f"mapping 0x{map_index:04X}:{sub:02X} missing or 0"
        index, subindex, bits = entry >> 16, entry >> 8 & 0xFF, entry & 0xFF
        if bits == 0:
            return objects, f"mapping 0x{map_index:04X}:{sub:02X} has length 0"
        if index in DUMMY_TYPES and subindex == 0:
            objects.append(MappedObject(index, 0, bits, offset, "dummy", None, dummy=True))
        else:
            var = od.get_variable(index, subindex)
            name = var.qualname if var is not None else f"0x{index:04X}:{subindex:02X}"
            objects.append(MappedObject(index, subindex, bits, offset, name,
                                        var.data_type if var is not None else None))
        offset += bits
    return objects, ""


class PdoMap:
    """The PDOs object dictionaries describe, by CAN-ID: what `Decoder` uses to
    show a PDO's mapped values. add_od() once per node."""

    def __init__(self) -> None:
        self._by_id: Dict[Tuple[int, bool], List[PdoDefinition]] = {}

    def add_od(self, od: Any, node_id: Optional[int] = None) -> List[PdoDefinition]:
        """Read the PDOs (0x1400.. RPDO, 0x1800.. TPDO communication objects and
        their mappings 0x1600.. / 0x1A00..) of `od` on node node_id (default:
        od.node_id; ValueError when neither is known). PDOs whose COB-ID is
        invalid (bit 31) are left out. The PDOs found are returned."""
        node = node_id if node_id is not None else od.node_id
        if node is None or isinstance(node, bool) or not 1 <= node <= 127:
            raise ValueError(f"a node-id 1..127 is needed for the PDOs of {od.source or 'the OD'}, "
                             f"got {node!r}")
        found: List[PdoDefinition] = []
        for kind, comm, mapping in (("TPDO", _TPDO_COMM, _TPDO_MAP),
                                    ("RPDO", _RPDO_COMM, _RPDO_MAP)):
            for n in range(_PDO_COUNT):
                cob = _int_entry(od, comm + n, 1, node)
                if cob is None or cob & _COB_INVALID:
                    continue
                extended = bool(cob & _COB_EXT)
                can_id = cob & (_COB_29_BITS if extended else _COB_11_BITS)
                objects, problem = _mapping(od, mapping + n, node)
                pdo = PdoDefinition(f"{kind}{n + 1}", node, can_id, extended, objects, problem)
                self._by_id.setdefault((can_id, extended), []).append(pdo)
                found.append(pdo)
        return found

    def lookup(self, can_id: int, extended: bool = False) -> Optional[PdoDefinition]:
        """The PDO on that CAN-ID: a TPDO before an RPDO (the producer's mapping
        tells what is sent), then in the order the dictionaries were added."""
        pdos = self._by_id.get((can_id, extended))
        if not pdos:
            return None
        return next((p for p in pdos if p.name.startswith("TPDO")), pdos[0])

    def __len__(self) -> int:
        return sum(len(pdos) for pdos in self._by_id.values())


def _take_bits(data: bytes, offset: int, bits: int) -> bytes:
    """bits bits of data from bit offset (LSB first, as co_pdo_map's copy_bits),
    as (bits + 7) // 8 bytes."""
    number = int.from_bytes(data, "little") >> offset & ((1 << bits) - 1)
    return number.to_bytes((bits + 7) // 8, "little")


def _short_real32(value: float) -> str:
    packed = struct.pack("<f", value)
    for digits in range(1, 10):
        text = f"{value:.{digits}g}"
        if struct.pack("<f", float(text)) == packed:
            return text
    return repr(value)


def format_pdo_value(dtype: DataType, value: Any) -> str:
    """A mapped value: integers in decimal, booleans true/false, strings quoted,
    bytes in hex, times ISO."""
    if dtype == DataType.BOOLEAN:
        return "true" if value else "false"
    if dtype == DataType.REAL32:
        return _short_real32(value)
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, TimeOfDay):
        return format_time_of_day(value)
    if isinstance(value, TimeDifference):
        return f"{value.days}d {value.ms}ms"
    if isinstance(value, bytes):
        return hex_bytes(value) if value else "(empty)"
    if isinstance(value, str):
        return repr(value)
    return str(value)


def _object_value(obj: MappedObject, raw: bytes) -> str:
    dtype = obj.data_type
    if dtype is None:
        return hex_bytes(raw)
    size = dtype.size
    if size is not None:
        if obj.bits > 8 * size:
            return f"{hex_bytes(raw)}?"          # more bits than the type: no value
        raw = raw + bytes(size - len(raw))      # a partial mapping: the rest reads 0
    try:
        return format_pdo_value(dtype, decode_value(dtype, raw))
    except OdValueError:
        return f"{hex_bytes(raw)}?"


def pdo_text(pdo: PdoDefinition, data: bytes, fd: bool, rtr: bool = False) -> str:
    """'TPDO1 node 5 Speed=1200, Enabled=true' by the mapping (dummies left
    out); a frame shorter than the mapping, or longer (classic; fd: longer than
    the mapping rounded up to an FD length, the padding), is malformed."""
    head = f"{pdo.name} node {pdo.node_id}"
    if rtr:
        return f"{head} remote request"
    if pdo.problem:
        return f"{head} {hex_bytes(data)} ({pdo.problem})" if data else f"{head} ({pdo.problem})"
    need = pdo.size
    if len(data) < need:
        return _with_bytes(f"{head} malformed: {len(data)} bytes, mapping needs {need}", data)
    values = [f"{obj.name}={_object_value(obj, _take_bits(data, obj.offset, obj.bits))}"
              for obj in pdo.objects if not obj.dummy]
    text = f"{head} {', '.join(values)}" if values else head
    problems = []
    allowed = fd_len_round(need) if fd and need <= 64 else need
    if len(data) > allowed:
        problems.append(f"{len(data)} bytes, mapping has {need}")
    if fd and any(obj.bits % 8 for obj in pdo.objects):
        problems.append("mapping not byte-wise (fd)")
    return f"{text} malformed: {', '.join(problems)}" if problems else text


# ------------------------------------------------------------------ ids from an OD

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
            cob = _int_entry(od, index, 0, node_id)
            if cob is None or (service == "EMCY" and cob & _COB_INVALID):
                continue
            extended = service == "EMCY" and bool(cob & _COB_EXT)
            can_id = cob & (_COB_29_BITS if extended else _COB_11_BITS)
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
