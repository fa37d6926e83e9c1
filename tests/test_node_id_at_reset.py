"""A running local node given another node-id by the application
(`set_node_id_at_reset`): it keeps its node-id until the next reset, then
boots under the new one; checked on the wire (boot-up, heartbeat, SDO or
USDO server, EMCY COB-ID) on classic and fd lines, and wrong use refused."""

from __future__ import annotations

import pytest
from helpers import Recorder

from canopenfd import ConfigurationError
from canopenfd.od import demo_od


@pytest.mark.parametrize("mode", ["classic", "fd"])
@pytest.mark.parametrize("reset", ["RESET_NODE", "RESET_COMMUNICATION"])
def test_the_node_runs_under_the_new_node_id_after_the_reset(net, bus_name, mode, reset):
    device = net.open_line(bus_name, mode=mode).create_local_node(5, 50, od=demo_od(mode))
    line = net.open_line(bus_name, mode=mode)
    frames, resets = Recorder(), Recorder()
    net.open_line(bus_name, mode=mode, monitor=True).on_frame(frames)
    device.on_reset(resets)
    vendor = device[0x1018][1].raw
    read_vendor = lambda node_id: int.from_bytes(line.add_node(node_id).read((0x1018, 1)),
                                                 "little")
    device.set_node_id_at_reset(9)
    assert device.node_id == 5                        # until the reset
    assert read_vendor(5) == vendor
    frames.wait_for(lambda c: [f for f in c if f.id == 0x705], 2, "a heartbeat as node 5")
    start = len(frames)
    device.apply(reset)
    resets.wait_for(lambda c: len(c) == 1, 2, "the reset")
    boot = frames.wait_for(lambda c: [f for f in c[start:] if f.id == 0x709], 2, "boot-up")
    assert bytes(boot[0].data) == b"\x00"
    assert device.node_id == 9
    assert read_vendor(9) == vendor
    device.emcy.raise_error(0x5000)                   # EMCY on 0x80 + the new node-id
    frames.wait_for(lambda c: [f for f in c[start:] if f.id == 0x89], 2, "EMCY of node 9")
    after = frames.snapshot()[start:]
    assert [f for f in after if f.id in (0x85, 0x705, 0x585)] == []
    # the new node-id once: the next reset keeps it
    start = len(frames)
    device.apply("RESET_NODE")
    frames.wait_for(lambda c: [f for f in c[start:] if f.id == 0x709 and f.data == b"\x00"],
                    2, "the second boot-up")
    assert device.node_id == 9


def test_wrong_use_is_refused(net, bus_name):
    line = net.open_line(bus_name, mode="fd")
    line.add_node(7)
    device = line.create_local_node(5, od=demo_od("fd"), boot=False)
    with pytest.raises(ConfigurationError, match="not booted"):
        device.set_node_id_at_reset(9)
    device.boot()
    with pytest.raises(ConfigurationError, match="node-id 7 is a remote node this line"):
        device.set_node_id_at_reset(7)
    with pytest.raises(ConfigurationError, match="node-id 128 outside 1..127"):
        device.set_node_id_at_reset(128)
    device.apply("RESET_NODE")
    assert device.node_id == 5                        # nothing was set


def test_messages_name_the_node_by_its_new_node_id(net, bus_name):
    """After the reset every service of the node names it by the id it runs
    with (the messages were built from the id at creation before)."""
    device = net.open_line(bus_name, mode="classic").create_local_node(5, od=demo_od("classic"))
    resets = Recorder()
    device.on_reset(resets)
    device.set_node_id_at_reset(9)
    device.apply("RESET_NODE")
    resets.wait_for(lambda c: len(c) == 1, 2, "the reset")
    assert device.node_id == 9
    wrong_uses = [lambda: device.emcy.raise_error(0x10000),           # EMCY producer
                  lambda: device.errors.report(999),                  # error-report bits
                  lambda: device.srdo.set_data(1, b"\x01"),           # SRDO (not started)
                  lambda: device.lss.accept_bit_timings([99]),        # LSS slave
                  lambda: device.drive_simulation.start(tick_ms=0)]   # CiA 402 simulation
    for call in wrong_uses:
        with pytest.raises(ConfigurationError) as refused:
            call()
        assert "local node 9 on line" in str(refused.value), str(refused.value)
        assert "node 5" not in str(refused.value)
