"""`canopenfd lss ...` against our own nodes' LSS slaves on an in-process bus
(the CLI runs on the test's Network): fast scan of an unconfigured node,
scan, inquire, set-id with store, and usage errors."""

from __future__ import annotations

import time

import pytest

from canopenfd.cli import main
from canopenfd.od import demo_od
from helpers import scaled

VENDOR, PRODUCT, REVISION = 0x000001A2, 0x00BEEF01, 0x00020003


def identity_od(serial: int):
    od = demo_od("classic")
    for sub, value in enumerate((VENDOR, PRODUCT, REVISION, serial), start=1):
        od[0x1018][sub].default = value
    return od


def run(net, bus_name, capsys, *argv: str):
    status = main(["lss", *argv, "--channel", bus_name, "--classic"], network=net)
    out = capsys.readouterr()
    return status, out.out, out.err


def test_fastscan_gives_an_unconfigured_node_its_id(net, bus_name, capsys):
    node = net.open_line(bus_name, mode="classic").create_local_node(
        255, od=identity_od(0x77))
    status, out, _ = run(net, bus_name, capsys, "fastscan", "--node-ids", "20-21")
    assert status == 0
    assert out.splitlines() == [
        f"vendor 0x{VENDOR:08X} product 0x{PRODUCT:08X} revision 0x{REVISION:08X} "
        "serial 0x00000077 -> node 20",
        "1 device(s) without a node-id found"]
    deadline = time.monotonic() + scaled(3)
    while node.node_id != 20 and time.monotonic() < deadline:   # told by the runtime
        time.sleep(0.01)
    assert node.node_id == 20
    status, out, _ = run(net, bus_name, capsys, "fastscan", "--node-ids", "22")
    assert status == 0 and out.strip() == "no device without a node-id answered"


def test_scan_inquire_set_id(net, bus_name, capsys):
    stored = []
    for node_id, serial in ((5, 1), (6, 2)):
        node = net.open_line(bus_name, mode="classic").create_local_node(
            node_id, od=identity_od(serial))
        node.lss.on_store(stored.append)
    status, out, _ = run(net, bus_name, capsys, "scan", hex(VENDOR), hex(PRODUCT))
    assert status == 0
    assert [line.split()[-1] for line in out.splitlines()[:2]] == ["0x00000001", "0x00000002"]
    address = f"{VENDOR:#x}:{PRODUCT:#x}:{REVISION:#x}:2"
    status, out, _ = run(net, bus_name, capsys, "inquire", "--address", address)
    assert status == 0 and out.strip().endswith("serial 0x00000002 node-id 6")
    status, out, _ = run(net, bus_name, capsys, "set-id", "9", "--address", address, "--store")
    assert status == 0 and "node-id 9 configured and stored" in out
    assert stored == [9]


@pytest.mark.parametrize("argv, message", [
    (("fastscan", "--node-ids", "0-3"), "node-ids must be 1..127"),
    (("fastscan", "--node-ids", "5,5"), "names a node-id twice"),
    (("inquire", "--address", "1:2:3"), "expected VENDOR:PRODUCT:REVISION:SERIAL"),
    (("scan", "0x1", "zz"), "product 'zz' is not a number"),
    (("scan", "1", "2", "--serials", "9-1"), "LOW above HIGH"),
    (("set-id", "200"), "node-id 200 outside 1..127"),
    (("inquire", "--address", "1:2:3:4"), "no device answered LSS address 1:2:3:4"),
])
def test_usage_errors_name_the_problem(net, bus_name, capsys, argv, message):
    status, _, err = run(net, bus_name, capsys, *argv)
    assert status == 2 and message in err


def test_device_command_runs_a_factory_fresh_node(net, bus_name, capsys):
    """`canopenfd device --node-id 255 --serial N`: silent until a fast scan
    gives it a node-id, then it says so and runs with it."""
    import threading
    runner = threading.Thread(target=main, args=(
        ["device", "--channel", bus_name, "--classic", "--node-id", "255", "--serial", "0x55",
         "--duration", str(scaled(3))],), kwargs={"network": net})
    runner.start()
    line = net.open_line(bus_name, mode="classic")
    line.lss.timeout_ms = 50
    deadline = time.monotonic() + scaled(2)
    found = []
    while not found and time.monotonic() < deadline:   # until the device runs
        found = line.lss.fast_scan([30])
    runner.join(scaled(10))
    assert [d.serial for d in found] == [0x55] and found[0].node_id == 30
    captured = capsys.readouterr()
    assert "node 255 (factory-fresh)" in captured.err and "error" not in captured.err
    assert "node 30: node-id given by LSS (was 255)" in captured.out
    assert "node 30: INITIALISING -> PRE-OPERATIONAL" in captured.out


@pytest.mark.parametrize("argv, message", [
    (("--node-id", "255", "--od", "builtin:classic", "--serial", "x"), "is not a number"),
    (("--node-id", "300",), "node-id 300 outside 1..127"),
])
def test_device_lss_usage_errors(net, bus_name, capsys, argv, message):
    status = main(["device", "--channel", bus_name, "--classic", *argv], network=net)
    assert status == 2 and message in capsys.readouterr().err
