"""atheris harness: XDD/XDC import (canopenfd.od.xdd, canopenfd.od.xmltree) on
arbitrary bytes.

Fails on any exception but OdFileError from the import, and on an imported
dictionary that does not validate, export to EDS and read back (_checks.py).
Run: python tests/fuzz/py/fuzz_xdd.py -max_total_time=60   (README-py.md)
"""

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from _checks import imported, round_trip  # noqa: E402
from _common import instrumented, main  # noqa: E402

with instrumented():
    from canopenfd.od.xdd import xdd_from_text


def load_xdd(data: bytes):
    return xdd_from_text(data, "fuzz.xdd")


def check(data: bytes) -> None:
    od = imported(load_xdd, data)
    if od is not None:
        round_trip(od)


if __name__ == "__main__":
    main("fuzz_xdd", check, (".xdd", ".xdc"), ("xdd.dict",))
