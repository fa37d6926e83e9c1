"""The retentive text store (canopenfd.services.store_text): a node's saved
parameters as one readable line per entry with a checksum, written atomically
on every save (over the network too), read at boot; damaged, truncated,
duplicated, contradictory or hostile files stop the boot with file:line; the
`canopenfd store export|import|seal` conversions."""

from __future__ import annotations

import os

import pytest

from canopenfd import AbortError
from canopenfd.cli.entry import main
from canopenfd.od import DataType, demo_od
from canopenfd.services import atomic_file
from canopenfd.services.store_image import ParameterImage, Record
from canopenfd.services.store_text import StoreFileError, TextStore, format_text
from helpers import Recorder, run_cli

NODE, CLIENT = 5, 2
SAVE_ALL = bytes([NODE, 0x01, 1, 0x01, 0x10, 0x10, 0x07, 4]) + b"save"


def boot(net, bus, store):
    line = net.open_line(bus, mode="fd")
    return line.create_local_node(NODE, od=demo_od("fd"), store=store)


def saved_store(net, bus, path, heartbeat=1234):
    """A text store holding 0x1017 = heartbeat, saved by a node."""
    node = boot(net, bus + "-donor", TextStore(path))
    node[0x1017].raw = heartbeat
    node.save_parameters()
    return path.read_text()


def test_a_save_writes_one_readable_line_per_entry_and_a_restart_loads_it(net, bus_name,
                                                                         tmp_path):
    path = tmp_path / "params.txt"
    text = saved_store(net, bus_name, path)
    assert "1017 00 UNSIGNED16 2 : D2 04\n" in text            # 1234, least significant first
    assert "2009 00 VISIBLE_STRING 9 : 63 61 6E 6F 70 65 6E 66 64\n" in text
    assert text.splitlines()[3:5] == ["format 1", text.splitlines()[4]]
    assert text.splitlines()[-1].startswith("checksum ")
    assert not os.path.exists(str(path) + ".tmp")
    node = boot(net, bus_name, TextStore(path))
    assert node.store_status == "ok" and node[0x1017].raw == 1234


def test_a_save_over_the_network_is_answered_after_the_text_is_on_disk(net, bus_name,
                                                                       tmp_path):
    path = tmp_path / "params.txt"
    node = boot(net, bus_name, TextStore(path))
    client = net.open_line(bus_name, mode="fd", monitor=True)
    answers = Recorder()
    client.on_frame(lambda f: answers(f) if f.id == 0x580 + NODE else None)
    node[0x1017].raw = 0x0BB8
    client.send_frame(0x600 + CLIENT, SAVE_ALL)
    assert answers.wait_count(1)[0].data == bytes([CLIENT, 0x21, 1, 0x01, 0x10, 0x10])
    assert "1017 00 UNSIGNED16 2 : B8 0B\n" in path.read_text()


def test_comments_order_and_spacing_are_free_values_are_sealed(net, bus_name, tmp_path):
    path = tmp_path / "params.txt"
    lines = saved_store(net, bus_name, path).splitlines()
    entries = [line for line in lines if line[:1].isdigit()]
    # a person reorders entries, adds comments and blank lines: still loads
    path.write_text("\n".join(lines[:5] + ["", "# moved", *reversed(entries), lines[-1]]) + "\n")
    assert boot(net, bus_name + "-a", TextStore(path))[0x1017].raw == 1234
    # a changed value without `store seal` is refused at the checksum line
    edited = [line.replace("D2 04", "E8 03") for line in lines]
    path.write_text("\n".join(edited) + "\n")
    with pytest.raises(StoreFileError, match=rf"params.txt:{len(lines)}: checksum .*store seal"):
        boot(net, bus_name + "-b", TextStore(path))
    # sealed, it loads the person's value
    assert main(["store", "seal", str(path)]) == 0
    assert boot(net, bus_name + "-c", TextStore(path))[0x1017].raw == 1000


HEADER = "format 1\nsignature 00000000\n"


@pytest.mark.parametrize("text, where, words", [
    ("", 0, "truncated: no 'format' line"),
    (HEADER, 0, "truncated: no 'checksum' line after line 2"),
    (HEADER + "1017 00 UNSIGNED16 2 : E8", 3, "length 2 but 1 data bytes"),
    (HEADER + "1017 00 UNSIGNED16 2 : E8 03\n1017 00 UNSIGNED16 2 : E8 03\n", 4,
     "1017:00 is already on line 3 (duplicated)"),
    (HEADER + "1017 00 UNSIGNED32 2 : E8 03\n", 3, "length 2 contradicts UNSIGNED32 (4 bytes)"),
    (HEADER + "1017 00 UNSIGNED16 2 : E8 3\n", 3, "data byte '3' is not two hex digits"),
    (HEADER + "1017 00 FLOAT 4 : 00 00 00 00\n", 3, "'FLOAT' is not a CiA 301 data type"),
    (HEADER + "2000 00 DOMAIN 1 : 00\n", 3, "DOMAIN entries are never stored"),
    (HEADER + "2000 00 OCTET_STRING 99999999999 : 00\n", 3, "larger than 65535"),
    (HEADER + "1017:00 = 1000\n", 3, "expected 'INDEX SUB TYPE LENGTH : DATA'"),
    (HEADER + "checksum 00000000\n1017 00 UNSIGNED16 2 : E8 03\n", 4,
     "after the checksum line 3"),
    ("format 2\n", 1, "format '2', expected 1"),
    ("signature 00000000\nformat 1\n", 1, "expected the 'format' line"),
    (HEADER.replace("00000000", "xyz"), 2, "signature 'xyz' is not 8 hex digits"),
    (HEADER + "1017 00 UNSIGNED16 2 : E8 03\x00\n", 3, "control character"),
    ("format 1\n\xff\xfe\n", 2, "not ASCII text"),
])
def test_damaged_text_stores_stop_the_boot_naming_file_and_line(net, bus_name, tmp_path, text,
                                                                 where, words):
    path = tmp_path / "params.txt"
    path.write_bytes(text.encode("latin-1"))
    line = net.open_line(bus_name, mode="fd")
    with pytest.raises(StoreFileError) as info:
        line.create_local_node(NODE, od=demo_od("fd"), store=TextStore(path))
    location = f"{path}:{where}: " if where else f"{path}: "
    assert str(info.value).startswith(location) and words in str(info.value), str(info.value)
    assert line.local_node is None       # never started half-configured


def test_a_huge_file_is_refused_before_it_is_parsed(net, bus_name, tmp_path):
    path = tmp_path / "params.txt"
    path.write_bytes(b"#" * (4 * 1024 * 1024 + 1))
    with pytest.raises(StoreFileError, match="more than the 4194304 a text store may have"):
        boot(net, bus_name, TextStore(path))


@pytest.mark.parametrize("cut_at", ["write", "fsync", "replace"])
def test_a_power_cut_during_a_save_keeps_the_old_store(net, bus_name, tmp_path, monkeypatch,
                                                      cut_at):
    path = tmp_path / "params.txt"
    old = saved_store(net, bus_name, path, heartbeat=100)
    node = boot(net, bus_name, TextStore(path))
    node[0x1017].raw = 200

    def cut(*args, **kwargs):
        raise OSError(5, f"power cut at {cut_at}")
    monkeypatch.setattr(atomic_file.os, cut_at, cut)
    with pytest.raises(AbortError) as info:
        node.save_parameters()
    monkeypatch.undo()
    assert info.value.code == 0x08000020
    assert path.read_text() == old and not os.path.exists(str(path) + ".tmp")
    # a temporary file a real cut left half-written is ignored at the next boot
    (tmp_path / "params.txt.tmp").write_text("format 1\n1017 00 UNSI")
    assert boot(net, bus_name + "-after", TextStore(path))[0x1017].raw == 100


@pytest.mark.parametrize("torn_after, words", [
    ("1017 00 UNSIGNED16 2 : D2 04\n", "truncated: no 'checksum' line after line {n}"),
    ("1017 00 UNSIGNED16 2 : D2", ":{n}: 1017:00: length 2 but 1 data bytes"),
])
def test_a_torn_store_on_a_medium_without_atomic_rename_is_refused(net, bus_name, tmp_path,
                                                                   torn_after, words):
    path = tmp_path / "params.txt"
    text = saved_store(net, bus_name, path)
    torn = text[:text.index(torn_after) + len(torn_after)]
    path.write_text(torn)
    with pytest.raises(StoreFileError) as info:
        boot(net, bus_name, TextStore(path))
    assert words.format(n=len(torn.rstrip("\n").splitlines())) in str(info.value)


def test_export_and_import_convert_between_the_binary_image_and_text(net, bus_name, tmp_path,
                                                                     capsys):
    binary, text = tmp_path / "params.bin", tmp_path / "params.txt"
    node = boot(net, bus_name + "-bin", str(binary))
    node[0x1017].raw = 4321
    node.save_parameters()
    assert main(["store", "export", str(binary), str(text)]) == 0
    assert "1017 00 UNSIGNED16 2 : E1 10\n" in text.read_text()
    assert boot(net, bus_name + "-text", TextStore(text))[0x1017].raw == 4321
    # edit, seal, import: the binary store of the C stack loads the edited value
    text.write_text(text.read_text().replace("E1 10", "10 27"))
    assert main(["store", "seal", str(text)]) == 0
    back = tmp_path / "back.bin"
    assert main(["store", "import", str(text), str(back)]) == 0
    assert "params.txt -> " in capsys.readouterr().out
    restarted = boot(net, bus_name + "-back", str(back))
    assert restarted.store_status == "ok" and restarted[0x1017].raw == 10000


def test_the_cli_refuses_damaged_input_with_file_line_and_writes_nothing(tmp_path):
    text, image = tmp_path / "params.txt", tmp_path / "out.bin"
    text.write_text(HEADER + "1017 00 UNSIGNED16 2 : E8 03\n1017 00 UNSIGNED16 2 : 00 00\n"
                    "checksum 00000000\n")
    result = run_cli("store", "import", str(text), str(image))
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert f"{text}:4: 1017:00 is already on line 3" in result.stderr
    assert not image.exists()
    image.write_bytes(b"\x55" * 40)
    result = run_cli("store", "export", str(image), str(text) + "2")
    assert result.returncode == 2 and f"{image}: magic" in result.stderr
    assert not os.path.exists(str(text) + "2")


@pytest.mark.parametrize("record, words", [
    ((0x2060, 0, DataType.UNSIGNED16, b"\x01\x00"), "2060:00: no stored entry of that key"),
    ((0x1018, 1, DataType.UNSIGNED32, b"\x01\x00\x00\x00"), "1018:01: no stored entry"),
    ((0x1017, 0, DataType.UNSIGNED32, b"\x01\x00\x00\x00"),
     "1017:00: type UNSIGNED32, the object dictionary says UNSIGNED16"),
    ((0x2009, 0, DataType.VISIBLE_STRING, b"x" * 40),
     "2009:00: length 40, the entry holds 32 bytes at most"),
])
def test_entries_the_dictionary_contradicts_stop_the_boot_at_their_line(net, bus_name,
                                                                        tmp_path, record,
                                                                        words):
    """A sealed file whose entry does not fit the node's dictionary (a typo
    in an index, another type or length) is refused, never skipped."""
    path = tmp_path / "params.txt"
    records = [Record(0x2006, 0, int(DataType.UNSIGNED16), b"\x10\x00"),
               Record(record[0], record[1], int(record[2]), record[3])]
    records.sort(key=lambda r: r.key)
    text = format_text(ParameterImage(0, records))
    path.write_text(text)
    number = next(n for n, line in enumerate(text.splitlines(), 1)
                  if line.startswith(f"{record[0]:04X} {record[1]:02X} "))
    with pytest.raises(StoreFileError) as info:
        boot(net, bus_name, TextStore(path))
    assert str(info.value).startswith(f"{path}:{number}: {words}"), str(info.value)
