"""Error-status bits and the EMCY code table of the local node (`node.errors`).

    from canopenfd.services.errors import ErrorBit, ErrorRegister

    me = line.create_local_node(1, od=demo_od("classic"))
    me.errors.define(16, 0x2310, ErrorRegister.CURRENT)   # bit 16: over-current
    me.errors.report(16, 0x0042)   # EMCY 10 23 03 10 42 00 00 00, 0x1001 = 0x03
    me.errors.report(16)           # already set: counted, nothing sent
    me.errors.reset(16)            # EMCY 00 00 00 10 00 00 00 00 (error reset)
    me.errors.count(16)            # 2

A bit is one error situation; the code table gives it an EMCY error code and
its error register (0x1001) classes. Bits 0..15 are the stack's own
(`ErrorBit`: CAN overrun, error passive, heartbeat / life guarding, bus-off,
RPDO length, SYNC length, RPDO deadline), the application declares bits
16..127. A report sends one EMCY the first time the bit is set (bytes 0-1
code, 2 error register, 3 the bit, 4-5 the report's code); a reset clears it
and sends the reset EMCY (fd lines: the code marked "removed"). 0x1001 is
derived from one condition per register bit, by default "a set bit of that
class" (`set_condition` changes one). A report setting a communication-class
bit applies the error behaviour 0x1029:01 (0 = leave OPERATIONAL for
PRE-OPERATIONAL, 1 = stay, 2 = STOPPED). `expose(0x2100)` shows the bit
array to the network in an OCTET_STRING entry of the OD, bit n in byte n // 8.
"""

from __future__ import annotations

from typing import Dict, Iterable, List, Tuple

from .._binding.constants import ErrorBit, ErrorRegister
from .._binding.context import LineContext, LocalNodeService
from .._binding.runtime import ErrorsState
from .._checks import check_int
from ..errors import ConfigurationError
from ..od import DataType, ODVariable
from .views import LocalNodeView

__all__ = ["ErrorBits", "ErrorBit", "ErrorRegister", "BITS", "FIRST_APPLICATION_BIT"]

#: Error-status bits (0..BITS-1) and the first one the application may define.
BITS = 128
FIRST_APPLICATION_BIT = 16
_BYTES = BITS // 8
_RESERVED_REGISTER_BIT = 6


class ErrorBits(LocalNodeService):
    """The local node's error-status bits (`local_node.errors`)."""

    def __init__(self, context: LineContext, node: LocalNodeView) -> None:
        self._context = context
        self.node = node

    def __repr__(self) -> str:
        return f"<ErrorBits of {self.node!r}>"

    def _checked_bit(self, bit: object, what: str) -> Tuple[int, str]:
        checked = check_int(bit, "bit", 0, BITS - 1, f"{what} of {self._where}")
        if checked < FIRST_APPLICATION_BIT:
            raise ConfigurationError(
                f"{what} bit {checked} of {self._where}: bits 0..{FIRST_APPLICATION_BIT - 1} "
                f"belong to the stack's own detectors; the application's bits are "
                f"{FIRST_APPLICATION_BIT}..{BITS - 1}")
        where = f"{what} bit {checked} of {self._where}"
        if not self.node.booted:
            raise ConfigurationError(f"{where}: the node is not booted yet")
        return checked, where

    def define(self, bit: int, code: int, register_bits: int = 0) -> None:
        """Declare application bit `bit` (16..127): its EMCY error code
        (1..0xFFFF) and 0x1001 class bits (`ErrorRegister`; generic is added).
        A set bit cannot be redefined (reset it first)."""
        checked, where = self._checked_bit(bit, "define error")
        check_int(code, "code", 1, 0xFFFF, where)
        check_int(register_bits, "register_bits", 0, 0xFF, where)
        if register_bits & (1 << _RESERVED_REGISTER_BIT):
            raise ConfigurationError(f"{where}: register_bits 0x{register_bits:02X} uses bit 6, "
                                     "which CiA 301 reserves")
        self._context.runtime.errors_define(self._context.index, checked, code, register_bits,
                                            where)

    def report(self, bit: int, code: int = 0) -> bool:
        """Set a defined bit; `code` (0..0xFFFF) travels in EMCY bytes 4-5.
        True: newly set, its EMCY sent; False: it was set already (counted,
        nothing sent)."""
        return self._report(bit, code, False) == 0

    def reset(self, bit: int, code: int = 0) -> bool:
        """Clear a bit: the reset EMCY goes out. False (nothing sent) when it
        was clear."""
        return self._report(bit, code, True) == 0

    def _report(self, bit: object, code: object, reset: bool) -> int:
        checked, where = self._checked_bit(bit, "reset error" if reset else "report error")
        info = check_int(code, "code", 0, 0xFFFF, where)
        return self._context.runtime.errors_report(self._context.index, checked, info, reset,
                                                   where)

    def set_condition(self, register_bit: int, bits: Iterable[int]) -> None:
        """0x1001 bit `register_bit` (0..7, not 6) is set while any of `bits`
        is; replaces the code table's default for it."""
        where = f"error register condition of {self._where}"
        check_int(register_bit, "register_bit", 0, 7, where)
        if register_bit == _RESERVED_REGISTER_BIT:
            raise ConfigurationError(f"{where}: register bit 6 is reserved (CiA 301)")
        mask = bytearray(_BYTES)
        for bit in bits:
            check_int(bit, "bit", 0, BITS - 1, where)
            mask[bit // 8] |= 1 << (bit % 8)
        if not self.node.booted:
            raise ConfigurationError(f"{where}: the node is not booted yet")
        self._context.runtime.errors_condition(self._context.index, register_bit, bytes(mask),
                                               where)

    def expose(self, index: int = 0x2100) -> None:
        """Show the bit array to the network in the OD entry index:00, an
        OCTET_STRING (up to 16 bytes; CANopenNode's place is 0x2100): read-only,
        kept up to date. Asked for explicitly, since an OCTET_STRING there may
        be the application's own entry."""
        where = f"expose error bits of {self._where}"
        check_int(index, "index", 1, 0xFFFF, where)
        entry = self.node.od[index] if self.node.od is not None and index in self.node.od \
            else None
        if not isinstance(entry, ODVariable) or entry.data_type != DataType.OCTET_STRING:
            raise ConfigurationError(f"{where}: 0x{index:04X}:00 must be an OCTET_STRING "
                                     f"variable of the node's OD, got {entry!r}")
        if not self.node.booted:
            raise ConfigurationError(f"{where}: the node is not booted yet")
        self._context.runtime.errors_expose(self._context.index, index, where)

    def _state(self) -> ErrorsState:
        where = f"error bits of {self._where}"
        if not self.node.booted:
            raise ConfigurationError(f"{where}: the node is not booted yet")
        return self._context.runtime.errors_state(self._context.index, where)

    @property
    def bits(self) -> bytes:
        """The bit array as 0x2100 holds it: bit n in byte n // 8 at bit n % 8."""
        return self._state().bits

    @property
    def set_bits(self) -> List[int]:
        """The bits set now, ascending."""
        array = self.bits
        return [bit for bit in range(BITS) if array[bit // 8] >> (bit % 8) & 1]

    def is_set(self, bit: int) -> bool:
        check_int(bit, "bit", 0, BITS - 1, f"error bit of {self._where}")
        return bit in self.set_bits

    def count(self, bit: int) -> int:
        """How often `bit` was reported (repetitions included)."""
        check_int(bit, "bit", 0, BITS - 1, f"error count of {self._where}")
        return self._state().counts[bit]

    @property
    def register(self) -> int:
        """The part of 0x1001 the bits make (0x1001 itself: `node.emcy.error_register`)."""
        return self._state().bits_register

    @property
    def table(self) -> Dict[int, Tuple[int, int]]:
        """The code table: {bit: (EMCY code, 0x1001 class bits)} of every defined bit."""
        state = self._state()
        return {bit: (code, state.classes[bit]) for bit, code in enumerate(state.codes) if code}
