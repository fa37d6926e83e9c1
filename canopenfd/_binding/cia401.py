"""The C core's CiA 401 channel logic (csrc/core/co_cia401.c) for Python.

Each class owns one C struct: the profile module copies the channel's
parameters from the object dictionary into it (`set`) and asks it what goes
into the OD, whether a TPDO fires and which level goes to an output. The
structs are private to their owner, so no lock is needed.
"""

from __future__ import annotations

from .core import ffi, lib

#: 0x1000 of a CiA 401 device: the profile number and one bit per I/O kind.
PROFILE = int(lib.CO_CIA401_PROFILE)
HAS_DIGITAL_INPUTS = int(lib.CO_CIA401_HAS_DIGITAL_INPUTS)
HAS_DIGITAL_OUTPUTS = int(lib.CO_CIA401_HAS_DIGITAL_OUTPUTS)
HAS_ANALOG_INPUTS = int(lib.CO_CIA401_HAS_ANALOG_INPUTS)
HAS_ANALOG_OUTPUTS = int(lib.CO_CIA401_HAS_ANALOG_OUTPUTS)
#: 0x6421 default: upper limit, lower limit, delta.
DEFAULT_TRIGGER = int(lib.CO_CIA401_AI_DEFAULT_TRIGGER)


class _Channel:
    """A C struct of co_cia401.h; `set(name=value, ...)` copies parameters in."""

    _TYPE = ""

    def __init__(self) -> None:
        self._c = ffi.new(self._TYPE)

    def set(self, **parameters: int) -> None:
        for name, value in parameters.items():
            setattr(self._c, name, value)


class _Input(_Channel):
    """An input: `update` stores a new value and says whether its TPDO fires."""

    _UPDATE = ""

    @property
    def value(self) -> int:
        """What the input's OD entry (0x6000 / 0x6401) holds."""
        return int(self._c.value)

    def update(self, value: int) -> bool:
        return bool(getattr(lib, self._UPDATE)(self._c, value))


class _Output(_Channel):
    """An output: `write` (0x6200 / 0x6411 written) and `fault` give the
    physical level."""

    _WRITE = ""
    _FAULT = ""

    @property
    def physical(self) -> int:
        return int(self._c.physical)

    def write(self, value: int) -> int:
        return int(getattr(lib, self._WRITE)(self._c, value))

    def fault(self) -> int:
        return int(getattr(lib, self._FAULT)(self._c))


class DigitalInputGroup(_Input):
    """8 digital inputs: 0x6000 sub n with 0x6002/0x6003/0x6005..0x6008."""

    _TYPE = "co_cia401_din_t *"
    _UPDATE = "co_cia401_din_update"


class DigitalOutputGroup(_Output):
    """8 digital outputs: 0x6200 sub n with 0x6202/0x6206/0x6207/0x6208."""

    _TYPE = "co_cia401_dout_t *"
    _WRITE = "co_cia401_dout_write"
    _FAULT = "co_cia401_dout_fault"


class AnalogInput(_Input):
    """One 16-bit analogue input: 0x6401 sub n with 0x6421/0x6423..0x6428."""

    _TYPE = "co_cia401_ain_t *"
    _UPDATE = "co_cia401_ain_update"

    def reset(self, value: int) -> None:
        """Value and delta reference set without a trigger."""
        lib.co_cia401_ain_reset(self._c, value)


class AnalogOutput(_Output):
    """One 16-bit analogue output: 0x6411 sub n with 0x6443/0x6444."""

    _TYPE = "co_cia401_aout_t *"
    _WRITE = "co_cia401_aout_write"
    _FAULT = "co_cia401_aout_fault"
