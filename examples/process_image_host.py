"""A host MCU and its CANopen coprocessor, in one process: the CANopen task
is configured by examples/data/process_image_io.txt alone (seed 004 setup
file), the host talks to it over a pseudo-terminal with the message form of
the ESAcademy CANopen API, and another line plays the network.

    python examples/process_image_host.py

The same device runs on a real bus with
`canopenfd device --setup examples/data/process_image_io.txt --channel can0 --host-link pty`.
"""

from __future__ import annotations

import os
import pathlib
import queue
import tty

import canopenfd
from canopenfd.gateway.remote_access_stream import FdStream
from canopenfd.processimage.host import ProcessImage
from canopenfd.processimage.setup_file import load_setup_file
from canopenfd.processimage.task import ProcessImageTask

SETUP = pathlib.Path(__file__).resolve().parent / "data" / "process_image_io.txt"


def main() -> None:
    setup = load_setup_file(str(SETUP))
    with canopenfd.Network() as net:
        line = net.open_line("mem:plant", mode="classic")
        network = net.open_line("mem:plant", mode="classic")
        tpdos: "queue.Queue[bytes]" = queue.Queue()
        net.open_line("mem:plant", mode="classic", monitor=True).on_frame(
            lambda frame: tpdos.put(bytes(frame.data)) if frame.id == 0x1C0 else None)

        task_end, host_end = os.openpty()
        tty.setraw(task_end)
        tty.setraw(host_end)
        task = ProcessImageTask(line, setup, FdStream(task_end, "coprocessor"))
        with ProcessImage(FdStream(host_end, "host")) as host:
            ident = host.get_id()
            print(f"host: task {int.from_bytes(ident[:2], 'little'):04X}h version "
                  f"{ident[3]}.{ident[2]}, status {host.get_status():02X}h")
            print(f"host: InitCANopen -> {host.init_canopen()}")
            for _ in range(2):                            # initialising, pre-operational
                print(f"host: NMTChange {host.wait_indication().params[0]:02X}h")
            network.nmt.send("START", 0x40)
            print(f"host: NMTChange {host.wait_indication().params[0]:02X}h")

            print(f"host: wrote {host.write(0, bytes((0x12, 0x34)))} input bytes")
            print(f"network: TPDO 1 carries {tpdos.get(timeout=5).hex(' ')}")
            network.send_frame(0x240, bytes((0xAB, 0xCD)))
            indication = host.wait_indication()
            offset, length = indication.params
            print(f"host: ReceivedData {offset}..{offset + length - 1}, read "
                  f"{host.read(offset, length).hex(' ')}")
            print(f"host: read past the end gives {len(host.read(6, 10))} bytes, "
                  f"from offset 9 {len(host.read(9, 1))}")
        task.close()


if __name__ == "__main__":
    main()
