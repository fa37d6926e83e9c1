"""The C enums as Python sees them match the C headers.

canopenfd._binding.constants builds its enums from the binding (what cffi
took from the headers' cffi blocks); a few Python tables are still written by
hand (enums outside the cdef, the OD model's type codes, the abort texts).
These tests parse every enum of the public headers (build_ext.CDEF_HEADERS,
read from build_ext.py so a header move needs no change here) and compare:
each Python member has the C value, no C member is missing in Python, and
every member the package's code names exists in C.
"""

from __future__ import annotations

import ast
import enum
import importlib.util
import pathlib
import re
from typing import Dict, List, Optional, Tuple

import pytest

import canopenfd
from canopenfd._binding import constants
from canopenfd.errors import ABORT_TEXT, USDO_ABORT_TEXT
from canopenfd.od import DataType, ObjectType
from canopenfd.services import GuardEvent

ROOT = pathlib.Path(__file__).resolve().parents[1]
PACKAGE = pathlib.Path(canopenfd.__file__).resolve().parent


def _build_ext():
    spec = importlib.util.spec_from_file_location("build_ext_under_test", ROOT / "build_ext.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


BUILD_EXT = _build_ext()

_COMMENT = re.compile(r"/\*.*?\*/|//[^\n]*", re.S)
_ENUM = re.compile(r"\benum\s*(\w+)?\s*\{(.*?)\}\s*(\w+)?\s*;", re.S)
_SUFFIX = re.compile(r"(?<=[0-9a-fA-F])[uUlL]+\b")


class CEnum:
    def __init__(self, tag: Optional[str], typedef: Optional[str], members: Dict[str, int],
                 header: str) -> None:
        self.tag = tag
        self.typedef = typedef
        self.members = members
        self.header = header

    def named(self, c_type: str) -> bool:
        return c_type in (self.typedef, f"enum {self.tag}")


def parse_enums(text: str, header: str, known: Optional[Dict[str, int]] = None) -> List[CEnum]:
    """Every enum of a C text: members with their values (implicit ones counted on);
    `known` holds members of other headers an expression may name (and grows)."""
    known = {} if known is None else known
    found = []
    for match in _ENUM.finditer(_COMMENT.sub(" ", text)):
        tag, body, typedef = match.groups()
        members: Dict[str, int] = {}
        value = 0
        for item in body.split(","):
            item = item.strip()
            if not item:
                continue
            name, _, expression = (part.strip() for part in item.partition("="))
            if expression:
                # integer literals, earlier members, + - | << of them
                value = eval(_SUFFIX.sub("", expression), {"__builtins__": {}},
                             {**known, **members})
            members[name] = value
            known[name] = value
            value += 1
        found.append(CEnum(tag, typedef, members, header))
    return found


def _header_enums() -> List[CEnum]:
    """The enums of the cdef headers and of the headers they include (for the
    members an expression names, e.g. CO_SDO_BLKSIZE_MAX of co_sdo.h)."""
    root = pathlib.Path(BUILD_EXT.ROOT)
    known: Dict[str, int] = {}
    for included in ("csrc/include/canopenfd/co_sdo.h",):
        parse_enums((root / included).read_text(encoding="utf-8"), included, known)
    return [enum_ for header in BUILD_EXT.CDEF_HEADERS
            for enum_ in parse_enums((root / header).read_text(encoding="utf-8"), header, known)]


HEADER_ENUMS = _header_enums()
CDEF_ENUMS = parse_enums(BUILD_EXT.cdef_text(), "cdef")


def c_enum(c_type: str) -> CEnum:
    matches = [e for e in HEADER_ENUMS if e.named(c_type)]
    assert len(matches) == 1, f"{c_type}: {len(matches)} definitions in {BUILD_EXT.CDEF_HEADERS}"
    return matches[0]


def prefixed(enums: List[CEnum], prefix: str, exclude: Tuple[str, ...] = ()) -> Dict[str, int]:
    """{name without prefix: value} of every member starting with prefix."""
    skipped = tuple(prefix + rest for rest in exclude)
    return {name[len(prefix):]: value for e in enums for name, value in e.members.items()
            if name.startswith(prefix) and not (skipped and name.startswith(skipped))}


def members(python_enum: type) -> Dict[str, int]:
    return {name: int(member) for name, member in python_enum.__members__.items()}


def test_the_header_parser_reads_values_and_implicit_members():
    parsed = parse_enums("typedef enum x { A = 0x10u, B, C = -3, D = A | 1 } x_t; "
                         "enum { E = 1 << 2 /* c */ };", "t")
    assert [e.members for e in parsed] == [{"A": 16, "B": 17, "C": -3, "D": 17}, {"E": 4}]
    assert parsed[0].named("x_t") and parsed[0].named("enum x") and parsed[1].tag is None


@pytest.mark.parametrize("python_enum", list(constants.C_ENUMS), ids=lambda e: e.__name__)
def test_generated_enums_equal_their_c_enum(python_enum):
    """Each enum built from the binding has exactly the C members and values
    (a C member outside the cffi block would be missing here)."""
    c_type, prefix, exclude = constants.C_ENUMS[python_enum]
    if c_type is not None:
        expected = prefixed([c_enum(c_type)], prefix)
    else:
        expected = prefixed(HEADER_ENUMS, prefix, exclude)
    assert expected, f"{python_enum.__name__}: no C member starts with {prefix}"
    assert members(python_enum) == expected


@pytest.mark.parametrize("name", list(constants._NOT_IN_CDEF))
def test_enums_outside_the_cdef_equal_their_header(name):
    """Written by hand until the enum moves into its header's cffi block."""
    source, values = constants._NOT_IN_CDEF[name]
    c_type, prefix = (part.strip() for part in source.split("/"))
    assert prefixed([c_enum(c_type)], prefix) == values
    assert members(getattr(constants, name)) == values
    assert not prefixed(CDEF_ENUMS, prefix), f"{c_type} is in the cdef now: build {name} from lib"


def test_guard_events_are_the_c_guard_events():
    assert set(GuardEvent.__members__) == set(constants.GuardEventCode.__members__)
    for member in constants.GuardEventCode:
        assert GuardEvent.from_code(int(member)) is GuardEvent[member.name]
    assert GuardEvent.from_code(0) is None and GuardEvent.from_code(7) is None


def test_store_status_texts_cover_every_c_status():
    from canopenfd.services.store import STORE_STATUS
    assert set(STORE_STATUS) == set(c_enum("co_store_status_t").members.values())
    assert STORE_STATUS[int(constants.StoreStatus.IO)] == "io-error"


def test_od_model_type_codes_equal_the_c_ones():
    """The OD model is pure Python; its codes are CiA 301's, as the C core has them."""
    assert members(DataType) == prefixed([c_enum("co_od_type_t")], "CO_TYPE_")
    objects = prefixed([c_enum("co_od_object_code_t")], "CO_OBJECT_")
    assert {name: members(ObjectType)[name] for name in objects} == objects


def test_abort_texts_cover_exactly_the_c_abort_codes():
    cia = c_enum("co_abort_t").members
    assert set(ABORT_TEXT) == set(cia.values()) - {cia["CO_ABORT_NONE"]}
    usdo = c_enum("co_usdo_abort_t").members
    assert set(USDO_ABORT_TEXT) == set(usdo.values()) - {usdo["CO_USDO_ABORT_NONE"]}


def test_general_errors_of_the_clients_are_the_c_codes():
    """What cancel() sends by default (co_usdo_abort_t is outside the cdef)."""
    from canopenfd.transfer import SdoClient, UsdoClient
    assert UsdoClient.GENERAL_ERROR == c_enum("co_usdo_abort_t").members["CO_USDO_ABORT_UNKNOWN"]
    assert SdoClient.GENERAL_ERROR == c_enum("co_abort_t").members["CO_ABORT_GENERAL"]


def _package_sources():
    for path in sorted(PACKAGE.rglob("*.py")):
        yield path, ast.parse(path.read_text(encoding="utf-8"), str(path))


def test_every_c_name_the_package_uses_exists_in_c():
    """`EventKind.GUARD`, `lib.CO_EV_GUARD`: a member C dropped or renamed would
    only fail when that line runs; here it fails at once."""
    enums = {name: getattr(constants, name) for name in constants.__all__
             if isinstance(getattr(constants, name), enum.EnumMeta)}
    cdef_names = {name for e in CDEF_ENUMS for name in e.members}
    missing = []
    for path, tree in _package_sources():
        where = path.relative_to(PACKAGE.parent)
        for node in ast.walk(tree):
            if not (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)):
                continue
            owner, attr = node.value.id, node.attr
            if owner in enums and attr.isupper() and attr not in enums[owner].__members__:
                missing.append(f"{where}:{node.lineno}: {owner}.{attr}")
            if owner == "lib" and attr.startswith("CO_") and attr.isupper() and \
                    attr not in cdef_names:
                missing.append(f"{where}:{node.lineno}: lib.{attr}")
    assert not missing, "names of C constants that C does not have:\n" + "\n".join(missing)


def test_every_command_kind_has_its_named_arguments():
    """co_rt_command_t's args hold one member per command kind, named after it
    (the binding fills the member by the kind's name)."""
    from canopenfd._binding.constants import CommandKind
    from canopenfd._binding.core import ffi
    members = {name for name, _ in ffi.typeof("co_rt_command_t").fields[2][1].type.fields}
    assert members == {kind.name.lower() for kind in CommandKind}
