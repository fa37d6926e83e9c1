"""A local node serving an object dictionary, over the in-process bus: typed
access, limits and abort codes, heartbeat through 0x1017/0x1016, the
parameter store, OD files by path, node-id relative values, refused ODs.

Tests marked xfail(strict=True) describe behaviour the API documents (or the
brief of this work asks for) that the code does not have yet: each says what
happens instead. When the code is fixed they fail as XPASS; drop the mark then.
"""

from __future__ import annotations

import os
import random
import time
from typing import Any, List

import pytest
from helpers import Recorder, scaled

import canopenfd
from canopenfd import ConfigurationError, NmtState
from canopenfd.errors import AbortError
from canopenfd.od import (DataType, ODArray, ODRecord, ODVariable, ObjectDictionary,
                          OdValueError, TimeDifference, TimeOfDay, demo_od, encode)

T = 5.0  # default wait, scaled by CANOPENFD_TIME_SCALE
DATA = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data", "od")
NODE = 3

VALUE_HIGH, VALUE_LOW = 0x06090031, 0x06090032
LENGTH_HIGH, LENGTH_LOW = 0x06070012, 0x06070013
UNSUPPORTED_ACCESS = 0x06010000

MODES = pytest.mark.parametrize("mode", ["fd", "classic"])

_PYTHON_TYPE = {DataType.BOOLEAN: bool, DataType.REAL32: float, DataType.REAL64: float,
                DataType.VISIBLE_STRING: str, DataType.UNICODE_STRING: str,
                DataType.OCTET_STRING: bytes, DataType.TIME_OF_DAY: TimeOfDay,
                DataType.TIME_DIFFERENCE: TimeDifference}


def python_type(dtype: DataType) -> type:
    return int if dtype.is_integer else _PYTHON_TYPE[dtype]


def value_entries(od: ObjectDictionary, mode: str) -> List[ODVariable]:
    """Every entry a node on a `mode` line holds a value for (DOMAIN data
    lives with the application; entries of the other line mode are left out)."""
    return [var for var in od.entries()
            if var.data_type != DataType.DOMAIN and var.line_mode in (None, mode)]


def start_value(var: ODVariable, node_id: int = NODE) -> Any:
    """What the node starts with: the default (the type's zero without one)."""
    return var.decode_raw(var.default_bytes(node_id))


def serve(net: canopenfd.Network, bus: str, mode: str, od: Any = None, node_id: int = NODE,
          **kwargs: Any) -> canopenfd.LocalNode:
    line = net.open_line(bus, mode=mode)
    return line.create_local_node(node_id, od=demo_od(mode) if od is None else od, **kwargs)


def other_values(var: ODVariable) -> List[Any]:
    """Valid values other than the default, from the entry's metadata: the
    limits (or the type's range) for numbers, the longest and a short string."""
    dtype, default = var.data_type, start_value(var)
    if dtype == DataType.BOOLEAN:
        candidates: List[Any] = [not default]
    elif dtype.is_integer or dtype.is_real:
        low = dtype.min if var.low_limit is None else var.low_limit
        high = dtype.max if var.high_limit is None else var.high_limit
        if dtype.is_real:
            low, high = max(low, -1e6), min(high, 1e6)   # exactly representable
            candidates = [high, low, 0.5 if low <= 0.5 <= high else high]
        else:
            candidates = [high, low, (low + high) // 2]
    elif dtype in (DataType.VISIBLE_STRING, DataType.UNICODE_STRING):
        unit = 1 if dtype == DataType.VISIBLE_STRING else 2
        longest = (var.max_length or var.storage_size) // unit
        filler = "Zq" if dtype == DataType.VISIBLE_STRING else "Ωq"
        candidates = [(filler * longest)[:longest], filler[0]]
    elif dtype == DataType.OCTET_STRING:
        size = var.max_length or var.storage_size
        candidates = [bytes(range(0xA0, 0xA0 + size)), b"\x5a"]
    elif dtype == DataType.TIME_OF_DAY:
        candidates = [TimeOfDay(default.ms + 1234, default.days + 1)]
    elif dtype == DataType.TIME_DIFFERENCE:
        candidates = [TimeDifference(default.ms + 1234, default.days + 2)]
    else:  # pragma: no cover - every demo type is covered above
        raise AssertionError(f"no test value for {dtype.name}")
    return [value for value in candidates if value != default]


def wait_reset(node: canopenfd.LocalNode, command: str) -> None:
    """Apply a reset and wait until it ran (its parameters are loaded then)."""
    resets = Recorder()
    node.on_reset(resets)
    node.apply(command)
    resets.wait_count(1, timeout=T)
    node.wait_for_state(NmtState.PRE_OPERATIONAL, timeout=scaled(T))


def monitor_frames(net: canopenfd.Network, bus: str, mode: str) -> Recorder:
    frames = Recorder()
    net.open_line(bus, mode=mode, monitor=True).on_frame(frames)
    return frames


def heartbeats(frames: Recorder, node_id: int, since: float, until: float = float("inf")):
    return [f for f in frames.snapshot()
            if f.id == 0x700 + node_id and f.data != b"\0" and since <= f.timestamp < until]


# ------------------------------------------------------------------ reading
@MODES
def test_every_entry_reads_its_default_with_the_right_python_type(net, bus_name, mode):
    od = demo_od(mode)
    node = serve(net, bus_name, mode, od)
    entries = value_entries(od, mode)
    assert len(entries) > 40
    for var in entries:
        value = node[(var.index, var.subindex)].raw
        assert type(value) is python_type(var.data_type), (var, value)
        assert value == start_value(var), var
        if var.default is not None:
            assert value == var.default, var
        assert node[(var.index, var.subindex)].data == var.default_bytes(NODE), var
    # The same entry by the other keys the OD accepts.
    assert node["Producer heartbeat time"].raw == node[0x1017].raw == node["0x1017"].raw
    assert node["0x1018:2"].raw == node[(0x1018, 2)].raw == node["Identity object.Product code"].raw


@MODES
def test_a_large_domain_without_memory_is_refused_with_a_hint(net, bus_name, mode):
    """0x2100 (max 16 MiB) gets no memory by itself: refused, the refusal says
    serve_domain is the fix, and node.unserved_domains names it."""
    node = serve(net, bus_name, mode)
    with pytest.raises(AbortError) as caught:
        _ = node[0x2100].data
    assert caught.value.code == UNSUPPORTED_ACCESS
    assert (caught.value.node, caught.value.index, caught.value.subindex) == (NODE, 0x2100, 0)
    assert "node.serve_domain(0x2100, capacity)" in str(caught.value)
    assert [(v.index, v.subindex) for v in node.unserved_domains] == [(0x2100, 0)]


@MODES
def test_a_small_domain_is_kept_in_the_stack_by_itself(net, bus_name, mode):
    """0x200F (max 1024 bytes, at most AUTO_DOMAIN_LIMIT) has memory from boot:
    empty at first, written and read back, longer than its maximum refused."""
    node = serve(net, bus_name, mode)
    assert node[0x200F].data == b""
    node[0x200F].data = bytes(range(256)) * 4
    assert node[0x200F].data == bytes(range(256)) * 4
    with pytest.raises(AbortError) as caught:
        node[0x200F].data = bytes(1025)
    assert caught.value.code in (0x06070010, 0x06070012)
    assert "serve_domain" not in str(caught.value)


# ------------------------------------------------------------------ writing
# The EMCY producer keeps these from the active errors: the error register,
# the error history, the FD active error list.
KEPT_BY_EMCY = (0x1001, 0x1003, 0x1032)


@MODES
def test_emcy_entries_refuse_writes(net, bus_name, mode):
    od = demo_od(mode)
    node = serve(net, bus_name, mode, od)
    assert 0x1001 in od
    with pytest.raises(AbortError) as caught:
        node[0x1001].raw = 0xFF
    assert caught.value.code == 0x06010002
    assert (caught.value.node, caught.value.index, caught.value.subindex) == (NODE, 0x1001, 0)
    assert node[0x1001].raw == 0


@MODES
def test_writes_round_trip_for_every_data_type_and_entry(net, bus_name, mode):
    od = demo_od(mode)
    node = serve(net, bus_name, mode, od)
    written = set()
    for var in value_entries(od, mode):
        if var.in_object and var.subindex == 0:
            continue                               # the counts stay as they are
        if var.index in KEPT_BY_EMCY:
            continue                               # see test_emcy_entries_refuse_writes
        for value in other_values(var):
            entry = node[(var.index, var.subindex)]
            entry.raw = value
            assert entry.raw == value, (var, value)
            assert type(entry.raw) is python_type(var.data_type)
            assert entry.data == var.encode_raw(value), var
            written.add(var.data_type)
        entry.data = var.default_bytes(NODE)                 # the wire form works too
        assert entry.raw == start_value(var), var
    every_type = {dtype for dtype in DataType if dtype != DataType.DOMAIN}
    assert written == every_type, every_type - written


LIMITED = [(var.index, var.subindex) for var in demo_od("fd").entries()
           if var.low_limit is not None or var.high_limit is not None]


@MODES
@pytest.mark.parametrize("key", LIMITED, ids=[f"{i:04X}sub{s}" for i, s in LIMITED])
def test_value_outside_the_limits_is_refused_in_python_and_in_c(net, bus_name, mode, key):
    od = demo_od(mode)
    node = serve(net, bus_name, mode, od)
    var = od[key]
    step = 0.5 if var.data_type.is_real else 1
    before = node[key].raw
    for value, code in ((var.high_limit + step, VALUE_HIGH), (var.low_limit - step, VALUE_LOW)):
        with pytest.raises(OdValueError, match=f"^{var.where} "):   # the Python check
            node[key].raw = value
        with pytest.raises(AbortError) as caught:                    # the C check
            node[key].data = encode(var.data_type, value)
        error = caught.value
        assert error.code == code, f"{var.where} {value!r}: 0x{error.code:08X}"
        assert (error.node, error.index, error.subindex) == (NODE, var.index, var.subindex)
        assert f"0x{code:08X}" in str(error) and var.where in str(error)
        assert node[key].raw == before
    for value in (var.low_limit, var.high_limit):                   # limits are inclusive
        node[key].raw = value
        assert node[key].raw == value


@MODES
def test_wrong_length_through_data_is_refused(net, bus_name, mode):
    od = demo_od(mode)
    node = serve(net, bus_name, mode, od)
    checked = 0
    for var in value_entries(od, mode):
        if var.size is None:
            continue
        entry, good = node[(var.index, var.subindex)], var.default_bytes(NODE)
        for data, code in ((good + b"\0", LENGTH_HIGH), (good[:-1], LENGTH_LOW)):
            with pytest.raises(AbortError) as caught:
                entry.data = data
            assert caught.value.code == code, f"{var.where} {len(data)} bytes"
        assert entry.data == good
        checked += 1
    assert checked > 30
    text = node[0x2009]                                   # VISIBLE_STRING, at most 32 bytes
    with pytest.raises(AbortError) as caught:
        text.data = b"x" * 33
    assert caught.value.code == LENGTH_HIGH
    with pytest.raises(OdValueError, match="0x2009:00"):
        text.raw = "x" * 33
    assert text.raw == "canopenfd"


def test_missing_entries_raise_key_error(net, bus_name):
    node = serve(net, bus_name, "fd")
    for key in (0x3000, "0x1018:7", (0x1018, 7), "no such entry", "Identity object.Nope"):
        with pytest.raises((KeyError, ConfigurationError), match="not in the object dictionary"):
            node[key]


@pytest.mark.parametrize("index, kind", [(0x1018, "RECORD"), (0x1016, "ARRAY")])
def test_record_or_array_without_sub_index_is_a_configuration_error(net, bus_name, index, kind):
    node = serve(net, bus_name, "fd")
    with pytest.raises(ConfigurationError, match=f"0x{index:04X} .* is an {kind}; give a sub-index"):
        node[index].raw


def test_record_access_suggested_by_the_error_message_works(net, bus_name):
    node = serve(net, bus_name, "fd")
    with pytest.raises(ConfigurationError) as caught:
        node[0x1018].raw
    assert "4120" not in str(caught.value)
    assert "node[0x1018][1].raw" in str(caught.value)
    assert node[0x1018][1].raw == 0
    assert node[0x1018]["Vendor-ID"].raw == 0


def test_node_without_od_has_no_entries(net, bus_name):
    node = net.open_line(bus_name).create_local_node(NODE)
    with pytest.raises(ConfigurationError, match="serves no object dictionary"):
        node[0x1017]


@MODES
def test_application_writes_to_ro_entries_are_allowed(net, bus_name, mode):
    """co_od_put is the application's access: access rights are for the
    network (SDO/USDO), so the application may set ro entries, e.g. the
    identity or a measured value. Type, length and limits still apply."""
    od = demo_od(mode)
    node = serve(net, bus_name, mode, od)
    read_only = [var for var in value_entries(od, mode)
                 if var.access_type == "ro" and not (var.in_object and var.subindex == 0)
                 and var.index not in KEPT_BY_EMCY]
    assert {(v.index, v.subindex) for v in read_only} >= {(0x1018, 1), (0x2014, 0)}
    for var in read_only:
        value = other_values(var)[0]
        node[(var.index, var.subindex)].raw = value
        assert node[(var.index, var.subindex)].raw == value, var
    with pytest.raises(AbortError) as caught:
        node["0x1018:1"].data = b"\1\2"
    assert caught.value.code == LENGTH_LOW


# ------------------------------------------------------------------ heartbeat
@MODES
def test_heartbeat_period_from_0x1017_changes_at_once(net, bus_name, mode):
    frames = monitor_frames(net, bus_name, mode)
    od = demo_od(mode)
    od[0x1017].default = 2000
    node = serve(net, bus_name, mode, od)
    frames.wait_for(lambda fs: any(f.id == 0x700 + NODE and f.data == b"\0" for f in fs),
                    what="boot-up")
    assert node.heartbeat_ms == 2000
    node[0x1017].raw = 50
    changed = time.monotonic()
    assert node.heartbeat_ms == 50
    time.sleep(1.0)                              # let protocol time pass
    # the monitor delivers late: a heartbeat after the window means all of it is in
    frames.wait_for(lambda fs: heartbeats(frames, NODE, changed + 1.0), 5,
                    "a heartbeat after the 1 s window")
    beats = heartbeats(frames, NODE, changed, changed + 1.0)
    assert 5 <= len(beats) <= 40, f"{len(beats)} heartbeats in 1 s at 50 ms (about 20)"
    for frame in beats:
        assert frame.id == 0x700 + NODE
        assert frame.data == bytes([NmtState.PRE_OPERATIONAL])       # 1 byte: the state
        assert frame.fd is (mode == "fd")
        assert not frame.ext and not frame.rtr

    node.heartbeat_ms = 0                        # the property writes 0x1017
    assert node[0x1017].raw == 0
    off = time.monotonic()
    time.sleep(0.4)
    assert heartbeats(frames, NODE, off + 0.1, off + 0.4) == []


@MODES
def test_heartbeat_ms_is_0x1017(net, bus_name, mode):
    node = serve(net, bus_name, mode, heartbeat_ms=40)      # replaces the OD default (0)
    assert node[0x1017].raw == 40 and node.heartbeat_ms == 40
    node[0x1017].raw = 123
    assert node.heartbeat_ms == 123
    node.heartbeat_ms = 77
    assert node[0x1017].raw == 77
    wait_reset(node, "reset-communication")                  # back to the start value
    assert node.heartbeat_ms == 40 == node[0x1017].raw


def _consumer_od(mode: str, watched: int, timeout_ms: int) -> ObjectDictionary:
    od = demo_od(mode)
    od["0x1016:1"].default = (watched << 16) | timeout_ms
    return od


# The consumer entries of 0x1016 and those of add_node() share one table in
# the line (co_hb_consumer). add_node(id) with timeout 0 only watches states:
# it leaves an entry 0x1016 configured as it is (and gives way to one written
# later), and remove_node() never clears an entry that mirrors 0x1016.
def _watch_and_lose(net, bus: str, remote) -> None:
    started, lost = Recorder(), Recorder()
    remote.on_heartbeat_started(started)
    remote.on_heartbeat_lost(lost)
    device = net.open_line(bus, mode="fd").create_local_node(7, heartbeat_ms=30)
    started.wait_count(1)
    device.heartbeat_ms = 0
    lost.wait_count(1, timeout=1.0)


@pytest.mark.parametrize("order", ["add_node_after", "add_node_before"])
def test_heartbeat_consumer_configured_by_the_od(net, bus_name, order):
    line = net.open_line(bus_name, mode="fd")
    od = _consumer_od("fd", 7, 150)
    if order == "add_node_before":
        remote = line.add_node(7)
        node = line.create_local_node(NODE, od=od)
    else:
        node = line.create_local_node(NODE, od=od)
        remote = line.add_node(7)
    assert node["0x1016:1"].raw == (7 << 16) | 150
    _watch_and_lose(net, bus_name, remote)


def test_heartbeat_consumer_time_written_to_0x1016_after_add_node(net, bus_name):
    line = net.open_line(bus_name, mode="fd")
    node = line.create_local_node(NODE, od=demo_od("fd"))
    remote = line.add_node(7)
    node["0x1016:1"].raw = (7 << 16) | 150
    assert node["0x1016:1"].raw == (7 << 16) | 150
    _watch_and_lose(net, bus_name, remote)


def test_remove_node_leaves_the_consumer_entry_of_0x1016(net, bus_name):
    line = net.open_line(bus_name, mode="fd")
    line.create_local_node(NODE, od=_consumer_od("fd", 7, 150))
    line.remove_node(line.add_node(7).node_id)
    # the OD's 0x1016:1 still watches node 7: a new RemoteNode hears it lost
    _watch_and_lose(net, bus_name, line.add_node(7))


def test_consumer_time_of_a_node_that_0x1016_monitors_is_refused_at_once(net, bus_name):
    line = net.open_line(bus_name, mode="fd")
    node = line.create_local_node(NODE, od=_consumer_od("fd", 7, 150))
    with pytest.raises(ConfigurationError, match=r"0x1016:01 \(150 ms\)"):
        line.add_node(7, heartbeat_timeout_ms=500)
    remote = line.add_node(7)                       # states only: fine
    with pytest.raises(ConfigurationError, match="node 7 is monitored by"):
        remote.heartbeat_timeout_ms = 500
    assert remote.heartbeat_timeout_ms == 0
    assert node["0x1016:1"].raw == (7 << 16) | 150   # untouched
    line.add_node(8, heartbeat_timeout_ms=500)      # a node 0x1016 does not name
    _watch_and_lose(net, bus_name, remote)          # 0x1016's 150 ms still rules


def test_consumer_time_next_to_a_var_0x1016(net, bus_name):
    """An OD whose 0x1016 is a VAR (not CiA 301's array) monitors nothing: the
    check for a conflicting 0x1016 entry passes (it crashed with AttributeError
    before mypy pointed at it)."""
    od = demo_od("fd")
    del od[0x1016]
    od.add_object(ODVariable("Consumer heartbeat time", 0x1016, 0, DataType.UNSIGNED32,
                             "rw", (7 << 16) | 150))
    line = net.open_line(bus_name, mode="fd")
    line.create_local_node(NODE, od=od)
    remote = line.add_node(7, heartbeat_timeout_ms=500)
    assert remote.heartbeat_timeout_ms == 500


# ------------------------------------------------------------------ store
def _stored_node(net: canopenfd.Network, bus: str, mode: str, store: str,
                 problems: Recorder = None) -> canopenfd.LocalNode:
    """A node with the demo OD and a store; problems registered before boot."""
    line = net.open_line(bus, mode=mode)
    node = line.create_local_node(NODE, od=demo_od(mode), store=store, boot=False)
    if problems is not None:
        node.on_store_problem(problems)
    node.boot()
    return node


def _all_defaults(node: canopenfd.LocalNode, mode: str) -> None:
    for var in value_entries(node.od, mode):
        assert node[(var.index, var.subindex)].raw == start_value(var), var


def _save_some(node: canopenfd.LocalNode) -> None:
    node[0x1017].raw = 50
    node[0x2006].raw = 4321
    node[0x2009].raw = "saved"
    node.save_parameters()


@MODES
def test_saved_parameters_come_back_in_a_new_network(tmp_path, bus_name, mode):
    store = str(tmp_path / "params.bin")
    with canopenfd.Network() as net:
        node = _stored_node(net, bus_name, mode, store)
        assert not os.path.exists(store)           # nothing saved by itself
        _save_some(node)
        assert os.path.getsize(store) > 0
        node[0x2006].raw = 11                      # changed after the save: not kept
    with canopenfd.Network() as net:
        frames = monitor_frames(net, bus_name, mode)
        problems = Recorder()
        node = _stored_node(net, bus_name, mode, store, problems)
        assert node[0x1017].raw == 50 and node.heartbeat_ms == 50
        assert node[0x2006].raw == 4321
        assert node[0x2009].raw == "saved"
        assert node[0x2008].raw == 1.5             # not changed, default
        booted = time.monotonic()
        frames.wait_for(lambda fs: len(heartbeats(frames, NODE, booted)) >= 3,
                        timeout=2.0, what="heartbeats at the saved period")
        assert len(problems) == 0


@MODES
def test_restore_defaults_then_reset_node_brings_the_defaults_back(tmp_path, net, bus_name,
                                                                  mode):
    node = _stored_node(net, bus_name, mode, str(tmp_path / "params.bin"))
    _save_some(node)
    node.restore_defaults()
    assert node[0x2006].raw == 4321                # only the next reset loads defaults
    wait_reset(node, "reset-node")
    assert node[0x1017].raw == 0 and node[0x2006].raw == 1000
    assert node[0x2009].raw == "canopenfd"


@MODES
def test_reset_communication_restores_only_communication_parameters(tmp_path, net, bus_name,
                                                                   mode):
    node = _stored_node(net, bus_name, mode, str(tmp_path / "params.bin"))
    _save_some(node)
    node[0x1017].raw = 99
    node[0x2006].raw = 11
    node["0x1018:1"].raw = 0x1234                  # communication, ro, not stored: default
    wait_reset(node, "reset-communication")
    assert node[0x1017].raw == 50                  # saved communication parameter
    assert node["0x1018:1"].raw == 0
    assert node[0x2006].raw == 11                  # manufacturer: untouched
    wait_reset(node, "reset-node")
    assert node[0x2006].raw == 4321


@MODES
def test_restore_defaults_of_one_group(tmp_path, net, bus_name, mode):
    node = _stored_node(net, bus_name, mode, str(tmp_path / "params.bin"))
    _save_some(node)
    node.restore_defaults("communication")
    wait_reset(node, "reset-node")
    assert node[0x1017].raw == 0                   # communication: default again
    assert node[0x2006].raw == 4321                # manufacturer: still saved
    with pytest.raises(ConfigurationError, match="group must be one of"):
        node.save_parameters("everything")


def _damaged_boot(tmp_path, net: canopenfd.Network, bus_name: str, mode: str,
                  damage) -> tuple:
    """Save parameters in one network, damage the file, boot a node on it in `net`."""
    store = str(tmp_path / "params.bin")
    with canopenfd.Network() as first:
        _save_some(_stored_node(first, bus_name, mode, store))
    damage(store)
    problems = Recorder()
    return _stored_node(net, bus_name, mode, store, problems), problems


def _flip_middle_byte(path: str) -> None:
    with open(path, "r+b") as handle:
        data = bytearray(handle.read())
        data[len(data) // 2] ^= 0xFF
        handle.seek(0)
        handle.write(data)


@MODES
def test_damaged_store_is_reported_and_the_node_runs_on_defaults(tmp_path, net, bus_name,
                                                                  mode):
    node, problems = _damaged_boot(tmp_path, net, bus_name, mode, _flip_middle_byte)
    status, skipped = problems.wait_count(1)[0]
    assert status == "damaged" and isinstance(skipped, int)
    assert node.store_status == "damaged"
    _all_defaults(node, mode)


@MODES
def test_foreign_store_file_is_reported(tmp_path, net, bus_name, mode):
    def foreign(path: str) -> None:
        with open(path, "wb") as handle:
            handle.write(random.Random(1301).randbytes(300))
    node, problems = _damaged_boot(tmp_path, net, bus_name, mode, foreign)
    status, _skipped = problems.wait_count(1)[0]
    assert status in ("foreign", "damaged")
    assert node.store_status == status
    _all_defaults(node, mode)


def test_store_status_is_ok_after_a_good_load(tmp_path, bus_name):
    store = str(tmp_path / "params.bin")
    with canopenfd.Network() as net:
        _save_some(_stored_node(net, bus_name, "fd", store))
    with canopenfd.Network() as net:
        node = _stored_node(net, bus_name, "fd", store)
        assert node[0x2006].raw == 4321
        assert node.store_status == "ok"


def test_unwritable_store_path_fails_the_save(tmp_path, net, bus_name):
    store = str(tmp_path / "no such dir" / "params.bin")
    problems = Recorder()
    node = _stored_node(net, bus_name, "fd", store, problems)
    assert node.store_status == "empty"            # nothing to load is no problem
    with pytest.raises(AbortError) as caught:
        node.save_parameters()
    error = caught.value
    assert error.code in (0x08000020, 0x06060000)
    assert (error.index, error.subindex) == (0x1010, 1)
    assert "save_parameters('all')" in str(error) and f"0x{error.code:08X}" in str(error)
    assert not os.path.exists(os.path.dirname(store))
    assert node[0x2006].raw == 1000                # the node goes on
    assert len(problems) == 0


def test_store_without_od_is_a_configuration_error(tmp_path, net, bus_name):
    line = net.open_line(bus_name)
    with pytest.raises(ConfigurationError, match=r"store needs an object dictionary \(od="):
        line.create_local_node(NODE, store=str(tmp_path / "params.bin"))
    assert line.local_node is None


# ------------------------------------------------------------------ files
@MODES
def test_dcf_served_by_path_starts_with_its_parameter_values(net, bus_name, mode):
    node = serve(net, bus_name, mode, os.path.join(DATA, "commissioned.dcf"), node_id=9)
    assert node.od.source_format == "DCF"
    assert node[0x1000].raw == 0x000F0191                 # DefaultValue
    assert node[0x1017].raw == 250 == node.heartbeat_ms   # ParameterValue=250 (default 0)
    assert node["0x1800:2"].raw == 1                      # ParameterValue=1 (default 254)
    assert node["0x1800:1"].raw == 0x180 + 9              # $NODEID+0x180 with this node
    wait_reset(node, "reset-node")                        # and so after every reset
    assert node[0x1017].raw == 250 and node["0x1800:1"].raw == 0x189


def test_xdc_served_by_path_uses_its_actual_values(net, bus_name):
    node = serve(net, bus_name, "classic", os.path.join(DATA, "classic_node.xdc"), node_id=9)
    assert node[0x1014].raw == 0xA0                       # actualValue over $NODEID+0x80
    assert node[0x1017].raw == 500                        # actualValue, default 0
    assert node["0x1800:1"].raw == 0x180 + 9


@pytest.mark.parametrize("name, mode", [("classic_vendor.eds", "classic"),
                                        ("fd_device.xdd", "fd")])
def test_vendor_files_with_a_count_in_sub0_can_be_served(net, bus_name, name, mode):
    node = serve(net, bus_name, mode, os.path.join(DATA, name), node_id=9)
    assert node[0x1014].raw == 0x80 + 9


def test_node_id_relative_default_gets_the_node_id(net, bus_name):
    od = ObjectDictionary()
    emcy = ODVariable("COB-ID EMCY", 0x1014, 0, DataType.UNSIGNED32, "rw")
    emcy.set_default(0x80, relative_to_node_id=True, expr="$NODEID+0x80")
    od.add_object(emcy)
    od.add_object(ODVariable("Producer heartbeat time", 0x1017, 0, DataType.UNSIGNED16, "rw", 0))
    first = serve(net, bus_name, "fd", od, node_id=0x21)
    second = serve(net, bus_name, "fd", od, node_id=0x22)   # the same OD object, another id
    assert first[0x1014].raw == 0xA1 == emcy.default_for(0x21)
    assert second[0x1014].raw == 0xA2
    first[0x1014].raw = 0x1234
    wait_reset(first, "reset-communication")
    assert first[0x1014].raw == 0xA1


def test_node_id_relative_real_and_string_defaults(net, bus_name):
    """Only integers are relative in C; a REAL gets the node-id added once when
    served, a relative string is refused naming the entry (it crashed with a
    TypeError before mypy pointed at it): by set_default, and, when the flag is
    set as a plain attribute, when the node is created."""
    real = ODVariable("Offset", 0x2001, 0, DataType.REAL32, "rw")
    real.set_default(0.5, relative_to_node_id=True)
    node = serve(net, bus_name, "fd", _single(real), node_id=0x21)
    assert node[0x2001].raw == 0x21 + 0.5
    text = ODVariable("Label", 0x2002, 0, DataType.VISIBLE_STRING, "rw")
    with pytest.raises(OdValueError, match="0x2002:00 Label: .*needs a numeric type"):
        text.set_default("abc", relative_to_node_id=True)
    text.set_default("abc")
    text.relative_to_node_id = True   # behind set_default's check
    line = net.open_line(bus_name)
    with pytest.raises(ConfigurationError, match="0x2002:00 Label: .*needs a numeric type"):
        line.create_local_node(NODE, od=_single(text))
    assert line.local_node is None


# ------------------------------------------------------------------ refused ODs
def _single(var: ODVariable) -> ObjectDictionary:
    od = ObjectDictionary()
    od.add_object(var)
    return od


@pytest.mark.parametrize("case", ["default_outside_limits", "min_above_max"])
def test_od_refused_by_c_names_the_entry(net, bus_name, case):
    if case == "default_outside_limits":
        var = ODVariable("Speed", 0x2001, 0, DataType.UNSIGNED8, "rw", 50,
                         low_limit=0, high_limit=10)
        problem = "outside its limits"
    else:
        var = ODVariable("Speed", 0x2001, 0, DataType.UNSIGNED8, "rw", 5,
                         low_limit=10, high_limit=2)
        problem = "minimum above maximum"
    line = net.open_line(bus_name)
    with pytest.raises(ConfigurationError, match=f"0x2001:00: .*{problem}"):
        line.create_local_node(NODE, od=_single(var))
    assert line.local_node is None
    node = line.create_local_node(NODE, od=demo_od("fd"))   # the line is still usable
    assert node[0x2006].raw == 1000


def _array_without_sub0() -> ObjectDictionary:
    array = ODArray("No sub 0", 0x2000)
    for sub in (1, 2):
        array.add_member(ODVariable(f"Element {sub}", 0x2000, sub, DataType.UNSIGNED8, "rw", 0))
    od = ObjectDictionary()
    od.add_object(array)
    return od


def _short_array() -> ObjectDictionary:
    array = ODArray("Short array", 0x2000)
    array.add_member(ODVariable("Highest sub-index supported", 0x2000, 0, DataType.UNSIGNED8,
                                "ro", 1))
    for sub in (1, 2):
        array.add_member(ODVariable(f"Element {sub}", 0x2000, sub, DataType.UNSIGNED8, "rw", 0))
    od = ObjectDictionary()
    od.add_object(array)
    return od


def test_array_with_sub0_below_its_highest_sub_is_served(net, bus_name):
    # sub 0 may count what is in use (0x1003, PDO mappings): below the subs present
    node = net.open_line(bus_name).create_local_node(NODE, od=_short_array())
    assert node[0x2000][0].raw == 1
    assert node[0x2000][2].raw == 0


def test_record_without_sub0_is_refused(net, bus_name):
    record = ODRecord("No count", 0x2002)
    record.add_member(ODVariable("Value", 0x2002, 1, DataType.UNSIGNED8, "rw", 5))
    od = ObjectDictionary()
    od.add_object(record)
    with pytest.raises(ConfigurationError, match="refused"):
        net.open_line(bus_name).create_local_node(NODE, od=od)


def test_refusal_at_seal_names_the_entry(net, bus_name):
    with pytest.raises(ConfigurationError, match="0x2000"):
        net.open_line(bus_name).create_local_node(NODE, od=_array_without_sub0())


def test_line_is_usable_after_a_refusal_at_seal(net, bus_name):
    line = net.open_line(bus_name)
    with pytest.raises(ConfigurationError):
        line.create_local_node(NODE, od=_array_without_sub0())
    assert line.create_local_node(NODE, od=demo_od("fd"))[0x2006].raw == 1000


def test_file_path_that_cannot_be_read_raises(net, bus_name):
    line = net.open_line(bus_name)
    with pytest.raises(ConfigurationError, match="garbage.eds:[0-9]+: binary data"):
        line.create_local_node(NODE, od=os.path.join(DATA, "hostile", "garbage.eds"))
    with pytest.raises(ConfigurationError, match="od must be an ObjectDictionary"):
        line.create_local_node(NODE, od=42)
    assert line.local_node is None


def test_export_of_the_served_od_as_eds_and_dcf_with_current_values(net, bus_name, tmp_path):
    from canopenfd.od import import_od
    node = net.open_line(bus_name, mode="fd").create_local_node(NODE, od=demo_od("fd"))
    node[0x1017].raw = 345
    node["Demo record.Label"].raw = "exported"
    eds = import_od(text_file(tmp_path / "node.eds", node.export_eds()))
    assert eds[0x1017].default == demo_od("fd")[0x1017].default
    dcf_path = tmp_path / "node.dcf"
    node.export_dcf(str(dcf_path))
    dcf = import_od(str(dcf_path))
    assert dcf.node_id == NODE
    assert dcf[0x1017].value == 345
    assert dcf["Demo record.Label"].value == "exported"
    # a node built from the DCF starts with those values
    clone = net.open_line(bus_name + "-clone", mode="fd").create_local_node(NODE, od=dcf)
    assert clone[0x1017].raw == 345 and clone["Demo record.Label"].raw == "exported"


def text_file(path, text):
    path.write_text(text)
    return str(path)
