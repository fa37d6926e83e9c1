"""The CiA 402 power state machine as the master sees it: the states decoded
from the statusword (0x6041) and the controlword (0x6040) commands that move
between them. Facts and sources: docs/protocol-notes.md, "CiA 402 drive"."""

from __future__ import annotations

import enum
from typing import Dict, Tuple

from ...errors import ConfigurationError

__all__ = ["DriveState", "decode_state", "Command", "MODES", "mode_number", "mode_name",
           "SW_TARGET_REACHED", "SW_BIT12", "CW_NEW_SET_POINT", "CW_CHANGE_IMMEDIATELY",
           "CW_RELATIVE", "CW_FAULT_RESET"]


class DriveState(str, enum.Enum):
    """A power state, spelled as python-canopen's BaseNode402 spells it."""

    NOT_READY_TO_SWITCH_ON = "NOT READY TO SWITCH ON"
    SWITCH_ON_DISABLED = "SWITCH ON DISABLED"
    READY_TO_SWITCH_ON = "READY TO SWITCH ON"
    SWITCHED_ON = "SWITCHED ON"
    OPERATION_ENABLED = "OPERATION ENABLED"
    QUICK_STOP_ACTIVE = "QUICK STOP ACTIVE"
    FAULT_REACTION_ACTIVE = "FAULT REACTION ACTIVE"
    FAULT = "FAULT"
    UNKNOWN = "UNKNOWN"          # a statusword no state matches: the drive is wrong

    def __str__(self) -> str:
        return self.value


# (mask, pattern) per state: four states are told apart by bits 0..3 and 6,
# the other four need bit 5 (quick stop) too.
_PATTERNS: Tuple[Tuple[int, int, DriveState], ...] = (
    (0x4F, 0x00, DriveState.NOT_READY_TO_SWITCH_ON),
    (0x4F, 0x40, DriveState.SWITCH_ON_DISABLED),
    (0x6F, 0x21, DriveState.READY_TO_SWITCH_ON),
    (0x6F, 0x23, DriveState.SWITCHED_ON),
    (0x6F, 0x27, DriveState.OPERATION_ENABLED),
    (0x6F, 0x07, DriveState.QUICK_STOP_ACTIVE),
    (0x4F, 0x0F, DriveState.FAULT_REACTION_ACTIVE),
    (0x4F, 0x08, DriveState.FAULT),
)


def decode_state(statusword: int) -> DriveState:
    for mask, pattern, state in _PATTERNS:
        if statusword & mask == pattern:
            return state
    return DriveState.UNKNOWN


class Command(enum.IntEnum):
    """Controlword values of the power commands (bits 0..3, 7)."""

    DISABLE_VOLTAGE = 0x00
    QUICK_STOP = 0x02
    SHUTDOWN = 0x06
    SWITCH_ON = 0x07
    ENABLE_OPERATION = 0x0F
    FAULT_RESET = 0x80          # acts on the rising edge of bit 7


SW_TARGET_REACHED = 0x0400
SW_BIT12 = 0x1000               # set-point acknowledge / homing attained / speed 0
CW_NEW_SET_POINT = 0x0010
CW_CHANGE_IMMEDIATELY = 0x0020
CW_RELATIVE = 0x0040
CW_FAULT_RESET = 0x0080

#: Modes of operation (0x6060 / 0x6061) by name.
MODES: Dict[str, int] = {
    "profile_position": 1, "profile_velocity": 3, "homing": 6,
    "cyclic_synchronous_position": 8, "cyclic_synchronous_velocity": 9,
    "cyclic_synchronous_torque": 10,
}
_ALIASES = {"pp": 1, "pv": 3, "hm": 6, "csp": 8, "csv": 9, "cst": 10}


def mode_number(mode: object) -> int:
    """0x6060 value of a mode given by name ("csp", "profile_position") or number."""
    if isinstance(mode, str):
        key = mode.lower()
        if key in MODES:
            return MODES[key]
        if key in _ALIASES:
            return _ALIASES[key]
    elif isinstance(mode, int) and not isinstance(mode, bool) and mode in MODES.values():
        return mode
    raise ConfigurationError(f"unknown mode of operation {mode!r}: one of "
                     f"{', '.join(list(MODES) + list(_ALIASES))} or {sorted(MODES.values())}")


def mode_name(number: int) -> str:
    for name, value in MODES.items():
        if value == number:
            return name
    return f"mode {number}"
