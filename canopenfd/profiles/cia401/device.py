"""A local CiA 401 generic I/O device bound to the application's I/O.

The application reports its input levels (`set_inputs`, `set_analog_input`)
and hears its outputs (`on_digital_outputs`, `on_analog_output`,
`on_outputs`). The device itself runs in the C core (co_cia401_od, started
through `node.generic_io`): it keeps the channels' parameters equal to the
node's object dictionary (a master configures them with SDO/USDO writes),
applies polarity and filter to the inputs, writes 0x6000/0x6401 and sends
the inputs' TPDO when a change passes the interrupt masks, limits or deltas,
moves the physical outputs on every write of 0x6200/0x6411 (SDO, USDO, RPDO)
and applies the error values on NMT stop or a fault. This class checks the
application's arguments and turns the core's output changes into callbacks.
"""

from __future__ import annotations

import threading
from typing import Callable, List, NamedTuple, Optional, Tuple

from ..._callbacks import CallbackList
from ...errors import ConfigurationError
from ...line import Line
from ...node import LocalNode
from ...services.generic_io import OutputChange
from . import objects as o

DigitalCallback = Callable[[int], None]
AnalogCallback = Callable[[int, int], None]


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
        # what the callbacks last told: the core's changes arrive per kind
        self._digital_groups: List[int] = [0] * layout.output_groups
        self._analog: Tuple[int, ...] = (0,) * layout.analog_outputs
        self._digital_changed = CallbackList("IoDevice digital outputs")
        self._analog_changed = CallbackList("IoDevice analogue output")
        self._outputs_changed = CallbackList("IoDevice outputs")
        node.generic_io.on_change(self._changed)

    def __repr__(self) -> str:
        layout = self.layout
        return (f"<IoDevice node {self.node.node_id}: {layout.digital_inputs} DI, "
                f"{layout.digital_outputs} DO, {layout.analog_inputs} AI, "
                f"{layout.analog_outputs} AO>")

    def start(self) -> None:
        """Run the core's device over the booted node (create_io_device does
        it): from then on it hears SDO/USDO writes and every RPDO mapping the
        outputs, and the inputs can be set."""
        self.node.generic_io.start()

    def bind_rpdos(self) -> None:
        """The name start() had when only RPDO1/RPDO2 needed binding; kept
        for callers that build an IoDevice themselves."""
        self.start()

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
        self.node.generic_io.set_inputs(1, levels.to_bytes(self.layout.input_groups, "little"))

    def set_analog_input(self, channel: int, value: int) -> None:
        """The value of analogue input `channel` (1..n, INTEGER16): 0x6401
        takes it; TPDO2 is sent when the channel's trigger selection says so."""
        count = self.layout.analog_inputs
        if isinstance(channel, bool) or not isinstance(channel, int) or \
                not 1 <= channel <= count:
            raise ConfigurationError(f"{self!r}: analogue input channel must be 1..{count}, "
                                     f"got {channel!r}")
        if isinstance(value, bool) or not isinstance(value, int) or \
                not -0x8000 <= value <= 0x7FFF:
            raise ConfigurationError(f"{self!r}: analogue input {channel} takes an INTEGER16 "
                                     f"-32768..32767, got {value!r}")
        self.node.generic_io.set_analog_input(channel, value)

    # ------------------------------------------------------------ outputs
    @property
    def outputs(self) -> Outputs:
        """The physical outputs now."""
        groups, analog = self.node.generic_io.outputs(self.layout.output_groups,
                                                      self.layout.analog_outputs)
        return Outputs(int.from_bytes(groups, "little"), analog)

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
        self.node.generic_io.fault()

    # ------------------------------------------------------------ internals
    def _changed(self, change: OutputChange) -> None:
        """The core moved outputs of one kind: tell what differs from before."""
        with self._lock:
            if change.kind == "digital":
                before = list(self._digital_groups)
                self._digital_groups = list(change.levels)
                digital = self._digital_groups != before
                analog_moved: List[Tuple[int, int]] = []
            else:
                digital = False
                analog_moved = [(channel, now) for channel, (was, now)
                                in enumerate(zip(self._analog, change.levels), start=1)
                                if was != now]
                self._analog = tuple(change.levels)
            levels = sum(group << (8 * n) for n, group in enumerate(self._digital_groups))
            after = Outputs(levels & ((1 << self.layout.digital_outputs) - 1), self._analog)
        if digital:
            self._digital_changed.fire(after.digital)
        for channel, value in analog_moved:
            self._analog_changed.fire(channel, value)
        if change.last:
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
    device.start()
    return device
