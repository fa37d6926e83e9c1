"""Host driver bridge: moves frames between a python-can bus and a line whose
driver is CO_DRIVER_HOST.

Two daemon threads per line, because python-can has no way to wait for "a
frame to receive or a frame to send" at once:
  rx: bus.recv(0.1) -> co_rt_host_receive   (error frames ignored)
  tx: co_rt_host_transmit(batch, 100 ms) -> bus.send
Python code runs per frame here by nature; SocketCAN lines do not need this.
"""

from __future__ import annotations

import logging
import threading
from typing import TYPE_CHECKING, Optional, Protocol

from .core import ffi, lib
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


_RECV_TIMEOUT_S = 0.1
_TRANSMIT_TIMEOUT_MS = 100


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
        cframe = ffi.new("co_frame_t *")
        closed = lib.CO_RT_ERR_CLOSED
        while not self._stop.is_set():
            try:
                msg = self._bus.recv(_RECV_TIMEOUT_S)
            except Exception as exc:  # noqa: BLE001 - a dead bus ends the thread
                if not self._stop.is_set():
                    log.error("line %r: python-can recv failed, receiving stops: %s",
                              self._label, exc)
                return
            if msg is None or msg.is_error_frame:
                continue
            data = bytes(msg.data) if not msg.is_remote_frame else b""
            if len(data) > 64:
                self.rx_errors += 1
                log.warning("line %r: frame 0x%X of %d bytes ignored (at most 64)",
                            self._label, msg.arbitration_id, len(data))
                continue
            cframe.id = msg.arbitration_id
            cframe.len = msg.dlc if msg.is_remote_frame else len(data)
            cframe.flags = ((lib.CO_FRAME_FD if msg.is_fd else 0)
                            | (lib.CO_FRAME_BRS if msg.bitrate_switch else 0)
                            | (lib.CO_FRAME_ESI if msg.error_state_indicator else 0)
                            | (lib.CO_FRAME_EXT if msg.is_extended_id else 0)
                            | (lib.CO_FRAME_RTR if msg.is_remote_frame else 0))
            ffi.memmove(cframe.data, data, len(data))
            if self._rt.host_receive(self._line, cframe) == closed:
                return

    # ---------------------------------------------------------------- tx
    def _tx_loop(self) -> None:
        import can

        frames = ffi.new("co_frame_t[]", HOST_BATCH)
        while True:
            n = self._rt.host_transmit(self._line, frames, HOST_BATCH, _TRANSMIT_TIMEOUT_MS)
            if n < 0:
                return  # CLOSED: the runtime stopped
            for i in range(n):
                f = frames[i]
                flags = f.flags
                rtr = bool(flags & lib.CO_FRAME_RTR)
                msg = can.Message(
                    arbitration_id=f.id, is_extended_id=bool(flags & lib.CO_FRAME_EXT),
                    is_remote_frame=rtr, is_fd=bool(flags & lib.CO_FRAME_FD),
                    bitrate_switch=bool(flags & lib.CO_FRAME_BRS),
                    error_state_indicator=bool(flags & lib.CO_FRAME_ESI),
                    data=None if rtr else bytes(ffi.buffer(f.data, f.len)), dlc=f.len)
                try:
                    self._bus.send(msg)
                except Exception as exc:  # noqa: BLE001 - counted and logged
                    self.tx_errors += 1
                    log.warning("line %r: python-can send of 0x%X failed: %s",
                                self._label, f.id, exc)
            if self._stop.is_set() and n == 0:
                return
