"""Every example in examples/ runs (a subprocess, as a reader would start it)
and prints what it promises; the ones needing a SocketCAN interface run in
the vcan lane."""

from __future__ import annotations

import os
import pathlib
import subprocess
import sys

import pytest

from helpers import NEUTRAL_CWD, package_env, scaled

EXAMPLES = pathlib.Path(__file__).resolve().parent.parent / "examples"

#: example -> (arguments, lines its output must hold)
EXPECTED = {
    "nmt_heartbeat.py": ((), ["manager: node 2 booted", "manager: node 2 is STOPPED",
                              "manager: node 2 heartbeat lost"]),
    "device_with_eds.py": ((), [
        "tool:    write -100 refused: 0x08000022",
        "device:  setpoint 2800 accepted",
        "tool:    EMCY 0x8611",
        "tool:    not sent: 0x2000:00 Speed setpoint: 9999 above HighLimit 3000",
        "tool:    write 9999 refused: 0x06090031",
        "device:  after reset, acceleration = 800"]),
    "transfer_by_name.py": ((), ["fd      USDO  Setpoint read back: -321",
                                 "classic SDO   Setpoint read back: -321",
                                 "classic SDO   write refused: 0x06010002"]),
    "pdo_remap.py": ((), ["mapped: ['Process data.Process data 1'", "on COB-ID 0x185",
                          "PDOs received: 10; last values [5, 0, 0, 5000]"]),
    "sync_cyclic.py": (("--cycles", "30"), ["cycles received: 30", "no cycle skipped"]),
    "process_image_host.py": ((), ["host: task 1234h version 1.2, status 01h",
                                   "host: InitCANopen -> True", "host: NMTChange 7Fh",
                                   "host: NMTChange 05h", "network: TPDO 1 carries 12 34",
                                   "host: ReceivedData 2..3, read ab cd",
                                   "host: read past the end gives 2 bytes, from offset 9 0"]),
    "asyncio_many.py": ((), [f"node {n}: vendor 00000000, 65536 bytes ok" for n in range(2, 10)]
                        + ["24 transfers, 8 at a time"]),
    "firmware_download.py": ((), ["downloaded 1048576 bytes (bulk)", "device: image verified"]),
    "firmware_download.py --classic": (("--classic", "--size", "100000"),
                                       ["downloaded 100000 bytes (block)",
                                        "device: image verified"]),
    "interfaces.py": ((), ["opened <Line 'Virtual bus channel interfaces-example' fd",
                           "node 5: vendor 0x00000000"]),
    "interfaces.py --classic": (("--classic",), ["classic #0>", "node 5: vendor 0x00000000"]),
    "io_device.py": ((), ["master:  device type 0x000F0191",
                          "master:  TPDO1 digital inputs 03 00",
                          "device:  digital outputs 10001111", "device:  analogue output 1 = -300",
                          "device:  digital outputs 10001110",
                          "device:  after NMT stop Outputs(digital=142, analog=(0, 0))"]),
}
#: examples that need a SocketCAN interface (tested on vcan below)
NEEDS_VCAN = {"two_processes.py"}
#: examples whose test lives with their feature's tests
TESTED_ELSEWHERE = {"master_drives_rpdo.py": "tests/test_master_rpdo.py",
                    "cia402_drive.py": "tests/test_cia402.py",
                    "mqtt_gateway.py": "tests/test_gateway_mqtt.py"}


def run_example(name: str, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(EXAMPLES / name), *args], cwd=NEUTRAL_CWD,
                          env=package_env(), capture_output=True, text=True,
                          timeout=scaled(120))


def test_every_example_is_tested():
    scripts = {p.name for p in EXAMPLES.glob("*.py")}
    covered = {key.split()[0] for key in EXPECTED} | NEEDS_VCAN | set(TESTED_ELSEWHERE)
    assert scripts <= covered, f"examples without a test: {sorted(scripts - covered)}"


@pytest.mark.parametrize("key", sorted(EXPECTED))
def test_example_runs_and_prints_what_it_promises(key):
    args, lines = EXPECTED[key]
    done = run_example(key.split()[0], *args)
    assert done.returncode == 0, f"stdout:\n{done.stdout}\nstderr:\n{done.stderr}"
    for line in lines:
        assert line in done.stdout, f"{line!r} missing from:\n{done.stdout}"
    assert "Traceback" not in done.stderr, done.stderr


@pytest.mark.vcan
def test_two_processes_on_vcan(vcan):
    done = run_example("two_processes.py", "--channel", vcan[0], "--seconds",
                       str(scaled(20)))
    assert done.returncode == 0, f"stdout:\n{done.stdout}\nstderr:\n{done.stderr}"
    out = done.stdout
    assert "master: node 5 is PRE-OPERATIONAL" in out, out
    assert "master: setpoint 42" in out and "master: node 5 started" in out, out
    pids = {line.rsplit("pid ", 1)[1] for line in out.splitlines() if "pid " in line}
    assert len(pids) == 2 and str(os.getpid()) not in pids, out
