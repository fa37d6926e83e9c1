"""Builders of the CiA 302 manager objects an application adds to its
object dictionary: per-node arrays (0x1F81 slave assignment, 0x1F84..0x1F88
expected identity, 0x1F26/0x1F27 expected configuration stamp, ...) and a
slave's "verify configuration" stamp 0x1020, and the manager's request
objects a tool writes (0x1F82, 0x1F83, 0x1F25 with the 0x1F22 concise DCFs).

    from canopenfd.od import add_node_array, add_stamp, demo_od

    od = demo_od("classic")
    add_node_array(od, 0x1F81, "Slave assignment", {2: 0x0D, 3: 0x05}, highest=3)
"""

from __future__ import annotations

from typing import Mapping, Tuple

from .datatypes import DataType
from .model import ODArray, ODVariable, ObjectDictionary

__all__ = ["add_node_array", "add_stamp", "add_manager_requests"]


def add_node_array(od: ObjectDictionary, index: int, name: str, values: Mapping[int, int],
                   highest: int) -> None:
    """An ARRAY of UNSIGNED32 (rw) with one sub-index per node-id 1..highest,
    sub n = values[n] (0 when not given); sub 0 = highest."""
    array = ODArray(name, index)
    array.add_member(ODVariable("Highest sub-index supported", index, 0, DataType.UNSIGNED8,
                                "ro", highest))
    for node in range(1, highest + 1):
        array.add_member(ODVariable(f"{name} {node}", index, node, DataType.UNSIGNED32, "rw",
                                    values.get(node, 0)))
    od.add_object(array)


def add_stamp(od: ObjectDictionary, stamp: Tuple[int, int]) -> None:
    """0x1020 verify configuration: sub 1 date (days since 1984), sub 2 time
    (ms after midnight), the stamp a configuration manager checks and writes."""
    array = ODArray("Verify configuration", 0x1020)
    array.add_member(ODVariable("Highest sub-index supported", 0x1020, 0, DataType.UNSIGNED8,
                                "ro", 2))
    for sub, (name, value) in enumerate((("Configuration date", stamp[0]),
                                         ("Configuration time", stamp[1])), start=1):
        array.add_member(ODVariable(name, 0x1020, sub, DataType.UNSIGNED32, "rw", value))
    od.add_object(array)


def add_manager_requests(od: ObjectDictionary, highest: int, dcf_nodes: int = 0,
                         dcf_room: int = 1024) -> None:
    """The network manager's request objects for node-ids 1..highest and 0x80
    (all nodes), written by a tool: 0x1F82 request NMT and 0x1F83 request
    node guarding (UNSIGNED8), 0x1F25 configuration request (UNSIGNED32,
    "conf" = 0x666E6F63); with dcf_nodes, 0x1F22 concise DCFs for nodes
    1..dcf_nodes (DOMAINs of dcf_room bytes, kept in the stack's memory:
    a runtime node serves at most 8 memory domains)."""
    for index, name, kind in ((0x1F82, "Request NMT", DataType.UNSIGNED8),
                              (0x1F83, "Request node guarding", DataType.UNSIGNED8),
                              (0x1F25, "Configuration request", DataType.UNSIGNED32)):
        array = ODArray(name, index)
        array.add_member(ODVariable("Highest sub-index supported", index, 0,
                                    DataType.UNSIGNED8, "ro", 0x80))
        for sub in (*range(1, highest + 1), 0x80):
            array.add_member(ODVariable(f"{name} {sub}", index, sub, kind, "rw", 0))
        od.add_object(array)
    if not dcf_nodes:
        return
    array = ODArray("Concise DCF", 0x1F22)
    array.add_member(ODVariable("Highest sub-index supported", 0x1F22, 0, DataType.UNSIGNED8,
                                "ro", dcf_nodes))
    for sub in range(1, dcf_nodes + 1):
        array.add_member(ODVariable(f"Concise DCF {sub}", 0x1F22, sub, DataType.DOMAIN, "rw",
                                    b"", max_length=dcf_room))
    od.add_object(array)
