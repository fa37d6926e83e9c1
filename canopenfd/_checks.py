"""Argument checks shared by lines, nodes and services."""

from __future__ import annotations

import enum
from typing import Type, TypeVar, Union

from .errors import ConfigurationError

__all__ = ["check_node_id", "check_ms", "check_int", "enum_member"]

E = TypeVar("E", bound=enum.IntEnum)


def check_node_id(node_id: object, where: str) -> int:
    """A node-id 1..127 or ConfigurationError naming the value and the place."""
    if isinstance(node_id, bool) or not isinstance(node_id, int):
        raise ConfigurationError(f"{where}: node-id must be an int 1..127, got {node_id!r}")
    if not 1 <= node_id <= 127:
        raise ConfigurationError(f"{where}: node-id {node_id} outside 1..127")
    return node_id


def enum_member(kind: Type[E], value: Union[E, int, str], name: str, where: str) -> E:
    """A member of `kind` given as itself, its value or its name in any case
    ('master', 'ASLEEP'); ConfigurationError listing the names."""
    try:
        return kind[value.upper()] if isinstance(value, str) else kind(value)
    except (KeyError, ValueError):
        raise ConfigurationError(
            f"{where}: {name} must be one of "
            f"{', '.join(member.name.lower() for member in kind)}, got {value!r}") from None


def check_ms(value: object, name: str, where: str) -> int:
    """A time in ms 0..65535 (16-bit CANopen object) or ConfigurationError."""
    if isinstance(value, bool) or not isinstance(value, int):
        raise ConfigurationError(f"{where}: {name} must be an int 0..65535 ms, got {value!r}")
    if not 0 <= value <= 0xFFFF:
        raise ConfigurationError(f"{where}: {name} {value} ms outside 0..65535")
    return value


def check_int(value: object, name: str, low: int, high: int, where: str) -> int:
    """An int low..high (not a bool) or ConfigurationError naming value and place."""
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise ConfigurationError(f"{where}: {name} must be an int {low}..{high:#x}, "
                                 f"got {value!r}")
    return value
