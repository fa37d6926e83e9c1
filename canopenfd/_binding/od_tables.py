"""Turn an `ObjectDictionary` into the C core's entry definitions.

The C object dictionary is filled once, before the local node boots, from
this flat list (`co_od_def_t`, one per VAR and per sub-entry). Values travel
as wire bytes, so the C side never interprets Python objects.
"""

from __future__ import annotations

from typing import List, Mapping, Optional, Tuple

from ..od import DataType, ObjectDictionary, ODVariable, OdValueError
from ..od.datatypes import Value, encode
from .core import CData, ffi, lib

_ACCESS = {
    "ro": lib.CO_ACCESS_RO, "wo": lib.CO_ACCESS_WO, "rw": lib.CO_ACCESS_RW,
    "rwr": lib.CO_ACCESS_RWR, "rww": lib.CO_ACCESS_RWW, "const": lib.CO_ACCESS_CONST,
}
_PDO_FLAGS = {
    None: 0, "tpdo": lib.CO_OD_MAP_TPDO, "rpdo": lib.CO_OD_MAP_RPDO,
    "both": lib.CO_OD_MAP_TPDO | lib.CO_OD_MAP_RPDO,
}
_MODE_FLAGS = {None: 0, "fd": lib.CO_OD_FD_ONLY, "classic": lib.CO_OD_CLASSIC_ONLY}


def _object_code(var: ODVariable) -> int:
    parent = var.parent
    if var.in_object:
        return int(getattr(parent, "object_type", lib.CO_OBJECT_RECORD))
    return int(var.object_type)


def _start_value(var: ODVariable, node_id: int) -> Tuple[bytes, bool]:
    """(bytes, node-id relative): a DCF/XDC configured value wins over the
    default; a relative value is passed as its offset for the C side to add
    the node-id at every reset."""
    base: Optional[Value] = var.value_base
    relative = var.value_relative_to_node_id
    if base is None:
        base, relative = var.default_base, var.relative_to_node_id
    if base is None:
        return var.default_bytes(node_id), False
    if not relative:
        return encode(var.data_type, base), False
    if var.data_type.is_integer:
        return encode(var.data_type, base), True
    if var.data_type.is_real and isinstance(base, (int, float)):   # added once, here
        return encode(var.data_type, base + node_id), False
    raise OdValueError(f"a value relative to the node-id needs a numeric type, "
                       f"not {var.data_type.name} (got {base!r})", f"{var.where} {var.qualname}")


def _size(var: ODVariable, start: bytes) -> int:
    if var.data_type == DataType.DOMAIN:
        return 0
    if var.size is not None:
        return var.size
    return max(var.storage_size, len(start))


def definitions(od: ObjectDictionary, node_id: int,
                overrides: Optional[Mapping[Tuple[int, int], Value]] = None
                ) -> Tuple[CData, int, List[CData]]:
    """(co_od_def_t array, count, keep-alive list) for `od` on node `node_id`.
    `overrides` maps (index, sub) to a start value replacing the default."""
    return entry_definitions(list(od.entries()), node_id, overrides)


def entry_definitions(entries: List[ODVariable], node_id: int,
                      overrides: Optional[Mapping[Tuple[int, int], Value]] = None
                      ) -> Tuple[CData, int, List[CData]]:
    """The same for a list of entries (one object added at run time)."""
    defs = ffi.new("co_od_def_t[]", max(len(entries), 1))
    keep: List[CData] = [defs]
    for i, var in enumerate(entries):
        d = defs[i]
        start, relative = _start_value(var, node_id)
        if overrides and (var.index, var.subindex) in overrides:
            start, relative = var.encode_raw(overrides[(var.index, var.subindex)]), False
        d.index, d.sub = var.index, var.subindex
        d.object_code = _object_code(var)
        d.type = int(var.data_type)
        d.access = _ACCESS[var.access_type]
        flags = _PDO_FLAGS[var.pdo_mappable] | _MODE_FLAGS[var.line_mode]
        if var.store:
            flags |= lib.CO_OD_STORE
        if relative:
            flags |= lib.CO_OD_NODEID_RELATIVE
        if var.low_limit is not None:
            flags |= lib.CO_OD_HAS_MIN
            ffi.memmove(d.min, encode(var.data_type, var.low_limit), var.size or 0)
        if var.high_limit is not None:
            flags |= lib.CO_OD_HAS_MAX
            ffi.memmove(d.max, encode(var.data_type, var.high_limit), var.size or 0)
        d.flags = flags
        d.size = _size(var, start)
        if var.data_type != DataType.DOMAIN and start:
            buf = ffi.new("uint8_t[]", start)
            keep.append(buf)
            d.default_value = buf
            d.default_length = len(start)
    return defs, len(entries), keep
