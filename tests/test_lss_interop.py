"""LSS (CiA 305) interop: python-canopen's LssMaster (`network.lss`), an
independent implementation, drives our local node's LSS slave over
python-can's virtual bus. Our node runs the slave because its OD has the
serial number 0x1018:04 (co_stack sets it up)."""

from __future__ import annotations

import itertools
import os

import pytest

import canopenfd
from canopenfd.od import demo_od
from helpers import virtual_bus

can = pytest.importorskip("can")
canopen = pytest.importorskip("canopen")
lss_module = pytest.importorskip("canopen.lss")

NODE = 5
IDENTITY = {1: 0x000001A2, 2: 0x00BEEF01, 3: 0x00020003, 4: 0x80000001}
_channels = itertools.count(1)


@pytest.fixture
def rig():
    """python-canopen on a virtual bus, our node 5 with an identity on it."""
    channel = f"lss-{os.getpid()}-{next(_channels)}"
    peer = canopen.Network()
    peer.connect(interface="virtual", channel=channel)
    od = demo_od("classic")
    for sub, value in IDENTITY.items():
        od[0x1018][sub].default = value
    with canopenfd.Network() as net:
        line = net.open_line(bus=virtual_bus(channel), mode="classic")
        node = line.create_local_node(NODE, od=od)
        try:
            yield peer.lss, node
        finally:
            peer.disconnect()


def test_python_canopen_configures_our_slave(rig):
    lss, node = rig
    LssError = lss_module.LssError
    # Nothing answers in the waiting state ...
    with pytest.raises(LssError):
        lss.inquire_node_id()
    # ... switch state global, then every inquiry.
    lss.send_switch_state_global(lss.CONFIGURATION_STATE)
    assert lss.inquire_node_id() == NODE
    for cs, sub in ((lss_module.CS_INQUIRE_VENDOR_ID, 1), (lss_module.CS_INQUIRE_PRODUCT_CODE, 2),
                    (lss_module.CS_INQUIRE_REVISION_NUMBER, 3),
                    (lss_module.CS_INQUIRE_SERIAL_NUMBER, 4)):
        assert lss.inquire_lss_address(cs) == IDENTITY[sub]
    # Configure node-id: accepted (pending until reset communication) ...
    lss.configure_node_id(9)
    assert lss.inquire_node_id() == NODE
    # ... or refused with error 1 (out of range).
    with pytest.raises(LssError, match="LSS Error: 1"):
        lss.configure_node_id(0)
    # No bit timing or store support in this node: error 1 (not supported).
    with pytest.raises(LssError, match="LSS Error: 1"):
        lss.configure_bit_timing(2)
    with pytest.raises(LssError, match="LSS Error: 1"):
        lss.store_configuration()
    # Once the application persists node-ids, store succeeds.
    stored = []
    node.lss.on_store(stored.append)
    lss.store_configuration()
    assert stored == [9]
    assert node.lss.info["persistent"] == 9
    lss.send_switch_state_global(lss.WAITING_STATE)
    with pytest.raises(LssError):
        lss.inquire_node_id()


def test_python_canopen_selects_our_slave(rig):
    lss, _ = rig
    # A wrong serial number: nobody answers (python-canopen raises).
    with pytest.raises(lss_module.LssError, match="No LSS response"):
        lss.send_switch_state_selective(IDENTITY[1], IDENTITY[2], IDENTITY[3], IDENTITY[4] ^ 1)
    assert lss.send_switch_state_selective(IDENTITY[1], IDENTITY[2], IDENTITY[3],
                                           IDENTITY[4]) is True
    assert lss.inquire_lss_address(lss_module.CS_INQUIRE_SERIAL_NUMBER) == IDENTITY[4]
    lss.send_switch_state_global(lss.WAITING_STATE)


def test_python_canopen_fast_scan_skips_a_configured_node(rig):
    lss, _ = rig
    # Our node has a node-id: it takes no part in fast scan (CiA 305).
    assert lss.fast_scan() == (False, None)


def test_python_canopen_fast_scans_our_unconfigured_node():
    """Our node starts with node-id 255 (only LSS runs); python-canopen's fast
    scan finds its address, configures node-id 12 and switches it back to
    waiting: our node boots with 12, which python-canopen sees."""
    channel = f"lss-{os.getpid()}-{next(_channels)}"
    peer = canopen.Network()
    peer.connect(interface="virtual", channel=channel)
    # few 1-bits: python-canopen waits its full response timeout for each
    identity = {1: 0x00000001, 2: 0x00000002, 3: 0x00000001, 4: 0x80000000}
    od = demo_od("classic")
    for sub, value in identity.items():
        od[0x1018][sub].default = value
    try:
        with canopenfd.Network() as net:
            line = net.open_line(bus=virtual_bus(channel), mode="classic")
            node = line.create_local_node(255, od=od)
            assert node.state.label == "INITIALISING"      # no boot-up without a node-id
            remote = peer.add_node(12)
            found, address = peer.lss.fast_scan()
            assert found is True
            assert address == [identity[1], identity[2], identity[3], identity[4]]
            peer.lss.configure_node_id(12)
            assert node.node_id == 255                     # pending until back to waiting
            peer.lss.send_switch_state_global(peer.lss.WAITING_STATE)
            remote.nmt.wait_for_bootup(timeout=5)
            assert node.node_id == 12
            node.nmt.wait_for_state("PRE-OPERATIONAL", timeout=5)
            assert node.lss.info["active"] == 12
            # Configured now: a second fast scan finds nobody.
            assert peer.lss.fast_scan() == (False, None)
    finally:
        peer.disconnect()
