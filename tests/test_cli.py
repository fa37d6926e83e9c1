"""The `canopenfd` command, run as `python -m canopenfd` in a subprocess."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest
from helpers import NEUTRAL_CWD, package_env, run_cli, scaled

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
run = run_cli


def assert_clean_error(result: subprocess.CompletedProcess, *words: str) -> None:
    assert result.returncode == 2, result
    assert "Traceback" not in result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("canopenfd: error: ")
    for word in words:
        assert word in lines[0]


def test_version():
    result = run("--version")
    assert result.returncode == 0
    assert result.stdout.strip() == "canopenfd 0.1.0"


def test_demo():
    result = run("demo", "--duration", "1.5")
    assert result.returncode == 0, result.stderr
    out = result.stdout
    for text in ("boot-up node 2 [FD BRS]", "NMT start node 2", "NMT stop node 2",
                 "NMT pre-operational node 2", "NMT reset-comm node 2",
                 "heartbeat node 2 OPERATIONAL", "heartbeat node 2 STOPPED",
                 "PRE-OPERATIONAL -> OPERATIONAL", "sees node 2 boot-up",
                 "node 2 heartbeat lost"):
        assert text in out, f"{text!r} missing from the demo output:\n{out}"
    # every line starts with a time stamp
    for line in out.strip().splitlines():
        float(line.split()[0])


def test_bad_node_id_exits_2():
    assert_clean_error(run("device", "--channel", "mem:x", "--node-id", "200"), "node-id 200")
    assert_clean_error(run("nmt", "start", "300", "--channel", "mem:x"), "node-id 300")
    assert_clean_error(run("nmt", "start", "five", "--channel", "mem:x"), "'five'")


def test_bad_interface_exits_2():
    assert_clean_error(run("monitor", "--channel", "nosuchcan9", "--duration", "0.1"),
                       "nosuchcan9")
    assert_clean_error(run("nmt", "start", "5", "--channel", "x", "--interface", "nosuch"),
                       "nosuch")


def test_usage_error_exits_2():
    result = run("nmt", "jump", "5", "--channel", "mem:x")
    assert result.returncode == 2 and "invalid choice" in result.stderr


def test_nmt_and_monitor_on_in_process_and_virtual_buses():
    result = run("nmt", "reset-comm", "all", "--channel", "mem:x")
    assert result.returncode == 0, result.stderr
    assert "sent NMT reset-comm to all nodes on mem:x (fd)" in result.stdout
    pytest.importorskip("can")
    result = run("nmt", "start", "5", "--channel", "cli-test", "--interface", "virtual",
                 "--classic")
    assert result.returncode == 0, result.stderr
    assert "sent NMT start to node 5 on cli-test (classic)" in result.stdout
    result = run("monitor", "--channel", "mem:x", "--duration", "0.2")
    assert result.returncode == 0, result.stderr


def test_main_in_process(capsys):
    from canopenfd.cli import main

    assert main(["device", "--channel", "mem:cli", "--node-id", "3", "--heartbeat", "20",
                 "--duration", "0.2"]) == 0
    assert main(["device", "--channel", "mem:cli", "--node-id", "3", "--heartbeat",
                 "70000"]) == 2
    err = capsys.readouterr().err
    assert "--heartbeat 70000 ms outside 0..65535" in err


def test_example_nmt_heartbeat_runs():
    result = subprocess.run([sys.executable, os.path.join(ROOT, "examples", "nmt_heartbeat.py")],
                            capture_output=True, text=True, timeout=scaled(60),
                            env=package_env(), cwd=NEUTRAL_CWD, check=False)
    assert result.returncode == 0, result.stderr
    for text in ("manager: node 2 booted", "device:  PRE-OPERATIONAL -> OPERATIONAL",
                 "manager: node 2 is STOPPED", "manager: node 2 heartbeat lost"):
        assert text in result.stdout, result.stdout
