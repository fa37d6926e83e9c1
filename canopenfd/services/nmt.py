"""NMT states and commands, and the NMT objects of lines and nodes.

`NmtState` and `NmtCommand` are the C enums (co_nmt_state_t,
co_nmt_command_t, built in canopenfd._binding.constants). Both also accept the
names python-canopen uses
('OPERATIONAL', 'PRE-OPERATIONAL', 'RESET COMMUNICATION', ...), so code written
for python-canopen (`node.nmt.state = 'OPERATIONAL'`) keeps working.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Callable, Optional, Union

from .._binding.constants import NmtCommand, NmtState
from ..errors import ConfigurationError

if TYPE_CHECKING:  # pragma: no cover
    from ..line import Line
    from ..node import LocalNode, RemoteNode


NodeTarget = Union[int, str]


def parse_node_target(node_id: NodeTarget) -> int:
    """0..127 or 'all' -> the NMT frame's node-id byte (0 = all nodes)."""
    if isinstance(node_id, str):
        if node_id.strip().lower() == "all":
            return 0
        try:
            node_id = int(node_id.strip(), 0)
        except ValueError:
            raise ConfigurationError(
                f"NMT target {node_id!r} invalid: expected a node-id 1..127, 0 or 'all'"
            ) from None
    if isinstance(node_id, bool) or not isinstance(node_id, int):
        raise ConfigurationError(
            f"NMT target must be a node-id 1..127, 0 or 'all', got {node_id!r}")
    if not 0 <= node_id <= 127:
        raise ConfigurationError(
            f"node-id {node_id} outside 0..127 for an NMT command (0 or 'all' = every node)")
    return node_id


class NmtMaster:
    """The NMT master of a line (`line.nmt`): sends commands to one node or to all.

    CAN does not echo our own frames, so a command that targets the line's own
    local node (its node-id, or 'all' with include_self=True) is applied to it
    by the runtime as well.
    """

    def __init__(self, line: "Line") -> None:
        self._line = line

    def send(self, command: Union[NmtCommand, int, str], node_id: NodeTarget = 0,
             include_self: bool = False) -> None:
        """Send an NMT command; node_id 0 or 'all' addresses every node."""
        self._line._send_nmt(NmtCommand.parse(command), parse_node_target(node_id),
                             bool(include_self))

    def send_command(self, code: Union[NmtCommand, int, str]) -> None:
        """python-canopen's `network.nmt.send_command(code)`: to all nodes."""
        self.send(code, 0)

    def start(self, node_id: NodeTarget = 0, include_self: bool = False) -> None:
        self.send(NmtCommand.START, node_id, include_self)

    def stop(self, node_id: NodeTarget = 0, include_self: bool = False) -> None:
        self.send(NmtCommand.STOP, node_id, include_self)

    def pre_operational(self, node_id: NodeTarget = 0, include_self: bool = False) -> None:
        self.send(NmtCommand.PRE_OPERATIONAL, node_id, include_self)

    def reset_node(self, node_id: NodeTarget = 0, include_self: bool = False) -> None:
        self.send(NmtCommand.RESET_NODE, node_id, include_self)

    def reset_communication(self, node_id: NodeTarget = 0,
                            include_self: bool = False) -> None:
        self.send(NmtCommand.RESET_COMMUNICATION, node_id, include_self)


class LocalNmt:
    """`local_node.nmt`: the NMT slave of our own node.

    Setting `.state` applies the matching command locally (as if the master had
    sent it), e.g. `node.nmt.state = 'OPERATIONAL'`; nothing goes on the bus
    except what the node itself sends (boot-up after a reset).
    """

    def __init__(self, node: "LocalNode") -> None:
        self._node = node

    @property
    def state(self) -> NmtState:
        return self._node.state

    @state.setter
    def state(self, value: Union[NmtState, NmtCommand, str, int]) -> None:
        self._node.apply(_command_for_state(value))

    def wait_for_state(self, state: Union[NmtState, str, int], timeout: float = 10.0) -> None:
        self._node.wait_for_state(state, timeout)


class RemoteNmt:
    """`remote_node.nmt`: NMT master for one remote node plus its heartbeat
    view, shaped like python-canopen's NmtMaster."""

    def __init__(self, node: "RemoteNode") -> None:
        self._node = node

    @property
    def state(self) -> NmtState:
        """Last state the node reported (PRE-OPERATIONAL right after its
        boot-up, as CiA 301 and python-canopen have it; UNKNOWN when never heard)."""
        return self._node.state

    @state.setter
    def state(self, value: Union[NmtState, NmtCommand, str, int]) -> None:
        # Like python-canopen: setting a state sends the command leading to it.
        # The getter keeps telling what the node reported until its next heartbeat.
        self.send_command(_command_for_state(value))

    def send_command(self, code: Union[NmtCommand, int, str]) -> None:
        self._node.line.nmt.send(code, self._node.node_id)

    def start(self) -> None:
        self.send_command(NmtCommand.START)

    def stop(self) -> None:
        self.send_command(NmtCommand.STOP)

    def pre_operational(self) -> None:
        self.send_command(NmtCommand.PRE_OPERATIONAL)

    def reset_node(self) -> None:
        self.send_command(NmtCommand.RESET_NODE)

    def reset_communication(self) -> None:
        self.send_command(NmtCommand.RESET_COMMUNICATION)

    def wait_for_bootup(self, timeout: float = 10.0) -> None:
        self._node.wait_for_bootup(timeout)

    def wait_for_heartbeat(self, timeout: float = 10.0) -> NmtState:
        return self._node.wait_for_heartbeat(timeout)

    def wait_for_state(self, state: Union[NmtState, str, int], timeout: float = 10.0) -> None:
        self._node.wait_for_state(state, timeout)

    def add_heartbeat_callback(self, callback: Callable[[NmtState], None]) -> None:
        self._node.add_heartbeat_callback(callback)

    @property
    def heartbeat_alive(self) -> Optional[bool]:
        return self._node.heartbeat_alive


def _command_for_state(value: Union[NmtState, NmtCommand, str, int]) -> NmtCommand:
    """The command that leads to a state: 'OPERATIONAL' -> START and so on.
    Strings follow python-canopen's NMT_COMMANDS ('RESET', 'RESET COMMUNICATION')."""
    if isinstance(value, NmtCommand):
        return value
    if isinstance(value, NmtState):
        for command in NmtCommand:
            if command.target is value:
                return command
        raise ConfigurationError(f"no NMT command leads to state {value.label}")
    if isinstance(value, str):
        return NmtCommand.parse(value)
    return _command_for_state(NmtState.parse(value))
