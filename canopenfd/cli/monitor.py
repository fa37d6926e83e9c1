"""`canopenfd monitor`: print every frame of a line, raw and decoded; filter
them (--node, --service, --id), write them to a log file (--log) or decode
a log file offline (--replay).

Receive path: a monitor line posts each frame as an event into the
runtime's event queue; the Network's dispatcher reads them in batches
(EVENT_BATCH per call) and hands them to `on_frame`. A Python consumer
decodes some 25 000 - 45 000 frames/s, while an in-process bus moves
hundreds of thousands: the monitor opens its Network with a large event
queue (MONITOR_EVENT_CAPACITY events, memory touched only as far as a
backlog reaches) so a burst is shown late but whole. Should the queue fill
anyway, the runtime counts what it dropped per line (events_lost, plus
rx_overflow of the line's receive queue); the monitor prints that count in
its output as soon as it grows, and at the end, never guessed."""

from __future__ import annotations

import argparse
import sys
import threading
import time
from typing import Any, Callable, Dict, Iterable, Optional, Tuple

from ..decode import Decoder
from ..frame import Frame
from .common import (EXIT_OK, Printer, UsageError, add_line_options, command_line, node_id_arg)
from .frame_filter import FrameFilter, add_filter_options

#: Events the monitor's own runtime queues for it (112 bytes each, at most
#: 28 MiB, touched only as far as a backlog reaches): a 4 MiB USDO bulk
#: transfer on an in-process bus (69 909 frames) fits.
MONITOR_EVENT_CAPACITY = 1 << 18

#: How often a live monitor flushes its output and looks at the loss counters.
_TICK_S = 0.2


def add_parsers(subparsers: Any) -> None:
    p = subparsers.add_parser("monitor", help="print every frame, decoded; log or replay them")
    add_line_options(p, channel_required=False)
    p.add_argument("--od", action="append", metavar="FILE[@NODE]",
                   help="object dictionary (EDS, DCF, XDD or XDC) of node NODE: its PDOs "
                        "are shown as name=value by their mapping; NODE may be left out when "
                        "the file names its node-id (DCF, XDC); repeatable, one per node")
    p.add_argument("--duration", type=float, metavar="SECONDS",
                   help="stop after SECONDS (default: run until Ctrl-C)")
    p.add_argument("--count", type=int, metavar="N", help="stop after N frames shown")
    p.add_argument("--log", metavar="FILE",
                   help="also write the frames shown to FILE with python-can's can.Logger; "
                        "the extension picks the format: .log (candump -L), .asc, .blf "
                        "(these keep CAN FD frames), .csv, .trc (classic frames only), "
                        ".mf4, .db, as the installed python-can writes them; FILE.log.gz "
                        "compresses")
    p.add_argument("--replay", metavar="FILE",
                   help="decode the frames of a log file (any format can.LogReader reads: "
                        ".log, .asc, .blf, .csv, .trc, .mf4, .db) instead of a bus: same "
                        "output, times relative to its first frame; replaces --channel")
    add_filter_options(p)
    p.set_defaults(func=cmd_monitor)


def _monitor_od(spec: str) -> Tuple[Any, int]:
    """`monitor --od FILE[@NODE]`: the dictionary and the node-id it describes
    (NODE, else the node-id the DCF/XDC names)."""
    path, node = spec, None
    head, at, tail = spec.rpartition("@")
    if at and head and tail.strip().isdigit():
        path = head
        node = node_id_arg(int(tail), f"--od {spec}: NODE")
    from ..od import OdFileError, import_od

    try:
        od = import_od(path, node_id=node)
    except OdFileError as exc:
        raise UsageError(f"--od {exc}") from None
    except OSError as exc:
        raise UsageError(f"--od {path}: {exc.strerror or exc}") from None
    node = node if node is not None else od.node_id
    if node is None:
        raise UsageError(f"--od {spec}: give the node-id it describes as FILE@NODE "
                         "(the file names none)")
    return od, node


class _Shown:
    """What the monitor does with each frame: filter, decode, print, log;
    stops at --count. One thread feeds it (the dispatcher, or the replay)."""

    def __init__(self, args: argparse.Namespace, decoder: Decoder, printer: Printer,
                 frame_filter: FrameFilter, log: Any) -> None:
        self.count = args.count
        self.decoder = decoder
        self.printer = printer
        self.filter = frame_filter
        self.log = log
        self.done = threading.Event()
        self.shown = 0
        self.hidden = 0
        self._stopped = False
        self._lock = threading.Lock()   # stop() waits for a frame being handled

    def stop(self) -> None:
        """No frame after this (the log is closed next)."""
        with self._lock:
            self._stopped = True
            self.done.set()

    def __call__(self, frame: Frame) -> None:
        with self._lock:
            if not self._stopped:
                self._handle(frame)

    def _handle(self, frame: Frame) -> None:
        if self.done.is_set():
            return
        if self.filter.active and not self.filter.accepts(frame, self.decoder):
            self.decoder.meaning(frame)        # keeps following transfers and guarding
            self.hidden += 1
            return
        self.printer.line(f"{'TX' if frame.tx else 'RX'}  {self.decoder.describe(frame)}",
                          frame.timestamp)
        if self.log is not None:
            self.log.write(frame)
        self.shown += 1
        if self.count is not None and self.shown >= self.count:
            self.done.set()

    def summary(self, lost: Optional[int]) -> str:
        parts = [f"{self.shown} frame{'' if self.shown == 1 else 's'} shown"]
        if self.hidden:
            parts.append(f"{self.hidden} filtered out")
        if lost is not None:
            parts.append(f"{lost} lost" + (" (the monitor fell behind: the runtime's event "
                                           "queue was full)" if lost else ""))
        if self.log is not None:
            parts.append(f"{self.log.written} written to {self.log.path}")
        return "monitor: " + ", ".join(parts)


def cmd_monitor(args: argparse.Namespace) -> int:
    if args.count is not None and args.count < 1:
        raise UsageError(f"--count must be >= 1, got {args.count}")
    if (args.channel is None) == (args.replay is None):
        raise UsageError("monitor needs --channel (a bus) or --replay FILE (a log file), "
                         "not both" if args.channel else "monitor needs --channel (a bus) or "
                         "--replay FILE (a log file)")
    if args.replay is not None and args.duration is not None:
        raise UsageError("--duration is for a bus: --replay reads the whole file")
    frame_filter = FrameFilter.from_args(args)
    # Follows SDO block transfers and guarding requests across frames; decodes
    # the PDOs of the --od dictionaries by their mappings.
    decoder = Decoder()
    for spec in args.od or ():
        od, node = _monitor_od(spec)
        count = decoder.add_od(od, node)
        print(f"node {node}: {count} PDO{'' if count == 1 else 's'} from {od.source or spec}",
              file=sys.stderr)
    from .frame_log import FrameLog, read_log

    frames = read_log(args.replay) if args.replay is not None else None
    log = FrameLog(args.log, fd_line=args.replay is None and not args.classic) \
        if args.log else None
    try:
        if frames is not None:
            return _replay(args, frames, decoder, frame_filter, log)
        return _live(args, decoder, frame_filter, log)
    finally:
        if log is not None:
            log.close()


def _replay(args: argparse.Namespace, frames: Iterable[Frame], decoder: Decoder,
            frame_filter: FrameFilter, log: Any) -> int:
    printer: Optional[Printer] = None
    shown: Optional[_Shown] = None
    for frame in frames:
        if printer is None:
            printer = Printer(t0=frame.timestamp, flush=False)
            shown = _Shown(args, decoder, printer, frame_filter, log)
        assert shown is not None
        shown(frame)
        if shown.done.is_set() or printer.broken.is_set():
            break
    if printer is None:
        print(f"monitor: {args.replay} holds no frames", file=sys.stderr)
        return EXIT_OK
    assert shown is not None
    printer.flush()
    print(shown.summary(None), file=sys.stderr)
    return EXIT_OK


def _live(args: argparse.Namespace, decoder: Decoder, frame_filter: FrameFilter,
          log: Any) -> int:
    with command_line(args, monitor=True, event_capacity=MONITOR_EVENT_CAPACITY) as line:
        # a terminal shows each line at once; a file or pipe gets them every _TICK_S
        isatty = getattr(sys.stdout, "isatty", None)
        printer = Printer(flush=bool(isatty and isatty()))
        shown = _Shown(args, decoder, printer, frame_filter, log)
        line.on_frame(shown)
        line.on_comm_event(lambda ev: printer.line(f"--  {ev.name.lower().replace('_', ' ')}"))
        print(f"monitoring {args.channel} ({line.mode}); Ctrl-C to stop", file=sys.stderr)
        lost = _LossCounter(lambda: line.stats)
        try:
            _run(shown.done, printer, args.duration, lost)
        except KeyboardInterrupt:
            pass
        shown.stop()
        lost.report(printer)
        printer.flush()
        print(shown.summary(lost.total), file=sys.stderr)
        return EXIT_OK


class _LossCounter:
    """The frames the runtime dropped for the monitor line: its events lost
    (event queue full) and rx overflows (receive queue full), C counters."""

    def __init__(self, stats: Callable[[], Dict[str, int]]) -> None:
        self._stats = stats
        self._base = self._read()
        self.total = 0

    def _read(self) -> int:
        stats = self._stats()
        return int(stats["events_lost"]) + int(stats["rx_overflow"])

    def report(self, printer: Printer) -> None:
        """A line in the output when frames were lost since the last look."""
        now = self._read() - self._base
        if now > self.total:
            printer.line(f"--  {now - self.total} frames lost: the monitor fell behind "
                         f"(the runtime's event queue was full); {now} lost so far")
            self.total = now


def _run(done: threading.Event, printer: Printer, duration: Optional[float],
         lost: _LossCounter) -> None:
    """Until done, a broken pipe, or duration seconds (None = forever);
    flushes the output and reports losses every _TICK_S."""
    deadline = None if duration is None else time.monotonic() + duration
    while not done.is_set() and not printer.broken.is_set():
        remaining = None if deadline is None else deadline - time.monotonic()
        if remaining is not None and remaining <= 0:
            return
        done.wait(_TICK_S if remaining is None else min(remaining, _TICK_S))
        lost.report(printer)
        printer.flush()
