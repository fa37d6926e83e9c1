"""XDD and XDC files (CiA 311 / CiA 1311, ISO 15745 XML): import.

Two dialects are read, matched by local element names (any namespace):

- CiA 311 (classic CANopen): ``CANopenObjectList`` / ``CANopenObject``
  (index "1018", name, objectType, dataType "0007", accessType, PDOmapping
  no/default/optional/TPDO/RPDO, defaultValue, lowLimit, highLimit,
  subNumber, actualValue in XDCs, denotation, objFlags, uniqueIDRef) /
  ``CANopenSubObject`` (subIndex "01", ...). Attributes missing on an object
  are taken from the ``parameter`` its uniqueIDRef names (access, IEC type,
  defaultValue, actualValue, allowedValues range).
- CiA 1311 (CANopen FD), as written by CANopen FD tools:
  ``CANopenFDObjectList`` / ``CANopenFDDataObject`` (index, name, dataType
  "07", objectType) / ``CANopenFDDataElement`` (subIndex, name, dataType,
  accessUSDO, accessPDO no/t/r/tr, defaultValue, lowLimit, highLimit, unit,
  objFlags). There every object lists its elements, VARs included (one
  element, sub-index 00), and objectType is often 7 for everything: an object
  with a single sub-index-0 element is a VAR; otherwise an ARRAY when its
  dataType is a basic type all elements >= 1 share, else a RECORD.

Values use the EDS notation (`textvalues`: 0x hex, a leading 0 is octal,
$NODEID+offset). Also read: DeviceIdentity (into device_info with EDS key
names), ProfileBody file attributes (file_info), deviceCommissioning (node-id,
bit rate), supported baud rates, dummyUsage.

Lenient by default, like the EDS reader: a slip whose intent is clear is
recovered and recorded in ``od.load_warnings`` as an error-severity `Problem`
(file:line, element, what was done instead); ``strict=True`` raises at the
first. Recovery: a dataType that is no CiA 301 basic type is served as
OCTET_STRING (raw bytes), a missing/unparsable one skips the entry; a default,
actual value or limit that does not fit is dropped; an unknown access type is
ro, an unknown PDO mapping "no", bad objFlags 0; a repeated object or
sub-index keeps the first; a sub-object without a name is named ``sub<n>``.

Hostile input fails with `OdFileError` naming file, line and element: DOCTYPE
and ENTITY declarations are refused (see `xmltree`), sizes are capped.
"""

from __future__ import annotations

import re
from typing import Callable, Dict, List, Optional, Set, Union

from .datatypes import DataType, Value
from .errors import OdFileError, OdValueError
from .fileio import Source, read_source
from .model import (ACCESS_TYPES, ODArray, ODRecord, ODVariable, ObjectDictionary,
                    ObjectType, format_index)
from .objects import ODObject
from .textvalues import parse_int, parse_value
from .validate import ERROR, WARNING, Problem
from .xmltree import Node, parse_xml

__all__ = ["import_xdd"]

_LISTS = ("CANopenObjectList", "CANopenFDObjectList")
_OBJECTS = ("CANopenObject", "CANopenFDDataObject", "CANopenFDObject")
_SUBS = ("CANopenSubObject", "CANopenFDDataElement", "CANopenFDSubObject")
_MAX_SUBS = 256

_PARAMETER_ACCESS = {
    "const": "const", "read": "ro", "write": "wo", "readwrite": "rw",
    "readwriteinput": "rww", "readwriteoutput": "rwr",
}
_IEC_TYPES = {
    "BOOL": DataType.BOOLEAN, "SINT": DataType.INTEGER8, "INT": DataType.INTEGER16,
    "DINT": DataType.INTEGER32, "LINT": DataType.INTEGER64, "USINT": DataType.UNSIGNED8,
    "UINT": DataType.UNSIGNED16, "UDINT": DataType.UNSIGNED32, "ULINT": DataType.UNSIGNED64,
    "BYTE": DataType.UNSIGNED8, "WORD": DataType.UNSIGNED16, "DWORD": DataType.UNSIGNED32,
    "LWORD": DataType.UNSIGNED64, "REAL": DataType.REAL32, "LREAL": DataType.REAL64,
    "STRING": DataType.VISIBLE_STRING, "WSTRING": DataType.UNICODE_STRING,
}
_PDO_311 = {"no": None, "default": "auto", "optional": "auto", "tpdo": "tpdo", "rpdo": "rpdo"}
_PDO_FD = {"no": None, "": None, "t": "tpdo", "tx": "tpdo", "tpdo": "tpdo", "r": "rpdo",
           "rx": "rpdo", "rpdo": "rpdo", "tr": "both", "rt": "both", "both": "both"}
_MAX_BITRATE = 1_000_000_000
_RATE_RE = re.compile(r"^\s*(\d+(?:\.\d+)?)\s*(k|m)?\s*(?:bit/s|bps|baud)?", re.IGNORECASE)


class _Reader:
    def __init__(self, name: str, root: Node, strict: bool = False) -> None:
        self.name = name
        self.root = root
        self.strict = strict
        self.warnings: List[Problem] = []
        self.parameters: Dict[str, Node] = {}
        for node in root.iter("parameter"):
            unique = node.get("uniqueID")
            if unique:
                self.parameters[unique] = node

    def fail(self, node: Node, problem: str, owner: Optional[int] = None) -> OdFileError:
        return OdFileError(problem, self.name, node.line, _describe(node, owner))

    def warn(self, node: Optional[Node], problem: str, owner: Optional[int] = None) -> None:
        where = self.name if node is None else f"{self.name}:{node.line} {_describe(node, owner)}"
        self.warnings.append(Problem(WARNING, where, problem))

    def deviate(self, node: Node, problem: str, instead: str,
                owner: Optional[int] = None) -> None:
        """A deviation strict mode refuses: raise when strict, else record it
        (error severity) with what was done `instead`."""
        if self.strict:
            raise self.fail(node, problem, owner)
        self.warnings.append(Problem(ERROR, f"{self.name}:{node.line} {_describe(node, owner)}",
                                     f"{problem}; {instead}"))

    # -------------------------------------------------------- attributes
    def attr(self, node: Node, name: str, param: Optional[Node] = None) -> Optional[str]:
        """An attribute, else the same item from the uniqueIDRef parameter."""
        value = node.get(name)
        if value is not None or param is None:
            return value
        return _parameter_item(param, name)

    def hex_attr(self, node: Node, name: str, high: int, owner: Optional[int]) -> Optional[int]:
        text = node.get(name)
        if text is None:
            return None
        digits = text.strip()
        if digits[:2].lower() == "0x":
            digits = digits[2:]
        if not re.fullmatch(r"[0-9A-Fa-f]{1,8}", digits):
            raise self.fail(node, f"{name} {text!r} is not a hex number", owner)
        number = int(digits, 16)
        if number > high:
            raise self.fail(node, f"{name} {text!r} is above 0x{high:X}", owner)
        return number

    def dec_attr(self, node: Node, name: str, owner: Optional[int]) -> Optional[int]:
        text = node.get(name)
        if text is None or not text.strip():
            return None
        try:
            return int(text.strip(), 16) if text.strip()[:2].lower() == "0x" \
                else int(text.strip(), 10)
        except ValueError:
            raise self.fail(node, f"{name} {text[:20]!r} is not a number", owner) from None

    # -------------------------------------------------------- entries
    def data_type(self, node: Node, owner: Optional[int], param: Optional[Node],
                  inherited: Optional[DataType]) -> Optional[DataType]:
        """The entry's type; None (a recorded deviation) when it cannot be known."""
        text = node.get("dataType")
        if text is not None and text.strip():
            try:
                number = self.hex_attr(node, "dataType", 0xFFFF, owner)
            except OdFileError as exc:
                self.deviate(node, exc.problem, "entry skipped", owner)
                return None
            assert number is not None   # the attribute is there (text above)
            try:
                return DataType(number)
            except ValueError:
                self.deviate(node, f"dataType 0x{number:04X} is not a CiA 301 data type"
                             + (" (manufacturer/profile complex type)" if number >= 0x40 else ""),
                             "served as OCTET_STRING (raw bytes)", owner)
                return DataType.OCTET_STRING
        if param is not None:
            for child in param.children:
                if child.tag.upper() in _IEC_TYPES:
                    return _IEC_TYPES[child.tag.upper()]
        if inherited is not None:
            return inherited
        self.deviate(node, "dataType is missing", "entry skipped", owner)
        return None

    def access(self, node: Node, owner: Optional[int], param: Optional[Node]) -> str:
        text = node.get("accessType") or node.get("accessUSDO")
        if text is None and param is not None and param.get("access"):
            text = _PARAMETER_ACCESS.get((param.get("access") or "").lower())
            if text is None:
                raise self.fail(node, f"parameter access {param.get('access')!r} has no "
                                      f"CANopen access type", owner)
        if not text:
            self.warn(node, "accessType is missing; taken as ro", owner)
            return "ro"
        lowered = text.strip().lower()
        if lowered not in ACCESS_TYPES:
            self.deviate(node, f"access type {text!r} is not one of "
                               f"{', '.join(ACCESS_TYPES)}", "taken as ro", owner)
            return "ro"
        return lowered

    def pdo(self, node: Node, owner: Optional[int]) -> Optional[str]:
        text = node.get("PDOmapping")
        if text is not None:
            table, key = _PDO_311, text.strip().lower()
        else:
            text = node.get("accessPDO")
            if text is None:
                return None
            table, key = _PDO_FD, text.strip().lower()
        if key not in table:
            self.deviate(node, f"PDO mapping {text!r} is not one of "
                               f"{', '.join(k for k in table if k)}", "taken as no", owner)
            return None
        return table[key]

    def variable(self, node: Node, index: int, subindex: int, name: str,
                 owner: Optional[int], inherited: Optional[DataType] = None
                 ) -> Optional[ODVariable]:
        """An entry; None when it is skipped (a recorded deviation)."""
        param = self.parameters.get(node.get("uniqueIDRef") or "")
        dtype = self.data_type(node, owner, param, inherited)
        if dtype is None:
            return None
        try:
            var = ODVariable(name, index, subindex, dtype, self.access(node, owner, param))
        except OdValueError as exc:
            raise self.fail(node, exc.problem, owner) from None
        pdo = self.pdo(node, owner)
        if pdo is not None:
            var.pdo_mappable = True if pdo == "auto" else pdo
        for attr, setter in (("lowLimit", "low_limit"), ("highLimit", "high_limit")):
            text = self.attr(node, attr, param)
            if text is None or not text.strip():
                continue
            if not dtype.is_numeric:
                self.warn(node, f"{attr} ignored: {dtype.name} has no order", owner)
                continue
            if "$" in text:
                self.warn(node, f"{attr} {text!r} depends on the node-id; ignored", owner)
                continue
            self.lenient_value(node, owner, attr, text, dtype, "limit dropped",
                               lambda value, _r, _t: setattr(var, setter, value))
        for attr, store in (("defaultValue", var.set_default), ("actualValue", var.set_value)):
            text = self.attr(node, attr, param)
            if text is None:
                continue
            self.lenient_value(node, owner, attr, text, dtype,
                               "no default (the type's zero)" if attr == "defaultValue"
                               else "no configured value", store)
        # stripped like every EDS value, so an EDS export reads back the same
        var.denotation = (node.get("denotation") or "").strip()
        var.unit = (node.get("unit") or "").strip()
        try:
            flags = self.dec_attr(node, "objFlags", owner)
        except OdFileError as exc:
            self.deviate(node, exc.problem, "taken as 0", owner)
            flags = 0
        if flags is not None and not 0 <= flags <= 0xFFFFFFFF:
            self.deviate(node, f"objFlags {flags} outside 0..0xFFFFFFFF (32 bits)",
                         "taken as 0", owner)
            flags = 0
        var.obj_flags = flags or 0
        return var

    def lenient_value(self, node: Node, owner: Optional[int], attr: str, text: str,
                      dtype: DataType, instead: str,
                      setter: Callable[[Optional[Value], bool, str], object]) -> None:
        """Parse `text` and hand it to `setter(value, relative, text)`; a value
        that does not parse or fit is a deviation: dropped unless strict."""
        try:
            value, relative = parse_value(dtype, text)
            if value is None and not text.strip():
                return  # defaultValue="" on a number: no value
            setter(value, relative, text.strip())
        except OdValueError as exc:
            self.deviate(node, f"{attr} {text[:40]!r}: {exc.problem}", instead, owner)


def _describe(node: Node, owner: Optional[int]) -> str:
    if node.get("subIndex") is not None:
        text = f'<{node.tag} subIndex="{node.get("subIndex")}">'
        return f"{text} of {format_index(owner)}" if owner is not None else text
    if node.get("index") is not None:
        return f'<{node.tag} index="{node.get("index")}">'
    return f"<{node.tag}>"


def _parameter_item(param: Node, name: str) -> Optional[str]:
    lowered = name.lower()
    if lowered in ("defaultvalue", "actualvalue"):
        child = param.find(name)
        return child.get("value") if child is not None else None
    if lowered in ("lowlimit", "highlimit"):
        child = param.find("minValue" if lowered == "lowlimit" else "maxValue")
        return child.get("value") if child is not None else None
    return None


# ------------------------------------------------------------------ import
def import_xdd(source: Source, node_id: Optional[int] = None,
               mode: Optional[str] = None, strict: bool = False) -> ObjectDictionary:
    """An ObjectDictionary from an XDD or XDC file (path or open file).

    `node_id` resolves $NODEID (default: the XDC's deviceCommissioning
    nodeID); `mode` overrides the guess ('fd' for the CiA 1311 dialect or
    when 0x1000 is an ARRAY / 0x1030 exists, else 'classic'). Lenient unless
    `strict` (see the module docstring)."""
    data, name = read_source(source)
    return xdd_from_text(data, name, node_id, mode, strict)


def xdd_from_text(data: Union[bytes, str], name: str, node_id: Optional[int] = None,
                  mode: Optional[str] = None, strict: bool = False) -> ObjectDictionary:
    """`import_xdd` of content already read (`name` is used in messages)."""
    root = parse_xml(data, name)
    reader = _Reader(name, root, strict)
    lists = list(root.iter(*_LISTS))
    if not lists:
        raise OdFileError("no CANopenObjectList (or CANopenFDObjectList) element: "
                          "not an XDD/XDC device description", name, root.line, f"<{root.tag}>")
    if len(lists) > 1:
        reader.warn(lists[1], "a second object list is ignored")
    object_list = lists[0]
    od = ObjectDictionary()
    od.source = name
    body = _owner_body(root, object_list)
    if body is not None:
        for attr, key in (("fileName", "FileName"), ("fileCreator", "CreatedBy"),
                          ("fileCreationDate", "CreationDate"), ("fileVersion", "FileVersion")):
            text = body.get(attr)
            if text:
                od.file_info[key] = text
    _read_identity(root, od)
    _read_commissioning(reader, root, od, node_id)
    _read_dummies(root, od)
    for node in object_list.children:
        if node.tag not in _OBJECTS:
            continue
        obj = _read_object(reader, node)
        if obj is None:
            continue
        if obj.index in od.indices:
            reader.deviate(node, f"object {format_index(obj.index)} is defined twice",
                           "the first one is used")
            continue
        od.add_object(obj)
    fd_dialect = object_list.tag == "CANopenFDObjectList"
    od.mode = mode if mode is not None else (
        "fd" if fd_dialect or isinstance(od.indices.get(0x1000), ODArray)
        or 0x1030 in od.indices else "classic")
    od.load_warnings = reader.warnings
    commissioned = root.find("deviceCommissioning") is not None or any(
        var.value_base is not None for var in od.entries())
    od.source_format = "XDC" if name.lower().endswith(".xdc") or commissioned else "XDD"
    return od


def _owner_body(root: Node, target: Node) -> Optional[Node]:
    for body in root.iter("ProfileBody"):
        if any(node is target for node in body.iter(*_LISTS)):
            return body
    return None


def _read_identity(root: Node, od: ObjectDictionary) -> None:
    identity = root.find("DeviceIdentity")
    if identity is None:
        return
    for tags, key in ((("vendorName", "vendorInfo"), "VendorName"),
                      (("vendorID",), "VendorNumber"),
                      (("productName", "deviceName"), "ProductName"),
                      (("productID", "productCode"), "ProductNumber"),
                      (("revisionNumber",), "RevisionNumber"),
                      (("orderNumber",), "OrderCode")):
        for tag in tags:
            text = identity.child_text(tag)
            if text:
                od.device_info[key] = text
                break
    for node in root.iter("supportedBaudRate"):
        rate = _bitrate(node.get("value") or "")
        if rate:
            od.device_info[f"BaudRate_{rate // 1000}"] = "1"


def _bitrate(text: str) -> Optional[int]:
    """'250 Kbps' -> 250000, '1 Mbps' -> 1000000, '500/2000 kbps' -> 500000;
    None for no rate or one outside 1 bit/s..1 Gbit/s (what an EDS can hold:
    Baudrate is in kbit/s, at most 1000000)."""
    match = _RATE_RE.match(text)
    if not match or len(match.group(1)) > 20:
        return None
    number = float(match.group(1))
    unit = (match.group(2) or "").lower()
    scale = 1000 if unit == "k" else 1_000_000 if unit == "m" else 1
    rate = number * scale
    return int(rate) if 1 <= rate <= _MAX_BITRATE else None


def _read_commissioning(reader: _Reader, root: Node, od: ObjectDictionary,
                        node_id: Optional[int]) -> None:
    node = root.find("deviceCommissioning")
    if node is not None:
        # in the EDS [DeviceComissioning] key names; NodeID and Baudrate below,
        # only when valid, in EDS notation (a DCF export must read back)
        for attr, key in (("nodeName", "NodeName"), ("networkNumber", "NetNumber"),
                          ("networkName", "NetworkName"), ("CANopenManager", "CANopenManager")):
            text = node.get(attr)
            if text is not None:
                od.device_commissioning[key] = text
        text = node.get("nodeID")
        if text and text.strip():
            try:
                xdc_node = parse_int(text)
            except OdValueError as exc:
                raise reader.fail(node, f"nodeID: {exc.problem}") from None
            if 1 <= xdc_node <= 127:
                od.device_commissioning["NodeID"] = str(xdc_node)
                if node_id is None:
                    node_id = xdc_node
            else:
                reader.warn(node, f"nodeID {xdc_node} is not a node-id 1..127; ignored")
        rate_text = node.get("actualBaudRate") or ""
        od.bitrate = _bitrate(rate_text)
        if od.bitrate is None and rate_text.strip():
            reader.warn(node, f"actualBaudRate {rate_text[:30]!r} is not a bit rate of "
                              f"1 bit/s..1 Gbit/s; ignored")
        elif od.bitrate is not None:
            od.device_commissioning["Baudrate"] = str(od.bitrate // 1000)
    od.node_id = node_id


def _read_dummies(root: Node, od: ObjectDictionary) -> None:
    for node in root.iter("dummy"):
        match = re.fullmatch(r"\s*Dummy([0-9A-Fa-f]{4})\s*=\s*1\s*", node.get("entry") or "")
        if match and 1 <= int(match.group(1), 16) <= 7:
            od.dummy_usage.add(int(match.group(1), 16))


def _read_object(reader: _Reader, node: Node) -> Optional[ODObject]:
    index = reader.hex_attr(node, "index", 0xFFFF, None)
    if index is None or index == 0:
        raise reader.fail(node, "index is missing" if index is None else "index 0 is not valid")
    name = node.get("name")
    if not name or not name.strip():
        raise reader.fail(node, "name is missing")
    object_type = reader.dec_attr(node, "objectType", None)
    if object_type is None:
        object_type = ObjectType.VAR
    if object_type not in (ObjectType.VAR, ObjectType.ARRAY, ObjectType.RECORD,
                           ObjectType.DOMAIN):
        reader.deviate(node, f"objectType {object_type} is not VAR (7), ARRAY (8), "
                             f"RECORD (9) or DOMAIN (2)", "object skipped")
        return None
    subs = [child for child in node.children if child.tag in _SUBS]
    if len(subs) > _MAX_SUBS:
        raise reader.fail(node, f"{len(subs)} sub-objects; at most {_MAX_SUBS} sub-indices exist")
    number = reader.dec_attr(node, "subNumber", None)
    if number is not None and number > _MAX_SUBS:
        raise reader.fail(node, f"subNumber {number} is more than {_MAX_SUBS} sub-indices")
    if number is not None and number != len(subs):
        reader.warn(node, f"subNumber={number} but {len(subs)} sub-objects are given")
    own_type = _own_type(node)
    if object_type in (ObjectType.VAR, ObjectType.DOMAIN):
        if not subs:
            return reader.variable(node, index, 0, name.strip(), None,
                                   DataType.DOMAIN if object_type == ObjectType.DOMAIN else None)
        if len(subs) == 1 and reader.hex_attr(subs[0], "subIndex", 0xFF, index) == 0:
            var = reader.variable(subs[0], index, 0, name.strip(), index, own_type)
            return var
        if object_type == ObjectType.DOMAIN:
            raise reader.fail(node, "a DOMAIN object has no sub-objects")
    if not subs:
        raise reader.fail(node, "an ARRAY/RECORD object needs sub-objects")
    entries: Dict[int, ODVariable] = {}
    skipped: Set[int] = set()
    for sub_node in subs:
        sub = reader.hex_attr(sub_node, "subIndex", 0xFF, index)
        if sub is None:
            raise reader.fail(sub_node, "subIndex is missing", index)
        if sub in entries or sub in skipped:
            reader.deviate(sub_node, f"sub-index {sub} is defined twice",
                           "the first one is used", index)
            continue
        sub_name = sub_node.get("name")
        if not sub_name or not sub_name.strip():
            sub_name = f"sub{sub}"
            reader.deviate(sub_node, "name is missing", f"named {sub_name!r}", index)
        entry = reader.variable(sub_node, index, sub, sub_name.strip(), index,
                                own_type if sub else None)
        if entry is None:
            skipped.add(sub)
        else:
            entries[sub] = entry
    if not entries:
        reader.deviate(node, "no usable sub-objects", "object skipped")
        return None
    if object_type == ObjectType.VAR:  # CiA 1311 files: infer from the elements
        elements = {var.data_type for sub, var in entries.items() if sub >= 1}
        object_type = ObjectType.ARRAY if own_type is not None and elements == {own_type} \
            else ObjectType.RECORD
    count = entries.get(0)
    if count is not None and count.data_type != DataType.UNSIGNED8:
        # a value in sub-index 0, where the UNSIGNED8 count belongs (as the EDS reader)
        sub0_node = next(sub_node for sub_node in subs
                         if reader.hex_attr(sub_node, "subIndex", 0xFF, index) == 0)
        problem = (f"sub-index 0 of {format_index(index)} is {count.data_type.name}, not the "
                   f"UNSIGNED8 count of an ARRAY/RECORD")
        if len(entries) == 1:
            reader.deviate(sub0_node, problem, f"served as a VAR {format_index(index)} named "
                                               f"{count.name!r}", index)
            return count
        reader.deviate(sub0_node, problem, f"replaced by 'Highest sub-index supported' "
                                           f"(ro, {max(entries)})", index)
        entries[0] = ODVariable("Highest sub-index supported", index, 0, DataType.UNSIGNED8,
                                "ro", max(entries))
    container = ODArray(name.strip(), index) if object_type == ObjectType.ARRAY \
        else ODRecord(name.strip(), index)
    for sub in sorted(entries):
        container.add_member(entries[sub])
    return container


def _own_type(node: Node) -> Optional[DataType]:
    """The object's own dataType when it is a basic CiA 301 type."""
    text = node.get("dataType")
    if not text:
        return None
    try:
        return DataType(int(text.strip().removeprefix("0x").removeprefix("0X"), 16))
    except ValueError:
        return None
