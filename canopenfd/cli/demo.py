"""`canopenfd demo`: two nodes and a monitor on an in-process bus, no
hardware: NMT and heartbeat, USDO (SDO on classic lines), PDOs, SYNC, EMCY."""

from __future__ import annotations

import argparse
import os
import threading
import time
from typing import Any, Callable, List

from ..decode import decode
from ..errors import AbortError, CanopenFDError
from ..frame import Frame
from ..line import Line
from ..od.demo import PROCESS_DATA
from ..network import Network
from . import demo_manager
from .common import EXIT_FAILED, EXIT_OK, Printer, UsageError, rate_text


def add_parsers(subparsers: Any) -> None:
    p = subparsers.add_parser("demo", help="two nodes on an in-process CAN FD bus (no hardware)")
    p.add_argument("--duration", type=float, default=3.0, metavar="SECONDS",
                   help="how long the NMT and heartbeat part runs before the USDO/SDO and "
                        "process-data parts (default 3)")
    p.add_argument("--classic", action="store_true",
                   help="classic CAN bus instead (SDO, 8-byte PDOs, classic EMCY)")
    p.add_argument("--manager", action="store_true",
                   help="instead: a network manager bringing up three devices (LSS fast scan "
                        "of a factory-fresh one, a re-configuration from a DCF, CiA 302-2 "
                        "start-up)")
    p.set_defaults(func=cmd_demo)


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
        f"{ended - started:.3f} s, {rate_text(transfer.transferred, ended - started)}; node 2 "
        f"holds {'identical' if down_ok else 'DIFFERENT'} bytes")
    started = time.monotonic()
    transfer = client.start_upload(2, 0x2100, 0, max_size=total,
                                  size_hint=0 if fd else total)
    ended = _finished(transfer)
    data = transfer.result()
    up_ok = data == payload
    mode = transfer.mode if transfer.mode not in (None, "auto") else "mode of the server's choice"
    say(f"node 1   upload: {transfer.transferred} bytes, {mode}, {ended - started:.3f} s, "
        f"{rate_text(transfer.transferred, ended - started)}; "
        f"{'identical to' if up_ok else 'DIFFERENT from'} what was sent")
    return down_ok and up_ok and back == 123


_DEMO_BULK_CLASSIC = 64 << 10  # classic lines: SDO block transfer, 7 bytes a frame
_PROCESS_DATA = PROCESS_DATA  # the demo's PDO-mappable UNSIGNED32 array
_SYNC_PERIOD = 0.05           # s
_SYNC_OVERFLOW = 8            # the SYNC counter runs 1..8
_SYNC_SHOWN = 4               # SYNC exchanges printed before SYNC stops
_EMCY_CODE = 0x2310           # "current, device output side"


def _demo_node_od(mode: str) -> Any:
    """The built-in demo dictionary with RPDO 1 / TPDO 1, the SYNC objects and
    "Process data" 0x2300 (demo_od(pdos=1)); 0x1019 = 8, so SYNCs carry a counter."""
    from ..od import demo_od

    od = demo_od(mode, pdos=1)
    overflow = od.get_variable(0x1019, 0)
    assert overflow is not None   # demo_od(pdos=...) has the SYNC objects
    overflow.default = _SYNC_OVERFLOW
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


def _final_states(manager_line: Any, device: Any) -> str:
    """The last line: node 2's own state, and what node 1 last heard from
    heartbeats, marked stale when node 2's heartbeat is off (the demo switches
    it off, so node 1's view stops at that moment)."""
    heard = ", ".join(f"{n}: {s.label}" for n, s in manager_line.states.items())
    stale = " (node 2's heartbeat is off since; node 1 hears no later state)" \
        if device.heartbeat_ms == 0 else ""
    return (f"done: node 2 is {device.state.label}; last states heard by node 1 "
            f"{{{heard}}}{stale}")


def cmd_demo(args: argparse.Namespace) -> int:
    """Two nodes and a monitor on the in-process bus 'mem:demo' (CAN FD, or
    classic with --classic): NMT and heartbeat, USDO (a read, a write, 1 MiB
    each way; SDO and 64 KiB on classic lines), then PDOs, SYNC and EMCY."""
    from ..od import demo_od

    if args.manager:
        return demo_manager.run(args.classic, Printer().line)
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
        manager = manager_line.create_local_node(1, od=_demo_node_od(mode), boot=False)
        manager.serve_domain(0x2100, 64 << 10)   # node 1 is no bulk target: a little memory
        manager.boot()
        watched = manager_line.add_node(2, heartbeat_timeout_ms=250, od=demo_od(mode))
        lost = threading.Event()
        watched.on_bootup(lambda: say("node 1   sees node 2 boot-up"))
        watched.on_state_change(lambda s: say(f"node 1   sees node 2 {s.label}"))
        watched.on_heartbeat_started(lambda: say("node 1   node 2 heartbeat started"))
        def on_lost() -> None:
            say("node 1   node 2 heartbeat lost")
            lost.set()

        watched.on_heartbeat_lost(on_lost)

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
        say(_final_states(manager_line, device))
    return EXIT_OK if usdo_ok else EXIT_FAILED

