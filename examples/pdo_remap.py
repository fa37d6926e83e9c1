"""Remap a device's TPDO from the master and take its values in callbacks.

The device (node 5, CAN FD, the demo dictionary with one PDO each way) maps
nothing at first. The master maps four "Process data" entries into the
device's TPDO 1 (the CiA procedure: disable, clear, map, enable, over USDO),
makes it event-driven with a 20 ms event timer, starts the device, and counts
the PDOs its callback sees while the device's application changes the values.
The frames are decoded in C: Python runs once per PDO, not per byte or frame
field.

Run:  python3 examples/pdo_remap.py
"""

import threading
import time

import canopenfd
from canopenfd.od import demo_od
from canopenfd.od.demo import PROCESS_DATA


def main() -> None:
    with canopenfd.Network() as net:
        device = net.open_line("mem:pdo-remap").create_local_node(
            5, od=demo_od("fd", pdos=1))
        line = net.open_line("mem:pdo-remap")
        drive = line.add_node(5, demo_od("fd", pdos=1))

        tpdo = drive.tpdo[1]
        tpdo.read()                                  # the device's current mapping
        tpdo.clear()
        for sub in range(1, 5):
            tpdo.add_variable(PROCESS_DATA, sub)     # or by name: "Process data 1"
        tpdo.trans_type = 255                        # event-driven ...
        tpdo.event_timer = 20                        # ... and at least every 20 ms
        tpdo.enabled = True
        tpdo.save()                                  # written to the device over USDO
        print(f"mapped: {[v.name for v in tpdo]} on COB-ID 0x{tpdo.cob_id:03X}")

        seen = []
        done = threading.Event()

        def on_pdo(pdo) -> None:
            seen.append([v.raw for v in pdo])
            if len(seen) >= 10:
                done.set()

        tpdo.add_callback(on_pdo)
        drive.nmt.state = "OPERATIONAL"
        for step in range(1, 6):                     # the device's application at work
            device[(PROCESS_DATA, 1)].raw = step
            device[(PROCESS_DATA, 4)].raw = step * 1000
            time.sleep(0.02)
        done.wait(5)
        print(f"PDOs received: {len(seen)}; last values {seen[-1]}")
        print(f"the master's line stats: pdo frames {line.service_stats['pdo_watched']}")


if __name__ == "__main__":
    main()
