"""A gateway publishing a device's process data, states and EMCYs to an MQTT
broker, and a dashboard (another MQTT client) that watches them and reads an
entry of the device through the broker.

    python3 examples/mqtt_gateway.py [--broker HOST] [--port 1883]

Needs a running broker (e.g. Debian's mosquitto) and paho-mqtt
(pip install 'canopenfd[mqtt]'). The device is simulated on an in-process
bus; on a real gateway the line would be "can0".
"""

import argparse
import json
import queue

import paho.mqtt.client as mqtt
from paho.mqtt.enums import CallbackAPIVersion

import canopenfd
from canopenfd.gateway.mqtt import MqttBridge
from canopenfd.od import demo_od

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("--broker", default="localhost", help="MQTT broker host")
parser.add_argument("--port", type=int, default=1883, help="MQTT broker port")
args = parser.parse_args()

# the dashboard: any MQTT client, here paho
arrived: "queue.Queue[mqtt.MQTTMessage]" = queue.Queue()
dashboard = mqtt.Client(CallbackAPIVersion.VERSION2)
dashboard.on_message = lambda client, userdata, message: arrived.put(message)
dashboard.connect(args.broker, args.port)
dashboard.subscribe("canopen/demo-gw/#", qos=1)
dashboard.loop_start()


def next_message(topic_end: str, payload: str = "") -> mqtt.MQTTMessage:
    """The next message on a topic ending so (with that payload, if given)."""
    while True:
        message = arrived.get(timeout=10)
        if message.topic.endswith(topic_end) and payload in ("", message.payload.decode()):
            return message


with canopenfd.Network() as net:
    line = net.open_line("mem:plant", mode="fd")              # "can0" on a gateway
    device = net.open_line("mem:plant", mode="fd").create_local_node(
        5, od=demo_od("fd", pdos=1), heartbeat_ms=100)
    tpdo = device.tpdo[1]                                      # the device sends a value
    tpdo.read()
    tpdo.clear()
    tpdo.add_variable("Demo UNSIGNED16")
    tpdo.trans_type = 254
    tpdo.enabled = True
    tpdo.save()

    with MqttBridge({1: line}, args.broker, args.port, gateway="demo-gw") as bridge:
        bridge.watch(1, 5, od=demo_od("fd", pdos=1), pdos="node", heartbeat_timeout_ms=500)
        line.nmt.start(5)
        print("state:", next_message("/1/5/state", "OPERATIONAL").payload.decode())

        device["Demo UNSIGNED16"].raw = 4711
        device.tpdo[1].transmit()
        value = next_message("/1/5/pdo/Demo UNSIGNED16")
        print("value:", value.payload.decode())

        device.emcy.raise_error(0x4210, register_bits=0x08)    # over temperature
        print("emcy code:", hex(json.loads(next_message("/1/5/emcy").payload)["code"]))

        dashboard.publish("canopen/demo-gw/1/5/cmd/read",
                          json.dumps({"id": 1, "key": "Producer heartbeat time"}), qos=1)
        reply = json.loads(next_message("/1/5/reply").payload)
        print("read heartbeat time:", reply)

dashboard.disconnect()
dashboard.loop_stop()
