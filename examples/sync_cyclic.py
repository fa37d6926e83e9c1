"""A SYNC-driven cycle: the master produces SYNC every 10 ms (with a counter),
the device's application runs one step per SYNC and its synchronous TPDO
(type 1) carries the result of every cycle back.

SYNC production and the TPDO's sampling at each SYNC run in the C runtime;
Python sees one callback per SYNC on the device and one per PDO on the
master, and checks that no cycle was skipped.

Run:  python3 examples/sync_cyclic.py [--cycles N]
"""

import argparse
import threading

import canopenfd
from canopenfd.od import demo_od
from canopenfd.od.demo import PROCESS_DATA

CYCLE_S = 0.010


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cycles", type=int, default=50)
    args = parser.parse_args()
    with canopenfd.Network() as net:
        device_line = net.open_line("mem:cyclic")
        device = device_line.create_local_node(5, 100, od=demo_od("fd", pdos=1))
        line = net.open_line("mem:cyclic")
        drive = line.add_node(5, demo_od("fd", pdos=1))

        # TPDO 1 of the device: the cycle number and the SYNC counter, type 1
        tpdo = drive.tpdo[1]
        tpdo.read()
        tpdo.clear()
        tpdo.add_variable("Process data", "Process data 1")
        tpdo.add_variable("Process data", "Process data 2")
        tpdo.trans_type = 1                          # sampled and sent at every SYNC
        tpdo.enabled = True
        tpdo.save()
        # SYNCs will carry a counter (1..16): CiA 301 wants the consumer told the
        # same overflow value (a SYNC of another length is refused and counted)
        drive.od["Synchronous counter overflow value"].raw = 16

        cycle = [0]

        def application_step(counter: int) -> None:  # the device, once per SYNC
            cycle[0] += 1
            device[(PROCESS_DATA, 1)].raw = cycle[0]
            device[(PROCESS_DATA, 2)].raw = counter

        device_line.sync.add_callback(application_step)

        received = []
        finished = threading.Event()

        def on_pdo(pdo) -> None:                     # the master, once per PDO
            received.append(pdo["Process data 1"].raw)
            if len(received) >= args.cycles:
                finished.set()

        tpdo.add_callback(on_pdo)
        line.nmt.state = "OPERATIONAL"
        drive.wait_for_state("OPERATIONAL", timeout=5)
        line.sync.start(CYCLE_S, overflow=16)        # SYNC with counter 1..16
        finished.wait(10)
        line.sync.stop()

        steps = [b - a for a, b in zip(received, received[1:])]
        print(f"cycles received: {len(received)}, application steps between two PDOs: "
              f"{sorted(set(steps))}")
        # A TPDO samples at a SYNC what the application wrote at the previous one.
        print("no cycle skipped" if set(steps) <= {1} else "cycles skipped: "
              f"{sum(s - 1 for s in steps if s > 1)}")


if __name__ == "__main__":
    main()
