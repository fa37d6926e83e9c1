"""The runtime side of a simulated CiA 402 drive: `node.drive_simulation`.

The drive itself is C (csrc/core/co_cia402_sim.c) running in the runtime
thread over the local node's OD, so controlwords and SYNCs are answered
without Python; this service only starts it and injects faults. Building
the drive's OD and PDOs is `canopenfd.profiles.cia402.create_simulated_drive`.
"""

from __future__ import annotations

from .._binding.context import LineContext, LocalNodeService
from ..errors import ConfigurationError

__all__ = ["DriveSimulation"]


class DriveSimulation(LocalNodeService):
    """Start (once) and fault the simulated drive of a local node."""

    def __init__(self, context: LineContext) -> None:
        self._context = context
        self.running = False

    def start(self, tick_ms: float = 1.0) -> None:
        """Run the drive: its profile modes step every `tick_ms`; its cyclic
        modes follow the line's SYNC. The OD must hold the CiA 402 objects."""
        where = f"{self._where}: simulated drive start(tick_ms={tick_ms!r})"
        if isinstance(tick_ms, bool) or not isinstance(tick_ms, (int, float)) or \
                not 0.05 <= tick_ms <= 1000:
            raise ConfigurationError(f"{where}: tick_ms must be a number 0.05..1000")
        self._context.runtime.cia402_sim_start(self._context.index, round(tick_ms * 1000),
                                               where)
        self.running = True

    def fault(self, code: int) -> None:
        """A device fault: 0x603F = code, EMCY sent, Fault reaction active,
        then Fault (the master clears it with a fault reset)."""
        where = f"{self._where}: simulated drive fault(0x{code:04X})" \
            if isinstance(code, int) else f"{self._where}: simulated drive fault({code!r})"
        if isinstance(code, bool) or not isinstance(code, int) or not 1 <= code <= 0xFFFF:
            raise ConfigurationError(f"{where}: the error code must be an int 0x0001..0xFFFF")
        self._context.runtime.cia402_sim_fault(self._context.index, code, where)
