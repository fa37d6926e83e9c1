"""The object dictionary of a CiA 401 generic I/O device, built in code.

Communication objects (0x1000 with the profile and I/O functionality, 0x1001,
0x1017, 0x1018), the predefined PDOs (TPDO1 digital inputs, TPDO2 analogue
inputs, RPDO1 digital outputs, RPDO2 analogue outputs: CiA 301 default
COB-IDs, valid, event-driven type 255) and the profile objects of each I/O
kind the device has. Sources: docs/protocol-notes.md, section "CiA 401".
"""

from __future__ import annotations

from typing import Iterable, NamedTuple, Tuple

from ..._binding import cia401 as c
from ...errors import ConfigurationError
from ...od import DataType, ODArray, ODRecord, ODVariable, ObjectDictionary

U8, U16, U32 = DataType.UNSIGNED8, DataType.UNSIGNED16, DataType.UNSIGNED32
I16, I32, BOOL = DataType.INTEGER16, DataType.INTEGER32, DataType.BOOLEAN

READ_INPUT, INPUT_POLARITY, INPUT_FILTER = 0x6000, 0x6002, 0x6003
INPUT_INTERRUPT_ENABLE, INPUT_ANY_CHANGE, INPUT_RISING, INPUT_FALLING = (0x6005, 0x6006,
                                                                         0x6007, 0x6008)
WRITE_OUTPUT, OUTPUT_POLARITY, OUTPUT_ERROR_MODE, OUTPUT_ERROR_VALUE, OUTPUT_FILTER_MASK = (
    0x6200, 0x6202, 0x6206, 0x6207, 0x6208)
READ_ANALOG_INPUT, WRITE_ANALOG_OUTPUT = 0x6401, 0x6411
ANALOG_TRIGGER, ANALOG_INTERRUPT_ENABLE = 0x6421, 0x6423
ANALOG_UPPER, ANALOG_LOWER, ANALOG_DELTA, ANALOG_NEGATIVE_DELTA, ANALOG_POSITIVE_DELTA = (
    0x6424, 0x6425, 0x6426, 0x6427, 0x6428)
ANALOG_OUTPUT_ERROR_MODE, ANALOG_OUTPUT_ERROR_VALUE = 0x6443, 0x6444

#: One PDO's payload: what bounds the channels each kind's PDO carries.
PAYLOAD = {"classic": 8, "fd": 64}


class Layout(NamedTuple):
    """How many channels of each kind a device has."""
    digital_inputs: int
    digital_outputs: int
    analog_inputs: int
    analog_outputs: int

    @property
    def input_groups(self) -> int:
        return (self.digital_inputs + 7) // 8

    @property
    def output_groups(self) -> int:
        return (self.digital_outputs + 7) // 8


def check_layout(layout: Layout, mode: str, where: str) -> None:
    """Each kind fits its one predefined PDO (8 or 64 bytes)."""
    payload = PAYLOAD[mode]
    limits = (("digital_inputs", payload * 8), ("digital_outputs", payload * 8),
              ("analog_inputs", payload // 2), ("analog_outputs", payload // 2))
    for (name, limit), count in zip(limits, layout):
        if isinstance(count, bool) or not isinstance(count, int) or not 0 <= count <= limit:
            raise ConfigurationError(
                f"{where}: {name} must be an int 0..{limit} (one {mode} PDO of {payload} "
                f"bytes carries them), got {count!r}")
    if not any(layout):
        raise ConfigurationError(f"{where}: a CiA 401 device needs at least one channel")


def device_type(layout: Layout) -> int:
    """0x1000: profile 401 and one bit per I/O kind present."""
    bits = (c.HAS_DIGITAL_INPUTS, c.HAS_DIGITAL_OUTPUTS, c.HAS_ANALOG_INPUTS,
            c.HAS_ANALOG_OUTPUTS)
    return c.PROFILE | sum(bit for bit, count in zip(bits, layout) if count)


def _array(od: ObjectDictionary, index: int, name: str, dtype: DataType, access: str,
           count: int, default: object, mappable: bool = False) -> None:
    array = ODArray(name, index)
    array.add_member(ODVariable("Highest sub-index supported", index, 0, U8, "ro", count))
    for sub in range(1, count + 1):
        array.add_member(ODVariable(f"{name} {sub}", index, sub, dtype, access, default,
                                    pdo_mapping=mappable))
    od.add_object(array)


def _pdo(od: ObjectDictionary, kind: str, number: int, mapped: Iterable[Tuple[int, int, int]]
         ) -> None:
    """PDO `number` of `kind` with its default COB-ID (valid), type 255 and
    the mapping (index, sub, bits) entries."""
    comm, mapping, subs = ((0x1400, 0x1600, (1, 2, 5)) if kind == "RPDO"
                           else (0x1800, 0x1A00, (1, 2, 3, 5, 6)))
    base = (0x200 if kind == "RPDO" else 0x180) + 0x100 * (number - 1)
    comm, mapping = comm + number - 1, mapping + number - 1
    record = ODRecord(f"{kind} communication parameter {number}", comm)
    record.add_member(ODVariable("Highest sub-index supported", comm, 0, U8, "ro", max(subs)))
    fields = {1: ("COB-ID used by PDO", U32), 2: ("Transmission type", U8),
              3: ("Inhibit time", U16), 5: ("Event timer", U16), 6: ("SYNC start value", U8)}
    for sub in subs:
        name, dtype = fields[sub]
        var = ODVariable(name, comm, sub, dtype, "rw", 255 if sub == 2 else 0)
        if sub == 1:
            var.set_default(base, relative_to_node_id=True)
        record.add_member(var)
    od.add_object(record)
    entries = [index << 16 | sub << 8 | bits for index, sub, bits in mapped]
    array = ODArray(f"{kind} mapping parameter {number}", mapping)
    array.add_member(ODVariable("Number of mapped objects", mapping, 0, U8, "rw",
                                len(entries)))
    for sub, entry in enumerate(entries, start=1):
        array.add_member(ODVariable(f"Mapped object {sub}", mapping, sub, U32, "rw", entry))
    od.add_object(array)


def _communication(od: ObjectDictionary, mode: str, layout: Layout) -> None:
    kind = device_type(layout)
    if mode == "fd":
        # CiA 1301: 0x1000 is an ARRAY, one device type per logical device
        _array(od, 0x1000, "Device type", U32, "ro", 1, kind)
    else:
        od.add_object(ODVariable("Device type", 0x1000, 0, U32, "ro", kind))
    od.add_object(ODVariable("Error register", 0x1001, 0, U8, "ro", 0, pdo_mapping=True))
    od.add_object(ODVariable("Producer heartbeat time", 0x1017, 0, U16, "rw", 0))
    identity = ODRecord("Identity object", 0x1018)
    identity.add_member(ODVariable("Highest sub-index supported", 0x1018, 0, U8, "ro", 4))
    for sub, what in enumerate(("Vendor-ID", "Product code", "Revision number",
                                "Serial number"), start=1):
        identity.add_member(ODVariable(what, 0x1018, sub, U32, "ro", 0))
    od.add_object(identity)


def _digital(od: ObjectDictionary, layout: Layout) -> None:
    groups = layout.input_groups
    if groups:
        _array(od, READ_INPUT, "Read input 8-bit", U8, "ro", groups, 0, mappable=True)
        for index, name, default in ((INPUT_POLARITY, "Polarity input 8-bit", 0),
                                     (INPUT_FILTER, "Filter constant input 8-bit", 0),
                                     (INPUT_ANY_CHANGE, "Interrupt mask any change 8-bit",
                                      0xFF),
                                     (INPUT_RISING, "Interrupt mask low-to-high 8-bit", 0),
                                     (INPUT_FALLING, "Interrupt mask high-to-low 8-bit", 0)):
            _array(od, index, name, U8, "rw", groups, default)
        od.add_object(ODVariable("Global interrupt enable digital 8-bit",
                                 INPUT_INTERRUPT_ENABLE, 0, BOOL, "rw", True))
        _pdo(od, "TPDO", 1, ((READ_INPUT, sub, 8) for sub in range(1, groups + 1)))
    groups = layout.output_groups
    if groups:
        _array(od, WRITE_OUTPUT, "Write output 8-bit", U8, "rw", groups, 0, mappable=True)
        for index, name, default in ((OUTPUT_POLARITY, "Change polarity output 8-bit", 0),
                                     (OUTPUT_ERROR_MODE, "Error mode output 8-bit", 0xFF),
                                     (OUTPUT_ERROR_VALUE, "Error value output 8-bit", 0),
                                     (OUTPUT_FILTER_MASK, "Filter mask output 8-bit", 0xFF)):
            _array(od, index, name, U8, "rw", groups, default)
        _pdo(od, "RPDO", 1, ((WRITE_OUTPUT, sub, 8) for sub in range(1, groups + 1)))


def _analog(od: ObjectDictionary, layout: Layout) -> None:
    count = layout.analog_inputs
    if count:
        _array(od, READ_ANALOG_INPUT, "Read analogue input 16-bit", I16, "ro", count, 0,
               mappable=True)
        _array(od, ANALOG_TRIGGER, "Analogue input interrupt trigger selection", U8, "rw",
               count, c.DEFAULT_TRIGGER)
        od.add_object(ODVariable("Analogue input global interrupt enable",
                                 ANALOG_INTERRUPT_ENABLE, 0, BOOL, "rw", False))
        for index, name, dtype in ((ANALOG_UPPER, "Analogue input interrupt upper limit", I32),
                                   (ANALOG_LOWER, "Analogue input interrupt lower limit", I32),
                                   (ANALOG_DELTA, "Analogue input interrupt delta", U32),
                                   (ANALOG_NEGATIVE_DELTA,
                                    "Analogue input interrupt negative delta", U32),
                                   (ANALOG_POSITIVE_DELTA,
                                    "Analogue input interrupt positive delta", U32)):
            _array(od, index, name, dtype, "rw", count, 0)
        _pdo(od, "TPDO", 2, ((READ_ANALOG_INPUT, sub, 16) for sub in range(1, count + 1)))
    count = layout.analog_outputs
    if count:
        _array(od, WRITE_ANALOG_OUTPUT, "Write analogue output 16-bit", I16, "rw", count, 0,
               mappable=True)
        _array(od, ANALOG_OUTPUT_ERROR_MODE, "Analogue output error mode", U8, "rw", count, 1)
        _array(od, ANALOG_OUTPUT_ERROR_VALUE, "Analogue output error value", I32, "rw",
               count, 0)
        _pdo(od, "RPDO", 2, ((WRITE_ANALOG_OUTPUT, sub, 16) for sub in range(1, count + 1)))


def io_device_od(mode: str, layout: Layout) -> ObjectDictionary:
    """The object dictionary of a CiA 401 device with `layout`'s channels."""
    od = ObjectDictionary(mode=mode)
    _communication(od, mode, layout)
    _digital(od, layout)
    _analog(od, layout)
    return od
