"""Read and write a device's entries by name: USDO on a CAN FD line, SDO on a
classic line, the same calls for both (the line decides the protocol).

A device (node 5, the demo dictionary) runs on each line; the tool reads its
identity, writes a record member by name, reads a string, and lists what a
failed write says.

Run:  python3 examples/transfer_by_name.py
(in-process buses; on hardware open the lines with canopenfd.connect("can0"))
"""

import canopenfd
from canopenfd.od import demo_od


def session(net: canopenfd.Network, mode: str) -> None:
    bus = f"mem:by-name-{mode}"
    net.open_line(bus, mode=mode).create_local_node(5, od=demo_od(mode))
    line = net.open_line(bus, mode=mode)
    drive = line.add_node(5, demo_od(mode))          # names and types from the OD
    protocol = "USDO" if mode == "fd" else "SDO"
    vendor = drive.od["Identity object"]["Vendor-ID"].raw
    print(f"{mode:7} {protocol:4}  Vendor-ID = 0x{vendor:08X}")
    drive.od["Demo record"]["Setpoint"].raw = -321
    print(f"{mode:7} {protocol:4}  Setpoint read back: {drive.od['Demo record.Setpoint'].raw}")
    print(f"{mode:7} {protocol:4}  Label: {drive.od['Demo record.Label'].raw!r}")
    raw = drive.usdo.upload(0x1018, 1) if mode == "fd" else drive.sdo.upload(0x1018, 1)
    print(f"{mode:7} {protocol:4}  0x1018:01 as bytes: {raw.hex()}")
    try:
        drive.od["Identity object"]["Vendor-ID"].raw = 1     # read-only on the device
    except canopenfd.AbortError as exc:
        print(f"{mode:7} {protocol:4}  write refused: 0x{exc.code:08X} ({exc.meaning})")


def main() -> None:
    with canopenfd.Network() as net:
        session(net, "fd")
        session(net, "classic")


if __name__ == "__main__":
    main()
