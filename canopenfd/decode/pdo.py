"""PDO frames, by the CiA 301 default CAN-IDs ("TPDO1 node 5 01 02") or by
the mapping of an object dictionary (`PdoMap`: "TPDO1 node 5 Speed=1200,
Enabled=true"). Mapping entries as csrc/core/co_pdo_map.c: index << 16 |
sub << 8 | bits, bits packed LSB first; dummies 0x0002..0x0007."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional, Tuple

from ..frame import fd_len_round
from ..od.datatypes import (DataType, TimeDifference, TimeOfDay, decode as decode_value,
                             real32_text)
from ..od.errors import OdValueError
from .od_values import COB_11_BITS, COB_29_BITS, COB_EXT, COB_INVALID, configured_int
from .raw import hex_bytes, with_bytes
from .time import format_time_of_day

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
#: Mapping sub 0 values that make a PDO an MPDO (CiA 301).
_MPDO_MARKERS = {0xFF: "DAM", 0xFE: "SAM"}
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
    mpdo: str = ""                  # 'DAM' / 'SAM': mapping sub 0 = 0xFF / 0xFE

    @property
    def bits(self) -> int:
        return sum(obj.bits for obj in self.objects)

    @property
    def size(self) -> int:
        """Bytes the mapping fills."""
        return (self.bits + 7) // 8

def _mapping(od: Any, map_index: int, node_id: int) -> Tuple[List[MappedObject], str]:
    count = configured_int(od, map_index, 0, node_id) or 0
    if count == 0:
        return [], f"no mapping in 0x{map_index:04X}"
    objects: List[MappedObject] = []
    offset = 0
    for sub in range(1, min(count, 64) + 1):
        entry = configured_int(od, map_index, sub, node_id)
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
        self._ods: Dict[int, Any] = {}      # by node-id: names MPDOs' objects

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
        self._ods[node] = od
        for kind, comm, mapping in (("TPDO", _TPDO_COMM, _TPDO_MAP),
                                    ("RPDO", _RPDO_COMM, _RPDO_MAP)):
            for n in range(_PDO_COUNT):
                cob = configured_int(od, comm + n, 1, node)
                if cob is None or cob & COB_INVALID:
                    continue
                extended = bool(cob & COB_EXT)
                can_id = cob & (COB_29_BITS if extended else COB_11_BITS)
                mpdo = _MPDO_MARKERS.get(configured_int(od, mapping + n, 0, node) or 0, "")
                objects, problem = _mapping(od, mapping + n, node) if not mpdo else ([], "")
                pdo = PdoDefinition(f"{kind}{n + 1}", node, can_id, extended, objects, problem,
                                    mpdo)
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

    def variable(self, node_id: int, index: int, sub: int) -> Optional[Any]:
        """The OD variable index:sub of node node_id, when its OD was added."""
        od = self._ods.get(node_id)
        return od.get_variable(index, sub) if od is not None else None

    def __len__(self) -> int:
        return sum(len(pdos) for pdos in self._by_id.values())


def _take_bits(data: bytes, offset: int, bits: int) -> bytes:
    """bits bits of data from bit offset (LSB first, as co_pdo_map's copy_bits),
    as (bits + 7) // 8 bytes."""
    number = int.from_bytes(data, "little") >> offset & ((1 << bits) - 1)
    return number.to_bytes((bits + 7) // 8, "little")


def format_pdo_value(dtype: DataType, value: Any) -> str:
    """A mapped value: integers in decimal, booleans true/false, strings quoted,
    bytes in hex, times ISO."""
    if dtype == DataType.BOOLEAN:
        return "true" if value else "false"
    if dtype == DataType.REAL32:
        return real32_text(value)
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
        return with_bytes(f"{head} malformed: {len(data)} bytes, mapping needs {need}", data)
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

