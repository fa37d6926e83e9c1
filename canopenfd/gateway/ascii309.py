"""The CiA 309-3 ASCII protocol: one request line in, one answer line out.

Pure functions, no I/O: `parse_request` turns a line into a `Request` (or
the error `Reply` the gateway sends back), the `format_*` functions make
the answer and event lines, `encode_value` / `format_value` convert between
the protocol's data type notation (u8, x16, r32, vs, os, d, ...) and the
bytes on the bus. Nothing here raises on input: a line of any content and
length gives a Request or an error Reply (the server bounds the length
before it gets here, `MAX_LINE`).

The grammar, as CiA 309-3 and the gateways its users know (CANopenNode's
`cocomm`, Lely's `coctl`) write it::

    [seq] [[net] node] r[ead] index sub [type]
    [seq] [[net] node] w[rite] index sub type value
    [seq] [[net] node] start | stop | preop[erational] | reset node | reset comm[unication]
    [seq] [net] set network N | set node N | set sdo_timeout MS | set sdo_block 0|1
    [seq] info version | help [datatype|lss]
    [seq] [net] lss_switch_glob 0|1 | lss_switch_sel vendor product revision serial
    [seq] [net] lss_set_node N | lss_conf_bitrate 0 index | lss_activate_bitrate MS
    [seq] [net] lss_store | lss_inquire_addr [0..3] | lss_get_node
    [seq] [net] _lss_fastscan [MS] | lss_allnodes [MS [start store [8 scan values]]]

Answers: `[seq] OK`, `[seq] <value>`, `[seq] ERROR: <code> #<text>` (codes
100..600 below) and `[seq] ERROR: 0x<abort code> #<text>` for an SDO/USDO
abort. Numbers are decimal or 0x-hex; '#' starts a comment; commands and
type names are case-insensitive; lines end with LF (a CR before it is
dropped). Layout choices and their evidence: docs/protocol-notes.md,
section "CiA 309-3 ASCII gateway".
"""

from __future__ import annotations

import base64
import binascii
import struct
from typing import Dict, List, NamedTuple, Optional, Tuple, Union

from ..errors import ABORT_TEXT
from ..od.datatypes import DataType, TimeDifference, TimeOfDay, decode, encode, real32_text
from ..od.errors import OdValueError

__all__ = ["ERROR_TEXT", "TYPES", "AsciiType", "Reply", "Request", "MAX_LINE",
           "parse_request", "encode_value", "format_value", "format_ok", "format_error",
           "format_abort", "format_answer", "tokenize", "HELP", "HELP_DATATYPE", "HELP_LSS"]

#: Longest request line the server takes (bytes, terminator included); a
#: longer one is answered with error 101 and skipped. Base64 of a 48 KiB
#: domain fits.
MAX_LINE = 65536

# CiA 309-3 gateway error codes (the standard's names, in our words)
REQUEST_NOT_SUPPORTED = 100
SYNTAX_ERROR = 101
INTERNAL_STATE = 102
TIME_OUT = 103
NO_DEFAULT_NET = 104
NO_DEFAULT_NODE = 105
UNSUPPORTED_NET = 106
UNSUPPORTED_NODE = 107
HEARTBEAT_STARTED = 202
HEARTBEAT_LOST = 203
LSS_MANUFACTURER = 501
LSS_NODE_ID_NOT_SUPPORTED = 502
LSS_BIT_RATE_NOT_SUPPORTED = 503
LSS_STORE_FAILED = 504
LSS_MEDIA_ERROR = 505
OUT_OF_MEMORY = 600

ERROR_TEXT: Dict[int, str] = {
    100: "Request not supported",
    101: "Syntax error",
    102: "Request not processed due to internal state",
    103: "Time-out",
    104: "No default net set",
    105: "No default node set",
    106: "Unsupported net",
    107: "Unsupported node",
    200: "Lost guarding message",
    201: "Lost connection",
    202: "Heartbeat started",
    203: "Heartbeat lost",
    204: "Wrong NMT state",
    205: "Boot-up",
    300: "Error passive",
    301: "Bus off",
    303: "CAN buffer overflow",
    304: "CAN init",
    305: "CAN active (at init or start-up)",
    400: "PDO already used",
    401: "PDO length exceeded",
    501: "LSS implementation- / manufacturer-specific error",
    502: "LSS node-ID not supported",
    503: "LSS bit-rate not supported",
    504: "LSS parameter storing failed",
    505: "LSS command failed because of media error",
    600: "Running out of memory",
}

_U32 = 0xFFFFFFFF


# ---------------------------------------------------------------- answers
class Reply(NamedTuple):
    """An answer line (without its CR LF) for sequence `seq`."""

    seq: int
    text: str


def format_ok(seq: int) -> str:
    return f"[{seq}] OK"


def format_answer(seq: int, value: str) -> str:
    return f"[{seq}] {value}"


def format_error(seq: int, code: int, detail: str = "") -> str:
    """`[seq] ERROR: 101 #Syntax error` (detail: appended after a colon)."""
    text = ERROR_TEXT.get(code, "-")
    detail = " ".join(detail.split())      # one line, whatever the detail held
    return f"[{seq}] ERROR: {code} #{text}{': ' + detail if detail else ''}"


def format_abort(seq: int, code: int) -> str:
    """`[seq] ERROR: 0x06020000 #Object does not exist ...` (CiA 301 abort code)."""
    return f"[{seq}] ERROR: 0x{code:08X} #{ABORT_TEXT.get(code, 'unknown abort code')}"


def _error(seq: int, code: int, detail: str = "") -> Reply:
    return Reply(seq, format_error(seq, code, detail))


# ---------------------------------------------------------------- data types
class AsciiType(NamedTuple):
    """A data type of the protocol: its name, the CiA 301 type it carries, and
    whether integers print as hex (x8..x64, a CANopenNode extension)."""

    name: str
    data_type: DataType
    hex_digits: int = 0


TYPES: Dict[str, AsciiType] = {t.name: t for t in (
    AsciiType("b", DataType.BOOLEAN),
    AsciiType("i8", DataType.INTEGER8), AsciiType("i16", DataType.INTEGER16),
    AsciiType("i32", DataType.INTEGER32), AsciiType("i64", DataType.INTEGER64),
    AsciiType("u8", DataType.UNSIGNED8), AsciiType("u16", DataType.UNSIGNED16),
    AsciiType("u32", DataType.UNSIGNED32), AsciiType("u64", DataType.UNSIGNED64),
    AsciiType("x8", DataType.UNSIGNED8, 2), AsciiType("x16", DataType.UNSIGNED16, 4),
    AsciiType("x32", DataType.UNSIGNED32, 8), AsciiType("x64", DataType.UNSIGNED64, 16),
    AsciiType("r32", DataType.REAL32), AsciiType("r64", DataType.REAL64),
    AsciiType("t", DataType.TIME_OF_DAY), AsciiType("td", DataType.TIME_DIFFERENCE),
    AsciiType("vs", DataType.VISIBLE_STRING), AsciiType("os", DataType.OCTET_STRING),
    AsciiType("us", DataType.UNICODE_STRING), AsciiType("d", DataType.DOMAIN),
    # not in CiA 309-3: bytes as hex pairs (CANopenNode's "hex"); also what a
    # read without a type prints
    AsciiType("hex", DataType.DOMAIN),
)}

#: The protocol's type for a CiA 301 type code a USDO server sent with its data.
TYPE_OF_CODE: Dict[int, AsciiType] = {
    int(t.data_type): t for t in TYPES.values() if not t.hex_digits and t.name != "hex"}

_BASE64_TYPES = ("os", "us", "d")
_ESCAPES = {"\\": "\\\\", "\n": "\\n", "\r": "\\r", "\t": "\\t", '"': '""'}
_UNESCAPE = {"\\": "\\", "n": "\n", "r": "\r", "t": "\t"}


def _parse_int(text: str) -> Optional[int]:
    """Decimal or 0x-hex (a leading sign allowed), else None."""
    body = text[1:] if text[:1] in ("+", "-") else text
    if body[:2].lower() == "0x":
        digits, allowed, base = body[2:], "0123456789abcdefABCDEF", 16
    else:
        digits, allowed, base = body, "0123456789", 10
    if not digits or len(digits) > 24 or any(c not in allowed for c in digits):
        return None
    value = int(digits, base)
    return -value if text[:1] == "-" else value


def _quote(data: bytes) -> str:
    """A visible string as one token: in double quotes, a quote doubled,
    backslash, CR, LF, tab as C escapes, other control and non-ASCII bytes as
    \\xHH, so any bytes survive one line and come back the same."""
    out = ['"']
    for byte in data:
        char = chr(byte)
        if char in _ESCAPES:
            out.append(_ESCAPES[char])
        elif byte < 0x20 or byte >= 0x7F:
            out.append(f"\\x{byte:02X}")
        else:
            out.append(char)
    out.append('"')
    return "".join(out)


def _unquote(token: str) -> Optional[bytes]:
    """The bytes of a vs token (quoted or a bare word), None when malformed."""
    if not token.startswith('"'):
        body = token
    elif len(token) >= 2 and token.endswith('"'):
        body = token[1:-1]
    else:
        return None
    out = bytearray()
    i = 0
    while i < len(body):
        char = body[i]
        if char == '"':
            if body[i + 1:i + 2] != '"':
                return None
            out.append(0x22)
            i += 2
            continue
        if char == "\\":
            code = body[i + 1:i + 2]
            if code in _UNESCAPE:
                out += _UNESCAPE[code].encode()
                i += 2
                continue
            if code == "x" and len(body) >= i + 4:
                try:
                    out.append(int(body[i + 2:i + 4], 16))
                except ValueError:
                    return None
                i += 4
                continue
            return None
        if ord(char) > 0xFF:
            out += char.encode("utf-8")
        else:
            out.append(ord(char))
        i += 1
    return bytes(out)


def _float_text(value: float, single: bool) -> str:
    """The shortest decimal that reads back as the same float (REAL32: the
    same 32-bit value)."""
    return real32_text(value) if single else repr(value)


def format_value(kind: AsciiType, data: bytes) -> str:
    """The text of `data` read as `kind`; bytes that do not fit the type's
    size print as hex pairs (as CANopenNode does), never an error."""
    dtype = kind.data_type
    if kind.name == "hex":
        return " ".join(f"{b:02X}" for b in data)
    if kind.name == "vs":
        return _quote(data)
    if kind.name in _BASE64_TYPES:
        return base64.b64encode(data).decode("ascii")
    size = dtype.size
    if size is None or len(data) != size:
        return " ".join(f"{b:02X}" for b in data)
    try:
        value = decode(dtype, data)
    except OdValueError:
        return " ".join(f"{b:02X}" for b in data)
    if isinstance(value, bool):
        return "1" if value else "0"
    if isinstance(value, int):
        if kind.hex_digits:
            return f"0x{value:0{kind.hex_digits}X}"
        return str(value)
    if isinstance(value, float):
        return _float_text(value, dtype == DataType.REAL32)
    if isinstance(value, (TimeOfDay, TimeDifference)):
        return f"{value.ms} {value.days}"
    return " ".join(f"{b:02X}" for b in data)


def encode_value(kind: AsciiType, tokens: List[str]) -> Union[bytes, str]:
    """The bytes of a written value (its tokens), or the reason it is not one."""
    name, dtype = kind.name, kind.data_type
    if dtype in (DataType.TIME_OF_DAY, DataType.TIME_DIFFERENCE):
        if len(tokens) != 2:
            return f"{name} takes two numbers: milliseconds and days"
        ms, days = _parse_int(tokens[0]), _parse_int(tokens[1])
        if ms is None or days is None:
            return f"{name} value {' '.join(tokens)!r} is not two numbers"
        try:
            cls = TimeOfDay if dtype == DataType.TIME_OF_DAY else TimeDifference
            return encode(dtype, cls(ms, days))
        except (OdValueError, ValueError, TypeError) as exc:
            return str(exc)
    if name == "hex":
        text = "".join(tokens)
        if len(text) % 2 or not all(c in "0123456789abcdefABCDEF" for c in text):
            return "hex data must be pairs of hex digits"
        return bytes.fromhex(text)
    if len(tokens) != 1:
        return (f"{name} takes one value, got {len(tokens)} tokens" +
                (" (quote a visible string with spaces)" if name == "vs" else ""))
    token = tokens[0]
    if name == "vs":
        data = _unquote(token)
        return data if data is not None else f"malformed visible string {token!r}"
    if name in _BASE64_TYPES:
        body = token[1:-1] if len(token) >= 2 and token[0] == token[-1] == '"' else token
        try:
            return base64.b64decode(body, validate=True)
        except (binascii.Error, ValueError):
            return f"{name} value is not base64 (RFC 2045, one line)"
    if dtype.is_real:
        try:
            number = float(token)
        except ValueError:
            return f"{token!r} is not a real number"
        try:
            return encode(dtype, number)
        except (OdValueError, OverflowError, struct.error) as exc:
            return str(exc)
    value = _parse_int(token)
    if value is None:
        return f"{token!r} is not a number (decimal or 0x hex)"
    if dtype == DataType.BOOLEAN:
        if value not in (0, 1):
            return f"boolean {token!r} is not 0 or 1"
        return bytes([value])
    if not dtype.min <= value <= dtype.max:  # type: ignore[operator]
        return f"{token} is outside {name} ({dtype.min}..{dtype.max})"
    try:
        return encode(dtype, value)
    except OdValueError as exc:
        return str(exc)


# ---------------------------------------------------------------- requests
class Request(NamedTuple):
    """One parsed request. net/node: as given on the line (None: the
    session's default applies). command: the canonical name ('read',
    'write', 'start', 'stop', 'preop', 'reset_node', 'reset_comm',
    'set_network', 'set_node', 'set_sdo_timeout', 'set_sdo_block',
    'info_version', 'help', 'lss_switch_glob', ...). args: its numbers;
    kind and value for read/write."""

    seq: int
    net: Optional[int]
    node: Optional[int]
    command: str
    args: Tuple[int, ...] = ()
    kind: Optional[AsciiType] = None
    value: bytes = b""
    topic: str = ""


def tokenize(line: str) -> Optional[List[str]]:
    """Whitespace-separated tokens; a token starting with '"' runs to its
    closing quote ('""' inside is a quote); '#' at a token start ends the
    line. None for an unclosed quote."""
    tokens: List[str] = []
    i, n = 0, len(line)
    while i < n:
        char = line[i]
        if char in " \t\r\n\v\f":
            i += 1
            continue
        if char == "#":
            break
        if char == '"':
            j = i + 1
            while True:
                end = line.find('"', j)
                if end < 0:
                    return None
                if line[end + 1:end + 2] == '"':
                    j = end + 2
                    continue
                break
            tokens.append(line[i:end + 1])
            i = end + 1
            continue
        j = i
        while j < n and line[j] not in " \t\r\n\v\f":
            j += 1
        tokens.append(line[i:j])
        i = j
    return tokens


_NMT = {"start": "start", "stop": "stop", "preop": "preop", "preoperational": "preop"}
_RESET = {"node": "reset_node", "comm": "reset_comm", "communication": "reset_comm"}
# LSS commands: (name, least and most number of arguments)
_LSS_ARGS = {"lss_switch_glob": (1, 1), "lss_switch_sel": (4, 4), "lss_set_node": (1, 1),
             "lss_conf_bitrate": (2, 2), "lss_activate_bitrate": (1, 1), "lss_store": (0, 0),
             "lss_inquire_addr": (0, 1), "lss_get_node": (0, 0), "_lss_fastscan": (0, 1),
             "lss_allnodes": (0, 11)}
_NET_ONLY = ("set", "info", "help") + tuple(_LSS_ARGS)


def parse_request(raw: Union[str, bytes]) -> Union[Request, Reply, None]:
    """The request on one line, the error Reply to send instead, or None for
    an empty or comment-only line (nothing is answered)."""
    line = raw.decode("latin-1") if isinstance(raw, (bytes, bytearray)) else raw
    tokens = tokenize(line)
    if tokens is None:
        return _error(_leading_seq(line), SYNTAX_ERROR, "unclosed quote")
    if not tokens:
        return None
    head = tokens[0]
    if not (head.startswith("[") and head.endswith("]")):
        return _error(0, SYNTAX_ERROR, "a request starts with [sequence]")
    seq = _parse_int(head[1:-1])
    if seq is None or not 0 <= seq <= _U32:
        return _error(0, SYNTAX_ERROR, f"sequence {head!r} is not 0..4294967295")
    numbers: List[int] = []
    i = 1
    while i < len(tokens) and tokens[i][:1].isdigit():
        number = _parse_int(tokens[i])
        if number is None or number < 0:
            return _error(seq, SYNTAX_ERROR, f"{tokens[i]!r} is not a number")
        numbers.append(number)
        i += 1
    if i >= len(tokens):
        return _error(seq, SYNTAX_ERROR, "no command")
    if len(numbers) > 2:
        return _error(seq, SYNTAX_ERROR, "more than net and node before the command")
    command, rest = tokens[i].lower(), tokens[i + 1:]
    net: Optional[int] = None
    node: Optional[int] = None
    if command in _NET_ONLY or command.startswith("lss_"):
        if len(numbers) > 1:
            return _error(seq, SYNTAX_ERROR, f"{command} takes a net, not a node")
        net = numbers[0] if numbers else None
    elif len(numbers) == 2:
        net, node = numbers
    elif numbers:
        node = numbers[0]
    if net is not None and not 1 <= net <= 127:
        # CiA 309-3 nets are 1..127 (0: all networks, not supported here)
        return _error(seq, UNSUPPORTED_NET, f"net {net}")
    if node is not None and node > 127:
        return _error(seq, UNSUPPORTED_NODE, f"node {node}")
    return _parse_command(seq, net, node, command, rest)


def _leading_seq(line: str) -> int:
    """The [sequence] a broken line starts with (0 when none), so even an
    error answer carries it."""
    text = line.lstrip()
    if text.startswith("["):
        end = text.find("]", 0, 16)
        if end > 0:
            value = _parse_int(text[1:end])
            if value is not None and 0 <= value <= _U32:
                return value
    return 0


def leading_seq(data: bytes) -> int:
    """_leading_seq of raw bytes (the head of an overlong line)."""
    return _leading_seq(data[:32].decode("latin-1"))


def _numbers(seq: int, tokens: List[str], what: str) -> Union[List[int], Reply]:
    out = []
    for token in tokens:
        value = _parse_int(token)
        if value is None or not 0 <= value <= _U32:
            return _error(seq, SYNTAX_ERROR, f"{what}: {token!r} is not a number 0..0xFFFFFFFF")
        out.append(value)
    return out


def _parse_command(seq: int, net: Optional[int], node: Optional[int], command: str,
                   rest: List[str]) -> Union[Request, Reply]:
    if command in ("r", "read", "w", "write"):
        return _parse_transfer(seq, net, node, command[0] == "w", rest)
    if command in _NMT:
        if rest:
            return _error(seq, SYNTAX_ERROR, f"{command} takes no argument")
        return Request(seq, net, node, _NMT[command])
    if command == "reset":
        if len(rest) != 1 or rest[0].lower() not in _RESET:
            return _error(seq, SYNTAX_ERROR, "reset node | reset comm[unication]")
        return Request(seq, net, node, _RESET[rest[0].lower()])
    if command == "set":
        return _parse_set(seq, net, rest)
    if command == "info":
        if [t.lower() for t in rest] != ["version"]:
            return _error(seq, REQUEST_NOT_SUPPORTED, "info version is the info request served")
        return Request(seq, net, None, "info_version")
    if command == "help":
        topic = rest[0].lower() if rest else ""
        if len(rest) > 1 or topic not in ("", "datatype", "lss"):
            return _error(seq, SYNTAX_ERROR, "help [datatype|lss]")
        return Request(seq, net, None, "help", topic=topic)
    if command in _LSS_ARGS:
        least, most = _LSS_ARGS[command]
        if not least <= len(rest) <= most:
            return _error(seq, SYNTAX_ERROR, f"{command} takes {least}..{most} arguments")
        numbers = _numbers(seq, rest, command)
        if isinstance(numbers, Reply):
            return numbers
        return _check_lss(seq, net, command, numbers)
    return _error(seq, REQUEST_NOT_SUPPORTED, f"unknown command {command[:32]!r}")


def _parse_transfer(seq: int, net: Optional[int], node: Optional[int], write: bool,
                    rest: List[str]) -> Union[Request, Reply]:
    usage = "w[rite] index sub type value" if write else "r[ead] index sub [type]"
    if len(rest) < (4 if write else 2) or (not write and len(rest) > 3):
        return _error(seq, SYNTAX_ERROR, usage)
    index, sub = _parse_int(rest[0]), _parse_int(rest[1])
    if index is None or not 0 <= index <= 0xFFFF:
        return _error(seq, SYNTAX_ERROR, f"index {rest[0]!r} is not 0..0xFFFF")
    if sub is None or not 0 <= sub <= 0xFF:
        return _error(seq, SYNTAX_ERROR, f"sub-index {rest[1]!r} is not 0..0xFF")
    kind: Optional[AsciiType] = None
    if len(rest) > 2:
        kind = TYPES.get(rest[2].lower())
        if kind is None:
            return _error(seq, SYNTAX_ERROR, f"unknown data type {rest[2][:16]!r}")
    if not write:
        return Request(seq, net, node, "read", (index, sub), kind)
    assert kind is not None
    data = encode_value(kind, rest[3:])
    if isinstance(data, str):
        return _error(seq, SYNTAX_ERROR, data)
    return Request(seq, net, node, "write", (index, sub), kind, data)


def _parse_set(seq: int, net: Optional[int], rest: List[str]) -> Union[Request, Reply]:
    if len(rest) != 2:
        return _error(seq, SYNTAX_ERROR, "set network|node|sdo_timeout|sdo_block VALUE")
    what, value = rest[0].lower(), _parse_int(rest[1])
    limits = {"network": (1, 127), "node": (1, 127), "sdo_timeout": (1, 0xFFFF),
              "sdo_block": (0, 1)}
    if what not in limits:
        return _error(seq, REQUEST_NOT_SUPPORTED, f"set {what[:32]}")
    low, high = limits[what]
    if value is None or not low <= value <= high:
        return _error(seq, SYNTAX_ERROR, f"set {what} takes {low}..{high}")
    return Request(seq, net, None, f"set_{what}", (value,))


def _check_lss(seq: int, net: Optional[int], command: str,
               numbers: List[int]) -> Union[Request, Reply]:
    def bad(detail: str) -> Reply:
        return _error(seq, SYNTAX_ERROR, f"{command}: {detail}")
    if command == "lss_switch_glob" and numbers[0] > 1:
        return bad("0 (waiting) or 1 (configuration)")
    if command == "lss_set_node" and not (1 <= numbers[0] <= 127 or numbers[0] == 255):
        return bad("node-id 1..127 or 255 (unconfigured)")
    if command == "lss_conf_bitrate" and (numbers[0] > 255 or numbers[1] > 255):
        return bad("table selector and index are 0..255")
    if command in ("lss_activate_bitrate", "_lss_fastscan") and numbers and numbers[0] > 0xFFFF:
        return bad("milliseconds 0..65535")
    if command == "lss_inquire_addr" and numbers and numbers[0] > 3:
        return bad("0 vendor, 1 product, 2 revision, 3 serial")
    if command == "lss_allnodes":
        if len(numbers) not in (0, 1, 3, 11):
            return bad("[timeout [start store [8 scan values]]]")
        if numbers and numbers[0] > 0xFFFF:
            return bad("timeout 0..65535 ms")
        if len(numbers) >= 3 and (not 1 <= numbers[1] <= 127 or numbers[2] > 1):
            return bad("start node-id 1..127, store 0|1")
        if len(numbers) == 11 and any(n > 2 for n in numbers[3::2]):
            return bad("scan types are 0 (scan), 1 (ignore), 2 (match)")
        if len(numbers) == 11 and numbers[3] == 1:
            return bad("the vendor-ID cannot be ignored (scan type 1): every fast scan "
                       "starts with it")
    return Request(seq, net, None, command, tuple(numbers))


# ---------------------------------------------------------------- help
HELP = """\
# [seq] [[net] node] r[ead] index sub [type]       read an entry (SDO, USDO on fd lines)
# [seq] [[net] node] w[rite] index sub type value  write an entry
# [seq] [[net] node] start|stop|preop|reset node|reset comm   NMT command (node 0: all)
# [seq] [net] set network N | set node N           the session's default net and node
# [seq] [net] set sdo_timeout MS | set sdo_block 0|1
# [seq] info version                               gateway identity and protocol version
# [seq] help [datatype|lss]
# answers: [seq] OK | [seq] value | [seq] ERROR: code #text
# events: net node BOOT_UP | net node STATE OPER|STOP|PREOP | net node ERROR: 202|203 #text
#         net node EMCY code register b0 b1 b2 b3 b4"""

HELP_DATATYPE = """\
# b boolean 0|1; i8 i16 i32 i64 u8 u16 u32 u64 decimal (0x hex accepted)
# x8 x16 x32 x64 unsigned shown as 0x hex; r32 r64 real
# t td time of day / difference: milliseconds days
# vs visible string in double quotes ("" for a quote, \\n \\r \\t \\\\ \\xHH escapes)
# os us d octet string, unicode string, domain: base64 (RFC 2045, one line)
# hex bytes as hex pairs (not in CiA 309-3); a read without a type shows this"""

HELP_LSS = """\
# [seq] [net] lss_switch_glob 0|1                  all slaves to waiting / configuration
# [seq] [net] lss_switch_sel vendor product revision serial
# [seq] [net] lss_set_node N                       node-id of the slave in configuration
# [seq] [net] lss_conf_bitrate 0 index             CiA table: 0=1M 1=800k 2=500k 3=250k
#                                                  4=125k 6=50k 7=20k 8=10k 9=auto
# [seq] [net] lss_activate_bitrate MS
# [seq] [net] lss_store
# [seq] [net] lss_inquire_addr [0..3]              all four, or vendor/product/rev/serial
# [seq] [net] lss_get_node
# [seq] [net] _lss_fastscan [MS]                   find one unconfigured slave (fast scan),
#                                                  left in configuration: its LSS address
# [seq] [net] lss_allnodes [MS [start store [T0 vendor T1 product T2 revision T3 serial]]]
#                                                  fast scan: node-ids from start on; T:
#                                                  0 scan, 1 ignore (not the vendor), 2 match"""
