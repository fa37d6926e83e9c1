"""A minimal, defended XML tree for XDD/XDC files.

Built directly on expat (what xml.etree uses underneath) because the
readers need the line number of every element for their messages, and
ElementTree's C implementation does not keep one. Tags and attribute names
are reduced to their local names (namespace prefixes dropped), so files match
whatever namespace (CiA 311 or CiA 1311) they declare.

Defences, standard library only: DOCTYPE and ENTITY declarations are refused
before parsing (by a scan of the raw text) and again by expat handlers, so
"billion laughs" and external entities never expand; nesting depth and the
number of elements are capped; the file size is capped by the caller.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Dict, Iterator, List, NoReturn, Optional, Union
from xml.parsers import expat

from .errors import OdFileError

MAX_DEPTH = 64
MAX_ELEMENTS = 200_000
MAX_TEXT = 64 * 1024  # characters kept per element
_DECLARATION = re.compile(rb"<!\s*(DOCTYPE|ENTITY)", re.IGNORECASE)


@dataclass
class Node:
    """An element: local tag name, attributes by local name, line, children."""

    tag: str
    attrib: Dict[str, str]
    line: int
    children: List["Node"] = field(default_factory=list)
    text: str = ""

    def get(self, name: str, default: Optional[str] = None) -> Optional[str]:
        """An attribute by name, case-insensitively (files differ in case)."""
        if name in self.attrib:
            return self.attrib[name]
        lowered = name.lower()
        for key, value in self.attrib.items():
            if key.lower() == lowered:
                return value
        return default

    def iter(self, *tags: str) -> Iterator["Node"]:
        """This element and all below it whose tag is in `tags` (all if none)."""
        stack = [self]
        while stack:
            node = stack.pop()
            if not tags or node.tag in tags:
                yield node
            stack.extend(reversed(node.children))

    def find(self, *tags: str) -> Optional["Node"]:
        return next(self.iter(*tags), None)

    def child_text(self, tag: str) -> Optional[str]:
        """Text of the first descendant `tag` (or of its first <label>)."""
        node = self.find(tag)
        if node is None:
            return None
        text = node.text.strip()
        if not text:
            label = node.find("label")
            text = label.text.strip() if label is not None else ""
        return text or None


class _Refused(Exception):
    pass


def _local(name: str) -> str:
    return name.rsplit(":", 1)[-1]


def parse_xml(data: Union[bytes, str], name: str) -> Node:
    """The root element of an XML document; OdFileError (file, line) on
    malformed, hostile or oversized input."""
    # surrogatepass: a text stream decoded with surrogateescape; expat refuses those bytes
    raw = data.encode("utf-8", "surrogatepass") if isinstance(data, str) else data
    if not raw.strip():
        raise OdFileError("the file is empty", name)
    scan = raw
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        scan = raw.decode("utf-16", errors="replace").encode("utf-8")
    found = _DECLARATION.search(scan)
    if found:
        line = scan.count(b"\n", 0, found.start()) + 1
        raise OdFileError(f"<!{found.group(1).decode().upper()} declarations are not allowed "
                          f"(they enable entity-expansion and external-entity attacks; "
                          f"XDD/XDC files need none)", name, line)
    parser = expat.ParserCreate("UTF-8" if isinstance(data, str) else None)
    root: List[Node] = []
    stack: List[Node] = []
    count = [0]

    def refuse(*_args: object) -> NoReturn:
        raise _Refused("DOCTYPE/ENTITY declarations are not allowed")

    def start(tag: str, attrs: Dict[str, str]) -> None:
        count[0] += 1
        if count[0] > MAX_ELEMENTS:
            raise _Refused(f"more than {MAX_ELEMENTS} XML elements")
        if len(stack) >= MAX_DEPTH:
            raise _Refused(f"XML nested deeper than {MAX_DEPTH} levels")
        node = Node(_local(tag), {_local(k): v for k, v in attrs.items()},
                    parser.CurrentLineNumber)
        if stack:
            stack[-1].children.append(node)
        else:
            root.append(node)
        stack.append(node)

    def end(_tag: str) -> None:
        stack.pop()

    def text(chunk: str) -> None:
        if stack and len(stack[-1].text) < MAX_TEXT:
            stack[-1].text += chunk

    parser.StartDoctypeDeclHandler = refuse
    parser.EntityDeclHandler = refuse
    parser.ExternalEntityRefHandler = refuse
    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = text
    try:
        parser.SetParamEntityParsing(expat.XML_PARAM_ENTITY_PARSING_NEVER)
    except AttributeError:  # pragma: no cover - very old expat
        pass
    try:
        parser.Parse(raw, True)
    except _Refused as exc:
        raise OdFileError(str(exc), name, parser.CurrentLineNumber) from None
    except expat.ExpatError as exc:
        raise OdFileError(f"not well-formed XML: {expat.ErrorString(exc.code)}",
                          name, exc.lineno) from None
    except (ValueError, LookupError, UnicodeError, RecursionError) as exc:
        # LookupError: an encoding name expat does not know
        raise OdFileError(f"cannot parse XML: {exc}", name) from None
    if not root:
        raise OdFileError("no XML element found", name)
    return root[0]
