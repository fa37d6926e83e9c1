"""The C stack's enums and constants as Python enums, built from the binding.

cffi knows every enum of the cdef (the headers' `/* cffi:begin */` blocks):
a named enum's members through `ffi.typeof(...)`, an anonymous one's as
`lib.CO_...` names. Each enum here takes its members from there, named as in
C without the prefix (CO_COMM_BUS_OFF -> CommEvent.BUS_OFF), so a value
changed in a header is the value Python uses, and a member renamed or removed
in C is gone here too. tests/test_c_constants.py compares every enum with the
headers and checks that each member the package uses exists in C.

The one enum the cdef lacks (co_guard_event_t) is listed in `_NOT_IN_CDEF`,
checked against its header by the same test.
"""

from __future__ import annotations

import enum
from typing import Dict, Iterable, List, Optional, Tuple, Type, TypeVar, Union

from ..errors import ConfigurationError
from .core import ffi, lib

__all__ = [
    "AbortCode", "CommEvent", "CommandKind", "Driver", "EmcyStatus", "EventKind", "FrameFlag",
    "GuardEventCode", "HeartbeatEvent", "Indicate", "Mode", "NmtCommand", "NmtState",
    "OdOrigin", "ParameterGroup", "RtStatus", "StoreStatus", "C_ENUMS", "c_members",
]

E = TypeVar("E", bound=enum.IntEnum)


def c_members(prefix: str, c_type: Optional[str] = None,
              exclude: Iterable[str] = ()) -> List[Tuple[str, int]]:
    """(name without prefix, value) of a C enum, in value order: the members of
    the named enum `c_type`, or (anonymous enums) every `lib` name starting with
    `prefix` except those starting with prefix + one of `exclude`."""
    if c_type is not None:
        names: Dict[str, int] = dict(ffi.typeof(c_type).relements)
        strays = [name for name in names if not name.startswith(prefix)]
        if strays:   # the prefix is how Python names the members: it must hold for all
            raise ImportError(f"{c_type}: members {strays} do not start with {prefix}")
    else:
        names = {name: getattr(lib, name) for name in dir(lib) if name.startswith(prefix)}
    skipped = tuple(prefix + rest for rest in exclude)
    members = [(name[len(prefix):], value) for name, value in names.items()
               if not (skipped and name.startswith(skipped))]
    return sorted(members, key=lambda member: (member[1], member[0]))


#: Python enum -> (C enum type or None for an anonymous enum, prefix, excluded
#: sub-prefixes): what tests/test_c_constants.py compares with the headers.
C_ENUMS: Dict[type, Tuple[Optional[str], str, Tuple[str, ...]]] = {}


def _c_enum(name: str, prefix: str, c_type: Optional[str] = None, *,
            base: Type[E] = enum.IntEnum,  # type: ignore[assignment]
            exclude: Tuple[str, ...] = (), doc: str = "") -> Type[E]:
    members = c_members(prefix, c_type, exclude)
    cls: Type[E] = base(name, members, module=__name__, qualname=name)  # type: ignore[call-arg]
    cls.__doc__ = doc
    C_ENUMS[cls] = (c_type, prefix, exclude)
    return cls


# ---------------------------------------------------------------- the runtime
EventKind = _c_enum("EventKind", "CO_EV_", "co_rt_event_kind_t",
                    doc="Kinds of the events the runtime posts (co_rt_event_kind_t).")
CommandKind = _c_enum("CommandKind", "CO_CMD_", "co_rt_command_kind_t",
                      doc="Commands of the runtime's mailbox (co_rt_command_kind_t).")
RtStatus = _c_enum("RtStatus", "CO_RT_", "co_rt_status_t",
                   doc="Status codes of the runtime's calls (co_rt_status_t; errors < 0).")
Driver = _c_enum("Driver", "CO_DRIVER_", "co_rt_driver_t",
                 doc="Drivers a line can run on (co_rt_driver_t).")
Indicate = _c_enum("Indicate", "CO_RT_INDICATE_",
                   doc="Kinds of object dictionary requests answered by the application.")

# ---------------------------------------------------------------- lines and frames
Mode = _c_enum("Mode", "CO_MODE_", "co_mode_t", doc="Line modes (co_mode_t).")
CommEvent = _c_enum("CommEvent", "CO_COMM_", "co_comm_event_t",
                    doc="Communication-state events of a line (co_comm_event_t).")
FrameFlag = _c_enum("FrameFlag", "CO_FRAME_", exclude=("MAX_DATA", "CLASSIC_MAX"),
                    doc="Flag bits of co_frame_t.flags.")

# ---------------------------------------------------------------- NMT and heartbeat


def _normalise(name: str) -> str:
    """'pre-operational', 'Pre Operational', 'PRE_OPERATIONAL' -> 'PRE_OPERATIONAL'."""
    return name.strip().upper().replace("-", "_").replace(" ", "_")


class _NmtStateBase(enum.IntEnum):
    """What NmtState adds to its C members (co_nmt_state_t)."""

    @property
    def label(self) -> str:
        """The python-canopen spelling: 'PRE-OPERATIONAL', 'OPERATIONAL', ..."""
        return self.name.replace("_", "-")

    def __str__(self) -> str:
        return self.label

    def __eq__(self, other: object) -> bool:
        # python-canopen compares states with strings: keep that working.
        if isinstance(other, str):
            try:
                return self is type(self).parse(other)
            except ConfigurationError:
                return False
        return int.__eq__(self, other)

    def __ne__(self, other: object) -> bool:
        result = self.__eq__(other)
        return result if result is NotImplemented else not result

    __hash__ = int.__hash__

    @classmethod
    def parse(cls, value: Union["_NmtStateBase", int, str]) -> "NmtState":
        """An NmtState from itself, its code or its name (any spelling)."""
        if isinstance(value, cls):
            return value  # type: ignore[return-value]
        if isinstance(value, str):
            key = _normalise(value)
            key = {"INITIALIZING": "INITIALISING", "PREOP": "PRE_OPERATIONAL",
                   "PRE_OP": "PRE_OPERATIONAL", "BOOTUP": "INITIALISING",
                   "BOOT_UP": "INITIALISING"}.get(key, key)
            try:
                return cls[key]  # type: ignore[return-value]
            except KeyError:
                raise ConfigurationError(
                    f"NMT state {value!r} unknown: expected one of "
                    "'INITIALISING', 'PRE-OPERATIONAL', 'OPERATIONAL', 'STOPPED'") from None
        if isinstance(value, int) and not isinstance(value, bool):
            try:
                return cls(value)  # type: ignore[return-value]
            except ValueError:
                raise ConfigurationError(
                    f"NMT state 0x{value:02X} unknown: expected 0x00, 0x04, 0x05 or 0x7F"
                ) from None
        raise ConfigurationError(f"NMT state must be a name or a code, got {value!r}")


class _NmtCommandBase(enum.IntEnum):
    """What NmtCommand adds to its C members (co_nmt_command_t)."""

    @property
    def label(self) -> str:
        """Short spelling used by the CLI and the decoder: 'start', 'reset-comm'..."""
        return _COMMAND_LABELS[self.name]

    @property
    def target(self) -> "NmtState":
        """State the command leads to (INITIALISING for the resets: the node
        then boots and is PRE-OPERATIONAL right after)."""
        return NmtState[_COMMAND_TARGETS[self.name]]

    @classmethod
    def parse(cls, value: Union["_NmtCommandBase", int, str]) -> "NmtCommand":
        """An NmtCommand from itself, its code, its name, a CLI label
        ('reset-comm') or a python-canopen state name ('OPERATIONAL' = start)."""
        if isinstance(value, cls):
            return value  # type: ignore[return-value]
        if isinstance(value, str):
            key = _normalise(value)
            key = _COMMAND_ALIASES.get(key, key)
            if key in cls.__members__:
                return cls[key]  # type: ignore[return-value]
            raise ConfigurationError(
                f"NMT command {value!r} unknown: expected one of start, stop, "
                "pre-operational, reset-node, reset-comm (or a python-canopen state "
                "name such as 'OPERATIONAL')")
        if isinstance(value, int) and not isinstance(value, bool):
            try:
                return cls(value)  # type: ignore[return-value]
            except ValueError:
                raise ConfigurationError(
                    f"NMT command 0x{value:02X} unknown: expected 0x01, 0x02, 0x80, "
                    "0x81 or 0x82") from None
        raise ConfigurationError(f"NMT command must be a name or a code, got {value!r}")


# By member name, so the tables hold for whatever values C gives the members.
_COMMAND_LABELS = {
    "START": "start",
    "STOP": "stop",
    "PRE_OPERATIONAL": "pre-operational",
    "RESET_NODE": "reset-node",
    "RESET_COMMUNICATION": "reset-comm",
}

_COMMAND_TARGETS = {
    "START": "OPERATIONAL",
    "STOP": "STOPPED",
    "PRE_OPERATIONAL": "PRE_OPERATIONAL",
    "RESET_NODE": "INITIALISING",
    "RESET_COMMUNICATION": "INITIALISING",
}

# Every other spelling people use: CLI labels and python-canopen's NMT_COMMANDS keys.
_COMMAND_ALIASES = {
    "OPERATIONAL": "START",
    "STOPPED": "STOP",
    "PRE_OP": "PRE_OPERATIONAL",
    "PREOP": "PRE_OPERATIONAL",
    "ENTER_PRE_OPERATIONAL": "PRE_OPERATIONAL",
    "INITIALISING": "RESET_NODE",
    "INITIALIZING": "RESET_NODE",
    "RESET": "RESET_NODE",
    "RESET_COMM": "RESET_COMMUNICATION",
}

NmtState = _c_enum(
    "NmtState", "CO_NMT_", "co_nmt_state_t", base=_NmtStateBase,
    doc="NMT state of a node, as carried by its heartbeat (CiA 301); UNKNOWN: never "
        "heard of (remote nodes only). Compares equal to its python-canopen names.")
NmtCommand = _c_enum("NmtCommand", "CO_NMT_CMD_", "co_nmt_command_t", base=_NmtCommandBase,
                     doc="NMT command specifiers (CiA 301).")
HeartbeatEvent = _c_enum("HeartbeatEvent", "CO_HB_", "co_hb_event_t",
                         doc="What the heartbeat consumer reports of a node (co_hb_event_t).")

# ---------------------------------------------------------------- object dictionary
AbortCode = _c_enum("AbortCode", "CO_ABORT_", "co_abort_t",
                    doc="CiA 301 SDO abort codes (co_abort_t).")
ParameterGroup = _c_enum("ParameterGroup", "CO_GROUP_", "enum co_od_group",
                         doc="Parameter groups of 0x1010 / 0x1011 (bit masks).")
OdOrigin = _c_enum("OdOrigin", "CO_ORIGIN_", "co_od_origin_t",
                   doc="Who wrote an object dictionary entry (co_od_origin_t).")
StoreStatus = _c_enum("StoreStatus", "CO_STORE_", "co_store_status_t",
                      doc="What a parameter load found in the store (co_store_status_t).")

# ---------------------------------------------------------------- EMCY
EmcyStatus = _c_enum("EmcyStatus", "CO_EMCY_STATUS_",
                     doc="Bits of the FD EMCY's status byte (priority mask and flags).")

# ---------------------------------------------------------------- not in the cdef
# C enums the binding does not carry (they are outside the headers' cffi
# blocks): written out here, checked against the header by
# tests/test_c_constants.py. Once the enum moves into its header's cffi block,
# build it with _c_enum like the others.
_NOT_IN_CDEF: Dict[str, Tuple[str, Dict[str, int]]] = {
    "GuardEventCode": ("co_guard_event_t / CO_GUARD_", {
        "STARTED": 1, "STATE_CHANGED": 2, "LOST": 3, "RESUMED": 4, "TOGGLE_ERROR": 5,
        "UNEXPECTED_STATE": 6}),
}

GuardEventCode = enum.IntEnum(  # type: ignore[misc]
    "GuardEventCode", list(_NOT_IN_CDEF["GuardEventCode"][1].items()), module=__name__,
    qualname="GuardEventCode")
GuardEventCode.__doc__ = "What node guarding reports of a guarded node (co_guard_event_t)."
