"""Two processes on one SocketCAN interface: a device in one, a master in the
other, as on a real bus (each opens the interface itself; the kernel carries
the frames between them). CAN FD needs an FD-capable interface (MTU 72):

    ip link add dev vcan0 type vcan && ip link set vcan0 mtu 72 up   # a virtual one

    python3 examples/two_processes.py --channel vcan0            # spawns the device, runs the master
    python3 examples/two_processes.py device --channel can0      # or each role by hand,
    python3 examples/two_processes.py master --channel can0      # on two machines
"""

import argparse
import os
import subprocess
import sys
import time

import canopenfd
from canopenfd.od import demo_od

NODE = 5


def device(channel: str, seconds: float) -> None:
    with canopenfd.connect(channel) as line:
        node = line.create_local_node(NODE, 50, od=demo_od("fd"))
        node[0x2200, 1].raw = 42                    # "Demo record.Setpoint"
        print(f"device: node {NODE} on {channel}, pid {os.getpid()}", flush=True)
        time.sleep(seconds)


def master(channel: str) -> None:
    with canopenfd.connect(channel) as line:
        drive = line.add_node(NODE, demo_od("fd"), heartbeat_timeout_ms=500)
        # the device process may take a while to start on a slow or loaded machine
        state = drive.wait_for_heartbeat(timeout=30)
        print(f"master: node {NODE} is {state.label}")
        print(f"master: setpoint {drive.od['Demo record.Setpoint'].raw}")
        line.nmt.start(NODE)
        drive.wait_for_state("OPERATIONAL", timeout=5)
        print(f"master: node {NODE} started, pid {os.getpid()}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("role", nargs="?", choices=["device", "master"])
    parser.add_argument("--channel", default="vcan0")
    parser.add_argument("--seconds", type=float, default=10.0, help="how long the device runs")
    args = parser.parse_args()
    if args.role == "device":
        device(args.channel, args.seconds)
    elif args.role == "master":
        master(args.channel)
    else:
        child = subprocess.Popen([sys.executable, __file__, "device", "--channel", args.channel,
                                  "--seconds", str(args.seconds)])
        try:
            master(args.channel)
        finally:
            child.terminate()
            child.wait(10)


if __name__ == "__main__":
    main()
