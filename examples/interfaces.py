"""Opening a line on the CAN hardware you have: SocketCAN natively, or any
python-can interface (PCAN, Kvaser, Vector, IXXAT, virtual, ...) with its own
options. The same script then reads a device's identity over SDO/USDO.

    python3 examples/interfaces.py                                # python-can virtual, self-test
    python3 examples/interfaces.py --channel can0 --node 5        # SocketCAN (ip link set up)
    python3 examples/interfaces.py --interface pcan --channel PCAN_USBBUS1 \\
        --bitrate 500000 --classic --node 5
    python3 examples/interfaces.py --interface kvaser --channel 0 --bitrate 1000000 \\
        --data-bitrate 4000000 --node 5                             # CAN FD on a Kvaser
    python3 examples/interfaces.py --interface socketcan --channel can0 --node 5
                                   # python-can's socketcan: a Python thread per frame

Native SocketCAN (no --interface) keeps Python off the per-frame path; a
python-can interface runs the frames through two bridge threads. Bit rates of
SocketCAN interfaces are set with `ip link`, not here:
    ip link set can0 type can bitrate 500000 dbitrate 2000000 fd on && ip link set can0 up
"""

import argparse

import canopenfd
from canopenfd.od import demo_od


def open_line(args: argparse.Namespace) -> canopenfd.Line:
    mode = "classic" if args.classic else "fd"
    if args.interface is None:
        return canopenfd.connect(args.channel, mode=mode)
    options = {}
    if args.bitrate:
        options["bitrate"] = args.bitrate
    if args.data_bitrate:
        options["data_bitrate"] = args.data_bitrate
    return canopenfd.connect(args.channel, args.interface, mode=mode, **options)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--interface", help="python-can interface (default: native SocketCAN, "
                                            "or python-can's virtual when no --channel)")
    parser.add_argument("--channel", help="interface name / python-can channel")
    parser.add_argument("--bitrate", type=int)
    parser.add_argument("--data-bitrate", type=int)
    parser.add_argument("--classic", action="store_true", help="classic CAN (SDO), not FD")
    parser.add_argument("--node", type=int, help="the device to read (default: a self-test "
                                                 "device on the same bus)")
    args = parser.parse_args()
    self_test = args.channel is None
    if self_test:
        args.interface, args.channel = "virtual", "interfaces-example"
    with open_line(args) as line:
        print(f"opened {line!r}")
        node_id = args.node or 5
        if self_test:
            mode = "classic" if args.classic else "fd"
            device = canopenfd.connect(args.channel, args.interface, mode=mode)
            device.create_local_node(node_id, od=demo_od(mode))
        drive = line.add_node(node_id)
        client = drive.usdo if line.mode == "fd" else drive.sdo
        identity = [int.from_bytes(client.upload(0x1018, sub), "little") for sub in (1, 2, 3)]
        print(f"node {node_id}: vendor 0x{identity[0]:08X}, product 0x{identity[1]:08X}, "
              f"revision 0x{identity[2]:08X}")
        print(f"line counters: {dict((k, v) for k, v in line.stats.items() if v)}")
        if self_test:
            device.disconnect()


if __name__ == "__main__":
    main()
