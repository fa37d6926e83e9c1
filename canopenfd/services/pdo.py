"""PDO configuration (CiA 301 / CiA 1301) with python-canopen's names.

    drive = line.add_node(5, od="drive.eds")
    tpdo = drive.tpdo[1]                     # TPDO 1: 0x1800 / 0x1A00
    tpdo.read()                              # what the node has now
    tpdo.clear()
    tpdo.add_variable("Statusword")          # by name ...
    tpdo.add_variable(0x6064, 0)             # ... or index, sub (length from the OD)
    tpdo.trans_type = 255
    tpdo.event_timer = 10                    # ms
    tpdo.enabled = True
    tpdo.save()                              # the CiA 301 procedure, see PdoMap.save
    me.rpdo[1].add_variable(0x0005, 0, 8)    # an RPDO may skip bytes with a dummy entry

`node.tpdo` / `node.rpdo` exist on remote nodes (read and written through
USDO on fd lines, SDO on classic lines) and on the local node (its own
object dictionary). The PDO numbers are those of the node's OD: TPDO n is
0x1800 + n - 1 (communication) / 0x1A00 + n - 1 (mapping), RPDO n 0x1400 /
0x1600 + n - 1, n = 1..512.

Checked before anything is sent (ConfigurationError naming node, PDO, field,
expected and given value): transmission types 0, 1..240, 254, 255 and 252/253
(classic lines, TPDOs only); inhibit time and event timer 0..65535; SYNC start
value 0..240; mapped objects exist, are mappable in the PDO's direction and
hold the mapped length; dummy entries 0x0002..0x0007 in RPDOs only; byte-wise
lengths on fd lines; the total within 8 bytes (classic) or 64 bytes (fd) and
the entries within the mapping object's sub-entries; a changed value for an
entry the OD marks read-only (a fixed parameter is only skipped while it
still has the value read). The node checks again
(CiA 301 abort codes); a refusal raises the transfer's abort exception
(SdoAbortError / UsdoAbortError, AbortError on the local node) whose message
names the PDO and the step, also as `.pdo` and `.step`.

Process data on the local node (the runtime sends and receives the PDOs
itself; Python hears only what it asks for):

    me.rpdo[1].add_callback(lambda pdo: print(pdo["Setpoint"].raw))
    me.rpdo[1].wait_for_reception(timeout=1)   # returns the reception time
    me[0x2200][1].raw = 7; me.tpdo[1].transmit()  # an event TPDO goes out now
    me.trigger_pdo(0x2006)                      # every event TPDO mapping 0x2006
    me.tpdo[2].send_dam(6, 0x2300, 1, bytes(4))  # MPDO (mapping sub 0 = 0xFF)
    me.tpdo[3].send_sam(0x2300, 1)              # MPDO (sub 0 = 0xFE), scanner list 0x1FA0

Each reception of a listened RPDO sets its `data` (the mapped values, laid
out as in the PDO) before the callbacks run, so `pdo["name"].raw` and
`[v.raw for v in pdo]` give the received values; `PdoMap.data` and
`PdoVariable.raw` decode any PDO's bytes.

Process data of other nodes (heard by CAN-ID, co_rt_pdo_watch): a remote
node's TPDOs (what it sends) and RPDOs (what others send it):

    drive.tpdo.read()                         # COB-IDs and mappings from the node
    drive.tpdo[1].add_callback(lambda pdo: print(pdo["Statusword"].raw))
    drive.rpdo[1].wait_for_reception(timeout=1)

Without read() (or a `cob_id` set here) the OD's COB-ID is used, with its
mapping when none was made here.

A master drives a remote node's RPDO (the runtime produces the frame the
device consumes, on the COB-ID and with the mapping read() from the node or
read(from_od=True) from its EDS; no Python per frame):

    drive.rpdo.read()
    drive.rpdo[1]["Controlword"].raw = 15     # checked, written into the runtime's frame
    drive.rpdo[1].transmit()                  # once
    drive.rpdo[1].start(0.01)                 # every 10 ms until stop()
    drive.rpdo[1].start_sync()                # or after SYNCs (types 0..240)
    drive.rpdo[1].stop()
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
import time
from typing import (Callable, Dict, Iterator, List, NamedTuple, Optional, Protocol, Tuple, Union,
                    overload)

from .._binding.constants import EventKind
from .._binding.context import Deferred, LineContext
from .._binding.runtime import Event
from .._aio import LoopArg
from .._callbacks import CallbackList, Until
from ..errors import AbortError, ConfigurationError
from ..frame import Frame
from ..od import ODArray, ODRecord, ODVariable, ObjectDictionary
from ..od.errors import OdValueError
from ..od.datatypes import DataType, Value, decode
from . import pdo_steps
from .served_od import LocalValue, ServedDictionary
from .views import LocalNodeView, NodeView

__all__ = ["PdoMaps", "PdoMap", "PdoVariable", "PdoAccess", "LocalPdoAccess",
           "RemotePdoAccess", "PDO_NOT_VALID", "RTR_NOT_ALLOWED", "FRAME_29BIT", "DUMMY_BITS",
           "MPDO_MARKERS"]

log = logging.getLogger(__name__)

#: COB-ID flags (sub 1 of the communication object).
PDO_NOT_VALID = 1 << 31
RTR_NOT_ALLOWED = 1 << 30
FRAME_29BIT = 1 << 29

#: Dummy mapping entries (RPDOs only): data type index -> length in bits.
DUMMY_BITS = {0x0002: 8, 0x0003: 16, 0x0004: 32, 0x0005: 8, 0x0006: 16, 0x0007: 32}

#: How add_variable names an entry: index, name, (index, sub) or 'INDEX:SUB'...
EntryKey = Union[int, str, Tuple[int, int]]
#: ... and the sub-index (number or name) when index is an object.
SubKey = Union[int, str, None]

_MAX_ENTRIES = 64
#: Mapping sub 0 values that make a PDO a multiplexed PDO (CiA 301).
MPDO_MARKERS = {"SAM": 0xFE, "DAM": 0xFF}
_BITS = {"classic": 64, "fd": 512}
_COMM = {"rpdo": 0x1400, "tpdo": 0x1800}
_MAP = {"rpdo": 0x1600, "tpdo": 0x1A00}
_PREDEFINED = {"rpdo": 0x200, "tpdo": 0x180}
# Communication sub-entries: sub -> (attribute, what, size in bytes).
_COMM_SUBS = {1: ("cob_id", "COB-ID", 4), 2: ("trans_type", "transmission type", 1),
              3: ("inhibit_time", "inhibit time", 2), 5: ("event_timer", "event timer", 2),
              6: ("sync_start_value", "SYNC start value", 1)}
# Aborts that mean "this optional sub-entry is not there" when reading.
_ABSENT = (0x06090011, 0x06020000)


# ------------------------------------------------------------------ node access
class PdoAccess(Protocol):
    """How one node's PDO objects are read and written."""

    #: A remote node (through USDO / SDO), else the local node (its own OD).
    remote: bool

    @property
    def booted(self) -> bool:
        """The node can be read and written (a remote node: always, as far as we know)."""
        ...

    def read(self, index: int, sub: int) -> bytes:
        ...

    def write(self, index: int, sub: int, data: bytes) -> None:
        ...


class RemoteTransfers(Protocol):
    """A remote node's USDO / SDO access (`remote.usdo`, `remote.sdo`)."""

    def upload(self, key: Tuple[int, int]) -> bytes:
        ...

    def download(self, key: Tuple[int, int], data: bytes) -> None:
        ...

    async def aupload(self, key: Tuple[int, int]) -> bytes:
        ...

    async def adownload(self, key: Tuple[int, int], data: bytes) -> None:
        ...


class RemotePdoAccess:
    """A remote node's PDO objects, through its transfer API (USDO on fd
    lines, SDO on classic lines)."""

    remote = True
    booted = True

    def __init__(self, transfers: RemoteTransfers) -> None:
        self._transfers = transfers

    def read(self, index: int, sub: int) -> bytes:
        return self._transfers.upload((index, sub))

    def write(self, index: int, sub: int, data: bytes) -> None:
        self._transfers.download((index, sub), data)

    async def aread(self, index: int, sub: int) -> bytes:
        return await self._transfers.aupload((index, sub))

    async def awrite(self, index: int, sub: int, data: bytes) -> None:
        await self._transfers.adownload((index, sub), data)


class LocalPdoAccess:
    """The local node's PDO objects, in the OD it serves (once booted)."""

    remote = False

    def __init__(self, node: LocalNodeView, served: ServedDictionary) -> None:
        self._node = node
        self._served = served

    @property
    def booted(self) -> bool:
        return self._node.booted

    def _value(self, index: int, sub: int) -> LocalValue:
        if not self._node.booted:
            raise ConfigurationError(f"{_where_of(self._node, False)} is not booted yet: its "
                                     "PDO objects cannot be read or written")
        return self._served.variable_value(index, sub)

    def read(self, index: int, sub: int) -> bytes:
        return self._value(index, sub).data

    def write(self, index: int, sub: int, data: bytes) -> None:
        self._value(index, sub).data = data


def _where_of(node: NodeView, remote: bool) -> str:
    return f"{'node' if remote else 'local node'} {node.node_id}"


class _Wiring(NamedTuple):
    """What the PdoMaps of a node hand each of its PdoMaps."""

    context: LineContext
    access: PdoAccess
    # local RPDOs: PDO number -> the map's reception handler
    receivers: Dict[int, Callable[[bytes, int], Deferred]]
    # each map's "stop hearing your CAN-ID" (the node is removed)
    stops: List[Callable[[str], None]]


def _add_context(exc: AbortError, pdo: str, step: str) -> None:
    """Name the PDO and the step in an abort (same exception, same code)."""
    exc.pdo = pdo            # type: ignore[attr-defined]
    exc.step = step          # type: ignore[attr-defined]
    text = exc.args[0] if exc.args else str(exc)
    exc.args = (f"{pdo}, {step}: {text}",) + tuple(exc.args[1:])


# ------------------------------------------------------------------ collection
class PdoMaps(Mapping[int, "PdoMap"]):
    """The TPDOs or RPDOs of one node (`node.tpdo`, `node.rpdo`), by PDO
    number 1..512 (`node.tpdo[1]`), or by the index of the communication or
    mapping object (`node.tpdo[0x1A00]`). Only the PDOs the node's OD has
    (a communication object with sub 1) are there."""

    def __init__(self, context: LineContext, node: NodeView, kind: str, od: ObjectDictionary,
                 access: PdoAccess) -> None:
        if kind not in _COMM:
            raise ConfigurationError(f"PDO kind must be 'tpdo' or 'rpdo', got {kind!r}")
        self.node = node
        self.kind = kind
        self.od = od
        self._where = _where_of(node, access.remote)
        self._wiring = _Wiring(context, access, {}, [])
        #: {number: PdoMap} (python-canopen's name)
        self.maps: Dict[int, PdoMap] = {}
        for number in range(1, 513):
            if od.get_variable(_COMM[kind] + number - 1, 1) is not None:
                self.maps[number] = PdoMap(self, number, self._wiring)
        if kind == "rpdo" and not access.remote:
            context.subscribe(EventKind.PDO, self._event_received)

    def __repr__(self) -> str:
        return f"<PdoMaps {self.kind.upper()} {list(self.maps)} of {self._where}>"

    @property
    def map(self) -> "PdoMaps":
        """python-canopen's `node.tpdo.map[1]`: this collection."""
        return self

    def _number(self, key: int) -> int:
        comm, mapping = _COMM[self.kind], _MAP[self.kind]
        if comm <= key < comm + 512:
            return key - comm + 1
        if mapping <= key < mapping + 512:
            return key - mapping + 1
        return key

    @overload
    def __getitem__(self, key: int) -> "PdoMap":
        ...

    @overload
    def __getitem__(self, key: str) -> "PdoVariable":
        ...

    def __getitem__(self, key: Union[int, str]) -> Union["PdoMap", "PdoVariable"]:
        """The PdoMap of a number or index; for a name, the first mapped
        PdoVariable of that name in any of these PDOs (python-canopen)."""
        if isinstance(key, int) and not isinstance(key, bool):
            number = self._number(key)
            if number in self.maps:
                return self.maps[number]
            have = ", ".join(str(n) for n in self.maps) or "none"
            raise KeyError(f"{self._where} has no {self.kind.upper()} {key} in its "
                           f"object dictionary (it has: {have})")
        if isinstance(key, str):
            for pdo_map in self.maps.values():
                for var in pdo_map.map:
                    if key in (var.name, getattr(var.od, "name", None)):
                        return var
        raise KeyError(f"{self._where}: no {self.kind.upper()} {key!r}")

    def __iter__(self) -> Iterator[int]:
        return iter(self.maps)

    def __len__(self) -> int:
        return len(self.maps)

    def read(self, from_od: bool = False) -> None:
        """Read every PDO's configuration (see PdoMap.read)."""
        for pdo_map in self.maps.values():
            pdo_map.read(from_od=from_od)

    def save(self) -> None:
        """Save every PDO whose COB-ID is known (read or set), in number order."""
        for pdo_map in self.maps.values():
            if pdo_map.cob_id is not None:
                pdo_map.save()

    async def aread(self, from_od: bool = False) -> None:
        for pdo_map in self.maps.values():
            await pdo_map.aread(from_od=from_od)

    async def asave(self) -> None:
        for pdo_map in self.maps.values():
            if pdo_map.cob_id is not None:
                await pdo_map.asave()

    def stop_watching(self, what: str) -> None:
        """Stop hearing this node's PDOs on their CAN-IDs (the line calls it
        when the node is removed)."""
        for stop in self._wiring.stops:
            stop(what)

    def stop_producing(self, what: str) -> None:
        """Stop and free the runtime producers of these remote RPDOs (the node
        gets another object dictionary, hence other PdoMaps)."""
        for pdo_map in self.maps.values():
            pdo_map.release_producer(what)

    def _event_received(self, event: Event) -> Deferred:
        """CO_EV_PDO (the local node's RPDOs): a = the PDO number, data = its values."""
        receive = self._wiring.receivers.get(event.a)
        return receive(event.data, event.coalesced) if receive is not None else None


# ------------------------------------------------------------------ one PDO
class PdoVariable:
    """One mapping entry of a PDO: an OD entry (`od`), a dummy (RPDOs) or an
    entry the node's OD does not describe (`od` None). `offset` and `length`
    are in bits; `raw` decodes the entry from the PDO's `data`."""

    def __init__(self, index: int, subindex: int, length: int,
                 od: Optional[ODVariable] = None) -> None:
        self.od = od
        self.index = index
        self.subindex = subindex
        #: mapped length in bits
        self.length = length
        #: first bit in the PDO (bit 0 = least significant bit of byte 0)
        self.offset = 0
        self.pdo_parent: Optional[PdoMap] = None

    @property
    def is_dummy(self) -> bool:
        return self.od is None and self.index in DUMMY_BITS and self.subindex == 0

    @property
    def name(self) -> str:
        if self.od is not None:
            return self.od.qualname
        if self.is_dummy:
            return f"Dummy {DataType(self.index).name}"
        return f"0x{self.index:04X}:{self.subindex:02X}"

    @property
    def mapping_value(self) -> int:
        """The mapping entry as written to the node: index << 16 | sub << 8 | bits."""
        return self.index << 16 | self.subindex << 8 | self.length

    def __repr__(self) -> str:
        return (f"<PdoVariable {self.name!r} 0x{self.index:04X}:{self.subindex:02X} "
                f"bits {self.offset}..{self.offset + self.length - 1}>")

    def get_data(self) -> bytes:
        """The entry's bytes from the PDO's `data`: the mapped bits, the rest
        of the object 0 (as a receiving node fills it); for a string the
        mapped bytes."""
        data = self.pdo_parent.data if self.pdo_parent is not None else b""
        needed = (self.offset + self.length + 7) // 8
        if len(data) < needed:
            raise ConfigurationError(f"{self.name}: the PDO data hold {len(data)} bytes, "
                                     f"the entry needs {needed}")
        whole = int.from_bytes(bytes(data[:needed]), "little")
        value = (whole >> self.offset) & ((1 << self.length) - 1)
        size = self.od.size if self.od is not None else None
        if size is None:
            size = (self.length + 7) // 8
        return value.to_bytes(size, "little")

    @property
    def raw(self) -> Value:
        """The typed value in the PDO's `data` (bytes when the type is unknown).
        Settable on a remote node's RPDO (the master fills the frame it sends
        to the device) and on the local node's PDOs (writes its OD entry)."""
        data = self.get_data()
        if self.od is None:
            return int.from_bytes(data, "little") if self.is_dummy else data
        return decode(self.od.data_type, data)

    @raw.setter
    def raw(self, value: Value) -> None:
        self._parent("raw =").set_variable(self, self._encode(value))

    @property
    def phys(self) -> Value:
        """`raw` scaled by the OD's factor (python-canopen's `phys`); equal to
        `raw` when there is no factor or the value is not a number."""
        raw = self.raw
        factor = getattr(self.od, "factor", 1) or 1
        if factor == 1 or isinstance(raw, bool) or not isinstance(raw, (int, float)):
            return raw
        return raw * factor

    @phys.setter
    def phys(self, value: Value) -> None:
        factor = getattr(self.od, "factor", 1) or 1
        if factor != 1 and isinstance(value, (int, float)) and not isinstance(value, bool):
            scaled = value / factor
            is_int = self.od is not None and self.od.data_type.is_integer
            value = round(scaled) if is_int else scaled
        self.raw = value

    @property
    def data(self) -> bytes:
        """The entry's bytes (`get_data()`); settable like `raw`, with the
        object's size in bytes."""
        return self.get_data()

    @data.setter
    def data(self, value: bytes) -> None:
        if not isinstance(value, (bytes, bytearray, memoryview)):
            raise ConfigurationError(f"{self._where()}: data must be bytes, got "
                                     f"{type(value).__name__}")
        value = bytes(value)
        size = self.od.size if self.od is not None and self.od.size else \
            (self.length + 7) // 8
        if len(value) != size:
            raise ConfigurationError(f"{self._where()}: data must be {size} bytes, got "
                                     f"{len(value)}")
        if self.od is not None:
            self.raw = decode(self.od.data_type, value)
        else:
            self._parent("data =").set_variable(self, self._fit(value))

    def _where(self) -> str:
        parent = self.pdo_parent
        return f"{parent.where if parent is not None else 'PDO'} {self.name!r}"

    def _parent(self, what: str) -> "PdoMap":
        if self.pdo_parent is None:
            raise ConfigurationError(f"{self.name!r}: {what} needs a PDO this entry is "
                                     "mapped in")
        return self.pdo_parent

    def _encode(self, value: Value) -> bytes:
        """value as the entry's bytes, checked against the OD's type and limits
        and against the mapped bits (a partly mapped number must fit them)."""
        where = self._where()
        if self.od is None:
            if isinstance(value, int) and not isinstance(value, bool):
                if not 0 <= value < 1 << self.length:
                    raise ConfigurationError(f"{where}: {value} does not fit the {self.length} "
                                             f"mapped bits (0..{(1 << self.length) - 1})")
                return value.to_bytes((self.length + 7) // 8, "little")
            if isinstance(value, (bytes, bytearray)):
                return self._fit(bytes(value))
            raise ConfigurationError(f"{where}: an entry the OD does not describe takes an int "
                                     f"or bytes, got {type(value).__name__}")
        dtype = self.od.data_type
        try:
            data = self.od.encode_raw(value)
        except OdValueError as exc:          # type, range, limits
            raise ConfigurationError(f"{where} ({dtype.name}): {exc}") from None
        whole = 8 * len(data)
        if dtype.is_integer and self.length < whole:
            low, high = (-(1 << (self.length - 1)), (1 << (self.length - 1)) - 1) \
                if dtype.signed else (0, (1 << self.length) - 1)
            if not low <= int.from_bytes(data, "little", signed=dtype.signed) <= high:
                raise ConfigurationError(f"{where}: {value!r} does not fit the {self.length} "
                                         f"mapped bits of the {dtype.name} ({low}..{high})")
        elif not dtype.is_integer and int.from_bytes(data, "little") >> self.length:
            raise ConfigurationError(f"{where}: {value!r} ({len(data)} bytes) does not fit the "
                                     f"{self.length} mapped bits")
        if len(data) < (self.length + 7) // 8:      # a string shorter than its mapping
            data = data.ljust((self.length + 7) // 8, b"\0")
        return data

    def _fit(self, value: bytes) -> bytes:
        need = (self.length + 7) // 8
        if len(value) != need:
            raise ConfigurationError(f"{self._where()}: {len(value)} bytes, the {self.length} "
                                     f"mapped bits take {need}")
        return value


class PdoMap:
    """One PDO: communication parameters and mapping (python-canopen names).

    Attributes read from or written to the node: `cob_id` (the CAN-ID),
    `enabled` (COB-ID bit 31 clear), `rtr_allowed` (bit 30 clear; classic),
    `extended` (bit 29: 29-bit CAN-ID), `trans_type`, `inhibit_time` (100 µs),
    `event_timer` (ms), `sync_start_value`, and `map` (also `variables`): the
    mapped PdoVariables. None = not known (not read, not set): not written.
    """

    def __init__(self, maps: PdoMaps, number: int, wiring: _Wiring) -> None:
        self.pdo_node = maps
        self._context = wiring.context
        self._access = wiring.access
        self._remote = wiring.access.remote
        self.number = number
        self.is_rpdo = maps.kind == "rpdo"
        self.com_index = _COMM[maps.kind] + number - 1
        self.map_index = _MAP[maps.kind] + number - 1
        #: the PDO in messages: 'TPDO1'
        self.label = f"{maps.kind.upper()}{number}"
        self.enabled = False
        self.rtr_allowed = True
        self.extended = False
        self._cob_id: Optional[int] = None
        self._trans_type: Optional[int] = None
        self._inhibit_time: Optional[int] = None
        self._event_timer: Optional[int] = None
        self._sync_start_value: Optional[int] = None
        #: Default COB-ID in the predefined connection set (PDOs 1..4), else None.
        self.predefined_cob_id: Optional[int] = None
        if number <= 4:
            self.predefined_cob_id = _PREDEFINED[maps.kind] + (number - 1) * 0x100 + \
                maps.node.node_id
        #: The mapped entries in PDO order (python-canopen's name).
        self.map: List[PdoVariable] = []
        #: Total mapped length in bits.
        self.length = 0
        #: PDO bytes (ceil(length / 8)); `PdoVariable.raw` decodes them.
        self.data = bytearray()
        # The mapping is written by save() only when it was changed here.
        self._map_changed = False
        self._mpdo: Optional[str] = None
        # Communication values as read (sub -> value): read-only ones are not rewritten.
        self._read_values: Dict[int, Optional[int]] = {}
        # Receptions (local RPDOs listened to): callbacks, count, last time.
        self._callbacks: Optional[CallbackList] = None
        self._received = 0
        #: time.time() of the last reception (with callbacks or waits).
        self.timestamp: Optional[float] = None
        #: Seconds between the last two receptions (None before the second).
        self.period: Optional[float] = None
        # Remote nodes' PDOs: the CAN-ID watched (bit 29 = 29-bit) and the
        # waits in progress; frames shorter than the mapping are not delivered.
        self._watched: Optional[int] = None
        self._waits = 0
        #: Frames heard on a remote PDO's CAN-ID too short for its mapping (ignored).
        self.short_frames = 0
        #: Values of this PDO received just before the one now in `data` that
        #: no callback saw: the callbacks fell behind and the runtime kept only
        #: the newest (0 while they keep up). `skipped_total` adds them all up.
        self.skipped = 0
        self.skipped_total = 0
        # A remote RPDO the master produces (co_rt_rpdo_*): the runtime's slot,
        # the (CAN-ID key, bytes) it was opened for, and what keeps it sending
        # (None, ("period", µs, False) or ("sync", every, acyclic)) to restore
        # when the COB-ID or the mapping changes.
        self._slot: Optional[int] = None
        self._slot_key: Optional[Tuple[int, int]] = None
        self._sending: Optional[Tuple[str, int, bool]] = None
        wiring.receivers[number] = self._event_received
        wiring.stops.append(self._stop_watch)
        wiring.stops.append(self.release_producer)

    # ------------------------------------------------------------ identity
    @property
    def node(self) -> NodeView:
        return self.pdo_node.node

    @property
    def where(self) -> str:
        """'node 5 TPDO1' — the place named in messages."""
        return f"{_where_of(self.node, self._remote)} {self.label}"

    @property
    def name(self) -> str:
        """python-canopen's descriptive name: 'TxPDO1_node5'."""
        return f"{'Rx' if self.is_rpdo else 'Tx'}PDO{self.number}_node{self.node.node_id}"

    @property
    def mode(self) -> str:
        return self._context.mode

    @property
    def max_bits(self) -> int:
        """Largest PDO payload on the node's line: 64 bits (classic), 512 (fd)."""
        return _BITS[self.mode]

    @property
    def capacity(self) -> int:
        """Mapping entries the node's mapping object has room for (0..64)."""
        obj = self._od.get(self.map_index) if self._od is not None else None
        if not isinstance(obj, (ODArray, ODRecord)):
            return 0
        return len([s for s in obj.subindices if 1 <= s <= _MAX_ENTRIES])

    @property
    def variables(self) -> List[PdoVariable]:
        """The mapped entries (same list as `map`)."""
        return self.map

    @property
    def _od(self) -> Optional[ObjectDictionary]:
        return self.pdo_node.od

    def __repr__(self) -> str:
        cob = "?" if self._cob_id is None else f"0x{self._cob_id:X}"
        return (f"<PdoMap {self.where} COB-ID {cob} {'enabled' if self.enabled else 'disabled'}"
                f" type {self._trans_type} {[v.name for v in self.map]}>")

    def __iter__(self) -> Iterator[PdoVariable]:
        return iter(self.map)

    def __len__(self) -> int:
        return len(self.map)

    def __getitem__(self, key: Union[int, str]) -> PdoVariable:
        """A mapped entry by position (0..63), index, name or 'INDEX:SUB'."""
        if isinstance(key, int) and not isinstance(key, bool):
            if 0 <= key < _MAX_ENTRIES:
                if key < len(self.map):
                    return self.map[key]
            else:
                for var in self.map:
                    if var.index == key:
                        return var
        elif isinstance(key, str):
            for var in self.map:
                if key in (var.name, getattr(var.od, "name", None),
                           f"0x{var.index:04X}:{var.subindex:02X}"):
                    return var
        if not self.map and not self._read_values:
            raise KeyError(f"{self.where}: {key!r}: the mapping is not known yet; read() it "
                           "from the node (or read(from_od=True) from its EDS) first")
        raise KeyError(f"{self.where}: {key!r} is not mapped (mapped: "
                       f"{', '.join(v.name for v in self.map) or 'nothing'})")

    # ------------------------------------------------------------ parameters
    def _field(self, field: str, value: object, low: int, high: int, expected: str) -> int:
        if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
            raise ConfigurationError(f"{self.where}: {field} must be {expected}, got {value!r}")
        return value

    @property
    def cob_id(self) -> Optional[int]:
        """The CAN-ID (0..0x7FF; up to 0x1FFFFFFF with `extended`), without
        the flag bits (`enabled`, `rtr_allowed`, `extended`)."""
        return self._cob_id

    @cob_id.setter
    def cob_id(self, value: Optional[int]) -> None:
        self._cob_id = None if value is None else self._field(
            "cob_id", value, 0, 0x1FFFFFFF,
            "the CAN-ID 0..0x7FF (0..0x1FFFFFFF with extended=True; enabled/rtr_allowed "
            "are separate attributes)")
        if value is not None:
            self._retarget("cob_id")

    def _trans_type_expected(self) -> str:
        if not self.is_rpdo and self.mode == "classic":
            return "0, 1..240, 252, 253, 254 or 255"
        why = "RPDOs" if self.is_rpdo else "fd lines"
        return f"0, 1..240, 254 or 255 (252/253 are for TPDOs on classic lines, not {why})"

    def _check_trans_type(self, value: object) -> int:
        if isinstance(value, int) and not isinstance(value, bool) and (
                0 <= value <= 240 or value in (254, 255) or
                (value in (252, 253) and not self.is_rpdo and self.mode == "classic")):
            return value
        raise ConfigurationError(f"{self.where}: trans_type must be "
                                 f"{self._trans_type_expected()}, got {value!r}")

    @property
    def trans_type(self) -> Optional[int]:
        """Transmission type: 0 (synchronous acyclic), 1..240 (every n-th
        SYNC), 252/253 (RTR; classic TPDOs), 254/255 (event driven)."""
        return self._trans_type

    @trans_type.setter
    def trans_type(self, value: Optional[int]) -> None:
        self._trans_type = None if value is None else self._check_trans_type(value)

    @property
    def inhibit_time(self) -> Optional[int]:
        """Minimum time between two transmissions, in 100 µs (0..65535)."""
        return self._inhibit_time

    @inhibit_time.setter
    def inhibit_time(self, value: Optional[int]) -> None:
        self._inhibit_time = None if value is None else self._field(
            "inhibit_time", value, 0, 0xFFFF, "0..65535 (units of 100 µs)")

    @property
    def event_timer(self) -> Optional[int]:
        """TPDO: transmission period in ms; RPDO: reception deadline (0 = off)."""
        return self._event_timer

    @event_timer.setter
    def event_timer(self, value: Optional[int]) -> None:
        self._event_timer = None if value is None else self._field(
            "event_timer", value, 0, 0xFFFF, "0..65535 ms")

    @property
    def sync_start_value(self) -> Optional[int]:
        """SYNC counter value of the first transmission (0 = not used), 0..240."""
        return self._sync_start_value

    @sync_start_value.setter
    def sync_start_value(self, value: Optional[int]) -> None:
        self._sync_start_value = None if value is None else self._field(
            "sync_start_value", value, 0, 240, "0..240")

    @property
    def is_periodic(self) -> bool:
        """python-canopen: synchronous PDOs (types 0..240) are periodic."""
        return self._trans_type is not None and self._trans_type <= 240

    # ------------------------------------------------------------ process data
    def _local_rpdo(self, what: str) -> None:
        where = f"{self.where}: {what}"
        if not self.is_rpdo:
            raise ConfigurationError(f"{where}: this is a TPDO of the local node; the "
                                     "runtime sends it (receptions are RPDOs)")
        if not self._access.booted:
            raise ConfigurationError(f"{where}: the node is not booted yet")

    def _listen(self, what: str) -> CallbackList:
        if self._remote:
            return self._watch(what)
        self._local_rpdo(what)
        context = self._context
        with context.cond:
            if self._callbacks is None:
                if not self.map and not self._read_values:
                    self.read()          # the mapping the OD has now, to decode
                context.runtime.pdo_listen(context.index, self.number, True,
                                           f"{self.where}: {what}")
                self._callbacks = CallbackList(f"{self.where} reception")
            return self._callbacks

    # A remote node's PDO: its frames are heard by CAN-ID (co_rt_pdo_watch).
    def _frame_key(self) -> int:
        return self._cob_id | (FRAME_29BIT if self.extended else 0)  # type: ignore[operator]

    def _watch(self, what: str) -> CallbackList:
        """Start hearing this remote PDO's CAN-ID (the COB-ID read or set;
        else the OD's, with its mapping when none was made here)."""
        with self._context.cond:
            if self._callbacks is None:
                self._callbacks = CallbackList(f"{self.where} reception")
            if self._watched is None:
                if self._cob_id is None:
                    if not self.map:
                        self.read(from_od=True)
                    else:
                        raw = self._from_od(self.com_index, 1, 4, "reading the COB-ID") or 0
                        self._cob_id = raw & 0x1FFFFFFF
                        self.extended = bool(raw & FRAME_29BIT)
                        self.enabled = not raw & PDO_NOT_VALID
                if not self.extended and self._cob_id > 0x7FF:  # type: ignore[operator]
                    raise ConfigurationError(f"{self.where}: {what}: COB-ID 0x{self._cob_id:X} "
                                             "is not an 11-bit CAN-ID (extended=False)")
                key = self._frame_key()
                self._context.pdo_watches.watch(key, self._event_frame, f"{self.where}: {what}")
                self._watched = key
            return self._callbacks

    def _retarget(self, what: str) -> None:
        """The COB-ID changed (read, save, cob_id =): hear the new CAN-ID and
        produce on it (a remote RPDO the master drives)."""
        if self._slot is not None:
            self._reopen_producer(what)
        if self._watched is None or self._cob_id is None:
            return
        key = self._frame_key()
        if key != self._watched and (self.extended or self._cob_id <= 0x7FF):
            watches = self._context.pdo_watches
            with self._context.cond:
                watches.watch(key, self._event_frame, f"{self.where}: {what}")
                watches.unwatch(self._watched, self._event_frame, f"{self.where}: {what}")
                self._watched = key

    def _stop_watch(self, what: str) -> None:
        """Stop hearing the CAN-ID (no callback and no wait left, node removed)."""
        if self._watched is not None:
            with self._context.cond:
                self._context.pdo_watches.unwatch(self._watched, self._event_frame, what)
                self._watched = None

    def _release(self, what: str) -> None:
        if self._remote and not self._callbacks and self._waits == 0:
            self._stop_watch(f"{self.where}: {what}")

    def add_callback(self, callback: Callable[["PdoMap"], None],
                     loop: LoopArg = None) -> Callable[["PdoMap"], None]:
        """callback(pdo_map) on the dispatcher thread after each reception,
        `data` holding the received values (python-canopen's name). The
        local node: its RPDOs. A remote node: its TPDOs (what it sends) and
        its RPDOs (what others send it), heard by CAN-ID: the COB-ID read()
        or set here, else the OD's (its default, with $NODEID), and the OD's
        mapping when none was read or made here; a COB-ID changed later by
        read(), save() or `cob_id =` is followed."""
        return self._listen("add_callback").add(callback, loop)

    def remove_callback(self, callback: Callable[["PdoMap"], None]) -> None:
        """Remove a callback; a remote PDO is no longer heard once no
        callback and no wait is left."""
        if self._callbacks is not None:
            self._callbacks.remove(callback)
            self._release("remove_callback")

    def _reception_until(self) -> "Until[bool]":
        """A reception after this call; the PDO is heard until _reception_done()."""
        with self._context.cond:
            self._listen("wait_for_reception")
            self._waits += 1
            start = self._received
        return Until(lambda: self._received > start, f"{self.where}: wait_for_reception",
                     lambda: "no reception")

    def _reception_done(self) -> None:
        with self._context.cond:
            self._waits -= 1
            self._release("wait_for_reception")

    def wait_for_reception(self, timeout: Optional[float] = 10.0) -> float:
        """Block until the PDO is received after this call; returns the
        reception time (time.time()). TimeoutError when none came in time."""
        until = self._reception_until()
        try:
            self._context.waiter.wait_until(until, timeout)
        finally:
            self._reception_done()
        return self.timestamp  # type: ignore[return-value]

    async def await_for_reception(self, timeout: Optional[float] = 10.0) -> float:
        """wait_for_reception() for `await`; cancelling it stops hearing the
        PDO as wait_for_reception's end does."""
        until = self._reception_until()
        try:
            await self._context.waiter.await_until(until, timeout)
        finally:
            self._reception_done()
        return self.timestamp  # type: ignore[return-value]

    def _received_now(self, skipped: int) -> None:
        self.skipped = skipped
        if skipped:
            self.skipped_total += skipped
            self._context.fell_behind(self.where, skipped)
        now = time.time()
        if self.timestamp is not None:
            self.period = now - self.timestamp
        self.timestamp = now
        self._received += 1

    def _event_received(self, data: bytes, skipped: int) -> Deferred:
        """A reception (dispatcher thread, under the line's condition)."""
        if len(data) != (self.length + 7) // 8:
            try:                # the mapping changed (over the network): read it again
                self.read()
            except Exception:  # noqa: BLE001 - decoding is best effort; data still set
                log.exception("%s: mapping could not be read again", self.where)
        self.data = bytearray(data)
        self._received_now(skipped)
        callbacks = self._callbacks
        return (lambda: callbacks.fire(self)) if callbacks else None

    def _event_frame(self, frame: Frame, skipped: int) -> Deferred:
        """A frame on a watched remote PDO's CAN-ID (dispatcher thread, under
        the line's condition): `data` = its first ceil(length / 8) bytes (all
        of them while nothing is mapped)."""
        need = (self.length + 7) // 8
        if len(frame.data) < need:
            self.short_frames += 1
            log.debug("%s: frame of %d bytes on 0x%X, the mapping needs %d; ignored",
                      self.where, len(frame.data), frame.id, need)
            return None
        self.data = bytearray(frame.data[:need] if self.map else frame.data)
        self._received_now(skipped)
        callbacks = self._callbacks
        return (lambda: callbacks.fire(self)) if callbacks else None

    def transmit(self) -> None:
        """Send this PDO now, once. A remote node's RPDO: the master sends the
        frame the device receives, with the values set through
        `pdo["name"].raw = ...` (see start()). A TPDO of the local node: an
        application event (types 0, 254 and 255 take it, in OPERATIONAL);
        the values come from the OD (`node[...].raw = ...` or
        `me.tpdo[1]["name"].raw = ...` first). The error names why when it
        cannot."""
        if self._remote:
            if not self.is_rpdo:
                raise ConfigurationError(f"{self.where}: transmit() sends a remote node's "
                                         "RPDOs (the master produces them) or the local "
                                         "node's TPDOs; a remote node sends its own TPDOs")
            slot = self._producer("transmit()")
            context = self._context
            context.runtime.rpdo_send(context.index, slot, f"{self.where}: transmit()")
            return
        if self.is_rpdo:
            raise ConfigurationError(f"{self.where}: transmit() is for TPDOs")
        if not self._access.booted:
            raise ConfigurationError(f"{self.where}: the node is not booted yet")
        context = self._context
        context.runtime.pdo_trigger(context.index, self.number, f"{self.where}: transmit()")

    # ------------------------------------------------------------ MPDO
    # A TPDO of the local node whose mapping sub 0 is 0xFF (DAM) or 0xFE
    # (SAM) is a multiplexed PDO (CiA 301): each frame carries one object
    # with its address (co_mpdo.h; docs/protocol-notes.md "MPDO").
    def _local_mpdo(self, what: str) -> LineContext:
        where = f"{self.where}: {what}"
        if self._remote or self.is_rpdo:
            raise ConfigurationError(f"{where}: MPDOs are sent through a TPDO of the local "
                                     "node (mapping sub 0 = 0xFF DAM / 0xFE SAM)")
        if not self._access.booted:
            raise ConfigurationError(f"{where}: the node is not booted yet")
        return self._context

    def send_dam(self, node: int, index: Optional[int] = None, sub: Optional[int] = None,
                 data: Optional[bytes] = None) -> None:
        """DAM MPDO through this TPDO (mapping sub 0 = 0xFF, type 254/255,
        OPERATIONAL) to node `node` (0 = every consumer). `send_dam(node)`:
        the local object the mapping's sub 1 names (index, sub, 8..32 bits),
        written to the same index:sub there (the CiA 301 producer).
        `send_dam(node, index, sub, data)`: `data` (1..4 bytes,
        little-endian as in the OD) into index:sub there. The error names
        why it was not sent."""
        if index is None and sub is None and data is None:
            what = f"send_dam({node})"
            context = self._local_mpdo(what)
            context.runtime.mpdo_send_dam_mapped(context.index, self.number, node,
                                                 f"{self.where}: {what}")
            return
        what = f"send_dam({node}, {index!r}, {sub!r}, {data!r})"
        if index is None or sub is None or data is None:
            raise ConfigurationError(f"{self.where}: {what}: give index, sub and data, or only "
                                     "the node (the mapped object)")
        what = f"send_dam({node}, 0x{index:04X}, {sub}, {bytes(data)!r})"
        context = self._local_mpdo(what)
        if not isinstance(data, (bytes, bytearray)) or not 1 <= len(data) <= 4:
            raise ConfigurationError(f"{self.where}: {what}: data must be 1..4 bytes, got "
                                     f"{data!r}")
        context.runtime.mpdo_send_dam(context.index, self.number, node, index, sub, bytes(data),
                                      f"{self.where}: {what}")

    def send_sam(self, index: int, sub: int) -> None:
        """SAM MPDO: send the local object index:sub (named by the object
        scanner list 0x1FA0..0x1FCF, at most 4 bytes) through this TPDO
        (mapping sub 0 = 0xFE, type 254/255, OPERATIONAL); consumers find
        their own object for it in their dispatcher list 0x1FD0..0x1FFF."""
        what = f"send_sam(0x{index:04X}, {sub})"
        context = self._local_mpdo(what)
        context.runtime.mpdo_send_sam(context.index, self.number, index, sub,
                                      f"{self.where}: {what}")

    # ------------------------------------------------------------ master side
    # A remote node's RPDO, produced by the master in the C runtime: the
    # mapped bytes live in a runtime slot; each `raw =` writes its bits there
    # (one call, atomic with respect to sending); frames go out once
    # (transmit), periodically (start) or after SYNCs (start_sync), with no
    # Python per frame.
    def set_variable(self, var: PdoVariable, data: bytes) -> None:
        """Put a mapped entry's bytes (its low `var.length` bits) into `data`;
        a remote RPDO being produced gets them at once, the local node's
        entry is written to its OD."""
        if var.pdo_parent is not self:
            raise ConfigurationError(f"{self.where}: {var.name!r} is not mapped here")
        if not self._remote:
            self._write_local(var, data)
            return
        if not self.is_rpdo:
            raise ConfigurationError(f"{self.where}: {var.name!r}: a remote node's TPDO is "
                                     "what it sends; values can be set on its RPDOs (what "
                                     "the master sends it) or on the local node's PDOs")
        with self._context.cond:
            self._put_bits(var, data)
            if self._slot is not None:
                context = self._context
                context.runtime.rpdo_write(context.index, self._slot, var.offset, var.length,
                                           data, f"{self.where}: {var.name} = ...")

    def _put_bits(self, var: PdoVariable, data: bytes) -> None:
        size = (self.length + 7) // 8
        if len(self.data) != size:
            self.data = bytearray(size)
        whole = int.from_bytes(bytes(self.data), "little")
        mask = ((1 << var.length) - 1) << var.offset
        value = (int.from_bytes(data, "little") << var.offset) & mask
        self.data = bytearray(((whole & ~mask) | value).to_bytes(size, "little"))

    def _write_local(self, var: PdoVariable, data: bytes) -> None:
        """The local node: the PDO carries its OD's values, so write the entry."""
        od = var.od
        if od is None or var.is_dummy:
            raise ConfigurationError(f"{self.where}: {var.name!r} is not an entry of the "
                                     "local node's OD; nothing to write")
        if 8 * len(data) != var.length:
            raise ConfigurationError(f"{self.where}: {var.name!r} maps {var.length} bits of "
                                     "the object; set the whole object in the node's OD")
        self._access.write(var.index, var.subindex, data)
        self._put_bits(var, data)

    def _producer(self, what: str) -> int:
        """The runtime slot producing this remote RPDO (opened on first use)."""
        where = f"{self.where}: {what}"
        if not self.is_rpdo:
            raise ConfigurationError(f"{where}: only a remote node's RPDOs are sent by the "
                                     "master")
        if not self.map:
            raise ConfigurationError(f"{where}: nothing mapped; read() the mapping from the "
                                     "node (or read(from_od=True) from its EDS) first")
        if self._cob_id is None:
            raise ConfigurationError(f"{where}: the COB-ID is not known; read() the PDO or "
                                     "set cob_id")
        if not self.enabled:
            raise ConfigurationError(
                f"{where}: the PDO is disabled (COB-ID 0x{self._cob_id:X} with bit 31, "
                "'not valid'): the device would not take the frame; set enabled = True and "
                "save() it on the node first")
        if not self.extended and self._cob_id > 0x7FF:
            raise ConfigurationError(f"{where}: COB-ID 0x{self._cob_id:X} is not an 11-bit "
                                     "CAN-ID (extended=False)")
        with self._context.cond:
            if self._slot is None:
                self._open_producer(where)
            slot = self._slot
            assert slot is not None                 # _open_producer sets it or raises
            return slot

    def _open_producer(self, where: str) -> None:
        context = self._context
        size = (self.length + 7) // 8
        if len(self.data) != size:
            self.data = bytearray(size)
        key = (self._frame_key(), size)
        slot = context.runtime.rpdo_open(context.index, key[0], size, where)
        try:
            context.runtime.rpdo_write(context.index, slot, 0, 8 * size, bytes(self.data), where)
        except Exception:
            context.runtime.rpdo_close(context.index, slot, where)
            raise
        self._slot, self._slot_key = slot, key

    def _reopen_producer(self, what: str) -> None:
        """The COB-ID, the flags or the mapping changed: produce the new frame,
        keeping what made the old one go out (or stop, when it cannot)."""
        key = None
        if self._cob_id is not None and self.enabled and self.map and \
                (self.extended or self._cob_id <= 0x7FF):
            key = (self._frame_key(), (self.length + 7) // 8)
        if key == self._slot_key:
            # same frame layout: the values as they now stand here (read()
            # starts from zeros, as a new mapping does)
            context = self._context
            size = (self.length + 7) // 8
            if len(self.data) != size:
                self.data = bytearray(size)
            assert self._slot is not None           # a key is kept with its slot
            context.runtime.rpdo_write(context.index, self._slot, 0, 8 * size,
                                       bytes(self.data), f"{self.where}: {what}")
            return
        sending = self._sending
        self.release_producer(f"{self.where}: {what}")
        if key is None:
            if sending is not None:
                log.warning("%s: %s: stopped sending (disabled, no COB-ID or nothing mapped)",
                            self.where, what)
            return
        self._producer(what)
        if sending is not None:
            self._run(sending, what)

    def release_producer(self, what: str) -> None:
        """Stop sending this remote RPDO and free its runtime slot (the next
        transmit/start opens a new one)."""
        if self._slot is not None:
            context = self._context
            slot, self._slot, self._slot_key, self._sending = self._slot, None, None, None
            if not context.closed:
                context.runtime.rpdo_close(context.index, slot, what)

    def _run(self, sending: Tuple[str, int, bool], what: str) -> None:
        context = self._context
        slot = self._producer(what)
        where = f"{self.where}: {what}"
        context.runtime.rpdo_stop(context.index, slot, where)
        kind, amount, acyclic = sending
        if kind == "period":
            context.runtime.rpdo_start(context.index, slot, amount, where)
        else:
            context.runtime.rpdo_sync(context.index, slot, amount, acyclic, where)
        self._sending = sending

    def _remote_rpdo(self, what: str) -> None:
        if not (self._remote and self.is_rpdo):
            raise ConfigurationError(
                f"{self.where}: {what} is for a remote node's RPDOs (the master sends them); "
                + ("a remote node sends its own TPDOs" if self._remote else
                   "the local node's PDOs follow their transmission type"))

    def start(self, period: float) -> None:
        """Send this remote RPDO every `period` seconds (python-canopen's
        start; at least 0.0001 s), the first frame now, from the C runtime's
        timer until stop(). The values set with `raw =` go into the next
        frame. Replaces a start_sync()."""
        what = f"start({period!r})"
        self._remote_rpdo(what)
        if isinstance(period, bool) or not isinstance(period, (int, float)) or \
                not period > 0:
            raise ConfigurationError(f"{self.where}: {what}: the period must be a number of "
                                     f"seconds > 0, got {period!r}")
        period_us = round(period * 1e6)
        if not 100 <= period_us <= 0xFFFFFFFF:
            raise ConfigurationError(f"{self.where}: {what}: the period must be 0.0001 .. "
                                     f"4294 s, got {period!r}")
        self._run(("period", period_us, False), what)

    def start_sync(self, every: Optional[int] = None) -> None:
        """Send this remote RPDO right after SYNCs the line receives or
        produces, until stop(): after every `every`-th SYNC (1..240). By
        default from the RPDO's transmission type: 1..240 give `every`; 0
        (synchronous acyclic) sends after the first SYNC following a change
        (a `raw =`) only. A synchronous device applies the data at the SYNC
        after the reception, so each frame has a whole cycle to arrive.
        Replaces a start(period)."""
        what = f"start_sync({every!r})"
        self._remote_rpdo(what)
        acyclic = False
        if every is None:
            kind = self._trans_type
            if kind is None or kind > 240:
                raise ConfigurationError(
                    f"{self.where}: {what}: the transmission type is "
                    f"{'not known (read() it)' if kind is None else kind}, not synchronous "
                    "(0..240); give every=N, or use start(period) for an event RPDO")
            acyclic, every = kind == 0, max(kind, 1)
        elif isinstance(every, bool) or not isinstance(every, int) or not 1 <= every <= 240:
            raise ConfigurationError(f"{self.where}: {what}: every must be 1..240 SYNCs, got "
                                     f"{every!r}")
        self._run(("sync", every, acyclic), what)

    def stop(self) -> None:
        """Stop sending this remote RPDO periodically or on SYNC (no frame
        after stop() returns, except one already queued)."""
        self._remote_rpdo("stop()")
        if self._slot is not None:
            context = self._context
            context.runtime.rpdo_stop(context.index, self._slot, f"{self.where}: stop()")
        self._sending = None

    @property
    def producer_stats(self) -> Dict[str, int]:
        """The master's counters of this remote RPDO: frames `sent`,
        `tx_failed`, `not_operational` (held back: the local node is not
        OPERATIONAL), `writes`; all 0 before the first use."""
        if self._slot is None:
            return {"sent": 0, "tx_failed": 0, "not_operational": 0, "writes": 0}
        context = self._context
        return context.runtime.rpdo_stats(context.index, self._slot, f"{self.where}: stats")

    # ------------------------------------------------------------ mapping
    def clear(self) -> None:
        """Map nothing (save() then writes an empty mapping)."""
        self.map = []
        self.length = 0
        self.data = bytearray()
        self._mpdo = None
        self._map_changed = True

    @property
    def mpdo(self) -> Optional[str]:
        """'DAM' or 'SAM' when this PDO is a multiplexed PDO (mapping sub 0 =
        0xFF / 0xFE, as read() found or set here), else None. Setting it
        makes save() write that sub 0 (no entries; trans_type 254 or 255)."""
        return self._mpdo

    @mpdo.setter
    def mpdo(self, value: Optional[str]) -> None:
        if value is not None and value not in MPDO_MARKERS:
            raise ConfigurationError(f"{self.where}: mpdo must be 'DAM', 'SAM' or None, got "
                                     f"{value!r}")
        self.map, self.length, self.data = [], 0, bytearray()
        self._mpdo = value
        self._map_changed = True

    def _resolve(self, index: EntryKey, subindex: SubKey
                 ) -> Tuple[int, int, Optional[ODVariable]]:
        if isinstance(index, tuple) and len(index) == 2:
            index, subindex = index
        if isinstance(index, int) and not isinstance(index, bool) and index in DUMMY_BITS \
                and subindex == 0:
            return index, 0, None
        od = self._od
        try:
            entry = od[index] if od is not None else None
            if isinstance(entry, (ODRecord, ODArray)):
                # an ARRAY/RECORD needs its sub-index (None: not a mappable entry)
                entry = entry[subindex] if subindex is not None else None
            elif isinstance(entry, ODVariable) and not entry.in_object and \
                    subindex not in (0, None):
                entry = None            # a VAR has sub 0 only
        except KeyError:
            entry = None
        if isinstance(entry, ODVariable):
            return entry.index, entry.subindex, entry
        if isinstance(index, int) and not isinstance(index, bool) and \
                isinstance(subindex, int) and 0 <= index <= 0xFFFF and 0 <= subindex <= 0xFF:
            return index, subindex, None
        raise ConfigurationError(f"{self.where}: {index!r}"
                                 f"{'' if subindex == 0 else f' sub {subindex!r}'} is not in "
                                 f"the object dictionary of {_where_of(self.node, self._remote)}")

    def add_variable(self, index: EntryKey, subindex: SubKey = 0,
                     length: Optional[int] = None) -> PdoVariable:
        """Map the next entry: by index and sub-index (ints), a name
        ("Statusword", "Demo record.Setpoint"), (index, sub) or 'INDEX:SUB'.
        length: bits to map (default: the whole object from its data type);
        fewer bits map the low-order bits of a number or the first bytes of
        a string. RPDOs may map dummies 0x0002..0x0007 sub 0 (INTEGER8..
        UNSIGNED32, exact size) to skip bits. An entry missing from the OD
        needs an explicit length. Everything is checked here (see module
        doc); nothing is sent before save()."""
        index, subindex, variable = self._resolve(index, subindex)
        where = f"{self.where}: mapping 0x{index:04X}:{subindex:02X}"
        if variable is not None:
            where += f" {variable.qualname!r}"
        if variable is None and index in DUMMY_BITS and subindex == 0:
            if not self.is_rpdo:
                raise ConfigurationError(f"{where}: dummy entries (0x0002..0x0007) are for "
                                         "RPDOs only, not TPDOs")
            bits = DUMMY_BITS[index]
            if length is not None and length != bits:
                raise ConfigurationError(f"{where}: a dummy {DataType(index).name} maps "
                                         f"exactly {bits} bits, got {length!r}")
        elif variable is None:
            if length is None:
                raise ConfigurationError(f"{where}: not in the object dictionary; give the "
                                         "length in bits to map it anyway")
            bits = length
        else:
            bits = self._object_bits(variable, where) if length is None else length
            self._check_mappable(variable, bits, where)
        if isinstance(bits, bool) or not isinstance(bits, int) or not 1 <= bits <= 255:
            raise ConfigurationError(f"{where}: length must be 1..255 bits, got {bits!r}")
        if self.mode == "fd" and bits % 8:
            raise ConfigurationError(f"{where}: {bits} bits; fd lines map whole bytes only "
                                     "(a multiple of 8 bits)")
        self._check_room(len(self.map) + 1, self.length + bits, where)
        var = PdoVariable(index, subindex, bits, variable)
        self._append(var)
        self._mpdo = None           # mapped entries make it a plain PDO again
        self._map_changed = True
        return var

    def _object_bits(self, variable: ODVariable, where: str) -> int:
        if variable.data_type == DataType.DOMAIN:
            raise ConfigurationError(f"{where}: a DOMAIN cannot be mapped into a PDO")
        size = variable.size if variable.size is not None else variable.storage_size
        return 8 * size

    def _check_mappable(self, variable: ODVariable, bits: int, where: str) -> None:
        whole = self._object_bits(variable, where)
        direction = "rpdo" if self.is_rpdo else "tpdo"
        if variable.pdo_mappable not in (direction, "both"):
            raise ConfigurationError(
                f"{where}: the OD does not allow mapping it into a {direction.upper()} "
                f"(PDO mapping: {variable.pdo_mappable or 'no'}, access {variable.access_type})")
        if isinstance(bits, int) and not isinstance(bits, bool) and bits > whole:
            raise ConfigurationError(f"{where}: {bits} bits, the object holds {whole}")

    def _check_room(self, count: int, bits: int, where: str) -> None:
        if bits > self.max_bits:
            raise ConfigurationError(
                f"{where}: the mapping would be {bits} bits ({(bits + 7) // 8} bytes); a PDO "
                f"on a {self.mode} line holds {self.max_bits // 8} bytes ({self.max_bits} bits)")
        capacity = self.capacity
        if count > capacity:
            raise ConfigurationError(
                f"{where}: {count} entries; mapping object 0x{self.map_index:04X} has room "
                f"for {capacity}")

    def _append(self, var: PdoVariable) -> None:
        var.offset = self.length
        var.pdo_parent = self
        self.map.append(var)
        self.length += var.length
        self.data = bytearray((self.length + 7) // 8)

    # ------------------------------------------------------------ read
    def read(self, from_od: bool = False) -> None:
        """Read the configuration from the node (USDO on fd lines, SDO on
        classic lines; the local node: its OD), or with from_od=True from
        its object dictionary (the DCF value, else the default). Mapping
        entries become PdoVariables of the node's OD (dummies and entries
        the OD lacks are kept by index:sub). Sub-entries the OD lacks are
        not read (None)."""
        pdo_steps.run(self._read_steps(from_od), self._access)

    async def aread(self, from_od: bool = False) -> None:
        """read() for `await` (a remote node's transfers are awaited)."""
        await pdo_steps.arun(self._read_steps(from_od), self._access)

    def _read_steps(self, from_od: bool) -> "pdo_steps.Steps[None]":
        def fetch(index: int, sub: int, size: int, step: str,
                  optional: bool = False) -> "pdo_steps.Steps[Optional[int]]":
            if from_od:
                return pdo_steps.done(self._from_od(index, sub, size, step, optional))
            return self._from_node(index, sub, size, step, optional)
        values: Dict[int, Optional[int]] = {}
        for sub, (_attr, what, size) in _COMM_SUBS.items():
            if self._has(self.com_index, sub):
                values[sub] = yield from fetch(self.com_index, sub, size, f"reading the {what}",
                                               optional=sub != 1)
        self._read_values = values
        raw_cob = values.get(1)
        if raw_cob is None:
            raise ConfigurationError(f"{self.where}: 0x{self.com_index:04X}:01 (COB-ID) has "
                                     "no value")
        self._cob_id = raw_cob & 0x1FFFFFFF
        self.enabled = not raw_cob & PDO_NOT_VALID
        self.rtr_allowed = not raw_cob & RTR_NOT_ALLOWED
        self.extended = bool(raw_cob & FRAME_29BIT)
        self._trans_type = values.get(2)
        self._inhibit_time = values.get(3)
        self._event_timer = values.get(5)
        self._sync_start_value = values.get(6)
        self.map, self.length, self.data = [], 0, bytearray()
        self._mpdo = None
        if self._has(self.map_index, 0):
            count = (yield from fetch(self.map_index, 0, 1,
                                      "reading the number of mapped entries")) or 0
            self._mpdo = next((k for k, v in MPDO_MARKERS.items() if v == count), None)
            for sub in range(1, min(count, _MAX_ENTRIES) + 1 if self._mpdo is None else 1):
                value = yield from fetch(self.map_index, sub, 4, f"reading mapping entry {sub}")
                if not value or not value & 0xFF:
                    log.warning("%s: mapping entry %d is 0x%08X (no object or 0 bits); ignored",
                                self.where, sub, value or 0)
                    continue
                self._append(self._entry_variable(value))
        self._map_changed = False
        self._retarget("read")

    def _entry_variable(self, value: int) -> PdoVariable:
        index, sub, bits = value >> 16, (value >> 8) & 0xFF, value & 0xFF
        variable = None
        if not (index in DUMMY_BITS and sub == 0) and self._od is not None:
            variable = self._od.get_variable(index, sub)
        return PdoVariable(index, sub, bits, variable)

    def _has(self, index: int, sub: int) -> bool:
        return self._od is not None and self._od.get_variable(index, sub) is not None

    def _size(self, index: int, sub: int, standard: int) -> int:
        var = self._od.get_variable(index, sub) if self._od is not None else None
        if var is not None and var.data_type.is_integer and var.size:
            return var.size
        return standard

    def _from_node(self, index: int, sub: int, size: int, step: str,
                   optional: bool = False) -> "pdo_steps.Steps[Optional[int]]":
        size = self._size(index, sub, size)
        step = f"{step} (0x{index:04X}:{sub:02X})"
        try:
            data = yield (index, sub, None)
        except AbortError as exc:
            if optional and exc.code in _ABSENT:
                return None
            _add_context(exc, self.where, step)
            raise
        if len(data) != size:
            raise ConfigurationError(f"{self.where}, {step}: the node answered {len(data)} "
                                     f"bytes, {size} expected")
        return int.from_bytes(data, "little")

    def _from_od(self, index: int, sub: int, size: int, step: str,
                 optional: bool = False) -> Optional[int]:
        od = self._od
        var = od.get_variable(index, sub) if od is not None else None
        if var is None:
            if optional:
                return None
            raise ConfigurationError(f"{self.where}, {step}: 0x{index:04X}:{sub:02X} is not in "
                                     f"the object dictionary of "
                                     f"{_where_of(self.node, self._remote)}")
        value: Optional[Value]
        if var.value_base is not None:
            value, relative = var.value_base, var.value_relative_to_node_id
        else:
            value, relative = var.default_base, var.relative_to_node_id
        if value is None:
            return None if optional else 0
        if not isinstance(value, int) or isinstance(value, bool):
            raise ConfigurationError(f"{self.where}, {step}: 0x{index:04X}:{sub:02X} holds "
                                     f"{value!r}, not an integer")
        return value + self.node.node_id if relative else value

    # ------------------------------------------------------------ save
    def _writable(self, index: int, sub: int) -> bool:
        var = self._od.get_variable(index, sub) if self._od is not None else None
        return var is not None and var.writable

    def _plan(self) -> List[Tuple[str, int, int, int, int]]:
        """The writes of save(): (step, index, sub, value, size), all checked."""
        if self._cob_id is None:
            raise ConfigurationError(f"{self.where}: cob_id is not known; read() the PDO or set "
                                     "cob_id before save()")
        if not self._has(self.com_index, 1):
            raise ConfigurationError(f"{self.where}: the OD has no 0x{self.com_index:04X}:01")
        if not self.extended and self._cob_id > 0x7FF:
            raise ConfigurationError(f"{self.where}: cob_id must be 0..0x7FF for an 11-bit "
                                     f"CAN-ID (extended=False), got 0x{self._cob_id:X}")
        if self._trans_type is not None:
            self._check_trans_type(self._trans_type)
        cob = self._cob_id | (FRAME_29BIT if self.extended else 0) | \
            (0 if self.rtr_allowed else RTR_NOT_ALLOWED)
        com = self.com_index
        plan = [(f"disabling it (COB-ID 0x{com:04X}:01 = 0x{cob | PDO_NOT_VALID:08X})",
                 com, 1, cob | PDO_NOT_VALID, 4)]
        for sub in (2, 3, 5, 6):
            attr, what, size = _COMM_SUBS[sub]
            value = getattr(self, attr)
            if value is None or not self._has(com, sub):
                continue
            if not self._writable(com, sub):
                if value == self._read_values.get(sub):
                    continue            # fixed by the device and unchanged: nothing to write
                raise ConfigurationError(
                    f"{self.where}: {attr} {value} cannot be written: 0x{com:04X}:{sub:02X} is "
                    f"read-only in the OD (the node has {self._read_values.get(sub)}; set "
                    f"{attr} = None to leave it)")
            plan.append((f"writing the {what} (0x{com:04X}:{sub:02X} = {value})",
                         com, sub, value, size))
        if self._map_changed:
            plan += self._map_plan()
        if self.enabled:
            plan.append((f"enabling it (COB-ID 0x{com:04X}:01 = 0x{cob:08X})", com, 1, cob, 4))
        return [(step, index, sub, value, self._size(index, sub, size))
                for step, index, sub, value, size in plan]

    def _map_plan(self) -> List[Tuple[str, int, int, int, int]]:
        where = f"{self.where}: mapping"
        mapping = self.map_index
        if not self._has(mapping, 0):
            raise ConfigurationError(f"{where}: the OD has no mapping object "
                                     f"0x{mapping:04X}")
        if not self._writable(mapping, 0):
            raise ConfigurationError(f"{where}: 0x{mapping:04X}:00 is read-only in the OD "
                                     "(a fixed mapping cannot be changed)")
        if self._mpdo is not None:
            if self._trans_type not in (254, 255):
                raise ConfigurationError(f"{where}: an MPDO ({self._mpdo}) needs trans_type 254 "
                                         f"or 255, got {self._trans_type!r}")
            marker = MPDO_MARKERS[self._mpdo]
            return [(f"clearing the mapping (0x{mapping:04X}:00 = 0)", mapping, 0, 0, 1),
                    (f"making it a {self._mpdo} MPDO (0x{mapping:04X}:00 = 0x{marker:02X})",
                     mapping, 0, marker, 1)]
        bits = sum(var.length for var in self.map)
        self._check_room(len(self.map), bits, where)
        for var in self.map:
            if self.mode == "fd" and var.length % 8:
                raise ConfigurationError(f"{where}: {var.name} maps {var.length} bits; fd "
                                         "lines map whole bytes only")
            if var.is_dummy and not self.is_rpdo:
                raise ConfigurationError(f"{where}: dummy {var.name} in a TPDO")
        plan = [(f"clearing the mapping (0x{mapping:04X}:00 = 0)", mapping, 0, 0, 1)]
        for sub, var in enumerate(self.map, 1):
            step = (f"writing mapping entry {sub} (0x{mapping:04X}:{sub:02X} = "
                    f"0x{var.mapping_value:08X}, {var.name})")
            plan.append((step, mapping, sub, var.mapping_value, 4))
        count = len(self.map)
        step = f"setting the number of mapped entries (0x{mapping:04X}:00 = {count})"
        plan.append((step, mapping, 0, count, 1))
        return plan

    def save(self) -> None:
        """Write the configuration with the CiA 301 procedure, in this order:
        COB-ID with bit 31 set (invalid); transmission type, inhibit time,
        event timer, SYNC start value (those not None and in the OD, except
        read-only ones left as read); when the mapping was changed here
        (clear/add_variable): mapping sub 0 = 0, entries 1..n, sub 0 = n;
        finally, if `enabled`, the COB-ID without bit 31 (a disabled PDO
        stays invalid). Everything is checked before the first write; a
        refusal raises the abort exception naming this PDO and the step, and
        the procedure stops there (the PDO stays invalid)."""
        pdo_steps.run(self._save_steps(), self._access)

    async def asave(self) -> None:
        """save() for `await` (a remote node's transfers are awaited)."""
        await pdo_steps.arun(self._save_steps(), self._access)

    def _save_steps(self) -> "pdo_steps.Steps[None]":
        for step, index, sub, value, size in self._plan():
            try:
                yield (index, sub, value.to_bytes(size, "little"))
            except AbortError as exc:
                _add_context(exc, self.where, step)
                raise
        if self._map_changed:
            self._map_changed = False
        self._retarget("save")
