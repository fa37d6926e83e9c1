"""Lenient import of EDS/DCF/XDD/XDC files, strict check (issue 14 item 1).

The default import recovers slips whose intent is clear and lists each one in
`od.load_warnings` (severity "error": what `strict=True` and `canopenfd od
check` refuse), naming the file path as given and the line. Every quirk gets a
small inline file here; tests/test_od_corpus.py loads real vendor files.
"""

from __future__ import annotations

import io
import os

import pytest

from canopenfd.od import DataType, ODArray, ODRecord, OdFileError, import_eds, import_od
from canopenfd.od import import_xdd

from test_od_eds import BROKEN_FILES as BROKEN_EDS
from test_od_xdd import BROKEN_FILES as BROKEN_XDD

HEAD = "[DeviceInfo]\nVendorName=x\n"
VAR_2000 = "[2000]\nParameterName=A\nDataType=0x0005\nAccessType=rw\n"


def write(tmp_path, text, name="vendor.eds"):
    path = tmp_path / name
    path.write_bytes(text.encode("utf-8"))
    return str(path)


def recovered(od):
    """The deviations the lenient import recovered (strict would refuse them)."""
    return [str(p) for p in od.load_warnings if p.is_error]


def one_deviation(od, path, line, *words):
    """Exactly one recovered deviation; it names path:line and holds `words`."""
    found = recovered(od)
    assert len(found) == 1, found
    assert f"error: {path}:{line} " in found[0], found[0]
    for word in words:
        assert word in found[0], found[0]
    return found[0]


def strict_refuses(path, line, *words, reader=import_od):
    with pytest.raises(OdFileError) as info:
        reader(path, strict=True)
    assert (info.value.file, info.value.line) == (path, line)
    for word in words:
        assert word in str(info.value), str(info.value)


# ------------------------------------------------------------------ object lists
def test_supported_objects_count_below_the_keys(tmp_path):
    # python-canopen's e35.eds kind: SupportedObjects=3, keys 1 and 2 only
    path = write(tmp_path, HEAD + "[ManufacturerObjects]\nSupportedObjects=3\n1=0x2000\n"
                 "2=0x2001\n" + VAR_2000 + VAR_2000.replace("2000", "2001"))
    od = import_eds(path)
    assert sorted(od) == [0x2000, 0x2001]
    one_deviation(od, path, 4, "[ManufacturerObjects]", "SupportedObjects=3 but key 3 is missing",
                  "the 2 numbered keys present are used")
    strict_refuses(path, 4, "key 3 is missing")


def test_supported_objects_count_above_the_keys(tmp_path):
    # python-canopen's sample.eds: SupportedObjects=0 followed by 1=0x2000
    path = write(tmp_path, HEAD + "[ManufacturerObjects]\nSupportedObjects=0\n1=0x2000\n"
                 + VAR_2000)
    od = import_eds(path)
    one_deviation(od, path, 5, "SupportedObjects=0 but key 1 is present")
    assert not any("in no object list" in str(p) for p in od.load_warnings)
    strict_refuses(path, 5, "key 1 is present")


def test_listed_object_without_section(tmp_path):
    path = write(tmp_path, HEAD + "[OptionalObjects]\nSupportedObjects=1\n1=0x1017\n")
    od = import_od(path)
    assert len(od) == 0
    one_deviation(od, path, 5, "0x1017 is listed but has no [1017] section", "ignored")
    strict_refuses(path, 5, "0x1017 is listed")


def test_list_entry_that_names_no_index(tmp_path):
    path = write(tmp_path, HEAD + "[ManufacturerObjects]\nSupportedObjects=2\n1=0x2000\n2=\n"
                 + VAR_2000)
    od = import_eds(path)
    assert sorted(od) == [0x2000]
    one_deviation(od, path, 6, "entry 2 names no object index", "entry ignored")


# ------------------------------------------------------------------ data types
@pytest.mark.parametrize("code", ["0x0040", "0x005F", "0x0099", "0x0020"])
def test_unknown_data_type_is_served_as_octet_string(tmp_path, code):
    # python-canopen's sample.eds has DataType=0x40 with DefaultValue=0x0
    path = write(tmp_path, HEAD + f"[2020]\nParameterName=Complex\nObjectType=0x7\n"
                 f"DataType={code}\nAccessType=rw\nDefaultValue=01 02 03\nLowLimit=0x3\n")
    od = import_eds(path)
    var = od[0x2020]
    assert var.data_type == DataType.OCTET_STRING and var.default == b"\x01\x02\x03"
    message = one_deviation(od, path, 6, f"DataType 0x{int(code, 16):04X} is not a CiA 301",
                            "served as OCTET_STRING")
    assert ("complex type" in message) == (int(code, 16) >= 0x40)
    assert any(f"{path}:9" in str(p) and "LowLimit ignored: the data type is unknown" in str(p)
               for p in od.load_warnings)
    strict_refuses(path, 6, "is not a CiA 301 data type")


def test_unknown_data_type_with_integer_default_keeps_no_default(tmp_path):
    path = write(tmp_path, HEAD + "[2020]\nParameterName=Complex\nDataType=0x40\n"
                 "AccessType=rw\nDefaultValue=0x0\n")
    od = import_eds(path)
    assert od[0x2020].default_base is None
    found = recovered(od)
    assert len(found) == 2
    assert f"{path}:5 " in found[0] and "served as OCTET_STRING" in found[0]
    assert f"{path}:7 " in found[1] and "DefaultValue '0x0'" in found[1] \
        and "no default" in found[1]


@pytest.mark.parametrize("body, line, words", [
    (VAR_2000.replace("0x0005", "UNSIGNED8"), 5, ["DataType: 'UNSIGNED8' is not an integer"]),
    (VAR_2000.replace("DataType=0x0005\n", ""), 3, ["DataType is missing"]),
    (VAR_2000.replace("0x0005", "0x123456"), 5, ["DataType 0x123456 is not a CiA 301"]),
])
def test_unknowable_data_type_skips_the_entry(tmp_path, body, line, words):
    path = write(tmp_path, HEAD + body + "[2001]\nParameterName=B\nDataType=0x0006\n"
                 "AccessType=ro\n")
    od = import_eds(path)
    assert 0x2000 not in od and od[0x2001].data_type == DataType.UNSIGNED16
    one_deviation(od, path, line, *words, "entry skipped")
    strict_refuses(path, line, *words)


def test_record_sub_with_unknowable_type_is_skipped_alone(tmp_path):
    path = write(tmp_path, HEAD + "[2000]\nParameterName=R\nObjectType=0x9\nSubNumber=2\n"
                 "[2000sub0]\nParameterName=n\nDataType=0x0005\nAccessType=ro\nDefaultValue=1\n"
                 "[2000sub1]\nParameterName=x\nDataType=bogus\nAccessType=rw\n")
    od = import_eds(path)
    assert isinstance(od[0x2000], ODRecord) and sorted(od[0x2000]) == [0]
    one_deviation(od, path, 14, "[2000sub1]", "entry skipped")


def test_array_without_usable_members_is_skipped(tmp_path):
    # python-canopen's sample.eds: [3003] ObjectType=0x8 with no sub-objects
    path = write(tmp_path, HEAD + "[3003]\nParameterName=Valve\nObjectType=0x8\n"
                 "DataType=0x0008\nAccessType=rw\nDefaultValue=\n" + VAR_2000)
    od = import_eds(path)
    assert sorted(od) == [0x2000]
    assert any(f"{path}:3 [3003]" in p and "without usable sub-objects; object skipped" in p
               for p in recovered(od))


# ------------------------------------------------------------------ values
@pytest.mark.parametrize("dtype, text, words", [
    ("0x000F", "@ABCD", ["'@ABCD' is not hex bytes"]),          # python-canopen datatypes.eds
    ("0x000A", "ABC", ["odd number of hex digits"]),
    ("0x0005", "abc", ["'abc' is not an integer"]),
    ("0x0005", "300", ["300 outside UNSIGNED8"]),
    ("0x0005", "089", ["octal"]),
    ("0x0008", "1,5", ["not a decimal number for REAL32"]),
    ("0x0008", "$NODEID+1", ["$NODEID works only with integer types"]),
])
def test_default_that_does_not_parse_is_dropped(tmp_path, dtype, text, words):
    path = write(tmp_path, HEAD + f"[2000]\nParameterName=A\nDataType={dtype}\n"
                 f"AccessType=rw\nDefaultValue={text}\n")
    od = import_eds(path)
    assert od[0x2000].default_base is None
    one_deviation(od, path, 7, "[2000]", "DefaultValue", *words, "no default")
    strict_refuses(path, 7, *words)


def test_limit_and_parameter_value_that_do_not_parse_are_dropped(tmp_path):
    path = write(tmp_path, HEAD + VAR_2000 + "LowLimit=x1\nHighLimit=200\nParameterValue=999\n")
    od = import_od(path)
    var = od[0x2000]
    assert var.low_limit is None and var.high_limit == 200 and var.value_base is None
    found = recovered(od)
    assert len(found) == 2
    assert f"{path}:7 [2000]: LowLimit 'x1'" in found[0] and "limit dropped" in found[0]
    assert f"{path}:9 [2000]: ParameterValue '999'" in found[1]
    assert "no configured value" in found[1]


def test_compact_value_that_does_not_parse_is_dropped(tmp_path):
    path = write(tmp_path, HEAD + "[2000]\nParameterName=A\nObjectType=0x8\nDataType=0x0005\n"
                 "AccessType=ro\nCompactSubObj=2\n[2000Value]\nNrOfEntries=2\n1=7\n2=0xZZ\n")
    od = import_eds(path)
    assert isinstance(od[0x2000], ODArray)
    assert od[0x2000][1].default == 7 and od[0x2000][2].default_base is None
    one_deviation(od, path, 12, "[2000Value]", "'0xZZ'")


# ------------------------------------------------------------------ keys
@pytest.mark.parametrize("key, text, line, words, check", [
    ("AccessType", "readonly", 6, ["AccessType 'readonly'", "taken as ro"],
     lambda var: var.access_type == "ro"),
    ("PDOMapping", "7", 7, ["PDOMapping must be 0 or 1", "taken as 0"],
     lambda var: not var.pdo_mapping),
    ("Factor", "1,5", 7, ["Factor '1,5' is not a number", "taken as 1"],
     lambda var: var.factor == 1),
    ("ObjFlags", "lots", 7, ["ObjFlags", "taken as 0"], lambda var: var.obj_flags == 0),
])
def test_key_that_does_not_parse_is_replaced(tmp_path, key, text, line, words, check):
    body = VAR_2000.replace("AccessType=rw", "AccessType=readonly") if key == "AccessType" \
        else VAR_2000 + f"{key}={text}\n"
    path = write(tmp_path, HEAD + body)
    od = import_eds(path)
    assert check(od[0x2000])
    one_deviation(od, path, line, *words)
    strict_refuses(path, line, words[0])


def test_sub_object_without_name(tmp_path):
    path = write(tmp_path, HEAD + "[2000]\nParameterName=R\nObjectType=0x9\n"
                 "[2000sub0]\nDataType=0x0005\nAccessType=ro\nDefaultValue=0\n")
    od = import_eds(path)
    assert od[0x2000][0].name == "sub0"
    one_deviation(od, path, 6, "ParameterName is missing", "named 'sub0'")


def test_sub_object_with_the_records_object_type(tmp_path):
    # a generator that writes the record's ObjectType=0x09 into every sub-object
    path = write(tmp_path, HEAD + "[2000]\nParameterName=R\nObjectType=0x09\n"
                 "[2000sub0]\nParameterName=n\nObjectType=0x09\nDataType=0x05\nAccessType=ro\n"
                 "DefaultValue=0\n")
    od = import_eds(path)
    assert od[0x2000][0].data_type == DataType.UNSIGNED8
    one_deviation(od, path, 8, "[2000sub0]", "ObjectType 0x9 where a VAR", "taken as VAR")
    strict_refuses(path, 8, "ObjectType 0x9")


def test_value_in_sub0_of_a_record(tmp_path):
    # python-canopen's sample.eds [3010Sub0] (REAL32) and node-canopen's
    # test/sample.eds (VISIBLE_STRING): alone it becomes the object's VAR...
    path = write(tmp_path, HEAD + "[3010]\nParameterName=Raw\nObjectType=0x9\nSubNumber=1\n"
                 "[3010Sub0]\nParameterName=Temperature\nDataType=0x0008\nAccessType=ro\n"
                 "DefaultValue=1.5\n")
    od = import_eds(path)
    assert od[0x3010].name == "Temperature" and od[0x3010].default == 1.5
    one_deviation(od, path, 7, "[3010Sub0]", "sub-index 0 of 0x3010 is REAL32",
                  "served as a VAR 0x3010")
    strict_refuses(path, 7, "sub-index 0 of 0x3010 is REAL32")
    # ...next to other entries a real count replaces it
    path = write(tmp_path, HEAD + "[3011]\nParameterName=R\nObjectType=0x9\n"
                 "[3011sub0]\nParameterName=v\nDataType=0x0007\nAccessType=rw\n"
                 "[3011sub2]\nParameterName=w\nDataType=0x0006\nAccessType=rw\n"
                 "DefaultValue=9\n", "other.eds")
    od = import_eds(path)
    count = od[0x3011][0]
    assert (count.data_type, count.access_type, count.default) == (DataType.UNSIGNED8, "ro", 2)
    assert od[0x3011][2].default == 9
    one_deviation(od, path, 6, "sub-index 0 of 0x3011 is UNSIGNED32",
                  "replaced by 'Highest sub-index supported' (ro, 2)")


def test_empty_parameter_value_configures_nothing(tmp_path):
    path = write(tmp_path, HEAD + "[1008]\nParameterName=Name\nDataType=0x0009\n"
                 "AccessType=ro\nDefaultValue=Power Node\nParameterValue=\n", "node.dcf")
    od = import_od(path)
    assert od[0x1008].value_base is None and od[0x1008].default == "Power Node"
    assert recovered(od) == []


def test_missing_optional_keys_are_plain_warnings(tmp_path):
    path = write(tmp_path, "[2000]\nParameterName=A\nDataType=0x0007\n")
    od = import_eds(path)
    assert od[0x2000].access_type == "ro" and od[0x2000].default_base is None
    assert recovered(od) == []
    texts = [str(p) for p in od.load_warnings]
    assert any(t.startswith(f"warning: {path}:1 [2000]: AccessType is missing") for t in texts)
    assert any("[DeviceInfo] is missing" in t for t in texts)


def test_duplicate_keys_and_sections(tmp_path):
    path = write(tmp_path, HEAD + VAR_2000 + "AccessType=ro\n[2000]\nDefaultValue=3\n")
    od = import_eds(path)
    assert od[0x2000].access_type == "ro" and od[0x2000].default == 3
    texts = [str(p) for p in od.load_warnings]
    assert any(f"{path}:7 [2000]: duplicate key AccessType (also at line 6)" in t for t in texts)
    assert any(f"{path}:8 [2000]: section [2000] appears again" in t for t in texts)


def test_duplicate_sub_sections_keep_the_first(tmp_path):
    path = write(tmp_path, HEAD + "[2000]\nParameterName=R\nObjectType=0x9\n"
                 "[2000sub1]\nParameterName=a\nDataType=0x0005\nAccessType=rw\n"
                 "[2000sub01]\nParameterName=b\nDataType=0x0005\nAccessType=rw\n")
    od = import_eds(path)
    assert od[0x2000][1].name == "a"
    one_deviation(od, path, 10, "[2000sub01]", "defined twice", "the first one is used")


def test_orphan_sub_sections_and_extras_are_ignored(tmp_path):
    path = write(tmp_path, HEAD + VAR_2000 + "[3000sub1]\nParameterName=B\n"
                 "[3001Name]\nNrOfEntries=1\n1=x\n")
    od = import_eds(path)
    assert sorted(od) == [0x2000]
    found = recovered(od)
    assert len(found) == 2
    assert f"{path}:9 [3001Name]: belongs to 0x3001" in found[0]
    assert f"{path}:7 [3000sub1]: sub-object of 0x3000" in found[1]


def test_broken_object_links_are_dropped(tmp_path):
    path = write(tmp_path, HEAD + VAR_2000 + VAR_2000.replace("2000", "2001")
                 + "[2000ObjectLinks]\nObjectLinks=3\n1=0x2001\n2=0x2000\n"
                 + "[2001ObjectLinks]\nObjectLinks=1\n1=0x2000\n")
    od = import_eds(path)
    assert od[0x2000].object_links == [] and od[0x2001].object_links == []
    found = recovered(od)
    assert any(f"{path}:14 [2000ObjectLinks]: 0x2000 links to itself" in t for t in found)
    assert any(f"{path}:12 [2000ObjectLinks]: ObjectLinks=3 but key 3" in t for t in found)
    assert any("ObjectLinks form a cycle: 0x2000 -> 0x2001 -> 0x2000" in t for t in found)


def test_odd_spacing_comments_and_node_id_positions(tmp_path):
    path = write(tmp_path, "; written by hand\n# another comment\n\n  [DeviceInfo]  ; note\n"
                 "  VendorName =  x  \n[1800]\nParameterName=TPDO1\nObjectType=0x9\n"
                 "SubNumber=2\n[1800sub0]\nParameterName=n\nDataType=0x0005\nAccessType=ro\n"
                 "DefaultValue = 2 ; two entries\n[1800sub1]\nParameterName=COB-ID\n"
                 "DataType=0x0007\nAccessType=rw\nDefaultValue=0x180 + $NODEID\n[1800sub2]\n"
                 "ParameterName=type\nDataType=0x0005\nAccessType=rw\nDefaultValue=\t254\n"
                 "[1014]\nParameterName=EMCY\nDataType=0x0007\nAccessType=ro\n"
                 "DefaultValue=$NODEID+0x80\n[1200]\nParameterName=SDO\nObjectType=0x9\n"
                 "[1200sub0]\nParameterName=n\nDataType=0x0005\nAccessType=ro\nDefaultValue=1\n"
                 "[1200sub1]\nParameterName=rx\nDataType=0x0007\nAccessType=ro\n"
                 "DefaultValue=$nodeid\n")
    od = import_eds(path, node_id=5)
    assert recovered(od) == []
    assert od.device_info["VendorName"] == "x"
    assert od[0x1800][0].default == 2 and od[0x1800][2].default == 254
    assert od[0x1800][1].default == 0x185 and od[0x1014].default == 0x85
    assert od[0x1200][1].default == 5


def test_vendor_sections_are_read_around_with_a_warning(tmp_path):
    path = write(tmp_path, HEAD + "[VendorTuning]\nGain=7\n[Tools]\nTool1=x\n" + VAR_2000
                 + "VendorSpecialKey=1\n")
    od = import_eds(path)
    assert recovered(od) == [] and od[0x2000].name == "A"
    texts = [str(p) for p in od.load_warnings]
    assert any(f"warning: {path}:3 [VendorTuning]: section [VendorTuning] is not a CiA 306"
               in t for t in texts)
    assert not any("[Tools]" in t for t in texts)


def test_stray_lines_are_skipped(tmp_path):
    # a description that went on to a second line, a key before the first section
    path = write(tmp_path, "Generator=tool 1.2\n" + HEAD + VAR_2000
                 + "Description=first line\nsecond line of it\n")
    od = import_eds(path)
    assert od[0x2000].description == "first line" and od.device_info["VendorName"] == "x"
    found = recovered(od)
    assert len(found) == 2
    assert found[0].startswith(f"error: {path}:1: key 'Generator' before the first [section]")
    assert found[1].startswith(f"error: {path}:9 [2000]: expected key=value, a [section] or "
                               f"a ; comment, got 'second line of it'; line ignored")
    strict_refuses(path, 1, "before the first [section]")


def test_unrecoverable_files_are_still_refused_with_path_and_line(tmp_path):
    for text, line, words in (
            ("just some words\n", 1, "expected key=value"),
            ("; only a comment\nVendorName=x\n", 2, "before the first [section]"),
            (HEAD + VAR_2000 + "[2000sub1]\nParameterName=x\n", 7, "is a VAR"),
            (HEAD + "[1018]\nParameterName=I\nObjectType=0x9\n[1018sub100]\n", 6, "above 0xFF")):
        path = write(tmp_path, text)
        with pytest.raises(OdFileError) as info:
            import_eds(path)
        assert (info.value.file, info.value.line) == (path, line)
        assert words in str(info.value)


# ------------------------------------------------------------------ the old refusals
@pytest.mark.parametrize("text, words", BROKEN_EDS)
def test_every_strict_refusal_is_refused_or_named_when_lenient(text, words):
    """Each file test_od_eds.py refuses in strict mode is, by default, either
    refused the same way or loaded with a recorded deviation holding the same
    words (file and line included)."""
    try:
        od = import_eds(io.BytesIO(text.encode()))
    except OdFileError as exc:
        assert all(word in str(exc) for word in words), str(exc)
        return
    assert any(all(word in text for word in words) and text.startswith("error: <stream>:")
               for text in recovered(od)), recovered(od)


@pytest.mark.parametrize("data, words", BROKEN_XDD)
def test_every_strict_xdd_refusal_is_refused_or_named_when_lenient(data, words):
    try:
        od = import_xdd(io.BytesIO(data))
    except OdFileError as exc:
        assert all(word in str(exc) for word in words), str(exc)
        return
    assert any(all(word in text for word in words) and text.startswith("error: <stream>:")
               for text in recovered(od)), recovered(od)


# ------------------------------------------------------------------ XDD / XDC
def xdd(objects: str) -> str:
    return ('<?xml version="1.0" encoding="UTF-8"?>\n<ISO15745ProfileContainer>\n'
            f"<CANopenObjectList>\n{objects}\n</CANopenObjectList>\n"
            "</ISO15745ProfileContainer>\n")


def xdd_obj(index="2000", dtype="0005", access="rw", default="1", extra=""):
    return (f'<CANopenObject index="{index}" name="X" objectType="7" dataType="{dtype}" '
            f'accessType="{access}" defaultValue="{default}"{extra}/>')


@pytest.mark.parametrize("objects, words, check", [
    (xdd_obj(dtype="0040", default="0A0B"), ["dataType 0x0040", "served as OCTET_STRING"],
     lambda od: od[0x2000].data_type == DataType.OCTET_STRING
     and od[0x2000].default == b"\n\x0b"),
    (xdd_obj(dtype="zz"), ["dataType 'zz' is not a hex number", "entry skipped"],
     lambda od: 0x2000 not in od),
    (xdd_obj(default="300"), ["defaultValue '300'", "no default"],
     lambda od: od[0x2000].default_base is None),
    (xdd_obj(access="execute"), ["access type 'execute'", "taken as ro"],
     lambda od: od[0x2000].access_type == "ro"),
    (xdd_obj(extra=' PDOmapping="sometimes"'), ["PDO mapping 'sometimes'", "taken as no"],
     lambda od: not od[0x2000].pdo_mapping),
    (xdd_obj(extra=' objFlags="-5"'), ["objFlags -5 outside", "taken as 0"],
     lambda od: od[0x2000].obj_flags == 0),
    (xdd_obj(extra=' lowLimit="low"'), ["lowLimit 'low'", "limit dropped"],
     lambda od: od[0x2000].low_limit is None),
    ('<CANopenObject index="2000" name="A" objectType="3"/>', ["objectType 3", "object skipped"],
     lambda od: 0x2000 not in od),
])
def test_xdd_deviations_are_recovered_with_path_and_line(tmp_path, objects, words, check):
    path = write(tmp_path, xdd(objects), "vendor.xdd")
    od = import_od(path)
    assert check(od)
    one_deviation(od, path, 4, *words)
    strict_refuses(path, 4, words[0])


def test_xdd_repeated_object_and_sub_keep_the_first(tmp_path):
    record = ('<CANopenObject index="2001" name="R" objectType="9">\n'
              '<CANopenSubObject subIndex="00" name="a" dataType="0005" accessType="ro"/>\n'
              '<CANopenSubObject subIndex="00" name="b" dataType="0005" accessType="ro"/>\n'
              '<CANopenSubObject subIndex="01" dataType="0005" accessType="rw"/>\n'
              "</CANopenObject>")
    path = write(tmp_path, xdd(xdd_obj(default="1") + "\n" + xdd_obj(default="2") + "\n"
                               + record), "vendor.xdd")
    od = import_xdd(path)
    assert od[0x2000].default == 1 and od[0x2001][0].name == "a"
    assert od[0x2001][1].name == "sub1"
    found = recovered(od)
    assert len(found) == 3
    assert f"{path}:5 " in found[0] and "object 0x2000 is defined twice" in found[0]
    assert f"{path}:8 " in found[1] and "sub-index 0 is defined twice" in found[1]
    assert f"{path}:9 " in found[2] and "name is missing" in found[2]


# ------------------------------------------------------------------ od check
def test_od_check_lists_every_deviation_and_fails(tmp_path, capsys):
    from canopenfd.cli.od import main

    path = write(tmp_path, HEAD + "[ManufacturerObjects]\nSupportedObjects=3\n1=0x2000\n"
                 + VAR_2000 + "DefaultValue=abc\n[2001]\nParameterName=B\nDataType=0x0040\n"
                 "AccessType=rw\n")
    assert main(["check", path]) == 1
    out = capsys.readouterr().out
    assert f"error: {path}:4 [ManufacturerObjects]: SupportedObjects=3 but key 2" in out
    assert f"error: {path}:10 [2000]: DefaultValue 'abc'" in out
    assert f"error: {path}:13 [2001]: DataType 0x0040" in out
    assert "vendor.eds: FAILED: 3 errors" in out
    clean = write(tmp_path, HEAD + VAR_2000, "clean.eds")
    assert main(["check", clean]) == 0


def test_lenient_import_logs_each_recovered_deviation(tmp_path, caplog):
    path = write(tmp_path, HEAD + VAR_2000 + "DefaultValue=abc\n")
    with caplog.at_level("WARNING", logger="canopenfd.od"):
        import_od(path)
    assert [r.getMessage() for r in caplog.records] == [
        f"{path}:7 [2000]: DefaultValue 'abc': 'abc' is not an integer (decimal, 0x hex or "
        f"0 octal); no default (the type's zero)"]
    assert os.path.isabs(path)


# ------------------------------------------------------------------ README
def test_readme_lenient_import_block_runs(tmp_path):
    """README.md's lenient-import block, run as written from the repository
    root (tests/test_docs.py runs only pages whose blocks are whole scripts;
    README's other blocks are fragments, so this one is run here)."""
    import pathlib
    import re
    import subprocess
    import sys

    from helpers import package_env

    root = pathlib.Path(__file__).resolve().parent.parent
    text = (root / "README.md").read_text(encoding="utf-8")
    blocks = [b for b in re.findall(r"^```python\n(.*?)^```", text, re.S | re.M)
              if "strict=True" in b and "load_warnings" in b]
    assert len(blocks) == 1
    script = tmp_path / "block.py"  # run from a file: the installed package, not ./canopenfd
    script.write_text(blocks[0], encoding="utf-8")
    done = subprocess.run([sys.executable, str(script)], cwd=root, env=package_env(),
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    out = done.stdout
    assert "error: tests/data/vendor/pycanopen_sample.eds:845 [2020]: DataType 0x0040" in out
    assert ("strict: tests/data/vendor/pycanopen_sample.eds:790 [ManufacturerObjects]: "
            "SupportedObjects=0 but key 1 is present") in out


def test_xdd_value_in_sub0_is_repaired_and_exports_cleanly(tmp_path):
    # atheris (fuzz_xdd) finding: an XDD record with a VISIBLE_STRING sub 0 was
    # imported as is, so its EDS export was refused by the strict EDS reader
    from canopenfd.od import eds_from_text, export_eds

    record = ('<CANopenObject index="2000" name="R" objectType="9">\n'
              '<CANopenSubObject subIndex="00" name="Label" dataType="0009" accessType="rw" '
              'defaultValue="x"/>\n'
              '<CANopenSubObject subIndex="01" name="Out" dataType="0005" accessType="rw" '
              'defaultValue="3"/>\n'
              "</CANopenObject>")
    path = write(tmp_path, xdd(record), "vendor.xdd")
    od = import_xdd(path)
    assert od[0x2000][0].data_type == DataType.UNSIGNED8 and od[0x2000][0].default == 1
    assert od[0x2000][1].default == 3
    one_deviation(od, path, 5, "sub-index 0 of 0x2000 is VISIBLE_STRING",
                  "replaced by 'Highest sub-index supported' (ro, 1)")
    again = eds_from_text(export_eds(od), "again.eds", strict=True)
    assert again.diff(od) == []
    alone = write(tmp_path, xdd(record.replace(
        '<CANopenSubObject subIndex="01" name="Out" dataType="0005" accessType="rw" '
        'defaultValue="3"/>\n', "")), "alone.xdd")
    od = import_xdd(alone)
    assert od[0x2000].name == "Label" and od[0x2000].default == "x"


def test_two_keys_with_one_number_in_an_object_list(tmp_path):
    # found by CI's atheris run (fuzz_eds): "1" and "01" sorted as equal numbers
    # made the keys themselves compare (TypeError)
    path = write(tmp_path, HEAD + "[ManufacturerObjects]\nSupportedObjects=2\n1=0x2000\n"
                 "01=0x2001\n2=0x2002\n" + VAR_2000 + VAR_2000.replace("2000", "2001")
                 + VAR_2000.replace("2000", "2002"))
    od = import_eds(path)
    assert sorted(od) == [0x2000, 0x2001, 0x2002]
    found = recovered(od)
    assert any(f"{path}:6 " in text and "keys 1 and 01 both number entry 1" in text
               for text in found), found
    strict_refuses(path, 6, "keys 1 and 01 both number entry 1")
