"""The `canopenfd` command: demo, nmt, monitor, device, od, and the USDO
commands read, write, download, upload (canopenfd/cli_usdo.py).

Errors a user can fix (no such interface, wrong MTU, bad node-id) print one
line to stderr and exit with status 2, never a traceback.

`main(argv, network=...)` runs a command on a given Network (its lines stay
open afterwards) instead of one of its own: an in-process bus ('mem:NAME')
belongs to one Network, so tests and embedding programs reach the nodes they
run themselves this way.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import threading
import time
from typing import Any, Callable, Dict, List, Optional, Tuple

from . import __version__, cli_usdo
from .cli_od import add_od_parser
from .decode import Decoder, decode
from .errors import AbortError, CanopenFDError
from .frame import Frame
from .line import Line
from .network import Network
from .services.nmt import NmtCommand, parse_node_target
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


def _network(args: argparse.Namespace) -> Network:
    """The Network a command runs on: the one handed to main(), else a new one."""
    given = getattr(args, "network", None)
    return given if given is not None else Network()


def _owned(net: Network, args: argparse.Namespace) -> Optional[Network]:
    """net when the command created it (and closes it), None when it was handed in."""
    return None if net is getattr(args, "network", None) else net


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
    net = _network(args)
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
        _shutdown(_owned(net, args), owned)


def _monitor_od(spec: str) -> Tuple[Any, int]:
    """`monitor --od FILE[@NODE]`: the dictionary and the node-id it describes
    (NODE, else the node-id the DCF/XDC names)."""
    path, node = spec, None
    head, at, tail = spec.rpartition("@")
    if at and head and tail.strip().isdigit():
        path = head
        try:
            node = check_node_id(int(tail), f"--od {spec}: NODE")
        except CanopenFDError as exc:
            raise UsageError(str(exc)) from None
    from .od import OdFileError, import_od

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


def cmd_monitor(args: argparse.Namespace) -> int:
    if args.count is not None and args.count < 1:
        raise UsageError(f"--count must be >= 1, got {args.count}")
    # Follows SDO block transfers and guarding requests across frames; decodes
    # the PDOs of the --od dictionaries by their mappings.
    decoder = Decoder()
    for spec in args.od or ():
        od, node = _monitor_od(spec)
        count = decoder.add_od(od, node)
        print(f"node {node}: {count} PDO{'' if count == 1 else 's'} from {od.source or spec}",
              file=sys.stderr)
    owned: List[Any] = []
    net = _network(args)
    try:
        line = _open_line(net, args, owned, monitor=True)
        printer = Printer()
        done = threading.Event()
        seen = [0]

        def on_frame(frame: Frame) -> None:
            if done.is_set():
                return
            printer.line(f"{'TX' if frame.tx else 'RX'}  {decoder.describe(frame)}",
                         frame.timestamp)
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
        _shutdown(_owned(net, args), owned)


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


def _bytes_text(count: int) -> str:
    for unit, shift in (("GiB", 30), ("MiB", 20), ("KiB", 10)):
        if count >= 1 << shift and count % (1 << shift) == 0:
            return f"{count >> shift} {unit}"
    return f"{count} bytes"


def _device_domains(args: argparse.Namespace, od: Any, mode: str) -> Dict[Tuple[int, int], int]:
    """{(index, sub): capacity} of the DOMAIN entries the device keeps in
    memory: 0x2100 of the built-in fd dictionary (its DOMAIN_MAX_LENGTH,
    16 MiB, so the device can be the far end of large USDO transfers), then
    every --domain INDEX[:SUB]=BYTES (replacing a default for the same entry)."""
    from .od.demo import DOMAIN_MAX_LENGTH

    domains: Dict[Tuple[int, int], int] = {}
    if mode == "fd" and (args.od is None or args.od == "builtin:fd"):
        domains[(0x2100, 0)] = max(DOMAIN_MAX_LENGTH, 16 << 20)
    for spec in args.domain or ():
        index, sub, capacity = cli_usdo.parse_domain(spec, od)
        domains[(index, sub)] = capacity
    return domains


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
    domains = _device_domains(args, od, mode)
    owned: List[Any] = []
    net = _network(args)
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
        for (index, sub), capacity in domains.items():
            node.serve_domain((index, sub), capacity)
        node.boot()
        if args.heartbeat is not None and has_1017 and node.heartbeat_ms != args.heartbeat:
            node.heartbeat_ms = args.heartbeat   # a saved 0x1017 loaded at boot: override it
        source = args.od or f"builtin:{mode}"
        store = f", parameters in {args.store}" if args.store else ""
        for (index, sub), capacity in domains.items():
            name = od.get_variable(index, sub).qualname
            print(f"node {node_id}: 0x{index:04X}:{sub:02X} {name} in {_bytes_text(capacity)} "
                  "of memory", file=sys.stderr)
        print(f"node {node_id} running on {args.channel} ({line.mode}), heartbeat "
              f"{node.heartbeat_ms} ms, object dictionary {source}{store}; Ctrl-C to stop",
              file=sys.stderr)
        try:
            _wait(done, printer, args.duration)
        except KeyboardInterrupt:
            pass
        return EXIT_OK
    finally:
        _shutdown(_owned(net, args), owned)


_DEMO_BULK = 1 << 20          # bytes the demo moves each way over USDO
# Events the demo's runtime can queue: its monitor line reports each of the
# ~52 000 frames of the 1 MiB round trip, faster than Python takes them.
_DEMO_EVENTS = 1 << 16
_USDO_IDS = range(0x581, 0x680)   # USDO responses 0x581..0x5FF, requests 0x601..0x67F


class _FrameCount:
    """USDO frames the demo's monitor has shown (to wait for them)."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self.count = 0

    def add(self) -> None:
        with self._cond:
            self.count += 1
            self._cond.notify_all()

    def wait(self, count: int, timeout: float = 1.0) -> None:
        with self._cond:
            self._cond.wait_for(lambda: self.count >= count, timeout)


def _finished(transfer: Any) -> float:
    """Wait for a USDO transfer; the time it ended. Polls the runtime: the
    done event queues behind the monitor's frame events of a bulk transfer."""
    while not transfer.done():
        time.sleep(0.001)
    return time.monotonic()


def _demo_usdo(say: Callable[..., None], line: Line, remote: Any, device: Any,
               shown: _FrameCount, mute_from: List[float]) -> bool:
    """The demo's USDO part (SDO on classic lines; node 1 is the client,
    node 2 the server): a typed read, a write read back, then the bulk size
    (block on classic lines) down into node 2's memory domain 0x2100 and back
    up, compared byte for byte. False on a mismatch."""
    fd = line.mode == "fd"
    proto, bulk_mode = ("USDO", "bulk") if fd else ("SDO", "block")
    client = line.usdo if fd else line.sdo
    vendor = remote.od["Identity object.Vendor-ID"]
    say(f"node 1   {proto} read node 2 0x1018:01 Identity object.Vendor-ID")
    value = vendor.raw
    shown.wait(2)
    say(f"node 1   node 2 Vendor-ID = {value} (0x{value:08X})")
    setpoint = remote.od["Demo record.Setpoint"]
    say(f"node 1   {proto} write node 2 0x2200:01 Demo record.Setpoint = 123, read it back")
    setpoint.raw = 123
    back = setpoint.raw
    shown.wait(6)
    say(f"node 1   node 2 Setpoint reads back {back}"
        f"{'' if back == 123 else ' (expected 123)'}")

    total = _DEMO_BULK if fd else _DEMO_BULK_CLASSIC
    payload = os.urandom(total)
    size = f"{total >> 20} MiB" if total % (1 << 20) == 0 else f"{total >> 10} KiB"
    say(f"node 1   {proto} {size} to node 2 0x2100 (a memory domain) and back; frames not "
        "shown")
    started = time.monotonic()
    mute_from[0] = started
    transfer = client.start_download(2, 0x2100, 0, payload, mode=bulk_mode)
    ended = _finished(transfer)
    transfer.result()
    down_ok = device[0x2100].data == payload
    say(f"node 1   download: {transfer.transferred} bytes, {transfer.mode}, "
        f"{ended - started:.3f} s, {_rate(transfer.transferred, ended - started)}; node 2 "
        f"holds {'identical' if down_ok else 'DIFFERENT'} bytes")
    started = time.monotonic()
    transfer = client.start_upload(2, 0x2100, 0, max_size=total,
                                  **({} if fd else {"size_hint": total}))
    ended = _finished(transfer)
    data = transfer.result()
    up_ok = data == payload
    mode = transfer.mode if transfer.mode not in (None, "auto") else "mode of the server's choice"
    say(f"node 1   upload: {transfer.transferred} bytes, {mode}, {ended - started:.3f} s, "
        f"{_rate(transfer.transferred, ended - started)}; "
        f"{'identical to' if up_ok else 'DIFFERENT from'} what was sent")
    return down_ok and up_ok and back == 123


def _rate(count: int, seconds: float) -> str:
    return f"{count / seconds / 1e6:.1f} MB/s" if seconds > 0 else "- MB/s"


_DEMO_BULK_CLASSIC = 64 << 10  # classic lines: SDO block transfer, 7 bytes a frame
_PROCESS_DATA = 0x2300        # the demo's PDO-mappable UNSIGNED32 array (built here)
_SYNC_PERIOD = 0.05           # s
_SYNC_OVERFLOW = 8            # the SYNC counter runs 1..8
_SYNC_SHOWN = 4               # SYNC exchanges printed before SYNC stops
_EMCY_CODE = 0x2310           # "current, device output side"


def _demo_node_od(mode: str) -> Any:
    """The built-in demo dictionary plus what the process-data part needs:
    SYNC (0x1005, 0x1006, 0x1019 = 8, so SYNCs carry a counter), RPDO 1 and
    TPDO 1 (16 mapping entries each) and "Process data" 0x2300, 16 mappable
    UNSIGNED32 entries (64 bytes: one full CAN FD PDO)."""
    from .od import DataType, ODArray, ODRecord, ODVariable, demo_od

    u8, u16, u32 = DataType.UNSIGNED8, DataType.UNSIGNED16, DataType.UNSIGNED32
    od = demo_od(mode)
    od.add_object(ODVariable("COB-ID SYNC message", 0x1005, 0, u32, "rw", 0x80))
    od.add_object(ODVariable("Communication cycle period", 0x1006, 0, u32, "rw", 0))
    od.add_object(ODVariable("Synchronous counter overflow value", 0x1019, 0, u8, "rw",
                             _SYNC_OVERFLOW))
    fields = {1: ("COB-ID used by PDO", u32), 2: ("Transmission type", u8),
              3: ("Inhibit time", u16), 5: ("Event timer", u16), 6: ("SYNC start value", u8)}
    for kind, comm, mapping, base, subs in (("RPDO", 0x1400, 0x1600, 0x200, (1, 2, 5)),
                                            ("TPDO", 0x1800, 0x1A00, 0x180, (1, 2, 3, 5, 6))):
        record = ODRecord(f"{kind} communication parameter 1", comm)
        record.add_member(ODVariable("Highest sub-index supported", comm, 0, u8, "ro",
                                     max(subs)))
        for sub in subs:
            name, dtype = fields[sub]
            var = ODVariable(name, comm, sub, dtype, "rw", 255 if sub == 2 else 0)
            if sub == 1:   # CiA 301 predefined COB-ID, invalid until configured
                var.set_default(0x80000000 + base, relative_to_node_id=True)
            record.add_member(var)
        od.add_object(record)
        array = ODArray(f"{kind} mapping parameter 1", mapping)
        array.add_member(ODVariable("Number of mapped objects", mapping, 0, u8, "rw", 0))
        for sub in range(1, 17):
            array.add_member(ODVariable(f"Mapped object {sub}", mapping, sub, u32, "rw", 0))
        od.add_object(array)
    data = ODArray("Process data", _PROCESS_DATA)
    data.add_member(ODVariable("Highest sub-index supported", _PROCESS_DATA, 0, u8, "ro", 16))
    for sub in range(1, 17):
        data.add_member(ODVariable(f"Process data {sub}", _PROCESS_DATA, sub, u32, "rw", 0,
                                   pdo_mapping=True))
    od.add_object(data)
    return od


def _values_text(values: List[int]) -> str:
    return " ".join(str(v) for v in values)


def _emcy_text(emcy: Any) -> str:
    """Every field of a received EMCY, one line."""
    meaning = emcy.text if emcy.text.startswith("0x") else f"0x{emcy.code:04X} {emcy.text}"
    text = (f"EMCY from node {emcy.node}: code {meaning}, "
            f"register 0x{emcy.register:02X}, data {emcy.data.hex(' ')}")
    if emcy.fd:
        text += (f", logical device {emcy.logical_device}, spec {emcy.spec_number}, "
                 f"priority {emcy.priority}, non-recoverable {emcy.non_recoverable}, "
                 f"occurred {emcy.occurred}, repeated {emcy.repeated}, "
                 f"time stamp {emcy.time_stamp}")
    return text + (", error removed" if emcy.removed else "")


def _demo_process_data(say: Callable[..., None], manager_line: Line, manager: Any,
                       watched: Any, device_line: Line, device: Any) -> bool:
    """The demo's PDO, SYNC and EMCY part: node 2's TPDO 1 (64 bytes on fd
    lines, 8 on classic ones) into node 1's RPDO 1, once on request, then at
    every SYNC node 1 produces; then node 2 raises and clears an EMCY that
    node 1 consumes. False when node 1 received other values than were sent."""
    fd = manager_line.mode == "fd"
    count = 16 if fd else 2                     # UNSIGNED32 entries: 64 or 8 bytes
    subs = range(1, count + 1)
    names = f"Process data 1..{count}"
    cob_id = 0x180 + device.node_id

    say("node 1   NMT start node 2; node 1 starts itself")
    manager_line.nmt.start(2)
    manager.apply("start")
    device.wait_for_state("OPERATIONAL", timeout=2)
    tpdo = device.tpdo[1]
    tpdo.read()
    tpdo.clear()
    for sub in subs:
        tpdo.add_variable(_PROCESS_DATA, sub)
    tpdo.cob_id = cob_id
    tpdo.trans_type = 254                      # event-driven: sent on transmit()
    tpdo.enabled = True
    tpdo.save()
    rpdo = manager.rpdo[1]
    rpdo.read()
    rpdo.clear()
    for sub in subs:
        rpdo.add_variable(_PROCESS_DATA, sub)
    rpdo.cob_id = cob_id
    rpdo.enabled = True
    rpdo.save()
    say(f"node 2   TPDO1 0x{cob_id:03X} maps {names} (UNSIGNED32): {count * 4} bytes; "
        f"node 1 RPDO1 maps the same")

    sent = [sub * 1000 + sub for sub in subs]
    rest = f"Process data 2..{count}" if count > 2 else "Process data 2"
    received: List[List[int]] = []
    got = threading.Condition()
    last_sync = [0]

    def on_rpdo(pdo: Any) -> None:
        values = [v.raw for v in pdo]
        with got:
            received.append(values)
            got.notify_all()
        if len(received) == 1:
            say(f"node 1   RPDO1 from node 2: {len(pdo.data)} bytes, {names} = "
                f"{_values_text(values)}")
        elif len(received) <= 1 + _SYNC_SHOWN:
            say(f"node 1   SYNC {last_sync[0]} -> RPDO1 from node 2: Process data 1 = "
                f"{values[0]}, {rest} "
                f"{'unchanged' if values[1:] == sent[1:] else 'CHANGED'}")

    def wait_received(n: int) -> bool:
        with got:
            return got.wait_for(lambda: len(received) >= n, 2.0)

    rpdo.add_callback(on_rpdo)
    for sub, value in zip(subs, sent):
        device[_PROCESS_DATA][sub].raw = value
    say(f"node 2   TPDO1 transmit: {names} = {_values_text(sent)}")
    tpdo.transmit()
    ok = wait_received(1) and received[0] == sent
    say(f"node 1   RPDO1 values {'equal' if ok else 'DIFFER FROM'} what node 2 sent")

    # SYNC: node 1's line produces it, node 2's TPDO 1 answers each one; node
    # 2's application writes 10 x the counter into Process data 1 after each
    # SYNC, so every answer carries the previous SYNC's sample.
    tpdo.trans_type = 1
    tpdo.save()
    device_line.sync.add_callback(
        lambda counter: setattr(device[_PROCESS_DATA][1], "raw", counter * 10))
    manager_line.sync.add_callback(lambda counter: last_sync.__setitem__(0, counter))
    say("node 2   TPDO1 now synchronous (type 1); after each SYNC node 2 writes 10 x the "
        "counter into Process data 1")
    say(f"node 1   SYNC every {_SYNC_PERIOD * 1000:g} ms, counter 1..{_SYNC_OVERFLOW}")
    manager_line.sync.start(_SYNC_PERIOD, overflow=_SYNC_OVERFLOW)
    synced = wait_received(1 + _SYNC_SHOWN)
    manager_line.sync.stop()
    say(f"node 1   SYNC stopped; {min(len(received) - 1, _SYNC_SHOWN)} synchronous PDOs "
        "shown" + ("" if synced else " (TOO FEW)"))

    # EMCY: node 2 raises an error and clears it, node 1 consumes both
    emcys: List[Any] = []
    emcy_seen = threading.Condition()

    def on_emcy(emcy: Any) -> None:
        say(f"node 1   {_emcy_text(emcy)}")
        with emcy_seen:
            emcys.append(emcy)
            emcy_seen.notify_all()

    def wait_emcys(n: int) -> bool:
        with emcy_seen:
            return emcy_seen.wait_for(lambda: len(emcys) >= n, 2.0)

    watched.emcy.add_callback(on_emcy)
    extra = dict(logical_device=1, spec_number=301, priority=2,
                 time_stamp=123456789) if fd else {}
    say(f"node 2   EMCY raise 0x{_EMCY_CODE:04X}, data 01 02, manufacturer register bit"
        + (", logical device 1, spec 301, priority 2, time stamp 123456789" if fd else ""))
    device.emcy.raise_error(_EMCY_CODE, b"\x01\x02", register_bits=0x80, **extra)
    raised = wait_emcys(1)
    say(f"node 2   error register 0x{device.emcy.error_register:02X}, "
        f"{device.emcy.active} active; node 1 sees active "
        f"[{', '.join(f'0x{c:04X}' for c in watched.emcy.active)}]")
    say(f"node 2   EMCY clear 0x{_EMCY_CODE:04X}")
    device.emcy.clear(_EMCY_CODE, **({"logical_device": 1} if fd else {}))
    cleared = wait_emcys(2)
    say(f"node 2   error register 0x{device.emcy.error_register:02X}, "
        f"{device.emcy.active} active; node 1 sees active "
        f"[{', '.join(f'0x{c:04X}' for c in watched.emcy.active)}]")
    return ok and synced and raised and cleared


def cmd_demo(args: argparse.Namespace) -> int:
    """Two nodes and a monitor on the in-process bus 'mem:demo' (CAN FD, or
    classic with --classic): NMT and heartbeat, USDO (a read, a write, 1 MiB
    each way; SDO and 64 KiB on classic lines), then PDOs, SYNC and EMCY."""
    from .od import demo_od

    mode = "classic" if args.classic else "fd"
    if args.duration <= 0:
        raise UsageError(f"--duration must be > 0 s, got {args.duration:g}")
    with Network(event_capacity=_DEMO_EVENTS) as net:
        printer = Printer()
        say = printer.line
        shown = _FrameCount()
        mute_from = [float("inf")]   # frames stamped from then on are not shown

        def on_frame(frame: Frame) -> None:
            if frame.timestamp >= mute_from[0]:
                return
            say(f"bus      {decode(frame)}")
            if frame.id in _USDO_IDS:
                shown.add()

        monitor = net.open_line("mem:demo", mode=mode, monitor=True)
        monitor.on_frame(on_frame)

        manager_line = net.open_line("mem:demo", mode=mode)
        manager = manager_line.create_local_node(1, od=_demo_node_od(mode))
        watched = manager_line.add_node(2, heartbeat_timeout_ms=250, od=demo_od(mode))
        lost = threading.Event()
        watched.on_bootup(lambda: say("node 1   sees node 2 boot-up"))
        watched.on_state_change(lambda s: say(f"node 1   sees node 2 {s.label}"))
        watched.on_heartbeat_started(lambda: say("node 1   node 2 heartbeat started"))
        watched.on_heartbeat_lost(lambda: (say("node 1   node 2 heartbeat lost"), lost.set()))

        device_line = net.open_line("mem:demo", mode=mode)
        device = device_line.create_local_node(2, heartbeat_ms=100, od=_demo_node_od(mode),
                                               boot=False)
        device.serve_domain(0x2100, _DEMO_BULK)
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
            try:
                usdo_ok = _demo_usdo(say, manager_line, watched, device, shown, mute_from)
            except AbortError as exc:
                say(f"node 1   {'USDO' if mode == 'fd' else 'SDO'} failed: {exc}")
                usdo_ok = False
            try:
                process_ok = _demo_process_data(say, manager_line, manager, watched,
                                                device_line, device)
            except (CanopenFDError, TimeoutError) as exc:
                say(f"node 1   PDO/SYNC/EMCY part failed: {exc}")
                process_ok = False
            usdo_ok = usdo_ok and process_ok
        except KeyboardInterrupt:
            usdo_ok = True
        states = ", ".join(f"{n}: {s.label}" for n, s in manager_line.states.items())
        say(f"done: states seen by node 1 {{{states}}}")
    return EXIT_OK if usdo_ok else EXIT_FAILED


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
    p.add_argument("--classic", action="store_true",
                   help="classic CAN bus instead (SDO, 8-byte PDOs, classic EMCY)")
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
    p.add_argument("--od", action="append", metavar="FILE[@NODE]",
                   help="object dictionary (EDS, DCF, XDD or XDC) of node NODE: its PDOs "
                        "are shown as name=value by their mapping; NODE may be left out when "
                        "the file names its node-id (DCF, XDC); repeatable, one per node")
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
    p.add_argument("--domain", action="append", metavar="INDEX[:SUB]=BYTES",
                   help="keep DOMAIN entry INDEX[:SUB] (hex, or a name) in memory of BYTES "
                        "(like 16M, 512K, 0x100000), so USDO/SDO uploads and downloads reach "
                        "it; repeatable (the built-in fd dictionary has 0x2100 = 16M already)")
    p.add_argument("--duration", type=float, metavar="SECONDS")
    p.set_defaults(func=cmd_device)
    add_od_parser(sub)
    cli_usdo.add_usdo_parsers(sub, line_options)
    return parser


def main(argv: Optional[List[str]] = None, network: Optional[Network] = None) -> int:
    """Run the command line argv (default sys.argv[1:]); the exit status.
    network: run on this Network instead of a new one (see the module doc)."""
    args = build_parser().parse_args(argv)
    args.network = network
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
