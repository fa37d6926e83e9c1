"""Every ```python block of README.md runs here, as written, so the README
cannot drift from the API. Blocks that continue one another (the tour of the
local node, transfers, PDOs, EMCY, SYNC) run in order in one namespace, in a
world that gives them what the README assumes exists: a line (`line`), a
device on the bus (node 5, from `drive.eds` in the working directory) and a
`firmware` image. A new README block must be given its place in WORLDS."""

from __future__ import annotations

import ast
import asyncio
import contextlib
import os
import pathlib
import re
from typing import Dict, Iterator, List, Tuple

import pytest

import canopenfd
from canopenfd.od import DataType, ODVariable, demo_od, export_eds

README = pathlib.Path(__file__).resolve().parent.parent / "README.md"
_BLOCK = re.compile(r"^```python\n(.*?)^```", re.S | re.M)

#: README python blocks (1-based, in order) -> the world they run in; blocks of
#: one world share a namespace and run in this order ("none": on their own in an
#: empty directory, "repo": on their own in the source tree, for its sample files).
WORLDS = {1: "none", 2: "fd", 3: "repo", 4: "fd", 5: "fd", 6: "fd", 7: "fd", 8: "fd",
          9: "classic", 10: "fd", 11: "fd", 12: "classic", 13: "fd", 14: "none",
          15: "none", 16: "none", 17: "none"}


def readme_blocks() -> List[Tuple[int, int, str]]:
    """(number, line, code) of every python block."""
    text = README.read_text(encoding="utf-8")
    return [(n, text.count("\n", 0, m.start()) + 2, m.group(1))
            for n, m in enumerate(_BLOCK.finditer(text), 1)]


def drive_od(mode: str):
    """The device the README talks to: the demo dictionary with one PDO each
    way, plus the CiA 402 words its PDO examples map."""
    od = demo_od(mode, pdos=1)
    od.add_object(ODVariable("Controlword", 0x6040, 0, DataType.UNSIGNED16, "rw", 0,
                             pdo_mapping=True))
    od.add_object(ODVariable("Statusword", 0x6041, 0, DataType.UNSIGNED16, "ro", 0x0250,
                             pdo_mapping=True))
    od.add_object(ODVariable("Position actual value", 0x6064, 0, DataType.INTEGER32, "ro",
                             0, pdo_mapping=True))
    return od


@contextlib.contextmanager
def world(kind: str, tmp_path: pathlib.Path) -> Iterator[Dict[str, object]]:
    mode = "classic" if kind == "classic" else "fd"
    old = os.getcwd()
    os.chdir(tmp_path)
    net = canopenfd.Network()
    try:
        export_eds(drive_od(mode), "drive.eds")
        bus = f"mem:readme-{kind}"
        device = net.open_line(bus, mode=mode).create_local_node(5, 100, od="drive.eds",
                                                                 boot=False)
        device.serve_domain(0x2100, 1 << 20)
        device.boot()
        names: Dict[str, object] = {"net": net, "line": net.open_line(bus, mode=mode),
                                    "device": device, "firmware": os.urandom(20_000),
                                    "refresh": lambda: None}
        if kind == "classic":
            device.heartbeat_ms = 0            # a guarded device sends no heartbeat
            names["drive"] = names["line"].add_node(5, od="drive.eds")  # type: ignore
        yield names
    finally:
        net.close()
        os.chdir(old)


def run_block(code: str, names: Dict[str, object], where: str) -> None:
    """exec one block; top-level `await` runs it in an event loop."""
    compiled = compile(code, where, "exec", flags=ast.PyCF_ALLOW_TOP_LEVEL_AWAIT)
    result = eval(compiled, names)            # noqa: S307 - the README's own code
    if asyncio.iscoroutine(result):
        asyncio.run(result)


def test_every_block_has_a_world():
    numbers = [n for n, _, _ in readme_blocks()]
    assert numbers == sorted(WORLDS), (f"README python blocks {numbers}, WORLDS knows "
                                       f"{sorted(WORLDS)}: give new blocks their world")


@pytest.mark.parametrize("kind", sorted(set(WORLDS.values())))
def test_readme_blocks_run(kind, tmp_path):
    blocks = [(n, line, code) for n, line, code in readme_blocks() if WORLDS[n] == kind]
    if kind in ("none", "repo"):                 # standalone; "repo": paths of the source tree
        old = os.getcwd()
        os.chdir(README.parent if kind == "repo" else tmp_path)
        try:
            for n, line, code in blocks:
                run_block(code, {}, f"README.md:{line}")
        finally:
            os.chdir(old)
        return
    with world(kind, tmp_path) as names:
        for n, line, code in blocks:
            run_block(code, names, f"README.md:{line}")
