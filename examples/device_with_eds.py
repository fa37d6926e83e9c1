"""A device from a vendor EDS: it checks writes in Python, keeps parameters
in a file across restarts, and reports errors with EMCY.

The device (node 5) serves examples/data/demo_drive.eds; a tool on the same
bus (node 1's SDO client) writes a setpoint the device refuses, one it
accepts, stores the parameters and watches the EMCY the device raises when
the setpoint is out of its safe range.

Run:  python3 examples/device_with_eds.py [--channel CHANNEL] [--interface NAME]
Default: python-can's virtual bus (classic CAN); with real hardware give the
SocketCAN interface (--channel can0) or a python-can interface and channel.
"""

import argparse
import os
import tempfile
import threading

import canopenfd

HERE = os.path.dirname(os.path.abspath(__file__))
EDS = os.path.join(HERE, "data", "demo_drive.eds")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--channel", default="example-device")
    parser.add_argument("--interface", default="virtual")
    args = parser.parse_args()
    interface = None if args.interface == "socketcan" else args.interface
    store = os.path.join(tempfile.mkdtemp(), "drive-params.bin")

    # --- the device --------------------------------------------------------
    with canopenfd.connect(args.channel, interface, mode="classic") as device_line:
        device = device_line.create_local_node(5, od=EDS, store=store, boot=False)

        @device.on_write("Speed setpoint")
        def check_setpoint(request):
            # The EDS limits are -3000..3000; this drive refuses reversing
            # while its acceleration parameter is at the factory default.
            if request.value < 0 and device["Acceleration"].raw == 500:
                print(f"device:  refuses setpoint {request.value} (0x08000022)")
                return 0x08000022           # "because of the present device state"
            print(f"device:  setpoint {request.value} accepted")
            if abs(request.value) > 2500:
                device.emcy.raise_error(0x8611, b"\x01")   # a manufacturer-chosen code
            return None

        device.boot()

        # --- a tool on the same bus ------------------------------------------
        with canopenfd.connect(args.channel, interface, mode="classic") as tool_line:
            drive = tool_line.add_node(5, EDS)
            emcys = threading.Event()
            drive.emcy.add_callback(lambda e: (print(f"tool:    EMCY {e.text}"), emcys.set()))

            for value in (-100, 2800):
                try:
                    drive.sdo["Speed setpoint"].raw = value
                except canopenfd.SdoAbortError as exc:
                    print(f"tool:    write {value} refused: 0x{exc.code:08X} {exc.meaning}")
            try:
                drive.sdo["Speed setpoint"].raw = 9999      # checked here, by the EDS
            except canopenfd.OdValueError as exc:
                print(f"tool:    not sent: {exc}")
            try:                                            # the raw bytes: the device checks
                drive.sdo.download(0x2000, 0, (9999).to_bytes(2, "little", signed=True))
            except canopenfd.SdoAbortError as exc:
                print(f"tool:    write 9999 refused: 0x{exc.code:08X} {exc.meaning}")
            emcys.wait(5)
            print(f"tool:    error register 0x{drive.sdo['Error register'].raw:02X}")

            drive.sdo["Acceleration"].raw = 800
            drive.sdo["Store parameters"]["Save all parameters"].raw = 0x65766173   # "save"
            print(f"device:  store file holds {os.path.getsize(store)} bytes")

        # A reset loads the stored values back.
        device.apply("reset-node")
        device.wait_for_state("PRE-OPERATIONAL", timeout=5)
        print(f"device:  after reset, acceleration = {device['Acceleration'].raw}")


if __name__ == "__main__":
    main()
