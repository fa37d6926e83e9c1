"""PDO values published to a real MQTT broker: values/s with QoS 0 and 1 and
the gateway process's CPU per PDO (issue 16, "Performance").

    python3 bench/mqtt_bench.py [-d DEVICES] [-s SECONDS] [--period-ms MS]

DEVICES devices (nodes 5..) on an in-process fd line each send TPDO 1 (one
UNSIGNED16 value) every period; the gateway watches them and publishes every
value to a mosquitto started on loopback (Debian's package); `mosquitto_sub`
in another process counts what arrives. CPU = this process's user + system
seconds over the window (the gateway, and the simulated devices, whose C
producers cost little) per PDO heard.
"""

from __future__ import annotations

import argparse
import pathlib
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

from canopenfd import Network  # noqa: E402
from canopenfd.gateway.mqtt import MqttBridge  # noqa: E402
from canopenfd.od import demo_od  # noqa: E402
from mqtt_broker import Broker  # noqa: E402


def run(devices: int, seconds: float, period_ms: int, qos: int) -> dict:
    with tempfile.TemporaryDirectory() as folder, Network() as net:
        broker = Broker(pathlib.Path(folder))
        try:
            gw_line = net.open_line("mem:mqtt-bench", mode="fd")
            nodes = []
            for node_id in range(5, 5 + devices):
                device = net.open_line("mem:mqtt-bench", mode="fd").create_local_node(
                    node_id, od=demo_od("fd", pdos=1))
                tpdo = device.tpdo[1]
                tpdo.read()
                tpdo.clear()
                tpdo.add_variable("Demo UNSIGNED16")
                tpdo.trans_type = 255
                tpdo.event_timer = period_ms
                tpdo.enabled = True
                tpdo.save()
                nodes.append(device)
            counter = subprocess.Popen(
                ["mosquitto_sub", "-h", "127.0.0.1", "-p", str(broker.port), "-q", "1",
                 "-t", "canopen/bench/+/+/pdo/#"], stdout=subprocess.PIPE, text=True)
            time.sleep(0.5)                       # its subscription is in place
            with MqttBridge({1: gw_line}, port=broker.port, gateway="bench",
                            value_qos=qos) as bridge:
                heard = 0
                remotes = []
                for device in nodes:
                    remote = bridge.watch(1, device.node_id, od=demo_od("fd", pdos=1),
                                          pdos="node")

                    def count(pdo: object) -> None:
                        nonlocal heard
                        heard += 1
                    remote.tpdo[1].add_callback(count)
                    remotes.append(remote)
                cpu0, wall0 = time.process_time(), time.monotonic()
                for device in nodes:
                    device.nmt.state = "OPERATIONAL"
                time.sleep(seconds)
                for device in nodes:
                    device.nmt.state = "STOPPED"
                wall = time.monotonic() - wall0
                time.sleep(0.5)                   # the last values reach the broker
                cpu = time.process_time() - cpu0
                published = bridge.stats["published"]
                dropped = bridge.stats["dropped"]
                skipped = sum(remote.tpdo[1].skipped for remote in remotes)
            time.sleep(1.0)
            counter.terminate()
            received = len(counter.communicate(timeout=10)[0].splitlines())
            return {"heard": heard, "skipped": skipped, "published": published, "dropped": dropped,
                    "received": received, "per_s": heard / wall,
                    "cpu_us": 1e6 * cpu / max(heard, 1)}
        finally:
            broker.stop()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("-d", "--devices", type=int, default=4, help="devices sending PDOs")
    parser.add_argument("-s", "--seconds", type=float, default=5.0, help="window per row")
    parser.add_argument("--period-ms", type=int, default=1, help="TPDO event timer")
    args = parser.parse_args()
    print(f"{args.devices} devices, TPDO every {args.period_ms} ms, {args.seconds:g} s a row")
    print("| value QoS | PDOs/s heard | heard | published | received by mosquitto_sub "
          "| dropped | coalesced (newest kept) | CPU us / PDO |")
    print("|---|---|---|---|---|---|---|---|")
    for qos in (0, 1):
        r = run(args.devices, args.seconds, args.period_ms, qos)
        print(f"| {qos} | {r['per_s']:.0f} | {r['heard']} | {r['published']} | "
              f"{r['received']} | {r['dropped']} | {r['skipped']} | {r['cpu_us']:.0f} |")


if __name__ == "__main__":
    main()
