"""Host driver bridge: moves frames between a python-can bus and a line whose
driver is CO_DRIVER_HOST.

Two daemon threads per line, because python-can has no way to wait for "a
frame to receive or a frame to send" at once:
  rx: bus.recv(0.1), then recv(0) for whatever python-can has ready (up to
      HOST_BATCH frames) -> one co_rt_host_receive_frames call per batch,
      which waits while the line's rx queue is full: back-pressure into
      python-can's own buffer, no frame is dropped (error frames ignored)
  tx: co_rt_host_transmit(batch, 100 ms) -> bus.send per frame; a refused
      send (a full device queue) is retried, not dropped
Python code runs per frame here by nature (python-can's API is per message);
the C calls, and the GIL hand-overs each of them costs, happen per batch.
SocketCAN lines do not need this.
"""

from __future__ import annotations

import logging
import struct
import threading
import time
from typing import TYPE_CHECKING, Optional, Protocol

from .core import CData, ffi, lib
from .runtime import HOST_BATCH, Runtime

if TYPE_CHECKING:  # pragma: no cover
    import can

log = logging.getLogger("canopenfd")


class PythonCanBus(Protocol):
    """What the bridge uses of a python-can `can.BusABC`."""

    def recv(self, timeout: Optional[float] = None) -> Optional[can.Message]:
        ...

    def send(self, msg: can.Message, timeout: Optional[float] = None) -> None:
        ...

    def shutdown(self) -> None:
        ...


_RECV_TIMEOUT_S = 0.1
_TRANSMIT_TIMEOUT_MS = 100
# How long one co_rt_host_receive_frames call waits for room before the rx
# thread looks at its stop flag again (close() also wakes it at once).
_ROOM_WAIT_MS = 100
# A send python-can refuses (its device queue is full) is retried after a
# pause growing from _SEND_RETRY_FIRST_S to _SEND_RETRY_MAX_S, for at most
# _SEND_GIVE_UP_S in a row; only then is the frame counted lost.
_SEND_RETRY_FIRST_S = 0.0002
_SEND_RETRY_MAX_S = 0.01
_SEND_GIVE_UP_S = 2.0

# co_frame_t as bytes: id, len, flags, then the data
_FRAME_SIZE = ffi.sizeof("co_frame_t")
_DATA_OFFSET = ffi.offsetof("co_frame_t", "data")
_HEAD = struct.Struct("<IBB")
assert _HEAD.size == _DATA_OFFSET == ffi.offsetof("co_frame_t", "flags") + 1

_FD = lib.CO_FRAME_FD
_BRS = lib.CO_FRAME_BRS
_ESI = lib.CO_FRAME_ESI
_EXT = lib.CO_FRAME_EXT
_RTR = lib.CO_FRAME_RTR


class HostBridge:
    """The two frame-moving threads of one host-driver line."""

    def __init__(self, runtime: Runtime, line: int, bus: PythonCanBus, label: str) -> None:
        self._rt = runtime
        self._line = line
        self._bus = bus
        self._label = label
        self._stop = threading.Event()
        self.rx_errors = 0
        self.tx_errors = 0
        self._threads = [
            threading.Thread(target=self._rx_loop, name=f"canopenfd-host-rx {label}",
                             daemon=True),
            threading.Thread(target=self._tx_loop, name=f"canopenfd-host-tx {label}",
                             daemon=True),
        ]

    def start(self) -> None:
        for thread in self._threads:
            thread.start()

    def stop(self) -> None:
        """Ask both threads to end (tx also ends when the runtime stops)."""
        self._stop.set()

    def join(self, timeout: float) -> bool:
        """True when both threads ended within timeout."""
        for thread in self._threads:
            if thread is not threading.current_thread():
                thread.join(timeout)
        return not any(t.is_alive() for t in self._threads
                       if t is not threading.current_thread())

    # ---------------------------------------------------------------- rx
    def _rx_loop(self) -> None:
        frames = ffi.new("co_frame_t[]", HOST_BATCH)
        raw = ffi.buffer(frames)
        pack_head = _HEAD.pack_into
        recv = self._bus.recv
        stop = self._stop
        while not stop.is_set():
            count = 0
            failed: Optional[Exception] = None
            try:
                msg = recv(_RECV_TIMEOUT_S)
                while msg is not None:
                    if not msg.is_error_frame:
                        remote = msg.is_remote_frame
                        data = b"" if remote else msg.data
                        size = len(data)
                        if size > 64:
                            self.rx_errors += 1
                            log.warning("line %r: frame 0x%X of %d bytes ignored (at most 64)",
                                        self._label, msg.arbitration_id, size)
                        else:
                            offset = count * _FRAME_SIZE
                            pack_head(raw, offset, msg.arbitration_id,
                                      msg.dlc if remote else size,
                                      (_FD if msg.is_fd else 0)
                                      | (_BRS if msg.bitrate_switch else 0)
                                      | (_ESI if msg.error_state_indicator else 0)
                                      | (_EXT if msg.is_extended_id else 0)
                                      | (_RTR if remote else 0))
                            if size:
                                start = offset + _DATA_OFFSET
                                raw[start:start + size] = data
                            count += 1
                            if count == HOST_BATCH:
                                break
                    msg = recv(0)
            except Exception as exc:  # noqa: BLE001 - a dead bus ends the thread
                failed = exc
            if count and not self._hand_in(frames, count):
                return
            if failed is not None:
                if not stop.is_set():
                    log.error("line %r: python-can recv failed, receiving stops: %s",
                              self._label, failed)
                return

    def _hand_in(self, frames: CData, count: int) -> bool:
        """Give frames[0:count] to the line, waiting while its rx queue is
        full; False when the runtime closed (or we were stopped meanwhile)."""
        done = 0
        while done < count:
            taken = self._rt.host_receive_frames(self._line, frames + done, count - done,
                                                 _ROOM_WAIT_MS)
            if taken < 0:
                return False  # CLOSED: the runtime stopped
            done += taken
            if done < count and self._stop.is_set():
                return False
        return True

    # ---------------------------------------------------------------- tx
    def _tx_loop(self) -> None:
        import can

        frames = ffi.new("co_frame_t[]", HOST_BATCH)
        raw = ffi.buffer(frames)
        unpack_head = _HEAD.unpack_from
        message = can.Message
        while True:
            n = self._rt.host_transmit(self._line, frames, HOST_BATCH, _TRANSMIT_TIMEOUT_MS)
            if n < 0:
                return  # CLOSED: the runtime stopped
            for i in range(n):
                offset = i * _FRAME_SIZE
                can_id, length, flags = unpack_head(raw, offset)
                rtr = bool(flags & _RTR)
                start = offset + _DATA_OFFSET
                msg = message(
                    arbitration_id=can_id, is_extended_id=bool(flags & _EXT),
                    is_remote_frame=rtr, is_fd=bool(flags & _FD),
                    bitrate_switch=bool(flags & _BRS),
                    error_state_indicator=bool(flags & _ESI),
                    data=None if rtr else raw[start:start + length], dlc=length,
                    check=False)
                if not self._send(msg):
                    return
            if self._stop.is_set() and n == 0:
                return

    def _send(self, msg: can.Message) -> bool:
        """Send one message; a refusal (device queue full) is retried with a
        growing pause for up to _SEND_GIVE_UP_S, then counted and logged.
        False when stopped while retrying."""
        pause = _SEND_RETRY_FIRST_S
        give_up = None
        while True:
            try:
                self._bus.send(msg)
                return True
            except Exception as exc:  # noqa: BLE001 - retried, then counted and logged
                now = time.monotonic()
                if give_up is None:
                    give_up = now + _SEND_GIVE_UP_S
                if now >= give_up or self._stop.is_set():
                    self.tx_errors += 1
                    log.warning("line %r: python-can send of 0x%X failed: %s",
                                self._label, msg.arbitration_id, exc)
                    return not self._stop.is_set()
            time.sleep(pause)
            pause = min(pause * 2, _SEND_RETRY_MAX_S)
