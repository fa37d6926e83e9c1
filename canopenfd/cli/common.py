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
from typing import Any, Iterator, List, Optional, Tuple

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
    (`canopenfd monitor | head`) ends the program quietly instead of a traceback."""

    def __init__(self, t0: Optional[float] = None) -> None:
        self.t0 = time.monotonic() if t0 is None else t0
        self._lock = threading.Lock()
        self.broken = threading.Event()

    def line(self, text: str, when: Optional[float] = None) -> None:
        t = (time.monotonic() if when is None else when) - self.t0
        with self._lock:
            if self.broken.is_set():
                return
            try:
                print(f"{t:8.3f}  {text}", flush=True)
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
def add_line_options(parser: argparse.ArgumentParser) -> None:
    """--channel, --interface, --classic and --no-brs: what `command_line` opens."""
    parser.add_argument("--channel", required=True,
                        help="SocketCAN interface (vcan0, can0), 'mem:NAME', or the "
                             "python-can channel with --interface")
    parser.add_argument("--interface", metavar="NAME",
                        help="use python-can interface NAME (virtual, pcan, kvaser, ...)")
    parser.add_argument("--classic", action="store_true", help="classic CAN line (default fd)")
    parser.add_argument("--no-brs", action="store_true",
                        help="fd lines: send without bit-rate switch")


def _open_line(net: Network, args: argparse.Namespace, owned: List[Any],
               monitor: bool) -> Line:
    """The line named by --channel (and --interface, --classic, --no-brs)."""
    mode = "classic" if args.classic else "fd"
    brs = not args.no_brs
    if args.interface:
        try:
            import can
        except ImportError:
            raise UsageError("--interface needs python-can: pip install python-can") from None
        try:
            bus = can.Bus(interface=args.interface, channel=args.channel, fd=(mode == "fd"))
        except Exception as exc:  # python-can raises many kinds for a bad adapter
            raise UsageError(
                f"python-can interface {args.interface!r} channel {args.channel!r}: {exc}"
            ) from None
        owned.append(bus)
        return net.open_line(bus=bus, mode=mode, brs=brs, monitor=monitor)
    return net.open_line(args.channel, mode=mode, brs=brs, monitor=monitor)


@contextlib.contextmanager
def command_line(args: argparse.Namespace, monitor: bool = False) -> Iterator[Line]:
    """The line of the line options, on the Network main() was handed
    (`args.network`, left open: an in-process bus belongs to one Network, so
    tests and embedding programs reach their own nodes this way) or on a new
    one closed at the end, with the python-can bus it opened."""
    given = getattr(args, "network", None)
    net = given if given is not None else Network()
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
