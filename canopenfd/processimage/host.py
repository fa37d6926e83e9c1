"""`ProcessImage`: the host of seed 004, driving a CANopen Task over a byte
stream (a pty, a serial port, a socket) the way a host MCU would: one
request at a time, answers matched to it, indications to callbacks and to
the `indications` queue.

    image = ProcessImage(stream)
    image.init_canopen(bps=0, node_id=0)     # the task's defaults
    image.write(6, b"\\x01")                  # WriteProcessData
    image.read(0, 6)                         # ReadProcessData
"""

from __future__ import annotations

import queue
import threading
from typing import Callable, List, Optional

from ..errors import CommandError
from ..gateway.remote_access_stream import ByteStream
from . import codec

#: Seconds a request waits for its answer.
ANSWER_TIMEOUT = 2.0


class ProcessImageError(CommandError):
    """The task NAKed a request or did not answer it."""


def _check_byte(call: str, name: str, value: int) -> None:
    """Every parameter of the message form is one byte (seed 004 §1.1)."""
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 255:
        raise ValueError(f"ProcessImage.{call}: {name} {value!r} is not a byte 0..255")


class ProcessImage:
    def __init__(self, stream: ByteStream, *, timeout: float = ANSWER_TIMEOUT) -> None:
        self.stream = stream
        self.timeout = timeout
        #: Every indication received, in order (also given to the callbacks).
        self.indications: "queue.Queue[codec.Indication]" = queue.Queue()
        self._decoder = codec.TaskDecoder()
        self._request_lock = threading.Lock()    # one request at a time
        self._cond = threading.Condition()
        self._pending: Optional[int] = None
        self._answer: Optional[codec.Answer] = None
        self._callbacks: List[Callable[[codec.Indication], None]] = []
        self._closed = False
        self._thread = threading.Thread(target=self._run, name="process-image host",
                                        daemon=True)
        self._thread.start()

    def close(self) -> None:
        self._closed = True
        self.stream.close()
        self._thread.join(timeout=2.0)

    def __enter__(self) -> "ProcessImage":
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    @property
    def dropped(self) -> int:
        """Bytes from the task that fitted no answer or indication."""
        return self._decoder.dropped

    # ------------------------------------------------------------ indications
    def on_indication(self, callback: Callable[[codec.Indication], None]) -> None:
        """callback(indication) for every indication (from the reader thread)."""
        self._callbacks.append(callback)

    def on_nmt_change(self, callback: Callable[[int], None]) -> None:
        self._on(codec.NMT_CHANGE, lambda p: callback(p[0]))

    def on_received_data(self, callback: Callable[[int, int], None]) -> None:
        self._on(codec.RECEIVED_DATA, lambda p: callback(p[0], p[1]))

    def on_fatal_error(self, callback: Callable[[int], None]) -> None:
        self._on(codec.FATAL_ERROR, lambda p: callback(p[0]))

    def _on(self, code: int, call: Callable[[bytes], None]) -> None:
        self.on_indication(lambda ind: call(ind.params) if ind.code == code else None)

    def wait_indication(self, timeout: float = ANSWER_TIMEOUT) -> codec.Indication:
        """The next indication from the queue; ProcessImageError when none comes."""
        try:
            return self.indications.get(timeout=timeout)
        except queue.Empty:
            raise ProcessImageError(f"{self.stream.name}: no indication within "
                                    f"{timeout} s") from None

    # ------------------------------------------------------------ requests
    def get_id(self) -> bytes:
        """GetID: the task's 4 identification bytes."""
        return self._request(codec.GET_ID).data

    def get_status(self) -> int:
        """GetStatus: the status byte (bits 0-1 state, 2-4 image size)."""
        return self._request(codec.GET_STATUS).data[0]

    def init_canopen(self, bps: int = 0, node_id: int = 0) -> bool:
        """InitCANopen: True on ACK, False on NAK."""
        _check_byte("init_canopen", "bps", bps)
        _check_byte("init_canopen", "node_id", node_id)
        return self._request(codec.INIT_CANOPEN, bytes((bps, node_id)), nak_ok=True).ok

    def read(self, offset: int, length: int) -> bytes:
        """ReadProcessData: the bytes read (b"" when none: past the image)."""
        _check_byte("read", "offset", offset)
        _check_byte("read", "length", length)
        return self._request(codec.READ_DATA, bytes((offset, length)), nak_ok=True).data

    def write(self, offset: int, data: bytes) -> int:
        """WriteProcessData: the number of bytes written (0 past the image)."""
        _check_byte("write", "offset", offset)
        _check_byte("write", "length of data", len(data))
        answer = self._request(codec.WRITE_DATA, bytes((offset, len(data))) + bytes(data),
                               nak_ok=True)
        return answer.count

    def _request(self, code: int, params: bytes = b"", nak_ok: bool = False) -> codec.Answer:
        with self._request_lock:
            with self._cond:
                self._pending, self._answer = code, None
            self.stream.write(codec.encode_request(code, params))
            with self._cond:
                self._cond.wait_for(lambda: self._answer is not None or self._closed,
                                    self.timeout)
                answer = self._take_answer()
            if answer is None:
                raise ProcessImageError(f"{self.stream.name}: no answer to {chr(code)!r} "
                                        f"within {self.timeout} s")
            if not answer.ok and not nak_ok:
                raise ProcessImageError(f"{self.stream.name}: {chr(code)!r} refused (NAK)")
            return answer

    def _take_answer(self) -> Optional[codec.Answer]:
        """The answer that came (None: none), the request no longer pending."""
        answer, self._answer, self._pending = self._answer, None, None
        return answer

    def _run(self) -> None:
        while not self._closed:
            try:
                data = self.stream.read(0.1)
            except EOFError:
                break
            if not data:
                continue
            with self._cond:
                items, answered = self._decoder.feed(data, self._pending)
            for item in items:
                if isinstance(item, codec.Answer):
                    with self._cond:
                        self._answer = item
                        self._cond.notify_all()
                    continue
                self.indications.put(item)
                for callback in list(self._callbacks):
                    callback(item)
        with self._cond:
            self._closed = True
            self._cond.notify_all()
