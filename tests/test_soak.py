"""bench/soak.py (every service at once, nothing lost or leaked) as a test:
a short in-process run in every lane, two minutes on vcan in the vcan lane."""

import os
import subprocess
import sys

import pytest

from helpers import scaled

SOAK = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "bench",
                    "soak.py")


def run_soak(*args, limit):
    done = subprocess.run([sys.executable, SOAK, "--check", *args], capture_output=True,
                          text=True, timeout=limit)
    print(done.stdout, done.stderr)
    return done


def test_soak_in_process_loses_nothing():
    done = run_soak("--minutes", "0.15", "--interval", "3", "--fd", "mem:soak-fd",
                    "--classic", "mem:soak-classic", limit=120)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert "soak: nothing lost, nothing failed" in done.stdout
    # the figures are there, per interval and at the end
    assert done.stdout.count("t=") >= 2 and "end fd: PDOs sent" in done.stdout


@pytest.mark.vcan
def test_soak_two_minutes_on_vcan(vcan):
    fd, classic = vcan[0], vcan[2]
    done = run_soak("--minutes", "2", "--interval", "30", "--fd", fd, "--classic", classic,
                    "--pdo-ms", "5", "--hb-timeout-ms", str(int(scaled(500))),
                    "--transfer-timeout", str(scaled(2)), limit=int(120 + scaled(60)))
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert "soak: nothing lost, nothing failed" in done.stdout
