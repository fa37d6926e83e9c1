"""`canopenfd device --setup FILE [--host-link LINK]`: a device configured
only by a seed 004 setup file, its process image served to a host over a
pty, a serial/tty path or a Unix socket; without a host link it initialises
itself with the file's defaults (as a host sending InitCANopen 0 0 would)."""

from __future__ import annotations

import argparse
import os
import socket
import sys
import threading
import tty
from typing import Any, Optional

from ..gateway.remote_access_stream import FdStream
from ..processimage.setup_file import SetupFile, SetupFileError, load_setup_file
from ..processimage.task import ProcessImageTask
from .common import EXIT_OK, Printer, UsageError, command_line, wait_until_done

_EXCLUSIVE = ("od", "store", "domain", "serial", "heartbeat", "node_id")


def add_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--setup", metavar="FILE",
                        help="configure the device from a CANopen Task setup file "
                             "(ESAcademy CANopen API, 'COPTSKA8'): node-id, PDOs, constant "
                             "entries and the process image; replaces --node-id and --od")
    parser.add_argument("--host-link", metavar="LINK",
                        help="with --setup: where the host talks to the process image: 'pty' "
                             "(a new pseudo-terminal, its path printed), a tty or serial "
                             "device path, or unix:PATH (a socket listened on, one host at a "
                             "time); without it the device initialises itself at once")


def _load(args: argparse.Namespace) -> SetupFile:
    for name in _EXCLUSIVE:
        if getattr(args, name, None) not in (None, []):
            raise UsageError(f"--setup: --{name.replace('_', '-')} cannot be combined with it "
                             "(the setup file configures the device)")
    try:
        setup = load_setup_file(args.setup)
    except SetupFileError as exc:
        raise UsageError(str(exc)) from None
    for warning in setup.warnings:
        print(f"warning: {warning}", file=sys.stderr)
    if args.classic and setup.mode == "fd":
        raise UsageError(f"--classic: {args.setup} describes a CANopen FD device ([NODE] "
                         "flags bit 0)")
    args.classic = setup.mode == "classic"
    return setup


class _UnixLink:
    """unix:PATH: a listening socket; each host connection is served in turn."""

    def __init__(self, path: str, task: ProcessImageTask, printer: Printer) -> None:
        if os.path.exists(path):
            raise UsageError(f"--host-link unix:{path}: {path} exists already")
        self.path = path
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self.sock.bind(path)
        self.sock.listen(1)
        self.task = task
        self.printer = printer
        threading.Thread(target=self._accept, name="host link", daemon=True).start()

    def _accept(self) -> None:
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            self.printer.line(f"host connected on {self.path}")
            self.task.serve(FdStream(conn.fileno(), f"unix:{self.path}", owner=conn))
            self.task.wait_link_closed()
            self.printer.line(f"host left {self.path}")

    def close(self) -> None:
        self.sock.close()
        try:
            os.unlink(self.path)
        except OSError:
            pass


def _open_link(link: str, task: ProcessImageTask, printer: Printer) -> Optional[Any]:
    """Start serving `link`; what must be closed at the end (or None)."""
    if link.startswith("unix:"):
        unix = _UnixLink(link[5:], task, printer)
        print(f"host link: unix:{unix.path}", file=sys.stderr)
        return unix
    if link == "pty":
        master, slave = os.openpty()
        tty.setraw(master)
        tty.setraw(slave)
        print(f"host link: {os.ttyname(slave)}", file=sys.stderr)
        task.serve(FdStream(master, "pty"))
        return slave
    try:
        fd = os.open(link, os.O_RDWR | os.O_NOCTTY)
    except OSError as exc:
        raise UsageError(f"--host-link {link}: {exc.strerror}") from None
    if os.isatty(fd):
        tty.setraw(fd)
    print(f"host link: {link}", file=sys.stderr)
    task.serve(FdStream(fd, link))
    return None


def cmd_setup_device(args: argparse.Namespace) -> int:
    setup = _load(args)
    assert setup.node is not None
    with command_line(args) as line:
        printer = Printer()
        task = ProcessImageTask(line, setup)
        keep: Optional[Any] = None
        try:
            if args.host_link:
                keep = _open_link(args.host_link, task, printer)
                print(f"process image of {len(setup.image)} bytes from {args.setup}; the "
                      f"host's InitCANopen starts node {setup.node.node_id} (its default) on "
                      f"{args.channel} ({line.mode}); Ctrl-C to stop", file=sys.stderr)
            else:
                task.init_canopen(0, 0)
                print(f"node {task.node_id} running on {args.channel} ({line.mode}) from "
                      f"{args.setup}, process image of {len(setup.image)} bytes, no host "
                      "link; Ctrl-C to stop", file=sys.stderr)
            try:
                wait_until_done(threading.Event(), printer, args.duration)
            except KeyboardInterrupt:
                pass
        finally:
            task.close()
            if isinstance(keep, _UnixLink):
                keep.close()
            elif isinstance(keep, int):
                os.close(keep)
    return EXIT_OK
