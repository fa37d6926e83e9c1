"""The object dictionary a local node serves, as Python reaches it.

    node["Producer heartbeat time"].raw = 100     # LocalValue: typed, checked
    node[0x1018][1].raw                           # LocalObject of an ARRAY / RECORD
    node.serve_domain(0x2100, 16 << 20)           # a DOMAIN kept in the stack's memory
    node.on_object_changed(print)                 # after network and PDO writes

The C runtime holds the values; reads and writes go through it, atomically
with respect to its thread. The OD is defined in C once, at boot.
"""

from __future__ import annotations

import copy
import logging
from typing import Callable, Dict, List, Mapping, Optional, Tuple, Union

from .._binding.constants import EventKind, OdOrigin
from .._binding.context import Deferred, LineContext
from .._binding.runtime import Event
from .._aio import LoopArg
from .._callbacks import CallbackList
from ..errors import AbortError, ConfigurationError
from ..od import (ODArray, ODRecord, ODVariable, ObjectDictionary, OdStateError, export_dcf,
                  export_eds)
from ..od.objects import ODObject
from ..od.datatypes import DataType, Value
from ..od.fileio import Source
from .views import LocalNodeView

log = logging.getLogger(__name__)

__all__ = ["ServedDictionary", "LocalValue", "LocalObject", "Key", "ODEntry"]

#: An entry by index, "index:sub", (index, sub), name or "Object.Sub".
Key = Union[int, str, Tuple[int, int]]
ODEntry = Union[ODVariable, ODRecord, ODArray]

#: DOMAINs with a max_length up to this many bytes get memory at boot by
#: themselves (a small domain is a value to keep, like a string); larger ones,
#: and those without a max_length, wait for serve_domain or the application.
AUTO_DOMAIN_LIMIT = 64 * 1024

#: The writers on_object_changed names (the runtime reports no others).
_ORIGIN_NAMES = {int(OdOrigin.NETWORK): "network", int(OdOrigin.PDO): "pdo"}


class ServedDictionary:
    """A local node's served OD: typed values, memory domains and change
    callbacks (events OD_CHANGED)."""

    def __init__(self, context: LineContext, node: LocalNodeView) -> None:
        self._context = context
        #: The node serving it (`node.od` is the dictionary).
        self.node = node
        self._domains: Dict[Tuple[int, int], int] = {}
        self._changed = CallbackList(f"{context.where} object changed")
        context.subscribe(EventKind.OD_CHANGED, self._event_changed)

    # ------------------------------------------------------------ entries and values
    @property
    def where(self) -> str:
        """"local node 1 on line 'vcan0'" as the node is numbered now, for messages."""
        return self._context.node_where

    def entry(self, key: Key) -> ODEntry:
        """The OD entry of a key; ConfigurationError without an OD, KeyError when absent."""
        od = self.node.od
        if od is None:
            raise ConfigurationError(f"{self.where} serves no object dictionary "
                                     "(create it with od=...)")
        return od[key]

    def value(self, key: Key) -> Union["LocalValue", "LocalObject"]:
        entry = self.entry(key)
        if isinstance(entry, ODVariable):
            return LocalValue(self, entry)
        return LocalObject(self, entry)

    def variable_value(self, index: int, sub: int) -> "LocalValue":
        """The LocalValue of entry index:sub."""
        entry = self.entry((index, sub))
        if not isinstance(entry, ODVariable):
            raise ConfigurationError(f"{self.where}: 0x{index:04X}:{sub:02X} is not a value")
        return LocalValue(self, entry)

    def read(self, index: int, sub: int, what: str) -> Tuple[int, bytes]:
        """(abort code or 0, the entry's bytes)."""
        context = self._context
        return context.runtime.od_read(context.index, index, sub, f"{what} on {context.where}")

    def write(self, index: int, sub: int, data: bytes, what: str) -> int:
        """0, or the abort code the node refused the value with."""
        context = self._context
        return context.runtime.od_write(context.index, index, sub, data,
                                        f"{what} on {context.where}")

    @property
    def has_1017(self) -> bool:
        od = self.node.od
        return od is not None and isinstance(od.get_variable(0x1017, 0), ODVariable)

    # ------------------------------------------------------------ boot
    def define(self, overrides: Mapping[Tuple[int, int], Value], store_path: Optional[str],
               spare: Tuple[int, int] = (0, 0)) -> None:
        """Define the OD in the runtime (before the node is created): `overrides`
        replace start values, `store_path` is the parameter file (or None),
        `spare` the (entries, bytes) kept for objects added at run time."""
        od = self._od()
        context = self._context
        context.runtime.od_reserve(context.index, spare[0], spare[1],
                                   f"object dictionary of {self.where}")
        context.runtime.od_define(context.index, od, self.node.node_id, overrides, store_path,
                                  f"object dictionary of {self.where}")

    def add_live(self, obj: ODObject) -> None:
        """Add a new object to the running node's C OD (all its entries or
        none); OdStateError naming the node, the entry and the reason."""
        entries = [obj] if isinstance(obj, ODVariable) else \
            [obj.subindices[sub] for sub in sorted(obj.subindices)]
        context = self._context
        what = f"add_object(0x{obj.index:04X}) to {self.where}"
        try:
            context.runtime.od_add(context.index, entries, self.node.node_id, what)
        except ConfigurationError as error:
            hint = " (reserve more with create_local_node(..., od_spare_objects=N, " \
                   "od_spare_bytes=M))" if "no room left" in str(error) else ""
            raise OdStateError(f"{error}{hint}") from None

    def serve_domain(self, key: Key, capacity: int) -> None:
        entry = self.entry(key)
        what = f"serve_domain({key!r}) on {self.where}"
        if not isinstance(entry, ODVariable) or entry.data_type != DataType.DOMAIN:
            raise ConfigurationError(f"{what}: {entry!r} is not a DOMAIN entry")
        if isinstance(capacity, bool) or not isinstance(capacity, int) or \
                not 0 < capacity < 1 << 32:
            raise ConfigurationError(f"{what}: capacity must be 1..2^32-1 bytes, got "
                                     f"{capacity!r}")
        where = (entry.index, entry.subindex)
        if where in self._domains:
            raise ConfigurationError(f"{what}: the domain already has memory")
        self._domains[where] = capacity
        if self.node.booted:
            self._give_domain(entry.index, entry.subindex, capacity)

    def give_domains(self) -> None:
        """At boot, once the OD is defined: the memory of every domain served
        so far, and of every DOMAIN of at most AUTO_DOMAIN_LIMIT bytes
        (max_length) not served explicitly. The others (unserved_domains) are
        logged: the network's reads and writes of them are refused until served."""
        for var in self._od().entries():
            where = (var.index, var.subindex)
            if var.data_type == DataType.DOMAIN and where not in self._domains and \
                    var.max_length and var.max_length <= AUTO_DOMAIN_LIMIT:
                self._domains[where] = var.max_length
        for (index, sub), capacity in self._domains.items():
            self._give_domain(index, sub, capacity)
        unserved = self.unserved_domains()
        if unserved:
            shown = ", ".join(f"{var.where} {var.qualname!r}" for var in unserved[:5])
            more = f" and {len(unserved) - 5} more" if len(unserved) > 5 else ""
            log.info("%s: DOMAIN %s%s without memory: network reads and writes are refused "
                     "until node.serve_domain(key, capacity) gives it memory", self.where,
                     shown, more)

    def unserved_domains(self) -> List[ODVariable]:
        """The DOMAIN entries with no memory in the stack (refused to the network)."""
        od = self.node.od
        if od is None:
            return []
        return [var for var in od.entries() if var.data_type == DataType.DOMAIN and
                (var.index, var.subindex) not in self._domains]

    def domain_hint(self, var: ODVariable) -> str:
        """A hint for refusals of a DOMAIN that has no memory, else ''."""
        if var.data_type != DataType.DOMAIN or (var.index, var.subindex) in self._domains:
            return ""
        return (f" (a DOMAIN without memory: call node.serve_domain(0x{var.index:04X}, "
                "capacity) to keep its data in the stack)")

    def _give_domain(self, index: int, sub: int, capacity: int) -> None:
        context = self._context
        context.runtime.od_domain(context.index, index, sub, capacity,
                                  f"memory domain 0x{index:04X}:{sub:02X} of {self.where}")

    # ------------------------------------------------------------ exports
    def _od(self) -> ObjectDictionary:
        od = self.node.od
        if od is None:
            raise ConfigurationError(f"{self.where} serves no object dictionary")
        return od

    def export_eds(self, dest: Optional[Source] = None) -> Optional[str]:
        return export_eds(self._od(), dest)

    def export_dcf(self, dest: Optional[Source] = None) -> Optional[str]:
        snapshot = copy.deepcopy(self._od())
        snapshot.node_id = self.node.node_id
        for variable in snapshot.entries():
            if variable.data_type == DataType.DOMAIN or not self.node.booted:
                continue
            variable.value = self.variable_value(variable.index, variable.subindex).raw
        return export_dcf(snapshot, dest)

    # ------------------------------------------------------------ changes
    def on_changed(self, callback: Callable[["LocalValue", str], None],
                   loop: LoopArg = None) -> Callable[["LocalValue", str], None]:
        return self._changed.add(callback, loop)

    def _event_changed(self, event: Event) -> Deferred:
        """CO_EV_OD_CHANGED: a = index << 8 | sub, b = co_od_origin_t."""
        od = self.node.od
        var = od.get_variable(event.a >> 8, event.a & 0xFF) if od is not None else None
        if var is None:
            return None
        value = LocalValue(self, var)
        name = _ORIGIN_NAMES.get(event.b, str(event.b))
        return lambda: self._changed.fire(value, name)


class LocalObject:
    """An ARRAY or RECORD of a local node's OD: index it by sub-index or name."""

    def __init__(self, served: ServedDictionary, obj: Union[ODRecord, ODArray]) -> None:
        self._served = served
        self.node = served.node
        self.object = obj

    def __repr__(self) -> str:
        return f"<LocalObject 0x{self.object.index:04X} {self.object.name!r} of {self.node!r}>"

    def __getitem__(self, sub: Union[int, str]) -> "LocalValue":
        return LocalValue(self._served, self.object[sub])

    @property
    def raw(self) -> Value:
        raise ConfigurationError(
            f"{self._served.where}: 0x{self.object.index:04X} {self.object.name!r} is an "
            f"{type(self.object).__name__[2:].upper()}; give a sub-index, e.g. "
            f"node[0x{self.object.index:04X}][1].raw")


class LocalValue:
    """One entry of a local node's object dictionary: `.raw` is the typed value
    (checked against type, length and limits), `.data` the wire bytes.

    Reads and writes are atomic with respect to the stack's thread. A refused
    write raises AbortError with the CiA abort code, or OdValueError when the
    value cannot even be encoded; either way nothing changes."""

    def __init__(self, served: ServedDictionary, variable: ODVariable) -> None:
        self._served = served
        self.node = served.node
        self.variable = variable

    def __repr__(self) -> str:
        return f"<LocalValue {self.variable.where} {self.variable.qualname!r} of {self.node!r}>"

    def _what(self, verb: str) -> str:
        return f"{verb} {self.variable.where} {self.variable.qualname!r}"

    def _refused(self, code: int, verb: str) -> AbortError:
        var = self.variable
        return AbortError(code, self.node.node_id, var.index, var.subindex,
                          self._what(verb) + self._served.domain_hint(var))

    @property
    def data(self) -> bytes:
        var = self.variable
        code, data = self._served.read(var.index, var.subindex, self._what("read"))
        if code:
            raise self._refused(code, "read")
        return data

    @data.setter
    def data(self, data: bytes) -> None:
        var = self.variable
        code = self._served.write(var.index, var.subindex, bytes(data), self._what("write"))
        if code:
            raise self._refused(code, "write")

    @property
    def raw(self) -> Value:
        return self.variable.decode_raw(self.data)

    @raw.setter
    def raw(self, value: Value) -> None:
        self.data = self.variable.encode_raw(value)
