"""SRDOs and the GFC of a local node (CiA 304): `node.srdo`.

    me.srdo.start(2)                                   # SRDOs 1 and 2, off
    me.srdo.configure(1, SrdoConfig("produce", sct_ms=20, srvt_ms=5,
                                    cob_id=0x101, mapping=(0x62000120, 0x62010120)))
    me.srdo.set_data(1, b"\\x01\\x02\\x03\\x04")
    me.srdo.add_callback(print)                        # callback(SrdoNotice)
    me.srdo.read(2)                                    # SrdoStatus: state, data, ...
    me.srdo.send_gfc()                                 # after gfc(True)

The C core runs the pairs and their timing; Python configures, feeds and
reads. configure() computes the configuration's signature (0x13FF) and
declares it valid (0x13FE = 0xA5) unless told otherwise. A node whose OD has
the SRDO objects (0x1301+n, 0x1381+n, 0x13FE, 0x13FF) runs what they hold by
itself: the C core refuses writes to them while OPERATIONAL (0x08000022),
clears 0x13FE on any change, and the data are the mapped variables. This is not a
certified safety stack: see the README's SRDO section.
"""

from __future__ import annotations

import struct
from typing import Callable, Dict, List, NamedTuple, Optional, Protocol, Sequence, Tuple

from .._binding.constants import EventKind, SrdoState, SrdoViolation
from .._binding.context import Deferred, LineContext, LocalNodeService
from .._binding.runtime import Event, srdo_crc
from .._callbacks import CallbackList
from ..errors import ConfigurationError

__all__ = ["SrdoConfig", "SrdoNotice", "SrdoService", "SrdoState", "SrdoStatus",
           "SrdoViolation", "srdo_signature", "srdo_config_writes", "write_srdo_config",
           "CONFIG_VALID", "GFC_COB_ID", "COMMUNICATION_BASE", "MAPPING_BASE", "VALID_INDEX",
           "SIGNATURE_INDEX", "GFC_INDEX"]

#: 0x13FE: the value that declares the SRDO configuration valid.
CONFIG_VALID = 0xA5
#: The GFC's CAN-ID (one frame, no data).
GFC_COB_ID = 0x001
#: SRDO n's objects: 0x1300 + n (communication), 0x1380 + n (mapping); 0x13FE
#: configuration valid, 0x13FF sub n signature, 0x1300 the GFC parameter.
COMMUNICATION_BASE, MAPPING_BASE = 0x1300, 0x1380
VALID_INDEX, SIGNATURE_INDEX, GFC_INDEX = 0x13FE, 0x13FF, 0x1300
_DIRECTIONS = {"off": 0, "produce": 1, "consume": 2}
_DIRECTION_NAMES = {code: name for name, code in _DIRECTIONS.items()}
_TRANSMISSION_TYPE = 254


class SrdoConfig(NamedTuple):
    """0x1301+n and 0x1381+n of one SRDO. cob_id: the normal frame's (odd,
    0x101..0x17F); the inverted one is cob_id + 1. mapping: the 0x1381+n
    entries (index << 16 | sub << 8 | bits), normal and inverted alternating;
    they size the data, and on a node whose OD has the SRDO objects they name
    the variables sent (odd entries) and their complements (even entries)."""

    direction: str                 # 'produce', 'consume' or 'off'
    sct_ms: int = 0                # SCT: producer cycle / consumer's limit between normals
    srvt_ms: int = 0               # SRVT: inverted frame at most this long after the normal
    cob_id: int = 0
    mapping: Sequence[int] = ()

    @property
    def length(self) -> int:
        """Data bytes of a frame (the normal half of the mapping)."""
        return sum((entry & 0xFF) // 8 for entry in self.mapping[0::2])


class SrdoNotice(NamedTuple):
    """An SRDO entered the safe state: which one and why."""

    number: int
    violation: SrdoViolation


class SrdoStatus(NamedTuple):
    """One SRDO now: its state, why it is safe (NONE otherwise), the last valid
    data (None while not valid) and its counters."""

    state: SrdoState
    violation: SrdoViolation
    data: Optional[bytes]
    stats: Dict[str, int]


def _fields(config: SrdoConfig, where: str) -> Dict[str, int]:
    if config.direction not in _DIRECTIONS:
        raise ConfigurationError(f"{where}: direction must be 'produce', 'consume' or 'off', "
                                 f"got {config.direction!r}")
    checks = (("sct_ms", config.sct_ms, 0xFFFF), ("srvt_ms", config.srvt_ms, 0xFF),
              ("cob_id", config.cob_id, 0x7FF))
    for name, value, top in checks:
        if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= top:
            raise ConfigurationError(f"{where}: {name} must be 0..{top:#x}, got {value!r}")
    if len(config.mapping) > 16 or any(
            isinstance(e, bool) or not isinstance(e, int) or not 0 <= e <= 0xFFFFFFFF
            for e in config.mapping):
        raise ConfigurationError(f"{where}: mapping must be at most 16 UNSIGNED32 entries, "
                                 f"got {list(config.mapping)!r}")
    return {"direction": _DIRECTIONS[config.direction], "sct_ms": config.sct_ms,
            "srvt_ms": config.srvt_ms, "transmission_type": _TRANSMISSION_TYPE,
            "cob_id_normal": config.cob_id, "cob_id_inverted": config.cob_id + 1}


def srdo_signature(config: SrdoConfig) -> int:
    """The 0x13FF signature of a configuration: CRC-16-CCITT (polynomial
    0x1021, initial 0) over direction, SCT, SRVT, both COB-IDs, the mapping
    count and each mapping entry behind its sub-index, little-endian (see
    docs/protocol-notes.md, SRDO, for what is and is not confirmed)."""
    return srdo_crc(_fields(config, f"srdo_signature({config!r})"), config.mapping)


def srdo_config_writes(number: int, config: SrdoConfig, *, valid: int = CONFIG_VALID
                       ) -> List[Tuple[int, int, bytes]]:
    """The (index, sub, bytes) writes that give a device's SRDO `number` this
    configuration, in an order a CiA 304 device takes: the SRDO switched off
    and its mapping emptied first (a device may refuse mapping changes
    otherwise), the entries, the count, the timing and COB-IDs, the direction,
    then the signature (0x13FF) and last the valid flag (0x13FE)."""
    where = f"srdo_config_writes({number!r})"
    if isinstance(number, bool) or not isinstance(number, int) or not 1 <= number <= 64:
        raise ConfigurationError(f"{where}: SRDO number must be 1..64, got {number!r}")
    fields = _fields(config, where)
    comm, mapping = COMMUNICATION_BASE + number, MAPPING_BASE + number
    writes = [(comm, 1, b"\x00"), (mapping, 0, b"\x00")]
    writes += [(mapping, sub, struct.pack("<I", entry))
               for sub, entry in enumerate(config.mapping, start=1)]
    writes += [(mapping, 0, bytes([len(config.mapping)])),
               (comm, 2, struct.pack("<H", config.sct_ms)), (comm, 3, bytes([config.srvt_ms])),
               (comm, 4, bytes([fields["transmission_type"]])),
               (comm, 5, struct.pack("<I", config.cob_id)),
               (comm, 6, struct.pack("<I", config.cob_id + 1)),
               (comm, 1, bytes([fields["direction"]])),
               (SIGNATURE_INDEX, number, struct.pack("<H", srdo_signature(config))),
               (VALID_INDEX, 0, bytes([valid]))]
    return writes


class EntryWriter(Protocol):
    """What write_srdo_config writes through: a RemoteNode (SDO / USDO)."""

    def write(self, key: Tuple[int, int], value: bytes) -> None: ...


def write_srdo_config(node: EntryWriter, number: int, config: SrdoConfig, *,
                      valid: int = CONFIG_VALID) -> int:
    """Write SRDO `number`'s configuration, its signature and the valid flag
    to a device (srdo_config_writes, in order); returns the signature."""
    for index, sub, data in srdo_config_writes(number, config, valid=valid):
        node.write((index, sub), data)
    return srdo_signature(config)


class SrdoService(LocalNodeService):
    """The SRDOs and the GFC of our local node (`node.srdo`)."""

    def __init__(self, context: LineContext, read_entry: Callable[[int, int], int]) -> None:
        self._context = context
        self._read_entry = read_entry      # the local node's OD value at (index, sub)
        self._count = 0
        self._configs: Dict[int, SrdoConfig] = {}
        self._callbacks = CallbackList(f"{context.where} SRDO")
        context.subscribe(EventKind.SRDO, self._event)

    def __repr__(self) -> str:
        return f"<SrdoService of {self._where} ({self._count} SRDOs)>"

    def _call_where(self, call: str) -> str:
        return f"srdo {call} on {self._where}"

    def _number(self, number: int, where: str) -> int:
        if isinstance(number, bool) or not isinstance(number, int) or \
                not 1 <= number <= self._count:
            raise ConfigurationError(f"{where}: SRDO number must be 1..{self._count}"
                                     f"{' (start() first)' if not self._count else ''}, "
                                     f"got {number!r}")
        return number

    # ------------------------------------------------------------ set-up
    def start(self, count: int = 1) -> None:
        """Run `count` SRDOs (1..64, all off) and the GFC (off) on the node.
        They follow the node's NMT state: pairs flow in OPERATIONAL only."""
        where = self._call_where(f"start({count!r})")
        if isinstance(count, bool) or not isinstance(count, int) or not 1 <= count <= 64:
            raise ConfigurationError(f"{where}: count must be 1..64, got {count!r}")
        self._context.runtime.srdo_start(self._context.index, count, where)
        self._count = count

    def configure(self, number: int, config: SrdoConfig, *, valid: int = CONFIG_VALID,
                  signature: Optional[int] = None) -> int:
        """Give SRDO `number` its configuration (not while OPERATIONAL) with
        0x13FE = valid and 0x13FF = signature (default: the configuration's
        own CRC). Returns the signature used. A configuration whose valid
        flag or signature does not hold is taken, and the SRDO enters the
        safe state naming it once the node is OPERATIONAL. On a node whose OD
        has the SRDO objects they are written too (the next start runs them)
        and the mapped variables must exist and be mappable."""
        where = self._call_where(f"configure({number!r})")
        self._number(number, where)
        fields = _fields(config, where)
        signature = srdo_signature(config) if signature is None else signature
        if not 0 <= valid <= 0xFF or not 0 <= signature <= 0xFFFF:
            raise ConfigurationError(f"{where}: valid is UNSIGNED8 and signature UNSIGNED16, "
                                     f"got {valid!r}, {signature!r}")
        self._context.runtime.srdo_configure(self._context.index, number, fields,
                                             list(config.mapping), valid, signature, where)
        self._configs[number] = config
        return signature

    def configure_from_od(self, number: int) -> SrdoConfig:
        """Give SRDO `number` the configuration its objects in the node's own
        OD hold (0x1300 + n, 0x1380 + n, 0x13FE, 0x13FF sub n: written by a
        configuration tool, see write_srdo_config), as configure() takes it;
        returns that configuration. The OD must have these objects. Not
        needed any more: such a node follows its objects by itself (kept for
        reading them back as an SrdoConfig)."""
        where = self._call_where(f"configure_from_od({number!r})")
        self._number(number, where)
        comm, mapping = COMMUNICATION_BASE + number, MAPPING_BASE + number
        try:
            direction = self._read_entry(comm, 1)
            config = SrdoConfig(_DIRECTION_NAMES.get(direction, str(direction)),
                                sct_ms=self._read_entry(comm, 2),
                                srvt_ms=self._read_entry(comm, 3),
                                cob_id=self._read_entry(comm, 5),
                                mapping=tuple(self._read_entry(mapping, sub) for sub in
                                              range(1, self._read_entry(mapping, 0) + 1)))
            valid = self._read_entry(VALID_INDEX, 0)
            signature = self._read_entry(SIGNATURE_INDEX, number)
            inverted = self._read_entry(comm, 6)
        except KeyError as missing:
            raise ConfigurationError(f"{where}: the node's OD lacks an SRDO object: "
                                     f"{missing}") from None
        if inverted != config.cob_id + 1:
            raise ConfigurationError(f"{where}: 0x{comm:04X} sub 6 (inverted COB-ID) must be "
                                     f"sub 5 + 1 = 0x{config.cob_id + 1:X}, got 0x{inverted:X}")
        self.configure(number, config, valid=valid, signature=signature)
        return config

    # ------------------------------------------------------------ data
    def set_data(self, number: int, data: bytes) -> None:
        """A producer's data for the next pairs (exactly the mapped length);
        with the SRDO objects in the OD, written into the mapped variables
        (normal bytes and their complement) at once."""
        where = self._call_where(f"set_data({number!r})")
        self._number(number, where)
        self._context.runtime.srdo_set_data(self._context.index, number, bytes(data), where)

    def read(self, number: int) -> SrdoStatus:
        """SRDO `number` now; a consumer's data only while its pairs check."""
        where = self._call_where(f"read({number!r})")
        self._number(number, where)
        state, violation, data, stats = self._context.runtime.srdo_read(
            self._context.index, number, where)
        return SrdoStatus(SrdoState(state), SrdoViolation(violation),
                          data if state == SrdoState.RUNNING and data else None, stats)

    def restart(self, number: int) -> None:
        """Leave the safe state: start as on entering OPERATIONAL (the
        application decides that the cause is gone)."""
        where = self._call_where(f"restart({number!r})")
        self._number(number, where)
        self._context.runtime.srdo_restart(self._context.index, number, where)

    # ------------------------------------------------------------ GFC
    def gfc(self, on: bool = True) -> None:
        """0x1300: send and hear global fail-safe commands (needs start())."""
        self._context.runtime.gfc_enable(self._context.index, bool(on),
                                         self._call_where(f"gfc({on!r})"))

    def send_gfc(self) -> None:
        """Send a GFC: every consumer that hears it enters its safe state."""
        self._context.runtime.gfc_send(self._context.index, self._call_where("send_gfc()"))

    @property
    def gfc_stats(self) -> Dict[str, int]:
        return self._context.runtime.gfc_stats(self._context.index,
                                               self._call_where("gfc_stats"))

    # ------------------------------------------------------------ events
    def add_callback(self, callback: Callable[[SrdoNotice], None]) \
            -> Callable[[SrdoNotice], None]:
        """callback(SrdoNotice) for every safe-state entry of an SRDO."""
        return self._callbacks.add(callback)

    def remove_callback(self, callback: Callable[[SrdoNotice], None]) -> None:
        self._callbacks.remove(callback)

    def _event(self, event: Event) -> Deferred:
        """CO_EV_SRDO: node = SRDO number, a = co_srdo_violation_t."""
        notice = SrdoNotice(event.node, SrdoViolation(event.a))
        return lambda: self._callbacks.fire(notice)
