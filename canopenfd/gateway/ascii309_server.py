"""The CiA 309-3 ASCII gateway over TCP: host programs reach every node of
the gateway's lines with text requests (`canopenfd gateway --tcp PORT`).

    server = AsciiGateway({1: line})            # {net id: Line}
    await server.start("127.0.0.1", 0)          # server.port: the port bound
    ...
    await server.aclose()

or `AsciiGateway(...).start_in_thread(host, port)` for a program without an
event loop (returns a BackgroundGateway with .port and .close()).

Every client is a session with its own sequence numbers, default net/node,
SDO timeout and block switch; its requests run one after the other, in
order (a client pipelines as much as it likes; at most QUEUE_DEPTH lines
wait, then its socket is not read). Clients run side by side. Reads and
writes go through the line's public clients (`line.usdo` on fd lines,
`line.sdo` on classic lines, awaited: the transfer runs in C), NMT through
`line.nmt`, LSS through `line.lss` (one LSS request at a time per line:
sessions queue for it; a session that switched devices into configuration
holds the net's LSS until it switches them back or leaves).

Events (boot-ups, NMT state changes, heartbeat lost/started, EMCYs) reach
every client. They arrive on the dispatcher thread, which only puts the
line into a bounded queue (full: dropped and counted) and wakes the loop;
a client whose unread output passes `max_output` bytes misses events
(counted per client) and one that does not take an answer within
`write_timeout` seconds is disconnected with the reason logged. So a slow
or dead client never stalls the CAN side or the other clients.
"""

from __future__ import annotations

import asyncio
import collections
import logging
import socket
import threading
from typing import Any, Deque, Dict, List, Mapping, Optional, Set, Tuple, Union

from .. import __version__
from ..errors import AbortError, CanopenFDError
from ..line import Line
from ..services.emcy import Emcy
from ..services.lss import LssDevice, LssError
from ..services.nmt import HeartbeatEvent, NmtState
from ..transfer.client import uploaded_bytes
from . import ascii309 as proto
from .node_turns import taking_turn_async

__all__ = ["AsciiGateway", "BackgroundGateway", "Session", "lss_error_code"]

log = logging.getLogger(__name__)

#: Request lines a session keeps waiting before its socket is not read.
QUEUE_DEPTH = 64
#: Events kept between the dispatcher thread and the loop (then dropped).
EVENT_QUEUE = 4096
_STATE_NAMES = {NmtState.OPERATIONAL: "OPER", NmtState.STOPPED: "STOP",
                NmtState.PRE_OPERATIONAL: "PREOP"}
#: CiA 309-3 protocol version this gateway speaks, and the gateway class
#: (3: it runs the NMT master of its lines).
PROTOCOL_VERSION = (3, 0)
GATEWAY_CLASS = 3
_LSS_ERRORS = {"lss_set_node": proto.LSS_NODE_ID_NOT_SUPPORTED,
               "lss_conf_bitrate": proto.LSS_BIT_RATE_NOT_SUPPORTED,
               "lss_store": proto.LSS_STORE_FAILED, "lss_allnodes": proto.LSS_STORE_FAILED}


class Session:
    """One TCP client: its defaults and counters."""

    def __init__(self, gateway: "AsciiGateway", peer: str,
                 writer: asyncio.StreamWriter) -> None:
        self.peer = peer
        self.writer = writer
        self.net: Optional[int] = 1 if 1 in gateway.networks else None
        self.node: Optional[int] = None
        self.sdo_timeout_ms = gateway.sdo_timeout_ms
        self.sdo_block = False
        self.requests = 0
        self.events_dropped = 0
        self.closed = False

    def __repr__(self) -> str:
        return f"<Session {self.peer}>"


class AsciiGateway:
    """The CiA 309-3 ASCII server over the lines of `networks` ({net id 1..127: Line})."""

    def __init__(self, networks: Mapping[int, Line], *, sdo_timeout_ms: int = 500,
                 max_line: int = proto.MAX_LINE, max_output: int = 256 * 1024,
                 write_timeout: float = 10.0, max_clients: int = 64) -> None:
        where = "AsciiGateway"
        if not networks:
            raise CanopenFDError(f"{where}: no networks given ({{net id: Line}})")
        for net_id, line in networks.items():
            if isinstance(net_id, bool) or not isinstance(net_id, int) or \
                    not 1 <= net_id <= 127:
                raise CanopenFDError(f"{where}: net id {net_id!r} is not 1..127")
            if not isinstance(line, Line):
                raise CanopenFDError(f"{where}: net {net_id} is {line!r}, not a Line")
        if not 1 <= sdo_timeout_ms <= 0xFFFF:
            raise CanopenFDError(f"{where}: sdo_timeout_ms {sdo_timeout_ms} outside 1..65535")
        if max_line < 64:
            raise CanopenFDError(f"{where}: max_line {max_line} below 64 bytes")
        self.networks: Dict[int, Line] = dict(networks)
        self.sdo_timeout_ms = sdo_timeout_ms
        self.max_line = max_line
        self.max_output = max_output
        self.write_timeout = write_timeout
        self.max_clients = max_clients
        self.sessions: Set[Session] = set()
        #: counters: clients, requests, errors, lines_too_long, events,
        #: events_dropped (queue full), client_events_dropped, disconnected_slow,
        #: refused_clients, cancelled_transfers
        self.stats: Dict[str, int] = collections.Counter()
        self._server: Optional[asyncio.base_events.Server] = None
        self._loop: Optional[asyncio.AbstractEventLoop] = None
        self._events: Deque[str] = collections.deque()
        self._events_lock = threading.Lock()
        self._flush_pending = False
        self._lss_locks: Dict[int, asyncio.Lock] = {}
        # {net: the session that switched devices into LSS configuration}: the
        # net's LSS is its own until it switches them to waiting or leaves
        self._lss_owners: Dict[int, Session] = {}
        self._hooks: List[Tuple[Line, Any, Any]] = []
        self._tasks: Set["asyncio.Task[None]"] = set()

    # ---------------------------------------------------------------- life cycle
    @property
    def port(self) -> int:
        """The TCP port bound (after start)."""
        if self._server is None or not self._server.sockets:
            raise CanopenFDError("AsciiGateway: not started")
        return int(self._server.sockets[0].getsockname()[1])

    async def start(self, host: str = "127.0.0.1", port: int = 0) -> None:
        """Listen on host:port (0: any free port) and hear the lines' events."""
        if self._server is not None:
            raise CanopenFDError("AsciiGateway: already started")
        self._loop = asyncio.get_running_loop()
        self._server = await asyncio.start_server(self._client, host, port,
                                                  limit=self.max_line)
        for net_id, line in self.networks.items():
            on_node = self._node_hook(net_id)
            on_emcy = self._emcy_hook(net_id)
            line.on_node_event(on_node)
            line.on_emcy(on_emcy, nodes=range(1, 128))
            self._hooks.append((line, on_node, on_emcy))
            self._lss_locks[net_id] = asyncio.Lock()

    async def serve_forever(self) -> None:
        if self._server is None:
            raise CanopenFDError("AsciiGateway: start() first")
        await self._server.serve_forever()

    async def aclose(self) -> None:
        """Stop listening, close every session (their transfers are cancelled)."""
        for line, on_node, on_emcy in self._hooks:
            line.remove_node_event_callback(on_node)
            line.remove_emcy_callback(on_emcy)
        self._hooks = []
        if self._server is not None:
            self._server.close()
        for session in list(self.sessions):
            session.closed = True
            session.writer.transport.abort()    # its reader ends, its transfer is cancelled
        if self._tasks:
            _, late = await asyncio.wait(list(self._tasks), timeout=2.0)
            for task in late:
                task.cancel()
            if late:
                await asyncio.wait(late, timeout=2.0)
        if self._server is not None:
            await self._server.wait_closed()
            self._server = None

    def start_in_thread(self, host: str = "127.0.0.1", port: int = 0) -> "BackgroundGateway":
        """Run the server on an event loop of its own thread (for programs
        without asyncio); returns once it listens."""
        return BackgroundGateway(self, host, port)

    # ---------------------------------------------------------------- events (dispatcher thread)
    def _node_hook(self, net_id: int) -> Any:
        def on_node(node_id: int, kind: HeartbeatEvent, state: NmtState) -> None:
            if kind == HeartbeatEvent.BOOTUP:
                text = f"{net_id} {node_id} BOOT_UP"
            elif kind == HeartbeatEvent.LOST:
                text = f"{net_id} {node_id} ERROR: {proto.HEARTBEAT_LOST} " \
                       f"#{proto.ERROR_TEXT[proto.HEARTBEAT_LOST]}"
            elif kind == HeartbeatEvent.STARTED:
                text = f"{net_id} {node_id} ERROR: {proto.HEARTBEAT_STARTED} " \
                       f"#{proto.ERROR_TEXT[proto.HEARTBEAT_STARTED]}"
            elif state in _STATE_NAMES:
                text = f"{net_id} {node_id} STATE {_STATE_NAMES[state]}"
            else:
                return
            self._post_event(text)
        return on_node

    def _emcy_hook(self, net_id: int) -> Any:
        def on_emcy(emcy: Emcy) -> None:
            data = " ".join(str(b) for b in emcy.data[:5].ljust(5, b"\0"))
            self._post_event(f"{net_id} {emcy.node} EMCY {emcy.code:04X} "
                             f"{emcy.register:02X} {data}")
        return on_emcy

    def _post_event(self, text: str) -> None:
        """Any thread: queue an event line for every client (bounded)."""
        loop = self._loop
        if loop is None or loop.is_closed():
            return
        with self._events_lock:
            if len(self._events) >= EVENT_QUEUE:
                self.stats["events_dropped"] += 1
                return
            self._events.append(text)
            wake = not self._flush_pending
            self._flush_pending = True
        if wake:
            try:
                loop.call_soon_threadsafe(self._flush_events)
            except RuntimeError:   # the loop closed meanwhile
                pass

    def _flush_events(self) -> None:
        with self._events_lock:
            events, self._events = self._events, collections.deque()
            self._flush_pending = False
        self.stats["events"] += len(events)
        if not events:
            return
        data = "".join(f"{text}\r\n" for text in events).encode("ascii", "replace")
        for session in list(self.sessions):
            if session.closed:
                continue
            transport = session.writer.transport
            if transport.is_closing() or \
                    transport.get_write_buffer_size() + len(data) > self.max_output:
                session.events_dropped += len(events)
                self.stats["client_events_dropped"] += len(events)
                continue
            session.writer.write(data)

    # ---------------------------------------------------------------- one client
    async def _client(self, reader: asyncio.StreamReader,
                      writer: asyncio.StreamWriter) -> None:
        task = asyncio.current_task()
        if task is not None:
            self._tasks.add(task)
        peer = str(writer.get_extra_info("peername"))
        try:
            if len(self.sessions) >= self.max_clients:
                self.stats["refused_clients"] += 1
                writer.write(proto.format_error(0, proto.OUT_OF_MEMORY,
                                                f"{self.max_clients} clients already")
                             .encode() + b"\r\n")
                writer.close()
                return
            await self._serve(Session(self, peer, writer), reader)
        except asyncio.CancelledError:
            pass    # aclose() gave up waiting for this client: it ends here, quietly
        finally:
            if task is not None:
                self._tasks.discard(task)

    async def _serve(self, session: Session, reader: asyncio.StreamReader) -> None:
        writer = session.writer
        writer.transport.set_write_buffer_limits(high=self.max_output)
        sock = writer.get_extra_info("socket")
        if sock is not None:
            # the kernel's share of the client's unread output is bounded too
            try:
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, self.max_output)
            except OSError:
                pass
        self.sessions.add(session)
        self.stats["clients"] += 1
        lines: "asyncio.Queue[Optional[Tuple[bool, bytes]]]" = asyncio.Queue(QUEUE_DEPTH)
        worker = asyncio.ensure_future(self._work(session, lines))
        reset = False
        try:
            reset = await self._read(session, reader, lines)
        finally:
            if reset or session.closed:
                worker.cancel()          # the peer is gone: abort its transfer
            else:
                await lines.put(None)    # end of input: answer what came first
            await asyncio.gather(worker, return_exceptions=True)
            session.closed = True
            self.sessions.discard(session)
            self._release_lss(session)
            writer.close()
            try:
                await writer.wait_closed()
            except (ConnectionError, OSError):
                pass

    async def _read(self, session: Session, reader: asyncio.StreamReader,
                    lines: "asyncio.Queue[Optional[Tuple[bool, bytes]]]") -> bool:
        """Lines into the queue until end of input (False) or a reset (True)."""
        while not session.closed:
            try:
                line = await reader.readuntil(b"\n")
            except asyncio.IncompleteReadError as exc:
                if exc.partial.strip():
                    await lines.put((False, exc.partial))   # a last line without its LF
                return False
            except asyncio.LimitOverrunError as exc:
                self.stats["lines_too_long"] += 1
                head = await reader.readexactly(exc.consumed)
                if not await self._skip_line(reader):
                    return False
                await lines.put((True, head[:32]))
                continue
            except (ConnectionError, OSError):
                return True
            await lines.put((False, line))
        return True

    async def _skip_line(self, reader: asyncio.StreamReader) -> bool:
        """Drop input up to the next LF (True) or the end (False)."""
        while True:
            try:
                await reader.readuntil(b"\n")
                return True
            except asyncio.LimitOverrunError as exc:
                await reader.readexactly(exc.consumed)
            except (asyncio.IncompleteReadError, ConnectionError, OSError):
                return False

    async def _work(self, session: Session,
                    lines: "asyncio.Queue[Optional[Tuple[bool, bytes]]]") -> None:
        while True:
            item = await lines.get()
            if item is None:
                return
            too_long, line = item
            answer: Optional[str]
            if too_long:
                seq = proto.leading_seq(line)
                answer = proto.format_error(seq, proto.SYNTAX_ERROR,
                                            f"line longer than {self.max_line} bytes")
                self.stats["errors"] += 1
            else:
                session.requests += 1
                self.stats["requests"] += 1
                answer = await self.execute(session, line)
                if answer is None:
                    continue
            if not await self._send(session, answer):
                return

    async def _send(self, session: Session, answer: str) -> bool:
        writer = session.writer
        if writer.transport.is_closing():
            return False
        writer.write(answer.encode("ascii", "replace") + b"\r\n")
        if writer.transport.get_write_buffer_size() == 0:
            return True      # the kernel took it all: no wait (wait_for costs a task)
        try:
            await asyncio.wait_for(writer.drain(), self.write_timeout)
        except asyncio.TimeoutError:
            self.stats["disconnected_slow"] += 1
            log.warning("ASCII gateway: client %s did not read its answers for %.0f s: "
                        "disconnected", session.peer, self.write_timeout)
            session.closed = True
            writer.transport.abort()
            return False
        except (ConnectionError, OSError):
            session.closed = True
            return False
        return True

    # ---------------------------------------------------------------- requests
    async def execute(self, session: Session, raw: bytes) -> Optional[str]:
        """The answer line to one request line (None: nothing to answer)."""
        request = proto.parse_request(raw)
        if request is None:
            return None
        if isinstance(request, proto.Reply):
            self.stats["errors"] += 1
            return request.text
        try:
            return await self._dispatch(session, request)
        except CanopenFDError as exc:
            # a request the stack refused (closed network, a busy LSS master...)
            self.stats["errors"] += 1
            return proto.format_error(request.seq, proto.INTERNAL_STATE, str(exc)[:200])
        except Exception:  # noqa: BLE001 - a bug must cost one answer, not the session
            log.exception("ASCII gateway: request %r of %s failed", raw[:80], session.peer)
            self.stats["errors"] += 1
            return proto.format_error(request.seq, proto.INTERNAL_STATE, "internal error")

    def _net(self, session: Session, request: proto.Request) -> Union[Tuple[int, Line], str]:
        net = request.net if request.net is not None else session.net
        if net is None:
            return proto.format_error(request.seq, proto.NO_DEFAULT_NET)
        line = self.networks.get(net)
        if line is None:
            return proto.format_error(request.seq, proto.UNSUPPORTED_NET, f"net {net}")
        return net, line

    def _node(self, session: Session, request: proto.Request, lowest: int) -> Union[int, str]:
        node = request.node if request.node is not None else session.node
        if node is None:
            return proto.format_error(request.seq, proto.NO_DEFAULT_NODE)
        if not lowest <= node <= 127:
            return proto.format_error(request.seq, proto.UNSUPPORTED_NODE, f"node {node}")
        return node

    async def _dispatch(self, session: Session, request: proto.Request) -> str:
        seq, command = request.seq, request.command
        if command == "help":
            text = {"": proto.HELP, "datatype": proto.HELP_DATATYPE,
                    "lss": proto.HELP_LSS}[request.topic]
            return text.replace("\n", "\r\n") + "\r\n" + proto.format_ok(seq)
        if command == "set_network":
            if request.args[0] not in self.networks:
                self.stats["errors"] += 1
                return proto.format_error(seq, proto.UNSUPPORTED_NET, f"net {request.args[0]}")
            session.net = request.args[0]
            return proto.format_ok(seq)
        found = self._net(session, request)
        if isinstance(found, str):
            self.stats["errors"] += 1
            return found
        net, line = found
        if command == "set_node":
            session.node = request.args[0]
            return proto.format_ok(seq)
        if command == "set_sdo_timeout":
            session.sdo_timeout_ms = request.args[0]
            return proto.format_ok(seq)
        if command == "set_sdo_block":
            session.sdo_block = bool(request.args[0])
            return proto.format_ok(seq)
        if command == "info_version":
            return self._info_version(seq, line)
        if command.startswith("lss_") or command == "_lss_fastscan":
            async with self._lss_locks[net]:
                owner = self._lss_owners.get(net)
                if owner is not None and owner is not session:
                    self.stats["errors"] += 1
                    return proto.format_error(
                        seq, proto.INTERNAL_STATE,
                        f"LSS of net {net} is held by another client ({owner.peer}) until "
                        "it switches the devices back to waiting or disconnects")
                answer = await self._lss(seq, line, command, request.args)
                if answer == proto.format_ok(seq):
                    self._lss_owned(net, session, command, request.args)
                return answer
        if command in ("read", "write"):
            node = self._node(session, request, 1)
            if isinstance(node, str):
                self.stats["errors"] += 1
                return node
            return await self._transfer(session, request, net, line, node)
        node = self._node(session, request, 0)
        if isinstance(node, str):
            self.stats["errors"] += 1
            return node
        {"start": line.nmt.start, "stop": line.nmt.stop, "preop": line.nmt.pre_operational,
         "reset_node": line.nmt.reset_node,
         "reset_comm": line.nmt.reset_communication}[command](node)
        return proto.format_ok(seq)

    async def _transfer(self, session: Session, request: proto.Request, net: int,
                        line: Line, node: int) -> str:
        index, sub = request.args
        seq = request.seq
        timeout = session.sdo_timeout_ms / 1000.0
        fd = line.mode == "fd"
        client = line.usdo if fd else line.sdo
        options: Dict[str, Any] = {"timeout": timeout}
        if not fd:
            options["mode"] = "block" if session.sdo_block else "auto"
        # one SDO transfer per server on a classic line's default channel:
        # sessions (and the other host protocols) reaching the same node take turns
        try:
            async with taking_turn_async(line, node):
                result, transfer = await self._run_transfer(request, client, node, index,
                                                            sub, fd, options)
        except AbortError as exc:
            self.stats["errors"] += 1
            return proto.format_abort(seq, exc.code)
        if request.command == "write":
            return proto.format_ok(seq)
        data = uploaded_bytes(result)
        kind = request.kind
        if kind is None:
            # fd lines: the server names the type of what it sent (USDO)
            code = transfer.data_type
            kind = proto.TYPE_OF_CODE.get(code, proto.TYPES["hex"]) if code else \
                proto.TYPES["hex"]
        return proto.format_answer(seq, proto.format_value(kind, data))

    async def _run_transfer(self, request: proto.Request, client: Any, node: int, index: int,
                            sub: int, fd: bool, options: Dict[str, Any]) -> Tuple[Any, Any]:
        """(result, transfer) of the request's upload or download; a cancelled
        wait aborts the transfer on the bus too."""
        if request.command == "read":
            transfer = client.start_upload(node, index, sub, **options)
        else:
            if fd and request.kind is not None and request.kind.name != "hex":
                options["data_type"] = int(request.kind.data_type)
            transfer = client.start_download(node, index, sub, request.value, **options)
        try:
            result = await transfer
        except asyncio.CancelledError:
            # the client went away (or the server closes): abort on the bus too
            self.stats["cancelled_transfers"] += 1
            try:
                transfer.cancel()
            except CanopenFDError:
                pass
            raise
        return result, transfer

    def _lss_owned(self, net: int, session: Session, command: str,
                   args: Tuple[int, ...]) -> None:
        """After a successful LSS request: who holds the net's LSS now."""
        if command == "lss_switch_sel" or (command == "lss_switch_glob" and args[0]):
            self._lss_owners[net] = session
        elif command == "lss_switch_glob":
            self._lss_owners.pop(net, None)

    def _release_lss(self, session: Session) -> None:
        """A session ends: the devices it left in LSS configuration go back
        to waiting, so other clients can use LSS again."""
        for net, owner in list(self._lss_owners.items()):
            if owner is session:
                del self._lss_owners[net]
                try:
                    self.networks[net].lss.switch_global("waiting")
                except CanopenFDError as exc:     # the line closed meanwhile
                    log.info("ASCII gateway: LSS of net %d not switched back: %s", net, exc)

    def _info_version(self, seq: int, line: Line) -> str:
        identity = [0, 0, 0, 0]
        node = line.local_node
        if node is not None:
            for sub in range(1, 5):
                try:
                    value = node[(0x1018, sub)].raw
                except (CanopenFDError, KeyError, AttributeError):
                    break
                identity[sub - 1] = int(value) if isinstance(value, int) else 0
        vendor, product, revision, serial = identity
        major, minor = (int(part) for part in (__version__.split(".") + ["0", "0"])[:2])
        return proto.format_answer(
            seq, f"{vendor} {product} {revision >> 16}.{revision & 0xFFFF} {serial} "
                 f"{GATEWAY_CLASS} {PROTOCOL_VERSION[0]}.{PROTOCOL_VERSION[1]} "
                 f"{major}.{minor}")

    async def _lss(self, seq: int, line: Line, command: str, args: Tuple[int, ...]) -> str:
        lss = line.lss
        try:
            if command == "lss_switch_glob":
                lss.switch_global("configuration" if args[0] else "waiting")
            elif command == "lss_switch_sel":
                if not await lss.start_switch_selective(*args):
                    return proto.format_error(seq, proto.TIME_OUT, "no slave answered")
            elif command == "lss_set_node":
                await lss.start_configure_node_id(args[0])
            elif command == "lss_conf_bitrate":
                await lss.aconfigure_bit_timing(args[1], args[0])
            elif command == "lss_activate_bitrate":
                lss.activate_bit_timing(args[0])
            elif command == "lss_store":
                await lss.astore()
            elif command == "lss_get_node":
                return proto.format_answer(seq, f"0x{await lss.start_inquire('node_id'):02X}")
            elif command == "lss_inquire_addr":
                names = ["vendor_id", "product_code", "revision", "serial"]
                wanted = [names[args[0]]] if args else names
                values = [await lss.start_inquire(name) for name in wanted]
                return proto.format_answer(seq, " ".join(f"0x{v:08X}" for v in values))
            elif command == "_lss_fastscan":
                return await self._lss_fastscan(seq, line, args)
            elif command == "lss_allnodes":
                return await self._lss_allnodes(seq, line, args)
        except LssError as exc:
            self.stats["errors"] += 1
            return proto.format_error(seq, lss_error_code(command, exc), str(exc)[:200])
        return proto.format_ok(seq)

    async def _lss_fastscan(self, seq: int, line: Line, args: Tuple[int, ...]) -> str:
        """One unconfigured slave found by fast scan (step timeout `args[0]`
        ms, 0 or none: 100) and left selected in the configuration state for
        the next lss_set_node / lss_store: its LSS address, as CANopenNode's
        gateway answers it. None: a time-out error."""
        device = await line.lss.start_fast_scan_identify(
            timeout_ms=args[0] if args and args[0] else 100)
        if device is None:
            return proto.format_error(seq, proto.TIME_OUT, "no unconfigured device answered")
        return proto.format_answer(seq, _address(device))

    async def _lss_allnodes(self, seq: int, line: Line, args: Tuple[int, ...]) -> str:
        """Every unconfigured slave, one at a time: found by fast scan (with
        the scan types and values of the 11-number form: 0 scan, 1 ignore,
        2 match), given the next node-id from `start` (default 2, as
        CANopenNode), stored when asked (default yes), back to waiting."""
        lss = line.lss
        timeout = args[0] if args and args[0] else 100
        start, store = (args[1], bool(args[2])) if len(args) >= 3 else (2, True)
        match: Dict[str, int] = {}
        skip: List[str] = []
        if len(args) == 11:
            for part, kind, value in zip(_LSS_PARTS, args[3::2], args[4::2]):
                if kind == 1:
                    skip.append(part)
                elif kind == 2:
                    match[part] = value
        lines: List[str] = []
        node_id = start
        while True:
            device = await lss.start_fast_scan_identify(match=match, skip=skip,
                                                        timeout_ms=timeout)
            if device is None:
                break
            await lss.start_configure_node_id(node_id)
            if store:
                await lss.astore()
            lss.switch_global("waiting")
            lines.append(f"# Node-ID {node_id} assigned to: {_address(device)}")
            if node_id >= 127:
                lines.append("# Not all nodes scanned!")
                return "\r\n".join(lines + [proto.format_ok(seq)])
            node_id += 1
        lines.append(f"# Found {node_id - start} nodes, search finished.")
        return "\r\n".join(lines + [proto.format_ok(seq)])


_LSS_PARTS = ("vendor_id", "product_code", "revision", "serial")


def _address(device: LssDevice) -> str:
    return (f"0x{device.vendor_id:08X} 0x{device.product_code:08X} 0x{device.revision:08X} "
            f"0x{device.serial:08X}")


def lss_error_code(command: str, exc: LssError) -> int:
    """The CiA 309-3 code of an LSS failure."""
    name = exc.status.name
    if name == "TIMEOUT":
        return proto.TIME_OUT
    if name == "REFUSED":
        if exc.error == 2:
            return proto.LSS_MEDIA_ERROR
        if exc.error == 1:
            return _LSS_ERRORS.get(command, proto.LSS_MANUFACTURER)
        return proto.LSS_MANUFACTURER
    return proto.INTERNAL_STATE


class BackgroundGateway:
    """An AsciiGateway served by an event loop on its own thread."""

    def __init__(self, gateway: AsciiGateway, host: str, port: int) -> None:
        self.gateway = gateway
        self._loop = asyncio.new_event_loop()
        self._started = threading.Event()
        self._error: Optional[BaseException] = None
        self._thread = threading.Thread(target=self._run, args=(host, port),
                                        name="canopenfd-ascii-gateway", daemon=True)
        self._thread.start()
        self._started.wait()
        if self._error is not None:
            raise self._error

    @property
    def port(self) -> int:
        return self.gateway.port

    def _run(self, host: str, port: int) -> None:
        asyncio.set_event_loop(self._loop)
        try:
            self._loop.run_until_complete(self.gateway.start(host, port))
        except BaseException as exc:  # noqa: BLE001 - handed to the starting thread
            self._error = exc
            self._started.set()
            self._loop.close()
            return
        self._started.set()
        self._loop.run_forever()
        self._loop.run_until_complete(self.gateway.aclose())
        self._loop.close()

    def close(self) -> None:
        """Stop the server and its thread (idempotent)."""
        if self._thread.is_alive():
            self._loop.call_soon_threadsafe(self._loop.stop)
            self._thread.join(10)

    def __enter__(self) -> "BackgroundGateway":
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()
