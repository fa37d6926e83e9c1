"""The message form of the CANopen API (seed 004 §2.2, §4): the bytes of
requests (host -> task, ended by ';'), answers (ended by '.' ACK or '!' NAK)
and indications (task -> host, ended by '.').

Parameters are raw bytes (seed 004: "all parameters ... are BYTE oriented"),
so a ';' inside the parameters is data: a request's length follows from its
code ('W' from its len byte) and the terminator is checked where it must be.
A frame that fails (unknown code, wrong length, no ';' where one belongs)
is NAKed and counted; the decoder resynchronises after the first ';' inside
the bad frame, else after the next ';' that comes (this project's choice,
docs/protocol-notes.md "seed 004").
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, List, Optional, Tuple, Union

REQUEST_END = 0x3B     # ';'
ACK = 0x2E             # '.'
NAK = 0x21             # '!'

GET_ID = ord("V")
GET_STATUS = ord("S")
INIT_CANOPEN = ord("I")
READ_DATA = ord("R")
WRITE_DATA = ord("W")
NMT_CHANGE = ord("n")
RECEIVED_DATA = ord("d")
FATAL_ERROR = ord("f")

#: Parameter bytes of each request before any data ('W' adds len data bytes).
REQUEST_PARAMS = {GET_ID: 0, GET_STATUS: 0, INIT_CANOPEN: 2, READ_DATA: 2, WRITE_DATA: 2}
#: Parameter bytes of each indication.
INDICATION_PARAMS = {NMT_CHANGE: 1, RECEIVED_DATA: 2, FATAL_ERROR: 1}
#: A NAKed read or write answers "0!" (seed 004 §4.1.4/§4.1.5): a count byte 0, then '!'.
_COUNTED = (READ_DATA, WRITE_DATA)

# NMTChange values (seed 004 §4.2.1)
NMT_INITIALISING = 0x00
NMT_STOPPED = 0x04
NMT_OPERATIONAL = 0x05
NMT_PRE_OPERATIONAL = 0x7F
NMT_RESET_NODE = 0x81
NMT_RESET_COMMUNICATION = 0x82


@dataclass(frozen=True)
class Request:
    code: int
    params: bytes            # everything between the code and ';'


@dataclass(frozen=True)
class BadFrame:
    code: int                # the first byte of the refused frame
    reason: str              # key of RequestDecoder.refused
    dropped: int             # bytes thrown away


def nak_for(code: int) -> bytes:
    """The NAK a refused frame gets: "0!" for reads and writes, "!" else."""
    return bytes((0, NAK)) if code in _COUNTED else bytes((NAK,))


def encode_request(code: int, params: bytes = b"") -> bytes:
    return bytes((code,)) + params + bytes((REQUEST_END,))


def encode_indication(code: int, params: bytes) -> bytes:
    if len(params) != INDICATION_PARAMS[code]:
        raise ValueError(f"indication {chr(code)!r} takes {INDICATION_PARAMS[code]} bytes")
    return bytes((code,)) + params + bytes((ACK,))


class RequestDecoder:
    """Host bytes in, requests and refused frames out, in order."""

    def __init__(self) -> None:
        self._buffer = bytearray()
        self._skipping = False        # dropping bytes until the next ';'
        self.accepted = 0
        self.refused: Dict[str, int] = {"unknown code": 0, "no terminator": 0,
                                        "incomplete": 0}

    @property
    def buffered(self) -> int:
        """Bytes of an unfinished frame held (at most one frame's worth)."""
        return len(self._buffer)

    @property
    def pending(self) -> bool:
        """True while part of a frame waits for more bytes."""
        return bool(self._buffer) or self._skipping

    def _refuse(self, code: int, reason: str, dropped: int) -> BadFrame:
        self.refused[reason] += 1
        return BadFrame(code, reason, dropped)

    def feed(self, data: bytes) -> List[Union[Request, BadFrame]]:
        out: List[Union[Request, BadFrame]] = []
        buffer = self._buffer
        buffer += data
        while buffer:
            if self._skipping:
                end = buffer.find(REQUEST_END)
                if end < 0:
                    buffer.clear()
                    break
                del buffer[:end + 1]
                self._skipping = False
                continue
            code = buffer[0]
            if code not in REQUEST_PARAMS:
                end = buffer.find(REQUEST_END)
                out.append(self._refuse(code, "unknown code", end + 1 if end >= 0 else
                                        len(buffer)))
                self._skip_through(end)
                continue
            params = REQUEST_PARAMS[code]
            if code == WRITE_DATA:
                if len(buffer) < 3:
                    break
                params += buffer[2]
            need = 1 + params + 1
            if len(buffer) < need:
                break
            if buffer[need - 1] == REQUEST_END:
                out.append(Request(code, bytes(buffer[1:need - 1])))
                self.accepted += 1
                del buffer[:need]
                continue
            inner = buffer.find(REQUEST_END, 1, need)    # a frame cut short
            end = inner if inner >= 0 else buffer.find(REQUEST_END, need)
            out.append(self._refuse(code, "no terminator", end + 1 if end >= 0 else
                                    len(buffer)))
            self._skip_through(end)
        return out

    def _skip_through(self, end: int) -> None:
        if end >= 0:
            del self._buffer[:end + 1]
        else:
            self._buffer.clear()
            self._skipping = True

    def expire(self) -> Optional[BadFrame]:
        """The host went quiet inside a frame: refuse what is buffered."""
        if not self._buffer:
            self._skipping = False
            return None
        code, dropped = self._buffer[0], len(self._buffer)
        self._buffer.clear()
        self._skipping = False
        return self._refuse(code, "incomplete", dropped)


# ------------------------------------------------------------------ host side
@dataclass(frozen=True)
class Answer:
    request: int             # the request's code
    ok: bool                 # ACK '.' or NAK '!'
    data: bytes              # V: id, S: status, R: data read; W: b"" (count in `count`)
    count: int = 0           # R/W: the count byte


@dataclass(frozen=True)
class Indication:
    code: int
    params: bytes


def _answer_shape(request: int, buf: bytes) -> Optional[Tuple[Answer, int]]:
    """(answer, bytes used) when buf starts with a whole answer to `request`;
    None while it may still become one. ValueError when it cannot."""
    if not buf:
        return None
    if request in _COUNTED:
        count = buf[0]
        if count == 0:
            if len(buf) < 2:
                return None
            if buf[1] == NAK:
                return Answer(request, False, b"", 0), 2
            raise ValueError("count 0 without '!'")
        size = 1 + (count if request == READ_DATA else 0) + 1
        if len(buf) < size:
            return None
        if buf[size - 1] != ACK:
            raise ValueError("no '.' after the answer")
        data = bytes(buf[1:size - 1])
        return Answer(request, True, data, count), size
    if buf[0] == NAK:
        return Answer(request, False, b""), 1
    size = {GET_ID: 5, GET_STATUS: 2, INIT_CANOPEN: 1}[request]
    if len(buf) < size:
        return None
    if buf[size - 1] != ACK:
        raise ValueError("no '.' after the answer")
    return Answer(request, True, bytes(buf[:size - 1])), size


def _indication_shape(buf: bytes) -> Optional[Tuple[Indication, int]]:
    if not buf:
        return None
    params = INDICATION_PARAMS.get(buf[0])
    if params is None:
        raise ValueError(f"byte {buf[0]:02X} starts no indication")
    if len(buf) < params + 2:
        return None
    if buf[params + 1] != ACK:
        raise ValueError("no '.' after the indication")
    return Indication(buf[0], bytes(buf[1:params + 1])), params + 2


class TaskDecoder:
    """Task bytes in (at the host), answers and indications out. An answer
    is recognised by the request it answers; where an answer to V, R or W
    could begin like an indication, the whole answer shape decides (this
    project's choice: the task sends indications only between answers)."""

    def __init__(self) -> None:
        self._buffer = bytearray()
        self.dropped = 0

    def feed(self, data: bytes, pending: Optional[int]
             ) -> Tuple[List[Union[Answer, Indication]], bool]:
        """(what is complete, whether the pending request got its answer);
        pending: the code of the request awaiting its answer, or None."""
        self._buffer += data
        out: List[Union[Answer, Indication]] = []
        answered = False
        while self._buffer:
            buf = bytes(self._buffer)
            waiting = pending if not answered else None
            try:
                taken = self._take(buf, waiting)
            except ValueError:
                self._buffer.pop(0)        # out of step: drop a byte and look again
                self.dropped += 1
                continue
            if taken is None:
                break
            item, used = taken
            del self._buffer[:used]
            out.append(item)
            answered = answered or isinstance(item, Answer)
        return out, answered

    @staticmethod
    def _take(buf: bytes, pending: Optional[int]
              ) -> Optional[Tuple[Union[Answer, Indication], int]]:
        if pending is None:
            return _indication_shape(buf)
        if buf[0] not in INDICATION_PARAMS or pending in (GET_STATUS, INIT_CANOPEN):
            # S answers are below 20h and I answers are '.'/'!': never 'n', 'd', 'f'
            if buf[0] in INDICATION_PARAMS:
                return _indication_shape(buf)
            return _answer_shape(pending, buf)
        try:
            answer = _answer_shape(pending, buf)
        except ValueError:        # not the answer: an indication sent before it
            return _indication_shape(buf)
        if answer is not None:
            return answer
        # the answer's shape is still incomplete; a whole indication followed
        # by a whole answer is that (an indication crossed the request)
        try:
            indication = _indication_shape(buf)
            if indication is not None and _answer_shape(pending, buf[indication[1]:]):
                return indication
        except ValueError:
            pass
        return None
