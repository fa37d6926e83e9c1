"""The seed 004 setup file: the seed's own example records read as the seed
explains them, the object dictionary built from a file, and broken files
(truncated, contradictory, duplicated, hostile) refused with file:line."""

from __future__ import annotations

import pathlib

import pytest
from processimage_helpers import section, setup_text

from canopenfd.od import DataType
from canopenfd.processimage.device_od import build_od
from canopenfd.processimage.setup_file import (SetupFileError, load_setup_file,
                                               parse_setup_text)


def test_the_seeds_node_example() -> None:
    # seed 004 §5.2.2: 125 kbit/s, node 40h, 32-byte image, 2 RPDOs, 2 TPDOs, checksum 68h
    text = setup_text(NODE=["044020020200"], RPDO=None, TPDO=None, RWOD=None,
                      PIMG=None, COD=None)
    assert "[NODE]\n044020020200\n68\n" in text.replace("[NODE ]", "[NODE]")
    with pytest.raises(SetupFileError, match=r"f.txt:\d+: \[NODE\] says 2 RPDOs but there is "
                                             r"no \[RPDO\] section"):
        parse_setup_text(text, "f.txt")


def test_the_seeds_tpdo_example_and_spaces_in_labels() -> None:
    # seed 004 §5.2.4, label written "[ TPDO ]", checksum B6h as the seed gives it
    rwod = [f"0060{sub:02X}51{sub - 1:02X}" for sub in range(1, 11)] + ["FFFFFFFFFF"]
    text = ("COPTSKA8\n[NODE ]\n04402002020" "0\n68\n"
            "[ RPDO ]\n0000FF\n0000FF\n0400010203FFFFFFFF\n020405FFFFFFFFFFFF\n09\n"
            "[ TPDO ]\n0000F401FA00FF\n0000C800E803FF\n020607FFFFFFFFFFFF\n"
            "020809FFFFFFFFFFFF\nB6\n" + section("RWOD", rwod))
    with pytest.raises(SetupFileError, match="not RPDO-mappable"):
        parse_setup_text(text, "seed.txt")     # the seed's [RWOD] maps 6000h read-only
    rwod = [f"0060{sub:02X}{0xF1 if sub <= 6 else 0x51:02X}{sub - 1:02X}"
            for sub in range(1, 11)] + ["FFFFFFFFFF"]
    text = text.rsplit("[RWOD]", 1)[0] + section("RWOD", rwod)
    setup = parse_setup_text(text, "seed.txt")
    first, second = setup.tpdos
    assert (first.inhibit_100us, first.event_ms, first.transmission_type) == (500, 250, 0xFF)
    assert (second.inhibit_100us, second.event_ms) == (200, 1000)
    assert [p.entries for p in setup.rpdos] == [[0, 1, 2, 3], [4, 5]]
    assert [p.entries for p in setup.tpdos] == [[6, 7], [8, 9]]


def test_the_small_device_and_its_dictionary() -> None:
    setup = parse_setup_text(setup_text(), "dev.txt")
    assert setup.ident == bytes.fromhex("34120201")
    assert setup.node is not None and setup.node.node_id == 0x40 and setup.node.bps == 4
    assert setup.image == bytes.fromhex("0011223344556677")
    od = build_od(setup)
    assert od[0x1000].default == 0x000F0191                 # [COD]
    var = od["0x6200:2"]
    assert (var.data_type, var.access_type, var.default) == (DataType.UNSIGNED8, "rww", 0x33)
    assert od["0x6000:1"].access_type == "ro"
    assert od["0x1600:1"].default == 0x62000108               # [RPDO] mapping -> [RWOD]
    assert od["0x1A00:2"].default == 0x60000208
    assert od["0x1400:1"].default == 0x240                    # predefined + node-id
    assert [str(p) for p in od.validate() if p.is_error] == []
    assert setup.warnings == ["dev.txt:7: [NODE] image size 8 is not one GetStatus can report "
                              "((n+1)*32 or 255): the status byte reports the largest such "
                              "size below it"]


def _wide_pdo_device(node: str) -> str:
    """8 UNSIGNED64 entries (length code 0) filling one 64-byte RPDO."""
    rwod = [f"0020{sub:02X}F0{8 * (sub - 1):02X}" for sub in range(1, 9)] + ["FFFFFFFFFF"]
    return setup_text(NODE=[node], TPDO=None, COD=None, RWOD=rwod,
                      RPDO=["0000FF", "08" + "".join(f"{i:02X}" for i in range(8))],
                      PIMG=["00" * 64])


def test_fd_extension_64_byte_pdo() -> None:
    # [NODE] byte 7 = 01 (CANopen FD), bytes 8-9 = heartbeat 03E8h ms
    setup = parse_setup_text(_wide_pdo_device("04404001000001E803"), "fd.txt")
    assert setup.mode == "fd" and setup.node is not None and setup.node.heartbeat_ms == 1000
    assert setup.rwod[0].length == 8
    od = build_od(setup)
    assert od["0x2000:1"].data_type == DataType.UNSIGNED64
    assert od["0x1600:8"].default == 0x20000840
    assert od[0x1017].default == 1000
    # the same on a classic line: 64 bytes do not fit 8
    with pytest.raises(SetupFileError, match=r"fd.txt:\d+: \[RPDO\] RPDO 1 maps 64 bytes"):
        parse_setup_text(_wide_pdo_device("044040010000"), "fd.txt")


def test_tolerated_slips_are_warned_with_their_line() -> None:
    text = setup_text(ID=["abcd0201"]) + "[EXTRA]\n01\n01\n"
    text = text.replace(section("COD", [
        "4300100091010F00", "4F00600002000000", "4F00620002000000", "FFFFFFFFFFFFFFFF"]),
        section("COD", ["4300100091010F00", "4F00600002000000", "4F00620002000000",
                        "FFFFFFFFFFFFFFFF"], checksum="xx"))
    setup = parse_setup_text(text, "w.txt")
    assert setup.ident == bytes.fromhex("ABCD0201")
    assert any(w.startswith("w.txt:4: lower-case hex") for w in setup.warnings)
    assert any("unknown section [EXTRA] ignored" in w for w in setup.warnings)
    assert any("[COD] checksum 'xx' not checked" in w for w in setup.warnings)


def _replace_line(text: str, old: str, new: str) -> str:
    assert old in text
    return text.replace(old, new, 1)


GOOD = setup_text()
BROKEN = [
    ("magic", GOOD.replace("COPTSKA8", "COPTSKA9"), r"b.txt:1: expected 'COPTSKA8'"),
    ("empty", "", r"b.txt:1: expected 'COPTSKA8'"),
    ("checksum", _replace_line(GOOD, "044008010100\n4E", "044008010100\n4F"),
     r"b.txt:8: \[NODE\] checksum: expected 4E \(sum of its bytes\), got 4F"),
    ("truncated", GOOD[:GOOD.index("[RWOD]") + 20], r"b.txt:\d+: \[RWOD\]"),
    ("duplicated", GOOD + section("NODE", ["044008010100"]),
     r"b.txt:\d+: \[NODE\] given twice \(first at line 6\)"),
    ("not hex", _replace_line(GOOD, "34120201", "3412020G"), r"b.txt:4: 'G' in '3412020G'"),
    ("odd digits", _replace_line(GOOD, "0011223344556677", "001122334455667"),
     r"b.txt:\d+: odd number of hex digits"),
    ("data before label", GOOD.replace("// process image test device", "0102"),
     r"b.txt:2: data '0102' before any \[SECTION\]"),
    ("node-id", setup_text(NODE=["040008010100"]), r"\[NODE\] node-id 00: expected 01..7F"),
    ("bps", setup_text(NODE=["094008010100"]), r"\[NODE\] bit rate code 09"),
    ("node length", setup_text(NODE=["0440080101"]), r"\[NODE\] has 5 bytes"),
    ("image size", setup_text(PIMG=["00112233445566"]),
     r"\[PIMG\] has 7 bytes: \[NODE\] says the image has 8"),
    ("overlap", setup_text(RWOD=["0060015100", "0060025200", "006201F102", "006202F103",
                                 "FFFFFFFFFF"]),
     r"b.txt:\d+: \[RWOD\] 6000:02 overlaps 6000:01 \(line \d+\) at image byte 0"),
    ("past the image", setup_text(RWOD=["0060015100", "0060025101", "006201F102",
                                        "006202F407", "FFFFFFFFFF"]),
     r"\[RWOD\] 6200:02 bytes 7..10 lie past the process image of 8 bytes"),
    ("no end record", setup_text(RWOD=["0060015100"]), r"\[RWOD\] must end with a record"),
    ("unused offset", setup_text(RWOD=["00600151FF", "FFFFFFFFFF"]), r"offset FFh means unused"),
    ("rpdo read-only", setup_text(RWOD=["0060015100", "0060025101", "006201D102",
                                        "006202F103", "FFFFFFFFFF"]),
     r"\[RWOD\] 6200:01: RPDO-mapped but not writable"),
    ("pdo count", setup_text(RPDO=["0000FF"]), r"\[RPDO\] has 1 data lines: \[NODE\] says 1"),
    ("mapping ref", setup_text(RPDO=["0000FF", "020209FFFFFFFFFFFF"]),
     r"\[RPDO\] RPDO 1 maps \[RWOD\] entry 9: there are 4"),
    ("mapping direction", setup_text(RPDO=["0000FF", "020001FFFFFFFFFFFF"]),
     r"RPDO 1 maps 6000:01 \(line \d+\), which is not RPDO-mappable"),
    ("mapping tail", setup_text(RPDO=["0000FF", "02020300FFFFFFFFFF"]),
     r"bytes after the 2 mapped entries must be FFh"),
    ("ttype", setup_text(RPDO=["0000F5", "020203FFFFFFFFFFFF"]),
     r"transmission type F5 is not one CiA 301 allows"),
    ("cob-id", setup_text(RPDO=["0008FF", "020203FFFFFFFFFFFF"]),
     r"COB-ID 0800: expected an 11-bit CAN-ID"),
    ("cod cs", setup_text(COD=["6000100091010F00", "FFFFFFFFFFFFFFFF"]),
     r"\[COD\] command specifier 60 of 1000:00"),
    ("twice", setup_text(COD=["4F00600102000000", "FFFFFFFFFFFFFFFF"]),
     r"b.txt:\d+: 6000:01 defined twice \(first at line \d+\)"),
    ("builder's object", setup_text(COD=["4B17100064000000", "FFFFFFFFFFFFFFFF"]),
     r"1017:00 is made from \[NODE\]/\[RPDO\]/\[TPDO\]"),
    ("no node", setup_text(NODE=None), r"no \[NODE\] section"),
    ("label", GOOD.replace("[PIMG]", "[PIMG"), r"section label '\[PIMG' is not \[NAME\]"),
]


@pytest.mark.parametrize("text,message", [b[1:] for b in BROKEN], ids=[b[0] for b in BROKEN])
def test_broken_files_are_refused_with_file_and_line(text: str, message: str) -> None:
    with pytest.raises(SetupFileError, match=message):
        build_od(parse_setup_text(text, "b.txt"))


def test_hostile_files(tmp_path: pathlib.Path) -> None:
    binary = tmp_path / "binary.txt"
    binary.write_bytes(b"COPTSKA8\n[NODE]\n04\xff\n")
    with pytest.raises(SetupFileError, match=r"binary.txt:3: byte FF is not ASCII"):
        load_setup_file(str(binary))
    huge = tmp_path / "huge.txt"
    huge.write_bytes(b"COPTSKA8\n" + b"; padding\n" * 120000)
    with pytest.raises(SetupFileError, match=r"huge.txt: \d+ bytes; a setup file has at most"):
        load_setup_file(str(huge))
    with pytest.raises(SetupFileError, match=r"missing.txt: cannot read"):
        load_setup_file(str(tmp_path / "missing.txt"))
    good = tmp_path / "good.txt"
    good.write_text(GOOD)
    assert load_setup_file(str(good)).node is not None
