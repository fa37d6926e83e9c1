"""Interop with python-canopen (PyPI `canopen`), an independent classic
CANopen peer, on a classic vcan (the third name in CANOPENFD_VCAN)."""

from __future__ import annotations

import threading
import time

import pytest
from helpers import Recorder, scaled

import canopenfd
from canopenfd import NmtState

pytestmark = pytest.mark.vcan
canopen = pytest.importorskip("canopen")


@pytest.fixture
def channel(vcan):
    return vcan[2]


@pytest.fixture
def peer(channel):
    """A python-canopen network on the classic vcan."""
    network = canopen.Network()
    network.connect(interface="socketcan", channel=channel)
    yield network
    network.disconnect()


@pytest.fixture
def line(channel):
    with canopenfd.Network() as net:
        yield net.open_line(channel, mode="classic")


def heartbeat_od(ms: int):
    """A python-canopen object dictionary with 0x1017 (its LocalNode needs it)."""
    from canopen.objectdictionary import UNSIGNED16, ODVariable

    od = canopen.ObjectDictionary()
    var = ODVariable("Producer heartbeat time", 0x1017, 0)
    var.data_type = UNSIGNED16
    var.access_type = "rw"
    var.default = ms
    od.add_object(var)
    return od


def wait_canopen_state(node, state: str, timeout: float = 10.0) -> None:
    """python-canopen's heartbeat view reaches `state` (its own wait API)."""
    deadline = time.monotonic() + scaled(timeout)
    while node.nmt.state != state:
        remaining = deadline - time.monotonic()
        assert remaining > 0, f"python-canopen still sees {node.nmt.state}, not {state}"
        node.nmt.wait_for_heartbeat(timeout=remaining)


def test_python_canopen_sees_our_bootup_and_heartbeats(peer, line):
    remote = peer.add_node(5)
    ours = line.create_local_node(5, heartbeat_ms=50, boot=False)
    result = {}

    def wait_bootup():
        try:
            remote.nmt.wait_for_bootup(timeout=scaled(20))
            result["ok"] = True
        except Exception as exc:  # noqa: BLE001
            result["error"] = exc

    waiter = threading.Thread(target=wait_bootup)
    waiter.start()
    time.sleep(scaled(0.3))           # python-canopen has no hook to know it is waiting
    ours.boot()
    waiter.join(scaled(30))
    assert result == {"ok": True}
    assert remote.nmt.wait_for_heartbeat(timeout=scaled(10)) == "PRE-OPERATIONAL"

    line.nmt.start(5)                 # our own node: applied locally, heartbeat tells
    wait_canopen_state(remote, "OPERATIONAL")
    line.nmt.stop(5)
    wait_canopen_state(remote, "STOPPED")


def test_our_nmt_drives_python_canopen_local_node(peer, line):
    theirs = canopen.LocalNode(20, heartbeat_od(50))
    peer.add_node(theirs)
    remote = line.add_node(20, heartbeat_timeout_ms=400)
    bootups, started, lost = Recorder(), Recorder(), Recorder()
    remote.on_bootup(bootups)
    remote.on_heartbeat_started(started)
    remote.on_heartbeat_lost(lost)

    theirs.nmt.send_command(0x81)                  # python-canopen: sends its boot-up
    bootups.wait_count(1, timeout=10)
    theirs.nmt.state = "PRE-OPERATIONAL"           # starts its heartbeat (0x1017 = 50 ms)
    started.wait_count(1, timeout=10)
    remote.wait_for_state(NmtState.PRE_OPERATIONAL, timeout=scaled(10))

    line.nmt.start(20)
    remote.wait_for_state(NmtState.OPERATIONAL, timeout=scaled(10))
    assert theirs.nmt.state == "OPERATIONAL"
    line.nmt.stop("all")
    remote.wait_for_state(NmtState.STOPPED, timeout=scaled(10))
    assert theirs.nmt.state == "STOPPED"
    remote.nmt.state = "PRE-OPERATIONAL"            # python-canopen style, through our API
    remote.wait_for_state(NmtState.PRE_OPERATIONAL, timeout=scaled(10))
    assert theirs.nmt.state == "PRE-OPERATIONAL"

    theirs.nmt.stop_heartbeat()
    lost.wait_count(1, timeout=10)
    assert remote.heartbeat_alive is False
    theirs.nmt.start_heartbeat(50)
    started.wait_count(2, timeout=10)


def test_python_canopen_master_drives_our_node(peer, line):
    ours = line.create_local_node(7, heartbeat_ms=50)
    ours.wait_for_state(NmtState.PRE_OPERATIONAL, timeout=scaled(10))
    remote = peer.add_node(7)

    peer.nmt.send_command(0x01)                     # start all
    ours.wait_for_state(NmtState.OPERATIONAL, timeout=scaled(10))
    wait_canopen_state(remote, "OPERATIONAL")
    remote.nmt.state = "STOPPED"
    ours.wait_for_state(NmtState.STOPPED, timeout=scaled(10))
    remote.nmt.state = "PRE-OPERATIONAL"
    ours.wait_for_state(NmtState.PRE_OPERATIONAL, timeout=scaled(10))

    resets = Recorder()
    ours.on_reset(resets)
    result = {}

    def wait_bootup():
        try:
            remote.nmt.wait_for_bootup(timeout=scaled(20))
            result["ok"] = True
        except Exception as exc:  # noqa: BLE001
            result["error"] = exc

    waiter = threading.Thread(target=wait_bootup)
    waiter.start()
    time.sleep(scaled(0.3))
    remote.nmt.state = "RESET COMMUNICATION"
    waiter.join(scaled(30))
    assert result == {"ok": True}
    assert resets.wait_count(1) == [canopenfd.NmtCommand.RESET_COMMUNICATION]
    assert remote.nmt.wait_for_heartbeat(timeout=scaled(10)) == "PRE-OPERATIONAL"
    assert ours.state == NmtState.PRE_OPERATIONAL


def test_python_canopen_heartbeat_loss_is_detected(peer, line):
    theirs = canopen.LocalNode(30, heartbeat_od(40))
    peer.add_node(theirs)
    remote = line.add_node(30, heartbeat_timeout_ms=250)
    started, lost = Recorder(), Recorder()
    remote.on_heartbeat_started(started)
    remote.on_heartbeat_lost(lost)
    theirs.nmt.state = "PRE-OPERATIONAL"           # from INITIALISING: heartbeat starts
    started.wait_count(1, timeout=10)
    stopped_at = time.monotonic()
    theirs.nmt.stop_heartbeat()
    lost.wait_count(1, timeout=10)
    assert lost.times[0] - stopped_at >= 0.15


# ------------------------------------------------------------------ SDO
def test_python_canopen_sdo_client_against_our_server(line, peer):
    """python-canopen's SDO client (expedited, segmented, block with CRC) reads
    and writes our node's OD over a real classic SocketCAN line."""
    import os

    from canopenfd.od import demo_od
    node = line.create_local_node(5, od=demo_od("classic"), boot=False)
    node.serve_domain(0x2100, 1 << 20)
    node.boot()
    remote = peer.add_node(5, canopen.ObjectDictionary())
    remote.sdo.RESPONSE_TIMEOUT = scaled(1.0)
    node[0x1017].raw = 0x1234
    assert remote.sdo.upload(0x1017, 0) == b"\x34\x12"
    remote.sdo.download(0x1017, 0, (250).to_bytes(2, "little"))
    assert node[0x1017].raw == 250
    data = os.urandom(3000)
    remote.sdo.download(0x2100, 0, data, force_segment=True)
    assert node[0x2100].data == data and remote.sdo.upload(0x2100, 0) == data
    data = os.urandom(20000)
    with remote.sdo.open(0x2100, 0, "wb", size=len(data), block_transfer=True) as f:
        f.write(data)
    assert node[0x2100].data == data
    with remote.sdo.open(0x2100, 0, "rb", block_transfer=True) as f:
        assert f.read() == data


def test_python_canopen_sees_parameter_groups(line, peer, tmp_path):
    """A classic peer (python-canopen's SDO client and NMT master) reads the
    CiA 301 capability bits of declared groups, saves one with "save", and
    gets the saved values back after its reset communication; the
    autonomous group is saved without any command."""
    from canopenfd.od import demo_od
    from canopenfd.services.store_groups import StoreGroup

    groups = [StoreGroup("comm", [(0x1000, 0x1FFF)], reset="communication"),
              StoreGroup("tuning", [(0x2005, 0x2007)], mode="autonomous"),
              StoreGroup("limits", [(0x2001, 0x2004)], mode="both")]
    node = line.create_local_node(5, od=demo_od("classic"), store=str(tmp_path / "p.bin"),
                                  store_groups=groups, store_interval_ms=50)
    remote = peer.add_node(5, canopen.ObjectDictionary())
    remote.sdo.RESPONSE_TIMEOUT = scaled(1.0)
    bits = [int.from_bytes(remote.sdo.upload(0x1010, sub), "little") for sub in (1, 2, 3, 4)]
    assert bits == [3, 1, 2, 3]
    with pytest.raises(canopen.SdoAbortedError) as info:
        remote.sdo.download(0x1010, 3, b"save")       # autonomous only: not on command
    assert info.value.code == 0x08000020
    remote.sdo.download(0x1017, 0, (300).to_bytes(2, "little"))
    remote.sdo.download(0x1010, 2, b"save")
    remote.sdo.download(0x2006, 0, (777).to_bytes(2, "little"))   # saved autonomously
    remote.sdo.download(0x1017, 0, (40).to_bytes(2, "little"))
    resets = Recorder()
    node.on_reset(resets)
    remote.nmt.state = "RESET COMMUNICATION"
    resets.wait_count(1)
    node.wait_for_state(NmtState.PRE_OPERATIONAL, timeout=scaled(10))
    assert remote.sdo.upload(0x1017, 0) == (300).to_bytes(2, "little")
    remote.nmt.state = "RESET"                        # reset node: defaults, then saved
    resets.wait_count(2)
    node.wait_for_state(NmtState.PRE_OPERATIONAL, timeout=scaled(10))
    # 0x2006 (default 1000) was saved by the stack 50 ms after the write at
    # the latest, long before this reset
    assert remote.sdo.upload(0x2006, 0) == (777).to_bytes(2, "little")


def test_our_sdo_client_against_python_canopen_server(line, peer):
    """Our SDO client reads and writes python-canopen's LocalNode (its own SDO
    server) over a real classic SocketCAN line: expedited and segmented."""
    import os

    from canopen.objectdictionary import DOMAIN, UNSIGNED32, ODVariable
    od = canopen.ObjectDictionary()
    for index, dtype in ((0x2000, UNSIGNED32), (0x2001, DOMAIN)):
        var = ODVariable(f"v{index:X}", index, 0)
        var.data_type = dtype
        var.access_type = "rw"
        od.add_object(var)
    local = peer.create_node(7, od)
    store = {}
    local.add_write_callback(lambda index, subindex, od, data: store.__setitem__(index, data))
    local.add_read_callback(lambda index, subindex, od: store.get(index))
    line.sdo.download(7, 0x2000, 0, (0x12345678).to_bytes(4, "little"), timeout=scaled(1))
    assert bytes(store[0x2000]) == (0x12345678).to_bytes(4, "little")
    assert line.sdo.upload(7, 0x2000, timeout=scaled(1)) == (0x12345678).to_bytes(4, "little")
    data = os.urandom(2000)
    line.sdo.download(7, 0x2001, 0, data, mode="segmented", timeout=scaled(1))
    assert bytes(store[0x2001]) == data
    assert line.sdo.upload(7, 0x2001, timeout=scaled(1)) == data
