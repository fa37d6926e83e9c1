"""A real mosquitto broker on loopback for the MQTT gateway tests and bench,
and a subscriber that records what it receives."""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import threading
import time
from pathlib import Path
from typing import Any, List, Optional, Sequence, Tuple

import paho.mqtt.client as mqtt
from paho.mqtt.enums import CallbackAPIVersion

from helpers import Recorder, scaled

MOSQUITTO = shutil.which("mosquitto") or ("/usr/sbin/mosquitto"
                                          if os.path.exists("/usr/sbin/mosquitto") else None)


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _as_root() -> bool:
    return getattr(os, "geteuid", lambda: 1)() == 0


class Broker:
    """mosquitto listening on 127.0.0.1:port, its state kept in `folder` so a
    restart keeps persistent sessions (stop() lets it save them)."""

    def __init__(self, folder: Path, port: Optional[int] = None) -> None:
        if MOSQUITTO is None:
            raise RuntimeError("mosquitto is not installed (Debian package 'mosquitto')")
        self.folder = folder
        self.port = port or free_port()
        self.conf = folder / "mosquitto.conf"
        # As root, mosquitto drops to user "mosquitto", which cannot write its
        # database into our folder: the sessions would not survive a restart.
        user = "user root\n" if _as_root() else ""
        self.conf.write_text(f"listener {self.port} 127.0.0.1\nallow_anonymous true\n"
                             f"persistence true\npersistence_location {folder}/\n"
                             f"max_queued_messages 100000\n{user}", encoding="utf-8")
        self.process: Optional[subprocess.Popen] = None
        self.start()

    def start(self) -> None:
        self.process = subprocess.Popen([str(MOSQUITTO), "-c", str(self.conf)],
                                        stdout=subprocess.DEVNULL,
                                        stderr=open(self.folder / "mosquitto.log", "ab"))
        deadline = time.monotonic() + scaled(10)
        while time.monotonic() < deadline:
            try:
                socket.create_connection(("127.0.0.1", self.port), timeout=0.2).close()
                return
            except OSError:
                if self.process.poll() is not None:
                    break
                time.sleep(0.02)
        raise RuntimeError(f"mosquitto did not listen on {self.port}: "
                           f"{(self.folder / 'mosquitto.log').read_text(errors='replace')}")

    def stop(self) -> None:
        if self.process is not None and self.process.poll() is None:
            self.process.send_signal(signal.SIGTERM)
            self.process.wait(timeout=10)
            if not (self.folder / "mosquitto.db").exists():
                raise RuntimeError("mosquitto did not save its sessions: " +
                                   (self.folder / "mosquitto.log").read_text(errors="replace"))
        self.process = None


class Message:
    __slots__ = ("topic", "payload", "qos", "retain", "correlation")

    def __init__(self, topic: str, payload: bytes, qos: int, retain: bool,
                 correlation: Optional[bytes]) -> None:
        self.topic = topic
        self.payload = payload
        self.qos = qos
        self.retain = retain
        self.correlation = correlation

    @property
    def text(self) -> str:
        return self.payload.decode()

    @property
    def json(self) -> Any:
        return json.loads(self.payload)

    def __repr__(self) -> str:
        return f"<{self.topic} {self.payload[:60]!r} qos {self.qos} retain {self.retain}>"


class Subscriber:
    """A paho client subscribed to `topics` (QoS 1) that records every message.
    persistent: an MQTT 3.1.1 session the broker keeps while we are away."""

    def __init__(self, port: int, topics: Sequence[str], *, client_id: str = "",
                 persistent: bool = False) -> None:
        self.messages = Recorder()
        self._subscribed = threading.Event()
        self._topics = list(topics)
        if persistent:
            client = mqtt.Client(CallbackAPIVersion.VERSION2, client_id=client_id,
                                 protocol=mqtt.MQTTv311, clean_session=False)
        else:
            client = mqtt.Client(CallbackAPIVersion.VERSION2, client_id=client_id,
                                 protocol=mqtt.MQTTv5)
        client.reconnect_delay_set(min_delay=1, max_delay=2)
        client.on_connect = self._on_connect
        client.on_subscribe = lambda *args: self._subscribed.set()
        client.on_message = self._on_message
        self.client = client
        client.connect("127.0.0.1", port)
        client.loop_start()
        if not self._subscribed.wait(scaled(10)):
            raise RuntimeError("the test subscriber did not get its subscription")

    def _on_connect(self, client: Any, userdata: object, flags: object, reason: object,
                    properties: object = None) -> None:
        client.subscribe([(topic, 1) for topic in self._topics])

    def _on_message(self, client: object, userdata: object, message: Any) -> None:
        props = getattr(message, "properties", None)
        self.messages(Message(message.topic, bytes(message.payload), message.qos,
                              bool(message.retain), getattr(props, "CorrelationData", None)))

    def on(self, topic: str) -> List[Message]:
        return [m for m in self.messages.snapshot() if m.topic == topic]

    def wait(self, topic: str, count: int = 1, timeout: float = 5.0) -> List[Message]:
        self.messages.wait_for(lambda calls: len([m for m in calls if m.topic == topic])
                               >= count, timeout, f"{count} message(s) on {topic}")
        return self.on(topic)

    def publish(self, topic: str, payload: Any, **options: Any) -> None:
        text = payload if isinstance(payload, (str, bytes)) else json.dumps(payload)
        self.client.publish(topic, text, qos=1, **options).wait_for_publish(scaled(5))

    def close(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()


def messages_of(messages: List[Message]) -> List[Tuple[str, str]]:
    return [(m.topic, m.text) for m in messages]
