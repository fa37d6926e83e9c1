"""`Drive`: a master's control of a remote CiA 402 drive over SDO (classic
lines) or USDO (fd lines): the power state machine, modes of operation,
profile moves, homing. Every wait has a deadline; a timeout names the node,
the state wanted and the state reached; a fault names 0x603F's code.

    drive = Drive(line.add_node(5))
    drive.enable(timeout=2)
    drive.set_mode("profile_position")
    drive.move_to(1000, velocity=500)
"""

from __future__ import annotations

import struct
import time
from typing import Any, Callable, Dict, Optional, Set, Tuple

from ...errors import CanopenFDError
from .pdo_setup import Cyclic, setup_pdos
from .states import (CW_CHANGE_IMMEDIATELY, CW_NEW_SET_POINT, CW_RELATIVE, SW_BIT12,
                     SW_TARGET_REACHED, Command, DriveState, decode_state, mode_name,
                     mode_number)

__all__ = ["Drive", "DriveError", "DriveTimeoutError", "DriveFaultError"]

_FORMATS = {"u8": "<B", "i8": "<b", "u16": "<H", "i16": "<h", "u32": "<I", "i32": "<i"}
# the width and sign of each object the helper touches
_TYPES = {0x603F: "u16", 0x6040: "u16", 0x6041: "u16", 0x6060: "i8", 0x6061: "i8",
          0x6064: "i32", 0x606C: "i32", 0x6071: "i16", 0x6077: "i16", 0x607A: "i32",
          0x6081: "u32", 0x6083: "u32", 0x6084: "u32", 0x6098: "i8", 0x60FF: "i32"}


class DriveError(CanopenFDError):
    """A drive did not do what it was told."""


class DriveTimeoutError(DriveError):
    """The wanted state or event did not come in time; `reached` is the state
    the drive was in at the deadline."""

    def __init__(self, message: str, wanted: str, reached: DriveState) -> None:
        super().__init__(message)
        self.wanted = wanted
        self.reached = reached


class DriveFaultError(DriveError):
    """The drive is in Fault (or its reaction): `code` is 0x603F."""

    def __init__(self, message: str, code: int, state: DriveState) -> None:
        super().__init__(message)
        self.code = code
        self.state = state


#: enable() sends a step's controlword again after this long without its state.
RESEND_S = 0.1

# Which controlword moves each state one step towards Operation enabled.
_TOWARDS_ENABLED = {
    DriveState.SWITCH_ON_DISABLED: Command.SHUTDOWN,
    DriveState.READY_TO_SWITCH_ON: Command.SWITCH_ON,
    DriveState.SWITCHED_ON: Command.ENABLE_OPERATION,
    DriveState.QUICK_STOP_ACTIVE: Command.ENABLE_OPERATION,
}


class Drive:
    """Control of one remote CiA 402 drive (a RemoteNode of a line)."""

    def __init__(self, node: Any, *, timeout: float = 2.0, poll_s: float = 0.005) -> None:
        self.node = node
        self.timeout = timeout
        self.poll_s = poll_s
        self.controlword = 0      # the last one written
        self._cyclic: Optional[Cyclic] = None

    def __repr__(self) -> str:
        return f"<Drive node {self.node.id}>"

    # ------------------------------------------------------------ access
    def read(self, index: int) -> int:
        value = self.node.read((index, 0))
        if isinstance(value, (bytes, bytearray)):
            fmt = _FORMATS[_TYPES[index]]
            return int(struct.unpack(fmt, bytes(value)[:struct.calcsize(fmt)])[0])
        return int(value)

    def write(self, index: int, value: int) -> None:
        if self.node.object_dictionary is not None and \
                self.node.object_dictionary.get_variable(index, 0) is not None:
            self.node.write((index, 0), value)
        else:
            self.node.write((index, 0), struct.pack(_FORMATS[_TYPES[index]], value))

    def command(self, controlword: int) -> None:
        if self._cyclic is not None:
            # the cyclic RPDO is the controlword's one writer (an SDO write would
            # race the RPDO frames in flight): the drive takes it at the next SYNC
            self._cyclic.rpdo[self._cyclic.controlword_name].raw = int(controlword)
        else:
            self.write(0x6040, controlword)
        self.controlword = controlword

    # ------------------------------------------------------------ state
    @property
    def statusword(self) -> int:
        return self.read(0x6041)

    @property
    def state(self) -> DriveState:
        return decode_state(self.statusword)

    @property
    def error_code(self) -> int:
        return self.read(0x603F)

    @property
    def position(self) -> int:
        return self.read(0x6064)

    @property
    def velocity(self) -> int:
        return self.read(0x606C)

    def _where(self) -> str:
        return f"drive node {self.node.id}"

    def _fault(self, state: DriveState, doing: str) -> DriveFaultError:
        code = self.error_code
        return DriveFaultError(f"{self._where()}: {state} during {doing}: error code "
                               f"0x{code:04X} (0x603F)", code, state)

    def _sample(self) -> Tuple[float, int]:
        """(when the read was asked, statusword). The value is the drive's at
        about the asking moment: on a loaded host the answer can come back
        seconds later, so deadlines compare with the asking time."""
        asked = time.monotonic()
        return asked, self.statusword

    def _wait(self, wanted: str, done: Callable[[int], bool], timeout: Optional[float],
              doing: str, faults: bool = True) -> int:
        """Poll the statusword until done(statusword); a fault raises at once.
        Times out only on a statusword asked for after the deadline."""
        limit = self.timeout if timeout is None else timeout
        deadline = time.monotonic() + limit
        while True:
            asked, sw = self._sample()
            if done(sw):
                return sw
            state = decode_state(sw)
            if faults and state in (DriveState.FAULT, DriveState.FAULT_REACTION_ACTIVE):
                raise self._fault(state, doing)
            if asked >= deadline:
                raise DriveTimeoutError(
                    f"{self._where()}: {doing}: wanted {wanted}, state reached {state} "
                    f"(statusword 0x{sw:04X}) after {limit:g} s", wanted, state)
            time.sleep(self.poll_s)

    def wait_for_state(self, state: DriveState, timeout: Optional[float] = None,
                       doing: str = "") -> None:
        self._wait(str(state), lambda sw: decode_state(sw) is state, timeout,
                   doing or f"waiting for {state}",
                   faults=state not in (DriveState.FAULT, DriveState.FAULT_REACTION_ACTIVE))

    # ------------------------------------------------------------ power
    def enable(self, timeout: Optional[float] = None) -> None:
        """Walk to Operation enabled (shutdown, switch on, enable operation).
        Each state on the way has `timeout` s from its controlword being
        sent; it times out only on a statusword asked for after that (a slow
        read started earlier may show a state the drive has already left).
        A drive in Fault raises DriveFaultError: call fault_reset() first."""
        limit = self.timeout if timeout is None else timeout
        deadline = 0.0
        sent_at = 0.0
        seen: Set[DriveState] = set()
        while True:
            asked, sw = self._sample()
            state = decode_state(sw)
            if state is DriveState.OPERATION_ENABLED:
                return
            if state in (DriveState.FAULT, DriveState.FAULT_REACTION_ACTIVE):
                raise self._fault(state, "enable()")
            # a state not seen before in this walk is progress, however late
            # it is heard: it gets a whole budget (at most one per state, so
            # the walk ends)
            new = state not in seen
            if new:
                seen.add(state)
                deadline = time.monotonic() + limit
            elif asked >= deadline:
                raise DriveTimeoutError(
                    f"{self._where()}: enable(): wanted {DriveState.OPERATION_ENABLED}, "
                    f"state reached {state} {limit:g} s after controlword "
                    f"0x{self.controlword:04X} was sent", str(DriveState.OPERATION_ENABLED),
                    state)
            step = _TOWARDS_ENABLED.get(state)
            # sent again when the state did not follow: another writer (an RPDO
            # still in flight with an older controlword) may have undone it
            if step is not None and (new or self.controlword != step or
                                     time.monotonic() - sent_at > RESEND_S):
                self.command(step)
                sent_at = time.monotonic()
                if new:
                    deadline = sent_at + limit
            time.sleep(self.poll_s)

    def _power(self, command: Command, wanted: DriveState, timeout: Optional[float],
               doing: str) -> None:
        self.command(command)
        self.wait_for_state(wanted, timeout, doing)

    def shutdown(self, timeout: Optional[float] = None) -> None:
        """To Ready to switch on (power stage off, voltage on)."""
        self._power(Command.SHUTDOWN, DriveState.READY_TO_SWITCH_ON, timeout, "shutdown()")

    def switch_on(self, timeout: Optional[float] = None) -> None:
        self._power(Command.SWITCH_ON, DriveState.SWITCHED_ON, timeout, "switch_on()")

    def disable_voltage(self, timeout: Optional[float] = None) -> None:
        self._power(Command.DISABLE_VOLTAGE, DriveState.SWITCH_ON_DISABLED, timeout,
                    "disable_voltage()")

    def quick_stop(self, timeout: Optional[float] = None) -> None:
        """Operation enabled: to Quick stop active; else to Switch on disabled."""
        wanted = DriveState.QUICK_STOP_ACTIVE if self.state is DriveState.OPERATION_ENABLED \
            else DriveState.SWITCH_ON_DISABLED
        self._power(Command.QUICK_STOP, wanted, timeout, "quick_stop()")

    def fault_reset(self, timeout: Optional[float] = None) -> None:
        """A rising edge of controlword bit 7: Fault to Switch on disabled
        (a fault reaction in progress is waited out first)."""
        if self.state is DriveState.FAULT_REACTION_ACTIVE:
            self.wait_for_state(DriveState.FAULT, timeout, "fault_reset()")
        self.command(Command.DISABLE_VOLTAGE)
        self.command(Command.FAULT_RESET)
        self._wait(str(DriveState.SWITCH_ON_DISABLED),
                   lambda sw: decode_state(sw) is DriveState.SWITCH_ON_DISABLED, timeout,
                   "fault_reset()", faults=False)
        self.command(Command.DISABLE_VOLTAGE)

    # ------------------------------------------------------------ modes
    def set_mode(self, mode: object, timeout: Optional[float] = None) -> None:
        """Write 0x6060 and wait until 0x6061 shows it."""
        number = mode_number(mode)
        self.write(0x6060, number)
        limit = self.timeout if timeout is None else timeout
        deadline = time.monotonic() + limit
        while self.read(0x6061) != number:
            if time.monotonic() >= deadline:
                raise DriveTimeoutError(
                    f"{self._where()}: set_mode({mode!r}): 0x6061 shows "
                    f"{mode_name(self.read(0x6061))} after {limit:g} s", mode_name(number),
                    self.state)
            time.sleep(self.poll_s)

    @property
    def mode(self) -> str:
        return mode_name(self.read(0x6061))

    def _require(self, number: int, doing: str) -> None:
        shown = self.read(0x6061)
        if shown != number:
            raise DriveError(f"{self._where()}: {doing} needs mode {mode_name(number)}, the "
                             f"drive is in {mode_name(shown)}: call set_mode() first")
        state = self.state
        if state is not DriveState.OPERATION_ENABLED:
            if state in (DriveState.FAULT, DriveState.FAULT_REACTION_ACTIVE):
                raise self._fault(state, doing)
            raise DriveError(f"{self._where()}: {doing} needs {DriveState.OPERATION_ENABLED}, "
                             f"the drive is in {state}: call enable() first")

    def move_to(self, position: int, *, velocity: Optional[int] = None,
                acceleration: Optional[int] = None, deceleration: Optional[int] = None,
                relative: bool = False, immediately: bool = True, wait: bool = True,
                timeout: Optional[float] = None) -> None:
        """Profile position move: set-point, new set-point bit 4, the drive's
        acknowledge (bit 12), bit 4 cleared; with wait, until target reached
        (bit 10). A fault on the way raises DriveFaultError naming 0x603F."""
        doing = f"move_to({position})"
        self._require(1, doing)
        for index, value in ((0x6081, velocity), (0x6083, acceleration),
                             (0x6084, deceleration)):
            if value is not None:
                self.write(index, value)
        self.write(0x607A, position)
        base = int(Command.ENABLE_OPERATION) | (CW_RELATIVE if relative else 0) | \
            (CW_CHANGE_IMMEDIATELY if immediately else 0)
        self.command(base | CW_NEW_SET_POINT)
        self._wait("set-point acknowledge (bit 12)", lambda sw: bool(sw & SW_BIT12), timeout,
                   doing)
        self.command(base)
        if wait:
            self._wait("target reached (bit 10)",
                       lambda sw: decode_state(sw) is DriveState.OPERATION_ENABLED and
                       bool(sw & SW_TARGET_REACHED) and not sw & SW_BIT12, timeout, doing)

    def set_velocity(self, velocity: int, *, acceleration: Optional[int] = None,
                     wait: bool = False, timeout: Optional[float] = None) -> None:
        """Profile velocity: the target velocity 0x60FF; with wait, until reached."""
        doing = f"set_velocity({velocity})"
        self._require(3, doing)
        if acceleration is not None:
            self.write(0x6083, acceleration)
        self.write(0x60FF, velocity)
        if wait:
            self._wait("target velocity reached (bit 10)",
                       lambda sw: bool(sw & SW_TARGET_REACHED), timeout, doing)

    def home(self, method: int = 35, timeout: Optional[float] = None) -> None:
        """Homing mode, method 0x6098, start (bit 4), until homing attained (bit 12)."""
        doing = f"home(method={method})"
        self.set_mode("homing", timeout)
        self._require(6, doing)
        self.write(0x6098, method)
        self.command(int(Command.ENABLE_OPERATION) | CW_NEW_SET_POINT)
        self._wait("homing attained (bits 10, 12)",
                   lambda sw: sw & (SW_BIT12 | SW_TARGET_REACHED) == SW_BIT12 | SW_TARGET_REACHED,
                   timeout, doing)
        self.command(Command.ENABLE_OPERATION)

    # ------------------------------------------------------------ PDOs
    def setup_pdos(self, mode: object) -> Dict[str, Any]:
        """Map the drive's PDOs for `mode` (see pdo_setup): {"rpdo", "tpdo"}."""
        return setup_pdos(self.node, mode)

    def cyclic(self, mode: object, period: float = 0.001, sync: bool = True) -> Cyclic:
        """Cyclic synchronous position, velocity or torque: mode set, PDOs
        mapped (synchronous), the node started, SYNC every `period` s from
        the master's line (sync=False: the caller runs SYNC, once for many
        drives) and the target RPDO after each. Then enable() and set
        `.target`; `.stop()` ends SYNC and the RPDO."""
        if self._cyclic is not None:
            self._cyclic.stop()
        self._cyclic = Cyclic(self, mode, period, sync)
        return self._cyclic

    def stop_cyclic(self) -> None:
        if self._cyclic is not None:
            self._cyclic.stop()
            self._cyclic = None
