"""CiA 304's default COB-IDs of SRDO 1 (docs/protocol-notes.md, "SRDO and
GFC"): an OD whose 0x1301 sub 5 / 6 hold 0x0FF / 0x100 runs SRDO 1 on
0x0FF + 2 x node-id / 0x100 + 2 x node-id; a tool reads the CAN-IDs used, the
pair goes out on them, and after a reset under another node-id
(`set_node_id_at_reset`) they follow it. Over the in-process bus."""

from __future__ import annotations

import struct

from helpers import Recorder
from test_srdo import DATA, MAPPING, inverted, srdo_od

from canopenfd.services.srdo import SrdoConfig, srdo_config_writes


def cob_ids(remote):
    return tuple(struct.unpack("<I", remote.read((0x1301, sub)))[0] for sub in (5, 6))


def first_pair(frames, mark, ids):
    def pair(calls):
        got = [(f.id, bytes(f.data)) for f in calls[mark:] if f.id in ids]
        return got[:2] if len(got) >= 2 else None
    return frames.wait_for(pair, 3.0, f"a pair on {[hex(i) for i in ids]}")


def test_srdo_1_runs_on_the_default_cob_ids_of_its_node_id(net, bus_name):
    device = net.open_line(bus_name, mode="classic").create_local_node(5, od=srdo_od(0x0FF))
    tool = net.open_line(bus_name, mode="classic")
    frames = Recorder()
    net.open_line(bus_name, mode="classic", monitor=True).on_frame(frames)
    device.srdo.start(1)
    assert cob_ids(tool.add_node(5)) == (0x109, 0x10A)          # 0x0FF + 2 x 5
    device.set_node_id_at_reset(7)
    device.apply("RESET_COMMUNICATION")
    device.wait_for_state("PRE-OPERATIONAL")
    remote = tool.add_node(7)
    assert cob_ids(remote) == (0x10D, 0x10E)                    # 0x0FF + 2 x 7
    # a tool configures all but the COB-IDs, signing the CAN-IDs the device uses
    produce = SrdoConfig("produce", sct_ms=20, srvt_ms=10, cob_id=0x10D, mapping=MAPPING)
    for index, sub, value in srdo_config_writes(1, produce):
        if (index, sub) not in ((0x1301, 5), (0x1301, 6)):
            remote.write((index, sub), value)
    device.srdo.set_data(1, DATA)
    mark = len(frames)
    device.apply("start")
    assert first_pair(frames, mark, (0x10D, 0x10E)) == [(0x10D, DATA), (0x10E, inverted(DATA))]
