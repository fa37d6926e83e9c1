"""A commissioned device for the concise DCF and configuration manager tests:
its dictionary (EDS side) and a DCF of it with configured values."""

from __future__ import annotations

from canopenfd.od import DataType, ODArray, ODVariable, demo_od, export_dcf

NODE = 5


def stamp_object():
    stamp = ODArray("Verify configuration", 0x1020)
    stamp.add_member(ODVariable("Highest sub-index supported", 0x1020, 0, DataType.UNSIGNED8,
                                "ro", 2))
    stamp.add_member(ODVariable("Configuration date", 0x1020, 1, DataType.UNSIGNED32, "rw", 0))
    stamp.add_member(ODVariable("Configuration time", 0x1020, 2, DataType.UNSIGNED32, "rw", 0))
    return stamp


def device_od(node_id=None):
    """The device's dictionary (EDS side): demo, 2 PDOs each way, 0x1020,
    a string and an entry the DCF leaves alone."""
    od = demo_od("classic", node_id=node_id, pdos=2)
    od.add_object(ODVariable("Device name text", 0x2F00, 0, DataType.VISIBLE_STRING, "rw",
                             "default"))
    od.add_object(ODVariable("Unconfigured", 0x2F01, 0, DataType.UNSIGNED8, "rw", 3))
    od.add_object(stamp_object())
    return od


def make_dcf(tmp_path, node_id=NODE, relative=True):
    """A commissioned classic demo node with 2 PDOs each way: heartbeat,
    a string, TPDO 1 with a 2-entry mapping, RPDO 2's type, the 0x1020
    stamp, and configured values the converter must leave out."""
    od = device_od(node_id)
    od[0x1017].value = 250
    od[0x2F00].value = "axis 1"
    od[0x1018][1].value = 0x1234              # ro: left out
    od[0x1010][1].value = 1                   # a command: left out
    od[0x1800][1].set_value(0x180, relative_to_node_id=relative, expr="$NODEID+0x180")
    od[0x1800][2].value = 1
    od[0x1A00][0].value = 2
    od[0x1A00][1].value = 0x23000120
    od[0x1A00][2].value = 0x23000220
    od[0x1401][2].value = 254
    od[0x1020][1].value = 0x0000_4A5B
    od[0x1020][2].value = 0x0123_4567
    path = tmp_path / "node.dcf"
    export_dcf(od, str(path))
    return path
