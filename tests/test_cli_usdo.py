"""The USDO commands of the CLI (read, write, download, upload) and `device`
as a USDO server, run in-process: an in-process bus ('mem:NAME') belongs to
one Network, so the test runs its server nodes on a Network and hands that
Network to `canopenfd.cli.main(argv, network=...)`; the commands then open
their client line on it (the same code path as a Network of their own)."""

from __future__ import annotations

import io
import os
import re
import threading
import time

import pytest

from canopenfd.cli import main
from canopenfd.cli.common import parse_key
from canopenfd.cli.transfer import ProgressBar, parse_type
from canopenfd.od import DataType, demo_od, export_eds
from helpers import Recorder, scaled

SERVER = 5
DOMAIN = 0x2100
KiB, MiB = 1 << 10, 1 << 20


def make_server(net, bus, node_id=SERVER, domain=MiB):
    node = net.open_line(bus, mode="fd").create_local_node(node_id, od=demo_od("fd"),
                                                           boot=False)
    if domain:
        node.serve_domain(DOMAIN, domain)
    node.boot()
    return node


@pytest.fixture
def server(net, bus_name):
    return make_server(net, bus_name)


@pytest.fixture
def cli(net, bus_name, capsys):
    """cli(*argv) -> (exit status, stdout, stderr) of `canopenfd ARGV
    --channel BUS` run on the test's Network."""
    def run(*argv, channel=bus_name):
        capsys.readouterr()
        status = main([*argv, "--channel", channel], network=net)
        out, err = capsys.readouterr()
        assert "Traceback" not in err
        return status, out, err
    return run


def one_error(status, err, *words, code=2):
    assert status == code, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("canopenfd: error: "), err
    for word in words:
        assert word in lines[0], lines[0]


# ------------------------------------------------------------------ read
def test_read_raw_typed_and_by_name(server, cli, tmp_path):
    server[0x1017].raw = 0x1234
    server["Demo record.Gain"].raw = 2.5
    server["Demo record.Label"].raw = "spindle"
    assert cli("read", "5", "0x1017") == (0, "34 12\n", "")                 # no type: raw hex
    assert cli("read", "5", "1017", "--type", "U16")[1] == "4660 (0x1234)\n"
    assert cli("read", "5", "0x1017:0", "--type", "UNSIGNED16")[1] == "4660 (0x1234)\n"
    assert cli("read", "5", "0x2200:1", "--type", "0x03")[1] == "0 (0x0000)\n"
    # typed by the OD: names, records, every kind of value
    eds = tmp_path / "device.eds"
    export_eds(demo_od("fd"), str(eds))
    for od in (str(eds), "builtin:fd"):
        assert cli("read", "5", "Producer heartbeat time", "--od", od)[1] == "4660 (0x1234)\n"
        assert cli("read", "5", "Identity object.Vendor-ID", "--od", od)[1] == \
            "0 (0x00000000)\n"
        assert cli("read", "5", "Demo record.Gain", "--od", od)[1] == "2.5\n"
        assert cli("read", "5", "0x2200:4", "--od", od)[1] == "spindle\n"
    assert cli("read", "5", "Demo INTEGER8", "--od", "builtin:fd")[1] == "-8 (0xF8)\n"
    assert cli("read", "5", "Demo BOOLEAN", "--od", "builtin:fd")[1] == "true\n"
    assert cli("read", "5", "Demo OCTET_STRING", "--od", "builtin:fd")[1] == \
        "01 02 03 04 05 06 07 08\n"
    assert cli("read", "5", "Demo UNICODE_STRING", "--od", "builtin:fd")[1] == "Grüße\n"
    # --type wins over the OD
    assert cli("read", "5", "Producer heartbeat time", "--od", "builtin:fd",
               "--type", "DOMAIN")[1] == "34 12\n"


def test_read_bytes_that_do_not_fit_the_type_are_shown_raw(server, cli):
    server[0x1017].raw = 7
    status, out, err = cli("read", "5", "0x1017", "--type", "U32")
    assert (status, out) == (0, "07 00\n")
    assert "warning" in err and "UNSIGNED32" in err


def test_read_broadcast_prints_one_line_per_node(net, bus_name, cli):
    for node_id in (3, 4, 6):
        make_server(net, bus_name, node_id, domain=0)[0x1017].raw = node_id * 10
    status, out, err = cli("read", "0", "0x1017", "--type", "U16", "--timeout",
                           str(scaled(0.3)))
    assert status == 0, err
    assert out.splitlines() == ["node 3: 30 (0x001E)", "node 4: 40 (0x0028)",
                                "node 6: 60 (0x003C)"]
    status, out, _ = cli("read", "0", "0x1017", "--timeout", str(scaled(0.3)))  # raw
    assert out.splitlines()[0] == "node 3: 1e 00"
    status, out, _ = cli("read", "0", "0x5FFF", "--timeout", str(scaled(0.3)))
    assert status == 1                               # every node refused
    assert out.splitlines() == [f"node {n}: abort 0x33 (object does not exist)"
                                for n in (3, 4, 6)]


def test_read_broadcast_without_answers_fails(cli):
    status, out, err = cli("read", "0", "0x1000:1", "--timeout", "0.1")
    assert out == ""
    one_error(status, err, "no node answered within 0.1 s", code=1)


# ------------------------------------------------------------------ write
def test_write_typed_and_read_back(server, cli):
    status, out, err = cli("write", "5", "Demo record.Setpoint", "-42", "--od", "builtin:fd")
    assert status == 0, err
    assert out == "wrote 2 bytes (INTEGER16) to node 5 0x2200:01 (Demo record.Setpoint)\n"
    assert server["Demo record.Setpoint"].raw == -42
    assert cli("read", "5", "0x2200:1", "--od", "builtin:fd")[1] == "-42 (0xFFD6)\n"

    assert cli("write", "5", "0x1017", "0x64", "--type", "U16")[0] == 0   # hex
    assert server[0x1017].raw == 100
    assert cli("write", "5", "0x2200:1", "0xFFFE", "--type", "I16")[0] == 0  # two's complement
    assert server["Demo record.Setpoint"].raw == -2
    assert cli("write", "5", "0x2200:4", "axis 7", "--type", "VISIBLE_STRING")[0] == 0
    assert cli("read", "5", "0x2200:4", "--type", "VISIBLE_STRING")[1] == "axis 7\n"
    assert cli("write", "5", "Demo record.Gain", "0.125", "--od", "builtin:fd")[0] == 0
    assert server["Demo record.Gain"].raw == 0.125
    for text in ("01 02 ff", "0102FF"):
        assert cli("write", "5", "0x2100", text, "--type", "DOMAIN")[0] == 0
        assert server[DOMAIN].data == b"\x01\x02\xff"
        assert cli("read", "5", "0x2100")[1] == "01 02 ff\n"


def test_write_broadcast(net, bus_name, cli):
    nodes = [make_server(net, bus_name, node_id, domain=0) for node_id in (3, 4)]
    status, out, err = cli("write", "0", "0x1017", "250", "--type", "U16", "--timeout",
                           str(scaled(0.3)))
    assert status == 0, err
    assert out.splitlines() == ["node 3: written", "node 4: written"]
    assert [node[0x1017].raw for node in nodes] == [250, 250]


def test_write_without_a_type_is_refused(server, cli):
    before = server["Demo record.Label"].raw
    status, out, err = cli("write", "5", "0x2200:4", "hello")
    one_error(status, err, "give --type or --od")
    assert out == "" and server["Demo record.Label"].raw == before
    status, _, err = cli("write", "5", "0x3000", "1", "--od", "builtin:fd")
    one_error(status, err, "not in builtin:fd", "give --type")


# ------------------------------------------------------------------ download / upload
SUMMARY = r"(\d+) bytes in (\d+\.\d{3}) s \((\d+(?:\.\d\d)?) (?:MB|kB|B)/s(?:, (\w+))?\)"


def test_download_and_upload_a_file_byte_for_byte(server, cli, tmp_path):
    payload = os.urandom(200 * KiB)
    source, copy = tmp_path / "image.bin", tmp_path / "copy.bin"
    source.write_bytes(payload)
    status, out, err = cli("download", "5", "0x2100", str(source))
    assert status == 0, err
    assert err == ""                                 # no terminal, no --progress: no bar
    match = re.fullmatch(f"downloaded {SUMMARY}: {re.escape(str(source))} -> node 5 "
                         r"0x2100:00\n", out)
    assert match, out
    assert int(match.group(1)) == len(payload) and match.group(4) == "bulk"
    assert float(match.group(3)) > 0
    assert server[DOMAIN].data == payload

    copy.write_bytes(b"old contents")
    status, out, err = cli("upload", "5", "0x2100", str(copy))
    assert status == 0, err
    match = re.fullmatch(f"uploaded {SUMMARY}: node 5 0x2100:00 -> {re.escape(str(copy))}\n",
                         out)
    assert match and int(match.group(1)) == len(payload), out
    assert copy.read_bytes() == payload
    assert sorted(os.listdir(tmp_path)) == ["copy.bin", "image.bin"]   # no temporary left


@pytest.mark.parametrize("mode, size", [("expedited", 40), ("segmented", 3000),
                                        ("bulk", 5000), ("auto", 10)])
def test_download_modes(server, cli, tmp_path, mode, size):
    payload = os.urandom(size)
    (tmp_path / "f").write_bytes(payload)
    status, out, err = cli("download", "5", "0x2100", str(tmp_path / "f"), "--mode", mode)
    assert status == 0, err
    expected = "expedited" if mode == "auto" else mode
    assert re.fullmatch(f"downloaded {SUMMARY}: .*\n", out), out
    assert f"B/s, {expected})" in out and " 0.00 " not in out    # a unit that shows the rate
    assert server[DOMAIN].data == payload


def test_progress_with_the_option(server, cli, tmp_path):
    payload = os.urandom(300 * KiB)
    (tmp_path / "image.bin").write_bytes(payload)
    status, out, err = cli("download", "5", "0x2100", str(tmp_path / "image.bin"),
                           "--progress")
    assert status == 0 and out.startswith("downloaded 307200 bytes"), err
    lines = err.splitlines()
    assert lines and all(line.startswith("download [") for line in lines), err
    assert re.fullmatch(r"download \[#{24}\] 100%  300\.0 KiB / 300\.0 KiB  \d+(\.\d\d)? [kM]?B/s  "
                        r"ETA 0:00", lines[-1]), lines[-1]
    status, out, err = cli("upload", "5", "0x2100", str(tmp_path / "copy.bin"), "--progress")
    assert status == 0 and out.startswith("uploaded 307200 bytes"), err
    lines = err.splitlines()
    assert lines and all(line.startswith("upload  ") for line in lines), err
    assert all("%" not in line and "ETA" not in line for line in lines)   # size unknown
    assert re.fullmatch(r"upload  300\.0 KiB  \d+(\.\d\d)? [kM]?B/s", lines[-1]), lines[-1]


def test_progress_bar_on_a_terminal_redraws_in_place():
    stream = io.StringIO()
    bar = ProgressBar("download", 4 * MiB, stream=stream, tty=True)
    for moved in range(0, 4 * MiB, 64 * KiB):     # many callbacks at once: one drawing
        bar(moved)
    assert stream.getvalue().count("\r") == 1
    bar.close(4 * MiB)
    text = stream.getvalue()
    assert text.count("\r") == 2 and text.endswith("ETA 0:00\n")
    assert "  0%  0 B / 4.0 MiB" in text and "100%  4.0 MiB / 4.0 MiB" in text
    bar(MiB)                                      # a late callback draws nothing
    assert stream.getvalue() == text
    quiet = io.StringIO()
    ProgressBar("upload", None, stream=quiet, tty=True).close()   # never drawn: no newline
    assert quiet.getvalue() == ""


def test_upload_streams_progress_callbacks_from_the_runtime(server, cli, tmp_path,
                                                            monkeypatch):
    """The bar is the transfer's progress callback: it sees growing counts."""
    from canopenfd.cli import transfer as cli_transfer

    seen = Recorder()

    class Spy(ProgressBar):
        def __call__(self, moved):
            seen(moved)
            super().__call__(moved)

    monkeypatch.setattr(cli_transfer, "ProgressBar", Spy)
    server[DOMAIN].data = os.urandom(MiB)
    assert cli("upload", "5", "0x2100", str(tmp_path / "copy.bin"), "--progress")[0] == 0
    seen.wait_count(1)      # progress calls run on the dispatcher thread
    counts = seen.snapshot()
    assert counts and counts == sorted(counts) and counts[-1] <= MiB
    assert (tmp_path / "copy.bin").read_bytes() == server[DOMAIN].data


def test_client_id_and_timeout(net, bus_name, server, cli):
    frames = Recorder()
    net.open_line(bus_name, mode="fd", monitor=True).on_frame(frames)
    assert cli("read", "5", "0x1017", "--client-id", "100") == (0, "00 00\n", "")
    request = frames.wait_for(lambda c: [f for f in c if f.id == 0x600 + 100], 2,
                              "the request of client 100")[0]
    assert request.data[:2] == bytes([SERVER, 0x11])      # to node 5: upload
    started = time.monotonic()
    assert cli("read", "42", "0x1017", "--timeout", "0.3")[0] == 1   # nobody answers
    assert 0.25 <= time.monotonic() - started < scaled(3)


# ------------------------------------------------------------------ failures
def test_an_abort_exits_1_with_its_text(server, cli, tmp_path):
    status, out, err = cli("read", "5", "0x5FFF")
    one_error(status, err, "0x5FFF:00 from node 5", "USDO abort 0x33 (object does not exist) "
              "from the server", code=1)
    assert out == ""
    status, _, err = cli("write", "5", "0x1018:1", "1", "--type", "U32")     # read-only
    one_error(status, err, "0x1018:01", "USDO abort", code=1)
    status, _, err = cli("read", "42", "0x1000:1", "--timeout", "0.1")       # nobody there
    one_error(status, err, "node 42", "USDO abort 0x12", "from the client", code=1)
    # a failed upload leaves FILE as it was, and no temporary file
    target = tmp_path / "keep.bin"
    target.write_bytes(b"precious")
    status, out, err = cli("upload", "5", "0x5FFF", str(target), "--progress")
    assert status == 1 and "USDO abort 0x33" in err and out == ""
    assert target.read_bytes() == b"precious" and os.listdir(tmp_path) == ["keep.bin"]
    status, _, err = cli("upload", "5", "0x5FFF", str(tmp_path / "new.bin"))
    assert status == 1 and os.listdir(tmp_path) == ["keep.bin"]
    status, out, err = cli("download", "5", "0x1018:1", str(target))
    one_error(status, err, "USDO abort", code=1)


@pytest.mark.parametrize("argv, words", [
    (("read", "200", "0x1017"), ("NODE 200 outside 0..127",)),
    (("read", "five", "0x1017"), ("NODE 'five' is not a node-id",)),
    (("upload", "0", "0x2100", "x.bin"), ("NODE 0 (broadcast) works only with read and write",)),
    (("read", "5", "0x12345"), ("INDEX '0x12345' is not INDEX[:SUB]",)),
    (("read", "5", "1017:100"), ("INDEX '1017:100'",)),
    (("read", "5", "Producer heartbeat time"), ("names need --od FILE",)),
    (("read", "5", "No such thing", "--od", "builtin:fd"), ("no such name",)),
    (("read", "5", "Identity object", "--od", "builtin:fd"),
     ("RECORD 0x1018", "give a sub-index", "Identity object.Vendor-ID")),
    (("read", "5", "0x1017", "--od", "no-such.eds"), ("--od no-such.eds",)),
    (("read", "5", "0x1017", "--type", "U33"), ("--type 'U33' is not a data type",)),
    (("write", "5", "0x1017", "abc", "--type", "U16"),
     ("VALUE 'abc' is no UNSIGNED16", "not an integer")),
    (("write", "5", "0x1017", "70000", "--type", "U16"),
     ("VALUE '70000' is no UNSIGNED16", "70000 outside UNSIGNED16 0..65535")),
    (("write", "5", "Demo record.Setpoint", "900", "--od", "builtin:fd"),
     ("VALUE '900'", "Setpoint", "above HighLimit 500")),
    (("write", "5", "0x2100", "0g", "--type", "DOMAIN"), ("VALUE '0g' is no DOMAIN",)),
    (("write", "5", "0x2100", "123", "--type", "DOMAIN"), ("odd number of hex digits",)),
    (("write", "0", "0x2100", "00" * 57, "--type", "DOMAIN"), ("at most 56",)),
    (("read", "5", "0x1017", "--client-id", "128"), ("--client-id 128 outside 1..127",)),
    (("read", "127", "0x1017"), ("NODE 127 is our own USDO client id",)),
    (("read", "5", "0x1017", "--timeout", "0"), ("--timeout 0 s",)),
    (("read", "0", "0x1017", "--classic"), ("one node at a time",)),
    (("download", "5", "0x2100", "no-such-file.bin"), ("FILE no-such-file.bin",)),
    (("upload", "5", "0x2100", "/no/such/dir/x.bin"), ("directory /no/such/dir does not exist",)),
])
def test_bad_arguments_exit_2(server, cli, argv, words):
    status, out, err = cli(*argv)
    one_error(status, err, *words)
    assert out == ""


def test_bad_download_arguments_exit_2(server, cli, tmp_path):
    big = tmp_path / "big.bin"
    big.write_bytes(bytes(100))
    one_error(*cli("download", "5", "0x2100", str(big), "--mode", "expedited")[::2],
              "--mode expedited carries at most 56 bytes")
    one_error(*cli("download", "5", "0x2100", str(tmp_path))[::2], "FILE")


def test_argparse_errors_exit_2(net, capsys):
    for argv in (["write", "5", "0x1017", "--channel", "mem:x"],          # VALUE missing
                 ["download", "5", "0x2100", "f", "--mode", "fast", "--channel", "mem:x"],
                 ["read", "5", "0x1017", "--timeout", "soon", "--channel", "mem:x"]):
        with pytest.raises(SystemExit) as info:
            main(argv, network=net)
        assert info.value.code == 2
        err = capsys.readouterr().err
        assert "error:" in err and "Traceback" not in err


# ------------------------------------------------------------------ helpers
def test_key_and_type_parsing():
    od = demo_od("fd")
    assert parse_key("0x1018:1", None) == (0x1018, 1, None)
    assert parse_key("1018sub04", None) == (0x1018, 4, None)
    assert parse_key("2100", None) == (0x2100, 0, None)
    index, sub, variable = parse_key("Identity object.Serial number", od)
    assert (index, sub, variable.name) == (0x1018, 4, "Serial number")
    assert parse_key("0x1018", od)[:2] == (0x1018, 0)        # hex keeps sub 0
    for text, dtype in (("U8", DataType.UNSIGNED8), ("i64", DataType.INTEGER64),
                        ("real32", DataType.REAL32), ("7", DataType.UNSIGNED32),
                        ("0x0F", DataType.DOMAIN), ("string", DataType.VISIBLE_STRING),
                        ("visible-string", DataType.VISIBLE_STRING)):
        assert parse_type(text) == dtype


# ------------------------------------------------------------------ device as the server
def run_device(net, bus, *options, duration=2.0):
    """`canopenfd device` on the test's Network, in a thread; returns the
    thread and a remote view of node 6 on a line of the test."""
    line = net.open_line(bus, mode="fd")
    remote = line.add_node(6)
    booted = threading.Event()
    remote.on_bootup(booted.set)
    status = []
    thread = threading.Thread(target=lambda: status.append(main(
        ["device", "--channel", bus, "--node-id", "6", "--duration", str(scaled(duration)),
         *options], network=net)))
    thread.start()
    assert booted.wait(scaled(5)), "the device did not boot"
    return thread, status


def test_device_backs_the_demo_domain_with_16_mib(net, bus_name, cli, tmp_path, capsys):
    thread, status = run_device(net, bus_name)
    try:
        payload = os.urandom(300 * KiB)
        (tmp_path / "image.bin").write_bytes(payload)
        assert cli("download", "6", "0x2100", str(tmp_path / "image.bin"))[0] == 0
        assert cli("upload", "6", "Demo large domain", str(tmp_path / "copy.bin"),
                   "--od", "builtin:fd")[0] == 0
        assert (tmp_path / "copy.bin").read_bytes() == payload
    finally:
        thread.join(scaled(10))
    assert status == [0]


def test_device_domain_option_with_an_od_file(net, bus_name, cli, tmp_path):
    eds = tmp_path / "device.eds"
    export_eds(demo_od("fd"), str(eds))
    thread, status = run_device(net, bus_name, "--od", str(eds),
                                "--domain", "Demo large domain=512K", "--domain", "0x200F=1K")
    try:
        payload = os.urandom(400 * KiB)
        (tmp_path / "image.bin").write_bytes(payload)
        assert cli("download", "6", "0x2100", str(tmp_path / "image.bin"))[0] == 0
        assert cli("upload", "6", "0x2100", str(tmp_path / "copy.bin"))[0] == 0
        assert (tmp_path / "copy.bin").read_bytes() == payload
        assert cli("write", "6", "0x200F", "ab" * 100, "--type", "DOMAIN")[0] == 0
        assert cli("read", "6", "0x200F")[1] == " ".join(["ab"] * 100) + "\n"
        (tmp_path / "big.bin").write_bytes(bytes(600 * KiB))     # more than the 512 KiB
        assert cli("download", "6", "0x2100", str(tmp_path / "big.bin"))[0] == 1
    finally:
        thread.join(scaled(10))
    assert status == [0]


@pytest.mark.parametrize("option, words", [
    ("0x2001=1M", ("Demo BOOLEAN is BOOLEAN, not a DOMAIN",)),
    ("0x3000=1M", ("0x3000:00 is not in the object dictionary",)),
    ("0x2100=1Q", ("'1Q' is not a size",)),
    ("0x2100", ("expected INDEX[:SUB]=BYTES",)),
    ("0x2100=0", ("0 bytes outside",)),
])
def test_device_bad_domain_exits_2(net, bus_name, capsys, option, words):
    status = main(["device", "--channel", bus_name, "--node-id", "6", "--duration", "0.1",
                   "--domain", option], network=net)
    one_error(status, capsys.readouterr().err, "--domain", *words)


def test_rate_text_picks_a_unit_that_shows_the_rate():
    from canopenfd.cli.common import rate_text
    assert [rate_text(n, 1.0) for n in (0, 812, 5000, 35_200, 2_410_000)] == \
        ["0 B/s", "812 B/s", "5.00 kB/s", "35.20 kB/s", "2.41 MB/s"]
    assert rate_text(5000, 0) == "- B/s"


@pytest.mark.parametrize("mode, first, shown", [("block", 0xA4, "block"),
                                                ("normal", 0x40, "segmented"),
                                                ("auto", 0x40, "segmented")])
def test_classic_upload_mode_asks_for_block_or_normal(net, bus_name, cli, tmp_path, mode,
                                                      first, shown):
    """`upload --classic --mode block` asks for a block upload (the request's
    first byte 0xA4: ccs 5, CRC offered), normal / auto for a normal one (0x40)."""
    node = net.open_line(bus_name, mode="classic").create_local_node(SERVER,
                                                                    od=demo_od("classic"),
                                                                    boot=False)
    node.serve_domain(DOMAIN, 64 * KiB)
    node.boot()
    payload = os.urandom(3000)
    node[DOMAIN].data = payload
    requests = Recorder()
    watcher = net.open_line(bus_name, mode="classic", monitor=True)
    watcher.on_frame(lambda f: requests(f) if f.id == 0x600 + SERVER else None)
    target = tmp_path / "up.bin"
    status, out, err = cli("upload", "5", "0x2100", str(target), "--classic", "--mode", mode)
    assert status == 0, err
    assert re.fullmatch(f"uploaded {SUMMARY}: .*\n", out) and f", {shown})" in out, out
    assert target.read_bytes() == payload
    assert requests.wait_count(1)[0].data[0] == first


def test_upload_mode_is_refused_on_fd_lines(server, cli, tmp_path):
    status, _, err = cli("upload", "5", "0x2100", str(tmp_path / "x"), "--mode", "block")
    one_error(status, err, "--mode block", "--classic")
    status, _, err = cli("upload", "5", "0x2100", str(tmp_path / "x"), "--classic", "--mode",
                         "bulk")
    one_error(status, err, "--mode bulk", "--mode block")


def test_usdo_upload_mode_bulk_asks_the_server_to_stream(net, bus_name, cli, tmp_path):
    """`upload --mode bulk` sends 0x16 (our bulk upload request, with the
    client's window) and the summary names the bulk mode."""
    node = net.open_line(bus_name, mode="fd").create_local_node(SERVER, od=demo_od("fd"),
                                                               boot=False)
    node.serve_domain(DOMAIN, 64 * KiB)
    node.boot()
    payload = os.urandom(30000)
    node[DOMAIN].data = payload
    requests = Recorder()
    watcher = net.open_line(bus_name, mode="fd", monitor=True)
    watcher.on_frame(lambda f: requests(f) if 0x601 <= f.id <= 0x67F else None)
    target = tmp_path / "up.bin"
    status, out, err = cli("upload", "5", "0x2100", str(target), "--mode", "bulk")
    assert status == 0, err
    assert re.fullmatch(f"uploaded {SUMMARY}: .*\n", out) and ", bulk)" in out, out
    assert target.read_bytes() == payload
    first = requests.wait_count(1)[0]
    assert first.data[0] == SERVER and first.data[1] == 0x16 and first.data[3:6] == \
        bytes([0, 0x00, 0x21])


def test_device_names_a_domain_without_memory_and_the_option_that_fixes_it(
        net, bus_name, tmp_path, capsys):
    """A vendor file's DOMAIN above 64 KiB (here the demo's 0x2100 read from an
    EDS, no --domain) is refused to the network: the device says so at start."""
    eds = tmp_path / "device.eds"
    export_eds(demo_od("fd"), str(eds))
    thread, status = run_device(net, bus_name, "--od", str(eds), duration=0.5)
    thread.join(scaled(10))
    assert status == [0]
    err = capsys.readouterr().err
    assert ("0x2100:00 Demo large domain is a DOMAIN without memory" in err and
            "--domain 0x2100:00=SIZE" in err), err
    assert "0x200F" not in err                       # 1 KiB: memory of its own
