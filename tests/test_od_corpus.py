"""Real-world device description files (tests/data/vendor, see SOURCES.md there):
each is imported leniently, served by a local node and read back by a client
over SDO (classic line) and USDO (the same dictionary on an fd line), and by
python-canopen as an independent SDO client on python-can's virtual bus.

Values are checked twice: against literals taken from the file's text (so a
reader that misreads a notation fails), and for the first entries against the
dictionary's own start value. The count of recovered deviations per file is
pinned, so a reader that starts dropping (or stops reporting) things fails.
"""

from __future__ import annotations

import glob
import os
import time

import pytest

from canopenfd.od import DataType, OdFileError, import_od

VENDOR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data", "vendor")
NODE = 5
STACK_OWNED = (0x1001, 0x1003)  # error register, error history: the stack's state, not defaults
FILES = sorted(os.path.basename(path) for path in glob.glob(os.path.join(VENDOR, "*"))
               if path.lower().endswith((".eds", ".dcf", ".xdd", ".xdc")))

# (index, sub) -> value, read off each file by hand (node-id 5)
EXPECTED = {
    "pycanopen_sample.eds": {(0x1400, 1): 0x205, (0x1403, 1): 0x505, (0x1008, 0): "TEST DEVICE",
                             (0x1018, 1): 1, (0x3004, 2): 3, (0x3010, 0): 0.0,
                             (0x2020, 0): b""},
    "pycanopen_datatypes.eds": {(0x2009, 0): "ABCD", (0x200A, 0): b"\xab\xcd",
                                (0x2015, 0): -64, (0x2002, 0): 12, (0x2010, 0): -1},
    "pycanopen_sensor.eds": {(0x1800, 1): 0x405, (0x6041, 0): 75, (0x1018, 4): 533457},
    "pycanopen_e35_like.eds": {(0x1008, 0): "E35 look-alike", (0x1014, 0): 0x85,
                               (0x1017, 0): 250},
    "lely_sdev.dcf": {(0x1000, 0): 0x01020304, (0x2002, 0): -0x7F,
                      (0x2009, 0): '"Hello, World!"',
                      (0x200A, 0): bytes.fromhex("0123456789abcdef")},
    "lely_coctl.dcf": {(0x1005, 0): 0x40000080, (0x1F80, 0): 1, (0x1014, 0): 0x85},
    "lely_pdo_receive.dcf": {(0x1600, 1): 0x2000001C, (0x1400, 1): 0x182},
    "lely_time.dcf": {(0x1012, 0): 0xC0000100},
    "ros2canopen_simple.eds": {(0x1600, 1): 0x40000020, (0x1800, 1): 0x185,
                               (0x1018, 1): 0x360},
    "daxbot_example.eds": {(0x1016, 1): 196618, (0x1016, 2): 262154},
    "daxbot_sample.eds": {(0x1234, 0): "Test"},
    "drive_a_like.eds": {(0x1000, 0): 0x60192, (0x1802, 1): 0x80000385, (0x1802, 3): 0x12C},
    "drive_b_like.eds": {(0x1200, 1): 0x605, (0x1014, 0): 0x85, (0x1018, 1): 0x1A3},
    "gripper_like.eds": {(0x1600, 2): 0x607A0020, (0x1801, 1): 0x80000285},
    "scanned_like.eds": {(0x1401, 1): 0x305, (0x1014, 0): 0x85},
    "gocanopen_like.eds": {(0x1400, 1): 0x80000205, (0x100A, 0): "v0.9.1z", (0x1003, 0x10): 0},
    "spaced_like.eds": {(0x1017, 0): 750, (0x1018, 2): 7, (0x2003, 0): 42},
    "satellite_like.dcf": {(0x1008, 0): "Power Node", (0x1400, 1): 0x80000205,
                           (0x6000, 0): 3700},
    "editor_v4_like.eds": {(0x1200, 1): 0x605, (0x1400, 1): 0x205},
    "editor_v4_dup_like.eds": {(0x1018, 0): 0, (0x1018, 2): 2},
    "ros_slave_like.eds": {(0x1000, 0): 0xFFFF0192, (0x1400, 1): 0x80000205},
    "legacy_node_like.eds": {(0x2110, 0): -12, (0x1800, 1): 0x80000185, (0x1017, 0): 5000},
    "editor_like.xdd": {(0x1200, 1): 0x605, (0x2110, 0): -7, (0x1018, 2): 5},
    "editor_rtt_like.xdd": {(0x1023, 2): 0, (0x1014, 0): 0x85},
}

# recovered deviations (what strict=True refuses) per file
DEVIATIONS = {
    "pycanopen_sample.eds": 5, "pycanopen_datatypes.eds": 1, "pycanopen_e35_like.eds": 1,
    "lely_sdev.dcf": 4, "gocanopen_like.eds": 1, "spaced_like.eds": 4,
    "editor_rtt_like.xdd": 1, "daxbot_sample.eds": 1,
}


def test_corpus_is_complete():
    assert sorted(EXPECTED) == FILES
    assert len(FILES) >= 24
    sources = open(os.path.join(VENDOR, "SOURCES.md"), encoding="utf-8").read()
    for name in FILES:
        assert f"`{name}`" in sources, f"{name} has no entry in SOURCES.md"


@pytest.mark.parametrize("name", FILES)
def test_import_is_lenient_and_strict_names_the_first_deviation(name):
    path = os.path.join(VENDOR, name)
    od = import_od(path, node_id=NODE)
    recovered = [str(p) for p in od.load_warnings if p.is_error]
    assert len(recovered) == DEVIATIONS.get(name, 0), recovered
    for text in recovered:
        assert text.startswith(f"error: {path}:"), text
    if recovered:
        with pytest.raises(OdFileError) as info:
            import_od(path, node_id=NODE, strict=True)
        assert str(info.value).startswith(f"{path}:")
    else:
        import_od(path, node_id=NODE, strict=True)


@pytest.mark.parametrize("mode", ["classic", "fd"])
@pytest.mark.parametrize("name", FILES)
def test_served_and_read_back(net, bus_name, name, mode):
    path = os.path.join(VENDOR, name)
    start = time.monotonic()
    od = import_od(path, node_id=NODE, mode=mode)
    served_line = net.open_line(bus_name, mode=mode)
    if mode == "classic":
        served_line.create_local_node(NODE, od=path)      # by path, as users do
    else:
        served_line.create_local_node(NODE, od=od)        # the same file, an fd line: USDO
    remote = net.open_line(bus_name, mode=mode).add_node(NODE, od=od)
    for (index, sub), value in EXPECTED[name].items():
        var = od.get_variable(index, sub)
        got = remote.read((index, sub))
        if var.data_type in (DataType.REAL32, DataType.REAL64):
            assert got == pytest.approx(value), (index, sub)
        else:
            assert got == value, (hex(index), sub, got, value)
    checked = 0
    for var in od.entries():
        if checked == 4:
            break
        if not var.readable or var.data_type == DataType.DOMAIN or var.index in STACK_OWNED:
            continue
        assert remote.read((var.index, var.subindex)) == var.decode_raw(
            var.default_bytes(NODE)), var.where
        checked += 1
    assert time.monotonic() - start < 5


@pytest.fixture(scope="module")
def python_canopen():
    """python-canopen on python-can's virtual bus, shared by the files (its
    disconnect waits up to a second for the bus reader)."""
    canopen = pytest.importorskip("canopen")
    channel = f"corpus-{os.getpid()}"
    network = canopen.Network()
    network.connect(interface="virtual", channel=channel)
    yield canopen, network, channel
    network.disconnect()


@pytest.mark.parametrize("name", FILES)
def test_python_canopen_reads_what_we_serve(python_canopen, name):
    """python-canopen as the independent SDO client: the served bytes decode
    to the values read off the file."""
    import canopenfd

    canopen, network, channel = python_canopen
    path = os.path.join(VENDOR, name)
    od = import_od(path, node_id=NODE, mode="classic")
    with canopenfd.connect(channel, interface="virtual", mode="classic") as line:
        line.create_local_node(NODE, od=path)
        peer = network.add_node(NODE, canopen.ObjectDictionary())
        for (index, sub), value in EXPECTED[name].items():
            var = od.get_variable(index, sub)
            got = var.decode_raw(peer.sdo.upload(index, sub))
            if var.data_type in (DataType.REAL32, DataType.REAL64):
                assert got == pytest.approx(value), (hex(index), sub)
            else:
                assert got == value, (hex(index), sub, got, value)
