"""The C core's CiA 401 constants (csrc/core/co_cia401.h) for Python.

The device itself runs in the core (co_cia401_od, driven through
`node.generic_io`); the profile module needs only its numbers.
"""

from __future__ import annotations

from .core import lib

#: 0x1000 of a CiA 401 device: the profile number and one bit per I/O kind.
PROFILE = int(lib.CO_CIA401_PROFILE)
HAS_DIGITAL_INPUTS = int(lib.CO_CIA401_HAS_DIGITAL_INPUTS)
HAS_DIGITAL_OUTPUTS = int(lib.CO_CIA401_HAS_DIGITAL_OUTPUTS)
HAS_ANALOG_INPUTS = int(lib.CO_CIA401_HAS_ANALOG_INPUTS)
HAS_ANALOG_OUTPUTS = int(lib.CO_CIA401_HAS_ANALOG_OUTPUTS)
#: 0x6421 default: upper limit, lower limit, delta.
DEFAULT_TRIGGER = int(lib.CO_CIA401_AI_DEFAULT_TRIGGER)

