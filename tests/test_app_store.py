"""Parameter stores kept by the application (canopenfd.services.store): load at boot
and resets, saves from the application and over the network (USDO 0x1010,
answered only after the store's save() returned), failures reported with the
CiA abort code and never half-applied."""

import threading

import pytest

from canopenfd import AbortError, ConfigurationError
from canopenfd.od import demo_od
from canopenfd.services.store import MemoryStore
from helpers import Recorder, scaled

NODE, CLIENT = 5, 2
REQUEST, RESPONSE = 0x600 + CLIENT, 0x580 + NODE
SAVE_ALL = bytes([NODE, 0x01, 1, 0x01, 0x10, 0x10, 0x07, 4]) + (0x65766173).to_bytes(4, "little")


def make_node(net, bus, store, problems=None):
    line = net.open_line(bus, mode="fd")
    node = line.create_local_node(NODE, od=demo_od("fd"), store=store, boot=False)
    if problems is not None:
        node.on_store_problem(problems)
    node.boot()
    return node


def reset(node):
    """Reset the communication and wait until it ran (parameters loaded)."""
    resets = Recorder()
    node.on_reset(resets)
    node.apply("reset-communication")
    resets.wait_count(1)
    node.wait_for_state("PRE-OPERATIONAL")


def test_saved_parameters_come_back_from_the_application_store(net, bus_name):
    store = MemoryStore()
    node = make_node(net, bus_name, store)
    assert node.store_status == "empty"
    node[0x1017].raw = 321
    node.save_parameters()
    assert store.saves == 1 and store.image
    node[0x1017].raw = 5
    reset(node)
    assert node[0x1017].raw == 321
    # a new node (a restart of the device) loads the same image
    net2_node = make_node(net, bus_name + "-2", MemoryStore(store.image))
    assert net2_node[0x1017].raw == 321 and net2_node.store_status == "ok"


def test_a_failing_save_raises_and_keeps_the_old_image(net, bus_name):
    class Flaky(MemoryStore):
        fail = False

        def save(self, image):
            if self.fail:
                raise OSError("flash worn out")
            super().save(image)

    store = Flaky()
    node = make_node(net, bus_name, store)
    node[0x1017].raw = 100
    node.save_parameters()
    store.fail = True
    node[0x1017].raw = 200
    with pytest.raises(AbortError) as info:
        node.save_parameters()
    assert info.value.code == 0x08000020 and info.value.index == 0x1010
    reset(node)
    assert node[0x1017].raw == 100      # the image that reached the medium
    store.fail = False
    node[0x1017].raw = 300               # and the next save works again
    node.save_parameters()
    reset(node)
    assert node[0x1017].raw == 300


def test_network_save_is_answered_after_the_store_saved(net, bus_name):
    entered, release = threading.Event(), threading.Event()

    class Slow(MemoryStore):
        def save(self, image):
            entered.set()
            assert release.wait(scaled(5))
            super().save(image)

    store = Slow()
    node = make_node(net, bus_name, store)
    client = net.open_line(bus_name, mode="fd", monitor=True)
    answers = Recorder()
    client.on_frame(lambda f: answers(f) if f.id == RESPONSE else None)
    node[0x1017].raw = 444
    client.send_frame(REQUEST, SAVE_ALL)
    assert entered.wait(scaled(5))
    assert len(answers) == 0             # no answer while the medium is being written
    release.set()
    frame = answers.wait_count(1)[0]
    assert frame.data == bytes([CLIENT, 0x21, 1, 0x01, 0x10, 0x10])
    assert store.saves == 1
    node[0x1017].raw = 1
    reset(node)
    assert node[0x1017].raw == 444


def test_network_save_that_fails_is_aborted_with_0x60(net, bus_name):
    class Broken(MemoryStore):
        def save(self, image):
            raise OSError("no medium")

    node = make_node(net, bus_name, Broken())
    client = net.open_line(bus_name, mode="fd", monitor=True)
    answers = Recorder()
    client.on_frame(lambda f: answers(f) if f.id == RESPONSE else None)
    node[0x1017].raw = 444
    client.send_frame(REQUEST, SAVE_ALL)
    frame = answers.wait_count(1)[0]
    # USDO abort 0x60 = CiA 0x08000020 "data cannot be stored"
    assert frame.data[:7] == bytes([CLIENT, 0x7F, 1, 0x01, 0x10, 0x10, 0x60])
    reset(node)
    assert node[0x1017].raw != 444


@pytest.mark.parametrize("kind, status", [("garbage", "foreign"), ("flipped", "damaged"),
                                          ("unreadable", "io-error")])
def test_unusable_images_start_from_defaults_and_say_so(net, bus_name, kind, status):
    saved = MemoryStore()
    donor = make_node(net, bus_name + "-donor", saved)
    donor[0x1017].raw = 999
    donor.save_parameters()
    flipped = bytearray(saved.image)
    flipped[len(flipped) // 2] ^= 0x10
    image = {"garbage": b"garbage" * 10, "flipped": bytes(flipped), "unreadable": None}[kind]

    class Store(MemoryStore):
        def load(self):
            if image is None:
                raise OSError("medium unreadable")
            return image

    problems = Recorder()
    node = make_node(net, bus_name, Store(), problems)
    assert node.store_status == status
    assert problems.wait_count(1)[0] == (status, 0)
    assert node[0x1017].raw == demo_od("fd")[0x1017].default


def test_restore_defaults_through_the_application_store(net, bus_name):
    store = MemoryStore()
    node = make_node(net, bus_name, store)
    node[0x1017].raw = 777
    node.save_parameters()
    node.restore_defaults()
    assert store.saves == 2
    reset(node)
    assert node[0x1017].raw == demo_od("fd")[0x1017].default


def test_a_store_without_load_and_save_is_refused(net, bus_name):
    line = net.open_line(bus_name, mode="fd")
    with pytest.raises(ConfigurationError, match="load\\(\\) and save\\(image\\)"):
        line.create_local_node(NODE, od=demo_od("fd"), store=object())
