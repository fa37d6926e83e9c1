"""`canopenfd.connect()`: one line on a network of its own, the way
python-canopen's `network.connect(...)` opens its bus.

    line = canopenfd.connect("can0", mode="classic")                  # SocketCAN
    line = canopenfd.connect("PCAN_USBBUS1", interface="pcan", bitrate=500000,
                             mode="classic")                            # python-can
    drive = line.add_node(5, "drive.eds")
    ...
    line.disconnect()                 # or: with canopenfd.connect(...) as line:
"""

from __future__ import annotations

from typing import Any, Optional

from ._binding.hostbus import PythonCanBus
from .errors import ConfigurationError, InterfaceError
from .line import Line
from .network import Network

__all__ = ["connect"]


def connect(channel: Optional[str] = None, interface: Optional[str] = None, *,
            mode: str = "fd", brs: bool = True, **bus_options: Any) -> Line:
    """Open one CAN line on a new Network and return it; `line.disconnect()`
    (or leaving `with connect(...) as line:`) closes both.

    Without `interface`, channel is a SocketCAN interface ("can0", "vcan0") or
    "mem:NAME", served by the C runtime directly (no Python per frame). With
    `interface` ("pcan", "kvaser", "virtual", "socketcan", ...), a python-can
    Bus is made with channel, `fd` from the mode, and `bus_options` (bitrate=,
    data_bitrate=, any other keyword python-can's interface takes); it is
    shut down with the line."""
    where = f"connect(channel={channel!r}, interface={interface!r})"
    if interface is None:
        if bus_options:
            raise ConfigurationError(
                f"{where}: bus options ({', '.join(sorted(bus_options))}) need a python-can "
                "interface (interface='pcan', ...); a SocketCAN interface gets its bit rates "
                "from `ip link set can0 type can bitrate ... dbitrate ... fd on`")
        if channel is None:
            raise ConfigurationError(f"{where}: give the channel (an interface name like "
                                     "'can0', or 'mem:NAME')")
    network = Network()
    try:
        if interface is None:
            line = network.open_line(channel, mode=mode, brs=brs)
        else:
            bus = _python_can_bus(interface, channel, mode, bus_options, where)
            network.shutdown_with(bus)
            line = network.open_line(bus=bus, mode=mode, brs=brs)
    except BaseException:
        network.close()
        raise
    line.own_network = True
    return line


def _python_can_bus(interface: str, channel: Optional[str], mode: str,
                    options: "dict[str, Any]", where: str) -> PythonCanBus:
    if mode not in ("fd", "classic"):
        raise ConfigurationError(f"{where}: line mode {mode!r} unknown: expected 'fd' or "
                                 "'classic'")
    import can

    kwargs = dict(options)
    if channel is not None:
        kwargs["channel"] = channel
    try:
        return can.Bus(interface=interface, fd=(mode == "fd"), **kwargs)
    except Exception as exc:  # python-can raises many kinds for a missing or bad adapter
        raise InterfaceError(f"{where}: python-can could not open the bus: "
                             f"{type(exc).__name__}: {exc}") from exc
