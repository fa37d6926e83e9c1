"""Frames on 0x700 + node-id (CiA 301 NMT error control): boot-up, heartbeat,
and node guarding (the master's remote frame, the slave's state | toggle).

A guarding reply whose toggle bit is 0 looks like a heartbeat: alone, only a
byte with bit 7 set is known to be a reply. `GuardingTracker` (what the
stateful `Decoder` keeps) reads a node's next one-byte frame after a request
as the reply."""

from __future__ import annotations

from typing import Set

from .._binding.constants import NmtState

ERROR_CONTROL_BASE = 0x700

_GUARDED_STATES = (NmtState.STOPPED, NmtState.OPERATIONAL, NmtState.PRE_OPERATIONAL)


def guarding_request_text(node_id: int) -> str:
    return f"node guarding request node {node_id}"


def heartbeat_text(node_id: int, data: bytes, guarded: bool = False) -> str:
    """A frame on 0x700 + node-id: boot-up, heartbeat, or node guarding reply
    (bit 7 set is the guarding toggle; guarded: the answer to a request seen)."""
    if node_id == 0:
        return "heartbeat malformed: CAN-ID 0x700 (node-id 0)"
    if len(data) != 1:
        what = "node guarding reply" if guarded else "heartbeat"
        return f"{what} node {node_id} malformed: {len(data)} bytes, expected 1"
    code = data[0]
    if code == NmtState.INITIALISING:
        return f"boot-up node {node_id}"
    if code & 0x80 or guarded:
        return guarding_reply_text(node_id, code)
    try:
        state = NmtState(code)
    except ValueError:
        state = None
    if state is None or state is NmtState.UNKNOWN:
        return f"heartbeat node {node_id} malformed: state 0x{code:02X}"
    return f"heartbeat node {node_id} {state.label}"


def guarding_reply_text(node_id: int, code: int) -> str:
    """Node guarding reply: NMT state in bits 0..6, toggle in bit 7."""
    head = f"node guarding reply node {node_id}"
    toggle, state = code >> 7, code & 0x7F
    if state not in _GUARDED_STATES:
        return f"{head} toggle {toggle} malformed: state 0x{state:02X}"
    return f"{head} {NmtState(state).label} toggle {toggle}"


class GuardingTracker:
    """Open guarding requests and the nodes seen sending heartbeats: after a
    request the node's next one-byte frame is the reply, also with toggle 0,
    unless the node was seen sending heartbeats (bit 7 clear, unasked; a
    heartbeat producer answers no request), until its boot-up or a reply with
    toggle 1."""

    def __init__(self) -> None:
        self._requests: Set[int] = set()
        self._heartbeat_nodes: Set[int] = set()

    def requested(self, node_id: int) -> None:
        self._requests.add(node_id)

    def is_reply(self, node_id: int, data: bytes) -> bool:
        """Whether this frame on 0x700 + node_id answers an open guarding
        request (the request is then closed); keeps track of heartbeat producers."""
        asked = node_id in self._requests
        self._requests.discard(node_id)
        if len(data) != 1:
            return asked
        if data[0] == 0 or data[0] & 0x80:           # boot-up, or a reply with toggle 1
            self._heartbeat_nodes.discard(node_id)
            return asked
        if not asked:
            self._heartbeat_nodes.add(node_id)       # bit 7 clear, unasked: a heartbeat
            return False
        return node_id not in self._heartbeat_nodes

    def reset(self) -> None:
        self._requests.clear()
        self._heartbeat_nodes.clear()
