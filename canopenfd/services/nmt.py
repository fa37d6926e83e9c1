"""NMT: states and commands, the line's NMT master, the local node's NMT slave
and the heartbeat of remote nodes.

`NmtState` and `NmtCommand` are the C enums (co_nmt_state_t,
co_nmt_command_t, built in canopenfd._binding.constants). Both also accept the
names python-canopen uses ('OPERATIONAL', 'PRE-OPERATIONAL', 'RESET
COMMUNICATION', ...), so code written for python-canopen
(`node.nmt.state = 'OPERATIONAL'`) keeps working.

`NmtMaster` is `line.nmt`; `LocalNmt` / `RemoteNmt` are `node.nmt`. The state
a node is in lives in `NmtSlave` (our node, as the runtime reports it) and
`HeartbeatMonitor` (a remote node, as its boot-up and heartbeats tell).
"""

from __future__ import annotations

import collections
from typing import Callable, Deque, List, Optional, Tuple, Union

from .._binding.constants import CommandKind, EventKind, HeartbeatEvent, NmtCommand, NmtState
from .._binding.context import Deferred, LineContext, LocalNodeService
from .._binding.runtime import Event, now_us
from .._aio import LoopArg
from .._callbacks import CallbackList, Until, chain
from .._checks import check_ms
from ..errors import ConfigurationError

__all__ = ["NmtState", "NmtCommand", "NmtMaster", "LocalNmt", "RemoteNmt", "NmtSlave",
           "HeartbeatMonitor", "HeartbeatEvent", "NodeEvents", "parse_node_target", "state_of", "remote_state_of"]

StateLike = Union[NmtState, str, int]

#: add_heartbeat_callback's default bound: at most one heartbeat per 10 ms and
#: node reaches Python (heartbeat producers run at 1 ms and slower; a node
#: flooding its CAN-ID is cut to 100 calls a second).
DEFAULT_TICK_MS = 10

# How many recent states a node remembers, so a wait that starts a little
# late still sees a short-lived state (INITIALISING during a reset).
_HISTORY = 64


def state_of(code: int) -> NmtState:
    """The NmtState of a state code; UNKNOWN for a code that is none."""
    try:
        return NmtState(code)
    except ValueError:
        return NmtState.UNKNOWN


def remote_state_of(code: int) -> NmtState:
    """A boot-up (0) means the node is now PRE-OPERATIONAL (CiA 301; python-canopen
    reports it that way too)."""
    state = state_of(code)
    return NmtState.PRE_OPERATIONAL if state is NmtState.INITIALISING else state


class StateHistory:
    """Recent states of a node with a sequence number, for waits."""

    def __init__(self) -> None:
        self.seq = 0
        self._states: Deque[Tuple[int, NmtState]] = collections.deque(maxlen=_HISTORY)

    def push(self, state: NmtState) -> None:
        self.seq += 1
        self._states.append((self.seq, state))

    def seen_since(self, seq: int, state: NmtState) -> bool:
        return any(s == state for n, s in self._states if n > seq)


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

    # No other attributes: `line.nmt.stat = ...` (a typo) raises instead of doing nothing.
    __slots__ = ("_context",)

    def __init__(self, context: LineContext) -> None:
        self._context = context

    @property
    def state(self) -> NmtState:
        """Not readable: every node of the line has its own (`line[5].nmt.state`,
        `line.states`). Setting it sends the command to all nodes, as
        python-canopen's `network.nmt.state = 'OPERATIONAL'` does."""
        raise ConfigurationError(
            f"line.nmt.state on {self._context.where}: the line's nodes each have a state; "
            "read line[node_id].nmt.state or line.states")

    @state.setter
    def state(self, value: Union[NmtState, NmtCommand, str, int]) -> None:
        self.send(_command_for_state(value), 0)

    def send(self, command: Union[NmtCommand, int, str], node_id: NodeTarget = 0,
             include_self: bool = False) -> None:
        """Send an NMT command; node_id 0 or 'all' addresses every node."""
        command = NmtCommand.parse(command)
        target = parse_node_target(node_id)
        context = self._context
        label = "all" if target == 0 else f"node {target}"
        context.runtime.command(CommandKind.NMT_SEND, context.index,
                                what=f"NMT {command.label} {label} on {context.where}",
                                command=int(command), node_id=target,
                                include_self=int(bool(include_self)))

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


class NmtSlave(LocalNodeService):
    """The NMT slave of the local node as the runtime runs it: its state and
    transitions (events NMT_STATE, NMT_VETOED, NMT_RESET), the veto of "to
    operational" and the heartbeat producer time when no OD holds it."""

    def __init__(self, context: LineContext, node_id: int, heartbeat_ms: int) -> None:
        self._context = context
        self.node_id = node_id
        #: Set once the runtime created the node (boot()).
        self.booted = False
        #: The 0x1017 value resets restore (given at creation, or set before boot).
        self.heartbeat_default_ms = heartbeat_ms
        #: The heartbeat time as last set (mirrors the runtime without an OD).
        self.heartbeat_ms = heartbeat_ms
        self._allow_operational = True
        self._history = StateHistory()
        self._state_changed = CallbackList(f"node {node_id} state change")
        self._vetoed = CallbackList(f"node {node_id} veto")
        self._reset = CallbackList(f"node {node_id} reset")
        self._renumber_hooks: List[Callable[[int], None]] = []
        context.subscribe(EventKind.NMT_STATE, self._event_state)
        context.subscribe(EventKind.NMT_VETOED, self._event_vetoed)
        context.subscribe(EventKind.NMT_RESET, self._event_reset)

    def create(self) -> None:
        """Create the node in the runtime and boot it (boot-up, PRE-OPERATIONAL)."""
        context = self._context
        context.runtime.command(CommandKind.NODE_CREATE, context.index,
                                what=f"boot of {self._where}", node_id=self.node_id,
                                heartbeat_ms=self.heartbeat_ms)
        self.booted = True

    @property
    def state(self) -> NmtState:
        """Current NMT state (read from the runtime); INITIALISING before boot."""
        code = self._context.runtime.local_state(self._context.index, self._where)
        return NmtState.INITIALISING if code is None else NmtState(code)

    def apply(self, command: Union[NmtCommand, int, str]) -> None:
        command = NmtCommand.parse(command)
        if not self.booted:
            raise ConfigurationError(f"{self._where} is not booted yet: call boot() first")
        context = self._context
        context.runtime.command(CommandKind.NMT_LOCAL, context.index,
                                what=f"NMT {command.label} on {self._where}",
                                command=int(command))

    def _state_until(self, state: StateLike) -> "Until[bool]":
        target = NmtState.parse(state)
        start = self._history.seq
        return Until(lambda: self._history.seen_since(start, target) or self.state == target,
                     f"{self._where}: wait_for_state({target.label})",
                     lambda: f"still {self.state.label}, not {target.label}")

    def wait_for_state(self, state: StateLike, timeout: Optional[float] = 10.0) -> None:
        self._context.waiter.wait_until(self._state_until(state), timeout)

    async def await_for_state(self, state: StateLike, timeout: Optional[float] = 10.0) -> None:
        await self._context.waiter.await_until(self._state_until(state), timeout)

    def set_heartbeat(self, ms: int) -> None:
        """The heartbeat producer time without an OD: the runtime's once booted,
        else the default the node will boot with."""
        context = self._context
        with context.cond:
            if self.booted:
                context.runtime.command(CommandKind.HEARTBEAT_TIME, context.index,
                                        what=f"heartbeat_ms = {ms} on {self._where}",
                                        time_ms=ms)
            else:
                self.heartbeat_default_ms = ms  # becomes the node's 0x1017 default
            self.heartbeat_ms = ms

    @property
    def allow_operational(self) -> bool:
        return self._allow_operational

    @allow_operational.setter
    def allow_operational(self, allowed: bool) -> None:
        context = self._context
        context.runtime.command(CommandKind.ALLOW_OPERATIONAL, context.index,
                                what=f"allow_operational = {allowed} on {self._where}",
                                allow=int(allowed))
        self._allow_operational = allowed

    def on_state_change(self, callback: Callable[[NmtState, NmtState], None],
                        loop: LoopArg = None) -> Callable[[NmtState, NmtState], None]:
        return self._state_changed.add(callback, loop)

    def on_veto(self, callback: Callable[[], None], loop: LoopArg = None) -> Callable[[], None]:
        return self._vetoed.add(callback, loop)

    def on_reset(self, callback: Callable[[NmtCommand], None],
                 loop: LoopArg = None) -> Callable[[NmtCommand], None]:
        return self._reset.add(callback, loop)

    # ------------------------------------------------------------ events
    def _event_state(self, event: Event) -> Deferred:
        old, new = state_of(event.a), state_of(event.b)
        self._history.push(new)
        return lambda: self._state_changed.fire(old, new)

    def _event_vetoed(self, event: Event) -> Deferred:
        return self._vetoed.fire

    def add_renumber_hook(self, hook: Callable[[int], None]) -> None:
        """hook(node_id) on the dispatcher thread, before the reset's callbacks,
        when a reset gave the node another node-id."""
        self._renumber_hooks.append(hook)

    def _event_reset(self, event: Event) -> Deferred:
        # The runtime restored 0x1017 to its default (CiA 301 reset of the
        # communication parameters); mirror it (with an OD it is read there).
        self.heartbeat_ms = self.heartbeat_default_ms
        if 1 <= event.node <= 127 and event.node != self.node_id:
            for hook in self._renumber_hooks:   # the event names the node-id it now has
                hook(event.node)
        try:
            command: Union[NmtCommand, int] = NmtCommand(event.a)
        except ValueError:
            command = event.a
        return lambda: self._reset.fire(command)


class HeartbeatMonitor:
    """A remote node's NMT state as its boot-up and heartbeat messages tell
    (events HEARTBEAT of that node), with the waits and callbacks of
    RemoteNode. Node guarding reports into it too (`guard_lost`, ...)."""

    def __init__(self, context: LineContext, node_id: int, where: str) -> None:
        self._context = context
        self.node_id = node_id
        self._where = where
        self._history = StateHistory()
        # Event times (CLOCK_MONOTONIC µs, as the runtime stamps them): waits
        # accept only events that happened after the wait began.
        self._last_bootup_us = -1
        self._last_heartbeat_us = -1   # first heartbeat, state change, resumption
        #: True while heartbeats arrive, False after a loss or a boot-up, None before.
        self.alive: Optional[bool] = None
        self._tracked = NmtState.UNKNOWN
        self._bootup = CallbackList(f"node {node_id} boot-up")
        self._state_changed = CallbackList(f"node {node_id} state change")
        self._lost = CallbackList(f"node {node_id} heartbeat lost")
        self._started = CallbackList(f"node {node_id} heartbeat started")
        self._heartbeat = CallbackList(f"node {node_id} heartbeat")
        self._tick_ms: Optional[int] = None   # interval the runtime ticks with, None = off
        context.subscribe(EventKind.HEARTBEAT, self._event, node=node_id)

    # ------------------------------------------------------------ the consumer
    def watch(self, timeout_ms: int, what: str) -> None:
        """Monitor the node (consumer time timeout_ms, 0 = states only)."""
        context = self._context
        context.runtime.command(CommandKind.HB_WATCH, context.index, what=what,
                                node_id=self.node_id, time_ms=timeout_ms)

    def unwatch(self, what: str) -> None:
        context = self._context
        context.runtime.command(CommandKind.HB_UNWATCH, context.index, what=what,
                                node_id=self.node_id)

    def track_runtime_state(self) -> None:
        """Start from the state the runtime already knows (a node heard before)."""
        self._tracked = self.state

    @property
    def state(self) -> NmtState:
        context = self._context
        return remote_state_of(context.runtime.remote_state(context.index, self.node_id,
                                                            self._where))

    # ------------------------------------------------------------ waits
    # Each wait accepts only what happens after the call: the Until is made then.
    def _bootup_until(self) -> "Until[bool]":
        start = now_us()
        return Until(lambda: self._last_bootup_us >= start,
                     f"{self._where}: wait_for_bootup", lambda: "no boot-up")

    def _heartbeat_until(self) -> "Until[bool]":
        start = now_us()
        return Until(lambda: self._last_heartbeat_us >= start or self.alive is True,
                     f"{self._where}: wait_for_heartbeat", lambda: "no heartbeat")

    def _state_until(self, state: StateLike) -> "Until[bool]":
        target = NmtState.parse(state)
        start = self._history.seq
        return Until(lambda: self._history.seen_since(start, target) or self.state == target,
                     f"{self._where}: wait_for_state({target.label})",
                     lambda: f"last state {self.state.label}, not {target.label}")

    def wait_for_bootup(self, timeout: Optional[float] = 10.0) -> None:
        self._context.waiter.wait_until(self._bootup_until(), timeout)

    async def await_for_bootup(self, timeout: Optional[float] = 10.0) -> None:
        await self._context.waiter.await_until(self._bootup_until(), timeout)

    def wait_for_heartbeat(self, timeout: Optional[float] = 10.0) -> NmtState:
        self._context.waiter.wait_until(self._heartbeat_until(), timeout)
        return self.state

    async def await_for_heartbeat(self, timeout: Optional[float] = 10.0) -> NmtState:
        await self._context.waiter.await_until(self._heartbeat_until(), timeout)
        return self.state

    def wait_for_state(self, state: StateLike, timeout: Optional[float] = 10.0) -> None:
        self._context.waiter.wait_until(self._state_until(state), timeout)

    async def await_for_state(self, state: StateLike, timeout: Optional[float] = 10.0) -> None:
        await self._context.waiter.await_until(self._state_until(state), timeout)

    # ------------------------------------------------------------ callbacks
    def on_bootup(self, callback: Callable[[], None], loop: LoopArg = None) -> Callable[[], None]:
        return self._bootup.add(callback, loop)

    def on_state_change(self, callback: Callable[[NmtState], None],
                        loop: LoopArg = None) -> Callable[[NmtState], None]:
        return self._state_changed.add(callback, loop)

    def on_heartbeat_lost(self, callback: Callable[[], None],
                          loop: LoopArg = None) -> Callable[[], None]:
        return self._lost.add(callback, loop)

    def on_heartbeat_started(self, callback: Callable[[], None],
                             loop: LoopArg = None) -> Callable[[], None]:
        return self._started.add(callback, loop)

    def add_heartbeat_callback(self, callback: Callable[[NmtState], None],
                               min_interval_ms: int = DEFAULT_TICK_MS,
                               loop: LoopArg = None) -> None:
        """callback(state) for every heartbeat (and boot-up, state 0); the C
        runtime tells at most one heartbeat per min_interval_ms (per node), so
        a node sending too fast cannot flood Python. The first callback asks
        the runtime for the ticks; a later one with another interval changes it."""
        what = f"add_heartbeat_callback of {self._where}"
        check_ms(min_interval_ms, "min_interval_ms", what)
        self._heartbeat.add(callback, loop)
        if min_interval_ms != self._tick_ms:
            context = self._context
            context.runtime.command(CommandKind.HB_TICK, context.index, what=what,
                                    node_id=self.node_id, interval_ms=min_interval_ms, on=1)
            self._tick_ms = min_interval_ms

    def remove_heartbeat_callback(self, callback: Callable[[NmtState], None]) -> None:
        """Remove a callback; with the last one the runtime stops the ticks."""
        self._heartbeat.remove(callback)
        if not self._heartbeat and self._tick_ms is not None:
            context = self._context
            context.runtime.command(CommandKind.HB_TICK, context.index,
                                    what=f"remove_heartbeat_callback of {self._where}",
                                    node_id=self.node_id, interval_ms=0, on=0)
            self._tick_ms = None

    # ------------------------------------------------------------ reports (under the condition)
    def guard_lost(self) -> Callable[[], None]:
        """Node guarding lost the node: as a heartbeat loss."""
        self.alive = False
        return self._lost.fire

    def guard_alive(self) -> Callable[[], None]:
        """Node guarding (re)gained the node: as heartbeats (re)starting."""
        self.alive = True
        return self._started.fire

    def state_seen(self, state: NmtState) -> Deferred:
        """A state the node reported (heartbeat or guarding answer)."""
        self._history.push(state)
        if state == self._tracked:
            return None
        self._tracked = state
        return lambda: self._state_changed.fire(state)

    def _event(self, event: Event) -> Deferred:
        """CO_EV_HEARTBEAT of this node."""
        kind, state = event.a, remote_state_of(event.b)
        calls: List[Callable[[], None]] = []
        if kind == HeartbeatEvent.BOOTUP:
            self._last_bootup_us = max(self._last_bootup_us, event.time_us)
            self.alive = False
            self._history.push(NmtState.INITIALISING)
            calls.append(self._bootup.fire)
            calls.append(lambda: self._heartbeat.fire(NmtState.INITIALISING))
        elif kind == HeartbeatEvent.LOST:
            self.alive = False
            return self._lost.fire
        elif kind == HeartbeatEvent.TICK:
            # one heartbeat, told because callbacks asked (add_heartbeat_callback)
            self._last_heartbeat_us = max(self._last_heartbeat_us, event.time_us)
            calls.append(lambda: self._heartbeat.fire(state))
        else:
            self._last_heartbeat_us = max(self._last_heartbeat_us, event.time_us)
            if kind == HeartbeatEvent.STARTED:
                self.alive = True
                calls.append(self._started.fire)
        changed = self.state_seen(state)
        if changed is not None:
            calls.append(changed)
        return chain(calls)


class NodeEvents:
    """Every node's boot-up, NMT state changes and heartbeat loss/start on a
    line, watched with add_node or not (`line.on_node_event`): what a gateway
    reports to its hosts. Periodic heartbeats (TICK) are not told."""

    def __init__(self, context: LineContext) -> None:
        self._callbacks = CallbackList(f"{context.where} node event")
        context.observe(EventKind.HEARTBEAT, self._event)

    def add(self, callback: Callable[[int, HeartbeatEvent, NmtState], None],
            loop: LoopArg = None) -> Callable[[int, HeartbeatEvent, NmtState], None]:
        return self._callbacks.add(callback, loop)

    def remove(self, callback: Callable[[int, HeartbeatEvent, NmtState], None]) -> None:
        self._callbacks.remove(callback)

    def _event(self, event: Event) -> Deferred:
        """CO_EV_HEARTBEAT of any node: a = co_hb_event_t, b = the state."""
        if not self._callbacks or event.a == HeartbeatEvent.TICK:
            return None
        try:
            kind = HeartbeatEvent(event.a)
        except ValueError:
            return None
        node_id, state = event.node, remote_state_of(event.b)
        return lambda: self._callbacks.fire(node_id, kind, state)


class LocalNmt:
    """`local_node.nmt`: the NMT slave of our own node.

    Setting `.state` applies the matching command locally (as if the master had
    sent it), e.g. `node.nmt.state = 'OPERATIONAL'`; nothing goes on the bus
    except what the node itself sends (boot-up after a reset).
    """

    def __init__(self, slave: NmtSlave) -> None:
        self._slave = slave

    @property
    def state(self) -> NmtState:
        return self._slave.state

    @state.setter
    def state(self, value: Union[NmtState, NmtCommand, str, int]) -> None:
        self._slave.apply(_command_for_state(value))

    def wait_for_state(self, state: Union[NmtState, str, int], timeout: float = 10.0) -> None:
        self._slave.wait_for_state(state, timeout)

    async def await_for_state(self, state: Union[NmtState, str, int],
                              timeout: float = 10.0) -> None:
        await self._slave.await_for_state(state, timeout)


class RemoteNmt:
    """`remote_node.nmt`: NMT master for one remote node plus its heartbeat
    view, shaped like python-canopen's NmtMaster."""

    def __init__(self, monitor: HeartbeatMonitor, master: NmtMaster) -> None:
        self._monitor = monitor
        self._master = master

    @property
    def state(self) -> NmtState:
        """Last state the node reported (PRE-OPERATIONAL right after its
        boot-up, as CiA 301 and python-canopen have it; UNKNOWN when never heard)."""
        return self._monitor.state

    @state.setter
    def state(self, value: Union[NmtState, NmtCommand, str, int]) -> None:
        # Like python-canopen: setting a state sends the command leading to it.
        # The getter keeps telling what the node reported until its next heartbeat.
        self.send_command(_command_for_state(value))

    def send_command(self, code: Union[NmtCommand, int, str]) -> None:
        self._master.send(code, self._monitor.node_id)

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
        self._monitor.wait_for_bootup(timeout)

    def wait_for_heartbeat(self, timeout: float = 10.0) -> NmtState:
        return self._monitor.wait_for_heartbeat(timeout)

    def wait_for_state(self, state: Union[NmtState, str, int], timeout: float = 10.0) -> None:
        self._monitor.wait_for_state(state, timeout)

    async def await_for_bootup(self, timeout: float = 10.0) -> None:
        await self._monitor.await_for_bootup(timeout)

    async def await_for_heartbeat(self, timeout: float = 10.0) -> NmtState:
        return await self._monitor.await_for_heartbeat(timeout)

    async def await_for_state(self, state: Union[NmtState, str, int],
                              timeout: float = 10.0) -> None:
        await self._monitor.await_for_state(state, timeout)

    def add_heartbeat_callback(self, callback: Callable[[NmtState], None],
                               min_interval_ms: int = DEFAULT_TICK_MS,
                               loop: LoopArg = None) -> None:
        """python-canopen's callback(state) for every heartbeat (see
        HeartbeatMonitor.add_heartbeat_callback)."""
        self._monitor.add_heartbeat_callback(callback, min_interval_ms, loop=loop)

    def remove_heartbeat_callback(self, callback: Callable[[NmtState], None]) -> None:
        self._monitor.remove_heartbeat_callback(callback)

    @property
    def heartbeat_alive(self) -> Optional[bool]:
        return self._monitor.alive


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
