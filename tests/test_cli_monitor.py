"""`canopenfd monitor`: log files (--log, python-can's can.Logger) and their
offline decoding (--replay, can.LogReader), the filters (--node, --service,
--id), and that a 1 MiB USDO bulk transfer in the same process is shown
whole. Run in-process on mem: buses: the test's Network is handed to
`canopenfd.cli.main(argv, network=...)`, and an independent monitor line
(a Recorder on `on_frame`) gives the frames really on the bus."""

from __future__ import annotations

import os
import re
import threading
import time

import pytest

from canopenfd import Network
from canopenfd.cli import main
from canopenfd.cli.monitor import MONITOR_EVENT_CAPACITY
from canopenfd.od import demo_od
from helpers import Recorder, scaled

SERVER = 5
DOMAIN = 0x2100
MONITOR_S = 4.0          # how long a live monitor runs around the traffic (2 s was cut
#                          short once: a loaded machine took that long for the traffic)


def shown_lines(out):
    """The frame lines of the monitor's output without their time column."""
    return [line[10:] for line in out.splitlines() if line[10:12] in ("RX", "TX")]


def run_cli(capsys, net, *argv):
    capsys.readouterr()
    status = main(list(argv), network=net)
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    return status, out, err


def make_server(net, bus, mode):
    node = net.open_line(bus, mode=mode).create_local_node(
        SERVER, od=demo_od(mode, pdos=1), boot=False)
    node.serve_domain(DOMAIN, 1 << 16)
    node.boot()
    return node


def start_tpdo(node):
    tpdo = node.tpdo[1]
    tpdo.read()
    tpdo.clear()
    tpdo.add_variable("Demo UNSIGNED16")
    tpdo.add_variable("Demo record.Setpoint")
    tpdo.cob_id = 0x180 + SERVER
    tpdo.trans_type = 254
    tpdo.enabled = True
    tpdo.save()
    node.apply("start")
    node.wait_for_state("OPERATIONAL")
    return tpdo


def fd_traffic(net, bus, node):
    """USDO segmented and bulk downloads, an upload, a TPDO and EMCYs on an fd line."""
    client = net.open_line(bus, mode="fd")
    tpdo = start_tpdo(node)
    client.usdo.download(SERVER, DOMAIN, 0, os.urandom(1000), mode="segmented")
    client.usdo.download(SERVER, DOMAIN, 0, os.urandom(6000), mode="bulk")
    assert len(client.usdo.upload(SERVER, 0x1018, 1)) == 4
    node["Demo UNSIGNED16"].raw = 0x1234
    tpdo.transmit()
    assert node.emcy.raise_error(0x2310, b"\x01\x02", register_bits=0x80)
    assert node.emcy.clear(0x2310)


def classic_traffic(net, bus, node):
    """SDO expedited, segmented and block downloads and an upload on a classic line."""
    client = net.open_line(bus, mode="classic")
    client.sdo.download(SERVER, 0x1017, 0, b"\x10\x00")
    client.sdo.download(SERVER, DOMAIN, 0, os.urandom(300), mode="segmented")
    client.sdo.download(SERVER, DOMAIN, 0, os.urandom(3000), mode="block")
    assert client.sdo.upload(SERVER, DOMAIN) and len(client.sdo.upload(SERVER, 0x1018, 1)) == 4


def wait_for_monitor_line(net, count):
    """Until the network has count monitor lines (the CLI's is open)."""
    deadline = time.monotonic() + scaled(5)
    while sum(line.monitor for line in net.lines) < count:
        assert time.monotonic() < deadline, "the monitor did not open its line"
        time.sleep(0.01)
    time.sleep(0.05)               # its on_frame callback is registered right after


def live_monitor(capsys, net, bus, traffic, *options):
    """Run `monitor --channel bus OPTIONS` for MONITOR_S seconds around
    traffic(); (its output, the frames an independent monitor line saw)."""
    seen = Recorder()
    net.open_line(bus, mode="fd" if "--classic" not in options else "classic",
                  monitor=True).on_frame(seen)
    result = {}

    def monitor():
        result["run"] = run_cli(capsys, net, "monitor", "--channel", bus,
                                "--duration", str(scaled(MONITOR_S)), *options)

    thread = threading.Thread(target=monitor)
    thread.start()
    wait_for_monitor_line(net, 2)
    start = len(seen)             # (a boot-up still on its way belongs to neither)
    traffic()
    thread.join()
    status, out, err = result["run"]
    assert status == 0, err
    return out, err, seen.snapshot()[start:]


# ------------------------------------------------------------------ candump .log bytes
_CANDUMP = re.compile(r"^\((\d+\.\d+)\) (\S+) ([0-9A-F]+)(#|##([0-9A-F]))([0-9A-F]*)( [RT])?$")


def parse_candump(path):
    """(id, data, fd, brs, esi, extended) of every line of a candump -L file."""
    frames = []
    for number, text in enumerate(open(path).read().splitlines(), 1):
        match = _CANDUMP.match(text)
        assert match, f"{path}:{number}: not a candump line: {text!r}"
        can_id, fd = match.group(3), match.group(4).startswith("##")
        flags = int(match.group(5), 16) if fd else 0
        frames.append((int(can_id, 16), bytes.fromhex(match.group(6)), fd,
                       bool(flags & 1), bool(flags & 2), len(can_id) == 8))
    return frames


def frame_tuple(frame):
    return frame.id, frame.data, frame.fd, frame.brs, frame.esi, frame.ext


def test_fd_traffic_logged_as_candump_matches_the_bus_and_replays_the_same(
        net, bus_name, capsys, tmp_path):
    node = make_server(net, bus_name, "fd")
    log = tmp_path / "fd.log"
    out, err, seen = live_monitor(capsys, net, bus_name,
                                  lambda: fd_traffic(net, bus_name, node), "--log", str(log))
    live = shown_lines(out)
    assert len(live) == len(seen) > 120 and f"{len(seen)} frames shown, 0 lost" in err
    for needle in ("bulk segment", "download segment", "TPDO1 node 5 34 12",
                   "EMCY node 5", "[FD BRS]"):
        assert any(needle in line for line in live), needle
    # the file holds every frame of the bus, byte for byte, FD flags included
    assert parse_candump(log) == [frame_tuple(f) for f in seen]
    # replayed: the same lines (times aside)
    status, replay_out, replay_err = run_cli(capsys, None, "monitor", "--replay", str(log))
    assert status == 0 and shown_lines(replay_out) == live
    assert f"{len(seen)} frames shown" in replay_err


@pytest.mark.parametrize("suffix", [".asc", ".blf", ".log.gz"])
def test_other_log_formats_round_trip_fd_frames(net, bus_name, capsys, tmp_path, suffix):
    node = make_server(net, bus_name, "fd")
    log = tmp_path / f"fd{suffix}"
    out, _, seen = live_monitor(capsys, net, bus_name,
                                lambda: fd_traffic(net, bus_name, node), "--log", str(log))
    status, replay_out, _ = run_cli(capsys, None, "monitor", "--replay", str(log))
    assert status == 0 and shown_lines(replay_out) == shown_lines(out)
    assert len(shown_lines(out)) == len(seen)


@pytest.mark.parametrize("suffix", [".log", ".csv", ".trc"])
def test_classic_sdo_traffic_round_trips(net, bus_name, capsys, tmp_path, suffix):
    node = make_server(net, bus_name, "classic")
    log = tmp_path / f"classic{suffix}"
    out, _, seen = live_monitor(capsys, net, bus_name,
                                lambda: classic_traffic(net, bus_name, node),
                                "--classic", "--log", str(log))
    live = shown_lines(out)
    assert len(live) == len(seen) > 60
    assert any("block segment" in line for line in live)
    assert any("SDO" in line and "segment" in line for line in live)
    if suffix == ".log":
        assert parse_candump(log) == [frame_tuple(f) for f in seen]
    _, replay_out, _ = run_cli(capsys, None, "monitor", "--replay", str(log))
    assert shown_lines(replay_out) == live


# ------------------------------------------------------------------ filters
@pytest.fixture
def fd_log(net, bus_name, capsys, tmp_path):
    """(a candump log of fd_traffic, the frames on the bus)."""
    node = make_server(net, bus_name, "fd")
    log = tmp_path / "traffic.log"
    _, _, seen = live_monitor(capsys, net, bus_name,
                              lambda: fd_traffic(net, bus_name, node), "--log", str(log))
    return str(log), seen


def replay(capsys, path, *options):
    status, out, err = run_cli(capsys, None, "monitor", "--replay", path, *options)
    assert status == 0, err
    return shown_lines(out), err


def ids_of(lines):
    return [int(line.split()[1], 16) for line in lines]


def test_filters_by_id_service_and_node(fd_log, capsys):
    path, seen = fd_log
    ids = [f.id for f in seen]
    lines, err = replay(capsys, path, "--id", "0x185")
    assert ids_of(lines) == [i for i in ids if i == 0x185] and lines
    assert f"{len(seen) - len(lines)} filtered out" in err
    lines, _ = replay(capsys, path, "--id", "0x580-0x5FF", "--id", "133")   # 133 = 0x85
    assert ids_of(lines) == [i for i in ids if 0x580 <= i <= 0x5FF or i == 0x85]
    lines, _ = replay(capsys, path, "--service", "emcy")
    assert ids_of(lines) == [i for i in ids if i == 0x85] and len(lines) == 2
    lines, _ = replay(capsys, path, "--service", "pdo", "--service", "heartbeat")
    assert ids_of(lines) == [i for i in ids if i == 0x185 or 0x701 <= i <= 0x77F]
    lines, _ = replay(capsys, path, "--service", "usdo")
    assert ids_of(lines) == [i for i in ids if i in (0x585, 0x67F)]
    assert all("USDO" in line for line in lines)
    # node 5: its USDO (the client 127 talks to it), TPDO, EMCY, heartbeat, NMT
    lines, _ = replay(capsys, path, "--node", "5")
    assert len(lines) == len(seen)
    lines, _ = replay(capsys, path, "--node", "127", "--service", "usdo")
    assert ids_of(lines) == [i for i in ids if i in (0x585, 0x67F)]
    lines, _ = replay(capsys, path, "--node", "6")
    assert lines == []
    lines, _ = replay(capsys, path, "--service", "sdo")     # fd line: no classic SDO
    assert lines == []


def test_filters_apply_live(net, bus_name, capsys, tmp_path):
    node = make_server(net, bus_name, "fd")
    log = tmp_path / "emcy.log"
    out, err, seen = live_monitor(capsys, net, bus_name,
                                  lambda: fd_traffic(net, bus_name, node),
                                  "--service", "emcy", "--log", str(log))
    lines = shown_lines(out)
    assert ids_of(lines) == [0x85, 0x85] and "EMCY node 5" in lines[0]
    assert [entry[0] for entry in parse_candump(log)] == [0x85, 0x85]   # the log: shown ones
    assert f"{len(seen) - 2} filtered out" in err


@pytest.mark.parametrize("argv, words", [
    (["--service", "pdx"], ["--service", "unknown service 'pdx'", "tpdo", "usdo", "lss"]),
    (["--node", "0"], ["--node 0"]),
    (["--node", "x"], ["--node x"]),
    (["--id", "0x800-0x700"], ["--id 0x800-0x700", "ends (0x700) before it starts (0x800)"]),
    (["--id", "12g"], ["--id 12g", "not a CAN-ID"]),
    (["--id", "0x20000000"], ["outside 0..0x1FFFFFFF"]),
])
def test_bad_filters_are_one_clear_error(capsys, tmp_path, argv, words):
    path = tmp_path / "x.log"
    path.write_text("(1.000000) can0 123#01\n")
    status, out, err = run_cli(capsys, None, "monitor", "--replay", str(path), *argv)
    assert status == 2 and out == ""
    assert len(err.strip().splitlines()) == 1, err
    for word in words:
        assert word in err, err


def test_replay_and_log_errors_name_the_file(capsys, tmp_path):
    status, _, err = run_cli(capsys, None, "monitor", "--replay", str(tmp_path / "none.log"))
    assert status == 2 and "none.log: no such file" in err
    odd = tmp_path / "frames.xyz"
    odd.write_text("")
    status, _, err = run_cli(capsys, None, "monitor", "--replay", str(odd))
    assert status == 2 and "frames.xyz" in err and ".blf" in err
    broken = tmp_path / "broken.log"
    broken.write_text("(1.0) can0 123#01\nthis is no candump line\n")
    status, out, err = run_cli(capsys, None, "monitor", "--replay", str(broken))
    assert status == 2 and "broken.log" in err and "frame 2" in err, err
    status, _, err = run_cli(capsys, None, "monitor", "--replay", str(broken),
                             "--log", str(tmp_path / "out.xyz"))
    assert status == 2 and "out.xyz" in err and ".asc" in err
    status, _, err = run_cli(capsys, None, "monitor")
    assert status == 2 and "--channel" in err and "--replay" in err
    status, _, err = run_cli(capsys, None, "monitor", "--replay", str(broken),
                             "--duration", "1")
    assert status == 2 and "--duration" in err


def test_formats_without_fd_frames_are_refused_for_fd(fd_log, net, bus_name, capsys,
                                                      tmp_path):
    path, _ = fd_log
    for suffix in (".csv", ".trc"):
        status, _, err = run_cli(capsys, net, "monitor", "--channel", bus_name,
                                 "--log", str(tmp_path / f"x{suffix}"), "--duration", "0.1")
        assert status == 2 and f"x{suffix}" in err and "use .log, .asc or .blf" in err
        status, _, err = run_cli(capsys, None, "monitor", "--replay", path,
                                 "--log", str(tmp_path / f"y{suffix}"))
        assert status == 2 and "frame 1 is a CAN FD frame" in err, err


def test_replay_converts_formats_and_counts(fd_log, capsys, tmp_path):
    path, seen = fd_log
    asc = tmp_path / "copy.asc"
    status, out, err = run_cli(capsys, None, "monitor", "--replay", path, "--log", str(asc),
                               "--count", "10")
    assert status == 0 and len(shown_lines(out)) == 10 and f"10 written to {asc}" in err
    lines, _ = replay(capsys, str(asc))
    assert lines == shown_lines(out)


# ------------------------------------------------------------------ nothing lost
def frames_of(line):
    """Frames the line sent and received so far (its C counters)."""
    stats = line.stats
    return stats["rx_frames"] + stats["tx_frames"]


def test_a_1_mib_bulk_transfer_in_the_same_process_is_shown_whole(capsys, tmp_path):
    """The monitor's Network as the CLI opens it (its large event queue), the
    transfer on the same in-process bus: every frame shown, 0 lost (the
    runtime's count). Not timed."""
    data = os.urandom(1 << 20)
    with Network(MONITOR_EVENT_CAPACITY) as net:
        bus = "mem:monitor-1mib"
        node = net.open_line(bus, mode="fd").create_local_node(SERVER, od=demo_od("fd"),
                                                               boot=False)
        node.serve_domain(DOMAIN, len(data))
        node.boot()
        client = net.open_line(bus, mode="fd")
        result = {}

        def monitor():
            result["run"] = run_cli(capsys, net, "monitor", "--channel", bus,
                                    "--count", str(expected_frames()))

        def expected_frames():
            # initiate + accept, 60 bytes per segment, the last segment's response
            return 2 + (len(data) + 59) // 60 + 1

        thread = threading.Thread(target=monitor)
        thread.start()
        wait_for_monitor_line(net, 1)
        before = frames_of(client)          # (the node's boot-up may be among them)
        client.usdo.download(SERVER, DOMAIN, 0, data, mode="bulk")
        assert frames_of(client) - before == expected_frames()
        thread.join(scaled(120))
        assert not thread.is_alive(), "the monitor did not show every frame"
        status, out, err = result["run"]
    lines = shown_lines(out)
    assert status == 0 and len(lines) == expected_frames()
    assert f"{expected_frames()} frames shown, 0 lost" in err
    assert sum("bulk segment" in line for line in lines) == (len(data) + 59) // 60 - 1


def test_frames_lost_are_counted_by_the_runtime_and_reported(capsys):
    """A queue too small for the burst: the monitor says how many frames it
    lost (the runtime's count), in its output and at the end."""
    with Network(event_capacity=64) as net:
        bus = "mem:monitor-lossy"
        node = net.open_line(bus, mode="fd").create_local_node(SERVER, od=demo_od("fd"),
                                                               boot=False)
        node.serve_domain(DOMAIN, 1 << 18)
        node.boot()
        client = net.open_line(bus, mode="fd")
        result = {}
        thread = threading.Thread(target=lambda: result.update(run=run_cli(
            capsys, net, "monitor", "--channel", bus, "--duration", str(scaled(MONITOR_S)))))
        thread.start()
        wait_for_monitor_line(net, 1)
        before = frames_of(client)
        client.usdo.download(SERVER, DOMAIN, 0, os.urandom(1 << 18), mode="bulk")
        on_bus = frames_of(client) - before
        thread.join()
        monitor_line = next(line for line in net.lines if line.monitor)
        lost = monitor_line.stats["events_lost"]
    status, out, err = result["run"]
    shown = len([line for line in shown_lines(out) if " USDO " in line])
    assert status == 0 and lost > 0 and shown + lost == on_bus
    assert f"{len(shown_lines(out))} frames shown, {lost} lost (the monitor fell behind" in err
    reported = [int(m) for m in re.findall(r"--  \d+ frames lost: .*; (\d+) lost so far", out)]
    assert reported and reported[-1] == lost


# ------------------------------------------------------------------ the README's commands
def readme_monitor_commands():
    text = open(os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                             "README.md"), encoding="utf-8").read()
    section = text[text.index("### Monitor, filters and log files"):]
    block = re.search(r"^```sh\n(.*?)^```", section, re.S | re.M).group(1)
    return [line.split()[1:] for line in block.splitlines() if line.startswith("canopenfd ")]


def drive_eds(path):
    """node 5's EDS with TPDO1 as start_tpdo() maps it."""
    from canopenfd.od import export_eds

    od = demo_od("fd", pdos=1)
    od[0x1800][1].set_default(0x180, relative_to_node_id=True)
    entries = [od["Demo UNSIGNED16"], od["Demo record.Setpoint"]]
    for sub, entry in enumerate(entries, 1):
        od[0x1A00][sub].set_default(entry.index << 16 | entry.subindex << 8
                                    | entry.data_type.size * 8)
    od[0x1A00][0].set_default(len(entries))
    export_eds(od, str(path))


def test_the_readme_monitor_commands_run(net, bus_name, capsys, tmp_path, monkeypatch):
    """The README's three lines: the live one on a mem: bus instead of can0
    (in-process, it must share the traffic's Network), the offline ones as
    the `canopenfd` command in a subprocess."""
    import subprocess

    from helpers import cli_command, package_env

    def run_command(*argv, cwd):
        return subprocess.run(cli_command(*argv), capture_output=True, text=True, cwd=cwd,
                              env=package_env(), timeout=scaled(60), check=False)

    live, replay_pdos, convert = readme_monitor_commands()
    assert live[:3] == ["monitor", "--channel", "can0"] and replay_pdos[:2] == ["monitor",
                                                                                "--replay"]
    monkeypatch.chdir(tmp_path)
    node = make_server(net, bus_name, "fd")
    out, err, seen = live_monitor(capsys, net, bus_name, lambda: fd_traffic(net, bus_name, node),
                                  *live[3:])
    assert len(shown_lines(out)) == len(seen) and (tmp_path / "node5.log").exists()
    drive_eds(tmp_path / "drive.eds")
    result = run_command(*replay_pdos, cwd=str(tmp_path))
    assert result.returncode == 0, result.stderr
    lines = shown_lines(result.stdout)
    assert ids_of(lines) == [f.id for f in seen if f.id in (0x185, 0x85)]
    assert "TPDO1 node 5 Demo UNSIGNED16=4660" in lines[0].replace("  ", " "), lines
    result = run_command(*convert, cwd=str(tmp_path))
    assert result.returncode == 0, result.stderr
    assert ids_of(shown_lines(result.stdout)) == [f.id for f in seen if 0x580 <= f.id <= 0x5FF]
    assert (tmp_path / "node5.asc").stat().st_size > 0
