"""Objects added to (or removed from) a running local node's dictionary.

The C dictionary of a local node is built from the Python model when the node
boots. A change to the model after that would not reach the running node (a
read of the new object would answer 0x06020000 while the model has it), so
the change raises instead, naming the node, the index and the reason, and
leaves the model as it was.
"""

from __future__ import annotations

import pytest

from canopenfd.od import DataType, ODRecord, ODVariable, OdStateError, demo_od

NODE = 3
MODES = pytest.mark.parametrize("mode", ["fd", "classic"])


def serve(net, bus, mode, boot=True):
    od = demo_od(mode)
    node = net.open_line(bus, mode=mode).create_local_node(NODE, od=od, boot=boot)
    return node, od


@MODES
def test_an_object_added_after_boot_raises_and_changes_nothing(net, bus_name, mode):
    node, od = serve(net, bus_name, mode)
    before = sorted(od)
    new = ODVariable("Added late", 0x2F01, 0, DataType.UNSIGNED16, "rw", 7)
    with pytest.raises(OdStateError) as caught:
        od.add_object(new)
    text = str(caught.value)
    assert "0x2F01" in text and f"local node {NODE}" in text and "running" in text
    assert "before the node boots" in text            # what to do instead
    assert sorted(od) == before and 0x2F01 not in od and new.parent is None
    with pytest.raises(KeyError):                      # model and C agree: no such object
        node[0x2F01]


@MODES
def test_replacing_deleting_or_growing_objects_after_boot_raises(net, bus_name, mode):
    node, od = serve(net, bus_name, mode)
    heartbeat = od[0x1017]
    with pytest.raises(OdStateError, match="0x1017"):
        od[0x1017] = ODVariable("Producer heartbeat time", 0x1017, 0, DataType.UNSIGNED16)
    with pytest.raises(OdStateError, match="0x1018"):
        del od[0x1018]
    identity = od[0x1018]
    assert isinstance(identity, ODRecord)
    with pytest.raises(OdStateError, match="0x1018:09"):
        identity.add_member(ODVariable("Extra", 0x1018, 9, DataType.UNSIGNED32, "ro"))
    assert od[0x1017] is heartbeat and 9 not in identity and 0x1018 in od
    node[0x1017].raw = 250                             # the node still serves what it had
    assert node[0x1017].raw == 250


@MODES
def test_objects_added_before_boot_are_served(net, bus_name, mode):
    node, od = serve(net, bus_name, mode, boot=False)
    od.add_object(ODVariable("Added early", 0x2F01, 0, DataType.UNSIGNED16, "rw", 7))
    node.boot()
    assert node[0x2F01].raw == 7
    node[0x2F01].raw = 0x1234
    assert node[0x2F01].data == b"\x34\x12"


def test_a_dictionary_used_by_no_node_stays_editable():
    od = demo_od("fd")
    od.add_object(ODVariable("Free", 0x2F01, 0, DataType.UNSIGNED8))
    del od[0x2F01]
    assert 0x2F01 not in od



def test_the_dictionary_is_free_again_once_the_network_closed(bus_name):
    import canopenfd

    network = canopenfd.Network()
    try:
        node, od = serve(network, bus_name, "fd")
        with pytest.raises(OdStateError):
            od.add_object(ODVariable("Late", 0x2F01, 0, DataType.UNSIGNED8))
    finally:
        network.close()
    assert od.frozen_by is None
    od.add_object(ODVariable("Late", 0x2F01, 0, DataType.UNSIGNED8))
    assert 0x2F01 in od
