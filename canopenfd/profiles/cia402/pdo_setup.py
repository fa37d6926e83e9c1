"""PDO setup of a remote CiA 402 drive for a mode of operation, and the
cyclic synchronous exchange (CSP, CSV, CST) over those PDOs.

Classic lines: RPDO1 controlword, RPDO2 controlword + the mode's target,
TPDO1 statusword, TPDO2 statusword + the mode's actual value. Fd lines: one
RPDO1 and one TPDO1 carrying everything (a CAN FD frame has room for it).
Cyclic modes use synchronous PDOs (type 1): the drive takes the target at a
SYNC and answers with its actual values at the next one; profile modes use
event PDOs (type 255, TPDOs with an event timer)."""

from __future__ import annotations

from typing import Any, Dict, List, Optional, Tuple

from ...errors import ConfigurationError
from .states import Command, mode_name, mode_number

__all__ = ["setup_pdos", "Cyclic"]

# mode: (target, actual) objects
_MODE_OBJECTS: Dict[int, Tuple[int, int]] = {
    1: (0x607A, 0x6064), 3: (0x60FF, 0x606C), 6: (0x6098, 0x6064),
    8: (0x607A, 0x6064), 9: (0x60FF, 0x606C), 10: (0x6071, 0x6077)}
_FD_RPDO = (0x6040, 0x6060, 0x607A, 0x60FF, 0x6071)
_FD_TPDO = (0x6041, 0x6061, 0x6064, 0x606C, 0x6077, 0x603F)
_CYCLIC = (8, 9, 10)
EVENT_TIMER_MS = 10


def _plan(line_mode: str, mode: int) -> List[Tuple[str, int, Tuple[int, ...]]]:
    if line_mode == "fd":
        return [("rpdo", 1, _FD_RPDO), ("tpdo", 1, _FD_TPDO)]
    target, actual = _MODE_OBJECTS[mode]
    return [("rpdo", 1, (0x6040,)), ("rpdo", 2, (0x6040, target)),
            ("tpdo", 1, (0x6041,)), ("tpdo", 2, (0x6041, actual))]


def setup_pdos(node: Any, mode: object) -> Dict[str, Any]:
    """Map the drive's PDOs for `mode` over SDO/USDO (the node needs its OD:
    `line.add_node(id, od=drive_od(...))`). Returns {"rpdo": the PDO carrying
    the target, "tpdo": the one carrying the actual value}."""
    number = mode_number(mode)
    if node.object_dictionary is None:
        raise ConfigurationError(f"drive node {node.id}: setup_pdos({mode!r}) needs the "
                                 f"drive's OD on the remote node (add_node(..., od=...))")
    cyclic = number in _CYCLIC
    chosen: Dict[str, Any] = {}
    for kind, pdo_number, objects in _plan(node.line.mode, number):
        pdo = getattr(node, kind)[pdo_number]
        pdo.read()
        pdo.clear()
        for index in objects:
            pdo.add_variable(index, 0)
        pdo.trans_type = 1 if cyclic else 255
        if kind == "tpdo":
            pdo.event_timer = 0 if cyclic else EVENT_TIMER_MS
        pdo.enabled = True
        pdo.save()
        chosen[kind] = pdo
    return chosen


class Cyclic:
    """A running cyclic synchronous exchange: the master's line produces SYNC
    every `period` s (sync=False: another producer does, e.g. one SYNC for
    many drives) and, after each, the RPDO with the target set here; the
    drive's TPDO brings the actual value and statusword back."""

    def __init__(self, drive: Any, mode: object, period: float, sync: bool = True) -> None:
        self.drive = drive
        self.mode = mode_number(mode)
        if self.mode not in _CYCLIC:
            raise ConfigurationError(f"drive node {drive.node.id}: cyclic({mode!r}): "
                                     f"{mode_name(self.mode)} is not cyclic synchronous "
                                     f"(csp, csv, cst)")
        node = drive.node
        self._target_index, self._actual_index = _MODE_OBJECTS[self.mode]
        drive.set_mode(self.mode)
        pdos = setup_pdos(node, self.mode)
        self.rpdo, self.tpdo = pdos["rpdo"], pdos["tpdo"]
        self._target_name = self._entry(self.rpdo, self._target_index)
        self.controlword_name = self._entry(self.rpdo, 0x6040)
        self.rpdo[self.controlword_name].raw = int(drive.controlword)
        if any(variable.index == 0x6060 for variable in self.rpdo.map):
            self.rpdo[self._entry(self.rpdo, 0x6060)].raw = self.mode
        self._interpolation_period(node, period)
        node.start()                                  # PDOs run in OPERATIONAL
        self.rpdo.start_sync(every=1)
        self.line = node.line
        self._sync = sync
        if sync:
            self.line.sync.start(period)

    @staticmethod
    def _interpolation_period(node: Any, period: float) -> None:
        """0x60C2 = the SYNC period (value * 10^exponent s), when the drive has it."""
        od = node.object_dictionary
        if od.get_variable(0x60C2, 1) is None or od.get_variable(0x60C2, 2) is None:
            return
        for exponent in range(-6, 1):
            value = period / 10.0 ** exponent
            if abs(value - round(value)) < 1e-6 and 1 <= round(value) <= 255:
                node.write((0x60C2, 1), round(value))
                node.write((0x60C2, 2), exponent)
                return

    @staticmethod
    def _entry(pdo: Any, index: int) -> str:
        for variable in pdo.map:
            if variable.index == index:
                return str(variable.name)
        raise ConfigurationError(f"{pdo}: 0x{index:04X} is not mapped")

    @property
    def target(self) -> int:
        return int(self.rpdo[self._target_name].raw)

    @target.setter
    def target(self, value: int) -> None:
        """The next RPDO (after the next SYNC) carries it."""
        self.rpdo[self._target_name].raw = value

    def wait_actual(self, timeout: float = 1.0) -> int:
        """The actual value of the next TPDO received."""
        self.tpdo.wait_for_reception(timeout)
        return int(self.tpdo[self._entry(self.tpdo, self._actual_index)].raw)

    def stop(self) -> None:
        if self._sync:
            self.line.sync.stop()
        self.rpdo.stop()
