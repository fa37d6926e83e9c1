"""How the C enums become Python enums, and what the NMT enums add to their C members.

`constants` builds each enum at import time from cffi's view of the headers
(`c_enum`); mypy cannot see members made at run time, so it reads
`constants.pyi` instead, which tests/gen_constants_stub.py writes from the very
enums `constants` built (tests/test_typing.py fails when it is stale). The code
that is written by hand lives here, where mypy checks it.
"""

from __future__ import annotations

import enum
from typing import ClassVar, Dict, Iterable, List, Optional, Tuple, Type, TypeVar, Union

from ..errors import ConfigurationError
from .core import ffi, lib

__all__ = ["C_ENUMS", "c_members", "c_enum", "NmtStateBase", "NmtCommandBase"]


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
C_ENUMS: Dict[Type[enum.IntEnum], Tuple[Optional[str], str, Tuple[str, ...]]] = {}


def c_enum(name: str, prefix: str, c_type: Optional[str] = None, *,
           base: Type[enum.IntEnum] = enum.IntEnum, exclude: Tuple[str, ...] = (),
           module: str, doc: str = "") -> Type[enum.IntEnum]:
    """The IntEnum `name` (made in `module`, so it pickles) with the members of a
    C enum (see c_members), registered in C_ENUMS."""
    members = c_members(prefix, c_type, exclude)
    # The functional API, spelled through the metaclass: `base(name, members)`
    # would read to mypy as making a member.
    cls = enum.EnumMeta.__call__(base, name, members, module=module, qualname=name)
    assert issubclass(cls, base)
    cls.__doc__ = doc
    C_ENUMS[cls] = (c_type, prefix, exclude)
    return cls


def _normalise(name: str) -> str:
    """'pre-operational', 'Pre Operational', 'PRE_OPERATIONAL' -> 'PRE_OPERATIONAL'."""
    return name.strip().upper().replace("-", "_").replace(" ", "_")


State = TypeVar("State", bound="NmtStateBase")
Command = TypeVar("Command", bound="NmtCommandBase")


class NmtStateBase(enum.IntEnum):
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
        result = self.__eq__(other)   # int.__eq__ answers NotImplemented for non-ints
        return result if result is NotImplemented else not result

    __hash__ = int.__hash__

    @classmethod
    def parse(cls: Type[State], value: Union[State, int, str]) -> State:
        """An NmtState from itself, its code or its name (any spelling)."""
        if isinstance(value, cls):
            return value
        if isinstance(value, str):
            key = _normalise(value)
            key = {"INITIALIZING": "INITIALISING", "PREOP": "PRE_OPERATIONAL",
                   "PRE_OP": "PRE_OPERATIONAL", "BOOTUP": "INITIALISING",
                   "BOOT_UP": "INITIALISING"}.get(key, key)
            try:
                return cls[key]
            except KeyError:
                raise ConfigurationError(
                    f"NMT state {value!r} unknown: expected one of "
                    "'INITIALISING', 'PRE-OPERATIONAL', 'OPERATIONAL', 'STOPPED'") from None
        if isinstance(value, int) and not isinstance(value, bool):
            try:
                return cls(value)
            except ValueError:
                raise ConfigurationError(
                    f"NMT state 0x{value:02X} unknown: expected 0x00, 0x04, 0x05 or 0x7F"
                ) from None
        raise ConfigurationError(f"NMT state must be a name or a code, got {value!r}")


class NmtCommandBase(enum.IntEnum):
    """What NmtCommand adds to its C members (co_nmt_command_t)."""

    #: The NMT state enum `target` answers in; `constants` sets it once both
    #: enums exist (this module cannot import them: they are made there).
    states: ClassVar[Type[NmtStateBase]]

    @property
    def label(self) -> str:
        """Short spelling used by the CLI and the decoder: 'start', 'reset-comm'..."""
        return _COMMAND_LABELS[self.name]

    @property
    def target(self) -> NmtStateBase:
        """State the command leads to (INITIALISING for the resets: the node
        then boots and is PRE-OPERATIONAL right after)."""
        return self.states[_COMMAND_TARGETS[self.name]]

    @classmethod
    def parse(cls: Type[Command], value: Union[Command, int, str]) -> Command:
        """An NmtCommand from itself, its code, its name, a CLI label
        ('reset-comm') or a python-canopen state name ('OPERATIONAL' = start)."""
        if isinstance(value, cls):
            return value
        if isinstance(value, str):
            key = _normalise(value)
            key = _COMMAND_ALIASES.get(key, key)
            if key in cls.__members__:
                return cls[key]
            raise ConfigurationError(
                f"NMT command {value!r} unknown: expected one of start, stop, "
                "pre-operational, reset-node, reset-comm (or a python-canopen state "
                "name such as 'OPERATIONAL')")
        if isinstance(value, int) and not isinstance(value, bool):
            try:
                return cls(value)
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
