"""Python indications of a local node's OD (before-read, check-write, split
answers), driven by raw USDO requests over the in-process bus and checked on
the bytes of the server's answers (layouts: docs/protocol-notes.md)."""

import threading

import pytest

from canopenfd import AbortError, ConfigurationError
from canopenfd.od import demo_od
from helpers import Recorder, scaled

SERVER, CLIENT = 5, 2
REQUEST, RESPONSE = 0x600 + CLIENT, 0x580 + SERVER
SETPOINT = bytes([0x01, 0x00, 0x22])          # sub 1, index 0x2200 LE (INTEGER16)
U32 = (0x2007).to_bytes(2, "little")          # "Demo UNSIGNED32" 0x2007:00


@pytest.fixture
def rig(net, bus_name):
    """A server node with the demo OD, not booted yet, and a monitoring client line."""
    line = net.open_line(bus_name, mode="fd")
    node = line.create_local_node(SERVER, od=demo_od("fd"), boot=False)
    client = net.open_line(bus_name, mode="fd", monitor=True)
    answers = Recorder()
    client.on_frame(lambda f: answers(f) if f.id == RESPONSE else None)
    return node, client, answers


def ask(client, answers, data: bytes, timeout: float = 5.0):
    before = len(answers)
    client.send_frame(REQUEST, data)
    return answers.wait_count(before + 1, timeout)[before]


def write_setpoint(session: int, value: int) -> bytes:
    # expedited download: [server, 0x01, session, sub, index, type INTEGER16, N=2, value LE]
    return bytes([SERVER, 0x01, session]) + SETPOINT + bytes([0x03, 2]) + value.to_bytes(
        2, "little", signed=True)


def test_check_write_refusal_sends_the_abort_and_changes_nothing(rig):
    node, client, answers = rig
    seen = Recorder()

    @node.on_write("Demo record.Setpoint")
    def refuse_negative(request):
        seen((request.kind, request.value, request.data))
        if request.value < 0:
            raise AbortError(0x06090030, node.node_id, request.index, request.subindex)

    node.boot()
    frame = ask(client, answers, write_setpoint(1, -7))
    # abort [client, 0x7F, session, sub, index, 0x40 "invalid value"]
    assert frame.data[:7] == bytes([CLIENT, 0x7F, 1]) + SETPOINT + bytes([0x40])
    assert node[0x2200][1].raw == 0
    frame = ask(client, answers, write_setpoint(2, 42))
    assert frame.data == bytes([CLIENT, 0x21, 2]) + SETPOINT
    assert node[0x2200][1].raw == 42
    assert seen.snapshot() == [("write", -7, (-7).to_bytes(2, "little", signed=True)),
                               ("write", 42, (42).to_bytes(2, "little"))]


def test_returning_an_abort_code_refuses_too(rig):
    node, client, answers = rig
    node.boot()   # registered after boot: takes effect at once
    node.on_write((0x2200, 1), lambda request: 0x08000022)   # device state
    frame = ask(client, answers, write_setpoint(3, 5))
    assert frame.data[:7] == bytes([CLIENT, 0x7F, 3]) + SETPOINT + bytes([0x62])
    assert node[0x2200][1].raw == 0


def test_before_read_refreshes_the_value_that_is_sent(rig):
    node, client, answers = rig
    reads = Recorder()

    @node.on_read(0x2007)
    def refresh(request):
        reads(request.kind)
        node[0x2007].raw = 0xCAFEBABE

    node.boot()
    frame = ask(client, answers, bytes([SERVER, 0x11, 4, 0x00]) + U32)
    # [client, 0x31, session, sub, index, type U32 (0x07), N=4, value LE]
    assert frame.data[:12] == bytes([CLIENT, 0x31, 4, 0x00]) + U32 + bytes(
        [0x07, 4, 0xBE, 0xBA, 0xFE, 0xCA])
    assert reads.snapshot() == ["read"]


def test_deferred_write_is_answered_from_another_thread(rig):
    node, client, answers = rig
    waiting = []
    parked = threading.Event()

    @node.on_write(0x2200)   # the whole record
    def later(request):
        waiting.append(request)
        parked.set()
        return request.defer()

    node.boot()
    client.send_frame(REQUEST, write_setpoint(5, 9))
    assert parked.wait(scaled(5))
    assert len(answers) == 0          # nothing answered while the application decides
    assert node[0x2200][1].raw == 0
    threading.Thread(target=waiting[0].accept).start()
    frame = answers.wait_count(1)[0]
    assert frame.data == bytes([CLIENT, 0x21, 5]) + SETPOINT
    assert node[0x2200][1].raw == 9
    with pytest.raises(ConfigurationError, match="answered already"):
        waiting[0].refuse(0x08000000)


def test_several_callbacks_test_then_execute(rig):
    node, client, answers = rig
    order = Recorder()
    node.on_write((0x2200, 1), lambda r: order("first"))
    node.on_write((0x2200, 1), lambda r: order("second") or 0x06090031)   # value too high
    node.on_write((0x2200, 1), lambda r: order("never"))
    node.boot()
    frame = ask(client, answers, write_setpoint(6, 100))
    assert frame.data[:7] == bytes([CLIENT, 0x7F, 6]) + SETPOINT + bytes([0x41])
    assert order.snapshot() == ["first", "second"]
    assert node[0x2200][1].raw == 0


def test_a_raising_callback_refuses_with_general_error_and_the_stack_goes_on(rig):
    node, client, answers = rig
    node.on_write((0x2200, 1), lambda r: 1 / 0)
    node.boot()
    frame = ask(client, answers, write_setpoint(7, 1))
    assert frame.data[:7] == bytes([CLIENT, 0x7F, 7]) + SETPOINT + bytes([0x10])
    # unrelated entries are served as before
    frame = ask(client, answers, bytes([SERVER, 0x11, 8, 0x00]) + U32)
    assert frame.data[1] == 0x31


def test_removed_callback_lets_accesses_through(rig):
    node, client, answers = rig
    callback = node.on_write((0x2200, 1), lambda r: 0x08000000)
    node.boot()
    node.remove_indication(callback)
    frame = ask(client, answers, write_setpoint(9, 3))
    assert frame.data == bytes([CLIENT, 0x21, 9]) + SETPOINT
    assert node[0x2200][1].raw == 3


def test_wrong_use_names_the_problem(rig):
    node, _, _ = rig
    with pytest.raises(ConfigurationError, match="callable"):
        node.on_write(0x2200, "not a function")
    with pytest.raises(KeyError):
        node.on_read(0x5FFF, lambda r: None)


def test_an_application_that_never_answers_gets_the_client_a_timeout_and_frees_the_session(rig):
    node, client, answers = rig
    waiting = []
    # the first write is left waiting, later ones go through
    node.on_write((0x2200, 1), lambda r: None if waiting else waiting.append(r) or r.defer())
    node.boot()
    client.send_frame(REQUEST, write_setpoint(10, 4))
    # the server's idle timeout (1 s) answers the client with 0x12 ...
    frame = answers.wait_count(1, timeout=5)[0]
    assert frame.data[:7] == bytes([CLIENT, 0x7F, 10]) + SETPOINT + bytes([0x12])
    # ... and the late answer only frees the session: nothing written, nothing sent
    waiting[0].accept()
    assert node[0x2200][1].raw == 0
    frame = ask(client, answers, write_setpoint(11, 6))
    assert frame.data == bytes([CLIENT, 0x21, 11]) + SETPOINT
    assert len(answers) == 2
