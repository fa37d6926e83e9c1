"""A small INI reader for EDS/DCF files that keeps line numbers.

configparser loses line numbers, refuses duplicate keys and chokes on some
vendor files; this reader is tolerant where the files are messy (comments
with ';' or '#', blank lines, case of keys and section names, duplicate keys:
the last wins, with a warning) and strict where a guess would be wrong (a
broken section header is an error). A line that is neither a section, a
comment nor key=value (or a key before the first section) is skipped and
recorded as a deviation, unless `strict`; a text with no section at all is
not an EDS/DCF and is refused.

Text decoding: a UTF-8 or UTF-16 BOM is honoured; otherwise UTF-8 is tried,
then Windows-1252 (the usual vendor encoding), then Latin-1, which decodes
every byte, so no file makes the reader crash on its bytes.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Tuple, Union

from .errors import OdFileError

_LINE_SPLIT = re.compile(r"\r\n|\r|\n")
_HEADER = re.compile(r"^\[([^\[\]]*)\]\s*(?:[;#].*)?$")


@dataclass
class Key:
    name: str   # as written
    value: str  # stripped
    line: int


@dataclass
class Section:
    name: str   # as written (first occurrence)
    line: int
    keys: Dict[str, Key] = field(default_factory=dict)  # by lower-case name

    def get(self, key: str) -> Optional[Key]:
        found = self.keys.get(key)  # callers mostly pass lower-case names already
        return found if found is not None else self.keys.get(key.lower())

    def value(self, key: str, default: Optional[str] = None) -> Optional[str]:
        found = self.keys.get(key.lower())
        return found.value if found is not None else default


@dataclass
class IniFile:
    name: str
    sections: Dict[str, Section] = field(default_factory=dict)  # by lower-case name
    warnings: List[Tuple[int, str, str]] = field(default_factory=list)  # line, section, text
    deviations: List[Tuple[int, str, str]] = field(default_factory=list)  # skipped lines
    encoding: str = "utf-8"

    def section(self, name: str) -> Optional[Section]:
        return self.sections.get(name.lower())


def decode_text(data: Union[bytes, str]) -> Tuple[str, str]:
    """(text, encoding used)."""
    if isinstance(data, str):
        return data.lstrip("\ufeff"), "str"
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    elif data.startswith((b"\xff\xfe", b"\xfe\xff")):
        return data.decode("utf-16", errors="replace").lstrip("\ufeff"), "utf-16"
    for encoding in ("utf-8", "cp1252"):
        try:
            return data.decode(encoding), encoding
        except UnicodeDecodeError:
            pass
    return data.decode("latin-1"), "latin-1"


def parse_ini(data: Union[bytes, str], name: str, strict: bool = False) -> IniFile:
    """Sections and keys of an INI text; OdFileError names file and line."""
    text, encoding = decode_text(data)
    result = IniFile(name, encoding=encoding)
    if not text.strip():
        raise OdFileError("the file is empty", name)
    nul = text.find("\x00")
    if nul >= 0:
        nul_line = text.count("\n", 0, nul) + 1
        raise OdFileError("binary data (a NUL byte), not an EDS/DCF text file", name, nul_line)
    current: Optional[Section] = None
    for number, raw in enumerate(_LINE_SPLIT.split(text), start=1):
        line = raw.strip()
        if not line or line[0] in ";#" or line == "\x1a":  # \x1a: DOS end-of-file mark
            continue
        if line[0] == "[":
            match = _HEADER.match(line)
            if not match:
                raise OdFileError(f"bad section header {_shorten(line)!r} "
                                  f"(expected [Name])", name, number)
            title = match.group(1).strip()
            if not title:
                raise OdFileError("empty section name []", name, number)
            current = result.sections.get(title.lower())
            if current is None:
                current = Section(title, number)
                result.sections[title.lower()] = current
            else:
                result.warnings.append((number, title, (
                    f"section [{title}] appears again (first at line {current.line}); "
                    f"its keys are merged, later values win")))
            continue
        key, sep, value = line.partition("=")
        key = key.strip()
        if sep and key and current is not None:
            old = current.keys.get(key.lower())
            if old is not None:
                result.warnings.append((number, current.name, (
                    f"duplicate key {key} (also at line {old.line}); the last one is used")))
            current.keys[key.lower()] = Key(key, value.strip(), number)
            continue
        if not sep or not key:
            problem = (f"expected key=value, a [section] or a ; comment, "
                       f"got {_shorten(line)!r}")
        else:
            problem = f"key {_shorten(key)!r} before the first [section]"
        if strict:
            raise OdFileError(problem, name, number)
        result.deviations.append((number, current.name if current else "", problem))
    if not result.sections:  # not an EDS/DCF at all: no guessing
        if result.deviations:
            number, _, problem = result.deviations[0]
            raise OdFileError(problem, name, number)
        raise OdFileError("no [section]: not an EDS/DCF file", name)
    return result


def _shorten(text: str, width: int = 40) -> str:
    printable = "".join(c if c.isprintable() else "?" for c in text)
    return printable if len(printable) <= width else printable[:width - 3] + "..."
