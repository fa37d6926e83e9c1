"""CiA 401 generic I/O device profile: a local device bound to the
application's digital and analogue inputs and outputs (see `create_io_device`)."""

from .device import IoDevice, Outputs, create_io_device
from .objects import Layout, device_type, io_device_od

__all__ = ["IoDevice", "Outputs", "create_io_device", "Layout", "device_type", "io_device_od"]
