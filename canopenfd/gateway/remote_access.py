"""The seed 001 remote-access protocol (ESAcademy's CANopenIA serial protocol):
frames, CRC-16 and the messages, as pure functions.

A frame is `<start><length><payload><checksum>`: the start byte carries the
network number (bits 0..3, 1..15), a checksum flag (bit 4) and a 16-bit length
flag (bit 5); the length counts the payload; the CRC-16 covers length and
payload, little-endian. The payload's first byte is the command, response or
indication letter. Every layout and where it comes from: docs/protocol-notes.md,
"Remote access protocol (seed 001)".

Nothing here raises on bytes from the wire: `FrameDecoder.feed` takes any bytes,
returns the good frames and counts the rest, and re-synchronises one byte after
the start of a bad frame; the parsers return None for what they cannot read.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import Dict, FrozenSet, List, Optional, Tuple, Union

from ..errors import ConfigurationError

#: The start byte's fields.
START_NET_MASK = 0x0F
START_CHECKSUM = 0x10
START_LENGTH16 = 0x20
START_RESERVED = 0xC0
#: The seed's default start byte: network 1, checksum on, 8-bit length.
START_DEFAULT = 0x11

#: The seed's limits: 28 bytes of user data; its largest header (the remote
#: read response "U", node, index, sub, error) adds 7, so a payload (the
#: length field) is at most 35 bytes. A host and gateway that both know
#: longer frames can raise the limit (`max_payload`) up to 0xFFFF.
SEED_MAX_DATA = 28
SEED_MAX_PAYLOAD = 35
MAX_PAYLOAD = 0xFFFF


class CrcVariant(enum.Enum):
    """Which CRC-16 the frames carry (both MSB-first, initial value 0, no final XOR).

    SEED: the polynomial the seed names, x^16+x^15+x^2+1 (0x8005); the seed gives
    no initial value or bit order, so the vendor host code's convention (MSB
    first, 0) is taken: the catalogue's CRC-16/UMTS (alias BUYPASS), check value
    0xFEE8. XMODEM: what ESAcademy's published Python host (2024) computes
    (crcmod "xmodem", polynomial 0x1021), check value 0x31C3: for CANgineBerry
    firmware that follows the code rather than the manual."""

    SEED = 0x8005
    XMODEM = 0x1021


def _table(poly: int) -> Tuple[int, ...]:
    table = []
    for byte in range(256):
        crc = byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ poly) if crc & 0x8000 else (crc << 1)
        table.append(crc & 0xFFFF)
    return tuple(table)


_TABLES: Dict[CrcVariant, Tuple[int, ...]] = {variant: _table(variant.value)
                                              for variant in CrcVariant}


def crc16(data: bytes, variant: CrcVariant = CrcVariant.SEED, crc: int = 0) -> int:
    """The frame checksum of `data` (table-driven, MSB first, from `crc`)."""
    table = _TABLES[variant]
    for byte in data:
        crc = ((crc << 8) & 0xFFFF) ^ table[((crc >> 8) ^ byte) & 0xFF]
    return crc


def parse_crc(value: Union[str, CrcVariant]) -> CrcVariant:
    """'seed' / 'xmodem' (or the enum) -> CrcVariant; ConfigurationError else."""
    if isinstance(value, CrcVariant):
        return value
    try:
        return CrcVariant[str(value).strip().upper()]
    except KeyError:
        raise ConfigurationError(
            f"remote access: unknown CRC variant {value!r}: expected 'seed' "
            "(x^16+x^15+x^2+1, as the seed writes) or 'xmodem' (ESAcademy's host code)"
        ) from None


def check_net(net: int, what: str) -> int:
    if isinstance(net, bool) or not isinstance(net, int) or not 1 <= net <= START_NET_MASK:
        raise ConfigurationError(f"{what}: network number must be 1..15 (the start byte's "
                                 f"bits 0..3; 0 is reserved), got {net!r}")
    return net


def encode_frame(payload: bytes, net: int = 1, *, checksum: bool = True,
                 crc: CrcVariant = CrcVariant.SEED, length16: Optional[bool] = None) -> bytes:
    """One frame around `payload`. The length field is 8-bit unless the payload
    needs 16 bits or length16=True asks for them (strict in what we send)."""
    check_net(net, "encode_frame")
    size = len(payload)
    if not 1 <= size <= MAX_PAYLOAD:
        raise ConfigurationError(f"encode_frame: payload of {size} bytes, expected 1..{MAX_PAYLOAD}")
    wide = size > 0xFF if length16 is None else bool(length16)
    if size > 0xFF and not wide:
        raise ConfigurationError(f"encode_frame: {size} bytes need the 16-bit length")
    start = net | (START_CHECKSUM if checksum else 0) | (START_LENGTH16 if wide else 0)
    length = size.to_bytes(2 if wide else 1, "little")
    body = length + bytes(payload)
    tail = crc16(body, crc).to_bytes(2, "little") if checksum else b""
    return bytes((start,)) + body + tail


@dataclass(frozen=True)
class Frame:
    """A frame as received: its network number, payload and start-byte flags."""
    net: int
    payload: bytes
    checksum: bool = True
    length16: bool = False


@dataclass
class DecoderStats:
    """What a FrameDecoder saw: good frames, and each kind of bad input."""
    frames: int = 0
    bad_crc: int = 0
    bad_length: int = 0        # length 0, or above max_payload
    truncated: int = 0         # a frame that stopped arriving (idle timeout or close)
    no_checksum: int = 0       # refused: checksum flag off while required
    garbage_bytes: int = 0     # bytes skipped while looking for a start byte

    def as_dict(self) -> Dict[str, int]:
        return dict(self.__dict__)


@dataclass
class FrameDecoder:
    """Bytes in, frames out. Bounded: it keeps at most one frame in progress
    (header + max_payload + checksum) plus what one feed() brought.

    A start byte is one with reserved bits 6..7 clear and a network 1..15
    (of `nets`, when given: the networks the reader serves, so that fewer
    stray bytes look like a start). After a bad frame (CRC, length) the
    search resumes at the byte after its start byte, so a frame hidden in the
    bad one's bytes is still found. A frame in progress for longer than
    `idle_timeout` seconds without its next byte is counted truncated and
    dropped the same way (`expire(now)`, which feed() runs too): a false
    start claiming more bytes than come holds the search at most that long.
    Frames without checksum are refused (counted `no_checksum`) unless
    require_checksum=False: without a CRC nothing tells a frame from noise."""

    crc: CrcVariant = CrcVariant.SEED
    max_payload: int = SEED_MAX_PAYLOAD
    require_checksum: bool = True
    idle_timeout: float = 0.5
    nets: Optional[FrozenSet[int]] = None
    stats: DecoderStats = field(default_factory=DecoderStats)
    _buffer: bytearray = field(default_factory=bytearray)
    _last_byte_at: float = 0.0

    def __post_init__(self) -> None:
        if isinstance(self.max_payload, bool) or not isinstance(self.max_payload, int) \
                or not 1 <= self.max_payload <= MAX_PAYLOAD:
            raise ConfigurationError(f"FrameDecoder: max_payload must be 1..{MAX_PAYLOAD}, "
                                     f"got {self.max_payload!r}")

    @property
    def pending(self) -> int:
        """Bytes held for a frame not complete yet."""
        return len(self._buffer)

    def expire(self, now: float) -> List[Frame]:
        """Drop a frame that stopped arriving (counted `truncated`); the
        frames found in the bytes after its start byte."""
        if self._buffer and now - self._last_byte_at > self.idle_timeout:
            self.stats.truncated += 1
            del self._buffer[:1]
            return self._scan()
        return []

    def close(self) -> None:
        """End of the stream: a frame in progress is truncated."""
        if self._buffer:
            self.stats.truncated += 1
            self._buffer.clear()

    def feed(self, data: bytes, now: float = 0.0) -> List[Frame]:
        """The frames completed by `data` (received at time `now`, seconds)."""
        frames = self.expire(now) if data else []
        if data:
            self._last_byte_at = now
            self._buffer += data
        return frames + self._scan()

    def _is_start(self, byte: int) -> bool:
        if byte & START_RESERVED or not byte & START_NET_MASK:
            return False
        return self.nets is None or (byte & START_NET_MASK) in self.nets

    def _scan(self) -> List[Frame]:
        frames: List[Frame] = []
        buf = self._buffer
        while buf:
            start = buf[0]
            if not self._is_start(start):
                # not a start byte: skip to the next candidate
                skip = 1
                while skip < len(buf) and not self._is_start(buf[skip]):
                    skip += 1
                self.stats.garbage_bytes += skip
                del buf[:skip]
                continue
            wide = bool(start & START_LENGTH16)
            header = 3 if wide else 2
            if len(buf) < header:
                break
            length = int.from_bytes(buf[1:header], "little")
            if length == 0 or length > self.max_payload:
                self.stats.bad_length += 1
                del buf[:1]
                continue
            has_crc = bool(start & START_CHECKSUM)
            if not has_crc and self.require_checksum:
                self.stats.no_checksum += 1
                del buf[:1]
                continue
            total = header + length + (2 if has_crc else 0)
            if len(buf) < total:
                break
            payload = bytes(buf[header:header + length])
            if has_crc:
                got = int.from_bytes(buf[header + length:total], "little")
                if crc16(bytes(buf[1:header + length]), self.crc) != got:
                    self.stats.bad_crc += 1
                    del buf[:1]
                    continue
            del buf[:total]
            self.stats.frames += 1
            frames.append(Frame(start & START_NET_MASK, payload, has_crc, wide))
        return frames


# ---------------------------------------------------------------- messages

class Letter(enum.IntEnum):
    """The first payload byte (seed 001 §7): commands from the host and the
    gateway's responses use the same letter; D is the gateway's indication."""
    WRITE_LOCAL = ord("W")
    READ_LOCAL = ord("R")
    WRITE_REMOTE = ord("S")
    READ_REMOTE = ord("U")
    NEW_DATA = ord("D")


class RaError(enum.IntFlag):
    """The error field of responses (UNSIGNED16, a bit per cause; seed 001 §6)."""
    OD_NOT_FOUND = 1 << 0
    INVALID_LENGTH = 1 << 1
    INVALID_COMMAND = 1 << 2
    BUSY = 1 << 3
    NO_RESOURCES = 1 << 4
    TX_FULL = 1 << 5
    ABORTED = 1 << 6
    RX_TOO_SMALL = 1 << 7
    TOGGLE = 1 << 8
    TIMEOUT = 1 << 9
    MISC = 1 << 10
    NOT_SUPPORTED = 1 << 11
    NODE_NOT_AVAILABLE = 1 << 12
    NVM_FAILURE = 1 << 13
    PDO_INCOMPLETE = 1 << 14


def error_text(error: int) -> str:
    """'OD_NOT_FOUND|BUSY' for the bits set (unknown bits in hex)."""
    if not error:
        return "no error"
    names = [bit.name or "" for bit in RaError if error & bit]
    rest = error & ~sum(int(bit) for bit in RaError)
    if rest:
        names.append(f"0x{rest:04X}")
    return "|".join(names)


@dataclass(frozen=True)
class LocalWrite:
    index: int
    sub: int
    data: bytes


@dataclass(frozen=True)
class LocalRead:
    index: int
    sub: int


@dataclass(frozen=True)
class RemoteWrite:
    node: int
    index: int
    sub: int
    data: bytes


@dataclass(frozen=True)
class RemoteRead:
    node: int
    index: int
    sub: int


@dataclass(frozen=True)
class Response:
    """A response: its letter, node (remote ones; None for local), index, sub,
    error bits and data (read responses)."""
    letter: Letter
    node: Optional[int]
    index: int
    sub: int
    error: int
    data: bytes = b""


@dataclass(frozen=True)
class NewData:
    """Indication D: node, index, sub and the data."""
    node: int
    index: int
    sub: int
    data: bytes


Command = Union[LocalWrite, LocalRead, RemoteWrite, RemoteRead]


@dataclass(frozen=True)
class BadCommand:
    """A command payload that could not be read: the letter (0 when empty),
    why (INVALID_COMMAND or INVALID_LENGTH), and the header fields present."""
    letter: int
    error: RaError
    node: Optional[int]
    index: int
    sub: int


def _u16(data: bytes, at: int) -> int:
    return data[at] | data[at + 1] << 8


def _check_key(index: int, sub: int, what: str) -> None:
    if not 0 <= index <= 0xFFFF or not 0 <= sub <= 0xFF:
        raise ConfigurationError(f"{what}: index 0x{index:X} / sub 0x{sub:X} out of range "
                                 "(index 0..0xFFFF, sub 0..0xFF)")


def _check_node(node: int, what: str) -> None:
    if not 0 <= node <= 0xFF:
        raise ConfigurationError(f"{what}: node-id {node} does not fit a byte")


def encode_command(command: Command) -> bytes:
    """The payload of a host command."""
    what = f"encode_command({command!r})"
    _check_key(command.index, command.sub, what)
    key = command.index.to_bytes(2, "little") + bytes((command.sub,))
    if isinstance(command, LocalWrite):
        return bytes((Letter.WRITE_LOCAL,)) + key + bytes(command.data)
    if isinstance(command, LocalRead):
        return bytes((Letter.READ_LOCAL,)) + key
    _check_node(command.node, what)
    if isinstance(command, RemoteWrite):
        return bytes((Letter.WRITE_REMOTE, command.node)) + key + bytes(command.data)
    return bytes((Letter.READ_REMOTE, command.node)) + key


def parse_command(payload: bytes) -> Union[Command, BadCommand]:
    """A host command, or BadCommand saying why not (never raises)."""
    if not payload:
        return BadCommand(0, RaError.INVALID_COMMAND, None, 0, 0)
    letter = payload[0]
    remote = letter in (Letter.WRITE_REMOTE, Letter.READ_REMOTE)
    if letter not in (Letter.WRITE_LOCAL, Letter.READ_LOCAL, Letter.WRITE_REMOTE,
                      Letter.READ_REMOTE):
        return BadCommand(letter, RaError.INVALID_COMMAND, None, 0, 0)
    at = 2 if remote else 1
    node = payload[1] if remote and len(payload) > 1 else (0 if remote else None)
    if len(payload) < at + 3:
        index = _u16(payload, at) if len(payload) >= at + 2 else 0
        return BadCommand(letter, RaError.INVALID_LENGTH, node, index, 0)
    index, sub, rest = _u16(payload, at), payload[at + 2], bytes(payload[at + 3:])
    if letter == Letter.WRITE_LOCAL:
        return LocalWrite(index, sub, rest)
    if letter == Letter.WRITE_REMOTE:
        assert node is not None
        return RemoteWrite(node, index, sub, rest)
    if rest:       # a read carries nothing after the sub-index
        return BadCommand(letter, RaError.INVALID_LENGTH, node, index, sub)
    if letter == Letter.READ_LOCAL:
        return LocalRead(index, sub)
    assert node is not None
    return RemoteRead(node, index, sub)


def encode_response(response: Response) -> bytes:
    """The payload of a response: letter, [node], index, sub, error, [data]."""
    head = bytes((response.letter,))
    if response.letter in (Letter.WRITE_REMOTE, Letter.READ_REMOTE):
        head += bytes((response.node or 0,))
    body = (head + response.index.to_bytes(2, "little") + bytes((response.sub,))
            + (response.error & 0xFFFF).to_bytes(2, "little"))
    if response.letter in (Letter.READ_LOCAL, Letter.READ_REMOTE):
        body += response.data
    return body


def encode_new_data(indication: NewData) -> bytes:
    """The payload of indication D: letter, node, index, sub, data."""
    _check_key(indication.index, indication.sub, "encode_new_data")
    _check_node(indication.node, "encode_new_data")
    return (bytes((Letter.NEW_DATA, indication.node)) + indication.index.to_bytes(2, "little")
            + bytes((indication.sub,)) + bytes(indication.data))


def parse_device_message(payload: bytes) -> Union[Response, NewData, None]:
    """A payload from the gateway: a response or indication D; None when
    unreadable (unknown letter or too short; never raises)."""
    if not payload:
        return None
    letter = payload[0]
    if letter == Letter.NEW_DATA:
        if len(payload) < 5:
            return None
        return NewData(payload[1], _u16(payload, 2), payload[4], bytes(payload[5:]))
    if letter not in (Letter.WRITE_LOCAL, Letter.READ_LOCAL, Letter.WRITE_REMOTE,
                      Letter.READ_REMOTE):
        return None
    remote = letter in (Letter.WRITE_REMOTE, Letter.READ_REMOTE)
    at = 2 if remote else 1
    if len(payload) < at + 5:
        return None
    data = bytes(payload[at + 5:])
    if letter in (Letter.WRITE_LOCAL, Letter.WRITE_REMOTE) and data:
        return None
    return Response(Letter(letter), payload[1] if remote else None, _u16(payload, at),
                    payload[at + 2], _u16(payload, at + 3), data)


# ---------------------------------------------------------------- the gateway's own entries
# (seed 001 §9: the manufacturer-specific entries the host reads and writes with R/W)

#: [5F00h,1..4]: own node-id, own NMT state, hardware status, hardware/firmware kind.
STATUS_INDEX = 0x5F00
#: [5F01h,1..0Ah]: reset, sleep objection, PDO filter, manager control, default times, rescan.
CONTROL_INDEX = 0x5F01
#: [5F04h,n]: the last known state of node n.
NODE_STATE_INDEX = 0x5F04
#: [5F0Ah,01h]: an NMT command: high byte node (0 = all), low byte command specifier.
NMT_INDEX = 0x5F0A

#: [5F01h,01h] values: 129 soft reset, 130 hard reset.
RESET_SOFT = 129
RESET_HARD = 130


class NodeStatus(enum.IntEnum):
    """States of [5F00h,02h] and [5F04h,n] (seed 001 §9.3). NMT states keep
    their heartbeat codes; the rest are the manager's events for a node."""
    BOOT = 0x00
    STOPPED = 0x04
    OPERATIONAL = 0x05
    PREOP = 0x7F
    EMCY_NEW = 0x80
    EMCY_OVER = 0x81
    HB_ACTIVE = 0x90
    HB_LOST = 0x91
    SCAN_STARTED = 0x9F
    SCAN_COMPLETE = 0xA0
    SCAN_ABORTED = 0xA8
    RESET_APP = 0xB0
    RESET_COM = 0xB1
    SLEEP = 0xF0
    BOOTLOADER = 0xF1


class HwStatus(enum.IntFlag):
    """[5F00h,03h]: the CAN side's condition."""
    INIT = 1 << 0
    CAN_ERROR = 1 << 1
    ERROR_PASSIVE = 1 << 2
    RX_OVERRUN = 1 << 3
    TX_OVERRUN = 1 << 4
    CAN_FD = 1 << 5
    TX_BUSY = 1 << 6
    BUS_OFF = 1 << 7


class ManagerControl(enum.IntFlag):
    """[5F01h,04h] bits 0..4 (16..22 and 24..30 are node counts)."""
    KEEP_OP = 1 << 0
    HB_RECEIVE_ALL = 1 << 1
    PDO_RECEIVE_ALL = 1 << 2
    PDO_TRANSMIT_ALL = 1 << 3
    USE_SCANNED = 1 << 4


#: The NMT command specifiers [5F0Ah,01h] takes (CiA 301's).
NMT_COMMANDS = (0x01, 0x02, 0x80, 0x81, 0x82)
