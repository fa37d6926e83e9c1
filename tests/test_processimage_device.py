"""`canopenfd device --setup FILE`: a device configured by a seed 004 setup
file alone, on python-can's virtual bus, driven by a host through a Unix
socket (`ProcessImage`) while python-canopen, an independent peer, reads
its constant entries by SDO and exchanges PDOs with it."""

from __future__ import annotations

import os
import pathlib
import threading
import time

import pytest
from helpers import Recorder, scaled
from processimage_helpers import setup_text

from canopenfd.gateway.remote_access_stream import FdStream
from canopenfd.processimage.host import ProcessImage

canopen = pytest.importorskip("canopen")

NODE = 0x40


def _wait_for(predicate, what: str, timeout: float = 5.0) -> None:
    deadline = time.monotonic() + scaled(timeout)
    while not predicate():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.02)


def _connect_unix(path: str) -> FdStream:
    import socket
    _wait_for(lambda: os.path.exists(path), f"the host link {path}")
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    sock.connect(path)
    return FdStream(sock.fileno(), "host", owner=sock)


def _peer_node(network):
    """python-canopen's view of node 0x40: the PDO and image objects."""
    from canopen.objectdictionary import (UNSIGNED8, UNSIGNED32, ODRecord, ODVariable,
                                          ObjectDictionary)
    od = ObjectDictionary()
    device_type = ODVariable("Device type", 0x1000, 0)
    device_type.data_type = UNSIGNED32
    od.add_object(device_type)
    for index in (0x6000, 0x6200):
        record = ODRecord(f"Image {index:04X}", index)
        for sub in (0, 1, 2):
            var = ODVariable(f"sub{sub}", index, sub)
            var.data_type = UNSIGNED8
            var.access_type = "rw"
            record.add_member(var)
        od.add_object(record)
    return network.add_node(NODE, od)


def test_setup_device_exchanges_pdos_with_python_canopen(tmp_path: pathlib.Path) -> None:
    from canopenfd.cli import main

    setup = tmp_path / "dev.txt"
    setup.write_text(setup_text())
    socket_path = str(tmp_path / "host.sock")
    channel = f"pimg-{os.getpid()}"
    peer = canopen.Network()
    peer.connect(interface="virtual", channel=channel, receive_own_messages=False)
    result = []
    device = threading.Thread(target=lambda: result.append(main([
        "device", "--setup", str(setup), "--channel", channel, "--interface", "virtual",
        "--host-link", f"unix:{socket_path}", "--duration", str(scaled(8))])))
    device.start()
    try:
        with ProcessImage(_connect_unix(socket_path)) as image:
            assert image.get_status() == 0x01          # waiting for InitCANopen
            assert image.init_canopen(0, 0)
            node = _peer_node(peer)
            assert node.sdo.upload(0x1000, 0) == bytes.fromhex("91010F00")   # [COD]
            node.sdo.download(0x6200, 2, b"\x42")
            received = Recorder()
            image.on_received_data(lambda offset, length: received((offset, length)))
            received.wait_value((3, 1))                  # the SDO write, ReceivedData
            assert image.read(3, 1) == b"\x42"

            heard = Recorder()
            peer.subscribe(0x180 + NODE, lambda can_id, data, ts: heard(bytes(data)))
            peer.nmt.send_command(0x01)                  # start all
            _wait_for(lambda: image.get_status() & 3 == 2, "operating")
            time.sleep(scaled(0.2))
            assert image.write(0, b"\x0a\x0b") == 2      # the host's inputs...
            heard.wait_value(b"\x0a\x0b")                # ...go out in TPDO 1
            peer.send_message(0x200 + NODE, b"\xc1\xc2")  # RPDO 1 from python-canopen
            received.wait_value((2, 2))
            assert image.read(2, 2) == b"\xc1\xc2"
    finally:
        device.join(timeout=scaled(15))
        peer.disconnect()
    assert result == [0]
    assert not os.path.exists(socket_path)


def test_setup_device_without_host_runs_at_once(tmp_path: pathlib.Path, capsys) -> None:
    from canopenfd.cli import main

    setup = tmp_path / "dev.txt"
    setup.write_text(setup_text())
    assert main(["device", "--setup", str(setup), "--channel", "mem:pimg-cli",
                 "--duration", "0.2"]) == 0
    err = capsys.readouterr().err
    assert f"node 64 running on mem:pimg-cli (classic) from {setup}" in err
    assert "image size 8 is not one GetStatus can report" in err     # the file's warning


def test_setup_device_usage_errors(tmp_path: pathlib.Path, capsys) -> None:
    from canopenfd.cli import main

    broken = tmp_path / "broken.txt"
    broken.write_text(setup_text(PIMG=["0011"]))
    assert main(["device", "--setup", str(broken), "--channel", "mem:pimg-bad"]) == 2
    assert f"{broken}:" in capsys.readouterr().err
    good = tmp_path / "good.txt"
    good.write_text(setup_text())
    assert main(["device", "--setup", str(good), "--node-id", "5",
                 "--channel", "mem:pimg-bad"]) == 2
    assert "--node-id cannot be combined with it" in capsys.readouterr().err
    assert main(["device", "--host-link", "pty", "--node-id", "5",
                 "--channel", "mem:pimg-bad"]) == 2
    assert "--host-link serves a process image: it needs --setup" in capsys.readouterr().err
    fd_text = setup_text(NODE=["04400801010001"])
    fd = tmp_path / "fd.txt"
    fd.write_text(fd_text)
    assert main(["device", "--setup", str(fd), "--classic", "--channel", "mem:pimg-bad"]) == 2
    assert "describes a CANopen FD device" in capsys.readouterr().err
