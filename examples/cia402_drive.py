"""Drive a CiA 402 servo drive: enable, profile position move, cyclic
synchronous position with SYNC, shutdown.

The drive here is the simulated one of canopenfd.profiles.cia402 (node 5: its
state machine and motion model run in the C runtime), on the in-process bus
"mem:cia402-example"; point the master's line at a real bus ("can0") and drop
the simulated drive to run the same code against a real drive.

Run:  python3 examples/cia402_drive.py [--fd]
"""

import sys
import time

import canopenfd
from canopenfd.profiles.cia402 import Drive, DriveError, create_simulated_drive, drive_od

MODE = "fd" if "--fd" in sys.argv[1:] else "classic"
BUS = "mem:cia402-example"


def main() -> None:
    with canopenfd.Network() as net:
        create_simulated_drive(net.open_line(BUS, mode=MODE), 5)        # the "drive"

        line = net.open_line(BUS, mode=MODE)                            # the master
        drive = Drive(line.add_node(5, od=drive_od(MODE)), timeout=2.0)
        print(f"drive state: {drive.state}")

        # profile position: enable, move, wait for "target reached"
        drive.set_mode("profile_position")
        drive.enable()
        print(f"drive state: {drive.state}")
        drive.move_to(2000, velocity=20000, acceleration=200000, deceleration=200000)
        print(f"profile position: at {drive.position}")

        # cyclic synchronous position: SYNC every 2 ms, a new target after each
        cyclic = drive.cyclic("csp", period=0.002)
        drive.enable()
        for step in range(1, 51):
            cyclic.target = 2000 + step * 20
            time.sleep(0.002)
        deadline = time.monotonic() + 2
        while drive.position != 3000 and time.monotonic() < deadline:
            time.sleep(0.005)
        print(f"cyclic synchronous position: at {drive.position} after {step} targets")
        drive.stop_cyclic()

        drive.shutdown()
        print(f"drive state: {drive.state}")
        try:
            drive.move_to(0)
        except DriveError as exc:       # the helper says what is missing
            print(f"refused: {exc}")


if __name__ == "__main__":
    main()
