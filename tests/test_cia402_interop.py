"""Interop: python-canopen's BaseNode402 (PyPI `canopen`, an independent
CiA 402 master) drives our simulated drive on a python-can virtual bus: it
reads the drive's PDO configuration, finds the statusword in TPDO1 and the
controlword in RPDO1 (the drive's defaults), walks the power state machine
through its own transition table and switches modes of operation."""

from __future__ import annotations

import itertools
import os
import time

import pytest
from helpers import scaled, virtual_bus

import canopenfd
from canopenfd.od import export_eds
from canopenfd.profiles.cia402 import create_simulated_drive, drive_od

canopen = pytest.importorskip("canopen")
_channels = itertools.count(1)


@pytest.fixture
def their_drive(tmp_path):
    """python-canopen's BaseNode402 for our simulated drive 5 (OD from our EDS)."""
    channel = f"cia402-{os.getpid()}-{next(_channels)}"
    peer = canopen.Network()
    peer.connect(interface="virtual", channel=channel)
    try:
        with canopenfd.Network() as net:
            line = net.open_line(bus=virtual_bus(channel), mode="classic")
            sim = create_simulated_drive(line, 5)
            eds = tmp_path / "drive.eds"
            export_eds(drive_od("classic", 5), str(eds))
            od = canopen.import_od(str(eds), 5)
            node = canopen.BaseNode402(5, od)
            peer.add_node(node)
            yield node, sim
    finally:
        peer.disconnect()


def test_base_node_402_walks_the_state_machine(their_drive):
    node, sim = their_drive
    node.TIMEOUT_SWITCH_STATE_FINAL = scaled(2)
    node.nmt.state = "PRE-OPERATIONAL"
    node.setup_402_state_machine()
    assert 0x6041 in node.tpdo_values and 0x6040 in node.rpdo_pointers
    node.nmt.state = "OPERATIONAL"
    # TPDO1 (statusword) comes on change and every 100 ms: python-canopen's cache
    node.tpdo[1].wait_for_reception(scaled(1))
    assert node.state == "SWITCH ON DISABLED"
    node.state = "READY TO SWITCH ON"
    node.state = "SWITCHED ON"
    node.state = "OPERATION ENABLED"
    assert node.sdo[0x6041].raw & 0x6F == 0x27
    # the event TPDO1 brought every statusword change to python-canopen's cache
    assert node.tpdo_values[0x6041] & 0x6F == 0x27
    node.state = "QUICK STOP ACTIVE"
    assert node.sdo[0x6041].raw & 0x6F == 0x07
    node.state = "SWITCH ON DISABLED"
    assert node.state == "SWITCH ON DISABLED"


def test_base_node_402_op_mode_and_fault_reset(their_drive):
    node, sim = their_drive
    node.TIMEOUT_SWITCH_STATE_FINAL = scaled(2)
    node.nmt.state = "PRE-OPERATIONAL"
    node.setup_402_state_machine()
    assert node.is_op_mode_supported("CYCLIC SYNCHRONOUS POSITION")
    node.op_mode = "PROFILED VELOCITY"
    assert node.op_mode == "PROFILED VELOCITY"
    assert node.sdo[0x6061].raw == 3
    node.nmt.state = "OPERATIONAL"
    node.tpdo[1].wait_for_reception(scaled(1))
    node.state = "OPERATION ENABLED"
    sim.drive_simulation.fault(0x5530)
    deadline = time.monotonic() + scaled(2)
    while not node.is_faulted():
        assert time.monotonic() < deadline, "python-canopen never saw the fault"
        time.sleep(0.01)
    assert node.sdo[0x603F].raw == 0x5530
    node.reset_from_fault()
    assert node.state == "OPERATION ENABLED"
    assert node.sdo[0x603F].raw == 0
