"""Byte streams the remote-access protocol runs over, each read with a
timeout: a TCP connection (SocketStream), a serial port through pyserial
(SerialStream; the optional `serial` extra), a file descriptor such as a
pty (FdStream, POSIX); and the TCP listener."""

from __future__ import annotations

import collections
import logging
import os
import select
import socket
import threading
from typing import Any, Callable, Deque, Optional, Protocol

from ..errors import ConfigurationError, InterfaceError

log = logging.getLogger(__name__)

#: Bytes asked of the OS per read.
READ_CHUNK = 4096


class ByteStream(Protocol):
    """What the server and client need of a connection."""

    name: str

    def read(self, timeout: float) -> bytes:
        """Bytes received within `timeout` s (b'' when none); EOFError once closed."""
        ...

    def write(self, data: bytes) -> None:
        """Send all of `data`; EOFError once closed."""
        ...

    def close(self) -> None:
        ...


class FdStream:
    """A stream over a file descriptor (POSIX: a pty, a tty): select with a
    timeout, os.read / os.write. `owner` (an object holding the descriptor)
    is closed with it, else the descriptor itself when `close_fd`."""

    def __init__(self, fd: int, name: str, *, owner: Any = None, close_fd: bool = True) -> None:
        self.fd = fd
        self.name = name
        self._owner = owner
        self._close_fd = close_fd
        self._closed = False
        self._write_lock = threading.Lock()
        # closing from another thread wakes a read blocked in select
        self._wake_r, self._wake_w = os.pipe()

    def __repr__(self) -> str:
        return f"<FdStream {self.name} fd={self.fd}>"

    def read(self, timeout: float) -> bytes:
        if self._closed:
            raise EOFError(f"{self.name}: closed")
        try:
            ready, _, _ = select.select([self.fd, self._wake_r], [], [], timeout)
        except (OSError, ValueError):
            raise EOFError(f"{self.name}: closed") from None
        if self._closed:
            raise EOFError(f"{self.name}: closed")
        if self.fd not in ready:
            return b""
        try:
            data = os.read(self.fd, READ_CHUNK)
        except OSError as exc:    # a pty whose other end closed reads EIO
            raise EOFError(f"{self.name}: {exc}") from None
        if not data:
            raise EOFError(f"{self.name}: end of stream")
        return data

    def write(self, data: bytes) -> None:
        with self._write_lock:
            view = memoryview(data)
            while view:
                if self._closed:
                    raise EOFError(f"{self.name}: closed")
                try:
                    written = os.write(self.fd, view)
                except BlockingIOError:
                    select.select([], [self.fd], [], 0.1)
                    continue
                except OSError as exc:
                    raise EOFError(f"{self.name}: {exc}") from None
                view = view[written:]

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        os.write(self._wake_w, b"x")
        if self._owner is not None:
            try:
                self._owner.close()
            except OSError:
                pass
        elif self._close_fd:
            try:
                os.close(self.fd)
            except OSError:
                pass
        for fd in (self._wake_r, self._wake_w):
            try:
                os.close(fd)
            except OSError:
                pass


class SocketStream:
    """A TCP connection as a stream (sockets select on every OS); closing it
    from another thread ends a read within its timeout."""

    def __init__(self, sock: socket.socket, name: str) -> None:
        self.name = name
        self._sock = sock
        self._closed = False
        self._write_lock = threading.Lock()
        sock.setblocking(True)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

    def __repr__(self) -> str:
        return f"<SocketStream {self.name}>"

    def read(self, timeout: float) -> bytes:
        if self._closed:
            raise EOFError(f"{self.name}: closed")
        try:
            ready, _, _ = select.select([self._sock], [], [], timeout)
            if not ready:
                return b""
            data = self._sock.recv(READ_CHUNK)
        except (OSError, ValueError) as exc:
            raise EOFError(f"{self.name}: {exc}") from None
        if not data:
            raise EOFError(f"{self.name}: closed by the peer")
        return data

    def write(self, data: bytes) -> None:
        with self._write_lock:
            if self._closed:
                raise EOFError(f"{self.name}: closed")
            try:
                self._sock.sendall(data)
            except OSError as exc:
                raise EOFError(f"{self.name}: {exc}") from None

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        try:
            self._sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        self._sock.close()


class SerialStream:
    """A pyserial port as a stream (any OS pyserial supports)."""

    def __init__(self, port: Any, name: str) -> None:
        self.name = name
        self._port = port
        self._timeout: Optional[float] = port.timeout
        self._closed = False
        self._write_lock = threading.Lock()

    def __repr__(self) -> str:
        return f"<SerialStream {self.name}>"

    def read(self, timeout: float) -> bytes:
        if self._closed:
            raise EOFError(f"{self.name}: closed")
        try:
            if timeout != self._timeout:      # pyserial reconfigures the port on each change
                self._port.timeout = timeout
                self._timeout = timeout
            first = self._port.read(1)
            if not first:
                return b""
            waiting = self._port.in_waiting
            return bytes(first) + (bytes(self._port.read(min(waiting, READ_CHUNK)))
                                   if waiting else b"")
        except (OSError, TypeError, ValueError, AttributeError) as exc:
            # pyserial's SerialException is an OSError; a port closed under a
            # read fails with TypeError/AttributeError in some versions
            raise EOFError(f"{self.name}: {exc}") from None

    def write(self, data: bytes) -> None:
        with self._write_lock:
            if self._closed:
                raise EOFError(f"{self.name}: closed")
            try:
                self._port.write(data)
            except (OSError, TypeError, ValueError) as exc:
                raise EOFError(f"{self.name}: {exc}") from None

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        try:
            self._port.cancel_read()
        except (OSError, AttributeError):
            pass
        try:
            self._port.close()
        except OSError:
            pass


def open_serial(path: str, baud: int = 115200) -> SerialStream:
    """A serial port as a stream (8N1, raw). Needs pyserial (`pip install
    canopenfd[serial]`)."""
    if isinstance(baud, bool) or not isinstance(baud, int) or baud <= 0:
        raise ConfigurationError(f"serial port {path}: baud rate must be a positive int, "
                                 f"got {baud!r}")
    try:
        import serial  # type: ignore[import-untyped]
    except ImportError:
        raise ConfigurationError(
            f"serial port {path}: pyserial is not installed (pip install 'canopenfd[serial]')"
        ) from None
    try:
        port = serial.Serial(path, baud, timeout=0.1)
    except (OSError, ValueError) as exc:
        raise InterfaceError(f"serial port {path} at {baud} Bd: {exc}") from None
    return SerialStream(port, f"serial {path}")


def connect_tcp(host: str, port: int, timeout: float = 5.0) -> SocketStream:
    """A TCP connection to a remote-access gateway as a stream."""
    try:
        sock = socket.create_connection((host, port), timeout=timeout)
    except OSError as exc:
        raise InterfaceError(f"remote access TCP {host}:{port}: {exc}") from None
    return SocketStream(sock, f"tcp {host}:{port}")


class TcpListener:
    """Accepts TCP connections on its own thread and hands each one, as a
    stream, to `on_connection`."""

    def __init__(self, port: int, on_connection: Callable[[SocketStream], None],
                 host: str = "127.0.0.1") -> None:
        if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 0xFFFF:
            raise ConfigurationError(f"remote access TCP: port must be 0..65535, got {port!r}")
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self._sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            self._sock.bind((host, port))
        except OSError as exc:
            self._sock.close()
            raise InterfaceError(f"remote access TCP {host}:{port}: {exc}") from None
        self._sock.listen(8)
        self.host = host
        self.port: int = self._sock.getsockname()[1]
        self._on_connection = on_connection
        self._closed = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True,
                                        name=f"remote-access tcp {self.port}")
        #: the last peers that connected, as "tcp ADDRESS:PORT" (bounded: a
        #: listener may run for months)
        self.connections: Deque[str] = collections.deque(maxlen=100)
        self._thread.start()

    def _run(self) -> None:
        while not self._closed.is_set():
            try:
                ready, _, _ = select.select([self._sock], [], [], 0.2)
                if not ready or self._closed.is_set():
                    continue
                conn, peer = self._sock.accept()
            except (OSError, ValueError):
                return
            name = f"tcp {peer[0]}:{peer[1]}"
            self.connections.append(name)
            try:
                self._on_connection(SocketStream(conn, name))
            except Exception:  # noqa: BLE001 - one host's failure never ends the listener
                log.exception("remote access TCP %d: %s", self.port, name)
                conn.close()

    def close(self, timeout: Optional[float] = 2.0) -> None:
        self._closed.set()
        self._thread.join(timeout)
        self._sock.close()
