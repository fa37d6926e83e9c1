"""Exceptions of canopenfd.

Every message names what went wrong and where (node, line/channel, what was
expected and what was given), so a log line alone is enough to fix the call.
"""

from __future__ import annotations


class CanopenFDError(Exception):
    """Base class of every error raised by canopenfd."""


class ConfigurationError(CanopenFDError, ValueError):
    """Wrong use of the API: a value out of range, a second local node on a
    line, a monitor-only call on a normal line, an unknown mode..."""


class InterfaceError(CanopenFDError, OSError):
    """The CAN interface cannot be used: it does not exist, is down, is not a
    CAN interface, or its MTU does not fit the line mode."""


class ClosedError(CanopenFDError, RuntimeError):
    """The network (and so every line and node of it) was closed."""


class CommandError(CanopenFDError):
    """The runtime refused a command for a reason that is not a wrong
    argument (mailbox full, runtime out of memory...)."""
