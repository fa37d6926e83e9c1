"""`canopenfd od show|check FILE`, run as `python -m canopenfd od ...` in a subprocess
from a neutral working directory, plus the in-process entry point."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys

import pytest
from helpers import package_env, scaled

from canopenfd.cli.od import main as od_main

DATA = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data", "od")
HOSTILE = os.path.join(DATA, "hostile")


def run_od(cwd, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "canopenfd", "od", *args],
                          capture_output=True, text=True, timeout=scaled(60),
                          env=package_env(), cwd=str(cwd), check=False)


def data(name: str) -> str:
    return os.path.join(DATA, name)


def test_show_every_kind_of_file(tmp_path):
    for name, header, row in (
            ("classic_vendor.eds", "classic_vendor.eds: EDS, classic, node-id -, 17 objects",
             "0x1014     COB-ID EMCY"),
            ("commissioned.dcf", "commissioned.dcf: DCF, classic, node-id 5",
             "$NODEID+0x180 (0x185)"),
            ("fd_device.xdd", "fd_device.xdd: XDD, fd, node-id -, 25 objects",
             "0x1030     Version Information"),
            ("classic_node.xdc", "classic_node.xdc: XDC, classic, node-id 32",
             "value=0x000101F4")):
        result = run_od(tmp_path, "show", data(name))
        assert result.returncode == 0, result.stderr
        lines = result.stdout.splitlines()
        assert lines[0].startswith(header), lines[0]
        assert "index:sub  name" in result.stdout and row in result.stdout
        assert result.stderr == ""


def test_show_table_columns_and_builtin(tmp_path):
    result = run_od(tmp_path, "show", "builtin:fd", "--node-id", "4")
    assert result.returncode == 0, result.stderr
    out = result.stdout
    assert out.startswith("builtin:fd: built-in demo, fd, node-id 4, 35 objects, 60 entries")
    header = next(line for line in out.splitlines() if line.startswith("index:sub"))
    assert header.split() == ["index:sub", "name", "type", "access", "default", "limits",
                              "pdo", "flags"]
    row = next(line for line in out.splitlines() if line.startswith("0x2006 "))
    assert row.split() == ["0x2006", "Demo", "UNSIGNED16", "UNSIGNED16", "rw", "1000",
                           "10..5000", "both", "store"]
    assert "0x2200:04    Label" in out and "0x2200:03" not in out
    assert "fd-only" in out and "max=16777216" in out
    classic = run_od(tmp_path, "show", "builtin:classic")
    assert "0x1000     Device type  " in classic.stdout and "0x1030" not in classic.stdout


def test_check_clean_file_exits_0(tmp_path):
    result = run_od(tmp_path, "check", data("fd_device.xdd"))
    assert result.returncode == 0, result.stdout + result.stderr
    assert result.stdout.strip().endswith("(25 objects, 114 entries, fd)")
    assert "OK: 0 errors" in result.stdout


def test_check_warnings_only_exits_0(tmp_path):
    result = run_od(tmp_path, "check", data("classic_vendor.eds"))
    assert result.returncode == 0
    assert f"warning: {data('classic_vendor.eds')}:389 [2000]: duplicate key AccessType" \
        in result.stdout
    assert "OK: 0 errors, 1 warning" in result.stdout


def test_check_semantic_errors_exit_1(tmp_path):
    result = run_od(tmp_path, "check", os.path.join(HOSTILE, "semantic_errors.eds"))
    assert result.returncode == 1
    out = result.stdout
    assert "error: 0x1017:00 Producer heartbeat time: default: 5000 above HighLimit 1000" in out
    assert "COB-ID $NODEID+0x180 is also used by 0x1801:01" in out
    assert "FAILED: 3 errors" in out


def test_check_recovered_deviation_is_an_error_exit_1(tmp_path):
    # issue 14: import is lenient (the entry is served as bytes), `od check`
    # still reports the deviation as an error and exits 1
    path = os.path.join(HOSTILE, "bad_datatype.eds")
    result = run_od(tmp_path, "check", path)
    assert result.returncode == 1
    assert (f"error: {path}:27 [1018sub2]: DataType 0x0099 is not a CiA 301 data type"
            in result.stdout)
    assert "served as OCTET_STRING" in result.stdout
    assert "bad_datatype.eds: FAILED: 3 errors" in result.stdout  # + 0x1018:02 type
    assert "cannot be read" not in result.stdout and "Traceback" not in result.stderr


@pytest.mark.parametrize("name, words", [
    ("billion_laughs.xdd", "billion_laughs.xdd:2: <!DOCTYPE declarations are not allowed"),
    ("garbage.eds", "binary data"),
])
def test_check_unreadable_file_exits_1(tmp_path, name, words):
    result = run_od(tmp_path, "check", os.path.join(HOSTILE, name))
    assert result.returncode == 1
    assert result.stdout.startswith("error: ") and words in result.stdout
    assert "cannot be read" in result.stdout and "Traceback" not in result.stderr


def test_mode_option_and_unknown_extension_sniffing(tmp_path):
    shutil.copy(data("classic_vendor.eds"), tmp_path / "vendor.txt")
    shutil.copy(data("fd_device.xdd"), tmp_path / "drive.cfg")
    assert run_od(tmp_path, "check", "vendor.txt").returncode == 0
    assert run_od(tmp_path, "check", "drive.cfg").returncode == 0
    result = run_od(tmp_path, "check", "drive.cfg", "--mode", "classic")
    assert result.returncode == 1 and "must be a VAR of UNSIGNED32 on classic" in result.stdout


def test_usage_errors_exit_2_with_one_line(tmp_path):
    for args, words in ((("show", "nosuch.eds"), "nosuch.eds: no such file"),
                        (("check", "nosuch.xdd"), "nosuch.xdd: no such file"),
                        (("show", str(tmp_path)), "is a directory"),
                        (("show", "builtin:can"), "builtin:fd and builtin:classic"),
                        (("show", data("commissioned.dcf"), "--node-id", "200"),
                         "--node-id 200 outside 1..127")):
        result = run_od(tmp_path, *args)
        assert result.returncode == 2, (args, result)
        lines = result.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("canopenfd: error: ")
        assert words in lines[0]
    result = run_od(tmp_path, "frobnicate", "x.eds")
    assert result.returncode == 2 and "invalid choice" in result.stderr


def test_in_process_entry_point(capsys):
    assert od_main(["check", data("commissioned.dcf")]) == 0
    assert "commissioned.dcf: OK" in capsys.readouterr().out
    assert od_main(["show", "nosuch.eds"]) == 2
    assert "nosuch.eds: no such file" in capsys.readouterr().err
