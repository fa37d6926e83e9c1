"""atheris harness: EDS/DCF import (canopenfd.od.eds) on arbitrary bytes.

Fails on any exception but OdFileError from the import, and on an imported
dictionary that does not validate, export and read back (see _checks.py).
Run: python tests/fuzz/py/fuzz_eds.py -max_total_time=60   (README-py.md)
"""

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from _checks import imported, round_trip  # noqa: E402
from _common import instrumented, main  # noqa: E402

with instrumented():
    from canopenfd.od.eds import eds_from_text


def load_eds(data: bytes):
    return eds_from_text(data, "fuzz.eds")


def check(data: bytes) -> None:
    od = imported(load_eds, data)
    if od is not None:
        round_trip(od)


if __name__ == "__main__":
    main("fuzz_eds", check, (".eds", ".dcf"), ("eds.dict",))
