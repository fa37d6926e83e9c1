"""The C-only example device (examples/c): built with the project's core, it
boots and serves its object dictionary to a client (fd: USDO, classic: SDO)
in the in-process self-test; its firmware cross-builds for Cortex-M4 and
Cortex-M0+ (-Werror) when arm-none-eabi-gcc is installed (tests/run_all.sh
installs it). On vcan it is read by our Python client (test_vcan_c_example)."""

from __future__ import annotations

import os
import shutil
import subprocess

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
EXAMPLE = os.path.join(ROOT, "examples", "c")
BINARY = os.path.join(ROOT, "build", "examples", "fd_device")


def make(*targets: str) -> subprocess.CompletedProcess:
    return subprocess.run(["make", "-s", "-C", EXAMPLE, *targets], capture_output=True,
                          text=True, timeout=600)


@pytest.fixture(scope="module")
def fd_device() -> str:
    built = make("linux")
    assert built.returncode == 0, built.stdout + built.stderr
    return BINARY


@pytest.mark.parametrize("mode", ["fd", "classic"])
def test_example_device_serves_its_od_to_a_client(fd_device, mode):
    args = [fd_device, "--selftest"] + (["--classic"] if mode == "classic" else [])
    run = subprocess.run(args, capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    lines = run.stdout.splitlines()
    assert lines == [
        "device type 0x1000:00 = 0x00000191",
        "vendor-id 0x1018:01 = 0x12345678",
        "product code 0x1018:02 = 0x00000001",
        "serial number 0x1018:04 = 0x0000002A",
        'device name 0x1008:00 = "canopenfd C example"',
        f"self-test passed ({mode}, node 5, client {'USDO' if mode == 'fd' else 'SDO'})",
    ]


def test_example_device_refuses_bad_arguments(fd_device):
    run = subprocess.run([fd_device, "vcan0", "200"], capture_output=True, text=True, timeout=10)
    assert run.returncode == 2 and "usage: fd_device" in run.stderr


@pytest.mark.skipif(shutil.which("arm-none-eabi-gcc") is None,
                    reason="arm-none-eabi-gcc not installed (tests/run_all.sh installs it)")
def test_example_firmware_cross_builds_for_cortex_m():
    # Build first: a build prints its own lines, which the size table must not get.
    built = make("cross")
    assert built.returncode == 0, built.stdout + built.stderr
    built = make("footprint")
    assert built.returncode == 0, built.stdout + built.stderr
    sizes = {}
    for line in built.stdout.splitlines()[1:]:
        text, data, bss, _dec, _hex, name = line.split()
        sizes[os.path.basename(name)] = (int(text), int(data), int(bss))
    assert set(sizes) == {f"{cpu}_{kind}.elf" for cpu in ("cortex-m4", "cortex-m0plus")
                          for kind in ("fd", "classic")}
    # a one-kind build links none of the other kind's services
    for cpu in ("cortex-m4", "cortex-m0plus"):
        fd_text, classic_text = sizes[f"{cpu}_fd.elf"][0], sizes[f"{cpu}_classic.elf"][0]
        assert 0 < fd_text < classic_text
    nm = subprocess.run(["arm-none-eabi-nm", os.path.join(ROOT, "build", "examples",
                                                          "cortex-m4_fd.elf")],
                        capture_output=True, text=True, check=True).stdout
    assert "co_usdo_server_init" in nm and "co_sdo_server_init" not in nm
