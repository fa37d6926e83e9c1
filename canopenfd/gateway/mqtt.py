"""The MQTT side of a gateway: process data, EMCYs, NMT states and boot-ups of
watched nodes published to an existing MQTT broker, and SDO/USDO reads and
writes and NMT commands taken from it (issue 16, part 5).

Topics (`canopen/<gateway>/<net>/<node>/...`, the hierarchy proposed for
CiA 309 gateways with the gateway's name and the node added):

    canopen/<gw>/status                      "online" / "offline" (retained; the
                                             broker sends "offline" when we vanish)
    canopen/<gw>/<net>/<node>/pdo/<name>     a mapped value, JSON (retained, value_qos)
    canopen/<gw>/<net>/<node>/state          NMT state or "LOST" (retained, event_qos)
    canopen/<gw>/<net>/<node>/bootup         JSON {"time": ...} (event_qos)
    canopen/<gw>/<net>/<node>/emcy           JSON, every EMCY field (event_qos)
    canopen/<gw>/<net>/<node>/cmd/read       {"id": .., "key": "0x1018:1"} or index/sub
    canopen/<gw>/<net>/<node>/cmd/write      {"id": .., "key": .., "value": ..} or "data": hex
    canopen/<gw>/<net>/<node>/cmd/nmt        {"id": .., "command": "start"}
    canopen/<gw>/<net>/cmd/nmt               the same for every node of the net
    canopen/<gw>/<net>/<node>/reply          {"id": .., "ok": true, "value": ..} or
                                             {"id": .., "ok": false, "error": .., "abort": ..}

A request carrying MQTT 5 "response topic" / "correlation data" is answered
there with that correlation data; `reply_to` in the JSON payload does the same
for MQTT 3.1.1 clients. Values are JSON numbers, strings and booleans; bytes
travel as hex strings. Commands run on a small pool of worker threads (a
transfer waits for the bus, the MQTT network thread must not); beyond
`max_pending` queued commands a request is answered "busy" at once.
Events published with QoS >= 1 while the broker is away are queued by the
client (up to `max_queued`) and sent after the reconnect; what does not fit is
counted in `stats["dropped"]`, like QoS 0 values published while away.
"""

from __future__ import annotations

import json
import logging
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Any, Callable, Dict, List, Mapping, Optional, Tuple, Union

from ..errors import AbortError, CanopenFDError, ConfigurationError
from ..od.datatypes import TimeDifference, TimeOfDay
from ..services.emcy import Emcy
from ..services.pdo import PdoMap
from .node_turns import taking_turn

try:
    import paho.mqtt.client as _paho
    from paho.mqtt.enums import CallbackAPIVersion
    from paho.mqtt.properties import Properties
    from paho.mqtt.packettypes import PacketTypes
except ImportError:  # pragma: no cover - the error names the extra to install
    _paho = None  # type: ignore[assignment]

log = logging.getLogger(__name__)

ROOT = "canopen"
_NMT_VERBS = ("start", "stop", "pre_operational", "reset_node", "reset_communication")
_NMT_ALIASES = {"preop": "pre_operational", "preoperational": "pre_operational",
                "reset": "reset_node", "reset_comm": "reset_communication"}
#: Seconds a command waits while other requests hold its node (node_turns).
TURN_TIMEOUT = 60.0
_TOPIC_UNSAFE = str.maketrans({"/": "_", "+": "_", "#": "_", "\0": "_"})


def topic_part(name: str) -> str:
    """A name usable as one topic level (no '/', '+', '#')."""
    return name.translate(_TOPIC_UNSAFE)


def json_value(value: object) -> object:
    """A typed OD value as JSON: bytes become a hex string, TIME_OF_DAY and
    TIME_DIFFERENCE {"ms": .., "days": ..} (json.dumps knows neither)."""
    if isinstance(value, (bytes, bytearray, memoryview)):
        return bytes(value).hex()
    if isinstance(value, (TimeOfDay, TimeDifference)):
        return {"ms": value.ms, "days": value.days}
    return value


def emcy_json(emcy: Emcy) -> Dict[str, object]:
    fields: Dict[str, object] = {"code": emcy.code, "register": emcy.register,
                                 "data": emcy.data.hex(), "fd": emcy.fd,
                                 "time": emcy.timestamp}
    if emcy.fd:
        fields.update(logical_device=emcy.logical_device, spec_number=emcy.spec_number,
                      status=emcy.status, time_stamp=emcy.time_stamp)
    return fields


class CommandFailed(CanopenFDError):
    """A command from the broker that cannot be carried out (its text is the
    reply's "error")."""


class _Request:
    """Where and how a command is answered."""

    def __init__(self, topic: str, correlation: Optional[bytes], request_id: object) -> None:
        self.topic = topic
        self.correlation = correlation
        self.request_id = request_id


class MqttBridge:
    """Publishes what watched nodes do and serves commands, through `broker`.

    lines: {net_id: Line} (net ids 1..127). gateway: this gateway's topic
    level. value_qos: QoS of PDO values (retained); event_qos: QoS of states,
    boot-ups, EMCYs and replies. Start with `start()` (or `with`), watch nodes
    with `watch(net, node_id, pdos=...)`.
    """

    def __init__(self, lines: Mapping[int, Any], broker: str = "localhost", port: int = 1883,
                 *, gateway: str = "gateway", client_id: Optional[str] = None,
                 value_qos: int = 0, event_qos: int = 1, keepalive: int = 30,
                 max_queued: int = 10000, workers: int = 4, max_pending: int = 64,
                 username: Optional[str] = None, password: Optional[str] = None) -> None:
        if _paho is None:
            raise ConfigurationError("the MQTT gateway needs paho-mqtt: "
                                     "pip install 'canopenfd[mqtt]'")
        where = f"MqttBridge({broker}:{port})"
        for net in lines:
            if not isinstance(net, int) or not 1 <= net <= 127:
                raise ConfigurationError(f"{where}: network id {net!r} is not 1..127")
        if not lines:
            raise ConfigurationError(f"{where}: no line to serve")
        for name, qos in (("value_qos", value_qos), ("event_qos", event_qos)):
            if qos not in (0, 1, 2):
                raise ConfigurationError(f"{where}: {name} must be 0, 1 or 2, got {qos!r}")
        if not gateway or topic_part(gateway) != gateway:
            raise ConfigurationError(f"{where}: gateway name {gateway!r} must be one topic "
                                     "level (no '/', '+', '#')")
        self.lines = dict(lines)
        self.broker = broker
        self.port = port
        self.gateway = gateway
        self.base = f"{ROOT}/{gateway}"
        self.value_qos = value_qos
        self.event_qos = event_qos
        self._keepalive = keepalive
        self._max_pending = max_pending
        self._lock = threading.Lock()
        self._connected = threading.Event()
        self._pending = 0
        self._closed = False
        self.stats: Dict[str, int] = dict.fromkeys(
            ("published", "dropped", "commands", "command_errors", "bad_commands", "busy",
             "connects", "disconnects"), 0)
        self._workers = ThreadPoolExecutor(max_workers=workers,
                                           thread_name_prefix="canopenfd-mqtt")
        client = _paho.Client(CallbackAPIVersion.VERSION2,
                              client_id=client_id or f"canopenfd-{gateway}",
                              protocol=_paho.MQTTv5)
        if username is not None:
            client.username_pw_set(username, password)
        client.max_queued_messages_set(max_queued)
        client.reconnect_delay_set(min_delay=1, max_delay=5)
        client.will_set(f"{self.base}/status", "offline", qos=1, retain=True)
        client.on_connect = self._on_connect
        client.on_disconnect = self._on_disconnect
        client.on_subscribe = self._on_subscribe
        client.on_message = self._on_message
        self._client = client

    # ------------------------------------------------------------ life
    def start(self, timeout: float = 5.0) -> "MqttBridge":
        """Connect (in the background, reconnecting whenever the broker goes
        away) and wait up to `timeout` s for the first connection; raises
        ConnectionError naming the broker when it did not come."""
        self._client.connect_async(self.broker, self.port, keepalive=self._keepalive)
        self._client.loop_start()
        if not self._connected.wait(timeout):
            self.close()
            raise ConnectionError(f"MQTT broker {self.broker}:{self.port} did not accept a "
                                  f"connection within {timeout} s")
        return self

    def wait_connected(self, timeout: Optional[float] = None) -> bool:
        return self._connected.wait(timeout)

    @property
    def connected(self) -> bool:
        return self._connected.is_set()

    def close(self) -> None:
        """Stop publishing and serving, say "offline", disconnect."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
        self._workers.shutdown(wait=True)
        if self._connected.is_set():
            info = self._client.publish(f"{self.base}/status", "offline", qos=1, retain=True)
            try:
                info.wait_for_publish(timeout=2)
            except (RuntimeError, ValueError):
                pass
        self._client.disconnect()
        self._client.loop_stop()

    def __enter__(self) -> "MqttBridge":
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------ publishing
    def publish(self, topic: str, payload: object, qos: int, retain: bool = False) -> None:
        """Publish JSON `payload` (a str is sent as it is) below this gateway
        (nothing once closed: the watched nodes' callbacks stay registered)."""
        if self._closed:
            return
        text = payload if isinstance(payload, str) else json.dumps(payload)
        info = self._client.publish(f"{self.base}/{topic}", text, qos=qos, retain=retain)
        queued = info.rc == _paho.MQTT_ERR_SUCCESS or (
            qos > 0 and info.rc == _paho.MQTT_ERR_NO_CONN)
        with self._lock:
            self.stats["published" if queued else "dropped"] += 1

    def watch(self, net: int, node_id: int, od: Any = None, *, pdos: Optional[str] = "od",
              heartbeat_timeout_ms: Optional[int] = None) -> Any:
        """Publish node `node_id` of network `net`: its NMT states, heartbeat
        loss, boot-ups and EMCYs, and the values of its TPDOs by name (pdos:
        "od" = the mapping its OD/DCF describes, "node" = read from the node
        now, None = no PDOs). Returns the line's RemoteNode."""
        line = self._line(net, f"watch({net}, {node_id})")
        node = line.add_node(node_id, od=od, heartbeat_timeout_ms=heartbeat_timeout_ms)
        prefix = f"{net}/{node_id}"
        state_qos = self.event_qos

        state_lock = threading.Lock()   # the last state published is the node's state

        def state(new: Any) -> None:
            with state_lock:
                self.publish(f"{prefix}/state", getattr(new, "name", str(new)), state_qos,
                             True)

        def lost() -> None:
            self.publish(f"{prefix}/state", "LOST", state_qos, True)

        def bootup() -> None:
            self.publish(f"{prefix}/bootup", {"time": time.time()}, self.event_qos)

        def emcy(event: Emcy) -> None:
            self.publish(f"{prefix}/emcy", emcy_json(event), self.event_qos)

        node.on_state_change(state)
        node.on_heartbeat_lost(lost)
        node.on_bootup(bootup)
        node.emcy.add_callback(emcy)
        with state_lock:     # a state heard before the watch began: told at once
            if node.state.name != "UNKNOWN":
                self.publish(f"{prefix}/state", node.state.name, state_qos, True)
        if pdos is not None:
            self._watch_pdos(node, prefix, pdos)
        return node

    def _watch_pdos(self, node: Any, prefix: str, source: str) -> None:
        if source not in ("od", "node"):
            raise ConfigurationError(f"watch: pdos must be 'od', 'node' or None, got {source!r}")
        if node.object_dictionary is None:
            raise ConfigurationError(f"watch: node {node.node_id} has no object dictionary "
                                     "to name its PDO values (give od=...) or pass pdos=None")
        node.tpdo.read(from_od=(source == "od"))
        for number in node.tpdo:
            pdo = node.tpdo[number]
            if pdo.enabled and len(pdo):
                pdo.add_callback(self._pdo_publisher(prefix))

    def _pdo_publisher(self, prefix: str) -> Callable[[PdoMap], None]:
        def publish(pdo: PdoMap) -> None:
            for variable in pdo:
                if variable.is_dummy:
                    continue
                self.publish(f"{prefix}/pdo/{topic_part(variable.name)}",
                             json_value(variable.raw), self.value_qos, True)
        return publish

    # ------------------------------------------------------------ commands
    def _line(self, net: int, where: str) -> Any:
        line = self.lines.get(net)
        if line is None:
            raise ConfigurationError(f"{where}: no network {net} (known: "
                                     f"{sorted(self.lines)})")
        return line

    def _on_connect(self, client: Any, userdata: object, flags: object, reason: Any,
                    properties: object = None) -> None:
        if getattr(reason, "is_failure", False):
            log.warning("MQTT broker %s:%s refused the connection: %s", self.broker,
                        self.port, reason)
            return
        # connected counts once the command topics are subscribed (on_subscribe)
        client.subscribe([(f"{self.base}/+/+/cmd/+", 1), (f"{self.base}/+/cmd/+", 1)])
        client.publish(f"{self.base}/status", "online", qos=1, retain=True)
        with self._lock:
            self.stats["connects"] += 1

    def _on_subscribe(self, client: object, userdata: object, mid: int, reasons: object,
                      properties: object = None) -> None:
        self._connected.set()

    def _on_disconnect(self, client: object, userdata: object, flags: object, reason: object,
                       properties: object = None) -> None:
        self._connected.clear()
        with self._lock:
            self.stats["disconnects"] += 1
        if not self._closed:
            log.warning("MQTT broker %s:%s went away (%s); reconnecting", self.broker,
                        self.port, reason)

    def _on_message(self, client: object, userdata: object, message: Any) -> None:
        """On the MQTT network thread: parse, then hand the work to a worker.
        Nothing may escape: paho re-raises a callback's exception and its
        network thread (every publish and command) ends with it."""
        try:
            self._take(message)
        except Exception:  # noqa: BLE001 - logged and counted, the bridge goes on
            log.exception("MQTT gateway: command on %r failed", message.topic)
            with self._lock:
                self.stats["command_errors"] += 1

    def _take(self, message: Any) -> None:
        parts = message.topic[len(self.base) + 1:].split("/")
        props = getattr(message, "properties", None)
        reply_topic = getattr(props, "ResponseTopic", None)
        correlation = getattr(props, "CorrelationData", None)
        try:
            request = json.loads(message.payload or b"{}")
        except (ValueError, RecursionError):    # nested too deep is not JSON to us
            request = None
        request_id = request.get("id") if isinstance(request, dict) else None
        if isinstance(request, dict) and isinstance(request.get("reply_to"), str):
            reply_topic = reply_topic or request["reply_to"]
        try:
            net, node_id, verb = self._parse_topic(parts)
        except CommandFailed as exc:
            with self._lock:
                self.stats["bad_commands"] += 1
            self._reply(_Request(reply_topic or f"{self.base}/reply", correlation, request_id),
                        error=str(exc))
            return
        default_reply = f"{self.base}/{net}/{node_id}/reply" if node_id else \
            f"{self.base}/{net}/reply"
        where = _Request(reply_topic or default_reply, correlation, request_id)
        if not isinstance(request, dict):
            with self._lock:
                self.stats["bad_commands"] += 1
            self._reply(where, error=f"{verb}: the payload must be a JSON object, got "
                                     f"{bytes(message.payload[:40])!r}")
            return
        with self._lock:
            busy = self._pending >= self._max_pending or self._closed
            if not busy:
                self._pending += 1
            self.stats["busy" if busy else "commands"] += 1
        if busy:
            self._reply(where, error=f"busy: {self._max_pending} commands are waiting")
            return
        self._workers.submit(self._run, where, net, node_id, verb, request)

    def _parse_topic(self, parts: List[str]) -> Tuple[int, int, str]:
        # [net, node, "cmd", verb] or [net, "cmd", verb]
        if len(parts) == 4 and parts[2] == "cmd":
            net_text, node_text, verb = parts[0], parts[1], parts[3]
        elif len(parts) == 3 and parts[1] == "cmd":
            net_text, node_text, verb = parts[0], "0", parts[2]
        else:
            raise CommandFailed(f"unknown command topic {'/'.join(parts)!r}")
        try:
            net, node_id = int(net_text), int(node_text)
        except ValueError:
            raise CommandFailed(f"net and node must be numbers: {'/'.join(parts)!r}") from None
        if net not in self.lines:
            raise CommandFailed(f"no network {net} (known: {sorted(self.lines)})")
        if not 0 <= node_id <= 127:
            raise CommandFailed(f"node {node_id} is not 1..127")
        if verb not in ("read", "write", "nmt") or (node_id == 0 and verb != "nmt"):
            raise CommandFailed(f"unknown command {verb!r} for "
                                f"{'node ' + str(node_id) if node_id else 'a network'}")
        return net, node_id, verb

    def _run(self, where: _Request, net: int, node_id: int, verb: str,
             request: Dict[str, Any]) -> None:
        try:
            value = getattr(self, f"_do_{verb}")(self.lines[net], node_id, request)
        except AbortError as exc:
            with self._lock:
                self.stats["command_errors"] += 1
            self._reply(where, error=str(exc), abort=f"0x{exc.code:08X}")
        except (CanopenFDError, ValueError, TypeError, KeyError, OSError) as exc:
            with self._lock:
                self.stats["command_errors"] += 1
            self._reply(where, error=str(exc) or type(exc).__name__)
        except Exception:  # noqa: BLE001 - a fault of ours still gets its answer
            log.exception("MQTT gateway: %s of node %d on network %d failed", verb, node_id,
                          net)
            with self._lock:
                self.stats["command_errors"] += 1
            self._reply(where, error=f"{verb}: internal error (see the gateway's log)")
        else:
            self._reply(where, value=value)
        finally:
            with self._lock:
                self._pending -= 1

    @staticmethod
    def _key(request: Dict[str, Any]) -> Union[str, Tuple[int, int]]:
        if "key" in request:
            key = request["key"]
            if not isinstance(key, str):
                raise CommandFailed(f"key must be a string (name or 'INDEX:SUB'), got {key!r}")
            return key
        index, sub = request.get("index"), request.get("sub", 0)
        if isinstance(index, str):
            index = int(index, 0)
        if isinstance(sub, str):
            sub = int(sub, 0)
        if not isinstance(index, int) or not isinstance(sub, int):
            raise CommandFailed("a read or write names its entry: 'key' or 'index' (+ 'sub')")
        return (index, sub)

    def _do_read(self, line: Any, node_id: int, request: Dict[str, Any]) -> object:
        key = self._key(request)
        with taking_turn(line, node_id, TURN_TIMEOUT):
            return json_value(line.add_node(node_id).read(key))

    def _do_write(self, line: Any, node_id: int, request: Dict[str, Any]) -> object:
        node = line.add_node(node_id)
        key = self._key(request)
        if "data" in request:
            value: Any = bytes.fromhex(str(request["data"]))
        elif "value" in request:
            value = request["value"]
        else:
            raise CommandFailed("write: give 'value' (typed by the node's OD) or 'data' (hex)")
        with taking_turn(line, node_id, TURN_TIMEOUT):
            node.write(key, value)
        return None

    def _do_nmt(self, line: Any, node_id: int, request: Dict[str, Any]) -> object:
        command = str(request.get("command", "")).lower()
        command = _NMT_ALIASES.get(command, command)
        if command not in _NMT_VERBS:
            raise CommandFailed(f"nmt: unknown command {request.get('command')!r} "
                                f"(one of {', '.join(_NMT_VERBS)})")
        getattr(line.nmt, command)(node_id)
        return None

    def _reply(self, where: _Request, *, value: object = None, error: Optional[str] = None,
               abort: Optional[str] = None) -> None:
        body: Dict[str, object] = {"id": where.request_id, "ok": error is None}
        if error is None:
            body["value"] = value
        else:
            body["error"] = error
            if abort is not None:
                body["abort"] = abort
        properties = None
        if where.correlation is not None:
            properties = Properties(PacketTypes.PUBLISH)  # type: ignore[no-untyped-call]
            properties.CorrelationData = where.correlation
        try:
            text = json.dumps(body)
        except (TypeError, ValueError):     # a value JSON cannot hold: said so, not lost
            text = json.dumps({"id": where.request_id, "ok": False,
                               "error": f"the value {value!r:.80} has no JSON form"})
        try:
            info = self._client.publish(where.topic, text, qos=self.event_qos,
                                        properties=properties)
        except ValueError as exc:     # a response topic with wildcards, or empty
            log.warning("MQTT gateway: reply %s to %r not sent: %s", where.request_id,
                        where.topic, exc)
            with self._lock:
                self.stats["dropped"] += 1
            return
        with self._lock:
            self.stats["published" if info.rc in (_paho.MQTT_ERR_SUCCESS,
                                                  _paho.MQTT_ERR_NO_CONN) else "dropped"] += 1
