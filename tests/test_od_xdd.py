"""XDD/XDC import (CiA 311 and the CiA 1311 CANopen FD layout), including hostile files."""

from __future__ import annotations

import io
import os
import time

import pytest

from canopenfd.od import (DataType, ODArray, ODRecord, ODVariable, OdFileError, import_od,
                          import_xdd)

DATA = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data", "od")
HOSTILE = os.path.join(DATA, "hostile")
FD_XDD = os.path.join(DATA, "fd_device.xdd")
XDC = os.path.join(DATA, "classic_node.xdc")


def fails_fast(source, *words, bound=30.0):
    # A bound against a hang or a blow-up, not a speed figure: generous, so a loaded
    # CI machine (one run took 5.5 s here at load average 10) does not fail it.
    start = time.monotonic()
    with pytest.raises(OdFileError) as info:
        import_xdd(source, strict=True)  # the lenient default: tests/test_od_lenient.py
    assert time.monotonic() - start < bound
    for word in words:
        assert word in str(info.value), str(info.value)
    return info.value


def xml(objects: str, list_tag: str = "CANopenObjectList") -> bytes:
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<ISO15745ProfileContainer>\n'
            f"<{list_tag}>\n{objects}\n</{list_tag}>\n</ISO15745ProfileContainer>\n").encode()


# ------------------------------------------------------------------ FD device
def test_fd_xdd_shapes_and_mode():
    od = import_xdd(FD_XDD)
    assert od.mode == "fd" and od.source_format == "XDD"
    assert [p for p in od.validate() if p.is_error] == []
    assert isinstance(od[0x1000], ODArray) and od[0x1000][2].default == 0x00020191
    assert isinstance(od[0x1017], ODVariable) and od[0x1017].high_limit == 60000
    assert isinstance(od[0x1018], ODRecord)  # dataType 0x23: identity record
    assert isinstance(od[0x1030], ODArray) and od[0x1030][1].default == 0x51500100
    history = od[0x1031]
    assert isinstance(history, ODRecord) and history[4].data_type == DataType.DOMAIN
    assert isinstance(od[0x1032], ODArray) and od[0x1032][0].default == 0
    assert od[0x1800][1].relative_to_node_id and od[0x1800][1].default_base == 0x40000180
    assert od[0x2000].data_type == DataType.VISIBLE_STRING and len(od[0x2000].default) == 128
    assert od.device_info == {"VendorName": "Acme GmbH", "VendorNumber": "0x000001A5",
                              "ProductName": "Acme FD Drive 7", "ProductNumber": "0x00FD0007",
                              "RevisionNumber": "0x00010002"}
    assert od.file_info["FileName"] == "acme_fd_drive.xdd" and od.dummy_usage == {2, 5}


def test_fd_xdd_64_byte_pdo_mappings():
    od = import_xdd(FD_XDD)
    for index in (0x1600, 0x1A00):
        mapping = od[index]
        count = mapping[0].default
        bits = 0
        for sub in range(1, count + 1):
            entry = mapping[sub].default
            target = od.get_variable(entry >> 16, (entry >> 8) & 0xFF)
            assert target is not None and target.size * 8 == entry & 0xFF
            assert target.pdo_mappable == ("rpdo" if index < 0x1800 else "tpdo")
            bits += entry & 0xFF
        assert bits == 64 * 8, hex(index)
    assert od[0x1600][0].high_limit == 64 and od[0x1001].pdo_mappable == "tpdo"


def test_node_id_and_mode_arguments():
    od = import_xdd(FD_XDD, node_id=4, mode="classic")
    assert od[0x1014].default == 0x84 and od.mode == "classic"
    assert any("must be a VAR of UNSIGNED32 on classic" in str(p) for p in od.validate())


# ------------------------------------------------------------------ classic XDC
def test_xdc_commissioning_actual_values_and_parameters():
    od = import_od(XDC)
    assert od.source_format == "XDC" and od.mode == "classic"
    assert od.node_id == 32 and od.bitrate == 250_000
    assert od.device_commissioning["NodeName"] == "valve_left"
    assert od.device_info["VendorName"] == "Acme Valves AB"
    assert od.device_info["BaudRate_125"] == "1" and od.device_info["BaudRate_1000"] == "1"
    assert od[0x1014].default == 0x80 + 32 and od[0x1014].value == 0xA0
    assert od[0x1017].value == 500 and od[0x1016][1].value == 0x000101F4
    assert od[0x1800][1].value == 0x180 + 32 and od[0x1800][2].value == 1
    # attributes taken from the uniqueIDRef parameter
    assert od[0x1000].data_type == DataType.UNSIGNED32 and od[0x1000].default == 0x191
    assert od[0x1000].access_type == "ro"
    valve = od[0x2001]
    assert (valve.data_type, valve.access_type, valve.low_limit, valve.high_limit) == \
        (DataType.INTEGER16, "rwr", -1000, 1000)
    assert valve.pdo_mappable == "tpdo" and valve.denotation == "Main valve"
    assert od[0x2002].pdo_mappable == "rpdo" and od[0x1001].pdo_mappable == "tpdo"
    assert [p for p in od.validate() if p.is_error] == []


def test_streams_and_sniffing(tmp_path):
    with open(FD_XDD, "rb") as handle:
        from_stream = import_xdd(handle)
    with open(FD_XDD, encoding="utf-8") as handle:
        from_text = import_xdd(handle)
    renamed = tmp_path / "device.xml-ish"
    renamed.write_bytes(open(FD_XDD, "rb").read())
    assert from_stream == from_text == import_od(str(renamed)) == import_od(FD_XDD)


def test_fd_layout_inference_rules():
    od = import_xdd(io.BytesIO(xml("""
      <CANopenFDDataObject index="2000" name="Plain" dataType="06" objectType="07">
        <CANopenFDDataElement subIndex="00" name="Plain" dataType="06"
          accessUSDO="rw" accessPDO="tr" defaultValue="7"/>
      </CANopenFDDataObject>
      <CANopenFDDataObject index="2001" name="Mixed" dataType="07" objectType="07">
        <CANopenFDDataElement subIndex="00" name="Count" dataType="05"
          accessUSDO="ro" defaultValue="2"/>
        <CANopenFDDataElement subIndex="01" name="A" dataType="07" accessUSDO="ro"/>
        <CANopenFDDataElement subIndex="02" name="B" dataType="06" accessUSDO="ro"/>
      </CANopenFDDataObject>
      <CANopenFDDataObject index="2002" name="Explicit" dataType="07" objectType="9">
        <CANopenFDDataElement subIndex="00" name="Count" dataType="05"
          accessUSDO="ro" defaultValue="1"/>
        <CANopenFDDataElement subIndex="01" name="A" accessUSDO="ro"/>
      </CANopenFDDataObject>""", "CANopenFDObjectList")))
    assert od.mode == "fd"
    assert isinstance(od[0x2000], ODVariable) and od[0x2000].pdo_mappable == "both"
    assert isinstance(od[0x2001], ODRecord)
    assert isinstance(od[0x2002], ODRecord) and od[0x2002][1].data_type == DataType.UNSIGNED32


# ------------------------------------------------------------------ hostile files
@pytest.mark.parametrize("name, words", [
    ("billion_laughs.xdd", ["billion_laughs.xdd:2", "DOCTYPE declarations are not allowed"]),
    ("external_entity.xdd", ["external_entity.xdd:2", "DOCTYPE"]),
    ("bad_datatype.xdd", ["bad_datatype.xdd:11", 'subIndex="02"', "of 0x1018",
                          "dataType 0x0099 is not a CiA 301 data type"]),
    ("huge_subnumber.xdd", ["huge_subnumber.xdd:4", 'index="1016"', "subNumber 100000000"]),
    ("invalid_utf8.xdd", ["invalid_utf8.xdd:4", "not well-formed XML"]),
    ("truncated.xdd", ["truncated.xdd:4", "not well-formed XML"]),
])
def test_hostile_files(name, words):
    fails_fast(os.path.join(HOSTILE, name), *words)


OBJ = ('<CANopenObject index="{index}" name="X" objectType="7" dataType="{dtype}" '
       'accessType="{access}" defaultValue="{default}"/>')


def obj(index="2000", dtype="0005", access="rw", default="1"):
    return OBJ.format(index=index, dtype=dtype, access=access, default=default)


BROKEN_FILES = [
    (b"", ["the file is empty"]),
    (b"\x00\x01\x02garbage\xff", ["<stream>:1", "not well-formed"]),
    (b"<a><b></a>", ["<stream>:1", "mismatched tag"]),
    (b"<a/>", ["no CANopenObjectList", "<a>"]),
    (b"<a>" * 1000 + b"</a>" * 1000, ["nested deeper than 64"]),
    (b"<a>" + b"<b/>" * 250_000 + b"</a>", ["more than 200000 XML elements"]),
    ('<?xml version="1.0" encoding="UTF-16"?><!DOCTYPE x [<!ENTITY a "b">]><a/>'
     .encode("utf-16"), ["DOCTYPE"]),
    (b'<a><!ENTITY x "y"></a>', ["ENTITY declarations are not allowed"]),
    (b'<?xml version="1.0" encoding="UT5-8"?><a/>', ["unknown encoding"]),
    (xml(obj(index="XYZ")), [":4", 'index="XYZ"', "is not a hex number"]),
    (xml(obj(index="12345")), ["is above 0xFFFF"]),
    (xml(obj(dtype="0099")), [":4", "dataType 0x0099"]),
    (xml(obj(access="execute")), ["access type 'execute'"]),
    (xml(obj(default="300")), ["defaultValue '300'", "300 outside UNSIGNED8"]),
    (xml(obj(dtype="0007", default="$NODEID*2")), ["node-id expression"]),
    (xml(obj() + "\n" + obj()), [":5", "object 0x2000 is defined twice"]),
    (xml('<CANopenObject index="2000" name="A" objectType="3"/>'), ["objectType 3"]),
    (xml('<CANopenObject index="2000" name="R" objectType="9"/>'), ["needs sub-objects"]),
    (xml('<CANopenObject index="2000" name="R" objectType="9">' + "".join(
        f'<CANopenSubObject subIndex="{i % 256:02X}" name="s{i}" dataType="0005" '
        f'accessType="ro"/>' for i in range(300)) + "</CANopenObject>"),
     ["300 sub-objects"]),
    (xml('<CANopenObject index="2000" name="R" objectType="9">'
         '<CANopenSubObject subIndex="00" name="a" dataType="0005" accessType="ro"/>'
         '<CANopenSubObject subIndex="00" name="b" dataType="0005" accessType="ro"/>'
         "</CANopenObject>"), ["sub-index 0 is defined twice"]),
    (xml('<CANopenObject index="2000" name="V" objectType="7" accessType="rw"/>'),
     ["dataType is missing"]),
    (xml('<CANopenObject index="2000" objectType="7" dataType="0005"/>'), ["name is missing"]),
    (xml(obj(dtype="0007") + '<CANopenObject index="2001" name="P" objectType="7" '
         'dataType="0005" accessType="rw" PDOmapping="sometimes"/>'), ["PDO mapping 'sometimes'"]),
]


@pytest.mark.parametrize("data, words", BROKEN_FILES)
def test_broken_files_name_file_line_and_element(data, words):
    fails_fast(io.BytesIO(data), *words)


def test_file_size_cap(tmp_path):
    big = tmp_path / "big.xdd"
    with open(big, "wb") as handle:
        handle.write(b"<a>")
        handle.truncate(50 * 1024 * 1024)
    fails_fast(str(big), "big.xdd", "limited to 16 MiB")


# ------------------------------------------------------------------ fuzz findings
# Found by tests/fuzz/py (atheris) or the review around it.
def xdc(objects: str, extra: str) -> bytes:
    """An XDC whose object list is at line 4; `extra` (one line) at line 3."""
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<ISO15745ProfileContainer>\n{extra}\n'
            f"<CANopenObjectList>\n{objects}\n</CANopenObjectList>\n"
            f"</ISO15745ProfileContainer>\n").encode()


@pytest.mark.parametrize("flags", ["-5", "4294967296", "99999999999999"])
def test_fuzz_objflags_outside_32_bits(tmp_path, flags):
    # accepted before: the EDS export wrote ObjFlags=0x-5, which no reader takes
    path = tmp_path / "hostile.xdd"
    path.write_bytes(xml(obj().replace("/>", f' objFlags="{flags}"/>')))
    error = fails_fast(str(path), "hostile.xdd:4 ", 'index="2000"',
                       f"objFlags {int(flags)} outside 0..0xFFFFFFFF")
    assert (error.file, error.line) == (str(path), 4)


def test_fuzz_bit_rates_and_node_id_out_of_range_are_ignored():
    """A 400-digit bit rate raised OverflowError; a rate or node-id an EDS cannot
    hold reached the DCF export, which then could not be read back."""
    from canopenfd.od import eds_from_text, export_dcf

    for rate in ("9" * 400 + " kbps", "5000000 kbps", "0 kbps"):
        data = xdc(obj(), f'<supportedBaudRate value="{rate}"/>'
                          f'<deviceCommissioning nodeID="300" actualBaudRate="{rate}"/>')
        od = import_xdd(io.BytesIO(data))
        assert od.bitrate is None and od.node_id is None
        assert not any(key.startswith("BaudRate_") for key in od.device_info)
        warnings = " | ".join(str(w) for w in od.load_warnings)
        assert "<stream>:3 <deviceCommissioning>: nodeID 300 is not a node-id" in warnings
        assert "is not a bit rate of 1 bit/s..1 Gbit/s; ignored" in warnings
        again = eds_from_text(export_dcf(od), "again.dcf")
        assert again.bitrate is None and again.node_id is None and again.diff(od) == []
    od = import_xdd(io.BytesIO(xdc(obj(), '<deviceCommissioning nodeID="0x20" '
                                          'actualBaudRate="0.5 Mbps"/>')))
    assert od.device_commissioning == {"NodeID": "32", "Baudrate": "500"}
    again = eds_from_text(export_dcf(od), "again.dcf")
    assert (again.node_id, again.bitrate) == (32, 500_000)


def test_fuzz_denotation_and_unit_are_stripped_like_eds_values():
    from canopenfd.od import eds_from_text, export_eds

    od = import_xdd(io.BytesIO(xml(obj().replace("/>", ' denotation=" d " unit="u&#9;"/>'))))
    assert (od[0x2000].denotation, od[0x2000].unit) == ("d", "u")
    assert eds_from_text(export_eds(od), "again.eds").diff(od) == []


def test_fuzz_text_stream_with_lone_surrogates():
    # str.encode raised UnicodeEncodeError before expat saw the text
    error = fails_fast(io.StringIO('<a>\n<b x="\udcff"/></a>'), "<stream>:2",
                       "not well-formed XML")
    assert error.line == 2
