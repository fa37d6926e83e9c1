"""The package's annotations hold: mypy (pyproject.toml's [tool.mypy], strict)
finds no error in it, py.typed and the C enums' stub are installed, and the stub
is what the binding builds from the C headers now.

Modules others are still typing are listed in EXCLUDED: their errors are not
counted, and an entry that has become clean fails the test until it is removed,
so the list only shrinks (to empty: then every module is checked).
"""

from __future__ import annotations

import enum
import importlib.util
import pathlib
import re
import subprocess
import sys
import time
import types
from typing import Dict, List, Set

import pytest

import canopenfd
from canopenfd._binding import constants

ROOT = pathlib.Path(__file__).resolve().parents[1]
SOURCE = ROOT / "canopenfd"
INSTALLED = pathlib.Path(canopenfd.__file__).resolve().parent

# Modules with mypy errors left (none now: every module of the package is
# checked); a module that has to be excluded again must be named here, and
# leaves as soon as it is clean.
EXCLUDED: Set[str] = set()

_MESSAGE = re.compile(r"^(?P<path>[^:\n]+\.pyi?):(?P<line>\d+): (?P<kind>error|note): ")


def _module_of(path: str) -> str:
    parts = list(pathlib.Path(path).resolve().relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _load_generator() -> types.ModuleType:
    spec = importlib.util.spec_from_file_location("gen_constants_stub",
                                                  ROOT / "tests" / "gen_constants_stub.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def mypy_messages(tmp_path_factory: pytest.TempPathFactory) -> Dict[str, List[str]]:
    """{module: its mypy messages} of a run on the source tree, from a directory
    outside it (the cache there too), with the project's configuration."""
    pytest.importorskip("mypy")
    workdir = tmp_path_factory.mktemp("mypy")
    started = time.monotonic()
    run = subprocess.run(
        [sys.executable, "-m", "mypy", "--config-file", str(ROOT / "pyproject.toml"),
         "--cache-dir", str(workdir / "cache"), "--no-color-output", "--no-pretty",
         str(SOURCE)],
        cwd=workdir, capture_output=True, text=True, timeout=300)
    print(f"mypy took {time.monotonic() - started:.1f} s")
    # 0: clean, 1: errors found; anything else (2) is mypy failing to run
    assert run.returncode in (0, 1), f"mypy did not run:\n{run.stdout}{run.stderr}"
    messages: Dict[str, List[str]] = {}
    for line in run.stdout.splitlines():
        match = _MESSAGE.match(line)
        if match:
            messages.setdefault(_module_of(match["path"]), []).append(line)
        else:   # only the summary line is not a message
            assert line.startswith(("Found ", "Success: ")), f"unexpected mypy output: {line}"
    return messages


def test_mypy_finds_no_error_outside_the_excluded_modules(
        mypy_messages: Dict[str, List[str]]) -> None:
    found = [line for module, lines in sorted(mypy_messages.items())
             if module not in EXCLUDED for line in lines]
    assert not found, "mypy (pyproject.toml's [tool.mypy]):\n" + "\n".join(found)


def test_every_excluded_module_still_has_errors(mypy_messages: Dict[str, List[str]]) -> None:
    """A module that mypy passes now leaves EXCLUDED, so it stays checked."""
    clean = sorted(module for module in EXCLUDED if not any(
        " error: " in line for line in mypy_messages.get(module, [])))
    assert not clean, f"clean now, remove from EXCLUDED in {__file__}: {clean}"


def test_the_constants_stub_is_what_the_binding_builds() -> None:
    """constants.pyi is generated from the enums built out of the C headers: a
    C enum changed without regenerating it fails here."""
    stub = SOURCE / "_binding" / "constants.pyi"
    expected = _load_generator().render(constants)
    assert stub.read_text(encoding="utf-8") == expected, \
        "canopenfd/_binding/constants.pyi is stale: run python tests/gen_constants_stub.py"


def test_the_stub_generator_writes_every_member_with_its_base() -> None:
    """What the comparison above relies on: a changed member changes the text."""
    generator = _load_generator()
    from canopenfd._binding.c_enums import NmtStateBase, c_members

    def fake(value: int) -> types.ModuleType:
        module = types.ModuleType("fake_constants")
        module.Kind = enum.IntEnum("Kind", [("ONE", 1), ("BIG", 0x06010002)])
        module.Kind.__doc__ = "Kinds."
        module.State = NmtStateBase("State", [("OFF", 0), ("ON", value)])
        module.c_members = c_members
        module.__all__ = ["Kind", "State", "c_members"]
        return module

    text = generator.render(fake(5))
    assert 'class Kind(enum.IntEnum):\n    """Kinds."""\n    ONE = 1\n    BIG = 0x06010002\n' \
        in text
    assert "class State(NmtStateBase):\n    OFF = 0\n    ON = 5\n" in text
    assert "from .c_enums import NmtStateBase, c_members as c_members\n" in text
    assert generator.render(fake(6)) != text
    stray = types.ModuleType("stray")
    stray.value = 1
    stray.__all__ = ["value"]
    with pytest.raises(ValueError, match="constants.value: neither an enum nor"):
        generator.render(stray)


def test_the_package_ships_its_types() -> None:
    """pip install puts py.typed (PEP 561) and the enums' stub into the package."""
    assert (INSTALLED / "py.typed").is_file()
    assert (INSTALLED / "_binding" / "constants.pyi").is_file()
