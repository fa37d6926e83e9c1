"""The `canopenfd` command: demo, nmt, monitor, device.

Errors a user can fix (no such interface, wrong MTU, bad node-id) print one
line to stderr and exit with status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import threading
import time
from typing import Any, Callable, List, Optional

from . import __version__
from .cli_od import add_od_parser
from .decode import decode, describe
from .errors import CanopenFDError
from .frame import Frame
from .line import Line
from .network import Network
from .nmt import NmtCommand, parse_node_target
from .node import check_ms, check_node_id

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_USAGE = 2

_NMT_CHOICES = {
    "start": NmtCommand.START,
    "stop": NmtCommand.STOP,
    "preop": NmtCommand.PRE_OPERATIONAL,
    "reset-node": NmtCommand.RESET_NODE,
    "reset-comm": NmtCommand.RESET_COMMUNICATION,
}


class UsageError(Exception):
    """A bad command-line value (exit 2)."""


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


def _wait(done: threading.Event, printer: Printer, duration: Optional[float]) -> None:
    """Until done, a broken pipe, or duration seconds (None = forever)."""
    deadline = None if duration is None else time.monotonic() + duration
    while not done.is_set() and not printer.broken.is_set():
        remaining = None if deadline is None else deadline - time.monotonic()
        if remaining is not None and remaining <= 0:
            return
        done.wait(0.5 if remaining is None else min(remaining, 0.5))


# ------------------------------------------------------------------ lines
def _open_line(net: Network, args: argparse.Namespace, owned: List[Any],
               monitor: bool = False) -> Line:
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


def _shutdown(net: Optional[Network], owned: List[Any]) -> None:
    if net is not None:
        net.close()
    for bus in owned:
        try:
            bus.shutdown()
        except Exception:  # noqa: BLE001 - best effort at exit
            pass


# ------------------------------------------------------------------ commands
def cmd_nmt(args: argparse.Namespace) -> int:
    command = _NMT_CHOICES[args.command]
    try:
        target = parse_node_target(args.target)
    except CanopenFDError as exc:
        raise UsageError(str(exc)) from None
    owned: List[Any] = []
    net = Network()
    try:
        # A monitor line reports our own frame once it went out, so we close
        # only after the command really left.
        line = _open_line(net, args, owned, monitor=True)
        sent = threading.Event()
        line.on_frame(lambda f: sent.set() if f.tx and f.id == 0 else None)
        line.nmt.send(command, target)
        if not sent.wait(args.timeout):
            print(f"canopenfd: error: the NMT frame was not sent on {args.channel} "
                  f"within {args.timeout:g} s (bus off, or no other node acknowledging?)",
                  file=sys.stderr)
            return EXIT_FAILED
        who = "all nodes" if target == 0 else f"node {target}"
        print(f"sent NMT {command.label} to {who} on {args.channel} "
              f"({'classic' if args.classic else 'fd'})")
        return EXIT_OK
    finally:
        _shutdown(net, owned)


def cmd_monitor(args: argparse.Namespace) -> int:
    if args.count is not None and args.count < 1:
        raise UsageError(f"--count must be >= 1, got {args.count}")
    owned: List[Any] = []
    net = Network()
    try:
        line = _open_line(net, args, owned, monitor=True)
        printer = Printer()
        done = threading.Event()
        seen = [0]

        def on_frame(frame: Frame) -> None:
            if done.is_set():
                return
            printer.line(f"{'TX' if frame.tx else 'RX'}  {describe(frame)}", frame.timestamp)
            seen[0] += 1
            if args.count is not None and seen[0] >= args.count:
                done.set()

        line.on_frame(on_frame)
        line.on_comm_event(lambda ev: printer.line(f"--  {ev.name.lower().replace('_', ' ')}"))
        print(f"monitoring {args.channel} ({line.mode}); Ctrl-C to stop", file=sys.stderr)
        try:
            _wait(done, printer, args.duration)
        except KeyboardInterrupt:
            pass
        return EXIT_OK
    finally:
        _shutdown(net, owned)


def _device_od(spec: Optional[str], mode: str, node_id: int) -> Any:
    """The ObjectDictionary `device --od` serves: the built-in demo one for the
    line's mode by default, builtin:fd / builtin:classic, or an EDS/DCF/XDD/XDC
    file (a file that cannot be read is a usage error naming file and line)."""
    from .od import OdFileError, demo_od, import_od

    if spec is None:
        return demo_od(mode)
    if spec.startswith("builtin:"):
        kind = spec[len("builtin:"):]
        if kind not in ("fd", "classic"):
            raise UsageError(f"--od {spec}: the built-in dictionaries are builtin:fd and "
                             "builtin:classic")
        return demo_od(kind)
    try:
        return import_od(spec, node_id=node_id)
    except OdFileError as exc:
        raise UsageError(f"--od {exc}") from None


def _check_store_path(path: Optional[str]) -> None:
    """--store FILE: its directory must exist (the file is created at the first save)."""
    if path is None:
        return
    if not path or os.path.isdir(path):
        raise UsageError(f"--store {path!r}: give a file name, not a directory")
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise UsageError(f"--store {path}: directory {folder} does not exist")


def cmd_device(args: argparse.Namespace) -> int:
    mode = "classic" if args.classic else "fd"
    try:
        node_id = check_node_id(args.node_id, "--node-id")
        if args.heartbeat is not None:
            check_ms(args.heartbeat, "--heartbeat", "device")
    except CanopenFDError as exc:
        raise UsageError(str(exc)) from None
    _check_store_path(args.store)
    od = _device_od(args.od, mode, node_id)
    # An explicit --heartbeat replaces 0x1017's start value (0 = off), so resets
    # come back to it; a value saved in --store is overwritten once after boot
    # (later resets load the saved one, as 0x1010 promises). Without it the
    # OD's value, or the saved one, rules.
    producer = od.get_variable(0x1017, 0)
    has_1017 = producer is not None
    if args.heartbeat is not None and has_1017:
        try:
            producer.value = args.heartbeat
        except CanopenFDError as exc:
            raise UsageError(f"--heartbeat {args.heartbeat}: {exc}") from None
    owned: List[Any] = []
    net = Network()
    try:
        line = _open_line(net, args, owned)
        printer = Printer()
        done = threading.Event()
        line.on_comm_event(lambda ev: printer.line(f"line {ev.name.lower().replace('_', ' ')}"))
        heartbeat = args.heartbeat if args.heartbeat is not None and not has_1017 else 0
        node = line.create_local_node(node_id, heartbeat_ms=heartbeat, od=od,
                                      store=args.store, boot=False)
        node.on_state_change(lambda old, new: printer.line(
            f"node {node_id}: {old.label} -> {new.label}"))
        node.on_reset(lambda kind: printer.line(f"node {node_id}: {kind.label}"))
        node.on_veto(lambda: printer.line(f"node {node_id}: start refused"))
        node.on_store_problem(lambda status, skipped: printer.line(
            f"node {node_id}: saved parameters in {args.store} are {status}; "
            "running on defaults"))
        node.boot()
        if args.heartbeat is not None and has_1017 and node.heartbeat_ms != args.heartbeat:
            node.heartbeat_ms = args.heartbeat   # a saved 0x1017 loaded at boot: override it
        source = args.od or f"builtin:{mode}"
        store = f", parameters in {args.store}" if args.store else ""
        print(f"node {node_id} running on {args.channel} ({line.mode}), heartbeat "
              f"{node.heartbeat_ms} ms, object dictionary {source}{store}; Ctrl-C to stop",
              file=sys.stderr)
        try:
            _wait(done, printer, args.duration)
        except KeyboardInterrupt:
            pass
        return EXIT_OK
    finally:
        _shutdown(net, owned)


def cmd_demo(args: argparse.Namespace) -> int:
    """Two nodes and a monitor on the in-process FD bus 'mem:demo'."""
    if args.duration <= 0:
        raise UsageError(f"--duration must be > 0 s, got {args.duration:g}")
    with Network() as net:
        printer = Printer()
        say = printer.line
        monitor = net.open_line("mem:demo", mode="fd", monitor=True)
        monitor.on_frame(lambda f: say(f"bus      {decode(f)}"))

        manager_line = net.open_line("mem:demo", mode="fd")
        manager_line.create_local_node(1)
        watched = manager_line.add_node(2, heartbeat_timeout_ms=250)
        lost = threading.Event()
        watched.on_bootup(lambda: say("node 1   sees node 2 boot-up"))
        watched.on_state_change(lambda s: say(f"node 1   sees node 2 {s.label}"))
        watched.on_heartbeat_started(lambda: say("node 1   node 2 heartbeat started"))
        watched.on_heartbeat_lost(lambda: (say("node 1   node 2 heartbeat lost"), lost.set()))

        device_line = net.open_line("mem:demo", mode="fd")
        device = device_line.create_local_node(2, heartbeat_ms=100, boot=False)
        device.on_state_change(lambda old, new: say(f"node 2   {old.label} -> {new.label}"))
        device.on_reset(lambda kind: say(f"node 2   {kind.label}"))
        device.boot()

        def step(text: str, action: Callable[[], None]) -> None:
            say(f"node 1   {text}")
            action()

        span = max(args.duration - 0.6, 0.6)
        t0 = printer.t0
        plan = [
            (0.15, "NMT start node 2", lambda: manager_line.nmt.start(2)),
            (0.40, "NMT stop node 2", lambda: manager_line.nmt.stop(2)),
            (0.60, "NMT pre-operational node 2", lambda: manager_line.nmt.pre_operational(2)),
            (0.80, "NMT reset-comm node 2", lambda: manager_line.nmt.reset_communication(2)),
            (1.00, "node 2 heartbeat off (0x1017 = 0)",
             lambda: setattr(device, "heartbeat_ms", 0)),
        ]
        try:
            for at, text, action in plan:
                delay = t0 + at * span - time.monotonic()
                if delay > 0:
                    time.sleep(delay)  # wall-clock protocol time passes between steps
                step(text, action)
            lost.wait(2.0)
            rest = t0 + args.duration - time.monotonic()
            if rest > 0:
                time.sleep(rest)
        except KeyboardInterrupt:
            pass
        states = ", ".join(f"{n}: {s.label}" for n, s in manager_line.states.items())
        say(f"done: states seen by node 1 {{{states}}}")
    return EXIT_OK


# ------------------------------------------------------------------ parser
def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="canopenfd", description="CANopen FD / classic CANopen tools")
    parser.add_argument("--version", action="version", version=f"canopenfd {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log to stderr")
    sub = parser.add_subparsers(dest="cmd", metavar="COMMAND")
    sub.required = True

    def line_options(p: argparse.ArgumentParser) -> None:
        p.add_argument("--channel", required=True,
                       help="SocketCAN interface (vcan0, can0), 'mem:NAME', or the "
                            "python-can channel with --interface")
        p.add_argument("--interface", metavar="NAME",
                       help="use python-can interface NAME (virtual, pcan, kvaser, ...)")
        p.add_argument("--classic", action="store_true", help="classic CAN line (default fd)")
        p.add_argument("--no-brs", action="store_true",
                       help="fd lines: send without bit-rate switch")

    p = sub.add_parser("demo", help="two nodes on an in-process CAN FD bus (no hardware)")
    p.add_argument("--duration", type=float, default=3.0, metavar="SECONDS")
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("nmt", help="send one NMT command")
    p.add_argument("command", choices=list(_NMT_CHOICES))
    p.add_argument("target", metavar="NODE|all", help="node-id 1..127, or all")
    line_options(p)
    p.add_argument("--timeout", type=float, default=2.0, metavar="SECONDS",
                   help="how long to wait for the frame to go out")
    p.set_defaults(func=cmd_nmt)

    p = sub.add_parser("monitor", help="print every frame, decoded")
    line_options(p)
    p.add_argument("--duration", type=float, metavar="SECONDS")
    p.add_argument("--count", type=int, metavar="N", help="stop after N frames")
    p.set_defaults(func=cmd_monitor)

    p = sub.add_parser("device", help="run a local node until interrupted")
    line_options(p)
    p.add_argument("--node-id", type=int, required=True)
    p.add_argument("--od", metavar="FILE",
                   help="object dictionary to serve: an EDS, DCF, XDD or XDC file, or "
                        "builtin:fd / builtin:classic (default: the built-in demo dictionary "
                        "of the line's mode)")
    p.add_argument("--store", metavar="FILE",
                   help="parameter store: values saved with 0x1010 load at boot and at "
                        "resets (the device saves nothing by itself)")
    p.add_argument("--heartbeat", type=int, default=None, metavar="MS",
                   help="heartbeat producer time, replacing the dictionary's 0x1017 "
                        "(0 = off; default: 0x1017 of the dictionary or the store)")
    p.add_argument("--duration", type=float, metavar="SECONDS")
    p.set_defaults(func=cmd_device)
    add_od_parser(sub)
    return parser


def main(argv: Optional[List[str]] = None) -> int:
    args = build_parser().parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    try:
        return args.func(args)
    except (CanopenFDError, UsageError) as exc:
        print(f"canopenfd: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
