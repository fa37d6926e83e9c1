"""pytest configuration for the Python tests (tests/c and tests/vm are not pytest).

- marker `vcan`: tests on real kernel SocketCAN. They run only when
  CANOPENFD_VCAN names the interfaces, e.g. "vcan0,vcan1,vcan2" (vcan0 and
  vcan1 with MTU 72, vcan2 with MTU 16), which tests/vm/run_in_vm.sh provides.
- CANOPENFD_TIME_SCALE (default 1) stretches every timeout, for slow VMs.
"""

from __future__ import annotations

import itertools
import os
import sys

import pytest

sys.path.insert(0, os.path.dirname(__file__))  # tests/helpers.py

from helpers import TIME_SCALE, scaled, shutdown_virtual_buses  # noqa: E402

_names = itertools.count(1)


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        "vcan: needs the vcan interfaces listed in CANOPENFD_VCAN (run via tests/vm/run_in_vm.sh)")


def vcan_interfaces() -> list:
    value = os.environ.get("CANOPENFD_VCAN", "").strip()
    return [name.strip() for name in value.split(",") if name.strip()]


@pytest.fixture
def vcan() -> list:
    """The vcan interface names, or skip."""
    names = vcan_interfaces()
    if len(names) < 3:
        pytest.skip("set CANOPENFD_VCAN=vcan0,vcan1,vcan2 (vcan0/1 MTU 72, vcan2 MTU 16) "
                    "to run the vcan tests, e.g. tests/vm/run_in_vm.sh -- python3 -m "
                    "pytest -m vcan tests/")
    return names


@pytest.fixture
def bus_name(request: pytest.FixtureRequest) -> str:
    """A fresh in-process bus name per test, so tests never hear each other."""
    return f"mem:{request.node.name[:40]}-{os.getpid()}-{next(_names)}"


@pytest.fixture
def net():
    import canopenfd

    network = canopenfd.Network()
    try:
        yield network
    finally:
        network.close()


@pytest.fixture
def time_scale() -> float:
    return TIME_SCALE


__all__ = ["scaled"]


@pytest.fixture(autouse=True)
def _shut_down_virtual_buses():
    """Buses from helpers.virtual_bus, after every fixture that used them."""
    yield
    shutdown_virtual_buses()
