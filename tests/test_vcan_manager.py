"""The network manager on real SocketCAN (vcan, CAN FD): three `canopenfd
device` processes — node 2 up to date, node 3 with an outdated configuration
(its 0x1020), and a factory-fresh one (node-id 255, serial 0x1004) — brought
up by our manager in this process: LSS fast scan gives the fresh one node 4,
the CiA 302-2 start-up checks each, re-configures node 3 from a concise DCF
in the configuration hook and starts all three."""

from __future__ import annotations

import queue
import subprocess
import time

import pytest
from helpers import NEUTRAL_CWD, cli_command, package_env, scaled

import canopenfd
from canopenfd.cli.demo_manager import (DATE, DEVICES, FRESH_ID, NEW_CONFIG, TIME, device_od,
                                        manager_od)
from canopenfd.od import export_eds
from canopenfd.od.concise import build_concise

pytestmark = pytest.mark.vcan


@pytest.fixture
def devices(vcan, tmp_path):
    """The three device processes on vcan0, each with its EDS (0x1018 identity,
    0x1020 stamp), started; killed at the end."""
    procs = []
    for node_id, (_, serial, stamp) in DEVICES.items():
        eds = tmp_path / f"device-{serial:x}.eds"
        export_eds(device_od("fd", serial, stamp), str(eds))
        procs.append(subprocess.Popen(
            cli_command("device", "--channel", vcan[0], "--node-id", str(node_id or 255),
                        "--od", str(eds), "--heartbeat", "100", "--duration", str(scaled(60))),
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=NEUTRAL_CWD,
            env=package_env()))
    for proc in procs:                       # each says so once its line is open
        seen = []
        while not seen or "Ctrl-C" not in seen[-1]:
            seen.append(proc.stderr.readline())
            if not seen[-1]:
                pytest.fail(f"a device ended before running: {seen}")
        assert "running on" in seen[-1] or "waits for an LSS master" in seen[-1], seen
    yield vcan[0], procs
    for proc in procs:
        if proc.poll() is None:
            proc.kill()
        proc.wait()


def test_manager_brings_up_three_device_processes(devices):
    channel, procs = devices
    with canopenfd.Network() as net:
        line = net.open_line(channel, mode="fd")
        line.create_local_node(1, od=manager_od("fd"))
        line.lss.timeout_ms = round(scaled(0.05) * 1000)
        found = line.lss.fast_scan([FRESH_ID])
        assert [(d.serial, d.node_id) for d in found] == [(0x1004, FRESH_ID)]
        events: "queue.Queue" = queue.Queue()
        line.manager.add_callback(events.put)
        time.sleep(scaled(0.3))              # the fresh device boots with node 4
        line.manager.start(config_hook=True)
        configured = []
        deadline = time.monotonic() + scaled(20)
        while time.monotonic() < deadline:
            event = events.get(timeout=scaled(20))
            if event.kind == "update-config":
                result = None
                if event.node_id == 3:
                    result = line.manager.configure(3, build_concise(NEW_CONFIG),
                                                    expected=(DATE, TIME)).result()
                    configured.append(result)
                line.manager.continue_config(event.node_id, result is None or result.ok)
            if event.kind in ("network-started", "halted"):
                break
        assert event.kind == "network-started", event
        assert [r.ok for r in configured] == [True]
        for node_id in (2, 3, FRESH_ID):
            remote = line.add_node(node_id)
            remote.nmt.wait_for_state("OPERATIONAL", timeout=scaled(5))
        assert line.add_node(3).usdo.upload(0x1017) == (200).to_bytes(2, "little")
    outputs = []
    for proc in procs:
        proc.kill()
        out, err = proc.communicate(timeout=scaled(10))
        outputs.append(out)
    assert "node 4: node-id given by LSS (was 255)" in outputs[2], outputs[2]
    for node_id, out in zip((2, 3, FRESH_ID), outputs):
        assert f"node {node_id}: PRE-OPERATIONAL -> OPERATIONAL" in out, out
