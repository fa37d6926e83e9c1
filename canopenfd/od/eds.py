"""EDS and DCF files (CiA 306): import, and EDS/DCF export.

Import reads [FileInfo], [DeviceInfo], [DummyUsage], [Comments],
[DeviceComissioning] (the spec's spelling; [DeviceCommissioning] too), the
object lists, object sections ``[1018]``, sub-object sections ``[1018sub1]``
(any case: ``sub``/``Sub``/``SUB``), compact arrays (``CompactSubObj=n`` with
``[xxxxName]``/``[xxxxValue]``/``[xxxxDenotation]``) and
``[xxxxObjectLinks]``. Values follow `textvalues` (a leading 0 is octal).

Choices where CiA 306 leaves room:

- ObjectType missing: VAR (CiA 306 says so). AccessType missing: 'ro' (the
  least a wrong guess can break), with a warning. PDOMapping missing: 0.
  DefaultValue missing: None (the entry starts at the type's zero).
- Compact arrays: sub 0 is "NrOfObjects" (UNSIGNED8, ro, default n); subs
  1..n take DataType/AccessType/PDOMapping/limits/DefaultValue from the object
  section and are named "<ParameterName><n>" unless [xxxxName] names them.
- Inline comments: ``value ; text`` is cut at the ';' for numeric keys;
  names and string values are kept whole (they may contain ';').
- ObjectLinks must name existing objects other than the object itself, and
  may not form cycles.
- $NODEID in LowLimit/HighLimit is dropped with a warning (a limit that moves
  with the node-id cannot be checked without one).
- An empty ``ParameterValue=`` (DCF tools write one into every entry) is no
  configured value, for strings too.
- Keys starting with ``canopenfd_`` carry what CiA 306 cannot express
  (LineMode, MaxLength, Store, PDODirection); other tools ignore them.

Lenient by default: a slip whose intent is clear (an object list count that
disagrees with its keys, a manufacturer or unknown DataType, a DefaultValue or
limit that does not parse, a listed object without a section, a broken
ObjectLinks list, ...) is recovered and recorded in ``od.load_warnings`` as an
error-severity `Problem` naming file, line and section, and saying what was
done instead. ``strict=True`` raises `OdFileError` at the first of them (what
``canopenfd od check`` counts as an error). Recovery choices:

- DataType that is a number but no CiA 301 basic type (0x0040.. manufacturer
  or device-profile complex types, reserved codes): served as OCTET_STRING
  (bytes of the default's length; the default only if it is hex bytes).
- DataType missing or not a number: the entry (or object) is skipped.
- DefaultValue / ParameterValue / LowLimit / HighLimit that does not fit the
  type: dropped (the entry starts at the type's zero, resp. has no limit).
- PDOMapping, ObjFlags or Factor that does not parse: 0 / 0 / 1.
- AccessType that is no CiA 306 access type: ro.
- ParameterName missing on a sub-object: named ``sub<n>``; a sub-object with
  the record's ObjectType (0x9): taken as VAR.
- A value where sub-index 0 of an ARRAY/RECORD needs its UNSIGNED8 count:
  alone it becomes the object's VAR, else an UNSIGNED8 count replaces it.
- A line that is not key=value (or a key before the first section): skipped
  (`ini`); a text without any section is refused.

Unrecoverable input still fails fast with `OdFileError` (file, line, section, problem):
SubNumber/CompactSubObj/NrOfEntries are capped at 256 sub-indices, object
lists and links at 65535 entries, files at 16 MiB.
"""

from __future__ import annotations

import datetime as _dt
import io
import os
import re
from typing import IO, Callable, Dict, List, Optional, Tuple, TypeVar, Union, cast

from .datatypes import DataType, Value
from .errors import OdFileError, OdValueError
from .fileio import Source, read_source
from .ini import IniFile, Key, Section, parse_ini
from .model import (ACCESS_TYPES, ODArray, ODRecord, ODVariable, ObjectDictionary,
                    ObjectType, format_index)
from .objects import ODObject
from .textvalues import format_value, parse_int, parse_value
from .validate import ERROR, WARNING, Problem, find_link_cycle

T = TypeVar("T")

__all__ = ["import_eds", "export_eds", "export_dcf"]

_OBJECT_RE = re.compile(r"^([0-9a-f]{4})$", re.IGNORECASE)
_SUB_RE = re.compile(r"^([0-9a-f]{4})sub([0-9a-f]+)$", re.IGNORECASE)
_EXTRA_RE = re.compile(r"^([0-9a-f]{4})(name|value|denotation|objectlinks)$", re.IGNORECASE)
_LIST_SECTIONS = ("MandatoryObjects", "OptionalObjects", "ManufacturerObjects")
_MAX_SUBS = 256
_MAX_LIST = 0xFFFF
_INLINE_COMMENT = re.compile(r"\s*;.*$")
_DECIMAL_RE = re.compile(r"[0-9]{1,10}")
_STRING_KEYS = ("parametername", "denotation", "description", "unit")
_EXT = "canopenfd_"  # lower case: INI key names are matched in lower case


class _Reader:
    """One import: the parsed INI text plus where to point errors."""

    def __init__(self, ini: IniFile, strict: bool = False) -> None:
        self.ini = ini
        self.name = ini.name
        self.strict = strict
        self.unknown_type = False  # set by data_type(): the type was replaced
        self.warnings: List[Problem] = []

    # -------------------------------------------------------- errors
    def fail(self, section: Section, problem: str, key: Optional[Key] = None) -> OdFileError:
        line = key.line if key is not None else section.line
        return OdFileError(problem, self.name, line, f"[{section.name}]")

    def warn(self, section: Optional[Section], problem: str, key: Optional[Key] = None) -> None:
        line = key.line if key is not None else (section.line if section else None)
        where = f"{self.name}:{line}" if line else self.name
        if section is not None:
            where += f" [{section.name}]"
        self.warnings.append(Problem(WARNING, where, problem))

    def deviate(self, section: Section, problem: str, instead: str,
                key: Optional[Key] = None) -> None:
        """A deviation strict mode refuses: raise when strict, else record it
        as an error-severity problem saying what was done `instead`."""
        if self.strict:
            raise self.fail(section, problem, key)
        line = key.line if key is not None else section.line
        self.warnings.append(Problem(ERROR, f"{self.name}:{line} [{section.name}]",
                                     f"{problem}; {instead}"))

    # -------------------------------------------------------- typed keys
    def raw(self, section: Section, key_name: str) -> Tuple[Optional[str], Optional[Key]]:
        key = section.get(key_name)
        if key is None:
            return None, None
        value = key.value
        if key_name.lower() not in _STRING_KEYS:
            value = _INLINE_COMMENT.sub("", value)
        return value, key

    def int_key(self, section: Section, key_name: str, default: Optional[int] = None,
                low: int = 0, high: int = 0xFFFFFFFF) -> Optional[int]:
        text, key = self.raw(section, key_name)
        if key is None or not text:
            return default
        try:
            number = parse_int(text)
        except OdValueError as exc:
            raise self.fail(section, f"{key.name}: {exc.problem}", key) from None
        if not low <= number <= high:
            raise self.fail(section, f"{key.name} {number} outside {low}..{high}", key)
        return number

    def index_key(self, section: Section, key: Key, low: int) -> int:
        """The object index a list or link entry (``1=0x1018``) names."""
        index = self.int_key(section, key.name, None, low, 0xFFFF)
        if index is None:
            raise self.fail(section, f"entry {key.name} names no object index (empty value)",
                            key)
        return index

    def guard(self, section: Section, key: Optional[Key], action: Callable[[], T]) -> T:
        """Run a model setter; its OdValueError becomes an OdFileError here."""
        try:
            return action()
        except OdValueError as exc:
            prefix = f"{key.name}: " if key is not None else ""
            raise self.fail(section, prefix + exc.problem, key) from None

    # -------------------------------------------------------- entries
    def data_type(self, section: Section, default: Optional[DataType] = None
                  ) -> Optional[DataType]:
        """The entry's type; None (after a recorded deviation) when the entry
        must be skipped because its type cannot be known."""
        text, key = self.raw(section, "DataType")
        if key is None or not text:
            if default is not None:
                return default
            self.deviate(section, "DataType is missing", "entry skipped")
            return None
        try:
            number = parse_int(text)
        except OdValueError as exc:
            self.deviate(section, f"DataType: {exc.problem}", "entry skipped", key)
            return None
        try:
            return DataType(number)
        except ValueError:
            pass
        if not 0 <= number <= 0xFFFF:
            self.deviate(section, f"DataType {text} is not a CiA 301 data type",
                         "entry skipped", key)
            return None
        self.deviate(section, f"DataType 0x{number:04X} is not a CiA 301 data type"
                     + (" (manufacturer/profile complex type)" if number >= 0x40 else ""),
                     "served as OCTET_STRING (raw bytes)", key)
        self.unknown_type = True
        return DataType.OCTET_STRING

    def access_type(self, section: Section) -> str:
        text, key = self.raw(section, "AccessType")
        if key is None or not text:
            self.warn(section, "AccessType is missing; taken as ro")
            return "ro"
        lowered = text.lower()
        if lowered not in ACCESS_TYPES:
            self.deviate(section, f"AccessType {text!r} is not one of "
                                  f"{', '.join(ACCESS_TYPES)}", "taken as ro", key)
            return "ro"
        return lowered

    def flag(self, section: Section, key_name: str) -> bool:
        text, key = self.raw(section, key_name)
        if key is None or not text:
            return False
        lowered = text.lower()
        if lowered in ("1", "0x1", "true", "yes"):
            return True
        if lowered in ("0", "0x0", "false", "no"):
            return False
        if self.strict or key_name.lower() != "pdomapping":  # only PDOMapping has a safe 0
            raise self.fail(section, f"{key.name} must be 0 or 1, got {text!r}", key)
        self.deviate(section, f"{key.name} must be 0 or 1, got {text!r}", "taken as 0", key)
        return False

    def variable(self, section: Section, index: int, subindex: int,
                 name: Optional[str] = None, template: bool = False) -> Optional[ODVariable]:
        """An entry from the keys of `section` (`template`: the element of a
        compact array, described by the ARRAY's own section); None when it is
        skipped (a recorded deviation)."""
        if name is None:
            name = section.value("ParameterName")
            if not name:
                name = f"sub{subindex}"
                self.deviate(section, "ParameterName is missing", f"named {name!r}")
        object_type = ObjectType.VAR if template else \
            self.int_key(section, "ObjectType", ObjectType.VAR, 0, 0xFF)
        if object_type not in (ObjectType.VAR, ObjectType.DOMAIN):
            # generators that copy the record's ObjectType=0x9 onto its sub-objects
            self.deviate(section, f"ObjectType 0x{object_type:X} where a VAR (0x7) or "
                                  f"DOMAIN (0x2) entry is expected", "taken as VAR",
                         section.get("ObjectType"))
            object_type = ObjectType.VAR
        self.unknown_type = False
        dtype = self.data_type(section, DataType.DOMAIN
                               if object_type == ObjectType.DOMAIN else None)
        if dtype is None:
            return None
        unknown_type = self.unknown_type
        var = self.guard(section, None, lambda: ODVariable(
            name, index, subindex, dtype, self.access_type(section)))
        self.fill(section, var, unknown_type)
        return var

    def fill(self, section: Section, var: ODVariable, unknown_type: bool = False) -> None:
        """Everything but name, type and access, from the keys of `section`
        (`unknown_type`: the file's DataType was replaced by OCTET_STRING, so
        its limits mean nothing here)."""
        dtype = var.data_type
        var.pdo_mapping = self.flag(section, "PDOMapping")
        for key_name in ("LowLimit", "HighLimit"):
            key = section.get(key_name)
            if key is None or not _INLINE_COMMENT.sub("", key.value):
                continue
            if not dtype.is_numeric:
                reason = "the data type is unknown" if unknown_type \
                    else f"{dtype.name} has no order"
                self.warn(section, f"{key.name} ignored: {reason}", key)
                continue
            if "$" in key.value:
                self.warn(section, f"{key.name} {key.value!r} depends on the node-id; "
                                   f"ignored", key)
                continue
            attr = "low_limit" if key_name == "LowLimit" else "high_limit"
            self.lenient_value(section, key_name, dtype, "limit dropped",
                               lambda limit, _r, _t: setattr(var, attr, limit), False)
        self.lenient_value(section, "DefaultValue", dtype, "no default (the type's zero)",
                           var.set_default)
        value_key = section.get("ParameterValue")
        if value_key is not None and value_key.value.strip():  # empty: nothing configured
            self.lenient_value(section, "ParameterValue", dtype, "no configured value",
                               var.set_value)
            if var.value_base is not None:
                var.value_line = value_key.line
        var.denotation = section.value("Denotation", "") or ""
        var.description = section.value("Description", "") or ""
        var.unit = section.value("Unit", "") or ""
        factor, key = self.raw(section, "Factor")
        if factor:
            try:
                var.factor = float(factor)
            except ValueError:
                self.deviate(section, f"Factor {factor!r} is not a number", "taken as 1", key)
        try:
            var.obj_flags = self.int_key(section, "ObjFlags", 0, 0, 0xFFFFFFFF) or 0
        except OdFileError as exc:
            self.deviate(section, exc.problem, "taken as 0", section.get("ObjFlags"))
        self.extensions(section, var)

    def lenient_value(self, section: Section, key_name: str, dtype: DataType, instead: str,
                      setter: Callable[[Optional[Value], bool, str], object],
                      allow_node_id: bool = True) -> None:
        """Parse the value key `key_name` and hand it to `setter(value,
        relative, text)`; a value that does not parse or fit is a deviation:
        dropped (`instead` says so) unless strict."""
        key = section.get(key_name)
        if key is None:
            return
        text = key.value
        if dtype not in (DataType.VISIBLE_STRING, DataType.UNICODE_STRING):
            text = _INLINE_COMMENT.sub("", text)
        try:
            value, relative = parse_value(dtype, text, allow_node_id)
            setter(value, relative, text.strip())
        except OdValueError as exc:
            self.deviate(section, f"{key.name} {_shown(text)}: {exc.problem}", instead, key)

    def extensions(self, section: Section, var: ODVariable) -> None:
        if not any(name.startswith(_EXT) for name in section.keys):
            return
        mode, key = self.raw(section, _EXT + "LineMode")
        if mode:
            self.guard(section, key, lambda: setattr(var, "line_mode", mode.lower()))
        length = self.int_key(section, _EXT + "MaxLength", None, 0, 0xFFFFFFFF)
        if length is not None:
            var.max_length = length
        store, key = self.raw(section, _EXT + "Store")
        if store:
            var.store = self.flag(section, _EXT + "Store")
        direction, key = self.raw(section, _EXT + "PDODirection")
        if direction:
            self.guard(section, key, lambda: setattr(var, "pdo_direction", direction.lower()))


def _shown(text: str) -> str:
    return repr(text if len(text) <= 40 else text[:37] + "...")


# ------------------------------------------------------------------ import
def import_eds(source: Source, node_id: Optional[int] = None,
               mode: Optional[str] = None, strict: bool = False) -> ObjectDictionary:
    """An ObjectDictionary from an EDS or DCF file (path or open file).

    `node_id` resolves $NODEID expressions (default: the DCF's NodeID);
    `mode` ('fd'/'classic') overrides the guess from the file (FD when 0x1000
    is an ARRAY or 0x1030 exists). Lenient unless `strict` (see the module
    docstring): recovered deviations are in ``od.load_warnings``."""
    data, name = read_source(source)
    return eds_from_text(data, name, node_id, mode, strict)


def eds_from_text(data: Union[bytes, str], name: str, node_id: Optional[int] = None,
                  mode: Optional[str] = None, strict: bool = False) -> ObjectDictionary:
    """`import_eds` of content already read (`name` is used in messages)."""
    ini = parse_ini(data, name, strict)
    reader = _Reader(ini, strict)
    for line, section_name, text in ini.warnings:
        reader.warnings.append(Problem(WARNING, f"{name}:{line} [{section_name}]", text))
    for line, section_name, text in ini.deviations:
        where = f"{name}:{line} [{section_name}]" if section_name else f"{name}:{line}"
        reader.warnings.append(Problem(ERROR, where, f"{text}; line ignored"))
    od = ObjectDictionary()
    od.source = name
    _read_metadata(reader, od, node_id)
    listed = _read_object_lists(reader)
    _read_objects(reader, od, listed)
    _note_unknown_sections(reader)
    od.mode = mode if mode is not None else (
        "fd" if isinstance(od.indices.get(0x1000), ODArray) or 0x1030 in od.indices
        else "classic")
    od.load_warnings = reader.warnings
    commissioned = ini.section("DeviceComissioning") or ini.section("DeviceCommissioning")
    od.source_format = "DCF" if name.lower().endswith(".dcf") or commissioned else "EDS"
    return od


def _plain(section: Optional[Section]) -> Dict[str, str]:
    if section is None:
        return {}
    return {key.name: key.value for key in section.keys.values()}


def _read_metadata(reader: _Reader, od: ObjectDictionary, node_id: Optional[int]) -> None:
    ini = reader.ini
    od.file_info = _plain(ini.section("FileInfo"))
    od.device_info = _plain(ini.section("DeviceInfo"))
    if ini.section("DeviceInfo") is None:
        reader.warn(None, "[DeviceInfo] is missing (CiA 306 requires it)")
    comments = ini.section("Comments")
    if comments is not None:
        count = reader.int_key(comments, "Lines", 0, 0, _MAX_LIST) or 0
        od.comments = "\n".join(comments.value(f"Line{i}", "") or "" for i in range(1, count + 1))
    dummies = ini.section("DummyUsage")
    if dummies is not None:
        for index in range(1, 8):
            if reader.flag(dummies, f"Dummy{index:04X}"):
                od.dummy_usage.add(index)
    commissioning = ini.section("DeviceComissioning") or ini.section("DeviceCommissioning")
    if commissioning is not None:
        od.device_commissioning = _plain(commissioning)
        dcf_node = reader.int_key(commissioning, "NodeID", None, 0, 0xFF)
        if dcf_node is not None and not 1 <= dcf_node <= 127:
            reader.warn(commissioning, f"NodeID {dcf_node} is not a node-id 1..127; ignored",
                        commissioning.get("NodeID"))
            dcf_node = None
        if node_id is None:
            node_id = dcf_node
        rate = reader.int_key(commissioning, "Baudrate", None, 0, 1_000_000)
        if rate:
            od.bitrate = rate * 1000
    od.node_id = node_id


def _read_object_lists(reader: _Reader) -> Optional[Dict[int, Tuple[Section, Key]]]:
    """index -> (list section, key) of every listed object; None without lists."""
    found: Dict[int, Tuple[Section, Key]] = {}
    present = False
    for list_name in _LIST_SECTIONS:
        section = reader.ini.section(list_name)
        if section is None:
            continue
        present = True
        count = reader.int_key(section, "SupportedObjects", 0, 0, _MAX_LIST) or 0
        # the numbered keys as written: their count may disagree with SupportedObjects
        # (by number only: "1" and "01" are one number, and keys do not compare)
        numbered = sorted(((int(key.name, 10), key) for key in section.keys.values()
                           if _DECIMAL_RE.fullmatch(key.name)
                           and 1 <= int(key.name, 10) <= _MAX_LIST),
                          key=lambda pair: pair[0])
        first_of: Dict[int, Key] = {}
        for number, key in numbered:
            if number in first_of:
                reader.deviate(section, f"keys {first_of[number].name} and {key.name} both "
                               f"number entry {number}", "both are used", key)
            first_of.setdefault(number, key)
        present_numbers = set(first_of)
        missing = [n for n in range(1, count + 1) if n not in present_numbers]
        if missing:
            reader.deviate(section, f"SupportedObjects={count} but key {missing[0]} is missing"
                           + (f" ({len(missing)} keys missing)" if len(missing) > 1 else ""),
                           f"the {len(numbered)} numbered keys present are used",
                           section.get("SupportedObjects"))
        extra = [key for number, key in numbered if number > count]
        if extra:
            reader.deviate(section, f"SupportedObjects={count} but key {extra[0].name} "
                           f"is present", f"the {len(numbered)} numbered keys present are used",
                           extra[0])
        for number, key in numbered:
            try:
                index = reader.index_key(section, key, 1)
            except OdFileError as exc:
                if reader.strict:
                    raise
                reader.deviate(section, exc.problem, "entry ignored", key)
                continue
            if index in found:
                reader.warn(section, f"{format_index(index)} is listed twice", key)
            found[index] = (section, key)
    return found if present else None


def _read_objects(reader: _Reader, od: ObjectDictionary,
                  listed: Optional[Dict[int, Tuple[Section, Key]]]) -> None:
    objects: Dict[int, Section] = {}
    subs: Dict[int, List[Tuple[int, Section]]] = {}
    extras: Dict[Tuple[int, str], Section] = {}
    for section in reader.ini.sections.values():
        title = section.name
        match = _OBJECT_RE.match(title)
        if match:
            objects[int(match.group(1), 16)] = section
            continue
        match = _SUB_RE.match(title)
        if match:
            digits = match.group(2).lstrip("0") or "0"
            sub = int(digits, 16) if len(digits) <= 8 else 1 << 32
            if sub > 0xFF:
                raise reader.fail(section, f"sub-index 0x{match.group(2)[:10]} is above 0xFF")
            siblings = subs.setdefault(int(match.group(1), 16), [])
            twins = [other for other_sub, other in siblings if other_sub == sub]
            if twins:  # e.g. [1018sub1] and [1018sub01]
                reader.deviate(section, f"sub-index 0x{sub:02X} is defined twice (also "
                               f"[{twins[0].name}] at line {twins[0].line})",
                               "the first one is used")
                continue
            siblings.append((sub, section))
            continue
        match = _EXTRA_RE.match(title)
        if match:
            extras[(int(match.group(1), 16), match.group(2).lower())] = section
    for (index, kind), section in sorted(extras.items()):
        if index not in objects:
            reader.deviate(section, f"belongs to {format_index(index)}, which has no "
                                    f"[{index:04X}] section", "section ignored")
            del extras[(index, kind)]
    for index in sorted(objects):
        obj = _read_object(reader, index, objects[index], subs.pop(index, []), extras)
        if obj is not None:
            od.add_object(obj)
    for index, orphans in sorted(subs.items()):
        sub, section = orphans[0]
        reader.deviate(section, f"sub-object of {format_index(index)}, which has no "
                                f"[{index:04X}] section",
                       f"{len(orphans)} sub-object section{'s' if len(orphans) > 1 else ''} "
                       f"ignored")
    _read_links(reader, od, extras)
    if listed is None:
        reader.warn(None, "no [MandatoryObjects]/[OptionalObjects]/[ManufacturerObjects] "
                          "lists; every object section was read")
        return
    for index, (section, key) in sorted(listed.items()):
        if index not in objects:
            reader.deviate(section, f"{format_index(index)} is listed but has no "
                                    f"[{index:04X}] section", "list entry ignored", key)
    for index in sorted(set(objects) - set(listed)):
        if index in od.indices:
            reader.warn(objects[index], f"{format_index(index)} is in no object list")


_KNOWN_SECTIONS = re.compile(
    r"^(FileInfo|DeviceInfo|DummyUsage|Comments|MandatoryObjects|OptionalObjects|"
    r"ManufacturerObjects|DeviceCom+issioning|DynamicChannels|Tools|Tool\d+|"
    r"SupportedModules|ConnectedModules|M\d+\w*)$", re.IGNORECASE)


def _note_unknown_sections(reader: _Reader) -> None:
    """Vendor sections CiA 306 does not define are ignored, with a warning, so
    `od check` shows that something in the file was not read."""
    for section in reader.ini.sections.values():
        title = section.name
        if not (_KNOWN_SECTIONS.match(title) or _OBJECT_RE.match(title)
                or _SUB_RE.match(title) or _EXTRA_RE.match(title)):
            reader.warn(section, f"section [{title}] is not a CiA 306 section; ignored")


def _read_object(reader: _Reader, index: int, section: Section,
                 subs: List[Tuple[int, Section]],
                 extras: Dict[Tuple[int, str], Section]) -> Optional[ODObject]:
    name = section.value("ParameterName")
    if not name:
        raise reader.fail(section, "ParameterName is missing")
    object_type = reader.int_key(section, "ObjectType", ObjectType.VAR, 0, 0xFF)
    if object_type in (ObjectType.NULL, ObjectType.DEFTYPE, ObjectType.DEFSTRUCT):
        reader.warn(section, f"ObjectType 0x{object_type:X} ({ObjectType(object_type).name}) "
                             f"is not supported; object skipped", section.get("ObjectType"))
        return None
    if object_type in (ObjectType.VAR, ObjectType.DOMAIN):
        if subs:
            raise reader.fail(subs[0][1], f"{format_index(index)} is a VAR, it has no "
                                          f"sub-indices")
        return reader.variable(section, index, 0, name)
    if object_type not in (ObjectType.ARRAY, ObjectType.RECORD):
        reader.deviate(section, f"ObjectType 0x{object_type:X} is not a CiA 301 object "
                                f"code (0x2, 0x7, 0x8, 0x9)", "object skipped",
                       section.get("ObjectType"))
        return None
    container = ODArray(name, index) if object_type == ObjectType.ARRAY else ODRecord(name, index)
    container.description = section.value("Description", "") or ""
    compact = reader.int_key(section, "CompactSubObj", 0, 0, 0xFFFFFFFF) or 0
    if compact:
        if compact > _MAX_SUBS - 1:
            raise reader.fail(section, f"CompactSubObj {compact} is more than 255 "
                                       f"sub-indices", section.get("CompactSubObj"))
        if object_type != ObjectType.ARRAY:
            raise reader.fail(section, "CompactSubObj is only allowed on ARRAY objects "
                                       "(ObjectType 0x8)", section.get("CompactSubObj"))
        if not _build_compact(reader, section, container, compact):
            return None
        if subs:
            reader.warn(subs[0][1], "sub-object sections next to CompactSubObj; "
                                    "they replace the generated entries")
    else:
        number = reader.int_key(section, "SubNumber", None, 0, 0xFFFFFFFF)
        if number is not None and number > _MAX_SUBS:
            raise reader.fail(section, f"SubNumber {number} is more than {_MAX_SUBS} "
                                       f"sub-indices", section.get("SubNumber"))
        if number is None:
            reader.warn(section, "SubNumber is missing")
        elif number != len(subs):
            reader.warn(section, f"SubNumber={number} but {len(subs)} sub-object "
                                 f"section{'s' if len(subs) != 1 else ''} exist",
                        section.get("SubNumber"))
    for sub, sub_section in sorted(subs, key=lambda item: item[0]):
        member = reader.variable(sub_section, index, sub)
        if member is not None:
            container.add_member(member)
    count = container.subindices.get(0)
    if count is not None and count.data_type != DataType.UNSIGNED8 and not compact:
        return _repair_sub0(reader, section, container, subs)
    if not container.subindices:
        reader.deviate(section, f"{format_index(index)} is an "
                                f"{'ARRAY' if object_type == ObjectType.ARRAY else 'RECORD'} "
                                f"without usable sub-objects", "object skipped")
        return None
    for kind in ("name", "value", "denotation"):
        extra = extras.get((index, kind))
        if extra is not None:
            _apply_compact_extra(reader, extra, kind, container)
    return container


def _repair_sub0(reader: _Reader, section: Section, container: Union[ODRecord, ODArray],
                 subs: List[Tuple[int, Section]]) -> ODObject:
    """Sub-index 0 of an ARRAY/RECORD holds the highest sub-index (UNSIGNED8);
    some files put a value there. Alone, it is served as the object's VAR (the
    same index:00 on the wire); next to other entries a proper count replaces
    it. Either way a recorded deviation."""
    value = container.subindices[0]
    sub0_section = next(sub_section for sub, sub_section in subs if sub == 0)
    problem = (f"sub-index 0 of {format_index(container.index)} is {value.data_type.name}, "
               f"not the UNSIGNED8 count of an ARRAY/RECORD")
    if len(container.subindices) == 1:
        reader.deviate(sub0_section, problem, f"served as a VAR {format_index(container.index)}"
                                              f" named {value.name!r}")
        var = value.copy()
        return var
    highest = max(container.subindices)
    reader.deviate(sub0_section, problem, f"replaced by 'Highest sub-index supported' "
                                          f"(ro, {highest})")
    members = [container.subindices[sub] for sub in sorted(container.subindices) if sub]
    fixed = type(container)(container.name, container.index)
    fixed.description = container.description
    fixed.add_member(ODVariable("Highest sub-index supported", container.index, 0,
                                DataType.UNSIGNED8, "ro", highest))
    for member in members:
        fixed.add_member(member)
    return fixed


def _build_compact(reader: _Reader, section: Section, container: Union[ODRecord, ODArray],
                   count: int) -> bool:
    """The n entries of a compact array; False when its element type is
    unusable (the object is skipped, a recorded deviation)."""
    count_entry = ODVariable("NrOfObjects", container.index, 0, DataType.UNSIGNED8, "ro", count)
    container.add_member(count_entry)
    template = reader.variable(section, container.index, 1, container.name, template=True)
    if template is None:
        return False
    template.object_links = []
    for sub in range(1, count + 1):
        var = template.copy()
        var.subindex = sub
        var.name = f"{container.name}{sub}"
        container.add_member(var)
    return True


def _apply_compact_extra(reader: _Reader, section: Section, kind: str,
                         container: Union[ODRecord, ODArray]) -> None:
    """[xxxxName] / [xxxxValue] / [xxxxDenotation]: per-sub names, defaults, denotations."""
    count = reader.int_key(section, "NrOfEntries", None, 0, 0xFFFFFFFF)
    if count is not None and count > _MAX_SUBS:
        raise reader.fail(section, f"NrOfEntries {count} is more than {_MAX_SUBS} "
                                   f"sub-indices", section.get("NrOfEntries"))
    entries = [key for lower, key in section.keys.items() if lower != "nrofentries"]
    if count is not None and count != len(entries):
        reader.warn(section, f"NrOfEntries={count} but {len(entries)} entries are given",
                    section.get("NrOfEntries"))
    for key in entries:
        try:  # decimal (ASCII digits only: int() would take '1_0' or Arabic digits), or 0x hex
            if key.name.lower().startswith("0x"):
                sub = parse_int(key.name)
            elif _DECIMAL_RE.fullmatch(key.name):
                sub = int(key.name, 10)
            else:
                raise ValueError(key.name)
        except (OdValueError, ValueError):
            raise reader.fail(section, f"key {_shown(key.name)} is not a sub-index", key) from None
        var = container.subindices.get(sub)
        if var is None or sub == 0:
            raise reader.fail(section, f"sub-index {sub} is not an entry of "
                                       f"{format_index(container.index)}", key)
        if kind == "name":
            if not key.value:
                raise reader.fail(section, f"empty name for sub-index {sub}", key)
            var.name = key.value
        elif kind == "denotation":
            var.denotation = key.value
        else:
            reader.lenient_value(section, key.name, var.data_type,
                                 "no default (the type's zero)", var.set_default)


def _read_links(reader: _Reader, od: ObjectDictionary,
                extras: Dict[Tuple[int, str], Section]) -> None:
    sections: Dict[int, Section] = {}
    for (index, kind), section in sorted(extras.items()):
        if kind != "objectlinks":
            continue
        sections[index] = section
        obj = od.indices.get(index)
        if obj is None:
            reader.deviate(section, f"links of {format_index(index)}, which does not exist",
                           "links ignored")
            continue
        count = reader.int_key(section, "ObjectLinks", 0, 0, _MAX_LIST) or 0
        links: List[int] = []
        for number in range(1, count + 1):
            key = section.get(str(number))
            if key is None:
                reader.deviate(section, f"ObjectLinks={count} but key {number} is missing",
                               "link ignored", section.get("ObjectLinks"))
                continue
            target = reader.index_key(section, key, 0)
            if target == index:
                reader.deviate(section, f"{format_index(index)} links to itself",
                               "link ignored", key)
            elif target not in od.indices:
                reader.deviate(section, f"link to {format_index(target)}, which does "
                                        f"not exist", "link ignored", key)
            else:
                links.append(target)
        obj.object_links = links
    cycle = find_link_cycle({i: o.object_links for i, o in od.indices.items()})
    if cycle:
        reader.deviate(sections[cycle[0]], "ObjectLinks form a cycle: "
                       + " -> ".join(format_index(i) for i in cycle),
                       "the links of the objects in it are ignored")
        for index in cycle:
            od.indices[index].object_links = []


# ------------------------------------------------------------------ export
def export_dcf(od: ObjectDictionary, dest: Union[Source, None] = None) -> Optional[str]:
    """`export_eds` with a [DeviceComissioning] section (node-id, bit rate)."""
    return export_eds(od, dest, dcf=True)


def export_eds(od: ObjectDictionary, dest: Union[Source, None] = None,
               dcf: bool = False) -> Optional[str]:
    """Write `od` as an EDS (UTF-8) to a path or text stream; with dest None,
    return the text. Configured values (`value`) are written as
    ParameterValue. Sub-objects are always written as their own sections.

    INI lines cannot quote: leading and trailing spaces of string values are
    lost, and a value holding a line break raises OdValueError."""
    file_name = os.path.basename(os.fspath(dest)) if isinstance(dest, (str, os.PathLike)) \
        else "device.eds"
    lines: List[str] = []
    _write_header(lines, od, file_name, dcf)
    groups = {name: [] for name in _LIST_SECTIONS}  # type: Dict[str, List[int]]
    for index in sorted(od.indices):
        groups[_list_of(index)].append(index)
    for list_name in _LIST_SECTIONS:
        indices = groups[list_name]
        lines.append(f"[{list_name}]")
        lines.append(f"SupportedObjects={len(indices)}")
        lines.extend(f"{n}=0x{index:04X}" for n, index in enumerate(indices, start=1))
        lines.append("")
        for index in indices:
            _write_object(lines, od.indices[index])
    text = "\n".join(lines)
    if dest is None:
        return text
    if isinstance(dest, (str, os.PathLike)):
        with open(dest, "w", encoding="utf-8", newline="\n") as handle:
            handle.write(text)
    else:
        _write_to_stream(dest, text)
    return None


def _write_to_stream(dest: Union[IO[str], IO[bytes]], text: str) -> None:
    """A text stream gets the text, a binary one (BytesIO, open(..., "wb")) its
    UTF-8 bytes (casts: IO[...] cannot be told apart by isinstance, io's bases can)."""
    if isinstance(dest, (io.RawIOBase, io.BufferedIOBase)):
        cast(IO[bytes], dest).write(text.encode("utf-8"))
    else:
        cast(IO[str], dest).write(text)


def _list_of(index: int) -> str:
    if index in (0x1000, 0x1001, 0x1018):
        return "MandatoryObjects"
    if 0x2000 <= index <= 0x5FFF:
        return "ManufacturerObjects"
    return "OptionalObjects"


def _one_line(text: str, what: str) -> str:
    if "\n" in text or "\r" in text:
        raise OdValueError(f"{what} {text[:30]!r}... holds a line break; an EDS cannot "
                           f"store it")
    return text


def _write_header(lines: List[str], od: ObjectDictionary, file_name: str, dcf: bool) -> None:
    now = _dt.datetime.now()
    info = {
        "FileName": file_name, "FileVersion": "1", "FileRevision": "0", "EDSVersion": "4.0",
        "Description": "", "CreationTime": now.strftime("%I:%M%p"),
        "CreationDate": now.strftime("%m-%d-%Y"), "CreatedBy": "canopenfd",
    }
    info.update({k: v for k, v in od.file_info.items() if k != "FileName"})
    _write_section(lines, "FileInfo", info)
    device = dict(od.device_info)
    identity = od.indices.get(0x1018)
    for sub, key in ((1, "VendorNumber"), (2, "ProductNumber"), (3, "RevisionNumber")):
        var = identity.subindices.get(sub) if isinstance(identity, (ODRecord, ODArray)) else None
        if key not in device and var is not None and isinstance(var.default, int):
            device[key] = f"0x{var.default:X}"
    defaults = {"VendorName": "", "ProductName": "", "OrderCode": "",
                "SimpleBootUpMaster": "0", "SimpleBootUpSlave": "1", "Granularity": "8",
                "DynamicChannelsSupported": "0", "GroupMessaging": "0", "LSS_Supported": "0",
                "NrOfRXPDO": str(sum(0x1400 <= i <= 0x15FF for i in od.indices)),
                "NrOfTXPDO": str(sum(0x1800 <= i <= 0x19FF for i in od.indices))}
    for key, value in defaults.items():
        device.setdefault(key, value)
    if not any(key.lower().startswith("baudrate_") for key in device):
        for rate in (10, 20, 50, 125, 250, 500, 800, 1000):
            device[f"BaudRate_{rate}"] = "1" if od.bitrate == rate * 1000 else "0"
    _write_section(lines, "DeviceInfo", device)
    lines.append("[DummyUsage]")
    lines.extend(f"Dummy{i:04X}={1 if i in od.dummy_usage else 0}" for i in range(1, 8))
    lines.append("")
    if od.comments:
        comment_lines = od.comments.split("\n")
        lines.append("[Comments]")
        lines.append(f"Lines={len(comment_lines)}")
        lines.extend(f"Line{n}={text}" for n, text in enumerate(comment_lines, start=1))
        lines.append("")
    if dcf:
        commissioning = dict(od.device_commissioning)
        if od.node_id is not None:
            commissioning["NodeID"] = str(od.node_id)
        if od.bitrate:
            commissioning["Baudrate"] = str(od.bitrate // 1000)
        _write_section(lines, "DeviceComissioning", commissioning)


def _write_section(lines: List[str], name: str, keys: Dict[str, str]) -> None:
    lines.append(f"[{name}]")
    lines.extend(f"{key}={_one_line(str(value), key)}" for key, value in keys.items())
    lines.append("")


def _write_object(lines: List[str], obj: ODObject) -> None:
    if isinstance(obj, ODVariable):
        _write_variable(lines, f"{obj.index:04X}", obj)
    else:
        lines.append(f"[{obj.index:04X}]")
        lines.append(f"ParameterName={_one_line(obj.name, 'ParameterName')}")
        lines.append(f"ObjectType=0x{int(obj.object_type):X}")
        lines.append(f"SubNumber=0x{len(obj.subindices):X}")
        if obj.description:
            lines.append(f"Description={_one_line(obj.description, 'Description')}")
        lines.append("")
        for sub in sorted(obj.subindices):
            _write_variable(lines, f"{obj.index:04X}sub{sub:X}", obj.subindices[sub])
    if obj.object_links:
        lines.append(f"[{obj.index:04X}ObjectLinks]")
        lines.append(f"ObjectLinks={len(obj.object_links)}")
        lines.extend(f"{n}=0x{target:04X}" for n, target in
                     enumerate(obj.object_links, start=1))
        lines.append("")


def _write_variable(lines: List[str], section: str, var: ODVariable) -> None:
    dtype = var.data_type
    keys: List[Tuple[str, str]] = [
        ("ParameterName", var.name),
        ("ObjectType", f"0x{int(var.object_type):X}"),
        ("DataType", f"0x{int(dtype):04X}"),
        ("AccessType", var.access_type),
    ]
    if var.default_base is not None:
        keys.append(("DefaultValue", format_value(dtype, var.default_base,
                                                  var.relative_to_node_id)))
    keys.append(("PDOMapping", "1" if var.pdo_mapping else "0"))
    if var.low_limit is not None:
        keys.append(("LowLimit", format_value(dtype, var.low_limit)))
    if var.high_limit is not None:
        keys.append(("HighLimit", format_value(dtype, var.high_limit)))
    if var.value_base is not None:
        keys.append(("ParameterValue", format_value(dtype, var.value_base,
                                                    var.value_relative_to_node_id)))
    for key, text in (("Denotation", var.denotation), ("Description", var.description),
                      ("Unit", var.unit)):
        if text:
            keys.append((key, text))
    if var.factor != 1:
        keys.append(("Factor", repr(float(var.factor))))
    if var.obj_flags:
        keys.append(("ObjFlags", f"0x{var.obj_flags:X}"))
    if var.line_mode is not None:
        keys.append((_EXT + "LineMode", var.line_mode))
    if var.max_length is not None:
        keys.append((_EXT + "MaxLength", str(var.max_length)))
    if var.store_explicit is not None and var.store_explicit != var.store_auto:
        keys.append((_EXT + "Store", "1" if var.store_explicit else "0"))
    if var.pdo_direction is not None:
        keys.append((_EXT + "PDODirection", var.pdo_direction))
    lines.append(f"[{section}]")
    for key, text in keys:
        try:
            lines.append(f"{key}={_one_line(text, key)}")
        except OdValueError as exc:
            raise exc.at(f"{var.where} {var.qualname}") from None
    lines.append("")
