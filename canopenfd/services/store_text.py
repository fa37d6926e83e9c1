"""The retentive text store: a node's saved parameters in a text file a person
can read and edit, one entry a line (index, sub-index, type, length, data
bytes in hex), with a checksum line so damage is found.

    # comments and blank lines are free
    format 1
    signature 5A0C11E2
    1017 00 UNSIGNED16 2 : E8 03
    2000 01 VISIBLE_STRING 5 : 68 65 6C 6C 6F
    checksum 3B9D0A77

- `format 1` comes first, `signature` (the OD layout's, information only)
  before the entries, `checksum` last. Entries may come in any order.
- Data bytes are the entry's bytes in the object dictionary, least
  significant first as on the bus, two hex digits each. The type is the CiA
  301 data type name: a value is never loaded into an entry that changed type.
- checksum: the CRC-32 the stack's binary image of the same records carries
  (canopenfd.services.store_image), so comments and spacing may change but
  no value can without `canopenfd store seal FILE` (a deliberate edit).

TextStore is a StoreMedium: the node's image is written as this text on each
save (atomically, see atomic_file) and read at boot. A file that is not a
whole, consistent store stops the boot with StoreFileError naming the file and
line: the node never starts on half of its parameters.
"""

from __future__ import annotations

import os
import re
from typing import Dict, List, Optional, Tuple

from ..errors import ConfigurationError
from ..od.datatypes import DataType
from ..od.model import ObjectDictionary
from .atomic_file import replace_file
from .store_image import ImageError, ParameterImage, Record, build_image, parse_image

__all__ = ["StoreFileError", "TextStore", "format_text", "parse_text"]

FORMAT = 1
#: Larger files are refused before they are read (a store holds parameters,
#: not bulk data: this bounds what a hostile file can make the boot allocate).
MAX_FILE_BYTES = 4 * 1024 * 1024
#: The longest value an entry may hold (the stack never stores DOMAINs).
MAX_LENGTH = 0xFFFF

_ENTRY = re.compile(r"([0-9A-Fa-f]{4})[ \t]+([0-9A-Fa-f]{2})[ \t]+([A-Z0-9_]+)[ \t]+([0-9]+)"
                    r"[ \t]*:[ \t]*(.*)")
_HEX8 = re.compile(r"[0-9A-Fa-f]{8}")
_BYTE = re.compile(r"[0-9A-Fa-f]{2}")
_CONTROL = re.compile(r"[\x00-\x08\x0A-\x1F\x7F]")


class StoreFileError(ConfigurationError):
    """A text store that cannot be used: ``params.txt:7: ...``."""

    def __init__(self, problem: str, file: str, line: Optional[int] = None) -> None:
        self.problem = problem
        self.file = file
        self.line = line
        super().__init__(f"{file if line is None else f'{file}:{line}'}: {problem}")


# ---------------------------------------------------------------- writing

def _checksum(image: ParameterImage) -> int:
    sealed = build_image(image)
    return int.from_bytes(sealed[24:28], "little")


def _type_name(code: int) -> str:
    try:
        return DataType(code).name
    except ValueError:
        raise ImageError(f"data type 0x{code:02X} is not a CiA 301 type") from None


def format_text(image: ParameterImage) -> str:
    """The text of a store holding these records."""
    lines = ["# canopenfd retentive parameters: index sub-index type length : data",
             "# (hex bytes, least significant first). After editing by hand run",
             "# `canopenfd store seal FILE`, else the checksum refuses the file.",
             f"format {FORMAT}", f"signature {image.signature:08X}"]
    for r in image.records:
        data = " ".join(f"{b:02X}" for b in r.data)
        lines.append(f"{r.index:04X} {r.sub:02X} {_type_name(r.type)} {len(r.data)} : {data}"
                     .rstrip())
    lines.append(f"checksum {_checksum(image):08X}")
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------- reading

def _lines(text: bytes, file: str) -> List[Tuple[int, str]]:
    """(line number, text) of each meaningful line; refuses what is not
    printable ASCII (a binary or hostile file) at its line."""
    if len(text) > MAX_FILE_BYTES:
        raise StoreFileError(f"{len(text)} bytes, more than the {MAX_FILE_BYTES} a text "
                             "store may have", file)
    out = []
    for number, raw in enumerate(text.split(b"\n"), 1):
        try:
            line = raw.decode("ascii").rstrip("\r")
        except UnicodeDecodeError:
            raise StoreFileError("not ASCII text (a binary image? `canopenfd store export` "
                                 "converts one)", file, number) from None
        if _CONTROL.search(line):
            raise StoreFileError("control character in the line", file, number)
        line = line.strip()
        if line and not line.startswith("#"):
            out.append((number, line))
    return out


def _entry(line: str, file: str, number: int) -> Record:
    match = _ENTRY.fullmatch(line)
    if match is None:
        raise StoreFileError(f"expected 'INDEX SUB TYPE LENGTH : DATA' (e.g. '1017 00 "
                             f"UNSIGNED16 2 : E8 03'), got {line[:60]!r}", file, number)
    index, sub, type_name, length_text, data_text = match.groups()
    where = f"{index.upper()}:{sub.upper()}"
    try:
        data_type = DataType[type_name]
    except KeyError:
        raise StoreFileError(f"{where}: {type_name!r} is not a CiA 301 data type name", file,
                             number) from None
    if data_type is DataType.DOMAIN:
        raise StoreFileError(f"{where}: DOMAIN entries are never stored", file, number)
    length = int(length_text[:8])
    if len(length_text) > 8 or length > MAX_LENGTH:
        raise StoreFileError(f"{where}: length {length_text} larger than {MAX_LENGTH}", file,
                             number)
    if data_type.size is not None and length != data_type.size:
        raise StoreFileError(f"{where}: length {length} contradicts {data_type.name} "
                             f"({data_type.size} bytes)", file, number)
    tokens = data_text.split()
    bad = next((t for t in tokens if not _BYTE.fullmatch(t)), None)
    if bad is not None:
        raise StoreFileError(f"{where}: data byte {bad[:12]!r} is not two hex digits", file,
                             number)
    if len(tokens) != length:
        raise StoreFileError(f"{where}: length {length} but {len(tokens)} data bytes", file,
                             number)
    return Record(int(index, 16), int(sub, 16), int(data_type),
                  bytes(int(t, 16) for t in tokens))


def _header_value(lines: List[Tuple[int, str]], at: int, name: str, file: str) -> str:
    if at >= len(lines):
        last = lines[-1][0] if lines else 0
        raise StoreFileError(f"truncated: no '{name}' line after line {last}", file)
    number, line = lines[at]
    word, _, value = line.partition(" ")
    if word != name:
        raise StoreFileError(f"expected the '{name}' line, got {line[:60]!r}", file, number)
    return value.strip()


def parse_text(text: bytes, file: str, check: bool = True,
               lines_of: Optional[Dict[int, int]] = None) -> ParameterImage:
    """The records of a text store; StoreFileError (file:line) when it is not
    whole and consistent. check=False accepts any checksum (for seal);
    lines_of, when given, gets each record's line number by key."""
    lines = _lines(text, file)
    version = _header_value(lines, 0, "format", file)
    if version != str(FORMAT):
        raise StoreFileError(f"format {version[:20]!r}, expected {FORMAT}", file, lines[0][0])
    signature = _header_value(lines, 1, "signature", file)
    if not _HEX8.fullmatch(signature):
        raise StoreFileError(f"signature {signature[:20]!r} is not 8 hex digits", file,
                             lines[1][0])
    seen: Dict[int, int] = {}
    records: List[Record] = []
    for number, line in lines[2:]:
        if line.startswith("checksum"):
            break
        record = _entry(line, file, number)
        if record.key in seen:
            raise StoreFileError(f"{record.index:04X}:{record.sub:02X} is already on line "
                                 f"{seen[record.key]} (duplicated)", file, number)
        seen[record.key] = number
        records.append(record)
    at = 2 + len(records)
    value = _header_value(lines, at, "checksum", file)
    number = lines[at][0]
    if at + 1 < len(lines):
        raise StoreFileError(f"{lines[at + 1][1][:60]!r} after the checksum line {number}",
                             file, lines[at + 1][0])
    if lines_of is not None:
        lines_of.update(seen)
    image = ParameterImage(int(signature, 16), sorted(records, key=lambda r: r.key))
    if not _HEX8.fullmatch(value):
        raise StoreFileError(f"checksum {value[:20]!r} is not 8 hex digits", file, number)
    if check and int(value, 16) != _checksum(image):
        raise StoreFileError(f"checksum {value.upper()}, the entries give "
                             f"{_checksum(image):08X}: damaged, or edited without "
                             "`canopenfd store seal`", file, number)
    return image


def _read(path: str) -> Optional[bytes]:
    try:
        with open(path, "rb") as f:
            return f.read(MAX_FILE_BYTES + 1)
    except FileNotFoundError:
        return None


class TextStore:
    """A StoreMedium keeping the node's saved parameters in a text file.
    `create_local_node(..., store=TextStore("params.txt"))`."""

    def __init__(self, path: "str | os.PathLike[str]") -> None:
        self.path = os.fspath(path)
        if not self.path:
            raise ConfigurationError("TextStore: the path is empty")
        self._loaded: Optional[ParameterImage] = None
        self._lines: Dict[int, int] = {}

    def __repr__(self) -> str:
        return f"TextStore({self.path!r})"

    def load(self) -> Optional[bytes]:
        """The stack's image of the file's entries; None when there is no
        file yet; StoreFileError when it is damaged."""
        text = _read(self.path)
        self._loaded, self._lines = None, {}
        if text is None:
            return None
        try:
            self._loaded = parse_text(text, self.path, lines_of=self._lines)
            return build_image(self._loaded)
        except ImageError as exc:
            raise StoreFileError(str(exc), self.path) from None

    def check_od(self, od: ObjectDictionary) -> None:
        """After load(), at boot: every entry of the file must be a stored
        entry of the node's dictionary with the same type and a length that
        fits, else StoreFileError at its line (a person's typo in an index
        is never dropped in silence)."""
        for record in self._loaded.records if self._loaded is not None else ():
            line = self._lines.get(record.key)
            where = f"{record.index:04X}:{record.sub:02X}"
            variable = od.get_variable(record.index, record.sub)
            if variable is None or not variable.store:
                raise StoreFileError(f"{where}: no stored entry of that key in the object "
                                     "dictionary", self.path, line)
            if int(variable.data_type) != record.type:
                raise StoreFileError(f"{where}: type {_type_name(record.type)}, the object "
                                     f"dictionary says {variable.data_type.name}", self.path,
                                     line)
            if len(record.data) > variable.storage_size:
                raise StoreFileError(f"{where}: length {len(record.data)}, the entry holds "
                                     f"{variable.storage_size} bytes at most", self.path, line)

    def save(self, image: bytes) -> None:
        replace_file(self.path, format_text(parse_image(image)).encode("ascii"))
