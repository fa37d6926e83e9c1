#!/usr/bin/env python3
"""Classic SDO throughput over a SocketCAN interface (vcan): our client and
python-canopen's client, each against our server and python-canopen's
LocalNode server, side by side in one run, next to the raw classic frame rate.

    python3 bench/sdo_bench.py [-t SECONDS] [-e SECONDS] [--sizes 1024,65536,1048576] [IFACE]
    (bash bench/vcan_bench.sh --sdo / make -C bench sdo run it in the VM)

Processes: the server under test runs in its own process (ours: a canopenfd
local node 5 with the demo OD and a 16 MiB DOMAIN at 0x2100, served by the C
runtime; theirs: python-canopen's LocalNode 7 with read/write callbacks, its
python-can bus filtered to 0x607), one server at a time. Both clients run in
this process (ours: a canopenfd classic line, open for the whole run; theirs: a
canopen.Network whose python-can bus is filtered to the two servers' responses,
connected only for its own rows, since its notifier thread runs Python for each
frame on 0x585 and would slow our rows otherwise).

Every row runs transfers back to back for a time budget (-t, -e for expedited
rows); a transfer still running at the end of the budget is cut (aborted) and
the bytes it moved so far count, so kB/s is always bytes moved / time. A row
whose first transfer did not finish within the budget is marked "partial".
The raw classic frame rate comes from build/bench/raw_socketcan -c (C,
sendmmsg/recvmmsg 32 per call), run in the same process tree just before.
Figures are printed; nothing is asserted about timing. Exit status 1 when a
transfer failed (other than an n/a row), else 0.
"""

from __future__ import annotations

import argparse
import logging
import os
import queue
import subprocess
import sys
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

OURS, THEIRS = 5, 7            # server node-ids
U32_OURS, U32_THEIRS = 0x2007, 0x2000   # 4-byte expedited entries
DOMAIN_OURS = 0x2100
DOMAIN_THEIRS_W = 0x2001       # their server: writes go into a dict
UPLOAD_THEIRS = 0x2100         # their server: 0x2100:n = prebuilt n-th size for uploads
TIMEOUT = 5.0                  # per-response timeout of both clients (slow VM)
SETTLE_S = 1.5                 # quiet time after a cut or failure (see settle())


def pattern(size: int) -> bytes:
    return bytes((i * 7 + (i >> 8)) & 0xFF for i in range(size))


def size_name(size: int) -> str:
    if size >= 1 << 20 and size % (1 << 20) == 0:
        return f"{size >> 20} MiB"
    if size >= 1024 and size % 1024 == 0:
        return f"{size >> 10} KiB"
    return f"{size} B"


# ====================================================================== servers
def serve_ours(iface: str) -> None:
    import canopenfd
    from canopenfd.od import demo_od
    with canopenfd.Network() as net:
        node = net.open_line(iface, mode="classic").create_local_node(
            OURS, od=demo_od("classic"), boot=False)
        node.serve_domain(DOMAIN_OURS, 16 << 20)
        node.boot()
        print("ready", flush=True)
        sys.stdin.read()         # until the parent closes our stdin


def serve_theirs(iface: str, sizes: list) -> None:
    import canopen
    net = canopen.Network()
    net.connect(interface="socketcan", channel=iface,
                can_filters=[{"can_id": 0x600 + THEIRS, "can_mask": 0x7FF}])
    od = canopen.ObjectDictionary()
    for index, dtype in ((U32_THEIRS, canopen.objectdictionary.UNSIGNED32),
                         (DOMAIN_THEIRS_W, canopen.objectdictionary.DOMAIN)):
        var = canopen.objectdictionary.ODVariable(f"v{index:X}", index, 0)
        var.data_type = dtype
        var.access_type = "rw"
        od.add_object(var)
    record = canopen.objectdictionary.ODRecord("uploads", UPLOAD_THEIRS)
    for sub in range(1, len(sizes) + 1):
        var = canopen.objectdictionary.ODVariable(f"u{sub}", UPLOAD_THEIRS, sub)
        var.data_type = canopen.objectdictionary.DOMAIN
        var.access_type = "rw"
        record.add_member(var)
    od.add_object(record)
    node = net.create_node(THEIRS, od)
    store = {(U32_THEIRS, 0): b"\x01\x02\x03\x04"}
    for sub, size in enumerate(sizes, 1):
        store[(UPLOAD_THEIRS, sub)] = pattern(size)
    node.add_write_callback(lambda index, subindex, od, data:
                            store.__setitem__((index, subindex), bytes(data)))
    node.add_read_callback(lambda index, subindex, od: store.get((index, subindex)))
    print("ready", flush=True)
    sys.stdin.read()
    net.disconnect()


class LocalServer:
    """Our server on its own line of our client's Network: one runtime thread
    runs both ends, like raw_socketcan's one-thread yardstick (like with like
    for the raw share; no cross-process wake-ups per frame)."""

    def __init__(self, client: "OurClient", iface: str) -> None:
        from canopenfd.od import demo_od
        self.node = client.net.open_line(iface, mode="classic").create_local_node(
            OURS, od=demo_od("classic"), boot=False)
        self.node.serve_domain(DOMAIN_OURS, 16 << 20)
        self.node.boot()

    def stop(self) -> None:
        # A runtime keeps its lines until it closes: the node stays (so no
        # "ours" server may follow; main() checks the order).
        pass


class Server:
    def __init__(self, which: str, iface: str, sizes: list) -> None:
        args = [sys.executable, os.path.abspath(__file__), "--serve", which,
                "--sizes", ",".join(map(str, sizes)), iface]
        self.proc = subprocess.Popen(args, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     text=True)
        line = self.proc.stdout.readline()
        if line.strip() != "ready":
            self.proc.kill()
            raise SystemExit(f"sdo_bench: the {which} server did not start ({line!r})")

    def stop(self) -> None:
        try:
            self.proc.stdin.close()
            self.proc.wait(20)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


# ====================================================================== raw reference
def raw_rate(iface: str, frames: int) -> dict:
    binary = os.path.join(ROOT, "build", "bench", "raw_socketcan")
    out = subprocess.run([binary, "-c", "-n", str(frames), "-r", "3", iface],
                         capture_output=True, text=True)
    rates = {}
    for line in out.stdout.splitlines():
        label, fields = line[:40].strip(), line[40:].split()
        if label.startswith(("write + read", "sendmmsg + recvmmsg")) and len(fields) == 6:
            # frames, time s, frames/s, MB/s, ns/frame, lost
            rates["batched" if label.startswith("sendmmsg") else "single"] = (
                int(float(fields[2])), int(fields[5]))
    if "batched" not in rates:
        raise SystemExit(f"sdo_bench: raw_socketcan -c failed (status {out.returncode}):\n"
                         f"{out.stdout}{out.stderr}")
    return rates


# ====================================================================== clients
class Cut(Exception):
    """The budget ended inside a transfer; .moved bytes were moved."""

    def __init__(self, moved: int) -> None:
        super().__init__(moved)
        self.moved = moved


class OurClient:
    name = "ours"

    def __init__(self, iface: str) -> None:
        import canopenfd
        self.net = canopenfd.Network()
        self.line = self.net.open_line(iface, mode="classic")
        self.sdo = self.line.sdo

    def open(self) -> None:
        pass   # open from __init__ to the end: the "local" server lives on its Network

    def close(self) -> None:
        self.net.close()

    def _run(self, start, deadline: float):
        moved = [0]

        def progress(n: int) -> None:
            moved[0] = n
        transfer = start(progress)
        try:
            value = transfer.result(timeout=max(0.001, deadline - time.monotonic()))
        except TimeoutError:
            transfer.cancel()
            try:
                transfer.result(timeout=TIMEOUT)
            except Exception:  # noqa: BLE001 - the abort we asked for
                pass
            raise Cut(moved[0]) from None
        return value, transfer.mode

    def expedited(self, node, upload, deadline):
        index = U32_OURS if node == OURS else U32_THEIRS
        if upload:
            value = self.sdo.upload(node, index, 0, timeout=TIMEOUT)
            assert len(value) == 4, value
        else:
            self.sdo.download(node, index, 0, b"\x78\x56\x34\x12", mode="expedited",
                              timeout=TIMEOUT)
        return "expedited"

    def download(self, node, mode, data, deadline):
        index = DOMAIN_OURS if node == OURS else DOMAIN_THEIRS_W
        _, used = self._run(lambda p: self.sdo.start_download(
            node, index, 0, data, mode=mode, timeout=TIMEOUT, progress=p), deadline)
        return used

    def upload(self, node, mode, size, sub, expect, deadline):
        index, sub = (DOMAIN_OURS, 0) if node == OURS else (UPLOAD_THEIRS, sub)
        self.sdo.block_threshold = 1 if mode == "block" else None
        value, used = self._run(lambda p: self.sdo.start_upload(
            node, index, sub, timeout=TIMEOUT, progress=p,
            size_hint=size if mode == "block" else 0), deadline)
        if value != expect:
            raise RuntimeError(f"upload returned {len(value)} bytes that differ from the "
                               f"{len(expect)} expected")
        return used


class TheirClient:
    name = "python-canopen"

    def __init__(self, iface: str) -> None:
        self.iface = iface
        self.net = None
        self.nodes = {}

    def open(self) -> None:
        """Connect for this client's own rows only: its python-can notifier
        thread runs Python for every frame its filters pass, and our server
        answers on 0x585 too, so while connected it would take CPU from our
        client's block uploads (127 frames on 0x585 per sub-block)."""
        import canopen
        self.close()   # a row that raised left it connected
        self.net = canopen.Network()
        self.net.connect(interface="socketcan", channel=self.iface, can_filters=[
            {"can_id": 0x580 + OURS, "can_mask": 0x7FF},
            {"can_id": 0x580 + THEIRS, "can_mask": 0x7FF}])
        for node in (OURS, THEIRS):
            remote = canopen.RemoteNode(node, canopen.ObjectDictionary())
            self.net.add_node(remote)
            remote.sdo.RESPONSE_TIMEOUT = TIMEOUT
            self.nodes[node] = remote.sdo

    def close(self) -> None:
        if self.net is not None:
            self.net.disconnect()
            self.net = None
            self.nodes = {}

    def expedited(self, node, upload, deadline):
        sdo = self.nodes[node]
        self._drain(sdo)
        index = U32_OURS if node == OURS else U32_THEIRS
        if upload:
            value = sdo.upload(index, 0)
            assert len(value) == 4, value
        else:
            sdo.download(index, 0, b"\x78\x56\x34\x12")
        return "expedited"

    @staticmethod
    def _drain(sdo) -> None:
        # Late answers of a cut or failed transfer must not meet the next one.
        try:
            while True:
                sdo.responses.get_nowait()
        except queue.Empty:
            pass

    @staticmethod
    def _cut(sdo, stream, moved):
        # Stop the stream without its end-of-transfer exchange, abort the server.
        stream._done = True
        stream._error = True
        stream._initialized = False
        try:
            sdo.abort(0x08000000)
        except Exception:  # noqa: BLE001
            pass
        try:
            stream.close()
        except Exception:  # noqa: BLE001
            pass
        time.sleep(0.2)
        TheirClient._drain(sdo)
        raise Cut(moved)

    def download(self, node, mode, data, deadline):
        sdo = self.nodes[node]
        self._drain(sdo)
        index = DOMAIN_OURS if node == OURS else DOMAIN_THEIRS_W
        stream = sdo.open(index, 0, "wb", buffering=0, size=len(data),
                          block_transfer=(mode == "block"), force_segment=(mode == "segmented"))
        view = memoryview(data)
        pos, n = 0, 0
        while pos < len(data):
            pos += stream.write(view[pos:pos + 7])
            n += 1
            if n % 64 == 0 and time.monotonic() > deadline and pos < len(data):
                self._cut(sdo, stream, pos)
        stream.close()
        return mode

    def upload(self, node, mode, size, sub, expect, deadline):
        sdo = self.nodes[node]
        self._drain(sdo)
        index, sub = (DOMAIN_OURS, 0) if node == OURS else (UPLOAD_THEIRS, sub)
        stream = sdo.open(index, sub, "rb", buffering=0, block_transfer=(mode == "block"))
        parts, pos, n = [], 0, 0
        while True:
            chunk = stream.read(7)
            if not chunk:
                break
            parts.append(chunk)
            pos += len(chunk)
            n += 1
            if n % 64 == 0 and time.monotonic() > deadline and pos < size:
                self._cut(sdo, stream, pos)
        stream.close()
        if b"".join(parts) != expect:
            raise RuntimeError(f"upload returned {pos} bytes that differ from the "
                               f"{len(expect)} expected")
        return mode


# ====================================================================== rows
class Row:
    def __init__(self, client, server, op, mode, size):
        self.client, self.server, self.op, self.mode, self.size = client, server, op, mode, size
        self.done = 0
        self.bytes = 0
        self.seconds = 0.0
        self.partial = False
        self.failed = 0
        self.note = ""
        self.na = ""
        self.modes_used = set()
        self.server_name = "ours" if server == OURS else "python-canopen"

    @property
    def tps(self):
        return self.done / self.seconds if self.seconds else 0.0

    @property
    def kbps(self):
        return self.bytes / self.seconds / 1000 if self.seconds else 0.0


def measure(row: Row, one, budget: float, max_failures: int = 2) -> Row:
    start = time.monotonic()
    deadline = start + budget
    while True:
        try:
            used = one(deadline)
            row.done += 1
            row.bytes += row.size
            row.modes_used.add(used)
        except Cut as cut:
            row.bytes += cut.moved
            if row.done == 0:
                row.partial = True
            row.seconds = time.monotonic() - start
            settle()
            return row
        except Exception as exc:  # noqa: BLE001 - reported in the table
            row.failed += 1
            row.note = f"{type(exc).__name__}: {exc}"[:160]
            if row.failed >= max_failures:
                break
            settle()
        if time.monotonic() >= deadline:
            break
    row.seconds = time.monotonic() - start
    if row.failed:
        settle()
    return row


def settle() -> None:
    """After a cut or failed transfer (untimed): let late answers arrive and a
    server channel the cut left open time out (our server: 1 s), so neither
    meets the next transfer. A server cannot tell a new block download
    initiate from a segment of a sub-block still open, and python-canopen's
    client takes any late frame as the answer to its next request."""
    time.sleep(SETTLE_S)


HEADER = (f"{'client':<15} {'server':<15} {'op':<8} {'mode':<10} {'size':>7} "
          f"{'transfers/s':>12} {'kB/s':>9} {'xfers':>6} {'time s':>7}  "
          f"{'ours/py-co':>10} {'raw share':>9}  note")


def fmt(row: Row, ratio, share) -> str:
    server = row.server_name
    if row.na:
        return (f"{row.client:<15} {server:<15} {row.op:<8} {row.mode:<10} "
                f"{size_name(row.size):>7} {'n/a':>12} {'n/a':>9} {'-':>6} {'-':>7}  "
                f"{'-':>10} {'-':>9}  {row.na}")
    notes = []
    if row.partial:
        notes.append(f"partial: {row.bytes} of {row.size} B in the {row.seconds:.1f} s budget")
    other = row.modes_used - {row.mode}
    if other:
        notes.append(f"mode used: {', '.join(sorted(other))}")
    if row.failed:
        notes.append(f"{row.failed} failed: {row.note}")
    tps = f"{row.tps:.2f}" if row.done else f"~{row.bytes / row.size / row.seconds:.4f}"
    return (f"{row.client:<15} {server:<15} {row.op:<8} {row.mode:<10} {size_name(row.size):>7} "
            f"{tps:>12} {row.kbps:>9.2f} {row.done:>6} {row.seconds:>7.1f}  "
            f"{ratio:>10} {share:>9}  {'; '.join(notes)}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("iface", nargs="?", default="vcan0")
    ap.add_argument("-t", type=float, default=6.0, help="seconds per segmented/block row")
    ap.add_argument("-e", type=float, default=3.0, help="seconds per expedited row")
    ap.add_argument("-n", type=int, default=100000, help="frames per raw reference run")
    ap.add_argument("--sizes", default="1024,65536,1048576")
    ap.add_argument("--servers", default="ours,local,theirs",
                    help="ours = our server in its own process, local = our server on a "
                         "second line of our client's runtime (one thread), theirs = "
                         "python-canopen's LocalNode")
    ap.add_argument("--serve", choices=("ours", "theirs"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]
    servers = args.servers.split(",")
    if not set(servers) <= {"ours", "local", "theirs"}:
        ap.error(f"--servers: unknown server in {args.servers!r}")
    if "local" in servers and "ours" in servers[servers.index("local"):]:
        ap.error("--servers: 'ours' cannot follow 'local' (the local node 5 stays on the line)")
    if args.serve == "ours":
        serve_ours(args.iface)
        return 0
    if args.serve == "theirs":
        serve_theirs(args.iface, sizes)
        return 0

    import canopen
    import canopenfd  # noqa: F401
    # python-canopen logs every abort it sends; the table reports failures.
    logging.getLogger("canopen").setLevel(logging.CRITICAL)
    print(f"SDO throughput over {args.iface} (classic CAN), python {sys.version.split()[0]}, "
          f"python-canopen {canopen.__version__}; budget {args.t:g} s per row "
          f"({args.e:g} s expedited)")
    raw = raw_rate(args.iface, args.n)
    raw_fps = raw["batched"][0]
    print(f"raw classic 8-byte frames (raw_socketcan -c, {args.n} frames, best of 3): "
          f"sendmmsg+recvmmsg 32/call {raw_fps} frames/s = {raw_fps * 7 / 1000:.1f} kB/s @7 B "
          f"(lost {raw['batched'][1]}); write+read 1/call {raw['single'][0]} frames/s")
    print()
    print(HEADER)
    sys.stdout.flush()

    clients = [OurClient(args.iface), TheirClient(args.iface)]
    rows = []
    status = 0
    for which in servers:
        node = THEIRS if which == "theirs" else OURS
        server = (LocalServer(clients[0], args.iface) if which == "local"
                  else Server(which, args.iface, sizes))
        try:
            plan = [("download", "expedited", 4), ("upload", "expedited", 4)]
            for size in sizes:
                for op in ("download", "upload"):
                    for mode in ("segmented", "block"):
                        plan.append((op, mode, size))
            for op, mode, size in plan:
                data = pattern(size)
                if node == OURS and op == "upload" and mode != "expedited":
                    # fill our server's domain (untimed, our block download)
                    clients[0].sdo.download(OURS, DOMAIN_OURS, 0, data, mode="block",
                                            timeout=TIMEOUT)
                pair = []
                for client in clients:
                    client.open()
                    row = Row(client.name, node, op, mode, size)
                    if which == "local":
                        row.server_name = "ours, 1 thread"
                    if node == THEIRS and mode == "block" and op == "download":
                        row.na = "n/a: python-canopen's LocalNode has no block download server"
                    elif mode == "expedited":
                        measure(row, lambda d, c=client, u=(op == "upload"):
                                c.expedited(node, u, d), args.e)
                    elif op == "download":
                        measure(row, lambda d, c=client: c.download(node, mode, data, d), args.t)
                    else:
                        sub = sizes.index(size) + 1
                        measure(row, lambda d, c=client: c.upload(node, mode, size, sub, data, d),
                                args.t)
                    if row.failed and not (node == THEIRS and mode == "block"):
                        status = 1
                    if client is not clients[0]:
                        client.close()
                    pair.append(row)
                ours, theirs = pair
                ratio = (f"{ours.kbps / theirs.kbps:.1f}x"
                         if ours.kbps and theirs.kbps and not ours.na else "-")
                for row in pair:
                    share = (f"{row.kbps * 1000 / (raw_fps * 7) * 100:.1f} %"
                             if mode == "block" and row.kbps and not row.na else "-")
                    print(fmt(row, ratio if row is ours else "-", share), flush=True)
                    rows.append(row)
        finally:
            server.stop()
    for client in clients:
        client.close()

    raw2 = raw_rate(args.iface, args.n)
    print(f"\nraw classic frames again after the rows: {raw2['batched'][0]} frames/s batched, "
          f"{raw2['single'][0]} frames/s 1/call")
    block = [(o, t) for o, t in zip(rows[::2], rows[1::2])
             if o.mode == "block" and o.server == OURS and o.kbps and t.kbps]
    if block:
        print("\nblock transfers against our server (ours vs python-canopen client, share of "
              "raw frames/s x 7 B):")
        for o, t in block:
            print(f"  {o.server_name:<14} {o.op:<8} {size_name(o.size):>7}: ours {o.kbps:8.2f} kB/s = "
                  f"{o.kbps / t.kbps:6.1f}x python-canopen ({t.kbps:.2f} kB/s), "
                  f"{o.kbps * 1000 / (raw_fps * 7) * 100:5.1f} % of raw")
    return status


if __name__ == "__main__":
    sys.exit(main())
