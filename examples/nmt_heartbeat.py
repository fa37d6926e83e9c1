"""NMT and heartbeat between two nodes on the in-process CAN FD bus.

Node 1 is a manager: it watches node 2's heartbeat and commands its NMT state.
Node 2 is a device producing a heartbeat every 100 ms. No hardware needed:
both run on the in-process bus "mem:example" inside one Network (one C
thread runs both lines; callbacks arrive on the network's dispatcher thread).

Run:  python3 examples/nmt_heartbeat.py
For real hardware, replace "mem:example" with a SocketCAN interface ("can0")
and run each node in its own process or machine.
"""

import threading
import time

import canopenfd


def main() -> None:
    with canopenfd.Network() as net:  # closing the network stops everything
        # --- node 1, the manager ------------------------------------------
        manager = net.open_line("mem:example", mode="fd")
        manager.create_local_node(1)
        # Watch node 2: lost if no heartbeat within 250 ms.
        device_view = manager.add_node(2, heartbeat_timeout_ms=250)
        booted, lost = threading.Event(), threading.Event()
        device_view.on_bootup(lambda: (print("manager: node 2 booted"), booted.set()))
        device_view.on_state_change(lambda state: print(f"manager: node 2 is {state}"))
        device_view.on_heartbeat_started(lambda: print("manager: node 2 heartbeat started"))
        device_view.on_heartbeat_lost(lambda: (print("manager: node 2 heartbeat lost"),
                                               lost.set()))

        # --- node 2, the device -------------------------------------------
        device_line = net.open_line("mem:example", mode="fd")
        # boot=False: register callbacks first so the first transition is seen too.
        device = device_line.create_local_node(2, heartbeat_ms=100, boot=False)
        device.on_state_change(lambda old, new: print(f"device:  {old} -> {new}"))
        device.on_reset(lambda kind: print(f"device:  {kind.name.lower()}"))
        device.boot()  # boot-up message, then PRE-OPERATIONAL, then heartbeats

        # --- the manager drives the device --------------------------------
        # Events set from callbacks never miss anything; wait_for_bootup()
        # waits for the *next* boot-up, so it must start before the node boots.
        booted.wait(timeout=5)
        manager.nmt.start(2)  # or device_view.nmt.state = "OPERATIONAL"
        device_view.wait_for_state("OPERATIONAL", timeout=5)  # its heartbeat says so

        manager.nmt.stop(2)
        device_view.wait_for_state("STOPPED", timeout=5)

        booted.clear()
        manager.nmt.reset_communication(2)  # new boot-up, back to PRE-OPERATIONAL
        booted.wait(timeout=5)
        device_view.wait_for_heartbeat(timeout=5)

        states = {n: str(s) for n, s in manager.states.items()}
        print(f"states seen by the manager: {states}")

        # --- the device stops its heartbeat: the manager notices ----------
        device.heartbeat_ms = 0
        lost.wait(timeout=5)
        time.sleep(0.05)  # let the last callback lines print before closing
        counters = {k: v for k, v in manager.stats.items() if v}
        print(f"manager line stats: {counters}")


if __name__ == "__main__":
    main()
