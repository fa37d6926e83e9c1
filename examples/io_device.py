"""A CiA 401 generic I/O device and a master on the in-process bus.

The device has 16 digital inputs, 8 digital outputs, 2 analogue inputs and
2 analogue outputs; the application feeds it input levels and hears its
outputs. The master configures the interrupt masks by SDO, receives the
device's TPDOs, drives its outputs by SDO and RPDO, and stops it: outputs
with error mode set go to their error value.

Run:  python3 examples/io_device.py
For real hardware, replace "mem:io" with a SocketCAN interface ("can0").
"""

import threading

import canopenfd
from canopenfd.profiles.cia401 import create_io_device

NODE = 5


def main() -> None:
    with canopenfd.Network() as net:
        # --- the device: its application binds the I/O ---------------------
        device_line = net.open_line("mem:io", mode="classic")
        device = create_io_device(device_line, NODE, digital_inputs=16, digital_outputs=8,
                                  analog_inputs=2, analog_outputs=2)
        changed = threading.Event()

        def show_digital(levels: int) -> None:
            print(f"device:  digital outputs {levels:08b}")
            changed.set()

        def show_analog(channel: int, value: int) -> None:
            print(f"device:  analogue output {channel} = {value}")
            changed.set()

        device.on_digital_outputs(show_digital)
        device.on_analog_output(show_analog)

        # --- the master ----------------------------------------------------
        master_line = net.open_line("mem:io", mode="classic")
        master_line.create_local_node(1)
        io = master_line.add_node(NODE, od=device.node.od)   # the device's EDS would do
        print(f"master:  device type 0x{io.read(0x1000):08X}")
        io.write((0x6006, 1), 0x00)          # inputs 1..8: no TPDO on any change ...
        io.write((0x6007, 1), 0x01)          # ... only when input 1 rises
        received = threading.Event()

        def show_tpdo(pdo) -> None:
            print(f"master:  TPDO1 digital inputs {bytes(pdo.data).hex(' ')}")
            received.set()

        io.tpdo[1].add_callback(show_tpdo)
        io.start()
        device.node.wait_for_state("OPERATIONAL")

        device.set_inputs(0x0002)            # input 2 rises: masked, no TPDO
        device.set_inputs(0x0003)            # input 1 rises: TPDO1
        received.wait(timeout=5)
        print(f"master:  reads 0x6000:01 = 0x{io.read((0x6000, 1)):02X}")

        io.write((0x6202, 1), 0x80)          # output 8 inverted
        changed.clear()
        io.write((0x6200, 1), 0x0F)          # by SDO
        changed.wait(timeout=5)
        changed.clear()
        master_line.send_frame(0x300 + NODE, (-300).to_bytes(2, "little", signed=True)
                               + (1000).to_bytes(2, "little"))   # RPDO2: analogue outputs
        changed.wait(timeout=5)

        io.write((0x6206, 1), 0x01)          # on a fault only output 1 changes ...
        io.write((0x6207, 1), 0x00)          # ... to 0
        changed.clear()
        io.stop()
        changed.wait(timeout=5)
        print(f"device:  after NMT stop {device.outputs}")


if __name__ == "__main__":
    main()
