"""The monitor's decoder on MPDOs (docs/mpdo.md): a CAN-ID an OD makes an
MPDO (mapping sub 0 = 0xFF DAM / 0xFE SAM) shows what the frame writes or
publishes, its value typed by the OD of the node it belongs to; without
that OD the frame stays a plain PDO. Texts checked byte for byte."""

from __future__ import annotations

from test_decode_services import _record, _var, fd

from canopenfd import Frame
from canopenfd.cli import main
from canopenfd.decode import Decoder, PdoMap, decode
from canopenfd.od import import_od


def _mpdo(comm, cob_id, marker):
    kind = "TPDO" if comm >= 0x1800 else "RPDO"
    text = _record(comm, f"{kind} communication parameter", [
        (f"COB-ID used by {kind}", 0x07, cob_id), ("Transmission type", 0x05, 254)])
    mapping = comm + 0x200
    return (text + f"[{mapping:04X}]\nParameterName={kind} mapping parameter\nObjectType=0x9\n"
            f"SubNumber=2\n\n" + _var(mapping, 0, "Number of mapped objects", 0x05, marker)
            + _var(mapping, 1, "Mapped object 1", 0x07, 0))


EDS = ("[FileInfo]\nFileName=mpdo_test.eds\n\n[DeviceInfo]\nVendorName=Test\n\n"
       + _var(0x2001, None, "Mode", 0x05, 0, mapping=1)
       + _var(0x2002, None, "Speed", 0x03, 0, mapping=1)
       + _var(0x2003, None, "Label", 0x09, "AB", mapping=1)
       + _mpdo(0x1800, "$NODEID+0x180", 0xFF)         # TPDO1: DAM producer
       + _mpdo(0x1801, "$NODEID+0x280", 0xFE))        # TPDO2: SAM producer


def decoder(tmp_path, nodes=(5, 6)):
    path = tmp_path / "mpdo_test.eds"
    path.write_text(EDS)
    return Decoder([(import_od(path), node) for node in nodes])


def test_pdo_map_marks_mpdos(tmp_path):
    path = tmp_path / "mpdo_test.eds"
    path.write_text(EDS)
    found = PdoMap().add_od(import_od(path), 5)
    assert [(p.name, p.can_id, p.mpdo, p.objects, p.problem) for p in found] == [
        ("TPDO1", 0x185, "DAM", [], ""), ("TPDO2", 0x285, "SAM", [], "")]


def test_dam_frames(tmp_path):
    d = decoder(tmp_path)
    # node 6's OD says Speed is INTEGER16: the first 2 value bytes
    assert d.decode(Frame(0x185, bytes([0x86, 0x02, 0x20, 0x00, 0xFE, 0xFF, 0x00, 0x00]))) == \
        "TPDO1 node 5 DAM to node 6 0x2002:00 = -2"
    assert d.decode(Frame(0x185, bytes([0x86, 0x03, 0x20, 0x00, 0x41, 0x42, 0x43, 0x44]))) == \
        "TPDO1 node 5 DAM to node 6 0x2003:00 = 41 42 43 44"     # a string: no fixed size
    # every node (no single OD types it), a node whose OD is unknown, an object it lacks
    assert d.decode(Frame(0x185, bytes([0x80, 0x01, 0x20, 0x00, 0x07, 0x00, 0x00, 0x00]))) == \
        "TPDO1 node 5 DAM to all nodes 0x2001:00 = 07 00 00 00"
    assert d.decode(Frame(0x185, bytes([0x89, 0x02, 0x20, 0x00, 0xFE, 0xFF, 0x00, 0x00]))) == \
        "TPDO1 node 5 DAM to node 9 0x2002:00 = FE FF 00 00"
    assert d.decode(Frame(0x185, bytes([0x86, 0xFF, 0x2F, 0x01, 0x01, 0x02, 0x00, 0x00]))) == \
        "TPDO1 node 5 DAM to node 6 0x2FFF:01 = 01 02 00 00"
    assert d.describe(Frame(0x186, bytes([0x85, 0x01, 0x20, 0x00, 0x2A, 0x00, 0x00, 0x00]))) == (
        "0x186 [8] 85 01 20 00 2A 00 00 00".ljust(30)
        + " TPDO1 node 6 DAM to node 5 0x2001:00 = 42")


def test_sam_frames(tmp_path):
    d = decoder(tmp_path)
    assert d.decode(Frame(0x285, bytes([0x05, 0x02, 0x20, 0x00, 0x2C, 0x01, 0x00, 0x00]))) == \
        "TPDO2 node 5 SAM from node 5 0x2002:00 = 300"
    assert d.decode(fd(0x286, bytes([0x06, 0x01, 0x20, 0x00, 0x07, 0x00, 0x00, 0x00]))) == \
        "TPDO2 node 6 SAM from node 6 0x2001:00 = 7 [FD BRS]"


def test_malformed_mpdos(tmp_path):
    d = decoder(tmp_path)
    assert d.decode(Frame(0x185, bytes([0x86, 0x02, 0x20, 0x00]))) == \
        "TPDO1 node 5 DAM malformed: 4 bytes, an MPDO has 8 (86 02 20 00)"
    assert d.decode(Frame(0x285, b"")) == "TPDO2 node 5 SAM malformed: 0 bytes, an MPDO has 8"
    assert d.decode(Frame(0x185, bytes([0x05, 0x02, 0x20, 0x00, 0x2C, 0x01, 0x00, 0x00]))) == (
        "TPDO1 node 5 SAM from node 5 0x2002:00 = 300 malformed: the mapping makes it a DAM "
        "MPDO")


def test_without_the_od_an_mpdo_stays_a_pdo(tmp_path):
    frame = Frame(0x185, bytes([0x86, 0x02, 0x20, 0x00, 0xFE, 0xFF, 0x00, 0x00]))
    assert decode(frame) == "TPDO1 node 5 86 02 20 00 FE FF 00 00"
    assert Decoder().decode(frame) == "TPDO1 node 5 86 02 20 00 FE FF 00 00"
    # node 6's OD alone knows its own TPDOs, not node 5's
    assert decoder(tmp_path, nodes=(6,)).decode(frame) == "TPDO1 node 5 86 02 20 00 FE FF 00 00"


def test_the_monitor_shows_mpdos(tmp_path, capsys):
    """`canopenfd monitor --replay LOG --od EDS@5 --od EDS@6`: the same texts."""
    eds = tmp_path / "mpdo_test.eds"
    eds.write_text(EDS)
    log = tmp_path / "mpdo.log"
    log.write_text("(1.000000) can0 185#86022000FEFF0000\n"
                   "(1.001000) can0 285#050220002C010000\n")
    capsys.readouterr()
    status = main(["monitor", "--replay", str(log), "--classic", "--od", f"{eds}@5",
                   "--od", f"{eds}@6"])
    out, err = capsys.readouterr()
    assert status == 0, err
    shown = [line[10:] for line in out.splitlines() if line[10:12] in ("RX", "TX")]
    assert [line.split(None, 1)[1] for line in shown] == [
        "0x185 [8] 86 02 20 00 FE FF 00 00".ljust(30) + " TPDO1 node 5 DAM to node 6 "
        "0x2002:00 = -2",
        "0x285 [8] 05 02 20 00 2C 01 00 00".ljust(30) + " TPDO2 node 5 SAM from node 5 "
        "0x2002:00 = 300"]
