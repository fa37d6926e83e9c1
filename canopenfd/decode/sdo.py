"""Classic SDO frames (CiA 301, classic frames on 0x601..0x67F and
0x581..0x5FF): expedited, segmented and block transfers, 'SDO 5 rx initiate
upload 0x1018:01'.

The CAN-ID names the server either way: 0x600 + node-id carries the client's
requests ("rx", what the server receives), 0x580 + node-id the server's
responses ("tx"). Byte 0 is the command specifier (bits 7-5: ccs from the
client, scs from the server), bytes 1-2 the index (LE), byte 3 the sub-index,
bytes 4-7 data or a size in initiate and abort frames. Reserved bits of byte 0
are ignored, as stacks do. Block sub-block segments have no command specifier:
byte 0 is c (last segment) << 7 | seqno (1..127), so alone they read as
whatever command byte 0 happens to spell; `SdoBlockTracker` (what the stateful
`Decoder` keeps) follows each server's block transfers and names them
"block segment #N"."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, Optional, Tuple

from ..errors import ABORT_TEXT
from .raw import hex_bytes

_SDO_RX = 0x600     # client -> server, + server node-id
_SDO_TX = 0x580     # server -> client, + server node-id
_SDO_LEN = 8
_SDO_ABORT = 0x80
_SDO_BLKSIZE_MAX = 127
_SDO_CS_MASK = 0xE3             # ccs/scs and the sub-command bits of block frames
_SDO_NETWORK = 0xE0             # SDO networking: the network indication (ccs/scs 7)
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


def _sdo_network(data: bytes, confirmed: bool) -> str:
    """SDO networking (gateway; layout in docs/protocol-notes.md): byte 0 0xE0,
    the network (LE16) and the node a client asks the gateway to reach. Read
    alone it may also be a block segment (#96, last)."""
    what = "network indication confirmed" if confirmed else "network indication"
    network, node = data[1] | data[2] << 8, data[3]
    target = "back to the gateway itself" if network == 0 else f"network {network} node {node}"
    return f"{what}: {target} or {_block_segment(data[0])}"


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
    if command == _SDO_NETWORK:
        return _sdo_network(data, False)
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
    if command == _SDO_NETWORK:
        return _sdo_network(data, True)
    return _sdo_unknown(command)


def sdo_text(can_id: int, data: bytes) -> str:
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


class SdoBlockTracker:
    """The sub-block phases of the block transfers seen, per server node-id.

    The server's initiate block download response (or the client's start
    block upload) begins the sub-block phase; each ack starts the next
    sub-block at #1 (a partial ack: the rest again); an ack that covers the
    last segment ends it (the end frames have command specifiers again). An
    abort from either side ends it, and so does any frame from the acking side
    that is no ack (its end was missed). A segment out of order says
    "(expected #N)", a partial ack "(partial, N sent)"."""

    def __init__(self) -> None:
        self._blocks: Dict[int, _Block] = {}

    def text(self, can_id: int, data: bytes) -> str:
        """The frame's text as `sdo_text` has it, or "block segment #N" while
        its server is in a sub-block phase; takes the frame as the next one seen."""
        text = sdo_text(can_id, data)
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

    def transfer(self, node_id: int) -> Optional[str]:
        """'block download' / 'block upload' while that server is in a sub-block
        phase, else None."""
        block = self._blocks.get(node_id)
        if block is None:
            return None
        return "block upload" if block.upload else "block download"

    def reset(self) -> None:
        self._blocks.clear()

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
