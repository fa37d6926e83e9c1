"""The transfer commands of `canopenfd`: read, write, download, upload
(USDO on CAN FD lines, SDO with --classic).

    canopenfd read NODE INDEX[:SUB] --channel IFACE [--type T] [--od FILE]
    canopenfd write NODE INDEX[:SUB] VALUE --channel IFACE [--type T] [--od FILE]
    canopenfd download NODE INDEX[:SUB] FILE --channel IFACE [--mode M] [--progress]
    canopenfd upload NODE INDEX[:SUB] FILE --channel IFACE [--progress]

On a CAN FD line every command is a USDO client (CiA 1301) with node-id
--client-id (default 127); with --classic it is an SDO client (CiA 301) of
the node's default SDO channel. INDEX and SUB are hex (`0x1018:1`, `1018:01`,
`1018sub1`; SUB defaults to 0); with --od FILE (the remote node's EDS, DCF,
XDD or XDC, or builtin:fd) INDEX may also be a name (`"Producer heartbeat
time"`, `"Identity object.Vendor-ID"`) and values are typed by the file.

Exit status: 0 done, 1 the transfer failed (an abort: ours, such as a
timeout, or the server's), 2 a bad argument (one line on stderr, never a
traceback).
"""

from __future__ import annotations

import argparse
import contextlib
import datetime as _dt
import math
import os
import stat
import sys
import tempfile
import threading
import time
from typing import Any, Callable, Dict, Iterator, Optional, TextIO, Tuple

from ..errors import AbortError, CanopenFDError
from ..od import (DataType, ODVariable, ObjectDictionary, OdFileError, OdValueError,
                  TimeDifference, TimeOfDay, demo_od, import_od)
from ..od import decode as _decode
from ..od.datatypes import real32_text
from ..od import encode as _encode
from ..transfer import Transfer, UsdoAbortError
from .common import (EXIT_FAILED, EXIT_OK, UsageError, add_line_options, builtin_od_kind,
                     command_line, parse_key, print_error, rate_text)

#: download modes: 'bulk' on fd lines (USDO), 'block' on classic lines (SDO)
MODES = ("auto", "expedited", "segmented", "bulk", "block")
#: upload modes: 'bulk' on fd lines (USDO: the server streams), 'normal' (expedited or
#: segmented, as the server picks) and 'block' on classic lines (SDO)
UPLOAD_MODES = ("auto", "normal", "block", "bulk")

DEFAULT_CLIENT_ID = 127
DEFAULT_TIMEOUT_S = 1.0
EXPEDITED_MAX = 56          # bytes an expedited USDO transfer carries
TRANSFER_MAX = 0xFFFFFFFE   # bytes a transfer moves at most
_WAIT_SLICE_S = 0.1         # result() in slices: Ctrl-C works, a late done event costs <= this

# --type names besides the CiA 301 ones (UNSIGNED32, VISIBLE_STRING, ...).
_TYPE_ALIASES: Dict[str, DataType] = {
    "BOOL": DataType.BOOLEAN,
    "FLOAT": DataType.REAL32, "F32": DataType.REAL32, "R32": DataType.REAL32,
    "DOUBLE": DataType.REAL64, "F64": DataType.REAL64, "R64": DataType.REAL64,
    "STRING": DataType.VISIBLE_STRING, "STR": DataType.VISIBLE_STRING,
    "VSTR": DataType.VISIBLE_STRING, "VS": DataType.VISIBLE_STRING,
    "OCTETS": DataType.OCTET_STRING, "OSTR": DataType.OCTET_STRING,
    "OS": DataType.OCTET_STRING,
    "USTR": DataType.UNICODE_STRING, "UNICODE": DataType.UNICODE_STRING,
    "BYTES": DataType.DOMAIN,
    "TOD": DataType.TIME_OF_DAY, "TD": DataType.TIME_DIFFERENCE,
}
for _bits in (8, 16, 24, 32, 40, 48, 56, 64):
    _TYPE_ALIASES[f"U{_bits}"] = _TYPE_ALIASES[f"UINT{_bits}"] = DataType[f"UNSIGNED{_bits}"]
    _TYPE_ALIASES[f"I{_bits}"] = _TYPE_ALIASES[f"INT{_bits}"] = DataType[f"INTEGER{_bits}"]
_TYPE_HINT = "U8..U64, I8..I64, BOOLEAN, REAL32, REAL64, VISIBLE_STRING, OCTET_STRING, " \
             "UNICODE_STRING, DOMAIN, TIME_OF_DAY, TIME_DIFFERENCE or a CiA 301 code like 0x07"
_TRUE = ("1", "true", "on", "yes")
_FALSE = ("0", "false", "off", "no")


# ------------------------------------------------------------------ parser
def add_parsers(subparsers: Any) -> None:
    """Register read, write, download and upload on the main parser's subparsers."""
    key_help = "entry: INDEX[:SUB] in hex (0x1018:1), or a name from --od"
    unicast_help = "node-id 1..127 (decimal or 0x hex)"
    broadcast_help = ("node-id 1..127 (decimal or 0x hex), or 0: every node (USDO "
                      "broadcast, not with --classic)")
    answer_help = ("how long to wait for each answer of the server (default "
                   f"{DEFAULT_TIMEOUT_S:g})")
    window_help = ("how long to wait for each answer of the server (default "
                   f"{DEFAULT_TIMEOUT_S:g}; with NODE 0 how long to collect the answers)")

    def transfer_options(p: argparse.ArgumentParser, timeout_help: str, od_use: str) -> None:
        add_line_options(p)
        p.add_argument("--client-id", type=int, default=DEFAULT_CLIENT_ID, metavar="N",
                       help=f"our USDO client node-id 1..127 (default {DEFAULT_CLIENT_ID}; "
                            "fd lines only)")
        p.add_argument("--timeout", type=float, default=DEFAULT_TIMEOUT_S, metavar="SECONDS",
                       help=timeout_help)
        p.add_argument("--od", metavar="FILE",
                       help="the remote node's EDS/DCF/XDD/XDC, or builtin:fd / "
                            f"builtin:classic: {od_use}")

    p = subparsers.add_parser("read", help="read one entry of a node (USDO, or SDO with "
                                           "--classic) and print it")
    p.add_argument("node", metavar="NODE", help=broadcast_help)
    p.add_argument("key", metavar="INDEX[:SUB]", help=key_help)
    p.add_argument("--type", metavar="T",
                   help=f"print the value as this type ({_TYPE_HINT}); default: the type "
                        "from --od, else raw hex bytes")
    transfer_options(p, window_help, "names for INDEX, and the value's type")
    p.set_defaults(func=cmd_read)

    p = subparsers.add_parser("write", help="write one entry of a node (USDO, or SDO with "
                                            "--classic)")
    p.add_argument("node", metavar="NODE", help=broadcast_help)
    p.add_argument("key", metavar="INDEX[:SUB]", help=key_help)
    p.add_argument("value", metavar="VALUE",
                   help="integers in decimal or 0x hex, booleans true/false, strings as "
                        "text, OCTET_STRING / DOMAIN as hex bytes ('01 02 ff' or 0102ff), "
                        "TIME_OF_DAY like 2024-05-01T12:00:00, TIME_DIFFERENCE in ms")
    p.add_argument("--type", metavar="T",
                   help=f"the value's type ({_TYPE_HINT}); default: the type from --od")
    transfer_options(p, window_help, "names for INDEX, and the value's type")
    p.set_defaults(func=cmd_write)

    p = subparsers.add_parser("download", help="send a file's contents to an entry (USDO, "
                                               "or SDO with --classic)")
    p.add_argument("node", metavar="NODE", help=unicast_help)
    p.add_argument("key", metavar="INDEX[:SUB]", help=key_help)
    p.add_argument("file", metavar="FILE", help="the file to send")
    p.add_argument("--mode", choices=list(MODES), default="auto",
                   help="transfer mode (default auto: USDO expedited up to 56 bytes, "
                        "segmented below 4 KiB, bulk above; SDO expedited up to 4 bytes, "
                        "segmented below 1 KiB, block above); bulk is USDO's, block SDO's")
    p.add_argument("--progress", action="store_true",
                   help="show the progress bar on stderr even when it is no terminal")
    transfer_options(p, answer_help, "names for INDEX")
    p.set_defaults(func=cmd_download)

    p = subparsers.add_parser("upload", help="read an entry into a file (USDO, or SDO with "
                                             "--classic)")
    p.add_argument("node", metavar="NODE", help=unicast_help)
    p.add_argument("key", metavar="INDEX[:SUB]", help=key_help)
    p.add_argument("file", metavar="FILE", help="the file to write (replaced once complete)")
    p.add_argument("--mode", choices=list(UPLOAD_MODES), default="auto",
                   help="bulk (USDO): the server streams the data in the client's window; "
                        "block (SDO, --classic): a block upload (CRC, sub-blocks of 127 "
                        "segments); normal (SDO): expedited or segmented as the server picks; "
                        "default auto: USDO bulk when --od gives the entry a size of 4 KiB "
                        "or more, else as the server picks")
    p.add_argument("--progress", action="store_true",
                   help="show the progress (bytes, rate) on stderr even when it is no "
                        "terminal")
    transfer_options(p, answer_help, "names for INDEX")
    p.set_defaults(func=cmd_upload)


# ------------------------------------------------------------------ argument parsing
def parse_node(text: str, broadcast: bool) -> int:
    """NODE: 1..127 (decimal or 0x hex), 0 = broadcast when allowed."""
    try:
        node = int(text.strip(), 16) if text.strip().lower().startswith("0x") \
            else int(text.strip(), 10)
    except ValueError:
        raise UsageError(f"NODE {text!r} is not a node-id (1..127"
                         f"{', 0 = every node' if broadcast else ''})") from None
    if node == 0 and not broadcast:
        raise UsageError("NODE 0 (broadcast) works only with read and write: give a node-id "
                         "1..127")
    if not 0 <= node <= 127:
        raise UsageError(f"NODE {node} outside 0..127 (0 = every node)" if broadcast
                         else f"NODE {node} outside 1..127")
    return node


def parse_type(text: str) -> DataType:
    """--type: a CiA 301 name (UNSIGNED32), a short one (U32, I16, REAL32,
    STRING, ...) or the type code (7, 0x07)."""
    name = text.strip().upper().replace("-", "_")
    if name in _TYPE_ALIASES:
        return _TYPE_ALIASES[name]
    try:
        return DataType.parse(name)
    except OdValueError:
        pass
    try:
        return DataType.parse(int(name, 0))
    except (ValueError, OdValueError):
        raise UsageError(f"--type {text!r} is not a data type: give {_TYPE_HINT}") from None


def _parse_int(dtype: DataType, text: str) -> int:
    stripped = text.strip().replace("_", "")
    sign = -1 if stripped.startswith("-") else 1
    digits = stripped.lstrip("+-")
    try:
        if digits[:2].lower() == "0x":
            number = int(digits[2:], 16)
            # 0xFFFF as INTEGER16 is -1 (two's complement of the type's width)
            size, high = dtype.size, dtype.max
            if dtype.signed and sign > 0 and size is not None and high is not None and \
                    high < number < 1 << (8 * size):
                number -= 1 << (8 * size)
        else:
            number = int(digits, 10)
    except ValueError:
        raise OdValueError("not an integer (decimal or 0x hex)") from None
    return sign * number


def _parse_hex(text: str) -> bytes:
    digits = "".join(text.split())
    if digits[:2].lower() == "0x":
        digits = digits[2:]
    if len(digits) % 2:
        raise OdValueError("an odd number of hex digits (give whole bytes: 01 02 ff)")
    try:
        return bytes.fromhex(digits)
    except ValueError:
        raise OdValueError("not hex bytes (like '01 02 ff' or 0102ff)") from None


def parse_value(dtype: DataType, text: str) -> Any:
    """The Python value of VALUE for dtype (range-checked by the encoder later)."""
    if dtype == DataType.BOOLEAN:
        lowered = text.strip().lower()
        if lowered in _TRUE or lowered in _FALSE:
            return lowered in _TRUE
        raise OdValueError("not a BOOLEAN (true/false, 1/0, on/off)")
    if dtype.is_integer:
        return _parse_int(dtype, text)
    if dtype.is_real:
        try:
            return float(text.strip())
        except ValueError:
            raise OdValueError("not a number") from None
    if dtype in (DataType.VISIBLE_STRING, DataType.UNICODE_STRING):
        return text
    if dtype in (DataType.OCTET_STRING, DataType.DOMAIN):
        return _parse_hex(text)
    if dtype == DataType.TIME_OF_DAY:
        try:
            return TimeOfDay.from_datetime(_dt.datetime.fromisoformat(text.strip()))
        except ValueError:
            raise OdValueError("not a date and time (like 2024-05-01T12:00:00)") from None
    try:   # TIME_DIFFERENCE: milliseconds
        return TimeDifference.from_timedelta(
            _dt.timedelta(milliseconds=_parse_int(DataType.UNSIGNED64, text)))
    except (OverflowError, OdValueError):
        raise OdValueError("not a time difference in milliseconds") from None


# ------------------------------------------------------------------ value output
def format_value(dtype: DataType, value: Any) -> str:
    """A read value for the terminal: integers in decimal and hex, strings
    as text, bytes as hex."""
    if dtype == DataType.BOOLEAN:
        return "true" if value else "false"
    if dtype.is_integer:
        width = dtype.size or 1
        return f"{value} (0x{value & ((1 << (8 * width)) - 1):0{2 * width}X})"
    if dtype == DataType.REAL32:
        return real32_text(value)
    if dtype.is_real:
        return repr(value)
    if isinstance(value, TimeOfDay):
        return value.to_datetime().isoformat(timespec="milliseconds")
    if isinstance(value, TimeDifference):
        return f"{value.to_timedelta()} ({value.days * 86_400_000 + value.ms} ms)"
    if isinstance(value, (bytes, bytearray)):
        return hex_bytes(bytes(value))
    return str(value)


def hex_bytes(data: bytes) -> str:
    return data.hex(" ") if data else "(empty)"


def _show(data: bytes, dtype: Optional[DataType], variable: Optional[ODVariable]) -> str:
    """Typed text of the bytes read; raw hex when the type is unknown or the
    bytes do not decode as it (a warning on stderr then)."""
    if dtype is None and variable is None:
        return hex_bytes(data)
    try:
        if dtype is not None:
            return format_value(dtype, _decode(dtype, data))
        assert variable is not None
        return format_value(variable.data_type, variable.decode_raw(data))
    except OdValueError as exc:
        kind = (dtype or variable.data_type).name  # type: ignore[union-attr]
        print(f"canopenfd: warning: the {len(data)} bytes read are no {kind} ({exc}); "
              "shown raw", file=sys.stderr)
        return hex_bytes(data)


def _size_text(count: float) -> str:
    for unit in ("B", "KiB", "MiB"):
        if count < 1024:
            return f"{count:.0f} {unit}" if unit == "B" else f"{count:.1f} {unit}"
        count /= 1024
    return f"{count:.2f} GiB"


def _eta_text(seconds: float) -> str:
    if not math.isfinite(seconds) or seconds < 0:
        return "--:--"
    seconds = int(round(seconds))
    hours, rest = divmod(seconds, 3600)
    return f"{hours}:{rest // 60:02d}:{rest % 60:02d}" if hours else \
        f"{rest // 60}:{rest % 60:02d}"


class ProgressBar:
    """Progress of one transfer on stderr (the transfer's progress callback,
    called on the dispatcher thread): bar, percent, bytes, rate and ETA when
    the size is known, else bytes and rate. On a terminal the line is redrawn
    in place at most 10 times a second; elsewhere (--progress into a file or
    pipe) one line is written at most every second."""

    WIDTH = 24

    def __init__(self, verb: str, total: Optional[int], stream: Optional[TextIO] = None,
                 tty: Optional[bool] = None) -> None:
        self.verb = verb
        self.total = total
        self.stream = stream if stream is not None else sys.stderr
        self.tty = self.stream.isatty() if tty is None else tty
        self.interval = 0.1 if self.tty else 1.0
        self.t0 = time.monotonic()
        self._lock = threading.Lock()
        self._moved = 0
        self._last: Optional[float] = None
        self._width = 0
        self._closed = False

    def start(self) -> None:
        self.t0 = time.monotonic()

    def __call__(self, moved: int) -> None:
        with self._lock:
            if self._closed:
                return
            self._moved = max(self._moved, moved)
            now = time.monotonic()
            if self._last is not None and now - self._last < self.interval:
                return
            self._draw(now)

    def close(self, moved: Optional[int] = None) -> None:
        """The last state (moved bytes when the transfer completed), then a
        newline on a terminal; later callbacks are ignored."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            if moved is not None:
                self._moved = moved
                self._draw(time.monotonic())
            if self.tty and self._last is not None:
                self._write("\n")

    def text(self, now: float) -> str:
        elapsed = now - self.t0
        moved = self._moved
        rate = moved / elapsed if elapsed > 0 else 0.0
        if self.total is None:
            return f"{self.verb}  {_size_text(moved)}  {rate_text(moved, elapsed)}"
        fraction = min(1.0, moved / self.total) if self.total else 1.0
        filled = int(fraction * self.WIDTH)
        bar = "#" * filled + "-" * (self.WIDTH - filled)
        # the first moments (connection, first chunk) would give a wild guess
        eta = 0.0 if moved >= self.total else \
            (self.total - moved) / rate if rate > 0 and elapsed >= 0.3 else math.inf
        return (f"{self.verb} [{bar}] {fraction * 100:3.0f}%  {_size_text(moved)} / "
                f"{_size_text(self.total)}  {rate_text(moved, elapsed)}  "
                f"ETA {_eta_text(eta)}")

    def _draw(self, now: float) -> None:
        self._last = now
        text = self.text(now)
        if self.tty:
            padded = text.ljust(self._width)
            self._width = len(text)
            self._write("\r" + padded)
        else:
            self._write(text + "\n")

    def _write(self, text: str) -> None:
        try:
            self.stream.write(text)
            self.stream.flush()
        except (OSError, ValueError):
            pass   # a closed stderr never stops a transfer


# ------------------------------------------------------------------ session
def _load_od(spec: Optional[str], node: int) -> Optional[ObjectDictionary]:
    """--od FILE (the remote node's dictionary) or builtin:fd / builtin:classic."""
    if spec is None:
        return None
    kind = builtin_od_kind(spec)
    if kind is not None:
        return demo_od(kind, node_id=node or None)
    try:
        return import_od(spec, node_id=node or None)
    except OdFileError as exc:
        raise UsageError(f"--od {exc}") from None
    except OSError as exc:
        raise UsageError(f"--od {spec}: {exc.strerror or exc}") from None


def _check_common(args: argparse.Namespace, node: int) -> None:
    if args.classic and node == 0:
        raise UsageError(f"NODE 0 (broadcast) is USDO's: classic SDO talks to one node at a time")
    if not 1 <= args.client_id <= 127:
        raise UsageError(f"--client-id {args.client_id} outside 1..127")
    if node == args.client_id and not args.classic:
        raise UsageError(f"NODE {node} is our own USDO client id: give the server's node-id, "
                         "or another --client-id")
    if not (0 < args.timeout <= 3600):
        raise UsageError(f"--timeout {args.timeout:g} s outside (0, 3600]")


@contextlib.contextmanager
def _client_line(args: argparse.Namespace) -> Iterator[Any]:
    """The line named by the line options (our USDO client on it as
    --client-id on fd lines); closed at the end (unless the network was
    handed in)."""
    with command_line(args) as line:
        if line.mode == "fd":
            _client(line).client_id = args.client_id
        yield line


def _client(line: Any) -> Any:
    """USDO on fd lines, SDO on classic lines."""
    return line.usdo if line.mode == "fd" else line.sdo


def _wait(transfer: Transfer) -> Any:
    """transfer.result(), in slices so Ctrl-C cancels the transfer (the
    abort goes to the server) instead of leaving it running."""
    try:
        while True:
            try:
                return transfer.result(timeout=_WAIT_SLICE_S)
            except TimeoutError:
                continue
    except KeyboardInterrupt:
        try:
            transfer.cancel()
        except CanopenFDError:
            pass
        raise


def _failed(exc: AbortError) -> int:
    text = str(exc)
    if isinstance(exc.__cause__, OSError):
        text += f" ({exc.__cause__.strerror or exc.__cause__})"
    print_error(text)
    return EXIT_FAILED


def _where(index: int, sub: int, variable: Optional[ODVariable]) -> str:
    name = f" ({variable.qualname})" if variable is not None else ""
    return f"0x{index:04X}:{sub:02X}{name}"


def _abort_text(error: AbortError) -> str:
    """A broadcast answer's refusal: USDO's one-byte code, else the CiA 301 one."""
    if isinstance(error, UsdoAbortError):
        return f"abort 0x{error.usdo_code:02X} ({error.meaning})"
    return f"abort 0x{error.code:08X} ({error.meaning})"


# ------------------------------------------------------------------ read / write
def cmd_read(args: argparse.Namespace) -> int:
    node = parse_node(args.node, broadcast=True)
    _check_common(args, node)
    od = _load_od(args.od, node)
    index, sub, variable = parse_key(args.key, od)
    dtype = parse_type(args.type) if args.type is not None else None
    with _client_line(args) as line:
        try:
            transfer = _client(line).start_upload(node, index, sub, timeout=args.timeout)
            result = _wait(transfer)
        except AbortError as exc:
            return _failed(exc)
        if node != 0:
            print(_show(result, dtype, variable))
            return EXIT_OK
        return _broadcast_report(result, args.timeout,
                                 lambda data: _show(data, dtype, variable))


def _broadcast_report(answers: Dict[int, Any], window: float,
                      show: Callable[[Any], str]) -> int:
    """One line per answering node; exit 1 when none answered or all refused."""
    if not answers:
        print_error(f"no node answered within {window:g} s")
        return EXIT_FAILED
    for node in sorted(answers):
        answer = answers[node]
        text = _abort_text(answer) if isinstance(answer, AbortError) else show(answer)
        print(f"node {node}: {text}")
    refused = all(isinstance(answer, AbortError) for answer in answers.values())
    return EXIT_FAILED if refused else EXIT_OK


def _encode_value(args: argparse.Namespace, index: int, sub: int,
                  variable: Optional[ODVariable]) -> Tuple[bytes, DataType]:
    """VALUE as wire bytes and the type code to send with it."""
    place = f"0x{index:04X}:{sub:02X}"
    if args.type is not None:
        dtype = parse_type(args.type)
        try:
            return _encode(dtype, parse_value(dtype, args.value)), dtype
        except OdValueError as exc:
            raise UsageError(f"VALUE {args.value!r} is no {dtype.name}: {exc}") from None
    if variable is None:
        if args.od is not None:
            raise UsageError(f"write {place}: the entry is not in {args.od}, so VALUE has no "
                             "type: give --type (--type DOMAIN for raw hex bytes)")
        raise UsageError(f"write {place}: VALUE needs a type: give --type or --od "
                         "(--type DOMAIN for raw hex bytes)")
    dtype = variable.data_type
    try:
        return variable.encode_raw(parse_value(dtype, args.value)), dtype
    except OdValueError as exc:
        raise UsageError(f"VALUE {args.value!r} for {variable.where} {variable.qualname} "
                         f"({dtype.name}): {exc.problem}") from None


def cmd_write(args: argparse.Namespace) -> int:
    node = parse_node(args.node, broadcast=True)
    _check_common(args, node)
    od = _load_od(args.od, node)
    index, sub, variable = parse_key(args.key, od)
    data, dtype = _encode_value(args, index, sub, variable)
    if node == 0 and len(data) > EXPEDITED_MAX:
        raise UsageError(f"write to every node (NODE 0): {len(data)} bytes, a broadcast "
                         f"carries at most {EXPEDITED_MAX}")
    with _client_line(args) as line:
        try:
            if node == 0:
                transfer = _client(line).start_download(0, index, sub, data, mode="expedited",
                                                        data_type=int(dtype),
                                                        timeout=args.timeout)
            else:
                transfer = _client(line).start_download(node, index, sub, data,
                                                        data_type=int(dtype),
                                                        timeout=args.timeout)
            result = _wait(transfer)
        except AbortError as exc:
            return _failed(exc)
        if node == 0:
            return _broadcast_report(result, args.timeout, lambda _: "written")
        print(f"wrote {len(data)} byte{'s' if len(data) != 1 else ''} ({dtype.name}) to "
              f"node {node} {_where(index, sub, variable)}")
        return EXIT_OK


# ------------------------------------------------------------------ download / upload
def _show_progress(args: argparse.Namespace) -> bool:
    if args.progress:
        return True
    try:
        return sys.stderr.isatty()
    except (AttributeError, ValueError):
        return False


def _summary(verb: str, size: int, seconds: float, transfer: Transfer) -> str:
    mode = transfer.mode if transfer.mode not in (None, "auto") else None
    return (f"{verb} {size} bytes in {seconds:.3f} s ({rate_text(size, seconds)}"
            f"{', ' + mode if mode else ''})")


def cmd_download(args: argparse.Namespace) -> int:
    node = parse_node(args.node, broadcast=False)
    _check_common(args, node)
    od = _load_od(args.od, node)
    index, sub, variable = parse_key(args.key, od)
    try:
        source = open(args.file, "rb")
    except OSError as exc:
        raise UsageError(f"FILE {args.file}: {exc.strerror or exc}") from None
    with source:
        info = os.fstat(source.fileno())
        if not stat.S_ISREG(info.st_mode):
            raise UsageError(f"FILE {args.file} is not a regular file (its size must be known "
                             "before the transfer)")
        size = info.st_size
        if size > TRANSFER_MAX:
            raise UsageError(f"FILE {args.file}: {size} bytes; a transfer moves at most "
                             f"{TRANSFER_MAX}")
        if args.mode == "expedited" and size > EXPEDITED_MAX:
            raise UsageError(f"--mode expedited carries at most {EXPEDITED_MAX} bytes; "
                             f"{args.file} has {size}")
        bar = ProgressBar("download", size) if _show_progress(args) else None
        try:
            with _client_line(args) as line:
                started = time.monotonic()
                if bar is not None:
                    bar.start()
                try:
                    transfer = _client(line).start_download(node, index, sub, source,
                                                            mode=args.mode, timeout=args.timeout,
                                                            progress=bar)
                    _wait(transfer)
                except AbortError as exc:
                    if bar is not None:
                        bar.close()
                    return _failed(exc)
                seconds = time.monotonic() - started
                if bar is not None:
                    bar.close(size)
        finally:
            if bar is not None:
                bar.close()
        print(_summary("downloaded", size, seconds, transfer) +
              f": {args.file} -> node {node} {_where(index, sub, variable)}")
    return EXIT_OK


@contextlib.contextmanager
def _output_file(path: str) -> Iterator[Any]:
    """The file an upload streams into: a temporary file next to FILE that
    replaces it once the upload completed (FILE stays as it was on failure);
    FILE itself when it exists and is no regular file (a device, a FIFO)."""
    folder = os.path.dirname(os.path.abspath(path))
    if os.path.isdir(path):
        raise UsageError(f"FILE {path} is a directory")
    if not os.path.isdir(folder):
        raise UsageError(f"FILE {path}: directory {folder} does not exist")
    if os.path.exists(path) and not stat.S_ISREG(os.stat(path).st_mode):
        try:
            target = open(path, "wb")
        except OSError as exc:
            raise UsageError(f"FILE {path}: {exc.strerror or exc}") from None
        with target:
            yield target
        return
    try:
        handle, temporary = tempfile.mkstemp(dir=folder, prefix=f".{os.path.basename(path)}.",
                                             suffix=".part")
    except OSError as exc:
        raise UsageError(f"FILE {path}: {exc.strerror or exc}") from None
    done = False
    try:
        with os.fdopen(handle, "wb") as target:
            yield target
        if os.path.exists(path):   # keep the permissions of the file replaced
            os.chmod(temporary, stat.S_IMODE(os.stat(path).st_mode))
        else:                      # mkstemp made it 0600: as open() would, instead
            os.chmod(temporary, 0o666 & ~_umask())
        os.replace(temporary, path)
        done = True
    finally:
        if not done:
            try:
                os.unlink(temporary)
            except OSError:
                pass


def _umask() -> int:
    """The process umask, read without changing it (os.umask would, for a
    moment, for every thread)."""
    try:
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    return 0o022


class _Failed(Exception):
    def __init__(self, status: int) -> None:
        super().__init__(status)
        self.status = status


def cmd_upload(args: argparse.Namespace) -> int:
    node = parse_node(args.node, broadcast=False)
    _check_common(args, node)
    if args.mode in ("normal", "block") and not args.classic:
        raise UsageError(f"--mode {args.mode} is for SDO uploads (--classic): a USDO server "
                         "picks expedited or segmented by itself (--mode bulk asks it to "
                         "stream)")
    if args.mode == "bulk" and args.classic:
        raise UsageError("--mode bulk is for USDO uploads (without --classic): SDO's "
                         "streaming upload is --mode block")
    od = _load_od(args.od, node)
    index, sub, variable = parse_key(args.key, od)
    # USDO AUTO: the entry's size from the OD lets the client ask for bulk
    size_hint = 0
    if variable is not None and not args.classic and 0 < variable.storage_size < 0xFFFFFFFF:
        size_hint = variable.storage_size
    bar = ProgressBar("upload", None) if _show_progress(args) else None
    try:
        with _output_file(args.file) as target, _client_line(args) as line:
            started = time.monotonic()
            if bar is not None:
                bar.start()
            try:
                mode = {"normal": "segmented"}.get(args.mode, args.mode)
                transfer = _client(line).start_upload(node, index, sub, file=target,
                                                      timeout=args.timeout, progress=bar,
                                                      mode=mode, size_hint=size_hint)
                _wait(transfer)
            except AbortError as exc:
                if bar is not None:
                    bar.close()
                raise _Failed(_failed(exc)) from None
            seconds = time.monotonic() - started
            size = transfer.transferred
            if bar is not None:
                bar.close(size)
    except _Failed as failed:
        return failed.status
    finally:
        if bar is not None:
            bar.close()
    print(_summary("uploaded", size, seconds, transfer) +
          f": node {node} {_where(index, sub, variable)} -> {args.file}")
    return EXIT_OK
