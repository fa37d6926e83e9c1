"""The python-can bus options of every command that opens a line (--bitrate,
--data-bitrate, --bus-option KEY=VALUE): the can.Bus keyword arguments they
assemble, their errors, and a real python-can `virtual` bus opened with them
(python-can's VirtualBus takes any further keyword arguments)."""

from __future__ import annotations

import os
import threading
import time

import pytest

from canopenfd.cli import build_parser, main
from canopenfd.cli.common import UsageError, bus_kwargs, bus_option_value
from helpers import scaled

can = pytest.importorskip("can")

#: every command with the line options, and the arguments it needs besides them
COMMANDS = {
    "monitor": [], "device": ["--node-id", "5"], "nmt": ["start", "5"],
    "read": ["5", "0x1017"], "write": ["5", "0x1017", "1"],
    "download": ["5", "0x2100", "f.bin"], "upload": ["5", "0x2100", "f.bin"],
}


def parse(command, *options):
    return build_parser().parse_args([command, *COMMANDS[command], "--channel", "c0",
                                      *options])


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_every_line_command_takes_the_bus_options(command):
    args = parse(command, "--interface", "pcan", "--bitrate", "500000", "--data-bitrate",
                 "2000000", "--bus-option", "f_clock_mhz=80", "--bus-option", "state=passive")
    assert bus_kwargs(args) == {"interface": "pcan", "channel": "c0", "fd": True,
                                "bitrate": 500000, "data_bitrate": 2000000,
                                "f_clock_mhz": 80, "state": "passive"}


def test_the_demo_opens_no_line_of_a_user_and_has_no_bus_options():
    actions = build_parser()._subparsers._group_actions[0].choices["demo"]._actions
    assert not any("--bitrate" in action.option_strings for action in actions)


@pytest.mark.parametrize("text, value", [
    ("80", 80), ("0x1F", 0x1F), ("-3", -3), ("010", 10), ("2.5", 2.5), ("1e6", 1e6),
    ("true", True), ("False", False), ("passive", "passive"), ("", ""), ("PCAN_USBBUS1",
                                                                           "PCAN_USBBUS1"),
])
def test_bus_option_values_are_typed_when_they_read_as_a_type(text, value):
    got = bus_option_value(text)
    assert got == value and type(got) is type(value)


def test_classic_lines_pass_fd_false_and_no_data_bitrate():
    args = parse("nmt", "--interface", "kvaser", "--classic", "--bitrate", "250000")
    assert bus_kwargs(args) == {"interface": "kvaser", "channel": "c0", "fd": False,
                                "bitrate": 250000}
    with pytest.raises(UsageError, match="--data-bitrate.*--classic"):
        bus_kwargs(parse("nmt", "--interface", "kvaser", "--classic",
                         "--data-bitrate", "2000000"))


@pytest.mark.parametrize("option, words", [
    ("novalue", ["'novalue'", "KEY=VALUE"]),
    ("=5", ["KEY=VALUE"]),
    ("bad key=1", ["KEY=VALUE"]),
    ("bitrate=5", ["bitrate is set by --bitrate"]),
    ("fd=false", ["fd is set by --classic"]),
    ("channel=x", ["channel is set by --channel"]),
])
def test_bad_bus_options_are_one_clear_error(option, words, capsys):
    assert main(["nmt", "start", "5", "--channel", "c0", "--interface", "virtual",
                 "--bus-option", option]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    for word in words:
        assert word in err, err


def test_a_bus_option_given_twice_is_refused():
    with pytest.raises(UsageError, match="--bus-option a given twice"):
        bus_kwargs(parse("nmt", "--interface", "virtual", "--bus-option", "a=1",
                         "--bus-option", "a=2"))


def test_bus_options_need_an_interface(capsys):
    for extra in (["--bitrate", "500000"], ["--data-bitrate", "2000000"],
                  ["--bus-option", "a=1"], ["--bitrate", "0"]):
        assert main(["nmt", "start", "5", "--channel", "mem:x", *extra]) == 2
        err = capsys.readouterr().err
        assert extra[0] in err and "need --interface" in err, err


def test_mem_channel_help_says_in_process_only():
    for command in COMMANDS:
        parser = build_parser()._subparsers._group_actions[0].choices[command]
        channel = next(a for a in parser._actions if "--channel" in a.option_strings)
        assert "shared only by the lines of one process" in channel.help


def test_a_real_virtual_bus_gets_the_options(monkeypatch):
    """The assembled arguments reach can.Bus: a python-can virtual bus opened
    with receive_own_messages=true hears its own NMT frame."""
    opened = []
    real_bus = can.Bus

    def spy(**kwargs):
        bus = real_bus(**kwargs)
        opened.append((kwargs, bus))
        return bus

    monkeypatch.setattr(can, "Bus", spy)
    channel = f"bus-options-{os.getpid()}"
    listener = real_bus(interface="virtual", channel=channel)
    try:
        assert main(["nmt", "start", "5", "--channel", channel, "--interface", "virtual",
                     "--bitrate", "1000000", "--data-bitrate", "5000000",
                     "--bus-option", "receive_own_messages=true",
                     "--bus-option", "rx_queue_size=0x100"]) == 0
        kwargs, bus = opened[0]
        assert kwargs == {"interface": "virtual", "channel": channel, "fd": True,
                          "bitrate": 1000000, "data_bitrate": 5000000,
                          "receive_own_messages": True, "rx_queue_size": 256}
        assert bus.receive_own_messages is True
        message = listener.recv(scaled(2))
        assert message is not None and message.arbitration_id == 0
        assert bytes(message.data) == bytes([1, 5])            # NMT start node 5
    finally:
        listener.shutdown()


def test_monitor_on_a_virtual_bus_with_bus_options_logs_the_frames(tmp_path, capsys):
    channel = f"monitor-virtual-{os.getpid()}"
    log = tmp_path / "virtual.log"
    sender = can.Bus(interface="virtual", channel=channel)
    result = {}
    thread = threading.Thread(target=lambda: result.update(status=main([
        "monitor", "--channel", channel, "--interface", "virtual", "--classic",
        "--bitrate", "500000", "--bus-option", "preserve_timestamps=false",
        "--log", str(log), "--count", "2", "--duration", str(scaled(5))])))
    thread.start()
    try:
        time.sleep(scaled(0.5))
        sender.send(can.Message(arbitration_id=0x000, data=[0x01, 0x05], is_extended_id=False))
        sender.send(can.Message(arbitration_id=0x705, data=[0x05], is_extended_id=False))
        thread.join(scaled(10))
    finally:
        sender.shutdown()
    assert result["status"] == 0
    out = capsys.readouterr().out
    assert "NMT start node 5" in out and "heartbeat node 5 OPERATIONAL" in out
    lines = log.read_text().splitlines()
    # candump -L: "(time) channel ID#DATA R" (R: received by the monitor)
    assert [line.split()[2:] for line in lines] == [["000#0105", "R"], ["705#05", "R"]], lines
