"""The CANopen Task of seed 004 serving a host over a byte stream: it owns
the process image of a setup file, creates the local node at InitCANopen
and answers GetID, GetStatus, InitCANopen, ReadProcessData and
WriteProcessData; NMTChange, ReceivedData and FatalError go to the host as
indications.

The image bytes an [RWOD] entry owns live in the node's object dictionary
(PDOs and SDO/USDO reach them there, in the C stack); the bytes no entry
owns, and every byte before InitCANopen, live here. An access past the end
copies fewer bytes, or none, and never reaches outside the image.
"""

from __future__ import annotations

import logging
import threading
import time
from typing import Any, Dict, List, Optional, Tuple

from ..services.nmt import NmtState
from ..errors import CanopenFDError, ClosedError, ConfigurationError
from ..gateway.remote_access_stream import ByteStream
from . import codec
from .device_od import build_od
from .setup_file import MAX_IMAGE, ImageEntry, SetupFile

log = logging.getLogger(__name__)

#: GetStatus bits 0-1 (seed 004 §4.1.2).
STATUS_INITIALISING, STATUS_READY, STATUS_OPERATING = 0, 1, 2
#: FatalError codes (this project's; seed 004 §4.2.3 leaves them internal).
FATAL_BUS_OFF = 0x01
FATAL_INTERFACE_DOWN = 0x02
FATAL_STACK_CLOSED = 0x03      # the node's network was closed under the task
#: A frame the host leaves unfinished this long is refused (s).
FRAME_TIMEOUT = 0.5
#: Indications kept while no host reads them.
MAX_PENDING = 256
#: How often the task looks for indications while the host is quiet (s).
POLL = 0.02


def status_size_bits(size: int) -> int:
    """Bits 2-4 of the status byte: (value + 1) * 32, 111b = 255; a size in
    between reports the largest such size below it (32 for smaller ones)."""
    if size >= MAX_IMAGE:
        return 7
    return max(0, min(6, size // 32 - 1))


class ProcessImageTask:
    """The device `setup` describes on `line` (a Line without a local node),
    serving the host on `stream` (or on each stream given to `serve` later,
    one at a time). `close()` ends it; the node stays on the line."""

    def __init__(self, line: Any, setup: SetupFile, stream: Optional[ByteStream] = None, *,
                 frame_timeout: float = FRAME_TIMEOUT) -> None:
        assert setup.node is not None
        self.line = line
        self.setup = setup
        self.stream: Optional[ByteStream] = None
        self.frame_timeout = frame_timeout
        self.node: Any = None
        self.bps = setup.node.bps          # the InitCANopen code in use (0 = default)
        self.node_id = setup.node.node_id
        self.decoder = codec.RequestDecoder()
        self.indications_sent = 0
        self.indications_dropped = 0
        self._image = bytearray(setup.image)
        self._owner: List[Optional[ImageEntry]] = [None] * len(self._image)
        self._entries: Dict[Tuple[int, int], ImageEntry] = {}
        for entry in setup.rwod:
            self._entries[(entry.index, entry.sub)] = entry
            for byte in range(entry.offset, entry.offset + entry.length):
                self._owner[byte] = entry
        self._lock = threading.Lock()          # the image and the indication queue
        self._pending: List[Tuple[int, bytes]] = []
        self._own_reset = False
        self._stack_lost = False
        self._closed = False
        self._thread: Optional[threading.Thread] = None
        if stream is not None:
            self.serve(stream)

    # ------------------------------------------------------------ life
    def serve(self, stream: ByteStream) -> None:
        """Serve the host on `stream` until it ends (EOF) or close()."""
        if self._thread is not None and self._thread.is_alive():
            raise ConfigurationError(f"process image task: already serving "
                                     f"{self.stream.name if self.stream else '?'}")
        self.stream = stream
        self.decoder.expire()     # a frame the last host left unfinished is not continued
        self._thread = threading.Thread(target=self._run, args=(stream,),
                                        name="process-image task", daemon=True)
        self._thread.start()

    def wait_link_closed(self, timeout: Optional[float] = None) -> bool:
        """Wait until the stream being served ends; True when it did."""
        thread = self._thread
        if thread is not None:
            thread.join(timeout)
        return thread is None or not thread.is_alive()

    def close(self) -> None:
        self._closed = True
        if self.stream is not None:
            self.stream.close()
        if self._thread is not None and threading.current_thread() is not self._thread:
            self._thread.join(timeout=2.0)

    def __enter__(self) -> "ProcessImageTask":
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    @property
    def stats(self) -> Dict[str, int]:
        out = {"accepted": self.decoder.accepted, "indications": self.indications_sent,
               "indications dropped": self.indications_dropped}
        out.update({f"refused {k}": v for k, v in self.decoder.refused.items()})
        return out

    @property
    def status(self) -> int:
        state = STATUS_OPERATING if self.node is not None else STATUS_READY
        return state | status_size_bits(len(self._image)) << 2

    # ------------------------------------------------------------ the C-like API
    def read(self, offset: int, length: int) -> bytes:
        """ReadProcessData: the bytes at offset (fewer at the end, none past it)."""
        end = min(offset + length, len(self._image))
        out = bytearray()
        with self._lock:
            pos = offset
            while pos < end:
                entry = self._owner[pos]
                if entry is None or self.node is None:
                    out.append(self._image[pos])
                    pos += 1
                    continue
                data = self.node[(entry.index, entry.sub)].data
                stop = min(end, entry.offset + entry.length)
                out += data[pos - entry.offset:stop - entry.offset]
                pos = stop
        return bytes(out)

    def write(self, offset: int, data: bytes) -> int:
        """WriteProcessData: bytes written (fewer at the end, none past it)."""
        end = min(offset + len(data), len(self._image))
        changed: List[ImageEntry] = []
        with self._lock:
            pos = offset
            while pos < end:
                entry = self._owner[pos]
                if entry is None or self.node is None:
                    self._image[pos] = data[pos - offset]
                    pos += 1
                    continue
                value = self.node[(entry.index, entry.sub)]
                stop = min(end, entry.offset + entry.length)
                old = value.data
                current = bytearray(old)
                current[pos - entry.offset:stop - entry.offset] = data[pos - offset:stop - offset]
                if current != old:
                    try:
                        value.data = bytes(current)
                    except CanopenFDError as exc:     # (unsigned entries take any bytes)
                        log.warning("process image byte %d: %s", pos, exc)
                        return pos - offset
                    changed.append(entry)
                pos = stop
        self._trigger_tpdos(changed)
        return max(0, end - offset)

    def _trigger_tpdos(self, changed: List[ImageEntry]) -> None:
        """A changed value is the event of the event-driven TPDOs mapping it:
        each such TPDO is sent once, after the whole write (never half of it:
        seed 004 §3.3, consistency)."""
        if not changed or self.node is None or self.node.state != NmtState.OPERATIONAL:
            return
        refs = {self.setup.rwod.index(entry) for entry in changed}
        for pdo in self.setup.tpdos:
            if refs.intersection(pdo.entries):
                try:
                    self.node.tpdo[pdo.number].transmit()
                except CanopenFDError as exc:    # a synchronous type takes no events
                    log.debug("TPDO %d: %s", pdo.number, exc)

    def init_canopen(self, bps: int, node_id: int) -> bool:
        """InitCANopen: start the node, or re-initialise the running one (a
        reset node, with the new node-id when one is given: seed 004 §4.1.3);
        False for values out of range or a node-id the line watches."""
        assert self.setup.node is not None
        if bps > 8 or node_id > 127:
            return False
        node_id = node_id or self.setup.node.node_id
        self.bps = bps or self.setup.node.bps
        if self.node is not None:
            if node_id != self.node.node_id:
                try:
                    self.node.set_node_id_at_reset(node_id)
                except CanopenFDError as exc:
                    log.warning("InitCANopen: %s", exc)
                    return False
                self.node_id = node_id
            self._own_reset = True       # the reset says 'n' 00 itself, then boots
            self.node.apply("RESET_NODE")
            return True
        self._indicate(codec.NMT_CHANGE, bytes((codec.NMT_INITIALISING,)))
        with self._lock:
            preset = bytes(self._image)
        node = self.line.create_local_node(node_id, od=build_od(self.setup), boot=False)
        node.on_state_change(self._state_changed)
        node.on_reset(self._reset)
        node.on_object_changed(self._object_changed)
        self.line.on_comm_event(self._comm_event)
        self.node_id = node_id
        self.node = node
        node.boot()
        for pdo in self.setup.rpdos:
            node.rpdo[pdo.number].add_callback(self._rpdo_received)
        self.write(0, preset)    # what the host wrote before InitCANopen stays
        return True

    # ------------------------------------------------------------ indications
    def _indicate(self, code: int, params: bytes) -> None:
        with self._lock:
            if len(self._pending) >= MAX_PENDING:     # no host reads them: keep the newest
                del self._pending[0]
                self.indications_dropped += 1
            self._pending.append((code, params))

    def _state_changed(self, old: Any, new: Any) -> None:
        self._indicate(codec.NMT_CHANGE, bytes((int(new) & 0xFF,)))

    def _reset(self, kind: Any) -> None:
        if kind.name == "RESET_NODE":    # entries reload [PIMG]; so do the other bytes
            with self._lock:
                for pos, owner in enumerate(self._owner):
                    if owner is None:
                        self._image[pos] = self.setup.image[pos]
        if self._own_reset:           # InitCANopen's reset: 'n' 00 was said already
            self._own_reset = False
            return
        self._indicate(codec.NMT_CHANGE, bytes((int(kind) & 0xFF,)))

    def _object_changed(self, value: Any, origin: str) -> None:
        if origin != "network":      # RPDOs: _rpdo_received, one indication per run
            return
        var = value.variable
        entry = self._entries.get((var.index, var.subindex))
        if entry is not None:
            self._indicate(codec.RECEIVED_DATA, bytes((entry.offset, entry.length)))

    def _rpdo_received(self, pdo: Any) -> None:
        """ReceivedData for what an RPDO wrote: one indication per run of
        consecutive image bytes (seed 004 §4.2.2)."""
        runs: List[List[int]] = []
        for var in pdo.map:
            entry = self._entries.get((var.index, var.subindex))
            if entry is None:
                continue                       # a dummy or an entry outside the image
            if runs and runs[-1][0] + runs[-1][1] == entry.offset:
                runs[-1][1] += entry.length
            else:
                runs.append([entry.offset, entry.length])
        for offset, length in runs:
            self._indicate(codec.RECEIVED_DATA, bytes((offset, min(length, 0xFF))))

    def _comm_event(self, event: Any) -> None:
        code = {"BUS_OFF": FATAL_BUS_OFF, "IFACE_DOWN": FATAL_INTERFACE_DOWN}.get(event.name)
        if code is not None:
            self._indicate(codec.FATAL_ERROR, bytes((code,)))

    def _take_indications(self) -> bytes:
        """The queued indications; adjacent ReceivedData ranges merged into
        one (seed 004 §4.2.2: one indication for consecutive bytes)."""
        with self._lock:
            pending, self._pending = self._pending, []
        merged: List[Tuple[int, bytes]] = []
        for code, params in pending:
            if code == codec.RECEIVED_DATA and merged and merged[-1][0] == code:
                offset, length = merged[-1][1]
                if offset + length == params[0] and length + params[1] <= 0xFF:
                    merged[-1] = (code, bytes((offset, length + params[1])))
                    continue
            merged.append((code, params))
        self.indications_sent += len(merged)
        return b"".join(codec.encode_indication(code, params) for code, params in merged)

    # ------------------------------------------------------------ the link
    def _answer(self, request: codec.Request) -> bytes:
        code, params = request.code, request.params
        if code == codec.GET_ID:
            return self.setup.ident + bytes((codec.ACK,))
        if code == codec.GET_STATUS:
            return bytes((self.status, codec.ACK))
        try:
            return self._carry_out(code, params)
        except ClosedError as exc:
            log.error("process image task: %s", exc)
            if not self._stack_lost:
                self._stack_lost = True
                self._indicate(codec.FATAL_ERROR, bytes((FATAL_STACK_CLOSED,)))
        except CanopenFDError as exc:
            log.error("process image task: %r: %s", chr(code), exc)
        return codec.nak_for(code)

    def _carry_out(self, code: int, params: bytes) -> bytes:
        if code == codec.INIT_CANOPEN:
            ok = self.init_canopen(params[0], params[1])
            return bytes((codec.ACK if ok else codec.NAK,))
        offset, length = params[0], params[1]
        if code == codec.READ_DATA:
            data = self.read(offset, length)
            return bytes((len(data),)) + data + bytes((codec.ACK,)) if data else \
                codec.nak_for(code)
        count = self.write(offset, params[2:])
        return bytes((count, codec.ACK)) if count else codec.nak_for(code)

    def _run(self, stream: ByteStream) -> None:
        last_byte = time.monotonic()
        while not self._closed:
            try:
                data = stream.read(POLL)
            except EOFError:
                break
            now = time.monotonic()
            if data:
                last_byte = now
                for item in self.decoder.feed(data):
                    self._send(stream, self._answer(item) if isinstance(item, codec.Request)
                               else codec.nak_for(item.code))
            elif self.decoder.pending and now - last_byte > self.frame_timeout:
                refused = self.decoder.expire()
                if refused is not None:
                    self._send(stream, codec.nak_for(refused.code))
            if not self.decoder.pending:
                out = self._take_indications()
                if out:
                    self._send(stream, out)
        stream.close()

    @staticmethod
    def _send(stream: ByteStream, data: bytes) -> None:
        try:
            stream.write(data)
        except EOFError:
            stream.close()      # the read then ends the loop
