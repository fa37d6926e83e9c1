"""Documentation that runs: every ```python block of the pages listed here is
executed as a script (each block on its own, in a fresh interpreter), so a
renamed call or a changed behaviour breaks the test, not the reader."""

from __future__ import annotations

import pathlib
import re
import subprocess
import sys

import pytest

from helpers import package_env

ROOT = pathlib.Path(__file__).resolve().parent.parent
#: Pages whose python blocks are whole scripts.
RUNNABLE_PAGES = ["docs/from-python-canopen.md", "docs/network-manager-requests.md",
                  "docs/error-bits.md",
                  "docs/gateway-ascii.md", "docs/remote-access.md", "docs/usdo-transfers.md",
                  "docs/routing.md", "docs/process-image.md", "docs/parameter-store.md",
                  "docs/live-objects.md", "docs/asyncio.md",
                  "docs/cia401.md", "docs/srdo.md", "docs/cia402.md", "docs/mpdo.md"]
_BLOCK = re.compile(r"^```python\n(.*?)^```", re.S | re.M)


def blocks() -> list:
    found = []
    for page in RUNNABLE_PAGES:
        text = (ROOT / page).read_text(encoding="utf-8")
        for number, match in enumerate(_BLOCK.finditer(text), 1):
            line = text.count("\n", 0, match.start()) + 2
            found.append(pytest.param(match.group(1), id=f"{page}:{line}"))
        assert found, f"{page} has no python block"
    return found


@pytest.mark.parametrize("code", blocks())
def test_python_block_runs(code, tmp_path):
    script = tmp_path / "block.py"
    script.write_text(code, encoding="utf-8")
    done = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=package_env(),
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, f"stdout:\n{done.stdout}\nstderr:\n{done.stderr}"
    assert "Traceback" not in done.stderr
