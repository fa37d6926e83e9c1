"""The gateway side of the seed 001 remote-access protocol: serves the lines
of a Network to hosts over byte streams (serial ports, TCP connections).

Per network number (the start byte's bits 0..3) one Line: local commands
(W, R) reach the line's local node's OD or the gateway's own entries
(0x5F00 status, 0x5F01 control, 0x5F04 node states, 0x5F0A NMT); remote
commands (S, U) run on the line's USDO client (fd) or SDO client (classic),
one at a time per connection (a second one is answered BUSY, as the seed's
limited implementations do). Indications D go to every connection: entries
of the local node written by the network, NMT states and heartbeat events of
every node, EMCYs, the CAN side's condition, and the PDO values of scanned
nodes (remote_access_manager.py).

Each connection has a reader thread (frames in, local commands answered at
once), a worker for its remote command and a writer thread with a bounded
queue, so a slow host never holds the CAN side: indications beyond the bound
are dropped and counted, responses never (with RESPONSE_QUEUE of them
waiting, the host's further requests are not read until it takes some).
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from functools import partial
from typing import Callable, Dict, List, Mapping, Optional, Tuple, Union

from .. import CommEvent, __version__
from ..errors import AbortError, CanopenFDError, ConfigurationError
from ..line import Line, ODLike
from ..node import LocalNode
from ..services.emcy import Emcy
from ..services.nmt import NmtState
from ..services.served_od import LocalValue
from ..transfer.client import Transfer
from ..transfer.sdo import SdoClient
from ..transfer.usdo import UsdoClient
from . import remote_access as ra
from .node_turns import TurnTimeout, taking_turn
from .remote_access_manager import MinimalManager, node_status_of
from .remote_access_stream import ByteStream, TcpListener, open_serial

log = logging.getLogger(__name__)

#: Indications a connection queues for a slow host before dropping (counted).
INDICATION_QUEUE = 4096
#: Responses a connection queues for its host; then its input is not read
#: until the host takes some (responses are never dropped).
RESPONSE_QUEUE = 64
#: Hosts served at once (each costs three threads); more are closed, counted.
MAX_CONNECTIONS = 16

_ABORT_BITS = {
    0x06020000: ra.RaError.OD_NOT_FOUND,      # object does not exist
    0x06090011: ra.RaError.OD_NOT_FOUND,      # sub-index does not exist
    0x06070010: ra.RaError.INVALID_LENGTH,    # length does not match
    0x06070012: ra.RaError.INVALID_LENGTH,    # too long
    0x06070013: ra.RaError.INVALID_LENGTH,    # too short
    0x05030000: ra.RaError.TOGGLE,
    0x05040000: ra.RaError.TIMEOUT,
    0x05040005: ra.RaError.NO_RESOURCES,      # out of memory
    0x06010000: ra.RaError.NOT_SUPPORTED,     # unsupported access
    0x06010001: ra.RaError.NOT_SUPPORTED,     # write-only entry read
    0x06010002: ra.RaError.NOT_SUPPORTED,     # read-only entry written
}


def error_for_abort(code: int) -> int:
    """The error bits for a CiA 301 abort code: its own bit where the seed has
    one, else 'transfer was aborted'."""
    return int(_ABORT_BITS.get(code, ra.RaError.ABORTED))


#: The hardware status bits a communication event sets, and those it clears.
_HW_SET = {CommEvent.BUS_OFF: ra.HwStatus.BUS_OFF,
           CommEvent.ERROR_PASSIVE: ra.HwStatus.ERROR_PASSIVE,
           CommEvent.ERROR_WARNING: ra.HwStatus.CAN_ERROR,
           CommEvent.RX_OVERFLOW: ra.HwStatus.RX_OVERRUN,
           CommEvent.TX_OVERFLOW: ra.HwStatus.TX_OVERRUN,
           CommEvent.TX_QUEUE_FULL: ra.HwStatus.TX_BUSY}
_HW_CLEAR = {CommEvent.ERROR_ACTIVE: ra.HwStatus.ERROR_PASSIVE | ra.HwStatus.CAN_ERROR,
             CommEvent.BUS_OFF_RECOVERED: ra.HwStatus.BUS_OFF,
             CommEvent.TX_QUEUE_EMPTY: ra.HwStatus.TX_BUSY}


def _firmware_word() -> int:
    """[5F00h,04h]: custom hardware (0), a manager (2), our version major.minor."""
    parts = (__version__.split(".") + ["0", "0"])[:2]
    numbers = [int(p) if p.isdigit() else 0 for p in parts]
    return 0x00 | 0x02 << 8 | (numbers[0] & 0xFF) << 16 | (numbers[1] & 0xFF) << 24


class _Served:
    """One network number's line: its manager and what indications it sends."""

    def __init__(self, server: "RemoteAccessServer", net: int, line: Line,
                 manager: MinimalManager) -> None:
        self.server = server
        self.net = net
        self.line = line
        self.manager = manager
        self.hw = ra.HwStatus.INIT | (ra.HwStatus.CAN_FD if line.mode == "fd" else 0)
        self._hooked_local: Optional[LocalNode] = None
        self._hooked = False    # unhook() ends the local node's callbacks (not removable)

    @property
    def local(self) -> Optional[LocalNode]:
        return self.line.local_node

    @property
    def own_id(self) -> int:
        local = self.local
        return local.node_id if local is not None else 0

    def hook(self) -> None:
        """Subscribe to what the indications report."""
        self._hooked = True
        self.line.on_comm_event(self._comm_event)
        self.line.on_emcy(self._emcy, nodes=[n for n in range(1, 128) if n != self.own_id])
        self.hook_local()

    def unhook(self) -> None:
        """Undo hook(): the line consumes only the EMCYs it consumed before."""
        self._hooked = False
        self.line.remove_comm_event_callback(self._comm_event)
        self.line.remove_emcy_callback(self._emcy)

    def hook_local(self) -> None:
        local = self.local
        if local is None or local is self._hooked_local:
            return
        self._hooked_local = local
        local.on_state_change(self._own_state)
        if local.od is not None:
            local.on_object_changed(self._object_changed)

    # ------------------------------------------------------------ indications
    def _object_changed(self, value: LocalValue, origin: str) -> None:
        if not self._hooked:
            return
        var = value.variable
        try:
            data = value.data
        except CanopenFDError:
            return
        # the sender of an SDO/USDO write or PDO is not known here: node 0
        self.server.indicate(self.net, ra.NewData(0, var.index, var.subindex, data))

    def _own_state(self, old: NmtState, new: NmtState) -> None:
        if not self._hooked:
            return
        self.server.indicate(self.net, ra.NewData(self.own_id, ra.STATUS_INDEX, 2,
                                                  bytes((node_status_of(new),))))

    def _comm_event(self, event: CommEvent) -> None:
        """[5F00h,03h] follows the line's communication events; overruns stay
        set (the seed: "set if ... occurred")."""
        hw = self.hw
        if event in _HW_SET:
            hw |= _HW_SET[event]
        elif event in _HW_CLEAR:
            hw &= ~_HW_CLEAR[event]
        if hw != self.hw:
            self.hw = hw
            self.server.indicate(self.net, ra.NewData(self.own_id, ra.STATUS_INDEX, 3,
                                                      bytes((int(hw) & 0xFF,))))

    def _emcy(self, emcy: Emcy) -> None:
        # classic: the error reset (code 0); fd: the EMCY of a removed error
        status = ra.NodeStatus.EMCY_OVER if emcy.removed else ra.NodeStatus.EMCY_NEW
        self.manager.report(emcy.node, status)

    # ------------------------------------------------------------ the gateway's entries
    def read_own(self, index: int, sub: int) -> Tuple[int, bytes]:
        """(error, data) of a 0x5F00..0x5F0A entry."""
        local = self.local
        if index == ra.STATUS_INDEX:
            if sub == 1:
                return 0, bytes((self.own_id,))
            if sub == 2:
                state = local.state if local is not None else NmtState.UNKNOWN
                return 0, bytes((node_status_of(state),))
            if sub == 3:
                return 0, bytes((int(self.hw) & 0xFF,))
            if sub == 4:
                return 0, _firmware_word().to_bytes(4, "little")
        elif index == ra.CONTROL_INDEX:
            if sub == 4:
                return 0, self.manager.control_word().to_bytes(4, "little")
            if sub == 8:
                return 0, self.manager.heartbeat_ms.to_bytes(2, "little")
            if sub in (1, 0x0A):
                return int(ra.RaError.NOT_SUPPORTED), b""    # write-only
        elif index == ra.NODE_STATE_INDEX and 1 <= sub <= 127:
            return 0, bytes((self.manager.status(sub),))
        elif index == ra.NMT_INDEX and sub == 1:
            return int(ra.RaError.NOT_SUPPORTED), b""        # write-only
        return int(ra.RaError.OD_NOT_FOUND), b""

    def write_own(self, index: int, sub: int, data: bytes) -> int:
        """The error of a write to a 0x5F00..0x5F0A entry."""
        def number(size: int) -> Optional[int]:
            return int.from_bytes(data, "little") if len(data) == size else None

        if index == ra.STATUS_INDEX and 1 <= sub <= 4:
            return int(ra.RaError.NOT_SUPPORTED)               # read-only
        if index == ra.NODE_STATE_INDEX and 1 <= sub <= 127:
            return int(ra.RaError.NOT_SUPPORTED)
        if index == ra.NMT_INDEX and sub == 1:
            value = number(2)
            if value is None:
                return int(ra.RaError.INVALID_LENGTH)
            node, command = value >> 8, value & 0xFF
            if node > 127 or command not in ra.NMT_COMMANDS:
                return int(ra.RaError.INVALID_COMMAND)
            self.line.nmt.send(command, node)
            return 0
        if index == ra.CONTROL_INDEX:
            if sub == 1:
                value = number(1)
                if value is None:
                    return int(ra.RaError.INVALID_LENGTH)
                local = self.local
                if value not in (ra.RESET_SOFT, ra.RESET_HARD) or local is None:
                    return int(ra.RaError.NOT_SUPPORTED)
                local.apply("RESET_NODE" if value == ra.RESET_SOFT else "RESET_COMMUNICATION")
                return 0
            if sub == 4:
                value = number(4)
                if value is None:
                    return int(ra.RaError.INVALID_LENGTH)
                return self.manager.set_control(value)
            if sub == 8:
                value = number(2)
                if value is None:
                    return int(ra.RaError.INVALID_LENGTH)
                return self.manager.set_heartbeat_ms(value)
            if sub == 0x0A:
                value = number(1)
                if value is None:
                    return int(ra.RaError.INVALID_LENGTH)
                return self.manager.rescan(value & 0x7F)
        return int(ra.RaError.OD_NOT_FOUND)


def _is_own_entry(index: int) -> bool:
    return index in (ra.STATUS_INDEX, ra.CONTROL_INDEX, ra.NODE_STATE_INDEX, ra.NMT_INDEX)


class RemoteAccessConnection:
    """One host's stream: reader, remote-command worker and writer threads."""

    def __init__(self, server: "RemoteAccessServer", stream: ByteStream) -> None:
        self.server = server
        self.stream = stream
        # only the served networks' start bytes count: fewer false starts in noise
        self.decoder = ra.FrameDecoder(crc=server.crc, max_payload=server.max_payload,
                                       idle_timeout=server.idle_timeout,
                                       nets=frozenset(server.served))
        #: unknown letters, bad command lengths, remote commands refused busy,
        #: indications dropped for a slow host
        self.unknown_command = 0
        self.invalid_length = 0
        self.busy = 0
        self.indications_dropped = 0
        self.internal_errors = 0
        self.closed = threading.Event()
        # (is an indication, frame); None ends the writer
        self._out: "queue.Queue[Optional[Tuple[bool, bytes]]]" = queue.Queue()
        self._queued_indications = 0
        self._queued_responses = 0
        #: times the reader waited for the host to take its responses
        self.output_waits = 0
        self._count_lock = threading.Lock()
        self._taken = threading.Condition(self._count_lock)   # the writer took a response
        # one remote command at a time: the next one while it runs is refused BUSY
        self._remote: "queue.Queue[Optional[Tuple[int, ra.Command]]]" = queue.Queue()
        self._remote_running = False
        self._transfer: Optional[Transfer] = None    # the remote command's, while it runs
        self._threads = [
            threading.Thread(target=self._read_loop, daemon=True, name=f"ra read {stream.name}"),
            threading.Thread(target=self._write_loop, daemon=True, name=f"ra write {stream.name}"),
            threading.Thread(target=self._remote_loop, daemon=True,
                             name=f"ra remote {stream.name}"),
        ]
        for thread in self._threads:
            thread.start()

    def __repr__(self) -> str:
        return f"<RemoteAccessConnection {self.stream.name}>"

    @property
    def stats(self) -> Dict[str, int]:
        stats = self.decoder.stats.as_dict()
        stats.update(unknown_command=self.unknown_command, invalid_length=self.invalid_length,
                     busy=self.busy, indications_dropped=self.indications_dropped,
                     internal_errors=self.internal_errors, output_waits=self.output_waits)
        return stats

    # ------------------------------------------------------------ output
    def send_payload(self, net: int, payload: bytes, indication: bool = False) -> None:
        """Queue a frame for the host: an indication is dropped (counted) when
        the queue is full, a response waits for room (the host's next request
        is not read meanwhile)."""
        if self.closed.is_set():
            return
        with self._count_lock:
            if indication:
                if self._queued_indications >= self.server.indication_queue:
                    self.indications_dropped += 1
                    return
                self._queued_indications += 1
            else:
                if self._queued_responses >= RESPONSE_QUEUE:
                    self.output_waits += 1
                while self._queued_responses >= RESPONSE_QUEUE:
                    if self.closed.is_set():
                        return
                    self._taken.wait(0.1)
                self._queued_responses += 1
        self._out.put((indication, ra.encode_frame(payload, net, crc=self.server.crc)))

    def _write_loop(self) -> None:
        while True:
            item = self._out.get()
            if item is None:
                return
            indication, frame = item
            with self._count_lock:
                if indication:
                    self._queued_indications -= 1
                else:
                    self._queued_responses -= 1
                    self._taken.notify_all()
            try:
                self.stream.write(frame)
            except EOFError:
                self.close()
                return

    # ------------------------------------------------------------ input
    def _read_loop(self) -> None:
        try:
            while not self.closed.is_set():
                try:
                    data = self.stream.read(0.1)
                except EOFError:
                    break
                now = time.monotonic()
                frames = self.decoder.feed(data, now) if data else self.decoder.expire(now)
                for frame in frames:
                    try:
                        self._handle(frame)
                    except Exception:   # a fault of ours never ends the host's connection
                        log.exception("remote access %s: frame %r", self.stream.name, frame)
                        self.internal_errors += 1
        finally:
            self.decoder.close()
            self.close()

    def _respond(self, net: int, response: ra.Response) -> None:
        self.send_payload(net, ra.encode_response(response))

    def _handle(self, frame: ra.Frame) -> None:
        command = ra.parse_command(frame.payload)
        served = self.server.served.get(frame.net)
        if isinstance(command, ra.BadCommand):
            if command.error == ra.RaError.INVALID_COMMAND:
                self.unknown_command += 1
            else:
                self.invalid_length += 1
            if command.letter in tuple(ra.Letter) and command.letter != ra.Letter.NEW_DATA:
                self._respond(frame.net, ra.Response(ra.Letter(command.letter), command.node,
                                                     command.index, command.sub,
                                                     int(command.error)))
            else:
                # an unknown letter has no response layout: the letter and the error
                self.send_payload(frame.net, bytes((command.letter,))
                                  + int(command.error).to_bytes(2, "little"))
            return
        assert served is not None      # the decoder passes served networks only
        if isinstance(command, (ra.LocalRead, ra.LocalWrite)):
            self._respond(frame.net, self.server.local(served, command))
            return
        with self._count_lock:
            busy, self._remote_running = self._remote_running, True
        if busy:
            self.busy += 1
            self._respond(frame.net, self.server.refusal(command, int(ra.RaError.BUSY)))
            return
        self._remote.put((frame.net, command))

    def _remote_loop(self) -> None:
        while True:
            item = self._remote.get()
            if item is None:
                return
            net, command = item
            served = self.server.served.get(net)
            assert served is not None and isinstance(command, (ra.RemoteRead, ra.RemoteWrite))
            try:
                response = self.server.remote(served, command, started=self._started)
            except Exception:   # answered, and the next remote command is taken
                log.exception("remote access %s: %r", self.stream.name, command)
                self.internal_errors += 1
                response = self.server.refusal(command, int(ra.RaError.MISC))
            with self._count_lock:
                self._remote_running = False
                self._transfer = None
            self._respond(net, response)

    def _started(self, transfer: Transfer) -> None:
        """The remote command's transfer runs: close() aborts it (once the
        host is gone nobody wants its result)."""
        with self._count_lock:
            self._transfer = transfer
            gone = self.closed.is_set()
        if gone:
            self._abort(transfer)

    @staticmethod
    def _abort(transfer: Transfer) -> None:
        try:
            transfer.cancel()
        except CanopenFDError:      # it ended meanwhile
            pass

    def close(self) -> None:
        with self._count_lock:      # the reader, the writer and the server may all close
            if self.closed.is_set():
                return
            self.closed.set()
            transfer = self._transfer
            self._taken.notify_all()
        if transfer is not None:
            self._abort(transfer)
        self._out.put(None)
        self._remote.put(None)
        self.stream.close()
        self.server.forget(self)


class RemoteAccessServer:
    """Serves `networks` ({net: Line}, net 1..15) over the remote-access
    protocol. `serve(stream)`, `serve_serial(path)`, `serve_tcp(port)` add
    connections; `close()` ends them.

    crc: 'seed' or 'xmodem' (see remote_access.CrcVariant); max_payload: the
    longest payload accepted and sent (the seed's 35; longer read answers are
    refused RX_TOO_SMALL); sdo_timeout: the SDO/USDO client's per-frame
    timeout (s) for remote commands; remote_timeout: seconds one may take;
    control / heartbeat_ms: the minimal manager's start values ([5F01h,04h],
    [5F01h,08h]); known: {net: {node: OD or EDS path}} the manager reads PDO
    configurations of (PDO_RECEIVE_ALL); max_connections: hosts served at
    once (a further TCP host is closed at once, counted `refused_connections`;
    serve() raises ConfigurationError).

    Create the lines' local nodes first: the server watches every other
    node-id of each line (line.add_node) and consumes their EMCYs until
    close(), which gives each line back as the server found it."""

    def __init__(self, networks: Mapping[int, Line], *, crc: Union[str, ra.CrcVariant] = "seed",
                 max_payload: int = ra.SEED_MAX_PAYLOAD, sdo_timeout: float = 1.0,
                 remote_timeout: float = 30.0,
                 idle_timeout: float = 0.5, control: int = 0, heartbeat_ms: int = 1000,
                 known: Optional[Mapping[int, Mapping[int, ODLike]]] = None,
                 indication_queue: int = INDICATION_QUEUE,
                 max_connections: int = MAX_CONNECTIONS) -> None:
        if not networks:
            raise ConfigurationError("RemoteAccessServer: no network to serve (give {1: line})")
        unsupported = control & (ra.ManagerControl.PDO_TRANSMIT_ALL | ra.ManagerControl.USE_SCANNED)
        if unsupported:
            raise ConfigurationError(
                f"RemoteAccessServer: manager control 0x{control:08X} refused "
                f"({ra.error_text(ra.RaError.NOT_SUPPORTED)}: bits 3 and 4 are not served)")
        for net in networks:
            ra.check_net(net, "RemoteAccessServer")
        self.crc = ra.parse_crc(crc)
        ra.FrameDecoder(max_payload=max_payload)    # checks the value
        self.max_payload = max_payload
        self.sdo_timeout = sdo_timeout
        self.remote_timeout = remote_timeout
        self.idle_timeout = idle_timeout
        self.indication_queue = indication_queue
        if isinstance(max_connections, bool) or not isinstance(max_connections, int) or \
                max_connections < 1:
            raise ConfigurationError(f"RemoteAccessServer: max_connections must be an int "
                                     f">= 1, got {max_connections!r}")
        self.max_connections = max_connections
        self._lock = threading.Lock()
        self._connections: List[RemoteAccessConnection] = []
        self._listeners: List[TcpListener] = []
        self._closed = False
        self._totals: Dict[str, int] = {}    # the server's counters and those of ended connections
        self.served: Dict[int, _Served] = {}
        known = known or {}
        for net, line in networks.items():
            manager = MinimalManager(line, partial(self.indicate, net),
                                     heartbeat_ms=heartbeat_ms, known=known.get(net, {}))
            self.served[net] = _Served(self, net, line, manager)
        try:
            for served in self.served.values():
                served.hook()
                served.manager.start()
                if control:
                    served.manager.set_control(control)    # checked above: taken
        except BaseException:
            self.close()     # the networks started already stop their automation
            raise

    def __enter__(self) -> "RemoteAccessServer":
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    # ------------------------------------------------------------ connections
    def serve(self, stream: ByteStream) -> RemoteAccessConnection:
        """Serve one host on `stream` (its threads start now)."""
        with self._lock:
            if self._closed:
                raise ConfigurationError("RemoteAccessServer: closed")
            if len(self._connections) >= self.max_connections:
                self._totals["refused_connections"] = \
                    self._totals.get("refused_connections", 0) + 1
                raise ConfigurationError(f"RemoteAccessServer: {stream.name} refused, "
                                         f"{self.max_connections} hosts served already")
            connection = RemoteAccessConnection(self, stream)
            self._connections.append(connection)
        return connection

    def serve_serial(self, path: str, baud: int = 115200) -> RemoteAccessConnection:
        """Serve the host on serial port `path` (pyserial)."""
        return self.serve(open_serial(path, baud))

    def serve_tcp(self, port: int = 0, host: str = "127.0.0.1") -> int:
        """Accept hosts on TCP `host:port` (0: any free port); the port."""
        listener = TcpListener(port, lambda stream: self._accept(stream), host)
        with self._lock:
            self._listeners.append(listener)
        return listener.port

    def _accept(self, stream: ByteStream) -> None:
        try:
            self.serve(stream)
        except ConfigurationError as exc:     # closed, or hosts enough
            log.info("remote access: %s", exc)
            stream.close()

    def forget(self, connection: RemoteAccessConnection) -> None:
        with self._lock:
            if connection in self._connections:
                self._connections.remove(connection)
                self._finished_stats(connection)

    def _finished_stats(self, connection: RemoteAccessConnection) -> None:
        for key, value in connection.stats.items():
            self._totals[key] = self._totals.get(key, 0) + value

    @property
    def connections(self) -> List[RemoteAccessConnection]:
        with self._lock:
            return list(self._connections)

    @property
    def stats(self) -> Dict[str, int]:
        """Counters of every connection, ended ones included."""
        with self._lock:
            total = dict(self._totals)
            for connection in self._connections:
                for key, value in connection.stats.items():
                    total[key] = total.get(key, 0) + value
        return total

    def close(self) -> None:
        with self._lock:
            self._closed = True
            listeners, self._listeners = self._listeners, []
            connections = list(self._connections)
        for listener in listeners:
            listener.close()
        for connection in connections:
            connection.close()
        for served in self.served.values():
            served.manager.stop()
            served.unhook()

    # ------------------------------------------------------------ indications
    def indicate(self, net: int, indication: ra.NewData) -> None:
        """Send indication D to every connected host (dropped for a host whose
        queue is full, counted); one longer than max_payload is not sent
        (counted `indications_too_long`: a cut value would be a wrong one)."""
        if self._closed:
            return
        payload = ra.encode_new_data(indication)
        if len(payload) > self.max_payload:
            with self._lock:
                self._totals["indications_too_long"] = \
                    self._totals.get("indications_too_long", 0) + 1
            return
        for connection in self.connections:
            connection.send_payload(net, payload, indication=True)

    # ------------------------------------------------------------ commands
    def refusal(self, command: ra.Command, error: int) -> ra.Response:
        letter = ra.Letter(ra.encode_command(command)[0])
        node = command.node if isinstance(command, (ra.RemoteRead, ra.RemoteWrite)) else None
        return ra.Response(letter, node, command.index, command.sub, error)

    def _read_answer(self, command: ra.Command, data: bytes) -> ra.Response:
        """A read response, or RX_TOO_SMALL when it does not fit max_payload."""
        header = 7 if isinstance(command, ra.RemoteRead) else 6
        if header + len(data) > self.max_payload:
            return self.refusal(command, int(ra.RaError.RX_TOO_SMALL))
        response = self.refusal(command, 0)
        return ra.Response(response.letter, response.node, command.index, command.sub, 0, data)

    def local(self, served: _Served, command: Union[ra.LocalRead, ra.LocalWrite]
              ) -> ra.Response:
        """W or R on the line's local node (or the gateway's own entries)."""
        served.hook_local()
        if _is_own_entry(command.index):
            if isinstance(command, ra.LocalRead):
                error, data = served.read_own(command.index, command.sub)
                return (self.refusal(command, error) if error
                        else self._read_answer(command, data))
            return self.refusal(command, served.write_own(command.index, command.sub,
                                                          command.data))
        local = served.local
        if local is None:
            return self.refusal(command, int(ra.RaError.NODE_NOT_AVAILABLE))
        try:
            value = local[(command.index, command.sub)]
            if not isinstance(value, LocalValue):
                return self.refusal(command, int(ra.RaError.OD_NOT_FOUND))
            if isinstance(command, ra.LocalRead):
                return self._read_answer(command, value.data)
            value.data = command.data
            return self.refusal(command, 0)
        except KeyError:
            return self.refusal(command, int(ra.RaError.OD_NOT_FOUND))
        except AbortError as exc:
            return self.refusal(command, error_for_abort(exc.code))
        except CanopenFDError as exc:
            log.debug("remote access: %r refused: %s", command, exc)
            return self.refusal(command, int(ra.RaError.MISC))

    def remote(self, served: _Served, command: Union[ra.RemoteRead, ra.RemoteWrite],
               started: Optional[Callable[[Transfer], None]] = None) -> ra.Response:
        """S or U through the line's USDO (fd) or SDO (classic) client;
        started(transfer) once its transfer runs."""
        if not 1 <= command.node <= 127:
            return self.refusal(command, int(ra.RaError.NODE_NOT_AVAILABLE))
        if command.node == served.own_id:
            # no transfer to ourselves on the bus: the local entry
            local: Union[ra.LocalRead, ra.LocalWrite] = (
                ra.LocalRead(command.index, command.sub) if isinstance(command, ra.RemoteRead)
                else ra.LocalWrite(command.index, command.sub, command.data))
            answer = self.local(served, local)
            return ra.Response(ra.Letter(ra.encode_command(command)[0]), command.node,
                               command.index, command.sub, answer.error, answer.data)
        line = served.line
        try:
            # other hosts' requests for the node (any protocol) go first
            with taking_turn(line, command.node, self.remote_timeout):
                return self._transfer(line, command, started)
        except TurnTimeout:
            return self.refusal(command, int(ra.RaError.TIMEOUT))

    def _transfer(self, line: Line, command: Union[ra.RemoteRead, ra.RemoteWrite],
                  started: Optional[Callable[[Transfer], None]]) -> ra.Response:
        client: Union[UsdoClient, SdoClient] = line.usdo if line.mode == "fd" else line.sdo
        try:
            if isinstance(command, ra.RemoteRead):
                transfer = client.start_upload(command.node, command.index, command.sub,
                                               timeout=self.sdo_timeout)
                if started is not None:
                    started(transfer)
                result = transfer.result(self.remote_timeout)
                assert isinstance(result, bytes)
                return self._read_answer(command, result)
            transfer = client.start_download(command.node, command.index, command.sub,
                                             command.data, timeout=self.sdo_timeout)
            if started is not None:
                started(transfer)
            transfer.result(self.remote_timeout)
            return self.refusal(command, 0)
        except AbortError as exc:
            return self.refusal(command, error_for_abort(exc.code))
        except TimeoutError:
            transfer.cancel()
            return self.refusal(command, int(ra.RaError.TIMEOUT))
        except CanopenFDError as exc:
            log.debug("remote access: %r failed: %s", command, exc)
            return self.refusal(command, int(ra.RaError.MISC))


def serve_network(networks: Mapping[int, Line], *, serial: Optional[str] = None,
                  baud: int = 115200, tcp: Optional[int] = None,
                  **options: object) -> RemoteAccessServer:
    """A server on the given endpoints (a convenience for the CLI and scripts)."""
    server = RemoteAccessServer(networks, **options)  # type: ignore[arg-type]
    try:
        if serial is not None:
            server.serve_serial(serial, baud)
        if tcp is not None:
            server.serve_tcp(tcp)
    except BaseException:
        server.close()
        raise
    return server


__all__ = ["RemoteAccessServer", "RemoteAccessConnection", "serve_network", "error_for_abort"]
