"""A device built from a CANopen FD setup file ([NODE] byte 7 = 01) run on an
fd line: it exchanges 64-byte PDOs with our own fd peer line and is read and
written by USDO; the host sees ReceivedData for every byte an RPDO or a USDO
download wrote, and the TPDO carries the host's bytes, byte for byte."""

from __future__ import annotations

import contextlib
import os
import tty

import pytest
from helpers import Recorder
from processimage_helpers import setup_text

from canopenfd import UsdoAbortError
from canopenfd.gateway.remote_access_stream import FdStream
from canopenfd.processimage.host import ProcessImage
from canopenfd.processimage.setup_file import parse_setup_text
from canopenfd.processimage.task import ProcessImageTask

NODE = 0x40
RPDO_ID, TPDO_ID = 0x200 + NODE, 0x180 + NODE
PRESET = bytes(range(0x80, 0x80 + 128))          # the image's initial content


def fd_setup_text() -> str:
    """A 128-byte image: RPDO 1 writes bytes 0..63 (0x2000:1..8, UNSIGNED64,
    read-write), TPDO 1 sends bytes 64..127 (0x2001:1..8, read-only)."""
    rwod = [f"0020{sub:02X}F0{8 * (sub - 1):02X}" for sub in range(1, 9)]
    rwod += [f"0120{sub:02X}50{64 + 8 * (sub - 1):02X}" for sub in range(1, 9)]
    return setup_text(
        # 125 kbit/s, node 40h, 128 bytes, 1 RPDO, 1 TPDO, functionality 0, FD, no heartbeat
        NODE=["044080010100010000"],
        RPDO=["0000FF", "08" + "".join(f"{i:02X}" for i in range(8))],
        TPDO=["0000" "0000" "0000" "FE", "08" + "".join(f"{i:02X}" for i in range(8, 16))],
        COD=None, RWOD=rwod + ["FFFFFFFFFF"], PIMG=[PRESET.hex().upper()])


@contextlib.contextmanager
def fd_device(net, channel):
    """(host, received, states) for the FD setup on an fd line of channel."""
    setup = parse_setup_text(fd_setup_text(), "fd.txt")
    assert setup.mode == "fd"
    task_end, host_end = os.openpty()
    tty.setraw(task_end)
    tty.setraw(host_end)
    task = ProcessImageTask(net.open_line(channel, mode="fd"), setup,
                            FdStream(task_end, "task"))
    try:
        with ProcessImage(FdStream(host_end, "host")) as host:
            received, states = Recorder(), Recorder()
            host.on_received_data(lambda offset, length: received((offset, length)))
            host.on_nmt_change(states)
            assert host.init_canopen(0, 0)
            states.wait_value(0x7F)
            yield host, received, states
    finally:
        task.close()


def exchange(net, channel, tpdo_heard):
    """The whole exchange on `channel`; tpdo_heard(data) waits for the TPDO
    carrying `data` and returns its payload as sent on the bus."""
    with fd_device(net, channel) as (host, received, states):
        peer = net.open_line(channel, mode="fd")
        remote = peer.add_node(NODE)

        # USDO: the preset bytes of a TPDO entry; a download lands in the image
        assert remote.usdo.upload((0x2001, 1)) == PRESET[64:72]
        remote.usdo.download((0x2000, 3), bytes.fromhex("0102030405060708"))
        received.wait_value((16, 8))
        assert host.read(16, 8) == bytes.fromhex("0102030405060708")

        peer.nmt.send("START", NODE)
        states.wait_value(0x05)

        # a 64-byte RPDO from the peer: one ReceivedData for the whole run
        rpdo = bytes(range(0x40, 0x80))
        start = len(received)
        peer.send_frame(RPDO_ID, rpdo)
        assert received.wait_value((0, 64), start=start) >= start
        assert host.read(0, 64) == rpdo
        assert remote.usdo.upload((0x2000, 8)) == rpdo[56:64]

        # the host writes its 64 input bytes: TPDO 1 (type FEh, sent on change)
        inputs = bytes((7 * i + 3) & 0xFF for i in range(64))        # not the preset
        assert host.write(64, inputs) == 64
        assert tpdo_heard(inputs) == inputs
        assert remote.usdo.upload((0x2001, 4)) == inputs[24:32]
        # read-only TPDO entries refuse a USDO download; the image keeps the host's bytes
        with pytest.raises(UsdoAbortError) as refused:
            remote.usdo.download((0x2001, 1), bytes(8))
        assert refused.value.code == 0x06010002 and refused.value.from_server
        assert host.read(64, 64) == inputs
        assert received.snapshot().count((0, 64)) == 1 and (64, 64) not in received.snapshot()


def test_fd_setup_device_exchanges_64_byte_pdos_and_usdo(net, bus_name):
    monitor = Recorder()
    net.open_line(bus_name, mode="fd", monitor=True).on_frame(monitor)

    def tpdo_heard(data):
        frame = monitor.wait_for(lambda frames: [f for f in frames if f.id == TPDO_ID
                                                 and bytes(f.data) == data], what="TPDO")[0]
        assert frame.fd
        return bytes(frame.data)

    exchange(net, bus_name, tpdo_heard)
