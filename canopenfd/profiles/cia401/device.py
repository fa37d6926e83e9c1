"""A local CiA 401 generic I/O device bound to the application's I/O.

The application reports its input levels (`set_inputs`, `set_analog_input`)
and hears its outputs (`on_digital_outputs`, `on_analog_output`,
`on_outputs`). The C core's channel logic (canopenfd._binding.cia401)
decides: polarity and filter of inputs, whether a change fires the input's
TPDO (interrupt masks, limits, deltas), the physical level of an output
written by SDO/USDO or RPDO (polarity, filter mask) and, on a fault, which
outputs take their error value. Parameters are read from the node's object
dictionary at each change, so a master configures them with SDO writes.
"""

from __future__ import annotations

import threading
from typing import Callable, List, NamedTuple, Optional, Tuple, TypeVar

from ..._binding.cia401 import AnalogInput, AnalogOutput, DigitalInputGroup, DigitalOutputGroup
from ..._callbacks import CallbackList
from ...errors import ConfigurationError
from ...line import Line
from ...node import LocalNode, LocalValue
from ...services.nmt import NmtCommand, NmtState
from . import objects as o

DigitalCallback = Callable[[int], None]
AnalogCallback = Callable[[int, int], None]
ChannelT = TypeVar("ChannelT")


class Outputs(NamedTuple):
    """The physical outputs: digital levels (bit n-1 = output n) and the
    analogue values (channel n at position n-1)."""
    digital: int
    analog: Tuple[int, ...]


OutputsCallback = Callable[[Outputs], None]


class IoDevice:
    """A CiA 401 device on a local node (`node`); build it with
    `create_io_device`. Channels are numbered from 1 as the sub-indices;
    digital levels travel as one int, bit n-1 = channel n."""

    def __init__(self, node: LocalNode, layout: o.Layout) -> None:
        self.node = node
        self.layout = layout
        self._lock = threading.Lock()
        self._inputs = [DigitalInputGroup() for _ in range(layout.input_groups)]
        self._outputs = [DigitalOutputGroup() for _ in range(layout.output_groups)]
        self._analog_inputs = [AnalogInput() for _ in range(layout.analog_inputs)]
        self._analog_outputs = [AnalogOutput() for _ in range(layout.analog_outputs)]
        self._digital_changed = CallbackList("IoDevice digital outputs")
        self._analog_changed = CallbackList("IoDevice analogue output")
        self._outputs_changed = CallbackList("IoDevice outputs")
        for group in self._outputs:
            group.set(filter_mask=0xFF)
        node.on_object_changed(self._written)
        node.on_state_change(self._state_changed)
        node.on_reset(self._reset)

    def __repr__(self) -> str:
        layout = self.layout
        return (f"<IoDevice node {self.node.node_id}: {layout.digital_inputs} DI, "
                f"{layout.digital_outputs} DO, {layout.analog_inputs} AI, "
                f"{layout.analog_outputs} AO>")

    # ------------------------------------------------------------ inputs
    def set_inputs(self, levels: int) -> None:
        """The levels of every digital input (bit n-1 = input n): 0x6000 takes
        them after polarity and filter; TPDO1 is sent when a change passes the
        interrupt masks (in OPERATIONAL)."""
        count = self.layout.digital_inputs
        if isinstance(levels, bool) or not isinstance(levels, int) or \
                not 0 <= levels < 1 << count:
            raise ConfigurationError(f"{self!r}: set_inputs needs an int 0..0x{(1 << count) - 1:X}"
                                     f" ({count} digital inputs), got {levels!r}")
        fire = None
        with self._lock:
            for number, group in enumerate(self._inputs, start=1):
                group.set(polarity=self._int(o.INPUT_POLARITY, number),
                          filter=self._int(o.INPUT_FILTER, number),
                          interrupt_enable=bool(self._int(o.INPUT_INTERRUPT_ENABLE)),
                          any_change=self._int(o.INPUT_ANY_CHANGE, number),
                          rising=self._int(o.INPUT_RISING, number),
                          falling=self._int(o.INPUT_FALLING, number))
                triggered = group.update((levels >> (8 * (number - 1))) & 0xFF)
                self._entry(o.READ_INPUT, number).raw = group.value
                if triggered and fire is None:
                    fire = (o.READ_INPUT, number)
        # every group sits in TPDO1: one trigger sends them all once
        if fire is not None:
            self._trigger(fire)

    def set_analog_input(self, channel: int, value: int) -> None:
        """The value of analogue input `channel` (1..n, INTEGER16): 0x6401
        takes it; TPDO2 is sent when the channel's trigger selection says so."""
        ain = self._channel(self._analog_inputs, channel, "analogue input")
        if isinstance(value, bool) or not isinstance(value, int) or \
                not -0x8000 <= value <= 0x7FFF:
            raise ConfigurationError(f"{self!r}: analogue input {channel} takes an INTEGER16 "
                                     f"-32768..32767, got {value!r}")
        with self._lock:
            ain.set(trigger=self._int(o.ANALOG_TRIGGER, channel),
                    interrupt_enable=bool(self._int(o.ANALOG_INTERRUPT_ENABLE)),
                    upper_limit=self._int(o.ANALOG_UPPER, channel),
                    lower_limit=self._int(o.ANALOG_LOWER, channel),
                    delta=self._int(o.ANALOG_DELTA, channel),
                    negative_delta=self._int(o.ANALOG_NEGATIVE_DELTA, channel),
                    positive_delta=self._int(o.ANALOG_POSITIVE_DELTA, channel))
            triggered = ain.update(value)
            self._entry(o.READ_ANALOG_INPUT, channel).raw = value
        if triggered:
            self._trigger((o.READ_ANALOG_INPUT, channel))

    # ------------------------------------------------------------ outputs
    @property
    def outputs(self) -> Outputs:
        """The physical outputs now."""
        with self._lock:
            return self._snapshot()

    def on_digital_outputs(self, callback: DigitalCallback) -> DigitalCallback:
        """callback(levels) when the digital output levels changed (bit n-1 = output n)."""
        return self._digital_changed.add(callback)

    def on_analog_output(self, callback: AnalogCallback) -> AnalogCallback:
        """callback(channel, value) when analogue output `channel` changed."""
        return self._analog_changed.add(callback)

    def on_outputs(self, callback: OutputsCallback) -> OutputsCallback:
        """callback(outputs) with every physical output after any change."""
        return self._outputs_changed.add(callback)

    def fault(self) -> None:
        """A device fault or communication error (call it from e.g. a remote
        node's on_heartbeat_lost): outputs whose error mode is set take their
        error value. The node does it itself when NMT stops it."""
        with self._lock:
            digital_before, analog_before = self._snapshot()
            for number, group in enumerate(self._outputs, start=1):
                group.set(error_mode=self._int(o.OUTPUT_ERROR_MODE, number),
                          error_value=self._int(o.OUTPUT_ERROR_VALUE, number))
                group.fault()
            for channel, aout in enumerate(self._analog_outputs, start=1):
                aout.set(error_mode=bool(self._int(o.ANALOG_OUTPUT_ERROR_MODE, channel)),
                         error_value=self._int(o.ANALOG_OUTPUT_ERROR_VALUE, channel))
                aout.fault()
            after = self._snapshot()
        self._tell(digital_before, analog_before, after)

    # ------------------------------------------------------------ internals
    def _entry(self, index: int, sub: int) -> LocalValue:
        entry = self.node[(index, sub)]
        if not isinstance(entry, LocalValue):     # the OD is ours: only a bug gets here
            raise ConfigurationError(f"{self!r}: 0x{index:04X}:{sub:02X} is not an entry")
        return entry

    def _int(self, index: int, sub: int = 0) -> int:
        """An integer (or BOOLEAN) entry of the device's OD."""
        raw = self._entry(index, sub).raw
        if not isinstance(raw, int):
            raise ConfigurationError(f"{self!r}: 0x{index:04X}:{sub:02X} holds {raw!r}, "
                                     "not an integer")
        return int(raw)

    def _channel(self, channels: List[ChannelT], channel: int, what: str) -> ChannelT:
        if isinstance(channel, bool) or not isinstance(channel, int) or \
                not 1 <= channel <= len(channels):
            raise ConfigurationError(f"{self!r}: {what} channel must be 1..{len(channels)}, "
                                     f"got {channel!r}")
        return channels[channel - 1]

    def _trigger(self, key: Tuple[int, int]) -> None:
        if self.node.state == NmtState.OPERATIONAL:
            self.node.trigger_pdo(key)

    def _snapshot(self) -> Outputs:
        digital = sum(group.physical << (8 * n) for n, group in enumerate(self._outputs))
        digital &= (1 << self.layout.digital_outputs) - 1
        return Outputs(digital, tuple(aout.physical for aout in self._analog_outputs))

    def _written(self, value: LocalValue, origin: str) -> None:
        """0x6200 or 0x6411 written by SDO/USDO."""
        variable = value.variable
        if variable.index in (o.WRITE_OUTPUT, o.WRITE_ANALOG_OUTPUT) and variable.subindex:
            self._apply(variable.index, (variable.subindex,))

    def _received(self, index: int, count: int) -> Callable[[object], None]:
        """An RPDO callback: the OD already holds what it carried (the core's
        RPDO copy tells no OD observer, so this is how outputs hear it)."""
        subs = tuple(range(1, count + 1))
        return lambda pdo_map: self._apply(index, subs)

    def bind_rpdos(self) -> None:
        """Hear RPDO1/RPDO2 (the node must be booted: create_io_device does it)."""
        if self.layout.output_groups:
            self.node.rpdo[1].add_callback(self._received(o.WRITE_OUTPUT,
                                                          self.layout.output_groups))
        if self.layout.analog_outputs:
            self.node.rpdo[2].add_callback(self._received(o.WRITE_ANALOG_OUTPUT,
                                                          self.layout.analog_outputs))

    def _apply(self, index: int, subs: Tuple[int, ...]) -> None:
        """Outputs `subs` of 0x6200 or 0x6411 take the OD's values."""
        with self._lock:
            digital_before, analog_before = self._snapshot()
            for sub in subs:
                written = self._int(index, sub)
                if index == o.WRITE_OUTPUT:
                    group = self._outputs[sub - 1]
                    group.set(polarity=self._int(o.OUTPUT_POLARITY, sub),
                              filter_mask=self._int(o.OUTPUT_FILTER_MASK, sub))
                    group.write(written)
                else:
                    self._analog_outputs[sub - 1].write(written)
            after = self._snapshot()
        self._tell(digital_before, analog_before, after)

    def _reset(self, command: NmtCommand) -> None:
        """Reset node reloaded every default: 0x6000/0x6401 get the inputs back
        (the levels did not change) and the outputs follow the reloaded
        0x6200/0x6411, which the application hears."""
        if command != NmtCommand.RESET_NODE:
            return
        with self._lock:
            for number, group in enumerate(self._inputs, start=1):
                self._entry(o.READ_INPUT, number).raw = group.value
            for channel, ain in enumerate(self._analog_inputs, start=1):
                self._entry(o.READ_ANALOG_INPUT, channel).raw = ain.value
        self._apply(o.WRITE_OUTPUT, tuple(range(1, self.layout.output_groups + 1)))
        self._apply(o.WRITE_ANALOG_OUTPUT, tuple(range(1, self.layout.analog_outputs + 1)))

    def _state_changed(self, old: NmtState, new: NmtState) -> None:
        if new == NmtState.STOPPED:
            self.fault()

    def _tell(self, digital_before: int, analog_before: Tuple[int, ...], after: Outputs
              ) -> None:
        if after.digital != digital_before:
            self._digital_changed.fire(after.digital)
        for channel, (was, now) in enumerate(zip(analog_before, after.analog), start=1):
            if was != now:
                self._analog_changed.fire(channel, now)
        if after != (digital_before, analog_before):
            self._outputs_changed.fire(after)


def create_io_device(line: Line, node_id: int, *, digital_inputs: int = 16,
                     digital_outputs: int = 8, analog_inputs: int = 2, analog_outputs: int = 2,
                     heartbeat_ms: int = 0, on_outputs: Optional[OutputsCallback] = None
                     ) -> IoDevice:
    """Create and boot a CiA 401 I/O device as the line's local node: its
    object dictionary (profile objects, predefined PDOs: TPDO1 digital
    inputs, TPDO2 analogue inputs, RPDO1 digital outputs, RPDO2 analogue
    outputs), then the binding of its channels. on_outputs: callback(outputs)
    after every change of a physical output."""
    layout = o.Layout(digital_inputs, digital_outputs, analog_inputs, analog_outputs)
    o.check_layout(layout, line.mode, f"create_io_device({node_id}) on {line!r}")
    node = line.create_local_node(node_id, heartbeat_ms, od=o.io_device_od(line.mode, layout),
                                  boot=False)
    device = IoDevice(node, layout)
    if on_outputs is not None:
        device.on_outputs(on_outputs)
    node.boot()
    device.bind_rpdos()
    return device
