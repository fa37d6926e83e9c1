"""The host side of the seed 001 remote-access protocol: drive a gateway (a
CANopenIA coprocessor, or `canopenfd gateway --serial/--remote-access-tcp`)
over a serial line or TCP as the local API drives a line: read and write the
gateway's local OD and any node's OD, NMT, states, and indications.

    with RemoteAccessClient.open_serial("/dev/ttyUSB0") as gw:
        drive = gw.node(5, od="drive.eds")          # typed by the node's OD
        drive.write("Producer heartbeat time", 100)
        drive.start()
        gw.on_data(lambda net, d: print(d.node, hex(d.index), d.sub, d.data.hex()))

Calls block until the response (one command at a time, as the protocol
has no request tag); indications arrive on the client's reader thread.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from functools import partial
from typing import Callable, Dict, List, Optional, Union

from ..errors import CanopenFDError, ConfigurationError
from ..od import ObjectDictionary, import_od
from ..od.datatypes import Value
from ..od.fileio import Source
from ..services.nmt import NmtCommand
from ..transfer.client import Key
from ..transfer.remote import resolve
from . import remote_access as ra
from .remote_access_stream import ByteStream, connect_tcp, open_serial

log = logging.getLogger(__name__)

#: NMT commands by name, as `canopenfd nmt` spells them, and their specifier.
NMT_NAMES = {"start": 0x01, "stop": 0x02, "preop": 0x80, "reset-node": 0x81,
             "reset-comm": 0x82}


class RemoteAccessError(CanopenFDError):
    """The gateway answered a command with error bits (`error`, `error_text`),
    or did not answer (`error` None)."""

    def __init__(self, what: str, error: Optional[int], net: int) -> None:
        self.error = error
        self.net = net
        self.error_text = "no response" if error is None else ra.error_text(error)
        super().__init__(f"{what} on network {net}: {self.error_text}"
                         + ("" if error is None else f" (0x{error:04X})"))


class RemoteAccessClient:
    """A host's connection to a remote-access gateway over `stream`.

    net: the network number (1..15) commands go to unless a call says
    otherwise; timeout: seconds to wait for a response (a remote command
    waits for the node's SDO/USDO answer, so allow for its timeout)."""

    def __init__(self, stream: ByteStream, *, net: int = 1,
                 crc: Union[str, ra.CrcVariant] = "seed",
                 max_payload: int = ra.SEED_MAX_PAYLOAD, timeout: float = 6.0) -> None:
        self.net = ra.check_net(net, "RemoteAccessClient")
        self.crc = ra.parse_crc(crc)
        self.max_payload = max_payload
        self.timeout = timeout
        self.stream = stream
        self.decoder = ra.FrameDecoder(crc=self.crc, max_payload=max_payload)
        #: responses that matched no command in progress, and unreadable payloads
        self.unexpected = 0
        self.unreadable = 0
        #: indication callbacks that raised (logged)
        self.callback_errors = 0
        self._request_lock = threading.Lock()
        self._responses: "queue.Queue[ra.Response]" = queue.Queue()
        self._data_callbacks: List[Callable[[int, ra.NewData], None]] = []
        self._state_callbacks: List[Callable[[int, int, int], None]] = []
        self._closed = threading.Event()
        #: set when the reader ended: the gateway closed the stream (or close())
        self._ended = threading.Event()
        self._reader = threading.Thread(target=self._read_loop, daemon=True,
                                        name=f"ra client {stream.name}")
        self._reader.start()

    @classmethod
    def open_serial(cls, path: str, baud: int = 115200, **options: object
                    ) -> "RemoteAccessClient":
        """A client on serial port `path` (pyserial)."""
        return cls(open_serial(path, baud), **options)  # type: ignore[arg-type]

    @classmethod
    def connect(cls, host: str, port: int, **options: object) -> "RemoteAccessClient":
        """A client on a TCP connection to `host:port`."""
        return cls(connect_tcp(host, port), **options)  # type: ignore[arg-type]

    def __enter__(self) -> "RemoteAccessClient":
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"<RemoteAccessClient {self.stream.name} net {self.net}>"

    def close(self) -> None:
        self._closed.set()
        self.stream.close()
        self._reader.join(2.0)

    @property
    def stats(self) -> Dict[str, int]:
        stats = self.decoder.stats.as_dict()
        stats.update(unexpected=self.unexpected, unreadable=self.unreadable,
                     callback_errors=self.callback_errors)
        return stats

    # ------------------------------------------------------------ indications
    def on_data(self, callback: Callable[[int, ra.NewData], None]
                ) -> Callable[[int, ra.NewData], None]:
        """callback(net, NewData) for every indication D (process data, and
        the status entries 0x5F00 / 0x5F04)."""
        self._data_callbacks.append(callback)
        return callback

    def on_node_state(self, callback: Callable[[int, int, int], None]
                      ) -> Callable[[int, int, int], None]:
        """callback(net, node, status) for every [5F04h,n] indication (NodeStatus
        codes: NMT states, heartbeat active/lost, EMCY, scans)."""
        self._state_callbacks.append(callback)
        return callback

    def _read_loop(self) -> None:
        while not self._closed.is_set():
            try:
                data = self.stream.read(0.1)
            except EOFError:
                break
            now = time.monotonic()
            frames = self.decoder.feed(data, now) if data else self.decoder.expire(now)
            for frame in frames:
                message = ra.parse_device_message(frame.payload)
                if message is None:
                    self.unreadable += 1
                elif isinstance(message, ra.NewData):
                    self._deliver(frame.net, message)
                else:
                    self._responses.put(message)
        self.decoder.close()
        self._ended.set()

    def _deliver(self, net: int, data: ra.NewData) -> None:
        """Run the callbacks on the reader thread; one that raises is logged
        (the reader must go on: responses come through it too)."""
        calls: List[Callable[[], None]] = [partial(cb, net, data) for cb in self._data_callbacks]
        if data.index == ra.NODE_STATE_INDEX and data.data:
            calls += [partial(cb, net, data.sub, data.data[0]) for cb in self._state_callbacks]
        for call in calls:
            try:
                call()
            except Exception:
                self.callback_errors += 1
                log.exception("remote access client %s: indication callback", self.stream.name)

    # ------------------------------------------------------------ requests
    def _request(self, command: ra.Command, net: Optional[int], what: str) -> ra.Response:
        net = self.net if net is None else ra.check_net(net, what)
        payload = ra.encode_command(command)
        if len(payload) > self.max_payload:
            raise ConfigurationError(f"{what}: {len(payload)} bytes of command, the protocol "
                                     f"carries at most {self.max_payload} (max_payload)")
        letter = payload[0]
        node = command.node if isinstance(command, (ra.RemoteRead, ra.RemoteWrite)) else None
        with self._request_lock:
            if self._closed.is_set():
                raise RemoteAccessError(f"{what}: client closed", None, net)
            if self._ended.is_set():
                raise RemoteAccessError(f"{what}: the gateway closed the connection", None,
                                        net)
            while not self._responses.empty():     # answers to commands that timed out
                self._responses.get_nowait()
                self.unexpected += 1
            try:
                self.stream.write(ra.encode_frame(payload, net, crc=self.crc))
            except EOFError as exc:
                raise RemoteAccessError(f"{what}: {exc}", None, net) from None
            deadline = time.monotonic() + self.timeout
            while True:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise RemoteAccessError(what, None, net)
                try:
                    # short waits: a gateway hanging up ends the wait at once
                    response = self._responses.get(timeout=min(remaining, 0.1))
                except queue.Empty:
                    if self._ended.is_set() and self._responses.empty():
                        raise RemoteAccessError(f"{what}: the gateway closed the connection",
                                                None, net) from None
                    continue
                if (response.letter == letter and response.node == node
                        and (response.error or (response.index == command.index
                                                and response.sub == command.sub))):
                    break
                self.unexpected += 1
        if response.error:
            raise RemoteAccessError(what, response.error, net)
        return response

    def read_local(self, index: int, sub: int = 0, *, net: Optional[int] = None) -> bytes:
        """Read an entry of the gateway's own OD (R)."""
        return self._request(ra.LocalRead(index, sub), net,
                             f"read local 0x{index:04X}:{sub:02X}").data

    def write_local(self, index: int, sub: int, data: bytes, *,
                    net: Optional[int] = None) -> None:
        """Write an entry of the gateway's own OD (W)."""
        self._request(ra.LocalWrite(index, sub, bytes(data)), net,
                      f"write local 0x{index:04X}:{sub:02X}")

    def read_remote(self, node: int, index: int, sub: int = 0, *,
                    net: Optional[int] = None) -> bytes:
        """Read an entry of node `node` through the gateway's SDO/USDO client (U)."""
        return self._request(ra.RemoteRead(node, index, sub), net,
                             f"read node {node} 0x{index:04X}:{sub:02X}").data

    def write_remote(self, node: int, index: int, sub: int, data: bytes, *,
                     net: Optional[int] = None) -> None:
        """Write an entry of node `node` through the gateway (S)."""
        self._request(ra.RemoteWrite(node, index, sub, bytes(data)), net,
                      f"write node {node} 0x{index:04X}:{sub:02X}")

    # ------------------------------------------------------------ NMT, status, manager
    def nmt(self, command: Union[str, int, NmtCommand], node: int = 0, *,
            net: Optional[int] = None) -> None:
        """Send an NMT command ('start', 'stop', 'preop', 'reset-node',
        'reset-comm' or the specifier) to `node` (0 = all) via [5F0Ah,01h]."""
        if isinstance(command, str):
            if command not in NMT_NAMES:
                raise ConfigurationError(f"nmt: unknown command {command!r}, expected one of "
                                         f"{sorted(NMT_NAMES)}")
            code = NMT_NAMES[command]
        else:
            code = int(command)
        if code not in ra.NMT_COMMANDS or not 0 <= node <= 127:
            raise ConfigurationError(f"nmt: command 0x{code:02X} to node {node}: expected a "
                                     "specifier 1, 2, 0x80, 0x81, 0x82 and node 0..127")
        self.write_local(ra.NMT_INDEX, 1, (node << 8 | code).to_bytes(2, "little"), net=net)

    def node_state(self, node: int, *, net: Optional[int] = None) -> int:
        """[5F04h,node]: the node's last known NodeStatus code."""
        return self.read_local(ra.NODE_STATE_INDEX, node, net=net)[0]

    def own_node_id(self, *, net: Optional[int] = None) -> int:
        return self.read_local(ra.STATUS_INDEX, 1, net=net)[0]

    def own_state(self, *, net: Optional[int] = None) -> int:
        return self.read_local(ra.STATUS_INDEX, 2, net=net)[0]

    def hardware_status(self, *, net: Optional[int] = None) -> ra.HwStatus:
        return ra.HwStatus(self.read_local(ra.STATUS_INDEX, 3, net=net)[0])

    def manager_control(self, *, net: Optional[int] = None) -> int:
        """[5F01h,04h]: the automation bits (ManagerControl) and node counts."""
        return int.from_bytes(self.read_local(ra.CONTROL_INDEX, 4, net=net), "little")

    def set_manager(self, control: int, heartbeat_ms: Optional[int] = None, *,
                    net: Optional[int] = None) -> None:
        """Switch the minimal manager's automation ([5F01h,04h]) and, given, its
        heartbeat time ([5F01h,08h]) first."""
        if heartbeat_ms is not None:
            self.write_local(ra.CONTROL_INDEX, 8, heartbeat_ms.to_bytes(2, "little"), net=net)
        self.write_local(ra.CONTROL_INDEX, 4, int(control).to_bytes(4, "little"), net=net)

    def rescan(self, node: int, *, net: Optional[int] = None) -> None:
        """[5F01h,0Ah]: scan a node's PDO configuration again."""
        self.write_local(ra.CONTROL_INDEX, 0x0A, bytes((node,)), net=net)

    def reset(self, hard: bool = False, *, net: Optional[int] = None) -> None:
        """[5F01h,01h]: reset the gateway's node (soft: application, hard:
        communication)."""
        value = ra.RESET_HARD if hard else ra.RESET_SOFT
        self.write_local(ra.CONTROL_INDEX, 1, bytes((value,)), net=net)

    # ------------------------------------------------------------ node views
    def node(self, node_id: int, od: Union[ObjectDictionary, Source, None] = None, *,
             net: Optional[int] = None) -> "RemoteAccessNode":
        """A node behind the gateway as `line.add_node` gives it: `read(key)` /
        `write(key, value)` typed by its OD (an ObjectDictionary or an
        EDS/DCF/XDD file), NMT and its state. The gateway's own node-id
        reaches the gateway's local OD."""
        where = f"RemoteAccessClient.node({node_id!r})"
        if isinstance(node_id, bool) or not isinstance(node_id, int) or not 1 <= node_id <= 127:
            raise ConfigurationError(f"{where}: node-id must be 1..127")
        if od is not None and not isinstance(od, ObjectDictionary):
            od = import_od(od, node_id=node_id)
        return RemoteAccessNode(self, node_id, od, self.net if net is None else
                                ra.check_net(net, where))


class RemoteAccessNode:
    """One node reached through a remote-access gateway (RemoteAccessClient.node)."""

    def __init__(self, client: RemoteAccessClient, node_id: int,
                 od: Optional[ObjectDictionary], net: int) -> None:
        self.client = client
        self.node_id = node_id
        self.object_dictionary = od
        self.net = net

    def __repr__(self) -> str:
        return f"<RemoteAccessNode {self.node_id} net {self.net} via {self.client.stream.name}>"

    def _where(self, verb: str, key: Key) -> str:
        return f"node {self.node_id} {verb}({key!r})"

    def read(self, key: Key) -> Union[Value, bytes]:
        """The entry's value: typed when the OD knows it, else its bytes."""
        index, sub, variable = resolve(key, self.object_dictionary, self._where("read", key))
        data = self.client.read_remote(self.node_id, index, sub, net=self.net)
        return variable.decode_raw(data) if variable is not None else data

    def write(self, key: Key, value: Union[Value, bytes]) -> None:
        """Write an entry: typed by the OD when it knows the entry, else bytes."""
        where = self._where("write", key)
        index, sub, variable = resolve(key, self.object_dictionary, where)
        if variable is not None:
            data = variable.encode_raw(value)
        elif isinstance(value, (bytes, bytearray, memoryview)):
            data = bytes(value)
        else:
            raise ConfigurationError(f"{where}: without an OD entry the value must be bytes, "
                                     f"got {type(value).__name__} (give od=...)")
        self.client.write_remote(self.node_id, index, sub, data, net=self.net)

    @property
    def state(self) -> int:
        """[5F04h,n]: the last state or event the gateway knows (NodeStatus code)."""
        return self.client.node_state(self.node_id, net=self.net)

    def start(self) -> None:
        self.client.nmt("start", self.node_id, net=self.net)

    def stop(self) -> None:
        self.client.nmt("stop", self.node_id, net=self.net)

    def pre_operational(self) -> None:
        self.client.nmt("preop", self.node_id, net=self.net)

    def reset_node(self) -> None:
        self.client.nmt("reset-node", self.node_id, net=self.net)

    def reset_communication(self) -> None:
        self.client.nmt("reset-comm", self.node_id, net=self.net)
