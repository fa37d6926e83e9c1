"""A master drives a device's RPDO, the way CiA 402 drive scripts do.

Node 5 is a device serving the demo object dictionary with one RPDO
(demo_od(pdos=1)); its RPDO callback prints what it receives. The master
(a line without a local node) configures that RPDO over SDO/USDO, then fills
it by name and sends it: once, every 10 ms, and after each SYNC. The frames
are produced by the C runtime: Python only writes a value when it changes.
No hardware needed: both sit on the in-process bus "mem:rpdo-example".

Run:  python3 examples/master_drives_rpdo.py [--classic]
"""

import sys
import threading
import time

import canopenfd
from canopenfd.od import demo_od

MODE = "classic" if "--classic" in sys.argv[1:] else "fd"
BUS = "mem:rpdo-example"


def main() -> None:
    with canopenfd.Network() as net:
        # --- node 5, the device -------------------------------------------
        device = net.open_line(BUS, mode=MODE).create_local_node(
            5, od=demo_od(MODE, pdos=1))
        received = []
        heard = threading.Event()

        def on_rpdo(pdo) -> None:
            values = [var.raw for var in pdo]
            received.append(values)
            if len(received) <= 3:                     # the first few only
                print(f"device: RPDO1 received {values}")
            heard.set()
        device.rpdo[1].add_callback(on_rpdo)

        # --- the master ---------------------------------------------------
        line = net.open_line(BUS, mode=MODE)
        drive = line.add_node(5, od=demo_od(MODE, pdos=1))
        rpdo = drive.rpdo[1]
        rpdo.read()                                    # over USDO (fd) / SDO (classic)
        rpdo.clear()
        rpdo.add_variable("Process data.Process data 1")          # 32 bits
        rpdo.add_variable("Process data.Process data 2", None, 16)  # its low 16 bits
        rpdo.trans_type = 255
        rpdo.enabled = True
        rpdo.save()                                    # the CiA 301 procedure
        drive.start()                                  # NMT: RPDOs are taken in OPERATIONAL
        device.nmt.wait_for_state("OPERATIONAL", timeout=5)

        # once
        rpdo["Process data.Process data 1"].raw = 15
        rpdo["Process data.Process data 2"].raw = 0x1234
        rpdo.transmit()
        heard.wait(timeout=5)

        # every 10 ms, from the C runtime's timer
        rpdo.start(0.01)
        time.sleep(0.1)
        rpdo["Process data.Process data 1"].raw = 31   # the next frame carries it
        time.sleep(0.1)
        rpdo.stop()
        sent = rpdo.producer_stats["sent"]
        time.sleep(0.05)
        print(f"master: periodic: {sent} frames sent, last value seen by the device "
              f"{received[-1]}")

        # after every SYNC the master produces
        before = rpdo.producer_stats["sent"]
        rpdo.start_sync(every=1)
        line.sync.start(0.02)
        time.sleep(0.2)
        line.sync.stop()
        rpdo.stop()
        print(f"master: SYNC-driven: {rpdo.producer_stats['sent'] - before} frames sent")
        print(f"device: {len(received)} receptions in all")


if __name__ == "__main__":
    main()
