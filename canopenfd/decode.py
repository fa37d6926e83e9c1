"""One-line, human-readable text for a CAN frame: NMT, boot-up, heartbeat,
node guarding, SYNC, TIME, EMCY (classic and FD), PDOs, USDO (CAN FD frames on
0x601..0x67F and 0x581..0x5FF) and classic SDO (classic frames on the same
CAN-IDs) decoded, malformed ones marked; anything else shown raw. Used by the
CLI monitor and the demo; pure Python, no runtime needed. SYNC, TIME, EMCY and
PDOs are decoded in `canopenfd.decode_services`.

`decode()` / `describe()` look at one frame alone: PDOs by the CiA 301 default
CAN-IDs ("TPDO1 node 5 01 02"). A `Decoder` (what the monitor keeps) also
follows what needs earlier frames, and decodes PDOs by the mappings of the
object dictionaries given to it (`Decoder(ods=[(od, node_id)])`):

- A classic SDO block transfer's sub-block segments carry no command
  specifier (byte 0 is the last-segment bit and a sequence number), so alone
  they read as whatever command byte 0 happens to spell; the `Decoder` follows
  each SDO server's transfers and names them "block segment #N".
- A node guarding reply whose toggle bit is 0 looks like a heartbeat; after a
  node guarding request (remote frame on 0x700 + node-id) the `Decoder` reads
  the node's next one-byte frame as the reply. Alone, only a byte with bit 7
  set (toggle 1) is known to be a reply."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Dict, Iterable, Optional, Set, Tuple

from .decode_services import (EMCY_BASE, SYNC_ID, TIME_ID, PdoDefinition, PdoMap,
                              ServiceIds, default_pdo, default_pdo_text, emcy_text, hex_bytes,
                              pdo_text, service_text, sync_text, time_text)
from .errors import ABORT_TEXT, USDO_ABORT_TEXT
from .services.nmt import NmtCommand, NmtState
from .od.datatypes import DataType

_FD = 0x01
_BRS = 0x02
_ESI = 0x04
_EXT = 0x08
_RTR = 0x10


def _fields(frame: Any):
    """(id, data, flags) of a Frame, a python-can Message or an (id, data[, flags]) tuple."""
    if isinstance(frame, tuple):
        can_id, data = frame[0], bytes(frame[1])
        return can_id, data, (frame[2] if len(frame) > 2 else 0)
    if hasattr(frame, "arbitration_id"):  # python-can Message
        flags = ((_FD if frame.is_fd else 0) | (_BRS if frame.bitrate_switch else 0)
                 | (_ESI if frame.error_state_indicator else 0)
                 | (_EXT if frame.is_extended_id else 0)
                 | (_RTR if frame.is_remote_frame else 0))
        return frame.arbitration_id, bytes(frame.data), flags
    return frame.id, bytes(frame.data), frame.flags


def format_raw(frame: Any, max_bytes: Optional[int] = None) -> str:
    """'0x181 [8] 01 02 03 04 05 06 07 08' (29-bit ids with 8 digits, RTR marked);
    with max_bytes, longer data is cut there and ends with '...'."""
    can_id, data, flags = _fields(frame)
    ident = f"0x{can_id:08X}" if flags & _EXT else f"0x{can_id:03X}"
    if flags & _RTR:
        length = getattr(frame, "length", len(data))
        return f"{ident} [{length}] RTR"
    text = f"{ident} [{len(data)}]"
    if max_bytes is not None and len(data) > max_bytes:
        return f"{text} {hex_bytes(data[:max_bytes])} ..."
    return f"{text} {hex_bytes(data)}" if data else text


def format_flags(frame: Any) -> str:
    """'[FD]', '[FD BRS]', '[FD BRS ESI]' or '' for classic frames."""
    _, _, flags = _fields(frame)
    if not flags & _FD:
        return ""
    parts = ["FD"] + (["BRS"] if flags & _BRS else []) + (["ESI"] if flags & _ESI else [])
    return "[" + " ".join(parts) + "]"


def _is_sdo_id(can_id: int) -> bool:
    """0x581..0x5FF or 0x601..0x67F: (U)SDO server->client or client->server."""
    return 0x581 <= can_id <= 0x5FF or 0x601 <= can_id <= 0x67F


def meaning(frame: Any) -> str:
    """What the frame means in CANopen terms, '' when it is nothing this module
    knows. On 0x581..0x5FF and 0x601..0x67F a CAN FD frame is USDO and a
    classic frame is SDO, read alone: byte 0 is taken as a command specifier, so a
    block transfer's sub-block segment reads as the command its byte 0 spells, or
    as 'unknown command 0xNN or block segment #N' (a `Decoder` knows which).
    PDOs are named by the default CAN-IDs only (a `Decoder` with an object
    dictionary decodes their values)."""
    return _meaning(frame, None)


def _meaning(frame: Any, decoder: Optional["Decoder"]) -> str:
    can_id, data, flags = _fields(frame)
    rtr, fd = bool(flags & _RTR), bool(flags & _FD)
    if decoder is not None:
        service = decoder.service(can_id, bool(flags & _EXT))
        if service is not None and not rtr:
            return service_text(service[0], service[1], data, fd)
        pdo = decoder.pdo(can_id, bool(flags & _EXT))
        if pdo is not None:
            return pdo_text(pdo, data, fd, rtr)
    if flags & _EXT:
        return ""
    if rtr:
        if 0x701 <= can_id <= 0x77F:
            if decoder is not None:
                decoder.guarding_requested(can_id - 0x700)
            return f"node guarding request node {can_id - 0x700}"
        found = default_pdo(can_id)
        return default_pdo_text(can_id, data, rtr=True) if found and found[0][0] == "T" else ""
    if can_id == 0x000:
        return _nmt(data)
    if can_id == SYNC_ID:
        return sync_text(data)
    if EMCY_BASE < can_id <= EMCY_BASE + 0x7F:
        return emcy_text(can_id - EMCY_BASE, data, fd)
    if can_id == TIME_ID:
        return time_text(data)
    if 0x700 <= can_id <= 0x77F:
        node = can_id - 0x700
        guarded = decoder is not None and decoder.guarding_reply(node, data)
        return _heartbeat(node, data, guarded)
    if _is_sdo_id(can_id):
        if fd:
            return _usdo(can_id, data)
        return decoder.sdo(can_id, data) if decoder is not None else _sdo(can_id, data)
    return default_pdo_text(can_id, data)


def decode(frame: Any) -> str:
    """Readable one-line text: the meaning when known, else the raw frame;
    FD frames end with their marker ('[FD BRS]')."""
    return _decode(frame, meaning(frame))


def _decode(frame: Any, text: str) -> str:
    text = text or format_raw(frame)
    marker = format_flags(frame)
    return f"{text} {marker}" if marker else text


#: describe() shows at most this many raw bytes of a frame it decodes (a USDO
#: segment's 60 data bytes would drown the line); undecoded frames show all.
DESCRIBE_RAW_BYTES = 12


def describe(frame: Any, width: int = 30) -> str:
    """Raw frame, then its meaning: the CLI monitor's line."""
    return _describe(frame, meaning(frame), width)


def _describe(frame: Any, text: str, width: int) -> str:
    raw = format_raw(frame, DESCRIBE_RAW_BYTES if text else None)
    marker = format_flags(frame)
    line = f"{raw:<{width}} {text}".rstrip() if text else raw
    return f"{line} {marker}" if marker else line


def _nmt(data: bytes) -> str:
    if len(data) != 2:
        return f"NMT malformed: {len(data)} bytes, expected 2" + (
            f" ({hex_bytes(data)})" if data else "")
    command, node_id = data
    target = "all" if node_id == 0 else f"node {node_id}"
    try:
        label = NmtCommand(command).label
    except ValueError:
        return f"NMT malformed: unknown command 0x{command:02X} for {target}"
    if node_id > 127:
        return f"NMT {label} node {node_id} malformed: node-id outside 0..127"
    return f"NMT {label} {target}"


_GUARDED_STATES = (NmtState.STOPPED, NmtState.OPERATIONAL, NmtState.PRE_OPERATIONAL)


def _heartbeat(node_id: int, data: bytes, guarded: bool = False) -> str:
    """A frame on 0x700 + node-id: boot-up, heartbeat, or node guarding reply
    (bit 7 set is the guarding toggle; guarded: the answer to a request seen)."""
    if node_id == 0:
        return "heartbeat malformed: CAN-ID 0x700 (node-id 0)"
    if len(data) != 1:
        what = "node guarding reply" if guarded else "heartbeat"
        return f"{what} node {node_id} malformed: {len(data)} bytes, expected 1"
    code = data[0]
    if code == NmtState.INITIALISING:
        return f"boot-up node {node_id}"
    if code & 0x80 or guarded:
        return _guarding_reply(node_id, code)
    try:
        state = NmtState(code)
    except ValueError:
        state = None
    if state is None or state is NmtState.UNKNOWN:
        return f"heartbeat node {node_id} malformed: state 0x{code:02X}"
    return f"heartbeat node {node_id} {state.label}"


def _guarding_reply(node_id: int, code: int) -> str:
    """Node guarding reply: NMT state in bits 0..6, toggle in bit 7."""
    head = f"node guarding reply node {node_id}"
    toggle, state = code >> 7, code & 0x7F
    if state not in _GUARDED_STATES:
        return f"{head} toggle {toggle} malformed: state 0x{state:02X}"
    return f"{head} {NmtState(state).label} toggle {toggle}"


# ------------------------------------------------------------------ USDO
# Wire format: csrc/core/co_usdo.h (the codec, source of truth) and
# docs/protocol-notes.md. The CAN-ID's low 7 bits name the sender, byte 0 the
# addressee (0 = broadcast), byte 1 is the command specifier, byte 2 the
# session-ID; sub-index (byte 3) comes before the index (bytes 4-5, LE).

_USDO_REQUEST = 0x600    # + client node-id
_USDO_RESPONSE = 0x580   # + server node-id
_USDO_EXPEDITED_MAX = 56
_USDO_SEGMENT_DATA = 60

# Layouts (co_usdo_layout_t): bytes the frame needs before any data.
_MUX = "mux"                  # dest cs sid sub index(2)                 6
_EXPEDITED = "expedited"      # mux type N data[N]                       8 + N
_INITIATE = "initiate"        # mux type reserved size(4)                12
_SEGMENT = "segment"          # dest cs sid counter data[60]             64
_LAST = "last"                # dest cs sid n data[n]                    4 + n
_COUNTER = "counter"          # dest cs sid counter                      4
_END = "end"                  # dest cs sid                              3
_ABORT = "abort"              # mux code                                 7
_BULK_ACCEPT = "bulk accept"  # mux pacing(2), 100 us units, 0 = none    8

_HEAD_LEN = {_MUX: 6, _EXPEDITED: 8, _INITIATE: 12, _SEGMENT: 64, _LAST: 4, _COUNTER: 4,
             _END: 3, _ABORT: 7, _BULK_ACCEPT: 8}
_HAS_MUX = (_MUX, _EXPEDITED, _INITIATE, _ABORT, _BULK_ACCEPT)

#: Command specifier -> (text, layout), as co_usdo_cs_t / co_usdo_layout_of.
#: Data-carrying frames are named after the data ("upload segment" is the
#: server's 0x33), confirmations "... response".
USDO_COMMANDS: Dict[int, Tuple[str, str]] = {
    0x01: ("download expedited", _EXPEDITED),
    0x02: ("download initiate", _INITIATE),
    0x03: ("download segment", _SEGMENT),
    0x04: ("download last segment", _LAST),
    0x06: ("bulk download initiate", _INITIATE),
    0x07: ("bulk segment", _SEGMENT),
    0x08: ("bulk last segment", _LAST),
    0x11: ("upload request", _MUX),
    0x13: ("upload segment request", _COUNTER),
    0x21: ("download expedited response", _MUX),
    0x22: ("download initiate response", _MUX),
    0x23: ("download segment response", _COUNTER),
    0x24: ("download last segment response", _END),
    0x26: ("bulk accept", _BULK_ACCEPT),
    0x28: ("bulk last segment response", _END),
    0x31: ("upload expedited", _EXPEDITED),
    0x32: ("upload initiate", _INITIATE),
    0x33: ("upload segment", _SEGMENT),
    0x34: ("upload last segment", _LAST),
    0x7F: ("ABORT", _ABORT),
}

_SHORT_TYPE_PREFIXES = (("UNSIGNED", "U"), ("INTEGER", "I"), ("REAL", "R"))


def usdo_type_name(code: int) -> str:
    """Name of a USDO data-type byte (CiA 301 type index): 'U32', 'I16', 'R64',
    'BOOLEAN', 'VISIBLE_STRING', 'DOMAIN'...; 'type 0xNN' when it is none."""
    try:
        name = DataType(code).name
    except ValueError:
        return f"type 0x{code:02X}"
    for long, short in _SHORT_TYPE_PREFIXES:
        if name.startswith(long) and name[len(long):].isdigit():
            return short + name[len(long):]
    return name


def usdo_abort_text(code: int) -> str:
    """'0x33 object does not exist', '0x99 unknown abort code'."""
    return f"0x{code:02X} {USDO_ABORT_TEXT.get(code, 'unknown abort code')}"


def _pacing(units: int) -> str:
    if units == 0:
        return "pacing 0 (none)"
    micros = units * 100
    shown = f"{micros} us" if micros < 1000 else f"{micros / 1000:g} ms"
    return f"pacing {units} ({shown})"


def _usdo(can_id: int, data: bytes) -> str:
    sender = can_id - (_USDO_REQUEST if can_id > _USDO_REQUEST else _USDO_RESPONSE)
    if len(data) < 3:
        return (f"USDO {sender} malformed: {len(data)} bytes, expected at least 3"
                + (f" ({hex_bytes(data)})" if data else ""))
    dest = "bcast" if data[0] == 0 else str(data[0])
    head = f"USDO {sender}->{dest} sid {data[2]}"
    cs = data[1]
    command = USDO_COMMANDS.get(cs)
    if command is None:
        return f"{head} unknown command 0x{cs:02X}"
    name, layout = command
    mux: Optional[str] = None
    if layout in _HAS_MUX and len(data) >= 6:
        mux = f"0x{data[4] | data[5] << 8:04X}:{data[3]:02X}"
    what = f"{head} {name}" + (f" {mux}" if mux else "")

    def malformed(why: str) -> str:
        return f"{what} malformed: {why}"

    need = _HEAD_LEN[layout]
    if len(data) < need:
        return malformed(f"{len(data)} bytes, expected {need}"
                         + (" or more" if layout in (_EXPEDITED, _LAST) else ""))
    if layout == _EXPEDITED:
        n = data[7]
        if n > _USDO_EXPEDITED_MAX:
            return malformed(f"N={n} > {_USDO_EXPEDITED_MAX}")
        if len(data) < 8 + n:
            return malformed(f"{len(data)} bytes, N={n} needs {8 + n}")
        text = f"{what} {usdo_type_name(data[6])} N={n}"
        return f"{text} {hex_bytes(data[8:8 + n])}" if n else text
    if layout == _INITIATE:
        size = int.from_bytes(data[8:12], "little")
        shown = "0xFFFFFFFF (unknown)" if size == 0xFFFFFFFF else str(size)
        return f"{what} {usdo_type_name(data[6])} size {shown}"
    if layout == _SEGMENT:
        return f"{what} #{data[3]} {_USDO_SEGMENT_DATA} B"
    if layout == _LAST:
        n = data[3]
        if n > _USDO_SEGMENT_DATA:
            return malformed(f"n={n} > {_USDO_SEGMENT_DATA}")
        if len(data) < 4 + n:
            return malformed(f"{len(data)} bytes, n={n} needs {4 + n}")
        return f"{what} {n} B"
    if layout == _COUNTER:
        return f"{what} #{data[3]}"
    if layout == _ABORT:
        return f"{what} {usdo_abort_text(data[6])}"
    if layout == _BULK_ACCEPT:
        return f"{what} {_pacing(data[6] | data[7] << 8)}"
    return what  # _MUX, _END: nothing more


# ------------------------------------------------------------------ classic SDO
# CiA 301 SDO protocols (expedited, segmented, block): classic 8-byte frames. The
# CAN-ID names the server either way: 0x600 + node-id carries the client's
# requests ("rx", what the server receives), 0x580 + node-id the server's
# responses ("tx"). Byte 0 is the command specifier (bits 7-5: ccs from the
# client, scs from the server), bytes 1-2 the index (LE), byte 3 the sub-index,
# bytes 4-7 data or a size in initiate and abort frames. Reserved bits of byte 0
# are ignored, as stacks do. Block sub-block segments have no command specifier:
# byte 0 is c (last segment) << 7 | seqno (1..127).

_SDO_RX = 0x600     # client -> server, + server node-id
_SDO_TX = 0x580     # server -> client, + server node-id
_SDO_LEN = 8
_SDO_ABORT = 0x80
_SDO_BLKSIZE_MAX = 127
_SDO_CS_MASK = 0xE3             # ccs/scs and the sub-command bits of block frames
_SDO_BLOCK_ACK = 0xA2           # client: block upload ack; server: block download ack
_SDO_BLOCK_UPLOAD_START = 0xA3  # client
_SDO_BLOCK_DOWNLOAD_OK = 0xA0   # server: initiate block download response


def sdo_abort_text(code: int) -> str:
    """'0x06010002 attempt to write a read-only object', '0x12345678 unknown abort code'."""
    return f"0x{code:08X} {ABORT_TEXT.get(code, 'unknown abort code')}"


def _sdo_node(can_id: int) -> Tuple[int, bool]:
    """(server node-id, True for a client->server frame)."""
    if can_id > _SDO_RX:
        return can_id - _SDO_RX, True
    return can_id - _SDO_TX, False


def _sdo_head(can_id: int) -> str:
    node, rx = _sdo_node(can_id)
    return f"SDO {node} {'rx' if rx else 'tx'}"


def _sdo_mux(data: bytes) -> str:
    return f"0x{data[1] | data[2] << 8:04X}:{data[3]:02X}"


def _sdo_size(data: bytes, indicated: int) -> str:
    if not indicated:
        return "size not indicated"
    return f"size {int.from_bytes(data[4:8], 'little')}"


def _sdo_crc(command: int) -> str:
    """' crc' when the cc/sc bit (CRC supported) is set."""
    return " crc" if command & 0x04 else ""


def _sdo_checked(text: str, *problems: str) -> str:
    found = [p for p in problems if p]
    return f"{text} malformed: {', '.join(found)}" if found else text


def _blksize_problem(blksize: int) -> str:
    return "" if 1 <= blksize <= _SDO_BLKSIZE_MAX else f"blksize {blksize} outside 1..127"


def _sdo_initiate(name: str, data: bytes) -> str:
    """Initiate download request / initiate upload response (one layout)."""
    command = data[0]
    expedited, sized, unused = command & 0x02, command & 0x01, (command >> 2) & 0x03
    mux = _sdo_mux(data)
    if not expedited:
        return f"{name} {mux} {_sdo_size(data, sized)}"
    if sized:
        payload = data[4:8 - unused]
        return f"{name} expedited {mux} {len(payload)} B {hex_bytes(payload)}"
    return f"{name} expedited {mux} size not indicated {hex_bytes(data[4:8])}"


def _sdo_segment(name: str, data: bytes) -> str:
    """Download segment request / upload segment response: t, n unused bytes, c."""
    command = data[0]
    count = 7 - ((command >> 1) & 0x07)
    text = f"{name} t={command >> 4 & 1}{' last' if command & 1 else ''} {count} B"
    return f"{text} {hex_bytes(data[1:1 + count])}" if count else text


def _sdo_abort(data: bytes) -> str:
    return f"ABORT {_sdo_mux(data)} {sdo_abort_text(int.from_bytes(data[4:8], 'little'))}"


def _sdo_ack(name: str, data: bytes) -> str:
    ackseq, blksize = data[1], data[2]
    return _sdo_checked(f"{name} seqno {ackseq} blksize {blksize}",
                        f"seqno {ackseq} outside 0..127" if ackseq > _SDO_BLKSIZE_MAX else "",
                        _blksize_problem(blksize))


def _sdo_end(name: str, data: bytes) -> str:
    """End block download request / end block upload (server): n unused bytes, CRC."""
    return f"{name} n={(data[0] >> 2) & 0x07} crc 0x{data[1] | data[2] << 8:04X}"


def _block_segment(command: int) -> str:
    return f"block segment #{command & 0x7F}{' last' if command & 0x80 else ''}"


def _sdo_unknown(command: int) -> str:
    """Byte 0 is no command specifier of this direction: it may still be a block
    segment of a transfer whose start was not seen."""
    text = f"unknown command 0x{command:02X}"
    return f"{text} or {_block_segment(command)}" if command & 0x7F else text


def _sdo_client(data: bytes) -> str:
    """A client->server frame, byte 0 read as a command specifier (ccs)."""
    command = data[0]
    ccs = command >> 5
    if ccs == 0:
        return _sdo_segment("download segment", data)
    if ccs == 1:
        return _sdo_initiate("initiate download", data)
    if ccs == 2:
        return f"initiate upload {_sdo_mux(data)}"
    if ccs == 3:
        return f"upload segment request t={command >> 4 & 1}"
    if ccs == 4:
        return _sdo_abort(data)
    if ccs == 5:                                     # block upload, cs in bits 1-0
        cs = command & 0x03
        if cs == 0:
            return _sdo_checked(f"initiate block upload {_sdo_mux(data)} blksize {data[4]} "
                                f"pst {data[5]}{_sdo_crc(command)}", _blksize_problem(data[4]))
        if cs == 1:
            return "end block upload response"
        if cs == 2:
            return _sdo_ack("block upload ack", data)
        return "start block upload"
    if ccs == 6:                                     # block download, cs in bit 0
        if command & 0x01:
            return _sdo_end("end block download", data)
        return (f"initiate block download {_sdo_mux(data)} {_sdo_size(data, command & 0x02)}"
                f"{_sdo_crc(command)}")
    return _sdo_unknown(command)


def _sdo_server(data: bytes) -> str:
    """A server->client frame, byte 0 read as a command specifier (scs)."""
    command = data[0]
    scs = command >> 5
    if scs == 0:
        return _sdo_segment("upload segment", data)
    if scs == 1:
        return f"download segment response t={command >> 4 & 1}"
    if scs == 2:
        return _sdo_initiate("initiate upload response", data)
    if scs == 3:
        return f"initiate download response {_sdo_mux(data)}"
    if scs == 4:
        return _sdo_abort(data)
    if scs == 5:                                     # block download, ss in bits 1-0
        ss = command & 0x03
        if ss == 0:
            return _sdo_checked(f"initiate block download response {_sdo_mux(data)} "
                                f"blksize {data[4]}{_sdo_crc(command)}", _blksize_problem(data[4]))
        if ss == 1:
            return "end block download response"
        if ss == 2:
            return _sdo_ack("block download ack", data)
        return _sdo_unknown(command)
    if scs == 6:                                     # block upload, ss in bit 0
        if command & 0x01:
            return _sdo_end("end block upload", data)
        return (f"initiate block upload response {_sdo_mux(data)} "
                f"{_sdo_size(data, command & 0x02)}{_sdo_crc(command)}")
    return _sdo_unknown(command)


def _sdo(can_id: int, data: bytes) -> str:
    """A classic SDO frame read alone: byte 0 is taken as a command specifier (a
    block sub-block segment reads as the command its byte 0 spells; byte 0 that is
    no command specifier says 'unknown command 0xNN or block segment #N')."""
    head = _sdo_head(can_id)
    if len(data) != _SDO_LEN:
        return (f"{head} malformed: {len(data)} bytes, expected {_SDO_LEN}"
                + (f" ({hex_bytes(data)})" if data else ""))
    _, rx = _sdo_node(can_id)
    return f"{head} {_sdo_client(data) if rx else _sdo_server(data)}"


@dataclass
class _Block:
    """A block transfer's sub-block phase: one side sends segments, the other acks."""

    upload: bool                 # True: the server sends the segments
    expected: int = 1            # next sequence number
    sent: int = 0                # highest sequence number of this sub-block
    last: Optional[int] = None   # sequence number of this sub-block's c=1 segment


class Decoder:
    """A frame decoder that follows what needs earlier frames, and decodes PDOs
    by object dictionaries: what `canopenfd monitor` keeps for its lifetime.
    Same text as `meaning()` / `decode()` / `describe()`, except:

    - PDOs: with `ods` (pairs of an `ObjectDictionary` and the node-id it
      describes, None for the OD's own, e.g. a DCF's) a frame on a PDO's CAN-ID
      (its COB-ID from 0x1400../0x1800.., $NODEID resolved) reads
      "TPDO1 node 5 name=value, ..." by the mapping (0x1600../0x1A00..);
      see `decode_services.pdo_text`. `add_od()` adds one later. The SYNC,
      TIME and EMCY CAN-IDs of those dictionaries (0x1005, 0x1012, 0x1014)
      are decoded as such too (before PDOs and the default ids).
    - Node guarding: after a request (remote frame on 0x700 + node-id) the
      node's next one-byte frame there is the reply, also with toggle 0 --
      unless the node was seen sending heartbeats (bit 7 clear, unasked; a
      heartbeat producer answers no request), until its boot-up or a reply
      with toggle 1.
    - Classic SDO: while a server is in a block transfer's sub-block phase,
      the sending side's frames are "block segment #N" ("... last" for c=1).

    Per server node-id: the server's initiate block download response (or the
    client's start block upload) begins the sub-block phase; each ack starts the
    next sub-block at #1 (a partial ack: the rest again); an ack that covers the
    last segment ends it (the end frames have command specifiers again). An abort
    from either side ends it, and so does any frame from the acking side that is
    no ack (its end was missed). A segment out of order says "(expected #N)", a
    partial ack "(partial, N sent)".

    Feed every frame of the bus once, in order, from one thread: each call of
    meaning(), decode() or describe() takes the frame as the next one seen.
    Frames of other kinds decode as `meaning()` does."""

    def __init__(self, ods: Iterable[Tuple[Any, Optional[int]]] = ()) -> None:
        self._blocks: Dict[int, _Block] = {}
        self._guard_requests: Set[int] = set()
        self._heartbeat_nodes: Set[int] = set()
        self._pdos = PdoMap()
        self._services = ServiceIds()
        for od, node_id in ods:
            self.add_od(od, node_id)

    def add_od(self, od: Any, node_id: Optional[int] = None) -> int:
        """Decode the PDOs of `od` (an ObjectDictionary) on node node_id
        (default: od.node_id; ValueError when neither is known); the number of
        PDOs it defines. Its SYNC, TIME and EMCY CAN-IDs are taken too."""
        found = self._pdos.add_od(od, node_id)      # checks the node-id
        self._services.add_od(od, node_id if node_id is not None else od.node_id)
        return len(found)

    def meaning(self, frame: Any) -> str:
        return _meaning(frame, self)

    def decode(self, frame: Any) -> str:
        return _decode(frame, self.meaning(frame))

    def describe(self, frame: Any, width: int = 30) -> str:
        return _describe(frame, self.meaning(frame), width)

    def transfer(self, node_id: int) -> Optional[str]:
        """'block download' / 'block upload' while that server is in a sub-block
        phase, else None."""
        block = self._blocks.get(node_id)
        if block is None:
            return None
        return "block upload" if block.upload else "block download"

    def reset(self) -> None:
        """Forget every transfer, guarding request and heartbeat producer seen."""
        self._blocks.clear()
        self._guard_requests.clear()
        self._heartbeat_nodes.clear()

    # -- what _meaning asks
    def pdo(self, can_id: int, extended: bool) -> Optional[PdoDefinition]:
        return self._pdos.lookup(can_id, extended)

    def service(self, can_id: int, extended: bool) -> Optional[Tuple[str, int]]:
        return self._services.lookup(can_id, extended)

    def guarding_requested(self, node_id: int) -> None:
        self._guard_requests.add(node_id)

    def guarding_reply(self, node_id: int, data: bytes) -> bool:
        """Whether this frame on 0x700 + node_id answers an open guarding
        request (the request is then closed); keeps track of heartbeat producers."""
        asked = node_id in self._guard_requests
        self._guard_requests.discard(node_id)
        if len(data) != 1:
            return asked
        if data[0] == 0 or data[0] & 0x80:           # boot-up, or a reply with toggle 1
            self._heartbeat_nodes.discard(node_id)
            return asked
        if not asked:
            self._heartbeat_nodes.add(node_id)       # bit 7 clear, unasked: a heartbeat
            return False
        return node_id not in self._heartbeat_nodes

    def sdo(self, can_id: int, data: bytes) -> str:
        text = _sdo(can_id, data)
        if len(data) != _SDO_LEN:
            return text                              # malformed: the state stays
        node, rx = _sdo_node(can_id)
        command = data[0]
        block = self._blocks.get(node)
        if block is not None:
            if rx != block.upload:                   # the side sending the segments
                if command == _SDO_ABORT:            # seqno 0: no segment
                    del self._blocks[node]
                    return text
                return f"{_sdo_head(can_id)} {self._segment(block, command)}"
            if command & _SDO_CS_MASK == _SDO_BLOCK_ACK:
                return text + self._ack(node, block, data)
            del self._blocks[node]                   # abort, or the ack/end was missed
        if command & _SDO_CS_MASK == (_SDO_BLOCK_UPLOAD_START if rx else _SDO_BLOCK_DOWNLOAD_OK):
            self._blocks[node] = _Block(upload=rx)
        return text

    @staticmethod
    def _segment(block: _Block, command: int) -> str:
        text = _block_segment(command)
        seqno = command & 0x7F
        if seqno == 0:
            return f"{text} malformed: sequence number 0"
        if seqno != block.expected:
            text += f" (expected #{block.expected})"
        block.expected = seqno + 1
        block.sent = max(block.sent, seqno)
        if command & 0x80:
            block.last = seqno
        return text

    def _ack(self, node: int, block: _Block, data: bytes) -> str:
        ackseq = data[1]
        if block.last is not None and ackseq >= block.last:
            del self._blocks[node]                   # all there: the end frames follow
            return ""
        note = f" (partial, {block.sent} sent)" if ackseq < block.sent else ""
        block.expected, block.sent, block.last = 1, 0, None
        return note
