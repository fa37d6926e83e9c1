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


#: CiA 301 SDO abort codes and their meaning (USDO uses the same meanings).
ABORT_TEXT = {
    0x05030000: "toggle bit not alternated",
    0x05040000: "SDO protocol timed out",
    0x05040001: "client/server command specifier not valid or unknown",
    0x05040002: "invalid block size",
    0x05040003: "invalid sequence number",
    0x05040004: "CRC error",
    0x05040005: "out of memory",
    0x06010000: "unsupported access to an object",
    0x06010001: "attempt to read a write-only object",
    0x06010002: "attempt to write a read-only object",
    0x06020000: "object does not exist in the object dictionary",
    0x06040041: "object cannot be mapped to the PDO",
    0x06040042: "number and length of mapped objects would exceed the PDO length",
    0x06040043: "general parameter incompatibility",
    0x06040047: "general internal incompatibility in the device",
    0x06060000: "access failed due to a hardware error",
    0x06070010: "data type does not match, length of service parameter does not match",
    0x06070012: "data type does not match, length of service parameter too high",
    0x06070013: "data type does not match, length of service parameter too low",
    0x06090011: "sub-index does not exist",
    0x06090030: "invalid value for parameter",
    0x06090031: "value of parameter written too high",
    0x06090032: "value of parameter written too low",
    0x06090036: "maximum value is less than minimum value",
    0x060A0023: "resource not available: SDO connection",
    0x08000000: "general error",
    0x08000020: "data cannot be transferred or stored to the application",
    0x08000021: "data cannot be transferred or stored because of local control",
    0x08000022: "data cannot be transferred or stored because of the device state",
    0x08000023: "object dictionary dynamic generation failed or no object dictionary",
    0x08000024: "no data available",
}


#: One-byte USDO (CiA 1301) abort codes and their meaning; values and evidence in
#: docs/protocol-notes.md and co_usdo_abort_t (csrc/include/canopenfd/co_usdo.h).
#: 0x71..0xFF are reserved by CiA.
USDO_ABORT_TEXT = {
    0x10: "unknown error",
    0x11: "USDO protocol error",
    0x12: "USDO timed out",
    0x13: "command specifier unknown or unexpected",
    0x14: "invalid segment counter",
    0x15: "data size differs from the size field",
    0x16: "out of memory",
    0x17: "general parameter incompatibility",
    0x18: "general internal incompatibility in the device",
    0x19: "general routing error",
    0x1A: "destination network unknown",
    0x1B: "destination node unknown",
    0x1C: "source network unknown",
    0x1D: "source node unknown",
    0x1E: "unexpected data length",
    0x1F: "multiplexer of the response differs from the request",
    0x20: "parallel access to the same sub-index",
    0x21: "session-ID wrong or unknown",
    0x30: "unsupported access to an object",
    0x31: "attempt to read a write-only object",
    0x32: "attempt to write a read-only object",
    0x33: "object does not exist",
    0x34: "sub-index does not exist",
    0x35: "hardware error",
    0x36: "data type or length does not match",
    0x37: "length too high",
    0x38: "length too low",
    0x40: "invalid value",
    0x41: "value too high",
    0x42: "value too low",
    0x43: "maximum value is less than minimum value",
    0x44: "minimum value is greater than maximum value",
    0x45: "CAN-ID or frame format is read-only",
    0x50: "object cannot be mapped to the PDO",
    0x51: "mapping would exceed the PDO length",
    0x52: "parameter cannot be mapped",
    0x53: "RPDO-only object mapped into a TPDO",
    0x54: "TPDO-only object mapped into an RPDO",
    0x55: "PDO parameters written while the PDO is valid",
    0x56: "PDO mapping written while the mapping is valid",
    0x60: "data cannot be transferred or stored to the application",
    0x61: "data cannot be transferred or stored because of local control",
    0x62: "data cannot be transferred or stored because of the device state",
    0x63: "object dictionary dynamic generation failed or no object dictionary",
    0x64: "no data available",
    0x70: "USDO server busy",
}


class AbortError(CanopenFDError):
    """An object dictionary access was refused with a CiA 301 abort code.

    `code` is the 32-bit abort code, `meaning` its text, `node` the node-id
    and `index` / `subindex` the entry."""

    def __init__(self, code: int, node: int, index: int, subindex: int, what: str = "") -> None:
        self.code = code
        self.meaning = ABORT_TEXT.get(code, "unknown abort code")
        self.node = node
        self.index = index
        self.subindex = subindex
        place = f"node {node} 0x{index:04X}:{subindex:02X}"
        super().__init__(f"{what + ': ' if what else ''}{place}: abort 0x{code:08X} "
                         f"({self.meaning})")


class TransferAbortError(AbortError):
    """A client transfer (SDO or USDO) ended with an abort: `code` (CiA 301),
    `meaning`, `node`, `index`, `subindex`, and `from_server` (else we
    aborted: timeout, cancel, a CRC or size error we detected)."""

    def __init__(self, code: int, meaning: str, shown: str, protocol: str, node: int,
                 index: int, subindex: int, from_server: bool, what: str = "") -> None:
        self.code = code
        self.meaning = meaning
        self.node = node
        self.index = index
        self.subindex = subindex
        self.from_server = from_server
        origin = "server" if from_server else "client"
        place = f"node {node} 0x{index:04X}:{subindex:02X}"
        CanopenFDError.__init__(self, f"{what or place}: {protocol} abort {shown} ({meaning}) "
                                      f"from the {origin}")

