"""Thin, thread-safe wrapper around one `co_rt_t` of the cffi binding.

It turns negative status codes into exceptions carrying `co_rt_last_error`'s
text, and it makes every call after `free()` raise ClosedError instead of
touching freed memory.
"""

from __future__ import annotations

import re
import threading
from typing import (Callable, Dict, List, Mapping, NamedTuple, Optional, Sequence, Tuple, Type,
                    Union)

from ..errors import CanopenFDError, ClosedError, CommandError, ConfigurationError, InterfaceError
from ..frame import Frame
from ..od import ODVariable, ObjectDictionary
from ..od.datatypes import Value
from .constants import CommandKind, EventKind
from .core import CData, ffi, lib
from .od_tables import definitions, entry_definitions
from .transfers import TransferRequest

#: The runtime's "line N: " prefix of its error texts.
_LINE_NUMBER = re.compile(r"^line \d+: ")

_ERRORS = {
    lib.CO_RT_ERR_ARGUMENT: ConfigurationError,
    lib.CO_RT_ERR_NO_INTERFACE: InterfaceError,
    lib.CO_RT_ERR_MTU: InterfaceError,
    lib.CO_RT_ERR_SOCKET: InterfaceError,
    lib.CO_RT_ERR_FULL: CommandError,
    lib.CO_RT_ERR_STATE: ConfigurationError,
    lib.CO_RT_ERR_NO_MEMORY: CommandError,
    lib.CO_RT_ERR_CLOSED: ClosedError,
    lib.CO_RT_ERR_MODE: ConfigurationError,
}

EVENT_BATCH = 256   # events taken per wake-up of the dispatcher
HOST_BATCH = 256


class Event(NamedTuple):
    """One runtime event (co_rt_event_t) in Python values."""

    kind: int                 # EventKind
    line: int
    node: int
    a: int
    b: int
    time_us: int              # CLOCK_MONOTONIC
    frame: Optional[Frame]    # FRAME (monitor lines), PDO_FRAME
    data: bytes               # EMCY: the encoded EMCY; PDO: the RPDO's mapped values;
    #                           MANAGER: a boot report's index, values, abort;
    #                           MPDO: the frame, RPDO, local index:sub
    coalesced: int = 0        # PDO, PDO_FRAME, MPDO: older values of the source it replaced


def status_text(status: int) -> str:
    return ffi.string(lib.co_rt_status_text(status)).decode("utf-8", "replace")


def frame_to_c(frame: Frame, out: CData) -> None:
    """Fill a co_frame_t (cdata) from a Frame."""
    out.id = frame.id
    out.len = len(frame.data) if not frame.rtr else frame.rtr_len
    out.flags = frame.flags
    ffi.memmove(out.data, frame.data, len(frame.data))


def frame_from_c(cframe: CData, timestamp: float = 0.0, tx: bool = False) -> Frame:
    """A Frame from a co_frame_t (cdata)."""
    flags = cframe.flags
    length = min(cframe.len, 64)
    rtr = bool(flags & lib.CO_FRAME_RTR)
    data = b"" if rtr else bytes(ffi.buffer(cframe.data, length))
    return Frame.from_flags(cframe.id, data, flags, timestamp=timestamp, tx=tx,
                            rtr_len=length if rtr else 0)


class Runtime:
    """One C runtime (its thread, mailbox, event queue and lines)."""

    def __init__(self, event_capacity: int = 0) -> None:
        self._lock = threading.Lock()
        # Application threads blocked in co_rt_transfer_wait: free() waits
        # until they left (stop() has woken them).
        self._idle = threading.Condition(self._lock)
        self._waiters = 0
        self._events = ffi.new("co_rt_event_t[]", EVENT_BATCH)
        self._rt = ffi.NULL
        self._stopped = False
        rt = lib.co_rt_new(event_capacity)
        if rt == ffi.NULL:
            raise CommandError("co_rt_new failed: out of memory")
        self._rt = rt
        rc = lib.co_rt_start(rt)
        if rc < 0:
            text = self.last_error() or status_text(rc)
            lib.co_rt_free(rt)
            self._rt = ffi.NULL
            raise _ERRORS.get(rc, CanopenFDError)(f"cannot start the runtime thread: {text}")

    # ------------------------------------------------------------ lifecycle
    @property
    def closed(self) -> bool:
        return self._stopped

    def stop(self) -> None:
        """Stop the C thread; waiters (events, host transmit) return CLOSED."""
        with self._lock:
            if self._stopped or self._rt == ffi.NULL:
                self._stopped = True
                return
            self._stopped = True
            lib.co_rt_stop(self._rt)

    def free(self) -> None:
        """Free the runtime. Only once every thread that waits in it has left."""
        with self._lock:
            self._stopped = True
            while self._waiters > 0 and self._rt != ffi.NULL:
                lib.co_rt_stop(self._rt)   # idempotent; wakes the waiters
                self._idle.wait(0.1)
            if self._rt != ffi.NULL:
                lib.co_rt_free(self._rt)
                self._rt = ffi.NULL

    def _live(self, what: str) -> CData:
        if self._stopped or self._rt == ffi.NULL:
            raise ClosedError(f"{what}: the network is closed")
        return self._rt

    def require_open(self, what: str) -> None:
        """ClosedError ("what: the network is closed") once stopped."""
        self._live(what)

    # ------------------------------------------------------------ errors
    def last_error(self) -> str:
        if self._rt == ffi.NULL:
            return ""
        buf = ffi.new("char[]", 512)
        lib.co_rt_last_error(self._rt, buf, 512)
        return ffi.string(buf).decode("utf-8", "replace")

    def _raise(self, status: int, what: str,
               overrides: Optional[Dict[int, Type[CanopenFDError]]] = None) -> None:
        # The runtime numbers lines ("line 0: ..."); `what` names the line the
        # way the user opened it, so the number would only mislead (a file line?).
        text = _LINE_NUMBER.sub("", self.last_error() or status_text(status), count=1)
        kind = (overrides or {}).get(status) or _ERRORS.get(status, CanopenFDError)
        raise kind(f"{what}: {text}")

    # ------------------------------------------------------------ calls
    def add_line(self, driver: int, channel: str, mode: int, brs: bool, rx_queue: int,
                 tx_queue: int, monitor: bool, what: str) -> int:
        config = ffi.new("co_rt_line_config_t *")
        channel_c = ffi.new("char[]", channel.encode("utf-8"))
        config.driver = driver
        config.channel = channel_c
        config.mode = mode
        config.brs = int(brs)
        config.rx_queue = rx_queue
        config.tx_queue = tx_queue
        config.monitor = int(monitor)
        with self._lock:
            rc = lib.co_rt_add_line(self._live(what), config)
            if rc < 0:
                # Opening a line, "wrong state" means the interface is down.
                self._raise(rc, what, {lib.CO_RT_ERR_STATE: InterfaceError})
        return rc

    def command(self, kind: int, line: int, what: str = "command",
                frame: Optional[Frame] = None, **fields: int) -> None:
        """Post a command; `fields` fill the member of co_rt_command_t's args
        named after the kind (node_create: node_id, heartbeat_ms; nmt_send:
        command, node_id, include_self; ...), `frame` that of SEND_FRAME."""
        cmd = ffi.new("co_rt_command_t *")
        cmd.kind = kind
        cmd.line = line
        args = getattr(cmd.args, CommandKind(kind).name.lower())
        if frame is not None:
            frame_to_c(frame, args)
        for name, value in fields.items():
            setattr(args, name, value)
        with self._lock:
            rc = lib.co_rt_command(self._live(what), cmd)
            if rc < 0:
                self._raise(rc, what)

    # ------------------------------------------------------------ object dictionary
    def od_define(self, line: int, od: ObjectDictionary, node_id: int,
                  overrides: Mapping[Tuple[int, int], Value], store_path: Optional[str],
                  what: str) -> None:
        """Define the local node's OD (co_od_def_t table from od, `overrides`
        replacing start values) before the node is created."""
        defs, count, _keep = definitions(od, node_id, overrides)
        path = ffi.new("char[]", store_path.encode("utf-8")) if store_path else ffi.NULL
        with self._lock:
            rc = lib.co_rt_od_define(self._live(what), line, defs, count, path)
            if rc < 0:
                self._raise(rc, what)

    def od_reserve(self, line: int, spare_entries: int, spare_bytes: int, what: str) -> None:
        """Room for entries added while the node runs, before od_define."""
        with self._lock:
            rc = lib.co_rt_od_reserve(self._live(what), line, spare_entries, spare_bytes)
            if rc < 0:
                self._raise(rc, what)

    def od_add(self, line: int, entries: List[ODVariable], node_id: int, what: str) -> None:
        """Add entries to the running node's OD, all or none (served at once)."""
        defs, count, _keep = entry_definitions(entries, node_id)
        with self._lock:
            rc = lib.co_rt_od_add(self._live(what), line, defs, count)
            if rc < 0:
                self._raise(rc, what)

    def od_read(self, line: int, index: int, sub: int, what: str) -> Tuple[int, bytes]:
        """(abort code or 0, value bytes); grows the buffer when it is too small."""
        size = 64
        length = ffi.new("uint32_t *")
        while True:
            buf = ffi.new("uint8_t[]", size)
            with self._lock:
                rc = lib.co_rt_od_read(self._live(what), line, index, sub, buf, size, length)
                if rc < 0:
                    self._raise(rc, what)
            if rc == lib.CO_ABORT_OUT_OF_MEMORY and length[0] > size:
                size = length[0]
                continue
            return rc, (bytes(ffi.buffer(buf, length[0])) if rc == 0 else b"")

    def od_write(self, line: int, index: int, sub: int, data: bytes, what: str) -> int:
        with self._lock:
            rc = lib.co_rt_od_write(self._live(what), line, index, sub, data, len(data))
            if rc < 0:
                self._raise(rc, what)
        return rc

    def od_domain(self, line: int, index: int, sub: int, capacity: int, what: str) -> None:
        with self._lock:
            rc = lib.co_rt_od_domain(self._live(what), line, index, sub, capacity)
            if rc < 0:
                self._raise(rc, what)

    def od_indicate(self, line: int, first: int, last: int, kinds: int, what: str) -> None:
        """Network reads/writes of keys first..last (index << 8 | sub) wait on
        the application (CO_EV_OD_REQUEST) until od_answer."""
        with self._lock:
            rc = lib.co_rt_od_indicate(self._live(what), line, first >> 8, first & 0xFF,
                                       last >> 8, last & 0xFF, kinds)
            if rc < 0:
                self._raise(rc, what)

    def od_request_value(self, line: int, token: int, what: str) -> bytes:
        """The value a waiting check-write would write."""
        size = 64
        length = ffi.new("uint32_t *")
        while True:
            buf = ffi.new("uint8_t[]", size)
            with self._lock:
                rc = lib.co_rt_od_request_value(self._live(what), line, token, buf, size, length)
                grow = rc == lib.CO_RT_ERR_ARGUMENT and length[0] > size
                if rc < 0 and not grow:
                    self._raise(rc, what)
            if not grow:
                return bytes(ffi.buffer(buf, length[0]))
            size = length[0]

    def od_answer(self, line: int, token: int, abort: int, what: str) -> None:
        with self._lock:
            rc = lib.co_rt_od_answer(self._live(what), line, token, abort)
            if rc < 0:
                self._raise(rc, what)

    def store_application(self, line: int, image: bytes, status: int, what: str) -> None:
        with self._lock:
            rc = lib.co_rt_store_application(self._live(what), line, image, len(image), status)
            if rc < 0:
                self._raise(rc, what)

    def store_autonomous_pending(self, line: int, what: str) -> bool:
        """Whether the staged image is an autonomous save's."""
        with self._lock:
            rc = lib.co_rt_store_autonomous_pending(self._live(what), line)
            if rc < 0:
                self._raise(rc, what)
            return rc == 1

    def store_groups(self, line: int, rows: Sequence[Tuple[int, int, int, int, int]],
                     min_interval_ms: int, what: str) -> None:
        """Declare parameter groups: (first_key, last_key, sub, mode, reset) rows."""
        table = ffi.new("co_store_group_t[]", len(rows))
        for i, (first, last, sub, mode, reset) in enumerate(rows):
            table[i].first_key, table[i].last_key = first, last
            table[i].sub, table[i].mode, table[i].reset = sub, mode, reset
        with self._lock:
            rc = lib.co_rt_store_groups(self._live(what), line, table, len(rows),
                                        min_interval_ms)
            if rc < 0:
                self._raise(rc, what)

    def store_staged(self, line: int, what: str) -> Optional[bytes]:
        """The image waiting to be persisted, None when none waits."""
        size = 256
        length = ffi.new("uint32_t *")
        while True:
            buf = ffi.new("uint8_t[]", size)
            with self._lock:
                rc = lib.co_rt_store_staged(self._live(what), line, buf, size, length)
                grow = rc == lib.CO_RT_ERR_ARGUMENT and length[0] > size
                if rc == lib.CO_RT_ERR_STATE:
                    return None
                if rc < 0 and not grow:
                    self._raise(rc, what)
            if not grow:
                return bytes(ffi.buffer(buf, length[0]))
            size = length[0]

    def store_finish(self, line: int, ok: bool, what: str) -> None:
        with self._lock:
            rc = lib.co_rt_store_finish(self._live(what), line, int(ok))
            if rc < 0:
                self._raise(rc, what)

    # ------------------------------------------------------------ client transfers
    def usdo_client(self, line: int, node_id: int, what: str) -> None:
        with self._lock:
            rc = lib.co_rt_usdo_client(self._live(what), line, node_id)
            if rc < 0:
                self._raise(rc, what)

    def transfer_start(self, line: int, request: TransferRequest, what: str) -> int:
        c_request = request.to_c()
        with self._lock:
            rc = lib.co_rt_transfer_start(self._live(what), line, c_request)
            if rc < 0:
                self._raise(rc, what)
        return rc

    def transfer_cancel(self, line: int, handle: int, code: int, what: str) -> None:
        with self._lock:
            rc = lib.co_rt_transfer_cancel(self._live(what), line, handle, code)
            if rc < 0:
                self._raise(rc, what)

    def transfer_result(self, line: int, handle: int, what: str) -> Dict[str, int]:
        out = ffi.new("co_rt_transfer_result_t *")
        with self._lock:
            rc = lib.co_rt_transfer_result(self._live(what), line, handle, out)
            if rc < 0:
                self._raise(rc, what)
        return {name: getattr(out, name)
                for name, _ in ffi.typeof("co_rt_transfer_result_t").fields}

    def transfer_notify(self, line: int, handle: int, what: str) -> bool:
        """Ask for the transfer's TRANSFER_DONE event; True when it ended
        already (then none comes)."""
        with self._lock:
            rc = lib.co_rt_transfer_notify(self._live(what), line, handle)
            if rc < 0:
                self._raise(rc, what)
        return rc == 1

    def transfer_wait(self, line: int, handle: int, timeout_ms: int, what: str) -> bool:
        """Block (GIL released) until the transfer ended or timeout_ms passed;
        True when it ended."""
        with self._lock:
            rt = self._live(what)
            self._waiters += 1
        try:
            rc = lib.co_rt_transfer_wait(rt, line, handle, timeout_ms)
        finally:
            with self._lock:
                self._waiters -= 1
                self._idle.notify_all()
        if rc < 0:
            with self._lock:
                self._live(what)
                self._raise(rc, what)
        return rc == 1

    def transfer_data(self, line: int, handle: int, size: int, what: str) -> bytes:
        buf = ffi.new("uint8_t[]", max(size, 1))
        with self._lock:
            rc = lib.co_rt_transfer_data(self._live(what), line, handle, buf, size)
            if rc < 0:
                self._raise(rc, what)
        return bytes(ffi.buffer(buf, rc))

    def usdo_answers(self, line: int, handle: int, what: str) -> List[Tuple[int, int, bytes]]:
        """[(node, abort, data bytes)] of a USDO broadcast."""
        out = ffi.new("co_rt_usdo_answer_t[]", 127)
        with self._lock:
            rc = lib.co_rt_usdo_answers(self._live(what), line, handle, out, 127)
            if rc < 0:
                self._raise(rc, what)
        return [(a.node, a.abort, bytes(ffi.buffer(a.data, a.length))) for a in out[0:rc]]

    def transfer_release(self, line: int, handle: int, what: str) -> None:
        with self._lock:
            rc = lib.co_rt_transfer_release(self._live(what), line, handle)
            if rc < 0:
                self._raise(rc, what)

    # ------------------------------------------------------------ configuration manager
    def config_start(self, line: int, node: int, dcf: bytes, stamp: Optional[Tuple[int, int]],
                     continue_on_error: bool, timeout_ms: int, what: str) -> int:
        """Start a configuration (the DCF is copied): its handle."""
        request = ffi.new("co_rt_config_request_t *")
        data = ffi.from_buffer(dcf)
        request.node = node
        request.dcf = data
        request.dcf_length = len(dcf)
        request.check_stamp = int(stamp is not None)
        request.date, request.time = stamp if stamp is not None else (0, 0)
        request.continue_on_error = int(continue_on_error)
        request.timeout_ms = timeout_ms
        with self._lock:
            rc = lib.co_rt_config_start(self._live(what), line, request)
            if rc < 0:
                self._raise(rc, what)
        return int(rc)

    def config_result(self, line: int, handle: int, what: str) -> Dict[str, int]:
        out = ffi.new("co_rt_config_result_t *")
        with self._lock:
            rc = lib.co_rt_config_result(self._live(what), line, handle, out)
            if rc < 0:
                self._raise(rc, what)
        return {name: int(getattr(out, name))
                for name, _ in ffi.typeof("co_rt_config_result_t").fields}

    def config_entries(self, line: int, handle: int, count: int,
                       what: str) -> List[Tuple[int, int, int]]:
        """[(index, sub, abort)] told so far, in order."""
        out = ffi.new("co_rt_config_entry_t[]", max(count, 1))
        with self._lock:
            rc = lib.co_rt_config_entries(self._live(what), line, handle, out, count)
            if rc < 0:
                self._raise(rc, what)
        return [(int(e.index), int(e.sub), int(e.abort)) for e in out[0:rc]]

    def config_cancel(self, line: int, handle: int, what: str) -> None:
        with self._lock:
            rc = lib.co_rt_config_cancel(self._live(what), line, handle)
            if rc < 0:
                self._raise(rc, what)

    def config_release(self, line: int, handle: int, what: str) -> None:
        with self._lock:
            if self._stopped or self._rt == ffi.NULL:
                return   # the network closed: the runtime freed it
            rc = lib.co_rt_config_release(self._rt, line, handle)
            if rc < 0:
                self._raise(rc, what)

    def od_store(self, line: int, group_mask: int, save: bool, what: str) -> int:
        call = lib.co_rt_od_save if save else lib.co_rt_od_restore_defaults
        with self._lock:
            rc = call(self._live(what), line, group_mask)
            if rc < 0:
                self._raise(rc, what)
        return rc

    def store_status(self, line: int, what: str) -> int:
        with self._lock:
            rc = lib.co_rt_store_status(self._live(what), line)
            if rc < 0:
                self._raise(rc, what)
        return rc

    def _counters(self, fetch: Callable[[CData, int, CData], int], ctype: str, line: int,
                  what: str) -> Dict[str, int]:
        """{counter: value} of a flat stats struct filled by fetch(rt, line, out)."""
        out = ffi.new(ctype + " *")
        with self._lock:
            rc = fetch(self._live(what), line, out)
            if rc < 0:
                self._raise(rc, what)
        return {name: getattr(out, name) for name, _ in ffi.typeof(ctype).fields}

    def line_stats(self, line: int, what: str) -> Dict[str, int]:
        return self._counters(lib.co_rt_line_stats, "co_line_stats_t", line, what)

    def membus_comm_event(self, line: int, event: int, what: str) -> None:
        self._call(what, lib.co_rt_membus_comm_event, line, event)

    def event_stats(self, line: int, what: str) -> Dict[str, int]:
        return self._counters(lib.co_rt_event_stats, "co_rt_event_stats_t", line, what)

    def driver_stats(self, line: int, what: str) -> Dict[str, int]:
        return self._counters(lib.co_rt_driver_stats, "co_rt_driver_stats_t", line, what)

    def service_stats(self, line: int, what: str) -> Dict[str, Union[int, Dict[str, int]]]:
        """{service: {counter: value}} of co_rt_service_stats_t."""
        out = ffi.new("co_rt_service_stats_t *")
        with self._lock:
            rc = lib.co_rt_service_stats(self._live(what), line, out)
            if rc < 0:
                self._raise(rc, what)
        result: Dict[str, Union[int, Dict[str, int]]] = {}
        for name, field in ffi.typeof("co_rt_service_stats_t").fields:
            value = getattr(out, name)
            if field.type.kind == "struct":
                result[name] = {n: getattr(value, n) for n, _ in field.type.fields}
            else:
                result[name] = value
        return result

    def local_state(self, line: int, what: str) -> Optional[int]:
        """The local node's state, None while the line has none (yet)."""
        with self._lock:
            rc = lib.co_rt_local_state(self._live(what), line)
        if rc == lib.CO_RT_ERR_STATE:
            return None
        if rc < 0:
            self._raise(rc, what)
        return rc

    def node_id_at_reset(self, line: int, node_id: int, what: str) -> None:
        """The local node takes node_id at its next reset."""
        with self._lock:
            rc = lib.co_rt_node_id_at_reset(self._live(what), line, node_id)
            if rc < 0:
                self._raise(rc, what)

    def remote_state(self, line: int, node_id: int, what: str) -> int:
        with self._lock:
            rc = lib.co_rt_remote_state(self._live(what), line, node_id)
            if rc < 0:
                self._raise(rc, what)
        return rc

    def remote_states(self, line: int, what: str) -> Dict[int, int]:
        """{node_id: state code} of every node 1..127 the line has heard of."""
        result: Dict[int, int] = {}
        unknown = lib.CO_NMT_UNKNOWN
        with self._lock:
            rt = self._live(what)
            for node_id in range(1, 128):
                rc = lib.co_rt_remote_state(rt, line, node_id)
                if rc < 0:
                    self._raise(rc, what)
                if rc != unknown:
                    result[node_id] = rc
        return result

    # ------------------------------------------------------------ process data and errors
    def _call(self, what: str, fn: Callable[..., int], *args: object) -> int:
        """Call lib.fn(rt, *args) under the lock; a negative status raises."""
        with self._lock:
            rc = fn(self._live(what), *args)
            if rc < 0:
                self._raise(rc, what)
        return rc

    def emcy(self, line: int, fields: Mapping[str, Union[int, bool, bytes]], clear: bool,
             what: str) -> int:
        """Raise (or clear) an error of the local node's EMCY producer:
        0 = sent or queued, 1 = already active, 2 = clear of an error not active."""
        error = ffi.new("co_rt_emcy_t *")
        for name, value in fields.items():
            if name == "msef":
                ffi.memmove(error.msef, bytes(value).ljust(5, b"\0"), 5)
            else:
                setattr(error, name, value)
        return self._call(what, lib.co_rt_emcy, line, error, int(clear))

    def emcy_state(self, line: int, what: str) -> Dict[str, int]:
        out = ffi.new("co_rt_emcy_state_t *")
        self._call(what, lib.co_rt_emcy_state, line, out)
        return {name: getattr(out, name)
                for name, _ in ffi.typeof("co_rt_emcy_state_t").fields}

    def errors_define(self, line: int, bit: int, code: int, register_bits: int,
                      what: str) -> None:
        self._call(what, lib.co_rt_errors_define, line, bit, code, register_bits)

    def errors_report(self, line: int, bit: int, info: int, reset: bool, what: str) -> int:
        """0 = set / cleared (EMCY sent or queued), 1 = already set, 2 = reset of a
        clear bit."""
        return self._call(what, lib.co_rt_errors_report, line, bit, info, int(reset))

    def errors_condition(self, line: int, register_bit: int, mask: bytes, what: str) -> None:
        self._call(what, lib.co_rt_errors_condition, line, register_bit, mask)

    def errors_expose(self, line: int, index: int, what: str) -> None:
        self._call(what, lib.co_rt_errors_expose, line, index)

    def errors_state(self, line: int, what: str) -> "ErrorsState":
        out = ffi.new("co_rt_errors_state_t *")
        self._call(what, lib.co_rt_errors_state, line, out)
        return ErrorsState(bytes(out.bits), int(out.error_register), int(out.bits_register),
                           [int(c) for c in out.codes], [int(c) for c in out.classes],
                           [int(c) for c in out.counts])

    def emcy_watch(self, line: int, node_id: int, watch: bool, what: str) -> None:
        self._call(what, lib.co_rt_emcy_watch, line, node_id, int(watch))

    def pdo_trigger(self, line: int, number: int, what: str) -> None:
        self._call(what, lib.co_rt_pdo_trigger, line, number)

    def pdo_trigger_object(self, line: int, index: int, sub: int, what: str) -> int:
        return self._call(what, lib.co_rt_pdo_trigger_object, line, index, sub)

    def mpdo_send_dam(self, line: int, number: int, node: int, index: int, sub: int,
                      data: bytes, what: str) -> None:
        self._call(what, lib.co_rt_mpdo_send_dam, line, number, node, index, sub, data, len(data))

    def mpdo_send_dam_mapped(self, line: int, number: int, node: int, what: str) -> None:
        self._call(what, lib.co_rt_mpdo_send_dam_mapped, line, number, node)

    def mpdo_listen(self, line: int, listen: bool, what: str) -> None:
        self._call(what, lib.co_rt_mpdo_listen, line, int(listen))

    def mpdo_send_sam(self, line: int, number: int, index: int, sub: int, what: str) -> None:
        self._call(what, lib.co_rt_mpdo_send_sam, line, number, index, sub)

    def mpdo_stats(self, line: int, what: str) -> Dict[str, int]:
        out = ffi.new("co_mpdo_stats_t *")
        self._call(what, lib.co_rt_mpdo_stats, line, out)
        return {name: getattr(out, name) for name, _ in ffi.typeof("co_mpdo_stats_t").fields}

    def pdo_listen(self, line: int, number: int, listen: bool, what: str) -> None:
        self._call(what, lib.co_rt_pdo_listen, line, number, int(listen))

    def pdo_watch(self, line: int, can_id: int, watch: bool, what: str) -> None:
        """Hear (CO_EV_PDO_FRAME) every data frame on can_id (bit 29: a 29-bit
        id), e.g. another node's TPDO; watch=False stops."""
        self._call(what, lib.co_rt_pdo_watch, line, can_id, int(watch))

    # A master producing other nodes' RPDOs (co_rt_rpdo_*): a slot per RPDO.
    def rpdo_open(self, line: int, can_id: int, length: int, what: str) -> int:
        """A producer of can_id (bit 29: 29-bit) carrying length bytes, all 0:
        its slot."""
        return self._call(what, lib.co_rt_rpdo_open, line, can_id, length)

    def rpdo_close(self, line: int, slot: int, what: str) -> None:
        self._call(what, lib.co_rt_rpdo_close, line, slot)

    def rpdo_write(self, line: int, slot: int, bit_offset: int, bit_length: int,
                   value: bytes, what: str) -> None:
        """Put the low bit_length bits of value (little endian) at bit_offset."""
        self._call(what, lib.co_rt_rpdo_write, line, slot, bit_offset, bit_length,
                   value, len(value))

    def rpdo_read(self, line: int, slot: int, length: int, what: str) -> bytes:
        out = ffi.new("uint8_t[]", max(length, 1))
        n = self._call(what, lib.co_rt_rpdo_read, line, slot, out, length)
        return bytes(ffi.buffer(out, n))

    def rpdo_send(self, line: int, slot: int, what: str) -> None:
        self._call(what, lib.co_rt_rpdo_send, line, slot)

    def rpdo_sync(self, line: int, slot: int, every: int, acyclic: bool, what: str) -> None:
        self._call(what, lib.co_rt_rpdo_sync, line, slot, every, int(acyclic))

    def rpdo_start(self, line: int, slot: int, period_us: int, what: str) -> None:
        self._call(what, lib.co_rt_rpdo_start, line, slot, period_us)

    def rpdo_stop(self, line: int, slot: int, what: str) -> None:
        self._call(what, lib.co_rt_rpdo_stop, line, slot)

    def rpdo_stats(self, line: int, slot: int, what: str) -> Dict[str, int]:
        out = ffi.new("co_rt_rpdo_stats_t *")
        self._call(what, lib.co_rt_rpdo_stats, line, slot, out)
        return {name: getattr(out, name)
                for name, _ in ffi.typeof("co_rt_rpdo_stats_t").fields}

    def sync_producer(self, line: int, period_us: int, window_us: int, overflow: int,
                      what: str) -> None:
        self._call(what, lib.co_rt_sync_producer, line, period_us, window_us, overflow)

    def sync_listen(self, line: int, listen: bool, what: str) -> None:
        self._call(what, lib.co_rt_sync_listen, line, int(listen))

    def led_listen(self, line: int, listen: bool, what: str) -> None:
        self._call(what, lib.co_rt_led_listen, line, int(listen))

    def led_state(self, line: int, what: str) -> Tuple[Tuple[int, int], Tuple[bool, bool], int]:
        """((run pattern, error pattern), (run lit, error lit), cause bits)."""
        out = ffi.new("co_rt_led_state_t *")
        self._call(what, lib.co_rt_led_state, line, out)
        return ((int(out.pattern[0]), int(out.pattern[1])),
                (bool(out.on[0]), bool(out.on[1])), int(out.causes))

    def led_causes(self, line: int, mask: int, active: int, what: str) -> None:
        self._call(what, lib.co_rt_led_causes, line, mask, active)

    def time_send(self, line: int, unix_us: int, what: str) -> None:
        self._call(what, lib.co_rt_time_send, line, unix_us)

    # ---------------------------------------------------------------- SRDO and GFC
    def srdo_start(self, line: int, count: int, what: str) -> None:
        self._call(what, lib.co_rt_srdo_start, line, count)

    def srdo_configure(self, line: int, number: int, fields: Mapping[str, int],
                       mapping: Sequence[int], valid: int, signature: int, what: str) -> None:
        config = _srdo_config(fields, mapping)
        self._call(what, lib.co_rt_srdo_configure, line, number, config, valid, signature)

    def srdo_set_data(self, line: int, number: int, data: bytes, what: str) -> None:
        self._call(what, lib.co_rt_srdo_set_data, line, number, data, len(data))

    def srdo_read(self, line: int, number: int, what: str) -> Tuple[int, int, bytes, Dict[str, int]]:
        """(state, violation, valid data (b'' when not valid), counters)."""
        out = ffi.new("co_rt_srdo_status_t *")
        self._call(what, lib.co_rt_srdo_read, line, number, out)
        stats = {name: getattr(out.stats, name) for name, _ in ffi.typeof("co_srdo_stats_t").fields}
        return out.state, out.violation, bytes(out.data[0:out.length]), stats

    def srdo_restart(self, line: int, number: int, what: str) -> None:
        self._call(what, lib.co_rt_srdo_restart, line, number)

    def gfc_enable(self, line: int, on: bool, what: str) -> None:
        self._call(what, lib.co_rt_gfc_enable, line, on)

    def gfc_send(self, line: int, what: str) -> None:
        self._call(what, lib.co_rt_gfc_send, line)

    def gfc_stats(self, line: int, what: str) -> Dict[str, int]:
        out = ffi.new("co_gfc_stats_t *")
        self._call(what, lib.co_rt_gfc_stats, line, out)
        return {name: getattr(out, name) for name, _ in ffi.typeof("co_gfc_stats_t").fields}

    # ---------------------------------------------------------------- CiA 401 I/O device
    def cia401_start(self, line: int, what: str) -> None:
        self._call(what, lib.co_rt_cia401_start, line)

    def cia401_set_inputs(self, line: int, first: int, raw: bytes, what: str) -> None:
        self._call(what, lib.co_rt_cia401_set_inputs, line, first, raw, len(raw))

    def cia401_set_analog_input(self, line: int, channel: int, value: int, what: str) -> None:
        self._call(what, lib.co_rt_cia401_set_analog_input, line, channel, value)

    def cia401_fault(self, line: int, what: str) -> None:
        self._call(what, lib.co_rt_cia401_fault, line)

    def cia401_outputs(self, line: int, groups: int, channels: int, what: str
                       ) -> Tuple[bytes, Tuple[int, ...]]:
        """The physical outputs: one byte per digital group, the analogue values."""
        digital = ffi.new("uint8_t[]", max(groups, 1))
        analog = ffi.new("int32_t[]", max(channels, 1))
        self._call(what, lib.co_rt_cia401_outputs, line, digital, groups, analog, channels)
        return bytes(digital[0:groups]), tuple(int(v) for v in analog[0:channels])

    # ---------------------------------------------------------------- CiA 402 simulated drive
    def cia402_sim_start(self, line: int, tick_us: int, what: str) -> None:
        self._call(what, lib.co_rt_cia402_sim_start, line, tick_us)

    def cia402_sim_fault(self, line: int, code: int, what: str) -> None:
        self._call(what, lib.co_rt_cia402_sim_fault, line, code)

    def sleep_start(self, line: int, master: bool, check_ms: int, prepare_ms: int,
                    silent_ms: int, wake_repeat_ms: int, objection: int, what: str) -> None:
        config = ffi.new("co_rt_sleep_config_t *")
        config.master = int(master)
        config.check_ms = check_ms
        config.prepare_ms = prepare_ms
        config.silent_ms = silent_ms
        config.wake_repeat_ms = wake_repeat_ms
        config.objection = objection
        self._call(what, lib.co_rt_sleep_start, line, config)

    def sleep_stop(self, line: int, what: str) -> None:
        self._call(what, lib.co_rt_sleep_stop, line)

    def sleep_objection(self, line: int, reason: int, what: str) -> None:
        self._call(what, lib.co_rt_sleep_objection, line, reason)

    def sleep_act(self, line: int, action: int, status: int, reason: int, what: str) -> None:
        self._call(what, lib.co_rt_sleep_act, line, action, status, reason)

    def flyma_start(self, line: int, priority: int, timing_ms: Mapping[str, int],
                    what: str) -> None:
        """timing_ms: co_rt_flyma_config_t's *_ms fields (0 = the default)."""
        config = ffi.new("co_rt_flyma_config_t *")
        config.priority = priority
        for name, value in timing_ms.items():
            setattr(config, name, value)
        self._call(what, lib.co_rt_flyma_start, line, config)

    def flyma_stop(self, line: int, what: str) -> None:
        self._call(what, lib.co_rt_flyma_stop, line)

    def flyma_act(self, line: int, action: int, what: str) -> None:
        self._call(what, lib.co_rt_flyma_act, line, action)

    def flyma_state(self, line: int, what: str) -> Tuple[int, int, int, Dict[str, int]]:
        """(state, active master, its priority, counters) of the local node's flying master."""
        out = ffi.new("co_rt_flyma_state_t *")
        self._call(what, lib.co_rt_flyma_state, line, out)
        return out.state, out.master, out.master_priority, {
            name: getattr(out.stats, name) for name, _ in ffi.typeof("co_flyma_stats_t").fields}

    def sleep_state(self, line: int, what: str) -> Tuple[int, Dict[str, int]]:
        """(phase, counters) of the line's sleep service."""
        stats = ffi.new("co_sleep_stats_t *")
        phase = self._call(what, lib.co_rt_sleep_state, line, stats)
        return phase, {name: getattr(stats, name)
                       for name, _ in ffi.typeof("co_sleep_stats_t").fields}

    def redundancy_start(self, line: int, redundant: str, master: bool,
                         values: Mapping[str, int], what: str) -> None:
        """values: co_rt_redundancy_config_t's integer fields."""
        config = ffi.new("co_rt_redundancy_config_t *")
        name = ffi.new("char[]", redundant.encode())
        config.redundant = name
        config.master = int(master)
        for field, value in values.items():
            setattr(config, field, value)
        self._call(what, lib.co_rt_redundancy_start, line, config)

    def redundancy_select(self, line: int, bus: int, what: str) -> None:
        self._call(what, lib.co_rt_redundancy_select, line, bus)

    def redundancy_state(self, line: int, what: str) -> Tuple[int, Tuple[int, ...]]:
        """(active bus, the redundancy object's subs 0..4)."""
        out = ffi.new("uint8_t[5]")
        active = self._call(what, lib.co_rt_redundancy_state, line, out)
        return active, tuple(out)

    def gateway_join(self, line: int, network_id: int, what: str) -> None:
        self._call(what, lib.co_rt_gateway_join, line, network_id)

    def gateway_network(self, line: int, what: str) -> int:
        return self._call(what, lib.co_rt_gateway_network, line)

    def gateway_route(self, net: int, via_net: int, node_id: int, what: str) -> None:
        self._call(what, lib.co_rt_gateway_route, net, via_net, node_id, ffi.NULL)

    def gateway_resolve(self, net: int, what: str) -> Tuple[int, int, int]:
        """(co_gateway_route_kind_t, line index or -1, gateway node or 0)."""
        line = ffi.new("int *")
        node = ffi.new("uint8_t *")
        kind = self._call(what, lib.co_rt_gateway_resolve, net, line, node)
        return kind, int(line[0]), int(node[0])

    def gateway_emcy_route(self, line: int, node_id: int, networks: int, what: str) -> None:
        self._call(what, lib.co_rt_gateway_emcy_route, line, node_id, networks)

    def gateway_sdo_buffering(self, on: bool, what: str) -> None:
        self._call(what, lib.co_rt_gateway_sdo_buffering, on)

    def gateway_stats(self, what: str) -> Dict[str, int]:
        out = ffi.new("co_gateway_stats_t *")
        self._call(what, lib.co_rt_gateway_stats, out)
        return {name: getattr(out, name) for name, _ in ffi.typeof("co_gateway_stats_t").fields}

    def guard(self, line: int, node_id: int, guard_ms: int, life_factor: int,
              what: str) -> None:
        self._call(what, lib.co_rt_guard, line, node_id, guard_ms, life_factor)

    def lss_start(self, line: int, kind: int, values: Sequence[int], node_ids: Sequence[int],
                  timeout_ms: int, what: str, settle_ms: int = 0,
                  fastscan_filter: Sequence[Tuple[int, int]] = ()) -> None:
        """Start a request of the line's LSS master (co_rt_lss_start);
        fastscan_filter: (kind, match value) per part of the address."""
        request = ffi.new("co_rt_lss_request_t *")
        request.kind = kind
        for i, value in enumerate(values):
            request.value[i] = value
        for i, node_id in enumerate(node_ids):
            request.node_ids[i] = node_id
        request.node_id_count = len(node_ids)
        for i, (part_kind, match) in enumerate(fastscan_filter):
            request.fs_kind[i] = part_kind
            request.fs_match[i] = match
        request.timeout_ms = timeout_ms
        request.settle_ms = settle_ms
        self._call(what, lib.co_rt_lss_start, line, request)

    def lss_cancel(self, line: int, what: str) -> None:
        """End the running LSS request with CO_LSS_CANCELLED (co_rt_lss_cancel)."""
        self._call(what, lib.co_rt_lss_cancel, line)

    def lss_result(self, line: int, what: str
                   ) -> Tuple[Dict[str, int], List[Tuple[Tuple[int, int, int, int], int]]]:
        """The last finished LSS request: its co_lss_master_result_t fields and
        the devices it found as ((vendor, product, revision, serial), node_id)."""
        out = ffi.new("co_lss_master_result_t *")
        devices = ffi.new("co_rt_lss_device_t[127]")
        count = self._call(what, lib.co_rt_lss_result, line, out, devices, 127)
        result = {name: getattr(out, name)
                  for name, _ in ffi.typeof("co_lss_master_result_t").fields}
        found: List[Tuple[Tuple[int, int, int, int], int]] = []
        for i in range(count):
            a = devices[i].address
            found.append(((a[0], a[1], a[2], a[3]), devices[i].node_id))
        return result, found

    def lss_stats(self, line: int, what: str) -> Dict[str, int]:
        out = ffi.new("co_lss_master_stats_t *")
        self._call(what, lib.co_rt_lss_stats, line, out)
        return {name: getattr(out, name)
                for name, _ in ffi.typeof("co_lss_master_stats_t").fields}

    def lss_slave_config(self, line: int, store: bool, bit_timings: int, what: str) -> None:
        self._call(what, lib.co_rt_lss_slave_config, line, int(store), bit_timings)

    def lss_slave_answer(self, line: int, error: int, what: str) -> None:
        self._call(what, lib.co_rt_lss_slave_answer, line, error)

    def lss_slave_info(self, line: int, what: str) -> Tuple[int, int, int, int]:
        out = ffi.new("uint8_t[4]")
        self._call(what, lib.co_rt_lss_slave_info, line, out)
        return out[0], out[1], out[2], out[3]
    # ---------------------------------------------------------------- network manager
    def manager_start(self, line: int, hooks: int, parallel: int, retry_ms: int,
                      what: str) -> None:
        self._call(what, lib.co_rt_manager_start, line, hooks, parallel, retry_ms)

    def manager_stop(self, line: int, what: str) -> None:
        self._call(what, lib.co_rt_manager_stop, line)

    def manager_continue(self, line: int, answer: int, node_id: int, done: bool,
                         what: str) -> None:
        self._call(what, lib.co_rt_manager_continue, line, answer, node_id, int(done))

    def manager_state(self, line: int, node_id: int, what: str) -> Optional[int]:
        """The manager's phase (node_id 0) or a slave's status | error << 8; None
        while no manager runs."""
        with self._lock:
            rc = lib.co_rt_manager_state(self._live(what), line, node_id)
        if rc == lib.CO_RT_ERR_STATE:
            return None
        if rc < 0:
            self._raise(rc, what)
        return rc

    def host_receive(self, line: int, cframe: CData) -> int:
        """Hand a frame to a host-driver line; returns the status (no raise:
        the caller is a bridge thread that decides what to do)."""
        with self._lock:
            if self._stopped or self._rt == ffi.NULL:
                return lib.CO_RT_ERR_CLOSED
            return lib.co_rt_host_receive(self._rt, line, cframe)

    # The two blocking waits run without the lock (they may block for a while);
    # Network.close() joins their threads before free(), so _rt stays valid.
    def read_events(self, timeout_ms: int) -> Optional[List[Event]]:
        """The events posted since the last call (up to EVENT_BATCH), waiting up
        to timeout_ms for one; None once the runtime stopped. One thread only
        (the dispatcher): the buffer is reused."""
        rt = self._rt
        if rt == ffi.NULL:
            return None
        n = lib.co_rt_wait_events(rt, self._events, EVENT_BATCH, timeout_ms)
        if n < 0:
            return None   # CO_RT_ERR_CLOSED
        return [_event(self._events[i]) for i in range(n)]

    def host_receive_frames(self, line: int, frames: CData, count: int, timeout_ms: int) -> int:
        """Hand count frames to a host-driver line, waiting up to timeout_ms
        while its rx queue is full (back-pressure); returns how many it took
        or CO_RT_ERR_CLOSED. Runs without the lock, like host_transmit."""
        rt = self._rt
        if rt == ffi.NULL or self._stopped:
            return lib.CO_RT_ERR_CLOSED
        return lib.co_rt_host_receive_frames(rt, line, frames, count, timeout_ms)

    def host_transmit(self, line: int, frames: CData, max_frames: int, timeout_ms: int) -> int:
        rt = self._rt
        if rt == ffi.NULL:
            return lib.CO_RT_ERR_CLOSED
        return lib.co_rt_host_transmit(rt, line, frames, max_frames, timeout_ms)


# Plain ints: every event is compared with these on the dispatcher thread, and
# an IntEnum member lookup costs ~0.1 us each.
_EV_FRAME = int(EventKind.FRAME)
_EV_PDO_FRAME = int(EventKind.PDO_FRAME)
_EV_WITH_DATA = (int(EventKind.EMCY), int(EventKind.PDO), int(EventKind.MANAGER),
                 int(EventKind.MPDO), int(EventKind.CIA401))


def _event(ev: CData) -> Event:
    """An Event from a co_rt_event_t (cdata)."""
    kind = ev.kind
    frame = None
    data = b""
    if kind == _EV_FRAME:
        frame = frame_from_c(ev.frame, timestamp=ev.time_us / 1e6, tx=bool(ev.a))
    elif kind == _EV_PDO_FRAME:
        frame = frame_from_c(ev.frame, timestamp=ev.time_us / 1e6)
    elif kind in _EV_WITH_DATA:
        # the encoded EMCY / the RPDO's mapped values / a boot report's details /
        # an MPDO and where it went / a CiA 401 device's outputs (no CAN frame flags)
        data = bytes(ffi.buffer(ev.frame.data, min(ev.frame.len, 64)))
    return Event(kind, ev.line, ev.node, ev.a, ev.b, ev.time_us, frame, data, ev.coalesced)


class ErrorsState(NamedTuple):
    """The local node's error bits (co_rt_errors_state_t): per bit its code
    table entry (code 0 = not defined) and report count."""
    bits: bytes
    error_register: int
    bits_register: int
    codes: List[int]
    classes: List[int]
    counts: List[int]


class EmcyFields(NamedTuple):
    """Every field of an EMCY (co_emcy_msg_t); the FD-only ones are 0 on classic."""
    code: int
    error_register: int
    msef: bytes
    logical_device: int
    spec_number: int
    status: int
    time_stamp: int


def decode_emcy(data: bytes, fd: bool) -> Optional[EmcyFields]:
    """The fields of an EMCY, decoded by the C codec; None when malformed."""
    out = ffi.new("co_emcy_msg_t *")
    decode = lib.co_emcy_decode_fd if fd else lib.co_emcy_decode_classic
    if not decode(data, len(data), out):
        return None
    return EmcyFields(int(out.code), int(out.error_register), bytes(ffi.buffer(out.msef, 5)),
                      int(out.logical_device), int(out.spec_number), int(out.status),
                      int(out.time_stamp))


def _srdo_config(fields: Mapping[str, int], mapping: Sequence[int]) -> CData:
    """A co_srdo_config_t of checked fields (see services/srdo.py) and mapping."""
    config = ffi.new("co_srdo_config_t *")
    for name, value in fields.items():
        setattr(config, name, value)
    config.map_count = len(mapping)
    for i, entry in enumerate(mapping):
        config.map[i] = entry
    return config


def srdo_crc(fields: Mapping[str, int], mapping: Sequence[int]) -> int:
    """The core's 0x13FF CRC of a configuration (co_srdo_crc): one byte
    layout for the device and for a tool computing it."""
    return int(lib.co_srdo_crc(_srdo_config(fields, mapping)))


def now_us() -> int:
    return lib.co_rt_now_us()
