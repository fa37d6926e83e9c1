"""Parameter groups declared by the application (canopenfd.services.store_groups)
on a classic node over `mem:`: the CiA 301 capability bits 0x1010/0x1011 report
per group (SDO bytes on the bus), "save" refused with 0x08000020 for a group
not saved on command, the reset type (a group restored at reset
communication, another only at reset node), autonomous saves by the stack
(a local or network write reaches the file without any save command), and
declarations refused with the group and block named."""

from __future__ import annotations

import time

import pytest

from canopenfd import ConfigurationError
from canopenfd.od import demo_od
from canopenfd.services.store import MemoryStore
from canopenfd.services.store_groups import StoreGroup
from canopenfd.services.store_image import parse_image
from canopenfd.services.store_text import TextStore
from helpers import Recorder, scaled

NODE = 7
REQUEST, RESPONSE = 0x600 + NODE, 0x580 + NODE
SAVE = b"save"
GROUPS = [
    StoreGroup("comm", [(0x1000, 0x1FFF)], reset="communication"),           # sub 2
    StoreGroup("tuning", [(0x2005, 0x2007)], mode="autonomous"),             # sub 3
    StoreGroup("limits", [(0x2001, 0x2004)], mode="on-command", reset="node"),  # sub 4
]


def boot(net, bus, path, groups=GROUPS, interval_ms=200):
    line = net.open_line(bus, mode="classic")
    return line.create_local_node(NODE, od=demo_od("classic"), store=str(path),
                                  store_groups=groups, store_interval_ms=interval_ms)


class Client:
    """Raw SDO expedited requests from node 0x7F's side, answers checked bytewise."""

    def __init__(self, net, bus):
        self.line = net.open_line(bus, mode="classic", monitor=True)
        self.answers = Recorder()
        self.line.on_frame(lambda f: self.answers(f) if f.id == RESPONSE else None)

    def exchange(self, request: bytes) -> bytes:
        count = len(self.answers)
        self.line.send_frame(REQUEST, request)
        return bytes(self.answers.wait_count(count + 1)[count].data)

    def upload(self, index: int, sub: int) -> bytes:
        return self.exchange(bytes([0x40, index & 0xFF, index >> 8, sub, 0, 0, 0, 0]))

    def download(self, index: int, sub: int, data: bytes) -> bytes:
        command = 0x23 | (4 - len(data)) << 2
        return self.exchange(bytes([command, index & 0xFF, index >> 8, sub]) +
                             data.ljust(4, b"\0"))


def saved(path, index, sub=0):
    """The bytes the file holds for an entry, None when none."""
    try:
        image = parse_image(path.read_bytes())
    except FileNotFoundError:
        return None
    return next((r.data for r in image.records if (r.index, r.sub) == (index, sub)), None)


def wait_saved(path, index, data, timeout=5.0):
    deadline = time.monotonic() + scaled(timeout)
    while saved(path, index) != data:
        assert time.monotonic() < deadline, f"0x{index:04X} never saved as {data.hex()}"
        time.sleep(0.01)


def reset(node, command):
    resets = Recorder()
    node.on_reset(resets)
    node.apply(command)
    resets.wait_count(1)
    node.wait_for_state("PRE-OPERATIONAL")


def test_0x1010_reports_each_groups_capability_bits_on_the_wire(net, bus_name, tmp_path):
    boot(net, bus_name, tmp_path / "p.bin")
    sdo = Client(net, bus_name)
    # bit 0 on command, bit 1 autonomously; sub 1 = every group
    for sub, bits in ((1, 3), (2, 1), (3, 2), (4, 1)):
        assert sdo.upload(0x1010, sub) == bytes([0x43, 0x10, 0x10, sub, bits, 0, 0, 0])
    assert sdo.upload(0x1011, 3) == bytes([0x43, 0x11, 0x10, 3, 1, 0, 0, 0])
    # "save" to the autonomous-only group: 0x08000020, nothing written
    assert sdo.download(0x1010, 3, SAVE) == bytes([0x80, 0x10, 0x10, 3, 0x20, 0, 0, 0x08])
    assert not (tmp_path / "p.bin").exists()
    assert sdo.download(0x1010, 4, SAVE) == bytes([0x60, 0x10, 0x10, 4, 0, 0, 0, 0])
    assert saved(tmp_path / "p.bin", 0x2003) == (-1000).to_bytes(2, "little", signed=True)


def test_the_reset_type_decides_which_reset_restores_a_group(net, bus_name, tmp_path):
    path = tmp_path / "p.bin"
    node = boot(net, bus_name, path)
    sdo = Client(net, bus_name)
    node[0x1017].raw = 300
    node[0x2003].raw = -5
    assert sdo.download(0x1010, 1, SAVE) == bytes([0x60, 0x10, 0x10, 1, 0, 0, 0, 0])
    node[0x1017].raw = 50
    node[0x2003].raw = -6
    reset(node, "reset-communication")
    assert node[0x1017].raw == 300       # "comm": reset communication
    assert node[0x2003].raw == -6        # "limits": only at reset node
    reset(node, "reset-node")
    assert node[0x2003].raw == -5


def test_autonomous_groups_are_saved_by_the_stack_without_a_command(net, bus_name, tmp_path):
    path = tmp_path / "p.bin"
    node = boot(net, bus_name, path)
    sdo = Client(net, bus_name)
    node[0x2006].raw = 1234                           # a local write
    wait_saved(path, 0x2006, (1234).to_bytes(2, "little"))
    assert sdo.download(0x2006, 0, (4321).to_bytes(2, "little"))[0] == 0x60   # a network one
    wait_saved(path, 0x2006, (4321).to_bytes(2, "little"))
    for value in range(100, 150):                     # a burst: the last value lands
        node[0x2007].raw = value
    wait_saved(path, 0x2007, (149).to_bytes(4, "little"))
    node[0x2003].raw = 77                             # on command only: not saved
    node[0x2005].raw = 9
    wait_saved(path, 0x2005, bytes([9]))
    assert saved(path, 0x2003) is None
    restarted = boot(net, bus_name + "-restart", path)
    assert restarted[0x2006].raw == 4321 and restarted[0x2007].raw == 149
    assert restarted[0x2003].raw == -1000


@pytest.mark.parametrize("groups, words", [
    ([StoreGroup("a", [(0x2000, 0x20FF)]), StoreGroup("b", [(0x2080, 0x2100)])],
     "store group 'b': block 0x2080:00..0x2100:FF overlaps 0x2000:00..0x20FF:FF of group 'a'"),
    ([StoreGroup("a", [(0x2000, 0x20FF)], mode="sometimes")], "mode 'sometimes'"),
    ([StoreGroup("a", [(0x2000, 0x20FF)], reset="power")], "reset 'power'"),
    ([StoreGroup("all", [(0x2000, 0x20FF)])], "'all': the name is taken"),
    ([StoreGroup("a", [(0x0800, 0x20FF)])], "outside 0x1000:00..0xFFFF:FF"),
    ([StoreGroup("a", [(0x3000, 0x2000)])], "is empty (first after last)"),
    ([StoreGroup(f"g{n}", [(0x2000 + n, 0x2000 + n)]) for n in range(9)], "1..8 store groups"),
])
def test_bad_declarations_are_refused_naming_the_group(net, bus_name, tmp_path, groups, words):
    line = net.open_line(bus_name, mode="classic")
    with pytest.raises(ConfigurationError, match="create_local_node") as info:
        line.create_local_node(NODE, od=demo_od("classic"), store=str(tmp_path / "p.bin"),
                               store_groups=groups)
    assert words in str(info.value)
    assert line.local_node is None


def wait_for(condition, what, timeout=5.0):
    deadline = time.monotonic() + scaled(timeout)
    while not condition():
        assert time.monotonic() < deadline, what
        time.sleep(0.01)


def test_the_text_store_is_written_on_change(net, bus_name, tmp_path):
    """Retentive variables: a change of an autonomous group's member reaches
    the text file through the application store, no save command."""
    path = tmp_path / "p.txt"
    line = net.open_line(bus_name, mode="classic")
    node = line.create_local_node(NODE, od=demo_od("classic"), store=TextStore(path),
                                  store_groups=GROUPS, store_interval_ms=100)
    node[0x2006].raw = 1234
    wait_for(lambda: path.exists() and "2006 00 UNSIGNED16 2 : D2 04\n" in path.read_text(),
             "0x2006 never written to the text store")
    assert "2003 00" not in path.read_text()          # "limits" is saved on command only
    node[0x2003].raw = -7
    node.save_parameters("limits")
    assert "2003 00 INTEGER16 2 : F9 FF\n" in path.read_text()
    with pytest.raises(ConfigurationError, match="one of all, comm, tuning, limits"):
        node.save_parameters("communication")
    restarted = boot_on(net, bus_name + "-restart", TextStore(path))
    assert restarted[0x2006].raw == 1234 and restarted[0x2003].raw == -7


def boot_on(net, bus, store):
    line = net.open_line(bus, mode="classic")
    return line.create_local_node(NODE, od=demo_od("classic"), store=store,
                                  store_groups=GROUPS, store_interval_ms=100)


def test_an_autonomous_save_the_medium_refuses_is_retried(net, bus_name):
    class Flaky(MemoryStore):
        failures = 1

        def save(self, image):
            if self.failures:
                self.failures -= 1
                raise OSError("medium busy")
            super().save(image)

    store = Flaky()
    node = boot_on(net, bus_name, store)
    node[0x2005].raw = 42
    # the first save raised: the stack marks the group changed and saves again
    wait_for(lambda: store.saves == 1, "the refused autonomous save was never retried")
    assert store.failures == 0
    assert boot_on(net, bus_name + "-restart", MemoryStore(store.image))[0x2005].raw == 42


def test_an_application_save_while_an_autonomous_image_waits_persists_both(net, bus_name):
    """The stack staged an autonomous image the dispatcher has not written yet
    (it is busy in a callback): save_parameters writes that image first, then
    its own, instead of failing on the busy staging slot."""
    import threading

    store = MemoryStore()
    node = boot_on(net, bus_name, store)
    busy, release = threading.Event(), threading.Event()

    def hold_the_dispatcher(value, origin):
        busy.set()
        assert release.wait(scaled(10))
    node.on_object_changed(hold_the_dispatcher)
    sdo = Client(net, bus_name)
    sdo.line.send_frame(REQUEST, bytes([0x2B, 0x17, 0x10, 0, 0x2C, 0x01, 0, 0]))  # 0x1017
    assert busy.wait(scaled(5))
    node[0x2006].raw = 555               # autonomous: staged, its event waits
    time.sleep(scaled(0.2))
    node[0x2003].raw = -9
    node.save_parameters("limits")       # takes the autonomous image to the medium first
    release.set()
    assert store.saves == 2
    image = parse_image(store.image)
    values = {(r.index, r.sub): r.data for r in image.records}
    assert values[(0x2006, 0)] == (555).to_bytes(2, "little")
    assert values[(0x2003, 0)] == (-9).to_bytes(2, "little", signed=True)
