"""canopenfd.connect(): one line on a network of its own, python-canopen's
network.connect() way, over SocketCAN names / mem: or a python-can interface."""

from __future__ import annotations

import itertools
import os

import pytest

import canopenfd
from canopenfd import ClosedError, ConfigurationError, InterfaceError
from canopenfd.od import demo_od

can = pytest.importorskip("can")
_channels = itertools.count(1)


def _channel() -> str:
    return f"connect-{os.getpid()}-{next(_channels)}"


def test_python_can_interface_line_serves_and_closes_its_bus():
    channel = _channel()
    with canopenfd.connect(channel, interface="virtual", mode="classic") as master:
        assert master.own_network and master.mode == "classic"
        device_line = canopenfd.connect(channel, interface="virtual", mode="classic")
        device_line.create_local_node(5, od=demo_od("classic"))
        device_line.local_node[0x1017].raw = 250
        drive = master.add_node(5, demo_od("classic"))
        assert drive.sdo["Producer heartbeat time"].raw == 250
        device_line.disconnect()
        device_line.disconnect()                       # idempotent
        assert device_line.network.closed
    assert master.network.closed
    with pytest.raises(ClosedError):
        master.add_node(6)


def test_python_can_bus_is_shut_down_with_the_line(monkeypatch):
    made = []
    real_bus = can.Bus

    def recording_bus(*args, **kwargs):
        bus = real_bus(*args, **kwargs)
        made.append((bus, kwargs))
        return bus

    monkeypatch.setattr(can, "Bus", recording_bus)
    line = canopenfd.connect(_channel(), interface="virtual", mode="fd",
                             receive_own_messages=False)
    (bus, kwargs), = made
    assert kwargs["fd"] is True and kwargs["receive_own_messages"] is False
    line.disconnect()
    assert bus._is_shutdown                            # python-can's own flag


def test_socketcan_names_and_mem_need_no_interface():
    with canopenfd.connect("mem:" + _channel()) as line:
        assert line.mode == "fd" and line.own_network
        line.create_local_node(1)
        assert line.local_node.state == "PRE-OPERATIONAL"


def test_wrong_use_names_the_problem():
    with pytest.raises(ConfigurationError, match="bitrate.*python-can interface"):
        canopenfd.connect("can0", bitrate=500000)
    with pytest.raises(ConfigurationError, match="give the channel"):
        canopenfd.connect()
    with pytest.raises(InterfaceError, match="interface='no-such-interface'"):
        canopenfd.connect("x", interface="no-such-interface")
    with pytest.raises(ConfigurationError, match="mode 'fast'"):
        canopenfd.connect("x", interface="virtual", mode="fast")
    with canopenfd.Network() as net:
        line = net.open_line("mem:" + _channel())
        with pytest.raises(ConfigurationError, match="close that network"):
            line.disconnect()
        with pytest.raises(ConfigurationError, match="canopenfd.connect"):
            with line:
                pass
        assert not net.closed
