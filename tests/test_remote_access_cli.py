"""`canopenfd gateway` with the remote-access options: in-process over TCP,
and as a process on a pty's serial port stopped by SIGTERM."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import threading
import time
import tty
from typing import List

import pytest

import canopenfd
from canopenfd.cli import main
from canopenfd.gateway import remote_access as ra
from canopenfd.gateway.remote_access_client import RemoteAccessClient
from canopenfd.gateway.remote_access_stream import FdStream
from canopenfd.od import demo_od

from helpers import NEUTRAL_CWD, cli_command, package_env, scaled


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def connect_when_listening(port: int, timeout: float = 10.0) -> RemoteAccessClient:
    """The gateway thread opens its listener after the line: connect once it does."""
    deadline = time.monotonic() + scaled(timeout)
    while True:
        try:
            return RemoteAccessClient.connect("127.0.0.1", port)
        except canopenfd.errors.InterfaceError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.05)


def test_gateway_tcp_in_process(net: canopenfd.Network, bus_name: str) -> None:
    device = net.open_line(bus_name).create_local_node(5, od=demo_od("fd"))
    port = free_port()
    status: List[int] = []
    runner = threading.Thread(target=lambda: status.append(main(
        ["gateway", "--channel", bus_name, "--node-id", "1", "--remote-access-tcp", str(port),
         "--remote-access-manager", "0x5", "--remote-access-node", "5=builtin:fd",
         "--duration", str(scaled(3))], network=net)))
    runner.start()
    try:
        with connect_when_listening(port) as client:
            assert client.own_node_id() == 1
            assert client.manager_control() & 0x1F == (ra.ManagerControl.KEEP_OP
                                                       | ra.ManagerControl.PDO_RECEIVE_ALL)
            # the known node was scanned (its TPDO configuration read by USDO)
            deadline = time.monotonic() + scaled(5)
            while client.node_state(5) != ra.NodeStatus.SCAN_COMPLETE:
                assert time.monotonic() < deadline, hex(client.node_state(5))
                time.sleep(0.05)
            device[0x1018][3].raw = 0x0102
            assert client.read_remote(5, 0x1018, 3) == b"\x02\x01\x00\x00"
            device.wait_for_state("OPERATIONAL", timeout=scaled(5))   # KEEP_OP started it
    finally:
        runner.join(scaled(30))
    assert status == [0]


def test_gateway_needs_an_endpoint(net: canopenfd.Network, bus_name: str,
                                   capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["gateway", "--channel", bus_name], network=net) == 2
    assert "no host endpoint given (--tcp PORT, --mqtt BROKER, --serial PATH or " in \
        capsys.readouterr().err
    assert main(["gateway", "--channel", bus_name, "--remote-access-tcp", "0",
                 "--remote-access-manager", "x"], network=net) == 2
    assert "--remote-access-manager 'x': not a number" in capsys.readouterr().err
    assert main(["gateway", "--channel", bus_name, "--remote-access-tcp", "0",
                 "--remote-access-manager", "8"], network=net) == 2
    assert ("manager control 0x00000008 refused (NOT_SUPPORTED: bits 3 and 4 are not "
            "served)") in capsys.readouterr().err
    assert main(["gateway", "--channel", bus_name, "--remote-access-tcp", "0",
                 "--remote-access-node", "200=x.eds"], network=net) == 2
    assert "--remote-access-node '200=x.eds': expected NODE=FILE with a node-id 1..127" in \
        capsys.readouterr().err
    # a file that cannot be read: the option that named it, the file
    assert main(["gateway", "--channel", bus_name, "--remote-access-tcp", "0",
                 "--remote-access-node", "5=/nonexistent/x.eds"], network=net) == 2
    err = capsys.readouterr().err
    assert "--remote-access-node 5: /nonexistent/x.eds" in err, err


def test_gateway_process_on_a_serial_port_stops_on_sigterm() -> None:
    pytest.importorskip("serial")
    master, slave = os.openpty()
    tty.setraw(master)
    path = os.ttyname(slave)
    proc = subprocess.Popen(
        cli_command("gateway", "--channel", "mem:gw", "--node-id", "3", "--serial", path,
                    "--baud", "57600"),
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=package_env(),
        cwd=NEUTRAL_CWD)
    try:
        assert proc.stderr is not None
        started = proc.stderr.readline()
        assert f"gateway on mem:gw (fd): remote access on serial {path} (57600 Bd)" in started
        with RemoteAccessClient(FdStream(master, "pty master")) as client:
            assert client.own_node_id() == 3
            assert client.read_local(0x1017) == b"\x00\x00"
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=scaled(20))
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
        os.close(slave)
    assert proc.returncode == 0, err
    assert "remote access: frames 2," in out


def test_gateway_stops_remote_access_whatever_ends_it(net: canopenfd.Network, bus_name: str,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """A failure while the gateway serves still closes the remote-access
    server (before: its listener and threads outlived the command)."""
    from canopenfd.gateway.gateway import Gateway

    calls: List[int] = []
    status = Gateway.status

    def failing_status(self: Gateway) -> str:
        calls.append(1)
        if len(calls) == 2:          # the first status line after the endpoints started
            raise RuntimeError("status failed")
        return status(self)

    monkeypatch.setattr(Gateway, "status", failing_status)
    port = free_port()
    with pytest.raises(RuntimeError, match="status failed"):
        main(["gateway", "--channel", bus_name, "--remote-access-tcp", str(port),
              "--duration", "30"], network=net)
    with pytest.raises(OSError):
        socket.create_connection(("127.0.0.1", port), timeout=scaled(2)).close()
