"""Exceptions of the object dictionary package.

They live here, not in canopenfd/errors.py, so the OD data model stays a
self-contained, pure-Python package; both derive from `ConfigurationError`, so
code that already catches wrong use of canopenfd catches them too.
"""

from __future__ import annotations

from typing import Optional

from ..errors import ConfigurationError


class OdError(ConfigurationError):
    """Base class of the object dictionary errors."""


class OdValueError(OdError):
    """A value that does not fit an entry: wrong Python type, outside the data
    type's range or the entry's limits, too long, not encodable.

    The message names the entry (when known), what was expected and what was
    given: ``0x1017:00 Producer heartbeat time: 70000 outside UNSIGNED16 0..65535``.
    """

    def __init__(self, problem: str, entry: Optional[str] = None) -> None:
        self.problem = problem
        self.entry = entry
        super().__init__(f"{entry}: {problem}" if entry else problem)

    def at(self, entry: str) -> "OdValueError":
        """The same problem, located at `entry` (unless it already names one)."""
        return self if self.entry else OdValueError(self.problem, entry)


class OdFileError(OdError):
    """An EDS/DCF/XDD/XDC file that cannot be read: the message names the file,
    the line (or section / element) and the problem, e.g.
    ``demo.eds:42 [1018sub2]: DataType 0x0099 is not a CiA 301 data type``."""

    def __init__(self, problem: str, file: str = "<file>", line: Optional[int] = None,
                 where: Optional[str] = None) -> None:
        self.problem = problem
        self.file = file
        self.line = line
        self.where = where
        location = file if line is None else f"{file}:{line}"
        if where:
            location = f"{location} {where}"
        super().__init__(f"{location}: {problem}")


class OdStateError(OdError):
    """A change to a dictionary that a running local node serves: its C
    dictionary was built from the model when the node booted, so an object
    added, replaced or removed afterwards would not be served (the model and
    the node would disagree). The message names the node, the entry and what
    to do instead; the model is left unchanged."""
