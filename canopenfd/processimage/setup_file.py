"""The CANopen Task setup file of seed 004 §5 ("COPTSKA8"): hexadecimal
records in labelled sections, each closed by a checksum byte, read into
tables the device is built from (`build_od`).

The reader is exact: every contradiction (overlapping image ranges, a
variable past the image, a mapping that names no [RWOD] entry, a count that
disagrees with [NODE], a bad checksum, a section given twice) raises
`SetupFileError` naming file:line, so a half-configured device never starts.
It is tolerant where intent is clear: unknown sections, lower-case hex and
the seed's own "xx" checksum placeholders are accepted and listed in
`SetupFile.warnings` (file:line: what was done).

CANopen FD extensions (this project's; docs/protocol-notes.md "seed 004"):
[NODE] may carry a 7th byte (bit 0: CANopen FD line) and an 8th/9th byte
(heartbeat producer time in ms, little-endian); on an fd line a PDO mapping
record may hold up to 64 entries; [RWOD] length 0 means 8 bytes and 5..7 are
allowed (UNSIGNED40..64), so 64-byte PDOs can be filled with fewer entries.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Tuple, Union

from ..errors import ConfigurationError

#: The first 8 characters of every setup file (seed 004 §5.1).
MAGIC = "COPTSKA8"
#: Files larger than this are refused unread (a setup file is a few KiB).
MAX_FILE_SIZE = 1 << 20
#: The largest process image (seed 004 §3.1).
MAX_IMAGE = 255
#: Offset 255 marks "invalid or unused" (seed 004 §3.1).
UNUSED_OFFSET = 0xFF
KNOWN_SECTIONS = ("ID", "NODE", "RPDO", "TPDO", "COD", "RWOD", "PIMG")
#: The [NODE] byte 7 flag of a CANopen FD line (this project's extension).
NODE_FLAG_FD = 0x01
#: Expedited SDO upload response command specifiers -> data bytes.
_COD_SIZES = {0x4F: 1, 0x4B: 2, 0x47: 3, 0x43: 4}
_RPDO_TYPES = set(range(0, 241)) | {0xFE, 0xFF}
_TPDO_TYPES = set(range(0, 241)) | {0xFC, 0xFD, 0xFE, 0xFF}


class SetupFileError(ConfigurationError):
    """A setup file that cannot configure a device; the message names file:line."""


@dataclass
class NodeParams:
    bps: int                 # 0 = default, 1..8 as InitCANopen (seed 004 §4.1.3)
    node_id: int             # default node-id 1..127
    image_size: int
    rpdo_count: int
    tpdo_count: int
    functionality: int       # manufacturer specific (kept, not interpreted)
    fd: bool = False         # extension: the device runs on a CANopen FD line
    heartbeat_ms: int = 0    # extension: 0x1017


@dataclass
class PdoParams:
    number: int              # 1-based
    cob_id: int              # 0 = predefined connection set; bit 15 = not valid
    transmission_type: int
    inhibit_100us: int
    event_ms: int
    entries: List[int]       # indices into SetupFile.rwod
    line: int


@dataclass
class ConstEntry:
    index: int
    sub: int
    data: bytes
    line: int


@dataclass
class ImageEntry:
    index: int
    sub: int
    length: int
    readable: bool
    writable: bool
    mappable: bool
    rpdo_only: bool          # bit 7 (with bit 6): the direction of the mapping
    offset: int
    line: int


@dataclass
class SetupFile:
    path: str
    ident: bytes = bytes(4)
    node: Optional[NodeParams] = None
    rpdos: List[PdoParams] = field(default_factory=list)
    tpdos: List[PdoParams] = field(default_factory=list)
    cod: List[ConstEntry] = field(default_factory=list)
    rwod: List[ImageEntry] = field(default_factory=list)
    image: bytes = b""
    warnings: List[str] = field(default_factory=list)

    @property
    def mode(self) -> str:
        return "fd" if self.node is not None and self.node.fd else "classic"


@dataclass
class _Section:
    label: str
    line: int                               # of the label
    rows: List[Tuple[int, bytes]] = field(default_factory=list)   # (line, bytes)


class _Reader:
    def __init__(self, path: str) -> None:
        self.path = path
        self.warnings: List[str] = []

    def fail(self, line: int, message: str) -> SetupFileError:
        return SetupFileError(f"{self.path}:{line}: {message}")

    def warn(self, line: int, message: str) -> None:
        self.warnings.append(f"{self.path}:{line}: {message}")

    # ------------------------------------------------------------ lines
    def hex_row(self, number: int, text: str) -> bytes:
        if len(text) % 2:
            raise self.fail(number, f"odd number of hex digits in {text!r}: values are "
                                    "whole bytes")
        if any(c not in "0123456789ABCDEFabcdef" for c in text):
            bad = next(c for c in text if c not in "0123456789ABCDEFabcdef")
            raise self.fail(number, f"{bad!r} in {text!r}: data is hexadecimal without 0x or h")
        if text != text.upper():
            self.warn(number, f"lower-case hex {text!r} read as {text.upper()!r} (the seed "
                              "writes A..F in capitals)")
        return bytes.fromhex(text)

    def sections(self, text: str) -> List[_Section]:
        lines = text.splitlines()
        if not lines or not lines[0].startswith(MAGIC):
            first = lines[0][:20] if lines else ""
            raise self.fail(1, f"expected {MAGIC!r} at the start of the first line, got "
                               f"{first!r}")
        found: List[_Section] = []
        current: Optional[_Section] = None
        for number, raw in enumerate(lines[1:], start=2):
            stripped = "".join(raw.split())
            if not stripped or stripped[0] in ";/":
                continue
            if stripped.startswith("["):
                if not stripped.endswith("]") or len(stripped) < 3:
                    raise self.fail(number, f"section label {raw.strip()!r} is not [NAME]")
                label = stripped[1:-1]
                if label != label.upper():
                    self.warn(number, f"label [{label}] read as [{label.upper()}]")
                    label = label.upper()
                for earlier in found:
                    if earlier.label == label:
                        raise self.fail(number, f"[{label}] given twice (first at line "
                                                f"{earlier.line})")
                current = _Section(label, number)
                found.append(current)
                continue
            if current is None:
                raise self.fail(number, f"data {stripped[:20]!r} before any [SECTION] label")
            if stripped.upper() == "XX":
                current.rows.append((number, b"?"))      # the seed's checksum placeholder
                continue
            current.rows.append((number, self.hex_row(number, stripped)))
        return found

    def data_rows(self, section: _Section) -> List[Tuple[int, bytes]]:
        """The rows before the checksum, the checksum checked (seed 004 §5.2:
        the last line is the sum of every byte of the entry, modulo 256)."""
        if not section.rows:
            raise self.fail(section.line, f"[{section.label}] is empty: data and a checksum "
                                          "line expected")
        line, checksum = section.rows[-1]
        rows = section.rows[:-1]
        if checksum == b"?":
            self.warn(line, f"[{section.label}] checksum 'xx' not checked")
        elif len(checksum) != 1:
            raise self.fail(line, f"[{section.label}] must end with a one-byte checksum "
                                  f"line, got {len(checksum)} bytes")
        else:
            total = sum(sum(row) for _, row in rows) & 0xFF
            if total != checksum[0]:
                raise self.fail(line, f"[{section.label}] checksum: expected {total:02X} (sum "
                                      f"of its bytes), got {checksum[0]:02X}")
        if not rows:
            raise self.fail(section.line, f"[{section.label}] has a checksum but no data")
        for row_line, row in rows:
            if row == b"?":
                raise self.fail(row_line, f"[{section.label}] 'xx' is allowed only as the "
                                          "checksum line")
        return rows


def _flat(rows: List[Tuple[int, bytes]]) -> Tuple[int, bytes]:
    return rows[0][0], b"".join(row for _, row in rows)


def _records(reader: _Reader, label: str, rows: List[Tuple[int, bytes]], size: int
             ) -> List[Tuple[int, bytes]]:
    """Fixed-size records ended by one of all FFh (seed 004 §5.2.5, §5.2.6),
    each with the line it starts on."""
    records: List[Tuple[int, bytes]] = []
    buffer = b""
    for line, row in rows:
        start = line if not buffer else None
        buffer += row
        while len(buffer) >= size:
            record, buffer = buffer[:size], buffer[size:]
            records.append((start if start is not None else line, record))
            start = line
    if buffer:
        raise reader.fail(rows[-1][0], f"[{label}] ends in a record cut short: {len(buffer)} "
                                       f"of {size} bytes")
    if not records or records[-1][1] != b"\xff" * size:
        raise reader.fail(rows[-1][0], f"[{label}] must end with a record of {size} FFh bytes")
    for line, record in records[:-1]:
        if record == b"\xff" * size:
            raise reader.fail(line, f"[{label}] has records after its FFh end record")
    return records[:-1]


def _node(reader: _Reader, rows: List[Tuple[int, bytes]]) -> NodeParams:
    line, data = _flat(rows)
    if len(data) not in (6, 7, 9):
        raise reader.fail(line, f"[NODE] has {len(data)} bytes: expected 6 (bps, node-id, "
                                "image size, RPDOs, TPDOs, functionality), 7 (+ flags) or 9 "
                                "(+ heartbeat ms)")
    bps, node_id, size, rpdos, tpdos, functionality = data[:6]
    if bps > 8:
        raise reader.fail(line, f"[NODE] bit rate code {bps:02X}: expected 00..08")
    if not 1 <= node_id <= 127:
        raise reader.fail(line, f"[NODE] node-id {node_id:02X}: expected 01..7F")
    if size == 0:
        raise reader.fail(line, "[NODE] process image size 00: expected 01..FF")
    flags = data[6] if len(data) > 6 else 0
    if flags & ~NODE_FLAG_FD:
        raise reader.fail(line, f"[NODE] flags {flags:02X}: only bit 0 (CANopen FD) is defined")
    heartbeat = int.from_bytes(data[7:9], "little") if len(data) == 9 else 0
    if size != MAX_IMAGE and (size % 32 or size > 224):
        reader.warn(line, f"[NODE] image size {size} is not one GetStatus can report ((n+1)*32"
                          " or 255): the status byte reports the largest such size below it")
    return NodeParams(bps, node_id, size, rpdos, tpdos, functionality,
                      bool(flags & NODE_FLAG_FD), heartbeat)


def _pdos(reader: _Reader, kind: str, rows: List[Tuple[int, bytes]], count: int,
          fd: bool) -> List[PdoParams]:
    comm_size = 3 if kind == "RPDO" else 7
    if len(rows) != 2 * count:
        raise reader.fail(rows[0][0], f"[{kind}] has {len(rows)} data lines: [NODE] says "
                                      f"{count} {kind}s, so {count} communication lines and "
                                      f"{count} mapping lines")
    most = 64 if fd else 8
    pdos = []
    for number in range(1, count + 1):
        comm_line, comm = rows[number - 1]
        map_line, mapping = rows[count + number - 1]
        if len(comm) != comm_size:
            raise reader.fail(comm_line, f"[{kind}] {kind} {number} communication: expected "
                                         f"{comm_size} bytes, got {len(comm)}")
        cob_id = int.from_bytes(comm[:2], "little")
        if cob_id & 0x7FFF > 0x7FF or cob_id & 0x7800:
            raise reader.fail(comm_line, f"[{kind}] {kind} {number} COB-ID {cob_id:04X}: "
                                         "expected an 11-bit CAN-ID (bit 15: not valid)")
        if cob_id == 0 and number > 4:
            raise reader.fail(comm_line, f"[{kind}] {kind} {number} COB-ID 0000: only PDOs 1..4"
                                         " have a predefined CAN-ID")
        ttype = comm[-1]
        if ttype not in (_RPDO_TYPES if kind == "RPDO" else _TPDO_TYPES):
            raise reader.fail(comm_line, f"[{kind}] {kind} {number} transmission type "
                                         f"{ttype:02X} is not one CiA 301 allows")
        inhibit = int.from_bytes(comm[2:4], "little") if kind == "TPDO" else 0
        event = int.from_bytes(comm[4:6], "little") if kind == "TPDO" else 0
        if not mapping:
            raise reader.fail(map_line, f"[{kind}] {kind} {number} mapping line is empty")
        entries = mapping[0]
        room = max(8, entries) if fd else 8
        if entries > most:
            raise reader.fail(map_line, f"[{kind}] {kind} {number} maps {entries} entries: at "
                                        f"most {most} on a {'fd' if fd else 'classic'} line")
        if len(mapping) != 1 + room:
            raise reader.fail(map_line, f"[{kind}] {kind} {number} mapping: expected {1 + room} "
                                        f"bytes (count and {room} entries), got {len(mapping)}")
        used = list(mapping[1:1 + entries])
        if UNUSED_OFFSET in used:
            raise reader.fail(map_line, f"[{kind}] {kind} {number} says {entries} entries but "
                                        "an FFh (unused) is among them")
        if any(b != UNUSED_OFFSET for b in mapping[1 + entries:]):
            raise reader.fail(map_line, f"[{kind}] {kind} {number}: bytes after the {entries} "
                                        "mapped entries must be FFh")
        pdos.append(PdoParams(number, cob_id, ttype, inhibit, event, used, map_line))
    return pdos


def _cod(reader: _Reader, rows: List[Tuple[int, bytes]]) -> List[ConstEntry]:
    entries = []
    for line, record in _records(reader, "COD", rows, 8):
        cs, index, sub = record[0], int.from_bytes(record[1:3], "little"), record[3]
        if cs not in _COD_SIZES:
            raise reader.fail(line, f"[COD] command specifier {cs:02X} of {index:04X}:{sub:02X}:"
                                    " expected an expedited upload response 43/47/4B/4F")
        entries.append(ConstEntry(index, sub, record[4:4 + _COD_SIZES[cs]], line))
    return entries


def _rwod(reader: _Reader, rows: List[Tuple[int, bytes]]) -> List[ImageEntry]:
    entries = []
    for line, record in _records(reader, "RWOD", rows, 5):
        index, sub, info, offset = int.from_bytes(record[:2], "little"), record[2], record[3], \
            record[4]
        where = f"[RWOD] {index:04X}:{sub:02X}"
        length = info & 0x07 or 8
        if info & 0x08:
            raise reader.fail(line, f"{where}: access byte {info:02X} sets reserved bit 3")
        readable, writable = bool(info & 0x10), bool(info & 0x20)
        mappable, rpdo_only = bool(info & 0x40), bool(info & 0x80)
        if not (readable or writable):
            raise reader.fail(line, f"{where}: access byte {info:02X} allows neither read "
                                    "(bit 4) nor write (bit 5)")
        if rpdo_only and not mappable:
            raise reader.fail(line, f"{where}: access byte {info:02X} sets the mapping "
                                    "direction (bit 7) without mapping (bit 6)")
        if mappable and rpdo_only and not writable:
            raise reader.fail(line, f"{where}: RPDO-mapped but not writable: an RPDO writes it")
        if mappable and not rpdo_only and not readable:
            raise reader.fail(line, f"{where}: TPDO-mapped but not readable: a TPDO reads it")
        if offset == UNUSED_OFFSET:
            raise reader.fail(line, f"{where}: offset FFh means unused; an [RWOD] entry needs "
                                    "a place in the process image")
        entries.append(ImageEntry(index, sub, length, readable, writable, mappable, rpdo_only,
                                  offset, line))
    return entries


def _check_tables(reader: _Reader, setup: SetupFile) -> None:
    node = setup.node
    assert node is not None
    owner: Dict[int, ImageEntry] = {}
    for entry in setup.rwod:
        end = entry.offset + entry.length
        if end > node.image_size:
            raise reader.fail(entry.line, f"[RWOD] {entry.index:04X}:{entry.sub:02X} bytes "
                                          f"{entry.offset}..{end - 1} lie past the process "
                                          f"image of {node.image_size} bytes")
        for byte in range(entry.offset, end):
            other = owner.get(byte)
            if other is not None:
                raise reader.fail(entry.line, f"[RWOD] {entry.index:04X}:{entry.sub:02X} "
                                              f"overlaps {other.index:04X}:{other.sub:02X} "
                                              f"(line {other.line}) at image byte {byte}")
            owner[byte] = entry
    seen: Dict[Tuple[int, int], int] = {}
    items: List[Union[ConstEntry, ImageEntry]] = [*setup.cod, *setup.rwod]
    for item in items:
        key = (item.index, item.sub)
        if key in seen:
            raise reader.fail(item.line, f"{item.index:04X}:{item.sub:02X} defined twice "
                                         f"(first at line {seen[key]})")
        seen[key] = item.line
    limit = 64 if node.fd else 8
    for kind, pdos in (("RPDO", setup.rpdos), ("TPDO", setup.tpdos)):
        for pdo in pdos:
            total = 0
            for ref in pdo.entries:
                if ref >= len(setup.rwod):
                    raise reader.fail(pdo.line, f"[{kind}] {kind} {pdo.number} maps [RWOD] "
                                                f"entry {ref}: there are {len(setup.rwod)}")
                entry = setup.rwod[ref]
                if not entry.mappable or entry.rpdo_only != (kind == "RPDO"):
                    raise reader.fail(pdo.line, f"[{kind}] {kind} {pdo.number} maps "
                                                f"{entry.index:04X}:{entry.sub:02X} (line "
                                                f"{entry.line}), which is not {kind}-mappable")
                total += entry.length
            if total > limit:
                raise reader.fail(pdo.line, f"[{kind}] {kind} {pdo.number} maps {total} bytes: "
                                            f"a PDO holds at most {limit}")


def parse_setup_text(text: str, path: str = "<setup>") -> SetupFile:
    """A SetupFile from the text of a setup file (path only names it in messages)."""
    reader = _Reader(path)
    sections = {s.label: s for s in reader.sections(text)}
    for label, section in sections.items():
        if label not in KNOWN_SECTIONS:
            reader.warn(section.line, f"unknown section [{label}] ignored")
    if "NODE" not in sections:
        raise reader.fail(len(text.splitlines()) or 1, "no [NODE] section: node-id, image "
                                                       "size and PDO counts are needed")
    setup = SetupFile(path)
    node = setup.node = _node(reader, reader.data_rows(sections["NODE"]))
    if "ID" in sections:
        line, ident = _flat(reader.data_rows(sections["ID"]))
        if len(ident) != 4:
            raise reader.fail(line, f"[ID] has {len(ident)} bytes: expected 4")
        if int.from_bytes(ident[:2], "little") >= 0xF000:
            reader.warn(line, "[ID] manufacturer identification F000h..FFFFh is reserved")
        setup.ident = ident
    else:
        reader.warn(sections["NODE"].line, "no [ID] section: GetID answers 00 00 00 00")
    for kind, count in (("RPDO", node.rpdo_count), ("TPDO", node.tpdo_count)):
        if kind in sections:
            pdos = _pdos(reader, kind, reader.data_rows(sections[kind]), count, node.fd)
            setattr(setup, kind.lower() + "s", pdos)
        elif count:
            raise reader.fail(sections["NODE"].line, f"[NODE] says {count} {kind}s but there is "
                                                     f"no [{kind}] section")
    if "COD" in sections:
        setup.cod = _cod(reader, reader.data_rows(sections["COD"]))
    if "RWOD" in sections:
        setup.rwod = _rwod(reader, reader.data_rows(sections["RWOD"]))
    if "PIMG" in sections:
        line, image = _flat(reader.data_rows(sections["PIMG"]))
        if len(image) != node.image_size:
            raise reader.fail(line, f"[PIMG] has {len(image)} bytes: [NODE] says the image has "
                                    f"{node.image_size}")
        setup.image = image
    else:
        setup.image = bytes(node.image_size)
    _check_tables(reader, setup)
    setup.warnings = reader.warnings
    return setup


def load_setup_file(path: str) -> SetupFile:
    """Read and check a setup file; SetupFileError (file:line) when it cannot
    configure a device."""
    try:
        size = os.path.getsize(path)
        if size > MAX_FILE_SIZE:
            raise SetupFileError(f"{path}: {size} bytes; a setup file has at most "
                                 f"{MAX_FILE_SIZE}")
        with open(path, "rb") as handle:
            raw = handle.read(MAX_FILE_SIZE + 1)
    except OSError as exc:
        raise SetupFileError(f"{path}: cannot read: {exc.strerror or exc}") from None
    try:
        text = raw.decode("ascii")
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise SetupFileError(f"{path}:{line}: byte {raw[exc.start]:02X} is not ASCII (the "
                             "setup file is an ASCII text file)") from None
    return parse_setup_text(text, path)
