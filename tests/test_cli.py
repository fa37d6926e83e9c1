"""The `canopenfd` command, run as `python -m canopenfd` in a subprocess."""

from __future__ import annotations

import os
import subprocess
import sys
import threading

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
                 "node 2 heartbeat lost",
                 # USDO: a typed read, a write read back, 1 MiB each way
                 "upload request 0x1018:01", "node 2 Vendor-ID = 0 (0x00000000)",
                 "download expedited 0x2200:01 I16 N=2 7B 00", "Setpoint reads back 123",
                 "download: 1048576 bytes, bulk, ", "node 2 holds identical bytes",
                 "upload: 1048576 bytes, ", "identical to what was sent"):
        assert text in out, f"{text!r} missing from the demo output:\n{out}"
    assert "B/s" in out and "DIFFERENT" not in out
    assert len(out.splitlines()) < 100           # the bulk frames are not printed
    assert "events lost" not in result.stderr
    # every line starts with a time stamp
    for line in out.strip().splitlines():
        float(line.split()[0])
    check_demo_process_data(out, fd=True)
    # the last line tells node 2's real state and marks node 1's view as stale
    last = out.strip().splitlines()[-1]
    assert "done: node 2 is OPERATIONAL; last states heard by node 1 {" in last, last
    assert "heartbeat is off" in last, last


def _after(out: str, marker: str) -> str:
    """The rest of the demo line holding marker (it must be there)."""
    lines = [line for line in out.splitlines() if marker in line]
    assert len(lines) == 1, f"{marker!r} in {len(lines)} lines of:\n{out}"
    return lines[0].split(marker, 1)[1]


def check_demo_process_data(out: str, fd: bool) -> None:
    """The demo's PDO, SYNC and EMCY part: values received equal the values
    sent (64 bytes on fd lines, 8 on classic ones), synchronous PDOs follow
    the SYNC counter, the EMCY is raised then removed with every field."""
    count = 16 if fd else 2
    assert f"maps Process data 1..{count} (UNSIGNED32): {count * 4} bytes" in out, out
    sent = _after(out, f"TPDO1 transmit: Process data 1..{count} = ").split()
    assert sent == [str(n * 1001) for n in range(1, count + 1)]
    got = _after(out, f"RPDO1 from node 2: {count * 4} bytes, Process data 1..{count} = ")
    assert got.split() == sent
    assert "RPDO1 values equal what node 2 sent" in out
    # four synchronous answers: SYNC counter 1..4, Process data 1 the value
    # node 2 wrote at an earlier SYNC (10 x its counter), the rest as sent
    syncs = [line.split("node 1   SYNC ", 1)[1] for line in out.splitlines()
             if "-> RPDO1 from node 2" in line]
    assert len(syncs) == 4, out
    counters = [int(line.split()[0]) for line in syncs]
    assert counters == [1, 2, 3, 4], out
    values = [int(line.split("Process data 1 = ")[1].split(",")[0]) for line in syncs]
    assert values[0] in (1001, 10) and all(v % 10 == 0 and v < 10 * c
                                           for v, c in zip(values[1:], counters[1:])), out
    assert all(line.endswith("unchanged") for line in syncs), out
    assert "SYNC stopped; 4 synchronous PDOs shown" in out
    # EMCY raised: every field on node 1's side, then removed
    raised = _after(out, "node 1   EMCY from node 2: code 0x2310 current, device output "
                         "side (current), register 0x83, ")
    assert raised.startswith("data 01 02 00 00 00") and "removed" not in raised
    if fd:
        assert ("logical device 1, spec 301, priority 2, non-recoverable False, "
                "occurred True, repeated False, time stamp 123456789") in raised
        removed = _after(out, "node 1   EMCY from node 2: code 0x2310 current, device output "
                              "side (current), register 0x00")
        assert "occurred False" in removed and removed.endswith("error removed")
    else:
        assert "logical device" not in raised
        removed = _after(out, "node 1   EMCY from node 2: code 0x0000 error reset")
        assert removed.endswith("error removed")
    assert "1 active; node 1 sees active [0x2310]" in out
    assert "0 active; node 1 sees active []" in out
    lines = out.splitlines()
    assert lines.index(next(line for line in lines if "sees active [0x2310]" in line)) < \
        lines.index(next(line for line in lines if "sees active []" in line))


def test_demo_classic():
    result = run("demo", "--classic", "--duration", "1.0")
    assert result.returncode == 0, result.stderr
    out = result.stdout
    assert "[FD" not in out
    for text in ("boot-up node 2", "NMT start node 2", "node 2 heartbeat lost",
                 "node 2 Vendor-ID = 0 (0x00000000)", "Setpoint reads back 123",
                 "download: 65536 bytes, block, ", "node 2 holds identical bytes",
                 "upload: 65536 bytes, block, ", "identical to what was sent"):
        assert text in out, f"{text!r} missing from the classic demo output:\n{out}"
    assert "events lost" not in result.stderr
    check_demo_process_data(out, fd=False)


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


def _cli_actions():
    """(command path, argparse action) of every argument of every command."""
    import argparse

    from canopenfd.cli import build_parser

    def walk(parser, path):
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for name, child in action.choices.items():
                    yield from walk(child, path + (name,))
            else:
                yield path, action

    return list(walk(build_parser(), ()))


def test_every_argument_has_a_help_text():
    missing = [" ".join(path + (action.option_strings[-1] if action.option_strings
                                else action.dest,))
               for path, action in _cli_actions() if not action.help]
    assert missing == []


def test_timeout_help_mentions_node_0_only_where_node_0_is_allowed():
    timeouts = {path[0]: action.help for path, action in _cli_actions()
                if "--timeout" in action.option_strings and path[0] != "nmt"}
    assert set(timeouts) == {"read", "write", "download", "upload"}
    for command, text in timeouts.items():
        assert ("NODE 0" in text) == (command in ("read", "write")), (command, text)


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


# ------------------------------------------------------------------ device --od / --store
DATA = os.path.join(ROOT, "tests", "data", "od")


def device(*args: str, duration: str = "0.5") -> subprocess.CompletedProcess:
    return run("device", "--channel", "mem:x", "--node-id", "5", "--duration", duration, *args)


def started_line(result: subprocess.CompletedProcess) -> str:
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr
    lines = [line for line in result.stderr.splitlines() if line.startswith("node 5 running on ")]
    assert len(lines) == 1, result.stderr
    assert "node 5: INITIALISING -> PRE-OPERATIONAL" in result.stdout
    return lines[0]


@pytest.mark.parametrize("args, mode, od", [
    ((), "fd", "builtin:fd"),
    (("--classic",), "classic", "builtin:classic"),
    (("--od", "builtin:classic", "--classic"), "classic", "builtin:classic"),
    (("--od", "builtin:fd"), "fd", "builtin:fd"),
])
def test_device_serves_the_builtin_od(args, mode, od):
    line = started_line(device(*args))
    assert f"({mode}), heartbeat 0 ms, object dictionary {od};" in line


def test_device_serves_an_od_file_and_its_heartbeat():
    for name, heartbeat in (("commissioned.dcf", 250), ("classic_node.xdc", 500)):
        path = os.path.join(DATA, name)
        line = started_line(device("--classic", "--od", path))
        assert f"heartbeat {heartbeat} ms, object dictionary {path};" in line


@pytest.mark.parametrize("value", ["0", "40"])
def test_device_heartbeat_overrides_0x1017(value):
    path = os.path.join(DATA, "commissioned.dcf")                     # 0x1017 = 250
    line = started_line(device("--classic", "--od", path, "--heartbeat", value))
    assert f"heartbeat {value} ms" in line


def test_device_heartbeat_on_the_bus_from_the_od():
    """The device's heartbeat comes from the DCF's 0x1017 (250 ms): another
    bus on the same python-can virtual channel sees its frames."""
    can = pytest.importorskip("can")
    channel = f"cli-od-{os.getpid()}"
    path = os.path.join(DATA, "commissioned.dcf")
    command = ["device", "--channel", channel, "--interface", "virtual", "--classic",
               "--node-id", "5", "--od", path]
    from canopenfd.cli import main

    duration = scaled(1.2)
    bus = can.Bus(interface="virtual", channel=channel, receive_own_messages=False)
    try:
        seen = []
        stop = threading.Event()

        def listen():
            while not stop.is_set():
                msg = bus.recv(0.05)
                if msg is not None:
                    seen.append(msg)
        listener = threading.Thread(target=listen)
        listener.start()
        try:
            assert main(command + ["--duration", str(duration)]) == 0
        finally:
            stop.set()
            listener.join()
    finally:
        bus.shutdown()
    beats = [m for m in seen if m.arbitration_id == 0x705 and bytes(m.data) == b"\x7f"]
    expected = duration / 0.25
    assert 2 <= len(beats) <= expected + 3, f"{len(beats)} heartbeats in {duration:g} s at 250 ms"
    assert all(not m.is_fd for m in beats)


def test_device_store_keeps_saved_parameters(tmp_path):
    """The device saves nothing by itself; values saved in the store (here by
    a node of this process) come back when the device boots with --store."""
    import canopenfd
    from canopenfd.od import demo_od

    store = str(tmp_path / "params.bin")
    line = started_line(device("--store", store))
    assert f"parameters in {store};" in line
    assert not os.path.exists(store)
    with canopenfd.Network() as net:
        node = net.open_line("mem:save").create_local_node(5, od=demo_od("fd"), store=store)
        node[0x1017].raw = 30
        node.save_parameters()
    assert "heartbeat 30 ms" in started_line(device("--store", store))
    assert "heartbeat 70 ms" in started_line(device("--store", store, "--heartbeat", "70"))


def test_device_damaged_store_is_reported(tmp_path):
    store = tmp_path / "params.bin"
    store.write_bytes(b"\x55" * 64)
    result = device("--store", str(store))
    assert "heartbeat 0 ms" in started_line(result)
    assert f"saved parameters in {store} are" in result.stdout


@pytest.mark.parametrize("args, words", [
    # a file the lenient import still refuses (bad_datatype.eds loads since issue 14)
    (("--od", os.path.join(DATA, "hostile", "huge_subnumber.eds")),
     (f"--od {os.path.join(DATA, 'hostile', 'huge_subnumber.eds')}:11 [1016]",
      "SubNumber 100000000")),
    (("--od", os.path.join(DATA, "hostile", "truncated.xdd")),
     (f"--od {os.path.join(DATA, 'hostile', 'truncated.xdd')}:4",)),
    (("--od", "no-such-file.eds"), ("--od no-such-file.eds: no such file",)),
    (("--od", "builtin:can"), ("builtin:fd and builtin:classic",)),
    (("--store", os.path.join(ROOT, "no-such-dir", "p.bin")), ("--store", "no-such-dir",
                                                                "does not exist")),
    (("--heartbeat", "-5"), ("--heartbeat -5 ms outside 0..65535",)),
])
def test_device_bad_od_or_store_exits_2(args, words):
    assert_clean_error(device(*args), *words)
