"""Node guarding (classic lines): what it tells about a guarded node.

    drive.guard(100, 3)                        # guard node every 100 ms, 3 misses = lost
    drive.add_guard_callback(print)            # callback(GuardEvent, NmtState)
"""

from __future__ import annotations

import enum
from typing import Optional

from .._binding.constants import GuardEventCode

__all__ = ["GuardEvent"]


class GuardEvent(str, enum.Enum):
    """What node guarding tells about a guarded node (co_guard_event_t)."""

    STARTED = "started"                  # first valid answer
    STATE_CHANGED = "state-changed"      # an answer with another state
    LOST = "lost"                        # life time factor answers missed in a row
    RESUMED = "resumed"                  # a valid answer after LOST
    TOGGLE_ERROR = "toggle-error"        # answer with the wrong toggle bit: not taken
    UNEXPECTED_STATE = "unexpected-state"

    @classmethod
    def from_code(cls, code: int) -> Optional["GuardEvent"]:
        """The event of a co_guard_event_t code, None for an unknown one."""
        try:
            return cls[GuardEventCode(code).name]
        except ValueError:
            return None
