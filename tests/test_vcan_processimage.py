"""A device configured only by a seed 004 setup file on a classic vcan (the
third name in CANOPENFD_VCAN), its host on a pty: python-canopen reads its
constant entries, writes an image entry by SDO and exchanges PDOs with it;
the interface going down reaches the host as FatalError 02."""

from __future__ import annotations

import os
import subprocess
import tty
from typing import Optional

import pytest
from helpers import Recorder, scaled
from processimage_helpers import setup_text

import canopenfd
from canopenfd.gateway.remote_access_stream import FdStream
from canopenfd.processimage.host import ProcessImage
from canopenfd.processimage.setup_file import parse_setup_text
from canopenfd.processimage.task import ProcessImageTask

pytestmark = pytest.mark.vcan
canopen = pytest.importorskip("canopen")
can = pytest.importorskip("can")

NODE = 0x40


def test_setup_device_on_vcan(vcan) -> None:
    channel = vcan[2]
    peer: Optional[canopen.Network] = canopen.Network()
    peer.connect(interface="socketcan", channel=channel)
    master, slave = os.openpty()
    tty.setraw(master)
    tty.setraw(slave)
    try:
        with canopenfd.Network() as net:
            line = net.open_line(channel, mode="classic")
            task = ProcessImageTask(line, parse_setup_text(setup_text(), "dev.txt"),
                                    FdStream(master, "task"))
            with ProcessImage(FdStream(slave, "host")) as image:
                received = Recorder()
                states = Recorder()
                fatal = Recorder()
                image.on_received_data(lambda offset, length: received((offset, length)))
                image.on_nmt_change(states)
                image.on_fatal_error(fatal)
                assert image.init_canopen(0, 0)
                states.wait_value(0x7F)
                node = peer.add_node(NODE, canopen.ObjectDictionary())
                assert node.sdo.upload(0x1000, 0) == bytes.fromhex("91010F00")
                node.sdo.download(0x6200, 1, b"\x77")
                received.wait_value((2, 1))
                assert image.read(2, 1) == b"\x77"

                heard = Recorder()
                peer.subscribe(0x180 + NODE, lambda can_id, data, ts: heard(bytes(data)))
                peer.nmt.send_command(0x01)
                states.wait_value(0x05)
                assert image.write(0, b"\x5a\xa5") == 2
                heard.wait_value(b"\x5a\xa5")
                peer.send_message(0x200 + NODE, b"\x01\x02")
                received.wait_value((2, 2))
                assert image.read(2, 2) == b"\x01\x02"

                peer.disconnect()    # python-canopen's reader stops on a downed interface
                peer = None

                def ip(state: str) -> None:
                    subprocess.run(["ip", "link", "set", channel, state], check=True,
                                   timeout=scaled(30))
                ip("down")
                try:
                    fatal.wait_value(0x02, timeout=10)
                finally:
                    ip("up")
            task.close()
    finally:
        if peer is not None:
            peer.disconnect()


def test_fd_setup_device_on_fd_vcan(vcan, net) -> None:
    """The CANopen FD setup of tests/test_processimage_fd.py on a kernel fd
    line (the first name in CANOPENFD_VCAN): a raw FD socket checks the
    64-byte TPDO as the kernel carried it."""
    from test_processimage_fd import TPDO_ID, exchange
    from test_vcan_services import recv_all

    raw = can.Bus(interface="socketcan", channel=vcan[0], fd=True)
    try:
        def tpdo_heard(data: bytes) -> bytes:
            msg = recv_all(raw, TPDO_ID, 1)[0]         # the first TPDO is the host's write
            assert msg.is_fd and msg.bitrate_switch
            return bytes(msg.data)

        exchange(net, vcan[0], tpdo_heard)
    finally:
        raw.shutdown()
