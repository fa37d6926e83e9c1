"""The object dictionary of a device configured by a setup file alone: the
communication objects the stack needs, the PDOs of [RPDO]/[TPDO], the
constant entries of [COD] and the process-image entries of [RWOD] (their
defaults taken from [PIMG], so a reset reloads the initial image)."""

from __future__ import annotations

from typing import Dict, List, Optional, Tuple, Union

from ..od import DataType, ODArray, ODRecord, ODVariable, ObjectDictionary
from .setup_file import ConstEntry, ImageEntry, PdoParams, SetupFile, SetupFileError

U8, U16, U32 = DataType.UNSIGNED8, DataType.UNSIGNED16, DataType.UNSIGNED32
_UNSIGNED = {1: U8, 2: U16, 3: DataType.UNSIGNED24, 4: U32, 5: DataType.UNSIGNED40,
             6: DataType.UNSIGNED48, 7: DataType.UNSIGNED56, 8: DataType.UNSIGNED64}
# objects this builder makes from [NODE]/[RPDO]/[TPDO]; a [COD]/[RWOD] entry may not name them
_BUILT = {0x1001, 0x1005, 0x1006, 0x1017, 0x1019}
_PDO_RANGES = ((0x1400, 0x15FF), (0x1600, 0x17FF), (0x1800, 0x19FF), (0x1A00, 0x1BFF))


def _is_built(index: int) -> bool:
    return index in _BUILT or any(low <= index <= high for low, high in _PDO_RANGES)


def _access(entry: ImageEntry) -> str:
    if entry.readable and entry.writable:
        if not entry.mappable:
            return "rw"
        return "rww" if entry.rpdo_only else "rwr"
    return "ro" if entry.readable else "wo"


def _variables(setup: SetupFile, image: bytes) -> Dict[int, List[ODVariable]]:
    """[COD] and [RWOD] entries grouped by index."""
    by_index: Dict[int, List[ODVariable]] = {}
    items: List[Union[ConstEntry, ImageEntry]] = [*setup.cod, *setup.rwod]
    for item in items:
        where = f"{setup.path}:{item.line}"
        if _is_built(item.index):
            raise SetupFileError(f"{where}: {item.index:04X}:{item.sub:02X} is made from "
                                 "[NODE]/[RPDO]/[TPDO]; it cannot be given here")
        if isinstance(item, ConstEntry):
            var = ODVariable(f"Constant {item.index:04X}:{item.sub:02X}", item.index, item.sub,
                             _UNSIGNED[len(item.data)], "const",
                             int.from_bytes(item.data, "little"))
        else:
            value = int.from_bytes(image[item.offset:item.offset + item.length], "little")
            var = ODVariable(f"Image {item.offset}..{item.offset + item.length - 1}",
                             item.index, item.sub, _UNSIGNED[item.length], _access(item),
                             value, pdo_mapping=item.mappable)
        by_index.setdefault(item.index, []).append(var)
    return by_index


def _add_objects(od: ObjectDictionary, setup: SetupFile, image: bytes) -> None:
    for index, variables in sorted(_variables(setup, image).items()):
        if len(variables) == 1 and variables[0].subindex == 0:
            od.add_object(variables[0])
            continue
        record = ODRecord(f"Object {index:04X}", index)
        subs = {var.subindex: var for var in variables}
        if 0 not in subs:    # a RECORD needs its highest sub-index
            subs[0] = ODVariable("Highest sub-index supported", index, 0, U8, "const",
                                 max(subs))
        elif subs[0].data_type != U8:
            raise SetupFileError(f"{setup.path}: {index:04X}:00 of a record must be one byte")
        for sub in sorted(subs):
            record.add_member(subs[sub])
        od.add_object(record)


def _pdo(od: ObjectDictionary, setup: SetupFile, kind: str, pdo: PdoParams) -> None:
    comm_base, map_base, id_base = ((0x1400, 0x1600, 0x200) if kind == "RPDO"
                                    else (0x1800, 0x1A00, 0x180))
    comm, mapping = comm_base + pdo.number - 1, map_base + pdo.number - 1
    record = ODRecord(f"{kind} communication parameter {pdo.number}", comm)
    fields: List[Tuple[int, str, DataType, int]] = [
        (2, "Transmission type", U8, pdo.transmission_type)]
    if kind == "TPDO":
        fields += [(3, "Inhibit time", U16, pdo.inhibit_100us), (5, "Event timer", U16,
                                                                 pdo.event_ms),
                   (6, "SYNC start value", U8, 0)]
    record.add_member(ODVariable("Highest sub-index supported", comm, 0, U8, "ro",
                                 fields[-1][0]))
    cob = ODVariable("COB-ID used by PDO", comm, 1, U32, "rw", 0)
    if pdo.cob_id == 0:
        cob.set_default(id_base + 0x100 * (pdo.number - 1), relative_to_node_id=True)
    else:
        cob.default = (pdo.cob_id & 0x7FF) | (0x80000000 if pdo.cob_id & 0x8000 else 0)
    record.add_member(cob)
    for sub, name, dtype, value in fields:
        record.add_member(ODVariable(name, comm, sub, dtype, "rw", value))
    od.add_object(record)
    array = ODArray(f"{kind} mapping parameter {pdo.number}", mapping)
    array.add_member(ODVariable("Number of mapped objects", mapping, 0, U8, "rw",
                                len(pdo.entries)))
    for sub in range(1, max(8, len(pdo.entries)) + 1):
        value = 0
        if sub <= len(pdo.entries):
            entry = setup.rwod[pdo.entries[sub - 1]]
            value = entry.index << 16 | entry.sub << 8 | entry.length * 8
        array.add_member(ODVariable(f"Mapped object {sub}", mapping, sub, U32, "rw", value))
    od.add_object(array)


def build_od(setup: SetupFile, image: Optional[bytes] = None) -> ObjectDictionary:
    """The ObjectDictionary a setup file describes (node-id: [NODE]'s default);
    the [RWOD] entries' defaults come from `image` (default: [PIMG])."""
    node = setup.node
    assert node is not None
    od = ObjectDictionary(mode=setup.mode, node_id=node.node_id)
    given = {entry.index for entry in setup.cod} | {entry.index for entry in setup.rwod}
    if 0x1000 not in given:
        od.add_object(ODVariable("Device type", 0x1000, 0, U32, "ro", 0))
    od.add_object(ODVariable("Error register", 0x1001, 0, U8, "ro", 0))
    od.add_object(ODVariable("COB-ID SYNC message", 0x1005, 0, U32, "rw", 0x80))
    od.add_object(ODVariable("Communication cycle period", 0x1006, 0, U32, "rw", 0))
    od.add_object(ODVariable("Producer heartbeat time", 0x1017, 0, U16, "rw", node.heartbeat_ms))
    od.add_object(ODVariable("Synchronous counter overflow value", 0x1019, 0, U8, "rw", 0))
    if 0x1018 not in given:
        identity = ODRecord("Identity object", 0x1018)
        identity.add_member(ODVariable("Highest sub-index supported", 0x1018, 0, U8, "ro", 1))
        identity.add_member(ODVariable("Vendor-ID", 0x1018, 1, U32, "ro", 0))
        od.add_object(identity)
    _add_objects(od, setup, setup.image if image is None else image)
    for kind, pdos in (("RPDO", setup.rpdos), ("TPDO", setup.tpdos)):
        for pdo in pdos:
            _pdo(od, setup, kind, pdo)
    od.device_info.update({"VendorName": "canopenfd", "ProductName": "process image device"})
    od.file_info["Description"] = f"built from setup file {setup.path}"
    return od
