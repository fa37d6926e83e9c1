"""Concise DCF (CiA 302-3) in Python: canopenfd.od.concise parses and builds
the layout with the C iterator's checks (each error naming the byte offset),
converts a DCF (entries with a ParameterValue, writable, PDOs in the CiA 301
order; checked entry by entry, against python-canopen's reading of the same
DCF, and by writing the result into our own node, which enforces the PDO
procedure), and `canopenfd dcf2concise` prints and writes it."""

from __future__ import annotations

import struct

import pytest

from canopenfd import SdoAbortError
from canopenfd.cli.entry import main
from canopenfd.od import OdFileError, import_od
from canopenfd.od.concise import (ConciseDcfError, ConciseEntry, build_concise,
                                  concise_from_od, parse_concise)
from dcf_helpers import NODE, device_od, make_dcf



def entry(index, sub, data):
    return struct.pack("<HBI", index, sub, len(data)) + data


TWO = struct.pack("<I", 2) + entry(0x1017, 0, b"\xe8\x03") + entry(0x1800, 1, b"\x85\x01\x00\x80")


# ------------------------------------------------------------------ the layout
def test_build_gives_the_layout_bytes_and_parse_reads_them_back():
    data = build_concise([(0x1017, 0, b"\xe8\x03"), (0x1800, 1, b"\x85\x01\x00\x80")])
    assert data == bytes.fromhex("02000000" "17100002000000e803" "00180104000000850100 80".replace(" ", ""))
    assert data == TWO
    assert parse_concise(data) == [ConciseEntry(0x1017, 0, b"\xe8\x03"),
                                   ConciseEntry(0x1800, 1, b"\x85\x01\x00\x80")]
    assert parse_concise(build_concise([])) == []


@pytest.mark.parametrize("data, offset, text", [
    (b"\x01\x00", 0, "shorter than the 4-byte number of entries"),
    (TWO[:10], 4, "entry 0: header cut short (6 of 7 bytes)"),
    (TWO[:12], 7, "entry 0 (0x1017:00): data size 2 goes past the end (1 bytes left)"),
    (TWO[:13], 13, "1 entries where 2 were announced"),
    (TWO[:19], 13, "entry 1: header cut short"),
    (TWO[:-1], 16, "entry 1 (0x1800:01): data size 4 goes past the end"),
    (TWO + b"\x00", 24, "1 bytes after the last of the 2 announced entries"),
    (b"\x01" + TWO[1:], 13, "11 bytes after the last of the 1 announced entries"),
    (struct.pack("<I", 1) + entry(0x2000, 0, b"")[:3] + b"\xff\xff\xff\xff", 7,
     "data size 4294967295 goes past the end (0 bytes left)"),
])
def test_every_malformation_names_its_byte_offset(data, offset, text):
    with pytest.raises(ConciseDcfError) as info:
        parse_concise(data, "x.cdcf")
    assert info.value.offset == offset
    assert text in str(info.value)
    assert str(info.value).startswith(f"x.cdcf: byte {offset}: ")


# ------------------------------------------------------------------ DCF -> concise
def test_dcf_entries_order_and_bytes(tmp_path):
    conv = concise_from_od(import_od(str(make_dcf(tmp_path))))
    assert [(e.where, e.data.hex()) for e in conv.entries] == [
        ("0x1017:00", "fa00"),
        # RPDO 2: only its type is configured (no COB-ID to switch off)
        ("0x1401:02", "fe"),
        # TPDO 1: off, type, mapping cleared, entries, count, COB-ID
        ("0x1800:01", "85010080"),
        ("0x1800:02", "01"),
        ("0x1A00:00", "00"),
        ("0x1A00:01", "20010023"),
        ("0x1A00:02", "20020023"),
        ("0x1A00:00", "02"),
        ("0x1800:01", "85010000"),
        ("0x2F00:00", b"axis 1".hex()),
    ]
    left_out = dict(conv.skipped)
    assert left_out["0x1018:01"] == "ro: the node refuses writes"
    assert "command" in left_out["0x1010:01"]
    assert "stamp" in left_out["0x1020:01"]
    assert conv.stamp == (0x4A5B, 0x01234567)
    assert "0x2F01:00" not in left_out       # no ParameterValue: not configured, not listed
    assert parse_concise(conv.data) == conv.entries


def test_changed_only_leaves_out_defaults(tmp_path):
    path = make_dcf(tmp_path)
    od = import_od(str(path))
    od[0x1800][2].value = od[0x1800][2].default      # now equal to the default (254)
    conv = concise_from_od(od, changed_only=True)
    assert "0x1800:02" not in [e.where for e in conv.entries]
    assert dict(conv.skipped)["0x1800:02"] == "equal to the default (--changed-only)"


def test_node_id_relative_value_without_node_id_names_file_and_line(tmp_path):
    path = make_dcf(tmp_path)
    text = path.read_text().replace("NodeID=0x05", "NodeID=").replace("NodeID=5", "NodeID=")
    path.write_text(text)
    od = import_od(str(path))
    assert od.node_id is None
    line = next(n for n, t in enumerate(text.splitlines(), 1)
                if t.startswith("ParameterValue=$NODEID+0x180"))
    with pytest.raises(OdFileError) as info:
        concise_from_od(od)
    assert f"node.dcf:{line} 0x1800:01" in str(info.value)
    assert "depends on the node-id" in str(info.value)
    # with a node-id it converts
    assert concise_from_od(import_od(str(path), node_id=9)).entries[-2].data == \
        (0x189).to_bytes(4, "little")


def test_python_canopen_reads_the_same_values(tmp_path):
    """python-canopen's import_od of the same DCF: every writable entry with a
    value is in our list with the bytes python-canopen encodes (the last
    write of each index:sub, PDOs being written twice), and ours has no other."""
    canopen = pytest.importorskip("canopen")
    path = make_dcf(tmp_path)
    theirs = {}
    for obj in canopen.import_od(str(path), node_id=NODE).values():
        members = obj.values() if hasattr(obj, "subindices") else [obj]
        for var in members:
            if getattr(var, "value", None) is None or "w" not in var.access_type:
                continue
            if var.index in (0x1010, 0x1011, 0x1020):
                continue
            theirs[(var.index, var.subindex)] = var.encode_raw(var.value)
    ours = {}
    for e in concise_from_od(import_od(str(path))).entries:
        ours[(e.index, e.subindex)] = e.data
    assert ours == theirs


def test_the_concise_entries_configure_our_own_node(net, bus_name, tmp_path):
    """Written one by one over SDO into our node (which holds CiA 301's PDO
    rules), every entry is accepted; the node then holds the DCF's values.
    The same entries in plain index order are refused at the mapping."""
    conv = concise_from_od(import_od(str(make_dcf(tmp_path))))
    node = net.open_line(bus_name, mode="classic").create_local_node(NODE, od=device_od())
    remote = net.open_line(bus_name, mode="classic").add_node(NODE)
    for e in conv.entries:
        remote.sdo.download(e.index, e.subindex, e.data)
    assert node[0x1017].raw == 250
    assert node[0x1A00][2].raw == 0x23000220
    assert node[0x1800][1].raw == 0x185
    assert node[0x2F00].raw == "axis 1"
    # index order, as a naive converter writes: the mapping count (2) goes
    # before the entries, so a changed entry is refused (the node holds CiA
    # 301's rule; an equal value passes, so the entry must differ)
    remote.sdo.download(0x1800, 1, (0x80000185).to_bytes(4, "little"))
    remote.sdo.download(0x1A00, 0, b"\x02")
    with pytest.raises(SdoAbortError) as info:
        remote.sdo.download(0x1A00, 1, (0x23000320).to_bytes(4, "little"))
    assert "0x1A00:01" in str(info.value)


# ------------------------------------------------------------------ CLI
def test_cli_writes_the_concise_dcf_and_prints_a_summary(tmp_path, capsys):
    path = make_dcf(tmp_path)
    out = tmp_path / "node.cdcf"
    assert main(["dcf2concise", str(path), "-o", str(out)]) == 0
    printed = capsys.readouterr().out.splitlines()
    assert printed[0] == "0x1017:00  fa 00"
    assert "left out 0x1018:01: ro: the node refuses writes" in printed
    assert printed[-1].startswith(f"node.dcf -> {out}: 10 entries, ")
    assert "0x1020 date 0x00004a5b time 0x01234567" in printed[-1]
    assert parse_concise(out.read_bytes()) == concise_from_od(import_od(str(path))).entries


def test_cli_errors_name_the_file(tmp_path, capsys):
    assert main(["dcf2concise", str(tmp_path / "missing.dcf")]) == 2
    assert "missing.dcf: no such file" in capsys.readouterr().err
    bad = tmp_path / "bad.dcf"
    bad.write_text(make_dcf(tmp_path).read_text().replace("NodeID=0x05", "NodeID=")
                   .replace("NodeID=5", "NodeID="))
    assert main(["dcf2concise", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "bad.dcf:" in err and "0x1800:01" in err and "--node-id" in err
    assert main(["dcf2concise", str(bad), "--node-id", "200"]) == 2
    assert "--node-id 200 outside 1..127" in capsys.readouterr().err
