"""`canopenfd demo --manager`: LSS fast scan of a factory-fresh device, the
CiA 302-2 start-up with the configuration hook re-configuring an outdated
device from a concise DCF, every device started (fd and classic)."""

from __future__ import annotations

import pytest

from canopenfd.cli import main


@pytest.mark.parametrize("argv", [["demo", "--manager"], ["demo", "--manager", "--classic"]])
def test_manager_demo_brings_up_three_devices(argv, capsys):
    assert main(argv) == 0
    out = [line.split(None, 1)[1] for line in capsys.readouterr().out.splitlines()]
    assert "sensor    serial 0x1004: factory-fresh, no node-id (255): only LSS answers" in out
    assert "manager  LSS fast scan: serial 0x1004 -> node 4" in out
    assert "manager  node 3: 0x1020:01 outdated" in out
    assert "manager  node 3: configured, 1 entries written" in out
    assert "manager  node 2: 0x1020:02 current" in out
    assert out[-2] == ("manager  network started: node 2 OPERATIONAL, node 3 OPERATIONAL, "
                       "node 4 OPERATIONAL")
    assert out[-1] == "io module heartbeat now 200 ms, 0x1020 = (15000, 43200000)"
