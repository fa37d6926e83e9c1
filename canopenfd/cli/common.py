"""What the command groups of `canopenfd` share: exit statuses and error
lines, the line options (--channel, --interface, --classic, --no-brs) and the
line a command opens with them, time-stamped output, argument checks, and
INDEX[:SUB] (read/write/download/upload and `device --domain`).

Errors a user can fix raise `UsageError` (or the stack's `CanopenFDError`);
`main` prints them as one line on stderr and exits with EXIT_USAGE, never a
traceback."""

from __future__ import annotations

import argparse
import contextlib
import re
import sys
import threading
import time
from typing import Any, Dict, Iterator, List, Optional, Tuple

from ..errors import CanopenFDError
from ..line import Line
from ..network import Network
from .._checks import check_ms, check_node_id
from ..od import ODArray, ODRecord, ODVariable, ObjectDictionary

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_USAGE = 2

_KEY_RE = re.compile(r"^(?:0x)?([0-9a-f]{1,4})(?:(?::|sub)(?:0x)?([0-9a-f]{1,2}))?$",
                     re.IGNORECASE)

#: (index, sub, the object dictionary's entry or None)
Entry = Tuple[int, int, Optional[ODVariable]]


class UsageError(Exception):
    """A bad command-line value (exit 2)."""


def print_error(text: str) -> None:
    print(f"canopenfd: error: {text}", file=sys.stderr)


# ------------------------------------------------------------------ output
class Printer:
    """Time-stamped lines on stdout, safe from any thread; a closed pipe
    (`canopenfd monitor | head`) ends the program quietly instead of a traceback.
    flush: after every line (default; what a program reading the output as
    it comes needs), else the caller flushes (`flush()`) from time to time:
    the monitor, which would otherwise make a system call per frame."""

    def __init__(self, t0: Optional[float] = None, flush: bool = True) -> None:
        self.t0 = time.monotonic() if t0 is None else t0
        self._lock = threading.Lock()
        self.broken = threading.Event()
        self._flush_each = flush

    def line(self, text: str, when: Optional[float] = None) -> None:
        t = (time.monotonic() if when is None else when) - self.t0
        with self._lock:
            if self.broken.is_set():
                return
            try:
                print(f"{t:8.3f}  {text}", flush=self._flush_each)
            except BrokenPipeError:
                self.broken.set()

    def flush(self) -> None:
        with self._lock:
            if self.broken.is_set():
                return
            try:
                sys.stdout.flush()
            except BrokenPipeError:
                self.broken.set()


def wait_until_done(done: threading.Event, printer: Printer, duration: Optional[float]) -> None:
    """Until done, a broken pipe, or duration seconds (None = forever)."""
    deadline = None if duration is None else time.monotonic() + duration
    while not done.is_set() and not printer.broken.is_set():
        remaining = None if deadline is None else deadline - time.monotonic()
        if remaining is not None and remaining <= 0:
            return
        done.wait(0.5 if remaining is None else min(remaining, 0.5))


# ------------------------------------------------------------------ lines
def add_line_options(parser: argparse.ArgumentParser, channel_required: bool = True) -> None:
    """--channel, --interface, the python-can bus options, --classic and
    --no-brs: what `command_line` opens."""
    parser.add_argument("--channel", required=channel_required,
                        help="SocketCAN interface (vcan0, can0); 'mem:NAME', an in-process "
                             "bus shared only by the lines of one process (no other program "
                             "sees it); or the python-can channel with --interface")
    parser.add_argument("--interface", metavar="NAME",
                        help="use python-can interface NAME (virtual, pcan, kvaser, ...)")
    parser.add_argument("--bitrate", type=int, metavar="BIT/S",
                        help="--interface only: nominal bit rate, passed to can.Bus(bitrate=...) "
                             "(SocketCAN interfaces take theirs from 'ip link')")
    parser.add_argument("--data-bitrate", type=int, metavar="BIT/S",
                        help="--interface only: CAN FD data-phase bit rate, passed to "
                             "can.Bus(data_bitrate=...) (interfaces that want timing values "
                             "instead take them with --bus-option)")
    parser.add_argument("--bus-option", action="append", metavar="KEY=VALUE",
                        help="--interface only: one more keyword argument of can.Bus "
                             "(repeatable), e.g. --bus-option f_clock_mhz=80; VALUE is taken "
                             "as an int (decimal or 0x hex), float or true/false when it reads "
                             "as one, else as text")
    parser.add_argument("--classic", action="store_true", help="classic CAN line (default fd)")
    parser.add_argument("--no-brs", action="store_true",
                        help="fd lines: send without bit-rate switch")


#: can.Bus arguments the line options set themselves
_RESERVED_BUS_KEYS = ("interface", "channel", "fd", "bitrate", "data_bitrate")


def bus_option_value(text: str) -> Any:
    """A --bus-option VALUE as int, float, bool, else the text itself."""
    stripped = text.strip()
    lowered = stripped.lower()
    if lowered in ("true", "false"):
        return lowered == "true"
    for base in (10, 0):           # 0: 0x.. hex (and 0o, 0b)
        try:
            return int(stripped, base)
        except ValueError:
            pass
    try:
        return float(stripped)
    except ValueError:
        return text


def bus_kwargs(args: argparse.Namespace) -> Dict[str, Any]:
    """The keyword arguments of can.Bus for the line options (with --interface)."""
    mode = "classic" if args.classic else "fd"
    kwargs: Dict[str, Any] = {"interface": args.interface, "channel": args.channel,
                              "fd": mode == "fd"}
    if args.bitrate is not None:
        kwargs["bitrate"] = args.bitrate
    if args.data_bitrate is not None:
        if mode == "classic":
            raise UsageError("--data-bitrate is the CAN FD data phase: leave it out with "
                             "--classic")
        kwargs["data_bitrate"] = args.data_bitrate
    for option in args.bus_option or ():
        key, equals, value = option.partition("=")
        key = key.strip()
        if not equals or not key.isidentifier():
            raise UsageError(f"--bus-option {option!r}: expected KEY=VALUE with KEY a "
                             "keyword of can.Bus (like receive_own_messages=true)")
        if key in _RESERVED_BUS_KEYS:
            raise UsageError(f"--bus-option {option!r}: {key} is set by "
                             f"{'--classic' if key == 'fd' else '--' + key.replace('_', '-')}")
        if key in kwargs:
            raise UsageError(f"--bus-option {key} given twice")
        kwargs[key] = bus_option_value(value)
    return kwargs


def _open_line(net: Network, args: argparse.Namespace, owned: List[Any],
               monitor: bool) -> Line:
    """The line named by --channel (and --interface, the bus options, --classic, --no-brs)."""
    mode = "classic" if args.classic else "fd"
    brs = not args.no_brs
    if args.interface:
        kwargs = bus_kwargs(args)
        try:
            import can
        except ImportError:
            raise UsageError("--interface needs python-can: pip install python-can") from None
        try:
            bus = can.Bus(**kwargs)
        except Exception as exc:  # python-can raises many kinds for a bad adapter
            raise UsageError(
                f"python-can interface {args.interface!r} channel {args.channel!r}: {exc}"
            ) from None
        owned.append(bus)
        return net.open_line(bus=bus, mode=mode, brs=brs, monitor=monitor)
    given = [name for name, value in (("--bitrate", args.bitrate),
                                      ("--data-bitrate", args.data_bitrate),
                                      ("--bus-option", args.bus_option)) if value is not None]
    if given:
        raise UsageError(f"{', '.join(given)} need --interface (python-can); SocketCAN "
                         "interfaces take their bit rates from 'ip link', mem: buses have none")
    return net.open_line(args.channel, mode=mode, brs=brs, monitor=monitor)


@contextlib.contextmanager
def command_line(args: argparse.Namespace, monitor: bool = False,
                 event_capacity: int = 0) -> Iterator[Line]:
    """The line of the line options, on the Network main() was handed
    (`args.network`, left open: an in-process bus belongs to one Network, so
    tests and embedding programs reach their own nodes this way) or on a new
    one closed at the end, with the python-can bus it opened (event_capacity:
    its runtime event queue, 0 = default)."""
    given = getattr(args, "network", None)
    net = given if given is not None else Network(event_capacity)
    owned: List[Any] = []
    try:
        yield _open_line(net, args, owned, monitor)
    finally:
        if net is not given:
            net.close()
        for bus in owned:
            try:
                bus.shutdown()
            except Exception:  # noqa: BLE001 - best effort at exit
                pass


# ------------------------------------------------------------------ arguments
def node_id_arg(value: object, where: str) -> int:
    """A node-id 1..127, else a UsageError naming where it came from."""
    try:
        return check_node_id(value, where)
    except CanopenFDError as exc:
        raise UsageError(str(exc)) from None


def ms_arg(value: object, name: str, where: str) -> int:
    """A time in ms 0..65535 (a 16-bit CANopen object), else a UsageError."""
    try:
        return check_ms(value, name, where)
    except CanopenFDError as exc:
        raise UsageError(str(exc)) from None


def builtin_od_kind(spec: str) -> Optional[str]:
    """'fd' / 'classic' for --od builtin:fd / builtin:classic, None for a file name."""
    if not spec.startswith("builtin:"):
        return None
    kind = spec[len("builtin:"):]
    if kind not in ("fd", "classic"):
        raise UsageError(f"--od {spec}: the built-in dictionaries are builtin:fd and "
                         "builtin:classic")
    return kind


def od_arg(spec: Optional[str], mode: str, node_id: Optional[int],
           option: str = "--od") -> Any:
    """The ObjectDictionary an --od-like option names: the built-in demo one
    for the line's mode when None, builtin:fd / builtin:classic, or an
    EDS/DCF/XDD/XDC file (one that cannot be read is a usage error naming
    `option`, the file and the line)."""
    from ..od import OdFileError, demo_od, import_od

    if spec is None:
        return demo_od(mode)
    kind = builtin_od_kind(spec)
    if kind is not None:
        return demo_od(kind)
    try:
        return import_od(spec, node_id=node_id)
    except OdFileError as exc:
        raise UsageError(f"{option} {exc}") from None


def parse_key(text: str, od: Optional[ObjectDictionary], what: str = "INDEX") -> Entry:
    """(index, sub, the OD's entry or None) of INDEX[:SUB] in hex, or with an
    OD of a name ('Producer heartbeat time', 'Identity object.Vendor-ID')."""
    text = text.strip()
    match = _KEY_RE.match(text)
    if od is not None:
        try:
            entry = od[text]
        except KeyError:
            entry = None
        if isinstance(entry, ODVariable):
            return entry.index, entry.subindex, entry
        if isinstance(entry, (ODRecord, ODArray)) and not match:
            first = min([s for s in entry.subindices if s > 0] or [1])
            raise UsageError(f"{what} {text!r} is the {entry.object_type.name} "
                             f"0x{entry.index:04X}: give a sub-index, e.g. "
                             f"0x{entry.index:04X}:{first:X} or "
                             f"'{entry.name}.{entry[first].name}'")
    if match:
        index = int(match.group(1), 16)
        sub = int(match.group(2), 16) if match.group(2) is not None else 0
        return index, sub, od.get_variable(index, sub) if od is not None else None
    if od is not None:
        raise UsageError(f"{what} {text!r}: no such name in the object dictionary, and not "
                         "INDEX[:SUB] in hex (like 0x1018:1)")
    raise UsageError(f"{what} {text!r} is not INDEX[:SUB] in hex (like 0x1018:1 or 1017); "
                     "names need --od FILE")


def rate_text(count: float, seconds: float) -> str:
    """Bytes per second in the unit that shows it: '812 B/s', '35.20 kB/s',
    '2.41 MB/s' (a 5 000-byte transfer is not '0.00 MB/s'); '-' without time."""
    if seconds <= 0:
        return "- B/s"
    rate = count / seconds
    if rate >= 1e6:
        return f"{rate / 1e6:.2f} MB/s"
    if rate >= 1e3:
        return f"{rate / 1e3:.2f} kB/s"
    return f"{rate:.0f} B/s"
